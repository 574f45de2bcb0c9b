//! Sparse nonlinear least squares on the pose graph: Gauss-Newton and Levenberg-Marquardt
//! on the manifold (Grisetti et al. 2010, Algorithm 1 and §IV; Kümmerle et al. 2011, §III).
//!
//! Each iteration linearises every edge at the current estimate, assembles the normal
//! equations H δ = −g with H = Σ w Jᵀ Ω J and g = Σ w Jᵀ Ω e (w the robust kernel's IRLS
//! weight, 1 without a kernel), solves them with a sparse Cholesky factorisation and applies
//! x ← x ⊞ δ. Fixed nodes are not variables; when no node is fixed the first pose node is
//! (the gauge freedom of a graph of relative measurements).
//!
//! Levenberg-Marquardt solves (H + λI) δ = −g and accepts the step only when it lowers the
//! cost F = Σ ρ(eᵀΩe): then λ ← λ / f, otherwise λ ← λ·f and the step is solved again, in
//! the same iteration (Marquardt 1963; the schedule of GTSAM's `LevenbergMarquardtOptimizer`
//! with its defaults λ₀ = 1e-5, f = 10, λ_max = 1e5).
//!
//! With [`Damping::Marquardt`] the damping is λ·diag(H) instead of λI (Marquardt 1963: the
//! step is invariant to the scale of each variable).
//!
//! # Stopping rule
//! After an iteration that took F_before to F_after, optimisation stops when
//! F_after ≤ `absolute_tolerance`, or F_before − F_after ≤ `absolute_tolerance`, or
//! (F_before − F_after) / F_before ≤ `relative_tolerance` (each a [`Termination`] naming the
//! test), or `max_iterations` iterations have run, or (LM) λ exceeded `lambda_max` without
//! finding a step that lowers F. This is GTSAM's `checkConvergence` on F (GTSAM's own error is
//! F/2, so its absolute tolerance is ours / 2). Gauss-Newton never takes a step that raises
//! F: such a step ends the run as [`Termination::Diverged`], with the graph at the best
//! iterate (the one before the step); a singular H ends it as [`Termination::Singular`].
//!
//! # Initialisation and loop closures (the defaults)
//! [`Optimizer::optimize`] first initialises ([`Optimizer::initialise`]): with
//! [`Initialisation::Auto`] a planar pose graph is also given LAGO's global estimate
//! ([`crate::lago`]) and the start with the lower cost F is kept. It then refines
//! ([`Optimizer::refine`]) in up to two stages. Edges are *odometry* (a pose-pose edge between
//! node ids that differ by one) or *closures* (every other edge: loop closures, landmark
//! observations). Stage 1 puts `closure_kernel` (default DCS, Φ = 1) on the closures; stage 2
//! puts every closure whose eᵀΩe at the stage-1 result is at most `closure_inlier_chi2` back at
//! full weight (ρ = `kernel`), keeps the kernel on the others and optimises again; it repeats
//! the test at the new estimate (closures accepted stay accepted) until no closure changes, at
//! most 8 rounds, because the stage-1 estimate, with every closure down-weighted, can put a
//! correct closure outside the bound that the better estimate puts inside. So correct
//! edges end at full weight and the result is the least-squares optimum of the edges
//! accepted, while a false closure (eᵀΩe of thousands) keeps a weight below 1e-4. Odometry
//! edges are never down-weighted (they carry `kernel`, default none). The stage-2 bound
//! follows the edge's dimension (χ²₂ of the same probability for 2-D point edges), and a
//! front end may classify the edges itself and mark closures that start stage 1 at full
//! weight ([`Optimizer::set_closures`]; the landmark front end does).

use crate::error::GraphError;
use crate::factor::{linearize, retract, Linearized};
use crate::graph::{Edge, NodeValue, PoseGraph};
use crate::kernel::RobustKernel;
use crate::lago;
use crate::linear::{BlockPattern, Factorization, Ordering, SparseLlt};
use serde::{Deserialize, Serialize};

/// The nonlinear solver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Undamped Gauss-Newton: every step is taken.
    GaussNewton,
    /// Levenberg-Marquardt with λI damping and step rejection.
    #[default]
    LevenbergMarquardt,
}

/// The damping term D of Levenberg-Marquardt's (H + λD) δ = −g.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Damping {
    /// D = I (Levenberg 1944; GTSAM's default).
    #[default]
    Identity,
    /// D = diag(H), each entry at least 1e-9 (Marquardt 1963; GTSAM's `diagonalDamping`).
    Marquardt,
}

/// Where refinement starts (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Initialisation {
    /// LAGO's estimate when the graph is planar pose-only and LAGO's start has the lower cost
    /// F; the input estimates otherwise (default).
    #[default]
    Auto,
    /// The input estimates as given.
    Input,
    /// LAGO's estimate whenever the graph allows it (the input otherwise).
    Lago,
}

/// The start refinement used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Start {
    /// The input estimates.
    Input,
    /// LAGO's global estimate ([`crate::lago`]).
    Lago,
}

/// What [`Optimizer::initialise`] did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct InitReport {
    /// The start kept.
    pub start: Start,
    /// Cost F (stage-1 kernels) of the input estimates.
    pub input_cost: f64,
    /// Cost F of LAGO's estimate, when computed.
    pub lago_cost: Option<f64>,
}

