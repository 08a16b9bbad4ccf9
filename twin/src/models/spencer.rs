//! Spencer's modified Bouc–Wen model (Spencer, Dyke, Sain & Carlson, J. Eng. Mech.
//! 123(3), 1997), eqs. (9)–(14) of that paper, in SI units:
//!
//! * F = c1 ẏ + k1 (x − x0) + F_off, with F_off the load cell's zero (not in the paper; 0
//!   by default)
//! * ż = −γ |ẋ − ẏ| z |z|^(n−1) − β (ẋ − ẏ) |z|^n + A (ẋ − ẏ)
//! * ẏ = [α z + c0 ẋ + k0 (x − y)] / (c0 + c1)
//! * α = αa + αb u, c1 = c1a + c1b u, c0 = c0a + c0b u
//! * u̇ = −η (u − v_cmd): first-order filter of the command voltage (field dynamics),
//!   with v_cmd = `volts_per_amp` · I.
//!
//! The Bouc–Wen state is stiff at 1 kHz ((γ+β)|ẋ−ẏ||z| ~ 10⁴ 1/s), so (y, z) are integrated
//! with TR-BDF2; u is integrated exactly.

use serde::{Deserialize, Serialize};

use crate::fluid::signum0;
use crate::integrate::{trbdf2_adaptive, Matrix, StiffSystem, Tolerance, Vector};
use crate::model::{substep_count, substeps, DamperInput, DamperModel, DamperOutput};

/// Parameters of the modified Bouc–Wen model (defaults: Spencer et al. 1997, Table 1,
/// converted to SI).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SpencerParams {
    /// c0a \[N·s/m\].
    pub c0a: f64,
    /// c0b \[N·s/(m·V)\].
    pub c0b: f64,
    /// k0 \[N/m\].
    pub k0: f64,
    /// c1a \[N·s/m\].
    pub c1a: f64,
    /// c1b \[N·s/(m·V)\].
    pub c1b: f64,
    /// k1 \[N/m\] (accumulator stiffness).
    pub k1: f64,
    /// x0 \[m\] (accumulator initial displacement).
    pub x0: f64,
    /// F_off \[N\]: the load cell's zero, added to the force (not in the paper; with k1,
    /// x0 gives an offset too, which `mrtwin fit` holds and fits this one instead).
    pub load_cell_offset_n: f64,
    /// αa \[N/m\].
    pub alpha_a: f64,
    /// αb \[N/(m·V)\].
    pub alpha_b: f64,
    /// γ \[1/m²\].
    pub gamma: f64,
    /// β \[1/m²\].
    pub beta: f64,
    /// A \[-\].
    pub a: f64,
    /// n \[-\].
    pub n: f64,
    /// η \[1/s\] (command filter).
    pub eta: f64,
    /// Command voltage per ampere of coil current \[V/A\].
    pub volts_per_amp: f64,
    /// Longest internal integration step \[s\].
    pub max_substep_s: f64,
}

impl Default for SpencerParams {
    fn default() -> Self {
        Self {
            c0a: 2100.0,
            c0b: 350.0,
            k0: 4690.0,
            c1a: 28_300.0,
            c1b: 2950.0,
            k1: 500.0,
            x0: 0.143,
            load_cell_offset_n: 0.0,
            alpha_a: 14_000.0,
            alpha_b: 69_500.0,
            gamma: 3.63e6,
            beta: 3.63e6,
            a: 301.0,
            n: 2.0,
            eta: 190.0,
            volts_per_amp: 1.125,
            max_substep_s: 2.5e-4,
        }
    }
}

/// The modified Bouc–Wen damper.
#[derive(Debug, Clone)]
pub struct Spencer {
    params: SpencerParams,
    y: f64,
    z: f64,
    u: f64,
    energy_j: f64,
    prev: Option<DamperInput>,
}

struct BoucWen<'a> {
    p: &'a SpencerParams,
    u: f64,
    from: DamperInput,
    to: DamperInput,
}

impl BoucWen<'_> {
    fn coefficients(&self) -> (f64, f64, f64) {
        let p = self.p;
        (
            p.alpha_a + p.alpha_b * self.u,
            p.c0a + p.c0b * self.u,
            p.c1a + p.c1b * self.u,
        )
    }
}

