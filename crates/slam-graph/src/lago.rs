//! LAGO: a global initial estimate of a planar pose graph by two linear least-squares
//! problems (Carlone, Aragues, Castellanos and Bona, "A fast and accurate approximation for
//! planar pose graph optimization", IJRR 2014, §4–5).
//!
//! 1. **Orientations.** Along a breadth-first spanning tree rooted at the fixed nodes (the
//!    gauge) the measured relative headings are summed, giving θ̂. Each edge i → j with
//!    measured heading δ then gets the regularised measurement δ + 2πkᵢⱼ,
//!    kᵢⱼ = round((θ̂ⱼ − θ̂ᵢ − δ) / 2π) (the paper's eq. 17; tree edges have k = 0), and the
//!    headings solve min Σ wᵢⱼ (θⱼ − θᵢ − δ − 2πkᵢⱼ)², wᵢⱼ = 1/σ²_θ, σ²_θ the θθ entry of
//!    Ω⁻¹: one linear solve, no wrap-around left.
//! 2. **Positions.** With the headings fixed, the error of edge i → j in translation is
//!    linear in the positions: rᵢⱼ = tⱼ − tᵢ − Rᵢ t_z, weighted by
//!    Rᵢ R_z Λ R_zᵀ Rᵢᵀ with Λ = (Σ_tt)⁻¹ the marginal translation information of the
//!    measurement (g2o's error is R_zᵀ(Rᵢᵀ(tⱼ − tᵢ) − t_z)); a second linear solve.
//!
//! Both normal equations are solved by the same sparse Cholesky as the optimiser's
//! ([`crate::linear`]). Fixed nodes keep their values. The estimate is defined only for a
//! graph of poses and pose-pose edges in which every pose is joined to a fixed one.

use crate::error::GraphError;
use crate::graph::{Edge, NodeValue, PoseGraph};
use crate::linear::{BlockPattern, Factorization, Ordering, SparseLlt};
use slam_models::{detmath, normalize_angle, Matrix2, Pose2};
use std::collections::VecDeque;
use std::f64::consts::TAU;

/// LAGO's estimate of every node (indexed like [`PoseGraph::nodes`]), with the nodes marked
/// in `fixed` held at their values; `None` when the graph has points or pose-point edges,
/// no fixed node, or a pose not joined to a fixed one (then there is no unique estimate).
/// Errors only when a linear system is not positive definite (an information matrix whose
/// marginal variances are not finite and positive).
pub fn estimate(graph: &PoseGraph, fixed: &[bool]) -> Result<Option<Vec<NodeValue>>, GraphError> {
    estimate_in_order(graph, fixed, None)
}

