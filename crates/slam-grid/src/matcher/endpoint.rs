//! The truncated endpoint model on the incremental distance field: the scorer, hill
//! climber and exhaustive grid search of grid FastSLAM's scan matching.
//!
//! A prepared scan's end points are in the robot frame ([`RangeData`]); every pose
//! evaluation is then one rotation and translation per beam and a bilinear look-up in a
//! grid's incrementally repaired distance field ([`DistanceField`]), with no trigonometry
//! per beam (GMapping recomputes sin/cos and rounding for every beam of every evaluation).
//!
//! Endpoint model (PR §6.4, "likelihood field"): a beam ending at distance d from the
//! nearest occupied cell contributes ln p = −min(d, r)²/(2σ²) (the truncation r is the
//! outlier floor). The scan's log-likelihood is Σ ln p divided by the gain g (GMapping's
//! `ogain`). Unlike the lazy field's mean value s̄ the other matchers score, this is a
//! log-likelihood, which a particle filter needs for its weights and for the Gaussian fit
//! of the improved proposal (Grisetti et al. 2007, eqs. 14–16).
//!
//! Two truncations, coarse to fine, are the caller's choice: the coarse search and the hill
//! climber's coarse phase score with a wide r (`capture`, e.g. the field's full reach) so
//! that a pose several centimetres off still feels the walls; the fine phase with the
//! model's own r, so that beams ending on clutter pull the mode less.

use super::branch_bound::{branch_and_bound, Lattice, Levels};
use super::hill_climb::{climb, Climb};
use super::levels::Storage;
use super::pyramids::MinPyramid;
use super::MAX_PYRAMID_DEPTH;
use crate::cell::CellIndex;
use crate::error::{ensure_config, GridError};
use crate::grid::distance::DistanceField;
use crate::grid::tiles::{TILE_BITS, TILE_CELLS, TILE_SIZE};
use crate::scan::RangeData;
use slam_models::{Matrix3, Point2, Pose2, Vector3};

/// The parameters of the truncated endpoint model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EndpointModel {
    /// 1/(2σ²·g), per m².
    pub k: f64,
    /// Truncation r, metres: distances beyond it count as r (at most the field's reach).
    pub radius: f64,
    /// The gain g itself: `g ·` an [`EndpointScore::log_likelihood`] is the untempered
    /// Σ ln p.
    pub gain: f64,
}

impl EndpointModel {
    /// The model with standard deviation `sigma` (metres), truncation `radius` (metres) and
    /// gain `gain` (≥ 1 tempers the scan's likelihood): k = 1/(2σ²·g).
    pub fn new(sigma: f64, radius: f64, gain: f64) -> Self {
        Self {
            k: 1.0 / (2.0 * sigma * sigma * gain),
            radius,
            gain,
        }
    }
}

/// The score of one pose: Σ ln p / g, and how many end points ended within the
/// truncation r (the beams that "find the map").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EndpointScore {
    /// Σ −min(d, r)²·k over the end points.
    pub log_likelihood: f64,
    /// End points closer than r to an obstacle.
    pub inliers: usize,
}

/// Sub-cell position bits of [`score`]'s fixed-point coordinates (1/1024 cell).
const FRAC_BITS: u32 = 10;
/// One cell in those coordinates.
const ONE: i32 = 1 << FRAC_BITS;
/// 1.5·2⁵²: for |x| < 2⁵¹, the low 32 bits of `(x + MAGIC).to_bits()` are x rounded to the
/// nearest integer, in two's complement (the sum's exponent is fixed, so its mantissa holds
/// the integer): a float-to-integer rounding without the saturation checks of `as`, which
/// vectorises.
const MAGIC: f64 = 6_755_399_441_055_744.0;
/// Fixed-point coordinates are clamped to ±2³⁰ (±2²⁰ cells, far beyond any grid's
/// [`crate::MAX_MAP_EXTENT_CELLS`]) before the rounding: an end point off the map reads as
/// far, never wraps.
const FIXED_LIMIT: f64 = (1 << 30) as f64;
/// End points per block of [`score`]: its buffers stay in L1 (64 · 12 bytes).
const BLOCK: usize = 64;
/// Partial sums of [`score`] (lanes a compiler can keep in vector registers).
const LANES: usize = 8;

/// Scores the robot-frame end points `points` at `pose` (bilinear interpolation of the
/// distance field between the four cell centres around each end point).
///
/// The filter's hottest code (two thirds of a grid FastSLAM run), written so that the
/// arithmetic vectorises and only the table reads are per end point. In blocks of 64 end
/// points, three passes:
///
/// 1. the rotation and translation (sine and cosine once per pose) to cell-centre
///    coordinates rounded to 1/1024 cell (0.05 mm at 5 cm cells), as integers;
/// 2. per end point, the cell (a shift) and its four stored distances (whole units of
///    1/16 cell); the tile of the previous end point is kept (consecutive end points mostly
///    share a 32×32 tile) and the corner indices are masked into it, so that no bounds
///    check is needed;
/// 3. the bilinear blend with weights k/1024 (exact in f32), the truncation at r, the
///    square and the sum, in f32 over eight partial sums in a fixed order (the same bytes
///    on every run), then scaled to metres in f64.
///
/// Against the continuous model ([`score_reference`], the test's reference) this rounds each end
/// point's position by at most 1/2048 cell per axis, which moves its distance by at most
/// 17/2048 unit per axis (the stored field changes by at most 17 units between
/// neighbouring cells), and sums in f32 (relative error ≈ 10⁻⁷ per addition).
pub fn score(
    field: &DistanceField<'_>,
    points: &[Point2],
    pose: &Pose2,
    model: &EndpointModel,
) -> EndpointScore {
    let frame = field.frame();
    let inv = 1.0 / frame.resolution;
    let unit = field.metres_per_unit();
    let one = ONE as f64;
    let (s, c) = pose.theta.sin_cos();
    let (s, c) = (s * inv * one, c * inv * one);
    let (tx, ty) = (
        ((pose.x - frame.origin.x) * inv - 0.5) * one,
        ((pose.y - frame.origin.y) * inv - 0.5) * one,
    );
    // The truncation r and the inlier bound in distance units (f32: the comparisons are
    // with f32 blends).
    let r = (model.radius / unit) as f32;
    let r_in = (model.radius * 0.999 / unit) as f32;
    let mut sums = [0.0f32; LANES];
    let mut inliers = [0u32; LANES];
    let mut reader = CornerReader::new(field);
    let mut qu = [0i32; BLOCK];
    let mut qv = [0i32; BLOCK];
    let mut d = [[0u8; BLOCK]; 4];
    let mut padding = 0;
    for block in points.chunks(BLOCK) {
        let n = block.len();
        // 1. Fixed-point cell-centre coordinates (cell (i, j) has its centre at (i, j)).
        // (NaN, from a NaN pose, stays NaN, whose low bits read as cell 0: no panic.)
        let fixed = |x: f64| (x.clamp(-FIXED_LIMIT, FIXED_LIMIT) + MAGIC).to_bits() as i32;
        for ((p, u), v) in block.iter().zip(&mut qu).zip(&mut qv) {
            *u = fixed(c * p.x - s * p.y + tx);
            *v = fixed(s * p.x + c * p.y + ty);
        }
        // 2. The four corners' distances.
        for (k, (&u, &v)) in qu[..n].iter().zip(&qv[..n]).enumerate() {
            let (iu, iv) = (u >> FRAC_BITS, v >> FRAC_BITS);
            let corners = reader.read(iu, iv);
            for (column, value) in d.iter_mut().zip(corners) {
                column[k] = value;
            }
        } // 3. Blend, truncate, square and sum, LANES end points at a time; the block's tail
          //    is padded with end points on an obstacle (distance 0: they add nothing to the
          //    sum and one inlier each, taken off below).
        let padded = n.next_multiple_of(LANES).min(BLOCK);
        for k in n..padded {
            (qu[k], qv[k]) = (0, 0);
            d.iter_mut().for_each(|column| column[k] = 0);
        }
        let scale = 1.0 / one as f32;
        let frac = |q: i32| (q & (ONE - 1)) as f32 * scale;
        // Groups of LANES as fixed-size arrays, so that the lanes need no bounds checks and
        // the loop vectorises (the same operations per lane, in the same order).
        let group = |column: &[u8], g: usize| -> [u8; LANES] {
            std::array::from_fn(|l| column[(g + l) & (BLOCK - 1)])
        };
        for g in (0..padded).step_by(LANES) {
            let (qu8, qv8): ([i32; LANES], [i32; LANES]) = (
                std::array::from_fn(|l| qu[(g + l) & (BLOCK - 1)]),
                std::array::from_fn(|l| qv[(g + l) & (BLOCK - 1)]),
            );
            let (c0, c1, c2, c3) = (
                group(&d[0], g),
                group(&d[1], g),
                group(&d[2], g),
                group(&d[3], g),
            );
            for l in 0..LANES {
                let (au, av) = (frac(qu8[l]), frac(qv8[l]));
                let (d00, d10) = (c0[l] as f32, c1[l] as f32);
                let (d01, d11) = (c2[l] as f32, c3[l] as f32);
                let d0 = d00 + au * (d10 - d00);
                let d1 = d01 + au * (d11 - d01);
                let dm = (d0 + av * (d1 - d0)).min(r);
                inliers[l] += u32::from(dm < r_in);
                sums[l] += dm * dm;
            }
        }
        padding += padded - n;
    }
    // The lanes in a fixed order, in f64.
    let total: f64 = sums.iter().map(|&v| v as f64).sum();
    EndpointScore {
        log_likelihood: -model.k * total * unit * unit,
        inliers: inliers.iter().map(|&v| v as usize).sum::<usize>()
            - padding * usize::from(0.0 < r_in),
    }
}

