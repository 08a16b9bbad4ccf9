//! Detection limits: the smallest size of each candidate effect that the record could have
//! shown, given the final model, its noise and the decision rules.
//!
//! "Nothing is missing" is a claim about sizes: an effect below what the record resolves
//! is not found, however real. So for every effect of the library the final model lacks,
//! the size at which the calibrated selector would accept it is computed in the model's
//! linearisation at the no-effect value, and reported beside the verdict.
//!
//! For effect e with size a (its first parameter: F_c, k, m, β, τ, C; the second, where
//! there is one, held at a stated shape), the change of the predicted force is `a g_e`,
//! `g_e` the secant (F(a) − F(0))/a of the whole prediction (sub-sample evaluation,
//! anti-alias filter), taken at the limit itself (up to three passes from a start of about
//! one noise unit). Refitting the final model's own parameters takes up the part of `g_e` in the span
//! of their Jacobian J: what the effect leaves is `h_e = g_e − J β`, `β` the weighted least
//! squares of `g_e` on J over the fitting samples (the knots' smoothness penalty
//! included, held parameters held). Then, with W the sample weights, s² the final model's
//! residual variance and the rules of `crate::select` (docs/diagnose.md §5):
//!
//! * **statistic**: T ≈ a² ‖h_e‖²_W / s² must beat the threshold t_e, the candidate's own
//!   bootstrap threshold from its last round (or, where it was screened out, the
//!   white-noise χ²(Δp) quantile scaled by the residual's AR(1) inflation m/n_eff):
//!   `a_T = s √(t_e / ‖h_e‖²_W)`;
//! * **interval**: the 95 % interval must clear zero, `a ≥ 1.96 s √(m/n_eff / ‖h_e‖²_W)`;
//! * **held-out gain**: the held-out mean square must fall by at least
//!   [`crate::Calibration::min_holdout_gain_noise`] σ_F², `a² ⟨h_e²⟩_W,held-out ≥ g σ_F²`;
//! * a chamber compliance must also deflect 0.1 of the displacement noise at the peak
//!   force (`select::compliance_resolved`);
//! * a field lag must be at least one step of the sub-sample grid, the sample interval
//!   over 8 (`select::lag_resolved`).
//!
//! The limit is the largest of these (about where the effect is found half the time). The
//! share of `g_e`'s weighted energy that J takes up is reported too: an effect whose
//! shape the fitted fluid law absorbs almost wholly (a current-independent Coulomb step is
//! a common offset of every knot's yield force) is not separable at any size.

use twin::Effect;

use crate::calibrate::Calibration;
use crate::data::Prepared;
use crate::model::{effect_params, evaluate, extend, Fit};
use crate::report::{DetectionLimit, Trial};
use crate::stats;

/// Presliding displacement at which a seal friction's limit is stated \[m\] (the middle of
/// the candidate's starts, 10–100 µm; bounded by the record's stroke).
pub const FRICTION_PRESLIDING_M: f64 = 3e-5;

/// Share of an effect's weighted energy the final model's parameters may take up before
/// the effect is reported as not separable on the record.
pub const NOT_SEPARABLE_SHARE: f64 = 0.999;

/// Relative eigenvalue below which a direction of the scaled normal matrix counts as one
/// the record does not resolve.
const PINV_CUTOFF: f64 = 1e-12;

/// The final model's linearisation over the fitting samples: its Jacobian and the
/// pseudo-inverse of the weighted normal matrix (penalty included, held parameters held).
struct Linearisation {
    jac: Vec<f64>,
    p: usize,
    normal: nalgebra::DMatrix<f64>,
}

