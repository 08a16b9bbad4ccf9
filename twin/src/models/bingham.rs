//! The Bingham baseline damper model: F = f_c(I) sgn(v) + c0(I) v + f0.
//!
//! The simplest phenomenological MR damper model (Stanway et al. 1987; PHYSICS.md
//! "Other common damper models"): a Coulomb element whose level f_c grows with current,
//! a viscous dashpot c0 and an offset f0 (accumulator). Algebraic, no state.

use serde::{Deserialize, Serialize};

use crate::fluid::signum0;
use crate::model::{DamperInput, DamperModel, DamperOutput};
use crate::models::quadratic_in_current;

/// Parameters of the Bingham damper; f_c and c0 are quadratic in |I|.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BinghamParams {
    /// f_c(I) = c0 + c1 |I| + c2 I² \[N\].
    pub friction_force_n: [f64; 3],
    /// c0(I) = c0 + c1 |I| + c2 I² \[N·s/m\].
    pub damping_n_s_m: [f64; 3],
    /// Force offset f0 \[N\].
    pub offset_n: f64,
}

impl Default for BinghamParams {
    /// Sized like the default two-chamber damper (≈1.1 kN Coulomb level at 1 A).
    fn default() -> Self {
        Self {
            friction_force_n: [30.0, 1300.0, -250.0],
            damping_n_s_m: [250.0, 1800.0, -300.0],
            offset_n: 0.0,
        }
    }
}

/// The Bingham damper.
#[derive(Debug, Clone)]
pub struct BinghamDamper {
    params: BinghamParams,
    energy_j: f64,
    prev_power: Option<f64>,
}

impl BinghamDamper {
    /// A model with these parameters.
    pub fn new(params: BinghamParams) -> Self {
        Self {
            params,
            energy_j: 0.0,
            prev_power: None,
        }
    }

    /// The force at an input.
    pub fn force(&self, inp: &DamperInput) -> f64 {
        let v = inp.velocity_m_s;
        quadratic_in_current(&self.params.friction_force_n, inp.current_a) * signum0(v)
            + quadratic_in_current(&self.params.damping_n_s_m, inp.current_a) * v
            + self.params.offset_n
    }

    fn output(&self, inp: &DamperInput, power: f64) -> DamperOutput {
        DamperOutput {
            force_n: self.force(inp),
            dissipated_power_w: power,
            dissipated_energy_j: self.energy_j,
            fluid_temperature_c: inp.ambient_temperature_c,
            effective_current_a: inp.current_a,
            // Algebraic: no solver to fail.
            solver_failed: false,
        }
    }
}

impl DamperModel for BinghamDamper {
    fn clone_box(&self) -> Box<dyn DamperModel> {
        Box::new(self.clone())
    }

    fn id(&self) -> &'static str {
        "bingham"
    }

    fn reset(&mut self, _input: &DamperInput) {
        self.energy_j = 0.0;
        self.prev_power = None;
    }

    fn step(&mut self, input: &DamperInput, dt: f64) -> DamperOutput {
        // Dissipation excludes the conservative offset f0.
        let power = (self.force(input) - self.params.offset_n) * input.velocity_m_s;
        if let Some(p0) = self.prev_power {
            self.energy_j += 0.5 * dt * (p0 + power);
        }
        self.prev_power = Some(power);
        self.output(input, power)
    }
}
