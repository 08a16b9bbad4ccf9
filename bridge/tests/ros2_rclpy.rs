//! The ROS 2 adapter against real ROS 2 peers: rclpy 9 on Fast DDS (`rmw_fastrtps_cpp`)
//! in the interop venv (`scripts/setup-venv.sh`), as separate processes. No mocks.
//!
//! Each test has its own `ROS_DOMAIN_ID` (this file uses 41..=43; the bench 78) so that
//! tests running in parallel never see each other. Every wait is bounded.
//!
//! rclpy has no type support for `mrtwin_msgs` (it would need the package built with
//! rosidl), so rclpy cannot publish or decode a `DamperSample`: the tests check (a) our
//! standard types both ways over DDS, (b) the `mrtwin_msgs` types by name in rclpy's graph,
//! (c) the DamperSample byte layout against rclpy's serialization of a type with the same
//! prefix (`geometry_msgs/PointStamped` = Header + 3 doubles), and (d) DamperSample over
//! DDS between two adapters.
#![cfg(feature = "ros2")]

use std::io::{BufRead, BufReader, Read};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use bridge::ros2::{Reliability, Ros2Config, Ros2Transport};
use bridge::transport::{Message, Topic, Transport};
use msgs::{
    Clock, DamperSample, DiagnosticArray, DiagnosticStatus, Float64, Header, KeyValue, Time,
    TwinOutput,
};

const DOMAIN_RCLPY_LISTENS: u16 = 41;
const DOMAIN_RCLPY_TALKS: u16 = 42;
const DOMAIN_TWO_ADAPTERS: u16 = 43;
/// Discovery between RustDDS and Fast DDS normally takes well under a second.
const DISCOVERY: Duration = Duration::from_secs(20);

/// A Python peer running in the background; its stdout arrives line by line.
struct Peer {
    child: Child,
    stdin: Option<std::process::ChildStdin>,
    lines: mpsc::Receiver<String>,
    stderr: std::thread::JoinHandle<String>,
}

