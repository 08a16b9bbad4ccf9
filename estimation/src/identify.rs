//! Offline identification of the simplified Bodner–Partom law, the pipeline of Skalski &
//! Zalewski (2014):
//!
//! 1. per test (one current, one frequency, starting from rest): τ = F/A, γ = Δx/h (4.1);
//!    the shear rate is the slope of a straight line through the start of the strain–time
//!    curve (their Fig. 5); the yield point τ0 and the Kirchhoff modulus G come from the
//!    intersection of straight lines fitted to the elastic and the plastic part of the τ–γ
//!    curve of the first loading (their Fig. 6);
//! 2. per current: n and R0 by Levenberg–Marquardt on the yield-point formula (5.3),
//!    τ0 = R0/√3 · (2n/(n+1) · ln(2 D0/γ̇))^(−1/(2n)), with D0 = 10⁶ 1/s fixed;
//! 3. across currents (and temperatures where they differ): the linear forms of (5.5),
//!    n = a0 + a1 i (+ a2 t) and R0 h = b0 + b1 i (+ b2 t), R0 h in kPa·m as in the paper.
//!
//! Standard errors come from the Gauss–Newton covariance s² (JᵀJ)⁻¹ with s² = SSR/(m − p).
//!
//! Segmentation of the first loading (this module's choice, the paper draws the lines by
//! hand): the loading runs from the first sample to the first maximum of the displacement;
//! τ_p is its peak stress; the elastic line is fitted to the points with τ between 10 % and
//! 50 % of τ_p before the peak, the plastic line to the points with strain between 3 and 8
//! elastic yield strains τ_p/G, and the shear rate to the strain–time points up to the start of
//! the plastic window. The test must start from rest (τ ≈ 0 at x = x0) and be sampled finely
//! enough to put at least three points on the elastic line.

use numerics::least_squares::{levenberg_marquardt, normal_equations, sum_of_squares, LmOptions};
use numerics::linalg::{self, LuDim};
use numerics::nalgebra::{Const, DMatrix, DVector, Matrix2, SMatrix, SVector};
use twin::fluid::BODNER_PARTOM_D0;

/// One test: a loading from rest at one current (SI units).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TestRecord {
    /// Where it came from (for messages).
    pub source: String,
    /// Coil current \[A\].
    pub current_a: f64,
    /// Temperature \[°C\], when recorded.
    pub temperature_c: Option<f64>,
    /// Time \[s\].
    pub time_s: Vec<f64>,
    /// Displacement \[m\].
    pub displacement_m: Vec<f64>,
    /// Force \[N\].
    pub force_n: Vec<f64>,
}

/// A straight line y = intercept + slope x fitted by least squares.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line {
    /// Intercept.
    pub intercept: f64,
    /// Slope.
    pub slope: f64,
    /// Points used.
    pub points: usize,
}

/// Step 1 for one test.
#[derive(Debug, Clone, PartialEq)]
pub struct FirstLoading {
    /// Source of the test.
    pub source: String,
    /// Current \[A\].
    pub current_a: f64,
    /// Temperature \[°C\] (25 when not recorded).
    pub temperature_c: f64,
    /// Shear rate γ̇ from the start of the strain–time curve \[1/s\].
    pub shear_rate_per_s: f64,
    /// Yield point τ0 \[Pa\].
    pub tau0_pa: f64,
    /// Kirchhoff modulus G, the slope of the elastic line \[Pa\].
    pub shear_modulus_pa: f64,
    /// Elastic line τ(γ).
    pub elastic: Line,
    /// Plastic line τ(γ).
    pub plastic: Line,
}

/// Step 2 for one current.
#[derive(Debug, Clone, PartialEq)]
pub struct LawFit {
    /// Current \[A\].
    pub current_a: f64,
    /// Mean temperature of the tests \[°C\].
    pub temperature_c: f64,
    /// n and its standard error.
    pub n: f64,
    /// Standard error of n.
    pub n_se: f64,
    /// R0 \[Pa\].
    pub r0_pa: f64,
    /// Standard error of R0 \[Pa\].
    pub r0_se_pa: f64,
    /// (γ̇, measured τ0, τ0 of the fitted law − measured) for each test \[1/s, Pa, Pa\].
    pub residuals: Vec<(f64, f64, f64)>,
    /// Root mean square of the residuals \[Pa\].
    pub rms_pa: f64,
}

