//! The pyramids of a grid: [`MaxPyramid`], the likelihood field's max-pooled levels that
//! [`super::BranchBoundMatcher`] searches (kept for many searches, in `f32` or compact), and
//! [`MinPyramid`], the distance field's min-pooled levels that the endpoint matcher's
//! coarse search prunes with.

use super::branch_bound::MAX_PYRAMID_DEPTH;
use super::levels::{Levels, Storage};
use crate::cell::{CellIndex, GridFrame};
use crate::error::{ensure_config, GridError};
use crate::grid::OccupancyGrid;
use crate::likelihood::LikelihoodParams;

/// The likelihood field of a rectangle of cells and its max-pooled coarser copies
/// (Hess et al. 2016, §V-B, "precomputed grids"):
///
/// P₀(c) = s(c), the likelihood-field value of cell c, and
/// P_k(x, y) = max of P₀ over the 2^k × 2^k block [x, x + 2^k) × [y, y + 2^k),
///
/// computed level by level as P_k(x, y) = max(P_{k−1}(x, y), P_{k−1}(x + h, y),
/// P_{k−1}(x, y + h), P_{k−1}(x + h, y + h)) with h = 2^(k−1). Every level keeps the full
/// resolution, so Σᵢ P_k(cᵢ + o) bounds from above the score Σᵢ P₀(cᵢ + o') of every
/// translation o' in the block o … o + (2^k − 1, 2^k − 1).
///
/// Cells outside the rectangle read the field's far value (its minimum, PR §6.4: the value
/// at `max_distance`), as the grid does outside its tiles; the levels are stored from
/// 2^(depth−1) − 1 cells below the rectangle so that blocks overlapping it from below are
/// bounded correctly.
#[derive(Debug, Clone)]
pub struct MaxPyramid {
    pub(super) frame: GridFrame,
    pub(super) params: LikelihoodParams,
    pub(super) levels: Levels,
}

impl MaxPyramid {
    /// The pyramid of `depth` levels over the inclusive cell rectangle `min … max` of
    /// `grid`'s likelihood field.
    ///
    /// Errors for a depth outside 1..=[`MAX_PYRAMID_DEPTH`], an empty rectangle, or one
    /// whose padded levels exceed [`MAX_PYRAMID_CELLS`](super::MAX_PYRAMID_CELLS) cells.
    pub fn new(
        grid: &OccupancyGrid,
        min: CellIndex,
        max: CellIndex,
        depth: u32,
    ) -> Result<Self, GridError> {
        Self::build(grid, min, max, depth, Storage::Full)
    }

    /// [`MaxPyramid::new`], its levels stored as `storage` says ([`Storage`]).
    pub(super) fn build(
        grid: &OccupancyGrid,
        min: CellIndex,
        max: CellIndex,
        depth: u32,
        storage: Storage,
    ) -> Result<Self, GridError> {
        let params = grid.likelihood_params();
        // The padding reads the far value too: the grid returns it outside its tiles, and
        // inside them the rectangle is what the caller asked for.
        let far = params.far_value();
        let window = |origin, w, _h, out: &mut [f32]| grid.field_window_into(origin, w, out);
        let levels = Levels::build(min, max, depth, 1, far, window, storage)?;
        Ok(Self {
            frame: grid.frame(),
            params,
            levels,
        })
    }

    /// The pyramid over every cell `grid` covers (its allocated tiles), e.g. a finished
    /// submap; `None` for an empty grid.
    pub fn covering(grid: &OccupancyGrid, depth: u32) -> Result<Option<Self>, GridError> {
        match grid.covered_cells() {
            Some((min, max)) => Self::new(grid, min, max, depth).map(Some),
            None => Ok(None),
        }
    }

    /// Number of levels.
    pub fn depth(&self) -> u32 {
        self.levels.depth()
    }

    /// The grid geometry the pyramid was built on.
    pub fn frame(&self) -> GridFrame {
        self.frame
    }

    /// Bytes held by the levels.
    pub fn memory_bytes(&self) -> usize {
        self.levels.memory_bytes()
    }

