//! Field values over regions and tiles.

use super::edt::{edt_2d, EdtScratch};
use super::params::LikelihoodParams;
use crate::cell::{CellIndex, GridFrame};
use crate::grid::tiles::TILE_CELLS;
use crate::grid::OccupancyGrid;
use slam_models::Point2;

/// Field of one tile (row-major like the tile): values s ∈ (0, 1] and the squared
/// distances d² (m², clamped to max_distance²) they come from.
#[derive(Clone)]
pub(crate) struct FieldTile {
    pub(crate) values: [f32; TILE_CELLS],
    pub(crate) dist2: [f32; TILE_CELLS],
}

impl FieldTile {
    /// A tile far from every obstacle.
    pub(crate) fn far(params: &LikelihoodParams) -> Self {
        Self {
            values: [params.far_value(); TILE_CELLS],
            dist2: [(params.max_distance * params.max_distance) as f32; TILE_CELLS],
        }
    }
}

/// Number of cells the obstacle search must look beyond a region for distances to be exact
/// up to `max_distance`.
#[inline]
pub(crate) fn margin_cells(params: &LikelihoodParams, resolution: f64) -> i32 {
    (params.max_distance / resolution).ceil().clamp(0.0, 4096.0) as i32
}

/// Field values s(c) and squared distances d(c)² (m², clamped) for the `w × h` cells
/// starting at `min` (row-major), from an exact EDT
/// of the grid's obstacles in the region grown by the margin, or `None` when that grown
/// region holds no obstacle (every value is then [`LikelihoodParams::far_value`]).
/// `margin` may be given smaller than [`margin_cells`] (tiles clamp it to one tile edge).
pub(crate) fn compute_region(
    grid: &OccupancyGrid,
    min: CellIndex,
    w: usize,
    h: usize,
    margin: i32,
) -> Option<(Vec<f32>, Vec<f32>)> {
    let params = grid.likelihood_params();
    let m = margin.max(0) as usize;
    let (gw, gh) = (w + 2 * m, h + 2 * m);
    let ox = min.x - m as i32;
    let oy = min.y - m as i32;
    let (obstacles, offsets) = grid.obstacle_mask(CellIndex::new(ox, oy), gw, gh);
    if !obstacles.iter().any(|&o| o) {
        return None;
    }
    let mut scratch = EdtScratch::default();
    let (d2, site) = edt_2d(&obstacles, gw, gh, &mut scratch);
    let res = grid.resolution();
    let mut out = Vec::with_capacity(w * h);
    let mut dist2 = Vec::with_capacity(w * h);
    let dmax = params.max_distance;
    let (far, far_d2) = (params.field_value(dmax), (dmax * dmax) as f32);
    // Surfaces of the obstacle sites, fitted on first use (many cells share a site).
    let mut surfaces: Vec<Option<Surface>> = if params.subcell {
        vec![None; gw * gh]
    } else {
        Vec::new()
    };
    // A surface lies within `Surface::REACH` cells of its obstacle cell's centre, so a cell
    // whose centre is that much beyond `max_distance` from the nearest obstacle centre is
    // far from the surface too: its far value without fitting the surface.
    let reach = if params.surface_lines {
        Surface::REACH_SEGMENT
    } else {
        Surface::REACH_POINT
    };
    let far_centre = dmax / res + reach;
    let far_centre2 = far_centre * far_centre;
    for y in 0..h {
        for x in 0..w {
            let k = (y + m) * gw + x + m;
            let d = if !d2[k].is_finite() || (params.subcell && d2[k] >= far_centre2) {
                f64::INFINITY
            } else if params.subcell {
                // Distance to the surface around the nearest obstacle cell (chosen by
                // centre distance: the exact EDT's feature transform).
                let s = site[k] as usize;
                let surface = *surfaces[s].get_or_insert_with(|| {
                    Surface::fit(s, &obstacles, &offsets, gw, gh, params.surface_lines)
                });
                surface.distance((x + m) as f64, (y + m) as f64) * res
            } else {
                d2[k].sqrt() * res
            };
            if d >= dmax {
                // The far value (d clamped to dmax), without its exp.
                out.push(far);
                dist2.push(far_d2);
            } else {
                out.push(params.field_value(d));
                dist2.push((d * d) as f32);
            }
        }
    }
    Some((out, dist2))
}

