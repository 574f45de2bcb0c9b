//! The Rao-Blackwellized particle filter on occupancy grids: the records' bookkeeping and
//! the front door of a scan here; an update's stages in [`stages`], their scheduling on
//! threads in [`schedule`].

use crate::config::GridFastConfig;
use crate::error::GridFastError;
use crate::matcher::field;
use crate::setup::Setup;
use rand_pcg::Pcg64Mcg;
use slam_grid::matcher::endpoint::score_scan;
use slam_grid::OccupancyGrid;
use slam_grid::RangeData;
use slam_models::keyframes::{self, Keyframe};
use slam_models::particle::PathNode;
use slam_models::OdometryJumpGuard;
use slam_models::{
    normalize_angle, ConfigError, GridMap, LaserScan, Pose2, ScanRecord, ScanUpdateInfo, TimedPose,
};
use std::sync::Arc;

mod scan_slam;
mod schedule;
mod stages;

/// One particle: its current corrected pose, its trajectory (a leaf of the shared tree),
/// its map (a slam-grid occupancy grid on copy-on-write tiles, with an incrementally
/// repaired distance field in the same kind of tiles) and its log weight.
#[derive(Clone)]
struct Particle {
    pose: Pose2,
    log_w: f64,
    map: OccupancyGrid,
    node: Option<Arc<PathNode>>,
}

/// Grid-based FastSLAM: a Rao-Blackwellized particle filter whose particles each carry a
/// trajectory and an occupancy grid (Murphy 2000; Hähnel et al. IROS 2003; Grisetti,
/// Stachniss & Burgard, T-RO 2007 — the GMapping family).
///
/// Each input record moves the estimate by its odometry; a record with a scan triggers a
/// filter update once the odometry path since the last update exceeds
/// [`GridFastConfig::linear_update`] metres or its accumulated turning exceeds
/// [`GridFastConfig::angular_update`] radians, both summed over the odometry of every
/// record (GMapping's rule; see [`GridFastConfig::accumulate_per_scan`]), or once the scan
/// no longer fits the best particle's map at the pose the odometry predicts
/// ([`GridFastConfig::scan_update_fraction`]: motion the odometry missed); the first scan
/// is always used. An update
/// draws every particle's pose from the configured [`crate::Proposal`], updates the weights,
/// resamples when N_eff < `resampling.threshold`·M, and integrates the scan into every
/// surviving particle's map. Between updates a pose is the last corrected pose ⊕ the
/// odometry increment since; a record with both the time stamp and the odometry of the
/// next processed scan is that scan's instant and takes its corrected pose (GMapping's
/// convention, [`slam_models::keyframes`]).
///
/// The world frame is the odometry frame placed at the constructor's `initial_pose`
/// (`Pose2::IDENTITY`: the odometry frame itself, GMapping's convention). Particles run in parallel
/// (rayon); each particle draws from its own random stream derived from `(seed, processed
/// scan index, particle index)`, so the output is identical for any number of threads.
///
/// ```
/// use slam_gridfast::{GridFastConfig, GridFastSlam};
/// use slam_models::{LaserScan, Pose2, ScanRecord, ScanSlam};
/// let config = GridFastConfig { particles: 5, ..Default::default() };
/// let mut slam = GridFastSlam::new(config, Pose2::IDENTITY, 7).unwrap();
/// let scan = LaserScan { angle_min: -1.5, angle_increment: 0.1, ranges: vec![2.0; 31],
///                        max_range: 30.0, sensor_pose: Pose2::IDENTITY };
/// slam.process(&ScanRecord { t: 0.0, odometry: Pose2::IDENTITY, scan: Some(scan) }).unwrap();
/// slam.process(&ScanRecord { t: 0.1, odometry: Pose2::new(0.1, 0.0, 0.0), scan: None }).unwrap();
/// assert_eq!(slam.trajectory().len(), 2);
/// ```
pub struct GridFastSlam {
    /// The configuration as given (`None`s still open).
    given: GridFastConfig,
    /// The effective configuration ([`GridFastConfig::resolve`], with the first processed
    /// scan once there is one).
    config: GridFastConfig,
    /// What follows from `config`: its values by their names, the empty map, the models.
    setup: Setup,
    seed: u64,
    /// World pose of the odometry frame.
    initial_pose: Pose2,
    particles: Vec<Particle>,
    best: usize,
    n_eff: f64,
    /// Per record: time, odometry, and the processed scan at or before it (u32::MAX: none).
    times: Vec<f64>,
    odometry: Vec<Pose2>,
    last_scan_of_record: Vec<u32>,
    /// Per processed scan: the record index and the scan as it came through the door
    /// (kept for re-rendering; shared with the pending integration).
    scan_records: Vec<usize>,
    scans: Vec<Arc<RangeData>>,
    acc_linear: f64,
    acc_angular: f64,
    motion_reference: Option<Pose2>,
    /// Checks each record's odometry against the previous one's ([`GridFastConfig::odometry_jump`]).
    guard: OdometryJumpGuard,
    /// Set when a full update failed half-way: every later record is refused.
    failed: Option<String>,
    /// The last processed scan where some particles' maps do not hold it yet.
    pending: Option<Pending>,
    /// (first index, count) of each group of identical particles (same pose, map and
    /// weight once the pending scan is integrated: before, only the first holds the map),
    /// covering the particles in order: all of them at the start, the copies of one parent
    /// after a resampling, one each otherwise. The pending scan is integrated once per
    /// group and copied, and the improved proposal computed once per group; the best
    /// particle leads its group.
    identical: Vec<(usize, usize)>,
    /// Off only in a test: every particle computes its own proposal.
    #[cfg(test)]
    share_fits: bool,
    /// The particles the last resampling left out: their maps are released during the
    /// next update, beside the integrations ([`schedule::step_groups`]), rather than alone at the
    /// end of this one.
    dead: Vec<Particle>,
}

