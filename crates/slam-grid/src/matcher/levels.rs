//! Max-pooled levels of a per-cell score (the precomputed grids of a branch-and-bound
//! search: Olson, ICRA 2009, §IV-C; Hess et al., ICRA 2016, §V-B), built row by row in a
//! buffer that a thread reuses from one search to the next.

use super::branch_bound::{MAX_PYRAMID_CELLS, MAX_PYRAMID_DEPTH};
use crate::cell::CellIndex;
use crate::error::{ensure_config, GridError};

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
    /// Level k at `[k·w·h, (k + 1)·w·h)`, each row-major.
    data: Vec<f32>,
    /// Whether `data` goes back to this thread's spare buffer when dropped ([`SPARE`]).
    pooled: bool,
}

/// Largest buffer kept for reuse by a thread (bytes): the levels of a search pyramid are
/// tens of megabytes for a 30 m scan, and a fresh allocation of that size costs more in
/// page faults than filling it.
const MAX_SPARE_BYTES: usize = 128 << 20;

thread_local! {
    /// One spare buffer per thread, for the pyramids of [`Levels::build`] with `pooled`.
    static SPARE: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
}

impl Clone for Levels {
    fn clone(&self) -> Self {
        Self {
            data: self.data.clone(),
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
fn larger(a: f32, b: f32) -> f32 {
    if b > a {
        b
    } else {
        a
    }
}

impl Levels {
    /// The `depth` levels over the inclusive rectangle `min … max` with lattice stride
    /// `stride`; `base(origin, w, h, out)` writes the row-major values of the `w × h` cells
    /// from `origin` into `out` (every element; the rectangle grown by the padding below
    /// it, which reads `far`). `pooled`: in this thread's spare buffer, given back when the
    /// levels are dropped (for pyramids built and dropped per search: the same values,
    /// fewer page faults).
    pub(crate) fn build(
        min: CellIndex,
        max: CellIndex,
        depth: u32,
        stride: i32,
        far: f32,
        base: impl FnOnce(CellIndex, usize, usize, &mut [f32]),
        pooled: bool,
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
        let len = depth as usize * n;
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
        // P_k from P_{k−1}: the max over the 4 cells (x, y), (x + h, y), (x, y + h),
        // (x + h, y + h), h = stride·2^(k−1), a cell outside the rectangle reading `far` (the
        // minimum, so it changes nothing unless all four are outside): first along rows,
        // then, in place, between a row and the one h above it (rows going up, so that row
        // is read before it is overwritten).
        for k in 1..depth as usize {
            let half = (stride as usize) << (k - 1);
            let (done, rest) = data.split_at_mut(k * n);
            let prev = &done[(k - 1) * n..];
            let next = &mut rest[..n];
            for (out, src) in next.chunks_exact_mut(w).zip(prev.chunks_exact(w)) {
                if half < w {
                    let m = w - half;
                    let (o, a, b) = (&mut out[..m], &src[..m], &src[half..]);
                    for i in 0..m {
                        o[i] = larger(a[i], b[i]);
                    }
                    out[m..].copy_from_slice(&src[m..]);
                } else {
                    out.copy_from_slice(src);
                }
            }
            for y in 0..h.saturating_sub(half) {
                let (low, high) = next.split_at_mut((y + half) * w);
                let (row, above) = (&mut low[y * w..(y + 1) * w], &high[..w]);
                for i in 0..w {
                    row[i] = larger(row[i], above[i]);
                }
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
        self.data[level as usize * n + y as usize * self.width + x as usize]
    }

    /// Σ over `cells` of P_level(c + m·(dx, dy)), (dx, dy) in lattice steps.
    #[inline]
    pub(crate) fn score(&self, level: u32, cells: &[CellIndex], dx: i32, dy: i32) -> f32 {
        let (dx, dy) = (dx * self.stride, dy * self.stride);
        cells
            .iter()
            .map(|c| self.value(level, CellIndex::new(c.x + dx, c.y + dy)))
            .sum()
    }

    pub(crate) fn depth(&self) -> u32 {
        self.depth
    }

    /// The value of every cell outside the stored rectangle (the score's minimum).
    #[cfg(test)]
    pub(crate) fn far(&self) -> f32 {
        self.far
    }

    /// Bytes held by the levels.
    pub(crate) fn memory_bytes(&self) -> usize {
        self.depth as usize * self.width * self.height * std::mem::size_of::<f32>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With a lattice stride, and built in a reused (dirty, larger) buffer, every level is
    /// still the maximum over its block of lattice cells, checked by brute force from the
    /// definition on pseudo-random values (cells outside the rectangle read `far`).
    #[test]
    fn strided_pooled_levels_are_block_maxima() {
        let value = |x: i32, y: i32| ((x * 7919 + y * 104_729).rem_euclid(997)) as f32 - 500.0;
        let far = -1000.0;
        let fill = |o: CellIndex, w: usize, _h: usize, out: &mut [f32]| {
            for (i, v) in out.iter_mut().enumerate() {
                *v = value(o.x + (i % w) as i32, o.y + (i / w) as i32);
            }
        };
        // A larger pyramid first, so that the second reuses its dirty buffer.
        drop(
            Levels::build(
                CellIndex::new(0, 0),
                CellIndex::new(90, 80),
                5,
                2,
                far,
                fill,
                true,
            )
            .unwrap(),
        );
        for pooled in [true, false] {
            let (min, max, depth, stride) = (CellIndex::new(-3, 4), CellIndex::new(30, 25), 4, 3);
            let l = Levels::build(min, max, depth, stride, far, fill, pooled).unwrap();
            for k in 0..depth {
                for y in -30..30 {
                    for x in -30..35 {
                        let mut m = far;
                        for b in 0..1 << k {
                            for a in 0..1 << k {
                                let (xx, yy) = (x + a * stride, y + b * stride);
                                let inside =
                                    (min.x..=max.x).contains(&xx) && (min.y..=max.y).contains(&yy);
                                if inside {
                                    m = m.max(value(xx, yy));
                                }
                            }
                        }
                        let lowest = CellIndex::new(
                            min.x - ((1 << (depth - 1)) - 1) * stride,
                            min.y - ((1 << (depth - 1)) - 1) * stride,
                        );
                        if x >= lowest.x && y >= lowest.y {
                            assert_eq!(
                                l.value(k, CellIndex::new(x, y)),
                                m,
                                "level {k} at ({x}, {y}), pooled {pooled}"
                            );
                        }
                    }
                }
            }
        }
    }
}
