//! The log-odds occupancy grid on copy-on-write tiles.
//!
//! Split by concern: this file holds the grid type, its growth and its read access;
//! `integrate` writes scans into it (ray casting and log-odds updates); [`distance`] is the
//! optional incrementally repaired distance field. The lazy likelihood field the matchers
//! read lives in [`crate::likelihood`]: the grid only stores its per-tile entries, type
//! erased, and drops those a write may have changed, so that the grid does not depend on
//! the likelihood module.

pub mod distance;
mod import;
mod integrate;
mod raytrace;
pub(crate) mod sensor_model;
pub(crate) mod tiles;

use crate::cell::{CellIndex, GridFrame};
use crate::error::{ensure_config, GridError};
use distance::{DistanceField, IncrementalDistance, MAX_DISTANCE_RADIUS};
#[cfg(test)]
pub(crate) use raytrace::trace_segment;
use sensor_model::InverseSensorModel;
use slam_models::{GridMap, Point2};
use std::any::Any;
use std::sync::{Arc, OnceLock};
use tiles::{split, Tile, TileLayout, TileTable, TILE_SIZE};

/// Largest width or height of the area a grid covers, cells (2¹⁶: 3.3 km at 5 cm, 655 m at
/// 1 cm). A scan that would stretch the grid beyond it is refused with
/// [`GridError::MapTooLarge`]: no building or campus map comes near it, while one glitched
/// pose or range kilometres away from the rest does, and would make the dense map export
/// ([`OccupancyGrid::to_grid_map`]) span the gap.
pub const MAX_MAP_EXTENT_CELLS: u64 = 1 << 16;

/// Largest number of cells in the bounding box of the area a grid covers (2²⁸ ≈ 2.7·10⁸:
/// a square of 819 m at 5 cm, 164 m at 1 cm), so that the dense export
/// ([`OccupancyGrid::to_grid_map`], one byte per cell) stays below 256 MiB. Beyond it,
/// [`GridError::MapTooLarge`].
pub const MAX_MAP_CELLS: u64 = 1 << 28;

/// Counters of the copy-on-write machinery (since creation or the last
/// [`OccupancyGrid::reset_copy_stats`]); clones start from the source's counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CopyStats {
    /// Tiles allocated fresh (first write to an unknown tile).
    pub tiles_created: u64,
    /// Shared tiles copied before a write (copy-on-write).
    pub tiles_copied: u64,
    /// Bytes copied by those copies (`tiles_copied` × tile size).
    pub bytes_copied: u64,
}

/// A log-odds occupancy grid (PR §9.2) that grows on demand, stored as 32×32 tiles behind
/// `Arc`.
///
/// * Cells hold clamped log-odds l = ln(p/(1−p)) as `f32`; never-observed cells are 0
///   (p = ½, "unknown").
/// * Cell (i, j) covers `[ox + i·res, ox + (i+1)·res) × [oy + j·res, oy + (j+1)·res)`, with
///   (ox, oy) the origin (default (0, 0)); indices may be negative.
/// * `Clone` copies only the table of tile pointers (a few bytes per 1024 cells); a later
///   write copies just the tiles it changes that are still shared
///   ([`OccupancyGrid::copy_stats`] counts them). Grid FastSLAM's particles share maps so.
/// * Each grid also caches a likelihood field per tile ([`crate::likelihood`]), computed
///   lazily by the matchers, shared between clones in the same way and dropped where a
///   write changes which cells are obstacles.
/// * Optionally ([`OccupancyGrid::with_incremental_distance`]) a grid also keeps a
///   truncated distance field repaired after every integration from the cells whose
///   obstacle status flipped ([`distance`]), for particle filters that match every scan.
///
/// ```
/// use slam_grid::{InverseSensorModel, OccupancyGrid};
/// use slam_models::{LaserScan, Point2, Pose2};
/// let mut grid = OccupancyGrid::new(0.05, InverseSensorModel::default());
/// let scan = LaserScan { angle_min: 0.0, angle_increment: 0.0, ranges: vec![1.0],
///                        max_range: 30.0, sensor_pose: Pose2::IDENTITY };
/// grid.integrate_scan(&Pose2::IDENTITY, &scan);
/// assert!(grid.probability(grid.world_to_cell(&Point2::new(1.0, 0.0))) > 0.5);
/// assert!(grid.probability(grid.world_to_cell(&Point2::new(0.5, 0.0))) < 0.5);
/// let copy = grid.clone(); // cheap: tiles are shared
/// assert_eq!(copy.log_odds(copy.world_to_cell(&Point2::new(1.0, 0.0))), grid.log_odds(grid.world_to_cell(&Point2::new(1.0, 0.0))));
/// ```
#[derive(Clone)]
pub struct OccupancyGrid {
    frame: GridFrame,
    model: InverseSensorModel,
    /// Which cells are obstacles, and whether tiles keep mean hit positions.
    pub(crate) params: ObstacleRule,
    /// The covered rectangle and the sparse slot index of the stored tiles.
    pub(crate) table: TileTable,
    /// The bounding box of every cell the grid was asked to cover (no growth slack), the
    /// extent checked against [`MAX_MAP_EXTENT_CELLS`] and [`MAX_MAP_CELLS`].
    span: Option<(CellIndex, CellIndex)>,
    /// One entry per slot of `table.index`: `None` for a stored neighbour never written.
    tiles: Vec<Option<Arc<Tile>>>,
    /// The lazy likelihood field's cache, one cell per tile slot; the table itself is
    /// allocated on the first field read, so grids that never read the lazy field (grid
    /// FastSLAM's, which use the incremental one) have one table less to clone.
    pub(crate) fields: OnceLock<TileCache>,
    /// The lazy field's own state (its parameters and far tile; `None`: the defaults),
    /// type erased like its tiles.
    pub(crate) field_state: Option<Arc<dyn Any + Send + Sync>>,
    pub(crate) distance: Option<IncrementalDistance>,
    stats: CopyStats,
}

