//! The keyframe graph's optimisation and the trajectory at every record: the smoother's
//! graph of one node per record (odometry edges between records, the keyframe graph's
//! scan-matching and loop-closure edges between keyframes) and the map rendered from it;
//! the odometry noise model ([`OdometryNoise`](super::OdometryNoise)) its edges use.

use super::{invert, Constraint, LaserGraphSlam};
use crate::error::GraphError;
use crate::graph::PoseGraph;
use crate::optimizer::Optimizer;
use slam_grid::OccupancyGrid;
use slam_models::{normalize_angle, GridMap, Matrix3, Pose2};

impl LaserGraphSlam {
    /// Optimises the keyframe graph (first keyframe held) and writes the poses back.
    pub(super) fn optimize_keyframes(&mut self) -> Result<(), GraphError> {
        let mut graph = PoseGraph::new();
        for (k, kf) in self.keyframes.iter().enumerate() {
            graph.add_pose(k as u64, kf.global)?;
        }
        graph.fix(0)?;
        let shares = self.closure_shares();
        for (c, &n) in self.constraints.iter().zip(&shares) {
            let information = c.edge_information() / n as f64;
            graph.add_between(c.from as u64, c.to as u64, c.z, information)?;
        }
        let mut opt = Optimizer::new(&graph, self.config.optimizer)?;
        opt.optimize(&mut graph)?;
        for (kf, p) in self.keyframes.iter_mut().zip(graph.poses()) {
            kf.global = p;
        }
        self.stats.optimizations += 1;
        // The smoothed trajectory (cached per record count) no longer holds.
        if let Ok(cached) = self.smoothed.get_mut() {
            *cached = None;
        }
        Ok(())
    }

    /// For every constraint, the number of loop closures that share its information: with
    /// `closures-share-submap` (the default), a loop closure's is shared with every other
    /// closure whose earlier keyframe lies in the same submap (the first submap the
    /// keyframe was inserted into), so that their information adds up to one closure's;
    /// 1 for the scan-matching edges and otherwise.
    ///
    /// Those closures match scans against one grid: its errors (the keyframes' local
    /// poses it was built from, the anchoring keyframe's jitter in it) are common to all
    /// of them, and n measurements whose errors are shared are worth about one, not n
    /// (covariance intersection's conservative bound for fully correlated estimates,
    /// Julier and Uhlmann 1997: each weighed by 1/n). Counted as independent, a hundred
    /// such closures outweighed the scan-matching chain (docs/results/graph.md).
    pub(super) fn closure_shares(&self) -> Vec<usize> {
        let mut shares = vec![1; self.constraints.len()];
        if !self.config.closures_share_submap {
            return shares;
        }
        let mut first = vec![usize::MAX; self.keyframes.len()];
        for (s, submap) in self.submaps.iter().enumerate() {
            for &k in &submap.keyframes {
                if first[k] == usize::MAX {
                    first[k] = s;
                }
            }
        }
        // A keyframe in no submap (none is, before the first scan) is a group of its own.
        let group = |c: &Constraint| match first.get(c.from) {
            Some(&s) if s != usize::MAX => Ok(s),
            _ => Err(c.from),
        };
        let mut count = std::collections::HashMap::new();
        for c in self.constraints.iter().filter(|c| c.loop_closure) {
            *count.entry(group(c)).or_insert(0usize) += 1;
        }
        for (share, c) in shares.iter_mut().zip(&self.constraints) {
            if c.loop_closure {
                *share = count[&group(c)];
            }
        }
        shares
    }

    /// The pose of every record before smoothing: the last keyframe's optimised pose
    /// composed with the odometry since (the odometry itself before the first keyframe).
    fn composed_poses(&self) -> Vec<Pose2> {
        (0..self.times.len())
            .map(|i| match self.last_keyframe_at[i] {
                Some(k) => {
                    let kf = &self.keyframes[k];
                    kf.global
                        .compose(&self.odometry[kf.record].between(&self.odometry[i]))
                }
                None => self.odometry[i],
            })
            .collect()
    }

