//! The configuration of [`super::LaserOdometry`] (the `[laser-odometry]` table of a run's
//! config) and its checks.

use crate::error::{ensure_config, GridError};
use crate::scanmatch::{EndpointMatchingConfig, ScanMatchConfig, ScanMatchOdometry};
use serde::{Deserialize, Serialize};
use slam_models::Pose2;

/// A prediction of the next scan's pose that the search is centred on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MotionPrediction {
    /// The last pose ⊕ the increment between the two scans before (the same motion per
    /// scan again), its translation clamped to the search window.
    ConstantVelocity,
    /// The last pose: no motion assumed; the search window alone finds the motion.
    ZeroMotion,
}

/// Most hypotheses in [`LaserOdometryConfig::hypotheses`].
pub const MAX_HYPOTHESES: usize = 4;

/// Configuration of [`super::LaserOdometry`] (the `[laser-odometry]` table of a run's config).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct LaserOdometryConfig {
    /// The map and the endpoint model (scan-matching odometry's configuration, its
    /// defaults; its `linear-update` / `angular-update` are the map update thresholds).
    /// Its window search and match range are replaced by this table's `search-range-xy`,
    /// `search-range-theta`, `search-prior-std` and `match-max-range`, and its
    /// `odometry-jump` is not used: giving one of those here is an error naming the key to
    /// set instead.
    pub matcher: ScanMatchConfig,
    /// The search window around each hypothesis: ± this in x and y, metres. Default 1.5 m
    /// (more than the largest step between the bench logs' keyframes: 1.19 m on Intel).
    pub search_range_xy: f64,
    /// … and ± this in θ, radians, in [0, π]. Default 0.8 rad (Intel's keyframes: up to
    /// 0.62 rad apart).
    pub search_range_theta: f64,
    /// Standard deviations (metres, radians) of the weak Gaussian prior around each
    /// hypothesis that decides between near-equal fits (a corridor's length); 0 for none.
    /// Default (0.5, 0.3).
    pub search_prior_std: [f64; 2],
    /// End points farther than this from the sensor are not matched, metres. Default 30.
    pub match_max_range: f64,
    /// The predictions searched around, in order of preference on a tie (1 to 4, no
    /// repeats). Default zero motion, then constant velocity.
    pub hypotheses: Vec<MotionPrediction>,
    /// With a rotation prior, the ± θ range of the search around its hypothesis, radians,
    /// in [0, π]. Default 0.1 rad.
    pub prior_range_theta: f64,
    /// Scans per submap (the local map holds this to twice this many written scans); 0 for
    /// one map of every scan. Default 20 (Cartographer's default is 90 scans at full
    /// rate; laser odometry writes a scan every 0.1 m or 0.1 rad, so 20 to 40 scans span a
    /// few metres of travel, and on keyframe logs up to 25 m).
    pub submap_scans: usize,
    /// The narrow search around the prediction tried first: ± this in x and y, metres
    /// (at most `search-range-xy`); 0 with `narrow-range-theta` 0: no narrow search, the
    /// wide one on every scan. Default 0.3 m, with `good-fit` above 1 (the wide search on
    /// every scan too) and `wide-margin` 0.03: the narrow match kept unless a wide one fits
    /// clearly better (on 2026-12-03: graph on Intel without odometry 0.351 → 0.278 m,
    /// the office's worst of seeds 0–4 0.87 → 0.41 m for gridfast, docs/results.md; with
    /// `good-fit` 0.95 it was cheaper but less accurate).
    pub narrow_range_xy: f64,
    /// … and ± this in θ, radians, in [0, π] (at most the prediction's own θ range).
    /// Default 0.25 rad.
    pub narrow_range_theta: f64,
    /// The narrow search's match is taken, without the wide search, when at least this
    /// fraction of the end points fit the map (end within `likelihood-radius` of an
    /// occupied cell), ≥ 0; above 1 the wide search always runs. Default 1.5 (always): on
    /// real scans (Intel's keyframes, ~1 m apart) a narrow match around a poor prediction
    /// often fits 80–90 % of the beams at a wrong pose, so a good fit alone does not make
    /// the wide search unnecessary (0.95 made laser odometry less accurate there).
    pub good_fit: f64,
    /// Standard deviations (metres, radians) of the motion prior around the prediction
    /// that weighs the wide search's results against each other and against the narrow
    /// one: the highest L − ½ (|Δxy|²/σ_xy² + Δθ²/σ_θ²) wins, L the fine log-likelihood
    /// (tempered by `matching.gain`); 0 for none. Default (0, 0): none (with (0.3, 0.3)
    /// laser odometry alone was no better on Intel, docs/results.md).
    pub motion_prior_std: [f64; 2],
    /// The narrow search's match is kept over the wide search's winner unless the latter
    /// has more inliers by more than this fraction of the end points, in [0, 1] (a place
    /// far from the prediction must fit clearly better, not about as well: in a corridor
    /// or a row of like offices many places fit); only with the narrow search on. Default
    /// 0.03.
    pub wide_margin: f64,
    /// Multi-hypothesis laser odometry (over a whole recording, [`super::laser_odometry`],
    /// or a stream of scans, [`super::LaserOdometryStream`], whose poses then come out up
    /// to this many scans late; [`super::LaserOdometry::process`] decides every step at
    /// once): after an ambiguous step, scans over which each of its poses is followed as a
    /// branch (its own local map and pose chain) before the branch whose matches fit the
    /// most end points in mapped cells over those scans is kept; 0: off, one branch. Default 5 (on the
    /// bench logs 4–6 hold csail and fhw, but acapulco's corridor only 5: 1.530 m at 4,
    /// 2.670 m at 6, docs/results.md).
    pub branch_lag: usize,
    /// Most branches followed at once, 2 to [`MAX_BRANCHES`] (an ambiguous step when as
    /// many are followed is decided at once, as without branches). Default 3.
    pub max_branches: usize,
    /// A step is ambiguous when the narrow match and the wide search's best are distinct
    /// poses (more than [`DISTINCT_XY`] or [`DISTINCT_THETA`] apart) and the one not
    /// taken fits at most this fraction of the end points fewer than the one taken (or
    /// more), in [0, 1]. Default 0.2 (0.1 left csail two steps 2 m wrong, laser
    /// odometry alone 0.647 against 0.466 m; the other six bench logs the same).
    pub ambiguity_margin: f64,
    /// With branches on: when the match taken fits less than this fraction of the end
    /// points, the wide search also runs over the headings from `search-range-theta` to
    /// `turn-search-range` either side of the last pose (a turn faster than the window),
    /// and its best is a branch when it fits more end points than the match taken (and is
    /// a distinct pose); 0: never. Default 0.7 (a turn candidate kept when it merely fit
    /// within `ambiguity-margin` took fhw's turn on the spot 113° the wrong way).
    pub turn_search_fit: f64,
    /// The largest heading change from the last pose the turn search covers, radians, in
    /// [0, π] (at most `search-range-theta`: no turn search). Default 1.6 rad (92°; the
    /// bench logs' largest turn between two keyframes is 78°, csail).
    pub turn_search_range: f64,
}

