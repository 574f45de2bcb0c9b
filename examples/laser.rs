//! A CARMEN log → grid FastSLAM behind `Box<dyn ScanSlam>` → a ROS map_server map.
use slam::gridfast::{GridFastConfig, GridFastSlam, Pose2};
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
    let config = GridFastConfig {
        particles: 30,
        ..GridFastConfig::default()
    };
    let mut filter: Box<dyn ScanSlam> = Box::new(GridFastSlam::new(config, Pose2::IDENTITY, 0)?);
    for record in &data.records {
        filter.process(record)?;
    }
    // The best particle's map as map.pgm + map.yaml, as ROS map_server reads them.
    std::fs::create_dir_all(&out)?;
    write_ros_map(&out, "map", &filter.map())?;
    println!("{}: the map is in {}", filter.name(), out.display());
    Ok(())
}
