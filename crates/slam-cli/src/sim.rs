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
use slam_sim::scenario::ScenarioOptions;
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

/// Scenario name and options for a `--sim`/`slam sim` argument: `replay:<map.yaml>` loads the
/// map into the options.
pub(crate) fn scenario_options(
    spec: &str,
    seed: u64,
    steps: Option<u64>,
) -> Result<(String, ScenarioOptions), CliError> {
    let mut opts = ScenarioOptions {
        seed,
        steps: steps.map(|s| s as usize),
        ..Default::default()
    };
    let name = match spec.split_once(':') {
        Some(("replay", map)) => {
            if map.is_empty() {
                return Err(CliError::InvalidArgument(
                    "scenario replay needs a map: replay:<map.yaml> (a ROS map_server YAML)".into(),
                ));
            }
            // A map image is accepted too: its resolution and origin come from the
            // map_server YAML of the same name beside it.
            let mut path = Path::new(map).to_path_buf();
            if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("pgm")) {
                path.set_extension("yaml");
                if !path.exists() {
                    return Err(CliError::InvalidArgument(format!(
                        "replay:{map}: a map image needs its map_server YAML (resolution, origin) \
                         beside it, expected {}",
                        path.display()
                    )));
                }
            }
            opts.replay_map = Some(slam_io::ros_map::read_ros_map(&path)?);
            "replay".to_string()
        }
        Some((other, _)) => {
            return Err(CliError::InvalidArgument(format!(
                "scenario `{spec}`: only `replay` takes an argument (`replay:<map.yaml>`), not `{other}`"
            )))
        }
        None if spec == "replay" => {
            return Err(CliError::InvalidArgument(
                "scenario replay needs a map: replay:<map.yaml> (a ROS map_server YAML)".into(),
            ))
        }
        None => spec.to_string(),
    };
    Ok((name, opts))
}

/// The map file of a `replay:<map>` scenario spec (an input that must not lie in `--out`).
pub(crate) fn replay_map(spec: &str) -> Option<&Path> {
    match spec.split_once(':') {
        Some(("replay", map)) if !map.is_empty() => Some(Path::new(map)),
        _ => None,
    }
}

/// Generates scenario `name`, checking that it has exactly the `steps` asked for (steps for
/// landmark scenarios, scans for laser ones): a scenario whose path ends sooner is an error
/// that says how many it can give.
pub(crate) fn generate_exact(name: &str, opts: &ScenarioOptions) -> Result<SimOutput, CliError> {
    let output = slam_sim::scenario::generate(name, opts)?;
    if let Some(want) = opts.steps {
        let (got, what) = match &output {
            SimOutput::Landmark(run) => (run.dataset.steps.len(), "steps"),
            SimOutput::Laser(run) => (
                run.dataset
                    .records
                    .iter()
                    .filter(|r| r.scan.is_some())
                    .count(),
                "scans",
            ),
        };
        if got != want {
            return Err(CliError::InvalidArgument(format!(
                "--steps {want}: scenario {name} (seed {}) gives {got} {what}, its path ends \
                 there; ask for at most {got}",
                opts.seed
            )));
        }
    }
    Ok(output)
}

/// Runs `slam sim` with `args`, printing what was written to `out`.
pub fn sim(args: &SimArgs, out: &mut dyn Write) -> Result<SimReport, CliError> {
    let mut inputs: Vec<(&str, &Path)> = Vec::new();
    if let Some(map) = replay_map(&args.scenario) {
        inputs.push(("replay map", map));
    }
    let (name, opts) = scenario_options(&args.scenario, args.seed, args.steps)?;
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
