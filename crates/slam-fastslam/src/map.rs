//! A particle's landmark map: the landmarks in a [`PersistentMap`] keyed by landmark key, and
//! a spatial index (a second persistent map from grid cells to the keys filed there) so that
//! "which landmarks are near this point" costs O(k·log N) for k nearby landmarks instead of
//! O(N). Both halves share structure between particles, so copying a map is O(1).

use crate::landmark::Landmark;
use crate::tree::PersistentMap;
use slam_models::Point2;
use std::sync::Arc;

/// The map of one particle.
#[derive(Clone, Debug)]
pub struct LandmarkMap {
    landmarks: PersistentMap<Landmark>,
    /// Cell key → keys of the landmarks filed in that cell.
    cells: PersistentMap<Arc<Vec<u32>>>,
    /// Edge of a spatial-index cell, metres.
    cell_size: f64,
    /// Next key to hand out to a landmark created without a known id.
    next_key: u32,
}

/// Interleaves the bits of two 16-bit values (Morton / Z-order), so cells near the origin
/// get small keys and the cell tree stays shallow.
fn morton(a: u32, b: u32) -> u32 {
    fn spread(mut v: u32) -> u32 {
        v &= 0xFFFF;
        v = (v | (v << 8)) & 0x00FF_00FF;
        v = (v | (v << 4)) & 0x0F0F_0F0F;
        v = (v | (v << 2)) & 0x3333_3333;
        v = (v | (v << 1)) & 0x5555_5555;
        v
    }
    spread(a) | (spread(b) << 1)
}

/// Zig-zag: 0, −1, 1, −2, … → 0, 1, 2, 3, …
fn zigzag(v: i64) -> u32 {
    (((v << 1) ^ (v >> 63)) & 0xFFFF_FFFF) as u32
}

impl LandmarkMap {
    /// An empty map whose spatial index uses square cells of `cell_size` metres (> 0).
    pub fn new(cell_size: f64) -> Self {
        Self {
            landmarks: PersistentMap::new(),
            cells: PersistentMap::new(),
            cell_size,
            next_key: 0,
        }
    }

    /// Number of landmarks.
    pub fn len(&self) -> usize {
        self.landmarks.len()
    }

    /// True when the map holds no landmark.
    pub fn is_empty(&self) -> bool {
        self.landmarks.is_empty()
    }

    /// The landmark under `key`.
    pub fn get(&self, key: u32) -> Option<&Landmark> {
        self.landmarks.get(key)
    }

    /// All landmarks in key order.
    pub fn iter(&self) -> impl Iterator<Item = (u32, &Landmark)> {
        self.landmarks.iter()
    }

    /// The landmark tree itself (for structure-sharing diagnostics).
    pub fn tree(&self) -> &PersistentMap<Landmark> {
        &self.landmarks
    }

    /// Integer cell coordinates of a point. Coordinates are clamped to ±2¹⁵ cells; the cell
    /// key wraps beyond that, which only adds far-away candidates to a query (every query
    /// re-checks true distances).
    fn cell_coords(&self, p: &Point2) -> (i64, i64) {
        let f = |v: f64| (v / self.cell_size).floor().clamp(-32768.0, 32767.0) as i64;
        (f(p.x), f(p.y))
    }

    fn cell_key(cx: i64, cy: i64) -> u32 {
        morton(zigzag(cx), zigzag(cy))
    }

    fn file(&mut self, cell: u32, key: u32) {
        match self.cells.get_mut(cell) {
            Some(list) => Arc::make_mut(list).push(key),
            None => {
                self.cells.insert(cell, Arc::new(vec![key]));
            }
        }
    }

    fn unfile(&mut self, cell: u32, key: u32) {
        let empty = match self.cells.get_mut(cell) {
            Some(list) => {
                let l = Arc::make_mut(list);
                l.retain(|&k| k != key);
                l.is_empty()
            }
            None => false,
        };
        if empty {
            self.cells.remove(cell);
        }
    }

    /// A key no landmark uses, for a landmark created without a known id.
    pub fn fresh_key(&mut self) -> u32 {
        while self.landmarks.contains_key(self.next_key) {
            self.next_key = self.next_key.wrapping_add(1);
        }
        let k = self.next_key;
        self.next_key = self.next_key.wrapping_add(1);
        k
    }

    /// Inserts (or replaces) the landmark under `key` and files it in the spatial index.
    pub fn insert(&mut self, key: u32, mut lm: Landmark) {
        if let Some(old) = self.landmarks.get(key) {
            let c = old.cell;
            self.unfile(c, key);
        }
        let (cx, cy) = self.cell_coords(&lm.mean);
        lm.cell = Self::cell_key(cx, cy);
        self.file(lm.cell, key);
        self.landmarks.insert(key, lm);
    }

