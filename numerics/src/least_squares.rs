//! Nonlinear least squares: the one Levenberg–Marquardt loop of mrtwin.
//!
//! The loop is generic over the problem. The caller's state `S` holds the parameters and
//! whatever it caches at them (residuals, a model evaluation with its Jacobian), and two
//! closures describe the problem:
//!
//! * `linearize(&state)` returns the Gauss–Newton normal equations at the state,
//!   `(JᵀWJ, −JᵀW r)` with r the (weighted) residual and J = ∂r/∂θ, or `None` when they
//!   cannot be formed (the loop stops there);
//! * `trial(&state, &step)` returns the state at θ + step and its cost Σ w r², or `None`
//!   when that point is not admissible. A problem with bounds projects the trial point
//!   onto them here.
//!
//! Each iteration solves `(JᵀWJ + λ D) δ = −JᵀW r` by Cholesky, D the diagonal of JᵀWJ
//! with each entry raised to at least [`LmOptions::diag_floor`] (Marquardt's scaling),
//! and tries θ + δ. A trial that lowers the cost is accepted and λ shrinks by
//! [`LmOptions::lambda_down`] (not below [`LmOptions::lambda_min`]); a rejected trial, or
//! a damped system Cholesky cannot solve, multiplies λ by [`LmOptions::lambda_up`] and
//! tries again, at most [`LmOptions::max_tries`] times. The loop ends when an accepted
//! step lowers the cost by a relative [`LmOptions::rel_tol`] or less, or moves every
//! parameter by less than [`LmOptions::step_tol`]; when no trial lowers the cost; or
//! after [`LmOptions::max_iter`] iterations.
//!
//! [`levenberg_marquardt_two_trials`] runs the same loop with each trial's successor
//! evaluated beside it on a second thread (for a fit that has a core to itself).

use crate::linalg;
use nalgebra::{DMatrix, DVector};

/// Options of [`levenberg_marquardt`]. The defaults are those of diagnose's model fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmOptions {
    /// Most iterations (linearisations).
    pub max_iter: usize,
    /// Most trials (damping increases) per iteration.
    pub max_tries: usize,
    /// Damping λ at the start.
    pub lambda_init: f64,
    /// Factor on λ after a rejected trial (> 1).
    pub lambda_up: f64,
    /// Factor on λ after an accepted trial (< 1).
    pub lambda_down: f64,
    /// Smallest λ after an accepted trial.
    pub lambda_min: f64,
    /// Floor of the diagonal entries of JᵀWJ in the damping term, so that a parameter the
    /// data do not move is still damped (0: damp by the diagonal as it is).
    pub diag_floor: f64,
    /// Converged when an accepted step lowers the cost by this fraction or less.
    pub rel_tol: f64,
    /// Converged when an accepted step moves every parameter by less than this (0: off).
    pub step_tol: f64,
}

impl Default for LmOptions {
    fn default() -> Self {
        Self {
            max_iter: 40,
            max_tries: 12,
            lambda_init: 1e-3,
            lambda_up: 10.0,
            lambda_down: 0.3,
            lambda_min: 1e-9,
            diag_floor: 1e-12,
            rel_tol: 1e-7,
            step_tol: 0.0,
        }
    }
}

/// Why [`levenberg_marquardt`] stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LmStop {
    /// An accepted step met [`LmOptions::rel_tol`] or [`LmOptions::step_tol`].
    Converged,
    /// No trial of an iteration lowered the cost (a minimum within the damping's reach).
    NoDescent,
    /// `linearize` returned `None`.
    NoLinearization,
    /// [`LmOptions::max_iter`] iterations ran.
    MaxIterations,
}

/// The result of [`levenberg_marquardt`].
#[derive(Debug, Clone, PartialEq)]
pub struct LmOutcome<S> {
    /// The state of the lowest cost found.
    pub state: S,
    /// Its cost.
    pub cost: f64,
    /// Iterations run (linearisations formed).
    pub iterations: usize,
    /// Why the loop stopped.
    pub stop: LmStop,
}

/// Minimise a sum of squares by Levenberg–Marquardt from `start` (of cost `start_cost`);
/// see the module docs for the closures and the damping rule.
pub fn levenberg_marquardt<S, L, T>(
    start: S,
    start_cost: f64,
    opts: &LmOptions,
    linearize: L,
    mut trial: T,
) -> LmOutcome<S>
where
    L: FnMut(&S) -> Option<(DMatrix<f64>, DVector<f64>)>,
    T: FnMut(&S, &DVector<f64>) -> Option<(S, f64)>,
{
    lm_loop(
        start,
        start_cost,
        opts,
        linearize,
        1,
        |state, steps, out| {
            out.extend(steps.iter().map(|step| trial(state, step)));
        },
    )
}

