//! The rig's anti-alias filter, seen in the force channel.
//!
//! A data-acquisition front end low-pass filters every channel before sampling. On the
//! smooth channels (displacement, velocity) the filter is, well below its cut-off, a pure
//! delay τ_g; but the damper force is a *nonlinear* function of velocity that jumps by
//! 2 F_y at a stroke reversal, and the recorded force is the filtered jump — a smeared,
//! overshooting step — not the law evaluated at the filtered velocity. On the proving
//! ground this difference alone is 2–17 σ_F on null records (docs/diagnose.md §1).
//!
//! So every model's force is passed through the same filter before it is compared with
//! the measurement: with u(t) = F_model(v_meas(t)) and v_meas(t) = v(t − τ_g),
//! `F_meas(t) = H[F_model(v)](t) = (H u)(t + τ_g)`: filter the model's force, then advance
//! it by the filter's low-frequency group delay. H is a unit-gain second-order Butterworth
//! low-pass (the usual analog front end), discretised by the bilinear transform with
//! pre-warping. Its cut-off is read from the current channel's steps, the filter's own
//! step response seen through the same front end
//! ([`crate::current::ConditionedCurrent::front_end_cutoff_hz`]), where they show it;
//! otherwise it is fitted with the baseline from a grid of fractions of the sample rate,
//! "no filter" included ([`crate::select`]).

use serde::Serialize;

use crate::subsample::SubGrid;

/// The filter over the m fine steps of an interval whose inputs are linear between its
/// ends. At an interval's start the filter's last input x[k-1] is always the interval's
/// first value y_start (a run starts from steady state at it; an interval ends on its
/// last value), so the state is (x[k-2], z[k-1], z[k-2]) and the maps act on
/// u = (x[k-2], z[k-1], z[k-2], y_start, y_end): the read at fine step se (between steps
/// se − 1 and se), z[k-1] and z[k-2] after the interval, and x[k-2] after it, which
/// depends on the two ends only.
struct LinearInterval {
    read: [f64; 5],
    z1: [f64; 5],
    z2: [f64; 5],
    x2: [f64; 2],
}

impl LinearInterval {
    fn new(b: [f64; 3], a1: f64, a2: f64, m: usize, se: usize, frac: f64) -> Self {
        // Responses to the six unit inputs (x[k-1], x[k-2], z[k-1], z[k-2], y_start, y_end).
        let mut read = [0.0; 6];
        let mut after = [[0.0; 6]; 4];
        for i in 0..6 {
            let mut u = [0.0; 6];
            u[i] = 1.0;
            let [mut x1, mut x2, mut z1, mut z2, ya, yb] = u;
            for s in 1..=m {
                let w = s as f64 / m as f64;
                let x0 = (1.0 - w) * ya + w * yb;
                let o = b[0] * x0 + b[1] * x1 + b[2] * x2 - a1 * z1 - a2 * z2;
                if s == se {
                    read[i] = (1.0 - frac) * z1 + frac * o;
                }
                (x2, x1, z2, z1) = (x1, x0, z1, o);
            }
            for (row, v) in after.iter_mut().zip([x1, x2, z1, z2]) {
                row[i] = v;
            }
        }
        // x[k-1] = y_start: its column joins y_start's.
        let fold = |w: [f64; 6]| [w[1], w[2], w[3], w[0] + w[4], w[5]];
        let x2 = fold(after[1]);
        LinearInterval {
            read: fold(read),
            z1: fold(after[2]),
            z2: fold(after[3]),
            x2: [x2[3], x2[4]],
        }
    }
}

/// A unit-DC-gain second-order Butterworth low-pass applied to model outputs, followed by
/// an advance of its DC group delay.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AntiAlias {
    /// Cut-off frequency \[Hz\].
    pub cutoff_hz: f64,
    /// Cut-off as a fraction of the sample rate.
    pub cutoff_per_fs: f64,
    /// Group delay at low frequency, advanced back \[samples\].
    pub delay_samples: f64,
    /// Where the cut-off came from.
    pub source: CutoffSource,
    #[serde(skip)]
    b0: f64,
    #[serde(skip)]
    a1: f64,
    #[serde(skip)]
    a2: f64,
}

