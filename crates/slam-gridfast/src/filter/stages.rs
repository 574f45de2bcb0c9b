//! One filter update as named stages (kiss-icp's `RegisterFrame`, Cartographer's
//! `AddRangeData` → `ScanMatch` → `InsertIntoSubmap`):
//!
//! 1. [`shared_match`]: the best particle's match, which every particle uses (the improved
//!    proposal's coarse correction, or scan-matched odometry's corrected increment);
//! 2. [`draw_group`]: each group of identical particles integrates the pending scan and
//!    draws its poses (the two run on threads as [`schedule::step_groups`] decides);
//! 3. [`GridFastSlam::reweigh`]: the new poses and weights, N_eff and the best particle;
//! 4. [`GridFastSlam::resample_into_groups`]: selective resampling into groups of copies;
//! 5. [`GridFastSlam::queue_integration`]: the scan checked against every group's map and
//!    left pending, to be integrated at the start of the next update.

use super::schedule;
use super::{numerical, stream, GridFastSlam, Particle, Pending};
use crate::config::Proposal;
use crate::error::GridFastError;
use crate::matcher::field;
use crate::proposal::{improved_fit, motion_and_likelihood, Drawn, Step};
use crate::setup::Setup;
use slam_grid::matcher::endpoint::{grid_search, hill_climb};
use slam_grid::RangeData;
use slam_models::motion::{MotionModel, OdometryModel};
use slam_models::particle::{effective_sample_size_log, normalize_log_weights, PathNode};
use slam_models::{OdometryControl, Pose2, ScanUpdateInfo};
use std::sync::Arc;

/// What one processed scan's match on the best particle's map gives every particle.
pub(super) struct Shared {
    /// The improved proposal's correction x̂_best ⊖ x'_best from the coarse search
    /// (identity when the search is off or the proposal is another).
    pub correction: Pose2,
    /// The increment and motion model the particles sample (scan-matched odometry
    /// corrects them; the others keep the odometry's).
    pub u: OdometryControl,
    pub motion: OdometryModel,
    /// Particles whose match failed in the shared match (all of them or none).
    pub failures: usize,
}

/// A reweighed update: normalised log weights, N_eff, the best particle and the counts of
/// failed and recovered matches.
struct Weighed {
    log_w: Vec<f64>,
    n_eff: f64,
    best: usize,
    failures: usize,
    recoveries: usize,
}

/// The particles after a resampling: groups of identical particles (leader, copies) in
/// order, the best particle's index, and the particles left out.
struct Regrouped {
    groups: Vec<(Particle, usize)>,
    best: usize,
    dead: Vec<Particle>,
}

impl GridFastSlam {
    /// The update at processed scan `k` (`prepared`, from the front door): the stages in
    /// order.
    pub(super) fn update(
        &mut self,
        k: usize,
        prepared: Arc<RangeData>,
    ) -> Result<ScanUpdateInfo, GridFastError> {
        let r_prev = self.scan_records[k - 1];
        let odo_now = *self.odometry.last().unwrap_or(&Pose2::IDENTITY);
        let u = (self.setup.odometry).control_from_poses(&self.odometry[r_prev], &odo_now);
        let (shared, drawn) = self.match_and_draw(k, &prepared, u)?;
        let w = self.reweigh(k, &drawn, shared.failures)?;
        let m = self.particles.len();
        let resample = w.n_eff < self.setup.resampling.threshold * m as f64;
        let regrouped = self.resample_into_groups(k, &w, resample)?;
        self.queue_integration(k, prepared, regrouped)?;
        self.n_eff = w.n_eff;
        Ok(ScanUpdateInfo {
            processed_scan: true,
            n_eff: Some(w.n_eff),
            resampled: resample,
            match_failures: w.failures,
            match_recoveries: w.recoveries,
            odometry_jumps_skipped: 0,
        })
    }

    /// Stages 1 and 2: the shared match and every group's draws, scheduled by
    /// [`schedule::step_groups`] (the maps take the pending scan meanwhile).
    fn match_and_draw(
        &mut self,
        k: usize,
        prepared: &RangeData,
        u: OdometryControl,
    ) -> Result<(Shared, Vec<Drawn>), GridFastError> {
        let (setup, seed, m) = (&self.setup, self.seed, self.particles.len());
        let share_fits = self.shares_fits();
        let integrated = self.pending.as_ref().map(|p| p.k);
        let stepped = schedule::step_groups(
            &mut self.particles,
            self.best,
            self.pending.take(),
            &self.identical,
            std::mem::take(&mut self.dead),
            |best: &Particle| shared_match(setup, best, prepared, u, m),
            |group: &[Particle], start: usize, shared: &Shared| {
                let step = Step {
                    setup,
                    scan: prepared,
                    u,
                    correction: shared.correction,
                };
                draw_group(&step, (seed, k), group, start, shared, share_fits)
            },
        );
        // The scan the maps just took is kept only to re-render maps: its matching points
        // go (the Arc is unique once step_groups dropped the pending scan).
        if let Some(scan) = integrated.and_then(|j| self.scans.get_mut(j)) {
            if let Some(scan) = Arc::get_mut(scan) {
                scan.release_matching_points();
            }
        }
        stepped.inspect_err(|e| {
            // The maps no longer all hold the same scans: refuse further records.
            self.failed = Some(e.to_string());
        })
    }

