//! A map that contradicts itself, found without ground truth: the scans, at the poses a
//! laser filter estimated for them, looking through walls that other scans of the same run
//! put there.
//!
//! A consistent run places every wall where every scan that sees it ends its beams, and no
//! scan's beam passes through a wall the others have seen: the space in front of a wall is
//! free for every scan. When a run bends the map (a heading error at a corridor junction)
//! or doubles a corridor (a loop closed wrongly), the scans of one part see walls that the
//! scans of the other part cross: beams of one scan pass through cells where several other
//! scans ended theirs. [`map_contradictions`] counts those beams: a first pass marks, per
//! cell, the number of distinct scans whose beams end there; a second walks every beam from
//! the sensor to `end_margin` before its end point and calls it a contradiction when it
//! crosses a cell that at least `min_scans` scans have hit. A scan contradicts the map
//! when more than `beam_fraction` of its checked beams do, and a run is
//! [`MapCheck::inconsistent`] when more than `scan_fraction` of its scans contradict.
//!
//! The thresholds were set on the simulated office with exact poses (no scan contradicts)
//! and with its second lap turned or moved (78–98 % of the scans contradict), and on real
//! runs: Intel by grid FastSLAM, scan-matching odometry and the graph front end (3.6 %,
//! 3.7 % and 9.5 % of the scans contradict, relations 0.046–0.056 m) and fhw with `hard`
//! odometry (perturbation seed 2) bent by 75° (31 %) (`tests/robust.rs`,
//! `docs/results.md`). Glass, doors, people walking and beams grazing a wall make a few
//! beams of a correct run contradict, which the per-scan fraction absorbs. The check is
//! coarse: a bend whose two parts barely overlap contradicts little (fhw-hard-p2, grid
//! FastSLAM seed 1, 9.5 m aligned ATE: 6.8 %), which the ATE criterion of the suite
//! catches where there is truth.

use slam_models::{detmath, LaserScan, Point2, Pose2};

/// The detector's settings ([`MapCheckParams::default`] for the documented values).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapCheckParams {
    /// Cell size of the hit-count grid, metres (0.1). A map whose cells would exceed
    /// [`MapCheckParams::max_cells`] is counted on cells twice as large, as often as needed.
    pub resolution: f64,
    /// Largest number of grid cells (8 · 2²⁰ by default, 48 MiB of counts).
    pub max_cells: usize,
    /// Every `beam_step`-th beam is used (2).
    pub beam_step: usize,
    /// Returns beyond this range, metres, are not used (30 m): the far ends of long beams
    /// are where angular error is largest.
    pub max_range: f64,
    /// A cell is a wall when at least this many distinct scans end a beam in it (3).
    pub min_scans: u16,
    /// The last part of a beam, metres, not checked (0.6 m: its own wall, blurred by the
    /// poses' noise, and the wall it grazes at a shallow angle).
    pub end_margin: f64,
    /// A scan contradicts the map when more than this fraction of its checked beams cross
    /// a wall (0.25).
    pub beam_fraction: f64,
    /// A scan with fewer checked beams than this is not judged (20).
    pub min_beams: usize,
    /// A run is inconsistent when more than this fraction of its judged scans contradict
    /// the map (0.15).
    pub scan_fraction: f64,
}

impl Default for MapCheckParams {
    fn default() -> Self {
        Self {
            resolution: 0.1,
            max_cells: 8 << 20,
            beam_step: 2,
            max_range: 30.0,
            min_scans: 3,
            end_margin: 0.6,
            beam_fraction: 0.25,
            min_beams: 20,
            scan_fraction: 0.15,
        }
    }
}

/// What [`map_contradictions`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapCheck {
    /// Scans judged (with at least [`MapCheckParams::min_beams`] checked beams).
    pub scans: usize,
    /// Judged scans more than [`MapCheckParams::beam_fraction`] of whose beams cross a wall.
    pub contradicting: usize,
    /// `contradicting / scans` (0 when no scan was judged).
    pub fraction: f64,
    /// Beams crossing a wall over beams checked, all scans together.
    pub beam_fraction: f64,
    /// Whether `fraction` exceeds [`MapCheckParams::scan_fraction`].
    pub inconsistent: bool,
    /// The cell size used, metres (larger than asked for a very large map).
    pub resolution: f64,
}

/// The hit-count grid over a bounding box.
struct Counts {
    min: Point2,
    resolution: f64,
    width: usize,
    height: usize,
    /// Distinct scans ending a beam in each cell, and the last scan counted (index + 1).
    hits: Vec<u16>,
    last: Vec<u32>,
}