/// Optimiser settings; the defaults are GTSAM's `LevenbergMarquardtParams` defaults, plus the
/// initialisation and loop-closure treatment of the module documentation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", default, deny_unknown_fields)]
pub struct OptimizerConfig {
    /// Gauss-Newton or Levenberg-Marquardt (default).
    pub method: Method,
    /// Robust kernel applied to every edge not under `closure_kernel` (default none).
    pub kernel: RobustKernel,
    /// Kernel on the closures (non-odometry edges) in stage 1, and on the closures stage 2
    /// rejects (default DCS, Φ = 1: Agarwal et al. 2013's value; a closure counts fully only
    /// while eᵀΩe ≤ 1, so a false one pulls with at most 3Φ of cost from the first iteration).
    /// `none` turns the two-stage treatment off.
    pub closure_kernel: RobustKernel,
    /// Stage 2: a closure whose eᵀΩe at the stage-1 result is at most this is an inlier and
    /// returns to full weight (default 16.27, the χ²(3) 99.9 % quantile: one correct 3-DoF
    /// edge in a thousand would exceed it). 2-D edges (points) use the χ²(2) quantile of the
    /// same probability (13.82 for the default).
    pub closure_inlier_chi2: f64,
    /// Start of the refinement (default auto: LAGO when it gives the lower cost).
    pub initialisation: Initialisation,
    /// LM damping term (default λI).
    pub damping: Damping,
    /// Iteration limit (≥ 1; default 100).
    pub max_iterations: usize,
    /// Stop when the cost's relative decrease is at most this (≥ 0; default 1e-5).
    pub relative_tolerance: f64,
    /// Stop when the cost, or its absolute decrease, is at most this (≥ 0; default 1e-5).
    pub absolute_tolerance: f64,
    /// LM: initial damping λ₀ > 0 (default 1e-5, in units of H's entries).
    pub lambda_initial: f64,
    /// LM: factor f > 1 by which λ grows after a rejected step and shrinks after an accepted
    /// one (default 10).
    pub lambda_factor: f64,
    /// LM: give up (stop) when λ exceeds this (default 1e5).
    pub lambda_max: f64,
    /// Fill-reducing ordering of the sparse Cholesky (default AMD).
    pub ordering: Ordering,
    /// Numeric Cholesky kernel (default: faer chooses).
    pub factorization: Factorization,
}

impl Default for OptimizerConfig {
    fn default() -> Self {
        Self {
            method: Method::LevenbergMarquardt,
            kernel: RobustKernel::None,
            closure_kernel: RobustKernel::Dcs { phi: 1.0 },
            closure_inlier_chi2: 16.27,
            initialisation: Initialisation::Auto,
            damping: Damping::Identity,
            max_iterations: 100,
            relative_tolerance: 1e-5,
            absolute_tolerance: 1e-5,
            lambda_initial: 1e-5,
            lambda_factor: 10.0,
            lambda_max: 1e5,
            ordering: Ordering::Amd,
            factorization: Factorization::Auto,
        }
    }
}

impl OptimizerConfig {
    /// The stopping rule of the module documentation (GTSAM's `checkConvergence` on the cost
    /// F) after an iteration took F from `before` to `after`: `Some(reason)` to stop.
    pub fn converged(&self, before: f64, after: f64) -> Option<Termination> {
        let decrease = before - after;
        if after <= self.absolute_tolerance {
            Some(Termination::CostBelowTolerance)
        } else if decrease <= self.absolute_tolerance {
            Some(Termination::AbsoluteDecrease)
        } else if decrease / before <= self.relative_tolerance {
            Some(Termination::RelativeDecrease)
        } else {
            None
        }
    }

    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<(), GraphError> {
        let bad = |field, value: f64, expected| {
            Err(GraphError::InvalidConfig(slam_models::ConfigError::new(
                "optimiser",
                field,
                value,
                expected,
            )))
        };
        if self.max_iterations == 0 {
            return bad("max_iterations", 0.0, "≥ 1");
        }
        for (f, v) in [
            ("relative_tolerance", self.relative_tolerance),
            ("absolute_tolerance", self.absolute_tolerance),
        ] {
            if !(v >= 0.0 && v.is_finite()) {
                return bad(f, v, "finite and ≥ 0");
            }
        }
        if !(self.lambda_initial > 0.0 && self.lambda_initial.is_finite()) {
            return bad("lambda_initial", self.lambda_initial, "finite and > 0");
        }
        if !(self.lambda_factor > 1.0 && self.lambda_factor.is_finite()) {
            return bad("lambda_factor", self.lambda_factor, "finite and > 1");
        }
        if !(self.lambda_max >= self.lambda_initial && self.lambda_max.is_finite()) {
            return bad("lambda_max", self.lambda_max, "finite and ≥ lambda_initial");
        }
        for (f, k) in [
            ("kernel parameter", self.kernel),
            ("closure_kernel parameter", self.closure_kernel),
        ] {
            if let Some(p) = k.parameter() {
                if !(p > 0.0 && p.is_finite()) {
                    return bad(f, p, "finite and > 0");
                }
            }
        }
        if !(self.closure_inlier_chi2 > 0.0 && self.closure_inlier_chi2.is_finite()) {
            return bad(
                "closure_inlier_chi2",
                self.closure_inlier_chi2,
                "finite and > 0",
            );
        }
        Ok(())
    }
}

/// What one iteration did (faer-style diagnostics, not errors).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct IterationInfo {
    /// 0-based iteration number.
    pub iteration: usize,
    /// χ² = Σ eᵀΩe before the iteration (no kernel applied).
    pub chi2_before: f64,
    /// χ² after it (equal to `chi2_before` when no step was accepted).
    pub chi2_after: f64,
    /// The cost minimised, F = Σ ρ(eᵀΩe), before (= χ² without a kernel).
    pub cost_before: f64,
    /// F after.
    pub cost_after: f64,
    /// LM: the λ of the accepted (or last tried) step; 0 for Gauss-Newton.
    pub lambda: f64,
    /// ‖δ‖₂ of the accepted step (0 when none was).
    pub step_norm: f64,
    /// LM: steps rejected (and re-solved with a larger λ) in this iteration.
    pub rejected_steps: usize,
    /// Whether a step was applied.
    pub accepted: bool,
}

/// How optimisation ended: converged by one of three tests, or stopped for another reason.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Termination {
    /// Converged: the cost fell to at most `absolute_tolerance`.
    CostBelowTolerance,
    /// Converged: the cost's absolute decrease was at most `absolute_tolerance`.
    AbsoluteDecrease,
    /// Converged: the cost's relative decrease was at most `relative_tolerance`.
    RelativeDecrease,
    /// Not converged: `max_iterations` iterations ran.
    MaxIterations,
    /// LM: λ exceeded `lambda_max` with no step lowering the cost (at a minimum to working
    /// precision, or stuck).
    LambdaLimit,
    /// Gauss-Newton: a step raised the cost; it was not taken and the graph holds the best
    /// iterate.
    Diverged,
    /// Gauss-Newton: H was not positive definite (an unconstrained variable); the graph holds
    /// the last iterate.
    Singular,
}

