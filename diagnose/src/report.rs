//! The diagnosis as data: what the JSON output and the Markdown report hold.

use std::collections::BTreeMap;

use serde::Serialize;

/// A model's fit quality.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ModelSummary {
    /// Readable model name.
    pub model: String,
    /// RMS residual on the fitting part \[N\].
    #[serde(rename = "train_rmse_N")]
    pub train_rmse_n: f64,
    /// RMS residual on the held-out part \[N\].
    #[serde(rename = "holdout_rmse_N")]
    pub holdout_rmse_n: f64,
    /// Held-out RMS with every sample counted alike \[N\].
    #[serde(rename = "holdout_rmse_unweighted_N")]
    pub holdout_rmse_unweighted_n: f64,
    /// Number of parameters.
    pub parameters: usize,
}

/// A region where the residual concentrates.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Mismatch {
    /// Region name.
    pub region: String,
    /// Fraction of the residual energy Σ r² that falls in the region.
    pub share_of_residual_energy: f64,
    /// Fraction of the samples in the region.
    pub share_of_samples: f64,
    /// Mean square of the ±10 ms moving-average residual in the region, less the white-noise
    /// part, over that of the whole record (systematic structure).
    pub structure_ratio: f64,
    /// Readable description.
    pub description: String,
}

/// A current knot whose yield force or viscous coefficient the record does not pin down:
/// at the record's peak speed V its `c V`, or its `F_y`, exceeds
/// [`UnidentifiedKnot::LIMIT`] times the record's peak force, so it cancels against other
/// terms (curvature, compliance, leak) where the knot has data, and a current between it
/// and its neighbour is predicted from interpolated values that mean nothing.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct UnidentifiedKnot {
    /// The knot's current \[A\].
    pub current_a: f64,
    /// Its fitted yield force \[N\].
    pub yield_force_n: f64,
    /// Its fitted viscous coefficient \[N s/m\].
    pub viscous_n_s_m: f64,
    /// What ran away, in words.
    pub why: String,
}

impl UnidentifiedKnot {
    /// How many times the record's peak force a knot's `c V` or `F_y` may reach.
    pub const LIMIT: f64 = crate::model::UNIDENTIFIED_KNOT_LIMIT;
}

/// A current knot whose fitting strokes stay slow: their 95th percentile of |v̂| is below
/// [`SlowKnot::REACH`] of the speed the record asks of the knot (the same percentile over
/// its fitting and held-out samples; at least [`SlowKnot::ASKED`] of the record's peak
/// speed), so the knot's speed curvature c₂ (the force law's bend at speed) is not fitted
/// there but held at its neighbours' ([`crate::model::hold_unreached_curvature`]); forces
/// at that current and higher speeds are predicted with the neighbours' shape.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SlowKnot {
    /// The knot's current \[A\].
    pub current_a: f64,
    /// The speed its fitting samples reach (95th percentile of |v̂|) \[m/s\].
    pub reach_m_s: f64,
    /// The speed the record asks of it (95th percentile of |v̂| over its fitting and
    /// held-out samples) \[m/s\].
    pub asked_m_s: f64,
    /// The speed curvature it was given \[N\] (`c₂ v|v|/V`, V the record's peak speed).
    pub curvature_n: f64,
}

impl SlowKnot {
    /// Share of the speed the record asks of a knot that its fitting samples must reach.
    pub const REACH: f64 = crate::model::CURVATURE_REACH;
    /// Share of the record's peak speed the record must ask of the knot.
    pub const ASKED: f64 = crate::model::CURVATURE_ASKED;
}

/// A fitted parameter with its 95 % interval.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Parameter {
    /// Value in `unit`.
    pub value: f64,
    /// 95 % interval: ±1.96 of the fit's standard error (inflated for autocorrelated
    /// residuals) and the model-error spread between the record's halves, combined in
    /// quadrature ([`Parameter::halves_spread`]).
    pub ci95: [f64; 2],
    /// The fit's own 95 % interval, ±1.96 standard errors, without the model-error spread.
    pub ci95_fit: [f64; 2],
    /// The spread of the value between the record's halves beyond what their standard
    /// errors explain, s_m = √(max(0, ((a − b)² − se_a² − se_b²)/2)) with a the value fitted
    /// on the fitting blocks and b on the held-out blocks (in `unit`; 0 where they agree
    /// within their errors, and where the held-out refit failed). A model that is wrong
    /// in a way that changes over the record gives the halves different values.
    pub halves_spread: f64,
    /// Unit.
    pub unit: String,
    /// The parameter this one is held equal to, when the model ties them (a thermal
    /// softening's viscous terms soften with the yield force until
    /// `select::free_thermal_apart` frees them): its value and interval are that one's,
    /// not a measurement of its own.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tied_to: Option<String>,
}