/// Where a filter's cut-off came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CutoffSource {
    /// Read from the current channel's steps ([`crate::current::ConditionedCurrent::front_end_cutoff_hz`]).
    CurrentSteps,
    /// Fitted with the baseline to the force, from [`CUTOFF_GRID`].
    ForceFit,
}

/// Cut-off fractions of the sample rate tried for the anti-alias filter (besides none).
pub const CUTOFF_GRID: [f64; 7] = [0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45];

impl AntiAlias {
    /// Second-order Butterworth at `cutoff_per_fs` × the sample rate `1/dt` (bilinear
    /// transform, pre-warped so the cut-off is exact).
    pub fn butterworth2(cutoff_per_fs: f64, dt: f64) -> Self {
        let k = (std::f64::consts::PI * cutoff_per_fs).tan();
        let norm = 1.0 / (1.0 + std::f64::consts::SQRT_2 * k + k * k);
        let b0 = k * k * norm;
        let a1 = 2.0 * (k * k - 1.0) * norm;
        let a2 = (1.0 - std::f64::consts::SQRT_2 * k + k * k) * norm;
        // DC group delay of B(z)/A(z): Σ n b_n / Σ b_n − Σ n a_n / Σ a_n, with B = b0 (1, 2, 1).
        let delay = 1.0 - (a1 + 2.0 * a2) / (1.0 + a1 + a2);
        AntiAlias {
            cutoff_hz: cutoff_per_fs / dt,
            cutoff_per_fs,
            delay_samples: delay,
            source: CutoffSource::ForceFit,
            b0,
            a1,
            a2,
        }
    }

    /// The same filter, its cut-off read from the current channel's steps.
    pub fn from_current_steps(self) -> Self {
        AntiAlias {
            source: CutoffSource::CurrentSteps,
            ..self
        }
    }

    /// Filter and advance, in place, the `cols` columns of the row-major `n × cols` matrix
    /// `y` (n = `h.len()`). Each contiguous run (a new one where `h` is 0: the start and
    /// every time gap) starts from the filter's steady state at its first value. A column
    /// that has fallen back to exact zeros gets exact zeros again once its filter tail is
    /// below 1e-12 of the column's largest input, so a sparse Jacobian stays sparse.
    pub fn apply(&self, h: &[f64], y: &mut [f64], cols: usize) {
        let n = h.len();
        debug_assert_eq!(y.len(), n * cols);
        let mut z = vec![0.0; y.len()];
        let b = [self.b0, 2.0 * self.b0, self.b0];
        // Per column: x[n-1], x[n-2], z[n-1], z[n-2], largest |x| so far.
        let mut st = vec![[0.0f64; 5]; cols];
        let mut start = 0;
        while start < n {
            let mut end = start + 1;
            while end < n && h[end] > 0.0 {
                end += 1;
            }
            for (c, s) in st.iter_mut().enumerate() {
                let y0 = y[start * cols + c];
                *s = [y0, y0, y0, y0, y0.abs()];
            }
            for j in start..end {
                let (row, out_row) = (
                    &y[j * cols..(j + 1) * cols],
                    &mut z[j * cols..(j + 1) * cols],
                );
                for ((&x0, out), s) in row.iter().zip(out_row.iter_mut()).zip(st.iter_mut()) {
                    let [x1, x2, z1, z2, peak] = *s;
                    let mut o = b[0] * x0 + b[1] * x1 + b[2] * x2 - self.a1 * z1 - self.a2 * z2;
                    let peak = peak.max(x0.abs());
                    if x0 == 0.0 && x1 == 0.0 && x2 == 0.0 && o.abs() <= 1e-12 * peak {
                        o = 0.0;
                    }
                    *out = o;
                    *s = [x0, x1, o, z1, peak];
                }
            }
            // Advance by the group delay (linear interpolation; the run's last value past
            // its end).
            let last = end - 1;
            for j in start..end {
                let pos = j as f64 + self.delay_samples;
                let k = (pos.floor() as usize).min(last);
                let frac = if k >= last { 0.0 } else { pos - k as f64 };
                let k2 = (k + 1).min(last);
                for c in 0..cols {
                    y[j * cols + c] = (1.0 - frac) * z[k * cols + c] + frac * z[k2 * cols + c];
                }
            }
            start = end;
        }
    }

