//! The recording as diagnose sees it: signals, derived acceleration and dissipated energy,
//! current levels, strokes (cycles), segments, stroke phases and the fitting / held-out split.

use serde::Serialize;

/// The signals of a recording (SI units, PHYSICS.md conventions).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Signals {
    /// Time \[s\], strictly increasing.
    pub time_s: Vec<f64>,
    /// Displacement x \[m\], positive in extension.
    pub displacement_m: Vec<f64>,
    /// Velocity v \[m/s\].
    pub velocity_m_s: Vec<f64>,
    /// Measured rod force \[N\].
    pub force_n: Vec<f64>,
    /// Coil current \[A\].
    pub current_a: Vec<f64>,
    /// `true` when the velocity column was computed from the displacement by the reader
    /// (then only the displacement carries information about the velocity).
    pub velocity_derived: bool,
}

/// Why a recording cannot be diagnosed.
#[derive(Debug, Clone, PartialEq)]
pub struct DataError(pub String);

impl std::fmt::Display for DataError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for DataError {}

/// Stroke phase of a sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// |v| below a quarter of the stroke's peak speed.
    NearReversal,
    /// Speed rising (v·a > 0).
    Accelerating,
    /// Speed falling.
    Decelerating,
}

impl Phase {
    /// All phases, in report order.
    pub const ALL: [Phase; 3] = [
        Phase::NearReversal,
        Phase::Accelerating,
        Phase::Decelerating,
    ];
    /// Name in the report.
    pub fn name(self) -> &'static str {
        match self {
            Phase::NearReversal => "near reversal",
            Phase::Accelerating => "accelerating",
            Phase::Decelerating => "decelerating",
        }
    }
}

/// A recording prepared for fitting.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// Time \[s\].
    pub t: Vec<f64>,
    /// Displacement \[m\].
    pub x: Vec<f64>,
    /// Velocity v \[m/s\], rebuilt from the displacement and velocity channels
    /// ([`crate::measure`]).
    pub v: Vec<f64>,
    /// Standard deviation of the rebuilt velocity's error \[m/s\].
    pub v_sigma: Vec<f64>,
    /// Weight of each sample in every fit and every error figure: σ_F² / (σ_F² + the
    /// force variance the velocity error causes), set from the baseline
    /// ([`crate::model::predictive_weights`]); 1 until then.
    pub weight: Vec<f64>,
    /// Acceleration \[m/s²\], local-cubic derivative of the rebuilt velocity.
    pub a: Vec<f64>,
    /// Current \[A\]: the recorded channel conditioned ([`crate::current`]): held plateaus
    /// at their level, steps sharp.
    pub i: Vec<f64>,
    /// Measured force \[N\].
    pub f: Vec<f64>,
    /// Cumulative dissipated energy ∫ F v dt from the measurement \[kJ\].
    pub energy_kj: Vec<f64>,
    /// Step to the previous sample \[s\] (0 at the start and after a time gap).
    pub h: Vec<f64>,
    /// Current knots (the distinct current levels, or a grid when there are many).
    pub knots: Vec<f64>,
    /// Weights λ of the knots' smoothness penalty in every fit, per family (F_y, c V,
    /// c₂; [`crate::model::knot_penalty`]), in weighted-SSE units per N²; 0 until the
    /// baseline has set them ([`crate::model::knot_smoothing`]).
    pub knot_smoothing: [f64; 3],
    /// The rig's anti-alias filter every model force passes through before it is compared
    /// with the measurement (fitted with the baseline; `None` until then, or when no
    /// filter fits better).
    pub anti_alias: Option<crate::antialias::AntiAlias>,
    /// The model's inputs on the sub-sample grid it is evaluated on behind the filter.
    pub subgrid: crate::subsample::SubGrid,
    /// The current channel's plateaus and steps ([`crate::current`]); `i` is its placed
    /// current.
    pub current: crate::current::ConditionedCurrent,
    /// Per sample j: where in the interval (j − 1, j] the placed current steps.
    pub current_step_at: Vec<Option<f64>>,
    /// `true` when the knots are the record's own held levels (at most 12 distinct
    /// currents), `false` when the current varies continuously and the knots are a grid.
    pub held_levels: bool,
    /// How the yield force is interpolated between the knots of a grid.
    pub yield_curve: YieldCurve,
    /// Stroke (cycle) index of each sample.
    pub cycle: Vec<usize>,
    /// Number of strokes.
    pub cycles: usize,
    /// Segment index of each sample (new segment at a current step or a change of stroke).
    pub segment: Vec<usize>,
    /// Number of segments.
    pub segments: usize,
    /// Stroke phase of each sample.
    pub phase: Vec<Phase>,
    /// Peak speed of each sample's stroke \[m/s\].
    pub stroke_speed: Vec<f64>,
    /// `true` for held-out samples (never for excluded ones).
    pub holdout: Vec<bool>,
    /// `true` for fitting samples (never for excluded ones).
    pub train: Vec<bool>,
    /// `true` for samples left out of fitting and validation (a channel stuck, or the ends
    /// of the record and its segments).
    pub excluded: Vec<bool>,
    /// Validation block of each sample (contiguous in time; odd blocks are held out).
    pub block: Vec<usize>,
    /// Number of validation blocks.
    pub blocks: usize,
    /// Velocity scale of the friction smoothing \[m/s\] (1 % of the peak speed, at least
    /// the leak velocity of the measurement model).
    pub friction_velocity: f64,
    /// Peak speed of the record \[m/s\] (scale of the curvature term).
    pub velocity_scale: f64,
    /// Half the displacement's range \[m\] (the stroke amplitude of a symmetric record).
    pub half_stroke_m: f64,
    /// The middle of the displacement's range \[m\]: the stroke's centre, where a
    /// chamber's volume is its mid-stroke volume (`model::Chamber`).
    pub stroke_centre_m: f64,
    /// What the measurement model found.
    pub measurement: crate::measure::MeasurementSummary,
    /// How the data were split.
    pub split_method: String,
}

impl Prepared {
    /// The record's peak force \[N\]: the largest |F| over the samples not left out.
    pub fn peak_force(&self) -> f64 {
        self.f
            .iter()
            .zip(&self.excluded)
            .filter(|(_, x)| !**x)
            .map(|(f, _)| f.abs())
            .fold(0.0, f64::max)
    }

    /// Put the rig's anti-alias filter behind every model force (`None`: no filter): the
    /// current steps are placed again under it ([`crate::current::ConditionedCurrent::place`])
    /// and the sub-sample grid rebuilt.
    pub fn set_anti_alias(&mut self, aa: Option<crate::antialias::AntiAlias>) {
        self.anti_alias = aa;
        let dt = self.measurement.sample_interval_s;
        // The delay the model's force is advanced by: the filter's, run at the sub-sample
        // grid's rate (crate::antialias::AntiAlias::resample), close to the analog one.
        let m = crate::subsample::OVERSAMPLING;
        let placed = self.current.place(
            &self.t,
            &self.h,
            aa.map(|a| {
                let fine = a.at_subsample_rate(m);
                (a.cutoff_hz, fine.delay_samples / m as f64 * dt)
            }),
        );
        self.i = placed.i;
        self.current_step_at = placed.step_at;
        self.subgrid = crate::subsample::SubGrid::build(
            &self.channels(),
            crate::subsample::OVERSAMPLING,
            &self.current_step_at,
        );
    }

