//! Tests of laser odometry (simulated office paths, real Intel scan pairs).

use super::hypotheses::{best_fit, Branches};
use super::*;
use crate::scanmatch::EndpointMatchingConfig;
use crate::testutil::SegmentWorld;
use slam_models::{ScanRecord, YawRate};

/// A path through the simulated office (true poses), with the heading turning.
fn office_path(n: usize) -> Vec<Pose2> {
    (0..n)
        .map(|k| {
            let s = k as f64 / n as f64;
            Pose2::new(
                1.5 + 9.0 * s,
                3.0 + 0.6 * (6.0 * s).sin(),
                0.5 * (5.0 * s).sin(),
            )
        })
        .collect()
}

fn records(path: &[Pose2], world: &SegmentWorld) -> Vec<ScanRecord> {
    path.iter()
        .enumerate()
        .map(|(k, p)| ScanRecord {
            t: k as f64 * 0.2,
            // Odometry a laser-only recording does not have: it must be ignored.
            odometry: Pose2::new(1e3, -1e3, 2.0),
            scan: Some(world.scan(p, 361, std::f64::consts::TAU * 0.75, 20.0)),
        })
        .collect()
}

/// Laser odometry through the office with no odometry: every pose within 5 cm and
/// 1° of the truth (expressed in the frame of the first pose), by simulator truth.
/// With zero-motion prediction the search alone finds the ~8 cm, ~2° steps.
#[test]
fn tracks_the_office_without_odometry() {
    let world = SegmentWorld::office();
    let path = office_path(90);
    let recs = records(&path, &world);
    for prediction in [
        MotionPrediction::ConstantVelocity,
        MotionPrediction::ZeroMotion,
    ] {
        let config = LaserOdometryConfig {
            hypotheses: vec![prediction],
            ..Default::default()
        };
        let run = laser_odometry(&recs, None, config).unwrap();
        assert_eq!((run.odometry.len(), run.scans), (90, 90));
        assert_eq!((run.failures, run.with_prior), (0, 0), "{prediction:?}");
        for (k, (est, truth)) in run.odometry.iter().zip(&path).enumerate() {
            let truth = path[0].between(truth);
            assert!(
                est.distance(&truth) < 0.05
                    && normalize_angle(est.theta - truth.theta).abs() < 1f64.to_radians(),
                "{prediction:?} scan {k}: {est:?} vs {truth:?}"
            );
        }
    }
}

/// Narrow first (Olson 2009): on the office path's small steps (10 cm, a few degrees)
/// the narrow search around the constant-velocity prediction fits and the wide search
/// is run on at most 3 of 61 scans, and a jump of 0.9 m (the prediction 0.8 m off,
/// beyond the narrow ±0.3 m, found by the narrow search's climb or the wide search) is
/// followed: every pose within 5 cm and 1° of the truth. With `good-fit` above 1 every
/// scan after the first is searched wide, to the same poses.
#[test]
fn narrow_first_and_wide_only_when_the_narrow_fit_is_poor() {
    let world = SegmentWorld::office();
    let full = office_path(90);
    let path: Vec<Pose2> = full[..40].iter().chain(&full[48..70]).copied().collect();
    let recs = records(&path, &world);
    for (good_fit, wide) in [(0.95, 0..=3), (1.5, 61..=61)] {
        let config = LaserOdometryConfig {
            good_fit,
            narrow_range_xy: 0.3,
            narrow_range_theta: 0.25,
            motion_prior_std: [0.3, 0.3],
            ..Default::default()
        };
        let run = laser_odometry(&recs, None, config).unwrap();
        assert_eq!((run.scans, run.failures), (62, 0));
        assert!(wide.contains(&run.wide_searches), "{}", run.wide_searches);
        for (k, (est, truth)) in run.odometry.iter().zip(&path).enumerate() {
            let truth = path[0].between(truth);
            assert!(
                est.distance(&truth) < 0.05
                    && normalize_angle(est.theta - truth.theta).abs() < 1f64.to_radians(),
                "good-fit {good_fit}, scan {k}: {est:?} vs {truth:?}"
            );
        }
    }
}

