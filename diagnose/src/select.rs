//! Locate the mismatch, try every candidate, select forward, and assemble the report.

use std::collections::BTreeMap;

use twin::Effect;

use crate::data::{prepare, DataError, Phase, Prepared, Signals};
use crate::model::{baseline_start, effect_params, evaluate, extend, fit, Fit};
use crate::report::*;
use crate::stats;

/// Acceptance thresholds (docs/diagnose.md explains each).
#[derive(Debug, Clone, PartialEq)]
pub struct Thresholds {
    /// Smallest relative fall of the held-out RMS.
    pub min_holdout_drop: f64,
    /// Smallest paired z of the per-stroke held-out improvement.
    pub min_holdout_z: f64,
    /// Largest (most negative allowed) ΔBIC with the effective sample size.
    pub max_delta_bic: f64,
    /// Smallest relative fall of the residual structure in a flagged region.
    pub min_structure_drop: f64,
    /// Structure ratio above which a region is flagged.
    pub flag_ratio: f64,
    /// Two passing candidates whose ΔBIC differ by less than this fraction of the
    /// best |ΔBIC| (and the second fails on top of the first) are undecided.
    pub tie_fraction: f64,
}

impl Default for Thresholds {
    fn default() -> Self {
        Self {
            min_holdout_drop: 0.005,
            min_holdout_z: 2.5,
            max_delta_bic: -10.0,
            min_structure_drop: 0.2,
            flag_ratio: 1.2,
            tie_fraction: 0.1,
        }
    }
}

/// A diagnosis: the report and the data behind the plots.
#[derive(Debug, Clone)]
pub struct Diagnosis {
    /// The report.
    pub report: Report,
    /// The prepared data.
    pub data: Prepared,
    /// Baseline prediction \[N\].
    pub baseline_force: Vec<f64>,
    /// Final prediction \[N\].
    pub final_force: Vec<f64>,
    /// Effects of the final model (findings and the chosen side of undecided pairs).
    pub final_effects: Vec<Effect>,
}

impl Diagnosis {
    /// Effect ids found.
    pub fn found(&self) -> Vec<String> {
        self.report
            .findings
            .iter()
            .map(|f| f.effect.clone())
            .collect()
    }
}

/// Region membership of a sample.
struct Regions {
    names: Vec<String>,
    member: Vec<Vec<usize>>, // per sample, region indices
}

fn regions(d: &Prepared) -> Regions {
    let mut names: Vec<String> = Vec::new();
    let idx = |names: &mut Vec<String>, s: String| -> usize {
        if let Some(k) = names.iter().position(|x| *x == s) {
            k
        } else {
            names.push(s);
            names.len() - 1
        }
    };
    let n = d.len();
    let t0 = d.t[0];
    let span = (d.t[n - 1] - t0).max(1e-9);
    let imax = d.i.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let tol = (0.02 * imax).max(1e-3);
    let mut last_step = f64::NEG_INFINITY;
    let mut seg_desc: Vec<(f64, f64, f64, usize)> = vec![(f64::INFINITY, 0.0, 0.0, 0); d.segments];
    for j in 0..n {
        let s = &mut seg_desc[d.segment[j]];
        s.0 = s.0.min(d.t[j]);
        s.1 = s.1.max(d.t[j]);
        s.2 += d.i[j];
        s.3 += 1;
    }
    let mut member = Vec::with_capacity(n);
    for j in 0..n {
        let mut m = Vec::with_capacity(8);
        m.push(idx(
            &mut names,
            format!("stroke phase: {}", d.phase[j].name()),
        ));
        m.push(idx(
            &mut names,
            if d.v[j] < 0.0 {
                "direction: compression (v < 0)".into()
            } else {
                "direction: rebound (v > 0)".into()
            },
        ));
        let b = ((d.v[j].abs() / d.stroke_speed[j].max(1e-12)) * 5.0)
            .floor()
            .min(4.0) as usize;
        m.push(idx(
            &mut names,
            format!("speed: {}–{} % of the stroke's peak", b * 20, b * 20 + 20),
        ));
        let k = d
            .knots
            .iter()
            .enumerate()
            .min_by(|a, b| (a.1 - d.i[j]).abs().total_cmp(&(b.1 - d.i[j]).abs()))
            .map(|x| x.0)
            .unwrap_or(0);
        m.push(idx(&mut names, format!("current ≈ {:.3} A", d.knots[k])));
        let sd = seg_desc[d.segment[j]];
        m.push(idx(
            &mut names,
            format!(
                "segment {} ({:.2}–{:.2} s, {:.3} A)",
                d.segment[j] + 1,
                sd.0,
                sd.1,
                sd.2 / sd.3 as f64
            ),
        ));
        let q = (((d.t[j] - t0) / span) * 5.0).floor().min(4.0) as usize;
        m.push(idx(
            &mut names,
            format!("time: fifth {} of the record", q + 1),
        ));
        if j > 0 && (d.i[j] - d.i[j - 1]).abs() > tol {
            last_step = d.t[j];
        }
        if d.t[j] - last_step < 0.05 {
            m.push(idx(&mut names, "within 50 ms after a current step".into()));
        }
        member.push(m);
    }
    Regions { names, member }
}

