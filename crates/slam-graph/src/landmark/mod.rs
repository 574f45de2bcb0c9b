//! The landmark front end: full SLAM of a path and a point map from controls and
//! range-bearing observations, as a pose graph (Grisetti et al. 2010, §III; Thrun and
//! Montemerlo, "The GraphSLAM algorithm", IJRR 2006), behind `slam_models::LandmarkSlam`.
//!
//! # The graph
//! * **Pose nodes**: the initial pose (fixed: the gauge, as the EKF's zero initial
//!   covariance), then one node at every update that uses an observation, and at least every
//!   `max_steps_between_nodes` updates. Path entries between two nodes are the earlier node's
//!   estimate ⊕ the controls composed since it.
//! * **Odometry edges** between consecutive pose nodes: the controls composed from the
//!   identity with the motion model, Z = g(…g(I, u₁)…, u_k), and the motion noise propagated
//!   over them in the earlier node's frame, Σ ← G Σ Gᵀ + R (+ the extra noise, + a floor of
//!   1e-9 on the diagonal so a robot standing still still gives a positive-definite
//!   information); Ω = (A Σ Aᵀ)⁻¹ with A = diag(R(θ_Z)ᵀ, 1), because the edge's error is
//!   expressed in Z's frame.
//! * **Landmark nodes**, initialised by the inverse observation model from the current pose,
//!   with one range-bearing edge per associated observation, Ω = Q⁻¹.
//!
//! # Data association
//! The EKF's own code and options (`slam_models::association`): known ids (with the χ²₂
//! outlier gate), or for id-less observations individual compatibility gates and nearest
//! neighbour or JCBB, ambiguity rejection and provisional landmarks. It runs against the
//! **association belief**, a dense joint Gaussian of the current pose and every landmark:
//! the graph's Laplace marginal (blocks of H⁻¹ at the optimum, by sparse Cholesky solves)
//! after each optimisation, moved by the EKF's prediction and landmark augmentation until
//! the next one. Observations between two optimisations do not shrink it, so between them
//! the gates are conservative (wider than an EKF's).
//!
//! # Optimisation rule
//! Levenberg-Marquardt on the whole graph, warm-started from the current estimates (new
//! poses from odometry, new landmarks from the inverse model), once the new pose nodes
//! since the last run reach max(`optimize_every`, ⌈`optimize_growth` × pose nodes⌉), and
//! once more in `finish`; each run is bounded by the optimiser's `max_iterations`. Each
//! costs one sparse factorisation per iteration plus one sparse solve per coordinate of the
//! belief (3 + 2n), so with a fixed interval a run is quadratic in its length; the growth
//! fraction makes it linear (optimisations get rarer as the graph grows). Between two
//! runs the current pose is the last node's estimate ⊕ the controls since (dead
//! reckoning), so the online path is coarser than the smoothed one.
//!
//! # False associations (loop-closure treatment)
//! The optimiser's two-stage treatment ([`crate::optimizer`], on by default): stage 1 puts
//! DCS (Φ = 1) on the *closures*, stage 2 returns every closure with eᵀΩe ≤ χ²₂(0.999) = 13.82
//! to full weight. Here a closure is a re-observation of a landmark first seen more than
//! `closure_window` pose nodes before (the observations of a landmark while it first stays in
//! view are not: DCS would cut their typical χ² ≈ 2 to weight 0.44); a closure kept as an
//! inlier by one optimisation starts the next one's stage 1 at full weight (stage 2 judges it
//! again), so the short incremental runs are not spent re-admitting the same edges.
//!
//! # Outputs
//! [`pose`](LandmarkSlam::pose) and [`pose_covariance`](LandmarkSlam::pose_covariance) are
//! the belief's (after an optimisation: the smoothed latest pose and its marginal);
//! [`landmarks`](LandmarkSlam::landmarks) the graph's points with the belief's marginal
//! covariances; [`full_path`](LandmarkSlam::full_path) the optimised path.

