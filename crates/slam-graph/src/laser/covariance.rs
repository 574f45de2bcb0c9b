//! The covariance of a scan match from a wide sampling of its tempered likelihood (Olson,
//! "Real-time correlative scan matching", ICRA 2009, §III-B, eq. 14–16).
//!
//! The Gauss-Newton covariance σ̂²H⁻¹ of the matcher is a local, quadratic picture of the
//! optimum and, with independent beams, orders of magnitude too confident; once floored it
//! is almost isotropic, so in a corridor, where the scan fixes the pose across the walls
//! but hardly along them, a scan-match edge outweighs the odometry in the direction the
//! scan knows nothing about. Sampling the response over a window of poses as wide as the
//! uncertainty it must represent keeps that shape: along the corridor the response is
//! flat and the sampled variance approaches the window's, across it the response is sharp
//! and the variance is the lattice's.
//!
//! Also the front end's use of it: a local match's covariance by the configured
//! [`MatchCovariance`] and the edge information from it (the `match-min-std` floor).

use super::{LaserGraphSlam, MatchCovariance};
use slam_grid::{CellIndex, OccupancyGrid, RangeData};
use slam_models::{Matrix3, Pose2};

/// Where and how the likelihood is sampled around a match (see [`response_covariance`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ResponseSampling {
    /// Half-width of the translation window, metres (the lattice step is one grid cell).
    pub linear_window: f64,
    /// Half-width of the rotation window, radians (the step moves the farthest end point
    /// by one cell).
    pub angular_window: f64,
    /// T in the weights exp(ℓ/T): 1 treats the beams as independent; larger values
    /// account for their correlation and for map errors (Olson 2009 §III-B's scaling).
    pub temperature: f64,
}

impl ResponseSampling {
    /// The sampling `match-covariance` configures: its own window for
    /// [`MatchCovariance::Response`], none for [`MatchCovariance::Matcher`].
    pub(crate) fn configured(c: MatchCovariance) -> Option<Self> {
        match c {
            MatchCovariance::Matcher => None,
            MatchCovariance::Response {
                linear_window,
                angular_window,
                temperature,
            } => Some(Self {
                linear_window,
                angular_window,
                temperature,
            }),
        }
    }
}

/// Most rotations sampled on each side of the mode.
const MAX_ROTATION_STEPS: i32 = 64;

