//! Reading bags: rosbag2 directories (with or without `metadata.yaml`), bare `.mcap`
//! files, bags of other writers, and files a crashed recorder left without summary or
//! footer.
//!
//! [`RawMessages`] walks the MCAP data section record by record with mcap's linear
//! reader (no summary or footer needed; chunk CRCs are checked before a chunk's messages
//! are handed out). A file that ends in the middle of a record is *truncated*: the
//! messages before the cut are returned and a note says so. A file that ends with the
//! MCAP magic but breaks inside is *corrupted*: an error naming the file. [`read_bag`]
//! decodes the mrtwin topics and lists the others as skipped.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use mcap::sans_io::LinearReaderOptions;

use crate::transport::{Message, Topic};

use super::metadata::{read_metadata, BagInfo, METADATA_FILE};
use super::{known_topic, normalize_type, BagError, MESSAGE_ENCODING};

/// A channel of a bag: topic, type and schema.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChannelInfo {
    /// Topic name as recorded.
    pub topic: String,
    /// ROS type (`pkg/msg/Type`; the schema name).
    pub type_name: String,
    /// Schema encoding (`ros2msg`).
    pub schema_encoding: String,
    /// Message encoding (`cdr`).
    pub message_encoding: String,
    /// Schema text (the full `ros2msg` definition), empty without schema.
    pub definition: String,
    /// `offered_qos_profiles` of the channel's metadata, if any.
    pub qos: Option<String>,
}

/// One message as stored: its channel, times and payload.
#[derive(Debug, Clone)]
pub struct RawMessage {
    /// Its channel.
    pub channel: Arc<ChannelInfo>,
    /// Receive time \[ns\].
    pub log_time_ns: u64,
    /// Publish time \[ns\].
    pub publish_time_ns: u64,
    /// Payload (CDR with the encapsulation header, for `cdr` channels).
    pub data: Vec<u8>,
}

/// The files to read and the metadata of a bag path.
struct Resolved {
    files: Vec<PathBuf>,
    metadata: Option<BagInfo>,
    notes: Vec<String>,
}

fn resolve(path: &Path) -> Result<Resolved, BagError> {
    let meta = fs_metadata(path)?;
    if meta.is_file() && path.file_name().is_some_and(|n| n == METADATA_FILE) {
        let dir = path.parent().unwrap_or(Path::new("."));
        return resolve(if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        });
    }
    if meta.is_file() {
        return Ok(Resolved {
            files: vec![path.to_owned()],
            metadata: None,
            notes: Vec::new(),
        });
    }
    let meta_path = path.join(METADATA_FILE);
    let mut notes = Vec::new();
    if meta_path.exists() {
        let info = read_metadata(&meta_path)?;
        let bad = |reason: String| BagError::NotABag {
            path: path.to_owned(),
            reason,
        };
        if info.storage_identifier != "mcap" {
            return Err(bad(format!(
                "storage {:?} is not supported (only mcap; `ros2 bag convert` turns sqlite3 bags into mcap)",
                info.storage_identifier
            )));
        }
        let mode = info.compression_mode.to_ascii_lowercase();
        if !(mode.is_empty() || mode == "none" || mode == "message") {
            return Err(bad(format!(
                "file compression {:?} ({}) is not supported; decompress the bag first",
                info.compression_mode, info.compression_format
            )));
        }
        if mode == "message" {
            return Err(bad(
                "per-message compression is not supported; decompress the bag first".into(),
            ));
        }
        let files: Vec<PathBuf> = info
            .relative_file_paths
            .iter()
            .map(|f| path.join(Path::new(f).file_name().unwrap_or(f.as_ref())))
            .collect();
        if !files.is_empty() {
            let missing: Vec<String> = files
                .iter()
                .filter(|f| !f.exists())
                .map(|f| f.display().to_string())
                .collect();
            if !missing.is_empty() {
                return Err(BagError::Metadata {
                    file: meta_path,
                    reason: format!("storage files missing: {}", missing.join(", ")),
                });
            }
            return Ok(Resolved {
                files,
                metadata: Some(info),
                notes,
            });
        }
        notes.push(format!(
            "{} lists no storage files; reading the .mcap files of the directory",
            meta_path.display()
        ));
        let files = mcap_files(path)?;
        if files.is_empty() {
            return Err(BagError::Empty {
                path: path.to_owned(),
                what: "metadata.yaml lists no files and the directory holds no .mcap file".into(),
            });
        }
        return Ok(Resolved {
            files,
            metadata: Some(info),
            notes,
        });
    }
    let files = mcap_files(path)?;
    if files.is_empty() {
        return Err(BagError::Empty {
            path: path.to_owned(),
            what: "not a bag: the directory holds neither metadata.yaml nor a .mcap file".into(),
        });
    }
    notes.push(format!(
        "{}: no metadata.yaml; read {} directly",
        path.display(),
        files
            .iter()
            .map(|f| f.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    ));
    Ok(Resolved {
        files,
        metadata: None,
        notes,
    })
}

