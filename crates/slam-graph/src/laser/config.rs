//! The configuration of [`super::LaserGraphSlam`].

use crate::error::GraphError;
use crate::kernel::RobustKernel;
use crate::optimizer::{Initialisation, OptimizerConfig};
use serde::{Deserialize, Serialize};
use slam_grid::{InverseSensorModel, LikelihoodParams, RefinedCorrelativeMatcher};
use slam_models::OdometryJumpLimit;

mod validate;

/// Most scans per submap: a submap's grid and its loop-closure pyramid grow with it.
pub const MAX_SUBMAP_SCANS: usize = 10_000;

/// Standard deviations of one odometry increment Δ = o_{i−1}⁻¹ ⊕ o_i between consecutive
/// records, by the usual linear growth with the motion (Probabilistic Robotics §5.4's
/// α-model reduced to one translation and one rotation term each):
///
/// σ_xy = `translation_per_metre`·|Δt| + `translation_per_radian`·|Δθ| + `min_translation`,
/// σ_θ = `rotation_per_radian`·|Δθ| + `rotation_per_metre`·|Δt| + `min_rotation`,
///
/// with |Δt| the distance and |Δθ| the absolute heading change of the increment; the
/// covariance is diag(σ_xy², σ_xy², σ_θ²) in the frame of the earlier record.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default, rename_all = "kebab-case")]
pub struct OdometryNoise {
    /// Metres of position noise per metre travelled. Default 0.1.
    pub translation_per_metre: f64,
    /// Metres of position noise per radian turned. Default 0.01.
    pub translation_per_radian: f64,
    /// Radians of heading noise per radian turned. Default 0.1.
    pub rotation_per_radian: f64,
    /// Radians of heading noise per metre travelled. Default 0.05.
    pub rotation_per_metre: f64,
    /// Position noise floor per increment, metres (> 0, so that a record without motion
    /// is held to its neighbour, not left free). Default 0.002.
    pub min_translation: f64,
    /// Heading noise floor per increment, radians (> 0). Default 0.001.
    pub min_rotation: f64,
}

impl Default for OdometryNoise {
    fn default() -> Self {
        Self {
            translation_per_metre: 0.1,
            translation_per_radian: 0.01,
            rotation_per_radian: 0.1,
            rotation_per_metre: 0.05,
            min_translation: 0.002,
            min_rotation: 0.001,
        }
    }
}

/// How the covariance of a local scan match (the edge between consecutive keyframes) is
/// estimated before the `match-min-std` floor is added and it becomes the edge's
/// information. (Loop closures keep the matcher's own.)
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case", tag = "kind")]
pub enum MatchCovariance {
    /// The matcher's own: Gauss-Newton's σ̂²H⁻¹ at its optimum (the correlative or
    /// branch-and-bound lattice's when the refinement fails). A local, quadratic and, with
    /// independent beams, very confident estimate: once floored, nearly isotropic.
    Matcher,
    /// Olson 2009's covariance of the response (eq. 14–16): the moments of
    /// wₖ ∝ exp(ℓ(xₖ)/T) over a lattice of poses around the match (one cell, and the
    /// rotation that moves the farthest end point one cell, apart), ℓ the scan's
    /// likelihood-field log-likelihood. Wide enough to see that a corridor's response is
    /// flat along its axis, so the odometry keeps its weight there.
    #[serde(rename_all = "kebab-case")]
    Response {
        /// Half-width of the translation window, metres (> 0, ≤ 2). Default 0.3.
        linear_window: f64,
        /// Half-width of the rotation window, radians (in [0, 0.5]). Default 0.03.
        angular_window: f64,
        /// T (≥ 1): 1 treats the beams as independent; larger values flatten the
        /// response for their correlation and the map's errors. Default 10.
        temperature: f64,
    },
}

impl Default for MatchCovariance {
    fn default() -> Self {
        MatchCovariance::Response {
            linear_window: 0.3,
            angular_window: 0.03,
            temperature: 10.0,
        }
    }
}

