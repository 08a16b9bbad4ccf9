//! The measurement model: what a recording's own channels say about their noise, the
//! velocity rebuilt from them, and the stretches where a channel is stuck.
//!
//! On a rig, displacement, velocity and force are all measured. The velocity is often
//! differentiated from a noisy displacement or read from a separate noisy sensor, so near
//! a stroke reversal its sign is uncertain — and the Bingham force jumps by 2 F_y there.
//! diagnose therefore
//! 1. rebuilds the velocity from both channels by local cubic least squares over a window
//!    of at most ±5 % of the local stroke period (unbiased for cubics, so the reversal is
//!    not shifted), narrowed at each sample where the displacement's slope shows that a
//!    wider window averages over faster motion (intersection of confidence intervals), and
//!    fuses the displacement's derivative and the smoothed velocity channel by their
//!    estimated error variances;
//! 2. estimates each channel's white-noise level from the residual of that local fit
//!    (`e_j² / (1 − H_jj)`, median, χ²₁ corrected: robust to the force jump and to
//!    structure), and from it the standard deviation σ_v̂ of the rebuilt velocity;
//! 3. reports stretches where a channel repeats one value (clipping, a dead sensor, a
//!    saturated amplifier), which the fit and the held-out check then leave out.
//!
//! The models (`crate::model`) predict the *expected* force under that velocity error:
//! the fluid law gets a pre-yield "leak" velocity `v_ε ≥ √(π/2) σ_v̂`, the slope the
//! sign function has at v = 0 once it is smoothed by a Gaussian velocity error
//! (d/dv E[sgn(v + e)] = √(2/π)/σ at 0).

use nalgebra::{Matrix4, Vector4};

use crate::stats::median;
use serde::Serialize;

/// √(π/2): the leak velocity that matches the slope of a Gaussian-smoothed sign at zero,
/// per unit velocity error standard deviation.
pub const LEAK_PER_SIGMA: f64 = 1.253_314_137_315_500_3;

/// Local cubic least-squares fit at every sample.
#[derive(Debug, Clone, Default)]
struct LocalFit {
    /// Fitted value at the sample.
    value: Vec<f64>,
    /// Fitted first derivative at the sample.
    slope: Vec<f64>,
    /// Leverage H_jj of the sample on its own fitted value.
    leverage: Vec<f64>,
    /// Σ of squared weights of the derivative estimate (its variance per unit noise variance).
    slope_gain: Vec<f64>,
}

/// Slope of `y` at sample j where a window is too short for a cubic: the forward
/// difference, the backward one at the end of the run `(a, b)`, 0 in a run of one sample.
fn one_sided_slope(t: &[f64], y: &[f64], j: usize, (a, b): (usize, usize)) -> f64 {
    if j + 1 < b {
        (y[j + 1] - y[j]) / (t[j + 1] - t[j])
    } else if j > a {
        (y[j] - y[j - 1]) / (t[j] - t[j - 1])
    } else {
        0.0
    }
}

/// Local cubic fit of `y(t)` over ±`half[j]` samples around each sample j, windows cut at
/// time gaps (`run` lists the gap-free runs as half-open index ranges).
fn local_cubic(t: &[f64], y: &[f64], half: &[usize], run: &[(usize, usize)]) -> LocalFit {
    let n = t.len();
    let mut out = LocalFit {
        value: vec![0.0; n],
        slope: vec![0.0; n],
        leverage: vec![1.0; n],
        slope_gain: vec![f64::INFINITY; n],
    };
    for &(a, b) in run {
        for j in a..b {
            let lo = j.saturating_sub(half[j]).max(a);
            let hi = (j + half[j] + 1).min(b);
            if hi - lo < 5 {
                out.value[j] = y[j];
                out.slope[j] = one_sided_slope(t, y, j, (a, b));
                continue;
            }
            let scale = (t[hi - 1] - t[lo]).max(1e-12);
            let mut m = Matrix4::<f64>::zeros();
            let mut r = Vector4::<f64>::zeros();
            for k in lo..hi {
                let s = (t[k] - t[j]) / scale;
                let bv = Vector4::new(1.0, s, s * s, s * s * s);
                m += bv * bv.transpose();
                r += bv * y[k];
            }
            let Some(inv) = m.try_inverse() else {
                out.value[j] = y[j];
                continue;
            };
            let beta = inv * r;
            out.value[j] = beta[0];
            out.slope[j] = beta[1] / scale;
            out.leverage[j] = inv[(0, 0)];
            out.slope_gain[j] = inv[(1, 1)] / (scale * scale);
        }
    }
    out
}

