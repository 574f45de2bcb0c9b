//! Unit tests of the occupancy grid: beam updates, growth, copy-on-write, fields, export.

use super::*;
use crate::likelihood::{LikelihoodField, LikelihoodParams};
use slam_models::{LaserScan, Pose2};

fn scan(ranges: Vec<f64>, angle_min: f64, inc: f64) -> LaserScan {
    LaserScan {
        angle_min,
        angle_increment: inc,
        ranges,
        max_range: 30.0,
        sensor_pose: Pose2::IDENTITY,
    }
}

/// A 360° scan of a square room of half-width `h` centred on the world origin, seen from
/// `pose` (exact ray–wall intersection).
fn room_scan(pose: &Pose2, h: f64, n: usize) -> LaserScan {
    let inc = 2.0 * std::f64::consts::PI / n as f64;
    let ranges = (0..n)
        .map(|k| {
            let a = pose.theta + k as f64 * inc;
            let (s, c) = a.sin_cos();
            let mut best = f64::INFINITY;
            for (d, p) in [(c, pose.x), (s, pose.y)] {
                if d.abs() > 1e-12 {
                    for wall in [-h, h] {
                        let t = (wall - p) / d;
                        if t > 0.0 {
                            best = best.min(t);
                        }
                    }
                }
            }
            best
        })
        .collect();
    scan(ranges, 0.0, inc)
}

#[test]
fn single_beam_marks_free_then_occupied() {
    let mut g = OccupancyGrid::new(0.1, InverseSensorModel::default());
    g.integrate_scan(&Pose2::new(0.05, 0.05, 0.0), &scan(vec![1.0], 0.0, 0.0));
    let m = InverseSensorModel::default();
    for i in 0..10 {
        assert_eq!(g.log_odds(CellIndex::new(i, 0)), m.l_free, "cell {i}");
    }
    assert_eq!(g.log_odds(CellIndex::new(10, 0)), m.l_occ);
    assert_eq!(g.log_odds(CellIndex::new(11, 0)), 0.0);
    assert_eq!(g.log_odds(CellIndex::new(5, 1)), 0.0);
    // Clamping: many hits saturate at l_max.
    for _ in 0..20 {
        g.integrate_scan(&Pose2::new(0.05, 0.05, 0.0), &scan(vec![1.0], 0.0, 0.0));
    }
    assert_eq!(g.log_odds(CellIndex::new(10, 0)), m.l_max);
    assert_eq!(g.log_odds(CellIndex::new(3, 0)), m.l_min);
}

#[test]
fn far_hits_that_do_not_clear_count_as_no_returns() {
    let model = InverseSensorModel {
        no_return_range: 0.0,
        max_range: 2.0,
        hit_margin: 0.0,
        far_hits_clear: false,
        ..Default::default()
    };
    let mut g = OccupancyGrid::new(0.1, model);
    // Beam 0 along +x: a hit at 1 m; beam 1 along +y: a hit at exactly max_range; both
    // along the axes from the centre of cell (0, 0).
    let s = scan(vec![1.0, 2.0], 0.0, std::f64::consts::FRAC_PI_2);
    g.integrate_scan(&Pose2::new(0.05, 0.05, 0.0), &s);
    assert_eq!(g.log_odds(CellIndex::new(10, 0)), model.l_occ);
    assert_eq!(g.log_odds(CellIndex::new(5, 0)), model.l_free);
    // The reading at the limit neither marks its end cell nor clears the way to it.
    assert!((1..=25).all(|j| g.log_odds(CellIndex::new(0, j)) == 0.0));
    // With the default (far hits clear), the same reading is a hit at the limit.
    let mut d = OccupancyGrid::new(
        0.1,
        InverseSensorModel {
            far_hits_clear: true,
            ..model
        },
    );
    d.integrate_scan(&Pose2::new(0.05, 0.05, 0.0), &s);
    assert_eq!(d.log_odds(CellIndex::new(0, 20)), model.l_occ);
    assert_eq!(d.log_odds(CellIndex::new(0, 10)), model.l_free);
}

