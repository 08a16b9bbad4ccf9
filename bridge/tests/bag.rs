//! rosbag2/MCAP bags: round trips, damage (truncation at many offsets, flipped bytes,
//! empty files and directories), foreign topics, and a writer killed with SIGKILL.

use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use bridge::bag::{
    self, read_bag, read_recording, write_recording, write_recording_mcap, BagCompression,
    BagError, BagWriter, BagWriterOptions,
};
use bridge::qos::Reliability;
use bridge::transport::{Message, Topic};
use bridge::{Recording, Sample};
use msgs::{
    Clock, DamperSample, DiagnosticArray, DiagnosticStatus, Float64, Header, KeyValue, RosMessage,
    Time, TwinOutput, YieldEstimate,
};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mrtwin-bag-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A damper stroked at 2 Hz with a current step, 1 kHz, `n` samples (uneven last steps).
fn recording(n: usize) -> Recording {
    let samples = (0..n)
        .map(|i| {
            let t = i as f64 * 1e-3 + if i > n - 3 { 0.3e-3 } else { 0.0 };
            let w = 2.0 * std::f64::consts::PI * 2.0;
            let current = if t < 0.5 { 0.5 } else { 1.0 };
            Sample {
                time_s: t,
                displacement_m: 0.01 * (w * t).sin(),
                velocity_m_s: 0.01 * w * (w * t).cos(),
                force_n: 800.0 * current * (w * t).cos().signum() + 300.0 * (w * t).cos(),
                current_a: current,
                temperature_c: (i % 7 != 0).then_some(25.0 + t),
            }
        })
        .collect();
    Recording {
        samples,
        velocity_derived: false,
        has_temperature: true,
        source: "synthetic".into(),
    }
}

fn assert_same_recording(a: &Recording, b: &Recording) {
    assert_eq!(a.samples.len(), b.samples.len());
    for (x, y) in a.samples.iter().zip(&b.samples) {
        assert!(
            (x.time_s - y.time_s).abs() <= 1e-9,
            "{} vs {}",
            x.time_s,
            y.time_s
        );
        assert_eq!(x.displacement_m, y.displacement_m);
        assert_eq!(x.velocity_m_s, y.velocity_m_s);
        assert_eq!(x.force_n, y.force_n);
        assert_eq!(x.current_a, y.current_a);
        assert_eq!(x.temperature_c, y.temperature_c);
    }
    assert_eq!(a.has_temperature, b.has_temperature);
}

