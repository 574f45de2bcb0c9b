//! The FastSLAM filter: a particle set, adaptive resampling, and the [`LandmarkSlam`]
//! interface.

use crate::config::{FastSlamConfig, Variant};
use crate::error::FastSlamError;
use crate::map::LandmarkMap;
#[allow(unused_imports)]
use crate::par::*;
use crate::particle::{estimates, stream, Obs, Particle, ParticleStats, StepContext};
use slam_models::particle::{
    effective_sample_size_log, normalize_log_weights, ParticlePaths, PathNode,
};
use slam_models::{
    normalize_angle, Control, FilterError, LandmarkEstimate, LandmarkSlam, Matrix3, Pose2,
    RangeBearing, UpdateInfo, Vector3, WeightedPose,
};

/// Stream index reserved for the resampler's random draws (particles use 0..M).
const RESAMPLE_STREAM: u64 = u64::MAX;

/// FastSLAM 1.0 / 2.0 over point landmarks observed by range and bearing.
///
/// Call [`LandmarkSlam::predict`] with each control and [`LandmarkSlam::update`] with the
/// observations taken after it. FastSLAM 1.0 samples poses in `predict`; FastSLAM 2.0 keeps
/// the control until `update`, where the measurement-informed proposal needs it.
///
/// Determinism: particle k at filter tick t draws from a random stream that is a function of
/// (seed, t, k) only, and the weight reductions run serially in particle order, so the
/// output is bit-identical for any number of rayon threads.
///
/// # Example
/// ```
/// use slam_fastslam::{FastSlam, FastSlamConfig, Variant};
/// use slam_models::{Control, LandmarkId, LandmarkSlam, OdometryControl, Pose2, RangeBearing};
/// let config = FastSlamConfig { variant: Variant::FastSlam2, particles: 10, ..Default::default() };
/// let mut f = FastSlam::new(config, Pose2::IDENTITY, 42).unwrap();
/// f.predict(&Control::Odometry(OdometryControl { rot1: 0.0, trans: 1.0, rot2: 0.0 })).unwrap();
/// let z = RangeBearing { range: 2.0, bearing: 0.3, id: Some(LandmarkId(4)) };
/// let info = f.update(&[z]).unwrap();
/// assert_eq!(info.new_landmarks, 1);
/// assert_eq!(f.landmarks().len(), 1);
/// ```
#[derive(Debug, Clone)]
pub struct FastSlam {
    config: FastSlamConfig,
    particles: Vec<Particle>,
    seed: u64,
    /// Counts predict/update calls; keys the random streams.
    tick: u64,
    /// Number of `update` calls so far.
    updates: u64,
    /// FastSLAM 2.0: the control received by `predict`, applied in `update`.
    pending: Option<Control>,
    /// Index of the particle with the largest weight.
    best: usize,
}

impl FastSlam {
    /// A filter with `config.particles` particles, all at `initial_pose` with empty maps and
    /// equal weights. Errors on an invalid configuration or a non-finite pose.
    pub fn new(
        config: FastSlamConfig,
        initial_pose: Pose2,
        seed: u64,
    ) -> Result<Self, FastSlamError> {
        config.validate()?;
        for (what, v) in [
            ("initial pose x", initial_pose.x),
            ("initial pose y", initial_pose.y),
            ("initial pose theta", initial_pose.theta),
        ] {
            if !v.is_finite() {
                return Err(FastSlamError::NonFiniteInput { what, value: v });
            }
        }
        let m = config.particles;
        let proto = Particle {
            pose: initial_pose,
            path: PathNode::child(None, initial_pose, 0),
            log_weight: -(m as f64).ln(),
            map: LandmarkMap::new(config.index_cell_size),
            provisional: Vec::new(),
        };
        Ok(Self {
            particles: vec![proto; m],
            config,
            seed,
            tick: 0,
            updates: 0,
            pending: None,
            best: 0,
        })
    }

