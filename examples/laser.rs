//! A CARMEN log → grid FastSLAM behind `Box<dyn ScanSlam>` → a ROS map_server map.
use slam::eval::{run_scans, FilterConfig, RunOptions};
use slam::io::{carmen::read_carmen, ros_map::write_ros_map};
use slam::prelude::*;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // `cargo run --release --example laser -- LOG OUT_DIR`: any CARMEN log, plain or .gz.
    let arg =
        |k: usize, default: &str| PathBuf::from(std::env::args().nth(k).unwrap_or(default.into()));
    let (log, out) = (
        arg(1, "../shared/datasets/bench/intel.log"),
        arg(2, "slam-out/laser"),
    );
    let data = read_carmen(&log)?.dataset;
    let config = FilterConfig::from_toml("filter = \"gridfast\"\nparticles = 30")?.config;
    let mut filter: Box<dyn ScanSlam> = config.build_scan(0)?;
    // Every record in file order; the figures need a ground truth (`RunOptions`).
    let run = run_scans(filter.as_mut(), &data, &RunOptions::default())?;
    // The best particle's map as map.pgm + map.yaml, as ROS map_server reads them.
    std::fs::create_dir_all(&out)?;
    write_ros_map(&out, "map", &run.map)?;
    println!(
        "{}: {} poses in {:.1} s, the map is in {}",
        filter.name(),
        run.trajectory.len(),
        run.metrics.wall_s,
        out.display()
    );
    Ok(())
}
