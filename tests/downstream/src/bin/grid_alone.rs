//! slam-grid alone: mapping with known poses. A wall at x = 3 m seen from two known poses
//! fills the cells on the wall and clears the ones in front of it.
use slam_grid::{InverseSensorModel, LaserScan, OccupancyGrid, Point2, Pose2};

fn main() {
    let mut grid = OccupancyGrid::new(0.05, InverseSensorModel::default());
    for pose in [Pose2::IDENTITY, Pose2::new(0.5, 0.2, 0.0)] {
        // 31 beams over ±30°, each to the wall x = 3 m (in the world frame, heading 0).
        let (n, step) = (31, 2.0_f64.to_radians());
        let angle_min = -30.0_f64.to_radians();
        let ranges = (0..n)
            .map(|k| (3.0 - pose.x) / (angle_min + k as f64 * step).cos())
            .collect();
        let scan = LaserScan {
            angle_min,
            angle_increment: step,
            ranges,
            max_range: 10.0,
            sensor_pose: Pose2::IDENTITY,
        };
        grid.integrate_scan(&pose, &scan);
    }
    let map = grid.to_grid_map();
    let at = |x: f64, y: f64| {
        let (ix, iy) = map.cell_of(&Point2::new(x, y)).expect("inside the map");
        map.get(ix, iy).expect("inside the map")
    };
    let (wall, open) = (at(3.01, 0.1), at(1.5, 0.1));
    assert!(
        wall > 50 && (0..50).contains(&open),
        "wall {wall}, open {open}"
    );
    println!("wall cell {wall} %, open cell {open} %");
}
