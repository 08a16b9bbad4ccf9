//! Health checks of the twin, computed sample by sample over a sliding window.
//!
//! Every check has OK/WARN/ERROR thresholds in [`HealthConfig`] (parameter-file section
//! `health`); a check with no data yet is STALE. The checks (docs/estimation.md):
//!
//! * **prediction residual**: RMS of F − F̂ over the window divided by the range of the
//!   measured force in the window.
//! * **innovation consistency**: mean normalised innovation squared (NIS)
//!   (F − F̂)²/σ_F² over the window, σ_F the force sensor's noise; under a consistent model
//!   it is ≈ 1 (χ²_N/N, standard deviation √(2/N)).
//! * **yield stress**: the estimate τ0 at the present current against the commissioned
//!   reference curve τ0_ref(I); relative change, not judged while the estimate's relative
//!   standard deviation exceeds `tau0_max_relative_std`.
//! * **gas preload**: the estimated preload against the commissioned one (relative loss).
//! * **thermal**: mean dissipated power over the window and the fluid temperature rise,
//!   the larger of the recorded one (fluid − ambient) and a lumped estimate
//!   C dΔT/dt = P − G ΔT driven by the dissipated power.
//! * **sample rate**: the rate measured from the timestamps against the nominal one, and
//!   dropouts (gaps longer than `dropout_factor` nominal intervals).
//! * **data quality**: the fraction of samples the estimator rejected in the window.

use serde::{Deserialize, Serialize};

use crate::online::Tau0Estimate;

/// Severity of a check, as in ROS `diagnostic_msgs/DiagnosticStatus`.
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Level {
    /// Within the OK threshold.
    Ok = 0,
    /// Beyond the WARN threshold.
    Warn = 1,
    /// Beyond the ERROR threshold.
    Error = 2,
    /// No data.
    Stale = 3,
}

impl Level {
    /// `OK`, `WARN`, `ERROR`, `STALE`.
    pub fn name(self) -> &'static str {
        match self {
            Level::Ok => "OK",
            Level::Warn => "WARN",
            Level::Error => "ERROR",
            Level::Stale => "STALE",
        }
    }
}

/// A pair of thresholds: WARN at `warn` and beyond, ERROR at `error` and beyond.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HealthThresholds {
    /// WARN threshold.
    pub warn: f64,
    /// ERROR threshold.
    pub error: f64,
}

impl HealthThresholds {
    const fn new(warn: f64, error: f64) -> Self {
        Self { warn, error }
    }

    /// The level of a value (larger is worse); NaN is OK (no evidence).
    pub fn level(&self, value: f64) -> Level {
        if value >= self.error {
            Level::Error
        } else if value >= self.warn {
            Level::Warn
        } else {
            Level::Ok
        }
    }
}

/// Thresholds and windows of the health checks (parameter-file section `health`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HealthConfig {
    /// Length of the sliding window of every windowed check \[s\]. Default 2 s.
    pub window_s: f64,
    /// Prediction residual RMS / force range in the window. Default WARN 0.05, ERROR 0.15.
    pub residual: HealthThresholds,
    /// Force sensor noise σ_F used by the innovation test \[N\]. Default 10 N.
    pub force_noise_std_n: f64,
    /// Mean NIS over the window. Default WARN 4, ERROR 25 (a consistent model gives ≈ 1).
    pub nis: HealthThresholds,
    /// Commissioned reference τ0(I): (current A, τ0 Pa) pairs, ascending current. Default
    /// empty (the yield-stress check then reports OK with "no reference").
    pub tau0_reference: Vec<(f64, f64)>,
    /// Relative change |τ0 − τ0_ref|/τ0_ref. Default WARN 0.10, ERROR 0.30.
    pub tau0_change: HealthThresholds,
    /// The change is not judged while the estimate's relative standard deviation σ/τ0 is
    /// above this (an estimate the data do not pin down yet). Default 0.5.
    pub tau0_max_relative_std: f64,
    /// References below this are not compared (near 0 A) \[Pa\]. Default 1 kPa.
    pub tau0_min_reference_pa: f64,
    /// Commissioned gas preload \[Pa\]; none: the check does not apply. Default none.
    pub gas_preload_reference_pa: Option<f64>,
    /// Relative loss of gas preload (p_ref − p)/p_ref. Default WARN 0.15, ERROR 0.40.
    pub gas_preload_loss: HealthThresholds,
    /// Lumped heat capacity of fluid and body for the temperature estimate \[J/K\]. Default 300.
    pub heat_capacity_j_per_k: f64,
    /// Heat loss conductance to ambient \[W/K\]. Default 1.5.
    pub heat_loss_w_per_k: f64,
    /// Fluid temperature rise above ambient \[K\]. Default WARN 30 K, ERROR 60 K.
    pub temperature_rise_k: HealthThresholds,
    /// Nominal sample rate \[Hz\]; none: taken from the median interval of the first
    /// 100 samples. Default none.
    pub nominal_rate_hz: Option<f64>,
    /// Relative shortfall of the rate, 1 − rate/nominal. Default WARN 0.10, ERROR 0.50.
    pub rate_shortfall: HealthThresholds,
    /// A gap longer than this many nominal intervals is a dropout. Default 2.5.
    pub dropout_factor: f64,
    /// Dropouts in the window. Default WARN 1, ERROR 10.
    pub dropouts: HealthThresholds,
    /// Fraction of samples rejected in the window. Default WARN 1e-9 (any), ERROR 0.05.
    pub rejected_fraction: HealthThresholds,
}

