//! Generators and checks of the bag reader: bare `.mcap` files and rosbag2 directories
//! (`bridge::bag::read_bag`, then `recording_from_contents`), and `metadata.yaml`
//! (`bridge::bag::metadata::parse_metadata`).
//!
//! The MCAP files are written here with the `mcap` crate and options the bag writer never
//! uses (chunked or not, compressed or not, with or without CRCs and summary), with
//! mrtwin topics under any namespace, foreign topics, wrong types and encodings, channels
//! without schema, valid CDR payloads or mutated ones; then, most of the time, the whole
//! file is mutated. The reader takes paths, so each worker writes the input into its own
//! scratch directory (the same files every time).

use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::Path;

use bridge::bag::metadata::{
    parse_metadata, to_yaml, FileInfo, StartingTime, TopicMetadata, TopicWithCount,
};
use bridge::bag::writer::topic_definition;
use bridge::bag::{qos_profiles_yaml, read_bag, recording_from_contents, BagInfo};
use bridge::qos::Reliability;
use bridge::transport::{Message, Topic};

use super::cdr::RandomMessage;
use super::mutate::mutate;
use super::rng::Rng;
use super::{names_file, FuzzInput, Parser, Scratch, Verdict};

/// Largest generated `.mcap` file.
const MAX_MCAP: usize = 8192;
/// Largest generated `metadata.yaml`.
const MAX_YAML: usize = 4096;
/// The storage file of a generated bag directory.
const MCAP_NAME: &str = "fuzz_0.mcap";

/// The bag parsers.
pub fn parsers() -> Vec<Parser> {
    vec![
        Parser {
            name: "bag-mcap",
            entry: "bridge::bag::read_bag on a bare .mcap file, then recording_from_contents",
            generate: generate_mcap_input,
            check: check_mcap,
        },
        Parser {
            name: "bag-directory",
            entry: "bridge::bag::read_bag on a rosbag2 directory (metadata.yaml + .mcap)",
            generate: generate_directory,
            check: check_directory,
        },
        Parser {
            name: "bag-metadata",
            entry: "bridge::bag::metadata::parse_metadata; accepted → to_yaml → parse round trip",
            generate: generate_metadata_input,
            check: check_metadata,
        },
    ]
}

/// One channel of a generated file.
struct ChannelSpec {
    topic: String,
    type_name: String,
    encoding: &'static str,
    /// The mrtwin topic whose CDR the payloads are (when the type is the topic's).
    payload: Option<Topic>,
    with_schema: bool,
}

fn random_channel(rng: &mut Rng) -> ChannelSpec {
    let topic = *rng.pick(&Topic::ALL);
    let name = match rng.below(4) {
        0 => format!("/{}", topic.key()),
        1 => format!("/lab/d{}/{}", rng.below(3), topic.key()),
        2 => bridge::bag::topic_name("d1", topic),
        _ => topic.key().to_owned(),
    };
    match rng.below(8) {
        0 => ChannelSpec {
            topic: "/chatter".into(),
            type_name: "std_msgs/msg/String".into(),
            encoding: "cdr",
            payload: None,
            with_schema: true,
        },
        1 => ChannelSpec {
            topic: name,
            type_name: "std_msgs/msg/Float64".into(),
            encoding: "cdr",
            payload: Some(Topic::PredictedForce),
            with_schema: true,
        },
        2 => ChannelSpec {
            topic: name,
            type_name: topic.type_name().into(),
            encoding: ["json", "ros1", ""][rng.below(3)],
            payload: Some(topic),
            with_schema: rng.one_in(2),
        },
        _ => ChannelSpec {
            topic: name,
            // ROS 1 style names are accepted too.
            type_name: if rng.one_in(4) {
                topic.type_name().replace("/msg/", "/")
            } else {
                topic.type_name().into()
            },
            encoding: "cdr",
            payload: Some(topic),
            with_schema: !rng.one_in(8),
        },
    }
}

/// A random message of `topic`, as CDR.
fn random_payload(rng: &mut Rng, topic: Topic) -> Vec<u8> {
    let message = match topic {
        Topic::Sample => Message::Sample(msgs::DamperSample::random(rng)),
        Topic::Output => Message::Output(msgs::TwinOutput::random(rng)),
        Topic::PredictedForce => Message::PredictedForce(msgs::Float64::random(rng)),
        Topic::YieldEstimate => Message::YieldEstimate(msgs::YieldEstimate::random(rng)),
        Topic::Diagnostics => Message::Diagnostics(msgs::DiagnosticArray::random(rng)),
        Topic::Clock => Message::Clock(msgs::Clock::random(rng)),
    };
    message.to_cdr()
}