/// [`estimate`] with the unknowns numbered by `order` (per node: its position in a
/// fill-reducing order, `None` exactly for the nodes marked in `fixed`; the optimiser's block
/// numbering), so that both systems are factorised in that order without an AMD of their own;
/// without `order`, natural numbering and AMD on each system.
pub(crate) fn estimate_in_order(
    graph: &PoseGraph,
    fixed: &[bool],
    order: Option<&[Option<usize>]>,
) -> Result<Option<Vec<NodeValue>>, GraphError> {
    let nodes = graph.nodes();
    let n = nodes.len();
    let mut poses = Vec::with_capacity(n);
    for node in nodes {
        match node.value {
            NodeValue::Pose(p) => poses.push(p),
            NodeValue::Point(_) => return Ok(None),
        }
    }
    let mut edges = Vec::with_capacity(graph.edges().len());
    for e in graph.edges() {
        match e {
            Edge::Between(b) => edges.push(*b),
            _ => return Ok(None),
        }
    }
    if !fixed.iter().any(|&f| f) {
        return Ok(None);
    }
    // Breadth-first spanning tree from the fixed nodes: θ̂ by summing measured headings.
    let mut adj: Vec<Vec<(usize, usize)>> = vec![Vec::new(); n];
    for (k, e) in edges.iter().enumerate() {
        adj[e.from].push((k, e.to));
        adj[e.to].push((k, e.from));
    }
    let mut tree_theta = vec![f64::NAN; n];
    let mut queue = VecDeque::new();
    for i in 0..n {
        if fixed[i] {
            tree_theta[i] = poses[i].theta;
            queue.push_back(i);
        }
    }
    while let Some(i) = queue.pop_front() {
        for &(k, j) in &adj[i] {
            if tree_theta[j].is_nan() {
                let e = &edges[k];
                let d = e.measurement.theta;
                tree_theta[j] = if e.from == i {
                    tree_theta[i] + d
                } else {
                    tree_theta[i] - d
                };
                queue.push_back(j);
            }
        }
    }
    if tree_theta.iter().any(|t| t.is_nan()) {
        return Ok(None);
    }
    // Variable numbering of the free nodes.
    let mut var = vec![None; n];
    let mut m = 0;
    for i in 0..n {
        if !fixed[i] {
            var[i] = Some(m);
            m += 1;
        }
    }
    let ordering = match order {
        Some(o) if o.len() == n && o.iter().zip(fixed).all(|(v, &f)| v.is_none() == f) => {
            var.copy_from_slice(o);
            Ordering::Natural
        }
        _ => Ordering::Amd,
    };
    if m == 0 {
        return Ok(None);
    }
    // Marginal covariance Σ = Ω⁻¹ of each measurement.
    let mut sigma = Vec::with_capacity(edges.len());
    for e in &edges {
        let s = e
            .information
            .try_inverse()
            .ok_or(GraphError::NotPositiveDefinite { iteration: 0 })?;
        sigma.push(s);
    }

    // 1. Orientations.
    let pairs: Vec<(usize, usize)> = edges
        .iter()
        .filter_map(|e| Some((var[e.from]?, var[e.to]?)))
        .collect();
    let mut solver = Linear::new(&vec![1; m], pairs.iter().copied(), ordering)?;
    for (e, s) in edges.iter().zip(&sigma) {
        let d = e.measurement.theta;
        let k = ((tree_theta[e.to] - tree_theta[e.from] - d) / TAU).round();
        let delta = d + TAU * k;
        let w = 1.0 / s[(2, 2)];
        // r = θⱼ − θᵢ − δ; J = [−1, 1].
        solver.add_scalar(
            var[e.from],
            var[e.to],
            tree_theta[e.from],
            tree_theta[e.to],
            delta,
            w,
        );
    }
    let theta = solver.solve()?;
    let heading = |i: usize| match var[i] {
        Some(v) => theta[v],
        None => tree_theta[i],
    };

    // 2. Positions.
    let mut solver = Linear::new(&vec![2; m], pairs.iter().copied(), ordering)?;
    for (e, s) in edges.iter().zip(&sigma) {
        let stt = Matrix2::new(s[(0, 0)], s[(0, 1)], s[(1, 0)], s[(1, 1)]);
        let lambda = stt
            .try_inverse()
            .ok_or(GraphError::NotPositiveDefinite { iteration: 0 })?;
        let (si, ci) = detmath::sin_cos(heading(e.from));
        let (sz, cz) = detmath::sin_cos(e.measurement.theta);
        let ri = Matrix2::new(ci, -si, si, ci);
        let rz = Matrix2::new(cz, -sz, sz, cz);
        let rot = ri * rz;
        let w = rot * lambda * rot.transpose();
        let w = (w + w.transpose()) * 0.5;
        let tz = ri * slam_models::Vector2::new(e.measurement.x, e.measurement.y);
        let (pi, pj) = (&poses[e.from], &poses[e.to]);
        solver.add_vector(
            var[e.from],
            var[e.to],
            [pi.x, pi.y],
            [pj.x, pj.y],
            [tz.x, tz.y],
            &w,
        );
    }
    let t = solver.solve()?;
    let out = (0..n)
        .map(|i| match var[i] {
            Some(v) => NodeValue::Pose(Pose2::new(
                t[2 * v],
                t[2 * v + 1],
                normalize_angle(theta[v]),
            )),
            None => NodeValue::Pose(poses[i]),
        })
        .collect();
    Ok(Some(out))
}

/// A linear least-squares problem Σ ‖xⱼ − xᵢ − c‖²_W over blocks of one size, some ends
/// fixed (their values given), assembled into H x = b and solved by the sparse Cholesky.
struct Linear {
    pattern: BlockPattern,
    h: Vec<f64>,
    b: Vec<f64>,
    ordering: Ordering,
}

impl Linear {
    fn new(
        dims: &[usize],
        pairs: impl IntoIterator<Item = (usize, usize)>,
        ordering: Ordering,
    ) -> Result<Self, GraphError> {
        let pattern = BlockPattern::new(dims, pairs);
        Ok(Self {
            h: vec![0.0; pattern.nnz()],
            b: vec![0.0; pattern.n()],
            pattern,
            ordering,
        })
    }

