//! [`GridFastSlam`] behind the workspace's filter traits: [`slam_models::FromConfig`] and
//! [`ScanSlam`] (the estimates as the front ends read them).

use super::GridFastSlam;
use crate::config::GridFastConfig;
use crate::error::GridFastError;
use slam_models::particle::normalize_log_weights;
use slam_models::{
    FilterError, GridMap, Pose2, ScanRecord, ScanSlam, ScanUpdateInfo, TimedPose, WeightedPose,
};

slam_models::from_config_by_new!(GridFastSlam, GridFastConfig, GridFastError);

impl ScanSlam for GridFastSlam {
    fn name(&self) -> &str {
        "gridfast"
    }

    /// See [`GridFastSlam::step`]. `n_eff` in the returned info is the effective sample
    /// size of the weights after the update and before any resampling (the value the
    /// resampling decision used).
    fn process(&mut self, record: &ScanRecord) -> Result<ScanUpdateInfo, FilterError> {
        self.step(record).map_err(FilterError::from)
    }

    fn pose(&self) -> Pose2 {
        match self.times.len() {
            0 => self.initial_pose,
            n => {
                let path = self.best_path();
                self.pose_at_record(n - 1, &path)
            }
        }
    }

    fn trajectory(&self) -> Vec<TimedPose> {
        let path = self.best_path();
        (0..self.times.len())
            .map(|i| TimedPose {
                t: self.times[i],
                pose: self.pose_at_record(i, &path),
            })
            .collect()
    }

    /// The best particle's map with the last processed scan (which the particles' maps
    /// take only at the start of the next update).
    fn map(&self) -> GridMap {
        let best = &self.particles[self.best];
        if let Some(pending) = &self.pending {
            let mut map = best.map.clone();
            // Checked when it was processed: it cannot fail here.
            if map
                .try_integrate_prepared(&best.pose, &pending.scan)
                .is_ok()
            {
                return map.to_grid_map();
            }
        }
        best.map.to_grid_map()
    }

    /// [`GridFastSlam::render_map`]: every processed scan integrated at the best
    /// particle's corrected trajectory on a grid of `resolution` metres.
    fn render_map(&self, resolution: f64) -> Option<Result<GridMap, FilterError>> {
        (resolution > 0.0 && resolution.is_finite())
            .then(|| GridFastSlam::render_map(self, resolution).map_err(FilterError::from))
    }

    /// [`GridFastSlam::config`]: the effective [`GridFastConfig`].
    fn effective_config(&self) -> Option<&dyn std::any::Any> {
        Some(&self.config)
    }

    fn particles(&self) -> Option<Vec<WeightedPose>> {
        let mut lw: Vec<f64> = self.particles.iter().map(|p| p.log_w).collect();
        normalize_log_weights(&mut lw).ok()?;
        // Each particle's corrected pose ⊕ the odometry since the last processed scan.
        let since = match (self.scan_records.last(), self.odometry.last()) {
            (Some(&r), Some(now)) => self.odometry[r].between(now),
            _ => Pose2::IDENTITY,
        };
        Some(
            self.particles
                .iter()
                .zip(lw)
                .map(|(p, l)| WeightedPose {
                    pose: p.pose.compose(&since),
                    weight: l.exp(),
                })
                .collect(),
        )
    }
}