impl StiffSystem<2> for BoucWen<'_> {
    fn rhs(&self, theta: f64, s: &Vector<2>) -> (Vector<2>, Matrix<2>) {
        let p = self.p;
        let inp = self.from.lerp(&self.to, theta);
        let (x, xd) = (inp.displacement_m, inp.velocity_m_s);
        let (y, z) = (s[0], s[1]);
        let (alpha, c0, c1) = self.coefficients();
        let yd = (alpha * z + c0 * xd + p.k0 * (x - y)) / (c0 + c1);
        let w = xd - yd;
        let az = z.abs();
        let zn1 = az.powf(p.n - 1.0);
        let zd = -p.gamma * w.abs() * z * zn1 - p.beta * w * az * zn1 + p.a * w;
        // Jacobian.
        let dyd_dy = -p.k0 / (c0 + c1);
        let dyd_dz = alpha / (c0 + c1);
        let dg_dw = -p.gamma * signum0(w) * z * zn1 - p.beta * az * zn1 + p.a;
        let dg_dz = -p.gamma * w.abs() * p.n * zn1 - p.beta * w * p.n * zn1 * signum0(z);
        let j = Matrix::<2>::new(dyd_dy, dyd_dz, -dg_dw * dyd_dy, -dg_dw * dyd_dz + dg_dz);
        (Vector::<2>::new(yd, zd), j)
    }
}

impl Spencer {
    /// A model with these parameters.
    pub fn new(params: SpencerParams) -> Self {
        Self {
            params,
            y: 0.0,
            z: 0.0,
            u: 0.0,
            energy_j: 0.0,
            prev: None,
        }
    }

    fn ydot_and_force(&self, inp: &DamperInput) -> (f64, f64) {
        let p = &self.params;
        let sys = BoucWen {
            p,
            u: self.u,
            from: *inp,
            to: *inp,
        };
        let yd = sys.rhs(0.0, &Vector::<2>::new(self.y, self.z)).0[0];
        let c1 = p.c1a + p.c1b * self.u;
        (
            yd,
            c1 * yd + p.k1 * (inp.displacement_m - p.x0) + p.load_cell_offset_n,
        )
    }

    /// Dissipated power: force minus the conservative spring k1 (x − x0) and k0, times the
    /// velocities of the dashpots and the hysteretic element: c0 (ẋ−ẏ)² + c1 ẏ² + α z (ẋ−ẏ)
    /// (the Bouc–Wen term's power; non-negative over a cycle, not at every instant).
    fn power(&self, inp: &DamperInput) -> f64 {
        let p = &self.params;
        let (yd, _) = self.ydot_and_force(inp);
        let w = inp.velocity_m_s - yd;
        let c0 = p.c0a + p.c0b * self.u;
        let c1 = p.c1a + p.c1b * self.u;
        let alpha = p.alpha_a + p.alpha_b * self.u;
        c0 * w * w + c1 * yd * yd + alpha * self.z * w
    }

    fn output(&self, inp: &DamperInput) -> DamperOutput {
        DamperOutput {
            force_n: self.ydot_and_force(inp).1,
            dissipated_power_w: self.power(inp),
            dissipated_energy_j: self.energy_j,
            fluid_temperature_c: inp.ambient_temperature_c,
            effective_current_a: self.u / self.params.volts_per_amp,
            solver_failed: false,
        }
    }
}

impl DamperModel for Spencer {
    fn clone_box(&self) -> Box<dyn DamperModel> {
        Box::new(self.clone())
    }

    fn id(&self) -> &'static str {
        "spencer"
    }

    fn reset(&mut self, input: &DamperInput) {
        self.y = input.displacement_m;
        self.z = 0.0;
        self.u = self.params.volts_per_amp * input.current_a.abs();
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
            atol: Vector::<2>::new(1e-12, 1e-12),
            rtol: 1e-10,
        };
        let mut power0 = self.power(&prev);
        // A sub-step the solver cannot take even at 2⁻¹⁰ of it holds (y, z) and is reported.
        let mut solver_failed = false;
        for (from, to, h) in substeps(prev, *input, dt, n) {
            let cmd = self.params.volts_per_amp * 0.5 * (from.current_a + to.current_a).abs();
            self.u += (1.0 - (-self.params.eta * h).exp()) * (cmd - self.u);
            let sys = BoucWen {
                p: &self.params,
                u: self.u,
                from,
                to,
            };
            match trbdf2_adaptive(&sys, &Vector::<2>::new(self.y, self.z), 0.0, 1.0, h, &tol) {
                Ok(s) => {
                    self.y = s[0];
                    self.z = s[1];
                }
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
