//! The live system against real peers: `mrtwin node` and `mrtwin stand` as separate
//! processes, a Python eclipse-zenoh subscriber decoding with python `rosbags`, and an
//! iceoryx2 controller in this test process (a separate process from the node).
//!
//! Every test has its own damper name, zenoh port and iceoryx2 service prefix, and every
//! wait is bounded.
//!
//! A test runs when the transports it needs are compiled in (`cargo test -p mrtwin
//! --no-default-features --features zenoh` runs the zenoh ones); the helpers they share
//! are then partly unused.
#![cfg_attr(
    not(all(feature = "ros2", feature = "zenoh", feature = "iceoryx2")),
    allow(dead_code, unused_imports)
)]

use std::path::Path;
use std::process::Command;
use std::time::Duration;

#[cfg(feature = "iceoryx2")]
use bridge::iceoryx2::controller::{run_controller, ControllerOptions};
#[cfg(feature = "iceoryx2")]
use bridge::iceoryx2::Iceoryx2Config;
use mrtwin_tests::{
    await_line, free_port, run_python, run_python_env, run_python_with_msgs, ChildGuard, TempDir,
};

/// The live tests start several processes each and check timing (staleness within 2 s,
/// 1 kHz without loss): on a 2-core machine they run one at a time.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|p| p.into_inner())
}

fn mrtwin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mrtwin"))
}

fn write(path: &Path, text: &str) {
    std::fs::write(path, text).expect("write parameter file");
}

/// Subscribes to `mrtwin/<damper>/**` for `seconds`, prints one JSON line per message:
/// receive wall time, key and the decoded fields (CDR decoded by python `rosbags` from our
/// .msg files).
const ZENOH_LISTENER: &str = r#"
import json, sys, time, threading
import zenoh
from rosbags.typesys import Stores, get_typestore, get_types_from_msg
endpoint, damper, seconds, msgdir = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4]
ts = get_typestore(Stores.ROS2_HUMBLE)
types = {}
for name in ["TwinOutput", "YieldEstimate", "DamperSample"]:
    types.update(get_types_from_msg(open(f"{msgdir}/{name}.msg").read(), f"mrtwin_msgs/msg/{name}"))
ts.register(types)
kinds = {"twin/output": "mrtwin_msgs/msg/TwinOutput", "twin/yield_estimate": "mrtwin_msgs/msg/YieldEstimate",
         "diagnostics": "diagnostic_msgs/msg/DiagnosticArray", "twin/predicted_force": "std_msgs/msg/Float64"}
lock = threading.Lock()
out = []
def on_sample(s):
    now = time.time()
    key = str(s.key_expr)
    rel = key.split(f"mrtwin/{damper}/", 1)[1]
    if rel not in kinds:
        return
    m = ts.deserialize_cdr(bytes(s.payload.to_bytes()), kinds[rel])
    rec = {"t": now, "key": rel}
    if rel == "twin/output":
        rec.update(stamp=m.header.stamp.sec + m.header.stamp.nanosec * 1e-9, predicted=m.predicted_force,
                   measured=m.measured_force, residual=m.residual, model=m.model_id)
    elif rel == "diagnostics":
        rec.update(status={st.name: int(st.level) for st in m.status})
    elif rel == "twin/yield_estimate":
        rec.update(tau0=m.tau0, current=m.current)
    with lock:
        out.append(rec)
conf = zenoh.Config()
conf.insert_json5("mode", '"peer"')
conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
conf.insert_json5("scouting/multicast/enabled", "false")
session = zenoh.open(conf)
sub = session.declare_subscriber(f"mrtwin/{damper}/**", on_sample)
print(json.dumps({"ready": time.time()}), flush=True)
time.sleep(seconds)
session.close()
with lock:
    for r in out:
        print(json.dumps(r))
"#;

