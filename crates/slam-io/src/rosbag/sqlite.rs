//! rosbag2's sqlite3 storage (`.db3`): a `topics` table (`id`, `name`, `type`,
//! `serialization_format`) and a `messages` table (`topic_id`, `timestamp` in nanoseconds,
//! `data` the serialised message), read through SQLite itself (rusqlite, SQLite compiled
//! in). The file is opened read-only; messages are read in insertion order.
//!
//! A truncated file is found before SQLite reads it: the database header (SQLite's file
//! format, §1.3) gives the page size (offset 16) and the page count (offset 28), and the file
//! must hold that many pages. Damage SQLite itself finds while reading is reported with the
//! messages read up to it.

use super::container::{normalise_type, BagFormat, Each, RawMessage, Topics};
use crate::error::IoError;
use rusqlite::{Connection, OpenFlags};
use std::collections::BTreeMap;
use std::path::Path;

/// The page count and page size the header promises, checked against the file's length.
fn check_length(file: &Path, topics: &Topics) -> Result<(), IoError> {
    use std::io::Read as _;
    let damaged = |why: String| topics.damaged(file, BagFormat::Sqlite3, why);
    let len = std::fs::metadata(file)
        .map_err(|e| IoError::io(file, e))?
        .len() as usize;
    let mut bytes = [0u8; 100];
    if len < 100 {
        return Err(damaged(format!(
            "a 100-byte SQLite header, found {len} byte(s)"
        )));
    }
    std::fs::File::open(file)
        .and_then(|mut h| h.read_exact(&mut bytes))
        .map_err(|e| IoError::io(file, e))?;
    // Page size: big-endian u16 at 16, where 1 means 65536.
    let page = match u16::from_be_bytes([bytes[16], bytes[17]]) {
        1 => 65536,
        p => usize::from(p),
    };
    let pages = u32::from_be_bytes([bytes[28], bytes[29], bytes[30], bytes[31]]) as usize;
    // The page count is valid when the change counter (24) matches version-valid-for (92).
    let valid = bytes[24..28] == bytes[92..96] && pages > 0;
    if !page.is_power_of_two() || page < 512 {
        return Err(damaged(format!("page size {page} in the header")));
    }
    if valid && len < pages.saturating_mul(page) {
        return Err(damaged(format!(
            "the header counts {pages} page(s) of {page} bytes, the file holds {len} byte(s)"
        )));
    }
    if len % page != 0 {
        return Err(damaged(format!(
            "{len} byte(s), not a whole number of {page}-byte pages"
        )));
    }
    Ok(())
}

/// The messages of one sqlite3 storage file, in insertion order.
pub(crate) fn messages(file: &Path, topics: &mut Topics, f: &mut Each<'_>) -> Result<(), IoError> {
    check_length(file, topics)?;
    let flags = OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX;
    let db = Connection::open_with_flags(file, flags)
        .map_err(|e| IoError::invalid(file, e.to_string()))?;
    let sql_err = |topics: &Topics, e: rusqlite::Error| topics.damaged(file, BagFormat::Sqlite3, e);
    let tables: i64 = db
        .query_row(
            "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name IN ('topics', 'messages')",
            [],
            |r| r.get(0),
        )
        .map_err(|e| sql_err(topics, e))?;
    if tables != 2 {
        return Err(IoError::invalid(
            file,
            "an SQLite database without rosbag2's `topics` and `messages` tables: not a ROS 2 bag",
        ));
    }
    // id → (name, type, serialization format)
    let mut by_id: BTreeMap<i64, (String, String, String)> = BTreeMap::new();
    {
        let mut st = db
            .prepare("SELECT id, name, type, serialization_format FROM topics")
            .map_err(|e| sql_err(topics, e))?;
        let mut rows = st.query([]).map_err(|e| sql_err(topics, e))?;
        while let Some(r) = rows.next().map_err(|e| sql_err(topics, e))? {
            let get = |k| r.get::<_, String>(k);
            let (id, name, ty, enc) = (
                r.get::<_, i64>(0).map_err(|e| sql_err(topics, e))?,
                get(1).map_err(|e| sql_err(topics, e))?,
                get(2).map_err(|e| sql_err(topics, e))?,
                get(3).map_err(|e| sql_err(topics, e))?,
            );
            by_id.insert(id, (name, normalise_type(&ty), enc));
        }
    }
    let mut st = db
        .prepare("SELECT topic_id, timestamp, data FROM messages ORDER BY id")
        .map_err(|e| sql_err(topics, e))?;
    let mut rows = st.query([]).map_err(|e| sql_err(topics, e))?;
    while let Some(r) = rows.next().map_err(|e| sql_err(topics, e))? {
        let id: i64 = r.get(0).map_err(|e| sql_err(topics, e))?;
        let t: i64 = r.get(1).map_err(|e| sql_err(topics, e))?;
        let data = r
            .get_ref(2)
            .and_then(|v| v.as_blob().map_err(Into::into))
            .map_err(|e| sql_err(topics, e))?;
        let Some((name, ty, enc)) = by_id.get(&id) else {
            return Err(topics.damaged(
                file,
                BagFormat::Sqlite3,
                format!("a message of topic_id {id}, which the topics table does not list"),
            ));
        };
        let Ok(t) = u64::try_from(t) else {
            return Err(IoError::Bag {
                path: file.to_path_buf(),
                topic: name.clone(),
                what: format!("a message timestamp of {t} ns, expected one ≥ 0"),
            });
        };
        let index = topics.add(file, name, ty, enc, t)?;
        f(RawMessage {
            topic: name,
            msg_type: ty,
            encoding: enc,
            index,
            log_time_ns: t,
            data,
        })?;
    }
    Ok(())
}
