//! Max-pooled levels of a per-cell score (the precomputed grids of a branch-and-bound
//! search: Olson, ICRA 2009, §IV-C; Hess et al., ICRA 2016, §V-B), built row by row: kept
//! in `f32`, in 8-bit codes above level 0 (pyramids cached for many searches), or in a
//! buffer that a thread reuses from one search to the next (pyramids built per search).

use super::branch_bound::{MAX_PYRAMID_CELLS, MAX_PYRAMID_DEPTH};
use crate::cell::CellIndex;
use crate::error::{ensure_config, GridError};

/// How [`Levels::build`] stores the levels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Storage {
    /// Every level in `f32`, in a fresh allocation.
    Full,
    /// Every level in `f32`, in this thread's spare buffer, given back when the levels are
    /// dropped: for pyramids built and dropped per search (the same values, fewer page
    /// faults).
    Pooled,
    /// Level 0 in `f32`, the levels above it in 8-bit codes rounded up (a quarter of their
    /// memory): for pyramids kept for many searches. Code q reads lo + (hi − lo)·q/255 over
    /// the values' range [lo, hi] (level 0's and `far`: max-pooling stays in it), and each
    /// value takes the smallest code that reads at least it, so a coarse level reads its
    /// block maximum or at most (hi − lo)/255 more: still a bound, and a branch and bound
    /// whose exact scores come from level 0 finds a pose of the same best score (of
    /// equally scoring poses possibly another: the visiting order follows the bounds).
    Compact,
}

/// Max-pooled levels of any per-cell score over a rectangle of cells, with a lattice
/// stride m ≥ 1 (translations in steps of m cells): P₀(c) = v(c) and
/// P_k(x, y) = max of P₀ over {x + a·m : 0 ≤ a < 2^k} × {y + b·m : 0 ≤ b < 2^k}, computed as
/// P_k(x, y) = max(P_{k−1}(x, y), P_{k−1}(x + h, y), P_{k−1}(x, y + h), P_{k−1}(x + h, y + h))
/// with h = m·2^(k−1). Cells outside the rectangle read `far`, the score's minimum.
#[derive(Debug)]
pub(crate) struct Levels {
    /// Lowest stored cell (the rectangle's minimum corner less the padding).
    origin: CellIndex,
    width: usize,
    height: usize,
    stride: i32,
    far: f32,
    depth: u32,
    /// Level k at `[k·w·h, (k + 1)·w·h)`, each row-major: every level, or level 0 alone
    /// when the levels above it are in `codes`.
    data: Vec<f32>,
    /// [`Storage::Compact`]: level k ≥ 1 at `[(k − 1)·w·h, k·w·h)`, 8-bit codes read
    /// through `table`; empty otherwise.
    codes: Vec<u8>,
    /// The value of each code.
    table: [f32; 256],
    /// Whether `data` goes back to this thread's spare buffer when dropped ([`SPARE`]).
    pooled: bool,
}

/// Largest buffer kept for reuse by a thread (bytes): the levels of a search pyramid are
/// tens of megabytes for a 30 m scan, and a fresh allocation of that size costs more in
/// page faults than filling it.
const MAX_SPARE_BYTES: usize = 128 << 20;

thread_local! {
    /// One spare buffer per thread, for the levels of [`Storage::Pooled`].
    static SPARE: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
}

impl Clone for Levels {
    fn clone(&self) -> Self {
        Self {
            data: self.data.clone(),
            codes: self.codes.clone(),
            pooled: false,
            ..*self
        }
    }
}

impl Drop for Levels {
    fn drop(&mut self) {
        let bytes = self.data.capacity() * std::mem::size_of::<f32>();
        if self.pooled && bytes <= MAX_SPARE_BYTES {
            let data = std::mem::take(&mut self.data);
            SPARE.with(|s| {
                let mut spare = s.borrow_mut();
                if spare.capacity() < data.capacity() {
                    *spare = data;
                }
            });
        }
    }
}

/// max(a, b) for values that are never NaN (a plain comparison, which vectorises; `f32::max`
/// also handles NaN).
#[inline(always)]
fn larger<T: PartialOrd>(a: T, b: T) -> T {
    if b > a {
        b
    } else {
        a
    }
}

