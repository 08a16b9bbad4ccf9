//! The two-chamber flow-mode damper of Graczykowski & Pawłowski, with each extra physical
//! effect switchable.
//!
//! Single-rod damper: piston area Ap, rod area Ar, chamber 1 on the rod side (A1 = Ap − Ar),
//! chamber 2 on the piston side over a floating piston and the gas. Pressures are gauge.
//! Equations (PHYSICS.md, "Paper 2", reconstructed from first principles):
//!
//! * chamber 1: (V1(x)/K) ṗ1 = A1 v − Q,             V1 = V10 − A1 x
//! * chamber 2: (V2(x)/K + Vg/(κ p2)) ṗ2 = Q − Ap v,  Vg = Vg0 (p0/p2)^(1/κ),
//!   V2 = V20 + Ap x + Vg0 − Vg
//! * gap flow Q(Δp), Δp = p1 − p2, from [`crate::gap`]: Bingham (blocked while
//!   |Δp| ≤ 2 τ_y L/h), Herschel–Bulkley or Bodner–Partom (5.2)
//! * rod force F = A1 p1 − Ap p2 (+ seal friction + fluid inertia + the fluid's yield
//!   step, [`FluidParams::yield_step_share`]); at rest F = −p0 Ar.
//!
//! Effects ([`EffectSet`]):
//! * `fluid_compressibility` off: K = ∞, the model is algebraic: Q = A1 v, and with the gas
//!   spring p2 = p0 (Vg0/(Vg0 + Ar x))^κ (the rod volume goes into the gas).
//! * `gas_spring` off: chamber 2 opens into an ideal compensator at zero gauge pressure
//!   (p2 ≡ 0), so there is neither preload nor gas stiffness.
//! * `seal_friction`: F_f = F_c tanh(v / v_s).
//! * `fluid_inertia`: F_i = (m_f + m_r) a, m_f = ρ L A1² / (b h), the fluid in the gap
//!   moving at Q/(b h) with Q = A1 v (its incompressible-limit form), and m_r the rigid
//!   mass moving between the load cell and the piston (rod, clevis, fixture), which a rig's
//!   load cell reads as the same `m a`: the two are one lumped inertia.
//! * `field_lag`: the fluid feels an effective current with τ_f İ_eff = I − I_eff.
//! * `thermal_softening`: lumped heat balance C Ṫ = P − G_th (T − T_amb) driven by the
//!   dissipated power P = QΔp + F_f v; τ_y falls linearly and μ exponentially with T
//!   (Bingham, Herschel–Bulkley), or through t in (5.5) (Bodner–Partom).
//!
//! The compressible model is stiff (chamber time constant V/(K dQ/dΔp) ~ 10⁻⁴ s): it is
//! integrated with TR-BDF2 ([`crate::integrate`]) in sub-steps of at most
//! `max_substep_s`; field lag is integrated exactly, the slow heat balance explicitly.

use serde::{Deserialize, Serialize};

use crate::effects::{Effect, EffectSet};
use crate::fluid::{Bingham, BodnerPartom, HerschelBulkley};
use crate::gap::{GapLaw, SlitFlow, SlitGap};
use crate::integrate::{trbdf2_adaptive, Matrix, NotConverged, StiffSystem, Tolerance, Vector};
use crate::model::{substep_count, substeps, DamperInput, DamperModel, DamperOutput};
use crate::models::polynomial_in_current;

/// The rod-force error, as a fraction of the yield force A1 Δp_y, below which the sub-step
/// after an opening flow is taken by step doubling instead of in parts
/// ([`TwoChamber::relaxed_after_switch`]). At 10⁻³ (about 1 N on the paper's damper at
/// 1 A) it is below what one ordinary 1 ms sub-step already errs by near a reversal (up
/// to 2.5 N against a 2 µs reference at 2 Hz, 10 mm, 1 A).
const SETTLED_FORCE_TOL: f64 = 1e-3;

/// Parts of a sub-step around a switch between blocked and flowing
/// ([`TwoChamber::switch_in_parts`]), and of the sub-step after an opening where step
/// doubling does not settle ([`TwoChamber::relaxed_after_switch`]).
const REFINE: usize = 8;

/// Which constitutive law the fluid follows in the gap.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum FluidLaw {
    /// Bingham plastic with τ_y(I), μ(I) quadratic in current.
    #[default]
    Bingham,
    /// Herschel–Bulkley with τ_y(I), k(I) quadratic in current and flow index m.
    HerschelBulkley,
    /// Bodner–Partom with n(t, i), R0(t, i, h) of Skalski & Zalewski (5.5).
    BodnerPartom,
}