/// A coefficient with its standard error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coefficient {
    /// Value.
    pub value: f64,
    /// Standard error (NaN without degrees of freedom).
    pub se: f64,
}

/// Step 3: the linear forms of (5.5).
#[derive(Debug, Clone, PartialEq)]
pub struct CurrentDependence {
    /// n = a0 + a1 i (+ a2 t).
    pub n: Vec<Coefficient>,
    /// R0 h = b0 + b1 i (+ b2 t) \[kPa·m\].
    pub r0_h_kpa_m: Vec<Coefficient>,
    /// Whether a temperature term was fitted (temperatures differed).
    pub with_temperature: bool,
    /// Temperature at which the intercepts hold when no temperature term was fitted \[°C\].
    pub temperature_c: f64,
}

/// The whole identification.
#[derive(Debug, Clone, PartialEq)]
pub struct Identification {
    /// Gap h \[m\] and shear area A \[m²\] used.
    pub gap_m: f64,
    /// Shear area \[m²\].
    pub area_m2: f64,
    /// Step 1, per test.
    pub tests: Vec<FirstLoading>,
    /// Step 2, per current (ascending).
    pub laws: Vec<LawFit>,
    /// Step 3, when two or more currents were fitted.
    pub dependence: Option<CurrentDependence>,
}

/// What can go wrong.
#[derive(Debug, Clone, PartialEq)]
pub enum IdentifyError {
    /// A test cannot be processed (source, reason).
    Test(String, String),
    /// A current has fewer than three tests at distinct shear rates.
    TooFewRates(f64, usize),
    /// The law fit did not converge (current).
    NoConvergence(f64),
    /// Nothing to identify.
    Empty,
}

impl std::fmt::Display for IdentifyError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            IdentifyError::Test(src, why) => write!(f, "{src}: {why}"),
            IdentifyError::TooFewRates(i, k) => write!(
                f,
                "current {i} A has {k} test(s) at distinct shear rates; (5.3) needs three or more"
            ),
            IdentifyError::NoConvergence(i) => {
                write!(f, "the fit of (5.3) at {i} A did not converge")
            }
            IdentifyError::Empty => f.write_str("no tests to identify"),
        }
    }
}

impl std::error::Error for IdentifyError {}

/// Least-squares straight line through (x, y).
pub fn fit_line(x: &[f64], y: &[f64]) -> Option<Line> {
    let m = x.len();
    if m < 2 || y.len() != m {
        return None;
    }
    let mx = x.iter().sum::<f64>() / m as f64;
    let my = y.iter().sum::<f64>() / m as f64;
    let sxx: f64 = x.iter().map(|v| (v - mx).powi(2)).sum();
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    Some(Line {
        intercept: my - slope * mx,
        slope,
        points: m,
    })
}

