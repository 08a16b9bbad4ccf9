//! Constitutive laws of the MR fluid in simple shear.
//!
//! Each law relates the shear stress τ \[Pa\] to the (plastic) shear rate γ̇ \[1/s\].
//! Stresses and rates are odd functions: negative rates give negative stresses.
//!
//! * [`Bingham`]: τ = τ_y sgn γ̇ + μ γ̇.
//! * [`HerschelBulkley`]: τ = (τ_y + k |γ̇|^m) sgn γ̇.
//! * [`BodnerPartom`]: the simplified Bodner–Partom law of Skalski & Zalewski (2014),
//!   eq. (5.2), its yield point (5.3) and the identified parameters (5.5).

use serde::{Deserialize, Serialize};

/// Bingham plastic: τ = τ_y sgn(γ̇) + μ γ̇ (for |τ| > τ_y; rigid below).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bingham {
    /// Yield stress τ_y \[Pa\].
    pub yield_stress_pa: f64,
    /// Plastic viscosity μ \[Pa·s\].
    pub viscosity_pa_s: f64,
}

impl Bingham {
    /// Shear stress at a given shear rate (sgn(0) = 0).
    pub fn shear_stress(&self, shear_rate: f64) -> f64 {
        signum0(shear_rate) * self.yield_stress_pa + self.viscosity_pa_s * shear_rate
    }
}

/// Herschel–Bulkley: τ = (τ_y + k |γ̇|^m) sgn(γ̇); m = 1 is Bingham with μ = k.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HerschelBulkley {
    /// Yield stress τ_y \[Pa\].
    pub yield_stress_pa: f64,
    /// Consistency k \[Pa·s^m\].
    pub consistency_pa_sm: f64,
    /// Flow index m \[-\] (m < 1 shear thinning).
    pub flow_index: f64,
}

impl HerschelBulkley {
    /// Shear stress at a given shear rate (sgn(0) = 0).
    pub fn shear_stress(&self, shear_rate: f64) -> f64 {
        signum0(shear_rate)
            * (self.yield_stress_pa
                + self.consistency_pa_sm * shear_rate.abs().powf(self.flow_index))
    }
}

/// D0 of Skalski & Zalewski (2014): limiting plastic shear rate, fixed at 10⁶ 1/s.
pub const BODNER_PARTOM_D0: f64 = 1.0e6;

/// Simplified Bodner–Partom law of Skalski & Zalewski (2014), eq. (5.2):
///
/// γ̇ᴵ = 2 D0 exp[ −½ (R0 / (√3 τ))^(2n) (n+1)/n ] sgn(τ)
///
/// `r0_pa` is R0 in pascal. The paper's identified R0 (5.5) is read in **kPa with the
/// gap h in metres** (see [`BodnerPartom::from_paper`]): that reading gives τ0 ≈ 364 kPa at
/// 1 A, 25 °C, h = 0.7 mm, 73 1/s, the scale of their force records.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BodnerPartom {
    /// Rate-sensitivity exponent n \[-\].
    pub n: f64,
    /// Isotropic hardening (here constant) R0 \[Pa\].
    pub r0_pa: f64,
    /// Limiting shear rate D0 \[1/s\].
    pub d0: f64,
}

impl BodnerPartom {
    /// Parameters identified by Skalski & Zalewski, eq. (5.5):
    /// n = 0.18 + 0.10 i − 0.0001 t, R0 = (6.8 − 0.07 i − 0.01 t) / h, with i in A,
    /// t in °C and h in m; R0 from (5.5) is in kPa and converted here to Pa.
    pub fn from_paper(current_a: f64, temperature_c: f64, gap_m: f64) -> Self {
        let n = 0.18 + 0.10 * current_a - 0.0001 * temperature_c;
        let r0_kpa = (6.8 - 0.07 * current_a - 0.01 * temperature_c) / gap_m;
        Self {
            n,
            r0_pa: r0_kpa * 1.0e3,
            d0: BODNER_PARTOM_D0,
        }
    }

