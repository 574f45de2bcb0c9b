//! ROS 1 bags, format 2.0 (wiki.ros.org/Bags/Format/2.0), read from the start of the file
//! to its end without the index, so a bag whose recording was cut short (no index yet)
//! reads as far as it was written.
//!
//! The file is the line `#ROSBAG V2.0\n` and then records, each a `uint32` header length,
//! the header (fields, each a `uint32` length then `name=value`), a `uint32` data length and
//! the data; all integers little endian. The header's `op` field says what the record is:
//!
//! | op | record | read |
//! | --- | --- | --- |
//! | 0x03 | bag header: `index_pos`, `conn_count`, `chunk_count` | checked at the end |
//! | 0x05 | chunk: `compression` (`none`, `bz2`, `lz4`), `size` (uncompressed) | its records |
//! | 0x07 | connection: `conn`, `topic`; data: `type`, `md5sum`, … | topic and type |
//! | 0x02 | message data: `conn`, `time` (`uint32` s, `uint32` ns) | the message |
//! | 0x04, 0x06 | index data, chunk info | counted |
//!
//! The file is streamed record by record (never held whole); a length field is trusted only
//! up to the bytes the file still holds and [`crate::bounds::MAX_RECORD_BYTES`]. An index
//! data record (0x04, version 1) is read by its entry `count` (12 bytes each), not by its
//! data length, as the official reader (`rosbag`'s `bag.py`) does: the ROS 1.1 C++ writer
//! (April to July 2010, until ros/ros commit 76cb7556) wrote that length as
//! `count * sizeof(IndexEntry)`, 24 bytes an entry on x86-64, beside 12-byte entries
//! (fixture `rosbag1-index-2010.bag`).
//!
//! A connection's `md5sum` is checked against the definitions we decode
//! (`msgs::ros1_md5`): another definition under a known name is refused when its topic is
//! used. An indexed bag (`index_pos` ≠ 0) must hold the chunks and chunk-info records its
//! header counts, so a file cut anywhere, even between records, is an error.

use super::container::{normalise_type, BagFormat, Each, RawMessage, Topics};
use super::msgs::ros1_md5;
use crate::bounds::MAX_RECORD_BYTES;
use crate::error::IoError;
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::Path;

const MAGIC: &[u8] = b"#ROSBAG V2.0\n";
/// The largest record and the largest chunk after decompression, bytes (rosbag's default
/// chunk is 768 KiB): the bound on what a hostile length or `size` field can make us
/// allocate ([`crate::bounds::MAX_RECORD_BYTES`]).
const MAX_CHUNK: usize = MAX_RECORD_BYTES;
/// Bytes of one index entry (format 2.0 index data, version 1): `time` (8) and `offset` (4).
const INDEX_ENTRY: u64 = 12;

const OP_MSG_DATA: u8 = 0x02;
const OP_BAG_HEADER: u8 = 0x03;
const OP_INDEX_DATA: u8 = 0x04;
const OP_CHUNK: u8 = 0x05;
const OP_CHUNK_INFO: u8 = 0x06;
const OP_CONNECTION: u8 = 0x07;

/// A header field: its name and value.
type Field<'a> = (&'a [u8], &'a [u8]);

/// One record: where it starts, its header fields and its data.
struct Record<'a> {
    at: usize,
    fields: Vec<Field<'a>>,
    data: &'a [u8],
}

impl<'a> Record<'a> {
    fn field(&self, name: &str) -> Result<&'a [u8], String> {
        self.fields
            .iter()
            .find(|(n, _)| *n == name.as_bytes())
            .map(|(_, v)| *v)
            .ok_or_else(|| format!("record at byte {}: no `{name}` field", self.at))
    }

    fn int<const N: usize>(&self, name: &str) -> Result<[u8; N], String> {
        let v = self.field(name)?;
        v.try_into().map_err(|_| {
            format!(
                "record at byte {}: field `{name}` of {} byte(s), expected {N}",
                self.at,
                v.len()
            )
        })
    }

    fn u32(&self, name: &str) -> Result<u32, String> {
        self.int::<4>(name).map(u32::from_le_bytes)
    }

    fn u64(&self, name: &str) -> Result<u64, String> {
        self.int::<8>(name).map(u64::from_le_bytes)
    }

    fn op(&self) -> Result<u8, String> {
        self.int::<1>("op").map(|b| b[0])
    }
}