/// Half-width of the moving average that separates structure from noise \[s\].
const SMOOTH_HALF_WIDTH_S: f64 = 0.01;

/// The residual smoothed by a centred moving average over ±10 ms, and the number of
/// samples averaged.
fn smooth(d: &Prepared, r: &[f64]) -> (Vec<f64>, usize) {
    let n = r.len();
    let dt = (d.t[n - 1] - d.t[0]) / (n - 1) as f64;
    let w = ((SMOOTH_HALF_WIDTH_S / dt).round() as usize).max(1);
    let mut cs = vec![0.0; n + 1];
    for j in 0..n {
        cs[j + 1] = cs[j] + r[j];
    }
    let sm = (0..n)
        .map(|j| {
            let lo = j.saturating_sub(w);
            let hi = (j + w + 1).min(n);
            (cs[hi] - cs[lo]) / (hi - lo) as f64
        })
        .collect();
    (sm, 2 * w + 1)
}

struct RegionStats {
    energy: Vec<f64>,
    count: Vec<usize>,
    structure: Vec<f64>, // mean square of the smoothed residual
    total_energy: f64,
    total_structure: f64,
}

/// Residual energy per region and its structure: the mean square of the ±10 ms moving
/// average minus the part white noise would leave in it (σ²/window, σ² from the
/// high-pass residual), floored at 0.
fn region_stats(d: &Prepared, reg: &Regions, r: &[f64], holdout_only: bool) -> RegionStats {
    let (sm, win) = smooth(d, r);
    let k = reg.names.len();
    let mut energy = vec![0.0; k];
    let mut count = vec![0usize; k];
    let mut st = vec![0.0; k];
    let (mut te, mut ts, mut tn, mut hp) = (0.0, 0.0, 0usize, 0.0);
    for j in 0..d.len() {
        if holdout_only && !d.holdout[j] {
            continue;
        }
        let e = r[j] * r[j];
        te += e;
        ts += sm[j] * sm[j];
        hp += (r[j] - sm[j]).powi(2);
        tn += 1;
        for &q in &reg.member[j] {
            energy[q] += e;
            count[q] += 1;
            st[q] += sm[j] * sm[j];
        }
    }
    let w = win as f64;
    // High-pass part holds (1 − 1/w) of white noise.
    let noise = hp / tn.max(1) as f64 / (1.0 - 1.0 / w) / w;
    let structure = (0..k)
        .map(|q| {
            if count[q] > 0 {
                (st[q] / count[q] as f64 - noise).max(0.0)
            } else {
                0.0
            }
        })
        .collect();
    RegionStats {
        energy,
        count,
        structure,
        total_energy: te,
        total_structure: (ts / tn.max(1) as f64 - noise).max(0.0),
    }
}

/// Flagged regions (indices; `usize::MAX` stands for the whole record).
fn flagged(d: &Prepared, reg: &Regions, r: &[f64], th: &Thresholds) -> Vec<usize> {
    let s = region_stats(d, reg, r, false);
    let n = d.len();
    let mut out = vec![usize::MAX];
    for q in 0..reg.names.len() {
        if s.count[q] as f64 >= 0.01 * n as f64
            && s.structure[q] >= th.flag_ratio * s.total_structure
        {
            out.push(q);
        }
    }
    out
}

