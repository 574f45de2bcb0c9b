//! slam-graph on the M3500 benchmark (`../shared/datasets/pose-graphs/`) against GTSAM's
//! figure for the same problem (the fixture `crates/slam-graph/tests/fixtures/m3500_gtsam.json`,
//! made by `scripts/gtsam_compare.sh`, which says how).

mod common;

use slam_graph::{Method, Optimizer, OptimizerConfig, StopReason};

fn fixture() -> serde_json::Value {
    let p = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/crates/slam-graph/tests/fixtures/m3500_gtsam.json"
    );
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

/// The file reads whole: the counts of the datasets README.
#[test]
fn m3500_reads() {
    let Some(path) = common::dataset("pose-graphs/input_M3500_g2o.g2o") else {
        return;
    };
    let g = slam_eval::pose_graph::read_pose_graph(&path).unwrap();
    assert_eq!(g.nodes().len(), 3500);
    assert_eq!(g.edges().len(), 5453);
}

/// From the file's initial guess, Levenberg-Marquardt with GTSAM's default schedule and
/// stopping rule reaches the χ² of GTSAM's result (g2o's error evaluated there) to a relative
/// 1e-6. Why 1e-6: both stop once an iteration lowers χ² by less than 1e-5 of itself, and LM
/// converges quadratically near the optimum, so each result's excess over the optimum is a
/// small fraction of that last decrease; the two programs also minimise slightly different
/// errors (t2v against GTSAM's Log), whose optima differ, in χ², by far less (both measured
/// 2026-12-02: 137.912951 against 137.912951, 7e-10 apart). The initial χ² is the datasets
/// README's independent figure, 2.56667e6. Gauss-Newton reaches the same optimum.
#[test]
fn m3500_matches_gtsam() {
    let Some(path) = common::dataset("pose-graphs/input_M3500_g2o.g2o") else {
        return;
    };
    let want = fixture()["chi2_final_g2o_error"].as_f64().unwrap();
    for method in [Method::LevenbergMarquardt, Method::GaussNewton] {
        let mut g = slam_eval::pose_graph::read_pose_graph(&path).unwrap();
        let config = OptimizerConfig {
            method,
            ..OptimizerConfig::default()
        };
        let r = Optimizer::new(&g, config)
            .unwrap()
            .optimize(&mut g)
            .unwrap();
        assert!(
            (r.initial_chi2 / 2.56667e6 - 1.0).abs() < 5e-6,
            "{}",
            r.initial_chi2
        );
        assert!(
            (r.final_chi2 / want - 1.0).abs() < 1e-6,
            "{method:?}: χ² {} against GTSAM's {want}",
            r.final_chi2
        );
        assert!(matches!(
            r.stop,
            StopReason::RelativeDecrease | StopReason::AbsoluteDecrease
        ));
        assert!(r.iterations.len() < 20, "{} iterations", r.iterations.len());
        // The gauge: pose 0 stays at the origin.
        assert_eq!(g.pose(0), Some(slam_models::Pose2::IDENTITY));
    }
}

/// GTSAM 4.3.0's figures for issue 30 (`tests/gtsam_truth.py`, which says how they were made).
fn truth(file: &str) -> serde_json::Value {
    let p = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/crates/slam-graph/tests/fixtures/issue30_gtsam.json"
    );
    let all: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
    all["files"][file].clone()
}

/// From M3500a's own (poor) initial guess, the defaults (LAGO's start when better, then LM)
/// reach the best optimum known, χ² 912.1 in g2o's error (the datasets README: slam-graph and
/// GTSAM started from the clean M3500 optimum), within 1 %; GTSAM from the same file guess
/// stops several times higher (its figure, in the fixture, is asserted to be, so the test
/// says something GTSAM's default does not do). The TORO file reads whole.
#[test]
fn m3500a_reaches_the_best_optimum_from_its_own_guess() {
    let Some(path) = common::dataset("pose-graphs/M3500a.graph") else {
        return;
    };
    let mut g = slam_eval::pose_graph::read_pose_graph(&path).unwrap();
    assert_eq!((g.nodes().len(), g.edges().len()), (3500, 5453));
    let r = Optimizer::new(&g, OptimizerConfig::default())
        .unwrap()
        .optimize(&mut g)
        .unwrap();
    assert!(r.stop.converged(), "{:?}", r.stop);
    assert!(
        (r.final_chi2 / 912.1 - 1.0).abs() < 0.01,
        "χ² {} against 912.1",
        r.final_chi2
    );
    let gtsam = truth("M3500a.graph")["chi2_final_g2o_error"]
        .as_f64()
        .unwrap();
    assert!(gtsam > 2.0 * 912.1, "GTSAM's {gtsam}");
    assert!(r.rejected_closures.is_empty());
}