impl Linearisation {
    fn new(d: &Prepared, fit: &Fit) -> Option<Self> {
        let lay = &fit.layout;
        let p = lay.len();
        let jac = evaluate(d, lay, &fit.theta, true).jac;
        let (jtj, _) =
            crate::model::penalised_normal_equations(d, lay, &fit.theta, &fit.force, &jac);
        // A pseudo-inverse of the column-scaled matrix: a knot the record leaves
        // unidentified (c of 10⁹ N s/m beside F_y of 10² N) makes it too ill-conditioned to
        // invert as it stands, and directions it cannot resolve are dropped, not amplified.
        let scale: Vec<f64> = (0..p)
            .map(|q| {
                let v = jtj[(q, q)];
                if v > 1e-300 {
                    1.0 / v.sqrt()
                } else {
                    0.0
                }
            })
            .collect();
        let a = nalgebra::DMatrix::<f64>::from_fn(p, p, |i, k| scale[i] * jtj[(i, k)] * scale[k]);
        let eig = nalgebra::SymmetricEigen::new(a);
        let top = eig.eigenvalues.iter().fold(0.0f64, |m, x| m.max(*x));
        if !(top.is_finite() && top > 0.0) {
            return None;
        }
        let inv: Vec<f64> = eig
            .eigenvalues
            .iter()
            .map(|&l| if l > PINV_CUTOFF * top { 1.0 / l } else { 0.0 })
            .collect();
        let q = &eig.eigenvectors;
        let normal = nalgebra::DMatrix::<f64>::from_fn(p, p, |i, k| {
            let s: f64 = (0..p).map(|m| q[(i, m)] * inv[m] * q[(k, m)]).sum();
            scale[i] * s * scale[k]
        });
        Some(Linearisation { jac, p, normal })
    }

    /// `g − J β`, β the weighted least squares of `g` on J over the fitting samples.
    fn unabsorbed(&self, d: &Prepared, g: &[f64]) -> Vec<f64> {
        let p = self.p;
        let mut jtg = nalgebra::DVector::<f64>::zeros(p);
        for j in (0..d.len()).filter(|&j| d.train[j]) {
            let wg = d.weight[j] * g[j];
            for (q, v) in self.jac[j * p..(j + 1) * p].iter().enumerate() {
                jtg[q] += v * wg;
            }
        }
        let beta = &self.normal * jtg;
        (0..d.len())
            .map(|j| {
                let row = &self.jac[j * p..(j + 1) * p];
                g[j] - row.iter().zip(beta.iter()).map(|(a, b)| a * b).sum::<f64>()
            })
            .collect()
    }
}

/// Weighted sums of a column over the fitting samples and its weighted mean square over
/// the held-out ones.
fn weighted_energy(d: &Prepared, h: &[f64]) -> (f64, f64) {
    let (mut train, mut ho, mut wsum) = (0.0, 0.0, 0.0);
    for (j, hj) in h.iter().enumerate() {
        let w = d.weight[j];
        if d.train[j] {
            train += w * hj * hj;
        } else if d.holdout[j] {
            ho += w * hj * hj;
            wsum += w;
        }
    }
    (train, ho / f64::max(wsum, 1e-300))
}

/// One shape an effect's limit is stated at: the seal friction at a presliding
/// displacement, or as a step without one (never reported, its absorbed share shown).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Shape {
    /// The effect's only shape (or its second parameter at its neutral value).
    Plain,
    /// A Dahl friction presliding over this displacement \[m\].
    Presliding(f64),
    /// A friction step without presliding (Coulomb, Stribeck): at the presliding bound.
    Step,
}

/// The effect's parameters at size `a` in shape `shape`.
fn effect_values(e: Effect, shape: Shape, a: f64) -> Vec<f64> {
    match (e, shape) {
        (Effect::SealFriction, Shape::Presliding(xp)) => vec![a, xp],
        (Effect::SealFriction, _) => vec![a, crate::model::XP_MIN],
        (Effect::FluidCompressibility, _) => vec![a, 0.0, 0.0, 0.0],
        (Effect::ThermalSoftening, _) => vec![a, 0.0],
        _ => vec![a],
    }
}

/// A first size of about one force-noise unit, from which the secant is taken.
fn start_size(d: &Prepared, e: Effect, fit: &Fit) -> f64 {
    let sigma = d.measurement.force_noise_hf_n.max(1e-9);
    let rms = |xs: &[f64]| (xs.iter().map(|x| x * x).sum::<f64>() / xs.len().max(1) as f64).sqrt();
    let fpeak = d.peak_force().max(1e-9);
    match e {
        Effect::SealFriction => sigma,
        Effect::GasSpring => sigma / rms(&d.x).max(1e-9),
        Effect::FluidInertia => sigma / rms(&d.a).max(1e-9),
        Effect::ThermalSoftening => {
            let e_end = d.energy_kj.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            sigma / (rms(&fit.force).max(1e-9) * e_end.max(1e-9))
        }
        Effect::FieldLag => 1e-3,
        Effect::FluidCompressibility => 0.002 * d.half_stroke_m.max(1e-6) / fpeak,
    }
}