mod config;

pub use config::{GraphLandmarkConfig, MAX_LANDMARKS};

use crate::error::GraphError;
use crate::graph::PoseGraph;
use crate::optimizer::{OptimizeReport, Optimizer};
use slam_models::association::{
    projected_cov, Association, AssociationMode, Associator, DenseGaussian, JointGaussian,
    AUTO_ID_BASE,
};
use slam_models::gaussian::mahalanobis_squared;
use slam_models::{
    Control, FilterError, LandmarkEstimate, LandmarkId, LandmarkSlam, Matrix2, Matrix3, Pose2,
    RangeBearing, UpdateInfo, Vector3,
};
use std::collections::HashMap;

/// Added to the diagonal of every odometry edge's covariance (m², m², rad²), so that a
/// stationary robot, whose motion model noise is zero, still gives an invertible Ω.
const MOTION_VARIANCE_FLOOR: f64 = 1e-9;

/// Graph node ids of landmarks start here (pose nodes count from 0).
const LANDMARK_NODE_BASE: u64 = 1 << 40;

/// Diagnostics of the optimisations so far (faer-style info struct).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GraphLandmarkStats {
    /// Pose nodes in the graph (the fixed initial one included).
    pub pose_nodes: usize,
    /// Edges in the graph.
    pub edges: usize,
    /// Optimisations run.
    pub optimizations: usize,
    /// LM iterations over all of them.
    pub iterations: usize,
    /// χ² = Σ eᵀΩe after the last optimisation.
    pub last_chi2: f64,
}

/// Graph-based full SLAM with point landmarks (see the module documentation).
///
/// ```
/// use slam_graph::landmark::{GraphLandmarkConfig, GraphLandmarkSlam};
/// use slam_models::{Control, LandmarkId, LandmarkSlam, OdometryControl, Pose2, RangeBearing};
/// let mut g = GraphLandmarkSlam::new(GraphLandmarkConfig::default(), Pose2::IDENTITY, 0).unwrap();
/// g.predict(&Control::Odometry(OdometryControl { rot1: 0.0, trans: 1.0, rot2: 0.0 })).unwrap();
/// let z = RangeBearing::new(2.0, 0.5, Some(LandmarkId(7))).unwrap();
/// assert_eq!(g.update(&[z]).unwrap().new_landmarks, 1);
/// g.finish().unwrap();
/// assert_eq!(g.landmarks()[0].id, LandmarkId(7));
/// assert_eq!(g.full_path().unwrap().len(), 2);
/// ```
#[derive(Debug, Clone)]
pub struct GraphLandmarkSlam {
    config: GraphLandmarkConfig,
    graph: PoseGraph,
    /// The association belief: pose = the current estimate, landmark j = graph point j.
    belief: DenseGaussian,
    ids: Vec<LandmarkId>,
    index: HashMap<LandmarkId, usize>,
    next_id: u32,
    assoc: Associator,
    step: u64,
    /// Per path entry: the graph index of its pose node and the composed motion since it.
    path: Vec<(usize, Pose2)>,
    /// Id of the latest pose node, and the controls composed since it with their covariance
    /// (in its frame).
    last_node: u64,
    rel: Pose2,
    rel_cov: Matrix3,
    updates_since_node: usize,
    nodes_since_optimization: usize,
    associations: Vec<Association>,
    stats: GraphLandmarkStats,
    /// Per landmark: the id of the pose node that first saw it.
    first_seen: Vec<u64>,
    /// Per edge: whether the last optimisation kept it as a closure inlier.
    inlier: Vec<bool>,
}