/// [`levenberg_marquardt`] with each trial's successor (the next damping, in case the
/// trial is rejected) tried at the same time on a second thread: the same iterates, the
/// same outcome, in less time where trials are often rejected and a core is idle (a fit
/// that runs alone). `trial` must be a function of its arguments only.
pub fn levenberg_marquardt_two_trials<S, L, T>(
    start: S,
    start_cost: f64,
    opts: &LmOptions,
    linearize: L,
    trial: T,
) -> LmOutcome<S>
where
    S: Send + Sync,
    L: FnMut(&S) -> Option<(DMatrix<f64>, DVector<f64>)>,
    T: Fn(&S, &DVector<f64>) -> Option<(S, f64)> + Sync,
{
    lm_loop(
        start,
        start_cost,
        opts,
        linearize,
        2,
        |state, steps, out| {
            if let [first, second] = steps {
                let trial = &trial;
                std::thread::scope(|s| {
                    let next = s.spawn(move || trial(state, second));
                    out.push(trial(state, first));
                    out.push(next.join().expect("a trial panicked"));
                });
            } else {
                out.extend(steps.iter().map(|step| trial(state, step)));
            }
        },
    )
}

/// The loop of [`levenberg_marquardt`], its trials `batch` at a time: the damped steps of
/// the next `batch` dampings (λ, λ × `lambda_up`, …; a damping Cholesky cannot solve
/// counts as a try) go to `trials` together, and the first trial that lowers the cost, in
/// damping order, is taken, as one at a time would take it.
fn lm_loop<S, L, B>(
    start: S,
    start_cost: f64,
    opts: &LmOptions,
    mut linearize: L,
    batch: usize,
    mut trials: B,
) -> LmOutcome<S>
where
    L: FnMut(&S) -> Option<(DMatrix<f64>, DVector<f64>)>,
    B: FnMut(&S, &[DVector<f64>], &mut Vec<Option<(S, f64)>>),
{
    let mut state = start;
    let mut cost = start_cost;
    let mut lambda = opts.lambda_init;
    let mut iterations = 0;
    let mut stop = LmStop::MaxIterations;
    // The steps of a batch, and the λ each was solved at.
    let mut steps: Vec<DVector<f64>> = Vec::with_capacity(batch);
    let mut lambdas: Vec<f64> = Vec::with_capacity(batch);
    let mut results = Vec::with_capacity(batch);
    for _ in 0..opts.max_iter {
        let Some((jtj, g)) = linearize(&state) else {
            stop = LmStop::NoLinearization;
            break;
        };
        iterations += 1;
        let p = jtj.nrows();
        let mut accepted = None;
        let mut tries = 0;
        while accepted.is_none() && tries < opts.max_tries {
            // The next `batch` solvable dampings, each with the λ it was solved at.
            steps.clear();
            lambdas.clear();
            while steps.len() < batch && tries < opts.max_tries {
                let mut a = jtj.clone();
                for q in 0..p {
                    a[(q, q)] += lambda * jtj[(q, q)].max(opts.diag_floor);
                }
                if let Some(step) = linalg::solve_spd(a, &g) {
                    steps.push(step);
                    lambdas.push(lambda);
                }
                lambda *= opts.lambda_up;
                tries += 1;
            }
            if steps.is_empty() {
                break;
            }
            results.clear();
            trials(&state, &steps, &mut results);
            for ((at, step), result) in lambdas.iter().zip(&steps).zip(results.drain(..)) {
                let Some((next, c)) = result else { continue };
                if c.is_finite() && c < cost {
                    let rel = (cost - c) / cost.max(1e-300);
                    let small = opts.step_tol > 0.0 && step.iter().all(|d| d.abs() < opts.step_tol);
                    state = next;
                    cost = c;
                    lambda = (at * opts.lambda_down).max(opts.lambda_min);
                    // Not "rel <= rel_tol": a NaN (from an infinite start cost) stops too.
                    let progressing = rel > opts.rel_tol;
                    accepted = Some(!progressing || small);
                    break;
                }
            }
        }
        match accepted {
            None => {
                stop = LmStop::NoDescent;
                break;
            }
            Some(true) => {
                stop = LmStop::Converged;
                break;
            }
            Some(false) => {}
        }
    }
    LmOutcome {
        state,
        cost,
        iterations,
        stop,
    }
}