fn mismatch_list(d: &Prepared, reg: &Regions, r: &[f64], th: &Thresholds) -> Vec<Mismatch> {
    let s = region_stats(d, reg, r, false);
    let n = d.len() as f64;
    let mut list: Vec<Mismatch> = (0..reg.names.len())
        .filter(|&q| s.count[q] as f64 >= 0.01 * n)
        .map(|q| {
            let es = s.energy[q] / s.total_energy.max(1e-300);
            let ss = s.count[q] as f64 / n;
            let sr = s.structure[q] / s.total_structure.max(1e-300);
            Mismatch {
                region: reg.names[q].clone(),
                share_of_residual_energy: es,
                share_of_samples: ss,
                structure_ratio: sr,
                description: format!(
                    "{:.1} % of the residual energy in {:.1} % of the samples ({:.2}× the average); \
                     systematic (±10 ms-averaged, noise removed) residual {:.2}× the record's{}",
                    100.0 * es,
                    100.0 * ss,
                    es / ss.max(1e-12),
                    sr,
                    if sr >= th.flag_ratio { " — flagged" } else { "" }
                ),
            }
        })
        .filter(|m| m.share_of_residual_energy > 1.1 * m.share_of_samples || m.structure_ratio >= th.flag_ratio)
        .collect();
    list.sort_by(|a, b| {
        let ea = a.share_of_residual_energy - a.share_of_samples;
        let eb = b.share_of_residual_energy - b.share_of_samples;
        eb.total_cmp(&ea)
    });
    list.truncate(10);
    list
}

fn residual(d: &Prepared, force: &[f64]) -> Vec<f64> {
    d.f.iter().zip(force).map(|(f, p)| f - p).collect()
}

fn residual_stats(d: &Prepared, r: &[f64]) -> ResidualStats {
    let n = r.len();
    let band = 1.96 / (n as f64).sqrt();
    let rho1 = stats::autocorr(r, 1);
    let (q, crit) = stats::ljung_box(r, 20);
    let n_eff = stats::effective_n(n, rho1);
    let step: Vec<f64> = (0..n)
        .map(|j| {
            if j == 0 {
                0.0
            } else {
                (d.i[j] - d.i[j - 1]) * d.v[j].signum()
            }
        })
        .collect();
    let signals: [(&str, &[f64]); 4] = [
        ("velocity", &d.v),
        ("acceleration", &d.a),
        ("displacement", &d.x),
        ("current steps (ΔI · sgn v)", &step),
    ];
    let cross = signals
        .iter()
        .map(|(name, s)| {
            let (lag, rho) = stats::max_crosscorr(r, s, -50..=50);
            CrossCorrelation {
                signal: name.to_string(),
                max_abs_rho: rho.abs(),
                lag_samples: lag,
                band95: band,
                band95_autocorrelated: 1.96 / n_eff.sqrt(),
            }
        })
        .collect();
    ResidualStats {
        whiteness: Whiteness {
            rho1,
            band95: band,
            ljung_box_q20: q,
            ljung_box_crit95: crit,
        },
        cross_correlation: cross,
    }
}

fn holdout_cycle_sse(d: &Prepared, force: &[f64]) -> Vec<f64> {
    let mut s = vec![0.0; d.cycles];
    for j in 0..d.len() {
        if d.holdout[j] {
            s[d.cycle[j]] += (d.f[j] - force[j]).powi(2);
        }
    }
    // Blocks with held-out samples only.
    let mut has = vec![false; d.cycles];
    for j in 0..d.len() {
        if d.holdout[j] {
            has[d.cycle[j]] = true;
        }
    }
    s.into_iter()
        .zip(has)
        .filter(|x| x.1)
        .map(|x| x.0)
        .collect()
}

fn effect_parameters(fit: &Fit, e: Effect) -> BTreeMap<String, Parameter> {
    let mut out = BTreeMap::new();
    if let Some(k) = fit.layout.index(e) {
        for (q, info) in effect_params(e).iter().enumerate() {
            let v = fit.theta[k + q] * info.scale;
            let se = fit.se[k + q] * info.scale;
            out.insert(
                info.name.to_string(),
                Parameter {
                    value: v,
                    ci95: [v - 1.96 * se, v + 1.96 * se],
                    unit: info.unit.to_string(),
                },
            );
        }
    }
    out
}

