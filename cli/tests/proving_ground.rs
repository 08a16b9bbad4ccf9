//! The fast slice of the proving ground: `scripts/proving_ground/study.py --quick` runs
//! `mrtwin diagnose` on eight fixed scenarios of the independent Python simulator (its
//! own slit-flow laws, chambers, gas, friction, lag, heat and rig-like measurement chain;
//! no code shared with `twin` or `diagnose`) and scores the result against the hidden
//! truth. The full 300-scenario study and its figures are in BENCHMARKS.md.

use std::time::Duration;

use mrtwin_tests::{
    entry_of, generate_scenario, read_json, repo_root, run, run_python, succeeded, TempDir,
    RUN_FILE,
};

/// The simulator's own physics checks (`check_generator.py --quick`): slit-flow limits and
/// closed forms, compressible chambers tending to the incompressible force as K → ∞ (the
/// reversal step's sampling stated on the record), the blocked gap's stiffness K A1²/V1,
/// positive dissipation, a conservative gas spring, fine-grid convergence, the null twin,
/// and effect sizes on target wherever the sizing's bounds allow. The proving ground is
/// only as independent as it is right.
#[test]
fn the_independent_simulators_physics_checks_pass() {
    let script = repo_root().join("scripts/proving_ground/check_generator.py");
    let stdout = run_python(
        RUN_FILE,
        &[script.to_str().unwrap(), "--quick"],
        Duration::from_secs(600),
    );
    eprintln!("{stdout}");
    let checks = stdout.lines().filter(|l| l.starts_with("[ok]")).count();
    assert!(
        !stdout.contains("[FAIL]") && stdout.contains("all checks passed"),
        "a physics check of the simulator failed:\n{stdout}"
    );
    assert!(checks >= 24, "only {checks} checks ran:\n{stdout}");
}

#[test]
fn quick_slice_of_the_independent_proving_ground() {
    let dir = TempDir::new("pg");
    let study = repo_root().join("scripts/proving_ground/study.py");
    let out = dir.path("out");
    let md = dir.path("quick.md");
    let stdout = run_python(
        RUN_FILE,
        &[
            study.to_str().unwrap(),
            "--quick",
            "--jobs",
            "2",
            "--selectors",
            "calibrated",
            "--bin",
            env!("CARGO_BIN_EXE_mrtwin"),
            "--out",
            out.to_str().unwrap(),
            "--markdown",
            md.to_str().unwrap(),
        ],
        Duration::from_secs(900),
    );
    eprintln!("{stdout}");
    let text = std::fs::read_to_string(out.join("results.json")).expect("results.json");
    let j: serde_json::Value = serde_json::from_str(&text).expect("valid JSON");
    let records = j["records"].as_array().unwrap();
    assert_eq!(records.len(), 8, "the quick slice has eight scenarios");
    let (mut exact, mut detected, mut hidden_total, mut false_total) = (0, 0, 0, 0);
    for r in records {
        let run = &r["runs"][0];
        assert_eq!(run["rc"], 0, "seed {}: diagnose failed: {run}", r["seed"]);
        let ids = |k: &str| -> Vec<String> {
            let mut v: Vec<String> = run[k]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_str().unwrap().to_string())
                .collect();
            v.sort();
            v
        };
        let (hidden, found) = (ids("hidden"), ids("findings"));
        if hidden == found && run["undecided"].as_array().unwrap().is_empty() {
            exact += 1;
        }
        detected += hidden.iter().filter(|h| found.contains(h)).count();
        hidden_total += hidden.len();
        false_total += found.iter().filter(|f| !hidden.contains(f)).count();
        eprintln!("seed {}: hidden {hidden:?}, found {found:?}", r["seed"]);
    }
    eprintln!(
        "quick slice: {exact} of 8 exact, {detected} of {hidden_total} hidden effects found, \
         {false_total} false findings"
    );
    // A regression guard on independent data, not the goal (BENCHMARKS.md has the
    // study). When it was written: 1 exact, 5 of 9 found, 5 false findings; since the
    // twelfth pass of issue 10: 8 exact, 9 of 9, none false. The bounds leave room for
    // one record to flip (seed 26's anti-alias filter is on a knife edge).
    assert_eq!(hidden_total, 9, "the slice's scenarios changed");
    assert!(exact >= 6, "only {exact} of 8 records exact");
    assert!(detected >= 8, "only {detected} of 9 hidden effects found");
    assert!(
        false_total <= 1,
        "{false_total} false findings in 8 records"
    );
    check_breakdown(&out, exact, hidden_total);
}

/// `breakdown.py` on the quick slice's directory: every grouping puts each of the eight
/// records in exactly one class, and its classes' exact sets add up to the `exact` counted
/// above from the same results.json (the script's scoring is study.py's, its grouping reads
/// the scenario metas), and its detection table counts each hidden effect once.
fn check_breakdown(out: &std::path::Path, exact: usize, hidden_total: usize) {
    let script = repo_root().join("scripts/proving_ground/breakdown.py");
    let json = out.join("breakdown.json");
    let stdout = run_python(
        RUN_FILE,
        &[
            script.to_str().unwrap(),
            out.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ],
        Duration::from_secs(120),
    );
    eprintln!("{stdout}");
    let b = read_json(&json);
    let table = b["table"].as_object().expect("a table of groupings");
    assert!(table.len() >= 7, "groupings: {:?}", table.keys());
    for (grouping, classes) in table {
        let (mut records, mut exact_sum) = (0, 0);
        for t in classes.as_object().unwrap().values() {
            records += t["records"].as_u64().unwrap();
            exact_sum += t["exact"].as_u64().unwrap();
        }
        assert_eq!(records, 8, "{grouping}: {records} records over its classes");
        assert_eq!(
            exact_sum as usize, exact,
            "{grouping}: exact sets over its classes"
        );
    }
    let hidden_counted: u64 = b["detection_by_hidden_count"]
        .as_object()
        .expect("a detection table")
        .values()
        .flat_map(|by_count| by_count.as_object().unwrap().values())
        .map(|k| k[1].as_u64().unwrap())
        .sum();
    assert_eq!(
        hidden_counted as usize, hidden_total,
        "hidden effects in the detection table"
    );
}

/// Generates proving-ground scenario `seed` with the independent Python simulator and
/// diagnoses it: the scenario's meta JSON and the diagnosis JSON.
fn generate_and_diagnose(seed: u32) -> (serde_json::Value, serde_json::Value) {
    let (m, d, _) = generate_and_diagnose_with_residuals(seed);
    (m, d)
}

/// [`generate_and_diagnose`], also returning the per-sample comparison diagnose writes with
/// `--residuals` (CSV text).
fn generate_and_diagnose_with_residuals(
    seed: u32,
) -> (serde_json::Value, serde_json::Value, String) {
    generate_and_diagnose_as(seed, false, &[])
}

/// Scenario `seed`'s null twin (`generate.py --null-twin`: the same damper, fluid,
/// excitation and measurement noise with nothing hidden) diagnosed: its meta JSON and the
/// diagnosis JSON.
fn generate_null_twin_and_diagnose(seed: u32) -> (serde_json::Value, serde_json::Value) {
    let (m, d, _) = generate_and_diagnose_as(seed, true, &[]);
    assert_null(seed, &m);
    (m, d)
}

/// Generates scenario `seed` (or its null twin) and diagnoses it, with diagnose's options
/// `extra` besides the outputs: meta, diagnosis and the `--residuals` CSV text.
fn generate_and_diagnose_as(
    seed: u32,
    null_twin: bool,
    extra: &[&str],
) -> (serde_json::Value, serde_json::Value, String) {
    let dir = TempDir::new(&format!(
        "pg-seed{seed}{}",
        if null_twin { "-twin" } else { "" }
    ));
    let (csv, meta) = generate_scenario(&dir, seed, null_twin);
    let json = dir.path("d.json");
    let (report, residuals) = (dir.path("d.md"), dir.path("r.residuals.csv"));
    let mut diagnose_args = vec![
        "diagnose",
        csv.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "--residuals",
        residuals.to_str().unwrap(),
    ];
    diagnose_args.extend_from_slice(extra);
    succeeded(
        run(env!("CARGO_BIN_EXE_mrtwin"), &diagnose_args),
        "mrtwin diagnose",
    );
    let residuals = std::fs::read_to_string(&residuals).expect("diagnose wrote its residuals");
    (read_json(&meta), read_json(&json), residuals)
}

/// [`generate_and_diagnose`] for a scenario that must be a null (nothing hidden).
fn generate_null_and_diagnose(seed: u32) -> (serde_json::Value, serde_json::Value) {
    let (m, d) = generate_and_diagnose(seed);
    assert_null(seed, &m);
    (m, d)
}

/// Scenario `seed` (its meta JSON `m`) hides nothing.
fn assert_null(seed: u32, m: &serde_json::Value) {
    assert!(
        m["hidden"].as_array().unwrap().is_empty(),
        "seed {seed} is a null"
    );
}

/// A null's diagnosis reports no finding.
fn assert_reports_nothing(seed: u32, d: &serde_json::Value) {
    assert!(
        d["findings"].as_array().unwrap().is_empty(),
        "seed {seed}: false findings on a null: {}",
        d["findings"]
    );
}

