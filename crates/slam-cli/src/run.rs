//! `slam run`: one filter over one input (a simulated scenario or a dataset), then the
//! outputs and the metrics.
//!
//! The filter is built by `slam_eval::factory` and run and scored by
//! [`slam_eval::run_landmarks_observed`] / [`slam_eval::run_scans_observed`]; this module
//! parses nothing and loops over nothing itself: it checks the options, loads the input,
//! hands the run an observer (progress bar, `--frames`, Ctrl-C) and writes the outputs.
//!
//! * Landmark filters: `trajectory.tum` is the filter's full-SLAM path where it has one
//!   (FastSLAM's best particle at the end, whose map is `landmarks.csv`), with the online
//!   estimates in `trajectory-online.tum`; for the EKF, `trajectory.tum` is the online
//!   estimates. `estimates.csv` holds the per-step Gaussian pose summary, covariance and
//!   NEES ([`slam_io::estimates_csv`]). Outputs: `trajectory.tum`
//!   [, `trajectory-online.tum`], `estimates.csv`, `landmarks.csv`, `map.png`,
//!   `config.toml`, `metrics.json`.
//! * Laser filters: the trajectory is the filter's own, one pose per record. Outputs:
//!   `trajectory.tum`, `map.pgm` + `map.yaml`, `map.png`, `config.toml`, `metrics.json`.
//!
//! Simulated runs also write the simulator's `ground_truth.tum`, so that both files can be
//! handed to `evo` (docs/evaluation.md).
//!
//! Only the filter is timed (`wall_s`); reading the data, the observer and writing the
//! outputs are not.
//!
//! Every option and the output folder are checked before the data is loaded; the outputs
//! are staged and renamed into place with `metrics.json` last (see `outdir`), and Ctrl-C
//! stops the run between steps with nothing written.

use crate::cli::RunArgs;
use crate::error::CliError;
use crate::filters::{self, DataKind, FilterInfo, Setup};
use crate::mcap::McapRecorder;
use crate::outdir::{OutDir, Owner};
use crate::pictures;
use crate::progress::Progress;
use slam_eval::input::{self, replay_map, Input, InputData};
use slam_eval::run::{
    run_landmarks_observed, run_scans_observed, Flow, LandmarkProgress, ObserverError, RunError,
    RunOptions, ScanProgress,
};
use slam_eval::Metrics;
use slam_models::{LandmarkDataset, ScanDataset, TimedPose};
use slam_sim::NoiseModels;
use std::io::Write;
use std::path::{Path, PathBuf};

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
    /// `--live`: the view, kept serving until the outputs are in place.
    live: Option<slam_ros::live::RunView>,
}

