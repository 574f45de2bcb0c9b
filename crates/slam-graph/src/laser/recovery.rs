//! Recovery of a local scan match that the odometry put outside the correlative window.
//!
//! The local match searches ±`local-matcher.correlative.angular-window` (0.3 rad) around
//! the odometry's prediction. Odometry that turned in place can be off by more than that,
//! more than the turn itself: `perturb-odometry --profile moderate` (5 % rotation noise per
//! radian) gives fhw a step that turned −0.83 rad, measured −0.40 rad, and Intel `hard`
//! steps whose heading is 0.8–0.9 rad off. The correlative search then either finds
//! nothing above `local-min-score` (the odometry is used, and the scan inserted at the
//! wrong heading) or a wrong optimum at the edge of its window; either way the submap and
//! every later keyframe inherit a heading error of tens of degrees, and the map is bent
//! (docs/results/graph.md, "Turns the odometry got wrong"). Grid FastSLAM's answer to the
//! same steps is its turn search (slam-gridfast's `RecoveryConfig`); this is the graph's.
//!
//! On a keyframe whose odometry turned at least `turn` since the previous keyframe, or
//! whose local match failed or scored below `local-min-score`, the scan is matched again
//! by branch and bound ([`BranchBoundMatcher`]) on a [`MaxPyramid`] of the submap, then
//! refined by the local matcher's Gauss-Newton step:
//!
//! 1. within `radius` of the predicted position and the local window plus `turn-scale` ×
//!    the odometry's turn of the predicted heading (a heading further off is more often a
//!    symmetric place seen the other way round than odometry that wrong), at most
//!    `max-angle` (csail has a corridor that a window of ±3.13 rad, on a 1.88 rad turn,
//!    took 180° flipped: it scored 0.73 against the right heading's 0.65);
//! 2. a failed match that step 1 did not recover: over **every heading** (±π) within
//!    `radius` + `step-growth` × the odometry's translation since the previous keyframe,
//!    taken only at `loop-min-score` or above (a step's direction of travel can be as wrong
//!    as its heading: acapulco `hard` has a step 1.04 m backwards that the odometry
//!    measured 0.9 rad turned and 0.65 m aside; belgioioso `hard` one that turned 0.65 rad
//!    and was measured 0.02 rad).
//!
//! Its match replaces the local one only when it scores at least `gain` times as well
//! (and at least `local-min-score`): where the odometry was right the local match is
//! already the best in the window, and a heading that explains the scan no better than
//! the predicted one is not taken.

use super::config::ensure;
use super::{loops, LaserGraphSlam};
use crate::error::GraphError;
use serde::{Deserialize, Serialize};
use slam_grid::{BranchBoundMatcher, MatchResult, OccupancyGrid, RangeData};
use slam_models::Pose2;

/// The local-match recovery's settings (`[local-recovery]` in TOML; module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default, rename_all = "kebab-case")]
pub struct LocalRecovery {
    /// Whether the recovery runs at all. Default true.
    pub enabled: bool,
    /// A keyframe whose odometry turned at least this much since the previous keyframe
    /// (|Δθ|, radians, ≥ 0) is searched again (module documentation); a failed or poor
    /// local match always is. Default 0.3: the local window's half-width, beyond which a turn's
    /// odometry error of the same order as the turn can leave it.
    pub turn: f64,
    /// Half-width of the first search's translation window around the predicted position,
    /// metres, in (0, 2]. Default 0.3 (the local window's).
    pub radius: f64,
    /// A failed or poor local match that the first search did not recover is searched
    /// over every heading within `radius` + this × the odometry's translation since the
    /// previous keyframe (at most `radius` + 2 m) and taken only at `loop-min-score` or
    /// above (≥ 0). Default 1: a step's direction of travel can be as wrong as its
    /// heading.
    pub step_growth: f64,
    /// The first search covers the headings within the local window plus this × the
    /// odometry's |Δθ| of the predicted heading (≥ 0). Default 3: the odometry's heading
    /// error on a turn can exceed the turn itself (Intel `hard`: 0.88 rad on a measured
    /// turn of 0.56 rad; 1.5 left such a step unrecovered and the map lost, 3.7 m).
    pub turn_scale: f64,
    /// … and at most this, radians, in (0, π]. Default π/2: a turn's odometry more than a
    /// quarter turn off is less likely than a corridor seen the other way round.
    pub max_angle: f64,
    /// The recovered match replaces the local one only when its score is at least this
    /// factor times the local match's (≥ 1). Default 1.1.
    pub gain: f64,
}

impl Default for LocalRecovery {
    fn default() -> Self {
        Self {
            enabled: true,
            turn: 0.3,
            radius: 0.3,
            step_growth: 1.0,
            turn_scale: 3.0,
            max_angle: std::f64::consts::FRAC_PI_2,
            gain: 1.1,
        }
    }
}

