//! Multi-hypothesis laser odometry: an ambiguous step followed as several branches for a
//! few scans, then the branch whose matches fit best kept.
//!
//! A scan in a corridor or just after a fast turn can fit about as well at two distinct
//! poses (the narrow match around constant velocity and the wide search's best, or a
//! heading beyond the window found by a turn search): one decision there is a coin toss,
//! and a wrong one is never undone (the next prediction starts from it, and the local map
//! is written with it). So, as in a multiple-hypothesis tracker with a fixed decision lag
//! (Reid, IEEE TAC 1979; Cox and Hingorani, PAMI 1996: N-scan-back pruning), each distinct
//! pose of an ambiguous step ([`super::LaserOdometry::propose`]'s alternatives) starts a
//! branch: a copy of the laser odometry (its own local map, prediction and pose chain)
//! that takes that pose. Every branch matches the next scans on its own; `lag` scans after
//! the first split the branch whose matched poses fit the most end points where its map
//! has observed anything, summed over the scans since that split (Σ inliers / end points
//! in observed cells of each scan, [`super::LaserOdometry::known_fit`]; a failed match
//! adds 0), is kept and the others are dropped. End points in unmapped space are left
//! out: counted as misses they favour a pose that lays the scan over the mapped part (the
//! branch stuck behind the robot in a corridor wins on the plain inlier fraction over 5,
//! 10 and 20 scans on acapulco). Every branch shares the poses before the split, so
//! the sums compare like with like.
//!
//! Branch 0 always takes the match [`super::LaserOdometry::process`] would take (the
//! children are appended after it) and wins ties, so without an ambiguous step, or when
//! the default choice fits best, the poses are those of one [`super::LaserOdometry`] to
//! the bit. Deterministic: no randomness, branches in a fixed order.

use super::LaserOdometry;
use crate::error::GridError;
use slam_models::{LaserScan, Pose2};

/// The index of the highest fit, the first of equal ones (branch 0, the default, wins a
/// tie); 0 for an empty slice.
pub(crate) fn best_fit(fits: &[f64]) -> usize {
    (0..fits.len()).fold(0, |best, i| if fits[i] > fits[best] { i } else { best })
}

/// One branch: its laser odometry and its poses since the last decision.
#[derive(Debug, Clone)]
struct Branch {
    lo: LaserOdometry,
    /// Its poses of the scans not yet decided, in order.
    poses: Vec<Pose2>,
    /// Σ inliers / end points in observed cells over the scans since the open split.
    fit: f64,
}

/// Laser odometry with ambiguous steps followed as branches for `lag` scans (module
/// documentation); the poses come out with a delay of at most `lag` scans.
#[derive(Debug, Clone)]
pub(crate) struct Branches {
    branches: Vec<Branch>,
    lag: usize,
    max: usize,
    /// Scans processed since the oldest split not yet decided (`None`: one branch).
    open: Option<usize>,
    /// Poses decided, one per scan, in order.
    decided: Vec<Pose2>,
    /// Ambiguous steps that started a branch.
    splits: usize,
    /// Decisions that kept a branch other than the default one (branch 0).
    switches: usize,
}

impl Branches {
    /// Starts with one branch, `lo`; `lag` scans to a decision (0: never branch), at most
    /// `max` branches at once (at least 1).
    pub(crate) fn new(lo: LaserOdometry, lag: usize, max: usize) -> Self {
        Self {
            branches: vec![Branch {
                lo,
                poses: Vec::new(),
                fit: 0.0,
            }],
            lag,
            max: max.max(1),
            open: None,
            decided: Vec::new(),
            splits: 0,
            switches: 0,
        }
    }

    /// Matches the next scan in every branch (`turn`: the rotation prior, as in
    /// [`LaserOdometry::process`]), starting a branch for each alternative of an ambiguous
    /// step while there is room, and decides when the open split is `lag` scans old.
    pub(crate) fn push(&mut self, scan: &LaserScan, turn: Option<f64>) -> Result<(), GridError> {
        let count = self.branches.len();
        let mut born = Vec::new();
        for b in &mut self.branches {
            let step = b.lo.propose(scan, turn, self.lag > 0)?;
            let room = self.max.saturating_sub(count + born.len());
            for &(i, m) in step.alternatives.iter().take(room) {
                let mut child = b.clone();
                let (pose, _) = child.lo.commit(&step, Some((i, m.pose)))?;
                child.poses.push(pose);
                child.fit += b.lo.known_fit(&step, &m);
                born.push(child);
            }
            b.fit += step.matched.map_or(0.0, |(_, m)| b.lo.known_fit(&step, &m));
            let (pose, _) = b.lo.commit(&step, step.matched.map(|(i, m)| (i, m.pose)))?;
            b.poses.push(pose);
        }
        if !born.is_empty() {
            self.splits += born.len();
            self.branches.extend(born);
            self.open.get_or_insert(0);
        }
        match self.open.as_mut() {
            None => self.flush(0),
            Some(age) => {
                *age += 1;
                if *age >= self.lag {
                    self.decide();
                }
            }
        }
        Ok(())
    }

    /// Keeps the branch that fits best (the first on a tie), moves its pending poses to
    /// the decided ones, and closes the split.
    fn decide(&mut self) {
        let fits: Vec<f64> = self.branches.iter().map(|b| b.fit).collect();
        let best = best_fit(&fits);
        self.switches += usize::from(best != 0);
        let kept = self.branches.swap_remove(best);
        self.branches = vec![kept];
        self.open = None;
        self.flush(0);
    }

    /// Moves branch `i`'s pending poses to the decided ones and restarts its fit.
    fn flush(&mut self, i: usize) {
        let b = &mut self.branches[i];
        self.decided.append(&mut b.poses);
        b.fit = 0.0;
    }

    /// Decides any open split now (the best branch so far), so that every scan pushed has
    /// its pose among the decided ones.
    pub(crate) fn close(&mut self) {
        if self.open.is_some() {
            self.decide();
        }
    }

    /// The poses decided since the last call, in scan order (moved out).
    pub(crate) fn take_decided(&mut self) -> Vec<Pose2> {
        std::mem::take(&mut self.decided)
    }

    /// Scans pushed whose pose is not decided yet (0 without an open split).
    pub(crate) fn pending(&self) -> usize {
        self.branches[0].poses.len()
    }

    /// The laser odometry of branch 0 (after [`Self::close`], the one kept).
    pub(crate) fn odometry(&self) -> &LaserOdometry {
        &self.branches[0].lo
    }

    /// Ambiguous steps that started a branch, and decisions that kept a branch other than
    /// the default one.
    pub(crate) fn splits_and_switches(&self) -> (usize, usize) {
        (self.splits, self.switches)
    }

    /// Decides any open split and returns every scan's pose not taken yet, the laser
    /// odometry of the branch kept, and the splits and switches.
    #[cfg(test)]
    pub(crate) fn finish(mut self) -> (Vec<Pose2>, LaserOdometry, usize, usize) {
        self.close();
        let lo = self.branches.swap_remove(0).lo;
        (self.decided, lo, self.splits, self.switches)
    }

    /// Branches followed now.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.branches.len()
    }

    /// Poses decided so far.
    #[cfg(test)]
    pub(crate) fn decided(&self) -> &[Pose2] {
        &self.decided
    }
}