/// The same score as [`score`] in f64 throughout, the end point's continuous position and
/// one running sum in the order of the end points: the reference [`score`] is tested and
/// benchmarked against (the scorer before issue 21's speed work; it does not vectorise).
pub fn score_reference(
    field: &DistanceField<'_>,
    points: &[Point2],
    pose: &Pose2,
    model: &EndpointModel,
) -> EndpointScore {
    let frame = field.frame();
    let inv = 1.0 / frame.resolution;
    let unit = field.metres_per_unit();
    let (s, c) = pose.theta.sin_cos();
    let (tx, ty) = (
        (pose.x - frame.origin.x) * inv - 0.5,
        (pose.y - frame.origin.y) * inv - 0.5,
    );
    let (s, c) = (s * inv, c * inv);
    let mut sum = 0.0;
    let mut inliers = 0;
    let r_in = model.radius * 0.999;
    let mut reader = CornerReader::new(field);
    for p in points {
        // Cell-centre coordinates: cell (i, j) has its centre at (i, j).
        let u = c * p.x - s * p.y + tx;
        let v = s * p.x + c * p.y + ty;
        let (iu, iv) = (fast_floor(u), fast_floor(v));
        let (au, av) = (u - iu as f64, v - iv as f64);
        let d = reader.read(iu, iv);
        let d0 = d[0] as f64 + au * (d[1] as f64 - d[0] as f64);
        let d1 = d[2] as f64 + au * (d[3] as f64 - d[2] as f64);
        let dm = ((d0 + av * (d1 - d0)) * unit).min(model.radius);
        if dm < r_in {
            inliers += 1;
        }
        sum += dm * dm;
    }
    EndpointScore {
        log_likelihood: -model.k * sum,
        inliers,
    }
}

/// Reads the four distances around a cell for the scorers, keeping the tile of the previous
/// end point (consecutive beams mostly end in the same tile).
struct CornerReader<'f, 'a> {
    field: &'f DistanceField<'a>,
    /// The tile of the previous end point and its cells (`None`: all far).
    key: (i32, i32),
    cells: Option<&'a [u8; TILE_CELLS]>,
    far: [u8; 4],
}

impl<'f, 'a> CornerReader<'f, 'a> {
    fn new(field: &'f DistanceField<'a>) -> Self {
        let key = (i32::MIN, i32::MIN);
        CornerReader {
            field,
            key,
            cells: field.tile_cells(key.0, key.1),
            far: [field.max_units(); 4],
        }
    }

    /// The distances at cells (iu, iv), (iu + 1, iv), (iu, iv + 1), (iu + 1, iv + 1).
    #[inline(always)]
    fn read(&mut self, iu: i32, iv: i32) -> [u8; 4] {
        const MASK: i32 = TILE_SIZE as i32 - 1;
        const LAST: usize = TILE_CELLS - 1;
        if (iu & MASK) == MASK || (iv & MASK) == MASK {
            return self.field.dist4(CellIndex::new(iu, iv));
        }
        // All four corners in one tile.
        let t = (iu >> TILE_BITS, iv >> TILE_BITS);
        if t != self.key {
            self.key = t;
            self.cells = self.field.tile_cells(t.0, t.1);
        }
        match self.cells {
            Some(cells) => {
                let i = ((iv & MASK) as usize) * TILE_SIZE + (iu & MASK) as usize;
                // i + TILE_SIZE + 1 ≤ LAST here: the masks only drop the bounds checks.
                [
                    cells[i & LAST],
                    cells[(i + 1) & LAST],
                    cells[(i + TILE_SIZE) & LAST],
                    cells[(i + TILE_SIZE + 1) & LAST],
                ]
            }
            None => self.far,
        }
    }
}

/// ⌊x⌋ as an integer without a libm call (x well inside the i32 range; NaN maps to 0).
#[inline(always)]
fn fast_floor(x: f64) -> i32 {
    let i = x as i32;
    i - ((i as f64) > x) as i32
}

/// The score of every matching point of `scan` at `pose`.
#[inline]
pub fn score_scan(
    field: &DistanceField<'_>,
    scan: &RangeData,
    pose: &Pose2,
    model: &EndpointModel,
) -> EndpointScore {
    score(field, &scan.points, pose, model)
}

/// The log-likelihood of the coarse subset ([`RangeData::coarse_points`]) at `pose`, for
/// choosing between starting points.
pub fn coarse_score(
    field: &DistanceField<'_>,
    scan: &RangeData,
    pose: &Pose2,
    model: &EndpointModel,
) -> f64 {
    score(field, scan.coarse_points(), pose, model).log_likelihood
}

