//! Unit tests of the landmark front end: the marginal covariance against a dense inverse of
//! H built from finite-difference Jacobians, bad input, a stationary robot, and the
//! linear-Gaussian case in which the smoother's last-pose marginal equals a Kalman filter's.

use super::*;
use crate::factor::{linearize, retract, Linearized};
use crate::graph::NodeValue;
use crate::optimizer::OptimizerConfig;
use nalgebra::DMatrix;
use slam_models::{OdometryControl, Point2};

fn odo(trans: f64, rot: f64) -> Control {
    Control::Odometry(OdometryControl {
        rot1: rot,
        trans,
        rot2: 0.0,
    })
}

fn rb(range: f64, bearing: f64, id: u32) -> RangeBearing {
    RangeBearing::new(range, bearing, Some(LandmarkId(id))).unwrap()
}

/// H = Σ JᵀΩJ with every J by central differences of the edge errors (independent of the
/// analytic Jacobians and of the sparse solver), over the free nodes, inverted densely.
fn dense_covariance(g: &PoseGraph) -> (DMatrix<f64>, Vec<Option<usize>>) {
    let x: Vec<NodeValue> = g.nodes().iter().map(|n| n.value).collect();
    let mut off = Vec::new();
    let mut n = 0;
    for node in g.nodes() {
        if node.fixed {
            off.push(None);
        } else {
            off.push(Some(n));
            n += node.value.dim();
        }
    }
    let err = |xs: &[NodeValue], e: &crate::graph::Edge| -> Vec<f64> {
        match linearize(e, xs).unwrap() {
            Linearized::Between { e, .. } => e.as_slice().to_vec(),
            Linearized::Point { e, .. } => e.as_slice().to_vec(),
        }
    };
    let mut h = DMatrix::<f64>::zeros(n, n);
    for e in g.edges() {
        let omega: DMatrix<f64> = match linearize(e, &x).unwrap() {
            Linearized::Between { omega, .. } => DMatrix::from_column_slice(3, 3, omega.as_slice()),
            Linearized::Point { omega, .. } => DMatrix::from_column_slice(2, 2, omega.as_slice()),
        };
        let rows = omega.nrows();
        let mut j = DMatrix::<f64>::zeros(rows, n);
        let (a, b) = e.nodes();
        for node in [a, b] {
            let Some(o) = off[node] else { continue };
            for k in 0..x[node].dim() {
                let hstep = 1e-6;
                let mut d = [0.0; 3];
                d[k] = hstep;
                let mut xp = x.clone();
                xp[node] = retract(&x[node], &d);
                d[k] = -hstep;
                let mut xm = x.clone();
                xm[node] = retract(&x[node], &d);
                let (ep, em) = (err(&xp, e), err(&xm, e));
                for r in 0..rows {
                    j[(r, o + k)] = normalize(ep[r] - em[r]) / (2.0 * hstep);
                }
            }
        }
        h += j.transpose() * omega * j;
    }
    (h.try_inverse().expect("H invertible"), off)
}

fn normalize(d: f64) -> f64 {
    slam_models::normalize_angle(d)
}

