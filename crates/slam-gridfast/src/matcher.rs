//! Scan likelihood and hill-climbing scan matching against one particle's map.
//!
//! The beam end points are computed once per scan in the robot frame
//! ([`PreparedScan`], from slam-grid's prepared scan); every pose evaluation is then one
//! rotation and translation per beam and a bilinear look-up in the particle map's
//! incrementally repaired distance field ([`slam_grid::DistanceField`]), with no
//! trigonometry per beam (GMapping recomputes sin/cos and rounding for every beam of every
//! evaluation).
//!
//! Why a scorer of its own and not slam-grid's matchers: the improved proposal needs the
//! scan's log-likelihood under the truncated Gaussian endpoint model on the incremental
//! field (weights, the Gaussian fit of eqs. 14–16), evaluated ~100 times per particle and
//! scan; slam-grid's matchers score the mean of its lazily computed likelihood field.
//!
//! Endpoint model (PR §6.4, "likelihood field"): a beam ending at distance d from the
//! nearest occupied cell contributes ln p = −min(d, r)²/(2σ²) (the truncation r is the
//! outlier floor). The scan's log-likelihood is Σ ln p divided by the gain g (GMapping's
//! `ogain`).
//!
//! Two truncations, coarse to fine: the coarse search and the hill climber's coarse phase
//! score with r = the distance field's full reach (`field_radius`, 0.2 m by default), so
//! that a pose several centimetres off still feels the walls; the hill climber's fine
//! phase, the proposal's samples and the weights use the likelihood's own r
//! (`likelihood_radius`, 0.15 m), so that beams ending on clutter pull the mode less.

use slam_grid::{CellIndex, DistanceField, GridError};
use slam_models::{LaserScan, Pose2};

/// A scan prepared once per update: slam-grid's prepared scan (beam directions, for
/// integrating it into every particle's map) and the end points used for matching in the
/// robot frame (metres).
#[derive(Debug, Clone)]
pub(crate) struct PreparedScan {
    pub grid: slam_grid::PreparedScan,
    pub points: Vec<[f64; 2]>,
    /// Every 4th of `points`: the coarse phase of hill climbing evaluates these only.
    pub coarse: Vec<[f64; 2]>,
}

/// The largest f64 below `x`, for a positive finite `x` (the config validates
/// `max_range > 0`): `f64::next_down`, which is newer than this workspace's MSRV 1.85.
fn below(x: f64) -> f64 {
    f64::from_bits(x.to_bits() - 1)
}

impl PreparedScan {
    /// Every `step`-th end point of the hits with 0 < r < `max_range` (the scan's
    /// `sensor_pose` applied): a reading at `max_range` itself is a no return for the
    /// filter's sensor model (`far_hits_clear` off), so it is not matched either.
    pub fn new(scan: &LaserScan, step: usize, max_range: f64) -> Result<Self, GridError> {
        let grid = slam_grid::PreparedScan::with_limits(scan, f64::MIN_POSITIVE, below(max_range))?;
        let points: Vec<[f64; 2]> = grid
            .points()
            .iter()
            .step_by(step.max(1))
            .map(|p| [p.x, p.y])
            .collect();
        let coarse = points.iter().step_by(4).copied().collect();
        Ok(Self {
            grid,
            points,
            coarse,
        })
    }
}

/// The particle map's distance field. Every map of the filter is created with
/// [`slam_grid::OccupancyGrid::with_incremental_distance`] (see
/// [`crate::filter::new_map`]), so it is always there.
#[inline]
pub(crate) fn field(map: &slam_grid::OccupancyGrid) -> DistanceField<'_> {
    map.distance_field()
        .expect("every gridfast map is created with an incremental distance field")
}

/// The endpoint-model parameters of one filter.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Likelihood {
    /// 1/(2σ²·g), per m².
    pub k: f64,
    /// Truncation r, metres: distances beyond it count as r (at most the field's reach).
    pub radius: f64,
    /// The gain g itself: `g ·` a [`Score::log_likelihood`] is the untempered Σ ln p.
    pub gain: f64,
}

/// The score of one pose: Σ ln p / g, and how many beams ended within the truncation r.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Score {
    pub log_likelihood: f64,
    pub inliers: usize,
}

/// Evaluates the scan log-likelihood at `pose` (bilinear interpolation of the distance
/// field between the four cell centres around each end point).
#[inline]
pub(crate) fn score(
    field: &DistanceField<'_>,
    scan: &PreparedScan,
    pose: &Pose2,
    lk: &Likelihood,
) -> Score {
    score_points(field, &scan.points, pose, lk)
}

