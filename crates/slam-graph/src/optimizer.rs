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
//! follows the edge's dimension (χ²₂ of the same probability for 2-D point edges). When
//! closures are still rejected, one innovation round (each closure judged against the
//! uncertainty of the path between its nodes, guarded by joint compatibility) and then
//! graduated non-convexity with truncated least squares on the closures (the `gnc`
//! submodule; truncation `closure_gnc_chi2`; its estimate kept only when its truncated
//! cost is lower) look for a better accepted set. A front end may classify the edges itself and mark closures that start stage 1 at full
//! weight ([`Optimizer::set_closures`]; the landmark front end does).

use crate::error::GraphError;
use crate::factor::{linearize, retract, Linearized};
use crate::graph::{Edge, NodeValue, PoseGraph};
use crate::kernel::RobustKernel;
use crate::lago;
use crate::linear::{block_amd_rank, BlockPattern, Ordering, SparseLlt};

mod closures;
mod config;
mod covariance;
mod gnc;

use closures::inlier_bounds;
pub use config::{
    Damping, InitReport, Initialisation, IterationInfo, Method, OptimizeReport, OptimizerConfig,
    Start, StopReason, Termination,
};

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
    /// The GNC stage's truncation per edge dimension ([`OptimizerConfig::closure_gnc_chi2`]).
    gnc_chi2: [f64; 4],
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
        if config.ordering == Ordering::Amd {
            // Blocks numbered in the AMD order of the block graph: H is assembled already
            // permuted, and LAGO's systems share the order (crate::linear::block_amd_rank).
            let pairs = graph.edges().iter().filter_map(|e| {
                let (i, j) = e.nodes();
                Some((block_of[i]?, block_of[j]?))
            });
            let rank = block_amd_rank(dims.len(), pairs)?;
            let mut nodes = vec![0; dims.len()];
            let mut sizes = vec![0; dims.len()];
            for (b, &r) in rank.iter().enumerate() {
                nodes[r] = node_of_block[b];
                sizes[r] = dims[b];
            }
            for (r, &i) in nodes.iter().enumerate() {
                block_of[i] = Some(r);
            }
            node_of_block = nodes;
            dims = sizes;
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
        // The blocks are in the fill-reducing order already (or natural, as asked).
        let llt = SparseLlt::analyse(&pattern, Ordering::Natural, config.factorization)?;
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
            gnc_chi2: inlier_bounds(config.closure_gnc_chi2),
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
        let order = (self.config.ordering == Ordering::Amd).then_some(self.block_of.as_slice());
        let Some(x) = lago::estimate_in_order(graph, &fixed, order)? else {
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
            if !stop.failed() && !rejected_closures.is_empty() {
                stop = self.gnc_round(graph, &mut iterations, &mut rejected_closures, stop)?;
            }
        }
        self.report(
            graph,
            &start,
            iterations,
            stop,
            stage1_iterations,
            rejected_closures,
        )
    }

    /// The report of [`Optimizer::refine`] at the graph's estimate.
    fn report(
        &self,
        graph: &PoseGraph,
        start: &[NodeValue],
        iterations: Vec<IterationInfo>,
        stop: Termination,
        stage1_iterations: usize,
        rejected_closures: Vec<usize>,
    ) -> Result<OptimizeReport, GraphError> {
        let (final_chi2, final_cost) = self.cost(graph)?;
        // The start's cost under the final kernels, so that the two costs compare.
        let (initial_chi2, initial_cost) = self.evaluate(graph.edges(), start)?;
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

/// ρ of an edge in stage 1.
fn stage1_kernel(c: &OptimizerConfig, closure: bool) -> RobustKernel {
    if closure && c.closure_kernel != RobustKernel::None {
        c.closure_kernel
    } else {
        c.kernel
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
