//! An incrementally repaired truncated distance field, stored per tile beside the occupancy.
//!
//! A grid built with [`crate::OccupancyGrid::with_incremental_distance`] keeps, for every
//! cell, the Euclidean distance from its centre to the nearest obstacle cell centre
//! (obstacle: log-odds > `occupied_threshold`, see [`crate::OccupancyGrid::is_obstacle`]),
//! truncated at `radius` cells and stored as a `u8` in 1/[`DISTANCE_UNITS_PER_CELL`] cell.
//! It is the likelihood field of the endpoint model (Probabilistic Robotics §6.4) in the
//! form a particle filter needs:
//!
//! * **shared like the occupancy**: one 32×32 `u8` tile per occupancy tile slot behind
//!   `Arc`, so grid clones share it and a write copies only the tiles it changes;
//! * **repaired in O(changed cells)**: scan integration reports the cells whose obstacle
//!   status flipped; around a cell that became an obstacle the distance kernel is stamped
//!   (dist ← min(dist, kernel)); around a cell that stopped being one, the window of
//!   `radius` cells is recomputed from the obstacles within 2·`radius`.
//!
//! The lazily computed field of [`crate::likelihood`] (exact EDT per tile, sub-cell hit
//! positions, recomputed after any change) is independent of this one and stays what the
//! standalone matchers use.
//!
//! Invariant (checked by the tests against a brute-force recomputation): after every
//! integration, every cell's value equals min(16·√(dx² + dy²), 16·radius) rounded, over the
//! obstacle cells at offset (dx, dy). The covered rectangle of such a grid always extends at
//! least `radius` cells beyond every obstacle, so no stamp is ever cut off at its border, and
//! the tiles within `radius` (< one tile) of an obstacle are stored: a written tile's eight
//! neighbours always are.

use super::tiles::{split, TileTable, TILE_BITS, TILE_CELLS, TILE_SIZE};
use crate::cell::{CellIndex, GridFrame};
use std::sync::Arc;

/// Distance units per cell: a stored value v means v / 16 cells.
pub const DISTANCE_UNITS_PER_CELL: f64 = 16.0;
/// Largest truncation radius, cells (16 · 15 = 240 fits a `u8`).
pub const MAX_DISTANCE_RADIUS: u32 = 15;

const TILE_MASK: i32 = TILE_SIZE as i32 - 1;

/// One tile of truncated distances, row-major like the occupancy tile.
#[derive(Debug, Clone)]
pub(crate) struct DistanceTile {
    dist: [u8; TILE_CELLS],
}

/// The precomputed stamp: min(16·√(dx² + dy²), 16·radius) for |dx|, |dy| ≤ radius.
#[derive(Debug)]
struct Kernel {
    radius: i32,
    /// 16·radius: the truncated value (also the value of a missing tile).
    max: u8,
    values: Vec<u8>,
}

impl Kernel {
    fn new(radius: i32) -> Self {
        let mut values = Vec::with_capacity(((2 * radius + 1) * (2 * radius + 1)) as usize);
        for dy in -radius..=radius {
            for dx in -radius..=radius {
                let d = ((dx * dx + dy * dy) as f64).sqrt().min(radius as f64);
                values.push((d * DISTANCE_UNITS_PER_CELL).round() as u8);
            }
        }
        Self {
            radius,
            max: (radius as f64 * DISTANCE_UNITS_PER_CELL).round() as u8,
            values,
        }
    }
}

/// The distance tiles of one grid, one per occupancy tile slot (same slot numbers).
#[derive(Debug, Clone)]
pub(crate) struct IncrementalDistance {
    kernel: Arc<Kernel>,
    tiles: Vec<Option<Arc<DistanceTile>>>,
}

impl IncrementalDistance {
    /// An all-far field of `slots` tiles, truncated at `radius` cells (1..=15).
    pub(crate) fn new(radius: u32, slots: usize) -> Self {
        Self {
            kernel: Arc::new(Kernel::new(radius.clamp(1, MAX_DISTANCE_RADIUS) as i32)),
            tiles: vec![None; slots],
        }
    }

