//! Fixed-size square tiles and the sparse tile table of a grid.
//!
//! A grid covers a rectangle of tiles ([`TileLayout`], four integers: what the grid has
//! been asked to cover), but stores only the tiles that hold data and their eight
//! neighbours ([`TileIndex`]: tile coordinates → slot), so that its memory grows with the
//! area actually observed, never with the bounding box of scans far apart (a glitched
//! pose 10 km away costs the tiles that scan touches, not the 10 km between).
//! Each slot holds `None` (never written: every cell unknown) or an `Arc<Tile>`. Cloning a
//! grid clones the table of `Arc`s, never the cells; writing a tile that another grid
//! shares copies that one tile first (copy-on-write).

use crate::cell::CellIndex;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

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

/// One tile, row-major (index = ly·TILE_SIZE + lx): log-odds values, a bit per cell that
/// marks cells at the lower clamp, and, for grids whose likelihood field measures to
/// sub-cell hit positions, the hit statistics of its cells.
#[derive(Clone)]
pub(crate) struct Tile {
    pub(crate) cells: [f32; TILE_CELLS],
    /// Bit `l` set ⇒ `cells[l]` equals the grid's `l_min`: a free-space update (a negative
    /// log-odds step) cannot change such a cell, so integration skips it after reading
    /// 1 bit instead of 4 bytes (most cells a scan crosses are free and saturated, and the
    /// 4 KiB of log-odds of 30 particles' tiles do not stay in cache). A clear bit says
    /// nothing: the bit is set when a write stores `l_min` and cleared by any other write.
    pub(crate) floor: [u64; TILE_CELLS / 64],
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

/// Bytes of a tile's log-odds and lower-clamp bits.
pub(crate) const TILE_BYTES_LOG_ODDS: usize =
    std::mem::size_of::<[f32; TILE_CELLS]>() + std::mem::size_of::<[u64; TILE_CELLS / 64]>();

/// Bytes of a tile's data with hit statistics (log-odds and their lower-clamp bits + mean
/// hit positions + counts).
pub(crate) const TILE_BYTES_WITH_HITS: usize =
    TILE_BYTES_LOG_ODDS + std::mem::size_of::<HitStats>();

impl Tile {
    /// An all-unknown tile (log-odds 0, no floor bits, no hits), with hit statistics when
    /// `with_hits`.
    pub(crate) fn unknown(with_hits: bool) -> Self {
        Self {
            cells: [0.0; TILE_CELLS],
            floor: [0; TILE_CELLS / 64],
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
            TILE_BYTES_LOG_ODDS
        }
    }
}

impl Tile {
    /// Whether `cells[l]` is known to be at the lower clamp.
    #[inline(always)]
    pub(crate) fn at_floor(&self, l: usize) -> bool {
        (self.floor[l >> 6] >> (l & 63)) & 1 == 1
    }

    /// Stores `v` in cell `l` and keeps its floor bit (`v == l_min`).
    #[inline(always)]
    pub(crate) fn set(&mut self, l: usize, v: f32, l_min: f32) {
        self.cells[l] = v;
        let bit = 1u64 << (l & 63);
        if v == l_min {
            self.floor[l >> 6] |= bit;
        } else {
            self.floor[l >> 6] &= !bit;
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

/// A rectangle of tile coordinates, tiles [tx0, tx0 + tw) × [ty0, ty0 + th), with its
/// slots numbered row-major (the area a grid covers, and the tiles one scan touches).
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

/// The hash of a tile key: one multiply-xorshift round (splitmix64's finaliser), cheap
/// enough for a look-up per beam end point and mixing both coordinates into the low bits
/// (the bucket) and the high bits (the control byte).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct TileHasher(u64);

impl Hasher for TileHasher {
    #[inline]
    fn finish(&self) -> u64 {
        self.0
    }

    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(self.0 ^ b as u64);
        }
    }

    #[inline]
    fn write_u64(&mut self, x: u64) {
        self.0 = slam_models::rng::splitmix64(x ^ self.0);
    }
}

/// The key of tile (tx, ty).
#[inline]
fn key(tx: i32, ty: i32) -> u64 {
    ((ty as u32 as u64) << 32) | tx as u32 as u64
}

/// The sparse slot table: tile coordinates → slot, slots numbered 0, 1, … in the order the
/// tiles were first stored. Slots are never removed, so a slot number stays valid for the
/// grid's life (the per-slot tables beside it — tiles, cached fields, distance tiles —
/// only grow by pushing).
#[derive(Debug, Clone, Default)]
pub(crate) struct TileIndex {
    slots: HashMap<u64, u32, BuildHasherDefault<TileHasher>>,
    coords: Vec<(i32, i32)>,
}

impl TileIndex {
    /// The slot of tile (tx, ty), if stored.
    #[inline]
    pub(crate) fn get(&self, tx: i32, ty: i32) -> Option<usize> {
        self.slots.get(&key(tx, ty)).map(|&s| s as usize)
    }

    /// Tile coordinates of a slot.
    #[inline]
    pub(crate) fn tile_of_slot(&self, slot: usize) -> (i32, i32) {
        self.coords[slot]
    }

