//! The command line, as clap types. This module only describes the arguments; the
//! subcommands live in [`crate::run`], [`crate::sim`], [`crate::eval`] and `list`.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{ArgGroup, Args, Parser, Subcommand};
use std::ffi::OsStr;
use std::path::PathBuf;

/// `slam`: run 2-D SLAM filters on simulated worlds and real logs, and score the results.
#[derive(Debug, Parser)]
#[command(
    name = "slam",
    // The package version and the commit it was built from (build.rs; "unknown" outside
    // a git checkout), so a bug report names the exact source.
    version = concat!(env!("CARGO_PKG_VERSION"), " (commit ", env!("SLAM_GIT_COMMIT"), ")"),
    about = "2-D SLAM (EKF-SLAM, FastSLAM 1.0/2.0, grid FastSLAM, scan matching) on simulated worlds and real logs",
    long_about = None,
    propagate_version = true
)]
pub struct Cli {
    /// The subcommand.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
// The run options make `Run` large; a command is parsed once per process, so boxing it
// would buy nothing.
#[allow(clippy::large_enum_variant)]
pub enum Command {
    /// Run one filter on a simulated scenario or a dataset; write trajectory, map, picture and metrics.
    Run(RunArgs),
    /// Write a simulated dataset (Freiburg files or a CARMEN log) with its ground truth.
    Sim(SimArgs),
    /// Score a TUM trajectory against ground truth (ATE, RPE) or Kümmerle relations.
    Eval(EvalArgs),
    /// Optimise a pose graph (g2o file); write the result, its χ² and a before/after picture.
    Optimize(OptimizeArgs),
    /// Localize a log on a saved map (Monte Carlo localization); write trajectory, picture and metrics.
    Localize(crate::localize::LocalizeArgs),
    /// Run a laser filter as a ROS 2 node (scans and odometry in; map, map → odom, pose out) until Ctrl-C.
    Ros2(crate::ros2::Ros2Args),
    /// List the filters and scenarios.
    List,
    /// Say what a dataset holds (a ROS bag's topics, counts, laser and odometry; a log's records).
    Info(InfoArgs),
    /// Print a shell completion script (e.g. `slam completions bash > ~/.local/share/bash-completion/completions/slam`).
    Completions(CompletionsArgs),
}

/// `slam completions`.
#[derive(Debug, Clone, Args)]
pub struct CompletionsArgs {
    /// The shell to write the completion script for.
    #[arg(value_name = "SHELL")]
    pub shell: clap_complete::Shell,
}

/// `slam info`.
#[derive(Debug, Clone, Args)]
pub struct InfoArgs {
    /// The dataset: a ROS bag (.mcap, .db3, ROS 1 .bag, rosbag2 folder), a CARMEN log, a Freiburg or MRCLAM folder.
    #[arg(value_name = "PATH")]
    pub path: PathBuf,
}

/// `slam optimize`.
#[derive(Debug, Clone, Args)]
pub struct OptimizeArgs {
    /// The pose graph, g2o format (VERTEX_SE2, VERTEX_XY, EDGE_SE2, EDGE_SE2_XY, FIX) or TORO's
    /// (VERTEX2, EDGE2, EQUIV); a file of edges only is initialised along its odometry.
    #[arg(value_name = "GRAPH.g2o")]
    pub graph: PathBuf,

    /// Output folder: optimized.g2o, result.json, graph.png, config.toml.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,

    /// Optimiser configuration, a TOML file (see configs/graph.toml); unknown keys are an error.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,

    /// Robust kernel, overriding the config file: none, huber:DELTA, cauchy:C or dcs:PHI.
    #[arg(long, value_name = "KERNEL")]
    pub kernel: Option<String>,
}

/// `slam run`.
#[derive(Debug, Clone, Args)]
#[command(group(ArgGroup::new("input").required(true).args(["sim", "dataset"])))]
pub struct RunArgs {
    /// Filter to run (see `slam list`): ekf, fastslam1, fastslam2, graph, scanmatch, known-poses, gridfast.
    #[arg(long, value_name = "NAME", value_parser = filter_names())]
    pub filter: String,