/// The obstacle surface near one obstacle cell, in region cell coordinates (cell (i, j)
/// centred at (i, j)), estimated from the mean hit positions (GMapping's per-cell
/// statistic) of the obstacle cells around it.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Surface {
    /// A point: the hit-count-weighted mean of the mean hit positions of the obstacle cells
    /// in the 3×3 neighbourhood. Averaging over neighbours matters where a wall runs along
    /// a cell boundary: range noise then splits its hits between two cells whose own means
    /// sit on either side of the wall (truncated distributions), while their joint mean is
    /// on it.
    Point { c: [f64; 2] },
    /// A segment {c + t·e : t ∈ [t0, t1]} (|e| = 1): the total-least-squares line through
    /// the same weighted means, cut to the extent of the means along it.
    Segment {
        c: [f64; 2],
        e: [f64; 2],
        t0: f64,
        t1: f64,
    },
}

/// Largest ratio λ₂/λ₁ of the weighted scatter matrix's eigenvalues for which the means
/// around a site count as one straight wall (an L-shaped corner in a 3×3 neighbourhood
/// gives ≈ 0.3 and more, a wall's truncated-noise spread across it at σ = 0.2 cell ≈ 0.05).
const LINE_RATIO: f64 = 0.15;

/// Where a mapped wall ends, along its line (cells): `ts` sorted ascending are the
/// positions of the hit means on the line, `start` the site's. The run of means from
/// `start` upwards (consecutive spacing ≤ 2.2: one missing cell is bridged) ends at its
/// last mean t_l; with hits spread uniformly along the wall, the last cell's hits cover
/// [entry, end] and their mean is the middle, so end = t_l + (t_l − entry), the entry
/// taken half a cell past the previous column's mean t_p (its cell fully covered):
/// end = t_l + clamp(t_l − t_p − ½, 0, ½), exact for walls along the grid axes; half a
/// cell when there is no previous column within 1.5 cells.
fn run_end(ts: impl Iterator<Item = f64>, start: f64) -> f64 {
    let (mut last, mut prev) = (start, f64::NEG_INFINITY);
    for t in ts {
        if t <= last {
            if t < last - 0.5 {
                prev = prev.max(t);
            }
            continue;
        }
        if t - last > 2.2 {
            break;
        }
        if t > last + 0.5 {
            // A new column: the last one becomes the previous column.
            prev = last;
        }
        last = t;
    }
    let gap = last - prev;
    let grow = if gap <= 1.5 {
        (gap - 0.5).clamp(0.0, 0.5)
    } else {
        0.5
    };
    last + grow
}

impl Surface {
    /// The farthest a point surface lies from its obstacle cell's centre, cells: the mean
    /// of hit means in the 3×3 neighbourhood, each within half a cell of its cell's centre
    /// (offsets of ±128/256), so within 1.5 cells per axis, 1.5·√2 < 2.13.
    const REACH_POINT: f64 = 2.13;
    /// The same for a segment: its ends are projections onto the line of hit means in the
    /// 5×5 neighbourhood (within 2.5·√2 of the centre) lying within half a cell of the
    /// line, moved on by at most half a cell (`run_end`): 2.5·√2 + 0.5 + 0.5 < 4.55.
    const REACH_SEGMENT: f64 = 4.55;