/// City10000 from its file's guess: at or below GTSAM 4.3.0's χ² (g2o's error at GTSAM's
/// result, the fixture) from the same guess.
#[test]
fn city10000_at_or_below_gtsam() {
    let Some(path) = common::dataset("pose-graphs/city10000.g2o") else {
        return;
    };
    let mut g = slam_eval::pose_graph::read_pose_graph(&path).unwrap();
    let r = Optimizer::new(&g, OptimizerConfig::default())
        .unwrap()
        .optimize(&mut g)
        .unwrap();
    let gtsam = truth("city10000.g2o")["chi2_final_g2o_error"]
        .as_f64()
        .unwrap();
    assert!(r.stop.converged(), "{:?}", r.stop);
    assert!(
        r.final_chi2 <= gtsam * (1.0 + 1e-6),
        "χ² {} against GTSAM's {gtsam}",
        r.final_chi2
    );
}

/// Gauss-Newton from M3500a's own guess (no LAGO, no closure treatment) raises χ² on its
/// third step: the run says `diverged`, keeps the best iterate (the graph's χ² is the lowest
/// any iteration reached, below the start) and the report counts as worse than a success.
#[test]
fn diverging_gauss_newton_is_reported() {
    let Some(path) = common::dataset("pose-graphs/M3500a.graph") else {
        return;
    };
    let mut g = slam_eval::pose_graph::read_pose_graph(&path).unwrap();
    let config = OptimizerConfig {
        method: Method::GaussNewton,
        initialisation: slam_graph::Initialisation::Input,
        closure_kernel: slam_graph::RobustKernel::None,
        ..OptimizerConfig::default()
    };
    let mut o = Optimizer::new(&g, config).unwrap();
    let r = o.optimize(&mut g).unwrap();
    assert_eq!(r.stop, StopReason::Diverged);
    assert!(r.worse_than_start());
    let last = r.iterations.last().unwrap();
    assert!(!last.accepted);
    let best = r
        .iterations
        .iter()
        .map(|i| i.chi2_after)
        .fold(f64::INFINITY, f64::min);
    assert_eq!(r.final_chi2, best);
    assert_eq!(o.cost(&g).unwrap().0, best);
    assert!(r.final_chi2 < r.initial_chi2);
}

/// The kind of a false loop closure.
#[derive(Debug, Clone, Copy)]
enum FalseKind {
    /// Claims the two poses coincide (a place recognised wrongly).
    Identity,
    /// A random relative pose: x, y uniform in ±10 m, θ uniform in (−π, π].
    RandomPose,
}

/// The seeded generator of corrupted graphs: `graph` plus round(fraction × edges) false
/// closures between random pairs of poses (ids more than one apart, no pair twice), each with
/// the information matrix of the graph's first edge (an odometry edge: the false closure
/// claims to be as certain as odometry).
fn with_false_closures(
    graph: &slam_graph::PoseGraph,
    fraction: f64,
    kind: FalseKind,
    seed: u64,
) -> slam_graph::PoseGraph {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut g = graph.clone();
    let slam_graph::Edge::Between(first) = graph.edges()[0] else {
        panic!("the first edge is not pose-pose")
    };
    let ids: Vec<u64> = graph.nodes().iter().map(|n| n.id).collect();
    let n = (fraction * graph.edges().len() as f64).round() as usize;
    let mut used = std::collections::HashSet::new();
    while used.len() < n {
        let (a, b) = (
            ids[rng.random_range(0..ids.len())],
            ids[rng.random_range(0..ids.len())],
        );
        if a.abs_diff(b) <= 1 || !used.insert((a.min(b), a.max(b))) {
            continue;
        }
        let z = match kind {
            FalseKind::Identity => slam_models::Pose2::IDENTITY,
            FalseKind::RandomPose => slam_models::Pose2::new(
                rng.random_range(-10.0..10.0),
                rng.random_range(-10.0..10.0),
                rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
            ),
        };
        g.add_between(a, b, z, first.information).unwrap();
    }
    g
}