/// The last processed scan, checked against every particle's map but not yet integrated:
/// the maps take it at the start of the next update, the best particle's group first (its
/// map is the coarse search's) and the others beside that search (see
/// [`schedule::step_groups`]); the
/// filter's map ([`slam_models::ScanSlam::map`]) adds it to a copy of the best particle's map.
struct Pending {
    /// The scan's index among the processed scans (for an error).
    k: usize,
    scan: Arc<RangeData>,
}

/// The largest f64 below `x`, for a positive finite `x` (the config validates
/// `max_range > 0`): `f64::next_down`, which is newer than this workspace's MSRV 1.85.
fn below(x: f64) -> f64 {
    f64::from_bits(x.to_bits() - 1)
}

/// A slam-grid failure while processing scan `k` (a non-finite pose or end point).
fn numerical(k: usize, e: slam_grid::GridError) -> GridFastError {
    GridFastError::Numerical {
        scan: k,
        reason: e.to_string(),
    }
}

/// The random stream of particle `i` (or `u64::MAX` for the resampler) at scan `step`
/// ([`slam_models::rng::particle_stream`]).
fn stream(seed: u64, step: usize, i: u64) -> Pcg64Mcg {
    slam_models::rng::particle_stream(seed, step as u64, i)
}

impl GridFastSlam {
    /// A filter with `config.particles` particles, all with empty maps, whose world frame
    /// is the odometry frame placed at `initial_pose`: a record's uncorrected pose is
    /// `initial_pose ⊕ odometry` (`Pose2::IDENTITY` draws the map in the odometry frame).
    /// `seed` fixes every random draw. Values left `None` (the range limit, the preset's)
    /// are taken from the first processed scan ([`GridFastConfig::resolve`]); until then
    /// the filter holds provisional ones. Errors on an invalid configuration or a
    /// non-finite pose.
    pub fn new(
        config: GridFastConfig,
        initial_pose: Pose2,
        seed: u64,
    ) -> Result<Self, GridFastError> {
        if !initial_pose.is_finite() {
            return Err(GridFastError::InvalidRecord {
                index: 0,
                t: f64::NAN,
                reason: format!("initial pose {initial_pose:?} is not finite"),
            });
        }
        let effective = config.resolve(None)?;
        let config_jump = config.odometry_jump;
        let setup = Setup::new(&effective)?;
        let m = config.particles;
        let particles = (0..m)
            .map(|_| Particle {
                pose: Pose2::IDENTITY,
                log_w: -(m as f64).ln(),
                map: setup.empty.clone(),
                node: None,
            })
            .collect();
        Ok(Self {
            given: config,
            setup,
            config: effective,
            seed,
            initial_pose,
            particles,
            best: 0,
            n_eff: m as f64,
            times: Vec::new(),
            odometry: Vec::new(),
            last_scan_of_record: Vec::new(),
            scan_records: Vec::new(),
            scans: Vec::new(),
            acc_linear: 0.0,
            acc_angular: 0.0,
            motion_reference: None,
            failed: None,
            pending: None,
            identical: vec![(0, m)],
            #[cfg(test)]
            share_fits: true,
            dead: Vec::new(),
            guard: OdometryJumpGuard::new(config_jump).map_err(|_| {
                ConfigError::new(
                    "grid FastSLAM",
                    "odometry_jump.max_jump",
                    config_jump.max_jump,
                    "> 0 m and finite",
                )
            })?,
        })
    }

