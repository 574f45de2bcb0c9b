//! Matching benchmarks: one correlative + Gauss-Newton match of a 180-beam scan (the
//! default windows: ±0.4 m, ±12°), and the stages on their own; the same match on a grid
//! whose field measures to fitted lines (`LikelihoodParams::surface_lines`), and the
//! field of the whole room computed from scratch both ways; and grid FastSLAM's wide
//! search of a poor match (indoor window ±1.5 m / ±0.4 rad) by branch and bound over a
//! pyramid built per search against the brute-force lattice search it replaced; and the
//! best particle's coarse search (indoor window ±0.3 m / ±0.9 rad) by branch and bound
//! against the exhaustive search over the same lattice; and the endpoint scorer alone against
//! the one before issue 21's speed work.
// criterion_group! generates undocumented public functions.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, Criterion};
use slam_grid::{
    CellIndex, CorrelativeMatcher, GaussNewtonMatcher, HillClimbMatcher, InverseSensorModel,
    LikelihoodField, LikelihoodParams, OccupancyGrid, RangeData, RefinedCorrelativeMatcher,
};
use slam_models::{LaserScan, Pose2};
use std::hint::black_box;

/// Ray casting in a 10 m × 6 m room with a box and a pillar (segments).
fn cast(x: f64, y: f64, a: f64) -> f64 {
    let segs = [
        (0.0, 0.0, 10.0, 0.0),
        (10.0, 0.0, 10.0, 6.0),
        (10.0, 6.0, 0.0, 6.0),
        (0.0, 6.0, 0.0, 0.0),
        (3.0, 1.0, 4.2, 1.0),
        (4.2, 1.0, 4.2, 1.7),
        (4.2, 1.7, 3.0, 1.7),
        (3.0, 1.7, 3.0, 1.0),
        (7.0, 3.5, 7.3, 3.5),
        (7.3, 3.5, 7.3, 3.8),
        (7.3, 3.8, 7.0, 3.8),
        (7.0, 3.8, 7.0, 3.5),
        (6.0, 6.0, 8.0, 4.5),
    ];
    let (dx, dy) = (a.cos(), a.sin());
    let mut best = 30.0f64;
    for (px, py, qx, qy) in segs {
        let (ex, ey) = (qx - px, qy - py);
        let den = dx * ey - dy * ex;
        if den.abs() < 1e-12 {
            continue;
        }
        let (wx, wy) = (px - x, py - y);
        let t = (wx * ey - wy * ex) / den;
        let u = (wx * dy - wy * dx) / den;
        if t > 0.0 && (0.0..=1.0).contains(&u) {
            best = best.min(t);
        }
    }
    best
}

fn scan_at(p: &Pose2, n: usize, fov: f64) -> LaserScan {
    let inc = fov / n as f64;
    let amin = -fov / 2.0;
    LaserScan {
        angle_min: amin,
        angle_increment: inc,
        ranges: (0..n)
            .map(|k| cast(p.x, p.y, p.theta + amin + k as f64 * inc))
            .collect(),
        max_range: 30.0,
        sensor_pose: Pose2::IDENTITY,
    }
}

/// The room mapped from 16 full scans, with the given likelihood parameters.
fn room_grid(params: LikelihoodParams) -> OccupancyGrid {
    let mut grid = OccupancyGrid::new(0.05, InverseSensorModel::default())
        .with_likelihood(params)
        .expect("valid parameters");
    for &(x, y) in &[(1.5, 3.0), (5.0, 3.0), (8.5, 2.0), (5.5, 5.0)] {
        for k in 0..4 {
            let p = Pose2::new(x, y, k as f64 * std::f64::consts::FRAC_PI_2);
            grid.integrate_scan(&p, &scan_at(&p, 720, std::f64::consts::TAU));
        }
    }
    grid
}

