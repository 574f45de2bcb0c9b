//! The containers of ROS bags, each reduced to one stream of (topic, type, encoding, log
//! time, bytes): MCAP files (through the `mcap` crate), rosbag2 sqlite3 files (`sqlite.rs`,
//! feature `rosbag-sqlite`), ROS 1 bags (`ros1.rs`, feature `rosbag1`) and rosbag2 folders
//! (a `metadata.yaml` naming the storage and its files). Everything above this module sees
//! messages only, whatever the container.

use crate::bounds::MAX_RECORD_BYTES;
use crate::error::IoError;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What one topic of a bag holds.
#[derive(Debug, Clone, PartialEq)]
pub struct TopicInfo {
    /// The topic name, e.g. `/scan`.
    pub topic: String,
    /// The message type as the bag names it, normalised to `package/msg/Type`.
    pub msg_type: String,
    /// The message encoding: `cdr` for ROS 2, `ros1` for ROS 1.
    pub encoding: String,
    /// Number of messages.
    pub count: usize,
    /// Earliest and latest log time (recording clock), nanoseconds since the epoch.
    pub log_time_ns: (u64, u64),
}

/// The container a bag is stored in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BagFormat {
    /// MCAP (ROS 2's default storage since Iron), a file or a rosbag2 folder.
    Mcap,
    /// SQLite 3 (rosbag2's storage before Iron, `.db3`), a file or a rosbag2 folder.
    Sqlite3,
    /// A ROS 1 bag (format 2.0, `.bag`).
    Ros1,
}

impl BagFormat {
    /// `ROS 1 bag` or `ROS 2 bag`.
    pub fn ros(self) -> &'static str {
        match self {
            BagFormat::Ros1 => "ROS 1 bag",
            BagFormat::Mcap | BagFormat::Sqlite3 => "ROS 2 bag",
        }
    }

    /// The storage's name: `MCAP`, `sqlite3`, `ROS 1 bag`.
    pub fn storage(self) -> &'static str {
        match self {
            BagFormat::Mcap => "MCAP",
            BagFormat::Sqlite3 => "sqlite3",
            BagFormat::Ros1 => "ROS 1 bag",
        }
    }
}

/// The first bytes of each container.
const SQLITE_MAGIC: &[u8] = b"SQLite format 3\0";
const ROS1_MAGIC: &[u8] = b"#ROSBAG V";
/// ROS 1's format 1.2 and older (`#ROSRECORD V1.2`): recognised, to be refused by name.
const ROS1_OLD_MAGIC: &[u8] = b"#ROSRECORD V";

/// The container of the file at `path`, by its first bytes; `None` for anything else.
pub(crate) fn sniff(path: &Path) -> Option<BagFormat> {
    let mut head = [0u8; 16];
    let mut f = std::fs::File::open(path).ok()?;
    let n = std::io::Read::read(&mut f, &mut head).ok()?;
    let head = &head[..n];
    if head.starts_with(mcap::MAGIC) {
        Some(BagFormat::Mcap)
    } else if head.starts_with(SQLITE_MAGIC) {
        Some(BagFormat::Sqlite3)
    } else if head.starts_with(ROS1_MAGIC) || head.starts_with(ROS1_OLD_MAGIC) {
        Some(BagFormat::Ros1)
    } else {
        None
    }
}

/// A bag found at a path: its container, its files in recording order, and whether each
/// message is zstd-compressed (rosbag2's `compression_mode: message`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct BagFiles {
    pub format: BagFormat,
    pub files: Vec<PathBuf>,
    pub zstd_messages: bool,
}