/// Scans 0.5 m and 0.3 rad apart with a rotation rate prior (the true rate): the prior
/// sets the heading and a narrow θ window finds the match; a sudden turn the constant
/// velocity prediction misses by 0.6 rad is found with the prior.
#[test]
fn a_rotation_prior_carries_a_sudden_turn() {
    let world = SegmentWorld::office();
    // Straight along the corridor, then a sudden 0.6 rad turn on the spot.
    let mut path: Vec<Pose2> = (0..8)
        .map(|k| Pose2::new(2.0 + 0.4 * k as f64, 3.0, 0.0))
        .collect();
    path.push(Pose2::new(4.8, 3.0, 0.6));
    path.push(Pose2::new(5.1, 3.2, 0.6));
    let recs = records(&path, &world);
    let rates: Vec<YawRate> = (0..=100)
        .map(|i| {
            let t = i as f64 * 0.02;
            // The turn happens between scans 7 (t = 1.4) and 8 (t = 1.6).
            let rate = if (1.4..1.6).contains(&t) { 3.0 } else { 0.0 };
            YawRate { t, rate }
        })
        .collect();
    let run = laser_odometry(&recs, Some(&rates), LaserOdometryConfig::default()).unwrap();
    assert_eq!(run.with_prior, 9);
    for (est, truth) in run.odometry.iter().zip(&path) {
        let truth = path[0].between(truth);
        assert!(est.distance(&truth) < 0.05, "{est:?} vs {truth:?}");
        assert!(normalize_angle(est.theta - truth.theta).abs() < 0.02);
    }
}

/// ∫ω dt by the trapezoidal rule is exact for a rate linear in time, and a gap or an
/// interval outside the samples gives no prior.
#[test]
fn yaw_rate_integration() {
    let rates: Vec<YawRate> = (0..=50)
        .map(|i| {
            let t = i as f64 * 0.1;
            YawRate {
                t,
                rate: 0.2 + 0.3 * t,
            }
        })
        .collect();
    // ∫ (0.2 + 0.3 t) dt from 1.05 to 3.33 = 0.2·Δt + 0.15·(t1² − t0²).
    let (t0, t1) = (1.05, 3.33);
    let exact = 0.2 * (t1 - t0) + 0.15 * (t1 * t1 - t0 * t0);
    let got = integrate_yaw_rate(&rates, t0, t1).unwrap();
    assert!((got - exact).abs() < 1e-12, "{got} vs {exact}");
    assert_eq!(integrate_yaw_rate(&rates, 2.0, 2.0), None);
    assert_eq!(integrate_yaw_rate(&rates, 3.0, 2.0), None);
    assert_eq!(integrate_yaw_rate(&rates, 6.0, 7.0), None);
    let gappy: Vec<YawRate> = rates
        .iter()
        .copied()
        .filter(|r| !(2.0..3.0).contains(&r.t))
        .collect();
    assert_eq!(integrate_yaw_rate(&gappy, 1.0, 4.0), None);
    assert!(integrate_yaw_rate(&gappy, 0.5, 1.5).is_some());
}

/// Records without a scan take the time interpolation of the scan poses around them.
#[test]
fn records_between_scans_are_interpolated() {
    let world = SegmentWorld::office();
    let path = office_path(20);
    let mut recs = records(&path, &world);
    // Insert a scan-less record halfway in time between scans 4 and 5.
    recs.insert(
        5,
        ScanRecord {
            t: 0.9,
            odometry: Pose2::IDENTITY,
            scan: None,
        },
    );
    let run = laser_odometry(&recs, None, LaserOdometryConfig::default()).unwrap();
    let (a, b, m) = (run.odometry[4], run.odometry[6], run.odometry[5]);
    assert!((m.x - 0.5 * (a.x + b.x)).abs() < 1e-12 && (m.y - 0.5 * (a.y + b.y)).abs() < 1e-12);
    assert_eq!(run.scans, 20);
}