/// The former name of [`Termination`].
pub type StopReason = Termination;

impl Termination {
    /// Whether one of the three convergence tests ended the run.
    pub fn converged(&self) -> bool {
        matches!(
            self,
            Termination::CostBelowTolerance
                | Termination::AbsoluteDecrease
                | Termination::RelativeDecrease
        )
    }

    /// Whether the run failed (diverged or singular): not a usable optimum.
    pub fn failed(&self) -> bool {
        matches!(self, Termination::Diverged | Termination::Singular)
    }
}

/// The result of [`Optimizer::optimize`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OptimizeReport {
    /// χ² at the initial guess.
    pub initial_chi2: f64,
    /// χ² at the result.
    pub final_chi2: f64,
    /// F at the initial guess.
    pub initial_cost: f64,
    /// F at the result.
    pub final_cost: f64,
    /// One entry per iteration (both stages).
    pub iterations: Vec<IterationInfo>,
    /// How the (last stage of the) run ended.
    pub stop: Termination,
    /// The initialisation (default when [`Optimizer::refine`] is called alone: the input).
    pub init: InitReport,
    /// Iterations of stage 1 (the rest are stage 2's).
    pub stage1_iterations: usize,
    /// Closures down-weighted at the end (indices into [`PoseGraph::edges`]).
    pub rejected_closures: Vec<usize>,
}

impl OptimizeReport {
    /// Whether the result is worse than the start (cost F under the final kernels higher
    /// than at the input) or the run failed: `slam optimize` exits non-zero then.
    pub fn worse_than_start(&self) -> bool {
        self.final_cost > self.initial_cost || self.stop.failed()
    }
}

/// A sparse least-squares optimiser bound to one graph structure (nodes, fixed flags and
/// edges): the variable layout, the pattern of H and its symbolic factorisation are built by
/// [`Optimizer::new`] and reused by every iteration.
#[derive(Debug)]
pub struct Optimizer {
    config: OptimizerConfig,
    /// Variable block of each node (None when fixed).
    block_of: Vec<Option<usize>>,
    /// Node index of each block.
    node_of_block: Vec<usize>,
    /// Per edge: block and row offset of the diagonal blocks and of the off-diagonal pair.
    slots: Vec<EdgeSlots>,
    pattern: BlockPattern,
    diag: Vec<usize>,
    llt: SparseLlt,
    h: Vec<f64>,
    damped: Vec<f64>,
    g: Vec<f64>,
    delta: Vec<f64>,
    lambda: f64,
    iteration: usize,
    n_edges: usize,
    /// ρ of each edge in the current stage.
    edge_kernel: Vec<RobustKernel>,
    /// Whether each edge is a closure (see the module documentation).
    closure: Vec<bool>,
    /// Closures that start stage 1 at full weight ([`Optimizer::set_closures`]).
    trusted: Vec<bool>,
    /// The kernels at the last stage-2 test (to see whether a round changed any).
    last_kernel: Vec<RobustKernel>,
    /// Stage 2's inlier bound on eᵀΩe per edge dimension (index 2 and 3; see
    /// [`OptimizerConfig::closure_inlier_chi2`]).
    inlier_chi2: [f64; 4],
}

#[derive(Debug, Clone, Copy)]
struct EdgeSlots {
    /// (block, r(block, block)) of each endpoint that is a variable.
    a: Option<(usize, usize)>,
    b: Option<(usize, usize)>,
    /// r(I, J) of the off-diagonal block, I < J, when both ends are variables.
    ab: usize,
}

/// The gauge: the fixed nodes, or the first pose when none is fixed.
fn fixed_nodes(graph: &PoseGraph) -> Vec<bool> {
    let mut fixed: Vec<bool> = graph.nodes().iter().map(|n| n.fixed).collect();
    if !fixed.iter().any(|&f| f) {
        if let Some(i) = graph
            .nodes()
            .iter()
            .position(|n| matches!(n.value, NodeValue::Pose(_)))
        {
            fixed[i] = true;
        }
    }
    fixed
}

impl Optimizer {
    /// Lays out the variables, builds the pattern of H and analyses it. Errors on an invalid
    /// configuration, a graph with nothing to optimise, or a failed symbolic analysis.
    pub fn new(graph: &PoseGraph, config: OptimizerConfig) -> Result<Self, GraphError> {
        config.validate()?;
        if graph.nodes().is_empty() {
            return Err(GraphError::Empty("the graph has no nodes"));
        }
        let fixed = fixed_nodes(graph);
        let mut block_of = vec![None; graph.nodes().len()];
        let mut node_of_block = Vec::new();
        let mut dims = Vec::new();
        for (i, n) in graph.nodes().iter().enumerate() {
            if !fixed[i] {
                block_of[i] = Some(dims.len());
                node_of_block.push(i);
                dims.push(n.value.dim());
            }
        }
        if dims.is_empty() {
            return Err(GraphError::Empty("every node is fixed"));
        }
        let pairs = graph.edges().iter().filter_map(|e| {
            let (i, j) = e.nodes();
            Some((block_of[i]?, block_of[j]?))
        });
        let pattern = BlockPattern::new(&dims, pairs);
        let slots = graph
            .edges()
            .iter()
            .map(|e| {
                let (i, j) = e.nodes();
                let (bi, bj) = (block_of[i], block_of[j]);
                let ab = match (bi, bj) {
                    (Some(x), Some(y)) => pattern.row_offset(x.min(y), x.max(y)),
                    _ => 0,
                };
                EdgeSlots {
                    a: bi.map(|x| (x, pattern.row_offset(x, x))),
                    b: bj.map(|y| (y, pattern.row_offset(y, y))),
                    ab,
                }
            })
            .collect();
        let llt = SparseLlt::analyse(&pattern, config.ordering, config.factorization)?;
        let closure: Vec<bool> = graph
            .edges()
            .iter()
            .map(|e| !is_odometry(graph, e))
            .collect();
        let n = pattern.n();
        let nnz = pattern.nnz();
        Ok(Self {
            config,
            block_of,
            node_of_block,
            slots,
            diag: pattern.diagonal_positions(),
            pattern,
            llt,
            h: vec![0.0; nnz],
            damped: vec![0.0; nnz],
            g: vec![0.0; n],
            delta: vec![0.0; n],
            lambda: config.lambda_initial,
            iteration: 0,
            n_edges: graph.edges().len(),
            edge_kernel: closure.iter().map(|&c| stage1_kernel(&config, c)).collect(),
            trusted: vec![false; closure.len()],
            last_kernel: Vec::new(),
            closure,
            inlier_chi2: inlier_bounds(config.closure_inlier_chi2),
        })
    }

