//! Calibration of the twin's own model to recordings (`mrtwin fit`, issue 12).
//!
//! The records are run through the same [`TwinPipeline`] as the live node and `replay`
//! (conditioning, model stepping on the sample stamps; no estimator), so the residual
//! the fit minimises is the one a replay of the fitted parameters shows. The free
//! parameters are the model's own keys ([`ParamKey`]); positive ones are fitted in log
//! space, the others around their start on the scale of their start. Levenberg–Marquardt
//! ([`numerics::least_squares`]) with a forward-difference Jacobian, whose columns are
//! simulated in parallel.
//!
//! What a record can identify ([`free_parameters`]): with the geometry unknown, the yield
//! force and viscous coefficient as laws in current, through τ_y(I), μ(I) at the base
//! geometry (as many polynomial coefficients as the record has current levels, at most
//! three); a chamber compliance through K at the base chamber volumes; the gas stiffness
//! through its volume (its preload is one offset with the load cell's zero, so p0 is
//! held); each other effect by its one parameter. For Spencer's Bouc–Wen twin, the
//! parameters of [`SpencerKey`] (A, n, x0 and the command gain held); those a record still
//! cannot tell apart are reported by [`fit_or_unidentified`] with the optimum reached, so
//! that the caller can hold them there and fit again.

use std::fmt;

use nalgebra::{DMatrix, DVector};
use numerics::least_squares::{
    levenberg_marquardt, normal_equations, sum_of_squares, LmOptions, LmStop,
};
use numerics::parallel::map_indexed;
use twin::models::{FluidLaw, ModelKind, ModelParams, SpencerParams, MAX_CURRENT_COEFFS};
use twin::{Effect, EffectSet};

use crate::conditioning::{ConditioningConfig, CurrentChannel, SensorSample};
use crate::pipeline::{PipelineConfig, Processed, TwinPipeline};

/// One parameter the fit may move, by its parameter-file key.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamKey {
    /// `bingham.friction_force_n[k]`.
    BinghamFriction(usize),
    /// `bingham.damping_n_s_m[k]`.
    BinghamDamping(usize),
    /// `bingham.offset_n`.
    BinghamOffset,
    /// `two_chamber.fluid.yield_stress_pa[k]`.
    YieldStress(usize),
    /// `two_chamber.fluid.viscosity_pa_s[k]`.
    Viscosity(usize),
    /// `two_chamber.fluid.flow_index` (Herschel–Bulkley).
    FlowIndex,
    /// `two_chamber.fluid.pre_yield_leak` (fitted when the base file gives one).
    PreYieldLeak,
    /// `two_chamber.fluid.yield_step_share` (fitted when the base file gives one).
    YieldStepShare,
    /// `two_chamber.fluid.yield_step_velocity_m_s` (fitted with the yield step).
    YieldStepVelocity,
    /// `two_chamber.load_cell_offset_n`.
    LoadCellOffset,
    /// `two_chamber.bulk_modulus_pa` (`fluid_compressibility`).
    BulkModulus,
    /// `two_chamber.gas_volume_m3` (`gas_spring`).
    GasVolume,
    /// `two_chamber.seal_friction_n` (`seal_friction`).
    SealFriction,
    /// `two_chamber.moving_mass_kg` (`fluid_inertia`: the rig's moving mass beside the gap
    /// fluid's, which keeps its density).
    MovingMass,
    /// `two_chamber.field_time_constant_s` (`field_lag`).
    FieldTimeConstant,
    /// `two_chamber.heat_capacity_j_per_k` (`thermal_softening`).
    HeatCapacity,
    /// `conditioning.driver_lag_s`: the current driver's first-order lag, when the
    /// recording's current column is its command voltage.
    DriverLag,
    /// A parameter of Spencer's modified Bouc–Wen model (`spencer.*`).
    Spencer(SpencerKey),
}

/// The fitted parameters of Spencer's modified Bouc–Wen model (`twin::models::spencer`,
/// Spencer et al. 1997, eqs. (9)–(14)). A, n, x0 and the command gain are held: z can be
/// rescaled with A, γ, β and α together without changing the force, n is fixed at the
/// paper's 2, −k1·x0 is one offset with the load cell's zero (fitted as that), and the
/// gain only rescales the laws in u.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpencerKey {
    /// c0a \[N·s/m\].
    C0a,
    /// c0b \[N·s/(m·V)\].
    C0b,
    /// k0 \[N/m\].
    K0,
    /// c1a \[N·s/m\].
    C1a,
    /// c1b \[N·s/(m·V)\].
    C1b,
    /// k1 \[N/m\].
    K1,
    /// F_off \[N\]: the load cell's zero (x0 is held: with k1 it is the same offset).
    LoadCellOffset,
    /// αa \[N/m\].
    AlphaA,
    /// αb \[N/(m·V)\].
    AlphaB,
    /// γ \[1/m²\].
    Gamma,
    /// β \[1/m²\].
    Beta,
    /// η \[1/s\]: the command filter (field dynamics).
    Eta,
}

impl SpencerKey {
    /// The key under `spencer.` in the parameter file.
    pub fn name(self) -> &'static str {
        match self {
            SpencerKey::C0a => "c0a",
            SpencerKey::C0b => "c0b",
            SpencerKey::K0 => "k0",
            SpencerKey::C1a => "c1a",
            SpencerKey::C1b => "c1b",
            SpencerKey::K1 => "k1",
            SpencerKey::LoadCellOffset => "load_cell_offset_n",
            SpencerKey::AlphaA => "alpha_a",
            SpencerKey::AlphaB => "alpha_b",
            SpencerKey::Gamma => "gamma",
            SpencerKey::Beta => "beta",
            SpencerKey::Eta => "eta",
        }
    }

    fn get(self, p: &SpencerParams) -> f64 {
        match self {
            SpencerKey::C0a => p.c0a,
            SpencerKey::C0b => p.c0b,
            SpencerKey::K0 => p.k0,
            SpencerKey::C1a => p.c1a,
            SpencerKey::C1b => p.c1b,
            SpencerKey::K1 => p.k1,
            SpencerKey::LoadCellOffset => p.load_cell_offset_n,
            SpencerKey::AlphaA => p.alpha_a,
            SpencerKey::AlphaB => p.alpha_b,
            SpencerKey::Gamma => p.gamma,
            SpencerKey::Beta => p.beta,
            SpencerKey::Eta => p.eta,
        }
    }

    fn slot(self, p: &mut SpencerParams) -> &mut f64 {
        match self {
            SpencerKey::C0a => &mut p.c0a,
            SpencerKey::C0b => &mut p.c0b,
            SpencerKey::K0 => &mut p.k0,
            SpencerKey::C1a => &mut p.c1a,
            SpencerKey::C1b => &mut p.c1b,
            SpencerKey::K1 => &mut p.k1,
            SpencerKey::LoadCellOffset => &mut p.load_cell_offset_n,
            SpencerKey::AlphaA => &mut p.alpha_a,
            SpencerKey::AlphaB => &mut p.alpha_b,
            SpencerKey::Gamma => &mut p.gamma,
            SpencerKey::Beta => &mut p.beta,
            SpencerKey::Eta => &mut p.eta,
        }
    }
}