    /// Whether a group of identical particles computes the improved proposal's fit once
    /// (always, but in the test that checks it changes nothing).
    fn shares_fits(&self) -> bool {
        #[cfg(test)]
        return self.share_fits;
        #[cfg(not(test))]
        true
    }

    /// Stage 3: each particle takes its drawn pose and multiplies its weight; the weights
    /// are normalised, N_eff computed and the best particle found.
    fn reweigh(
        &mut self,
        k: usize,
        drawn: &[Drawn],
        shared_failures: usize,
    ) -> Result<Weighed, GridFastError> {
        let mut failures = shared_failures;
        let mut recoveries = 0;
        let mut log_w: Vec<f64> = Vec::with_capacity(self.particles.len());
        for (p, d) in self.particles.iter_mut().zip(drawn) {
            p.pose = d.pose;
            p.log_w += d.log_weight;
            p.node = Some(PathNode::child(p.node.take(), d.pose, k));
            failures += d.match_failed as usize;
            recoveries += d.match_recovered as usize;
            log_w.push(p.log_w);
        }
        normalize_log_weights(&mut log_w).map_err(|e| GridFastError::Numerical {
            scan: k,
            reason: e.to_string(),
        })?;
        let n_eff = effective_sample_size_log(&log_w);
        let mut best = 0;
        for (i, (p, &l)) in self.particles.iter_mut().zip(&log_w).enumerate() {
            p.log_w = l;
            if l > log_w[best] {
                best = i;
            }
        }
        Ok(Weighed {
            log_w,
            n_eff,
            best,
            failures,
            recoveries,
        })
    }

    /// Stage 4: with `resample`, the particles drawn by the resampler (from the stream
    /// `u64::MAX`) as groups of copies of one parent, weights reset to 1/M; otherwise every
    /// particle its own group.
    fn resample_into_groups(
        &mut self,
        k: usize,
        w: &Weighed,
        resample: bool,
    ) -> Result<Regrouped, GridFastError> {
        let m = self.particles.len();
        // Drawn before the particles are taken apart, so that a failure leaves them whole.
        let drawn = if resample {
            let weights: Vec<f64> = w.log_w.iter().map(|l| l.exp()).collect();
            let mut rng = stream(self.seed, k, u64::MAX);
            Some(
                (self.setup.resampling.scheme)
                    .resample(&weights, &mut rng)
                    .map_err(|e| GridFastError::Numerical {
                        scan: k,
                        reason: e.to_string(),
                    })?,
            )
        } else {
            None
        };
        let mut old = std::mem::take(&mut self.particles);
        let Some(idx) = drawn else {
            let groups = old.into_iter().map(|p| (p, 1)).collect();
            let (best, dead) = (w.best, Vec::new());
            return Ok(Regrouped { groups, best, dead });
        };
        let mut groups: Vec<(Particle, usize)> = Vec::new();
        let mut new_best = None;
        let mut j = 0;
        while j < idx.len() {
            let a = idx[j];
            let mut n = 1;
            while j + n < idx.len() && idx[j + n] == a {
                n += 1;
            }
            if a == w.best && new_best.is_none() {
                new_best = Some(groups.len());
            }
            let mut p = std::mem::replace(&mut old[a], self.empty_particle());
            p.log_w = -(m as f64).ln();
            groups.push((p, n));
            j += n;
        }
        let g = new_best.unwrap_or(0);
        let best = groups[..g].iter().map(|(_, n)| n).sum();
        Ok(Regrouped {
            groups,
            best,
            dead: old,
        })
    }

    /// A particle with the empty map, at the identity, weight 1 and no path.
    fn empty_particle(&self) -> Particle {
        Particle {
            pose: Pose2::IDENTITY,
            log_w: 0.0,
            map: self.setup.empty.clone(),
            node: None,
        }
    }

