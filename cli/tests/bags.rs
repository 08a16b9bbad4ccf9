//! Bags against real third-party readers and writers (python `rosbags`, `mcap` +
//! `mcap-ros2-support` from the interop venv), through the `mrtwin` binary.

use std::path::{Path, PathBuf};
use std::process::Output;
use std::time::Duration;

use bridge::bag::{BagWriter, BagWriterOptions};
use bridge::transport::Message;
use msgs::{
    Clock, DamperSample, DiagnosticArray, DiagnosticStatus, Float64, Header, KeyValue, Time,
    TwinOutput, YieldEstimate,
};
use serde_json::Value;

fn mrtwin<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Output {
    let o = mrtwin_tests::run(env!("CARGO_BIN_EXE_mrtwin"), args);
    assert!(
        o.status.success(),
        "mrtwin failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mrtwin-bags-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn msg_file(name: &str) -> String {
    mrtwin_tests::repo_root()
        .join("msgs/msg")
        .join(name)
        .display()
        .to_string()
}

/// Reads a bag with rosbags' AnyReader (our types registered from the .msg files) and
/// with mcap + mcap_ros2's decoder; writes {"rosbags": [...], "mcap": [...]} to argv[2],
/// each message as {topic, type, log_time, data} with NaN as null.
const READ_BOTH: &str = r#"
import sys, json, dataclasses, math
from pathlib import Path
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore, get_types_from_msg
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

bag, out, msgdir = Path(sys.argv[1]), sys.argv[2], Path(sys.argv[3])

def plain(o):
    if isinstance(o, float):
        return None if math.isnan(o) else o
    if isinstance(o, (bool, int, str)) or o is None:
        return o
    if isinstance(o, (bytes, bytearray)):
        return list(o)
    if hasattr(o, 'tolist'):
        return plain(o.tolist())
    if isinstance(o, (list, tuple)):
        return [plain(x) for x in o]
    if dataclasses.is_dataclass(o):
        return {f.name: plain(getattr(o, f.name)) for f in dataclasses.fields(o) if not f.name.startswith('_') and not f.name.isupper()}
    if hasattr(o, '__slots__'):
        return {k: plain(getattr(o, k)) for k in o.__slots__ if not k.startswith('_') and not k.isupper()}
    raise TypeError(type(o))

ts = get_typestore(Stores.ROS2_HUMBLE)
types = {}
for name in ['DamperSample', 'TwinOutput', 'YieldEstimate']:
    types.update(get_types_from_msg((msgdir / f'{name}.msg').read_text(), f'mrtwin_msgs/msg/{name}'))
ts.register(types)
result = {'rosbags': [], 'mcap': []}
with AnyReader([bag], default_typestore=ts) as reader:
    for conn, t, raw in reader.messages():
        m = reader.deserialize(raw, conn.msgtype)
        result['rosbags'].append({'topic': conn.topic, 'type': conn.msgtype, 'log_time': t, 'data': plain(m)})
mcaps = [bag] if bag.suffix == '.mcap' else sorted(bag.glob('*.mcap'))
for path in mcaps:
    with open(path, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == 'ros2', reader.get_header()
        stats = reader.get_summary().statistics
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            assert schema.encoding == 'ros2msg' and channel.message_encoding == 'cdr'
            assert message.data[:4] in (b'\x00\x01\x00\x00', b'\x00\x00\x00\x00')
            result['mcap'].append({'topic': channel.topic, 'type': schema.name, 'log_time': message.log_time, 'data': plain(decoded)})
        assert stats.message_count == len(result['mcap']), (stats.message_count, len(result['mcap']))
json.dump(result, open(out, 'w'))
print(len(result['rosbags']), len(result['mcap']))
"#;

fn read_with_python(bag: &Path, dir: &Path) -> (Vec<Value>, Vec<Value>) {
    let out = dir.join("python.json");
    let msgdir = mrtwin_tests::repo_root().join("msgs/msg");
    mrtwin_tests::run_python(
        READ_BOTH,
        &[
            bag.to_str().unwrap(),
            out.to_str().unwrap(),
            msgdir.to_str().unwrap(),
        ],
        Duration::from_secs(60),
    );
    let v: Value = mrtwin_tests::read_json(&out);
    let take = |k: &str| v[k].as_array().unwrap().clone();
    (take("rosbags"), take("mcap"))
}

fn every_topic(steps: usize) -> Vec<(Message, u64)> {
    let mut out = Vec::new();
    for i in 0..steps {
        let t = 0.01 * i as f64;
        let ns = Time::from_secs_f64(t).as_nanos() as u64;
        let header = Header::at(t, "d1");
        let n = i % 3;
        out.push((
            Message::Sample(DamperSample {
                header: header.clone(),
                displacement: 1e-3 * i as f64,
                velocity: -0.1,
                force: 100.0 + i as f64,
                current: 0.5,
                temperature: if i % 2 == 0 { f64::NAN } else { 30.0 },
            }),
            ns,
        ));
        out.push((
            Message::Output(TwinOutput {
                header: header.clone(),
                predicted_force: 99.0,
                measured_force: 100.0 + i as f64,
                residual: 1.0 + i as f64,
                dissipated_power: 2.5,
                fluid_temperature: 31.0,
                model_id: "two-chamber".into(),
                health_level: (i % 4) as u8,
            }),
            ns + 1000,
        ));
        out.push((Message::PredictedForce(Float64 { data: 99.5 }), ns + 2000));
        out.push((
            Message::YieldEstimate(YieldEstimate {
                header: header.clone(),
                current: 0.5,
                tau0: 3.6e5,
                tau0_std: 1e4,
                curve_current: [0.5, 1.0, 2.0][..n].to_vec(),
                curve_tau0: [3.6e5, 4.0e5, 4.5e5][..n].to_vec(),
                curve_tau0_std: [1e4, 2e4, 3e4][..n].to_vec(),
            }),
            ns + 3000,
        ));
        out.push((
            Message::Diagnostics(DiagnosticArray {
                header: header.clone(),
                status: vec![DiagnosticStatus {
                    level: DiagnosticStatus::WARN,
                    name: "mrtwin: residual".into(),
                    message: format!("step {i}"),
                    hardware_id: "d1".into(),
                    values: vec![KeyValue::new("rms_N", "12.5")],
                }],
            }),
            ns + 4000,
        ));
        out.push((
            Message::Clock(Clock {
                clock: header.stamp,
            }),
            ns + 5000,
        ));
    }
    out
}

fn to_json(m: &Message) -> Value {
    match m {
        Message::Sample(x) => serde_json::to_value(x),
        Message::Output(x) => serde_json::to_value(x),
        Message::PredictedForce(x) => serde_json::to_value(x),
        Message::YieldEstimate(x) => serde_json::to_value(x),
        Message::Diagnostics(x) => serde_json::to_value(x),
        Message::Clock(x) => serde_json::to_value(x),
    }
    .unwrap()
}

#[test]
fn every_topic_we_write_decodes_in_rosbags_and_mcap() {
    let dir = scratch("every");
    let bag = dir.join("bag");
    let msgs = every_topic(12);
    let mut w = BagWriter::create(&bag, BagWriterOptions::default()).unwrap();
    for (m, t) in &msgs {
        w.write_message("lab/d1", m, *t).unwrap();
    }
    w.finish().unwrap();
    let (rosbags, mcap) = read_with_python(&bag, &dir);
    for (reader, got) in [("rosbags", &rosbags), ("mcap", &mcap)] {
        assert_eq!(got.len(), msgs.len(), "{reader}");
        for (g, (m, t)) in got.iter().zip(&msgs) {
            let topic = m.topic();
            assert_eq!(
                g["topic"],
                bridge::bag::topic_name("lab/d1", topic),
                "{reader}"
            );
            assert_eq!(g["type"], topic.type_name(), "{reader}");
            assert_eq!(g["log_time"].as_u64(), Some(*t), "{reader}");
            assert_eq!(g["data"], to_json(m), "{reader}: {topic:?}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn simulated_bag_matches_the_csv_in_python_readers() {
    let dir = scratch("sim");
    let common = [
        "simulate",
        "--model",
        "two-chamber",
        "--frequency",
        "2",
        "--current",
        "1",
        "--duration",
        "0.4",
        "--rate",
        "1000",
        "--noise",
        "0.01",
        "--name",
        "rig/d3",
        "--out",
    ];
    let csv = dir.join("sim.csv");
    let bag = dir.join("sim");
    mrtwin(&[&common[..], &[csv.to_str().unwrap()]].concat());
    mrtwin(&[&common[..], &[bag.to_str().unwrap()]].concat());
    let rec = bridge::read_csv(&csv).unwrap();
    let (rosbags, mcap) = read_with_python(&bag, &dir);
    for (reader, got) in [("rosbags", &rosbags), ("mcap", &mcap)] {
        assert_eq!(got.len(), rec.samples.len(), "{reader}");
        for (g, s) in got.iter().zip(&rec.samples) {
            assert_eq!(g["topic"], "/rig/d3/sensor/sample");
            let d = &g["data"];
            let stamp = &d["header"]["stamp"];
            let t = stamp["sec"].as_f64().unwrap() + stamp["nanosec"].as_f64().unwrap() * 1e-9;
            assert!((t - s.time_s).abs() < 1e-9, "{reader}: {t} vs {}", s.time_s);
            assert_eq!(d["header"]["frame_id"], "rig/d3");
            assert_eq!(
                d["displacement"].as_f64(),
                Some(s.displacement_m),
                "{reader}"
            );
            assert_eq!(d["velocity"].as_f64(), Some(s.velocity_m_s), "{reader}");
            assert_eq!(d["force"].as_f64(), Some(s.force_n), "{reader}");
            assert_eq!(d["current"].as_f64(), Some(s.current_a), "{reader}");
            assert_eq!(d["temperature"].as_f64(), s.temperature_c, "{reader}");
        }
    }
    // convert gives the CSV back.
    let back = dir.join("back.csv");
    mrtwin(&["convert", bag.to_str().unwrap(), back.to_str().unwrap()]);
    let again = bridge::read_csv(&back).unwrap();
    assert_eq!(again.samples.len(), rec.samples.len());
    for (a, b) in again.samples.iter().zip(&rec.samples) {
        assert!((a.time_s - b.time_s).abs() < 1e-9);
        assert_eq!((a.force_n, a.temperature_c), (b.force_n, b.temperature_c));
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Writes a rosbag2 bag with rosbags' Writer (MCAP storage, version argv[3]): our
/// DamperSample (registered from the .msg file) on /rig/d7/sensor/sample at 500 Hz and a
/// std_msgs/Float64 on /weather/temperature every 10th sample.
const WRITE_ROSBAGS: &str = r#"
import sys
from pathlib import Path
from rosbags.rosbag2 import Writer, StoragePlugin
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

out, msgfile, version, n = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
ts = get_typestore(Stores.ROS2_HUMBLE)
ts.register(get_types_from_msg(msgfile.read_text(), 'mrtwin_msgs/msg/DamperSample'))
DS = ts.types['mrtwin_msgs/msg/DamperSample']
Header = ts.types['std_msgs/msg/Header']
Time = ts.types['builtin_interfaces/msg/Time']
F64 = ts.types['std_msgs/msg/Float64']
with Writer(out, version=version, storage_plugin=StoragePlugin.MCAP) as w:
    cs = w.add_connection('/rig/d7/sensor/sample', DS.__msgtype__, typestore=ts)
    cf = w.add_connection('/weather/temperature', F64.__msgtype__, typestore=ts)
    for i in range(n):
        t = 1_000_000_000 + i * 2_000_000
        msg = DS(header=Header(stamp=Time(sec=t // 10**9, nanosec=t % 10**9), frame_id='d7'),
                 displacement=(i % 50) * 1e-4 - 2.5e-3, velocity=0.5 - i * 1e-3,
                 force=10.0 * i - 300.0, current=0.5 if i < n // 2 else 1.0,
                 temperature=25.0 + i * 0.01)
        w.write(cs, t, ts.serialize_cdr(msg, DS.__msgtype__))
        if i % 10 == 0:
            w.write(cf, t, ts.serialize_cdr(F64(data=float(i)), F64.__msgtype__))
print('ok')
"#;

#[test]
fn a_rosbags_bag_opens_in_mrtwin_with_the_unknown_topic_skipped() {
    let dir = scratch("foreign");
    let n = 300usize;
    for version in ["8", "9"] {
        let bag = dir.join(format!("v{version}"));
        mrtwin_tests::run_python(
            WRITE_ROSBAGS,
            &[
                bag.to_str().unwrap(),
                &msg_file("DamperSample.msg"),
                version,
                &n.to_string(),
            ],
            Duration::from_secs(60),
        );
        let info = mrtwin(&["info", bag.to_str().unwrap()]);
        let text = String::from_utf8_lossy(&info.stdout);
        assert!(
            text.contains("skipped       /weather/temperature (std_msgs/msg/Float64): 30 messages"),
            "{text}"
        );
        assert!(
            text.contains(&format!(
                "/rig/d7/sensor/sample  mrtwin_msgs/msg/DamperSample  {n} msgs, 0.598 s, 500.0 Hz"
            )),
            "{text}"
        );
        assert!(
            text.contains(&format!(
                "rosbag2 version {version}, storage mcap, 330 messages"
            )),
            "{text}"
        );
        let csv = dir.join(format!("v{version}.csv"));
        let conv = mrtwin(&["convert", bag.to_str().unwrap(), csv.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&conv.stderr);
        assert!(err.contains("skipped topic /weather/temperature"), "{err}");
        let rec = bridge::read_csv(&csv).unwrap();
        assert_eq!(rec.samples.len(), n);
        for (i, s) in rec.samples.iter().enumerate() {
            let t = 1.0 + (i as f64) * 0.002;
            assert!((s.time_s - t).abs() < 1e-9, "{} vs {t}", s.time_s);
            assert_eq!(s.displacement_m, (i % 50) as f64 * 1e-4 - 2.5e-3);
            assert_eq!(s.velocity_m_s, 0.5 - i as f64 * 1e-3);
            assert_eq!(s.force_n, 10.0 * i as f64 - 300.0);
            assert_eq!(s.current_a, if i < n / 2 { 0.5 } else { 1.0 });
            assert_eq!(s.temperature_c, Some(25.0 + i as f64 * 0.01));
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
