//! Simulator → EKF-SLAM behind `Box<dyn LandmarkSlam>`, or FastSLAM 2.0 with one word changed.
use slam::ekf::{EkfConfig, EkfSlam};
use slam::fastslam::{FastSlam, FastSlamConfig, Variant};
use slam::prelude::*;
use slam::sim::{scenario::generate, SimOutput};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // A simulated loop with 50 landmarks and exact ground truth (seed 0).
    let SimOutput::Landmark(run) = generate("loop", &Default::default())? else {
        return Err("loop is a landmark scenario".into());
    };
    // Both filters use the noise models the data was simulated with.
    let (mut ekf, mut fast) = (EkfConfig::default(), FastSlamConfig::default());
    (ekf.motion, ekf.sensor) = (run.motion, run.sensor);
    (fast.variant, fast.motion, fast.sensor) = (Variant::FastSlam2, run.motion, run.sensor);
    // `cargo run --example landmarks -- fastslam2` swaps the filter; nothing else changes.
    let start = run.dataset.initial_pose;
    let mut filter: Box<dyn LandmarkSlam> = match std::env::args().nth(1).as_deref() {
        Some("fastslam2") => Box::new(FastSlam::new(fast, start, 0)?),
        _ => Box::new(EkfSlam::new(ekf, start, 0)?),
    };
    let mut squared = 0.0;
    for (step, truth) in run.dataset.steps.iter().zip(&run.true_poses) {
        filter.predict(&step.control)?;
        filter.update(&step.observations)?;
        let e = filter.pose().between(truth);
        squared += e.x * e.x + e.y * e.y;
    }
    let ate = (squared / run.true_poses.len() as f64).sqrt();
    println!(
        "{}: {} landmarks, ATE {ate:.3} m",
        filter.name(),
        filter.landmarks().len()
    );
    Ok(())
}
