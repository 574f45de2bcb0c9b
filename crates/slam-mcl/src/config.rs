//! The configuration of Monte Carlo localization, with documented defaults
//! (`configs/mcl.toml` is the same as a file).

use serde::{Deserialize, Serialize};
use slam_models::error::ensure_config;
use slam_models::motion::OdometryModel;
use slam_models::ConfigError;

/// Which measurement model weighs the particles (Probabilistic Robotics ch. 6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SensorKind {
    /// The likelihood field ("end point") model, PR §6.4 table 6.3: each end point scored by
    /// its distance to the nearest obstacle (slam-grid's exact distance transform). Smooth
    /// and cheap (one look-up per beam); the default, as in nav2 AMCL.
    #[default]
    LikelihoodField,
    /// The beam model, PR §6.3 table 6.1: each range compared with the range z* cast on the
    /// map from the particle (slam-grid's Amanatides–Woo walk), a mixture of a Gaussian
    /// hit, an exponential short reading, a max-range spike and a uniform.
    Beam,
}

/// The measurement model's parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct SensorConfig {
    /// Which model. Default `likelihood-field`.
    pub model: SensorKind,
    /// Beams used per scan, evenly spaced over the scan (PR §6.6: beams are not
    /// independent; fewer beams keep the posterior from being over-confident). Default 60.
    pub max_beams: usize,
    /// σ_hit, metres: the Gaussian of a hit about the map's obstacle (both models).
    /// Default 0.1 m.
    pub sigma_hit: f64,
    /// z_hit: weight of the hit component. Default 0.9.
    pub z_hit: f64,
    /// z_rand: weight of the uniform component over [0, z_max]. Default 0.1.
    pub z_rand: f64,
    /// z_short (beam model only): weight of unexpected short readings. Default 0.05.
    pub z_short: f64,
    /// z_max (beam model only): weight of the max-range readings. Default 0.05.
    pub z_max_weight: f64,
    /// λ_short (beam model only), 1/m: decay of the short readings. Default 0.1.
    pub lambda_short: f64,
    /// Readings at or beyond this (metres), and beyond the scan's own `max_range`, are
    /// "no return": the likelihood field skips them, the beam model scores them with
    /// z_max. Also z_max of the uniform component. Default 30 m.
    pub max_range: f64,
    /// Readings below this (metres) are skipped (the robot's own body). Default 0.05 m.
    pub min_range: f64,
    /// The likelihood field is exact up to this distance from an obstacle (metres) and
    /// constant beyond (nav2's `laser_likelihood_max_dist`); a longer reach gives a
    /// converging global cloud a slope to follow. Default 1.0 m.
    pub max_distance: f64,
    /// Each scan's log-likelihood is multiplied by this (a power 0 < k ≤ 1 on p(z | x, m)):
    /// the usual correction for beams that are not independent (PR §6.6, "inflate the
    /// noise"). Default 0.2 (on Intel with 60 beams, 1.0 left N_eff at 2–20 of 500 particles
    /// and a global cloud collapsed onto one particle at the first scan).
    pub weight_exponent: f64,
    /// Adaptive tempering: when the scan weighed with `weight_exponent` would leave fewer
    /// than this fraction of the particles effective (N_eff / N), the exponent is lowered
    /// for this update to the largest k ≤ `weight_exponent` that keeps N_eff ≥ this · N
    /// (bisection; likelihood tempering as in Del Moral et al. 2006's adaptive SMC
    /// samplers, the rest of the scan's evidence dropped). This stops a sparse global cloud
    /// from collapsing at the first scans onto whichever particle happens to lie nearest a
    /// plausible pose. 0 switches it off. Default 0.03 (0.1 kept random particles of a
    /// recovery heavy enough to widen a converged Intel cloud past 0.5 m at 419 m).
    pub min_n_eff_ratio: f64,
    /// The same floor while a global start converges (`MclConfig::converge_min_travel`);
    /// the larger of the two applies then. A global cloud holds several look-alike places
    /// at once; a higher floor keeps any one scan from deciding between them by sampling
    /// luck before the robot has seen what tells them apart. 0 = `min_n_eff_ratio` only.
    /// Default 0.1 (the 0.03 afterwards keeps a recovery's random particles light).
    pub global_min_n_eff_ratio: f64,
}

