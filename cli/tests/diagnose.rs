//! End-to-end tests of `mrtwin diagnose`: JSON shape, report and plots, exit code 0 with
//! and without findings, bad input rejected with a clear message.

use std::fs;
use std::path::Path;
use std::process::Output;

use mrtwin_tests::TempDir;

use bridge::csv::{write_csv, Recording, Sample};
use diagnose::study::{generate, Scenario, YieldLaw};
use twin::Effect;

fn mrtwin<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Output {
    mrtwin_tests::run(env!("CARGO_BIN_EXE_mrtwin"), args)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Write the study recording of `scn` (seed 7) as CSV.
fn write_scenario(scn: &Scenario, path: &Path) {
    let (sig, _) = generate(scn, 7);
    let samples = (0..sig.time_s.len())
        .map(|k| Sample {
            time_s: sig.time_s[k],
            displacement_m: sig.displacement_m[k],
            velocity_m_s: sig.velocity_m_s[k],
            force_n: sig.force_n[k],
            current_a: sig.current_a[k],
            temperature_c: None,
        })
        .collect();
    let rec = Recording {
        samples,
        velocity_derived: false,
        has_temperature: false,
        source: scn.name.clone(),
    };
    write_csv(path, &rec).expect("cannot write the test recording");
}

/// Nothing hidden: current steps without lag, a saturating yield curve.
fn null_scenario() -> Scenario {
    Scenario {
        name: "null".into(),
        hidden: vec![],
        yield_law: YieldLaw::Saturating,
    }
}

fn json(path: &Path) -> serde_json::Value {
    let text = fs::read_to_string(path).expect("JSON written");
    serde_json::from_str(&text).expect("valid JSON")
}

#[test]
fn finds_field_lag_with_json_report_and_plots() {
    let dir = TempDir::new("lag");
    let csv = dir.path("lag.csv");
    write_scenario(&Scenario::hidden(Effect::FieldLag), &csv);
    let (out_json, out_md, plots) = (dir.path("d.json"), dir.path("d.md"), dir.path("plots"));
    let out_html = dir.path("d.html");
    let out_res = dir.path("r.csv");
    let o = mrtwin(&[
        "diagnose".as_ref(),
        csv.as_os_str(),
        "--json".as_ref(),
        out_json.as_os_str(),
        "--report".as_ref(),
        out_md.as_os_str(),
        "--plots".as_ref(),
        plots.as_os_str(),
        "--html".as_ref(),
        out_html.as_os_str(),
        "--residuals".as_ref(),
        out_res.as_os_str(),
    ]);
    assert_eq!(o.status.code(), Some(0), "stderr: {}", stderr(&o));
    let j = json(&out_json);
    check_residuals_csv(&out_res, &j);
    assert_eq!(j["samples"], 30_000);
    assert!(j["input"].as_str().unwrap().ends_with("lag.csv"));
    for key in ["train_rmse_N", "holdout_rmse_N"] {
        assert!(j["baseline"][key].as_f64().unwrap() > 0.0);
        assert!(j["final"][key].as_f64().unwrap() > 0.0);
    }
    assert!(j["baseline"]["model"].is_string() && j["final"]["model"].is_string());
    let mismatch = j["mismatch"].as_array().unwrap();
    assert!(!mismatch.is_empty());
    for m in mismatch {
        assert!(m["region"].is_string() && m["description"].is_string());
        let share = m["share_of_residual_energy"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&share));
    }
    let findings = j["findings"].as_array().unwrap();
    assert_eq!(findings.len(), 1, "{findings:?}");
    let f = &findings[0];
    assert_eq!(f["effect"], "field_lag");
    assert!(f["explanation"].is_string());
    let tau = &f["parameters"]["field_time_constant"];
    assert_eq!(tau["unit"], "ms");
    let (v, lo, hi) = (
        tau["value"].as_f64().unwrap(),
        tau["ci95"][0].as_f64().unwrap(),
        tau["ci95"][1].as_f64().unwrap(),
    );
    assert!(lo > 0.0 && lo <= v && v <= hi, "{tau}");
    let ev = &f["evidence"];
    assert!(
        ev["holdout_rmse_after_N"].as_f64().unwrap()
            < ev["holdout_rmse_before_N"].as_f64().unwrap()
    );
    assert!(ev["delta_bic"].as_f64().unwrap() < 0.0);
    check_holdout_harm(&j);
    assert!(j["undecided"].as_array().unwrap().is_empty());
    let md = fs::read_to_string(&out_md).unwrap();
    assert!(md.contains("**field_lag**"), "{md}");
    for svg in [
        "loops_force_velocity.svg",
        "loops_force_displacement.svg",
        "residual_by_phase.svg",
        "residual_over_time.svg",
    ] {
        let text = fs::read_to_string(plots.join(svg)).unwrap_or_else(|_| panic!("{svg}"));
        assert!(
            text.contains("<svg") && text.contains("final model"),
            "{svg}"
        );
    }
    check_html_report(&dir, &out_html, &md);
}