    /// Applies `f` to the landmark under `key` (copying only its path if shared) and
    /// re-files it if its mean moved to another cell. Returns `f`'s result, or `None` when
    /// the key is absent.
    pub fn update<R>(&mut self, key: u32, f: impl FnOnce(&mut Landmark) -> R) -> Option<R> {
        let lm = self.landmarks.get_mut(key)?;
        let r = f(lm);
        let old_cell = lm.cell;
        let mean = lm.mean;
        let (cx, cy) = self.cell_coords(&mean);
        let new_cell = Self::cell_key(cx, cy);
        if new_cell != old_cell {
            if let Some(lm) = self.landmarks.get_mut(key) {
                lm.cell = new_cell;
            }
            self.unfile(old_cell, key);
            self.file(new_cell, key);
        }
        Some(r)
    }

    /// Removes the landmark under `key`.
    pub fn remove(&mut self, key: u32) -> Option<Landmark> {
        let lm = self.landmarks.remove(key)?;
        self.unfile(lm.cell, key);
        Some(*lm)
    }

    /// Calls `f(key, landmark)` for every landmark whose mean lies within `radius` metres of
    /// `center` (keys in cell order, then filing order: deterministic).
    pub fn for_each_near(&self, center: &Point2, radius: f64, mut f: impl FnMut(u32, &Landmark)) {
        if self.landmarks.is_empty() {
            return;
        }
        let r2 = radius * radius;
        // A radius spanning more cells than there are landmarks: a linear scan is cheaper.
        let span = (2.0 * radius / self.cell_size).ceil() + 1.0;
        if !span.is_finite() || span * span > 4.0 * self.landmarks.len() as f64 + 16.0 {
            for (k, lm) in self.landmarks.iter() {
                if (lm.mean - center).norm_squared() <= r2 {
                    f(k, lm);
                }
            }
            return;
        }
        let lo = self.cell_coords(&Point2::new(center.x - radius, center.y - radius));
        let hi = self.cell_coords(&Point2::new(center.x + radius, center.y + radius));
        for cx in lo.0..=hi.0 {
            for cy in lo.1..=hi.1 {
                let Some(list) = self.cells.get(Self::cell_key(cx, cy)) else {
                    continue;
                };
                for &k in list.iter() {
                    if let Some(lm) = self.landmarks.get(k) {
                        // Wrapped cell keys can alias far cells; check the true cell too.
                        if lm.cell == Self::cell_key(cx, cy)
                            && (lm.mean - center).norm_squared() <= r2
                        {
                            f(k, lm);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::{LandmarkId, Matrix2};

    fn lm(x: f64, y: f64) -> Landmark {
        Landmark {
            id: LandmarkId(0),
            mean: Point2::new(x, y),
            cov: Matrix2::identity(),
            existence: 1,
            observations: 1,
            cell: 0,
        }
    }

    #[test]
    fn near_query_matches_brute_force() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
        let mut m = LandmarkMap::new(3.0);
        let mut pts = Vec::new();
        for k in 0..2000u32 {
            let p = (rng.random_range(-60.0..60.0), rng.random_range(-60.0..60.0));
            m.insert(k, lm(p.0, p.1));
            pts.push(p);
        }
        // Move some landmarks across cells through `update`, remove others.
        for k in (0..2000u32).step_by(7) {
            m.update(k, |l| l.mean.x += 4.0);
            pts[k as usize].0 += 4.0;
        }
        for k in (0..2000u32).step_by(11) {
            m.remove(k);
        }
        for _ in 0..50 {
            let c = Point2::new(rng.random_range(-70.0..70.0), rng.random_range(-70.0..70.0));
            let r = rng.random_range(0.5..12.0);
            let mut got = Vec::new();
            m.for_each_near(&c, r, |k, _| got.push(k));
            got.sort_unstable();
            let want: Vec<u32> = (0..2000u32)
                .filter(|k| k % 11 != 0)
                .filter(|&k| {
                    let p = pts[k as usize];
                    (p.0 - c.x).powi(2) + (p.1 - c.y).powi(2) <= r * r
                })
                .collect();
            assert_eq!(got, want);
        }
    }

    #[test]
    fn fresh_keys_skip_used_ones() {
        let mut m = LandmarkMap::new(5.0);
        m.insert(0, lm(0.0, 0.0));
        m.insert(2, lm(1.0, 0.0));
        let a = m.fresh_key();
        m.insert(a, lm(2.0, 0.0));
        let b = m.fresh_key();
        assert_eq!((a, b), (1, 3));
    }
}