impl GraphLandmarkSlam {
    /// A graph with the fixed pose node `initial_pose` and no landmarks. `seed` is accepted
    /// for the common constructor shape (config, initial pose, seed); the algorithm draws no
    /// random numbers. Rejects invalid configurations and non-finite poses.
    pub fn new(
        config: GraphLandmarkConfig,
        initial_pose: Pose2,
        seed: u64,
    ) -> Result<Self, GraphError> {
        let _ = seed;
        config.validate()?;
        if !initial_pose.is_finite() {
            return Err(GraphError::InvalidInput(format!(
                "initial pose {initial_pose:?} is not finite"
            )));
        }
        let start = Pose2::new(initial_pose.x, initial_pose.y, initial_pose.theta);
        let mut graph = PoseGraph::new();
        graph.add_pose(0, start)?;
        graph.fix(0)?;
        Ok(Self {
            // Observations closer than the sensor's `min_range` are rejected: their edge
            // would be degenerate.
            assoc: Associator::new(config.association, config.sensor.min_range),
            next_id: if config.association.mode == AssociationMode::Auto {
                AUTO_ID_BASE
            } else {
                0
            },
            belief: DenseGaussian::new(start, Matrix3::zeros()),
            graph,
            config,
            ids: Vec::new(),
            index: HashMap::new(),
            step: 0,
            path: vec![(0, Pose2::IDENTITY)],
            last_node: 0,
            rel: Pose2::IDENTITY,
            rel_cov: Matrix3::zeros(),
            updates_since_node: 0,
            nodes_since_optimization: 0,
            associations: Vec::new(),
            stats: GraphLandmarkStats {
                pose_nodes: 1,
                ..GraphLandmarkStats::default()
            },
            first_seen: Vec::new(),
            inlier: Vec::new(),
        })
    }

    /// The configuration in use.
    pub fn config(&self) -> &GraphLandmarkConfig {
        &self.config
    }

    /// The pose graph as built and optimised so far (pose node ids count from 0 in path
    /// order; landmark node ids are 2⁴⁰ + the landmark's number in [`Self::landmarks`]).
    pub fn graph(&self) -> &PoseGraph {
        &self.graph
    }

    /// What became of each observation of the last update, in input order.
    pub fn last_associations(&self) -> &[Association] {
        &self.associations
    }

    /// Diagnostics of the graph and its optimisations.
    pub fn stats(&self) -> GraphLandmarkStats {
        GraphLandmarkStats {
            edges: self.graph.edges().len(),
            ..self.stats
        }
    }

    /// Number of provisional landmarks waiting for more sightings.
    pub fn provisional_count(&self) -> usize {
        self.assoc.provisional_count()
    }

    fn fresh_id(&mut self) -> LandmarkId {
        while self.index.contains_key(&LandmarkId(self.next_id)) {
            self.next_id = self.next_id.wrapping_add(1);
        }
        let id = LandmarkId(self.next_id);
        self.next_id = self.next_id.wrapping_add(1);
        id
    }

    fn information(cov: &Matrix3) -> Option<Matrix3> {
        let inv = cov.try_inverse()?;
        let inv = (inv + inv.transpose()) * 0.5;
        inv.iter().all(|v| v.is_finite()).then_some(inv)
    }

    /// Moves the belief and the composed odometry by one control.
    pub fn predict_control(&mut self, control: &Control) -> Result<(), GraphError> {
        control
            .validate()
            .map_err(|e| GraphError::InvalidInput(e.to_string()))?;
        let m = &self.config.motion;
        let e = self.config.extra_motion_noise;
        let extra = Matrix3::from_diagonal(&Vector3::new(e[0], e[1], e[2]));
        let pose = self.belief.pose();
        let new_pose = m.predict(&pose, control);
        let g = m.jacobian_state(&pose, control);
        let r = m.noise_covariance(&pose, control) + extra;
        let g_rel = m.jacobian_state(&self.rel, control);
        let r_rel = m.noise_covariance(&self.rel, control) + extra;
        let rel = m.predict(&self.rel, control);
        let rel_cov = g_rel * self.rel_cov * g_rel.transpose() + r_rel;
        let finite = new_pose.is_finite()
            && rel.is_finite()
            && g.iter()
                .chain(r.iter())
                .chain(rel_cov.iter())
                .all(|v| v.is_finite());
        if !finite {
            return Err(GraphError::InvalidInput(format!(
                "control {control:?} gives a non-finite prediction"
            )));
        }
        self.belief.predict(&new_pose, &g, &r);
        self.rel = rel;
        self.rel_cov = (rel_cov + rel_cov.transpose()) * 0.5;
        Ok(())
    }

