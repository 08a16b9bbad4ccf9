//! Pressure-driven flow of the MR fluid through the annular gap, treated as a slit of
//! width b = 2π r_mean, height h and active (magnetised) length L.
//!
//! For a fluid whose shear rate is γ̇ = f(τ), the slit flow rate under a pressure drop Δp
//! is (wall stress τw = Δp h / (2L)):
//!
//! Q = 2b (L/Δp)² ∫₀^τw τ f(τ) dτ = b h² / (2 τw²) ∫₀^τw τ f(τ) dτ.
//!
//! * Bingham: the Buckingham–Reiner result of PHYSICS.md,
//!   Q = b h³ Δp / (12 μ L) (1 − δ)² (1 + δ/2), δ = Δp_y/|Δp|, Δp_y = 2 τ_y L / h,
//!   and Q = 0 while |Δp| ≤ Δp_y (**flow blocking**).
//! * Herschel–Bulkley: the integral in closed form with u = τw − τ_y, p = 1/m:
//!   ∫ = k^(−p) [u^(p+2)/(p+2) + τ_y u^(p+1)/(p+1)].
//! * Bodner–Partom (5.2): the integral as an incomplete gamma function, see
//!   [`BodnerPartom::first_moment_of_rate`]; no sharp yield, but the flow below the
//!   yield point (5.3) is exponentially small, so blocking emerges from the law.
//!
//! A **pre-yield leak** may run in parallel with any law: Q_leak = G_leak Δp. With
//! G_leak = λ b h³/(12 μ L) it is the pre-yield branch of a bi-viscous fluid whose
//! pre-yield viscosity is μ/λ (Stanway's bi-viscous model, the slit flow below yield),
//! the same law as diagnose's leaky Bingham line (`diagnose::bingham::phi_leaky`,
//! v_ε = λ F_y/c): the flow no longer blocks, it creeps at G_leak Δp.

use crate::fluid::{signum0, Bingham, BodnerPartom, HerschelBulkley};

/// Slit geometry of the annular gap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlitGap {
    /// b = 2π r_mean \[m\].
    pub width_m: f64,
    /// h \[m\].
    pub height_m: f64,
    /// Active length L \[m\].
    pub length_m: f64,
}

/// The constitutive law in the gap, with parameters at the present field and temperature.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GapLaw {
    /// Bingham plastic.
    Bingham(Bingham),
    /// Herschel–Bulkley.
    HerschelBulkley(HerschelBulkley),
    /// Simplified Bodner–Partom (rigid-viscoplastic in the gap).
    BodnerPartom(BodnerPartom),
}

/// Flow through the gap for one law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlitFlow {
    /// Geometry.
    pub gap: SlitGap,
    /// Law with its present parameters.
    pub law: GapLaw,
    /// Conductance of the pre-yield leak in parallel with the law, G_leak \[m³/(Pa·s)\]
    /// (0: none, the law alone).
    pub leak_m3_per_pa_s: f64,
}

impl SlitFlow {
    /// Wall shear stress for a pressure drop: τw = |Δp| h / (2L).
    pub fn wall_stress(&self, dp: f64) -> f64 {
        dp.abs() * self.gap.height_m / (2.0 * self.gap.length_m)
    }

    /// Yield pressure Δp_y = 2 τ_y L / h of a law with a sharp yield stress (0 for
    /// Bodner–Partom, which has none).
    pub fn yield_pressure(&self) -> f64 {
        let tau_y = match self.law {
            GapLaw::Bingham(b) => b.yield_stress_pa,
            GapLaw::HerschelBulkley(hb) => hb.yield_stress_pa,
            GapLaw::BodnerPartom(_) => 0.0,
        };
        2.0 * tau_y * self.gap.length_m / self.gap.height_m
    }

    /// Flow rate Q from chamber 1 to chamber 2 \[m³/s\] under Δp = p1 − p2 \[Pa\], and
    /// dQ/dΔp (≥ 0): the law's flow plus the pre-yield leak G_leak Δp. Q is odd in Δp;
    /// the law's part is C¹ (its dQ/dΔp → 0 at the yield pressure).
    pub fn flow(&self, dp: f64) -> (f64, f64) {
        let (q, dq) = self.law_flow(dp);
        (q + self.leak_m3_per_pa_s * dp, dq + self.leak_m3_per_pa_s)
    }