#[test]
fn no_return_and_far_hits_only_clear() {
    let model = InverseSensorModel {
        no_return_range: 0.5,
        max_range: 2.0,
        ..Default::default()
    };
    let mut g = OccupancyGrid::new(0.1, model);
    // Beam 0 along +x: no return (30 m); beam 1 along +y: a hit at 5 m, beyond max_range.
    let s = scan(vec![30.0, 5.0], 0.0, std::f64::consts::FRAC_PI_2);
    g.integrate_scan(&Pose2::new(0.05, 0.05, 0.0), &s);
    assert!(g.log_odds(CellIndex::new(4, 0)) < 0.0);
    assert_eq!(g.log_odds(CellIndex::new(6, 0)), 0.0);
    assert!(g.log_odds(CellIndex::new(0, 19)) < 0.0);
    assert_eq!(g.log_odds(CellIndex::new(0, 21)), 0.0);
    assert!((0..60).all(|j| g.log_odds(CellIndex::new(0, j)) <= 0.0));
}

#[test]
fn grows_in_every_direction_and_exports() {
    let mut g = OccupancyGrid::new(0.05, InverseSensorModel::default());
    let pose = Pose2::new(-3.0, 7.0, 0.3);
    let s = room_scan(&Pose2::new(0.0, 0.0, 0.3), 4.0, 360);
    // The room seen from its centre, placed around (−3, 7): walls at x = −7, 1, y = 3, 11.
    g.integrate_scan(&pose, &s);
    // Beam 0 points along the heading (0.3 rad) and meets the wall x = 1 at y = 7 + 4·tan 0.3.
    let wall = g.world_to_cell(&Point2::new(1.0, 7.0 + 4.0 * 0.3f64.tan()));
    let near = [-1, 0, 1]
        .iter()
        .flat_map(|&dx| [-1, 0, 1].map(|dy| CellIndex::new(wall.x + dx, wall.y + dy)))
        .any(|c| g.log_odds(c) > 0.0);
    assert!(near, "no occupied cell near the wall");
    let map = g.to_grid_map();
    let (lo, hi) = g.known_bounds().unwrap();
    assert_eq!(map.width, (hi.x - lo.x + 1) as usize);
    assert!(map.width as f64 * 0.05 > 7.9 && map.width as f64 * 0.05 < 8.3);
    // The robot's own cell is free, and its map cell agrees with the grid.
    let robot = Point2::new(-3.01, 7.01);
    let c = g.world_to_cell(&robot);
    let (ix, iy) = map.cell_of(&robot).unwrap();
    assert_eq!(((ix as i32) + lo.x, (iy as i32) + lo.y), (c.x, c.y));
    assert!(map.get(ix, iy).unwrap() < 50 && map.get(ix, iy).unwrap() >= 0);
    assert!(map.cells.iter().any(|&v| v > 50));
}

#[test]
fn clone_shares_tiles_and_writes_copy_only_touched_ones() {
    // A 100 m × 100 m... no: 10⁶ cells = 50 m × 50 m at 5 cm, all tiles allocated.
    let mut g = OccupancyGrid::new(0.05, InverseSensorModel::default());
    for y in 0..5 {
        for x in 0..5 {
            let p = Pose2::new(-20.0 + 10.0 * x as f64, -20.0 + 10.0 * y as f64, 0.0);
            g.integrate_scan(&p, &room_scan(&Pose2::IDENTITY, 4.9, 720));
        }
    }
    let before = g.allocated_tiles();
    assert!(before >= 900, "{before} tiles allocated");
    let mut c = g.clone();
    assert_eq!(c.shared_tiles(), before);
    c.reset_copy_stats();
    // One short-range scan (3 m room) touches a handful of tiles only.
    let pose = Pose2::new(0.0, 0.0, 0.0);
    let s = room_scan(&Pose2::IDENTITY, 1.5, 360);
    c.integrate_scan(&pose, &s);
    let st = c.copy_stats();
    // The scan spans 3 m = 60 cells: at most ⌈60/32⌉+1 = 3 tiles per axis.
    assert!(st.tiles_copied >= 1 && st.tiles_copied <= 9, "{st:?}");
    assert_eq!(
        st.bytes_copied,
        st.tiles_copied * OccupancyGrid::TILE_BYTES as u64
    );
    assert_eq!(st.tiles_created, 0);
    // The original is untouched; the copy changed.
    let wall = c.world_to_cell(&Point2::new(1.5, 0.0));
    assert!(c.log_odds(wall) > 0.0);
    assert!(g.log_odds(wall) < 0.0, "original grid was modified");
    assert_eq!(c.shared_tiles() as u64, before as u64 - st.tiles_copied);
    // Writing the same scan again copies nothing more (the tiles are now private).
    c.reset_copy_stats();
    c.integrate_scan(&pose, &s);
    assert_eq!(c.copy_stats().tiles_copied, 0);
}

