//! Real rig records as they come (issue 17): the Dyke record's continuous command-voltage
//! "current" is summarised, its clipped stretch found and left out, and a twin fitted on
//! the first part of the record, with the command voltage turned into a lagging coil
//! current whose lag the fit finds, replays the rest well below the force RMS with a
//! yield stress that stays physical.

use std::path::{Path, PathBuf};
use std::process::Output;

use mrtwin_tests::{csv_column, fitted_parameter, read_json, rms_finite, succeeded, TempDir};

fn mrtwin<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Output {
    mrtwin_tests::run(env!("CARGO_BIN_EXE_mrtwin"), args)
}

/// The stdout of a run that must succeed.
fn ok(o: Output, what: &str) -> String {
    String::from_utf8_lossy(&succeeded(o, what).stdout).into_owned()
}

fn dyke() -> PathBuf {
    mrtwin_tests::repo_root().join("../shared/data/real/dyke-nees/ransim_u.csv")
}

fn p(path: &Path) -> String {
    path.display().to_string()
}

#[test]
fn info_summarises_a_continuous_current_and_finds_the_clipped_force() {
    let out = ok(mrtwin(&["info".to_string(), p(&dyke())]), "info");
    let currents = out
        .lines()
        .find(|l| l.starts_with("currents"))
        .expect("a currents line");
    // One readable line instead of a thousand levels.
    assert!(
        currents.contains("continuous") && currents.len() < 200,
        "{currents}"
    );
    assert!(currents.contains("-0.441 to 2.705"), "{currents}");
    // The force is clipped at 4545.4545 N at the end of the record (twice).
    let stuck: Vec<&str> = out.lines().filter(|l| l.starts_with("stuck")).collect();
    assert_eq!(
        stuck
            .iter()
            .filter(|l| l.contains("force_N at 4545.4545"))
            .count(),
        2,
        "{out}"
    );
    assert!(stuck.iter().all(|l| l.contains("from 19.")), "{out}");
}

#[test]
fn a_held_current_record_still_lists_its_levels() {
    let dir = TempDir::new("real-levels");
    let rec = dir.path("levels.csv");
    let mut csv = String::from("time_s,displacement_m,velocity_m_s,force_N,current_A\n");
    for k in 0..3000 {
        let t = k as f64 * 1e-3;
        let i = [0.0, 0.5, 1.0][k / 1000];
        let x = 0.005 * (6.0 * t).sin();
        csv.push_str(&format!(
            "{t},{x},{},{},{i}\n",
            0.03 * (6.0 * t).cos(),
            100.0 * (6.0 * t).cos() + (k % 7) as f64
        ));
    }
    std::fs::write(&rec, csv).unwrap();
    let out = ok(mrtwin(&["info".to_string(), p(&rec)]), "info");
    assert!(out.contains("currents      0, 0.5, 1 A"), "{out}");
    assert!(out.contains("stuck         none"), "{out}");
}

#[test]
fn a_twin_fitted_on_the_first_part_replays_the_rest_with_a_physical_yield_stress() {
    let dir = TempDir::new("real-dyke");
    // First 12 s to fit, the last 8 s to judge.
    let text = std::fs::read_to_string(dyke()).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let (mut first, mut rest) = (format!("{header}\n"), format!("{header}\n"));
    for l in lines {
        let t: f64 = l.split(',').next().unwrap().parse().unwrap();
        let part = if t < 12.0 { &mut first } else { &mut rest };
        part.push_str(l);
        part.push('\n');
    }
    let (fit_rec, judge_rec) = (dir.path("first.csv"), dir.path("rest.csv"));
    std::fs::write(&fit_rec, first).unwrap();
    std::fs::write(&judge_rec, rest).unwrap();
    let base = mrtwin_tests::repo_root().join("launch-config/examples/dyke-command-voltage.yaml");
    // The driver's lag is fitted: from the example's 10 ms and from none at all (a base
    // with `driver_lag_s: 0`), the two fits must land on the same lag, which the record
    // then identifies to a few per cent.
    let base_text = std::fs::read_to_string(&base).unwrap();
    assert!(base_text.contains("driver_lag_s: 0.01"), "{base_text}");
    let base0 = dir.path("base0.yaml");
    std::fs::write(
        &base0,
        base_text.replace("driver_lag_s: 0.01", "driver_lag_s: 0.0"),
    )
    .unwrap();
    let fit_lag = |base: &Path, name: &str| -> (f64, f64, String) {
        let twin = dir.path(&format!("{name}.yaml"));
        let json = dir.path(&format!("{name}.json"));
        ok(
            mrtwin(&[
                "fit",
                &p(&fit_rec),
                "--params",
                &p(base),
                "--effects",
                "none",
                "--out",
                &p(&twin),
                "--json",
                &p(&json),
            ]),
            "fit",
        );
        let report = read_json(&json);
        let lag = fitted_parameter(&report, "conditioning.driver_lag_s")
            .unwrap_or_else(|| panic!("the driver lag is not fitted: {report}"))
            .clone();
        let written = std::fs::read_to_string(&twin).unwrap();
        assert!(
            written.contains(&format!("driver_lag_s: {}", lag["value"])),
            "the fitted lag is not what was written\n{written}"
        );
        (
            lag["value"].as_f64().unwrap(),
            lag["std_error"].as_f64().unwrap(),
            p(&twin),
        )
    };
    let (lag, se, twin) = fit_lag(&base, "twin");
    let (lag0, _, _) = fit_lag(&base0, "twin0");
    assert!(
        (0.002..0.05).contains(&lag) && se < 0.1 * lag,
        "driver lag {lag} ± {se} s"
    );
    assert!(
        (lag - lag0).abs() < 2.0 * se,
        "the fitted lag depends on its start: {lag} s from 10 ms, {lag0} s from none (± {se})"
    );
    assert!(
        (lag - 0.01).abs() > 1e-6,
        "the lag was not moved from its start"
    );
    let twin = PathBuf::from(twin);
    let written = std::fs::read_to_string(&twin).unwrap();
    assert!(
        written.contains("current_channel: command_voltage"),
        "{written}"
    );
    let out = dir.path("replay.csv");
    ok(
        mrtwin(&[
            "replay",
            &p(&judge_rec),
            "--params",
            &p(&twin),
            "--out",
            &p(&out),
        ]),
        "replay",
    );
    let force = csv_column(&out, "force_N");
    let residual: Vec<f64> = csv_column(&out, "residual_N")
        .into_iter()
        .filter(|r| r.is_finite())
        .collect();
    // The clipped stretch (in this part) is not judged.
    assert!(
        residual.len() < force.len(),
        "{} {}",
        residual.len(),
        force.len()
    );
    let (r, f) = (rms_finite(&residual), rms_finite(&force));
    assert!(
        r < 0.65 * f,
        "held-out replay RMS {r:.1} N against a force RMS {f:.1} N"
    );
    // The coil current never goes negative, and τ0 is published as a physical number.
    assert!(csv_column(&out, "current_A").iter().all(|i| *i >= 0.0));
    let tau0: Vec<f64> = csv_column(&out, "tau0_Pa")
        .into_iter()
        .filter(|t| t.is_finite())
        .collect();
    assert!(
        tau0.len() > force.len() / 2,
        "{} of {}",
        tau0.len(),
        force.len()
    );
    assert!(
        tau0.iter().all(|t| *t >= 0.0),
        "a negative yield stress was published"
    );
}