    /// The truncation radius, cells.
    #[inline]
    pub(crate) fn radius(&self) -> i32 {
        self.kernel.radius
    }

    /// Adds an all-far tile for a new occupancy slot.
    pub(crate) fn push_slot(&mut self) {
        self.tiles.push(None);
    }

    /// A read-only view for matching.
    pub(crate) fn view<'a>(&'a self, table: &'a TileTable, frame: GridFrame) -> DistanceField<'a> {
        DistanceField {
            frame,
            table,
            tiles: &self.tiles,
            radius: self.kernel.radius,
            max: self.kernel.max,
        }
    }

    /// Forgets every value and stamps the given obstacle cells (a full rebuild).
    pub(crate) fn rebuild(&mut self, table: &TileTable, obstacles: &[CellIndex]) {
        self.tiles.iter_mut().for_each(|t| *t = None);
        for &c in obstacles {
            self.stamp(table, c);
        }
    }

    /// Restores the invariant after the cells in `flips` changed obstacle status
    /// (`is_obstacle` gives the status now; `obstacle_row(y, x0, out)` the status of the
    /// cells (x0 + i, y) into `out[i]`). `flips` is sorted and deduplicated in place.
    pub(crate) fn repair(
        &mut self,
        table: &TileTable,
        flips: &mut Vec<CellIndex>,
        is_obstacle: impl Fn(CellIndex) -> bool,
        obstacle_row: impl Fn(i32, i32, &mut [bool]),
    ) {
        flips.sort_unstable();
        flips.dedup();
        // Cells that are no longer obstacles: recompute their neighbourhood from scratch
        // (this also re-stamps every obstacle near them, new ones included).
        for &c in flips.iter() {
            if !is_obstacle(c) {
                self.recompute_window(table, c, &obstacle_row);
            }
        }
        // Cells that became obstacles: dist ← min(dist, kernel) around them.
        for &c in flips.iter() {
            if is_obstacle(c) {
                self.stamp(table, c);
            }
        }
    }

    /// The tile of `slot`, private to this grid (created all-far, or copied if shared).
    #[inline]
    fn tile_mut(&mut self, slot: usize) -> &mut DistanceTile {
        let max = self.kernel.max;
        let t = self.tiles[slot].get_or_insert_with(|| {
            Arc::new(DistanceTile {
                dist: [max; TILE_CELLS],
            })
        });
        Arc::make_mut(t)
    }

    /// dist ← min(dist, kernel) around obstacle cell `c`. Shared tiles are copied only
    /// where a value actually decreases.
    fn stamp(&mut self, table: &TileTable, c: CellIndex) {
        let kernel = Arc::clone(&self.kernel);
        let (rad, max) = (kernel.radius, kernel.max);
        let w = (2 * rad + 1) as usize;
        let (x0, y0, x1, y1) = (c.x - rad, c.y - rad, c.x + rad, c.y + rad);
        for y in y0..=y1 {
            let row = &kernel.values[(y - c.y + rad) as usize * w..][..w];
            let k_at = |x: i32| row[(x - c.x + rad) as usize];
            self.rewrite_row(table, y, x0, x1, |x, cur| {
                let k = k_at(x);
                (k < max && k < cur).then_some(k)
            });
        }
    }