#[test]
fn tile_fields_match_dense_field_and_brute_force() {
    let mut g = OccupancyGrid::new(0.05, InverseSensorModel::default())
        .with_likelihood(LikelihoodParams {
            subcell: false,
            ..Default::default()
        })
        .unwrap();
    g.integrate_scan(
        &Pose2::new(0.3, -0.2, 0.1),
        &room_scan(&Pose2::new(0.3, -0.2, 0.1), 2.0, 360),
    );
    let params = g.likelihood_params();
    let (lo, hi) = g.known_bounds().unwrap();
    let lo = CellIndex::new(lo.x - 8, lo.y - 8);
    let hi = CellIndex::new(hi.x + 8, hi.y + 8);
    let dense = LikelihoodField::from_grid(&g, lo, hi);
    let obstacles: Vec<CellIndex> = (lo.y..=hi.y)
        .flat_map(|y| (lo.x..=hi.x).map(move |x| CellIndex::new(x, y)))
        .filter(|&c| g.is_obstacle(c))
        .collect();
    assert!(obstacles.len() > 100);
    for y in (lo.y..=hi.y).step_by(3) {
        for x in (lo.x..=hi.x).step_by(3) {
            let c = CellIndex::new(x, y);
            let d = obstacles
                .iter()
                .map(|o| (((o.x - x) as f64).powi(2) + ((o.y - y) as f64).powi(2)).sqrt())
                .fold(f64::INFINITY, f64::min)
                * 0.05;
            let want = params.field_value(d);
            assert!((dense.value(c) - want).abs() < 1e-6, "dense at {c:?}");
            assert!((g.likelihood(c) - want).abs() < 1e-6, "tile at {c:?}");
        }
    }
    // A write far away keeps cached fields; a write changing obstacles here refreshes them.
    let probe = g.world_to_cell(&Point2::new(1.0, 0.0));
    let before = g.likelihood(probe);
    g.integrate_scan(&Pose2::new(0.0, 0.0, 0.0), &scan(vec![1.0; 5], -0.02, 0.01));
    g.integrate_scan(&Pose2::new(0.0, 0.0, 0.0), &scan(vec![1.0; 5], -0.02, 0.01));
    let after = g.likelihood(probe);
    assert!(
        before < 0.9 && (after - 1.0).abs() < 1e-6,
        "{before} -> {after}"
    );
}