/// [`score`] over an explicit set of robot-frame end points.
#[inline]
fn score_points(
    field: &DistanceField<'_>,
    points: &[[f64; 2]],
    pose: &Pose2,
    lk: &Likelihood,
) -> Score {
    let frame = field.frame();
    let inv = 1.0 / frame.resolution;
    let unit = field.metres_per_unit();
    let (s, c) = pose.theta.sin_cos();
    let (tx, ty) = (
        (pose.x - frame.origin.x) * inv - 0.5,
        (pose.y - frame.origin.y) * inv - 0.5,
    );
    let (s, c) = (s * inv, c * inv);
    let mut sum = 0.0;
    let mut inliers = 0;
    let r_in = lk.radius * 0.999;
    let mut field = field.cursor();
    for p in points {
        // Cell-centre coordinates: cell (i, j) has its centre at (i, j).
        let u = c * p[0] - s * p[1] + tx;
        let v = s * p[0] + c * p[1] + ty;
        let (iu, iv) = (fast_floor(u), fast_floor(v));
        let (au, av) = (u - iu as f64, v - iv as f64);
        let d = field.dist4(CellIndex::new(iu, iv));
        let d0 = d[0] as f64 + au * (d[1] as f64 - d[0] as f64);
        let d1 = d[2] as f64 + au * (d[3] as f64 - d[2] as f64);
        let dm = ((d0 + av * (d1 - d0)) * unit).min(lk.radius);
        if dm < r_in {
            inliers += 1;
        }
        sum += dm * dm;
    }
    Score {
        log_likelihood: -lk.k * sum,
        inliers,
    }
}

/// ⌊x⌋ as an integer without a libm call (x well inside the i32 range; NaN maps to 0).
#[inline(always)]
fn fast_floor(x: f64) -> i32 {
    let i = x as i32;
    i - ((i as f64) > x) as i32
}

/// The outcome of a match.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MatchOutcome {
    pub pose: Pose2,
    pub score: Score,
}

/// Hill-climbing parameters.
#[derive(Debug, Clone, Copy)]
pub(crate) struct HillClimb {
    pub linear_step: f64,
    pub angular_step: f64,
    pub refinements: usize,
}

/// Exhaustive coarse search (Olson's correlative matching, ICRA 2009, at one coarse
/// resolution) over the poses `initial` ⊕ (dx, dy, dθ) with |dx|, |dy| ≤ `range_xy` in
/// steps of `step_xy` and |dθ| ≤ `range_theta` in steps of `step_theta`, scored with the
/// coarse beam subset (times the subsampling factor) plus the log motion prior
/// −½ eᵀR⁻¹e: the mode of likelihood × motion model on the grid. Returns the best pose (the
/// initial pose wins ties).
pub(crate) fn grid_search(
    field: &DistanceField<'_>,
    scan: &PreparedScan,
    initial: &Pose2,
    lk: &Likelihood,
    window: &SearchWindow,
) -> Pose2 {
    let points = if scan.coarse.len() >= 20 {
        &scan.coarse
    } else {
        &scan.points
    };
    let mut best = *initial;
    let scale = scan.points.len() as f64 / points.len().max(1) as f64;
    let mut top = scale * score_points(field, points, initial, lk).log_likelihood;
    let nxy = (window.range_xy / window.step_xy).floor() as i32;
    let nth = (window.range_theta / window.step_theta).floor() as i32;
    for it in -nth..=nth {
        for iy in -nxy..=nxy {
            for ix in -nxy..=nxy {
                if ix == 0 && iy == 0 && it == 0 {
                    continue;
                }
                let delta = Pose2::new(
                    ix as f64 * window.step_xy,
                    iy as f64 * window.step_xy,
                    it as f64 * window.step_theta,
                );
                let cand = initial.compose(&delta);
                // The motion model's prior keeps ambiguous directions (corridors) at
                // the prediction: −½ eᵀR⁻¹e with e = candidate − prediction.
                let e =
                    slam_models::Vector3::new(cand.x - initial.x, cand.y - initial.y, delta.theta);
                let prior = 0.5 * e.dot(&(window.information * e));
                let s = scale * score_points(field, points, &cand, lk).log_likelihood - prior;
                if s > top {
                    top = s;
                    best = cand;
                }
            }
        }
    }
    best
}

