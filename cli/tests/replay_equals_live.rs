//! Live and replay run the same twin core: the samples a live twin node received,
//! recorded from the wire by `mrtwin record` and replayed with `mrtwin replay`, give
//! byte for byte the messages the node published — outputs, predicted forces, yield
//! estimates and every `/diagnostics` the samples caused. Only the STALE announcements
//! the node made by the wall clock while no samples came (before the first, after the
//! last) have no counterpart in a replay, which never waits.
//!
//! Separate processes over zenoh on a loopback port of this test's own, bounded waits.
#![cfg(feature = "zenoh")]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use bridge::transport::{Message, Topic};
use mrtwin_tests::{free_port, ChildGuard, TempDir};

fn mrtwin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mrtwin"))
}

fn write(path: &Path, text: &str) {
    std::fs::write(path, text).expect("write parameter file");
}

/// The CDR bytes of each topic's messages in a bag, in log order.
fn by_topic(bag: &Path) -> BTreeMap<Topic, Vec<(Message, Vec<u8>)>> {
    let contents = bridge::bag::read_bag(bag).expect("bag opens");
    let mut map: BTreeMap<Topic, Vec<(Message, Vec<u8>)>> = BTreeMap::new();
    for m in contents.messages {
        let cdr = m.message.to_cdr();
        map.entry(m.topic).or_default().push((m.message, cdr));
    }
    map
}

/// A diagnostics message the node sent by the wall clock: its sensor stream is STALE.
fn announces_silence(m: &Message) -> bool {
    let Message::Diagnostics(d) = m else {
        return false;
    };
    d.status
        .iter()
        .any(|s| s.name.ends_with("sensor stream") && s.level == msgs::DiagnosticStatus::STALE)
}

/// One live run: recorder (zenoh listener), twin node and stand (both connecting to it),
/// 3 s of samples at 500 Hz. Returns the recorded bag, the twin's parameter file and the
/// damper name.
fn live_run(dir: &TempDir, attempt: u32) -> (PathBuf, PathBuf, String) {
    let port = free_port();
    let damper = format!("rl{}x{attempt}", std::process::id());
    let twin = dir.path(&format!("twin{attempt}.yaml"));
    write(
        &twin,
        &format!(
            "mrtwin_twin:\n  ros__parameters:\n    damper: {damper}\n    model: two-chamber\n    transports: [zenoh]\n    input: zenoh\n    control_service: false\n    zenoh:\n      multicast_scouting: false\n      connect: [\"tcp/127.0.0.1:{port}\"]\n"
        ),
    );
    let stand = dir.path(&format!("stand{attempt}.yaml"));
    write(
        &stand,
        &format!(
            "mrtwin_stand:\n  ros__parameters:\n    damper: {damper}\n    model: two-chamber\n    transports: [zenoh]\n    rate_hz: 500.0\n    currents_a: [0.5, 1.5]\n    frequencies_hz: [2.0]\n    segment_duration_s: 1.5\n    noise_n: 5.0\n    zenoh:\n      multicast_scouting: false\n      connect: [\"tcp/127.0.0.1:{port}\"]\n"
        ),
    );
    let recorder = dir.path(&format!("recorder{attempt}.yaml"));
    write(
        &recorder,
        &format!(
            "/**:\n  ros__parameters:\n    damper: {damper}\n    zenoh:\n      multicast_scouting: false\n      listen: [\"tcp/127.0.0.1:{port}\"]\n"
        ),
    );
    let live_bag = dir.path(&format!("live{attempt}"));
    let rec = ChildGuard::spawn(mrtwin().args([
        "record",
        "--out",
        live_bag.to_str().unwrap(),
        "--transport",
        "zenoh",
        "--topics",
        "sensor/sample,twin/output,twin/predicted_force,twin/yield_estimate,/diagnostics",
        "--ros-args",
        "--params-file",
        recorder.to_str().unwrap(),
    ]));
    std::thread::sleep(Duration::from_millis(800));
    let node = ChildGuard::spawn(mrtwin().args([
        "node",
        "--duration",
        "30",
        "--ros-args",
        "--params-file",
        twin.to_str().unwrap(),
    ]));
    std::thread::sleep(Duration::from_millis(1500));
    let (ok, _, err) = ChildGuard::spawn(mrtwin().args([
        "stand",
        "--duration",
        "3",
        "--ros-args",
        "--params-file",
        stand.to_str().unwrap(),
    ]))
    .wait(Duration::from_secs(30));
    assert!(ok, "stand failed: {err}");
    std::thread::sleep(Duration::from_millis(1000));
    node.interrupt();
    let (ok, _, err) = node.wait(Duration::from_secs(20));
    assert!(ok, "node failed: {err}");
    std::thread::sleep(Duration::from_millis(500));
    rec.interrupt();
    let (ok, _, err) = rec.wait(Duration::from_secs(20));
    assert!(ok, "recorder failed: {err}");

    (live_bag, twin, damper)
}