/// Finds the bag at `path`: a file (its container by its first bytes) or a rosbag2 folder.
pub(crate) fn bag_files(path: &Path) -> Result<BagFiles, IoError> {
    if !path.is_dir() {
        let format = match sniff(path) {
            Some(f) => f,
            None if !path.exists() => {
                return Err(IoError::NotFound {
                    path: path.to_path_buf(),
                    what: "no such file or folder".into(),
                })
            }
            None => {
                return Err(IoError::invalid(
                    path,
                    "not a bag: the file starts with neither the MCAP, the SQLite nor the \
                     ROS 1 bag magic bytes",
                ))
            }
        };
        return Ok(BagFiles {
            format,
            files: vec![path.to_path_buf()],
            zstd_messages: false,
        });
    }
    let meta = path.join("metadata.yaml");
    let text = std::fs::read_to_string(&meta).map_err(|e| IoError::io(&meta, e))?;
    let value = |key: &str| {
        text.lines()
            .find_map(|l| l.trim().strip_prefix(key))
            .map(|v| v.trim().trim_matches(['"', '\'']).to_string())
    };
    let storage = value("storage_identifier:");
    let compression = value("compression_format:").unwrap_or_default();
    let mode = value("compression_mode:")
        .unwrap_or_default()
        .to_ascii_lowercase();
    let mut files = Vec::new();
    let mut in_files = false;
    for line in text.lines() {
        let t = line.trim();
        if t.starts_with("relative_file_paths:") {
            in_files = true;
            continue;
        }
        if in_files {
            match t.strip_prefix("- ") {
                Some(f) => files.push(path.join(f.trim().trim_matches(['"', '\'']))),
                None => in_files = false,
            }
        }
    }
    let format = match storage.as_deref() {
        Some("mcap") => BagFormat::Mcap,
        Some("sqlite3") => BagFormat::Sqlite3,
        Some(other) => {
            return Err(IoError::invalid(
                &meta,
                format!("storage_identifier {other:?} is not supported (expected mcap or sqlite3)"),
            ))
        }
        None => {
            return Err(IoError::invalid(
                &meta,
                "no storage_identifier: not a rosbag2 metadata.yaml",
            ))
        }
    };
    let zstd_messages = match (mode.as_str(), compression.as_str()) {
        ("" | "none", _) => false,
        ("message", "zstd") => true,
        ("file", _) => {
            return Err(IoError::invalid(
                &meta,
                format!(
                    "compression_mode file ({compression}): the storage files are compressed \
                     whole; decompress them (e.g. `zstd -d`) and the folder with `ros2 bag \
                     decompress`, or read the decompressed storage file directly"
                ),
            ))
        }
        _ => {
            return Err(IoError::invalid(
                &meta,
                format!(
                    "compression_mode {mode:?} with compression_format {compression:?} is not \
                     supported (expected none, or message with zstd)"
                ),
            ))
        }
    };
    if files.is_empty() {
        return Err(IoError::invalid(
            &meta,
            "relative_file_paths lists no storage file",
        ));
    }
    for f in &files {
        if !f.is_file() {
            return Err(IoError::NotFound {
                path: f.clone(),
                what: format!("storage file listed in {} is missing", meta.display()),
            });
        }
    }
    Ok(BagFiles {
        format,
        files,
        zstd_messages,
    })
}

/// `pkg/Type` → `pkg/msg/Type`; other names unchanged.
pub(crate) fn normalise_type(name: &str) -> String {
    let parts: Vec<&str> = name.split('/').collect();
    match parts.as_slice() {
        [pkg, ty] => format!("{pkg}/msg/{ty}"),
        _ => name.to_string(),
    }
}

/// One message as the container holds it.
pub(crate) struct RawMessage<'a> {
    pub topic: &'a str,
    pub msg_type: &'a str,
    pub encoding: &'a str,
    /// 0-based index of the message on its topic.
    pub index: usize,
    pub log_time_ns: u64,
    pub data: &'a [u8],
}

/// The topics seen so far and how far reading got (for the error of a damaged file).
pub(crate) struct Topics {
    map: BTreeMap<String, TopicInfo>,
    /// Messages read in the current file.
    pub read: usize,
    /// The log time of the last message read in the current file.
    pub last_time: Option<u64>,
}

impl Topics {
    /// No topic seen yet.
    pub fn new() -> Self {
        Topics {
            map: BTreeMap::new(),
            read: 0,
            last_time: None,
        }
    }

    /// Counts one message of `topic` and returns its index on the topic; a topic whose type
    /// changes is an error.
    pub fn add(
        &mut self,
        file: &Path,
        topic: &str,
        msg_type: &str,
        encoding: &str,
        log_time_ns: u64,
    ) -> Result<usize, IoError> {
        let info = self
            .map
            .entry(topic.to_string())
            .or_insert_with(|| TopicInfo {
                topic: topic.to_string(),
                msg_type: msg_type.to_string(),
                encoding: encoding.to_string(),
                count: 0,
                log_time_ns: (log_time_ns, log_time_ns),
            });
        if info.msg_type != msg_type {
            return Err(IoError::Bag {
                path: file.to_path_buf(),
                topic: topic.to_string(),
                what: format!(
                    "the topic carries two message types, {} and {msg_type}",
                    info.msg_type
                ),
            });
        }
        let index = info.count;
        info.count += 1;
        info.log_time_ns.0 = info.log_time_ns.0.min(log_time_ns);
        info.log_time_ns.1 = info.log_time_ns.1.max(log_time_ns);
        self.read += 1;
        self.last_time = Some(log_time_ns);
        Ok(index)
    }

    /// The error of a damaged file: what broke, how many messages were read before it, and
    /// the log time of the last.
    pub fn damaged(&self, file: &Path, format: BagFormat, why: impl std::fmt::Display) -> IoError {
        let len = std::fs::metadata(file).map(|m| m.len()).unwrap_or(0);
        IoError::invalid(
            file,
            format!(
                "truncated or corrupt {} ({why}): {} message(s) read before the damage in this \
                 {len}-byte file{}",
                format.storage(),
                self.read,
                match self.last_time {
                    Some(t) => format!(", the last logged at {} s", t as f64 * 1e-9),
                    None => String::new(),
                }
            ),
        )
    }
}

/// The largest message after zstd decompression, bytes (a bound on what a hostile
/// compressed message can make us allocate).
const MAX_MESSAGE: u64 = MAX_RECORD_BYTES as u64;

