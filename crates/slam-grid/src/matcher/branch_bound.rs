//! Branch-and-bound correlative scan matching over a precomputed max-pyramid (Olson, "Real-time
//! correlative scan matching", ICRA 2009, §IV-C; Hess, Kohler, Rapp and Andor, "Real-time
//! loop closure in 2D LIDAR SLAM", ICRA 2016, §V: Cartographer's
//! `FastCorrelativeScanMatcher2D`).
//!
//! The search is global within its window, so it is the tool for loop closures, where the
//! initial guess can be metres and tens of degrees off: a [`MaxPyramid`] of a map region is
//! built once and reused for every scan searched against that region.

pub(crate) use super::levels::Levels;
pub use super::pyramids::MaxPyramid;
use super::{
    check_input, covariance_from_log_likelihood, transform_points, validate_window, MatchResult,
};
use crate::cell::{CellIndex, GridFrame};
use crate::error::{ensure_config, GridError};
use crate::grid::OccupancyGrid;
use crate::scan::RangeData;
use serde::{Deserialize, Serialize};
use slam_models::Pose2;

/// Most rotations searched on each side of the initial heading (as the correlative matcher).
const MAX_ROTATIONS: i32 = 100_000;

/// Most cells of one pyramid level (64 MB of `f32` per level at the bound).
pub const MAX_PYRAMID_CELLS: usize = 16_000_000;

/// Deepest pyramid: the coarsest level's blocks are 2^(depth−1) cells wide.
pub const MAX_PYRAMID_DEPTH: u32 = 12;

/// Branch-and-bound search of a window of poses (Hess et al. 2016, §V, Algorithm 3; Olson
/// 2009, §IV-C) that returns the same optimum as brute force over the same lattice:
///
/// * rotations θ = θ₀ + k·δθ, |k·δθ| ≤ `angular_window`, with δθ chosen (when
///   `angular_step` is 0) so that the farthest end point moves by at most one cell,
///   δθ = acos(1 − r²/(2·d_max²)) (Hess et al. eq. 7);
/// * translations t₀ + (i, j)·r with |i|, |j| ≤ `linear_window` / r rounded to whole cells
///   (r the resolution);
/// * score Σᵢ P₀(cell of R(θ)pᵢ + t₀ + (i, j)), the likelihood field summed over the n end
///   points (the end points are rotated once per θ and the translation moves whole cells).
///
/// The candidates of one rotation are first blocks of 2^(depth−1) × 2^(depth−1) translations
/// scored by the coarsest pyramid level, an upper bound of every translation inside. The
/// search is depth first: children (the four half-size blocks) in order of decreasing bound,
/// and a block is pruned as soon as its bound cannot beat the best exact score found so far,
/// or `min_score`·n. The result is exact because every bound is an upper bound.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct BranchBoundMatcher {
    /// Half-width of the translation window in x and y, metres. Default 1 m.
    pub linear_window: f64,
    /// Half-width of the rotation window, radians. Default 0.5 rad (29°).
    pub angular_window: f64,
    /// Rotation step, radians; 0 chooses it from the scan's farthest end point (see the
    /// type doc). Default 0.
    pub angular_step: f64,
    /// Pyramid levels (1: exhaustive search at full resolution). Default 6, blocks of
    /// 32 × 32 cells at the top.
    pub depth: u32,
    /// Poses whose mean field value per end point is below this are not returned
    /// (a loop-closure acceptance threshold, in [0, 1]). Default 0.
    pub min_score: f64,
    /// Fewer end points than this is an error. Default 10.
    pub min_points: usize,
}

impl Default for BranchBoundMatcher {
    fn default() -> Self {
        Self {
            linear_window: 1.0,
            angular_window: 0.5,
            angular_step: 0.0,
            depth: 6,
            min_score: 0.0,
            min_points: 10,
        }
    }
}

/// One node of the search: a rotation index and a block of translations (lowest offset in
/// cells from the window's centre) with its bound or, at level 0, its exact score.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Candidate {
    pub(crate) rotation: u32,
    pub(crate) dx: i32,
    pub(crate) dy: i32,
    pub(crate) score: f32,
}

/// The search lattice of one scan: its end-point cells for every rotation at the window's
/// centre, rotations θ₀ + k·δθ with |k| ≤ `k_max`, translations in lattice steps (of the
/// levels' stride) up to `half_steps` either way.
pub(crate) struct Lattice {
    pub(crate) dtheta: f64,
    pub(crate) k_max: i32,
    pub(crate) half_steps: i32,
    n: usize,
    cells: Vec<CellIndex>,
    /// The inclusive box of every rotation's cells.
    bounds: Vec<(CellIndex, CellIndex)>,
}

