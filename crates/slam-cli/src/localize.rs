//! `slam localize`: Monte Carlo localization (slam-mcl) of a log on a saved map.

use crate::error::CliError;
use crate::mcap::McapRecorder;
use crate::outdir::{OutDir, Owner};
use clap::Args;
use serde::Serialize;
use slam_eval::input::InputData;
use slam_mcl::{InitialBelief, Mcl, MclConfig, MclMap, StepInfo};
use slam_models::{Pose2, TimedPose, WeightedPose};
use slam_viz::picture::{Picture, Rgb};
use std::io::Write;
use std::path::{Path, PathBuf};

/// `slam localize`.
#[derive(Debug, Clone, Args)]
#[command(group(clap::ArgGroup::new("start").required(true).args(["global", "initial_pose"])))]
pub struct LocalizeArgs {
    /// The map: a ROS map_server YAML (PGM or PNG image; resolution, origin, negate and
    /// thresholds honoured), e.g. the map.yaml of a `slam run`.
    #[arg(long, value_name = "MAP.yaml")]
    pub map: PathBuf,
    /// The log to localize: a CARMEN log or a ROS bag (as `slam run --dataset`).
    #[arg(long, value_name = "PATH")]
    pub dataset: PathBuf,
    /// Global localization: the start is unknown (particles over all the free space).
    #[arg(long)]
    pub global: bool,
    /// The start in the map frame, `x,y,theta[,sx,sy,stheta]` (m, rad; the σ default to
    /// 0.25 m, 0.25 m, 0.2 rad).
    #[arg(long, value_name = "X,Y,THETA[,SX,SY,STHETA]", value_parser = initial_pose, allow_hyphen_values = true)]
    pub initial_pose: Option<[f64; 6]>,
    /// MCL configuration, a TOML file (see configs/mcl.toml); unknown keys are an error.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Seed of the filter's random numbers (same seed, same output).
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub seed: u64,
    /// Reference trajectory (TUM) to score against without alignment (the map fixes the frame).
    #[arg(long, value_name = "FILE")]
    pub ground_truth: Option<PathBuf>,
    /// Distances travelled (m) at which the picture shows the particle cloud, comma separated
    /// (default: the first update, the moment of convergence, the end).
    #[arg(long, value_name = "M,M,…", value_delimiter = ',', value_parser = cloud_distance)]
    pub clouds: Option<Vec<f64>>,
    /// ROS bags: the LaserScan topic.
    #[arg(long, value_name = "TOPIC")]
    pub scan_topic: Option<String>,
    /// ROS bags: the Odometry topic, or /tf.
    #[arg(long, value_name = "TOPIC")]
    pub odom_topic: Option<String>,
    /// Output folder: trajectory.tum, metrics.json, localization.png, config.toml.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Write into a non-empty --out that slam localize did not make (and let --mcap
    /// replace an MCAP file slam did not write).
    #[arg(long)]
    pub force: bool,
    /// Also write the localization as an MCAP file of ROS 2 messages (as `slam run
    /// --mcap`): /map once, /pose, /tf, /scan per record, /particles at each update,
    /// /trajectory snapshots, /ground_truth with --ground-truth.
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    /// Serve the localization to Foxglove over its WebSocket protocol on ADDRESS (default
    /// 127.0.0.1:8765) while it runs (docs/ros2.md).
    #[arg(long, value_name = "ADDRESS", num_args = 0..=1, default_missing_value = slam_ros::live::DEFAULT_ADDRESS)]
    pub live: Option<String>,
    /// With --live: after the localization, keep serving its last state until Ctrl-C.
    #[arg(long, requires = "live")]
    pub live_hold: bool,
}

/// Bound of `--initial-pose`'s x, y and σx, σy, metres: slam-io's bound of every position
/// it reads (`slam_io::bounds::MAX_COORD`). `1e300,0,0` was taken and the run ended on an
/// error about a non-finite pose in its output's staging file, naming no option.
const MAX_START_METRES: f64 = slam_io::bounds::MAX_COORD;

