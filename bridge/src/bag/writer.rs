//! [`BagWriter`]: the streaming bag writer of the recorder.
//!
//! Layout: `<dir>/metadata.yaml` and `<dir>/<dir name>_0.mcap`, as `ros2 bag record -s mcap`.
//!
//! # Crash safety and the loss bound
//!
//! Messages collect in an in-memory chunk (mcap's buffered chunk mode: no seeking, so a
//! chunk reaches the file in one piece or, if the process dies while writing it, as a
//! truncated tail the reader drops). [`BagWriter::flush`] closes the chunk, writes it and
//! its message indexes, flushes (and by default `fsync`s) the file, then rewrites
//! `metadata.yaml` atomically (temporary file + rename) with the counts so far. A flush
//! happens
//! * on every [`BagWriter::write`] once [`BagWriterOptions::flush_period`] has passed since
//!   the last one, and on [`BagWriter::tick`] (call it from the recorder's loop so a quiet
//!   topic is flushed too);
//! * on its own when the chunk reaches [`BagWriterOptions::chunk_size`] bytes (written, not
//!   yet `fsync`ed: it survives `kill -9`, not a power cut);
//! * in [`BagWriter::finish`] (also run on drop), which adds the summary section.
//!
//! After a `kill -9` every message written before the last completed flush is readable
//! by [`super::read_bag`] (and by `mcap recover`): at most the messages of one flush
//! period (default 1 s) are lost — or one chunk (default 512 KiB of messages) when that is
//! smaller. `metadata.yaml` always exists, and its counts are those of the last flush (≤
//! what the file holds).

use std::collections::{BTreeMap, HashMap};
use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::qos::Reliability;
use crate::transport::{Message, Topic};

use super::metadata::{
    self, BagInfo, FileInfo, StartingTime, TopicMetadata, TopicWithCount, METADATA_FILE,
    METADATA_VERSION,
};
use super::{
    qos_profiles_yaml, topic_name, topic_reliability, BagError, MESSAGE_ENCODING, PROFILE,
    SCHEMA_ENCODING,
};

/// Chunk compression.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BagCompression {
    /// Uncompressed chunks.
    None,
    /// zstd chunks (what rosbag2's MCAP plugin uses by default).
    #[default]
    Zstd,
    /// lz4 chunks.
    Lz4,
}

/// Options of [`BagWriter`].
#[derive(Debug, Clone)]
pub struct BagWriterOptions {
    /// Uncompressed bytes after which a chunk is closed and written.
    pub chunk_size: u64,
    /// Longest time between flushes (see the module's loss bound).
    pub flush_period: Duration,
    /// Chunk compression.
    pub compression: BagCompression,
    /// `fsync` the data file on every flush (survives power loss, not only `kill -9`).
    pub sync: bool,
}

impl Default for BagWriterOptions {
    fn default() -> Self {
        Self {
            chunk_size: 512 * 1024,
            flush_period: Duration::from_secs(1),
            compression: BagCompression::Zstd,
            sync: true,
        }
    }
}

/// What a finished bag holds.
#[derive(Debug, Clone, PartialEq)]
pub struct BagSummary {
    /// The `.mcap` file.
    pub mcap_path: PathBuf,
    /// Messages written.
    pub message_count: u64,
    /// (topic name, type, count) in order of first use.
    pub topics: Vec<(String, String, u64)>,
    /// First and last log time \[ns\], if any message.
    pub time_range_ns: Option<(u64, u64)>,
}

struct ChannelState {
    id: u16,
    name: String,
    type_name: String,
    qos: String,
    count: u64,
}

/// Streaming writer of a rosbag2 directory with MCAP storage (or of a bare `.mcap` file).
pub struct BagWriter {
    dir: Option<PathBuf>,
    mcap_path: PathBuf,
    file_name: String,
    writer: Option<mcap::Writer<BufWriter<File>>>,
    channels: Vec<ChannelState>,
    by_name: HashMap<String, usize>,
    /// (namespace, topic) → channel index, for [`BagWriter::write_message`].
    typed: Vec<(String, Topic, usize)>,
    options: BagWriterOptions,
    last_flush: Instant,
    count: u64,
    flushed_count: u64,
    range: Option<(u64, u64)>,
}