    /// Replaces the classification of the module documentation: `closure[k]` says whether
    /// edge k is a closure (under `closure_kernel` in stage 1 and judged in stage 2), and
    /// `trusted[k]` whether that closure starts stage 1 at full weight anyway (an inlier of
    /// an earlier optimisation of the same graph; stage 2 judges it again). Errors when a
    /// slice's length is not the number of edges.
    pub fn set_closures(&mut self, closure: &[bool], trusted: &[bool]) -> Result<(), GraphError> {
        if closure.len() != self.n_edges || trusted.len() != self.n_edges {
            return Err(GraphError::InvalidInput(format!(
                "closure flags for {} and {} edges, the graph has {}",
                closure.len(),
                trusted.len(),
                self.n_edges
            )));
        }
        self.closure = closure.to_vec();
        self.trusted = trusted.to_vec();
        self.set_stage1();
        Ok(())
    }

    /// Number of scalar unknowns.
    pub fn dimension(&self) -> usize {
        self.pattern.n()
    }

    /// Stored entries of H's upper triangle and of its Cholesky factor.
    pub fn nonzeros(&self) -> (usize, usize) {
        (self.pattern.nnz(), self.llt.factor_nnz())
    }

    /// Whether node `index` is a variable (not fixed, not the gauge).
    pub fn is_variable(&self, index: usize) -> bool {
        self.block_of.get(index).is_some_and(|b| b.is_some())
    }

    /// χ² = Σ eᵀΩe and F = Σ ρ(eᵀΩe) of `graph` at its current estimates.
    pub fn cost(&self, graph: &PoseGraph) -> Result<(f64, f64), GraphError> {
        let x: Vec<NodeValue> = graph.nodes().iter().map(|n| n.value).collect();
        self.evaluate(graph.edges(), &x)
    }

    fn evaluate(&self, edges: &[Edge], x: &[NodeValue]) -> Result<(f64, f64), GraphError> {
        let (mut chi2, mut cost) = (0.0, 0.0);
        for (k, (e, kernel)) in edges.iter().zip(&self.edge_kernel).enumerate() {
            let s = linearize(e, x).ok_or_else(|| degenerate(k))?.chi2();
            chi2 += s;
            cost += kernel.robustify(s).0;
        }
        Ok((chi2, cost))
    }

    /// Assembles H (upper triangle) and g at `x`; returns (χ², F).
    fn assemble(&mut self, edges: &[Edge], x: &[NodeValue]) -> Result<(f64, f64), GraphError> {
        self.h.fill(0.0);
        self.g.fill(0.0);
        let (mut chi2, mut cost) = (0.0, 0.0);
        let mut sys = System {
            p: &self.pattern,
            h: &mut self.h,
            g: &mut self.g,
        };
        for (k, ((edge, slot), kernel)) in edges
            .iter()
            .zip(&self.slots)
            .zip(&self.edge_kernel)
            .enumerate()
        {
            let lin = linearize(edge, x).ok_or_else(|| degenerate(k))?;
            let s = lin.chi2();
            let (rho, w) = kernel.robustify(s);
            chi2 += s;
            cost += rho;
            match lin {
                Linearized::Between { e, a, b, omega } => {
                    sys.accumulate(slot, &e, &a, &b, &(omega * w))
                }
                Linearized::Point { e, a, b, omega } => {
                    sys.accumulate(slot, &e, &a, &b, &(omega * w))
                }
            }
        }
        Ok((chi2, cost))
    }

    /// Solves (H + λI) δ = −g into `self.delta`; false when not positive definite.
    fn solve(&mut self, lambda: f64) -> bool {
        self.damped.copy_from_slice(&self.h);
        if lambda > 0.0 {
            match self.config.damping {
                Damping::Identity => {
                    for &d in &self.diag {
                        self.damped[d] += lambda;
                    }
                }
                Damping::Marquardt => {
                    for &d in &self.diag {
                        self.damped[d] += lambda * self.h[d].max(1e-9);
                    }
                }
            }
        }
        if !self.llt.factorize(&self.pattern, &self.damped) {
            return false;
        }
        for (d, g) in self.delta.iter_mut().zip(&self.g) {
            *d = -g;
        }
        self.llt.solve_in_place(&mut self.delta);
        self.delta.iter().all(|v| v.is_finite())
    }

    /// x ⊞ δ for every variable node.
    fn retract_all(&self, x: &[NodeValue], out: &mut [NodeValue]) {
        out.copy_from_slice(x);
        for (b, &node) in self.node_of_block.iter().enumerate() {
            let o = self.pattern.offset[b];
            out[node] = retract(&x[node], &self.delta[o..o + self.pattern.dim[b]]);
        }
    }