/// Candidate half-widths of the adaptive local cubic windows \[samples\] (about ×1.25 apart).
const HALF_WIDTH_GRID: [usize; 19] = [
    3, 4, 5, 6, 8, 10, 12, 15, 19, 24, 30, 38, 48, 60, 75, 95, 120, 150, 190,
];

/// Threshold of the intersection-of-confidence-intervals rule, in standard deviations.
/// 3.5 on the proving ground: 2.0 and 2.5 took windows narrower than the MSE-optimal ones
/// on records whose old windows were right (seed 0: velocity error 2.5 → 3.9·10⁻⁴ m/s at
/// 2.5), 3.5 and 5 kept those within 2 % and cut the error 3–8× where the old windows
/// averaged over faster motion (seeds 22, 30, 44, 50).
const ICI_GAMMA: f64 = 3.5;

/// Local cubic fit of `y(t)` whose half-width at every sample is chosen for its slope by
/// the intersection-of-confidence-intervals rule (Goldenshluger & Nemirovski 1997;
/// Katkovnik 1999): the windows grow along [`HALF_WIDTH_GRID`] up to `cap[j]` (that
/// included), and the widest one is kept whose slope still lies, with ±[`ICI_GAMMA`] of its
/// noise standard deviation, in the intersection of the narrower windows' intervals. A
/// window that averages over faster motion than a cubic follows moves its slope by more
/// than its noise and is not taken; over slow motion the widest window is. `sigma` is the
/// channel's white-noise σ. Returns the fit and the chosen half-widths.
fn local_cubic_adaptive_slope(
    t: &[f64],
    y: &[f64],
    cap: &[usize],
    run: &[(usize, usize)],
    sigma: f64,
) -> (LocalFit, Vec<usize>) {
    let n = t.len();
    let mut out = LocalFit {
        value: y.to_vec(),
        slope: vec![0.0; n],
        leverage: vec![1.0; n],
        slope_gain: vec![f64::INFINITY; n],
    };
    let mut chosen = vec![0usize; n];
    for &(a, b) in run {
        let span = if b > a + 1 {
            (t[b - 1] - t[a]) / (b - a - 1) as f64
        } else {
            1.0
        };
        for j in a..b {
            // Moments of the window in units of the run's mean step (u = (t_k − t_j)/span),
            // grown one sample at a time on each side.
            let mut m = Matrix4::<f64>::zeros();
            let mut r = Vector4::<f64>::zeros();
            let add = |k: usize, m: &mut Matrix4<f64>, r: &mut Vector4<f64>| {
                let u = (t[k] - t[j]) / span;
                let bv = Vector4::new(1.0, u, u * u, u * u * u);
                *m += bv * bv.transpose();
                *r += bv * y[k];
            };
            add(j, &mut m, &mut r);
            let (mut lo, mut hi) = (j, j + 1);
            let (mut low, mut high) = (f64::NEG_INFINITY, f64::INFINITY);
            let mut best: Option<(f64, f64, f64, f64, usize)> = None;
            let widest = cap[j].max(3);
            let widths = HALF_WIDTH_GRID
                .iter()
                .copied()
                .filter(|hw| *hw < widest)
                .chain(std::iter::once(widest));
            for hw in widths {
                let (lo_new, hi_new) = (j.saturating_sub(hw).max(a), (j + hw + 1).min(b));
                if lo_new == lo && hi_new == hi && best.is_some() {
                    break;
                }
                while lo > lo_new {
                    lo -= 1;
                    add(lo, &mut m, &mut r);
                }
                while hi < hi_new {
                    add(hi, &mut m, &mut r);
                    hi += 1;
                }
                if hi - lo < 5 {
                    continue;
                }
                // Scaled to s = u / hw so that the normal matrix is well conditioned.
                let d = Matrix4::from_diagonal(&Vector4::new(
                    1.0,
                    1.0 / hw as f64,
                    1.0 / (hw * hw) as f64,
                    1.0 / (hw * hw * hw) as f64,
                ));
                let Some(inv) = (d * m * d).try_inverse() else {
                    break;
                };
                let beta = inv * (d * r);
                let to_time = 1.0 / (hw as f64 * span);
                let fit = (
                    beta[0],
                    beta[1] * to_time,
                    inv[(0, 0)],
                    inv[(1, 1)] * to_time * to_time,
                    hw,
                );
                let half_band = ICI_GAMMA * sigma * fit.3.max(0.0).sqrt();
                low = low.max(fit.1 - half_band);
                high = high.min(fit.1 + half_band);
                if best.is_some() && low > high {
                    break;
                }
                best = Some(fit);
            }
            if let Some((value, slope, leverage, slope_gain, hw)) = best {
                out.value[j] = value;
                out.slope[j] = slope;
                out.leverage[j] = leverage;
                out.slope_gain[j] = slope_gain;
                chosen[j] = hw;
            } else {
                out.slope[j] = one_sided_slope(t, y, j, (a, b));
            }
        }
    }
    (out, chosen)
}