/// Runs `slam run` with `args`, printing a short summary to `out`.
pub fn run(args: &RunArgs, out: &mut dyn Write) -> Result<RunReport, CliError> {
    let info = filters::find(&args.filter)?;
    // A name that serves both kinds of data (`graph`): the kind-specific checks run once
    // the data has picked the filter.
    let both = slam_eval::factory::serves_both_kinds(&args.filter);
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
    if args.live.is_some() && info.kind != DataKind::Laser && !both {
        return Err(CliError::InvalidArgument(format!(
            "--live applies to laser filters; `{}` maps landmarks",
            info.name
        )));
    }
    filters::check_particles(&info, args.particles.is_some())?;
    if args.poses.is_some() && info.name != "known-poses" {
        return Err(CliError::InvalidArgument(format!(
            "--poses applies to --filter known-poses, not `{}`",
            info.name
        )));
    }
    let given_poses = match &args.poses {
        Some(p) => Some(slam_io::tum::read_tum(p)?),
        None => None,
    };
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
    let placeholder = Setup::of_run(args, slam_models::Pose2::default(), None);
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
        ("--poses", &args.poses),
    ] {
        if let Some(p) = path {
            inputs.push((option, p.as_path()));
        }
    }
    if let Some(map) = args.sim.as_deref().and_then(replay_map) {
        inputs.push(("--sim replay map", map));
    }
    if let Some(mcap) = &args.mcap {
        crate::mcap::check_path(mcap, &inputs, &out_dir, args.force)?;
    }
    // The filter against the kind of data, before anything is generated or read.
    if let Some(kind) = input::kind_before_loading(args.sim.as_deref(), args.dataset.as_deref()) {
        if !both && kind != info.kind {
            return Err(CliError::WrongDataKind {
                filter: info.name.to_string(),
                needs: info.kind.as_str(),
                input: match (&args.sim, &args.dataset) {
                    (Some(spec), _) => format!("scenario {spec}"),
                    (None, Some(path)) => path.display().to_string(),
                    (None, None) => String::new(),
                },
                found: kind.as_str(),
                suggest: filters::names_of(kind),
            });
        }
    }
    let staging = OutDir::prepare(&out_dir, Owner::Run, args.force, &inputs)?;
    let laser_odometry = filters::laser_odometry_config(&info, args.config.as_deref())?;
    let mut input = load_input(args, &laser_odometry)?;
    if let (Some(poses), Some(path)) = (&given_poses, &args.poses) {
        let InputData::Laser(dataset) = &mut input.data else {
            return Err(CliError::InvalidArgument(format!(
                "--poses {}: known-poses maps laser data",
                path.display()
            )));
        };
        dataset.records = crate::poses::apply_poses(&dataset.records, poses, path)?;
    }
    let _ = writeln!(out, "input: {}", input.description);
    let info = slam_eval::factory::find_for(info.name, input.kind()).unwrap_or(info);
    if both {
        let wrong = |option: &str| {
            CliError::InvalidArgument(format!(
                "{option} does not apply to `{}` on {} data",
                info.name,
                info.kind.as_str()
            ))
        };
        if args.frames.is_some() && info.kind != DataKind::Landmark {
            return Err(wrong("--frames"));
        }
        if args.map_resolution.is_some() && info.kind != DataKind::Laser {
            return Err(wrong("--map-resolution"));
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
    let run = |input: &Input| -> Result<Finished, CliError> {
        match &input.data {
            InputData::Landmark { dataset, sim_noise } => {
                run_landmark(&ctx, input, dataset, *sim_noise)
            }
            InputData::Laser(dataset) => run_scan(&ctx, input, dataset),
        }
    };
    let Finished {
        metrics,
        files,
        notes,
        live,
    } = match threads {
        Some(n) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| CliError::Threads {
                    threads: n,
                    message: e.to_string(),
                })?;
            pool.install(|| run(&input))?
        }
        None => run(&input)?,
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
    crate::hold_live(args.live_hold, live.as_ref().map(|v| v.server()));
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
        return input::scenario_base_name(spec);
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

/// Generates the scenario or reads the dataset (slam-eval's [`slam_eval::input`]); the
/// description names the dataset options by their flags. `laser_odometry`: how the odometry
/// is made from the scans, should it be (the config file's `[laser-odometry]` table).
fn load_input(
    args: &RunArgs,
    laser_odometry: &slam_grid::LaserOdometryConfig,
) -> Result<Input, CliError> {
    let mut input = load_input_named_by_option(args, laser_odometry)?;
    input.description = crate::error::with_flags(&input.description);
    Ok(input)
}

fn load_input_named_by_option(
    args: &RunArgs,
    laser_odometry: &slam_grid::LaserOdometryConfig,
) -> Result<Input, CliError> {
    if let Some(spec) = &args.sim {
        let params = input::ScenarioParams {
            landmarks: args.landmarks,
            laps: args.laps,
        };
        let mut input =
            input::simulate_with(spec, args.seed, args.steps.map(|s| s as usize), params)?;
        if args.odometry.as_deref() == Some("none") {
            input::withhold_odometry(&mut input, &[], input::NoOdometry::Withheld, laser_odometry)?;
        }
        return Ok(input);
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
        odom_frame: args.odom_frame.clone(),
        base_frame: args.base_frame.clone(),
        laser_only: args.odometry.as_deref() == Some("none"),
        imu_topic: args.imu_topic.clone(),
    };
    Ok(input::open_with(path, &options, laser_odometry)?)
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

fn write_err(path: &Path) -> impl FnOnce(std::io::Error) -> CliError + '_ {
    move |e| CliError::Write {
        path: path.to_path_buf(),
        source: e,
    }
}

/// The library's run options for this run: the input's name and clock, and the
/// reference, relations and map resolution of the command line.
fn run_options<'a>(ctx: &'a RunContext<'_>, input: &'a Input) -> RunOptions<'a> {
    RunOptions {
        ground_truth: ctx.ground_truth.as_deref(),
        relations: ctx.relations.as_deref(),
        map_resolution: ctx.args.map_resolution,
        ..input.run_options()
    }
}

/// A run error as the program reports it: a stop is Ctrl-C's, an observer's error is the
/// program's own (a frame it could not write).
fn run_error(e: RunError) -> CliError {
    match e {
        RunError::Step {
            filter,
            step,
            t,
            source,
        } => CliError::FilterStep {
            filter,
            step,
            t,
            source,
        },
        RunError::Stopped { done, steps } => CliError::Interrupted { step: done, steps },
        RunError::Observer { source, .. } => match source.downcast::<CliError>() {
            Ok(e) => *e,
            Err(e) => CliError::InvalidArgument(e.to_string()),
        },
        RunError::CannotRender { filter, .. } => CliError::InvalidArgument(format!(
            "--map-resolution: filter `{filter}` keeps no scans to re-render its map from (gridfast does)"
        )),
        RunError::Render {
            filter,
            resolution,
            source,
        } => CliError::InvalidArgument(format!(
            "--map-resolution {resolution}: the map of filter `{filter}` cannot be re-rendered on cells this small ({source}); choose a coarser --map-resolution"
        )),
    }
}

