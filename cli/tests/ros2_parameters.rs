//! The nodes' ROS 2 parameters (issue 14) against rclpy's `AsyncParameterClient` with
//! Fast DDS (the interop venv, no ROS install): the twin inside `mrtwin demo` and
//! `mrtwin node`, and `mrtwin stand`. Each test has its own ROS domain (96, 97, 98) and
//! every wait is bounded.
#![cfg(feature = "ros2")]

use std::process::Command;
use std::time::Duration;

use mrtwin_tests::{run_python_env, run_python_with_msgs, ChildGuard, TempDir};
use serde_json::Value;

/// Two live processes at 1 kHz each: one test at a time on a 2-core machine.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|p| p.into_inner())
}

fn mrtwin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mrtwin"))
}

/// argv: target node, `force` to also check that a set takes effect at the next sample
/// (the demo publishes `/twin/predicted_force`). Prints one JSON line.
const CLIENT: &str = concat!(
    include_str!("ros2_parameters_ask.py"),
    include_str!("ros2_parameters_client.py")
);

fn client(domain: &str, target: &str, force: bool) -> Value {
    let env = [
        ("ROS_DOMAIN_ID", domain),
        ("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp"),
    ];
    let timeout = Duration::from_secs(120);
    let out = if force {
        run_python_with_msgs(CLIENT, &[target, "force"], &env, timeout)
    } else {
        run_python_env(CLIENT, &[target, "plain"], &env, timeout)
    };
    serde_json::from_str(out.lines().last().unwrap_or_default())
        .unwrap_or_else(|e| panic!("rclpy JSON ({e}):\n{out}"))
}

/// What both nodes must do: serve the runtime keys (not the restart-only ones), answer
/// get and describe, refuse a bad value with its reason and change nothing, take a good
/// one.
fn check_common(v: &Value) {
    assert_eq!(v["services"], true, "{v}");
    for key in [
        "health.residual.warn",
        "estimator.settings.memory_s",
        "two_chamber.bulk_modulus_pa",
        "model",
    ] {
        assert_eq!(v["has"][key], true, "{key} not listed: {v}");
    }
    assert_eq!(v["has"]["damper"], false, "restart-only key served: {v}");
    assert_eq!(v["described"], "stale_after_s", "{v}");
    let bad = &v["bad"];
    assert_eq!(bad["ok"], false, "{v}");
    assert!(bad["reason"].as_str().unwrap().contains("positive"), "{v}");
    assert_eq!(v["bad_type"]["ok"], false, "{v}");
    assert_eq!(v["bad_effect"]["ok"], false, "{v}");
    assert!(
        v["bad_effect"]["reason"]
            .as_str()
            .unwrap()
            .contains("warp_drive"),
        "{v}"
    );
    assert_eq!(
        v["stale_after_bad"]["double"], v["stale_before"]["double"],
        "{v}"
    );
    assert_eq!(v["good"]["ok"], true, "{v}");
    assert_eq!(v["warn_after"]["double"], 0.07, "{v}");
}

#[test]
#[cfg(all(feature = "zenoh", feature = "iceoryx2"))]
fn rclpy_reads_and_sets_the_parameters_of_the_twin_inside_the_demo() {
    let _serial = serial();
    let demo = ChildGuard::spawn(mrtwin().args(["demo", "--duration", "60", "--domain-id", "96"]));
    let v = client("96", "mrtwin_twin", true);
    drop(demo);
    check_common(&v);
    // A 50 kN load-cell offset set while the twin runs: the predicted forces before it
    // stay below 30 kN, and from the next sample the twin steps all carry it: every output
    // stamped after the client had the answer, and every one after the first shifted one.
    // Outputs stepped before the set may still arrive after the answer
    // (`unshifted_after_set`, a backlog: not bounded here).
    assert_eq!(v["offset_set"]["ok"], true, "{v}");
    assert!(v["before"].as_u64().unwrap() > 1000, "{v}");
    assert!(v["old_max"].as_f64().unwrap() < 30_000.0, "{v}");
    assert!(v["after"].as_u64().unwrap() > 1000, "{v}");
    assert!(v["stamped_after_answer"].as_u64().unwrap() > 1000, "{v}");
    assert_eq!(v["unshifted_stamped_after_answer"], 0, "{v}");
    assert_eq!(v["shifted_then_all"], true, "{v}");
}

/// `mrtwin node|stand` for 60 s under namespace `ns`, its `ros__parameters` (the lines
/// of `body`, indented by four) in a file of `dir`.
fn spawn_node(dir: &TempDir, command: &str, body: &str, ns: &str) -> ChildGuard {
    let params = dir.path("params.yaml");
    let section = if command == "stand" {
        "mrtwin_stand"
    } else {
        "mrtwin_twin"
    };
    std::fs::write(
        &params,
        format!("{section}:\n  ros__parameters:\n    {body}\n"),
    )
    .expect("write parameter file");
    ChildGuard::spawn(mrtwin().args([
        command,
        "--duration",
        "60",
        "--ros-args",
        "--params-file",
        params.to_str().unwrap(),
        "-r",
        &format!("__ns:={ns}"),
    ]))
}

