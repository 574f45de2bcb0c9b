//! Simulator → EKF-SLAM behind `Box<dyn LandmarkSlam>`, or FastSLAM 2.0 with one word changed.
use slam::eval::{run_landmarks, FilterConfig, RunOptions};
use slam::prelude::*;
use slam::sim::{scenario::generate, SimOutput};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // A simulated loop with 50 landmarks and exact ground truth (seed 0).
    let SimOutput::Landmark(sim) = generate("loop", &Default::default())? else {
        return Err("loop is a landmark scenario".into());
    };
    // The filter is a configuration: `filter = "fastslam2"` swaps it, nothing else changes
    // (`cargo run --example landmarks -- fastslam2` does that).
    let name = std::env::args().nth(1).unwrap_or("ekf".into());
    let mut config = FilterConfig::from_toml(&format!("filter = \"{name}\""))?;
    // The filter assumes the noise models the data was simulated with.
    config.apply_sim_noise(&sim.noise_models());
    let start = sim.dataset.initial_pose;
    let mut filter: Box<dyn LandmarkSlam> = config.config.build_landmark(start, 0)?;
    // Every step (predict, update), scored against the simulator's ground truth.
    let run = run_landmarks(filter.as_mut(), &sim.dataset, &RunOptions::default())?;
    let m = &run.metrics;
    println!(
        "{}: {} landmarks, ATE {:.3} m, {:.0} % of steps' NEES in the 95 % band",
        m.filter,
        run.landmarks.len(),
        m.ate_rmse_m.unwrap_or(f64::NAN),
        100.0 * m.nees_pose_in_band_fraction.unwrap_or(f64::NAN),
    );
    Ok(())
}
