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
//! # Stopping rule
//! After an iteration that took F_before to F_after, optimisation stops when
//! F_after ≤ `absolute_tolerance`, or F_before − F_after ≤ `absolute_tolerance`, or
//! (F_before − F_after) / F_before ≤ `relative_tolerance`, or `max_iterations` iterations have
//! run, or (LM) λ exceeded `lambda_max` without finding a step that lowers F. This is GTSAM's
//! `checkConvergence` on F (GTSAM's own error is F/2, so its absolute tolerance is ours / 2).

use crate::error::GraphError;
use crate::factor::{linearize, retract, Linearized};
use crate::graph::{Edge, NodeValue, PoseGraph};
use crate::kernel::RobustKernel;
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

/// Optimiser settings; the defaults are GTSAM's `LevenbergMarquardtParams` defaults.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", default, deny_unknown_fields)]
pub struct OptimizerConfig {
    /// Gauss-Newton or Levenberg-Marquardt (default).
    pub method: Method,
    /// Robust kernel applied to every edge (default none).
    pub kernel: RobustKernel,
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
    pub fn converged(&self, before: f64, after: f64) -> Option<StopReason> {
        let decrease = before - after;
        if after <= self.absolute_tolerance {
            Some(StopReason::CostBelowTolerance)
        } else if decrease <= self.absolute_tolerance {
            Some(StopReason::AbsoluteDecrease)
        } else if decrease / before <= self.relative_tolerance {
            Some(StopReason::RelativeDecrease)
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
        if let Some(p) = self.kernel.parameter() {
            if !(p > 0.0 && p.is_finite()) {
                return bad("kernel parameter", p, "finite and > 0");
            }
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

/// Why optimisation stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum StopReason {
    /// The cost fell to at most `absolute_tolerance`.
    CostBelowTolerance,
    /// The cost's absolute decrease was at most `absolute_tolerance` (or it increased).
    AbsoluteDecrease,
    /// The cost's relative decrease was at most `relative_tolerance`.
    RelativeDecrease,
    /// `max_iterations` iterations ran.
    MaxIterations,
    /// LM: λ exceeded `lambda_max` with no step lowering the cost.
    LambdaLimit,
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
    /// One entry per iteration.
    pub iterations: Vec<IterationInfo>,
    /// Why it stopped.
    pub stop: StopReason,
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
        })
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
        for (k, e) in edges.iter().enumerate() {
            let s = linearize(e, x).ok_or_else(|| degenerate(k))?.chi2();
            chi2 += s;
            cost += self.config.kernel.robustify(s).0;
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
        for (k, (edge, slot)) in edges.iter().zip(&self.slots).enumerate() {
            let lin = linearize(edge, x).ok_or_else(|| degenerate(k))?;
            let s = lin.chi2();
            let (rho, w) = self.config.kernel.robustify(s);
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
            for &d in &self.diag {
                self.damped[d] += lambda;
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
    /// a step is accepted. Errors when the graph's structure differs from the one this
    /// optimiser was built for, on a degenerate edge, or (Gauss-Newton) when H is singular.
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
                info.chi2_after = chi2;
                info.cost_after = cost;
                info.accepted = true;
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

    /// Iterates until the stopping rule of the module documentation holds.
    pub fn optimize(&mut self, graph: &mut PoseGraph) -> Result<OptimizeReport, GraphError> {
        let (initial_chi2, initial_cost) = self.cost(graph)?;
        let mut iterations = Vec::new();
        let c = self.config;
        let stop = loop {
            if iterations.len() >= c.max_iterations {
                break StopReason::MaxIterations;
            }
            let info = self.iterate(graph)?;
            iterations.push(info);
            if !info.accepted {
                break StopReason::LambdaLimit;
            }
            if let Some(reason) = c.converged(info.cost_before, info.cost_after) {
                break reason;
            }
        };
        let (final_chi2, final_cost) = self.cost(graph)?;
        Ok(OptimizeReport {
            initial_chi2,
            final_chi2,
            initial_cost,
            final_cost,
            iterations,
            stop,
        })
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
        let x: Vec<NodeValue> = graph.nodes().iter().map(|n| n.value).collect();
        self.assemble(graph.edges(), &x)?;
        if !self.llt.factorize(&self.pattern, &self.h) {
            return Err(GraphError::NotPositiveDefinite {
                iteration: self.iteration,
            });
        }
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