impl BagWriter {
    /// Create the bag directory `dir` (it must not exist, or be empty) with its
    /// `metadata.yaml` (no messages yet) and `<dir name>_0.mcap`.
    pub fn create(dir: &Path, options: BagWriterOptions) -> Result<Self, BagError> {
        if dir.exists() {
            let mut entries = fs::read_dir(dir).map_err(|e| BagError::io(dir, "list", e))?;
            if entries.next().is_some() {
                return Err(BagError::write(
                    dir,
                    "the directory exists and is not empty (a bag is never written over)",
                ));
            }
        }
        fs::create_dir_all(dir).map_err(|e| BagError::io(dir, "create directory", e))?;
        let stem = dir
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .filter(|s| !s.is_empty() && s != "." && s != "..")
            .unwrap_or_else(|| "bag".into());
        let file_name = format!("{stem}_0.mcap");
        let mut w = Self::open(dir.join(&file_name), Some(dir.to_owned()), options)?;
        w.file_name = file_name;
        w.write_metadata_yaml()?;
        Ok(w)
    }

    /// Create a bare `.mcap` file (no directory, no `metadata.yaml`).
    pub fn create_mcap(path: &Path, options: BagWriterOptions) -> Result<Self, BagError> {
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            fs::create_dir_all(parent).map_err(|e| BagError::io(parent, "create directory", e))?;
        }
        Self::open(path.to_owned(), None, options)
    }

    fn open(
        mcap_path: PathBuf,
        dir: Option<PathBuf>,
        options: BagWriterOptions,
    ) -> Result<Self, BagError> {
        let file = fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&mcap_path)
            .map_err(|e| BagError::io(&mcap_path, "create", e))?;
        let compression = match options.compression {
            BagCompression::None => None,
            BagCompression::Zstd => Some(mcap::Compression::Zstd),
            BagCompression::Lz4 => Some(mcap::Compression::Lz4),
        };
        let mut writer = mcap::WriteOptions::new()
            .profile(PROFILE)
            .library(concat!("mrtwin/", env!("CARGO_PKG_VERSION")))
            .compression(compression)
            .compression_threads(0)
            .chunk_size(Some(options.chunk_size.max(1)))
            // Buffered chunks: a chunk reaches the file whole, never as a placeholder
            // header patched later (see the module doc).
            .disable_seeking(true)
            .create(BufWriter::with_capacity(1 << 16, file))
            .map_err(|e| mcap_error(&mcap_path, e))?;
        // Magic and header reach the file at once: a recorder killed before its first
        // flush leaves a valid (empty) MCAP file, not a 0-byte one.
        writer.flush().map_err(|e| mcap_error(&mcap_path, e))?;
        let file_name = mcap_path
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        Ok(Self {
            dir,
            mcap_path,
            file_name,
            writer: Some(writer),
            channels: Vec::new(),
            by_name: HashMap::new(),
            typed: Vec::new(),
            options,
            last_flush: Instant::now(),
            count: 0,
            flushed_count: 0,
            range: None,
        })
    }

    /// The `.mcap` file being written.
    pub fn mcap_path(&self) -> &Path {
        &self.mcap_path
    }

    /// Messages written so far.
    pub fn message_count(&self) -> u64 {
        self.count
    }

    /// Messages written before the last completed flush: these survive a `kill -9`.
    pub fn flushed_message_count(&self) -> u64 {
        self.flushed_count
    }

    /// Write one message: CDR bytes with the encapsulation header, on `topic_name`
    /// (absolute, e.g. `/d1/sensor/sample`) of ROS type `type_name` whose full `ros2msg`
    /// text is `definition`, offered with `reliability`. Times in ns. Flushes when the
    /// flush period has passed.
    #[allow(clippy::too_many_arguments)]
    pub fn write(
        &mut self,
        topic_name: &str,
        type_name: &str,
        definition: &str,
        reliability: Reliability,
        log_time_ns: u64,
        publish_time_ns: u64,
        cdr: &[u8],
    ) -> Result<(), BagError> {
        let idx = match self.by_name.get(topic_name) {
            Some(&i) => {
                if self.channels[i].type_name != type_name {
                    return Err(BagError::write(
                        &self.mcap_path,
                        format!(
                            "topic {topic_name} already carries {}, not {type_name}",
                            self.channels[i].type_name
                        ),
                    ));
                }
                i
            }
            None => self.add_channel(topic_name, type_name, definition, reliability)?,
        };
        self.write_to(idx, log_time_ns, publish_time_ns, cdr)
    }

    fn write_to(
        &mut self,
        idx: usize,
        log_time_ns: u64,
        publish_time_ns: u64,
        cdr: &[u8],
    ) -> Result<(), BagError> {
        let ch = &mut self.channels[idx];
        if cdr.len() < 4 {
            return Err(BagError::write(
                &self.mcap_path,
                format!(
                    "message on {} has {} bytes, fewer than the CDR encapsulation header",
                    ch.name,
                    cdr.len()
                ),
            ));
        }
        let writer = self.writer.as_mut().expect("writer present until finish");
        writer
            .write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id: ch.id,
                    sequence: ch.count as u32,
                    log_time: log_time_ns,
                    publish_time: publish_time_ns,
                },
                cdr,
            )
            .map_err(|e| mcap_error(&self.mcap_path, e))?;
        ch.count += 1;
        self.count += 1;
        self.range = Some(match self.range {
            None => (log_time_ns, log_time_ns),
            Some((a, b)) => (a.min(log_time_ns), b.max(log_time_ns)),
        });
        self.tick()
    }

    /// Write an mrtwin [`Message`] on its topic under `namespace` (the damper name; see
    /// [`topic_name`]) with its QoS. The publish time is the message's header stamp (the
    /// `/clock` time for [`Message::Clock`]; the log time for messages without a stamp).
    pub fn write_message(
        &mut self,
        namespace: &str,
        msg: &Message,
        log_time_ns: u64,
    ) -> Result<(), BagError> {
        let topic = msg.topic();
        let publish = message_stamp_ns(msg)
            .and_then(|t| u64::try_from(t).ok())
            .unwrap_or(log_time_ns);
        let cached = self
            .typed
            .iter()
            .find(|(ns, t, _)| *t == topic && ns == namespace)
            .map(|(_, _, i)| *i);
        let idx = match cached {
            Some(i) => i,
            None => {
                let name = topic_name(namespace, topic);
                let i = match self.by_name.get(&name) {
                    Some(&i) if self.channels[i].type_name == topic.type_name() => i,
                    Some(_) => {
                        return Err(BagError::write(
                            &self.mcap_path,
                            format!("topic {name} already carries another type"),
                        ))
                    }
                    None => self.add_channel(
                        &name,
                        topic.type_name(),
                        &topic_definition(topic),
                        topic_reliability(topic),
                    )?,
                };
                self.typed.push((namespace.to_string(), topic, i));
                i
            }
        };
        self.write_to(idx, log_time_ns, publish, &msg.to_cdr())
    }

    fn add_channel(
        &mut self,
        topic_name: &str,
        type_name: &str,
        definition: &str,
        reliability: Reliability,
    ) -> Result<usize, BagError> {
        let writer = self.writer.as_mut().expect("writer present until finish");
        let err = |e: mcap::McapError| mcap_error(&self.mcap_path, e);
        let schema = writer
            .add_schema(type_name, SCHEMA_ENCODING, definition.as_bytes())
            .map_err(err)?;
        let qos = qos_profiles_yaml(reliability);
        let mut meta = BTreeMap::new();
        meta.insert("offered_qos_profiles".to_string(), qos.clone());
        let id = writer
            .add_channel(schema, topic_name, MESSAGE_ENCODING, &meta)
            .map_err(err)?;
        self.channels.push(ChannelState {
            id,
            name: topic_name.to_string(),
            type_name: type_name.to_string(),
            qos,
            count: 0,
        });
        self.by_name
            .insert(topic_name.to_string(), self.channels.len() - 1);
        Ok(self.channels.len() - 1)
    }

    /// Flush if the flush period has passed and messages are waiting. Call it from the
    /// recorder's loop so the loss bound holds when messages stop arriving.
    pub fn tick(&mut self) -> Result<(), BagError> {
        if self.count > self.flushed_count && self.last_flush.elapsed() >= self.options.flush_period
        {
            self.flush()?;
        }
        Ok(())
    }

    /// Close the current chunk, write and flush it (and `fsync` with
    /// [`BagWriterOptions::sync`]), then rewrite `metadata.yaml` atomically.
    pub fn flush(&mut self) -> Result<(), BagError> {
        let writer = self.writer.as_mut().expect("writer present until finish");
        writer.flush().map_err(|e| mcap_error(&self.mcap_path, e))?;
        if self.options.sync {
            // `Writer::flush` flushed the BufWriter; reach the file through the mcap
            // writer's stream is not possible, so sync by path.
            sync_path(&self.mcap_path)?;
        }
        self.flushed_count = self.count;
        self.last_flush = Instant::now();
        self.write_metadata_yaml()
    }

    /// Finish the bag: summary section (schemas, channels, statistics, chunk indexes),
    /// footer, a `rosbag2` metadata record carrying the metadata, and the final
    /// `metadata.yaml`.
    pub fn finish(mut self) -> Result<BagSummary, BagError> {
        self.finish_inner()?;
        Ok(BagSummary {
            mcap_path: self.mcap_path.clone(),
            message_count: self.count,
            topics: self
                .channels
                .iter()
                .map(|c| (c.name.clone(), c.type_name.clone(), c.count))
                .collect(),
            time_range_ns: self.range,
        })
    }

    fn finish_inner(&mut self) -> Result<(), BagError> {
        let Some(mut writer) = self.writer.take() else {
            return Ok(());
        };
        let path = self.mcap_path.clone();
        let info = self.info();
        let mut meta = BTreeMap::new();
        meta.insert("serialized_metadata".to_string(), metadata::to_yaml(&info));
        writer
            .write_metadata(&mcap::records::Metadata {
                name: "rosbag2".into(),
                metadata: meta,
            })
            .map_err(|e| mcap_error(&path, e))?;
        writer.finish().map_err(|e| mcap_error(&path, e))?;
        let buf = writer.into_inner();
        let file = buf
            .into_inner()
            .map_err(|e| BagError::io(&path, "write", e.into_error()))?;
        if self.options.sync {
            file.sync_all()
                .map_err(|e| BagError::io(&path, "sync", e))?;
        }
        self.flushed_count = self.count;
        self.write_metadata_yaml()
    }

    /// The metadata of what was written so far.
    fn info(&self) -> BagInfo {
        let (start, duration) = self.range.map(|(a, b)| (a, b - a)).unwrap_or((0, 0));
        BagInfo {
            version: METADATA_VERSION,
            storage_identifier: "mcap".into(),
            relative_file_paths: vec![self.file_name.clone()],
            duration: metadata::Duration {
                nanoseconds: duration,
            },
            starting_time: StartingTime {
                nanoseconds_since_epoch: start,
            },
            message_count: self.count,
            topics_with_message_count: self
                .channels
                .iter()
                .map(|c| TopicWithCount {
                    topic_metadata: TopicMetadata {
                        name: c.name.clone(),
                        type_name: c.type_name.clone(),
                        serialization_format: MESSAGE_ENCODING.into(),
                        offered_qos_profiles: serde_norway::Value::String(c.qos.clone()),
                        type_description_hash: String::new(),
                    },
                    message_count: c.count,
                })
                .collect(),
            compression_format: String::new(),
            compression_mode: String::new(),
            files: vec![FileInfo {
                path: self.file_name.clone(),
                starting_time: StartingTime {
                    nanoseconds_since_epoch: start,
                },
                duration: metadata::Duration {
                    nanoseconds: duration,
                },
                message_count: self.count,
            }],
            custom_data: None,
            ros_distro: "mrtwin".into(),
        }
    }

    /// Write `metadata.yaml` atomically (temporary file, fsync, rename).
    fn write_metadata_yaml(&self) -> Result<(), BagError> {
        let Some(dir) = &self.dir else {
            return Ok(());
        };
        let path = dir.join(METADATA_FILE);
        let tmp = dir.join(".metadata.yaml.tmp");
        let text = metadata::to_yaml(&self.info());
        let write = || -> std::io::Result<()> {
            let mut f = File::create(&tmp)?;
            f.write_all(text.as_bytes())?;
            if self.options.sync {
                f.sync_all()?;
            }
            fs::rename(&tmp, &path)
        };
        write().map_err(|e| BagError::io(&path, "write", e))
    }
}

