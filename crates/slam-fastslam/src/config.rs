//! Configuration of the FastSLAM filters.

use crate::error::FastSlamError;
use serde::{Deserialize, Serialize};
use slam_models::measurement::RangeBearingModel;
use slam_models::motion::MotionModels;
use slam_models::particle::Resampler;

/// Which FastSLAM.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Variant {
    /// FastSLAM 1.0 (Montemerlo et al. 2002; PR table 13.1): poses sampled from the motion
    /// model, importance weight = measurement likelihood. Serialised as `"fastslam1"`.
    #[serde(rename = "fastslam1")]
    FastSlam1,
    /// FastSLAM 2.0 (Montemerlo et al. 2003; PR table 13.2/13.3): poses sampled from a
    /// proposal that includes the current measurements; works with a single particle.
    /// Serialised as `"fastslam2"`.
    #[serde(rename = "fastslam2")]
    #[default]
    FastSlam2,
}

/// How observations are matched to landmarks, per particle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Association {
    /// Use the observation's id when it has one, maximum likelihood when it has none.
    /// A dataset should give ids on all observations or on none: a filter-assigned key and a
    /// data id are both just keys and could collide in a mixed dataset.
    #[default]
    Auto,
    /// Always use the data's ids; observations without an id are rejected.
    Known,
    /// Ignore any ids; maximum likelihood with the new-landmark threshold `p0`
    /// (Montemerlo et al. 2002 §4; PR table 13.3).
    MaximumLikelihood,
}

/// Upper bound of [`FastSlamConfig::particles`]: 10⁵ particles, each with its own map of
/// landmarks, already cost gigabytes on a large map; 10⁹ would be an allocation abort.
pub const MAX_PARTICLES: usize = 100_000;

/// Upper bound of [`FastSlamConfig::max_landmarks`]: each landmark costs every particle that
/// holds it a small EKF and O(log N) tree nodes, so 10⁷ landmarks is already gigabytes.
pub const MAX_LANDMARKS: usize = 10_000_000;

/// FastSLAM settings. Every field has a documented default ([`FastSlamConfig::default`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct FastSlamConfig {
    /// FastSLAM 1.0 or 2.0. Default 2.0.
    pub variant: Variant,
    /// Number of particles M (1 ..= [`MAX_PARTICLES`]). Default 100.
    pub particles: usize,
    /// Motion noise (velocity and odometry models; PR tables 5.3/5.6). Default: the
    /// slam-models defaults.
    pub motion: MotionModels,
    /// Range-bearing sensor noise Q = diag(σr², σφ²). Default: σr = 0.1 m, σφ = 0.05 rad.
    pub sensor: RangeBearingModel,
    /// Data association. Default [`Association::Auto`].
    pub association: Association,
    /// New-landmark likelihood p0 (a density in the measurement space, 1/(m·rad)): under
    /// maximum-likelihood association an observation whose best likelihood is below p0
    /// starts a new landmark, and a new landmark contributes p0 to the importance weight
    /// (PR table 13.3 lines 12, 19). Default 1e-3.
    pub p0: f64,
    /// Resample only when N_eff < `resample_threshold`·M (0 < t ≤ 1). Default 0.5.
    pub resample_threshold: f64,
    /// Resampling scheme (slam-models). Default systematic.
    pub resampler: Resampler,
    /// Sensor range, metres, for negative evidence: landmarks predicted within it (and
    /// within the field of view) but not seen lose existence. `None` (default) disables
    /// negative evidence.
    pub max_range: Option<f64>,
    /// Full field of view of the sensor, radians, centred on the heading; `None` (default)
    /// means all around.
    pub fov: Option<f64>,
    /// Fraction of the range and of the half field of view kept free at the edges: a
    /// landmark counts as "expected in view" only inside (1 − margin)·range and
    /// (1 − margin)·fov/2, so noise at the boundary does not cost existence. Default 0.1.
    pub visibility_margin: f64,
    /// Existence counter of a new landmark. Default 1.
    pub existence_initial: i32,
    /// Upper bound of the existence counter (so a landmark that stops being seen does not
    /// survive forever). Default 20.
    pub existence_max: i32,
    /// A landmark is removed when its existence counter drops below this. Default 0 (a
    /// landmark seen once is gone after two steps in view without being seen).
    pub existence_threshold: i32,
    /// A landmark started by maximum-likelihood association is provisional until it has
    /// been observed `confirm_observations` times (its first sighting included); a
    /// provisional landmark not confirmed within `provisional_steps` updates is removed.
    /// This catches false alarms that leave the field of view before negative evidence
    /// could remove them. `provisional_steps` = 0 disables it. Defaults 2 and 5.
    pub confirm_observations: u32,
    /// See `confirm_observations`. Default 5.
    pub provisional_steps: u32,
    /// Maximum-likelihood association considers landmarks within this distance (metres) of
    /// the observation's inverse-mapped position. Default 3 m.
    pub association_radius: f64,
    /// Cell edge of each particle's spatial index, metres. Default 5 m.
    pub index_cell_size: f64,
    /// Most landmarks a particle's map may hold (1 ..= [`MAX_LANDMARKS`]): an update that
    /// could take a map past it (map size + observations) is refused with
    /// [`FastSlamError::TooManyLandmarks`] before anything changes, so clutter or a
    /// runaway association cannot grow memory without bound. Default 1,000,000.
    pub max_landmarks: usize,
}