impl ParamKey {
    /// The dotted parameter-file key.
    pub fn key(self) -> String {
        match self {
            ParamKey::BinghamFriction(k) => format!("bingham.friction_force_n[{k}]"),
            ParamKey::BinghamDamping(k) => format!("bingham.damping_n_s_m[{k}]"),
            ParamKey::BinghamOffset => "bingham.offset_n".into(),
            ParamKey::YieldStress(k) => format!("two_chamber.fluid.yield_stress_pa[{k}]"),
            ParamKey::Viscosity(k) => format!("two_chamber.fluid.viscosity_pa_s[{k}]"),
            ParamKey::FlowIndex => "two_chamber.fluid.flow_index".into(),
            ParamKey::PreYieldLeak => "two_chamber.fluid.pre_yield_leak".into(),
            ParamKey::YieldStepShare => "two_chamber.fluid.yield_step_share".into(),
            ParamKey::YieldStepVelocity => "two_chamber.fluid.yield_step_velocity_m_s".into(),
            ParamKey::LoadCellOffset => "two_chamber.load_cell_offset_n".into(),
            ParamKey::BulkModulus => "two_chamber.bulk_modulus_pa".into(),
            ParamKey::GasVolume => "two_chamber.gas_volume_m3".into(),
            ParamKey::SealFriction => "two_chamber.seal_friction_n".into(),
            ParamKey::MovingMass => "two_chamber.moving_mass_kg".into(),
            ParamKey::FieldTimeConstant => "two_chamber.field_time_constant_s".into(),
            ParamKey::HeatCapacity => "two_chamber.heat_capacity_j_per_k".into(),
            ParamKey::DriverLag => "conditioning.driver_lag_s".into(),
            ParamKey::Spencer(k) => format!("spencer.{}", k.name()),
        }
    }

    /// The value in `cfg`.
    pub fn get(self, cfg: &PipelineConfig) -> f64 {
        let p = &cfg.params;
        let t = &p.two_chamber;
        match self {
            ParamKey::BinghamFriction(k) => p.bingham.friction_force_n[k],
            ParamKey::BinghamDamping(k) => p.bingham.damping_n_s_m[k],
            ParamKey::BinghamOffset => p.bingham.offset_n,
            ParamKey::YieldStress(k) => coefficient(&t.fluid.yield_stress_pa, k),
            ParamKey::Viscosity(k) => coefficient(&t.fluid.viscosity_pa_s, k),
            ParamKey::FlowIndex => t.fluid.flow_index,
            ParamKey::PreYieldLeak => t.fluid.pre_yield_leak,
            ParamKey::YieldStepShare => t.fluid.yield_step_share,
            ParamKey::YieldStepVelocity => t.fluid.yield_step_velocity_m_s,
            ParamKey::LoadCellOffset => t.load_cell_offset_n,
            ParamKey::BulkModulus => t.bulk_modulus_pa,
            ParamKey::GasVolume => t.gas_volume_m3,
            ParamKey::SealFriction => t.seal_friction_n,
            ParamKey::MovingMass => t.moving_mass_kg,
            ParamKey::FieldTimeConstant => t.field_time_constant_s,
            ParamKey::HeatCapacity => t.heat_capacity_j_per_k,
            ParamKey::DriverLag => cfg.conditioning.driver_lag_s,
            ParamKey::Spencer(k) => k.get(&p.spencer),
        }
    }

    /// Set the value in `cfg`.
    pub fn set(self, cfg: &mut PipelineConfig, v: f64) {
        let p = &mut cfg.params;
        let t = &mut p.two_chamber;
        match self {
            ParamKey::BinghamFriction(k) => p.bingham.friction_force_n[k] = v,
            ParamKey::BinghamDamping(k) => p.bingham.damping_n_s_m[k] = v,
            ParamKey::BinghamOffset => p.bingham.offset_n = v,
            ParamKey::YieldStress(k) => set_coefficient(&mut t.fluid.yield_stress_pa, k, v),
            ParamKey::Viscosity(k) => set_coefficient(&mut t.fluid.viscosity_pa_s, k, v),
            ParamKey::FlowIndex => t.fluid.flow_index = v,
            ParamKey::PreYieldLeak => t.fluid.pre_yield_leak = v,
            ParamKey::YieldStepShare => t.fluid.yield_step_share = v,
            ParamKey::YieldStepVelocity => t.fluid.yield_step_velocity_m_s = v,
            ParamKey::LoadCellOffset => t.load_cell_offset_n = v,
            ParamKey::BulkModulus => t.bulk_modulus_pa = v,
            ParamKey::GasVolume => t.gas_volume_m3 = v,
            ParamKey::SealFriction => t.seal_friction_n = v,
            ParamKey::MovingMass => t.moving_mass_kg = v,
            ParamKey::FieldTimeConstant => t.field_time_constant_s = v,
            ParamKey::HeatCapacity => t.heat_capacity_j_per_k = v,
            ParamKey::DriverLag => cfg.conditioning.driver_lag_s = v,
            ParamKey::Spencer(k) => *k.slot(&mut p.spencer) = v,
        }
    }

