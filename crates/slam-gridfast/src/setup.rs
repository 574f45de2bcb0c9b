//! What the filter derives once from its effective configuration ([`Setup`]): every
//! parameter under the name it has in [`GridFastConfig`], as a plain number, beside the
//! objects built from them (the endpoint models, the empty map, the sample offsets).
//! Built when the filter is made and again when the first scan fixes the values the
//! configuration left open; nothing of it is rebuilt per update.

use crate::config::{GridFastConfig, Proposal, ResamplingConfig, StartChoice};
use crate::error::GridFastError;
use slam_grid::matcher::endpoint::{EndpointModel, HillClimbSteps, SearchWindow};
use slam_grid::{InverseSensorModel, OccupancyGrid};
use slam_models::motion::OdometryModel;
use slam_models::{Matrix3, Vector3};

/// A search window, ± range and step in x/y (metres) and θ (radians): the coarse search's
/// (`matching.search-*`) or the recovery's (`matching.recovery.*`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Window {
    pub range_xy: f64,
    pub step_xy: f64,
    pub range_theta: f64,
    pub step_theta: f64,
}

impl Window {
    /// The window with R⁻¹ = `covariance`⁻¹ (zero when singular) as its motion prior.
    pub fn with_prior(&self, covariance: &Matrix3) -> SearchWindow {
        SearchWindow {
            range_xy: self.range_xy,
            step_xy: self.step_xy,
            range_theta: self.range_theta,
            step_theta: self.step_theta,
            information: covariance.try_inverse().unwrap_or_else(Matrix3::zeros),
        }
    }
}

/// `matching.recovery`: the wide search a poor match triggers ([`crate::RecoveryConfig`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Recovery {
    /// `trigger-fraction`: a match with fewer inliers than this fraction of the beams is poor.
    pub trigger_fraction: f64,
    /// `observed-only`: count the fraction among the beams whose end point the map can judge.
    pub observed_only: bool,
    /// `accept-fraction`: the wide match is taken only with at least this fraction of the
    /// beams on the map.
    pub accept_fraction: f64,
    /// `range-xy`, `step-xy`, `range-theta`, `step-theta`.
    pub window: Window,
    /// `turn-trigger`, radians.
    pub turn_trigger: f64,
    /// `turn-range-theta`, radians.
    pub turn_range_theta: f64,
    /// `turn-range-xy`, metres.
    pub turn_range_xy: f64,
    /// `turn-accept-fraction`.
    pub turn_accept_fraction: f64,
    /// ln(ε / (1 − ε)), ε = `outlier-weight`: the broad component's weight relative to
    /// the odometry model's in the recovered particles' motion density.
    pub log_outlier_odds: f64,
}

/// ⌈`fraction` · n⌉ beams of a scan with `n` used beams.
pub(crate) fn beams(fraction: f64, n: usize) -> usize {
    (fraction * n as f64).ceil() as usize
}