    /// For the cells (x, y), x0 ≤ x ≤ x1, of stored tiles: writes `f(x, current value)`
    /// where it is `Some`, one tile look-up per tile the row crosses; a tile is made
    /// private (created all-far, or copied if shared) only when a value is written to it.
    #[inline]
    fn rewrite_row(
        &mut self,
        table: &TileTable,
        y: i32,
        x0: i32,
        x1: i32,
        f: impl Fn(i32, u8) -> Option<u8>,
    ) {
        let ty = y >> TILE_BITS;
        let row = (y & TILE_MASK) as usize * TILE_SIZE;
        let mut xa = x0;
        while xa <= x1 {
            let tx = xa >> TILE_BITS;
            // The last cell of this tile on the row, or x1.
            let xb = x1.min(xa | TILE_MASK);
            if let Some(slot) = table.slot(tx, ty) {
                let local = |x: i32| row + (x & TILE_MASK) as usize;
                // The first write, found on the tile as stored.
                let first = match &self.tiles[slot] {
                    Some(t) => (xa..=xb).find_map(|x| f(x, t.dist[local(x)]).map(|v| (x, v))),
                    None => (xa..=xb).find_map(|x| f(x, self.kernel.max).map(|v| (x, v))),
                };
                if let Some((xf, v)) = first {
                    let tile = self.tile_mut(slot);
                    tile.dist[local(xf)] = v;
                    for x in xf + 1..=xb {
                        if let Some(v) = f(x, tile.dist[local(x)]) {
                            tile.dist[local(x)] = v;
                        }
                    }
                }
            }
            xa = xb + 1;
        }
    }

    /// Recomputes the window of `radius` around `c` exactly from the obstacles within
    /// 2·`radius` of `c`: the window's values are found in a local buffer first and only
    /// the cells whose value changes are written, so a shared tile is copied only when it
    /// really changes.
    fn recompute_window(
        &mut self,
        table: &TileTable,
        c: CellIndex,
        obstacle_row: &impl Fn(i32, i32, &mut [bool]),
    ) {
        let kernel = Arc::clone(&self.kernel);
        let (rad, max) = (kernel.radius, kernel.max);
        let w = (2 * rad + 1) as usize;
        const W_MAX: usize = 2 * MAX_DISTANCE_RADIUS as usize + 1;
        let mut buf = [max; W_MAX * W_MAX];
        let mut row = [false; 4 * MAX_DISTANCE_RADIUS as usize + 1];
        let row = &mut row[..(4 * rad + 1) as usize];
        for oy in c.y - 2 * rad..=c.y + 2 * rad {
            obstacle_row(oy, c.x - 2 * rad, row);
            for (ox, _) in (c.x - 2 * rad..).zip(row.iter()).filter(|(_, &o)| o) {
                // The window's cells within the kernel of obstacle (ox, oy).
                let (x0, x1) = ((c.x - rad).max(ox - rad), (c.x + rad).min(ox + rad));
                for y in (c.y - rad).max(oy - rad)..=(c.y + rad).min(oy + rad) {
                    let n = (x1 - x0 + 1) as usize;
                    let k_row = &kernel.values[(y - oy + rad) as usize * w..];
                    let b_row = &mut buf[(y - c.y + rad) as usize * w..];
                    let ks = &k_row[(x0 - ox + rad) as usize..][..n];
                    let bs = &mut b_row[(x0 - c.x + rad) as usize..][..n];
                    for (b, &k) in bs.iter_mut().zip(ks) {
                        *b = (*b).min(k);
                    }
                }
            }
        }
        for y in c.y - rad..=c.y + rad {
            let b_row = &buf[(y - c.y + rad) as usize * w..][..w];
            self.rewrite_row(table, y, c.x - rad, c.x + rad, |x, cur| {
                let v = b_row[(x - c.x + rad) as usize];
                (v != cur).then_some(v)
            });
        }
    }
}

/// A read-only view of a grid's incrementally repaired truncated distance field (see the
/// [module documentation](self)), from [`crate::OccupancyGrid::distance_field`].
///
/// Values are in 1/[`DISTANCE_UNITS_PER_CELL`] cell, from the cell centre to the nearest
/// obstacle cell centre, truncated at [`DistanceField::max_units`]; cells outside the
/// grid's table read as truncated.
#[derive(Debug, Clone, Copy)]
pub struct DistanceField<'a> {
    frame: GridFrame,
    table: &'a TileTable,
    tiles: &'a [Option<Arc<DistanceTile>>],
    radius: i32,
    max: u8,
}

impl<'a> DistanceField<'a> {
    /// The grid's world ↔ cell frame.
    #[inline]
    pub fn frame(&self) -> GridFrame {
        self.frame
    }

