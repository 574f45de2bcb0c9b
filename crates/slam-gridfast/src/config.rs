//! The configuration of [`crate::GridFastSlam`].

use crate::error::GridFastError;
use serde::{Deserialize, Serialize};
use slam_models::motion::OdometryModel;
use slam_models::particle::Resampler;

/// How each particle draws its new pose at a processed scan.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Proposal {
    /// Sample from the odometry motion model p(xₜ | xₜ₋₁, uₜ) (PR table 5.6) and weight by
    /// the scan likelihood p(zₜ | xₜ, mₜ₋₁): the plain FastSLAM 1.0 proposal on grids.
    Odometry,
    /// Odometry pre-corrected by scan matching (Hähnel, Burgard, Fox & Thrun, IROS 2003): the
    /// scan is matched once against the best particle's map, the matched motion replaces the
    /// raw odometry increment, and every particle samples from the motion model around the
    /// corrected increment with its noise scaled by
    /// [`GridFastConfig::corrected_odometry_noise_scale`]; weights by the scan likelihood.
    ScanMatchedOdometry,
    /// The improved proposal (Grisetti, Stachniss & Burgard, T-RO 2007, §IV and Table I):
    /// each particle matches the scan against its own map, evaluates K poses around the
    /// mode, fits N(μ, Σ) to likelihood × motion model over them (eqs. 14–15), **samples**
    /// its new pose from that Gaussian and multiplies its weight by η = Σⱼ τ(xⱼ) (eq. 18).
    #[default]
    Improved,
}

/// Upper bound of [`GridFastConfig::particles`]: every particle carries its own map, so
/// 10⁴ particles already need gigabytes on a building-sized map (GMapping runs 30–100);
/// 10⁹ would be an allocation abort.
pub const MAX_PARTICLES: usize = 10_000;