#[test]
fn interpolation_gradient_matches_finite_differences() {
    let mut g = OccupancyGrid::new(0.05, InverseSensorModel::default());
    g.integrate_scan(&Pose2::IDENTITY, &room_scan(&Pose2::IDENTITY, 1.0, 360));
    for &(x, y) in &[(0.913, 0.1234), (0.87, -0.55), (-0.9311, 0.402)] {
        let p = Point2::new(x, y);
        let (_, grad) = g.likelihood_interpolated(&p);
        let h = 1e-5;
        let (_, gc) = g.likelihood_bicubic(&p);
        let cx = (g.likelihood_bicubic(&Point2::new(x + h, y)).0
            - g.likelihood_bicubic(&Point2::new(x - h, y)).0)
            / (2.0 * h);
        let cy = (g.likelihood_bicubic(&Point2::new(x, y + h)).0
            - g.likelihood_bicubic(&Point2::new(x, y - h)).0)
            / (2.0 * h);
        assert!(
            (gc[0] - cx).abs() < 1e-4 && (gc[1] - cy).abs() < 1e-4,
            "{gc:?} vs {cx},{cy}"
        );
        // Both interpolants reproduce the samples at cell centres.
        let c = g.world_to_cell(&p);
        let centre = g.cell_center(c);
        assert!((g.likelihood_bicubic(&centre).0 - g.likelihood(c) as f64).abs() < 1e-5);
        assert!((g.likelihood_interpolated(&centre).0 - g.likelihood(c) as f64).abs() < 1e-6);
        let fx = (g.likelihood_interpolated(&Point2::new(x + h, y)).0
            - g.likelihood_interpolated(&Point2::new(x - h, y)).0)
            / (2.0 * h);
        let fy = (g.likelihood_interpolated(&Point2::new(x, y + h)).0
            - g.likelihood_interpolated(&Point2::new(x, y - h)).0)
            / (2.0 * h);
        assert!(
            (grad[0] - fx).abs() < 1e-4 && (grad[1] - fy).abs() < 1e-4,
            "{grad:?} vs {fx},{fy}"
        );
    }
}

#[test]
fn rejects_invalid_input() {
    let mut g = OccupancyGrid::new(0.05, InverseSensorModel::default());
    assert!(g
        .try_integrate_scan(&Pose2::new(f64::NAN, 0.0, 0.0), &scan(vec![1.0], 0.0, 0.0))
        .is_err());
    assert!(g
        .try_integrate_scan(&Pose2::IDENTITY, &scan(vec![f64::INFINITY], 0.0, 0.0))
        .is_err());
    assert!(g
        .try_integrate_scan(&Pose2::IDENTITY, &scan(vec![-1.0], 0.0, 0.0))
        .is_err());
    assert_eq!(g.allocated_tiles(), 0);
    assert!(OccupancyGrid::try_new(0.0, InverseSensorModel::default()).is_err());
}

#[test]
fn subcell_field_measures_to_mean_hit_positions() {
    // A wall at x = 1.013 (not on a cell boundary), seen head-on by many beams.
    let mut g = OccupancyGrid::new(0.05, InverseSensorModel::default());
    let n = 41;
    let ranges: Vec<f64> = (0..n)
        .map(|k| 1.013 / (-0.2 + 0.01 * k as f64).cos())
        .collect();
    let s = scan(ranges, -0.2, 0.01);
    g.integrate_scan(&Pose2::IDENTITY, &s);
    // Cell column 20 covers [1.00, 1.05): its centre (1.025) is 1.2 cm from the wall. The
    // field is measured from the mean of the end points in the cell's 3×3 neighbourhood.
    let c = g.world_to_cell(&Point2::new(1.013, 0.0));
    assert_eq!(c.x, 20);
    let inside: Vec<Point2> = s
        .hit_points()
        .into_iter()
        .filter(|p| {
            let q = g.world_to_cell(p);
            (q.x - c.x).abs() <= 1 && (q.y - c.y).abs() <= 1
        })
        .collect();
    let mean = inside
        .iter()
        .fold(Point2::origin(), |a, p| a + p.coords / inside.len() as f64);
    let params = g.likelihood_params();
    let want = params.field_value((mean - g.cell_center(c)).norm());
    assert!(
        (g.likelihood(c) - want).abs() < 2e-3,
        "{} vs {want}",
        g.likelihood(c)
    );
    // Two cells in front: 1.013 − 0.925 = 8.8 cm.
    let f = CellIndex::new(c.x - 2, c.y);
    let want = params.field_value((mean - g.cell_center(f)).norm());
    assert!((g.likelihood(f) - want).abs() < 2e-3);
    // The bicubic interpolant along x peaks within 2 mm of the wall (a cell-centred
    // interpolant would peak at 1.025).
    let best = (0..200)
        .map(|i| 0.95 + i as f64 * 0.0005)
        .max_by(|a, b| {
            let fa = g.likelihood_bicubic(&Point2::new(*a, 0.01)).0;
            let fb = g.likelihood_bicubic(&Point2::new(*b, 0.01)).0;
            fa.total_cmp(&fb)
        })
        .unwrap();
    assert!((best - 1.013).abs() < 0.002, "peak at {best}");
}

