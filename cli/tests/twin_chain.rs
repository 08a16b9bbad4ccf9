//! The closed loop of issue 12, end to end through the binary: `mrtwin fit` →
//! `mrtwin diagnose --params --write-params` → `mrtwin replay` of both twins, on simulated
//! records, on an independent proving-ground record and on real ones (UTFSM, Dyke), and the
//! refusals (files, identifiability).

use std::path::{Path, PathBuf};
use std::process::Output;

use mrtwin_tests::{
    csv_column, entry_of, fitted_parameter, generate_scenario, read_json, rms_finite, succeeded,
    TempDir,
};
use node::config::{TwinNodeParams, TWIN_NODE};

fn mrtwin<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Output {
    mrtwin_tests::run(env!("CARGO_BIN_EXE_mrtwin"), args)
}

fn p(path: &Path) -> String {
    path.display().to_string()
}

/// Replay RMS residual of `params` on `rec`.
fn replay_rms(dir: &Path, rec: &Path, params: &Path, tag: &str) -> f64 {
    let out = dir.join(format!("replay-{tag}.csv"));
    succeeded(
        mrtwin(&["replay", &p(rec), "--params", &p(params), "--out", &p(&out)]),
        "replay",
    );
    rms_finite(&csv_column(&out, "residual_N"))
}

struct Chain {
    twin: PathBuf,
    upgraded: PathBuf,
    json: serde_json::Value,
    twin_rms: f64,
    upgraded_rms: f64,
    /// Over every sample where both are finite: (the upgraded twin's replay, diagnose's
    /// final model from its `--residuals`) RMS residual \[N\].
    same_samples: (f64, f64),
}

fn chain(dir: &Path, rec: &Path) -> Chain {
    let twin = dir.join("twin.yaml");
    let upgraded = dir.join("upgraded.yaml");
    let js = dir.join("d.json");
    succeeded(mrtwin(&["fit", &p(rec), "--out", &p(&twin)]), "fit");
    succeeded(
        mrtwin(&[
            "diagnose",
            &p(rec),
            "--params",
            &p(&twin),
            "--write-params",
            &p(&upgraded),
            "--json",
            &p(&js),
            "--report",
            &p(&dir.join("d.md")),
            "--residuals",
            &p(&dir.join("residuals.csv")),
        ]),
        "diagnose --params",
    );
    let json = read_json(&js);
    let twin_rms = replay_rms(dir, rec, &twin, "twin");
    let upgraded_rms = replay_rms(dir, rec, &upgraded, "upgraded");
    let diagnose_final = {
        let res = dir.join("residuals.csv");
        let (f, m) = (csv_column(&res, "force_N"), csv_column(&res, "final_N"));
        f.iter().zip(&m).map(|(f, m)| f - m).collect::<Vec<_>>()
    };
    let replayed = csv_column(&dir.join("replay-upgraded.csv"), "residual_N");
    assert_eq!(
        diagnose_final.len(),
        replayed.len(),
        "one row per sample in both"
    );
    let both = |e: &[f64], other: &[f64]| {
        let kept: Vec<f64> = e
            .iter()
            .zip(other)
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .map(|(a, _)| *a)
            .collect();
        rms_finite(&kept)
    };
    let same_samples = (
        both(&replayed, &diagnose_final),
        both(&diagnose_final, &replayed),
    );
    Chain {
        twin,
        upgraded,
        json,
        twin_rms,
        upgraded_rms,
        same_samples,
    }
}

/// Issue 12's goal on a record: the upgraded twin replays at least as well as diagnose's
/// final model predicts its held-out blocks. Both plain RMS figures: the replay's residual
/// is unweighted, and so is `holdout_rmse_unweighted_N` (diagnose's headline figure is
/// weighted by how predictable each sample's force is under the velocity error, which
/// since its nineteenth pass discounts reversal samples by the error the record shows —
/// UTFSM 2mm5Hz: 65.2 N weighted, 77.6 N plain; 68.5 and 68.6 N before). And over the same
/// samples, the replay against diagnose's final model on every sample, within
/// [`SAME_SAMPLES_TOLERANCE`]: the two are different formulations of the same effects (the
/// twin's force from the measured velocity, diagnose's the expected force under the
/// velocity error), each at its own optimum.
fn assert_upgrade_at_least_as_good_as_diagnoses_final(c: &Chain) {
    assert_upgrade_within_of_diagnoses_final(c, SAME_SAMPLES_TOLERANCE);
}

