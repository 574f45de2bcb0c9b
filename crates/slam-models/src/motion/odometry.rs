//! The odometry motion model, Probabilistic Robotics §5.4.
//!
//! Between two odometry poses x̄ = (x̄, ȳ, θ̄) and x̄' the motion is summarised as a
//! rotation, a translation and a second rotation (PR table 5.5 lines 2–4):
//!
//! ```text
//! δrot1  = atan2(ȳ' − ȳ, x̄' − x̄) − θ̄
//! δtrans = √((x̄' − x̄)² + (ȳ' − ȳ)²)
//! δrot2  = θ̄' − θ̄ − δrot1
//! ```
//!
//! and applied to the state (PR table 5.6 lines 5–7):
//!
//! ```text
//! x' = x + δtrans·cos(θ + δrot1),  y' = y + δtrans·sin(θ + δrot1),  θ' = θ + δrot1 + δrot2
//! ```
//!
//! Noise (PR table 5.6, variances): σ²rot1 = α1·δrot1² + α2·δtrans²,
//! σ²trans = α3·δtrans² + α4·(δrot1² + δrot2²), σ²rot2 = α1·δrot2² + α2·δtrans²;
//! the three are independent, so M = diag(σ²rot1, σ²trans, σ²rot2) and R = V·M·Vᵀ.

use super::MotionModel;
use crate::angle::normalize_angle;
use crate::data::OdometryControl;
use crate::detmath;
use crate::sampling;
use crate::{Matrix3, Pose2};
use rand::Rng;
use serde::{Deserialize, Serialize};

/// Odometry motion model with noise parameters α1..α4 (PR table 5.6), dimensionless.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct OdometryModel {
    /// α1: rotation noise from rotation; α2: rotation noise from translation;
    /// α3: translation noise from translation; α4: translation noise from rotation.
    pub alpha: [f64; 4],
    /// Translations shorter than this (metres) count as a pure rotation: δrot1 = 0 and
    /// δrot2 = the whole heading change, so no atan2 is taken of odometry noise.
    pub min_translation: f64,
}

impl Default for OdometryModel {
    /// α = (0.01, 0.0005, 0.01, 0.0005) (≈ 10 % of the rotation and the translation as one
    /// standard deviation), `min_translation` = 1 mm.
    fn default() -> Self {
        Self {
            alpha: [0.01, 0.0005, 0.01, 0.0005],
            min_translation: 1e-3,
        }
    }
}

impl OdometryModel {
    /// A model with the given α1..α4 and the default pure-rotation threshold.
    pub fn new(alpha: [f64; 4]) -> Self {
        Self {
            alpha,
            ..Self::default()
        }
    }

    /// The control (δrot1, δtrans, δrot2) between two odometry readings (PR table 5.5,
    /// lines 2–4), with two robustness rules:
    ///
    /// * a translation below `min_translation` is a pure rotation (δrot1 = 0);
    /// * a backward motion (|δrot1| > π/2) is expressed with a negative δtrans and the
    ///   rotations reduced by π, so a reversing robot is not modelled as two half-turns.
    ///
    /// Applying the result with [`MotionModel::predict`] to `from` gives `to` exactly.
    pub fn control_from_poses(&self, from: &Pose2, to: &Pose2) -> OdometryControl {
        let dx = to.x - from.x;
        let dy = to.y - from.y;
        let dtheta = normalize_angle(to.theta - from.theta);
        let trans = detmath::hypot(dx, dy);
        if trans < self.min_translation {
            return OdometryControl {
                rot1: 0.0,
                trans: 0.0,
                rot2: dtheta,
            };
        }
        let mut rot1 = normalize_angle(detmath::atan2(dy, dx) - from.theta);
        let mut trans = trans;
        if rot1.abs() > std::f64::consts::FRAC_PI_2 {
            rot1 = normalize_angle(rot1 + std::f64::consts::PI);
            trans = -trans;
        }
        OdometryControl {
            rot1,
            trans,
            rot2: normalize_angle(dtheta - rot1),
        }
    }