impl Default for HealthConfig {
    fn default() -> Self {
        Self {
            window_s: 2.0,
            residual: HealthThresholds::new(0.05, 0.15),
            force_noise_std_n: 10.0,
            nis: HealthThresholds::new(4.0, 25.0),
            tau0_reference: Vec::new(),
            tau0_change: HealthThresholds::new(0.10, 0.30),
            tau0_max_relative_std: 0.5,
            tau0_min_reference_pa: 1000.0,
            gas_preload_reference_pa: None,
            gas_preload_loss: HealthThresholds::new(0.15, 0.40),
            heat_capacity_j_per_k: 300.0,
            heat_loss_w_per_k: 1.5,
            temperature_rise_k: HealthThresholds::new(30.0, 60.0),
            nominal_rate_hz: None,
            rate_shortfall: HealthThresholds::new(0.10, 0.50),
            dropout_factor: 2.5,
            dropouts: HealthThresholds::new(1.0, 10.0),
            rejected_fraction: HealthThresholds::new(1e-9, 0.05),
        }
    }
}

/// One processed sample as the health monitor sees it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Observation {
    /// Time \[s\].
    pub time_s: f64,
    /// Measured force \[N\].
    pub force_n: f64,
    /// Force the twin predicted \[N\].
    pub predicted_force_n: f64,
    /// Coil current \[A\].
    pub current_a: f64,
    /// Dissipated power from the twin \[W\].
    pub dissipated_power_w: f64,
    /// Fluid temperature from the twin (or a sensor) \[°C\].
    pub fluid_temperature_c: f64,
    /// Ambient temperature \[°C\].
    pub ambient_temperature_c: f64,
    /// The yield-stress estimate at the present current, if any.
    pub estimate: Option<Tau0Estimate>,
    /// The estimator rejected this sample (or a channel is stuck): its residual is left out.
    pub rejected: bool,
    /// A channel stuck at one value (its CSV column name), as the conditioning found.
    pub stuck_channel: Option<&'static str>,
    /// Estimated gas preload \[Pa\], where the model has a gas spring.
    pub gas_preload_pa: Option<f64>,
}

/// The state of one check.
#[derive(Debug, Clone, PartialEq)]
pub struct Check {
    /// Name, e.g. "prediction residual" ([`CheckId::name`]).
    pub name: String,
    /// Level.
    pub level: Level,
    /// One line for people.
    pub message: String,
    /// Key–value pairs (numbers formatted).
    pub values: Vec<(String, String)>,
}

/// The health checks, in the order [`HealthMonitor::checks`] reports them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CheckId {
    /// RMS of F − F̂ relative to the force range.
    PredictionResidual,
    /// Mean normalised innovation squared.
    InnovationConsistency,
    /// τ0 against the commissioned reference.
    YieldStress,
    /// Gas preload against the commissioned one.
    GasPreload,
    /// Dissipated power and temperature rise.
    Thermal,
    /// Sample rate and dropouts.
    SampleRate,
    /// Samples the estimator rejected.
    DataQuality,
}

impl CheckId {
    /// Every check, in report order.
    pub const ALL: [CheckId; 7] = [
        CheckId::PredictionResidual,
        CheckId::InnovationConsistency,
        CheckId::YieldStress,
        CheckId::GasPreload,
        CheckId::Thermal,
        CheckId::SampleRate,
        CheckId::DataQuality,
    ];

    /// The name reported in [`Check::name`], e.g. "prediction residual".
    pub fn name(self) -> &'static str {
        match self {
            CheckId::PredictionResidual => "prediction residual",
            CheckId::InnovationConsistency => "innovation consistency",
            CheckId::YieldStress => "yield stress",
            CheckId::GasPreload => "gas preload",
            CheckId::Thermal => "thermal",
            CheckId::SampleRate => "sample rate",
            CheckId::DataQuality => "data quality",
        }
    }
}

impl std::fmt::Display for CheckId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Sums over one block of the sliding window.
#[derive(Debug, Clone, Copy)]
struct Block {
    start_s: f64,
    n: u64,
    /// Finite residual samples.
    n_res: u64,
    sum_r2: f64,
    f_min: f64,
    f_max: f64,
    sum_power: f64,
    rejected: u64,
    /// Of them, with a stuck channel.
    stuck: u64,
    dropouts: u64,
    /// First and last timestamp of the block.
    t_first: f64,
    t_last: f64,
}

impl Block {
    fn new(start_s: f64) -> Self {
        Self {
            start_s,
            n: 0,
            n_res: 0,
            sum_r2: 0.0,
            f_min: f64::INFINITY,
            f_max: f64::NEG_INFINITY,
            sum_power: 0.0,
            rejected: 0,
            stuck: 0,
            dropouts: 0,
            t_first: f64::NAN,
            t_last: f64::NAN,
        }
    }

