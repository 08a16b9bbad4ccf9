//! The damper models, and how to build one by name.

pub mod bingham;
pub mod direct_shear;
pub mod spencer;
pub mod two_chamber;

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::effects::EffectSet;
use crate::model::DamperModel;

pub use bingham::{BinghamDamper, BinghamParams};
pub use direct_shear::{DirectShear, DirectShearParams};
pub use spencer::{Spencer, SpencerParams};
pub use two_chamber::{FluidLaw, FluidParams, TwoChamber, TwoChamberParams};

/// c0 + c1 |I| + c2 I², floored at 0: how the models' yield levels and viscosities grow
/// with coil current (quadratic, as Graczykowski & Pawłowski assume).
pub fn quadratic_in_current(c: &[f64; 3], current_a: f64) -> f64 {
    polynomial_in_current(c, current_a)
}

/// Most coefficients a law in current may have ([`polynomial_in_current`]): a quartic,
/// which passes through five current levels (a rig's usual test matrix) exactly.
pub const MAX_CURRENT_COEFFS: usize = 5;

/// c0 + c1 |I| + c2 I² + c3 |I|³ + …, floored at 0: a law in current with as many
/// coefficients as `c` holds. Three are the quadratic of Graczykowski & Pawłowski;
/// `mrtwin fit` uses up to [`MAX_CURRENT_COEFFS`] when a record holds that many current
/// levels. Summed term by term from c0, each term ck·|I|·…·|I|: for three coefficients
/// exactly the rounding of `c0 + c1 i + c2 i i`.
pub fn polynomial_in_current(c: &[f64], current_a: f64) -> f64 {
    let i = current_a.abs();
    c.iter()
        .enumerate()
        .map(|(k, ck)| (0..k).fold(*ck, |term, _| term * i))
        .fold(0.0, |sum, term| sum + term)
        .max(0.0)
}

/// The models mrtwin knows. In parameter files and on the command line by
/// [`ModelKind::name`]; an unknown name is an error listing the known ones.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum ModelKind {
    /// Bingham baseline F = f_c sgn v + c0 v + f0.
    Bingham,
    /// Spencer's modified Bouc–Wen.
    Spencer,
    /// Direct-shear Bodner–Partom gap of Skalski & Zalewski.
    DirectShear,
    /// Two-chamber flow-mode damper of Graczykowski & Pawłowski.
    TwoChamber,
}

impl ModelKind {
    /// The effects a choice names for this model (`ModelDefault`: [`Self::default_effects`]).
    pub fn effects(self, choice: crate::effects::EffectsChoice) -> EffectSet {
        choice.resolve(self.default_effects())
    }

    /// Every model.
    pub const ALL: [ModelKind; 4] = [
        ModelKind::Bingham,
        ModelKind::Spencer,
        ModelKind::DirectShear,
        ModelKind::TwoChamber,
    ];

    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Bingham => "bingham",
            ModelKind::Spencer => "spencer",
            ModelKind::DirectShear => "direct-shear",
            ModelKind::TwoChamber => "two-chamber",
        }
    }

    /// The effects a model takes by default (two-chamber: the paper's model).
    pub fn default_effects(self) -> EffectSet {
        match self {
            ModelKind::TwoChamber => EffectSet::paper(),
            _ => EffectSet::NONE,
        }
    }
}

impl fmt::Display for ModelKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown model name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnknownModel(pub String);

impl fmt::Display for UnknownModel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let names: Vec<_> = ModelKind::ALL.iter().map(|m| m.name()).collect();
        write!(
            f,
            "unknown model '{}' (expected one of: {})",
            self.0,
            names.join(", ")
        )
    }
}

impl std::error::Error for UnknownModel {}

impl FromStr for ModelKind {
    type Err = UnknownModel;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        ModelKind::ALL
            .into_iter()
            .find(|m| m.name() == s.trim())
            .ok_or_else(|| UnknownModel(s.trim().to_string()))
    }
}

impl TryFrom<String> for ModelKind {
    type Error = UnknownModel;
    fn try_from(s: String) -> Result<Self, Self::Error> {
        s.parse()
    }
}

impl From<ModelKind> for String {
    fn from(m: ModelKind) -> Self {
        m.name().to_string()
    }
}

/// Parameters of every model, as one parameter-file section each.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct ModelParams {
    /// `bingham`.
    pub bingham: BinghamParams,
    /// `spencer`.
    pub spencer: SpencerParams,
    /// `direct-shear`.
    pub direct_shear: DirectShearParams,
    /// `two-chamber`.
    pub two_chamber: TwoChamberParams,
}

/// A model that does not take some of the effects asked for.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnsupportedEffects {
    /// The model.
    pub model: ModelKind,
    /// The effects it cannot take.
    pub effects: EffectSet,
}

impl fmt::Display for UnsupportedEffects {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "model '{}' has no switchable effects (asked for: {}); effects apply to two-chamber",
            self.model, self.effects
        )
    }
}

impl std::error::Error for UnsupportedEffects {}

/// Build a model. Only `two-chamber` takes effects; the others accept `none`.
pub fn build(
    kind: ModelKind,
    params: &ModelParams,
    effects: EffectSet,
) -> Result<Box<dyn DamperModel>, UnsupportedEffects> {
    if kind != ModelKind::TwoChamber && effects != EffectSet::NONE {
        return Err(UnsupportedEffects {
            model: kind,
            effects,
        });
    }
    Ok(match kind {
        ModelKind::Bingham => Box::new(BinghamDamper::new(params.bingham.clone())),
        ModelKind::Spencer => Box::new(Spencer::new(params.spencer.clone())),
        ModelKind::DirectShear => Box::new(DirectShear::new(params.direct_shear.clone())),
        ModelKind::TwoChamber => Box::new(TwoChamber::new(params.two_chamber.clone(), effects)),
    })
}