/// Most branches of multi-hypothesis laser odometry
/// ([`LaserOdometryConfig::max_branches`]).
pub const MAX_BRANCHES: usize = 4;

/// Two matches of one scan more than this far apart (metres) are distinct poses (an
/// ambiguous step's branches), [`LaserOdometryConfig::ambiguity_margin`].
pub const DISTINCT_XY: f64 = 0.2;

/// … or more than this apart in heading, radians.
pub const DISTINCT_THETA: f64 = 0.1;

impl Default for LaserOdometryConfig {
    fn default() -> Self {
        Self {
            matcher: ScanMatchConfig::default(),
            search_range_xy: 1.5,
            search_range_theta: 0.8,
            search_prior_std: [0.5, 0.3],
            match_max_range: 30.0,
            hypotheses: vec![
                MotionPrediction::ZeroMotion,
                MotionPrediction::ConstantVelocity,
            ],
            prior_range_theta: 0.1,
            submap_scans: 20,
            narrow_range_xy: 0.3,
            narrow_range_theta: 0.25,
            good_fit: 1.5,
            motion_prior_std: [0.0, 0.0],
            wide_margin: 0.03,
            branch_lag: 5,
            max_branches: 3,
            ambiguity_margin: 0.2,
            turn_search_fit: 0.7,
            turn_search_range: 1.6,
        }
    }
}

impl LaserOdometryConfig {
    /// The configuration of each submap's matching: `matcher` with this table's window,
    /// prior and match range.
    pub fn matcher_config(&self) -> ScanMatchConfig {
        ScanMatchConfig {
            matching: EndpointMatchingConfig {
                search_range_xy: self.search_range_xy,
                search_range_theta: self.search_range_theta,
                search_prior_std: self.search_prior_std,
                ..self.matcher.matching
            },
            match_max_range: self.match_max_range,
            ..self.matcher.clone()
        }
    }