#[test]
fn protected_scan_hits_are_marked_once_and_not_cleared_by_the_same_scan() {
    // Along +x from the centre of cell (0, 0) on a 10 cm grid: beams 0 and 2 end in cell
    // (10, 0), beam 1 crosses it and ends in cell (20, 0).
    let s = scan(vec![1.0, 2.0, 1.01], 0.0, 0.0);
    let pose = Pose2::new(0.05, 0.05, 0.0);
    let m = InverseSensorModel {
        hit_margin: 0.0,
        ..Default::default()
    };
    let mut every = OccupancyGrid::new(0.1, m);
    every.integrate_scan(&pose, &s);
    let mut once = OccupancyGrid::new(
        0.1,
        InverseSensorModel {
            protect_scan_hits: true,
            ..m
        },
    );
    once.integrate_scan(&pose, &s);
    let c = |x| CellIndex::new(x, 0);
    // Every beam counts: crossed once, hit twice.
    assert_eq!(every.log_odds(c(10)), m.l_free + 2.0 * m.l_occ);
    // Protected: one l_occ, and beam 1 does not clear it.
    assert_eq!(once.log_odds(c(10)), m.l_occ);
    for g in [&every, &once] {
        assert_eq!(g.log_odds(c(20)), m.l_occ);
        assert_eq!(g.log_odds(c(15)), m.l_free);
        assert_eq!(g.log_odds(c(5)), (3.0 * m.l_free).max(m.l_min));
    }
}

#[test]
fn without_subcell_fields_tiles_keep_no_hit_statistics() {
    let params = LikelihoodParams {
        subcell: false,
        ..Default::default()
    };
    let mut g = OccupancyGrid::new(0.05, InverseSensorModel::default())
        .with_likelihood(params)
        .unwrap();
    let s = room_scan(&Pose2::IDENTITY, 1.5, 360);
    g.integrate_scan(&Pose2::IDENTITY, &s);
    let mut c = g.clone();
    c.reset_copy_stats();
    c.integrate_scan(&Pose2::new(0.2, 0.1, 0.0), &s);
    let st = c.copy_stats();
    // Log-odds only: 4 KiB per copied tile, and 128 bytes of lower-clamp bits.
    assert!(st.tiles_copied >= 1, "{st:?}");
    assert_eq!(st.bytes_copied, st.tiles_copied * (4096 + 128));
    // Every obstacle is at its cell centre for the field.
    let (lo, hi) = g.known_bounds().unwrap();
    let (w, h) = ((hi.x - lo.x + 1) as usize, (hi.y - lo.y + 1) as usize);
    let (obstacles, offsets) = c.obstacle_mask(lo, w, h);
    assert!(obstacles.iter().any(|&o| o));
    assert!(offsets.iter().all(|&o| o == (0, 0, 0)));
}

/// A grid with an incremental distance field, as grid FastSLAM's particles use.
fn grid_with_distance() -> OccupancyGrid {
    OccupancyGrid::new(0.05, InverseSensorModel::default())
        .with_incremental_distance(4)
        .unwrap()
}

