//! The configuration: serde, bounds, resolution from the data.

use super::*;

fn scan(ranges: Vec<f64>, max_range: f64) -> LaserScan {
    LaserScan {
        angle_min: -1.5,
        angle_increment: 3.0 / (ranges.len() - 1) as f64,
        ranges,
        max_range,
        sensor_pose: slam_models::Pose2::IDENTITY,
    }
}

#[test]
fn default_is_valid_and_round_trips_through_serde() {
    let c = GridFastConfig::default();
    c.validate().unwrap();
    let json = serde_json::to_string(&c).unwrap();
    let back: GridFastConfig = serde_json::from_str(&json).unwrap();
    assert_eq!(back, c);
    let p: GridFastConfig = serde_json::from_str(
        r#"{"particles": 5, "proposal": {"kind": "scan-matched-odometry"},
                "map": {"resolution": 0.1}, "matching": {"min-inlier-fraction": 0.3}}"#,
    )
    .unwrap();
    assert_eq!(p.proposal.kind, Proposal::ScanMatchedOdometry);
    assert_eq!(p.map.resolution, Some(0.1));
    assert_eq!(p.matching.min_inlier_fraction, 0.3);
    assert_eq!(p.linear_update, 1.0);
    // Unknown keys, old flat names and snake_case spellings are errors.
    for bad in [
        r#"{"particle": 5}"#,
        r#"{"resolution": 0.1}"#,
        r#"{"matching": {"min_inlier_fraction": 0.3}}"#,
        r#"{"sensor": {"range": 3}}"#,
    ] {
        assert!(
            serde_json::from_str::<GridFastConfig>(bad).is_err(),
            "{bad}"
        );
    }
}

/// `particles = 10^9` used to be accepted and allocated.
#[test]
fn particle_count_is_capped() {
    let c = GridFastConfig {
        particles: 1_000_000_000,
        ..Default::default()
    };
    let e = c.validate().unwrap_err().to_string();
    assert!(
        e.contains("particles = 1000000000") && e.contains("10000"),
        "{e}"
    );
    assert!(crate::GridFastSlam::new(c, slam_models::Pose2::IDENTITY, 0).is_err());
    let c = GridFastConfig {
        particles: MAX_PARTICLES,
        ..Default::default()
    };
    assert!(c.validate().is_ok());
}

#[test]
fn bad_values_are_rejected() {
    let mut c = GridFastConfig {
        particles: 0,
        ..Default::default()
    };
    assert!(c.validate().is_err());
    c.particles = 3;
    c.matching.field_radius = Some(1.0); // 20 cells of the indoor 5 cm
    assert!(matches!(
        c.resolve(None),
        Err(GridFastError::InvalidConfig(slam_models::ConfigError {
            field: "matching.field-radius",
            ..
        }))
    ));
    c.matching.field_radius = Some(0.2);
    for r in [0.0, 0.25, f64::NAN] {
        c.matching.likelihood_radius = Some(r);
        assert!(matches!(
            c.resolve(None),
            Err(GridFastError::InvalidConfig(slam_models::ConfigError {
                field: "matching.likelihood-radius",
                ..
            }))
        ));
    }
    c.matching.likelihood_radius = Some(0.2);
    c.resolve(None).unwrap();
    c.matching.sigma = Some(f64::NAN);
    assert!(c.validate().is_err());
    c.matching.sigma = None;
    c.sensor.max_range = Some(-1.0);
    assert!(c.validate().is_err());
}

/// The turn search's and the mixture's keys: each out-of-range value (NaN included) is
/// refused naming its key.
#[test]
fn bad_turn_search_values_are_rejected() {
    type Edit = fn(&mut crate::RecoveryConfig, f64);
    let cases: [(&str, Edit, &[f64]); 5] = [
        (
            "matching.recovery.turn-trigger",
            |r, v| r.turn_trigger = v,
            &[-0.1, f64::NAN],
        ),
        (
            "matching.recovery.turn-range-theta",
            |r, v| r.turn_range_theta = v,
            &[-0.1, 3.2, f64::NAN],
        ),
        (
            "matching.recovery.turn-range-xy",
            |r, v| r.turn_range_xy = Some(v),
            &[-0.1, 5.1, f64::NAN],
        ),
        (
            "matching.recovery.turn-accept-fraction",
            |r, v| r.turn_accept_fraction = v,
            &[-0.1, 1.1, f64::NAN],
        ),
        (
            "matching.recovery.outlier-weight",
            |r, v| r.outlier_weight = v,
            &[0.0, 1.0, f64::NAN],
        ),
    ];
    for (key, edit, values) in cases {
        for &v in values {
            let mut c = GridFastConfig::default();
            edit(&mut c.matching.recovery, v);
            match c.resolve(None) {
                Err(GridFastError::InvalidConfig(e)) => assert_eq!(e.field, key, "{v}"),
                other => panic!("{key} = {v}: {other:?}"),
            }
        }
    }
    GridFastConfig::default().resolve(None).unwrap();
}