    /// The `[laser-odometry.matcher]` keys this table replaces ([`Self::matcher_config`])
    /// or does not use (`odometry-jump`) must keep their defaults: a value given there was
    /// ignored without a word (NaN and infinities included, since they were never checked).
    /// The error names the key and the one to set instead.
    fn check_replaced_matcher_keys(&self) -> Result<(), GridError> {
        let (m, d) = (&self.matcher, ScanMatchConfig::default());
        let same = |a: f64, b: f64| a.to_bits() == b.to_bits();
        let replaced: [(&'static str, f64, bool, &'static str); 5] = [
            (
                "matcher.matching.search-range-xy",
                m.matching.search_range_xy,
                same(m.matching.search_range_xy, d.matching.search_range_xy),
                "its default (not used: set laser-odometry.search-range-xy)",
            ),
            (
                "matcher.matching.search-range-theta",
                m.matching.search_range_theta,
                same(m.matching.search_range_theta, d.matching.search_range_theta),
                "its default (not used: set laser-odometry.search-range-theta)",
            ),
            (
                "matcher.matching.search-prior-std",
                m.matching.search_prior_std[0],
                same(
                    m.matching.search_prior_std[0],
                    d.matching.search_prior_std[0],
                ) && same(
                    m.matching.search_prior_std[1],
                    d.matching.search_prior_std[1],
                ),
                "its default (not used: set laser-odometry.search-prior-std)",
            ),
            (
                "matcher.match-max-range",
                m.match_max_range,
                same(m.match_max_range, d.match_max_range),
                "its default (not used: set laser-odometry.match-max-range)",
            ),
            (
                "matcher.odometry-jump",
                m.odometry_jump.max_jump,
                same(m.odometry_jump.max_jump, d.odometry_jump.max_jump)
                    && m.odometry_jump.on_jump == d.odometry_jump.on_jump,
                "its default (laser odometry makes the odometry: no jump limit is used)",
            ),
        ];
        for (key, value, ok, expected) in replaced {
            ensure_config(ok, key, value, expected)?;
        }
        Ok(())
    }

    /// Checks every value (the matcher's by [`ScanMatchOdometry::new`]'s rules), naming the
    /// key that is wrong.
    pub fn validate(&self) -> Result<(), GridError> {
        self.check_replaced_matcher_keys()?;
        ScanMatchOdometry::new(self.matcher_config(), Pose2::IDENTITY, 0)?;
        let h = &self.hypotheses;
        let repeated = h.iter().enumerate().any(|(i, a)| h[..i].contains(a));
        ensure_config(
            (1..=MAX_HYPOTHESES).contains(&h.len()) && !repeated,
            "hypotheses",
            h.len() as f64,
            "1 to 4 predictions, none repeated",
        )?;
        ensure_config(
            (0.0..=std::f64::consts::PI).contains(&self.prior_range_theta),
            "prior-range-theta",
            self.prior_range_theta,
            "in [0, π] rad",
        )?;
        ensure_config(
            self.narrow_range_xy >= 0.0 && self.narrow_range_xy.is_finite(),
            "narrow-range-xy",
            self.narrow_range_xy,
            ">= 0 m",
        )?;
        ensure_config(
            (0.0..=std::f64::consts::PI).contains(&self.narrow_range_theta),
            "narrow-range-theta",
            self.narrow_range_theta,
            "in [0, π] rad",
        )?;
        ensure_config(
            self.good_fit >= 0.0 && self.good_fit.is_finite(),
            "good-fit",
            self.good_fit,
            ">= 0 (above 1: always the wide search)",
        )?;
        for (v, name) in self
            .motion_prior_std
            .into_iter()
            .zip(["motion-prior-std[0]", "motion-prior-std[1]"])
        {
            ensure_config(v >= 0.0 && v.is_finite(), name, v, ">= 0 (0: no prior)")?;
        }
        ensure_config(
            (2..=MAX_BRANCHES).contains(&self.max_branches),
            "max-branches",
            self.max_branches as f64,
            "2 to 4",
        )?;
        ensure_config(
            (0.0..=1.0).contains(&self.ambiguity_margin),
            "ambiguity-margin",
            self.ambiguity_margin,
            "in [0, 1]",
        )?;
        ensure_config(
            (0.0..=1.0).contains(&self.turn_search_fit),
            "turn-search-fit",
            self.turn_search_fit,
            "in [0, 1] (0: no turn search)",
        )?;
        ensure_config(
            (0.0..=std::f64::consts::PI).contains(&self.turn_search_range),
            "turn-search-range",
            self.turn_search_range,
            "in [0, π] rad",
        )?;
        ensure_config(
            (-1.0..=1.0).contains(&self.wide_margin),
            "wide-margin",
            self.wide_margin,
            "in [-1, 1] (-1: the wide search's winner always replaces the narrow match)",
        )
    }
}