    /// Physical only when positive: fitted as a logarithm.
    pub fn positive(self) -> bool {
        matches!(
            self,
            ParamKey::FlowIndex
                | ParamKey::PreYieldLeak
                | ParamKey::YieldStepShare
                | ParamKey::YieldStepVelocity
                | ParamKey::BulkModulus
                | ParamKey::GasVolume
                | ParamKey::SealFriction
                | ParamKey::FieldTimeConstant
                | ParamKey::HeatCapacity
                | ParamKey::DriverLag
        ) || matches!(self, ParamKey::Spencer(k) if k != SpencerKey::LoadCellOffset)
    }
}

impl fmt::Display for ParamKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.key())
    }
}

/// Coefficient `k` of a law in current (absent ones are 0).
fn coefficient(c: &[f64], k: usize) -> f64 {
    c.get(k).copied().unwrap_or(0.0)
}

/// Set coefficient `k` of a law in current, padding with zeros up to it.
fn set_coefficient(c: &mut Vec<f64>, k: usize, v: f64) {
    if c.len() <= k {
        c.resize(k + 1, 0.0);
    }
    c[k] = v;
}

/// The parameters a record can identify for `model` with `effects`, and what each
/// choice means (the notes go into the fit's report). `current_levels` is the number of
/// distinct current levels in the records (a continuously varying current counts as
/// many). When the recording's current column is a command voltage, the driver's lag is
/// fitted too (from [`DRIVER_LAG_START_S`] when the base gives none), except for spencer,
/// whose command filter η is that lag.
pub fn free_parameters(
    cfg: &PipelineConfig,
    current_levels: usize,
) -> Result<(Vec<ParamKey>, Vec<String>), FitError> {
    let (model, params, effects) = (cfg.model, &cfg.params, cfg.effects);
    let k = current_levels.clamp(1, 3);
    let mut notes = Vec::new();
    if k < 3 && model != ModelKind::Spencer {
        notes.push(format!(
            "the records hold {current_levels} current level(s): only the first {k} \
             coefficient(s) of each law in current are fitted, the others keep their base values"
        ));
    }
    let mut keys = Vec::new();
    match model {
        ModelKind::Bingham => {
            keys.extend((0..k).map(ParamKey::BinghamFriction));
            keys.extend((0..k).map(ParamKey::BinghamDamping));
            keys.push(ParamKey::BinghamOffset);
        }
        ModelKind::TwoChamber => {
            keys = two_chamber_keys(params, effects, current_levels, &mut notes);
        }
        ModelKind::Spencer => {
            keys = spencer_keys(effects, current_levels, &mut notes)?;
        }
        other => return Err(FitError::UnsupportedModel(other)),
    }
    if cfg.conditioning.current_channel == CurrentChannel::CommandVoltage {
        if model == ModelKind::Spencer {
            notes.push(
                "conditioning.driver_lag_s: the current column is a command voltage; spencer's \
                 command filter η is the field's lag, so the driver's lag keeps its base value"
                    .into(),
            );
        } else {
            notes.push(format!(
                "conditioning.driver_lag_s: the current column is the driver's command voltage; \
                 the driver's first-order lag is fitted (from {} s when the base gives none; \
                 --hold conditioning.driver_lag_s keeps the base value), its gain is held (it \
                 only rescales the laws in current)",
                if cfg.conditioning.driver_lag_s > 0.0 {
                    cfg.conditioning.driver_lag_s
                } else {
                    DRIVER_LAG_START_S
                }
            ));
            keys.push(ParamKey::DriverLag);
        }
    }
    Ok((keys, notes))
}

/// The two-chamber model's free parameters: the laws in current τ_y(I) and μ(I) with one
/// coefficient per current level (up to a quartic), the fluid law's own shape parameters
/// where the base file uses them, the load cell's zero, and one parameter per effect
/// (each with what it means in `notes`).
fn two_chamber_keys(
    params: &ModelParams,
    effects: EffectSet,
    current_levels: usize,
    notes: &mut Vec<String>,
) -> Vec<ParamKey> {
    let k_fluid = current_levels.clamp(1, MAX_CURRENT_COEFFS);
    let mut keys = Vec::new();
    notes.push(
        "the geometry (bore, rod, gap, chamber volumes) is not fitted: the records \
         identify the yield force and the viscous coefficient as laws in current, \
         fitted here as τ_y(I) and μ(I) at the base geometry"
            .into(),
    );
    if k_fluid > 3 {
        notes.push(format!(
            "the records hold {current_levels} current levels: τ_y(I) and μ(I) are \
             fitted with {k_fluid} coefficients each (c0 + c1 |I| + … + c{} |I|^{})",
            k_fluid - 1,
            k_fluid - 1
        ));
    }
    keys.extend((0..k_fluid).map(ParamKey::YieldStress));
    keys.extend((0..k_fluid).map(ParamKey::Viscosity));
    if params.two_chamber.fluid.law == FluidLaw::HerschelBulkley {
        keys.push(ParamKey::FlowIndex);
    }
    if params.two_chamber.fluid.pre_yield_leak > 0.0 {
        keys.push(ParamKey::PreYieldLeak);
    }
    if params.two_chamber.fluid.yield_step_share > 0.0 {
        keys.push(ParamKey::YieldStepShare);
        keys.push(ParamKey::YieldStepVelocity);
    }
    keys.push(ParamKey::LoadCellOffset);
    for e in effects.iter() {
        keys.push(match e {
            Effect::FluidCompressibility => {
                notes.push(
                    "fluid_compressibility: the records identify a chamber compliance \
                     V/(K A²), fitted through K at the base chamber volumes"
                        .into(),
                );
                ParamKey::BulkModulus
            }
            Effect::GasSpring => {
                notes.push(
                    "gas_spring: the preload force −p0·Ar and the load cell's zero are \
                     one offset; p0 keeps its base value and the stiffness κ p0 Ar²/Vg0 \
                     is fitted through the gas volume"
                        .into(),
                );
                ParamKey::GasVolume
            }
            Effect::SealFriction => ParamKey::SealFriction,
            Effect::FluidInertia => {
                notes.push(
                    "fluid_inertia: the gap fluid's mass and a rig's moving mass are one \
                     `m a`; the fluid keeps its density and the moving mass is fitted"
                        .into(),
                );
                ParamKey::MovingMass
            }
            Effect::FieldLag => ParamKey::FieldTimeConstant,
            Effect::ThermalSoftening => {
                notes.push(
                    "thermal_softening: fitted through the heat capacity, with the \
                     fluid's temperature coefficients and the heat loss at their base values"
                        .into(),
                );
                ParamKey::HeatCapacity
            }
        });
    }
    keys
}