    /// Fits the surface of obstacle cell `s` (see the variants); `lines` false always gives
    /// the point.
    fn fit(
        s: usize,
        obstacles: &[bool],
        offsets: &[(i8, i8, u8)],
        gw: usize,
        gh: usize,
        lines: bool,
    ) -> Self {
        let (cx, cy) = ((s % gw) as i64, (s / gw) as i64);
        // Weighted means of the obstacle cells' hit means in the 3×3 (fit) and 5×5 (extent)
        // neighbourhoods.
        let mut pts = [([0.0f64; 2], 0.0f64, false); 25];
        let mut n = 0;
        let (mut sx, mut sy, mut sw) = (0.0, 0.0, 0.0);
        for ny in (cy - 2).max(0)..=(cy + 2).min(gh as i64 - 1) {
            for nx in (cx - 2).max(0)..=(cx + 2).min(gw as i64 - 1) {
                let i = ny as usize * gw + nx as usize;
                if !obstacles[i] {
                    continue;
                }
                let (ox, oy, c) = offsets[i];
                let wgt = c.max(1) as f64;
                let p = [nx as f64 + ox as f64 / 256.0, ny as f64 + oy as f64 / 256.0];
                let inner = (nx - cx).abs() <= 1 && (ny - cy).abs() <= 1;
                pts[n] = (p, wgt, inner);
                n += 1;
                if inner {
                    sx += wgt * p[0];
                    sy += wgt * p[1];
                    sw += wgt;
                }
            }
        }
        let c = [sx / sw, sy / sw];
        if !lines {
            return Surface::Point { c };
        }
        // Weighted scatter of the 3×3 means about their mean (total least squares:
        // the line's direction is the principal eigenvector).
        let (mut sxx, mut sxy, mut syy, mut m) = (0.0, 0.0, 0.0, 0);
        for &(p, wgt, inner) in &pts[..n] {
            if inner {
                let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
                sxx += wgt * dx * dx;
                sxy += wgt * dx * dy;
                syy += wgt * dy * dy;
                m += 1;
            }
        }
        let half_tr = 0.5 * (sxx + syy);
        let disc = (0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy).sqrt();
        let (l1, l2) = (half_tr + disc, half_tr - disc);
        if m < 2 || l1 <= 0.0 || l2 > LINE_RATIO * l1 {
            return Surface::Point { c };
        }
        // Principal direction: angle ½·atan2(2 sxy, sxx − syy).
        let phi = 0.5 * (2.0 * sxy).atan2(sxx - syy);
        let e = [phi.cos(), phi.sin()];
        // Extent: the run of means of the 5×5 neighbourhood lying on the line (within half
        // a cell of it) through the site's own mean, bridging one missing cell (spacing up
        // to 2.2 cells), see `run_end`.
        let (ox, oy, _) = offsets[s];
        let site = [
            cx as f64 + ox as f64 / 256.0 - c[0],
            cy as f64 + oy as f64 / 256.0 - c[1],
        ];
        let ts = site[0] * e[0] + site[1] * e[1];
        let mut ts_on = [0.0f64; 25];
        let mut k = 0;
        for &(p, _, _) in &pts[..n] {
            let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
            if (-dx * e[1] + dy * e[0]).abs() <= 0.5 {
                ts_on[k] = dx * e[0] + dy * e[1];
                k += 1;
            }
        }
        let on = &mut ts_on[..k];
        on.sort_unstable_by(f64::total_cmp);
        let t1 = run_end(on.iter().copied(), ts);
        let t0 = -run_end(on.iter().rev().map(|t| -t), -ts);
        Surface::Segment { c, e, t0, t1 }
    }

    /// Euclidean distance (cells) from (x, y) to the surface.
    #[inline]
    fn distance(&self, x: f64, y: f64) -> f64 {
        match *self {
            Surface::Point { c } => (x - c[0]).hypot(y - c[1]),
            Surface::Segment { c, e, t0, t1 } => {
                let (dx, dy) = (x - c[0], y - c[1]);
                let t = (dx * e[0] + dy * e[1]).clamp(t0, t1);
                (dx - t * e[0]).hypot(dy - t * e[1])
            }
        }
    }
}

/// A dense likelihood field over a rectangle of cells of a grid: s = exp(−d²/(2σ²)) with d
/// the Euclidean distance (metres, clamped to `max_distance`) from the cell centre to the
/// nearest obstacle cell, found by an exact EDT (to its centre when
/// [`LikelihoodParams::subcell`] is off; to the mean hit position of it and its neighbours
/// when on, or to the line fitted through those with [`LikelihoodParams::surface_lines`]).
///
/// ```
/// use slam_grid::{CellIndex, InverseSensorModel, LikelihoodField, OccupancyGrid};
/// use slam_models::{LaserScan, Pose2};
/// let mut grid = OccupancyGrid::new(0.05, InverseSensorModel::default());
/// let scan = LaserScan { angle_min: -0.5, angle_increment: 0.01, ranges: vec![2.0; 101],
///                        max_range: 30.0, sensor_pose: Pose2::IDENTITY };
/// grid.integrate_scan(&Pose2::IDENTITY, &scan);
/// let field = LikelihoodField::from_grid(&grid, CellIndex::new(0, -20), CellIndex::new(60, 20));
/// // The end points lie on an arc of radius 2 m: high likelihood there, low 1 m closer.
/// let wall = grid.world_to_cell(&slam_models::Point2::new(1.99, 0.0));
/// assert!(field.value(wall) > 0.8);
/// assert!(field.value(grid.world_to_cell(&slam_models::Point2::new(1.0, 0.0))) < 0.01);
/// ```
#[derive(Debug, Clone)]
pub struct LikelihoodField {
    frame: GridFrame,
    min: CellIndex,
    width: usize,
    height: usize,
    far: f32,
    values: Vec<f32>,
}

