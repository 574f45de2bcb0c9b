//! The filter's tests: bookkeeping per record, the front door, the stages on simulated rooms.

use super::*;
use crate::Proposal;
use slam_models::{FilterError, ScanSlam};

/// A 181-beam scan of a square room of half-width 3 m seen from `pose`.
fn room_scan(pose: &Pose2) -> LaserScan {
    let inc = std::f64::consts::PI / 180.0;
    let ranges = (0..181)
        .map(|k| {
            let a = pose.theta - std::f64::consts::FRAC_PI_2 + k as f64 * inc;
            let (dx, dy) = (a.cos(), a.sin());
            let hit = |d: f64, c: f64| {
                if d.abs() < 1e-12 {
                    f64::INFINITY
                } else {
                    (3.0f64.copysign(d) - c) / d
                }
            };
            let (tx, ty) = (hit(dx, pose.x), hit(dy, pose.y));
            tx.min(ty)
        })
        .collect();
    LaserScan {
        angle_min: -std::f64::consts::FRAC_PI_2,
        angle_increment: inc,
        ranges,
        max_range: 30.0,
        sensor_pose: Pose2::IDENTITY,
    }
}

fn rec(t: f64, odo: Pose2, scan: bool) -> ScanRecord {
    ScanRecord {
        t,
        odometry: odo,
        scan: scan.then(|| room_scan(&odo)),
    }
}

/// `initial_pose` places the odometry frame in the world: before any record the pose
/// is `initial_pose`, before the first processed scan a record sits at
/// `initial_pose ⊕ odometry`, and the first scan's pose is the same composition.
#[test]
fn initial_pose_places_the_odometry_frame() {
    let start = Pose2::new(2.0, -1.0, 0.7);
    let config = GridFastConfig {
        particles: 3,
        ..Default::default()
    };
    let mut f = GridFastSlam::new(config.clone(), start, 1).unwrap();
    assert_eq!(ScanSlam::pose(&f), start);
    let odo = [Pose2::new(0.2, 0.1, 0.05), Pose2::new(0.3, 0.1, 0.1)];
    f.process(&rec(0.0, odo[0], false)).unwrap();
    f.process(&rec(0.1, odo[1], true)).unwrap();
    let traj = f.trajectory();
    for (k, o) in odo.iter().enumerate() {
        let want = start.compose(o);
        assert!(
            traj[k].pose.distance(&want) < 1e-12,
            "{k}: {:?}",
            traj[k].pose
        );
        assert!(normalize_angle(traj[k].pose.theta - want.theta).abs() < 1e-12);
    }
    let bad = Pose2::new(f64::NAN, 0.0, 0.0);
    assert!(GridFastSlam::new(config, bad, 1).is_err());
}