    /// Simulated scenario to run on (see `slam list`); `replay:<map.yaml>` replays a ROS map.
    #[arg(long, value_name = "SCENARIO", value_parser = ScenarioName)]
    pub sim: Option<String>,

    /// Seed of the simulator and of the filter's random numbers (same seed, same output).
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub seed: u64,

    /// Number of simulated steps (the scenario's own length when not given); exactly this
    /// many, or an error saying why not. Only with --sim.
    #[arg(long, value_name = "N", requires = "sim", conflicts_with = "dataset", value_parser = clap::value_parser!(u64).range(1..))]
    pub steps: Option<u64>,

    /// Number of landmarks of a landmark scenario (`loop`, `figure8`, `clutter`, `city`),
    /// instead of its own. Only with --sim.
    #[arg(long, value_name = "N", requires = "sim", conflicts_with = "dataset")]
    pub landmarks: Option<usize>,

    /// Laps of a closed-loop scenario when --steps is not given (0–10,000; default 1.1 for
    /// the landmark loops, 2 for `office`). Only with --sim.
    #[arg(
        long,
        value_name = "LAPS",
        requires = "sim",
        conflicts_with = "dataset"
    )]
    pub laps: Option<f64>,

    /// Dataset: a Freiburg folder (world.dat + sensor_data.dat), a CARMEN log (.log, .clf,
    /// .gz), an MRCLAM folder (with --robot), or a ROS bag (an .mcap or .db3 file, a folder
    /// with metadata.yaml, or a ROS 1 .bag file).
    #[arg(long, value_name = "PATH")]
    pub dataset: Option<PathBuf>,

    /// Robot number 1–5 for MRCLAM datasets.
    #[arg(long, value_name = "N", requires = "dataset")]
    pub robot: Option<u32>,

    /// ROS bags: the sensor_msgs/msg/LaserScan topic (needed when there are several).
    #[arg(long, value_name = "TOPIC", requires = "dataset")]
    pub scan_topic: Option<String>,

    /// ROS bags: the nav_msgs/msg/Odometry topic, or /tf for the odom → base transform.
    #[arg(long, value_name = "TOPIC", requires = "dataset")]
    pub odom_topic: Option<String>,

    /// ROS bags: the odometry frame of the /tf odometry chain (default odom).
    #[arg(long, value_name = "FRAME", requires = "dataset")]
    pub odom_frame: Option<String>,

    /// ROS bags: the robot's base frame of the /tf odometry chain (needed when several
    /// transforms leave the odometry frame, e.g. odom → base_footprint and odom → base_link).
    #[arg(long, value_name = "FRAME", requires = "dataset")]
    pub base_frame: Option<String>,
    /// Laser data: `none` makes the odometry from the scans (laser odometry: each scan
    /// matched against the map of those before it) instead of using the recording's; a
    /// recording without odometry gets it anyway.
    #[arg(long, value_name = "SOURCE", value_parser = ["recorded", "none"])]
    pub odometry: Option<String>,

    /// ROS bags: a sensor_msgs/msg/Imu topic whose yaw rate (angular_velocity.z) is the
    /// rotation prior of laser odometry (recordings without odometry, --odometry none).
    #[arg(long, value_name = "TOPIC", requires = "dataset")]
    pub imu_topic: Option<String>,

    /// ROS bags: the laser's pose in the robot's base frame, `x,y,theta` (metres,
    /// radians); replaces /tf_static.
    #[arg(long, value_name = "X,Y,THETA", requires = "dataset", value_parser = laser_pose, allow_hyphen_values = true)]
    pub laser_pose: Option<slam_io::Pose2>,

    /// known-poses: the poses to write the scans at, a TUM file (instead of the log's
    /// odometry). Each scan takes the pose nearest in time within 5 ms, in file order
    /// (scans sharing a time take that time's poses in order); a scan without one is an
    /// error; odometry-only records are dropped.
    #[arg(long, value_name = "FILE.tum", requires = "dataset")]
    pub poses: Option<PathBuf>,

    /// Number of particles (particle filters only); overrides the config file.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub particles: Option<u64>,

    /// Filter configuration, a TOML file (see configs/FILTER.toml); unknown keys are an error.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,

    /// gridfast: the environment its scale-dependent settings are for (cell size, endpoint
    /// model, search windows; docs/gridfast.md); overrides the config file's `preset`.
    /// `auto` chooses from the first scan.
    #[arg(long, value_name = "PRESET", value_parser = ["auto", "indoor", "outdoor"])]
    pub preset: Option<String>,

    /// Ground-truth trajectory (TUM) to score against, instead of the dataset's own.
    #[arg(long, value_name = "FILE")]
    pub ground_truth: Option<PathBuf>,

    /// Kümmerle et al. relations file to score the trajectory with.
    #[arg(long, value_name = "FILE")]
    pub relations: Option<PathBuf>,

    /// Output folder (default ./slam-out/FILTER-DATASET): a new or empty folder, or one an
    /// earlier `slam run` wrote (its files are replaced).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,

    /// Write into a non-empty --out that slam run did not make: the files slam run writes
    /// are replaced there, all others are left alone. Also lets --mcap replace an MCAP file
    /// slam did not write.
    #[arg(long)]
    pub force: bool,

    /// Laser filters: write the map re-rendered at this cell size in metres (e.g. 0.01)
    /// from the best trajectory and every scan, instead of the filter's own grid (gridfast).
    #[arg(long, value_name = "METRES", value_parser = positive_metres)]
    pub map_resolution: Option<f64>,

    /// Worker threads for the parallel parts of a filter (results do not depend on it).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..=1024))]
    pub threads: Option<u64>,

    /// Landmark filters: write one picture every --frame-every steps (and after the last)
    /// into this new or empty folder, numbered `frame-000001.png`, `frame-000002.png`, …, to
    /// make an animation of the run (e.g. `ffmpeg -framerate 10 -i DIR/frame-%06d.png
    /// run.mp4`). Every frame has the same window and size.
    #[arg(long, value_name = "DIR")]
    pub frames: Option<PathBuf>,

    /// With --frames: steps between two frames.
    #[arg(long, value_name = "K", default_value_t = 10, requires = "frames",
          value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    pub frame_every: u64,

    /// Also write the run as an MCAP file of ROS 2 messages (map, trajectory, poses, tf,
    /// scans, particles, landmarks; see docs/rosbag.md), for Foxglove or `ros2 bag play`.
    /// Not an input nor inside an input folder or --out; an existing MCAP file slam wrote is
    /// replaced, another MCAP file only with --force.
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,

    /// With --mcap: steps between two snapshots of the trajectory, map and landmarks
    /// (default: about 100 snapshots per run).
    #[arg(long, value_name = "K", requires = "mcap",
          value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    pub mcap_every: Option<u64>,

    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,

    /// Laser filters: serve the run to Foxglove over its WebSocket protocol on ADDRESS
    /// (default 127.0.0.1:8765) while it happens (docs/ros2.md).
    #[arg(long, value_name = "ADDRESS", num_args = 0..=1, default_missing_value = slam_ros::live::DEFAULT_ADDRESS)]
    pub live: Option<String>,

    /// With --live: after the run, keep serving its last state until Ctrl-C.
    #[arg(long, requires = "live")]
    pub live_hold: bool,
}