/// Configuration of [`super::LaserGraphSlam`]. Lengths in metres, angles in radians; the
/// keys are kebab-case in TOML (`submap-scans = 20`), the nested slam-grid structs keep
/// their own names.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default, rename_all = "kebab-case")]
pub struct LaserGraphConfig {
    /// Cell edge of the submaps and of the rendered map, metres, in [1e-4, 10]. Default 0.05.
    pub resolution: f64,
    /// Inverse sensor model of the submaps (slam-grid's defaults).
    pub sensor_model: InverseSensorModel,
    /// Likelihood field the matchers score against (slam-grid's defaults: σ = 5 cm,
    /// truncated at 0.3 m).
    pub likelihood: LikelihoodParams,
    /// End points farther than this from the sensor are not matched, metres. Default 20.
    pub match_max_range: f64,
    /// A scan becomes a keyframe (matched, inserted, a node of the online graph) once the
    /// odometry moved this far since the last keyframe, metres. Default 0.2. The first
    /// scan is always one.
    pub keyframe_distance: f64,
    /// … or turned this much, radians. Default 0.15.
    pub keyframe_angle: f64,
    /// Scan-to-submap matcher for the odometry edges: correlative search around the
    /// odometry prediction, then Gauss-Newton (slam-grid). Default: ±0.3 m, ±0.3 rad.
    pub local_matcher: RefinedCorrelativeMatcher,
    /// A local match scoring below this mean field value per end point is rejected and the
    /// odometry increment used instead. Default 0.25.
    pub local_min_score: f64,
    /// The search over every heading that recovers a local match the odometry put
    /// outside the window (turns in place; [`super::LocalRecovery`]).
    pub local_recovery: super::LocalRecovery,
    /// Factor on the matches' covariances before they become information. Default 1.
    pub match_covariance_scale: f64,
    /// How a match's covariance is estimated. Default: from the tempered likelihood
    /// sampled over ±0.3 m and ±0.03 rad at T = 10.
    pub match_covariance: MatchCovariance,
    /// Standard deviations (m, rad) added in quadrature to a match's covariance before it
    /// becomes an edge's information: the sampled response is a lower bound on the error
    /// (it knows nothing of map errors). Added, not a lower bound on the eigenvalues, so
    /// the response's anisotropy survives. Default (0.02, 0.002): a scan fixes the heading
    /// far better than 0.01 rad, the earlier floor, which let the odometry's heading
    /// errors into the office's map (docs/results/graph.md).
    pub match_min_std: [f64; 2],
    /// A local match whose translational σ_max / σ_min (of its edge's information, the
    /// floor included) is this or more is degenerate along σ_max's direction (a
    /// corridor's axis: the scan does not fix the position along it, and the match slides
    /// there, short of the truth); along that direction alone the keyframe graph's edge
    /// takes the odometry increment, by least squares with the odometry's variance along
    /// it, the odometry's weight ramping up from 0 at this ratio to full at 1.5× it (Zhang,
    /// Kaess and Singh, ICRA 2016; `covariance::fuse_degenerate`). The submaps keep the
    /// match's pose (the fused one in the submaps cost 0.24 m on edmonton-hard). ≥ 1, or 0
    /// for never. Default 2. Without it, holding the keyframes (the default) left the
    /// simulated office 4.1 % too small: its corridor matches were 2.9 % short
    /// (docs/results/graph.md).
    pub degenerate_anisotropy: f64,
    /// Scans per submap (≥ 2, ≤ [`MAX_SUBMAP_SCANS`]); a new submap starts every half of
    /// this, so two overlap and the older (fuller) one is matched against (Hess et al.
    /// 2016 §IV). Default 20.
    pub submap_scans: usize,
    /// The odometry edges' noise (every record is a node of the smoothed trajectory).
    pub odometry_noise: OdometryNoise,
    /// Loop closure: a branch-and-bound match is accepted at this mean field value per end
    /// point or above, in [0, 1]. Default 0.55.
    pub loop_min_score: f64,
    /// Loop closure: the search radius (the branch-and-bound translation window) around the
    /// predicted pose before any uncertainty, metres. Default 0.5.
    pub loop_radius: f64,
    /// Loop closure: metres added to the radius per metre of graph distance between the
    /// submap and the searching keyframe (the scan-matching chain since the closures that
    /// last joined them: their relative uncertainty grows with it). Default 0.05.
    pub loop_radius_growth: f64,
    /// Loop closure: the largest radius, metres (≤ 50). Default 12: the drift of a 1.3 km
    /// lap of the simulated campus is 5–10 m (docs/results/graph.md).
    pub loop_max_radius: f64,
    /// Loop closure: the rotation window before any uncertainty, radians. Default 0.2.
    pub loop_angle: f64,
    /// Loop closure: radians added to the rotation window per metre of path between the
    /// of graph distance between the submap and the searching keyframe. Default 0.02.
    pub loop_angle_growth: f64,
    /// Loop closure: the largest rotation window, radians (≤ π). Default 0.8.
    pub loop_max_angle: f64,
    /// Loop closure: a match is rejected as ambiguous (a corridor, a repeated room) when
    /// the best score found near any of 24 poses shifted from it by 0.25, 0.5 or 1 m in 8
    /// directions (a small search around each) reaches this fraction of its own score
    /// (Olson 2009 §V's uniqueness test, in a cheap form), in (0, 1]; 1 switches the test
    /// off. Default 0.9.
    pub loop_ambiguity_ratio: f64,
    /// Loop closure: a match whose score surface is flat along one direction is rejected:
    /// the response covariance of the match on the submap (`match-covariance`'s sampling,
    /// its default window when that is `matcher`) has translational standard deviations
    /// σ_max / σ_min above this bound (the square root of the 2 × 2 block's condition
    /// number; a corridor's is about 12, a room's under 2), ≥ 1. Default 4.
    pub loop_max_anisotropy: f64,
    /// Loop closure: candidate closures are held back and checked for mutual consistency
    /// in groups (Olson 2009, `consistency.rs`): a group collects the closures found over
    /// at most this many keyframes from its first (≥ 1). Default 10.
    pub loop_group_span: usize,
    /// … and is evaluated earlier once this many keyframes (≥ 1) found no closure. Default 3.
    pub loop_group_gap: usize,
    /// Loop closure: the fewest mutually consistent closures of a group that enter the
    /// graph (≥ 1; 1 lets a lone closure in unchecked). Default 2.
    pub loop_group_min_size: usize,
    /// Loop closure: a group's dominant cluster is accepted only when λ₁ / λ₂ of its
    /// consistency matrix reaches this (≥ 1; Olson's confidence test). Default 2.
    pub loop_group_min_ratio: f64,
    /// Loop closure: standard deviation of the scan-matching chain's drift per metre of
    /// path [m/m, rad/m], the uncertainty of the local poses between two closures of a
    /// group (each ≥ 0). Default [0.02, 0.005].
    pub loop_group_drift: [f64; 2],
    /// Loop closure: every candidate submap is searched first within this radius, metres
    /// (and `loop-wide-angle`), the narrow window; the whole window (up to
    /// `loop-max-radius`) only when it is wider and the narrow search found nothing
    /// acceptable: at most one wide search per keyframe, and after one that found nothing
    /// none for `loop-wide-interval` keyframes (the per-scan budget that keeps the search
    /// cheap when the uncertainty is large). Default 3.
    pub loop_wide_radius: f64,
    /// Loop closure: the narrow window's rotation half-width, radians (see
    /// `loop-wide-radius`). Default 0.6.
    pub loop_wide_angle: f64,
    /// Loop closure: keyframes after a wide search that found nothing before the next
    /// (≥ 1). Default 4.
    pub loop_wide_interval: usize,
    /// Loop closure: levels of the max-pyramid (slam-grid's `MaxPyramid`). Default 6.
    pub loop_depth: u32,
    /// Loop closure: a submap is searched only once its last scan is this many keyframes
    /// old (the overlapping local submaps are not loops). Default 30.
    pub loop_min_scan_gap: usize,
    /// Loop closure: at most this many submaps (the nearest) are searched per keyframe.
    /// Default 3.
    pub loop_max_candidates: usize,
    /// Loop closure: the fraction of its candidacies in which a submap is searched, in
    /// (0, 1]. Each submap counts the keyframes for which it is among the
    /// `loop-max-candidates` nearest (n) and the searches run (m), and is searched when
    /// m / n < ratio after counting this one (Cartographer's per-submap `FixedRatioSampler`,
    /// `constraint_builder.sampling_ratio`, 0.3 there): its first candidacy is always
    /// searched, then one in 1 / ratio; deterministic. Default 1, every candidate
    /// searched: on the robustness suite 0.5 cut Intel's CPU by a quarter but lost
    /// closures elsewhere (acapulco-moderate 0.18 → 0.69 m aligned ATE;
    /// docs/results/graph.md).
    pub loop_sampling_ratio: f64,
    /// Loop closure: at most this many finished submaps' grids and pyramids kept for
    /// reuse (least recently used dropped; a submap not in the cache is rebuilt from its
    /// keyframes' scans, the same grid and pyramid). Default 64: the byte budget
    /// `loop-pyramid-cache-bytes` is what bounds it on real logs.
    pub loop_pyramid_cache: usize,
    /// Loop closure: the cached pyramids' bytes are kept under this, less one pyramid of
    /// the cache's mean size, before a new one is built (least recently used dropped; at
    /// least one kept). Default 48 MiB: on `bench/intel.log` (2 MB per pyramid) about 24
    /// submaps, which saves most of the 154 rebuilds of its 71 submaps that a cache of 6
    /// made (a sixth of the run's CPU); on acapulco (8 MB per pyramid) about 6, as before.
    pub loop_pyramid_cache_bytes: usize,
    /// The optimiser (slam-graph's Levenberg-Marquardt), run after every keyframe that
    /// added a loop closure. Default: the optimiser's default treatment of loop closures
    /// (DCS Φ = 1 on them, then the consistent ones back at full weight; odometry untouched:
    /// see `slam_graph::optimizer`), warm-started from the current keyframe poses (no LAGO
    /// initialisation), at most 20 iterations.
    pub optimizer: OptimizerConfig,
    /// Whether the loop closures into one submap share one closure's information in the
    /// keyframe graph (each weighed by 1 / their number): they match against the same
    /// grid, so their errors are largely common. Default true. `false` counts every
    /// closure as independent, as before: on the simulated campus without odometry (seed
    /// 2) a hundred closures into a submap then outweighed the scan-matching chain and
    /// bent the map by up to 1 m (docs/results/graph.md).
    pub closures_share_submap: bool,
    /// Whether the trajectory graph (one node per record) holds every keyframe at the
    /// keyframe graph's optimum. `true` (the default): it places only the records between
    /// keyframes, each run of them the odometry chain bent to meet the two keyframes at
    /// its ends, the correction shared in proportion to the odometry edges' uncertainty;
    /// the keyframes' poses are the keyframe graph's (odometry there only where a match
    /// failed or was degenerate).
    /// `false`: the keyframes are estimated again, jointly with every record's odometry
    /// edge, the scan-matching edges and the loop closures (the odometry then weighs on
    /// the keyframes too). On the simulated campus the joint estimate shrank the map by
    /// 0.28 % and doubled its aligned ATE (0.536 m against 0.28 m); on Intel's relations
    /// it cost 6 mm (docs/results/graph.md, "the trajectory graph").
    pub smoother_holds_keyframes: bool,
    /// The optimiser of the trajectory graph (one node per record). Default: LM without a
    /// robust kernel, at most 20 iterations: a kernel on every edge would down-weight the
    /// odometry edges that disagree most with the scan matches, which are exactly the
    /// ones the smoother must correct (on Intel, DCS there costs 0.9° of relations error);
    /// false closures are kept out by `smoother-max-closure-chi2` instead.
    pub smoother: OptimizerConfig,
    /// A loop closure whose squared error eᵀΩe in the optimised keyframe graph exceeds
    /// this is treated as false (the robust kernel rejected it) and left out of the
    /// trajectory graph (only when the trajectory graph does not hold the keyframes,
    /// `smoother-holds-keyframes = false`). Default 16.27, the χ²(3) 99.9 % quantile.
    pub smoother_max_closure_chi2: f64,
    /// The largest odometry jump between two consecutive records, and whether a larger
    /// one is an error (default: beyond 5 m) or skipped.
    pub odometry_jump: OdometryJumpLimit,
}

