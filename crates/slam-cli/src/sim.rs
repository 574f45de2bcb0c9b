//! `slam sim`: writes a simulated dataset in the formats the readers take, with its ground
//! truth, so that `slam run --dataset` can replay it.
//!
//! * Landmark scenarios → a Freiburg course folder: `world.dat` (the true landmarks),
//!   `sensor_data.dat`, and the sidecars `initial_pose.dat`, `times.dat` and
//!   `ground_truth.tum` (written by `slam_io::freiburg::write_freiburg`).
//! * Laser scenarios → a CARMEN log `<scenario>.log` and `ground_truth.tum`.
//!
//! `replay:<map.yaml>` (or `replay:<map.pgm>` with its YAML beside it) reads a ROS
//! map_server map and drives through its free space.
//!
//! The folder is new, empty, or one an earlier `slam sim` marked as its own (`.slam-sim`,
//! whose listed files are replaced, so no sidecar of an earlier scenario is left); a folder
//! holding anything else, a dataset above all, is refused (see `outdir`). `--steps` is
//! exact: a scenario that ends sooner is an error saying so.

use crate::cli::SimArgs;
use crate::error::CliError;
use crate::outdir::{OutDir, Owner};
use slam_eval::input::{generate_exact, replay_map, scenario_options};
use slam_sim::SimOutput;
use std::io::Write;
use std::path::{Path, PathBuf};

/// What `slam sim` wrote.
#[derive(Debug, Clone)]
pub struct SimReport {
    /// The output folder.
    pub out_dir: PathBuf,
    /// The path to pass to `slam run --dataset`.
    pub dataset_path: PathBuf,
    /// The ground-truth trajectory file.
    pub ground_truth: PathBuf,
    /// `"landmark"` or `"laser"`.
    pub kind: &'static str,
    /// Steps (landmark) or records (laser) written.
    pub steps: usize,
}

/// Runs `slam sim` with `args`, printing what was written to `out`.
pub fn sim(args: &SimArgs, out: &mut dyn Write) -> Result<SimReport, CliError> {
    let mut inputs: Vec<(&str, &Path)> = Vec::new();
    if let Some(map) = replay_map(&args.scenario) {
        inputs.push(("replay map", map));
    }
    let (name, opts) = scenario_options(&args.scenario, args.seed, args.steps.map(|s| s as usize))?;
    let staging = OutDir::prepare(&args.out, Owner::Sim, false, &inputs)?;
    let output = generate_exact(&name, &opts)?;
    let dir = &args.out;
    let stage = staging.stage();
    let gt_path = dir.join("ground_truth.tum");
    let report = match output {
        SimOutput::Landmark(run) => {
            slam_io::freiburg::write_freiburg(stage, &run.dataset)?;
            let d = &run.dataset;
            let obs: usize = d.steps.iter().map(|s| s.observations.len()).sum();
            let _ = writeln!(
                out,
                "wrote {name} (seed {}): {} steps, {obs} observations, {} landmarks as Freiburg course data in {}",
                args.seed,
                d.steps.len(),
                d.landmarks.as_ref().map_or(0, Vec::len),
                dir.display()
            );
            SimReport {
                out_dir: dir.clone(),
                dataset_path: dir.clone(),
                ground_truth: gt_path,
                kind: "landmark",
                steps: d.steps.len(),
            }
        }
        SimOutput::Laser(run) => {
            let log = dir.join(format!("{name}.log"));
            slam_io::carmen::write_carmen(&stage.join(format!("{name}.log")), &run.dataset)?;
            let d = &run.dataset;
            let gt = d.ground_truth.as_deref().unwrap_or_default();
            slam_io::tum::write_tum(&stage.join("ground_truth.tum"), gt)?;
            let scans = d.records.iter().filter(|r| r.scan.is_some()).count();
            let _ = writeln!(
                out,
                "wrote {name} (seed {}): {} records, {scans} scans as a CARMEN log {}",
                args.seed,
                d.records.len(),
                log.display()
            );
            SimReport {
                out_dir: dir.clone(),
                dataset_path: log,
                ground_truth: gt_path,
                kind: "laser",
                steps: d.records.len(),
            }
        }
    };
    if crate::stop_requested() {
        return Err(CliError::Interrupted {
            step: report.steps,
            steps: report.steps,
        });
    }
    staging.commit(&[])?;
    let run_hint = if report.kind == "landmark" {
        // The Freiburg reader picks up ground_truth.tum from the folder by itself.
        format!(
            "slam run --filter fastslam2 --dataset {}",
            report.dataset_path.display()
        )
    } else {
        format!(
            "slam run --filter gridfast --dataset {} --ground-truth {}",
            report.dataset_path.display(),
            report.ground_truth.display()
        )
    };
    let _ = writeln!(
        out,
        "ground truth: {}\nrun a filter on it: {run_hint}",
        report.ground_truth.display(),
    );
    Ok(report)
}