    /// One iteration (see the module documentation); the graph's estimates are updated when
    /// a step is accepted (never one that raises the cost F). Errors when the graph's
    /// structure differs from the one this optimiser was built for, on a degenerate edge, or
    /// (Gauss-Newton) when H is singular.
    pub fn iterate(&mut self, graph: &mut PoseGraph) -> Result<IterationInfo, GraphError> {
        if graph.edges().len() != self.n_edges || graph.nodes().len() != self.block_of.len() {
            return Err(GraphError::Empty(
                "the graph's structure changed since the optimiser was built",
            ));
        }
        let iteration = self.iteration;
        self.iteration += 1;
        let x: Vec<NodeValue> = graph.nodes().iter().map(|n| n.value).collect();
        let (chi2_before, cost_before) = self.assemble(graph.edges(), &x)?;
        let mut trial = x.clone();
        let mut info = IterationInfo {
            iteration,
            chi2_before,
            chi2_after: chi2_before,
            cost_before,
            cost_after: cost_before,
            lambda: 0.0,
            step_norm: 0.0,
            rejected_steps: 0,
            accepted: false,
        };
        match self.config.method {
            Method::GaussNewton => {
                if !self.solve(0.0) {
                    return Err(GraphError::NotPositiveDefinite { iteration });
                }
                self.retract_all(&x, &mut trial);
                let (chi2, cost) = self.evaluate(graph.edges(), &trial)?;
                // A step that raises the cost (or makes it non-finite) is not taken.
                if cost <= cost_before {
                    info.chi2_after = chi2;
                    info.cost_after = cost;
                    info.accepted = true;
                }
            }
            Method::LevenbergMarquardt => loop {
                info.lambda = self.lambda;
                if self.solve(self.lambda) {
                    self.retract_all(&x, &mut trial);
                    let (chi2, cost) = self.evaluate(graph.edges(), &trial)?;
                    if cost < cost_before {
                        info.chi2_after = chi2;
                        info.cost_after = cost;
                        info.accepted = true;
                        self.lambda /= self.config.lambda_factor;
                        break;
                    }
                }
                info.rejected_steps += 1;
                self.lambda *= self.config.lambda_factor;
                if self.lambda > self.config.lambda_max {
                    break;
                }
            },
        }
        if info.accepted {
            info.step_norm = self.delta.iter().map(|v| v * v).sum::<f64>().sqrt();
            for (i, v) in trial.into_iter().enumerate() {
                graph.set_value(i, v);
            }
        }
        Ok(info)
    }

    /// Initialises ([`Optimizer::initialise`]) then refines ([`Optimizer::refine`]): the
    /// whole pipeline of the module documentation.
    pub fn optimize(&mut self, graph: &mut PoseGraph) -> Result<OptimizeReport, GraphError> {
        let initial: Vec<NodeValue> = graph.nodes().iter().map(|n| n.value).collect();
        let init = self.initialise(graph)?;
        let mut report = self.refine(graph)?;
        report.init = init;
        // The start of the report is the input, not the initialisation.
        let (chi2, cost) = self.evaluate(graph.edges(), &initial)?;
        report.initial_chi2 = chi2;
        report.initial_cost = cost;
        Ok(report)
    }

    /// Sets the graph's estimates to the start chosen by `initialisation`: LAGO's estimate
    /// ([`crate::lago::estimate`], planar pose graphs only) replaces the input when asked
    /// for, or (auto) when its cost F under the stage-1 kernels is lower.
    pub fn initialise(&mut self, graph: &mut PoseGraph) -> Result<InitReport, GraphError> {
        self.set_stage1();
        let (_, input_cost) = self.cost(graph)?;
        let mut report = InitReport {
            start: Start::Input,
            input_cost,
            lago_cost: None,
        };
        if self.config.initialisation == Initialisation::Input {
            return Ok(report);
        }
        let fixed = fixed_nodes(graph);
        let Some(x) = lago::estimate(graph, &fixed)? else {
            return Ok(report);
        };
        let (_, lago_cost) = self.evaluate(graph.edges(), &x)?;
        report.lago_cost = Some(lago_cost);
        if self.config.initialisation == Initialisation::Lago || lago_cost < input_cost {
            for (i, v) in x.into_iter().enumerate() {
                graph.set_value(i, v);
            }
            report.start = Start::Lago;
        }
        Ok(report)
    }

    fn set_stage1(&mut self) {
        let c = self.config;
        for ((k, &closure), &trusted) in self
            .edge_kernel
            .iter_mut()
            .zip(&self.closure)
            .zip(&self.trusted)
        {
            *k = stage1_kernel(&c, closure && !trusted);
        }
    }

    /// Iterates from the graph's current estimates until the stopping rule of the module
    /// documentation holds, in one stage (no closure kernel) or two (see the module
    /// documentation). The report's `init` says "input".
    pub fn refine(&mut self, graph: &mut PoseGraph) -> Result<OptimizeReport, GraphError> {
        self.set_stage1();
        let start: Vec<NodeValue> = graph.nodes().iter().map(|n| n.value).collect();
        let mut iterations = Vec::new();
        let mut stop = self.run(graph, &mut iterations)?;
        let stage1_iterations = iterations.len();
        let mut rejected_closures = Vec::new();
        if self.config.closure_kernel != RobustKernel::None && !stop.failed() {
            // Stage 2, repeated: a correct closure that the stage-1 estimate (distorted by
            // down-weighting every closure) put outside the bound passes at the better
            // estimate of the next round; the rounds stop when the accepted set is stable.
            self.last_kernel.clone_from(&self.edge_kernel);
            stop = self.stage2_rounds(graph, &mut iterations, &mut rejected_closures, stop)?;
            if !stop.failed() && !rejected_closures.is_empty() {
                stop =
                    self.innovation_round(graph, &mut iterations, &mut rejected_closures, stop)?;
            }
        }
        let (final_chi2, final_cost) = self.cost(graph)?;
        // The start's cost under the final kernels, so that the two costs compare.
        let (initial_chi2, initial_cost) = self.evaluate(graph.edges(), &start)?;
        Ok(OptimizeReport {
            initial_chi2,
            final_chi2,
            initial_cost,
            final_cost,
            iterations,
            stop,
            init: InitReport {
                start: Start::Input,
                input_cost: initial_cost,
                lago_cost: None,
            },
            stage1_iterations,
            rejected_closures,
        })
    }