/// A matched pose and its score.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EndpointMatch {
    /// The pose (world frame).
    pub pose: Pose2,
    /// Its score under the fine model.
    pub score: EndpointScore,
}

/// Hill-climbing parameters (GMapping's `lstep`, `astep`, `iterations`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HillClimbSteps {
    /// Initial translation step, metres.
    pub linear_step: f64,
    /// Initial rotation step, radians.
    pub angular_step: f64,
    /// Step halvings before stopping.
    pub refinements: usize,
}

/// Most iterations (tries of the six moves) of one [`hill_climb`]: a hard cap that keeps
/// pathological inputs bounded (≈ GMapping's ~121 evaluations).
const CLIMB_BUDGET: u32 = 64;

/// GMapping-style hill climbing from `initial` (the crate's climber, Grisetti et al. 2007
/// §VI) in two phases: while the steps are at least a quarter of the initial ones, the
/// coarse subset scores under `capture` (4× cheaper evaluations, the wide truncation's
/// capture range); then every point under `model`, which also scores the result.
pub fn hill_climb(
    field: &DistanceField<'_>,
    scan: &RangeData,
    initial: &Pose2,
    capture: &EndpointModel,
    model: &EndpointModel,
    steps: &HillClimbSteps,
) -> EndpointMatch {
    let mut c = Climb {
        pose: *initial,
        linear_step: steps.linear_step,
        angular_step: steps.angular_step,
        halvings: 0,
        budget: CLIMB_BUDGET,
    };
    let refinements = u32::try_from(steps.refinements).unwrap_or(u32::MAX);
    if scan.has_coarse_subset() {
        let points = &scan.coarse[..];
        let start = score(field, points, &c.pose, capture);
        climb(
            &mut c,
            2.min(refinements),
            start,
            |s| s.log_likelihood,
            |p| score(field, points, p, capture),
        );
    }
    let start = score(field, &scan.points, &c.pose, model);
    let best = climb(
        &mut c,
        refinements.saturating_add(1),
        start,
        |s| s.log_likelihood,
        |p| score(field, &scan.points, p, model),
    );
    EndpointMatch {
        pose: c.pose,
        score: best,
    }
}

/// The window of [`grid_search`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SearchWindow {
    /// ± this in x and y around the initial pose, metres.
    pub range_xy: f64,
    /// Translation step, metres (> 0).
    pub step_xy: f64,
    /// ± this in θ, radians.
    pub range_theta: f64,
    /// Rotation step, radians (> 0).
    pub step_theta: f64,
    /// R⁻¹, the inverse of the motion model's covariance at the initial pose (the prior).
    pub information: Matrix3,
}

impl SearchWindow {
    /// The log motion prior −½ eᵀR⁻¹e of `candidate` = `initial` ⊕ δ, with
    /// e = (x − x₀, y − y₀, δθ): it keeps ambiguous directions (corridors) at the
    /// prediction.
    #[inline]
    pub fn log_prior(&self, initial: &Pose2, candidate: &Pose2, dtheta: f64) -> f64 {
        let e = Vector3::new(candidate.x - initial.x, candidate.y - initial.y, dtheta);
        -0.5 * e.dot(&(self.information * e))
    }
}

/// Coarse search (Olson's correlative matching, ICRA 2009, at one coarse resolution) over
/// the poses `initial` ⊕ (dx, dy, dθ) with |dx|, |dy| ≤ `range_xy` in steps of `step_xy`
/// and |dθ| ≤ `range_theta` in steps of `step_theta`, scored with the coarse subset (times
/// the subsampling factor) plus the log motion prior −½ eᵀR⁻¹e: the mode of likelihood ×
/// motion model on the lattice. Returns the best pose (the initial pose wins ties, then the
/// first in the order of [`grid_search_exhaustive`]).
///
/// The result is that of [`grid_search_exhaustive`], bit for bit, found by branch and bound
/// (Olson 2009, §IV-C) on the same objective: each rotation's block of translations is
/// split in four until single poses, which are scored exactly as the exhaustive search does.
/// A block's bound takes, per end point, the least distance over the cells any of its poses
/// reads (from a min-pyramid of the distance field, built once per search over the cells
/// the window reaches: a few look-ups per end point and block), since a
/// bilinear blend is never below its smallest corner and min(d, r)² grows with d; and the
/// prior's maximum over the block bounded by its tangent plane at the block's centre (less
/// the curvature's negative part, should R⁻¹ not be positive semi-definite). A block is dropped only when its bound is below the best score found
/// so far (less a relative 10⁻⁵ for rounding: the bounds sum in f64, [`score`] in f32),
/// so no pose that could win is skipped.
///
/// Falls back to the exhaustive search when the window reaches more than 4·10⁶ cells or
/// the input is not finite.
pub fn grid_search(
    field: &DistanceField<'_>,
    scan: &RangeData,
    initial: &Pose2,
    model: &EndpointModel,
    window: &SearchWindow,
) -> Pose2 {
    match CoarseSearch::new(field, scan, initial, model, window) {
        Some(search) => search.run(),
        None => grid_search_exhaustive(field, scan, initial, model, window),
    }
}

/// The exhaustive form of [`grid_search`]: every pose of the lattice scored, in the order
/// rotation, then y, then x (each from the most negative offset), the initial pose first;
/// a later pose replaces the best only with a strictly higher score. The reference the
/// branch-and-bound search is tested against, and its fallback.
pub fn grid_search_exhaustive(
    field: &DistanceField<'_>,
    scan: &RangeData,
    initial: &Pose2,
    model: &EndpointModel,
    window: &SearchWindow,
) -> Pose2 {
    let points = scan.coarse_points();
    let mut best = *initial;
    let scale = scan.points.len() as f64 / points.len().max(1) as f64;
    let mut top = scale * score(field, points, initial, model).log_likelihood;
    let nxy = (window.range_xy / window.step_xy).floor() as i32;
    let nth = (window.range_theta / window.step_theta).floor() as i32;
    for it in -nth..=nth {
        for iy in -nxy..=nxy {
            for ix in -nxy..=nxy {
                if ix == 0 && iy == 0 && it == 0 {
                    continue;
                }
                let (cand, s) =
                    lattice_score(field, points, scale, initial, model, window, ix, iy, it);
                if s > top {
                    top = s;
                    best = cand;
                }
            }
        }
    }
    best
}

/// The pose `initial` ⊕ (ix·step_xy, iy·step_xy, it·step_theta) and its coarse-search
/// objective: one expression for both searches, so that they agree to the bit.
#[inline]
#[allow(clippy::too_many_arguments)]
fn lattice_score(
    field: &DistanceField<'_>,
    points: &[Point2],
    scale: f64,
    initial: &Pose2,
    model: &EndpointModel,
    window: &SearchWindow,
    ix: i32,
    iy: i32,
    it: i32,
) -> (Pose2, f64) {
    let delta = Pose2::new(
        ix as f64 * window.step_xy,
        iy as f64 * window.step_xy,
        it as f64 * window.step_theta,
    );
    let cand = initial.compose(&delta);
    let prior = window.log_prior(initial, &cand, delta.theta);
    (
        cand,
        scale * score(field, points, &cand, model).log_likelihood + prior,
    )
}