/// A bi-viscous null scenario diagnosed: its metadata, the diagnosis, σ_F, the baseline's
/// held-out RMS and its relative leak λ.
fn bi_viscous_null_baseline(seed: u32) -> (serde_json::Value, serde_json::Value, f64, f64, f64) {
    let (m, d) = generate_null_and_diagnose(seed);
    assert_eq!(m["fluid"]["law"], "biviscous", "the scenario changed");
    let sigma_f = m["sigma_F_N"].as_f64().unwrap();
    let held_out = d["baseline"]["holdout_rmse_N"].as_f64().unwrap();
    let lambda = d["baseline_parameters"]["leak_per_yield_velocity"]
        .as_f64()
        .unwrap();
    (m, d, sigma_f, held_out, lambda)
}

/// A bi-viscous fluid whose pre-yield ramp spans half the stroke (proving-ground null
/// seed 54: viscosity ratio 495, a civil damper whose force is a steep line up to
/// 18 kN at 28 mm/s and nearly flat above it, 43 mm/s peak). The baseline's relative leak
/// is the fluid's inverse viscosity ratio; from the fixed starts alone it ended in the
/// absolute-leak basin (λ = 0) at 4.68 σ_F held-out. Nothing is hidden, so nothing may be
/// found, and the baseline must come near the noise: 1.13 σ_F from the fitted start; 1.25
/// since the current channel's plateaus are denoised (diagnose::current), with λ at 0.99 of
/// the fluid's 1/ratio where it was 0.83 (the misfit left is in the fastest held-out
/// strokes at 1.0 A).
#[test]
fn a_bi_viscous_fluid_below_yield_over_half_the_stroke_is_fitted_to_the_noise() {
    let (m, d, sigma_f, held_out, lambda) = bi_viscous_null_baseline(54);
    let truth = 1.0 / m["fluid"]["visc_ratio"].as_f64().unwrap();
    eprintln!(
        "held-out {:.2} σ_F, relative leak {lambda:.5} (1/ratio {truth:.5})",
        held_out / sigma_f
    );
    assert!(
        held_out <= 1.3 * sigma_f,
        "baseline held-out {held_out:.1} N against σ_F {sigma_f:.1} N"
    );
    assert!(
        (0.9 * truth..=1.1 * truth).contains(&lambda),
        "relative leak {lambda} against the fluid's 1/ratio {truth}"
    );
    assert_reports_nothing(54, &d);
}

/// A bi-viscous null under a random current (proving-ground seed 289: viscosity ratio 283,
/// eight knots). The baseline's start fitted to the data (relative leak 0.0056) fits the
/// fitting blocks 27 % better than the fixed starts, not the half better that alone makes
/// it the baseline, and the fixed starts' basin (λ = 0, an absolute leak of 13.5 mm/s)
/// predicted the held-out blocks at 3.95 σ_F. Of the two basins the one that predicts
/// better is kept (diagnose::model::better_basin): the fitted start's. Nothing may be
/// found and the baseline must come near the noise.
#[test]
fn of_two_leak_basins_the_one_that_predicts_is_the_baseline() {
    let (_, d, sigma_f, held_out, lambda) = bi_viscous_null_baseline(289);
    eprintln!(
        "held-out {:.2} σ_F, relative leak {lambda:.5}",
        held_out / sigma_f
    );
    assert!(
        held_out <= 1.8 * sigma_f,
        "baseline held-out {held_out:.1} N against σ_F {sigma_f:.1} N"
    );
    assert!(lambda > 0.0, "the absolute-leak basin was kept");
    assert_reports_nothing(289, &d);
}

/// The force noise a record is judged against, on a slowly sampled null (proving-ground
/// seed 87: 200 Hz, a random current, a civil damper, white force noise). The force
/// channel's own estimate (residuals about cubics over ±3 samples) takes for noise the
/// force a cubic over 35 ms cannot follow, and said 1.90 σ_F; a finding's held-out gain had
/// to clear a floor 3.6 times too high. Read again from the settled baseline's residual
/// (diagnose::measure::residual_white_noise_sigma), it must come near the generator's σ_F,
/// a little under it where the anti-alias filter has taken the top of the band.
#[test]
fn a_slowly_sampled_records_force_noise_is_read_from_the_baselines_residual() {
    let (m, d) = generate_null_and_diagnose(87);
    assert_eq!(m["excitation"]["fs_hz"], 200, "the scenario changed");
    let sigma_f = m["sigma_F_N"].as_f64().unwrap();
    let hf = d["measurement"]["force_noise_hf_n"].as_f64().unwrap();
    eprintln!("force noise {:.3} σ_F", hf / sigma_f);
    assert!(
        (0.8 * sigma_f..=1.3 * sigma_f).contains(&hf),
        "force noise {hf:.1} N against the generator's σ_F {sigma_f:.1} N"
    );
    assert_reports_nothing(87, &d);
}

/// A compliance whose gain is in the samples right after each reversal (proving-ground
/// seed 159: a compressible fluid with 0.03 % air and a 12 kg moving mass, 500 Hz,
/// Savitzky–Golay velocity). Its held-out RMS falls 213.8 → 108.8 N, but the smoothed
/// residual structure only 14 %: the transient is sharp, counted as noise by the smoother,
/// and the compliance failed the structure rule while a 3 kN seal friction, hidden nowhere,
/// passed it. The held-out mean square above the force noise counts as structure too
/// (diagnose::select::judge): exactly the hidden pair is found, with no seal. Since session
/// 62 that mean square may be the typical held-out block's (here it falls further, 0.87,
/// than the pooled one): either way it is the held-out excess, not the smoothed structure,
/// that passes it.
#[test]
fn a_compliance_whose_gain_is_sharp_passes_the_structure_rule() {
    let (m, d) = generate_and_diagnose(159);
    assert_eq!(
        hidden_effects(&m),
        ["fluid_compressibility", "fluid_inertia"],
        "the scenario changed"
    );
    assert_eq!(
        found_effects(&d),
        ["fluid_compressibility", "fluid_inertia"],
        "{}",
        d["findings"]
    );
    let compliance = d["trials"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["effect"] == "fluid_compressibility" && t["accepted"] == true)
        .expect("an accepted compliance trial");
    eprintln!("{}", compliance["evidence"]);
    let region = compliance["evidence"]["structure_region"].as_str().unwrap();
    assert!(
        [
            "held-out mean square above the force noise",
            "typical held-out block's mean square above the force noise"
        ]
        .contains(&region),
        "{region}"
    );
}

/// A strong compressibility's chamber changes volume along the stroke, and the accepted
/// model follows it (proving-ground seed 91: a Papanastasiou fluid under 2 kHz sines,
/// entrained air at 11 MPa in a chamber of 133 cm³ whose annulus of 34 cm² sweeps ±12.5 mm,
/// ±32 % of its volume, beside a LuGre seal friction). Tested as one all-air volume the
/// compressibility is found (two parameters against its null); then its liquid share and
/// volume change are freed (diagnose::select::free_chamber_shape) and the held-out RMS
/// falls from 2.39 to 1.80 σ_F, under which the friction (0.4 σ_F left unabsorbed) is
/// found too. Before, the lumped volume left the misfit the friction sat under and only the
/// compressibility was reported. The volume change is checked against the generator's own
/// geometry, which diagnose never sees: −A₁ x̂ / V₁₀.
#[test]
fn a_chambers_volume_that_follows_the_stroke_is_fitted_and_uncovers_a_friction() {
    let (m, d) = generate_and_diagnose(91);
    assert_eq!(
        hidden_effects(&m),
        ["fluid_compressibility", "seal_friction"],
        "the scenario changed"
    );
    assert_eq!(
        found_effects(&d),
        ["fluid_compressibility", "seal_friction"],
        "{}",
        d["trials"]
    );
    let g = &m["geometry"];
    let num = |v: &serde_json::Value| v.as_f64().unwrap_or_else(|| panic!("{v}"));
    let truth = -num(&g["A1"]) * num(&m["excitation"]["peak_x"]) / num(&g["V10"]);
    let (lam, ci) = finding_parameter(&d, "fluid_compressibility", "volume_change");
    eprintln!(
        "volume change {lam:.3} [{:.3}, {:.3}], generator {truth:.3}",
        ci[0], ci[1]
    );
    assert!(
        (lam - truth).abs() < 0.15 * truth.abs(),
        "volume change {lam:.3} against the generator's {truth:.3}"
    );
    assert!(ci[0] < truth && truth < ci[1], "{ci:?} against {truth:.3}");
}