    /// RMS of the finite residuals; NaN without any.
    fn residual_rms(&self) -> f64 {
        if self.n_res > 0 {
            (self.sum_r2 / self.n_res as f64).sqrt()
        } else {
            f64::NAN
        }
    }
}

/// Blocks per window: the window slides in steps of window/BLOCKS.
const BLOCKS: usize = 10;

/// Health monitor: feed [`Observation`]s, read [`Check`]s.
#[derive(Debug, Clone)]
pub struct HealthMonitor {
    cfg: HealthConfig,
    blocks: std::collections::VecDeque<Block>,
    last_time_s: Option<f64>,
    first_intervals: Vec<f64>,
    nominal_interval_s: Option<f64>,
    temperature_rise_k: f64,
    recorded_rise_k: f64,
    /// The last channel found stuck.
    stuck_channel: Option<&'static str>,
    last: Option<Observation>,
    tau0_smoothed: Option<Tau0Estimate>,
    gas_preload_pa: Option<f64>,
    samples: u64,
}

impl HealthMonitor {
    /// A monitor with these thresholds.
    pub fn new(cfg: HealthConfig) -> Self {
        let nominal_interval_s = cfg.nominal_rate_hz.filter(|r| *r > 0.0).map(|r| 1.0 / r);
        Self {
            cfg,
            blocks: std::collections::VecDeque::with_capacity(BLOCKS + 1),
            last_time_s: None,
            first_intervals: Vec::new(),
            nominal_interval_s,
            temperature_rise_k: 0.0,
            recorded_rise_k: 0.0,
            last: None,
            tau0_smoothed: None,
            gas_preload_pa: None,
            stuck_channel: None,
            samples: 0,
        }
    }

    /// The thresholds.
    pub fn config(&self) -> &HealthConfig {
        &self.cfg
    }

    fn block_len(&self) -> f64 {
        self.cfg.window_s / BLOCKS as f64
    }

    /// One processed sample.
    pub fn observe(&mut self, o: &Observation) {
        self.samples += 1;
        let t = o.time_s;
        let time_ok = t.is_finite();
        // Intervals and dropouts.
        let mut dropout = false;
        let mut dt = 0.0;
        if let (true, Some(t0)) = (time_ok, self.last_time_s) {
            dt = t - t0;
            if self.nominal_interval_s.is_none() && dt > 0.0 {
                self.first_intervals.push(dt);
                if self.first_intervals.len() >= 100 {
                    let mut v = std::mem::take(&mut self.first_intervals);
                    v.sort_by(f64::total_cmp);
                    self.nominal_interval_s = Some(v[v.len() / 2]);
                }
            }
            if let Some(nom) = self.nominal_interval_s {
                dropout = dt > self.cfg.dropout_factor * nom || dt <= 0.0;
            } else {
                dropout = dt <= 0.0;
            }
        }
        if time_ok && self.last_time_s.is_none_or(|t0| t > t0) {
            self.last_time_s = Some(t);
        }
        // Window blocks (only a finite time can place the sample).
        let now = self.last_time_s.unwrap_or(0.0);
        let bl = self.block_len();
        if self.blocks.back().is_none_or(|b| now >= b.start_s + bl) {
            let start = self
                .blocks
                .back()
                .map_or(now, |b| b.start_s + bl * ((now - b.start_s) / bl).floor());
            self.blocks.push_back(Block::new(start));
            while self.blocks.len() > BLOCKS
                || self
                    .blocks
                    .front()
                    .is_some_and(|b| b.start_s + self.cfg.window_s + bl <= now)
            {
                self.blocks.pop_front();
            }
        }
        let b = self.blocks.back_mut().expect("a block was just pushed");
        b.n += 1;
        if b.t_first.is_nan() && time_ok {
            b.t_first = t;
        }
        if time_ok {
            b.t_last = t;
        }
        b.rejected += u64::from(o.rejected);
        b.stuck += u64::from(o.stuck_channel.is_some());
        if o.stuck_channel.is_some() {
            self.stuck_channel = o.stuck_channel;
        }
        b.dropouts += u64::from(dropout);
        let r = o.force_n - o.predicted_force_n;
        if r.is_finite() && !o.rejected {
            b.n_res += 1;
            b.sum_r2 += r * r;
            b.f_min = b.f_min.min(o.force_n);
            b.f_max = b.f_max.max(o.force_n);
        }
        if o.dissipated_power_w.is_finite() {
            b.sum_power += o.dissipated_power_w;
        }
        // Lumped temperature rise, integrated exactly over the step for constant power.
        let p = o.dissipated_power_w;
        if p.is_finite() && dt > 0.0 && dt.is_finite() {
            let g = self.cfg.heat_loss_w_per_k.max(1e-12);
            let c = self.cfg.heat_capacity_j_per_k.max(1e-12);
            let target = p.max(0.0) / g;
            let decay = (-dt * g / c).exp();
            self.temperature_rise_k = target + (self.temperature_rise_k - target) * decay;
        }
        let rec = o.fluid_temperature_c - o.ambient_temperature_c;
        if rec.is_finite() {
            self.recorded_rise_k = rec;
        }
        if let Some(e) = o.estimate {
            if e.tau0_pa.is_finite() && e.tau0_std_pa.is_finite() {
                self.tau0_smoothed = Some(e);
            }
        }
        if let Some(g) = o.gas_preload_pa.filter(|g| g.is_finite()) {
            // Smoothed over about one window of samples.
            let n = (self.cfg.window_s / self.nominal_interval_s.unwrap_or(1e-3)).max(1.0);
            self.gas_preload_pa = Some(match self.gas_preload_pa {
                Some(prev) => prev + (g - prev) / n,
                None => g,
            });
        }
        self.last = Some(*o);
    }

