//! Scan integration: each beam traced exactly from the sensor (Amanatides–Woo,
//! [`super::raytrace`]) and the inverse sensor model's log-odds added to the cells it
//! crosses and ends in (PR table 9.1/9.2), tile by tile under copy-on-write.
//!
//! Each beam's free cells are updated as the walk reaches them, the walk carrying the
//! cell's index inside its tile, so that a tile's data and the scan's hit mask for it are
//! looked up once per visit and the many cells already at the lower clamp cost a bit test.
//! The updates are the ones a list of every traced cell, applied in beam order, would make.

use super::raytrace::Ray;
use super::tiles::{split, Tile, TileLayout, HIT_CAP, TILE_BITS, TILE_CELLS, TILE_SIZE};
use super::OccupancyGrid;
use crate::cell::CellIndex;
use crate::error::GridError;
use crate::scan::{RangeData, RangeRules};
use slam_models::{LaserScan, Pose2};
use std::sync::Arc;

/// Continuous cell coordinates (u, v) (see [`crate::cell`]).
type CellPoint = (f64, f64);

/// A cell's column (row) inside its tile is `x & TILE_MASK` (`y & TILE_MASK`).
const TILE_MASK: i32 = TILE_SIZE as i32 - 1;

impl OccupancyGrid {
    /// Integrates one scan taken at `robot_pose` (world frame) with the inverse sensor model
    /// (PR table 9.1/9.2), tracing each beam exactly (Amanatides–Woo) from the sensor
    /// (`robot_pose ⊕ scan.sensor_pose`). Within one scan all free-space updates are applied
    /// before the hits, so a cell both crossed and hit ends up l_free + l_occ (with
    /// [`crate::InverseSensorModel::protect_scan_hits`]: l_occ, once).
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
        let data = RangeData::new(scan, &self.model)?;
        self.try_integrate_prepared(robot_pose, &data)
    }

    /// Integrates a scan classified at the door ([`RangeData`], built under this grid's
    /// sensor model: [`GridError::OtherRangeRules`] otherwise): each return marks its end
    /// cell and clears the space up to `hit_margin` before it, each miss clears its length;
    /// no trigonometry per beam (one `sin_cos` per call).
    pub fn try_integrate_prepared(
        &mut self,
        robot_pose: &Pose2,
        scan: &RangeData,
    ) -> Result<(), GridError> {
        let Footprint {
            start,
            segs,
            lo,
            hi,
        } = self.footprint(robot_pose, scan)?;
        self.ensure_covers(lo, hi)?;
        self.integrate_footprint(start, &segs, lo, hi);
        Ok(())
    }

    /// Whether [`OccupancyGrid::try_integrate_prepared`] would accept this scan at this
    /// pose, without changing the grid: the same checks (a finite pose, finite end points
    /// within ±2³⁰ cells, the map extent limits), so that a caller can report an error at
    /// the scan that caused it and integrate later.
    pub fn check_integrable(&self, robot_pose: &Pose2, scan: &RangeData) -> Result<(), GridError> {
        let f = self.footprint(robot_pose, scan)?;
        self.check_extent(f.lo, f.hi).map(|_| ())
    }

    /// The beams of `scan` at `robot_pose` as segments in continuous cell coordinates and
    /// the cells they need covered, or the error the integration reports.
    fn footprint(&self, robot_pose: &Pose2, scan: &RangeData) -> Result<Footprint, GridError> {
        if !robot_pose.is_finite() {
            return Err(GridError::NonFinite {
                what: "robot pose",
                value: f64::NAN,
            });
        }
        if scan.rules != RangeRules::of(&self.model) {
            return Err(GridError::OtherRangeRules);
        }
        let sensor = robot_pose.compose(&scan.origin);
        let (s, c) = sensor.theta.sin_cos();
        let start = self.frame.world_to_continuous(&sensor.translation());
        let inv_res = 1.0 / self.frame.resolution;
        let m = self.model;
        // (end of the free stretch, end point, hit?) in continuous cell coordinates: the
        // returns, then the misses. The order of the free stretches changes nothing (each
        // adds the same l_free, and the changed cells are sorted before the fields are
        // repaired); the hits keep scan order (their running mean position).
        let mut segs: Vec<(CellPoint, CellPoint, bool)> =
            Vec::with_capacity(scan.returns.len() + scan.misses.len());
        let (mut lo_x, mut lo_y, mut hi_x, mut hi_y) = (start.0, start.1, start.0, start.1);
        let rays =
            (scan.returns.iter().map(|r| (r, true))).chain(scan.misses.iter().map(|r| (r, false)));
        for (b, hit) in rays {
            let len = b.length;
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
        Ok(Footprint {
            start,
            segs,
            lo,
            hi,
        })
    }

    /// The integration proper of a [`Footprint`] whose cells `lo ..= hi` are covered.
    fn integrate_footprint(
        &mut self,
        start: CellPoint,
        segs: &[(CellPoint, CellPoint, bool)],
        lo: CellIndex,
        hi: CellIndex,
    ) {
        let m = self.model;
        // The scan's own tile slots, row-major over the tiles it touches (one tile of
        // border): sorting hits by them sorts by (ty, tx), and their number is bounded by
        // the map extent checked above.
        let (t0, _) = split(lo);
        let (t1, _) = split(hi);
        let layout = TileLayout {
            tx0: t0.0 - 1,
            ty0: t0.1 - 1,
            tw: t1.0 - t0.0 + 3,
            th: t1.1 - t0.1 + 3,
        };
        let mut hits: Vec<(u32, u16, i8, i8)> = Vec::with_capacity(segs.len());
        for &(_, end, hit) in segs {
            if !hit {
                continue;
            }
            let end_cell = CellIndex::new(end.0.floor() as i32, end.1.floor() as i32);
            let ((tx, ty), local) = split(end_cell);
            if let Some(slot) = layout.slot(tx, ty) {
                // End point relative to its cell centre, in 1/256 cell.
                let q = |f: f64| (f * 256.0).round().clamp(-128.0, 127.0) as i8;
                let ox = q(end.0 - end_cell.x as f64 - 0.5);
                let oy = q(end.1 - end_cell.y as f64 - 0.5);
                hits.push((slot as u32, local as u16, ox, oy));
            }
        }
        let mut changed: Vec<usize> = Vec::new();
        let mut flips: Vec<(u32, u16)> = Vec::new();
        let mut protected = if m.protect_scan_hits {
            // Sorted by cell so that a cell's repeated hits are adjacent.
            hits.sort_unstable_by_key(|h| (h.0, h.1));
            ProtectedMasks::new(&hits)
        } else {
            ProtectedMasks::new(&[])
        };
        // Free cells first, beam by beam (returns, then misses, each in scan order), each
        // walked cell by cell (its end cell too when it is a miss).
        for &(free_end, _, hit) in segs {
            let walk = TileWalk::new(start, free_end, !hit);
            self.apply_free(
                &layout,
                walk,
                m.l_free,
                &mut protected,
                &mut changed,
                &mut flips,
            );
        }
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
            d.repair(
                &self.table,
                &mut cells,
                |c| self.is_obstacle(c),
                |y, x0, out| self.obstacle_row(y, x0, out),
            );
            self.distance = Some(d);
        }
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

    /// Adds `delta` (clamped) to the cells `walk` visits, in its order, except to the cells
    /// of `protected` (the scan's hits, by scan slot) and to cells at the lower clamp when
    /// `delta` ≤ 0. A tile is made private (created or copied) only when one of its cells
    /// really changes, as a per-cell list applied in the same order would; the grid slots
    /// whose tiles had a cell change obstacle status go to `changed`, and (with an
    /// incremental distance field) those cells to `flips` as (slot, local index).
    fn apply_free(
        &mut self,
        scan: &TileLayout,
        mut walk: TileWalk,
        delta: f32,
        protected: &mut ProtectedMasks,
        changed: &mut Vec<usize>,
        flips: &mut Vec<(u32, u16)>,
    ) {
        if walk.left == 0 {
            return;
        }
        let track = self.distance.is_some();
        let (lmin, lmax, thr) = (
            self.model.l_min,
            self.model.l_max,
            self.params.occupied_threshold,
        );
        let use_floor = delta <= 0.0;
        // One pass per visit of the walk to a tile: the tile's stored data and hit mask are
        // looked up once, then its cells are stepped through by their local index.
        loop {
            walk.enter_tile();
            let (tx, ty) = walk.tile();
            // Every cell of a beam lies in the scan's tiles (its bounding box is covered).
            debug_assert!(scan.contains(tx, ty));
            let mask = match scan.slot(tx, ty) {
                Some(s) if !protected.is_empty() => protected.get(s as u32),
                _ => None,
            };
            let skip = |l: usize| mask.is_some_and(|m| is_set(m, l));
            // A cell at the lower clamp cannot change under a negative step (its floor bit
            // is read instead of its value).
            let floored = |t: &Tile, l: usize| use_floor && t.at_floor(l);
            let stored = self
                .table
                .slot(tx, ty)
                .and_then(|s| self.tiles[s].as_deref());
            // Read only until the first cell whose value changes (saturated cells leave a
            // shared tile shared).
            let mut next = Next::InTile;
            let write = match walk.seek_change(stored, mask, delta, lmin, lmax) {
                None => true,
                Some(n) => {
                    next = n;
                    false
                }
            };
            if write {
                let slot = self.slot_for_write(tx, ty);
                let tile = self.tile_for_write(slot);
                let mut status_changed = false;
                loop {
                    let l = walk.local();
                    if !skip(l) && !floored(tile, l) {
                        let v = tile.cells[l];
                        let nv = (v + delta).clamp(lmin, lmax);
                        let flip = (v > thr) != (nv > thr);
                        status_changed |= flip;
                        tile.set(l, nv, lmin);
                        if flip && track {
                            flips.push((slot as u32, l as u16));
                        }
                    }
                    next = walk.advance();
                    if next != Next::InTile {
                        break;
                    }
                }
                if status_changed && changed.last() != Some(&slot) {
                    changed.push(slot);
                }
            }
            if next == Next::Done {
                return;
            }
        }
    }

    /// The tile of `slot`, private to this grid: created if absent, copied if shared
    /// (copy-on-write, counted in the stats).
    pub(super) fn tile_for_write(&mut self, slot: usize) -> &mut Tile {
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
                tile.set(l, nv, lmin);
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
}

/// A scan placed on the grid: the sensor's position and per beam (end of the free stretch,
/// end point, hit?) in continuous cell coordinates, and the cells `lo ..= hi` the
/// integration needs covered.
struct Footprint {
    start: CellPoint,
    segs: Vec<(CellPoint, CellPoint, bool)>,
    lo: CellIndex,
    hi: CellIndex,
}

/// A beam's walk over the grid ([`Ray`]) that also keeps the current cell's index inside
/// its tile: an x step moves it by ±1 and a y step by ±[`TILE_SIZE`], so the walk knows
/// without a look-up when it leaves a tile.
#[derive(Clone, Copy)]
struct TileWalk {
    ray: Ray,
    /// Current cell's column and row inside its tile (leaving 0 ..< TILE_SIZE: a new tile).
    lx: i32,
    ly: i32,
    /// Cells still to visit, the current one included.
    left: u32,
}

/// Where a [`TileWalk`] stands after a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Next {
    /// In the same tile as before.
    InTile,
    /// In another tile ([`TileWalk::enter_tile`] before reading it).
    NewTile,
    /// Past its last cell.
    Done,
}

