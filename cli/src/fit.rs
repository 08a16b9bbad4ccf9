//! `mrtwin fit RECORDING… --out TWIN.yaml`: calibrate the twin's own model to recordings
//! (`node::fit`) and write it as a parameter file that `node`, `stand`, `replay` and
//! `simulate` read as is.
//!
//! The held-out check: each record is cut into contiguous time blocks; the model is fitted
//! on the even blocks and judged on the odd ones. The parameters written are then refitted
//! on every sample, starting from there.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use launch_config::load_params;
use node::conditioning::{ConditioningConfig, SensorSample};
use node::config::{EstimatorSection, TwinNodeParams, STAND_NODE, TWIN_NODE};
use node::fit::{
    alternate_blocks, current_levels, fit_or_unidentified, free_parameters, predict, rms_residual,
    FitError, FitOutcome, FitProblem, ParamKey, Unidentified,
};
use node::pipeline::PipelineConfig;
use numerics::least_squares::LmStop;
use serde::Serialize;
use serde_json::json;
use twin::models::{
    polynomial_in_current, BinghamParams, FluidLaw, ModelKind, ModelParams, SpencerParams,
    TwoChamberParams,
};
use twin::EffectSet;

/// Arguments of `mrtwin fit`.
#[derive(Debug, Args)]
pub struct FitArgs {
    /// Recordings (CSV in the PHYSICS.md format, rosbag2 directories or .mcap files).
    #[arg(required = true, value_name = "RECORDING")]
    pub recordings: Vec<PathBuf>,
    /// Model to fit: `two-chamber`, `bingham` or `spencer` (default: the one of `--params`, else
    /// two-chamber).
    #[arg(long, value_name = "NAME")]
    pub model: Option<String>,
    /// Effects of the two-chamber model, comma separated ids, `paper`, `all` or `none`
    /// (default: those of `--params`, else none).
    #[arg(long, value_name = "LIST")]
    pub effects: Option<String>,
    /// Twin parameter file to start from (section `mrtwin_twin`): geometry, fluid law and
    /// every parameter the fit holds.
    #[arg(long, value_name = "BASE.yaml")]
    pub params: Option<PathBuf>,
    /// Where to write the fitted twin (sections `mrtwin_twin` and `mrtwin_stand`).
    #[arg(long, value_name = "TWIN.yaml")]
    pub out: PathBuf,
    /// Also write the fit's report as JSON here.
    #[arg(long, value_name = "OUT.json")]
    pub json: Option<PathBuf>,
    /// Contiguous time blocks per record for the held-out check (odd ones held out).
    #[arg(long, value_name = "N", default_value_t = 8)]
    pub blocks: usize,
    /// Parameters to hold at their base values, comma separated keys as the fit prints
    /// them; a key without an index holds every coefficient
    /// (`two_chamber.fluid.yield_stress_pa`).
    #[arg(long, value_name = "KEYS", value_delimiter = ',')]
    pub hold: Vec<String>,
}

/// What the written file holds for each node: the model, its effects and its section.
#[derive(Debug, Clone, Serialize)]
pub struct TwinSection<'a> {
    /// Model.
    pub model: ModelKind,
    /// Effects (ids, or `none`).
    pub effects: String,
    /// `bingham` parameters (model `bingham`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bingham: Option<&'a BinghamParams>,
    /// `spencer` parameters (model `spencer`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spencer: Option<&'a SpencerParams>,
    /// `two_chamber` parameters (model `two-chamber`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub two_chamber: Option<&'a TwoChamberParams>,
    /// The conditioning the fit ran with (e.g. a command-voltage current channel), when it
    /// is not the default; the twin node's section only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub conditioning: Option<&'a ConditioningConfig>,
    /// The estimator settings the base file gave, when they are not the default; the twin
    /// node's section only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimator: Option<EstimatorSection>,
}

impl<'a> TwinSection<'a> {
    /// The section of `model` with `effects` and `params`, and the conditioning and
    /// estimator settings of `base` (the configuration the fit ran with).
    pub fn new(
        model: ModelKind,
        effects: EffectSet,
        params: &'a ModelParams,
        base: &'a PipelineConfig,
    ) -> Self {
        let conditioning = &base.conditioning;
        let estimator = EstimatorSection {
            enabled: base.estimator.is_some(),
            settings: base.estimator.clone().unwrap_or_default(),
        };
        Self {
            model,
            effects: effects.to_string(),
            bingham: (model == ModelKind::Bingham).then_some(&params.bingham),
            spencer: (model == ModelKind::Spencer).then_some(&params.spencer),
            two_chamber: (model == ModelKind::TwoChamber).then_some(&params.two_chamber),
            conditioning: (*conditioning != ConditioningConfig::default()).then_some(conditioning),
            estimator: (estimator != EstimatorSection::default()).then_some(estimator),
        }
    }
}