    fn totals(&self) -> Block {
        let mut t = Block::new(self.blocks.front().map_or(0.0, |b| b.start_s));
        for b in &self.blocks {
            t.n += b.n;
            t.n_res += b.n_res;
            t.sum_r2 += b.sum_r2;
            t.f_min = t.f_min.min(b.f_min);
            t.f_max = t.f_max.max(b.f_max);
            t.sum_power += b.sum_power;
            t.rejected += b.rejected;
            t.stuck += b.stuck;
            t.dropouts += b.dropouts;
            if t.t_first.is_nan() {
                t.t_first = b.t_first;
            }
            if !b.t_last.is_nan() {
                t.t_last = b.t_last;
            }
        }
        t
    }

    /// τ0_ref at a current, interpolated linearly (held at the ends).
    pub fn reference_tau0(&self, current_a: f64) -> Option<f64> {
        let r = &self.cfg.tau0_reference;
        let i = current_a.abs();
        let first = r.first()?;
        let last = r.last()?;
        if i <= first.0 {
            return Some(first.1);
        }
        if i >= last.0 {
            return Some(last.1);
        }
        let k = r.partition_point(|p| p.0 <= i);
        let (a, b) = (r[k - 1], r[k]);
        Some(a.1 + (i - a.0) / (b.0 - a.0) * (b.1 - a.1))
    }

    /// The current state of every check, in the order of [`CheckId::ALL`].
    pub fn checks(&self) -> Vec<Check> {
        let Some(f) = self.findings() else {
            return CheckId::ALL.into_iter().map(stale).collect();
        };
        let cfg = &self.cfg;
        vec![
            report(f.residual.as_ref(), cfg),
            report(f.innovation.as_ref(), cfg),
            report(Some(&f.yield_stress), cfg),
            report(Some(&f.gas_preload), cfg),
            report(Some(&f.thermal), cfg),
            report(Some(&f.sample_rate), cfg),
            report(Some(&f.data_quality), cfg),
        ]
    }

    /// The worst level of the checks: the level of [`HealthMonitor::checks`] without
    /// formatting any message (no allocation; cheap enough to ask after every sample).
    pub fn level(&self) -> Level {
        let Some(f) = self.findings() else {
            return Level::Stale;
        };
        let cfg = &self.cfg;
        [
            level_of(f.residual.as_ref(), cfg),
            level_of(f.innovation.as_ref(), cfg),
            f.yield_stress.level(cfg),
            f.gas_preload.level(cfg),
            f.thermal.level(cfg),
            f.sample_rate.level(cfg),
            f.data_quality.level(cfg),
        ]
        .into_iter()
        .fold(Level::Ok, Level::max)
    }

    /// What every check finds now; none before the first observation.
    fn findings(&self) -> Option<Findings> {
        let last = self.last?;
        let w = self.totals();
        Some(Findings {
            residual: self.residual(&w),
            innovation: self.innovation(&w),
            yield_stress: self.yield_stress(&last),
            gas_preload: self.gas_preload(),
            thermal: self.thermal(&w),
            sample_rate: self.sample_rate(&w),
            data_quality: self.data_quality(&w),
        })
    }

    /// Prediction residual over the window; none (STALE) without a finite ratio.
    fn residual(&self, w: &Block) -> Option<Residual> {
        let rms_n = w.residual_rms();
        let range_n = w.f_max - w.f_min;
        let normalised = rms_n / range_n;
        normalised.is_finite().then_some(Residual {
            rms_n,
            range_n,
            normalised,
        })
    }

    /// Mean NIS over the window; none (STALE) while it is not finite.
    fn innovation(&self, w: &Block) -> Option<Innovation> {
        let rms = w.residual_rms();
        let sigma_n = self.cfg.force_noise_std_n;
        let mean_nis = rms * rms / (sigma_n * sigma_n);
        mean_nis.is_finite().then_some(Innovation {
            mean_nis,
            samples: w.n_res,
            sigma_n,
        })
    }

