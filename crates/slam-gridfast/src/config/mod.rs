//! The configuration of [`crate::GridFastSlam`]: nested tables (sensor, map, matching,
//! proposal, resampling, motion), kebab-case keys, every value documented with its default.
//!
//! Values that depend on the environment — the sensor's range limit, the cell size, and
//! the lengths of the endpoint model and of the searches that scale with it — are
//! `Option`s: `None` takes them from the data (the range limit) or from the
//! [`Preset`] (everything else), which is itself chosen from the data unless the config
//! names one. [`GridFastConfig::resolve`] turns a configuration and the first scan into
//! the effective one, with every value set; the filter runs with that.

use crate::error::GridFastError;
use serde::{Deserialize, Serialize};
use slam_models::motion::OdometryModel;
use slam_models::particle::Resampler;
use slam_models::LaserScan;

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
    /// [`ProposalConfig::corrected_odometry_noise_scale`]; weights by the scan likelihood.
    ScanMatchedOdometry,
    /// The improved proposal (Grisetti, Stachniss & Burgard, T-RO 2007, §IV and Table I):
    /// each particle matches the scan against its own map, evaluates K poses around the
    /// mode, fits N(μ, Σ) to likelihood × motion model over them (eqs. 14–15), **samples**
    /// its new pose from that Gaussian and multiplies its weight by η = Σⱼ τ(xⱼ) (eq. 18).
    #[default]
    Improved,
}

/// How the improved proposal chooses between its two starting points, the particle's
/// prediction x' and x' moved by the best particle's coarse correction c (see
/// [`MatchingConfig::start_choice`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StartChoice {
    /// When c reaches beyond the hill climber's first steps, climb from both and keep the
    /// match with the larger likelihood × motion prior p(z | m, x)·p(x | x', R) — the
    /// mode the improved proposal approximates (Grisetti et al. 2007, eq. 9), and what the
    /// particle's weight then scores; otherwise climb once, as with `coarse-score`.
    #[default]
    Posterior,
    /// Climb once, from the start whose coarse-subset likelihood is larger, whatever the
    /// motion prior says (the rule before 2026-12-02).
    CoarseScore,
}

/// The range limit used before the first scan has been seen (the filter re-reads it from
/// that scan when [`SensorConfig::max_range`] is `None`), metres.
const PROVISIONAL_MAX_RANGE: f64 = 50.0;

/// Upper bound of [`GridFastConfig::particles`]: every particle carries its own map, so
/// 10⁴ particles already need gigabytes on a building-sized map (GMapping runs 30–100);
/// 10⁹ would be an allocation abort.
pub const MAX_PARTICLES: usize = 10_000;

/// The laser, as the filter uses it. Beam geometry (angles, count, mounting) and the
/// no-return convention (a reading at or above the scan's `max_range` is no return) always
/// come from the data.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct SensorConfig {
    /// Beams with a range at or above this are not used (neither for mapping nor for
    /// matching: slam-grid's sensor model with `far_hits_clear` off), metres. `None` (the
    /// default): the first processed scan's own `max_range`, its no-return value, so every
    /// return the laser gives is used. No-return readings are never used.
    pub max_range: Option<f64>,
    /// Use every `beam_step`-th hit (end point within `max_range`) for matching and
    /// weighting (1 = all). Mapping always uses every beam. Default 1.
    pub beam_step: usize,
}

impl Default for SensorConfig {
    fn default() -> Self {
        Self {
            max_range: None,
            beam_step: 1,
        }
    }
}

/// Every particle's occupancy grid.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct MapConfig {
    /// Cell edge length of every particle's map, metres. Default from the preset: 0.05
    /// indoor (GMapping's `delta`), 0.2 outdoor.
    pub resolution: Option<f64>,
    /// Log-odds added to a cell where a beam ended. Default 0.85 (p = 0.7).
    pub log_odds_hit: f32,
    /// Log-odds added to a cell a beam passed through (negative). Default −0.2 (p = 0.45):
    /// walls survive more grazing pass-throughs (docs/results/defaults.md).
    pub log_odds_miss: f32,
    /// Log-odds clamping bounds (lower, upper). Default (−2.0, 3.5).
    pub log_odds_clamp: [f32; 2],
}