/// A sensor sample at `t` seconds with finite values (so a recording can be made of it).
fn sample_payload(rng: &mut Rng, t: f64) -> Vec<u8> {
    Message::Sample(msgs::DamperSample {
        header: msgs::Header::at(t, "d1"),
        displacement: rng.uniform(-0.02, 0.02),
        velocity: rng.uniform(-0.2, 0.2),
        force: rng.uniform(-1e3, 1e3),
        current: rng.uniform(0.0, 1.0),
        temperature: if rng.one_in(2) { f64::NAN } else { 25.0 },
    })
    .to_cdr()
}

const MCAP_DICTIONARY: &[&[u8]] = &[
    b"\x89MCAP0\r\n",
    b"ros2",
    b"ros2msg",
    b"cdr",
    b"/sensor/sample",
    b"mrtwin_msgs/msg/DamperSample",
    b"zstd",
    b"lz4",
    &[0x01],
    &[0x02],
    &[0x03],
    &[0x04],
    &[0x05],
    &[0x06],
    &[0x0f],
    &[0, 1, 0, 0],
];

/// A `.mcap` file; `Ok(messages written)` when nothing in it was damaged on purpose.
fn generate_mcap(rng: &mut Rng) -> (Vec<u8>, Option<u64>) {
    let compression = match rng.below(8) {
        0 => Some(mcap::Compression::Zstd),
        1 => Some(mcap::Compression::Lz4),
        _ => None,
    };
    let crcs = rng.one_in(2);
    let summary = rng.one_in(2);
    let options = mcap::WriteOptions::new()
        .profile("ros2")
        .compression(compression)
        .use_chunks(!rng.one_in(3))
        .chunk_size(Some(rng.range(64, 4096) as u64))
        .calculate_chunk_crcs(crcs)
        .calculate_data_section_crc(crcs)
        .calculate_summary_section_crc(crcs)
        .emit_summary_records(summary)
        .emit_summary_offsets(summary)
        .emit_statistics(summary)
        .emit_message_indexes(summary)
        .emit_chunk_indexes(summary);
    let Ok(mut writer) = mcap::Writer::with_options(Cursor::new(Vec::new()), options) else {
        return (Vec::new(), None);
    };
    let mut intact = true;
    let mut channels = Vec::new();
    // Usually a sample topic with a run of samples, so recordings are made.
    let sample_run = rng.one_in(2);
    if sample_run {
        channels.push(ChannelSpec {
            topic: "/d1/sensor/sample".into(),
            type_name: Topic::Sample.type_name().into(),
            encoding: "cdr",
            payload: Some(Topic::Sample),
            with_schema: true,
        });
    }
    for _ in 0..rng.range(usize::from(!sample_run), 3) {
        channels.push(random_channel(rng));
    }
    let mut ids = Vec::new();
    for c in &channels {
        let definition = c
            .payload
            .filter(|t| t.type_name() == c.type_name)
            .map(topic_definition)
            .unwrap_or_else(|| "string data\n".into());
        let schema = if c.with_schema {
            match writer.add_schema(&c.type_name, "ros2msg", definition.as_bytes()) {
                Ok(id) => id,
                Err(_) => return (Vec::new(), None),
            }
        } else {
            0
        };
        let mut metadata = BTreeMap::new();
        if rng.one_in(2) {
            metadata.insert(
                "offered_qos_profiles".to_owned(),
                qos_profiles_yaml(Reliability::Reliable),
            );
        }
        match writer.add_channel(schema, &c.topic, c.encoding, &metadata) {
            Ok(id) => ids.push(id),
            Err(_) => return (Vec::new(), None),
        }
    }
    let mut written = 0u64;
    let mut t = rng.uniform(0.0, 100.0);
    let count = rng.range(0, 12);
    for _ in 0..count {
        let k = if sample_run && rng.one_in(2) {
            0
        } else {
            rng.below(channels.len())
        };
        let c = &channels[k];
        t += rng.uniform(0.0001, 0.01);
        let mut payload = match c.payload {
            Some(Topic::Sample) if k == 0 && sample_run => sample_payload(rng, t),
            Some(topic) => random_payload(rng, topic),
            None => vec![0, 1, 0, 0, 1, 0, 0, 0, 0],
        };
        if rng.one_in(8) {
            mutate(rng, &mut payload, &[], 256);
            intact = false;
        }
        let time = (t * 1e9) as u64;
        let header = mcap::records::MessageHeader {
            channel_id: ids[k],
            sequence: written as u32,
            log_time: time,
            publish_time: time,
        };
        if writer.write_to_known_channel(&header, &payload).is_err() {
            return (Vec::new(), None);
        }
        written += 1;
    }
    if writer.finish().is_err() {
        return (Vec::new(), None);
    }
    let bytes = writer.into_inner().into_inner();
    (bytes, intact.then_some(written))
}

