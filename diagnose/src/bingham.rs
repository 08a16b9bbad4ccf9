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
    let mut lo = 1.0 + (u / 1.5).sqrt();
    let mut hi = 1.5 + u;
    let mut x = hi.min(lo + u);
    for _ in 0..60 {
        let g = x - 1.5 + 0.5 / (x * x) - u;
        if g > 0.0 {
            hi = x;
        } else {
            lo = x;
        }
        let dg = 1.0 - 1.0 / (x * x * x);
        let newton = x - g / dg;
        let next = if dg > 0.0 && newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if (next - x).abs() <= 1e-14 * x {
            x = next;
            break;
        }
        x = next;
    }
    let dg = 1.0 - 1.0 / (x * x * x);
    (x, if dg > 0.0 { 1.0 / dg } else { f64::INFINITY })
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
        };
        let fy = a1 * 2.0 * tau * gap.length_m / gap.height_m;
        let c = 12.0 * mu * gap.length_m * a1 * a1 / (gap.width_m * gap.height_m.powi(3));
        for v in [0.002, 0.05, 0.3] {
            let twin_f = a1 * flow.pressure_drop(a1 * v);
            let (f, _, _) = force(v, fy, c);
            assert!((f / twin_f - 1.0).abs() < 1e-8, "{v}: {f} vs {twin_f}");
        }
    }
}