#[test]
#[cfg(feature = "zenoh")]
fn zenoh_peer_gets_twin_outputs_and_health_goes_stale_then_ok() {
    let _serial = serial();
    let dir = TempDir::new("zenoh_stale");
    let port = free_port();
    let damper = format!("zs{}", std::process::id());
    let twin_params = dir.path("twin.yaml");
    write(
        &twin_params,
        &format!(
            "mrtwin_twin:\n  ros__parameters:\n    damper: {damper}\n    model: two-chamber\n    transports: [zenoh]\n    input: zenoh\n    control_service: false\n    stale_after_s: 0.5\n    zenoh:\n      multicast_scouting: false\n      listen: [\"tcp/127.0.0.1:{port}\"]\n"
        ),
    );
    let stand_params = dir.path("stand.yaml");
    write(
        &stand_params,
        &format!(
            "mrtwin_stand:\n  ros__parameters:\n    damper: {damper}\n    model: two-chamber\n    transports: [zenoh]\n    currents_a: [1.0]\n    frequencies_hz: [2.0]\n    segment_duration_s: 100.0\n    noise_n: 5.0\n    faults:\n      silence_at_s: 3.0\n      silence_for_s: 3.0\n    zenoh:\n      multicast_scouting: false\n      connect: [\"tcp/127.0.0.1:{port}\"]\n"
        ),
    );
    let node = ChildGuard::spawn(mrtwin().args([
        "node",
        "--duration",
        "13",
        "--ros-args",
        "--params-file",
        twin_params.to_str().unwrap(),
    ]));
    std::thread::sleep(Duration::from_millis(500));
    let msgdir = mrtwin_tests::repo_root().join("msgs/msg");
    let listener = std::thread::spawn({
        let endpoint = format!("tcp/127.0.0.1:{port}");
        let damper = damper.clone();
        move || {
            run_python(
                ZENOH_LISTENER,
                &[&endpoint, &damper, "11", msgdir.to_str().unwrap()],
                Duration::from_secs(40),
            )
        }
    });
    std::thread::sleep(Duration::from_millis(1500));
    let stand = ChildGuard::spawn(mrtwin().args([
        "stand",
        "--duration",
        "9",
        "--ros-args",
        "--params-file",
        stand_params.to_str().unwrap(),
    ]));
    let (ok, _, err) = stand.wait(Duration::from_secs(30));
    assert!(ok, "stand failed: {err}");
    let out = listener.join().expect("listener thread");
    let (ok, node_out, err) = node.wait(Duration::from_secs(30));
    assert!(ok, "node failed: {err}");

    let recs: Vec<serde_json::Value> = out
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .filter(|v: &serde_json::Value| v.get("key").is_some())
        .collect();
    let outputs: Vec<&serde_json::Value> =
        recs.iter().filter(|r| r["key"] == "twin/output").collect();
    // 9 s of stand minus 3 s of silence at 1 kHz; the listener joins late by ~1.5 s.
    assert!(
        outputs.len() > 4000,
        "only {} twin outputs reached the zenoh peer; node: {node_out}",
        outputs.len()
    );
    assert!(outputs.iter().all(|o| o["model"] == "two-chamber"));
    let rms = (outputs
        .iter()
        .map(|o| o["residual"].as_f64().unwrap().powi(2))
        .sum::<f64>()
        / outputs.len() as f64)
        .sqrt();
    let peak = outputs
        .iter()
        .map(|o| o["measured"].as_f64().unwrap().abs())
        .fold(0.0, f64::max);
    assert!(
        rms < 0.05 * peak,
        "twin and stand run the same model: residual RMS {rms} N vs peak {peak} N"
    );
    assert!(
        recs.iter().any(|r| r["key"] == "twin/yield_estimate"),
        "no yield estimate"
    );

    // The silence: the largest gap between consecutive output stamps.
    let stamps: Vec<f64> = outputs
        .iter()
        .map(|o| o["stamp"].as_f64().unwrap())
        .collect();
    let (i, gap) = stamps
        .windows(2)
        .enumerate()
        .map(|(i, w)| (i, w[1] - w[0]))
        .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
    assert!(
        gap > 2.5,
        "no silence seen in the stamps (largest gap {gap} s)"
    );
    let silence_from = stamps[i];
    let resumed_at = stamps[i + 1];
    let stream_level = |r: &serde_json::Value| -> Option<i64> {
        r.get("status")?
            .as_object()?
            .iter()
            .find(|(k, _)| k.ends_with("sensor stream"))
            .and_then(|(_, v)| v.as_i64())
    };
    let diags: Vec<(f64, i64)> = recs
        .iter()
        .filter_map(|r| Some((r["t"].as_f64()?, stream_level(r)?)))
        .collect();
    assert!(!diags.is_empty(), "no /diagnostics");
    let stale = diags
        .iter()
        .find(|(t, l)| *t > silence_from && *l == 3)
        .expect("health never went STALE");
    assert!(
        stale.0 - silence_from < 2.0,
        "STALE {} s after the last sample",
        stale.0 - silence_from
    );
    let back = diags
        .iter()
        .find(|(t, l)| *t > resumed_at && *l == 0)
        .expect("health never came back to OK");
    assert!(
        back.0 - resumed_at < 2.0,
        "OK {} s after samples resumed",
        back.0 - resumed_at
    );
}

