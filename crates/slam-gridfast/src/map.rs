//! A particle's map: a log-odds occupancy grid made of copy-on-write tiles, with a
//! truncated distance field (the likelihood field of the endpoint model, PR §6.4)
//! **maintained incrementally** in the same tiles.
//!
//! Why here and not in slam-grid: a particle filter matches every scan of every particle
//! against that particle's own map, so the distance field must be (a) shared between
//! particles exactly like the occupancy (tile by tile, copy on write) and (b) updated in
//! O(changed cells), not recomputed per match. Both need the cell writes of the scan
//! integration to report which cells changed occupancy, which is internal to this module.
//!
//! Cell (cx, cy) covers [cx·r, (cx+1)·r) × [cy·r, (cy+1)·r) in the world frame (r the
//! resolution). Tiles are 32 × 32 cells; tile (tx, ty) = (cx >> 5, cy >> 5). The tile
//! table grows on demand; a missing tile is unknown space (log-odds 0, no occupied cell).
//!
//! The field stores, per cell, the Euclidean distance from its centre to the nearest
//! occupied cell centre in 1/16 cell units, truncated at `radius` cells. Occupied means
//! log-odds > 0. Invariant (checked by the tests against a brute-force recomputation):
//! after every [`TileMap::integrate`], `dist` equals that truncated distance exactly.

use slam_models::{GridMap, LaserScan, Point2, Pose2};
use std::sync::Arc;

/// log2 of the tile edge in cells.
const TILE_BITS: i32 = 5;
/// Tile edge in cells.
const TILE: i32 = 1 << TILE_BITS;
const TILE_MASK: i32 = TILE - 1;
const TILE_CELLS: usize = (TILE * TILE) as usize;
/// Distance field units per cell.
pub(crate) const DIST_SCALE: f64 = 16.0;

/// One 32 × 32 tile: log-odds and truncated distances, row-major (index = y·32 + x).
#[derive(Clone)]
struct Tile {
    log_odds: [f32; TILE_CELLS],
    dist: [u8; TILE_CELLS],
}

impl Tile {
    fn new(max_dist: u8) -> Self {
        Self {
            log_odds: [0.0; TILE_CELLS],
            dist: [max_dist; TILE_CELLS],
        }
    }
}

/// Parameters shared by every map of a filter (one `Arc` for all particles).
#[derive(Debug, Clone)]
pub(crate) struct MapParams {
    /// Cell edge, metres.
    pub resolution: f64,
    /// Log-odds increments for a hit and a pass-through, and the clamp bounds.
    pub l_hit: f32,
    pub l_miss: f32,
    pub l_min: f32,
    pub l_max: f32,
    /// Field truncation radius in cells (1..=15); 0 disables the field (rendering).
    pub radius: i32,
    /// Beams at or beyond this range are skipped, metres.
    pub max_range: f64,
    /// Precomputed kernel: min(16·√(dx²+dy²), 16·radius) for |dx|, |dy| ≤ radius.
    kernel: Vec<u8>,
    /// 16·radius: the truncated distance, field units.
    max_dist: u8,
}

impl MapParams {
    /// Parameters with the distance kernel precomputed.
    pub fn new(
        resolution: f64,
        l_hit: f32,
        l_miss: f32,
        clamp: [f32; 2],
        radius: i32,
        max_range: f64,
    ) -> Self {
        let w = 2 * radius + 1;
        let mut kernel = Vec::with_capacity((w * w) as usize);
        for dy in -radius..=radius {
            for dx in -radius..=radius {
                let d = ((dx * dx + dy * dy) as f64).sqrt().min(radius as f64);
                kernel.push((d * DIST_SCALE).round() as u8);
            }
        }
        Self {
            resolution,
            l_hit,
            l_miss,
            l_min: clamp[0],
            l_max: clamp[1],
            radius,
            max_range,
            kernel,
            max_dist: (radius as f64 * DIST_SCALE).round() as u8,
        }
    }

    /// The truncated distance value, in field units.
    #[inline]
    pub fn max_dist(&self) -> u8 {
        self.max_dist
    }
}

/// A copy-on-write tiled occupancy grid with an incremental distance field.
/// `Clone` copies the tile table (one pointer per tile), never the cells.
#[derive(Clone)]
pub(crate) struct TileMap {
    params: Arc<MapParams>,
    /// Tile coordinates of the table's lower-left tile.
    tx0: i32,
    ty0: i32,
    /// Table size in tiles.
    ntx: i32,
    nty: i32,
    tiles: Vec<Option<Arc<Tile>>>,
}