/// Step 1: shear rate, yield point and G of one test from rest (see the module docs).
pub fn first_loading(
    test: &TestRecord,
    gap_m: f64,
    area_m2: f64,
) -> Result<FirstLoading, IdentifyError> {
    let err = |why: &str| IdentifyError::Test(test.source.clone(), why.to_string());
    let n = test.time_s.len();
    if n < 10 || test.displacement_m.len() != n || test.force_n.len() != n {
        return Err(err(
            "fewer than 10 samples, or columns of different lengths",
        ));
    }
    if [&test.time_s, &test.displacement_m, &test.force_n]
        .iter()
        .any(|c| c.iter().any(|v| !v.is_finite()))
    {
        return Err(err("non-finite value"));
    }
    let (t0, x0) = (test.time_s[0], test.displacement_m[0]);
    // First loading: up to the first displacement maximum.
    let mut end = 1;
    while end < n && test.displacement_m[end] >= test.displacement_m[end - 1] {
        end += 1;
    }
    let gamma: Vec<f64> = test.displacement_m[..end]
        .iter()
        .map(|x| (x - x0) / gap_m)
        .collect();
    let tau: Vec<f64> = test.force_n[..end].iter().map(|f| f / area_m2).collect();
    let (peak_k, &tau_p) = tau
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .ok_or_else(|| err("empty loading"))?;
    if tau_p <= 0.0 || tau[0].abs() > 0.1 * tau_p {
        return Err(err(
            "the test does not start from rest (the stress at the start is not near zero) or never loads",
        ));
    }
    let (ex, ey): (Vec<f64>, Vec<f64>) = (0..peak_k)
        .filter(|&k| tau[k] >= 0.1 * tau_p && tau[k] <= 0.5 * tau_p)
        .map(|k| (gamma[k], tau[k]))
        .unzip();
    if ex.len() < 3 {
        return Err(err(&format!(
            "only {} point(s) on the elastic line of the first loading: sample faster",
            ex.len()
        )));
    }
    let elastic = fit_line(&ex, &ey).ok_or_else(|| err("degenerate elastic line"))?;
    if elastic.slope <= 0.0 {
        return Err(err("elastic line does not rise"));
    }
    let gamma_y = tau_p / elastic.slope;
    let (lo, hi) = (3.0 * gamma_y, 8.0 * gamma_y);
    let (px, py): (Vec<f64>, Vec<f64>) = (0..end)
        .filter(|&k| gamma[k] >= lo && gamma[k] <= hi)
        .map(|k| (gamma[k], tau[k]))
        .unzip();
    if px.len() < 3 {
        return Err(err(&format!(
            "only {} point(s) on the plastic line (strain {lo:.3}–{hi:.3}): the stroke is too short or the sampling too slow",
            px.len()
        )));
    }
    let plastic = fit_line(&px, &py).ok_or_else(|| err("degenerate plastic line"))?;
    let gi = (plastic.intercept - elastic.intercept) / (elastic.slope - plastic.slope);
    let tau0 = elastic.intercept + elastic.slope * gi;
    // Shear rate: straight line through the start of the strain–time curve.
    let (sx, sy): (Vec<f64>, Vec<f64>) = (0..end)
        .filter(|&k| gamma[k] <= lo)
        .map(|k| (test.time_s[k] - t0, gamma[k]))
        .unzip();
    let rate = fit_line(&sx, &sy).ok_or_else(|| err("degenerate strain–time line"))?;
    if !(rate.slope > 0.0 && tau0 > 0.0 && tau0.is_finite()) {
        return Err(err("no positive shear rate or yield point"));
    }
    Ok(FirstLoading {
        source: test.source.clone(),
        current_a: test.current_a,
        temperature_c: test.temperature_c.unwrap_or(25.0),
        shear_rate_per_s: rate.slope,
        tau0_pa: tau0,
        shear_modulus_pa: elastic.slope,
        elastic,
        plastic,
    })
}

/// τ0 of (5.3) for parameters (n, R0) at a shear rate.
pub fn yield_point(n: f64, r0_pa: f64, shear_rate: f64) -> f64 {
    twin::fluid::BodnerPartom {
        n,
        r0_pa,
        d0: BODNER_PARTOM_D0,
    }
    .yield_point(shear_rate)
}

