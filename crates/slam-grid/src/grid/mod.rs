//! The log-odds occupancy grid on copy-on-write tiles.

pub mod distance;
mod raytrace;
pub(crate) mod sensor_model;
pub(crate) mod tiles;

use crate::cell::{CellIndex, GridFrame};
use crate::error::{ensure_config, GridError};
use crate::likelihood::{compute_region, FieldTile, LikelihoodParams};
use crate::scan::PreparedScan;
use distance::{DistanceField, IncrementalDistance, MAX_DISTANCE_RADIUS};
pub(crate) use raytrace::trace_segment;
use sensor_model::InverseSensorModel;
use slam_models::{GridMap, LaserScan, Point2, Pose2};
use std::sync::{Arc, OnceLock};
use tiles::{split, Tile, TileLayout, TileTable, HIT_CAP, TILE_CELLS, TILE_SIZE};

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

/// Continuous cell coordinates (u, v) (see [`crate::cell`]).
type CellPoint = (f64, f64);

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
///   lazily by the matchers and shared between clones in the same way.
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
    params: LikelihoodParams,
    /// The covered rectangle and the sparse slot index of the stored tiles.
    table: TileTable,
    /// The bounding box of every cell the grid was asked to cover (no growth slack), the
    /// extent checked against [`MAX_MAP_EXTENT_CELLS`] and [`MAX_MAP_CELLS`].
    span: Option<(CellIndex, CellIndex)>,
    /// One entry per slot of `table.index`: `None` for a stored neighbour never written.
    tiles: Vec<Option<Arc<Tile>>>,
    /// The lazy likelihood field's cache, one cell per tile slot; the table itself is
    /// allocated on the first field read, so grids that never read the lazy field (grid
    /// FastSLAM's, which use the incremental one) have one table less to clone.
    fields: OnceLock<FieldCache>,
    far_field: Arc<FieldTile>,
    distance: Option<IncrementalDistance>,
    stats: CopyStats,
}

/// Lazily computed field tiles, one cell per tile slot.
type FieldCache = Vec<OnceLock<Arc<FieldTile>>>;