/// Scratch buffers reused across integrations (one per worker).
#[derive(Default)]
pub(crate) struct Scratch {
    flips: Vec<(i32, i32)>,
    hits: Vec<(i32, i32)>,
    hit_set: CellSet,
}

/// A small open-addressing set of cells (the end cells of one scan), so that beams do not
/// clear the cells other beams of the same scan end in.
#[derive(Default)]
struct CellSet {
    slots: Vec<(i32, i32)>,
    used: Vec<bool>,
    mask: usize,
}

impl CellSet {
    fn reset(&mut self, n: usize) {
        let cap = (2 * n + 2).next_power_of_two();
        if self.slots.len() != cap {
            self.slots = vec![(0, 0); cap];
            self.used = vec![false; cap];
        } else {
            self.used.iter_mut().for_each(|u| *u = false);
        }
        self.mask = cap - 1;
    }

    #[inline]
    fn hash(c: (i32, i32)) -> usize {
        ((c.0 as u32 as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (c.1 as u32 as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F))
        .rotate_right(29) as usize
    }

    fn insert(&mut self, c: (i32, i32)) {
        let mut i = Self::hash(c) & self.mask;
        while self.used[i] {
            if self.slots[i] == c {
                return;
            }
            i = (i + 1) & self.mask;
        }
        self.used[i] = true;
        self.slots[i] = c;
    }

    #[inline]
    fn contains(&self, c: (i32, i32)) -> bool {
        let mut i = Self::hash(c) & self.mask;
        while self.used[i] {
            if self.slots[i] == c {
                return true;
            }
            i = (i + 1) & self.mask;
        }
        false
    }
}

impl TileMap {
    /// An empty (all unknown) map.
    pub fn new(params: Arc<MapParams>) -> Self {
        Self {
            params,
            tx0: 0,
            ty0: 0,
            ntx: 0,
            nty: 0,
            tiles: Vec::new(),
        }
    }

    /// The shared parameters.
    #[inline]
    pub fn params(&self) -> &MapParams {
        &self.params
    }

    /// The cell containing world point (x, y).
    #[cfg(test)]
    pub fn cell_of(&self, x: f64, y: f64) -> (i32, i32) {
        let r = self.params.resolution;
        ((x / r).floor() as i32, (y / r).floor() as i32)
    }

    #[inline]
    fn slot(&self, cx: i32, cy: i32) -> Option<usize> {
        let tx = (cx >> TILE_BITS) - self.tx0;
        let ty = (cy >> TILE_BITS) - self.ty0;
        if tx < 0 || ty < 0 || tx >= self.ntx || ty >= self.nty {
            None
        } else {
            Some((ty * self.ntx + tx) as usize)
        }
    }

    #[inline]
    fn cell_index(cx: i32, cy: i32) -> usize {
        (((cy & TILE_MASK) << TILE_BITS) | (cx & TILE_MASK)) as usize
    }

    /// Log-odds of a cell (0 = unknown).
    #[inline]
    pub fn log_odds(&self, cx: i32, cy: i32) -> f32 {
        match self.slot(cx, cy).and_then(|s| self.tiles[s].as_deref()) {
            Some(t) => t.log_odds[Self::cell_index(cx, cy)],
            None => 0.0,
        }
    }

    /// Truncated distance of a cell to the nearest occupied cell, field units.
    #[inline]
    pub fn dist(&self, cx: i32, cy: i32) -> u8 {
        match self.slot(cx, cy).and_then(|s| self.tiles[s].as_deref()) {
            Some(t) => t.dist[Self::cell_index(cx, cy)],
            None => self.params.max_dist(),
        }
    }

    /// The four distances around a continuous cell position: cells (cx, cy), (cx+1, cy),
    /// (cx, cy+1), (cx+1, cy+1), with a single tile lookup when all four share a tile.
    #[inline]
    pub fn dist4(&self, cx: i32, cy: i32) -> [u8; 4] {
        if (cx & TILE_MASK) != TILE_MASK && (cy & TILE_MASK) != TILE_MASK {
            match self.slot(cx, cy).and_then(|s| self.tiles[s].as_deref()) {
                Some(t) => {
                    let i = Self::cell_index(cx, cy);
                    let w = TILE as usize;
                    [t.dist[i], t.dist[i + 1], t.dist[i + w], t.dist[i + w + 1]]
                }
                None => [self.params.max_dist(); 4],
            }
        } else {
            [
                self.dist(cx, cy),
                self.dist(cx + 1, cy),
                self.dist(cx, cy + 1),
                self.dist(cx + 1, cy + 1),
            ]
        }
    }

