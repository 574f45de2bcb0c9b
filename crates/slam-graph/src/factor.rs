//! Errors and their analytic Jacobians for each edge kind, with respect to the additive
//! update of g2o's `VertexSE2::oplusImpl`: a pose (x, y, θ) ⊞ δ = (x + δx, y + δy,
//! normalise(θ + δθ)), a point l ⊞ δ = l + δ (Kümmerle et al. 2011; Grisetti et al. 2010,
//! §IV-A). The tests check every Jacobian against central differences of the error.

use crate::graph::{BetweenEdge, Edge, NodeValue, PointXyEdge, RangeBearingEdge};
use slam_models::measurement::RangeBearingModel;
use slam_models::{detmath, normalize_angle, Matrix2, Matrix2x3, Matrix3, Point2, Pose2};
use slam_models::{Vector2, Vector3};

/// One edge linearised at the current estimate: e, ∂e/∂(first node), ∂e/∂(second node), Ω.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Linearized {
    /// A 3-dimensional error between two poses.
    Between {
        /// e = t2v(Z⁻¹ Xᵢ⁻¹ Xⱼ).
        e: Vector3,
        /// ∂e/∂xᵢ (Grisetti et al. 2010, eq. 32, Aᵢⱼ).
        a: Matrix3,
        /// ∂e/∂xⱼ (Bᵢⱼ).
        b: Matrix3,
        /// Ω.
        omega: Matrix3,
    },
    /// A 2-dimensional error between a pose and a point.
    Point {
        /// e.
        e: Vector2,
        /// ∂e/∂(x, y, θ) of the pose.
        a: Matrix2x3,
        /// ∂e/∂l of the point.
        b: Matrix2,
        /// Ω.
        omega: Matrix2,
    },
}

impl Linearized {
    /// The squared Mahalanobis error s = eᵀΩe.
    pub fn chi2(&self) -> f64 {
        match self {
            Linearized::Between { e, omega, .. } => e.dot(&(omega * e)),
            Linearized::Point { e, omega, .. } => e.dot(&(omega * e)),
        }
    }
}

fn pose(v: &NodeValue) -> Pose2 {
    match *v {
        NodeValue::Pose(p) => p,
        // Kinds are checked when edges are added; a point here is a caller's set_value bug.
        NodeValue::Point(p) => Pose2::new(p.x, p.y, 0.0),
    }
}

fn point(v: &NodeValue) -> Point2 {
    match *v {
        NodeValue::Point(p) => p,
        NodeValue::Pose(p) => Point2::new(p.x, p.y),
    }
}

/// e = t2v(Z⁻¹ (Xᵢ⁻¹ Xⱼ)) with its Jacobians. With Rᵢ, R_z the rotations of xᵢ and Z and
/// Δt = tⱼ − tᵢ: e_t = R_zᵀ(Rᵢᵀ Δt − t_z), e_θ = normalise(θⱼ − θᵢ − θ_z);
/// ∂e_t/∂tᵢ = −R_zᵀRᵢᵀ, ∂e_t/∂θᵢ = R_zᵀ (dRᵢᵀ/dθ) Δt, ∂e_t/∂tⱼ = R_zᵀRᵢᵀ,
/// ∂e_θ/∂θᵢ = −1, ∂e_θ/∂θⱼ = 1 (Grisetti et al. 2010, eqs. 30–32).
pub fn between(edge: &BetweenEdge, xi: &Pose2, xj: &Pose2) -> Linearized {
    let z = &edge.measurement;
    let (si, ci) = detmath::sin_cos(xi.theta);
    let (sz, cz) = detmath::sin_cos(z.theta);
    let dx = xj.x - xi.x;
    let dy = xj.y - xi.y;
    // d = Rᵢᵀ Δt and its derivative in θᵢ.
    let d = Vector2::new(ci * dx + si * dy, -si * dx + ci * dy);
    let dd = Vector2::new(-si * dx + ci * dy, -ci * dx - si * dy);
    let rz_t = Matrix2::new(cz, sz, -sz, cz);
    let ri_t = Matrix2::new(ci, si, -si, ci);
    let et = rz_t * (d - Vector2::new(z.x, z.y));
    let e = Vector3::new(et.x, et.y, normalize_angle(xj.theta - xi.theta - z.theta));
    let m = rz_t * ri_t;
    let g = rz_t * dd;
    let a = Matrix3::new(
        -m[(0, 0)],
        -m[(0, 1)],
        g.x, //
        -m[(1, 0)],
        -m[(1, 1)],
        g.y, //
        0.0,
        0.0,
        -1.0,
    );
    let b = Matrix3::new(
        m[(0, 0)],
        m[(0, 1)],
        0.0, //
        m[(1, 0)],
        m[(1, 1)],
        0.0, //
        0.0,
        0.0,
        1.0,
    );
    Linearized::Between {
        e,
        a,
        b,
        omega: edge.information,
    }
}