    /// Replaces every particle's map with one map holding `landmarks` (a prior map, e.g.
    /// surveyed landmarks or a previous run's result; each keeps its id as key, with
    /// existence `existence_max`). All particles share that one tree: O(N log N) to build
    /// once, O(1) per particle. Errors on a non-finite mean or a covariance that is not
    /// symmetric positive definite.
    pub fn set_prior_map(&mut self, landmarks: &[LandmarkEstimate]) -> Result<(), FastSlamError> {
        let mut map = LandmarkMap::new(self.config.index_cell_size);
        for l in landmarks {
            let finite = l.mean.x.is_finite() && l.mean.y.is_finite();
            if !finite {
                return Err(FastSlamError::NonFiniteInput {
                    what: "prior landmark mean",
                    value: if l.mean.x.is_finite() {
                        l.mean.y
                    } else {
                        l.mean.x
                    },
                });
            }
            let c = l.covariance;
            if (c[(0, 1)] - c[(1, 0)]).abs() > 1e-9 * c.norm() || c.cholesky().is_none() {
                return Err(slam_models::ModelError::NotPositiveDefinite {
                    what: "prior landmark covariance",
                }
                .into());
            }
            map.insert(
                l.id.0,
                crate::landmark::Landmark {
                    id: l.id,
                    mean: l.mean,
                    cov: c,
                    existence: self.config.existence_max,
                    observations: self.config.confirm_observations.max(1),
                    cell: 0,
                },
            );
        }
        for p in &mut self.particles {
            p.map = map.clone();
            p.provisional.clear();
        }
        Ok(())
    }

    /// The configuration.
    pub fn config(&self) -> &FastSlamConfig {
        &self.config
    }

    /// The particle set (normalised log weights).
    pub fn particle_set(&self) -> &[Particle] {
        &self.particles
    }

    /// The particle with the largest weight.
    pub fn best_particle(&self) -> &Particle {
        &self.particles[self.best]
    }

    /// The weighted mean pose (circular mean for θ) and the weighted covariance of the
    /// particle poses about it (angle differences normalised).
    pub fn mean_pose(&self) -> (Pose2, Matrix3) {
        let (mut x, mut y, mut s, mut c) = (0.0, 0.0, 0.0, 0.0);
        let w: Vec<f64> = self.particles.iter().map(|p| p.log_weight.exp()).collect();
        let total: f64 = w.iter().sum();
        for (p, wi) in self.particles.iter().zip(&w) {
            x += wi * p.pose.x;
            y += wi * p.pose.y;
            s += wi * p.pose.theta.sin();
            c += wi * p.pose.theta.cos();
        }
        let mean = Pose2::new(x / total, y / total, s.atan2(c));
        let mut cov = Matrix3::zeros();
        for (p, wi) in self.particles.iter().zip(&w) {
            let d = Vector3::new(
                p.pose.x - mean.x,
                p.pose.y - mean.y,
                normalize_angle(p.pose.theta - mean.theta),
            );
            cov += d * d.transpose() * (wi / total);
        }
        (mean, cov)
    }

    /// Resamples now, whatever N_eff (normally [`LandmarkSlam::update`] decides). Each new
    /// particle shares its ancestor's map: a pointer copy.
    pub fn resample(&mut self) -> Result<(), FastSlamError> {
        let w: Vec<f64> = self.particles.iter().map(|p| p.log_weight.exp()).collect();
        let mut rng = stream(self.seed, self.tick, RESAMPLE_STREAM);
        let idx = self.config.resampler.resample(&w, &mut rng)?;
        let m = self.particles.len();
        let best_old = self.best;
        let mut next = Vec::with_capacity(m);
        for &i in &idx {
            let mut p = self.particles[i].clone();
            p.log_weight = -(m as f64).ln();
            next.push(p);
        }
        // The best particle survives resampling (it has the largest weight, so systematic
        // and residual resampling copy it); keep pointing at its first copy.
        self.best = idx.iter().position(|&i| i == best_old).unwrap_or(0);
        self.particles = next;
        self.tick += 1;
        Ok(())
    }