    /// [`MaxPyramid::new`] with the levels above 0 in 8-bit codes, rounded up: a quarter
    /// of their memory (and of the transient while building), and
    /// [`value`](Self::value) above level 0 reads at most 1/255 of the field's range more
    /// (the maximum over the block, or above it: still a bound). A
    /// [`super::BranchBoundMatcher`] search scores its poses on level 0, which is kept exact, so
    /// it finds a pose of the same best score (of equally scoring poses, possibly
    /// another).
    pub fn new_compact(
        grid: &OccupancyGrid,
        min: CellIndex,
        max: CellIndex,
        depth: u32,
    ) -> Result<Self, GridError> {
        Self::build(grid, min, max, depth, Storage::Compact)
    }

    /// P_level(c): the maximum field value over the 2^level-cell block whose lowest corner
    /// is `c` (level 0: the field value of `c`); the far value outside the stored cells.
    #[inline]
    pub fn value(&self, level: u32, c: CellIndex) -> f32 {
        self.levels.value(level, c)
    }
}

/// Most cells of a [`MinPyramid`] level: beyond this the coarse search falls back to brute
/// force (4 MB per level; an indoor scan's window needs about 10⁵ cells).
pub(crate) const MAX_MIN_PYRAMID_CELLS: usize = 4_000_000;

/// Min-pooled truncated distances of a rectangle of cells, a two-dimensional sparse table of
/// square blocks (the distance analogue of [`MaxPyramid`]):
///
/// Q₀(c) = d(c), and Q_L(x, y) = min of d over [x, x + 2^L) × [y, y + 2^L),
///
/// computed level by level as Q_L(x, y) = min(Q_{L−1}(x, y), Q_{L−1}(x + h, y),
/// Q_{L−1}(x, y + h), Q_{L−1}(x + h, y + h)) with h = 2^(L−1), separably (rows, then
/// columns), on `u8` distances so the passes vectorise. Any box of cells is the union of
/// squares of the side 2^L ≤ its shorter side, so [`MinPyramid::min_over`] is the exact
/// minimum of d over the box in a few look-ups. Since the endpoint model's cost min(d, r)²
/// grows with d, that minimum bounds from above every beam whose bilinear read (a blend of
/// four cells, never below the smallest) lies in the box: the bound the coarse search
/// ([`super::endpoint::grid_search`]) prunes with.
#[derive(Debug, Clone)]
pub(crate) struct MinPyramid {
    origin: CellIndex,
    width: usize,
    height: usize,
    /// Level L holds Q_L at row-major index (y − origin.y)·width + (x − origin.x) for the
    /// squares inside the rectangle; entries whose square leaves it are 0 (never read).
    /// Levels below the bottom one are empty.
    levels: Vec<Vec<u8>>,
}

