//! slam-ekf + slam-fastslam + slam-sim: the simulator's `loop` through EKF-SLAM behind
//! `Box<dyn LandmarkSlam>`, or FastSLAM 2.0 by changing the one line that builds the
//! filter (`filter_swap fastslam2` takes the other arm), or by a config file
//! (`filter_swap --config FILE`: its `filter` key picks the filter, its other keys are that
//! filter's config, e.g. tests/downstream/configs/*.toml), scored against the simulator's
//! true poses and landmarks. Only these three crates' re-exports are used (and `toml` to
//! read the file).
use slam_ekf::prelude::*;
use slam_ekf::{EkfConfig, EkfSlam};
use slam_fastslam::{FastSlam, FastSlamConfig, Variant};
use slam_sim::scenario::{generate, ScenarioOptions};
use slam_sim::SimOutput;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let which = std::env::args().nth(1).unwrap_or_else(|| "ekf".into());
    let SimOutput::Landmark(sim) = generate("loop", &ScenarioOptions::default())? else {
        return Err("loop is a landmark scenario".into());
    };
    // The filters assume the noise models the data was simulated with (slam-sim's rule).
    let noise = sim.noise_models();
    let mut ekf = EkfConfig::default();
    noise.apply_to(&mut ekf.motion, &mut ekf.sensor, false, false);
    let mut fastslam2 = FastSlamConfig {
        variant: Variant::FastSlam2,
        ..FastSlamConfig::default()
    };
    noise.apply_to(&mut fastslam2.motion, &mut fastslam2.sensor, false, false);
    let start = sim.dataset.initial_pose;
    // The one line that picks the filter; nothing below depends on which.
    let mut filter: Box<dyn LandmarkSlam> = match which.as_str() {
        "--config" => from_file(std::env::args().nth(2).ok_or("--config FILE")?, &sim)?,
        "fastslam2" => Box::new(FastSlam::new(fastslam2, start, 0)?),
        _ => Box::new(EkfSlam::new(ekf, start, 0)?),
    };
    let mut online = Vec::new();
    for step in &sim.dataset.steps {
        filter.predict(&step.control)?;
        filter.update(&step.observations)?;
        online.push(filter.pose());
    }
    // The run's answer: the full-SLAM path where the filter keeps one (FastSLAM; entry 0 is
    // the initial pose), else the online estimates (the EKF).
    let answer = filter.full_path().map_or(online, |p| p[1..].to_vec());
    // Dead reckoning (the controls composed by the motion model's mean) is the reference a
    // filter must beat.
    let mut dead = start;
    let (mut sq, mut sq_dead) = (0.0, 0.0);
    for ((step, truth), p) in sim.dataset.steps.iter().zip(&sim.true_poses).zip(&answer) {
        dead = sim.motion.predict(&dead, &step.control);
        sq += (p.x - truth.x).powi(2) + (p.y - truth.y).powi(2);
        sq_dead += (dead.x - truth.x).powi(2) + (dead.y - truth.y).powi(2);
    }
    let n = sim.true_poses.len() as f64;
    let (rmse, rmse_dead) = ((sq / n).sqrt(), (sq_dead / n).sqrt());
    // Each mapped landmark against the true one of the same id (the loop keeps ids).
    let truth = sim.dataset.landmarks.as_deref().unwrap_or_default();
    let mapped = filter.landmarks();
    let worst = mapped
        .iter()
        .map(|l| {
            let (_, t) = truth.iter().find(|(id, _)| *id == l.id).expect("a true id");
            (l.mean - t).norm()
        })
        .fold(0.0, f64::max);
    println!(
        "{}: {} steps, position RMSE {rmse:.3} m (dead reckoning {rmse_dead:.3} m), \
         {} landmarks, worst {worst:.3} m off",
        filter.name(),
        sim.true_poses.len(),
        mapped.len()
    );
    // Both filters must beat dead reckoning and map every true landmark (the loop has 50,
    // all seen) within 0.5 m; a filter that lost the loop fails both.
    assert!(
        rmse < rmse_dead,
        "position RMSE {rmse} m, dead reckoning {rmse_dead} m"
    );
    assert!(
        mapped.len() == truth.len() && worst < 0.5,
        "{} landmarks, worst {worst} m",
        mapped.len()
    );
    Ok(())
}

/// The filter a config file names: `filter = "ekf" | "fastslam1" | "fastslam2"` and that
/// filter's own keys (kebab-case, unknown keys refused by the filter's config), with the
/// simulator's noise models applied as for the built-in arms.
fn from_file(
    path: String,
    sim: &slam_sim::LandmarkSimRun,
) -> Result<Box<dyn LandmarkSlam>, Box<dyn std::error::Error>> {
    let mut table: toml::Table = std::fs::read_to_string(&path)?.parse()?;
    let kind = match table.remove("filter") {
        Some(toml::Value::String(s)) => s,
        _ => return Err(format!("{path}: a `filter = \"...\"` key is required").into()),
    };
    let noise = sim.noise_models();
    let start = sim.dataset.initial_pose;
    Ok(match kind.as_str() {
        "ekf" => {
            let mut c: EkfConfig = table.try_into()?;
            noise.apply_to(&mut c.motion, &mut c.sensor, false, false);
            Box::new(EkfSlam::new(c, start, 0)?)
        }
        "fastslam1" | "fastslam2" => {
            let mut c: FastSlamConfig = table.try_into()?;
            c.variant = if kind == "fastslam1" {
                Variant::FastSlam1
            } else {
                Variant::FastSlam2
            };
            noise.apply_to(&mut c.motion, &mut c.sensor, false, false);
            Box::new(FastSlam::new(c, start, 0)?)
        }
        other => return Err(format!("{path}: unknown filter {other:?}").into()),
    })
}