/// [`assert_upgrade_at_least_as_good_as_diagnoses_final`] with the upgraded twin allowed
/// `tolerance` (a share) above diagnose's final model over the same samples.
fn assert_upgrade_within_of_diagnoses_final(c: &Chain, tolerance: f64) {
    let (twin, final_model) = c.same_samples;
    assert!(
        twin <= final_model * (1.0 + tolerance),
        "over the same samples: upgraded twin {twin} N against diagnose's final {final_model} N"
    );
    let final_holdout = c.json["final"]["holdout_rmse_unweighted_N"]
        .as_f64()
        .unwrap();
    assert!(
        c.upgraded_rms <= final_holdout,
        "upgraded twin {} N against diagnose's final {final_holdout} N",
        c.upgraded_rms
    );
}

/// How much worse than diagnose's final model, over the same samples, the upgraded twin may
/// replay: 0.1 %. The twin is fitted on every sample, diagnose's final on the training
/// blocks; since diagnose's final model is refitted at the optimum its last round showed
/// (session 72), on UTFSM 25mm0x5Hz it fits the record's samples 0.015 % better than the
/// twin's converged fit (53.310 against 53.318 N; 53.3 N is 0.51 of the twin's 103.8 N).
const SAME_SAMPLES_TOLERANCE: f64 = 1e-3;

fn found(c: &Chain) -> Vec<String> {
    c.json["findings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["effect"].as_str().unwrap().to_string())
        .collect()
}

fn load(path: &Path) -> TwinNodeParams {
    launch_config::load_params(path, TWIN_NODE).unwrap()
}

fn simulate(dir: &Path, name: &str, effects: &str, extra: &[&str], seed: u64) -> PathBuf {
    let out = dir.join(name);
    let seed = seed.to_string();
    let mut args = vec![
        "simulate",
        "--model",
        "two-chamber",
        "--effects",
        effects,
        "--noise",
        "0.005",
        "--seed",
        &seed,
        "--out",
    ];
    let o = p(&out);
    args.push(&o);
    args.extend_from_slice(extra);
    succeeded(mrtwin(&args), "simulate");
    out
}

#[test]
fn on_a_record_with_nothing_missing_the_upgrade_is_the_fitted_twin_at_the_noise_floor() {
    let dir = TempDir::new("chain-null");
    let rec = simulate(&dir.path(""), "null.csv", "none", &[], 3);
    let c = chain(&dir.path(""), &rec);
    assert!(found(&c).is_empty(), "found {:?}", found(&c));
    let (twin, up) = (load(&c.twin), load(&c.upgraded));
    assert_eq!(twin.model_params(), up.model_params());
    assert_eq!(
        twin.model.effects(twin.effects),
        up.model.effects(up.effects)
    );
    assert_eq!(c.twin_rms, c.upgraded_rms);
    // The fit tried a pre-yield leak and, the simulated fluid having none, did not keep it.
    assert_eq!(twin.two_chamber.fluid.pre_yield_leak, 0.0);
    // The noise of `simulate --noise 0.005`: 0.5 % of the peak |F| of the noiseless force.
    let force = csv_column(&rec, "force_N");
    let sigma = 0.005 * force.iter().fold(0.0f64, |m, f| m.max(f.abs()));
    assert!(
        (c.twin_rms / sigma - 1.0).abs() < 0.1,
        "replay RMS {} against the noise σ ≈ {sigma}",
        c.twin_rms
    );
    // The fit started far away (default τ_y) yet the twin file is what replay reproduces.
    let reported = c.json["twin"]["replay_rmse_N"].as_f64().unwrap();
    assert!((reported - c.twin_rms).abs() < 1e-6 * c.twin_rms);
}

#[test]
fn a_hidden_gas_spring_reaches_the_twin_and_replay_confirms_the_claimed_gain() {
    let dir = TempDir::new("chain-gas");
    let rec = simulate(
        &dir.path(""),
        "gas.csv",
        "gas_spring",
        &["--gas-preload", "4.0e6"],
        4,
    );
    let c = chain(&dir.path(""), &rec);
    assert!(
        found(&c).contains(&"gas_spring".to_string()),
        "{:?}",
        found(&c)
    );
    let up = load(&c.upgraded);
    assert!(up.model.effects(up.effects).has(twin::Effect::GasSpring));
    assert!(
        c.upgraded_rms < c.twin_rms,
        "{} → {}",
        c.twin_rms,
        c.upgraded_rms
    );
    let claim = c.json["twin"]["predicted_replay_ratio"].as_f64().unwrap();
    let ratio = c.upgraded_rms / c.twin_rms;
    assert!(
        (ratio - claim).abs() <= 0.15,
        "replay ratio {ratio} against diagnose's {claim}"
    );
    // The stand and the simulator take the upgraded file as it is.
    succeeded(
        mrtwin(&[
            "simulate",
            "--model",
            "two-chamber",
            "--effects",
            "gas_spring",
            "--params",
            &p(&c.upgraded),
            "--duration",
            "0.5",
            "--out",
            &p(&dir.path("").join("again.csv")),
        ]),
        "simulate --params upgraded",
    );
}

fn real_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/real")
}