/// Step 2: n and R0 by Levenberg–Marquardt on (5.3) over (γ̇, τ0) points, D0 = 10⁶ 1/s.
/// Parameters are (n, ln R0) inside; the residuals are in Pa.
pub fn fit_law(points: &[(f64, f64)]) -> Option<(f64, f64, [[f64; 2]; 2], f64)> {
    let m = points.len();
    if m < 2 {
        return None;
    }
    let resid = |p: [f64; 2]| -> Option<Vec<f64>> {
        let r: Vec<f64> = points
            .iter()
            .map(|&(g, t)| yield_point(p[0], p[1].exp(), g) - t)
            .collect();
        r.iter().all(|v| v.is_finite()).then_some(r)
    };
    let jac = |p: [f64; 2]| -> Option<DMatrix<f64>> {
        let mut j = DMatrix::zeros(m, 2);
        for (k, h) in [(0usize, 1e-6), (1, 1e-7)] {
            let mut pp = p;
            let mut pm = p;
            pp[k] += h;
            pm[k] -= h;
            let (rp, rm) = (resid(pp)?, resid(pm)?);
            for i in 0..m {
                j[(i, k)] = (rp[i] - rm[i]) / (2.0 * h);
            }
        }
        Some(j)
    };
    // Marquardt's damping of the diagonal as it is, λ ÷ 10 on success (not below 1e-12),
    // × 10 on failure up to 30 times; converged at a relative SSR decrease of 1e-14 or a
    // step below 1e-12 in both parameters. n must stay positive.
    let opts = LmOptions {
        max_iter: 200,
        max_tries: 30,
        lambda_init: 1e-3,
        lambda_up: 10.0,
        lambda_down: 0.1,
        lambda_min: 1e-12,
        diag_floor: 0.0,
        rel_tol: 1e-14,
        step_tol: 1e-12,
    };
    let mut best: Option<([f64; 2], f64)> = None;
    // Several starting values of n; ln R0 from the mean point for that n.
    for n0 in [0.1, 0.2, 0.3, 0.5, 0.8, 1.2] {
        let (g, t) = points[m / 2];
        let z = 2.0 * n0 / (n0 + 1.0) * (2.0 * BODNER_PARTOM_D0 / g).ln();
        let p = [n0, (t * 3f64.sqrt() * z.powf(0.5 / n0)).ln()];
        let Some(r) = resid(p) else { continue };
        let s = sum_of_squares(&r);
        let fit = levenberg_marquardt(
            (p, r),
            s,
            &opts,
            |(p, r): &([f64; 2], Vec<f64>)| Some(normal_equations(&jac(*p)?, r)),
            |(p, _): &([f64; 2], Vec<f64>), d: &DVector<f64>| {
                let q = [p[0] + d[0], p[1] + d[1]];
                let rq = if q[0] > 0.0 { resid(q)? } else { return None };
                let sq = sum_of_squares(&rq);
                Some(((q, rq), sq))
            },
        );
        let (p, s) = (fit.state.0, fit.cost);
        if best.is_none_or(|(_, bs)| s < bs) {
            best = Some((p, s));
        }
    }
    let (p, s) = best?;
    // Covariance of (n, R0): s² (JᵀJ)⁻¹ with the Jacobian in (n, R0).
    let r0 = p[1].exp();
    let j = jac(p)?;
    let mut a = Matrix2::zeros();
    for row in j.row_iter() {
        let jr = [row[0], row[1] / r0];
        for u in 0..2 {
            for v in 0..2 {
                a[(u, v)] += jr[u] * jr[v];
            }
        }
    }
    let s2 = if m > 2 { s / (m - 2) as f64 } else { f64::NAN };
    let inv = linalg::inverse(&a)?;
    let cov = [
        [s2 * inv[(0, 0)], s2 * inv[(0, 1)]],
        [s2 * inv[(1, 0)], s2 * inv[(1, 1)]],
    ];
    Some((p[0], r0, cov, s))
}

/// Linear least squares with standard errors: y ≈ X β.
fn linear_fit<const N: usize>(rows: &[[f64; N]], y: &[f64]) -> Option<Vec<Coefficient>>
where
    Const<N>: LuDim,
{
    let m = rows.len();
    if m < N {
        return None;
    }
    let mut a = SMatrix::<f64, N, N>::zeros();
    let mut b = SVector::<f64, N>::zeros();
    for (x, &yy) in rows.iter().zip(y) {
        for u in 0..N {
            b[u] += x[u] * yy;
            for v in 0..N {
                a[(u, v)] += x[u] * x[v];
            }
        }
    }
    let beta = linalg::solve(&a, &b)?;
    let ssr: f64 = rows
        .iter()
        .zip(y)
        .map(|(x, yy)| (yy - (0..N).map(|u| x[u] * beta[u]).sum::<f64>()).powi(2))
        .sum();
    let s2 = if m > N {
        ssr / (m - N) as f64
    } else {
        f64::NAN
    };
    let inv = linalg::inverse(&a)?;
    Some(
        (0..N)
            .map(|u| Coefficient {
                value: beta[u],
                se: (s2 * inv[(u, u)]).sqrt(),
            })
            .collect(),
    )
}

/// Group key of a current (to 1 mA).
fn current_key(i: f64) -> i64 {
    (i.abs() * 1000.0).round() as i64
}

