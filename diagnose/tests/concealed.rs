//! diagnose on recordings with concealed effects (diagnose::study: twin's two-chamber model
//! with formulations that differ from diagnose's candidates, σ = 10 N force noise):
//! it must name exactly the hidden effect(s), the held-out error must fall, and on null
//! recordings (current steps without lag, an S-shaped yield curve) it must find nothing.

use diagnose::study::{generate, Scenario, YieldLaw};
use diagnose::{diagnose, Diagnosis, Options};
use twin::Effect;

const SEEDS: [u64; 3] = [1000, 1001, 1002];

fn run(scn: &Scenario, seed: u64) -> Diagnosis {
    let (sig, _) = generate(scn, seed);
    diagnose(&sig, &scn.name, &Options::default()).expect("generated data are valid")
}

fn expect_exactly(scn: &Scenario, seeds: &[u64]) {
    for &seed in seeds {
        let dg = run(scn, seed);
        let r = &dg.report;
        let mut want: Vec<String> = scn.hidden.iter().map(|e| e.id().to_string()).collect();
        want.sort();
        let mut got = dg.found();
        got.sort();
        assert_eq!(
            got, want,
            "{} seed {seed}: found {got:?}, undecided {:?}",
            scn.name, r.undecided
        );
        assert!(
            r.undecided.is_empty(),
            "{} seed {seed}: {:?}",
            scn.name,
            r.undecided
        );
        for f in &r.findings {
            assert!(
                f.evidence.holdout_rmse_after_n < f.evidence.holdout_rmse_before_n,
                "{} seed {seed}: {} does not lower the held-out error",
                scn.name,
                f.effect
            );
            for (name, p) in &f.parameters {
                assert!(
                    p.ci95[0] <= p.value && p.value <= p.ci95[1],
                    "{name}: {p:?}"
                );
            }
        }
        if want.is_empty() {
            assert_eq!(r.final_model.holdout_rmse_n, r.baseline.holdout_rmse_n);
        } else {
            assert!(
                r.final_model.holdout_rmse_n < r.baseline.holdout_rmse_n,
                "{} seed {seed}: held-out {} → {}",
                scn.name,
                r.baseline.holdout_rmse_n,
                r.final_model.holdout_rmse_n
            );
        }
    }
}

#[test]
fn finds_hidden_seal_friction() {
    expect_exactly(&Scenario::hidden(Effect::SealFriction), &SEEDS);
}

#[test]
fn finds_hidden_gas_spring() {
    expect_exactly(&Scenario::hidden(Effect::GasSpring), &SEEDS);
}

#[test]
fn finds_hidden_compressibility() {
    expect_exactly(&Scenario::hidden(Effect::FluidCompressibility), &SEEDS);
}

#[test]
fn finds_hidden_thermal_softening_without_a_temperature_channel() {
    let scn = Scenario::hidden(Effect::ThermalSoftening);
    let (_, rise) = generate(&scn, 1);
    assert!(
        (8.0..14.0).contains(&rise),
        "temperature rise {rise} K, want about 10 K"
    );
    expect_exactly(&scn, &SEEDS);
}

#[test]
fn finds_hidden_field_lag() {
    expect_exactly(&Scenario::hidden(Effect::FieldLag), &SEEDS);
}

#[test]
fn finds_hidden_fluid_inertia() {
    expect_exactly(&Scenario::hidden(Effect::FluidInertia), &SEEDS);
}

#[test]
fn finds_nothing_with_current_steps_and_no_lag() {
    let scn = Scenario {
        name: "null".into(),
        hidden: vec![],
        yield_law: YieldLaw::Saturating,
    };
    expect_exactly(&scn, &SEEDS);
}

#[test]
fn finds_nothing_with_an_s_shaped_yield_curve() {
    let scn = Scenario {
        name: "null, S-shaped yield".into(),
        hidden: vec![],
        yield_law: YieldLaw::SShaped,
    };
    expect_exactly(&scn, &SEEDS);
}

#[test]
fn finds_both_gas_spring_and_thermal_softening() {
    let scn = Scenario {
        name: "gas + thermal".into(),
        hidden: vec![Effect::GasSpring, Effect::ThermalSoftening],
        yield_law: YieldLaw::Saturating,
    };
    expect_exactly(&scn, &SEEDS[..2]);
}