/// The MR fluid of the gap: law, dependence on current and temperature.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FluidParams {
    /// Constitutive law in the gap.
    pub law: FluidLaw,
    /// Yield stress τ_y(I) = c0 + c1 |I| + c2 I² + … \[Pa, Pa/A, Pa/A², …\] at the reference
    /// temperature: 1 to [`crate::models::MAX_CURRENT_COEFFS`] coefficients, a quadratic by
    /// default ([`polynomial_in_current`]).
    pub yield_stress_pa: Vec<f64>,
    /// Plastic viscosity μ(I) (Herschel–Bulkley: consistency k(I)) = c0 + c1 |I| + c2 I² + …,
    /// 1 to [`crate::models::MAX_CURRENT_COEFFS`] coefficients.
    pub viscosity_pa_s: Vec<f64>,
    /// Current above which the laws in current are held at their value there \[A\]: the
    /// edge of the currents they were fitted on, beyond which a quartic may turn anywhere
    /// (an MR fluid saturates rather). `mrtwin fit` sets it to the records' peak current
    /// when it fits more than three coefficients. 0: no limit.
    pub current_range_a: f64,
    /// Herschel–Bulkley flow index m \[-\].
    pub flow_index: f64,
    /// Relative fall of τ_y per kelvin above the reference temperature \[1/K\].
    pub yield_stress_temp_coeff_per_k: f64,
    /// Exponential fall of μ per kelvin: μ(T) = μ(T_ref) exp(−β (T − T_ref)) \[1/K\].
    pub viscosity_temp_coeff_per_k: f64,
    /// Reference temperature of the polynomials \[°C\].
    pub reference_temperature_c: f64,
    /// Pre-yield leak λ \[-\]: a linear flow G_leak Δp in parallel with the law,
    /// G_leak = λ b h³/(12 μ(I, T) L), λ the bi-viscous fluid's inverse viscosity ratio
    /// μ/μ_pre ([`crate::gap`]). 0: the law alone (the flow blocks below yield). For
    /// Herschel–Bulkley the consistency k(I, T) stands for μ; for Bodner–Partom, whose
    /// law does not use it, μ is the `viscosity_pa_s` polynomial.
    pub pre_yield_leak: f64,
    /// Yield step β \[-\]: a share of the yield force reached as a step at flow start,
    /// `F_s = β A1 Δp_y(I, T) tanh(v / v_s)` beside the slit law, whose own rise from the
    /// yield point is a square root (Buckingham's slit equation). It follows the yield
    /// stress at every current and temperature. A real fluid's yield at reversal is often
    /// sharper than the slit law's; `mrtwin diagnose` finds it as the fluid's yield-scaled
    /// step (its `fluid_shape`) and `--write-params` carries it here. 0: none.
    pub yield_step_share: f64,
    /// Velocity scale v_s of the yield step's tanh \[m/s\].
    pub yield_step_velocity_m_s: f64,
}

impl Default for FluidParams {
    /// An MRF-132DG-like fluid: τ_y from 0.5 kPa (0 A) to 35.5 kPa (1 A) and 50.5 kPa (2 A);
    /// μ from 0.092 Pa·s (LORD, 40 °C) rising with field as Graczykowski & Pawłowski assume.
    fn default() -> Self {
        Self {
            law: FluidLaw::Bingham,
            yield_stress_pa: vec![500.0, 45_000.0, -10_000.0],
            viscosity_pa_s: vec![0.092, 0.5, -0.1],
            current_range_a: 0.0,
            flow_index: 0.8,
            yield_stress_temp_coeff_per_k: 0.005,
            viscosity_temp_coeff_per_k: 0.02,
            reference_temperature_c: 25.0,
            pre_yield_leak: 0.0,
            yield_step_share: 0.0,
            yield_step_velocity_m_s: 1.0e-3,
        }
    }
}