impl Lattice {
    /// The lattice of `points` (robot frame) around `initial` with rotation step `dtheta`
    /// (> 0) and `k_max` rotations per side.
    pub(crate) fn new(
        frame: &GridFrame,
        points: &[slam_models::Point2],
        initial: &Pose2,
        dtheta: f64,
        k_max: f64,
        half_steps: i32,
    ) -> Result<Self, GridError> {
        if k_max > MAX_ROTATIONS as f64 {
            return Err(GridError::InvalidConfig(slam_models::ConfigError::new(
                "branch-and-bound matcher",
                "branch-and-bound rotations per side (angular_window / angular_step)",
                k_max,
                "at most 100000: a larger angular_step or a smaller angular_window",
            )));
        }
        // Without end points there is nothing to place on the lattice (and no box of cells
        // to bound a rotation's score by).
        if points.is_empty() {
            return Err(GridError::TooFewPoints {
                found: 0,
                needed: 1,
            });
        }
        let k_max = k_max as i32;
        let n = points.len();
        let rotations = (2 * k_max + 1) as usize;
        let mut cells = vec![CellIndex::default(); rotations * n];
        let mut bounds = Vec::with_capacity(rotations);
        // Each rotation's cells (`PointCells::cells_at`, vectorised), then their box.
        let arrays = super::PointCells::new(points);
        for (k, out) in (-k_max..=k_max).zip(cells.chunks_mut(n.max(1))) {
            let pose = Pose2::new(initial.x, initial.y, initial.theta + k as f64 * dtheta);
            arrays.cells_at(frame, &pose, out);
            let (mut lo, mut hi) = (
                CellIndex::new(i32::MAX, i32::MAX),
                CellIndex::new(i32::MIN, i32::MIN),
            );
            for c in out.iter() {
                lo = CellIndex::new(lo.x.min(c.x), lo.y.min(c.y));
                hi = CellIndex::new(hi.x.max(c.x), hi.y.max(c.y));
            }
            bounds.push((lo, hi));
        }
        Ok(Self {
            dtheta,
            k_max,
            half_steps,
            n,
            cells,
            bounds,
        })
    }

    /// Rotation `r`'s end-point cells and their inclusive box.
    #[inline]
    fn rotation(&self, r: usize) -> (&[CellIndex], (CellIndex, CellIndex)) {
        (&self.cells[r * self.n..(r + 1) * self.n], self.bounds[r])
    }

    /// The inclusive rectangle of cells the lattice's end points reach with every
    /// translation of up to `half_steps · stride` cells.
    pub(crate) fn reach(&self, stride: i32) -> (CellIndex, CellIndex) {
        let (mut lo, mut hi) = (
            CellIndex::new(i32::MAX, i32::MAX),
            CellIndex::new(i32::MIN, i32::MIN),
        );
        for c in &self.cells {
            lo = CellIndex::new(lo.x.min(c.x), lo.y.min(c.y));
            hi = CellIndex::new(hi.x.max(c.x), hi.y.max(c.y));
        }
        let l = self.half_steps * stride.max(1);
        (
            CellIndex::new(lo.x - l, lo.y - l),
            CellIndex::new(hi.x + l, hi.y + l),
        )
    }
}