/// UTFSM test `stem`, five currents concatenated (as scripts/diagnose-real.py does).
fn utfsm(stem: &str, out: &Path) {
    let mut text = String::from("time_s,displacement_m,velocity_m_s,force_N,current_A\n");
    let mut t_end = 0.0;
    for (tag, amps) in [
        ("0A", 0.0),
        ("0x25A", 0.25),
        ("0x5A", 0.5),
        ("0x75A", 0.75),
        ("1A", 1.0),
    ] {
        let path = real_dir().join(format!("maurel-utfsm/preprocessed/{stem}{tag}.txt"));
        let rows: Vec<Vec<f64>> = std::fs::read_to_string(&path)
            .unwrap()
            .lines()
            .filter(|l| !l.trim().is_empty())
            .map(|l| l.split_whitespace().map(|x| x.parse().unwrap()).collect())
            .collect();
        let (t0, dt) = (rows[0][0], rows[1][0] - rows[0][0]);
        let mut last = t_end;
        for r in &rows {
            last = t_end + r[0] - t0;
            text.push_str(&format!(
                "{last:.6},{},{},{},{amps}\n",
                r[1] * 1e-3,
                r[2] * 1e-3,
                r[3]
            ));
        }
        t_end = last + dt;
    }
    std::fs::write(out, text).unwrap();
}

#[test]
fn real_records_upgrade_the_twin_where_diagnose_finds_something() {
    let dir = TempDir::new("chain-real");
    let rec = &dir.path("").join("utfsm-2mm5Hz.csv");
    utfsm("2mm5Hz", rec);
    let c = chain(&dir.path(""), rec);
    assert!(
        !found(&c).is_empty(),
        "the UTFSM record's compliance is large"
    );
    assert!(
        c.upgraded_rms < 0.8 * c.twin_rms,
        "{} → {}",
        c.twin_rms,
        c.upgraded_rms
    );
    // Issue 12's goal on this record: the upgraded twin replays at least as well as
    // diagnose's final model predicts its held-out blocks (63.6 against 64.2 N plain since
    // session 87, 77.6 N before; 68.4 N with quadratics; 73.2 N before the twin had a
    // pre-yield leak, which the upgrade tried and kept). Over the same samples it no longer
    // matches diagnose's final model: since session 87 that model is refitted in the
    // relative-leak basin once the compressibility is in (diagnose::model::
    // relative_leak_basin), 57.0 N there, and the twin's laws (quartics in current, no
    // speed curvature per knot) replay at 63.6 N from either leak start the upgrade tries
    // (the twin's own 0.26 and diagnose's 0.14 end at 67.89 and 67.91 N held out).
    assert_upgrade_within_of_diagnoses_final(&c, 0.12);
    assert!(load(&c.upgraded).two_chamber.fluid.pre_yield_leak > 0.0);
    // and its replay ratio is the one diagnose claimed for its own models (0.392 against
    // 0.392 with quartic laws, 0.417 against 0.346 with quadratics).
    let claimed = c.json["twin"]["diagnose_holdout_ratio"].as_f64().unwrap();
    let ratio = c.upgraded_rms / c.twin_rms;
    assert!(
        (ratio - claimed).abs() <= 0.15,
        "replay ratio {ratio} against diagnose's {claimed}"
    );
    let dyke = real_dir().join("dyke-nees/ransim_u.csv");
    let d = TempDir::new("chain-dyke");
    let c = chain(&d.path(""), &dyke);
    // Its command voltage holds five levels, but the quartic τ_y fell as the command rose
    // (29 → 10 kPa between 0.4 and 1.2 V): the fit keeps quadratics.
    let fluid = load(&c.twin).two_chamber.fluid;
    assert_eq!(
        fluid.yield_stress_pa.len(),
        3,
        "{:?}",
        fluid.yield_stress_pa
    );
    assert_eq!(fluid.current_range_a, 0.0);
    let claim = c.json["twin"]["predicted_replay_ratio"].as_f64().unwrap();
    let ratio = c.upgraded_rms / c.twin_rms;
    assert!(
        ratio <= 1.0 + 1e-9,
        "an upgrade must not replay worse: {ratio}"
    );
    assert!((ratio - claim).abs() <= 0.15, "{ratio} against {claim}");
    // Since session 62 diagnose finds the command's field lag and a seal friction here, and
    // the upgraded twin replays the record better (337.1 against 381.2 N, 0.884).
    assert!(ratio < 0.95, "Dyke's upgrade gains little: {ratio}");
}