/// The part of the likelihood parameters the grid itself needs: which cells are obstacles
/// (log-odds above `occupied_threshold`; a change of status invalidates cached field tiles
/// and repairs the incremental distance field) and whether tiles keep mean hit positions
/// (`subcell`). Set with [`crate::LikelihoodParams`] through
/// [`OccupancyGrid::with_likelihood`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ObstacleRule {
    pub(crate) occupied_threshold: f32,
    pub(crate) subcell: bool,
}

impl ObstacleRule {
    /// The rule of the default likelihood parameters (a test in the likelihood module
    /// checks that they agree).
    pub(crate) const DEFAULT: Self = Self {
        occupied_threshold: 0.0,
        subcell: true,
    };
}

/// One entry of the per-tile cache a grid keeps for its lazy likelihood field, type erased
/// so that the grid does not depend on the module that computes it.
pub(crate) type CachedTile = Arc<dyn Any + Send + Sync>;

/// The per-tile cache: one cell per tile slot, filled on first read.
pub(crate) type TileCache = Vec<OnceLock<CachedTile>>;

impl std::fmt::Debug for OccupancyGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OccupancyGrid")
            .field("frame", &self.frame)
            .field("covered", &self.table.rect())
            .field("slots", &self.table.len())
            .field("allocated_tiles", &self.allocated_tiles())
            .field("stats", &self.stats)
            .finish()
    }
}

impl OccupancyGrid {
    /// An empty grid (every cell unknown) with origin (0, 0), cell edge `resolution` metres,
    /// the given inverse sensor model and default [`crate::LikelihoodParams`].
    ///
    /// A non-finite or non-positive resolution is replaced by 0.05 m; use
    /// [`OccupancyGrid::try_new`] to have it rejected instead.
    pub fn new(resolution: f64, model: InverseSensorModel) -> Self {
        let resolution = if resolution.is_finite() && resolution > 0.0 {
            resolution
        } else {
            0.05
        };
        Self {
            frame: GridFrame::new(Point2::origin(), resolution),
            model,
            params: ObstacleRule::DEFAULT,
            table: TileTable::default(),
            span: None,
            tiles: Vec::new(),
            fields: OnceLock::new(),
            field_state: None,
            distance: None,
            stats: CopyStats::default(),
        }
    }

    /// Like [`OccupancyGrid::new`], validating the resolution (> 0, finite) and the model.
    pub fn try_new(resolution: f64, model: InverseSensorModel) -> Result<Self, GridError> {
        ensure_config(resolution > 0.0, "resolution", resolution, "> 0 m")?;
        model.validate()?;
        Ok(Self::new(resolution, model))
    }