/// Spencer's Bouc–Wen model's free parameters (no effects): the laws in u fitted linear
/// and the command filter η only with two current levels or more; A, n, x0 and the gain
/// held (`notes` say why).
fn spencer_keys(
    effects: EffectSet,
    current_levels: usize,
    notes: &mut Vec<String>,
) -> Result<Vec<ParamKey>, FitError> {
    let mut keys = Vec::new();
    if effects != EffectSet::NONE {
        return Err(FitError::Effects(format!(
            "model 'spencer' takes no effects (asked for: {effects})"
        )));
    }
    notes.push(
        "spencer: A, n, x0 and volts_per_amp are held (z rescales with A, γ, β and α \
         together; −k1·x0 is one offset with the load cell's zero, fitted as \
         load_cell_offset_n; the gain only rescales the laws in u)"
            .into(),
    );
    use SpencerKey::*;
    keys.extend(
        [C0a, K0, C1a, K1, LoadCellOffset, AlphaA, Gamma, Beta]
            .into_iter()
            .map(ParamKey::Spencer),
    );
    if current_levels >= 2 {
        notes.push(
            "spencer: the laws in u are linear (αb, c0b, c1b fitted) and the command \
             filter η is fitted from the changes of current"
                .into(),
        );
        keys.extend([C0b, C1b, AlphaB, Eta].into_iter().map(ParamKey::Spencer));
    } else {
        notes.push("spencer: one current level: αb, c0b, c1b and η keep their base values".into());
    }
    Ok(keys)
}

/// Where the fit starts the driver's lag when the base file gives none (0) \[s\]: a
/// typical current driver and coil (Dyke's prototype: 10–20 ms).
pub const DRIVER_LAG_START_S: f64 = 0.005;

impl FitOutcome {
    /// `base` with the fitted model parameters and conditioning: the configuration a
    /// replay of this fit runs (and a twin file written from it holds).
    pub fn applied_to(&self, base: &PipelineConfig) -> PipelineConfig {
        PipelineConfig {
            params: self.params.clone(),
            conditioning: self.conditioning.clone(),
            ..base.clone()
        }
    }
}

/// The value the fit starts `key` from: its value in `cfg`, or [`DRIVER_LAG_START_S`] for
/// a driver lag of 0 (a lag is fitted as a logarithm).
fn start_value(key: ParamKey, cfg: &PipelineConfig) -> f64 {
    let v = key.get(cfg);
    if key == ParamKey::DriverLag && v <= 0.0 {
        DRIVER_LAG_START_S
    } else {
        v
    }
}

/// Why a fit was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum FitError {
    /// `mrtwin fit` calibrates `bingham`, `spencer` and `two-chamber`.
    UnsupportedModel(ModelKind),
    /// The model does not take the effects asked for.
    Effects(String),
    /// Too few usable samples for the parameters.
    TooFewSamples {
        /// Usable samples.
        samples: usize,
        /// Free parameters.
        parameters: usize,
    },
    /// A positive parameter starts at zero or below.
    BadStart(ParamKey, f64),
    /// The records do not tell these parameters apart (normal equations singular).
    NotIdentifiable(Vec<ParamKey>),
    /// The model produced a non-finite force.
    NonFinite(ParamKey),
}

impl fmt::Display for FitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FitError::UnsupportedModel(m) => write!(
                f,
                "model '{m}' cannot be fitted yet (mrtwin fit calibrates bingham, spencer and \
                 two-chamber)"
            ),
            FitError::Effects(e) => write!(f, "{e}"),
            FitError::TooFewSamples {
                samples,
                parameters,
            } => write!(
                f,
                "{samples} usable samples are too few for {parameters} free parameters"
            ),
            FitError::BadStart(k, v) => write!(
                f,
                "parameter '{k}' starts at {v}: it must be positive to be fitted"
            ),
            FitError::NotIdentifiable(keys) => {
                let names: Vec<String> = keys.iter().map(|k| k.key()).collect();
                write!(
                    f,
                    "not identifiable: the records cannot tell apart {} (hold some of them, or \
                     record more current levels and strokes)",
                    names.join(", ")
                )
            }
            FitError::NonFinite(k) => write!(
                f,
                "the model gives a non-finite force near '{k}': the fit did not converge"
            ),
        }
    }
}

impl std::error::Error for FitError {}

/// What to fit.
#[derive(Debug, Clone)]
pub struct FitProblem<'a> {
    /// The pipeline at the start values (its estimator is switched off for the fit).
    pub config: PipelineConfig,
    /// Free parameters.
    pub keys: Vec<ParamKey>,
    /// The records, each run through its own pipeline.
    pub records: &'a [Vec<SensorSample>],
    /// Per record and sample: used by the fit (the others are held out).
    pub mask: Vec<Vec<bool>>,
}

/// A fitted parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct FittedParam {
    /// Which.
    pub key: ParamKey,
    /// Start value.
    pub start: f64,
    /// Fitted value.
    pub value: f64,
    /// Standard error (residual autocorrelation taken into account).
    pub std_error: f64,
}

/// The result of [`fit`].
#[derive(Debug, Clone)]
pub struct FitOutcome {
    /// Parameters at the optimum.
    pub params: ModelParams,
    /// The conditioning at the optimum (a fitted driver lag; else the base's).
    pub conditioning: ConditioningConfig,
    /// The free parameters.
    pub fitted: Vec<FittedParam>,
    /// RMS residual over the fitted samples at the start \[N\].
    pub start_rmse_n: f64,
    /// RMS residual over the fitted samples at the optimum \[N\].
    pub rmse_n: f64,
    /// Fitted samples.
    pub samples: usize,
    /// Levenberg–Marquardt iterations.
    pub iterations: usize,
    /// Why the iterations stopped.
    pub stop: LmStop,
}