impl FluidParams {
    /// The flow through slit `gap` at current `i` \[A\] and temperature `t` \[°C\]: the
    /// law with its parameters there, and the pre-yield leak λ b h³/(12 μ L) beside it.
    pub fn flow_in(&self, gap: SlitGap, i: f64, t: f64) -> SlitFlow {
        let dt = t - self.reference_temperature_c;
        let i_law = if self.current_range_a > 0.0 {
            i.abs().min(self.current_range_a)
        } else {
            i
        };
        let tau_y = polynomial_in_current(&self.yield_stress_pa, i_law)
            * (1.0 - self.yield_stress_temp_coeff_per_k * dt).max(0.0);
        // μ(I, T) (Herschel–Bulkley: the consistency k(I, T)).
        let mu = polynomial_in_current(&self.viscosity_pa_s, i_law).max(1e-6)
            * (-self.viscosity_temp_coeff_per_k * dt).exp();
        let law = match self.law {
            FluidLaw::Bingham => GapLaw::Bingham(Bingham {
                yield_stress_pa: tau_y,
                viscosity_pa_s: mu,
            }),
            FluidLaw::HerschelBulkley => GapLaw::HerschelBulkley(HerschelBulkley {
                yield_stress_pa: tau_y,
                consistency_pa_sm: mu,
                flow_index: self.flow_index,
            }),
            FluidLaw::BodnerPartom => {
                GapLaw::BodnerPartom(BodnerPartom::from_paper(i.abs(), t, gap.height_m))
            }
        };
        let leak_m3_per_pa_s = if self.pre_yield_leak > 0.0 {
            self.pre_yield_leak * gap.width_m * gap.height_m.powi(3) / (12.0 * mu * gap.length_m)
        } else {
            0.0
        };
        SlitFlow {
            gap,
            law,
            leak_m3_per_pa_s,
        }
    }
}

/// Geometry and effect parameters of the two-chamber damper (SI units).
///
/// Defaults: a seat-damper-sized unit like the LORD MRD-1003-5 of the second paper
/// (32 mm bore, 10 mm rod, 2 MPa gas preload), giving about 1.3 kN yield force at 1 A.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TwoChamberParams {
    /// Piston (bore) diameter \[m\].
    pub piston_diameter_m: f64,
    /// Rod diameter \[m\].
    pub rod_diameter_m: f64,
    /// Fluid volume of chamber 1 (rod side) at x = 0 \[m³\].
    pub chamber1_volume_m3: f64,
    /// Fluid volume of chamber 2 (piston side) at x = 0 \[m³\].
    pub chamber2_volume_m3: f64,
    /// Mean radius of the annular gap \[m\]; slit width b = 2π r.
    pub gap_mean_radius_m: f64,
    /// Gap height h \[m\].
    pub gap_height_m: f64,
    /// Active (magnetised) length of the gap L \[m\].
    pub gap_active_length_m: f64,
    /// The fluid.
    pub fluid: FluidParams,
    /// Effective bulk modulus K \[Pa\] (`fluid_compressibility`).
    pub bulk_modulus_pa: f64,
    /// Gas preload p0 \[Pa gauge\] (`gas_spring`).
    pub gas_preload_pa: f64,
    /// Gas volume at x = 0 \[m³\] (`gas_spring`).
    pub gas_volume_m3: f64,
    /// Polytropic index κ of the gas (`gas_spring`).
    pub polytropic_index: f64,
    /// Coulomb seal friction F_c \[N\] (`seal_friction`).
    pub seal_friction_n: f64,
    /// Velocity scale of the tanh friction smoothing \[m/s\] (`seal_friction`).
    pub seal_friction_velocity_m_s: f64,
    /// Fluid density \[kg/m³\] (`fluid_inertia`).
    pub fluid_density_kg_m3: f64,
    /// Rigid mass moving between the load cell and the piston m_r \[kg\] (`fluid_inertia`,
    /// beside the gap fluid's: a rig's rod, clevis and fixture). Default 0.
    pub moving_mass_kg: f64,
    /// Field time constant τ_f \[s\] (`field_lag`).
    pub field_time_constant_s: f64,
    /// Lumped heat capacity of fluid and body \[J/K\] (`thermal_softening`).
    pub heat_capacity_j_per_k: f64,
    /// Heat loss conductance to ambient \[W/K\] (`thermal_softening`).
    pub heat_loss_w_per_k: f64,
    /// What the load cell reads at zero rod force \[N\]: a rig's zero error, added to the
    /// predicted force (a measurement offset, not physics; `mrtwin fit` estimates it).
    pub load_cell_offset_n: f64,
    /// Longest internal integration step \[s\].
    pub max_substep_s: f64,
}

impl Default for TwoChamberParams {
    fn default() -> Self {
        let ap = area(0.032);
        let a1 = ap - area(0.010);
        Self {
            piston_diameter_m: 0.032,
            rod_diameter_m: 0.010,
            chamber1_volume_m3: a1 * 0.06,
            chamber2_volume_m3: ap * 0.06,
            gap_mean_radius_m: 0.0145,
            gap_height_m: 0.8e-3,
            gap_active_length_m: 0.02,
            fluid: FluidParams::default(),
            bulk_modulus_pa: 5.0e8,
            gas_preload_pa: 2.0e6,
            gas_volume_m3: 2.0e-5,
            polytropic_index: 1.4,
            seal_friction_n: 20.0,
            seal_friction_velocity_m_s: 1.0e-3,
            fluid_density_kg_m3: 3090.0,
            moving_mass_kg: 0.0,
            field_time_constant_s: 0.010,
            heat_capacity_j_per_k: 300.0,
            heat_loss_w_per_k: 1.5,
            load_cell_offset_n: 0.0,
            max_substep_s: 1.0e-3,
        }
    }
}

