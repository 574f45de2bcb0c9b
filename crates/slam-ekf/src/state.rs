//! The EKF-SLAM state: mean μ = (x, y, θ, m₁ₓ, m₁ᵧ, …, mₙₓ, mₙᵧ) and its dense covariance Σ
//! (a `faer::Mat`, column-major), with the three operations of PR table 10.1:
//! prediction, landmark augmentation and the (batched) measurement update.
//!
//! Costs, with N = 3 + 2n the state dimension:
//!
//! * prediction touches only the pose rows and columns, O(N);
//! * adding a landmark fills two new rows/columns, O(N) (amortised growth: the buffer's
//!   capacity doubles, so no full reallocation per landmark);
//! * an update with m observations forms Σ·Hᵀ in O(N·m) from the sparsity of H (each
//!   row pair touches the pose and one landmark), then applies the covariance change as one
//!   symmetric rank-2m update in place, O(N²·m), reading and writing Σ once.

use crate::error::EkfError;
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::{Accum, Mat, Par};
use slam_models::association::{JointGaussian, Linearised};
use slam_models::measurement::InverseRangeBearing;
use slam_models::{normalize_angle, Matrix2, Matrix3, Point2, Pose2};

/// Index of landmark `j`'s x coordinate in the state vector.
#[inline]
pub(crate) fn lm_index(j: usize) -> usize {
    3 + 2 * j
}

/// Mean and covariance of the joint pose–landmark Gaussian.
#[derive(Debug, Clone)]
pub(crate) struct State {
    mean: Vec<f64>,
    cov: Mat<f64>,
    /// Reserved rows = columns of `cov`.
    capacity: usize,
    /// Scratch: Σ·Hᵀ (N × 2m), reused between updates.
    pht: Mat<f64>,
}

impl State {
    pub(crate) fn new(pose: Pose2, pose_cov: Matrix3) -> Self {
        let capacity = 3 + 2 * 16;
        let mut cov = Mat::<f64>::with_capacity(capacity, capacity);
        cov.resize_with(3, 3, |i, j| pose_cov[(i, j)]);
        Self {
            mean: vec![pose.x, pose.y, pose.theta],
            cov,
            capacity,
            pht: Mat::new(),
        }
    }

    /// State dimension N = 3 + 2n.
    #[inline]
    pub(crate) fn dim(&self) -> usize {
        self.mean.len()
    }

    #[inline]
    pub(crate) fn landmark_count(&self) -> usize {
        (self.dim() - 3) / 2
    }

    pub(crate) fn covariance(&self) -> faer::MatRef<'_, f64> {
        self.cov.as_ref()
    }

    pub(crate) fn mean(&self) -> &[f64] {
        &self.mean
    }

    #[inline]
    pub(crate) fn pose(&self) -> Pose2 {
        Pose2::new(self.mean[0], self.mean[1], self.mean[2])
    }

    #[inline]
    pub(crate) fn landmark(&self, j: usize) -> Point2 {
        let k = lm_index(j);
        Point2::new(self.mean[k], self.mean[k + 1])
    }

    pub(crate) fn pose_cov(&self) -> Matrix3 {
        Matrix3::from_fn(|r, c| self.cov[(r, c)])
    }

    pub(crate) fn landmark_cov(&self, j: usize) -> Matrix2 {
        let k = lm_index(j);
        Matrix2::from_fn(|r, c| self.cov[(k + r, k + c)])
    }

    /// Σ_{x, mⱼ} (3×2).
    pub(crate) fn pose_landmark_cov(&self, j: usize) -> nalgebra::Matrix3x2<f64> {
        let k = lm_index(j);
        nalgebra::Matrix3x2::from_fn(|r, c| self.cov[(r, k + c)])
    }

    /// Σ_{mᵢ, mⱼ} (2×2).
    pub(crate) fn landmark_landmark_cov(&self, i: usize, j: usize) -> Matrix2 {
        let (a, b) = (lm_index(i), lm_index(j));
        Matrix2::from_fn(|r, c| self.cov[(a + r, b + c)])
    }
}