/// White-noise standard deviation of a channel from its local-fit residuals (robust).
fn noise_sigma(y: &[f64], fit: &LocalFit) -> f64 {
    let z: Vec<f64> = y
        .iter()
        .zip(&fit.value)
        .zip(&fit.leverage)
        .filter(|(_, h)| **h < 0.95)
        .map(|((a, b), h)| (a - b).powi(2) / (1.0 - h))
        .collect();
    // Median of χ²₁ is 0.4549.
    (median(z) / 0.454_936_4).sqrt()
}

/// White-noise σ of a series from its residuals about local cubics over ±3 samples
/// ([`noise_sigma`]), `runs` its contiguous stretches.
fn white_noise_sigma(t: &[f64], y: &[f64], runs: &[(usize, usize)]) -> f64 {
    noise_sigma(y, &local_cubic(t, y, &vec![3; t.len()], runs))
}

/// White-noise σ of a model's force residual `r` (`h[j]` the step to the previous sample,
/// 0 at a gap), by the force channel's own estimator ([`measure`]).
///
/// The force channel's estimate takes for noise whatever a cubic over ±3 samples cannot
/// follow. Sampled slowly, that is force: at 200 Hz a random current moves the yield force
/// and a stroke turns within 7 samples, and on the proving ground's random-current records
/// at 200 Hz the channel's estimate was a median 1.43 × the generator's σ_F (up to 4.8 ×;
/// medians of 0.8–1.0 × from 1 kHz up). The residual of a fitted model has that force
/// taken out.
pub fn residual_white_noise_sigma(t: &[f64], r: &[f64], h: &[f64]) -> f64 {
    white_noise_sigma(t, r, &contiguous_runs(h))
}

/// A stretch where one channel holds exactly one value (clipped or stuck).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FlatStretch {
    /// Channel name (CSV column).
    pub channel: String,
    /// First and last time of the stretch \[s\].
    pub start_s: f64,
    /// Last time \[s\].
    pub end_s: f64,
    /// Samples in the stretch.
    pub samples: usize,
    /// The value the channel is stuck at.
    pub value: f64,
}

