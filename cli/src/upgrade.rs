//! `mrtwin diagnose --params TWIN.yaml --write-params UPGRADED.yaml`: what diagnose found,
//! written into the twin (issue 12).
//!
//! diagnose judges candidates in its own measurement-aware formulation, with the twin's
//! effects already in the baseline; each accepted effect's fitted value is translated into
//! the two-chamber model's own parameter ([`seed_effect`]), and the upgraded twin is then
//! calibrated through the node's pipeline (`node::fit`), so the file written predicts what
//! a replay of it shows.

use std::path::{Path, PathBuf};

use ::diagnose::report::{FluidShape, Parameter, ShapeFollows};
use ::diagnose::Diagnosis;
use anyhow::{bail, Result};
use node::conditioning::SensorSample;
use node::config::TwinNodeParams;
use node::fit::{predict, rms_residual, FitError};
use node::pipeline::PipelineConfig;
use serde_json::{json, Value};
use twin::models::{ModelKind, TwoChamberParams};
use twin::{Effect, EffectSet};

use crate::fit::{calibrate_with_leak_trial, write_twin_file, TwinSection};

/// Widths of the twin's tanh seal friction tried when the upgrade adds one, as shares of
/// the record's peak speed (the first, 1 %, is also the start of every other upgrade;
/// docs/fit.md gives the profile on the UTFSM records).
pub const FRICTION_WIDTHS: [f64; 2] = [0.01, 0.10];

/// Where the fit starts the fluid's yield-step width, as a share of the record's peak speed.
/// Unlike the friction's, the width is fitted (`fluid.yield_step_velocity_m_s`): on the
/// UTFSM records it converges to the same 13 mm/s from 1 and 6 mm/s (docs/fit.md).
pub const YIELD_STEP_WIDTH_START: f64 = 0.10;

/// Whether the twin carries this part of the fluid's shape as it is: a step that follows
/// the yield force (`fluid.yield_step_share`).
fn carried(shape: &FluidShape) -> bool {
    shape.follows == ShapeFollows::YieldForce && shape.share > 0.0
}

/// The fluid's step at reversal as the upgrade seeds the twin's yield step with it.
#[derive(Debug, Clone, Copy)]
struct StepSeed {
    /// The step's share of the mean yield force, `fluid.yield_step_share`'s start.
    share: f64,
    /// Whether diagnose's step follows the viscous coefficient, which the twin has no
    /// shape for: its yield step is the nearest one, tried and kept only where the
    /// upgraded twin predicts its held-out blocks better with it than without.
    nearest: bool,
}

/// The yield step the upgrade tries: diagnose's yield-scaled step as it is, or else its
/// step that follows the viscous coefficient, as the same step height at the mean yield
/// force of the fit that found it (`FluidShape::mean_yield_force_n`). UTFSM 5mm3Hz's step
/// follows the viscous coefficient since the candidates' Jacobian carries a held yield
/// softness (issue 10, session 90); without a step its upgraded twin replayed at 64.6 N
/// against diagnose's final 46.9 N, with the nearest step 38.1 N.
fn step_seed(dg: &Diagnosis) -> Option<StepSeed> {
    let shapes = &dg.report.fluid_shape;
    if let Some(s) = shapes.iter().find(|s| carried(s)) {
        return Some(StepSeed {
            share: s.share,
            nearest: false,
        });
    }
    shapes
        .iter()
        .find(|s| {
            s.follows == ShapeFollows::ViscousCoefficient
                && s.step_n > 0.0
                && s.mean_yield_force_n > 0.0
        })
        .map(|s| StepSeed {
            share: s.step_n / s.mean_yield_force_n,
            nearest: true,
        })
}

/// The SI value of an effect's single parameter in a diagnose finding.
fn si_value(e: Effect, parameters: &std::collections::BTreeMap<String, Parameter>) -> Option<f64> {
    let info = ::diagnose::model::effect_params(e).first()?;
    let p = parameters.get(info.name)?;
    Some(p.value / info.scale)
}