impl BranchBoundMatcher {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), GridError> {
        validate_window(self.linear_window, self.angular_window, self.angular_step)?;
        ensure_config(
            (1..=MAX_PYRAMID_DEPTH).contains(&self.depth),
            "depth",
            self.depth as f64,
            "in 1..=12",
        )?;
        ensure_config(
            (0.0..=1.0).contains(&self.min_score),
            "min_score",
            self.min_score,
            "in [0, 1] (mean field value per end point)",
        )
    }

    /// The rotations and the end-point cells of every one of them, translation at `initial`.
    fn lattice(
        &self,
        frame: &GridFrame,
        scan: &RangeData,
        initial: &Pose2,
    ) -> Result<Lattice, GridError> {
        let res = frame.resolution;
        let dtheta = super::rotation_step(self.angular_step, res, scan.max_point_range);
        let k_max = (self.angular_window / dtheta).floor();
        Lattice::new(
            frame,
            &scan.points,
            initial,
            dtheta,
            k_max,
            (self.linear_window / res).round() as i32,
        )
    }

    /// Searches the window around `initial` in a pyramid built beforehand (e.g. of a
    /// submap, reused for many scans); see the type documentation. `Ok(None)` when no pose
    /// scores at least `min_score`.
    ///
    /// The covariance is the crate's sampled fit of the scan likelihood
    /// (PR table 6.3) on the 3×3×3 lattice around the optimum with spacings (r, r, δθ).
    pub fn match_in(
        &self,
        pyramid: &MaxPyramid,
        scan: &RangeData,
        initial: &Pose2,
    ) -> Result<Option<MatchResult>, GridError> {
        self.validate()?;
        if self.depth > pyramid.depth() {
            return Err(GridError::InvalidConfig(slam_models::ConfigError::new(
                "branch-and-bound matcher",
                "depth",
                self.depth as f64,
                "at most the pyramid's depth",
            )));
        }
        if !initial.is_finite() {
            return Err(GridError::NonFinite {
                what: "initial pose",
                value: f64::NAN,
            });
        }
        let frame = pyramid.frame;
        let (u, v) = frame.world_to_continuous(&initial.translation());
        let far = u.abs().max(v.abs())
            + (scan.max_point_range + self.linear_window) / frame.resolution
            + 2.0;
        if far.is_nan() || far > super::MAX_MATCH_CELLS {
            return Err(GridError::OutOfGrid {
                what: "scan matching around the initial pose",
                cells: far,
            });
        }
        if scan.points.len() < self.min_points.max(1) {
            return Err(GridError::TooFewPoints {
                found: scan.points.len(),
                needed: self.min_points.max(1),
            });
        }
        let lat = self.lattice(&frame, scan, initial)?;
        let Some(best) = self.search(pyramid, &lat) else {
            return Ok(None);
        };
        let res = frame.resolution;
        let pose = Pose2::new(
            initial.x + best.dx as f64 * res,
            initial.y + best.dy as f64 * res,
            initial.theta + (best.rotation as i32 - lat.k_max) as f64 * lat.dtheta,
        );
        let params = pyramid.params;
        let covariance = covariance_from_log_likelihood(&pose, [res, res, lat.dtheta], |p| {
            transform_points(&scan.points, p)
                .map(|w| params.log_likelihood(pyramid.value(0, frame.world_to_cell(&w))))
                .sum()
        });
        Ok(Some(MatchResult {
            pose,
            score: best.score as f64 / lat.n as f64,
            covariance,
        }))
    }

    /// Builds the pyramid of the cells the window can reach in `grid` and searches it;
    /// `Ok(None)` when no pose scores at least `min_score`.
    pub fn match_grid(
        &self,
        grid: &OccupancyGrid,
        scan: &RangeData,
        initial: &Pose2,
    ) -> Result<Option<MatchResult>, GridError> {
        self.validate()?;
        check_input(grid, scan, initial, self.min_points, self.linear_window)?;
        let frame = grid.frame();
        let lat = self.lattice(&frame, scan, initial)?;
        let (lo, hi) = lat.reach(1);
        let pyramid = MaxPyramid::new(grid, lo, hi, self.depth)?;
        self.match_in(&pyramid, scan, initial)
    }

    /// Depth-first branch and bound; the best exact candidate scoring at least
    /// `min_score`·n, if any.
    fn search(&self, pyramid: &MaxPyramid, lat: &Lattice) -> Option<Candidate> {
        let threshold = (self.min_score * lat.n as f64) as f32;
        branch_and_bound(
            &pyramid.levels,
            lat,
            self.depth - 1,
            threshold,
            |_, _, _, _| 0.0,
        )
    }
}