    /// The samples as model inputs.
    pub fn channels(&self) -> crate::subsample::Channels<'_> {
        crate::subsample::Channels {
            h: &self.h,
            v: &self.v,
            a: &self.a,
            x: &self.x,
            i: &self.i,
            energy_kj: &self.energy_kj,
            v_sigma: &self.v_sigma,
        }
    }

    /// Current steps signed by the stroke direction, `ΔI · sgn v` at every sample (0 at the
    /// first): the signal a field lag leaves its trace on.
    pub fn current_steps(&self) -> Vec<f64> {
        (0..self.len())
            .map(|j| {
                if j == 0 {
                    0.0
                } else {
                    (self.i[j] - self.i[j - 1]) * self.v[j].signum()
                }
            })
            .collect()
    }
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }
    /// No samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

/// Check the signals: equal lengths, enough samples, finite values, increasing time.
fn validate(s: &Signals) -> Result<(), DataError> {
    let n = s.time_s.len();
    for (name, len) in [
        ("displacement_m", s.displacement_m.len()),
        ("velocity_m_s", s.velocity_m_s.len()),
        ("force_N", s.force_n.len()),
        ("current_A", s.current_a.len()),
    ] {
        if len != n {
            return Err(DataError(format!(
                "column {name} has {len} samples, time_s has {n}"
            )));
        }
    }
    if n < 200 {
        return Err(DataError(format!(
            "only {n} samples: diagnose needs at least 200 (several strokes)"
        )));
    }
    for k in 0..n {
        let row = [
            s.time_s[k],
            s.displacement_m[k],
            s.velocity_m_s[k],
            s.force_n[k],
            s.current_a[k],
        ];
        if row.iter().any(|x| !x.is_finite()) {
            return Err(DataError(format!("sample {k} holds a non-finite value")));
        }
        if k > 0 && s.time_s[k] <= s.time_s[k - 1] {
            return Err(DataError(format!("time does not increase at sample {k}")));
        }
    }
    Ok(())
}

/// Step to the previous sample (0 at the start and after a gap of more than 5 median steps).
fn steps(t: &[f64]) -> Vec<f64> {
    let dt = crate::stats::median(t.windows(2).map(|w| w[1] - w[0]).collect());
    let mut h = vec![0.0; t.len()];
    for k in 1..t.len() {
        let d = t[k] - t[k - 1];
        h[k] = if d > 5.0 * dt { 0.0 } else { d };
    }
    h
}

/// Current knots: the held levels — clusters of currents within 2 % of the largest
/// current that hold at least 1 % of the samples each (transitions between levels and
/// noise on the channel make no level of their own) — when there are at most 12 of them
/// and they hold at least 90 % of the samples; otherwise 8 knots evenly spread over the
/// range (a continuously varying current).
fn current_knots(i: &[f64]) -> Vec<f64> {
    let tol = level_tolerance(i);
    let mut sorted = i.to_vec();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len();
    let min_count = (n / 100).max(20);
    let mut levels = Vec::new();
    let mut covered = 0usize;
    let mut a = 0;
    while a < n {
        let mut b = a + 1;
        while b < n && sorted[b] - sorted[b - 1] <= tol && sorted[b] - sorted[a] <= 2.0 * tol {
            b += 1;
        }
        if b - a >= min_count {
            levels.push((sorted[a..b].iter().sum::<f64>() / (b - a) as f64, b - a));
            covered += b - a;
        }
        a = b;
    }
    // Levels closer than the tolerance are one knot (two random levels a few mA apart
    // would make two knots the data cannot tell apart).
    let mut merged: Vec<(f64, usize)> = Vec::new();
    for (l, c) in levels {
        match merged.last_mut() {
            Some((m, mc)) if l - *m <= tol => {
                *m = (*m * *mc as f64 + l * c as f64) / (*mc + c) as f64;
                *mc += c;
            }
            _ => merged.push((l, c)),
        }
    }
    let levels: Vec<f64> = merged.into_iter().map(|x| x.0).collect();
    if !levels.is_empty() && levels.len() <= 12 && covered as f64 >= 0.9 * n as f64 {
        levels
    } else {
        let (lo, hi) = (sorted[0], sorted[n - 1]);
        if hi - lo <= tol {
            return vec![0.5 * (lo + hi)];
        }
        (0..8).map(|j| lo + (hi - lo) * j as f64 / 7.0).collect()
    }
}

/// The currents the fitted knots cover, widened by the level tolerance.
fn fitted_range(knots: &[f64], tol: f64) -> (f64, f64) {
    let lo = knots.iter().fold(f64::INFINITY, |m, k| m.min(*k)) - tol;
    let hi = knots.iter().fold(f64::NEG_INFINITY, |m, k| m.max(*k)) + tol;
    (lo, hi)
}

/// The record's held levels that no fitted knot stands for.
fn unfitted_levels(levels: &[f64], knots: &[f64], tol: f64) -> Vec<f64> {
    levels
        .iter()
        .copied()
        .filter(|l| knots.iter().all(|k| (k - l).abs() > tol))
        .collect()
}

/// Held-out samples that are not a prediction of the fitted model: beyond the fitted
/// currents, or held at a level the fit did not see.
#[derive(Debug, PartialEq)]
struct Unscored {
    samples: Vec<usize>,
    beyond: usize,
    at_unfitted: usize,
}

fn unscored(
    i: &[f64],
    holdout: &[bool],
    (lo, hi): (f64, f64),
    unfitted: &[f64],
    tol: f64,
) -> Unscored {
    let mut u = Unscored {
        samples: Vec::new(),
        beyond: 0,
        at_unfitted: 0,
    };
    for (j, (&c, _)) in i.iter().zip(holdout).enumerate().filter(|(_, (_, h))| **h) {
        if c < lo || c > hi {
            u.beyond += 1;
        } else if unfitted.iter().any(|l| (c - l).abs() <= tol) {
            u.at_unfitted += 1;
        } else {
            continue;
        }
        u.samples.push(j);
    }
    u
}

/// Drop the current knots the fitting blocks barely reach, weakest first, until every
/// knot left carries at least 2 % of the fitting samples (and 50) in interpolation weight
/// and none is fixed only in a blend with its neighbour ([`blend_only_knot`]).
/// A level seen only in held-out blocks (random current levels) would otherwise have free
/// parameters nothing constrains; its samples are interpolated between the neighbouring
/// knots instead.
fn knots_the_fit_can_see(mut knots: Vec<f64>, i: &[f64], train: &[bool]) -> Vec<f64> {
    let m = train.iter().filter(|t| **t).count();
    let min_support = (0.02 * m as f64).max(50.0);
    while knots.len() > 1 {
        let mut support = vec![0.0; knots.len()];
        for (&c, _) in i.iter().zip(train).filter(|(_, t)| **t) {
            let (k, lam, _) = knot_weights(&knots, c);
            support[k] += 1.0 - lam;
            support[k + 1] += lam;
        }
        let (weakest, s) =
            support.iter().enumerate().fold(
                (0, f64::INFINITY),
                |b, (k, s)| if *s < b.1 { (k, *s) } else { b },
            );
        if s < min_support {
            knots.remove(weakest);
            continue;
        }
        match blend_only_knot(&knots, i, train, &support, 0.25 * min_support) {
            Some(k) => {
                knots.remove(k);
            }
            None => break,
        }
    }
    knots
}

