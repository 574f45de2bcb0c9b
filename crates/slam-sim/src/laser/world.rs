//! A world of line segments.

use slam_models::Point2;

/// A wall: the segment from `a` to `b` (world frame, metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// First end point.
    pub a: Point2,
    /// Second end point.
    pub b: Point2,
}

/// A 2-D world of line segments.
#[derive(Debug, Clone)]
pub struct World {
    segments: Vec<Segment>,
}

impl World {
    /// The walls.
    pub fn segments(&self) -> &[Segment] {
        &self.segments
    }
}