/// Depth-first branch and bound over `levels` from level `top` down (Hess et al. 2016,
/// Algorithm 3): the best exact candidate scoring at least `threshold`, if any. A
/// candidate's score is Σ P_level over the end points plus `bonus(rotation, dx, dy,
/// level)`, which must bound from above the exact bonus of every translation in the block
/// at levels above 0 (e.g. a motion prior; 0 for none), so that every bound stays an upper
/// bound and the result exact.
pub(crate) fn branch_and_bound(
    levels: &Levels,
    lat: &Lattice,
    top: u32,
    threshold: f32,
    bonus: impl Fn(u32, i32, i32, u32) -> f32,
) -> Option<Candidate> {
    let step = 1i32 << top;
    let l = lat.half_steps;
    let n_rot = 2 * lat.k_max as usize + 1;
    let mut roots = Vec::new();
    for r in 0..n_rot {
        let (cells, bounds) = lat.rotation(r);
        let mut dy = -l;
        while dy <= l {
            // Four blocks of the row at a time (the same scores as one by one).
            let row: Vec<(i32, i32)> = (-l..=l).step_by(step as usize).map(|dx| (dx, dy)).collect();
            for moves in row.chunks(4) {
                let scores = levels.score4(top, cells, bounds, moves);
                for (&(dx, dy), score) in moves.iter().zip(scores) {
                    roots.push(Candidate {
                        rotation: r as u32,
                        dx,
                        dy,
                        score: score + bonus(r as u32, dx, dy, top),
                    });
                }
            }
            dy += step;
        }
    }
    sort_descending(&mut roots);
    let mut best: Option<Candidate> = None;
    descend(levels, lat, &roots, top, threshold, &bonus, &mut best);
    best
}

/// Visits `candidates` (sorted by decreasing bound, all at `level`) depth first.
fn descend(
    levels: &Levels,
    lat: &Lattice,
    candidates: &[Candidate],
    level: u32,
    threshold: f32,
    bonus: &impl Fn(u32, i32, i32, u32) -> f32,
    best: &mut Option<Candidate>,
) {
    let l = lat.half_steps;
    for c in candidates {
        let beaten = match best {
            Some(b) => c.score <= b.score,
            None => c.score < threshold,
        };
        if beaten {
            // Sorted: every later candidate is bounded by this one's bound.
            return;
        }
        if level == 0 {
            *best = Some(*c);
            continue;
        }
        let half = 1i32 << (level - 1);
        let (cells, bounds) = lat.rotation(c.rotation as usize);
        let mut moves = [(0, 0); 4];
        let mut count = 0;
        for (ox, oy) in [(0, 0), (half, 0), (0, half), (half, half)] {
            let (dx, dy) = (c.dx + ox, c.dy + oy);
            if dx <= l && dy <= l {
                moves[count] = (dx, dy);
                count += 1;
            }
        }
        let scores = levels.score4(level - 1, cells, bounds, &moves[..count]);
        let mut children = [*c; 4];
        for ((child, &(dx, dy)), score) in children.iter_mut().zip(&moves[..count]).zip(scores) {
            *child = Candidate {
                rotation: c.rotation,
                dx,
                dy,
                score: score + bonus(c.rotation, dx, dy, level - 1),
            };
        }
        let children = &mut children[..count];
        sort_descending(children);
        descend(levels, lat, children, level - 1, threshold, bonus, best);
    }
}

/// Sorts by decreasing score; ties keep their order (a stable sort), so the search is
/// deterministic.
fn sort_descending(c: &mut [Candidate]) {
    c.sort_by(|a, b| b.score.total_cmp(&a.score));
}

