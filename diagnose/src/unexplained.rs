//! What the final model still leaves unexplained: structure in the residual beyond noise.
//!
//! The residual is grouped several ways (signed speed × current, position × direction,
//! time, time after a current step). In each grouping the group means are tested against
//! zero with a χ² that uses the variance and the effective sample size of the residual
//! *within* the groups (n / τ_int, τ_int = 1 + 2 Σ ρ_k up to the first ρ_k < 0.05), so
//! coloured noise alone does not look like structure, and structure does not hide itself by
//! lengthening the correlation time it is judged with. A grouping is reported when its χ² exceeds
//! the 99 % critical value **and** its systematic part (the group means) holds at least
//! 3 % of the residual's mean square — a structure too small to matter is not reported
//! even when a long record makes it significant. Beside the groupings, a residual whose RMS
//! is more than 2.5 times the force channel's own high-frequency noise
//! ([`crate::measure`]) is reported as a "residual level" entry (its `chi2` is then the
//! ratio squared, against 2.5²): misfit spread over everything escapes every grouping.

use crate::data::Prepared;
use crate::report::Unexplained;
use crate::stats;

/// A residual RMS above this multiple of the force channel's high-frequency noise is
/// reported as structure (coloured force noise alone — AR(1) up to ρ = 0.8 — stays below 2).
pub const LEVEL_RATIO: f64 = 2.5;

/// Smallest share of the residual mean square a reported structure holds.
pub const MIN_SHARE: f64 = 0.03;

/// Integrated autocorrelation time of `r` (at least 1).
pub fn integrated_time(r: &[f64]) -> f64 {
    let mut tau = 1.0;
    for k in 1..=200.min(r.len() / 4) {
        let rho = stats::autocorr(r, k);
        if rho < 0.05 {
            break;
        }
        tau += 2.0 * rho;
    }
    tau
}

struct Grouping {
    name: &'static str,
    /// Group label of each sample (`None`: not in any group).
    label: Vec<Option<usize>>,
    names: Vec<String>,
}

fn speed_current(d: &Prepared) -> Grouping {
    let nk = d.knots.len();
    let mut names = Vec::new();
    for k in 0..nk {
        for dir in ["compression", "rebound"] {
            for b in 0..5 {
                names.push(format!(
                    "{dir} at {}–{} % of the stroke's peak speed, {:.2} A",
                    20 * b,
                    20 * b + 20,
                    d.knots[k]
                ));
            }
        }
    }
    let label = (0..d.len())
        .map(|j| {
            let k = nearest(&d.knots, d.i[j]);
            let dir = usize::from(d.v[j] >= 0.0);
            let b = ((d.v[j].abs() / d.stroke_speed[j].max(1e-12)) * 5.0).min(4.0) as usize;
            Some((k * 2 + dir) * 5 + b)
        })
        .collect();
    Grouping {
        name: "signed speed × current",
        label,
        names,
    }
}

fn position_direction(d: &Prepared) -> Grouping {
    let lo = d.x.iter().copied().fold(f64::INFINITY, f64::min);
    let span = (2.0 * d.half_stroke_m).max(1e-12);
    let mut names = Vec::new();
    for dir in ["compression", "rebound"] {
        for b in 0..8 {
            names.push(format!(
                "{dir} at x = {:.1}…{:.1} mm",
                1e3 * (lo + span * b as f64 / 8.0),
                1e3 * (lo + span * (b + 1) as f64 / 8.0)
            ));
        }
    }
    let label = (0..d.len())
        .map(|j| {
            let b = (((d.x[j] - lo) / span) * 8.0).min(7.0) as usize;
            Some(usize::from(d.v[j] >= 0.0) * 8 + b)
        })
        .collect();
    Grouping {
        name: "position × direction",
        label,
        names,
    }
}

fn time_tenths(d: &Prepared) -> Grouping {
    let (t0, t1) = (d.t[0], d.t[d.len() - 1]);
    let span = (t1 - t0).max(1e-12);
    let names = (0..10)
        .map(|b| {
            format!(
                "{:.1}–{:.1} s",
                t0 + span * b as f64 / 10.0,
                t0 + span * (b + 1) as f64 / 10.0
            )
        })
        .collect();
    let label =
        d.t.iter()
            .map(|t| Some((((t - t0) / span) * 10.0).min(9.0) as usize))
            .collect();
    Grouping {
        name: "time",
        label,
        names,
    }
}

/// Time after the last current step, signed by the step and the stroke direction.
// Several per-sample arrays are read with one index: a range loop is clearer.
#[allow(clippy::needless_range_loop)]
fn after_step(d: &Prepared) -> Option<Grouping> {
    let tol = crate::data::level_tolerance(&d.i);
    let edges = [0.0, 0.005, 0.015, 0.04, 0.1];
    let mut last: Option<(f64, f64)> = None;
    let mut label = vec![None; d.len()];
    let mut any = false;
    for j in 0..d.len() {
        if j > 0 && (d.i[j] - d.i[j - 1]).abs() > tol {
            last = Some((d.t[j], (d.i[j] - d.i[j - 1]).signum()));
            any = true;
        }
        if let Some((ts, sg)) = last {
            let dt = d.t[j] - ts;
            if let Some(b) = edges.windows(2).position(|w| dt >= w[0] && dt < w[1]) {
                let up = usize::from(sg * d.v[j].signum() > 0.0);
                label[j] = Some(up * 4 + b);
            }
        }
    }
    if !any {
        return None;
    }
    let mut names = Vec::new();
    for kind in ["force falling (ΔI·v < 0)", "force rising (ΔI·v > 0)"] {
        for w in edges.windows(2) {
            names.push(format!(
                "{:.0}–{:.0} ms after a current step, {kind}",
                1e3 * w[0],
                1e3 * w[1]
            ));
        }
    }
    Some(Grouping {
        name: "time after a current step",
        label,
        names,
    })
}