/// What the measurement model found in a recording.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MeasurementSummary {
    /// Median sample interval \[s\].
    pub sample_interval_s: f64,
    /// Typical stroke period (twice the median time between displacement reversals) \[s\].
    pub stroke_period_s: f64,
    /// Median half-width of the local cubic window \[samples\] (at most 5 % of the local
    /// stroke period, 3–400 samples; narrower where the motion is faster than a cubic over
    /// that window).
    pub window_half_samples: usize,
    /// White-noise σ of the displacement channel \[m\].
    pub displacement_noise_m: f64,
    /// White-noise σ of the velocity channel \[m/s\] (`null` when it was derived).
    pub velocity_noise_m_s: Option<f64>,
    /// σ of the rebuilt velocity \[m/s\].
    pub rebuilt_velocity_sigma_m_s: f64,
    /// The velocity error's scale κ against `rebuilt_velocity_sigma_m_s` that the force
    /// channel shows near reversal (`crate::model::velocity_error_scale`; 1 before the
    /// baseline is fitted): the sample weights take the velocity error as κ σ_v̂.
    pub velocity_error_scale: f64,
    /// High-frequency (white) part of the force noise \[N\]: from the force channel alone,
    /// or from the settled baseline's residual where that is lower
    /// ([`residual_white_noise_sigma`]).
    pub force_noise_hf_n: f64,
    /// Whether the velocity column was derived from displacement by the reader.
    pub velocity_derived: bool,
    /// Channels stuck at one value, left out of fitting and validation.
    pub flat_stretches: Vec<FlatStretch>,
    /// Samples left out for them.
    pub excluded_samples: usize,
    /// Samples left out at the ends of the record and of each segment between gaps: the
    /// first and last local window (`window_half_samples` there), where a rig's
    /// differentiated velocity and the rebuilt one are one-sided. A rod stopping at the end
    /// of a record holds its force in the plug while a one-sided derivative gives its
    /// velocity either sign (proving-ground seeds 20 and 21: 3–5 samples off by 280–390
    /// σ_F were most of the held-out error).
    pub edge_samples: usize,
    /// The anti-alias filter fitted with the baseline (`null`: none fits better).
    pub anti_alias: Option<crate::antialias::AntiAlias>,
    /// The current channel's plateaus and steps ([`crate::current`]).
    pub current: Option<crate::current::CurrentSummary>,
}

/// The measurement model applied to one recording.
#[derive(Debug, Clone)]
pub struct Measured {
    /// Rebuilt velocity \[m/s\].
    pub v: Vec<f64>,
    /// Acceleration from the rebuilt velocity \[m/s²\].
    pub a: Vec<f64>,
    /// Standard deviation of the rebuilt velocity's error at each sample \[m/s\].
    pub v_sigma: Vec<f64>,
    /// Samples left out (a channel stuck, with a margin of 2 samples; the first and last
    /// local window of the record and of each segment).
    pub excluded: Vec<bool>,
    /// The summary for the report.
    pub summary: MeasurementSummary,
}

/// Stroke reversals: the extrema of the displacement, found with a hysteresis of 2 % of
/// its range (the displacement is the cleanest channel; a noisy velocity would cross zero
/// many times at each reversal).
fn reversals(x: &[f64]) -> Vec<usize> {
    let lo = x.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let hyst = 0.02 * (hi - lo);
    let mut marks = Vec::new();
    let (mut max_k, mut min_k) = (0usize, 0usize);
    let mut dir = 0i8;
    for k in 1..x.len() {
        if x[k] > x[max_k] {
            max_k = k;
        }
        if x[k] < x[min_k] {
            min_k = k;
        }
        if dir >= 0 && x[max_k] - x[k] > hyst {
            if dir > 0 {
                marks.push(max_k);
            }
            dir = -1;
            min_k = k;
        } else if dir <= 0 && x[k] - x[min_k] > hyst {
            if dir < 0 {
                marks.push(min_k);
            }
            dir = 1;
            max_k = k;
        }
    }
    marks
}

/// Local stroke period at every sample: twice the time between the displacement reversals
/// around it; `typical` before the first and after the last reversal.
fn local_periods(t: &[f64], marks: &[usize], typical: f64) -> Vec<f64> {
    let mut out = vec![typical; t.len()];
    for w in marks.windows(2) {
        let p = (2.0 * (t[w[1]] - t[w[0]])).min(4.0 * typical);
        for o in out.iter_mut().take(w[1]).skip(w[0]) {
            *o = p;
        }
    }
    out
}