#[test]
fn rclpy_reads_and_sets_the_parameters_of_mrtwin_node() {
    let _serial = serial();
    let dir = TempDir::new("ros2_parameters_node");
    let node = spawn_node(
        &dir,
        "node",
        "damper: paramsdamper\n    transports: [ros2]\n    input: ros2\n    control_service: false\n    ros2:\n      domain_id: 97",
        "/rig",
    );
    let v = client("97", "/rig/mrtwin_twin", false);
    drop(node);
    check_common(&v);
}

/// argv: target node, namespace. Reads the stand's samples as native `mrtwin_msgs`.
const STAND_CLIENT: &str = concat!(
    include_str!("ros2_parameters_ask.py"),
    include_str!("ros2_stand_parameters_client.py")
);

#[test]
fn rclpy_reads_and_sets_the_parameters_of_mrtwin_stand_and_the_samples_follow() {
    let _serial = serial();
    let dir = TempDir::new("ros2_parameters_stand");
    let stand = spawn_node(
        &dir,
        "stand",
        "damper: standparams\n    transports: [ros2]\n    ros2:\n      domain_id: 98",
        "/standrig",
    );
    let out = run_python_with_msgs(
        STAND_CLIENT,
        &["/standrig/mrtwin_stand", "/standrig"],
        &[
            ("ROS_DOMAIN_ID", "98"),
            ("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp"),
        ],
        Duration::from_secs(120),
    );
    drop(stand);
    let v: Value = serde_json::from_str(out.lines().last().unwrap_or_default())
        .unwrap_or_else(|e| panic!("rclpy JSON ({e}):\n{out}"));
    eprintln!("{v}");
    assert_eq!(v["services"], true, "{v}");
    // The programme, model and faults are served; the pacing, seed and name are not.
    for (key, served) in [
        ("currents_a", true),
        ("noise_n", true),
        ("faults.drop_probability", true),
        ("two_chamber.load_cell_offset_n", true),
        ("rate_hz", false),
        ("seed", false),
        ("damper", false),
    ] {
        assert_eq!(v["has"][key], served, "{key}: {v}");
    }
    assert_eq!(
        v["currents_before"],
        serde_json::json!([0.5, 1.0, 2.0]),
        "{v}"
    );
    assert_eq!(v["described"], "noise_n", "{v}");
    // Refused with their reasons, and nothing changes.
    assert_eq!(v["bad_noise"]["ok"], false, "{v}");
    assert!(
        v["bad_noise"]["reason"].as_str().unwrap().contains("≥ 0"),
        "{v}"
    );
    assert_eq!(v["bad_rate"]["ok"], false, "{v}");
    assert_eq!(v["bad_model"]["ok"], false, "{v}");
    assert!(
        v["bad_model"]["reason"].as_str().unwrap().contains("magic"),
        "{v}"
    );
    assert_eq!(v["noise_after_bad"], v["noise_before"], "{v}");
    // The stream before: the default programme's first current.
    assert!(v["before"].as_u64().unwrap() > 1000, "{v}");
    assert_eq!(v["currents_seen_before"], serde_json::json!([0.5]), "{v}");
    // A new programme from the next sample: every sample stamped after the client had the
    // answer is at 1.75 A (a sample is made no earlier than its stamp), and every sample
    // after the first 1.75 A one too. Samples made before the set may still arrive after
    // the answer (`old_after_set`, a backlog: not bounded here).
    assert_eq!(v["currents_set"]["ok"], true, "{v}");
    assert_eq!(v["currents_get"], serde_json::json!([1.75]), "{v}");
    assert!(v["after"].as_u64().unwrap() > 1000, "{v}");
    assert!(v["stamped_after_answer"].as_u64().unwrap() > 1000, "{v}");
    assert_eq!(v["old_stamped_after_answer"], 0, "{v}");
    assert_eq!(v["new_then_all"], true, "{v}");
    // A model parameter: a 50 kN load-cell offset, from the next sample.
    assert!(v["old_force_max"].as_f64().unwrap() < 30_000.0, "{v}");
    assert_eq!(v["offset_set"]["ok"], true, "{v}");
    assert!(v["after_offset"].as_u64().unwrap() > 1000, "{v}");
    assert!(
        v["stamped_after_offset_answer"].as_u64().unwrap() > 1000,
        "{v}"
    );
    assert_eq!(v["unshifted_stamped_after_answer"], 0, "{v}");
    assert_eq!(v["shifted_then_all"], true, "{v}");
}