impl MinPyramid {
    /// Levels `bottom` ..= `top` of the inclusive rectangle `min … max` (the lower ones
    /// are dropped once built: boxes whose shorter side is below 2^`bottom` read 0), the
    /// distances read a row at a time: `row(start, out)` fills `out` with d(start),
    /// d(start + (1, 0)), ….
    ///
    /// Errors for an empty rectangle, `bottom` above `top`, a `top` above
    /// [`MAX_PYRAMID_DEPTH`] − 1, or more than [`MAX_MIN_PYRAMID_CELLS`] cells.
    pub(crate) fn build(
        min: CellIndex,
        max: CellIndex,
        bottom: u32,
        top: u32,
        mut row: impl FnMut(CellIndex, &mut [u8]),
    ) -> Result<Self, GridError> {
        ensure_config(
            bottom <= top,
            "min-pyramid bottom level",
            bottom as f64,
            "at most the top level",
        )?;
        ensure_config(
            top < MAX_PYRAMID_DEPTH,
            "min-pyramid top level",
            top as f64,
            "below 12",
        )?;
        let w = max.x as i64 - min.x as i64 + 1;
        let h = max.y as i64 - min.y as i64 + 1;
        ensure_config(
            w > 0 && h > 0,
            "min-pyramid rectangle (cells)",
            w.min(h) as f64,
            "max ≥ min in x and y",
        )?;
        ensure_config(
            w.saturating_mul(h) <= MAX_MIN_PYRAMID_CELLS as i64,
            "min-pyramid level (cells)",
            w as f64 * h as f64,
            "at most 4e6 cells",
        )?;
        let (w, h) = (w as usize, h as usize);
        let mut base = vec![0u8; w * h];
        for (y, out) in base.chunks_exact_mut(w).enumerate() {
            row(CellIndex::new(min.x, min.y + y as i32), out);
        }
        let mut levels = Vec::with_capacity(top as usize + 1);
        levels.push(base);
        for level in 1..=top as usize {
            let half = 1usize << (level - 1);
            let prev = &levels[level - 1];
            // Rows: min of the cell and the one `half` to its right.
            let mut next = vec![0u8; w * h];
            if half < w {
                for (out, src) in next.chunks_exact_mut(w).zip(prev.chunks_exact(w)) {
                    for ((o, a), b) in out.iter_mut().zip(src).zip(&src[half..]) {
                        *o = (*a).min(*b);
                    }
                }
            }
            // Columns, in place: the same between a row and the one `half` above it (read
            // before it is overwritten, the rows going up).
            for y in 0..h {
                let (low, high) = next.split_at_mut((y + 1) * w);
                let row = &mut low[y * w..];
                // Row y + half starts (half − 1) rows into `high`.
                match high.get((half - 1) * w..half * w) {
                    Some(above) if y + half < h => {
                        for (o, b) in row.iter_mut().zip(above) {
                            *o = (*o).min(*b);
                        }
                    }
                    _ => row.fill(0),
                }
            }
            levels.push(next);
            // Below `bottom` a level only feeds the next one.
            if level - 1 < bottom as usize {
                levels[level - 1] = Vec::new();
            }
        }
        Ok(Self {
            origin: min,
            width: w,
            height: h,
            levels,
        })
    }

    /// The highest level built.
    #[inline]
    pub(crate) fn top(&self) -> u32 {
        self.levels.len() as u32 - 1
    }

