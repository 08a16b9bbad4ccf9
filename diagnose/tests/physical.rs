//! At a single stroke frequency a fluid mass (F = m a = −m ω² x) and a spring of stiffness
//! k = −m ω² predict the same force. A gas spring only stiffens (k ≥ 0: the gas pushes the
//! rod out harder the further it is in), so a positive mass cannot be a gas: diagnose must
//! name the inertia, with the generator's mass, and never the gas. (Before parameters
//! were held physical this record was reported as undecided between the two.)

use diagnose::{diagnose, Options, Signals};
use twin::models::two_chamber::{TwoChamber, TwoChamberParams};
use twin::stand::{run, Noise, Programme};
use twin::{Effect, EffectSet};

#[test]
fn inertia_at_one_frequency_is_named_inertia_never_a_negative_gas_spring() {
    let mut p = TwoChamberParams::default();
    // A heavy fluid column (m_f ≈ 4.5 kg) so that the inertia force (≈ 35 N at 5 Hz, 8 mm)
    // stands well above the noise.
    p.fluid_density_kg_m3 *= 10.0;
    let mut model = TwoChamber::new(p, EffectSet::NONE.with(Effect::FluidInertia));
    let prog = Programme::grid(0.008, &[5.0], &[0.0, 0.5, 1.0], 8.0, 500.0);
    let samples = run(
        &mut model,
        &prog,
        Some(Noise {
            fraction: 0.004,
            seed: 3,
        }),
    );
    let sig = Signals {
        time_s: samples.iter().map(|s| s.time_s).collect(),
        displacement_m: samples.iter().map(|s| s.input.displacement_m).collect(),
        velocity_m_s: samples.iter().map(|s| s.input.velocity_m_s).collect(),
        force_n: samples.iter().map(|s| s.measured_force_n).collect(),
        current_a: samples.iter().map(|s| s.input.current_a).collect(),
        velocity_derived: false,
    };
    let dg = diagnose(&sig, "one frequency", &Options::default()).unwrap();
    let r = &dg.report;
    assert_eq!(
        dg.found(),
        vec!["fluid_inertia".to_string()],
        "undecided {:?}",
        r.undecided
    );
    // The generator's fluid column: ρ L A1² / (b h) with ten times the density.
    let m = r.findings[0].parameters["fluid_mass"].value;
    let p10 = {
        let mut p = TwoChamberParams::default();
        p.fluid_density_kg_m3 *= 10.0;
        p
    };
    let width = 2.0 * std::f64::consts::PI * p10.gap_mean_radius_m;
    let want = p10.fluid_density_kg_m3 * p10.gap_active_length_m * p10.annulus_area().powi(2)
        / (width * p10.gap_height_m);
    assert!(
        (m / want - 1.0).abs() < 0.3,
        "mass {m} kg, generator {want} kg"
    );
    assert!(r.final_model.holdout_rmse_n < 0.9 * r.baseline.holdout_rmse_n);
}