/// Write the twin file at `out` whole or not at all (written beside it, then renamed).
pub fn write_twin_file(out: &Path, header: &str, section: &TwinSection<'_>) -> Result<()> {
    // The stand simulates the damper itself: it has no sensor conditioning.
    let stand = TwinSection {
        conditioning: None,
        estimator: None,
        ..section.clone()
    };
    let text = launch_config::params_yaml(header, &[(TWIN_NODE, section), (STAND_NODE, &stand)])
        .map_err(|e| anyhow::anyhow!("cannot write the parameters as YAML: {e}"))?;
    crate::output::write_whole(out, text.as_bytes())
}

/// The records as the node sees them, one list per file.
pub fn load_records(paths: &[PathBuf]) -> Result<Vec<Vec<SensorSample>>> {
    paths
        .iter()
        .map(|p| {
            let rec = bridge::open_recording(p).with_context(|| format!("read {}", p.display()))?;
            if rec.is_empty() {
                bail!("{}: no samples", p.display());
            }
            Ok(sensor_samples(&rec))
        })
        .collect()
}

/// A recording's samples as the node sees them.
pub fn sensor_samples(rec: &bridge::csv::Recording) -> Vec<SensorSample> {
    rec.samples
        .iter()
        .map(SensorSample::from_recording)
        .collect()
}

/// Base parameters: the file's, with the model and effects of the flags.
pub fn base_params(
    params: Option<&Path>,
    model: Option<&str>,
    effects: Option<&str>,
) -> Result<TwinNodeParams> {
    let mut p: TwinNodeParams = match params {
        Some(f) => load_params(f, TWIN_NODE)?,
        None => TwinNodeParams {
            effects: twin::EffectsChoice::List(EffectSet::NONE),
            ..TwinNodeParams::default()
        },
    };
    if let Some(m) = model {
        p.model = m.parse().context("--model")?;
    }
    if let Some(e) = effects {
        p.effects = e.parse().context("--effects")?;
    }
    p.validate()?;
    Ok(p)
}

fn stop_text(stop: LmStop) -> &'static str {
    match stop {
        LmStop::Converged => "converged",
        LmStop::NoDescent => "no step lowers the residual further",
        LmStop::NoLinearization => "the model could not be linearised",
        LmStop::MaxIterations => "iteration limit",
    }
}

/// Fit `config`'s free parameters to `records`: the held-out check on alternate blocks,
/// then the refit on all samples. Returns (split fit, held-out RMS at the start, held-out
/// RMS of the split fit, per-block held-out RMS, full fit, notes).
pub struct Calibrated {
    /// Fit on the even blocks.
    pub split: FitOutcome,
    /// Held-out RMS of the start parameters \[N\].
    pub holdout_start_rmse_n: f64,
    /// Held-out RMS of the split fit \[N\].
    pub holdout_rmse_n: f64,
    /// Held-out RMS per held-out block (record, block, RMS).
    pub holdout_blocks: Vec<(usize, usize, f64)>,
    /// Fit on every sample: what is written.
    pub full: FitOutcome,
    /// What the records identify and what was held.
    pub notes: Vec<String>,
}

/// The coefficients that make a law in current more than a quadratic: `[3]` and `[4]` of
/// `yield_stress_pa` and `viscosity_pa_s`.
const BEYOND_QUADRATIC: [ParamKey; 4] = [
    ParamKey::YieldStress(3),
    ParamKey::YieldStress(4),
    ParamKey::Viscosity(3),
    ParamKey::Viscosity(4),
];