    /// The effective configuration: every value set, from the first processed scan where
    /// the given configuration left it open (before that scan, provisional values).
    pub fn config(&self) -> &GridFastConfig {
        &self.config
    }

    /// Takes the open values of the given configuration from the first scan and rebuilds
    /// what depends on them (the particles' maps are still empty).
    fn configure_from(&mut self, scan: &LaserScan) -> Result<(), GridFastError> {
        let effective = self.given.resolve(Some(scan))?;
        if effective != self.config {
            self.setup = Setup::new(&effective)?;
            for p in &mut self.particles {
                p.map = self.setup.empty.clone();
            }
            self.config = effective;
        }
        Ok(())
    }

    /// Number of scans the filter has processed (full updates).
    pub fn processed_scans(&self) -> usize {
        self.scans.len()
    }

    /// The best particle's corrected pose at each processed scan, with the scan's time.
    pub fn corrected_poses(&self) -> Vec<TimedPose> {
        self.best_path()
            .into_iter()
            .zip(&self.scan_records)
            .map(|(pose, &r)| TimedPose {
                t: self.times[r],
                pose,
            })
            .collect()
    }

    /// Re-renders the best particle's map at `resolution` metres per cell (e.g. 0.01 for
    /// a 5 cm matching grid) by integrating every processed scan, as the door classified
    /// it, at the best particle's corrected trajectory, with the same inverse sensor model.
    /// Returns an empty map for a non-positive or non-finite resolution, and the grid's
    /// error when a scan cannot be written at this cell size (the map would pass
    /// [`slam_grid::grid::MAX_MAP_CELLS`]: [`GridError::MapTooLarge`](slam_grid::GridError)):
    /// such scans were left out without a word, and a map of none of them was the empty
    /// map, which `slam run --map-resolution 0.003` reported as an error about its output's
    /// staging file.
    pub fn render_map(&self, resolution: f64) -> Result<GridMap, slam_grid::GridError> {
        if !(resolution > 0.0 && resolution.is_finite()) {
            return Ok(GridMap::unknown(0.0, slam_models::Point2::origin(), 0, 0));
        }
        let mut map = OccupancyGrid::new(resolution, self.setup.sensor_model);
        for (pose, scan) in self.best_path().iter().zip(&self.scans) {
            // Every kept scan passed the door and every path pose is finite.
            map.try_integrate_prepared(pose, scan)?;
        }
        Ok(map.to_grid_map())
    }

    fn best_path(&self) -> Vec<Pose2> {
        match self.particles.get(self.best).and_then(|p| p.node.as_ref()) {
            Some(n) => n.path(),
            None => Vec::new(),
        }
    }

    /// The pose of record `i` by [`slam_models::keyframes::pose_at_record`]: the last
    /// corrected pose ⊕ the odometry since, except at a processed scan's own instant.
    fn pose_at_record(&self, i: usize, path: &[Pose2]) -> Pose2 {
        // (`get`: after a failed update the path may not match the scans kept.)
        let keyframe = |k: usize| {
            Some(Keyframe {
                record: *self.scan_records.get(k)?,
                pose: *path.get(k)?,
            })
        };
        let (previous, next) = match self.last_scan_of_record[i] {
            u32::MAX => (None, 0),
            k => (keyframe(k as usize), k as usize + 1),
        };
        let next = keyframe(next);
        // Before the first processed scan a record's pose is its odometry placed in the
        // world (skipped at the identity, where it is the odometry itself, bit for bit).
        let previous = previous.or_else(|| {
            (self.initial_pose != Pose2::IDENTITY).then(|| Keyframe {
                record: i,
                pose: self.initial_pose.compose(&self.odometry[i]),
            })
        });
        keyframes::pose_at_record(&self.times, &self.odometry, i, previous, next)
            .expect("record and scan indices are the filter's own and always in range")
    }

