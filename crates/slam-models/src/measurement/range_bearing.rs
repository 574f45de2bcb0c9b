//! The range-bearing landmark model.
//!
//! For a robot at (x, y, θ) and a landmark at m = (mx, my), with δ = (mx − x, my − y) and
//! q = δᵀδ (PR table 10.1 lines 12–16, eq. 6.40):
//!
//! ```text
//! h(x, m) = ( √q , atan2(δy, δx) − θ )
//!
//! ∂h/∂(x,y,θ) = [ −δx/√q  −δy/√q   0 ]        ∂h/∂m = [  δx/√q  δy/√q ]
//!               [  δy/q   −δx/q   −1 ]                [ −δy/q   δx/q  ]
//! ```
//!
//! The inverse model places a landmark from a measurement z = (r, φ):
//! m = (x + r·cos(θ + φ), y + r·sin(θ + φ)), with
//!
//! ```text
//! ∂m/∂(x,y,θ) = [ 1 0 −r·sin(θ+φ) ]     ∂m/∂(r,φ) = [ cos(θ+φ)  −r·sin(θ+φ) ]
//!               [ 0 1  r·cos(θ+φ) ]                 [ sin(θ+φ)   r·cos(θ+φ) ]
//! ```
//!
//! These two Jacobians give a new landmark's covariance *and* its cross-covariance with the
//! pose and every other landmark (Σmm = Gx·Σxx·Gxᵀ + Gz·Q·Gzᵀ, Σm· = Gx·Σx·).

use crate::angle::normalize_angle;
use crate::data::RangeBearing;
use crate::detmath;
use crate::error::{ensure_finite, ModelError};
use crate::{Matrix2, Matrix2x3, Point2, Pose2, Vector2};
use serde::{Deserialize, Serialize};

/// Range-bearing sensor noise: independent Gaussian errors on range and bearing.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct RangeBearingModel {
    /// Standard deviation of the range, metres.
    pub sigma_range: f64,
    /// Standard deviation of the bearing, radians.
    pub sigma_bearing: f64,
    /// Landmarks closer than this (metres) are degenerate: bearing is undefined.
    pub min_range: f64,
}

impl Default for RangeBearingModel {
    /// σr = 0.1 m, σφ = 0.05 rad (≈ 2.9°), minimum range 1 mm.
    fn default() -> Self {
        Self {
            sigma_range: 0.1,
            sigma_bearing: 0.05,
            min_range: 1e-3,
        }
    }
}

/// h(x, m) with its two Jacobians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PredictedRangeBearing {
    /// Predicted measurement ẑ = (range in m, bearing in rad, in (−π, π\]).
    pub z: Vector2,
    /// ∂h/∂(x, y, θ), 2×3.
    pub h_pose: Matrix2x3,
    /// ∂h/∂(mx, my), 2×2.
    pub h_landmark: Matrix2,
}

/// The inverse model m = h⁻¹(x, z) with its two Jacobians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseRangeBearing {
    /// Landmark position in the world frame.
    pub landmark: Point2,
    /// ∂m/∂(x, y, θ), 2×3.
    pub g_pose: Matrix2x3,
    /// ∂m/∂(r, φ), 2×2.
    pub g_z: Matrix2,
}

/// Smallest σr (metres) and σφ (radians): a micrometre, a microradian, finer than any
/// range-bearing sensor, so that the information 1/σ² stays below 1e12. `sigma-bearing =
/// 1e-300` gave an infinite information and a FastSLAM 2.0 trajectory a thousand
/// kilometres long, reported as an error about its picture.
pub const MIN_SIGMA: f64 = 1e-6;
/// Largest σr, metres: a kilometre, beyond every landmark sensor's reach, so a range
/// carries some information. `sigma-range = 1e300` squared to an infinite noise and the
/// run ended on an error about a non-finite landmark in its output's staging file.
/// (σφ is bounded by π: a bearing spread beyond half a turn says nothing.)
pub const MAX_SIGMA_RANGE: f64 = 1e3;

