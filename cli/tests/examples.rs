//! The examples of `examples/`, each run end to end as its README says against a real
//! `mrtwin` in separate processes: the rclpy listener against `mrtwin demo`, the zenoh
//! subscriber and the rosbags reader against `mrtwin node`/`stand`/`record` started with
//! `launch-config/examples/*.yaml`, the iceoryx2 controller (a workspace binary) against
//! `mrtwin node` with iceoryx2 input.
//!
//! Every test has its own ROS domain, zenoh port, damper name and iceoryx2 service (the
//! `-p` overrides on top of the README's parameter files), and every wait is bounded. The
//! Python examples run with the interop venv's Python (`$MRTWIN_PYTHON`, see
//! `scripts/setup-venv.sh`).
//!
//! A test runs when the transports it needs are compiled in (cargo features of `mrtwin`);
//! the helpers they share are then partly unused.
#![cfg_attr(
    not(all(feature = "ros2", feature = "zenoh", feature = "iceoryx2")),
    allow(dead_code, unused_imports)
)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use mrtwin_tests::{await_line, free_port, repo_root, ChildGuard, TempDir};
use serde_json::Value;

/// ROS domain of this file's tests (live.rs uses 91 and 93, bridge's tests 41–43 and 78).
const DOMAIN: &str = "95";

/// Each live test runs two or three processes at 1 kHz: on a 2-core machine they run one
/// at a time.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|p| p.into_inner())
}

fn mrtwin() -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_mrtwin"));
    cmd.current_dir(repo_root());
    cmd
}

fn params_file(name: &str) -> String {
    repo_root()
        .join("launch-config/examples")
        .join(name)
        .display()
        .to_string()
}

/// Run a Python example to completion; its stdout. Panics with its output on failure.
fn run_python_example(script: &str, args: &[&str], timeout: Duration) -> String {
    let path = repo_root().join("examples").join(script);
    let child = ChildGuard::spawn(Command::new(mrtwin_tests::python()).arg(path).args(args));
    let (ok, out, err) = child.wait(timeout);
    assert!(ok, "{script} failed:\nstderr:\n{err}\nstdout:\n{out}");
    out
}

/// The example's closing `--json` summary line.
fn summary(out: &str) -> Value {
    out.lines()
        .rev()
        .find_map(|l| {
            serde_json::from_str::<Value>(l)
                .ok()
                .filter(Value::is_object)
        })
        .unwrap_or_else(|| panic!("no JSON summary in:\n{out}"))
}

/// Stop a node with Ctrl-C and check it stopped cleanly; its stdout and stderr.
fn stop(node: ChildGuard, what: &str) -> String {
    node.interrupt();
    let (ok, out, err) = node.wait(Duration::from_secs(30));
    assert!(ok, "{what} failed:\n{err}\n{out}");
    out + &err
}

/// `-p` overrides on top of `launch-config/examples/*.yaml`: this test's own damper and
/// zenoh port (`endpoint_key`: `listen` or `connect`), zenoh only.
fn zenoh_overrides(damper: &str, port: u16, endpoint_key: &str) -> Vec<String> {
    vec![
        "-p".into(),
        format!("damper:={damper}"),
        "-p".into(),
        "transports:=[zenoh]".into(),
        "-p".into(),
        format!("zenoh.{endpoint_key}:=[\"tcp/127.0.0.1:{port}\"]"),
    ]
}

/// `mrtwin node` with the example twin file and this test's zenoh overrides (listening on
/// `port`): `flags` before `--ros-args`, `ros` after the file (e.g. `-r __ns:=/rig7`).
fn example_twin(damper: &str, port: u16, flags: &[&str], ros: &[&str]) -> ChildGuard {
    let twin_yaml = params_file("twin.yaml");
    ChildGuard::spawn(
        mrtwin()
            .args(["node", "--duration", "90"])
            .args(flags)
            .args(["--ros-args", "--params-file", &twin_yaml])
            .args(ros)
            .args(zenoh_overrides(damper, port, "listen")),
    )
}

/// `mrtwin stand` with the example stand file, connecting to the twin on `port`.
fn example_stand(damper: &str, port: u16) -> ChildGuard {
    let stand_yaml = params_file("stand.node.yaml");
    ChildGuard::spawn(
        mrtwin()
            .args([
                "stand",
                "--duration",
                "90",
                "--ros-args",
                "--params-file",
                &stand_yaml,
            ])
            .args(zenoh_overrides(damper, port, "connect")),
    )
}

