//! The laser front end of slam-graph (`--filter graph`) against ground truth: the simulated
//! office (slam-sim: two laps of a corridor loop, biased odometry), where the loop must be
//! closed and every accepted closure must be true, and a prefix of the Intel benchmark log
//! scored by the Kümmerle et al. 2009 relations (slam-io).

mod common;

use slam::graph::laser::{LaserGraphConfig, LaserGraphSlam};
use slam::models::{Pose2, ScanRecord, ScanSlam, TimedPose};

fn run(records: &[ScanRecord], config: LaserGraphConfig) -> LaserGraphSlam {
    let mut slam = LaserGraphSlam::new(config, Pose2::IDENTITY, 0).unwrap();
    common::run_scans(&mut slam, records);
    slam
}

/// Every accepted loop closure agrees with the ground truth: the measured pose of the later
/// record in the frame of the earlier is within 0.25 m and 3° of the true relative pose.
fn assert_closures_true(slam: &LaserGraphSlam, truth: &[TimedPose]) {
    for (a, b, z) in slam.loop_closures() {
        let t = truth[a].pose.between(&truth[b].pose);
        let dt = z.distance(&t);
        let dth = slam::models::normalize_angle(z.theta - t.theta).abs();
        assert!(
            dt < 0.25 && dth < 3f64.to_radians(),
            "false closure {a} → {b}: measured {z:?}, true {t:?}"
        );
    }
}

/// The trajectory's shape against the truth: the aligned ATE (SE(2) least squares,
/// slam-eval) and the scale a similarity alignment would apply on top (the estimate's
/// spread about its centroid against the truth's, both aligned: above 1 when the map is
/// too small).
fn shape(slam: &LaserGraphSlam, truth: &[TimedPose]) -> (f64, f64) {
    let traj = slam.trajectory();
    let aligned = slam::eval::metrics::ate(&traj, truth).unwrap().rmse_aligned;
    assert_eq!(traj.len(), truth.len());
    let a: Vec<_> = traj.iter().map(|p| p.pose.translation()).collect();
    let b: Vec<_> = truth.iter().map(|p| p.pose.translation()).collect();
    let t = slam::eval::metrics::align_se2(&a, &b);
    let a: Vec<_> = a.iter().map(|p| t.transform_point(p)).collect();
    let mean = |v: &[slam::models::Point2]| {
        v.iter()
            .fold(nalgebra::Vector2::zeros(), |s, p| s + p.coords)
            / v.len() as f64
    };
    let (ca, cb) = (mean(&a), mean(&b));
    let (mut num, mut den) = (0.0, 0.0);
    for (p, q) in a.iter().zip(&b) {
        num += (p.coords - ca).dot(&(q.coords - cb));
        den += (p.coords - ca).norm_squared();
    }
    (aligned, num / den)
}