    /// The smoothed τ0 estimate against the reference at its current.
    fn yield_stress(&self, last: &Observation) -> YieldStress {
        let (Some(e), Some(_)) = (self.tau0_smoothed, last.estimate) else {
            return YieldStress::NoEstimate {
                current_a: last.current_a,
            };
        };
        match self.reference_tau0(e.current_a) {
            Some(r) if r >= self.cfg.tau0_min_reference_pa => YieldStress::Compared {
                estimate: e,
                reference_pa: r,
                change: (e.tau0_pa - r) / r,
                judged: e.tau0_std_pa <= self.cfg.tau0_max_relative_std * e.tau0_pa.abs(),
            },
            _ => YieldStress::Unreferenced(e),
        }
    }

    /// The smoothed gas preload against the commissioned one.
    fn gas_preload(&self) -> GasPreload {
        match (self.gas_preload_pa, self.cfg.gas_preload_reference_pa) {
            (Some(p), Some(r)) if r > 0.0 => GasPreload::Compared {
                preload_pa: p,
                reference_pa: r,
                loss: (r - p) / r,
            },
            (Some(p), _) => GasPreload::Unreferenced { preload_pa: p },
            (None, _) => GasPreload::NoEstimate,
        }
    }

    /// Dissipated power over the window and the temperature rise.
    fn thermal(&self, w: &Block) -> Thermal {
        Thermal {
            mean_power_w: if w.n > 0 {
                w.sum_power / w.n as f64
            } else {
                0.0
            },
            rise_k: self.temperature_rise_k.max(self.recorded_rise_k),
            estimated_rise_k: self.temperature_rise_k,
            recorded_rise_k: self.recorded_rise_k,
        }
    }

    /// The rate over the window against the nominal one, and the dropouts.
    fn sample_rate(&self, w: &Block) -> SampleRate {
        let span = w.t_last - w.t_first;
        let rate_hz = if span > 0.0 && w.n > 1 {
            (w.n - 1) as f64 / span
        } else {
            f64::NAN
        };
        match self.nominal_interval_s {
            Some(nom) if rate_hz.is_finite() => SampleRate::Measured {
                rate_hz,
                nominal_hz: 1.0 / nom,
                dropouts: w.dropouts,
            },
            _ => SampleRate::Learning {
                samples: self.samples,
                dropouts: w.dropouts,
            },
        }
    }

    /// Rejected samples in the window.
    fn data_quality(&self, w: &Block) -> DataQuality {
        DataQuality {
            rejected: w.rejected,
            stuck: w.stuck,
            stuck_channel: self.stuck_channel,
            samples: w.n,
            fraction: if w.n > 0 {
                w.rejected as f64 / w.n as f64
            } else {
                0.0
            },
        }
    }
}

/// What every check found after the last observation, in numbers.
struct Findings {
    residual: Option<Residual>,
    innovation: Option<Innovation>,
    yield_stress: YieldStress,
    gas_preload: GasPreload,
    thermal: Thermal,
    sample_rate: SampleRate,
    data_quality: DataQuality,
}

/// What one check found, in numbers: enough to judge its level without formatting
/// anything, and to write its message and key–values when a [`Check`] is asked for.
trait Finding {
    /// The check.
    const ID: CheckId;
    /// The level under the thresholds of `cfg`.
    fn level(&self, cfg: &HealthConfig) -> Level;
    /// One line for people.
    fn message(&self, cfg: &HealthConfig) -> String;
    /// Key–value pairs (numbers formatted).
    fn values(&self, cfg: &HealthConfig) -> Vec<(String, String)>;
}

/// The level of a finding; none (no data) is STALE.
fn level_of<F: Finding>(f: Option<&F>, cfg: &HealthConfig) -> Level {
    f.map_or(Level::Stale, |f| f.level(cfg))
}

/// The [`Check`] of a finding; none (no data) is STALE.
fn report<F: Finding>(f: Option<&F>, cfg: &HealthConfig) -> Check {
    match f {
        Some(f) => Check {
            name: F::ID.name().to_string(),
            level: f.level(cfg),
            message: f.message(cfg),
            values: f.values(cfg),
        },
        None => stale(F::ID),
    }
}

/// A check without data.
fn stale(id: CheckId) -> Check {
    Check {
        name: id.name().to_string(),
        level: Level::Stale,
        message: "no data yet".to_string(),
        values: Vec::new(),
    }
}

/// "; σ widened for model error …" when the model-error part of σ is at least the
/// statistical part, else "".
fn widened(e: &Tau0Estimate) -> String {
    let stat2 = e.tau0_std_pa.powi(2) - e.model_std_pa.powi(2);
    if e.model_std_pa > 0.0 && e.model_std_pa.powi(2) >= stat2 {
        format!(
            "; σ widened for model error (structure left in the residual, the yield \
             force's spread between near-yield laws, and a current-independent friction \
             the fit reads as yield, up to the curve's zero-current intercept): ±{:.1} kPa \
             of it",
            e.model_std_pa / 1e3
        )
    } else {
        String::new()
    }
}

fn kv(k: &str, v: String) -> (String, String) {
    (k.to_string(), v)
}

/// Prediction residual: RMS of F − F̂ against the range of F in the window.
struct Residual {
    rms_n: f64,
    range_n: f64,
    normalised: f64,
}

impl Finding for Residual {
    const ID: CheckId = CheckId::PredictionResidual;

