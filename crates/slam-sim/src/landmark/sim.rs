//! The landmark simulation loop.

use super::{LandmarkWorld, RangeBearingSensor};
use crate::error::{check_range, check_steps, SimError};
use crate::path::{Follower, FollowerConfig, Path};
use crate::rng::{stream, tag};
use crate::LandmarkSimRun;
use serde::{Deserialize, Serialize};
use slam_models::measurement::RangeBearingModel;
use slam_models::motion::{MotionModel, MotionModels};
use slam_models::{Control, LandmarkDataset, LandmarkStep, TimedPose};

/// Which kind of control the simulated robot reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ControlKind {
    /// [`Control::Odometry`] (δrot1, δtrans, δrot2), the default.
    #[default]
    Odometry,
    /// [`Control::Velocity`] (v, ω, Δt).
    Velocity,
}

/// Everything a landmark simulation needs besides the world, the path and the seed.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct LandmarkSimConfig {
    /// Dataset name.
    pub name: String,
    /// Number of steps (one control and one scan each).
    pub steps: usize,
    /// The controller that steers the true robot along the path.
    pub follower: FollowerConfig,
    /// Which control the data reports.
    pub control: ControlKind,
    /// The motion noise model reported with the data (what a filter should use).
    pub motion: MotionModels,
    /// The model the motion noise is actually drawn from, when it differs from `motion`
    /// (a deliberately mismatched filter model); `None` = `motion`.
    pub true_motion: Option<MotionModels>,
    /// The sensor (its `noise` is the model reported with the data).
    pub sensor: RangeBearingSensor,
    /// The sensor noise actually drawn, when it differs from `sensor.noise`; `None` = same.
    pub true_sensor_noise: Option<RangeBearingModel>,
}

impl Default for LandmarkSimConfig {
    /// 500 steps of the default follower (0.2 m, 0.2 s each), odometry controls with
    /// α = (0.005, 0.0002, 0.005, 0.0002) (≈ 7 % of each motion component as one standard
    /// deviation), the default [`RangeBearingSensor`], no mismatch.
    fn default() -> Self {
        let mut motion = MotionModels::default();
        motion.odometry.alpha = [0.005, 0.0002, 0.005, 0.0002];
        Self {
            name: "landmark-sim".into(),
            steps: 500,
            follower: FollowerConfig::default(),
            control: ControlKind::Odometry,
            motion,
            true_motion: None,
            sensor: RangeBearingSensor::default(),
            true_sensor_noise: None,
        }
    }
}

/// Checks that every α of a motion model is finite and non-negative.
fn validate_motion(m: &MotionModels) -> Result<(), SimError> {
    for a in m.odometry.alpha.iter().chain(m.velocity.alpha.iter()) {
        check_range("motion alpha", *a, 0.0, 1e3, "0 <= alpha <= 1000")?;
    }
    Ok(())
}