fn fs_metadata(path: &Path) -> Result<std::fs::Metadata, BagError> {
    std::fs::metadata(path).map_err(|e| BagError::io(path, "open", e))
}

fn mcap_files(dir: &Path) -> Result<Vec<PathBuf>, BagError> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| BagError::io(dir, "list", e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|x| x == "mcap"))
        .collect();
    files.sort();
    Ok(files)
}

/// Counts the bytes read from the file (for error offsets).
struct Counting<R> {
    inner: R,
    count: Arc<AtomicU64>,
}

impl<R: Read> Read for Counting<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.count.fetch_add(n as u64, Ordering::Relaxed);
        Ok(n)
    }
}

type Reader = mcap::io::MessageReader<Counting<BufReader<File>>>;

struct OpenFile {
    path: PathBuf,
    reader: Reader,
    consumed: Arc<AtomicU64>,
    /// The file ends with the MCAP magic: it was finished, so an early end is damage.
    finished: bool,
    messages: u64,
    channels: HashMap<u16, Arc<ChannelInfo>>,
}

/// Iterator over the messages of a bag in file order, every topic included.
///
/// It ends early, without an error, at the cut of a truncated file (see
/// [`RawMessages::notes`]); damage is an error, after which it yields nothing more.
pub struct RawMessages {
    pending: std::vec::IntoIter<PathBuf>,
    current: Option<OpenFile>,
    metadata: Option<BagInfo>,
    files: Vec<PathBuf>,
    notes: Vec<String>,
    failed: bool,
}

impl RawMessages {
    /// Open a bag directory, a bare `.mcap` file, or a bag's `metadata.yaml`.
    pub fn open(path: &Path) -> Result<Self, BagError> {
        let r = resolve(path)?;
        let mut it = Self {
            pending: r.files.clone().into_iter(),
            current: None,
            metadata: r.metadata,
            files: r.files,
            notes: r.notes,
            failed: false,
        };
        it.open_next()?;
        Ok(it)
    }

    /// The bag's `metadata.yaml`, when it has one.
    pub fn metadata(&self) -> Option<&BagInfo> {
        self.metadata.as_ref()
    }

    /// The `.mcap` files, in reading order.
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }

    /// What was unusual so far: no metadata.yaml, a truncated file (with the number of
    /// messages recovered), ….
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    fn open_next(&mut self) -> Result<(), BagError> {
        self.current = None;
        let Some(path) = self.pending.next() else {
            return Ok(());
        };
        let mut file = File::open(&path).map_err(|e| BagError::io(&path, "open", e))?;
        let len = file
            .metadata()
            .map_err(|e| BagError::io(&path, "open", e))?
            .len();
        if len == 0 {
            return Err(BagError::Empty {
                path: path.clone(),
                what: "the MCAP file is empty (0 bytes)".into(),
            });
        }
        let mut head = [0u8; 8];
        let n = read_up_to(&mut file, &mut head).map_err(|e| BagError::io(&path, "read", e))?;
        if head[..n] != mcap::MAGIC[..n] {
            return Err(BagError::NotABag {
                path: path.clone(),
                reason: "not an MCAP file (its first bytes are not the MCAP magic)".into(),
            });
        }
        let finished = len >= 16 && {
            use std::io::{Seek, SeekFrom};
            let mut tail = [0u8; 8];
            file.seek(SeekFrom::End(-8))
                .and_then(|_| file.read_exact(&mut tail))
                .map_err(|e| BagError::io(&path, "read", e))?;
            file.seek(SeekFrom::Start(0))
                .map_err(|e| BagError::io(&path, "read", e))?;
            tail == mcap::MAGIC
        };
        if !finished {
            use std::io::{Seek, SeekFrom};
            file.seek(SeekFrom::Start(0))
                .map_err(|e| BagError::io(&path, "read", e))?;
        }
        let consumed = Arc::new(AtomicU64::new(0));
        let source = Counting {
            inner: BufReader::with_capacity(1 << 16, file),
            count: consumed.clone(),
        };
        // No record is longer than the file; a chunk's decompressed size is bounded
        // generously. This keeps a damaged length field from asking for terabytes.
        let limit = usize::try_from(len.saturating_mul(64).max(256 << 20)).unwrap_or(usize::MAX);
        let options = LinearReaderOptions::default()
            .with_skip_end_magic(true)
            .with_prevalidate_chunk_crcs(true)
            .with_validate_data_section_crc(true)
            .with_record_length_limit(limit);
        self.current = Some(OpenFile {
            path,
            reader: mcap::io::MessageReader::new_with_options(source, options),
            consumed,
            finished,
            messages: 0,
            channels: HashMap::new(),
        });
        Ok(())
    }
}

