//! The physical effects a damper model can include, by the ids of PHYSICS.md.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// One physical effect beyond the incompressible Bingham flow-mode damper.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Effect {
    /// Finite bulk modulus of the fluid in each chamber.
    FluidCompressibility,
    /// Gas accumulator: preload p0 and polytropic stiffness.
    GasSpring,
    /// Coulomb friction of seals and guides.
    SealFriction,
    /// Fluid heating by dissipated power; yield stress and viscosity fall with temperature.
    ThermalSoftening,
    /// First-order lag of the magnetic field behind the coil current.
    FieldLag,
    /// Mass of the fluid accelerated through the gap.
    FluidInertia,
}

impl Effect {
    /// Every effect, in PHYSICS.md order.
    pub const ALL: [Effect; 6] = [
        Effect::FluidCompressibility,
        Effect::GasSpring,
        Effect::SealFriction,
        Effect::ThermalSoftening,
        Effect::FieldLag,
        Effect::FluidInertia,
    ];

    /// The id used on the command line, in JSON and in PHYSICS.md.
    pub fn id(self) -> &'static str {
        match self {
            Effect::FluidCompressibility => "fluid_compressibility",
            Effect::GasSpring => "gas_spring",
            Effect::SealFriction => "seal_friction",
            Effect::ThermalSoftening => "thermal_softening",
            Effect::FieldLag => "field_lag",
            Effect::FluidInertia => "fluid_inertia",
        }
    }

    fn bit(self) -> u8 {
        1 << (self as u8)
    }
}

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.id())
    }
}

/// An unknown effect id.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnknownEffect(pub String);

impl fmt::Display for UnknownEffect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let ids: Vec<_> = Effect::ALL.iter().map(|e| e.id()).collect();
        write!(
            f,
            "unknown effect '{}' (expected one of: {}, or none)",
            self.0,
            ids.join(", ")
        )
    }
}

impl std::error::Error for UnknownEffect {}

impl FromStr for Effect {
    type Err = UnknownEffect;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Effect::ALL
            .into_iter()
            .find(|e| e.id() == s.trim())
            .ok_or_else(|| UnknownEffect(s.trim().to_string()))
    }
}

/// A set of effects switched on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct EffectSet(u8);

impl EffectSet {
    /// No effect: the incompressible Bingham flow-mode damper.
    pub const NONE: EffectSet = EffectSet(0);

    /// The model of Graczykowski & Pawłowski: compressibility and the gas spring.
    pub fn paper() -> Self {
        Self::from_iter([Effect::FluidCompressibility, Effect::GasSpring])
    }

    /// Every effect.
    pub fn all() -> Self {
        Self::from_iter(Effect::ALL)
    }

    /// Is `e` on?
    pub fn has(self, e: Effect) -> bool {
        self.0 & e.bit() != 0
    }

    /// This set with `e` switched on.
    pub fn with(self, e: Effect) -> Self {
        Self(self.0 | e.bit())
    }

    /// This set with `e` switched off.
    pub fn without(self, e: Effect) -> Self {
        Self(self.0 & !e.bit())
    }

    /// The effects on, in PHYSICS.md order.
    pub fn iter(self) -> impl Iterator<Item = Effect> {
        Effect::ALL.into_iter().filter(move |e| self.has(*e))
    }

    /// Parse a comma list of ids, or `none`.
    pub fn parse_list(s: &str) -> Result<Self, UnknownEffect> {
        if s.trim() == "none" || s.trim().is_empty() {
            return Ok(Self::NONE);
        }
        s.split(',')
            .map(Effect::from_str)
            .try_fold(Self::NONE, |acc, e| Ok(acc.with(e?)))
    }
}

impl FromIterator<Effect> for EffectSet {
    fn from_iter<T: IntoIterator<Item = Effect>>(iter: T) -> Self {
        iter.into_iter().fold(Self::NONE, |s, e| s.with(e))
    }
}