    /// The checks of a record at the door, the only ones: a finite time and odometry, and a
    /// scan that is well formed ([`LaserScan::validate`]) with a finite `sensor_pose`.
    fn check_record(&self, record: &ScanRecord) -> Result<(), GridFastError> {
        let bad = |reason: String| GridFastError::InvalidRecord {
            index: self.times.len(),
            t: record.t,
            reason,
        };
        if !record.t.is_finite() {
            return Err(bad("time is not finite".into()));
        }
        if !record.odometry.is_finite() {
            return Err(bad(format!("odometry {:?} is not finite", record.odometry)));
        }
        if let Some(s) = &record.scan {
            s.validate().map_err(|e| bad(format!("scan: {e}")))?;
            if !s.sensor_pose.is_finite() {
                return Err(bad("scan sensor_pose is not finite".into()));
            }
        }
        Ok(())
    }

    /// Processes one record (the [`slam_models::ScanSlam::process`] contract, with this crate's error).
    pub fn step(&mut self, record: &ScanRecord) -> Result<ScanUpdateInfo, GridFastError> {
        self.check_record(record)?;
        let (odometry, skipped) =
            self.guard
                .check(&record.odometry)
                .map_err(|e| GridFastError::InvalidRecord {
                    index: self.times.len(),
                    t: record.t,
                    reason: e.to_string(),
                })?;
        let mut info = self.step_with(record, odometry)?;
        info.odometry_jumps_skipped = skipped as usize;
        Ok(info)
    }

    /// [`GridFastSlam::step`] with the record's odometry replaced by the guarded one. A
    /// record that fails leaves the per-record bookkeeping as it was, so that the filter
    /// can go on with the next record (it used to index past its tables).
    fn step_with(
        &mut self,
        record: &ScanRecord,
        odometry: Pose2,
    ) -> Result<ScanUpdateInfo, GridFastError> {
        if let Some(reason) = &self.failed {
            return Err(GridFastError::InvalidRecord {
                index: self.times.len(),
                t: record.t,
                reason: format!(
                    "the filter stopped at an earlier failure ({reason}); start a new filter"
                ),
            });
        }
        let n = self.times.len();
        let (scans, saved) = (
            self.scans.len(),
            (self.motion_reference, self.acc_linear, self.acc_angular),
        );
        let r = self.step_unchecked(record, odometry);
        if let Err(e) = &r {
            self.times.truncate(n);
            self.odometry.truncate(n);
            self.last_scan_of_record.truncate(n);
            (self.motion_reference, self.acc_linear, self.acc_angular) = saved;
            // A failure inside a full update may have moved the particles past the scans
            // kept: refuse further records rather than mix the two.
            let moved = self
                .particles
                .iter()
                .any(|p| p.node.as_ref().map_or(0, |n| n.path().len()) != scans);
            if moved || self.particles.is_empty() {
                self.failed = Some(e.to_string());
            }
        }
        r
    }

    fn step_unchecked(
        &mut self,
        record: &ScanRecord,
        odometry: Pose2,
    ) -> Result<ScanUpdateInfo, GridFastError> {
        // Motion is accumulated over every odometry reading, as GMapping's processScan
        // does per reading (`m_linearDistance += |Δ|`, `m_angularDistance += |Δθ|`);
        // with `accumulate_per_scan` only from scan record to scan record (what a ROS
        // node that sees only the scans does).
        if !self.setup.accumulate_per_scan || record.scan.is_some() {
            if let Some(prev) = self.motion_reference {
                self.acc_linear += prev.distance(&odometry);
                self.acc_angular += normalize_angle(odometry.theta - prev.theta).abs();
            }
            self.motion_reference = Some(odometry);
        }
        self.times.push(record.t);
        self.odometry.push(odometry);
        let first = self.scans.is_empty();
        let arrival = match &record.scan {
            Some(scan) => Some(self.admit(first, scan)?),
            None => None,
        };
        let update = match &arrival {
            Some(prepared) => {
                first
                    || self.acc_linear >= self.setup.linear_update
                    || self.acc_angular >= self.setup.angular_update
                    || self.scan_misfits(prepared, &odometry)
            }
            None => false,
        };
        let prepared = match (arrival, update) {
            (Some(prepared), true) => Arc::new(prepared),
            _ => {
                let last = self.last_scan_of_record.last().copied().unwrap_or(u32::MAX);
                self.last_scan_of_record.push(last);
                return Ok(ScanUpdateInfo {
                    processed_scan: false,
                    n_eff: Some(self.n_eff),
                    resampled: false,
                    ..ScanUpdateInfo::default()
                });
            }
        };
        let k = self.scans.len();
        let info = if first {
            self.first_scan(&prepared, odometry)?
        } else {
            self.update(k, Arc::clone(&prepared))?
        };
        self.scan_records.push(self.times.len() - 1);
        self.scans.push(prepared);
        self.last_scan_of_record.push(k as u32);
        self.acc_linear = 0.0;
        self.acc_angular = 0.0;
        Ok(info)
    }

