//! The bounds of every configuration value ([`GridFastConfig::validate`]) and the
//! relations that hold once every value is known ([`GridFastConfig::check_resolved`]).

use super::{GridFastConfig, MAX_PARTICLES};
use crate::error::GridFastError;

/// `ok`, or the configuration error naming `field`, its `value` and the bound `expected`.
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

/// Checks an optional value when it is given.
fn check_opt(
    v: Option<f64>,
    ok: impl Fn(f64) -> bool,
    field: &'static str,
    expected: &'static str,
) -> Result<(), GridFastError> {
    match v {
        Some(v) => check(ok(v), field, v, expected),
        None => Ok(()),
    }
}

impl GridFastConfig {
    /// Checks every given value against its documented range (the relations between
    /// values that depend on the preset are checked by [`GridFastConfig::resolve`]).
    pub fn validate(&self) -> Result<(), GridFastError> {
        self.check_top()?;
        self.check_sensor_map()?;
        self.check_matching()?;
        self.check_recovery()?;
        self.check_proposal_motion()?;
        Ok(())
    }

    /// Bounds of the top-level values and the odometry-jump limit.
    fn check_top(&self) -> Result<(), GridFastError> {
        check(
            (1..=MAX_PARTICLES).contains(&self.particles),
            "particles",
            self.particles as f64,
            "1 ..= 10000 (MAX_PARTICLES)",
        )?;
        check(
            self.odometry_jump.max_jump > 0.0,
            "odometry-jump.max-jump",
            self.odometry_jump.max_jump,
            "> 0 m and finite",
        )?;
        check(
            self.linear_update >= 0.0,
            "linear-update",
            self.linear_update,
            ">= 0",
        )?;
        check(
            self.angular_update >= 0.0,
            "angular-update",
            self.angular_update,
            ">= 0",
        )?;
        check(
            (0.0..=1.0).contains(&self.scan_update_fraction),
            "scan-update-fraction",
            self.scan_update_fraction,
            "in [0, 1]",
        )?;
        Ok(())
    }

    /// Bounds of `[sensor]` and `[map]`.
    fn check_sensor_map(&self) -> Result<(), GridFastError> {
        let s = &self.sensor;
        check_opt(s.max_range, |v| v > 0.0, "sensor.max-range", "> 0")?;
        check(
            s.beam_step >= 1,
            "sensor.beam-step",
            s.beam_step as f64,
            ">= 1",
        )?;
        let map = &self.map;
        check_opt(map.resolution, |v| v > 0.0, "map.resolution", "> 0")?;
        check(
            map.log_odds_hit > 0.0,
            "map.log-odds-hit",
            map.log_odds_hit as f64,
            "> 0",
        )?;
        check(
            map.log_odds_miss < 0.0,
            "map.log-odds-miss",
            map.log_odds_miss as f64,
            "< 0",
        )?;
        check(
            map.log_odds_clamp[0] < 0.0,
            "map.log-odds-clamp[0]",
            map.log_odds_clamp[0] as f64,
            "< 0",
        )?;
        check(
            map.log_odds_clamp[1] > 0.0,
            "map.log-odds-clamp[1]",
            map.log_odds_clamp[1] as f64,
            "> 0",
        )?;
        Ok(())
    }

    /// Bounds of `[matching]` but its recovery.
    fn check_matching(&self) -> Result<(), GridFastError> {
        let m = &self.matching;
        check_opt(m.sigma, |v| v > 0.0, "matching.sigma", "> 0")?;
        check_opt(m.field_radius, |v| v > 0.0, "matching.field-radius", "> 0")?;
        check_opt(
            m.likelihood_radius,
            |v| v > 0.0,
            "matching.likelihood-radius",
            "> 0",
        )?;
        check(m.gain > 0.0, "matching.gain", m.gain, "> 0")?;
        check_opt(m.linear_step, |v| v > 0.0, "matching.linear-step", "> 0")?;
        check(
            m.angular_step > 0.0,
            "matching.angular-step",
            m.angular_step,
            "> 0",
        )?;
        check(
            m.refinements <= 30,
            "matching.refinements",
            m.refinements as f64,
            "<= 30",
        )?;
        check(
            (0.0..=1.0).contains(&m.min_inlier_fraction),
            "matching.min-inlier-fraction",
            m.min_inlier_fraction,
            "in [0, 1]",
        )?;
        check_opt(
            m.search_range_xy,
            |v| v >= 0.0,
            "matching.search-range-xy",
            ">= 0",
        )?;
        check_opt(
            m.search_step_xy,
            |v| v > 0.0,
            "matching.search-step-xy",
            "> 0",
        )?;
        check_opt(
            m.search_range_theta,
            |v| v >= 0.0,
            "matching.search-range-theta",
            ">= 0",
        )?;
        check_opt(
            m.search_step_theta,
            |v| v > 0.0,
            "matching.search-step-theta",
            "> 0",
        )?;
        Ok(())
    }

