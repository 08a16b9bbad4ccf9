//! End-to-end tests of the `mrtwin` binary.
//!
//! They live in the `mrtwin` package (not in `mrtwin-tests`) because Cargo builds a
//! package's binaries before its integration tests and tells them where the binary is
//! through `CARGO_BIN_EXE_mrtwin`; other packages get neither guarantee.

use std::fs;
use std::path::Path;
use std::process::Output;

use mrtwin_tests::TempDir;

/// Run `mrtwin` with `args`.
fn mrtwin<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Output {
    mrtwin_tests::run(env!("CARGO_BIN_EXE_mrtwin"), args)
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Assert success, showing stderr otherwise.
fn ok(o: &Output) {
    assert!(o.status.success(), "mrtwin failed: {}", stderr(o));
}

/// Assert failure with exit code 1 and an `error:` message; return stderr.
fn fails(o: &Output) -> String {
    let err = stderr(o);
    assert_eq!(
        o.status.code(),
        Some(1),
        "expected exit code 1; stderr: {err}"
    );
    assert!(err.starts_with("error: "), "stderr: {err}");
    err
}

/// A short two-chamber run: 2 segments of 0.5 s at 1000 Hz.
fn short_run(out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "simulate",
        "--model",
        "two-chamber",
        "--frequency",
        "1.66,3.33",
        "--current",
        "1",
        "--duration",
        "0.5",
        "--rate",
        "1000",
        "--out",
    ];
    let out = out.to_str().expect("temporary path is UTF-8");
    args.push(out);
    args.extend_from_slice(extra);
    mrtwin(&args)
}

#[test]
fn help_lists_every_subcommand() {
    let o = mrtwin(&["--help"]);
    ok(&o);
    let text = stdout(&o);
    for sub in ["simulate", "yield-stress", "paper"] {
        assert!(
            text.lines().any(|l| l.trim_start().starts_with(sub)),
            "{sub} missing from --help:\n{text}"
        );
    }
}

#[test]
fn yield_stress_json_matches_the_paper() {
    let o = mrtwin(&[
        "yield-stress",
        "--current",
        "1",
        "--temperature",
        "25",
        "--gap",
        "0.7e-3",
        "--shear-rate",
        "73",
        "--json",
    ]);
    ok(&o);
    let v: serde_json::Value = serde_json::from_str(stdout(&o).trim()).expect("one JSON object");
    let tau0 = v["tau0_Pa"].as_f64().expect("tau0_Pa");
    assert!((tau0 / 364.6e3 - 1.0).abs() < 5e-3, "tau0 = {tau0}");
    let n = v["n"].as_f64().expect("n");
    assert!((n - 0.2775).abs() < 1e-12, "n = {n}");
    let r0 = v["R0"].as_f64().expect("R0");
    assert!((r0 / (6.48 / 0.7e-3 * 1e3) - 1.0).abs() < 1e-9, "R0 = {r0}");
    assert_eq!(v["R0_unit"], "Pa");
}

#[test]
fn yield_stress_human_output_and_defaults() {
    let o = mrtwin(&["yield-stress", "--current", "1", "--shear-rate", "73"]);
    ok(&o);
    let text = stdout(&o);
    assert!(text.starts_with("tau0 = 364."), "{text}");
    assert!(
        text.contains("n = 0.2775") && text.contains("R0 = 9257.1 kPa"),
        "{text}"
    );
    assert!(
        text.contains("h = 0.7 mm") && text.contains("t = 25 °C"),
        "{text}"
    );
}

#[test]
fn yield_stress_rejects_out_of_range_inputs() {
    for (flag, value) in [
        ("--gap", "0"),
        ("--gap", "-1e-3"),
        ("--shear-rate", "0"),
        ("--shear-rate", "-5"),
        ("--shear-rate", "2e6"),
    ] {
        let mut args = vec!["yield-stress", "--current", "1", flag, value];
        if flag != "--shear-rate" {
            args.extend(["--shear-rate", "73"]);
        }
        let err = fails(&mrtwin(&args));
        assert!(err.contains(flag), "{flag} {value}: {err}");
    }
}

#[test]
fn simulate_writes_a_readable_csv() {
    let dir = TempDir::new("simulate_writes_a_readable_csv");
    let csv = dir.path("sub/run.csv");
    let o = short_run(&csv, &[]);
    ok(&o);
    let summary = stderr(&o);
    assert!(
        summary.contains("two-chamber") && summary.contains("1000 samples"),
        "{summary}"
    );

    let text = fs::read_to_string(&csv).expect("CSV written");
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("time_s,displacement_m,velocity_m_s,force_N,current_A,temperature_C")
    );
    assert_eq!(lines.count(), 1000);

    let rec = bridge::csv::read_csv(&csv).expect("bridge reads it back");
    assert_eq!(rec.len(), 1000);
    assert!(rec.has_temperature && !rec.velocity_derived);
    let first = rec.samples[0];
    assert_eq!(
        (first.time_s, first.displacement_m, first.current_a),
        (0.0, 0.0, 1.0)
    );
    assert!(rec.samples.iter().all(|s| s.force_n.is_finite()));
}

