//! A small encoder of OMG CDR (XCDR version 1, little endian): the inverse of the bag
//! reader's decoder (`rosbag/cdr.rs`), with the same rules (DDS-XTypes 1.3 §7.4.3.4, CORBA
//! 3.0 §15.3.1):
//!
//! * the message starts with the encapsulation header `00 01 00 00` (CDR little endian);
//! * a primitive of size n (1, 2, 4 or 8 bytes) starts at an offset of the body (the bytes
//!   after the header) that is a multiple of n, zero bytes padding the gap;
//! * a string is a `uint32` length counting the terminating NUL, then the bytes and NUL;
//! * a sequence is a `uint32` element count, then the elements; a fixed array has no count.
//!
//! The encoder cannot fail: every value it is given has a CDR form. A length beyond
//! `u32::MAX` has none, and is refused by the message encoders before they get here.

/// A growing CDR little-endian message.
pub(crate) struct CdrWriter {
    buf: Vec<u8>,
}

/// Length of the encapsulation header; alignment counts from the byte after it.
const HEADER: usize = 4;

impl CdrWriter {
    /// An empty message: the encapsulation header only.
    pub fn new() -> Self {
        let mut buf = Vec::with_capacity(256);
        buf.extend_from_slice(&[0, 1, 0, 0]);
        CdrWriter { buf }
    }

    /// The encoded message (header and body).
    pub fn into_bytes(self) -> Vec<u8> {
        self.buf
    }

    /// Pads with zeros so that the next primitive of size `n` is aligned.
    fn align(&mut self, n: usize) {
        let pos = self.buf.len() - HEADER;
        let pad = (n - pos % n) % n;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    /// An `int8`.
    pub fn i8(&mut self, v: i8) {
        self.buf.push(v as u8);
    }

    /// A `bool` (one byte, 0 or 1).
    pub fn bool(&mut self, v: bool) {
        self.buf.push(u8::from(v));
    }

    /// A `uint32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// An `int32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `float32` (the nearest `f32` to `v`).
    pub fn f32(&mut self, v: f64) {
        self.align(4);
        self.buf.extend_from_slice(&(v as f32).to_le_bytes());
    }

    /// A `float64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `string`: length with the NUL, bytes, NUL. The caller guarantees that `s` holds
    /// no NUL and is shorter than `u32::MAX` bytes (frame ids and namespaces of this crate).
    pub fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }

    /// A sequence's element count. The caller guarantees `n ≤ u32::MAX` (checked by the
    /// message encoders).
    pub fn count(&mut self, n: usize) {
        self.u32(n as u32);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rosbag::cdr::Cdr;
    use crate::rosbag::wire::Wire;

    /// The decoder of the bag reader reads back what the encoder wrote, alignment included.
    #[test]
    fn round_trip_through_the_readers_decoder() {
        let mut w = CdrWriter::new();
        w.i8(7);
        w.u32(5);
        w.i8(-3);
        w.f64(1.5);
        w.string("map");
        w.f32(0.1);
        w.i32(-42);
        w.count(2);
        w.f32(2.5);
        w.f32(f64::INFINITY);
        let b = w.into_bytes();
        // By hand: u8 at body 0, pad 1..4, u32 at 4, i8 at 8, pad to 16, f64 at 16,
        // string length at 24, "map\0" at 28..32, f32 at 32, i32 at 36, count at 40.
        assert_eq!(&b[..4], &[0, 1, 0, 0]);
        assert_eq!(b.len(), 4 + 52);
        assert_eq!(&b[4 + 1..4 + 4], &[0, 0, 0]);
        let mut c = Cdr::new(&b).unwrap();
        // The reader has no u8/i8 reader of its own; skip them through a u32-sized peek.
        assert_eq!(b[4], 7);
        assert_eq!(b[4 + 8] as i8, -3);
        c.u32("skip u8 + pad").unwrap();
        assert_eq!(c.u32("u32").unwrap(), 5);
        c.u32("skip i8 + pad").unwrap();
        assert_eq!(c.f64("f64").unwrap(), 1.5);
        assert_eq!(c.string("s").unwrap(), "map");
        assert_eq!(c.f32("f32").unwrap(), f64::from(0.1f32));
        assert_eq!(c.i32("i32").unwrap(), -42);
        assert_eq!(c.seq_f32("seq").unwrap(), vec![2.5, f64::INFINITY]);
        assert_eq!(c.remaining(), 0);
    }
}