impl Default for MapConfig {
    fn default() -> Self {
        Self {
            resolution: None,
            log_odds_hit: 0.85,
            log_odds_miss: -0.2,
            log_odds_clamp: [-2.0, 3.5],
        }
    }
}

/// The endpoint model and the scan matching against each particle's map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct MatchingConfig {
    /// Standard deviation σ of the endpoint model (PR §6.4): a beam whose end point lies
    /// at distance d from the nearest occupied cell contributes −d²/(2σ²) to the log
    /// likelihood, metres. Default from the preset: 0.05 indoor, 0.2 outdoor (one cell).
    pub sigma: Option<f64>,
    /// How far from the occupied cells each particle map's distance field reaches, metres
    /// (1 to 15 cells). This is the capture range of the coarse search and of the hill
    /// climber's coarse phase, which score with the endpoint model truncated here.
    /// Default from the preset: 0.2 indoor, 0.8 outdoor (four cells).
    pub field_radius: Option<f64>,
    /// The endpoint model's truncation r (PR §6.4's outlier floor): a beam ending farther
    /// than r from any occupied cell counts as an outlier with the constant penalty
    /// −r²/(2σ²), metres, in (0, `field_radius`]. It applies where the pose is decided and
    /// weighed: the hill climber's fine phase, the improved proposal's samples, and every
    /// proposal's weights. Default from the preset: 0.6 outdoor; 0.15 indoor, below the
    /// field's reach, because outliers then stop pulling the pose on Intel and the office
    /// while the capture range stays (docs/results/defaults.md).
    pub likelihood_radius: Option<f64>,
    /// The summed beam log-likelihood is divided by this in the particle weights (every
    /// proposal) and in the coarse search's trade-off against the motion prior: a
    /// smoothing of the over-confident independent-beam model, GMapping's `ogain`, which
    /// enters its weight normalisation only. The improved proposal's Gaussian N(μ, Σ) is
    /// fitted to the untempered likelihood (see the proposal's docs for why). Default 3.
    pub gain: f64,
    /// Hill-climbing matcher: initial translation step, metres. Default from the preset:
    /// 0.4 outdoor; 0.1 indoor (twice GMapping's: the wider first steps widen the capture
    /// range at the cost of a few more evaluations).
    pub linear_step: Option<f64>,
    /// Hill-climbing matcher: initial rotation step, radians. Default 0.1.
    pub angular_step: f64,
    /// Hill-climbing matcher: how many times the steps are halved. Default 6 (final steps
    /// 1.6 mm / 1.6 mrad indoors).
    pub refinements: usize,
    /// Coarse search before hill climbing: ±this in x and y around the best particle's
    /// prediction, metres (0 with `search_range_theta` 0 switches the search off).
    /// Default from the preset: 0.3 indoor, 1.2 outdoor.
    pub search_range_xy: Option<f64>,
    /// Coarse search translation step, metres. Default from the preset: 0.05 indoor, 0.2
    /// outdoor.
    pub search_step_xy: Option<f64>,
    /// Coarse search: ±this in θ, radians. Default from the preset: 0.9 indoor, 0.3
    /// outdoor. Indoors the window covers the heading errors of odometry between keyframes
    /// that turned in place (up to 0.88 rad on the robustness suite's `hard` inputs, whose
    /// runs the earlier ±0.3 lost: docs/gridfast.md); the motion prior that weighs the
    /// search keeps far headings from winning where the odometry is good.
    pub search_range_theta: Option<f64>,
    /// Coarse search rotation step, radians. Default from the preset: 0.025 indoor, 0.01
    /// outdoor.
    pub search_step_theta: Option<f64>,
    /// A match counts as failed, and the particle falls back to the motion model, when
    /// fewer than this fraction of the used beams end within `likelihood_radius` of an
    /// occupied cell at the matched pose. Default 0.25.
    pub min_inlier_fraction: f64,
    /// How each particle chooses where its hill climbing starts: `posterior` (default)
    /// climbs from both its prediction and the prediction moved by the best particle's
    /// coarse correction when the two are farther apart than the climber's first steps,
    /// and keeps the match with the larger likelihood × motion prior; `coarse-score`
    /// climbs once from the start whose coarse-subset likelihood is larger. On csail the
    /// coarse-score rule let a scan looking into space the map had not seen take a pose
    /// 0.6 rad off the good odometry, because a few dozen more beams found walls there
    /// (docs/gridfast.md).
    pub start_choice: StartChoice,
    /// What a poor match triggers before that fallback: a wider search.
    pub recovery: RecoveryConfig,
}