/// `n` bytes of `buf` at `*pos`, or an error naming the byte.
fn take<'a>(buf: &'a [u8], pos: &mut usize, n: usize, what: &str) -> Result<&'a [u8], String> {
    let at = *pos;
    super::wire::take(buf, pos, n, what).map_err(|e| format!("at byte {at}: {e}"))
}

fn len(buf: &[u8], pos: &mut usize, what: &str) -> Result<usize, String> {
    let b = take(buf, pos, 4, what)?;
    Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
}

/// The record at `*pos` of `buf` (a chunk's decompressed records).
fn record<'a>(buf: &'a [u8], pos: &mut usize) -> Result<Record<'a>, String> {
    let at = *pos;
    let n = len(buf, pos, "a record's header length")?;
    let header = take(buf, pos, n, "a record header")?;
    let fields = record_fields(header, &mut 0).map_err(|e| format!("record at byte {at}: {e}"))?;
    let n = len(buf, pos, "a record's data length")?;
    let data = take(buf, pos, n, "a record's data")?;
    Ok(Record { at, fields, data })
}

/// The bag file, read record by record.
struct Source {
    r: std::io::BufReader<std::fs::File>,
    /// The byte the next read starts at.
    pos: u64,
    /// The file's length, bytes.
    len: u64,
}

impl Source {
    /// The next `n` bytes into `out`: `n` is trusted up to the bytes left in the file and
    /// [`MAX_RECORD_BYTES`], checked before anything is allocated.
    fn bytes(&mut self, out: &mut Vec<u8>, n: u64, what: &str) -> Result<(), String> {
        use std::io::Read as _;
        let left = self.len - self.pos;
        if n > left {
            return Err(format!(
                "at byte {}: {what} of {n} byte(s), only {left} byte(s) left in the file",
                self.pos
            ));
        }
        if n > MAX_RECORD_BYTES as u64 {
            return Err(format!(
                "at byte {}: {what} of {n} bytes, more than the {MAX_RECORD_BYTES} read",
                self.pos
            ));
        }
        out.clear();
        out.resize(n as usize, 0);
        self.r
            .read_exact(out)
            .map_err(|e| format!("at byte {}: {what}: {e}", self.pos))?;
        self.pos += n;
        Ok(())
    }

    /// A `uint32` length field.
    fn len_field(&mut self, what: &str) -> Result<u64, String> {
        let mut b = Vec::new();
        self.bytes(&mut b, 4, what)?;
        Ok(u64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])))
    }

    /// The record at the reading position: its header into `header`, its data into `data`.
    /// An index data record's data is its entry count's worth of bytes (module doc).
    fn record<'b>(
        &mut self,
        header: &'b mut Vec<u8>,
        data: &'b mut Vec<u8>,
    ) -> Result<Record<'b>, String> {
        let at = self.pos as usize;
        let n = self.len_field("a record's header length")?;
        self.bytes(header, n, "a record header")?;
        let header: &'b Vec<u8> = header;
        let fields =
            record_fields(header, &mut 0).map_err(|e| format!("record at byte {at}: {e}"))?;
        let r = Record {
            at,
            fields,
            data: &[],
        };
        let stated = self.len_field("a record's data length")?;
        let n = match (r.op(), r.u32("ver"), r.u32("count")) {
            (Ok(OP_INDEX_DATA), Ok(1), Ok(count)) => u64::from(count) * INDEX_ENTRY,
            _ => stated,
        };
        self.bytes(data, n, "a record's data")?;
        let data: &'b Vec<u8> = data;
        Ok(Record { data, ..r })
    }
}