/// UTFSM 25mm0x5Hz, five held currents: the twin's laws in current are quartics through
/// them (five coefficients, held above the records' peak current), and the upgraded twin
/// replays at least as well as diagnose's final model, over the same samples too (53.3
/// against 53.5 N; with quadratics it was 56.3 N and the goal failed on this record).
/// The fitted twin with the fourth and fifth coefficients held at 0 (a quadratic)
/// replays worse than the quartic one (105.4 against 103.8 N).
#[test]
fn five_current_levels_give_the_twin_quartic_laws_and_the_upgrade_matches_diagnose() {
    let dir = TempDir::new("chain-quartic");
    let rec = &dir.path("").join("utfsm-25mm0x5Hz.csv");
    utfsm("25mm0x5Hz", rec);
    let c = chain(&dir.path(""), rec);
    let fluid = load(&c.twin).two_chamber.fluid;
    assert_eq!(
        fluid.yield_stress_pa.len(),
        5,
        "{:?}",
        fluid.yield_stress_pa
    );
    assert_eq!(fluid.viscosity_pa_s.len(), 5, "{:?}", fluid.viscosity_pa_s);
    assert!(
        (fluid.current_range_a - 1.0).abs() < 1e-9,
        "{}",
        fluid.current_range_a
    );
    assert_eq!(
        load(&c.upgraded).two_chamber.fluid.yield_stress_pa.len(),
        5,
        "the upgrade keeps the quartic"
    );
    assert_upgrade_at_least_as_good_as_diagnoses_final(&c);
    let quadratic = dir.path("").join("quadratic.yaml");
    let hold = [
        "two_chamber.fluid.yield_stress_pa[3]",
        "two_chamber.fluid.yield_stress_pa[4]",
        "two_chamber.fluid.viscosity_pa_s[3]",
        "two_chamber.fluid.viscosity_pa_s[4]",
    ]
    .join(",");
    succeeded(
        mrtwin(&["fit", &p(rec), "--out", &p(&quadratic), "--hold", &hold]),
        "fit with a quadratic",
    );
    let held = load(&quadratic).two_chamber.fluid;
    assert_eq!(held.yield_stress_pa.len(), 3, "{:?}", held.yield_stress_pa);
    assert_eq!(held.current_range_a, 0.0, "no range for a quadratic");
    let quadratic_rms = replay_rms(&dir.path(""), rec, &quadratic, "quadratic");
    assert!(
        c.twin_rms < quadratic_rms - 0.5,
        "quartic {} N, quadratic {quadratic_rms} N",
        c.twin_rms
    );
}