/// Evidence for a candidate.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Evidence {
    /// Held-out RMS before adding the effect \[N\].
    #[serde(rename = "holdout_rmse_before_N")]
    pub holdout_rmse_before_n: f64,
    /// Held-out RMS after \[N\].
    #[serde(rename = "holdout_rmse_after_N")]
    pub holdout_rmse_after_n: f64,
    /// The typical held-out block's RMS before adding the effect \[N\]: the root of the
    /// geometric mean of the blocks' mean squares, each block one vote whatever its misfit.
    #[serde(rename = "holdout_typical_block_rmse_before_N")]
    pub holdout_typical_block_rmse_before_n: f64,
    /// The same after \[N\].
    #[serde(rename = "holdout_typical_block_rmse_after_N")]
    pub holdout_typical_block_rmse_after_n: f64,
    /// The largest ratio of a held-out block's mean square after to before: how much worse
    /// the candidate makes the block it hurts most (below 1: it helps every block).
    pub holdout_worst_block_ms_ratio: f64,
    /// Where the candidate predicts the held-out blocks worse: the block it hurts most and
    /// the current knot where that block's added error gathers (absent when it hurts none).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub holdout_harm: Option<HeldOutHarm>,
    /// Change of the information criterion with the effective sample size (negative: better).
    pub delta_bic: f64,
    /// Effective sample size used in the criterion and the intervals.
    pub effective_samples: f64,
    /// Paired z statistic of the per-stroke held-out improvement.
    pub holdout_z: f64,
    /// Relative fall of the residual structure in the best flagged region.
    pub structure_drop: f64,
    /// That region.
    pub structure_region: String,
    /// The calibrated evidence (the `calibrated` selector).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibration: Option<crate::calibrate::CalibratedEvidence>,
}

/// An accepted effect.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Finding {
    /// Effect id (PHYSICS.md).
    pub effect: String,
    /// What it means physically, with the numbers.
    pub explanation: String,
    /// Fitted parameters of the effect in the final model.
    pub parameters: BTreeMap<String, Parameter>,
    /// Why it was accepted.
    pub evidence: Evidence,
    /// Held-out RMS per held-out validation block, before and after the effect.
    pub block_gains: Vec<BlockGain>,
}

/// The held-out error of one held-out validation block, before and after.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct BlockGain {
    /// Start of the block \[s\].
    pub start_s: f64,
    /// End of the block \[s\].
    pub end_s: f64,
    /// Held-out samples in it.
    pub samples: usize,
    /// RMS before \[N\].
    #[serde(rename = "rmse_before_N")]
    pub rmse_before_n: f64,
    /// RMS after \[N\].
    #[serde(rename = "rmse_after_N")]
    pub rmse_after_n: f64,
}

/// The held-out block a candidate predicts worst against the model without it, and where
/// in it the added error gathers: at one current knot, the knot's fitting samples few or
/// slower than the held-out ones, the candidate has moved that knot's fluid law where the
/// fitting blocks do not hold it (docs/diagnose.md, "Held-out harm").
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct HeldOutHarm {
    /// The block: its span, held-out samples, and RMS without the candidate and with it.
    #[serde(flatten)]
    pub block: BlockGain,
    /// The current knot (nearest to the samples) that holds most of the block's added
    /// squared error \[A\].
    pub knot_a: f64,
    /// That knot's share of the added squared error (summed over the block's samples whose
    /// error grew).
    pub knot_share: f64,
    /// The fastest of those samples at the knot \[m/s\].
    pub peak_speed_m_s: f64,
    /// Fitting samples at the knot (anywhere in the record).
    pub fitting_samples_at_knot: usize,
    /// The fastest of them \[m/s\].
    pub fitting_peak_speed_m_s: f64,
}

/// Structure the final model leaves in the residual beyond noise.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Unexplained {
    /// What the residual was grouped by.
    pub grouping: String,
    /// Where the structure concentrates (the groups with the largest mean residual).
    pub concentrates_in: Vec<String>,
    /// RMS of the systematic part (group means) \[N\].
    #[serde(rename = "systematic_rms_N")]
    pub systematic_rms_n: f64,
    /// Its share of the residual's mean square.
    pub share_of_residual: f64,
    /// Test statistic: χ² of the group means with the effective sample size.
    pub chi2: f64,
    /// Its 99 % critical value.
    pub chi2_crit99: f64,
    /// Signals the residual correlates with beyond the autocorrelated band.
    pub correlates_with: Vec<String>,
}

