//! Marginal covariances of the estimate (the Laplace approximation at the optimum).

use super::Optimizer;
use crate::error::GraphError;
use crate::graph::{NodeValue, PoseGraph};

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
    pub(super) fn factor_undamped(&mut self, graph: &PoseGraph) -> Result<(), GraphError> {
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
    pub(super) fn joint_covariance(
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
