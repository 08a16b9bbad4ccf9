//! End-to-end tests of `mrtwin identify`: the Skalski–Zalewski pipeline on recordings that
//! `mrtwin simulate` made with the direct-shear model and the paper's law (5.5).

use std::fs;
use std::path::Path;
use std::process::Output;

use mrtwin_tests::TempDir;

fn mrtwin<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Output {
    mrtwin_tests::run(env!("CARGO_BIN_EXE_mrtwin"), args)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn ok(o: &Output) {
    assert!(o.status.success(), "mrtwin failed: {}", stderr(o));
}

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

/// One test from rest: 10 mm stroke, 30 ms at 20 kHz (the first loading), 0.1 % noise.
fn record(out: &Path, current: f64, frequency: f64, seed: u64) {
    ok(&mrtwin(&[
        "simulate",
        "--model",
        "direct-shear",
        "--amplitude",
        "0.01",
        "--frequency",
        &frequency.to_string(),
        "--current",
        &current.to_string(),
        "--duration",
        "0.03",
        "--rate",
        "20000",
        "--noise",
        "0.001",
        "--seed",
        &seed.to_string(),
        "--out",
        out.to_str().unwrap(),
    ]));
}

/// n and R0 of (5.5) at 25 °C, h = 0.7 mm (R0 in Pa).
fn paper(i: f64) -> (f64, f64) {
    (
        0.18 + 0.10 * i - 0.0001 * 25.0,
        (6.8 - 0.07 * i - 0.01 * 25.0) / 0.7e-3 * 1e3,
    )
}

#[test]
fn identify_gives_back_the_papers_law_and_writes_json() {
    let dir = TempDir::new("paper");
    let mut files = Vec::new();
    for (k, i) in [0.5, 1.0, 2.0].into_iter().enumerate() {
        for (j, f) in [1.66, 3.33, 5.0].into_iter().enumerate() {
            let p = dir.path(&format!("i{i}_f{f}.csv"));
            record(&p, i, f, (10 * k + j) as u64);
            files.push(p);
        }
    }
    let json = dir.path("id.json");
    let mut args: Vec<String> = vec!["identify".into()];
    args.extend(files.iter().map(|p| p.display().to_string()));
    args.extend(["--json".into(), json.display().to_string()]);
    let out = mrtwin(&args);
    ok(&out);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("Bodner–Partom law (5.3) per current"),
        "{text}"
    );
    assert!(text.contains("dependence on current (5.5)"), "{text}");
    let v: serde_json::Value = serde_json::from_str(&fs::read_to_string(&json).unwrap()).unwrap();
    let laws = v["laws"].as_array().unwrap();
    assert_eq!(laws.len(), 3);
    for law in laws {
        let i = law["current_A"].as_f64().unwrap();
        let (n, r0) = paper(i);
        let nf = law["n"].as_f64().unwrap();
        let r0f = law["R0_Pa"].as_f64().unwrap();
        assert!((nf / n - 1.0).abs() < 0.02, "{i} A: n {nf} vs {n}\n{text}");
        assert!(
            (r0f / r0 - 1.0).abs() < 0.02,
            "{i} A: R0 {r0f} vs {r0}\n{text}"
        );
        assert!(law["n_se"].as_f64().unwrap().is_finite());
        assert_eq!(law["residuals"].as_array().unwrap().len(), 3);
    }
    let n = v["dependence"]["n"].as_array().unwrap();
    assert!(
        (n[1]["value"].as_f64().unwrap() - 0.10).abs() < 0.01,
        "{text}"
    );
}

#[test]
fn identify_rejects_bad_input_with_clear_errors() {
    let dir = TempDir::new("bad");
    // Two rates only at one current.
    let a = dir.path("a.csv");
    let b = dir.path("b.csv");
    record(&a, 1.0, 1.66, 1);
    record(&b, 1.0, 3.33, 2);
    let err = fails(&mrtwin(&[
        "identify",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
    ]));
    assert!(err.contains("three or more"), "{err}");
    // A recording with two currents is not one test.
    let two = dir.path("two.csv");
    ok(&mrtwin(&[
        "simulate",
        "--model",
        "direct-shear",
        "--current",
        "0.5,1",
        "--frequency",
        "1.66",
        "--duration",
        "0.02",
        "--rate",
        "20000",
        "--out",
        two.to_str().unwrap(),
    ]));
    let err = fails(&mrtwin(&["identify", two.to_str().unwrap()]));
    assert!(
        err.contains("two.csv") && err.contains("one test at one current"),
        "{err}"
    );
    // Too slow a sampling puts no points on the elastic line.
    let slow = dir.path("slow.csv");
    ok(&mrtwin(&[
        "simulate",
        "--model",
        "direct-shear",
        "--current",
        "1",
        "--frequency",
        "5",
        "--duration",
        "0.05",
        "--rate",
        "400",
        "--out",
        slow.to_str().unwrap(),
    ]));
    let err = fails(&mrtwin(&["identify", slow.to_str().unwrap()]));
    assert!(
        err.contains("slow.csv") && err.contains("elastic line"),
        "{err}"
    );
    // Bad geometry and a missing file.
    let err = fails(&mrtwin(&["identify", a.to_str().unwrap(), "--gap", "-1"]));
    assert!(err.contains("--gap"), "{err}");
    let err = fails(&mrtwin(&[
        "identify",
        dir.path("missing.csv").to_str().unwrap(),
    ]));
    assert!(err.contains("missing.csv"), "{err}");
}
