//! A map of point landmarks with a spatial hash.

use crate::error::SimError;
use slam_models::{LandmarkId, Point2};

/// Point landmarks (world frame, metres) with a uniform-grid index, so that "which landmarks
/// are within r of p" costs O(landmarks near p), independent of the world's size.
///
/// # Example
///
/// ```
/// use slam_models::{LandmarkId, Point2};
/// use slam_sim::landmark::LandmarkWorld;
/// let w = LandmarkWorld::new(
///     vec![(LandmarkId(0), Point2::new(1.0, 0.0)), (LandmarkId(1), Point2::new(50.0, 0.0))],
///     6.0,
/// )
/// .unwrap();
/// let mut near = Vec::new();
/// w.within(&Point2::new(0.0, 0.0), 6.0, &mut near);
/// assert_eq!(near, vec![0]);
/// ```
#[derive(Debug, Clone)]
pub struct LandmarkWorld {
    landmarks: Vec<(LandmarkId, Point2)>,
    /// Grid origin (lower-left corner of cell (0, 0)).
    origin: Point2,
    cell: f64,
    nx: usize,
    ny: usize,
    /// CSR layout: landmarks of cell k are `items[starts[k]..starts[k+1]]` (indices into
    /// `landmarks`, ascending).
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl LandmarkWorld {
    /// Builds the index with cells of `cell` metres (choose about the sensor's max range).
    /// Landmark positions must be finite; ids should be unique (not checked).
    pub fn new(landmarks: Vec<(LandmarkId, Point2)>, cell: f64) -> Result<Self, SimError> {
        if !(cell.is_finite() && cell > 0.0) {
            return Err(SimError::InvalidParameter {
                name: "cell",
                value: cell.to_string(),
                expected: "a positive finite cell size",
            });
        }
        if landmarks.len() >= u32::MAX as usize {
            return Err(SimError::InvalidWorld("too many landmarks".into()));
        }
        let (mut lo, mut hi) = (Point2::new(0.0, 0.0), Point2::new(0.0, 0.0));
        for (i, (id, p)) in landmarks.iter().enumerate() {
            if !(p.x.is_finite() && p.y.is_finite()) {
                return Err(SimError::InvalidWorld(format!(
                    "landmark {id} has a non-finite position ({}, {})",
                    p.x, p.y
                )));
            }
            if i == 0 {
                (lo, hi) = (*p, *p);
            }
            lo = Point2::new(lo.x.min(p.x), lo.y.min(p.y));
            hi = Point2::new(hi.x.max(p.x), hi.y.max(p.y));
        }
        let nx = (((hi.x - lo.x) / cell).floor() as usize + 1).min(1 << 20);
        let ny = (((hi.y - lo.y) / cell).floor() as usize + 1).min(1 << 20);
        let ncell = nx
            .checked_mul(ny)
            .filter(|&n| n <= 1 << 26)
            .ok_or_else(|| {
                SimError::InvalidWorld("landmark world too large for its cell size".into())
            })?;
        let key = |p: &Point2| -> usize {
            let ix = (((p.x - lo.x) / cell) as usize).min(nx - 1);
            let iy = (((p.y - lo.y) / cell) as usize).min(ny - 1);
            iy * nx + ix
        };
        let mut counts = vec![0u32; ncell + 1];
        for (_, p) in &landmarks {
            counts[key(p) + 1] += 1;
        }
        for k in 0..ncell {
            counts[k + 1] += counts[k];
        }
        let starts = counts.clone();
        let mut fill = counts;
        let mut items = vec![0u32; landmarks.len()];
        for (i, (_, p)) in landmarks.iter().enumerate() {
            let k = key(p);
            items[fill[k] as usize] = i as u32;
            fill[k] += 1;
        }
        Ok(Self {
            landmarks,
            origin: lo,
            cell,
            nx,
            ny,
            starts,
            items,
        })
    }

    /// All landmarks, in the order given.
    pub fn landmarks(&self) -> &[(LandmarkId, Point2)] {
        &self.landmarks
    }

    /// Number of landmarks.
    pub fn len(&self) -> usize {
        self.landmarks.len()
    }

    /// True when there are no landmarks.
    pub fn is_empty(&self) -> bool {
        self.landmarks.is_empty()
    }

    /// Indices (into [`LandmarkWorld::landmarks`]) of the landmarks within `radius` of `c`,
    /// ascending, written into `out` (cleared first).
    pub fn within(&self, c: &Point2, radius: f64, out: &mut Vec<usize>) {
        out.clear();
        if self.landmarks.is_empty() || radius.is_nan() || radius < 0.0 {
            return;
        }
        let r2 = radius * radius;
        let cell_range = |v: f64, o: f64, n: usize| -> Option<(usize, usize)> {
            let a = ((v - radius - o) / self.cell).floor();
            let b = ((v + radius - o) / self.cell).floor();
            if b < 0.0 || a > (n - 1) as f64 || !a.is_finite() || !b.is_finite() {
                return None;
            }
            Some((a.max(0.0) as usize, (b as usize).min(n - 1)))
        };
        let (Some((x0, x1)), Some((y0, y1))) = (
            cell_range(c.x, self.origin.x, self.nx),
            cell_range(c.y, self.origin.y, self.ny),
        ) else {
            return;
        };
        for iy in y0..=y1 {
            for ix in x0..=x1 {
                let k = iy * self.nx + ix;
                for &i in &self.items[self.starts[k] as usize..self.starts[k + 1] as usize] {
                    let p = self.landmarks[i as usize].1;
                    if (p - c).norm_squared() <= r2 {
                        out.push(i as usize);
                    }
                }
            }
        }
        out.sort_unstable();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::stream;
    use rand::Rng;

    #[test]
    fn within_matches_brute_force() {
        let mut rng = stream(3, 77);
        let lms: Vec<_> = (0..3000)
            .map(|i| {
                (
                    LandmarkId(i),
                    Point2::new(
                        rng.random_range(-100.0..300.0),
                        rng.random_range(-50.0..50.0),
                    ),
                )
            })
            .collect();
        let w = LandmarkWorld::new(lms.clone(), 7.0).unwrap();
        let mut out = Vec::new();
        for _ in 0..200 {
            let c = Point2::new(
                rng.random_range(-120.0..320.0),
                rng.random_range(-70.0..70.0),
            );
            let r = rng.random_range(0.0..25.0);
            w.within(&c, r, &mut out);
            let brute: Vec<usize> = (0..lms.len())
                .filter(|&i| (lms[i].1 - c).norm_squared() <= r * r)
                .collect();
            assert_eq!(out, brute);
        }
        assert!(
            LandmarkWorld::new(vec![(LandmarkId(0), Point2::new(f64::NAN, 0.0))], 1.0).is_err()
        );
        let empty = LandmarkWorld::new(Vec::new(), 1.0).unwrap();
        empty.within(&Point2::new(0.0, 0.0), 5.0, &mut out);
        assert!(out.is_empty());
    }
}