#[test]
#[cfg(feature = "iceoryx2")]
fn iceoryx2_controller_process_runs_1khz_for_10s_against_the_node_without_loss() {
    let _serial = serial();
    let dir = TempDir::new("ice_loop");
    let prefix = format!("mrtwin/icetest{}", std::process::id());
    let params = dir.path("twin.yaml");
    write(
        &params,
        &format!(
            "mrtwin_twin:\n  ros__parameters:\n    damper: ice{}\n    model: two-chamber\n    transports: [iceoryx2]\n    input: iceoryx2\n    control_service: true\n    iceoryx2:\n      service_prefix: {prefix}\n",
            std::process::id()
        ),
    );
    let node = ChildGuard::spawn(mrtwin().args([
        "node",
        "--duration",
        "25",
        "--ros-args",
        "--params-file",
        params.to_str().unwrap(),
    ]));
    let cfg = Iceoryx2Config {
        service_prefix: prefix,
        ..Default::default()
    };
    let summary = run_controller(
        &cfg,
        &ControllerOptions {
            rate_hz: 1000.0,
            seconds: 10.0,
            server_timeout: Duration::from_secs(10),
            ..Default::default()
        },
    )
    .expect("controller loop");
    node.interrupt();
    let (ok, out, err) = node.wait(Duration::from_secs(20));
    assert!(ok, "node failed: {err}");
    assert_eq!(summary.samples, 10_000, "{summary:?}");
    assert_eq!(summary.lost, 0, "{summary:?}");
    assert_eq!(summary.timeouts, 0, "{summary:?}");
    assert_eq!(summary.mismatched, 0, "{summary:?}");
    assert_eq!(summary.rejected, 0, "{summary:?}");
    assert!(out.contains("control requests"), "{out}");
}

/// Runs `mrtwin node` on ROS 2 alone (its own domain `domain`, namespace `ns`, samples in
/// over ROS 2) while `peer` runs with that domain's ROS environment; the peer's last line
/// as JSON and the node's standard output, once the node stopped cleanly.
#[cfg(feature = "ros2")]
fn ros2_node_with_peer(
    domain: u16,
    ns: &str,
    damper: &str,
    peer: impl FnOnce(&[(&str, &str)]) -> String,
) -> (serde_json::Value, String) {
    let dir = TempDir::new(&format!("ros2_peer_{damper}"));
    let params = dir.path("twin.yaml");
    write(
        &params,
        &format!(
            "mrtwin_twin:\n  ros__parameters:\n    damper: {damper}\n    model: two-chamber\n    transports: [ros2]\n    input: ros2\n    control_service: false\n    ros2:\n      domain_id: {domain}\n"
        ),
    );
    let node = ChildGuard::spawn(mrtwin().args([
        "node",
        "--duration",
        "40",
        "--ros-args",
        "--params-file",
        params.to_str().unwrap(),
        "-r",
        &format!("__ns:={ns}"),
    ]));
    let out = peer(&[
        ("ROS_DOMAIN_ID", &domain.to_string()),
        ("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp"),
    ]);
    node.interrupt();
    let (ok, node_out, err) = node.wait(Duration::from_secs(20));
    assert!(ok, "node failed: {err}");
    let v = serde_json::from_str(out.lines().last().unwrap()).expect("rclpy JSON");
    (v, node_out)
}

/// An rclpy node (Fast DDS from PyPI): publishes damper samples as the standard
/// `std_msgs/Float64MultiArray` on `<ns>/sensor/sample_array`, listens to the twin's
/// predicted force (`std_msgs/Float64`) and `/diagnostics`, and reports rclpy's view of
/// the graph. Prints one JSON object.
const RCLPY_PEER: &str = r#"
import json, math, sys, time
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy, HistoryPolicy
from std_msgs.msg import Float64, Float64MultiArray, MultiArrayDimension
from diagnostic_msgs.msg import DiagnosticArray
ns, label = sys.argv[1], sys.argv[2]
rclpy.init()
node = rclpy.create_node("rclpy_peer")
forces, diags = [], []
qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
node.create_subscription(Float64, f"{ns}/twin/predicted_force", lambda m: forces.append(m.data), qos)
node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: diags.append([(s.name, int.from_bytes(s.level, "little") if isinstance(s.level, bytes) else int(s.level)) for s in m.status]), 10)
pub = node.create_publisher(Float64MultiArray, f"{ns}/sensor/sample_array", QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT))
deadline = time.time() + 25
while pub.get_subscription_count() == 0 and time.time() < deadline:
    rclpy.spin_once(node, timeout_sec=0.05)
matched = pub.get_subscription_count()
t0 = time.time()
sent = 0
for k in range(1000):
    t = t0 + k * 0.002
    w = 2 * math.pi * 2.0
    x, v = 0.01 * math.sin(w * (t - t0)), 0.01 * w * math.cos(w * (t - t0))
    m = Float64MultiArray()
    m.layout.dim = [MultiArrayDimension(label=label, size=6, stride=6)]
    m.data = [t, x, v, 0.0, 1.0, float("nan")]
    pub.publish(m)
    sent += 1
    end = t0 + (k + 1) * 0.002
    while time.time() < end:
        rclpy.spin_once(node, timeout_sec=max(0.0, end - time.time()))
deadline = time.time() + 5
while time.time() < deadline and len(forces) < sent:
    rclpy.spin_once(node, timeout_sec=0.05)