    /// V = ∂g/∂(δrot1, δtrans, δrot2) (3×3).
    pub fn jacobian_control(&self, pose: &Pose2, u: &OdometryControl) -> Matrix3 {
        let (s, c) = detmath::sin_cos(pose.theta + u.rot1);
        Matrix3::new(
            -u.trans * s,
            c,
            0.0, //
            u.trans * c,
            s,
            0.0, //
            1.0,
            0.0,
            1.0,
        )
    }

    /// M = diag(σ²rot1, σ²trans, σ²rot2) from PR table 5.6.
    pub fn control_noise(&self, u: &OdometryControl) -> Matrix3 {
        let a = &self.alpha;
        let (r1, t, r2) = (normalize_angle(u.rot1), u.trans, normalize_angle(u.rot2));
        Matrix3::from_diagonal(&crate::Vector3::new(
            a[0] * r1 * r1 + a[1] * t * t,
            a[2] * t * t + a[3] * (r1 * r1 + r2 * r2),
            a[0] * r2 * r2 + a[1] * t * t,
        ))
    }
}

impl MotionModel for OdometryModel {
    type Control = OdometryControl;

    fn predict(&self, pose: &Pose2, u: &OdometryControl) -> Pose2 {
        let (s, c) = detmath::sin_cos(pose.theta + u.rot1);
        Pose2::new(
            pose.x + u.trans * c,
            pose.y + u.trans * s,
            pose.theta + u.rot1 + u.rot2,
        )
    }

    fn jacobian_state(&self, pose: &Pose2, u: &OdometryControl) -> Matrix3 {
        let (s, c) = detmath::sin_cos(pose.theta + u.rot1);
        Matrix3::new(1.0, 0.0, -u.trans * s, 0.0, 1.0, u.trans * c, 0.0, 0.0, 1.0)
    }

    fn noise_covariance(&self, pose: &Pose2, u: &OdometryControl) -> Matrix3 {
        let v = self.jacobian_control(pose, u);
        v * self.control_noise(u) * v.transpose()
    }