fn valid_level(v: &Value) -> bool {
    v.as_u64().is_some_and(|l| l <= 3)
}

#[test]
#[cfg(all(feature = "ros2", feature = "zenoh", feature = "iceoryx2"))]
fn rclpy_listener_prints_the_demo_twins_force_and_health() {
    let _serial = serial();
    let demo =
        ChildGuard::spawn(mrtwin().args(["demo", "--duration", "90", "--domain-id", DOMAIN]));
    let out = run_python_example(
        "rclpy-listener/listener.py",
        &[
            "--domain-id",
            DOMAIN,
            "--count",
            "2000",
            "--timeout",
            "40",
            "--json",
        ],
        Duration::from_secs(60),
    );
    let demo_out = stop(demo, "mrtwin demo");
    let v = summary(&out);
    assert!(v["forces"].as_u64().unwrap() >= 2000, "{out}");
    assert_eq!(v["finite"], v["forces"], "non-finite forces: {out}");
    let (min, max) = (v["min_n"].as_f64().unwrap(), v["max_n"].as_f64().unwrap());
    assert!(
        min < 0.0 && max > 0.0 && max - min < 1e5,
        "a stroke's force changes sign: {min} to {max} N"
    );
    assert!(
        v["diagnostics"].as_u64().unwrap() >= 1,
        "no /diagnostics: {out}"
    );
    let levels = v["levels"].as_object().unwrap();
    assert!(levels.values().all(valid_level), "{levels:?}");
    assert!(
        levels.contains_key("/mrtwin_twin: sensor stream")
            && levels.contains_key("/mrtwin_twin: prediction residual"),
        "{levels:?}"
    );
    // The demo's stand adds 5 N of force noise to the same model the twin runs.
    let rms = v["residual_rms_n"].as_f64().unwrap();
    assert!(
        rms > 0.0 && rms < 0.05 * max.max(-min),
        "residual RMS {rms} N"
    );
    assert!(
        out.lines()
            .any(|l| l.starts_with("health: ") && l.contains("sensor stream OK")),
        "{out}"
    );
    assert!(demo_out.contains("outputs received:"), "{demo_out}");
}

#[test]
#[cfg(feature = "zenoh")]
fn zenoh_subscriber_decodes_the_twins_outputs_estimates_and_diagnostics() {
    let _serial = serial();
    let port = free_port();
    let damper = format!("exz{}", std::process::id());
    let node = example_twin(&damper, port, &[], &[]);
    let stand = example_stand(&damper, port);
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let out = run_python_example(
        "zenoh-subscriber/subscriber.py",
        &[
            "--connect",
            &endpoint,
            "--damper",
            &damper,
            "--count",
            "2000",
            "--timeout",
            "40",
            "--json",
        ],
        Duration::from_secs(60),
    );
    stop(stand, "mrtwin stand");
    stop(node, "mrtwin node");
    let v = summary(&out);
    assert!(v["outputs"].as_u64().unwrap() >= 2000, "{out}");
    assert_eq!(v["forces_finite"], true, "{out}");
    // The stand measures the force: every output has a residual.
    assert_eq!(v["residuals_finite"], true, "{out}");
    let levels = v["health_levels"].as_array().unwrap();
    assert!(
        !levels.is_empty() && levels.iter().all(valid_level),
        "{out}"
    );
    assert_eq!(v["models"], serde_json::json!(["two-chamber"]), "{out}");
    // 10 Hz yield estimates over ≥ 2 s of outputs.
    assert!(v["yield_estimates"].as_u64().unwrap() >= 10, "{out}");
    let tau0 = v["tau0_pa"][0].as_f64().expect("a finite τ0 estimate");
    assert!(tau0 > 0.0 && tau0 < 1e6, "τ0 {tau0} Pa");
    let diag = v["diagnostics"][0]
        .as_object()
        .expect("a diagnostics array");
    assert!(diag.values().all(valid_level), "{diag:?}");
    assert!(
        diag.keys().any(|k| k.ends_with("sensor stream")),
        "{diag:?}"
    );
}