impl LocalRecovery {
    /// Checks the fields against their documented ranges.
    pub fn validate(&self) -> Result<(), GraphError> {
        let pi = std::f64::consts::PI;
        let (t, r, ts) = (self.turn, self.radius, self.turn_scale);
        ensure(t >= 0.0, "local-recovery.turn", t, ">= 0 rad")?;
        ensure(
            r > 0.0 && r <= 2.0,
            "local-recovery.radius",
            r,
            "in (0, 2] m",
        )?;
        ensure(ts >= 0.0, "local-recovery.turn-scale", ts, ">= 0")?;
        let (ma, s, g) = (self.max_angle, self.step_growth, self.gain);
        ensure(
            ma > 0.0 && ma <= pi,
            "local-recovery.max-angle",
            ma,
            "in (0, pi] rad",
        )?;
        ensure(s >= 0.0, "local-recovery.step-growth", s, ">= 0")?;
        ensure(g >= 1.0, "local-recovery.gain", g, ">= 1")
    }
}

impl LaserGraphSlam {
    /// The recovered match of `scan` on `grid` around `predicted` (module documentation)
    /// when it should replace `local` (the local match, `None` when it failed); `delta` is
    /// the odometry's motion since the previous keyframe. `None` when the recovery does not
    /// run or finds nothing better.
    pub(super) fn recover_local_match(
        &self,
        grid: &OccupancyGrid,
        scan: &RangeData,
        predicted: &Pose2,
        delta: &Pose2,
        local: Option<&MatchResult>,
    ) -> Option<MatchResult> {
        let c = &self.config;
        let r = &c.local_recovery;
        let poor = local.is_none_or(|m| m.score < c.local_min_score);
        if !r.enabled || (!poor && delta.theta.abs() < r.turn) {
            return None;
        }
        let bar = match local {
            Some(m) if m.score >= c.local_min_score => r.gain * m.score,
            _ => c.local_min_score,
        };
        if bar > 1.0 {
            return None;
        }
        // A matching error (too few end points, an empty submap) means nothing to recover
        // with: the local match, or the odometry, stands.
        let Ok(Some(pyramid)) = loops::loop_pyramid(grid, c.loop_depth) else {
            return None;
        };
        // First the headings within `turn-scale` × the turn (plus the local window) of the
        // prediction: a heading further off is a symmetric place seen the other way round
        // (csail: a corridor matched 180° flipped at a 1.88 rad turn) more often than
        // odometry that wrong.
        let turned = (c.local_matcher.correlative.angular_window
            + r.turn_scale * delta.theta.abs())
        .min(r.max_angle);
        let search = |radius: f64, angle: f64, bar: f64| {
            let matcher = BranchBoundMatcher {
                linear_window: radius,
                angular_window: angle,
                angular_step: 0.0,
                depth: c.loop_depth,
                min_score: bar,
                min_points: c.local_matcher.correlative.min_points,
            };
            let hit = matcher.match_in(&pyramid, scan, predicted).ok()??;
            let m = self.refine_near(grid, scan, hit);
            (m.score >= bar).then_some(m)
        };
        let near = search(r.radius, turned, bar);
        if near.is_some() || !poor {
            return near;
        }
        // A failed match, nothing near: every heading within the wider window, held to the
        // loop closures' bar (a pose far from the prediction needs more than not failing).
        let step = delta.translation().coords.norm();
        search(
            (r.radius + r.step_growth * step).min(2.0 + r.radius),
            std::f64::consts::PI,
            bar.max(c.loop_min_score),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn out_of_range_settings_are_rejected() {
        assert!(LocalRecovery::default().validate().is_ok());
        for (r, field) in [
            (
                LocalRecovery {
                    turn: -0.1,
                    ..LocalRecovery::default()
                },
                "local-recovery.turn",
            ),
            (
                LocalRecovery {
                    radius: 0.0,
                    ..LocalRecovery::default()
                },
                "local-recovery.radius",
            ),
            (
                LocalRecovery {
                    gain: f64::NAN,
                    ..LocalRecovery::default()
                },
                "local-recovery.gain",
            ),
            (
                LocalRecovery {
                    turn_scale: -1.0,
                    ..LocalRecovery::default()
                },
                "local-recovery.turn-scale",
            ),
            (
                LocalRecovery {
                    max_angle: 3.2,
                    ..LocalRecovery::default()
                },
                "local-recovery.max-angle",
            ),
            (
                LocalRecovery {
                    step_growth: f64::INFINITY,
                    ..LocalRecovery::default()
                },
                "local-recovery.step-growth",
            ),
            (
                LocalRecovery {
                    gain: 0.9,
                    ..LocalRecovery::default()
                },
                "local-recovery.gain",
            ),
        ] {
            match r.validate() {
                Err(GraphError::FrontEndConfig { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: {other:?}"),
            }
        }
    }
}
