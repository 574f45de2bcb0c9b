//! The simulated range-bearing sensor.

use super::world::LandmarkWorld;
use crate::error::{check_range, SimError};
use crate::rng::{normal, poisson};
use rand::Rng;
use serde::{Deserialize, Serialize};
use slam_models::detmath;
use slam_models::measurement::RangeBearingModel;
use slam_models::{normalize_angle, Pose2, RangeBearing};

/// A range-bearing sensor at the robot's origin, looking along its heading.
///
/// A landmark at true range r and bearing φ (PR eq. 6.40, via
/// [`RangeBearingModel::predict`]) is *visible* when `min_range ≤ r ≤ max_range` and
/// |φ| ≤ fov/2; each visible landmark is *detected* independently with probability
/// `detection_probability`, and reported as z = (r + ε_r, φ + ε_φ) with
/// ε_r ~ N(0, σr²), ε_φ ~ N(0, σφ²) (σ from `noise`), the bearing normalised to (−π, π] and
/// a (rare) negative noisy range clamped to 0. In addition, a Poisson(`clutter_rate`) number
/// of false alarms per scan is drawn uniformly over the footprint (the annular sector
/// min_range ≤ r ≤ max_range, |φ| ≤ fov/2, uniform in *area*: r = √(u·(R² − r₀²) + r₀²)).
/// With `hide_ids` every observation has `id: None`.
///
/// # Example
///
/// ```
/// use rand::SeedableRng;
/// use slam_models::{LandmarkId, Point2, Pose2};
/// use slam_sim::landmark::{LandmarkWorld, RangeBearingSensor};
/// let world = LandmarkWorld::new(vec![(LandmarkId(7), Point2::new(3.0, 0.0))], 6.0).unwrap();
/// let sensor = RangeBearingSensor::default(); // σr 0.1 m, σφ 1.5°, 0.5–6 m, 180°
/// let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(1);
/// let mut clutter_rng = rand_pcg::Pcg64Mcg::seed_from_u64(2);
/// let (mut scratch, mut obs) = (Vec::new(), Vec::new());
/// sensor.observe(&Pose2::new(0.0, 0.0, 0.0), &world, &mut rng, &mut clutter_rng, &mut scratch, &mut obs);
/// assert_eq!(obs.len(), 1);
/// let (z, is_clutter) = obs[0];
/// assert!(!is_clutter && z.id == Some(LandmarkId(7)) && (z.range - 3.0).abs() < 0.6);
/// ```
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct RangeBearingSensor {
    /// Noise standard deviations (σr in metres, σφ in radians); the same struct the filters use.
    pub noise: RangeBearingModel,
    /// Largest range at which landmarks are seen, metres.
    pub max_range: f64,
    /// Smallest range at which landmarks are seen, metres (> 0 keeps the bearing defined).
    pub min_range: f64,
    /// Full field of view, radians, centred on the heading (2π = all around).
    pub fov: f64,
    /// Probability that a visible landmark is reported, in [0, 1].
    pub detection_probability: f64,
    /// Mean number of false alarms per scan (Poisson rate λ ≥ 0).
    pub clutter_rate: f64,
    /// Report `id: None` for every observation (unknown data association).
    pub hide_ids: bool,
}

impl Default for RangeBearingSensor {
    /// σr = 0.1 m, σφ = 1.5° (0.0262 rad), range 0.5–6 m, 180° field of view, every visible
    /// landmark detected, no clutter, ids reported.
    fn default() -> Self {
        Self {
            noise: RangeBearingModel::new(0.1, 1.5f64.to_radians()),
            max_range: 6.0,
            min_range: 0.5,
            fov: std::f64::consts::PI,
            detection_probability: 1.0,
            clutter_rate: 0.0,
            hide_ids: false,
        }
    }
}