    /// Bounds of `[matching.recovery]`.
    fn check_recovery(&self) -> Result<(), GridFastError> {
        let rc = &self.matching.recovery;
        check(
            (0.0..=1.0).contains(&rc.trigger_fraction),
            "matching.recovery.trigger-fraction",
            rc.trigger_fraction,
            "in [0, 1]",
        )?;
        check(
            (0.0..=1.0).contains(&rc.accept_fraction),
            "matching.recovery.accept-fraction",
            rc.accept_fraction,
            "in [0, 1]",
        )?;
        check_opt(
            rc.range_xy,
            |v| v >= 0.0,
            "matching.recovery.range-xy",
            ">= 0",
        )?;
        check_opt(
            rc.range_theta,
            |v| (0.0..=std::f64::consts::PI).contains(&v),
            "matching.recovery.range-theta",
            "in [0, π]",
        )?;
        check_opt(rc.step_xy, |v| v > 0.0, "matching.recovery.step-xy", "> 0")?;
        check_opt(
            rc.step_theta,
            |v| v > 0.0,
            "matching.recovery.step-theta",
            "> 0",
        )?;
        check(
            rc.turn_trigger >= 0.0,
            "matching.recovery.turn-trigger",
            rc.turn_trigger,
            ">= 0",
        )?;
        check(
            (0.0..=std::f64::consts::PI).contains(&rc.turn_range_theta),
            "matching.recovery.turn-range-theta",
            rc.turn_range_theta,
            "in [0, π]",
        )?;
        check_opt(
            rc.turn_range_xy,
            |v| v >= 0.0,
            "matching.recovery.turn-range-xy",
            ">= 0",
        )?;
        check(
            (0.0..=1.0).contains(&rc.turn_accept_fraction),
            "matching.recovery.turn-accept-fraction",
            rc.turn_accept_fraction,
            "in [0, 1]",
        )?;
        check(
            rc.outlier_weight > 0.0 && rc.outlier_weight < 1.0,
            "matching.recovery.outlier-weight",
            rc.outlier_weight,
            "in (0, 1)",
        )?;
        Ok(())
    }

    /// Bounds of `[proposal]`, `[resampling]` and `[motion]`.
    fn check_proposal_motion(&self) -> Result<(), GridFastError> {
        let p = &self.proposal;
        check(
            (1..=9).contains(&p.samples_per_axis),
            "proposal.samples-per-axis",
            p.samples_per_axis as f64,
            "in 1..=9",
        )?;
        check_opt(
            p.sample_range_xy,
            |v| v >= 0.0,
            "proposal.sample-range-xy",
            ">= 0",
        )?;
        check(
            p.sample_range_theta >= 0.0,
            "proposal.sample-range-theta",
            p.sample_range_theta,
            ">= 0",
        )?;
        check(
            p.corrected_odometry_noise_scale >= 0.0,
            "proposal.corrected-odometry-noise-scale",
            p.corrected_odometry_noise_scale,
            ">= 0",
        )?;
        check(
            (0.0..=1.0).contains(&self.resampling.threshold),
            "resampling.threshold",
            self.resampling.threshold,
            "in [0, 1]",
        )?;
        for (a, name) in self.motion.odometry.alpha.iter().zip([
            "motion.odometry.alpha[0]",
            "motion.odometry.alpha[1]",
            "motion.odometry.alpha[2]",
            "motion.odometry.alpha[3]",
        ]) {
            check(*a >= 0.0, name, *a, ">= 0")?;
        }
        let t = self.motion.odometry.min_translation;
        check(
            (0.0..=slam_models::motion::MAX_MIN_TRANSLATION).contains(&t),
            "motion.odometry.min-translation",
            t,
            "in [0, 1] m (a step shorter than this is taken as a turn in place)",
        )?;
        check(
            self.motion.min_std[0] > 0.0,
            "motion.min-std[0]",
            self.motion.min_std[0],
            "> 0",
        )?;
        check(
            self.motion.min_std[1] > 0.0,
            "motion.min-std[1]",
            self.motion.min_std[1],
            "> 0",
        )?;
        Ok(())
    }

    /// The relations between values that only hold once every value is known.
    pub(super) fn check_resolved(&self) -> Result<(), GridFastError> {
        // Every value is set here (`resolve` calls this after `with_preset`).
        let v = |x: Option<f64>| x.unwrap_or(f64::NAN);
        let (m, rc) = (&self.matching, &self.matching.recovery);
        let (field_radius, likelihood_radius) = (v(m.field_radius), v(m.likelihood_radius));
        let cells = field_radius / v(self.map.resolution);
        check(
            (1.0..=15.0).contains(&cells),
            "matching.field-radius",
            field_radius,
            "between 1 and 15 cells of map.resolution",
        )?;
        // A range limit below one cell maps and matches nothing: every scan was dropped
        // and the run ended on an error about its output's empty map.pgm.
        if let Some(max_range) = self.sensor.max_range {
            check(
                max_range >= v(self.map.resolution),
                "sensor.max-range",
                max_range,
                "at least map.resolution (one cell; a shorter limit maps nothing)",
            )?;
        }
        check(
            likelihood_radius <= field_radius,
            "matching.likelihood-radius",
            likelihood_radius,
            "at most matching.field-radius",
        )?;
        check(
            v(m.search_range_xy) / v(m.search_step_xy) <= 50.0
                && v(m.search_range_theta) / v(m.search_step_theta) <= 50.0,
            "matching.search-range-xy",
            v(m.search_range_xy),
            "at most 50 steps per side in each search dimension",
        )?;
        check(
            v(rc.range_xy) / v(rc.step_xy) <= 50.0 && v(rc.range_theta) / v(rc.step_theta) <= 100.0,
            "matching.recovery.range-xy",
            v(rc.range_xy),
            "at most 50 steps per side in x and y and 100 in θ",
        )?;
        check(
            v(rc.turn_range_xy) / v(rc.step_xy) <= 50.0,
            "matching.recovery.turn-range-xy",
            v(rc.turn_range_xy),
            "at most 50 steps of matching.recovery.step-xy per side",
        )?;
        check(
            rc.turn_range_theta / v(rc.step_theta) <= 400.0,
            "matching.recovery.turn-range-theta",
            rc.turn_range_theta,
            "at most 400 steps of matching.recovery.step-theta per side",
        )
    }
}