/// Put the value diagnose fitted for `e` into the two-chamber parameters, as a start for
/// the twin's own fit. `si` in diagnose's units (SI): friction force \[N\], stiffness
/// \[N/m\], mass \[kg\], softening per dissipated energy \[1/kJ\], field time constant
/// \[s\], chamber compliance \[m/N\]. `friction_velocity` is diagnose's tanh scale
/// (1 % of the record's peak speed); `gas` whether the upgraded twin has a gas spring.
pub fn seed_effect(
    tc: &mut TwoChamberParams,
    e: Effect,
    si: f64,
    friction_velocity: f64,
    gas: bool,
) {
    let a1 = tc.annulus_area();
    let ar = tc.rod_area();
    let ap = tc.piston_area();
    let slit = tc.slit();
    match e {
        Effect::SealFriction => {
            tc.seal_friction_n = si.max(1e-3);
            tc.seal_friction_velocity_m_s = friction_velocity.max(1e-6);
        }
        // k = κ p0 Ar² / Vg0 (the incompressible gas spring at x = 0).
        Effect::GasSpring => {
            if si > 0.0 && tc.gas_preload_pa > 0.0 {
                tc.gas_volume_m3 = tc.polytropic_index * tc.gas_preload_pa * ar * ar / si;
            }
        }
        // m = m_f + m_r, m_f = ρ L A1² / (b h): what the gap fluid does not carry at its
        // density is the rig's moving mass; a mass below the gap fluid's is its density.
        Effect::FluidInertia => {
            if si > 0.0 {
                let m_f = tc.fluid_mass_kg();
                if si >= m_f {
                    tc.moving_mass_kg = si - m_f;
                } else {
                    tc.moving_mass_kg = 0.0;
                    tc.fluid_density_kg_m3 =
                        si * slit.width_m * slit.height_m / (slit.length_m * a1 * a1);
                }
            }
        }
        Effect::FieldLag => tc.field_time_constant_s = si.max(1e-5),
        // F_y (1 − β E) against τ_y (1 − α ΔT) with ΔT ≈ E / C: C = α / β.
        Effect::ThermalSoftening => {
            if tc.fluid.yield_stress_temp_coeff_per_k <= 0.0 {
                tc.fluid.yield_stress_temp_coeff_per_k = 0.005;
            }
            if si > 0.0 {
                tc.heat_capacity_j_per_k = 1e3 * tc.fluid.yield_stress_temp_coeff_per_k / si;
            }
        }
        // Compliance C = V1/(K A1²) (+ V2/(K Ap²) when chamber 2 is closed by the gas).
        Effect::FluidCompressibility => {
            if si > 0.0 {
                let mut v = tc.chamber1_volume_m3 / (a1 * a1);
                if gas {
                    v += tc.chamber2_volume_m3 / (ap * ap);
                }
                tc.bulk_modulus_pa = v / si;
            }
        }
    }
}

/// The viscous terms' softening over the yield force's, β_c/β_y, of a thermal softening
/// whose viscous softening diagnose freed from the yield force's
/// (`diagnose::select::free_thermal_apart`); `None` while they are tied (its value is then
/// the yield force's by construction, not a measurement) or without a finding.
fn freed_viscous_softening_ratio(dg: &Diagnosis) -> Option<f64> {
    let f = dg
        .report
        .findings
        .iter()
        .find(|f| f.effect == Effect::ThermalSoftening.id())?;
    let [y, c] = ::diagnose::model::effect_params(Effect::ThermalSoftening) else {
        return None;
    };
    let (by, bc) = (f.parameters.get(y.name)?, f.parameters.get(c.name)?);
    (bc.tied_to.is_none() && by.value > 0.0).then(|| bc.value.max(0.0) / by.value)
}

/// Put the viscous softening diagnose freed into the two-chamber parameters, after
/// [`seed_effect`] has set the thermal softening's heat capacity C = 10³ α_y/β_y. The
/// twin's viscosity falls as μ exp(−α_η ΔT) ≈ μ (1 − α_η ΔT) where diagnose's viscous
/// terms fall as c (1 − β_c E), E \[kJ\] = C ΔT/10³: α_η = β_c C/10³ = α_y β_c/β_y
/// (`ratio` = β_c/β_y). The twin's fit moves C, not α_η: the ratio is held.
pub fn seed_viscous_softening(tc: &mut TwoChamberParams, ratio: f64) {
    tc.fluid.viscosity_temp_coeff_per_k = tc.fluid.yield_stress_temp_coeff_per_k * ratio;
}

/// What `diagnose --params` adds to its output: the JSON entry `twin`, and a line for the
/// terminal when an upgraded twin was written.
pub struct TwinCheck {
    /// The `twin` entry of the diagnosis JSON.
    pub json: Value,
    /// "upgraded twin FILE: replay RMS … → …" (with `--write-params`).
    pub summary: Option<String>,
}

/// What the upgrade carries over from a diagnosis: each finding as the twin effect and its
/// value in SI units, and the fluid's step at reversal as the twin's yield step
/// ([`step_seed`]).
fn carried_over(dg: &Diagnosis) -> (Vec<(Effect, f64)>, Option<StepSeed>) {
    let found = dg
        .report
        .findings
        .iter()
        .filter_map(|f| {
            let e: Effect = f.effect.parse().ok()?;
            Some((e, si_value(e, &f.parameters)?))
        })
        .collect();
    (found, step_seed(dg))
}