/// The belief after an optimisation is the Laplace marginal: the blocks of H⁻¹ for the
/// latest pose and every landmark, H from numerical Jacobians and a dense inverse.
#[test]
fn belief_is_the_marginal_of_the_dense_inverse() {
    let mut g = GraphLandmarkSlam::new(
        GraphLandmarkConfig {
            optimize_every: 1,
            ..GraphLandmarkConfig::default()
        },
        Pose2::new(0.3, -0.2, 0.4),
        0,
    )
    .unwrap();
    let steps = [
        (odo(1.0, 0.1), vec![rb(3.0, 0.5, 1), rb(4.0, -0.6, 2)]),
        (odo(1.0, 0.2), vec![rb(2.6, 0.7, 1)]),
        (odo(0.8, -0.1), vec![rb(3.1, -0.9, 2), rb(5.0, 1.2, 3)]),
        (odo(1.2, 0.3), vec![]),
        (odo(0.9, 0.0), vec![rb(2.9, 1.0, 3), rb(4.2, 0.2, 1)]),
    ];
    for (u, zs) in &steps {
        g.predict_control(u).unwrap();
        g.update_observations(zs).unwrap();
    }
    g.optimize_now().unwrap();
    let (cov, off) = dense_covariance(g.graph());
    let last = g.graph().node_index(g.last_node).unwrap();
    let o = off[last].unwrap();
    let pxx = g.pose_covariance();
    for r in 0..3 {
        for c in 0..3 {
            let want = cov[(o + r, o + c)];
            assert!(
                (pxx[(r, c)] - want).abs() < 1e-5 * cov[(o + r, o + r)],
                "pose ({r}, {c}): {} vs {want}",
                pxx[(r, c)]
            );
        }
    }
    for (j, l) in g.landmarks().iter().enumerate() {
        let i = g.graph().node_index(LANDMARK_NODE_BASE + j as u64).unwrap();
        let ol = off[i].unwrap();
        for r in 0..2 {
            for c in 0..2 {
                let want = cov[(ol + r, ol + c)];
                assert!(
                    (l.covariance[(r, c)] - want).abs() < 1e-5 * cov[(ol + r, ol + r)],
                    "landmark {j} ({r}, {c}): {} vs {want}",
                    l.covariance[(r, c)]
                );
            }
            for c in 0..3 {
                let want = cov[(ol + r, o + c)];
                let got = g.belief.pose_landmark_cov(j)[(c, r)];
                assert!((got - want).abs() < 1e-5 * cov[(ol + r, ol + r)].max(cov[(o + c, o + c)]));
            }
        }
    }
}

/// Linear-Gaussian case: a robot driving straight along x (odometry has no rotation, so
/// the models are linear in x) observing a landmark straight ahead, whose range is linear in
/// x. Then the smoother's marginal of the last pose equals a Kalman filter's posterior
/// variance, computed here by hand in x alone.
#[test]
fn linear_case_matches_the_kalman_filter() {
    let mut config = GraphLandmarkConfig::default();
    config.motion.odometry.alpha = [0.0, 0.0, 0.02, 0.0];
    let sr: f64 = 0.2;
    config.sensor.sigma_range = sr;
    let mut g = GraphLandmarkSlam::new(config, Pose2::IDENTITY, 0).unwrap();
    // Kalman filter on s = (x, m): x ← x + d with variance α₃d², z = m − x with variance σr².
    let mut p = DMatrix::<f64>::zeros(2, 2);
    let mut first = true;
    for k in 0..6 {
        let d = 0.5 + 0.1 * k as f64;
        g.predict_control(&odo(d, 0.0)).unwrap();
        p[(0, 0)] += 0.02 * d * d;
        let x_true: f64 = (0..=k).map(|i| 0.5 + 0.1 * i as f64).sum();
        g.update_observations(&[rb(10.0 - x_true, 0.0, 5)]).unwrap();
        if first {
            // m = x + z: augmentation.
            let pxx = p[(0, 0)];
            p = DMatrix::from_row_slice(2, 2, &[pxx, pxx, pxx, pxx + sr * sr]);
            first = false;
        } else {
            let hrow = DMatrix::from_row_slice(1, 2, &[-1.0, 1.0]);
            let s = (&hrow * &p * hrow.transpose())[(0, 0)] + sr * sr;
            let kg = &p * hrow.transpose() / s;
            p = &p - &kg * &hrow * &p;
        }
    }
    g.finish().unwrap();
    let pxx = g.pose_covariance()[(0, 0)];
    assert!(
        (pxx - p[(0, 0)]).abs() < 1e-5 * p[(0, 0)],
        "{pxx} vs Kalman {}",
        p[(0, 0)]
    );
    let pmm = g.landmarks()[0].covariance[(0, 0)];
    assert!(
        (pmm - p[(1, 1)]).abs() < 1e-5 * p[(1, 1)],
        "{pmm} vs {}",
        p[(1, 1)]
    );
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let c = GraphLandmarkConfig {
        association: AssociationMode::KnownIds.into(),
        ..GraphLandmarkConfig::default()
    };
    let mut g = GraphLandmarkSlam::new(c.clone(), Pose2::IDENTITY, 0).unwrap();
    g.predict_control(&odo(1.0, 0.0)).unwrap();
    let no_id = RangeBearing::new(2.0, 0.1, None).unwrap();
    assert_eq!(
        g.update_observations(&[rb(1.0, 0.0, 1), no_id]),
        Err(GraphError::MissingId { index: 1 })
    );
    let nan = RangeBearing {
        range: f64::NAN,
        bearing: 0.0,
        id: Some(LandmarkId(1)),
    };
    assert!(matches!(
        g.update_observations(&[nan]),
        Err(GraphError::InvalidInput(_))
    ));
    assert!(matches!(
        g.predict_control(&odo(f64::INFINITY, 0.0)),
        Err(GraphError::InvalidInput(_))
    ));
    assert!(matches!(
        GraphLandmarkSlam::new(c.clone(), Pose2::new(f64::NAN, 0.0, 0.0), 0),
        Err(GraphError::InvalidInput(_))
    ));
    let bad = GraphLandmarkConfig {
        optimize_every: 0,
        ..c
    };
    assert!(matches!(
        GraphLandmarkSlam::new(bad, Pose2::IDENTITY, 0),
        Err(GraphError::InvalidConfig(slam_models::ConfigError {
            field: "optimize_every",
            ..
        }))
    ));
    // A zero range (the landmark on the robot: bearing undefined) is rejected, not an error.
    let mut g = GraphLandmarkSlam::new(GraphLandmarkConfig::default(), Pose2::IDENTITY, 0).unwrap();
    g.predict_control(&odo(1.0, 0.0)).unwrap();
    let info = g.update_observations(&[rb(0.0, 0.3, 9)]).unwrap();
    assert_eq!((info.rejected, info.new_landmarks), (1, 0));
    g.finish().unwrap();
    let small = GraphLandmarkConfig {
        max_landmarks: 1,
        ..GraphLandmarkConfig::default()
    };
    let mut g = GraphLandmarkSlam::new(small, Pose2::IDENTITY, 0).unwrap();
    g.predict_control(&odo(1.0, 0.0)).unwrap();
    assert_eq!(
        g.update_observations(&[rb(1.0, 0.0, 1), rb(2.0, 0.5, 2)]),
        Err(GraphError::TooManyLandmarks { max: 1 })
    );
}

