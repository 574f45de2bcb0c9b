//! The velocity motion model, Probabilistic Robotics §5.3.
//!
//! With control u = (v, ω) held for Δt and φ = ω·Δt, the robot moves on a circular arc
//! (PR eq. 5.9, table 5.3 line 7–9):
//!
//! ```text
//! x' = x − (v/ω)·sin θ + (v/ω)·sin(θ + φ)
//! y' = y + (v/ω)·cos θ − (v/ω)·cos(θ + φ)
//! θ' = θ + φ (+ γ̂·Δt in the sampler)
//! ```
//!
//! We write the same motion as
//!
//! ```text
//! Δx = v·Δt·(cos θ·s(φ) − sin θ·c(φ)),   Δy = v·Δt·(sin θ·s(φ) + cos θ·c(φ))
//! s(φ) = sin φ / φ,   c(φ) = (1 − cos φ) / φ
//! ```
//!
//! which is algebraically identical for φ ≠ 0, and whose functions s and c are evaluated by
//! their Taylor series near φ = 0. The straight-line limit (Δx = v·Δt·cos θ, …) is thus reached
//! continuously, with continuous Jacobians, and nothing ever divides by ω.
//!
//! Noise (PR table 5.3): v̂ = v + ε(α1·v² + α2·ω²), ω̂ = ω + ε(α3·v² + α4·ω²), and a final
//! rotation γ̂ = ε(α5·v² + α6·ω²), where ε(b²) is zero-mean Gaussian noise with variance b².
//! Linearised (PR table 10.1, line 6): R = V·M·Vᵀ with M = diag(α1v²+α2ω², α3v²+α4ω²);
//! we add the γ̂ term as R₃₃ += (α5v²+α6ω²)·Δt², which table 10.1 omits.

use super::MotionModel;
use crate::data::VelocityControl;
use crate::detmath;
use crate::sampling;
use crate::{Matrix3, Matrix3x2, Pose2};
use rand::Rng;
use serde::{Deserialize, Serialize};

/// Below this |φ| = |ω·Δt| the series expansions of s and c are used (their truncation error
/// there is below 1e-17).
const SERIES_LIMIT: f64 = 1e-3;

/// s(φ) = sin φ / φ, continuous at 0.
#[inline]
fn s(phi: f64) -> f64 {
    if phi.abs() < SERIES_LIMIT {
        let p2 = phi * phi;
        1.0 - p2 / 6.0 + p2 * p2 / 120.0
    } else {
        detmath::sin(phi) / phi
    }
}

/// c(φ) = (1 − cos φ) / φ, continuous at 0.
#[inline]
fn c(phi: f64) -> f64 {
    if phi.abs() < SERIES_LIMIT {
        let p2 = phi * phi;
        phi * (0.5 - p2 / 24.0 + p2 * p2 / 720.0)
    } else {
        (1.0 - detmath::cos(phi)) / phi
    }
}

/// s'(φ) = (φ·cos φ − sin φ) / φ².
#[inline]
fn ds(phi: f64) -> f64 {
    if phi.abs() < SERIES_LIMIT {
        let p2 = phi * phi;
        phi * (-1.0 / 3.0 + p2 / 30.0)
    } else {
        (phi * detmath::cos(phi) - detmath::sin(phi)) / (phi * phi)
    }
}

/// c'(φ) = (φ·sin φ − (1 − cos φ)) / φ².
#[inline]
fn dc(phi: f64) -> f64 {
    if phi.abs() < SERIES_LIMIT {
        let p2 = phi * phi;
        0.5 - p2 / 8.0 + p2 * p2 / 144.0
    } else {
        (phi * detmath::sin(phi) - (1.0 - detmath::cos(phi))) / (phi * phi)
    }
}

/// Velocity motion model with noise parameters α1..α6 (PR table 5.3), dimensionless
/// (variances scale with v² [m²/s²] and ω² [rad²/s²]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct VelocityModel {
    /// α1..α6 as in PR table 5.3: (α1, α2) → v, (α3, α4) → ω, (α5, α6) → final rotation γ.
    pub alpha: [f64; 6],
}

impl Default for VelocityModel {
    /// α = (0.01, 0.001, 0.001, 0.01, 0.0001, 0.001): a few percent of v and ω.
    fn default() -> Self {
        Self {
            alpha: [0.01, 0.001, 0.001, 0.01, 0.0001, 0.001],
        }
    }
}

impl VelocityModel {
    /// A model with the given α1..α6.
    pub fn new(alpha: [f64; 6]) -> Self {
        Self { alpha }
    }

    /// The pose increment (Δx, Δy, Δθ) in the world frame for heading θ and control u.
    #[inline]
    fn increment(theta: f64, v: f64, omega: f64, dt: f64) -> (f64, f64, f64) {
        let phi = omega * dt;
        let (st, ct) = detmath::sin_cos(theta);
        let (sp, cp) = (s(phi), c(phi));
        let d = v * dt;
        (d * (ct * sp - st * cp), d * (st * sp + ct * cp), phi)
    }