    /// Adds a pose node at the current estimate, joined to the previous one by the composed
    /// odometry; returns its graph index.
    fn add_pose_node(&mut self) -> Result<usize, GraphError> {
        let id = self.last_node + 1;
        let index = self.graph.add_pose(id, self.belief.pose())?;
        let z = self.rel;
        let (s, c) = slam_models::detmath::sin_cos(z.theta);
        let a = Matrix3::new(c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0);
        let cov = a * (self.rel_cov + Matrix3::identity() * MOTION_VARIANCE_FLOOR) * a.transpose();
        let info = Self::information(&cov).ok_or_else(|| {
            GraphError::InvalidInput(format!("odometry covariance {cov:?} is not invertible"))
        })?;
        self.graph.add_between(self.last_node, id, z, info)?;
        self.last_node = id;
        self.rel = Pose2::IDENTITY;
        self.rel_cov = Matrix3::zeros();
        self.updates_since_node = 0;
        self.nodes_since_optimization += 1;
        self.stats.pose_nodes += 1;
        Ok(index)
    }

    fn q_information(&self) -> Matrix2 {
        // Q = diag(σr², σφ²) with both σ > 0 (validated).
        let q = self.config.sensor.noise_covariance();
        Matrix2::from_diagonal(&slam_models::Vector2::new(1.0 / q[(0, 0)], 1.0 / q[(1, 1)]))
    }

    /// A landmark edge from the latest pose node to landmark `j`.
    fn add_observation_edge(&mut self, j: usize, z: &RangeBearing) -> Result<(), GraphError> {
        let info = self.q_information();
        self.graph.add_range_bearing(
            self.last_node,
            LANDMARK_NODE_BASE + j as u64,
            z.range,
            z.bearing,
            info,
        )?;
        Ok(())
    }

    /// A new landmark node from the inverse observation model at the current pose, its edge,
    /// and its rows in the belief.
    fn insert_landmark(&mut self, z: &RangeBearing, id: LandmarkId) -> Result<(), GraphError> {
        let inv = self.config.sensor.inverse(&self.belief.pose(), z);
        if !(inv.landmark.x.is_finite() && inv.landmark.y.is_finite()) {
            return Err(GraphError::InvalidInput(format!(
                "observation {z:?} places a landmark at a non-finite position"
            )));
        }
        let max = self.config.max_landmarks;
        if self.ids.len() >= max {
            return Err(GraphError::TooManyLandmarks { max });
        }
        let j = self.ids.len();
        self.graph
            .add_point(LANDMARK_NODE_BASE + j as u64, inv.landmark)?;
        let slot = self
            .belief
            .add_landmark(&inv, &self.config.sensor.noise_covariance());
        debug_assert_eq!(slot, j);
        self.ids.push(id);
        self.index.insert(id, j);
        self.first_seen.push(self.last_node);
        self.add_observation_edge(j, z)
    }