/// Stamps of the samples in the bag and of the outputs the node published.
fn stamps(bag: &BTreeMap<Topic, Vec<(Message, Vec<u8>)>>) -> (Vec<f64>, Vec<f64>) {
    let of = |topic: Topic| -> Vec<f64> {
        bag.get(&topic)
            .into_iter()
            .flatten()
            .filter_map(|(m, _)| match m {
                Message::Sample(s) => Some(s.header.stamp.as_secs_f64()),
                Message::Output(o) => Some(o.header.stamp.as_secs_f64()),
                _ => None,
            })
            .collect()
    };
    (of(Topic::Sample), of(Topic::Output))
}

/// The recorded samples the node stepped (those whose stamp an output carries), written
/// as a bag of their own: exactly the node's input. `None` when an output has no recorded
/// sample (the recorder lost one the node got), so the node's input cannot be rebuilt.
fn node_input(
    live: &BTreeMap<Topic, Vec<(Message, Vec<u8>)>>,
    damper: &str,
    out: &Path,
) -> Option<usize> {
    let (samples, outputs) = stamps(live);
    let stepped: std::collections::BTreeSet<u64> =
        outputs.iter().map(|t| (t * 1e9).round() as u64).collect();
    let mut writer = bridge::bag::BagWriter::create(out, Default::default()).expect("create bag");
    let mut n = 0;
    for ((m, _), t) in live[&Topic::Sample].iter().zip(&samples) {
        let ns = (t * 1e9).round() as u64;
        if stepped.contains(&ns) {
            writer.write_message(damper, m, ns).expect("write sample");
            n += 1;
        }
    }
    writer.finish().expect("finish bag");
    (n == outputs.len()).then_some(n)
}

#[test]
fn replaying_the_samples_of_a_live_run_publishes_the_same_bytes() {
    let dir = TempDir::new("replay_equals_live");
    // The replay gets exactly the samples the node stepped. Samples travel best effort
    // (sensor-data QoS) and the node may miss one the recorder got (typically the very
    // first, before zenoh's routes settle); those are left out of the replay's input,
    // recognised by their stamps. If the recorder missed a sample the node got, the
    // node's input cannot be rebuilt and the run is repeated (at most three runs).
    let mut runs = Vec::new();
    let (live, input, twin) = loop {
        let attempt = runs.len() as u32;
        let (bag, twin, damper) = live_run(&dir, attempt);
        let live = by_topic(&bag);
        let input = dir.path(&format!("input{attempt}"));
        let (samples, outputs) = stamps(&live);
        match node_input(&live, &damper, &input) {
            Some(n) if n > 0 => {
                if n < samples.len() {
                    eprintln!(
                        "run {attempt}: the node stepped {n} of the {} samples recorded",
                        samples.len()
                    );
                }
                break (live, input, twin);
            }
            _ => runs.push(format!(
                "run {attempt}: {} samples recorded, {} outputs published",
                samples.len(),
                outputs.len()
            )),
        }
        assert!(
            runs.len() < 3,
            "node input not recoverable in any run:\n{}",
            runs.join("\n")
        );
    };
    let replay_bag = dir.path("replay");
    let o = mrtwin()
        .args(["replay", input.to_str().unwrap(), "--params"])
        .arg(&twin)
        .arg("--out")
        .arg(&replay_bag)
        .output()
        .expect("run replay");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let replay = by_topic(&replay_bag);
    let samples = live.get(&Topic::Sample).map_or(0, Vec::len);
    // 3 s at 500 Hz, nearly all of them stepped by the node.
    assert!(samples >= 1400, "only {samples} samples recorded");
    let stepped = replay[&Topic::Sample].len();
    assert!(
        stepped + 10 >= samples,
        "the node stepped only {stepped} of {samples} samples"
    );
    for topic in [Topic::Output, Topic::PredictedForce, Topic::YieldEstimate] {
        let (l, r) = (&live[&topic], &replay[&topic]);
        assert!(!l.is_empty(), "{topic:?}: nothing published live");
        assert_eq!(
            l.len(),
            r.len(),
            "{topic:?}: live {} vs replay {}",
            l.len(),
            r.len()
        );
        for (i, (a, b)) in l.iter().zip(r).enumerate() {
            assert!(
                a.1 == b.1,
                "{topic:?} #{i} differs:\nlive   {:?}\nreplay {:?}",
                a.0,
                b.0
            );
        }
    }
    assert_eq!(
        live[&Topic::Output].len(),
        stepped,
        "one output per stepped sample"
    );
    let live_diag: Vec<&(Message, Vec<u8>)> = live[&Topic::Diagnostics]
        .iter()
        .filter(|(m, _)| !announces_silence(m))
        .collect();
    let replay_diag = &replay[&Topic::Diagnostics];
    assert!(
        replay_diag.len() >= 3,
        "{} diagnostics in the replay",
        replay_diag.len()
    );
    assert!(
        live[&Topic::Diagnostics].len() > live_diag.len(),
        "the node announced no silence before the first sample"
    );
    assert_eq!(live_diag.len(), replay_diag.len());
    for (i, (a, b)) in live_diag.iter().zip(replay_diag).enumerate() {
        assert!(
            a.1 == b.1,
            "diagnostics #{i} differ:\nlive   {:?}\nreplay {:?}",
            a.0,
            b.0
        );
    }
}