/// Which of the fluid's coefficients a step at reversal follows ([`FluidShape`]).
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ShapeFollows {
    /// The yield force F_y(I): a yield sharper than the baseline's slit law.
    YieldForce,
    /// The viscous coefficient c(I): a steep rise at low speed (shear thinning,
    /// bi-viscous).
    ViscousCoefficient,
}

/// A step at each velocity reversal that follows one of the fluid's coefficients at every
/// current, taken up by the final model as the fluid's own shape (not a finding): the
/// seal-friction candidate's step, which fitted better scaled by the fluid and showed no
/// presliding. `step_N · coefficient(I) / mean_coefficient · tanh(v / tanh_velocity)`.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct FluidShape {
    /// What the step follows.
    pub follows: ShapeFollows,
    /// The step at the mean coefficient \[N\].
    #[serde(rename = "step_N")]
    pub step_n: f64,
    /// The mean of the coefficient over the current knots (F_y \[N\] or c \[N s/m\]).
    pub mean_coefficient: f64,
    /// The step's share of the coefficient, `step_N / mean_coefficient` (\[1\] for the yield
    /// force, \[m/s\] for the viscous coefficient).
    pub share: f64,
    /// The mean yield force over the current knots in the same fit \[N\] (equal to
    /// `mean_coefficient` when the step follows the yield force): where the step follows
    /// the viscous coefficient, `step_N / mean_yield_force_N` is the share of the nearest
    /// yield-scaled step, the one the twin's fluid has.
    #[serde(rename = "mean_yield_force_N")]
    pub mean_yield_force_n: f64,
    /// Velocity scale of the step's tanh \[m/s\].
    pub tanh_velocity_m_s: f64,
    /// Held-out RMS before \[N\].
    #[serde(rename = "holdout_rmse_before_N")]
    pub holdout_rmse_before_n: f64,
    /// Held-out RMS with the step \[N\].
    #[serde(rename = "holdout_rmse_after_N")]
    pub holdout_rmse_after_n: f64,
    /// The same in words (the report's line).
    pub explanation: String,
}

/// Explanations the data cannot tell apart.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Undecided {
    /// The effects.
    pub effects: Vec<String>,
    /// Why no choice was made.
    pub why: String,
}

/// The smallest size of a library effect the final model lacks that this record could
/// have shown under the calibrated selector's rules ([`crate::limits`]): below it the
/// effect may be present and not be found.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct DetectionLimit {
    /// Effect id.
    pub effect: String,
    /// The shape the limit is stated at (a friction's presliding, a constant compliance).
    pub shape: String,
    /// The effect's size parameter.
    pub parameter: String,
    /// Its unit.
    pub unit: String,
    /// The limit in `unit` (`null`: not separable on this record at any size).
    pub limit: Option<f64>,
    /// RMS of the effect's force at the limit \[N\].
    #[serde(rename = "effect_rms_N")]
    pub effect_rms_n: Option<f64>,
    /// Share of the effect's (weighted) force the final model's own parameters take up
    /// when refitted: 1 is an effect the fitted fluid law imitates wholly.
    pub absorbed_share: f64,
    /// The rule that sets the limit (statistic, interval, held-out gain, resolved
    /// deflection), or why there is none.
    pub rule: String,
}

/// One candidate tried in one round of forward selection.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Trial {
    /// Round (1-based).
    pub round: usize,
    /// Effect id.
    pub effect: String,
    /// Evidence.
    pub evidence: Evidence,
    /// Parameters of the effect.
    pub parameters: BTreeMap<String, Parameter>,
    /// Rules passed: held-out, criterion, interval, structure.
    pub passed: [bool; 4],
    /// Accepted in this round.
    pub accepted: bool,
}

/// Residual whiteness.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Whiteness {
    /// Lag-1 autocorrelation.
    pub rho1: f64,
    /// 95 % band of a white residual, ±1.96/√n.
    pub band95: f64,
    /// Ljung–Box Q over 20 lags.
    pub ljung_box_q20: f64,
    /// Its 95 % critical value.
    pub ljung_box_crit95: f64,
}

/// Cross-correlation of the residual with a signal.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CrossCorrelation {
    /// Signal.
    pub signal: String,
    /// Largest |ρ| over lags ±50 samples (residual after the signal for positive lags).
    pub max_abs_rho: f64,
    /// Its lag in samples.
    pub lag_samples: i64,
    /// 95 % band of a white residual, ±1.96/√n.
    pub band95: f64,
    /// The wider band for the residual's own autocorrelation, ±1.96/√n_eff.
    pub band95_autocorrelated: f64,
}

