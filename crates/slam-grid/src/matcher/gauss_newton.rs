//! Gauss-Newton matching on the bilinearly interpolated likelihood field (Hector SLAM).

use super::{check_input, mean_interpolated, transform_points, MatchResult};
use crate::error::{ensure_config, GridError};
use crate::grid::OccupancyGrid;
use crate::scan::RangeData;
use serde::{Deserialize, Serialize};
use slam_models::{Matrix3, Pose2, Vector3};

/// Gauss-Newton minimisation of Σᵢ (1 − M(Sᵢ(ξ)))² over ξ = (x, y, θ), where M is the
/// likelihood field interpolated between cell centres (bilinearly as in Hector SLAM, or
/// bicubically, the default: see [`Interpolation`]) and Sᵢ(ξ) = R(θ)·pᵢ + t
/// (Kohlbrecher et al., "A flexible and scalable SLAM system with full 3D motion
/// estimation", SSRR 2011, eq. 7–13):
///
/// ```text
/// H = Σ Jᵢᵀ Jᵢ,   Jᵢ = ∇M(Sᵢ) · ∂Sᵢ/∂ξ,   ∂Sᵢ/∂ξ = [1 0 −s·px − c·py; 0 1 c·px − s·py],
/// Δξ = H⁻¹ Σ Jᵢᵀ (1 − M(Sᵢ))
/// ```
///
/// Each step is accepted only if it lowers the cost (otherwise halved, up to 6 times). The
/// covariance is σ̂²·H⁻¹ with σ̂² = cost/(n − 3). Converges from within about σ + one cell of
/// the optimum; start it from a correlative or hill-climbing result.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct GaussNewtonMatcher {
    /// Maximum Gauss-Newton iterations. Default 20.
    pub max_iterations: u32,
    /// Stop when a step moves less than this, metres (rotation scaled by 1 m). Default 1e-5.
    pub tolerance: f64,
    /// Largest accepted total displacement from the initial pose, metres; beyond it the
    /// match is reported as [`GridError::Degenerate`]. Default 0.5 m.
    pub max_displacement: f64,
    /// Fewer end points than this is an error. Default 10.
    pub min_points: usize,
    /// How the field is interpolated between cell centres. Default bicubic.
    pub interpolation: Interpolation,
    /// σ of M = exp(−D/(2σ²)) for the bicubic interpolant, metres; 0 (the default) uses
    /// the grid's [`crate::LikelihoodParams::sigma`]. A narrower σ than the field's sharpens
    /// the optimum on clean simulated maps but made scan-matching odometry on the real
    /// Intel log worse (docs/results/defaults.md).
    pub sigma: f64,
}

/// Interpolation of the likelihood field between cell centres.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Interpolation {
    /// Bilinear over 2×2 cells (Hector SLAM, Kohlbrecher et al. 2011 eq. 5–6). Its maxima
    /// lie on cell centres, so a wall's estimated position snaps to one.
    Bilinear,
    /// Catmull-Rom bicubic over 4×4 cells: C¹, with maxima between cell centres.
    #[default]
    Bicubic,
}

impl Interpolation {
    /// Field value and world-frame gradient at `p` (`sigma` > 0 for the bicubic one).
    #[inline]
    pub(crate) fn eval(
        self,
        grid: &OccupancyGrid,
        p: &slam_models::Point2,
        sigma: f64,
    ) -> (f64, [f64; 2]) {
        match self {
            Interpolation::Bilinear => grid.likelihood_interpolated(p),
            Interpolation::Bicubic => grid.likelihood_bicubic_sigma(p, sigma),
        }
    }
}

impl Default for GaussNewtonMatcher {
    fn default() -> Self {
        Self {
            max_iterations: 20,
            tolerance: 1e-5,
            max_displacement: 0.5,
            min_points: 10,
            interpolation: Interpolation::Bicubic,
            sigma: 0.0,
        }
    }
}