/// Every trial's `holdout_harm`, where present, names a held-out block the trial made
/// worse and one of the record's current knots, with a share of the added error in (0, 1].
fn check_holdout_harm(j: &serde_json::Value) {
    let knots: Vec<f64> = j["split"]["current_knots_a"]
        .as_array()
        .unwrap()
        .iter()
        .map(|k| k.as_f64().unwrap())
        .collect();
    let trials = j["trials"].as_array().unwrap();
    let harmed: Vec<&serde_json::Value> = trials
        .iter()
        .filter_map(|t| t["evidence"].get("holdout_harm"))
        .collect();
    for h in &harmed {
        let f = |k: &str| h[k].as_f64().unwrap_or_else(|| panic!("{k} in {h}"));
        assert!(f("rmse_after_N") > f("rmse_before_N"), "{h}");
        assert!(f("start_s") <= f("end_s"), "{h}");
        assert!(f("knot_share") > 0.0 && f("knot_share") <= 1.0, "{h}");
        assert!(
            knots.contains(&f("knot_a")),
            "{h} not at a knot of {knots:?}"
        );
        assert!(h["samples"].as_u64().unwrap() > 0, "{h}");
    }
    // Every trial that makes some block worse says so: its worst block's mean-square
    // ratio above 1 goes with a harm entry, and none without.
    for t in trials {
        let worse = t["evidence"]["holdout_worst_block_ms_ratio"]
            .as_f64()
            .unwrap()
            > 1.0;
        assert_eq!(worse, t["evidence"].get("holdout_harm").is_some(), "{t}");
    }
}

/// The HTML page of a diagnosis with a finding: one self-contained file holding the
/// report and the four plots inline, which headless Chromium renders with the plots'
/// line colours on screen.
fn check_html_report(dir: &TempDir, html: &Path, md: &str) {
    let page = fs::read_to_string(html).expect("HTML written");
    assert!(page.starts_with("<!DOCTYPE html>"));
    assert!(!html.with_extension("html.partial").exists());
    // The report's own text, rendered: every Markdown heading is an HTML heading.
    let headings: Vec<&str> = md.lines().filter_map(|l| l.strip_prefix("## ")).collect();
    assert!(headings.len() >= 3, "{md}");
    for h in &headings {
        assert!(
            page.contains(&format!("<h2>{h}</h2>")),
            "heading {h} missing"
        );
    }
    assert!(page.contains("<strong>field_lag</strong>"));
    assert!(page.contains("<table>"));
    // Self-contained: nothing fetched from elsewhere.
    for external in [
        "<script", "<link", "<img", "<iframe", "src=", "url(", "@import",
    ] {
        assert!(!page.contains(external), "the page references {external}");
    }
    assert!(!page.contains("href=\"http"));
    // The four plots inline, each with its curves and legend.
    assert_eq!(page.matches("<svg").count(), 4);
    assert_eq!(page.matches("<figcaption>").count(), 4);
    for svg in page.split("<svg").skip(1) {
        let svg = &svg[..svg.find("</svg>").expect("closed svg")];
        assert!(svg.contains("final model"), "a plot without its legend");
        assert!(svg.matches("<polyline").count() + svg.matches("<path").count() >= 2);
    }
    // Rendered by a real browser: not blank, and the plots' line colours are on screen.
    let png = dir.path("page.png");
    let (ok, _, err) = mrtwin_tests::ChildGuard::spawn(
        std::process::Command::new(chromium())
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--hide-scrollbars",
                "--window-size=1000,16000",
            ])
            .arg(format!(
                "--user-data-dir={}",
                dir.path("chromium-profile").display()
            ))
            .arg(format!("--screenshot={}", png.display()))
            .arg(format!("file://{}", html.display())),
    )
    .wait(std::time::Duration::from_secs(120));
    assert!(ok && png.exists(), "chromium failed: {err}");
    let script =
        fs::read_to_string(mrtwin_tests::repo_root().join("cli/tests/screenshot_check.py"))
            .expect("the screenshot check");
    let out = mrtwin_tests::run_python(
        &script,
        &[&png.display().to_string()],
        std::time::Duration::from_secs(60),
    );
    let m: serde_json::Value = serde_json::from_str(&out).expect("check's JSON");
    let nonwhite = m["nonwhite_fraction"].as_f64().unwrap();
    assert!(nonwhite > 0.01, "the page renders blank: {m}");
    assert!(m["colours"].as_u64().unwrap() > 100, "{m}");
    // Baseline (orange), final model (green) and measured (blue) curves.
    for (k, name) in [(0, "blue"), (1, "orange"), (2, "green")] {
        assert!(
            m["palette_pixels"][k].as_u64().unwrap() > 200,
            "no {name} curve on screen: {m}"
        );
    }
}