/// The pipeline's predicted force at every sample of each record (NaN where the sample
/// was dropped or a channel is stuck, so that no fit or RMS uses it): exactly what a
/// replay of `cfg` predicts. The pipeline's own log lines are not written: the fit
/// evaluates trial parameters whose solver may fail on every sample (a rejected step),
/// and a replay of the result says so itself.
pub fn predict(cfg: &PipelineConfig, records: &[Vec<SensorSample>]) -> Vec<Vec<f64>> {
    tracing::subscriber::with_default(tracing::subscriber::NoSubscriber::default(), || {
        predict_quietly(cfg, records)
    })
}

fn predict_quietly(cfg: &PipelineConfig, records: &[Vec<SensorSample>]) -> Vec<Vec<f64>> {
    let cfg = PipelineConfig {
        estimator: None,
        ..cfg.clone()
    };
    records
        .iter()
        .map(|rec| {
            let Ok(mut p) = TwinPipeline::new(cfg.clone()) else {
                return vec![f64::NAN; rec.len()];
            };
            rec.iter()
                .map(|s| match p.process(s) {
                    Processed::Stepped(st) if st.stuck.is_none() => st.output.force_n,
                    Processed::Stepped(_) | Processed::Dropped(_) => f64::NAN,
                })
                .collect()
        })
        .collect()
}

/// RMS of measured − predicted over the samples where `use_sample` holds and both are
/// finite, and how many there were.
pub fn rms_residual(
    records: &[Vec<SensorSample>],
    predicted: &[Vec<f64>],
    use_sample: impl Fn(usize, usize) -> bool,
) -> (f64, usize) {
    let mut sse = 0.0;
    let mut n = 0usize;
    for (r, (rec, pred)) in records.iter().zip(predicted).enumerate() {
        for (j, (s, f)) in rec.iter().zip(pred).enumerate() {
            let e = s.force_n - f;
            if use_sample(r, j) && e.is_finite() {
                sse += e * e;
                n += 1;
            }
        }
    }
    ((sse / n.max(1) as f64).sqrt(), n)
}

/// Parameter transform: θ = start·e^z for positive parameters, θ = start + scale·z else.
#[derive(Debug, Clone, Copy)]
struct Transform {
    start: f64,
    scale: f64,
    log: bool,
}

impl Transform {
    fn new(key: ParamKey, start: f64, floor: f64) -> Result<Self, FitError> {
        if key.positive() {
            if !(start > 0.0 && start.is_finite()) {
                return Err(FitError::BadStart(key, start));
            }
            return Ok(Self {
                start,
                scale: 1.0,
                log: true,
            });
        }
        Ok(Self {
            start,
            scale: start.abs().max(floor),
            log: false,
        })
    }
    fn value(&self, z: f64) -> f64 {
        if self.log {
            self.start * z.exp()
        } else {
            self.start + self.scale * z
        }
    }
    fn derivative(&self, z: f64) -> f64 {
        if self.log {
            self.value(z)
        } else {
            self.scale
        }
    }
}

/// Forward-difference step in the scaled parameters.
const FD_STEP: f64 = 1e-4;

struct State {
    z: Vec<f64>,
    residual: Vec<f64>,
}

fn scale_floor(key: ParamKey, problem: &FitProblem<'_>) -> f64 {
    // A coefficient that starts at zero moves on the scale of its neighbours.
    let p = &problem.config.params;
    let max_abs = |xs: &[f64]| xs.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let force_scale = || {
        problem
            .records
            .iter()
            .flatten()
            .map(|s| s.force_n.abs())
            .filter(|f| f.is_finite())
            .fold(0.0f64, f64::max)
            .max(1.0)
    };
    match key {
        ParamKey::BinghamFriction(_) => max_abs(&p.bingham.friction_force_n).max(1.0),
        ParamKey::BinghamDamping(_) => max_abs(&p.bingham.damping_n_s_m).max(1.0),
        ParamKey::YieldStress(_) => max_abs(&p.two_chamber.fluid.yield_stress_pa).max(1.0),
        ParamKey::Viscosity(_) => max_abs(&p.two_chamber.fluid.viscosity_pa_s).max(1e-3),
        ParamKey::BinghamOffset
        | ParamKey::LoadCellOffset
        | ParamKey::Spencer(SpencerKey::LoadCellOffset) => 0.01 * force_scale(),
        _ => 1.0,
    }
}

/// Fit the free parameters of `problem` to the masked samples.
pub fn fit(problem: &FitProblem<'_>) -> Result<FitOutcome, FitError> {
    fit_or_unidentified(problem)?.map_err(|u| FitError::NotIdentifiable(u.keys))
}

/// Where a fit stopped whose parameters the records cannot tell apart.
#[derive(Debug, Clone)]
pub struct Unidentified {
    /// The parameters with the largest share of the weakest direction, largest first.
    pub keys: Vec<ParamKey>,
    /// The configuration at the optimum the iterations reached.
    pub optimum: PipelineConfig,
}

/// [`fit`], with the optimum reached when the standard errors cannot be formed (`Ok(Err)`),
/// so that a caller that holds a parameter can start again from there.
pub fn fit_or_unidentified(
    problem: &FitProblem<'_>,
) -> Result<Result<FitOutcome, Unidentified>, FitError> {
    let (objective, r0) = Objective::new(problem)?;
    let usable = objective.usable;
    let start_cost = sum_of_squares(&r0);
    let start = State {
        z: vec![0.0; problem.keys.len()],
        residual: r0,
    };
    let mut last_error = None;
    let opts = LmOptions {
        max_iter: 80,
        rel_tol: 1e-6,
        step_tol: 1e-6,
        ..LmOptions::default()
    };
    let outcome = levenberg_marquardt(
        start,
        start_cost,
        &opts,
        |st: &State| match objective.jacobian(st) {
            Ok(j) => Some(normal_equations(&j, &st.residual)),
            Err(e) => {
                last_error = Some(e);
                None
            }
        },
        |st: &State, step: &DVector<f64>| {
            let z: Vec<f64> = st.z.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
            let r = objective.residual(&z)?;
            let cost = sum_of_squares(&r);
            Some((State { z, residual: r }, cost))
        },
    );
    if let (LmStop::NoLinearization, Some(e)) = (outcome.stop, last_error) {
        return Err(e);
    }
    let st = &outcome.state;
    let j = objective.jacobian(st)?;
    let jtj = j.transpose() * &j;
    let optimum = objective.config_at(&st.z);
    let std_z = match standard_errors(&jtj, &st.residual, &problem.keys) {
        Ok(s) => s,
        Err(keys) => return Ok(Err(Unidentified { keys, optimum })),
    };
    let PipelineConfig {
        params,
        conditioning,
        ..
    } = optimum;
    let fitted = problem
        .keys
        .iter()
        .zip(&objective.transforms)
        .zip(st.z.iter().zip(&std_z))
        .map(|((&key, t), (&z, &se))| FittedParam {
            key,
            start: t.start,
            value: t.value(z),
            std_error: t.derivative(z).abs() * se,
        })
        .collect();
    Ok(Ok(FitOutcome {
        params,
        conditioning,
        fitted,
        start_rmse_n: (start_cost / usable as f64).sqrt(),
        rmse_n: (outcome.cost / usable as f64).sqrt(),
        samples: usable,
        iterations: outcome.iterations,
        stop: outcome.stop,
    }))
}

