//! Whole-Intel benchmark run: relations error, wall time, real-time factor and peak RSS.
//!
//! ```text
//! cargo run --release --example gridfast_intel -- \
//!     [--particles 30] [--proposal improved|odometry|scan-matched-odometry] [--threads 1 (0: all)] \
//!     [--seed 1] [--config file.json] [--log PATH] [--relations PATH] [--map DIR]
//! ```
//!
//! Defaults read `../shared/datasets/bench/intel.log` and
//! `../shared/datasets/slam-benchmark-relations/intel.relations` (or under `$SLAM_DATASETS`).
//! The run is slam-eval's `run_scans`; the relations error uses the datasets README's rule
//! (slam-eval's `relations_error`).

use slam_gridfast::{GridFastConfig, GridFastSlam, Proposal};
use slam_models::Pose2;
use std::path::PathBuf;

fn peak_rss_mb() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// CPU seconds (user + system) of this process so far, from /proc/self/stat.
fn cpu_seconds() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/stat").ok()?;
    let rest = &s[s.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let data = std::env::var_os("SLAM_DATASETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/datasets"));
    let mut log = data.join("bench/intel.log");
    let mut relations = data.join("slam-benchmark-relations/intel.relations");
    let mut config = GridFastConfig::default();
    let (mut threads, mut seed, mut map_dir) = (1usize, 1u64, None::<PathBuf>);
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut val = || args.next().ok_or_else(|| format!("{a} needs a value"));
        match a.as_str() {
            "--particles" => config.particles = val()?.parse()?,
            "--proposal" => {
                config.proposal.kind = serde_json::from_str::<Proposal>(&format!("\"{}\"", val()?))?
            }
            "--threads" => threads = val()?.parse()?,
            "--seed" => seed = val()?.parse()?,
            "--log" => log = val()?.into(),
            "--relations" => relations = val()?.into(),
            "--map" => map_dir = Some(val()?.into()),
            "--config" => {
                let text = std::fs::read_to_string(val()?)?;
                let particles = config.particles;
                config = serde_json::from_str(&text)?;
                if config.particles == GridFastConfig::default().particles {
                    config.particles = particles;
                }
            }
            other => return Err(format!("unknown argument {other}").into()),
        }
    }
    let carmen = slam_io::carmen::read_carmen(&log)?;
    let rel = slam_io::relations::read_relations(&relations)?;
    let records = &carmen.dataset.records;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    let threads = pool.current_num_threads();
    let (proposal, particles) = (config.proposal.kind, config.particles);
    let mut slam = GridFastSlam::new(config, Pose2::IDENTITY, seed)?;
    let cpu0 = cpu_seconds().unwrap_or(f64::NAN);
    // slam-eval's run: `process` on every record, timed (the filter only).
    let opts = slam_eval::RunOptions {
        relations: Some(&rel),
        ..Default::default()
    };
    let run = pool.install(|| slam_eval::run_scans(&mut slam, &carmen.dataset, &opts))?;
    let wall = run.metrics.wall_s;
    let cpu = cpu_seconds().unwrap_or(f64::NAN) - cpu0;
    let (failures, resamples, processed) = run.updates.iter().fold((0, 0, 0), |(f, r, p), u| {
        (
            f + u.match_failures,
            r + u.resampled as usize,
            p + u.processed_scan as usize,
        )
    });
    let traj = run.trajectory;
    let span =
        records.last().map(|r| r.t).unwrap_or(0.0) - records.first().map(|r| r.t).unwrap_or(0.0);
    let e = slam_eval::metrics::relations_error(&traj, &rel);
    println!(
        "proposal={proposal:?} particles={particles} threads={threads} seed={seed} records={} processed={processed} \
         resamples={resamples} match_failures={failures}",
        records.len()
    );
    println!(
        "relations: trans {:.4} ± {:.4} m, rot {:.3} ± {:.3} deg (used {}, dropped {})",
        e.trans_mean, e.trans_std, e.rot_mean_deg, e.rot_std_deg, e.used, e.dropped
    );
    println!(
        "wall {:.2} s (cpu {:.2} s), real-time factor {:.1}x, {:.3} ms per particle per processed scan, peak RSS {:.1} MB",
        wall,
        cpu,
        span / wall,
        1e3 * wall / (processed.max(1) * particles) as f64,
        peak_rss_mb().unwrap_or(f64::NAN)
    );
    if let Some(dir) = map_dir {
        // The best particle's map rendered at 5 cm, as a ROS map_server PGM + YAML.
        std::fs::create_dir_all(&dir)?;
        slam_io::ros_map::write_ros_map(&dir, "map", &slam.render_map(0.05)?)?;
    }
    Ok(())
}