/// The `--residuals` CSV: one row per sample, and the report's held-out RMS (weighted, of
/// the baseline and of the final model) recomputed from its rows.
fn check_residuals_csv(path: &std::path::Path, j: &serde_json::Value) {
    let text = fs::read_to_string(path).expect("the residuals CSV");
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("time_s,velocity_m_s,velocity_sigma_m_s,current_A,force_N,baseline_N,final_N,weight,role")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len() as u64, j["samples"].as_u64().unwrap());
    let num = |r: &[&str], k: usize| r[k].parse::<f64>().expect("a number");
    for (col, key) in [(5, "baseline"), (6, "final")] {
        let (mut s, mut w) = (0.0, 0.0);
        for r in rows.iter().filter(|r| r[8] == "held_out") {
            s += num(r, 7) * (num(r, 4) - num(r, col)).powi(2);
            w += num(r, 7);
        }
        let rms = (s / w).sqrt();
        let want = j[key]["holdout_rmse_N"].as_f64().unwrap();
        assert!(
            (rms / want - 1.0).abs() < 1e-6,
            "{key}: {rms} from the CSV, {want} in the JSON"
        );
    }
    for role in ["fit", "held_out", "excluded"] {
        assert!(rows.iter().any(|r| r[8] == role), "no {role} row");
    }
    // The roles are the split's: a held-out sample the split leaves unscored is neither.
    for (role, key) in [("fit", "train_samples"), ("held_out", "holdout_samples")] {
        let rows_of = rows.iter().filter(|r| r[8] == role).count() as u64;
        assert_eq!(rows_of, j["split"][key].as_u64().unwrap(), "{role} rows");
    }
}

