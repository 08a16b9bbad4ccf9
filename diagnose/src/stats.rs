//! Residual statistics: autocorrelation, effective sample size, cross-correlation with
//! confidence bands, and the paired held-out test over strokes.
//!
//! The general ones (autocorrelation, AR(1) effective sample size, median, normal and χ²
//! quantiles, Wilson interval) are those of [`numerics::stats`], re-exported or wrapped
//! here with diagnose's conventions; the tests below keep checking them through diagnose.

pub use numerics::stats::{autocorr, chi2_quantile, normal_quantile, wilson95};

/// Effective sample size of `n` AR(1)-correlated residuals with lag-1 autocorrelation
/// `rho1`: n (1 − ρ)/(1 + ρ) ([`numerics::stats::effective_sample_size`], ρ clamped to
/// \[0, [`numerics::stats::AR1_RHO_MAX`]\]), at least 10.
pub fn effective_n(n: usize, rho1: f64) -> f64 {
    numerics::stats::effective_sample_size(n, rho1).max(10.0)
}

/// Normalised cross-correlation ρ(k) = corr(r\[j\], s\[j − k\]) for k in `lags`;
/// returns the lag and value of the largest |ρ|.
pub fn max_crosscorr(r: &[f64], s: &[f64], lags: std::ops::RangeInclusive<i64>) -> (i64, f64) {
    let n = r.len();
    let mr = r.iter().sum::<f64>() / n as f64;
    let ms = s.iter().sum::<f64>() / n as f64;
    let vr: f64 = r.iter().map(|x| (x - mr).powi(2)).sum();
    let vs: f64 = s.iter().map(|x| (x - ms).powi(2)).sum();
    if vr <= 0.0 || vs <= 0.0 {
        return (0, 0.0);
    }
    let norm = (vr * vs).sqrt();
    let mut best = (0i64, 0.0f64);
    for k in lags {
        let mut acc = 0.0;
        for (j, rj) in r.iter().enumerate() {
            let i = j as i64 - k;
            if i >= 0 && (i as usize) < n {
                acc += (rj - mr) * (s[i as usize] - ms);
            }
        }
        let rho = acc / norm;
        if rho.abs() > best.1.abs() {
            best = (k, rho);
        }
    }
    best
}

/// Ljung–Box statistic over lags 1..=m and the 95 % quantile of χ²(m) (Wilson–Hilferty).
pub fn ljung_box(r: &[f64], m: usize) -> (f64, f64) {
    let n = r.len() as f64;
    let q: f64 = (1..=m)
        .map(|k| autocorr(r, k).powi(2) / (n - k as f64))
        .sum::<f64>()
        * n
        * (n + 2.0);
    let mf = m as f64;
    let z = 1.645;
    let crit = mf * (1.0 - 2.0 / (9.0 * mf) + z * (2.0 / (9.0 * mf)).sqrt()).powi(3);
    (q, crit)
}

/// The median of `v` (the upper one of an even count; 0 for an empty vector), by selection
/// in place (no full sort): [`numerics::stats::median`].
pub fn median(mut v: Vec<f64>) -> f64 {
    numerics::stats::median(&mut v).unwrap_or(0.0)
}

/// Paired test over blocks (strokes): mean and standard error of the per-block
/// differences `before − after`; returns (mean, z = mean / se).
pub fn paired_z(before: &[f64], after: &[f64]) -> (f64, f64) {
    let n = before.len().min(after.len());
    if n < 3 {
        return (0.0, 0.0);
    }
    let d: Vec<f64> = (0..n).map(|k| before[k] - after[k]).collect();
    let m = d.iter().sum::<f64>() / n as f64;
    let var = d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n as f64 - 1.0);
    let se = (var / n as f64).sqrt();
    (
        m,
        if se > 0.0 {
            m / se
        } else if m == 0.0 {
            // Identical predictions (a candidate whose parameter stayed at its no-effect
            // value): no difference, not 0/0.
            0.0
        } else {
            f64::INFINITY * m.signum()
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_predictions_have_a_paired_z_of_zero() {
        let sse = [3.0, 1.0, 4.0, 1.5];
        assert_eq!(paired_z(&sse, &sse), (0.0, 0.0));
        let better: Vec<f64> = sse.iter().map(|x| x - 0.5).collect();
        assert_eq!(paired_z(&sse, &better).1, f64::INFINITY);
    }

    #[test]
    fn quantiles_match_tables() {
        assert!((normal_quantile(0.975) - 1.959_964).abs() < 1e-6);
        assert!((normal_quantile(1e-4) + 3.719_016).abs() < 1e-5);
        assert!((chi2_quantile(0.95, 1.0) - 3.841_459).abs() < 1e-5);
        assert!((chi2_quantile(0.999, 2.0) - 13.815_51).abs() < 1e-4);
        // Wilson–Hilferty at ν = 5: table 11.0705 (within 0.5 %).
        assert!((chi2_quantile(0.95, 5.0) / 11.0705 - 1.0).abs() < 5e-3);
        let (lo, hi) = wilson95(95, 100);
        assert!(
            (lo - 0.8882).abs() < 1e-3 && (hi - 0.9785).abs() < 1e-3,
            "{lo} {hi}"
        );
    }

    #[test]
    fn white_and_correlated_sequences() {
        // A deterministic pseudo-random white sequence (LCG).
        let mut s = 12345u64;
        let white: Vec<f64> = (0..20000)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        assert!(autocorr(&white, 1).abs() < 0.03);
        let (q, crit) = ljung_box(&white, 10);
        assert!(q < 2.0 * crit, "white: Q {q} vs {crit}");
        let mut ar = vec![0.0; white.len()];
        for k in 1..ar.len() {
            ar[k] = 0.9 * ar[k - 1] + white[k];
        }
        let rho = autocorr(&ar, 1);
        assert!((rho - 0.9).abs() < 0.03, "AR(1) ρ1 {rho}");
        let ne = effective_n(ar.len(), rho);
        assert!((ne / (20000.0 * 0.1 / 1.9) - 1.0).abs() < 0.4, "n_eff {ne}");
        let (q, crit) = ljung_box(&ar, 10);
        assert!(q > crit);
        // Cross-correlation finds a delayed copy.
        let delayed: Vec<f64> = (0..white.len())
            .map(|j| if j >= 7 { white[j - 7] } else { 0.0 })
            .collect();
        let (lag, rho) = max_crosscorr(&delayed, &white, -20..=20);
        assert_eq!(lag, 7);
        assert!(rho > 0.99);
    }
}