#[test]
fn one_pose_per_record_and_same_instant_records_share_the_correction() {
    let mut f = GridFastSlam::new(
        GridFastConfig {
            particles: 4,
            linear_update: 0.5,
            ..Default::default()
        },
        Pose2::IDENTITY,
        1,
    )
    .unwrap();
    let path = [
        rec(0.0, Pose2::new(0.0, 0.0, 0.0), false),
        rec(0.0, Pose2::new(0.0, 0.0, 0.0), true),
        rec(1.0, Pose2::new(0.3, 0.0, 0.0), false),
        rec(1.5, Pose2::new(0.4, 0.0, 0.0), true), // 0.4 m: not processed
        // An earlier reading printed with the scan's time stamp, then the scan's own
        // ODOM line (same time, same odometry), then the scan.
        rec(2.0, Pose2::new(0.55, 0.08, 0.05), false),
        rec(2.0, Pose2::new(0.6, 0.1, 0.1), false),
        rec(2.0, Pose2::new(0.6, 0.1, 0.1), true), // processed
        rec(3.0, Pose2::new(0.8, 0.1, 0.1), false),
    ];
    let processed: Vec<bool> = path
        .iter()
        .map(|r| f.process(r).unwrap().processed_scan)
        .collect();
    assert_eq!(
        processed,
        [false, true, false, false, false, false, true, false]
    );
    let traj = f.trajectory();
    assert_eq!(traj.len(), path.len());
    // Before the second update: the odometry itself (world = odometry frame), the
    // earlier reading with the scan's time stamp included.
    for i in 0..5 {
        assert!(traj[i].pose.approx_eq(&path[i].odometry, 1e-12));
    }
    // The ODOM line at the scan's instant takes the scan's corrected pose.
    assert_eq!(traj[5].pose, traj[6].pose);
    let corrected = f.corrected_poses();
    assert_eq!(corrected.len(), 2);
    assert_eq!(corrected[1].pose, traj[6].pose);
    // The scan was matched, so its corrected pose is not the odometry: the earlier
    // reading really did keep the previous correction.
    assert!(!traj[6].pose.approx_eq(&path[6].odometry, 1e-9));
    // Afterwards: corrected pose ⊕ odometry since.
    let expect = traj[6]
        .pose
        .compose(&path[6].odometry.between(&path[7].odometry));
    assert!(traj[7].pose.approx_eq(&expect, 1e-12));
    assert!(f.pose().approx_eq(&expect, 1e-12));
    let w: f64 = f.particles().unwrap().iter().map(|p| p.weight).sum();
    assert!((w - 1.0).abs() < 1e-9);
    // The room is square: the matched pose stays within a few cm of the truth.
    assert!(corrected[1].pose.distance(&path[6].odometry) < 0.05);
}

#[test]
fn readings_beyond_max_range_are_neither_mapped_nor_matched() {
    let mut config = GridFastConfig {
        particles: 2,
        ..Default::default()
    };
    config.sensor.max_range = Some(2.0);
    let mut f = GridFastSlam::new(config, Pose2::IDENTITY, 1).unwrap();
    // The room's walls are 3 m away straight ahead: beyond max_range.
    let pose = Pose2::new(0.0, 0.0, 0.0);
    f.process(&rec(0.0, pose, true)).unwrap();
    // Matching uses only readings below max_range: the limit itself, a reading beyond
    // it and a no return are all left out.
    let scan = LaserScan {
        angle_min: 0.0,
        ranges: vec![1.0, 2.0, 2.5, 30.0],
        ..room_scan(&pose)
    };
    let prepared = f.admit(false, &scan).unwrap();
    assert_eq!(prepared.points(), &[slam_models::Point2::new(1.0, 0.0)]);
    // Nothing is marked or cleared along the +x axis up to and at the wall.
    let map = &f.particles[0].map;
    for x in [0.5, 1.5, 2.5, 3.0] {
        let c = map.world_to_cell(&slam_models::Point2::new(x, 0.01));
        assert_eq!(map.log_odds(c), 0.0, "x = {x}");
    }
}