/// Typical stroke period: twice the median time between displacement reversals; the
/// record's span when it has fewer than three reversals.
fn stroke_period(t: &[f64], marks: &[usize]) -> f64 {
    let span = t[t.len() - 1] - t[0];
    let gaps: Vec<f64> = marks.windows(2).map(|w| t[w[1]] - t[w[0]]).collect();
    if gaps.len() < 2 {
        span
    } else {
        (2.0 * median(gaps)).min(span)
    }
}

/// The runs of contiguous samples `(start, end)`: a new run begins at every gap (`h[j] = 0`).
fn contiguous_runs(h: &[f64]) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    if h.is_empty() {
        return runs;
    }
    let mut a = 0;
    for (j, &step) in h.iter().enumerate().skip(1) {
        if step == 0.0 {
            runs.push((a, j));
            a = j;
        }
    }
    runs.push((a, h.len()));
    runs
}

/// The velocity used, and its standard error per sample: the displacement's local-cubic
/// slope (`fx`, error variance `var_vx`), fused with the measured velocity channel when
/// there is one (its local cubic over the same `chosen` windows, inverse-variance
/// weighted). Returns (v̂, σ_v̂, and the velocity channel's own noise σ when measured).
fn rebuilt_velocity(
    t: &[f64],
    v: &[f64],
    fx: &LocalFit,
    var_vx: &[f64],
    chosen: &[usize],
    runs: &[(usize, usize)],
    velocity_derived: bool,
) -> (Vec<f64>, Vec<f64>, Option<f64>) {
    if velocity_derived {
        let v_sigma = var_vx.iter().map(|&vx| standard_error(vx)).collect();
        return (fx.slope.clone(), v_sigma, None);
    }
    let fv = local_cubic(t, v, chosen, runs);
    let sv = noise_sigma(v, &fv);
    // Per sample: the displacement slope's error variance vx and the channel's vv.
    let (fused, v_sigma) = (0..t.len())
        .map(|j| {
            let vx = var_vx[j];
            let vv = sv * sv * fv.leverage[j];
            let value = if vv <= 0.0 || !vx.is_finite() {
                fv.value[j]
            } else if vx <= 0.0 {
                fx.slope[j]
            } else {
                (fx.slope[j] / vx + fv.value[j] / vv) / (1.0 / vx + 1.0 / vv)
            };
            let v_var = if vx.is_finite() && vx > 0.0 && vv > 0.0 {
                1.0 / (1.0 / vx + 1.0 / vv)
            } else if vv > 0.0 {
                vv
            } else {
                vx
            };
            (value, standard_error(v_var))
        })
        .unzip();
    (fused, v_sigma, Some(sv))
}

/// √variance, 0 where the variance is not finite (no estimate).
fn standard_error(var: f64) -> f64 {
    if var.is_finite() {
        var.max(0.0).sqrt()
    } else {
        0.0
    }
}

/// Flat (stuck) stretches of displacement, force and, when measured, velocity: each as
/// `(start, end, stretch)`.
fn flat_stretches(
    t: &[f64],
    dt: f64,
    (x, f, v): (&[f64], &[f64], &[f64]),
    velocity_derived: bool,
) -> Vec<(usize, usize, FlatStretch)> {
    let mut channels = vec![("displacement_m", x), ("force_N", f)];
    if !velocity_derived {
        channels.push(("velocity_m_s", v));
    }
    let values: Vec<&[f64]> = channels.iter().map(|c| c.1).collect();
    numerics::signal::stuck_runs(dt, &values)
        .into_iter()
        .map(|(k, r)| {
            let (channel, y) = channels[k];
            let stretch = FlatStretch {
                channel: channel.to_string(),
                start_s: t[r.start],
                end_s: t[r.end - 1],
                samples: r.len(),
                value: y[r.start],
            };
            (r.start, r.end, stretch)
        })
        .collect()
}