#[test]
fn simulate_rejects_an_unknown_model() {
    let dir = TempDir::new("simulate_rejects_an_unknown_model");
    let out = dir.path("x.csv");
    let err = fails(&mrtwin(&[
        "simulate".as_ref(),
        "--model".as_ref(),
        "bouc-wen-9000".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]));
    assert!(err.contains("'bouc-wen-9000'"), "{err}");
    for name in ["bingham", "spencer", "direct-shear", "two-chamber"] {
        assert!(err.contains(name), "{name} not listed: {err}");
    }
    assert!(!out.exists());
}

#[test]
fn simulate_rejects_an_unknown_effect() {
    let dir = TempDir::new("simulate_rejects_an_unknown_effect");
    let err = fails(&short_run(
        &dir.path("x.csv"),
        &["--effects", "gas_spring,magic_smoke"],
    ));
    assert!(
        err.contains("'magic_smoke'") && err.contains("--effects"),
        "{err}"
    );
}

#[test]
fn simulate_rejects_effects_on_bingham() {
    let dir = TempDir::new("simulate_rejects_effects_on_bingham");
    let out = dir.path("x.csv");
    let err = fails(&mrtwin(&[
        "simulate".as_ref(),
        "--model".as_ref(),
        "bingham".as_ref(),
        "--effects".as_ref(),
        "seal_friction".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]));
    assert!(
        err.contains("bingham") && err.contains("seal_friction"),
        "{err}"
    );
}

#[test]
fn simulate_reports_unknown_keys_in_the_params_file() {
    let dir = TempDir::new("simulate_reports_unknown_keys_in_the_params_file");
    let params = dir.path("stand.yaml");
    fs::write(
        &params,
        "mrtwin_stand:\n  ros__parameters:\n    two_chamber:\n      bulk_modulus_pa: 5.0e8\n      gas_preload_pq: 2.0e6\n",
    )
    .expect("write params");
    let params_arg = params.to_str().expect("UTF-8 path");
    let err = fails(&short_run(&dir.path("x.csv"), &["--params", params_arg]));
    assert!(err.contains(params_arg), "file not named: {err}");
    assert!(err.contains("gas_preload_pq"), "key not named: {err}");
    assert!(err.contains("line 5"), "line not named: {err}");
}

/// At the first sample the compressible two-chamber model is at rest: F = −p0 Ar.
#[test]
fn flags_override_the_params_file_which_overrides_defaults() {
    let dir = TempDir::new("flags_override_the_params_file");
    let params = dir.path("stand.yaml");
    fs::write(
        &params,
        "mrtwin_stand:\n  ros__parameters:\n    two_chamber:\n      gas_preload_pa: 1.0e6\n",
    )
    .expect("write params");
    let params_arg = params.to_str().expect("UTF-8 path");
    let rod_area = std::f64::consts::PI * 0.25 * 0.010_f64.powi(2);
    let first_force = |extra: &[&str]| {
        let csv = dir.path("run.csv");
        ok(&short_run(&csv, extra));
        bridge::csv::read_csv(&csv).expect("read back").samples[0].force_n
    };
    let cases: [(&[&str], f64); 3] = [
        (&[], 2.0e6),
        (&["--params", params_arg], 1.0e6),
        (&["--params", params_arg, "--gas-preload", "3e6"], 3.0e6),
    ];
    for (extra, p0) in cases {
        let f = first_force(extra);
        assert!(
            (f / (-p0 * rod_area) - 1.0).abs() < 1e-9,
            "{extra:?}: F = {f}"
        );
    }
}

#[test]
fn same_seed_same_bytes_other_seed_other_bytes() {
    let dir = TempDir::new("same_seed_same_bytes");
    let run = |name: &str, seed: &str| {
        let csv = dir.path(name);
        ok(&short_run(&csv, &["--noise", "0.02", "--seed", seed]));
        fs::read(&csv).expect("CSV written")
    };
    let a = run("a.csv", "7");
    let b = run("b.csv", "7");
    let c = run("c.csv", "8");
    assert!(a == b, "same seed gave different files");
    assert!(a != c, "different seeds gave the same file");
}