/// The window of [`grid_search`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct SearchWindow {
    pub range_xy: f64,
    pub step_xy: f64,
    pub range_theta: f64,
    pub step_theta: f64,
    /// R⁻¹, the inverse of the motion model's covariance at the prediction.
    pub information: slam_models::Matrix3,
}

/// The coarse-beam score of a pose (for choosing between starting points).
pub(crate) fn coarse_score(
    field: &DistanceField<'_>,
    scan: &PreparedScan,
    pose: &Pose2,
    lk: &Likelihood,
) -> f64 {
    let points = if scan.coarse.len() >= 20 {
        &scan.coarse
    } else {
        &scan.points
    };
    score_points(field, points, pose, lk).log_likelihood
}

/// GMapping-style hill climbing (Grisetti et al. 2007 §VI; `ScanMatcher::optimize`): from
/// `initial`, try the six moves ±x, ±y (world frame) and ±θ; take the best if it improves
/// the score, otherwise halve both steps, `refinements` times. After a step, the move that
/// would undo it is not evaluated again (it leads back to a pose that scored lower). The
/// coarse phase scores with `capture` (the wide truncation), the fine phase and the
/// returned score with `lk`.
pub(crate) fn hill_climb(
    field: &DistanceField<'_>,
    scan: &PreparedScan,
    initial: &Pose2,
    capture: &Likelihood,
    lk: &Likelihood,
    hc: &HillClimb,
) -> MatchOutcome {
    // Coarse phase: while the steps are at least a quarter of the initial ones, a quarter
    // of the beams decide (4× cheaper evaluations, same capture range); then all beams.
    let mut best = *initial;
    let (mut ls, mut as_) = (hc.linear_step, hc.angular_step);
    let mut halvings = 0;
    let coarse_halvings = if scan.coarse.len() >= 20 {
        2.min(hc.refinements)
    } else {
        0
    };
    // A hard cap keeps pathological inputs bounded (≈ GMapping's ~121 evaluations).
    let mut budget = 64;
    for phase in 0..2 {
        let (points, last, lk) = if phase == 0 {
            (&scan.coarse[..], coarse_halvings, capture)
        } else {
            (&scan.points[..], hc.refinements + 1, lk)
        };
        let mut best_score = score_points(field, points, &best, lk);
        let mut back: Option<usize> = None;
        while halvings < last && budget > 0 {
            budget -= 1;
            let moves = [
                Pose2::new(best.x + ls, best.y, best.theta),
                Pose2::new(best.x - ls, best.y, best.theta),
                Pose2::new(best.x, best.y + ls, best.theta),
                Pose2::new(best.x, best.y - ls, best.theta),
                Pose2::new(best.x, best.y, best.theta + as_),
                Pose2::new(best.x, best.y, best.theta - as_),
            ];
            let mut improved = None;
            let mut top = best_score.log_likelihood;
            for (i, m) in moves.into_iter().enumerate() {
                // The move back to where the last step came from scored below the current
                // pose already (moves come in ± pairs: i ^ 1 undoes i).
                if back == Some(i) {
                    continue;
                }
                let s = score_points(field, points, &m, lk);
                if s.log_likelihood > top {
                    top = s.log_likelihood;
                    improved = Some((i, m, s));
                }
            }
            match improved {
                Some((i, m, s)) => {
                    best = m;
                    best_score = s;
                    back = Some(i ^ 1);
                }
                None => {
                    ls *= 0.5;
                    as_ *= 0.5;
                    halvings += 1;
                    back = None;
                }
            }
        }
        if phase == 1 {
            return MatchOutcome {
                pose: best,
                score: best_score,
            };
        }
    }
    MatchOutcome {
        pose: best,
        score: score(field, scan, &best, lk),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use slam_grid::{InverseSensorModel, OccupancyGrid};

    pub(crate) fn empty_map() -> OccupancyGrid {
        let model = InverseSensorModel {
            l_free: -0.4,
            no_return_range: 0.0,
            hit_margin: 0.0,
            protect_scan_hits: true,
            ..Default::default()
        };
        OccupancyGrid::new(0.05, model)
            .with_incremental_distance(4)
            .unwrap()
    }

    /// A closed room ≈ 8 m × 5 m with a pillar, scanned with 361 beams over 360°. The walls
    /// run through cell centres (x = ±4.025, y = ±2.525 on the 5 cm grid): a wall on a cell
    /// boundary puts its hits on either side by floating-point rounding, which moves the
    /// mapped wall by up to half a cell and the best match with it.
    pub(crate) fn room_scan(pose: &Pose2) -> LaserScan {
        let n = 361;
        let inc = 2.0 * std::f64::consts::PI / n as f64;
        let ranges = (0..n)
            .map(|k| {
                let a = pose.theta - std::f64::consts::PI + k as f64 * inc;
                let (dx, dy) = (a.cos(), a.sin());
                let mut t = f64::INFINITY;
                for (wall, dir, coord) in [
                    (4.025, dx, pose.x),
                    (-4.025, dx, pose.x),
                    (2.525, dy, pose.y),
                    (-2.525, dy, pose.y),
                ] {
                    if dir != 0.0 {
                        let tt = (wall - coord) / dir;
                        if tt > 0.0 {
                            t = t.min(tt);
                        }
                    }
                }
                // Pillar: a circle of radius 0.3 m at (1.5, 1.0).
                let (ox, oy) = (pose.x - 1.5, pose.y - 1.0);
                let b = ox * dx + oy * dy;
                let disc = b * b - (ox * ox + oy * oy - 0.09);
                if disc > 0.0 && -b - disc.sqrt() > 0.0 {
                    t = t.min(-b - disc.sqrt());
                }
                t
            })
            .collect();
        LaserScan {
            angle_min: -std::f64::consts::PI,
            angle_increment: inc,
            ranges,
            max_range: 30.0,
            sensor_pose: Pose2::IDENTITY,
        }
    }

    /// A beam ending 0.18 m from the nearest wall cell scores min(d, r)²: d itself under the
    /// 0.2 m capture truncation (an inlier), r under a 0.15 m one (an outlier).
    #[test]
    fn each_beam_is_truncated_at_the_likelihood_radius() {
        let mut map = empty_map();
        let origin = Pose2::new(0.0, 0.0, 0.0);
        map.integrate_scan(&origin, &room_scan(&origin));
        // The wall x = 4.025 runs through cell centres; the end point lies 0.4 of the way
        // from the centre 0.2 m from it to the one 0.15 m from it, on a row of centres.
        let point = [[4.025 - 0.18, 0.025]];
        let lk = |radius: f64| Likelihood {
            k: 1.0,
            radius,
            gain: 1.0,
        };
        let wide = score_points(&field(&map), &point, &origin, &lk(0.2));
        let tight = score_points(&field(&map), &point, &origin, &lk(0.15));
        assert!(
            (wide.log_likelihood + 0.18 * 0.18).abs() < 1e-4,
            "{}",
            wide.log_likelihood
        );
        assert_eq!(wide.inliers, 1);
        assert!((tight.log_likelihood + 0.15 * 0.15).abs() < 1e-9);
        assert_eq!(tight.inliers, 0);
    }

    #[test]
    fn hill_climbing_recovers_an_offset_pose() {
        let mut map = empty_map();
        for p in [
            Pose2::new(0.0, 0.0, 0.0),
            Pose2::new(-1.0, -0.5, 1.0),
            Pose2::new(1.0, -1.0, -2.0),
        ] {
            map.integrate_scan(&p, &room_scan(&p));
        }
        let truth = Pose2::new(0.3, 0.4, 0.3);
        let scan = PreparedScan::new(&room_scan(&truth), 1, 50.0).unwrap();
        let lk = Likelihood {
            k: 1.0 / (2.0 * 0.05 * 0.05 * 3.0),
            radius: 0.2,
            gain: 3.0,
        };
        let hc = HillClimb {
            linear_step: 0.05,
            angular_step: 0.05,
            refinements: 5,
        };
        for off in [
            Pose2::new(0.1, -0.08, 0.05),
            Pose2::new(-0.12, 0.1, -0.08),
            Pose2::new(0.0, 0.15, 0.0),
        ] {
            let init = Pose2::new(truth.x + off.x, truth.y + off.y, truth.theta + off.theta);
            let m = hill_climb(&field(&map), &scan, &init, &lk, &lk, &hc);
            assert!(
                m.pose.distance(&truth) < 0.02,
                "{:?} from {:?}",
                m.pose,
                init
            );
            assert!(slam_models::normalize_angle(m.pose.theta - truth.theta).abs() < 0.01);
            assert!(m.score.inliers as f64 > 0.9 * scan.points.len() as f64);
        }
        // An empty map has no inliers.
        let empty = empty_map();
        assert_eq!(score(&field(&empty), &scan, &truth, &lk).inliers, 0);
    }
}