    /// V = ∂g/∂(v, ω) (3×2), PR table 10.1 line 4, in the series-safe form.
    pub fn jacobian_control(&self, pose: &Pose2, u: &VelocityControl) -> Matrix3x2 {
        let dt = u.dt;
        let phi = u.omega * dt;
        let (st, ct) = detmath::sin_cos(pose.theta);
        let (sp, cp, dsp, dcp) = (s(phi), c(phi), ds(phi), dc(phi));
        // ∂Δx/∂v, ∂Δy/∂v
        let dxv = dt * (ct * sp - st * cp);
        let dyv = dt * (st * sp + ct * cp);
        // ∂Δx/∂ω = v·Δt·Δt·(cos θ·s' − sin θ·c'), likewise Δy.
        let k = u.v * dt * dt;
        let dxw = k * (ct * dsp - st * dcp);
        let dyw = k * (st * dsp + ct * dcp);
        Matrix3x2::new(dxv, dxw, dyv, dyw, 0.0, dt)
    }

    /// M = diag(α1v²+α2ω², α3v²+α4ω²): the control noise covariance (PR table 10.1 line 5).
    pub fn control_noise(&self, u: &VelocityControl) -> nalgebra::Matrix2<f64> {
        let (v2, w2) = (u.v * u.v, u.omega * u.omega);
        let a = &self.alpha;
        nalgebra::Matrix2::new(a[0] * v2 + a[1] * w2, 0.0, 0.0, a[2] * v2 + a[3] * w2)
    }
}

impl MotionModel for VelocityModel {
    type Control = VelocityControl;

    fn predict(&self, pose: &Pose2, u: &VelocityControl) -> Pose2 {
        let (dx, dy, dth) = Self::increment(pose.theta, u.v, u.omega, u.dt);
        Pose2::new(pose.x + dx, pose.y + dy, pose.theta + dth)
    }

    /// G (PR table 10.1 line 3): identity plus ∂Δx/∂θ = −Δy, ∂Δy/∂θ = Δx.
    fn jacobian_state(&self, pose: &Pose2, u: &VelocityControl) -> Matrix3 {
        let (dx, dy, _) = Self::increment(pose.theta, u.v, u.omega, u.dt);
        Matrix3::new(1.0, 0.0, -dy, 0.0, 1.0, dx, 0.0, 0.0, 1.0)
    }

    fn noise_covariance(&self, pose: &Pose2, u: &VelocityControl) -> Matrix3 {
        let v = self.jacobian_control(pose, u);
        let m = self.control_noise(u);
        let mut r = v * m * v.transpose();
        let a = &self.alpha;
        r[(2, 2)] += (a[4] * u.v * u.v + a[5] * u.omega * u.omega) * u.dt * u.dt;
        r
    }