    /// Grows the tile table to cover cells [x0, x1] × [y0, y1].
    fn ensure(&mut self, x0: i32, y0: i32, x1: i32, y1: i32) {
        let (a, b) = (x0 >> TILE_BITS, y0 >> TILE_BITS);
        let (c, d) = (x1 >> TILE_BITS, y1 >> TILE_BITS);
        if self.ntx > 0
            && a >= self.tx0
            && b >= self.ty0
            && c < self.tx0 + self.ntx
            && d < self.ty0 + self.nty
        {
            return;
        }
        // Grow with a margin so that exploration does not reallocate every scan.
        const MARGIN: i32 = 4;
        let (nx0, ny0, nx1, ny1) = if self.ntx == 0 {
            (a - MARGIN, b - MARGIN, c + MARGIN, d + MARGIN)
        } else {
            (
                if a < self.tx0 { a - MARGIN } else { self.tx0 },
                if b < self.ty0 { b - MARGIN } else { self.ty0 },
                if c >= self.tx0 + self.ntx {
                    c + MARGIN
                } else {
                    self.tx0 + self.ntx - 1
                },
                if d >= self.ty0 + self.nty {
                    d + MARGIN
                } else {
                    self.ty0 + self.nty - 1
                },
            )
        };
        let (nw, nh) = (nx1 - nx0 + 1, ny1 - ny0 + 1);
        let mut tiles = vec![None; (nw * nh) as usize];
        for ty in 0..self.nty {
            for tx in 0..self.ntx {
                let old = &mut self.tiles[(ty * self.ntx + tx) as usize];
                let (gx, gy) = (tx + self.tx0 - nx0, ty + self.ty0 - ny0);
                tiles[(gy * nw + gx) as usize] = old.take();
            }
        }
        self.tx0 = nx0;
        self.ty0 = ny0;
        self.ntx = nw;
        self.nty = nh;
        self.tiles = tiles;
    }

    /// The tile holding (cx, cy), created or un-shared as needed. The cell must be
    /// inside the table (see [`TileMap::ensure`]).
    #[inline]
    fn tile_mut(&mut self, slot: usize) -> &mut Tile {
        let max = self.params.max_dist();
        let t = self.tiles[slot].get_or_insert_with(|| Arc::new(Tile::new(max)));
        Arc::make_mut(t)
    }

    /// Adds `delta` to a cell's log-odds (clamped); records a flip of its occupancy.
    #[inline]
    fn update_cell(&mut self, cx: i32, cy: i32, delta: f32, flips: &mut Vec<(i32, i32)>) {
        let Some(slot) = self.slot(cx, cy) else {
            return;
        };
        let (lo, hi) = (self.params.l_min, self.params.l_max);
        let t = self.tile_mut(slot);
        let c = &mut t.log_odds[Self::cell_index(cx, cy)];
        let old = *c;
        let new = (old + delta).clamp(lo, hi);
        *c = new;
        if (old > 0.0) != (new > 0.0) {
            flips.push((cx, cy));
        }
    }