    /// Stage-2 rounds with the plain test until no closure changes (at most
    /// [`MAX_STAGE2_ROUNDS`]); returns the last stop.
    fn stage2_rounds(
        &mut self,
        graph: &mut PoseGraph,
        iterations: &mut Vec<IterationInfo>,
        rejected: &mut Vec<usize>,
        mut stop: Termination,
    ) -> Result<Termination, GraphError> {
        for _ in 0..MAX_STAGE2_ROUNDS {
            if !self.classify_closures(graph, rejected, false)? {
                break;
            }
            self.lambda = self.config.lambda_initial;
            let budget = self.config.max_iterations.saturating_sub(iterations.len());
            if budget == 0 {
                break;
            }
            stop = self.run_limited(graph, iterations, budget)?;
            if stop.failed() {
                break;
            }
        }
        Ok(stop)
    }

    /// One guarded round of the innovation test ([`Optimizer::classify_closures`]) on the
    /// closures the plain rounds left rejected: the closures it accepts go to full weight and
    /// the plain rounds run again; the round is kept only when it passes the joint test of
    /// the closures it added (Neira and Tardós 2001's joint compatibility, in cost form): the
    /// least-squares cost of the full-weight edges grows, from the optimum without them to
    /// the optimum with them, by at most the χ²(d) quantile of `closure_inlier_chi2`'s
    /// probability, d the added closures' dimensions. Otherwise (a false closure whose claim
    /// fell inside a wide relative uncertainty, which bends the graph to fit it) the round is
    /// undone with everything it moved.
    fn innovation_round(
        &mut self,
        graph: &mut PoseGraph,
        iterations: &mut Vec<IterationInfo>,
        rejected: &mut Vec<usize>,
        stop: Termination,
    ) -> Result<Termination, GraphError> {
        let saved_x: Vec<NodeValue> = graph.nodes().iter().map(|n| n.value).collect();
        let saved_kernel = self.edge_kernel.clone();
        let saved_rejected = rejected.clone();
        let saved_iterations = iterations.len();
        let (before, _) = self.full_weight_chi2(graph)?;
        if !self.classify_closures(graph, rejected, true)? {
            return Ok(stop);
        }
        self.lambda = self.config.lambda_initial;
        let budget = self.config.max_iterations.saturating_sub(iterations.len());
        let mut after = stop;
        if budget > 0 {
            after = self.run_limited(graph, iterations, budget)?;
        }
        if !after.failed() {
            after = self.stage2_rounds(graph, iterations, rejected, after)?;
        }
        let (chi2_after, dims_after) = self.full_weight_chi2(graph)?;
        let (_, dims_before) = {
            let now = std::mem::replace(&mut self.edge_kernel, saved_kernel.clone());
            let r = self.full_weight_chi2(graph);
            self.edge_kernel = now;
            r?
        };
        let added = dims_after.saturating_sub(dims_before);
        let p = slam_models::chi2::regularized_gamma_p(1.5, 0.5 * self.config.closure_inlier_chi2);
        let bound = if added > 0 && p < 1.0 {
            slam_models::chi2::chi2_quantile(added, p)
        } else {
            f64::INFINITY
        };
        if after.failed() || chi2_after - before > bound {
            for (i, v) in saved_x.into_iter().enumerate() {
                graph.set_value(i, v);
            }
            self.edge_kernel = saved_kernel;
            self.last_kernel.clone_from(&self.edge_kernel);
            *rejected = saved_rejected;
            iterations.truncate(saved_iterations);
            return Ok(stop);
        }
        Ok(after)
    }

    /// The summed eᵀΩe of the edges at full weight (odometry and accepted closures) at the
    /// current estimate, and the sum of their dimensions.
    fn full_weight_chi2(&self, graph: &PoseGraph) -> Result<(f64, usize), GraphError> {
        let x: Vec<NodeValue> = graph.nodes().iter().map(|n| n.value).collect();
        let (mut chi2, mut dims) = (0.0, 0);
        for (k, e) in graph.edges().iter().enumerate() {
            if !self.closure[k] || self.edge_kernel[k] == self.config.kernel {
                let lin = linearize(e, &x).ok_or_else(|| degenerate(k))?;
                chi2 += lin.chi2();
                dims += match lin {
                    Linearized::Between { .. } => 3,
                    Linearized::Point { .. } => 2,
                };
            }
        }
        Ok((chi2, dims))
    }

    /// Stage 2's test at the graph's current estimate. A closure passes when its eᵀΩe is
    /// within its bound ([`inlier_bounds`]), or else when its innovation form is:
    /// eᵀS⁻¹e with S = Ω⁻¹ + J Σ Jᵀ, J = [∂e/∂xᵢ ∂e/∂xⱼ] and Σ the joint covariance of the two
    /// nodes under the current weights (the χ² test of an edge that the estimate did not
    /// absorb, as in an EKF's gate: a down-weighted correct closure is judged against the
    /// uncertainty of the path between its nodes, not as if that path were exact). A passing
    /// closure gets `kernel` (full weight) and keeps it in later rounds (the accepted set only
    /// grows, so the rounds end); every other keeps its kernel and is listed in `rejected`.
    /// Returns whether any closure's kernel changed.
    fn classify_closures(
        &mut self,
        graph: &PoseGraph,
        rejected: &mut Vec<usize>,
        innovation: bool,
    ) -> Result<bool, GraphError> {
        let x: Vec<NodeValue> = graph.nodes().iter().map(|n| n.value).collect();
        let mut failing = Vec::new();
        for (k, e) in graph.edges().iter().enumerate() {
            if !self.closure[k] {
                continue;
            }
            let lin = linearize(e, &x).ok_or_else(|| degenerate(k))?;
            if lin.chi2() <= self.bound(&lin) {
                self.edge_kernel[k] = self.config.kernel;
            } else {
                failing.push((k, lin));
            }
        }
        rejected.clear();
        let passed = if innovation {
            self.innovation_passes(graph, &failing)?
        } else {
            vec![false; failing.len()]
        };
        for ((k, _), pass) in failing.into_iter().zip(passed) {
            if pass {
                self.edge_kernel[k] = self.config.kernel;
            } else {
                rejected.push(k);
            }
        }
        let changed = self.stage2_kernel_changed();
        Ok(changed)
    }