    /// The truncation radius, cells.
    #[inline]
    pub fn radius_cells(&self) -> u32 {
        self.radius as u32
    }

    /// The truncated value, 16·radius (distance units).
    #[inline]
    pub fn max_units(&self) -> u8 {
        self.max
    }

    /// Metres per distance unit (resolution / 16).
    #[inline]
    pub fn metres_per_unit(&self) -> f64 {
        self.frame.resolution / DISTANCE_UNITS_PER_CELL
    }

    /// The inclusive cell rectangle of the grid's table (every tile it covers); every cell
    /// outside it reads [`DistanceField::max_units`]. `None` for an empty grid.
    pub(crate) fn covered(&self) -> Option<(CellIndex, CellIndex)> {
        self.table.covered_cells()
    }

    /// The stored tile (tx, ty), `None` when all far.
    #[inline]
    fn tile(&self, tx: i32, ty: i32) -> Option<&'a DistanceTile> {
        let tiles: &'a [Option<Arc<DistanceTile>>] = self.tiles;
        self.table.slot(tx, ty).and_then(|s| tiles[s].as_deref())
    }

    /// The cells of the stored tile (tx, ty), row-major, `None` when all far
    /// ([`DistanceField::max_units`]): for readers that cache a tile themselves.
    #[inline]
    pub(crate) fn tile_cells(&self, tx: i32, ty: i32) -> Option<&'a [u8; TILE_CELLS]> {
        self.tile(tx, ty).map(|t| &t.dist)
    }

    /// A reader that remembers the last tile it looked up ([`DistanceCursor`]).
    #[inline]
    pub fn cursor(&self) -> DistanceCursor<'a> {
        let tile = (i32::MIN, i32::MIN);
        DistanceCursor {
            field: *self,
            tile,
            data: self.tile(tile.0, tile.1),
        }
    }

    /// Truncated distance of cell `c` to the nearest obstacle, distance units.
    #[inline]
    pub fn dist(&self, c: CellIndex) -> u8 {
        let ((tx, ty), local) = split(c);
        match self
            .table
            .slot(tx, ty)
            .and_then(|s| self.tiles[s].as_deref())
        {
            Some(t) => t.dist[local],
            None => self.max,
        }
    }

    /// The distances of the cells `start`, `start` + (1, 0), …, one per element of `out`
    /// (a row of cells read tile by tile: the same values as [`DistanceField::dist`]).
    pub fn read_row(&self, start: CellIndex, out: &mut [u8]) {
        let ((_, ty), _) = split(start);
        let mut x = start.x;
        let mut rest = out;
        while !rest.is_empty() {
            let ((tx, _), local) = split(CellIndex::new(x, start.y));
            let lx = (x & TILE_MASK) as usize;
            let n = (TILE_SIZE - lx).min(rest.len());
            let (head, tail) = rest.split_at_mut(n);
            match self.tile(tx, ty) {
                Some(t) => head.copy_from_slice(&t.dist[local..local + n]),
                None => head.fill(self.max),
            }
            rest = tail;
            // Wrapping: a row running past i32::MAX reads on from i32::MIN, never overflows.
            x = x.wrapping_add(n as i32);
        }
    }

    /// The four distances [d(i, j), d(i+1, j), d(i, j+1), d(i+1, j+1)] around `c` = (i, j),
    /// the corners of a bilinear interpolation between cell centres; one tile look-up when
    /// all four lie in one tile.
    #[inline]
    pub fn dist4(&self, c: CellIndex) -> [u8; 4] {
        if (c.x & TILE_MASK) != TILE_MASK && (c.y & TILE_MASK) != TILE_MASK {
            let (tx, ty) = (c.x >> TILE_BITS, c.y >> TILE_BITS);
            match self
                .table
                .slot(tx, ty)
                .and_then(|s| self.tiles[s].as_deref())
            {
                Some(t) => {
                    let ((_, _), i) = split(c);
                    [
                        t.dist[i],
                        t.dist[i + 1],
                        t.dist[i + TILE_SIZE],
                        t.dist[i + TILE_SIZE + 1],
                    ]
                }
                None => [self.max; 4],
            }
        } else {
            // Wrapping: a cell at i32::MAX (a far-off pose, saturated) reads as far, never
            // overflows.
            let (x1, y1) = (c.x.wrapping_add(1), c.y.wrapping_add(1));
            [
                self.dist(c),
                self.dist(CellIndex::new(x1, c.y)),
                self.dist(CellIndex::new(c.x, y1)),
                self.dist(CellIndex::new(x1, y1)),
            ]
        }
    }
}