/// A field cache of `n` empty cells.
fn empty_field_cache(n: usize) -> FieldCache {
    (0..n).map(|_| OnceLock::new()).collect()
}

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
    /// the given inverse sensor model and default [`LikelihoodParams`].
    ///
    /// A non-finite or non-positive resolution is replaced by 0.05 m; use
    /// [`OccupancyGrid::try_new`] to have it rejected instead.
    pub fn new(resolution: f64, model: InverseSensorModel) -> Self {
        let resolution = if resolution.is_finite() && resolution > 0.0 {
            resolution
        } else {
            0.05
        };
        let params = LikelihoodParams::default();
        Self {
            frame: GridFrame::new(Point2::origin(), resolution),
            model,
            params,
            table: TileTable::default(),
            span: None,
            tiles: Vec::new(),
            fields: OnceLock::new(),
            far_field: Arc::new(FieldTile::far(&params)),
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

    /// This grid with its likelihood-field parameters replaced (cached fields dropped).
    pub fn with_likelihood(mut self, params: LikelihoodParams) -> Result<Self, GridError> {
        params.validate()?;
        self.params = params;
        self.far_field = Arc::new(FieldTile::far(&params));
        self.fields = OnceLock::new();
        // The obstacle threshold may have changed: rebuild the incremental field.
        if let Some(d) = self.distance.take() {
            return self.with_incremental_distance(d.radius() as u32);
        }
        Ok(self)
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

    /// The likelihood-field parameters.
    pub fn likelihood_params(&self) -> LikelihoodParams {
        self.params
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

    /// Bytes held by one tile (log-odds and mean hit positions of its cells; a grid whose
    /// [`LikelihoodParams::subcell`] is off keeps no hit positions: 4 KiB).
    pub const TILE_BYTES: usize = tiles::TILE_BYTES_WITH_HITS;

    /// Inclusive range of cells covered by the tile table (`None` while empty): the
    /// rectangle the grid has grown to, of which only the observed tiles are stored.
    pub fn covered_cells(&self) -> Option<(CellIndex, CellIndex)> {
        let r = self.table.rect();
        if r.len() == 0 {
            return None;
        }
        let t = TILE_SIZE as i32;
        Some((
            CellIndex::new(r.tx0 * t, r.ty0 * t),
            CellIndex::new((r.tx0 + r.tw) * t - 1, (r.ty0 + r.th) * t - 1),
        ))
    }

    /// Grows the covered rectangle so that it holds cells `min ..= max` (keeps existing
    /// tiles; stores nothing: tiles are stored when written).
    ///
    /// Fails with [`GridError::MapTooLarge`], changing nothing, when the bounding box of
    /// every cell covered so far and these would be wider or higher than
    /// [`MAX_MAP_EXTENT_CELLS`] or hold more than [`MAX_MAP_CELLS`] cells.
    pub fn ensure_covers(&mut self, min: CellIndex, max: CellIndex) -> Result<(), GridError> {
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
        self.span = Some((lo, hi));
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
    fn slot_for_write(&mut self, tx: i32, ty: i32) -> usize {
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

    /// Integrates one scan taken at `robot_pose` (world frame) with the inverse sensor model
    /// (PR table 9.1/9.2), tracing each beam exactly (Amanatides–Woo) from the sensor
    /// (`robot_pose ⊕ scan.sensor_pose`). Within one scan all free-space updates are applied
    /// before the hits, so a cell both crossed and hit ends up l_free + l_occ (with
    /// [`InverseSensorModel::protect_scan_hits`]: l_occ, once).
    ///
    /// Invalid input (a non-finite pose, NaN or negative readings) leaves the grid unchanged;
    /// [`OccupancyGrid::try_integrate_scan`] reports it instead.
    pub fn integrate_scan(&mut self, robot_pose: &Pose2, scan: &LaserScan) {
        let _ = self.try_integrate_scan(robot_pose, scan);
    }

    /// [`OccupancyGrid::integrate_scan`], returning an error for invalid input.
    pub fn try_integrate_scan(
        &mut self,
        robot_pose: &Pose2,
        scan: &LaserScan,
    ) -> Result<(), GridError> {
        let prepared = PreparedScan::new(scan)?;
        self.try_integrate_prepared(robot_pose, &prepared)
    }

    /// Integrates a [`PreparedScan`] (no trigonometry per beam: one `sin_cos` per call).
    pub fn try_integrate_prepared(
        &mut self,
        robot_pose: &Pose2,
        scan: &PreparedScan,
    ) -> Result<(), GridError> {
        if !robot_pose.is_finite() {
            return Err(GridError::NonFinite {
                what: "robot pose",
                value: f64::NAN,
            });
        }
        let sensor = robot_pose.compose(&scan.sensor_pose);
        let (s, c) = sensor.theta.sin_cos();
        let start = self.frame.world_to_continuous(&sensor.translation());
        let inv_res = 1.0 / self.frame.resolution;
        let m = self.model;
        // Segment ends in continuous cell coordinates, and whether the end cell is a hit.
        // (end of the free stretch, end point, hit?) in continuous cell coordinates.
        let mut segs: Vec<(CellPoint, CellPoint, bool)> = Vec::with_capacity(scan.beams.len());
        let (mut lo_x, mut lo_y, mut hi_x, mut hi_y) = (start.0, start.1, start.0, start.1);
        for b in &scan.beams {
            if b.range < m.min_range {
                continue;
            }
            // A hit beyond max_range (at or beyond it when far hits do not clear).
            let far = b.hit
                && if m.far_hits_clear {
                    b.range > m.max_range
                } else {
                    b.range >= m.max_range
                };
            let (len, hit) = if b.hit && !far {
                (b.range, true)
            } else if far && m.far_hits_clear {
                (m.max_range, false)
            } else {
                (m.no_return_range.min(b.range), false)
            };
            if len <= 0.0 {
                continue;
            }
            // Beam direction in the world: R(θ_sensor)·dir.
            let (dx, dy) = (c * b.dir.0 - s * b.dir.1, s * b.dir.0 + c * b.dir.1);
            let end = (start.0 + len * dx * inv_res, start.1 + len * dy * inv_res);
            let free_len = if hit {
                (len - m.hit_margin).max(0.0)
            } else {
                len
            };
            let free_end = (
                start.0 + free_len * dx * inv_res,
                start.1 + free_len * dy * inv_res,
            );
            lo_x = lo_x.min(end.0);
            lo_y = lo_y.min(end.1);
            hi_x = hi_x.max(end.0);
            hi_y = hi_y.max(end.1);
            segs.push((free_end, end, hit));
        }
        if !(lo_x.is_finite() && lo_y.is_finite() && hi_x.is_finite() && hi_y.is_finite()) {
            return Err(GridError::NonFinite {
                what: "beam end point",
                value: f64::NAN,
            });
        }
        const LIMIT: f64 = (1u32 << 30) as f64;
        if lo_x.abs() > LIMIT || lo_y.abs() > LIMIT || hi_x.abs() > LIMIT || hi_y.abs() > LIMIT {
            return Err(GridError::OutOfGrid {
                what: "beam end point",
                cells: lo_x.abs().max(hi_x.abs()).max(lo_y.abs()).max(hi_y.abs()),
            });
        }
        // With an incremental distance field the table extends `radius` cells beyond
        // every end point, so that no obstacle's stamp is cut off.
        let margin = self.distance.as_ref().map_or(0, |d| d.radius());
        let (lo, hi) = (
            CellIndex::new(lo_x.floor() as i32 - margin, lo_y.floor() as i32 - margin),
            CellIndex::new(hi_x.floor() as i32 + margin, hi_y.floor() as i32 + margin),
        );
        self.ensure_covers(lo, hi)?;
        // Free cells first, gathered as (slot, local) so consecutive cells of a tile are
        // written under one copy-on-write check. The slots are this scan's own, row-major
        // over the tiles it touches (one tile of border): sorting by them sorts by
        // (ty, tx), and their number is bounded by the map extent checked above.
        let (t0, _) = split(lo);
        let (t1, _) = split(hi);
        let layout = TileLayout {
            tx0: t0.0 - 1,
            ty0: t0.1 - 1,
            tw: t1.0 - t0.0 + 3,
            th: t1.1 - t0.1 + 3,
        };
        let mut free: Vec<(u32, u16)> = Vec::with_capacity(segs.len() * 64);
        let mut hits: Vec<(u32, u16, i8, i8)> = Vec::with_capacity(segs.len());
        let push = |v: &mut Vec<(u32, u16)>, cell: CellIndex| {
            let ((tx, ty), local) = split(cell);
            if let Some(slot) = layout.slot(tx, ty) {
                v.push((slot as u32, local as u16));
            }
        };
        for &(free_end, end, hit) in &segs {
            let last = trace_segment(start, free_end, |cell| push(&mut free, cell));
            if hit {
                let end_cell = CellIndex::new(end.0.floor() as i32, end.1.floor() as i32);
                let ((tx, ty), local) = split(end_cell);
                if let Some(slot) = layout.slot(tx, ty) {
                    // End point relative to its cell centre, in 1/256 cell.
                    let q = |f: f64| (f * 256.0).round().clamp(-128.0, 127.0) as i8;
                    let ox = q(end.0 - end_cell.x as f64 - 0.5);
                    let oy = q(end.1 - end_cell.y as f64 - 0.5);
                    hits.push((slot as u32, local as u16, ox, oy));
                }
            } else {
                push(&mut free, last);
            }
        }
        let mut changed: Vec<usize> = Vec::new();
        let mut flips: Vec<(u32, u16)> = Vec::new();
        let protected: &[(u32, u16, i8, i8)] = if m.protect_scan_hits {
            // Sorted by cell so that a tile's hits are found by binary search and a cell's
            // repeated hits are adjacent.
            hits.sort_unstable_by_key(|h| (h.0, h.1));
            &hits
        } else {
            &[]
        };
        self.apply(
            &layout,
            &free,
            m.l_free,
            protected,
            &mut changed,
            &mut flips,
        );
        self.apply_hits(
            &layout,
            &hits,
            m.l_occ,
            m.protect_scan_hits,
            &mut changed,
            &mut flips,
        );
        self.invalidate_fields(changed);
        if let Some(mut d) = self.distance.take() {
            let mut cells: Vec<CellIndex> = flips
                .iter()
                .map(|&(slot, local)| self.cell_of_slot(slot as usize, local as usize))
                .collect();
            d.repair(&self.table, &mut cells, |c| self.is_obstacle(c));
            self.distance = Some(d);
        }
        Ok(())
    }

    /// Cell `local` of the tile in `slot`.
    #[inline]
    fn cell_of_slot(&self, slot: usize, local: usize) -> CellIndex {
        let (tx, ty) = self.table.tile_of_slot(slot);
        let t = TILE_SIZE as i32;
        CellIndex::new(
            tx * t + (local % TILE_SIZE) as i32,
            ty * t + (local / TILE_SIZE) as i32,
        )
    }

    /// Adds `delta` to the listed cells (clamped), except to the cells of `protected`
    /// (sorted by slot), copying shared tiles on first write and recording the slots where
    /// some cell changed obstacle status, and (with an incremental distance field) those
    /// cells in `flips` as (slot, local index). `updates` and `protected` name tiles by
    /// their slot in `scan` (the scan's tiles); `changed` and `flips` get the grid's slots.
    fn apply(
        &mut self,
        scan: &TileLayout,
        updates: &[(u32, u16)],
        delta: f32,
        protected: &[(u32, u16, i8, i8)],
        changed: &mut Vec<usize>,
        flips: &mut Vec<(u32, u16)>,
    ) {
        let track = self.distance.is_some();
        let (lmin, lmax, thr) = (
            self.model.l_min,
            self.model.l_max,
            self.params.occupied_threshold,
        );
        // Updates come sorted by tile slot: handle each tile's run at once.
        for run in updates.chunk_by(|a, b| a.0 == b.0) {
            let (tx, ty) = scan.tile_of_slot(run[0].0 as usize);
            let stored = self.table.slot(tx, ty).and_then(|s| self.tiles[s].as_ref());
            let mask = protected_mask(protected, run[0].0);
            let skip = |l: u16| mask.is_some_and(|m| (m[l as usize >> 6] >> (l & 63)) & 1 == 1);
            // Skip the copy entirely when no value in the run would change (saturated cells).
            let needs_write = match stored {
                None => run.iter().any(|&(_, l)| !skip(l)),
                Some(t) => run.iter().any(|&(_, l)| {
                    let v = t.cells[l as usize];
                    !skip(l) && (v + delta).clamp(lmin, lmax) != v
                }),
            };
            if !needs_write {
                continue;
            }
            let slot = self.slot_for_write(tx, ty);
            let tile = self.tile_for_write(slot);
            let mut status_changed = false;
            for &(_, l) in run {
                if skip(l) {
                    continue;
                }
                let v = &mut tile.cells[l as usize];
                let nv = (*v + delta).clamp(lmin, lmax);
                let flip = (*v > thr) != (nv > thr);
                status_changed |= flip;
                *v = nv;
                if flip && track {
                    flips.push((slot as u32, l));
                }
            }
            if status_changed && changed.last() != Some(&slot) {
                changed.push(slot);
            }
        }
    }

    /// The tile of `slot`, private to this grid: created if absent, copied if shared
    /// (copy-on-write, counted in the stats).
    fn tile_for_write(&mut self, slot: usize) -> &mut Tile {
        let entry = &mut self.tiles[slot];
        let arc = match entry {
            None => {
                self.stats.tiles_created += 1;
                entry.insert(Arc::new(Tile::unknown(self.params.subcell)))
            }
            Some(a) => {
                if Arc::strong_count(a) > 1 {
                    self.stats.tiles_copied += 1;
                    self.stats.bytes_copied += a.bytes() as u64;
                }
                a
            }
        };
        Arc::make_mut(arc)
    }

    /// Adds `delta` (= l_occ) to the hit cells (once per cell when `once`, the updates
    /// then sorted by cell) and folds each end point into its cell's mean hit position
    /// (running mean over the first [`HIT_CAP`] hits).
    fn apply_hits(
        &mut self,
        scan: &TileLayout,
        updates: &[(u32, u16, i8, i8)],
        delta: f32,
        once: bool,
        changed: &mut Vec<usize>,
        flips: &mut Vec<(u32, u16)>,
    ) {
        let track = self.distance.is_some();
        let (lmin, lmax, thr) = (
            self.model.l_min,
            self.model.l_max,
            self.params.occupied_threshold,
        );
        // Updates come sorted by tile slot: handle each tile's run at once.
        for run in updates.chunk_by(|a, b| a.0 == b.0) {
            let (tx, ty) = scan.tile_of_slot(run[0].0 as usize);
            let stored = self.table.slot(tx, ty).and_then(|s| self.tiles[s].as_ref());
            let needs_write = match stored {
                None => true,
                Some(t) => run.iter().any(|&(_, l, _, _)| {
                    let v = t.cells[l as usize];
                    (v + delta).clamp(lmin, lmax) != v
                        || t.hit.as_ref().is_some_and(|h| h.hits[l as usize] < HIT_CAP)
                }),
            };
            if !needs_write {
                continue;
            }
            let slot = self.slot_for_write(tx, ty);
            let tile = self.tile_for_write(slot);
            let mut field_changed = false;
            for (i, &(_, l, ox, oy)) in run.iter().enumerate() {
                let repeat = once && i > 0 && run[i - 1].1 == l;
                let l = l as usize;
                let v = tile.cells[l];
                let nv = if repeat {
                    v
                } else {
                    (v + delta).clamp(lmin, lmax)
                };
                let flip = (v > thr) != (nv > thr);
                field_changed |= flip;
                if flip && track {
                    flips.push((slot as u32, l as u16));
                }
                tile.cells[l] = nv;
                let Some(h) = tile.hit.as_deref_mut() else {
                    continue;
                };
                let n = h.hits[l];
                if n < HIT_CAP {
                    let mean = |m: i8, o: i8| {
                        let m = m as i32;
                        (m + ((o as i32 - m) as f32 / (n as f32 + 1.0)).round() as i32)
                            .clamp(-128, 127) as i8
                    };
                    let (mx, my) = (mean(h.hit_x[l], ox), mean(h.hit_y[l], oy));
                    field_changed |= nv > thr && (mx != h.hit_x[l] || my != h.hit_y[l]);
                    h.hit_x[l] = mx;
                    h.hit_y[l] = my;
                    h.hits[l] = n + 1;
                }
            }
            if field_changed && changed.last() != Some(&slot) {
                changed.push(slot);
            }
        }
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

    /// The cached field tile of a slot, computed on first use.
    #[inline]
    fn field_tile(&self, slot: usize) -> &FieldTile {
        let fields = self
            .fields
            .get_or_init(|| empty_field_cache(self.table.len()));
        fields[slot].get_or_init(|| {
            let (tx, ty) = self.table.tile_of_slot(slot);
            let t = TILE_SIZE as i32;
            let margin = crate::likelihood::margin_cells_clamped(&self.params, self.resolution());
            match compute_region(
                self,
                CellIndex::new(tx * t, ty * t),
                TILE_SIZE,
                TILE_SIZE,
                margin,
            ) {
                None => self.far_field.clone(),
                Some((v, d2)) => {
                    let mut values = [0.0f32; TILE_CELLS];
                    values.copy_from_slice(&v);
                    let mut dist2 = [0.0f32; TILE_CELLS];
                    dist2.copy_from_slice(&d2);
                    Arc::new(FieldTile { values, dist2 })
                }
            }
        })
    }

    /// Likelihood-field value s ∈ (0, 1] of cell `c` (PR §6.4): exp(−d²/(2σ²)) with d the
    /// distance from the cell centre to the nearest obstacle cell (its mean hit position
    /// when `subcell` is on, else its centre), clamped to `max_distance`. Computed per tile
    /// on first use and cached.
    #[inline]
    pub fn likelihood(&self, c: CellIndex) -> f32 {
        let ((tx, ty), local) = split(c);
        match self.table.slot(tx, ty) {
            Some(s) => self.field_tile(s).values[local],
            None => self.far_field.values[0],
        }
    }

    /// Bilinear interpolation of the likelihood field at world point `p` between the four
    /// surrounding cell centres (Hector SLAM, Kohlbrecher et al. 2011, eq. 5–6), with its
    /// gradient in the world frame (per metre).
    #[inline]
    pub fn likelihood_interpolated(&self, p: &Point2) -> (f64, [f64; 2]) {
        let (u, v) = self.frame.world_to_continuous(p);
        let (u, v) = (u - 0.5, v - 0.5);
        let (x0, y0) = (u.floor(), v.floor());
        let (fx, fy) = (u - x0, v - y0);
        let (i, j) = (clamp_cell(x0), clamp_cell(y0));
        let blk = self.field_block::<2>(i, j, false);
        let (m00, m10) = (blk[0][0] as f64, blk[0][1] as f64);
        let (m01, m11) = (blk[1][0] as f64, blk[1][1] as f64);
        let val = fy * (fx * m11 + (1.0 - fx) * m01) + (1.0 - fy) * (fx * m10 + (1.0 - fx) * m00);
        let du = fy * (m11 - m01) + (1.0 - fy) * (m10 - m00);
        let dv = fx * (m11 - m10) + (1.0 - fx) * (m01 - m00);
        let inv = 1.0 / self.frame.resolution;
        (val, [du * inv, dv * inv])
    }

    /// The N×N block of field values (or squared distances) with lower-left cell (i0, j0),
    /// as `out[row][column]`; one tile lookup when the block lies inside one tile.
    #[inline]
    fn field_block<const N: usize>(&self, i0: i32, j0: i32, dist2: bool) -> [[f32; N]; N] {
        let mut out = [[0.0f32; N]; N];
        let n = N as i32 - 1;
        let bits = tiles::TILE_BITS;
        let (tx, ty) = (i0 >> bits, j0 >> bits);
        if tx == (i0 + n) >> bits && ty == (j0 + n) >> bits {
            let tile: &FieldTile = match self.table.slot(tx, ty) {
                Some(s) => self.field_tile(s),
                None => &self.far_field,
            };
            let arr = if dist2 { &tile.dist2 } else { &tile.values };
            let t = TILE_SIZE as i32;
            let (lx, ly) = ((i0 - tx * t) as usize, (j0 - ty * t) as usize);
            for (b, row) in out.iter_mut().enumerate() {
                let base = (ly + b) * TILE_SIZE + lx;
                row.copy_from_slice(&arr[base..base + N]);
            }
        } else {
            for (b, row) in out.iter_mut().enumerate() {
                for (a, v) in row.iter_mut().enumerate() {
                    let c = CellIndex::new(i0 + a as i32, j0 + b as i32);
                    *v = if dist2 {
                        self.distance_squared(c)
                    } else {
                        self.likelihood(c)
                    };
                }
            }
        }
        out
    }

    /// Squared distance d² (m², clamped to max_distance²) from the centre of cell `c` to the
    /// nearest obstacle, the quantity the field value is computed from.
    #[inline]
    pub fn distance_squared(&self, c: CellIndex) -> f32 {
        let ((tx, ty), local) = split(c);
        match self.table.slot(tx, ty) {
            Some(s) => self.field_tile(s).dist2[local],
            None => self.far_field.dist2[0],
        }
    }

    /// The likelihood field at world point `p` from a bicubic (Catmull-Rom) interpolation
    /// of the squared obstacle distance over the 4×4 surrounding cell centres:
    /// M = exp(−D/(2σ²)) with D the interpolated d², and its gradient in the world frame
    /// (per metre), ∇M = −M·∇D/(2σ²).
    ///
    /// Interpolating d² rather than M matters: Catmull-Rom reproduces quadratics, and
    /// d² = (x − w)² across a straight wall at w is one, so the peak lands on the wall's
    /// (mean hit) position instead of on a cell centre, as the bilinear interpolant's does.
    #[inline]
    pub fn likelihood_bicubic(&self, p: &Point2) -> (f64, [f64; 2]) {
        self.likelihood_bicubic_sigma(p, self.params.sigma)
    }

    /// [`OccupancyGrid::likelihood_bicubic`] with a σ of the caller's choice (metres, > 0)
    /// in M = exp(−D/(2σ²)): the squared distances do not depend on σ, so a refinement can
    /// use a narrower Gaussian than the field's own.
    #[inline]
    pub fn likelihood_bicubic_sigma(&self, p: &Point2, sigma: f64) -> (f64, [f64; 2]) {
        let (u, v) = self.frame.world_to_continuous(p);
        let (u, v) = (u - 0.5, v - 0.5);
        let (x0, y0) = (u.floor(), v.floor());
        let (wx, dwx) = catmull_rom_weights(u - x0);
        let (wy, dwy) = catmull_rom_weights(v - y0);
        let (i, j) = (clamp_cell(x0), clamp_cell(y0));
        let blk = self.field_block::<4>(i - 1, j - 1, true);
        let (mut val, mut du, mut dv) = (0.0, 0.0, 0.0);
        for (b, (&wyb, &dwyb)) in wy.iter().zip(&dwy).enumerate() {
            let (mut row, mut drow) = (0.0, 0.0);
            for (a, (&wxa, &dwxa)) in wx.iter().zip(&dwx).enumerate() {
                let m = blk[b][a] as f64;
                row += wxa * m;
                drow += dwxa * m;
            }
            val += wyb * row;
            du += wyb * drow;
            dv += dwyb * row;
        }
        let inv = 1.0 / self.frame.resolution;
        let k = -0.5 / (sigma * sigma);
        let m = (k * val.max(0.0)).exp();
        (m, [m * k * du * inv, m * k * dv * inv])
    }

    /// Copies the likelihood-field values of the `w × h` cells starting at `min` into a
    /// row-major buffer
    /// (tile by tile; cells outside the table get the far value).
    pub fn field_window(&self, min: CellIndex, w: usize, h: usize) -> Vec<f32> {
        let far = self.far_field.values[0];
        let mut out = vec![far; w * h];
        if w == 0 || h == 0 {
            return out;
        }
        let t = TILE_SIZE as i32;
        let max_x = min.x + w as i32 - 1;
        let max_y = min.y + h as i32 - 1;
        for ty in (min.y >> tiles::TILE_BITS)..=(max_y >> tiles::TILE_BITS) {
            for tx in (min.x >> tiles::TILE_BITS)..=(max_x >> tiles::TILE_BITS) {
                let Some(slot) = self.table.slot(tx, ty) else {
                    continue;
                };
                let f = self.field_tile(slot);
                let x0 = (tx * t).max(min.x);
                let x1 = (tx * t + t - 1).min(max_x);
                let y0 = (ty * t).max(min.y);
                let y1 = (ty * t + t - 1).min(max_y);
                for y in y0..=y1 {
                    let src = (y - ty * t) as usize * TILE_SIZE + (x0 - tx * t) as usize;
                    let dst = (y - min.y) as usize * w + (x0 - min.x) as usize;
                    let n = (x1 - x0 + 1) as usize;
                    out[dst..dst + n].copy_from_slice(&f.values[src..src + n]);
                }
            }
        }
        out
    }

    /// The smallest rectangle of cells holding every observed (non-zero log-odds) cell, as
    /// inclusive corners; `None` for an empty grid.
    pub fn known_bounds(&self) -> Option<(CellIndex, CellIndex)> {
        let t = TILE_SIZE as i32;
        let mut lo = CellIndex::new(i32::MAX, i32::MAX);
        let mut hi = CellIndex::new(i32::MIN, i32::MIN);
        for (s, tile) in self.tiles.iter().enumerate() {
            let Some(tile) = tile else { continue };
            let (tx, ty) = self.table.tile_of_slot(s);
            for (k, &v) in tile.cells.iter().enumerate() {
                if v != 0.0 {
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

/// The cells of tile `slot` among `protected` (sorted by slot) as a 1024-bit mask, or
/// `None` when it has none.
#[inline]
fn protected_mask(protected: &[(u32, u16, i8, i8)], slot: u32) -> Option<[u64; TILE_CELLS / 64]> {
    let a = protected.partition_point(|h| h.0 < slot);
    let b = a + protected[a..].partition_point(|h| h.0 == slot);
    (a < b).then(|| {
        let mut m = [0u64; TILE_CELLS / 64];
        for &(_, l, _, _) in &protected[a..b] {
            m[l as usize >> 6] |= 1 << (l & 63);
        }
        m
    })
}

/// A floored continuous cell coordinate as a cell index, clamped to ±2³⁰ so that the
/// interpolation's block arithmetic (a few cells beyond it) cannot overflow for a point
/// far off the map (such a point reads the far value either way).
#[inline]
fn clamp_cell(x: f64) -> i32 {
    const L: f64 = (1u32 << 30) as f64;
    x.clamp(-L, L) as i32
}

/// Catmull-Rom weights of the samples at −1, 0, 1, 2 for a point at t ∈ [0, 1), and
/// their derivatives with respect to t.
#[inline]
fn catmull_rom_weights(t: f64) -> ([f64; 4], [f64; 4]) {
    let t2 = t * t;
    let t3 = t2 * t;
    (
        [
            0.5 * (-t3 + 2.0 * t2 - t),
            0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
            0.5 * (-3.0 * t3 + 4.0 * t2 + t),
            0.5 * (t3 - t2),
        ],
        [
            0.5 * (-3.0 * t2 + 4.0 * t - 1.0),
            0.5 * (9.0 * t2 - 10.0 * t),
            0.5 * (-9.0 * t2 + 8.0 * t + 1.0),
            0.5 * (3.0 * t2 - 2.0 * t),
        ],
    )
}

#[cfg(test)]
mod tests;