    /// Optimises the graph now (adding a pose node first if controls were composed since the
    /// last one) and recomputes the association belief from its marginals. Returns the
    /// optimiser's report.
    pub fn optimize_now(&mut self) -> Result<OptimizeReport, GraphError> {
        if self.updates_since_node > 0 || self.rel != Pose2::IDENTITY {
            // A leaf node for the current pose (the path entries since the previous node
            // keep referring to that node: this one's only edge makes it their composition).
            self.add_pose_node()?;
        }
        self.nodes_since_optimization = 0;
        if self.graph.nodes().len() < 2 {
            return Err(GraphError::Empty("only the fixed initial pose"));
        }
        let mut opt = Optimizer::new(&self.graph, self.config.optimizer)?;
        let closure = self.closures();
        self.inlier.resize(closure.len(), false);
        opt.set_closures(&closure, &self.inlier)?;
        let report = opt.optimize(&mut self.graph)?;
        self.inlier.clone_from(&closure);
        for &k in &report.rejected_closures {
            self.inlier[k] = false;
        }
        if self.config.optimizer.closure_kernel == crate::RobustKernel::None {
            self.inlier.fill(false);
        }
        self.stats.optimizations += 1;
        self.stats.iterations += report.iterations.len();
        self.stats.last_chi2 = report.final_chi2;
        let last = self
            .graph
            .node_index(self.last_node)
            .ok_or(GraphError::UnknownNode { id: self.last_node })?;
        let mut nodes = Vec::with_capacity(1 + self.ids.len());
        nodes.push(last);
        for j in 0..self.ids.len() {
            let id = LANDMARK_NODE_BASE + j as u64;
            nodes.push(
                self.graph
                    .node_index(id)
                    .ok_or(GraphError::UnknownNode { id })?,
            );
        }
        let cov = opt.marginal_covariance(&self.graph, &nodes)?;
        let pose = self.graph.pose(self.last_node).unwrap_or(Pose2::IDENTITY);
        let mut mean = Vec::with_capacity(3 + 2 * self.ids.len());
        mean.extend([pose.x, pose.y, pose.theta]);
        for j in 0..self.ids.len() {
            let p = self
                .graph
                .point(LANDMARK_NODE_BASE + j as u64)
                .unwrap_or(slam_models::Point2::origin());
            mean.extend([p.x, p.y]);
        }
        self.belief = DenseGaussian {
            mean: nalgebra::DVector::from_vec(mean),
            cov,
        };
        Ok(report)
    }

    /// Per edge of the graph: whether it is a closure, i.e. a re-observation of a landmark
    /// first seen more than `closure_window` pose nodes before the observing one.
    fn closures(&self) -> Vec<bool> {
        let nodes = self.graph.nodes();
        self.graph
            .edges()
            .iter()
            .map(|e| match e {
                crate::graph::Edge::RangeBearing(rb) => {
                    let pose = nodes[rb.pose].id;
                    let j = nodes[rb.point].id.saturating_sub(LANDMARK_NODE_BASE) as usize;
                    self.first_seen
                        .get(j)
                        .is_some_and(|&f| pose.saturating_sub(f) > self.config.closure_window)
                }
                _ => false,
            })
            .collect()
    }