    /// The law's flow alone (no leak) and its dQ/dΔp.
    fn law_flow(&self, dp: f64) -> (f64, f64) {
        let SlitGap {
            width_m: b,
            height_m: h,
            length_m: l,
        } = self.gap;
        let a = dp.abs();
        match self.law {
            GapLaw::Bingham(bi) => {
                let dpy = self.yield_pressure();
                if a <= dpy {
                    return (0.0, 0.0);
                }
                let g = b * h.powi(3) / (12.0 * bi.viscosity_pa_s * l);
                let d = dpy / a;
                let q = g * a * (1.0 - d).powi(2) * (1.0 + 0.5 * d);
                (signum0(dp) * q, g * (1.0 - d * d * d))
            }
            GapLaw::HerschelBulkley(hb) => {
                let tw = self.wall_stress(dp);
                let u = tw - hb.yield_stress_pa;
                if u <= 0.0 {
                    return (0.0, 0.0);
                }
                let p = 1.0 / hb.flow_index;
                let kp = hb.consistency_pa_sm.powf(-p);
                let up1 = u.powf(p + 1.0);
                let integral = kp * (up1 * u / (p + 2.0) + hb.yield_stress_pa * up1 / (p + 1.0));
                let rate_w = kp * u.powf(p);
                slit_from_moment(b, h, l, dp, tw, integral, rate_w)
            }
            GapLaw::BodnerPartom(bp) => {
                let tw = self.wall_stress(dp);
                if tw <= 0.0 {
                    return (0.0, 0.0);
                }
                let integral = bp.first_moment_of_rate(tw);
                let rate_w = bp.plastic_rate(tw);
                slit_from_moment(b, h, l, dp, tw, integral, rate_w)
            }
        }
    }

    /// The pressure drop that drives the flow `q` (the inverse of [`Self::flow`]); zero
    /// flow gives zero pressure drop (the midpoint of the blocked range).
    pub fn pressure_drop(&self, q: f64) -> f64 {
        if q == 0.0 {
            return 0.0;
        }
        let target = q.abs();
        let dpy = self.yield_pressure();
        // Below the yield pressure only the leak flows: Δp = Q / G_leak.
        if self.leak_m3_per_pa_s > 0.0 && target <= self.leak_m3_per_pa_s * dpy {
            return q / self.leak_m3_per_pa_s;
        }
        // Bracket: Q(lo) < target ≤ Q(hi).
        let mut lo = dpy;
        let mut hi = lo.max(1.0e3) * 2.0;
        while self.flow(hi).0 < target {
            lo = hi;
            hi *= 2.0;
            if hi > 1.0e12 {
                return signum0(q) * hi;
            }
        }
        // Safeguarded Newton from the upper end (Q is increasing).
        let mut x = hi;
        for _ in 0..200 {
            let (fq, dq) = self.flow(x);
            let r = fq - target;
            if r.abs() <= 1.0e-13 * target {
                break;
            }
            if r > 0.0 {
                hi = x;
            } else {
                lo = x;
            }
            let newton = if dq > 0.0 { x - r / dq } else { f64::NAN };
            x = if newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
            if hi - lo <= 1.0e-14 * hi {
                break;
            }
        }
        signum0(q) * x
    }
}

