//! The FastSLAM filter: a particle set, adaptive resampling, and the [`LandmarkSlam`]
//! interface.

use crate::config::{FastSlamConfig, Variant};
use crate::error::FastSlamError;
use crate::map::LandmarkMap;
use crate::particle::{estimates, stream, Obs, Particle, ParticleStats, StepContext};
use rayon::prelude::*;
use slam_models::particle::{effective_sample_size_log, normalize_log_weights};
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
            log_weight: -(m as f64).ln(),
            map: LandmarkMap::new(config.index_cell_size),
        };
        Ok(Self {
            particles: vec![proto; m],
            config,
            seed,
            tick: 0,
            pending: None,
            best: 0,
        })
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
        let ctx = StepContext {
            config: &self.config,
            ln_p0: self.config.p0.ln(),
        };
        let (seed, tick) = (self.seed, self.tick);
        let pending = self.pending.take();
        let stats: Vec<ParticleStats> = match self.config.variant {
            Variant::FastSlam1 => self
                .particles
                .par_iter_mut()
                .map(|p| p.update_fastslam1(&ctx, &obs))
                .collect(),
            Variant::FastSlam2 => self
                .particles
                .par_iter_mut()
                .enumerate()
                .map(|(k, p)| {
                    let mut rng = stream(seed, tick, k as u64);
                    p.update_fastslam2(&ctx, pending.as_ref(), &obs, &mut rng)
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
}