    /// Integrates one scan taken at robot pose `pose` (the scan's `sensor_pose` is applied):
    /// every used beam lowers the log-odds of the cells it traverses (exact grid traversal,
    /// Amanatides & Woo 1987) and raises the log-odds of the cell it ends in (PR table 9.1
    /// with the inverse sensor model of PR §9.2). Each cell is updated at most once per scan
    /// as a hit, and a cell some beam ends in is never cleared by the other beams of the
    /// same scan, so a wall seen at a grazing angle is not erased. The distance field is then repaired around every cell whose
    /// occupancy flipped.
    pub fn integrate(&mut self, pose: &Pose2, scan: &LaserScan, scratch: &mut Scratch) {
        let r = self.params.resolution;
        let sensor = pose.compose(&scan.sensor_pose);
        let (sx, sy) = (sensor.x / r, sensor.y / r);
        let max_range = self.params.max_range.min(scan.max_range);
        // Bounding box of everything this scan may touch (end points and field stamps).
        let rad = self.params.radius.max(0) * 2 + 2;
        let (mut x0, mut y0) = (sx.floor() as i32, sy.floor() as i32);
        let (mut x1, mut y1) = (x0, y0);
        let (s0, c0) = sensor.theta.sin_cos();
        let (ds, dc) = scan.angle_increment.sin_cos();
        let (mut sa, mut ca) = scan.angle_min.sin_cos();
        let ends: Vec<Option<(f64, f64)>> = scan
            .ranges
            .iter()
            .map(|&range| {
                // Beam direction in the world: θ_sensor + angle_min + k·increment, by
                // rotating the unit vector incrementally.
                let (bs, bc) = (s0 * ca + c0 * sa, c0 * ca - s0 * sa);
                let (nsa, nca) = (sa * dc + ca * ds, ca * dc - sa * ds);
                sa = nsa;
                ca = nca;
                if !(range > 0.0 && range < max_range) {
                    return None;
                }
                let (ex, ey) = (sx + range * bc / r, sy + range * bs / r);
                x0 = x0.min(ex.floor() as i32);
                y0 = y0.min(ey.floor() as i32);
                x1 = x1.max(ex.floor() as i32);
                y1 = y1.max(ey.floor() as i32);
                Some((ex, ey))
            })
            .collect();
        self.ensure(x0 - rad, y0 - rad, x1 + rad, y1 + rad);
        scratch.flips.clear();
        scratch.hits.clear();
        let miss = self.params.l_miss;
        let hit = self.params.l_hit;
        let mut flips = std::mem::take(&mut scratch.flips);
        for &(ex, ey) in ends.iter().flatten() {
            scratch.hits.push((ex.floor() as i32, ey.floor() as i32));
        }
        scratch.hit_set.reset(scratch.hits.len());
        for &c in &scratch.hits {
            scratch.hit_set.insert(c);
        }
        let set = &scratch.hit_set;
        for &(ex, ey) in ends.iter().flatten() {
            traverse(sx, sy, ex, ey, |cx, cy| {
                if !set.contains((cx, cy)) {
                    self.update_cell(cx, cy, miss, &mut flips)
                }
            });
        }
        scratch.hits.sort_unstable();
        scratch.hits.dedup();
        for k in 0..scratch.hits.len() {
            let (cx, cy) = scratch.hits[k];
            self.update_cell(cx, cy, hit, &mut flips);
        }
        if self.params.radius > 0 && !flips.is_empty() {
            flips.sort_unstable();
            flips.dedup();
            // Cells that became free: recompute the field in their neighbourhood.
            for &(cx, cy) in &flips {
                if self.log_odds(cx, cy) <= 0.0 {
                    self.recompute_window(cx, cy);
                }
            }
            // Cells that became occupied: stamp the distance kernel (min).
            for &(cx, cy) in &flips {
                if self.log_odds(cx, cy) > 0.0 {
                    self.stamp(cx, cy, None);
                }
            }
        }
        scratch.flips = flips;
    }

    /// dist ← min(dist, kernel) around occupied cell (cx, cy), optionally clipped to a
    /// window [wx0, wx1] × [wy0, wy1].
    fn stamp(&mut self, cx: i32, cy: i32, clip: Option<(i32, i32, i32, i32)>) {
        let rad = self.params.radius;
        let w = 2 * rad + 1;
        let params = Arc::clone(&self.params);
        let max = params.max_dist();
        for dy in -rad..=rad {
            let y = cy + dy;
            if let Some((_, wy0, _, wy1)) = clip {
                if y < wy0 || y > wy1 {
                    continue;
                }
            }
            for dx in -rad..=rad {
                let x = cx + dx;
                if let Some((wx0, _, wx1, _)) = clip {
                    if x < wx0 || x > wx1 {
                        continue;
                    }
                }
                let k = params.kernel[((dy + rad) * w + dx + rad) as usize];
                if k >= max {
                    continue;
                }
                let Some(slot) = self.slot(x, y) else {
                    continue;
                };
                // Avoid un-sharing a tile when nothing changes.
                let cur = match self.tiles[slot].as_deref() {
                    Some(t) => t.dist[Self::cell_index(x, y)],
                    None => max,
                };
                if k < cur {
                    self.tile_mut(slot).dist[Self::cell_index(x, y)] = k;
                }
            }
        }
    }