/// `x,y,theta[,sx,sy,stheta]`: finite numbers, |x|, |y|, σx, σy ≤ 1e6 m, |θ| and σθ ≤ 2π
/// (beyond a full turn a heading spread says nothing: use `--global`), σ ≥ 0.
fn initial_pose(s: &str) -> Result<[f64; 6], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected x,y,theta[,sx,sy,stheta] (numbers), found {s:?}"))?;
    let mut out = [0.0, 0.0, 0.0, 0.25, 0.25, 0.2];
    if !(v.len() == 3 || v.len() == 6) || v.iter().any(|x| !x.is_finite()) {
        return Err(format!(
            "expected 3 or 6 finite numbers x,y,theta[,sx,sy,stheta], found {s:?}"
        ));
    }
    if v[3..].iter().any(|x| *x < 0.0) {
        return Err(format!("standard deviations must be >= 0, found {s:?}"));
    }
    out[..v.len()].copy_from_slice(&v);
    let tau = std::f64::consts::TAU;
    let [x, y, th, sx, sy, sth] = out;
    if [x, y, sx, sy].iter().any(|m| m.abs() > MAX_START_METRES) || th.abs() > tau || sth > tau {
        return Err(format!(
            "expected |x|, |y|, sx, sy <= 1e6 m and |theta|, stheta <= 2π rad, found {s:?}"
        ));
    }
    Ok(out)
}

/// One `--clouds` distance: finite metres ≥ 0 (`nan` was taken and drew no cloud).
fn cloud_distance(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!(
            "expected a finite distance travelled >= 0 m, found {s:?}"
        )),
    }
}

/// One measurement update in metrics.json.
#[derive(Debug, Clone, Serialize)]
pub struct UpdateRow {
    /// Record time, s.
    pub t: f64,
    /// Odometry distance travelled since the first record, m.
    pub travelled: f64,
    /// Particles after the update (and any resampling).
    pub particles: usize,
    /// Cloud spread √(σx² + σy²) after the weighting, m.
    pub spread: f64,
    /// Effective sample size after the weighting.
    pub n_eff: f64,
    /// Resampled at this update.
    pub resampled: bool,
    /// Random particles injected (augmented MCL).
    pub injected: usize,
    /// The exponent the scan's likelihood was raised to (below `weight-exponent` when
    /// adaptive tempering kept N_eff up).
    pub exponent: f64,
    /// A global start not yet converged by the filter's own test (slam-mcl's
    /// `StepInfo::converging`): the evidence of each update is scaled by its translation.
    pub converging: bool,
}

/// What `slam localize` measured (metrics.json).
#[derive(Debug, Clone, Serialize)]
pub struct LocalizeReport {
    /// The map file.
    pub map: PathBuf,
    /// The log.
    pub dataset: PathBuf,
    /// Seed.
    pub seed: u64,
    /// `global` or `initial-pose`.
    pub start: &'static str,
    /// Records processed.
    pub records: usize,
    /// Measurement updates.
    pub updates: usize,
    /// Odometry distance travelled over the log, m.
    pub travelled: f64,
    /// Fewest / most particles over the updates.
    pub particles_min: usize,
    /// See `particles_min`.
    pub particles_max: usize,
    /// Distance travelled (m) at the first update whose spread was below 0.5 m, from which
    /// on it stayed below 0.5 m until the end (`None`: never converged for good).
    pub converged_after: Option<f64>,
    /// Time of that update, s.
    pub converged_at: Option<f64>,
    /// ATE RMSE (m) against --ground-truth, as is (no alignment), over every pose.
    pub ate_rmse: Option<f64>,
    /// The same over the poses after convergence.
    pub ate_rmse_converged: Option<f64>,
    /// Largest position error after convergence, m.
    pub ate_max_converged: Option<f64>,
    /// Output files.
    pub files: Vec<PathBuf>,
    /// Every measurement update.
    pub steps: Vec<UpdateRow>,
}

/// Spread (m) below which the cloud counts as converged.
pub const CONVERGED_SPREAD: f64 = 0.5;

