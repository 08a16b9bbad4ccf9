//! The sample-by-sample interface shared by every damper model.
//!
//! A model is driven by [`DamperModel::step`] with the kinematics and current measured
//! (or commanded) at the end of the step; it integrates its internal state across the
//! step, interpolating the input linearly from the previous sample, and returns the
//! force. The same code serves live streams, replays and offline fits.

/// What drives a damper model at one instant (SI units, PHYSICS.md conventions:
/// x positive in extension).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DamperInput {
    /// Piston displacement x \[m\].
    pub displacement_m: f64,
    /// Piston velocity v = dx/dt \[m/s\].
    pub velocity_m_s: f64,
    /// Piston acceleration \[m/s²\] (used by fluid inertia; 0 where unknown).
    pub acceleration_m_s2: f64,
    /// Coil current \[A\].
    pub current_a: f64,
    /// Ambient (housing) temperature \[°C\].
    pub ambient_temperature_c: f64,
}

impl DamperInput {
    /// Linear interpolation between two inputs, `theta` ∈ \[0, 1\].
    pub fn lerp(&self, other: &Self, theta: f64) -> Self {
        let l = |a: f64, b: f64| a + (b - a) * theta;
        Self {
            displacement_m: l(self.displacement_m, other.displacement_m),
            velocity_m_s: l(self.velocity_m_s, other.velocity_m_s),
            acceleration_m_s2: l(self.acceleration_m_s2, other.acceleration_m_s2),
            current_a: l(self.current_a, other.current_a),
            ambient_temperature_c: l(self.ambient_temperature_c, other.ambient_temperature_c),
        }
    }
}

/// How many equal sub-steps of at most `max_substep_s` cover a step of `dt` (at least 1).
pub fn substep_count(dt: f64, max_substep_s: f64) -> usize {
    ((dt / max_substep_s).ceil() as usize).max(1)
}

/// `count` equal sub-steps from `from` to `to` over `dt` seconds: the input at the start
/// and at the end of each (interpolated linearly) and the sub-step's length.
pub fn substeps(
    from: DamperInput,
    to: DamperInput,
    dt: f64,
    count: usize,
) -> impl Iterator<Item = (DamperInput, DamperInput, f64)> {
    let h = dt / count as f64;
    (0..count).map(move |k| {
        (
            from.lerp(&to, k as f64 / count as f64),
            from.lerp(&to, (k + 1) as f64 / count as f64),
            h,
        )
    })
}

/// What a damper model predicts at the end of a step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DamperOutput {
    /// Force on the rod \[N\], positive when the damper resists extension.
    pub force_n: f64,
    /// Power dissipated at the end of the step \[W\] (≥ 0).
    pub dissipated_power_w: f64,
    /// Energy dissipated since reset \[J\], integrated inside the model's sub-steps.
    pub dissipated_energy_j: f64,
    /// Fluid temperature \[°C\] (the ambient one where the model is isothermal).
    pub fluid_temperature_c: f64,
    /// The current the fluid feels \[A\] (lags the coil current with field lag on).
    pub effective_current_a: f64,
    /// The implicit solver ([`crate::integrate`]) did not converge on this step, even at
    /// 2⁻¹⁰ of it: the state it integrates was held at the step's start.
    pub solver_failed: bool,
}

/// A damper model stepped sample by sample.
pub trait DamperModel: Send {
    /// Short identifier (`bingham`, `spencer`, `direct-shear`, `two-chamber`).
    fn id(&self) -> &'static str;
    /// Put the model at rest in equilibrium with `input` (no history).
    fn reset(&mut self, input: &DamperInput);
    /// Advance by `dt` seconds to the instant where `input` was taken. The first call
    /// after construction resets the model at `input` and integrates nothing.
    fn step(&mut self, input: &DamperInput, dt: f64) -> DamperOutput;
    /// A copy with the same state, for what-if predictions (a planned current) that
    /// must not advance the twin itself.
    fn clone_box(&self) -> Box<dyn DamperModel>;
}
