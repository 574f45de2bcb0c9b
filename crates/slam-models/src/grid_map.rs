//! A plain occupancy raster: what a scan-based filter hands out as "the map".
//!
//! The working grids (log-odds, copy-on-write tiles) live in `slam-grid`; this is the
//! exchange format that writers and pictures consume, laid out exactly like ROS
//! `nav_msgs/OccupancyGrid`, so it exports to map_server without conversion.

use crate::Point2;
use serde::{Deserialize, Serialize};

/// An occupancy grid in ROS convention.
///
/// Cell (ix, iy) covers the square [ox + ix·res, ox + (ix+1)·res) × [oy + iy·res, oy + (iy+1)·res)
/// in the world frame, where (ox, oy) = `origin` is the world position of the lower-left
/// corner of cell (0, 0). `cells` is row-major with row 0 at the **bottom** (smallest y).
/// Values: −1 unknown, 0 free … 100 occupied (occupancy probability in percent).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GridMap {
    /// Cell edge length, metres.
    pub resolution: f64,
    /// World position of the lower-left corner of cell (0, 0), metres.
    pub origin: Point2,
    /// Number of columns (x direction).
    pub width: usize,
    /// Number of rows (y direction).
    pub height: usize,
    /// Row-major occupancy values, `width·height` of them.
    pub cells: Vec<i8>,
}

impl GridMap {
    /// Value of an unknown cell.
    pub const UNKNOWN: i8 = -1;

    /// An all-unknown grid.
    pub fn unknown(resolution: f64, origin: Point2, width: usize, height: usize) -> Self {
        Self {
            resolution,
            origin,
            width,
            height,
            cells: vec![Self::UNKNOWN; width * height],
        }
    }

    /// The value of cell (ix, iy), or `None` outside the grid.
    #[inline]
    pub fn get(&self, ix: usize, iy: usize) -> Option<i8> {
        (ix < self.width && iy < self.height).then(|| self.cells[iy * self.width + ix])
    }

    /// The cell containing world point `p`, or `None` outside the grid.
    pub fn cell_of(&self, p: &Point2) -> Option<(usize, usize)> {
        let fx = ((p.x - self.origin.x) / self.resolution).floor();
        let fy = ((p.y - self.origin.y) / self.resolution).floor();
        (fx >= 0.0 && fy >= 0.0 && (fx as usize) < self.width && (fy as usize) < self.height)
            .then_some((fx as usize, fy as usize))
    }

    /// World position of the centre of cell (ix, iy).
    pub fn cell_center(&self, ix: usize, iy: usize) -> Point2 {
        Point2::new(
            self.origin.x + (ix as f64 + 0.5) * self.resolution,
            self.origin.y + (iy as f64 + 0.5) * self.resolution,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_round_trip() {
        let g = GridMap::unknown(0.05, Point2::new(-1.0, -2.0), 40, 80);
        let c = g.cell_center(7, 33);
        assert_eq!(g.cell_of(&c), Some((7, 33)));
        assert_eq!(g.cell_of(&Point2::new(-1.01, 0.0)), None);
        assert_eq!(g.cell_of(&Point2::new(0.999, 1.999)), Some((39, 79)));
        assert_eq!(g.get(40, 0), None);
    }
}
