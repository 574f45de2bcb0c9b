//! One landmark of one particle: a 2-D Gaussian (a 2×2 EKF) plus an existence counter.
//!
//! FastSLAM factors the posterior as p(x₁:t | z, u)·Πₙ p(mₙ | x₁:t, z, u) (Montemerlo et al.
//! 2002, eq. 4): given a particle's path the landmarks are independent, so each is a 2-D
//! Gaussian updated by its own EKF (PR table 13.1 lines 11–16).

use slam_models::measurement::RangeBearingModel;
use slam_models::{LandmarkId, Matrix2, Point2, Pose2, RangeBearing, Vector2};

/// A landmark estimate held in a particle's map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Landmark {
    /// Reported identity: the data's id under known association, otherwise the key the
    /// particle assigned.
    pub id: LandmarkId,
    /// Mean position μ (world frame, m).
    pub mean: Point2,
    /// Covariance Σ (m²), symmetric positive definite.
    pub cov: Matrix2,
    /// Existence counter: +1 per observation, −1 per step in which the landmark was
    /// expected in view but not seen; the landmark is removed when it falls below the
    /// configured threshold (Montemerlo et al. 2002, §4 "negative evidence").
    pub existence: i32,
    /// Number of observations used on this landmark, its initialisation included.
    pub observations: u32,
    /// Key of the spatial-index cell the landmark is filed under.
    pub(crate) cell: u32,
}

/// The prediction of one observation of one landmark from one pose.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Innovation {
    /// ν = z − ẑ, bearing normalised.
    pub nu: Vector2,
    /// H_m = ∂h/∂m.
    pub h_m: Matrix2,
    /// H_x = ∂h/∂(x, y, θ).
    pub h_x: slam_models::Matrix2x3,
    /// S = H_m Σ H_mᵀ + Q: innovation covariance with the pose held fixed.
    pub s: Matrix2,
}

impl Landmark {
    /// The landmark initialised from one observation at `pose` with the inverse measurement
    /// model: μ = h⁻¹(x, z), Σ = G_z Q G_zᵀ with G_z = ∂h⁻¹/∂z = H_m⁻¹
    /// (PR table 13.1 lines 8–9).
    pub(crate) fn from_observation(
        sensor: &RangeBearingModel,
        pose: &Pose2,
        z: &RangeBearing,
        id: LandmarkId,
        existence: i32,
    ) -> Self {
        let inv = sensor.inverse(pose, z);
        let cov = symmetrize(&(inv.g_z * sensor.noise_covariance() * inv.g_z.transpose()));
        Self {
            id,
            mean: inv.landmark,
            cov,
            existence,
            observations: 1,
            cell: 0,
        }
    }

    /// ẑ, ν and the Jacobians of observing this landmark from `pose`; `None` when the
    /// landmark is within the sensor's minimum range of `pose` (bearing undefined).
    pub(crate) fn innovation(
        &self,
        sensor: &RangeBearingModel,
        pose: &Pose2,
        z: &Vector2,
    ) -> Option<Innovation> {
        let pred = sensor.predict(pose, &self.mean).ok()?;
        let nu = RangeBearingModel::innovation(z, &pred.z);
        let h_m = pred.h_landmark;
        let s = symmetrize(&(h_m * self.cov * h_m.transpose() + sensor.noise_covariance()));
        Some(Innovation {
            nu,
            h_m,
            h_x: pred.h_pose,
            s,
        })
    }

