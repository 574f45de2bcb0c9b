//! Correlative multi-resolution scan matching (Olson, "Real-time correlative scan
//! matching", ICRA 2009).

use super::{check_input, covariance_by_sampling, validate_window, MatchResult};
use crate::cell::CellIndex;
use crate::error::{ensure_config, GridError};
use crate::grid::OccupancyGrid;
use crate::scan::RangeData;
use serde::{Deserialize, Serialize};
use slam_models::{ConfigError, Pose2};

/// Most rotations searched on each side of the initial heading (the automatic step is at
/// least 10⁻⁴ rad, so ≤ 31 416 within the largest window, π).
const MAX_ROTATIONS: i32 = 100_000;

/// Exhaustive search of a window of poses around the initial guess, made fast with two
/// resolutions (Olson 2009, §IV):
///
/// 1. the likelihood field around the search area is copied once into a dense window W;
/// 2. a max-pooled copy C, C(c) = max of W over the f×f cells c … c + (f−1, f−1), bounds
///    the score of every translation in an f×f block of candidate offsets from above;
/// 3. for each rotation (step chosen so the farthest end point moves about one cell) the
///    end points are rotated once; every block gets its upper bound from C;
/// 4. blocks are visited in order of decreasing bound, scoring each of their translations
///    exactly on W, until the best exact score beats every remaining bound.
///
/// The result is the exact maximum over the fine lattice (translations in cells, rotations
/// in angular steps) of Σ s(cell of pᵢ), the same answer as brute force. Follow it with
/// [`super::GaussNewtonMatcher`] for sub-cell accuracy ([`super::RefinedCorrelativeMatcher`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct CorrelativeMatcher {
    /// Half-width of the translation window in x and y, metres. Default 0.4 m.
    pub linear_window: f64,
    /// Half-width of the rotation window, radians. Default 0.21 rad (12°).
    pub angular_window: f64,
    /// Rotation step, radians; 0 chooses the angle that moves the farthest end point by
    /// one cell, acos(1 − res²/(2 r²)) (Olson 2009 / Cartographer). Default 0.
    pub angular_step: f64,
    /// Edge of a coarse block, in fine cells (≥ 1). Default 8.
    pub coarse_factor: u32,
    /// Fewer end points than this is an error. Default 10.
    pub min_points: usize,
}

impl Default for CorrelativeMatcher {
    fn default() -> Self {
        Self {
            linear_window: 0.4,
            angular_window: 0.21,
            angular_step: 0.0,
            coarse_factor: 8,
            min_points: 10,
        }
    }
}