/// The `ws://…` address a node or demo printed for its Foxglove live view.
fn foxglove_url(node: &mut ChildGuard) -> String {
    let lines = node.stdout_lines();
    let (url, _) = await_line(&lines, Duration::from_secs(30), "Foxglove line", |l| {
        let rest = l.strip_prefix("Foxglove live view: ")?;
        Some(rest.split_whitespace().next()?.to_string())
    });
    // The rest of stdout is not read: keep the pipe drained so the child never blocks.
    std::thread::spawn(move || lines.iter().for_each(drop));
    url
}

/// What every live view carries, whoever serves it.
fn assert_live_view(v: &Value, out: &str, namespace: &str) {
    let channels: Vec<&str> = v["channels"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(Value::as_str)
        .collect();
    let mut expected: Vec<String> = [
        "sensor/sample",
        "twin/fv_loop",
        "twin/output",
        "twin/predicted_force",
        "twin/yield_estimate",
    ]
    .iter()
    .map(|t| format!("{namespace}/{t}"))
    .collect();
    expected.push("/diagnostics".into());
    expected.sort();
    assert_eq!(channels, expected, "{out}");
    // Every loop point is the sample and the twin output of its stamp, bit for bit.
    assert_eq!(v["mismatches"], 0, "{out}");
    let points = v["loop_points"].as_u64().unwrap();
    assert!(
        v["counts"]["fv_loop_checked"].as_u64().unwrap() >= points * 9 / 10,
        "most loop points were checked against their sample and output: {out}"
    );
    let range = &v["velocity_range"];
    assert!(
        range[0].as_f64().unwrap() < -0.01 && range[1].as_f64().unwrap() > 0.01,
        "the loop spans both stroke directions: {out}"
    );
    // A damper dissipates: force and velocity mostly share their sign (PHYSICS.md signs).
    assert!(v["dissipating_fraction"].as_f64().unwrap() > 0.8, "{out}");
    // The twin follows the stand's damper: residual small against the force.
    assert!(
        v["rms_residual"].as_f64().unwrap() < 0.05 * v["rms_force"].as_f64().unwrap(),
        "{out}"
    );
    let tau0 = v["tau0"].as_f64().expect("a yield estimate");
    assert!(tau0 > 0.0 && tau0 < 1e6, "τ0 {tau0} Pa");
    let diag = v["diagnostics"].as_object().expect("a diagnostics array");
    assert!(
        diag.keys().any(|k| k.ends_with("sensor stream")) && diag.values().all(valid_level),
        "{diag:?}"
    );
}

#[test]
#[cfg(all(
    feature = "ros2",
    feature = "zenoh",
    feature = "iceoryx2",
    feature = "foxglove"
))]
fn foxglove_client_watches_the_demo_twin_live() {
    let _serial = serial();
    let prefix = format!("mrtwin_fx{}", std::process::id());
    let mut demo = ChildGuard::spawn(mrtwin().args([
        "demo",
        "--duration",
        "60",
        "--domain-id",
        DOMAIN,
        "--key-prefix",
        &prefix,
        "--foxglove",
        "0",
    ]));
    let url = foxglove_url(&mut demo);
    assert!(
        url.starts_with("ws://127.0.0.1:"),
        "a bare port listens on loopback: {url}"
    );
    let out = run_python_example(
        "foxglove-client/client.py",
        &[
            "--url",
            &url,
            "--count",
            "3000",
            "--timeout",
            "30",
            "--json",
        ],
        Duration::from_secs(45),
    );
    stop(demo, "mrtwin demo");
    let v = summary(&out);
    assert_eq!(v["server"], "mrtwin /mrtwin_twin", "{out}");
    assert_live_view(&v, &out, "");
}

#[test]
#[cfg(all(feature = "zenoh", feature = "foxglove"))]
fn foxglove_client_watches_mrtwin_node_under_its_namespace() {
    let _serial = serial();
    let port = free_port();
    let damper = format!("exfx{}", std::process::id());
    let mut node = example_twin(
        &damper,
        port,
        &["--foxglove", "127.0.0.1:0"],
        &["-r", "__ns:=/rig7"],
    );
    let url = foxglove_url(&mut node);
    let stand = example_stand(&damper, port);
    let out = run_python_example(
        "foxglove-client/client.py",
        &[
            "--url",
            &url,
            "--count",
            "2000",
            "--timeout",
            "30",
            "--json",
        ],
        Duration::from_secs(45),
    );
    stop(stand, "mrtwin stand");
    stop(node, "mrtwin node");
    let v = summary(&out);
    assert_eq!(v["server"], "mrtwin /rig7/mrtwin_twin", "{out}");
    assert_live_view(&v, &out, "/rig7");
}