    /// Samples every particle's pending control from the motion model (FastSLAM 1.0
    /// prediction; FastSLAM 2.0 when a second control arrives before any update).
    fn sample_motion_all(&mut self, u: &Control) {
        let (seed, tick, cfg) = (self.seed, self.tick, &self.config);
        self.particles
            .par_iter_mut()
            .enumerate()
            .for_each(|(k, p)| {
                let mut rng = stream(seed, tick, k as u64);
                p.sample_motion(cfg, u, &mut rng);
            });
        self.tick += 1;
    }

    fn validate_control(u: &Control) -> Result<(), FastSlamError> {
        u.validate().map_err(FastSlamError::from)
    }
}

slam_models::from_config_by_new!(FastSlam, FastSlamConfig, FastSlamError);

impl LandmarkSlam for FastSlam {
    fn name(&self) -> &str {
        match self.config.variant {
            Variant::FastSlam1 => "fastslam1",
            Variant::FastSlam2 => "fastslam2",
        }
    }

    fn predict(&mut self, control: &Control) -> Result<(), FilterError> {
        Self::validate_control(control)?;
        match self.config.variant {
            Variant::FastSlam1 => self.sample_motion_all(control),
            Variant::FastSlam2 => {
                if let Some(prev) = self.pending.take() {
                    self.sample_motion_all(&prev);
                }
                self.pending = Some(*control);
            }
        }
        Ok(())
    }

    /// One measurement update of every particle (in parallel), then normalisation of the
    /// weights, N_eff, and resampling when N_eff < threshold·M. Observations with a NaN/∞
    /// value are an error; those with a range below the sensor's minimum (the Freiburg data
    /// holds one negative range) are counted as rejected and skipped. The diagnostics
    /// (`associated`, `new_landmarks`, `removed`, `nis`) are the best particle's.
    fn update(&mut self, observations: &[RangeBearing]) -> Result<UpdateInfo, FilterError> {
        let mut obs = Vec::with_capacity(observations.len());
        let mut rejected = 0;
        for z in observations {
            for (what, v) in [
                ("observation range", z.range),
                ("observation bearing", z.bearing),
            ] {
                if !v.is_finite() {
                    return Err(FastSlamError::NonFiniteInput { what, value: v }.into());
                }
            }
            if z.range < self.config.sensor.min_range {
                rejected += 1;
                continue;
            }
            obs.push(Obs {
                z: z.to_vector(),
                raw: *z,
            });
        }
        // Checked before anything changes: every observation could start a landmark.
        let largest = self
            .particles
            .iter()
            .map(|p| p.map.len())
            .max()
            .unwrap_or(0);
        if largest.saturating_add(obs.len()) > self.config.max_landmarks {
            return Err(FastSlamError::TooManyLandmarks {
                landmarks: largest,
                observations: obs.len(),
                max: self.config.max_landmarks,
            }
            .into());
        }
        let ctx = StepContext {
            config: &self.config,
            ln_p0: self.config.p0.ln(),
            update_index: self.updates,
        };
        self.updates += 1;
        // This update's poses become path step `updates` (step 0 is the initial pose).
        let step = self.updates as usize;
        let (seed, tick) = (self.seed, self.tick);
        let pending = self.pending.take();
        let stats: Vec<ParticleStats> = match self.config.variant {
            Variant::FastSlam1 => self
                .particles
                .par_iter_mut()
                .map(|p| {
                    let st = p.update_fastslam1(&ctx, &obs);
                    p.extend_path(step);
                    st
                })
                .collect(),
            Variant::FastSlam2 => self
                .particles
                .par_iter_mut()
                .enumerate()
                .map(|(k, p)| {
                    let mut rng = stream(seed, tick, k as u64);
                    let st = p.update_fastslam2(&ctx, pending.as_ref(), &obs, &mut rng);
                    p.extend_path(step);
                    st
                })
                .collect(),
        };
        self.tick += 1;
        let mut lw: Vec<f64> = self.particles.iter().map(|p| p.log_weight).collect();
        normalize_log_weights(&mut lw).map_err(|e| FastSlamError::Degenerate(e.to_string()))?;
        for (p, l) in self.particles.iter_mut().zip(&lw) {
            p.log_weight = *l;
        }
        self.best = (0..lw.len()).fold(0, |b, i| if lw[i] > lw[b] { i } else { b });
        let n_eff = effective_sample_size_log(&lw);
        let st = stats[self.best];
        let mut info = UpdateInfo {
            observations: observations.len(),
            associated: st.associated,
            new_landmarks: st.new_landmarks,
            rejected: rejected + st.rejected,
            removed: st.removed,
            nis: st.nis,
            n_eff: Some(n_eff),
            resampled: false,
        };
        let m = self.particles.len();
        if m > 1 && n_eff < self.config.resample_threshold * m as f64 {
            self.resample()?;
            info.resampled = true;
        }
        Ok(info)
    }