fn area(d: f64) -> f64 {
    std::f64::consts::PI * 0.25 * d * d
}

impl TwoChamberParams {
    /// Piston area Ap \[m²\].
    pub fn piston_area(&self) -> f64 {
        area(self.piston_diameter_m)
    }
    /// Rod area Ar \[m²\].
    pub fn rod_area(&self) -> f64 {
        area(self.rod_diameter_m)
    }
    /// Annular area of chamber 1, A1 = Ap − Ar \[m²\].
    pub fn annulus_area(&self) -> f64 {
        self.piston_area() - self.rod_area()
    }
    /// The gap as a slit.
    pub fn slit(&self) -> SlitGap {
        SlitGap {
            width_m: 2.0 * std::f64::consts::PI * self.gap_mean_radius_m,
            height_m: self.gap_height_m,
            length_m: self.gap_active_length_m,
        }
    }
    /// Effective fluid mass seen at the rod, m_f = ρ L A1² / (b h) \[kg\].
    pub fn fluid_mass_kg(&self) -> f64 {
        let s = self.slit();
        self.fluid_density_kg_m3 * s.length_m * self.annulus_area().powi(2)
            / (s.width_m * s.height_m)
    }
    /// The inertia the load cell reads with `fluid_inertia`, m_f + m_r \[kg\].
    pub fn inertial_mass_kg(&self) -> f64 {
        self.fluid_mass_kg() + self.moving_mass_kg
    }
    /// Gap flow law at current `i` and temperature `t`.
    pub fn flow_at(&self, i: f64, t: f64) -> SlitFlow {
        self.fluid.flow_in(self.slit(), i, t)
    }
}

/// The two-chamber damper model.
#[derive(Debug, Clone)]
pub struct TwoChamber {
    params: TwoChamberParams,
    effects: EffectSet,
    p1: f64,
    p2: f64,
    current_eff: f64,
    temperature_c: f64,
    energy_j: f64,
    /// Force and dissipated power at the end of the last (sub-)step.
    last_force_power: (f64, f64),
    /// The last sub-step switched between blocked and flowing: refine the next one.
    refine_next: bool,
    /// The chamber solver failed in the last step (pressures held).
    solver_failed: bool,
    prev: Option<DamperInput>,
}

/// A stretch of a sub-step: its ends (the kinematics linear between them), its length
/// \[s\] and the gap's flow law at the sub-step's current.
#[derive(Clone, Copy)]
struct Span {
    from: DamperInput,
    to: DamperInput,
    h: f64,
    flow: SlitFlow,
}

impl Span {
    /// Another stretch of the same sub-step (same flow law).
    fn with(&self, from: DamperInput, to: DamperInput, h: f64) -> Span {
        Span {
            from,
            to,
            h,
            ..*self
        }
    }

    /// The two halves of this stretch.
    fn halves(&self) -> (Span, Span) {
        let mid = self.from.lerp(&self.to, 0.5);
        (
            self.with(self.from, mid, 0.5 * self.h),
            self.with(mid, self.to, 0.5 * self.h),
        )
    }

    /// |Δp| − Δp_y at the chamber pressures `y`: positive where the gap flows.
    fn excess(&self, y: &Vector<2>) -> f64 {
        (y[0] - y[1]).abs() - self.flow.yield_pressure()
    }

    /// Whether the gap flows at the chamber pressures `y`.
    fn flowing(&self, y: &Vector<2>) -> bool {
        self.excess(y) > 0.0
    }

    /// Whether the flow opened or blocked between `y0` and `y1` (never without a yield
    /// pressure).
    fn switched(&self, y0: &Vector<2>, y1: &Vector<2>) -> bool {
        self.flow.yield_pressure() > 0.0 && self.flowing(y0) != self.flowing(y1)
    }
}

/// Chamber pressures over one stretch, with the kinematics interpolated across it.
struct Chambers<'a> {
    m: &'a TwoChamber,
    span: Span,
}