/// The covariance of the pose of a match at `mode`, in the grid's frame (m², rad²):
///
/// ```text
/// wₖ ∝ exp(ℓ(xₖ)/T),   μ = Σ wₖ dₖ,   Σ = Σ wₖ dₖdₖᵀ − μμᵀ + diag(δ²/12)
/// ```
///
/// over the lattice xₖ = mode ⊕ dₖ, dₖ = (i·r, j·r, k·δθ), |i·r| ≤ `linear_window`,
/// |k·δθ| ≤ `angular_window` (r the cell edge, δθ = r / farthest end point's range), where
/// ℓ(x) = Σᵢ ln p(zᵢ | x, m) is the likelihood-field log-likelihood of the scan read at the
/// cell of each end point (PR table 6.3) and δ = (r, r, δθ) the lattice steps, whose
/// quantisation variance keeps Σ positive definite when the response is sharper than the
/// lattice (Olson 2009 eq. 14–16; GMapping's proposal fit, Grisetti et al. 2007 eq. 16–18,
/// uses the same moments on a 3×3×3 lattice).
///
/// `None` for a scan without end points.
pub(crate) fn response_covariance(
    grid: &OccupancyGrid,
    scan: &RangeData,
    mode: &Pose2,
    sampling: &ResponseSampling,
) -> Option<Matrix3> {
    let points = scan.points();
    if points.is_empty() {
        return None;
    }
    let res = grid.resolution();
    let r_max = scan.max_point_range().max(res);
    let dtheta = res / r_max;
    let l = (sampling.linear_window / res).round().max(0.0) as i32;
    let a = ((sampling.angular_window / dtheta).round() as i32).clamp(0, MAX_ROTATION_STEPS);
    let n = points.len();
    // End-point cells at every sampled rotation (translation = the mode's).
    let frame = grid.frame();
    let mut cells: Vec<CellIndex> = Vec::with_capacity((2 * a + 1) as usize * n);
    let (mut lo, mut hi) = (
        CellIndex::new(i32::MAX, i32::MAX),
        CellIndex::new(i32::MIN, i32::MIN),
    );
    for k in -a..=a {
        let (s, c) = (mode.theta + k as f64 * dtheta).sin_cos();
        for p in points {
            let w =
                slam_models::Point2::new(mode.x + c * p.x - s * p.y, mode.y + s * p.x + c * p.y);
            let cell = frame.world_to_cell(&w);
            lo = CellIndex::new(lo.x.min(cell.x), lo.y.min(cell.y));
            hi = CellIndex::new(hi.x.max(cell.x), hi.y.max(cell.y));
            cells.push(cell);
        }
    }
    // Per-cell log-likelihood over every cell a shifted end point reaches.
    let min = CellIndex::new(lo.x - l, lo.y - l);
    let w = (hi.x - lo.x + 2 * l + 1) as usize;
    let h = (hi.y - lo.y + 2 * l + 1) as usize;
    let params = grid.likelihood_params();
    // Cells at or beyond `max-distance` all hold the far value, in long runs: the last
    // logarithm is kept (the same function of the same value, so the same bits).
    let mut last: Option<(u32, f32)> = None;
    let ll: Vec<f32> = grid
        .field_window(min, w, h)
        .into_iter()
        .map(|s| match last {
            Some((bits, v)) if bits == s.to_bits() => v,
            _ => {
                let v = params.log_likelihood(s) as f32;
                last = Some((s.to_bits(), v));
                v
            }
        })
        .collect();
    // ℓ at every lattice pose, indexed [k][j][i].
    let side = (2 * l + 1) as usize;
    // Accumulated end point by end point (each pose's sum still adds the end points in
    // scan order, so the sums are the same as pose by pose), a window row at a time: the
    // reads are contiguous instead of one scattered cell per end point and pose.
    let mut scores = vec![0.0f64; (2 * a + 1) as usize * side * side];
    for (k, pose_scores) in scores.chunks_exact_mut(side * side).enumerate() {
        for c in &cells[k * n..(k + 1) * n] {
            let b = (c.y - l - min.y) as usize * w + (c.x - l - min.x) as usize;
            for (j, row) in pose_scores.chunks_exact_mut(side).enumerate() {
                let src = &ll[b + j * w..b + j * w + side];
                for (s, &v) in row.iter_mut().zip(src) {
                    *s += v as f64;
                }
            }
        }
    }
    let best = scores.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let t = sampling.temperature;
    let mut wsum = 0.0;
    let mut m1 = [0.0f64; 3];
    let mut m2 = Matrix3::zeros();
    let mut idx = 0;
    for k in -a..=a {
        for j in -l..=l {
            for i in -l..=l {
                let wk = ((scores[idx] - best) / t).exp();
                idx += 1;
                let d = [i as f64 * res, j as f64 * res, k as f64 * dtheta];
                wsum += wk;
                for (u, du) in d.iter().enumerate() {
                    m1[u] += wk * du;
                    for (v, dv) in d.iter().enumerate() {
                        m2[(u, v)] += wk * du * dv;
                    }
                }
            }
        }
    }
    let mut cov = Matrix3::zeros();
    for u in 0..3 {
        for v in 0..3 {
            cov[(u, v)] = m2[(u, v)] / wsum - m1[u] * m1[v] / (wsum * wsum);
        }
    }
    for (u, step) in [res, res, dtheta].into_iter().enumerate() {
        cov[(u, u)] += step * step / 12.0;
    }
    Some((cov + cov.transpose()) * 0.5)
}

impl super::LaserGraphSlam {
    /// [`fuse_degenerate`] for the local match `z` (information `information`) of the
    /// keyframe at record `b` against the odometry increment `odometry` since the keyframe
    /// at record `a`, with `degenerate-anisotropy`; `None` when that is 0 or the match is
    /// not degenerate.
    pub(super) fn degenerate_edge(
        &self,
        z: &Pose2,
        information: &Matrix3,
        odometry: &Pose2,
        (a, b): (usize, usize),
    ) -> Option<(Pose2, Matrix3)> {
        let min_anisotropy = self.config.degenerate_anisotropy;
        if min_anisotropy <= 0.0 {
            return None;
        }
        let covariance = self.odometry_chain_covariance(a, b);
        fuse_degenerate(z, information, odometry, &covariance, min_anisotropy)
    }
}