/// A 10 km odometry jump is rejected with the record's index and the bound; with
/// `on_jump = "skip"` it is taken as no motion, counted in the step info, and the
/// particles' maps stay the room's (the jump used to stretch every particle's grid
/// over 10 km).
#[test]
fn an_odometry_jump_is_an_error_or_skipped_on_request() {
    let config = GridFastConfig {
        particles: 3,
        ..Default::default()
    };
    let poses: Vec<Pose2> = (0..8)
        .map(|k| Pose2::new(0.2 * k as f64, 0.0, 0.0))
        .collect();
    let mut f = GridFastSlam::new(config.clone(), Pose2::IDENTITY, 1).unwrap();
    for (k, p) in poses.iter().enumerate() {
        f.step(&rec(k as f64, *p, true)).unwrap();
    }
    // The glitched record carries the room's scan as seen from its true pose.
    let mut glitch = rec(8.0, Pose2::new(1.6, 0.0, 0.0), true);
    glitch.odometry.x += 10_000.0;
    let e = f.step(&glitch).unwrap_err();
    assert!(
        matches!(e, GridFastError::InvalidRecord { index: 8, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("max-jump = 5 m"), "{e}");

    let mut f = GridFastSlam::new(
        GridFastConfig {
            odometry_jump: slam_models::OdometryJumpLimit {
                max_jump: 5.0,
                on_jump: slam_models::OnOdometryJump::Skip,
            },
            ..config
        },
        Pose2::IDENTITY,
        1,
    )
    .unwrap();
    let mut skipped = 0;
    for (k, p) in poses.iter().enumerate() {
        skipped += f
            .step(&rec(k as f64, *p, true))
            .unwrap()
            .odometry_jumps_skipped;
    }
    skipped += f.step(&glitch).unwrap().odometry_jumps_skipped;
    skipped += f
        .step(&rec(9.0, Pose2::new(1.6, 0.0, 0.0), true))
        .unwrap()
        .odometry_jumps_skipped;
    assert_eq!(skipped, 2);
    assert_eq!(f.trajectory().len(), 10);
    let map = f.map();
    assert!(
        map.width as f64 * map.resolution < 10.0,
        "{} cells wide",
        map.width
    );
    assert!(f.pose().x.abs() < 3.0, "{:?}", f.pose());
}

/// Issue 21: an odometry error of 1.3 m and 20° at one scan (the odometry frame jumps
/// by E = (0, 1.2 m, 20°) and stays there, as after a wheel slip) is beyond the hill
/// climber's and the coarse search's reach. The poor match is noticed (few beams on the
/// map), the wide search finds the true pose, and the filter follows the simulated
/// room's exact ground truth afterwards. With the recovery switched off the same run
/// ends 1.7 m off, so the test can fail. (Not every error of this size needs it: the
/// local search alone recovers E = (1.3, −1, 20°) or (0.8, −0.6, 30°) in this room. Nor
/// is every one noticed: after E = (−1, 0.5, −20°) the hill climber settles 0.8 m off
/// along a wall with most beams still on the map — a known limit of the inlier test.)
#[test]
fn a_bad_odometry_jump_is_noticed_and_recovered() {
    use crate::matcher::tests::room_scan;
    let truth: Vec<Pose2> = (0..8)
        .map(|k| {
            let k = k as f64;
            Pose2::new(-1.5 + 0.35 * k, -0.8 + 0.2 * k, 0.1 * k)
        })
        .collect();
    let jump = Pose2::new(0.0, 1.2, 20f64.to_radians());
    let run = |trigger: f64| {
        let mut config = GridFastConfig {
            particles: 10,
            linear_update: 0.3,
            angular_update: 0.3,
            ..Default::default()
        };
        config.matching.recovery.trigger_fraction = trigger;
        // The heading windows of the outdoor preset (±0.3 rad coarse, ±0.4 rad
        // recovery): the indoor ±0.9 rad coarse search alone finds this jump, and the
        // test is about what answers a jump the coarse search misses.
        config.matching.search_range_theta = Some(0.3);
        config.matching.recovery.range_theta = Some(0.4);
        let mut f = GridFastSlam::new(config, Pose2::IDENTITY, 3).unwrap();
        let (mut recovered, mut failed) = (0, 0);
        for (k, p) in truth.iter().enumerate() {
            let odometry = if k >= 5 { jump.compose(p) } else { *p };
            let info = f
                .step(&ScanRecord {
                    t: k as f64,
                    odometry,
                    scan: Some(room_scan(p)),
                })
                .unwrap();
            assert!(info.processed_scan);
            if k == 5 {
                (recovered, failed) = (info.match_recoveries, info.match_failures);
            } else if trigger > 0.0 {
                assert_eq!(
                    (info.match_recoveries, info.match_failures),
                    (0, 0),
                    "scan {k}"
                );
            }
        }
        (f.corrected_poses(), recovered, failed)
    };
    let (poses, recovered, failed) = run(0.4);
    assert_eq!(poses.len(), truth.len());
    assert!(
        recovered > 0 && failed == 0,
        "{recovered} recovered, {failed} failed"
    );
    for (k, (e, t)) in poses.iter().zip(&truth).enumerate() {
        assert!(
            e.pose.distance(t) < 0.05 && normalize_angle(e.pose.theta - t.theta).abs() < 0.02,
            "scan {k}: {:?} against the truth {t:?}",
            e.pose
        );
    }
    let (poses, recovered, _) = run(0.0);
    assert_eq!(recovered, 0);
    let last = poses.last().unwrap().pose;
    assert!(
        last.distance(truth.last().unwrap()) > 0.3,
        "without the recovery the run should stay lost: {last:?}"
    );
}

/// Issue 21, fhw-hard: the odometry misses most of a turn in place. The robot turns
/// 1.65 rad over three keyframes while creeping 3 cm; the odometry reports a tenth of
/// the turn, so it neither moved `linear-update` nor turned `angular-update` and those
/// scans are not due; the next scan that is due (after 1 m) is then 1.5 rad off, beyond
/// every search window. The scans themselves show the turn: at the predicted pose few
/// of their beams find the map, so each is processed (`scan-update-fraction`) while
/// the error is still within the coarse search's ±0.9 rad, and the filter follows the
/// simulated room's exact ground truth. Switched off, the same run ends far off, so
/// the test can fail.
#[test]
fn a_turn_the_odometry_missed_is_noticed_from_the_scans() {
    use crate::matcher::tests::room_scan;
    let mut truth = vec![
        Pose2::new(-3.0, 1.0, 0.0),
        Pose2::new(-2.0, 1.0, 0.0),
        Pose2::new(-1.0, 1.0, 0.0),
    ];
    for k in 1..=3 {
        truth.push(Pose2::new(-1.0 + 0.01 * k as f64, 1.0, -0.55 * k as f64));
    }
    for _ in 0..3 {
        let last = *truth.last().unwrap();
        truth.push(last.compose(&Pose2::new(0.95, 0.0, 0.0)));
    }
    // The odometry: the true increments, with 90 % of each turn-in-place step lost.
    let mut odometry = vec![truth[0]];
    for k in 1..truth.len() {
        let mut step = truth[k - 1].between(&truth[k]);
        if (3..6).contains(&k) {
            step.theta *= 0.1;
        }
        odometry.push(odometry[k - 1].compose(&step));
    }
    let run = |fraction: f64| {
        let config = GridFastConfig {
            particles: 10,
            scan_update_fraction: fraction,
            ..Default::default()
        };
        let mut f = GridFastSlam::new(config, Pose2::IDENTITY, 5).unwrap();
        let mut processed = Vec::new();
        for (k, (p, o)) in truth.iter().zip(&odometry).enumerate() {
            let info = f
                .step(&ScanRecord {
                    t: k as f64,
                    odometry: *o,
                    scan: Some(room_scan(p)),
                })
                .unwrap();
            processed.push(info.processed_scan);
        }
        (f.trajectory(), processed)
    };
    let (estimate, processed) = run(GridFastConfig::default().scan_update_fraction);
    // Every turn step is processed although the odometry does not ask for it.
    assert!(processed[3..6].iter().all(|&p| p), "{processed:?}");
    // The world frame is the odometry frame, which starts at the first true pose.
    for (k, (e, t)) in estimate.iter().zip(&truth).enumerate() {
        assert!(
            e.pose.distance(t) < 0.05 && normalize_angle(e.pose.theta - t.theta).abs() < 0.03,
            "scan {k}: {:?} against the truth {t:?}",
            e.pose
        );
    }
    let (estimate, processed) = run(0.0);
    assert!(!processed[3..6].iter().any(|&p| p), "{processed:?}");
    let (last, goal) = (estimate.last().unwrap().pose, truth.last().unwrap());
    assert!(
        last.distance(goal) > 0.3 || normalize_angle(last.theta - goal.theta).abs() > 0.3,
        "without the scan trigger the run should be lost: {last:?}"
    );
}

/// The particles' maps take a processed scan only at the next update (beside the
/// coarse search), so the filter's map adds it itself: after a second scan that sees a
/// wall the first did not, that wall is in the map. Odometry proposal, so that nothing
/// is matched (the scans share no wall); every beam but a wall's is a no return.
/// Computing the improved proposal once per group of identical particles (the copies
/// of one parent since a resampling) gives the same bytes as computing it for every
/// particle: a run in a square room with odometry that overstates the motion by 10 %
/// and ignores a slow turn, so that the particles disagree and resample.
#[test]
fn one_proposal_per_group_of_identical_particles_changes_nothing() {
    let run = |share: bool| {
        let config = GridFastConfig {
            particles: 12,
            linear_update: 0.2,
            ..Default::default()
        };
        let mut f = GridFastSlam::new(config, Pose2::IDENTITY, 9).unwrap();
        f.share_fits = share;
        let mut resampled = 0;
        for k in 0..60 {
            let a = 0.1 * k as f64;
            let truth = Pose2::new(
                1.2 * a.cos() - 1.2,
                1.2 * a.sin(),
                a + 0.5 * std::f64::consts::PI,
            );
            let odometry = Pose2::new(
                1.32 * a.cos() - 1.32,
                1.32 * a.sin(),
                0.9 * a + 0.5 * std::f64::consts::PI,
            );
            let info = f
                .step(&ScanRecord {
                    t: k as f64,
                    odometry,
                    scan: Some(room_scan(&truth)),
                })
                .unwrap();
            resampled += usize::from(info.resampled);
        }
        (f.trajectory(), resampled)
    };
    let (shared, resampled) = run(true);
    assert!(
        resampled >= 3,
        "the run must resample to have groups ({resampled})"
    );
    assert_eq!(shared, run(false).0);
}

#[test]
fn the_map_holds_the_last_processed_scan() {
    let mut config = GridFastConfig {
        particles: 3,
        linear_update: 0.5,
        ..Default::default()
    };
    config.proposal.kind = Proposal::Odometry;
    config.sensor.max_range = Some(10.0);
    // Beams between `from` and `to` (rad, sensor frame) see a wall; `range` gives the
    // distance along the beam at angle `a`.
    let scan = |t: f64, odometry: Pose2, from: f64, to: f64, range: &dyn Fn(f64) -> f64| {
        let inc = std::f64::consts::PI / 180.0;
        let ranges = (0..181)
            .map(|k| {
                let a = -std::f64::consts::FRAC_PI_2 + k as f64 * inc;
                if (from..=to).contains(&a) {
                    range(a)
                } else {
                    10.0
                }
            })
            .collect();
        ScanRecord {
            t,
            odometry,
            scan: Some(LaserScan {
                angle_min: -std::f64::consts::FRAC_PI_2,
                angle_increment: inc,
                ranges,
                max_range: 10.0,
                sensor_pose: Pose2::IDENTITY,
            }),
        }
    };
    let mut f = GridFastSlam::new(config, Pose2::IDENTITY, 1).unwrap();
    // The wall x = 3 ahead, then, 0.6 m on, the wall y = 2 on the left (60° to 90°).
    let ahead = scan(0.0, Pose2::IDENTITY, -0.5, 0.5, &|a: f64| 3.0 / a.cos());
    f.step(&ahead).unwrap();
    let left = scan(1.0, Pose2::new(0.6, 0.0, 0.0), 1.05, 1.58, &|a: f64| {
        2.0 / a.sin()
    });
    assert!(f.step(&left).unwrap().processed_scan);
    let map = f.map();
    // An occupied cell within 4 cells of (x, y) along the axis `across` the wall.
    let occupied_near = |x: f64, y: f64, across: (i64, i64)| {
        let Some((i, j)) = map.cell_of(&slam_models::Point2::new(x, y)) else {
            return false;
        };
        (-4..=4).any(|d| {
            let (i, j) = (i as i64 + d * across.0, j as i64 + d * across.1);
            (i >= 0 && j >= 0) && map.get(i as usize, j as usize).is_some_and(|v| v > 50)
        })
    };
    assert!(occupied_near(2.9, 0.0, (1, 0)), "the first scan's wall");
    assert!(occupied_near(1.1, 1.9, (0, 1)), "the last scan's wall");
    assert_eq!(f.map().cells, map.cells, "asking again changes nothing");
}

#[test]
fn invalid_records_are_rejected_with_their_index() {
    let mut f = GridFastSlam::new(GridFastConfig::default(), Pose2::IDENTITY, 1).unwrap();
    f.process(&rec(0.0, Pose2::IDENTITY, true)).unwrap();
    let bad = ScanRecord {
        t: 1.0,
        odometry: Pose2 {
            x: f64::NAN,
            y: 0.0,
            theta: 0.0,
        },
        scan: None,
    };
    let e = f.step(&bad).unwrap_err();
    assert!(
        matches!(e, GridFastError::InvalidRecord { index: 1, .. }),
        "{e}"
    );
    let mut s = rec(1.0, Pose2::IDENTITY, true);
    if let Some(scan) = s.scan.as_mut() {
        scan.ranges[3] = -1.0;
    }
    // Through the trait the typed error is kept as the source.
    let e = f.process(&s).unwrap_err();
    assert!(matches!(e, FilterError::InvalidInput { .. }), "{e:?}");
    let typed = std::error::Error::source(&e)
        .and_then(|s| s.downcast_ref::<GridFastError>())
        .expect("the typed source");
    assert!(
        matches!(typed, GridFastError::InvalidRecord { index: 1, .. }),
        "{typed:?}"
    );
    assert!(GridFastSlam::new(
        GridFastConfig {
            particles: 0,
            ..Default::default()
        },
        Pose2::IDENTITY,
        1
    )
    .is_err());
}

#[test]
fn render_map_is_finer_and_agrees_with_the_matching_map() {
    let mut f = GridFastSlam::new(
        GridFastConfig {
            particles: 3,
            ..Default::default()
        },
        Pose2::IDENTITY,
        1,
    )
    .unwrap();
    f.process(&rec(0.0, Pose2::new(0.2, 0.1, 0.3), true))
        .unwrap();
    let coarse = f.map();
    let fine = f.render_map(0.01).unwrap();
    assert_eq!(fine.resolution, 0.01);
    // The wall at x = 3 m ahead is occupied in both (the hit lands in the cell on
    // either side of x = 3 depending on rounding).
    let occupied = |m: &GridMap, eps: f64| {
        [3.0 - eps, 3.0 + eps].iter().any(|&x| {
            m.cell_of(&slam_models::Point2::new(x, 0.1))
                .and_then(|(i, j)| m.get(i, j))
                .is_some_and(|v| v > 50)
        })
    };
    assert!(occupied(&fine, 0.005) && occupied(&coarse, 0.025));
    let q = slam_models::Point2::new(1.5, 0.1);
    let (fx, fy) = fine.cell_of(&q).unwrap();
    assert!((0..50).contains(&fine.get(fx, fy).unwrap()));
    // A cell size at which the scan's 3 m make a map beyond the grid's cell bound is the
    // grid's error, not a map without the scan (an empty map, before: `slam run
    // --map-resolution 0.003` on the campus ended on an error about its staging map.pgm).
    match f.render_map(1e-5) {
        Err(slam_grid::GridError::MapTooLarge { resolution, .. }) => assert_eq!(resolution, 1e-5),
        other => panic!("{other:?}"),
    }
}
