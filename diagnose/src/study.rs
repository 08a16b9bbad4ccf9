//! Recordings with concealed effects, generated with formulations that differ from the
//! candidate models of [`crate::model`], for the tests and the `diagnose-study` binary.
//!
//! The damper is twin's two-chamber model ([`twin::models::two_chamber::TwoChamber`],
//! exact Bingham slit flow, TR-BDF2 chambers) with these differences from diagnose's own
//! candidates:
//! * yield stress and viscosity saturate in current, `τ_y = τ_off + τ_1 g(I)`,
//!   `μ = μ_0 + μ_1 g(I)` with `g = tanh(I / 0.6 A)` (the "unusual" null uses an S-shaped
//!   `g`), while diagnose fits free values per current level;
//! * `seal_friction`: exponential smoothing `F_c (1 − exp(−|v|/v_s)) sgn v`, v_s = 2 mm/s
//!   (diagnose: tanh with its own scale);
//! * `gas_spring`: polytropic gas (p2 = p0 (Vg0/(Vg0 + Ar x))^1.4), diagnose: F0 + k x;
//! * `fluid_compressibility`: two chambers with position-dependent volumes and a 1.5 GPa
//!   oil (diagnose: one lumped compliance, backward Euler);
//! * `thermal_softening`: lumped heat balance with losses, C Ṫ = P − G (T − T_a), yield
//!   linear and viscosity exponential in T (diagnose: scale linear in the dissipated energy);
//! * `field_lag`: second order, two cascaded lags of 6 ms and 4 ms (diagnose: first order);
//! * `fluid_inertia`: twin's gap fluid mass m_f a (the only physical form).
//!
//! Programme: 60 s at 500 Hz, three 20 s blocks at 1, 2.5 and 5 Hz (8 mm amplitude); in
//! each the current steps through 0, 0.5 and 1 A every 0.7 s, so steps fall at every stroke
//! phase. Force noise: Gaussian, σ = 10 N.

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use twin::models::two_chamber::{TwoChamber, TwoChamberParams};
use twin::{DamperInput, DamperModel, Effect, EffectSet};

use crate::data::Signals;

/// Force-noise standard deviation \[N\].
pub const NOISE_N: f64 = 10.0;
/// Sample rate \[Hz\].
pub const RATE_HZ: f64 = 500.0;

/// Which yield law in current the generator uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum YieldLaw {
    /// Saturating: g(I) = tanh(I / 0.6).
    Saturating,
    /// S-shaped: flat near 0 A, steep around 0.5 A, flat again near 1 A.
    SShaped,
}

impl YieldLaw {
    fn g(self, i: f64) -> f64 {
        let i = i.abs();
        match self {
            YieldLaw::Saturating => (i / 0.6).tanh(),
            YieldLaw::SShaped => {
                let s = |x: f64| 0.5 * (1.0 + ((x - 0.5) / 0.12).tanh());
                (s(i) - s(0.0)) / (s(1.0) - s(0.0))
            }
        }
    }
}

/// A study scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// Short name.
    pub name: String,
    /// Hidden effects.
    pub hidden: Vec<Effect>,
    /// Yield law.
    pub yield_law: YieldLaw,
}

impl Scenario {
    /// One hidden effect.
    pub fn hidden(e: Effect) -> Self {
        Self {
            name: format!("hidden {}", e.id()),
            hidden: vec![e],
            yield_law: YieldLaw::Saturating,
        }
    }
    /// Every scenario of the study: each effect alone, the nulls, and two pairs.
    pub fn all() -> Vec<Scenario> {
        let mut v: Vec<Scenario> = Effect::ALL.iter().map(|e| Self::hidden(*e)).collect();
        v.push(Self {
            name: "null (current steps, no lag)".into(),
            hidden: vec![],
            yield_law: YieldLaw::Saturating,
        });
        v.push(Self {
            name: "null, S-shaped τ0(I)".into(),
            hidden: vec![],
            yield_law: YieldLaw::SShaped,
        });
        v.push(Self {
            name: "pair seal_friction + field_lag".into(),
            hidden: vec![Effect::SealFriction, Effect::FieldLag],
            yield_law: YieldLaw::Saturating,
        });
        v.push(Self {
            name: "pair gas_spring + thermal_softening".into(),
            hidden: vec![Effect::GasSpring, Effect::ThermalSoftening],
            yield_law: YieldLaw::Saturating,
        });
        v
    }
    fn has(&self, e: Effect) -> bool {
        self.hidden.contains(&e)
    }
}

