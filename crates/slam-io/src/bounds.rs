//! The physical bounds every reader checks its values against.
//!
//! A number that parses and is finite can still be absurd (`1e308` m, a heading of 10¹⁵ rad,
//! a time in the year 3×10¹⁰): downstream code would turn it into infinities, endless loops
//! or huge allocations. Each reader therefore checks every field against the bound of its
//! kind below and reports a violation as [`crate::IoError::OutOfBounds`], naming the file,
//! the 1-based line, the field, the value and the bound.
//!
//! The bounds are far beyond any real 2-D SLAM data (the real datasets in
//! `../shared/datasets` stay within 100 m, 82 m ranges, |θ| ≤ π, Unix times ≈ 1.2×10⁹ s)
//! and far inside the range where `f64` arithmetic on them loses metre-level precision.

use std::f64::consts::TAU;

/// Largest absolute coordinate (x, y, z, a landmark or map origin), metres: 1000 km.
pub const MAX_COORD: f64 = 1e6;
/// Largest range reading or sensor maximum range, metres. No 2-D laser or landmark sensor
/// measures this far; CARMEN's "no return" codes are 51–82 m.
pub const MAX_RANGE: f64 = 1000.0;
/// Largest absolute robot heading, radians. Headings may be unwrapped (a simulator's
/// odometry keeps turning), so this allows about 1,600 turns.
pub const MAX_HEADING: f64 = 1e4;
/// Largest absolute relative angle (a bearing, a rotation increment, a relative yaw, a scan's
/// start angle), radians: one full turn.
pub const MAX_ANGLE: f64 = TAU;
/// Largest absolute time, seconds (Unix time 10¹⁰ s is the year 2286).
pub const MAX_TIME: f64 = 1e10;
/// Longest span of times within one file, seconds (about 116 days).
pub const MAX_TIME_SPAN: f64 = 1e7;
/// Largest absolute linear speed or acceleration field, m/s (or m/s²).
pub const MAX_SPEED: f64 = 100.0;
/// Largest absolute angular speed, rad/s.
pub const MAX_TURN_RATE: f64 = 100.0;
/// Largest absolute value of any other numeric field (an unused auxiliary field, a
/// remission, a covariance entry in m²): refuses `1e308` wherever it appears.
pub const MAX_MAGNITUDE: f64 = 1e12;
/// Finest and coarsest map resolution, metres per cell.
pub const RESOLUTION_RANGE: (f64, f64) = (1e-4, 1e3);
/// Most cells in a map image (2²⁸: 256 MiB of 8-bit cells).
pub const MAX_MAP_CELLS: usize = 1 << 28;
/// Most beams (range readings) in one laser scan, for every reader (CARMEN lines, bag
/// messages): ten times the densest 2-D scanners (a 0.1° scanner has 3,600 beams per turn).
pub const MAX_BEAMS: usize = 100_000;
/// Largest record a binary container may hold, bytes (256 MiB), compressed or after
/// decompression: an MCAP record or chunk, a ROS 1 bag record or decompressed chunk, a
/// rosbag2 zstd-compressed message. A length field is trusted only up to this cap and the
/// bytes the file still holds; a scan of [`MAX_BEAMS`] beams is 0.4 MB.
pub const MAX_RECORD_BYTES: usize = 1 << 28;

/// Tracks the times of one file: each must be within [`MAX_TIME_SPAN`] of the file's first
/// time, either way. Times may repeat or step back: real logs do (the Intel log has records
/// stamped 0 among times of 33 s and more), and readers keep file order; but a time years
/// away from the rest is a corrupted value.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct TimeSpan {
    first: Option<f64>,
}

impl TimeSpan {
    /// Checks `t` (already within ±[`MAX_TIME`]); `Err` holds the broken bound in words.
    pub fn check(&mut self, t: f64) -> Result<(), String> {
        let first = *self.first.get_or_insert(t);
        if (t - first).abs() > MAX_TIME_SPAN {
            return Err(format!(
                "a time within {MAX_TIME_SPAN} s of the file's first time ({first})"
            ));
        }
        Ok(())
    }
}

/// Largest text input, bytes (2 GiB): a plain file's size, or a gzip file's decompressed
/// size (all members). Reading stops at this many bytes, so a small "gzip bomb" cannot
/// exhaust memory; a larger input is [`crate::IoError::TooLarge`].
pub const MAX_TEXT_BYTES: u64 = 2 << 30;

/// Longest line of a text input, bytes (16 MiB). The longest legitimate line is a CARMEN
/// scan of [`MAX_BEAMS`] readings, about 2 MB; a longer one (a gzip of one endless line)
/// is refused while it is being decompressed, so it never costs [`MAX_TEXT_BYTES`] of memory.
pub const MAX_LINE_BYTES: usize = 16 << 20;