    /// This filter run at `m` times the sample rate, as [`AntiAlias::resample`] runs it (its
    /// step is one sub-sample: `delay_samples / m` is its advance in samples).
    pub fn at_subsample_rate(&self, m: usize) -> AntiAlias {
        AntiAlias::butterworth2(self.cutoff_per_fs / m.max(1) as f64, 1.0)
    }

    /// The filter and advance of [`AntiAlias::apply`] run at `g.m` times the sample rate
    /// on model outputs given on the sub-sample grid `g` ([`crate::subsample`]), read
    /// back at the samples. `y` is row-major `g.len() × cols`; the result `n × cols`, n the
    /// number of samples. Inside a refined interval the filter takes the grid's own
    /// points; inside the others, the outputs interpolated linearly between the samples.
    /// Runs restart at every zero step, as in `apply`; a column whose input and state are
    /// all zero stays exactly zero.
    pub fn resample(&self, g: &SubGrid, y: &[f64], cols: usize) -> Vec<f64> {
        #[cfg(target_arch = "x86_64")]
        if numerics::simd::has_avx2() {
            // SAFETY: the CPU runs AVX2 (checked at run time just above).
            return unsafe { self.resample_avx2(g, y, cols) };
        }
        self.resample_portable(g, y, cols)
    }

