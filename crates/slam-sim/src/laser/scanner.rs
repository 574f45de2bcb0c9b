//! The simulated planar laser scanner.

use super::World;
use crate::error::{check_range, SimError};
use crate::rng::normal;
use rand::Rng;
use serde::{Deserialize, Serialize};
use slam_models::{LaserScan, Pose2};

/// A planar laser range finder.
///
/// Beam k (0 ≤ k < `beams`) points at −fov/2 + k·fov/(beams − 1) radians from the sensor
/// heading (so 181 beams over 180° is the CARMEN `FLASER` geometry, 1° apart, −90°…+90°).
/// For the true range r to the nearest wall along the beam (PR §6.3, beam model):
///
/// * no wall within `max_range` → the reading is exactly `max_range` ("no return");
/// * with probability `short_reading_probability` an unexpected obstacle (a person, a
///   reflection) gives a reading uniform in [0, r) (PR's p_short, with a uniform instead of
///   an exponential profile);
/// * otherwise r + ε, ε ~ N(0, σ²) (PR's p_hit), clamped to ≥ 0; a noisy reading at or
///   beyond `max_range` reads as "no return".
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct LaserScanner {
    /// Number of beams (≥ 2).
    pub beams: usize,
    /// Angular range covered, radians (first to last beam), centred on the heading.
    pub fov: f64,
    /// Readings at or beyond this range are "no return", metres.
    pub max_range: f64,
    /// Range noise σ, metres.
    pub sigma: f64,
    /// Probability per beam of a random short reading.
    pub short_reading_probability: f64,
    /// Pose of the scanner in the robot frame.
    pub sensor_pose: Pose2,
}

impl Default for LaserScanner {
    /// 181 beams over 180° (1° resolution), range 20 m, σ = 1 cm, no short readings, at the
    /// robot's origin (a SICK LMS-200 as in the CARMEN logs).
    fn default() -> Self {
        Self {
            beams: 181,
            fov: std::f64::consts::PI,
            max_range: 20.0,
            sigma: 0.01,
            short_reading_probability: 0.0,
            sensor_pose: Pose2::IDENTITY,
        }
    }
}

impl LaserScanner {
    /// Rejects NaN/∞ and out-of-range settings.
    pub fn validate(&self) -> Result<(), SimError> {
        if self.beams < 2 || self.beams > 100_000 {
            return Err(SimError::InvalidParameter {
                name: "beams",
                value: self.beams.to_string(),
                expected: "2 ..= 100000 beams",
            });
        }
        check_range(
            "laser fov",
            self.fov,
            1e-6,
            2.0 * std::f64::consts::PI,
            "0 < fov <= 2π rad",
        )?;
        check_range(
            "laser max_range",
            self.max_range,
            1e-3,
            1e5,
            "0 < max_range <= 1e5 m",
        )?;
        check_range("laser sigma", self.sigma, 0.0, 1e3, "0 <= sigma <= 1000 m")?;
        check_range(
            "short_reading_probability",
            self.short_reading_probability,
            0.0,
            1.0,
            "a probability in [0, 1]",
        )?;
        if !self.sensor_pose.is_finite() {
            return Err(SimError::InvalidParameter {
                name: "sensor_pose",
                value: format!("{:?}", self.sensor_pose),
                expected: "a finite pose",
            });
        }
        Ok(())
    }

    /// (angle of beam 0, angle between beams), radians.
    pub fn geometry(&self) -> (f64, f64) {
        (-0.5 * self.fov, self.fov / (self.beams - 1) as f64)
    }

    /// The noise-free ranges (`max_range` for no return) from robot pose `pose`.
    pub fn true_ranges(&self, world: &World, pose: &Pose2) -> Vec<f64> {
        let s = pose.compose(&self.sensor_pose);
        let (a0, inc) = self.geometry();
        (0..self.beams)
            .map(|k| {
                let a = s.theta + a0 + k as f64 * inc;
                world
                    .cast(&s.translation(), a, self.max_range)
                    .unwrap_or(self.max_range)
            })
            .collect()
    }