/// A knot whose value the fitting samples fix only in a blend with its neighbour: the
/// Gram matrix of the interpolation weights, `G = Σ w wᵀ` over the fitting samples, has
/// an eigenvalue below `floor` (one level between two knots, and none on the knots'
/// other sides, fixes only `(1 − λ) F_k + λ F_k+1`; a held-out level at another blend
/// then sees whatever the fit left in the free direction: 28 kN off on a 19 kN record).
/// Returns the knot with the largest share of that direction, the less supported of two
/// equal shares.
fn blend_only_knot(
    knots: &[f64],
    i: &[f64],
    train: &[bool],
    support: &[f64],
    floor: f64,
) -> Option<usize> {
    let nk = knots.len();
    if nk < 2 {
        return None;
    }
    let mut g = nalgebra::DMatrix::<f64>::zeros(nk, nk);
    for (&c, _) in i.iter().zip(train).filter(|(_, t)| **t) {
        let (k, lam, _) = knot_weights(knots, c);
        let (a, b) = (1.0 - lam, lam);
        g[(k, k)] += a * a;
        g[(k, k + 1)] += a * b;
        g[(k + 1, k)] += a * b;
        g[(k + 1, k + 1)] += b * b;
    }
    let eig = nalgebra::SymmetricEigen::new(g);
    let (q, low) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .fold(
            (0, f64::INFINITY),
            |b, (q, x)| if *x < b.1 { (q, *x) } else { b },
        );
    if low >= floor {
        return None;
    }
    let vec = eig.eigenvectors.column(q);
    (0..nk).max_by(|&a, &b| {
        let (va, vb) = (vec[a].abs(), vec[b].abs());
        if (va - vb).abs() > 1e-9 {
            va.total_cmp(&vb)
        } else {
            support[b].total_cmp(&support[a])
        }
    })
}

/// Knot segment and weight for current `i`: F(i) = (1 − λ) F[k] + λ F[k+1]; and dλ/di.
pub fn knot_weights(knots: &[f64], i: f64) -> (usize, f64, f64) {
    let nk = knots.len();
    if nk == 1 || i <= knots[0] {
        return (0, 0.0, 0.0);
    }
    if i >= knots[nk - 1] {
        return (nk - 2, 1.0, 0.0);
    }
    let k = knots
        .partition_point(|&x| x <= i)
        .saturating_sub(1)
        .min(nk - 2);
    let w = knots[k + 1] - knots[k];
    (k, (i - knots[k]) / w, 1.0 / w)
}

/// Interpolation of a per-knot family at one current: up to four knots, each with its
/// weight and the weight's derivative in current, `F(i) = Σ w_q F[q]`.
#[derive(Debug, Clone, Copy)]
pub struct KnotInterpolation {
    /// The knots' indices (the first `len` are used).
    index: [usize; 4],
    /// Their weights.
    weight: [f64; 4],
    /// The weights' derivatives in current \[1/A\].
    dweight: [f64; 4],
    /// How many knots carry weight.
    len: usize,
    /// Straight lines between two knots: the slope is their difference times the inverse
    /// spacing, the arithmetic of the lines before the curve existed (so a record on lines
    /// is fitted bit for bit as before).
    linear: bool,
}

impl KnotInterpolation {
    fn add(&mut self, q: usize, w: f64, dw: f64) {
        if let Some(p) = self.index[..self.len].iter().position(|&x| x == q) {
            self.weight[p] += w;
            self.dweight[p] += dw;
        } else {
            self.index[self.len] = q;
            self.weight[self.len] = w;
            self.dweight[self.len] = dw;
            self.len += 1;
        }
    }
    /// The interpolated value of `family` (the knots' values).
    pub fn value(&self, family: &[f64]) -> f64 {
        (0..self.len)
            .map(|p| self.weight[p] * family[self.index[p]])
            .sum()
    }
    /// Its derivative in current.
    pub fn slope(&self, family: &[f64]) -> f64 {
        if self.linear && self.len == 2 {
            return (family[self.index[1]] - family[self.index[0]]) * self.dweight[1];
        }
        (0..self.len)
            .map(|p| self.dweight[p] * family[self.index[p]])
            .sum()
    }
    /// The (index, weight) pairs.
    pub fn pairs(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        (0..self.len).map(|p| (self.index[p], self.weight[p]))
    }
}

/// How the yield force is interpolated in current between the knots of a grid (a
/// continuously varying current; held levels are always joined by straight lines).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum YieldCurve {
    /// Straight lines between knots.
    Lines,
    /// A cubic Hermite curve through the knots ([`knot_interpolation`]).
    Cubic,
    /// The option's default: the baseline is settled on both and the one that fits the
    /// fitting blocks better is kept (`select::settled_baseline_on_its_curve`); never the
    /// curve of a [`Prepared`] record, which the model reads as lines.
    #[default]
    Auto,
}

impl YieldCurve {
    /// Name on the command line and in the report.
    pub fn name(self) -> &'static str {
        match self {
            YieldCurve::Lines => "lines",
            YieldCurve::Cubic => "cubic",
            YieldCurve::Auto => "auto",
        }
    }
    /// The curve of a name ([`YieldCurve::name`]).
    pub fn parse(s: &str) -> Option<Self> {
        [YieldCurve::Lines, YieldCurve::Cubic, YieldCurve::Auto]
            .into_iter()
            .find(|x| x.name() == s)
    }
}

/// The interpolation of the knots at current `i`: straight lines between knots
/// ([`knot_weights`]), or with `cubic` a cubic Hermite curve whose slope at each interior
/// knot is that of the parabola through it and its two neighbours (the secant at the end
/// knots). Both pass through every knot and are flat beyond the end knots; the curve's
/// weights are linear in the knots' values, so a fit's Jacobian stays a sum of columns.
///
/// The yield force of a grid of knots over a continuously varying current takes the curve
/// under [`YieldCurve::Cubic`] ([`crate::model`]): against the generator's own τ0(I) at the
/// knots of continuous-current proving-ground records, straight lines are 1.3–4 σ_F off
/// and the curve 0.3–0.9 σ_F (docs/diagnose.md, Limits).
pub fn knot_interpolation(knots: &[f64], i: f64, cubic: bool) -> KnotInterpolation {
    let (k, lam, dlam) = knot_weights(knots, i);
    let nk = knots.len();
    let mut out = KnotInterpolation {
        index: [0; 4],
        weight: [0.0; 4],
        dweight: [0.0; 4],
        len: 0,
        linear: false,
    };
    if nk == 1 {
        out.add(0, 1.0, 0.0);
        return out;
    }
    let k2 = k + 1;
    if !cubic || nk < 3 || dlam == 0.0 {
        out.linear = true;
        out.add(k, 1.0 - lam, -dlam);
        out.add(k2, lam, dlam);
        return out;
    }
    let h = knots[k2] - knots[k];
    let t = lam;
    let (t2, t3) = (t * t, t * t * t);
    let (h00, h10, h01, h11) = (
        2.0 * t3 - 3.0 * t2 + 1.0,
        t3 - 2.0 * t2 + t,
        -2.0 * t3 + 3.0 * t2,
        t3 - t2,
    );
    let (d00, d10, d01, d11) = (
        (6.0 * t2 - 6.0 * t) / h,
        (3.0 * t2 - 4.0 * t + 1.0) / h,
        (-6.0 * t2 + 6.0 * t) / h,
        (3.0 * t2 - 2.0 * t) / h,
    );
    out.add(k, h00, d00);
    out.add(k2, h01, d01);
    // h · slope at knot q as weights on the knots: the parabola's derivative through q's
    // neighbours, or the secant at an end knot.
    let slope = |q: usize| -> [(usize, f64); 3] {
        if q == 0 {
            let g = knots[1] - knots[0];
            [(0, -h / g), (1, h / g), (1, 0.0)]
        } else if q == nk - 1 {
            let g = knots[q] - knots[q - 1];
            [(q - 1, -h / g), (q, h / g), (q, 0.0)]
        } else {
            let (a, b) = (knots[q] - knots[q - 1], knots[q + 1] - knots[q]);
            [
                (q - 1, -h * b / (a * (a + b))),
                (q, h * (b - a) / (a * b)),
                (q + 1, h * a / (b * (a + b))),
            ]
        }
    };
    for (q, w) in slope(k) {
        out.add(q, h10 * w, d10 * w);
    }
    for (q, w) in slope(k2) {
        out.add(q, h11 * w, d11 * w);
    }
    out
}