impl StiffSystem<2> for Chambers<'_> {
    fn rhs(&self, theta: f64, y: &Vector<2>) -> (Vector<2>, Matrix<2>) {
        let p = &self.m.params;
        let (from, to) = (&self.span.from, &self.span.to);
        let x = from.displacement_m + theta * (to.displacement_m - from.displacement_m);
        let v = from.velocity_m_s + theta * (to.velocity_m_s - from.velocity_m_s);
        let (a1, ap) = (p.annulus_area(), p.piston_area());
        let k = p.bulk_modulus_pa;
        let v1 = p.chamber1_volume_m3 - a1 * x;
        let (q, dq) = self.span.flow.flow(y[0] - y[1]);
        let g1 = k / v1;
        let f1 = g1 * (a1 * v - q);
        if !self.m.effects.has(Effect::GasSpring) {
            return (
                Vector::<2>::new(f1, 0.0),
                Matrix::<2>::new(-g1 * dq, g1 * dq, 0.0, 0.0),
            );
        }
        let (c2, dc2) = self.m.chamber2_compliance(y[1], x);
        let net = q - ap * v;
        let f2 = net / c2;
        let j = Matrix::<2>::new(-g1 * dq, g1 * dq, dq / c2, -dq / c2 - net * dc2 / (c2 * c2));
        (Vector::<2>::new(f1, f2), j)
    }
}

impl TwoChamber {
    /// A model with these parameters and effects.
    pub fn new(params: TwoChamberParams, effects: EffectSet) -> Self {
        Self {
            params,
            effects,
            p1: 0.0,
            p2: 0.0,
            current_eff: 0.0,
            temperature_c: 25.0,
            energy_j: 0.0,
            last_force_power: (0.0, 0.0),
            refine_next: false,
            solver_failed: false,
            prev: None,
        }
    }

    /// The parameters.
    pub fn params(&self) -> &TwoChamberParams {
        &self.params
    }

    /// The effects switched on.
    pub fn effects(&self) -> EffectSet {
        self.effects
    }

    /// Chamber pressures (p1, p2) \[Pa gauge\].
    pub fn pressures(&self) -> (f64, f64) {
        (self.p1, self.p2)
    }

    fn gas_pressure_at_rest(&self) -> f64 {
        if self.effects.has(Effect::GasSpring) {
            self.params.gas_preload_pa
        } else {
            0.0
        }
    }

    /// Gas volume at pressure p2 (absolute pressure is not needed: p0 is the preload at
    /// which the gas holds Vg0, and the polytropic law is applied to gauge pressure as in
    /// PHYSICS.md; p2 is floored at 1 kPa to keep the law defined).
    fn gas_volume(&self, p2: f64) -> f64 {
        let p = &self.params;
        p.gas_volume_m3 * (p.gas_preload_pa / p2.max(1.0e3)).powf(1.0 / p.polytropic_index)
    }

    /// Compliance of chamber 2 with its gas, C2 = V2/K + Vg/(κ p2), and dC2/dp2.
    fn chamber2_compliance(&self, p2: f64, x: f64) -> (f64, f64) {
        let p = &self.params;
        let kappa = p.polytropic_index;
        let p2c = p2.max(1.0e3);
        let vg = self.gas_volume(p2c);
        let v2 = p.chamber2_volume_m3 + p.piston_area() * x + p.gas_volume_m3 - vg;
        let gas = vg / (kappa * p2c);
        let c2 = v2 / p.bulk_modulus_pa + gas;
        // dVg/dp2 = −Vg/(κ p2); d(Vg/(κ p2))/dp2 = −Vg (1+κ)/(κ² p2²).
        let dc2 = gas / p.bulk_modulus_pa - vg * (1.0 + kappa) / (kappa * kappa * p2c * p2c);
        (c2, dc2)
    }

    /// Gas pressure with incompressible fluid: the gas takes the rod volume,
    /// p2 = p0 (Vg0 / (Vg0 + Ar x))^κ.
    fn incompressible_gas_pressure(&self, x: f64) -> f64 {
        let p = &self.params;
        if !self.effects.has(Effect::GasSpring) {
            return 0.0;
        }
        let vg = (p.gas_volume_m3 + p.rod_area() * x).max(1e-3 * p.gas_volume_m3);
        p.gas_preload_pa * (p.gas_volume_m3 / vg).powf(p.polytropic_index)
    }

    fn seal_friction(&self, v: f64) -> f64 {
        if self.effects.has(Effect::SealFriction) {
            self.params.seal_friction_n * (v / self.params.seal_friction_velocity_m_s).tanh()
        } else {
            0.0
        }
    }

    /// The fluid's yield step `β A1 Δp_y tanh(v / v_s)` ([`FluidParams::yield_step_share`])
    /// with the flow law at the present current and temperature.
    fn yield_step(&self, v: f64, flow: &SlitFlow) -> f64 {
        let f = &self.params.fluid;
        if f.yield_step_share > 0.0 {
            f.yield_step_share
                * self.params.annulus_area()
                * flow.yield_pressure()
                * (v / f.yield_step_velocity_m_s).tanh()
        } else {
            0.0
        }
    }