/// The first law in current of `fluid` (`yield_stress_pa`, then `viscosity_pa_s`) that
/// falls as the current rises within [0, `peak`] A, by more than 2 % of its largest value
/// there, with the current where it falls; `None` when both rise (or hold).
fn falling_law(fluid: &twin::models::FluidParams, peak: f64) -> Option<(&'static str, f64)> {
    const GRID: usize = 200;
    for (name, c) in [
        ("yield_stress_pa", &fluid.yield_stress_pa),
        ("viscosity_pa_s", &fluid.viscosity_pa_s),
    ] {
        let at = |k: usize| {
            let i = peak * k as f64 / GRID as f64;
            (i, polynomial_in_current(c, i))
        };
        let top = (0..=GRID).map(|k| at(k).1).fold(0.0f64, f64::max);
        let mut high = 0.0f64;
        for k in 0..=GRID {
            let (i, v) = at(k);
            if v < high - 0.02 * top {
                return Some((name, i));
            }
            high = high.max(v);
        }
    }
    None
}

/// Calibrate `config` to `records` (see [`Calibrated`]). When the records hold more than
/// three current levels, the laws in current are fitted with up to five coefficients
/// (`node::fit::free_parameters`); if a fitted law then falls as the current rises within
/// the records' currents (an MR fluid's yield stress and viscosity rise with field: Dyke's
/// command-voltage record gave a τ_y quartic that halves between 0.4 and 1.2 V and rises
/// again), the fit is made again with quadratics and the notes say why.
pub fn calibrate(
    config: &PipelineConfig,
    records: &[Vec<SensorSample>],
    blocks: usize,
    hold: &[String],
) -> Result<Calibrated> {
    let c = calibrate_laws_as_given(config, records, blocks, hold)?;
    // The coefficients past the quadratic that this fit moved (a cubic has no `[4]`).
    let beyond: Vec<ParamKey> = c
        .full
        .fitted
        .iter()
        .map(|f| f.key)
        .filter(|k| BEYOND_QUADRATIC.contains(k))
        .collect();
    let fitted = c.full.applied_to(config);
    let fluid = &fitted.params.two_chamber.fluid;
    let falling = match fluid.current_range_a {
        peak if !beyond.is_empty() && peak > 0.0 => falling_law(fluid, peak),
        _ => None,
    };
    let Some((law, at)) = falling else {
        return Ok(c);
    };
    let mut quadratic = config.clone();
    for c in [
        &mut quadratic.params.two_chamber.fluid.yield_stress_pa,
        &mut quadratic.params.two_chamber.fluid.viscosity_pa_s,
    ] {
        c.truncate(3);
    }
    let added: Vec<String> = beyond.iter().map(|k| k.key()).collect();
    let hold: Vec<String> = hold.iter().chain(&added).cloned().collect();
    let mut q = calibrate_laws_as_given(&quadratic, records, blocks, &hold)?;
    // The holds added here are the fallback's, not the user's: said once, below.
    q.notes
        .retain(|n| !added.iter().any(|k| *n == held_note(k)));
    q.notes.push(format!(
        "the laws in current were then fitted as quadratics instead: with {} \
         coefficients, two_chamber.fluid.{law} fell as the current rose (at {at:.3} A)",
        fluid.yield_stress_pa.len().max(fluid.viscosity_pa_s.len())
    ));
    Ok(q)
}

/// The note of a parameter held by `--hold`.
fn held_note(key: &str) -> String {
    format!("{key} held at its base value (--hold)")
}