/// Prints the run's warnings on stderr.
fn warn(warnings: &[String]) {
    for w in warnings {
        eprintln!("slam: warning: {w}");
    }
}

fn run_landmark(
    ctx: &RunContext<'_>,
    input: &Input,
    dataset: &LandmarkDataset,
    sim_noise: Option<NoiseModels>,
) -> Result<Finished, CliError> {
    let info = &ctx.info;
    let built = filters::build_landmark(
        info,
        &Setup::of_run(ctx.args, dataset.initial_pose, sim_noise),
    )?;
    let mut filter = built.filter;
    let steps = &dataset.steps;
    let ground_truth = ctx.ground_truth.as_ref().or(dataset.ground_truth.as_ref());
    let particle_count = filter.particles().map(|p| p.len());
    let seeded = sim_noise.is_some() || particle_count.is_some();
    let title = pictures::title(
        info.name,
        &input.name,
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
    let mut progress = Progress::new(steps.len(), ctx.args.quiet);
    // Progress, the --frames pictures, --mcap and Ctrl-C, after every step (not timed).
    let mut observer = |p: &LandmarkProgress<'_>| -> Result<Flow, ObserverError> {
        if let Some(f) = &mut frames {
            f.step(
                p.step,
                p.steps,
                &title,
                p.filter,
                p.online,
                ground_truth.map(Vec::as_slice),
                dataset.landmarks.as_deref(),
            )?;
        }
        if let Some(r) = &mut mcap {
            let t = steps[p.step].t;
            r.landmark_step(t, odometry.get(p.step).map(|q| q.pose), p.filter)?;
        }
        progress.set(p.step + 1);
        Ok(if crate::stop_requested() {
            Flow::Stop
        } else {
            Flow::Continue
        })
    };
    let opts = run_options(ctx, input);
    let run = run_landmarks_observed(filter.as_mut(), dataset, &opts, &mut observer)
        .map_err(run_error)?;
    progress.finish();
    if let Some(f) = frames {
        f.finish()?;
    }
    warn(&run.warnings);
    let trajectory = run.trajectory();

    let dir = ctx.stage;
    let mut files = Vec::new();
    let p = dir.join("trajectory.tum");
    slam_io::tum::write_tum(&p, trajectory)?;
    files.push(p);
    if run.full_path.is_some() {
        let p = dir.join("trajectory-online.tum");
        slam_io::tum::write_tum(&p, &run.online)?;
        files.push(p);
    }
    let p = dir.join("estimates.csv");
    slam_io::estimates_csv::write_estimates_csv(&p, &run.estimates)?;
    files.push(p);
    if ctx.simulated {
        if let Some(gt) = &dataset.ground_truth {
            let p = dir.join("ground_truth.tum");
            slam_io::tum::write_tum(&p, gt)?;
            files.push(p);
        }
    }
    let mut notes: Vec<String> = built
        .noise_note
        .into_iter()
        .chain(run.notes.clone())
        .collect();
    if let Some(r) = mcap {
        notes.push(r.finish(
            trajectory,
            None,
            Some(&run.landmarks),
            ground_truth.map(Vec::as_slice),
        )?);
    }
    let p = dir.join("landmarks.csv");
    slam_io::landmarks_csv::write_landmarks_csv(&p, &run.landmarks)?;
    files.push(p);
    let pic = pictures::landmark_run_picture(
        &title,
        filter.as_ref(),
        &run,
        ground_truth.map(Vec::as_slice),
        dataset.landmarks.as_deref(),
        &mut notes,
    );
    let p = dir.join("map.png");
    pic.save_png(&p)?;
    files.push(p);
    let p = dir.join("config.toml");
    std::fs::write(&p, &built.config_toml).map_err(write_err(&p))?;
    files.push(p);
    let p = dir.join("metrics.json");
    run.metrics.write(&p).map_err(write_err(&p))?;
    files.push(p);
    Ok(Finished {
        metrics: run.metrics,
        files,
        notes,
        live: None,
    })
}