impl CorrelativeMatcher {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), GridError> {
        validate_window(self.linear_window, self.angular_window, self.angular_step)?;
        ensure_config(
            self.coarse_factor >= 1 && self.coarse_factor <= 64,
            "coarse_factor",
            self.coarse_factor as f64,
            "in 1..=64",
        )
    }

    /// Searches the window around `initial`; see the type documentation.
    pub fn match_prepared(
        &self,
        grid: &OccupancyGrid,
        scan: &RangeData,
        initial: &Pose2,
    ) -> Result<MatchResult, GridError> {
        self.validate()?;
        let res = grid.resolution();
        let f = self.coarse_factor as i32;
        // The window's corners and widths are i32 cell arithmetic: keep them far from
        // overflow (an initial pose 1e10 m off used to wrap them into an out-of-bounds index).
        check_input(
            grid,
            scan,
            initial,
            self.min_points,
            self.linear_window + f as f64 * res,
        )?;
        let frame = grid.frame();
        let dtheta = super::rotation_step(self.angular_step, res, scan.max_point_range);
        let k_max = (self.angular_window / dtheta).ceil();
        if k_max > MAX_ROTATIONS as f64 {
            return Err(GridError::InvalidConfig(ConfigError::new(
                "correlative matcher",
                "angular_step",
                self.angular_step,
                "large enough for at most 100000 rotations per side of angular_window \
                 (angular_window / angular_step)",
            )));
        }
        let k_max = k_max as i32;
        // Below 2^30 cells by the reach check above.
        let l = (self.linear_window / res).ceil() as i32;
        let n = scan.points.len();

        // End-point cells for every rotation (translation = initial), and their bounds.
        let n_rot = (2 * k_max + 1) as usize;
        // Grown a rotation at a time, as when pushed cell by cell: a zeroed allocation of
        // the whole (`vec![…; n_rot · n]`) raised acapulco's peak RSS by 13 MB.
        let arrays = super::PointCells::new(&scan.points);
        let mut cells: Vec<CellIndex> = Vec::with_capacity(n_rot * n);
        for k in -k_max..=k_max {
            let theta = initial.theta + k as f64 * dtheta;
            let pose = Pose2::new(initial.x, initial.y, theta);
            let start = cells.len();
            cells.resize(start + n, CellIndex::default());
            arrays.cells_at(&frame, &pose, &mut cells[start..]);
        }
        let (mut lo, mut hi) = (
            CellIndex::new(i32::MAX, i32::MAX),
            CellIndex::new(i32::MIN, i32::MIN),
        );
        for c in &cells {
            lo = CellIndex::new(lo.x.min(c.x), lo.y.min(c.y));
            hi = CellIndex::new(hi.x.max(c.x), hi.y.max(c.y));
        }
        // Window: every cell an end point can reach with offsets in [−l, l + f − 1].
        let min = CellIndex::new(lo.x - l, lo.y - l);
        let w = hi.x as i64 - lo.x as i64 + 2 * l as i64 + f as i64;
        let h = hi.y as i64 - lo.y as i64 + 2 * l as i64 + f as i64;
        if w.saturating_mul(h) > 64_000_000 {
            return Err(GridError::InvalidConfig(ConfigError::new(
                "correlative matcher",
                "linear_window",
                self.linear_window,
                "a search window of at most 64e6 cells with the scan's extent: \
                 shorten the matching range or the window",
            )));
        }
        let (w, h) = (w as usize, h as usize);
        // The field only in the tiles some read reaches: an end point's sums read the
        // cells [c − l, c + l + f − 1] (fine offsets up to 2l, coarse maxima f wide), at
        // most 2 × 2 tiles (their cells outside hold the far value, never read).
        let bits = crate::grid::tiles::TILE_BITS;
        let t0 = (min.x >> bits, min.y >> bits);
        let tw = (((min.x + w as i32 - 1) >> bits) - t0.0 + 1) as usize;
        let th = (((min.y + h as i32 - 1) >> bits) - t0.1 + 1) as usize;
        let mut wanted = vec![false; tw * th];
        for c in &cells {
            let (x0, y0) = ((c.x - l) >> bits, (c.y - l) >> bits);
            let (x1, y1) = ((c.x + l + f - 1) >> bits, (c.y + l + f - 1) >> bits);
            for ty in y0..=y1 {
                for tx in x0..=x1 {
                    wanted[(ty - t0.1) as usize * tw + (tx - t0.0) as usize] = true;
                }
            }
        }
        let mut fine = vec![0.0f32; w * h];
        grid.field_window_tiles_into(min, w, &mut fine, |tx, ty| {
            wanted[(ty - t0.1) as usize * tw + (tx - t0.0) as usize]
        });
        let coarse = sliding_max(&fine, w, h, f as usize);
        // Linear indices of each rotation's end points at offset (−l, −l).
        let idx: Vec<u32> = cells
            .iter()
            .map(|c| ((c.y - l - min.y) as usize * w + (c.x - l - min.x) as usize) as u32)
            .collect();

        // Upper bounds of every (rotation, block).
        let blocks: Vec<i32> = (0..).map(|b| b * f).take_while(|&o| o <= 2 * l).collect();
        let mut candidates: Vec<(f32, u32, i32, i32)> =
            Vec::with_capacity(n_rot * blocks.len() * blocks.len());
        let (mut offsets, mut sums) = (Vec::new(), Vec::new());
        for r in 0..n_rot {
            let pts = &idx[r * n..(r + 1) * n];
            for &by in &blocks {
                offsets.clear();
                offsets.extend(blocks.iter().map(|&bx| by as usize * w + bx as usize));
                sums_at(&coarse, pts, &offsets, &mut sums);
                for (&bx, &ub) in blocks.iter().zip(&sums) {
                    candidates.push((ub, r as u32, bx, by));
                }
            }
        }
        candidates.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));

        // Branch and bound over the fine offsets.
        let mut best = (f32::NEG_INFINITY, 0u32, 0i32, 0i32);
        for &(ub, r, bx, by) in &candidates {
            if ub <= best.0 {
                break;
            }
            let pts = &idx[r as usize * n..(r as usize + 1) * n];
            let xs = bx..(bx + f).min(2 * l + 1);
            for oy in by..(by + f).min(2 * l + 1) {
                offsets.clear();
                offsets.extend(xs.clone().map(|ox| oy as usize * w + ox as usize));
                sums_at(&fine, pts, &offsets, &mut sums);
                for (ox, &s) in xs.clone().zip(&sums) {
                    if s > best.0 {
                        best = (s, r, ox, oy);
                    }
                }
            }
        }
        let (s, r, ox, oy) = best;
        let pose = Pose2::new(
            initial.x + (ox - l) as f64 * res,
            initial.y + (oy - l) as f64 * res,
            initial.theta + (r as i32 - k_max) as f64 * dtheta,
        );
        let covariance = covariance_by_sampling(grid, scan, &pose, [res, res, dtheta]);
        Ok(MatchResult {
            pose,
            score: s as f64 / n as f64,
            covariance,
        })
    }
}