#[test]
fn paper_writes_recordings_plots_and_summary() {
    let dir = TempDir::new("paper_writes_recordings_plots_and_summary");
    let out = dir.path("paper");
    let o = mrtwin(&[
        "paper".as_ref(),
        "--duration".as_ref(),
        "0.5".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    ok(&o);
    let table = stdout(&o);
    assert!(
        table.contains("direct-shear") && table.contains("two-chamber"),
        "{table}"
    );
    assert!(
        table.contains("73 1/s") && table.contains("217 1/s"),
        "{table}"
    );

    for model in ["direct-shear", "two-chamber"] {
        let rec = bridge::csv::read_csv(&out.join(format!("{model}.csv"))).expect("CSV");
        assert_eq!(rec.len(), 9 * 200, "{model}: 9 segments of 0.5 s at 400 Hz");
        for plot in ["fx", "fv"] {
            let svg = fs::read_to_string(out.join(format!("{model}-{plot}.svg"))).expect("SVG");
            assert!(
                svg.starts_with("<svg") && svg.contains("</svg>"),
                "{model}-{plot}"
            );
        }
    }
    let svg = fs::read_to_string(out.join("direct-shear-tau-gamma.svg")).expect("τ–γ SVG");
    assert!(svg.starts_with("<svg"));

    let summary: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(out.join("summary.json")).expect("summary"))
            .expect("valid JSON");
    let models = summary["models"].as_array().expect("models");
    assert_eq!(models.len(), 2);
    for m in models {
        let segments = m["segments"].as_array().expect("segments");
        assert_eq!(segments.len(), 9);
        for s in segments {
            assert!(s["peak_force_N"].as_f64().is_some_and(|f| f > 0.0), "{s}");
        }
    }
    let rows = summary["yield_stress"]["rows"].as_array().expect("τ0 rows");
    assert_eq!(rows.len(), 3);
    let tau0_1a_73 = rows[1]["tau0_Pa"][0].as_f64().expect("τ0 at 1 A, 73 1/s");
    assert!((tau0_1a_73 / 364.6e3 - 1.0).abs() < 5e-3);
}

#[test]
fn the_example_parameter_file_runs_every_effect_with_bodner_partom() {
    let dir = TempDir::new("example_params");
    let out = dir.path("bp.csv");
    let params = Path::new(env!("CARGO_MANIFEST_DIR")).join("../launch-config/examples/stand.yaml");
    let o = short_run(
        &out,
        &[
            "--params",
            params.to_str().expect("UTF-8 path"),
            "--effects",
            "all",
            "--fluid",
            "bodner-partom",
        ],
    );
    ok(&o);
    let rec = bridge::csv::read_csv(&out).expect("readable recording");
    let peak = rec
        .samples
        .iter()
        .map(|s| s.force_n.abs())
        .fold(0.0, f64::max);
    // The comment in the file promises a force near 5 kN at 1 A with its 1 mm gap.
    assert!((1.0e3..1.0e4).contains(&peak), "peak {peak} N");
}

/// Write `text` as a CSV file in a fresh temporary directory and run `mrtwin info` on it.
fn info_on(test: &str, text: &str) -> (TempDir, Output) {
    let dir = TempDir::new(test);
    let path = dir.path("rec.csv");
    fs::write(&path, text).expect("write test CSV");
    let o = mrtwin(&["info", path.to_str().expect("UTF-8 path")]);
    (dir, o)
}

#[test]
fn info_summarises_a_simulated_recording() {
    let dir = TempDir::new("info_ok");
    let csv = dir.path("tc.csv");
    ok(&short_run(&csv, &[]));
    let o = mrtwin(&["info", csv.to_str().expect("UTF-8 path")]);
    ok(&o);
    let out = stdout(&o);
    assert!(out.contains("samples       1000"), "{out}");
    assert!(out.contains("1000.0 Hz"), "{out}");
    assert!(out.contains("gaps          0"), "{out}");
}

#[test]
fn info_rejects_nan_naming_line_and_column() {
    let (_d, o) = info_on(
        "info_nan",
        "time_s,displacement_m,force_N,current_A\n0,0,1,1\n0.001,0.0001,nan,1\n",
    );
    let err = fails(&o);
    assert!(
        err.contains("rec.csv") && err.contains("line 3") && err.contains("force_N"),
        "{err}"
    );
}

#[test]
fn info_rejects_unsorted_time_naming_the_line() {
    let (_d, o) = info_on(
        "info_unsorted",
        "time_s,displacement_m,force_N,current_A\n0,0,1,1\n0.002,0,1,1\n0.001,0,1,1\n",
    );
    let err = fails(&o);
    assert!(err.contains("line 4"), "{err}");
}

#[test]
fn info_rejects_a_missing_column_naming_it() {
    let (_d, o) = info_on("info_missing", "time_s,displacement_m,current_A\n0,0,1\n");
    let err = fails(&o);
    assert!(err.contains("force_N"), "{err}");
}