/// A [`DistanceField`] reader that remembers the last tile it looked up: a scan's
/// consecutive end points mostly fall in one 32×32 tile, so most reads skip the table
/// look-up. Reads the same values as the field itself.
#[derive(Debug, Clone, Copy)]
pub struct DistanceCursor<'a> {
    field: DistanceField<'a>,
    /// The tile `data` belongs to.
    tile: (i32, i32),
    data: Option<&'a DistanceTile>,
}

impl<'a> DistanceCursor<'a> {
    /// [`DistanceField::dist4`].
    #[inline]
    pub fn dist4(&mut self, c: CellIndex) -> [u8; 4] {
        if (c.x & TILE_MASK) != TILE_MASK && (c.y & TILE_MASK) != TILE_MASK {
            let t = (c.x >> TILE_BITS, c.y >> TILE_BITS);
            if t != self.tile {
                self.tile = t;
                self.data = self.field.tile(t.0, t.1);
            }
            match self.data {
                Some(t) => {
                    let ((_, _), i) = split(c);
                    [
                        t.dist[i],
                        t.dist[i + 1],
                        t.dist[i + TILE_SIZE],
                        t.dist[i + TILE_SIZE + 1],
                    ]
                }
                None => [self.field.max; 4],
            }
        } else {
            self.field.dist4(c)
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::grid::sensor_model::InverseSensorModel;
    use crate::{CellIndex, OccupancyGrid};
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64Mcg;
    use slam_models::{LaserScan, Point2, Pose2};

    use super::DISTANCE_UNITS_PER_CELL;

    fn grid(radius: u32) -> OccupancyGrid {
        let model = InverseSensorModel {
            l_free: -0.4,
            hit_margin: 0.0,
            no_return_range: 0.0,
            ..Default::default()
        };
        OccupancyGrid::new(0.05, model)
            .with_incremental_distance(radius)
            .unwrap()
    }

    fn scan(ranges: Vec<f64>) -> LaserScan {
        let (a, inc) = LaserScan::flaser_geometry(ranges.len());
        LaserScan {
            angle_min: a,
            angle_increment: inc,
            ranges,
            max_range: 80.0,
            sensor_pose: Pose2::IDENTITY,
        }
    }

    /// Brute force: the truncated distance from every cell of the window to the nearest
    /// obstacle cell, against the incrementally repaired field.
    fn check_field(g: &OccupancyGrid, x0: i32, y0: i32, x1: i32, y1: i32) {
        let f = g.distance_field().unwrap();
        let mut cursor = f.cursor();
        let rad = f.radius_cells() as i32;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let mut best = f.max_units();
                for dy in -rad..=rad {
                    for dx in -rad..=rad {
                        if g.is_obstacle(CellIndex::new(x + dx, y + dy)) {
                            let d = ((dx * dx + dy * dy) as f64).sqrt().min(rad as f64);
                            best = best.min((d * DISTANCE_UNITS_PER_CELL).round() as u8);
                        }
                    }
                }
                assert_eq!(f.dist(CellIndex::new(x, y)), best, "cell ({x}, {y})");
                let d4 = f.dist4(CellIndex::new(x, y));
                assert_eq!(d4[3], f.dist(CellIndex::new(x + 1, y + 1)));
                assert_eq!(cursor.dist4(CellIndex::new(x, y)), d4);
            }
        }
    }