/// The fluid shapes diagnose found that the twin does not take (their explanations): a
/// step that follows the viscous coefficient unless the upgraded twin kept it as its
/// nearest yield step (`nearest_kept`).
fn not_carried(dg: &Diagnosis, nearest_kept: bool) -> Vec<&str> {
    dg.report
        .fluid_shape
        .iter()
        .filter(|s| !carried(s) && !nearest_kept)
        .map(|s| s.explanation.as_str())
        .collect()
}

/// Write the upgraded twin: the twin of `params` with the effects diagnose found switched
/// on and calibrated on `records` (the recording `input`, as the node sees it).
pub fn write_upgraded(
    params: &TwinNodeParams,
    params_path: &Path,
    dg: &Diagnosis,
    records: &[Vec<SensorSample>],
    input: &Path,
    out: Option<&Path>,
) -> Result<TwinCheck> {
    let config = params.pipeline_config()?;
    let (twin_rmse, _) = rms_residual(records, &predict(&config, records), |_, _| true);
    let (found, step) = carried_over(dg);
    // A step the twin has no shape for is tried only where the twin has a yield step.
    let step = step.filter(|st| !st.nearest || config.model == ModelKind::TwoChamber);
    // The effect ids added (JSON `added`), and what the upgrade adds in words.
    let added: Vec<&str> = found.iter().map(|(e, _)| e.id()).collect();
    let mut adds = added.clone();
    if step.is_some() {
        adds.push("the fluid's yield step");
    }
    let (b, f) = (
        dg.report.baseline.holdout_rmse_unweighted_n,
        dg.report.final_model.holdout_rmse_unweighted_n,
    );
    // diagnose's baseline is its own (and may fit worse or better than the twin), so its
    // ratio does not carry over; the variance its findings explain does: taken off the
    // twin's residual it predicts the upgraded twin's replay.
    let explained = (b * b - f * f).max(0.0);
    let claim = (twin_rmse * twin_rmse - explained).max(0.0).sqrt() / twin_rmse;
    let mut json = json!({
        "params": params_path.display().to_string(),
        "model": config.model.name(),
        "effects": config.effects.to_string(),
        "replay_rmse_N": twin_rmse,
        "diagnose_holdout_ratio": f / b,
        "diagnose_explained_variance_N2": explained,
        "predicted_replay_ratio": claim,
        "fluid_shape_not_carried": not_carried(dg, false),
    });
    let Some(out) = out else {
        return Ok(TwinCheck {
            json,
            summary: None,
        });
    };
    let summary = |up_rmse: f64| {
        Some(format!(
            "upgraded twin {}: replay RMS {twin_rmse:.2} N → {up_rmse:.2} N (ratio {:.3})",
            out.display(),
            up_rmse / twin_rmse
        ))
    };
    if adds.is_empty() {
        write_twin_file(
            out,
            &format!(
                "Written by `mrtwin diagnose --write-params` from {}: nothing found on {}, \
                 the twin is unchanged.",
                params_path.display(),
                input.display()
            ),
            &TwinSection::new(config.model, config.effects, &config.params, &config),
        )?;
        json["upgraded"] = json!({
            "file": out.display().to_string(),
            "added": added,
            "yield_step_added": false,
            "replay_rmse_N": twin_rmse,
            "replay_ratio": 1.0,
        });
        return Ok(TwinCheck {
            json,
            summary: summary(twin_rmse),
        });
    }
    if config.model != ModelKind::TwoChamber {
        bail!(
            "--write-params: the twin's model '{}' takes no effects and no yield step; fit a \
             two-chamber twin (mrtwin fit --model two-chamber) to add {}",
            config.model,
            adds.join(", ")
        );
    }
    let effects = found
        .iter()
        .fold(config.effects, |set: EffectSet, (e, _)| set.with(*e));
    let viscous = freed_viscous_softening_ratio(dg);
    let best = calibrated_at_best_width(&config, (&found, viscous), step, effects, records)?;
    let (c, held, profile) = (best.calibrated, best.held, best.profile);
    let step_kept = best.with_step;
    if !step_kept {
        adds.retain(|a| *a != "the fluid's yield step");
    }
    if adds.is_empty() {
        adds.push("nothing (the fluid's step, tried as the twin's nearest yield step, did not predict the held-out blocks better)");
    }
    json["fluid_shape_not_carried"] = json!(not_carried(dg, step_kept && best.nearest.is_some()));
    // The full fit ran through the same pipeline on every sample: its RMS is the replay's.
    let up_rmse = c.full.rmse_n;
    let fitted = c.full.applied_to(&config);
    write_twin_file(
        out,
        &format!(
            "Written by `mrtwin diagnose --write-params`: {} upgraded with {} found on {} and \
             calibrated there.\nReplay RMS residual {:.4} N → {:.4} N (ratio {:.3}; predicted from \
             the variance diagnose explained: {:.3}).{}",
            params_path.display(),
            adds.join(", "),
            input.display(),
            twin_rmse,
            up_rmse,
            up_rmse / twin_rmse,
            claim,
            if held.is_empty() {
                String::new()
            } else {
                format!(
                    "\nHeld at diagnose's value (the record does not identify it in the twin): {}.",
                    held.join(", ")
                )
            }
        ),
        &TwinSection::new(ModelKind::TwoChamber, effects, &fitted.params, &fitted),
    )?;
    json["upgraded"] = json!({
        "file": out.display().to_string(),
        "added": added,
        "yield_step_added": step_kept,
        "nearest_yield_step": best.nearest,
        "effects": effects.to_string(),
        "replay_rmse_N": up_rmse,
        "replay_ratio": up_rmse / twin_rmse,
        "fit": crate::fit::report_json(&c, &[PathBuf::from(input)]),
        "held_at_diagnose_value": held,
        "seal_friction_width_profile": profile,
    });
    Ok(TwinCheck {
        json,
        summary: summary(up_rmse),
    })
}