impl RangeBearingModel {
    /// σr in [[`MIN_SIGMA`], [`MAX_SIGMA_RANGE`]] m, σφ in [[`MIN_SIGMA`], π] rad,
    /// `min_range` finite and ≥ 0; the error names the field (`sensor.sigma_range`, …).
    pub fn validate(&self) -> Result<(), crate::ModelError> {
        for (name, v, ok, expected) in [
            (
                "sensor.sigma_range",
                self.sigma_range,
                (MIN_SIGMA..=MAX_SIGMA_RANGE).contains(&self.sigma_range),
                "in [1e-6, 1000] m",
            ),
            (
                "sensor.sigma_bearing",
                self.sigma_bearing,
                (MIN_SIGMA..=std::f64::consts::PI).contains(&self.sigma_bearing),
                "in [1e-6, π] rad",
            ),
            (
                "sensor.min_range",
                self.min_range,
                self.min_range >= 0.0,
                "finite and >= 0",
            ),
        ] {
            if !(ok && v.is_finite()) {
                return Err(crate::ModelError::OutOfRange {
                    name,
                    value: v,
                    expected,
                });
            }
        }
        Ok(())
    }

    /// A model with the given standard deviations (metres, radians).
    pub fn new(sigma_range: f64, sigma_bearing: f64) -> Self {
        Self {
            sigma_range,
            sigma_bearing,
            ..Self::default()
        }
    }

    /// Q = diag(σr², σφ²).
    pub fn noise_covariance(&self) -> Matrix2 {
        Matrix2::new(
            self.sigma_range * self.sigma_range,
            0.0,
            0.0,
            self.sigma_bearing * self.sigma_bearing,
        )
    }

    /// ẑ = h(x, m) and its Jacobians. Errors when the landmark is within `min_range` of the
    /// robot (the bearing and the Jacobians are undefined there) or inputs are not finite.
    pub fn predict(
        &self,
        pose: &Pose2,
        landmark: &Point2,
    ) -> Result<PredictedRangeBearing, ModelError> {
        let dx = landmark.x - pose.x;
        let dy = landmark.y - pose.y;
        let q = dx * dx + dy * dy;
        ensure_finite("landmark-robot offset", q)?;
        ensure_finite("pose theta", pose.theta)?;
        let r = q.sqrt();
        if r < self.min_range {
            return Err(ModelError::DegenerateGeometry {
                range: r,
                min_range: self.min_range,
            });
        }
        let z = Vector2::new(r, normalize_angle(detmath::atan2(dy, dx) - pose.theta));
        let h_pose = Matrix2x3::new(-dx / r, -dy / r, 0.0, dy / q, -dx / q, -1.0);
        let h_landmark = Matrix2::new(dx / r, dy / r, -dy / q, dx / q);
        Ok(PredictedRangeBearing {
            z,
            h_pose,
            h_landmark,
        })
    }

    /// m = h⁻¹(x, z) and its Jacobians w.r.t. the pose and the measurement.
    pub fn inverse(&self, pose: &Pose2, z: &RangeBearing) -> InverseRangeBearing {
        let a = pose.theta + z.bearing;
        let (s, c) = detmath::sin_cos(a);
        let r = z.range;
        InverseRangeBearing {
            landmark: Point2::new(pose.x + r * c, pose.y + r * s),
            g_pose: Matrix2x3::new(1.0, 0.0, -r * s, 0.0, 1.0, r * c),
            g_z: Matrix2::new(c, -r * s, s, r * c),
        }
    }

