//! The pose graph: nodes (robot poses in SE(2), landmark points in R²) and edges (measured
//! relations between two nodes with an information matrix), in the form of Grisetti,
//! Kümmerle, Stachniss and Burgard, "A tutorial on graph-based SLAM" (IEEE ITS Magazine 2010),
//! §III, and of g2o's 2-D types (Kümmerle et al., ICRA 2011).
//!
//! Nodes carry the caller's integer ids (a g2o file's vertex ids); edges refer to nodes by
//! their position in [`PoseGraph::nodes`], resolved from ids when the edge is added.

use crate::error::GraphError;
use slam_models::{Matrix2, Matrix3, Point2, Pose2};
use std::collections::HashMap;

/// The value of a node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NodeValue {
    /// A robot pose (x, y in metres, θ in radians in (−π, π]), world frame.
    Pose(Pose2),
    /// A landmark position, world frame, metres.
    Point(Point2),
}

impl NodeValue {
    /// Degrees of freedom: 3 for a pose, 2 for a point.
    pub fn dim(&self) -> usize {
        match self {
            NodeValue::Pose(_) => 3,
            NodeValue::Point(_) => 2,
        }
    }
}

/// A node: its id, its current estimate, and whether the optimiser may move it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    /// The caller's id (unique in the graph).
    pub id: u64,
    /// The current estimate.
    pub value: NodeValue,
    /// A fixed node is held at its value (g2o's `FIX`); fixing one pose removes the gauge
    /// freedom of a graph with only relative edges.
    pub fixed: bool,
}

/// A relative-pose edge (g2o `EDGE_SE2`): pose `to` measured in the frame of pose `from`.
/// Its error is g2o's e = t2v(Z⁻¹ (Xᵢ⁻¹ Xⱼ)) (Grisetti et al. 2010, eq. 30), with t2v the
/// vector (x, y, θ) of a pose and θ normalised to (−π, π].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BetweenEdge {
    /// Index of pose i in [`PoseGraph::nodes`].
    pub from: usize,
    /// Index of pose j.
    pub to: usize,
    /// The measurement Z = Xᵢ⁻¹ Xⱼ.
    pub measurement: Pose2,
    /// Ω, the inverse covariance of the measurement in the order (x, y, θ); symmetric PD.
    pub information: Matrix3,
}

/// A point observed in a pose's frame (g2o `EDGE_SE2_XY`): e = Rᵢᵀ (l − tᵢ) − z.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointXyEdge {
    /// Index of the observing pose.
    pub pose: usize,
    /// Index of the point.
    pub point: usize,
    /// The point's coordinates in the pose's frame, metres.
    pub measurement: Point2,
    /// Ω, 2×2, symmetric PD.
    pub information: Matrix2,
}

/// A range-bearing observation of a point: e = (r̂ − r, normalise(φ̂ − φ)) with ĥ the model
/// of `slam_models::measurement::RangeBearingModel::predict` (PR eq. 6.40).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeBearingEdge {
    /// Index of the observing pose.
    pub pose: usize,
    /// Index of the point.
    pub point: usize,
    /// Range (m) and bearing (rad, CCW from the heading).
    pub range: f64,
    /// Bearing, radians.
    pub bearing: f64,
    /// Ω in the order (range, bearing), symmetric PD.
    pub information: Matrix2,
}

/// An edge of the graph.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Edge {
    /// Pose to pose.
    Between(BetweenEdge),
    /// Pose to point, Cartesian.
    PointXy(PointXyEdge),
    /// Pose to point, range and bearing.
    RangeBearing(RangeBearingEdge),
}

impl Edge {
    /// The two node indices (first the observing/earlier pose).
    pub fn nodes(&self) -> (usize, usize) {
        match self {
            Edge::Between(e) => (e.from, e.to),
            Edge::PointXy(e) => (e.pose, e.point),
            Edge::RangeBearing(e) => (e.pose, e.point),
        }
    }
}

/// A 2-D pose graph. Build it with the `add_*` methods (each validates its input), optimise
/// it with [`crate::Optimizer`], read the estimates back from [`PoseGraph::nodes`].
///
/// # Example
/// ```
/// use slam_graph::{PoseGraph, Optimizer, OptimizerConfig};
/// use slam_models::{Matrix3, Pose2};
/// let mut g = PoseGraph::new();
/// g.add_pose(0, Pose2::IDENTITY).unwrap();
/// g.add_pose(1, Pose2::new(0.9, 0.1, 0.0)).unwrap();
/// g.add_between(0, 1, Pose2::new(1.0, 0.0, 0.0), Matrix3::identity()).unwrap();
/// let report = Optimizer::new(&g, OptimizerConfig::default()).unwrap().optimize(&mut g).unwrap();
/// // The default stopping rule ends once χ² falls by at most 1e-5.
/// assert!(report.final_chi2 < 1e-5);
/// assert!(g.pose(1).unwrap().approx_eq(&Pose2::new(1.0, 0.0, 0.0), 1e-3));
/// ```
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PoseGraph {
    nodes: Vec<Node>,
    edges: Vec<Edge>,
    index: HashMap<u64, usize>,
}