    fn flow(&self) -> SlitFlow {
        self.params.flow_at(self.current_eff, self.temperature_c)
    }

    /// Force and dissipated power for the present pressures at kinematics `inp`.
    fn force_and_power(&self, inp: &DamperInput, flow: &SlitFlow) -> (f64, f64) {
        let p = &self.params;
        let dp = self.p1 - self.p2;
        let q = if self.effects.has(Effect::FluidCompressibility) {
            flow.flow(dp).0
        } else {
            p.annulus_area() * inp.velocity_m_s
        };
        let ff = self.seal_friction(inp.velocity_m_s) + self.yield_step(inp.velocity_m_s, flow);
        let inertia = if self.effects.has(Effect::FluidInertia) {
            p.inertial_mass_kg() * inp.acceleration_m_s2
        } else {
            0.0
        };
        let force = p.annulus_area() * self.p1 - p.piston_area() * self.p2
            + ff
            + inertia
            + p.load_cell_offset_n;
        let power = (q * dp).max(0.0) + ff * inp.velocity_m_s;
        (force, power)
    }

    fn solve_pressures(&mut self, from: &DamperInput, to: &DamperInput, h: f64, flow: SlitFlow) {
        if self.effects.has(Effect::FluidCompressibility) {
            // Around a switch between blocked and flowing, the chamber pressures relax on
            // the fast time constant V/(K dQ/dΔp): the sub-step holding the switch is cut
            // into `REFINE` parts where the flow is open, and the one after an opening is
            // taken by step doubling (docs/physics.md, "Integration").
            let y0 = Vector::<2>::new(self.p1, self.p2);
            let span = Span {
                from: *from,
                to: *to,
                h,
                flow,
            };
            let uniform = |m: &Self| {
                substeps(*from, *to, h, REFINE).try_fold(y0, |y, (a, b, hk)| {
                    m.integrate_chambers(&y, &span.with(a, b, hk))
                })
            };
            let y = if self.refine_next {
                // The sub-step after a switch: where one step and two half steps agree
                // (step doubling) and the flow keeps its state, the halves are the answer;
                // otherwise `REFINE` parts, as before.
                match self.relaxed_after_switch(&y0, &span) {
                    Some(y) => Ok((y, false)),
                    None => uniform(self).map(|y| (y, span.switched(&y0, &y))),
                }
            } else {
                // One step over the whole sub-step first: where the flow keeps its state
                // (all but the sub-steps at a stroke reversal) that is the answer.
                self.chambers_step(&y0, &span).and_then(|y1| {
                    if !span.switched(&y0, &y1) {
                        return Ok((y1, false));
                    }
                    // The flow opens or blocks within it: the sub-step is taken in
                    // `REFINE` parts, each cut further around the switch. (Taking the
                    // whole sub-step cut around the switch first, as before, only to
                    // throw it away when it confirms the switch, was the slow 1 % of
                    // the control loop's round trips: BENCHMARKS.md, "iceoryx2 control
                    // service".) Where the parts end on the side the flow started on,
                    // the whole sub-step cut around the switch decides, as before.
                    let yu = self.switch_in_parts(&y0, &y1, &span)?;
                    if span.switched(&y0, &yu) {
                        // Only an opening flow leaves pressures relaxing into the next
                        // sub-step; once blocked (Q = 0) they change smoothly.
                        return Ok((yu, span.flowing(&yu)));
                    }
                    let yb = self.refine_switch(&y0, y1, &span)?;
                    Ok(if span.switched(&y0, &yb) {
                        (yu, true)
                    } else {
                        (yb, false)
                    })
                })
            };
            // A sub-step the solver cannot take even at 2⁻¹⁰ of it holds the pressures
            // and is reported, not hidden.
            match y {
                Ok((y, switched)) => {
                    self.refine_next = switched;
                    self.p1 = y[0];
                    self.p2 = y[1];
                }
                Err(NotConverged) => self.solver_failed = true,
            }
        } else {
            self.p2 = self.incompressible_gas_pressure(to.displacement_m);
            let q = self.params.annulus_area() * to.velocity_m_s;
            self.p1 = self.p2 + flow.pressure_drop(q);
        }
    }