    /// Innovation ν = z − ẑ with the bearing component normalised to (−π, π].
    #[inline]
    pub fn innovation(z: &Vector2, z_pred: &Vector2) -> Vector2 {
        Vector2::new(z[0] - z_pred[0], normalize_angle(z[1] - z_pred[1]))
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

    fn h(pose: &Pose2, m: &Point2) -> Vector2 {
        RangeBearingModel::default().predict(pose, m).unwrap().z
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]
        #[test]
        fn jacobians_match_finite_differences(p in pose_strategy(), r in 0.2..30.0f64, b in -PI..PI) {
            // Landmarks placed by range and bearing so that bearings near ±π are covered.
            let m = Point2::new(p.x + r * (p.theta + b).cos(), p.y + r * (p.theta + b).sin());
            let pred = RangeBearingModel::default().predict(&p, &m).unwrap();
            let eps = 1e-6;
            for k in 0..3 {
                let (mut a, mut c) = (p.to_vector(), p.to_vector());
                a[k] += eps;
                c[k] -= eps;
                let d = RangeBearingModel::innovation(&h(&Pose2::from_vector(&a), &m), &h(&Pose2::from_vector(&c), &m)) / (2.0 * eps);
                prop_assert!((pred.h_pose.column(k) - d).abs().max() < 1e-5);
            }
            for k in 0..2 {
                let (mut a, mut c) = (m, m);
                a[k] += eps;
                c[k] -= eps;
                let d = RangeBearingModel::innovation(&h(&p, &a), &h(&p, &c)) / (2.0 * eps);
                prop_assert!((pred.h_landmark.column(k) - d).abs().max() < 1e-5);
            }
        }

        #[test]
        fn inverse_jacobians_match_finite_differences(p in pose_strategy(), r in 0.0..30.0f64, b in -3.5..3.5f64) {
            let model = RangeBearingModel::default();
            let z = RangeBearing { range: r, bearing: b, id: None };
            let inv = model.inverse(&p, &z);
            let eps = 1e-6;
            for k in 0..3 {
                let (mut a, mut c) = (p.to_vector(), p.to_vector());
                a[k] += eps;
                c[k] -= eps;
                let d = (model.inverse(&Pose2::from_vector(&a), &z).landmark - model.inverse(&Pose2::from_vector(&c), &z).landmark) / (2.0 * eps);
                prop_assert!((inv.g_pose.column(k) - d).abs().max() < 1e-5);
            }
            for k in 0..2 {
                let (mut za, mut zc) = (z, z);
                if k == 0 { za.range += eps; zc.range -= eps; } else { za.bearing += eps; zc.bearing -= eps; }
                let d = (model.inverse(&p, &za).landmark - model.inverse(&p, &zc).landmark) / (2.0 * eps);
                prop_assert!((inv.g_z.column(k) - d).abs().max() < 1e-5);
            }
        }

        #[test]
        fn inverse_round_trips(p in pose_strategy(), r in 0.01..30.0f64, b in -PI..PI) {
            let model = RangeBearingModel::default();
            let m = model.inverse(&p, &RangeBearing { range: r, bearing: b, id: None }).landmark;
            let z = model.predict(&p, &m).unwrap().z;
            prop_assert!((z[0] - r).abs() < 1e-9);
            prop_assert!(normalize_angle(z[1] - b).abs() < 1e-9);
        }
    }

    #[test]
    fn sigmas_outside_their_range_are_refused_by_name() {
        for (sr, sb, key) in [
            (1e300, 0.05, "sensor.sigma_range"),
            (1e-300, 0.05, "sensor.sigma_range"),
            (1001.0, 0.05, "sensor.sigma_range"),
            (0.1, 1e300, "sensor.sigma_bearing"),
            (0.1, 1e-300, "sensor.sigma_bearing"),
            (0.1, 3.2, "sensor.sigma_bearing"),
        ] {
            match RangeBearingModel::new(sr, sb).validate() {
                Err(crate::ModelError::OutOfRange { name, .. }) => assert_eq!(name, key),
                other => panic!("{sr}, {sb}: {other:?}"),
            }
        }
        for (sr, sb) in [(MIN_SIGMA, MIN_SIGMA), (0.1, 0.05), (MAX_SIGMA_RANGE, PI)] {
            RangeBearingModel::new(sr, sb).validate().unwrap();
        }
    }

    #[test]
    fn degenerate_geometry_is_an_error() {
        let p = Pose2::new(1.0, 2.0, 0.3);
        let err = RangeBearingModel::default()
            .predict(&p, &Point2::new(1.0, 2.0))
            .unwrap_err();
        assert!(matches!(err, ModelError::DegenerateGeometry { .. }));
        assert!(RangeBearingModel::default()
            .predict(&p, &Point2::new(f64::NAN, 2.0))
            .is_err());
    }

    #[test]
    fn innovation_wraps_bearing() {
        let nu = RangeBearingModel::innovation(
            &Vector2::new(1.0, PI - 0.01),
            &Vector2::new(1.0, -PI + 0.01),
        );
        assert!((nu[1] + 0.02).abs() < 1e-12);
    }
}