    /// c = (n+1)/(2n): the factor ½ (n+1)/n of eq. (5.2).
    fn c(&self) -> f64 {
        0.5 * (self.n + 1.0) / self.n
    }

    /// z = c (R0/(√3|τ|))^(2n) = ln(2 D0 / |γ̇ᴵ|): the exponent of eq. (5.2).
    fn exponent(&self, tau: f64) -> f64 {
        let s = (self.r0_pa / (3f64.sqrt() * tau.abs())).powf(2.0 * self.n);
        self.c() * s
    }

    /// Plastic shear rate γ̇ᴵ(τ), eq. (5.2).
    pub fn plastic_rate(&self, tau: f64) -> f64 {
        if tau == 0.0 {
            return 0.0;
        }
        signum0(tau) * 2.0 * self.d0 * (-self.exponent(tau)).exp()
    }

    /// γ̇ᴵ(τ) and its derivative dγ̇ᴵ/dτ (always ≥ 0).
    pub fn plastic_rate_and_slope(&self, tau: f64) -> (f64, f64) {
        if tau == 0.0 {
            return (0.0, 0.0);
        }
        let z = self.exponent(tau);
        let rate = 2.0 * self.d0 * (-z).exp();
        // d z / d|τ| = −2n z / |τ|  ⇒  d rate / d|τ| = rate · 2n z / |τ|
        let slope = rate * 2.0 * self.n * z / tau.abs();
        (signum0(tau) * rate, slope)
    }

    /// The yield point of the law, eq. (5.3): the stress at which the plastic rate
    /// equals `plastic_rate` (> 0):
    /// τ0 = R0/√3 · ( 2n/(n+1) · ln(2 D0 / γ̇ᴵ) )^(−1/(2n)).
    ///
    /// It is the exact inverse of (5.2). Returns NaN for rates outside (0, 2 D0).
    pub fn yield_point(&self, plastic_rate: f64) -> f64 {
        let g = plastic_rate.abs();
        if !(g > 0.0 && g < 2.0 * self.d0) {
            return f64::NAN;
        }
        let ln = (2.0 * self.d0 / g).ln();
        self.r0_pa / 3f64.sqrt() * (2.0 * self.n / (self.n + 1.0) * ln).powf(-0.5 / self.n)
    }

    /// Shear stress at which the plastic rate equals `plastic_rate`, odd in the rate
    /// (zero rate gives zero stress): the inverse of (5.2) used in rate-driven flows.
    pub fn shear_stress(&self, plastic_rate: f64) -> f64 {
        if plastic_rate == 0.0 {
            0.0
        } else {
            signum0(plastic_rate) * self.yield_point(plastic_rate)
        }
    }

    /// ∫₀^τw τ γ̇ᴵ(τ) dτ for τw ≥ 0, in closed form:
    /// (R0² D0 / (3n)) c^(1/n) Γ(−1/n, z_w), with z_w = ln(2 D0/γ̇ᴵ(τw)).
    ///
    /// This is the integral that gives the slit flow rate of a generalised Newtonian
    /// fluid (see `gap`). Γ(a, z) is the upper incomplete gamma function.
    pub fn first_moment_of_rate(&self, tau_w: f64) -> f64 {
        if tau_w <= 0.0 {
            return 0.0;
        }
        let z = self.exponent(tau_w);
        if z > 700.0 {
            return 0.0;
        }
        let a = -1.0 / self.n;
        self.r0_pa * self.r0_pa * self.d0 / (3.0 * self.n)
            * self.c().powf(1.0 / self.n)
            * upper_incomplete_gamma(a, z)
    }
}

