//! rosbag2 directories with MCAP storage, and bare `.mcap` files (issue 4).
//!
//! A bag written here is what `ros2 bag record -s mcap` leaves behind (see `docs/bags.md`):
//!
//! ```text
//! my_bag/
//!   metadata.yaml      rosbag2_bagfile_information, version 8, storage_identifier mcap
//!   my_bag_0.mcap      profile ros2; schemas ros2msg (full .msg text with dependencies);
//!                      channels cdr with offered_qos_profiles; messages = CDR with the
//!                      4-byte encapsulation header; chunked, indexed, summary + statistics
//! ```
//!
//! * [`writer`]: [`BagWriter`], the streaming writer of the recorder. It cuts a chunk and
//!   flushes at least every [`BagWriterOptions::flush_period`] and rewrites `metadata.yaml`
//!   atomically each time, so a `kill -9` loses at most the messages of the last flush
//!   period (see [`writer`] for the exact bound).
//! * [`reader`]: [`read_bag`] / [`RawMessages`]: directories with or without
//!   `metadata.yaml`, bare `.mcap` files, bags of other writers (rosbag2, python `rosbags`),
//!   files without summary or footer (a crashed recorder); topics that are not mrtwin's are
//!   skipped and listed with their counts.
//! * [`samples`]: a [`crate::Recording`] to and from the `sensor/sample` topic.
//! * [`metadata`]: `metadata.yaml` and the QoS strings.

pub mod metadata;
pub mod reader;
pub mod samples;
pub mod writer;

use std::path::{Path, PathBuf};

use crate::qos::Reliability;
use crate::transport::Topic;

pub use metadata::{qos_profiles_yaml, BagInfo};
pub use reader::{
    read_bag, BagContents, BagMessage, ChannelInfo, RawMessage, RawMessages, SkippedTopic,
    TopicSummary,
};
pub use samples::{read_recording, recording_from_contents, write_recording, write_recording_mcap};
pub use writer::{BagCompression, BagSummary, BagWriter, BagWriterOptions};

/// Schema encoding of ROS 2 message definitions in MCAP.
pub const SCHEMA_ENCODING: &str = "ros2msg";
/// Message encoding of ROS 2 messages in MCAP and rosbag2.
pub const MESSAGE_ENCODING: &str = "cdr";
/// MCAP header profile of ROS 2 bags.
pub const PROFILE: &str = "ros2";