impl Drop for BagWriter {
    fn drop(&mut self) {
        // Best effort: a bag dropped without `finish` still gets its summary.
        let _ = self.finish_inner();
    }
}

/// A writer error of the `mcap` crate as a [`BagError`] naming `path`. An I/O error keeps
/// its cause ("No space left on device" on a full disk, "File too large" under a file-size
/// limit): the `mcap` error's own text leaves it out.
fn mcap_error(path: &Path, e: mcap::McapError) -> BagError {
    match e {
        mcap::McapError::Io(error) => BagError::io(path, "write", error),
        e => BagError::write(path, e),
    }
}

fn sync_path(path: &Path) -> Result<(), BagError> {
    File::options()
        .write(true)
        .open(path)
        .and_then(|f| f.sync_data())
        .map_err(|e| BagError::io(path, "sync", e))
}

/// The full `ros2msg` definition of an mrtwin topic's type.
pub fn topic_definition(topic: Topic) -> String {
    use msgs::RosMessage;
    match topic {
        Topic::Sample => msgs::DamperSample::definition(),
        Topic::Output => msgs::TwinOutput::definition(),
        Topic::PredictedForce => msgs::Float64::definition(),
        Topic::YieldEstimate => msgs::YieldEstimate::definition(),
        Topic::Diagnostics => msgs::DiagnosticArray::definition(),
        Topic::Clock => msgs::Clock::definition(),
    }
}