/// A gas spring judged against the baseline's optimum, not a stop short of it
/// (proving-ground seed 107: 3.6 N/mm of polytropic gas at x = 0, a bi-viscous fluid under
/// a continuously varying current, 1 kHz, 16 s of multi-sine strokes). Its baseline stops
/// 133 noise units of fitting SSE short of its own optimum: every candidate of round 1
/// shows it (a field lag fitted to no lag took the held-out RMS 45.5 → 26.3 N). Fitted from
/// the stop, the gas halved most held-out blocks and made three blocks the stopped baseline
/// misfits (49–99 N) worse, so pooled the held-out RMS rose and only the typical block's
/// reading (diagnose::select, `broad_gain`, sessions 53–69) found it. Since session 70 the
/// candidates are fitted again from the baseline's better parameters
/// (`judged_from_current_optimum`): the gas takes the pooled held-out RMS down by half, and
/// nothing else is found (the yield force on straight lines between the knots, which
/// `--yield-curve auto` keeps here: the baseline fits 21.6 N on them against 22.9 N on the
/// cubic curve, where the gas takes the held-out RMS down by only a quarter). Since
/// session 83 the knot at 1.291 A, whose fitting samples never reach its 1.68 kN yield
/// force, is started again from its neighbours' and refitted free
/// (diagnose::model::hold_unyielded_knots; it fits 21.54 N against 21.62): the baseline
/// predicts the held-out blocks at 26.4 N instead of 45.5 N, and the gas takes them to
/// 21.0 N as before (a fifth off the pooled RMS, where it took half). The
/// typical-block reading keeps its unit test
/// (`one_extrapolated_block_neither_hides_a_broad_gain_nor_passes_as_one`).
#[test]
fn a_gas_spring_fitted_from_the_baselines_optimum_predicts_the_held_out_blocks() {
    let (m, d) = generate_and_diagnose(107);
    assert_eq!(hidden_effects(&m), ["gas_spring"], "the scenario changed");
    let found = found_effects(&d);
    assert_eq!(found, ["gas_spring"], "{}", d["trials"]);
    let gas = d["trials"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["effect"] == "gas_spring" && t["round"] == 1)
        .expect("the gas spring's first-round trial");
    let e = &gas["evidence"];
    eprintln!("{e}");
    let num = |k: &str| e[k].as_f64().unwrap_or_else(|| panic!("{k}: {e}"));
    // The baseline stopped short of its optimum, by far more than one noise unit ...
    let shortfall = e["calibration"]["current_shortfall"]
        .as_f64()
        .unwrap_or_else(|| panic!("current_shortfall: {e}"));
    assert!(shortfall > 50.0, "shortfall {shortfall}");
    // ... and from its better parameters the gas predicts the held-out blocks pooled, and
    // in the typical block, with no block hurt more than the typical block gains.
    let (b, a) = (num("holdout_rmse_before_N"), num("holdout_rmse_after_N"));
    assert_eq!(d["yield_curve"], "lines", "{}", d["yield_curve_fits"]);
    assert!(a < 0.85 * b, "pooled held-out {b:.2} -> {a:.2} N");
    let (tb, ta) = (
        num("holdout_typical_block_rmse_before_N"),
        num("holdout_typical_block_rmse_after_N"),
    );
    assert!(ta < 0.8 * tb, "typical block {tb:.2} -> {ta:.2} N");
    assert!(
        num("holdout_worst_block_ms_ratio") <= (tb / ta).powi(2),
        "{e}"
    );
    assert!(num("structure_drop") >= 0.2, "{e}");
    let truth = m["effects"][0]["parameters"]["stiffness_at_0_N_m"]
        .as_f64()
        .unwrap()
        / 1e3;
    let k = gas["parameters"]["stiffness"]["value"].as_f64().unwrap();
    assert!(
        (k - truth).abs() < 0.1 * truth,
        "stiffness {k:.3} N/mm against the generator's {truth:.3} at x = 0"
    );
    eprintln!("stiffness {k:.3} N/mm, generator {truth:.3}");
}

/// A coil driver's lag far from the best unfitted start (proving-ground seed 287: a driver
/// with rails, 93 ms and 9 ms poles, effective time constant 27 ms, beside a gas spring and
/// a thermal drift, 1 kHz random strokes under a random current). From the best unfitted of
/// the three starts, 3 ms, the lag ended at 2.8 ms and explained nothing, and nothing was
/// reported. Each start is now fitted part of the way and the best fitted one carried on
/// (diagnose::select::fit_candidate_limited): the lag is found near the generator's, and
/// nothing that was not hidden. Its interval is not asserted: with the yield force on the
/// cubic curve (which `--yield-curve auto` keeps here: the baseline fits 57.5 N on it
/// against 123.5 N on lines) the lag comes out at 21.1 ms [20.4, 21.9] against the driver's
/// effective 26.8 ms (on straight lines, before session 80, the interval held it), and the
/// fitting and held-out halves agree, so nothing widens it: a first-order lag fitted to a
/// second-order driver is a model-form error that an interval from the fit's own noise
/// cannot show (BENCHMARKS.md, issue 10, session 80).
#[test]
fn a_field_lag_is_fitted_from_the_start_that_fits_best() {
    let (m, d) = generate_and_diagnose(287);
    assert_eq!(
        hidden_effects(&m),
        ["field_lag", "gas_spring", "thermal_softening"],
        "the scenario changed"
    );
    let found = found_effects(&d);
    assert!(found.contains(&"field_lag"), "{}", d["trials"]);
    assert!(
        found.iter().all(|f| hidden_effects(&m).contains(f)),
        "a false finding: {found:?}"
    );
    let truth = entry_of(&m["effects"], "field_lag")["parameters"]["effective_tau_s"]
        .as_f64()
        .unwrap()
        * 1e3;
    let (tau, ci) = finding_parameter(&d, "field_lag", "field_time_constant");
    eprintln!("lag {tau:.2} ms {ci:?}, generator's effective {truth:.2} ms");
    // The generator's lag is second order with rails; its effective time constant is an
    // approximation, which the first-order lag must come within 30 % of.
    assert!(
        (tau / truth - 1.0).abs() < 0.3,
        "lag {tau:.2} ms {ci:?} against the generator's effective {truth:.2} ms"
    );
    let lag = entry_of(&d["findings"], "field_lag");
    let (b, a) = (
        lag["evidence"]["holdout_rmse_before_N"].as_f64().unwrap(),
        lag["evidence"]["holdout_rmse_after_N"].as_f64().unwrap(),
    );
    assert!(a < 0.8 * b, "held-out {b:.1} -> {a:.1} N");
}

/// A bi-viscous null (proving-ground seed 200: viscosity ratio 265, a random current)
/// whose steep force rise at low speed a constant seal-friction step of 2.1 kN fitted, with
/// no presliding displacement resolved, better than the same step scaled by the yield
/// force: it was reported as a seal. It is the fluid's: nothing is reported, and the final
/// model carries the rise, in the baseline's relative leak (since 2026-11-27, the basin that
/// predicts better: model::better_basin) or as a step scaled by the viscous coefficient in
/// the fluid's shape (before), and predicts the held-out blocks near the noise.
#[test]
fn a_bi_viscous_rise_at_low_speed_is_the_fluids_shape_not_a_seal() {
    let (m, d) = generate_null_and_diagnose(200);
    assert_eq!(m["fluid"]["law"], "biviscous", "the scenario changed");
    assert_reports_nothing(200, &d);
    let shape = d["fluid_shape"].as_array().unwrap();
    let lambda = d["final_parameters"]["leak_per_yield_velocity"]
        .as_f64()
        .unwrap();
    assert!(
        lambda > 0.0 || shape.iter().any(|s| s["follows"] == "viscous_coefficient"),
        "neither a relative leak nor a viscosity-scaled step carries the rise: {shape:?}"
    );
    let sigma_f = m["sigma_F_N"].as_f64().unwrap();
    let fin = d["final"]["holdout_rmse_N"].as_f64().unwrap();
    eprintln!(
        "final held-out {:.2} σ_F, relative leak {lambda}",
        fin / sigma_f
    );
    assert!(
        fin <= 1.2 * sigma_f,
        "final held-out {fin} N, σ_F {sigma_f} N"
    );
}

/// The current channel's measurement model (diagnose::current) on three nulls of the
/// independent simulator. Seed 77: 1 kHz, a random current held 0.3–1 s at a time (30
/// steps), 2.2 mA of channel noise; taken as recorded, the model saw each filtered step
/// and filtered its force again, and the baseline's held-out RMS was 6.15 σ_F. Seed 131:
/// 2.5 kHz, three steps; a field lag of 0.14 ms passed at T = 3.3 against a bootstrap
/// threshold of 0.05, below the white-noise one. Seed 213: 2 kHz, 14 steps, AR(1) force
/// noise; the cut-off fitted to the force was 0.15 f_s against the true 0.372, the force
/// 1–2 samples after each step was 20–30 σ_F off, and a field lag of 0.34 ms passed. Each
/// must find the plateaus and steps, read its filter from the steps to within 0.01 f_s of
/// the generated one, report nothing, and come within its bound (seed 77: 2.2 σ_F, 1.89
/// with the model; seed 213: 1.5, 1.39 with it).
#[test]
fn current_steps_and_noise_are_modelled_and_no_lag_is_made_of_them() {
    for (seed, steps, within) in [(77, 30, 2.2), (131, 3, 1.15), (213, 14, 1.5)] {
        let (m, d) = generate_null_and_diagnose(seed);
        let cur = &d["measurement"]["current"];
        let sigma_i = m["measurement"]["sigma_I_A"].as_f64().unwrap();
        let noise = cur["noise_a"].as_f64().unwrap();
        assert!(
            (noise / sigma_i - 1.0).abs() < 0.15,
            "seed {seed}: current noise {noise} A, generated with {sigma_i} A"
        );
        assert_eq!(cur["steps"], steps, "seed {seed}: {cur}");
        let aa = &d["measurement"]["anti_alias"];
        let true_cutoff = m["measurement"]["aa_cutoff_hz"].as_f64().unwrap()
            / m["excitation"]["fs_hz"].as_f64().unwrap();
        assert_eq!(aa["source"], "current_steps", "seed {seed}: {aa}");
        assert!(
            (aa["cutoff_per_fs"].as_f64().unwrap() - true_cutoff).abs() < 0.01,
            "seed {seed}: cut-off {aa} against {true_cutoff} f_s"
        );
        let sigma_f = m["sigma_F_N"].as_f64().unwrap();
        let held_out = d["baseline"]["holdout_rmse_N"].as_f64().unwrap();
        eprintln!("seed {seed}: {cur}, baseline {:.2} σ_F", held_out / sigma_f);
        assert!(
            held_out <= within * sigma_f,
            "seed {seed}: baseline held-out {:.2} σ_F",
            held_out / sigma_f
        );
        assert_reports_nothing(seed, &d);
    }
}