impl TileWalk {
    /// The cells a [`Ray`] from `start` to `end` visits before its end cell, and the end
    /// cell too when `with_end`.
    #[inline]
    fn new(start: CellPoint, end: CellPoint, with_end: bool) -> Self {
        let ray = Ray::new(start, end);
        Self {
            ray,
            lx: 0,
            ly: 0,
            left: ray.steps_left() + with_end as u32,
        }
    }

    /// Takes up the current cell's position inside its (new) tile.
    #[inline(always)]
    fn enter_tile(&mut self) {
        self.lx = self.ray.x & TILE_MASK;
        self.ly = self.ray.y & TILE_MASK;
    }

    /// The current tile's coordinates.
    #[inline(always)]
    fn tile(&self) -> (i32, i32) {
        (self.ray.x >> TILE_BITS, self.ray.y >> TILE_BITS)
    }

    /// The current cell's index inside its tile.
    #[inline(always)]
    fn local(&self) -> usize {
        // (The mask changes nothing, lx and ly being in 0 ..< TILE_SIZE; it spares the
        // bounds checks of the reads.)
        (((self.ly as usize) << TILE_BITS) | self.lx as usize) & (TILE_CELLS - 1)
    }

    /// Walks on through the current tile (`tile`, `None` when unknown) while the cells
    /// would keep their value under `delta` (clamped to `lmin ..= lmax`) or are in `mask`:
    /// `None` standing on the first cell that changes, else where the walk went. Kept out
    /// of line, on a copy of the walk, so that its state stays in registers.
    #[inline(never)]
    fn seek_change(
        &mut self,
        tile: Option<&Tile>,
        mask: Option<&TileMask>,
        delta: f32,
        lmin: f32,
        lmax: f32,
    ) -> Option<Next> {
        let mut w = *self;
        let use_floor = delta <= 0.0;
        let skip = |l: usize| mask.is_some_and(|m| is_set(m, l));
        let found = match tile {
            None => loop {
                if !skip(w.local()) {
                    break None;
                }
                match w.advance() {
                    Next::InTile => {}
                    n => break Some(n),
                }
            },
            Some(t) => loop {
                let l = w.local();
                let keeps = skip(l) || (use_floor && t.at_floor(l)) || {
                    let v = t.cells[l];
                    (v + delta).clamp(lmin, lmax) == v
                };
                if !keeps {
                    break None;
                }
                match w.advance() {
                    Next::InTile => {}
                    n => break Some(n),
                }
            },
        };
        *self = w;
        found
    }