impl Default for MatchingConfig {
    fn default() -> Self {
        Self {
            sigma: None,
            field_radius: None,
            likelihood_radius: None,
            gain: 3.0,
            linear_step: None,
            angular_step: 0.1,
            refinements: 6,
            search_range_xy: None,
            search_step_xy: None,
            search_range_theta: None,
            search_step_theta: None,
            min_inlier_fraction: 0.25,
            start_choice: StartChoice::Posterior,
            recovery: RecoveryConfig::default(),
        }
    }
}

/// The answer to a poor match (improved proposal): a particle whose hill-climbed match has
/// fewer than `trigger_fraction` of its beams on the map searches a wide window around its
/// prediction by branch and bound over a coarse-to-fine max-pyramid of the capture field
/// (Olson, ICRA 2009, §IV-C; Cartographer; [`slam_grid::matcher::endpoint::wide_search`]),
/// with the motion prior widened to the window, and climbs from the best pose found. The result replaces the local match when more beams find the map there.
/// Only then is the motion model the fallback.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct RecoveryConfig {
    /// A match with fewer than this fraction of its beams within `likelihood_radius` of the
    /// map is poor and triggers the wide search (0 switches it off). Default 0.4.
    pub trigger_fraction: f64,
    /// Count `trigger_fraction` among the beams whose end point the map can judge — it
    /// lies in an observed cell or within `likelihood_radius` of an obstacle — rather than
    /// among all the used beams; a match below `min_inlier_fraction` of all the beams is
    /// poor either way. Default true: a scan looking into space not yet mapped has most of
    /// its end points in unknown cells, which says nothing against its pose, while a pose
    /// that is off puts end points into space the map knows to be free. Counting all the
    /// beams sent csail's scans into new space to the wide search, which took an aliased
    /// pose 1.4 m away for every particle (docs/gridfast.md).
    pub observed_only: bool,
    /// The wide search's match is taken only when at least this fraction of the used beams
    /// end within `likelihood-radius` of the map there: a pose far from the motion model's
    /// prediction needs most of the scan to fit. Below it the particle keeps its local
    /// match, or falls back to the motion model. Where the robot faces space not yet mapped,
    /// a wrong pose can fit more beams than the right one, which fits few: on fhw up to
    /// 50 % at 2.4 m from an exact odometry prediction (docs/gridfast.md). Default 0.6.
    pub accept_fraction: f64,
    /// ± this in x and y around the prediction, metres. Default from the preset: 1.5
    /// indoor, 3.0 outdoor.
    pub range_xy: Option<f64>,
    /// ± this in θ, radians (at least the coarse search's, whose failure it answers).
    /// Default from the preset: 0.9 indoor, 0.4 outdoor.
    pub range_theta: Option<f64>,
    /// Translation step, metres, rounded to whole map cells (at least one): the lattice of
    /// the branch-and-bound search. Default from the preset: 0.1 indoor, 0.4 outdoor (two
    /// cells).
    pub step_xy: Option<f64>,
    /// Rotation step, radians. Default from the preset: 0.02 indoor, 0.01 outdoor.
    pub step_theta: Option<f64>,
    /// A processed step whose odometry turned by at least this much (|δrot1| + |δrot2|,
    /// radians) answers a poor match that the wide window's search did not recover with a
    /// second search: every heading (± `turn-range-theta`) at the predicted position
    /// (± `turn-range-xy`), taken with `turn-accept-fraction`. Default 0.5 (the default
    /// `angular-update`: a step processed for turning).
    /// Odometry that turned in place can be off by more than the turn itself: on
    /// `perturb-odometry --seed 2 --profile hard` fhw a measured +50.8° for a true −20.1°
    /// (1.24 rad, 7σ of the motion model), which bent the map at a junction with every
    /// filter seed (docs/gridfast.md, "Turns in place the odometry got wrong").
    pub turn_trigger: f64,
    /// ± this in θ, radians, for a poor match on a turn (`turn-trigger`): π, the full
    /// circle, by default, in steps of `step-theta`.
    pub turn_range_theta: f64,
    /// ± this in x and y around the prediction, metres, for a poor match on a turn (in
    /// steps of `step-xy`). Default from the preset: 0.3 indoor, 1.2 outdoor (the coarse
    /// search's).
    pub turn_range_xy: Option<f64>,
    /// The turn search's match is taken with at least this fraction of the used beams on
    /// the map (and not poor, and more than the local match). Default 0.45: on
    /// `perturb-odometry --seed 2 --profile hard` fhw, the scan after the turn that the
    /// odometry measured 1.24 rad off fits 47–57 % of its beams at the right heading, at a
    /// junction it partly looks out of; the wide window's 0.6 guards poses metres away.
    pub turn_accept_fraction: f64,
    /// ε, the prior probability that a step's odometry is an outlier: the motion density
    /// of a recovered particle is the mixture (1 − ε)·N(x′, R) + ε·N(x′, R + W), W the
    /// searched window's (see [`RecoveryConfig`]). In (0, 1); default 0.01.
    pub outlier_weight: f64,
}