/// Fit `e` on top of `current` (several start values for the nonlinear ones).
fn fit_candidate(d: &Prepared, current: &Fit, e: Effect) -> Fit {
    let lay = current.layout.with(e);
    let fpeak = d.f.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(1e-9);
    let xr = {
        let lo = d.x.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = d.x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (0.5 * (hi - lo)).max(1e-6)
    };
    let starts: Vec<Vec<f64>> = match e {
        Effect::FieldLag => vec![vec![0.003], vec![0.01], vec![0.03]],
        Effect::FluidCompressibility => [0.002, 0.01, 0.05]
            .iter()
            .map(|f| vec![f * xr / fpeak])
            .collect(),
        _ => vec![vec![0.0; effect_params(e).len()]],
    };
    let mut best: Option<(f64, Vec<f64>)> = None;
    for s in starts {
        let th = extend(&current.layout, &current.theta, &lay, &[(e, s)]);
        let ev = evaluate(d, &lay, &th, false);
        let sse: f64 = (0..d.len())
            .filter(|&j| !d.holdout[j])
            .map(|j| (d.f[j] - ev.force[j]).powi(2))
            .sum();
        if best.as_ref().is_none_or(|b| sse < b.0) {
            best = Some((sse, th));
        }
    }
    let th = best.map(|b| b.1).unwrap_or_default();
    fit(d, &lay, &th)
}

struct Judged {
    effect: Effect,
    fit: Fit,
    evidence: Evidence,
    passed: [bool; 4],
}

impl Judged {
    fn ok(&self) -> bool {
        self.passed.iter().all(|x| *x)
    }
}

fn judge(
    d: &Prepared,
    reg: &Regions,
    current: &Fit,
    flags: &[usize],
    cand: Fit,
    e: Effect,
    th: &Thresholds,
) -> Judged {
    let before = current.holdout_rmse(d);
    let after = cand.holdout_rmse(d);
    let (_, z) = stats::paired_z(
        &holdout_cycle_sse(d, &current.force),
        &holdout_cycle_sse(d, &cand.force),
    );
    let n_eff = stats::effective_n(current.train_n, current.rho1);
    let dp = (cand.layout.len() - current.layout.len()) as f64;
    let dbic = n_eff * (cand.train_sse / current.train_sse).ln() + dp * n_eff.ln();
    let k = cand.layout.index(e).unwrap_or(0);
    let ci_ok = effect_params(e).iter().enumerate().any(|(q, info)| {
        let v = cand.theta[k + q];
        let se = cand.se[k + q];
        let lo = v - 1.96 * se;
        let hi = v + 1.96 * se;
        let excludes = lo > info.no_effect || hi < info.no_effect;
        let physical = info.sign == 0.0 || (v - info.no_effect) * info.sign > 0.0;
        se.is_finite() && excludes && physical
    });
    let r0 = residual(d, &current.force);
    let r1 = residual(d, &cand.force);
    let s0 = region_stats(d, reg, &r0, true);
    let s1 = region_stats(d, reg, &r1, true);
    // The candidate's own target: the region where its prediction changes most.
    let mut change = vec![(0.0, 0usize); reg.names.len()];
    for j in 0..d.len() {
        let c = (cand.force[j] - current.force[j]).powi(2);
        for &q in &reg.member[j] {
            change[q].0 += c;
            change[q].1 += 1;
        }
    }
    let target = (0..reg.names.len())
        .filter(|&q| change[q].1 as f64 >= 0.01 * d.len() as f64)
        .max_by(|&a, &b| {
            (change[a].0 / change[a].1 as f64).total_cmp(&(change[b].0 / change[b].1 as f64))
        });
    let mut regions_checked: Vec<usize> = flags.to_vec();
    regions_checked.extend(target);
    let mut best = (f64::NEG_INFINITY, String::new());
    for &q in &regions_checked {
        let (a, b, name) = if q == usize::MAX {
            (
                s0.total_structure,
                s1.total_structure,
                "whole record".to_string(),
            )
        } else {
            (s0.structure[q], s1.structure[q], reg.names[q].clone())
        };
        let drop = if a > 0.0 { 1.0 - b / a } else { 0.0 };
        if drop > best.0 {
            best = (drop, name);
        }
    }
    let passed = [
        after < before * (1.0 - th.min_holdout_drop) && z >= th.min_holdout_z,
        dbic <= th.max_delta_bic,
        ci_ok,
        best.0 >= th.min_structure_drop,
    ];
    Judged {
        effect: e,
        fit: cand,
        evidence: Evidence {
            holdout_rmse_before_n: before,
            holdout_rmse_after_n: after,
            delta_bic: dbic,
            effective_samples: n_eff,
            holdout_z: z,
            structure_drop: best.0,
            structure_region: best.1,
        },
        passed,
    }
}