    /// Recomputes the field exactly in the window of `radius` around (cx, cy) from the
    /// occupied cells within 2·radius.
    fn recompute_window(&mut self, cx: i32, cy: i32) {
        let rad = self.params.radius;
        let max = self.params.max_dist();
        for y in cy - rad..=cy + rad {
            for x in cx - rad..=cx + rad {
                if let Some(slot) = self.slot(x, y) {
                    if self.tiles[slot].is_some() {
                        let i = Self::cell_index(x, y);
                        if self.tiles[slot]
                            .as_deref()
                            .is_some_and(|t| t.dist[i] != max)
                        {
                            self.tile_mut(slot).dist[i] = max;
                        }
                    }
                }
            }
        }
        let clip = (cx - rad, cy - rad, cx + rad, cy + rad);
        for y in cy - 2 * rad..=cy + 2 * rad {
            for x in cx - 2 * rad..=cx + 2 * rad {
                if self.log_odds(x, y) > 0.0 {
                    self.stamp(x, y, Some(clip));
                }
            }
        }
    }

    /// The ROS-convention raster of the allocated tiles (−1 unknown, 0…100 occupancy
    /// probability in percent, p = 1 − 1/(1 + e^l)).
    pub fn to_grid_map(&self) -> GridMap {
        let r = self.params.resolution;
        let used: Vec<(i32, i32)> = (0..self.nty)
            .flat_map(|ty| (0..self.ntx).map(move |tx| (tx, ty)))
            .filter(|&(tx, ty)| self.tiles[(ty * self.ntx + tx) as usize].is_some())
            .collect();
        if used.is_empty() {
            return GridMap::unknown(r, Point2::origin(), 0, 0);
        }
        let (ax, ay) = used
            .iter()
            .fold((i32::MAX, i32::MAX), |a, t| (a.0.min(t.0), a.1.min(t.1)));
        let (bx, by) = used
            .iter()
            .fold((i32::MIN, i32::MIN), |a, t| (a.0.max(t.0), a.1.max(t.1)));
        let (cx0, cy0) = ((ax + self.tx0) * TILE, (ay + self.ty0) * TILE);
        let width = ((bx - ax + 1) * TILE) as usize;
        let height = ((by - ay + 1) * TILE) as usize;
        let mut map = GridMap::unknown(
            r,
            Point2::new(cx0 as f64 * r, cy0 as f64 * r),
            width,
            height,
        );
        for iy in 0..height {
            for ix in 0..width {
                let l = self.log_odds(cx0 + ix as i32, cy0 + iy as i32);
                if l != 0.0 {
                    let p = 1.0 - 1.0 / (1.0 + (l as f64).exp());
                    map.cells[iy * width + ix] = (p * 100.0).round() as i8;
                }
            }
        }
        map
    }