fn finite(what: &'static str, v: f64) -> Result<(), GraphError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(GraphError::NonFinite { what, value: v })
    }
}

impl PoseGraph {
    /// An empty graph.
    pub fn new() -> Self {
        Self::default()
    }

    /// The nodes, in the order they were added.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// The edges, in the order they were added.
    pub fn edges(&self) -> &[Edge] {
        &self.edges
    }

    /// The index in [`PoseGraph::nodes`] of the node with this id.
    pub fn node_index(&self, id: u64) -> Option<usize> {
        self.index.get(&id).copied()
    }

    /// The pose of node `id`, if it exists and is a pose.
    pub fn pose(&self, id: u64) -> Option<Pose2> {
        match self.node_index(id).map(|i| self.nodes[i].value) {
            Some(NodeValue::Pose(p)) => Some(p),
            _ => None,
        }
    }

    /// The position of node `id`, if it exists and is a point.
    pub fn point(&self, id: u64) -> Option<Point2> {
        match self.node_index(id).map(|i| self.nodes[i].value) {
            Some(NodeValue::Point(p)) => Some(p),
            _ => None,
        }
    }

    /// Every pose node's estimate, in node order.
    pub fn poses(&self) -> Vec<Pose2> {
        self.nodes
            .iter()
            .filter_map(|n| match n.value {
                NodeValue::Pose(p) => Some(p),
                NodeValue::Point(_) => None,
            })
            .collect()
    }

    fn add_node(&mut self, id: u64, value: NodeValue) -> Result<usize, GraphError> {
        if self.index.contains_key(&id) {
            return Err(GraphError::DuplicateNode { id });
        }
        let i = self.nodes.len();
        self.nodes.push(Node {
            id,
            value,
            fixed: false,
        });
        self.index.insert(id, i);
        Ok(i)
    }

    /// Adds a pose node; returns its index. Errors on a duplicate id or a non-finite pose.
    pub fn add_pose(&mut self, id: u64, pose: Pose2) -> Result<usize, GraphError> {
        finite("pose x", pose.x)?;
        finite("pose y", pose.y)?;
        finite("pose theta", pose.theta)?;
        self.add_node(id, NodeValue::Pose(Pose2::new(pose.x, pose.y, pose.theta)))
    }

    /// Adds a point (landmark) node; returns its index.
    pub fn add_point(&mut self, id: u64, p: Point2) -> Result<usize, GraphError> {
        finite("point x", p.x)?;
        finite("point y", p.y)?;
        self.add_node(id, NodeValue::Point(p))
    }

    /// Marks node `id` as fixed (held at its value by the optimiser).
    pub fn fix(&mut self, id: u64) -> Result<(), GraphError> {
        let i = self.node_index(id).ok_or(GraphError::UnknownNode { id })?;
        self.nodes[i].fixed = true;
        Ok(())
    }

    /// Sets the estimate of node `index` (the optimiser's write-back, or a caller's reset);
    /// the kind (pose or point) must not change.
    pub fn set_value(&mut self, index: usize, value: NodeValue) {
        debug_assert_eq!(self.nodes[index].value.dim(), value.dim());
        self.nodes[index].value = value;
    }

    fn pair(&self, from: u64, to: u64, want_point: bool) -> Result<(usize, usize), GraphError> {
        let a = self
            .node_index(from)
            .ok_or(GraphError::UnknownNode { id: from })?;
        let b = self
            .node_index(to)
            .ok_or(GraphError::UnknownNode { id: to })?;
        if a == b {
            return Err(GraphError::WrongNodeKind {
                from,
                to,
                reason: "an edge joins two different nodes",
            });
        }
        let ok = matches!(self.nodes[a].value, NodeValue::Pose(_))
            && matches!(self.nodes[b].value, NodeValue::Point(_)) == want_point
            && matches!(self.nodes[b].value, NodeValue::Pose(_)) != want_point;
        if !ok {
            return Err(GraphError::WrongNodeKind {
                from,
                to,
                reason: if want_point {
                    "a pose then a point"
                } else {
                    "two poses"
                },
            });
        }
        Ok((a, b))
    }

    /// Adds a relative-pose edge: `z` is pose `to` in the frame of pose `from`, `information`
    /// its 3×3 inverse covariance (x, y, θ). Errors on unknown ids, wrong node kinds,
    /// non-finite values, or an information matrix that is not symmetric PD.
    pub fn add_between(
        &mut self,
        from: u64,
        to: u64,
        z: Pose2,
        information: Matrix3,
    ) -> Result<usize, GraphError> {
        let (a, b) = self.pair(from, to, false)?;
        finite("measurement x", z.x)?;
        finite("measurement y", z.y)?;
        finite("measurement theta", z.theta)?;
        check_information(&information, from, to)?;
        self.edges.push(Edge::Between(BetweenEdge {
            from: a,
            to: b,
            measurement: Pose2::new(z.x, z.y, z.theta),
            information,
        }));
        Ok(self.edges.len() - 1)
    }

