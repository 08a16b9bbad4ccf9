//! The incompressible Bingham flow-mode damper in force units (Buckingham's slit equation).
//!
//! For a Bingham fluid in a slit (PHYSICS.md, "Paper 2"), the flow at pressure drop Δp is
//! `Q = b h³ Δp / (12 μ L) · (1 − δ)² (1 + δ/2)`, `δ = Δp_y / Δp`. With the piston pushing
//! `Q = A1 v` and `F = A1 Δp`, write `F_y = A1 Δp_y` (yield force) and
//! `c = 12 μ L A1² / (b h³)` (viscous coefficient). With `Φ = |F| / F_y` and `u = c |v| / F_y`:
//!
//! `u = G(Φ) = (Φ − 1)² (Φ + ½) / Φ² = Φ − 3/2 + 1/(2 Φ²)`  (Φ ≥ 1),
//!
//! i.e. Φ is the root ≥ 1 of `Φ³ − (3/2 + u) Φ² + ½ = 0`. At large velocity
//! `F ≈ 3/2 F_y + c v`; at v → 0 the force tends to ±F_y.

/// Φ(u) and dΦ/du: the root ≥ 1 of Φ³ − (3/2 + u) Φ² + ½ = 0, for u ≥ 0.
pub fn phi(u: f64) -> (f64, f64) {
    if u <= 1e-300 {
        return (1.0, f64::INFINITY);
    }
    // Bounds: G(1 + s) ≤ 1.5 s², so 1 + sqrt(u/1.5) ≤ Φ; and Φ ≤ 3/2 + u.
    let (lo, hi) = (1.0 + (u / 1.5).sqrt(), 1.5 + u);
    let x = safeguarded_newton(
        |x| x - 1.5 + 0.5 / (x * x) - u,
        |x| 1.0 - 1.0 / (x * x * x),
        lo,
        hi,
        hi.min(lo + u),
        4.0 * f64::EPSILON * (2.0 + u + hi),
    );
    let dg = 1.0 - 1.0 / (x * x * x);
    (x, if dg > 0.0 { 1.0 / dg } else { f64::INFINITY })
}

/// The root of an increasing `g` in `[lo, hi]` (g(lo) ≤ 0 ≤ g(hi)) from `x`: Newton steps,
/// bisection whenever a step would leave the bracket; relative tolerance 1e-14 on the
/// step, or |g| ≤ `floor`, the rounding error of evaluating g near the root (where g is
/// flat a step computed from a residual at rounding level never falls below 1e-14).
fn safeguarded_newton(
    g: impl Fn(f64) -> f64,
    dg: impl Fn(f64) -> f64,
    mut lo: f64,
    mut hi: f64,
    mut x: f64,
    floor: f64,
) -> f64 {
    for _ in 0..80 {
        let r = g(x);
        if r.abs() <= floor {
            return x;
        }
        if r > 0.0 {
            hi = x;
        } else {
            lo = x;
        }
        let d = dg(x);
        let newton = x - r / d;
        // Converged when the Newton step is below the tolerance, tested before the bracket:
        // at the root, rounding gives r either sign and can put the step on the bracket's
        // end, which would otherwise bisect a wide bracket.
        if d > 0.0 && (newton - x).abs() <= 1e-14 * x {
            return newton;
        }
        x = if d > 0.0 && newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
    }
    x
}

/// Rod force of the incompressible Bingham damper and its derivatives with respect to
/// the yield force `fy` and the viscous coefficient `c`: `(F, ∂F/∂fy, ∂F/∂c)`.
pub fn force(v: f64, fy: f64, c: f64) -> (f64, f64, f64) {
    if v == 0.0 {
        return (0.0, 0.0, 0.0);
    }
    let s = v.signum();
    let u = c * v.abs() / fy;
    let (p, dp) = phi(u);
    if !dp.is_finite() {
        return (s * fy, s, 0.0);
    }
    (s * fy * p, s * (p - u * dp), s * dp * v.abs())
}

/// The flow velocity that force `f` drives through the gap (inverse of [`force`]), and its
/// derivatives: `(w, ∂w/∂f, ∂w/∂fy, ∂w/∂c)`. Zero while |f| ≤ fy (blocked flow).
pub fn flow_velocity(f: f64, fy: f64, c: f64) -> (f64, f64, f64, f64) {
    let p = f.abs() / fy;
    if p <= 1.0 {
        return (0.0, 0.0, 0.0, 0.0);
    }
    let s = f.signum();
    let g = p - 1.5 + 0.5 / (p * p);
    let dg = 1.0 - 1.0 / (p * p * p);
    let w = s * fy / c * g;
    (w, dg / c, s * (g - p * dg) / c, -w / c)
}

