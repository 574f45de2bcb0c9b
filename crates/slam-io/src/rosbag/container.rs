//! The containers of ROS 2 bags: MCAP files (through the `mcap` crate) and rosbag2
//! folders (a `metadata.yaml` naming the storage files).

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
    /// The message encoding (`cdr` for ROS 2).
    pub encoding: String,
    /// Number of messages.
    pub count: usize,
    /// Earliest and latest log time (recording clock), nanoseconds since the epoch.
    pub log_time_ns: (u64, u64),
}

/// The files of a bag, in recording order.
pub(crate) fn bag_files(path: &Path) -> Result<Vec<PathBuf>, IoError> {
    if !path.is_dir() {
        return Ok(vec![path.to_path_buf()]);
    }
    let meta = path.join("metadata.yaml");
    let text = std::fs::read_to_string(&meta).map_err(|e| IoError::io(&meta, e))?;
    let mut storage = None;
    let mut files = Vec::new();
    let mut in_files = false;
    for line in text.lines() {
        let t = line.trim();
        if let Some(v) = t.strip_prefix("storage_identifier:") {
            storage = Some(v.trim().trim_matches(['"', '\'']).to_string());
        }
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
    match storage.as_deref() {
        Some("mcap") => {}
        Some(other) => {
            return Err(IoError::invalid(
                &meta,
                format!(
                    "storage_identifier {other:?} is not supported (expected mcap); \
                     `ros2 bag convert` can rewrite the bag as MCAP"
                ),
            ))
        }
        None => {
            return Err(IoError::invalid(
                &meta,
                "no storage_identifier: not a rosbag2 metadata.yaml",
            ))
        }
    }
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
    Ok(files)
}

/// `pkg/Type` → `pkg/msg/Type`; other names unchanged.
fn normalise_type(name: &str) -> String {
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

/// Reads every message of the bag at `path` (an MCAP file or a rosbag2 folder) in file
/// order and calls `f` on each; returns the topics seen. A truncated or corrupt file is an
/// error saying how many messages were read and the log time of the last one.
pub(crate) fn for_each_message(
    path: &Path,
    mut f: impl FnMut(&Path, RawMessage<'_>) -> Result<(), IoError>,
) -> Result<Vec<TopicInfo>, IoError> {
    let mut topics: BTreeMap<String, TopicInfo> = BTreeMap::new();
    for file in bag_files(path)? {
        let buf = std::fs::read(&file).map_err(|e| IoError::io(&file, e))?;
        if !buf.starts_with(mcap::MAGIC) {
            return Err(IoError::invalid(
                &file,
                "not an MCAP file (it does not start with the MCAP magic bytes)",
            ));
        }
        let stream =
            mcap::MessageStream::new(&buf).map_err(|e| IoError::invalid(&file, e.to_string()))?;
        let mut last_time = None;
        for (read, m) in stream.enumerate() {
            let m = m.map_err(|e| {
                IoError::invalid(
                    &file,
                    format!(
                        "truncated or corrupt MCAP ({e}): {read} message(s) read before the damage \
                         in this {}-byte file{}",
                        buf.len(),
                        match last_time {
                            Some(t) => format!(", the last logged at {} s", t as f64 * 1e-9),
                            None => String::new(),
                        }
                    ),
                )
            })?;
            last_time = Some(m.log_time);
            let ch = &m.channel;
            let msg_type = ch
                .schema
                .as_ref()
                .map_or_else(|| "(no schema)".to_string(), |s| normalise_type(&s.name));
            let info = topics.entry(ch.topic.clone()).or_insert_with(|| TopicInfo {
                topic: ch.topic.clone(),
                msg_type: msg_type.clone(),
                encoding: ch.message_encoding.clone(),
                count: 0,
                log_time_ns: (m.log_time, m.log_time),
            });
            if info.msg_type != msg_type {
                return Err(IoError::Bag {
                    path: file.clone(),
                    topic: ch.topic.clone(),
                    what: format!(
                        "the topic carries two message types, {} and {msg_type}",
                        info.msg_type
                    ),
                });
            }
            let index = info.count;
            info.count += 1;
            info.log_time_ns.0 = info.log_time_ns.0.min(m.log_time);
            info.log_time_ns.1 = info.log_time_ns.1.max(m.log_time);
            f(
                &file,
                RawMessage {
                    topic: &ch.topic,
                    msg_type: &msg_type,
                    encoding: &ch.message_encoding,
                    index,
                    log_time_ns: m.log_time,
                    data: &m.data,
                },
            )?;
        }
    }
    Ok(topics.into_values().collect())
}