    /// Adds a pose-to-point edge with the point measured in the pose's frame (g2o
    /// `EDGE_SE2_XY`).
    pub fn add_point_xy(
        &mut self,
        pose: u64,
        point: u64,
        z: Point2,
        information: Matrix2,
    ) -> Result<usize, GraphError> {
        let (a, b) = self.pair(pose, point, true)?;
        finite("measurement x", z.x)?;
        finite("measurement y", z.y)?;
        check_information(&information, pose, point)?;
        self.edges.push(Edge::PointXy(PointXyEdge {
            pose: a,
            point: b,
            measurement: z,
            information,
        }));
        Ok(self.edges.len() - 1)
    }

    /// Adds a range-bearing edge (range ≥ 0 in metres, bearing in radians, normalised here).
    pub fn add_range_bearing(
        &mut self,
        pose: u64,
        point: u64,
        range: f64,
        bearing: f64,
        information: Matrix2,
    ) -> Result<usize, GraphError> {
        let (a, b) = self.pair(pose, point, true)?;
        finite("range", range)?;
        finite("bearing", bearing)?;
        if range < 0.0 {
            return Err(GraphError::NonFinite {
                what: "range (must be ≥ 0)",
                value: range,
            });
        }
        check_information(&information, pose, point)?;
        self.edges.push(Edge::RangeBearing(RangeBearingEdge {
            pose: a,
            point: b,
            range,
            bearing: slam_models::normalize_angle(bearing),
            information,
        }));
        Ok(self.edges.len() - 1)
    }
}

/// Symmetric (to 1e-9 relative) and positive definite (a Cholesky factor exists).
fn check_information<const N: usize>(
    m: &nalgebra::SMatrix<f64, N, N>,
    from: u64,
    to: u64,
) -> Result<(), GraphError> {
    let bad = GraphError::InformationNotPositiveDefinite { from, to };
    if m.iter().any(|v| !v.is_finite()) {
        return Err(bad);
    }
    let scale = m.amax().max(f64::MIN_POSITIVE);
    if (m - m.transpose()).amax() > 1e-9 * scale {
        return Err(bad);
    }
    if nalgebra::Cholesky::new(*m).is_none() {
        return Err(bad);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builder_rejects_bad_input() {
        let mut g = PoseGraph::new();
        g.add_pose(0, Pose2::IDENTITY).unwrap();
        g.add_pose(1, Pose2::IDENTITY).unwrap();
        g.add_point(7, Point2::new(1.0, 2.0)).unwrap();
        let i3 = Matrix3::identity();
        let i2 = Matrix2::identity();
        assert_eq!(
            g.add_pose(1, Pose2::IDENTITY),
            Err(GraphError::DuplicateNode { id: 1 })
        );
        assert!(g.add_pose(2, Pose2::new(f64::NAN, 0.0, 0.0)).is_err());
        assert_eq!(
            g.add_between(0, 9, Pose2::IDENTITY, i3),
            Err(GraphError::UnknownNode { id: 9 })
        );
        assert!(matches!(
            g.add_between(0, 7, Pose2::IDENTITY, i3),
            Err(GraphError::WrongNodeKind { .. })
        ));
        assert!(matches!(
            g.add_between(0, 0, Pose2::IDENTITY, i3),
            Err(GraphError::WrongNodeKind { .. })
        ));
        assert!(matches!(
            g.add_point_xy(7, 0, Point2::origin(), i2),
            Err(GraphError::WrongNodeKind { .. })
        ));
        assert!(matches!(
            g.add_point_xy(0, 1, Point2::origin(), i2),
            Err(GraphError::WrongNodeKind { .. })
        ));
        let mut asym = i3;
        asym[(0, 1)] = 0.5;
        assert!(matches!(
            g.add_between(0, 1, Pose2::IDENTITY, asym),
            Err(GraphError::InformationNotPositiveDefinite { .. })
        ));
        assert!(matches!(
            g.add_between(0, 1, Pose2::IDENTITY, -i3),
            Err(GraphError::InformationNotPositiveDefinite { .. })
        ));
        assert!(g.add_range_bearing(0, 7, -1.0, 0.0, i2).is_err());
        assert_eq!(g.fix(42), Err(GraphError::UnknownNode { id: 42 }));
        assert!(g.add_between(0, 1, Pose2::IDENTITY, i3).is_ok());
        assert!(g.add_point_xy(1, 7, Point2::new(1.0, 2.0), i2).is_ok());
        assert_eq!(g.edges().len(), 2);
    }
}