    /// The chamber pressures over a sub-step in which the flow opens or blocks (`y1`, the
    /// one-step probe, on the other side of the yield pressure from `y0`), in `REFINE`
    /// parts, the one the probe puts the switch in (by linear interpolation of
    /// |Δp| − Δp_y) taken straight as two halves, each halved further while it holds the
    /// switch. Cheaper where the pressures change smoothly:
    /// - the stretch before the switch is one step where it ends on the side it started:
    ///   blocked before an opening (Q = 0), flowing before a blocking (as in an ordinary
    ///   sub-step; it stops one part short of the switch's part, where a Herschel–Bulkley
    ///   flow near its yield stress is steep: with it up to the switch's part the RMS
    ///   error at 5 Hz was 3× larger);
    /// - after a blocking, the blocked rest is one step;
    /// - after an opening, the rest is taken by step doubling
    ///   ([`TwoChamber::relaxed_after_switch`]) where more than 3 parts are left and it
    ///   settles.
    ///
    /// A switch sub-step costs 5–7 TR-BDF2 steps where it used to cost 6–12: these
    /// sub-steps are the slow 1 % of the control loop (BENCHMARKS.md, "iceoryx2 control
    /// service").
    fn switch_in_parts(
        &self,
        y0: &Vector<2>,
        y1: &Vector<2>,
        s: &Span,
    ) -> Result<Vector<2>, NotConverged> {
        let at = |k: usize| s.from.lerp(&s.to, k as f64 / REFINE as f64);
        let part = s.h / REFINE as f64;
        let opening = !s.flowing(y0);
        let (mut y, mut first) = (*y0, 0);
        // The stretch before the switch in one step, where it ends on the side it started.
        let theta = s.excess(y0) / (s.excess(y0) - s.excess(y1));
        let at_switch = ((theta * REFINE as f64).floor() as usize).min(REFINE - 1);
        let before = if opening {
            at_switch
        } else {
            at_switch.saturating_sub(1)
        };
        if before > 0 {
            let yb = self.chambers_step(y0, &s.with(s.from, at(before), before as f64 * part))?;
            if s.flowing(&yb) != opening {
                (y, first) = (yb, before);
            }
        }
        for k in first..REFINE {
            let was_flowing = s.flowing(&y);
            let this = s.with(at(k), at(k + 1), part);
            y = if k == at_switch {
                // The part the probe puts the switch in: straight to its halves.
                let (first_half, second_half) = this.halves();
                let ym = self.integrate_chambers(&y, &first_half)?;
                self.integrate_chambers(&ym, &second_half)?
            } else {
                self.integrate_chambers(&y, &this)?
            };
            if k + 1 == REFINE || was_flowing == s.flowing(&y) {
                continue;
            }
            let rest = s.with(at(k + 1), s.to, (REFINE - k - 1) as f64 * part);
            if was_flowing {
                // Blocked: the rest in one step while it stays blocked.
                let yr = self.chambers_step(&y, &rest)?;
                if !s.flowing(&yr) {
                    return Ok(yr);
                }
            } else if REFINE - k - 1 > 3 {
                // Opened: the pressures relax on a fast time constant; the rest by step
                // doubling where it settles (3 steps instead of the parts left).
                if let Some(yr) = self.relaxed_after_switch(&y, &rest) {
                    return Ok(yr);
                }
            }
        }
        Ok(y)
    }

    /// The chamber pressures over the sub-step after a switch by step doubling: one
    /// TR-BDF2 step over it and two over its halves. The halves are returned when the
    /// flow keeps its state in all three and their Richardson estimate of the halves'
    /// error in the rod force, |A1 e1 − Ap e2| with e = (y_halves − y_whole)/3 (TR-BDF2 is
    /// second order), is below [`SETTLED_FORCE_TOL`] of the yield force; `None` otherwise
    /// (or where Newton fails), and the caller takes the sub-step in parts.
    ///
    /// Where it settles this takes 3 TR-BDF2 steps instead of 8: the sub-steps after a
    /// reversal were the slow 1 % of the control loop (BENCHMARKS.md, "iceoryx2 control
    /// service").
    fn relaxed_after_switch(&self, y0: &Vector<2>, s: &Span) -> Option<Vector<2>> {
        let (first_half, second_half) = s.halves();
        let first = self.chambers_step(y0, &first_half).ok()?;
        let halves = self.chambers_step(&first, &second_half).ok()?;
        let whole = self.chambers_step(y0, s).ok()?;
        if [whole, first, halves].iter().any(|y| s.switched(y0, y)) {
            return None;
        }
        let e = (halves - whole) / 3.0;
        let p = &self.params;
        let force_error = (p.annulus_area() * e[0] - p.piston_area() * e[1]).abs();
        let yield_force = p.annulus_area() * s.flow.yield_pressure();
        (force_error <= SETTLED_FORCE_TOL * yield_force).then_some(halves)
    }