/// Residual statistics of one model.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ResidualStats {
    /// Whiteness.
    pub whiteness: Whiteness,
    /// Cross-correlations.
    pub cross_correlation: Vec<CrossCorrelation>,
}

/// RMS residual by stroke phase.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct PhaseResidual {
    /// Phase or direction.
    pub phase: String,
    /// Baseline RMS \[N\].
    #[serde(rename = "baseline_rms_N")]
    pub baseline_rms_n: f64,
    /// Final-model RMS \[N\].
    #[serde(rename = "final_rms_N")]
    pub final_rms_n: f64,
}

/// The split.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Split {
    /// How.
    pub method: String,
    /// Fitting samples.
    pub train_samples: usize,
    /// Held-out samples.
    pub holdout_samples: usize,
    /// Strokes.
    pub strokes: usize,
    /// Segments.
    pub segments: usize,
    /// Validation blocks (contiguous in time; odd ones held out).
    pub blocks: usize,
    /// Current knots \[A\].
    pub current_knots_a: Vec<f64>,
}

/// The whole diagnosis.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Report {
    /// Input description.
    pub input: String,
    /// Number of samples.
    pub samples: usize,
    /// How candidates were accepted (`calibrated`, `rules`, `sindy`).
    pub selector: String,
    /// How the yield force was interpolated between the knots of a grid (`lines`,
    /// `cubic`; held levels are always joined by lines).
    pub yield_curve: String,
    /// Under `--yield-curve auto` on a grid of knots: the settled baseline's fitting RMS
    /// \[N\] on each curve (`cubic`, `lines`); the lower one's curve is `yield_curve`.
    pub yield_curve_fits: Option<BTreeMap<String, f64>>,
    /// What the measurement model found: noise levels, rebuilt velocity, stuck stretches.
    pub measurement: crate::measure::MeasurementSummary,
    /// The split.
    pub split: Split,
    /// The baseline.
    pub baseline: ModelSummary,
    /// The baseline's measurement parameters (force offset, leak velocity).
    pub baseline_parameters: BTreeMap<String, f64>,
    /// Where the baseline residual concentrates.
    pub mismatch: Vec<Mismatch>,
    /// Baseline residual statistics.
    pub baseline_residual: ResidualStats,
    /// Accepted effects, in the order accepted.
    pub findings: Vec<Finding>,
    /// Explanations the data cannot tell apart.
    pub undecided: Vec<Undecided>,
    /// Effects accepted in their round and withdrawn at the end (their parameter fell back
    /// to its no-effect value once later effects were in).
    pub withdrawn: Vec<String>,
    /// Structure the fluid's own shape took up in the final model (a step near reversal
    /// that follows the yield force): not findings, no effect of the library.
    pub fluid_shape: Vec<FluidShape>,
    /// Structure the final model leaves beyond noise (empty when the residual is noise).
    pub unexplained: Vec<Unexplained>,
    /// The smallest size of each library effect the final model lacks that the record
    /// could have shown (the calibrated selector only; empty for the others).
    pub detection_limits: Vec<DetectionLimit>,
    /// Current knots of the final model that the record does not identify (their force
    /// law ran to values no damper has; [`UnidentifiedKnot`]).
    pub unidentified_knots: Vec<UnidentifiedKnot>,
    /// Current knots whose fitting strokes stay slow, their speed curvature held at their
    /// neighbours' ([`SlowKnot`]).
    pub slow_knots: Vec<SlowKnot>,
    /// Every candidate tried.
    pub trials: Vec<Trial>,
    /// The final model.
    #[serde(rename = "final")]
    pub final_model: ModelSummary,
    /// The final model's measurement parameters.
    pub final_parameters: BTreeMap<String, f64>,
    /// Final residual statistics.
    pub final_residual: ResidualStats,
    /// Held-out RMS per held-out block, baseline → final.
    pub holdout_blocks: Vec<BlockGain>,
    /// RMS residual by stroke phase, before and after.
    pub residual_by_phase: Vec<PhaseResidual>,
    /// The acceptance thresholds used.
    pub thresholds: BTreeMap<String, f64>,
}