/// The best calibration of the upgraded twin ([`calibrated_at_best_width`]).
struct BestUpgrade {
    calibrated: crate::fit::Calibrated,
    /// The keys held at diagnose's value.
    held: Vec<String>,
    /// The held-out RMS at each seal-friction width tried (empty without a friction).
    profile: Vec<Value>,
    /// Whether the kept calibration has the fluid's yield step.
    with_step: bool,
    /// For a step tried as the nearest shape ([`StepSeed::nearest`]): the held-out RMS with
    /// and without it (JSON `nearest_yield_step`), else null.
    nearest: Option<Value>,
}

/// The upgraded twin calibrated on `records`: `config` with the `found` effects seeded from
/// diagnose's values (a freed `viscous` softening too, as β_c/β_y; and the fluid's yield
/// `step`) and switched on
/// (`effects`). The twin's seal friction is a tanh step whose width the fit does not move
/// (freed, it runs off against the leak and τ_y(0)): with a friction added, the upgrade is
/// calibrated at each width of FRICTION_WIDTHS (a share of the record's peak speed) and the
/// lowest held-out RMS is kept. A step that is only the nearest shape is tried with and
/// without, the same way.
fn calibrated_at_best_width(
    config: &PipelineConfig,
    (found, viscous): (&[(Effect, f64)], Option<f64>),
    step: Option<StepSeed>,
    effects: EffectSet,
    records: &[Vec<SensorSample>],
) -> Result<BestUpgrade> {
    let peak_speed = records
        .iter()
        .flatten()
        .map(|s| s.velocity_m_s.abs())
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let adds_friction = found.iter().any(|(e, _)| *e == Effect::SealFriction);
    let widths: &[f64] = if adds_friction {
        &FRICTION_WIDTHS
    } else {
        &FRICTION_WIDTHS[..1]
    };
    let steps: Vec<Option<StepSeed>> = match step {
        Some(st) if st.nearest => vec![Some(st), None],
        other => vec![other],
    };
    let mut best: Option<(crate::fit::Calibrated, Vec<String>, bool)> = None;
    let mut by_step: [Option<f64>; 2] = [None, None];
    let mut first_error = None;
    let mut profile = Vec::new();
    for step in &steps {
        for share in widths {
            let mut upgraded = config.params.clone();
            for (e, si) in found {
                seed_effect(
                    &mut upgraded.two_chamber,
                    *e,
                    *si,
                    share * peak_speed,
                    effects.has(Effect::GasSpring),
                );
            }
            if let Some(ratio) = viscous {
                seed_viscous_softening(&mut upgraded.two_chamber, ratio);
            }
            if let Some(st) = step {
                // diagnose's F_c F_y(I)/F̄_y tanh(v/v_s) is β F_y(I) tanh(v/v_s): β = F_c/F̄_y.
                upgraded.two_chamber.fluid.yield_step_share = st.share;
                upgraded.two_chamber.fluid.yield_step_velocity_m_s =
                    (YIELD_STEP_WIDTH_START * peak_speed).max(1e-6);
            }
            let up_config = PipelineConfig {
                params: upgraded,
                effects,
                ..config.clone()
            };
            match calibrate_upgrade(config, &up_config, records) {
                Ok((c, held)) => {
                    if adds_friction {
                        profile.push(json!({
                            "seal_friction_velocity_m_s": share * peak_speed,
                            "yield_step": step.is_some(),
                            "holdout_rmse_n": c.holdout_rmse_n,
                        }));
                    }
                    let slot = &mut by_step[usize::from(step.is_none())];
                    *slot = Some(slot.map_or(c.holdout_rmse_n, |r| r.min(c.holdout_rmse_n)));
                    if best
                        .as_ref()
                        .is_none_or(|(b, _, _)| c.holdout_rmse_n < b.holdout_rmse_n)
                    {
                        best = Some((c, held, step.is_some()));
                    }
                }
                Err(e) => {
                    first_error.get_or_insert(e);
                }
            }
        }
    }
    let Some((calibrated, held, with_step)) = best else {
        return Err(first_error.expect("at least one calibration tried, and every one failed"));
    };
    let nearest = step.filter(|st| st.nearest).map(|st| {
        json!({
            "share_start": st.share,
            "holdout_rmse_n_with": by_step[0],
            "holdout_rmse_n_without": by_step[1],
        })
    });
    Ok(BestUpgrade {
        calibrated,
        held,
        profile,
        with_step,
        nearest,
    })
}