    /// The best particle's pose (FastSLAM 2.0 with a control not yet applied by an update:
    /// the pose before that control).
    fn pose(&self) -> Pose2 {
        self.particles[self.best].pose
    }

    /// The weighted covariance of the particle poses ([`FastSlam::mean_pose`]).
    fn pose_covariance(&self) -> Matrix3 {
        self.mean_pose().1
    }

    /// [`FastSlam::mean_pose`]: the weighted mean and covariance of the particle poses.
    fn pose_gaussian(&self) -> (Pose2, Matrix3) {
        self.mean_pose()
    }

    /// The best particle's landmarks, in key order.
    fn landmarks(&self) -> Vec<LandmarkEstimate> {
        estimates(&self.particles[self.best].map)
    }

    fn particles(&self) -> Option<Vec<WeightedPose>> {
        Some(
            self.particles
                .iter()
                .map(|p| WeightedPose {
                    pose: p.pose,
                    weight: p.log_weight.exp(),
                })
                .collect(),
        )
    }

    /// The best particle's path: the initial pose, then its pose after each update. Its
    /// map is [`LandmarkSlam::landmarks`].
    fn full_path(&self) -> Option<Vec<Pose2>> {
        Some(self.particles[self.best].path())
    }

    /// Every particle's path, the shared history stored once.
    fn particle_paths(&self) -> Option<ParticlePaths> {
        let leaves: Vec<&std::sync::Arc<PathNode>> =
            self.particles.iter().map(|p| &p.path).collect();
        let weights = self.particles.iter().map(|p| p.log_weight.exp()).collect();
        Some(ParticlePaths::from_leaves(&leaves, weights, self.best))
    }

