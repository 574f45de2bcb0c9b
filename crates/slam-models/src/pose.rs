//! SE(2) poses: the rigid motions of the plane.

use crate::angle::normalize_angle;
use crate::detmath;
use crate::error::{ensure_finite, ModelError};
use crate::{Matrix3, Point2, Vector3};
use serde::{Deserialize, Serialize};

/// A pose in the plane: position (x, y) in metres and heading θ in radians,
/// counter-clockwise from the x axis of the parent frame, kept in (−π, π].
///
/// A pose `a` is also the rigid transform that maps coordinates in frame `a` into the
/// parent frame: `a.transform_point(p) = R(θ)·p + t`. With that reading
///
/// * `a.compose(&b)` (a ⊕ b) is the pose `b`, given in frame `a`, expressed in the parent frame;
/// * `a.between(&b)` (b ⊖ a = a⁻¹ ⊕ b) is `b` expressed in frame `a`, the relative motion
///   from `a` to `b`;
/// * `a.inverse()` is the parent frame's origin expressed in frame `a`.
///
/// ```
/// use slam_models::Pose2;
/// let a = Pose2::new(1.0, 2.0, 0.5);
/// let b = Pose2::new(-0.3, 0.7, 2.9);
/// let d = a.between(&b);
/// assert!(a.compose(&d).approx_eq(&b, 1e-12));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose2 {
    /// x position, metres.
    pub x: f64,
    /// y position, metres.
    pub y: f64,
    /// Heading, radians in (−π, π].
    pub theta: f64,
}

impl Pose2 {
    /// The identity pose (0, 0, 0).
    pub const IDENTITY: Pose2 = Pose2 {
        x: 0.0,
        y: 0.0,
        theta: 0.0,
    };

    /// A pose with the heading normalised to (−π, π]. No finiteness check: use
    /// [`Pose2::try_new`] at input boundaries.
    #[inline]
    pub fn new(x: f64, y: f64, theta: f64) -> Self {
        Self {
            x,
            y,
            theta: normalize_angle(theta),
        }
    }

    /// Like [`Pose2::new`] but rejects NaN and infinite components.
    pub fn try_new(x: f64, y: f64, theta: f64) -> Result<Self, ModelError> {
        ensure_finite("pose x", x)?;
        ensure_finite("pose y", y)?;
        ensure_finite("pose theta", theta)?;
        Ok(Self::new(x, y, theta))
    }

    /// From a vector (x, y, θ); θ is normalised.
    #[inline]
    pub fn from_vector(v: &Vector3) -> Self {
        Self::new(v[0], v[1], v[2])
    }

    /// As a vector (x, y, θ).
    #[inline]
    pub fn to_vector(&self) -> Vector3 {
        Vector3::new(self.x, self.y, self.theta)
    }

    /// The position as a point.
    #[inline]
    pub fn translation(&self) -> Point2 {
        Point2::new(self.x, self.y)
    }

    /// True when every component is finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.theta.is_finite()
    }

    /// Composition a ⊕ b: x = xa + cosθa·xb − sinθa·yb, y = ya + sinθa·xb + cosθa·yb,
    /// θ = θa + θb (normalised). (Smith, Self & Cheeseman 1990; PR §7.)
    #[inline]
    pub fn compose(&self, b: &Pose2) -> Pose2 {
        let (s, c) = detmath::sin_cos(self.theta);
        Pose2::new(
            self.x + c * b.x - s * b.y,
            self.y + s * b.x + c * b.y,
            self.theta + b.theta,
        )
    }

    /// Inverse a⁻¹, so that a ⊕ a⁻¹ = a⁻¹ ⊕ a = identity.
    #[inline]
    pub fn inverse(&self) -> Pose2 {
        let (s, c) = detmath::sin_cos(self.theta);
        Pose2::new(
            -c * self.x - s * self.y,
            s * self.x - c * self.y,
            -self.theta,
        )
    }

    /// Relative pose b ⊖ a = a⁻¹ ⊕ b: the pose `b` expressed in the frame of `self` (= a).
    #[inline]
    pub fn between(&self, b: &Pose2) -> Pose2 {
        let (s, c) = detmath::sin_cos(self.theta);
        let dx = b.x - self.x;
        let dy = b.y - self.y;
        Pose2::new(c * dx + s * dy, -s * dx + c * dy, b.theta - self.theta)
    }

    /// Maps a point from this pose's local frame into the parent frame: R(θ)·p + t.
    #[inline]
    pub fn transform_point(&self, p: &Point2) -> Point2 {
        let (s, c) = detmath::sin_cos(self.theta);
        Point2::new(self.x + c * p.x - s * p.y, self.y + s * p.x + c * p.y)
    }

    /// Maps a point from the parent frame into this pose's local frame: R(θ)ᵀ·(p − t).
    #[inline]
    pub fn inverse_transform_point(&self, p: &Point2) -> Point2 {
        let (s, c) = detmath::sin_cos(self.theta);
        let dx = p.x - self.x;
        let dy = p.y - self.y;
        Point2::new(c * dx + s * dy, -s * dx + c * dy)
    }

    /// Jacobians of a ⊕ b with respect to a and to b (3×3 each), the classic
    /// compounding Jacobians J⊕₁ and J⊕₂ (Smith, Self & Cheeseman 1990).
    pub fn compose_jacobians(&self, b: &Pose2) -> (Matrix3, Matrix3) {
        let (s, c) = detmath::sin_cos(self.theta);
        let ja = Matrix3::new(
            1.0,
            0.0,
            -s * b.x - c * b.y, //
            0.0,
            1.0,
            c * b.x - s * b.y, //
            0.0,
            0.0,
            1.0,
        );
        let jb = Matrix3::new(
            c, -s, 0.0, //
            s, c, 0.0, //
            0.0, 0.0, 1.0,
        );
        (ja, jb)
    }

    /// Component-wise closeness with the heading compared modulo 2π.
    pub fn approx_eq(&self, other: &Pose2, tol: f64) -> bool {
        (self.x - other.x).abs() <= tol
            && (self.y - other.y).abs() <= tol
            && normalize_angle(self.theta - other.theta).abs() <= tol
    }

    /// Euclidean distance between the positions of two poses, metres.
    #[inline]
    pub fn distance(&self, other: &Pose2) -> f64 {
        detmath::hypot(self.x - other.x, self.y - other.y)
    }
}