/// The effects a scenario's meta JSON hides, sorted.
fn hidden_effects(meta: &serde_json::Value) -> Vec<&str> {
    sorted_strings(meta["hidden"].as_array().unwrap().iter())
}

/// The diagnosis's current knots (`split.current_knots_a`), in A.
fn current_knots(diagnosis: &serde_json::Value) -> Vec<f64> {
    diagnosis["split"]["current_knots_a"]
        .as_array()
        .unwrap()
        .iter()
        .map(|k| k.as_f64().unwrap())
        .collect()
}

/// Baseline parameter `knot{q}_{name}` of the diagnosis.
fn knot_parameter(diagnosis: &serde_json::Value, q: usize, name: &str) -> f64 {
    diagnosis["baseline_parameters"][format!("knot{q}_{name}")]
        .as_f64()
        .unwrap()
}

/// The effects a diagnosis found, sorted.
fn found_effects(diagnosis: &serde_json::Value) -> Vec<&str> {
    sorted_strings(
        diagnosis["findings"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| &f["effect"]),
    )
}

fn sorted_strings<'a>(values: impl Iterator<Item = &'a serde_json::Value>) -> Vec<&'a str> {
    let mut v: Vec<&str> = values.map(|x| x.as_str().unwrap()).collect();
    v.sort();
    v
}

/// A fitted parameter of a finding: its value and 95 % interval.
fn finding_parameter(d: &serde_json::Value, effect: &str, name: &str) -> (f64, [f64; 2]) {
    let p = &entry_of(&d["findings"], effect)["parameters"][name];
    let ci = p["ci95"].as_array().unwrap();
    (
        p["value"].as_f64().unwrap(),
        [ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap()],
    )
}

/// An accepted thermal softening frees its viscous terms' softening from the yield
/// force's (proving-ground seed 433: a fluid mass and a linear thermal softening hidden,
/// the viscosity softening 12.5 times faster per kelvin than the yield stress). Tested as
/// one factor, the softening is found; the one factor left the final held-out RMS at
/// 1.43 σ_F. Freed (diagnose::select::free_thermal_apart), the viscous terms take their
/// own softening and the final model predicts the held-out blocks at the noise, and each
/// 95 % interval holds the generator's coefficient over its heat capacity (β/C: 0.046/kJ
/// for the yield stress, 0.57/kJ for the viscosity).
#[test]
fn an_accepted_thermal_softening_frees_its_viscous_softening() {
    let (m, d) = generate_and_diagnose(433);
    assert_eq!(
        hidden_effects(&m),
        ["fluid_inertia", "thermal_softening"],
        "the scenario changed"
    );
    assert_eq!(found_effects(&d), ["fluid_inertia", "thermal_softening"]);
    let effect = m["effects"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["effect"] == "thermal_softening")
        .unwrap();
    let heat_capacity = m["thermal"]["C_J_K"].as_f64().unwrap();
    let truth = |key: &str| effect["parameters"][key].as_f64().unwrap() / heat_capacity * 1e3;
    let (yield_truth, viscous_truth) = (truth("beta_tau_per_K"), truth("beta_mu_per_K"));
    let (by, by_ci) = finding_parameter(&d, "thermal_softening", "softening_per_energy");
    let (bc, bc_ci) = finding_parameter(&d, "thermal_softening", "viscous_softening_per_energy");
    let viscous = &entry_of(&d["findings"], "thermal_softening")["parameters"]
        ["viscous_softening_per_energy"];
    assert!(viscous.get("tied_to").is_none(), "{viscous}");
    eprintln!(
        "yield {by} {by_ci:?} (true {yield_truth}); viscous {bc} {bc_ci:?} (true {viscous_truth})"
    );
    assert!(bc > 3.0 * by, "viscous {bc} against yield {by}");
    assert!(by_ci[0] <= yield_truth && yield_truth <= by_ci[1]);
    assert!(bc_ci[0] <= viscous_truth && viscous_truth <= bc_ci[1]);
    let sigma_f = m["sigma_F_N"].as_f64().unwrap();
    let held_out = d["final"]["holdout_rmse_N"].as_f64().unwrap();
    assert!(
        held_out < 1.1 * sigma_f,
        "final held-out {:.3} σ_F",
        held_out / sigma_f
    );
}

/// A bi-viscous fluid whose baseline a hidden effect led to the wrong basin is moved to its
/// own once that effect is found (proving-ground seed 745: viscosity ratio 425, a gas
/// spring and an exponential thermal softening hidden, random strokes at 200 Hz). Without
/// the gas spring in, the baseline takes the absolute-leak basin (a 10.5 mm/s leak, the
/// knots' c at their floor, speed curvatures of −15 and −25 kN). Once the gas spring is
/// found, the model is refitted from the relative-leak basin
/// (diagnose::model::relative_leak_basin): its λ comes out near the fluid's inverse
/// viscosity ratio, the held-out blocks fall from 6.4 σ_F, and the softening, hidden
/// behind the misfit before, is found.
#[test]
fn a_fluid_led_to_the_wrong_basin_by_a_hidden_effect_is_moved_once_that_effect_is_found() {
    let (m, d) = generate_and_diagnose(745);
    assert_eq!(
        hidden_effects(&m),
        ["gas_spring", "thermal_softening"],
        "the scenario changed"
    );
    assert_eq!(m["fluid"]["law"], "biviscous", "the scenario changed");
    let lambda = |model: &str| d[model]["leak_per_yield_velocity"].as_f64().unwrap();
    assert_eq!(
        lambda("baseline_parameters"),
        0.0,
        "the baseline is no longer in the absolute-leak basin: this test no longer tests \
         the move"
    );
    assert_eq!(found_effects(&d), ["gas_spring", "thermal_softening"]);
    let inverse_ratio = 1.0 / m["fluid"]["visc_ratio"].as_f64().unwrap();
    let fitted = lambda("final_parameters");
    eprintln!("λ {fitted} against 1/r = {inverse_ratio}");
    assert!(
        (0.5..2.0).contains(&(fitted / inverse_ratio)),
        "λ {fitted} against 1/r = {inverse_ratio}"
    );
    let sigma_f = m["sigma_F_N"].as_f64().unwrap();
    let held_out = d["final"]["holdout_rmse_N"].as_f64().unwrap() / sigma_f;
    assert!(held_out < 2.0, "final held-out {held_out:.2} σ_F");
}

/// A pair whose split the record's halves do not replicate is withdrawn (proving-ground
/// null 520: a bi-viscous fluid under sines of 1.6–7.3 Hz at 200 Hz, nothing hidden). The
/// pair `gas_spring+fluid_inertia` is accepted in round 1 (its statistic 17.7 against its
/// bootstrap null's 15.7), at 1.3 N/mm and 1.0 kg, each clear of zero on the fit's own
/// interval; refitted on the held-out blocks it splits otherwise, and with that spread
/// neither interval clears zero (diagnose::select::withdraw_unreplicated_pairs). Both are
/// withdrawn and nothing is reported; before, both were reported on this null.
#[test]
fn a_pair_whose_split_the_records_halves_do_not_replicate_is_withdrawn() {
    let (_, d) = generate_null_and_diagnose(520);
    let accepted_pair = d["trials"]
        .as_array()
        .unwrap()
        .iter()
        .any(|t| t["effect"] == "gas_spring+fluid_inertia" && t["accepted"] == true);
    assert!(
        accepted_pair,
        "the pair is no longer accepted in selection: this test no longer tests its withdrawal"
    );
    assert_reports_nothing(520, &d);
    let withdrawn = d["withdrawn"].as_array().unwrap();
    assert!(
        withdrawn.iter().any(|w| w
            .as_str()
            .unwrap()
            .starts_with("gas_spring and fluid_inertia: accepted as a pair")),
        "withdrawn: {withdrawn:?}"
    );
}