    fn level(&self, cfg: &HealthConfig) -> Level {
        cfg.residual.level(self.normalised)
    }

    fn message(&self, _: &HealthConfig) -> String {
        format!(
            "residual RMS {:.1} N is {:.1} % of the force range {:.0} N",
            self.rms_n,
            100.0 * self.normalised,
            self.range_n
        )
    }

    fn values(&self, cfg: &HealthConfig) -> Vec<(String, String)> {
        vec![
            kv("rms_n", format!("{:.3}", self.rms_n)),
            kv("force_range_n", format!("{:.3}", self.range_n)),
            kv("normalised", format!("{:.5}", self.normalised)),
            kv("warn", format!("{}", cfg.residual.warn)),
            kv("error", format!("{}", cfg.residual.error)),
        ]
    }
}

/// Innovation consistency: mean NIS (F − F̂)²/σ_F² over the window.
struct Innovation {
    mean_nis: f64,
    samples: u64,
    sigma_n: f64,
}

impl Finding for Innovation {
    const ID: CheckId = CheckId::InnovationConsistency;

    fn level(&self, cfg: &HealthConfig) -> Level {
        cfg.nis.level(self.mean_nis)
    }

    fn message(&self, _: &HealthConfig) -> String {
        format!(
            "mean normalised innovation squared {:.2} over {} samples (≈ 1 if consistent, σ_F = {} N)",
            self.mean_nis, self.samples, self.sigma_n
        )
    }

    fn values(&self, _: &HealthConfig) -> Vec<(String, String)> {
        vec![
            kv("mean_nis", format!("{:.4}", self.mean_nis)),
            kv("samples", self.samples.to_string()),
            kv("force_noise_std_n", format!("{}", self.sigma_n)),
        ]
    }
}

/// Yield stress: the τ0 estimate against the commissioned reference.
enum YieldStress {
    /// No estimate at the present current.
    NoEstimate { current_a: f64 },
    /// An estimate with no usable reference at its current.
    Unreferenced(Tau0Estimate),
    /// An estimate and its reference; `judged`: precise enough to be judged.
    Compared {
        estimate: Tau0Estimate,
        reference_pa: f64,
        change: f64,
        judged: bool,
    },
}

impl Finding for YieldStress {
    const ID: CheckId = CheckId::YieldStress;

    fn level(&self, cfg: &HealthConfig) -> Level {
        match *self {
            YieldStress::Compared {
                change,
                judged: true,
                ..
            } => cfg.tau0_change.level(change.abs()),
            _ => Level::Ok,
        }
    }

    fn message(&self, _: &HealthConfig) -> String {
        match *self {
            YieldStress::NoEstimate { .. } => {
                "no estimate at the present current yet (not yet excited both ways, or not identified: σ too large)".into()
            }
            YieldStress::Unreferenced(e) => format!(
                "τ0 {:.1} ± {:.1} kPa at {:.2} A (no reference to compare with){}",
                e.tau0_pa / 1e3,
                e.tau0_std_pa / 1e3,
                e.current_a,
                widened(&e)
            ),
            YieldStress::Compared {
                estimate: e,
                reference_pa: r,
                change,
                ..
            } => format!(
                "τ0 {:.1} ± {:.1} kPa at {:.2} A, {:+.1} % from the reference {:.1} kPa{}",
                e.tau0_pa / 1e3,
                e.tau0_std_pa / 1e3,
                e.current_a,
                100.0 * change,
                r / 1e3,
                widened(&e)
            ),
        }
    }

    fn values(&self, _: &HealthConfig) -> Vec<(String, String)> {
        let estimate = |e: &Tau0Estimate| {
            vec![
                kv("current_a", format!("{:.4}", e.current_a)),
                kv("tau0_pa", format!("{:.1}", e.tau0_pa)),
                kv("tau0_std_pa", format!("{:.1}", e.tau0_std_pa)),
                kv("tau0_model_std_pa", format!("{:.1}", e.model_std_pa)),
            ]
        };
        match self {
            YieldStress::NoEstimate { current_a } => {
                vec![kv("current_a", format!("{current_a:.3}"))]
            }
            YieldStress::Unreferenced(e) => estimate(e),
            YieldStress::Compared {
                estimate: e,
                reference_pa: r,
                change,
                ..
            } => {
                let mut v = estimate(e);
                v.push(kv("tau0_reference_pa", format!("{r:.1}")));
                v.push(kv("relative_change", format!("{change:.5}")));
                v
            }
        }
    }
}

/// Gas preload: the estimate against the commissioned one.
enum GasPreload {
    /// No estimate (a model without a gas spring).
    NoEstimate,
    /// An estimate, no reference.
    Unreferenced { preload_pa: f64 },
    /// An estimate and its relative loss from the reference.
    Compared {
        preload_pa: f64,
        reference_pa: f64,
        loss: f64,
    },
}

impl Finding for GasPreload {
    const ID: CheckId = CheckId::GasPreload;

    fn level(&self, cfg: &HealthConfig) -> Level {
        match *self {
            GasPreload::Compared { loss, .. } => cfg.gas_preload_loss.level(loss),
            _ => Level::Ok,
        }
    }