/// Parts of a generated bag: the `.mcap` file and, for intact ones, the message count.
fn mcap_parts(rng: &mut Rng, mutate_one_in: usize) -> (Vec<u8>, Option<u64>) {
    let (mut bytes, mut expected) = generate_mcap(rng);
    if !rng.one_in(mutate_one_in) {
        mutate(rng, &mut bytes, MCAP_DICTIONARY, MAX_MCAP);
        expected = None;
    }
    (bytes, expected)
}

fn generate_mcap_input(rng: &mut Rng) -> FuzzInput {
    let (bytes, expected) = mcap_parts(rng, 4);
    let mut input = FuzzInput::single("bag.mcap", bytes, expected.is_some());
    input.parts.push((
        "expected.txt".into(),
        expected
            .map_or(String::new(), |n| n.to_string())
            .into_bytes(),
    ));
    input
}

/// The message count an intact generated bag must give back.
fn expected_messages(input: &FuzzInput) -> Option<u64> {
    std::str::from_utf8(input.part("expected.txt"))
        .ok()?
        .parse()
        .ok()
}

/// Read the bag at `path` and make a recording of it; every error must name a path
/// inside `within`.
fn read_and_check(path: &Path, input: &FuzzInput, within: &Path) -> Result<Verdict, String> {
    let contents = match read_bag(path) {
        Ok(c) => c,
        Err(e) if input.valid => return Err(format!("intact bag rejected: {e}")),
        Err(e) => return names_file(&e.to_string(), &within.display().to_string()),
    };
    if input.valid {
        if let Some(n) = expected_messages(input) {
            if contents.message_count() != n {
                return Err(format!(
                    "intact bag of {n} messages read as {}",
                    contents.message_count()
                ));
            }
        }
    }
    // The recording of the sample topic: an error is fine, a panic is not.
    if let Ok(rec) = recording_from_contents(&contents) {
        if rec.samples.windows(2).any(|w| w[1].time_s <= w[0].time_s) {
            return Err("a bag's recording has non-increasing time".into());
        }
    }
    Ok(Verdict::Accepted)
}

fn check_mcap(input: &FuzzInput, scratch: &Scratch) -> Result<Verdict, String> {
    let path = scratch.dir().join("bag.mcap");
    std::fs::write(&path, input.part("bag.mcap")).map_err(|e| format!("scratch write: {e}"))?;
    read_and_check(&path, input, &path)
}

/// Random `rosbag2_bagfile_information`: mostly right, sometimes another storage,
/// compression, version or file list.
fn random_info(rng: &mut Rng) -> (BagInfo, bool) {
    let mut valid = true;
    let storage = if rng.one_in(10) {
        valid = false;
        "sqlite3"
    } else {
        "mcap"
    };
    let compression_mode = match rng.below(12) {
        0 => {
            valid = false;
            "FILE"
        }
        1 => {
            valid = false;
            "message"
        }
        2 => "none",
        _ => "",
    };
    let files = match rng.below(8) {
        0 => Vec::new(),
        1 => {
            valid = false;
            vec!["missing_0.mcap".to_owned()]
        }
        2 => vec![format!("some/dir/{MCAP_NAME}")],
        _ => vec![MCAP_NAME.to_owned()],
    };
    let topics = (0..rng.below(3))
        .map(|_| {
            let topic = *rng.pick(&Topic::ALL);
            TopicWithCount {
                topic_metadata: TopicMetadata {
                    name: bridge::bag::topic_name("d1", topic),
                    type_name: topic.type_name().into(),
                    serialization_format: "cdr".into(),
                    offered_qos_profiles: if rng.one_in(2) {
                        serde_norway::Value::String(qos_profiles_yaml(Reliability::BestEffort))
                    } else {
                        serde_norway::Value::Sequence(Vec::new())
                    },
                    type_description_hash: String::new(),
                },
                message_count: rng.below(20) as u64,
            }
        })
        .collect();
    let info = BagInfo {
        version: *rng.pick(&[8, 9, 5, u32::MAX]),
        storage_identifier: storage.into(),
        relative_file_paths: files.clone(),
        duration: bridge::bag::metadata::Duration {
            nanoseconds: rng.next_u64() >> rng.below(64),
        },
        starting_time: StartingTime {
            nanoseconds_since_epoch: rng.next_u64() >> rng.below(64),
        },
        message_count: rng.below(20) as u64,
        topics_with_message_count: topics,
        compression_format: if rng.one_in(8) {
            "zstd".into()
        } else {
            String::new()
        },
        compression_mode: compression_mode.into(),
        files: files
            .iter()
            .map(|f| FileInfo {
                path: f.clone(),
                starting_time: StartingTime::default(),
                duration: bridge::bag::metadata::Duration::default(),
                message_count: rng.below(20) as u64,
            })
            .collect(),
        custom_data: rng
            .one_in(2)
            .then(|| BTreeMap::from([("by".to_owned(), "fuzz".to_owned())])),
        ros_distro: "mrtwin".into(),
    };
    (info, valid)
}