/// Runs `slam localize`.
pub fn localize(args: &LocalizeArgs, out: &mut dyn Write) -> Result<LocalizeReport, CliError> {
    let config: MclConfig = crate::config::load(args.config.as_deref())?.config;
    config.validate().map_err(slam_mcl::MclError::from)?;
    let ground_truth = match &args.ground_truth {
        Some(p) => Some(slam_io::tum::read_tum(p)?),
        None => None,
    };
    let mut inputs: Vec<(&str, &Path)> = vec![("--map", &args.map), ("--dataset", &args.dataset)];
    for (o, p) in [
        ("--config", &args.config),
        ("--ground-truth", &args.ground_truth),
    ] {
        if let Some(p) = p {
            inputs.push((o, p.as_path()));
        }
    }
    if let Some(mcap) = &args.mcap {
        crate::mcap::check_path(mcap, &inputs, &args.out, args.force)?;
    }
    let staging = OutDir::prepare(&args.out, Owner::Localize, args.force, &inputs)?;
    let grid_map = slam_io::ros_map::read_ros_map(&args.map)?;
    let options = slam_io::DatasetOptions {
        scan_topic: args.scan_topic.clone(),
        odom_topic: args.odom_topic.clone(),
        ..Default::default()
    };
    let mut input = slam_eval::input::open(&args.dataset, &options)?;
    input.description = crate::error::with_flags(&input.description);
    let InputData::Laser(dataset) = &input.data else {
        return Err(CliError::InvalidArgument(format!(
            "--dataset {}: localization needs odometry and laser scans, not landmark data",
            args.dataset.display()
        )));
    };
    let _ = writeln!(out, "input: {}", input.description);
    let map = MclMap::new(grid_map, &config)?;
    let init = match args.initial_pose {
        Some(v) => InitialBelief::Gaussian {
            mean: Pose2::new(v[0], v[1], v[2]),
            sigma: [v[3], v[4], v[5]],
        },
        None => InitialBelief::Global,
    };
    let mut mcl = Mcl::new(config, map, init, args.seed)?;
    let mut live = crate::start_live(args.live.as_deref(), |o| o.default_topic().into(), out)?
        .map(slam_ros::live::RunView::new);
    let mut mcap = match &args.mcap {
        Some(p) => Some(McapRecorder::open(p, None, dataset.records.len(), None)?),
        None => None,
    };
    let (steps, clouds) = run_log(
        &mut mcl,
        &dataset.records,
        args.clouds.as_deref(),
        live.as_mut(),
        mcap.as_mut(),
    )?;
    let mut report = summarise(args, &steps, mcl.trajectory(), ground_truth.as_deref());
    let mcap_note = match mcap {
        Some(r) => Some(r.finish(
            mcl.trajectory(),
            Some(mcl.map().grid_map()),
            None,
            ground_truth.as_deref(),
        )?),
        None => None,
    };
    let dir = staging.stage();
    let p = dir.join("trajectory.tum");
    slam_io::tum::write_tum(&p, mcl.trajectory())?;
    let p = dir.join("localization.png");
    let est: Vec<Pose2> = mcl.trajectory().iter().map(|t| t.pose).collect();
    let mut pic = Picture::new()
        .title(format!(
            "MCL on {} ({}, seed {})",
            input.name, report.start, args.seed
        ))
        .map(mcl.map().grid_map())
        .particles(&clouds);
    if let Some(gt) = &ground_truth {
        let g: Vec<Pose2> = gt.iter().map(|t| t.pose).collect();
        pic = pic.ground_truth(&g).ground_truth_label("reference");
    }
    pic = pic.trajectory(&est, Rgb([200, 30, 30]), "MCL estimate");
    pic.save_png(&p)?;
    let p = dir.join("config.toml");
    std::fs::write(&p, crate::config::to_toml(mcl.config())).map_err(|e| CliError::Write {
        path: p.clone(),
        source: e,
    })?;
    let names = [
        "trajectory.tum",
        "localization.png",
        "config.toml",
        "metrics.json",
    ];
    report.files = names.iter().map(|n| args.out.join(n)).collect();
    let p = dir.join("metrics.json");
    let json = serde_json::to_string_pretty(&report).unwrap_or_default();
    std::fs::write(&p, json).map_err(|e| CliError::Write {
        path: p.clone(),
        source: e,
    })?;
    staging.commit(&names)?;
    crate::hold_live(args.live_hold, live.as_ref().map(|v| v.server()));
    let _ = writeln!(
        out,
        "{} records, {} updates, {:.1} m travelled, particles {}–{}, converged after {}",
        report.records,
        report.updates,
        report.travelled,
        report.particles_min,
        report.particles_max,
        report
            .converged_after
            .map_or("never".into(), |d| format!("{d:.1} m"))
    );
    if let (Some(a), Some(c)) = (report.ate_rmse, report.ate_rmse_converged) {
        let _ = writeln!(
            out,
            "ATE (no alignment): {a:.3} m; after convergence {c:.3} m"
        );
    }
    if let Some(note) = mcap_note {
        let _ = writeln!(out, "{note}");
    }
    let _ = writeln!(out, "wrote {}", args.out.display());
    Ok(report)
}