    /// Every particle's landmarks, in key order.
    fn particle_landmarks(&self) -> Option<Vec<Vec<LandmarkEstimate>>> {
        Some(self.particles.iter().map(|p| estimates(&p.map)).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Association;
    use crate::config::MAX_LANDMARKS;
    use rand::{Rng, SeedableRng};
    use rand_distr::{Distribution, Normal};
    use slam_models::{LandmarkId, OdometryControl, Point2};

    /// A small synthetic world: landmarks scattered around a circle of radius 8 m, the
    /// robot driving the circle with noisy odometry, a 6 m / 180° range-bearing sensor,
    /// optional hidden ids and one false alarm per scan on average.
    fn world(
        seed: u64,
        steps: usize,
        hide_ids: bool,
    ) -> (Vec<(Control, Vec<RangeBearing>)>, Vec<Point2>) {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
        let lms: Vec<Point2> = (0..40)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 40.0;
                let r = 8.0 + rng.random_range(-3.0..3.0);
                Point2::new(r * a.cos(), r * a.sin() + 8.0)
            })
            .collect();
        let (nr, nb) = (
            Normal::new(0.0, 0.1).unwrap(),
            Normal::new(0.0, 0.02).unwrap(),
        );
        let mut pose = Pose2::IDENTITY;
        let mut out = Vec::new();
        for _ in 0..steps {
            let u = OdometryControl {
                rot1: 0.0125,
                trans: 0.2,
                rot2: 0.0125,
            };
            pose = pose.compose(&Pose2::new(
                0.2 * 0.0125f64.cos(),
                0.2 * 0.0125f64.sin(),
                0.025,
            ));
            let noisy = OdometryControl {
                rot1: u.rot1 + nb.sample(&mut rng) * 0.1,
                trans: u.trans + nr.sample(&mut rng) * 0.05,
                rot2: u.rot2 + nb.sample(&mut rng) * 0.1,
            };
            let mut obs = Vec::new();
            for (k, m) in lms.iter().enumerate() {
                let d = pose.inverse_transform_point(m);
                let (r, b) = (d.coords.norm(), d.y.atan2(d.x));
                if r < 6.0 && b.abs() < std::f64::consts::FRAC_PI_2 {
                    let id = (!hide_ids).then_some(LandmarkId(k as u32));
                    obs.push(RangeBearing {
                        range: r + nr.sample(&mut rng),
                        bearing: b + nb.sample(&mut rng),
                        id,
                    });
                }
            }
            if hide_ids && rng.random_bool(0.7) {
                obs.push(RangeBearing {
                    range: rng.random_range(1.0..6.0),
                    bearing: rng.random_range(-1.5..1.5),
                    id: None,
                });
            }
            out.push((Control::Odometry(noisy), obs));
        }
        (out, lms)
    }

    fn config(variant: Variant, particles: usize) -> FastSlamConfig {
        FastSlamConfig {
            variant,
            particles,
            sensor: slam_models::measurement::RangeBearingModel::new(0.1, 0.02),
            max_range: Some(6.0),
            fov: Some(std::f64::consts::PI),
            ..Default::default()
        }
    }

    fn snapshot(f: &FastSlam) -> Vec<Vec<(u32, Point2, slam_models::Matrix2, i32)>> {
        f.particles
            .iter()
            .map(|p| {
                p.map
                    .iter()
                    .map(|(k, l)| (k, l.mean, l.cov, l.existence))
                    .collect()
            })
            .collect()
    }

    /// After resampling the particles share map nodes; writing to one particle's landmark
    /// (directly, and through a full filter update of only that particle) never changes
    /// any other particle's landmarks.
    /// Through the object-safe trait FastSLAM's error keeps its type: a NaN range is
    /// `InvalidInput` and downcasts back to `FastSlamError::NonFiniteInput`.
    #[test]
    fn trait_errors_keep_the_typed_source() {
        let mut f: Box<dyn LandmarkSlam> = Box::new(
            <FastSlam as slam_models::FromConfig>::from_config(
                FastSlamConfig::default(),
                Pose2::IDENTITY,
                3,
            )
            .unwrap(),
        );
        let z = RangeBearing {
            range: f64::NAN,
            bearing: 0.0,
            id: None,
        };
        let e = f.update(&[z]).unwrap_err();
        assert!(matches!(e, FilterError::InvalidInput { .. }), "{e:?}");
        let typed = std::error::Error::source(&e)
            .and_then(|s| s.downcast_ref::<FastSlamError>())
            .expect("the typed source");
        assert!(
            matches!(
                typed,
                FastSlamError::NonFiniteInput {
                    what: "observation range",
                    ..
                }
            ),
            "{typed:?}"
        );
        assert!(e.downcast_ref::<FastSlamError>().is_some());
    }