/// The time stamp a message carries, in ns (`None` for `Float64`).
pub fn message_stamp_ns(msg: &Message) -> Option<i64> {
    Some(match msg {
        Message::Sample(m) => m.header.stamp.as_nanos(),
        Message::Output(m) => m.header.stamp.as_nanos(),
        Message::YieldEstimate(m) => m.header.stamp.as_nanos(),
        Message::Diagnostics(m) => m.header.stamp.as_nanos(),
        Message::Clock(m) => m.clock.as_nanos(),
        Message::PredictedForce(_) => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A full disk or a file-size limit reaches the writer as an `mcap` I/O error, whose own
    /// text ("I/O error from writing, …") drops the cause; the recorder must say it.
    #[test]
    #[cfg(target_os = "linux")] // EFBIG = 27, ENOSPC = 28
    fn an_io_error_of_the_mcap_writer_names_the_file_and_its_cause() {
        let path = Path::new("/data/run/run_0.mcap");
        for (raw, cause) in [(27, "File too large"), (28, "No space left on device")] {
            let e = mcap_error(
                path,
                mcap::McapError::Io(std::io::Error::from_raw_os_error(raw)),
            );
            let text = e.to_string();
            assert!(
                text.starts_with("/data/run/run_0.mcap: cannot write: ") && text.contains(cause),
                "{text}"
            );
        }
        let e = mcap_error(path, mcap::McapError::TooManyChannels).to_string();
        assert!(
            e.starts_with("/data/run/run_0.mcap: cannot write bag: "),
            "{e}"
        );
    }
}