/// [`calibrate`] with the laws in current as [`free_parameters`] gives them.
fn calibrate_laws_as_given(
    config: &PipelineConfig,
    records: &[Vec<SensorSample>],
    blocks: usize,
    hold: &[String],
) -> Result<Calibrated> {
    let levels = current_levels(records);
    let (mut keys, mut notes) = free_parameters(config, levels)?;
    for h in hold {
        let held = |k: &node::fit::ParamKey| {
            let key = k.key();
            key == *h
                || key
                    .strip_prefix(h.as_str())
                    .is_some_and(|r| r.starts_with('['))
        };
        if !keys.iter().any(held) {
            bail!(
                "--hold {h}: not among the free parameters ({})",
                keys.iter().map(|k| k.key()).collect::<Vec<_>>().join(", ")
            );
        }
        keys.retain(|k| !held(k));
        notes.push(held_note(h));
    }
    // A law in current beyond a quadratic is held at the records' peak current.
    let mut config = config.clone();
    if keys.iter().any(|k| BEYOND_QUADRATIC.contains(k)) {
        let peak = records
            .iter()
            .flatten()
            .map(|s| s.current_a.abs())
            .filter(|i| i.is_finite())
            .fold(0.0f64, f64::max);
        config.params.two_chamber.fluid.current_range_a = peak;
        notes.push(format!(
            "two_chamber.fluid.current_range_a = {peak} A: above the records' peak current \
             the laws in current are held at their value there"
        ));
    }
    let config = &config;
    let blocks = blocks.max(2);
    let mask = alternate_blocks(records, blocks);
    let split_problem = FitProblem {
        config: config.clone(),
        keys,
        records,
        mask: mask.clone(),
    };
    let (split, keys) =
        fit_holding_unidentified(split_problem, &mut notes).context("fit on the even blocks")?;
    if split.stop == LmStop::MaxIterations {
        bail!(
            "the fit did not converge in {} iterations (RMS {:.4} N): the model does not \
             describe these records well enough to calibrate",
            split.iterations,
            split.rmse_n
        );
    }
    let held = |r: usize, j: usize| !mask[r][j];
    let (holdout_start_rmse_n, _) = rms_residual(records, &predict(config, records), held);
    let split_cfg = split.applied_to(config);
    let pred = predict(&split_cfg, records);
    let (holdout_rmse_n, _) = rms_residual(records, &pred, held);
    let mut holdout_blocks = Vec::new();
    for (r, rec) in records.iter().enumerate() {
        let n = rec.len().max(1);
        for b in (1..blocks).step_by(2) {
            let (rms, count) = rms_residual(records, &pred, |rr, j| rr == r && j * blocks / n == b);
            if count > 0 {
                holdout_blocks.push((r, b, rms));
            }
        }
    }
    let full_problem = FitProblem {
        config: split_cfg,
        keys,
        records,
        mask: records.iter().map(|r| vec![true; r.len()]).collect(),
    };
    let (full, _) =
        fit_holding_unidentified(full_problem, &mut notes).context("fit on all samples")?;
    if full.stop == LmStop::MaxIterations {
        bail!(
            "the fit on all samples did not converge in {} iterations",
            full.iterations
        );
    }
    Ok(Calibrated {
        split,
        holdout_start_rmse_n,
        holdout_rmse_n,
        holdout_blocks,
        full,
        notes,
    })
}

/// [`fit`], and for a spencer twin, whose modified Bouc–Wen law has more parameters than a
/// record usually pins down (k0, k1 and x0 on a short stroke; β beside γ; η on held
/// currents): when the normal equations are too near singular, the parameter with the
/// largest share of the weakest direction is held where the iterations left it (on the
/// floor of the valley the records cannot resolve; holding it at its base value instead
/// left UTFSM 2mm5Hz at 106.6 N held-out against 74.8 N), said in `notes` with its value,
/// and the fit repeated from there. Other models refuse by name, as their free parameters
/// are already the combinations a record identifies. Returns the fit and the keys it moved.
fn fit_holding_unidentified(
    mut problem: FitProblem<'_>,
    notes: &mut Vec<String>,
) -> Result<(FitOutcome, Vec<ParamKey>), FitError> {
    loop {
        match fit_or_unidentified(&problem)? {
            Ok(out) => return Ok((out, problem.keys)),
            Err(Unidentified {
                keys: weak,
                optimum,
            }) if problem.config.model == ModelKind::Spencer && problem.keys.len() > 1 => {
                let held = weak[0];
                // A positive parameter driven to zero restarts from its start.
                let start = std::mem::replace(&mut problem.config, optimum);
                for k in &problem.keys {
                    let v = k.get(&problem.config);
                    if !(v.is_finite() && (v > 0.0 || !k.positive())) {
                        k.set(&mut problem.config, k.get(&start));
                    }
                }
                // Driven to its limit in log space (k1 or β at 10⁻¹⁵⁶, say): its limit, 0.
                if held.positive() && held.get(&problem.config) < 1e-9 * held.get(&start).abs() {
                    held.set(&mut problem.config, 0.0);
                }
                let value = match held.get(&problem.config) {
                    0.0 => "0".to_string(),
                    v => format!("{v:.6e}"),
                };
                let others: Vec<String> = weak[1..].iter().map(|k| k.key()).collect();
                notes.push(if others.is_empty() {
                    format!(
                        "{held} held at {value}, where the iterations left it: the records \
                         barely move it (no interval)"
                    )
                } else {
                    format!(
                        "{held} held at {value}, where the iterations left it: the records \
                         cannot tell it apart from {} (no interval)",
                        others.join(", ")
                    )
                });
                problem.keys.retain(|k| *k != held);
            }
            Err(u) => return Err(FitError::NotIdentifiable(u.keys)),
        }
    }
}