fn read_up_to(file: &mut File, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match file.read(&mut buf[n..])? {
            0 => break,
            k => n += k,
        }
    }
    Ok(n)
}

fn is_truncation(e: &mcap::McapError) -> bool {
    match e {
        mcap::McapError::UnexpectedEof => true,
        mcap::McapError::Io(io) => io.kind() == std::io::ErrorKind::UnexpectedEof,
        _ => false,
    }
}

impl Iterator for RawMessages {
    type Item = Result<RawMessage, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        loop {
            let cur = self.current.as_mut()?;
            match cur.reader.next() {
                Some(Ok(m)) => {
                    cur.messages += 1;
                    let channel = cur
                        .channels
                        .entry(m.channel.id)
                        .or_insert_with(|| Arc::new(channel_info(&m.channel)))
                        .clone();
                    return Some(Ok(RawMessage {
                        channel,
                        log_time_ns: m.log_time,
                        publish_time_ns: m.publish_time,
                        data: m.data.into_owned(),
                    }));
                }
                Some(Err(e)) if is_truncation(&e) && !cur.finished => {
                    self.notes.push(format!(
                        "{}: truncated (ends inside a record, no summary or footer): recovered {} \
                         messages from the first {} bytes",
                        cur.path.display(),
                        cur.messages,
                        cur.consumed.load(Ordering::Relaxed)
                    ));
                }
                Some(Err(e)) => {
                    self.failed = true;
                    let reason = if is_truncation(&e) {
                        "the file ends with the MCAP magic but a record runs past its end \
                         (a damaged length field)"
                            .to_string()
                    } else {
                        e.to_string()
                    };
                    return Some(Err(BagError::Corrupt {
                        file: cur.path.clone(),
                        offset: cur.consumed.load(Ordering::Relaxed),
                        reason,
                    }));
                }
                None if !cur.finished => self.notes.push(format!(
                    "{}: unfinished (no summary or footer): recovered {} messages",
                    cur.path.display(),
                    cur.messages
                )),
                None => {}
            }
            if let Err(e) = self.open_next() {
                self.failed = true;
                return Some(Err(e));
            }
        }
    }
}

fn channel_info(c: &mcap::Channel<'_>) -> ChannelInfo {
    let (type_name, schema_encoding, definition) = match &c.schema {
        Some(s) => (
            s.name.clone(),
            s.encoding.clone(),
            String::from_utf8_lossy(&s.data).into_owned(),
        ),
        None => (String::new(), String::new(), String::new()),
    };
    ChannelInfo {
        topic: c.topic.clone(),
        type_name: normalize_type(&type_name),
        schema_encoding,
        message_encoding: c.message_encoding.clone(),
        definition,
        qos: c.metadata.get("offered_qos_profiles").cloned(),
    }
}

/// One decoded message of an mrtwin topic.
#[derive(Debug, Clone, PartialEq)]
pub struct BagMessage {
    /// Which mrtwin topic.
    pub topic: Topic,
    /// The topic name as recorded (`/d1/sensor/sample`).
    pub name: String,
    /// Receive time \[ns\].
    pub log_time_ns: u64,
    /// Publish time \[ns\].
    pub publish_time_ns: u64,
    /// The message.
    pub message: Message,
}