/// Configuration of grid-based FastSLAM. Lengths in metres, angles in radians.
///
/// Defaults follow GMapping's ROS defaults where GMapping has the parameter (particles 30,
/// 5 cm cells, `linearUpdate` 1.0 m, `angularUpdate` 0.5 rad, resampling threshold 0.5,
/// K = 3³ samples within ±1 cm / ±0.005 rad, likelihood gain 3).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GridFastConfig {
    /// Number of particles M (1 ..= [`MAX_PARTICLES`]). Default 30.
    pub particles: usize,
    /// Proposal distribution. Default [`Proposal::Improved`].
    pub proposal: Proposal,
    /// Cell edge length of every particle's map, metres. Default 0.05.
    pub resolution: f64,
    /// Run a filter update once the robot travelled this far (path length of the odometry
    /// since the last update), metres. Default 1.0 (GMapping `linearUpdate`).
    pub linear_update: f64,
    /// … or turned this much (sum of |Δθ| of the odometry since the last update), radians.
    /// Default 0.5 (GMapping `angularUpdate`).
    pub angular_update: f64,
    /// When true, the motion that triggers an update is summed from scan record to scan
    /// record only (the odometry at scan times, as a ROS node sees it); when false, over
    /// the odometry of every record (GMapping's `processScan`, which sums |Δodometry| over
    /// every laser reading of a raw log). Default false.
    pub accumulate_per_scan: bool,
    /// Resample when N_eff < `resample_threshold`·M (Grisetti et al. 2007 §V). Default 0.5.
    pub resample_threshold: f64,
    /// Resampling scheme (slam-models). Default systematic.
    pub resampler: Resampler,
    /// Odometry motion model (PR table 5.6) used between processed scans. Default
    /// α = (0.05, 0.002, 0.02, 0.002): 22 % of a rotation, 4.5 cm of heading per metre as
    /// rotation noise; 14 % of the translation as translation noise.
    pub motion: OdometryModel,
    /// Standard deviations added (in quadrature) to the motion model's position and heading
    /// noise so that its covariance stays positive definite for near-zero motion,
    /// (metres, radians). Default (0.01, 0.005).
    pub motion_min_std: [f64; 2],
    /// Scan-matched-odometry proposal only: factor on the motion model's standard deviations
    /// around the corrected increment. Default 0.3.
    pub corrected_odometry_noise_scale: f64,
    /// Beams with a range at or above this are not used (neither for mapping nor for
    /// matching: slam-grid's sensor model with `far_hits_clear` off), metres. No-return
    /// readings (≥ the scan's `max_range`) are never used.
    /// Default 50.
    pub max_range: f64,
    /// Use every `beam_step`-th hit (end point within `max_range`) for matching and
    /// weighting (1 = all). Mapping always uses every beam. Default 1.
    pub beam_step: usize,
    /// Log-odds added to a cell where a beam ended. Default 0.85 (p = 0.7).
    pub log_odds_hit: f32,
    /// Log-odds added to a cell a beam passed through (negative). Default −0.2 (p = 0.45):
    /// walls survive more grazing pass-throughs (on intel.log −0.2 scored 0.0555 m against
    /// 0.0578 m for −0.4).
    pub log_odds_miss: f32,
    /// Log-odds clamping bounds (lower, upper). Default (−2.0, 3.5).
    pub log_odds_clamp: [f32; 2],
    /// Standard deviation σ of the endpoint model (PR §6.4): a beam whose end point lies
    /// at distance d from the nearest occupied cell contributes −d²/(2σ²) to the log
    /// likelihood, metres. Default 0.05.
    pub likelihood_sigma: f64,
    /// How far from the occupied cells each particle map's distance field reaches, metres
    /// (1 to 15 cells). This is the capture range of the coarse search and of the hill
    /// climber's coarse phase, which score with the endpoint model truncated here.
    /// Default 0.2.
    pub field_radius: f64,
    /// The endpoint model's truncation r (PR §6.4's outlier floor): a beam ending farther
    /// than r from any occupied cell counts as an outlier with the constant penalty
    /// −r²/(2σ²), metres, in (0, `field_radius`]. It applies where the pose is decided and
    /// weighed: the hill climber's fine phase, the improved proposal's samples, and every
    /// proposal's weights. Default 0.15: on intel.log (30 particles, filter seeds 0–31) it
    /// lowers the relations error from 0.0557 m / 2.301° (r = 0.2 m, the field's reach) to
    /// 0.0544 m / 2.295°, and on the simulated office (seeds 1–80, ATE after SE(2)
    /// alignment, 1 / 10 / 30 particles) from 0.134 / 0.078 / 0.076 m to 0.095 / 0.074 /
    /// 0.072 m. Shrinking the capture range with it (`field_radius` 0.15) scores the same on
    /// Intel but 0.144 / 0.085 / 0.081 m on the office. The cost: with 8–10 particles a
    /// few more office runs (7 of 40 against 2, filter seed 42) end with a consistent map
    /// whose long corridors came out short, where only door jambs fix the position along
    /// them.
    pub likelihood_radius: f64,
    /// The summed beam log-likelihood is divided by this in the particle weights (every
    /// proposal) and in the coarse search's trade-off against the motion prior: a
    /// smoothing of the over-confident independent-beam model, GMapping's `ogain`, which
    /// enters its weight normalisation only. The improved proposal's Gaussian N(μ, Σ) is
    /// fitted to the untempered likelihood (see the proposal's docs for why). Default 3.
    pub likelihood_gain: f64,
    /// Hill-climbing matcher: initial translation step, metres. Default 0.1 (twice
    /// GMapping's: the wider first steps widen the capture range at the cost of a few
    /// more evaluations).
    pub match_linear_step: f64,
    /// Hill-climbing matcher: initial rotation step, radians. Default 0.1.
    pub match_angular_step: f64,
    /// Hill-climbing matcher: how many times the steps are halved. Default 6 (final steps
    /// 1.6 mm / 1.6 mrad).
    pub match_refinements: usize,
    /// Coarse search before hill climbing: ±this in x and y around the best particle's
    /// prediction, metres (0 with `search_range_theta` 0 switches the search off).
    /// Default 0.3.
    pub search_range_xy: f64,
    /// Coarse search translation step, metres. Default 0.05.
    pub search_step_xy: f64,
    /// Coarse search: ±this in θ, radians. Default 0.3.
    pub search_range_theta: f64,
    /// Coarse search rotation step, radians. Default 0.025.
    pub search_step_theta: f64,
    /// A match counts as failed when fewer than this fraction of the used beams end within
    /// `likelihood_radius` of an occupied cell at the matched pose. Default 0.25.
    pub match_min_inlier_fraction: f64,
    /// Improved proposal: samples per axis around the mode, so K = n³. Default 3.
    pub samples_per_axis: usize,
    /// Improved proposal: the samples span ±this around the mode in x and y, metres.
    /// Default 0.01.
    pub sample_range_xy: f64,
    /// Improved proposal: the samples span ±this around the mode in θ, radians.
    /// Default 0.005.
    pub sample_range_theta: f64,
    /// The largest odometry jump between two consecutive records, and whether a larger
    /// one is an error (default: beyond 5 m) or skipped
    /// ([`slam_models::OdometryJumpLimit`]).
    pub odometry_jump: slam_models::OdometryJumpLimit,
}