    /// This grid with an incrementally repaired truncated distance field of
    /// `radius_cells` cells (1..=15) switched on (see [`distance`]): built now from the
    /// grid's obstacles, then repaired after every integration in O(changed cells), shared
    /// between clones tile by tile. Read it with [`OccupancyGrid::distance_field`].
    /// Grids without it behave exactly as before.
    pub fn with_incremental_distance(mut self, radius_cells: u32) -> Result<Self, GridError> {
        ensure_config(
            (1..=MAX_DISTANCE_RADIUS).contains(&radius_cells),
            "incremental distance radius (cells)",
            radius_cells as f64,
            "1 to 15 cells",
        )?;
        let r = radius_cells as i32;
        // Keep the table at least `radius` cells beyond every obstacle (see [`distance`]).
        if let Some((lo, hi)) = self.known_bounds() {
            self.ensure_covers(
                CellIndex::new(lo.x - r, lo.y - r),
                CellIndex::new(hi.x + r, hi.y + r),
            )?;
        }
        let mut obstacles = Vec::new();
        let t = TILE_SIZE as i32;
        for (s, tile) in self.tiles.iter().enumerate() {
            let Some(tile) = tile else { continue };
            let (tx, ty) = self.table.tile_of_slot(s);
            for (k, &v) in tile.cells.iter().enumerate() {
                if v > self.params.occupied_threshold {
                    let (x, y) = ((k % TILE_SIZE) as i32, (k / TILE_SIZE) as i32);
                    obstacles.push(CellIndex::new(tx * t + x, ty * t + y));
                }
            }
        }
        let mut d = IncrementalDistance::new(radius_cells, self.table.len());
        d.rebuild(&self.table, &obstacles);
        self.distance = Some(d);
        Ok(self)
    }