/// One measurement update: the filter's diagnostics, the odometry distance travelled
/// since the first record (m), and the record's index.
#[derive(Debug, Clone, Copy)]
pub struct Update {
    /// The filter's diagnostics.
    pub info: StepInfo,
    /// Distance travelled, m.
    pub travelled: f64,
    /// Index of the record in the log.
    pub record: usize,
}

/// Feeds every record to the filter; returns each update's info with the distance
/// travelled, and the particle clouds at the chosen distances (default: first update,
/// convergence, end). With `live`, the state after each record also goes to the live view;
/// with `mcap`, to the MCAP file (the cloud at each update).
pub(crate) fn run_log(
    mcl: &mut Mcl,
    records: &[slam_models::ScanRecord],
    clouds_at: Option<&[f64]>,
    mut live: Option<&mut slam_ros::live::RunView>,
    mut mcap: Option<&mut McapRecorder>,
) -> Result<(Vec<Update>, Vec<WeightedPose>), CliError> {
    let mut steps = Vec::new();
    let mut clouds = Vec::new();
    let mut travelled = 0.0;
    let mut prev: Option<Pose2> = None;
    let mut wanted: Vec<f64> = clouds_at.map(<[f64]>::to_vec).unwrap_or_default();
    wanted.sort_by(f64::total_cmp);
    let mut next = 0;
    let mut converged_shown = clouds_at.is_some();
    for (record, r) in records.iter().enumerate() {
        if let Some(p) = prev {
            travelled += p.distance(&r.odometry);
        }
        prev = Some(r.odometry);
        let info = mcl.process(r).map_err(CliError::from)?;
        if let Some(v) = live.as_deref_mut() {
            v.localize_step(
                r,
                mcl.pose(),
                &mcl.particles(),
                mcl.map().grid_map(),
                mcl.trajectory(),
            );
        }
        if let Some(m) = mcap.as_deref_mut() {
            let cloud = info.updated.then(|| mcl.particles());
            m.localize_step(r, mcl.pose(), cloud.as_deref(), mcl.map().grid_map())?;
        }
        if info.updated {
            let first = steps.is_empty() && clouds_at.is_none();
            let due = next < wanted.len() && travelled >= wanted[next];
            let converged = !converged_shown && info.spread < CONVERGED_SPREAD;
            if first || due || converged {
                clouds.extend(mcl.particles());
                while next < wanted.len() && travelled >= wanted[next] {
                    next += 1;
                }
                converged_shown |= converged;
            }
            steps.push(Update {
                info,
                travelled,
                record,
            });
        }
        if crate::stop_requested() {
            return Err(CliError::Interrupted {
                step: steps.len(),
                steps: records.len(),
            });
        }
    }
    if clouds_at.is_none() {
        clouds.extend(mcl.particles());
    }
    Ok((steps, clouds))
}

