//! slam-gridfast + slam-io: a CARMEN log read by slam-io (no metrics, no image codec) and
//! run through grid FastSLAM, using only these two crates' re-exports.
//!
//! `gridfast_io LOG [RECORDS]` runs the first RECORDS records (default: all) and checks the
//! result against its own scans, as tests/grid.rs checks a map built from known poses: at
//! the filter's poses, the end points of every 10th scan (< 15 m) must fall on or next to an
//! occupied cell of its map (> 85 %). A misregistered map smears its walls and fails this;
//! the same check at the raw odometry poses is printed beside it for comparison.
use slam_gridfast::prelude::*;
use slam_gridfast::{GridFastConfig, GridFastSlam, GridMap, Pose2, ScanRecord};
use slam_io::carmen::read_carmen;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let log = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .ok_or("usage: gridfast_io LOG [RECORDS]")?;
    let n: usize = std::env::args()
        .nth(2)
        .map_or(Ok(usize::MAX), |s| s.parse())?;
    let data = read_carmen(&log)?.dataset;
    let records: Vec<&ScanRecord> = data.records.iter().take(n).collect();
    let config = GridFastConfig {
        particles: 10,
        ..GridFastConfig::default()
    };
    let mut filter = GridFastSlam::new(config, Pose2::IDENTITY, 0)?;
    for record in &records {
        filter.process(record)?;
    }
    let map = filter.map();
    let trajectory = filter.trajectory();
    if trajectory.len() != records.len() {
        return Err(format!(
            "{} poses for {} records: one pose per record expected",
            trajectory.len(),
            records.len()
        )
        .into());
    }
    let filtered: Vec<Pose2> = trajectory.iter().map(|p| p.pose).collect();
    let odometry: Vec<Pose2> = records.iter().map(|r| r.odometry).collect();
    let on_filter = on_map(&map, &records, &filtered);
    let on_odometry = on_map(&map, &records, &odometry);
    println!(
        "{}: {} records, map {}x{} cells; end points on occupied cells: {:.1} % at the \
         filter's poses, {:.1} % at the raw odometry",
        filter.name(),
        records.len(),
        map.width,
        map.height,
        100.0 * on_filter,
        100.0 * on_odometry
    );
    assert!(
        on_filter > 0.85,
        "map inconsistent with its own scans: {on_filter}"
    );
    Ok(())
}

/// The fraction of end points (< 15 m, every 10th scan) at `poses` that fall on or next to
/// an occupied cell (value > 50) of `map`.
fn on_map(map: &GridMap, records: &[&ScanRecord], poses: &[Pose2]) -> f64 {
    let (mut on, mut total) = (0usize, 0usize);
    let scanned = records.iter().zip(poses).filter(|(r, _)| r.scan.is_some());
    for (record, pose) in scanned.step_by(10) {
        let Some(scan) = &record.scan else { continue };
        for p in scan
            .hit_points()
            .into_iter()
            .filter(|p| p.coords.norm() < 15.0)
        {
            let w = pose.transform_point(&p);
            total += 1;
            let Some((ix, iy)) = map.cell_of(&w) else {
                continue;
            };
            let near = (-1i64..=1).any(|dy| {
                (-1i64..=1).any(|dx| {
                    let (x, y) = (ix as i64 + dx, iy as i64 + dy);
                    x >= 0 && y >= 0 && map.get(x as usize, y as usize).is_some_and(|v| v > 50)
                })
            });
            on += usize::from(near);
        }
    }
    on as f64 / total.max(1) as f64
}