    /// Associates a batch of observations, adds the pose node, edges and landmarks they
    /// call for and optimises when the rule of the module documentation says so.
    pub fn update_observations(
        &mut self,
        observations: &[RangeBearing],
    ) -> Result<UpdateInfo, GraphError> {
        for z in observations {
            if !(z.range.is_finite() && z.bearing.is_finite()) {
                return Err(GraphError::InvalidInput(format!(
                    "observation {z:?} is not finite"
                )));
            }
        }
        self.step += 1;
        self.updates_since_node += 1;
        let sensor = self.config.sensor;
        let mut info = UpdateInfo {
            observations: observations.len(),
            ..UpdateInfo::default()
        };
        // The EKF's association (slam_models::association::batch) against the belief.
        let mut pairing = self
            .assoc
            .pair(&self.belief, &sensor, &self.ids, &self.index, observations)
            .map_err(|index| GraphError::MissingId { index })?;
        for (_, lin) in &pairing.paired {
            let s = projected_cov(&self.belief, lin) + lin.q;
            info.nis += mahalanobis_squared(&lin.nu, &s).unwrap_or(0.0);
        }
        // Nothing updates the belief before the unpaired observations are judged (the
        // graph is optimised after them), so they see the predicted pose.
        let (pose, pxx) = (self.belief.pose(), self.belief.pose_cov());
        let ready =
            self.assoc
                .unpaired(&mut pairing, &pose, &pxx, &sensor, observations, self.step);
        // A pose node when the graph gains an edge at this pose, or the gap is too long.
        let observed =
            !pairing.paired.is_empty() || !pairing.new_known.is_empty() || !ready.is_empty();
        let node = if observed || self.updates_since_node >= self.config.max_steps_between_nodes {
            Some(self.add_pose_node()?)
        } else {
            None
        };
        for &(i, lin) in &pairing.paired {
            self.add_observation_edge(lin.landmark, &observations[i])?;
        }
        info.associated = pairing.paired.len();
        for &i in &pairing.new_known {
            let z = &observations[i];
            let Some(id) = z.id else { continue };
            if self.index.contains_key(&id) {
                // A second sighting of an id first seen in this batch: left out rather than
                // double counted, as the EKF does.
                continue;
            }
            self.insert_landmark(z, id)?;
            pairing.associations[i] = Association::New(id);
            info.new_landmarks += 1;
        }
        for i in ready {
            let id = self.fresh_id();
            self.insert_landmark(&observations[i], id)?;
            pairing.associations[i] = Association::New(id);
            info.new_landmarks += 1;
        }
        info.removed = self.assoc.expire(self.step);
        info.rejected = observations.len() - info.associated - info.new_landmarks;
        self.associations = pairing.associations;
        match node {
            Some(index) => self.path.push((index, Pose2::IDENTITY)),
            None => {
                let at = self
                    .graph
                    .node_index(self.last_node)
                    .ok_or(GraphError::UnknownNode { id: self.last_node })?;
                self.path.push((at, self.rel));
            }
        }
        let growth = (self.config.optimize_growth * self.stats.pose_nodes as f64).ceil() as usize;
        if self.nodes_since_optimization >= self.config.optimize_every.max(growth) {
            self.optimize_now()?;
        }
        Ok(info)
    }
}

slam_models::from_config_by_new!(GraphLandmarkSlam, GraphLandmarkConfig, GraphError);

impl LandmarkSlam for GraphLandmarkSlam {
    fn name(&self) -> &str {
        "graph"
    }

    fn predict(&mut self, control: &Control) -> Result<(), FilterError> {
        self.predict_control(control).map_err(FilterError::from)
    }

    fn update(&mut self, observations: &[RangeBearing]) -> Result<UpdateInfo, FilterError> {
        self.update_observations(observations)
            .map_err(FilterError::from)
    }

    fn finish(&mut self) -> Result<(), FilterError> {
        if self.graph.nodes().len() < 2 && self.rel == Pose2::IDENTITY {
            return Ok(()); // Nothing was observed or moved: nothing to optimise.
        }
        self.optimize_now().map(|_| ()).map_err(FilterError::from)
    }

    fn pose(&self) -> Pose2 {
        self.belief.pose()
    }

    fn pose_covariance(&self) -> Matrix3 {
        self.belief.pose_cov()
    }

    fn landmarks(&self) -> Vec<LandmarkEstimate> {
        self.ids
            .iter()
            .enumerate()
            .map(|(j, &id)| LandmarkEstimate {
                id,
                mean: self.belief.landmark(j),
                covariance: self.belief.landmark_cov(j),
            })
            .collect()
    }

    fn full_path(&self) -> Option<Vec<Pose2>> {
        let nodes = self.graph.nodes();
        Some(
            self.path
                .iter()
                .map(|&(i, rel)| match nodes[i].value {
                    crate::graph::NodeValue::Pose(p) => p.compose(&rel),
                    crate::graph::NodeValue::Point(_) => rel,
                })
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests;