/// A topic of a bag with its message count and log times.
#[derive(Debug, Clone, PartialEq)]
pub struct TopicSummary {
    /// Topic name as recorded.
    pub name: String,
    /// ROS type.
    pub type_name: String,
    /// The mrtwin topic, `None` when skipped.
    pub known: Option<Topic>,
    /// Messages read.
    pub count: u64,
    /// Their log times \[ns\], in file order.
    pub log_times_ns: Vec<u64>,
}

/// A topic [`read_bag`] did not decode.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SkippedTopic {
    /// Topic name.
    pub name: String,
    /// ROS type.
    pub type_name: String,
    /// Messages skipped.
    pub count: u64,
    /// Why.
    pub reason: String,
}

/// Everything of a bag that mrtwin understands.
#[derive(Debug, Clone, Default)]
pub struct BagContents {
    /// The path given.
    pub path: PathBuf,
    /// The `.mcap` files read.
    pub files: Vec<PathBuf>,
    /// `metadata.yaml`, when present.
    pub metadata: Option<BagInfo>,
    /// Messages of the mrtwin topics, decoded, in file order.
    pub messages: Vec<BagMessage>,
    /// Every topic (name, type and encoding: one name published with two types is two
    /// topics), in order of first message.
    pub topics: Vec<TopicSummary>,
    /// Topics that are not mrtwin's (or not CDR), with counts.
    pub skipped: Vec<SkippedTopic>,
    /// Recovery notes: missing metadata.yaml, truncated file, count mismatch.
    pub notes: Vec<String>,
}

impl BagContents {
    /// Total messages read (decoded and skipped).
    pub fn message_count(&self) -> u64 {
        self.topics.iter().map(|t| t.count).sum()
    }
}

/// Read a bag (directory, bare `.mcap` file or `metadata.yaml`): decode the mrtwin
/// topics, list the others as skipped.
pub fn read_bag(path: &Path) -> Result<BagContents, BagError> {
    let mut raw = RawMessages::open(path)?;
    let mut out = BagContents {
        path: path.to_owned(),
        files: raw.files().to_vec(),
        metadata: raw.metadata().cloned(),
        ..Default::default()
    };
    // Per topic name, type and encoding: channels of one name with different types (a
    // publisher of another type on the same topic) are different topics, each decoded as
    // its own type or skipped.
    let mut topic_index: HashMap<(String, String, String), usize> = HashMap::new();
    for (index, m) in (0_u64..).zip(raw.by_ref()) {
        let m = m?;
        let ch = &m.channel;
        let key = (
            ch.topic.clone(),
            ch.type_name.clone(),
            ch.message_encoding.clone(),
        );
        let idx = *topic_index.entry(key).or_insert_with(|| {
            let known = (ch.message_encoding == MESSAGE_ENCODING)
                .then(|| known_topic(&ch.topic, &ch.type_name))
                .flatten();
            out.topics.push(TopicSummary {
                name: ch.topic.clone(),
                type_name: ch.type_name.clone(),
                known,
                count: 0,
                log_times_ns: Vec::new(),
            });
            out.topics.len() - 1
        });
        let t = &mut out.topics[idx];
        t.count += 1;
        t.log_times_ns.push(m.log_time_ns);
        if let Some(topic) = t.known {
            let message = Message::from_cdr(topic, &m.data).map_err(|e| BagError::Decode {
                file: path.to_owned(),
                index,
                topic: ch.topic.clone(),
                type_name: ch.type_name.clone(),
                reason: e.to_string(),
            })?;
            out.messages.push(BagMessage {
                topic,
                name: ch.topic.clone(),
                log_time_ns: m.log_time_ns,
                publish_time_ns: m.publish_time_ns,
                message,
            });
        }
    }
    out.notes = raw.notes().to_vec();
    for t in &out.topics {
        if t.known.is_none() {
            out.skipped.push(SkippedTopic {
                name: t.name.clone(),
                type_name: t.type_name.clone(),
                count: t.count,
                reason: if known_topic(&t.name, &t.type_name).is_some() {
                    "not CDR encoded".into()
                } else {
                    "not an mrtwin topic (name and type)".into()
                },
            });
        }
    }
    if let Some(info) = &out.metadata {
        let read = out.message_count();
        if info.message_count != read {
            out.notes.push(format!(
                "metadata.yaml lists {} messages, the storage holds {read}{}",
                info.message_count,
                if read > info.message_count {
                    " (metadata of the last flush of an unfinished recording)"
                } else {
                    ""
                }
            ));
        }
    }
    Ok(out)
}