/// e = Rᵢᵀ(l − tᵢ) − z; ∂e/∂tᵢ = −Rᵢᵀ, ∂e/∂θᵢ = (dRᵢᵀ/dθ)(l − tᵢ), ∂e/∂l = Rᵢᵀ (g2o's
/// `EdgeSE2PointXY`).
pub fn point_xy(edge: &PointXyEdge, x: &Pose2, l: &Point2) -> Linearized {
    let (s, c) = detmath::sin_cos(x.theta);
    let dx = l.x - x.x;
    let dy = l.y - x.y;
    let e = Vector2::new(
        c * dx + s * dy - edge.measurement.x,
        -s * dx + c * dy - edge.measurement.y,
    );
    let a = Matrix2x3::new(-c, -s, -s * dx + c * dy, s, -c, -c * dx - s * dy);
    let b = Matrix2::new(c, s, -s, c);
    Linearized::Point {
        e,
        a,
        b,
        omega: edge.information,
    }
}

/// e = (r̂ − r, normalise(φ̂ − φ)) with ĥ and its Jacobians from
/// [`RangeBearingModel::predict`]. `None` when the point is within 1 mm of the pose, where
/// the bearing is undefined.
pub fn range_bearing(edge: &RangeBearingEdge, x: &Pose2, l: &Point2) -> Option<Linearized> {
    let p = RangeBearingModel::default().predict(x, l).ok()?;
    let e = Vector2::new(p.z.x - edge.range, normalize_angle(p.z.y - edge.bearing));
    Some(Linearized::Point {
        e,
        a: p.h_pose,
        b: p.h_landmark,
        omega: edge.information,
    })
}

/// Linearises `edge` at the estimates `x` (indexed like the graph's nodes).
pub fn linearize(edge: &Edge, x: &[NodeValue]) -> Option<Linearized> {
    match edge {
        Edge::Between(e) => Some(between(e, &pose(&x[e.from]), &pose(&x[e.to]))),
        Edge::PointXy(e) => Some(point_xy(e, &pose(&x[e.pose]), &point(&x[e.point]))),
        Edge::RangeBearing(e) => range_bearing(e, &pose(&x[e.pose]), &point(&x[e.point])),
    }
}