/// The fit's objective in the transformed coordinates z (each key's [`Transform`], z = 0
/// at the start): the records run through the pipeline at [`Objective::config_at`], one
/// residual per fitting sample that was usable at the start.
struct Objective<'a, 'r> {
    problem: &'a FitProblem<'r>,
    /// The pipeline at the start values, its estimator off.
    base: PipelineConfig,
    transforms: Vec<Transform>,
    /// Which of all the fitting samples' residuals were finite at the start (the others,
    /// dropped by conditioning, are left out at every parameter value).
    valid: Vec<bool>,
    /// How many were.
    usable: usize,
}

impl<'a, 'r> Objective<'a, 'r> {
    /// The objective of `problem`, and its residuals at the start. An error when the
    /// base configuration does not build or too few samples (≤ 2 per parameter) are usable.
    fn new(problem: &'a FitProblem<'r>) -> Result<(Self, Vec<f64>), FitError> {
        let base = PipelineConfig {
            estimator: None,
            ..problem.config.clone()
        };
        TwinPipeline::new(base.clone()).map_err(|e| FitError::Effects(e.to_string()))?;
        let transforms = problem
            .keys
            .iter()
            .map(|&k| Transform::new(k, start_value(k, &base), scale_floor(k, problem)))
            .collect::<Result<Vec<_>, _>>()?;
        let np = problem.keys.len();
        let mut objective = Objective {
            problem,
            base,
            transforms,
            valid: Vec::new(),
            usable: 0,
        };
        let r0 = objective.all_residuals(&vec![0.0; np]);
        let usable = r0.iter().filter(|e| e.is_finite()).count();
        if usable <= 2 * np {
            return Err(FitError::TooFewSamples {
                samples: usable,
                parameters: np,
            });
        }
        objective.valid = r0.iter().map(|e| e.is_finite()).collect();
        objective.usable = usable;
        let r0 = objective
            .usable_only(r0)
            .expect("finite at the start by construction");
        Ok((objective, r0))
    }

    /// The configuration at `z`.
    fn config_at(&self, z: &[f64]) -> PipelineConfig {
        let mut cfg = self.base.clone();
        for ((k, t), zi) in self.problem.keys.iter().zip(&self.transforms).zip(z) {
            k.set(&mut cfg, t.value(*zi));
        }
        cfg
    }

    /// Measured minus predicted force on every fitting sample with a finite measurement:
    /// NaN where the sample was dropped (the same samples at every parameter value: they
    /// are left out) or the model failed.
    fn all_residuals(&self, z: &[f64]) -> Vec<f64> {
        let problem = self.problem;
        let pred = predict(&self.config_at(z), problem.records);
        let mut r = Vec::new();
        for ((rec, pr), m) in problem.records.iter().zip(&pred).zip(&problem.mask) {
            for ((s, f), use_it) in rec.iter().zip(pr).zip(m) {
                if *use_it && s.force_n.is_finite() {
                    r.push(s.force_n - f);
                }
            }
        }
        r
    }

    /// The residuals of the usable samples; `None` when one of them is not finite (the
    /// model failed there).
    fn usable_only(&self, r: Vec<f64>) -> Option<Vec<f64>> {
        let mut out = Vec::with_capacity(self.usable);
        for (e, ok) in r.into_iter().zip(&self.valid) {
            if *ok {
                if !e.is_finite() {
                    return None;
                }
                out.push(e);
            }
        }
        Some(out)
    }

    /// The residuals at `z` (`None` where the model fails).
    fn residual(&self, z: &[f64]) -> Option<Vec<f64>> {
        self.usable_only(self.all_residuals(z))
    }

    /// Forward-difference Jacobian of the residuals in z at `st`, one column per
    /// parameter, the columns in parallel.
    fn jacobian(&self, st: &State) -> Result<DMatrix<f64>, FitError> {
        let np = self.problem.keys.len();
        let threads = std::thread::available_parallelism().map_or(1, |c| c.get());
        let cols: Vec<Result<Vec<f64>, FitError>> = map_indexed(np, threads, |q| {
            let mut z = st.z.clone();
            z[q] += FD_STEP;
            let r = self
                .residual(&z)
                .ok_or(FitError::NonFinite(self.problem.keys[q]))?;
            Ok(r.iter()
                .zip(&st.residual)
                .map(|(a, b)| (a - b) / FD_STEP)
                .collect())
        });
        let mut j = DMatrix::zeros(self.usable, np);
        for (q, c) in cols.into_iter().enumerate() {
            let c = c?;
            for (i, v) in c.into_iter().enumerate() {
                j[(i, q)] = v;
            }
        }
        Ok(j)
    }
}

/// Largest condition number of the correlation form of JᵀJ the fit accepts.
const MAX_CONDITION: f64 = 1e12;