graph = node.get_topic_names_and_types()
nodes = node.get_node_names_and_namespaces()
print(json.dumps({"matched": matched, "sent": sent, "forces": forces, "diags": diags,
                  "topics": {n: t for n, t in graph}, "nodes": nodes}))
node.destroy_node()
rclpy.shutdown()
"#;

#[test]
#[cfg(feature = "ros2")]
fn rclpy_feeds_the_twin_and_reads_its_force_diagnostics_and_graph() {
    let _serial = serial();
    // This test's own ROS domain.
    let (v, node_out) = ros2_node_with_peer(91, "/rig", "rclpydamper", |env| {
        run_python_env(
            RCLPY_PEER,
            &["/rig", msgs::SAMPLE_ARRAY_LABEL],
            env,
            Duration::from_secs(60),
        )
    });
    assert!(
        v["matched"].as_u64().unwrap() >= 1,
        "rclpy publisher never matched the twin: {v}"
    );
    // The twin consumed rclpy's samples: it printed how many it stepped.
    let stepped: u64 = node_out
        .split(" stepped")
        .next()
        .and_then(|s| s.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!(
        stepped >= 900,
        "twin stepped on {stepped} of 1000 rclpy samples: {node_out}"
    );
    let forces: Vec<f64> = v["forces"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_f64().unwrap_or(f64::NAN))
        .collect();
    assert!(
        forces.len() >= 900,
        "rclpy got {} predicted forces",
        forces.len()
    );
    assert!(
        forces.iter().all(|f| f.is_finite() && f.abs() < 1e5),
        "implausible forces"
    );
    assert!(
        forces.iter().any(|f| *f > 0.0) && forces.iter().any(|f| *f < 0.0),
        "force never changed sign over a stroke"
    );
    let names: Vec<String> = v["diags"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|a| {
            a.as_array()
                .unwrap()
                .iter()
                .map(|p| p[0].as_str().unwrap().to_string())
        })
        .collect();
    assert!(
        names.iter().any(|n| n == "/rig/mrtwin_twin: sensor stream"),
        "diagnostic names: {names:?}"
    );
    assert!(
        names
            .iter()
            .any(|n| n == "/rig/mrtwin_twin: prediction residual"),
        "diagnostic names: {names:?}"
    );
    let topics = &v["topics"];
    for (t, ty) in [
        ("/rig/twin/predicted_force", "std_msgs/msg/Float64"),
        ("/rig/twin/output", "mrtwin_msgs/msg/TwinOutput"),
        ("/rig/twin/yield_estimate", "mrtwin_msgs/msg/YieldEstimate"),
        ("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),
    ] {
        let types: Vec<&str> = topics[t]
            .as_array()
            .map(|a| a.iter().filter_map(|x| x.as_str()).collect())
            .unwrap_or_default();
        assert!(
            types.contains(&ty),
            "{t} has types {types:?} in rclpy's graph"
        );
    }
    let nodes = v["nodes"].as_array().unwrap();
    assert!(
        nodes
            .iter()
            .any(|n| n[0] == "mrtwin_twin" && n[1] == "/rig"),
        "nodes: {nodes:?}"
    );
}

/// An rclpy node with `mrtwin_msgs` built natively by rosidl from PyPI wheels
/// (`scripts/setup-msgs.sh`): publishes `DamperSample` on `<ns>/sensor/sample` (1000
/// samples of a 2 Hz, 10 mm stroke at 1 A with F = 1000 N sgn v + 2000 N s/m v) and reads
/// the twin's `TwinOutput` and `YieldEstimate` as typed messages. Prints one JSON object.
const RCLPY_NATIVE_PEER: &str = r#"
import json, math, sys, time
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy, HistoryPolicy
from mrtwin_msgs.msg import DamperSample, TwinOutput, YieldEstimate
ns = sys.argv[1]
rclpy.init()
node = rclpy.create_node("rclpy_native_peer")
outputs, estimates = [], []
f = lambda x: x if math.isfinite(x) else None  # JSON has no NaN
qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
node.create_subscription(TwinOutput, f"{ns}/twin/output", lambda m: outputs.append(
    [f(m.predicted_force), f(m.measured_force), f(m.residual), m.model_id, int(m.health_level)]), qos)
node.create_subscription(YieldEstimate, f"{ns}/twin/yield_estimate", lambda m: estimates.append(
    [f(m.current), f(m.tau0), f(m.tau0_std), list(m.curve_current), [f(x) for x in m.curve_tau0]]), qos)
pub = node.create_publisher(DamperSample, f"{ns}/sensor/sample", QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT))
deadline = time.time() + 25
while pub.get_subscription_count() == 0 and time.time() < deadline:
    rclpy.spin_once(node, timeout_sec=0.05)
matched = pub.get_subscription_count()
t0 = time.time()
sent = 0
for k in range(1000):
    t = k * 0.002
    w = 2 * math.pi * 2.0
    m = DamperSample()
    m.header.stamp.sec, m.header.stamp.nanosec = int(t), int(round((t % 1) * 1e9))
    m.header.frame_id = "damper"
    m.displacement, m.velocity = 0.01 * math.sin(w * t), 0.01 * w * math.cos(w * t)
    m.force = 1000.0 * math.copysign(1.0, m.velocity) + 2000.0 * m.velocity
    m.current, m.temperature = 1.0, float("nan")
    pub.publish(m)
    sent += 1
    end = t0 + (k + 1) * 0.002
    while time.time() < end:
        rclpy.spin_once(node, timeout_sec=max(0.0, end - time.time()))
deadline = time.time() + 5
while time.time() < deadline and len(outputs) < sent:
    rclpy.spin_once(node, timeout_sec=0.05)
print(json.dumps({"matched": matched, "sent": sent, "outputs": outputs, "estimates": estimates}))
node.destroy_node()
rclpy.shutdown()
"#;

#[test]
#[cfg(feature = "ros2")]
fn rclpy_exchanges_native_mrtwin_msgs_with_the_node() {
    let _serial = serial();
    // This test's own ROS domain.
    let (v, node_out) = ros2_node_with_peer(92, "/native", "nativedamper", |env| {
        run_python_with_msgs(
            RCLPY_NATIVE_PEER,
            &["/native"],
            env,
            Duration::from_secs(60),
        )
    });
    assert!(v["matched"].as_u64().unwrap() >= 1, "never matched: {v}");
    let outputs = v["outputs"].as_array().unwrap();
    assert!(
        outputs.len() >= 900,
        "rclpy decoded {} TwinOutput of 1000 samples sent: {node_out}",
        outputs.len()
    );
    // Each output carries the measured force of the sample rclpy sent, typed.
    for o in outputs {
        let (pred, meas, resid) = (o[0].as_f64(), o[1].as_f64(), o[2].as_f64());
        let (pred, meas, resid) = (pred.unwrap(), meas.unwrap(), resid.unwrap());
        assert!(pred.is_finite() && pred.abs() < 1e5, "{o}");
        assert!((meas.abs() - 1000.0).abs() <= 2000.0 * 0.126, "{o}");
        assert!(
            (resid - (meas - pred)).abs() < 1e-6 * meas.abs().max(1.0),
            "{o}"
        );
        assert_eq!(o[3], "two-chamber", "{o}");
        assert!(o[4].as_u64().unwrap() <= 3, "{o}");
    }
    // The twin's yield estimate, typed: at 1 A, with a curve; τ0 = F_y/a with F_y = 1000 N
    // and a = 2 L A1/h = 0.0363 m² of the default two-chamber damper.
    let estimates = v["estimates"].as_array().unwrap();
    let last = estimates
        .iter()
        .rev()
        .find(|e| e[1].as_f64().is_some())
        .unwrap_or_else(|| panic!("no finite τ0 in {} YieldEstimate", estimates.len()));
    let tau0 = last[1].as_f64().unwrap();
    eprintln!(
        "{} TwinOutput, {} YieldEstimate decoded; last estimate {last}",
        outputs.len(),
        estimates.len()
    );
    assert!((last[0].as_f64().unwrap() - 1.0).abs() < 1e-9, "{last}");
    assert!(
        (tau0 / (1000.0 / 0.0363) - 1.0).abs() < 0.2,
        "τ0 {tau0} Pa: {last}"
    );
    assert!(!last[3].as_array().unwrap().is_empty(), "{last}");
}

#[test]
#[cfg(all(feature = "ros2", feature = "zenoh", feature = "iceoryx2"))]
fn demo_runs_stand_and_twin_over_all_three_transports() {
    let _serial = serial();
    let o = mrtwin()
        .args(["demo", "--duration", "4", "--domain-id", "93"])
        .output()
        .expect("run demo");
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "demo failed: {}\n{out}",
        String::from_utf8_lossy(&o.stderr)
    );
    let live = out.lines().filter(|l| l.starts_with("t=")).count();
    assert!(live >= 3, "expected a live line per second:\n{out}");
    let line = out
        .lines()
        .find(|l| l.contains("outputs received:"))
        .expect("summary line");
    let counts: Vec<u64> = line
        .split_whitespace()
        .filter_map(|w| w.parse().ok())
        .collect();
    assert_eq!(counts.len(), 3, "{line}");
    // 4 s at 1 kHz; ROS 2 discovery may cost the first few hundred.
    assert!(counts.iter().all(|&n| n > 2500), "{line}");
    let whatif = out
        .lines()
        .find(|l| l.contains("what-if requests"))
        .expect("what-if line");
    let answered: u64 = whatif
        .split_whitespace()
        .find_map(|w| w.parse().ok())
        .unwrap();
    assert!(answered > 100, "{whatif}");
    assert!(out.contains("yield stress at 0.50 A"), "{out}");
}

