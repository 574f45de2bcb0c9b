//! The two serialisations the bag reader decodes, behind one trait: ROS 2's CDR (`cdr.rs`)
//! and ROS 1's own (`Ros1` here), so each message is decoded by one function whatever
//! the bag it came from.
//!
//! ROS 1 serialisation (wiki.ros.org/msg, "Serialization"; roscpp's `serialization.h`):
//! every primitive little endian and packed (no alignment); a `string` is a `uint32` byte
//! count (no terminating NUL) then the bytes; a variable-length array is a `uint32`
//! element count then the elements, a fixed-size array has no count; `time` is `uint32`
//! seconds then `uint32` nanoseconds; `std_msgs/Header` starts with a `uint32 seq` that
//! ROS 2 dropped.

use crate::bounds::MAX_BEAMS;
use std::fmt;

/// Why a message did not decode: the byte offset in the message body where decoding stopped
/// (after CDR's 4-byte encapsulation header) and what was expected there.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodeError {
    /// Byte offset in the message body.
    pub offset: usize,
    /// What was expected, in words.
    pub what: String,
    /// The serialisation (`CDR`, `ROS 1`).
    pub wire: &'static str,
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "at byte {} of the {} body: {}",
            self.offset, self.wire, self.what
        )
    }
}

impl std::error::Error for DecodeError {}

/// The reads a message decoder needs. Every method names the field it reads (`what`) so
/// an error can say which field broke; every count is checked against the bytes left
/// before anything is allocated.
pub(crate) trait Wire {
    /// An error at the cursor.
    fn err(&self, what: String) -> DecodeError;
    /// Bytes left after the cursor.
    fn remaining(&self) -> usize;
    /// A `uint32`.
    fn u32(&mut self, what: &str) -> Result<u32, DecodeError>;
    /// An `int32`.
    fn i32(&mut self, what: &str) -> Result<i32, DecodeError>;
    /// A `float32`, widened to `f64` (exactly).
    fn f32(&mut self, what: &str) -> Result<f64, DecodeError>;
    /// A `float64`.
    fn f64(&mut self, what: &str) -> Result<f64, DecodeError>;
    /// A `string` (UTF-8).
    fn string(&mut self, what: &str) -> Result<String, DecodeError>;
    /// Skips a fixed-size `float64[n]` array.
    fn skip_f64s(&mut self, n: usize, what: &str) -> Result<(), DecodeError>;
    /// The stamp of a `std_msgs/Header` (and the `seq` before it in ROS 1) as nanoseconds
    /// since the epoch: ROS 2's `builtin_interfaces/Time` is `int32 sec, uint32 nanosec`,
    /// ROS 1's `time` is `uint32 secs, uint32 nsecs`.
    fn header_stamp(&mut self) -> Result<i64, DecodeError>;

    /// A sequence count whose elements take at least `min_size` bytes each: a count that
    /// cannot fit in the bytes left is an error before anything is allocated.
    fn count(&mut self, what: &str, min_size: usize) -> Result<usize, DecodeError> {
        let n = self.u32(&format!("the element count of {what}"))? as usize;
        let need = n.saturating_mul(min_size.max(1));
        if need > self.remaining() {
            return Err(self.err(format!(
                "{what}: {n} element(s) of at least {min_size} byte(s), only {} byte(s) left",
                self.remaining()
            )));
        }
        Ok(n)
    }

    /// A `float32[]` sequence of a laser scan's beams, widened to `f64`: at most
    /// [`MAX_BEAMS`] elements (the cap of every reader), checked before allocating.
    fn seq_f32(&mut self, what: &str) -> Result<Vec<f64>, DecodeError> {
        let n = self.count(what, 4)?;
        if n > MAX_BEAMS {
            return Err(self.err(format!(
                "{what}: {n} beams, expected at most {MAX_BEAMS} per scan"
            )));
        }
        let mut v = Vec::with_capacity(n);
        for _ in 0..n {
            v.push(self.f32(what)?);
        }
        Ok(v)
    }
}

/// A nanosecond count that must be below 10⁹.
pub(crate) fn nanos<W: Wire + ?Sized>(w: &W, nsec: u32) -> Result<i64, DecodeError> {
    if nsec >= 1_000_000_000 {
        return Err(w.err(format!("header.stamp nanoseconds < 10^9, found {nsec}")));
    }
    Ok(i64::from(nsec))
}

