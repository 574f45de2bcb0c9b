//! The FastSLAM sweep of the README: FastSLAM 1.0 and 2.0 with 1, 10 and 100 particles on the
//! simulated `loop` (ids known) and `clutter` (ids hidden, detection 0.9, one false alarm per
//! scan) scenarios, several seeds each.
//!
//! ```text
//! cargo run --release --example fastslam_sweep -- [seeds]
//! ```
//!
//! Per cell: final position error (m) and the landmark map error of the best particle's map
//! (`slam_eval::metrics::landmark_error`: by id under known ids, otherwise nearest neighbour
//! within 1 m; RMSE over the matched pairs, unaligned since the simulated frame is anchored
//! at the known initial pose), means over the seeds, with dead reckoning for scale.
//! "Spurious" estimates matched no true landmark (persisting clutter or duplicates).

use slam_eval::metrics::landmark_error;
use slam_fastslam::{Association, FastSlam, FastSlamConfig, Variant};
use slam_models::{LandmarkEstimate, LandmarkSlam, Pose2};
use slam_sim::scenario::{generate, ScenarioOptions};
use slam_sim::{LandmarkSimRun, SimOutput};
use std::time::Instant;

fn scenario(name: &str, seed: u64) -> LandmarkSimRun {
    match generate(
        name,
        &ScenarioOptions {
            seed,
            ..Default::default()
        },
    ) {
        Ok(SimOutput::Landmark(r)) => r,
        _ => panic!("{name} is a landmark scenario"),
    }
}

/// Config matching the simulated noise, with negative evidence from the sensor's footprint.
fn config(run: &LandmarkSimRun, variant: Variant, particles: usize) -> FastSlamConfig {
    FastSlamConfig {
        variant,
        particles,
        motion: run.motion,
        sensor: run.sensor,
        association: Association::Auto,
        max_range: Some(run.sensor_config.max_range),
        fov: Some(run.sensor_config.fov),
        p0: std::env::var("P0")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(FastSlamConfig::default().p0),
        ..Default::default()
    }
}

fn run_filter(
    run: &LandmarkSimRun,
    cfg: FastSlamConfig,
    seed: u64,
) -> (Pose2, Vec<LandmarkEstimate>) {
    let mut f = FastSlam::new(cfg, run.dataset.initial_pose, seed).expect("valid config");
    let done = slam_eval::run_landmarks(&mut f, &run.dataset, &Default::default())
        .expect("finite simulated data");
    (f.pose(), done.landmarks)
}

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(5);
    println!("| scenario | filter | M | final pose error (m) | landmark RMSE (m) | landmarks (true) | matched | spurious | ms/step |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for name in ["loop", "clutter"] {
        let runs: Vec<LandmarkSimRun> = (0..seeds).map(|s| scenario(name, s)).collect();
        let truth_n = runs[0].dataset.landmarks.as_ref().map_or(0, |l| l.len());
        // Dead reckoning for scale.
        let mut dr = 0.0;
        for r in &runs {
            let mut p = r.dataset.initial_pose;
            for s in &r.dataset.steps {
                p = r.motion.predict(&p, &s.control);
            }
            dr += p.distance(r.true_poses.last().expect("steps"));
        }
        println!(
            "| {name} | dead reckoning | – | {:.3} | – | – | – | – | – |",
            dr / seeds as f64
        );
        for variant in [Variant::FastSlam1, Variant::FastSlam2] {
            for m in [1usize, 10, 100] {
                let (mut pe, mut le, mut nl, mut sp, mut mt, mut steps) =
                    (0.0, 0.0, 0.0, 0.0, 0.0, 0usize);
                let t0 = Instant::now();
                for (k, r) in runs.iter().enumerate() {
                    let (pose, lms) = run_filter(r, config(r, variant, m), 100 + k as u64);
                    pe += pose.distance(r.true_poses.last().expect("steps"));
                    let truth = r.dataset.landmarks.as_deref().unwrap_or(&[]);
                    let e = landmark_error(&lms, truth, name == "loop");
                    le += e.rmse;
                    nl += lms.len() as f64;
                    sp += e.spurious as f64;
                    mt += e.matched as f64;
                    steps += r.dataset.steps.len();
                }
                let ms = t0.elapsed().as_secs_f64() * 1e3 / steps as f64;
                let k = seeds as f64;
                let v = if variant == Variant::FastSlam1 {
                    "FastSLAM 1.0"
                } else {
                    "FastSLAM 2.0"
                };
                println!(
                    "| {name} | {v} | {m} | {:.3} | {:.3} | {:.1} ({truth_n}) | {:.1} | {:.1} | {ms:.3} |",
                    pe / k,
                    le / k,
                    nl / k,
                    mt / k,
                    sp / k
                );
            }
        }
    }
}