/// Two stock zenoh peers in their default configuration, one putting and one
/// subscribing: whether multicast scouting works on this machine at all.
const MULTICAST_PROBE: &str = r#"
import sys, time, threading, zenoh
key = sys.argv[1]
sub_session = zenoh.open(zenoh.Config())
got = threading.Event()
sub = sub_session.declare_subscriber(key, lambda s: got.set())
pub_session = zenoh.open(zenoh.Config())
deadline = time.time() + 8
while not got.is_set() and time.time() < deadline:
    pub_session.put(key, b"probe")
    time.sleep(0.1)
seen = got.is_set()
sub_session.close()
pub_session.close()
print("seen" if seen else "unseen")
"#;

/// Messages per key in 3 s from a zenoh peer that connects to `endpoint` (argv 1) and
/// subscribes to `keys` (argv 2).
const DIRECT_COUNT: &str = r#"
import collections, json, sys, time, zenoh
conf = zenoh.Config()
conf.insert_json5("connect/endpoints", json.dumps([sys.argv[1]]))
conf.insert_json5("scouting/multicast/enabled", "false")
n = collections.Counter()
s = zenoh.open(conf)
sub = s.declare_subscriber(sys.argv[2], lambda x: n.update([str(x.key_expr)]))
time.sleep(3)
s.close()
print(dict(n))
"#;