/// Two laps of the office over seeds 1–5 with the defaults. Every seed: the loop is
/// closed and every accepted closure is true; on seeds 3 and 5 the closures join the second
/// lap to the first (records more than a third of the run apart) and the trajectory at
/// every record is within 0.2 m RMSE of the truth (gridfast's bound in tests/gridfast.rs)
/// and at least four times better than the odometry (dead reckoning drifts 1.3–3.3 m on
/// seeds 1–7). (With the acceptance score lowered to 0.45 and the widest window from the
/// start, seed 1 accepts a closure 5 m off along a corridor: the defaults' margin is not
/// large; docs/results/graph.md.)
///
/// The shape, over the five seeds: the median aligned ATE within one grid cell (5 cm), the
/// worst within 8 cm, and every seed's scale within 1 % of the truth. Before the trajectory
/// graph held the keyframes and degenerate matches took the odometry along the corridors
/// (docs/results/graph.md), re-estimating the keyframes jointly with the odometry gave
/// 0.061 / 0.046 / 0.091 / 0.046 / 0.064 m on seeds 1–5 (median 0.061, worst 0.091 m);
/// holding the keyframes without the degenerate fusion, 0.29–0.59 m with the map 4.1 % too
/// small (seed 1: the corridor matches slid 2.9 % short).
#[test]
fn office_over_five_seeds() {
    let mut aligned = Vec::new();
    for seed in 1..=5 {
        let (records, truth) = common::office(seed);
        let slam = run(&records, LaserGraphConfig::default());
        let stats = slam.stats();
        let err = common::rmse(&slam.trajectory(), &truth);
        let odo = common::rmse(&common::dead_reckoning(&records), &truth);
        let (a, scale) = shape(&slam, &truth);
        eprintln!(
            "office seed {seed}: {stats:?}, RMSE {err:.3} m, odometry {odo:.3} m, aligned ATE {a:.4} m, Sim(2) scale {scale:.5}"
        );
        assert!(
            stats.loop_closures > 0,
            "seed {seed}: no loop closure found"
        );
        assert_closures_true(&slam, &truth);
        assert!((scale - 1.0).abs() < 0.01, "seed {seed}: scale {scale}");
        aligned.push(a);
        if seed == 3 || seed == 5 {
            // Closures join the second lap to the first: records far apart in time.
            let span = slam
                .loop_closures()
                .iter()
                .map(|(a, b, _)| b - a)
                .max()
                .unwrap();
            assert!(
                span > records.len() / 3,
                "seed {seed}: longest closure spans {span} records"
            );
            assert!(err < 0.2, "seed {seed}: RMSE {err} m");
            assert!(err * 4.0 < odo, "RMSE {err} m against odometry {odo} m");
        }
    }
    aligned.sort_by(f64::total_cmp);
    let (median, worst) = (aligned[2], aligned[4]);
    assert!(median < 0.05, "median aligned ATE {median} m: {aligned:?}");
    assert!(worst < 0.08, "worst aligned ATE {worst} m: {aligned:?}");
}

/// The first 3,000 records of the Intel benchmark input (≈ 200 scans, 10 minutes): far
/// better than the odometry (≈ 0.4 m) and within GMapping's full-log range (0.057–0.070 m,
/// 2.3–2.7°) by the relations metric.
#[test]
fn intel_prefix_relations_error() {
    let (Some(log), Some(rel)) = (
        common::dataset("bench/intel.log"),
        common::dataset("slam-benchmark-relations/intel.relations"),
    ) else {
        return;
    };
    let data = slam::io::carmen::read_carmen(&log).unwrap().dataset;
    let relations = slam::io::relations::read_relations(&rel).unwrap();
    let records = &data.records[..3000];
    let t_end = records.last().unwrap().t;
    let inside: Vec<_> = relations
        .iter()
        .filter(|r| r.t1.max(r.t2) <= t_end)
        .cloned()
        .collect();
    assert!(inside.len() > 300, "{} relations", inside.len());
    let odo = slam::eval::metrics::relations_error(&common::dead_reckoning(records), &inside);
    let slam = run(records, LaserGraphConfig::default());
    let traj = slam.trajectory();
    assert_eq!(traj.len(), records.len());
    let e = slam::eval::metrics::relations_error(&traj, &inside);
    eprintln!(
        "intel prefix: {} relations; odometry {:.3} m / {:.2} deg; graph {:.4} m / {:.3} deg; {:?}",
        e.used,
        odo.trans_mean,
        odo.rot_mean_deg,
        e.trans_mean,
        e.rot_mean_deg,
        slam.stats()
    );
    assert_eq!(e.dropped, 0);
    assert!(odo.trans_mean > 0.3);
    assert!(e.trans_mean < 0.07 && e.rot_mean_deg < 3.0, "{e:?}");
}

