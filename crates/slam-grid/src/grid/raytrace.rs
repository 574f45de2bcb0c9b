//! Exact grid traversal of a segment (Amanatides & Woo, "A fast voxel traversal algorithm
//! for ray tracing", Eurographics 1987).

use crate::cell::CellIndex;

/// Visits, in order, every cell the segment from `start` to `end` (continuous cell
/// coordinates, see [`crate::cell`]) passes through, **excluding** the cell containing
/// `end`, which is returned. The number of steps is fixed in advance to the Manhattan
/// distance between the start and end cells, so the walk always terminates and stays
/// 4-connected; where the segment passes exactly through a cell corner, the x step is taken
/// first. (The walk as a list of cells: what the tests check the geometry and the scan
/// integration against; the integration follows a [`Ray`] itself.)
#[cfg(test)]
pub(crate) fn trace_segment<F: FnMut(CellIndex)>(
    start: (f64, f64),
    end: (f64, f64),
    mut visit: F,
) -> CellIndex {
    let mut r = Ray::new(start, end);
    while r.steps_left() > 0 {
        visit(CellIndex::new(r.x, r.y));
        r.step();
    }
    CellIndex::new(r.x, r.y)
}

/// The state of an Amanatides–Woo walk from `start` towards the cell of `end`: the current
/// cell (`x`, `y`) and the steps still to take, for callers that follow the cells one by
/// one (the scan integration steps its tile-local index along with it). The number of
/// steps is fixed in advance to the Manhattan distance between the start and end cells, so
/// the walk always terminates and stays 4-connected; where the segment passes exactly
/// through a cell corner, the x step is taken first.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ray {
    /// Current cell.
    pub(crate) x: i32,
    pub(crate) y: i32,
    /// Direction of an x / y step (±1).
    pub(crate) step_x: i32,
    pub(crate) step_y: i32,
    // Parameter t ∈ [0, 1] along the segment at which the next x / y cell boundary is met,
    // and its increment per cell.
    t_max_x: f64,
    t_max_y: f64,
    t_delta_x: f64,
    t_delta_y: f64,
    // Steps left along x / y before the end cell is reached.
    n_x: u32,
    n_y: u32,
}

/// Along one axis of a segment starting at `start` in cell `cell` with extent `d`: the
/// parameter t ∈ [0, 1] at which it meets the next cell boundary, and t's increment per
/// cell (∞ for both when the segment does not move along the axis).
#[inline]
fn first_crossing(start: f64, cell: i32, d: f64) -> (f64, f64) {
    if d != 0.0 {
        let next = if d > 0.0 {
            (cell as f64 + 1.0 - start) / d
        } else {
            (start - cell as f64) / -d
        };
        (next, 1.0 / d.abs())
    } else {
        (f64::INFINITY, f64::INFINITY)
    }
}

impl Ray {
    /// A walk standing in the cell of `start`, with the Manhattan distance to the cell of
    /// `end` still to go.
    #[inline]
    pub(crate) fn new(start: (f64, f64), end: (f64, f64)) -> Self {
        let x = start.0.floor() as i32;
        let y = start.1.floor() as i32;
        let end_cell = CellIndex::new(end.0.floor() as i32, end.1.floor() as i32);
        let dx = end.0 - start.0;
        let dy = end.1 - start.1;
        let step_x = if dx > 0.0 { 1 } else { -1 };
        let step_y = if dy > 0.0 { 1 } else { -1 };
        let (t_max_x, t_delta_x) = first_crossing(start.0, x, dx);
        let (t_max_y, t_delta_y) = first_crossing(start.1, y, dy);
        Self {
            x,
            y,
            step_x,
            step_y,
            t_max_x,
            t_max_y,
            t_delta_x,
            t_delta_y,
            n_x: (end_cell.x - x).unsigned_abs(),
            n_y: (end_cell.y - y).unsigned_abs(),
        }
    }

    /// Steps left before the walk stands in the end cell.
    #[inline(always)]
    pub(crate) fn steps_left(&self) -> u32 {
        self.n_x + self.n_y
    }

    /// The segment parameter t ∈ [0, 1] at which the walk entered its current cell (0 in
    /// the start cell): the larger of the last x and y boundary crossings.
    #[inline]
    pub(crate) fn entry_t(&self) -> f64 {
        let tx = self.t_max_x - self.t_delta_x;
        let ty = self.t_max_y - self.t_delta_y;
        let t = match (tx.is_finite(), ty.is_finite()) {
            (true, true) => tx.max(ty),
            (true, false) => tx,
            (false, true) => ty,
            (false, false) => 0.0,
        };
        t.max(0.0)
    }