/// Calibrate the upgraded twin on `records`. When the records cannot identify a parameter
/// of an effect the upgrade added (the twin's fit is not diagnose's: on UTFSM 10mm1Hz
/// diagnose's fluid mass is resolved, the twin's `moving_mass_kg` is not, against the
/// chamber compliance at one frequency), that parameter is held at the value translated
/// from diagnose's finding and the fit is made again; the held keys are returned (and
/// written to the JSON). A base parameter that is not identifiable is an error as before.
fn calibrate_upgrade(
    config: &PipelineConfig,
    up_config: &PipelineConfig,
    records: &[Vec<SensorSample>],
) -> Result<(crate::fit::Calibrated, Vec<String>)> {
    let levels = node::fit::current_levels(records);
    let (base, _) = node::fit::free_parameters(config, levels)?;
    let base_keys: Vec<String> = base.iter().map(|k| k.key()).collect();
    let mut held: Vec<String> = Vec::new();
    loop {
        let err = match calibrate_with_leak_trial(up_config, records, 8, &held) {
            Ok(c) => return Ok((c, held)),
            Err(e) => e,
        };
        let added: Vec<String> = match err.root_cause().downcast_ref::<FitError>() {
            Some(FitError::NotIdentifiable(keys)) => keys
                .iter()
                .map(|k| k.key())
                .filter(|k| !base_keys.contains(k) && !held.contains(k))
                .collect(),
            _ => Vec::new(),
        };
        if added.is_empty() {
            return Err(err);
        }
        tracing::warn!(
            held = %added.join(", "),
            "the upgraded twin's fit cannot identify these on this record; they are held at \
             diagnose's values"
        );
        held.extend(added);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A freed viscous softening reaches the twin as α_η with the ratio diagnose fitted:
    /// over a small heat ΔT = 10³ E/C the twin's yield stress and viscosity fall by β_y E
    /// and β_c E, diagnose's rates per dissipated energy.
    #[test]
    fn a_freed_viscous_softening_seeds_the_twins_viscosity_coefficient() {
        let (by, bc) = (0.05, 0.6);
        let mut tc = TwoChamberParams::default();
        let viscous_before = tc.fluid.viscosity_temp_coeff_per_k;
        seed_effect(&mut tc, Effect::ThermalSoftening, by, 1e-3, false);
        assert_eq!(
            tc.fluid.viscosity_temp_coeff_per_k, viscous_before,
            "a tied softening leaves the twin's viscosity coefficient alone"
        );
        seed_viscous_softening(&mut tc, bc / by);
        let energy_kj = 1e-3;
        let dt = 1e3 * energy_kj / tc.heat_capacity_j_per_k;
        let yield_fall = tc.fluid.yield_stress_temp_coeff_per_k * dt;
        let viscous_fall = 1.0 - (-tc.fluid.viscosity_temp_coeff_per_k * dt).exp();
        assert!((yield_fall / (by * energy_kj) - 1.0).abs() < 1e-12);
        assert!((viscous_fall / (bc * energy_kj) - 1.0).abs() < 1e-3);
    }
}