impl Default for RecoveryConfig {
    fn default() -> Self {
        Self {
            trigger_fraction: 0.4,
            observed_only: true,
            accept_fraction: 0.6,
            range_xy: None,
            range_theta: None,
            step_xy: None,
            step_theta: None,
            turn_trigger: 0.5,
            turn_range_theta: std::f64::consts::PI,
            turn_range_xy: None,
            turn_accept_fraction: 0.45,
            outlier_weight: 0.01,
        }
    }
}

/// The proposal distribution.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct ProposalConfig {
    /// Which proposal. Default [`Proposal::Improved`].
    pub kind: Proposal,
    /// Improved proposal: samples per axis around the mode, so K = n³. Default 3.
    pub samples_per_axis: usize,
    /// Improved proposal: the samples span ±this around the mode in x and y, metres.
    /// Default from the preset: 0.01 indoor (GMapping's `llsamplerange`), 0.04 outdoor.
    pub sample_range_xy: Option<f64>,
    /// Improved proposal: the samples span ±this around the mode in θ, radians.
    /// Default 0.005.
    pub sample_range_theta: f64,
    /// Scan-matched-odometry proposal only: factor on the motion model's standard deviations
    /// around the corrected increment. Default 0.3.
    pub corrected_odometry_noise_scale: f64,
}

impl Default for ProposalConfig {
    fn default() -> Self {
        Self {
            kind: Proposal::Improved,
            samples_per_axis: 3,
            sample_range_xy: None,
            sample_range_theta: 0.005,
            corrected_odometry_noise_scale: 0.3,
        }
    }
}

/// Selective resampling (Grisetti et al. 2007 §V).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct ResamplingConfig {
    /// Resample when N_eff < `threshold`·M. Default 0.5.
    pub threshold: f64,
    /// Resampling scheme (slam-models). Default systematic.
    pub scheme: Resampler,
}

impl Default for ResamplingConfig {
    fn default() -> Self {
        Self {
            threshold: 0.5,
            scheme: Resampler::Systematic,
        }
    }
}