impl fmt::Display for EffectSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if *self == Self::NONE {
            return f.write_str("none");
        }
        let ids: Vec<_> = self.iter().map(|e| e.id()).collect();
        f.write_str(&ids.join(","))
    }
}

/// The effects asked for, as parameter files and the command line name them: empty (the
/// model's own, [`crate::models::ModelKind::default_effects`]), `paper` ([`EffectSet::paper`]), `all`,
/// `none`, or a comma list of ids. Parsed once, where the text is read; an unknown id is
/// an error listing the known ones.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum EffectsChoice {
    /// The model's own effects (written as the empty string).
    #[default]
    ModelDefault,
    /// The model of Graczykowski & Pawłowski (`paper`).
    Paper,
    /// Every effect (`all`).
    All,
    /// Exactly these (`none` or a comma list of ids).
    List(EffectSet),
}

impl EffectsChoice {
    /// The effect set, with `model_default` standing for the model's own.
    pub fn resolve(self, model_default: EffectSet) -> EffectSet {
        match self {
            EffectsChoice::ModelDefault => model_default,
            EffectsChoice::Paper => EffectSet::paper(),
            EffectsChoice::All => EffectSet::all(),
            EffectsChoice::List(set) => set,
        }
    }
}

impl FromStr for EffectsChoice {
    type Err = UnknownEffect;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Ok(match s.trim() {
            "" => EffectsChoice::ModelDefault,
            "paper" => EffectsChoice::Paper,
            "all" => EffectsChoice::All,
            list => EffectsChoice::List(EffectSet::parse_list(list)?),
        })
    }
}

impl TryFrom<String> for EffectsChoice {
    type Error = UnknownEffect;
    fn try_from(s: String) -> Result<Self, Self::Error> {
        s.parse()
    }
}

impl fmt::Display for EffectsChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EffectsChoice::ModelDefault => Ok(()),
            EffectsChoice::Paper => f.write_str("paper"),
            EffectsChoice::All => f.write_str("all"),
            EffectsChoice::List(set) => set.fmt(f),
        }
    }
}

impl From<EffectsChoice> for String {
    fn from(c: EffectsChoice) -> Self {
        c.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::ModelKind;

    #[test]
    fn parse_and_print_round_trip() {
        let s = EffectSet::parse_list("gas_spring,fluid_compressibility").unwrap();
        assert_eq!(s, EffectSet::paper());
        assert_eq!(s.to_string(), "fluid_compressibility,gas_spring");
        assert_eq!(EffectSet::parse_list("none").unwrap(), EffectSet::NONE);
        let err = EffectSet::parse_list("gas_spring,magic").unwrap_err();
        assert!(err.to_string().contains("'magic'"));
    }

    #[test]
    fn choices_parse_print_and_resolve() {
        for (text, choice) in [
            ("", EffectsChoice::ModelDefault),
            (" paper ", EffectsChoice::Paper),
            ("all", EffectsChoice::All),
            ("none", EffectsChoice::List(EffectSet::NONE)),
            (
                "seal_friction,field_lag",
                EffectsChoice::List(EffectSet::from_iter([
                    Effect::SealFriction,
                    Effect::FieldLag,
                ])),
            ),
        ] {
            let parsed: EffectsChoice = text.parse().unwrap();
            assert_eq!(parsed, choice, "{text:?}");
            assert_eq!(parsed.to_string().parse::<EffectsChoice>().unwrap(), choice);
        }
        assert_eq!(
            ModelKind::TwoChamber.effects(EffectsChoice::ModelDefault),
            EffectSet::paper()
        );
        assert_eq!(
            ModelKind::Bingham.effects(EffectsChoice::ModelDefault),
            EffectSet::NONE
        );
        assert_eq!(
            ModelKind::Bingham.effects(EffectsChoice::All),
            EffectSet::all()
        );
        let err = "gas_spring,magic".parse::<EffectsChoice>().unwrap_err();
        assert!(err.to_string().contains("'magic'") && err.to_string().contains("gas_spring"));
    }
}
