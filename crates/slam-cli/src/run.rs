//! `slam run`: one filter over one input (a simulated scenario or a dataset), then the
//! outputs and the metrics.
//!
//! * Landmark filters: `predict` with each step's control, `update` with its observations;
//!   the pose after the update is the online estimate at the step's time. `trajectory.tum`
//!   is the filter's full-SLAM path where it has one ([`LandmarkSlam::full_path`]: FastSLAM's
//!   best particle at the end, whose map is `landmarks.csv`), with the online estimates in
//!   `trajectory-online.tum`; for the EKF, a filter, `trajectory.tum` is the online
//!   estimates. `estimates.csv` holds the per-step Gaussian pose summary, covariance and
//!   NEES ([`slam_io::estimates_csv`]). Outputs: `trajectory.tum`
//!   [, `trajectory-online.tum`], `estimates.csv`, `landmarks.csv`, `map.png`,
//!   `config.toml`, `metrics.json`.
//! * Laser filters: `process` on every record in file order; the trajectory is the filter's
//!   own, one pose per record. Outputs: `trajectory.tum`, `map.pgm` + `map.yaml`, `map.png`,
//!   `config.toml`, `metrics.json`.
//!
//! Simulated runs also write the simulator's `ground_truth.tum`, so that both files can be
//! handed to `evo` (docs/evaluation.md).
//!
//! Only the filter loop is timed (`wall_s`); reading the data and writing the outputs are not.
//!
//! Every option and the output folder are checked before the data is loaded; the outputs
//! are staged and renamed into place with `metrics.json` last (see `outdir`), and Ctrl-C
//! stops the run between steps with nothing written.

use crate::cli::RunArgs;
use crate::error::CliError;
use crate::filters::{self, DataKind, FilterInfo, Setup};
use crate::mcap::McapRecorder;
use crate::metrics::{self, Metrics};
use crate::outdir::{OutDir, Owner};
use crate::pictures;
use crate::progress::Progress;
use crate::sim::{generate_exact, replay_map, scenario_options};
use slam_io::estimates_csv::PoseEstimateRow;
use slam_io::eval;
use slam_io::Dataset;
use slam_models::measurement::RangeBearingModel;
use slam_models::motion::MotionModels;
use slam_models::{LandmarkDataset, LandmarkSlam, LandmarkStep, ScanDataset, TimedPose};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What `slam run` did.
#[derive(Debug, Clone)]
pub struct RunReport {
    /// The output folder.
    pub out_dir: PathBuf,
    /// The metrics written to `metrics.json`.
    pub metrics: Metrics,
    /// The one-line description of the input.
    pub input: String,
    /// The files written, in order.
    pub files: Vec<PathBuf>,
}

/// What a run loop hands back.
struct Finished {
    metrics: Metrics,
    files: Vec<PathBuf>,
    /// Extra summary lines.
    notes: Vec<String>,
}

/// The data a run works on.
enum Data {
    Landmark {
        dataset: LandmarkDataset,
        /// The simulator's noise models (simulated runs only).
        sim_models: Option<(MotionModels, RangeBearingModel)>,
    },
    Laser(ScanDataset),
}

/// The input of a run, loaded.
struct Input {
    /// Name for `metrics.json` and the default output folder.
    name: String,
    /// What the user gave (`--sim loop`, a path), for messages.
    label: String,
    /// One line: what was found.
    description: String,
    /// False when the data's times are step indices, not a clock (Freiburg course data).
    has_clock: bool,
    /// Made by the simulator (its ground truth is written beside the trajectory).
    simulated: bool,
    data: Data,
}

impl Input {
    fn kind(&self) -> DataKind {
        match self.data {
            Data::Landmark { .. } => DataKind::Landmark,
            Data::Laser(_) => DataKind::Laser,
        }
    }
}