fn fmt_params(p: &BTreeMap<String, Parameter>) -> String {
    p.iter()
        .map(|(k, v)| {
            if let Some(t) = &v.tied_to {
                return format!("{k} held equal to {t}");
            }
            let mut s = format!(
                "{k} = {:.4} {} (95 % CI {:.4} … {:.4}",
                v.value, v.unit, v.ci95[0], v.ci95[1]
            );
            if v.halves_spread > 0.0 {
                s += &format!(
                    " with the halves' spread; the fit alone {:.4} … {:.4}",
                    v.ci95_fit[0], v.ci95_fit[1]
                );
            }
            s + ")"
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// The report as Markdown: what was wrong, where, which physics explains it, the fitted
/// parameters with intervals, and how much better the held-out fit is.
pub fn render_markdown(r: &Report) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "# mrtwin diagnose: {}\n", r.input);
    let _ = writeln!(
        s,
        "{} samples, {} strokes, {} segments, current knots {:?} A.\n",
        r.samples, r.split.strokes, r.split.segments, r.split.current_knots_a
    );
    let _ = writeln!(
        s,
        "**Split.** {} ({} fitting, {} held-out samples).\n",
        r.split.method, r.split.train_samples, r.split.holdout_samples
    );
    write_verdict(&mut s, r);
    write_unexplained(&mut s, r);
    write_detection_limits(&mut s, r);
    write_measurement(&mut s, r);
    write_fit(&mut s, r);
    write_residual_statistics(&mut s, r);
    write_trials(&mut s, r);
    s
}

/// The verdict: each finding with its evidence, the undecided groups, what was withdrawn, the
/// fluid's shape and the current knots the record does not identify or fits on slow strokes.
fn write_verdict(s: &mut String, r: &Report) {
    use std::fmt::Write;
    let _ = writeln!(s, "## Verdict\n");
    if r.findings.is_empty() && r.undecided.is_empty() {
        if r.unexplained.is_empty() {
            let _ = writeln!(
                s,
                "No candidate effect is supported, and the final residual shows no structure \
                 beyond noise: nothing in the library is missing above its detection limit on \
                 this record{}.\n",
                if r.detection_limits.is_empty() {
                    ""
                } else {
                    " (see *Detection limits*: smaller effects may be present)"
                }
            );
        } else {
            let _ = writeln!(
                s,
                "No candidate effect in the library is supported, **but the residual is \
                 still structured beyond noise** (see *Unexplained*): something the library \
                 does not hold is missing.\n"
            );
        }
    }
    for f in &r.findings {
        let e = &f.evidence;
        let why = match &e.calibration {
            Some(c) => format!(
                "beats its bootstrap null: statistic {:.1} against {:.1} at α = {:.1e} \
                 ({} replicates)",
                c.statistic, c.threshold, c.alpha, c.replicates
            ),
            None => format!(
                "paired z {:.1} over held-out blocks, ΔBIC {:.1} (n_eff {:.0}), residual \
                 structure in \"{}\" down {:.0} %",
                e.holdout_z,
                e.delta_bic,
                e.effective_samples,
                e.structure_region,
                100.0 * e.structure_drop
            ),
        };
        let better = f
            .block_gains
            .iter()
            .filter(|b| b.rmse_after_n < b.rmse_before_n)
            .count();
        // Accepted on the typical block's gain, the pooled RMS having risen.
        let typical = if e.holdout_rmse_after_n >= e.holdout_rmse_before_n {
            format!(
                "; pooled, the blocks it fits worse outweigh the rest: the typical held-out \
                 block {:.2} → {:.2} N",
                e.holdout_typical_block_rmse_before_n, e.holdout_typical_block_rmse_after_n
            )
        } else {
            String::new()
        };
        let _ = writeln!(
            s,
            "- **{}** — {}. Parameters: {}. Held-out RMS {:.2} → {:.2} N ({:.1} % {}; \
             better in {} of {} held-out blocks{typical}); {}.",
            f.effect,
            f.explanation,
            fmt_params(&f.parameters),
            e.holdout_rmse_before_n,
            e.holdout_rmse_after_n,
            100.0 * (1.0 - e.holdout_rmse_after_n / e.holdout_rmse_before_n).abs(),
            if typical.is_empty() {
                "lower"
            } else {
                "higher"
            },
            better,
            f.block_gains.len(),
            why
        );
    }
    for u in &r.undecided {
        let _ = writeln!(s, "- **undecided: {}** — {}", u.effects.join(" or "), u.why);
    }
    for w in &r.withdrawn {
        let _ = writeln!(s, "- withdrawn: {w}");
    }
    for w in &r.fluid_shape {
        let _ = writeln!(s, "- the fluid's shape (not a finding): {}", w.explanation);
    }
    if !r.unidentified_knots.is_empty() {
        let _ = writeln!(
            s,
            "\n**Current knots this record does not identify** (forces at currents between \
             them and their neighbours are not predicted):\n"
        );
        for k in &r.unidentified_knots {
            let _ = writeln!(s, "- {:.3} A: {}", k.current_a, k.why);
        }
    }
    if !r.slow_knots.is_empty() {
        let _ = writeln!(
            s,
            "\n**Current knots fitted on slow strokes only** (below {:.0} % of the speed the \
             record asks of them; the force law's bend at speed is their neighbours'):\n",
            100.0 * SlowKnot::REACH
        );
        for k in &r.slow_knots {
            let _ = writeln!(
                s,
                "- {:.3} A: fitted to {:.3} m/s, asked {:.3} m/s; speed curvature {:.0} N",
                k.current_a, k.reach_m_s, k.asked_m_s, k.curvature_n
            );
        }
    }
}

/// The structure still left in the final residual, where it concentrates and what it
/// correlates with (nothing when there is none).
fn write_unexplained(s: &mut String, r: &Report) {
    use std::fmt::Write;
    if !r.unexplained.is_empty() {
        let _ = writeln!(s, "\n## Unexplained\n");
        let _ = writeln!(
            s,
            "| grouping | concentrates in | systematic RMS (N) | share of residual | χ² (99 % crit.) | correlates with |"
        );
        let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- |");
        for u in &r.unexplained {
            let _ = writeln!(
                s,
                "| {} | {} | {:.2} | {:.1} % | {:.0} ({:.0}) | {} |",
                u.grouping,
                u.concentrates_in.join("; "),
                u.systematic_rms_n,
                100.0 * u.share_of_residual,
                u.chi2,
                u.chi2_crit99,
                u.correlates_with.join(", ")
            );
        }
    }
}

/// The detection limits: the smallest size of each library effect the final model lacks
/// that this record could have shown ([`crate::limits`]).
fn write_detection_limits(s: &mut String, r: &Report) {
    use std::fmt::Write;
    if r.detection_limits.is_empty() {
        return;
    }
    let _ = writeln!(s, "\n## Detection limits\n");
    let _ = writeln!(
        s,
        "The smallest size of each effect the final model lacks that this record could have \
         shown under the rules above (about where it would be found half the time), from the \
         final model's linearisation; below it an effect may be present and not found. \
         \"Absorbed\" is the share of the effect's force the final model's own parameters \
         imitate when refitted.\n"
    );
    let _ = writeln!(
        s,
        "| effect | shape | limit | its force RMS (N) | absorbed | set by |"
    );
    let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- |");
    for l in &r.detection_limits {
        let limit = l
            .limit
            .map(|v| format!("{} = {v:.3e} {}", l.parameter, l.unit))
            .unwrap_or_else(|| "none".into());
        let rms = l
            .effect_rms_n
            .map(|v| format!("{v:.2}"))
            .unwrap_or_else(|| "–".into());
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.1} % | {} |",
            l.effect,
            l.shape,
            limit,
            rms,
            100.0 * l.absorbed_share,
            l.rule
        );
    }
}