const YAML_DICTIONARY: &[&[u8]] = &[
    b"rosbag2_bagfile_information:",
    b"storage_identifier: ",
    b"relative_file_paths:",
    b"message_count: ",
    b"topics_with_message_count:",
    b"offered_qos_profiles: ",
    b"compression_mode: ",
    b"nanoseconds: ",
    b"- ",
    b": ",
    b"&a ",
    b"*a",
    b"<<: *a",
    b"!!binary ",
    b"!tag ",
    b"{",
    b"[",
    b"'",
    b"\"",
    b"|",
    b">-",
    b"\t",
    b"~",
    b"---\n",
    b"...\n",
    b"-1",
    b"18446744073709551616",
    b"1e400",
    b".nan",
];

/// A `metadata.yaml` text and whether it is an untouched, readable one.
fn metadata_text(rng: &mut Rng, mutate_one_in: usize) -> (Vec<u8>, bool) {
    let (info, mut valid) = random_info(rng);
    let mut text = to_yaml(&info).into_bytes();
    if !rng.one_in(mutate_one_in) {
        mutate(rng, &mut text, YAML_DICTIONARY, MAX_YAML);
        valid = false;
    }
    (text, valid)
}

fn generate_directory(rng: &mut Rng) -> FuzzInput {
    let (yaml, yaml_valid) = metadata_text(rng, 4);
    // The storage file is damaged less often here: the directory layer is the target.
    let (bytes, expected) = mcap_parts(rng, 2);
    FuzzInput {
        valid: yaml_valid && expected.is_some(),
        parts: vec![
            ("metadata.yaml".into(), yaml),
            (MCAP_NAME.into(), bytes),
            (
                "expected.txt".into(),
                expected
                    .map_or(String::new(), |n| n.to_string())
                    .into_bytes(),
            ),
        ],
    }
}

fn check_directory(input: &FuzzInput, scratch: &Scratch) -> Result<Verdict, String> {
    let dir = scratch.dir().join("bag");
    std::fs::create_dir_all(&dir).map_err(|e| format!("scratch dir: {e}"))?;
    for name in ["metadata.yaml", MCAP_NAME] {
        std::fs::write(dir.join(name), input.part(name))
            .map_err(|e| format!("scratch write: {e}"))?;
    }
    read_and_check(&dir, input, &dir)
}

fn generate_metadata_input(rng: &mut Rng) -> FuzzInput {
    let (text, valid) = metadata_text(rng, 4);
    FuzzInput::single("metadata.yaml", text, valid)
}

fn check_metadata(input: &FuzzInput, _: &Scratch) -> Result<Verdict, String> {
    let path = Path::new("bag/metadata.yaml");
    let text = String::from_utf8_lossy(input.part("metadata.yaml"));
    let info = match parse_metadata(&text, path) {
        Ok(info) => info,
        Err(e) if input.valid => return Err(format!("valid metadata.yaml rejected: {e}")),
        Err(e) => return names_file(&e.to_string(), "bag/metadata.yaml"),
    };
    // Round trip: what was read, written and read again, writes the same text.
    let written = to_yaml(&info);
    let again = parse_metadata(&written, path)
        .map_err(|e| format!("round trip: written metadata.yaml does not read back: {e}"))?;
    if to_yaml(&again) != written {
        return Err("round trip: metadata.yaml changes when read back".into());
    }
    Ok(Verdict::Accepted)
}