/// The example controller's binary, built the way `cargo run --release -p
/// iceoryx2-controller` builds it, in this test's target dir and profile (Cargo only
/// builds the binaries of a test's own package before it).
fn controller_binary() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable");
    // <target>/<profile>/deps/examples-<hash>
    let profile_dir = exe.parent().and_then(Path::parent).expect("profile dir");
    let target_dir = profile_dir.parent().expect("target dir");
    let profile = profile_dir.file_name().unwrap().to_str().unwrap();
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut cmd = Command::new(cargo);
    cmd.args([
        "build",
        "--quiet",
        "-p",
        "iceoryx2-controller",
        "--manifest-path",
    ])
    .arg(repo_root().join("Cargo.toml"))
    .arg("--target-dir")
    .arg(target_dir);
    match profile {
        "debug" => {}
        "release" => {
            cmd.arg("--release");
        }
        other => {
            cmd.args(["--profile", other]);
        }
    }
    let (ok, out, err) = ChildGuard::spawn(&mut cmd).wait(Duration::from_secs(900));
    assert!(
        ok,
        "building the iceoryx2 controller example failed:\n{err}\n{out}"
    );
    profile_dir.join(format!(
        "iceoryx2-controller{}",
        std::env::consts::EXE_SUFFIX
    ))
}

#[test]
#[cfg(feature = "iceoryx2")]
fn iceoryx2_controller_gets_forces_and_what_ifs_from_the_node() {
    let controller = controller_binary();
    let _serial = serial();
    let damper = format!("exi{}", std::process::id());
    let node = ChildGuard::spawn(mrtwin().args([
        "node",
        "--duration",
        "90",
        "--ros-args",
        "-p",
        &format!("damper:={damper}"),
        "-p",
        "input:=iceoryx2",
        "-p",
        "transports:=[iceoryx2]",
    ]));
    let service = format!("mrtwin/{damper}");
    let run = ChildGuard::spawn(Command::new(controller).args([
        "--service",
        &service,
        "--rate",
        "200",
        "--seconds",
        "3",
        "--print-every",
        "20",
    ]));
    let (ok, out, err) = run.wait(Duration::from_secs(60));
    let node_out = stop(node, "mrtwin node");
    assert!(ok, "controller failed:\n{err}\n{out}");
    assert!(
        out.starts_with(&format!("connected to {service}/twin/control")),
        "{out}"
    );
    // 600 cycles of one sample and one what-if, every one answered.
    let line = out
        .lines()
        .find(|l| l.starts_with("summary:"))
        .expect("summary line");
    let words: Vec<&str> = line.split_whitespace().collect();
    let after = |w: &str| -> f64 {
        let i = words
            .iter()
            .position(|x| *x == w)
            .unwrap_or_else(|| panic!("{line}"));
        words[i + 1].parse().unwrap()
    };
    assert_eq!(
        (after("sent"), after("replied"), after("lost")),
        (1200.0, 1200.0, 0.0),
        "{line}"
    );
    assert!(after("p50").is_finite() && after("p50") > 0.0, "{line}");
    // Each printed cycle: the force at 1 A and the what-if at 2 A, finite; the what-if is
    // the twin's answer for another current, not an echo.
    let cycles: Vec<(f64, f64)> = out
        .lines()
        .filter(|l| l.starts_with("t="))
        .map(|l| {
            let n: Vec<f64> = l
                .split_whitespace()
                .filter_map(|w| w.parse().ok())
                .collect();
            // t, x, force, current, planned current, what-if force, latency
            (n[2], n[5])
        })
        .collect();
    assert_eq!(cycles.len(), 30, "{out}");
    assert!(
        cycles.iter().all(|(f, w)| f.is_finite() && w.is_finite()),
        "{out}"
    );
    assert!(cycles.iter().any(|(f, w)| (f - w).abs() > 1.0), "{out}");
    assert!(
        node_out.contains("600 stepped") && node_out.contains("1200 control requests"),
        "{node_out}"
    );
}