/// The measurement model: the channels' noise, the rebuilt velocity and what was left out.
fn write_measurement(s: &mut String, r: &Report) {
    use std::fmt::Write;
    let m = &r.measurement;
    let _ = writeln!(
        s,
        "\n**Measurement.** Noise: displacement {:.2} µm, velocity {}, force (high-frequency) \
         {:.2} N; rebuilt velocity σ {:.3} mm/s (window ±{} samples, stroke period {:.3} s){}; \
         {} samples at the ends of the record and its segments left out (one-sided \
         velocity).{}\n",
        1e6 * m.displacement_noise_m,
        m.velocity_noise_m_s
            .map(|v| format!("{:.3} mm/s", 1e3 * v))
            .unwrap_or_else(|| "derived from displacement".into()),
        m.force_noise_hf_n,
        1e3 * m.rebuilt_velocity_sigma_m_s,
        m.window_half_samples,
        m.stroke_period_s,
        if m.velocity_error_scale > 1.0 {
            format!(
                "; near reversal the force shows a velocity error {}× that σ, and the \
                 samples are weighted for it",
                m.velocity_error_scale
            )
        } else {
            String::new()
        },
        m.edge_samples,
        if m.flat_stretches.is_empty() {
            String::new()
        } else {
            format!(
                " Left out ({} samples): {}.",
                m.excluded_samples,
                m.flat_stretches
                    .iter()
                    .map(|f| format!(
                        "{} stuck at {} from {:.3} to {:.3} s ({} samples)",
                        f.channel, f.value, f.start_s, f.end_s, f.samples
                    ))
                    .collect::<Vec<_>>()
                    .join("; ")
            )
        }
    );
}