/// The range limit and the preset come from the scan unless given; the result has
/// every value set, and an explicit value is kept over the preset's.
#[test]
fn resolve_takes_the_sensor_and_the_preset_from_the_data() {
    let c = GridFastConfig::default();
    // An office: returns 1–4 m, no-return value 81.83.
    let office = scan(vec![1.0, 2.0, 3.0, 81.83, 4.0], 81.83);
    let r = c.resolve(Some(&office)).unwrap();
    assert_eq!(r.sensor.max_range, Some(81.83));
    assert_eq!(r.preset, Preset::Indoor);
    assert_eq!(r.map.resolution, Some(0.05));
    // Indoors the heading windows cover odometry that turned in place (±0.9 rad).
    assert_eq!(
        (
            r.matching.search_range_theta,
            r.matching.recovery.range_theta
        ),
        (Some(0.9), Some(0.9))
    );
    // Open ground: median return 25 m.
    let campus = scan(vec![20.0, 25.0, 30.0, 80.0, 80.0], 80.0);
    let r = c.resolve(Some(&campus)).unwrap();
    assert_eq!(
        (r.sensor.max_range, r.preset),
        (Some(80.0), Preset::Outdoor)
    );
    assert_eq!(r.map.resolution, Some(0.2));
    assert_eq!(r.matching.field_radius, Some(0.8));
    assert_eq!(
        (
            r.matching.search_range_theta,
            r.matching.recovery.range_theta
        ),
        (Some(0.3), Some(0.4))
    );
    // Everything the preset sets is set.
    let json = serde_json::to_string(&r).unwrap();
    assert!(!json.contains("null"), "{json}");
    // An explicit range limit and preset win; an explicit value wins over the preset's.
    let mut c = GridFastConfig {
        preset: Preset::Indoor,
        ..Default::default()
    };
    c.sensor.max_range = Some(20.0);
    c.map.resolution = Some(0.1);
    let r = c.resolve(Some(&campus)).unwrap();
    assert_eq!(r.sensor.max_range, Some(20.0));
    assert_eq!(r.preset, Preset::Indoor);
    assert_eq!(r.map.resolution, Some(0.1));
    assert_eq!(r.matching.field_radius, Some(0.2));
    // Below a 26 m limit the campus scan keeps 20 and 25 m returns: still outdoor.
    assert_eq!(Preset::Auto.choose(&campus, 26.0), Preset::Outdoor);
    assert_eq!(
        Preset::Auto.choose(&scan(vec![80.0; 3], 80.0), 80.0),
        Preset::Indoor
    );
    // Resolving twice changes nothing.
    assert_eq!(r.resolve(Some(&office)).unwrap(), r);
}

/// Laser odometry widens the preset's coarse window to ±1 m indoors (the outdoor preset's
/// ±1.2 m is wider and stays); a window set in the configuration is kept either way.
#[test]
fn laser_odometry_widens_the_preset_window_only() {
    let indoor = scan(vec![2.0; 181], 30.0);
    let outdoor = scan(vec![20.0; 181], 80.0);
    let window = |source, set: Option<f64>, s: &LaserScan| {
        let mut c = GridFastConfig::default();
        c.motion.odometry_source = source;
        c.matching.search_range_xy = set;
        c.resolve(Some(s))
            .unwrap()
            .matching
            .search_range_xy
            .unwrap()
    };
    assert_eq!(window(OdometrySource::Robot, None, &indoor), 0.3);
    assert_eq!(
        window(OdometrySource::Laser, None, &indoor),
        LASER_ODOMETRY_SEARCH_RANGE_XY
    );
    assert_eq!(window(OdometrySource::Robot, None, &outdoor), 1.2);
    assert_eq!(window(OdometrySource::Laser, None, &outdoor), 1.2);
    assert_eq!(window(OdometrySource::Laser, Some(0.5), &indoor), 0.5);
    // A file says it in words.
    let c: GridFastConfig =
        serde_json::from_str(r#"{"motion": {"odometry-source": "laser"}}"#).unwrap();
    assert_eq!(c.motion.odometry_source, OdometrySource::Laser);
    assert!(
        serde_json::from_str::<GridFastConfig>(r#"{"motion": {"odometry-source": "wheels"}}"#)
            .is_err()
    );
}

/// `motion.odometry.min-translation` is checked (it was not: `inf` took every step as a
/// turn in place and the run stood still with exit code 0; NaN and negative values were
/// taken as they were).
#[test]
fn min_translation_outside_its_range_is_rejected() {
    for v in [f64::NAN, f64::INFINITY, -1.0, 1.5] {
        let mut c = GridFastConfig::default();
        c.motion.odometry.min_translation = v;
        match c.resolve(None) {
            Err(GridFastError::InvalidConfig(e)) => {
                assert_eq!(e.field, "motion.odometry.min-translation", "{v}")
            }
            other => panic!("min-translation = {v}: {other:?}"),
        }
    }
}

/// A range limit below one map cell is refused by key (`[sensor] max-range = 1e-300` dropped
/// every scan and the run ended on an error about its output's empty map.pgm); one cell
/// is taken.
#[test]
fn max_range_below_one_cell_is_rejected() {
    let mut c = GridFastConfig::default();
    c.map.resolution = Some(0.05);
    for v in [1e-300, 0.049] {
        c.sensor.max_range = Some(v);
        match c.resolve(None) {
            Err(GridFastError::InvalidConfig(e)) => assert_eq!(e.field, "sensor.max-range", "{v}"),
            other => panic!("max-range = {v}: {other:?}"),
        }
    }
    c.sensor.max_range = Some(0.05);
    c.resolve(None).unwrap();
}