/// `slam sim`.
#[derive(Debug, Clone, Args)]
pub struct SimArgs {
    /// Scenario (see `slam list`); `replay:<map.yaml>` replays a ROS map_server map.
    #[arg(value_name = "SCENARIO", value_parser = ScenarioName)]
    pub scenario: String,

    /// Seed of the simulator.
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub seed: u64,

    /// Number of steps, scans for laser scenarios (the scenario's own length when not
    /// given); exactly this many, or an error saying why not.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub steps: Option<u64>,

    /// Output folder: a new or empty folder, or one an earlier `slam sim` wrote (its files
    /// are replaced); never a folder holding anything else.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

/// `slam eval`. ATE "as is" compares the positions in the frames the files give (no
/// anchoring; `slam run` anchors a laser run's ground truth at the first common pose before
/// its ATE), "aligned" after the least-squares SE(2) alignment.
#[derive(Debug, Clone, Args)]
#[command(group(ArgGroup::new("reference").required(true).multiple(true).args(["ground_truth", "relations"])))]
pub struct EvalArgs {
    /// The estimated trajectory, TUM format.
    #[arg(long, value_name = "FILE")]
    pub estimate: PathBuf,

    /// Ground-truth trajectory, TUM format: gives ATE (as is and aligned) and RPE.
    #[arg(long, value_name = "FILE")]
    pub ground_truth: Option<PathBuf>,