impl super::ScanMatcher for BranchBoundMatcher {
    /// [`BranchBoundMatcher::match_grid`]; no pose above `min_score` is
    /// [`GridError::NoMatch`].
    fn match_prepared(
        &self,
        grid: &OccupancyGrid,
        scan: &RangeData,
        initial: &Pose2,
    ) -> Result<MatchResult, GridError> {
        self.match_grid(grid, scan, initial)?
            .ok_or(GridError::NoMatch {
                min_score: self.min_score,
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matcher::ScanMatcher;
    use crate::testutil::{office_map, SegmentWorld};

    /// Exactness: the optimum equals brute force over the same lattice, scored
    /// independently with the grid's own field lookups at each pose.
    #[test]
    fn equals_brute_force_on_its_lattice() {
        let g = office_map(0.05);
        let world = SegmentWorld::office();
        let m = BranchBoundMatcher {
            linear_window: 0.3,
            angular_window: 0.04,
            angular_step: 0.01,
            depth: 4,
            ..Default::default()
        };
        for (truth, off) in [
            (Pose2::new(2.5, 3.2, 0.3), (0.13, -0.21, 0.03)),
            (Pose2::new(5.2, 3.8, -1.2), (-0.25, 0.05, -0.02)),
            (Pose2::new(9.5, 2.5, 2.8), (0.02, 0.27, 0.0)),
            (Pose2::new(3.0, 6.3, -2.9), (-0.11, -0.12, 0.04)),
        ] {
            let scan = RangeData::new(
                &world.scan(&truth, 180, std::f64::consts::PI, 30.0),
                &Default::default(),
            )
            .unwrap();
            let initial = Pose2::new(truth.x + off.0, truth.y + off.1, truth.theta + off.2);
            let got = m.match_grid(&g, &scan, &initial).unwrap().unwrap();
            let mut best = f64::NEG_INFINITY;
            for k in -4..=4 {
                for j in -6..=6 {
                    for i in -6..=6 {
                        let p = Pose2::new(
                            initial.x + i as f64 * 0.05,
                            initial.y + j as f64 * 0.05,
                            initial.theta + k as f64 * 0.01,
                        );
                        best = best.max(super::super::mean_field_value(&g, &scan, &p));
                    }
                }
            }
            assert!(
                (got.score - best).abs() < 1e-5,
                "{} vs brute force {best}",
                got.score
            );
            // The returned pose scores what it claims.
            let own = super::super::mean_field_value(&g, &scan, &got.pose);
            assert!((own - got.score).abs() < 1e-5, "{own} vs {}", got.score);
        }
    }

    /// A known offset of 0.8 m and 20° on the simulated office is recovered to within a
    /// cell and an angular step, with a positive-definite covariance, from a pyramid built
    /// once over the whole map and reused; the compact pyramid finds the same pose and score.
    #[test]
    fn recovers_a_known_offset() {
        let res = 0.05;
        let g = office_map(res);
        let world = SegmentWorld::office();
        let pyramid = MaxPyramid::covering(&g, 6).unwrap().unwrap();
        let (min, max) = g.covered_cells().unwrap();
        let compact = MaxPyramid::new_compact(&g, min, max, 6).unwrap();
        let m = BranchBoundMatcher {
            linear_window: 1.0,
            angular_window: 0.45,
            ..Default::default()
        };
        for truth in [
            Pose2::new(2.5, 3.2, 0.3),
            Pose2::new(8.7, 6.5, -2.0),
            Pose2::new(10.0, 3.0, 1.6),
        ] {
            let scan = RangeData::new(
                &world.scan(&truth, 361, std::f64::consts::PI, 30.0),
                &Default::default(),
            )
            .unwrap();
            let initial = Pose2::new(truth.x - 0.6, truth.y + 0.53, truth.theta - 0.35);
            let r = m.match_in(&pyramid, &scan, &initial).unwrap().unwrap();
            // The compact pyramid finds the same best pose and score.
            let c = m.match_in(&compact, &scan, &initial).unwrap().unwrap();
            assert_eq!((c.pose, c.score), (r.pose, r.score));
            let dtheta = slam_models::normalize_angle(r.pose.theta - truth.theta).abs();
            assert!(
                r.pose.distance(&truth) < 1.5 * res,
                "{:?} vs {truth:?}",
                r.pose
            );
            assert!(dtheta < 0.02, "{dtheta} rad");
            assert!(r.score > 0.8, "score {}", r.score);
            let eig = r.covariance.symmetric_eigen().eigenvalues;
            assert!(eig.min() > 0.0, "{eig:?}");
            // The same search through the ScanMatcher trait (pyramid of the window only).
            let via_trait = m.match_prepared(&g, &scan, &initial).unwrap();
            assert_eq!(via_trait.pose, r.pose);
        }
    }

    /// A threshold no pose reaches gives `None` (and `NoMatch` through the trait); a bad
    /// depth is a configuration error.
    #[test]
    fn threshold_and_config_errors() {
        let g = office_map(0.1);
        let world = SegmentWorld::office();
        let truth = Pose2::new(2.5, 3.2, 0.3);
        let scan = RangeData::new(
            &world.scan(&truth, 181, std::f64::consts::PI, 30.0),
            &Default::default(),
        )
        .unwrap();
        // Far from the map, nothing scores above the far value.
        let lost = Pose2::new(50.0, 50.0, 0.0);
        let m = BranchBoundMatcher {
            min_score: 0.5,
            ..Default::default()
        };
        assert_eq!(m.match_grid(&g, &scan, &lost).unwrap(), None);
        assert!(matches!(
            m.match_prepared(&g, &scan, &lost),
            Err(GridError::NoMatch { .. })
        ));
        let bad = BranchBoundMatcher {
            depth: 0,
            ..Default::default()
        };
        let err = bad.match_grid(&g, &scan, &truth).unwrap_err();
        assert!(err.to_string().contains("depth"), "{err}");
        let pyramid = MaxPyramid::covering(&g, 3).unwrap().unwrap();
        assert!(m.match_in(&pyramid, &scan, &truth).is_err());
    }
}