/// Runs `slam run` with `args`, printing a short summary to `out`.
pub fn run(args: &RunArgs, out: &mut dyn Write) -> Result<RunReport, CliError> {
    let info = filters::find(&args.filter)?;
    // A name that serves both kinds (`graph`): the kind-specific checks run once the data
    // has picked the filter.
    let both = filters::serves_both_kinds(&args.filter);
    if let Some(why) = info.unavailable {
        return Err(CliError::FilterUnavailable {
            name: info.name.to_string(),
            reason: why.to_string(),
        });
    }
    if args.frames.is_some() && info.kind != DataKind::Landmark && !both {
        return Err(CliError::InvalidArgument(format!(
            "--frames applies to landmark filters (ekf, fastslam1, fastslam2); `{}` maps a grid",
            info.name
        )));
    }
    if args.map_resolution.is_some() && info.kind != DataKind::Laser && !both {
        return Err(CliError::InvalidArgument(format!(
            "--map-resolution applies to laser filters (gridfast); `{}` maps landmarks",
            info.name
        )));
    }
    filters::check_particles(&info, args.particles.is_some())?;
    // Fail on a missing config file before loading a possibly large dataset.
    if let Some(c) = &args.config {
        if !c.is_file() {
            return Err(CliError::Read {
                path: c.clone(),
                source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
            });
        }
    }
    // A bad configuration fails before the data is loaded: the filter is built once on a
    // placeholder start (the real one, with the data's initial pose and a simulation's
    // noise models, is built in the run).
    let placeholder = Setup {
        config_path: args.config.as_deref(),
        particles: args.particles.map(|p| p as usize),
        seed: args.seed,
        initial_pose: slam_models::Pose2::default(),
        sim_models: None,
    };
    match info.kind {
        _ if both => {}
        DataKind::Landmark => drop(filters::build_landmark(&info, &placeholder)?),
        DataKind::Laser => drop(filters::build_scan(&info, &placeholder)?),
    }
    // The small inputs are read, and the output folder checked, before the data is loaded.
    let ground_truth = match &args.ground_truth {
        Some(p) => Some(slam_io::tum::read_tum(p)?),
        None => None,
    };
    let relations = match &args.relations {
        Some(p) => Some(slam_io::relations::read_relations(p)?),
        None => None,
    };
    let out_dir = args.out.clone().unwrap_or_else(|| {
        PathBuf::from("slam-out").join(format!("{}-{}", info.name, file_safe(&default_name(args))))
    });
    let mut inputs: Vec<(&str, &Path)> = Vec::new();
    for (option, path) in [
        ("--dataset", &args.dataset),
        ("--ground-truth", &args.ground_truth),
        ("--relations", &args.relations),
        ("--config", &args.config),
    ] {
        if let Some(p) = path {
            inputs.push((option, p.as_path()));
        }
    }
    if let Some(map) = args.sim.as_deref().and_then(replay_map) {
        inputs.push(("--sim replay map", map));
    }
    if let Some(mcap) = &args.mcap {
        crate::mcap::check_path(mcap, &inputs, &out_dir)?;
    }
    let staging = OutDir::prepare(&out_dir, Owner::Run, args.force, &inputs)?;
    let mut input = load_input(args)?;
    let _ = writeln!(out, "input: {}", input.description);
    let info = filters::find_for(info.name, input.kind()).unwrap_or(info);
    if both {
        let wrong = |option: &str, kind: DataKind| {
            CliError::InvalidArgument(format!(
                "{option} does not apply to `{}` on {} data",
                info.name,
                kind.as_str()
            ))
        };
        if args.frames.is_some() && info.kind != DataKind::Landmark {
            return Err(wrong("--frames", info.kind));
        }
        if args.map_resolution.is_some() && info.kind != DataKind::Laser {
            return Err(wrong("--map-resolution", info.kind));
        }
    }
    if input.kind() != info.kind {
        return Err(CliError::WrongDataKind {
            filter: info.name.to_string(),
            needs: info.kind.as_str(),
            input: input.label.clone(),
            found: input.kind().as_str(),
            suggest: filters::names_of(input.kind()),
        });
    }
    if crate::stop_requested() {
        return Err(CliError::Interrupted { step: 0, steps: 0 });
    }
    let ctx = RunContext {
        info,
        args,
        stage: staging.stage(),
        ground_truth,
        relations,
        simulated: input.simulated,
    };
    let threads = args.threads.map(|t| t as usize);
    let run = |input: &mut Input| -> Result<Finished, CliError> {
        match &mut input.data {
            Data::Landmark {
                dataset,
                sim_models,
            } => run_landmark(&ctx, &input.name, input.has_clock, dataset, *sim_models),
            Data::Laser(dataset) => run_scan(&ctx, &input.name, input.has_clock, dataset),
        }
    };
    let Finished {
        metrics,
        files,
        notes,
    } = match threads {
        Some(n) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| CliError::Threads {
                    threads: n,
                    message: e.to_string(),
                })?;
            pool.install(|| run(&mut input))?
        }
        None => run(&mut input)?,
    };
    if crate::stop_requested() {
        return Err(CliError::Interrupted {
            step: metrics.steps,
            steps: metrics.steps,
        });
    }
    let order: Vec<String> = files
        .iter()
        .filter_map(|f| f.file_name().map(|n| n.to_string_lossy().to_string()))
        .collect();
    let order: Vec<&str> = order.iter().map(String::as_str).collect();
    let files = staging.commit(&order)?;
    print_summary(out, &metrics, &notes, &out_dir, &files);
    Ok(RunReport {
        out_dir,
        metrics,
        input: input.description,
        files,
    })
}

