//! A stiff-capable one-step integrator for the small ODE systems of the damper models.
//!
//! TR-BDF2 (Bank et al. 1985; Hosea & Shampine 1996): a trapezoidal stage to
//! t + γh followed by a BDF2 stage to t + h, γ = 2 − √2. It is second order, L-stable
//! (fast chamber modes with time constants far below the step are damped, not rung),
//! and needs one Newton solve per stage with the Jacobian of an N×N system, N ≤ 3 here.
//!
//! The Newton iteration starts from a linearly implicit (Rosenbrock–Euler) predictor and
//! is damped by backtracking on the scaled residual, so the C¹ kink of a flow law at its
//! yield pressure (flow blocking) is crossed without chattering. A stage that does not
//! converge is reported, and the caller halves the step. The linear systems are solved by
//! [`numerics::linalg::solve`] (nalgebra's LU with partial pivoting).

use nalgebra::{Const, SMatrix, SVector};
use numerics::linalg::{solve, LuDim};

/// A state vector of dimension N.
pub type Vector<const N: usize> = SVector<f64, N>;
/// An N×N matrix (Jacobian).
pub type Matrix<const N: usize> = SMatrix<f64, N, N>;

/// An ODE system ẏ = f(θ, y) on one step, θ ∈ \[0, 1\] the fraction of the step.
pub trait StiffSystem<const N: usize> {
    /// The right-hand side f(θ, y) and its Jacobian ∂f/∂y.
    fn rhs(&self, theta: f64, y: &Vector<N>) -> (Vector<N>, Matrix<N>);
}

/// Tolerances of the Newton iterations: a component has converged when its update is
/// below `atol[i] + rtol · |y[i]|`.
#[derive(Debug, Clone, Copy)]
pub struct Tolerance<const N: usize> {
    /// Absolute tolerance per component, in the state's units.
    pub atol: Vector<N>,
    /// Relative tolerance.
    pub rtol: f64,
}

/// A Newton iteration that did not converge in the allowed iterations.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NotConverged;

const GAMMA: f64 = 2.0 - std::f64::consts::SQRT_2;
const MAX_NEWTON: usize = 25;

/// One TR-BDF2 step from `y0` over the step fraction \[θ0, θ1\], with `h` the step's
/// length in seconds.
pub fn trbdf2_step<const N: usize, S: StiffSystem<N>>(
    sys: &S,
    y0: &Vector<N>,
    theta0: f64,
    theta1: f64,
    h: f64,
    tol: &Tolerance<N>,
) -> Result<Vector<N>, NotConverged>
where
    Const<N>: LuDim,
{
    let theta_g = theta0 + GAMMA * (theta1 - theta0);
    let (f0, j0) = sys.rhs(theta0, y0);
    // Stage 1 (trapezoid to t + γh): y_g − (y0 + γh/2 f0) − γh/2 f(y_g) = 0.
    let c1 = y0 + f0 * (0.5 * GAMMA * h);
    let guess1 = linearly_implicit_euler(y0, &f0, &j0, GAMMA * h);
    let (yg, fg, jg) = newton(sys, theta_g, &c1, 0.5 * GAMMA * h, guess1, tol)?;
    // Stage 2 (BDF2 to t + h):
    // y1 − (y_g − (1−γ)² y0)/(γ(2−γ)) − (1−γ)/(2−γ) h f(y1) = 0.
    let c2 = (yg - y0 * (1.0 - GAMMA).powi(2)) / (GAMMA * (2.0 - GAMMA));
    let a2 = (1.0 - GAMMA) / (2.0 - GAMMA);
    let guess2 = linearly_implicit_euler(&yg, &fg, &jg, (1.0 - GAMMA) * h);
    let (y1, _, _) = newton(sys, theta1, &c2, a2 * h, guess2, tol)?;
    Ok(y1)
}

/// y + (I − h J)⁻¹ h f: one linearly implicit Euler step, the Newton starting point.
fn linearly_implicit_euler<const N: usize>(
    y: &Vector<N>,
    f: &Vector<N>,
    j: &Matrix<N>,
    h: f64,
) -> Vector<N>
where
    Const<N>: LuDim,
{
    let m = Matrix::<N>::identity() - j * h;
    match solve(&m, &(f * h)) {
        Some(dy) => y + dy,
        None => *y,
    }
}

/// Solve z − c − ah f(θ, z) = 0 by damped Newton. Returns z with f and J evaluated at the
/// last iterate before the final (converged, tiny) update: exact enough for the next
/// stage's predictor, and it saves one evaluation of f per stage.
fn newton<const N: usize, S: StiffSystem<N>>(
    sys: &S,
    theta: f64,
    c: &Vector<N>,
    ah: f64,
    mut z: Vector<N>,
    tol: &Tolerance<N>,
) -> Result<(Vector<N>, Vector<N>, Matrix<N>), NotConverged>
where
    Const<N>: LuDim,
{
    let weight = |v: &Vector<N>, at: &Vector<N>| -> f64 {
        let mut m: f64 = 0.0;
        for i in 0..N {
            m = m.max(v[i].abs() / (tol.atol[i] + tol.rtol * at[i].abs()));
        }
        m
    };
    let (mut f, mut j) = sys.rhs(theta, &z);
    let mut g = z - c - f * ah;
    let mut gnorm = weight(&g, &z);
    for _ in 0..MAX_NEWTON {
        let m = Matrix::<N>::identity() - j * ah;
        let Some(dz) = solve(&m, &g) else {
            return Err(NotConverged);
        };
        if weight(&dz, &z) < 1.0 {
            return Ok((z - dz, f, j));
        }
        let mut lambda = 1.0;
        let mut accepted = false;
        for _ in 0..8 {
            let trial = z - dz * lambda;
            let (ft, jt) = sys.rhs(theta, &trial);
            let gt = trial - c - ft * ah;
            let gtn = weight(&gt, &trial);
            if gtn.is_finite() && (gtn <= gnorm || gtn < 1.0) {
                z = trial;
                f = ft;
                j = jt;
                g = gt;
                gnorm = gtn;
                accepted = true;
                break;
            }
            lambda *= 0.5;
        }
        if !accepted {
            return Err(NotConverged);
        }
    }
    Err(NotConverged)
}