/// Cells by which the boxes of the coarse search's bounds are widened on each side of the
/// continuous positions they are computed from, so that a rounding difference against
/// [`score`]'s own arithmetic never leaves a read cell out: [`score`] rounds each end
/// point to 1/1024 cell (up to 1/2048 ≈ 4.9·10⁻⁴ cells away), so the margin is twice that.
const BOX_MARGIN: f64 = 1e-3;

/// Relative tolerance below the best score under which a block is pruned: [`score`] sums
/// its squared distances in f32 lanes (within 10⁻⁶ of the total, its test says), the
/// bounds in f64, so a bound may sit that much below a score it bounds.
const PRUNE_TOLERANCE: f64 = 1e-5;

/// Most translation steps per side for the branch-and-bound coarse search (the config allows
/// 50); beyond, brute force.
const MAX_COARSE_STEPS: i32 = 1 << 10;

/// One branch-and-bound [`grid_search`]: the lattice, the end points at every rotation in
/// continuous cell coordinates, and the distance pyramid over the cells they reach.
struct CoarseSearch<'a, 'f> {
    field: &'a DistanceField<'f>,
    points: &'a [Point2],
    initial: &'a Pose2,
    model: &'a EndpointModel,
    window: &'a SearchWindow,
    scale: f64,
    nxy: i32,
    nth: i32,
    /// One translation step in x and in y of the lattice (rotated by the initial heading),
    /// in cells and in metres.
    step_cells: [(f64, f64); 2],
    step_world: [(f64, f64); 2],
    /// (u, v) of every end point, rotation by rotation, at translation (0, 0): the
    /// continuous coordinates [`score`] floors (cell (i, j) centred on (i, j)).
    rotated: Vec<(f64, f64)>,
    /// R⁻¹ + R⁻ᵀ: the gradient of eᵀR⁻¹e is this times e.
    info2: Matrix3,
    /// The least eigenvalue of `info2` (eᵀR⁻¹e is convex when it is ≥ 0).
    curvature: f64,
    pyramid: MinPyramid,
    /// Side of the top block of translations (a power of two ≥ 2·nxy + 1).
    top_size: i32,
}

/// The best pose found so far: score, position in the exhaustive search's order (−1 for
/// the initial pose), pose.
struct Best {
    score: f64,
    order: i64,
    pose: Pose2,
}

impl<'a, 'f> CoarseSearch<'a, 'f> {
    /// The search, or `None` when the branch-and-bound form does not apply (see
    /// [`grid_search`]).
    fn new(
        field: &'a DistanceField<'f>,
        scan: &'a RangeData,
        initial: &'a Pose2,
        model: &'a EndpointModel,
        window: &'a SearchWindow,
    ) -> Option<Self> {
        let frame = field.frame();
        let res = frame.resolution;
        let steps_xy = window.range_xy / window.step_xy;
        let steps_theta = window.range_theta / window.step_theta;
        let finite = initial.is_finite()
            && window.information.iter().all(|v| v.is_finite())
            && model.k.is_finite()
            && model.radius.is_finite();
        if !(finite
            && window.step_xy > 0.0
            && window.step_theta > 0.0
            && (0.0..MAX_COARSE_STEPS as f64).contains(&steps_xy)
            && (0.0..MAX_COARSE_STEPS as f64).contains(&steps_theta))
        {
            return None;
        }
        let info2 = window.information + window.information.transpose();
        let curvature = info2.symmetric_eigenvalues().min();
        if !curvature.is_finite() {
            return None;
        }
        let points = scan.coarse_points();
        let scale = scan.points.len() as f64 / points.len().max(1) as f64;
        let nxy = steps_xy.floor() as i32;
        let nth = steps_theta.floor() as i32;
        let (s0, c0) = initial.theta.sin_cos();
        let step = window.step_xy;
        let step_world = [(c0 * step, s0 * step), (-s0 * step, c0 * step)];
        let step_cells = [
            (step_world[0].0 / res, step_world[0].1 / res),
            (step_world[1].0 / res, step_world[1].1 / res),
        ];
        // As `score` computes them.
        let inv = 1.0 / res;
        let mut rotated = Vec::with_capacity((2 * nth as usize + 1) * points.len());
        for it in -nth..=nth {
            let pose = initial.compose(&Pose2::new(0.0, 0.0, it as f64 * window.step_theta));
            let (s, c) = pose.theta.sin_cos();
            let (s, c) = (s * inv, c * inv);
            let tx = (pose.x - frame.origin.x) * inv - 0.5;
            let ty = (pose.y - frame.origin.y) * inv - 0.5;
            rotated.extend(
                points
                    .iter()
                    .map(|p| (c * p.x - s * p.y + tx, s * p.x + c * p.y + ty)),
            );
        }
        let top_size = (2 * nxy as u32 + 1).next_power_of_two() as i32;
        let mut search = Self {
            field,
            points,
            initial,
            model,
            window,
            scale,
            nxy,
            nth,
            step_cells,
            step_world,
            rotated,
            info2,
            curvature,
            // Replaced below, once the reach is known.
            pyramid: MinPyramid::build(CellIndex::new(0, 0), CellIndex::new(0, 0), 0, 0, |_, _| {})
                .ok()?,
            top_size,
        };
        // The cells the top blocks read, over every rotation.
        let ext = search.extent(-nxy, -nxy, top_size);
        let (mut lo, mut hi) = (
            CellIndex::new(i32::MAX, i32::MAX),
            CellIndex::new(i32::MIN, i32::MIN),
        );
        for &(u, v) in &search.rotated {
            let (a, b) = cell_box(u, v, &ext);
            lo = CellIndex::new(lo.x.min(a.x), lo.y.min(a.y));
            hi = CellIndex::new(hi.x.max(b.x), hi.y.max(b.y));
        }
        if search.rotated.is_empty() {
            return None;
        }
        // Squares up to the top box's shorter side; every box is at least two cells wide
        // (the floor and the cell beyond), so level 0 is never read.
        let side = ((ext[1] - ext[0]).min(ext[3] - ext[2]) + 1.0).max(1.0);
        let top = (side.log2().floor() as u32).min(MAX_PYRAMID_DEPTH - 1);
        search.pyramid = MinPyramid::build(lo, hi, top.min(1), top, |start, row| {
            field.read_row(start, row)
        })
        .ok()?;
        Some(search)
    }