    /// (xⱼ − xᵢ − c)ᵀ W (xⱼ − xᵢ − c) for blocks of size D; a `None` end is fixed at its
    /// value in `vi` / `vj`.
    #[allow(clippy::too_many_arguments)]
    fn add<const D: usize>(
        &mut self,
        i: Option<usize>,
        j: Option<usize>,
        vi: [f64; D],
        vj: [f64; D],
        c: [f64; D],
        w: &nalgebra::SMatrix<f64, D, D>,
    ) {
        // The constant part of the residual: c plus the fixed ends moved to the right side.
        let mut rhs = nalgebra::SVector::<f64, D>::from_column_slice(&c);
        if i.is_none() {
            rhs += nalgebra::SVector::<f64, D>::from_column_slice(&vi);
        }
        if j.is_none() {
            rhs -= nalgebra::SVector::<f64, D>::from_column_slice(&vj);
        }
        // Normal equations of r = xⱼ − xᵢ − rhs: H += JᵀWJ, b += JᵀW rhs, J = [−I, I].
        let wr = w * rhs;
        let p = &self.pattern;
        if let Some(a) = i {
            p.add_block(&mut self.h, a, a, p.row_offset(a, a), w.as_slice());
            let o = p.offset[a];
            for k in 0..D {
                self.b[o + k] -= wr[k];
            }
        }
        if let Some(bj) = j {
            p.add_block(&mut self.h, bj, bj, p.row_offset(bj, bj), w.as_slice());
            let o = p.offset[bj];
            for k in 0..D {
                self.b[o + k] += wr[k];
            }
        }
        if let (Some(a), Some(bj)) = (i, j) {
            let (lo, hi) = (a.min(bj), a.max(bj));
            let neg = -w;
            p.add_block(&mut self.h, lo, hi, p.row_offset(lo, hi), neg.as_slice());
        }
    }

    fn add_scalar(&mut self, i: Option<usize>, j: Option<usize>, vi: f64, vj: f64, c: f64, w: f64) {
        self.add::<1>(
            i,
            j,
            [vi],
            [vj],
            [c],
            &nalgebra::SMatrix::<f64, 1, 1>::new(w),
        );
    }

    fn add_vector(
        &mut self,
        i: Option<usize>,
        j: Option<usize>,
        vi: [f64; 2],
        vj: [f64; 2],
        c: [f64; 2],
        w: &Matrix2,
    ) {
        self.add::<2>(i, j, vi, vj, c, w);
    }

    fn solve(self) -> Result<Vec<f64>, GraphError> {
        let mut llt = SparseLlt::analyse(&self.pattern, self.ordering, Factorization::Auto)?;
        if !llt.factorize(&self.pattern, &self.h) {
            return Err(GraphError::NotPositiveDefinite { iteration: 0 });
        }
        let mut x = self.b;
        llt.solve_in_place(&mut x);
        Ok(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::Matrix3;

    /// A square loop of four unit steps turning +90° each, the initial headings wrong by up
    /// to 3 rad (so a local method starts on the wrong side of ±π): the estimate is the
    /// truth, exactly, since consistent measurements give zero residuals in both problems.
    #[test]
    fn consistent_square_is_recovered_exactly() {
        let truth = [
            Pose2::new(0.0, 0.0, 0.0),
            Pose2::new(1.0, 0.0, std::f64::consts::FRAC_PI_2),
            Pose2::new(1.0, 1.0, std::f64::consts::PI),
            Pose2::new(0.0, 1.0, -std::f64::consts::FRAC_PI_2),
        ];
        let mut g = PoseGraph::new();
        g.add_pose(0, truth[0]).unwrap();
        for (i, p) in truth.iter().enumerate().skip(1) {
            g.add_pose(i as u64, Pose2::new(p.x + 3.0, p.y - 2.0, p.theta + 3.0))
                .unwrap();
        }
        let info = Matrix3::new(10.0, 1.0, 0.5, 1.0, 20.0, 0.2, 0.5, 0.2, 100.0);
        for i in 0..4 {
            let j = (i + 1) % 4;
            let z = truth[i].between(&truth[j]);
            g.add_between(i as u64, j as u64, z, info).unwrap();
        }
        let fixed = [true, false, false, false];
        let x = estimate(&g, &fixed).unwrap().unwrap();
        for (v, t) in x.iter().zip(&truth) {
            let NodeValue::Pose(p) = v else { panic!() };
            assert!(p.approx_eq(t, 1e-12), "{p:?} vs {t:?}");
        }
    }

    #[test]
    fn refuses_what_it_cannot_estimate() {
        let mut g = PoseGraph::new();
        g.add_pose(0, Pose2::IDENTITY).unwrap();
        g.add_pose(1, Pose2::IDENTITY).unwrap();
        g.add_pose(2, Pose2::IDENTITY).unwrap();
        g.add_between(0, 1, Pose2::new(1.0, 0.0, 0.0), Matrix3::identity())
            .unwrap();
        // Node 2 is not joined to the fixed node.
        assert_eq!(estimate(&g, &[true, false, false]).unwrap(), None);
        // No fixed node.
        assert_eq!(estimate(&g, &[false, false, false]).unwrap(), None);
        g.add_point(9, slam_models::Point2::new(1.0, 1.0)).unwrap();
        assert_eq!(estimate(&g, &[true, false, false, false]).unwrap(), None);
    }
}