/// `mrtwin fit --model spencer` on UTFSM 2mm5Hz, a damper that is not Spencer's: the
/// modified Bouc–Wen law has more parameters than the record pins down, so the fit holds
/// those it cannot tell apart where its iterations left them and says which; the file it
/// writes replays at the RMS it reports. Its hysteresis follows this record's loops far
/// better than the two-chamber slit law without effects does (held-out 74.8 against
/// 173.3 N).
#[test]
fn a_spencer_twin_is_fitted_to_a_real_record_holding_what_it_cannot_tell_apart() {
    let dir = TempDir::new("fit-spencer");
    let rec = &dir.path("utfsm-2mm5Hz.csv");
    utfsm("2mm5Hz", rec);
    let (twin, js) = (dir.path("spencer.yaml"), dir.path("spencer.json"));
    succeeded(
        mrtwin(&[
            "fit",
            &p(rec),
            "--model",
            "spencer",
            "--out",
            &p(&twin),
            "--json",
            &p(&js),
        ]),
        "fit --model spencer",
    );
    let report = read_json(&js);
    let notes: Vec<&str> = report["identifiable"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|n| n.as_str())
        .collect();
    // "spencer.k0 held at 4.690000e3, where the iterations left it: ..."
    let held: Vec<(&str, f64)> = notes
        .iter()
        .filter_map(|n| n.split_once(" held at "))
        .filter_map(|(key, rest)| Some((key, rest.split_once(',')?.0.parse().ok()?)))
        .collect();
    assert!(!held.is_empty(), "{notes:?}");
    let fitted = load(&twin);
    assert_eq!(fitted.model, twin::models::ModelKind::Spencer);
    // The file holds them at the values the notes give.
    let written = serde_json::to_value(&fitted.spencer).unwrap();
    for (key, value) in &held {
        assert!(fitted_parameter(&report, key).is_none(), "{key} is held");
        let name = key.strip_prefix("spencer.").unwrap();
        let v = written[name].as_f64().unwrap();
        assert!(
            (v - value).abs() <= 1e-6 * value.abs(),
            "{key}: {v} against {value}"
        );
    }
    assert!(fitted_parameter(&report, "spencer.c1b").is_some());
    // The file replays at the RMS the fit reports: the same pipeline.
    let replayed = replay_rms(&dir.path(""), rec, &twin, "spencer");
    let reported = report["rmse_n"].as_f64().unwrap();
    assert!(
        (replayed - reported).abs() < 1e-6 * reported,
        "{replayed} vs {reported}"
    );
    // Better on the unseen blocks than the two-chamber slit law fitted the same way.
    let two_chamber_js = dir.path("two-chamber.json");
    succeeded(
        mrtwin(&[
            "fit",
            &p(rec),
            "--out",
            &p(&dir.path("two-chamber.yaml")),
            "--json",
            &p(&two_chamber_js),
        ]),
        "fit",
    );
    let held_out = |j: &serde_json::Value| j["holdout"]["fitted_rmse_n"].as_f64().unwrap();
    let (spencer, slit) = (held_out(&report), held_out(&read_json(&two_chamber_js)));
    assert!(spencer < 0.6 * slit, "held-out {spencer} against {slit} N");
    // The stand reads the file as is.
    succeeded(
        mrtwin(&[
            "simulate",
            "--model",
            "spencer",
            "--params",
            &p(&twin),
            "--duration",
            "0.5",
            "--out",
            &p(&dir.path("sim.csv")),
        ]),
        "simulate --params",
    );
}