    /// PR table 5.6: perturb the three components of the control, then apply it.
    fn sample<R: Rng + ?Sized>(&self, pose: &Pose2, u: &OdometryControl, rng: &mut R) -> Pose2 {
        let m = self.control_noise(u);
        let noisy = OdometryControl {
            rot1: u.rot1 + sampling::normal(m[(0, 0)], rng),
            trans: u.trans + sampling::normal(m[(1, 1)], rng),
            rot2: u.rot2 + sampling::normal(m[(2, 2)], rng),
        };
        self.predict(pose, &noisy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::PI;

    fn pose_strategy() -> impl Strategy<Value = Pose2> {
        let theta = prop_oneof![-PI..PI, (PI - 1e-3)..PI, -PI..(-PI + 1e-3)];
        (-20.0..20.0f64, -20.0..20.0f64, theta).prop_map(|(x, y, t)| Pose2::new(x, y, t))
    }

    /// `min-translation` is validated (it was not: `inf` took every step as a turn in place
    /// and a run stood still with exit code 0; NaN and negative values were taken too).
    #[test]
    fn min_translation_outside_its_range_is_refused_by_name() {
        for bad in [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            -1e-9,
            1.5,
            1e300,
        ] {
            let mut m = crate::motion::MotionModels::default();
            m.odometry.min_translation = bad;
            match m.validate() {
                Err(crate::ModelError::OutOfRange { name, value, .. }) => {
                    assert_eq!(name, "motion.odometry.min_translation");
                    assert_eq!(value.to_bits(), bad.to_bits());
                }
                other => panic!("{bad}: {other:?}"),
            }
        }
        for good in [0.0, 1e-3, crate::motion::MAX_MIN_TRANSLATION] {
            let mut m = crate::motion::MotionModels::default();
            m.odometry.min_translation = good;
            m.validate().unwrap();
        }
    }

    fn control_strategy() -> impl Strategy<Value = OdometryControl> {
        (-PI..PI, prop_oneof![-2.0..2.0f64, Just(0.0)], -PI..PI)
            .prop_map(|(rot1, trans, rot2)| OdometryControl { rot1, trans, rot2 })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]
        #[test]
        fn jacobians_match_finite_differences(p in pose_strategy(), u in control_strategy()) {
            let m = OdometryModel::default();
            let h = 1e-6;
            let g = m.jacobian_state(&p, &u);
            let v = m.jacobian_control(&p, &u);
            for k in 0..3 {
                let (mut a, mut b) = (p.to_vector(), p.to_vector());
                a[k] += h;
                b[k] -= h;
                let (fa, fb) = (m.predict(&Pose2::from_vector(&a), &u), m.predict(&Pose2::from_vector(&b), &u));
                let col = [(fa.x - fb.x) / (2.0 * h), (fa.y - fb.y) / (2.0 * h), normalize_angle(fa.theta - fb.theta) / (2.0 * h)];
                for r in 0..3 { prop_assert!((g[(r, k)] - col[r]).abs() < 1e-6); }
                let (mut ua, mut ub) = ([u.rot1, u.trans, u.rot2], [u.rot1, u.trans, u.rot2]);
                ua[k] += h;
                ub[k] -= h;
                let mk = |c: [f64; 3]| OdometryControl { rot1: c[0], trans: c[1], rot2: c[2] };
                let (fa, fb) = (m.predict(&p, &mk(ua)), m.predict(&p, &mk(ub)));
                let col = [(fa.x - fb.x) / (2.0 * h), (fa.y - fb.y) / (2.0 * h), normalize_angle(fa.theta - fb.theta) / (2.0 * h)];
                for r in 0..3 { prop_assert!((v[(r, k)] - col[r]).abs() < 1e-6); }
            }
        }

        #[test]
        fn control_from_poses_round_trips(a in pose_strategy(), b in pose_strategy()) {
            let m = OdometryModel::default();
            let u = m.control_from_poses(&a, &b);
            let tol = if a.distance(&b) < m.min_translation { m.min_translation } else { 1e-9 };
            prop_assert!(m.predict(&a, &u).approx_eq(&b, tol));
            prop_assert!(u.rot1.abs() <= PI / 2.0 + 1e-12);
        }
    }

    #[test]
    fn pure_rotation_has_no_spurious_first_rotation() {
        let m = OdometryModel::default();
        let a = Pose2::new(1.0, 1.0, 0.2);
        // 1e-5 m of translation noise in a direction at right angles to the heading.
        let b = Pose2::new(1.0, 1.0 + 1e-5, 1.2);
        let u = m.control_from_poses(&a, &b);
        assert_eq!(u.rot1, 0.0);
        assert_eq!(u.trans, 0.0);
        assert!((u.rot2 - 1.0).abs() < 1e-12);
    }

    #[test]
    fn reversing_uses_negative_translation() {
        let m = OdometryModel::default();
        let a = Pose2::new(0.0, 0.0, 0.0);
        let b = Pose2::new(-1.0, 0.0, 0.0);
        let u = m.control_from_poses(&a, &b);
        assert!(u.rot1.abs() < 1e-12 && (u.trans + 1.0).abs() < 1e-12 && u.rot2.abs() < 1e-12);
    }

    #[test]
    fn sampler_moments_match_linearised_model() {
        use rand::SeedableRng;
        let m = OdometryModel::new([0.002, 0.0005, 0.002, 0.0005]);
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
        for u in [
            OdometryControl {
                rot1: 0.3,
                trans: 1.0,
                rot2: -0.2,
            },
            OdometryControl {
                rot1: 0.0,
                trans: 0.0,
                rot2: 1.2,
            }, // pure rotation
            OdometryControl {
                rot1: 0.1,
                trans: -0.5,
                rot2: 0.1,
            }, // reversing
        ] {
            let p = Pose2::new(-2.0, 4.0, -PI + 0.02);
            super::super::sampler_check::check(
                100_000,
                m.predict(&p, &u),
                m.noise_covariance(&p, &u),
                || m.sample(&p, &u, &mut rng),
            );
        }
    }
}