/// The knot nearest current `i` by interpolation weight: the one [`knot_weights`] gives at
/// least half the weight.
pub fn nearest_knot(knots: &[f64], i: f64) -> usize {
    let (k, lam, _) = knot_weights(knots, i);
    if lam > 0.5 {
        (k + 1).min(knots.len() - 1)
    } else {
        k
    }
}

/// Two currents closer than this are one level: 2 % of the largest |I|, at least 1 mA.
pub fn level_tolerance(i: &[f64]) -> f64 {
    let imax = i.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    (0.02 * imax).max(1e-3)
}

/// Strokes: a new cycle where v turns from below −5 % to above +5 % of the peak speed
/// (and at every time gap). Returns the cycle of each sample and the number of cycles.
fn strokes(v: &[f64], h: &[f64], vpeak: f64) -> (Vec<usize>, usize) {
    let thr = 0.05 * vpeak;
    let mut cycle = vec![0usize; v.len()];
    let (mut c, mut state, mut start) = (0usize, 0i8, 0usize);
    for k in 0..v.len() {
        if h[k] == 0.0 && k > 0 {
            c += 1;
            start = k;
            state = 0;
        }
        if v[k] < -thr {
            state = -1;
        } else if v[k] > thr && state == -1 {
            state = 1;
            if k - start > 4 {
                c += 1;
                start = k;
            }
        }
        cycle[k] = c;
    }
    (cycle, c + 1)
}

/// Segments: a new one at a current step, a time gap, or where the stroke period changes
/// by more than 20 %.
fn segments(
    t: &[f64],
    i: &[f64],
    h: &[f64],
    cycle: &[usize],
    cycles: usize,
) -> (Vec<usize>, usize) {
    let n = t.len();
    let tol = level_tolerance(i);
    let mut cycle_start = vec![0usize; cycles];
    let mut cycle_end = vec![0usize; cycles];
    for k in (0..n).rev() {
        cycle_start[cycle[k]] = k;
    }
    for k in 0..n {
        cycle_end[cycle[k]] = k;
    }
    let mut segment = vec![0usize; n];
    let mut seg = 0usize;
    let mut period_prev: Option<f64> = None;
    for k in 0..n {
        let mut new = k > 0 && (h[k] == 0.0 || (i[k] - i[k - 1]).abs() > tol);
        if k > 0 && cycle[k] != cycle[k - 1] {
            let cc = cycle[k];
            let period = t[cycle_end[cc]] - t[cycle_start[cc]];
            let complete = cc + 1 < cycles;
            if let (Some(p), true) = (period_prev, complete) {
                if (period / p - 1.0).abs() > 0.2 {
                    new = true;
                }
            }
            if complete {
                period_prev = Some(period);
            }
        }
        if new {
            seg += 1;
        }
        segment[k] = seg;
    }
    (segment, seg + 1)
}

/// Runs of one held current: a new run at every current step or time gap; the few
/// samples of a filtered step's transition join the run before them (a run shorter than
/// half a stroke period is no run of its own).
fn current_runs(t: &[f64], i: &[f64], h: &[f64], period: f64) -> (Vec<usize>, usize) {
    let tol = level_tolerance(i);
    let n = i.len();
    // Half a stroke period, but no longer than a sixteenth of the record: a record of a
    // few slow strokes (3.7 s period in 4 s) still has runs of its held levels.
    let shortest = (t[n - 1] - t[0]) / 16.0;
    let mut starts = vec![0usize];
    for k in 1..n {
        if h[k] == 0.0 || (i[k] - i[k - 1]).abs() > tol {
            starts.push(k);
        }
    }
    starts.push(n);
    let mut kept: Vec<usize> = Vec::new();
    for w in starts.windows(2) {
        let (a, b) = (w[0], w[1]);
        let gap_before = a > 0 && h[a] == 0.0;
        if kept.is_empty() || gap_before || t[b - 1] - t[a] >= (0.5 * period).min(shortest) {
            kept.push(a);
        }
    }
    let mut run = vec![0usize; n];
    for (r, w) in kept
        .iter()
        .chain(std::iter::once(&n))
        .collect::<Vec<_>>()
        .windows(2)
        .enumerate()
    {
        run[*w[0]..*w[1]].fill(r);
    }
    (run, kept.len())
}

/// Sample ranges of the parts `part` numbers (each part contiguous).
fn part_ranges(part: &[usize], parts: usize) -> Vec<(usize, usize)> {
    let mut range = vec![(usize::MAX, 0usize); parts];
    for (j, &s) in part.iter().enumerate() {
        range[s].0 = range[s].0.min(j);
        range[s].1 = j + 1;
    }
    range
}

/// At most 8 parts, each at least two stroke periods long: cut each part into blocks.
fn few_long_parts(t: &[f64], part: &[usize], parts: usize, period: f64) -> bool {
    parts <= 8
        && part_ranges(part, parts)
            .iter()
            .all(|&(a, b)| a < b && t[b - 1] - t[a] >= 2.0 * period)
}

/// Most validation blocks in a record.
const MAX_BLOCKS: usize = 16;

/// Validation blocks: contiguous stretches of time, each about three typical stroke
/// periods long (shorter only to have four blocks), alternately fitted and held out.
/// Alternate strokes of a periodic record are near-copies of each other, so holding out
/// every other stroke says little about new data; a held-out block is a stretch the fit
/// has not seen.
///
/// When the record is a few long parts (≤ 8, each ≥ 2 stroke periods: segments of one
/// current and frequency, or, under random strokes, runs of one held current), every
/// part is cut into an even number of blocks, so each part's current and frequency is
/// both fitted and held out. Otherwise (stepped or random currents) the whole record is
/// cut into an even
/// number of equal blocks. Returns the block of each sample, the number of blocks and a
/// description.
fn validation_blocks(
    t: &[f64],
    segment: &[usize],
    segments: usize,
    period: f64,
    what: &str,
) -> (Vec<usize>, usize, String) {
    let n = t.len();
    let seg_range = part_ranges(segment, segments);
    let dur = |a: usize, b: usize| t[b - 1] - t[a];
    // Three stroke periods, but at least four blocks in a short record.
    let target = (3.0 * period).min(dur(0, n) / 4.0);
    let even_count = |d: f64, most: usize| -> usize {
        let k = ((d / target).floor() as usize).clamp(2, most.max(2));
        k - k % 2
    };
    let per_segment = few_long_parts(t, segment, segments, period);
    let (block, next);
    let method;
    if per_segment {
        let most = (MAX_BLOCKS / segments).max(2);
        (block, next) = blocks_within_parts(t, &seg_range, |a, b| even_count(dur(a, b), most));
        method = format!(
            "contiguous blocks within each of the {segments} {what} (each cut into an even \
             number of blocks of at least three stroke periods); even blocks fit, odd blocks \
             held out, so every part's current and frequency is in both"
        );
    } else {
        next = even_count(dur(0, n), MAX_BLOCKS);
        block = equal_blocks(t, next);
        method = format!(
            "{next} contiguous blocks of equal time (at least three stroke periods each); \
             even blocks fit, odd blocks held out"
        );
    }
    (block, next, method)
}

/// Each part (a sample range `(a, b)`) cut into `blocks(a, b)` contiguous blocks of equal
/// time, numbered on from part to part. Returns the block of each sample (0 outside the
/// parts) and the number of blocks.
fn blocks_within_parts(
    t: &[f64],
    parts: &[(usize, usize)],
    blocks: impl Fn(usize, usize) -> usize,
) -> (Vec<usize>, usize) {
    let mut block = vec![0usize; t.len()];
    let mut next = 0usize;
    for &(a, b) in parts {
        let k = blocks(a, b);
        let (t0, len) = (t[a], (t[b - 1] - t[a]).max(1e-12));
        for j in a..b {
            block[j] = next + (((t[j] - t0) / len * k as f64) as usize).min(k - 1);
        }
        next += k;
    }
    (block, next)
}

