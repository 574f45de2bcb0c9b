//! The measurement models p(z | x, m) of a laser scan on the known map (Probabilistic
//! Robotics ch. 6), evaluated as log-likelihoods.

use crate::config::{SensorConfig, SensorKind};
use crate::map::MclMap;
use slam_models::{LaserScan, Point2, Pose2};

/// The beams of one scan that a measurement update uses: at most `max_beams`, evenly
/// spaced, below `min_range` dropped (decided once, as the scan enters).
#[derive(Debug, Clone, Default)]
pub struct ScanBeams {
    /// Sensor pose in the robot frame.
    pub sensor_pose: Pose2,
    /// (cos a, sin a, range) per used beam; a in the sensor frame, range in metres
    /// (`f64::INFINITY` for a no-return reading).
    pub beams: Vec<(f64, f64, f64)>,
}

impl ScanBeams {
    /// Picks the beams of `scan` for `config`: every ⌈n / max_beams⌉-th reading; readings
    /// at or beyond the scan's `max_range` or `config.max_range` are no-return (∞);
    /// non-finite or short readings are dropped.
    pub fn new(scan: &LaserScan, config: &SensorConfig) -> Self {
        let n = scan.len();
        let step = n.div_ceil(config.max_beams.max(1)).max(1);
        let limit = scan.max_range.min(config.max_range);
        let beams = (0..n)
            .step_by(step)
            .filter_map(|k| {
                let r = scan.ranges[k];
                if r.is_nan() || r < config.min_range {
                    return None;
                }
                let (s, c) = scan.beam_angle(k).sin_cos();
                if !(s.is_finite() && c.is_finite()) {
                    return None;
                }
                Some((c, s, if r >= limit { f64::INFINITY } else { r }))
            })
            .collect();
        Self {
            sensor_pose: scan.sensor_pose,
            beams,
        }
    }

    /// Number of beams used.
    pub fn len(&self) -> usize {
        self.beams.len()
    }

    /// True when no beam is usable.
    pub fn is_empty(&self) -> bool {
        self.beams.is_empty()
    }
}

/// ln p(z | x, m) of the scan at robot pose `pose` (before any exponent), and the number
/// of beams that entered it.
///
/// * Likelihood field (PR table 6.3): Σ ln(z_hit · N(d; 0, σ²) + z_rand / z_max) over the
///   end points of the readings with a return, d the distance from the end point to the
///   nearest obstacle (clamped to `max_distance`; outside the map, `max_distance`).
///   No-return readings are skipped, as PR's algorithm does.
/// * Beam model (PR table 6.1): Σ ln(z_hit · N(z; z*, σ²) + z_short · p_short + z_max ·
///   𝟙(z ≥ z_max) + z_rand / z_max · 𝟙(z < z_max)), z* the range cast on the map (z_max
///   when the beam meets no obstacle), p_short = λe^{−λz} / (1 − e^{−λz*}) for z < z*.
///   The Gaussian is not renormalised to [0, z_max] (η ≈ 1 for σ ≪ z*).
pub fn log_likelihood(
    map: &MclMap,
    config: &SensorConfig,
    beams: &ScanBeams,
    pose: &Pose2,
) -> (f64, usize) {
    let sensor = pose.compose(&beams.sensor_pose);
    let (s, c) = sensor.theta.sin_cos();
    let mut sum = 0.0;
    let mut used = 0;
    match config.model {
        SensorKind::LikelihoodField => {
            let params = map.likelihood_params();
            let field = map.field();
            for &(bc, bs, r) in &beams.beams {
                if !r.is_finite() {
                    continue;
                }
                let (dx, dy) = (c * bc - s * bs, s * bc + c * bs);
                let p = Point2::new(sensor.x + r * dx, sensor.y + r * dy);
                sum += params.log_likelihood(field.value_at(&p));
                used += 1;
            }
        }
        SensorKind::Beam => {
            const INV_SQRT_2PI: f64 = 0.398_942_280_401_432_7;
            let zmax = config.max_range;
            let sigma = config.sigma_hit;
            let lambda = config.lambda_short;
            let origin = sensor.translation();
            for &(bc, bs, r) in &beams.beams {
                let angle = sensor.theta + bs.atan2(bc);
                let expected = map.grid().cast_ray(&origin, angle, zmax).unwrap_or(zmax);
                let p = if !r.is_finite() {
                    config.z_max_weight
                } else {
                    let e = (r - expected) / sigma;
                    let hit = (-0.5 * e * e).exp() * INV_SQRT_2PI / sigma;
                    let short = if r < expected {
                        lambda * (-lambda * r).exp() / (1.0 - (-lambda * expected).exp()).max(1e-12)
                    } else {
                        0.0
                    };
                    config.z_hit * hit + config.z_short * short + config.z_rand / zmax
                };
                sum += p.max(1e-300).ln();
                used += 1;
            }
        }
    }
    (sum, used)
}