/// Level k of `w`-wide rows from level k − 1 (`prev`) into `next`: the max over the 4 cells
/// (x, y), (x + h, y), (x, y + h), (x + h, y + h), a cell outside the rectangle reading
/// `far`. First along rows, then, in place, between a row and the one h above it (rows
/// going up, so that row is read before it is overwritten).
fn pool<T: PartialOrd + Copy>(prev: &[T], next: &mut [T], w: usize, half: usize, far: T) {
    let h = prev.len() / w;
    for (out, src) in next.chunks_exact_mut(w).zip(prev.chunks_exact(w)) {
        let m = w.saturating_sub(half);
        let (o, a, b) = (&mut out[..m], &src[..m], &src[half.min(w)..]);
        for i in 0..m {
            o[i] = larger(a[i], b[i]);
        }
        for (o, &a) in out[m..].iter_mut().zip(&src[m..]) {
            *o = larger(a, far);
        }
    }
    for y in 0..h {
        if y + half < h {
            let (low, high) = next.split_at_mut((y + half) * w);
            let (row, above) = (&mut low[y * w..(y + 1) * w], &high[..w]);
            for i in 0..w {
                row[i] = larger(row[i], above[i]);
            }
        } else {
            for v in &mut next[y * w..(y + 1) * w] {
                *v = larger(*v, far);
            }
        }
    }
}

/// The 8-bit codes of [`Storage::Compact`] over the values' range [lo, hi].
struct Coder {
    lo: f32,
    hi: f32,
    /// The value code q reads: lo + (hi − lo)·q/255, and hi at 255.
    table: [f32; 256],
}

impl Coder {
    /// The codes over the range of `values` and `far`.
    fn new(values: &[f32], far: f32) -> Self {
        let (lo, hi) = values
            .iter()
            .fold((far, far), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        let mut table = [0.0f32; 256];
        for (q, t) in table.iter_mut().enumerate() {
            *t = lo + (hi - lo) * (q as f32 / 255.0);
        }
        table[255] = hi;
        Self { lo, hi, table }
    }

    /// The smallest code that reads at least `v` (255 above hi), from the estimate
    /// ⌈255·(v − lo)/(hi − lo)⌉ (a nondecreasing function of `v`, as is the result).
    #[inline]
    fn code(&self, v: f32) -> u8 {
        let (lo, hi) = (self.lo, self.hi);
        let mut q = if hi > lo {
            // ⌈x⌉ clamped to 0..=255, without the library call `ceil` is on x86-64 without
            // SSE4.1 (x is finite; NaN would give 0, as `x.ceil() as usize` does).
            let x = ((v - lo) / (hi - lo)) * 255.0;
            let t = x as i32;
            let c = if (t as f32) < x {
                t.saturating_add(1)
            } else {
                t
            };
            c.clamp(0, 255) as usize
        } else {
            0
        };
        while q < 255 && self.table[q] < v {
            q += 1;
        }
        q as u8
    }
}

impl Levels {
    /// The `depth` levels over the inclusive rectangle `min … max` with lattice stride
    /// `stride`, stored as `storage` says; `base(origin, w, h, out)` writes the row-major
    /// values of the `w × h` cells from `origin` into `out` (every element; the rectangle
    /// grown by the padding below it, which reads `far`).
    pub(crate) fn build(
        min: CellIndex,
        max: CellIndex,
        depth: u32,
        stride: i32,
        far: f32,
        base: impl FnOnce(CellIndex, usize, usize, &mut [f32]),
        storage: Storage,
    ) -> Result<Self, GridError> {
        ensure_config(
            (1..=MAX_PYRAMID_DEPTH).contains(&depth),
            "pyramid depth",
            depth as f64,
            "in 1..=12",
        )?;
        let stride = stride.max(1);
        let pad = ((1i64 << (depth - 1)) - 1) * stride as i64;
        let w = max.x as i64 - min.x as i64 + 1 + pad;
        let h = max.y as i64 - min.y as i64 + 1 + pad;
        if w <= pad || h <= pad {
            return Err(GridError::InvalidConfig(slam_models::ConfigError::new(
                "branch-and-bound matcher",
                "pyramid rectangle (cells)",
                0.0,
                "max ≥ min in x and y",
            )));
        }
        if w.saturating_mul(h) > MAX_PYRAMID_CELLS as i64 {
            return Err(GridError::InvalidConfig(slam_models::ConfigError::new(
                "branch-and-bound matcher",
                "pyramid level (cells)",
                w as f64 * h as f64,
                "at most 16e6 cells: a smaller region or a coarser grid",
            )));
        }
        let (w, h, pad) = (w as usize, h as usize, pad as usize);
        let n = w * h;
        let origin = CellIndex::new(min.x - pad as i32, min.y - pad as i32);
        let compact = storage == Storage::Compact;
        let pooled = storage == Storage::Pooled;
        let len = if compact { n } else { depth as usize * n };
        let mut data = if pooled {
            SPARE.with(|s| std::mem::take(&mut *s.borrow_mut()))
        } else {
            Vec::new()
        };
        // Every element is written below: old contents of a reused buffer are never read.
        if data.len() < len {
            data.resize(len, far);
        } else {
            data.truncate(len);
        }
        {
            let first = &mut data[..n];
            base(origin, w, h, first);
            first[..pad * w].fill(far);
            for row in first.chunks_exact_mut(w).skip(pad) {
                row[..pad].fill(far);
            }
        }
        let mut table = [0.0f32; 256];
        let mut codes = Vec::new();
        if compact {
            let coder = Coder::new(&data, far);
            table = coder.table;
            // A code is a nondecreasing function of the value, so the code of a block's
            // maximum is the maximum of its cells' codes: the levels above 0 are max-pooled
            // from level 0's codes (one byte a cell), the same codes as those of the `f32`
            // levels, and the cells outside read the code of `far`.
            let base: Vec<u8> = data.iter().map(|&v| coder.code(v)).collect();
            let far = coder.code(far);
            codes = vec![0u8; (depth as usize - 1) * n];
            for k in 1..depth as usize {
                let half = (stride as usize) << (k - 1);
                let (done, rest) = codes.split_at_mut((k - 1) * n);
                let prev = if k == 1 { &base } else { &done[(k - 2) * n..] };
                pool(prev, &mut rest[..n], w, half, far);
            }
        } else {
            for k in 1..depth as usize {
                let half = (stride as usize) << (k - 1);
                let (done, rest) = data.split_at_mut(k * n);
                pool(&done[(k - 1) * n..], &mut rest[..n], w, half, far);
            }
        }
        Ok(Self {
            origin,
            width: w,
            height: h,
            stride,
            far,
            depth,
            data,
            codes,
            table,
            pooled,
        })
    }