impl LikelihoodField {
    /// The field over cells `min ..= max` (inclusive corners) of `grid`, computed by one EDT
    /// over that rectangle grown by ⌈max_distance/resolution⌉ cells on each side.
    pub fn from_grid(grid: &OccupancyGrid, min: CellIndex, max: CellIndex) -> Self {
        let width = (max.x - min.x + 1).max(0) as usize;
        let height = (max.y - min.y + 1).max(0) as usize;
        let params = grid.likelihood_params();
        let far = params.far_value();
        let margin = margin_cells(&params, grid.resolution());
        let values = compute_region(grid, min, width, height, margin)
            .map(|(v, _)| v)
            .unwrap_or_else(|| vec![far; width * height]);
        Self {
            frame: grid.frame(),
            min,
            width,
            height,
            far,
            values,
        }
    }

    /// Field value of cell `c` (the far value outside the rectangle).
    #[inline]
    pub fn value(&self, c: CellIndex) -> f32 {
        let x = c.x - self.min.x;
        let y = c.y - self.min.y;
        if x < 0 || y < 0 || x as usize >= self.width || y as usize >= self.height {
            self.far
        } else {
            self.values[y as usize * self.width + x as usize]
        }
    }

    /// Field value at the cell containing world point `p`.
    #[inline]
    pub fn value_at(&self, p: &Point2) -> f32 {
        self.value(self.frame.world_to_cell(p))
    }

    /// Lower-left cell, width and height (cells).
    pub fn extent(&self) -> (CellIndex, usize, usize) {
        (self.min, self.width, self.height)
    }

    /// The world ↔ cell frame (the grid's).
    pub fn frame(&self) -> GridFrame {
        self.frame
    }
}

/// [`margin_cells`] clamped to one tile edge (what per-tile fields use: their EDT looks at
/// the 3×3 tiles around them).
#[inline]
pub(crate) fn margin_cells_clamped(params: &LikelihoodParams, resolution: f64) -> i32 {
    margin_cells(params, resolution).min(crate::grid::tiles::TILE_SIZE as i32)
}

#[cfg(test)]
mod tests {
    use crate::testutil::SegmentWorld;
    use crate::{InverseSensorModel, LikelihoodParams, OccupancyGrid};
    use slam_models::{Point2, Pose2};

    /// A corridor wall y = 1 on a cell boundary, mapped from noise-free scans taken while
    /// driving along it: its hits fall on either side of the boundary by rounding, and
    /// grazing beams clear some of the cells they land in, so the wall's obstacle cells
    /// have gaps and alternate sides.
    fn boundary_wall(surface_lines: bool) -> OccupancyGrid {
        let world = SegmentWorld {
            segments: vec![(Point2::new(-5.0, 1.0), Point2::new(10.0, 1.0))],
        };
        let params = LikelihoodParams {
            surface_lines,
            ..Default::default()
        };
        let mut g = OccupancyGrid::new(0.05, InverseSensorModel::default())
            .with_likelihood(params)
            .unwrap();
        for k in 0..40 {
            let pose = Pose2::new(0.1 * k as f64, 0.3 + 0.003 * k as f64, 0.2);
            let scan = world.scan(&pose, 181, std::f64::consts::PI, 20.0);
            g.integrate_scan(&pose, &scan);
        }
        g
    }

    /// Largest error (m) of the field's distances at the cell centres within two cells of
    /// the wall over x ∈ [1, 3], and of the bicubic interpolant's peak across the wall.
    fn wall_errors(g: &OccupancyGrid) -> (f64, f64) {
        let (mut dist_err, mut peak_err) = (0.0f64, 0.0f64);
        for i in 0..40 {
            let x = 1.0 + 0.05 * i as f64 + 0.025;
            for y in [0.925, 0.975, 1.025, 1.075] {
                let c = g.world_to_cell(&Point2::new(x, y));
                let d = (g.distance_squared(c) as f64).sqrt();
                dist_err = dist_err.max((d - (y - 1.0f64).abs()).abs());
            }
            // Peak of the interpolated field on a 0.1 mm lattice across the wall.
            let best = (0..400)
                .map(|j| 0.98 + 0.0001 * j as f64)
                .max_by(|a, b| {
                    let fa = g.likelihood_bicubic(&Point2::new(x, *a)).0;
                    let fb = g.likelihood_bicubic(&Point2::new(x, *b)).0;
                    fa.total_cmp(&fb)
                })
                .unwrap();
            peak_err = peak_err.max((best - 1.0).abs());
        }
        (dist_err, peak_err)
    }