/// Upper incomplete gamma Γ(a, z) for z > 0 and any real a, by the Legendre continued
/// fraction evaluated with the modified Lentz method (Numerical Recipes §6.2):
/// Γ(a,z) = e^(−z) z^a · 1/(z+1−a− 1(1−a)/(z+3−a− 2(2−a)/(z+5−a− …))).
/// Converges quickly for z ≳ 1 + |a|; used here with z = ln(2D0/γ̇) ≳ 5.
pub fn upper_incomplete_gamma(a: f64, z: f64) -> f64 {
    const TINY: f64 = 1.0e-300;
    let mut b = z + 1.0 - a;
    let mut c = 1.0 / TINY;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..200 {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        if d.abs() < TINY {
            d = TINY;
        }
        c = b + an / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() < 1.0e-11 {
            break;
        }
    }
    (-z + a * z.ln()).exp() * h
}

/// sgn with sgn(0) = 0 (Rust's `f64::signum` gives ±1 at ±0).
pub fn signum0(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yield_point_is_inverse_of_the_law() {
        let bp = BodnerPartom::from_paper(1.0, 25.0, 0.7e-3);
        for rate in [1e-3, 1.0, 73.0, 144.0, 217.0, 1e4] {
            let tau = bp.yield_point(rate);
            let back = bp.plastic_rate(tau);
            assert!(
                (back / rate - 1.0).abs() < 1e-10,
                "{rate} -> {tau} -> {back}"
            );
        }
    }

    #[test]
    fn slope_matches_finite_difference() {
        let bp = BodnerPartom::from_paper(2.0, 25.0, 0.7e-3);
        let tau = 5.0e5;
        let (_, slope) = bp.plastic_rate_and_slope(tau);
        let h = 1.0;
        let fd = (bp.plastic_rate(tau + h) - bp.plastic_rate(tau - h)) / (2.0 * h);
        assert!((slope / fd - 1.0).abs() < 1e-6);
    }

    #[test]
    fn incomplete_gamma_against_quadrature() {
        // Γ(a, z) = ∫_z^∞ t^(a−1) e^(−t) dt, by a fine composite Simpson rule.
        for &(a, z) in &[(-3.6, 5.0), (-2.0, 10.0), (-5.0, 3.0), (0.5, 2.0)] {
            let upper = z + 60.0;
            let n = 200_000;
            let h = (upper - z) / n as f64;
            let f = |t: f64| t.powf(a - 1.0) * (-t).exp();
            let mut s = f(z) + f(upper);
            for i in 1..n {
                let t = z + i as f64 * h;
                s += if i % 2 == 1 { 4.0 } else { 2.0 } * f(t);
            }
            let quad = s * h / 3.0;
            let cf = upper_incomplete_gamma(a, z);
            assert!(
                (cf / quad - 1.0).abs() < 1e-8,
                "a={a} z={z}: {cf} vs {quad}"
            );
        }
    }

    #[test]
    fn first_moment_against_quadrature() {
        let bp = BodnerPartom::from_paper(1.0, 25.0, 0.7e-3);
        let tau_w = 6.0e5;
        let n = 400_000;
        let h = tau_w / n as f64;
        let f = |t: f64| t * bp.plastic_rate(t);
        let mut s = f(0.0) + f(tau_w);
        for i in 1..n {
            s += if i % 2 == 1 { 4.0 } else { 2.0 } * f(i as f64 * h);
        }
        let quad = s * h / 3.0;
        let closed = bp.first_moment_of_rate(tau_w);
        assert!((closed / quad - 1.0).abs() < 1e-6, "{closed} vs {quad}");
    }

    #[test]
    fn herschel_bulkley_with_unit_index_is_bingham() {
        let hb = HerschelBulkley {
            yield_stress_pa: 1e4,
            consistency_pa_sm: 0.3,
            flow_index: 1.0,
        };
        let b = Bingham {
            yield_stress_pa: 1e4,
            viscosity_pa_s: 0.3,
        };
        for r in [-500.0, -1.0, 0.0, 2.0, 800.0] {
            assert!((hb.shear_stress(r) - b.shear_stress(r)).abs() < 1e-9);
        }
    }
}
