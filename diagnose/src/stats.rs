//! Residual statistics: autocorrelation, effective sample size, cross-correlation with
//! confidence bands, and the paired held-out test over strokes.

/// Autocorrelation of `r` at `lag` (biased estimator, mean removed).
pub fn autocorr(r: &[f64], lag: usize) -> f64 {
    let n = r.len();
    if n <= lag + 1 {
        return 0.0;
    }
    let m = r.iter().sum::<f64>() / n as f64;
    let var: f64 = r.iter().map(|x| (x - m).powi(2)).sum();
    if var <= 0.0 {
        return 0.0;
    }
    let cov: f64 = (lag..n).map(|k| (r[k] - m) * (r[k - lag] - m)).sum();
    cov / var
}

/// Effective sample size of `n` AR(1)-correlated residuals with lag-1 autocorrelation
/// `rho1`: n (1 − ρ)/(1 + ρ), ρ clamped to \[0, 0.999\], at least 10.
pub fn effective_n(n: usize, rho1: f64) -> f64 {
    let r = rho1.clamp(0.0, 0.999);
    (n as f64 * (1.0 - r) / (1.0 + r)).max(10.0)
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
/// in place (no full sort).
pub fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let m = v.len() / 2;
    *v.select_nth_unstable_by(m, f64::total_cmp).1
}

/// Quantile of the standard normal distribution (Acklam's rational approximation,
/// relative error below 1.2e-9).
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    let p = p.clamp(1e-300, 1.0 - 1e-16);
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// Quantile of χ²(ν) for any ν > 0: exact for ν = 1 and 2, Wilson–Hilferty otherwise.
pub fn chi2_quantile(p: f64, nu: f64) -> f64 {
    if (nu - 1.0).abs() < 1e-12 {
        return normal_quantile(0.5 + 0.5 * p).powi(2);
    }
    if (nu - 2.0).abs() < 1e-12 {
        return -2.0 * (1.0 - p).ln();
    }
    let z = normal_quantile(p);
    let k = 2.0 / (9.0 * nu);
    (nu * (1.0 - k + z * k.sqrt()).powi(3)).max(0.0)
}

/// Wilson score interval (95 %) of a proportion `k` of `n`.
pub fn wilson95(k: usize, n: usize) -> (f64, f64) {
    if n == 0 {
        return (0.0, 1.0);
    }
    let z = 1.959_963_984_540_054;
    let (nf, p) = (n as f64, k as f64 / n as f64);
    let den = 1.0 + z * z / nf;
    let mid = (p + z * z / (2.0 * nf)) / den;
    let half = z * (p * (1.0 - p) / nf + z * z / (4.0 * nf * nf)).sqrt() / den;
    ((mid - half).max(0.0), (mid + half).min(1.0))
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
        } else {
            f64::INFINITY * m.signum()
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

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