/// Where the odometry the filter is fed comes from, which decides how far the improved
/// proposal's coarse search must reach around the odometry's prediction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum OdometrySource {
    /// The robot's own odometry (wheel encoders, an IMU, a visual odometry): its error
    /// between two updates is a drift of centimetres, which the preset's window covers.
    #[default]
    Robot,
    /// Laser odometry (slam-grid's `LaserOdometry`: each scan matched against the scans
    /// before it), made when a recording has no odometry or it is withheld. Its errors are
    /// single wrong steps of 0.5–1.5 m along a corridor instead, so the preset's window
    /// [`MatchingConfig::search_range_xy`] is widened to at least
    /// [`LASER_ODOMETRY_SEARCH_RANGE_XY`] (a value set in the configuration is kept).
    Laser,
}

/// With [`OdometrySource::Laser`], the improved proposal's coarse search reaches at least
/// ± this in x and y around the prediction, metres (the preset's window when wider): the
/// indoor preset's ±0.3 m cannot reach back over laser odometry's wrong steps (`bench/intel.log`
/// without odometry, filter seeds 0–4: relations 0.880 m median with ±0.3 m, 0.197 m with
/// ±1 m; docs/results.md, "Laser-only mapping").
pub const LASER_ODOMETRY_SEARCH_RANGE_XY: f64 = 1.0;

/// The motion between processed scans.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct MotionConfig {
    /// Where the odometry comes from ([`OdometrySource`]). Default `robot`; `slam run` and
    /// `slam ros2` set `laser` when they feed the filter laser odometry.
    pub odometry_source: OdometrySource,
    /// Odometry motion model (PR table 5.6). Default α = (0.05, 0.002, 0.02, 0.002): 22 %
    /// of a rotation, 4.5 cm of heading per metre as rotation noise; 14 % of the
    /// translation as translation noise. Both of its keys must be given in a file (a
    /// missing one takes slam-models' default, not this one).
    pub odometry: OdometryModel,
    /// Standard deviations added (in quadrature) to the motion model's position and heading
    /// noise so that its covariance stays positive definite for near-zero motion,
    /// (metres, radians). Default (0.01, 0.005).
    pub min_std: [f64; 2],
}

impl Default for MotionConfig {
    fn default() -> Self {
        Self {
            odometry_source: OdometrySource::Robot,
            odometry: OdometryModel::new([0.05, 0.002, 0.02, 0.002]),
            min_std: [0.01, 0.005],
        }
    }
}

/// Configuration of grid-based FastSLAM. Lengths in metres, angles in radians.
///
/// Defaults follow GMapping's ROS defaults where GMapping has the parameter (particles 30,
/// 5 cm cells indoors, `linearUpdate` 1.0 m, `angularUpdate` 0.5 rad, resampling threshold
/// 0.5, K = 3³ samples within ±1 cm / ±0.005 rad, likelihood gain 3). `None` values come
/// from the data or the [`Preset`]; [`GridFastConfig::resolve`] fills them in.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct GridFastConfig {
    /// Number of particles M (1 ..= [`MAX_PARTICLES`]). Default 30.
    pub particles: usize,
    /// The environment the scale-dependent defaults are chosen for. Default
    /// [`Preset::Auto`] (from the first processed scan).
    pub preset: Preset,
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
    /// … or the scan no longer fits the map where the odometry puts it: a scan is also
    /// processed when fewer than this fraction of its used beams end within
    /// `matching.likelihood-radius` of an occupied cell of the best particle's map at that
    /// particle's pose ⊕ the odometry since the last update (one score evaluation per
    /// scan). This catches motion the odometry missed (a turn in place it under-reports)
    /// while the scans still overlap the map, before the error outgrows the searches'
    /// windows (docs/gridfast.md). Scans the odometry already makes due are not checked
    /// (on `bench/intel.log` and `bench/fhw.log` every scan is). 0 switches it off.
    /// Default 0.3.
    pub scan_update_fraction: f64,
    /// The laser.
    pub sensor: SensorConfig,
    /// The particles' maps.
    pub map: MapConfig,
    /// The endpoint model and scan matching.
    pub matching: MatchingConfig,
    /// The proposal distribution.
    pub proposal: ProposalConfig,
    /// Selective resampling.
    pub resampling: ResamplingConfig,
    /// The motion model between processed scans.
    pub motion: MotionConfig,
    /// The largest odometry jump between two consecutive records, and whether a larger
    /// one is an error (default: beyond 5 m) or skipped
    /// ([`slam_models::OdometryJumpLimit`]).
    pub odometry_jump: slam_models::OdometryJumpLimit,
}