    /// PR table 5.3: perturb v and ω, move on the exact arc, add the final rotation γ̂·Δt.
    fn sample<R: Rng + ?Sized>(&self, pose: &Pose2, u: &VelocityControl, rng: &mut R) -> Pose2 {
        let (v2, w2) = (u.v * u.v, u.omega * u.omega);
        let a = &self.alpha;
        let v = u.v + sampling::normal(a[0] * v2 + a[1] * w2, rng);
        let w = u.omega + sampling::normal(a[2] * v2 + a[3] * w2, rng);
        let g = sampling::normal(a[4] * v2 + a[5] * w2, rng);
        let (dx, dy, dth) = Self::increment(pose.theta, v, w, u.dt);
        Pose2::new(pose.x + dx, pose.y + dy, pose.theta + dth + g * u.dt)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::normalize_angle;
    use proptest::prelude::*;
    use std::f64::consts::PI;

    /// The textbook arc formula (PR eq. 5.9), for |ω| not tiny.
    fn arc(p: &Pose2, u: &VelocityControl) -> Pose2 {
        let r = u.v / u.omega;
        Pose2::new(
            p.x - r * p.theta.sin() + r * (p.theta + u.omega * u.dt).sin(),
            p.y + r * p.theta.cos() - r * (p.theta + u.omega * u.dt).cos(),
            p.theta + u.omega * u.dt,
        )
    }

    fn fd_state(m: &VelocityModel, p: &Pose2, u: &VelocityControl) -> Matrix3 {
        let h = 1e-6;
        let mut g = Matrix3::zeros();
        for k in 0..3 {
            let mut a = p.to_vector();
            a[k] += h;
            let mut b = p.to_vector();
            b[k] -= h;
            let (fa, fb) = (
                m.predict(&Pose2::from_vector(&a), u),
                m.predict(&Pose2::from_vector(&b), u),
            );
            g[(0, k)] = (fa.x - fb.x) / (2.0 * h);
            g[(1, k)] = (fa.y - fb.y) / (2.0 * h);
            g[(2, k)] = normalize_angle(fa.theta - fb.theta) / (2.0 * h);
        }
        g
    }

    fn fd_control(m: &VelocityModel, p: &Pose2, u: &VelocityControl) -> Matrix3x2 {
        let h = 1e-6;
        let mut j = Matrix3x2::zeros();
        for k in 0..2 {
            let (mut a, mut b) = (*u, *u);
            if k == 0 {
                a.v += h;
                b.v -= h;
            } else {
                a.omega += h;
                b.omega -= h;
            }
            let (fa, fb) = (m.predict(p, &a), m.predict(p, &b));
            j[(0, k)] = (fa.x - fb.x) / (2.0 * h);
            j[(1, k)] = (fa.y - fb.y) / (2.0 * h);
            j[(2, k)] = normalize_angle(fa.theta - fb.theta) / (2.0 * h);
        }
        j
    }

    /// Headings anywhere, including right at ±π; ω from large down to exactly 0.
    fn state_and_control() -> impl Strategy<Value = (Pose2, VelocityControl)> {
        let theta = prop_oneof![-PI..PI, (PI - 1e-3)..PI, -PI..(-PI + 1e-3)];
        let omega = prop_oneof![-3.0..3.0f64, -1e-4..1e-4f64, Just(0.0), -2e-3..2e-3f64];
        (
            -20.0..20.0f64,
            -20.0..20.0f64,
            theta,
            -2.0..2.0f64,
            omega,
            0.01..1.0f64,
        )
            .prop_map(|(x, y, t, v, w, dt)| {
                (Pose2::new(x, y, t), VelocityControl { v, omega: w, dt })
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]
        #[test]
        fn jacobian_state_matches_finite_differences((p, u) in state_and_control()) {
            let m = VelocityModel::default();
            let g = m.jacobian_state(&p, &u);
            let n = fd_state(&m, &p, &u);
            prop_assert!((g - n).abs().max() < 1e-6, "G {g} vs {n}");
        }

        #[test]
        fn jacobian_control_matches_finite_differences((p, u) in state_and_control()) {
            let m = VelocityModel::default();
            let v = m.jacobian_control(&p, &u);
            let n = fd_control(&m, &p, &u);
            prop_assert!((v - n).abs().max() < 1e-6, "V {v} vs {n}");
        }

        #[test]
        fn agrees_with_textbook_arc((p, mut u) in state_and_control(), w in 0.01..3.0f64, neg: bool) {
            u.omega = if neg { -w } else { w };
            prop_assert!(VelocityModel::default().predict(&p, &u).approx_eq(&arc(&p, &u), 1e-9));
        }
    }

    #[test]
    fn straight_line_limit_is_continuous() {
        let m = VelocityModel::default();
        let p = Pose2::new(1.0, -2.0, 0.7);
        let straight = m.predict(
            &p,
            &VelocityControl {
                v: 1.5,
                omega: 0.0,
                dt: 2.0,
            },
        );
        let expect = Pose2::new(1.0 + 3.0 * 0.7f64.cos(), -2.0 + 3.0 * 0.7f64.sin(), 0.7);
        assert!(straight.approx_eq(&expect, 1e-12));
        // Approaching ω → 0 from both sides and across the series switch-over.
        for w in [
            1e-2, 2e-3, 1.0001e-3, 0.9999e-3, 1e-6, -1e-6, -0.9999e-3, -1.0001e-3,
        ] {
            let q = m.predict(
                &p,
                &VelocityControl {
                    v: 1.5,
                    omega: w / 2.0,
                    dt: 2.0,
                },
            );
            assert!(q.distance(&straight) <= 1.5 * w.abs() + 1e-12, "w = {w}");
        }
        let a = m.predict(
            &p,
            &VelocityControl {
                v: 1.5,
                omega: 1.0001e-3 / 2.0,
                dt: 2.0,
            },
        );
        let b = m.predict(
            &p,
            &VelocityControl {
                v: 1.5,
                omega: 0.9999e-3 / 2.0,
                dt: 2.0,
            },
        );
        assert!(a.distance(&b) < 1e-6);
    }

    #[test]
    fn sampler_moments_match_linearised_model() {
        use rand::SeedableRng;
        let m = VelocityModel::new([0.002, 0.0005, 0.0005, 0.002, 0.0001, 0.0002]);
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(42);
        // A curve, a straight line (ω = 0) and a turn on the spot (v = 0), heading near π.
        for u in [
            VelocityControl {
                v: 1.0,
                omega: 0.5,
                dt: 0.5,
            },
            VelocityControl {
                v: 2.0,
                omega: 0.0,
                dt: 0.3,
            },
            VelocityControl {
                v: 0.0,
                omega: -1.0,
                dt: 0.4,
            },
        ] {
            let p = Pose2::new(3.0, -1.0, PI - 0.05);
            super::super::sampler_check::check(
                100_000,
                m.predict(&p, &u),
                m.noise_covariance(&p, &u),
                || m.sample(&p, &u, &mut rng),
            );
        }
    }
}