/// A gas spring and a fluid mass that cancel when fitted one at a time (proving-ground seed
/// 141: sines at 6.4, 5.3 and 1.9 Hz, a = −ω² x, with 65 N/mm of gas and 42 kg of gap
/// fluid hidden beside a coil-driver field lag). Alone, the mass fitted 0 kg and the gas
/// 12 N/mm, neither passed, and a false seal friction took part of what they left; fitted
/// as the pair `gas_spring+fluid_inertia` (diagnose::select::PAIRS) both were found at
/// their generated values, the pair accepted in round 2. Since session 87 the model is
/// refitted in the relative-leak basin once the lag is in (held-out 373 → 266 N;
/// diagnose::model::relative_leak_basin), and from there the gas passes alone in round 2
/// and the mass in round 3, at values closer to the generator's. The pair passes its four
/// rules in round 1 all the same. Since session 89 (the Jacobian carries a held yield
/// softness's term) the lag model's refit predicts the held-out blocks at 287 N, not
/// 266 N, and a seal friction of 294 N is accepted in round 2 beside the three: a false
/// finding, counted in BENCHMARKS.md (issue 10, session 89), not asserted away here.
#[test]
fn a_gas_spring_and_a_mass_that_cancel_alone_are_both_found() {
    let (m, d) = generate_and_diagnose(141);
    let hidden = hidden_effects(&m);
    assert_eq!(
        hidden,
        ["field_lag", "fluid_inertia", "gas_spring"],
        "the scenario changed"
    );
    let found = found_effects(&d);
    assert!(
        hidden.iter().all(|h| found.contains(h)),
        "findings {}",
        d["findings"]
    );
    let pair_passes = d["trials"].as_array().unwrap().iter().any(|t| {
        t["effect"] == "gas_spring+fluid_inertia"
            && t["round"] == 1
            && t["passed"].as_array().unwrap().iter().all(|p| p == true)
    });
    assert!(pair_passes, "the pair does not pass its rules in round 1");
    let truth = |effect: &str, key: &str| {
        entry_of(&m["effects"], effect)["parameters"][key]
            .as_f64()
            .unwrap()
    };
    // The generator's gas is polytropic (its stiffness at mid-stroke is quoted) and its
    // gap fluid's mass is ρ L A1²/(b h): the linear stiffness and the mass fitted over the
    // stroke must lie within 15 % of them.
    let k_true = truth("gas_spring", "stiffness_at_0_N_m") / 1000.0;
    let m_true = truth("fluid_inertia", "gap_fluid_mass_kg");
    let (k, _) = finding_parameter(&d, "gas_spring", "stiffness");
    let (mass, _) = finding_parameter(&d, "fluid_inertia", "fluid_mass");
    eprintln!("gas {k:.1} N/mm (generated {k_true:.1}), mass {mass:.1} kg (generated {m_true:.1})");
    assert!(
        (k / k_true - 1.0).abs() < 0.15,
        "gas {k} N/mm against {k_true}"
    );
    assert!(
        (mass / m_true - 1.0).abs() < 0.15,
        "mass {mass} kg against {m_true}"
    );
}

/// The online yield-stress estimator's σ on six proving-ground scenarios
/// (`scripts/proving_ground/estimator_coverage.py`): each replayed through the twin with
/// the generator's geometry and compared, every 0.5 s, with the yield stress the simulated
/// fluid really had. Run with and without the model-error widening (issue 13). The
/// 300-scenario study is in BENCHMARKS.md (seeds 0–299: 94 % within 2σ, 90–97 % in every
/// current range; issue 13, session 55); this is a regression guard, not the goal.
#[test]
fn the_yield_estimators_sigma_against_the_independent_truth() {
    let dir = TempDir::new("pg-cov");
    let script = repo_root().join("scripts/proving_ground/estimator_coverage.py");
    let work = dir.path("work");
    let summary = |widen: bool| -> serde_json::Value {
        let setting = format!("widen_for_model_error={widen}");
        run_python(
            RUN_FILE,
            &[
                script.to_str().unwrap(),
                "--seeds",
                "4,7,15,20,27,32",
                "--jobs",
                "2",
                "--bin",
                env!("CARGO_BIN_EXE_mrtwin"),
                "--out",
                work.to_str().unwrap(),
                "--estimator",
                &setting,
            ],
            Duration::from_secs(600),
        );
        read_json(&work.join("coverage.json"))
    };
    let (off, on) = (summary(false), summary(true));
    for j in [&off, &on] {
        assert!(
            j["failures"].as_array().unwrap().is_empty(),
            "{}",
            j["failures"]
        );
        // The twin's rod force per pascal is the generator's 2 L A1/h: τ0 and the truth
        // are in the same units.
        assert!(j["force_per_pa_max_rel_diff"].as_f64().unwrap() < 1e-9);
        assert_eq!(
            j["summary"]["overall"]["records"], 5,
            "records with estimates"
        );
    }
    let (a, b) = (&off["summary"]["overall"], &on["summary"]["overall"]);
    let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
    eprintln!(
        "2σ coverage {:.3} → {:.3} with the widening; median 2σ/τ {:.4} → {:.4} (a fixed \
         band would need ±{:.4} for the same share); median |error|/τ {:.4} → {:.4}",
        f(a, "cover2"),
        f(b, "cover2"),
        2.0 * f(a, "median_rel_sd"),
        2.0 * f(b, "median_rel_sd"),
        f(b, "const_band_same_cover"),
        f(a, "median_rel_err"),
        f(b, "median_rel_err")
    );
    // The estimates are close to the truth (what the widening leaves unpublished as not
    // identified changes the set a little).
    for v in [a, b] {
        assert!(f(v, "median_rel_err") < 0.10, "median error {v}");
    }
    // The widening covers more (44 → 91 % of the points within 2σ; 73 % before the
    // common-offset part for a seal friction read as yield) with a band narrower than a
    // fixed one holding the same share (median ±21 % of τ against ±255 %: the friction
    // is most of τ0 at the lowest currents).
    assert!(
        f(b, "cover2") > f(a, "cover2") + 0.1,
        "the widening covered too little more: {a} / {b}"
    );
    assert!(
        2.0 * f(b, "median_rel_sd") < f(b, "const_band_same_cover"),
        "the widened band is wider than a fixed one with the same coverage: {b}"
    );
}