/// A chunk's records, decompressed.
fn decompress<'a>(r: &Record<'a>) -> Result<Cow<'a, [u8]>, String> {
    use std::io::Read as _;
    let size = r.u32("size")? as usize;
    if size > MAX_CHUNK {
        return Err(format!(
            "chunk at byte {}: {size} bytes uncompressed, more than the {MAX_CHUNK} read",
            r.at
        ));
    }
    let compression = r.field("compression")?;
    let read = |src: &mut dyn std::io::Read| -> Result<Vec<u8>, String> {
        let mut out = Vec::new();
        src.take(size as u64 + 1)
            .read_to_end(&mut out)
            .map_err(|e| format!("chunk at byte {}: {e}", r.at))?;
        Ok(out)
    };
    let out: Cow<'a, [u8]> = match compression {
        b"none" => Cow::Borrowed(r.data),
        b"bz2" => Cow::Owned(read(&mut bzip2::read::BzDecoder::new(r.data))?),
        b"lz4" => Cow::Owned(read(
            &mut lz4::Decoder::new(r.data).map_err(|e| format!("chunk at byte {}: {e}", r.at))?,
        )?),
        other => {
            return Err(format!(
                "chunk at byte {}: compression {:?}, expected none, bz2 or lz4",
                r.at,
                String::from_utf8_lossy(other)
            ))
        }
    };
    if out.len() != size {
        return Err(format!(
            "chunk at byte {}: {} byte(s) after decompression, the header says {size}",
            r.at,
            out.len()
        ));
    }
    Ok(out)
}

/// A connection: topic, normalised type, encoding (`ros1`, or the md5sum that differs).
struct Connection {
    topic: String,
    msg_type: String,
    encoding: String,
}

fn connection(r: &Record<'_>) -> Result<(u32, Connection), String> {
    let id = r.u32("conn")?;
    let topic = String::from_utf8_lossy(r.field("topic")?).into_owned();
    // The data is a header of its own: type, md5sum, message_definition, callerid, …
    let mut hp = 0;
    let inner =
        record_fields(r.data, &mut hp).map_err(|e| format!("connection at byte {}: {e}", r.at))?;
    let get = |name: &str| {
        inner
            .iter()
            .find(|(n, _)| *n == name.as_bytes())
            .map(|(_, v)| String::from_utf8_lossy(v).into_owned())
            .ok_or_else(|| {
                format!(
                    "connection {id} ({topic}) at byte {}: no `{name}` field",
                    r.at
                )
            })
    };
    let msg_type = normalise_type(&get("type")?);
    let md5 = get("md5sum")?;
    let encoding = match ros1_md5(&msg_type) {
        Some(known) if md5 != known && md5 != "*" => format!("ros1 md5sum {md5}"),
        _ => "ros1".to_string(),
    };
    Ok((
        id,
        Connection {
            topic,
            msg_type,
            encoding,
        },
    ))
}

/// The `name=value` fields that fill `buf` (a connection record's data).
fn record_fields<'a>(buf: &'a [u8], pos: &mut usize) -> Result<Vec<Field<'a>>, String> {
    let mut out = Vec::new();
    while *pos < buf.len() {
        let n = len(buf, pos, "a field's length")?;
        let f = take(buf, pos, n, "a field")?;
        let eq = f
            .iter()
            .position(|&b| b == b'=')
            .ok_or("a field without `=`")?;
        out.push((&f[..eq], &f[eq + 1..]));
    }
    Ok(out)
}

/// Why reading stopped: damage in the file (reported with how far reading got) or an error
/// of the message's consumer (passed on as it is).
enum Stop {
    Damaged(String),
    Consumer(IoError),
}

impl From<String> for Stop {
    fn from(s: String) -> Self {
        Stop::Damaged(s)
    }
}

/// The reading state of one bag.
struct Reader<'f, 'g> {
    file: &'f Path,
    conns: BTreeMap<u32, Connection>,
    f: &'f mut Each<'g>,
}

impl Reader<'_, '_> {
    /// A connection or message record (top level or inside a chunk).
    fn record(&mut self, topics: &mut Topics, r: &Record<'_>) -> Result<(), Stop> {
        match r.op()? {
            OP_CONNECTION => {
                let (id, c) = connection(r)?;
                self.conns.entry(id).or_insert(c);
            }
            OP_MSG_DATA => {
                let id = r.u32("conn")?;
                let t = r.int::<8>("time")?;
                let sec = u32::from_le_bytes([t[0], t[1], t[2], t[3]]);
                let nsec = u32::from_le_bytes([t[4], t[5], t[6], t[7]]);
                let t = u64::from(sec) * 1_000_000_000 + u64::from(nsec);
                let c = self.conns.get(&id).ok_or_else(|| {
                    format!(
                        "message at byte {} on connection {id}, which no connection record \
                         before it defines",
                        r.at
                    )
                })?;
                let index = topics
                    .add(self.file, &c.topic, &c.msg_type, &c.encoding, t)
                    .map_err(Stop::Consumer)?;
                (self.f)(RawMessage {
                    topic: &c.topic,
                    msg_type: &c.msg_type,
                    encoding: &c.encoding,
                    index,
                    log_time_ns: t,
                    data: r.data,
                })
                .map_err(Stop::Consumer)?;
            }
            op => {
                return Err(Stop::Damaged(format!(
                    "record at byte {}: op {op:#04x} where a connection or message was expected",
                    r.at
                )))
            }
        }
        Ok(())
    }