impl Default for GridFastConfig {
    fn default() -> Self {
        Self {
            particles: 30,
            preset: Preset::Auto,
            linear_update: 1.0,
            angular_update: 0.5,
            accumulate_per_scan: false,
            scan_update_fraction: 0.3,
            sensor: SensorConfig::default(),
            map: MapConfig::default(),
            matching: MatchingConfig::default(),
            proposal: ProposalConfig::default(),
            resampling: ResamplingConfig::default(),
            motion: MotionConfig::default(),
            odometry_jump: slam_models::OdometryJumpLimit::default(),
        }
    }
}

impl GridFastConfig {
    /// The same configuration with the preset's values for every `None` of `preset`
    /// ([`Preset::Auto`] stands for [`Preset::Indoor`] here), the range limit left as it
    /// is; with [`OdometrySource::Laser`] the search window is at least
    /// [`LASER_ODOMETRY_SEARCH_RANGE_XY`].
    pub fn with_preset(&self, preset: Preset) -> GridFastConfig {
        let p = preset.values();
        let mut c = self.clone();
        c.preset = match preset {
            Preset::Auto => Preset::Indoor,
            other => other,
        };
        c.map.resolution.get_or_insert(p.resolution);
        let m = &mut c.matching;
        m.sigma.get_or_insert(p.sigma);
        m.field_radius.get_or_insert(p.field_radius);
        m.likelihood_radius.get_or_insert(p.likelihood_radius);
        m.linear_step.get_or_insert(p.linear_step);
        m.search_range_xy
            .get_or_insert(match c.motion.odometry_source {
                OdometrySource::Robot => p.search_range_xy,
                OdometrySource::Laser => p.search_range_xy.max(LASER_ODOMETRY_SEARCH_RANGE_XY),
            });
        m.search_step_xy.get_or_insert(p.search_step_xy);
        m.search_range_theta.get_or_insert(p.search_range_theta);
        m.search_step_theta.get_or_insert(p.search_step_theta);
        m.recovery.range_xy.get_or_insert(p.recovery_range_xy);
        m.recovery.range_theta.get_or_insert(p.recovery_range_theta);
        m.recovery.step_xy.get_or_insert(p.recovery_step_xy);
        m.recovery.step_theta.get_or_insert(p.recovery_step_theta);
        m.recovery
            .turn_range_xy
            .get_or_insert(p.recovery_turn_range_xy);
        c.proposal.sample_range_xy.get_or_insert(p.sample_range_xy);
        c
    }

    /// The effective configuration for a run whose first processed scan is `scan`: the
    /// range limit from the scan (its `max_range`, the no-return value) unless given, the
    /// preset chosen from the scan unless given ([`Preset::choose`]), and every other
    /// `None` from that preset. Without a scan (before the first one) the range limit is a
    /// provisional 50 m and `Auto` stands for indoor. The result is validated.
    pub fn resolve(&self, scan: Option<&LaserScan>) -> Result<GridFastConfig, GridFastError> {
        self.validate()?;
        let max_range = match (self.sensor.max_range, scan) {
            (Some(r), _) => r,
            (None, Some(s)) => s.max_range,
            (None, None) => PROVISIONAL_MAX_RANGE,
        };
        let preset = match scan {
            Some(s) => self.preset.choose(s, max_range),
            None => self.preset,
        };
        let mut c = self.with_preset(preset);
        c.sensor.max_range = Some(max_range);
        c.validate()?;
        c.check_resolved()?;
        Ok(c)
    }
}

mod preset;
mod validate;

pub use preset::{median_return_range, Preset, AUTO_OUTDOOR_MEDIAN_RANGE};

#[cfg(test)]
mod tests;