    /// The smoothed pose of every record: the graph of one node per record described in the
    /// module documentation, optimised from the composed poses. Falls back to the
    /// composed poses if the optimiser fails (it cannot on a connected chain with positive
    /// definite information, but the trait's accessors cannot return errors).
    pub fn smoothed_poses(&self) -> Vec<Pose2> {
        let n = self.times.len();
        if let Ok(guard) = self.smoothed.lock() {
            if let Some((m, poses)) = guard.as_ref() {
                if *m == n {
                    return poses.clone();
                }
            }
        }
        let initial = self.composed_poses();
        let poses = self.smooth(&initial).unwrap_or(initial);
        if let Ok(mut guard) = self.smoothed.lock() {
            *guard = Some((n, poses.clone()));
        }
        poses
    }

    fn smooth(&self, initial: &[Pose2]) -> Result<Vec<Pose2>, GraphError> {
        if initial.len() < 2 {
            return Ok(initial.to_vec());
        }
        let mut graph = PoseGraph::new();
        for (i, p) in initial.iter().enumerate() {
            graph.add_pose(i as u64, *p)?;
        }
        graph.fix(0)?;
        let hold = self.config.smoother_holds_keyframes;
        if hold {
            for kf in &self.keyframes {
                graph.fix(kf.record as u64)?;
            }
        }
        for i in 1..initial.len() {
            let delta = self.odometry[i - 1].between(&self.odometry[i]);
            let info = invert(&self.odometry_covariance(&delta));
            graph.add_between(i as u64 - 1, i as u64, delta, info)?;
        }
        // Held keyframes: their edges would join fixed nodes and change nothing.
        if !hold {
            for c in &self.constraints {
                if c.loop_closure && self.chi2(c) > self.config.smoother_max_closure_chi2 {
                    continue;
                }
                let (a, b) = (self.keyframes[c.from].record, self.keyframes[c.to].record);
                graph.add_between(a as u64, b as u64, c.z, c.edge_information())?;
            }
        }
        let mut opt = Optimizer::new(&graph, self.config.smoother)?;
        opt.optimize(&mut graph)?;
        Ok(graph.poses())
    }

    /// eᵀΩe of a constraint at the keyframes' current poses, e = (z⁻¹ ⊕ x_from⁻¹ ⊕ x_to)
    /// as (x, y, θ) with θ normalised (g2o's `EDGE_SE2` error).
    fn chi2(&self, c: &Constraint) -> f64 {
        let rel = self.keyframes[c.from]
            .global
            .between(&self.keyframes[c.to].global);
        let e = c.z.between(&rel);
        let v = slam_models::Vector3::new(e.x, e.y, normalize_angle(e.theta));
        (v.transpose() * c.edge_information() * v)[(0, 0)]
    }

    /// The map rendered at `resolution` from every keyframe's scan at its smoothed pose.
    pub fn render(&self, resolution: f64) -> Result<GridMap, GraphError> {
        let poses = self.smoothed_poses();
        let mut grid = OccupancyGrid::try_new(resolution, self.config.sensor_model)?;
        for kf in &self.keyframes {
            grid.try_integrate_prepared(&poses[kf.record], &self.prepare(&kf.scan)?)?;
        }
        Ok(grid.to_grid_map())
    }

    /// Covariance of one odometry increment ([`OdometryNoise`]), in the earlier record's
    /// frame.
    pub(super) fn odometry_covariance(&self, delta: &Pose2) -> Matrix3 {
        let n = &self.config.odometry_noise;
        let d = delta.translation().coords.norm();
        let a = normalize_angle(delta.theta).abs();
        let st = n.translation_per_metre * d + n.translation_per_radian * a + n.min_translation;
        let sr = n.rotation_per_radian * a + n.rotation_per_metre * d + n.min_rotation;
        Matrix3::from_diagonal(&slam_models::Vector3::new(st * st, st * st, sr * sr))
    }

    /// Covariance of the composed odometry from record `a` to record `b` (first order,
    /// in `a`'s frame): Σ ← J₁ Σ J₁ᵀ + J₂ Σᵢ J₂ᵀ along the chain.
    pub(super) fn odometry_chain_covariance(&self, a: usize, b: usize) -> Matrix3 {
        let mut acc = Pose2::IDENTITY;
        let mut cov = Matrix3::zeros();
        for j in a + 1..=b {
            let delta = self.odometry[j - 1].between(&self.odometry[j]);
            let (j1, j2) = acc.compose_jacobians(&delta);
            cov =
                j1 * cov * j1.transpose() + j2 * self.odometry_covariance(&delta) * j2.transpose();
            acc = acc.compose(&delta);
        }
        if a == b {
            cov = self.odometry_covariance(&Pose2::IDENTITY);
        }
        (cov + cov.transpose()) * 0.5
    }
}