impl std::ops::Mul for Pose2 {
    type Output = Pose2;
    /// `a * b` is `a.compose(&b)`.
    fn mul(self, rhs: Pose2) -> Pose2 {
        self.compose(&rhs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::PI;

    fn pose() -> impl Strategy<Value = Pose2> {
        (-50.0..50.0f64, -50.0..50.0f64, -PI..PI).prop_map(|(x, y, t)| Pose2::new(x, y, t))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        #[test]
        fn associativity(a in pose(), b in pose(), c in pose()) {
            let l = a.compose(&b).compose(&c);
            let r = a.compose(&b.compose(&c));
            prop_assert!(l.approx_eq(&r, 1e-9));
        }

        #[test]
        fn inverse_is_two_sided(a in pose()) {
            prop_assert!(a.compose(&a.inverse()).approx_eq(&Pose2::IDENTITY, 1e-10));
            prop_assert!(a.inverse().compose(&a).approx_eq(&Pose2::IDENTITY, 1e-10));
            prop_assert!(a.inverse().inverse().approx_eq(&a, 1e-10));
        }

        #[test]
        fn between_round_trip(a in pose(), b in pose()) {
            let d = a.between(&b);
            prop_assert!(a.compose(&d).approx_eq(&b, 1e-9));
            prop_assert!(d.approx_eq(&a.inverse().compose(&b), 1e-9));
        }

        #[test]
        fn point_round_trip(a in pose(), px in -10.0..10.0f64, py in -10.0..10.0f64) {
            let p = Point2::new(px, py);
            let q = a.inverse_transform_point(&a.transform_point(&p));
            prop_assert!((q - p).norm() < 1e-9);
            // Transforming a point equals composing with a pose at that point.
            let viapose = a.compose(&Pose2::new(px, py, 0.0));
            let direct = a.transform_point(&p);
            prop_assert!((viapose.x - direct.x).abs() < 1e-9 && (viapose.y - direct.y).abs() < 1e-9);
        }

        #[test]
        fn compose_jacobians_match_finite_differences(a in pose(), b in pose()) {
            let (ja, jb) = a.compose_jacobians(&b);
            let h = 1e-6;
            for k in 0..3 {
                let mut ap = a.to_vector(); ap[k] += h;
                let mut am = a.to_vector(); am[k] -= h;
                let fp = Pose2::from_vector(&ap).compose(&b);
                let fm = Pose2::from_vector(&am).compose(&b);
                let col = [(fp.x - fm.x) / (2.0 * h), (fp.y - fm.y) / (2.0 * h),
                    normalize_angle(fp.theta - fm.theta) / (2.0 * h)];
                for r in 0..3 { prop_assert!((ja[(r, k)] - col[r]).abs() < 1e-5); }
                let mut bp = b.to_vector(); bp[k] += h;
                let mut bm = b.to_vector(); bm[k] -= h;
                let fp = a.compose(&Pose2::from_vector(&bp));
                let fm = a.compose(&Pose2::from_vector(&bm));
                let col = [(fp.x - fm.x) / (2.0 * h), (fp.y - fm.y) / (2.0 * h),
                    normalize_angle(fp.theta - fm.theta) / (2.0 * h)];
                for r in 0..3 { prop_assert!((jb[(r, k)] - col[r]).abs() < 1e-5); }
            }
        }
    }

    #[test]
    fn known_values() {
        // Hand-computed: a = (1, 0, 90°), b = (1, 0, 0) ⇒ a ⊕ b = (1, 1, 90°).
        let a = Pose2::new(1.0, 0.0, PI / 2.0);
        let c = a.compose(&Pose2::new(1.0, 0.0, 0.0));
        assert!(c.approx_eq(&Pose2::new(1.0, 1.0, PI / 2.0), 1e-12));
        // Heading wraps: 3 rad + 3 rad = 6 rad ≡ 6 − 2π.
        let w = Pose2::new(0.0, 0.0, 3.0).compose(&Pose2::new(0.0, 0.0, 3.0));
        assert!((w.theta - (6.0 - 2.0 * PI)).abs() < 1e-12);
        assert!(Pose2::try_new(f64::NAN, 0.0, 0.0).is_err());
    }
}
