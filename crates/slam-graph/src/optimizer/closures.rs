//! Stages 2 and the innovation round of the loop-closure treatment (the module documentation
//! of [`super`]): closures re-tested at each new estimate against their χ² bound, then the
//! rejected ones judged against the uncertainty of the path between their nodes, guarded by
//! joint compatibility.

use super::{degenerate, IterationInfo, Optimizer, Termination};
use crate::error::GraphError;
use crate::factor::{linearize, Linearized};
use crate::graph::{NodeValue, PoseGraph};
use crate::kernel::RobustKernel;

impl Optimizer {
    /// Stage-2 rounds with the plain test until no closure changes (at most
    /// [`MAX_STAGE2_ROUNDS`]); returns the last stop.
    pub(super) fn stage2_rounds(
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
    pub(super) fn innovation_round(
        &mut self,
        graph: &mut PoseGraph,
        iterations: &mut Vec<IterationInfo>,
        rejected: &mut Vec<usize>,
        stop: Termination,
    ) -> Result<Termination, GraphError> {
        let saved = Snapshot::take(self, graph, rejected, iterations);
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
            let now = std::mem::replace(&mut self.edge_kernel, saved.kernel.clone());
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
            saved.restore(self, graph, rejected, iterations);
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
pub(super) fn inlier_bounds(chi2: f64) -> [f64; 4] {
    let p = slam_models::chi2::regularized_gamma_p(1.5, 0.5 * chi2);
    let two = if p < 1.0 {
        slam_models::chi2::chi2_quantile(2, p)
    } else {
        chi2
    };
    [chi2, chi2, two, chi2]
}

/// What a tentative stage (the innovation round, GNC) changes and must put back when its
/// result is not kept: the estimate, the edges' kernels, the rejected closures and the
/// iteration record's length.
pub(super) struct Snapshot {
    x: Vec<NodeValue>,
    kernel: Vec<RobustKernel>,
    rejected: Vec<usize>,
    iterations: usize,
}

impl Snapshot {
    /// The state now.
    pub(super) fn take(
        o: &Optimizer,
        graph: &PoseGraph,
        rejected: &[usize],
        iterations: &[IterationInfo],
    ) -> Self {
        Self {
            x: graph.nodes().iter().map(|n| n.value).collect(),
            kernel: o.edge_kernel.clone(),
            rejected: rejected.to_vec(),
            iterations: iterations.len(),
        }
    }

    /// Puts the state back (the stage-2 kernels too, which follow the edges' kernels).
    pub(super) fn restore(
        self,
        o: &mut Optimizer,
        graph: &mut PoseGraph,
        rejected: &mut Vec<usize>,
        iterations: &mut Vec<IterationInfo>,
    ) {
        for (i, v) in self.x.into_iter().enumerate() {
            graph.set_value(i, v);
        }
        o.edge_kernel = self.kernel;
        o.last_kernel.clone_from(&o.edge_kernel);
        *rejected = self.rejected;
        iterations.truncate(self.iterations);
    }
}
