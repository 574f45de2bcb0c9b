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
    for y in 0..h {
        for x in 0..w {
            let k = (y + m) * gw + x + m;
            let d = if !d2[k].is_finite() {
                f64::INFINITY
            } else if params.subcell {
                // Distance to the surface point of the nearest obstacle cell (chosen by
                // centre distance: the exact EDT's feature transform).
                let (sx, sy) = surface_point(site[k] as usize, &obstacles, &offsets, gw, gh);
                ((x + m) as f64 - sx).hypot((y + m) as f64 - sy) * res
            } else {
                d2[k].sqrt() * res
            };
            out.push(params.field_value(d));
            dist2.push((d.min(dmax) * d.min(dmax)) as f32);
        }
    }
    Some((out, dist2))
}

/// The surface point of obstacle cell `s` in region cell coordinates (cell (i, j) centred
/// at (i, j)): the hit-count-weighted mean of the mean hit positions of the obstacle cells
/// in its 3×3 neighbourhood. Averaging over neighbours matters where a wall runs along a
/// cell boundary: range noise then splits its hits between two cells whose own means sit
/// on either side of the wall (truncated distributions), while their joint mean is on it.
fn surface_point(
    s: usize,
    obstacles: &[bool],
    offsets: &[(i8, i8, u8)],
    gw: usize,
    gh: usize,
) -> (f64, f64) {
    let (cx, cy) = ((s % gw) as i64, (s / gw) as i64);
    let (mut sx, mut sy, mut sw) = (0.0, 0.0, 0.0);
    for ny in (cy - 1).max(0)..=(cy + 1).min(gh as i64 - 1) {
        for nx in (cx - 1).max(0)..=(cx + 1).min(gw as i64 - 1) {
            let n = ny as usize * gw + nx as usize;
            if !obstacles[n] {
                continue;
            }
            let (ox, oy, c) = offsets[n];
            let wgt = c.max(1) as f64;
            sx += wgt * (nx as f64 + ox as f64 / 256.0);
            sy += wgt * (ny as f64 + oy as f64 / 256.0);
            sw += wgt;
        }
    }
    (sx / sw, sy / sw)
}

/// A dense likelihood field over a rectangle of cells of a grid: s = exp(−d²/(2σ²)) with d
/// the Euclidean distance (metres, clamped to `max_distance`) from the cell centre to the
/// nearest obstacle cell, found by an exact EDT (to its centre when
/// [`LikelihoodParams::subcell`] is off; to its mean hit position when on).
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