    /// [`AntiAlias::resample`] compiled with AVX2: its column loops four lanes wide, the same
    /// results bit for bit ([`numerics::simd`]).
    ///
    /// # Safety
    /// The CPU must run AVX2 instructions ([`numerics::simd::has_avx2`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn resample_avx2(&self, g: &SubGrid, y: &[f64], cols: usize) -> Vec<f64> {
        self.resample_portable(g, y, cols)
    }

    /// The body of [`AntiAlias::resample`], inlined into each compiled version.
    #[inline(always)]
    fn resample_portable(&self, g: &SubGrid, y: &[f64], cols: usize) -> Vec<f64> {
        let (n, m) = (g.pos.len(), g.m.max(1));
        debug_assert_eq!(y.len(), g.len() * cols);
        let fine = self.at_subsample_rate(m);
        let b = [fine.b0, 2.0 * fine.b0, fine.b0];
        let (a1, a2) = (fine.a1, fine.a2);
        let kd = fine.delay_samples.floor() as usize;
        let frac = fine.delay_samples - kd as f64;
        // The read falls on the same fine step of every interval: step se (1-based).
        let se = kd % m + 1;
        let lin = LinearInterval::new(b, a1, a2, m, se, frac);
        // Rows are produced in order, each once (the reads of a run's intervals, then the
        // run's unread tail), so they are appended, not zeroed first.
        let mut out = Vec::with_capacity(n * cols);
        // Per column, one array each so that the columns of a step run side by side:
        // x[k-1], x[k-2], z[k-1], z[k-2] and the largest |x| so far; the read of the
        // current interval.
        let mut x1 = vec![0.0; cols];
        let mut x2 = vec![0.0; cols];
        let mut z1 = vec![0.0; cols];
        let mut z2 = vec![0.0; cols];
        let mut peak = vec![0.0; cols];
        let mut got = vec![0.0; cols];
        let row = |k: usize| &y[k * cols..(k + 1) * cols];
        let mut start = 0;
        while start < n {
            let mut end = start + 1;
            while end < n && g.h[g.pos[end]] > 0.0 {
                end += 1;
            }
            let y0 = row(g.pos[start]);
            for s in [&mut x1, &mut x2, &mut z1, &mut z2] {
                s.copy_from_slice(y0);
            }
            for (p, v) in peak.iter_mut().zip(y0) {
                *p = v.abs();
            }
            // Fine index k (0 at the run's first sample); sample r of the run reads the
            // filtered output at r m + kd + frac, once fine step k = r m + kd + 1 exists:
            // one read per interval, on its fine step se, from the interval whose steps
            // reach it.
            for j in start + 1..end {
                let k0 = (j - 1 - start) * m;
                let read = (k0 + se > kd).then(|| start + (k0 + se - 1 - kd) / m);
                let (ya, yb) = (row(g.pos[j - 1]), row(g.pos[j]));
                if !g.refined[j] {
                    // Inputs linear over the interval: the m steps in closed form.
                    let dot = |w: &[f64; 5], u: &[f64; 5]| {
                        w[0] * u[0] + w[1] * u[1] + w[2] * u[2] + w[3] * u[3] + w[4] * u[4]
                    };
                    // Without branches, so that the columns run side by side: a quiet
                    // column (no input over the interval) at rest stays at exact zeros,
                    // as every term is zero and `tiny` returns 0 (a Jacobian column of a
                    // knot the current is away from, most of the record); `+ 0.0` turns
                    // the −0 a zero input may give into 0.
                    for c in 0..cols {
                        let u = [x2[c], z1[c], z2[c], ya[c], yb[c]];
                        let pk = peak[c].max(ya[c].abs()).max(yb[c].abs());
                        let quiet = ya[c] == 0.0 && yb[c] == 0.0;
                        let floor = if quiet { 1e-12 * pk } else { -1.0 };
                        let tiny = |v: f64| if v.abs() <= floor { 0.0 } else { v };
                        got[c] = tiny(dot(&lin.read, &u));
                        z1[c] = tiny(dot(&lin.z1, &u));
                        z2[c] = tiny(dot(&lin.z2, &u));
                        x1[c] = yb[c];
                        x2[c] = lin.x2[0] * ya[c] + lin.x2[1] * yb[c] + 0.0;
                        peak[c] = pk;
                    }
                } else {
                    for s in 1..=m {
                        let xs = row(g.pos[j - 1] + s);
                        for c in 0..cols {
                            let x0 = xs[c];
                            if x0 == 0.0
                                && x1[c] == 0.0
                                && x2[c] == 0.0
                                && z1[c] == 0.0
                                && z2[c] == 0.0
                            {
                                // At rest and quiet: stays at rest (as above).
                                if s == se {
                                    got[c] = 0.0;
                                }
                                continue;
                            }
                            let mut o =
                                b[0] * x0 + b[1] * x1[c] + b[2] * x2[c] - a1 * z1[c] - a2 * z2[c];
                            peak[c] = peak[c].max(x0.abs());
                            if x0 == 0.0
                                && x1[c] == 0.0
                                && x2[c] == 0.0
                                && o.abs() <= 1e-12 * peak[c]
                            {
                                o = 0.0;
                            }
                            if s == se {
                                got[c] = (1.0 - frac) * z1[c] + frac * o;
                            }
                            (x2[c], x1[c], z2[c], z1[c]) = (x1[c], x0, z1[c], o);
                        }
                    }
                }
                if let Some(r) = read {
                    assert_eq!(out.len(), r * cols, "anti-alias reads out of order");
                    out.extend_from_slice(&got);
                }
            }
            // Samples whose read position lies past the run's last output take that output.
            let k = (end - 1 - start) * m;
            let first_unread = if k > kd { (k - 1 - kd) / m + 1 } else { 0 };
            for r in first_unread..end - start {
                assert_eq!(
                    out.len(),
                    (start + r) * cols,
                    "anti-alias reads out of order"
                );
                out.extend_from_slice(&z1);
            }
            start = end;
        }
        debug_assert_eq!(out.len(), n * cols);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_gain_and_a_delay_that_is_undone() {
        // A slow sine passes with unit gain and no lag once advanced.
        let fs = 1000.0;
        let aa = AntiAlias::butterworth2(0.25, 1.0 / fs);
        assert!((aa.cutoff_hz - 250.0).abs() < 1e-9);
        // Analog Butterworth: τ_g = √2 / ω_c = 0.9 samples here; the bilinear transform's
        // frequency warping shortens it (1/√2 samples at a quarter of the sample rate).
        assert!(
            (aa.delay_samples - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12,
            "{}",
            aa.delay_samples
        );
        let n = 4000;
        let h: Vec<f64> = (0..n)
            .map(|j| if j == 0 { 0.0 } else { 1.0 / fs })
            .collect();
        let s = |j: usize| (2.0 * std::f64::consts::PI * 5.0 * j as f64 / fs).sin();
        let mut y: Vec<f64> = (0..n).map(s).collect();
        aa.apply(&h, &mut y, 1);
        let err = (200..n - 10)
            .map(|j| (y[j] - s(j)).abs())
            .fold(0.0f64, f64::max);
        assert!(err < 2e-3, "{err}");
    }

    #[test]
    fn a_step_overshoots_like_a_butterworth_and_runs_restart_at_gaps() {
        let fs = 1000.0;
        let aa = AntiAlias::butterworth2(0.1, 1.0 / fs);
        let n = 400;
        // Two runs: the second starts at sample 200 (h = 0) at a constant value.
        let h: Vec<f64> = (0..n)
            .map(|j| if j == 0 || j == 200 { 0.0 } else { 1.0 / fs })
            .collect();
        let mut y: Vec<f64> = (0..n)
            .map(|j| if j < 200 { f64::from(j >= 50) } else { 3.0 })
            .collect();
        aa.apply(&h, &mut y, 1);
        let peak = y[..200].iter().cloned().fold(f64::MIN, f64::max);
        // A second-order Butterworth's step overshoot is 4.3 %.
        assert!((peak - 1.043).abs() < 0.01, "{peak}");
        assert!(y[200..].iter().all(|v| (v - 3.0).abs() < 1e-12));
        // Two columns are filtered independently.
        let mut m: Vec<f64> = (0..n).flat_map(|j| [f64::from(j >= 50), 2.0]).collect();
        aa.apply(&h, &mut m, 2);
        assert!((0..n).all(|j| (m[2 * j + 1] - 2.0).abs() < 1e-12));
        assert!((m[2 * 120] - y[120]).abs() < 1e-12);
    }

    /// A record with a step inside one sample interval: the filter behind the model, at
    /// 8 sub-samples, reproduces the continuous-time Butterworth's step response read at
    /// the samples (advanced by the group delay); on the samples alone it cannot.
    #[test]
    fn a_step_between_samples_is_filtered_as_in_continuous_time() {
        use crate::subsample::{Channels, SubGrid};
        let (fs, n, fc_per_fs) = (1000.0, 60, 0.25);
        let dt = 1.0 / fs;
        // Velocity crossing zero at t0 = 20.3 samples: the force steps from -1 to +1.
        let t0 = 20.3 * dt;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        let v: Vec<f64> = t.iter().map(|t| t - t0).collect();
        let a = vec![1.0; n];
        let h: Vec<f64> = (0..n).map(|k| if k == 0 { 0.0 } else { dt }).collect();
        let zeros = vec![0.0; n];
        let ch = Channels {
            h: &h,
            v: &v,
            a: &a,
            x: &zeros,
            i: &zeros,
            energy_kj: &zeros,
            v_sigma: &zeros,
        };
        // Analog second-order Butterworth: its step response, and its DC group delay √2/ω.
        let w = 2.0 * std::f64::consts::PI * fc_per_fs * fs;
        let z = std::f64::consts::FRAC_1_SQRT_2;
        let wd = w * (1.0 - z * z).sqrt();
        let step = |t: f64| {
            if t <= 0.0 {
                0.0
            } else {
                1.0 - (-z * w * t).exp()
                    * ((wd * t).cos() + z / (1.0 - z * z).sqrt() * (wd * t).sin())
            }
        };
        let tg = std::f64::consts::SQRT_2 / w;
        let truth: Vec<f64> = t.iter().map(|&t| -1.0 + 2.0 * step(t + tg - t0)).collect();
        let aa = AntiAlias::butterworth2(fc_per_fs, dt);
        let worst = |m: usize| {
            let g = SubGrid::build(&ch, m, &[]);
            let y: Vec<f64> = g.v.iter().map(|v| v.signum()).collect();
            let out = aa.resample(&g, &y, 1);
            out.iter()
                .zip(&truth)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f64, f64::max)
        };
        let (coarse, fine) = (worst(1), worst(8));
        assert!(
            fine < 0.06,
            "8 sub-samples: largest error {fine} of a step of 2"
        );
        assert!(coarse > 4.0 * fine, "samples only: {coarse} against {fine}");
    }

    /// The sub-sample grid (`m` steps per refined interval) of `n` samples `dt` apart,
    /// with a time gap before sample `gap` (none when `gap` ≥ n) and a current step at
    /// fraction `step(j)` of interval j where it says so; the velocity, held away from zero,
    /// refines no interval by itself.
    fn stepped_grid(
        n: usize,
        m: usize,
        dt: f64,
        gap: usize,
        step: impl Fn(usize) -> Option<f64>,
    ) -> crate::subsample::SubGrid {
        let h: Vec<f64> = (0..n)
            .map(|j| if j == 0 || j == gap { 0.0 } else { dt })
            .collect();
        let (v, zeros) = (vec![0.1; n], vec![0.0; n]);
        let step_at: Vec<Option<f64>> = (0..n).map(step).collect();
        let c = crate::subsample::Channels {
            h: &h,
            v: &v,
            a: &zeros,
            x: &zeros,
            i: &zeros,
            energy_kj: &zeros,
            v_sigma: &zeros,
        };
        crate::subsample::SubGrid::build(&c, m, &step_at)
    }

    #[test]
    fn a_quiet_column_comes_back_to_exact_zeros() {
        // A Jacobian column of a knot the current visits once: a pulse, then zeros. Its
        // filtered tail ends in exact zeros (+0, not −0 or a denormal), and a column that
        // never moves stays +0 throughout, in unrefined and refined intervals alike.
        let (n, m, dt) = (400, 4, 1e-3);
        // Every 50th interval refined, through a current step in it.
        let g = stepped_grid(n, m, dt, n, |j| (j % 50 == 7).then_some(0.5));
        assert_eq!(g.refined.iter().filter(|r| **r).count(), 8);
        let len = g.len();
        let y: Vec<f64> = (0..len)
            .flat_map(|k| [if (40..60).contains(&k) { -3.0 } else { 0.0 }, 0.0])
            .collect();
        let out = AntiAlias::butterworth2(0.25, dt).resample(&g, &y, 2);
        assert_eq!(out.len(), 2 * n);
        assert!(out[2 * 45] != 0.0, "the pulse passes");
        assert!(out.iter().skip(1).step_by(2).all(|v| v.to_bits() == 0));
        let first_zero = (0..n).rposition(|j| out[2 * j] != 0.0).unwrap() + 1;
        // Before the next refined interval (sample 107), whose steps zero a tail on their own.
        assert!(first_zero < 100, "the tail lasts to sample {first_zero}");
        assert!(out[2 * first_zero..].iter().all(|v| v.to_bits() == 0));
    }

    #[test]
    fn the_avx2_build_of_resample_gives_the_portable_results_bit_for_bit() {
        // Seven columns (an odd number: the vector loops' remainders too) of pulses,
        // sines and zeros, over unrefined and refined intervals and a time gap.
        let (n, m, dt) = (600, 4, 1e-3);
        let g = stepped_grid(n, m, dt, 301, |j| (j % 40 == 9).then_some(0.3));
        assert!(g.refined.iter().any(|r| *r) && g.refined.iter().any(|r| !*r));
        let cols = 7;
        let y: Vec<f64> = (0..g.len() * cols)
            .map(|e| {
                let (k, c) = ((e / cols) as f64, e % cols);
                match c {
                    0 => (k * 0.013).sin() * 1e3,
                    1 if (100.0..140.0).contains(&k) => -2.5,
                    2 => 0.0,
                    3 => (k * 0.41).cos() + 1e-9 * k,
                    _ => ((e * 2_654_435_761) % 1000) as f64 / 7.0 - 70.0,
                }
            })
            .collect();
        let aa = AntiAlias::butterworth2(0.22, dt);
        let portable = aa.resample_portable(&g, &y, cols);
        assert_eq!(portable.len(), n * cols);
        if !numerics::simd::has_avx2() {
            eprintln!("no AVX2 on this CPU: only the portable build runs");
            return;
        }
        // SAFETY: the CPU runs AVX2 (checked just above).
        let wide = unsafe { aa.resample_avx2(&g, &y, cols) };
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&wide), bits(&portable));
        assert_eq!(bits(&aa.resample(&g, &y, cols)), bits(&portable));
    }

    #[test]
    fn resample_without_refinement_is_apply() {
        use crate::subsample::SubGrid;
        let n = 300;
        let h: Vec<f64> = (0..n)
            .map(|j| if j == 0 || j == 150 { 0.0 } else { 1e-3 })
            .collect();
        let g = SubGrid {
            m: 1,
            refined: vec![false; n],
            pos: (0..n).collect(),
            h: h.clone(),
            ..SubGrid::default()
        };
        let mut y: Vec<f64> = (0..n)
            .flat_map(|j| [f64::from(j % 37 > 12), (j as f64 * 0.1).sin()])
            .collect();
        let aa = AntiAlias::butterworth2(0.3, 1e-3);
        let out = aa.resample(&g, &y, 2);
        aa.apply(&h, &mut y, 2);
        let worst = out
            .iter()
            .zip(&y)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-12, "{worst}");
    }
}