/// A parameter interval widened by the spread between the record's halves (issue 13;
/// docs/diagnose.md, Limits). Proving-ground seed 116 hides a 1.0 ms first-order field lag
/// (with a gas spring): the lag fitted on the fitting blocks comes out 0.92 ms, its own
/// interval 0.89–0.95 ms missing the generated value; refitted on the held-out blocks it
/// differs by more than the two standard errors explain, and the widened interval
/// (0.72–1.12 ms) holds it. (Seed 0 was this test's record until the nineteenth diagnose
/// pass, whose velocity error scale brought its lag to 25.0 ms against 25.3 generated with
/// halves that agree.)
#[test]
fn a_lag_whose_halves_disagree_gets_an_interval_that_holds_the_generated_value() {
    let (m, d) = generate_and_diagnose(116);
    let lag = entry_of(&m["effects"], "field_lag");
    assert_eq!(
        lag["parameters"]["kind"], "first_order",
        "the scenario changed"
    );
    let truth_ms = lag["parameters"]["effective_tau_s"].as_f64().unwrap() * 1e3;
    let (v, ci) = finding_parameter(&d, "field_lag", "field_time_constant");
    let p = &entry_of(&d["findings"], "field_lag")["parameters"]["field_time_constant"];
    let fit: Vec<f64> = p["ci95_fit"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let spread = p["halves_spread"].as_f64().unwrap();
    eprintln!(
        "lag {v:.2} ms (generated {truth_ms:.2}): fit alone {fit:?}, widened {ci:?}, \
         halves' spread {spread:.2} ms"
    );
    assert!(spread > 0.0, "the halves agree: {p}");
    assert!(ci[0] < fit[0] && ci[1] > fit[1], "not widened: {p}");
    assert!(
        ci[0] <= truth_ms && truth_ms <= ci[1],
        "{truth_ms} ms outside {ci:?}"
    );
}

/// A field lag seen only after current steps (proving-ground seed 253: a second-order lag
/// of 1.0 ms effective, the current stepping every 0.97 s). Eight equal validation blocks
/// of 0.5 s put all four steps in held-out blocks, and the lag, fitted on none of them,
/// came out 6 ms and predicted the held-out blocks worse, so nothing was found (issue 10,
/// twentieth pass). The split now keeps a step in the fitting blocks: the lag alone is
/// found, and its interval holds the generated time constant.
#[test]
fn a_field_lag_is_fitted_on_current_steps_the_split_keeps_in_the_fitting_blocks() {
    let (m, d) = generate_and_diagnose(253);
    assert_eq!(hidden_effects(&m), ["field_lag"], "the scenario changed");
    assert_eq!(
        m["excitation"]["current"]["mode"], "stepped",
        "the scenario changed"
    );
    let method = d["split"]["method"].as_str().unwrap();
    assert!(
        method.contains("current step in the fitting blocks"),
        "split: {method}"
    );
    assert_eq!(found_effects(&d), ["field_lag"], "split: {method}");
    let truth_ms = m["effects"][0]["parameters"]["effective_tau_s"]
        .as_f64()
        .unwrap()
        * 1e3;
    let (v, ci) = finding_parameter(&d, "field_lag", "field_time_constant");
    eprintln!("lag {v:.2} ms, interval {ci:?}, generated {truth_ms:.2} ms; split: {method}");
    assert!(
        ci[0] <= truth_ms && truth_ms <= ci[1],
        "{truth_ms} ms outside {ci:?}"
    );
}

/// A field lag shorter than one sample interval is found (proving-ground seed 324: a
/// first-order lag of 1.17 ms, sampled at 200 Hz, under a current stepped among four
/// levels). From the 3, 10 and 30 ms starts the knots followed the lag into a basin that
/// fit the fitting blocks 33 % worse than no lag at all, and nothing was found; from the
/// 1 ms start (diagnose::select::LAG_STARTS_S) the lag fits better than the model without
/// it, predicts the held-out blocks better, and comes out near the generated value.
#[test]
fn a_field_lag_shorter_than_a_sample_interval_is_found() {
    let (m, d) = generate_and_diagnose(324);
    assert_eq!(hidden_effects(&m), ["field_lag"], "the scenario changed");
    let dt_ms = 1e3 / m["excitation"]["fs_hz"].as_f64().unwrap();
    let truth_ms = m["effects"][0]["parameters"]["effective_tau_s"]
        .as_f64()
        .unwrap()
        * 1e3;
    assert!(
        truth_ms < dt_ms,
        "the scenario changed: {truth_ms} ms lag, {dt_ms} ms samples"
    );
    assert_eq!(found_effects(&d), ["field_lag"], "{}", d["trials"]);
    let lag = entry_of(&d["findings"], "field_lag");
    let bic = lag["evidence"]["delta_bic"].as_f64().unwrap();
    assert!(bic < 0.0, "the lag fits worse than no lag: ΔBIC {bic:.1}");
    let (v, ci) = finding_parameter(&d, "field_lag", "field_time_constant");
    eprintln!("lag {v:.2} ms, interval {ci:?}, generated {truth_ms:.2} ms, samples {dt_ms} ms");
    // The model's lag acts on the current between the grid's points; the generator's on
    // its 40× finer grid: within a quarter of the generated value.
    assert!(
        (v / truth_ms - 1.0).abs() < 0.25,
        "lag {v:.2} ms against {truth_ms:.2} ms"
    );
}

/// A lag shorter than one step of the model's sub-sample grid is not a finding
/// (proving-ground seed 780: a fluid mass hidden, no lag, 200 Hz, current stepped). With
/// the 1 ms start the lag candidate reached 0.22 ms, 0.04 of the sample interval, and beat
/// its bootstrap null beside the mass; so short a lag acts within the sub-interval that
/// holds a current step, as moving the step would (diagnose::select::lag_resolved). The
/// mass alone is found, and the lag's detection limit is that step.
#[test]
fn a_lag_shorter_than_a_step_of_the_sub_sample_grid_is_not_a_finding() {
    let (m, d) = generate_and_diagnose(780);
    assert_eq!(
        hidden_effects(&m),
        ["fluid_inertia"],
        "the scenario changed"
    );
    assert_eq!(found_effects(&d), ["fluid_inertia"], "{}", d["trials"]);
    let dt_ms = 1e3 / m["excitation"]["fs_hz"].as_f64().unwrap();
    let short = d["trials"].as_array().unwrap().iter().any(|t| {
        t["effect"] == "field_lag"
            && t["parameters"]["field_time_constant"]["value"]
                .as_f64()
                .unwrap()
                < dt_ms / 8.0
            && t["passed"][1].as_bool().unwrap()
    });
    assert!(short, "no short lag was tried here: {}", d["trials"]);
    let limit = d["detection_limits"]
        .as_array()
        .unwrap()
        .iter()
        .find(|l| l["effect"] == "field_lag")
        .expect("a lag limit");
    assert_eq!(limit["rule"], "resolved lag", "{limit}");
    assert!(
        (limit["limit"].as_f64().unwrap() - dt_ms / 8.0).abs() < 1e-6,
        "{limit}"
    );
}

/// A knot whose viscous coefficient runs away takes its neighbours' (proving-ground null
/// seed 154: a bi-viscous fluid of viscosity ratio 420 under random held currents, 1.5 s
/// per level). At 0.586 A and 1.338 A the strokes never leave the fluid's pre-yield ramp,
/// and the fit took c = 2.1·10⁷ and 1.5·10⁷ N s/m beside F_y of 24 and 40 N: a straight
/// line through the origin, which fits those samples as well as the fluid's own c beside a
/// yield force the stroke never reached, and predicts the held-out strokes at 13.2 σ_F.
/// Held at the neighbours' c (diagnose::model::hold_unidentified_viscous, kept because it
/// predicts no worse) it predicts them at 9.3 σ_F. The knots stay named, with the value
/// they were given; no knot of the baseline is left past the limit; nothing is found.
/// Run with the yield force on straight lines between the knots (`--yield-curve lines`,
/// the default until session 80): on the cubic curve, which `--yield-curve auto` keeps
/// here, no knot of this record runs away (baseline 5.8 σ_F), and the hold, which does not
/// depend on the curve, would go untested.
#[test]
fn a_knot_whose_viscous_coefficient_runs_away_takes_its_neighbours() {
    let (m, d, _) = generate_and_diagnose_as(154, false, &["--yield-curve", "lines"]);
    assert_null(154, &m);
    assert_eq!(d["yield_curve"], "lines");
    assert_reports_nothing(154, &d);
    let sigma_f = m["sigma_F_N"].as_f64().unwrap();
    let held_out = d["baseline"]["holdout_rmse_N"].as_f64().unwrap();
    let knots = d["unidentified_knots"].as_array().unwrap();
    eprintln!("held-out {:.2} σ_F; {knots:#?}", held_out / sigma_f);
    let held: Vec<&str> = knots
        .iter()
        .map(|k| k["why"].as_str().unwrap())
        .filter(|w| w.contains("held at its neighbours'"))
        .collect();
    assert_eq!(held.len(), 2, "{knots:#?}");
    // Every knot's viscous force at the record's peak speed is now below 100 times the
    // record's peak force (the peak force and speed as the report states them).
    let why = held[0];
    let number_before = |tag: &str| -> f64 {
        let at = why.find(tag).expect(tag);
        why[..at]
            .rsplit(' ')
            .find(|w| !w.is_empty())
            .unwrap()
            .parse()
            .expect("a number")
    };
    let (peak_force, peak_speed) = (number_before(" N at its peak"), number_before(" m/s"));
    let params = d["baseline_parameters"].as_object().unwrap();
    for (name, value) in params.iter().filter(|(n, _)| n.ends_with("_viscous_N_s_m")) {
        let cv = value.as_f64().unwrap() * peak_speed;
        assert!(cv < 100.0 * peak_force, "{name}: c V = {cv:.3e} N");
    }
    assert!(
        held_out < 11.0 * sigma_f,
        "baseline held-out {:.2} σ_F (13.2 with the runaway knots)",
        held_out / sigma_f
    );
}

/// A knot whose fitting samples never show the fluid yielding is started again from its
/// neighbours' yield force (proving-ground null seed 491: a Papanastasiou fluid under
/// three held currents, 1.00, 1.27 and 1.63 A). Fitted from the record's own start, the
/// knots at 1.27 and 1.63 A put F_y at 36 and 31 N, under the 1.5 and 1.4 kN their fitting
/// samples reach, and let the pre-yield leak carry the force: the held-out blocks were
/// predicted at 2.15 σ_F. Started from their neighbours' (diagnose::model::
/// hold_unyielded_knots) and refitted free, they settle at 1.79 and 1.92 kN, the fitting
/// RMS falls (18.9 → 17.6 N, which is what keeps the second start) and the held-out blocks,
/// which decide nothing here, fall to 1.23 σ_F. The knots are named with the values they
/// had; the yield force rises with the current as a fluid's does; nothing is found.
#[test]
fn a_knot_whose_fitting_samples_never_yield_is_refitted_from_its_neighbours_yield_force() {
    let (m, d) = generate_null_and_diagnose(491);
    assert_reports_nothing(491, &d);
    let sigma_f = m["sigma_F_N"].as_f64().unwrap();
    let held_out = d["baseline"]["holdout_rmse_N"].as_f64().unwrap();
    let knots = d["unidentified_knots"].as_array().unwrap();
    eprintln!("held-out {:.2} σ_F; {knots:#?}", held_out / sigma_f);
    let currents = current_knots(&d);
    let fy: Vec<f64> = (0..currents.len())
        .map(|q| knot_parameter(&d, q, "yield_force_N"))
        .collect();
    let restarted: Vec<(f64, f64)> = knots
        .iter()
        .filter(|k| {
            k["why"]
                .as_str()
                .unwrap()
                .contains("not fixed by its fitting samples")
        })
        .map(|k| {
            (
                k["current_a"].as_f64().unwrap(),
                k["yield_force_n"].as_f64().unwrap(),
            )
        })
        .collect();
    assert_eq!(restarted.len(), 2, "{knots:#?}");
    for (current, before) in restarted {
        let q = currents
            .iter()
            .position(|c| (c - current).abs() < 1e-9)
            .expect("a knot of the split");
        assert!(
            q > 0 && before < 0.1 * fy[q],
            "the {current:.3} A knot had {before:.0} N and has {:.0} N",
            fy[q]
        );
    }
    for q in 1..fy.len() {
        assert!(
            currents[q] > currents[q - 1] && fy[q] >= fy[q - 1],
            "yield force falls with the current: {currents:?} {fy:?}"
        );
    }
    assert!(
        held_out < 1.5 * sigma_f,
        "baseline held-out {:.2} σ_F (2.15 from the record's own start)",
        held_out / sigma_f
    );
}

/// A knot whose viscous coefficient and speed curvature both stand apart from the other
/// knots' is started again from its neighbours' (proving-ground seed 402: a thermal
/// softening hidden, 10 held currents). Fitted from the record's own start the 0.736 A
/// knot took c = 5.2 kN s/m, against 0.6–0.7 kN s/m at every other knot, beside
/// c₂ = −10.8 kN: the pair fits its fitting strokes, and its two held-out blocks were
/// predicted at 381 and 423 N RMS against 16–20 N elsewhere (baseline 18.0 σ_F). Started
/// from its neighbours' (diagnose::model::hold_outlier_viscous) and refitted free, it fits
/// the fitting blocks a little better (15.24 → 15.23 N, which is what keeps it) and the
/// held-out blocks, which decide nothing here, at 1.43 σ_F. The knot is named with the
/// values it had; nothing that is not hidden is found.
#[test]
fn a_knot_whose_viscous_coefficient_and_curvature_stand_apart_is_started_again() {
    let (m, d) = generate_and_diagnose(402);
    assert_eq!(
        hidden_effects(&m),
        ["thermal_softening"],
        "the scenario changed"
    );
    let found = found_effects(&d);
    assert!(
        found.iter().all(|f| *f == "thermal_softening"),
        "false findings: {found:?}"
    );
    let sigma_f = m["sigma_F_N"].as_f64().unwrap();
    let held_out = d["baseline"]["holdout_rmse_N"].as_f64().unwrap();
    let knots = d["unidentified_knots"].as_array().unwrap();
    eprintln!("held-out {:.2} σ_F; {knots:#?}", held_out / sigma_f);
    let apart: Vec<f64> = knots
        .iter()
        .filter(|k| k["why"].as_str().unwrap().contains("stand apart"))
        .map(|k| k["current_a"].as_f64().unwrap())
        .collect();
    assert_eq!(apart.len(), 1, "{knots:#?}");
    assert!((apart[0] - 0.736).abs() < 0.005, "{apart:?}");
    // The knot's viscous coefficient is now of its neighbours' size.
    let q = current_knots(&d)
        .iter()
        .position(|c| (c - apart[0]).abs() < 1e-9)
        .unwrap();
    let c = |q: usize| knot_parameter(&d, q, "viscous_N_s_m");
    let (below, at, above) = (c(q - 1), c(q), c(q + 1));
    assert!(
        at < 2.0 * below.max(above),
        "c {below:.0}, {at:.0}, {above:.0} N s/m"
    );
    assert!(
        held_out < 3.0 * sigma_f,
        "baseline held-out {:.2} σ_F (18.0 from the record's own start)",
        held_out / sigma_f
    );
}

/// The yield force between the knots of a grid on the curve that fits it (`--yield-curve
/// auto`, the default since session 80): the baseline is settled on the cubic curve and on
/// straight lines, and the lower fitting RMS is kept. Two validation nulls of the
/// proving ground, each diagnosed by default and on the other curve:
/// - seed 314 (a bi-viscous fluid of viscosity ratio 125 under a random current, 16 s of
///   1 kHz random strokes): on lines one held-out block was at 13.5 σ_F and all five at
///   6.2 σ_F; the curve fits better (4.32 N against 4.42) and predicts them at 1.38 σ_F;
/// - seed 440 (bi-viscous, ratio 136, 500 Hz random strokes): on the curve the baseline
///   ended in another leak basin, fitting at 20.2 N against 12.9 N on lines, and predicted
///   the held-out blocks at 3.32 σ_F against 1.33. Since session 83 the curve's knots whose
///   fitting samples never reach their yield force are started again from their
///   neighbours' (diagnose::model::hold_unyielded_knots): it fits at 14.8 N and predicts
///   at 1.39 σ_F, still behind the lines.
///
/// Each default run names the curve it kept and both fitting RMS values, reports nothing,
/// and predicts the held-out blocks under 2 σ_F and better than the other curve does
/// (314: under half).
#[test]
fn a_random_currents_yield_force_follows_the_curve_that_fits_between_the_knots() {
    for (seed, kept, other, share) in [(314, "cubic", "lines", 0.5), (440, "lines", "cubic", 1.0)] {
        let (m, d) = generate_null_and_diagnose(seed);
        let (_, alt, _) = generate_and_diagnose_as(seed, false, &["--yield-curve", other]);
        assert_eq!(
            d["yield_curve"], kept,
            "seed {seed}: {}",
            d["yield_curve_fits"]
        );
        assert_eq!(alt["yield_curve"], other);
        let fit = |c: &str| d["yield_curve_fits"][c].as_f64().unwrap();
        assert!(
            fit(kept) < fit(other),
            "seed {seed}: {}",
            d["yield_curve_fits"]
        );
        // The fitting RMS stated for the curve kept is the baseline's.
        let base_fit = d["baseline"]["train_rmse_N"].as_f64().unwrap();
        assert!(
            (base_fit - fit(kept)).abs() <= 1e-9 * base_fit,
            "seed {seed}"
        );
        assert_reports_nothing(seed, &d);
        let sigma_f = m["sigma_F_N"].as_f64().unwrap();
        let held_out = |d: &serde_json::Value| d["baseline"]["holdout_rmse_N"].as_f64().unwrap();
        let (by_default, by_other) = (held_out(&d), held_out(&alt));
        eprintln!(
            "seed {seed}: baseline held-out {kept} {:.2} σ_F, {other} {:.2} σ_F",
            by_default / sigma_f,
            by_other / sigma_f
        );
        assert!(
            by_default < 2.0 * sigma_f,
            "seed {seed}: {:.2} σ_F",
            by_default / sigma_f
        );
        assert!(
            by_default < share * by_other,
            "seed {seed}: {kept} {by_default:.1} N against {other} {by_other:.1} N"
        );
    }
}

/// A knot fitted on slow strokes only takes its neighbours' speed curvature
/// (proving-ground null seed 178: a Herschel–Bulkley fluid under random held currents,
/// sines to 0.5 m/s). The 1.403 A knot's fitting strokes reach 0.07 m/s and its held-out
/// ones 0.22 m/s; fitted free, its curvature c₂ ran to 11.6 kN and those strokes were
/// predicted 1.1 kN over the force (baseline held-out 1.97 σ_F). Held at the curvature
/// of the knots fitted at speed (diagnose::model::hold_unreached_curvature, kept because
/// it predicts no worse) the baseline predicts them at 1.06 σ_F. The report names the
/// knots, each fitted to under half the speed asked of it, with the curvature the model
/// uses; nothing is found.
#[test]
fn a_knot_fitted_on_slow_strokes_takes_its_neighbours_speed_curvature() {
    let (m, d) = generate_null_and_diagnose(178);
    assert_reports_nothing(178, &d);
    let sigma_f = m["sigma_F_N"].as_f64().unwrap();
    let held_out = d["baseline"]["holdout_rmse_N"].as_f64().unwrap();
    let slow = d["slow_knots"].as_array().unwrap();
    eprintln!("held-out {:.2} σ_F; {slow:#?}", held_out / sigma_f);
    let knots = current_knots(&d);
    let field = |k: &serde_json::Value, name: &str| k[name].as_f64().unwrap();
    for k in slow {
        assert!(
            field(k, "reach_m_s") < 0.5 * field(k, "asked_m_s"),
            "named but not slow: {k}"
        );
        // The curvature named is the one the baseline uses at that knot.
        let q = knots
            .iter()
            .position(|c| (c - field(k, "current_a")).abs() < 1e-9)
            .expect("a knot of the split");
        let used = d["baseline_parameters"][format!("knot{q}_curvature_N")]
            .as_f64()
            .unwrap();
        assert_eq!(used, field(k, "curvature_n"), "knot {q}");
    }
    assert!(
        slow.iter()
            .any(|k| (field(k, "current_a") - 1.403).abs() < 0.005),
        "the 1.403 A knot (fitted to 0.07 m/s, held out at 0.22 m/s) is not held: {slow:#?}"
    );
    assert!(
        held_out < 1.3 * sigma_f,
        "baseline held-out {:.2} σ_F (1.97 with the knot's own curvature)",
        held_out / sigma_f
    );
}

/// A 500 Hz record behind a 0.27 f_s anti-alias filter (proving-ground null seed 238: a
/// Herschel–Bulkley fluid, multisine strokes). The filter spreads each reversal's 2 F_y
/// jump over the samples around it, so the sample just before or after a reversal sits on
/// the jump's edge though its own velocity is far from zero, and the rebuilt velocity's
/// error moves the instant of reversal: the baseline missed such samples by 600–900 N
/// (σ_F 28 N) at weight ≈ 1, and 8 of 2 493 held-out samples put it at 1.42 σ_F. Its
/// weights now count the error through the filter (diagnose::model, a velocity error
/// common to neighbouring samples): those samples lose their weight, samples away from a
/// reversal keep theirs, and the baseline comes within 15 % of the noise.
#[test]
// Each sample is compared with its neighbours by index: a range loop is clearer.
#[allow(clippy::needless_range_loop)]
fn a_sample_on_the_filtered_edge_of_a_reversal_is_weighted_by_its_timing_error() {
    let (m, d, residuals) = generate_and_diagnose_with_residuals(238);
    assert_null(238, &m);
    assert_reports_nothing(238, &d);
    let kappa = d["measurement"]["velocity_error_scale"].as_f64().unwrap();
    let mut lines = residuals.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).expect(name);
    let (iv, is, iw, ir) = (
        col("velocity_m_s"),
        col("velocity_sigma_m_s"),
        col("weight"),
        col("role"),
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let num = |j: usize, c: usize| rows[j][c].parse::<f64>().unwrap();
    let (mut edge, mut away) = (Vec::new(), Vec::new());
    for j in 3..rows.len() - 3 {
        let v = num(j, iv);
        // The sample's own sign is certain (a flip is a 5 σ event): alone, its force is.
        if rows[j][ir] == "excluded" || v.abs() <= 5.0 * kappa * num(j, is) {
            continue;
        }
        if v * num(j + 1, iv) < 0.0 || v * num(j - 1, iv) < 0.0 {
            edge.push(num(j, iw));
        } else if (j - 3..=j + 3).all(|i| v * num(i, iv) > 0.0) {
            away.push(num(j, iw));
        }
    }
    let median = |w: &mut Vec<f64>| {
        w.sort_by(f64::total_cmp);
        w[w.len() / 2]
    };
    let (n_edge, n_away) = (edge.len(), away.len());
    let (edge, away) = (median(&mut edge), median(&mut away));
    let sigma_f = m["sigma_F_N"].as_f64().unwrap();
    let held_out = d["baseline"]["holdout_rmse_N"].as_f64().unwrap();
    eprintln!(
        "κ {kappa}: median weight {edge:.3} on {n_edge} samples next to a reversal, \
         {away:.3} on {n_away} away from one; held-out {:.2} σ_F",
        held_out / sigma_f
    );
    assert!(n_edge >= 20, "{n_edge} samples next to a reversal");
    // Without the filter's share they weighed 0.97 (median), as much as any other.
    assert!(edge < 0.3, "samples on the jump's edge keep weight {edge}");
    assert!(
        away > 0.95,
        "samples away from a reversal lost weight: {away}"
    );
    assert!(
        held_out < 1.15 * sigma_f,
        "baseline held-out {:.2} σ_F (1.42 before)",
        held_out / sigma_f
    );
}

/// A record whose fitting blocks do not pin a knot down (proving-ground null seed 81: a
/// bi-viscous fluid, viscosity ratio 470, under a random current on eight knots; the
/// 0.935 A knot's viscous coefficient runs to about 10⁹ N s/m, where its force is carried by
/// the pre-yield ramp). The report must say so (`unidentified_knots`), not only carry a
/// large held-out RMS, and a real damper's knots must not be flagged. (Until 2026-11-27 this
/// was null 212, whose two knots ran to 1.9·10⁸ N and 2·10¹⁰ N s/m; the baseline's other
/// leak basin now predicts it, model::better_basin, and pins both.)
#[test]
fn knots_a_record_does_not_identify_are_named() {
    let (_, d) = generate_null_and_diagnose(81);
    assert_reports_nothing(81, &d);
    let knots = d["unidentified_knots"].as_array().unwrap();
    eprintln!("{knots:#?}");
    let currents: Vec<f64> = knots
        .iter()
        .map(|k| k["current_a"].as_f64().unwrap())
        .collect();
    assert!(
        currents.iter().any(|i| (i - 0.935).abs() < 0.01),
        "the 0.935 A knot is not named: {knots:?}"
    );
    for k in knots {
        let why = k["why"].as_str().unwrap();
        assert!(why.contains("times the record's peak force"), "{why}");
    }
    // Seed 41 (a Bingham null at 2 kHz, held currents) identifies all its knots.
    let (_, d41) = generate_null_and_diagnose(41);
    assert!(
        d41["unidentified_knots"].as_array().unwrap().is_empty(),
        "{}",
        d41["unidentified_knots"]
    );
}

/// The detection-limit row of `effect` in a diagnosis: the one with a limit (presliding,
/// for a friction) or, with `step`, a friction's step without presliding.
fn limit_row<'a>(d: &'a serde_json::Value, effect: &str, step: bool) -> &'a serde_json::Value {
    d["detection_limits"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["effect"] == effect && r["limit"].is_null() == step)
        .unwrap_or_else(|| panic!("no limit row for {effect}: {}", d["detection_limits"]))
}