/// Which curve the yield force follows between the knots of a grid, and why, when
/// `--yield-curve auto` settled the baseline on both.
fn write_yield_curve(s: &mut String, r: &Report) {
    use std::fmt::Write;
    let Some(fits) = &r.yield_curve_fits else {
        return;
    };
    fn name(c: &str) -> &str {
        match c {
            "cubic" => "a cubic curve",
            "lines" => "straight lines",
            other => other,
        }
    }
    let others: Vec<String> = fits
        .iter()
        .filter(|(c, _)| **c != r.yield_curve)
        .map(|(c, v)| format!("on {} at {v:.2} N", name(c)))
        .collect();
    let _ = writeln!(
        s,
        "\nThe yield force follows {} between the current knots, on which the settled \
         baseline fits the fitting blocks at {:.2} N; {} (`--yield-curve auto` keeps the \
         lower).",
        name(&r.yield_curve),
        fits.get(&r.yield_curve).copied().unwrap_or(f64::NAN),
        others.join(", ")
    );
}

/// The baseline's and the final model's fit, where the baseline misses and the residual
/// by stroke phase.
fn write_fit(s: &mut String, r: &Report) {
    use std::fmt::Write;
    let _ = writeln!(s, "\n## Fit\n");
    let _ = writeln!(
        s,
        "| model | parameters | fitting RMS (N) | held-out RMS (N) |"
    );
    let _ = writeln!(s, "| --- | --- | --- | --- |");
    for m in [&r.baseline, &r.final_model] {
        let _ = writeln!(
            s,
            "| {} | {} | {:.2} | {:.2} |",
            m.model, m.parameters, m.train_rmse_n, m.holdout_rmse_n
        );
    }
    write_yield_curve(s, r);
    let _ = writeln!(s, "\n## Where the baseline misses\n");
    if r.mismatch.is_empty() {
        let _ = writeln!(s, "No region holds more than its share of the residual.\n");
    } else {
        let _ = writeln!(
            s,
            "| region | share of residual energy | share of samples | structure ratio |"
        );
        let _ = writeln!(s, "| --- | --- | --- | --- |");
        for m in &r.mismatch {
            let _ = writeln!(
                s,
                "| {} | {:.1} % | {:.1} % | {:.2} |",
                m.region,
                100.0 * m.share_of_residual_energy,
                100.0 * m.share_of_samples,
                m.structure_ratio
            );
        }
    }
    let _ = writeln!(s, "\n## Residual by stroke phase\n");
    let _ = writeln!(s, "| phase | baseline RMS (N) | final RMS (N) |");
    let _ = writeln!(s, "| --- | --- | --- |");
    for p in &r.residual_by_phase {
        let _ = writeln!(
            s,
            "| {} | {:.2} | {:.2} |",
            p.phase, p.baseline_rms_n, p.final_rms_n
        );
    }
}

