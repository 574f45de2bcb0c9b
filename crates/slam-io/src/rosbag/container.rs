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
/// `mcap` crate's sans-io linear reader with every record, compressed chunk and decompressed
/// chunk content bounded by [`MAX_RECORD_BYTES`], so a length field cannot make us
/// allocate more than that cap. The reader's requests for more bytes are trusted only up to
/// the bytes the file still holds (a record that claims 256 MiB in a 6 kB file is an error
/// after reading the 6 kB, not an allocation of 256 MiB), and the length fields inside schema
/// and channel records are checked against the record's bytes ([`check_mcap_record`]) before
/// the crate parses them (its parser reserves a string's stated length, up to 4 GiB, before
/// reading it). Only schema, channel and message records are parsed; a message after the
/// data end record is an error.
fn mcap_messages(file: &Path, topics: &mut Topics, f: &mut Each<'_>) -> Result<(), IoError> {
    use mcap::records::{op, Record};
    use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
    use std::io::Read as _;
    let mut src = std::fs::File::open(file).map_err(|e| IoError::io(file, e))?;
    let len = src.metadata().map_err(|e| IoError::io(file, e))?.len();
    let mut head = [0u8; 8];
    let starts = src.read_exact(&mut head).is_ok();
    if !starts || !head.starts_with(mcap::MAGIC) {
        return Err(IoError::invalid(
            file,
            "not an MCAP file (it does not start with the MCAP magic bytes)",
        ));
    }
    std::io::Seek::rewind(&mut src).map_err(|e| IoError::io(file, e))?;
    let mut src = std::io::BufReader::new(src);
    let damaged = |topics: &Topics, why: String| topics.damaged(file, BagFormat::Mcap, why);
    let options = LinearReaderOptions::default()
        .with_record_length_limit(MAX_RECORD_BYTES)
        .with_emit_chunks(false);
    let mut reader = LinearReader::new_with_options(options);
    let mut channels = mcap::read::ChannelAccumulator::default();
    // Bytes handed to the reader so far, and whether the data end record was passed.
    let (mut fed, mut past_data_end) = (0u64, false);
    while let Some(event) = reader.next_event() {
        match event.map_err(|e| damaged(topics, mcap_error(e)))? {
            LinearReadEvent::ReadRequest(need) => {
                // Never more than the file still holds: the request is a record's stated
                // length, which is trusted up to the cap only.
                let n = (need as u64).min(len.saturating_sub(fed)) as usize;
                let read = loop {
                    match src.read(reader.insert(n)) {
                        Ok(k) => break k,
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                        Err(e) => return Err(IoError::io(file, e)),
                    }
                };
                fed += read as u64;
                reader.notify_read(read);
            }
            LinearReadEvent::Record {
                opcode: op::DATA_END,
                ..
            } => past_data_end = true,
            LinearReadEvent::Record { opcode, data } => {
                if !matches!(opcode, op::SCHEMA | op::CHANNEL | op::MESSAGE) {
                    continue;
                }
                check_mcap_record(opcode, data).map_err(|e| damaged(topics, e))?;
                let record =
                    mcap::parse_record(opcode, data).map_err(|e| damaged(topics, mcap_error(e)))?;
                match record {
                    // The summary section repeats schemas and channels: not checked again.
                    Record::Schema { .. } | Record::Channel(_) if past_data_end => {}
                    Record::Schema { header, data } => channels
                        .add_schema_from_slice(header, &data)
                        .map_err(|e| damaged(topics, mcap_error(e)))?,
                    Record::Channel(c) => channels
                        .add_channel(c)
                        .map_err(|e| damaged(topics, mcap_error(e)))?,
                    Record::Message { .. } if past_data_end => {
                        return Err(damaged(
                            topics,
                            "a message record after the data end record".to_string(),
                        ))
                    }
                    Record::Message { header, data } => {
                        let Some(ch) = channels.get(header.channel_id) else {
                            return Err(damaged(
                                topics,
                                mcap_error(mcap::McapError::UnknownChannel(
                                    header.sequence,
                                    header.channel_id,
                                )),
                            ));
                        };
                        let msg_type = ch
                            .schema
                            .as_ref()
                            .map_or_else(|| "(no schema)".to_string(), |s| normalise_type(&s.name));
                        let index = topics.add(
                            file,
                            &ch.topic,
                            &msg_type,
                            &ch.message_encoding,
                            header.log_time,
                        )?;
                        f(RawMessage {
                            topic: &ch.topic,
                            msg_type: &msg_type,
                            encoding: &ch.message_encoding,
                            index,
                            log_time_ns: header.log_time,
                            data: data.as_ref(),
                        })?;
                    }
                    _ => {}
                }
            }
        }
    }
    Ok(())
}

/// Checks the length-prefixed fields of an MCAP schema or channel record against the bytes
/// the record holds (MCAP specification, "Schema" and "Channel"): each string, the schema's
/// data and the channel's metadata map must end within the record. `Err` says which field
/// broke the bound.
fn check_mcap_record(opcode: u8, data: &[u8]) -> Result<(), String> {
    use mcap::records::op;
    let name = if opcode == op::SCHEMA {
        "schema"
    } else {
        "channel"
    };
    let mut pos = 0usize;
    // A `uint32` length at `pos`, then that many bytes, all within `end`.
    let field = |pos: &mut usize, end: usize, what: &str| -> Result<(), String> {
        let at = *pos;
        let Some(b) = data.get(at..at + 4).filter(|_| at + 4 <= end) else {
            return Err(format!(
                "a {name} record of {} byte(s) ends before the length of its {what}",
                data.len()
            ));
        };
        let n = u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize;
        let left = end - (at + 4);
        if n > left {
            return Err(format!(
                "a {name} record whose {what} is {n} byte(s) long at byte {at} of the record, \
                 expected at most the {left} byte(s) left"
            ));
        }
        *pos = at + 4 + n;
        Ok(())
    };
    match opcode {
        op::SCHEMA => {
            pos += 2; // id
            field(&mut pos, data.len(), "name")?;
            field(&mut pos, data.len(), "encoding")?;
            field(&mut pos, data.len(), "data")?;
        }
        op::CHANNEL => {
            pos += 4; // id, schema id
            if pos > data.len() {
                return Err(format!("a channel record of {} byte(s)", data.len()));
            }
            field(&mut pos, data.len(), "topic")?;
            field(&mut pos, data.len(), "message encoding")?;
            let map_at = pos;
            field(&mut pos, data.len(), "metadata map")?;
            let end = pos;
            let mut p = map_at + 4;
            while p < end {
                field(&mut p, end, "metadata key")?;
                field(&mut p, end, "metadata value")?;
            }
        }
        _ => {}
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