fn matching(c: &mut Criterion) {
    let grid = room_grid(LikelihoodParams::default());
    let lines = LikelihoodParams {
        surface_lines: true,
        ..Default::default()
    };
    let grid_lines = room_grid(lines);
    let truth = Pose2::new(5.2, 2.9, 0.4);
    let scan = RangeData::new(
        &scan_at(&truth, 180, std::f64::consts::PI),
        &Default::default(),
    )
    .expect("scan");
    let initial = Pose2::new(5.4, 2.75, 0.4 + 0.12);
    let refined = RefinedCorrelativeMatcher::default();
    // Warm the per-tile field cache (as it is after the first match in a filter).
    let r = refined
        .match_prepared(&grid, &scan, &initial)
        .expect("match");
    println!("match error {:.4} m", r.pose.distance(&truth));
    let r = refined
        .match_prepared(&grid_lines, &scan, &initial)
        .expect("match");
    println!(
        "match error with surface lines {:.4} m",
        r.pose.distance(&truth)
    );
    let mut g = c.benchmark_group("scan_match");
    g.bench_function("correlative_plus_gauss_newton_180_beams", |b| {
        b.iter(|| refined.match_prepared(black_box(&grid), &scan, black_box(&initial)))
    });
    g.bench_function(
        "correlative_plus_gauss_newton_180_beams_surface_lines",
        |b| b.iter(|| refined.match_prepared(black_box(&grid_lines), &scan, black_box(&initial))),
    );
    // The field of the whole room (≈ 250 × 170 cells with the margin), from scratch.
    let (lo, hi) = (CellIndex::new(-20, -20), CellIndex::new(220, 140));
    g.bench_function("likelihood_field_room", |b| {
        b.iter(|| LikelihoodField::from_grid(black_box(&grid), lo, hi))
    });
    g.bench_function("likelihood_field_room_surface_lines", |b| {
        b.iter(|| LikelihoodField::from_grid(black_box(&grid_lines), lo, hi))
    });
    let corr = CorrelativeMatcher::default();
    g.bench_function("correlative_only_180_beams", |b| {
        b.iter(|| corr.match_prepared(black_box(&grid), &scan, black_box(&initial)))
    });
    let near = Pose2::new(truth.x + 0.03, truth.y - 0.02, truth.theta + 0.01);
    let gn = GaussNewtonMatcher::default();
    g.bench_function("gauss_newton_only_180_beams", |b| {
        b.iter(|| gn.match_prepared(black_box(&grid), &scan, black_box(&near)))
    });
    let hc = HillClimbMatcher::default();
    g.bench_function("hill_climb_only_180_beams", |b| {
        b.iter(|| hc.match_prepared(black_box(&grid), &scan, black_box(&near)))
    });
    g.finish();
}

/// The room mapped from four places with four 720-beam turns each, on 5 cm cells with the
/// incremental distance field (4-cell reach) that the endpoint model reads.
fn room_with_field() -> OccupancyGrid {
    let mut grid = OccupancyGrid::new(0.05, InverseSensorModel::default())
        .with_incremental_distance(4)
        .expect("radius");
    for &(x, y) in &[(1.5, 3.0), (5.0, 3.0), (8.5, 2.0), (5.5, 5.0)] {
        for k in 0..4 {
            let p = Pose2::new(x, y, k as f64 * std::f64::consts::FRAC_PI_2);
            grid.integrate_scan(&p, &scan_at(&p, 720, std::f64::consts::TAU));
        }
    }
    grid
}

/// The pose the endpoint benches match and its 180-beam, 180° scan.
fn scan_in_room() -> (Pose2, RangeData) {
    let truth = Pose2::new(5.2, 2.9, 0.4);
    let scan = RangeData::new(
        &scan_at(&truth, 180, std::f64::consts::PI),
        &Default::default(),
    )
    .expect("scan");
    (truth, scan)
}

fn wide_search(c: &mut Criterion) {
    use slam_grid::matcher::endpoint::{self, EndpointModel, SearchWindow};
    use slam_models::{Matrix3, Vector3};
    let grid = room_with_field();
    let field = grid.distance_field().expect("incremental field");
    let (truth, scan) = scan_in_room();
    // A 1.2 m / 17° odometry error; the gridfast defaults (indoor preset, gain 3).
    let initial = Pose2::new(4.3, 3.7, 0.1);
    let capture = EndpointModel::new(0.05, 0.2, 3.0);
    let window = SearchWindow {
        range_xy: 1.5,
        step_xy: 0.1,
        range_theta: 0.4,
        step_theta: 0.02,
        information: Matrix3::from_diagonal(&Vector3::new(1.8, 1.8, 25.0)),
    };
    let w = endpoint::wide_search(&field, &scan, &initial, &capture, &window).expect("search");
    let b = endpoint::grid_search_exhaustive(&field, &scan, &initial, &capture, &window);
    println!(
        "wide search: branch and bound {:.3} m off ({} pyramid cells), brute force {:.3} m off",
        w.pose.distance(&truth),
        w.pyramid_cells,
        b.distance(&truth)
    );
    let mut g = c.benchmark_group("wide_search");
    g.bench_function("branch_and_bound_with_pyramid_180_beams", |b| {
        b.iter(|| endpoint::wide_search(&field, &scan, black_box(&initial), &capture, &window))
    });
    // One rotation: mostly the cost of building the pyramid.
    let one = SearchWindow {
        range_theta: 0.0,
        ..window
    };
    g.bench_function("branch_and_bound_one_rotation_180_beams", |b| {
        b.iter(|| endpoint::wide_search(&field, &scan, black_box(&initial), &capture, &one))
    });
    g.bench_function("brute_force_180_beams", |b| {
        b.iter(|| {
            endpoint::grid_search_exhaustive(&field, &scan, black_box(&initial), &capture, &window)
        })
    });
    g.finish();
}