impl Default for SensorConfig {
    fn default() -> Self {
        Self {
            model: SensorKind::LikelihoodField,
            max_beams: 60,
            sigma_hit: 0.1,
            z_hit: 0.9,
            z_rand: 0.1,
            z_short: 0.05,
            z_max_weight: 0.05,
            lambda_short: 0.1,
            max_range: 30.0,
            min_range: 0.05,
            max_distance: 1.0,
            weight_exponent: 0.2,
            min_n_eff_ratio: 0.03,
            global_min_n_eff_ratio: 0.1,
        }
    }
}

/// KLD-sampling (Fox 2003; PR table 8.4): the number of particles drawn at each resampling
/// is the smallest n for which, with probability 1 − δ, the KL divergence between the
/// particle approximation and the true posterior is below ε, given the k histogram bins
/// the particles occupy:
///
/// ```text
/// n = (k − 1)/(2ε) · (1 − 2/(9(k − 1)) + √(2/(9(k − 1))) · z_{1−δ})³
/// ```
///
/// clamped to [`min_particles`, `max_particles`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct KldConfig {
    /// Fewest particles. Default 500 (nav2: 500).
    pub min_particles: usize,
    /// Most particles; global localization starts with this many. Default 20000 (nav2:
    /// 2000): Acapulco has 4,100 m² of free space, 5 particles per m², and with 5000 the
    /// global cloud settled on a wrong place on 3 of 7 bench logs.
    pub max_particles: usize,
    /// ε, the bound on the KL divergence. Default 0.05 (nav2 `pf_err`: 0.05).
    pub epsilon: f64,
    /// z_{1−δ}, the upper standard-normal quantile of the confidence 1 − δ. Default 2.33
    /// (δ = 0.01, nav2 `pf_z`: 0.99).
    pub z_quantile: f64,
    /// Bin edge in x and y, metres. Default 0.5 m (nav2's).
    pub bin_xy: f64,
    /// Bin edge in θ, radians. Default 10° (nav2's).
    pub bin_theta: f64,
    /// A cluster of particles (connected occupied bins) holding at least this fraction of
    /// the weight is a mode: it is counted (`StepInfo::modes`) and kept alive at
    /// resampling (clustered particle filtering, Milstein et al. 2002). Default 0.01.
    pub mode_min_mass: f64,
    /// Particles each mode keeps at a resampling at least (drawn from its own by weight,
    /// each cluster's mass kept), as far as `max_particles` leaves room: the count never
    /// passes `max_particles`. Default 100.
    pub mode_particles: usize,
    /// At most this many modes (the heaviest) are kept so. Default 8.
    pub max_modes: usize,
}

impl Default for KldConfig {
    fn default() -> Self {
        Self {
            min_particles: 500,
            max_particles: 20000,
            epsilon: 0.05,
            z_quantile: 2.33,
            bin_xy: 0.5,
            bin_theta: 10f64.to_radians(),
            mode_min_mass: 0.01,
            mode_particles: 100,
            max_modes: 8,
        }
    }
}

/// Augmented MCL (PR table 8.3): short- and long-term averages of the measurement
/// likelihood, w_fast and w_slow, and at each resampling every particle replaced by one
/// drawn uniformly from the free space with probability max(0, 1 − w_fast/w_slow).
/// 0 < α_slow ≪ α_fast ≤ 1; both 0 switch recovery off.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct RecoveryConfig {
    /// α_slow. Default 0.001 (nav2's suggested value; its default 0 switches recovery off).
    pub alpha_slow: f64,
    /// α_fast. Default 0.1 (nav2's suggested value).
    pub alpha_fast: f64,
}

impl Default for RecoveryConfig {
    fn default() -> Self {
        Self {
            alpha_slow: 0.001,
            alpha_fast: 0.1,
        }
    }
}