fn explanation(e: Effect, p: &BTreeMap<String, Parameter>) -> String {
    let g = |k: &str| p.get(k).map(|x| x.value).unwrap_or(f64::NAN);
    match e {
        Effect::SealFriction => format!(
            "a force step of {:.1} N at every velocity reversal, the same at every current: \
             Coulomb friction of seals and guides, which the Bingham yield force (scaling with \
             the fluid's shape law at each current) does not reproduce",
            g("friction_force")
        ),
        Effect::GasSpring => format!(
            "a force offset of {:.1} N and a stiffness of {:.3} N/mm present at every current: \
             gas accumulator preload (offset ≈ −p0 Ar) and its spring (a sensor offset would \
             look the same)",
            g("force_offset"),
            g("stiffness")
        ),
        Effect::FluidInertia => format!(
            "a force proportional to acceleration, {:.3} kg, largest at stroke ends and growing \
             with frequency squared: mass of the fluid accelerated through the gap",
            g("fluid_mass")
        ),
        Effect::ThermalSoftening => format!(
            "the force amplitude falls by {:.2} % per kJ dissipated: the fluid warms and its \
             yield stress and viscosity fall (no temperature channel needed)",
            100.0 * g("softening_per_energy")
        ),
        Effect::FieldLag => format!(
            "after each current step the force reaches its new level along an exponential with \
             time constant {:.1} ms: magnetic field rise time / eddy currents",
            g("field_time_constant")
        ),
        Effect::FluidCompressibility => format!(
            "the force lags velocity after each reversal (the F–v loop opens near v = 0): a \
             compliance of {:.4} mm/kN between piston and gap, i.e. a finite effective bulk \
             modulus of the fluid in the chambers",
            g("chamber_compliance")
        ),
    }
}