/// The whole Intel input, relations metric (`cargo test --release --test graph_laser --
/// --ignored`; about a minute on the shared machine). Bounds: better than the original
/// GMapping run, 0.057 m / 2.32° (dataset README), on every relation; and on the relations
/// whose ends the log's clock does not leave ambiguous (`RelationsResult::ambiguous`: the
/// input stamps up to 11 records spanning half a metre with one time), the bar of issue 31,
/// 0.035 m / 1.2°, on the way to the published graph-mapping record (0.031 m, Kümmerle et
/// al. 2009); see docs/results/graph.md for the figures.
#[test]
#[ignore]
fn intel_whole_log() {
    let (Some(log), Some(rel)) = (
        common::dataset("bench/intel.log"),
        common::dataset("slam-benchmark-relations/intel.relations"),
    ) else {
        return;
    };
    let records = slam::io::carmen::read_carmen(&log).unwrap().dataset.records;
    let relations = slam::io::relations::read_relations(&rel).unwrap();
    let slam = run(&records, LaserGraphConfig::default());
    let e = slam::eval::metrics::relations_error(&slam.trajectory(), &relations);
    eprintln!(
        "intel whole log: {} relations, {:.4} m / {:.3} deg; {:?}",
        e.used,
        e.trans_mean,
        e.rot_mean_deg,
        slam.stats()
    );
    assert_eq!((e.used, e.dropped), (2984, 0));
    assert!(e.trans_mean < 0.057 && e.rot_mean_deg < 2.32, "{e:?}");
    assert!(e.ambiguous < e.used);
    assert!(
        e.unambiguous_trans_mean < 0.035 && e.unambiguous_rot_mean_deg < 1.2,
        "{e:?}"
    );
}

/// Same input, same bytes: two runs give identical trajectories (no randomness).
#[test]
fn deterministic() {
    let (records, _) = common::office(7);
    let records = &records[..600];
    let a = run(records, LaserGraphConfig::default()).trajectory();
    let b = run(records, LaserGraphConfig::default()).trajectory();
    assert_eq!(a, b);
}

/// The one constructor shape: `FromConfig` builds the same front end as `new`; the initial
/// pose places the odometry frame in the world (the trajectory moves with it, checked
/// against the identity run composed with the placement); a non-finite one is a
/// configuration error naming `initial-pose`.
#[test]
fn constructor_shape() {
    use slam::models::FromConfig;
    let (records, _) = common::office(7);
    let records = &records[..200];
    let mut a = <LaserGraphSlam as FromConfig>::from_config(
        LaserGraphConfig::default(),
        Pose2::IDENTITY,
        99,
    )
    .unwrap();
    common::run_scans(&mut a, records);
    assert_eq!(
        a.trajectory(),
        run(records, LaserGraphConfig::default()).trajectory()
    );
    // The odometry frame placed in the world: the trajectory is the identity run's, moved
    // by that placement. Not bit for bit: a moved scan falls on the grid's cells with other
    // rounding, and a match can settle one lattice step (1 cm, 0.25°) apart. The keyframes
    // are the keyframe graph's (the trajectory graph holds them), so such a step is not
    // averaged with the odometry and shows down the chain: 0.25° over the 10 m driven
    // before the first loop closure is 4.4 cm (6–9 cm here; 3 cm when the trajectory
    // graph moved the keyframes). A wrong placement would be off by metres.
    let identity = a.trajectory();
    for place in [Pose2::new(2.0, -1.0, 0.0), Pose2::new(-3.0, 4.5, 0.7)] {
        let mut b = LaserGraphSlam::new(LaserGraphConfig::default(), place, 0).unwrap();
        common::run_scans(&mut b, records);
        let moved = b.trajectory();
        assert_eq!(moved.len(), identity.len());
        let worst = identity
            .iter()
            .zip(&moved)
            .map(|(i, m)| {
                let want = place.compose(&i.pose);
                let d = want.between(&m.pose);
                d.x.hypot(d.y) + d.theta.abs()
            })
            .fold(0.0, f64::max);
        assert!(worst < 0.12, "placement {place:?}: worst deviation {worst}");
    }
    let e = LaserGraphSlam::new(
        LaserGraphConfig::default(),
        Pose2::new(f64::NAN, 0.0, 0.0),
        0,
    )
    .unwrap_err();
    let slam::graph::GraphError::InvalidConfig(c) = &e else {
        panic!("{e}")
    };
    assert_eq!(c.key(), "initial-pose");
}