    fn message(&self, _: &HealthConfig) -> String {
        match *self {
            GasPreload::NoEstimate => "no gas preload estimate (model without a gas spring)".into(),
            GasPreload::Unreferenced { preload_pa } => {
                format!("gas preload {:.2} MPa (no reference)", preload_pa / 1e6)
            }
            GasPreload::Compared {
                preload_pa,
                reference_pa,
                loss,
            } => format!(
                "gas preload {:.2} MPa, {:.1} % below the commissioned {:.2} MPa",
                preload_pa / 1e6,
                100.0 * loss,
                reference_pa / 1e6
            ),
        }
    }

    fn values(&self, _: &HealthConfig) -> Vec<(String, String)> {
        match *self {
            GasPreload::NoEstimate => Vec::new(),
            GasPreload::Unreferenced { preload_pa } => {
                vec![kv("gas_preload_pa", format!("{preload_pa:.0}"))]
            }
            GasPreload::Compared {
                preload_pa,
                reference_pa,
                loss,
            } => vec![
                kv("gas_preload_pa", format!("{preload_pa:.0}")),
                kv("reference_pa", format!("{reference_pa:.0}")),
                kv("relative_loss", format!("{loss:.5}")),
            ],
        }
    }
}

/// Thermal: mean dissipated power and the fluid temperature rise.
struct Thermal {
    mean_power_w: f64,
    /// The larger of the two below.
    rise_k: f64,
    estimated_rise_k: f64,
    recorded_rise_k: f64,
}

impl Finding for Thermal {
    const ID: CheckId = CheckId::Thermal;

    fn level(&self, cfg: &HealthConfig) -> Level {
        cfg.temperature_rise_k.level(self.rise_k)
    }

    fn message(&self, _: &HealthConfig) -> String {
        format!(
            "mean dissipated power {:.1} W; fluid temperature rise {:.1} K (lumped estimate {:.1} K, model/sensor {:.1} K)",
            self.mean_power_w, self.rise_k, self.estimated_rise_k, self.recorded_rise_k
        )
    }

    fn values(&self, _: &HealthConfig) -> Vec<(String, String)> {
        vec![
            kv("mean_power_w", format!("{:.3}", self.mean_power_w)),
            kv("temperature_rise_k", format!("{:.3}", self.rise_k)),
            kv("estimated_rise_k", format!("{:.3}", self.estimated_rise_k)),
            kv("recorded_rise_k", format!("{:.3}", self.recorded_rise_k)),
        ]
    }
}

/// Sample rate: the measured rate against the nominal one, and dropouts.
enum SampleRate {
    /// The nominal rate is not known yet (or no rate over the window).
    Learning { samples: u64, dropouts: u64 },
    /// Rate and nominal rate.
    Measured {
        rate_hz: f64,
        nominal_hz: f64,
        dropouts: u64,
    },
}

impl Finding for SampleRate {
    const ID: CheckId = CheckId::SampleRate;

    fn level(&self, cfg: &HealthConfig) -> Level {
        match *self {
            SampleRate::Learning { .. } => Level::Ok,
            SampleRate::Measured {
                rate_hz,
                nominal_hz,
                dropouts,
            } => cfg
                .rate_shortfall
                .level(1.0 - rate_hz / nominal_hz)
                .max(cfg.dropouts.level(dropouts as f64)),
        }
    }

    fn message(&self, cfg: &HealthConfig) -> String {
        match *self {
            SampleRate::Learning { samples, .. } => {
                format!("learning the nominal rate ({samples} samples)")
            }
            SampleRate::Measured {
                rate_hz,
                nominal_hz,
                dropouts,
            } => format!(
                "{:.1} Hz (nominal {:.1} Hz), {} dropout(s) in the last {} s",
                rate_hz, nominal_hz, dropouts, cfg.window_s
            ),
        }
    }

    fn values(&self, _: &HealthConfig) -> Vec<(String, String)> {
        match *self {
            SampleRate::Learning { dropouts, .. } => vec![kv("dropouts", dropouts.to_string())],
            SampleRate::Measured {
                rate_hz,
                nominal_hz,
                dropouts,
            } => vec![
                kv("rate_hz", format!("{rate_hz:.3}")),
                kv("nominal_rate_hz", format!("{nominal_hz:.3}")),
                kv("dropouts", dropouts.to_string()),
            ],
        }
    }
}

/// Data quality: samples the estimator rejected in the window, and of them those with a
/// stuck channel.
struct DataQuality {
    rejected: u64,
    stuck: u64,
    stuck_channel: Option<&'static str>,
    samples: u64,
    fraction: f64,
}

impl Finding for DataQuality {
    const ID: CheckId = CheckId::DataQuality;

    fn level(&self, cfg: &HealthConfig) -> Level {
        cfg.rejected_fraction.level(self.fraction)
    }