/// Two real Intel keyframe pairs (`testdata/intel-pairs.log`: CARMEN `FLASER` lines,
/// 180 beams from −90° by 1°) and the ground truth between them: the Freiburg
/// benchmark's relation (Kümmerle et al. 2009), x, y and yaw of the second scan in the
/// frame of the first.
fn intel_pairs() -> Vec<(LaserScan, LaserScan, Pose2)> {
    let text = include_str!("../../testdata/intel-pairs.log");
    let numbers = |l: &str, skip: usize, take: usize| -> Vec<f64> {
        l.split_whitespace()
            .skip(skip)
            .take(take)
            .map(|v| v.parse().unwrap())
            .collect()
    };
    let scans: Vec<LaserScan> = text
        .lines()
        .filter(|l| l.starts_with("FLASER"))
        .map(|l| {
            // The beam count, then the ranges (the pose and host name after them).
            let n = numbers(l, 1, 1)[0] as usize;
            LaserScan {
                angle_min: -std::f64::consts::FRAC_PI_2,
                angle_increment: 1f64.to_radians(),
                ranges: numbers(l, 2, n),
                max_range: 81.83,
                sensor_pose: Pose2::IDENTITY,
            }
        })
        .collect();
    let truths: Vec<Pose2> = text
        .lines()
        .filter(|l| l.starts_with("RELATION"))
        .map(|l| {
            let f = numbers(l, 1, 8);
            Pose2::new(f[2], f[3], f[7])
        })
        .collect();
    scans
        .chunks(2)
        .zip(truths)
        .map(|(p, t)| (p[0].clone(), p[1].clone(), t))
        .collect()
}

/// Within 7 cm and 1° of a benchmark relation. The translation bound is loose because
/// on these turns on the spot the relations put the second scan about 6 cm sideways of
/// the first (the frame of the raw log's robot, the laser mounted off its centre, it
/// seems) where GMapping's own poses in the same log put it within 1 cm.
fn near(est: &Pose2, truth: &Pose2) -> bool {
    let e = truth.between(est);
    e.x.hypot(e.y) < 0.07 && e.theta.abs() < 1f64.to_radians()
}

/// Laser odometry's matcher recovers a known large displacement of a real scan pair:
/// the map of the first scan, the second searched from a guess 1.0 m and ±0.5 rad (and
/// 1.2 m, 0.7 rad) off its true pose is found within 7 cm and 1° of the benchmark's
/// relation; from scan-matching odometry's default window (±0.4 m, ±0.21 rad) at least
/// two of the four guesses end elsewhere. Through [`LaserOdometry`] the zero-motion hypothesis is half a radian off (the
/// robot turns on the spot) and the pose is found too.
#[test]
fn finds_a_large_displacement_of_a_real_scan_pair() {
    let pairs = intel_pairs();
    assert_eq!(pairs.len(), 2);
    let config = LaserOdometryConfig::default();
    let mut narrow = config.matcher_config();
    narrow.matching.search_range_xy = EndpointMatchingConfig::default().search_range_xy;
    narrow.matching.search_range_theta = EndpointMatchingConfig::default().search_range_theta;
    for (a, b, truth) in &pairs {
        let mut lo = LaserOdometry::new(config.clone()).unwrap();
        assert_eq!(lo.process(a, None).unwrap().1, MatchOutcome::First);
        let (pose, _) = lo.process(b, None).unwrap();
        assert!(near(&pose, truth), "{pose:?} vs {truth:?}");

        let model = config.matcher_config().sensor_model;
        let b = RangeData::with_limits(b, &model, 0.0, config.match_max_range).unwrap();
        let a = RangeData::with_limits(a, &model, 0.0, config.match_max_range).unwrap();
        let mut missed = 0;
        for offset in [
            Pose2::new(1.0, 0.0, 0.5),
            Pose2::new(-0.6, 0.8, -0.5),
            Pose2::new(0.0, -1.0, 0.5),
            Pose2::new(0.85, 0.85, -0.7),
        ] {
            let guess = truth.compose(&offset);
            let mut wide =
                ScanMatchOdometry::new(config.matcher_config(), Pose2::IDENTITY, 0).unwrap();
            wide.integrate(&Pose2::IDENTITY, &a).unwrap();
            let found = wide
                .match_scored(&b, &guess, wide.window().as_ref())
                .unwrap()
                .unwrap();
            assert!(
                near(&found.pose, truth),
                "{offset:?}: {found:?} vs {truth:?}"
            );
            let mut small = ScanMatchOdometry::new(narrow.clone(), Pose2::IDENTITY, 0).unwrap();
            small.integrate(&Pose2::IDENTITY, &a).unwrap();
            let found = small
                .match_scored(&b, &guess, small.window().as_ref())
                .unwrap()
                .unwrap();
            missed += usize::from(!near(&found.pose, truth));
        }
        // The hill climber alone sometimes walks that far, not always.
        assert!(missed >= 2, "the narrow window missed {missed} of 4");
    }
}

