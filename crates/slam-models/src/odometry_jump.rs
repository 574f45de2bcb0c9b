//! A guard against glitched odometry: a jump between two consecutive records beyond a
//! limit is an error, or, where the user asks for it, is skipped.
//!
//! One bad odometry record (a 10 km jump in a CARMEN log) would otherwise put a scan
//! kilometres away from the rest of the map, stretching everything laid out over the map's
//! bounding box; no robot moves metres between two odometry readings taken a fraction of a
//! second apart. The laser filters run every record's odometry through an
//! [`OdometryJumpGuard`] before using it.

use crate::{ModelError, Pose2};
use serde::{Deserialize, Serialize};

/// What a laser filter does with a record whose odometry jumped beyond
/// [`OdometryJumpLimit::max_jump`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum OnOdometryJump {
    /// Stop with [`ModelError::OdometryJump`] (the default: a glitch is reported, never
    /// mapped).
    #[default]
    Error,
    /// Take the jump as no motion: the record keeps the previous record's pose, later
    /// records move by their own increments from there, and the step info counts the
    /// skip (`ScanUpdateInfo::odometry_jumps_skipped`) so that the caller can warn.
    Skip,
}

/// The largest odometry change the laser filters accept between two consecutive records.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct OdometryJumpLimit {
    /// Largest distance between the odometry positions of two consecutive records, metres
    /// (> 0). Default 5 m: the largest step between records in the benchmark logs is 1.5 m
    /// (Freiburg's csail.log; Intel's 0.22 m), a glitch is kilometres.
    pub max_jump: f64,
    /// What to do beyond it. Default [`OnOdometryJump::Error`].
    pub on_jump: OnOdometryJump,
}

impl Default for OdometryJumpLimit {
    fn default() -> Self {
        Self {
            max_jump: 5.0,
            on_jump: OnOdometryJump::Error,
        }
    }
}

impl OdometryJumpLimit {
    /// Checks `max_jump` > 0 (finite; `f64::MAX` switches the check off in effect).
    pub fn validate(&self) -> Result<(), ModelError> {
        if self.max_jump.is_finite() && self.max_jump > 0.0 {
            Ok(())
        } else {
            Err(ModelError::OutOfRange {
                name: "odometry-jump.max-jump",
                value: self.max_jump,
                expected: "> 0 m and finite",
            })
        }
    }
}

/// Checks each record's odometry against the previous record's and hands the filter the
/// odometry to use: the reading itself until a jump is skipped, afterwards the reading
/// moved by the offset that makes the skipped jump no motion.
#[derive(Debug, Clone, Default)]
pub struct OdometryJumpGuard {
    limit: OdometryJumpLimit,
    /// The previous record's raw odometry.
    last: Option<Pose2>,
    /// `Some(o)` once a jump was skipped: the odometry used is o ⊕ reading.
    offset: Option<Pose2>,
    skipped: usize,
}

impl OdometryJumpGuard {
    /// A guard with the given limit (validated).
    pub fn new(limit: OdometryJumpLimit) -> Result<Self, ModelError> {
        limit.validate()?;
        Ok(Self {
            limit,
            ..Self::default()
        })
    }

    /// The odometry to use for the record with raw odometry `odometry` (finite), and
    /// whether its jump was skipped; [`ModelError::OdometryJump`] when it jumped more
    /// than `max_jump` from the previous record and jumps are errors (the guard is then
    /// unchanged, as if the record had not been seen).
    pub fn check(&mut self, odometry: &Pose2) -> Result<(Pose2, bool), ModelError> {
        let mut skipped = false;
        if let Some(last) = self.last {
            let jump = last.distance(odometry);
            if jump.is_nan() || jump > self.limit.max_jump {
                if self.limit.on_jump == OnOdometryJump::Error {
                    return Err(ModelError::OdometryJump {
                        jump,
                        max_jump: self.limit.max_jump,
                    });
                }
                // Used pose stays the previous one: o' ⊕ reading = o ⊕ last.
                let used_last = self.apply(&last);
                self.offset = Some(used_last.compose(&odometry.inverse()));
                self.skipped += 1;
                skipped = true;
            }
        }
        self.last = Some(*odometry);
        Ok((self.apply(odometry), skipped))
    }

    /// Jumps skipped so far.
    pub fn skipped(&self) -> usize {
        self.skipped
    }

    #[inline]
    fn apply(&self, odometry: &Pose2) -> Pose2 {
        match &self.offset {
            Some(o) => o.compose(odometry),
            None => *odometry,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_jump_is_an_error_by_default_and_names_the_bound() {
        let mut g = OdometryJumpGuard::new(OdometryJumpLimit::default()).unwrap();
        let a = Pose2::new(1.0, 2.0, 0.3);
        assert_eq!(g.check(&a).unwrap(), (a, false));
        let far = Pose2::new(10_001.0, 2.0, 0.3);
        let e = g.check(&far).unwrap_err();
        assert_eq!(
            e,
            ModelError::OdometryJump {
                jump: 10_000.0,
                max_jump: 5.0
            }
        );
        let msg = e.to_string();
        assert!(msg.contains("10000") && msg.contains("5 m"), "{msg}");
        // A normal step after the refused record is still measured from `a`.
        let b = Pose2::new(1.5, 2.0, 0.3);
        assert_eq!(g.check(&b).unwrap(), (b, false));
        assert_eq!(g.skipped(), 0);
        // NaN distances are jumps too.
        assert!(g.check(&Pose2::new(f64::NAN, 0.0, 0.0)).is_err());
    }

    #[test]
    fn a_skipped_jump_is_no_motion_and_later_increments_are_kept() {
        let limit = OdometryJumpLimit {
            max_jump: 2.0,
            on_jump: OnOdometryJump::Skip,
        };
        let mut g = OdometryJumpGuard::new(limit).unwrap();
        let a = Pose2::new(1.0, 2.0, 0.3);
        g.check(&a).unwrap();
        // A glitch 10 km away, then the odometry continues from the glitched value (a
        // reset of the odometry frame, rotated as well).
        let glitch = Pose2::new(10_001.0, -5.0, 2.0);
        let (used, skipped) = g.check(&glitch).unwrap();
        assert!(skipped);
        assert!(used.distance(&a) < 1e-9 && (used.theta - a.theta).abs() < 1e-12);
        let step = Pose2::new(0.5, 0.1, 0.05);
        let (next, skipped) = g.check(&glitch.compose(&step)).unwrap();
        assert!(!skipped);
        // The used odometry moved by the same increment, expressed in the robot frame.
        let inc = used.between(&next);
        assert!((inc.x - step.x).abs() < 1e-9 && (inc.y - step.y).abs() < 1e-9);
        assert!((inc.theta - step.theta).abs() < 1e-12);
        assert_eq!(g.skipped(), 1);
        assert!(OdometryJumpGuard::new(OdometryJumpLimit {
            max_jump: 0.0,
            ..limit
        })
        .is_err());
    }
}