/// Integrate over \[θ0, θ1\] (length `h` seconds), halving the step where Newton fails,
/// down to 2⁻¹⁰ of the original. [`NotConverged`] if even that fails: the caller holds
/// its state and reports it ([`crate::DamperOutput::solver_failed`]).
pub fn trbdf2_adaptive<const N: usize, S: StiffSystem<N>>(
    sys: &S,
    y0: &Vector<N>,
    theta0: f64,
    theta1: f64,
    h: f64,
    tol: &Tolerance<N>,
) -> Result<Vector<N>, NotConverged>
where
    Const<N>: LuDim,
{
    fn go<const N: usize, S: StiffSystem<N>>(
        sys: &S,
        y0: &Vector<N>,
        t0: f64,
        t1: f64,
        h: f64,
        tol: &Tolerance<N>,
        depth: u32,
    ) -> Result<Vector<N>, NotConverged>
    where
        Const<N>: LuDim,
    {
        match trbdf2_step(sys, y0, t0, t1, h, tol) {
            Ok(y) => Ok(y),
            Err(e) if depth >= 10 => Err(e),
            Err(_) => {
                let tm = 0.5 * (t0 + t1);
                let ym = go(sys, y0, t0, tm, 0.5 * h, tol, depth + 1)?;
                go(sys, &ym, tm, t1, 0.5 * h, tol, depth + 1)
            }
        }
    }
    go(sys, y0, theta0, theta1, h, tol, 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ẏ = −λ (y − cos t): stiff relaxation onto a slow manifold.
    struct Relax {
        lambda: f64,
        t0: f64,
        dt: f64,
    }
    impl StiffSystem<1> for Relax {
        fn rhs(&self, theta: f64, y: &Vector<1>) -> (Vector<1>, Matrix<1>) {
            let t = self.t0 + theta * self.dt;
            (
                Vector::<1>::new(-self.lambda * (y[0] - t.cos())),
                Matrix::<1>::new(-self.lambda),
            )
        }
    }

    fn run(lambda: f64, dt: f64, t_end: f64) -> f64 {
        let tol = Tolerance {
            atol: Vector::<1>::new(1e-12),
            rtol: 1e-12,
        };
        let mut y = Vector::<1>::new(1.0);
        let n = (t_end / dt).round() as usize;
        for k in 0..n {
            let sys = Relax {
                lambda,
                t0: k as f64 * dt,
                dt,
            };
            y = trbdf2_step(&sys, &y, 0.0, 1.0, dt, &tol).unwrap();
        }
        y[0]
    }

    fn exact(lambda: f64, t: f64) -> f64 {
        // y = (λ² cos t + λ sin t)/(λ²+1) + C e^{−λt}, y(0) = 1.
        let p = |t: f64| (lambda * lambda * t.cos() + lambda * t.sin()) / (lambda * lambda + 1.0);
        p(t) + (1.0 - p(0.0)) * (-lambda * t).exp()
    }

    /// ẏ = f with no root for the implicit stages: f is NaN away from the start state.
    struct Unsolvable;
    impl StiffSystem<1> for Unsolvable {
        fn rhs(&self, _theta: f64, y: &Vector<1>) -> (Vector<1>, Matrix<1>) {
            let f = if y[0] == 1.0 { 1.0 } else { f64::NAN };
            (Vector::<1>::new(f), Matrix::<1>::new(0.0))
        }
    }

    #[test]
    fn a_step_newton_cannot_take_is_an_error_not_the_start_state() {
        let tol = Tolerance {
            atol: Vector::<1>::new(1e-12),
            rtol: 1e-12,
        };
        let y0 = Vector::<1>::new(1.0);
        assert_eq!(
            trbdf2_adaptive(&Unsolvable, &y0, 0.0, 1.0, 1e-3, &tol),
            Err(NotConverged)
        );
        // A solvable system still integrates.
        let sys = Relax {
            lambda: 5.0,
            t0: 0.0,
            dt: 1e-3,
        };
        assert!(trbdf2_adaptive(&sys, &y0, 0.0, 1.0, 1e-3, &tol).is_ok());
    }

    #[test]
    fn second_order_convergence() {
        let lambda = 5.0;
        let e1 = (run(lambda, 0.02, 2.0) - exact(lambda, 2.0)).abs();
        let e2 = (run(lambda, 0.01, 2.0) - exact(lambda, 2.0)).abs();
        let order = (e1 / e2).log2();
        assert!((1.8..2.3).contains(&order), "observed order {order}");
    }

    #[test]
    fn stable_far_beyond_explicit_limit() {
        // λ dt = 1e5: explicit Euler would explode; TR-BDF2 tracks the slow manifold.
        let lambda = 1.0e8;
        let y = run(lambda, 1e-3, 1.0);
        assert!((y - exact(lambda, 1.0)).abs() < 1e-6, "{y}");
    }
}
