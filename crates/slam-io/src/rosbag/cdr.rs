//! A small decoder of OMG CDR (XCDR version 1), the serialisation of ROS 2 messages.
//!
//! A ROS 2 message is a 4-byte encapsulation header followed by the CDR body (DDS-XTypes
//! 1.3 §7.4.3.4 and the CORBA 3.0 CDR rules, §15.3.1):
//!
//! * header bytes 0–1: the representation identifier, `00 00` = CDR big endian, `00 01` =
//!   CDR little endian; bytes 2–3 are options and are ignored. Any other identifier
//!   (parameter lists, XCDR2) is refused with an error naming it;
//! * a primitive of size n (1, 2, 4 or 8 bytes) starts at an offset of the body that is a
//!   multiple of n (the padding bytes before it are skipped);
//! * a string is a `uint32` length that counts the terminating NUL, then the bytes and NUL;
//! * a sequence is a `uint32` element count, then the elements; a fixed-size array has no
//!   count.
//!
//! Every length is checked against the bytes that remain before anything is allocated, so
//! a hostile count costs nothing.

use super::wire::{nanos, take, DecodeError, Wire};

/// A cursor over one CDR-encoded message.
pub(crate) struct Cdr<'a> {
    body: &'a [u8],
    pos: usize,
    little: bool,
}

impl<'a> Cdr<'a> {
    /// Reads the encapsulation header of `data` and positions the cursor at the body.
    pub fn new(data: &'a [u8]) -> Result<Self, DecodeError> {
        if data.len() < 4 {
            return Err(DecodeError {
                offset: 0,
                wire: "CDR",
                what: format!(
                    "a 4-byte CDR encapsulation header, found a message of {} byte(s)",
                    data.len()
                ),
            });
        }
        let little = match (data[0], data[1]) {
            (0, 0) => false,
            (0, 1) => true,
            (a, b) => {
                return Err(DecodeError {
                    offset: 0,
                    wire: "CDR",
                    what: format!(
                        "encapsulation CDR_BE (00 00) or CDR_LE (00 01), found {a:02x} {b:02x} \
                         (parameter-list and XCDR2 encodings are not supported)"
                    ),
                })
            }
        };
        Ok(Cdr {
            body: &data[4..],
            pos: 0,
            little,
        })
    }

    /// Skips the padding before a primitive of size `n`.
    fn align(&mut self, n: usize) -> Result<(), DecodeError> {
        let pad = (n - self.pos % n) % n;
        if pad > self.remaining() {
            return Err(self.err(format!(
                "{pad} padding byte(s), only {} left (message truncated)",
                self.remaining()
            )));
        }
        self.pos += pad;
        Ok(())
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], DecodeError> {
        take(self.body, &mut self.pos, n, what).map_err(|w| self.err(w + " (message truncated)"))
    }

    fn bytes<const N: usize>(&mut self, what: &str) -> Result<[u8; N], DecodeError> {
        self.align(N)?;
        let s = self.take(N, what)?;
        let mut b = [0u8; N];
        b.copy_from_slice(s);
        if self.little {
            b.reverse();
        }
        // `b` is now big endian.
        Ok(b)
    }

    /// A `uint8` (`int8` and `bool` are read as their byte); used by the run writer's tests.
    #[cfg(test)]
    pub fn u8(&mut self, what: &str) -> Result<u8, DecodeError> {
        Ok(self.take(1, what)?[0])
    }
}

