//! slam-gridfast + slam-io: a CARMEN log read by slam-io (no metrics, no image codec) and
//! run through grid FastSLAM, using only these two crates' re-exports.
use slam_gridfast::prelude::*;
use slam_gridfast::{GridFastConfig, GridFastSlam, Pose2};
use slam_io::carmen::read_carmen;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // `gridfast_io LOG [RECORDS]`: the first RECORDS records (default 200) of any CARMEN log.
    let log = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .ok_or("usage: gridfast_io LOG [RECORDS]")?;
    let n: usize = std::env::args().nth(2).map_or(Ok(200), |s| s.parse())?;
    let data = read_carmen(&log)?.dataset;
    let config = GridFastConfig {
        particles: 10,
        ..GridFastConfig::default()
    };
    let mut filter = GridFastSlam::new(config, Pose2::IDENTITY, 0)?;
    for record in data.records.iter().take(n) {
        filter.process(record)?;
    }
    let map = filter.map();
    println!(
        "{}: {} poses, last {:?}, map {}x{} cells",
        filter.name(),
        filter.trajectory().len(),
        filter.pose(),
        map.width,
        map.height
    );
    Ok(())
}
