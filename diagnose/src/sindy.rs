//! The comparison method of the study: plain sparse regression (SINDy-style sequentially
//! thresholded least squares, Brunton, Proctor & Kutz, PNAS 113(15), 2016) of the baseline
//! residual on a library of candidate terms. No held-out check, no refit of the baseline,
//! no autocorrelation handling: a term is "found" when its coefficient survives the
//! threshold.
//!
//! Library (columns scaled to unit RMS; the effect each term stands for):
//! `tanh(v/v_s)` (seal_friction), `1`, `x` (gas_spring), `a` (fluid_inertia),
//! `E(t) B` (thermal_softening), `B_lag − B` with the current lagged by 10 ms (field_lag),
//! `dB/dt` (fluid_compressibility), and generic `v`, `v|v|`, `v³` (no effect), with B the
//! fitted baseline force.

use twin::Effect;

use crate::data::Prepared;
use crate::data::{prepare, DataError, Signals};
use crate::model::{evaluate, fit_baseline, Fit};

/// Threshold on a term's contribution (coefficient × column RMS) relative to the RMS of
/// the residual.
pub const THRESHOLD: f64 = 0.05;

/// Effects whose terms survive the sequential thresholding.
pub fn sindy_effects(signals: &Signals) -> Result<Vec<Effect>, DataError> {
    let d = prepare(signals)?;
    let base = fit_baseline(&d);
    Ok(sindy_select(&d, &base))
}

/// Effects whose terms survive the sequential thresholding on the residual of `base`.
pub fn sindy_select(d: &Prepared, base: &Fit) -> Vec<Effect> {
    let lay = &base.layout;
    let b = &base.force;
    let n = d.len();
    // Baseline with a 10 ms first-order lag on the current.
    let lag_lay = lay.with(Effect::FieldLag);
    let mut th_lag = base.theta.clone();
    th_lag.push(0.01);
    let b_lag = evaluate(d, &lag_lay, &th_lag, false).force;
    let mut db = vec![0.0; n];
    for j in 1..n.saturating_sub(1) {
        db[j] = (b[j + 1] - b[j - 1]) / (d.t[j + 1] - d.t[j - 1]);
    }
    let cols: Vec<(Option<Effect>, Vec<f64>)> = vec![
        (
            Some(Effect::SealFriction),
            d.v.iter()
                .map(|v| (v / d.friction_velocity).tanh())
                .collect(),
        ),
        (Some(Effect::GasSpring), vec![1.0; n]),
        (Some(Effect::GasSpring), d.x.clone()),
        (Some(Effect::FluidInertia), d.a.clone()),
        (
            Some(Effect::ThermalSoftening),
            (0..n).map(|j| d.energy_kj[j] * b[j]).collect(),
        ),
        (
            Some(Effect::FieldLag),
            (0..n).map(|j| b_lag[j] - b[j]).collect(),
        ),
        (Some(Effect::FluidCompressibility), db),
        (None, d.v.clone()),
        (None, d.v.iter().map(|v| v * v.abs()).collect()),
        (None, d.v.iter().map(|v| v * v * v).collect()),
    ];
    let rows: Vec<usize> = (0..n).filter(|&j| d.train[j]).collect();
    let r: Vec<f64> = rows.iter().map(|&j| d.f[j] - b[j]).collect();
    let r_rms = (r.iter().map(|x| x * x).sum::<f64>() / r.len() as f64).sqrt();
    let scale: Vec<f64> = cols
        .iter()
        .map(|(_, c)| {
            let s = (rows.iter().map(|&j| c[j] * c[j]).sum::<f64>() / rows.len() as f64).sqrt();
            if s > 0.0 {
                s
            } else {
                1.0
            }
        })
        .collect();
    let mut active: Vec<bool> = scale.iter().map(|s| *s > 0.0).collect();
    let mut coef = vec![0.0; cols.len()];
    for _ in 0..10 {
        let idx: Vec<usize> = (0..cols.len()).filter(|&k| active[k]).collect();
        if idx.is_empty() {
            break;
        }
        let m = idx.len();
        let mut a = nalgebra::DMatrix::<f64>::zeros(m, m);
        let mut y = nalgebra::DVector::<f64>::zeros(m);
        for (q, &j) in rows.iter().enumerate() {
            for (p1, &k1) in idx.iter().enumerate() {
                let x1 = cols[k1].1[j] / scale[k1];
                y[p1] += x1 * r[q];
                for (p2, &k2) in idx.iter().enumerate().skip(p1) {
                    a[(p1, p2)] += x1 * cols[k2].1[j] / scale[k2];
                }
            }
        }
        for p1 in 0..m {
            for p2 in 0..p1 {
                a[(p1, p2)] = a[(p2, p1)];
            }
            a[(p1, p1)] += 1e-9 * rows.len() as f64;
        }
        let Some(sol) = a.cholesky().map(|c| c.solve(&y)) else {
            break;
        };
        coef.iter_mut().for_each(|c| *c = 0.0);
        let mut changed = false;
        for (p1, &k) in idx.iter().enumerate() {
            coef[k] = sol[p1];
            if sol[p1].abs() < THRESHOLD * r_rms {
                active[k] = false;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    let mut found: Vec<Effect> = Vec::new();
    for (k, (e, _)) in cols.iter().enumerate() {
        if let Some(e) = e {
            if active[k] && coef[k] != 0.0 && !found.contains(e) {
                found.push(*e);
            }
        }
    }
    found.sort();
    found
}