/// A scan far from the rest of the map (a glitched pose) costs the tiles it touches, not
/// the box between: two rooms 800 m apart diagonally (16 000 cells at 5 cm, a box of
/// 2.5·10⁸ cells that a dense table spans with 250 000 slots) store a few hundred tiles,
/// and every value around the first room equals that of a grid that never saw the second.
#[test]
fn memory_grows_with_the_area_seen_not_with_the_box_of_far_scans() {
    let near = Pose2::new(0.3, -0.2, 0.1);
    let s = room_scan(&near, 2.0, 360);
    let mut a = grid_with_distance();
    a.try_integrate_scan(&near, &s).unwrap();
    let mut b = grid_with_distance();
    b.try_integrate_scan(&near, &s).unwrap();
    b.try_integrate_scan(&Pose2::new(800.0, 790.0, 0.1), &s)
        .unwrap();
    assert!(b.table.rect().len() > tiles::DENSE_TABLE_MAX_TILES);
    // Each room is 4 m = 80 cells across: 4×4 tiles, plus their neighbours.
    assert_eq!(b.allocated_tiles(), 2 * a.allocated_tiles());
    assert!(a.allocated_tiles() <= 16, "{}", a.allocated_tiles());
    assert!(b.table.len() <= 2 * 36, "{} slots", b.table.len());
    assert_eq!(b.tiles.len(), b.table.len());
    // Clones copy the stored tiles' table only.
    let c = b.clone();
    assert_eq!(c.shared_tiles(), b.allocated_tiles());
    // Same values around the first room, read through the hash index (b) and through the
    // dense table (a): occupancy, lazy field, incremental distance field.
    let (lo, hi) = a.covered_cells().unwrap();
    let (fa, fb) = (a.distance_field().unwrap(), b.distance_field().unwrap());
    let mut checked = 0;
    for y in lo.y..=hi.y {
        for x in lo.x..=hi.x {
            let c = CellIndex::new(x, y);
            assert_eq!(a.log_odds(c), b.log_odds(c), "{c:?}");
            assert_eq!(a.likelihood(c), b.likelihood(c), "{c:?}");
            assert_eq!(a.distance_squared(c), b.distance_squared(c), "{c:?}");
            assert_eq!(fa.dist(c), fb.dist(c), "{c:?}");
            checked += (fa.dist(c) < fa.max_units()) as usize;
        }
    }
    assert!(checked > 500, "{checked} cells near obstacles");
    let p = Point2::new(2.01, 0.37);
    assert_eq!(a.likelihood_bicubic(&p), b.likelihood_bicubic(&p));
    // Both rooms are in the export, which spans the box: 2.5·10⁸ cells is within
    // MAX_MAP_CELLS, so it is made (not checked here: 256 MB); its bounds are.
    let (klo, khi) = b.known_bounds().unwrap();
    assert!(khi.x - klo.x > 16_000 && khi.y - klo.y > 15_800);
}

/// A scan that would stretch the map beyond its maximum extent (a 10 km or 1000 km
/// odometry glitch) is refused with an error naming the bound, and changes nothing.
#[test]
fn a_scan_beyond_the_maximum_extent_is_refused_and_changes_nothing() {
    let near = Pose2::new(0.3, -0.2, 0.1);
    let s = room_scan(&near, 2.0, 360);
    let mut g = grid_with_distance();
    g.try_integrate_scan(&near, &s).unwrap();
    let (tiles_before, bounds_before) = (g.allocated_tiles(), g.known_bounds());
    let map_before = g.to_grid_map();
    for far in [
        Pose2::new(10_000.0, 0.0, 0.0),
        Pose2::new(0.0, -1.0e6, 0.0),
        // Within the per-side extent (2 km = 40 000 cells) but not the area (1.6·10⁹ cells).
        Pose2::new(2_000.0, 2_000.0, 0.0),
    ] {
        let err = g.try_integrate_scan(&far, &s).unwrap_err();
        let GridError::MapTooLarge { width, height, .. } = err else {
            panic!("{err:?}");
        };
        assert!(
            width.max(height) > MAX_MAP_EXTENT_CELLS || width * height > MAX_MAP_CELLS,
            "{width} × {height}"
        );
        let msg = err.to_string();
        assert!(
            msg.contains("maximum extent") && msg.contains(&MAX_MAP_EXTENT_CELLS.to_string()),
            "{msg}"
        );
    }
    assert_eq!(g.allocated_tiles(), tiles_before);
    assert_eq!(g.known_bounds(), bounds_before);
    assert_eq!(g.to_grid_map(), map_before);
    // The grid still takes scans near the map.
    g.try_integrate_scan(&Pose2::new(1.0, 0.0, 0.0), &s)
        .unwrap();
}

