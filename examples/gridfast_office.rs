//! Particles needed on the simulated `office`: the improved proposal against the odometry
//! proposal (issue 8's "fewer particles for the same error" curve).
//!
//! ```text
//! cargo run --release --example gridfast_office -- [--seeds 1,2,3,4,5,6,7,8] [--png docs/img/gridfast-office-particles.png]
//! ```
//!
//! For each proposal, particle count M ∈ {1, 5, 15, 30, 100, 300} and seed, the `office`
//! scenario (seed S, its defaults: two laps of the corridor loop) is run through
//! `GridFastSlam` with filter seed S; the error is the ATE (RMSE of position, m) against the
//! simulator's ground truth, anchored at the first pose as `slam run` does, and after the
//! least-squares SE(2) alignment. The anchored figure also counts a small heading error in
//! the first scans, which turns the whole (consistent) map about the start; the aligned one
//! measures the map's consistency. Prints a Markdown table of the means over seeds and draws
//! the anchored curves on log–log axes (improved in orange, odometry in blue).

use slam_gridfast::{GridFastConfig, GridFastSlam, Pose2, Proposal, ProposalConfig};
use slam_sim::scenario::{generate, ScenarioOptions};
use slam_sim::SimOutput;
use slam_viz::picture::{plot_series_with, Axes, Rgb, Scale, Series};
use std::path::PathBuf;

const PARTICLES: [usize; 6] = [1, 5, 15, 30, 100, 300];

/// ATE (m) of one run: as is after anchoring at the first pose, and after the least-squares
/// SE(2) alignment (which forgives a rotation of the whole map about the start).
fn run(
    proposal: Proposal,
    particles: usize,
    seed: u64,
) -> Result<(f64, f64), Box<dyn std::error::Error>> {
    let opts = ScenarioOptions {
        seed,
        ..ScenarioOptions::default()
    };
    let SimOutput::Laser(sim) = generate("office", &opts)? else {
        return Err("office is a laser scenario".into());
    };
    let config = GridFastConfig {
        proposal: ProposalConfig {
            kind: proposal,
            ..Default::default()
        },
        particles,
        ..GridFastConfig::default()
    };
    let mut slam = GridFastSlam::new(config, Pose2::IDENTITY, seed)?;
    // ATE against the simulator's truth, anchored at the estimate's start (slam-eval).
    let run = slam_eval::run_scans(&mut slam, &sim.dataset, &Default::default())?;
    let m = &run.metrics;
    Ok((
        m.ate_rmse_m.ok_or("office has ground truth")?,
        m.ate_rmse_aligned_m.ok_or("office has ground truth")?,
    ))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut seeds: Vec<u64> = (1..=8).collect();
    let mut png: Option<PathBuf> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut val = || args.next().ok_or_else(|| format!("{a} needs a value"));
        match a.as_str() {
            "--seeds" => {
                seeds = val()?
                    .split(',')
                    .map(str::parse)
                    .collect::<Result<_, _>>()?
            }
            "--png" => png = Some(val()?.into()),
            other => return Err(format!("unknown argument {other}").into()),
        }
    }
    let mut rows = Vec::new();
    for (proposal, name) in [
        (Proposal::Improved, "improved proposal"),
        (Proposal::Odometry, "odometry proposal"),
    ] {
        let (mut means, mut aligned) = (Vec::new(), Vec::new());
        for &m in &PARTICLES {
            let (mut sum, mut sum_aligned) = (0.0, 0.0);
            for &s in &seeds {
                let (e, a) = run(proposal, m, s)?;
                eprintln!("{name}, {m} particles, seed {s}: ATE {e:.3} m (aligned {a:.3} m)");
                sum += e;
                sum_aligned += a;
            }
            means.push(sum / seeds.len() as f64);
            aligned.push(sum_aligned / seeds.len() as f64);
        }
        rows.push((format!("{name}, ATE (m)"), means));
        rows.push((format!("{name}, ATE aligned (m)"), aligned));
    }
    let header: Vec<String> = PARTICLES.iter().map(|m| m.to_string()).collect();
    println!("| particles | {} |", header.join(" | "));
    println!("|---|{}", "---|".repeat(PARTICLES.len()));
    for (name, means) in &rows {
        let cells: Vec<String> = means
            .iter()
            .map(|e| {
                if e.is_finite() {
                    format!("{e:.3}")
                } else {
                    "–".into()
                }
            })
            .collect();
        println!("| {name} | {} |", cells.join(" | "));
    }
    if let Some(p) = png {
        let x: Vec<f64> = PARTICLES.iter().map(|&m| m as f64).collect();
        let series = [
            Series {
                y: &rows[0].1,
                colour: Rgb([230, 120, 20]),
            },
            Series {
                y: &rows[2].1,
                colour: Rgb([40, 90, 200]),
            },
        ];
        let axes = Axes {
            x: Scale::Log10,
            y: Scale::Log10,
        };
        plot_series_with(&p, &x, &series, None, axes)?;
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}