/// One message of every mrtwin topic per step, `steps` steps.
fn every_topic(steps: usize) -> Vec<(Message, u64)> {
    let mut out = Vec::new();
    for i in 0..steps {
        let t = 0.01 * i as f64;
        let ns = Time::from_secs_f64(t).as_nanos() as u64;
        let header = Header::at(t, "d1");
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
        out.push((
            Message::PredictedForce(Float64 {
                data: 99.0 + i as f64,
            }),
            ns + 2000,
        ));
        out.push((
            Message::YieldEstimate(YieldEstimate {
                header: header.clone(),
                current: 0.5,
                tau0: 3.6e5,
                tau0_std: 1e4,
                curve_current: vec![0.5, 1.0][..i % 3].to_vec(),
                curve_tau0: vec![3.6e5, 4.0e5][..i % 3].to_vec(),
                curve_tau0_std: vec![1e4, 2e4][..i % 3].to_vec(),
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

/// NaN-aware comparison (the samples carry NaN temperatures).
fn same_message(a: &Message, b: &Message) -> bool {
    a.to_cdr() == b.to_cdr()
}

#[test]
fn recording_round_trips_through_a_bag_dir_and_a_bare_mcap() {
    let dir = scratch("roundtrip");
    let rec = recording(1500);
    let summary = write_recording(&dir.join("bag"), &rec, "d1").unwrap();
    assert_eq!(summary.message_count, 1500);
    assert_eq!(summary.topics[0].0, "/d1/sensor/sample");
    let back = read_recording(&dir.join("bag")).unwrap();
    assert_same_recording(&rec, &back);
    // The metadata written beside the MCAP file.
    let info = bag::metadata::read_metadata(&dir.join("bag/metadata.yaml")).unwrap();
    assert_eq!(info.version, 8);
    assert_eq!(info.storage_identifier, "mcap");
    assert_eq!(info.relative_file_paths, vec!["bag_0.mcap".to_string()]);
    assert_eq!(info.message_count, 1500);
    assert_eq!(info.files[0].message_count, 1500);
    assert_eq!(info.starting_time.nanoseconds_since_epoch, 0);
    let last = Time::from_secs_f64(rec.samples.last().unwrap().time_s).as_nanos() as u64;
    assert_eq!(info.duration.nanoseconds, last);
    let t = &info.topics_with_message_count[0];
    assert_eq!(t.topic_metadata.type_name, "mrtwin_msgs/msg/DamperSample");
    assert_eq!(t.topic_metadata.serialization_format, "cdr");
    assert!(t
        .topic_metadata
        .offered_qos_profiles
        .as_str()
        .unwrap()
        .contains("reliability: 2"));
    // The directory path, its metadata.yaml, and the MCAP file inside all open it.
    assert_same_recording(
        &rec,
        &read_recording(&dir.join("bag/metadata.yaml")).unwrap(),
    );
    assert_same_recording(&rec, &read_recording(&dir.join("bag/bag_0.mcap")).unwrap());
    assert_same_recording(&rec, &bridge::open_recording(&dir.join("bag")).unwrap());
    // Bare .mcap.
    write_recording_mcap(&dir.join("x.mcap"), &rec, "d1").unwrap();
    assert_same_recording(&rec, &bridge::open_recording(&dir.join("x.mcap")).unwrap());
    // A bag is never written over.
    let err = write_recording(&dir.join("bag"), &rec, "d1").unwrap_err();
    assert!(err.to_string().contains("not empty"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn every_topic_round_trips_with_each_compression() {
    let dir = scratch("topics");
    let msgs = every_topic(40);
    for (k, compression) in [
        BagCompression::None,
        BagCompression::Zstd,
        BagCompression::Lz4,
    ]
    .into_iter()
    .enumerate()
    {
        let path = dir.join(format!("bag{k}"));
        let mut w = BagWriter::create(
            &path,
            BagWriterOptions {
                chunk_size: 2048,
                compression,
                ..Default::default()
            },
        )
        .unwrap();
        for (m, t) in &msgs {
            w.write_message("lab/d1", m, *t).unwrap();
        }
        w.finish().unwrap();
        let c = read_bag(&path).unwrap();
        assert!(c.notes.is_empty(), "{:?}", c.notes);
        assert!(c.skipped.is_empty());
        assert_eq!(c.messages.len(), msgs.len());
        for (got, (want, t)) in c.messages.iter().zip(&msgs) {
            assert!(same_message(&got.message, want), "{got:?} vs {want:?}");
            assert_eq!(got.log_time_ns, *t);
            assert_eq!(got.topic, want.topic());
        }
        assert_eq!(c.messages[0].name, "/lab/d1/sensor/sample");
        assert_eq!(c.messages[4].name, "/diagnostics");
        // Publish time is the header stamp.
        assert_eq!(c.messages[1].publish_time_ns, msgs[1].1 - 1000);
        assert_eq!(c.topics.len(), 6);
        assert!(c.topics.iter().all(|t| t.count == 40));
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

fn write_mixed_bag(path: &Path, chunk_size: u64) -> Vec<Message> {
    let mut w = BagWriter::create(
        path,
        BagWriterOptions {
            chunk_size,
            compression: BagCompression::None,
            ..Default::default()
        },
    )
    .unwrap();
    let msgs = every_topic(30);
    for (m, t) in &msgs {
        w.write_message("d1", m, *t).unwrap();
    }
    w.finish().unwrap();
    msgs.into_iter().map(|(m, _)| m).collect()
}

fn is_prefix(got: &[bag::BagMessage], want: &[Message]) -> bool {
    got.len() <= want.len()
        && got
            .iter()
            .zip(want)
            .all(|(g, w)| same_message(&g.message, w))
}

#[test]
fn truncation_at_any_offset_gives_a_prefix_or_an_error() {
    let dir = scratch("trunc");
    let want = write_mixed_bag(&dir.join("bag"), 1500);
    let bytes = std::fs::read(dir.join("bag/bag_0.mcap")).unwrap();
    let cut = dir.join("cut.mcap");
    let mut last = 0;
    let mut recovered_some = false;
    let mut offsets: Vec<usize> = (0..bytes.len()).step_by(37).collect();
    offsets.extend([1, 7, 8, 9, bytes.len() - 1, bytes.len() - 8]);
    offsets.sort();
    for &n in &offsets {
        std::fs::write(&cut, &bytes[..n]).unwrap();
        match read_bag(&cut) {
            Ok(c) => {
                assert!(is_prefix(&c.messages, &want), "cut at {n}");
                assert!(
                    c.messages.len() >= last,
                    "cut at {n}: fewer than a shorter cut"
                );
                last = c.messages.len();
                if c.messages.len() < want.len() {
                    assert!(
                        c.notes
                            .iter()
                            .any(|s| s.contains("truncated") || s.contains("unfinished")),
                        "cut at {n}: {:?}",
                        c.notes
                    );
                }
                recovered_some |= !c.messages.is_empty() && c.messages.len() < want.len();
            }
            Err(e) => {
                let text = e.to_string();
                assert!(text.contains("cut.mcap"), "cut at {n}: {text}");
            }
        }
    }
    assert!(recovered_some, "no cut recovered a partial bag");
    // The file without its summary section and footer (cut at the data end) reads whole.
    std::fs::write(&cut, &bytes[..bytes.len() - 8]).unwrap();
    assert_eq!(read_bag(&cut).unwrap().messages.len(), want.len());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn flipped_bytes_never_change_a_message_silently() {
    let dir = scratch("flip");
    let want = write_mixed_bag(&dir.join("bag"), 1500);
    let bytes = std::fs::read(dir.join("bag/bag_0.mcap")).unwrap();
    let bad = dir.join("bad.mcap");
    let mut errors = 0;
    for n in (0..bytes.len()).step_by(13) {
        let mut b = bytes.clone();
        b[n] ^= 0x5a;
        std::fs::write(&bad, &b).unwrap();
        match read_bag(&bad) {
            Ok(c) => assert!(
                is_prefix(&c.messages, &want),
                "flip at {n}: {:?} {:?} {:?}",
                c.skipped,
                c.notes,
                c.messages
                    .iter()
                    .zip(&want)
                    .find(|(g, w)| !same_message(&g.message, w))
            ),
            Err(e) => {
                errors += 1;
                assert!(e.to_string().contains("bad.mcap"), "flip at {n}: {e}");
            }
        }
    }
    assert!(errors > 0);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn empty_and_missing_pieces_are_clear_errors() {
    let dir = scratch("empty");
    // Empty file.
    std::fs::write(dir.join("e.mcap"), b"").unwrap();
    let e = read_bag(&dir.join("e.mcap")).unwrap_err();
    assert!(matches!(e, BagError::Empty { .. }), "{e}");
    assert!(
        e.to_string().contains("e.mcap") && e.to_string().contains("empty"),
        "{e}"
    );
    // Not MCAP.
    std::fs::write(dir.join("t.mcap"), b"time_s,force_N\n0,1\n").unwrap();
    let e = read_bag(&dir.join("t.mcap")).unwrap_err();
    assert!(e.to_string().contains("not an MCAP file"), "{e}");
    // Empty directory.
    std::fs::create_dir_all(dir.join("d")).unwrap();
    let e = read_bag(&dir.join("d")).unwrap_err();
    assert!(
        e.to_string().contains("neither metadata.yaml nor a .mcap"),
        "{e}"
    );
    // Missing path.
    let e = read_bag(&dir.join("nope")).unwrap_err();
    assert!(e.to_string().contains("nope"), "{e}");
    // A bag without metadata.yaml: the MCAP inside still reads, with a note.
    let rec = recording(200);
    write_recording(&dir.join("b"), &rec, "d1").unwrap();
    std::fs::remove_file(dir.join("b/metadata.yaml")).unwrap();
    let c = read_bag(&dir.join("b")).unwrap();
    assert_eq!(c.messages.len(), 200);
    assert!(c.notes[0].contains("no metadata.yaml"), "{:?}", c.notes);
    // Broken metadata.yaml, metadata naming a missing file, an sqlite3 bag.
    std::fs::write(
        dir.join("b/metadata.yaml"),
        "rosbag2_bagfile_information: [",
    )
    .unwrap();
    let e = read_bag(&dir.join("b")).unwrap_err();
    assert!(
        e.to_string()
            .contains("metadata.yaml: bad rosbag2 metadata"),
        "{e}"
    );
    let meta = "rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: mcap\n  \
                relative_file_paths: [gone_0.mcap]\n";
    std::fs::write(dir.join("b/metadata.yaml"), meta).unwrap();
    let e = read_bag(&dir.join("b")).unwrap_err();
    assert!(e.to_string().contains("gone_0.mcap"), "{e}");
    std::fs::write(
        dir.join("b/metadata.yaml"),
        meta.replace("mcap\n", "sqlite3\n"),
    )
    .unwrap();
    let e = read_bag(&dir.join("b")).unwrap_err();
    assert!(e.to_string().contains("sqlite3"), "{e}");
    // A bag with no sample topic is not a recording.
    let mut w = BagWriter::create(&dir.join("f"), BagWriterOptions::default()).unwrap();
    w.write_message("d1", &Message::PredictedForce(Float64 { data: 1.0 }), 5)
        .unwrap();
    w.finish().unwrap();
    let e = read_recording(&dir.join("f")).unwrap_err();
    assert!(e.to_string().contains("no sensor/sample messages"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn unknown_topics_are_skipped_and_counted() {
    let dir = scratch("unknown");
    let mut w = BagWriter::create(&dir.join("b"), BagWriterOptions::default()).unwrap();
    let rec = recording(50);
    for (i, s) in rec.samples.iter().enumerate() {
        let msg = Message::Sample(DamperSample {
            header: Header::at(s.time_s, "d1"),
            displacement: s.displacement_m,
            velocity: s.velocity_m_s,
            force: s.force_n,
            current: s.current_a,
            temperature: s.temperature_c.unwrap_or(f64::NAN),
        });
        let t = Time::from_secs_f64(s.time_s).as_nanos() as u64;
        w.write_message("d1", &msg, t).unwrap();
        if i % 5 == 0 {
            let cdr = msgs::cdr::encode(&Float64 { data: i as f64 });
            w.write(
                "/imu/temperature",
                Float64::TYPE_NAME,
                &Float64::definition(),
                Reliability::Reliable,
                t,
                t,
                &cdr,
            )
            .unwrap();
            // Our topic name with a foreign type is not ours either.
            w.write(
                "/d2/sensor/sample",
                "other_msgs/msg/Sample",
                "float64 x\n",
                Reliability::BestEffort,
                t,
                t,
                &cdr,
            )
            .unwrap();
        }
    }
    w.finish().unwrap();
    let c = read_bag(&dir.join("b")).unwrap();
    assert_eq!(c.messages.len(), 50);
    assert_eq!(c.skipped.len(), 2);
    assert_eq!(c.skipped[0].name, "/imu/temperature");
    assert_eq!(c.skipped[0].count, 10);
    assert_eq!(c.skipped[1].type_name, "other_msgs/msg/Sample");
    assert_same_recording(&rec, &read_recording(&dir.join("b")).unwrap());
    assert_eq!(Topic::parse("sensor/sample"), Some(Topic::Sample));
    std::fs::remove_dir_all(&dir).unwrap();
}

const KILL_ENV: &str = "MRTWIN_BAG_KILL_CHILD_DIR";

/// The child: write one sample per ms with a 40 ms flush period, print the flushed count
/// after each flush, until killed (or 20 s).
fn writer_child(dir: &Path) {
    let mut w = BagWriter::create(
        dir,
        BagWriterOptions {
            flush_period: Duration::from_millis(40),
            ..Default::default()
        },
    )
    .unwrap();
    let start = Instant::now();
    let mut reported = 0;
    for i in 0.. {
        let msg = kill_sample(i);
        w.write_message("d1", &msg, i * 1_000_000).unwrap();
        if w.flushed_message_count() != reported {
            reported = w.flushed_message_count();
            println!("flushed {reported}");
        }
        std::thread::sleep(Duration::from_micros(500));
        if start.elapsed() > Duration::from_secs(20) {
            break;
        }
    }
}

fn kill_sample(i: u64) -> Message {
    Message::Sample(DamperSample {
        header: Header::at(i as f64 * 1e-3, "d1"),
        displacement: (i as f64).sin() * 1e-2,
        velocity: i as f64,
        force: 10.0 * i as f64,
        current: 1.0,
        temperature: 25.0,
    })
}

#[test]
fn killed_writer_leaves_a_readable_bag() {
    if let Some(dir) = std::env::var_os(KILL_ENV) {
        writer_child(Path::new(&dir));
        return;
    }
    let dir = scratch("kill").join("bag");
    let mut child = std::process::Command::new(std::env::current_exe().unwrap())
        .args([
            "killed_writer_leaves_a_readable_bag",
            "--exact",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(KILL_ENV, &dir)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(stdout)
            .lines()
            .map_while(Result::ok)
        {
            if let Some(n) = line.strip_prefix("flushed ") {
                if tx.send(n.trim().parse::<u64>().unwrap()).is_err() {
                    break;
                }
            }
        }
    });
    let deadline = Instant::now() + Duration::from_secs(15);
    let mut flushes = 0;
    let mut flushed = 0;
    while flushes < 5 {
        let left = deadline.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(n) => {
                flushes += 1;
                flushed = n;
            }
            Err(_) => {
                child.kill().ok();
                panic!("the writer child reported {flushes} flushes within 15 s");
            }
        }
    }
    // Let it write past the flush, then SIGKILL (Child::kill is SIGKILL on Unix).
    std::thread::sleep(Duration::from_millis(15));
    child.kill().unwrap();
    child.wait().unwrap();
    // Anything flushed later than our last report only raises the count.
    while let Ok(n) = rx.try_recv() {
        flushed = flushed.max(n);
    }
    assert!(flushed > 0);
    let c = read_bag(&dir).unwrap();
    let info = c
        .metadata
        .as_ref()
        .expect("metadata.yaml exists after the kill");
    assert!(
        info.message_count >= flushed,
        "{} < {flushed}",
        info.message_count
    );
    assert!(
        c.messages.len() as u64 >= flushed,
        "{} < {flushed}",
        c.messages.len()
    );
    for (i, m) in c.messages.iter().enumerate() {
        assert!(
            same_message(&m.message, &kill_sample(i as u64)),
            "message {i}"
        );
    }
    let rec = read_recording(&dir).unwrap();
    assert_eq!(rec.samples.len(), c.messages.len());
    std::fs::remove_dir_all(dir.parent().unwrap()).unwrap();
}

fn fixtures_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/bags")
}

/// The first 3 s of the real UTFSM recording `preprocessed/10mm1Hz1A.txt`.
fn real_fixture_source() -> Recording {
    let file = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data/real/maurel-utfsm/preprocessed/10mm1Hz1A.txt");
    let mut rec = bridge::utfsm::read_preprocessed(&file).unwrap_or_else(|e| {
        panic!("the real-recording fixture needs shared/data/real/maurel-utfsm: {e}")
    });
    rec.samples.retain(|s| s.time_s < 3.0);
    rec
}

/// Regenerates `tests/fixtures/bags/utfsm-10mm1Hz1A` (scripts/make-fixtures.sh runs it).
#[test]
#[ignore = "writes the committed fixture; run by scripts/make-fixtures.sh"]
fn regenerate_real_fixture() {
    let dir = fixtures_dir().join("utfsm-10mm1Hz1A");
    let _ = std::fs::remove_dir_all(&dir);
    write_recording(&dir, &real_fixture_source(), "utfsm").unwrap();
}

#[test]
fn committed_fixtures_read_back() {
    let real = fixtures_dir().join("utfsm-10mm1Hz1A");
    let c = read_bag(&real).unwrap();
    assert!(c.notes.is_empty() && c.skipped.is_empty(), "{:?}", c.notes);
    assert_eq!(c.messages[0].name, "/utfsm/sensor/sample");
    assert_same_recording(&real_fixture_source(), &read_recording(&real).unwrap());
    let sim = fixtures_dir().join("simulated-two-chamber");
    let c = read_bag(&sim).unwrap();
    assert!(c.notes.is_empty() && c.skipped.is_empty(), "{:?}", c.notes);
    assert_eq!(c.metadata.as_ref().unwrap().message_count, 2000);
    let rec = read_recording(&sim).unwrap();
    assert_eq!(rec.samples.len(), 2000);
    assert!(rec.samples.iter().any(|s| s.current_a == 0.5));
    assert!(rec.samples.iter().any(|s| s.current_a == 1.0));
    let peak = rec
        .samples
        .iter()
        .map(|s| s.force_n.abs())
        .fold(0.0, f64::max);
    assert!(peak > 100.0, "peak force {peak} N");
}

/// Found by the fuzzer (issue 15, `fuzz-parsers --parser bag-mcap --seed 1`, input 2761):
/// a file with two channels of one topic name and two types (`DamperSample` and
/// `Float64` on `sensor/sample`). The reader took the first channel's type for every
/// message of the name and failed to decode the other channel's messages; each channel is
/// now read as its own type (the `Float64` one is not an mrtwin topic and is skipped).
#[test]
fn one_topic_name_with_two_types_reads_each_as_its_own() {
    let file = fixtures_dir().join("fuzz/two-types-on-one-topic.mcap");
    let c = read_bag(&file).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(c.message_count(), 5);
    let listing: Vec<(&str, &str, u64, Option<Topic>)> = c
        .topics
        .iter()
        .map(|t| (t.name.as_str(), t.type_name.as_str(), t.count, t.known))
        .collect();
    let sample = Some(Topic::Sample);
    assert_eq!(
        listing,
        [
            ("sensor/sample", DamperSample::TYPE_NAME, 1, sample),
            ("sensor/sample", Float64::TYPE_NAME, 2, None),
            ("/d1/sensor/sample", "", 1, None),
            ("/d1/sensor/sample", DamperSample::TYPE_NAME, 1, sample),
        ]
    );
    assert_eq!(c.messages.len(), 2);
    assert_eq!(c.skipped.len(), 2);
    assert_eq!(c.skipped[0].type_name, Float64::TYPE_NAME);
}