    /// The far cells' shortcut in `compute_region` rests on every surface lying within
    /// `Surface::REACH_POINT` (points) or `REACH_SEGMENT` (segments) cells of its obstacle
    /// cell's centre. Measured on the office mapped from noisy scans at 60 random poses,
    /// every obstacle cell's fitted surface, its farthest point from that centre (the point
    /// itself; a segment's two ends, the farthest points of a segment from any point).
    #[test]
    fn surfaces_lie_within_their_reach_of_the_obstacle_cell() {
        use super::Surface;
        use crate::cell::CellIndex;
        use rand::{Rng, SeedableRng};
        let world = SegmentWorld::office();
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
        for lines in [false, true] {
            let params = LikelihoodParams {
                surface_lines: lines,
                ..Default::default()
            };
            let mut g = OccupancyGrid::new(0.05, InverseSensorModel::default())
                .with_likelihood(params)
                .unwrap();
            for _ in 0..60 {
                let pose = Pose2::new(
                    rng.random_range(1.0..11.0),
                    rng.random_range(1.0..7.0),
                    rng.random_range(-3.1..3.1),
                );
                let mut scan = world.scan(&pose, 361, 2.0 * std::f64::consts::PI, 20.0);
                for r in &mut scan.ranges {
                    *r += rng.random_range(-0.03..0.03);
                }
                g.integrate_scan(&pose, &scan);
            }
            let (w, h) = (320, 200);
            let (obstacles, offsets) = g.obstacle_mask(CellIndex::new(-20, -20), w, h);
            let (mut worst, mut fitted) = (0.0f64, 0);
            for s in (0..w * h).filter(|&s| obstacles[s]) {
                let centre = [(s % w) as f64, (s / w) as f64];
                let far = |p: [f64; 2]| (p[0] - centre[0]).hypot(p[1] - centre[1]);
                let reach = match Surface::fit(s, &obstacles, &offsets, w, h, lines) {
                    Surface::Point { c } => far(c),
                    Surface::Segment { c, e, t0, t1 } => far([c[0] + t0 * e[0], c[1] + t0 * e[1]])
                        .max(far([c[0] + t1 * e[0], c[1] + t1 * e[1]])),
                };
                worst = worst.max(reach);
                fitted += 1;
            }
            let bound = if lines {
                Surface::REACH_SEGMENT
            } else {
                Surface::REACH_POINT
            };
            assert!(fitted > 1000, "{fitted} obstacle cells");
            assert!(
                worst <= bound,
                "lines {lines}: a surface {worst} cells away"
            );
            eprintln!("lines {lines}: farthest surface point {worst:.3} cells (bound {bound})");
        }
    }

    #[test]
    fn run_ends_follow_the_hits() {
        use super::run_end;
        // Columns of means at −2, −1, 0 (site) and a full last column at 1: the wall ends at
        // the far edge of that cell, 1.5.
        let ts = [-2.0, -1.0, 0.0, 1.0];
        assert!((run_end(ts.iter().copied(), 0.0) - 1.5).abs() < 1e-12);
        // The last cell covered over 0.4 of its width from its entry at 0.5: hits in
        // [0.5, 0.9], mean 0.7; the end is 0.9.
        let ts = [-1.0, 0.0, 0.7];
        assert!((run_end(ts.iter().copied(), 0.0) - 0.9).abs() < 1e-12);
        // Downwards, by the same function on negated positions: the end is −1.5.
        let down = -run_end(ts.iter().rev().map(|t| -t), 0.0);
        assert!((down + 1.5).abs() < 1e-12, "{down}");
        // One missing cell is bridged, two are not (the run ends at 2, grown by ½).
        let ts = [0.0, 2.0, 5.0];
        assert!((run_end(ts.iter().copied(), 0.0) - 2.5).abs() < 1e-12);
        // Two means per column (a wall along a cell boundary splits its hits) count as one.
        let ts = [-1.02, -0.98, 0.01, 0.03, 0.97, 1.01];
        let end = run_end(ts.iter().copied(), 0.01);
        assert!((end - 1.5).abs() < 0.03, "{end}");
    }

    #[test]
    fn fitted_lines_put_a_gappy_boundary_wall_where_it_is() {
        let g = boundary_wall(true);
        let (dist_err, peak_err) = wall_errors(&g);
        assert!(dist_err < 1e-3, "distance error {dist_err} m");
        assert!(peak_err < 1e-3, "peak {peak_err} m off the wall");
        // The point surfaces (distance to the mean of the 3×3 hit means) do not: end points
        // between mapped cells are pushed off the wall.
        let (dist_err, peak_err) = wall_errors(&boundary_wall(false));
        assert!(dist_err > 5e-3 || peak_err > 5e-3, "{dist_err} {peak_err}");
    }
}