/// A robot that never moves (zero motion noise) and sees one landmark: the floor keeps Ω
/// finite, the landmark stays where it was seen and the path has one entry per update.
#[test]
fn a_standing_robot_is_fine() {
    let mut g = GraphLandmarkSlam::new(GraphLandmarkConfig::default(), Pose2::IDENTITY, 0).unwrap();
    for _ in 0..20 {
        g.predict_control(&odo(0.0, 0.0)).unwrap();
        g.update_observations(&[rb(2.0, 0.0, 4)]).unwrap();
    }
    g.finish().unwrap();
    let l = g.landmarks();
    assert_eq!(l.len(), 1);
    assert!((l[0].mean - Point2::new(2.0, 0.0)).norm() < 1e-6);
    let path = g.full_path().unwrap();
    assert_eq!(path.len(), 21);
    assert!(path.iter().all(|p| p.approx_eq(&Pose2::IDENTITY, 1e-6)));
}

/// Updates without observations compose into one odometry edge per
/// `max_steps_between_nodes`; the path still has an entry per update, each the composition
/// of the controls, and `finish` adds the last pose as a leaf without moving anything.
#[test]
fn dead_reckoning_between_nodes_is_the_composition() {
    let c = GraphLandmarkConfig {
        max_steps_between_nodes: 4,
        optimizer: OptimizerConfig::default(),
        ..GraphLandmarkConfig::default()
    };
    let mut g = GraphLandmarkSlam::new(c, Pose2::new(1.0, 2.0, 0.5), 0).unwrap();
    let mut truth = vec![Pose2::new(1.0, 2.0, 0.5)];
    for k in 0..10 {
        let u = odo(0.5, 0.1 * k as f64);
        g.predict_control(&u).unwrap();
        g.update_observations(&[]).unwrap();
        let prev = *truth.last().unwrap();
        truth.push(g.config().motion.predict(&prev, &u));
    }
    g.finish().unwrap();
    assert_eq!(g.stats().pose_nodes, 1 + 2 + 1);
    let path = g.full_path().unwrap();
    assert_eq!(path.len(), truth.len());
    for (p, t) in path.iter().zip(&truth) {
        assert!(p.approx_eq(t, 1e-9), "{p:?} vs {t:?}");
    }
    assert!(g.pose().approx_eq(truth.last().unwrap(), 1e-9));
}