/// The Bingham slit law with a pre-yield leak, in force units: the flow velocity a force
/// drives is `w(F) = sgn F · (F_y/c · G(Φ) [Φ > 1] + v_ε Φ)`, `Φ = |F|/F_y`, G the slit
/// function of [`phi`]. This is the expected force of the Bingham damper when the velocity
/// it is evaluated at carries a random error (crate::measure): the jump at v = 0 becomes a
/// ramp of slope F_y/v_ε, and the law stays C¹ (G'(1) = 0). v_ε = 0 gives [`force`].
///
/// Φ for speed `u = c|v|/F_y ≥ e`, `e = c v_ε/F_y`: the root ≥ 1 of
/// `(1 + e) Φ³ − (3/2 + u) Φ² + ½ = 0`; returns (Φ, ∂Φ/∂u, ∂Φ/∂e).
pub fn phi_leaky(u: f64, e: f64) -> (f64, f64, f64) {
    if e <= 0.0 {
        let (p, dp) = phi(u);
        return (p, dp, if dp.is_finite() { -p * dp } else { 0.0 });
    }
    let g = |x: f64| (1.0 + e) * x - 1.5 + 0.5 / (x * x) - u;
    let dg = |x: f64| 1.0 + e - 1.0 / (x * x * x);
    // Bracket: with Φ = 1 + s, G(1 + s) = 3/2 k(s) s², k(s) = (1 + s/1.5)/(1 + s)² ≤ 1, so
    // the root s₀ of e(1 + s) + 3/2 s² = u lies at or below the root; dropping 1/(2Φ²)
    // gives Φ = (3/2 + u)/(1 + e) at or above it. Start from the root of
    // e(1 + s) + 3/2 k(s₀) s² = u (both roots in the form without cancellation at large e).
    // Over e in 1e-6…1e3 and u − e in 1e-8…1e2 (log-uniform) this takes 2.4 Newton steps
    // on average, against 8.4 from the old start 1 + (u − e)/(1 + e) in [1, 3/2 + u] and
    // a step-only convergence test.
    let du = (u - e).max(0.0);
    let s0 = 2.0 * du / (e + (e * e + 6.0 * du).sqrt());
    let (lo, hi) = (1.0 + s0, ((1.5 + u) / (1.0 + e)).max(1.0 + s0));
    let k = (1.0 + s0 / 1.5) / ((1.0 + s0) * (1.0 + s0));
    let s1 = 2.0 * du / (e + (e * e + 6.0 * k * du).sqrt());
    let floor = 4.0 * f64::EPSILON * (2.0 + u + (1.0 + e) * hi);
    let x = safeguarded_newton(g, dg, lo, hi, (1.0 + s1).clamp(lo, hi), floor);
    let d = dg(x);
    (x, 1.0 / d, -x / d)
}

/// Rod force of the leaky Bingham law and its derivatives: `(F, ∂F/∂F_y, ∂F/∂c, ∂F/∂v_ε)`.
pub fn force_leaky(v: f64, fy: f64, c: f64, veps: f64) -> (f64, f64, f64, f64) {
    if veps <= 0.0 {
        let (f, a, b) = force(v, fy, c);
        return (f, a, b, 0.0);
    }
    let av = v.abs();
    if av <= veps {
        return (fy * v / veps, v / veps, 0.0, -fy * v / (veps * veps));
    }
    let s = v.signum();
    let u = c * av / fy;
    let e = c * veps / fy;
    let (p, du, de) = phi_leaky(u, e);
    (
        s * fy * p,
        s * (p - u * du - e * de),
        s * (du * av + de * veps),
        s * c * de,
    )
}