/// The stroke and coil current at time t: (x, v, a, I).
fn programme(t: f64) -> (f64, f64, f64, f64) {
    let amp = 0.008;
    let (block, tl) = ((t / 20.0).floor().min(2.0) as usize, t % 20.0);
    let f = [1.0, 2.5, 5.0][block];
    let w = 2.0 * std::f64::consts::PI * f;
    let (s, c) = (w * tl).sin_cos();
    let level = (((t + 0.31) / 0.7).floor() as usize) % 3;
    (
        amp * s,
        amp * w * c,
        -amp * w * w * s,
        [0.0, 0.5, 1.0][level],
    )
}

/// Generate a 60 s recording of `scn` with noise seed `seed`; also returns the final fluid
/// temperature rise \[K\] (0 when isothermal).
pub fn generate(scn: &Scenario, seed: u64) -> (Signals, f64) {
    let mut p = TwoChamberParams::default();
    p.fluid.yield_stress_pa = vec![500.0, 40_000.0, 0.0];
    p.fluid.viscosity_pa_s = vec![0.092, 0.35, 0.0];
    p.bulk_modulus_pa = 1.5e9;
    p.gas_preload_pa = 1.17e6;
    p.heat_capacity_j_per_k = 450.0;
    p.heat_loss_w_per_k = 1.5;
    p.max_substep_s = 1.0e-3;
    let mut effects = EffectSet::NONE;
    for e in [
        Effect::FluidCompressibility,
        Effect::GasSpring,
        Effect::ThermalSoftening,
        Effect::FluidInertia,
    ] {
        if scn.has(e) {
            effects = effects.with(e);
        }
    }
    let mut model = TwoChamber::new(p, effects);
    let n = (60.0 * RATE_HZ) as usize;
    let dt = 1.0 / RATE_HZ;
    let (fc, vs) = (2.0 * NOISE_N, 0.002);
    let (tau1, tau2) = (0.006, 0.004);
    let mut lag1 = 0.0;
    let mut lag2 = 0.0;
    let normal = Normal::new(0.0, NOISE_N).expect("valid noise");
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut sig = Signals::default();
    let mut t_rise = 0.0;
    for k in 0..n {
        let t = k as f64 * dt;
        let (x, v, a, i) = programme(t);
        // Second-order field lag on the coil current, integrated exactly per sample.
        let i_field = if scn.has(Effect::FieldLag) {
            if k == 0 {
                lag1 = i;
                lag2 = i;
            } else {
                lag1 += (1.0 - (-dt / tau1).exp()) * (i - lag1);
                lag2 += (1.0 - (-dt / tau2).exp()) * (lag1 - lag2);
            }
            lag2
        } else {
            i
        };
        let input = DamperInput {
            displacement_m: x,
            velocity_m_s: v,
            acceleration_m_s2: a,
            current_a: scn.yield_law.g(i_field),
            ambient_temperature_c: 25.0,
        };
        let out = if k == 0 {
            model.reset(&input);
            model.step(&input, 0.0)
        } else {
            model.step(&input, dt)
        };
        t_rise = out.fluid_temperature_c - 25.0;
        let mut f = out.force_n;
        if scn.has(Effect::SealFriction) {
            f += fc * (1.0 - (-v.abs() / vs).exp()) * v.signum();
        }
        f += normal.sample(&mut rng);
        sig.time_s.push(t);
        sig.displacement_m.push(x);
        sig.velocity_m_s.push(v);
        sig.force_n.push(f);
        sig.current_a.push(i);
    }
    (sig, t_rise)
}