    /// Whether `scan`, not due for an update by the odometry, no longer fits the best
    /// particle's map at the pose the odometry predicts for it (that particle's corrected
    /// pose ⊕ the odometry since the last update): fewer than
    /// [`GridFastConfig::scan_update_fraction`] of its used beams end within the
    /// likelihood radius of an occupied cell. The best particle's map holds every processed
    /// scan but the last (the maps take it at the start of the next update, beside the
    /// coarse search): in space only the last processed scan has seen, a scan may count as
    /// misfit and trigger an update early, which then integrates that scan, so a robot
    /// standing still triggers it at most once.
    fn scan_misfits(&self, prepared: &RangeData, odometry: &Pose2) -> bool {
        let fraction = self.setup.scan_update_fraction;
        let (Some(&r_prev), true) = (self.scan_records.last(), fraction > 0.0) else {
            return false;
        };
        let best = &self.particles[self.best];
        let predicted = best.pose.compose(&self.odometry[r_prev].between(odometry));
        let n = prepared.points().len();
        if n == 0 {
            return false;
        }
        let likelihood = &self.setup.likelihood;
        let inliers = score_scan(&field(&best.map), prepared, &predicted, likelihood).inliers;
        (inliers as f64) < fraction * n as f64
    }

    fn first_scan(
        &mut self,
        prepared: &RangeData,
        odometry: Pose2,
    ) -> Result<ScanUpdateInfo, GridFastError> {
        // The first scan's pose in the world frame (the odometry itself at the identity).
        let pose = if self.initial_pose == Pose2::IDENTITY {
            odometry
        } else {
            self.initial_pose.compose(&odometry)
        };
        let node = PathNode::child(None, pose, 0);
        let mut map = self.particles[0].map.clone();
        map.try_integrate_prepared(&pose, prepared)
            .map_err(|e| numerical(0, e))?;
        for p in &mut self.particles {
            p.pose = pose;
            p.node = Some(Arc::clone(&node));
            p.map = map.clone();
        }
        Ok(ScanUpdateInfo {
            processed_scan: true,
            n_eff: Some(self.n_eff),
            resampled: false,
            match_failures: 0,
            match_recoveries: 0,
            odometry_jumps_skipped: 0,
        })
    }

    /// The front door of a record's scan, once it has passed [`GridFastSlam::check_record`]
    /// (first scan: after the configuration has taken the values it leaves open from it,
    /// [`GridFastSlam::configure_from`]): slam-grid's [`RangeData`], the scan classified
    /// once under the filter's sensor model ([`crate::setup::Setup::sensor_model`]) into
    /// returns — the hits with r < `sensor.max-range`, which the maps mark — and misses
    /// (none: with `far_hits_clear` off and no `no_return_range` nothing else clears
    /// space), with every `sensor.beam-step`-th of the returns with r > 0 (the scan's
    /// `sensor_pose` applied) as the matching points; a reading at `max-range` itself is a
    /// no return. The misfit test, the update's matching, every particle's integration and
    /// [`GridFastSlam::render_map`] take it as it is: no later stage asks a reading again.
    fn admit(&mut self, first: bool, scan: &LaserScan) -> Result<RangeData, GridFastError> {
        if first {
            self.configure_from(scan)?;
        }
        let k = self.scans.len();
        let (max_range, beam_step) = (self.setup.max_range, self.setup.beam_step);
        RangeData::with_limits_every(
            scan,
            &self.setup.sensor_model,
            f64::MIN_POSITIVE,
            below(max_range),
            beam_step,
        )
        .map_err(|e| numerical(k, e))
    }
}

#[cfg(test)]
mod tests;