/// Everything the two run loops share.
struct RunContext<'a> {
    info: FilterInfo,
    args: &'a RunArgs,
    /// Where the outputs are written before they are renamed into the output folder.
    stage: &'a Path,
    /// The input came from the simulator: write its ground truth too.
    simulated: bool,
    /// `--ground-truth`, read.
    ground_truth: Option<Vec<TimedPose>>,
    /// `--relations`, read.
    relations: Option<Vec<slam_io::relations::Relation>>,
}

/// The dataset's name for the default output folder, from the arguments alone (so the
/// folder can be checked before the data is loaded): the scenario, or the dataset's file
/// or folder name without `.gz`/`.log`/`.clf` (with `-robotN` for MRCLAM).
fn default_name(args: &RunArgs) -> String {
    if let Some(spec) = &args.sim {
        return base_name(spec);
    }
    let stem = args
        .dataset
        .as_deref()
        .and_then(Path::file_name)
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "dataset".into());
    let stem = stem
        .trim_end_matches(".gz")
        .trim_end_matches(".log")
        .trim_end_matches(".clf")
        .to_string();
    match args.robot {
        Some(r) => format!("{stem}-robot{r}"),
        None => stem,
    }
}

/// Reads the dataset or generates the scenario.
fn load_input(args: &RunArgs) -> Result<Input, CliError> {
    if let Some(spec) = &args.sim {
        let (name, opts) = scenario_options(spec, args.seed, args.steps)?;
        let output = generate_exact(&name, &opts)?;
        return Ok(match output {
            slam_sim::SimOutput::Landmark(run) => {
                let d = &run.dataset;
                let obs: usize = d.steps.iter().map(|s| s.observations.len()).sum();
                Input {
                    description: format!(
                        "simulated scenario {name} (seed {}): {} steps, {obs} observations, {} true landmarks, ground truth",
                        args.seed,
                        d.steps.len(),
                        d.landmarks.as_ref().map_or(0, Vec::len),
                    ),
                    name: base_name(&name),
                    label: format!("scenario {spec}"),
                    has_clock: true,
                    simulated: true,
                    data: Data::Landmark {
                        dataset: run.dataset,
                        sim_models: Some((run.motion, run.sensor)),
                    },
                }
            }
            slam_sim::SimOutput::Laser(run) => {
                let d = &run.dataset;
                let scans = d.records.iter().filter(|r| r.scan.is_some()).count();
                Input {
                    description: format!(
                        "simulated scenario {name} (seed {}): {} records, {scans} scans, ground truth",
                        args.seed,
                        d.records.len(),
                    ),
                    name: base_name(&name),
                    label: format!("scenario {spec}"),
                    has_clock: true,
                    simulated: true,
                    data: Data::Laser(run.dataset),
                }
            }
        });
    }
    let Some(path) = &args.dataset else {
        return Err(CliError::InvalidArgument(
            "give either --sim <scenario> or --dataset <path>".into(),
        ));
    };
    let options = slam_io::DatasetOptions {
        robot: args.robot,
        scan_topic: args.scan_topic.clone(),
        odom_topic: args.odom_topic.clone(),
        laser_pose: args.laser_pose,
    };
    let (dataset, description) = slam_io::open_dataset_with(path, &options)?;
    let stem = path
        .file_name()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "dataset".into());
    let stem = stem
        .trim_end_matches(".gz")
        .trim_end_matches(".log")
        .trim_end_matches(".clf")
        .trim_end_matches(".mcap")
        .to_string();
    let name_of = |n: &str| {
        if n.is_empty() {
            stem.clone()
        } else {
            n.to_string()
        }
    };
    // Freiburg course data has no clock: its step times are indices, unless the folder
    // carries the `times.dat` sidecar that simulated data is written with.
    let freiburg_without_clock =
        path.join("sensor_data.dat").is_file() && !path.join("times.dat").is_file();
    Ok(match dataset {
        Dataset::Landmark(d) => Input {
            name: name_of(&d.name),
            label: path.display().to_string(),
            description,
            has_clock: !freiburg_without_clock,
            simulated: false,
            data: Data::Landmark {
                dataset: d,
                sim_models: None,
            },
        },
        Dataset::Scan(d) => Input {
            name: name_of(&d.name),
            label: path.display().to_string(),
            description,
            has_clock: true,
            simulated: false,
            data: Data::Laser(d),
        },
    })
}

/// `replay:maps/x.yaml` → `replay`.
fn base_name(spec: &str) -> String {
    spec.split_once(':').map_or(spec, |(b, _)| b).to_string()
}