/// Where the fit starts a pre-yield leak it tries (λ, the inverse viscosity ratio of a
/// bi-viscous fluid; `twin::gap`). diagnose's baselines find 0.08–0.13 on the UTFSM records.
pub const LEAK_START: f64 = 0.02;

/// Least relative fall of the held-out RMS for which the fit keeps a pre-yield leak it
/// tried (5 %).
pub const LEAK_MIN_GAIN: f64 = 0.05;

/// The parameter-file key of the pre-yield leak.
const LEAK_KEY: &str = "two_chamber.fluid.pre_yield_leak";

/// [`calibrate`], and for a two-chamber twin whose Bingham or Herschel–Bulkley fluid has
/// no pre-yield leak yet (and `--hold` does not name it), the same fit with the leak
/// freed from [`LEAK_START`]. The leak is kept when it converges and lowers the held-out
/// RMS by at least [`LEAK_MIN_GAIN`]; the notes say which and why. On real records the
/// Bingham jump at v = 0 is where the twin misfits most (UTFSM 5mm3Hz: 139 N RMS at
/// |v| < 5 mm/s against 36 N above 50 mm/s), and the leak is the ramp a real fluid shows
/// there; on a record without one the trial costs a second fit and changes nothing.
pub fn calibrate_with_leak_trial(
    config: &PipelineConfig,
    records: &[Vec<SensorSample>],
    blocks: usize,
    hold: &[String],
) -> Result<Calibrated> {
    let fluid = &config.params.two_chamber.fluid;
    let held = hold.iter().any(|h| h == LEAK_KEY);
    let eligible = config.model == ModelKind::TwoChamber
        && matches!(fluid.law, FluidLaw::Bingham | FluidLaw::HerschelBulkley)
        && fluid.pre_yield_leak == 0.0;
    if !eligible {
        return calibrate(config, records, blocks, hold);
    }
    let hold: Vec<String> = hold.iter().filter(|h| *h != LEAK_KEY).cloned().collect();
    let mut plain = calibrate(config, records, blocks, &hold);
    if held {
        if let Ok(c) = &mut plain {
            c.notes.push(format!(
                "{LEAK_KEY} held at 0 (--hold): no pre-yield leak tried"
            ));
        }
        return plain;
    }
    let mut leaky_config = config.clone();
    leaky_config.params.two_chamber.fluid.pre_yield_leak = LEAK_START;
    let leaky = calibrate(&leaky_config, records, blocks, &hold);
    match (plain, leaky) {
        (Ok(p), Ok(mut l)) if l.holdout_rmse_n < (1.0 - LEAK_MIN_GAIN) * p.holdout_rmse_n => {
            l.notes.push(format!(
                "{LEAK_KEY}: a pre-yield leak was tried and kept: held-out RMS {:.4} N \
                 without, {:.4} N with (at least {:.0} % lower needed)",
                p.holdout_rmse_n,
                l.holdout_rmse_n,
                100.0 * LEAK_MIN_GAIN
            ));
            Ok(l)
        }
        (Ok(mut p), l) => {
            p.notes.push(match l {
                Ok(l) => format!(
                    "{LEAK_KEY}: a pre-yield leak was tried and not kept: held-out RMS {:.4} N \
                     without, {:.4} N with (at least {:.0} % lower needed)",
                    p.holdout_rmse_n,
                    l.holdout_rmse_n,
                    100.0 * LEAK_MIN_GAIN
                ),
                Err(e) => format!("{LEAK_KEY}: a pre-yield leak was tried and not kept: {e:#}"),
            });
            Ok(p)
        }
        (Err(e), Ok(mut l)) => {
            l.notes.push(format!(
                "{LEAK_KEY}: fitted with a pre-yield leak; without one the fit failed: {e:#}"
            ));
            Ok(l)
        }
        (Err(e), Err(_)) => Err(e),
    }
}