    /// Moves on to the next cell.
    #[inline(always)]
    fn advance(&mut self) -> Next {
        self.left -= 1;
        if self.left == 0 {
            return Next::Done;
        }
        if self.ray.step() {
            self.lx += self.ray.step_x;
        } else {
            self.ly += self.ray.step_y;
        }
        // A negative coordinate reads as a huge unsigned one.
        if ((self.lx | self.ly) as u32) < TILE_SIZE as u32 {
            Next::InTile
        } else {
            Next::NewTile
        }
    }
}

/// One bit per cell of a tile (bit `l & 63` of word `l >> 6` for cell `l`).
type TileMask = [u64; TILE_CELLS / 64];

/// Whether cell `l`'s bit is set in `m`.
#[inline(always)]
fn is_set(m: &TileMask, l: usize) -> bool {
    (m[l >> 6] >> (l & 63)) & 1 == 1
}

/// The hit cells of one scan by tile (the cells its other beams must not clear), looked up
/// on each visit of a beam to a tile: the tiles with hits by binary search over their scan
/// slots, behind a small direct-mapped memo of recent look-ups (neighbouring beams visit
/// the same tiles in turn).
struct ProtectedMasks {
    /// Scan slots of the tiles with hits, ascending.
    slots: Vec<u32>,
    /// Per entry of `slots`, the mask of its hit cells.
    masks: Vec<TileMask>,
    /// Per `slot % MEMO`, the last slot looked up there and its index in `slots`
    /// (`u32::MAX`: none); an empty entry has slot `u32::MAX`.
    memo: [(u32, u32); MEMO],
}