/// Σ over `pts` of `values[i + offset]` for each of `offsets`, into `sums` (resized): four
/// at a time in independent chains of additions, each the same sum as alone (the same
/// values in the same order from the start `Iterator::sum` takes); a chain waits on its
/// last addition, four overlap.
fn sums_at(values: &[f32], pts: &[u32], offsets: &[usize], sums: &mut Vec<f32>) {
    let start: f32 = std::iter::empty::<f32>().sum();
    sums.clear();
    sums.resize(offsets.len(), start);
    for (offs, out) in offsets.chunks(4).zip(sums.chunks_mut(4)) {
        if let &[a, b, c, d] = offs {
            let mut s = [start; 4];
            for &i in pts {
                let i = i as usize;
                s[0] += values[i + a];
                s[1] += values[i + b];
                s[2] += values[i + c];
                s[3] += values[i + d];
            }
            out.copy_from_slice(&s);
        } else {
            for (o, &off) in out.iter_mut().zip(offs) {
                *o = pts.iter().map(|&i| values[i as usize + off]).sum();
            }
        }
    }
}

/// C(x, y) = max of `src` over [x, x + f) × [y, y + f) (clipped at the far edges):
/// separable sliding maximum, O(w·h·f).
fn sliding_max(src: &[f32], w: usize, h: usize, f: usize) -> Vec<f32> {
    if f <= 1 {
        return src.to_vec();
    }
    let mut tmp = vec![0.0f32; w * h];
    for y in 0..h {
        let row = &src[y * w..(y + 1) * w];
        for x in 0..w {
            let end = (x + f).min(w);
            tmp[y * w + x] = row[x..end]
                .iter()
                .copied()
                .fold(f32::NEG_INFINITY, f32::max);
        }
    }
    let mut out = vec![0.0f32; w * h];
    for y in 0..h {
        let end = (y + f).min(h);
        let (dst, rest) = out[y * w..].split_at_mut(w);
        let _ = rest;
        dst.copy_from_slice(&tmp[y * w..(y + 1) * w]);
        for yy in y + 1..end {
            for x in 0..w {
                dst[x] = dst[x].max(tmp[yy * w + x]);
            }
        }
    }
    out
}

super::scan_matcher_by_inherent_method!(CorrelativeMatcher);

#[cfg(test)]
mod tests {
    use super::*;

    /// Four sums at once are each the sum alone, to the bit, for 1 to 9 offsets.
    #[test]
    fn sums_at_equals_each_sum_alone() {
        let values: Vec<f32> = (0..400)
            .map(|i| ((i * 7919) % 101) as f32 * 0.37 - 9.0)
            .collect();
        let pts: Vec<u32> = (0..50).map(|i| (i * 37) % 300).collect();
        let mut sums = Vec::new();
        for k in 1..=9 {
            let offsets: Vec<usize> = (0..k).map(|j| j * 11).collect();
            sums_at(&values, &pts, &offsets, &mut sums);
            assert_eq!(sums.len(), k);
            for (&off, s) in offsets.iter().zip(&sums) {
                let alone: f32 = pts.iter().map(|&i| values[i as usize + off]).sum();
                assert_eq!(s.to_bits(), alone.to_bits(), "offset {off}");
            }
        }
    }

    #[test]
    fn sliding_max_matches_brute_force() {
        let (w, h) = (13, 9);
        let src: Vec<f32> = (0..w * h).map(|i| ((i * 7919) % 101) as f32).collect();
        for f in [1, 2, 3, 8] {
            let got = sliding_max(&src, w, h, f);
            for y in 0..h {
                for x in 0..w {
                    let mut m = f32::NEG_INFINITY;
                    for yy in y..(y + f).min(h) {
                        for xx in x..(x + f).min(w) {
                            m = m.max(src[yy * w + xx]);
                        }
                    }
                    assert_eq!(got[y * w + x], m);
                }
            }
        }
    }
}