/// Decompresses one zstd frame of at most [`MAX_MESSAGE`] bytes.
fn unzstd(data: &[u8]) -> Result<Vec<u8>, String> {
    use std::io::Read as _;
    let mut out = Vec::new();
    zstd::stream::read::Decoder::new(data)
        .map_err(|e| e.to_string())?
        .take(MAX_MESSAGE + 1)
        .read_to_end(&mut out)
        .map_err(|e| format!("zstd message compression: {e}"))?;
    if out.len() as u64 > MAX_MESSAGE {
        return Err(format!(
            "a zstd-compressed message larger than {MAX_MESSAGE} bytes"
        ));
    }
    Ok(out)
}

/// Reads every message of the bag at `path` in file order and calls `f` on each; returns
/// the container and the topics seen. A truncated or corrupt file is an error saying how
/// many messages were read and the log time of the last one.
pub(crate) fn for_each_message(
    path: &Path,
    mut f: impl FnMut(&Path, RawMessage<'_>) -> Result<(), IoError>,
) -> Result<(BagFiles, Vec<TopicInfo>), IoError> {
    let bag = bag_files(path)?;
    let mut topics = Topics::new();
    for file in &bag.files {
        topics.read = 0;
        topics.last_time = None;
        let mut each = |m: RawMessage<'_>| -> Result<(), IoError> {
            if !bag.zstd_messages {
                return f(file, m);
            }
            let data = unzstd(m.data).map_err(|e| IoError::Bag {
                path: file.clone(),
                topic: m.topic.to_string(),
                what: format!("message {}: {e}", m.index + 1),
            })?;
            f(file, RawMessage { data: &data, ..m })
        };
        match bag.format {
            BagFormat::Mcap => mcap_messages(file, &mut topics, &mut each)?,
            #[cfg(feature = "rosbag-sqlite")]
            BagFormat::Sqlite3 => super::sqlite::messages(file, &mut topics, &mut each)?,
            #[cfg(feature = "rosbag1")]
            BagFormat::Ros1 => super::ros1::messages(file, &mut topics, &mut each)?,
            #[allow(unreachable_patterns)]
            other => {
                return Err(IoError::invalid(
                    file,
                    format!(
                        "a {} file, but slam-io was built without its `{}` feature",
                        other.storage(),
                        if other == BagFormat::Ros1 {
                            "rosbag1"
                        } else {
                            "rosbag-sqlite"
                        }
                    ),
                ))
            }
        }
    }
    Ok((bag, topics.map.into_values().collect()))
}

/// The callback each container calls with its messages.
pub(crate) type Each<'f> = dyn FnMut(RawMessage<'_>) -> Result<(), IoError> + 'f;

/// The messages of one MCAP file, streamed (the file is never held whole): through the
/// `mcap` crate's streaming reader with every record, compressed chunk and decompressed
/// chunk content bounded by [`MAX_RECORD_BYTES`], so a length field cannot make us
/// allocate more than that cap.
fn mcap_messages(file: &Path, topics: &mut Topics, f: &mut Each<'_>) -> Result<(), IoError> {
    let src = std::fs::File::open(file).map_err(|e| IoError::io(file, e))?;
    let mut head = [0u8; 8];
    let starts = std::io::Read::read_exact(&mut &src, &mut head).is_ok();
    if !starts || !head.starts_with(mcap::MAGIC) {
        return Err(IoError::invalid(
            file,
            "not an MCAP file (it does not start with the MCAP magic bytes)",
        ));
    }
    std::io::Seek::rewind(&mut &src).map_err(|e| IoError::io(file, e))?;
    let options =
        mcap::sans_io::LinearReaderOptions::default().with_record_length_limit(MAX_RECORD_BYTES);
    let stream = mcap::io::MessageReader::new_with_options(std::io::BufReader::new(src), options);
    for m in stream {
        let m = m.map_err(|e| topics.damaged(file, BagFormat::Mcap, mcap_error(e)))?;
        let ch = &m.channel;
        let msg_type = ch
            .schema
            .as_ref()
            .map_or_else(|| "(no schema)".to_string(), |s| normalise_type(&s.name));
        let index = topics.add(file, &ch.topic, &msg_type, &ch.message_encoding, m.log_time)?;
        f(RawMessage {
            topic: &ch.topic,
            msg_type: &msg_type,
            encoding: &ch.message_encoding,
            index,
            log_time_ns: m.log_time,
            data: &m.data,
        })?;
    }
    Ok(())
}

/// The `mcap` crate's error in words, with the cap named when a record was too large.
fn mcap_error(e: mcap::McapError) -> String {
    match e {
        mcap::McapError::ChunkTooLarge(n)
        | mcap::McapError::ChunkBufferTooLarge(n)
        | mcap::McapError::RecordTooLarge { len: n, .. } => {
            format!("a record or chunk of {n} bytes, expected at most {MAX_RECORD_BYTES} bytes")
        }
        other => other.to_string(),
    }
}