/// The whole pipeline over tests at three or more shear rates per current.
pub fn identify(
    tests: &[TestRecord],
    gap_m: f64,
    area_m2: f64,
) -> Result<Identification, IdentifyError> {
    if tests.is_empty() {
        return Err(IdentifyError::Empty);
    }
    let loadings = tests
        .iter()
        .map(|t| first_loading(t, gap_m, area_m2))
        .collect::<Result<Vec<_>, _>>()?;
    let mut groups: std::collections::BTreeMap<i64, Vec<&FirstLoading>> = Default::default();
    for l in &loadings {
        groups.entry(current_key(l.current_a)).or_default().push(l);
    }
    let mut laws = Vec::new();
    for (key, group) in &groups {
        let current = *key as f64 / 1000.0;
        let mut rates: Vec<f64> = group.iter().map(|l| l.shear_rate_per_s).collect();
        rates.sort_by(f64::total_cmp);
        rates.dedup_by(|a, b| (*a / *b - 1.0).abs() < 0.02);
        if rates.len() < 3 {
            return Err(IdentifyError::TooFewRates(current, rates.len()));
        }
        let pts: Vec<(f64, f64)> = group
            .iter()
            .map(|l| (l.shear_rate_per_s, l.tau0_pa))
            .collect();
        let (n, r0, cov, ssr) = fit_law(&pts).ok_or(IdentifyError::NoConvergence(current))?;
        let residuals: Vec<(f64, f64, f64)> = pts
            .iter()
            .map(|&(g, t)| (g, t, yield_point(n, r0, g) - t))
            .collect();
        laws.push(LawFit {
            current_a: current,
            temperature_c: group.iter().map(|l| l.temperature_c).sum::<f64>() / group.len() as f64,
            n,
            n_se: cov[0][0].sqrt(),
            r0_pa: r0,
            r0_se_pa: cov[1][1].sqrt(),
            rms_pa: (ssr / pts.len() as f64).sqrt(),
            residuals,
        });
    }
    let dependence = current_dependence(&laws, gap_m);
    Ok(Identification {
        gap_m,
        area_m2,
        tests: loadings,
        laws,
        dependence,
    })
}

/// Step 3: (5.5) in linear form over the per-current fits. The temperature term is fitted
/// only when the temperatures span more than 1 K and there are four or more fits.
pub fn current_dependence(laws: &[LawFit], gap_m: f64) -> Option<CurrentDependence> {
    if laws.len() < 2 {
        return None;
    }
    let tmin = laws
        .iter()
        .map(|l| l.temperature_c)
        .fold(f64::INFINITY, f64::min);
    let tmax = laws
        .iter()
        .map(|l| l.temperature_c)
        .fold(f64::NEG_INFINITY, f64::max);
    let tmean = laws.iter().map(|l| l.temperature_c).sum::<f64>() / laws.len() as f64;
    let ny: Vec<f64> = laws.iter().map(|l| l.n).collect();
    let ry: Vec<f64> = laws.iter().map(|l| l.r0_pa / 1e3 * gap_m).collect();
    if tmax - tmin > 1.0 && laws.len() >= 4 {
        let rows: Vec<[f64; 3]> = laws
            .iter()
            .map(|l| [1.0, l.current_a, l.temperature_c])
            .collect();
        Some(CurrentDependence {
            n: linear_fit(&rows, &ny)?,
            r0_h_kpa_m: linear_fit(&rows, &ry)?,
            with_temperature: true,
            temperature_c: tmean,
        })
    } else {
        let rows: Vec<[f64; 2]> = laws.iter().map(|l| [1.0, l.current_a]).collect();
        Some(CurrentDependence {
            n: linear_fit(&rows, &ny)?,
            r0_h_kpa_m: linear_fit(&rows, &ry)?,
            with_temperature: false,
            temperature_c: tmean,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn law_fit_recovers_exact_points() {
        let (n, r0) = (0.28, 9.4e6);
        let pts: Vec<(f64, f64)> = [73.0, 144.0, 217.0]
            .iter()
            .map(|&g| (g, yield_point(n, r0, g)))
            .collect();
        let (nf, r0f, _, _) = fit_law(&pts).unwrap();
        assert!((nf / n - 1.0).abs() < 1e-6, "{nf}");
        assert!((r0f / r0 - 1.0).abs() < 1e-6, "{r0f}");
    }
}