/// A name usable as part of a folder name.
fn file_safe(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Time span of the data (last time − first, in file order), or `None` when the data has
/// no usable clock: step indices (Freiburg course data), or timestamps so coarse that fewer
/// than a tenth of the steps have distinct times (some GMapping logs printed times as
/// `1.13486e+09`); the latter adds a summary note.
fn data_duration(times: &[f64], has_clock: bool, notes: &mut Vec<String>) -> Option<f64> {
    if !has_clock || times.len() < 2 {
        return None;
    }
    let mut distinct = times.to_vec();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    if distinct.len() < 2 || distinct.len() * 10 < times.len() {
        notes.push(format!(
            "no data duration / real-time factor: timestamps too coarse ({} distinct times for {} steps)",
            distinct.len(),
            times.len()
        ));
        return None;
    }
    Some(times[times.len() - 1] - times[0])
}

fn write_err(path: &Path) -> impl FnOnce(std::io::Error) -> CliError + '_ {
    move |e| CliError::Write {
        path: path.to_path_buf(),
        source: e,
    }
}

fn run_landmark(
    ctx: &RunContext<'_>,
    name: &str,
    has_clock: bool,
    dataset: &LandmarkDataset,
    sim_models: Option<(MotionModels, RangeBearingModel)>,
) -> Result<Finished, CliError> {
    let info = &ctx.info;
    let built = filters::build_landmark(
        info,
        &Setup {
            config_path: ctx.args.config.as_deref(),
            particles: ctx.args.particles.map(|p| p as usize),
            seed: ctx.args.seed,
            initial_pose: dataset.initial_pose,
            sim_models,
        },
    )?;
    let mut filter = built.filter;
    let steps = &dataset.steps;
    let ground_truth = ctx.ground_truth.as_ref().or(dataset.ground_truth.as_ref());
    // NEES needs the true pose at every step: a ground truth with exactly the steps' times.
    let truth_per_step = ground_truth.filter(|g| {
        g.len() == steps.len() && g.iter().zip(steps).all(|(p, s)| (p.t - s.t).abs() < 1e-9)
    });

    let particle_count = filter.particles().map(|p| p.len());
    let seeded = sim_models.is_some() || particle_count.is_some();
    let title = pictures::title(
        info.name,
        name,
        particle_count,
        seeded.then_some(ctx.args.seed),
    );
    let mut frames = match &ctx.args.frames {
        Some(dir) => Some(pictures::Frames::new(
            dir,
            ctx.args.frame_every as usize,
            ground_truth.map(Vec::as_slice),
            dataset.landmarks.as_deref(),
        )?),
        None => None,
    };
    // Drawing frames is output, not filtering: its time is taken off the run's wall time.
    let mut frame_time = std::time::Duration::ZERO;
    let true_landmarks: Option<Vec<slam_models::Point2>> = dataset
        .landmarks
        .as_ref()
        .map(|l| l.iter().map(|(_, p)| *p).collect());
    let mut mcap = McapRecorder::create(ctx.args, steps.len(), true_landmarks.as_deref())?;
    // The odometry frame of the ROS output: the controls' noise-free dead reckoning.
    let odometry = mcap
        .as_ref()
        .map(|_| slam_io::dead_reckoning(dataset))
        .unwrap_or_default();

    let mut online = Vec::with_capacity(steps.len());
    let mut estimates = Vec::with_capacity(steps.len());
    let mut progress = Progress::new(steps.len(), ctx.args.quiet);
    let start = Instant::now();
    for (k, step) in steps.iter().enumerate() {
        if crate::stop_requested() {
            return Err(CliError::Interrupted {
                step: k,
                steps: steps.len(),
            });
        }
        let fail = |source| CliError::FilterStep {
            filter: info.name.to_string(),
            step: k,
            t: step.t,
            source,
        };
        filter.predict(&step.control).map_err(fail)?;
        filter.update(&step.observations).map_err(fail)?;
        online.push(TimedPose {
            t: step.t,
            pose: filter.pose(),
        });
        let (mean, covariance) = filter.pose_gaussian();
        estimates.push(PoseEstimateRow {
            step: k,
            t: step.t,
            pose: mean,
            covariance,
            nees: truth_per_step.map(|truth| eval::nees_pose(&mean, &covariance, &truth[k].pose)),
        });
        if let Some(f) = &mut frames {
            let t0 = Instant::now();
            f.step(
                k,
                steps.len(),
                &title,
                filter.as_ref(),
                &online,
                ground_truth.map(Vec::as_slice),
                dataset.landmarks.as_deref(),
            )?;
            frame_time += t0.elapsed();
        }
        if let Some(r) = &mut mcap {
            r.landmark_step(step.t, odometry.get(k).map(|p| p.pose), filter.as_ref())?;
        }
        progress.set(k + 1);
    }
    // A smoother's last optimisation is part of the run's time.
    filter.finish().map_err(|source| CliError::FilterStep {
        filter: info.name.to_string(),
        step: steps.len(),
        t: steps.last().map_or(0.0, |s| s.t),
        source,
    })?;
    let mcap_time = mcap.as_ref().map(McapRecorder::elapsed).unwrap_or_default();
    let wall = start
        .elapsed()
        .saturating_sub(frame_time)
        .saturating_sub(mcap_time)
        .as_secs_f64();
    progress.finish();
    if let Some(f) = frames {
        f.finish()?;
    }

    // The full-SLAM path (entry 0 the initial pose, entry k the pose after step k, by the
    // LandmarkSlam contract) and the map, both the final best particle's: read together,
    // with no filter call between them.
    let full = full_trajectory(&*filter, steps);
    let landmarks = filter.landmarks();
    let particles = filter.particles();
    let mut m = Metrics::new(info.name, name, steps.len());
    let mut notes = Vec::new();
    let times: Vec<f64> = steps.iter().map(|s| s.t).collect();
    let span = data_duration(&times, has_clock, &mut notes);
    m.set_timing(wall, span);
    let trajectory = full.as_ref().unwrap_or(&online);
    if let Some(gt) = ground_truth {
        trajectory_metrics(&mut m, trajectory, gt);
        let mut o = Metrics::new(info.name, name, steps.len());
        trajectory_metrics(&mut o, &online, gt);
        m.online_ate_rmse_m = o.ate_rmse_m;
        m.online_ate_rmse_aligned_m = o.ate_rmse_aligned_m;
        m.online_rpe_trans_mean_m = o.rpe_trans_mean_m;
        m.online_rpe_rot_mean_deg = o.rpe_rot_mean_deg;
    }
    if let Some(rel) = &ctx.relations {
        notes.push(relations_metrics(&mut m, trajectory, rel));
    }
    if let Some(truth) = &dataset.landmarks {
        let by_id = steps
            .iter()
            .flat_map(|s| &s.observations)
            .any(|o| o.id.is_some());
        if !landmarks.is_empty() && !truth.is_empty() {
            let e = eval::landmark_error(&landmarks, truth, by_id);
            m.landmark_rmse_m = metrics::finite(Some(e.rmse));
            m.landmark_rmse_aligned_m = metrics::finite(Some(e.rmse_aligned));
            notes.push(format!(
                "{} landmarks mapped: {} matched to the {} true ones ({}), {} true ones unmatched, {} spurious",
                landmarks.len(),
                e.matched,
                truth.len(),
                if by_id { "by id" } else { "by nearest neighbour within 1 m" },
                e.unmatched_true,
                e.spurious
            ));
        }
    }
    let nees: Vec<f64> = estimates.iter().filter_map(|e| e.nees).collect();
    if let Some(s) = eval::nees_summary(&nees) {
        m.nees_pose_in_band_fraction = Some(s.in_band_fraction);
        m.nees_pose_median = metrics::finite(Some(s.median));
        m.nees_pose_mean = metrics::finite(Some(s.mean));
    }
    m.peak_rss_mb = metrics::peak_rss_mb();

    let dir = ctx.stage;
    let mut files = Vec::new();
    let p = dir.join("trajectory.tum");
    slam_io::tum::write_tum(&p, trajectory)?;
    files.push(p);
    if full.is_some() {
        let p = dir.join("trajectory-online.tum");
        slam_io::tum::write_tum(&p, &online)?;
        files.push(p);
    }
    let p = dir.join("estimates.csv");
    slam_io::estimates_csv::write_estimates_csv(&p, &estimates)?;
    files.push(p);
    if ctx.simulated {
        if let Some(gt) = &dataset.ground_truth {
            let p = dir.join("ground_truth.tum");
            slam_io::tum::write_tum(&p, gt)?;
            files.push(p);
        }
    }
    if let Some(r) = mcap {
        notes.push(r.finish(
            trajectory,
            None,
            Some(&landmarks),
            ground_truth.map(Vec::as_slice),
        )?);
    }
    let p = dir.join("landmarks.csv");
    slam_io::landmarks_csv::write_landmarks_csv(&p, &landmarks)?;
    files.push(p);
    let poses: Vec<_> = trajectory.iter().map(|t| t.pose).collect();
    let gt_poses: Option<Vec<_>> = ground_truth.map(|g| g.iter().map(|t| t.pose).collect());
    // Particle filters: every particle's path (grey) and landmark means (dots) from the
    // filter's path tree and maps; the estimate is the path written to trajectory.tum.
    // Paths are drawn only while they fit a bounded number of poses (shared history is
    // repeated once per particle when flattened).
    const MAX_DRAWN_POSES: usize = 2_000_000;
    let particle_paths: Vec<Vec<slam_models::Pose2>> = match filter.particle_paths() {
        Some(pp) if pp.leaves.len().saturating_mul(steps.len() + 1) <= MAX_DRAWN_POSES => {
            (0..pp.leaves.len()).map(|k| pp.path_of(k)).collect()
        }
        Some(_) => {
            notes.push(format!(
                "map.png: particle paths not drawn (more than {MAX_DRAWN_POSES} poses)"
            ));
            Vec::new()
        }
        None => Vec::new(),
    };
    let particle_landmarks: Vec<slam_models::Point2> = filter
        .particle_landmarks()
        .map(|maps| maps.iter().flatten().map(|l| l.mean).collect())
        .unwrap_or_default();
    let pic = pictures::landmark_picture(&pictures::LandmarkLayers {
        title,
        estimate: &poses,
        estimate_label: if full.is_some() {
            "best particle's path (full SLAM)"
        } else if particles.is_some() {
            "online estimate (best particle at each step)"
        } else {
            "estimate"
        },
        particle_paths: &particle_paths,
        particle_landmarks: &particle_landmarks,
        landmarks: &landmarks,
        particles: particles.as_deref(),
        ground_truth: gt_poses.as_deref(),
        true_landmarks: dataset.landmarks.as_deref(),
    });
    let p = dir.join("map.png");
    pic.save_png(&p)?;
    files.push(p);
    let p = dir.join("config.toml");
    std::fs::write(&p, &built.config_toml).map_err(write_err(&p))?;
    files.push(p);
    let p = dir.join("metrics.json");
    m.write(&p).map_err(write_err(&p))?;
    files.push(p);
    Ok(Finished {
        metrics: m,
        files,
        notes,
    })
}

