//! The lazy likelihood field every [`OccupancyGrid`] carries: field tiles computed on the
//! first read of a tile (exact EDT, [`compute_region`]), cached in the grid's per-tile
//! cache ([`crate::grid::TileCache`], shared between clones like the tiles) and dropped
//! by the grid where a write changes which cells are obstacles; with the look-ups the
//! matchers use (cell, bilinear, bicubic, dense windows).

use super::field::{compute_region, margin_cells_clamped, FieldTile};
use super::params::LikelihoodParams;
use crate::cell::CellIndex;
use crate::error::GridError;
use crate::grid::tiles::{self, split, TILE_CELLS, TILE_SIZE};
use crate::grid::{CachedTile, ObstacleRule, OccupancyGrid, TileCache};
use slam_models::Point2;
use std::sync::{Arc, OnceLock};

/// The lazy field's parameters and its far tile (the field far from every obstacle).
struct LazyState {
    params: LikelihoodParams,
    far: Arc<FieldTile>,
}

impl LazyState {
    fn new(params: LikelihoodParams) -> Self {
        Self {
            far: Arc::new(FieldTile::far(&params)),
            params,
        }
    }
}

/// The state of grids that never set their parameters.
fn default_state() -> &'static LazyState {
    static DEFAULT: OnceLock<LazyState> = OnceLock::new();
    DEFAULT.get_or_init(|| LazyState::new(LikelihoodParams::default()))
}

/// A field cache of `n` empty cells.
fn empty_field_cache(n: usize) -> TileCache {
    (0..n).map(|_| OnceLock::new()).collect()
}

impl OccupancyGrid {
    /// The lazy field's state: set by [`OccupancyGrid::with_likelihood`], else the
    /// defaults.
    #[inline]
    fn lazy_state(&self) -> &LazyState {
        self.field_state
            .as_ref()
            .and_then(|s| s.downcast_ref::<LazyState>())
            .unwrap_or_else(|| default_state())
    }

    /// This grid with its likelihood-field parameters replaced (cached fields dropped).
    pub fn with_likelihood(mut self, params: LikelihoodParams) -> Result<Self, GridError> {
        params.validate()?;
        self.params = ObstacleRule {
            occupied_threshold: params.occupied_threshold,
            subcell: params.subcell,
        };
        self.field_state = Some(Arc::new(LazyState::new(params)));
        self.fields = OnceLock::new();
        // The obstacle threshold may have changed: rebuild the incremental field.
        if let Some(d) = self.distance.take() {
            return self.with_incremental_distance(d.radius() as u32);
        }
        Ok(self)
    }

    /// Drops the cached likelihood-field tiles (8 bytes a cell): the next reads compute
    /// them again, to the same values. For a grid kept for rare reads after one wide
    /// read (e.g. a pyramid built from it).
    pub fn drop_field_cache(&mut self) {
        self.fields = OnceLock::new();
    }

    /// The likelihood-field parameters.
    pub fn likelihood_params(&self) -> LikelihoodParams {
        self.lazy_state().params
    }