impl Default for GridFastConfig {
    fn default() -> Self {
        Self {
            particles: 30,
            proposal: Proposal::Improved,
            resolution: 0.05,
            linear_update: 1.0,
            angular_update: 0.5,
            accumulate_per_scan: false,
            resample_threshold: 0.5,
            resampler: Resampler::Systematic,
            motion: OdometryModel::new([0.05, 0.002, 0.02, 0.002]),
            motion_min_std: [0.01, 0.005],
            corrected_odometry_noise_scale: 0.3,
            max_range: 50.0,
            beam_step: 1,
            log_odds_hit: 0.85,
            log_odds_miss: -0.2,
            log_odds_clamp: [-2.0, 3.5],
            likelihood_sigma: 0.05,
            field_radius: 0.2,
            likelihood_radius: 0.15,
            likelihood_gain: 3.0,
            match_linear_step: 0.1,
            match_angular_step: 0.1,
            match_refinements: 6,
            match_min_inlier_fraction: 0.25,
            search_range_xy: 0.3,
            search_step_xy: 0.05,
            search_range_theta: 0.3,
            search_step_theta: 0.025,
            samples_per_axis: 3,
            sample_range_xy: 0.01,
            sample_range_theta: 0.005,
            odometry_jump: slam_models::OdometryJumpLimit::default(),
        }
    }
}

fn check(
    ok: bool,
    field: &'static str,
    value: f64,
    expected: &'static str,
) -> Result<(), GridFastError> {
    Ok(slam_models::error::ensure_config(
        ok,
        "grid FastSLAM",
        field,
        value,
        expected,
    )?)
}