/// Cost Σ (1 − M)², Hessian approximation H = JᵀJ and gradient b = Jᵀr at `pose`.
fn normal_equations(
    interp: Interpolation,
    sigma: f64,
    grid: &OccupancyGrid,
    scan: &RangeData,
    pose: &Pose2,
) -> (f64, Matrix3, Vector3) {
    let (s, c) = pose.theta.sin_cos();
    let mut h = Matrix3::zeros();
    let mut b = Vector3::zeros();
    let mut cost = 0.0;
    for (p, w) in scan.points.iter().zip(transform_points(&scan.points, pose)) {
        let (m, g) = interp.eval(grid, &w, sigma);
        let r = 1.0 - m;
        let dth = g[0] * (-s * p.x - c * p.y) + g[1] * (c * p.x - s * p.y);
        let j = Vector3::new(g[0], g[1], dth);
        h += j * j.transpose();
        b += j * r;
        cost += r * r;
    }
    (cost, h, b)
}

fn cost_at(
    interp: Interpolation,
    sigma: f64,
    grid: &OccupancyGrid,
    scan: &RangeData,
    pose: &Pose2,
) -> f64 {
    transform_points(&scan.points, pose)
        .map(|w| {
            let r = 1.0 - interp.eval(grid, &w, sigma).0;
            r * r
        })
        .sum()
}

impl GaussNewtonMatcher {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), GridError> {
        ensure_config(self.tolerance > 0.0, "tolerance", self.tolerance, "> 0")?;
        ensure_config(
            self.max_displacement > 0.0,
            "max_displacement",
            self.max_displacement,
            "> 0 m",
        )?;
        ensure_config(
            self.sigma >= 0.0,
            "sigma",
            self.sigma,
            ">= 0 m (0: the grid's)",
        )
    }

    /// Refines `initial`; see the type documentation.
    pub fn match_prepared(
        &self,
        grid: &OccupancyGrid,
        scan: &RangeData,
        initial: &Pose2,
    ) -> Result<MatchResult, GridError> {
        self.validate()?;
        check_input(grid, scan, initial, self.min_points, self.max_displacement)?;
        let sigma = if self.sigma > 0.0 {
            self.sigma
        } else {
            grid.likelihood_params().sigma
        };
        let mut pose = *initial;
        let (mut cost, mut h, mut b) =
            normal_equations(self.interpolation, sigma, grid, scan, &pose);
        for _ in 0..self.max_iterations {
            let Some(chol) = nalgebra::Cholesky::new(h) else {
                return Err(GridError::Degenerate(
                    "Gauss-Newton Hessian is singular (end points far from every obstacle?)",
                ));
            };
            // r = 1 − M and J = ∇M·∂S/∂ξ = −∂r/∂ξ, so the Gauss-Newton step is +H⁻¹Jᵀr.
            let delta = chol.solve(&b);
            let mut step = 1.0;
            let mut accepted = None;
            for _ in 0..7 {
                let trial = Pose2::new(
                    pose.x + step * delta[0],
                    pose.y + step * delta[1],
                    pose.theta + step * delta[2],
                );
                let c = cost_at(self.interpolation, sigma, grid, scan, &trial);
                if c < cost {
                    accepted = Some((trial, c));
                    break;
                }
                step *= 0.5;
            }
            let Some((trial, _)) = accepted else { break };
            let moved = (step * delta[0]).hypot(step * delta[1]) + (step * delta[2]).abs();
            pose = trial;
            (cost, h, b) = normal_equations(self.interpolation, sigma, grid, scan, &pose);
            if moved < self.tolerance {
                break;
            }
        }
        if pose.distance(initial) > self.max_displacement {
            return Err(GridError::Degenerate(
                "Gauss-Newton moved farther than max_displacement",
            ));
        }
        let n = scan.points.len() as f64;
        let sigma2 = (cost / (n - 3.0).max(1.0)).max(1e-12);
        let covariance = h
            .try_inverse()
            .map(|hi| (hi + hi.transpose()) * (0.5 * sigma2))
            .filter(|c| c.iter().all(|v| v.is_finite()) && c[(0, 0)] > 0.0 && c[(2, 2)] > 0.0)
            .ok_or(GridError::Degenerate("Gauss-Newton Hessian is singular"))?;
        Ok(MatchResult {
            pose,
            score: mean_interpolated(grid, scan, &pose),
            covariance,
        })
    }
}

super::scan_matcher_by_inherent_method!(GaussNewtonMatcher);