    /// The cached field tile of a slot, computed on first use.
    #[inline]
    fn field_tile(&self, slot: usize) -> &FieldTile {
        let fields = self
            .fields
            .get_or_init(|| empty_field_cache(self.table.len()));
        let state = self.lazy_state();
        let entry = fields[slot].get_or_init(|| -> CachedTile {
            let (tx, ty) = self.table.tile_of_slot(slot);
            let t = TILE_SIZE as i32;
            let margin = margin_cells_clamped(&state.params, self.resolution());
            match compute_region(
                self,
                CellIndex::new(tx * t, ty * t),
                TILE_SIZE,
                TILE_SIZE,
                margin,
            ) {
                None => state.far.clone(),
                Some((v, d2)) => {
                    let mut values = [0.0f32; TILE_CELLS];
                    values.copy_from_slice(&v);
                    let mut dist2 = [0.0f32; TILE_CELLS];
                    dist2.copy_from_slice(&d2);
                    Arc::new(FieldTile { values, dist2 })
                }
            }
        });
        // Only this module fills the cache, always with field tiles.
        entry.downcast_ref::<FieldTile>().unwrap_or(&state.far)
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
            None => self.lazy_state().far.values[0],
        }
    }

    /// Bilinear interpolation of the likelihood field at world point `p` between the four
    /// surrounding cell centres (Hector SLAM, Kohlbrecher et al. 2011, eq. 5–6), with its
    /// gradient in the world frame (per metre).
    #[inline]
    pub fn likelihood_interpolated(&self, p: &Point2) -> (f64, [f64; 2]) {
        let (u, v) = self.frame().world_to_continuous(p);
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
        let inv = 1.0 / self.frame().resolution;
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
                None => &self.lazy_state().far,
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
            None => self.lazy_state().far.dist2[0],
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
        self.likelihood_bicubic_sigma(p, self.lazy_state().params.sigma)
    }

    /// [`OccupancyGrid::likelihood_bicubic`] with a σ of the caller's choice (metres, > 0)
    /// in M = exp(−D/(2σ²)): the squared distances do not depend on σ, so a refinement can
    /// use a narrower Gaussian than the field's own.
    #[inline]
    pub fn likelihood_bicubic_sigma(&self, p: &Point2, sigma: f64) -> (f64, [f64; 2]) {
        let (u, v) = self.frame().world_to_continuous(p);
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
        let inv = 1.0 / self.frame().resolution;
        let k = -0.5 / (sigma * sigma);
        let m = (k * val.max(0.0)).exp();
        (m, [m * k * du * inv, m * k * dv * inv])
    }

    /// Copies the likelihood-field values of the `w × h` cells starting at `min` into a
    /// row-major buffer
    /// (tile by tile; cells outside the table get the far value).
    pub fn field_window(&self, min: CellIndex, w: usize, h: usize) -> Vec<f32> {
        let mut out = vec![0.0; w * h];
        self.field_window_into(min, w, &mut out);
        out
    }

    /// [`OccupancyGrid::field_window`] into `out`, every element of it written: the
    /// `out.len() / w` rows of `w` cells from `min`.
    pub(crate) fn field_window_into(&self, min: CellIndex, w: usize, out: &mut [f32]) {
        self.field_window_tiles_into(min, w, out, |_, _| true);
    }

    /// [`OccupancyGrid::field_window_into`] over the tiles (tx, ty) (cell x >> TILE_BITS,
    /// y >> TILE_BITS) for which `wanted` is true; the cells of the other tiles get the far
    /// value, and those tiles' fields are neither read nor computed.
    pub(crate) fn field_window_tiles_into(
        &self,
        min: CellIndex,
        w: usize,
        out: &mut [f32],
        wanted: impl Fn(i32, i32) -> bool,
    ) {
        let far = self.lazy_state().far.values[0];
        out.fill(far);
        if w == 0 || out.len() < w {
            return;
        }
        let h = out.len() / w;
        let t = TILE_SIZE as i32;
        let max_x = min.x + w as i32 - 1;
        let max_y = min.y + h as i32 - 1;
        for ty in (min.y >> tiles::TILE_BITS)..=(max_y >> tiles::TILE_BITS) {
            for tx in (min.x >> tiles::TILE_BITS)..=(max_x >> tiles::TILE_BITS) {
                let Some(slot) = self.table.slot(tx, ty).filter(|_| wanted(tx, ty)) else {
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
    }
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
mod tests {
    use super::*;
    use crate::InverseSensorModel;

    /// A new grid's obstacle rule is the default parameters' (the grid cannot read them
    /// itself), and `with_likelihood` carries a changed rule over.
    #[test]
    fn the_grid_obstacle_rule_follows_the_likelihood_parameters() {
        let p = LikelihoodParams::default();
        let g = OccupancyGrid::new(0.05, InverseSensorModel::default());
        assert_eq!(g.params.occupied_threshold, p.occupied_threshold);
        assert_eq!(g.params.subcell, p.subcell);
        assert_eq!(g.likelihood_params(), p);
        let q = LikelihoodParams {
            occupied_threshold: 0.7,
            subcell: false,
            sigma: 0.1,
            ..p
        };
        let g = g.with_likelihood(q).unwrap();
        assert_eq!(g.params.occupied_threshold, 0.7);
        assert!(!g.params.subcell);
        assert_eq!(g.likelihood_params(), q);
        // Far from every obstacle the field reads the new parameters' far value.
        assert_eq!(g.likelihood(CellIndex::new(1000, 1000)), q.far_value());
    }

    /// A window over wanted tiles only: those tiles' cells equal the full window's (the
    /// field computed as on any read), every other cell is the far value, and a fresh
    /// grid has computed no field tile outside the wanted ones.
    #[test]
    fn a_window_over_some_tiles_reads_those_and_the_far_value_elsewhere() {
        let g = crate::testutil::office_map(0.05);
        let (lo, hi) = g.covered_cells().unwrap();
        let min = CellIndex::new(lo.x - 5, lo.y - 3);
        let (w, h) = ((hi.x - min.x + 7) as usize, (hi.y - min.y + 2) as usize);
        let full = g.field_window(min, w, h);
        let far = g.likelihood_params().far_value();
        let wanted = |tx: i32, ty: i32| (tx + 2 * ty) % 3 == 0;
        let fresh = crate::testutil::office_map(0.05);
        let mut part = vec![0.0f32; w * h];
        fresh.field_window_tiles_into(min, w, &mut part, wanted);
        let bits = tiles::TILE_BITS;
        let (mut kept, mut far_cells) = (0, 0);
        for y in 0..h {
            for x in 0..w {
                let c = CellIndex::new(min.x + x as i32, min.y + y as i32);
                let (k, v) = (y * w + x, part[y * w + x]);
                if wanted(c.x >> bits, c.y >> bits) {
                    assert_eq!(v.to_bits(), full[k].to_bits(), "wanted cell {c:?}");
                    kept += (v != far) as usize;
                } else {
                    assert_eq!(v, far, "unwanted cell {c:?}");
                    far_cells += (full[k] != far) as usize;
                }
            }
        }
        assert!(
            kept > 100 && far_cells > 100,
            "{kept} near cells kept, {far_cells} left far"
        );
        let computed = fresh
            .fields
            .get()
            .map_or(0, |f| f.iter().filter(|t| t.get().is_some()).count());
        let wanted_slots = (0..fresh.table.len())
            .filter(|&s| {
                let (tx, ty) = fresh.table.tile_of_slot(s);
                wanted(tx, ty)
            })
            .count();
        assert!(
            computed > 0 && computed <= wanted_slots,
            "{computed} tiles computed, {wanted_slots} wanted"
        );
    }
}