impl RangeBearingSensor {
    /// Rejects NaN/∞ and out-of-range settings.
    pub fn validate(&self) -> Result<(), SimError> {
        check_range(
            "sigma_range",
            self.noise.sigma_range,
            0.0,
            1e3,
            "0 <= sigma_range <= 1000 m",
        )?;
        check_range(
            "sigma_bearing",
            self.noise.sigma_bearing,
            0.0,
            10.0,
            "0 <= sigma_bearing <= 10 rad",
        )?;
        check_range(
            "max_range",
            self.max_range,
            1e-6,
            1e5,
            "0 < max_range <= 1e5 m",
        )?;
        check_range(
            "min_range",
            self.min_range,
            0.0,
            self.max_range,
            "0 <= min_range <= max_range",
        )?;
        check_range(
            "fov",
            self.fov,
            0.0,
            2.0 * std::f64::consts::PI,
            "0 <= fov <= 2π rad",
        )?;
        check_range(
            "detection_probability",
            self.detection_probability,
            0.0,
            1.0,
            "a probability in [0, 1]",
        )?;
        check_range(
            "clutter_rate",
            self.clutter_rate,
            0.0,
            1e4,
            "0 <= clutter_rate <= 1e4 per scan",
        )?;
        Ok(())
    }

    /// True when a landmark at true (range, bearing) is in the footprint.
    #[inline]
    pub fn in_footprint(&self, range: f64, bearing: f64) -> bool {
        range >= self.min_range && range <= self.max_range && bearing.abs() <= 0.5 * self.fov
    }

    /// Area of the footprint, m² (the annular sector): fov/2 · (R² − r₀²).
    pub fn footprint_area(&self) -> f64 {
        0.5 * self.fov * (self.max_range * self.max_range - self.min_range * self.min_range)
    }