/// x ⊞ δ for one node: additive with the heading normalised (g2o's `VertexSE2::oplusImpl`).
pub fn retract(v: &NodeValue, d: &[f64]) -> NodeValue {
    match *v {
        NodeValue::Pose(p) => NodeValue::Pose(Pose2::new(p.x + d[0], p.y + d[1], p.theta + d[2])),
        NodeValue::Point(p) => NodeValue::Point(Point2::new(p.x + d[0], p.y + d[1])),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::{BetweenEdge, PointXyEdge, RangeBearingEdge};
    use rand::{Rng, SeedableRng};

    /// Central differences of e(x ⊞ hδ) for each coordinate of both nodes, against the
    /// analytic Jacobians, at random configurations (including headings near ±π, where the
    /// normalisation must not break the derivative).
    fn check(edge: &Edge, x: &[NodeValue]) {
        let lin = linearize(edge, x).unwrap();
        let (ia, ib) = edge.nodes();
        let (e0, ja, jb): (Vec<f64>, nalgebra::DMatrix<f64>, nalgebra::DMatrix<f64>) = match lin {
            Linearized::Between { e, a, b, .. } => (
                e.as_slice().to_vec(),
                nalgebra::DMatrix::from_column_slice(3, 3, a.as_slice()),
                nalgebra::DMatrix::from_column_slice(3, 3, b.as_slice()),
            ),
            Linearized::Point { e, a, b, .. } => (
                e.as_slice().to_vec(),
                nalgebra::DMatrix::from_column_slice(2, 3, a.as_slice()),
                nalgebra::DMatrix::from_column_slice(2, 2, b.as_slice()),
            ),
        };
        let err = |xs: &[NodeValue]| -> Vec<f64> {
            match linearize(edge, xs).unwrap() {
                Linearized::Between { e, .. } => e.as_slice().to_vec(),
                Linearized::Point { e, .. } => e.as_slice().to_vec(),
            }
        };
        let h = 1e-6;
        for (node, jac) in [(ia, &ja), (ib, &jb)] {
            for k in 0..x[node].dim() {
                let mut d = [0.0; 3];
                d[k] = h;
                let mut xp = x.to_vec();
                xp[node] = retract(&x[node], &d);
                d[k] = -h;
                let mut xm = x.to_vec();
                xm[node] = retract(&x[node], &d);
                let (ep, em) = (err(&xp), err(&xm));
                for r in 0..e0.len() {
                    let mut diff = ep[r] - em[r];
                    if r == 2 || matches!(edge, Edge::RangeBearing(_)) && r == 1 {
                        diff = normalize_angle(diff);
                    }
                    let fd = diff / (2.0 * h);
                    assert!(
                        (fd - jac[(r, k)]).abs() < 1e-6,
                        "{edge:?} node {node} row {r} col {k}: fd {fd} vs {}",
                        jac[(r, k)]
                    );
                }
            }
        }
    }

    #[test]
    fn jacobians_match_finite_differences() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let pi = std::f64::consts::PI;
        for trial in 0..200 {
            let mut th = || {
                if trial % 10 == 0 {
                    pi - 1e-3 * rng.random::<f64>()
                } else {
                    rng.random_range(-pi..pi)
                }
            };
            let (t1, t2, t3) = (th(), th(), th());
            let mut c = || rng.random_range(-5.0..5.0);
            let xi = Pose2::new(c(), c(), t1);
            let xj = Pose2::new(c(), c(), t2);
            let l = Point2::new(c(), c());
            let z = Pose2::new(c(), c(), t3);
            let info3 = Matrix3::identity();
            let info2 = Matrix2::identity();
            let poses = [NodeValue::Pose(xi), NodeValue::Pose(xj)];
            check(
                &Edge::Between(BetweenEdge {
                    from: 0,
                    to: 1,
                    measurement: z,
                    information: info3,
                }),
                &poses,
            );
            let pl = [NodeValue::Pose(xi), NodeValue::Point(l)];
            check(
                &Edge::PointXy(PointXyEdge {
                    pose: 0,
                    point: 1,
                    measurement: Point2::new(z.x, z.y),
                    information: info2,
                }),
                &pl,
            );
            if xi.distance(&Pose2::new(l.x, l.y, 0.0)) > 0.1 {
                check(
                    &Edge::RangeBearing(RangeBearingEdge {
                        pose: 0,
                        point: 1,
                        range: z.x.abs(),
                        bearing: z.theta,
                        information: info2,
                    }),
                    &pl,
                );
            }
        }
    }

    /// The error is g2o's: zero exactly when Xⱼ = Xᵢ Z, and equal to the vector of
    /// Z⁻¹ (Xᵢ⁻¹ Xⱼ) composed with slam-models' own SE(2) operations.
    #[test]
    fn between_error_is_the_relative_pose_difference() {
        let xi = Pose2::new(1.0, -2.0, 2.5);
        let z = Pose2::new(0.7, 0.3, 1.2);
        let edge = BetweenEdge {
            from: 0,
            to: 1,
            measurement: z,
            information: Matrix3::identity(),
        };
        let Linearized::Between { e, .. } = between(&edge, &xi, &xi.compose(&z)) else {
            unreachable!()
        };
        assert!(e.norm() < 1e-12);
        let xj = Pose2::new(-0.4, 3.0, -2.9);
        let want = z.inverse().compose(&xi.between(&xj)).to_vector();
        let Linearized::Between { e, .. } = between(&edge, &xi, &xj) else {
            unreachable!()
        };
        assert!((e - want).norm() < 1e-12, "{e} vs {want}");
    }
}