/// Q = b h² I / (2 τw²) and dQ/dΔp from the first moment I = ∫₀^τw τ f dτ and the wall
/// rate f(τw): dQ/dτw = b h²/2 (f(τw)/τw − 2 I/τw³), dτw/dΔp = h/(2L).
fn slit_from_moment(
    b: f64,
    h: f64,
    l: f64,
    dp: f64,
    tw: f64,
    integral: f64,
    rate_w: f64,
) -> (f64, f64) {
    let q = b * h * h * integral / (2.0 * tw * tw);
    let dq_dtw = 0.5 * b * h * h * (rate_w.abs() / tw - 2.0 * integral / (tw * tw * tw));
    (signum0(dp) * q, (dq_dtw * h / (2.0 * l)).max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gap() -> SlitGap {
        SlitGap {
            width_m: 0.09,
            height_m: 0.8e-3,
            length_m: 0.02,
        }
    }

    #[test]
    fn herschel_bulkley_with_unit_index_matches_bingham() {
        let b = SlitFlow {
            gap: gap(),
            law: GapLaw::Bingham(Bingham {
                yield_stress_pa: 2.0e4,
                viscosity_pa_s: 0.4,
            }),
            leak_m3_per_pa_s: 0.0,
        };
        let hb = SlitFlow {
            gap: gap(),
            law: GapLaw::HerschelBulkley(HerschelBulkley {
                yield_stress_pa: 2.0e4,
                consistency_pa_sm: 0.4,
                flow_index: 1.0,
            }),
            leak_m3_per_pa_s: 0.0,
        };
        for dp in [-5e6, -1.2e6, 0.0, 5e5, 1.01e6, 3e6] {
            let (qb, db) = b.flow(dp);
            let (qh, dh) = hb.flow(dp);
            assert!(
                (qb - qh).abs() <= 1e-9 * qb.abs().max(1e-12),
                "{dp}: {qb} {qh}"
            );
            assert!(
                (db - dh).abs() <= 1e-6 * db.abs().max(1e-20),
                "{dp}: {db} {dh}"
            );
        }
    }

    #[test]
    fn newtonian_limit_is_plane_poiseuille() {
        let f = SlitFlow {
            gap: gap(),
            law: GapLaw::Bingham(Bingham {
                yield_stress_pa: 0.0,
                viscosity_pa_s: 0.1,
            }),
            leak_m3_per_pa_s: 0.0,
        };
        let g = gap();
        let dp = 1.0e5;
        let expected = g.width_m * g.height_m.powi(3) * dp / (12.0 * 0.1 * g.length_m);
        assert!((f.flow(dp).0 / expected - 1.0).abs() < 1e-12);
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let laws = [
            GapLaw::Bingham(Bingham {
                yield_stress_pa: 2.0e4,
                viscosity_pa_s: 0.4,
            }),
            GapLaw::HerschelBulkley(HerschelBulkley {
                yield_stress_pa: 2.0e4,
                consistency_pa_sm: 2.0,
                flow_index: 0.7,
            }),
            GapLaw::BodnerPartom(BodnerPartom::from_paper(1.0, 25.0, 0.8e-3)),
        ];
        for (law, leak) in laws.iter().flat_map(|l| [(*l, 0.0), (*l, 2.4e-11)]) {
            let f = SlitFlow {
                gap: gap(),
                law,
                leak_m3_per_pa_s: leak,
            };
            for dp in [3.0e5, 1.5e6, 4.0e6, 1.2e7, 2.0e7] {
                let (_, d) = f.flow(dp);
                let h = dp * 1e-6;
                let fd = (f.flow(dp + h).0 - f.flow(dp - h).0) / (2.0 * h);
                assert!(
                    (d - fd).abs() <= 1e-5 * fd.abs() + 1e-25,
                    "{law:?} {dp}: {d} vs {fd}"
                );
            }
        }
    }

    #[test]
    fn pressure_drop_inverts_flow() {
        let laws = [
            GapLaw::Bingham(Bingham {
                yield_stress_pa: 2.0e4,
                viscosity_pa_s: 0.4,
            }),
            GapLaw::HerschelBulkley(HerschelBulkley {
                yield_stress_pa: 2.0e4,
                consistency_pa_sm: 2.0,
                flow_index: 0.7,
            }),
            GapLaw::BodnerPartom(BodnerPartom::from_paper(1.0, 25.0, 0.8e-3)),
        ];
        // Without and with a pre-yield leak (λ = 0.05 of the Bingham conductance: the
        // smaller flows here run below the yield pressure through the leak alone).
        for (law, leak) in laws.iter().flat_map(|l| [(*l, 0.0), (*l, 2.4e-11)]) {
            let f = SlitFlow {
                gap: gap(),
                law,
                leak_m3_per_pa_s: leak,
            };
            for q in [-2e-4, -1e-6, 1e-8, 3e-5, 2e-4] {
                let dp = f.pressure_drop(q);
                assert!((f.flow(dp).0 / q - 1.0).abs() < 1e-9, "{law:?} {q}");
            }
        }
    }

    #[test]
    fn bodner_partom_flow_is_blocked_below_yield_point() {
        let bp = BodnerPartom::from_paper(1.0, 25.0, 0.8e-3);
        let f = SlitFlow {
            gap: gap(),
            law: GapLaw::BodnerPartom(bp),
            leak_m3_per_pa_s: 0.0,
        };
        // A wall stress at half the yield point for 1 1/s lets through a negligible flow.
        let tau = 0.5 * bp.yield_point(1.0);
        let dp = tau * 2.0 * gap().length_m / gap().height_m;
        let (q, _) = f.flow(dp);
        // Compare with the flow at the yield point of 100 1/s (a slow stroke).
        let dp_flowing = bp.yield_point(100.0) * 2.0 * gap().length_m / gap().height_m;
        let (q_flowing, _) = f.flow(dp_flowing);
        // (5.2) at half the stress of 1 1/s gives ~1e-3 1/s: five decades below.
        assert!(q < 1e-4 * q_flowing, "{q} vs {q_flowing}");
    }
}