    #[test]
    fn particles_never_alias_after_resampling() {
        let (data, _) = world(1, 40, false);
        let mut f = FastSlam::new(config(Variant::FastSlam1, 8), Pose2::IDENTITY, 2).unwrap();
        for (u, z) in &data {
            f.predict(u).unwrap();
            f.update(z).unwrap();
        }
        // Make particle 3 dominate so that every new particle is a copy of it.
        for (i, p) in f.particles.iter_mut().enumerate() {
            p.log_weight = if i == 3 { 0.0 } else { -1e3 };
        }
        f.best = 3;
        f.resample().unwrap();
        assert!(f
            .particles
            .windows(2)
            .all(|w| w[0].map.tree().ptr_eq(w[1].map.tree())));
        let before = snapshot(&f);
        let key = before[0][0].0;
        f.particles[0].map.update(key, |l| {
            l.mean.x += 1.0;
            l.cov *= 2.0;
            l.existence += 5;
        });
        let after = snapshot(&f);
        assert_ne!(after[0], before[0]);
        assert_eq!(&after[1..], &before[1..]);
        // A whole measurement update of particle 5 alone (new and existing landmarks).
        let ctx = StepContext {
            config: &f.config,
            ln_p0: f.config.p0.ln(),
            update_index: 99,
        };
        let z: Vec<Obs> = data[0]
            .1
            .iter()
            .map(|z| Obs {
                z: z.to_vector(),
                raw: *z,
            })
            .collect();
        let mut p5 = f.particles[5].clone();
        p5.update_fastslam1(&ctx, &z);
        f.particles[5] = p5;
        let after2 = snapshot(&f);
        assert_ne!(after2[5], after[5]);
        for i in (0..8).filter(|&i| i != 5) {
            assert_eq!(after2[i], after[i], "particle {i} changed");
        }
    }

    /// The landmark cap: once a map could pass `max_landmarks`, the update is refused with
    /// the bound named, and the filter is left exactly as it was (maps, pose, step count).
    #[test]
    fn landmark_cap_refuses_the_update_and_changes_nothing() {
        let (data, _) = world(1, 40, false);
        let max = 6;
        let cfg = FastSlamConfig {
            max_landmarks: max,
            ..config(Variant::FastSlam2, 4)
        };
        let mut f = FastSlam::new(cfg, Pose2::IDENTITY, 3).unwrap();
        let mut refused = false;
        for (u, z) in &data {
            f.predict(u).unwrap();
            let (before, updates, pose) = (snapshot(&f), f.updates, f.pose());
            match f.update(z) {
                Ok(_) => assert!(f.particles.iter().all(|p| p.map.len() <= max)),
                Err(e) => {
                    let largest = before.iter().map(Vec::len).max().unwrap();
                    assert!(largest + z.len() > max, "refused below the cap: {e}");
                    assert!(e.to_string().contains("max-landmarks = 6"), "{e}");
                    assert_eq!(snapshot(&f), before);
                    assert_eq!((f.updates, f.pose()), (updates, pose));
                    refused = true;
                    break;
                }
            }
        }
        assert!(
            refused,
            "the world has more than {max} landmarks in view over the run"
        );
        let bad = FastSlamConfig {
            max_landmarks: MAX_LANDMARKS + 1,
            ..FastSlamConfig::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("max-landmarks"));
    }