    /// Whether stage 2 changed any kernel since the last call (and remembers the current ones).
    fn stage2_kernel_changed(&mut self) -> bool {
        let changed = self.last_kernel != self.edge_kernel;
        self.last_kernel.clone_from(&self.edge_kernel);
        changed
    }

    /// Stage 2's bound for an edge of this dimension.
    fn bound(&self, lin: &Linearized) -> f64 {
        match lin {
            Linearized::Between { .. } => self.inlier_chi2[3],
            Linearized::Point { .. } => self.inlier_chi2[2],
        }
    }

    /// The innovation test of [`Optimizer::classify_closures`] for each failing closure;
    /// all false when H at the current weights cannot be factorised.
    fn innovation_passes(
        &mut self,
        graph: &PoseGraph,
        failing: &[(usize, Linearized)],
    ) -> Result<Vec<bool>, GraphError> {
        if failing.is_empty() {
            return Ok(Vec::new());
        }
        if self.factor_undamped(graph).is_err() {
            return Ok(vec![false; failing.len()]);
        }
        let mut out = Vec::with_capacity(failing.len());
        // A few edges at a time, so the joint covariance stays small.
        for chunk in failing.chunks(32) {
            let mut nodes = Vec::with_capacity(2 * chunk.len());
            for (k, _) in chunk {
                let (i, j) = graph.edges()[*k].nodes();
                nodes.extend([i, j]);
            }
            let sigma = self.joint_covariance(graph, &nodes)?;
            let mut row = 0;
            for (c, (_, lin)) in chunk.iter().enumerate() {
                let (i, j) = (nodes[2 * c], nodes[2 * c + 1]);
                let (di, dj) = (graph.nodes()[i].value.dim(), graph.nodes()[j].value.dim());
                let s = sigma.view((row, row), (di + dj, di + dj)).into_owned();
                row += di + dj;
                out.push(innovation_chi2(lin, &s).is_some_and(|m| m <= self.bound(lin)));
            }
        }
        Ok(out)
    }

    fn run(
        &mut self,
        graph: &mut PoseGraph,
        iterations: &mut Vec<IterationInfo>,
    ) -> Result<Termination, GraphError> {
        self.run_limited(graph, iterations, self.config.max_iterations)
    }

    /// Iterations until a stopping test holds or `budget` more have run.
    fn run_limited(
        &mut self,
        graph: &mut PoseGraph,
        iterations: &mut Vec<IterationInfo>,
        budget: usize,
    ) -> Result<Termination, GraphError> {
        let c = self.config;
        for _ in 0..budget {
            let info = match self.iterate(graph) {
                Ok(info) => info,
                Err(GraphError::NotPositiveDefinite { .. }) if c.method == Method::GaussNewton => {
                    return Ok(Termination::Singular)
                }
                Err(e) => return Err(e),
            };
            iterations.push(info);
            if !info.accepted {
                return Ok(match c.method {
                    Method::GaussNewton => Termination::Diverged,
                    Method::LevenbergMarquardt => Termination::LambdaLimit,
                });
            }
            if let Some(reason) = c.converged(info.cost_before, info.cost_after) {
                return Ok(reason);
            }
        }
        Ok(Termination::MaxIterations)
    }
}

/// Whether `e` is odometry: a pose-pose edge between node ids that differ by one.
pub fn is_odometry(graph: &PoseGraph, e: &Edge) -> bool {
    match e {
        Edge::Between(b) => graph.nodes()[b.from].id.abs_diff(graph.nodes()[b.to].id) == 1,
        _ => false,
    }
}

/// eᵀS⁻¹e with S = Ω⁻¹ + J Σ Jᵀ for an edge linearised as `lin` and the joint covariance
/// `sigma` of its two nodes (first node's coordinates first); None when S is not invertible.
fn innovation_chi2(lin: &Linearized, sigma: &nalgebra::DMatrix<f64>) -> Option<f64> {
    use nalgebra::DMatrix;
    let (e, j, omega) = match lin {
        Linearized::Between { e, a, b, omega } => {
            let mut j = DMatrix::zeros(3, 6);
            j.view_mut((0, 0), (3, 3)).copy_from(a);
            j.view_mut((0, 3), (3, 3)).copy_from(b);
            (
                DMatrix::from_column_slice(3, 1, e.as_slice()),
                j,
                DMatrix::from_column_slice(3, 3, omega.as_slice()),
            )
        }
        Linearized::Point { e, a, b, omega } => {
            let mut j = DMatrix::zeros(2, 5);
            j.view_mut((0, 0), (2, 3)).copy_from(a);
            j.view_mut((0, 3), (2, 2)).copy_from(b);
            (
                DMatrix::from_column_slice(2, 1, e.as_slice()),
                j,
                DMatrix::from_column_slice(2, 2, omega.as_slice()),
            )
        }
    };
    let s = omega.try_inverse()? + &j * sigma * j.transpose();
    let m = (e.transpose() * s.cholesky()?.solve(&e))[(0, 0)];
    m.is_finite().then_some(m)
}

/// At most this many rounds of stage 2 (re-test every closure, re-optimise); the accepted
/// set is usually stable after one or two.
const MAX_STAGE2_ROUNDS: usize = 8;

/// Stage 2's inlier bounds by edge dimension: `chi2` for 3-D edges, and for 2-D edges the
/// χ²(2) quantile of the same probability p = P(χ²(3) ≤ `chi2`) (13.82 for the default 16.27,
/// p = 0.999), so a correct edge of either kind is rejected with the same probability.
fn inlier_bounds(chi2: f64) -> [f64; 4] {
    let p = slam_models::chi2::regularized_gamma_p(1.5, 0.5 * chi2);
    let two = if p < 1.0 {
        slam_models::chi2::chi2_quantile(2, p)
    } else {
        chi2
    };
    [chi2, chi2, two, chi2]
}