/// `check_integrable` refuses exactly what the integration refuses (a non-finite pose, a
/// scan beyond the maximum extent, NaN-free input otherwise accepted) and changes nothing:
/// grid FastSLAM checks every particle's integration at its scan and integrates later.
#[test]
fn check_integrable_agrees_with_the_integration() {
    let near = Pose2::new(0.3, -0.2, 0.1);
    let s = room_scan(&near, 2.0, 360);
    let prepared = crate::RangeData::new(&s, &Default::default()).unwrap();
    let mut g = grid_with_distance();
    g.try_integrate_prepared(&near, &prepared).unwrap();
    let map_before = g.to_grid_map();
    for pose in [
        near,
        Pose2::new(1.0, 0.5, -0.3),
        Pose2::new(f64::NAN, 0.0, 0.0),
        Pose2::new(10_000.0, 0.0, 0.0),
        Pose2::new(2_000.0, 2_000.0, 0.0),
    ] {
        let checked = g.check_integrable(&pose, &prepared);
        assert_eq!(g.to_grid_map(), map_before, "the check changed the grid");
        let mut copy = g.clone();
        let done = copy.try_integrate_prepared(&pose, &prepared);
        assert_eq!(
            checked.as_ref().err().map(ToString::to_string),
            done.as_ref().err().map(ToString::to_string),
            "{pose:?}"
        );
    }
}

/// `obstacle_bounds` is the box of the walls of a room (x from −7 to 1 m, y from 3 to 11 m,
/// within two cells), and the brute-force box of `is_obstacle` over the observed rectangle
/// under thresholds above, at and below zero (below: unknown cells count) and above every
/// cell (`None`).
#[test]
fn obstacle_bounds_is_the_box_of_the_obstacles() {
    for thr in [0.0, 0.5, -0.5, 100.0] {
        let params = LikelihoodParams {
            occupied_threshold: thr,
            ..Default::default()
        };
        let mut g = OccupancyGrid::new(0.05, InverseSensorModel::default())
            .with_likelihood(params)
            .unwrap();
        g.integrate_scan(
            &Pose2::new(-3.0, 7.0, 0.3),
            &room_scan(&Pose2::new(0.0, 0.0, 0.3), 4.0, 360),
        );
        let (lo, hi) = g.known_bounds().unwrap();
        let mut brute: Option<(CellIndex, CellIndex)> = None;
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                if g.is_obstacle(CellIndex::new(x, y)) {
                    let (a, b) = brute.unwrap_or((CellIndex::new(x, y), CellIndex::new(x, y)));
                    brute = Some((
                        CellIndex::new(a.x.min(x), a.y.min(y)),
                        CellIndex::new(b.x.max(x), b.y.max(y)),
                    ));
                }
            }
        }
        assert_eq!(g.obstacle_bounds(), brute, "threshold {thr}");
        assert_eq!(brute.is_none(), thr == 100.0, "threshold {thr}");
        if thr == 0.0 {
            let (a, b) = brute.unwrap();
            let walls = [(a.x, -7.0), (b.x, 1.0), (a.y, 3.0), (b.y, 11.0)];
            for (cell, metres) in walls {
                assert!(
                    (cell as f64 * 0.05 - metres).abs() <= 0.1,
                    "{cell} vs {metres} m"
                );
            }
        }
    }
}

/// A minimum range at or beyond the maximum leaves no reading to map: refused by key
/// (`[sensor-model] min-range = 1e300` ended a known-poses run on an error about the
/// staging folder's empty map.pgm).
#[test]
fn min_range_at_or_beyond_max_range_is_refused() {
    for min_range in [20.0, 21.0, 1e300] {
        let model = InverseSensorModel {
            max_range: 20.0,
            min_range,
            ..InverseSensorModel::default()
        };
        match model.validate() {
            Err(crate::GridError::InvalidConfig(e)) => assert_eq!(e.field, "min_range"),
            other => panic!("min_range {min_range}: {other:?}"),
        }
    }
    InverseSensorModel {
        max_range: 20.0,
        min_range: 19.9,
        ..InverseSensorModel::default()
    }
    .validate()
    .unwrap();
}
