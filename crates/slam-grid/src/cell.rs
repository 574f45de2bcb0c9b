//! Cell indices and the world ↔ cell mapping.
//!
//! Two coordinate kinds never mix: world points ([`Point2`], metres, world frame) and cell
//! indices ([`CellIndex`], integers). Between them sits [`GridFrame`]: cell (i, j) covers the
//! square `[ox + i·res, ox + (i+1)·res) × [oy + j·res, oy + (j+1)·res)` of the world, where
//! (ox, oy) is the frame's origin. Continuous *cell coordinates* (u, v) = ((x − ox)/res,
//! (y − oy)/res) are used internally for beam tracing and interpolation: cell (i, j) spans
//! u ∈ [i, i+1), v ∈ [j, j+1) and its centre sits at (i + ½, j + ½).

use serde::{Deserialize, Serialize};
use slam_models::Point2;

/// Integer coordinates of a grid cell. Either may be negative: grids grow in every direction.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default, Serialize, Deserialize,
)]
pub struct CellIndex {
    /// Column (x direction).
    pub x: i32,
    /// Row (y direction).
    pub y: i32,
}

impl CellIndex {
    /// The cell (x, y).
    #[inline]
    pub const fn new(x: i32, y: i32) -> Self {
        Self { x, y }
    }
}

/// ⌊u⌋ as an `i32`, saturating beyond the `i32` range (0 for NaN): the same value as
/// `u.floor() as i32`, without the library call `floor` is on x86-64 without SSE4.1 (the
/// cell lookup of every end point of every scan-matching pose goes through it).
#[inline(always)]
pub(crate) fn floor_i32(u: f64) -> i32 {
    // Without a branch, so that loops over many points vectorise (`Lattice::new`): the
    // truncation lowered by one where it lies above u, except at i32::MIN (saturated).
    let t = u as i32;
    t - i32::from((t as f64) > u && t != i32::MIN)
}

/// ⌊u⌋ as an `i32` for |u| < 2³⁰, equal to [`floor_i32`] there (any other u gives some
/// value, never a panic): u + 1.5·2⁵² rounds u to the nearest integer (ties to even; exact
/// for |u| < 2⁵¹) and holds it in its low 32 bits, lowered by one where it lies above u.
/// Neither a branch nor a float-to-integer conversion (saturating in Rust, scalar on
/// x86-64's SSE2), so loops over many points vectorise (`Lattice::new`). The caller
/// bounds |u| first.
#[inline(always)]
pub(crate) fn floor_i32_bounded(u: f64) -> i32 {
    const MAGIC: f64 = 6_755_399_441_055_744.0; // 1.5 · 2⁵²
    let shifted = u + MAGIC;
    let rounded = shifted - MAGIC;
    (shifted.to_bits() as u32 as i32) - i32::from(rounded > u)
}

/// The bound on |u| below which [`floor_i32_bounded`] is exact.
pub(crate) const FLOOR_BOUNDED_LIMIT: f64 = 1_073_741_824.0; // 2³⁰

/// The affine map between world points and cells: an origin (world position of the
/// lower-left corner of cell (0, 0), metres) and a resolution (cell edge, metres).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GridFrame {
    /// World position of the lower-left corner of cell (0, 0), metres.
    pub origin: Point2,
    /// Cell edge length, metres (> 0).
    pub resolution: f64,
}

impl GridFrame {
    /// A frame with the given origin and resolution (no validation; grids validate).
    #[inline]
    pub fn new(origin: Point2, resolution: f64) -> Self {
        Self { origin, resolution }
    }

    /// The cell containing world point `p` (floor of the cell coordinates; a point on a
    /// cell's lower or left edge belongs to that cell). Coordinates beyond ±2³¹ cells
    /// saturate.
    #[inline]
    pub fn world_to_cell(&self, p: &Point2) -> CellIndex {
        let (u, v) = self.world_to_continuous(p);
        CellIndex::new(floor_i32(u), floor_i32(v))
    }

    /// Continuous cell coordinates (u, v) of a world point.
    #[inline]
    pub fn world_to_continuous(&self, p: &Point2) -> (f64, f64) {
        let inv = 1.0 / self.resolution;
        ((p.x - self.origin.x) * inv, (p.y - self.origin.y) * inv)
    }

    /// World position of the centre of cell `c`.
    #[inline]
    pub fn cell_center(&self, c: CellIndex) -> Point2 {
        Point2::new(
            self.origin.x + (c.x as f64 + 0.5) * self.resolution,
            self.origin.y + (c.y as f64 + 0.5) * self.resolution,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_negative_cells() {
        let f = GridFrame::new(Point2::new(-1.0, 2.0), 0.05);
        for &(i, j) in &[(0, 0), (-1, -1), (17, -300), (-4000, 25)] {
            let c = CellIndex::new(i, j);
            assert_eq!(f.world_to_cell(&f.cell_center(c)), c);
        }
        // Just left of the origin is cell −1, the origin itself is cell 0.
        assert_eq!(
            f.world_to_cell(&Point2::new(-1.0001, 2.0)),
            CellIndex::new(-1, 0)
        );
        assert_eq!(
            f.world_to_cell(&Point2::new(-1.0, 2.0)),
            CellIndex::new(0, 0)
        );
        let c = f.cell_center(CellIndex::new(2, 3));
        assert!((c.x - (-1.0 + 0.125)).abs() < 1e-12 && (c.y - (2.0 + 0.175)).abs() < 1e-12);
    }

    /// `floor_i32` is `floor` then a saturating cast, at integers, just beside them, at
    /// ±0, NaN and beyond the `i32` range.
    #[test]
    fn floor_i32_is_the_saturated_floor() {
        let mut values = vec![0.0, -0.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e300];
        for i in [
            -3_000_000_000i64,
            -2_147_483_649,
            -2_147_483_648,
            -1,
            0,
            1,
            7,
            2_147_483_647,
        ] {
            let x = i as f64;
            values.extend([
                x,
                x - 1e-9,
                x + 1e-9,
                x - 0.5,
                x + 0.5,
                x.next_down(),
                x.next_up(),
            ]);
        }
        for u in values {
            assert_eq!(floor_i32(u), u.floor() as i32, "u = {u:e}");
            if u.abs() < FLOOR_BOUNDED_LIMIT {
                assert_eq!(floor_i32_bounded(u), u.floor() as i32, "u = {u:e}");
            }
        }
    }
}