    /// One scan from `pose`: appends `(observation, is_clutter)` pairs to `out` (cleared
    /// first), sorted by bearing so that the order carries no identity information.
    ///
    /// Randomness: detections and noise come from `rng` in ascending landmark-index order,
    /// clutter from `clutter_rng`, so a change of the clutter rate leaves the true detections
    /// of a seed unchanged. `scratch` is a reusable buffer.
    pub fn observe<R: Rng + ?Sized, C: Rng + ?Sized>(
        &self,
        pose: &Pose2,
        world: &LandmarkWorld,
        rng: &mut R,
        clutter_rng: &mut C,
        scratch: &mut Vec<usize>,
        out: &mut Vec<(RangeBearing, bool)>,
    ) {
        out.clear();
        world.within(&pose.translation(), self.max_range, scratch);
        let (sr, sb) = (self.noise.sigma_range, self.noise.sigma_bearing);
        for &i in scratch.iter() {
            let (id, m) = world.landmarks()[i];
            let dx = m.x - pose.x;
            let dy = m.y - pose.y;
            let r = detmath::hypot(dx, dy);
            let b = normalize_angle(detmath::atan2(dy, dx) - pose.theta);
            if !self.in_footprint(r, b) {
                continue;
            }
            // The detection draw is made for every visible landmark, even with p = 1, so
            // that the noise stream does not depend on the detection probability.
            let u: f64 = rng.random();
            let (er, eb) = (normal(rng) * sr, normal(rng) * sb);
            if u >= self.detection_probability {
                continue;
            }
            out.push((
                RangeBearing {
                    range: (r + er).max(0.0),
                    bearing: normalize_angle(b + eb),
                    id: (!self.hide_ids).then_some(id),
                },
                false,
            ));
        }
        let n_clutter = poisson(self.clutter_rate, clutter_rng);
        let (r0, r1) = (self.min_range, self.max_range);
        for _ in 0..n_clutter {
            let u: f64 = clutter_rng.random();
            let v: f64 = clutter_rng.random();
            let r = (u * (r1 * r1 - r0 * r0) + r0 * r0).sqrt();
            let b = (v - 0.5) * self.fov;
            out.push((
                RangeBearing {
                    range: r,
                    bearing: normalize_angle(b),
                    id: None,
                },
                true,
            ));
        }
        out.sort_by(|a, b| {
            a.0.bearing
                .total_cmp(&b.0.bearing)
                .then(a.0.range.total_cmp(&b.0.range))
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::stream;
    use slam_models::{LandmarkId, Point2};

    /// A ring of landmarks at 4 m around the origin, every 10°.
    fn ring() -> LandmarkWorld {
        let lms = (0..36)
            .map(|k| {
                let a = (k as f64 * 10.0 + 5.0).to_radians();
                (LandmarkId(k), Point2::new(4.0 * a.cos(), 4.0 * a.sin()))
            })
            .collect();
        LandmarkWorld::new(lms, 5.0).unwrap()
    }

    #[test]
    fn noise_detection_and_clutter_statistics() {
        let world = ring();
        let sensor = RangeBearingSensor {
            noise: RangeBearingModel::new(0.2, 0.03),
            detection_probability: 0.8,
            clutter_rate: 1.5,
            fov: std::f64::consts::PI, // 18 of the 36 landmarks visible
            ..Default::default()
        };
        let pose = Pose2::new(0.0, 0.0, 0.0);
        let (mut rng, mut crng) = (stream(1, 10), stream(1, 11));
        let (mut scratch, mut out) = (Vec::new(), Vec::new());
        let scans = 20_000;
        let (mut n_det, mut n_clut) = (0usize, 0usize);
        let (mut sr, mut sr2, mut sb, mut sb2) = (0.0, 0.0, 0.0, 0.0);
        let mut clutter_r2 = 0.0;
        for _ in 0..scans {
            sensor.observe(&pose, &world, &mut rng, &mut crng, &mut scratch, &mut out);
            for (z, is_clutter) in &out {
                if *is_clutter {
                    n_clut += 1;
                    clutter_r2 += z.range * z.range;
                    assert!(sensor.in_footprint(z.range, z.bearing));
                    continue;
                }
                n_det += 1;
                let id = z.id.unwrap().0;
                let truth = (id as f64 * 10.0 + 5.0).to_radians();
                let (er, eb) = (z.range - 4.0, normalize_angle(z.bearing - truth));
                sr += er;
                sr2 += er * er;
                sb += eb;
                sb2 += eb * eb;
            }
        }
        // Detections: Binomial(18·scans, 0.8).
        let trials = 18.0 * scans as f64;
        let p = 0.8;
        let sd = (trials * p * (1.0 - p)).sqrt();
        assert!(
            (n_det as f64 - trials * p).abs() < 5.0 * sd,
            "detections {n_det}"
        );
        // Clutter count: Poisson(1.5·scans).
        let lam = 1.5 * scans as f64;
        assert!(
            (n_clut as f64 - lam).abs() < 5.0 * lam.sqrt(),
            "clutter {n_clut}"
        );
        // Uniform in area: E[r²] = (R² + r₀²)/2; Var[r²] = (R² − r₀²)²/12.
        let (r0, r1) = (sensor.min_range, sensor.max_range);
        let e = (r1 * r1 + r0 * r0) / 2.0;
        let sd_r2 = (r1 * r1 - r0 * r0) / 12f64.sqrt() / (n_clut as f64).sqrt();
        assert!((clutter_r2 / n_clut as f64 - e).abs() < 5.0 * sd_r2);
        // Noise: mean within 5 standard errors of 0; variance within 5 s.e. of σ²
        // (s.e. of a Gaussian sample variance: σ²·√(2/n)).
        let n = n_det as f64;
        for (s, s2, sigma) in [(sr, sr2, 0.2), (sb, sb2, 0.03)] {
            let mean = s / n;
            let var = s2 / n - mean * mean;
            assert!(mean.abs() < 5.0 * sigma / n.sqrt(), "mean {mean}");
            assert!(
                (var - sigma * sigma).abs() < 5.0 * sigma * sigma * (2.0 / n).sqrt(),
                "var {var}"
            );
        }
    }

    #[test]
    fn field_of_view_range_and_hidden_ids() {
        let world = ring();
        let sensor = RangeBearingSensor {
            noise: RangeBearingModel::new(0.0, 0.0),
            fov: 60f64.to_radians(),
            hide_ids: true,
            ..Default::default()
        };
        let (mut rng, mut crng) = (stream(2, 10), stream(2, 11));
        let (mut scratch, mut out) = (Vec::new(), Vec::new());
        // Facing +y: landmarks at 65°..115° are inside ±30° of 90°: 65, 75, 85, 95, 105, 115.
        let pose = Pose2::new(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        sensor.observe(&pose, &world, &mut rng, &mut crng, &mut scratch, &mut out);
        assert_eq!(out.len(), 6);
        assert!(out
            .iter()
            .all(|(z, c)| z.id.is_none() && !c && (z.range - 4.0).abs() < 1e-12));
        assert!(out.windows(2).all(|w| w[0].0.bearing <= w[1].0.bearing));
        // Too far: nothing within 6 m of (20, 0).
        sensor.observe(
            &Pose2::new(20.0, 0.0, 0.0),
            &world,
            &mut rng,
            &mut crng,
            &mut scratch,
            &mut out,
        );
        assert!(out.is_empty());
        let bad = RangeBearingSensor {
            detection_probability: 1.5,
            ..Default::default()
        };
        assert!(bad.validate().is_err());
    }
}