    /// P_level(c); `far` outside the stored cells.
    #[inline]
    pub(crate) fn value(&self, level: u32, c: CellIndex) -> f32 {
        let x = c.x as i64 - self.origin.x as i64;
        let y = c.y as i64 - self.origin.y as i64;
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return self.far;
        }
        let n = self.width * self.height;
        let i = y as usize * self.width + x as usize;
        if level > 0 && !self.codes.is_empty() {
            self.table[self.codes[(level as usize - 1) * n + i] as usize]
        } else {
            self.data[level as usize * n + i]
        }
    }

    /// The flat offset of translation (dx, dy) (lattice steps) when the box `bounds` moved
    /// by it stays inside the stored cells: cell c then reads index c.y·w + c.x + offset.
    #[inline]
    fn offset_inside(&self, bounds: (CellIndex, CellIndex), dx: i32, dy: i32) -> Option<i64> {
        let (dx, dy) = (
            dx as i64 * self.stride as i64,
            dy as i64 * self.stride as i64,
        );
        let (ox, oy) = (dx - self.origin.x as i64, dy - self.origin.y as i64);
        let (lo, hi) = bounds;
        let inside = lo.x as i64 + ox >= 0
            && lo.y as i64 + oy >= 0
            && hi.x as i64 + ox < self.width as i64
            && hi.y as i64 + oy < self.height as i64;
        inside.then_some(oy * self.width as i64 + ox)
    }

    /// Σ over `cells` of P_level(c + m·(dx, dy)), (dx, dy) in lattice steps. `bounds`, the
    /// inclusive box of `cells`, lets a box that stays inside the stored cells skip the
    /// per-cell bounds test; the sum is the same (the same values in the same order).
    #[inline]
    pub(crate) fn score(
        &self,
        level: u32,
        cells: &[CellIndex],
        bounds: (CellIndex, CellIndex),
        dx: i32,
        dy: i32,
    ) -> f32 {
        if let Some(offset) = self.offset_inside(bounds, dx, dy) {
            let w = self.width as i64;
            let index = |c: &CellIndex| (c.y as i64 * w + c.x as i64 + offset) as usize;
            let n = self.width * self.height;
            let level = level as usize;
            if level > 0 && !self.codes.is_empty() {
                let codes = &self.codes[(level - 1) * n..level * n];
                return cells
                    .iter()
                    .map(|c| self.table[codes[index(c)] as usize])
                    .sum();
            }
            let values = &self.data[level * n..(level + 1) * n];
            return cells.iter().map(|c| values[index(c)]).sum();
        }
        let (dx, dy) = (dx * self.stride, dy * self.stride);
        cells
            .iter()
            .map(|c| self.value(level, CellIndex::new(c.x + dx, c.y + dy)))
            .sum()
    }