    /// One noisy scan from robot pose `pose`. Exactly three random numbers are drawn per
    /// beam, whatever happens, so a seed's noise does not depend on the geometry.
    pub fn scan<R: Rng + ?Sized>(&self, world: &World, pose: &Pose2, rng: &mut R) -> LaserScan {
        let (a0, inc) = self.geometry();
        let mut ranges = self.true_ranges(world, pose);
        for r in ranges.iter_mut() {
            let u_short: f64 = rng.random();
            let u_val: f64 = rng.random();
            let e = normal(rng) * self.sigma;
            if *r >= self.max_range {
                *r = self.max_range;
            } else if u_short < self.short_reading_probability {
                *r *= u_val;
            } else {
                *r = (*r + e).clamp(0.0, self.max_range);
            }
        }
        LaserScan {
            angle_min: a0,
            angle_increment: inc,
            ranges,
            max_range: self.max_range,
            sensor_pose: self.sensor_pose,
        }
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // beams are indexed in parallel arrays
mod tests {
    use super::*;
    use crate::laser::Segment;
    use crate::rng::stream;

    /// A wall x = 5 from y = −100 to 100.
    fn wall() -> World {
        World::new(vec![Segment::new(5.0, -100.0, 5.0, 100.0)]).unwrap()
    }

    #[test]
    fn geometry_matches_flaser() {
        let s = LaserScanner::default();
        let (a0, inc) = s.geometry();
        let (b0, binc) = LaserScan::flaser_geometry(181);
        assert!((a0 - b0).abs() < 1e-15 && (inc - binc).abs() < 1e-15);
    }

    #[test]
    fn noise_statistics_and_no_return() {
        let sc = LaserScanner {
            sigma: 0.05,
            max_range: 8.0,
            ..Default::default()
        };
        let w = wall();
        let pose = Pose2::new(0.0, 0.0, 0.0);
        let truth = sc.true_ranges(&w, &pose);
        let (a0, inc) = sc.geometry();
        let mut rng = stream(4, 60);
        let (mut n, mut s, mut s2) = (0.0, 0.0, 0.0);
        for _ in 0..300 {
            let scan = sc.scan(&w, &pose, &mut rng);
            for k in 0..scan.len() {
                let a = a0 + k as f64 * inc;
                // Analytic: the wall is hit at 5/cos a when that is within range.
                let d = 5.0 / a.cos();
                if a.cos() > 0.0 && d < 8.0 - 0.5 {
                    assert!((truth[k] - d).abs() < 1e-9);
                    let e = scan.ranges[k] - d;
                    n += 1.0;
                    s += e;
                    s2 += e * e;
                } else if a.cos() <= 0.0 || d > 8.0 {
                    assert_eq!(scan.ranges[k], 8.0);
                    assert!(!scan.is_hit(k));
                }
            }
        }
        let mean = s / n;
        let var = s2 / n - mean * mean;
        assert!(mean.abs() < 5.0 * 0.05 / f64::sqrt(n), "mean {mean}");
        assert!(
            (var - 0.0025).abs() < 5.0 * 0.0025 * f64::sqrt(2.0 / n),
            "var {var}"
        );
    }

    #[test]
    fn short_readings_rate() {
        let p = 0.2;
        let sc = LaserScanner {
            sigma: 0.0,
            short_reading_probability: p,
            ..Default::default()
        };
        let w = wall();
        let pose = Pose2::new(0.0, 0.0, 0.0);
        let truth = sc.true_ranges(&w, &pose);
        let mut rng = stream(5, 61);
        let (mut hits, mut short) = (0.0, 0.0);
        for _ in 0..500 {
            let scan = sc.scan(&w, &pose, &mut rng);
            for k in 0..scan.len() {
                if truth[k] < sc.max_range {
                    hits += 1.0;
                    if scan.ranges[k] < truth[k] - 1e-12 {
                        short += 1.0;
                    }
                }
            }
        }
        let sd = (hits * p * (1.0 - p)).sqrt();
        assert!(
            (short - hits * p).abs() < 5.0 * sd,
            "{short} short of {hits}"
        );
        assert!(LaserScanner {
            beams: 1,
            ..Default::default()
        }
        .validate()
        .is_err());
    }

    #[test]
    fn sensor_offset_is_applied() {
        // Sensor 0.5 m ahead of the robot: the wall in front is 0.5 m closer.
        let sc = LaserScanner {
            sensor_pose: Pose2::new(0.5, 0.0, 0.0),
            ..Default::default()
        };
        let r = sc.true_ranges(&wall(), &Pose2::new(0.0, 0.0, 0.0));
        assert!((r[90] - 4.5).abs() < 1e-9);
    }
}
