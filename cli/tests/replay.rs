//! `mrtwin replay`: the committed fixture bags (one simulated, one converted from a real
//! UTFSM recording) replayed through the twin, compared with golden outputs, replayed twice
//! for byte identity, and checked against physics the golden file cannot know (on the
//! simulated bag the twin runs the simulator's own model, so its residual is the sensor
//! noise the simulator added).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use mrtwin_tests::{repo_root, TempDir};

fn mrtwin(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mrtwin"))
        .args(args)
        .output()
        .expect("run mrtwin")
}

fn fixture(name: &str) -> PathBuf {
    repo_root().join("tests/fixtures/bags").join(name)
}

fn replay_csv(input: &Path, out: &Path) -> Vec<u8> {
    let o = mrtwin(&[
        "replay".as_ref(),
        input.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(
        o.status.success(),
        "replay failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    std::fs::read(out).expect("replay output")
}

fn rows(text: &str) -> Vec<Vec<f64>> {
    text.lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .map(|x| x.parse::<f64>().expect("number"))
                .collect()
        })
        .collect()
}

fn column(header: &str, name: &str) -> usize {
    header
        .split(',')
        .position(|c| c == name)
        .unwrap_or_else(|| panic!("no column {name}"))
}

#[test]
fn fixture_replays_match_golden_and_repeat_byte_for_byte() {
    let dir = TempDir::new("replay_golden");
    for name in ["simulated-two-chamber", "utfsm-10mm1Hz1A"] {
        let a = replay_csv(&fixture(name), &dir.path(&format!("{name}-a.csv")));
        let b = replay_csv(&fixture(name), &dir.path(&format!("{name}-b.csv")));
        assert!(a == b, "{name}: two replays differ");
        let text = String::from_utf8(a).unwrap();
        let header = text.lines().next().unwrap();
        for col in [
            "time_s",
            "current_A",
            "force_N",
            "force_predicted_N",
            "residual_N",
            "tau0_Pa",
            "tau0_std_Pa",
            "health_level",
        ] {
            column(header, col);
        }
        let golden = std::fs::read_to_string(
            repo_root().join(format!("tests/fixtures/golden/{name}.replay.csv")),
        )
        .unwrap();
        assert_eq!(
            header,
            golden.lines().next().unwrap(),
            "{name}: columns changed"
        );
        let (new, old) = (rows(&text), rows(&golden));
        assert_eq!(new.len(), old.len(), "{name}: one row per input sample");
        for (i, (r, g)) in new.iter().zip(&old).enumerate() {
            for (j, (x, y)) in r.iter().zip(g).enumerate() {
                let same = (x.is_nan() && y.is_nan()) || (x - y).abs() <= 1e-9 * y.abs().max(1.0);
                assert!(same, "{name}: row {} column {j}: {x} vs golden {y}", i + 2);
            }
        }
    }
}

#[test]
fn simulated_bag_residual_is_the_simulators_noise() {
    let dir = TempDir::new("replay_noise");
    let text = String::from_utf8(replay_csv(
        &fixture("simulated-two-chamber"),
        &dir.path("r.csv"),
    ))
    .unwrap();
    let header = text.lines().next().unwrap();
    let (f, r) = (column(header, "force_N"), column(header, "residual_N"));
    let data = rows(&text);
    let peak = data.iter().map(|row| row[f].abs()).fold(0.0, f64::max);
    // scripts/make-fixtures.sh: --noise 0.01 → σ = 1 % of the record's peak |F|.
    let rms = (data.iter().map(|row| row[r] * row[r]).sum::<f64>() / data.len() as f64).sqrt();
    let sigma = 0.01 * peak;
    assert!(
        (rms / sigma - 1.0).abs() < 0.1,
        "residual RMS {rms:.2} N vs noise σ {sigma:.2} N"
    );
}

#[test]
fn replay_of_a_bag_and_of_its_csv_agree_and_bag_output_holds_the_outputs() {
    let dir = TempDir::new("replay_csv_bag");
    let bag = fixture("utfsm-10mm1Hz1A");
    let csv = dir.path("in.csv");
    let o = mrtwin(&["convert".as_ref(), bag.as_os_str(), csv.as_os_str()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let from_bag = replay_csv(&bag, &dir.path("a.csv"));
    let from_csv = replay_csv(&csv, &dir.path("b.csv"));
    assert!(from_bag == from_csv, "bag and CSV replays differ");
    let out = dir.path("out-bag");
    let o = mrtwin(&[
        "replay".as_ref(),
        bag.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let contents = bridge::bag::read_bag(&out).expect("replay bag opens");
    let count = |topic: bridge::transport::Topic| {
        contents
            .messages
            .iter()
            .filter(|m| m.topic == topic)
            .count()
    };
    let n = rows(&String::from_utf8(from_bag).unwrap()).len();
    assert_eq!(count(bridge::transport::Topic::Sample), n);
    assert_eq!(count(bridge::transport::Topic::Output), n);
    assert!(count(bridge::transport::Topic::Diagnostics) >= 3);
    assert!(count(bridge::transport::Topic::YieldEstimate) >= 20);
}

#[test]
fn bad_replay_input_fails_with_the_file_name() {
    let dir = TempDir::new("replay_bad");
    let empty = dir.path("empty.mcap");
    std::fs::write(&empty, b"").unwrap();
    let garbage = dir.path("garbage.csv");
    std::fs::write(
        &garbage,
        "time_s,displacement_m,force_N,current_A\n0,0,1,nan\n",
    )
    .unwrap();
    for p in [&empty, &garbage, &dir.path("missing.csv")] {
        let o = mrtwin(&["replay".as_ref(), p.as_os_str()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{} was accepted", p.display());
        assert!(
            err.contains(p.file_name().unwrap().to_str().unwrap()),
            "error does not name the file: {err}"
        );
    }
    let o = mrtwin(&[
        "replay".as_ref(),
        fixture("simulated-two-chamber").as_os_str(),
        "--rate".as_ref(),
        "fast".as_ref(),
    ]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--rate"));
}