    /// Moves to the next cell (only while [`Ray::steps_left`] > 0); true when the step was
    /// along x (by `step_x`), false when along y (by `step_y`). The x step is taken while
    /// the next x boundary comes first (`t_max_x ≤ t_max_y`) and x steps remain, or when
    /// no y step does.
    #[inline(always)]
    pub(crate) fn step(&mut self) -> bool {
        if (self.t_max_x <= self.t_max_y && self.n_x > 0) || self.n_y == 0 {
            self.x += self.step_x;
            self.t_max_x += self.t_delta_x;
            self.n_x -= 1;
            true
        } else {
            self.y += self.step_y;
            self.t_max_y += self.t_delta_y;
            self.n_y -= 1;
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use std::collections::BTreeSet;

    /// Does the segment a→b intersect the closed square of cell c, shrunk by `eps`?
    fn segment_hits_cell(a: (f64, f64), b: (f64, f64), c: CellIndex, eps: f64) -> bool {
        // Liang–Barsky clipping against [x0, x1] × [y0, y1].
        let (x0, x1) = (c.x as f64 + eps, c.x as f64 + 1.0 - eps);
        let (y0, y1) = (c.y as f64 + eps, c.y as f64 + 1.0 - eps);
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let mut t0: f64 = 0.0;
        let mut t1: f64 = 1.0;
        for (p, q) in [
            (-dx, a.0 - x0),
            (dx, x1 - a.0),
            (-dy, a.1 - y0),
            (dy, y1 - a.1),
        ] {
            if p == 0.0 {
                if q < 0.0 {
                    return false;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    t0 = t0.max(r);
                } else {
                    t1 = t1.min(r);
                }
            }
        }
        t0 <= t1
    }

    #[test]
    fn traversal_matches_brute_force_on_random_segments() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
        for _ in 0..2000 {
            let a = (rng.random_range(-20.0..20.0), rng.random_range(-20.0..20.0));
            let b = (rng.random_range(-20.0..20.0), rng.random_range(-20.0..20.0));
            let mut visited = Vec::new();
            let end = trace_segment(a, b, |c| visited.push(c));
            visited.push(end);
            // Consecutive cells are 4-neighbours; first is the start cell, last the end cell.
            assert_eq!(
                visited[0],
                CellIndex::new(a.0.floor() as i32, a.1.floor() as i32)
            );
            for w in visited.windows(2) {
                assert_eq!((w[0].x - w[1].x).abs() + (w[0].y - w[1].y).abs(), 1);
            }
            // Every visited cell touches the segment (closed cell), and every cell whose
            // interior the segment crosses (shrunk by 1e-9) was visited.
            let set: BTreeSet<CellIndex> = visited.iter().copied().collect();
            assert_eq!(set.len(), visited.len(), "a cell was visited twice");
            for c in &visited {
                assert!(
                    segment_hits_cell(a, b, *c, -1e-9),
                    "{c:?} not on {a:?}->{b:?}"
                );
            }
            let (lo_x, hi_x) = (a.0.min(b.0).floor() as i32, a.0.max(b.0).floor() as i32);
            let (lo_y, hi_y) = (a.1.min(b.1).floor() as i32, a.1.max(b.1).floor() as i32);
            for x in lo_x..=hi_x {
                for y in lo_y..=hi_y {
                    let c = CellIndex::new(x, y);
                    if segment_hits_cell(a, b, c, 1e-9) {
                        assert!(set.contains(&c), "{c:?} crossed by {a:?}->{b:?} but missed");
                    }
                }
            }
        }
    }

    #[test]
    fn axis_aligned_and_degenerate() {
        let mut v = Vec::new();
        let end = trace_segment((0.5, 0.5), (3.5, 0.5), |c| v.push(c));
        assert_eq!(
            v,
            vec![
                CellIndex::new(0, 0),
                CellIndex::new(1, 0),
                CellIndex::new(2, 0)
            ]
        );
        assert_eq!(end, CellIndex::new(3, 0));
        let mut v = Vec::new();
        let end = trace_segment((-0.5, -0.5), (-0.2, -0.7), |c| v.push(c));
        assert!(v.is_empty());
        assert_eq!(end, CellIndex::new(-1, -1));
    }
}