/// Association reads the EKF state through the shared trait.
impl JointGaussian for State {
    fn pose(&self) -> Pose2 {
        State::pose(self)
    }
    fn landmark_count(&self) -> usize {
        State::landmark_count(self)
    }
    fn landmark(&self, j: usize) -> Point2 {
        State::landmark(self, j)
    }
    fn pose_cov(&self) -> Matrix3 {
        State::pose_cov(self)
    }
    fn pose_landmark_cov(&self, j: usize) -> nalgebra::Matrix3x2<f64> {
        State::pose_landmark_cov(self, j)
    }
    fn landmark_cov(&self, j: usize) -> Matrix2 {
        State::landmark_cov(self, j)
    }
    fn landmark_landmark_cov(&self, i: usize, j: usize) -> Matrix2 {
        State::landmark_landmark_cov(self, i, j)
    }
}

impl State {
    /// EKF prediction (PR table 10.1 lines 3–5) given the predicted pose g(u, μ), its
    /// Jacobian G and the process noise R: Σxx ← G·Σxx·Gᵀ + R, Σxm ← G·Σxm, Σmx = Σxmᵀ.
    /// Landmark rows and columns are not touched: O(N).
    pub(crate) fn predict(&mut self, new_pose: &Pose2, g: &Matrix3, r: &Matrix3) {
        let n = self.dim();
        self.mean[0] = new_pose.x;
        self.mean[1] = new_pose.y;
        self.mean[2] = normalize_angle(new_pose.theta);
        let pxx = self.pose_cov();
        let new_pxx = g * pxx * g.transpose() + r;
        let new_pxx = (new_pxx + new_pxx.transpose()) * 0.5;
        for r in 0..3 {
            for c in 0..3 {
                self.cov[(r, c)] = new_pxx[(r, c)];
            }
        }
        // Σxm (rows 0..3 of each landmark column) and its mirror Σmx (columns 0..3).
        for c in 3..n {
            let col = self.cov.col_as_slice_mut(c);
            let v = g * slam_models::Vector3::new(col[0], col[1], col[2]);
            col[0] = v[0];
            col[1] = v[1];
            col[2] = v[2];
            for (k, vk) in v.iter().enumerate() {
                self.cov[(c, k)] = *vk;
            }
        }
    }

    /// Appends a landmark initialised by the inverse measurement model m = h⁻¹(x, z)
    /// (PR §10.2.3 with the full Jacobians): with Gx = ∂m/∂x, Gz = ∂m/∂z,
    ///
    /// ```text
    /// Σmm = Gx·Σxx·Gxᵀ + Gz·Q·Gzᵀ,   Σm· = Gx·Σx·   (cross-covariance with the pose and
    ///                                               every landmark already in the map)
    /// ```
    ///
    /// Returns the new landmark's slot. O(N), amortised. The covariance grows by doubling,
    /// never beyond `max_dim` rows (3 + 2 × the landmark cap), and its memory is reserved
    /// fallibly: [`EkfError::OutOfMemory`] instead of an abort.
    pub(crate) fn add_landmark(
        &mut self,
        inv: &InverseRangeBearing,
        q: &Matrix2,
        max_dim: usize,
    ) -> Result<usize, EkfError> {
        let n = self.dim();
        let need = n + 2;
        if need > self.capacity {
            let capacity = need.max((2 * self.capacity).min(max_dim));
            self.cov
                .try_reserve(capacity, capacity)
                .map_err(|_| EkfError::OutOfMemory {
                    dim: capacity,
                    bytes: (capacity as u128).pow(2) * 8,
                })?;
            self.capacity = capacity;
        }
        self.cov.resize_with(need, need, |_, _| 0.0);
        let gx = &inv.g_pose;
        // Σm· = Gx·Σx· over columns 0..n, and its mirror.
        for c in 0..n {
            let col = self.cov.col_as_slice(c);
            let v = gx * slam_models::Vector3::new(col[0], col[1], col[2]);
            self.cov[(n, c)] = v[0];
            self.cov[(n + 1, c)] = v[1];
            self.cov[(c, n)] = v[0];
            self.cov[(c, n + 1)] = v[1];
        }
        let pxx = self.pose_cov();
        let pmm = gx * pxx * gx.transpose() + inv.g_z * q * inv.g_z.transpose();
        let pmm = (pmm + pmm.transpose()) * 0.5;
        for r in 0..2 {
            for c in 0..2 {
                self.cov[(n + r, n + c)] = pmm[(r, c)];
            }
        }
        self.mean.push(inv.landmark.x);
        self.mean.push(inv.landmark.y);
        Ok(self.landmark_count() - 1)
    }

