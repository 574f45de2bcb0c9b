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
    let ll: Vec<f32> = grid
        .field_window(min, w, h)
        .into_iter()
        .map(|s| params.log_likelihood(s) as f32)
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
}