#[test]
fn bad_config_is_refused_by_key() {
    let field = |config: LaserOdometryConfig| match LaserOdometry::new(config) {
        Err(GridError::InvalidConfig(c)) => c.field,
        other => panic!("{other:?}"),
    };
    let repeated = vec![MotionPrediction::ZeroMotion, MotionPrediction::ZeroMotion];
    for (config, key) in [
        (
            LaserOdometryConfig {
                hypotheses: repeated,
                ..Default::default()
            },
            "hypotheses",
        ),
        (
            LaserOdometryConfig {
                hypotheses: Vec::new(),
                ..Default::default()
            },
            "hypotheses",
        ),
        (
            LaserOdometryConfig {
                prior_range_theta: f64::NAN,
                ..Default::default()
            },
            "prior-range-theta",
        ),
        (
            LaserOdometryConfig {
                good_fit: f64::NAN,
                ..Default::default()
            },
            "good-fit",
        ),
        (
            LaserOdometryConfig {
                wide_margin: 1.5,
                ..Default::default()
            },
            "wide-margin",
        ),
        (
            LaserOdometryConfig {
                motion_prior_std: [-0.1, 0.3],
                ..Default::default()
            },
            "motion-prior-std[0]",
        ),
        (
            LaserOdometryConfig {
                narrow_range_theta: 4.0,
                ..Default::default()
            },
            "narrow-range-theta",
        ),
    ] {
        assert_eq!(field(config), key);
    }
    let config = LaserOdometryConfig {
        search_range_xy: 100.0,
        ..Default::default()
    };
    assert_eq!(field(config), "matching.search_range_xy");
    // The matcher's keys this table replaces or does not use were ignored without a word
    // (`[laser-odometry.matcher] match-max-range = nan` ran with exit code 0): refused.
    let mut nan_window = LaserOdometryConfig::default();
    nan_window.matcher.matching.search_range_xy = f64::NAN;
    let mut theta = LaserOdometryConfig::default();
    theta.matcher.matching.search_range_theta = 0.2;
    let mut prior = LaserOdometryConfig::default();
    prior.matcher.matching.search_prior_std[1] = f64::INFINITY;
    let mut range = LaserOdometryConfig::default();
    range.matcher.match_max_range = 50.0;
    let mut jump = LaserOdometryConfig::default();
    jump.matcher.odometry_jump.max_jump = 1.0;
    for (config, key) in [
        (nan_window, "matcher.matching.search-range-xy"),
        (theta, "matcher.matching.search-range-theta"),
        (prior, "matcher.matching.search-prior-std"),
        (range, "matcher.match-max-range"),
        (jump, "matcher.odometry-jump"),
    ] {
        assert_eq!(field(config), key);
    }
    // The matcher's own keys (map, endpoint model) are still read.
    let mut own = LaserOdometryConfig::default();
    own.matcher.resolution = 0.1;
    LaserOdometry::new(own).unwrap();
}