    /// Bit-identical results on a rayon pool of 1 thread and one of 2 threads, for both
    /// variants, under hidden ids, clutter, negative evidence and resampling.
    #[cfg(feature = "parallel")]
    #[test]
    fn identical_output_for_one_and_two_threads() {
        let (data, _) = world(4, 120, true);
        for variant in [Variant::FastSlam1, Variant::FastSlam2] {
            let go = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| {
                    let mut f = FastSlam::new(config(variant, 48), Pose2::IDENTITY, 3).unwrap();
                    let mut resampled = 0;
                    let mut removed = 0;
                    let mut poses = Vec::new();
                    for (u, z) in &data {
                        f.predict(u).unwrap();
                        let info = f.update(z).unwrap();
                        resampled += info.resampled as usize;
                        removed += info.removed;
                        poses.push(f.pose());
                    }
                    poses.extend(f.full_path().unwrap());
                    let cloud: Vec<(Pose2, u64)> = f
                        .particles
                        .iter()
                        .map(|p| (p.pose, p.log_weight.to_bits()))
                        .collect();
                    (
                        poses,
                        f.landmarks(),
                        cloud,
                        snapshot(&f),
                        resampled,
                        removed,
                    )
                })
            };
            let (a, b) = (go(1), go(2));
            assert!(a.4 > 0, "{variant:?}: resampling not exercised");
            assert!(a.5 > 0, "{variant:?}: landmark removal not exercised");
            assert_eq!(a, b, "{variant:?}");
        }
    }

    /// Every particle's path holds the initial pose and one pose per update, ends at the
    /// particle's pose, and the best particle's path is the full-SLAM estimate; the
    /// flattened tree gives back the same paths.
    #[test]
    fn paths_have_one_pose_per_update_and_end_at_the_particles() {
        let (data, _) = world(3, 60, false);
        let start = Pose2::new(0.5, -0.25, 0.1);
        for variant in [Variant::FastSlam1, Variant::FastSlam2] {
            let mut f = FastSlam::new(config(variant, 12), start, 8).unwrap();
            let mut online = Vec::new();
            let mut resampled = 0;
            for (u, z) in &data {
                f.predict(u).unwrap();
                resampled += f.update(z).unwrap().resampled as usize;
                online.push(f.pose());
            }
            assert!(resampled > 0, "{variant:?}");
            let best = f.full_path().unwrap();
            assert_eq!(best.len(), data.len() + 1);
            assert_eq!((best[0], best[data.len()]), (start, f.pose()));
            let tree = f.particle_paths().unwrap();
            assert_eq!(tree.path_of(tree.best), best);
            let maps = f.particle_landmarks().unwrap();
            assert_eq!(maps.len(), f.particles.len());
            assert_eq!(maps[tree.best], f.landmarks());
            for (k, p) in f.particles.iter().enumerate() {
                let path = tree.path_of(k);
                assert_eq!(path, p.path());
                assert_eq!(path.len(), data.len() + 1);
                assert_eq!(path[data.len()], p.pose);
            }
            // The full-SLAM path is not the online one: the best particle changed lineage
            // at least once (otherwise this test would not tell the two apart).
            assert_ne!(&best[1..], &online[..], "{variant:?}");
        }
    }

    /// The path tree frees dead branches: after many resamplings every live node lies on
    /// some particle's path (none leaked), and the live nodes are far fewer than the nodes
    /// ever made (1 + M·T): the shared trunk (≤ T + 1) plus the branches since the last
    /// common ancestor, a few dozen steps deep for each of the M particles.
    #[test]
    fn dead_path_branches_are_freed() {
        let steps = 400;
        let m = 20;
        let (data, _) = world(5, steps, false);
        let mut f = FastSlam::new(config(Variant::FastSlam2, m), Pose2::IDENTITY, 4).unwrap();
        let mut made: Vec<std::sync::Weak<PathNode>> = Vec::new();
        let mut resampled = 0;
        for (u, z) in &data {
            f.predict(u).unwrap();
            resampled += f.update(z).unwrap().resampled as usize;
            for p in &f.particles {
                let w = std::sync::Arc::downgrade(&p.path);
                if !made.iter().rev().take(m).any(|o| o.ptr_eq(&w)) {
                    made.push(w);
                }
            }
        }
        assert!(resampled > 50, "only {resampled} resamplings");
        let live = made.iter().filter(|w| w.strong_count() > 0).count() + 1; // + the root
        let reachable = f.particle_paths().unwrap().nodes.len();
        assert_eq!(live, reachable);
        let bound = (steps + 1) + m * 30;
        assert!(
            live <= bound,
            "{live} live nodes > {bound} (made {})",
            1 + m * steps
        );
    }

    /// The weighted mean and covariance of the cloud match a direct computation.
    #[test]
    fn mean_pose_and_covariance() {
        let mut f = FastSlam::new(config(Variant::FastSlam1, 3), Pose2::IDENTITY, 1).unwrap();
        let poses = [
            Pose2::new(1.0, 0.0, 3.1),
            Pose2::new(2.0, 1.0, -3.1),
            Pose2::new(3.0, 2.0, 3.1),
        ];
        let w = [0.5f64, 0.25, 0.25];
        for ((p, q), wi) in f.particles.iter_mut().zip(poses).zip(w) {
            p.pose = q;
            p.log_weight = wi.ln();
        }
        let (m, c) = f.mean_pose();
        assert!((m.x - 1.75).abs() < 1e-12 && (m.y - 0.75).abs() < 1e-12);
        // Headings ±3.1 average across ±π, not to 0.
        assert!((m.theta.abs() - 3.1).abs() < 0.06);
        let var_x = 0.5 * 0.75f64.powi(2) + 0.25 * 0.25f64.powi(2) + 0.25 * 1.25f64.powi(2);
        assert!((c[(0, 0)] - var_x).abs() < 1e-12);
        assert!(c[(2, 2)] < 0.01);
    }

    #[test]
    fn rejects_non_finite_input_and_bad_config() {
        let mut f = FastSlam::new(config(Variant::FastSlam2, 2), Pose2::IDENTITY, 1).unwrap();
        let bad = RangeBearing {
            range: f64::NAN,
            bearing: 0.0,
            id: None,
        };
        assert!(f.update(&[bad]).is_err());
        let u = Control::Odometry(OdometryControl {
            rot1: f64::INFINITY,
            trans: 0.0,
            rot2: 0.0,
        });
        assert!(f.predict(&u).is_err());
        assert!(FastSlam::new(config(Variant::FastSlam2, 0), Pose2::IDENTITY, 1).is_err());
        let p = Pose2 {
            x: f64::NAN,
            y: 0.0,
            theta: 0.0,
        };
        assert!(FastSlam::new(config(Variant::FastSlam2, 2), p, 1).is_err());
        // A negative range (as in the Freiburg data) is skipped, not an error.
        let neg = RangeBearing {
            range: -0.03,
            bearing: 0.9,
            id: Some(LandmarkId(7)),
        };
        let info = f.update(&[neg]).unwrap();
        assert_eq!((info.rejected, info.new_landmarks), (1, 0));
        let _ = Association::Auto;
    }

    /// FastSLAM 2.0 with one particle on the synthetic circle ends close to the truth and
    /// maps every landmark once (known ids).
    #[test]
    fn single_particle_fastslam2_tracks_the_circle() {
        let (data, lms) = world(7, 252, false);
        let mut f = FastSlam::new(config(Variant::FastSlam2, 1), Pose2::IDENTITY, 5).unwrap();
        let mut dr = Pose2::IDENTITY;
        let mut truth = Pose2::IDENTITY;
        for (u, z) in &data {
            f.predict(u).unwrap();
            f.update(z).unwrap();
            dr = f.config.motion.predict(&dr, u);
            truth = truth.compose(&Pose2::new(
                0.2 * 0.0125f64.cos(),
                0.2 * 0.0125f64.sin(),
                0.025,
            ));
        }
        let err = f.pose().distance(&truth);
        assert!(
            err < 0.3,
            "final error {err} (dead reckoning {})",
            dr.distance(&truth)
        );
        for e in f.landmarks() {
            assert!((e.mean - lms[e.id.0 as usize]).norm() < 0.6);
        }
    }
}