    /// Kümmerle et al. relations file: gives the relations metric.
    #[arg(long, value_name = "FILE")]
    pub relations: Option<PathBuf>,
}

/// `x,y,theta`: three finite numbers, |x|, |y| ≤ 100 m (a sensor on a robot), |θ| ≤ 2π.
fn laser_pose(s: &str) -> Result<slam_io::Pose2, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected x,y,theta (three numbers), found {s:?}"))?;
    match v.as_slice() {
        [x, y, th] if x.abs() <= 100.0 && y.abs() <= 100.0 && th.abs() <= std::f64::consts::TAU => {
            Ok(slam_io::Pose2::new(*x, *y, *th))
        }
        [_, _, _] => Err(format!(
            "expected |x|, |y| ≤ 100 m and |theta| ≤ 2π rad (finite), found {s:?}"
        )),
        _ => Err(format!("expected x,y,theta (three numbers), found {s:?}")),
    }
}

/// A cell size in metres: a finite number > 0 (and ≥ 1 mm, so that a map stays a
/// reasonable size).
fn positive_metres(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .parse()
        .map_err(|_| format!("`{s}` is not a number of metres"))?;
    if v.is_finite() && v >= 0.001 {
        Ok(v)
    } else {
        Err(format!("`{s}`: expected a cell size of at least 0.001 m"))
    }
}

/// `--filter`: one of the factory's filter names, so clap lists them, suggests the nearest
/// for a typo and completes them.
fn filter_names() -> PossibleValuesParser {
    // One name may serve both kinds of data (`graph`): list it once.
    let mut names: Vec<&'static str> = Vec::new();
    for f in slam_eval::factory::filters() {
        if !names.contains(&f.name) {
            names.push(f.name);
        }
    }
    PossibleValuesParser::new(names.into_iter().map(PossibleValue::new))
}

/// A scenario name (`--sim`, `slam sim`): one of slam-sim's scenarios, or `replay:<map>`
/// whose map path is checked when the scenario is built. Clap lists the names, suggests
/// the nearest for a typo and completes them.
#[derive(Debug, Clone, Copy)]
struct ScenarioName;

impl ScenarioName {
    /// The scenario names; `replay` is shown as the form it takes, `replay:<map.yaml>`.
    fn values() -> impl Iterator<Item = PossibleValue> {
        slam_sim::scenario::list().into_iter().map(|s| {
            if s.name == "replay" {
                PossibleValue::new("replay:<map.yaml>")
            } else {
                PossibleValue::new(s.name)
            }
        })
    }
}

impl TypedValueParser for ScenarioName {
    type Value = String;

    fn parse_ref(
        &self,
        cmd: &clap::Command,
        arg: Option<&clap::Arg>,
        value: &OsStr,
    ) -> Result<String, clap::Error> {
        match value.to_str() {
            Some(s) if s.starts_with("replay:") => Ok(s.to_string()),
            _ => PossibleValuesParser::new(Self::values()).parse_ref(cmd, arg, value),
        }
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(Self::values()))
    }
}