/// `k` contiguous blocks of equal time over the record (block of each sample).
fn equal_blocks(t: &[f64], k: usize) -> Vec<usize> {
    blocks_within_parts(t, &[(0, t.len())], |_, _| k).0
}

/// The energy the damper has dissipated since the record's start, in kJ: the trapezoidal
/// integral of the power F·v it absorbs (negative power, the gas or the mass giving energy
/// back, counted as zero). The thermal-softening candidate's driver.
fn dissipated_energy_kj(f: &[f64], v: &[f64], h: &[f64]) -> Vec<f64> {
    let mut energy_kj = vec![0.0; f.len()];
    for k in 1..f.len() {
        let p = 0.5 * (f[k] * v[k] + f[k - 1] * v[k - 1]);
        energy_kj[k] = energy_kj[k - 1] + h[k] * p.max(0.0) * 1e-3;
    }
    energy_kj
}

/// Whether the current is held at a few levels: at most 12 knots, with at least 90 % of
/// the samples on one of them.
fn held_at_levels(i: &[f64], knots: &[f64]) -> bool {
    let tol = level_tolerance(i);
    let on = i
        .iter()
        .filter(|c| knots.iter().any(|k| (k - *c).abs() <= tol))
        .count();
    knots.len() <= 12 && on as f64 >= 0.9 * i.len() as f64
}

/// Each sample's stroke speed (the peak |v| of its stroke) and its phase in the stroke:
/// near reversal below a quarter of that speed, else accelerating or decelerating.
fn stroke_phases(v: &[f64], a: &[f64], cycle: &[usize], cycles: usize) -> (Vec<f64>, Vec<Phase>) {
    let mut stroke_peak = vec![0.0f64; cycles];
    for (&c, vk) in cycle.iter().zip(v) {
        stroke_peak[c] = stroke_peak[c].max(vk.abs());
    }
    let stroke_speed: Vec<f64> = cycle.iter().map(|&c| stroke_peak[c]).collect();
    let phase = v
        .iter()
        .zip(a)
        .zip(&stroke_speed)
        .map(|((&vk, &ak), &speed)| {
            if vk.abs() < 0.25 * speed {
                Phase::NearReversal
            } else if vk * ak > 0.0 {
                Phase::Accelerating
            } else {
                Phase::Decelerating
            }
        })
        .collect();
    (stroke_speed, phase)
}

/// The validation blocks chosen: the block of each sample, the number of blocks and a
/// description.
type BlockChoice = (Vec<usize>, usize, String);

/// What the choice of validation blocks weighs: the record's time, current and current
/// levels, its segments and its runs of one current.
struct BlockSplit<'a> {
    t: &'a [f64],
    i: &'a [f64],
    knots: &'a [f64],
    segment: &'a [usize],
    segments: usize,
    run: Vec<usize>,
    runs: usize,
    period: f64,
    /// The samples where a run of one current ends and the next begins.
    step_at: Vec<usize>,
    tol: f64,
}