/// Diagnose a recording.
pub fn diagnose(signals: &Signals, input: &str, th: &Thresholds) -> Result<Diagnosis, DataError> {
    let d = prepare(signals)?;
    let reg = regions(&d);
    let (lay, theta) = baseline_start(&d);
    let base = fit(&d, &lay, &theta);
    let summary = |f: &Fit| ModelSummary {
        model: f.layout.name(),
        train_rmse_n: f.train_rmse(),
        holdout_rmse_n: f.holdout_rmse(&d),
        parameters: f.layout.len(),
    };
    let r_base = residual(&d, &base.force);
    let mismatch = mismatch_list(&d, &reg, &r_base, th);
    let mut current = base.clone();
    let mut remaining: Vec<Effect> = Effect::ALL.to_vec();
    let mut accepted: Vec<(Effect, Evidence)> = Vec::new();
    let mut undecided: Vec<Undecided> = Vec::new();
    let mut undecided_effects: Vec<Effect> = Vec::new();
    let mut trials: Vec<Trial> = Vec::new();
    // Candidates that tied with the one accepted in the previous round.
    let mut pending_ties: Vec<(Effect, Effect)> = Vec::new();
    for round in 1..=Effect::ALL.len() {
        if remaining.is_empty() {
            break;
        }
        let flags = flagged(&d, &reg, &residual(&d, &current.force), th);
        // Candidates are fitted in parallel (independent fits on shared data).
        let judged: Vec<Judged> = std::thread::scope(|scope| {
            let handles: Vec<_> = remaining
                .iter()
                .map(|&e| {
                    let (d, reg, current, flags) = (&d, &reg, &current, &flags);
                    scope.spawn(move || {
                        let cand = fit_candidate(d, current, e);
                        judge(d, reg, current, flags, cand, e, th)
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().expect("candidate fit does not panic"))
                .collect()
        });
        // Resolve ties from the previous round: a tied candidate that no longer passes on
        // top of the accepted one is indistinguishable from it.
        for (winner, other) in pending_ties.drain(..) {
            let still = judged
                .iter()
                .find(|j| j.effect == other)
                .is_some_and(|j| j.ok());
            if !still {
                undecided.push(Undecided {
                    effects: vec![winner.id().into(), other.id().into()],
                    why: format!(
                        "{} and {} pass every rule on their own with nearly the same criterion \
                         (within {:.0} %), and neither adds anything once the other is in: the \
                         data cannot tell them apart. The final model carries {} for prediction.",
                        winner.id(),
                        other.id(),
                        100.0 * th.tie_fraction,
                        winner.id()
                    ),
                });
                undecided_effects.push(winner);
                remaining.retain(|x| *x != other);
            }
        }
        let best = judged
            .iter()
            .filter(|j| j.ok() && remaining.contains(&j.effect))
            .min_by(|a, b| a.evidence.delta_bic.total_cmp(&b.evidence.delta_bic));
        let best_effect = best.map(|b| b.effect);
        for j in &judged {
            trials.push(Trial {
                round,
                effect: j.effect.id().into(),
                evidence: j.evidence.clone(),
                parameters: effect_parameters(&j.fit, j.effect),
                passed: j.passed,
                accepted: Some(j.effect) == best_effect,
            });
        }
        let Some(best) = best else { break };
        for j in &judged {
            if j.effect != best.effect
                && j.ok()
                && (j.evidence.delta_bic - best.evidence.delta_bic).abs()
                    <= th.tie_fraction * best.evidence.delta_bic.abs()
            {
                pending_ties.push((best.effect, j.effect));
            }
        }
        accepted.push((best.effect, best.evidence.clone()));
        remaining.retain(|x| *x != best.effect);
        current = best.fit.clone();
    }
    // Ties pending after the last round: test the other on top of the final model.
    for (winner, other) in pending_ties.drain(..) {
        if remaining.contains(&other) {
            let flags = flagged(&d, &reg, &residual(&d, &current.force), th);
            let cand = fit_candidate(&d, &current, other);
            if !judge(&d, &reg, &current, &flags, cand, other, th).ok() {
                undecided.push(Undecided {
                    effects: vec![winner.id().into(), other.id().into()],
                    why: format!(
                        "{} and {} pass every rule on their own with nearly the same criterion, \
                         and the second adds nothing once the first is in",
                        winner.id(),
                        other.id()
                    ),
                });
                undecided_effects.push(winner);
            }
        }
    }
    let findings = accepted
        .iter()
        .filter(|(e, _)| !undecided_effects.contains(e))
        .map(|(e, ev)| {
            let parameters = effect_parameters(&current, *e);
            Finding {
                effect: e.id().into(),
                explanation: explanation(*e, &parameters),
                parameters,
                evidence: ev.clone(),
            }
        })
        .collect();
    let r_final = residual(&d, &current.force);
    let rms_where = |r: &[f64], pred: &dyn Fn(usize) -> bool| {
        let (mut s, mut m) = (0.0, 0usize);
        for (j, x) in r.iter().enumerate() {
            if pred(j) {
                s += x * x;
                m += 1;
            }
        }
        (s / m.max(1) as f64).sqrt()
    };
    let mut residual_by_phase: Vec<PhaseResidual> = Phase::ALL
        .iter()
        .map(|p| PhaseResidual {
            phase: p.name().into(),
            baseline_rms_n: rms_where(&r_base, &|j| d.phase[j] == *p),
            final_rms_n: rms_where(&r_final, &|j| d.phase[j] == *p),
        })
        .collect();
    for (name, neg) in [("compression", true), ("rebound", false)] {
        residual_by_phase.push(PhaseResidual {
            phase: name.into(),
            baseline_rms_n: rms_where(&r_base, &|j| (d.v[j] < 0.0) == neg),
            final_rms_n: rms_where(&r_final, &|j| (d.v[j] < 0.0) == neg),
        });
    }
    let thresholds = BTreeMap::from([
        ("min_holdout_rmse_drop".to_string(), th.min_holdout_drop),
        ("min_holdout_paired_z".to_string(), th.min_holdout_z),
        ("max_delta_bic".to_string(), th.max_delta_bic),
        ("min_structure_drop".to_string(), th.min_structure_drop),
        ("flag_structure_ratio".to_string(), th.flag_ratio),
        ("tie_fraction_of_delta_bic".to_string(), th.tie_fraction),
    ]);
    let report = Report {
        input: input.to_string(),
        samples: d.len(),
        split: Split {
            method: d.split_method.clone(),
            train_samples: d.holdout.iter().filter(|h| !**h).count(),
            holdout_samples: d.holdout.iter().filter(|h| **h).count(),
            strokes: d.cycles,
            segments: d.segments,
            current_knots_a: d.knots.clone(),
        },
        baseline: summary(&base),
        mismatch,
        baseline_residual: residual_stats(&d, &r_base),
        findings,
        undecided,
        trials,
        final_model: summary(&current),
        final_residual: residual_stats(&d, &r_final),
        residual_by_phase,
        thresholds,
    };
    Ok(Diagnosis {
        report,
        baseline_force: base.force,
        final_force: current.force,
        final_effects: current.layout.effects.clone(),
        data: d,
    })
}