fn nearest(knots: &[f64], i: f64) -> usize {
    (0..knots.len())
        .min_by(|&a, &b| (knots[a] - i).abs().total_cmp(&(knots[b] - i).abs()))
        .unwrap_or(0)
}

/// Signals the residual correlates with beyond the autocorrelated 95 % band.
fn correlates(d: &Prepared, r: &[f64], n_eff: f64) -> Vec<String> {
    let step = d.current_steps();
    let sgn: Vec<f64> = d.v.iter().map(|v| v.signum()).collect();
    let band = 1.96 / n_eff.max(1.0).sqrt();
    let signals: [(&str, &[f64]); 6] = [
        ("velocity", &d.v),
        ("sign of velocity", &sgn),
        ("acceleration", &d.a),
        ("displacement", &d.x),
        ("current steps (ΔI · sgn v)", &step),
        ("dissipated energy", &d.energy_kj),
    ];
    signals
        .iter()
        .filter_map(|(name, s)| {
            let (lag, rho) = stats::max_crosscorr(r, s, -20..=20);
            (rho.abs() > band).then(|| format!("{name} (ρ = {rho:.2} at lag {lag})"))
        })
        .collect()
}

/// Structure left in the residual `r` of the final model (validation samples; stuck
/// stretches left out).
pub fn unexplained(d: &Prepared, r: &[f64]) -> Vec<Unexplained> {
    let used: Vec<usize> = (0..d.len()).filter(|&j| !d.excluded[j]).collect();
    let ru: Vec<f64> = used.iter().map(|&j| r[j]).collect();
    let n = ru.len() as f64;
    let mean = ru.iter().sum::<f64>() / n;
    let var = ru.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
    if var <= 0.0 {
        return Vec::new();
    }
    let tau = integrated_time(&ru);
    let corr = correlates(d, r, n / tau);
    let mut out = Vec::new();
    // The level: a residual far above the force channel's own (high-frequency) noise is
    // structure, even where no grouping below catches it (misfit spread over everything).
    let hf = d.measurement.force_noise_hf_n;
    if hf > 0.0 && var.sqrt() > LEVEL_RATIO * hf {
        out.push(Unexplained {
            grouping: "residual level".into(),
            concentrates_in: vec![format!(
                "everywhere: RMS {:.1} N against {:.1} N of high-frequency noise in the force \
                 channel itself",
                var.sqrt(),
                hf
            )],
            systematic_rms_n: (var - hf * hf).max(0.0).sqrt(),
            share_of_residual: (1.0 - hf * hf / var).max(0.0),
            chi2: var / (hf * hf),
            chi2_crit99: LEVEL_RATIO * LEVEL_RATIO,
            correlates_with: corr.clone(),
        });
    }
    let mut groupings = vec![speed_current(d), position_direction(d), time_tenths(d)];
    groupings.extend(after_step(d));
    for g in groupings {
        let k = g.names.len();
        let mut sum = vec![0.0; k];
        let mut cnt = vec![0usize; k];
        for &j in &used {
            if let Some(b) = g.label[j] {
                sum[b] += r[j] - mean;
                cnt[b] += 1;
            }
        }
        let groups: Vec<usize> = (0..k).filter(|&b| cnt[b] >= 20).collect();
        if groups.len() < 2 {
            continue;
        }
        // The noise's own variance and correlation time come from the residual within the
        // groups (the group means taken out): structure must not lengthen its own yardstick.
        let within: Vec<f64> = used
            .iter()
            .map(|&j| match g.label[j] {
                Some(b) if cnt[b] >= 20 => r[j] - mean - sum[b] / cnt[b] as f64,
                _ => r[j] - mean,
            })
            .collect();
        let var_w = (within.iter().map(|x| x * x).sum::<f64>() / n).max(1e-300);
        let tau_w = integrated_time(&within);
        let chi2: f64 = groups
            .iter()
            .map(|&b| (cnt[b] as f64 / tau_w) * (sum[b] / cnt[b] as f64).powi(2) / var_w)
            .sum();
        let systematic: f64 = groups
            .iter()
            .map(|&b| cnt[b] as f64 * (sum[b] / cnt[b] as f64).powi(2))
            .sum::<f64>()
            / n;
        let crit = stats::chi2_quantile(0.99, (groups.len() - 1) as f64);
        let share = systematic / var;
        if chi2 <= crit || share < MIN_SHARE {
            continue;
        }
        let mut top = groups.clone();
        top.sort_by(|&a, &b| {
            let e = |q: usize| cnt[q] as f64 * (sum[q] / cnt[q] as f64).powi(2);
            e(b).total_cmp(&e(a))
        });
        out.push(Unexplained {
            grouping: g.name.into(),
            concentrates_in: top
                .iter()
                .take(3)
                .map(|&b| {
                    format!(
                        "{}: mean residual {:+.1} N",
                        g.names[b],
                        sum[b] / cnt[b] as f64
                    )
                })
                .collect(),
            systematic_rms_n: systematic.sqrt(),
            share_of_residual: share,
            chi2,
            chi2_crit99: crit,
            correlates_with: corr.clone(),
        });
    }
    out
}