    /// [`Levels::score`] of each translation of `moves` (at most 4): the same sums (each
    /// adds the same values in the same order from the start `Iterator::sum` takes), as
    /// four independent chains of additions when there are four and every moved box stays
    /// inside the stored cells (a chain waits on its last addition; four overlap).
    #[inline]
    pub(crate) fn score4(
        &self,
        level: u32,
        cells: &[CellIndex],
        bounds: (CellIndex, CellIndex),
        moves: &[(i32, i32)],
    ) -> [f32; 4] {
        let mut out = [0.0f32; 4];
        let offsets = match moves {
            [a, b, c, d] => [a, b, c, d].map(|&(dx, dy)| self.offset_inside(bounds, dx, dy)),
            _ => [None; 4],
        };
        let [Some(a), Some(b), Some(c), Some(d)] = offsets else {
            for (o, &(dx, dy)) in out.iter_mut().zip(moves) {
                *o = self.score(level, cells, bounds, dx, dy);
            }
            return out;
        };
        let offsets = [a, b, c, d];
        let w = self.width as i64;
        let n = self.width * self.height;
        let level = level as usize;
        let start: f32 = std::iter::empty::<f32>().sum();
        let mut sums = [start; 4];
        if level > 0 && !self.codes.is_empty() {
            let codes = &self.codes[(level - 1) * n..level * n];
            for c in cells {
                let i = c.y as i64 * w + c.x as i64;
                for (s, o) in sums.iter_mut().zip(offsets) {
                    *s += self.table[codes[(i + o) as usize] as usize];
                }
            }
        } else {
            let values = &self.data[level * n..(level + 1) * n];
            for c in cells {
                let i = c.y as i64 * w + c.x as i64;
                for (s, o) in sums.iter_mut().zip(offsets) {
                    *s += values[(i + o) as usize];
                }
            }
        }
        sums
    }

    /// Number of levels.
    pub(crate) fn depth(&self) -> u32 {
        self.depth
    }

    /// The value of every cell outside the stored rectangle (the score's minimum).
    #[cfg(test)]
    pub(crate) fn far(&self) -> f32 {
        self.far
    }