impl<'a> BlockSplit<'a> {
    fn new(
        t: &'a [f64],
        i: &'a [f64],
        h: &[f64],
        knots: &'a [f64],
        (segment, segments): (&'a [usize], usize),
        period: f64,
    ) -> Self {
        let (run, runs) = current_runs(t, i, h, period);
        let step_at = (1..t.len()).filter(|&j| run[j] != run[j - 1]).collect();
        BlockSplit {
            t,
            i,
            knots,
            segment,
            segments,
            run,
            runs,
            period,
            step_at,
            tol: level_tolerance(i),
        }
    }

    /// How many current levels the fitting (even) blocks of `b` leave out of the fit.
    fn unseen(&self, b: &[usize]) -> usize {
        let fitted: Vec<bool> = b.iter().map(|k| k % 2 == 0).collect();
        self.knots.len() - knots_the_fit_can_see(self.knots.to_vec(), self.i, &fitted).len()
    }

    /// A field lag shows only in the few ms after a current step: with every step in the
    /// held-out blocks (3 steps 0.97 s apart against blocks of 0.5 s, proving-ground seed
    /// 253) the fit cannot see the lag, and fits noise in its place.
    fn one_sided(&self, b: &[usize]) -> bool {
        self.step_at.len() >= 2 && self.step_at.iter().all(|&j| b[j] % 2 == 1)
    }

    /// The smallest share of a current level's samples that `b` puts in the fitting blocks.
    fn worst_share(&self, b: &[usize]) -> f64 {
        let n = self.t.len();
        self.knots
            .iter()
            .filter_map(|&k| {
                let at: Vec<usize> = (0..n)
                    .filter(|&j| (self.i[j] - k).abs() <= self.tol)
                    .collect();
                let fit = at.iter().filter(|&&j| b[j] % 2 == 0).count();
                (!at.is_empty()).then(|| fit as f64 / at.len() as f64)
            })
            .fold(1.0, f64::min)
    }

    /// The blocks by segment ([`validation_blocks`]), unless the record's current calls
    /// for another cut: random strokes make many short "segments", and equal blocks may
    /// leave a held current level to the held-out blocks alone, with nothing to predict it
    /// from. Then the runs of one current are cut instead (each both fitted and held out),
    /// when they are few and long.
    fn choose(&self) -> BlockChoice {
        let t = self.t;
        let by_segment = validation_blocks(t, self.segment, self.segments, self.period, "segments");
        let segments_few_long = few_long_parts(t, self.segment, self.segments, self.period);
        let runs_few_long = few_long_parts(t, &self.run, self.runs, self.period);
        // Every path below reads it at least once.
        let unseen_by_segment = self.unseen(&by_segment.0);
        if let Some(b) = self.halved_runs(
            (&by_segment.0, unseen_by_segment),
            segments_few_long,
            runs_few_long,
        ) {
            let runs = self.runs;
            (
                b,
                2 * runs,
                format!(
                    "{} blocks: each of the {runs} runs of one held current cut in two, the \
                     first half fitted and the second held out (equal blocks left a level with \
                     under a third of its samples fitted)",
                    2 * runs
                ),
            )
        } else if !segments_few_long && runs_few_long && unseen_by_segment > 0 {
            let by_run = validation_blocks(t, &self.run, self.runs, self.period, "current levels");
            if self.unseen(&by_run.0) < unseen_by_segment {
                by_run
            } else {
                by_segment
            }
        } else if (unseen_by_segment > 0 || self.one_sided(&by_segment.0)) && !segments_few_long {
            self.nearby_equal_blocks(by_segment)
        } else {
            by_segment
        }
    }

    /// A record of a few slow strokes (a 4 s random record with a 3.7 s stroke period) is
    /// cut into four blocks, and a held level may then have a quarter of its samples in
    /// the fitting blocks, one stroke direction or speed: predicted from that, its held-out
    /// blocks were 10–17 σ_F off (seeds 166, 190). When some level has less than a third
    /// of its samples fitted, a few runs of one current (at most 8, each at least an
    /// eighth of the record) are cut in half instead, if that fits the worst level's share
    /// better by 0.1 and leaves no more levels unfitted.
    fn halved_runs(
        &self,
        (by_segment, unseen_by_segment): (&[usize], usize),
        segments_few_long: bool,
        runs_few_long: bool,
    ) -> Option<Vec<usize>> {
        let (t, n) = (self.t, self.t.len());
        let run_range = part_ranges(&self.run, self.runs);
        let runs_long = self.runs <= 8
            && run_range
                .iter()
                .all(|&(a, b)| a < b && t[b - 1] - t[a] >= (t[n - 1] - t[0]) / 8.0);
        if segments_few_long || runs_few_long || !runs_long {
            return None;
        }
        let share_by_segment = self.worst_share(by_segment);
        if share_by_segment >= 1.0 / 3.0 {
            return None;
        }
        let b = blocks_within_parts(t, &run_range, |_, _| 2).0;
        (self.worst_share(&b) > share_by_segment + 0.1 && self.unseen(&b) <= unseen_by_segment)
            .then_some(b)
    }

    /// Equal blocks can alias with a periodic current sequence (4 levels of 0.9 s each
    /// against blocks of 1.76 s left one level to the held-out blocks alone, and the
    /// baseline 39 σ_F off there), or put every current step in the held-out blocks: try
    /// the even block counts near it, for the split that leaves fewest levels unfitted,
    /// then has a step in the fitting blocks (not fewer blocks than 4 less: blocks are the
    /// held-out evidence). The blocks' parity stays (even blocks fit): with random levels a
    /// swapped parity left two knots whose yield force ran away (null seed 235: held-out
    /// RMS 28 → 3452 N).
    fn nearby_equal_blocks(&self, by_segment: BlockChoice) -> BlockChoice {
        let base = by_segment.1;
        let key = |b: &[usize], k: usize| (self.unseen(b), self.one_sided(b), k.abs_diff(base));
        let mut best_key = key(&by_segment.0, base);
        let mut best = by_segment;
        for k in (base.saturating_sub(4).max(4)..=(base + 4).min(MAX_BLOCKS)).step_by(2) {
            let b = equal_blocks(self.t, k);
            let kb = key(&b, k);
            if kb < best_key {
                let method = format!(
                    "{k} contiguous blocks of equal time; even blocks fit, odd blocks held \
                     out (the count that leaves fewest current levels out of the fit, then \
                     puts a current step in the fitting blocks)"
                );
                best = (b, k, method);
                best_key = kb;
            }
        }
        best
    }
}

/// A held-out sample at a current beyond every level the fit reached is an extrapolation,
/// not a prediction (proving-ground seed 28: the last 0.2 s at 1.47 A, fitted up to
/// 1.06 A, held 91 % of the baseline's held-out error); one held at a level the fit never
/// saw (random held levels, each held once) tests how F_y is interpolated between levels,
/// which no candidate changes (seed 56: 0.74 A held 3.4 s in the held-out blocks and
/// 0.13 s in the fitting ones, 270 N off against 23 N). Neither is scored (taken out of
/// `holdout` when there are at least 20 of them and 100 scored samples stay). Samples
/// between levels (a current step's transient) are. Returns the split's description,
/// with what was left out.
fn leave_out_unscored(
    i: &[f64],
    holdout: &mut [bool],
    (levels, knots): (&[f64], &[f64]),
    held_levels: bool,
    split_method: String,
) -> String {
    let tol = level_tolerance(i);
    let (lo, hi) = fitted_range(knots, tol);
    let unfitted = if held_levels {
        unfitted_levels(levels, knots, tol)
    } else {
        Vec::new()
    };
    let Unscored {
        samples: outside,
        beyond,
        at_unfitted,
    } = unscored(i, holdout, (lo, hi), &unfitted, tol);
    if !take_out_of_holdout(holdout, &outside) {
        return split_method;
    }
    let mut why = Vec::new();
    if beyond > 0 {
        why.push(format!(
            "{beyond} at currents beyond the fitted levels ({:.3}–{:.3} A)",
            lo + tol,
            hi - tol
        ));
    }
    if at_unfitted > 0 {
        let list: Vec<String> = unfitted.iter().map(|l| format!("{l:.3}")).collect();
        why.push(format!(
            "{at_unfitted} at levels the fit did not see ({} A)",
            list.join(", ")
        ));
    }
    format!(
        "{split_method}; {} held-out samples are not scored: {}",
        outside.len(),
        why.join("; ")
    )
}

/// Takes `outside` out of `holdout` when there are at least 20 of them and 100 held-out
/// samples stay scored; whether it did.
fn take_out_of_holdout(holdout: &mut [bool], outside: &[usize]) -> bool {
    let scored = holdout.iter().filter(|h| **h).count() - outside.len();
    if outside.len() < 20 || scored < 100 {
        return false;
    }
    for &j in outside {
        holdout[j] = false;
    }
    true
}

/// How much faster than the fastest fitting sample at its current knot a held-out sample
/// may move and still be scored ([`leave_out_beyond_reach`]).
pub const FIT_SPEED_REACH: f64 = 1.25;

/// Held-out samples that move faster than [`FIT_SPEED_REACH`] times the fastest fitting
/// sample at their nearest current knot: the fluid law there (yield, viscous coefficient,
/// speed curvature) is extrapolated in speed, not predicted, and a candidate that moves
/// the knot moves that extrapolation far more than anything it explains. Proving-ground
/// seed 739 (a bi-viscous fluid yielding near 5 mm/s under random strokes and currents):
/// at 1.01 A the fitting blocks reach 3.5 mm/s and the held-out ones 7 mm/s, 183 N
/// held-out RMS there against 25 N fitted; the thermal softening hidden in it predicted
/// the pooled held-out blocks 69 → 273 N. Not scored, with [`leave_out_unscored`]'s
/// proviso (at least 20 of them, 100 scored samples stay).
/// Returns the split's description, with what was left out.
fn leave_out_beyond_reach(
    (i, v): (&[f64], &[f64]),
    train: &[bool],
    holdout: &mut [bool],
    knots: &[f64],
    split_method: String,
) -> String {
    let mut reach = vec![0.0f64; knots.len()];
    for j in (0..i.len()).filter(|&j| train[j]) {
        let k = nearest_knot(knots, i[j]);
        reach[k] = reach[k].max(v[j].abs());
    }
    let outside: Vec<usize> = (0..i.len())
        .filter(|&j| holdout[j] && v[j].abs() > FIT_SPEED_REACH * reach[nearest_knot(knots, i[j])])
        .collect();
    if !take_out_of_holdout(holdout, &outside) {
        return split_method;
    }
    format!(
        "{split_method}; {} held-out samples faster than {FIT_SPEED_REACH} times the fitting \
         samples at their current knot are not scored",
        outside.len()
    )
}

/// The middle of the displacement's range and half the range: the stroke's centre and
/// amplitude.
fn stroke_range(x: &[f64]) -> (f64, f64) {
    let hi = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let lo = x.iter().copied().fold(f64::INFINITY, f64::min);
    (0.5 * (lo + hi), 0.5 * (hi - lo))
}

/// Check and prepare the signals: validate, apply the measurement model, find strokes,
/// segments, phases and current knots, and split into validation blocks.
pub fn prepare(s: &Signals) -> Result<Prepared, DataError> {
    validate(s)?;
    let n = s.time_s.len();
    let t = s.time_s.clone();
    let x = s.displacement_m.clone();
    let f = s.force_n.clone();
    let h = steps(&t);
    let m = crate::measure::measure(&t, &x, &s.velocity_m_s, &f, &h, s.velocity_derived);
    let current = crate::current::ConditionedCurrent::condition(
        &t,
        &h,
        &s.current_a,
        m.summary.sample_interval_s,
    );
    let placed = current.place(&t, &h, None);
    let i = placed.i;
    let v = m.v;
    let a = m.a;
    let vpeak = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if vpeak <= 0.0 {
        return Err(DataError(
            "the piston does not move (velocity is zero throughout)".into(),
        ));
    }
    let energy_kj = dissipated_energy_kj(&f, &v, &h);
    let knots = current_knots(&i);
    let held_levels = held_at_levels(&i, &knots);
    let (cycle, cycles) = strokes(&v, &h, vpeak);
    let (stroke_speed, phase) = stroke_phases(&v, &a, &cycle, cycles);
    let (segment, segments) = segments(&t, &i, &h, &cycle, cycles);
    let period = m.summary.stroke_period_s;
    let (block, blocks, split_method) =
        BlockSplit::new(&t, &i, &h, &knots, (&segment, segments), period).choose();
    let excluded = m.excluded;
    if excluded.iter().filter(|e| !**e).count() < 200 {
        return Err(DataError(
            "fewer than 200 samples are left once the stuck (flat-lined) stretches and the \
             ends of the record and its segments (one local window each) are taken out"
                .into(),
        ));
    }
    let in_blocks = |parity: usize| -> Vec<bool> {
        block
            .iter()
            .zip(&excluded)
            .map(|(b, e)| b % 2 == parity && !e)
            .collect()
    };
    let mut holdout = in_blocks(1);
    let train = in_blocks(0);
    let levels = knots.clone();
    let knots = knots_the_fit_can_see(knots, &i, &train);
    let split_method = leave_out_unscored(
        &i,
        &mut holdout,
        (&levels, &knots),
        held_levels,
        split_method,
    );
    let split_method = leave_out_beyond_reach((&i, &v), &train, &mut holdout, &knots, split_method);
    let leak_velocity_min = crate::measure::LEAK_PER_SIGMA * m.summary.rebuilt_velocity_sigma_m_s;
    let friction_velocity = (0.01 * vpeak).max(leak_velocity_min);
    let (stroke_centre_m, half_stroke_m) = stroke_range(&x);
    let mut prepared = Prepared {
        t,
        x,
        v,
        v_sigma: m.v_sigma,
        weight: vec![1.0; n],
        a,
        i,
        f,
        energy_kj,
        h,
        held_levels,
        yield_curve: YieldCurve::Cubic,
        knots,
        knot_smoothing: [0.0; 3],
        anti_alias: None,
        subgrid: crate::subsample::SubGrid::default(),
        current,
        current_step_at: placed.step_at,
        cycle,
        cycles,
        segment,
        segments,
        phase,
        stroke_speed,
        holdout,
        train,
        excluded,
        block,
        blocks,
        friction_velocity,
        velocity_scale: vpeak,
        half_stroke_m,
        stroke_centre_m,
        measurement: m.summary,
        split_method,
    };
    prepared.subgrid = crate::subsample::SubGrid::build(
        &prepared.channels(),
        crate::subsample::OVERSAMPLING,
        &prepared.current_step_at,
    );
    Ok(prepared)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn cubic_knot_interpolation_passes_through_the_knots_and_follows_a_parabola_inside() {
        // Uneven knots; a parabola's values at them.
        let knots = [0.0, 0.3, 0.5, 0.9, 1.2, 2.0];
        let f = |i: f64| 3.0 - 2.0 * i + 1.5 * i * i;
        let fam: Vec<f64> = knots.iter().map(|&k| f(k)).collect();
        for (q, &k) in knots.iter().enumerate() {
            let ip = knot_interpolation(&knots, k, true);
            assert!((ip.value(&fam) - fam[q]).abs() < 1e-12, "knot {q}");
        }
        // Between interior knots (slopes from parabolas through three knots, exact for a
        // parabola) the curve is the parabola, and so is its slope; the linear one is not.
        for i in [0.35, 0.47, 0.6, 0.85, 1.0, 1.15] {
            let ip = knot_interpolation(&knots, i, true);
            assert!((ip.value(&fam) - f(i)).abs() < 1e-12, "value at {i}");
            assert!(
                (ip.slope(&fam) - (-2.0 + 3.0 * i)).abs() < 1e-9,
                "slope at {i}"
            );
            let w: f64 = ip.pairs().map(|(_, w)| w).sum();
            assert!((w - 1.0).abs() < 1e-12);
            let lin = knot_interpolation(&knots, i, false);
            assert!((lin.value(&fam) - f(i)).abs() > 1e-4, "linear at {i}");
        }
        // Flat beyond the end knots.
        let ip = knot_interpolation(&knots, 2.5, true);
        assert!((ip.value(&fam) - fam[5]).abs() < 1e-12 && ip.slope(&fam) == 0.0);
    }

    /// `n` samples `dt` apart of a sinusoidal stroke of amplitude `amp` at `freq(t)` Hz
    /// (exact velocity), the current `current(t)` and the force `force(t, v, i)`.
    pub(crate) fn sine_record(
        n: usize,
        dt: f64,
        amp: f64,
        freq: impl Fn(f64) -> f64,
        current: impl Fn(f64) -> f64,
        force: impl Fn(f64, f64, f64) -> f64,
    ) -> Signals {
        let mut s = Signals::default();
        for k in 0..n {
            let t = k as f64 * dt;
            let w = 2.0 * std::f64::consts::PI * freq(t);
            let (v, i) = (amp * w * (w * t).cos(), current(t));
            s.time_s.push(t);
            s.displacement_m.push(amp * (w * t).sin());
            s.velocity_m_s.push(v);
            s.current_a.push(i);
            s.force_n.push(force(t, v, i));
        }
        s
    }

    fn sine(n: usize) -> Signals {
        let w = 2.0 * std::f64::consts::PI * 3.0;
        sine_record(
            n,
            0.001,
            0.01,
            |_| 3.0,
            |t| if t < 1.0 { 0.0 } else { 1.0 },
            |t, _, _| 100.0 * (w * t).cos(),
        )
    }

    #[test]
    fn held_out_samples_beyond_or_at_an_unfitted_level_are_not_scored() {
        // Levels 0, 0.5, 1 and 1.5 A held in turn; 1 A held only in held-out samples, and
        // 1.5 A beyond the fitted knots; a transient between levels stays scored.
        let i = [0.0, 0.0, 0.5, 0.5, 0.75, 1.0, 1.0, 1.5, 1.5, 0.5];
        let holdout = [
            false, true, false, true, true, true, true, true, false, true,
        ];
        let levels = [0.0, 0.5, 1.0, 1.5];
        let knots = [0.0, 0.5];
        let tol = 0.03;
        let unfitted = unfitted_levels(&levels, &knots, tol);
        assert_eq!(unfitted, vec![1.0, 1.5]);
        let u = unscored(&i, &holdout, fitted_range(&knots, tol), &unfitted, tol);
        // 1.5 A lies beyond the fitted range: counted there, not as an unfitted level.
        assert_eq!(
            u,
            Unscored {
                samples: vec![4, 5, 6, 7],
                beyond: 4,
                at_unfitted: 0
            },
            "0.75 A is beyond 0.5 A too"
        );
        let wide = unscored(&i, &holdout, (-0.03, 1.53), &unfitted, tol);
        assert_eq!(wide.samples, vec![5, 6, 7]);
        assert_eq!((wide.beyond, wide.at_unfitted), (0, 3));
    }

    #[test]
    fn held_out_samples_faster_than_the_fit_reaches_at_their_knot_are_not_scored() {
        // Knots 0 and 1 A. At 0 A the fitting samples reach 10 mm/s and the held-out ones
        // 12 and 13 mm/s; at 1 A the fitting samples reach 5 mm/s, the held-out 20 mm/s.
        let knots = [0.0, 1.0];
        let mut i = Vec::new();
        let mut v = Vec::new();
        let mut train = Vec::new();
        let mut put = |c: f64, speed: f64, fit: bool, n: usize| {
            for k in 0..n {
                i.push(c);
                v.push(if k % 2 == 0 { speed } else { -speed });
                train.push(fit);
            }
        };
        put(0.0, 0.010, true, 100);
        put(0.0, 0.012, false, 100);
        put(0.0, 0.013, false, 30);
        put(1.0, 0.005, true, 100);
        put(1.0, 0.020, false, 30);
        // 0.4 A is nearest the 0 A knot; 0.6 A the 1 A knot.
        put(0.4, 0.012, false, 10);
        put(0.6, 0.012, false, 10);
        let holdout: Vec<bool> = train.iter().map(|t| !t).collect();
        let mut h = holdout.clone();
        let why = leave_out_beyond_reach((&i, &v), &train, &mut h, &knots, "split".into());
        let left_out: Vec<usize> = (0..h.len()).filter(|&j| holdout[j] && !h[j]).collect();
        // 12 mm/s is within 1.25 × 10 at 0 A (and at 0.4 A); 13 mm/s is not, nor are
        // 20 mm/s and 12 mm/s (0.6 A) against 5 mm/s at 1 A.
        let expect: Vec<usize> = (200..230).chain(330..360).chain(370..380).collect();
        assert_eq!(left_out, expect);
        assert!(why.contains("70 held-out samples faster"), "{why}");
        // Fewer than 20 beyond reach (200..215 of a held-out 100..215): all stay scored.
        let few: Vec<bool> = (0..h.len()).map(|j| holdout[j] && j < 215).collect();
        let mut h2 = few.clone();
        let same = leave_out_beyond_reach((&i, &v), &train, &mut h2, &knots, "split".into());
        assert_eq!((h2, same.as_str()), (few, "split"));
    }

    #[test]
    fn a_knot_fixed_only_in_a_blend_is_dropped() {
        // Fitting levels 0.5 A (between the knots at 0 and 1) and 2 A: the knots at 0 and
        // 1 are seen only as 0.5 F(0) + 0.5 F(1), each with plenty of support.
        let knots = vec![0.0, 1.0, 2.0];
        let i: Vec<f64> = (0..2000)
            .map(|k| if k < 1000 { 0.5 } else { 2.0 })
            .collect();
        let train = vec![true; i.len()];
        let kept = knots_the_fit_can_see(knots.clone(), &i, &train);
        assert_eq!(kept.len(), 2, "{kept:?}");
        assert!(kept.contains(&2.0), "{kept:?}");
        // A third fitting level on the other side of the knot at 1 A fixes both: kept.
        let i3: Vec<f64> = (0..3000)
            .map(|k| [0.5, 1.5, 2.0][k / 1000])
            .chain(std::iter::repeat_n(0.0, 1000))
            .collect();
        let kept = knots_the_fit_can_see(knots.clone(), &i3, &vec![true; i3.len()]);
        assert_eq!(kept, knots);
    }

    #[test]
    fn a_filtered_current_step_is_one_run_boundary() {
        // 0 A, then a step to 1 A through five transition samples, then 0.5 A: three runs.
        let n = 3000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let i: Vec<f64> = (0..n)
            .map(|k| match k {
                0..1000 => 0.0,
                1000..1005 => 0.2 * (k - 999) as f64,
                1005..2000 => 1.0,
                _ => 0.5,
            })
            .collect();
        let h = steps(&t);
        let (run, runs) = current_runs(&t, &i, &h, 0.2);
        assert_eq!(runs, 3);
        assert_eq!((run[999], run[1002], run[1500], run[2500]), (0, 0, 1, 2));
    }

    /// 4 s at 1 kHz of a ±10 mm sine at `freq` Hz, the current `current(t)`, and a
    /// Bingham-like force smoothed over `v_smooth` m/s.
    fn sine_with_current(freq: f64, v_smooth: f64, current: impl Fn(f64) -> f64) -> Signals {
        sine_record(
            4000,
            1e-3,
            0.01,
            |_| freq,
            current,
            |_, v, i| (200.0 + 800.0 * i) * (v / v_smooth).tanh() + 500.0 * v,
        )
    }

    #[test]
    fn a_current_step_is_left_in_the_fitting_blocks() {
        // Proving-ground seed 253's pattern: 4 s at 6 Hz, the current stepping 0 → 1 →
        // 1.5 A every 0.97 s. Eight equal blocks (three stroke periods each) put all four
        // steps in held-out blocks, where a field lag could be tested but never fitted.
        let s = sine_with_current(6.0, 0.01, |t| [0.0, 1.0, 1.5][((t / 0.97) as usize) % 3]);
        let steps_at: Vec<usize> = (1..4000)
            .filter(|&j| s.current_a[j] != s.current_a[j - 1])
            .collect();
        assert_eq!(steps_at.len(), 4);
        let eight = equal_blocks(&s.time_s, 8);
        assert!(
            steps_at.iter().all(|&j| eight[j] % 2 == 1),
            "the record no longer has every step held out under equal blocks"
        );
        let d = prepare(&s).unwrap();
        assert_ne!(d.blocks, 8, "{}", d.split_method);
        let fitted = steps_at.iter().filter(|&&j| d.train[j + 5]).count();
        assert!(fitted >= 1, "{}", d.split_method);
        assert!(
            fitted < steps_at.len(),
            "and one is held out: {}",
            d.split_method
        );
        assert_eq!(d.knots, vec![0.0, 1.0, 1.5], "every level still fitted");
    }

    #[test]
    fn a_slow_record_cuts_each_held_level_in_two() {
        // Proving-ground seed 166's pattern: 4 s holding 1.1, 0.55 and 0 A for 1.33 s each
        // under one slow stroke (3.7 s period). Four equal blocks leave the last level with
        // a quarter of its samples fitted; each level's run is cut in two instead.
        let s = sine_with_current(1.0 / 3.7, 0.002, |t| {
            [1.1, 0.55, 0.0][((t / (4.0 / 3.0)) as usize).min(2)]
        });
        let d = prepare(&s).unwrap();
        assert!(d.split_method.contains("cut in two"), "{}", d.split_method);
        assert_eq!(d.knots.len(), 3, "every level still fitted: {:?}", d.knots);
        for level in [0.0, 0.55, 1.1] {
            let at: Vec<usize> = (0..d.len()).filter(|&j| d.i[j] == level).collect();
            let fit = at.iter().filter(|&&j| d.train[j]).count() as f64;
            let held = at.iter().filter(|&&j| d.holdout[j]).count() as f64;
            let share = fit / (fit + held);
            assert!((0.4..=0.6).contains(&share), "{level} A: {share:.2} fitted");
        }
    }

    #[test]
    fn split_covers_every_current_and_phases_are_sane() {
        let d = prepare(&sine(2000)).unwrap();
        assert_eq!(d.knots, vec![0.0, 1.0]);
        assert!(d.cycles >= 6);
        for level in [0.0, 1.0] {
            let (mut tr, mut ho) = (0, 0);
            for j in 0..d.len() {
                if d.i[j] == level {
                    if d.holdout[j] {
                        ho += 1;
                    } else {
                        tr += 1;
                    }
                }
            }
            assert!(
                tr > 300 && ho > 300,
                "level {level}: {tr} fitting, {ho} held out"
            );
        }
        let near = d
            .phase
            .iter()
            .filter(|p| **p == Phase::NearReversal)
            .count();
        let share = near as f64 / d.len() as f64;
        // |cos| < 0.25 holds for 2 asin(0.25)/π ≈ 16 % of a sine.
        assert!((0.12..0.2).contains(&share), "near-reversal share {share}");
        assert!(d.segments >= 2);
    }

    #[test]
    fn bad_input_is_named() {
        let e = prepare(&sine(100)).unwrap_err();
        assert!(e.0.contains("only 100 samples"), "{e}");
        let mut s = sine(1000);
        s.force_n[500] = f64::NAN;
        assert!(prepare(&s).unwrap_err().0.contains("sample 500"));
        let mut s = sine(1000);
        s.velocity_m_s.iter_mut().for_each(|v| *v = 0.0);
        assert!(prepare(&s).unwrap_err().0.contains("does not move"));
        let mut s = sine(1000);
        s.current_a.pop();
        assert!(prepare(&s).unwrap_err().0.contains("current_A"));
    }
}