    /// The offsets (u_lo, u_hi, v_lo, v_hi), in cells, spanned by the translations of the
    /// block [i0, i0 + size) × [j0, j0 + size) clipped to the window.
    fn extent(&self, i0: i32, j0: i32, size: i32) -> [f64; 4] {
        let i1 = (i0 + size - 1).min(self.nxy);
        let j1 = (j0 + size - 1).min(self.nxy);
        let [a, b] = self.step_cells;
        let mut e = [
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for (i, j) in [(i0, j0), (i1, j0), (i0, j1), (i1, j1)] {
            let (i, j) = (i as f64, j as f64);
            let (u, v) = (i * a.0 + j * b.0, i * a.1 + j * b.1);
            e = [e[0].min(u), e[1].max(u), e[2].min(v), e[3].max(v)];
        }
        e
    }

    /// An upper bound of the objective over rotation `it`'s block of translations
    /// [i0, i0 + size) × [j0, j0 + size) (clipped to the window). The sum over the end
    /// points stops early once the bound falls below `cutoff` (the block is then pruned
    /// anyway): every partial sum is itself an upper bound, since each term only lowers it.
    fn bound(&self, it: i32, i0: i32, j0: i32, size: i32, cutoff: f64) -> f64 {
        let ext = self.extent(i0, j0, size);
        let n = self.points.len();
        let first = (it + self.nth) as usize * n;
        let unit = self.field.metres_per_unit();
        let radius = self.model.radius;
        let prior = self.prior_bound(it, i0, j0, size);
        let mut sum = 0.0;
        for chunk in self.rotated[first..first + n].chunks(8) {
            for &(u, v) in chunk {
                let (lo, hi) = cell_box(u, v, &ext);
                let dm = (self.pyramid.min_over(lo, hi) as f64 * unit).min(radius);
                sum += dm * dm;
            }
            let bound = self.scale * (-self.model.k * sum) + prior;
            if bound < cutoff {
                return bound;
            }
        }
        self.scale * (-self.model.k * sum) + prior
    }

    /// The bound below which a block is pruned (see [`CoarseSearch::prunes`]).
    #[inline]
    fn cutoff(best: &Best) -> f64 {
        best.score - PRUNE_TOLERANCE * (1.0 + best.score.abs())
    }

    /// The log prior's maximum over the block, bounded from above: for q(e) = eᵀR⁻¹e,
    /// q ≥ q(e_c) + ∇q(e_c)·Δ + ½λ|Δ|² (λ the least eigenvalue of R⁻¹ + R⁻ᵀ, Δ = e − e_c)
    /// ≥ q(e_c) − |∇q·a|·h_i − |∇q·b|·h_j − ½·max(0, −λ)·(h_i² + h_j²)·step² over the
    /// block, e_c its centre, a and b the lattice steps, h_i and h_j its half-widths in
    /// steps; and q ≥ 0 when λ ≥ 0.
    fn prior_bound(&self, it: i32, i0: i32, j0: i32, size: i32) -> f64 {
        let i1 = (i0 + size - 1).min(self.nxy);
        let j1 = (j0 + size - 1).min(self.nxy);
        let (ci, cj) = ((i0 + i1) as f64 * 0.5, (j0 + j1) as f64 * 0.5);
        let [a, b] = self.step_world;
        let e = Vector3::new(
            ci * a.0 + cj * b.0,
            ci * a.1 + cj * b.1,
            it as f64 * self.window.step_theta,
        );
        let q = e.dot(&(self.window.information * e));
        let g = self.info2 * e;
        let (hi, hj) = ((i1 - i0) as f64 * 0.5, (j1 - j0) as f64 * 0.5);
        let slope = (g[0] * a.0 + g[1] * a.1).abs() * hi + (g[0] * b.0 + g[1] * b.1).abs() * hj;
        let lower = if self.curvature >= 0.0 {
            (q - slope).max(0.0)
        } else {
            let step2 = self.window.step_xy * self.window.step_xy;
            q - slope + 0.5 * self.curvature * (hi * hi + hj * hj) * step2
        };
        -0.5 * lower
    }

    /// The exhaustive search's result, by branch and bound.
    fn run(&self) -> Pose2 {
        let initial_score =
            self.scale * score(self.field, self.points, self.initial, self.model).log_likelihood;
        let mut best = Best {
            score: initial_score,
            order: -1,
            pose: *self.initial,
        };
        let (lo, size) = (-self.nxy, self.top_size);
        let mut rotations: Vec<(f64, i32)> = (-self.nth..=self.nth)
            .map(|it| (self.bound(it, lo, lo, size, Self::cutoff(&best)), it))
            .collect();
        rotations.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        for (bound, it) in rotations {
            if self.prunes(bound, &best) {
                break;
            }
            self.descend(it, lo, lo, size, &mut best);
        }
        best.pose
    }

    /// True when a block bounded by `bound` cannot hold a pose that beats or ties `best`.
    #[inline]
    fn prunes(&self, bound: f64, best: &Best) -> bool {
        bound < Self::cutoff(best)
    }

    /// Depth first through rotation `it`'s block at (i0, j0) of `size` × `size`
    /// translations: the four sub-blocks in order of decreasing bound, single poses scored.
    fn descend(&self, it: i32, i0: i32, j0: i32, size: i32, best: &mut Best) {
        // A window of one translation (`range_xy` below `step_xy`: a search over headings
        // only) has a top block of a single pose, which is a leaf: halving it would give
        // blocks of size 0 and recurse without end.
        if size <= 1 {
            if i0 <= self.nxy && j0 <= self.nxy {
                self.leaf(it, i0, j0, best);
            }
            return;
        }
        let half = size / 2;
        let mut children = [(f64::NEG_INFINITY, 0, 0); 4];
        let mut n = 0;
        for (i, j) in [
            (i0, j0),
            (i0 + half, j0),
            (i0, j0 + half),
            (i0 + half, j0 + half),
        ] {
            if i > self.nxy || j > self.nxy {
                continue;
            }
            if half == 1 {
                self.leaf(it, i, j, best);
            } else {
                children[n] = (self.bound(it, i, j, half, Self::cutoff(best)), i, j);
                n += 1;
            }
        }
        let children = &mut children[..n];
        children.sort_by(|a, b| b.0.total_cmp(&a.0));
        for &(bound, i, j) in children.iter() {
            if !self.prunes(bound, best) {
                self.descend(it, i, j, half, best);
            }
        }
    }

    /// Scores the pose (ix, iy, it) exactly as the exhaustive search and keeps it if it wins
    /// there: a higher score, or an equal one earlier in its order.
    fn leaf(&self, it: i32, ix: i32, iy: i32, best: &mut Best) {
        if ix == 0 && iy == 0 && it == 0 {
            return;
        }
        let (cand, s) = lattice_score(
            self.field,
            self.points,
            self.scale,
            self.initial,
            self.model,
            self.window,
            ix,
            iy,
            it,
        );
        let side = 2 * self.nxy as i64 + 1;
        let order = ((it + self.nth) as i64 * side + (iy + self.nxy) as i64) * side
            + (ix + self.nxy) as i64;
        if s > best.score || (s == best.score && order < best.order) {
            *best = Best {
                score: s,
                order,
                pose: cand,
            };
        }
    }
}

/// The inclusive box of cells read by bilinear look-ups at (u + Δu, v + Δv) for every
/// (Δu, Δv) in the extent `ext` = (u_lo, u_hi, v_lo, v_hi): the floors and one beyond.
#[inline]
fn cell_box(u: f64, v: f64, ext: &[f64; 4]) -> (CellIndex, CellIndex) {
    (
        CellIndex::new(
            fast_floor(u + ext[0] - BOX_MARGIN),
            fast_floor(v + ext[2] - BOX_MARGIN),
        ),
        CellIndex::new(
            fast_floor(u + ext[1] + BOX_MARGIN).saturating_add(1),
            fast_floor(v + ext[3] + BOX_MARGIN).saturating_add(1),
        ),
    )
}

/// The outcome of a [`wide_search`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WideMatch {
    /// The best pose of the lattice (world frame).
    pub pose: Pose2,
    /// Its objective: the scaled coarse log-likelihood (cell look-ups) plus the log prior.
    pub score: f64,
    /// Cells of one pyramid level (the cost of building it: one distance look-up each, and
    /// as many max operations per level).
    pub pyramid_cells: usize,
}