impl Counts {
    fn cell(&self, p: &Point2) -> Option<usize> {
        let cx = ((p.x - self.min.x) / self.resolution).floor();
        let cy = ((p.y - self.min.y) / self.resolution).floor();
        (cx >= 0.0 && cy >= 0.0 && (cx as usize) < self.width && (cy as usize) < self.height)
            .then(|| cy as usize * self.width + cx as usize)
    }
}

/// The sensor origin and the used end points (world frame) of one scan at robot pose
/// `pose`: every `beam_step`-th hit with 0 < r ≤ `max_range`.
fn beams(pose: &Pose2, scan: &LaserScan, p: &MapCheckParams) -> (Point2, Vec<Point2>) {
    let sensor = pose.compose(&scan.sensor_pose);
    let origin = sensor.translation();
    let ends = (0..scan.len())
        .step_by(p.beam_step.max(1))
        .filter(|&k| scan.is_hit(k) && scan.ranges[k] > 0.0 && scan.ranges[k] <= p.max_range)
        .map(|k| {
            let (r, (s, c)) = (scan.ranges[k], detmath::sin_cos(scan.beam_angle(k)));
            sensor.transform_point(&Point2::new(r * c, r * s))
        })
        .collect();
    (origin, ends)
}

/// Counts the scans of a run that look through walls other scans of the run have seen
/// (see the module documentation). `scans` are the robot poses the run estimated at each
/// scan (world frame; the scan's own `sensor_pose` is applied) with the scans. Non-finite
/// poses or ranges are skipped. Cost: one pass over the end points and one walk of every
/// checked beam in half-cell steps.
pub fn map_contradictions(scans: &[(Pose2, &LaserScan)], p: &MapCheckParams) -> MapCheck {
    let rays: Vec<(Point2, Vec<Point2>)> = scans
        .iter()
        .filter(|(pose, _)| pose.is_finite())
        .map(|(pose, scan)| {
            let (o, ends) = beams(pose, scan, p);
            (
                o,
                ends.into_iter()
                    .filter(|e| e.x.is_finite() && e.y.is_finite())
                    .collect(),
            )
        })
        .collect();
    let (mut lo, mut hi) = (
        Point2::new(f64::INFINITY, f64::INFINITY),
        Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for (o, ends) in &rays {
        for q in std::iter::once(o).chain(ends) {
            (lo.x, lo.y) = (lo.x.min(q.x), lo.y.min(q.y));
            (hi.x, hi.y) = (hi.x.max(q.x), hi.y.max(q.y));
        }
    }
    let mut resolution = p.resolution;
    let empty = MapCheck {
        scans: 0,
        contradicting: 0,
        fraction: 0.0,
        beam_fraction: 0.0,
        inconsistent: false,
        resolution,
    };
    if !(lo.x.is_finite() && resolution > 0.0 && resolution.is_finite()) {
        return empty;
    }
    let size = |r: f64| {
        (
            ((hi.x - lo.x) / r).floor() as usize + 2,
            ((hi.y - lo.y) / r).floor() as usize + 2,
        )
    };
    while {
        let (w, h) = size(resolution);
        w.saturating_mul(h) > p.max_cells.max(1)
    } {
        resolution *= 2.0;
    }
    let (width, height) = size(resolution);
    let mut grid = Counts {
        min: lo,
        resolution,
        width,
        height,
        hits: vec![0; width * height],
        last: vec![0; width * height],
    };
    for (i, (_, ends)) in rays.iter().enumerate() {
        let tag = i as u32 + 1;
        for e in ends {
            if let Some(c) = grid.cell(e) {
                if grid.last[c] != tag {
                    grid.last[c] = tag;
                    grid.hits[c] = grid.hits[c].saturating_add(1);
                }
            }
        }
    }
    let step = 0.5 * resolution;
    let (mut judged, mut contradicting, mut crossed_all, mut checked_all) = (0, 0, 0usize, 0usize);
    for (o, ends) in &rays {
        let mut crossed = 0;
        for e in ends {
            let (dx, dy) = (e.x - o.x, e.y - o.y);
            let length = dx.hypot(dy);
            let n = ((length - p.end_margin) / step).floor();
            if n.is_nan() || n < 1.0 {
                continue;
            }
            let through = (1..=n as usize).any(|j| {
                let t = j as f64 * step / length;
                grid.cell(&Point2::new(o.x + t * dx, o.y + t * dy))
                    .is_some_and(|c| grid.hits[c] >= p.min_scans)
            });
            crossed += usize::from(through);
        }
        let checked = ends.len();
        crossed_all += crossed;
        checked_all += checked;
        if checked >= p.min_beams {
            judged += 1;
            contradicting += usize::from(crossed as f64 > p.beam_fraction * checked as f64);
        }
    }
    let fraction = if judged > 0 {
        contradicting as f64 / judged as f64
    } else {
        0.0
    };
    MapCheck {
        scans: judged,
        contradicting,
        fraction,
        beam_fraction: if checked_all > 0 {
            crossed_all as f64 / checked_all as f64
        } else {
            0.0
        },
        inconsistent: fraction > p.scan_fraction,
        resolution,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scan of `n` beams over 360° from a robot at `pose` inside the axis-aligned box
    /// [0, w] × [0, h] (exact ranges to its walls).
    fn box_scan(pose: &Pose2, w: f64, h: f64, n: usize) -> LaserScan {
        let inc = std::f64::consts::TAU / n as f64;
        let ranges = (0..n)
            .map(|k| {
                let a = pose.theta + k as f64 * inc - std::f64::consts::PI;
                let (c, s) = (a.cos(), a.sin());
                let tx = if c > 0.0 {
                    (w - pose.x) / c
                } else if c < 0.0 {
                    -pose.x / c
                } else {
                    f64::INFINITY
                };
                let ty = if s > 0.0 {
                    (h - pose.y) / s
                } else if s < 0.0 {
                    -pose.y / s
                } else {
                    f64::INFINITY
                };
                tx.min(ty)
            })
            .collect();
        LaserScan {
            angle_min: -std::f64::consts::PI,
            angle_increment: inc,
            ranges,
            max_range: 50.0,
            sensor_pose: Pose2::IDENTITY,
        }
    }

    /// Scans taken in a 10 m × 4 m room, at exact poses, do not contradict one another;
    /// the same scans with the second half's poses turned by 10° about the room's middle
    /// (a bent map) do: their walls lie across the first half's free space (0.3 m margin,
    /// 15 % of a scan's beams).
    #[test]
    fn a_room_is_consistent_and_the_same_room_bent_is_not() {
        let poses: Vec<Pose2> = (0..40)
            .map(|i| {
                Pose2::new(
                    1.0 + 0.2 * i as f64,
                    2.0 + 0.3 * (i as f64 * 0.5).sin(),
                    0.1,
                )
            })
            .collect();
        let scans: Vec<LaserScan> = poses.iter().map(|p| box_scan(p, 10.0, 4.0, 360)).collect();
        let pairs: Vec<(Pose2, &LaserScan)> = poses.iter().copied().zip(&scans).collect();
        // The mechanism, with a tighter margin and beam fraction than the defaults (which
        // tests/robust.rs checks on the simulated office): a 10° bend of a 10 m room moves
        // its far walls by less than the default margin allows.
        let p = MapCheckParams {
            end_margin: 0.3,
            beam_fraction: 0.15,
            ..Default::default()
        };
        let good = map_contradictions(&pairs, &p);
        assert_eq!(good.scans, 40);
        assert_eq!(good.contradicting, 0, "{good:?}");
        assert!(!good.inconsistent);
        let pivot = Pose2::new(5.0, 2.0, 0.0);
        let turn = pivot
            .compose(&Pose2::new(0.0, 0.0, 10f64.to_radians()))
            .compose(&pivot.inverse());
        let bent: Vec<(Pose2, &LaserScan)> = pairs
            .iter()
            .enumerate()
            .map(|(i, &(pose, s))| (if i >= 20 { turn.compose(&pose) } else { pose }, s))
            .collect();
        let bad = map_contradictions(&bent, &p);
        eprintln!("room: good {good:?}, bent {bad:?}");
        assert!(bad.inconsistent, "{bad:?}");
        assert!(bad.contradicting >= 20, "{bad:?}");
    }

    #[test]
    fn nothing_to_judge_is_consistent() {
        let r = map_contradictions(&[], &MapCheckParams::default());
        assert_eq!((r.scans, r.contradicting, r.inconsistent), (0, 0, false));
        let scan = box_scan(&Pose2::new(1.0, 1.0, 0.0), 2.0, 2.0, 360);
        let r = map_contradictions(
            &[(Pose2::new(f64::NAN, 0.0, 0.0), &scan)],
            &MapCheckParams::default(),
        );
        assert_eq!(r.scans, 0);
    }
}