/// UTFSM 25mm0x5Hz: diagnose's final model carries a step at reversal that follows the
/// yield force (its `fluid_shape`, not a finding). The upgrade carries it into the twin as
/// `fluid.yield_step_share` with its width fitted, and the upgraded twin replays at least
/// as well as diagnose's final model predicts its held-out blocks (53.3 against 57.9 N,
/// plain RMS). The same twin refitted without the step stays far above (70.6 N): the step,
/// not the refit, closes the gap. (Until session 90 this was UTFSM 5mm3Hz, whose step
/// follows the viscous coefficient once the candidates' fits converge.)
#[test]
fn the_fluids_yield_step_that_diagnose_carries_reaches_the_twin() {
    let dir = TempDir::new("chain-yield-step");
    let rec = &dir.path("").join("utfsm-25mm0x5Hz.csv");
    utfsm("25mm0x5Hz", rec);
    let c = chain(&dir.path(""), rec);
    let shape = c.json["fluid_shape"].as_array().unwrap();
    assert!(
        shape.iter().any(|s| s["follows"] == "yield_force"),
        "no yield-scaled step in diagnose's fluid shape: {shape:?}"
    );
    let upgrade = &c.json["twin"]["upgraded"];
    assert_eq!(upgrade["yield_step_added"], true);
    let up = load(&c.upgraded);
    let fluid = &up.two_chamber.fluid;
    assert!(fluid.yield_step_share > 0.0, "{}", fluid.yield_step_share);
    // Its width is fitted, away from where the fit started it.
    let start = upgrade["fit"]["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .find(|q| q["key"] == "two_chamber.fluid.yield_step_velocity_m_s")
        .and_then(|q| q["start"].as_f64())
        .expect("the step's width among the fitted parameters");
    assert!(
        (fluid.yield_step_velocity_m_s / start - 1.0).abs() > 0.05,
        "width {} not moved from its start {start}",
        fluid.yield_step_velocity_m_s
    );
    assert_upgrade_at_least_as_good_as_diagnoses_final(&c);
    // Without the step: the upgraded file with the share at 0, refitted.
    let text = std::fs::read_to_string(&c.upgraded).unwrap();
    let without = dir.path("").join("no-step.yaml");
    let share = format!("yield_step_share: {}", fluid.yield_step_share);
    assert!(text.contains(&share), "{share} not in the upgraded file");
    std::fs::write(&without, text.replace(&share, "yield_step_share: 0.0")).unwrap();
    let refit = dir.path("").join("no-step-fitted.yaml");
    succeeded(
        mrtwin(&[
            "fit",
            &p(rec),
            "--params",
            &p(&without),
            "--out",
            &p(&refit),
        ]),
        "fit without the step",
    );
    let no_step = replay_rms(&dir.path(""), rec, &refit, "no-step");
    assert!(
        no_step > 1.2 * c.upgraded_rms,
        "without the step {no_step} N, with it {} N",
        c.upgraded_rms
    );
}

/// UTFSM 5mm3Hz: diagnose's step at reversal follows the viscous coefficient (since the
/// candidates' Jacobian carries a held yield softness, issue 10 session 90), a shape the
/// twin has no counterpart for. The upgrade tries the twin's yield step as the nearest one,
/// from the same step height at diagnose's mean yield force, and keeps it because the
/// upgraded twin predicts its held-out blocks better with it (41.8 against 76.1 N); the
/// upgraded twin then replays at least as well as diagnose's final model predicts its
/// held-out blocks (38.1 against 46.9 N; 64.6 N without the step).
#[test]
fn a_step_that_follows_the_viscosity_reaches_the_twin_as_its_nearest_yield_step() {
    let dir = TempDir::new("chain-nearest-step");
    let rec = &dir.path("").join("utfsm-5mm3Hz.csv");
    utfsm("5mm3Hz", rec);
    let c = chain(&dir.path(""), rec);
    let shape = c.json["fluid_shape"].as_array().unwrap();
    assert!(
        shape.iter().all(|s| s["follows"] == "viscous_coefficient") && !shape.is_empty(),
        "diagnose's fluid shape changed: {shape:?}"
    );
    let upgrade = &c.json["twin"]["upgraded"];
    assert_eq!(upgrade["yield_step_added"], true);
    let nearest = &upgrade["nearest_yield_step"];
    let (with, without) = (
        nearest["holdout_rmse_n_with"].as_f64().unwrap(),
        nearest["holdout_rmse_n_without"].as_f64().unwrap(),
    );
    assert!(
        with < without,
        "held-out {with} N with the step, {without} N without"
    );
    assert!(
        c.json["twin"]["fluid_shape_not_carried"]
            .as_array()
            .unwrap()
            .is_empty(),
        "{}",
        c.json["twin"]
    );
    assert!(load(&c.upgraded).two_chamber.fluid.yield_step_share > 0.0);
    assert_upgrade_at_least_as_good_as_diagnoses_final(&c);
}

/// A two-chamber record simulated with `fluid_line` in the stand's fluid section (plus
/// `extra` flags to `simulate`), then `mrtwin fit` on it with its JSON report.
struct FitSimulated {
    rec: PathBuf,
    twin: PathBuf,
    report: serde_json::Value,
}

fn fit_simulated(dir: &Path, fluid_line: &str, extra: &[&str], seed: u64) -> FitSimulated {
    let stand = dir.join("stand.yaml");
    std::fs::write(
        &stand,
        format!(
            "mrtwin_stand:\n  ros__parameters:\n    model: two-chamber\n    effects: none\n    \
             two_chamber:\n      fluid:\n        {fluid_line}\n"
        ),
    )
    .unwrap();
    let stand = p(&stand);
    let mut flags = vec!["--params", stand.as_str()];
    flags.extend_from_slice(extra);
    let rec = simulate(dir, "simulated.csv", "none", &flags, seed);
    let (twin, js) = (dir.join("twin.yaml"), dir.join("fit.json"));
    succeeded(
        mrtwin(&["fit", &p(&rec), "--out", &p(&twin), "--json", &p(&js)]),
        "fit",
    );
    FitSimulated {
        rec,
        twin,
        report: read_json(&js),
    }
}

/// Four current levels make the laws in current cubics; a record whose yield stress falls
/// between 0.25 and 0.5 A (20 → 12 kPa, not an MR fluid's law, made so the fitted cubic
/// falls) gets quadratics instead, said in the report, and no range: the fallback holds
/// only the coefficients the records made free (a cubic has no `[4]`).
#[test]
fn a_fitted_law_that_falls_with_current_falls_back_to_a_quadratic() {
    let dir = TempDir::new("chain-falling-law");
    let fitted = fit_simulated(
        &dir.path(""),
        "yield_stress_pa: [78000.0, -370666.7, 632000.0, -309333.3]",
        &["--current", "0.25,0.5,0.75,1.0"],
        8,
    );
    let (twin, notes) = (fitted.twin, fitted.report["identifiable"].clone());
    assert!(
        notes
            .as_array()
            .unwrap()
            .iter()
            .any(|n| n.as_str().unwrap().contains("fitted as quadratics instead")),
        "{notes:#}"
    );
    let fluid = load(&twin).two_chamber.fluid;
    assert_eq!(
        fluid.yield_stress_pa.len(),
        3,
        "{:?}",
        fluid.yield_stress_pa
    );
    assert_eq!(fluid.viscosity_pa_s.len(), 3, "{:?}", fluid.viscosity_pa_s);
    assert_eq!(fluid.current_range_a, 0.0);
}

#[test]
fn a_pre_yield_leak_in_the_record_is_tried_kept_and_recovered_by_the_fit() {
    let dir = TempDir::new("chain-leak");
    let truth = 0.04;
    let FitSimulated { rec, twin, report } =
        fit_simulated(&dir.path(""), &format!("pre_yield_leak: {truth}"), &[], 6);
    let leak = fitted_parameter(&report, "two_chamber.fluid.pre_yield_leak")
        .unwrap_or_else(|| panic!("no leak fitted: {:#}", report["identifiable"]));
    let (value, se) = (
        leak["value"].as_f64().unwrap(),
        leak["std_error"].as_f64().unwrap(),
    );
    assert!(
        (value - truth).abs() <= 3.0 * se + 0.05 * truth,
        "λ {value} ± {se} against {truth}"
    );
    assert!(
        report["identifiable"]
            .as_array()
            .unwrap()
            .iter()
            .any(|n| n.as_str().unwrap().contains("tried and kept")),
        "{:#}",
        report["identifiable"]
    );
    assert_eq!(load(&twin).two_chamber.fluid.pre_yield_leak, value);
    // Held, the leak is not tried and the twin keeps none.
    succeeded(
        mrtwin(&[
            "fit",
            &p(&rec),
            "--hold",
            "two_chamber.fluid.pre_yield_leak",
            "--out",
            &p(&twin),
        ]),
        "fit --hold leak",
    );
    assert_eq!(load(&twin).two_chamber.fluid.pre_yield_leak, 0.0);
}

#[test]
fn bad_files_and_unidentifiable_fits_are_refused_and_nothing_is_written() {
    let dir = TempDir::new("chain-bad");
    let rec = simulate(&dir.path(""), "one.csv", "none", &["--current", "0.8"], 5);
    // Field lag on a record whose current never changes: its time constant moves nothing.
    let out = &dir.path("").join("lag.yaml");
    let o = mrtwin(&["fit", &p(&rec), "--effects", "field_lag", "--out", &p(out)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("not identifiable") && err.contains("field_time_constant_s"),
        "{err}"
    );
    assert!(!out.exists() && !out.with_extension("yaml.partial").exists());
    // Holding it, as the refusal advises, the fit goes through and keeps its base value.
    succeeded(
        mrtwin(&[
            "fit",
            &p(&rec),
            "--effects",
            "field_lag",
            "--hold",
            "two_chamber.field_time_constant_s",
            "--out",
            &p(out),
        ]),
        "fit --hold",
    );
    let held = load(out);
    assert_eq!(
        held.two_chamber.field_time_constant_s,
        TwinNodeParams::default().two_chamber.field_time_constant_s
    );
    let o = mrtwin(&["fit", &p(&rec), "--hold", "no_such_key", "--out", &p(out)]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--hold no_such_key"));
    // A twin file with a misspelt key: file, key and line.
    let bad = &dir.path("").join("bad.yaml");
    std::fs::write(
        bad,
        "mrtwin_twin:\n  ros__parameters:\n    model: two-chamber\n    two_chamber:\n      bulk_modulus: 1.0e9\n",
    )
    .unwrap();
    let up = &dir.path("").join("up.yaml");
    let o = mrtwin(&[
        "diagnose",
        &p(&rec),
        "--params",
        &p(bad),
        "--write-params",
        &p(up),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("bad.yaml") && err.contains("line 5") && err.contains("bulk_modulus"),
        "{err}"
    );
    assert!(!up.exists());
}

/// The closed loop on an independent record whose velocity a rig measured with noise
/// (proving-ground seed 433: 5 kHz, a velocity sensor with 1.5 % noise, a 78 kg moving
/// mass and a thermal softening hidden). diagnose finds the mass, and the upgraded twin
/// takes it as the rig's moving mass beside its gap fluid's (`moving_mass_kg`, fitted at
/// 76.5 kg; it was once a fluid density of 5.3·10⁵ kg/m³), whose acceleration the node
/// reads as the least-squares slope of the last 5 ms of velocity
/// (node::conditioning::AccelerationEstimator). With the difference of two samples the
/// twin's `m a` was mostly noise: it replayed at 80.9 N against the fitted twin's 81.6 N.
/// Now 40.6 N.
#[test]
fn the_upgraded_twin_uses_the_mass_diagnose_finds_behind_a_noisy_velocity() {
    let dir = TempDir::new("chain-pg-433");
    let (rec, meta) = generate_scenario(&dir, 433, false);
    let meta = read_json(&meta);
    assert_eq!(
        meta["measurement"]["velocity"], "sensor",
        "the scenario changed"
    );
    let c = chain(&dir.path(""), &rec);
    assert!(
        found(&c).contains(&"fluid_inertia".to_string()),
        "diagnose no longer finds the mass ({:?}): this test no longer tests the twin's use of it",
        found(&c)
    );
    // The generator's inertia: its rod's moving mass and its gap fluid's.
    let generated = &entry_of(&meta["effects"], "fluid_inertia")["parameters"];
    let generated_mass = generated["moving_mass_kg"].as_f64().unwrap()
        + generated["gap_fluid_mass_kg"].as_f64().unwrap();
    let (twin, up) = (load(&c.twin), load(&c.upgraded));
    let tc = &up.two_chamber;
    assert_eq!(
        tc.fluid_density_kg_m3, twin.two_chamber.fluid_density_kg_m3,
        "the fluid keeps its density"
    );
    assert!(
        (tc.inertial_mass_kg() / generated_mass - 1.0).abs() < 0.05,
        "the twin's inertia {} kg (moving {} kg) against the generated {generated_mass} kg",
        tc.inertial_mass_kg(),
        tc.moving_mass_kg
    );
    eprintln!("replay RMS {:.2} → {:.2} N", c.twin_rms, c.upgraded_rms);
    assert!(
        c.upgraded_rms < 0.6 * c.twin_rms,
        "replay RMS {} → {} N",
        c.twin_rms,
        c.upgraded_rms
    );
}
