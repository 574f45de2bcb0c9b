//! Matcher tests on a synthetic office with exact ray casting.

use super::*;
use crate::testutil::SegmentWorld;
use crate::InverseSensorModel;
use rand::{Rng, SeedableRng};

/// The map of the office built from noise-free 360° scans at known poses.
fn office_map(res: f64) -> OccupancyGrid {
    let world = SegmentWorld::office();
    // The grid is not aligned with the walls (as with any real map).
    let mut g = OccupancyGrid::new(res, InverseSensorModel::default())
        .with_origin(slam_models::Point2::new(-0.0137, -0.0311))
        .unwrap();
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(1);
    for &(x, y) in &[
        (1.5, 3.0),
        (5.0, 3.5),
        (10.5, 2.0),
        (2.0, 6.5),
        (9.0, 6.5),
        (7.0, 4.2),
        (4.5, 1.0),
    ] {
        for k in 0..4 {
            let pose = Pose2::new(x, y, k as f64 * 1.57);
            let mut scan = world.scan(&pose, 720, std::f64::consts::TAU * 0.999, 30.0);
            add_noise(&mut scan, &mut rng);
            g.integrate_scan(&pose, &scan);
        }
    }
    g
}

/// Range noise σ = 1 cm (as the simulated office laser).
fn add_noise(scan: &mut slam_models::LaserScan, rng: &mut rand_pcg::Pcg64Mcg) {
    let n = rand_distr::Normal::new(0.0, 0.01).unwrap();
    for r in scan.ranges.iter_mut().filter(|r| **r < 30.0) {
        *r = (*r + rng.sample(n)).max(0.0);
    }
}

fn trial_poses(n: usize, seed: u64) -> Vec<(Pose2, Pose2)> {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    let spots = [(2.5, 3.2), (5.2, 3.8), (9.5, 2.5), (3.0, 6.3), (8.5, 6.8)];
    (0..n)
        .map(|i| {
            let (x, y) = spots[i % spots.len()];
            let truth = Pose2::new(
                x + rng.random_range(-0.2..0.2),
                y + rng.random_range(-0.2..0.2),
                rng.random_range(-3.1..3.1),
            );
            // Offsets up to 0.3 m (in a disk) and 10°.
            let r = 0.3 * rng.random::<f64>().sqrt();
            let a = rng.random_range(0.0..std::f64::consts::TAU);
            let dth = rng.random_range(-10f64..10.0).to_radians();
            let initial = Pose2::new(
                truth.x + r * a.cos(),
                truth.y + r * a.sin(),
                truth.theta + dth,
            );
            (truth, initial)
        })
        .collect()
}

#[test]
fn correlative_equals_brute_force_on_its_lattice() {
    let g = office_map(0.05);
    let world = SegmentWorld::office();
    let m = CorrelativeMatcher {
        linear_window: 0.2,
        angular_window: 0.05,
        angular_step: 0.01,
        coarse_factor: 4,
        min_points: 10,
    };
    for (truth, initial) in trial_poses(5, 3) {
        let scan = RangeData::new(
            &world.scan(&truth, 180, std::f64::consts::PI, 30.0),
            &Default::default(),
        )
        .unwrap();
        let got = m.match_prepared(&g, &scan, &initial).unwrap();
        let mut best = f64::NEG_INFINITY;
        for k in -5..=5 {
            for j in -4..=4 {
                for i in -4..=4 {
                    let p = Pose2::new(
                        initial.x + i as f64 * 0.05,
                        initial.y + j as f64 * 0.05,
                        initial.theta + k as f64 * 0.01,
                    );
                    best = best.max(mean_field_value(&g, &scan, &p));
                }
            }
        }
        assert!(
            (got.score - best).abs() < 1e-5,
            "{} vs brute force {}",
            got.score,
            best
        );
    }
}

/// Offsets up to 0.3 m and 10°. On a 2.5 cm map ≥ 95 % of matches end within 1 cm and
/// 0.5° (on a 5 cm map the error is dominated by wall positions quantised to cells: the
/// median is about 1 cm, see the crate's README figures).
#[test]
fn refined_correlative_converges_from_large_offsets() {
    let g = office_map(0.025);
    let world = SegmentWorld::office();
    let m = RefinedCorrelativeMatcher::default();
    let trials = trial_poses(100, 42);
    let mut ok = 0;
    for (truth, initial) in &trials {
        let scan = RangeData::new(
            &world.scan(truth, 180, std::f64::consts::PI, 30.0),
            &Default::default(),
        )
        .unwrap();
        let r = m.match_prepared(&g, &scan, initial).unwrap();
        let dt = r.pose.distance(truth);
        let da = slam_models::normalize_angle(r.pose.theta - truth.theta).abs();
        if dt < 0.01 && da < 0.5f64.to_radians() {
            ok += 1;
        }
        assert!(r.covariance.symmetric_eigen().eigenvalues.min() > 0.0);
    }
    assert!(ok >= 95, "{ok}/100 within 1 cm and 0.5°");
}