/// Finished submaps keep no grid: the loop search rebuilds it from the keyframes' scans.
/// With a cache of one loop map (a rebuild at almost every search), or a byte budget of 0
/// (one pyramid kept), the run is the same, to the bit, as with a cache of a hundred and
/// no byte limit (every map built once): the rebuilt grids are the grids.
#[test]
fn loop_map_cache_size_does_not_change_the_result() {
    let (records, _) = common::office(3);
    let small = run(
        &records,
        LaserGraphConfig {
            loop_pyramid_cache: 1,
            ..Default::default()
        },
    );
    let no_bytes = run(
        &records,
        LaserGraphConfig {
            loop_pyramid_cache_bytes: 0,
            ..Default::default()
        },
    );
    let large = run(
        &records,
        LaserGraphConfig {
            loop_pyramid_cache: 100,
            loop_pyramid_cache_bytes: 1 << 40,
            ..Default::default()
        },
    );
    assert!(small.stats().loop_closures > 0);
    for other in [&no_bytes, &large] {
        assert_eq!(small.stats(), other.stats());
        assert_eq!(small.trajectory(), other.trajectory());
    }
}

/// The end-of-run flush: a log that ends while the first closures of the office's second
/// lap wait for the group test (it waits `loop-group-span` / `loop-group-gap` keyframes) is
/// settled by `ScanSlam::finish`, which slam-eval's run calls after the last record. Cut
/// where the first group holds two candidates (the state is checked: no closure in the
/// graph yet), the run ends with that group's closures in the graph, every one true, and the
/// last pose nearer the truth than without them.
#[test]
fn closures_pending_at_the_end_are_settled() {
    let (records, truth) = common::office(3);
    let mut slam = LaserGraphSlam::new(LaserGraphConfig::default(), Pose2::IDENTITY, 0).unwrap();
    let mut end = 0;
    for (i, r) in records.iter().enumerate() {
        slam.step(r).unwrap();
        if slam.pending_closures() >= 2 {
            end = i + 1;
            break;
        }
    }
    assert!(end > 0, "no loop closure candidate");
    assert_eq!(slam.stats().loop_closures, 0);
    let records = &records[..end];
    let truth = &truth[..end];
    let before = error_at_end(&slam.trajectory(), truth);
    // The whole run through slam-eval's loop (which calls finish after the last record).
    let flushed = run(records, LaserGraphConfig::default());
    let after = error_at_end(&flushed.trajectory(), truth);
    eprintln!(
        "cut at record {end}: {:?}; last pose {before:.3} m from the truth before the flush, {after:.3} m after",
        flushed.stats()
    );
    assert!(flushed.stats().loop_closures >= 2, "{:?}", flushed.stats());
    assert_eq!(flushed.pending_closures(), 0);
    assert_closures_true(&flushed, truth);
    assert!(
        after < before,
        "{after} m after the flush, {before} m before"
    );
}

/// A loop around one block of the simulated campus (65 m × 65 m of road, 1.2 laps ≈ 310 m;
/// the campus' trees and buildings, its 0.03 m range noise, 181 beams, 30 m range), with
/// the odometry noise doubled (α × 4) and a keyframe every 0.5 m to keep it cheap: its
/// records and ground truth.
fn campus_block(seed: u64) -> (Vec<ScanRecord>, Vec<TimedPose>) {
    use slam::sim::laser::{simulate_laser, LaserScanner, LaserSimConfig};
    use slam::sim::scenario::laser::{campus_world, CAMPUS_ROADS};
    let c = |i: usize, j: usize| slam::models::Point2::new(CAMPUS_ROADS[i], CAMPUS_ROADS[j]);
    let path =
        slam::sim::path::Path::rounded(&[c(0, 0), c(1, 0), c(1, 1), c(0, 1)], true, 4.0, 0.1)
            .unwrap();
    let mut cfg = LaserSimConfig::default();
    cfg.follower.speed = 1.5;
    cfg.follower.lookahead = 3.0;
    let per_scan = cfg.follower.speed * cfg.follower.dt * cfg.odometry_per_scan as f64;
    cfg.scans = (1.2 * path.length() / per_scan).round() as usize;
    cfg.odometry.alpha.iter_mut().for_each(|a| *a *= 4.0);
    cfg.scanner = LaserScanner {
        max_range: 30.0,
        sigma: 0.03,
        ..LaserScanner::default()
    };
    let run = simulate_laser(&campus_world(), &path, &cfg, seed).unwrap();
    (run.dataset.records, run.dataset.ground_truth.unwrap())
}