    /// The 2×2 EKF update with a computed innovation (PR table 13.1 lines 12–15):
    /// K = Σ H_mᵀ S⁻¹, μ ← μ + K ν, Σ ← (I − K H_m) Σ (I − K H_m)ᵀ + K Q Kᵀ (Joseph form,
    /// which keeps Σ symmetric positive definite). Returns false (and changes nothing) when
    /// S cannot be inverted.
    pub(crate) fn ekf_update(&mut self, sensor: &RangeBearingModel, inn: &Innovation) -> bool {
        let Some(s_inv) = inn.s.try_inverse() else {
            return false;
        };
        let k = self.cov * inn.h_m.transpose() * s_inv;
        let mean = self.mean + k * inn.nu;
        let a = Matrix2::identity() - k * inn.h_m;
        let cov = symmetrize(
            &(a * self.cov * a.transpose() + k * sensor.noise_covariance() * k.transpose()),
        );
        if !(mean.x.is_finite() && mean.y.is_finite() && cov.iter().all(|v| v.is_finite())) {
            return false;
        }
        self.mean = mean;
        self.cov = cov;
        true
    }
}

/// (A + Aᵀ)/2.
#[inline]
pub(crate) fn symmetrize<const D: usize>(
    a: &nalgebra::SMatrix<f64, D, D>,
) -> nalgebra::SMatrix<f64, D, D> {
    (a + a.transpose()) * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::gaussian::mahalanobis_squared;

    #[test]
    fn initial_covariance_is_the_propagated_noise() {
        // Monte-Carlo check of Σ = G_z Q G_zᵀ: inverse-map noisy measurements and compare
        // the sample covariance with the formula.
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let sensor = RangeBearingModel::new(0.05, 0.01);
        let pose = Pose2::new(1.0, -2.0, 0.7);
        let z = RangeBearing {
            range: 6.0,
            bearing: 0.4,
            id: None,
        };
        let l = Landmark::from_observation(&sensor, &pose, &z, LandmarkId(0), 1);
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(1);
        let (nr, nb) = (
            Normal::new(0.0, 0.05).unwrap(),
            Normal::new(0.0, 0.01).unwrap(),
        );
        let n = 100_000;
        let pts: Vec<Point2> = (0..n)
            .map(|_| {
                let zz = RangeBearing {
                    range: z.range + nr.sample(&mut rng),
                    bearing: z.bearing + nb.sample(&mut rng),
                    id: None,
                };
                sensor.inverse(&pose, &zz).landmark
            })
            .collect();
        let mean = pts.iter().fold(Vector2::zeros(), |a, p| a + p.coords) / n as f64;
        let mut c = Matrix2::zeros();
        for p in &pts {
            let d = p.coords - mean;
            c += d * d.transpose();
        }
        c /= (n - 1) as f64;
        assert!((mean - l.mean.coords).norm() < 0.002);
        // Linearisation + sampling error: a few percent.
        assert!((c - l.cov).norm() / l.cov.norm() < 0.03, "{c} vs {}", l.cov);
    }

    #[test]
    fn update_shrinks_covariance_and_moves_towards_the_measurement() {
        let sensor = RangeBearingModel::new(0.1, 0.02);
        let pose = Pose2::new(0.0, 0.0, 0.0);
        let mut l = Landmark {
            id: LandmarkId(1),
            mean: Point2::new(5.0, 0.0),
            cov: Matrix2::identity() * 0.25,
            existence: 1,
            observations: 1,
            cell: 0,
        };
        let z = Vector2::new(5.3, 0.05);
        let inn = l.innovation(&sensor, &pose, &z).unwrap();
        let before = l;
        assert!(l.ekf_update(&sensor, &inn));
        assert!(l.cov.determinant() < before.cov.determinant());
        // The posterior mean predicts the measurement better than the prior did.
        let after = l.innovation(&sensor, &pose, &z).unwrap();
        let q = sensor.noise_covariance();
        assert!(
            mahalanobis_squared(&after.nu, &q).unwrap() < mahalanobis_squared(&inn.nu, &q).unwrap()
        );
        // Joseph form equals the simple form (I − KH)Σ for the optimal gain.
        let k = before.cov * inn.h_m.transpose() * inn.s.try_inverse().unwrap();
        let simple = (Matrix2::identity() - k * inn.h_m) * before.cov;
        assert!((simple - l.cov).norm() < 1e-12);
        assert!(l.cov.cholesky().is_some());
    }
}