/// The filter's full-SLAM path paired with the steps' times: entry k + 1 of
/// [`LandmarkSlam::full_path`] is the pose after step k (entry 0, the initial pose, has no
/// step and is not written). `None` for filters without a path (the EKF), and, with a
/// warning, when the path breaks the one-pose-per-update contract.
fn full_trajectory(filter: &dyn LandmarkSlam, steps: &[LandmarkStep]) -> Option<Vec<TimedPose>> {
    let path = filter.full_path()?;
    if path.len() != steps.len() + 1 {
        eprintln!(
            "slam: warning: filter `{}` returned a path of {} poses for {} steps (the LandmarkSlam contract is the initial pose plus one per step); writing its online estimates instead",
            filter.name(),
            path.len(),
            steps.len()
        );
        return None;
    }
    Some(
        steps
            .iter()
            .zip(&path[1..])
            .map(|(s, &pose)| TimedPose { t: s.t, pose })
            .collect(),
    )
}

fn run_scan(
    ctx: &RunContext<'_>,
    name: &str,
    has_clock: bool,
    dataset: &ScanDataset,
) -> Result<Finished, CliError> {
    let info = &ctx.info;
    let built = filters::build_scan(
        info,
        &Setup {
            config_path: ctx.args.config.as_deref(),
            particles: ctx.args.particles.map(|p| p as usize),
            seed: ctx.args.seed,
            initial_pose: slam_models::Pose2::default(),
            sim_models: None,
        },
    )?;
    let mut filter = built.filter;
    // Ask before the run whether the filter can re-render its map at all.
    let cannot_render = || {
        CliError::InvalidArgument(format!(
            "--map-resolution: filter `{}` keeps no scans to re-render its map from (gridfast does)",
            info.name
        ))
    };
    if let Some(res) = ctx.args.map_resolution {
        filter.render_map(res).ok_or_else(cannot_render)?;
    }
    let records = &dataset.records;
    let mut mcap = McapRecorder::create(ctx.args, records.len(), None)?;
    let mut progress = Progress::new(records.len(), ctx.args.quiet);
    let start = Instant::now();
    // Odometry jumps the filter skipped (only with `odometry_jump.on_jump = "skip"`):
    // how many, and the first record's index and time.
    let (mut jumps, mut first_jump) = (0usize, None);
    for (k, record) in records.iter().enumerate() {
        if crate::stop_requested() {
            return Err(CliError::Interrupted {
                step: k,
                steps: records.len(),
            });
        }
        let step = filter
            .process(record)
            .map_err(|source| CliError::FilterStep {
                filter: info.name.to_string(),
                step: k,
                t: record.t,
                source,
            })?;
        if step.odometry_jumps_skipped > 0 {
            jumps += step.odometry_jumps_skipped;
            first_jump.get_or_insert((k, record.t));
        }
        if let Some(r) = &mut mcap {
            r.scan_step(record, filter.as_ref())?;
        }
        progress.set(k + 1);
    }
    if let Some((k, t)) = first_jump {
        eprintln!(
            "slam: warning: skipped {jumps} odometry jump(s) beyond odometry_jump.max_jump, taken as no motion (first at record {k}, t = {t} s)"
        );
    }
    let trajectory = filter.trajectory();
    // The filter's own map is part of the timed run; a re-rendering (output, not filtering)
    // is made after the clock and the memory peak are read, and replaces it.
    let own_map = ctx.args.map_resolution.is_none().then(|| filter.map());
    // Writing the MCAP file is output, not filtering.
    let mcap_time = mcap.as_ref().map(McapRecorder::elapsed).unwrap_or_default();
    let wall = start.elapsed().saturating_sub(mcap_time).as_secs_f64();
    progress.finish();
    let peak_rss_mb = metrics::peak_rss_mb();
    let map = match own_map {
        Some(map) => map,
        None => ctx
            .args
            .map_resolution
            .and_then(|res| filter.render_map(res))
            .ok_or_else(cannot_render)?,
    };
    let particles = filter.particles();
    if trajectory.len() != records.len() {
        eprintln!(
            "slam: warning: filter `{}` returned {} poses for {} records (the ScanSlam contract is one per record)",
            info.name,
            trajectory.len(),
            records.len()
        );
    }

    let mut m = Metrics::new(info.name, name, records.len());
    let mut notes = Vec::new();
    let times: Vec<f64> = records.iter().map(|r| r.t).collect();
    let span = data_duration(&times, has_clock, &mut notes);
    m.set_timing(wall, span);
    // Laser filters start at the identity pose (ScanSlam takes no initial pose), so the
    // ground truth is re-expressed in the estimate's frame, anchored at their first common
    // pose: "as is" then means "sharing the start frame", as for landmark runs.
    let ground_truth = ctx
        .ground_truth
        .as_ref()
        .or(dataset.ground_truth.as_ref())
        .map(|gt| eval::anchor_at_first_match(&trajectory, gt));
    if let Some(gt) = &ground_truth {
        trajectory_metrics(&mut m, &trajectory, gt);
    }
    if let Some(rel) = &ctx.relations {
        notes.push(relations_metrics(&mut m, &trajectory, rel));
    }
    m.peak_rss_mb = peak_rss_mb;

    let dir = ctx.stage;
    let mut files = Vec::new();
    let p = dir.join("trajectory.tum");
    slam_io::tum::write_tum(&p, &trajectory)?;
    files.push(p);
    if ctx.simulated {
        // The simulator's own frame, not the anchored copy the metrics use.
        if let Some(gt) = &dataset.ground_truth {
            let p = dir.join("ground_truth.tum");
            slam_io::tum::write_tum(&p, gt)?;
            files.push(p);
        }
    }
    if let Some(r) = mcap {
        notes.push(r.finish(&trajectory, Some(&map), None, ground_truth.as_deref())?);
    }
    slam_io::ros_map::write_ros_map(dir, "map", &map)?;
    files.push(dir.join("map.pgm"));
    files.push(dir.join("map.yaml"));
    let poses: Vec<_> = trajectory.iter().map(|t| t.pose).collect();
    let gt_poses: Option<Vec<_>> = ground_truth.map(|g| g.iter().map(|t| t.pose).collect());
    let particle_count = particles.as_ref().map(Vec::len);
    let title = pictures::title(
        info.name,
        name,
        particle_count,
        particle_count.map(|_| ctx.args.seed),
    );
    let pic = pictures::laser_picture(
        title,
        &map,
        &poses,
        gt_poses.as_deref().map(|g| {
            let label = if ctx.ground_truth.is_some() {
                "reference (--ground-truth)"
            } else {
                "ground truth"
            };
            (g, label)
        }),
        particles.as_deref(),
    );
    let p = dir.join("map.png");
    pic.save_png(&p)?;
    files.push(p);
    let p = dir.join("config.toml");
    std::fs::write(&p, &built.config_toml).map_err(write_err(&p))?;
    files.push(p);
    let p = dir.join("metrics.json");
    m.write(&p).map_err(write_err(&p))?;
    files.push(p);
    Ok(Finished {
        metrics: m,
        files,
        notes,
    })
}