/// What the secant at size `a` leaves: (g over every sample, h = g − Jβ).
fn secant(
    d: &Prepared,
    fit: &Fit,
    lin: &Linearisation,
    (e, shape): (Effect, Shape),
    a: f64,
) -> (Vec<f64>, Vec<f64>) {
    let lay = fit.layout.with(e);
    let theta = extend(
        &fit.layout,
        &fit.theta,
        &lay,
        &[(e, effect_values(e, shape, a))],
    );
    let f = evaluate(d, &lay, &theta, false).force;
    let g: Vec<f64> = f.iter().zip(&fit.force).map(|(x, y)| (x - y) / a).collect();
    let h = lin.unabsorbed(d, &g);
    (g, h)
}

/// The decision's threshold for `e`: its last trial's bootstrap threshold, or the white
/// χ²(Δp) quantile scaled by the AR(1) inflation where it was screened out.
fn threshold(e: Effect, trials: &[Trial], inflate: f64) -> Option<f64> {
    let last = trials.iter().rev().find(|t| t.effect == e.id())?;
    let c = last.evidence.calibration.as_ref()?;
    let dp = crate::model::tested_params(e) as f64;
    let white = stats::chi2_quantile(1.0 - c.alpha, dp);
    Some(if c.replicates > 0 {
        c.threshold.max(white)
    } else {
        white * inflate.max(1.0)
    })
}

/// The sizes each rule asks for, given the unabsorbed energies.
struct Asked {
    size: f64,
    rule: &'static str,
}

fn asked(
    d: &Prepared,
    e: Effect,
    (q_train, q_ho): (f64, f64),
    (s2, inflate, t): (f64, f64, f64),
    cal: &Calibration,
) -> Asked {
    let noise2 = d.measurement.force_noise_hf_n.powi(2);
    let mut rules = vec![
        ((t * s2 / q_train).sqrt(), "statistic"),
        (1.96 * (s2 * inflate / q_train).sqrt(), "interval"),
        (
            (cal.min_holdout_gain_noise * noise2 / q_ho).sqrt(),
            "held-out gain",
        ),
    ];
    if e == Effect::FluidCompressibility {
        rules.push((
            crate::model::MIN_COMPLIANCE_DEFLECTION_PER_NOISE * d.measurement.displacement_noise_m
                / d.peak_force().max(1e-9),
            "resolved deflection",
        ));
    }
    if e == Effect::FieldLag {
        rules.push((crate::model::shortest_resolved_lag_s(d), "resolved lag"));
    }
    let (size, rule) = rules
        .into_iter()
        .map(|(a, r)| (if a.is_finite() { a } else { f64::INFINITY }, r))
        .fold((0.0, "statistic"), |m, x| if x.0 > m.0 { x } else { m });
    Asked { size, rule }
}

/// RMS of `g` over the fitting and held-out samples (the excluded left out).
fn rms_all(d: &Prepared, g: &[f64]) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for (j, gj) in g.iter().enumerate() {
        if d.train[j] || d.holdout[j] {
            s += gj * gj;
            n += 1;
        }
    }
    (s / n.max(1) as f64).sqrt()
}

/// The shapes each effect's limit is stated at.
fn shapes(d: &Prepared, e: Effect) -> Vec<Shape> {
    match e {
        Effect::SealFriction => vec![
            Shape::Presliding(FRICTION_PRESLIDING_M.min(crate::model::xp_max(d))),
            Shape::Step,
        ],
        _ => vec![Shape::Plain],
    }
}