/// JᵀJ in correlation form: its diagonal's square roots d and Dᵀ⁻¹ JᵀJ D⁻¹. Err: the
/// parameters the records do not move at all (zero or NaN diagonal).
fn correlation_form(
    jtj: &DMatrix<f64>,
    keys: &[ParamKey],
) -> Result<(Vec<f64>, DMatrix<f64>), Vec<ParamKey>> {
    let np = keys.len();
    let dead: Vec<ParamKey> = (0..np)
        .filter(|&i| jtj[(i, i)].is_nan() || jtj[(i, i)] <= 0.0)
        .map(|i| keys[i])
        .collect();
    if !dead.is_empty() {
        return Err(dead);
    }
    let d: Vec<f64> = (0..np).map(|i| jtj[(i, i)].sqrt()).collect();
    let corr = DMatrix::from_fn(np, np, |i, j| jtj[(i, j)] / (d[i] * d[j]));
    Ok((d, corr))
}

/// Standard errors of the scaled parameters: σ² (JᵀJ)⁻¹ with σ² the residual variance,
/// inflated for the residual's lag-1 autocorrelation. Err: the parameters the records
/// cannot tell apart, when JᵀJ is too close to singular ([`weakest`]).
fn standard_errors(
    jtj: &DMatrix<f64>,
    r: &[f64],
    keys: &[ParamKey],
) -> Result<Vec<f64>, Vec<ParamKey>> {
    let np = keys.len();
    let (d, corr) = correlation_form(jtj, keys)?;
    let eig = corr.clone().symmetric_eigen();
    let (lo, hi) = eig
        .eigenvalues
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(l, h), e| (l.min(*e), h.max(*e)));
    if lo.is_nan() || lo <= 0.0 || hi / lo > MAX_CONDITION {
        return Err(weakest(&eig, keys));
    }
    let inv = corr.try_inverse().ok_or_else(|| weakest(&eig, keys))?;
    let n = r.len();
    let sigma2 = sum_of_squares(r) / (n - np).max(1) as f64;
    let inflation = numerics::stats::ar1_variance_inflation(numerics::stats::autocorr(r, 1));
    Ok((0..np)
        .map(|i| (sigma2 * inflation * inv[(i, i)]).sqrt() / d[i])
        .collect())
}

/// The parameters with the largest share of the weakest direction of JᵀJ (in
/// correlation form, eigen-decomposed as `eig`), the largest share first.
fn weakest(eig: &nalgebra::SymmetricEigen<f64, nalgebra::Dyn>, keys: &[ParamKey]) -> Vec<ParamKey> {
    let imin = eig
        .eigenvalues
        .iter()
        .enumerate()
        .fold(
            (0, f64::INFINITY),
            |(bi, bv), (i, v)| if *v < bv { (i, *v) } else { (bi, bv) },
        )
        .0;
    let mut share: Vec<(ParamKey, f64)> = keys
        .iter()
        .zip(eig.eigenvectors.column(imin).iter())
        .filter(|(_, c)| c.abs() > 0.3)
        .map(|(k, c)| (*k, c.abs()))
        .collect();
    share.sort_by(|a, b| b.1.total_cmp(&a.1));
    let out: Vec<ParamKey> = share.into_iter().map(|(k, _)| k).collect();
    if out.is_empty() {
        keys.to_vec()
    } else {
        out
    }
}

/// Number of distinct current levels in the records: currents rounded to 1 % of the
/// largest |I| (at least 5 mA), counting a level only when it holds 1 % of the samples.
pub fn current_levels(records: &[Vec<SensorSample>]) -> usize {
    let currents: Vec<f64> = records
        .iter()
        .flatten()
        .map(|s| s.current_a)
        .filter(|i| i.is_finite())
        .collect();
    let peak = currents.iter().fold(0.0f64, |m, i| m.max(i.abs()));
    let step = (0.01 * peak).max(0.005);
    let mut counts = std::collections::BTreeMap::<i64, usize>::new();
    for i in &currents {
        *counts.entry((i.abs() / step).round() as i64).or_default() += 1;
    }
    let min = (currents.len() / 100).max(1);
    counts.values().filter(|c| **c >= min).count()
}