/// The samples left out: each flat stretch with 2 samples either side, then the ends of
/// every run (`half` samples each, one local window, where the velocity is one-sided).
/// Returns the mask, the samples left out for flat stretches and those for the ends.
fn excluded_samples(
    n: usize,
    flats: &[(usize, usize, FlatStretch)],
    runs: &[(usize, usize)],
    half: &[usize],
) -> (Vec<bool>, usize, usize) {
    let mut excluded = vec![false; n];
    for (a, b, _) in flats {
        for e in excluded
            .iter_mut()
            .take((*b + 2).min(n))
            .skip(a.saturating_sub(2))
        {
            *e = true;
        }
    }
    let flat_samples = excluded.iter().filter(|e| **e).count();
    let mut edge_samples = 0;
    for &(a, b) in runs {
        if b <= a {
            continue;
        }
        let ends = (a..(a + half[a]).min(b)).chain(b.saturating_sub(half[b - 1]).max(a)..b);
        for j in ends {
            if !excluded[j] {
                excluded[j] = true;
                edge_samples += 1;
            }
        }
    }
    (excluded, flat_samples, edge_samples)
}

/// Apply the measurement model. `h[j]` is the step to the previous sample (0 at a gap).
pub fn measure(
    t: &[f64],
    x: &[f64],
    v: &[f64],
    f: &[f64],
    h: &[f64],
    velocity_derived: bool,
) -> Measured {
    let n = t.len();
    let dts: Vec<f64> = h.iter().copied().filter(|d| *d > 0.0).collect();
    let dt = if dts.is_empty() { 1e-3 } else { median(dts) };
    let runs = contiguous_runs(h);
    let marks = reversals(x);
    let period = stroke_period(t, &marks);
    let half: Vec<usize> = local_periods(t, &marks, period)
        .iter()
        .map(|p| ((0.05 * p / dt).round() as usize).clamp(3, 400))
        .collect();
    // Noise levels from short windows (a cubic follows any well-sampled motion over ±6
    // samples); the smoothing windows are then chosen per sample against them.
    let short_noise: Vec<usize> = half.iter().map(|h| (*h).min(6)).collect();
    let sx = noise_sigma(x, &local_cubic(t, x, &short_noise, &runs));
    let (fx, chosen) = local_cubic_adaptive_slope(t, x, &half, &runs, sx);
    let var_vx: Vec<f64> = fx.slope_gain.iter().map(|g| sx * sx * g).collect();
    let (v_hat, v_sigma, velocity_noise) =
        rebuilt_velocity(t, v, &fx, &var_vx, &chosen, &runs, velocity_derived);
    let sigma_v_hat = median(v_sigma.clone());
    let fa = local_cubic(t, &v_hat, &chosen, &runs);
    let force_noise = white_noise_sigma(t, f, &runs);
    let flats = flat_stretches(t, dt, (x, f, v), velocity_derived);
    let (excluded, excluded_samples, edge_samples) = excluded_samples(n, &flats, &runs, &half);
    let summary = MeasurementSummary {
        sample_interval_s: dt,
        stroke_period_s: period,
        window_half_samples: median(chosen.iter().map(|h| *h as f64).collect()) as usize,
        displacement_noise_m: sx,
        velocity_noise_m_s: velocity_noise,
        rebuilt_velocity_sigma_m_s: sigma_v_hat,
        velocity_error_scale: 1.0,
        force_noise_hf_n: force_noise,
        velocity_derived,
        flat_stretches: flats.into_iter().map(|x| x.2).collect(),
        excluded_samples,
        edge_samples,
        anti_alias: None,
        current: None,
    };
    Measured {
        v: v_hat,
        a: fa.slope,
        v_sigma,
        excluded,
        summary,
    }
}

/// The error function (Abramowitz & Stegun 7.1.26, |error| < 1.5e-7).
pub fn erf(x: f64) -> f64 {
    let s = x.signum();
    let x = x.abs();
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let y = 1.0
        - (((((1.061_405_429 * t - 1.453_152_027) * t) + 1.421_413_741) * t - 0.284_496_736) * t
            + 0.254_829_592)
            * t
            * (-x * x).exp();
    s * y
}