/// Monte Carlo localization: motion, measurement, particle count, recovery, and when to
/// update and resample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct MclConfig {
    /// The odometry motion model (PR table 5.6) the particles move with. Default
    /// α = (0.05, 0.01, 0.05, 0.01)… see [`MclConfig::default`].
    pub motion: OdometryModel,
    /// The measurement model.
    pub sensor: SensorConfig,
    /// KLD-sampling bounds.
    pub kld: KldConfig,
    /// Augmented MCL.
    pub recovery: RecoveryConfig,
    /// The filter updates only once the odometry moved this far (metres) since the last
    /// update… Default 0.2 m (nav2 `update_min_d`: 0.25).
    pub update_min_d: f64,
    /// …or turned this much (radians). Default 0.2 rad (nav2 `update_min_a`: 0.2).
    pub update_min_a: f64,
    /// Roughening (Gordon, Salmond & Smith 1993, §4): each particle copied at a
    /// resampling is jittered by a zero-mean Gaussian with σ = `roughening` · E · N^(−1/3)
    /// per axis, E the weighted standard deviation of the cloud along that axis before
    /// resampling (x, y in metres; θ as the circular deviation √(−2 ln R)), N the count
    /// drawn. A wide global cloud keeps exploring around its copies so that one near the
    /// true pose can climb into the likelihood's basin; a converged cloud is hardly
    /// touched (spread 0.1 m, 500 particles: σ ≈ 2 mm at 0.2). 0 switches it off.
    /// Default 0.2 (Gordon et al.'s K).
    pub roughening: f64,
    /// Resample when N_eff < `resample_ratio` · N (N_eff = 1/Σw²; Liu 1996), or when
    /// recovery wants random particles. Default 0.5.
    pub resample_ratio: f64,
    /// Cells of the map with an occupancy value (percent) at most this are free space,
    /// where global and random particles are drawn. Default 19 (map_server's free
    /// threshold 0.196).
    pub free_max: i8,
    /// The map prior p(x | m) of a pose outside the free space (an occupied or unknown
    /// cell) relative to one in it: each particle's weight is multiplied by this when its
    /// position is not in a free cell (PR §8.3.1: the robot cannot stand inside a wall or
    /// where it has never been). It also multiplies the particle's term of augmented MCL's
    /// average likelihood, so a cloud that drifted out of the map looks lost. 1 switches
    /// the prior off. Default 1e-6.
    pub not_free_weight: f64,
    /// Evidence from one place counted once (global start only): until the filter has
    /// converged (see `converge_min_travel`), each update's likelihood exponent is
    /// multiplied by min(1, d / `evidence_distance`), d the odometry translation (metres)
    /// since the previous update; the first scan counts in full. Scans taken while the
    /// robot turns in place see the same walls from the same point, and their errors (map
    /// errors, people, furniture) are shared, so weighing each as new evidence makes a
    /// look-alike room win before the robot has driven anywhere. With the tempering, k
    /// updates from one place weigh about as one scan, plus what the translation added.
    /// 0 switches it off. Default 0.5 m.
    pub evidence_distance: f64,
    /// A global start counts as converged (and `evidence_distance` stops applying) once
    /// the robot has travelled at least this far (metres of odometry) since the start and
    /// the heaviest cluster holds at least `converge_mode_mass` of the weight. Default 2 m.
    pub converge_min_travel: f64,
    /// See `converge_min_travel`: the weight the heaviest cluster must hold. Default 0.9.
    pub converge_mode_mass: f64,
}

impl Default for MclConfig {
    /// The motion noise α = (0.05, 0.01, 0.05, 0.01) (PR table 5.6 variances; about 22 %
    /// of the rotation and translation as one σ, wider than the SLAM filters' because the
    /// map cannot adapt to the robot).
    fn default() -> Self {
        Self {
            motion: OdometryModel::new([0.05, 0.01, 0.05, 0.01]),
            sensor: SensorConfig::default(),
            kld: KldConfig::default(),
            recovery: RecoveryConfig::default(),
            update_min_d: 0.2,
            update_min_a: 0.2,
            resample_ratio: 0.5,
            roughening: 0.2,
            free_max: 19,
            not_free_weight: 1e-6,
            evidence_distance: 0.2,
            converge_min_travel: 5.0,
            converge_mode_mass: 0.9,
        }
    }
}

const C: &str = "MCL";