fn run_scan(
    ctx: &RunContext<'_>,
    input: &Input,
    dataset: &ScanDataset,
) -> Result<Finished, CliError> {
    let info = &ctx.info;
    // Scans without a single return give nothing to match or map: said before the run
    // (issue 32: such a run ended with an error naming the staging folder's map file).
    let scans = dataset.records.iter().filter_map(|r| r.scan.as_ref());
    if scans.clone().all(|s| (0..s.len()).all(|k| !s.is_hit(k))) {
        return Err(CliError::NoReturns {
            input: input.label.clone(),
            scans: scans.count(),
        });
    }
    let mut setup = Setup::of_run(ctx.args, slam_models::Pose2::default(), None);
    setup.laser_odometry = input.laser_odometry.is_some();
    let built = filters::build_scan(info, &setup)?;
    let mut filter = built.filter;
    let mut mcap = McapRecorder::create(ctx.args, dataset.records.len(), None)?;
    let mut live = crate::start_live(
        ctx.args.live.as_deref(),
        |o| o.default_topic().into(),
        &mut std::io::stderr(),
    )?
    .map(slam_ros::live::RunView::new);
    let mut progress = Progress::new(dataset.records.len(), ctx.args.quiet);
    let mut observer = |p: &ScanProgress<'_>| -> Result<Flow, ObserverError> {
        if let Some(r) = &mut mcap {
            r.scan_step(p.record, p.filter)?;
        }
        if let Some(v) = &mut live {
            v.step(p.record, p.filter, p.step + 1 == p.steps);
        }
        progress.set(p.step + 1);
        Ok(if crate::stop_requested() {
            Flow::Stop
        } else {
            Flow::Continue
        })
    };
    let opts = run_options(ctx, input);
    let mut run =
        run_scans_observed(filter.as_mut(), dataset, &opts, &mut observer).map_err(run_error)?;
    progress.finish();
    warn(&run.warnings);
    let particles = filter.particles();
    // The configuration the filter ran with: it alone resolves what the given one left to
    // the data (gridfast: the range limit and preset, from its first scan).
    let effective = built.config.effective(filter.as_ref());
    let first_scan = dataset.records.iter().find_map(|r| r.scan.as_ref());
    if let (false, Some(scan)) = (ctx.args.quiet, first_scan) {
        if let Some(line) = filters::gridfast_settings(&built.config, &effective, scan) {
            eprintln!("{line}");
        }
    }
    // The outputs need nothing more from the filter: its particles' maps and kept scans
    // (and the per-record diagnostics) are freed before the pictures are drawn, so that the
    // outputs reuse their memory instead of adding to the run's peak.
    drop(filter);
    run.updates = Vec::new();

    let dir = ctx.stage;
    let mut files = Vec::new();
    let p = dir.join("trajectory.tum");
    slam_io::tum::write_tum(&p, &run.trajectory)?;
    files.push(p);
    if ctx.simulated {
        // The simulator's own frame, not the anchored copy the metrics use.
        if let Some(gt) = &dataset.ground_truth {
            let p = dir.join("ground_truth.tum");
            slam_io::tum::write_tum(&p, gt)?;
            files.push(p);
        }
    }
    let mut notes = run.notes;
    if let Some(r) = mcap {
        notes.push(r.finish(
            &run.trajectory,
            Some(&run.map),
            None,
            run.reference.as_deref(),
        )?);
    }
    slam_io::ros_map::write_ros_map(dir, "map", &run.map)?;
    files.push(dir.join("map.pgm"));
    files.push(dir.join("map.yaml"));
    let poses: Vec<_> = run.trajectory.iter().map(|t| t.pose).collect();
    let gt_poses: Option<Vec<_>> = run
        .reference
        .as_ref()
        .map(|g| g.iter().map(|t| t.pose).collect());
    let particle_count = particles.as_ref().map(Vec::len);
    let title = pictures::title(
        info.name,
        &input.name,
        particle_count,
        particle_count.map(|_| ctx.args.seed),
    );
    let pic = pictures::laser_picture(
        &title,
        &run.map,
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
    // With laser odometry, its table too: the file reproduces the run.
    let mut text = effective.table_toml();
    if let Some(c) = &input.laser_odometry {
        text.push('\n');
        text.push_str(&slam_eval::factory::laser_odometry_toml(c));
    }
    std::fs::write(&p, text).map_err(write_err(&p))?;
    files.push(p);
    let p = dir.join("metrics.json");
    run.metrics.write(&p).map_err(write_err(&p))?;
    files.push(p);
    Ok(Finished {
        metrics: run.metrics,
        files,
        notes,
        live,
    })
}

fn print_summary(
    out: &mut dyn Write,
    m: &Metrics,
    notes: &[String],
    dir: &Path,
    files: &[PathBuf],
) {
    for line in m.summary() {
        let _ = writeln!(out, "{line}");
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