/// Held-out mask: `blocks` contiguous time blocks per record, the odd ones held out
/// (true = fitted).
pub fn alternate_blocks(records: &[Vec<SensorSample>], blocks: usize) -> Vec<Vec<bool>> {
    records
        .iter()
        .map(|rec| {
            let n = rec.len().max(1);
            (0..rec.len()).map(|j| (j * blocks / n) % 2 == 0).collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use twin::models::{BinghamParams, TwoChamberParams};

    fn bingham_record(p: &BinghamParams, noise: f64) -> Vec<SensorSample> {
        simulated_record(
            &PipelineConfig {
                model: ModelKind::Bingham,
                params: ModelParams {
                    bingham: p.clone(),
                    ..ModelParams::default()
                },
                effects: EffectSet::NONE,
                estimator: None,
                ..PipelineConfig::default()
            },
            noise,
        )
    }

    /// 3 s at 1 kHz of a 10 mm, 2 Hz sinusoid, 1 s each at 0.2, 0.8 and 1.5 A, through
    /// `cfg`'s model, with a deterministic noise of standard deviation `noise` on the force.
    fn simulated_record(cfg: &PipelineConfig, noise: f64) -> Vec<SensorSample> {
        let mut rng = 12345u64;
        let mut gauss = || {
            // Sum of uniforms: a deterministic, roughly normal noise of unit variance.
            let mut s = 0.0;
            for _ in 0..12 {
                rng = rng
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                s += (rng >> 11) as f64 / (1u64 << 53) as f64;
            }
            s - 6.0
        };
        let mut model = twin::models::build(cfg.model, &cfg.params, cfg.effects).unwrap();
        (0..3000)
            .map(|j| {
                let t = j as f64 * 1e-3;
                let w = 2.0 * std::f64::consts::PI * 2.0;
                let current_a = [0.2, 0.8, 1.5][j / 1000];
                let input = twin::DamperInput {
                    displacement_m: 0.01 * (w * t).sin(),
                    velocity_m_s: 0.01 * w * (w * t).cos(),
                    acceleration_m_s2: 0.0,
                    current_a,
                    ambient_temperature_c: 25.0,
                };
                let f = model.step(&input, if j == 0 { 0.0 } else { 1e-3 }).force_n;
                SensorSample {
                    time_s: t,
                    displacement_m: input.displacement_m,
                    velocity_m_s: input.velocity_m_s,
                    force_n: f + noise * gauss(),
                    current_a,
                    temperature_c: f64::NAN,
                }
            })
            .collect()
    }

    #[test]
    fn a_bingham_twin_is_recovered_within_its_intervals_from_another_start() {
        let truth = BinghamParams {
            friction_force_n: [40.0, 900.0, -120.0],
            damping_n_s_m: [300.0, 1200.0, -150.0],
            offset_n: -35.0,
        };
        let recs = vec![bingham_record(&truth, 10.0)];
        let levels = current_levels(&recs);
        assert_eq!(levels, 3);
        let cfg = PipelineConfig {
            model: ModelKind::Bingham,
            effects: EffectSet::NONE,
            ..PipelineConfig::default()
        };
        let (keys, _) = free_parameters(&cfg, levels).unwrap();
        let truth = PipelineConfig {
            params: ModelParams {
                bingham: truth,
                ..ModelParams::default()
            },
            ..PipelineConfig::default()
        };
        let out = fit_every_sample(cfg, keys, &recs);
        assert!(out.start_rmse_n > 5.0 * out.rmse_n);
        assert_recovered_within_4_se(&out, &truth);
    }

    /// [`fit`] on every sample of `recs` from `start`.
    fn fit_every_sample(
        start: PipelineConfig,
        keys: Vec<ParamKey>,
        recs: &[Vec<SensorSample>],
    ) -> FitOutcome {
        let problem = FitProblem {
            config: start,
            mask: recs.iter().map(|r| vec![true; r.len()]).collect(),
            keys,
            records: recs,
        };
        let out = fit(&problem).unwrap();
        // The records' force noise is 10 N.
        assert!(out.rmse_n < 11.0 && out.rmse_n > 9.0, "{}", out.rmse_n);
        out
    }

    /// Every fitted parameter within 4 standard errors of its value in `truth`.
    fn assert_recovered_within_4_se(out: &FitOutcome, truth: &PipelineConfig) {
        for p in &out.fitted {
            let z = (p.value - p.key.get(truth)) / p.std_error;
            assert!(
                z.abs() < 4.0,
                "{}: {} vs {} ± {}",
                p.key,
                p.value,
                p.key.get(truth),
                p.std_error
            );
        }
    }

    #[test]
    fn a_spencer_twin_is_recovered_within_its_intervals_from_another_start() {
        let truth = PipelineConfig {
            model: ModelKind::Spencer,
            effects: EffectSet::NONE,
            estimator: None,
            params: ModelParams {
                spencer: SpencerParams {
                    load_cell_offset_n: 25.0,
                    ..SpencerParams::default()
                },
                ..ModelParams::default()
            },
            ..PipelineConfig::default()
        };
        let recs = vec![simulated_record(&truth, 10.0)];
        let (keys, notes) = free_parameters(&truth, current_levels(&recs)).unwrap();
        assert_eq!(keys.len(), 12, "{keys:?}");
        assert!(notes.iter().any(|n| n.contains("x0")), "{notes:?}");
        // Every fitted parameter starts 10–40 % off (Spencer et al.'s Table 1 is the truth;
        // the offset 10–40 N).
        let mut start = truth.clone();
        for (i, k) in keys.iter().enumerate() {
            let v = k.get(&truth);
            let off = 0.1 * (1 + i % 4) as f64 * v.max(100.0);
            k.set(&mut start, v + if i % 2 == 0 { off } else { -off });
        }
        let out = fit_every_sample(start, keys, &recs);
        assert!(out.start_rmse_n > 3.0 * out.rmse_n, "{}", out.start_rmse_n);
        assert_recovered_within_4_se(&out, &truth);
        // Effects are refused by name: the Bouc–Wen law takes none.
        let with_effect = PipelineConfig {
            effects: EffectSet::NONE.with(Effect::FieldLag),
            ..truth
        };
        assert!(matches!(
            free_parameters(&with_effect, 3),
            Err(FitError::Effects(e)) if e.contains("spencer") && e.contains("field_lag")
        ));
    }

    #[test]
    fn two_parameters_the_record_cannot_tell_apart_are_refused_by_name() {
        // One current level, yet three coefficients asked for: |I| and I² are one column.
        let truth = BinghamParams::default();
        let recs: Vec<Vec<SensorSample>> = vec![bingham_record(&truth, 5.0)
            .into_iter()
            .map(|mut s| {
                s.current_a = 0.8;
                s
            })
            .collect()];
        let cfg = PipelineConfig {
            model: ModelKind::Bingham,
            effects: EffectSet::NONE,
            ..PipelineConfig::default()
        };
        let (keys, _) = free_parameters(&cfg, 3).unwrap();
        let problem = FitProblem {
            config: cfg,
            mask: vec![vec![true; recs[0].len()]],
            keys,
            records: &recs,
        };
        match fit(&problem) {
            Err(FitError::NotIdentifiable(k)) => assert!(
                !k.is_empty()
                    && k.iter().all(|k| matches!(
                        k,
                        ParamKey::BinghamFriction(1 | 2) | ParamKey::BinghamDamping(1 | 2)
                    )),
                "{k:?}"
            ),
            other => panic!("expected a refusal, got {:?}", other.map(|o| o.fitted)),
        }
    }

    #[test]
    fn the_gas_preload_is_held_and_named_with_the_load_cell_offset() {
        let cfg = PipelineConfig {
            model: ModelKind::TwoChamber,
            params: ModelParams {
                two_chamber: TwoChamberParams::default(),
                ..ModelParams::default()
            },
            effects: EffectSet::NONE.with(Effect::GasSpring),
            ..PipelineConfig::default()
        };
        let (keys, notes) = free_parameters(&cfg, 5).unwrap();
        assert!(keys.contains(&ParamKey::GasVolume) && keys.contains(&ParamKey::LoadCellOffset));
        assert!(notes.iter().any(|n| n.contains("p0 keeps its base value")));
        assert!(!keys.contains(&ParamKey::DriverLag));
        let direct_shear = PipelineConfig {
            model: ModelKind::DirectShear,
            effects: EffectSet::NONE,
            ..cfg
        };
        assert!(matches!(
            free_parameters(&direct_shear, 3),
            Err(FitError::UnsupportedModel(ModelKind::DirectShear))
        ));
    }
}