    /// Batched EKF update with m linearised observations (PR table 10.1 lines 12–21, all
    /// observations at once). With the stacked H (2m × N, sparse), S = H·Σ·Hᵀ + Q = L·Lᵀ
    /// and W = Σ·Hᵀ·L⁻ᵀ:
    ///
    /// ```text
    /// μ ← μ + W·(L⁻¹ν),    Σ ← Σ − W·Wᵀ
    /// ```
    ///
    /// which is K·ν and Σ − K·S·Kᵀ for the optimal gain K = Σ·Hᵀ·S⁻¹, i.e. the Joseph form
    /// (I−KH)Σ(I−KH)ᵀ + KQKᵀ evaluated in its equivalent symmetric low-rank form: the
    /// change is a Gram product, so Σ stays symmetric and only loses the positive
    /// semi-definite W·Wᵀ. Returns the NIS νᵀS⁻¹ν.
    pub(crate) fn update(&mut self, obs: &[Linearised]) -> Result<f64, EkfError> {
        let m = obs.len();
        if m == 0 {
            return Ok(0.0);
        }
        let n = self.dim();
        let k = 2 * m;
        // Σ·Hᵀ column by column: O(N) per row of H.
        self.pht.resize_with(n, k, |_, _| 0.0);
        for (a, o) in obs.iter().enumerate() {
            let l = lm_index(o.landmark);
            for r in 0..2 {
                let h = [
                    o.h_pose[(r, 0)],
                    o.h_pose[(r, 1)],
                    o.h_pose[(r, 2)],
                    o.h_landmark[(r, 0)],
                    o.h_landmark[(r, 1)],
                ];
                let p0 = self.cov.col_as_slice(0);
                let p1 = self.cov.col_as_slice(1);
                let p2 = self.cov.col_as_slice(2);
                let p3 = self.cov.col_as_slice(l);
                let p4 = self.cov.col_as_slice(l + 1);
                let dst = self.pht.col_as_slice_mut(2 * a + r);
                for i in 0..n {
                    dst[i] =
                        h[0] * p0[i] + h[1] * p1[i] + h[2] * p2[i] + h[3] * p3[i] + h[4] * p4[i];
                }
            }
        }
        // S = H·(Σ·Hᵀ) + Q, again from the sparsity of H.
        let mut s = nalgebra::DMatrix::<f64>::zeros(k, k);
        for (b, ob) in obs.iter().enumerate() {
            let l = lm_index(ob.landmark);
            for col in 0..k {
                let w = self.pht.col_as_slice(col);
                for r in 0..2 {
                    s[(2 * b + r, col)] = ob.h_pose[(r, 0)] * w[0]
                        + ob.h_pose[(r, 1)] * w[1]
                        + ob.h_pose[(r, 2)] * w[2]
                        + ob.h_landmark[(r, 0)] * w[l]
                        + ob.h_landmark[(r, 1)] * w[l + 1];
                }
            }
            for r in 0..2 {
                for c in 0..2 {
                    s[(2 * b + r, 2 * b + c)] += ob.q[(r, c)];
                }
            }
        }
        let s = (&s + s.transpose()) * 0.5;
        let chol =
            nalgebra::Cholesky::new(s).ok_or(EkfError::InnovationNotPositiveDefinite { dim: k })?;
        let l_small = chol.l();
        let l_faer = Mat::<f64>::from_fn(k, k, |i, j| l_small[(i, j)]);
        // y = L⁻¹ν.
        let mut nu = nalgebra::DVector::<f64>::zeros(k);
        for (a, o) in obs.iter().enumerate() {
            nu[2 * a] = o.nu[0];
            nu[2 * a + 1] = o.nu[1];
        }
        let y = l_small
            .solve_lower_triangular(&nu)
            .ok_or(EkfError::InnovationNotPositiveDefinite { dim: k })?;
        let nis = y.norm_squared();
        // W = Σ·Hᵀ·L⁻ᵀ, i.e. Wᵀ = L⁻¹·(Σ·Hᵀ)ᵀ, solved in place.
        solve_lower_triangular_in_place(
            l_faer.as_ref(),
            self.pht.as_mut().transpose_mut(),
            Par::Seq,
        );
        // μ ← μ + W·y.
        for (col, &yc) in y.iter().enumerate() {
            let w = self.pht.col_as_slice(col);
            for (mi, wi) in self.mean.iter_mut().zip(w) {
                *mi += wi * yc;
            }
        }
        self.mean[2] = normalize_angle(self.mean[2]);
        // Σ ← Σ − W·Wᵀ: one rank-2m update, in place.
        matmul(
            self.cov.as_mut(),
            Accum::Add,
            self.pht.as_ref(),
            self.pht.as_ref().transpose(),
            -1.0,
            Par::Seq,
        );
        // The touched diagonal must stay positive.
        for i in (0..3).chain(obs.iter().flat_map(|o| {
            let l = lm_index(o.landmark);
            [l, l + 1]
        })) {
            let v = self.cov[(i, i)];
            // The pose block may be exactly zero (a filter updated before it ever moved).
            let ok = v.is_finite() && (v > 0.0 || (i < 3 && v == 0.0));
            if !ok {
                return Err(EkfError::CovarianceNotPositive { index: i, value: v });
            }
        }
        Ok(nis)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::measurement::RangeBearingModel;
    use slam_models::RangeBearing;
    use slam_models::Vector2;

    /// Dense reference: the textbook update with the full H and explicit inverse.
    fn dense_update(
        mean: &[f64],
        cov: &nalgebra::DMatrix<f64>,
        obs: &[Linearised],
    ) -> (nalgebra::DVector<f64>, nalgebra::DMatrix<f64>) {
        let n = mean.len();
        let k = 2 * obs.len();
        let mut h = nalgebra::DMatrix::<f64>::zeros(k, n);
        let mut q = nalgebra::DMatrix::<f64>::zeros(k, k);
        let mut nu = nalgebra::DVector::<f64>::zeros(k);
        for (a, o) in obs.iter().enumerate() {
            let l = lm_index(o.landmark);
            for r in 0..2 {
                for c in 0..3 {
                    h[(2 * a + r, c)] = o.h_pose[(r, c)];
                }
                for c in 0..2 {
                    h[(2 * a + r, l + c)] = o.h_landmark[(r, c)];
                    q[(2 * a + r, 2 * a + c)] = o.q[(r, c)];
                }
                nu[2 * a + r] = o.nu[r];
            }
        }
        let s = &h * cov * h.transpose() + q.clone();
        let kg = cov * h.transpose() * s.try_inverse().unwrap();
        let mu = nalgebra::DVector::from_column_slice(mean) + &kg * nu;
        // Joseph form.
        let ikh = nalgebra::DMatrix::<f64>::identity(n, n) - &kg * &h;
        let p = &ikh * cov * ikh.transpose() + &kg * q * kg.transpose();
        (mu, p)
    }

    fn to_dense(s: &State) -> nalgebra::DMatrix<f64> {
        nalgebra::DMatrix::from_fn(s.dim(), s.dim(), |i, j| s.cov[(i, j)])
    }

    fn some_state() -> (State, RangeBearingModel) {
        let sensor = RangeBearingModel::new(0.1, 0.05);
        let mut st = State::new(
            Pose2::new(0.3, -0.2, 0.4),
            Matrix3::from_diagonal(&slam_models::Vector3::new(0.02, 0.03, 0.01)),
        );
        // Landmarks added from different poses so cross-covariances are generic.
        for (i, (r, b)) in [(2.0, 0.3), (3.0, -1.0), (1.5, 2.5), (4.0, 0.9), (2.2, -2.0)]
            .iter()
            .enumerate()
        {
            let z = RangeBearing {
                range: *r,
                bearing: *b,
                id: None,
            };
            let inv = sensor.inverse(&st.pose(), &z);
            st.add_landmark(&inv, &sensor.noise_covariance(), usize::MAX)
                .unwrap();
            let p = st.pose();
            let g = Matrix3::new(1.0, 0.0, -0.1, 0.0, 1.0, 0.2, 0.0, 0.0, 1.0);
            let rr = Matrix3::from_diagonal(&slam_models::Vector3::new(0.01, 0.01, 0.002))
                * (i as f64 + 1.0);
            st.predict(&Pose2::new(p.x + 0.2, p.y + 0.1, p.theta + 0.1), &g, &rr);
        }
        (st, sensor)
    }

    #[test]
    fn batched_update_matches_dense_joseph_form() {
        let (mut st, sensor) = some_state();
        let pose = st.pose();
        let obs: Vec<Linearised> = [0usize, 2, 3]
            .iter()
            .map(|&j| {
                let pred = sensor.predict(&pose, &st.landmark(j)).unwrap();
                Linearised {
                    landmark: j,
                    nu: Vector2::new(0.05 * j as f64 - 0.04, 0.02),
                    h_pose: pred.h_pose,
                    h_landmark: pred.h_landmark,
                    q: sensor.noise_covariance(),
                }
            })
            .collect();
        let (mu, p) = dense_update(st.mean(), &to_dense(&st), &obs);
        st.update(&obs).unwrap();
        for i in 0..st.dim() {
            let expect = if i == 2 {
                normalize_angle(mu[i])
            } else {
                mu[i]
            };
            assert!((st.mean()[i] - expect).abs() < 1e-12, "mean {i}");
            for j in 0..st.dim() {
                assert!((st.cov[(i, j)] - p[(i, j)]).abs() < 1e-12, "cov ({i},{j})");
                assert_eq!(st.cov[(i, j)], st.cov[(j, i)], "exact symmetry ({i},{j})");
            }
        }
    }

    #[test]
    fn prediction_matches_dense_product() {
        let (mut st, _) = some_state();
        let before = to_dense(&st);
        let g = Matrix3::new(1.0, 0.0, -0.7, 0.0, 1.0, 0.4, 0.0, 0.0, 1.0);
        let r = Matrix3::from_diagonal(&slam_models::Vector3::new(0.01, 0.02, 0.003));
        st.predict(&Pose2::new(1.0, 2.0, 0.5), &g, &r);
        let n = st.dim();
        let mut fx = nalgebra::DMatrix::<f64>::identity(n, n);
        for i in 0..3 {
            for j in 0..3 {
                fx[(i, j)] = g[(i, j)];
            }
        }
        let mut rr = nalgebra::DMatrix::<f64>::zeros(n, n);
        for i in 0..3 {
            for j in 0..3 {
                rr[(i, j)] = r[(i, j)];
            }
        }
        let expect = &fx * before * fx.transpose() + rr;
        assert!((to_dense(&st) - expect).abs().max() < 1e-12);
    }

    #[test]
    fn augmentation_matches_full_jacobian_transform() {
        // Σ' = J·Σ·Jᵀ + Gz·Q·Gzᵀ with J = [I; Gx 0] (the full linearised augmentation).
        let (mut st, sensor) = some_state();
        let before = to_dense(&st);
        let n = st.dim();
        let z = RangeBearing {
            range: 2.7,
            bearing: -0.6,
            id: None,
        };
        let inv = sensor.inverse(&st.pose(), &z);
        let cap_before = st.capacity;
        st.add_landmark(&inv, &sensor.noise_covariance(), usize::MAX)
            .unwrap();
        let mut j = nalgebra::DMatrix::<f64>::zeros(n + 2, n);
        for i in 0..n {
            j[(i, i)] = 1.0;
        }
        for r in 0..2 {
            for c in 0..3 {
                j[(n + r, c)] = inv.g_pose[(r, c)];
            }
        }
        let mut gzq = nalgebra::DMatrix::<f64>::zeros(n + 2, n + 2);
        let b = inv.g_z * sensor.noise_covariance() * inv.g_z.transpose();
        for r in 0..2 {
            for c in 0..2 {
                gzq[(n + r, n + c)] = b[(r, c)];
            }
        }
        let expect = &j * before * j.transpose() + gzq;
        assert!((to_dense(&st) - expect).abs().max() < 1e-12);
        assert!(st.capacity >= cap_before);
    }

    #[test]
    fn capacity_grows_geometrically() {
        let sensor = RangeBearingModel::default();
        let mut st = State::new(Pose2::IDENTITY, Matrix3::identity() * 0.01);
        let mut growths = 0;
        let mut cap = st.capacity;
        for i in 0..1000 {
            let z = RangeBearing {
                range: 1.0 + (i % 7) as f64,
                bearing: 0.01 * i as f64,
                id: None,
            };
            st.add_landmark(
                &sensor.inverse(&st.pose(), &z),
                &sensor.noise_covariance(),
                usize::MAX,
            )
            .unwrap();
            if st.capacity != cap {
                growths += 1;
                cap = st.capacity;
            }
        }
        assert!(growths <= 8, "{growths} reallocations for 1000 landmarks");
        assert_eq!(st.landmark_count(), 1000);
    }
}