/// A Stribeck seal friction (proving-ground seed 31: 2.5 σ_F of force RMS) is a field-off
/// yield at every current: the generator's own projection onto a yield step and a viscous
/// term per current level leaves 0.10 σ_F of it. It is not found, and the report says why:
/// its detection limits give a step without presliding no limit and an absorbed share at
/// the generator's own figure, computed independently (diagnose::limits).
#[test]
fn a_friction_the_fluids_yield_absorbs_is_not_found_and_the_limits_say_why() {
    let (m, d) = generate_and_diagnose(31);
    assert_eq!(
        hidden_effects(&m),
        ["seal_friction"],
        "the scenario changed"
    );
    let hidden = entry_of(&m["effects"], "seal_friction");
    assert_eq!(
        hidden["parameters"]["kind"], "stribeck",
        "the scenario changed"
    );
    assert!(found_effects(&d).is_empty(), "{}", d["findings"]);
    let unabsorbed =
        hidden["u_unabsorbed"].as_f64().unwrap() / hidden["u_achieved"].as_f64().unwrap();
    let generator_absorbed = 1.0 - unabsorbed * unabsorbed;
    let step = limit_row(&d, "seal_friction", true);
    let absorbed = step["absorbed_share"].as_f64().unwrap();
    assert!(
        generator_absorbed > 0.99 && absorbed > 0.99,
        "absorbed: diagnose {absorbed}, the generator {generator_absorbed}"
    );
    assert!(
        step["rule"].as_str().unwrap().contains("never reported"),
        "{step}"
    );
}