/// RMSE of the positions of `a` against `b` after the SE(2) alignment of `a` onto `b` that
/// minimises it (closed form: the rotation angle atan2(Σ a×b, Σ a·b) of the centred points,
/// Umeyama 1991 without scale).
fn aligned_rmse(a: &[slam_models::Pose2], b: &[slam_models::Pose2]) -> f64 {
    let n = a.len() as f64;
    let (ax, ay) = a
        .iter()
        .fold((0.0, 0.0), |s, p| (s.0 + p.x / n, s.1 + p.y / n));
    let (bx, by) = b
        .iter()
        .fold((0.0, 0.0), |s, p| (s.0 + p.x / n, s.1 + p.y / n));
    let (mut cross, mut dot) = (0.0, 0.0);
    for (p, q) in a.iter().zip(b) {
        let (u, v) = ((p.x - ax, p.y - ay), (q.x - bx, q.y - by));
        cross += u.0 * v.1 - u.1 * v.0;
        dot += u.0 * v.0 + u.1 * v.1;
    }
    let (s, c) = cross.atan2(dot).sin_cos();
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(p, q)| {
            let (u0, u1) = (p.x - ax, p.y - ay);
            let x = c * u0 - s * u1 + bx;
            let y = s * u0 + c * u1 + by;
            (x - q.x).powi(2) + (y - q.y).powi(2)
        })
        .sum();
    (sum / n).sqrt()
}

/// M3500 with 1 %, 5 % and 10 % false loop closures (of its 5,453 edges: 55, 273, 545), once
/// claiming identity and once a random pose: the default settings end within 0.05 m RMSE
/// (after SE(2) alignment) of the clean graph's optimum (from least squares on the clean
/// graph with the closure treatment off, whose χ² `m3500_matches_gtsam` checks against
/// GTSAM), at least 90 % of the false closures rejected and no correct closure. Plain least squares on the same graphs ends metres off
/// (asserted for the 10 % cases, so the test can fail).
#[test]
fn m3500_survives_false_closures() {
    let Some(path) = common::dataset("pose-graphs/input_M3500_g2o.g2o") else {
        return;
    };
    let clean = slam_eval::pose_graph::read_pose_graph(&path).unwrap();
    let plain = OptimizerConfig {
        closure_kernel: slam_graph::RobustKernel::None,
        ..OptimizerConfig::default()
    };
    let mut reference = clean.clone();
    Optimizer::new(&reference, plain)
        .unwrap()
        .optimize(&mut reference)
        .unwrap();
    let truth = reference.poses();
    for (seed, fraction) in [(1, 0.01), (5, 0.05), (10, 0.10)] {
        for kind in [FalseKind::Identity, FalseKind::RandomPose] {
            let corrupted = with_false_closures(&clean, fraction, kind, seed);
            let n_false = corrupted.edges().len() - clean.edges().len();
            let mut g = corrupted.clone();
            let r = Optimizer::new(&g, OptimizerConfig::default())
                .unwrap()
                .optimize(&mut g)
                .unwrap();
            let rmse = aligned_rmse(&g.poses()[..truth.len()], &truth);
            eprintln!(
                "{fraction} {kind:?}: {n_false} false, rmse {rmse:.2e} m, {} rejected, {:?}, {} iterations",
                r.rejected_closures.len(),
                r.stop,
                r.iterations.len()
            );
            assert!(rmse < 0.05, "{fraction} {kind:?}: RMSE {rmse} m");
            // Exactly the false closures (the edges added last) are rejected.
            let first_false = clean.edges().len();
            assert!(r.rejected_closures.iter().all(|&k| k >= first_false));
            // All but a few (an identity claim between two poses that happen to coincide on
            // Manhattan's grid of streets is consistent) of the false ones.
            assert!(
                r.rejected_closures.len() * 10 >= n_false * 9,
                "{fraction} {kind:?}: {} of {n_false}",
                r.rejected_closures.len()
            );
            if fraction == 0.10 {
                let mut ls = corrupted.clone();
                Optimizer::new(&ls, plain)
                    .unwrap()
                    .optimize(&mut ls)
                    .unwrap();
                let off = aligned_rmse(&ls.poses(), &truth);
                assert!(off > 1.0, "least squares only {off} m off");
            }
        }
    }
}