/// The limit of one effect in one shape: (what the rules ask, the share the final model
/// absorbs, the effect's force RMS at the limit \[N\]). The secant is taken again at the
/// limit found until that moves by under 5 % (three passes at most): the lag and the
/// compliance are nonlinear in their size.
fn limit_of(
    d: &Prepared,
    fit: &Fit,
    lin: &Linearisation,
    (e, shape): (Effect, Shape),
    (s2, inflate, t): (f64, f64, f64),
    cal: &Calibration,
) -> (Asked, f64, f64) {
    let mut a = start_size(d, e, fit);
    let mut pass = 0;
    loop {
        let (g, h) = secant(d, fit, lin, (e, shape), a);
        let (q_train, q_ho) = weighted_energy(d, &h);
        let (g_train, _) = weighted_energy(d, &g);
        let absorbed = if g_train > 0.0 {
            (1.0 - q_train / g_train).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let ask = asked(d, e, (q_train, q_ho), (s2, inflate, t), cal);
        let rms = ask.size * rms_all(d, &g);
        let next = ask.size;
        pass += 1;
        let settled = !next.is_finite()
            || next <= 0.0
            || absorbed >= NOT_SEPARABLE_SHARE
            || (next / a - 1.0).abs() < 0.05;
        if settled || pass >= 3 {
            return (ask, absorbed, rms);
        }
        a = next;
    }
}

/// The detection limit of every library effect the final model `fit` lacks, under the
/// calibrated selector's rules (`trials` give each candidate's threshold).
pub fn detection_limits(
    d: &Prepared,
    fit: &Fit,
    trials: &[Trial],
    cal: &Calibration,
) -> Vec<DetectionLimit> {
    let Some(lin) = Linearisation::new(d, fit) else {
        return Vec::new();
    };
    let m = fit.train_n as f64;
    let s2 = fit.train_sse / (m - fit.layout.model_len() as f64).max(1.0);
    let inflate = m / stats::effective_n(fit.train_n, fit.rho1);
    let force_rms = rms_all(d, &d.f);
    let mut out = Vec::new();
    for e in Effect::ALL {
        if fit.layout.effects.contains(&e) {
            continue;
        }
        let Some(t) = threshold(e, trials, inflate) else {
            continue;
        };
        let info = effect_params(e)[0];
        for shape in shapes(d, e) {
            let (ask, absorbed, rms) = limit_of(d, fit, &lin, (e, shape), (s2, inflate, t), cal);
            let reportable = shape != Shape::Step;
            let separable = reportable
                && ask.size.is_finite()
                && absorbed < NOT_SEPARABLE_SHARE
                && rms <= force_rms;
            let rule = if separable {
                ask.rule.to_string()
            } else if !reportable {
                "never reported: at every current a step is an offset of the fluid's yield force"
                    .to_string()
            } else if absorbed >= NOT_SEPARABLE_SHARE {
                "not separable: the fitted fluid law takes up its shape".to_string()
            } else {
                "not separable: larger than the record's whole force".to_string()
            };
            out.push(DetectionLimit {
                effect: e.id().into(),
                shape: shape_note(d, e, shape),
                parameter: info.name.into(),
                unit: info.unit.into(),
                limit: separable.then_some(ask.size * info.scale),
                effect_rms_n: separable.then_some(rms),
                absorbed_share: absorbed,
                rule,
            });
        }
    }
    out
}

/// The shape at which the limit holds, in words.
fn shape_note(d: &Prepared, e: Effect, shape: Shape) -> String {
    match (e, shape) {
        (Effect::SealFriction, Shape::Presliding(xp)) => {
            format!("Dahl friction presliding over {:.0} µm", xp * 1e6)
        }
        (Effect::SealFriction, _) => "a step without presliding (Coulomb, Stribeck)".into(),
        (Effect::FluidCompressibility, _) => "constant compliance (γ = 0)".into(),
        (Effect::FieldLag, _) if d.current.summary().steps == 0 => {
            "first-order lag; the current never steps on this record".into()
        }
        (Effect::FieldLag, _) => "first-order lag".into(),
        (Effect::GasSpring, _) => "linear stiffness".into(),
        (Effect::FluidInertia, _) => "mass times the rebuilt acceleration".into(),
        (Effect::ThermalSoftening, _) => "softening per dissipated energy".into(),
    }
}
