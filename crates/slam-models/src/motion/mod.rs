//! Motion models: how a control moves the robot, with exact Jacobians, the control noise
//! mapped to state space, and samplers.
//!
//! * [`velocity`]: the velocity motion model, Probabilistic Robotics (PR) §5.3,
//!   tables 5.3 (sampler) and 10.1 (EKF linearisation).
//! * [`odometry`]: the odometry motion model, PR §5.4, tables 5.5/5.6.
//!
//! [`MotionModels`] bundles one of each and dispatches on [`Control`], which is what the
//! filters hold.

pub mod odometry;
pub mod velocity;

pub use odometry::OdometryModel;
pub use velocity::VelocityModel;

use crate::data::{Control, OdometryControl, VelocityControl};
use crate::{Matrix3, Pose2};
use rand::Rng;
use serde::{Deserialize, Serialize};

/// A probabilistic motion model p(x' | u, x) in the form the filters need.
pub trait MotionModel {
    /// The control type.
    type Control;

    /// The noise-free motion x' = g(u, x); θ' normalised to (−π, π].
    fn predict(&self, pose: &Pose2, u: &Self::Control) -> Pose2;

    /// G = ∂g/∂x (3×3), evaluated at (u, x).
    fn jacobian_state(&self, pose: &Pose2, u: &Self::Control) -> Matrix3;

    /// The control noise mapped to state space, R = V·M·Vᵀ (+ any noise that acts on the
    /// state directly), evaluated at (u, x). Units: m², m², rad².
    fn noise_covariance(&self, pose: &Pose2, u: &Self::Control) -> Matrix3;

    /// Draws x' ~ p(x' | u, x) by perturbing the control (PR tables 5.3 / 5.6).
    fn sample<R: Rng + ?Sized>(&self, pose: &Pose2, u: &Self::Control, rng: &mut R) -> Pose2;
}

/// Upper bound of [`OdometryModel::min_translation`], metres. A step shorter than the
/// threshold is taken as a turn in place (its translation dropped); odometry records are
/// centimetres to decimetres apart, so a threshold beyond a metre would drop the robot's
/// motion altogether (`inf` left every run standing still, with exit code 0).
pub const MAX_MIN_TRANSLATION: f64 = 1.0;

/// One velocity model and one odometry model; the filters hold this and call it with
/// whatever [`Control`] the data provides.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct MotionModels {
    /// Used for [`Control::Velocity`].
    pub velocity: VelocityModel,
    /// Used for [`Control::Odometry`].
    pub odometry: OdometryModel,
}

impl MotionModels {
    /// Every α finite and ≥ 0, and the odometry model's `min-translation` in
    /// [0, [`MAX_MIN_TRANSLATION`]] m; the error names the key (`motion.odometry.alpha`, …).
    pub fn validate(&self) -> Result<(), crate::ModelError> {
        let t = self.odometry.min_translation;
        if !(0.0..=MAX_MIN_TRANSLATION).contains(&t) {
            return Err(crate::ModelError::OutOfRange {
                name: "motion.odometry.min_translation",
                value: t,
                expected: "in [0, 1] m (a step shorter than this is taken as a turn in place)",
            });
        }
        let alphas = self
            .odometry
            .alpha
            .iter()
            .map(|&a| ("motion.odometry.alpha", a))
            .chain(
                self.velocity
                    .alpha
                    .iter()
                    .map(|&a| ("motion.velocity.alpha", a)),
            );
        for (name, a) in alphas {
            if !(a >= 0.0 && a.is_finite()) {
                return Err(crate::ModelError::OutOfRange {
                    name,
                    value: a,
                    expected: "finite and >= 0",
                });
            }
        }
        Ok(())
    }

    /// g(u, x) for either kind of control.
    pub fn predict(&self, pose: &Pose2, u: &Control) -> Pose2 {
        match u {
            Control::Velocity(c) => self.velocity.predict(pose, c),
            Control::Odometry(c) => self.odometry.predict(pose, c),
        }
    }

    /// G = ∂g/∂x for either kind of control.
    pub fn jacobian_state(&self, pose: &Pose2, u: &Control) -> Matrix3 {
        match u {
            Control::Velocity(c) => self.velocity.jacobian_state(pose, c),
            Control::Odometry(c) => self.odometry.jacobian_state(pose, c),
        }
    }

    /// R = V·M·Vᵀ for either kind of control.
    pub fn noise_covariance(&self, pose: &Pose2, u: &Control) -> Matrix3 {
        match u {
            Control::Velocity(c) => self.velocity.noise_covariance(pose, c),
            Control::Odometry(c) => self.odometry.noise_covariance(pose, c),
        }
    }

    /// Samples x' ~ p(x' | u, x) for either kind of control.
    pub fn sample<R: Rng + ?Sized>(&self, pose: &Pose2, u: &Control, rng: &mut R) -> Pose2 {
        match u {
            Control::Velocity(c) => self.velocity.sample(pose, c, rng),
            Control::Odometry(c) => self.odometry.sample(pose, c, rng),
        }
    }
}

impl From<VelocityControl> for Control {
    fn from(u: VelocityControl) -> Self {
        Control::Velocity(u)
    }
}

impl From<OdometryControl> for Control {
    fn from(u: OdometryControl) -> Self {
        Control::Odometry(u)
    }
}

#[cfg(test)]
pub(crate) mod sampler_check {
    //! Shared statistical check of a sampler against its linearised model.
    use crate::{normalize_angle, Matrix3, Pose2, Vector3};

    /// Draws `n` samples and checks that their mean is within 5 standard errors of the
    /// noise-free prediction and that their covariance matches `r` within 5 standard errors
    /// of a sample covariance ((RᵢᵢRⱼⱼ + Rᵢⱼ²)/n)^½ plus a 3 % allowance for the model's
    /// nonlinearity.
    pub fn check(n: usize, mean_expected: Pose2, r: Matrix3, mut draw: impl FnMut() -> Pose2) {
        let mut d = Vec::with_capacity(n);
        for _ in 0..n {
            let p = draw();
            d.push(Vector3::new(
                p.x - mean_expected.x,
                p.y - mean_expected.y,
                normalize_angle(p.theta - mean_expected.theta),
            ));
        }
        let mean: Vector3 = d.iter().sum::<Vector3>() / n as f64;
        let mut cov = Matrix3::zeros();
        for v in &d {
            let c = v - mean;
            cov += c * c.transpose();
        }
        cov /= (n - 1) as f64;
        for i in 0..3 {
            let se = (r[(i, i)] / n as f64).sqrt();
            assert!(
                mean[i].abs() <= 5.0 * se + 1e-12,
                "mean[{i}] = {} (se {se})",
                mean[i]
            );
            for j in 0..3 {
                let se = ((r[(i, i)] * r[(j, j)] + r[(i, j)].powi(2)) / n as f64).sqrt();
                let tol = 5.0 * se + 0.03 * (r[(i, i)] * r[(j, j)]).sqrt();
                assert!(
                    (cov[(i, j)] - r[(i, j)]).abs() <= tol,
                    "cov[{i},{j}] = {} vs linearised {} (tol {tol})",
                    cov[(i, j)],
                    r[(i, j)]
                );
            }
        }
    }
}