    /// The incrementally repaired distance field, when switched on with
    /// [`OccupancyGrid::with_incremental_distance`].
    #[inline]
    pub fn distance_field(&self) -> Option<DistanceField<'_>> {
        self.distance
            .as_ref()
            .map(|d| d.view(&self.table, self.frame))
    }

    /// This grid with its origin (world position of cell (0, 0)'s lower-left corner) moved.
    /// Only allowed on an empty grid; a non-finite origin is rejected.
    pub fn with_origin(mut self, origin: Point2) -> Result<Self, GridError> {
        crate::error::ensure_finite("grid origin x", origin.x)?;
        crate::error::ensure_finite("grid origin y", origin.y)?;
        if self.allocated_tiles() == 0 {
            self.frame.origin = origin;
        }
        Ok(self)
    }

    /// Cell edge length, metres.
    #[inline]
    pub fn resolution(&self) -> f64 {
        self.frame.resolution
    }

    /// The world ↔ cell frame.
    #[inline]
    pub fn frame(&self) -> GridFrame {
        self.frame
    }

    /// The inverse sensor model used by [`OccupancyGrid::integrate_scan`].
    pub fn sensor_model(&self) -> &InverseSensorModel {
        &self.model
    }

    /// The cell containing world point `p`.
    #[inline]
    pub fn world_to_cell(&self, p: &Point2) -> CellIndex {
        self.frame.world_to_cell(p)
    }

    /// World position of the centre of cell `c`.
    #[inline]
    pub fn cell_center(&self, c: CellIndex) -> Point2 {
        self.frame.cell_center(c)
    }

    /// Log-odds of cell `c`; 0 (unknown) for cells never written.
    #[inline]
    pub fn log_odds(&self, c: CellIndex) -> f32 {
        let ((tx, ty), local) = split(c);
        match self.table.slot(tx, ty) {
            Some(s) => match &self.tiles[s] {
                Some(t) => t.cells[local],
                None => 0.0,
            },
            None => 0.0,
        }
    }

    /// Occupancy probability p = 1 − 1/(1 + eˡ) of cell `c`; ½ when unknown.
    #[inline]
    pub fn probability(&self, c: CellIndex) -> f32 {
        1.0 - 1.0 / (1.0 + self.log_odds(c).exp())
    }

    /// True when cell `c` counts as an obstacle for the likelihood field
    /// (log-odds > `occupied_threshold`).
    #[inline]
    pub fn is_obstacle(&self, c: CellIndex) -> bool {
        self.log_odds(c) > self.params.occupied_threshold
    }

    /// Whether each cell (x0 + i, y) is an obstacle ([`OccupancyGrid::is_obstacle`]), into
    /// `out[i]`: one tile look-up per tile the row crosses instead of one per cell.
    pub(crate) fn obstacle_row(&self, y: i32, x0: i32, out: &mut [bool]) {
        let thr = self.params.occupied_threshold;
        let mask = TILE_SIZE as i32 - 1;
        let ty = y >> tiles::TILE_BITS;
        let row = (y & mask) as usize * TILE_SIZE;
        let mut i = 0;
        while i < out.len() {
            let x = x0 + i as i32;
            let n = (TILE_SIZE - (x & mask) as usize).min(out.len() - i);
            let seg = &mut out[i..i + n];
            match self
                .table
                .slot(x >> tiles::TILE_BITS, ty)
                .and_then(|s| self.tiles[s].as_deref())
            {
                Some(t) => {
                    let l = row + (x & mask) as usize;
                    for (o, &v) in seg.iter_mut().zip(&t.cells[l..l + n]) {
                        *o = v > thr;
                    }
                }
                // Never written: log-odds 0, as `log_odds` reads it.
                None => seg.fill(0.0 > thr),
            }
            i += n;
        }
    }

    /// Copy-on-write counters.
    pub fn copy_stats(&self) -> CopyStats {
        self.stats
    }

    /// Zeroes the copy-on-write counters.
    pub fn reset_copy_stats(&mut self) {
        self.stats = CopyStats::default();
    }

    /// Number of tiles holding data (allocated).
    pub fn allocated_tiles(&self) -> usize {
        self.tiles.iter().filter(|t| t.is_some()).count()
    }

    /// Number of allocated tiles this grid shares with another grid (a clone).
    pub fn shared_tiles(&self) -> usize {
        self.tiles
            .iter()
            .flatten()
            .filter(|t| Arc::strong_count(t) > 1)
            .count()
    }

    /// Bytes held by one tile (log-odds, a bit per cell marking the lower clamp, and mean
    /// hit positions of its cells; a grid whose [`crate::LikelihoodParams::subcell`] is off keeps
    /// no hit positions: 4 KiB + 128 bytes).
    pub const TILE_BYTES: usize = tiles::TILE_BYTES_WITH_HITS;

    /// Inclusive range of cells covered by the tile table (`None` while empty): the
    /// rectangle the grid has grown to, of which only the observed tiles are stored.
    pub fn covered_cells(&self) -> Option<(CellIndex, CellIndex)> {
        self.table.covered_cells()
    }

    /// The span (bounding box of every cell covered so far) once cells `min ..= max` are
    /// covered too, or [`GridError::MapTooLarge`] when it would break the extent limits
    /// ([`OccupancyGrid::ensure_covers`] without the change).
    fn check_extent(
        &self,
        min: CellIndex,
        max: CellIndex,
    ) -> Result<(CellIndex, CellIndex), GridError> {
        let (min, max) = (
            CellIndex::new(min.x.min(max.x), min.y.min(max.y)),
            CellIndex::new(min.x.max(max.x), min.y.max(max.y)),
        );
        let (lo, hi) = match self.span {
            Some((lo, hi)) => (
                CellIndex::new(lo.x.min(min.x), lo.y.min(min.y)),
                CellIndex::new(hi.x.max(max.x), hi.y.max(max.y)),
            ),
            None => (min, max),
        };
        let width = (hi.x as i64 - lo.x as i64 + 1) as u64;
        let height = (hi.y as i64 - lo.y as i64 + 1) as u64;
        if width > MAX_MAP_EXTENT_CELLS
            || height > MAX_MAP_EXTENT_CELLS
            || width * height > MAX_MAP_CELLS
        {
            return Err(GridError::MapTooLarge {
                width,
                height,
                resolution: self.frame.resolution,
            });
        }
        Ok((lo, hi))
    }

    /// Grows the covered rectangle so that it holds cells `min ..= max` (keeps existing
    /// tiles; stores nothing: tiles are stored when written).
    ///
    /// Fails with [`GridError::MapTooLarge`], changing nothing, when the bounding box of
    /// every cell covered so far and these would be wider or higher than
    /// [`MAX_MAP_EXTENT_CELLS`] or hold more than [`MAX_MAP_CELLS`] cells.
    pub fn ensure_covers(&mut self, min: CellIndex, max: CellIndex) -> Result<(), GridError> {
        let (lo, hi) = self.check_extent(min, max)?;
        self.span = Some((lo, hi));
        let (min, max) = (
            CellIndex::new(min.x.min(max.x), min.y.min(max.y)),
            CellIndex::new(min.x.max(max.x), min.y.max(max.y)),
        );
        let (t0, _) = split(min);
        let (t1, _) = split(max);
        if self.table.rect().len() > 0
            && self.table.rect().contains(t0.0, t0.1)
            && self.table.rect().contains(t1.0, t1.1)
        {
            return Ok(());
        }
        let old = self.table.rect();
        let (mut x0, mut y0, mut x1, mut y1) = (t0.0, t0.1, t1.0, t1.1);
        if old.len() > 0 {
            // Grow with slack (a quarter of the current size, at least 2 tiles) so that a
            // robot exploring steadily does not reallocate the table on every scan.
            let sx = (old.tw / 4).max(2);
            let sy = (old.th / 4).max(2);
            if x0 < old.tx0 {
                x0 -= sx;
            }
            if y0 < old.ty0 {
                y0 -= sy;
            }
            if x1 >= old.tx0 + old.tw {
                x1 += sx;
            }
            if y1 >= old.ty0 + old.th {
                y1 += sy;
            }
            x0 = x0.min(old.tx0);
            y0 = y0.min(old.ty0);
            x1 = x1.max(old.tx0 + old.tw - 1);
            y1 = y1.max(old.ty0 + old.th - 1);
        }
        // No tile moves: fields cached next to the old border saw only empty space beyond
        // it, which is still empty, so they stay valid.
        self.table.set_rect(TileLayout {
            tx0: x0,
            ty0: y0,
            tw: x1 - x0 + 1,
            th: y1 - y0 + 1,
        });
        Ok(())
    }

    /// The slot of tile (tx, ty) for a write: stored now if it was not, with its eight
    /// neighbours (whose cached fields and distance tiles its obstacles reach), each new
    /// slot getting an empty entry in every per-slot table.
    pub(super) fn slot_for_write(&mut self, tx: i32, ty: i32) -> usize {
        // (Written tiles lie in the covered rectangle, where `slot` sees every stored one.)
        if let Some(s) = self.table.slot(tx, ty) {
            if self.tiles[s].is_some() {
                return s; // written before: its neighbours are stored already
            }
        }
        for (dx, dy) in [
            (0, 0),
            (-1, -1),
            (0, -1),
            (1, -1),
            (-1, 0),
            (1, 0),
            (-1, 1),
            (0, 1),
            (1, 1),
        ] {
            let (_, added) = self.table.insert(tx.wrapping_add(dx), ty.wrapping_add(dy));
            if added {
                self.tiles.push(None);
                if let Some(f) = self.fields.get_mut() {
                    f.push(OnceLock::new());
                }
                if let Some(d) = &mut self.distance {
                    d.push_slot();
                }
            }
        }
        self.table.insert(tx, ty).0
    }

    /// Drops the cached fields of the given slots and their 8 neighbours (the obstacle
    /// margin never exceeds one tile).
    fn invalidate_fields(&mut self, mut changed: Vec<usize>) {
        let Some(fields) = self.fields.get_mut() else {
            return; // no field read yet: nothing cached
        };
        changed.sort_unstable();
        changed.dedup();
        for s in changed {
            let (tx, ty) = self.table.tile_of_slot(s);
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if let Some(n) = self.table.slot(tx + dx, ty + dy) {
                        fields[n] = OnceLock::new();
                    }
                }
            }
        }
    }

    /// Row-major obstacle flags of the `w × h` cells starting at `min`, and the mean hit
    /// offsets (1/256 cell from the centre) and hit counts of those cells.
    pub(crate) fn obstacle_mask(
        &self,
        min: CellIndex,
        w: usize,
        h: usize,
    ) -> (Vec<bool>, Vec<(i8, i8, u8)>) {
        let thr = self.params.occupied_threshold;
        let mut out = vec![false; w * h];
        let mut offsets = vec![(0i8, 0i8, 0u8); w * h];
        let t = TILE_SIZE as i32;
        // Walk tile by tile so each cell costs one array read.
        let (tx_lo, ty_lo) = (min.x >> tiles::TILE_BITS, min.y >> tiles::TILE_BITS);
        let max_x = min.x + w as i32 - 1;
        let max_y = min.y + h as i32 - 1;
        let (tx_hi, ty_hi) = (max_x >> tiles::TILE_BITS, max_y >> tiles::TILE_BITS);
        for ty in ty_lo..=ty_hi {
            for tx in tx_lo..=tx_hi {
                let Some(slot) = self.table.slot(tx, ty) else {
                    continue;
                };
                let Some(tile) = &self.tiles[slot] else {
                    continue;
                };
                let x0 = (tx * t).max(min.x);
                let x1 = (tx * t + t - 1).min(max_x);
                let y0 = (ty * t).max(min.y);
                let y1 = (ty * t + t - 1).min(max_y);
                for y in y0..=y1 {
                    let ly = (y - ty * t) as usize;
                    let oy = (y - min.y) as usize * w;
                    for x in x0..=x1 {
                        let k = ly * TILE_SIZE + (x - tx * t) as usize;
                        let o = oy + (x - min.x) as usize;
                        out[o] = tile.cells[k] > thr;
                        if let Some(h) = &tile.hit {
                            offsets[o] = (h.hit_x[k], h.hit_y[k], h.hits[k]);
                        }
                    }
                }
            }
        }
        (out, offsets)
    }

    /// The smallest rectangle of cells holding every observed (non-zero log-odds) cell, as
    /// inclusive corners; `None` for an empty grid.
    pub fn known_bounds(&self) -> Option<(CellIndex, CellIndex)> {
        self.stored_bounds(|v| v != 0.0)
    }

    /// The smallest rectangle of cells holding every obstacle
    /// ([`OccupancyGrid::is_obstacle`]) of [`OccupancyGrid::known_bounds`], as inclusive
    /// corners; `None` without one. Read tile by tile; cell by cell under a negative
    /// threshold, where unknown cells count as obstacles.
    pub fn obstacle_bounds(&self) -> Option<(CellIndex, CellIndex)> {
        let thr = self.params.occupied_threshold;
        if thr >= 0.0 {
            // An obstacle's log-odds exceed thr ≥ 0: it is an observed cell.
            return self.stored_bounds(|v| v > thr);
        }
        let (lo, hi) = self.known_bounds()?;
        let cells = (lo.y..=hi.y).flat_map(|y| (lo.x..=hi.x).map(move |x| CellIndex::new(x, y)));
        cells.filter(|&c| self.is_obstacle(c)).fold(None, |b, c| {
            let (l, h) = b.unwrap_or((c, c));
            Some((
                CellIndex::new(l.x.min(c.x), l.y.min(c.y)),
                CellIndex::new(h.x.max(c.x), h.y.max(c.y)),
            ))
        })
    }

    /// The smallest rectangle of the stored cells whose log-odds `keep` holds.
    fn stored_bounds(&self, keep: impl Fn(f32) -> bool) -> Option<(CellIndex, CellIndex)> {
        let t = TILE_SIZE as i32;
        let mut lo = CellIndex::new(i32::MAX, i32::MAX);
        let mut hi = CellIndex::new(i32::MIN, i32::MIN);
        for (s, tile) in self.tiles.iter().enumerate() {
            let Some(tile) = tile else { continue };
            let (tx, ty) = self.table.tile_of_slot(s);
            for (k, &v) in tile.cells.iter().enumerate() {
                if keep(v) {
                    let x = tx * t + (k % TILE_SIZE) as i32;
                    let y = ty * t + (k / TILE_SIZE) as i32;
                    lo.x = lo.x.min(x);
                    lo.y = lo.y.min(y);
                    hi.x = hi.x.max(x);
                    hi.y = hi.y.max(y);
                }
            }
        }
        (lo.x <= hi.x).then_some((lo, hi))
    }

    /// Exports the observed part of the grid as a [`GridMap`] (ROS convention: row 0 at the
    /// bottom, −1 unknown, else the occupancy probability in percent, rounded). An empty
    /// grid gives a 0×0 map.
    ///
    /// The map is dense over the bounding box of the observed cells, which lies within the
    /// covered area: at most [`MAX_MAP_CELLS`] cells (one byte each), because
    /// [`OccupancyGrid::ensure_covers`] refuses to grow the grid beyond that.
    pub fn to_grid_map(&self) -> GridMap {
        let Some((lo, hi)) = self.known_bounds() else {
            return GridMap::unknown(self.resolution(), self.frame.origin, 0, 0);
        };
        let w = (hi.x - lo.x + 1) as usize;
        let h = (hi.y - lo.y + 1) as usize;
        let res = self.resolution();
        let origin = Point2::new(
            self.frame.origin.x + lo.x as f64 * res,
            self.frame.origin.y + lo.y as f64 * res,
        );
        let mut map = GridMap::unknown(res, origin, w, h);
        for y in 0..h {
            for x in 0..w {
                let l = self.log_odds(CellIndex::new(lo.x + x as i32, lo.y + y as i32));
                if l != 0.0 {
                    let p = 1.0 - 1.0 / (1.0 + (l as f64).exp());
                    map.cells[y * w + x] = (p * 100.0).round().clamp(0.0, 100.0) as i8;
                }
            }
        }
        map
    }
}

#[cfg(test)]
mod tests;