/// What can go wrong with a bag. Every variant names the file concerned.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// The file system refused.
    #[error("{}: cannot {action}: {error}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// What was attempted.
        action: &'static str,
        /// The cause.
        #[source]
        error: std::io::Error,
    },
    /// There is nothing to read: an empty file, or a directory with neither
    /// `metadata.yaml` nor a `.mcap` file.
    #[error("{}: {what}", path.display())]
    Empty {
        /// The file or directory.
        path: PathBuf,
        /// What is missing.
        what: String,
    },
    /// Not an MCAP file (bad magic) or not a rosbag2 directory we can read.
    #[error("{}: {reason}", path.display())]
    NotABag {
        /// The file or directory.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// `metadata.yaml` does not parse or is inconsistent.
    #[error("{}: bad rosbag2 metadata: {reason}", file.display())]
    Metadata {
        /// The metadata file.
        file: PathBuf,
        /// Why.
        reason: String,
    },
    /// The MCAP data are damaged (CRC mismatch, malformed record, unknown channel, …).
    #[error("{}: corrupted MCAP data at or before byte {offset}: {reason}", file.display())]
    Corrupt {
        /// The `.mcap` file.
        file: PathBuf,
        /// Bytes consumed from the file when the damage was found.
        offset: u64,
        /// What the MCAP reader reported.
        reason: String,
    },
    /// A message's CDR payload does not decode as its topic's type.
    #[error("{}: message {index} on {topic} ({type_name}) does not decode: {reason}", file.display())]
    Decode {
        /// The bag.
        file: PathBuf,
        /// 0-based index of the message in the bag.
        index: u64,
        /// Topic name.
        topic: String,
        /// ROS type.
        type_name: String,
        /// The decoder's error.
        reason: String,
    },
    /// The bag holds no usable data for what was asked.
    #[error("{}: {reason}", path.display())]
    NoData {
        /// The bag.
        path: PathBuf,
        /// What is missing.
        reason: String,
    },
    /// Writing a bag failed or was given bad input.
    #[error("{}: cannot write bag: {reason}", path.display())]
    Write {
        /// The bag directory or file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
}

impl BagError {
    pub(crate) fn io(path: &Path, action: &'static str, error: std::io::Error) -> Self {
        BagError::Io {
            path: path.to_owned(),
            action,
            error,
        }
    }

    pub(crate) fn write(path: &Path, reason: impl ToString) -> Self {
        BagError::Write {
            path: path.to_owned(),
            reason: reason.to_string(),
        }
    }
}

/// Normalise a ROS type name to `pkg/msg/Type` (accepts the ROS 1 style `pkg/Type`).
pub fn normalize_type(type_name: &str) -> String {
    let parts: Vec<&str> = type_name.split('/').collect();
    match parts.as_slice() {
        [pkg, name] => format!("{pkg}/msg/{name}"),
        _ => type_name.to_string(),
    }
}

/// The mrtwin [`Topic`] a bag topic carries: its type must be the topic's type and its
/// name the topic's name under any namespace (`/lab/d1/sensor/sample` is
/// [`Topic::Sample`]). `None` for everything else.
pub fn known_topic(name: &str, type_name: &str) -> Option<Topic> {
    let type_name = normalize_type(type_name);
    let name = name.trim_start_matches('/');
    Topic::ALL.into_iter().find(|t| {
        let key = t.key();
        t.type_name() == type_name
            && (name == key
                || name
                    .strip_suffix(key)
                    .is_some_and(|prefix| prefix.ends_with('/')))
    })
}

/// The absolute bag topic name of `topic` in `namespace` (`d1` → `/d1/sensor/sample`);
/// `/diagnostics` and `/clock` stay global.
pub fn topic_name(namespace: &str, topic: Topic) -> String {
    let ns = namespace.trim_matches('/');
    if topic.ros_name().starts_with('/') || ns.is_empty() {
        format!("/{}", topic.key())
    } else {
        format!("/{ns}/{}", topic.key())
    }
}

/// QoS reliability mrtwin publishes `topic` with: best effort for sensor data.
pub fn topic_reliability(topic: Topic) -> Reliability {
    if topic.is_sensor_data() {
        Reliability::BestEffort
    } else {
        Reliability::Reliable
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The namespace of a known topic's name: `/lab/d1/sensor/sample` → `lab/d1`.
    fn topic_namespace(name: &str, topic: Topic) -> String {
        let name = name.trim_start_matches('/');
        name.strip_suffix(topic.key())
            .unwrap_or("")
            .trim_end_matches('/')
            .to_string()
    }

    #[test]
    fn topics_are_recognised_under_any_namespace() {
        let s = "mrtwin_msgs/msg/DamperSample";
        assert_eq!(known_topic("/sensor/sample", s), Some(Topic::Sample));
        assert_eq!(known_topic("/lab/d1/sensor/sample", s), Some(Topic::Sample));
        assert_eq!(
            known_topic("sensor/sample", "mrtwin_msgs/DamperSample"),
            Some(Topic::Sample)
        );
        assert_eq!(known_topic("/lab/xsensor/sample", s), None);
        assert_eq!(known_topic("/sensor/sample", "std_msgs/msg/Float64"), None);
        assert_eq!(
            topic_namespace("/lab/d1/sensor/sample", Topic::Sample),
            "lab/d1"
        );
        assert_eq!(topic_name("d1", Topic::Sample), "/d1/sensor/sample");
        assert_eq!(topic_name("d1", Topic::Diagnostics), "/diagnostics");
        assert_eq!(topic_name("", Topic::Output), "/twin/output");
    }
}