impl MclConfig {
    /// Checks every bound; the error names the field (`kld.max-particles`, …).
    pub fn validate(&self) -> Result<(), ConfigError> {
        for a in self.motion.alpha {
            ensure_config(a >= 0.0, C, "motion.alpha", a, "finite and >= 0")?;
        }
        let t = self.motion.min_translation;
        ensure_config(
            (0.0..=slam_models::motion::MAX_MIN_TRANSLATION).contains(&t),
            C,
            "motion.min_translation",
            t,
            "in [0, 1] m (a step shorter than this is taken as a turn in place)",
        )?;
        let s = &self.sensor;
        ensure_config(
            s.max_beams >= 1,
            C,
            "sensor.max_beams",
            s.max_beams as f64,
            ">= 1",
        )?;
        ensure_config(
            s.sigma_hit > 0.0,
            C,
            "sensor.sigma_hit",
            s.sigma_hit,
            "> 0 m",
        )?;
        ensure_config(s.z_hit > 0.0, C, "sensor.z_hit", s.z_hit, "> 0")?;
        ensure_config(s.z_rand >= 0.0, C, "sensor.z_rand", s.z_rand, ">= 0")?;
        ensure_config(s.z_short >= 0.0, C, "sensor.z_short", s.z_short, ">= 0")?;
        ensure_config(
            s.z_max_weight >= 0.0,
            C,
            "sensor.z_max_weight",
            s.z_max_weight,
            ">= 0",
        )?;
        ensure_config(
            s.lambda_short > 0.0,
            C,
            "sensor.lambda_short",
            s.lambda_short,
            "> 0 per m",
        )?;
        ensure_config(
            s.max_range > 0.0,
            C,
            "sensor.max_range",
            s.max_range,
            "> 0 m",
        )?;
        ensure_config(
            s.min_range >= 0.0 && s.min_range < s.max_range,
            C,
            "sensor.min_range",
            s.min_range,
            ">= 0 m and below max-range",
        )?;
        ensure_config(
            s.max_distance > 0.0,
            C,
            "sensor.max_distance",
            s.max_distance,
            "> 0 m",
        )?;
        ensure_config(
            s.weight_exponent > 0.0 && s.weight_exponent <= 1.0,
            C,
            "sensor.weight_exponent",
            s.weight_exponent,
            "in (0, 1]",
        )?;
        ensure_config(
            (0.0..1.0).contains(&s.min_n_eff_ratio),
            C,
            "sensor.min_n_eff_ratio",
            s.min_n_eff_ratio,
            "in [0, 1)",
        )?;
        ensure_config(
            (0.0..1.0).contains(&s.global_min_n_eff_ratio),
            C,
            "sensor.global_min_n_eff_ratio",
            s.global_min_n_eff_ratio,
            "in [0, 1)",
        )?;
        let k = &self.kld;
        ensure_config(
            k.min_particles >= 1,
            C,
            "kld.min_particles",
            k.min_particles as f64,
            ">= 1",
        )?;
        ensure_config(
            k.max_particles >= k.min_particles && k.max_particles <= 1_000_000,
            C,
            "kld.max_particles",
            k.max_particles as f64,
            ">= min-particles and <= 1000000",
        )?;
        ensure_config(
            k.epsilon > 0.0 && k.epsilon < 1.0,
            C,
            "kld.epsilon",
            k.epsilon,
            "in (0, 1)",
        )?;
        ensure_config(k.z_quantile > 0.0, C, "kld.z_quantile", k.z_quantile, "> 0")?;
        ensure_config(k.bin_xy > 0.0, C, "kld.bin_xy", k.bin_xy, "> 0 m")?;
        ensure_config(
            k.bin_theta > 0.0,
            C,
            "kld.bin_theta",
            k.bin_theta,
            "> 0 rad",
        )?;
        ensure_config(
            k.mode_min_mass > 0.0 && k.mode_min_mass <= 1.0,
            C,
            "kld.mode_min_mass",
            k.mode_min_mass,
            "in (0, 1]",
        )?;
        ensure_config(
            k.mode_particles <= k.max_particles,
            C,
            "kld.mode_particles",
            k.mode_particles as f64,
            "<= max-particles",
        )?;
        ensure_config(
            k.max_modes <= 1000,
            C,
            "kld.max_modes",
            k.max_modes as f64,
            "<= 1000",
        )?;
        let r = &self.recovery;
        ensure_config(
            (0.0..=1.0).contains(&r.alpha_slow),
            C,
            "recovery.alpha_slow",
            r.alpha_slow,
            "in [0, 1]",
        )?;
        ensure_config(
            (0.0..=1.0).contains(&r.alpha_fast)
                && (r.alpha_fast > r.alpha_slow || r.alpha_fast == 0.0),
            C,
            "recovery.alpha_fast",
            r.alpha_fast,
            "in [0, 1] and above alpha-slow (or both 0)",
        )?;
        ensure_config(
            self.update_min_d >= 0.0,
            C,
            "update_min_d",
            self.update_min_d,
            ">= 0 m",
        )?;
        ensure_config(
            self.update_min_a >= 0.0,
            C,
            "update_min_a",
            self.update_min_a,
            ">= 0 rad",
        )?;
        ensure_config(
            (0.0..=1.0).contains(&self.resample_ratio),
            C,
            "resample_ratio",
            self.resample_ratio,
            "in [0, 1]",
        )?;
        ensure_config(
            (0..100).contains(&self.free_max),
            C,
            "free_max",
            self.free_max as f64,
            "in 0 … 99",
        )?;
        ensure_config(
            (0.0..=10.0).contains(&self.roughening),
            C,
            "roughening",
            self.roughening,
            "in [0, 10]",
        )?;
        ensure_config(
            self.not_free_weight > 0.0 && self.not_free_weight <= 1.0,
            C,
            "not_free_weight",
            self.not_free_weight,
            "in (0, 1]",
        )?;
        ensure_config(
            self.evidence_distance >= 0.0,
            C,
            "evidence_distance",
            self.evidence_distance,
            "finite and >= 0 m",
        )?;
        ensure_config(
            self.converge_min_travel >= 0.0,
            C,
            "converge_min_travel",
            self.converge_min_travel,
            "finite and >= 0 m",
        )?;
        ensure_config(
            self.converge_mode_mass > 0.0 && self.converge_mode_mass <= 1.0,
            C,
            "converge_mode_mass",
            self.converge_mode_mass,
            "in (0, 1]",
        )?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// configs/mcl.toml spells out every default, key by key.
    #[test]
    fn the_example_file_is_the_defaults() {
        let text = include_str!("../../../configs/mcl.toml");
        let parsed: MclConfig = toml::from_str(text).unwrap();
        assert_eq!(parsed, MclConfig::default());
        // Every key is in the file: a table written from the defaults has no key the file
        // lacks.
        let written = toml::to_string(&MclConfig::default()).unwrap();
        let keys = |t: &str| -> Vec<String> {
            t.lines()
                .filter_map(|l| l.split_once('=').map(|(k, _)| k.trim().to_string()))
                .filter(|k| !k.starts_with('#'))
                .collect()
        };
        let in_file = keys(text);
        for k in keys(&written) {
            assert!(in_file.contains(&k), "configs/mcl.toml lacks `{k}`");
        }
        assert!(toml::from_str::<MclConfig>("update-min-dd = 1").is_err());
    }

    #[test]
    fn bounds_name_their_field() {
        let mut c = MclConfig::default();
        c.kld.max_particles = 10;
        assert_eq!(c.validate().unwrap_err().key(), "kld.max-particles");
        let mut c = MclConfig::default();
        c.sensor.weight_exponent = 0.0;
        assert_eq!(c.validate().unwrap_err().key(), "sensor.weight-exponent");
        let mut c = MclConfig::default();
        c.recovery.alpha_fast = 0.0005;
        assert_eq!(c.validate().unwrap_err().key(), "recovery.alpha-fast");
        // `motion.min-translation` was not checked: `inf` took every step as a turn in
        // place, NaN and negative values were taken as they were.
        for bad in [f64::INFINITY, f64::NAN, -1.0, 2.0] {
            let mut c = MclConfig::default();
            c.motion.min_translation = bad;
            assert_eq!(
                c.validate().unwrap_err().key(),
                "motion.min-translation",
                "{bad}"
            );
        }
        assert!(MclConfig::default().validate().is_ok());
    }
}