/// The effective configuration's values, named as its keys, and what follows from them.
pub(crate) struct Setup {
    /// `proposal.kind`.
    pub proposal: Proposal,
    /// `linear-update`, `angular-update`, `accumulate-per-scan`, `scan-update-fraction`.
    pub linear_update: f64,
    pub angular_update: f64,
    pub accumulate_per_scan: bool,
    pub scan_update_fraction: f64,
    /// `sensor.max-range` (the effective one), `sensor.beam-step`.
    pub max_range: f64,
    pub beam_step: usize,
    /// `map.*` as slam-grid's inverse sensor model ([`sensor_model`]).
    pub sensor_model: InverseSensorModel,
    /// An empty map (`map.resolution`, `matching.field-radius`): every particle's first map.
    pub empty: OccupancyGrid,
    /// `matching.sigma`, `matching.likelihood-radius`, `matching.gain`: the endpoint model
    /// where a pose is decided and weighed.
    pub likelihood: EndpointModel,
    /// The same model truncated at the field's reach (`matching.field-radius`, whole
    /// cells): the capture range of the coarse search and of the climber's first steps.
    pub capture: EndpointModel,
    /// `matching.linear-step`, `matching.angular-step`, `matching.refinements`.
    pub climb: HillClimbSteps,
    /// `matching.search-*`; `None` when both ranges are 0 (no coarse search).
    pub search: Option<Window>,
    /// `matching.min-inlier-fraction`.
    pub min_inlier_fraction: f64,
    /// `matching.start-choice`.
    pub start_choice: StartChoice,
    /// `matching.recovery`; `None` when its `trigger-fraction` is 0.
    pub recovery: Option<Recovery>,
    /// The K = n³ offsets of the improved proposal's samples (`proposal.samples-per-axis`,
    /// `proposal.sample-range-xy`, `proposal.sample-range-theta`).
    pub offsets: Vec<[f64; 3]>,
    /// `proposal.corrected-odometry-noise-scale`.
    pub corrected_odometry_noise_scale: f64,
    /// `motion.odometry`.
    pub odometry: OdometryModel,
    /// `motion.min-std` squared: the variances (m², m², rad²) added to the motion covariance.
    pub min_var: Vector3,
    /// `resampling` (`threshold`, `scheme`).
    pub resampling: ResamplingConfig,
}

/// An `Option` the effective configuration has set (NaN otherwise, which the filter never
/// sees: [`GridFastConfig::resolve`] sets every one).
fn set(x: Option<f64>) -> f64 {
    x.unwrap_or(f64::NAN)
}

impl Setup {
    /// The setup of an effective configuration (`config` from [`GridFastConfig::resolve`]).
    pub fn new(config: &GridFastConfig) -> Result<Self, GridFastError> {
        let (m, p) = (&config.matching, &config.proposal);
        let resolution = set(config.map.resolution);
        let field_radius = set(m.field_radius);
        let radius = (field_radius / resolution).round() as i32;
        let sigma = set(m.sigma);
        let likelihood = EndpointModel {
            k: 1.0 / (2.0 * sigma.powi(2) * m.gain),
            radius: set(m.likelihood_radius),
            gain: m.gain,
        };
        let max_range = set(config.sensor.max_range);
        let sensor_model = sensor_model(config, max_range);
        let (search_xy, search_theta) = (set(m.search_range_xy), set(m.search_range_theta));
        let rc = &m.recovery;
        let min_std = config.motion.min_std;
        Ok(Self {
            proposal: p.kind,
            linear_update: config.linear_update,
            angular_update: config.angular_update,
            accumulate_per_scan: config.accumulate_per_scan,
            scan_update_fraction: config.scan_update_fraction,
            max_range,
            beam_step: config.sensor.beam_step,
            sensor_model,
            empty: new_map(resolution, field_radius, sensor_model)?,
            likelihood,
            capture: EndpointModel {
                radius: radius as f64 * resolution,
                ..likelihood
            },
            climb: HillClimbSteps {
                linear_step: set(m.linear_step),
                angular_step: m.angular_step,
                refinements: m.refinements,
            },
            search: (search_xy > 0.0 || search_theta > 0.0).then(|| Window {
                range_xy: search_xy,
                step_xy: set(m.search_step_xy),
                range_theta: search_theta,
                step_theta: set(m.search_step_theta),
            }),
            min_inlier_fraction: m.min_inlier_fraction,
            start_choice: m.start_choice,
            recovery: (rc.trigger_fraction > 0.0).then(|| Recovery {
                trigger_fraction: rc.trigger_fraction,
                observed_only: rc.observed_only,
                accept_fraction: rc.accept_fraction,
                window: Window {
                    range_xy: set(rc.range_xy),
                    step_xy: set(rc.step_xy),
                    range_theta: set(rc.range_theta),
                    step_theta: set(rc.step_theta),
                },
                turn_trigger: rc.turn_trigger,
                turn_range_theta: rc.turn_range_theta,
                turn_range_xy: set(rc.turn_range_xy),
                turn_accept_fraction: rc.turn_accept_fraction,
                log_outlier_odds: (rc.outlier_weight / (1.0 - rc.outlier_weight)).ln(),
            }),
            offsets: sample_offsets(
                p.samples_per_axis,
                set(p.sample_range_xy),
                p.sample_range_theta,
            ),
            corrected_odometry_noise_scale: p.corrected_odometry_noise_scale,
            odometry: config.motion.odometry,
            min_var: Vector3::new(min_std[0].powi(2), min_std[0].powi(2), min_std[1].powi(2)),
            resampling: config.resampling,
        })
    }