    #[test]
    fn incremental_field_equals_brute_force_after_random_scans() {
        let mut g = grid(4);
        let mut rng = Pcg64Mcg::seed_from_u64(5);
        for i in 0..40 {
            let pose = Pose2::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-3.0..3.0),
            );
            // A room-ish scan with random ranges so that cells flip both ways.
            let ranges = (0..90).map(|_| rng.random_range(0.3..2.5)).collect();
            g.integrate_scan(&pose, &scan(ranges));
            if i % 10 == 9 {
                check_field(&g, -70, -70, 70, 70);
            }
        }
    }

    #[test]
    fn enabling_on_a_filled_grid_and_changing_the_threshold_rebuild_the_field() {
        let mut g = OccupancyGrid::new(0.05, InverseSensorModel::default());
        let mut rng = Pcg64Mcg::seed_from_u64(9);
        for _ in 0..5 {
            let ranges = (0..90).map(|_| rng.random_range(0.3..2.0)).collect();
            g.integrate_scan(&Pose2::new(0.01, 0.02, 0.3), &scan(ranges));
        }
        let g = g.with_incremental_distance(3).unwrap();
        check_field(&g, -50, -50, 50, 50);
        let params = crate::LikelihoodParams {
            occupied_threshold: 1.0,
            ..g.likelihood_params()
        };
        let g = g.with_likelihood(params).unwrap();
        check_field(&g, -50, -50, 50, 50);
        assert!(OccupancyGrid::new(0.05, InverseSensorModel::default())
            .with_incremental_distance(0)
            .is_err());
        assert!(OccupancyGrid::new(0.05, InverseSensorModel::default())
            .with_incremental_distance(16)
            .is_err());
    }

    #[test]
    fn read_row_reads_what_dist_reads() {
        let mut g = grid(4);
        g.integrate_scan(&Pose2::new(0.012, 0.013, 0.0), &scan(vec![3.02; 181]));
        let f = g.distance_field().unwrap();
        let mut seen = [false; 2];
        // Rows across stored and missing tiles, starting anywhere in a tile.
        for y in (-80..80).step_by(7) {
            for (x0, n) in [(-100, 250), (-33, 1), (31, 2), (5, 64), (-1, 97)] {
                let mut row = vec![1u8; n];
                f.read_row(CellIndex::new(x0, y), &mut row);
                for (i, &d) in row.iter().enumerate() {
                    let c = CellIndex::new(x0 + i as i32, y);
                    assert_eq!(d, f.dist(c), "{c:?}");
                    seen[usize::from(d == f.max_units())] = true;
                }
            }
        }
        assert_eq!(seen, [true, true], "rows read near and far cells");
    }

    #[test]
    fn clones_share_untouched_distance_tiles() {
        let mut a = grid(4);
        a.integrate_scan(&Pose2::new(0.012, 0.013, 0.0), &scan(vec![3.02; 181]));
        let mut b = a.clone();
        // A short scan far away changes a few tiles of b only.
        b.integrate_scan(&Pose2::new(2.5, 0.0, 0.0), &scan(vec![0.2; 181]));
        let (fa, fb) = (a.distance_field().unwrap(), b.distance_field().unwrap());
        let shared = fa
            .tiles
            .iter()
            .zip(fb.tiles)
            .filter(|(x, y)| match (x, y) {
                (Some(x), Some(y)) => std::sync::Arc::ptr_eq(x, y),
                _ => false,
            })
            .count();
        let own = fb.tiles.iter().flatten().count() - shared;
        assert!(
            shared > 0 && (1..=6).contains(&own),
            "{shared} shared, {own} own"
        );
        // a is unchanged by b's writes: its wall straight ahead is still at distance 0.
        let wall = a.world_to_cell(&Point2::new(3.032, 0.013));
        assert!(a.is_obstacle(wall));
        assert_eq!(fa.dist(wall), 0);
        check_field(&b, -20, -70, 110, 70);
    }
}