    fn all(&mut self, topics: &mut Topics, src: &mut Source) -> Result<(), Stop> {
        let mut header: Option<(u64, u32, u32)> = None;
        let (mut chunks, mut chunk_infos) = (0u64, 0u64);
        let (mut hbuf, mut dbuf) = (Vec::new(), Vec::new());
        while src.pos < src.len {
            let r = src.record(&mut hbuf, &mut dbuf)?;
            let op = r.op()?;
            if header.is_none() && op != OP_BAG_HEADER {
                return Err(Stop::Damaged(format!(
                    "the first record (byte {}) is op {op:#04x}, expected the bag header (0x03)",
                    r.at
                )));
            }
            match op {
                OP_BAG_HEADER if header.is_none() => {
                    header = Some((
                        r.u64("index_pos")?,
                        r.u32("conn_count")?,
                        r.u32("chunk_count")?,
                    ));
                }
                OP_CHUNK => {
                    chunks += 1;
                    let data = decompress(&r)?;
                    let mut p = 0;
                    while p < data.len() {
                        let inside = |e: String| format!("inside the chunk at byte {}: {e}", r.at);
                        let inner = record(&data, &mut p).map_err(inside)?;
                        self.record(topics, &inner).map_err(|e| match e {
                            Stop::Damaged(s) => Stop::Damaged(inside(s)),
                            other => other,
                        })?;
                    }
                }
                OP_INDEX_DATA => {}
                OP_CHUNK_INFO => chunk_infos += 1,
                _ => self.record(topics, &r)?,
            }
        }
        let Some((index_pos, _, chunk_count)) = header else {
            return Err(Stop::Damaged("no bag header record".into()));
        };
        if index_pos != 0 {
            if index_pos > src.len {
                return Err(Stop::Damaged(format!(
                    "the bag header puts the index at byte {index_pos}, the file ends at byte {}",
                    src.len
                )));
            }
            let want = u64::from(chunk_count);
            if chunks != want || chunk_infos != want {
                return Err(Stop::Damaged(format!(
                    "the bag header counts {want} chunk(s), the file holds {chunks} chunk(s) \
                     and {chunk_infos} chunk-info record(s)"
                )));
            }
        }
        Ok(())
    }
}