    /// One TR-BDF2 step of the chamber pressures. Where the flow opens or blocks within the
    /// step (|Δp| crosses Δp_y, a kink in Q(Δp)), the step is halved recursively down to
    /// `MIN_SUBSTEP_S`, so the kink is resolved finely while smooth stretches take long
    /// steps.
    fn integrate_chambers(&self, y0: &Vector<2>, s: &Span) -> Result<Vector<2>, NotConverged> {
        let y1 = self.chambers_step(y0, s)?;
        self.refine_switch(y0, y1, s)
    }

    /// The chamber pressures after one TR-BDF2 step over the stretch (halved only where
    /// Newton fails), without looking at the flow's switches.
    fn chambers_step(&self, y0: &Vector<2>, s: &Span) -> Result<Vector<2>, NotConverged> {
        let sys = Chambers { m: self, span: *s };
        let tol = Tolerance {
            atol: Vector::<2>::new(1.0, 1.0),
            rtol: 1e-9,
        };
        trbdf2_adaptive(&sys, y0, 0.0, 1.0, s.h, &tol)
    }

    /// `y1`, the one-step result of [`TwoChamber::chambers_step`], unless the flow opened
    /// or blocked within the step: then the step halved recursively around the switch,
    /// down to `MIN_SUBSTEP_S`.
    fn refine_switch(
        &self,
        y0: &Vector<2>,
        y1: Vector<2>,
        s: &Span,
    ) -> Result<Vector<2>, NotConverged> {
        const MIN_SUBSTEP_S: f64 = 3.2e-5;
        if s.switched(y0, &y1) && s.h > 2.0 * MIN_SUBSTEP_S {
            let (first_half, second_half) = s.halves();
            let ym = self.integrate_chambers(y0, &first_half)?;
            return self.integrate_chambers(&ym, &second_half);
        }
        Ok(y1)
    }

    fn output(&self) -> DamperOutput {
        let (force_n, dissipated_power_w) = self.last_force_power;
        DamperOutput {
            force_n,
            dissipated_power_w,
            dissipated_energy_j: self.energy_j,
            fluid_temperature_c: self.temperature_c,
            effective_current_a: self.current_eff,
            solver_failed: self.solver_failed,
        }
    }
}

impl DamperModel for TwoChamber {
    fn clone_box(&self) -> Box<dyn DamperModel> {
        Box::new(self.clone())
    }

    fn id(&self) -> &'static str {
        "two-chamber"
    }

    fn reset(&mut self, input: &DamperInput) {
        self.current_eff = input.current_a;
        self.temperature_c = input.ambient_temperature_c;
        self.energy_j = 0.0;
        self.refine_next = false;
        self.solver_failed = false;
        if self.effects.has(Effect::FluidCompressibility) {
            let p0 = self.gas_pressure_at_rest();
            self.p1 = p0;
            self.p2 = p0;
        } else {
            let flow = self.flow();
            self.solve_pressures(input, input, 0.0, flow);
        }
        self.last_force_power = self.force_and_power(input, &self.flow());
        self.prev = Some(*input);
    }

    fn step(&mut self, input: &DamperInput, dt: f64) -> DamperOutput {
        let Some(prev) = self.prev else {
            self.reset(input);
            return self.output();
        };
        self.solver_failed = false;
        let n = substep_count(dt, self.params.max_substep_s);
        let mut power0 = self.last_force_power.1;
        for (from, to, h) in substeps(prev, *input, dt, n) {
            let i_mid = 0.5 * (from.current_a + to.current_a);
            self.current_eff = if self.effects.has(Effect::FieldLag) {
                let tau = self.params.field_time_constant_s.max(1e-9);
                self.current_eff + (1.0 - (-h / tau).exp()) * (i_mid - self.current_eff)
            } else {
                to.current_a
            };
            let flow = self.flow();
            self.solve_pressures(&from, &to, h, flow);
            self.last_force_power = self.force_and_power(&to, &flow);
            let power1 = self.last_force_power.1;
            let mean_power = 0.5 * (power0 + power1);
            self.energy_j += h * mean_power;
            if self.effects.has(Effect::ThermalSoftening) {
                let p = &self.params;
                let loss = p.heat_loss_w_per_k * (self.temperature_c - to.ambient_temperature_c);
                self.temperature_c += h * (mean_power - loss) / p.heat_capacity_j_per_k;
            } else {
                self.temperature_c = to.ambient_temperature_c;
            }
            power0 = power1;
        }
        self.prev = Some(*input);
        self.output()
    }
}
