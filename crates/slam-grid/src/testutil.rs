//! Test helpers: a small polygonal world with exact ray casting (unit tests only).

use crate::{InverseSensorModel, OccupancyGrid};
use slam_models::{LaserScan, Point2, Pose2};

/// The map of [`SegmentWorld::office`] at `res` metres a cell from noise-free 360° scans at
/// 20 known poses (5 places, 4 headings each), the grid not aligned with the walls.
pub(crate) fn office_map(res: f64) -> OccupancyGrid {
    let world = SegmentWorld::office();
    let mut g = OccupancyGrid::new(res, InverseSensorModel::default())
        .with_origin(Point2::new(-0.0137, -0.0311))
        .unwrap();
    for &(x, y) in &[(1.5, 3.0), (5.0, 3.5), (10.5, 2.0), (2.0, 6.5), (9.0, 6.5)] {
        for k in 0..4 {
            let pose = Pose2::new(x, y, k as f64 * 1.57);
            g.integrate_scan(
                &pose,
                &world.scan(&pose, 720, std::f64::consts::TAU * 0.999, 30.0),
            );
        }
    }
    g
}

/// A world of line segments.
pub(crate) struct SegmentWorld {
    pub(crate) segments: Vec<(Point2, Point2)>,
}

impl SegmentWorld {
    /// A 12 m × 8 m office-like floor: outer walls, two rooms, a corridor, a pillar.
    pub(crate) fn office() -> Self {
        let p = Point2::new;
        let mut s = vec![
            (p(0.0, 0.0), p(12.0, 0.0)),
            (p(12.0, 0.0), p(12.0, 8.0)),
            (p(12.0, 8.0), p(0.0, 8.0)),
            (p(0.0, 8.0), p(0.0, 0.0)),
            // Corridor wall with two doors.
            (p(0.0, 5.0), p(3.0, 5.0)),
            (p(4.0, 5.0), p(8.0, 5.0)),
            (p(9.0, 5.0), p(12.0, 5.0)),
            // Room divider.
            (p(6.0, 5.0), p(6.0, 8.0)),
            // A cabinet and a slanted desk.
            (p(2.0, 1.0), p(3.5, 1.0)),
            (p(3.5, 1.0), p(3.5, 1.6)),
            (p(3.5, 1.6), p(2.0, 1.6)),
            (p(8.0, 2.5), p(9.5, 3.3)),
        ];
        // A square pillar.
        let (cx, cy, r) = (6.5, 2.0, 0.25);
        s.push((p(cx - r, cy - r), p(cx + r, cy - r)));
        s.push((p(cx + r, cy - r), p(cx + r, cy + r)));
        s.push((p(cx + r, cy + r), p(cx - r, cy + r)));
        s.push((p(cx - r, cy + r), p(cx - r, cy - r)));
        Self { segments: s }
    }

    /// Distance along the ray from `o` in direction `a` to the first segment (∞ if none).
    pub(crate) fn cast(&self, o: Point2, a: f64) -> f64 {
        let d = (a.cos(), a.sin());
        let mut best = f64::INFINITY;
        for (p, q) in &self.segments {
            let e = (q.x - p.x, q.y - p.y);
            let den = d.0 * e.1 - d.1 * e.0;
            if den.abs() < 1e-12 {
                continue;
            }
            let w = (p.x - o.x, p.y - o.y);
            let t = (w.0 * e.1 - w.1 * e.0) / den;
            let u = (w.0 * d.1 - w.1 * d.0) / den;
            if t > 0.0 && (0.0..=1.0).contains(&u) {
                best = best.min(t);
            }
        }
        best
    }

    /// A noise-free scan from robot pose `pose` (sensor at the robot origin): `n` beams over
    /// `fov` radians centred on the heading; misses read `max_range`.
    pub(crate) fn scan(&self, pose: &Pose2, n: usize, fov: f64, max_range: f64) -> LaserScan {
        let inc = fov / (n - 1) as f64;
        let angle_min = -fov / 2.0;
        let ranges = (0..n)
            .map(|k| {
                let r = self.cast(pose.translation(), pose.theta + angle_min + k as f64 * inc);
                if r < max_range {
                    r
                } else {
                    max_range
                }
            })
            .collect();
        LaserScan {
            angle_min,
            angle_increment: inc,
            ranges,
            max_range,
            sensor_pose: Pose2::IDENTITY,
        }
    }
}
