//! Pose NEES of EKF-SLAM on the simulated `loop`, averaged over Monte Carlo runs, with its
//! two-sided 95 % chi-square band, written as a PNG.
//!
//! ```text
//! cargo run --release --example ekf_nees -- [out.png] [runs]
//! ```
//!
//! Each run draws a new world and noise (seed = run index), runs [`slam_ekf::EkfSlam`]
//! with the simulator's own motion and sensor models and known ids, and records
//! ε = (x − x̂)ᵀ P⁻¹ (x − x̂) (heading difference normalised) after every step. For a
//! consistent filter the average over R runs satisfies R·ε̄ ~ χ²(3R), so ε̄ should stay in
//! [χ²⁻¹(0.025), χ²⁻¹(0.975)]/R (Bar-Shalom et al. 2001, §5.4.2). The plot shows ε̄ per
//! step (blue) and the band (shaded); the printed summary gives the share of steps inside
//! it over the first lap and the whole run.

use slam_ekf::{EkfConfig, EkfSlam};
use slam_eval::metrics::chi2_band;
use slam_sim::scenario::{generate, ScenarioOptions};
use slam_sim::SimOutput;
use slam_viz::picture::{plot_series, Series, BLUE};
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(args.next().unwrap_or_else(|| "ekf_nees.png".into()));
    let runs: usize = match args.next() {
        Some(s) => s.parse()?,
        None => 50,
    };
    if runs == 0 {
        return Err("runs must be at least 1".into());
    }
    let mut avg: Vec<f64> = Vec::new();
    for seed in 0..runs as u64 {
        let opts = ScenarioOptions {
            seed,
            ..ScenarioOptions::default()
        };
        let SimOutput::Landmark(r) = generate("loop", &opts)? else {
            return Err("loop is not a landmark scenario".into());
        };
        let config = EkfConfig {
            motion: r.motion,
            sensor: r.sensor,
            ..EkfConfig::default()
        };
        let mut ekf = EkfSlam::new(config, r.dataset.initial_pose, 0)?;
        // slam-eval's run gives each step's pose NEES against the simulator's true pose.
        let run = slam_eval::run_landmarks(&mut ekf, &r.dataset, &Default::default())?;
        for (k, row) in run.estimates.iter().enumerate() {
            let e = row
                .nees
                .ok_or("the simulator has a true pose at every step")?;
            if avg.len() <= k {
                avg.push(0.0);
            }
            avg[k] += e / runs as f64;
        }
    }
    let (lo, hi) = chi2_band(3, runs, 0.95);
    let x: Vec<f64> = (1..=avg.len()).map(|k| k as f64).collect();
    plot_series(
        &out,
        &x,
        &[Series {
            y: &avg,
            colour: BLUE,
        }],
        Some((lo, hi)),
    )?;
    // The loop path is ≈ 60.6 m long, driven at 0.2 m per step.
    let lap = ((60.6f64 / 0.2) as usize).min(avg.len());
    let inside = |s: &[f64]| s.iter().filter(|&&e| e >= lo && e <= hi).count();
    println!(
        "{runs} runs of loop, {} steps: 95% band [{lo:.3}, {hi:.3}]; first lap {}/{lap} steps inside \
         (mean {:.3}); whole run {}/{} inside (mean {:.3}); wrote {}",
        avg.len(),
        inside(&avg[..lap]),
        avg[..lap].iter().sum::<f64>() / lap as f64,
        inside(&avg),
        avg.len(),
        avg.iter().sum::<f64>() / avg.len() as f64,
        out.display()
    );
    Ok(())
}