/// Entries of [`ProtectedMasks`]' memo.
const MEMO: usize = 64;

impl ProtectedMasks {
    /// The masks of `hits` (sorted by scan slot).
    fn new(hits: &[(u32, u16, i8, i8)]) -> Self {
        let mut slots = Vec::new();
        let mut masks = Vec::new();
        for run in hits.chunk_by(|a, b| a.0 == b.0) {
            let mut m = [0u64; TILE_CELLS / 64];
            for &(_, l, _, _) in run {
                m[l as usize >> 6] |= 1 << (l & 63);
            }
            slots.push(run[0].0);
            masks.push(m);
        }
        Self {
            slots,
            masks,
            memo: [(u32::MAX, u32::MAX); MEMO],
        }
    }

    /// True when the scan has no protected cell.
    #[inline]
    fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// The mask of the tile in scan slot `slot`, or `None` when it has no hit.
    #[inline]
    fn get(&mut self, slot: u32) -> Option<&TileMask> {
        let e = &mut self.memo[slot as usize % MEMO];
        if e.0 != slot {
            let i = self
                .slots
                .binary_search(&slot)
                .map_or(u32::MAX, |i| i as u32);
            *e = (slot, i);
        }
        self.masks.get(e.1 as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::trace_segment;
    use crate::InverseSensorModel;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64Mcg;
    use std::collections::{HashMap, HashSet};

    /// A full-circle scan of `n` beams with random ranges: short ones, hits within reach,
    /// hits beyond `max_range` and no returns (the scan's own limit, 8 m).
    fn random_scan(rng: &mut Pcg64Mcg, n: usize) -> LaserScan {
        let ranges = (0..n)
            .map(|_| match rng.random_range(0..10) {
                0 => rng.random_range(0.0..0.1),
                1 => 8.0,
                2 => rng.random_range(4.0..8.0),
                _ => rng.random_range(0.1..4.0),
            })
            .collect();
        LaserScan {
            angle_min: -std::f64::consts::PI,
            angle_increment: 2.0 * std::f64::consts::PI / n as f64,
            ranges,
            max_range: 8.0,
            sensor_pose: Pose2::new(0.1, -0.05, 0.2),
        }
    }

    fn random_pose(rng: &mut Pcg64Mcg) -> Pose2 {
        Pose2::new(
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.2..3.2),
        )
    }

    /// The straightforward integration: every traced cell in a list, in beam order, each
    /// updated by reading and writing its value through the grid's public log-odds; then
    /// the hits. Returns the new log-odds of every cell the scan touches, and the tiles
    /// that must be made private: those where a free update changes a value, and those
    /// whose hits change a value or a hit statistic (or that are not stored yet).
    fn reference(
        g: &OccupancyGrid,
        pose: &Pose2,
        scan: &LaserScan,
    ) -> (HashMap<CellIndex, f32>, HashSet<(i32, i32)>) {
        let m = *g.sensor_model();
        let f = g
            .footprint(pose, &RangeData::new(scan, &m).unwrap())
            .unwrap();
        let mut free = Vec::new();
        let mut hits = Vec::new();
        for &(free_end, end, hit) in &f.segs {
            let last = trace_segment(f.start, free_end, |c| free.push(c));
            if hit {
                hits.push(CellIndex::new(end.0.floor() as i32, end.1.floor() as i32));
            } else {
                free.push(last);
            }
        }
        let protected: HashSet<CellIndex> = if m.protect_scan_hits {
            hits.iter().copied().collect()
        } else {
            HashSet::new()
        };
        let stored = |c: CellIndex| {
            let ((tx, ty), l) = split(c);
            g.table
                .slot(tx, ty)
                .and_then(|s| g.tiles[s].as_ref())
                .map(|t| (t, l))
        };
        let mut values: HashMap<CellIndex, f32> = HashMap::new();
        let mut written = HashSet::new();
        for c in free {
            if protected.contains(&c) {
                continue;
            }
            let v = *values.entry(c).or_insert_with(|| g.log_odds(c));
            let nv = (v + m.l_free).clamp(m.l_min, m.l_max);
            if nv != v || stored(c).is_none() {
                written.insert(split(c).0);
            }
            values.insert(c, nv);
        }
        let mut marked = HashSet::new();
        for c in hits {
            let v = *values.entry(c).or_insert_with(|| g.log_odds(c));
            let nv = (v + m.l_occ).clamp(m.l_min, m.l_max);
            let counts =
                stored(c).is_none_or(|(t, l)| t.hit.as_ref().is_some_and(|h| h.hits[l] < HIT_CAP));
            if nv != v || counts {
                written.insert(split(c).0);
            }
            if m.protect_scan_hits && !marked.insert(c) {
                continue;
            }
            values.insert(c, nv);
        }
        (values, written)
    }

    /// Every stored tile's floor bits say exactly which cells are at `l_min`.
    fn check_floor_bits(g: &OccupancyGrid) {
        let l_min = g.sensor_model().l_min;
        for tile in g.tiles.iter().flatten() {
            for (l, &v) in tile.cells.iter().enumerate() {
                assert_eq!(tile.at_floor(l), v == l_min, "cell {l}: {v}");
            }
        }
    }

    /// Truncated distance from each cell of the window to the nearest obstacle, by brute
    /// force, against the incrementally repaired field.
    fn check_distance(g: &OccupancyGrid, lo: CellIndex, hi: CellIndex) {
        let f = g.distance_field().unwrap();
        let rad = f.radius_cells() as i32;
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                let mut best = f.max_units();
                for dy in -rad..=rad {
                    for dx in -rad..=rad {
                        if g.is_obstacle(CellIndex::new(x + dx, y + dy)) {
                            let d = ((dx * dx + dy * dy) as f64).sqrt().min(rad as f64);
                            let units =
                                (d * super::super::distance::DISTANCE_UNITS_PER_CELL).round() as u8;
                            best = best.min(units);
                        }
                    }
                }
                assert_eq!(f.dist(CellIndex::new(x, y)), best, "cell ({x}, {y})");
            }
        }
    }

    /// On random maps and scans, for every combination of the options that change which
    /// cells a scan writes, the tile walk leaves exactly the log-odds of the per-cell
    /// reference, consistent floor bits and a correct distance field, creates and copies
    /// exactly the tiles where something changes, and a clone that shared the tiles keeps
    /// its values; the grid's obstacle rows agree with its per-cell obstacle test.
    #[test]
    fn tile_walk_equals_the_per_cell_reference_on_random_scans() {
        let mut rng = Pcg64Mcg::seed_from_u64(21);
        for case in 0..16 {
            let model = InverseSensorModel {
                l_free: -0.7,
                l_min: -2.0,
                max_range: 5.0,
                no_return_range: if case & 4 == 0 { 3.0 } else { 0.0 },
                hit_margin: if case & 8 == 0 { 0.05 } else { 0.0 },
                protect_scan_hits: case & 1 == 1,
                far_hits_clear: case & 2 == 2,
                ..Default::default()
            };
            let mut g = OccupancyGrid::try_new(0.05, model).unwrap();
            let with_distance = case % 3 != 0;
            if with_distance {
                g = g.with_incremental_distance(3).unwrap();
            }
            for _ in 0..12 {
                let (pose, scan) = (random_pose(&mut rng), random_scan(&mut rng, 120));
                g.try_integrate_scan(&pose, &scan).unwrap();
            }
            for _ in 0..4 {
                let (pose, scan) = (random_pose(&mut rng), random_scan(&mut rng, 120));
                let (expected, written) = reference(&g, &pose, &scan);
                // Every stored tile of `h` is shared with `g`: a write copies it.
                let was_stored = |&(tx, ty): &(i32, i32)| {
                    g.table
                        .slot(tx, ty)
                        .and_then(|s| g.tiles[s].as_ref())
                        .is_some()
                };
                let copies = written.iter().filter(|t| was_stored(t)).count() as u64;
                let creations = written.len() as u64 - copies;
                let (lo, hi) = g.known_bounds().unwrap();
                let (lo, hi) = (
                    CellIndex::new(lo.x - 200, lo.y - 200),
                    CellIndex::new(hi.x + 200, hi.y + 200),
                );
                let mut before = Vec::new();
                for y in lo.y..=hi.y {
                    for x in lo.x..=hi.x {
                        before.push(g.log_odds(CellIndex::new(x, y)));
                    }
                }
                let mut h = g.clone();
                h.reset_copy_stats();
                h.try_integrate_scan(&pose, &scan).unwrap();
                let st = h.copy_stats();
                assert_eq!((st.tiles_created, st.tiles_copied), (creations, copies));
                let mut i = 0;
                for y in lo.y..=hi.y {
                    for x in lo.x..=hi.x {
                        let c = CellIndex::new(x, y);
                        let want = expected.get(&c).copied().unwrap_or(before[i]);
                        assert_eq!(h.log_odds(c), want, "case {case}, cell {c:?}");
                        assert_eq!(g.log_odds(c), before[i], "the clone's source changed");
                        i += 1;
                    }
                }
                assert!(expected.values().any(|&v| v == model.l_min));
                check_floor_bits(&h);
                // The row reader the distance repair uses agrees with `is_obstacle`, across
                // tile edges and into tiles never written.
                let c = h.world_to_cell(&pose.translation());
                let mut row = [false; 301];
                for y in c.y - 150..=c.y + 150 {
                    h.obstacle_row(y, c.x - 150, &mut row);
                    for (i, &o) in row.iter().enumerate() {
                        let cell = CellIndex::new(c.x - 150 + i as i32, y);
                        assert_eq!(o, h.is_obstacle(cell), "{cell:?}");
                    }
                }
                if with_distance {
                    // Beams reach 5 m (100 cells) from the sensor.
                    let c = h.world_to_cell(&pose.translation());
                    let r = 110;
                    check_distance(
                        &h,
                        CellIndex::new(c.x - r, c.y - r),
                        CellIndex::new(c.x + r, c.y + r),
                    );
                }
                g = h;
            }
        }
    }
}