    /// min d over the inclusive box `lo … hi` (lo ≤ hi), or 0 (the least distance, so
    /// still a valid lower bound) when the box leaves the rectangle.
    #[inline]
    pub(crate) fn min_over(&self, lo: CellIndex, hi: CellIndex) -> u8 {
        let x0 = lo.x as i64 - self.origin.x as i64;
        let y0 = lo.y as i64 - self.origin.y as i64;
        let x1 = hi.x as i64 - self.origin.x as i64;
        let y1 = hi.y as i64 - self.origin.y as i64;
        if x0 < 0 || y0 < 0 || x1 >= self.width as i64 || y1 >= self.height as i64 {
            return 0;
        }
        let side = (x1 - x0).min(y1 - y0) + 1;
        if side <= 0 {
            return 0;
        }
        // The largest square that fits: 2^level ≤ the shorter side.
        let level = (63 - side.leading_zeros()).min(self.top());
        let size = 1i64 << level;
        let q = &self.levels[level as usize];
        if q.is_empty() {
            return 0;
        }
        let mut m = u8::MAX;
        let mut y = y0;
        loop {
            let row = &q[(y as usize) * self.width..];
            let mut x = x0;
            loop {
                m = m.min(row[x as usize]);
                if x + size > x1 {
                    break;
                }
                x = (x + size).min(x1 + 1 - size);
            }
            if y + size > y1 {
                break;
            }
            y = (y + size).min(y1 + 1 - size);
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::office_map;

    /// The pyramid's level k is the block maximum of level 0, checked cell by cell by
    /// brute force (cells outside the stored area read the far value).
    #[test]
    fn pyramid_levels_are_block_maxima() {
        let g = office_map(0.1);
        let p = MaxPyramid::new(&g, CellIndex::new(10, 5), CellIndex::new(60, 40), 4).unwrap();
        for k in 0..4u32 {
            for y in -2..45 {
                for x in 0..66 {
                    let mut m = f32::NEG_INFINITY;
                    for yy in y..y + (1 << k) {
                        for xx in x..x + (1 << k) {
                            let c = CellIndex::new(xx, yy);
                            let inside = (10..=60).contains(&xx) && (5..=40).contains(&yy);
                            let v = if inside {
                                g.likelihood(c)
                            } else {
                                p.levels.far()
                            };
                            m = m.max(v);
                        }
                    }
                    assert_eq!(
                        p.value(k, CellIndex::new(x, y)),
                        m,
                        "level {k} at ({x}, {y})"
                    );
                }
            }
        }
    }

    /// The compact pyramid: level 0 as the exact one, every coarser level at or above the
    /// exact block maximum by less than 1/255 of the value range (searches on it:
    /// `recovers_a_known_offset`).
    #[test]
    fn compact_pyramid_levels_bound_the_block_maxima() {
        let res = 0.05;
        let g = office_map(res);
        let (min, max) = g.covered_cells().unwrap();
        let exact = MaxPyramid::new(&g, min, max, 6).unwrap();
        let compact = MaxPyramid::new_compact(&g, min, max, 6).unwrap();
        assert!(4 * compact.memory_bytes() < 2 * exact.memory_bytes());
        let step = (1.0 - exact.levels.far()) / 255.0;
        for k in 0..6u32 {
            for y in (min.y - 40..=max.y + 5).step_by(3) {
                for x in (min.x - 40..=max.x + 5).step_by(3) {
                    let c = CellIndex::new(x, y);
                    let (e, q) = (exact.value(k, c), compact.value(k, c));
                    if k == 0 {
                        assert_eq!(q, e, "level 0 at ({x}, {y})");
                    } else {
                        assert!(q >= e && q - e <= step * 1.001, "level {k}: {q} vs {e}");
                    }
                }
            }
        }
    }
    /// The min-pyramid's box minimum equals the brute-force minimum over the box, for boxes
    /// of every shape (thin, square, wider than the top level's squares) on random values,
    /// and reads 0 for a box that leaves the rectangle.
    #[test]
    fn min_pyramid_box_minimum_is_exact() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
        let values: Vec<u8> = (0..70 * 50).map(|_| rng.random_range(3..=255)).collect();
        let (lo, hi) = (CellIndex::new(-20, 5), CellIndex::new(49, 54));
        let d = |c: CellIndex| values[((c.y - 5) * 70 + c.x + 20) as usize];
        let rows = |start: CellIndex, out: &mut [u8]| {
            for (x, v) in out.iter_mut().enumerate() {
                *v = d(CellIndex::new(start.x + x as i32, start.y));
            }
        };
        let p = MinPyramid::build(lo, hi, 0, 3, rows).unwrap();
        assert_eq!(p.top(), 3);
        for _ in 0..20_000 {
            let x0 = rng.random_range(-20..=49);
            let y0 = rng.random_range(5..=54);
            let x1 = rng.random_range(x0..=(x0 + 40).min(49));
            let y1 = rng.random_range(y0..=(y0 + 40).min(54));
            let mut m = u8::MAX;
            for y in y0..=y1 {
                for x in x0..=x1 {
                    m = m.min(d(CellIndex::new(x, y)));
                }
            }
            let (a, b) = (CellIndex::new(x0, y0), CellIndex::new(x1, y1));
            assert_eq!(p.min_over(a, b), m, "box {a:?} … {b:?}");
        }
        assert_eq!(p.min_over(CellIndex::new(-21, 5), CellIndex::new(0, 6)), 0);
        assert_eq!(
            p.min_over(CellIndex::new(40, 50), CellIndex::new(45, 55)),
            0
        );
        // Without levels 0 and 1, boxes narrower than 4 cells read 0, the others the same.
        let upper = MinPyramid::build(lo, hi, 2, 3, rows).unwrap();
        let (a, b) = (CellIndex::new(0, 10), CellIndex::new(2, 30));
        assert_eq!(upper.min_over(a, b), 0);
        let b = CellIndex::new(3, 30);
        assert_eq!(upper.min_over(a, b), p.min_over(a, b));
        assert!(MinPyramid::build(hi, lo, 0, 3, rows).is_err());
        assert!(MinPyramid::build(lo, hi, 3, 2, rows).is_err());
        assert!(MinPyramid::build(lo, CellIndex::new(3000, 3000), 0, 3, rows).is_err());
    }
}