/// Drives the robot along `path` for `cfg.steps` steps (fewer if the follower's carrot
/// reaches the end of an open path first)
/// and records the dataset, with all randomness from `seed`.
///
/// Each step k: the follower commands u = (v, ω, Δt) from the true pose x_{k−1}; with
/// velocity controls the true pose is x_k ~ p(x_k | u, x_{k−1}) drawn by the velocity
/// model's sampler (PR table 5.3) and u is reported; with odometry controls the intended
/// motion g(u, x_{k−1}) is converted to an odometry increment ū (PR table 5.5), ū is
/// reported, and x_k ~ p(x_k | ū, x_{k−1}) is drawn by the odometry sampler (PR table 5.6).
/// So the reported control and the truth are related exactly by the motion model the data
/// reports (unless `true_motion` says otherwise). The sensor then scans from x_k.
///
/// The dataset's `initial_pose` is the true start pose x₀ (the start of the path);
/// `ground_truth` holds x_k at t_k = k·Δt for k = 1..=steps, matching the step times.
pub fn simulate_landmarks(
    world: &LandmarkWorld,
    path: &Path,
    cfg: &LandmarkSimConfig,
    seed: u64,
) -> Result<LandmarkSimRun, SimError> {
    cfg.sensor.validate()?;
    check_steps("steps", cfg.steps)?;
    validate_motion(&cfg.motion)?;
    let gen_motion = cfg.true_motion.unwrap_or(cfg.motion);
    validate_motion(&gen_motion)?;
    let mut gen_sensor = cfg.sensor.clone();
    if let Some(noise) = cfg.true_sensor_noise {
        gen_sensor.noise = noise;
        gen_sensor.validate()?;
    }
    let mut follower = Follower::new(path, cfg.follower.clone())?;
    let mut motion_rng = stream(seed, tag::MOTION);
    let mut sensor_rng = stream(seed, tag::SENSOR);
    let mut clutter_rng = stream(seed, tag::CLUTTER);

    let start = path.start_pose();
    let mut pose = start;
    let mut steps = Vec::with_capacity(cfg.steps);
    let mut true_poses = Vec::with_capacity(cfg.steps);
    let mut is_clutter = Vec::with_capacity(cfg.steps);
    let mut gt = Vec::with_capacity(cfg.steps);
    let (mut scratch, mut obs) = (Vec::new(), Vec::new());
    for k in 1..=cfg.steps {
        // An open path is done when the carrot has reached its end.
        if follower.finished() {
            break;
        }
        let cmd = follower.command(&pose);
        let (control, next) = match cfg.control {
            ControlKind::Velocity => (
                Control::Velocity(cmd),
                gen_motion.velocity.sample(&pose, &cmd, &mut motion_rng),
            ),
            ControlKind::Odometry => {
                let intended = gen_motion.velocity.predict(&pose, &cmd);
                let u = gen_motion.odometry.control_from_poses(&pose, &intended);
                (
                    Control::Odometry(u),
                    gen_motion.odometry.sample(&pose, &u, &mut motion_rng),
                )
            }
        };
        pose = next;
        gen_sensor.observe(
            &pose,
            world,
            &mut sensor_rng,
            &mut clutter_rng,
            &mut scratch,
            &mut obs,
        );
        let t = k as f64 * cfg.follower.dt;
        steps.push(LandmarkStep {
            t,
            control,
            observations: obs.iter().map(|(z, _)| *z).collect(),
        });
        is_clutter.push(obs.iter().map(|(_, c)| *c).collect());
        true_poses.push(pose);
        gt.push(TimedPose { t, pose });
    }
    Ok(LandmarkSimRun {
        dataset: LandmarkDataset {
            name: cfg.name.clone(),
            initial_pose: start,
            steps,
            landmarks: Some(world.landmarks().to_vec()),
            ground_truth: Some(gt),
        },
        true_poses,
        is_clutter,
        motion: cfg.motion,
        sensor: cfg.sensor.noise,
        true_motion: gen_motion,
        true_sensor: gen_sensor.noise,
        sensor_config: cfg.sensor.clone(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::{LandmarkId, Point2};

    #[test]
    fn open_path_ends_the_run_and_bad_models_are_rejected() {
        let path = Path::new(vec![Point2::new(0.0, 0.0), Point2::new(10.0, 0.0)], false).unwrap();
        let world = LandmarkWorld::new(vec![(LandmarkId(0), Point2::new(5.0, 2.0))], 6.0).unwrap();
        let cfg = LandmarkSimConfig {
            steps: 1000,
            ..Default::default()
        };
        let run = simulate_landmarks(&world, &path, &cfg, 1).unwrap();
        // 10 m at 0.2 m per step: the carrot reaches the end after 50 steps.
        assert_eq!(run.dataset.steps.len(), 50);
        assert_eq!(run.dataset.ground_truth.as_ref().unwrap().len(), 50);
        assert!(run.true_poses.last().unwrap().x > 8.0);
        let mut bad = LandmarkSimConfig::default();
        bad.motion.odometry.alpha[0] = f64::NAN;
        assert!(simulate_landmarks(&world, &path, &bad, 1).is_err());
    }
}
