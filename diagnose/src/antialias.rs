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
//! pre-warping; its cut-off is fitted with the baseline from a grid of fractions of the
//! sample rate, "no filter" included ([`crate::select`]).

use serde::Serialize;

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
    #[serde(skip)]
    b0: f64,
    #[serde(skip)]
    a1: f64,
    #[serde(skip)]
    a2: f64,
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
            b0,
            a1,
            a2,
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
}