    /// Number of allocated tiles and the number of those this map does not share.
    #[cfg(test)]
    pub fn tile_counts(&self) -> (usize, usize) {
        let all = self.tiles.iter().flatten().count();
        let own = self
            .tiles
            .iter()
            .flatten()
            .filter(|t| Arc::strong_count(t) == 1)
            .count();
        (all, own)
    }
}

/// Visits the cells from the one containing (x0, y0) up to, not including, the one
/// containing (x1, y1), in cell units (Amanatides & Woo 1987).
#[inline]
fn traverse(x0: f64, y0: f64, x1: f64, y1: f64, mut visit: impl FnMut(i32, i32)) {
    let (mut cx, mut cy) = (x0.floor() as i32, y0.floor() as i32);
    let (ex, ey) = (x1.floor() as i32, y1.floor() as i32);
    let (dx, dy) = (x1 - x0, y1 - y0);
    let step_x = if dx > 0.0 { 1 } else { -1 };
    let step_y = if dy > 0.0 { 1 } else { -1 };
    let t_dx = if dx != 0.0 {
        (1.0 / dx).abs()
    } else {
        f64::INFINITY
    };
    let t_dy = if dy != 0.0 {
        (1.0 / dy).abs()
    } else {
        f64::INFINITY
    };
    let mut t_max_x = if dx > 0.0 {
        (cx as f64 + 1.0 - x0) * t_dx
    } else if dx < 0.0 {
        (x0 - cx as f64) * t_dx
    } else {
        f64::INFINITY
    };
    let mut t_max_y = if dy > 0.0 {
        (cy as f64 + 1.0 - y0) * t_dy
    } else if dy < 0.0 {
        (y0 - cy as f64) * t_dy
    } else {
        f64::INFINITY
    };
    let n = (ex - cx).abs() + (ey - cy).abs();
    for _ in 0..n {
        visit(cx, cy);
        if t_max_x < t_max_y {
            cx += step_x;
            t_max_x += t_dx;
        } else {
            cy += step_y;
            t_max_y += t_dy;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64Mcg;

    fn params(radius: i32) -> Arc<MapParams> {
        Arc::new(MapParams::new(0.05, 0.85, -0.4, [-2.0, 3.5], radius, 50.0))
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

    /// Brute force: truncated distance from every cell to the nearest occupied cell.
    fn check_field(m: &TileMap, x0: i32, y0: i32, x1: i32, y1: i32) {
        let rad = m.params.radius;
        let max = m.params.max_dist();
        for y in y0..=y1 {
            for x in x0..=x1 {
                let mut best = max;
                for dy in -rad..=rad {
                    for dx in -rad..=rad {
                        if m.log_odds(x + dx, y + dy) > 0.0 {
                            let d = ((dx * dx + dy * dy) as f64).sqrt().min(rad as f64);
                            best = best.min((d * DIST_SCALE).round() as u8);
                        }
                    }
                }
                assert_eq!(m.dist(x, y), best, "cell ({x}, {y})");
            }
        }
    }

    #[test]
    fn traversal_visits_a_connected_path_excluding_the_end() {
        let mut cells = Vec::new();
        traverse(0.5, 0.5, 5.2, 3.7, |x, y| cells.push((x, y)));
        assert_eq!(cells.first(), Some(&(0, 0)));
        assert_eq!(cells.len(), 5 + 3);
        for w in cells.windows(2) {
            assert_eq!((w[1].0 - w[0].0).abs() + (w[1].1 - w[0].1).abs(), 1);
        }
        assert!(!cells.contains(&(5, 3)));
        let mut back = Vec::new();
        traverse(-0.5, 2.5, -3.5, 2.5, |x, y| back.push((x, y)));
        assert_eq!(back, vec![(-1, 2), (-2, 2), (-3, 2)]);
    }

    #[test]
    fn incremental_field_equals_brute_force_after_random_scans() {
        let mut m = TileMap::new(params(4));
        let mut rng = Pcg64Mcg::seed_from_u64(5);
        let mut scratch = Scratch::default();
        for i in 0..40 {
            let pose = Pose2::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-3.0..3.0),
            );
            // A room-ish scan with random ranges so that cells flip both ways.
            let ranges = (0..90).map(|_| rng.random_range(0.3..2.5)).collect();
            m.integrate(&pose, &scan(ranges), &mut scratch);
            if i % 10 == 9 {
                check_field(&m, -70, -70, 70, 70);
            }
        }
    }

    #[test]
    fn clones_share_untouched_tiles() {
        let mut a = TileMap::new(params(4));
        let mut s = Scratch::default();
        a.integrate(
            &Pose2::new(0.012, 0.013, 0.0),
            &scan(vec![3.02; 181]),
            &mut s,
        );
        let (all, own) = a.tile_counts();
        assert_eq!(all, own);
        let mut b = a.clone();
        assert_eq!(b.tile_counts().1, 0);
        // A short scan far away touches few tiles; b un-shares only those.
        b.integrate(&Pose2::new(2.5, 0.0, 0.0), &scan(vec![0.2; 181]), &mut s);
        let (ball, bown) = b.tile_counts();
        assert!((1..=4).contains(&bown), "{bown} of {ball}");
        // a is unchanged by b's writes: its wall straight ahead is still there.
        let (wx, wy) = a.cell_of(3.032, 0.013);
        assert!(a.log_odds(wx, wy) > 0.0);
    }

    #[test]
    fn walls_become_occupied_and_free_space_free() {
        let mut m = TileMap::new(params(4));
        let mut s = Scratch::default();
        for _ in 0..3 {
            m.integrate(&Pose2::new(0.0, 0.0, 0.0), &scan(vec![2.02; 181]), &mut s);
        }
        // Straight ahead: wall at 2 m, free at 1 m.
        let (wx, wy) = m.cell_of(2.02, 0.0);
        assert!(m.log_odds(wx, wy) > 0.0);
        let (fx, fy) = m.cell_of(1.0, 0.0);
        assert!(m.log_odds(fx, fy) < 0.0);
        assert_eq!(m.dist(wx, wy), 0);
        let g = m.to_grid_map();
        let c = g.cell_of(&Point2::new(2.02, 0.0)).unwrap();
        assert!(g.get(c.0, c.1).unwrap() > 50);
        let f = g.cell_of(&Point2::new(1.0, 0.0)).unwrap();
        assert!(g.get(f.0, f.1).unwrap() < 50 && g.get(f.0, f.1).unwrap() >= 0);
    }
}