    /// Stage 5: every group's integration of the scan is checked now, so that a refused
    /// scan (kilometres off the map) is reported at this scan; the maps take it at the next
    /// update, in parallel with the coarse search (the same maps in the end, for any number
    /// of threads: no step of the update runs alone for an integration).
    fn queue_integration(
        &mut self,
        k: usize,
        prepared: Arc<RangeData>,
        regrouped: Regrouped,
    ) -> Result<(), GridFastError> {
        let Regrouped { groups, best, dead } = regrouped;
        let integrated = schedule::check_integrable(&groups, &prepared);
        self.dead = dead;
        let mut particles = Vec::with_capacity(particles_len(&groups));
        let mut later = Vec::with_capacity(groups.len());
        for (p, n) in groups {
            later.push((particles.len(), n));
            // The copies take the leader's map when it has integrated this scan
            // (`schedule::step_groups`); until then they hold an empty one, since a copy
            // made now would be dropped there unread (and copying the tile tables runs
            // alone).
            let copy = Particle {
                pose: p.pose,
                log_w: p.log_w,
                map: self.setup.empty.clone(),
                node: p.node.clone(),
            };
            particles.push(p);
            for _ in 1..n {
                particles.push(copy.clone());
            }
        }
        // The particles are put back before a failure is reported (a scan kilometres off
        // the map is refused by the grid), so that the filter stays usable.
        self.particles = particles;
        integrated.map_err(|e| numerical(k, e))?;
        self.identical = later;
        self.pending = Some(Pending { k, scan: prepared });
        self.best = best;
        Ok(())
    }
}

/// The number of particles `groups` (leader, copies) covers.
fn particles_len(groups: &[(Particle, usize)]) -> usize {
    groups.iter().map(|&(_, n)| n).sum()
}

/// Stage 1: what the best particle's map gives every particle: for the improved proposal
/// the correction of one exhaustive coarse search (coarse-to-fine: every particle gets a
/// second starting point for its hill climbing); for scan-matched odometry the increment
/// corrected by one match (Hähnel et al. 2003), or `m` failures when it fails.
fn shared_match(
    setup: &Setup,
    best: &Particle,
    scan: &RangeData,
    u: OdometryControl,
    m: usize,
) -> Shared {
    let motion = setup.odometry;
    let mut shared = Shared {
        correction: Pose2::IDENTITY,
        u,
        motion,
        failures: 0,
    };
    match (setup.proposal, &setup.search) {
        (Proposal::Improved, Some(window)) => {
            let predicted = motion.predict(&best.pose, &u);
            let r = motion.noise_covariance(&best.pose, &u)
                + slam_models::Matrix3::from_diagonal(&setup.min_var);
            let window = window.with_prior(&r);
            let f = field(&best.map);
            let found = grid_search(&f, scan, &predicted, &setup.capture, &window);
            shared.correction = predicted.between(&found);
        }
        (Proposal::ScanMatchedOdometry, _) => {
            let start = motion.predict(&best.pose, &u);
            let (capture, likelihood) = (&setup.capture, &setup.likelihood);
            let f = field(&best.map);
            let matched = hill_climb(&f, scan, &start, capture, likelihood, &setup.climb);
            if matched.score.inliers >= setup.min_inliers(scan.points().len()) {
                let s2 = setup.corrected_odometry_noise_scale.powi(2);
                let a = motion.alpha;
                shared.u = motion.control_from_poses(&best.pose, &matched.pose);
                shared.motion = OdometryModel {
                    alpha: [a[0] * s2, a[1] * s2, a[2] * s2, a[3] * s2],
                    ..motion
                };
            } else {
                shared.failures = m;
            }
        }
        _ => {}
    }
    shared
}

/// Stage 2: one group of identical particles' draws (the particles `start`, `start` + 1,
/// … of update `k`), each particle from its own stream ([`stream`] of `seed`). The
/// improved proposal's match, samples and fit once per group (same pose, same map: the
/// copies of one parent since a resampling, about a quarter of the particles on Intel)
/// unless `share_fits` is off (a test).
fn draw_group(
    step: &Step<'_>,
    (seed, k): (u64, usize),
    group: &[Particle],
    start: usize,
    shared: &Shared,
    share_fits: bool,
) -> Vec<Drawn> {
    let proposal = step.setup.proposal;
    let fit = |p: &Particle| improved_fit(&p.pose, &p.map, &field(&p.map), step);
    let shared_fit = (proposal == Proposal::Improved && share_fits)
        .then(|| group.first().map(fit))
        .flatten();
    group
        .iter()
        .enumerate()
        .map(|(j, p)| {
            let mut rng = stream(seed, k, (start + j) as u64);
            let f = field(&p.map);
            match (proposal, &shared_fit) {
                (Proposal::Improved, Some(fitted)) => fitted.draw(&p.pose, &f, step, &mut rng),
                (Proposal::Improved, None) => fit(p).draw(&p.pose, &f, step, &mut rng),
                _ => motion_and_likelihood(&p.pose, &f, step, &shared.motion, &shared.u, &mut rng),
            }
        })
        .collect()
}