impl GridFastConfig {
    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<(), GridFastError> {
        check(
            (1..=MAX_PARTICLES).contains(&self.particles),
            "particles",
            self.particles as f64,
            "1 ..= 10000 (MAX_PARTICLES)",
        )?;
        check(self.resolution > 0.0, "resolution", self.resolution, "> 0")?;
        check(
            self.odometry_jump.max_jump > 0.0,
            "odometry_jump.max_jump",
            self.odometry_jump.max_jump,
            "> 0 m and finite",
        )?;
        check(
            self.linear_update >= 0.0,
            "linear_update",
            self.linear_update,
            ">= 0",
        )?;
        check(
            self.angular_update >= 0.0,
            "angular_update",
            self.angular_update,
            ">= 0",
        )?;
        check(
            (0.0..=1.0).contains(&self.resample_threshold),
            "resample_threshold",
            self.resample_threshold,
            "in [0, 1]",
        )?;
        for (i, a) in self.motion.alpha.iter().enumerate() {
            let name = [
                "motion.alpha[0]",
                "motion.alpha[1]",
                "motion.alpha[2]",
                "motion.alpha[3]",
            ][i];
            check(*a >= 0.0, name, *a, ">= 0")?;
        }
        check(
            self.motion_min_std[0] > 0.0,
            "motion_min_std[0]",
            self.motion_min_std[0],
            "> 0",
        )?;
        check(
            self.motion_min_std[1] > 0.0,
            "motion_min_std[1]",
            self.motion_min_std[1],
            "> 0",
        )?;
        check(
            self.corrected_odometry_noise_scale >= 0.0,
            "corrected_odometry_noise_scale",
            self.corrected_odometry_noise_scale,
            ">= 0",
        )?;
        check(self.max_range > 0.0, "max_range", self.max_range, "> 0")?;
        check(
            self.beam_step >= 1,
            "beam_step",
            self.beam_step as f64,
            ">= 1",
        )?;
        check(
            self.log_odds_hit > 0.0,
            "log_odds_hit",
            self.log_odds_hit as f64,
            "> 0",
        )?;
        check(
            self.log_odds_miss < 0.0,
            "log_odds_miss",
            self.log_odds_miss as f64,
            "< 0",
        )?;
        check(
            self.log_odds_clamp[0] < 0.0,
            "log_odds_clamp[0]",
            self.log_odds_clamp[0] as f64,
            "< 0",
        )?;
        check(
            self.log_odds_clamp[1] > 0.0,
            "log_odds_clamp[1]",
            self.log_odds_clamp[1] as f64,
            "> 0",
        )?;
        check(
            self.likelihood_sigma > 0.0,
            "likelihood_sigma",
            self.likelihood_sigma,
            "> 0",
        )?;
        let cells = self.field_radius / self.resolution;
        check(
            self.field_radius > 0.0 && (1.0..=15.0).contains(&cells),
            "field_radius",
            self.field_radius,
            "between 1 and 15 cells",
        )?;
        check(
            self.likelihood_radius > 0.0 && self.likelihood_radius <= self.field_radius,
            "likelihood_radius",
            self.likelihood_radius,
            "> 0 and at most field_radius",
        )?;
        check(
            self.likelihood_gain > 0.0,
            "likelihood_gain",
            self.likelihood_gain,
            "> 0",
        )?;
        check(
            self.match_linear_step > 0.0,
            "match_linear_step",
            self.match_linear_step,
            "> 0",
        )?;
        check(
            self.match_angular_step > 0.0,
            "match_angular_step",
            self.match_angular_step,
            "> 0",
        )?;
        check(
            self.match_refinements <= 30,
            "match_refinements",
            self.match_refinements as f64,
            "<= 30",
        )?;
        check(
            (0.0..=1.0).contains(&self.match_min_inlier_fraction),
            "match_min_inlier_fraction",
            self.match_min_inlier_fraction,
            "in [0, 1]",
        )?;
        check(
            self.search_range_xy >= 0.0,
            "search_range_xy",
            self.search_range_xy,
            ">= 0",
        )?;
        check(
            self.search_step_xy > 0.0,
            "search_step_xy",
            self.search_step_xy,
            "> 0",
        )?;
        check(
            self.search_range_theta >= 0.0,
            "search_range_theta",
            self.search_range_theta,
            ">= 0",
        )?;
        check(
            self.search_step_theta > 0.0,
            "search_step_theta",
            self.search_step_theta,
            "> 0",
        )?;
        check(
            self.search_range_xy / self.search_step_xy <= 50.0
                && self.search_range_theta / self.search_step_theta <= 50.0,
            "search_range_xy",
            self.search_range_xy,
            "at most 50 steps per side in each search dimension",
        )?;
        check(
            (1..=9).contains(&self.samples_per_axis),
            "samples_per_axis",
            self.samples_per_axis as f64,
            "in 1..=9",
        )?;
        check(
            self.sample_range_xy >= 0.0,
            "sample_range_xy",
            self.sample_range_xy,
            ">= 0",
        )?;
        check(
            self.sample_range_theta >= 0.0,
            "sample_range_theta",
            self.sample_range_theta,
            ">= 0",
        )?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_valid_and_round_trips_through_serde() {
        let c = GridFastConfig::default();
        c.validate().unwrap();
        let json = serde_json::to_string(&c).unwrap();
        let back: GridFastConfig = serde_json::from_str(&json).unwrap();
        assert_eq!(back.particles, 30);
        let p: GridFastConfig =
            serde_json::from_str(r#"{"particles": 5, "proposal": "scan-matched-odometry"}"#)
                .unwrap();
        assert_eq!(p.proposal, Proposal::ScanMatchedOdometry);
        assert_eq!(p.linear_update, 1.0);
        assert!(serde_json::from_str::<GridFastConfig>(r#"{"particle": 5}"#).is_err());
    }

    /// `particles = 10^9` used to be accepted and allocated.
    #[test]
    fn particle_count_is_capped() {
        let c = GridFastConfig {
            particles: 1_000_000_000,
            ..Default::default()
        };
        let e = c.validate().unwrap_err().to_string();
        assert!(
            e.contains("particles = 1000000000") && e.contains("10000"),
            "{e}"
        );
        assert!(crate::GridFastSlam::new(c, slam_models::Pose2::IDENTITY, 0).is_err());
        let c = GridFastConfig {
            particles: MAX_PARTICLES,
            ..Default::default()
        };
        assert!(c.validate().is_ok());
    }

    #[test]
    fn bad_values_are_rejected() {
        let mut c = GridFastConfig {
            particles: 0,
            ..Default::default()
        };
        assert!(c.validate().is_err());
        c.particles = 3;
        c.field_radius = 1.0; // 20 cells
        assert!(matches!(
            c.validate(),
            Err(GridFastError::InvalidConfig(slam_models::ConfigError {
                field: "field_radius",
                ..
            }))
        ));
        c.field_radius = 0.2;
        for r in [0.0, 0.25, f64::NAN] {
            c.likelihood_radius = r;
            assert!(matches!(
                c.validate(),
                Err(GridFastError::InvalidConfig(slam_models::ConfigError {
                    field: "likelihood_radius",
                    ..
                }))
            ));
        }
        c.likelihood_radius = 0.2;
        c.validate().unwrap();
        c.likelihood_sigma = f64::NAN;
        assert!(c.validate().is_err());
    }
}