#[test]
fn hill_climb_and_gauss_newton_converge_from_small_offsets() {
    let g = office_map(0.05);
    let world = SegmentWorld::office();
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
    let (mut hc_ok, mut gn_ok) = (0, 0);
    for (truth, _) in trial_poses(50, 9) {
        let scan = RangeData::new(
            &world.scan(&truth, 180, std::f64::consts::PI, 30.0),
            &Default::default(),
        )
        .unwrap();
        let initial = Pose2::new(
            truth.x + rng.random_range(-0.06..0.06),
            truth.y + rng.random_range(-0.06..0.06),
            truth.theta + rng.random_range(-0.03..0.03),
        );
        let hc = HillClimbMatcher::default()
            .match_prepared(&g, &scan, &initial)
            .unwrap();
        if hc.pose.distance(&truth) < 0.02 && (hc.pose.theta - truth.theta).abs() < 0.01 {
            hc_ok += 1;
        }
        if let Ok(gn) = GaussNewtonMatcher::default().match_prepared(&g, &scan, &initial) {
            if gn.pose.distance(&truth) < 0.02 && (gn.pose.theta - truth.theta).abs() < 0.01 {
                gn_ok += 1;
            }
        }
        // The optimum scores at least as well as the start.
        assert!(hc.score >= mean_interpolated(&g, &scan, &initial));
    }
    assert!(hc_ok >= 47, "hill climbing: {hc_ok}/50");
    assert!(gn_ok >= 47, "Gauss-Newton: {gn_ok}/50");
}

#[test]
fn errors_for_bad_input() {
    let g = office_map(0.1);
    let world = SegmentWorld::office();
    let truth = Pose2::new(2.0, 3.0, 0.0);
    let mut scan = world.scan(&truth, 180, std::f64::consts::PI, 30.0);
    let p = RangeData::new(&scan, &Default::default()).unwrap();
    assert!(matches!(
        CorrelativeMatcher::default().match_prepared(&g, &p, &Pose2::new(f64::NAN, 0.0, 0.0)),
        Err(GridError::NonFinite { .. })
    ));
    scan.ranges.iter_mut().for_each(|r| *r = 30.0);
    let p = RangeData::new(&scan, &Default::default()).unwrap();
    assert!(matches!(
        HillClimbMatcher::default().match_prepared(&g, &p, &truth),
        Err(GridError::TooFewPoints { .. })
    ));
}

/// A laser pose about 1e10 m off (a glitch) used to wrap the correlative matcher's i32
/// window arithmetic into an out-of-bounds index; every matcher now refuses it with an
/// error naming the bound, and poses just inside the bound are matched without panicking.
#[test]
fn far_off_initial_poses_are_errors_not_panics() {
    let g = office_map(0.1);
    let world = SegmentWorld::office();
    let truth = Pose2::new(2.0, 3.0, 0.0);
    let scan = world.scan(&truth, 180, std::f64::consts::PI, 30.0);
    let p = RangeData::new(&scan, &Default::default()).unwrap();
    let matchers: [&dyn ScanMatcher; 4] = [
        &CorrelativeMatcher::default(),
        &RefinedCorrelativeMatcher::default(),
        &HillClimbMatcher::default(),
        &GaussNewtonMatcher::default(),
    ];
    for far in [
        Pose2::new(1e10, 3.0, 0.0),
        Pose2::new(2.0, -1e10, 0.3),
        Pose2::new(-1e300, 1e300, 0.0),
    ] {
        for m in matchers {
            let err = m.match_prepared(&g, &p, &far).unwrap_err();
            assert!(matches!(err, GridError::OutOfGrid { .. }), "{err:?}");
            assert!(err.to_string().contains("2^30 cells"), "{err}");
        }
    }
    // 1e7 m = 10^8 cells at 0.1 m: inside the bound, far off the map. Whatever the
    // matchers answer (no end point near an obstacle), they answer without panicking.
    let off = Pose2::new(1e7, -1e7, 0.1);
    for m in matchers {
        let _ = m.match_prepared(&g, &p, &off);
    }
    // An absurd rotation count is a configuration error, not an allocation.
    let fine = CorrelativeMatcher {
        angular_step: 1e-12,
        ..Default::default()
    };
    let e = fine.match_prepared(&g, &p, &truth).unwrap_err();
    let GridError::InvalidConfig(ref c) = e else {
        panic!("{e:?}")
    };
    assert_eq!(c.field, "angular_step");
    assert!(
        e.to_string().contains("angular-step = 0.000000000001"),
        "{e}"
    );
}

/// `PointCells::cells_at` gives every end point the cell `GridFrame::world_to_cell` gives
/// it after `transform_points` (the scalar path it replaces), on random points, poses and
/// frames: near the origin (the bounded floor), 10⁸ cells away (still bounded), 10⁹ cells
/// away and beyond the `i32` range (the saturating floor), with points on cell edges.
#[test]
fn point_cells_are_the_cells_of_the_transformed_points() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(5);
    for trial in 0..400 {
        let res = [0.05, 0.1, 0.025, 1.0][trial % 4];
        let far = [0.0, 1e8 * res, 1e9 * res, 1e12 * res][trial / 4 % 4];
        let frame = crate::cell::GridFrame::new(
            Point2::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0)),
            res,
        );
        let mut points: Vec<Point2> = (0..37)
            .map(|_| Point2::new(rng.random_range(-30.0..30.0), rng.random_range(-30.0..30.0)))
            .collect();
        // End points exactly on cell edges at the identity rotation.
        points.push(Point2::new(3.0 * res, -2.0 * res));
        points.push(Point2::new(0.0, 0.0));
        let pose = Pose2::new(
            far + rng.random_range(-10.0..10.0),
            -far + rng.random_range(-10.0..10.0),
            if trial % 3 == 0 {
                0.0
            } else {
                rng.random_range(-3.2..3.2)
            },
        );
        let mut got = vec![crate::cell::CellIndex::default(); points.len()];
        PointCells::new(&points).cells_at(&frame, &pose, &mut got);
        let expected: Vec<_> = transform_points(&points, &pose)
            .map(|w| frame.world_to_cell(&w))
            .collect();
        assert_eq!(got, expected, "trial {trial}, pose {pose:?}");
    }
}