/// The decision keeps the highest fit and, of equal ones, the first (the default branch).
#[test]
fn the_best_fit_is_the_first_of_the_highest() {
    assert_eq!(best_fit(&[3.0, 1.0]), 0);
    assert_eq!(best_fit(&[1.0, 2.0, 2.0]), 1);
    assert_eq!(best_fit(&[1.0, 1.0, 1.0]), 0);
    assert_eq!(best_fit(&[0.5, 0.4, 4.9]), 2);
    assert_eq!(best_fit(&[]), 0);
}

/// With `branch-lag` 0 no branch starts and the poses are [`LaserOdometry::process`]'s to
/// the bit (the office path).
#[test]
fn without_lag_the_poses_are_those_of_one_laser_odometry() {
    let world = SegmentWorld::office();
    let path = office_path(40);
    let recs = records(&path, &world);
    let scans: Vec<&LaserScan> = recs.iter().filter_map(|r| r.scan.as_ref()).collect();
    let config = LaserOdometryConfig {
        branch_lag: 0,
        ..Default::default()
    };
    let mut lo = LaserOdometry::new(config.clone()).unwrap();
    let plain: Vec<Pose2> = scans
        .iter()
        .map(|s| lo.process(s, None).unwrap().0)
        .collect();
    let mut at_once = Branches::new(LaserOdometry::new(config).unwrap(), 0, 3);
    for s in &scans {
        at_once.push(s, None).unwrap();
    }
    let (poses, _, splits, switches) = at_once.finish();
    assert_eq!((poses, splits, switches), (plain, 0, 0));
}

/// A featureless corridor (two parallel walls 2 m apart, its ends beyond the scanner's
/// reach): every place along it fits a scan alike, so the narrow match and the wide
/// search's differ and tie, and branches start. Never more than `max-branches` are
/// followed, the poses come out at most `branch-lag` scans late and one per scan, and a
/// second run gives the same poses to the bit. Across the corridor and in heading the poses stay within 5 cm and 1° of the truth
/// (along it nothing is observable).
#[test]
fn branch_bookkeeping_in_a_featureless_corridor() {
    let p = slam_models::Point2::new;
    let world = SegmentWorld {
        segments: vec![
            (p(-60.0, -1.0), p(60.0, -1.0)),
            (p(-60.0, 1.0), p(60.0, 1.0)),
        ],
    };
    let path: Vec<Pose2> = (0..30)
        .map(|k| Pose2::new(0.3 * k as f64, 0.1 * (0.3 * k as f64).sin(), 0.0))
        .collect();
    let recs = records(&path, &world);
    let scans: Vec<&LaserScan> = recs.iter().filter_map(|r| r.scan.as_ref()).collect();
    let (lag, max) = (4, 3);
    let config = LaserOdometryConfig {
        branch_lag: lag,
        max_branches: max,
        ..Default::default()
    };
    let run = || {
        let mut branches = Branches::new(LaserOdometry::new(config.clone()).unwrap(), lag, max);
        for (k, s) in scans.iter().enumerate() {
            branches.push(s, None).unwrap();
            assert!(
                (1..=max).contains(&branches.len()),
                "scan {k}: {}",
                branches.len()
            );
            let decided = branches.decided().len();
            assert!(
                decided + lag > k && decided <= k + 1,
                "scan {k}: {decided} decided"
            );
        }
        branches.finish()
    };
    let (poses, _, splits, switches) = run();
    assert!(splits > 0, "no branch started");
    assert!(switches <= splits, "{switches} switches, {splits} splits");
    assert_eq!(poses.len(), path.len());
    assert_eq!(run().0, poses);
    for (k, (est, truth)) in poses.iter().zip(&path).enumerate() {
        let truth = path[0].between(truth);
        assert!(
            (est.y - truth.y).abs() < 0.05
                && normalize_angle(est.theta - truth.theta).abs() < 1f64.to_radians(),
            "scan {k}: {est:?} vs {truth:?}"
        );
    }
}