/// ρ of an edge in stage 1.
fn stage1_kernel(c: &OptimizerConfig, closure: bool) -> RobustKernel {
    if closure && c.closure_kernel != RobustKernel::None {
        c.closure_kernel
    } else {
        c.kernel
    }
}

impl Optimizer {
    /// The joint marginal covariance of the nodes `nodes` (indices into
    /// [`PoseGraph::nodes`]) under the Laplace approximation at the current estimate: the
    /// blocks of H⁻¹, H = Σ w JᵀΩJ assembled undamped (kernel weights included) and factorised
    /// by the sparse Cholesky, one solve per requested column (Grisetti et al. 2010, §IV-C:
    /// the covariance of the estimate is the inverse of H). Rows and columns follow `nodes`
    /// (3 per pose, 2 per point); a fixed node's (the gauge's) are zero. Cost: one sparse
    /// solve per scalar column, O(columns × nnz(L)).
    pub fn marginal_covariance(
        &mut self,
        graph: &PoseGraph,
        nodes: &[usize],
    ) -> Result<nalgebra::DMatrix<f64>, GraphError> {
        if graph.edges().len() != self.n_edges || graph.nodes().len() != self.block_of.len() {
            return Err(GraphError::Empty(
                "the graph's structure changed since the optimiser was built",
            ));
        }
        self.factor_undamped(graph)?;
        self.joint_covariance(graph, nodes)
    }

    /// Assembles H at the graph's estimate (current kernel weights) and factorises it
    /// undamped, for [`Optimizer::joint_covariance`].
    fn factor_undamped(&mut self, graph: &PoseGraph) -> Result<(), GraphError> {
        let x: Vec<NodeValue> = graph.nodes().iter().map(|n| n.value).collect();
        self.assemble(graph.edges(), &x)?;
        if !self.llt.factorize(&self.pattern, &self.h) {
            return Err(GraphError::NotPositiveDefinite {
                iteration: self.iteration,
            });
        }
        Ok(())
    }

    /// The blocks of H⁻¹ for `nodes` from the factorisation [`Optimizer::factor_undamped`]
    /// left (see [`Optimizer::marginal_covariance`]).
    fn joint_covariance(
        &self,
        graph: &PoseGraph,
        nodes: &[usize],
    ) -> Result<nalgebra::DMatrix<f64>, GraphError> {
        // (row of the output, scalar variable) for every requested coordinate that is free.
        let mut wanted = Vec::new();
        let mut total = 0;
        for &i in nodes {
            let node = graph
                .nodes()
                .get(i)
                .ok_or(GraphError::UnknownNode { id: i as u64 })?;
            let d = node.value.dim();
            if let Some(b) = self.block_of[i] {
                let o = self.pattern.offset[b];
                wanted.extend((0..d).map(|k| (total + k, o + k)));
            }
            total += d;
        }
        let n = self.pattern.n();
        let mut out = nalgebra::DMatrix::zeros(total, total);
        // Columns in batches, so the right-hand sides stay within a few MB.
        let batch = (1 << 19) / n.max(1) + 1;
        let mut rhs = Vec::new();
        for chunk in wanted.chunks(batch) {
            rhs.clear();
            rhs.resize(n * chunk.len(), 0.0);
            for (c, &(_, v)) in chunk.iter().enumerate() {
                rhs[c * n + v] = 1.0;
            }
            self.llt.solve_columns_in_place(&mut rhs, chunk.len());
            for (c, &(col, _)) in chunk.iter().enumerate() {
                for &(row, v) in &wanted {
                    out[(row, col)] = rhs[c * n + v];
                }
            }
        }
        // H⁻¹ is symmetric; average away the solve's rounding.
        let sym = (&out + out.transpose()) * 0.5;
        Ok(sym)
    }
}

/// The normal equations being assembled.
struct System<'a> {
    p: &'a BlockPattern,
    h: &'a mut [f64],
    g: &'a mut [f64],
}

impl System<'_> {
    /// Adds one edge's JᵀWΩJ blocks and JᵀWΩe (W Ω already weighted as `wo`).
    fn accumulate<const R: usize, const DA: usize, const DB: usize>(
        &mut self,
        slot: &EdgeSlots,
        e: &nalgebra::SVector<f64, R>,
        ja: &nalgebra::SMatrix<f64, R, DA>,
        jb: &nalgebra::SMatrix<f64, R, DB>,
        wo: &nalgebra::SMatrix<f64, R, R>,
    ) {
        let woe = wo * e;
        let p = self.p;
        if let Some((ba, r)) = slot.a {
            let woja = wo * ja;
            let haa = ja.transpose() * woja;
            p.add_block(self.h, ba, ba, r, haa.as_slice());
            let ga = ja.transpose() * woe;
            let o = p.offset[ba];
            for (t, v) in self.g[o..o + DA].iter_mut().zip(ga.iter()) {
                *t += v;
            }
            if let Some((bb, _)) = slot.b {
                if ba < bb {
                    let hab = woja.transpose() * jb;
                    p.add_block(self.h, ba, bb, slot.ab, hab.as_slice());
                } else {
                    let hba = jb.transpose() * woja;
                    p.add_block(self.h, bb, ba, slot.ab, hba.as_slice());
                }
            }
        }
        if let Some((bb, r)) = slot.b {
            let hbb = jb.transpose() * (wo * jb);
            p.add_block(self.h, bb, bb, r, hbb.as_slice());
            let gb = jb.transpose() * woe;
            let o = p.offset[bb];
            for (t, v) in self.g[o..o + DB].iter_mut().zip(gb.iter()) {
                *t += v;
            }
        }
    }
}

fn degenerate(edge: usize) -> GraphError {
    GraphError::Degenerate {
        edge,
        reason: "the point is within 1 mm of the observing pose (bearing undefined)".into(),
    }
}