/// The residuals' whiteness and cross-correlations, baseline and final.
fn write_residual_statistics(s: &mut String, r: &Report) {
    use std::fmt::Write;
    let _ = writeln!(s, "\n## Residual statistics\n");
    let _ = writeln!(
        s,
        "| model | lag-1 autocorrelation | Ljung–Box Q(20) (95 % crit.) | velocity | acceleration | displacement | current steps |"
    );
    let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- | --- |");
    for (name, st) in [
        ("baseline", &r.baseline_residual),
        ("final", &r.final_residual),
    ] {
        let cc: Vec<String> = st
            .cross_correlation
            .iter()
            .map(|c| {
                format!(
                    "{:.3} at lag {} (band ±{:.3} white, ±{:.3} autocorr.)",
                    c.max_abs_rho, c.lag_samples, c.band95, c.band95_autocorrelated
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "| {name} | {:.3} (band ±{:.3}) | {:.0} ({:.0}) | {} |",
            st.whiteness.rho1,
            st.whiteness.band95,
            st.whiteness.ljung_box_q20,
            st.whiteness.ljung_box_crit95,
            cc.join(" | ")
        );
    }
}

/// Every candidate tried: the rules, the calibrated threshold and the verdict of each.
fn write_trials(s: &mut String, r: &Report) {
    use std::fmt::Write;
    let _ = writeln!(s, "\n## Every candidate tried\n");
    if r.selector == "calibrated" {
        let _ = writeln!(
            s,
            "Selector **calibrated**: a candidate is accepted when its held-out RMS falls, its \
             parameter is physical with a 95 % interval clear of the no-effect value, and its \
             statistic (the fall of the weighted fitting SSE over the residual variance) beats \
             the (1 − α) quantile of its own null from a wild block bootstrap of the current \
             model, α = {:.1e} per test ({:.0} % family-wise over the library and every round). \
             The four columns below are the first version's rules, shown for comparison.\n",
            r.thresholds.get("alpha_per_test").copied().unwrap_or(0.0),
            100.0 * r.thresholds.get("family_alpha").copied().unwrap_or(0.0)
        );
    }
    let _ = writeln!(
        s,
        "Rules: held-out RMS falls (≥ {:.1} % and paired z ≥ {:.1}); ΔBIC with the effective \
         sample size ≤ {:.0}; the parameter's 95 % CI excludes the no-effect value on the \
         physical side; the residual structure falls ≥ {:.0} % in a flagged region or the \
         region the candidate acts on.\n",
        100.0
            * r.thresholds
                .get("min_holdout_rmse_drop")
                .copied()
                .unwrap_or(0.0),
        r.thresholds
            .get("min_holdout_paired_z")
            .copied()
            .unwrap_or(0.0),
        r.thresholds.get("max_delta_bic").copied().unwrap_or(0.0),
        100.0
            * r.thresholds
                .get("min_structure_drop")
                .copied()
                .unwrap_or(0.0)
    );
    let _ = writeln!(
        s,
        "| round | effect | held-out RMS (N) | z | ΔBIC | structure drop | parameters | rules passed | statistic / calibrated threshold | accepted |"
    );
    let _ = writeln!(
        s,
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    let yn = |b: bool| if b { "yes" } else { "no" };
    for t in &r.trials {
        let e = &t.evidence;
        let _ = writeln!(
            s,
            "| {} | {} | {:.2} → {:.2} | {:.1} | {:.1} | {:.0} % | {} | held-out {}, ΔBIC {}, CI {}, structure {} | {} | {} |",
            t.round,
            t.effect,
            e.holdout_rmse_before_n,
            e.holdout_rmse_after_n,
            e.holdout_z,
            e.delta_bic,
            100.0 * e.structure_drop,
            fmt_params(&t.parameters),
            yn(t.passed[0]),
            yn(t.passed[1]),
            yn(t.passed[2]),
            yn(t.passed[3]),
            e.calibration
                .as_ref()
                .map(|c| if c.replicates > 0 {
                    format!("{:.1} / {:.1}", c.statistic, c.threshold)
                } else {
                    format!("{:.1} / screened out", c.statistic)
                })
                .unwrap_or_else(|| "—".into()),
            yn(t.accepted)
        );
    }
    write_holdout_harm(s, &r.trials);
}

/// Below the trials: each rejected candidate that made a held-out block at least twice as
/// bad in mean square ([`HARM_LISTED`]), where.
fn write_holdout_harm(s: &mut String, trials: &[Trial]) {
    use std::fmt::Write;
    let harmed: Vec<(&Trial, &HeldOutHarm)> = trials
        .iter()
        .filter(|t| !t.accepted)
        .filter_map(|t| t.evidence.holdout_harm.as_ref().map(|h| (t, h)))
        .filter(|(_, h)| {
            let b = &h.block;
            b.rmse_after_n * b.rmse_after_n >= HARM_LISTED * b.rmse_before_n * b.rmse_before_n
        })
        .collect();
    if harmed.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\nHeld-out blocks a rejected candidate predicts at least {HARM_LISTED}× worse in mean square:\n"
    );
    for (t, h) in harmed {
        let _ = writeln!(
            s,
            "- round {}, {}: {:.2}–{:.2} s, {:.1} → {:.1} N; {:.0} % of the added error at {:.3} A, \
             held out up to {:.1} mm/s, fitted there on {} samples up to {:.1} mm/s",
            t.round,
            t.effect,
            h.block.start_s,
            h.block.end_s,
            h.block.rmse_before_n,
            h.block.rmse_after_n,
            100.0 * h.knot_share,
            h.knot_a,
            1e3 * h.peak_speed_m_s,
            h.fitting_samples_at_knot,
            1e3 * h.fitting_peak_speed_m_s
        );
    }
}

/// How much worse in mean square a held-out block must be for the report to list it
/// ([`write_holdout_harm`]).
pub const HARM_LISTED: f64 = 2.0;