/// Inverse of [`force_leaky`]: `(w, ∂w/∂F, ∂w/∂F_y, ∂w/∂c, ∂w/∂v_ε)`.
pub fn flow_velocity_leaky(f: f64, fy: f64, c: f64, veps: f64) -> (f64, f64, f64, f64, f64) {
    let p = f.abs() / fy;
    let s = if f < 0.0 { -1.0 } else { 1.0 };
    let leak = (s * veps * p, veps / fy, -s * veps * p / fy, 0.0, s * p);
    if p <= 1.0 {
        return leak;
    }
    let (w, dwf, dwfy, dwc) = flow_velocity(f, fy, c);
    (w + leak.0, dwf + leak.1, dwfy + leak.2, dwc, leak.4)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phi_solves_the_slit_equation_and_limits() {
        for u in [1e-9, 1e-4, 0.1, 1.0, 10.0, 1e4] {
            let (p, dp) = phi(u);
            let g = (p - 1.0).powi(2) * (p + 0.5) / (p * p);
            assert!((g - u).abs() <= 1e-9 * u.max(1e-6), "u {u}: G(Φ) {g}");
            let (p2, _) = phi(u * (1.0 + 1e-6));
            let fd = (p2 - p) / (u * 1e-6);
            assert!((fd / dp - 1.0).abs() < 1e-3, "u {u}: dΦ/du {dp} vs {fd}");
        }
        // Large u: F ≈ 3/2 F_y + c v.
        let (p, _) = phi(1e6);
        assert!((p - 1e6 - 1.5).abs() < 1e-5);
    }

    #[test]
    fn flow_velocity_inverts_force_and_matches_the_gap_law() {
        let (fy, c) = (800.0, 1500.0);
        for v in [-0.3, -0.01, 1e-4, 0.05, 0.4] {
            let (f, _, _) = force(v, fy, c);
            let (w, _, _, _) = flow_velocity(f, fy, c);
            assert!((w - v).abs() < 1e-10 * v.abs().max(1.0), "{v}: {w}");
        }
        // Against twin's slit flow (Bingham): F = A1 Δp(Q = A1 v).
        use twin::fluid::Bingham;
        use twin::gap::{GapLaw, SlitFlow, SlitGap};
        let gap = SlitGap {
            width_m: 0.09,
            height_m: 8e-4,
            length_m: 0.02,
        };
        let (tau, mu, a1) = (3.0e4, 0.4, 7.0e-4);
        let flow = SlitFlow {
            gap,
            law: GapLaw::Bingham(Bingham {
                yield_stress_pa: tau,
                viscosity_pa_s: mu,
            }),
            leak_m3_per_pa_s: 0.0,
        };
        let fy = a1 * 2.0 * tau * gap.length_m / gap.height_m;
        let c = 12.0 * mu * gap.length_m * a1 * a1 / (gap.width_m * gap.height_m.powi(3));
        for v in [0.002, 0.05, 0.3] {
            let twin_f = a1 * flow.pressure_drop(a1 * v);
            let (f, _, _) = force(v, fy, c);
            assert!((f / twin_f - 1.0).abs() < 1e-8, "{v}: {f} vs {twin_f}");
        }
        // With a pre-yield leak λ the twin's slit (leak conductance λ b h³/(12 μ L)) is
        // this leaky law at v_ε = λ F_y/c, below and above the yield point.
        let lambda = 0.05;
        let leaky = SlitFlow {
            leak_m3_per_pa_s: lambda * gap.width_m * gap.height_m.powi(3)
                / (12.0 * mu * gap.length_m),
            ..flow
        };
        let veps = lambda * fy / c;
        for v in [
            -0.2,
            -0.5 * veps,
            0.1 * veps,
            0.99 * veps,
            1.01 * veps,
            0.01,
            0.3,
        ] {
            let twin_f = a1 * leaky.pressure_drop(a1 * v);
            let (f, _, _, _) = force_leaky(v, fy, c, veps);
            assert!((f / twin_f - 1.0).abs() < 1e-8, "{v}: {f} vs {twin_f}");
        }
    }

    #[test]
    fn leaky_law_inverts_its_force_and_matches_finite_differences() {
        let (fy, c, veps) = (800.0, 1500.0, 0.004);
        for v in [-0.3, -0.01, -0.003, 1e-4, 0.0039, 0.0041, 0.05, 0.4] {
            let (f, dfy, dc, de) = force_leaky(v, fy, c, veps);
            let (w, dwf, _, _, _) = flow_velocity_leaky(f, fy, c, veps);
            assert!((w - v).abs() < 1e-9 * v.abs().max(1e-3), "{v}: w {w}");
            let fd = |g: &dyn Fn(f64) -> f64, x: f64| {
                let h = 1e-6 * x;
                (g(x + h) - g(x - h)) / (2.0 * h)
            };
            let nfy = fd(&|x| force_leaky(v, x, c, veps).0, fy);
            let nc = fd(&|x| force_leaky(v, fy, x, veps).0, c);
            let ne = fd(&|x| force_leaky(v, fy, c, x).0, veps);
            for (a, b) in [(dfy, nfy), (dc, nc), (de, ne)] {
                assert!(
                    (a - b).abs() <= 1e-5 * (a.abs() + b.abs()).max(1e-6),
                    "{v}: {a} vs {b}"
                );
            }
            // ∂w/∂F is the reciprocal of ∂F/∂v.
            let dfdv = fd(&|x| force_leaky(x, fy, c, veps).0, v);
            assert!((dwf * dfdv - 1.0).abs() < 1e-4, "{v}: {dwf} · {dfdv}");
        }
        // v_ε → 0 gives the plain slit law.
        let (a, _, _, _) = force_leaky(0.02, fy, c, 1e-12);
        let (b, _, _) = force(0.02, fy, c);
        assert!((a - b).abs() < 1e-6);
    }
}