impl Default for LaserGraphConfig {
    fn default() -> Self {
        let mut local_matcher = RefinedCorrelativeMatcher::default();
        local_matcher.correlative.linear_window = 0.3;
        local_matcher.correlative.angular_window = 0.3;
        Self {
            resolution: 0.05,
            sensor_model: InverseSensorModel::default(),
            likelihood: LikelihoodParams::default(),
            match_max_range: 20.0,
            keyframe_distance: 0.2,
            keyframe_angle: 0.15,
            local_matcher,
            local_min_score: 0.25,
            local_recovery: super::LocalRecovery::default(),
            match_covariance_scale: 1.0,
            match_covariance: MatchCovariance::default(),
            match_min_std: [0.02, 0.002],
            submap_scans: 20,
            odometry_noise: OdometryNoise::default(),
            loop_min_score: 0.55,
            loop_radius: 0.5,
            loop_radius_growth: 0.05,
            loop_max_radius: 12.0,
            loop_angle: 0.2,
            loop_angle_growth: 0.02,
            loop_max_angle: 0.8,
            loop_ambiguity_ratio: 0.9,
            loop_max_anisotropy: 4.0,
            loop_group_span: 10,
            loop_group_gap: 3,
            loop_group_min_size: 2,
            loop_group_min_ratio: 2.0,
            loop_group_drift: [0.02, 0.005],
            loop_wide_radius: 3.0,
            loop_wide_angle: 0.6,
            loop_wide_interval: 4,
            loop_depth: 6,
            loop_min_scan_gap: 30,
            loop_max_candidates: 3,
            loop_sampling_ratio: 1.0,
            loop_pyramid_cache: 64,
            loop_pyramid_cache_bytes: 48 << 20,
            optimizer: OptimizerConfig {
                initialisation: Initialisation::Input,
                max_iterations: 20,
                ..OptimizerConfig::default()
            },
            closures_share_submap: true,
            smoother_holds_keyframes: true,
            degenerate_anisotropy: 2.0,
            smoother: OptimizerConfig {
                initialisation: Initialisation::Input,
                closure_kernel: RobustKernel::None,
                max_iterations: 20,
                ..OptimizerConfig::default()
            },
            smoother_max_closure_chi2: 16.27,
            odometry_jump: OdometryJumpLimit::default(),
        }
    }
}

/// `Err(GraphError::FrontEndConfig)` unless `ok` (and `value` finite).
pub(super) fn ensure(
    ok: bool,
    field: &'static str,
    value: f64,
    expected: &'static str,
) -> Result<(), GraphError> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(GraphError::FrontEndConfig {
            field,
            value,
            expected,
        })
    }
}