impl Default for FastSlamConfig {
    fn default() -> Self {
        Self {
            variant: Variant::FastSlam2,
            particles: 100,
            motion: MotionModels::default(),
            sensor: RangeBearingModel::default(),
            association: Association::Auto,
            p0: 1e-3,
            resample_threshold: 0.5,
            resampler: Resampler::Systematic,
            max_range: None,
            fov: None,
            visibility_margin: 0.1,
            existence_initial: 1,
            existence_max: 20,
            existence_threshold: 0,
            confirm_observations: 2,
            provisional_steps: 5,
            association_radius: 3.0,
            index_cell_size: 5.0,
            max_landmarks: 1_000_000,
        }
    }
}

impl FastSlamConfig {
    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<(), FastSlamError> {
        fn bad(field: &'static str, value: impl ToString, expected: &'static str) -> FastSlamError {
            FastSlamError::InvalidConfig(slam_models::ConfigError::new(
                "FastSLAM",
                field,
                value.to_string(),
                expected,
            ))
        }
        if !(1..=MAX_PARTICLES).contains(&self.particles) {
            return Err(bad(
                "particles",
                self.particles,
                "1 ..= 100000 (MAX_PARTICLES)",
            ));
        }
        if !(1..=MAX_LANDMARKS).contains(&self.max_landmarks) {
            return Err(bad(
                "max_landmarks",
                self.max_landmarks,
                "1 ..= 10000000 (MAX_LANDMARKS)",
            ));
        }
        if !(self.p0.is_finite() && self.p0 > 0.0) {
            return Err(bad("p0", self.p0, "a finite density > 0"));
        }
        if !(self.resample_threshold > 0.0 && self.resample_threshold <= 1.0) {
            return Err(bad(
                "resample_threshold",
                self.resample_threshold,
                "in (0, 1]",
            ));
        }
        if let Some(r) = self.max_range {
            if !(r.is_finite() && r > 0.0) {
                return Err(bad("max_range", r, "a finite range > 0 m"));
            }
        }
        if let Some(f) = self.fov {
            if !(f.is_finite() && f > 0.0) {
                return Err(bad("fov", f, "a finite angle > 0 rad"));
            }
        }
        if !(0.0..1.0).contains(&self.visibility_margin) {
            return Err(bad(
                "visibility_margin",
                self.visibility_margin,
                "in [0, 1)",
            ));
        }
        if self.existence_max < self.existence_initial {
            return Err(bad(
                "existence_max",
                self.existence_max,
                "at least existence_initial",
            ));
        }
        if self.existence_initial < self.existence_threshold {
            return Err(bad(
                "existence_initial",
                self.existence_initial,
                "at least existence_threshold",
            ));
        }
        if !(self.association_radius.is_finite() && self.association_radius > 0.0) {
            return Err(bad(
                "association_radius",
                self.association_radius,
                "finite and > 0 m",
            ));
        }
        if !(self.index_cell_size.is_finite() && self.index_cell_size > 0.0) {
            return Err(bad(
                "index_cell_size",
                self.index_cell_size,
                "finite and > 0 m",
            ));
        }
        // The sensor's and the motion models' own checks (σ, `min-range`, every α,
        // `min-translation`), as the EKF and the graph make them.
        let named = |e: slam_models::ModelError| match e {
            slam_models::ModelError::OutOfRange {
                name,
                value,
                expected,
            } => bad(name, value, expected),
            other => FastSlamError::Model(other),
        };
        self.sensor.validate().map_err(named)?;
        self.motion.validate().map_err(named)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_valid_and_round_trips() {
        let c = FastSlamConfig::default();
        c.validate().unwrap();
        let s = serde_json::to_string(&c).unwrap();
        let back: FastSlamConfig = serde_json::from_str(&s).unwrap();
        assert_eq!(back, c);
        let partial: FastSlamConfig =
            serde_json::from_str(r#"{"variant":"fastslam1","particles":7}"#).unwrap();
        assert_eq!(partial.variant, Variant::FastSlam1);
        assert_eq!(partial.particles, 7);
        assert!(serde_json::from_str::<FastSlamConfig>(r#"{"particle":7}"#).is_err());
    }

    /// `particles = 10^9` used to be accepted and allocated.
    #[test]
    fn particle_count_is_capped() {
        let c = FastSlamConfig {
            particles: 1_000_000_000,
            ..Default::default()
        };
        let e = c.validate().unwrap_err();
        let FastSlamError::InvalidConfig(ref ce) = e else {
            panic!("{e:?}")
        };
        assert_eq!((ce.field, ce.value.as_str()), ("particles", "1000000000"));
        let e = e.to_string();
        assert!(
            e.contains("FastSLAM") && e.contains("particles = 1000000000") && e.contains("100000"),
            "{e}"
        );
        let c = FastSlamConfig {
            particles: MAX_PARTICLES,
            ..Default::default()
        };
        assert!(c.validate().is_ok());
    }

    #[test]
    fn rejects_bad_values() {
        for c in [
            FastSlamConfig {
                particles: 0,
                ..Default::default()
            },
            FastSlamConfig {
                p0: f64::NAN,
                ..Default::default()
            },
            FastSlamConfig {
                resample_threshold: 0.0,
                ..Default::default()
            },
            FastSlamConfig {
                max_range: Some(-1.0),
                ..Default::default()
            },
            FastSlamConfig {
                index_cell_size: 0.0,
                ..Default::default()
            },
        ] {
            assert!(matches!(c.validate(), Err(FastSlamError::InvalidConfig(_))));
        }
    }

    /// The sensor's `min-range` and the odometry model's `min-translation` are checked as
    /// the EKF checks them (FastSLAM checked σ and α by hand and took a NaN, infinite or
    /// negative `min-range` and `min-translation` with exit code 0); the error names the key.
    #[test]
    fn sensor_and_motion_keys_are_checked_by_name() {
        for (key, value) in [
            ("sensor.min-range", f64::NAN),
            ("sensor.min-range", f64::INFINITY),
            ("sensor.min-range", -1.0),
            ("motion.odometry.min-translation", f64::NAN),
            ("motion.odometry.min-translation", f64::INFINITY),
            ("motion.odometry.min-translation", -1.0),
            ("motion.odometry.alpha", -1.0),
        ] {
            let mut c = FastSlamConfig::default();
            match key {
                "sensor.min-range" => c.sensor.min_range = value,
                "motion.odometry.min-translation" => c.motion.odometry.min_translation = value,
                _ => c.motion.odometry.alpha[2] = value,
            }
            let e = c.validate().unwrap_err().to_string();
            assert!(e.contains(key), "{key} = {value}: {e}");
        }
    }
}