#[test]
#[cfg(feature = "zenoh")]
fn rosbags_reader_reads_simulated_replayed_and_recorded_bags() {
    let dir = TempDir::new("examples_rosbags");
    let path = |name: &str| dir.path(name).display().to_string();
    let run = |args: &[&str]| {
        let o = mrtwin().args(args).output().expect("run mrtwin");
        assert!(
            o.status.success(),
            "mrtwin {args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    };
    // 2 s at 1 kHz: 2000 samples.
    run(&[
        "simulate",
        "--model",
        "two-chamber",
        "--frequency",
        "2",
        "--current",
        "0.5,1",
        "--duration",
        "1",
        "--rate",
        "1000",
        "--out",
        &path("sim"),
    ]);
    run(&["replay", &path("sim"), "--out", &path("replay")]);
    let read = |bag: &str| {
        let out = run_python_example(
            "rosbags-reader/read_bag.py",
            &[bag, "--json"],
            Duration::from_secs(60),
        );
        (summary(&out), out)
    };
    let count = |v: &Value, suffix: &str| -> u64 {
        v["counts"]
            .as_object()
            .unwrap()
            .iter()
            .find(|(topic, _)| topic.ends_with(suffix))
            .map_or(0, |(_, n)| n.as_u64().unwrap())
    };

    let (sim, out) = read(&path("sim"));
    assert_eq!(count(&sim, "/sensor/sample"), 2000, "{out}");
    assert_eq!(sim["counts"], sim["metadata_counts"], "{out}");
    assert!(out.contains("/sensor/sample t=0.000 s: x"), "{out}");

    let (rep, out) = read(&path("replay"));
    assert_eq!(rep["counts"], rep["metadata_counts"], "{out}");
    for topic in ["/sensor/sample", "/twin/output", "/twin/predicted_force"] {
        assert_eq!(count(&rep, topic), 2000, "{topic}: {out}");
    }
    assert!(count(&rep, "/twin/yield_estimate") >= 10, "{out}");
    assert!(count(&rep, "/diagnostics") >= 1, "{out}");
    assert_eq!(rep["outputs_finite"], true, "{out}");
    let levels = rep["health_levels"].as_array().unwrap();
    assert!(
        !levels.is_empty() && levels.iter().all(valid_level),
        "{out}"
    );
    assert!(
        rep["types"]
            .as_object()
            .unwrap()
            .values()
            .any(|t| t == "mrtwin_msgs/msg/TwinOutput"),
        "{out}"
    );

    // A live recording: twin and recorder on zenoh (own port and damper), the stand for 2 s.
    let _serial = serial();
    let port = free_port();
    let damper = format!("exr{}", std::process::id());
    let twin_yaml = params_file("twin.yaml");
    let node = ChildGuard::spawn(
        mrtwin()
            .args([
                "node",
                "--duration",
                "90",
                "--ros-args",
                "--params-file",
                &twin_yaml,
            ])
            .args(zenoh_overrides(&damper, port, "listen")),
    );
    let record = ChildGuard::spawn(
        mrtwin()
            .args([
                "record",
                "--out",
                &path("recorded"),
                "--ros-args",
                "--params-file",
                &twin_yaml,
            ])
            .args(zenoh_overrides(&damper, port, "connect")),
    );
    std::thread::sleep(Duration::from_millis(1500));
    let stand_yaml = params_file("stand.node.yaml");
    let (ok, _, err) = ChildGuard::spawn(
        mrtwin()
            .args([
                "stand",
                "--duration",
                "2",
                "--ros-args",
                "--params-file",
                &stand_yaml,
            ])
            .args(zenoh_overrides(&damper, port, "connect")),
    )
    .wait(Duration::from_secs(30));
    assert!(ok, "stand failed: {err}");
    std::thread::sleep(Duration::from_millis(500));
    stop(record, "mrtwin record");
    stop(node, "mrtwin node");
    let (rec, out) = read(&path("recorded"));
    assert_eq!(rec["counts"], rec["metadata_counts"], "{out}");
    let samples = count(&rec, "/sensor/sample");
    assert!(samples >= 1500, "{samples} samples recorded: {out}");
    assert!(count(&rec, "/twin/output") >= 1500, "{out}");
    assert_eq!(rec["outputs_finite"], true, "{out}");
}