#[test]
#[cfg(all(feature = "ros2", feature = "zenoh", feature = "iceoryx2"))]
fn a_stock_zenoh_peer_sees_the_demo_with_the_command_it_prints() {
    let _serial = serial();
    // The test's own key prefix and domain; everything else is what a user gets.
    let prefix = format!("mrtwin_look{}", std::process::id());
    let mut demo = ChildGuard::spawn(mrtwin().args([
        "demo",
        "--duration",
        "20",
        "--domain-id",
        "94",
        "--key-prefix",
        &prefix,
    ]));
    let lines = demo.stdout_lines();
    // The first live line comes after the commands: by then the twin publishes.
    let ((), printed) = await_line(&lines, Duration::from_secs(30), "live line", |l| {
        l.starts_with("t=").then_some(())
    });
    let command = printed
        .iter()
        .find_map(|l| l.trim().strip_prefix("python3 -c "))
        .unwrap_or_else(|| panic!("no zenoh command printed:\n{}", printed.join("\n")))
        .to_string();
    assert!(
        command.contains(&format!("{prefix}/demo")) && command.contains("zenoh.Config()"),
        "the command subscribes with zenoh's default configuration to the demo's keys: {command}"
    );
    assert!(
        printed
            .iter()
            .any(|l| l.contains("ROS_DOMAIN_ID=94 ros2 topic echo /twin/predicted_force")),
        "{}",
        printed.join("\n")
    );
    // Run it as pasted, with the interop venv's python3 first on PATH.
    let py = mrtwin_tests::python();
    let path = format!(
        "{}:{}",
        py.parent().expect("venv bin").display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let run = |cmd: &str| {
        let child = ChildGuard::spawn(
            Command::new("bash")
                .args(["-c", &format!("python3 -c {cmd}")])
                .env("PATH", &path),
        );
        let (ok, out, err) = child.wait(Duration::from_secs(30));
        assert!(ok, "the printed command failed:\n{err}\n{out}");
        out
    };
    let out = run(&command);
    let count = |topic: &str| -> u64 {
        let key = format!("'{prefix}/");
        out.split(", ")
            .filter(|kv| kv.contains(&key) && kv.contains(&format!("/{topic}'")))
            .find_map(|kv| {
                kv.rsplit(": ")
                    .next()?
                    .trim_matches(['}', '\n'])
                    .parse()
                    .ok()
            })
            .unwrap_or(0)
    };
    if count("twin/output") == 0 {
        // Nothing seen: tell a machine without multicast from a demo that is not
        // discoverable. Without multicast the user's way in is the direct endpoint.
        let probe = run_python(
            MULTICAST_PROBE,
            &[&format!("{prefix}/probe")],
            Duration::from_secs(30),
        );
        assert!(
            probe.contains("unseen"),
            "stock peers see each other here, but not the demo: {out}"
        );
        eprintln!(
            "multicast scouting does not work on this machine: checking the demo's direct endpoint"
        );
        let endpoint = printed
            .iter()
            .find_map(|l| l.split(" -e ").nth(1))
            .expect("direct endpoint printed")
            .trim()
            .to_string();
        let keys = format!("{prefix}/**");
        let direct = run_python(DIRECT_COUNT, &[&endpoint, &keys], Duration::from_secs(30));
        assert!(direct.contains("/twin/output"), "{direct}");
        return;
    }
    // 3 s of a 1 kHz twin; discovery may cost the first few hundred milliseconds.
    assert!(count("twin/output") > 1500, "{out}");
    assert!(
        count("sensor/sample") > 1500,
        "the stand is discoverable too: {out}"
    );
    assert!(count("diagnostics") >= 1, "{out}");
    drop(demo);
}

#[test]
#[cfg(feature = "zenoh")]
fn launch_brings_up_twin_and_stand_and_stops_them() {
    let _serial = serial();
    let dir = TempDir::new("launch");
    let port = free_port();
    let damper = format!("la{}", std::process::id());
    write(
        &dir.path("twin.yaml"),
        &format!("/**:\n  ros__parameters:\n    damper: {damper}\n    transports: [zenoh]\n    input: zenoh\n    control_service: false\n    zenoh:\n      multicast_scouting: false\n      listen: [\"tcp/127.0.0.1:{port}\"]\n"),
    );
    write(
        &dir.path("stand.yaml"),
        &format!("mrtwin_stand:\n  ros__parameters:\n    damper: {damper}\n    transports: [zenoh]\n    zenoh:\n      multicast_scouting: false\n      connect: [\"tcp/127.0.0.1:{port}\"]\n"),
    );
    let launch = dir.path("system.launch.yaml");
    write(
        &launch,
        "launch:\n  - node:\n      pkg: mrtwin\n      exec: twin\n      name: twin_a\n      namespace: /rig\n      param:\n        - from: twin.yaml\n        - {name: stale_after_s, value: 0.7}\n  - node:\n      pkg: mrtwin\n      exec: stand\n      param:\n        - from: stand.yaml\n",
    );
    let o = mrtwin()
        .args(["launch", launch.to_str().unwrap(), "--duration", "5"])
        .output()
        .expect("launch");
    let (out, err) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert!(o.status.success(), "launch failed:\n{err}\n{out}");
    // Both nodes ran under their launch names and stopped cleanly on SIGINT.
    let twin = out
        .lines()
        .find(|l| l.starts_with("/rig/twin_a: stopped"))
        .unwrap_or_else(|| panic!("{out}\n{err}"));
    let stepped: u64 = twin
        .split(" stepped")
        .next()
        .unwrap()
        .rsplit(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(stepped > 2000, "{twin}");
    assert!(
        out.lines().any(|l| l.starts_with("/mrtwin_stand: stopped")),
        "{out}"
    );

    // A typo in the launch file names the file, the key and its line.
    let bad = dir.path("bad.launch.yaml");
    write(
        &bad,
        "launch:\n  - node:\n      pkg: mrtwin\n      exec: twin\n      namspace: /x\n",
    );
    let o = mrtwin()
        .args(["launch", bad.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success()
            && err.contains("bad.launch.yaml")
            && err.contains("namspace")
            && err.contains("line 5"),
        "{err}"
    );
}

#[test]
#[cfg(feature = "zenoh")]
fn record_killed_with_sigkill_leaves_a_readable_bag_up_to_the_last_flush() {
    let _serial = serial();
    let dir = TempDir::new("record_kill");
    let port = free_port();
    let damper = format!("rk{}", std::process::id());
    let params = dir.path("params.yaml");
    write(
        &params,
        &format!("/**:\n  ros__parameters:\n    damper: {damper}\n    transports: [zenoh]\n    zenoh:\n      multicast_scouting: false\n      connect: [\"tcp/127.0.0.1:{port}\"]\n"),
    );
    let recorder_params = dir.path("recorder.yaml");
    write(
        &recorder_params,
        &format!("/**:\n  ros__parameters:\n    damper: {damper}\n    zenoh:\n      multicast_scouting: false\n      listen: [\"tcp/127.0.0.1:{port}\"]\n"),
    );
    let bag = dir.path("bag");
    let recorder = ChildGuard::spawn(mrtwin().args([
        "record",
        "--out",
        bag.to_str().unwrap(),
        "--transport",
        "zenoh",
        "--flush-period",
        "0.5",
        "--ros-args",
        "--params-file",
        recorder_params.to_str().unwrap(),
    ]));
    std::thread::sleep(Duration::from_millis(800));
    let stand = ChildGuard::spawn(mrtwin().args([
        "stand",
        "--duration",
        "3",
        "--ros-args",
        "--params-file",
        params.to_str().unwrap(),
    ]));
    let (ok, _, err) = stand.wait(Duration::from_secs(30));
    assert!(ok, "stand failed: {err}");
    std::thread::sleep(Duration::from_millis(1500)); // ≥ one flush period after the last sample
                                                     // kill -9: no chance to finish the bag.
    let mut recorder = recorder;
    let child = recorder.0.as_mut().unwrap();
    child.kill().unwrap();
    child.wait().unwrap();
    let contents = bridge::bag::read_bag(&bag).expect("the killed recorder's bag opens");
    let samples = contents
        .messages
        .iter()
        .filter(|m| m.topic == bridge::transport::Topic::Sample)
        .count();
    // 3 s at 1 kHz; everything was flushed before the kill (0.5 s flush period).
    assert!(
        samples >= 2900,
        "only {samples} samples in the bag after kill -9"
    );
    let stamps: Vec<u64> = contents
        .messages
        .iter()
        .filter(|m| m.topic == bridge::transport::Topic::Sample)
        .map(|m| m.publish_time_ns)
        .collect();
    assert!(
        stamps.windows(2).all(|w| w[0] < w[1]),
        "samples out of order"
    );
    assert!(bag.join("metadata.yaml").exists());
}

/// A parameter file asking for a transport this build left out reads as in any build;
/// starting the node then fails naming the transport and the feature that brings it.
#[test]
#[cfg(not(all(feature = "ros2", feature = "zenoh", feature = "iceoryx2")))]
fn a_transport_left_out_of_the_build_is_named_with_its_feature() {
    let dir = TempDir::new("not_compiled");
    for (kind, compiled) in [
        ("ros2", cfg!(feature = "ros2")),
        ("zenoh", cfg!(feature = "zenoh")),
        ("iceoryx2", cfg!(feature = "iceoryx2")),
    ] {
        if compiled {
            continue;
        }
        let params = dir.path(&format!("{kind}.yaml"));
        write(
            &params,
            &format!("mrtwin_twin:\n  ros__parameters:\n    transports: [{kind}]\n    input: {kind}\n    control_service: false\n"),
        );
        let o = mrtwin()
            .args(["node", "--duration", "1", "--ros-args", "--params-file"])
            .arg(&params)
            .output()
            .expect("run node");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success()
                && err.contains(&format!("{kind}: open: not compiled"))
                && err.contains(&format!("feature `{kind}`")),
            "{err}"
        );
    }
}

#[test]
#[cfg(feature = "zenoh")]
fn a_fleet_of_three_twins_started_by_a_launch_file_keeps_every_damper_in_step() {
    let _serial = serial();
    let dir = TempDir::new("fleet");
    let json = dir.path("fleet.json");
    let prefix = format!("mrtwin_fleet{}", std::process::id());
    let launch = dir.path("fleet.launch.yaml");
    write(
        &launch,
        &format!(
            "launch:\n  - node:\n      pkg: mrtwin\n      exec: fleet\n      name: fleet_a\n      namespace: /site7\n      args: --dampers 3 --duration 3 --key-prefix {prefix} --json {}\n",
            json.display()
        ),
    );
    let o = mrtwin()
        .args(["launch", launch.to_str().unwrap(), "--duration", "30"])
        .output()
        .expect("launch the fleet");
    assert!(
        o.status.success(),
        "fleet failed: {}\n{}",
        String::from_utf8_lossy(&o.stderr),
        String::from_utf8_lossy(&o.stdout)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("the fleet's JSON"))
            .expect("JSON");
    let dampers = v["dampers"].as_array().expect("one entry per damper");
    assert_eq!(dampers.len(), 3, "{v}");
    let mut names = Vec::new();
    for d in dampers {
        let n = |k: &str| d[k].as_u64().unwrap_or_else(|| panic!("{k} in {d}"));
        // 3 s at 1 kHz, every sample stepped by its own twin and its output seen centrally.
        assert!(n("sent") >= 2900 && n("sent") <= 3001, "{d}");
        assert_eq!(n("stepped"), n("sent"), "{d}");
        assert_eq!(n("received"), n("sent"), "{d}");
        assert_eq!(n("errors"), 0, "{d}");
        names.push(d["node"].as_str().unwrap().to_string());
    }
    // Each twin under the launch file's namespace, one per damper.
    assert_eq!(
        names,
        [
            "/site7/d001/mrtwin_twin",
            "/site7/d002/mrtwin_twin",
            "/site7/d003/mrtwin_twin"
        ]
    );
    assert_eq!(v["dampers_without_loss"], 3, "{v}");
    let cpu = v["cpu_percent"].as_f64().unwrap();
    assert!(cpu > 0.0 && cpu <= 100.0, "{v}");
    let p50 = v["latency_ms"]["p50"].as_f64().unwrap();
    let p99 = v["latency_ms"]["p99"].as_f64().unwrap();
    assert!(p50 > 0.0 && p50 <= p99, "{v}");
    // The fleet is set by its flags: a parameter override is refused, not ignored.
    let o = mrtwin()
        .args(["fleet", "--dampers", "1", "--ros-args", "-p", "noise_n:=3"])
        .output()
        .expect("run fleet");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("fleet takes no parameter files, -p overrides"),
        "{err}"
    );
}