    /// A match on a scan of `n` used beams fails with fewer inliers than this
    /// (`matching.min-inlier-fraction`, at least one).
    pub fn min_inliers(&self, n: usize) -> usize {
        beams(self.min_inlier_fraction, n).max(1)
    }
}

/// The inverse sensor model of every particle's map (and of the re-rendered map): the
/// configured log-odds; the cells a scan's beams end in are marked once per scan and
/// not cleared by that scan's other beams (`protect_scan_hits`); readings at or beyond
/// `max_range` (the effective `sensor.max-range`) count as no returns (`far_hits_clear`
/// off: they neither mark nor clear cells; clearing space up to `max_range` instead, as
/// GMapping's `maxUrange` does, made acapulco's maps grow to 290 MB for 30 particles and
/// its ATE worse); no-return readings and the space just before a hit are left alone (no
/// `no_return_range`, no `hit_margin`).
fn sensor_model(config: &GridFastConfig, max_range: f64) -> InverseSensorModel {
    InverseSensorModel {
        l_occ: config.map.log_odds_hit,
        l_free: config.map.log_odds_miss,
        l_min: config.map.log_odds_clamp[0],
        l_max: config.map.log_odds_clamp[1],
        max_range,
        no_return_range: 0.0,
        min_range: 0.0,
        hit_margin: 0.0,
        protect_scan_hits: true,
        far_hits_clear: false,
    }
}

/// An empty particle map: `resolution` m cells with a truncated distance field of
/// `field_radius` (validated to 1..=15 cells) for the scan likelihood (which truncates it
/// further at `likelihood-radius` where it decides and weighs a pose).
fn new_map(
    resolution: f64,
    field_radius: f64,
    model: InverseSensorModel,
) -> Result<OccupancyGrid, GridFastError> {
    let radius = (field_radius / resolution).round() as u32;
    // slam-grid's lazily computed field is not used: no sub-cell hit statistics (their
    // 3 KiB per tile would be copied with every tile a particle writes).
    let lazy_field = slam_grid::LikelihoodParams {
        subcell: false,
        ..Default::default()
    };
    let grid = OccupancyGrid::try_new(resolution, model)?
        .with_likelihood(lazy_field)?
        .with_incremental_distance(radius)?;
    Ok(grid)
}

/// The K = n³ sample offsets of the improved proposal: a regular grid spanning
/// ±`range_xy` in x and y and ±`range_theta` in θ (GMapping's `llsamplerange` /
/// `lasamplerange`).
pub(crate) fn sample_offsets(n: usize, range_xy: f64, range_theta: f64) -> Vec<[f64; 3]> {
    let axis = |r: f64| -> Vec<f64> {
        if n == 1 {
            vec![0.0]
        } else {
            (0..n)
                .map(|i| -r + 2.0 * r * i as f64 / (n - 1) as f64)
                .collect()
        }
    };
    let (xy, th) = (axis(range_xy), axis(range_theta));
    let mut out = Vec::with_capacity(n * n * n);
    for &dx in &xy {
        for &dy in &xy {
            for &dt in &th {
                out.push([dx, dy, dt]);
            }
        }
    }
    out
}
