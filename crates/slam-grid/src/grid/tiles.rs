//! Fixed-size square tiles and the dense tile table of a grid.
//!
//! A grid is a rectangle of tile slots; each slot holds `None` (never written: every cell
//! unknown) or an `Arc<Tile>`. Cloning a grid clones the table of `Arc`s, never the cells;
//! writing a tile that another grid shares copies that one tile first (copy-on-write).

use crate::cell::CellIndex;

/// log₂ of the tile edge, in cells.
pub const TILE_BITS: u32 = 5;
/// Tile edge length in cells (32: 4 KiB of `f32` log-odds per tile, like GMapping's
/// 32×32 patches).
pub const TILE_SIZE: usize = 1 << TILE_BITS;
/// Cells per tile.
pub const TILE_CELLS: usize = TILE_SIZE * TILE_SIZE;
const TILE_MASK: i32 = (TILE_SIZE as i32) - 1;

/// Hits after which a cell's mean hit position is frozen (so re-observing a mapped wall
/// leaves a shared tile shared).
pub(crate) const HIT_CAP: u8 = 16;

/// One tile, row-major (index = ly·TILE_SIZE + lx): log-odds values, and, for grids whose
/// likelihood field measures to sub-cell hit positions, the hit statistics of its cells.
#[derive(Clone)]
pub(crate) struct Tile {
    pub(crate) cells: [f32; TILE_CELLS],
    pub(crate) hit: Option<Box<HitStats>>,
}

/// Per cell the mean position of the beam end points that hit it (GMapping keeps the same
/// statistic), as an offset from the cell centre in 1/256 cell, with the number of hits
/// averaged (≤ [`HIT_CAP`]).
#[derive(Clone)]
pub(crate) struct HitStats {
    pub(crate) hit_x: [i8; TILE_CELLS],
    pub(crate) hit_y: [i8; TILE_CELLS],
    pub(crate) hits: [u8; TILE_CELLS],
}

/// Bytes of a tile's data with hit statistics (log-odds + mean hit positions + counts).
pub(crate) const TILE_BYTES_WITH_HITS: usize =
    std::mem::size_of::<[f32; TILE_CELLS]>() + std::mem::size_of::<HitStats>();

impl Tile {
    /// An all-unknown tile (log-odds 0, no hits), with hit statistics when `with_hits`.
    pub(crate) fn unknown(with_hits: bool) -> Self {
        Self {
            cells: [0.0; TILE_CELLS],
            hit: with_hits.then(|| {
                Box::new(HitStats {
                    hit_x: [0; TILE_CELLS],
                    hit_y: [0; TILE_CELLS],
                    hits: [0; TILE_CELLS],
                })
            }),
        }
    }

    /// Bytes of this tile's data.
    pub(crate) fn bytes(&self) -> usize {
        if self.hit.is_some() {
            TILE_BYTES_WITH_HITS
        } else {
            std::mem::size_of::<[f32; TILE_CELLS]>()
        }
    }
}

/// Tile coordinates of a cell and the cell's index inside its tile.
#[inline]
pub(crate) fn split(c: CellIndex) -> ((i32, i32), usize) {
    let t = (c.x >> TILE_BITS, c.y >> TILE_BITS);
    let local = ((c.y & TILE_MASK) as usize) * TILE_SIZE + (c.x & TILE_MASK) as usize;
    (t, local)
}

/// The rectangle of tile coordinates a grid currently covers: tiles
/// [tx0, tx0 + tw) × [ty0, ty0 + th), stored row-major.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct TileLayout {
    pub(crate) tx0: i32,
    pub(crate) ty0: i32,
    pub(crate) tw: i32,
    pub(crate) th: i32,
}

impl TileLayout {
    /// The slot of tile (tx, ty), if covered.
    #[inline]
    pub(crate) fn slot(&self, tx: i32, ty: i32) -> Option<usize> {
        let i = tx.wrapping_sub(self.tx0);
        let j = ty.wrapping_sub(self.ty0);
        if i < 0 || j < 0 || i >= self.tw || j >= self.th {
            None
        } else {
            Some((j * self.tw + i) as usize)
        }
    }

    /// Tile coordinates of a slot.
    #[inline]
    pub(crate) fn tile_of_slot(&self, slot: usize) -> (i32, i32) {
        let s = slot as i32;
        (self.tx0 + s % self.tw, self.ty0 + s / self.tw)
    }

    /// Number of slots.
    #[inline]
    pub(crate) fn len(&self) -> usize {
        (self.tw.max(0) as usize) * (self.th.max(0) as usize)
    }

    /// True when tile (tx, ty) is covered.
    #[inline]
    pub(crate) fn contains(&self, tx: i32, ty: i32) -> bool {
        self.slot(tx, ty).is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_handles_negative_cells() {
        assert_eq!(split(CellIndex::new(0, 0)), ((0, 0), 0));
        assert_eq!(split(CellIndex::new(-1, 0)), ((-1, 0), TILE_SIZE - 1));
        assert_eq!(
            split(CellIndex::new(33, -33)),
            ((1, -2), (TILE_SIZE - 1) * TILE_SIZE + 1)
        );
        let l = TileLayout {
            tx0: -2,
            ty0: 3,
            tw: 4,
            th: 2,
        };
        assert_eq!(l.slot(-2, 3), Some(0));
        assert_eq!(l.slot(1, 4), Some(7));
        assert_eq!(l.slot(2, 4), None);
        assert_eq!(l.tile_of_slot(7), (1, 4));
    }
}