/// The wide search of a poor match: branch and bound over a coarse-to-fine max-pyramid
/// (Olson, ICRA 2009, §IV-C; Hess et al., ICRA 2016, §V: Cartographer's fast correlative
/// matcher) of the endpoint model, with the motion prior, returning the same optimum as
/// brute force over the same lattice:
///
/// * translations (x₀ + i·m·res, y₀ + j·m·res) (world axes), |i|, |j| ≤ ⌊`range_xy`/(m·res)⌋,
///   with m = max(1, round(`step_xy`/res)) cells and res the field's cell size;
/// * rotations θ₀ + k·`step_theta`, |k| ≤ ⌊`range_theta`/`step_theta`⌋;
/// * objective f = s·Σᵢ v(cell of pᵢ) − ½eᵀR⁻¹e over the coarse subset p
///   ([`RangeData::coarse_points`]), with v(c) = −k·min(d(c), r)² the endpoint model at
///   the centre of the end point's cell (no interpolation), s the subsampling factor, and
///   e = (i·m·res, j·m·res, k·δθ) the offset from `initial`.
///
/// The pyramid is built here, over the cells the lattice can reach, because a particle's
/// map changes with every scan: one distance look-up per cell, then one max per cell and
/// level. A block's bound adds to the pyramid's the prior's maximum over the block bounded
/// from above by its tangent plane at the block's centre (the prior is concave), so every
/// bound is an upper bound and the search exact.
///
/// Errors when the lattice is too large for a pyramid ([`super::MAX_PYRAMID_CELLS`] cells)
/// or has too many rotations; the caller may then search by brute force ([`grid_search`]).
pub fn wide_search(
    field: &DistanceField<'_>,
    scan: &RangeData,
    initial: &Pose2,
    model: &EndpointModel,
    window: &SearchWindow,
) -> Result<WideMatch, GridError> {
    ensure_config(
        window.step_xy > 0.0 && window.step_theta > 0.0,
        "wide search step",
        window.step_xy.min(window.step_theta),
        "> 0",
    )?;
    if !initial.is_finite() {
        return Err(GridError::NonFinite {
            what: "wide search initial pose",
            value: f64::NAN,
        });
    }
    let frame = field.frame();
    let res = frame.resolution;
    let stride = (window.step_xy / res).round().max(1.0) as i32;
    let step = stride as f64 * res;
    let half_steps = (window.range_xy / step).floor().clamp(0.0, 1e6) as i32;
    let k_max = (window.range_theta / window.step_theta).floor().max(0.0);
    let points = scan.coarse_points();
    let scale = scan.points.len() as f64 / points.len().max(1) as f64;
    let lat = Lattice::new(
        &frame,
        points,
        initial,
        window.step_theta,
        k_max,
        half_steps,
    )?;
    // The coarsest level's blocks span the whole translation window.
    let span = (2 * half_steps + 1) as u32;
    let depth = (span.next_power_of_two().trailing_zeros() + 1).min(MAX_PYRAMID_DEPTH);
    let (lo, hi) = lat.reach(stride);
    let unit = field.metres_per_unit();
    let cell_value = |d: u8| {
        let d = (d as f64 * unit).min(model.radius);
        (-scale * model.k * d * d) as f32
    };
    // Distances are whole units: one value per unit, looked up per cell.
    let values: Vec<f32> = (0..=u8::MAX).map(cell_value).collect();
    let far = (-scale * model.k * model.radius * model.radius) as f32;
    // Cells outside the grid's table read the truncated distance, whose value is `far` when
    // the field reaches the model's radius, and so would every level there: the pyramid
    // over the part of the reach the table covers then holds the same values
    // (`Levels::value` reads far outside it) in fewer cells (a 30 m scan's reach, turned by
    // ±0.8 rad, is much larger than a local map). One far cell when they do not meet.
    let (lo, hi) = match field.covered() {
        _ if values[field.max_units() as usize] != far => (lo, hi),
        Some((a, b)) => {
            let (l, h) = (
                CellIndex::new(lo.x.max(a.x), lo.y.max(a.y)),
                CellIndex::new(hi.x.min(b.x), hi.y.min(b.y)),
            );
            if l.x <= h.x && l.y <= h.y {
                (l, h)
            } else {
                (lo, lo)
            }
        }
        None => (lo, lo),
    };
    let mut cells = 0;
    let base = |origin: CellIndex, w: usize, _h: usize, out: &mut [f32]| {
        cells = out.len();
        // A row of distances at a time, tile by tile (the same as `field.dist` per cell).
        let mut row = vec![0u8; w];
        for (y, out) in out.chunks_exact_mut(w).enumerate() {
            field.read_row(CellIndex::new(origin.x, origin.y + y as i32), &mut row);
            for (o, &d) in out.iter_mut().zip(&row) {
                *o = values[d as usize];
            }
        }
    };
    let levels = Levels::build(lo, hi, depth, stride, far, base, Storage::Pooled)?;
    let info = &window.information;
    let k0 = lat.k_max;
    let dtheta = lat.dtheta;
    // log prior of the block of 2^level × 2^level lattice steps from (dx, dy): exact at
    // level 0, else bounded by the tangent plane of q = eᵀR⁻¹e at the block's centre.
    let bonus = |rotation: u32, dx: i32, dy: i32, level: u32| -> f32 {
        let half = ((1i64 << level) - 1) as f64 * 0.5;
        let e = Vector3::new(
            (dx as f64 + half) * step,
            (dy as f64 + half) * step,
            (rotation as i32 - k0) as f64 * dtheta,
        );
        let ie = info * e;
        let q = e.dot(&ie);
        let h = half * step;
        let lower = (q - 2.0 * (ie[0].abs() + ie[1].abs()) * h).max(0.0);
        (-0.5 * if level == 0 { q } else { lower }) as f32
    };
    let top = depth - 1;
    let Some(best) = branch_and_bound(&levels, &lat, top, f32::NEG_INFINITY, bonus) else {
        // Unreachable: the window always holds the initial pose.
        return Ok(WideMatch {
            pose: *initial,
            score: f64::NEG_INFINITY,
            pyramid_cells: cells,
        });
    };
    Ok(WideMatch {
        pose: Pose2::new(
            initial.x + best.dx as f64 * step,
            initial.y + best.dy as f64 * step,
            initial.theta + (best.rotation as i32 - k0) as f64 * dtheta,
        ),
        score: best.score as f64,
        pyramid_cells: cells,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::SegmentWorld;
    use crate::{InverseSensorModel, OccupancyGrid};

    /// The office map (5 cm cells) with a 4-cell incremental distance field.
    fn office_map() -> OccupancyGrid {
        let world = SegmentWorld::office();
        let mut g = OccupancyGrid::new(0.05, InverseSensorModel::default())
            .with_incremental_distance(4)
            .unwrap();
        for &(x, y) in &[(1.5, 3.0), (5.0, 3.5), (10.5, 2.0), (2.0, 6.5), (9.0, 6.5)] {
            let pose = Pose2::new(x, y, 0.0);
            g.integrate_scan(
                &pose,
                &world.scan(&pose, 720, std::f64::consts::TAU * 0.999, 30.0),
            );
        }
        g
    }

    /// The scorer against a plain per-beam loop written from the definition (⌊·⌋ from
    /// libm, every corner read with [`DistanceField::dist`]) at poses whose end points
    /// cross tile borders, leave the stored tiles and fall off the map: the floating-point
    /// fallback bit for bit; the fixed-point scorer within its rounding bound (each
    /// distance within 17/1024 · √2 + 2⁻¹⁶ unit, so each squared one within 2·r times that,
    /// and the f32 sums within 10⁻⁶ of the total), with
    /// the same inliers except for beams that end within that bound of the inlier radius.
    #[test]
    fn score_is_the_plain_bilinear_sum() {
        let g = office_map();
        let field = g.distance_field().unwrap();
        let world = SegmentWorld::office();
        let scan_pose = Pose2::new(5.0, 3.5, 0.2);
        let points: Vec<Point2> = RangeData::new(
            &world.scan(&scan_pose, 361, std::f64::consts::TAU * 0.999, 30.0),
            &Default::default(),
        )
        .unwrap()
        .points()
        .to_vec();
        let model = EndpointModel::new(0.05, 0.15, 3.0);
        let unit = field.metres_per_unit();
        let frame = field.frame();
        let mut checked = 0;
        let (mut max_error, mut max_relative): (f64, f64) = (0.0, 0.0);
        for k in 0..200 {
            let t = k as f64;
            // From near the truth to far off the map (−40 m … 40 m).
            let spread = if k < 100 { 0.3 } else { 40.0 };
            let pose = Pose2::new(
                5.0 + spread * (0.37 * t).sin(),
                3.5 + spread * (0.61 * t).cos(),
                0.2 + 0.5 * (0.23 * t).sin(),
            );
            let (s, c) = pose.theta.sin_cos();
            let inv = 1.0 / frame.resolution;
            let (mut sum, mut inliers, mut borderline) = (0.0, 0, 0);
            let bound = (17.0 / 1024.0 * std::f64::consts::SQRT_2 + 1.0 / 65536.0) * unit;
            for p in &points {
                let u = (c * inv) * p.x - (s * inv) * p.y + ((pose.x - frame.origin.x) * inv - 0.5);
                let v = (s * inv) * p.x + (c * inv) * p.y + ((pose.y - frame.origin.y) * inv - 0.5);
                let (iu, iv) = (u.floor() as i32, v.floor() as i32);
                let (au, av) = (u - iu as f64, v - iv as f64);
                let d = |dx: i32, dy: i32| field.dist(CellIndex::new(iu + dx, iv + dy)) as f64;
                let d0 = d(0, 0) + au * (d(1, 0) - d(0, 0));
                let d1 = d(0, 1) + au * (d(1, 1) - d(0, 1));
                let dm = ((d0 + av * (d1 - d0)) * unit).min(model.radius);
                inliers += usize::from(dm < model.radius * 0.999);
                borderline += usize::from((dm - model.radius * 0.999).abs() <= bound);
                sum += dm * dm;
            }
            let exact = score_reference(&field, &points, &pose, &model);
            let plain = -model.k * sum;
            assert_eq!(exact.log_likelihood.to_bits(), plain.to_bits(), "{pose:?}");
            assert_eq!(exact.inliers, inliers, "{pose:?}");
            let got = score(&field, &points, &pose, &model);
            let tolerance =
                points.len() as f64 * model.k * 2.0 * model.radius * bound + 1e-6 * plain.abs();
            assert!(
                (got.log_likelihood - plain).abs() <= tolerance,
                "{pose:?}: {} vs {plain} (tolerance {tolerance})",
                got.log_likelihood
            );
            assert!(got.inliers.abs_diff(inliers) <= borderline, "{pose:?}");
            max_error = max_error.max((got.log_likelihood - plain).abs());
            max_relative = max_relative.max((got.log_likelihood - plain).abs() / tolerance);
            checked += usize::from(inliers > 0);
        }
        // Most poses near the truth find the map, so the comparison is not all-far.
        assert!(checked >= 90, "{checked}");
        // The rounding is felt (the two scorers are different code), and far below the bound.
        assert!(max_error > 0.0);
        println!("largest error {max_error:.3e}, {max_relative:.3} of the bound");
        // Far beyond any grid (the fixed-point coordinates clamp, never wrap) every end
        // point reads as far: n·r² each.
        for pose in [
            Pose2::new(3.0e9, -2.0e12, 0.3),
            Pose2::new(-1.0e300, 5.0, 1.0),
        ] {
            let got = score(&field, &points, &pose, &model);
            let all_far = -model.k * points.len() as f64 * model.radius * model.radius;
            assert_eq!(got.inliers, 0, "{pose:?}");
            assert!(
                (got.log_likelihood / all_far - 1.0).abs() < 1e-9,
                "{pose:?}"
            );
        }
    }

    /// Exactness: the branch-and-bound wide search returns the brute-force optimum of the
    /// same lattice and objective (coarse end points at cell centres, scaled, plus the
    /// motion prior), both the best cell and its score, computed here independently from
    /// the distance field cell by cell, with a lattice stride of one and of two cells.
    #[test]
    fn wide_search_finds_the_brute_force_optimum() {
        let g = office_map();
        let field = g.distance_field().unwrap();
        let world = SegmentWorld::office();
        let model = EndpointModel::new(0.05, 0.2, 3.0);
        let unit = field.metres_per_unit();
        for (truth, off, step_xy, info) in [
            (Pose2::new(2.5, 3.2, 0.3), (0.6, -0.5, 0.12), 0.05, 0.0),
            (Pose2::new(5.2, 3.8, -1.2), (-0.7, 0.3, -0.1), 0.1, 2.0),
            (Pose2::new(9.5, 2.5, 2.8), (0.2, 0.8, 0.0), 0.1, 0.5),
            (Pose2::new(3.0, 6.3, -2.9), (-0.4, -0.4, 0.08), 0.05, 8.0),
        ] {
            let scan = RangeData::new(
                &world.scan(&truth, 361, std::f64::consts::PI, 30.0),
                &Default::default(),
            )
            .unwrap();
            let initial = Pose2::new(truth.x + off.0, truth.y + off.1, truth.theta + off.2);
            let window = SearchWindow {
                range_xy: 1.0,
                step_xy,
                range_theta: 0.16,
                step_theta: 0.02,
                information: Matrix3::from_diagonal(&Vector3::new(info, info, 4.0 * info)),
            };
            let got = wide_search(&field, &scan, &initial, &model, &window).unwrap();
            // Brute force over the same lattice.
            let points = scan.coarse_points();
            let scale = scan.points().len() as f64 / points.len() as f64;
            let m = (step_xy / 0.05_f64).round() as i32;
            let step = m as f64 * 0.05;
            let n = (1.0 / step).floor() as i32;
            let v = |c: CellIndex| {
                let d = (field.dist(c) as f64 * unit).min(0.2);
                (-scale * model.k * d * d) as f32
            };
            let mut best = (f32::NEG_INFINITY, 0, 0, 0);
            let mut second = f32::NEG_INFINITY;
            for k in -8..=8 {
                let pose = Pose2::new(initial.x, initial.y, initial.theta + k as f64 * 0.02);
                let cells: Vec<CellIndex> = points
                    .iter()
                    .map(|p| g.world_to_cell(&pose.transform_point(p)))
                    .collect();
                for j in -n..=n {
                    for i in -n..=n {
                        let sum: f32 = cells
                            .iter()
                            .map(|c| v(CellIndex::new(c.x + i * m, c.y + j * m)))
                            .sum();
                        let e = Vector3::new(i as f64 * step, j as f64 * step, k as f64 * 0.02);
                        let s = sum + (-0.5 * e.dot(&(window.information * e))) as f32;
                        if s > best.0 {
                            second = best.0;
                            best = (s, i, j, k);
                        } else if s > second {
                            second = s;
                        }
                    }
                }
            }
            assert_eq!(got.score as f32, best.0, "score against brute force");
            if second < best.0 {
                let expected = Pose2::new(
                    initial.x + best.1 as f64 * step,
                    initial.y + best.2 as f64 * step,
                    initial.theta + best.3 as f64 * 0.02,
                );
                assert!(
                    got.pose.distance(&expected) < 1e-9
                        && (got.pose.theta - expected.theta).abs() < 1e-9,
                    "{:?} against brute force {expected:?}",
                    got.pose
                );
            }
            // A weak prior leaves the truth's neighbourhood the winner.
            if info <= 0.5 {
                assert!(
                    got.pose.distance(&truth) < 0.1,
                    "{:?} vs {truth:?}",
                    got.pose
                );
            }
        }
    }

    /// The branch-and-bound coarse search returns exactly the exhaustive search's pose (to
    /// the bit), over the indoor preset's window and others: lattice steps of one cell and
    /// of a non-integer number of cells, no prior, weak, strong and correlated priors and
    /// an indefinite one, poses near the truth, far from it and off the map (where every
    /// pose scores the same and the tie rule decides).
    #[test]
    fn grid_search_equals_the_exhaustive_search() {
        use rand::{Rng, SeedableRng};
        let g = office_map();
        let field = g.distance_field().unwrap();
        let world = SegmentWorld::office();
        let model = EndpointModel::new(0.05, 0.2, 3.0);
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(21);
        let windows = [
            (0.3, 0.05, 0.9, 0.025),
            (0.3, 0.07, 0.2, 0.013),
            (0.5, 0.1, 0.3, 0.02),
        ];
        let infos = [
            Matrix3::zeros(),
            Matrix3::from_diagonal(&Vector3::new(2.0, 2.0, 10.0)),
            Matrix3::from_diagonal(&Vector3::new(400.0, 400.0, 900.0)),
            Matrix3::new(300.0, 120.0, 10.0, 120.0, 80.0, -5.0, 10.0, -5.0, 200.0),
            Matrix3::new(5.0, 0.0, 0.0, 0.0, -3.0, 0.0, 0.0, 0.0, 20.0),
        ];
        let mut cases = 0;
        let mut moved = 0;
        for case in 0..40 {
            let truth = Pose2::new(
                rng.random_range(1.0..11.0),
                rng.random_range(0.5..7.5),
                rng.random_range(-3.1..3.1),
            );
            let scan = RangeData::new(
                &world.scan(&truth, 180, std::f64::consts::PI, 30.0),
                &Default::default(),
            )
            .unwrap();
            let off = if case % 10 == 9 { 40.0 } else { 0.25 };
            let initial = Pose2::new(
                truth.x + rng.random_range(-off..off),
                truth.y + rng.random_range(-off..off),
                truth.theta + rng.random_range(-0.6..0.6),
            );
            let (range_xy, step_xy, range_theta, step_theta) = windows[case % windows.len()];
            let window = SearchWindow {
                range_xy,
                step_xy,
                range_theta,
                step_theta,
                information: infos[case % infos.len()],
            };
            let fast = grid_search(&field, &scan, &initial, &model, &window);
            let slow = grid_search_exhaustive(&field, &scan, &initial, &model, &window);
            assert_eq!(
                [fast.x.to_bits(), fast.y.to_bits(), fast.theta.to_bits()],
                [slow.x.to_bits(), slow.y.to_bits(), slow.theta.to_bits()],
                "case {case}: {fast:?} against the exhaustive {slow:?}"
            );
            cases += 1;
            moved += usize::from(slow != initial);
        }
        // The cases are not all decided by the initial pose.
        assert!(moved >= 20, "{moved} of {cases} searches moved");
    }

    /// A window of headings only (`range_xy` below `step_xy`: one translation, the
    /// initial one; gridfast's `matching.search-range-xy = 0` with a heading window) is
    /// searched as the exhaustive search does. Its top block is a single pose, which the
    /// branch and bound halved into blocks of size 0 without end (a stack overflow that
    /// aborted `slam run --filter gridfast` with `[matching] search-range-xy = 0`).
    #[test]
    fn a_window_of_headings_only_equals_the_exhaustive_search() {
        let g = office_map();
        let field = g.distance_field().unwrap();
        let world = SegmentWorld::office();
        let model = EndpointModel::new(0.05, 0.2, 3.0);
        let truth = Pose2::new(6.0, 4.0, 0.3);
        let scan = RangeData::new(
            &world.scan(&truth, 180, std::f64::consts::PI, 30.0),
            &Default::default(),
        )
        .unwrap();
        let mut moved = 0;
        for (range_xy, dtheta) in [(0.0, 0.2), (0.04, -0.3), (1e-300, 0.1)] {
            let initial = Pose2::new(truth.x, truth.y, truth.theta + dtheta);
            let window = SearchWindow {
                range_xy,
                step_xy: 0.05,
                range_theta: 0.9,
                step_theta: 0.025,
                information: Matrix3::zeros(),
            };
            let fast = grid_search(&field, &scan, &initial, &model, &window);
            let slow = grid_search_exhaustive(&field, &scan, &initial, &model, &window);
            assert_eq!(
                [fast.x.to_bits(), fast.y.to_bits(), fast.theta.to_bits()],
                [slow.x.to_bits(), slow.y.to_bits(), slow.theta.to_bits()],
                "range_xy {range_xy}: {fast:?} against the exhaustive {slow:?}"
            );
            assert_eq!((fast.x, fast.y), (initial.x, initial.y));
            moved += usize::from(fast.theta != initial.theta);
        }
        // The heading is searched, not just the initial pose returned.
        assert_eq!(moved, 3);
    }
}