/// The unweighted normal equations `(JᵀJ, −Jᵀr)` of an m×p Jacobian `jac` (row i:
/// ∂rᵢ/∂θ) and residuals `r`, summed over the rows in order.
pub fn normal_equations(jac: &DMatrix<f64>, r: &[f64]) -> (DMatrix<f64>, DVector<f64>) {
    let p = jac.ncols();
    let mut jtj = DMatrix::<f64>::zeros(p, p);
    let mut g = DVector::<f64>::zeros(p);
    for (i, ri) in r.iter().enumerate().take(jac.nrows()) {
        for u in 0..p {
            g[u] -= jac[(i, u)] * ri;
            for v in 0..p {
                jtj[(u, v)] += jac[(i, u)] * jac[(i, v)];
            }
        }
    }
    (jtj, g)
}

/// The sum of squares of `r`.
pub fn sum_of_squares(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// y = a e^(−b t) on a grid, fitted from a poor start.
    fn exp_problem(a: f64, b: f64, noise: f64) -> (Vec<f64>, Vec<f64>) {
        let t: Vec<f64> = (0..40).map(|k| 0.1 * k as f64).collect();
        let y = t
            .iter()
            .enumerate()
            .map(|(k, &t)| a * (-b * t).exp() + noise * if k % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        (t, y)
    }

    fn fit_exp(t: &[f64], y: &[f64], start: [f64; 2], opts: &LmOptions) -> LmOutcome<[f64; 2]> {
        let resid = |p: &[f64; 2]| -> Vec<f64> {
            t.iter()
                .zip(y)
                .map(|(&t, &y)| p[0] * (-p[1] * t).exp() - y)
                .collect()
        };
        let jac = |p: &[f64; 2]| {
            DMatrix::from_fn(t.len(), 2, |i, k| {
                let e = (-p[1] * t[i]).exp();
                if k == 0 {
                    e
                } else {
                    -p[0] * t[i] * e
                }
            })
        };
        levenberg_marquardt(
            start,
            sum_of_squares(&resid(&start)),
            opts,
            |p| Some(normal_equations(&jac(p), &resid(p))),
            |p, d| {
                let q = [p[0] + d[0], p[1] + d[1]];
                Some((q, sum_of_squares(&resid(&q))))
            },
        )
    }

    #[test]
    fn two_trials_at_a_time_take_the_steps_one_at_a_time_takes() {
        // Rosenbrock's valley as residuals (10 (y − x²), 1 − x), from far away: many
        // trials are rejected, and inadmissible points (x > 1.5) refused too.
        let resid = |p: &[f64; 2]| vec![10.0 * (p[1] - p[0] * p[0]), 1.0 - p[0]];
        let jac = |p: &[f64; 2]| DMatrix::from_row_slice(2, 2, &[-20.0 * p[0], 10.0, -1.0, 0.0]);
        let tried = std::sync::atomic::AtomicUsize::new(0);
        let trial = |p: &[f64; 2], d: &DVector<f64>| {
            tried.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let q = [p[0] + d[0], p[1] + d[1]];
            (q[0] <= 1.5).then(|| (q, sum_of_squares(&resid(&q))))
        };
        for start in [[-1.2, 1.0], [-3.0, -2.0], [0.5, 4.0]] {
            let opts = LmOptions {
                lambda_init: 1e2,
                ..LmOptions::default()
            };
            let cost = sum_of_squares(&resid(&start));
            let lin = |p: &[f64; 2]| Some(normal_equations(&jac(p), &resid(p)));
            tried.store(0, std::sync::atomic::Ordering::Relaxed);
            let one = levenberg_marquardt(start, cost, &opts, lin, trial);
            let sequential = tried.load(std::sync::atomic::Ordering::Relaxed);
            let two = levenberg_marquardt_two_trials(start, cost, &opts, lin, trial);
            assert!(sequential > one.iterations, "some trials rejected: {one:?}");
            assert_eq!(one.state.map(f64::to_bits), two.state.map(f64::to_bits));
            assert_eq!(one.cost.to_bits(), two.cost.to_bits());
            assert_eq!((one.iterations, one.stop), (two.iterations, two.stop));
            assert!((one.state[0] - 1.0).abs() < 1e-6, "{one:?}");
        }
    }

    #[test]
    fn recovers_an_exponential_decay() {
        let (t, y) = exp_problem(2.5, 1.3, 0.0);
        let out = fit_exp(&t, &y, [1.0, 0.1], &LmOptions::default());
        // An exact fit ends with a cost no step can lower (or a step below rel_tol).
        assert!(
            matches!(out.stop, LmStop::Converged | LmStop::NoDescent),
            "{:?}",
            out.stop
        );
        assert!((out.state[0] - 2.5).abs() < 1e-6, "{:?}", out.state);
        assert!((out.state[1] - 1.3).abs() < 1e-6, "{:?}", out.state);
        assert!(out.cost < 1e-10, "{}", out.cost);
    }

    #[test]
    fn noisy_fit_reaches_the_least_squares_minimum() {
        // With alternating noise the minimum is not the truth; the gradient vanishes there.
        let (t, y) = exp_problem(2.5, 1.3, 0.01);
        let opts = LmOptions {
            max_iter: 200,
            rel_tol: 1e-14,
            ..LmOptions::default()
        };
        let out = fit_exp(&t, &y, [1.0, 0.1], &opts);
        let p = out.state;
        let r: Vec<f64> = t
            .iter()
            .zip(&y)
            .map(|(&t, &y)| p[0] * (-p[1] * t).exp() - y)
            .collect();
        let jac = DMatrix::from_fn(t.len(), 2, |i, k| {
            let e = (-p[1] * t[i]).exp();
            if k == 0 {
                e
            } else {
                -p[0] * t[i] * e
            }
        });
        let (_, g) = normal_equations(&jac, &r);
        assert!(g.amax() < 1e-8, "gradient {g}");
        assert!(
            (p[0] - 2.5).abs() < 0.02 && (p[1] - 1.3).abs() < 0.02,
            "{p:?}"
        );
    }

    #[test]
    fn inadmissible_trials_and_iteration_limits() {
        let (t, y) = exp_problem(2.5, 1.3, 0.0);
        // One iteration only: stops by the limit, cost lowered.
        let one = LmOptions {
            max_iter: 1,
            ..LmOptions::default()
        };
        let out = fit_exp(&t, &y, [1.0, 0.1], &one);
        assert_eq!((out.stop, out.iterations), (LmStop::MaxIterations, 1));
        // Every trial refused: the start comes back unchanged.
        let out = levenberg_marquardt(
            [1.0, 0.1],
            1.0,
            &LmOptions::default(),
            |_| Some((DMatrix::identity(2, 2), DVector::from_vec(vec![1.0, 1.0]))),
            |_, _| None,
        );
        assert_eq!(out.stop, LmStop::NoDescent);
        assert_eq!((out.state, out.cost), ([1.0, 0.1], 1.0));
        // No normal equations: stops before the first iteration.
        let out = levenberg_marquardt(0.0, 1.0, &LmOptions::default(), |_| None, |_, _| None);
        assert_eq!((out.stop, out.iterations), (LmStop::NoLinearization, 0));
    }

    #[test]
    fn the_damping_floor_keeps_a_dead_parameter_solvable() {
        // The second parameter does not enter the cost: JᵀJ is singular.
        let lin = |p: &[f64; 2]| {
            let mut jtj = DMatrix::zeros(2, 2);
            jtj[(0, 0)] = 1.0;
            Some((jtj, DVector::from_vec(vec![-(p[0] - 3.0), 0.0])))
        };
        let trial = |p: &[f64; 2], d: &DVector<f64>| {
            let q = [p[0] + d[0], p[1] + d[1]];
            Some((q, (q[0] - 3.0).powi(2)))
        };
        let out = levenberg_marquardt([0.0, 7.0], 9.0, &LmOptions::default(), lin, trial);
        assert!(
            (out.state[0] - 3.0).abs() < 1e-6 && out.state[1] == 7.0,
            "{:?}",
            out.state
        );
        // Without the floor the damped system stays singular and no step is found.
        let no_floor = LmOptions {
            diag_floor: 0.0,
            ..LmOptions::default()
        };
        let out = levenberg_marquardt([0.0, 7.0], 9.0, &no_floor, lin, trial);
        assert_eq!(out.stop, LmStop::NoDescent);
    }
}