/// The report's figures from the updates and the trajectory.
fn summarise(
    args: &LocalizeArgs,
    steps: &[Update],
    trajectory: &[TimedPose],
    ground_truth: Option<&[TimedPose]>,
) -> LocalizeReport {
    let rows: Vec<UpdateRow> = steps
        .iter()
        .map(|u| (&u.info, u.travelled))
        .map(|(s, d)| UpdateRow {
            t: s.t,
            travelled: d,
            particles: s.particles,
            spread: s.spread,
            n_eff: s.n_eff,
            resampled: s.resampled,
            injected: s.injected,
            exponent: s.exponent,
            converging: s.converging,
        })
        .collect();
    // Converged for good: the first update after the last one with a wide cloud.
    let last_wide = rows.iter().rposition(|r| r.spread >= CONVERGED_SPREAD);
    let conv_index = match last_wide {
        Some(i) => i + 1,
        None => 0,
    };
    let conv = rows.get(conv_index);
    let conv_record = steps.get(conv_index).map(|u| u.record);
    let (ate, ate_conv, ate_max) = match ground_truth {
        Some(gt) => {
            let all = slam_eval::metrics::ate(trajectory, gt).ok().map(|a| a.rmse);
            let errors: Vec<f64> = conv_record
                .map(|c0| {
                    in_file_order(trajectory, gt)
                        .into_iter()
                        .filter(|&(i, _)| i >= c0)
                        .map(|(i, j)| trajectory[i].pose.distance(&gt[j].pose))
                        .collect()
                })
                .unwrap_or_default();
            let n = errors.len() as f64;
            let rmse = (n > 0.0).then(|| (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt());
            let max = (n > 0.0).then(|| errors.iter().copied().fold(0.0, f64::max));
            (all, rmse, max)
        }
        None => (None, None, None),
    };
    LocalizeReport {
        map: args.map.clone(),
        dataset: args.dataset.clone(),
        seed: args.seed,
        start: if args.global {
            "global"
        } else {
            "initial-pose"
        },
        records: trajectory.len(),
        updates: rows.len(),
        travelled: steps.last().map_or(0.0, |s| s.travelled),
        particles_min: rows.iter().map(|r| r.particles).min().unwrap_or(0),
        particles_max: rows.iter().map(|r| r.particles).max().unwrap_or(0),
        converged_after: conv.map(|c| c.travelled),
        converged_at: conv.map(|c| c.t),
        ate_rmse: ate,
        ate_rmse_converged: ate_conv,
        ate_max_converged: ate_max,
        files: Vec::new(),
        steps: rows,
    }
}

/// Pairs (estimate, reference) of a reference written from the same log as the estimate
/// (bench `*.ref.tum`: one line per ODOM record): walking both in file order, each reference
/// line takes the next estimate within [`slam_eval::metrics::DEFAULT_MAX_DT`] of its time
/// (looking at most 64 records ahead). Pairing by nearest time alone mixes up the records
/// that share one printed stamp and the late records some logs stamp before their start
/// (Intel has 22).
fn in_file_order(est: &[TimedPose], gt: &[TimedPose]) -> Vec<(usize, usize)> {
    let dt = slam_eval::metrics::DEFAULT_MAX_DT;
    let mut pairs = Vec::with_capacity(gt.len());
    let mut i = 0;
    for (j, g) in gt.iter().enumerate() {
        let end = (i + 64).min(est.len());
        if let Some(k) = (i..end).find(|&k| (est[k].t - g.t).abs() <= dt) {
            pairs.push((k, j));
            i = k + 1;
        }
    }
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A start beyond slam-io's position bound, or a heading or heading spread beyond a
    /// turn, is refused by the option's parser (1e300,0,0 and a σx of 1e300 were taken and
    /// the run ended on an error about its staging trajectory.tum); bounds are inclusive.
    #[test]
    fn initial_pose_is_bounded() {
        for bad in [
            "1e300,0,0",
            "0,-1000001,0",
            "0,0,7",
            "0,0,0,1e300,1,1",
            "0,0,0,1,1,7",
        ] {
            let e = initial_pose(bad).unwrap_err();
            assert!(e.contains("1e6 m") && e.contains(bad), "{bad}: {e}");
        }
        assert_eq!(
            initial_pose("1e6,-1e6,-6.2,1e6,0,6.2").unwrap(),
            [1e6, -1e6, -6.2, 1e6, 0.0, 6.2]
        );
    }

    /// `--clouds` takes finite distances >= 0 (`nan` and `inf` were taken and drew no
    /// cloud); a distance never reached, as the tests' 1e9, is still taken.
    #[test]
    fn cloud_distances_are_finite() {
        for bad in ["nan", "inf", "-1", "x"] {
            assert!(cloud_distance(bad).unwrap_err().contains(bad), "{bad}");
        }
        assert_eq!(cloud_distance("1e9").unwrap(), 1e9);
        assert_eq!(cloud_distance(" 0 ").unwrap(), 0.0);
    }
}