/// Grid FastSLAM's coarse search of the best particle (the indoor preset's window: ±0.3 m
/// in 5 cm steps, ±0.9 rad in 0.025 rad steps, 12 337 poses) by branch and bound over a
/// min-pyramid built per search, against the exhaustive search over the same lattice; both
/// return the same pose.
fn coarse_search(c: &mut Criterion) {
    use slam_grid::matcher::endpoint::{self, EndpointModel, SearchWindow};
    use slam_models::{Matrix3, Vector3};
    let grid = room_with_field();
    let field = grid.distance_field().expect("incremental field");
    let (truth, scan) = scan_in_room();
    // A 0.14 m / 0.2 rad odometry error; the indoor preset's capture model (gain 3).
    let initial = Pose2::new(5.3, 2.8, 0.2);
    let capture = EndpointModel::new(0.05, 0.2, 3.0);
    let window = SearchWindow {
        range_xy: 0.3,
        step_xy: 0.05,
        range_theta: 0.9,
        step_theta: 0.025,
        information: Matrix3::from_diagonal(&Vector3::new(100.0, 100.0, 25.0)),
    };
    let fast = endpoint::grid_search(&field, &scan, &initial, &capture, &window);
    let slow = endpoint::grid_search_exhaustive(&field, &scan, &initial, &capture, &window);
    assert_eq!(fast, slow, "branch and bound against exhaustive");
    println!(
        "coarse search: {:.3} m, {:.3} rad off the truth",
        fast.distance(&truth),
        (fast.theta - truth.theta).abs()
    );
    let mut g = c.benchmark_group("coarse_search");
    g.bench_function("branch_and_bound_indoor_window_180_beams", |b| {
        b.iter(|| endpoint::grid_search(&field, &scan, black_box(&initial), &capture, &window))
    });
    g.bench_function("exhaustive_indoor_window_180_beams", |b| {
        b.iter(|| {
            endpoint::grid_search_exhaustive(&field, &scan, black_box(&initial), &capture, &window)
        })
    });
    g.finish();
}

/// The endpoint scorer alone (grid FastSLAM's inner loop): a 180-beam scan (every point,
/// and the coarse subset) scored at 64 poses within a few centimetres of the truth on the
/// incremental field of the room (5 cm cells, 4-cell reach), the current scorer against
/// the f64 reference it replaced (`endpoint::score_reference`) in the same run.
fn endpoint_score(c: &mut Criterion) {
    use slam_grid::matcher::endpoint::{self, EndpointModel};
    let grid = room_with_field();
    let field = grid.distance_field().expect("incremental field");
    let (truth, scan) = scan_in_room();
    let model = EndpointModel::new(0.05, 0.15, 3.0);
    let poses: Vec<Pose2> = (0..64)
        .map(|i| {
            let t = i as f64;
            Pose2::new(
                truth.x + 0.04 * (0.7 * t).sin(),
                truth.y + 0.04 * (1.3 * t).cos(),
                truth.theta + 0.03 * (0.9 * t).sin(),
            )
        })
        .collect();
    let mut g = c.benchmark_group("endpoint_score");
    g.bench_function("score_180_beams_64_poses", |b| {
        b.iter(|| {
            poses
                .iter()
                .map(|p| endpoint::score_scan(&field, &scan, black_box(p), &model).log_likelihood)
                .sum::<f64>()
        })
    });
    g.bench_function("score_reference_180_beams_64_poses", |b| {
        b.iter(|| {
            poses
                .iter()
                .map(|p| {
                    endpoint::score_reference(&field, scan.points(), black_box(p), &model)
                        .log_likelihood
                })
                .sum::<f64>()
        })
    });
    g.bench_function("coarse_score_64_poses", |b| {
        b.iter(|| {
            poses
                .iter()
                .map(|p| endpoint::coarse_score(&field, &scan, black_box(p), &model))
                .sum::<f64>()
        })
    });
    g.bench_function("coarse_score_reference_64_poses", |b| {
        b.iter(|| {
            poses
                .iter()
                .map(|p| {
                    endpoint::score_reference(&field, scan.coarse_points(), black_box(p), &model)
                        .log_likelihood
                })
                .sum::<f64>()
        })
    });
    g.finish();
}

criterion_group!(
    benches,
    matching,
    wide_search,
    coarse_search,
    endpoint_score
);
criterion_main!(benches);