/// The messages of one ROS 1 bag, in file order, the file streamed record by record.
pub(crate) fn messages(file: &Path, topics: &mut Topics, f: &mut Each<'_>) -> Result<(), IoError> {
    use std::io::Read as _;
    let io = |e| IoError::io(file, e);
    let fd = std::fs::File::open(file).map_err(io)?;
    let len = fd.metadata().map_err(io)?.len();
    let mut r = std::io::BufReader::new(fd);
    let mut head = Vec::with_capacity(MAGIC.len());
    (&mut r)
        .take(MAGIC.len() as u64)
        .read_to_end(&mut head)
        .map_err(io)?;
    if head != MAGIC {
        // The first line, for the message (at most 32 bytes of it).
        (&mut r).take(19).read_to_end(&mut head).map_err(io)?;
        let line = String::from_utf8_lossy(&head)
            .lines()
            .next()
            .unwrap_or_default()
            .to_string();
        let version = line
            .strip_prefix("#ROSBAG V")
            .or_else(|| line.strip_prefix("#ROSRECORD V"))
            .map_or_else(String::new, |v| format!(" (format {v})"));
        return Err(IoError::invalid(
            file,
            format!(
                "{line:?}{version}: only ROS 1 bag format 2.0 (#ROSBAG V2.0) is read; \
                 `rosbag fix` rewrites older bags as format 2.0"
            ),
        ));
    }
    let mut src = Source {
        r,
        pos: MAGIC.len() as u64,
        len,
    };
    let mut reader = Reader {
        file,
        conns: BTreeMap::new(),
        f,
    };
    match reader.all(topics, &mut src) {
        Ok(()) => Ok(()),
        Err(Stop::Consumer(e)) => Err(e),
        Err(Stop::Damaged(why)) => Err(topics.damaged(file, BagFormat::Ros1, why)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::rosbag::ros1_record as rec;

    /// An unindexed bag holding `records` after its header.
    fn bag(records: &[Vec<u8>]) -> Vec<u8> {
        let mut b = MAGIC.to_vec();
        b.extend(rec(
            &[
                ("op", &[OP_BAG_HEADER]),
                ("index_pos", &0u64.to_le_bytes()),
                ("conn_count", &0u32.to_le_bytes()),
                ("chunk_count", &0u32.to_le_bytes()),
            ],
            &[],
        ));
        for r in records {
            b.extend(r);
        }
        b
    }

    /// A message as read: topic, encoding, log time, data.
    type Read = (String, String, u64, Vec<u8>);

    /// The messages of `bytes`, or the error.
    fn read(bytes: &[u8]) -> Result<Vec<Read>, String> {
        // One file per call: the tests of this module run in parallel.
        static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let k = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let p = std::env::temp_dir().join(format!("slam-io-ros1-{}-{k}.bag", std::process::id()));
        std::fs::write(&p, bytes).unwrap();
        let mut out = Vec::new();
        let mut topics = Topics::new();
        let mut f = |m: RawMessage<'_>| {
            out.push((
                m.topic.to_string(),
                m.encoding.to_string(),
                m.log_time_ns,
                m.data.to_vec(),
            ));
            Ok(())
        };
        let r = messages(&p, &mut topics, &mut f).map_err(|e| e.to_string());
        let _ = std::fs::remove_file(&p);
        r.map(|()| out)
    }

    fn conn(id: u32, topic: &str, ty: &str, md5: &str) -> Vec<u8> {
        let data = rec(&[("type", ty.as_bytes()), ("md5sum", md5.as_bytes())], &[]);
        // A connection's data is its fields alone (no data-length field of their own).
        let fields = &data[4..data.len() - 4];
        rec(
            &[
                ("op", &[OP_CONNECTION]),
                ("conn", &id.to_le_bytes()),
                ("topic", topic.as_bytes()),
            ],
            fields,
        )
    }

    fn msg(id: u32, sec: u32, nsec: u32, data: &[u8]) -> Vec<u8> {
        let mut t = sec.to_le_bytes().to_vec();
        t.extend(nsec.to_le_bytes());
        rec(
            &[
                ("op", &[OP_MSG_DATA]),
                ("conn", &id.to_le_bytes()),
                ("time", &t),
            ],
            data,
        )
    }

    fn chunk(compression: &str, size: u32, data: &[u8]) -> Vec<u8> {
        rec(
            &[
                ("op", &[OP_CHUNK]),
                ("compression", compression.as_bytes()),
                ("size", &size.to_le_bytes()),
            ],
            data,
        )
    }

    #[test]
    fn messages_in_and_out_of_chunks_with_their_connections() {
        let md5 = "90c7ef2dc6895d81024acba2ac42f369";
        let mut inner = conn(3, "/scan", "sensor_msgs/LaserScan", md5);
        inner.extend(msg(3, 7, 5, b"abc"));
        let b = bag(&[
            chunk("none", inner.len() as u32, &inner),
            conn(4, "/x", "sensor_msgs/LaserScan", "0123"),
            msg(4, 1, 0, b"z"),
        ]);
        let m = read(&b).unwrap();
        assert_eq!(
            m,
            vec![
                (
                    "/scan".into(),
                    "ros1".into(),
                    7_000_000_005,
                    b"abc".to_vec()
                ),
                (
                    "/x".into(),
                    "ros1 md5sum 0123".into(),
                    1_000_000_000,
                    b"z".to_vec()
                ),
            ]
        );
        // A message before its connection.
        let e = read(&bag(&[msg(9, 1, 0, b"z")])).unwrap_err();
        assert!(
            e.contains("connection 9, which no connection record"),
            "{e}"
        );
    }

    #[test]
    fn hostile_chunks_are_errors_before_any_allocation() {
        let e = read(&bag(&[chunk("zip", 3, b"abc")])).unwrap_err();
        assert!(
            e.contains("compression \"zip\", expected none, bz2 or lz4"),
            "{e}"
        );
        let e = read(&bag(&[chunk("bz2", u32::MAX, b"abc")])).unwrap_err();
        assert!(
            e.contains("4294967295 bytes uncompressed, more than the"),
            "{e}"
        );
        let e = read(&bag(&[chunk("none", 4, b"abc")])).unwrap_err();
        assert!(
            e.contains("3 byte(s) after decompression, the header says 4"),
            "{e}"
        );
        let e = read(&bag(&[chunk("lz4", 3, b"abc")])).unwrap_err();
        assert!(
            e.contains("truncated or corrupt ROS 1 bag (chunk at byte"),
            "{e}"
        );
        let e = read(b"#ROSBAG V1.2\n").unwrap_err();
        assert!(e.contains("only ROS 1 bag format 2.0"), "{e}");
    }

    /// An index data record (version 1) of `count` entries after a message on `conn`,
    /// with the data length field `stated` (the 2010 writers' may disagree with the count).
    fn index(conn: u32, count: u32, stated: u32) -> Vec<u8> {
        let mut r = rec(
            &[
                ("op", &[OP_INDEX_DATA]),
                ("ver", &1u32.to_le_bytes()),
                ("conn", &conn.to_le_bytes()),
                ("count", &count.to_le_bytes()),
            ],
            &[],
        );
        r.truncate(r.len() - 4);
        r.extend(stated.to_le_bytes());
        for k in 0..count {
            r.extend(k.to_le_bytes());
            r.extend(0u32.to_le_bytes());
            r.extend(13u32.to_le_bytes());
        }
        r
    }

    #[test]
    fn index_records_are_read_by_their_entry_count_as_rosbag_does() {
        let md5 = "90c7ef2dc6895d81024acba2ac42f369";
        let before = [
            conn(1, "/scan", "sensor_msgs/LaserScan", md5),
            msg(1, 7, 0, b"abc"),
        ];
        // Length fields of 0, of one entry too few and of one too many, each followed by a
        // further message that must still be read (the count decides where the record ends).
        for stated in [0, 12, 36] {
            let mut records = before.to_vec();
            records.push(index(1, 2, stated));
            records.push(msg(1, 8, 0, b"de"));
            let m = read(&bag(&records)).unwrap();
            assert_eq!(m.len(), 2, "stated {stated}");
            assert_eq!(m[1].3, b"de".to_vec());
        }
        // A count beyond the file is damage, not an allocation.
        let mut records = before.to_vec();
        records.push(index(1, 2, 24)[..40].to_vec());
        let mut b = bag(&records);
        let n = b.len();
        b[n - 4..].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = read(&b).unwrap_err();
        assert!(e.contains("truncated or corrupt ROS 1 bag"), "{e}");
    }

    #[test]
    fn old_formats_are_refused_by_their_version() {
        let e = read(b"#ROSRECORD V1.2\nrest").unwrap_err();
        assert!(
            e.contains("\"#ROSRECORD V1.2\" (format 1.2): only ROS 1 bag format 2.0"),
            "{e}"
        );
        let e = read(b"#ROSBAG V1.3\n").unwrap_err();
        assert!(e.contains("(format 1.3)"), "{e}");
    }

    #[test]
    fn lengths_beyond_the_file_or_the_cap_are_errors_before_allocating() {
        // A message whose data length claims 4 GiB in a file of a few dozen bytes.
        let mut m = msg(1, 7, 0, b"abc");
        let n = m.len();
        m[n - 7..n - 3].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = read(&bag(&[conn(1, "/x", "std_msgs/String", "*"), m])).unwrap_err();
        assert!(
            e.contains("a record's data of 4294967295 byte(s), only 3 byte(s) left in the file"),
            "{e}"
        );
        // A header length beyond the file.
        let mut b = bag(&[]);
        b.extend(u32::MAX.to_le_bytes());
        let e = read(&b).unwrap_err();
        assert!(e.contains("a record header of 4294967295 byte(s)"), "{e}");
    }
}
