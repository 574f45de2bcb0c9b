//! Provisional landmarks: id-less observations that match no mapped landmark are held here
//! and join the state only after k consistent sightings, so that clutter (spurious
//! detections that are not seen again at the same place) never enters the map.
//!
//! A candidate keeps the running mean of its sightings' world positions and the covariance
//! of its latest sighting. A new sighting p (covariance Σp = Gx·Σxx·Gxᵀ + Gz·Q·Gzᵀ) is
//! consistent with a candidate c when (p − c)ᵀ(Σp + Σc)⁻¹(p − c) < χ²₂(p_gate). The
//! candidate's covariance is not shrunk by fusion: successive sightings share the pose
//! error, so treating them as independent would make the gate too tight.

use crate::{Matrix2, Point2};

#[derive(Debug, Clone)]
struct Candidate {
    point: Point2,
    cov: Matrix2,
    sightings: usize,
    last_seen: u64,
}

/// Landmarks seen but not yet mapped, each with its running mean, latest covariance, number
/// of sightings and the step it was last seen.
#[derive(Debug, Clone, Default)]
pub struct ProvisionalList {
    items: Vec<Candidate>,
}

impl ProvisionalList {
    /// Number of provisional landmarks.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// True when there is none.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Records a sighting at `step`; returns the number of sightings of the candidate it
    /// was attributed to and that candidate's index. A candidate already sighted in this
    /// step is not matched twice.
    pub fn sight(&mut self, p: Point2, cov: Matrix2, step: u64, gate: f64) -> (usize, usize) {
        let mut best: Option<(usize, f64)> = None;
        for (k, c) in self.items.iter().enumerate() {
            if c.last_seen == step {
                continue;
            }
            let d = p - c.point;
            let Some(inv) = (cov + c.cov).try_inverse() else {
                continue;
            };
            let d2 = (d.transpose() * inv * d)[(0, 0)];
            if d2 < gate && best.is_none_or(|(_, b)| d2 < b) {
                best = Some((k, d2));
            }
        }
        match best {
            Some((k, _)) => {
                let c = &mut self.items[k];
                c.sightings += 1;
                let w = 1.0 / c.sightings as f64;
                c.point += (p - c.point) * w;
                c.cov = cov;
                c.last_seen = step;
                (c.sightings, k)
            }
            None => {
                self.items.push(Candidate {
                    point: p,
                    cov,
                    sightings: 1,
                    last_seen: step,
                });
                (1, self.items.len() - 1)
            }
        }
    }

    /// Removes candidate `k` (it joined the map); the last candidate takes its index.
    pub fn remove(&mut self, k: usize) {
        self.items.swap_remove(k);
    }

    /// Drops candidates not seen for more than `max_age` steps; returns how many.
    pub fn expire(&mut self, step: u64, max_age: usize) -> usize {
        let before = self.items.len();
        self.items
            .retain(|c| step.saturating_sub(c.last_seen) <= max_age as u64);
        before - self.items.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn consistent_sightings_accumulate_and_stale_ones_expire() {
        let mut l = ProvisionalList::default();
        let cov = Matrix2::identity() * 0.01;
        let gate = 13.8;
        assert_eq!(l.sight(Point2::new(1.0, 1.0), cov, 1, gate).0, 1);
        assert_eq!(l.sight(Point2::new(1.05, 0.98), cov, 2, gate).0, 2);
        // Far away: a new candidate.
        assert_eq!(l.sight(Point2::new(3.0, 1.0), cov, 2, gate).0, 1);
        // Same step as the last sighting: cannot match the first candidate again.
        assert_eq!(l.sight(Point2::new(1.0, 1.0), cov, 2, gate).0, 1);
        assert_eq!(l.len(), 3);
        assert_eq!(l.expire(30, 20), 3);
    }
}