    fn message(&self, cfg: &HealthConfig) -> String {
        let mut m = format!(
            "{} of {} samples rejected in the last {} s",
            self.rejected, self.samples, cfg.window_s
        );
        if let (true, Some(channel)) = (self.stuck > 0, self.stuck_channel) {
            m.push_str(&format!(
                " ({} with {channel} stuck at one value: clipped or dead sensor)",
                self.stuck
            ));
        }
        m
    }

    fn values(&self, _: &HealthConfig) -> Vec<(String, String)> {
        vec![
            kv("rejected", self.rejected.to_string()),
            kv("stuck", self.stuck.to_string()),
            kv("samples", self.samples.to_string()),
            kv("rejected_fraction", format!("{:.6}", self.fraction)),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thresholds_order_levels() {
        let t = HealthThresholds::new(1.0, 2.0);
        assert_eq!(t.level(0.5), Level::Ok);
        assert_eq!(t.level(1.0), Level::Warn);
        assert_eq!(t.level(3.0), Level::Error);
        assert_eq!(t.level(f64::NAN), Level::Ok);
        assert!(Level::Stale > Level::Error);
    }

    #[test]
    fn no_data_is_stale() {
        let m = HealthMonitor::new(HealthConfig::default());
        assert_eq!(m.level(), Level::Stale);
        assert_eq!(m.checks().len(), 7);
    }

    /// The `yield stress` check says when σ was widened for model error (issue 13), with
    /// how much, and only then.
    #[test]
    fn the_yield_check_says_when_sigma_was_widened_for_model_error() {
        let check = |model_std_pa: f64| {
            let mut m = HealthMonitor::new(HealthConfig::default());
            m.observe(&Observation {
                time_s: 0.0,
                current_a: 1.0,
                estimate: Some(Tau0Estimate {
                    current_a: 1.0,
                    tau0_pa: 20e3,
                    tau0_std_pa: 3000.0,
                    model_std_pa,
                }),
                ..Default::default()
            });
            m.checks()
                .into_iter()
                .find(|c| c.name == CheckId::YieldStress.to_string())
                .expect("a yield stress check")
        };
        let widened = check(2900.0);
        assert!(
            widened.message.contains("σ widened for model error")
                && widened.message.contains("±2.9 kPa"),
            "{}",
            widened.message
        );
        assert!(widened
            .values
            .contains(&("tau0_model_std_pa".to_string(), "2900.0".to_string())));
        // A model-error part smaller than the statistical one is not announced.
        let statistical = check(1000.0);
        assert!(
            !statistical.message.contains("widened"),
            "{}",
            statistical.message
        );
    }

    #[test]
    fn checks_come_in_the_order_of_their_ids() {
        let mut m = HealthMonitor::new(HealthConfig::default());
        let names = |m: &HealthMonitor| m.checks().into_iter().map(|c| c.name).collect::<Vec<_>>();
        let ids: Vec<String> = CheckId::ALL.iter().map(|id| id.to_string()).collect();
        assert_eq!(names(&m), ids);
        m.observe(&Observation {
            time_s: 0.0,
            ..Default::default()
        });
        assert_eq!(names(&m), ids);
    }

    #[test]
    fn level_is_the_worst_check_level() {
        let mut m = HealthMonitor::new(HealthConfig {
            tau0_reference: vec![(0.0, 10e3), (1.0, 20e3)],
            gas_preload_reference_pa: Some(2e6),
            nominal_rate_hz: Some(1000.0),
            ..Default::default()
        });
        let mut seen = std::collections::BTreeSet::new();
        for k in 0..5000u32 {
            let x = f64::from(k);
            let drift = if k > 2500 { 0.5 * x } else { 0.0 };
            m.observe(&Observation {
                time_s: x * if k % 500 == 0 { 3e-3 } else { 1e-3 },
                force_n: 1000.0 * (x * 0.01).sin() + drift,
                predicted_force_n: 1000.0 * (x * 0.01).sin(),
                current_a: 0.5,
                dissipated_power_w: 20.0 * x.sqrt(),
                fluid_temperature_c: 25.0,
                ambient_temperature_c: 25.0,
                estimate: (k % 3 != 0).then_some(Tau0Estimate {
                    current_a: 0.5,
                    tau0_pa: 15e3 - x,
                    tau0_std_pa: 500.0,
                    model_std_pa: 0.0,
                }),
                rejected: k > 3000 && k % 101 == 0,
                stuck_channel: (k > 3000 && k % 202 == 0).then_some("force_N"),
                gas_preload_pa: (k > 1000).then_some(2e6 - 100.0 * x),
            });
            let worst = m.checks().iter().map(|c| c.level).max().unwrap();
            assert_eq!(m.level(), worst, "sample {k}: {:?}", m.checks());
            seen.insert(worst);
        }
        assert!(
            seen.contains(&Level::Ok) && seen.contains(&Level::Error),
            "{seen:?}"
        );
    }

    #[test]
    fn reference_is_interpolated() {
        let m = HealthMonitor::new(HealthConfig {
            tau0_reference: vec![(0.5, 10e3), (1.0, 20e3)],
            ..Default::default()
        });
        assert_eq!(m.reference_tau0(0.75), Some(15e3));
        assert_eq!(m.reference_tau0(2.0), Some(20e3));
    }
}
