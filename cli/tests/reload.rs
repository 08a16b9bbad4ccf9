//! A running twin node takes an upgraded parameter file without a restart: the effects
//! switch in flight, the outputs keep flowing, `/diagnostics` (`twin model`) names the
//! model, effects and parameter version, and a broken file is refused with its key and
//! line while the node runs on. Separate processes over zenoh on a loopback port of this
//! test's own, recorded from the wire by `mrtwin record`; bounded waits.
#![cfg(feature = "zenoh")]

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use bridge::transport::{Message, Topic};
use mrtwin_tests::{free_port, ChildGuard, TempDir};

fn mrtwin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mrtwin"))
}

fn write(path: &Path, text: &str) {
    // Write aside and rename, as an editor or a deployment tool would.
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, text).expect("write parameter file");
    std::fs::rename(&tmp, path).expect("rename parameter file");
}

/// A `twin model` status: (level, message, key → value).
type ModelStatus = (u8, String, Vec<(String, String)>);

/// The `twin model` status of a diagnostics message.
fn twin_model(m: &Message) -> Option<ModelStatus> {
    let Message::Diagnostics(d) = m else {
        return None;
    };
    let s = d.status.iter().find(|s| s.name.ends_with(": twin model"))?;
    let kv = s
        .values
        .iter()
        .map(|kv| (kv.key.clone(), kv.value.clone()))
        .collect();
    Some((s.level, s.message.clone(), kv))
}

fn value<'a>(kv: &'a [(String, String)], key: &str) -> &'a str {
    kv.iter()
        .find(|(k, _)| k == key)
        .map_or("", |(_, v)| v.as_str())
}

#[test]
fn a_running_node_takes_an_upgraded_parameter_file_and_refuses_a_broken_one() {
    let dir = TempDir::new("reload");
    let port = free_port();
    let damper = format!("rld{}", std::process::id());
    let twin_yaml = |effects: &str| {
        format!(
            "mrtwin_twin:\n  ros__parameters:\n    damper: {damper}\n    model: two-chamber\n    effects: {effects}\n    transports: [zenoh]\n    input: zenoh\n    control_service: false\n    zenoh:\n      multicast_scouting: false\n      connect: [\"tcp/127.0.0.1:{port}\"]\n"
        )
    };
    let twin = dir.path("twin.yaml");
    write(&twin, &twin_yaml("none"));
    let stand = dir.path("stand.yaml");
    write(
        &stand,
        &format!(
            "mrtwin_stand:\n  ros__parameters:\n    damper: {damper}\n    model: two-chamber\n    transports: [zenoh]\n    rate_hz: 500.0\n    currents_a: [1.0]\n    frequencies_hz: [2.0]\n    segment_duration_s: 100.0\n    zenoh:\n      multicast_scouting: false\n      connect: [\"tcp/127.0.0.1:{port}\"]\n"
        ),
    );
    let recorder = dir.path("recorder.yaml");
    write(
        &recorder,
        &format!(
            "/**:\n  ros__parameters:\n    damper: {damper}\n    zenoh:\n      multicast_scouting: false\n      listen: [\"tcp/127.0.0.1:{port}\"]\n"
        ),
    );
    let bag = dir.path("bag");
    let rec = ChildGuard::spawn(mrtwin().args([
        "record",
        "--out",
        bag.to_str().unwrap(),
        "--transport",
        "zenoh",
        "--topics",
        "twin/output,/diagnostics",
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
    let stand_run = ChildGuard::spawn(mrtwin().args([
        "stand",
        "--duration",
        "6",
        "--ros-args",
        "--params-file",
        stand.to_str().unwrap(),
    ]));
    std::thread::sleep(Duration::from_millis(2000));
    write(&twin, &twin_yaml("paper"));
    std::thread::sleep(Duration::from_millis(1500));
    write(&twin, &twin_yaml("magic"));
    let (ok, _, err) = stand_run.wait(Duration::from_secs(30));
    assert!(ok, "stand failed: {err}");
    std::thread::sleep(Duration::from_millis(500));
    node.interrupt();
    let (ok, _, node_err) = node.wait(Duration::from_secs(20));
    assert!(ok, "node failed: {node_err}");
    std::thread::sleep(Duration::from_millis(500));
    rec.interrupt();
    let (ok, _, err) = rec.wait(Duration::from_secs(20));
    assert!(ok, "recorder failed: {err}");

    let contents = bridge::bag::read_bag(&bag).expect("bag opens");
    let stamps: Vec<f64> = contents
        .messages
        .iter()
        .filter_map(|m| match &m.message {
            Message::Output(o) => Some(o.header.stamp.as_secs_f64()),
            _ => None,
        })
        .collect();
    // 6 s at 500 Hz, with no hole where the parameters changed.
    assert!(stamps.len() > 2500, "only {} outputs", stamps.len());
    let largest_gap = stamps.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
    assert!(
        largest_gap < 0.05,
        "the outputs stopped for {largest_gap} s"
    );

    let models: Vec<ModelStatus> = contents
        .messages
        .iter()
        .filter(|m| m.topic == Topic::Diagnostics)
        .filter_map(|m| twin_model(&m.message))
        .collect();
    let first = models.first().expect("a twin model status");
    assert_eq!(value(&first.2, "effects"), "none");
    assert_eq!(value(&first.2, "reloads"), "0");
    let upgraded = models
        .iter()
        .find(|(_, _, kv)| value(kv, "reloads") == "1")
        .unwrap_or_else(|| panic!("no reload reported; node: {node_err}"));
    assert_eq!(upgraded.0, msgs::DiagnosticStatus::OK, "{}", upgraded.1);
    assert_eq!(value(&upgraded.2, "effects"), "paper");
    assert_ne!(
        value(&upgraded.2, "params_version"),
        value(&first.2, "params_version")
    );
    let refused = models
        .iter()
        .find(|(level, _, _)| *level == msgs::DiagnosticStatus::WARN)
        .unwrap_or_else(|| panic!("the broken file was not reported; node: {node_err}"));
    let why = value(&refused.2, "refused");
    assert!(
        why.contains("twin.yaml") && why.contains("effects") && why.contains("magic"),
        "{why}"
    );
    assert_eq!(
        value(&refused.2, "effects"),
        "paper",
        "the node runs on as upgraded"
    );
    assert_eq!(value(&refused.2, "reloads"), "1");
}