/// Nodes and weights of 9-point Gauss–Hermite quadrature (probabilists' form: ∫ g(x) φ(x)
/// dx ≈ Σ w_k g(x_k) for the standard normal density φ).
pub(crate) const HERMITE9: [(f64, f64); 9] = [
    (-4.512_745_863_399_783, 2.234_584_400_774_66e-5),
    (-3.205_429_002_856_47, 2.789_141_321_231_77e-3),
    (-2.076_847_978_677_83, 4.991_640_676_521_79e-2),
    (-1.023_255_663_789_13, 2.440_975_028_949_39e-1),
    (0.0, 4.063_492_063_492_06e-1),
    (1.023_255_663_789_13, 2.440_975_028_949_39e-1),
    (2.076_847_978_677_83, 4.991_640_676_521_79e-2),
    (3.205_429_002_856_47, 2.789_141_321_231_77e-3),
    (4.512_745_863_399_783, 2.234_584_400_774_66e-5),
];

/// Variance of `g(v + e)`, e ~ N(0, σ²): how much of the force is unpredictable because
/// the velocity is (Gauss–Hermite quadrature; exact where g is smooth, a smoothed jump
/// otherwise).
pub fn variance_under_velocity_error(g: impl Fn(f64) -> f64, v: f64, sigma: f64) -> f64 {
    if sigma <= 0.0 {
        return 0.0;
    }
    hermite_variance(|x| g(v + sigma * x))
}