impl Peer {
    fn spawn(domain: u16, script: &str, args: &[&str]) -> Peer {
        let mut child = Command::new(mrtwin_tests::python())
            .arg("-u")
            .arg("-c")
            .arg(script)
            .args(args)
            .env("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
            .env("ROS_DOMAIN_ID", domain.to_string())
            .env_remove("ROS_LOCALHOST_ONLY")
            .env_remove("ROS_AUTOMATIC_DISCOVERY_RANGE")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start the rclpy peer");
        let stdin = child.stdin.take();
        let (tx, lines) = mpsc::channel();
        let out = child.stdout.take().unwrap();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let mut err = child.stderr.take().unwrap();
        let stderr = std::thread::spawn(move || {
            let mut s = String::new();
            err.read_to_string(&mut s).ok();
            s
        });
        Peer {
            child,
            stdin,
            lines,
            stderr,
        }
    }

    fn send_line(&mut self, line: &str) {
        use std::io::Write;
        let stdin = self.stdin.as_mut().expect("stdin");
        writeln!(stdin, "{line}").and_then(|_| stdin.flush()).ok();
    }

    /// The next stdout line starting with `tag`, within `timeout`; panics with the peer's
    /// stderr otherwise.
    fn expect_line(&mut self, tag: &str, timeout: Duration) -> String {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) if line.starts_with(tag) => {
                    return line[tag.len()..].trim().to_string();
                }
                Ok(_) => continue,
                Err(_) => self.fail(&format!(
                    "no `{tag}` line from the rclpy peer within {timeout:?}"
                )),
            }
        }
    }

    fn fail(&mut self, what: &str) -> ! {
        self.child.kill().ok();
        self.child.wait().ok();
        let stderr = std::mem::replace(&mut self.stderr, std::thread::spawn(String::new));
        panic!(
            "{what}\n--- peer stderr ---\n{}",
            stderr.join().unwrap_or_default()
        );
    }

    fn finish(mut self) {
        let deadline = Instant::now() + Duration::from_secs(10);
        while Instant::now() < deadline {
            if let Some(status) = self.child.try_wait().unwrap() {
                if !status.success() {
                    self.fail(&format!("rclpy peer exited with {status}"));
                }
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        self.fail("rclpy peer did not exit");
    }
}

impl Drop for Peer {
    fn drop(&mut self) {
        self.child.kill().ok();
        self.child.wait().ok();
    }
}

/// Wait until `cond` holds, polling; false after `timeout`.
fn wait_until(timeout: Duration, mut cond: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + timeout;
    while Instant::now() < deadline {
        if cond() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    cond()
}

fn diagnostics(node: &str, t: f64) -> DiagnosticArray {
    DiagnosticArray {
        header: Header::at(t, ""),
        status: vec![
            DiagnosticStatus {
                level: DiagnosticStatus::OK,
                name: format!("{node}: model"),
                message: "two-chamber model running".into(),
                hardware_id: "damper1".into(),
                values: vec![KeyValue::new("model", "two-chamber")],
            },
            DiagnosticStatus {
                level: DiagnosticStatus::WARN,
                name: format!("{node}: residual"),
                message: "residual RMS above 5 % of peak force".into(),
                hardware_id: "damper1".into(),
                values: vec![
                    KeyValue::new("rms_N", "41.25"),
                    KeyValue::new("peak_N", "612.5"),
                ],
            },
        ],
    }
}

const LISTENER: &str = r#"
import json, sys, time
import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64
from diagnostic_msgs.msg import DiagnosticArray

ns, name, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
rclpy.init()
node = Node('rclpy_probe')
forces, diags = [], []
qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
node.create_subscription(Float64, ns + '/twin/predicted_force', lambda m: forces.append(m.data), qos)
def on_diag(m):
    diags.append({'stamp': [m.header.stamp.sec, m.header.stamp.nanosec],
        'status': [{'level': s.level[0] if isinstance(s.level, bytes) else int(s.level),
                    'name': s.name, 'message': s.message, 'hardware_id': s.hardware_id,
                    'values': [[kv.key, kv.value] for kv in s.values]} for s in m.status]})
node.create_subscription(DiagnosticArray, '/diagnostics', on_diag, qos)

def graph():
    return ([[nm, nsp] for nm, nsp in node.get_node_names_and_namespaces()],
            [[t, list(ty)] for t, ty in node.get_topic_names_and_types()])

def ours_visible():
    nodes, topics = graph()
    return [name, ns] in nodes and any(t == ns + '/twin/output' for t, _ in topics)

print('READY', flush=True)
deadline = time.time() + 20
while time.time() < deadline and not (len(forces) >= n and diags and ours_visible()):
    rclpy.spin_once(node, timeout_sec=0.05)
nodes, topics = graph()
print('RESULT', json.dumps({'forces': forces, 'diags': diags, 'nodes': nodes, 'topics': topics}), flush=True)

# Phase 2: the Rust side shuts its adapter down; our node must leave the graph.
sys.stdin.readline()
t0 = time.time()
while time.time() < t0 + 20:
    rclpy.spin_once(node, timeout_sec=0.05)
    if [name, ns] not in node.get_node_names_and_namespaces():
        print('GONE', round(time.time() - t0, 3), flush=True)
        break
else:
    print('STILL', json.dumps(node.get_node_names_and_namespaces()), flush=True)
node.destroy_node()
rclpy.shutdown()
"#;

/// rclpy receives our predicted force and diagnostics with the right values, sees our node
/// and our topics with their type names, and sees the node leave after shutdown.
#[test]
fn rclpy_receives_outputs_sees_the_graph_and_sees_us_leave() {
    let ns = "/ros2_it_listen";
    let name = "twin_under_test";
    let cfg = Ros2Config {
        domain_id: DOMAIN_RCLPY_LISTENS,
        namespace: ns.parse().unwrap(),
        node_name: name.into(),
        ..Default::default()
    };
    let mut tr = Ros2Transport::new(
        &cfg,
        &[
            Topic::PredictedForce,
            Topic::Diagnostics,
            Topic::Output,
            Topic::YieldEstimate,
        ],
        &[Topic::Sample],
    )
    .expect("adapter");

    let n = 50usize;
    let mut peer = Peer::spawn(DOMAIN_RCLPY_LISTENS, LISTENER, &[ns, name, &n.to_string()]);
    peer.expect_line("READY", DISCOVERY);

    let matched = wait_until(DISCOVERY, || {
        tr.matched_subscriptions(Topic::PredictedForce) >= 1
            && tr.matched_subscriptions(Topic::Diagnostics) >= 1
    });
    if !matched {
        peer.fail("the rclpy subscriptions never matched our publishers");
    }
    let forces: Vec<f64> = (0..n).map(|i| -250.0 + 12.125 * i as f64).collect();
    for &f in &forces {
        tr.publish(&Message::PredictedForce(Float64 { data: f }))
            .unwrap();
    }
    let diag = diagnostics(name, 12.75);
    tr.publish(&Message::Diagnostics(diag.clone())).unwrap();

    let result: serde_json::Value =
        serde_json::from_str(&peer.expect_line("RESULT", Duration::from_secs(30))).unwrap();
    let got: Vec<f64> = result["forces"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(got, forces, "predicted forces as rclpy received them");

    let d = &result["diags"][0];
    assert_eq!(d["stamp"], serde_json::json!([12, 750_000_000]));
    for (i, s) in diag.status.iter().enumerate() {
        let r = &d["status"][i];
        assert_eq!(r["level"], s.level as u64);
        assert_eq!(r["name"], s.name.as_str());
        assert_eq!(r["message"], s.message.as_str());
        assert_eq!(r["hardware_id"], s.hardware_id.as_str());
        let kv: Vec<serde_json::Value> = s
            .values
            .iter()
            .map(|kv| serde_json::json!([kv.key, kv.value]))
            .collect();
        assert_eq!(r["values"], serde_json::Value::Array(kv));
    }
    assert_eq!(d["status"][1]["name"], "twin_under_test: residual");

    // rclpy's view of the graph: our node and our topics with their ROS type names.
    let nodes = result["nodes"].as_array().unwrap();
    assert!(
        nodes.contains(&serde_json::json!([name, ns])),
        "our node in rclpy's graph: {nodes:?}"
    );
    let topics = result["topics"].as_array().unwrap();
    for (topic, ty) in [
        (
            "/ros2_it_listen/twin/predicted_force",
            "std_msgs/msg/Float64",
        ),
        ("/ros2_it_listen/twin/output", "mrtwin_msgs/msg/TwinOutput"),
        (
            "/ros2_it_listen/twin/yield_estimate",
            "mrtwin_msgs/msg/YieldEstimate",
        ),
        (
            "/ros2_it_listen/sensor/sample",
            "mrtwin_msgs/msg/DamperSample",
        ),
        ("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),
    ] {
        assert!(
            topics.iter().any(|t| t[0] == topic && t[1]
                .as_array()
                .unwrap()
                .contains(&serde_json::json!(ty))),
            "{topic} [{ty}] not in rclpy's graph: {topics:?}"
        );
    }

    // Our view of the graph: the rclpy node and its subscriptions.
    let seen = wait_until(DISCOVERY, || {
        tr.graph()
            .nodes
            .contains(&("/".to_string(), "rclpy_probe".to_string()))
    });
    let g = tr.graph();
    assert!(seen, "rclpy_probe not in our graph: {:?}", g.nodes);
    assert!(g.nodes.contains(&(ns.to_string(), name.to_string())));
    assert!(g.topics.contains(&(
        "/ros2_it_listen/twin/predicted_force".to_string(),
        "std_msgs/msg/Float64".to_string()
    )));

    // Leaving the graph.
    tr.shutdown();
    peer.send_line("shutdown");
    let gone = peer.expect_line("GONE", Duration::from_secs(30));
    let secs: f64 = gone.parse().unwrap();
    eprintln!("rclpy saw our node leave {secs} s after shutdown");
    assert!(secs < 20.0, "left the graph after {secs} s");
    peer.finish();
}

const TALKER: &str = r#"
import sys, time
import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rosgraph_msgs.msg import Clock

ns, n = sys.argv[1], int(sys.argv[2])
rclpy.init()
node = Node('rclpy_talker', namespace=ns)
qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
pf = node.create_publisher(Float64, 'twin/predicted_force', qos)
pd = node.create_publisher(DiagnosticArray, '/diagnostics', qos)
pc = node.create_publisher(Clock, '/clock', qos)
deadline = time.time() + 20
while time.time() < deadline and min(p.get_subscription_count() for p in (pf, pd, pc)) < 1:
    rclpy.spin_once(node, timeout_sec=0.05)
counts = [p.get_subscription_count() for p in (pf, pd, pc)]
print('MATCHED', counts, flush=True)
for i in range(n):
    pf.publish(Float64(data=0.5 * i - 3.0))
    c = Clock()
    c.clock.sec = 100 + i
    c.clock.nanosec = 1000 * i
    pc.publish(c)
d = DiagnosticArray()
d.header.stamp.sec = 7
d.header.frame_id = 'frame'
s = DiagnosticStatus(level=DiagnosticStatus.ERROR, name='rclpy_talker: probe',
                     message='from rclpy', hardware_id='hw')
s.values = [KeyValue(key='k%d' % i, value='v%d' % i) for i in range(3)]
d.status = [s]
pd.publish(d)
for p in (pf, pd, pc):
    p.wait_for_all_acked(rclpy.duration.Duration(seconds=10))
print('SENT', flush=True)
time.sleep(0.5)
node.destroy_node()
rclpy.shutdown()
"#;

/// Our adapter consumes what rclpy publishes (standard types, reliable), exactly.
#[test]
fn adapter_consumes_what_rclpy_publishes() {
    let ns = "/ros2_it_talk";
    let cfg = Ros2Config {
        domain_id: DOMAIN_RCLPY_TALKS,
        namespace: ns.parse().unwrap(),
        node_name: "twin_listener".into(),
        ..Default::default()
    };
    let mut tr = Ros2Transport::new(
        &cfg,
        &[],
        &[Topic::PredictedForce, Topic::Diagnostics, Topic::Clock],
    )
    .expect("adapter");
    let n = 40usize;
    let mut peer = Peer::spawn(DOMAIN_RCLPY_TALKS, TALKER, &[ns, &n.to_string()]);
    let matched = peer.expect_line("MATCHED", Duration::from_secs(30));
    assert_eq!(matched, "[1, 1, 1]", "rclpy publishers matched our readers");

    let mut got = Vec::new();
    let total = 2 * n + 1;
    let complete = |got: &Vec<Message>| got.len() >= total;
    let ok = wait_until(DISCOVERY, || {
        tr.poll(&mut got).unwrap();
        complete(&got)
    });
    peer.expect_line("SENT", Duration::from_secs(15));
    assert!(ok, "received {} of {total} messages", got.len());
    let forces: Vec<f64> = got
        .iter()
        .filter_map(|m| match m {
            Message::PredictedForce(f) => Some(f.data),
            _ => None,
        })
        .collect();
    assert_eq!(
        forces,
        (0..n).map(|i| 0.5 * i as f64 - 3.0).collect::<Vec<_>>()
    );
    let clocks: Vec<Clock> = got
        .iter()
        .filter_map(|m| match m {
            Message::Clock(c) => Some(*c),
            _ => None,
        })
        .collect();
    assert_eq!(
        clocks,
        (0..n)
            .map(|i| Clock {
                clock: Time {
                    sec: 100 + i as i32,
                    nanosec: 1000 * i as u32,
                }
            })
            .collect::<Vec<_>>()
    );
    let diags: Vec<&DiagnosticArray> = got
        .iter()
        .filter_map(|m| match m {
            Message::Diagnostics(d) => Some(d),
            _ => None,
        })
        .collect();
    assert_eq!(diags.len(), 1);
    let expected = DiagnosticArray {
        header: Header {
            stamp: Time { sec: 7, nanosec: 0 },
            frame_id: "frame".into(),
        },
        status: vec![DiagnosticStatus {
            level: DiagnosticStatus::ERROR,
            name: "rclpy_talker: probe".into(),
            message: "from rclpy".into(),
            hardware_id: "hw".into(),
            values: (0..3)
                .map(|i| KeyValue::new(format!("k{i}"), format!("v{i}")))
                .collect(),
        }],
    };
    assert_eq!(diags[0], &expected);
    peer.finish();
    // Nothing else arrives and polling an idle adapter is fine.
    let mut rest = Vec::new();
    tr.poll(&mut rest).unwrap();
    assert!(rest.is_empty(), "{rest:?}");
}

const SERIALIZE: &str = r#"
import sys
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64, Header
from rosgraph_msgs.msg import Clock
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PointStamped

def header(sec, nanosec, frame):
    h = Header(); h.stamp.sec = sec; h.stamp.nanosec = nanosec; h.frame_id = frame
    return h
print('float64', serialize_message(Float64(data=-1234.5678)).hex())
c = Clock(); c.clock.sec = -3; c.clock.nanosec = 999999999
print('clock', serialize_message(c).hex())
d = DiagnosticArray(header=header(12, 5, 'abc'))
d.status = [DiagnosticStatus(level=DiagnosticStatus.WARN, name='mrtwin_twin: residual',
                             message='high', hardware_id='damper1',
                             values=[KeyValue(key='rms_N', value='12.5'), KeyValue(key='x', value='')]),
            DiagnosticStatus(level=DiagnosticStatus.STALE, name='n', message='', hardware_id='', values=[])]
print('diag', serialize_message(d).hex())
for frame in ['', 'd', 'damper1', 'damper_12']:
    p = PointStamped(header=header(1, 250000000, frame))
    p.point.x, p.point.y, p.point.z = 0.0125, -0.5, 612.25
    print('point', frame, serialize_message(p).hex())
"#;

fn unhex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex from python"))
        .collect()
}

/// `ours` equals `theirs` byte for byte, except that alignment padding (zero in ours)
/// may hold anything in theirs: Fast CDR leaves padding bytes uninitialised.
fn assert_same_cdr(what: &str, ours: &[u8], theirs: &[u8]) {
    assert_eq!(ours.len(), theirs.len(), "{what}: length");
    let differ: Vec<usize> = (0..ours.len())
        .filter(|&i| ours[i] != theirs[i] && ours[i] != 0)
        .collect();
    assert!(
        differ.is_empty(),
        "{what}: bytes differ at {differ:?}\n ours   {ours:02x?}\n theirs {theirs:02x?}"
    );
}

/// Our CDR equals rclpy's (rosidl + Fast CDR) for the standard types (up to padding
/// contents), and rclpy's bytes decode to the same values; a DamperSample starts with the
/// bytes of a PointStamped with the same header and displacement/velocity/force (the two
/// types share that prefix field for field), so rclpy's PointStamped bytes plus two
/// doubles decode as our DamperSample.
#[test]
fn cdr_bytes_match_rclpy_serialization() {
    let out = mrtwin_tests::run_python(SERIALIZE, &[], Duration::from_secs(20));
    let line = |tag: &str| -> Vec<u8> {
        unhex(
            out.lines()
                .find_map(|l| l.strip_prefix(&format!("{tag} ")))
                .unwrap_or_else(|| panic!("no {tag} in {out}")),
        )
    };
    let f = Float64 { data: -1234.5678 };
    assert_eq!(line("float64"), msgs::cdr::encode(&f));
    let c = Clock {
        clock: Time {
            sec: -3,
            nanosec: 999_999_999,
        },
    };
    assert_eq!(line("clock"), msgs::cdr::encode(&c));
    let d = DiagnosticArray {
        header: Header {
            stamp: Time {
                sec: 12,
                nanosec: 5,
            },
            frame_id: "abc".into(),
        },
        status: vec![
            DiagnosticStatus {
                level: DiagnosticStatus::WARN,
                name: "mrtwin_twin: residual".into(),
                message: "high".into(),
                hardware_id: "damper1".into(),
                values: vec![KeyValue::new("rms_N", "12.5"), KeyValue::new("x", "")],
            },
            DiagnosticStatus {
                level: DiagnosticStatus::STALE,
                name: "n".into(),
                ..Default::default()
            },
        ],
    };
    let theirs = line("diag");
    assert_same_cdr("DiagnosticArray", &msgs::cdr::encode(&d), &theirs);
    assert_eq!(msgs::cdr::decode::<DiagnosticArray>(&theirs).unwrap(), d);

    let mut points = 0;
    for l in out.lines().filter_map(|l| l.strip_prefix("point ")) {
        let mut parts = l.split(' ');
        let (frame, bytes) = match (parts.next(), parts.next()) {
            (Some(frame), Some(bytes)) => (frame, bytes),
            (Some(bytes), None) => ("", bytes),
            _ => panic!("bad line {l}"),
        };
        let s = DamperSample {
            header: Header {
                stamp: Time {
                    sec: 1,
                    nanosec: 250_000_000,
                },
                frame_id: frame.into(),
            },
            displacement: 0.0125,
            velocity: -0.5,
            force: 612.25,
            current: 0.75,
            temperature: -40.5,
        };
        let mut theirs = unhex(bytes);
        theirs.extend_from_slice(&s.current.to_le_bytes());
        theirs.extend_from_slice(&s.temperature.to_le_bytes());
        assert_same_cdr(
            &format!("DamperSample vs PointStamped, frame {frame:?}"),
            &msgs::cdr::encode(&s),
            &theirs,
        );
        assert_eq!(msgs::cdr::decode::<DamperSample>(&theirs).unwrap(), s);
        points += 1;
    }
    assert_eq!(points, 4);
}

/// DamperSample (which rclpy cannot build) and TwinOutput between two adapters over DDS,
/// plus the graph as RustDDS sees it, and clear errors for wrong use.
#[test]
fn mrtwin_types_between_two_adapters() {
    let base = Ros2Config {
        domain_id: DOMAIN_TWO_ADAPTERS,
        namespace: "/ros2_it_pair".parse().unwrap(),
        ..Default::default()
    };
    let mut stand_cfg = base.clone();
    stand_cfg.node_name = "stand".into();
    // Reliable samples for this test, so that it cannot lose one by chance.
    stand_cfg.qos.insert(
        Topic::Sample,
        bridge::ros2::QosOverride {
            reliability: Some(Reliability::Reliable),
            depth: None,
        },
    );
    let mut twin_cfg = stand_cfg.clone();
    twin_cfg.node_name = "twin".into();
    let mut stand = Ros2Transport::new(&stand_cfg, &[Topic::Sample], &[Topic::Output]).unwrap();
    let mut twin = Ros2Transport::new(&twin_cfg, &[Topic::Output], &[Topic::Sample]).unwrap();

    // Wrong use is an error naming the topic, not a panic.
    let e = stand
        .publish(&Message::Clock(Clock::default()))
        .unwrap_err()
        .to_string();
    assert!(e.contains("/clock") && e.contains("not among"), "{e}");

    assert!(
        wait_until(DISCOVERY, || {
            stand.matched_subscriptions(Topic::Sample) >= 1
                && twin.matched_subscriptions(Topic::Output) >= 1
        }),
        "the two adapters never matched"
    );
    let samples: Vec<DamperSample> = (0..200)
        .map(|i| DamperSample {
            header: Header::at(i as f64 * 1e-3, "damper1"),
            displacement: 0.01 * (i as f64 * 0.1).sin(),
            velocity: 0.1 * (i as f64 * 0.1).cos(),
            force: 300.0 + i as f64,
            current: 0.5,
            temperature: if i % 2 == 0 { f64::NAN } else { 25.0 },
        })
        .collect();
    for s in &samples {
        stand.publish(&Message::Sample(s.clone())).unwrap();
    }
    let mut got = Vec::new();
    assert!(
        wait_until(DISCOVERY, || {
            twin.poll(&mut got).unwrap();
            got.len() >= samples.len()
        }),
        "twin received {} of {} samples",
        got.len(),
        samples.len()
    );
    for (g, s) in got.iter().zip(&samples) {
        let Message::Sample(g) = g else {
            panic!("not a sample: {g:?}")
        };
        assert_eq!(g.header, s.header);
        assert_eq!(
            (g.displacement, g.velocity, g.force, g.current),
            (s.displacement, s.velocity, s.force, s.current)
        );
        assert_eq!(g.temperature.is_nan(), s.temperature.is_nan());
        // The twin answers each sample.
        twin.publish(&Message::Output(TwinOutput {
            header: g.header.clone(),
            predicted_force: g.force - 1.0,
            measured_force: g.force,
            residual: 1.0,
            model_id: "bingham".into(),
            ..Default::default()
        }))
        .unwrap();
    }
    let mut outs = Vec::new();
    assert!(
        wait_until(DISCOVERY, || {
            stand.poll(&mut outs).unwrap();
            outs.len() >= samples.len()
        }),
        "stand received {} outputs",
        outs.len()
    );
    for (o, s) in outs.iter().zip(&samples) {
        let Message::Output(o) = o else {
            panic!("not an output: {o:?}")
        };
        assert_eq!(o.header, s.header);
        assert_eq!(o.predicted_force, s.force - 1.0);
        assert_eq!(o.model_id, "bingham");
    }
    let g = stand.graph();
    assert!(g.topics.contains(&(
        "/ros2_it_pair/sensor/sample".into(),
        "mrtwin_msgs/msg/DamperSample".into()
    )));
    assert!(
        wait_until(DISCOVERY, || stand
            .graph()
            .nodes
            .contains(&("/ros2_it_pair".into(), "twin".into()))),
        "{:?}",
        stand.graph().nodes
    );
    drop(twin);
    stand.shutdown();
}