/// Headless Chromium: `chromium` or `chromium-browser` on PATH (scripts/setup-chromium.sh
/// installs the Debian package; scripts/test-all.sh runs it).
fn chromium() -> &'static str {
    ["chromium", "chromium-browser"]
        .into_iter()
        .find(|b| {
            std::process::Command::new(b)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
        .expect(
            "no chromium on PATH: run `bash scripts/setup-chromium.sh` (scripts/test-all.sh does)",
        )
}

#[test]
fn nothing_found_still_exits_zero() {
    let dir = TempDir::new("null");
    let csv = dir.path("null.csv");
    write_scenario(&null_scenario(), &csv);
    let out_json = dir.path("d.json");
    let o = mrtwin(&[
        "diagnose".as_ref(),
        csv.as_os_str(),
        "--json".as_ref(),
        out_json.as_os_str(),
    ]);
    assert_eq!(o.status.code(), Some(0), "stderr: {}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("nothing in the library is missing above its detection limit"),
        "{stdout}"
    );
    let j = json(&out_json);
    assert!(j["findings"].as_array().unwrap().is_empty());
    // What "nothing is missing" means on this record: a limit for every effect of the
    // library (the seal friction twice: with presliding, and as a step never reported).
    let limits = j["detection_limits"].as_array().unwrap();
    assert_eq!(limits.len(), 7, "{limits:?}");
    assert!(stdout.contains("## Detection limits"), "{stdout}");
    assert!(j["unexplained"].as_array().unwrap().is_empty());
    assert_eq!(j["selector"], "calibrated");
    assert_eq!(
        j["baseline"]["holdout_rmse_N"],
        j["final"]["holdout_rmse_N"]
    );
}

#[test]
fn bad_input_fails_with_a_clear_message() {
    let dir = TempDir::new("bad");
    // Missing file.
    let missing = dir.path("nope.csv");
    let o = mrtwin(&["diagnose".as_ref(), missing.as_os_str()]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(e.starts_with("error: ") && e.contains("nope.csv"), "{e}");
    // Missing column, named with the line.
    let csv = dir.path("bad.csv");
    fs::write(&csv, "time_s,displacement_m,force_N\n0,0,0\n0.001,0,0\n").unwrap();
    let o = mrtwin(&["diagnose".as_ref(), csv.as_os_str()]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(e.contains("current_A") && e.contains("line 1"), "{e}");
    // Valid CSV but far too short to diagnose.
    let mut text = String::from("time_s,displacement_m,velocity_m_s,force_N,current_A\n");
    for k in 0..50 {
        let t = k as f64 * 0.001;
        text.push_str(&format!("{t},{},{},{},1\n", 0.01 * t, 0.01, 10.0));
    }
    fs::write(&csv, text).unwrap();
    let o = mrtwin(&["diagnose".as_ref(), csv.as_os_str()]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("cannot diagnose") && e.contains("only 50 samples"),
        "{e}"
    );
    // Unknown baseline.
    let o = mrtwin(&[
        "diagnose".as_ref(),
        csv.as_os_str(),
        "--baseline".as_ref(),
        "spencer".as_ref(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("unknown baseline 'spencer'"));
}

/// The broadband real record (Dyke's prototype damper, random strokes, a continuously
/// varying command as the current channel, the force clipped at 4545.4545 N near its end):
/// the clipped stretches are named and left out, the loop plots are drawn (they were empty
/// before), the report either finds something with a held-out gain or lists what is
/// unexplained — never a bare "nothing is missing" — and the command's lag is found.
#[test]
fn broadband_real_record_gets_plots_stuck_channels_and_an_honest_verdict() {
    let dyke =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/real/dyke-nees/ransim_u.csv");
    assert!(dyke.is_file(), "{} is missing", dyke.display());
    let dir = TempDir::new("dyke");
    let (out_json, plots) = (dir.path("d.json"), dir.path("plots"));
    let o = mrtwin(&[
        "diagnose".as_ref(),
        dyke.as_os_str(),
        "--json".as_ref(),
        out_json.as_os_str(),
        "--plots".as_ref(),
        plots.as_os_str(),
        "--replicates".as_ref(),
        "8".as_ref(),
        "--report".as_ref(),
        dir.path("d.md").as_os_str(),
    ]);
    assert_eq!(o.status.code(), Some(0), "stderr: {}", stderr(&o));
    let j = json(&out_json);
    let flats = j["measurement"]["flat_stretches"].as_array().unwrap();
    assert!(
        flats.iter().any(|f| f["channel"] == "force_N"
            && (f["value"].as_f64().unwrap() - 4545.4545).abs() < 1e-6),
        "{flats:?}"
    );
    let found = !j["findings"].as_array().unwrap().is_empty();
    let unexplained = !j["unexplained"].as_array().unwrap().is_empty();
    assert!(
        found || unexplained,
        "neither a finding nor an unexplained entry"
    );
    if found {
        assert!(
            j["final"]["holdout_rmse_N"].as_f64().unwrap()
                < j["baseline"]["holdout_rmse_N"].as_f64().unwrap()
        );
    }
    // The current channel is the driver's command voltage, which the coil current follows
    // with the driver's and the coil's lag (the record's README): since session 62 (the
    // structure removed read in the typical held-out block) that lag is found, of the order
    // of Spencer et al. 1997's first-order filter on this damper family (η = 190 s⁻¹,
    // 5.3 ms; 7.4 ms here with 16 replicates).
    let lag = j["findings"]
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f["effect"] == "field_lag")
        .unwrap_or_else(|| panic!("no field lag: {}", j["findings"]));
    let tau = &lag["parameters"]["field_time_constant"];
    let ms = tau["value"].as_f64().unwrap();
    assert!((3.0..15.0).contains(&ms), "{tau}");
    assert!(
        tau["ci95"][0].as_f64().unwrap() > 1.0 && tau["ci95"][1].as_f64().unwrap() < 20.0,
        "{tau}"
    );
    for svg in ["loops_force_velocity.svg", "loops_force_displacement.svg"] {
        let text = fs::read_to_string(plots.join(svg)).unwrap();
        assert!(text.len() > 5_000, "{svg}: {} bytes", text.len());
        // Averaged loops per current band, or whole held-out strokes where the command
        // holds a level long enough (this record switches between about 0 and 2.2 V).
        assert!(
            (text.contains("mean per bin") || text.contains("held-out stroke"))
                && text.contains("final model"),
            "{svg}"
        );
    }
}

#[test]
fn selector_and_calibration_options_are_checked() {
    let dir = TempDir::new("sel");
    let csv = dir.path("null.csv");
    write_scenario(&null_scenario(), &csv);
    // An option's bad value: the exit code (2 for clap's refusal, 1 for the check after
    // it) and the message naming it.
    let refused = |option: &str, value: &str, code: i32, says: &str| {
        let o = mrtwin(&[
            "diagnose".as_ref(),
            csv.as_os_str(),
            option.as_ref(),
            value.as_ref(),
        ]);
        assert_eq!(o.status.code(), Some(code), "{option} {value}");
        assert!(stderr(&o).contains(says), "{}", stderr(&o));
    };
    refused("--selector", "magic", 2, "unknown selector 'magic'");
    refused("--yield-curve", "spline", 2, "unknown yield curve 'spline'");
    refused("--family-alpha", "1.5", 1, "--family-alpha 1.5");
    let out_json = dir.path("r.json");
    let o = mrtwin(&[
        "diagnose".as_ref(),
        csv.as_os_str(),
        "--selector".as_ref(),
        "rules".as_ref(),
        "--json".as_ref(),
        out_json.as_os_str(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(json(&out_json)["selector"], "rules");
    // Held current levels are joined by lines, so the default (`auto`) has no curve to
    // choose and says so.
    let j = json(&out_json);
    assert_eq!(j["yield_curve"], "lines");
    assert!(j["yield_curve_fits"].is_null(), "{}", j["yield_curve_fits"]);
}

/// A broadband stroke with a current that sweeps continuously (no held level): the loop
/// plots are averaged per bin of the held-out samples in each third of the current range.
#[test]
fn continuous_current_gets_binned_loop_plots() {
    let dir = TempDir::new("binned");
    let csv = dir.path("sweep.csv");
    let mut text = String::from("time_s,displacement_m,velocity_m_s,force_N,current_A\n");
    let (rate, n) = (500.0, 15_000);
    for k in 0..n {
        let t = k as f64 / rate;
        let (w1, w2) = (
            2.0 * std::f64::consts::PI * 1.3,
            2.0 * std::f64::consts::PI * 3.1,
        );
        let x = 0.006 * (w1 * t).sin() + 0.003 * (w2 * t + 0.7).sin();
        let v = 0.006 * w1 * (w1 * t).cos() + 0.003 * w2 * (w2 * t + 0.7).cos();
        let i = 0.1 + 0.9 * (0.5 - 0.5 * (2.0 * std::f64::consts::PI * t / 30.0).cos());
        let noise = 3.0 * ((k * 7919 % 1000) as f64 / 1000.0 - 0.5);
        let f = (200.0 + 600.0 * i) * (v / 0.004).tanh() + 900.0 * v + noise;
        text.push_str(&format!("{t},{x},{v},{f},{i}\n"));
    }
    fs::write(&csv, text).unwrap();
    let plots = dir.path("plots");
    let o = mrtwin(&[
        "diagnose".as_ref(),
        csv.as_os_str(),
        "--plots".as_ref(),
        plots.as_os_str(),
        "--replicates".as_ref(),
        "8".as_ref(),
        "--report".as_ref(),
        dir.path("r.md").as_os_str(),
    ]);
    assert_eq!(o.status.code(), Some(0), "stderr: {}", stderr(&o));
    for svg in ["loops_force_velocity.svg", "loops_force_displacement.svg"] {
        let text = fs::read_to_string(plots.join(svg)).unwrap();
        assert_eq!(
            text.matches("mean per bin").count(),
            3,
            "{svg}: three current bands"
        );
        assert!(text.contains("final model"), "{svg}");
    }
    // A grid of knots: the default settled the baseline on both yield curves, and the
    // report says which it kept and what each fitted.
    let report = fs::read_to_string(dir.path("r.md")).unwrap();
    let line = report
        .lines()
        .find(|l| l.starts_with("The yield force follows"))
        .unwrap_or_else(|| panic!("no yield-curve line in the report:\n{report}"));
    assert!(
        (line.contains("follows a cubic curve") && line.contains("on straight lines at"))
            || (line.contains("follows straight lines") && line.contains("on a cubic curve at")),
        "{line}"
    );
}