    /// Number of slots.
    #[inline]
    pub(crate) fn len(&self) -> usize {
        self.coords.len()
    }

    /// The slot of tile (tx, ty), and whether it was added now.
    pub(crate) fn insert(&mut self, tx: i32, ty: i32) -> (usize, bool) {
        let next = self.coords.len() as u32;
        let s = *self.slots.entry(key(tx, ty)).or_insert(next);
        if s == next {
            self.coords.push((tx, ty));
        }
        (s as usize, s == next)
    }
}

/// Largest covered rectangle, in tiles, for which a grid keeps a dense table of slot
/// numbers beside its sparse index (2¹⁶ tiles: 256 KiB, a square of 8192 cells, 410 m at
/// 5 cm). Such a table makes each look-up one array read, which the matchers' per-beam
/// look-ups need; beyond it (scans kilometres apart) look-ups go through the hash index,
/// so memory never grows with the covered area itself.
pub(crate) const DENSE_TABLE_MAX_TILES: usize = 1 << 16;

/// The covered rectangle and the stored tiles in it.
#[derive(Debug, Clone, Default)]
pub(crate) struct TileTable {
    /// The rectangle of tiles the grid covers (cells beyond it read as unknown and far
    /// from any obstacle).
    rect: TileLayout,
    /// The tiles stored (those with data and their neighbours; a few just outside `rect`).
    index: TileIndex,
    /// Row-major over `rect`, the slot of each covered tile (`u32::MAX`: not stored), while
    /// `rect` has at most [`DENSE_TABLE_MAX_TILES`] tiles.
    dense: Option<Vec<u32>>,
}

impl TileTable {
    /// The inclusive range of cells the covered rectangle spans (`None` while empty).
    pub(crate) fn covered_cells(&self) -> Option<(CellIndex, CellIndex)> {
        let r = self.rect;
        if r.len() == 0 {
            return None;
        }
        let t = TILE_SIZE as i32;
        Some((
            CellIndex::new(r.tx0 * t, r.ty0 * t),
            CellIndex::new((r.tx0 + r.tw) * t - 1, (r.ty0 + r.th) * t - 1),
        ))
    }

    /// The covered rectangle.
    #[inline]
    pub(crate) fn rect(&self) -> TileLayout {
        self.rect
    }

    /// The slot of tile (tx, ty) when it is covered and stored. Inlined into the
    /// matchers' per-beam loops: the dense table is one array read; the hash look-up is
    /// kept out of line so that it does not stop the inlining.
    #[inline(always)]
    pub(crate) fn slot(&self, tx: i32, ty: i32) -> Option<usize> {
        let s = self.rect.slot(tx, ty)?;
        match &self.dense {
            Some(d) => {
                let v = d[s];
                (v != u32::MAX).then_some(v as usize)
            }
            None => self.sparse_slot(tx, ty),
        }
    }

    /// [`TileTable::slot`] through the hash index (maps too large for the dense table).
    #[inline(never)]
    fn sparse_slot(&self, tx: i32, ty: i32) -> Option<usize> {
        self.index.get(tx, ty)
    }

    /// Tile coordinates of a slot.
    #[inline]
    pub(crate) fn tile_of_slot(&self, slot: usize) -> (i32, i32) {
        self.index.tile_of_slot(slot)
    }

    /// Number of slots.
    #[inline]
    pub(crate) fn len(&self) -> usize {
        self.index.len()
    }

    /// The slot of tile (tx, ty), covered or not, and whether it was added now.
    pub(crate) fn insert(&mut self, tx: i32, ty: i32) -> (usize, bool) {
        let (s, added) = self.index.insert(tx, ty);
        if added {
            if let (Some(d), Some(r)) = (&mut self.dense, self.rect.slot(tx, ty)) {
                d[r] = s as u32;
            }
        }
        (s, added)
    }

    /// Replaces the covered rectangle (rebuilding the dense table, or dropping it when
    /// the rectangle is too large for one).
    pub(crate) fn set_rect(&mut self, rect: TileLayout) {
        self.rect = rect;
        self.dense = (rect.len() <= DENSE_TABLE_MAX_TILES).then(|| {
            let mut d = vec![u32::MAX; rect.len()];
            for (s, &(tx, ty)) in self.index.coords.iter().enumerate() {
                if let Some(r) = rect.slot(tx, ty) {
                    d[r] = s as u32;
                }
            }
            d
        });
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

    #[test]
    fn tile_index_keeps_slots_and_separates_signs() {
        let mut ix = TileIndex::default();
        assert_eq!(ix.insert(-1, 0), (0, true));
        assert_eq!(ix.insert(0, -1), (1, true));
        assert_eq!(ix.insert(-1, 0), (0, false));
        assert_eq!(ix.insert(i32::MIN, i32::MAX), (2, true));
        assert_eq!(ix.get(0, -1), Some(1));
        assert_eq!(ix.get(-1, -1), None);
        assert_eq!(ix.tile_of_slot(2), (i32::MIN, i32::MAX));
        assert_eq!(ix.len(), 3);
    }
}