impl Wire for Cdr<'_> {
    fn err(&self, what: String) -> DecodeError {
        DecodeError {
            offset: self.pos,
            what,
            wire: "CDR",
        }
    }

    fn remaining(&self) -> usize {
        self.body.len() - self.pos
    }

    /// A `uint32`.
    fn u32(&mut self, what: &str) -> Result<u32, DecodeError> {
        Ok(u32::from_be_bytes(self.bytes::<4>(what)?))
    }

    /// An `int32`.
    fn i32(&mut self, what: &str) -> Result<i32, DecodeError> {
        Ok(i32::from_be_bytes(self.bytes::<4>(what)?))
    }

    /// A `float32`, widened to `f64` (exactly).
    fn f32(&mut self, what: &str) -> Result<f64, DecodeError> {
        Ok(f64::from(f32::from_be_bytes(self.bytes::<4>(what)?)))
    }

    /// A `float64`.
    fn f64(&mut self, what: &str) -> Result<f64, DecodeError> {
        Ok(f64::from_be_bytes(self.bytes::<8>(what)?))
    }

    /// A `string` (UTF-8; the length counts the terminating NUL).
    fn string(&mut self, what: &str) -> Result<String, DecodeError> {
        let n = self.u32(&format!("the length of {what}"))? as usize;
        if n == 0 {
            // Not valid CDR (the NUL is counted), but some writers emit it for "".
            return Ok(String::new());
        }
        let start = self.pos;
        let s = self.take(n, what)?;
        if s[n - 1] != 0 {
            return Err(DecodeError {
                offset: start + n - 1,
                what: format!("the NUL that ends {what}"),
                wire: "CDR",
            });
        }
        String::from_utf8(s[..n - 1].to_vec()).map_err(|_| DecodeError {
            offset: start,
            what: format!("{what} in UTF-8"),
            wire: "CDR",
        })
    }

    /// Skips a fixed-size `float64[n]` array.
    fn skip_f64s(&mut self, n: usize, what: &str) -> Result<(), DecodeError> {
        self.align(8)?;
        self.take(8 * n, what).map(|_| ())
    }

    fn header_stamp(&mut self) -> Result<i64, DecodeError> {
        let sec = self.i32("header.stamp.sec")?;
        let nsec = self.u32("header.stamp.nanosec")?;
        Ok(i64::from(sec) * 1_000_000_000 + nanos(self, nsec)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn little_and_big_endian_with_alignment() {
        // u32 5, then padding to 8, then f64 1.5, then string "ab".
        let mut le = vec![0, 1, 0, 0];
        le.extend(5u32.to_le_bytes());
        le.extend([0xee; 4]);
        le.extend(1.5f64.to_le_bytes());
        le.extend(3u32.to_le_bytes());
        le.extend(b"ab\0");
        let mut c = Cdr::new(&le).unwrap();
        assert_eq!(c.u32("n").unwrap(), 5);
        assert_eq!(c.f64("x").unwrap(), 1.5);
        assert_eq!(c.string("s").unwrap(), "ab");
        assert_eq!(c.remaining(), 0);

        let mut be = vec![0, 0, 0, 0];
        be.extend(5u32.to_be_bytes());
        be.extend([0; 4]);
        be.extend(1.5f64.to_be_bytes());
        be.extend(3u32.to_be_bytes());
        be.extend(b"ab\0");
        let mut c = Cdr::new(&be).unwrap();
        assert_eq!(c.u32("n").unwrap(), 5);
        assert_eq!(c.f64("x").unwrap(), 1.5);
        assert_eq!(c.string("s").unwrap(), "ab");
    }

    #[test]
    fn hostile_counts_and_headers_are_errors() {
        let mut m = vec![0, 1, 0, 0];
        m.extend(u32::MAX.to_le_bytes());
        let e = Cdr::new(&m).unwrap().seq_f32("ranges").unwrap_err();
        assert!(e.what.contains("4294967295 element(s)"), "{e}");
        let e = Cdr::new(&m).unwrap().string("frame_id").unwrap_err();
        assert!(e.what.contains("truncated"), "{e}");
        assert!(Cdr::new(&[0, 1]).is_err());
        let e = Cdr::new(&[0, 3, 0, 0]).err().unwrap();
        assert!(e.what.contains("found 00 03"), "{e}");
        let mut m = vec![0, 1, 0, 0];
        m.extend(2u32.to_le_bytes());
        m.extend(b"ab");
        assert!(Cdr::new(&m)
            .unwrap()
            .string("s")
            .unwrap_err()
            .what
            .contains("NUL"));
    }
}