/// The `n` bytes of `body` at `*pos` (then `*pos` moves past them), or, when fewer are
/// left, what was expected.
pub(crate) fn take<'a>(
    body: &'a [u8],
    pos: &mut usize,
    n: usize,
    what: &str,
) -> Result<&'a [u8], String> {
    let left = body.len() - *pos;
    if n > left {
        return Err(format!("{what} ({n} byte(s)), only {left} left"));
    }
    let s = &body[*pos..*pos + n];
    *pos += n;
    Ok(s)
}

/// A cursor over one ROS 1-serialised message.
pub(crate) struct Ros1<'a> {
    body: &'a [u8],
    pos: usize,
}

impl<'a> Ros1<'a> {
    /// A cursor at the start of `data` (a ROS 1 message has no header of its own).
    pub fn new(data: &'a [u8]) -> Self {
        Ros1 { body: data, pos: 0 }
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], DecodeError> {
        take(self.body, &mut self.pos, n, what).map_err(|w| self.err(w + " (message truncated)"))
    }

    fn bytes<const N: usize>(&mut self, what: &str) -> Result<[u8; N], DecodeError> {
        let mut b = [0u8; N];
        b.copy_from_slice(self.take(N, what)?);
        Ok(b)
    }
}

impl Wire for Ros1<'_> {
    fn err(&self, what: String) -> DecodeError {
        DecodeError {
            offset: self.pos,
            what,
            wire: "ROS 1",
        }
    }

    fn remaining(&self) -> usize {
        self.body.len() - self.pos
    }

    fn u32(&mut self, what: &str) -> Result<u32, DecodeError> {
        Ok(u32::from_le_bytes(self.bytes(what)?))
    }

    fn i32(&mut self, what: &str) -> Result<i32, DecodeError> {
        Ok(i32::from_le_bytes(self.bytes(what)?))
    }

    fn f32(&mut self, what: &str) -> Result<f64, DecodeError> {
        Ok(f64::from(f32::from_le_bytes(self.bytes(what)?)))
    }

    fn f64(&mut self, what: &str) -> Result<f64, DecodeError> {
        Ok(f64::from_le_bytes(self.bytes(what)?))
    }

    fn string(&mut self, what: &str) -> Result<String, DecodeError> {
        let n = self.u32(&format!("the length of {what}"))? as usize;
        let start = self.pos;
        let s = self.take(n, what)?;
        String::from_utf8(s.to_vec()).map_err(|_| DecodeError {
            offset: start,
            what: format!("{what} in UTF-8"),
            wire: "ROS 1",
        })
    }

    fn skip_f64s(&mut self, n: usize, what: &str) -> Result<(), DecodeError> {
        self.take(8 * n, what).map(|_| ())
    }

    fn header_stamp(&mut self) -> Result<i64, DecodeError> {
        self.u32("header.seq")?;
        let sec = self.u32("header.stamp.secs")?;
        let nsec = self.u32("header.stamp.nsecs")?;
        Ok(i64::from(sec) * 1_000_000_000 + nanos(self, nsec)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ros1_is_packed_little_endian_with_counted_strings() {
        // Header {seq 7, stamp 3 s 5 ns, frame "ab"}, then float64 1.5 right after (no
        // padding), then float32[] [2.5].
        let mut m = Vec::new();
        m.extend(7u32.to_le_bytes());
        m.extend(3u32.to_le_bytes());
        m.extend(5u32.to_le_bytes());
        m.extend(2u32.to_le_bytes());
        m.extend(b"ab");
        m.extend(1.5f64.to_le_bytes());
        m.extend(1u32.to_le_bytes());
        m.extend(2.5f32.to_le_bytes());
        let mut c = Ros1::new(&m);
        assert_eq!(c.header_stamp().unwrap(), 3_000_000_005);
        assert_eq!(c.string("frame").unwrap(), "ab");
        assert_eq!(c.f64("x").unwrap(), 1.5);
        assert_eq!(c.seq_f32("r").unwrap(), vec![2.5]);
        assert_eq!(c.remaining(), 0);
    }

    #[test]
    fn ros1_hostile_counts_and_stamps_are_errors() {
        let mut m = u32::MAX.to_le_bytes().to_vec();
        m.extend([0; 8]);
        let e = Ros1::new(&m).seq_f32("ranges").unwrap_err();
        assert!(e.what.contains("4294967295 element(s)"), "{e}");
        let e = Ros1::new(&m).string("frame_id").unwrap_err();
        assert!(e.what.contains("truncated"), "{e}");
        let mut m = vec![0; 8];
        m.extend(1_000_000_000u32.to_le_bytes());
        let e = Ros1::new(&m).header_stamp().unwrap_err();
        assert!(
            e.to_string().contains("at byte 12 of the ROS 1 body"),
            "{e}"
        );
    }
}
