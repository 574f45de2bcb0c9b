//! The one error type of slam-graph.

use thiserror::Error;

/// What went wrong while building or optimising a pose graph. Each variant names the node or
/// edge and the bound it broke.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GraphError {
    /// A node id was added twice.
    #[error("node {id} already exists")]
    DuplicateNode {
        /// The node's id.
        id: u64,
    },
    /// An edge or a fix referred to a node id that was never added.
    #[error("unknown node {id}")]
    UnknownNode {
        /// The id asked for.
        id: u64,
    },
    /// An edge joined nodes of the wrong kinds (e.g. a pose-pose edge ending at a point), or a
    /// node to itself.
    #[error("edge {from} → {to}: {reason}")]
    WrongNodeKind {
        /// Id of the first node.
        from: u64,
        /// Id of the second node.
        to: u64,
        /// What was expected, in words.
        reason: &'static str,
    },
    /// A value was NaN or infinite.
    #[error("{what} is not finite ({value})")]
    NonFinite {
        /// Which quantity.
        what: &'static str,
        /// The value given.
        value: f64,
    },
    /// An information matrix was not symmetric positive definite.
    #[error("edge {from} → {to}: information matrix is not symmetric positive definite")]
    InformationNotPositiveDefinite {
        /// Id of the first node.
        from: u64,
        /// Id of the second node.
        to: u64,
    },
    /// A field of [`crate::OptimizerConfig`] was outside its documented range.
    #[error(transparent)]
    InvalidConfig(#[from] slam_models::ConfigError),
    /// The graph has no free variable to optimise (no nodes, or all fixed).
    #[error("nothing to optimise: {0}")]
    Empty(&'static str),
    /// The normal equations were singular: some variable is not constrained by any edge (a
    /// node without edges, a landmark seen once by a bearing-only edge, ...) or the damping
    /// could not make them positive definite.
    #[error("normal equations are not positive definite at iteration {iteration} (an unconstrained node?)")]
    NotPositiveDefinite {
        /// 0-based iteration.
        iteration: usize,
    },
    /// A residual could not be evaluated (a range-bearing edge whose landmark sits on the
    /// pose, where the bearing is undefined).
    #[error("edge {edge}: {reason}")]
    Degenerate {
        /// 0-based index of the edge in [`crate::PoseGraph::edges`].
        edge: usize,
        /// What failed.
        reason: String,
    },
    /// Landmark front end: an observation had no id but the association mode is `KnownIds`.
    #[error("observation {index} has no landmark id, but association mode is known-ids")]
    MissingId {
        /// 0-based index in the update's batch.
        index: usize,
    },
    /// Landmark front end: one more landmark would exceed `max_landmarks`.
    #[error("the map would exceed max_landmarks = {max}")]
    TooManyLandmarks {
        /// The configured bound.
        max: usize,
    },
    /// Landmark front end: a control or observation that is not finite, or that gives a
    /// non-finite prediction.
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// A laser front-end configuration value ([`crate::laser::LaserGraphConfig`]) was
    /// outside its documented range.
    #[error("invalid laser front-end configuration: {field} = {value}, expected {expected}")]
    FrontEndConfig {
        /// The kebab-case key.
        field: &'static str,
        /// The value given.
        value: f64,
        /// What was expected, in words.
        expected: &'static str,
    },
    /// A grid, scan-preparation or matcher check of the laser front end failed (bad scan
    /// readings, a map beyond its maximum extent, ...).
    #[error(transparent)]
    Grid(#[from] slam_grid::GridError),
    /// A model-layer check of the laser front end failed (an odometry jump beyond its limit).
    #[error(transparent)]
    Model(#[from] slam_models::ModelError),
    /// The sparse factorisation's symbolic analysis failed (out of memory or index overflow).
    #[error("sparse Cholesky analysis failed: {0}")]
    Sparse(String),
}

impl From<GraphError> for slam_models::FilterError {
    fn from(e: GraphError) -> Self {
        use slam_models::FilterError;
        match e {
            e @ (GraphError::InvalidInput(_)
            | GraphError::MissingId { .. }
            | GraphError::NonFinite { .. }) => FilterError::invalid_input(e),
            e @ (GraphError::NotPositiveDefinite { .. } | GraphError::Degenerate { .. }) => {
                FilterError::numerical(e)
            }
            e => FilterError::other(e),
        }
    }
}