/// Within one record, the null twin's detection limits place each hidden effect about where
/// the selection finds it (proving-ground seed 65: a polytropic gas spring at 7.2 times its
/// null twin's limit; a Dahl seal friction at 0.83 times it and a thermal softening at 1.7
/// times it, both near the limit, where a test at its threshold finds an effect about half
/// the time). The generator's effects are not the candidates' shapes, so this is the
/// limit's linearisation of diagnose's own candidates read against independent physics.
/// (Until the force noise was read from the baseline's residual too, the limits were
/// higher: gas 5.6, friction 0.64 and thermal 1.3 times them, and the friction was not
/// found; it now is, and the set is exact.)
#[test]
fn the_null_twins_detection_limits_predict_what_the_record_shows() {
    let (m, d) = generate_and_diagnose(65);
    let (_, twin) = generate_null_twin_and_diagnose(65);
    assert_eq!(
        hidden_effects(&m),
        ["gas_spring", "seal_friction", "thermal_softening"],
        "the scenario changed"
    );
    let found = found_effects(&d);
    let ratio = |effect: &str| {
        let size = entry_of(&m["effects"], effect)["rms_effect_N"]
            .as_f64()
            .unwrap();
        let limit = limit_row(&twin, effect, false)["effect_rms_N"]
            .as_f64()
            .unwrap();
        size / limit
    };
    eprintln!(
        "gas {:.2}, friction {:.2}, thermal {:.2} × the twin's limits; found {found:?}",
        ratio("gas_spring"),
        ratio("seal_friction"),
        ratio("thermal_softening")
    );
    let q = ratio("gas_spring");
    assert!(q > 2.0, "gas spring at {q} times its twin's limit");
    for effect in ["seal_friction", "thermal_softening"] {
        let q = ratio(effect);
        assert!(
            (0.5..2.0).contains(&q),
            "{effect} at {q} × its twin's limit"
        );
    }
    assert_eq!(
        found,
        ["gas_spring", "seal_friction", "thermal_softening"],
        "the limits put every effect within reach"
    );
    // So near its limit the softening is the one factor: the viscous softening it reports
    // says it is the yield force's, not a measurement of its own.
    let viscous = &entry_of(&d["findings"], "thermal_softening")["parameters"]
        ["viscous_softening_per_energy"];
    assert_eq!(viscous["tied_to"], "softening_per_energy", "{viscous}");
}
