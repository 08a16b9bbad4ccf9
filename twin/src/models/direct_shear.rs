//! The direct-shear gap model of Skalski & Zalewski (2014).
//!
//! The fluid in a gap of height h between two cylinders is sheared by the piston stroke:
//! τ = F/A, γ = Δx/h (4.1), A = 2π r l with r = r1 + ⅔ (r2 − r1) (4.3), and the elastic–
//! viscoplastic split γ = τ/G + γᴵ (4.2), i.e.
//!
//! τ̇ = G (γ̇ − γ̇ᴵ(τ)),  γ̇ = v / h,
//!
//! with γ̇ᴵ(τ) the simplified Bodner–Partom law (5.4) and n(t, i), R0(t, i, h) from (5.5).
//! Under a constant shear rate the stress rises with slope G and saturates at the yield
//! point (5.3) for that rate: the shape of their Fig. 10. G is not given numerically in
//! the paper; the default (1 MPa) puts the elastic part of the first loading under
//! 0.3 mm of stroke, as their Fig. 3b suggests.
//!
//! The law is stiff near and above the yield point (G dγ̇ᴵ/dτ ≫ 1/dt), so τ is integrated
//! with TR-BDF2.

use serde::{Deserialize, Serialize};

use crate::fluid::BodnerPartom;
use crate::integrate::{trbdf2_adaptive, Matrix, StiffSystem, Tolerance, Vector};
use crate::model::{substep_count, substeps, DamperInput, DamperModel, DamperOutput};

/// Geometry and elasticity of the direct-shear gap.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DirectShearParams {
    /// Gap height h \[m\] (0.5, 0.7 or 1.0 mm in the paper).
    pub gap_height_m: f64,
    /// Inner radius of the gap r1 \[m\]; the outer radius is r1 + h.
    pub inner_radius_m: f64,
    /// Length of the gap l \[m\].
    pub length_m: f64,
    /// Kirchhoff (shear) modulus G \[Pa\].
    pub shear_modulus_pa: f64,
    /// Longest internal integration step \[s\].
    pub max_substep_s: f64,
}

impl Default for DirectShearParams {
    /// h = 0.7 mm; A ≈ 1.37e-3 m², so τ0 ≈ 364 kPa at 1 A gives about 500 N, the scale of
    /// the paper's records (10 N of friction was "about 2 %").
    fn default() -> Self {
        Self {
            gap_height_m: 0.7e-3,
            inner_radius_m: 0.0175,
            length_m: 0.0121,
            shear_modulus_pa: 1.0e6,
            max_substep_s: 2.5e-4,
        }
    }
}

impl DirectShearParams {
    /// Shear area A = 2π r l, r = r1 + ⅔ (r2 − r1), eq. (4.3).
    pub fn shear_area_m2(&self) -> f64 {
        let r = self.inner_radius_m + 2.0 / 3.0 * self.gap_height_m;
        2.0 * std::f64::consts::PI * r * self.length_m
    }
}

/// The direct-shear Bodner–Partom damper.
#[derive(Debug, Clone)]
pub struct DirectShear {
    params: DirectShearParams,
    tau: f64,
    energy_j: f64,
    prev: Option<DamperInput>,
}

struct Shear<'a> {
    params: &'a DirectShearParams,
    law: BodnerPartom,
    from: DamperInput,
    to: DamperInput,
}

impl StiffSystem<1> for Shear<'_> {
    fn rhs(&self, theta: f64, y: &Vector<1>) -> (Vector<1>, Matrix<1>) {
        let v = self.from.velocity_m_s + theta * (self.to.velocity_m_s - self.from.velocity_m_s);
        let g = self.params.shear_modulus_pa;
        let (rate, slope) = self.law.plastic_rate_and_slope(y[0]);
        (
            Vector::<1>::new(g * (v / self.params.gap_height_m - rate)),
            Matrix::<1>::new(-g * slope),
        )
    }
}

impl DirectShear {
    /// A model with these parameters.
    pub fn new(params: DirectShearParams) -> Self {
        Self {
            params,
            tau: 0.0,
            energy_j: 0.0,
            prev: None,
        }
    }

    /// The parameters.
    pub fn params(&self) -> &DirectShearParams {
        &self.params
    }

    /// Present shear stress τ \[Pa\].
    pub fn shear_stress(&self) -> f64 {
        self.tau
    }

    fn law(&self, inp: &DamperInput) -> BodnerPartom {
        BodnerPartom::from_paper(
            inp.current_a.abs(),
            inp.ambient_temperature_c,
            self.params.gap_height_m,
        )
    }

    /// Dissipated power A h τ γ̇ᴵ(τ) \[W\].
    fn power(&self, inp: &DamperInput) -> f64 {
        let p = &self.params;
        p.shear_area_m2() * p.gap_height_m * self.tau * self.law(inp).plastic_rate(self.tau)
    }

    fn output(&self, inp: &DamperInput) -> DamperOutput {
        DamperOutput {
            force_n: self.tau * self.params.shear_area_m2(),
            dissipated_power_w: self.power(inp),
            dissipated_energy_j: self.energy_j,
            fluid_temperature_c: inp.ambient_temperature_c,
            effective_current_a: inp.current_a,
            solver_failed: false,
        }
    }
}

impl DamperModel for DirectShear {
    fn clone_box(&self) -> Box<dyn DamperModel> {
        Box::new(self.clone())
    }

    fn id(&self) -> &'static str {
        "direct-shear"
    }

    fn reset(&mut self, input: &DamperInput) {
        self.tau = 0.0;
        self.energy_j = 0.0;
        self.prev = Some(*input);
    }

    fn step(&mut self, input: &DamperInput, dt: f64) -> DamperOutput {
        let Some(prev) = self.prev else {
            self.reset(input);
            return self.output(input);
        };
        let n = substep_count(dt, self.params.max_substep_s);
        let tol = Tolerance {
            atol: Vector::<1>::new(1e-3),
            rtol: 1e-10,
        };
        let mut power0 = self.power(&prev);
        // A sub-step the solver cannot take even at 2⁻¹⁰ of it holds τ and is reported.
        let mut solver_failed = false;
        for (from, to, h) in substeps(prev, *input, dt, n) {
            let sys = Shear {
                params: &self.params,
                law: self.law(&to),
                from,
                to,
            };
            match trbdf2_adaptive(&sys, &Vector::<1>::new(self.tau), 0.0, 1.0, h, &tol) {
                Ok(s) => self.tau = s[0],
                Err(_) => solver_failed = true,
            }
            let power1 = self.power(&to);
            self.energy_j += 0.5 * h * (power0 + power1);
            power0 = power1;
        }
        self.prev = Some(*input);
        DamperOutput {
            solver_failed,
            ..self.output(input)
        }
    }
}