/// The fit's report as JSON.
pub fn report_json(c: &Calibrated, inputs: &[PathBuf]) -> serde_json::Value {
    json!({
        "inputs": inputs.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
        "identifiable": c.notes,
        "samples": c.full.samples,
        "start_rmse_n": c.full.start_rmse_n,
        "rmse_n": c.full.rmse_n,
        "iterations": c.full.iterations,
        "stop": stop_text(c.full.stop),
        "holdout": {
            "how": "contiguous time blocks per record; fitted on the even blocks, judged on the odd ones",
            "start_rmse_n": c.holdout_start_rmse_n,
            "fitted_rmse_n": c.holdout_rmse_n,
            "fit_rmse_n": c.split.rmse_n,
            "blocks": c.holdout_blocks.iter().map(|(r, b, rms)| json!({"record": r, "block": b, "rmse_n": rms})).collect::<Vec<_>>(),
        },
        "parameters": c.full.fitted.iter().map(|p| json!({
            "key": p.key.key(),
            "start": p.start,
            "value": p.value,
            "std_error": p.std_error,
            "ci95": [p.value - 1.96 * p.std_error, p.value + 1.96 * p.std_error],
        })).collect::<Vec<_>>(),
    })
}

/// `mrtwin fit`.
pub fn run(args: &FitArgs) -> Result<()> {
    let params = base_params(
        args.params.as_deref(),
        args.model.as_deref(),
        args.effects.as_deref(),
    )?;
    let config = params.pipeline_config()?;
    let records = load_records(&args.recordings)?;
    let c = calibrate_with_leak_trial(&config, &records, args.blocks, &args.hold)?;
    let header = format!(
        "Written by `mrtwin fit` from {}.\nModel {}, effects {}: RMS residual {:.4} N (start {:.4} N); \
         held-out {:.4} N (start {:.4} N).",
        args.recordings
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        config.model,
        config.effects,
        c.full.rmse_n,
        c.full.start_rmse_n,
        c.holdout_rmse_n,
        c.holdout_start_rmse_n
    );
    let fitted = c.full.applied_to(&config);
    write_twin_file(
        &args.out,
        &header,
        &TwinSection::new(config.model, config.effects, &fitted.params, &fitted),
    )?;
    if let Some(j) = &args.json {
        let text = serde_json::to_string_pretty(&report_json(&c, &args.recordings))?;
        std::fs::write(j, text).with_context(|| format!("write {}", j.display()))?;
    }
    println!(
        "fit: model {}, effects {}, {} samples: RMS {:.4} N (start {:.4} N), held-out {:.4} N \
         (start {:.4} N); {} ({} iterations)",
        config.model,
        config.effects,
        c.full.samples,
        c.full.rmse_n,
        c.full.start_rmse_n,
        c.holdout_rmse_n,
        c.holdout_start_rmse_n,
        stop_text(c.full.stop),
        c.full.iterations
    );
    for n in &c.notes {
        println!("  note: {n}");
    }
    for p in &c.full.fitted {
        println!(
            "  {:<40} {:>14.6e}  ± {:.2e} (95 %: ±{:.2e})",
            p.key.key(),
            p.value,
            p.std_error,
            1.96 * p.std_error
        );
    }
    println!("wrote {}", args.out.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fitted quartics of two real records: UTFSM 25mm0x5Hz's rise over its 0–1 A;
    /// Dyke's τ_y (over 0–2.7 V of command) halves between 0.4 and 1.2 and rises again.
    #[test]
    fn a_law_that_falls_as_the_current_rises_is_found_and_named() {
        let mut fluid = twin::models::FluidParams {
            yield_stress_pa: vec![3361.1, 7214.2, 75111.4, -101351.7, 41912.1],
            viscosity_pa_s: vec![0.2215, 0.7222, 4.8739, -8.4522, 4.301],
            ..Default::default()
        };
        assert_eq!(falling_law(&fluid, 1.0), None);
        fluid.yield_stress_pa = vec![7739.8, 140667.3, -286916.3, 189935.3, -39488.4];
        let (law, at) = falling_law(&fluid, 2.7).unwrap();
        assert_eq!(law, "yield_stress_pa");
        assert!((0.4..0.6).contains(&at), "{at}");
        // A 2 % dip is tolerated; a falling viscosity is named as well.
        fluid.yield_stress_pa = vec![1000.0, 10_000.0];
        fluid.viscosity_pa_s = vec![1.0, 0.0, 0.0, 0.0, -0.015];
        assert_eq!(falling_law(&fluid, 1.0), None);
        fluid.viscosity_pa_s = vec![1.0, 0.0, 0.0, 0.0, -0.5];
        assert_eq!(
            falling_law(&fluid, 1.0).map(|f| f.0),
            Some("viscosity_pa_s")
        );
    }
}
