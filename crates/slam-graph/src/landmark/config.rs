//! Configuration of the landmark front end ([`super::GraphLandmarkSlam`]).

use crate::error::GraphError;
use crate::optimizer::{Initialisation, OptimizerConfig};
use serde::{Deserialize, Serialize};
use slam_models::association::AssociationOptions;
use slam_models::measurement::RangeBearingModel;
use slam_models::motion::MotionModels;
use slam_models::ModelError;

/// Most landmarks the map may hold: the association belief is dense, (3 + 2n)² × 8 bytes,
/// 3.2 GB at this bound.
pub const MAX_LANDMARKS: usize = 10_000;

/// Parameters of [`super::GraphLandmarkSlam`]. The noise models mean what they mean in
/// `slam_ekf::EkfConfig` (same names, same defaults) and the `[association]` table is the
/// same struct ([`AssociationOptions`]), so one data set's settings carry over between the two.
///
/// ```
/// let c: slam_graph::landmark::GraphLandmarkConfig = toml::from_str("optimize-every = 5").unwrap();
/// assert_eq!(c.optimize_every, 5);
/// c.validate().unwrap();
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct GraphLandmarkConfig {
    /// Motion models (velocity and odometry, PR tables 5.3/5.6); their noise, propagated
    /// between two pose nodes, is the information of the odometry edge.
    pub motion: MotionModels,
    /// Extra process noise per control, variances (m², m², rad²) added to the motion
    /// model's in the robot frame (as the EKF's `extra_motion_noise`).
    pub extra_motion_noise: [f64; 3],
    /// Range-bearing sensor noise Q = diag(σr², σφ²); Q⁻¹ is each landmark edge's
    /// information.
    pub sensor: RangeBearingModel,
    /// Data association: the mode, its gates and provisional landmarks, the EKF's
    /// `[association]` table (a bare mode string `association = "auto"` is still read).
    #[serde(deserialize_with = "slam_models::association::options_or_mode")]
    pub association: AssociationOptions,
    /// Most landmarks the map may hold (1 ..= [`MAX_LANDMARKS`]).
    pub max_landmarks: usize,
    /// A new pose node is added at every update with observations, and after this many
    /// updates without any (≥ 1); between nodes the controls are composed into one odometry
    /// edge whose covariance is the motion noise propagated over them.
    pub max_steps_between_nodes: usize,
    /// The graph is optimised (and the association belief recomputed from its marginals)
    /// after every this many new pose nodes (≥ 1), and once more by `finish`.
    pub optimize_every: usize,
    /// … or, when more, after the graph's pose nodes grew by this fraction (0 ..= 1) since the
    /// last optimisation: with a fixed interval a run costs O(length²); with a fraction it
    /// is linear (each optimisation's cost is proportional to the graph, and their number
    /// grows only logarithmically with it per unit of length).
    pub optimize_growth: f64,
    /// An observation edge is a closure (under the optimiser's loop-closure treatment, see
    /// the module documentation of [`super`]) when its landmark was first seen more than this
    /// many pose nodes before the observing pose node (default 3: with 20, wrong ids of
    /// landmarks seen in the last 20 nodes were not treated and `loop` with 5 % false ids
    /// ended at 0.15 m aligned ATE on seed 0 instead of 0.025 m).
    pub closure_window: u64,
    /// The optimiser; its `max_iterations` bounds each incremental optimisation (the
    /// estimate is warm-started, so a few iterations suffice: no LAGO). The loop-closure
    /// treatment is on by default (DCS Φ = 1 on the closures, then closures with
    /// eᵀΩe ≤ χ²₂(0.999) back at full weight); `[optimizer.closure-kernel] kind = "none"`
    /// turns it off.
    pub optimizer: OptimizerConfig,
}

