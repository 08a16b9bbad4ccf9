//! The detection limits of `diagnose::limits` against the decisions they predict: on a
//! null recording (twin's two-chamber model with its own formulations, diagnose::study),
//! an effect added at three times its stated limit is found, and at a third of it is not;
//! a friction step without presliding is stated as absorbed by the fluid's yield force.
//! The limit comes from the final model's linearisation; the decisions from the whole
//! nonlinear selection with its bootstrap, so the two can disagree.

use diagnose::report::DetectionLimit;
use diagnose::study::{generate, Scenario, YieldLaw};
use diagnose::{diagnose, Diagnosis, Options};

fn null() -> diagnose::Signals {
    let scn = Scenario {
        name: "null".into(),
        hidden: vec![],
        yield_law: YieldLaw::Saturating,
    };
    generate(&scn, 1000).0
}

fn run(sig: &diagnose::Signals) -> Diagnosis {
    diagnose(sig, "limits", &Options::default()).expect("generated data are valid")
}

/// The detection-limit row of `effect` that states a limit (`with_limit`) or none (a
/// friction's step without presliding).
fn row<'a>(dg: &'a Diagnosis, effect: &str, with_limit: bool) -> &'a DetectionLimit {
    dg.report
        .detection_limits
        .iter()
        .find(|l| l.effect == effect && l.limit.is_some() == with_limit)
        .unwrap_or_else(|| panic!("no such row for {effect}: {:?}", dg.report.detection_limits))
}

/// The stated limit of `effect` in SI units, and its force RMS \[N\].
fn limit(dg: &Diagnosis, effect: &str, to_si: f64) -> (f64, f64) {
    let l = row(dg, effect, true);
    (
        l.limit.expect("separable on this record") * to_si,
        l.effect_rms_n.expect("separable"),
    )
}

/// Adds `k x` (gas) or `m a` (inertia, a from the exact programme's velocity) and reports
/// whether `effect` was found.
fn found_with(sig: &diagnose::Signals, effect: &str, size: f64) -> bool {
    let mut s = sig.clone();
    let n = s.force_n.len();
    for j in 0..n {
        let add = match effect {
            "gas_spring" => size * s.displacement_m[j],
            _ => {
                let (a, b) = (j.saturating_sub(1), (j + 1).min(n - 1));
                let acc = (s.velocity_m_s[b] - s.velocity_m_s[a]) / (s.time_s[b] - s.time_s[a]);
                size * acc
            }
        };
        s.force_n[j] += add;
    }
    run(&s).found().iter().any(|f| f == effect)
}

#[test]
fn effects_above_their_stated_limit_are_found_and_below_it_are_not() {
    let sig = null();
    let base = run(&sig);
    assert!(base.found().is_empty(), "{:?}", base.found());
    // Every library effect has a row; a friction twice (with presliding, and as a step).
    let effects: Vec<&str> = base
        .report
        .detection_limits
        .iter()
        .map(|l| l.effect.as_str())
        .collect();
    assert_eq!(effects.len(), 7, "{effects:?}");
    for (effect, to_si) in [("gas_spring", 1e3), ("fluid_inertia", 1.0)] {
        let (size, rms) = limit(&base, effect, to_si);
        // A limit of a fraction of the noise to a few noise units: an effect 100 times
        // the noise would be a broken limit, one of 10⁻³ a limit of nothing.
        assert!(
            (0.01..3.0).contains(&(rms / diagnose::study::NOISE_N)),
            "{effect}: limit {size} SI, force RMS {rms} N"
        );
        assert!(
            found_with(&sig, effect, 3.0 * size),
            "{effect} at 3× its limit {size}"
        );
        assert!(
            !found_with(&sig, effect, size / 3.0),
            "{effect} at ⅓ of its limit {size}"
        );
    }
}

#[test]
fn a_friction_step_without_presliding_is_stated_as_the_fluids_yield() {
    let base = run(&null());
    let step = row(&base, "seal_friction", false);
    // A current-independent step is a common offset of every knot's yield force.
    assert!(step.absorbed_share > 0.95, "{step:?}");
    assert!(step.rule.contains("never reported"), "{step:?}");
    // The Dahl friction's presliding leaves more for the record to see.
    let dahl = row(&base, "seal_friction", true);
    assert!(
        dahl.absorbed_share < step.absorbed_share,
        "{dahl:?} {step:?}"
    );
}