/// The x-y block's √(λ_max / λ_min) of a covariance or information matrix (σ_max / σ_min
/// either way) and the unit eigenvector of λ_min (of an information matrix: the direction
/// of σ_max, the weak one).
pub(super) fn xy_anisotropy(m: &Matrix3) -> (f64, [f64; 2]) {
    let (a, b, d) = (m[(0, 0)], m[(0, 1)], m[(1, 1)]);
    let mean = 0.5 * (a + d);
    let r = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    let (hi, lo) = (mean + r, (mean - r).max(f64::MIN_POSITIVE));
    // Eigenvector of the smaller eigenvalue `lo`: (b, lo − a), or (lo − d, b); the larger
    // of the two is the better conditioned (both vanish only for an isotropic block).
    let (u, v) = ((b, lo - a), (lo - d, b));
    let e = if u.0.hypot(u.1) >= v.0.hypot(v.1) {
        u
    } else {
        v
    };
    let n = e.0.hypot(e.1);
    let dir = if n > 0.0 {
        [e.0 / n, e.1 / n]
    } else {
        [1.0, 0.0]
    };
    ((hi / lo).sqrt(), dir)
}

/// A scan-matching edge that is degenerate along one direction takes the odometry along
/// it (after Zhang, Kaess and Singh, "On degeneracy of optimization-based state
/// estimation problems", ICRA 2016: in the directions the measurement does not
/// constrain, keep the prior). `z`, `information`: the match's relative pose and
/// information in the earlier keyframe's frame; `odometry`, `odometry_covariance`: the
/// odometry increment over the same records and its covariance in the same frame.
///
/// With ρ the information's translational σ_max / σ_min and w the unit direction of
/// σ_max: when ρ < `min_anisotropy` (a), `None` (the match stands). Otherwise, along w
/// only, the two are combined by their variances there, σ_m² = wᵀ Σ_m w (Σ_m = Ω⁻¹, its
/// x-y block) and σ_o² = wᵀ Σ_o w, the odometry's weighed by the ramp
/// f = min(1, (ρ − a) / (a / 2)) so that the result is continuous in ρ:
/// z' = z + w · f σ_m² / (f σ_m² + σ_o²) · wᵀ(o − z) (x-y only; the heading and the
/// position across w stay the match's), and Ω' = Ω + (f / σ_o²) w wᵀ on the x-y block.
pub(crate) fn fuse_degenerate(
    z: &Pose2,
    information: &Matrix3,
    odometry: &Pose2,
    odometry_covariance: &Matrix3,
    min_anisotropy: f64,
) -> Option<(Pose2, Matrix3)> {
    let (rho, [wx, wy]) = xy_anisotropy(information);
    if rho.is_nan() || rho < min_anisotropy {
        return None;
    }
    let f = ((rho - min_anisotropy) / (0.5 * min_anisotropy)).min(1.0);
    let sigma_m = information.try_inverse()?;
    let along = |c: &Matrix3| wx * wx * c[(0, 0)] + 2.0 * wx * wy * c[(0, 1)] + wy * wy * c[(1, 1)];
    let (var_m, var_o) = (along(&sigma_m), along(odometry_covariance));
    if var_m.is_nan() || var_o.is_nan() || var_m <= 0.0 || var_o <= 0.0 || f <= 0.0 {
        return None;
    }
    let gain = f * var_m / (f * var_m + var_o);
    let e = wx * (odometry.x - z.x) + wy * (odometry.y - z.y);
    let pose = Pose2::new(z.x + gain * e * wx, z.y + gain * e * wy, z.theta);
    let mut fused = *information;
    let k = f / var_o;
    fused[(0, 0)] += k * wx * wx;
    fused[(0, 1)] += k * wx * wy;
    fused[(1, 0)] += k * wx * wy;
    fused[(1, 1)] += k * wy * wy;
    Some((pose, fused))
}

impl LaserGraphSlam {
    /// The covariance of a match at `pose` on `grid` ([`MatchCovariance`]), `matcher`'s
    /// own when so configured or when the sampling has nothing to sample.
    pub(super) fn match_covariance(
        &self,
        grid: &OccupancyGrid,
        scan: &RangeData,
        pose: &Pose2,
        matcher: Matrix3,
    ) -> Matrix3 {
        ResponseSampling::configured(self.config.match_covariance)
            .and_then(|sampling| response_covariance(grid, scan, pose, &sampling))
            .unwrap_or(matcher)
    }