impl Default for GraphLandmarkConfig {
    /// The EKF's defaults for the shared keys; a node at every update with observations (and
    /// at least every 10), optimisation after every node or 1 % growth of the graph, whichever
    /// comes later, with at most 10 LM iterations each.
    fn default() -> Self {
        Self {
            motion: MotionModels::default(),
            extra_motion_noise: [0.0; 3],
            sensor: RangeBearingModel::default(),
            association: AssociationOptions::default(),
            max_landmarks: 5000,
            max_steps_between_nodes: 10,
            optimize_every: 1,
            optimize_growth: 0.01,
            closure_window: 3,
            optimizer: OptimizerConfig {
                initialisation: Initialisation::Input,
                closure_kernel: crate::RobustKernel::Dcs { phi: 1.0 },
                max_iterations: 10,
                ..OptimizerConfig::default()
            },
        }
    }
}

fn check(
    field: &'static str,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), GraphError> {
    Ok(slam_models::error::ensure_config(
        ok,
        "graph landmark SLAM",
        field,
        value,
        expected,
    )?)
}

fn at_least_one(field: &'static str, v: usize) -> Result<(), GraphError> {
    check(field, v as f64, v >= 1, "at least 1")
}

impl GraphLandmarkConfig {
    /// Checks every field against its documented range; the error names the field, the
    /// value and the bound.
    pub fn validate(&self) -> Result<(), GraphError> {
        check(
            "max_landmarks",
            self.max_landmarks as f64,
            (1..=MAX_LANDMARKS).contains(&self.max_landmarks),
            "1 ..= 10000 (MAX_LANDMARKS)",
        )?;
        for v in self.extra_motion_noise {
            check("extra_motion_noise", v, v >= 0.0, "finite and >= 0")?;
        }
        let named = |e: ModelError| match e {
            ModelError::OutOfRange {
                name,
                value,
                expected,
            } => GraphError::InvalidConfig(slam_models::ConfigError::new(
                "graph landmark SLAM",
                name,
                value,
                expected,
            )),
            other => GraphError::InvalidInput(other.to_string()),
        };
        self.motion.validate().map_err(named)?;
        self.sensor.validate().map_err(named)?;
        self.association.validate().map_err(named)?;
        at_least_one("max_steps_between_nodes", self.max_steps_between_nodes)?;
        at_least_one("optimize_every", self.optimize_every)?;
        let g = self.optimize_growth;
        check("optimize_growth", g, (0.0..=1.0).contains(&g), "in [0, 1]")?;
        self.optimizer.validate()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_valid_and_round_trips() {
        let c = GraphLandmarkConfig::default();
        c.validate().unwrap();
        let s = toml::to_string(&c).unwrap();
        let back: GraphLandmarkConfig = toml::from_str(&s).unwrap();
        assert_eq!(back, c);
        assert!(toml::from_str::<GraphLandmarkConfig>("no_such_field = 1").is_err());
    }

    /// configs/graph-landmark.toml states the defaults (the closure treatment on).
    #[test]
    fn example_file_is_the_default() {
        let file: GraphLandmarkConfig =
            toml::from_str(include_str!("../../../../configs/graph-landmark.toml")).unwrap();
        assert_eq!(file, GraphLandmarkConfig::default());
        assert_eq!(file.closure_window, 3);
        assert_ne!(file.optimizer.closure_kernel, crate::RobustKernel::None);
    }

    #[test]
    fn rejects_bad_values_naming_the_field() {
        let bad = |c: GraphLandmarkConfig| match c.validate() {
            Err(GraphError::InvalidConfig(e)) => e.field,
            other => panic!("{other:?}"),
        };
        let d = GraphLandmarkConfig::default;
        assert_eq!(
            bad(GraphLandmarkConfig {
                optimize_every: 0,
                ..d()
            }),
            "optimize_every"
        );
        assert_eq!(
            bad(GraphLandmarkConfig {
                association: AssociationOptions {
                    gate_probability: 1.0,
                    ..AssociationOptions::default()
                },
                ..d()
            }),
            "association.gate_probability"
        );
        assert_eq!(
            bad(GraphLandmarkConfig {
                max_landmarks: MAX_LANDMARKS + 1,
                ..d()
            }),
            "max_landmarks"
        );
        let mut c = d();
        c.sensor.sigma_bearing = f64::NAN;
        assert_eq!(bad(c), "sensor.sigma_bearing");
        let mut c = d();
        c.optimizer.lambda_factor = 0.5;
        assert_eq!(bad(c), "lambda_factor");
    }
}