/// The position error of the last record against the truth, both taken relative to their
/// first pose (the robot ends near where it started: the drift of the loop).
fn error_at_end(trajectory: &[TimedPose], truth: &[TimedPose]) -> f64 {
    let (e0, t0) = (trajectory[0].pose, truth[0].pose);
    let (e, t) = (trajectory.last().unwrap().pose, truth.last().unwrap().pose);
    e0.between(&e).distance(&t0.between(&t))
}

/// The campus' failure in small (issue 31): after a long loop the scan-matching chain has
/// drifted beyond the old 3 m loop window (checked: without loop closure the last pose is
/// more than 3 m from the truth), so the revisit is found only by a window sized from the
/// graph distance. With the defaults the loop is closed (a closure joins records most of
/// the run apart), every closure is true, and the last pose ends within 0.5 m (the issue's
/// campus bar) of the truth; sampling half the candidacies (`loop-sampling-ratio` ½)
/// runs fewer searches and still closes it, as truly and as well.
#[test]
fn long_loop_beyond_the_narrow_window_is_closed() {
    let (records, truth) = campus_block(1);
    let config = LaserGraphConfig {
        keyframe_distance: 0.5,
        ..LaserGraphConfig::default()
    };
    let open = run(
        &records,
        LaserGraphConfig {
            loop_max_candidates: 0,
            ..config.clone()
        },
    );
    let drift = error_at_end(&open.trajectory(), &truth);
    // Half the candidacies searched (`loop-sampling-ratio` ½): fewer searches, and the
    // same loop must still be closed.
    let sampled = run(
        &records,
        LaserGraphConfig {
            loop_sampling_ratio: 0.5,
            ..config.clone()
        },
    );
    let slam = run(&records, config);
    let closed = error_at_end(&slam.trajectory(), &truth);
    assert!(
        sampled.stats().loop_searches < slam.stats().loop_searches,
        "sampled {} searches, every candidate {}",
        sampled.stats().loop_searches,
        slam.stats().loop_searches
    );
    let span = slam
        .loop_closures()
        .iter()
        .map(|(a, b, _)| b - a)
        .max()
        .unwrap_or(0);
    eprintln!(
        "campus block: {} records; last pose {drift:.3} m off without loop closure, {closed:.3} m with; longest closure {span} records; {:?}",
        records.len(),
        slam.stats()
    );
    assert!(drift > 3.0, "the chain drifted only {drift} m");
    assert!(
        span > records.len() * 2 / 3,
        "longest closure spans {span} records"
    );
    assert_closures_true(&slam, &truth);
    assert!(closed < 0.5, "last pose {closed} m from the truth");
    let sampled_span = sampled
        .loop_closures()
        .iter()
        .map(|(a, b, _)| b - a)
        .max()
        .unwrap_or(0);
    let sampled_closed = error_at_end(&sampled.trajectory(), &truth);
    eprintln!(
        "sampled ½: last pose {sampled_closed:.3} m; longest closure {sampled_span}; {:?}",
        sampled.stats()
    );
    assert!(
        sampled_span > records.len() * 2 / 3,
        "sampled: longest closure spans {sampled_span} records"
    );
    assert_closures_true(&sampled, &truth);
    assert!(
        sampled_closed < 0.5,
        "sampled: last pose {sampled_closed} m from the truth"
    );
}