/// Variance of `y(z)`, z ~ N(0, 1), by [`HERMITE9`]: `y` is called once at each node, in
/// order.
pub(crate) fn hermite_variance(mut y: impl FnMut(f64) -> f64) -> f64 {
    let (mut m1, mut m2) = (0.0, 0.0);
    for (x, w) in HERMITE9 {
        let y = y(x);
        m1 += w * y;
        m2 += w * y * y;
    }
    (m2 - m1 * m1).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn noise_levels_and_velocity_error_are_recovered() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let nx = Normal::new(0.0, 5e-6).unwrap();
        let nv = Normal::new(0.0, 2e-3).unwrap();
        let nf = Normal::new(0.0, 10.0).unwrap();
        let dt = 1e-3;
        let w = 2.0 * std::f64::consts::PI * 2.0;
        let n = 8000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        let xt: Vec<f64> = t.iter().map(|t| 0.01 * (w * t).sin()).collect();
        let vt: Vec<f64> = t.iter().map(|t| 0.01 * w * (w * t).cos()).collect();
        let x: Vec<f64> = xt.iter().map(|x| x + nx.sample(&mut rng)).collect();
        let v: Vec<f64> = vt.iter().map(|v| v + nv.sample(&mut rng)).collect();
        let f: Vec<f64> = vt
            .iter()
            .map(|v| 500.0 * v.signum() + 2000.0 * v + nf.sample(&mut rng))
            .collect();
        let mut h = vec![dt; n];
        h[0] = 0.0;
        let m = measure(&t, &x, &v, &f, &h, false);
        let s = &m.summary;
        assert!((s.displacement_noise_m / 5e-6 - 1.0).abs() < 0.1, "{s:?}");
        let sv = s.velocity_noise_m_s.unwrap();
        assert!((sv / 2e-3 - 1.0).abs() < 0.1, "{s:?}");
        // The force jump at reversals does not inflate the robust force-noise estimate much.
        assert!((s.force_noise_hf_n / 10.0 - 1.0).abs() < 0.15, "{s:?}");
        // The stated σ of the rebuilt velocity matches its actual error within 25 %.
        let err: f64 = (100..n - 100)
            .map(|j| (m.v[j] - vt[j]).powi(2))
            .sum::<f64>()
            / (n - 200) as f64;
        let ratio = err.sqrt() / s.rebuilt_velocity_sigma_m_s;
        assert!(
            (0.75..1.25).contains(&ratio),
            "actual/stated {ratio}, {s:?}"
        );
        assert!(
            err.sqrt() < 0.5 * sv,
            "rebuilding must beat the raw channel"
        );
        assert!((s.stroke_period_s - 0.5).abs() < 0.01);
        assert_eq!(s.excluded_samples, 0);
    }

    #[test]
    fn a_fast_small_motion_inside_a_slow_stroke_narrows_the_window() {
        // A slow 0.2 Hz stroke carrying a 4 Hz wiggle below the reversal hysteresis: the
        // stroke period says ±250 samples, over which a cubic cannot follow the wiggle.
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let nx = Normal::new(0.0, 2e-6).unwrap();
        let dt = 1e-3;
        let (w0, w1) = (
            2.0 * std::f64::consts::PI * 0.2,
            2.0 * std::f64::consts::PI * 4.0,
        );
        let n = 20_000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        let xt = |t: f64| 0.01 * (w0 * t).sin() + 2e-4 * (w1 * t).sin();
        let vt = |t: f64| 0.01 * w0 * (w0 * t).cos() + 2e-4 * w1 * (w1 * t).cos();
        let x: Vec<f64> = t.iter().map(|t| xt(*t) + nx.sample(&mut rng)).collect();
        let v: Vec<f64> = t.iter().map(|t| vt(*t)).collect();
        let f: Vec<f64> = v
            .iter()
            .map(|v| 1e4 * v + nx.sample(&mut rng) * 1e6)
            .collect();
        let mut h = vec![dt; n];
        h[0] = 0.0;
        let m = measure(&t, &x, &v, &f, &h, true);
        let s = &m.summary;
        assert!((s.stroke_period_s - 5.0).abs() < 0.3, "{s:?}");
        assert!(s.window_half_samples < 150, "{s:?}");
        let inner = 400..n - 400;
        let err = (inner.clone().map(|j| (m.v[j] - v[j]).powi(2)).sum::<f64>()
            / inner.len() as f64)
            .sqrt();
        // The 4 Hz part is 5 mm/s; the stroke period's ±250-sample cubic loses most of it.
        let fixed = local_cubic(&t, &x, &vec![250; n], &[(0, n)]);
        let err_fixed = (inner
            .clone()
            .map(|j| (fixed.slope[j] - v[j]).powi(2))
            .sum::<f64>()
            / inner.len() as f64)
            .sqrt();
        assert!(err_fixed > 1e-3, "fixed window error {err_fixed} m/s");
        assert!(err < 0.1 * err_fixed, "velocity error {err} m/s, {s:?}");
    }

    #[test]
    fn erf_and_the_variance_of_a_jump_under_velocity_error() {
        assert!((erf(0.5) - 0.520_499_877_8).abs() < 2e-7);
        assert!((erf(-1.5) + 0.966_105_146_5).abs() < 2e-7);
        // Var of a smooth line: slope² σ².
        let v = variance_under_velocity_error(|x| 3.0 * x, 0.2, 0.1);
        assert!((v - 0.09).abs() < 1e-9);
        // A jump ±1 at v = 0 far from the sample: no variance; at the jump: about 1.
        assert!(variance_under_velocity_error(f64::signum, 10.0, 1.0) < 1e-6);
        assert!(variance_under_velocity_error(f64::signum, 0.0, 1.0) > 0.5);
    }

    #[test]
    fn a_clipped_force_channel_is_found_and_left_out() {
        let n = 3000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let x: Vec<f64> = t.iter().map(|t| 0.01 * (6.0 * t).sin()).collect();
        let v: Vec<f64> = t.iter().map(|t| 0.06 * (6.0 * t).cos()).collect();
        let mut f: Vec<f64> = v.iter().map(|v| 1e4 * v).collect();
        for y in f.iter_mut().skip(2927) {
            *y = 4545.4545;
        }
        let mut h = vec![1e-3; n];
        h[0] = 0.0;
        let m = measure(&t, &x, &v, &f, &h, false);
        let fl = &m.summary.flat_stretches;
        assert_eq!(fl.len(), 1, "{fl:?}");
        assert_eq!(fl[0].channel, "force_N");
        assert_eq!(fl[0].samples, 73);
        assert!((fl[0].start_s - 2.927).abs() < 1e-9);
        assert!(m.excluded[2926] && m.excluded[2999] && !m.excluded[2900]);
    }
}