    /// Bytes held by the levels (their values, codes and code table).
    pub(crate) fn memory_bytes(&self) -> usize {
        self.data.len() * std::mem::size_of::<f32>()
            + self.codes.len()
            + std::mem::size_of_val(&self.table)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pseudo-random values in [−500, 496] and a `base` filling a window with them.
    fn value(x: i32, y: i32) -> f32 {
        ((x * 7919 + y * 104_729).rem_euclid(997)) as f32 - 500.0
    }

    fn fill(o: CellIndex, w: usize, _h: usize, out: &mut [f32]) {
        for (i, v) in out.iter_mut().enumerate() {
            *v = value(o.x + (i % w) as i32, o.y + (i / w) as i32);
        }
    }

    /// The maximum from the definition: over the lattice cells {x + a·m} × {y + b·m},
    /// 0 ≤ a, b < 2^k, of the rectangle `min … max` (`far` outside it).
    fn block_max(k: u32, x: i32, y: i32, stride: i32, rect: (CellIndex, CellIndex)) -> f32 {
        let (min, max) = rect;
        let mut m = -1000.0f32;
        for b in 0..1 << k {
            for a in 0..1 << k {
                let (xx, yy) = (x + a * stride, y + b * stride);
                if (min.x..=max.x).contains(&xx) && (min.y..=max.y).contains(&yy) {
                    m = m.max(value(xx, yy));
                }
            }
        }
        m
    }

    /// With a lattice stride, and built in a reused (dirty, larger) buffer, every level is
    /// still the maximum over its block of lattice cells, checked by brute force from the
    /// definition on pseudo-random values (cells outside the rectangle read `far`).
    #[test]
    fn strided_pooled_levels_are_block_maxima() {
        let far = -1000.0;
        // A larger pyramid first, so that the second reuses its dirty buffer.
        let (a, b) = (CellIndex::new(0, 0), CellIndex::new(90, 80));
        drop(Levels::build(a, b, 5, 2, far, fill, Storage::Pooled).unwrap());
        for storage in [Storage::Pooled, Storage::Full] {
            let (min, max, depth, stride) = (CellIndex::new(-3, 4), CellIndex::new(30, 25), 4, 3);
            let l = Levels::build(min, max, depth, stride, far, fill, storage).unwrap();
            let lowest = CellIndex::new(
                min.x - ((1 << (depth - 1)) - 1) * stride,
                min.y - ((1 << (depth - 1)) - 1) * stride,
            );
            for k in 0..depth {
                for y in lowest.y..30 {
                    for x in lowest.x..35 {
                        assert_eq!(
                            l.value(k, CellIndex::new(x, y)),
                            block_max(k, x, y, stride, (min, max)),
                            "level {k} at ({x}, {y}), {storage:?}"
                        );
                    }
                }
            }
        }
    }

    /// Compact levels: level 0 exact, every coarser level at or above the brute-force
    /// block maximum by at most one code step, (hi − lo)/255 over the values' range and
    /// `far`; a quarter of the memory of the levels above 0; a score is the sum of the
    /// values (inside the stored cells and across their edge).
    #[test]
    fn compact_levels_bound_the_block_maxima() {
        let far = -1000.0;
        let (min, max, depth, stride) = (CellIndex::new(5, -7), CellIndex::new(44, 20), 4, 2);
        let full = Levels::build(min, max, depth, stride, far, fill, Storage::Full).unwrap();
        let compact = Levels::build(min, max, depth, stride, far, fill, Storage::Compact).unwrap();
        let step = (496.0 - far) / 255.0;
        let n = full.width * full.height;
        let coder = Coder::new(&full.data[..n], far);
        assert_eq!(coder.table, compact.table);
        assert_eq!(compact.memory_bytes(), 4 * n + 3 * n + 1024);
        assert_eq!(full.memory_bytes(), 4 * 4 * n + 1024);
        for k in 0..depth {
            for y in -30..25 {
                for x in -20..50 {
                    let e = block_max(k, x, y, stride, (min, max));
                    let q = compact.value(k, CellIndex::new(x, y));
                    // The pooled codes are the codes of the pooled values.
                    let coded =
                        coder.table[coder.code(full.value(k, CellIndex::new(x, y))) as usize];
                    assert_eq!(q, if k == 0 { e } else { coded }, "level {k} at ({x}, {y})");
                    if k == 0 || x < full.origin.x || y < full.origin.y {
                        assert_eq!(q, e, "level {k} at ({x}, {y})");
                    } else {
                        assert!(q >= e && q - e <= step * 1.001, "level {k}: {q} vs {e}");
                    }
                }
            }
        }
        let cells = [
            CellIndex::new(6, 0),
            CellIndex::new(30, 19),
            CellIndex::new(8, 8),
        ];
        let bounds = (CellIndex::new(6, 0), CellIndex::new(30, 19));
        for (dx, dy) in [(0, 0), (-3, 1), (4, 2), (-40, 3)] {
            for k in 0..depth {
                let own: f32 = cells
                    .iter()
                    .map(|c| compact.value(k, CellIndex::new(c.x + dx * 2, c.y + dy * 2)))
                    .sum();
                assert_eq!(compact.score(k, &cells, bounds, dx, dy), own);
            }
        }
        // Four moves at once: each the sum alone, to the bit (inside and across the edge).
        for levels in [&full, &compact] {
            for (dx, dy) in [(0, 0), (-2, 1), (6, 2), (-40, 3), (3, -9)] {
                let moves = [(dx, dy), (dx + 1, dy), (dx, dy + 2), (dx + 1, dy + 2)];
                for k in 0..depth {
                    let four = levels.score4(k, &cells, bounds, &moves);
                    for (&(x, y), s) in moves.iter().zip(four) {
                        let one = levels.score(k, &cells, bounds, x, y);
                        assert_eq!(s.to_bits(), one.to_bits(), "level {k} move ({x}, {y})");
                    }
                    let three = levels.score4(k, &cells, bounds, &moves[..3]);
                    assert_eq!(three[..3], four[..3]);
                }
            }
        }
    }
}