/// ATE (as is, aligned) and RPE against a ground-truth trajectory. A metric that cannot be
/// computed (no pose matched in time, …) stays null, with a warning on stderr: the run's
/// outputs are still written.
fn trajectory_metrics(m: &mut Metrics, trajectory: &[TimedPose], gt: &[TimedPose]) {
    crate::eval::warn_stamp_order(trajectory, gt);
    match eval::ate(trajectory, gt) {
        Ok(ate) => {
            m.ate_rmse_m = Some(ate.rmse);
            m.ate_rmse_aligned_m = Some(ate.rmse_aligned);
        }
        Err(e) => eprintln!("slam: warning: no ATE: {e}"),
    }
    match eval::rpe(trajectory, gt) {
        Ok(rpe) => {
            m.rpe_trans_mean_m = Some(rpe.trans_mean);
            m.rpe_rot_mean_deg = Some(rpe.rot_mean_deg);
        }
        Err(e) => eprintln!("slam: warning: no RPE: {e}"),
    }
}

/// The Kümmerle et al. relations metric; returns a line for the summary.
fn relations_metrics(
    m: &mut Metrics,
    trajectory: &[TimedPose],
    relations: &[slam_io::relations::Relation],
) -> String {
    let r = eval::relations_error(trajectory, relations);
    if r.used > 0 {
        m.relations_trans_mean_m = Some(r.trans_mean);
        m.relations_rot_mean_deg = Some(r.rot_mean_deg);
        format!(
            "relations error {:.3} ± {:.3} m / {:.2} ± {:.2} deg ({} relations used, {} without both ends in the trajectory)",
            r.trans_mean, r.trans_std, r.rot_mean_deg, r.rot_std_deg, r.used, r.dropped
        )
    } else {
        let msg = format!(
            "no relations metric: none of the {} relations has both ends in the trajectory (within 6 ms); is it on the same clock?",
            relations.len()
        );
        eprintln!("slam: warning: {msg}");
        msg
    }
}