    /// Information of a match whose world-frame covariance is `cov`, expressed in the frame
    /// of a pose with heading `theta` (the edge's), with the `match-min-std` floor.
    pub(super) fn match_information(&self, cov: &Matrix3, theta: f64) -> Matrix3 {
        let r = planar_rotation(theta);
        let mut local = r.transpose() * cov * r * self.config.match_covariance_scale;
        let [sxy, sth] = self.config.match_min_std;
        local[(0, 0)] += sxy * sxy;
        local[(1, 1)] += sxy * sxy;
        local[(2, 2)] += sth * sth;
        invert(&local)
    }
}

/// The rotation of (x, y, θ) by `theta`: R(θ) on (x, y), the identity on θ. A covariance
/// C of (x, y, θ) in a frame turned by θ reads Rᵀ C R there.
pub(super) fn planar_rotation(theta: f64) -> Matrix3 {
    let (s, c) = theta.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// The inverse of a symmetric positive-definite 3×3 matrix, symmetrised (a covariance to an
/// information); a tiny diagonal is added if the inversion fails.
pub(super) fn invert(cov: &Matrix3) -> Matrix3 {
    let m = cov.try_inverse().unwrap_or_else(|| {
        (cov + Matrix3::identity() * 1e-12)
            .try_inverse()
            .unwrap_or(Matrix3::identity())
    });
    (m + m.transpose()) * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_grid::{InverseSensorModel, LikelihoodParams};
    use slam_models::LaserScan;

    /// A laser at (`x0`, 0) heading along x inside the box |x| ≤ `hx`, |y| ≤ `hy`, 361
    /// beams over 360°, 20 m max range; with `open_ends` the walls x = ±`hx` return
    /// nothing (a corridor).
    fn box_scan(x0: f64, hx: f64, hy: f64, open_ends: bool) -> LaserScan {
        let n = 361;
        let angle_min = -std::f64::consts::PI;
        let angle_increment = 2.0 * std::f64::consts::PI / (n - 1) as f64;
        let ranges = (0..n)
            .map(|i| {
                let a: f64 = angle_min + i as f64 * angle_increment;
                let to_side = hy / a.sin().abs().max(1e-12);
                let to_end = (hx - x0 * a.cos().signum()) / a.cos().abs().max(1e-12);
                if to_side <= to_end {
                    to_side.min(20.0)
                } else if open_ends {
                    20.0 // no return
                } else {
                    to_end.min(20.0)
                }
            })
            .collect();
        LaserScan {
            angle_min,
            angle_increment,
            ranges,
            max_range: 20.0,
            sensor_pose: Pose2::IDENTITY,
        }
    }

    /// The sampled covariance of the scan at the origin of the box, matched at its true
    /// pose in a map built from scans at x = −2 … 2 m every 0.1 m (walls seen densely, as
    /// a submap sees them).
    fn covariance_at_truth(hx: f64, hy: f64, open_ends: bool) -> Matrix3 {
        let mut grid = OccupancyGrid::try_new(0.05, InverseSensorModel::default())
            .unwrap()
            .with_likelihood(LikelihoodParams::default())
            .unwrap();
        for k in -20..=20 {
            let x0 = k as f64 * 0.1;
            let scan = box_scan(x0, hx, hy, open_ends);
            grid.try_integrate_scan(&Pose2::new(x0, 0.0, 0.0), &scan)
                .unwrap();
        }
        let scan = box_scan(0.0, hx, hy, open_ends);
        let prepared = RangeData::with_limits(&scan, grid.sensor_model(), 0.0, 20.0).unwrap();
        let sampling = ResponseSampling {
            linear_window: 0.3,
            angular_window: 0.02,
            temperature: 10.0,
        };
        response_covariance(&grid, &prepared, &Pose2::IDENTITY, &sampling).unwrap()
    }

    /// A corridor map built from the walls' scan, matched at the true pose: the sampled
    /// covariance is much larger along the corridor (x) than across it (y), and the
    /// across variance is of the order of the lattice's, while a closed room (walls on all
    /// four sides) is constrained in both directions.
    #[test]
    fn a_corridor_is_uncertain_along_its_axis_only() {
        // Walls at y = ±1 m, ends 15 m away and open.
        let cov = covariance_at_truth(15.0, 1.0, true);
        let (sx, sy) = (cov[(0, 0)].sqrt(), cov[(1, 1)].sqrt());
        eprintln!(
            "corridor: σ = ({sx:.4}, {sy:.4}) m, {:.5} rad",
            cov[(2, 2)].sqrt()
        );
        // A flat response over ±0.3 m has σ = 0.3/√3 = 0.17 m; the walls fix y to about a
        // cell (the lattice alone gives 0.05/√12 = 0.014 m).
        assert!(sx > 0.1, "along the corridor σ = {sx} m");
        assert!(sy < 0.03, "across the corridor σ = {sy} m");
        assert!(sx > 5.0 * sy, "σ along {sx} m, across {sy} m");
        assert!(cov.cholesky().is_some());
        assert_eq!(cov, cov.transpose());
        // A closed room 6 m × 2 m: both directions fixed to about a cell.
        let cov = covariance_at_truth(3.0, 1.0, false);
        let (sx, sy) = (cov[(0, 0)].sqrt(), cov[(1, 1)].sqrt());
        eprintln!(
            "room: σ = ({sx:.4}, {sy:.4}) m, {:.5} rad",
            cov[(2, 2)].sqrt()
        );
        assert!(sx < 0.03 && sy < 0.03, "room: σ = ({sx}, {sy}) m");
        assert!(cov.cholesky().is_some());
    }

    /// A corridor along x (information 100× weaker along x than along y): the fused edge
    /// takes the odometry's x, by the weights of least squares, and keeps the match's y
    /// and heading; an isotropic match is left alone. The expected values are worked out
    /// by hand from the formula, not taken from the function.
    #[test]
    fn a_degenerate_match_takes_the_odometry_along_its_weak_direction() {
        let info = Matrix3::from_diagonal(&slam_models::Vector3::new(1.0, 100.0, 1000.0));
        let z = Pose2::new(0.40, 0.00, 0.00);
        let odo = Pose2::new(0.50, 0.03, 0.01);
        let odo_cov = Matrix3::from_diagonal(&slam_models::Vector3::new(0.25, 0.25, 0.01));
        let (f, omega) = fuse_degenerate(&z, &info, &odo, &odo_cov, 2.0).unwrap();
        // Along x: (1 · 0.40 + 4 · 0.50) / (1 + 4) = 0.48; y and θ untouched.
        assert!((f.x - 0.48).abs() < 1e-12, "{f:?}");
        assert!(f.y.abs() < 1e-12 && f.theta.abs() < 1e-12, "{f:?}");
        assert!((omega[(0, 0)] - 5.0).abs() < 1e-12 && (omega[(1, 1)] - 100.0).abs() < 1e-12);
        // Rotated corridor: the weak direction is (cos 30°, sin 30°).
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let r = planar_rotation(30f64.to_radians());
        let info_r = r * info * r.transpose();
        let z_r = Pose2::new(0.40 * c, 0.40 * s, 0.0);
        let odo_r = Pose2::new(0.50 * c, 0.50 * s, 0.0);
        let (f, _) = fuse_degenerate(&z_r, &info_r, &odo_r, &odo_cov, 2.0).unwrap();
        assert!(
            (f.x - 0.48 * c).abs() < 1e-9 && (f.y - 0.48 * s).abs() < 1e-9,
            "{f:?}"
        );
        // Near the threshold the odometry's weight ramps up from zero: at ρ = 10 and a = 8,
        // f = (10 − 8) / 4 = 0.5, so the gain is 0.5 · 1 / (0.5 · 1 + 0.25) = 2/3 and
        // x = 0.40 + 2/3 · 0.1.
        let (f, omega) = fuse_degenerate(&z, &info, &odo, &odo_cov, 8.0).unwrap();
        assert!((f.x - (0.40 + 0.1 * 2.0 / 3.0)).abs() < 1e-12, "{f:?}");
        assert!((omega[(0, 0)] - 3.0).abs() < 1e-12, "{omega}");
        // σ ratio 10 ≥ 2 fused; an isotropic match (ratio 1) and a threshold above 10 not.
        let iso = Matrix3::from_diagonal(&slam_models::Vector3::new(100.0, 100.0, 1000.0));
        assert!(fuse_degenerate(&z, &iso, &odo, &odo_cov, 2.0).is_none());
        assert!(fuse_degenerate(&z, &info, &odo, &odo_cov, 10.5).is_none());
    }
}