/// `x` with 3 decimals, or in scientific notation when huge (a diverged NEES).
fn fmt_num(x: f64) -> String {
    if x.abs() >= 1e5 {
        format!("{x:.3e}")
    } else {
        format!("{x:.3}")
    }
}

fn fmt_opt(v: Option<f64>, unit: &str) -> String {
    match v {
        Some(x) => format!("{}{unit}", fmt_num(x)),
        None => "n/a".into(),
    }
}

fn print_summary(
    out: &mut dyn Write,
    m: &Metrics,
    notes: &[String],
    dir: &Path,
    files: &[PathBuf],
) {
    let rtf = m
        .real_time_factor
        .map(|r| format!(", {r:.1}x real time"))
        .unwrap_or_default();
    let _ = writeln!(
        out,
        "{} on {}: {} steps in {} s ({:.0} steps/s{rtf}), peak memory {}",
        m.filter,
        m.dataset,
        m.steps,
        if m.wall_s < 1.0 {
            format!("{:.3}", m.wall_s)
        } else {
            format!("{:.1}", m.wall_s)
        },
        m.steps_per_s.unwrap_or(0.0),
        fmt_opt(m.peak_rss_mb, " MB"),
    );
    if m.ate_rmse_m.is_some() {
        let _ = writeln!(
            out,
            "  ATE {} (aligned {}), RPE {} / {}",
            fmt_opt(m.ate_rmse_m, " m"),
            fmt_opt(m.ate_rmse_aligned_m, " m"),
            fmt_opt(m.rpe_trans_mean_m, " m"),
            fmt_opt(m.rpe_rot_mean_deg, " deg"),
        );
    }
    if m.online_ate_rmse_m.is_some() && m.online_ate_rmse_m != m.ate_rmse_m {
        let _ = writeln!(
            out,
            "  online estimates: ATE {} (aligned {}), RPE {} / {}",
            fmt_opt(m.online_ate_rmse_m, " m"),
            fmt_opt(m.online_ate_rmse_aligned_m, " m"),
            fmt_opt(m.online_rpe_trans_mean_m, " m"),
            fmt_opt(m.online_rpe_rot_mean_deg, " deg"),
        );
    }
    if m.landmark_rmse_m.is_some() {
        let _ = writeln!(
            out,
            "  landmarks RMSE {} (aligned {})",
            fmt_opt(m.landmark_rmse_m, " m"),
            fmt_opt(m.landmark_rmse_aligned_m, " m"),
        );
    }
    if let Some(f) = m.nees_pose_in_band_fraction {
        let _ = writeln!(
            out,
            "  pose NEES: {:.1} % of steps in the 95 % χ²(3) band, median {}, mean {} (consistent: 95 %, 2.366, 3)",
            100.0 * f,
            fmt_opt(m.nees_pose_median, ""),
            fmt_opt(m.nees_pose_mean, ""),
        );
    }
    for note in notes {
        let _ = writeln!(out, "  {note}");
    }
    let names: Vec<String> = files
        .iter()
        .filter_map(|f| f.file_name().map(|n| n.to_string_lossy().to_string()))
        .collect();
    let _ = writeln!(out, "  wrote {}/{{{}}}", dir.display(), names.join(", "));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_duration_needs_a_usable_clock() {
        let mut notes = Vec::new();
        assert_eq!(data_duration(&[1.0, 1.5, 4.0], true, &mut notes), Some(3.0));
        assert_eq!(data_duration(&[1.0, 1.5, 4.0], false, &mut notes), None);
        assert!(notes.is_empty());
        // 3 distinct times for 40 steps: printed with too few digits.
        let coarse: Vec<f64> = (0..40).map(|k| 1.0e9 + (k / 15) as f64 * 1e4).collect();
        assert_eq!(data_duration(&coarse, true, &mut notes), None);
        assert_eq!(notes.len(), 1);
    }
}
