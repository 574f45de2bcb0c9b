//! The sparse linear algebra of one Gauss-Newton step: the block pattern of the normal
//! matrix H = Σ Jᵀ W Ω J (fixed for the life of an optimiser, so it and its symbolic Cholesky
//! analysis are computed once) and faer's sparse LLᵀ with a fill-reducing ordering.
//!
//! H is stored as its upper triangle in compressed sparse columns (CSC). Every column of a
//! variable block J holds, in ascending order, the rows of each lower-numbered block I joined
//! to J by an edge, then the rows of J itself down to the diagonal, so the entry (i, k) of the
//! block pair (I, J) sits at `col_ptr[off(J) + k] + r(I, J) + i` with r(I, J) the same for
//! every column of J: assembly is a table look-up, no search.

use crate::error::GraphError;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky,
    SymmetricOrdering,
};
use faer::sparse::linalg::{amd, SupernodalThreshold};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use serde::{Deserialize, Serialize};

/// The fill-reducing ordering of the sparse Cholesky factorisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Ordering {
    /// Approximate minimum degree (Amestoy, Davis and Duff 1996), faer's implementation.
    #[default]
    Amd,
    /// The variables' own order (node insertion order); for comparison only.
    Natural,
}

/// Which numeric Cholesky kernel factorises H.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Factorization {
    /// faer's choice from the symbolic analysis' flop count (supernodal when dense enough).
    #[default]
    Auto,
    /// Column by column (up-looking), best for very sparse factors.
    Simplicial,
    /// Dense blocks of columns with the same pattern (BLAS-3 kernels).
    Supernodal,
}

/// The pattern of the upper triangle of H for a set of variable blocks and the pairs of
/// blocks that edges join.
#[derive(Debug, Clone)]
pub struct BlockPattern {
    /// Scalar offset of each block's first column.
    pub(crate) offset: Vec<usize>,
    /// Size of each block (3 for a pose, 2 for a point).
    pub(crate) dim: Vec<usize>,
    /// CSC column pointers (n + 1 entries).
    pub(crate) col_ptr: Vec<usize>,
    /// CSC row indices, ascending within each column.
    pub(crate) row_idx: Vec<usize>,
    /// Lower-numbered neighbours of each block, ascending, each with its row offset r(I, J).
    upper: Vec<Vec<(usize, usize)>>,
    /// r(J, J): where block J's own rows start within each of its columns.
    diag_row: Vec<usize>,
}

impl BlockPattern {
    /// The pattern for blocks of sizes `dims` joined by `pairs` (unordered, repeats allowed).
    pub fn new(dims: &[usize], pairs: impl IntoIterator<Item = (usize, usize)>) -> Self {
        let nb = dims.len();
        let mut offset = Vec::with_capacity(nb);
        let mut n = 0;
        for &d in dims {
            offset.push(n);
            n += d;
        }
        let mut nbrs: Vec<Vec<usize>> = vec![Vec::new(); nb];
        for (a, b) in pairs {
            if a != b {
                let (i, j) = if a < b { (a, b) } else { (b, a) };
                nbrs[j].push(i);
            }
        }
        let mut upper = Vec::with_capacity(nb);
        let mut diag_row = Vec::with_capacity(nb);
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for (j, list) in nbrs.iter_mut().enumerate() {
            list.sort_unstable();
            list.dedup();
            let mut r = 0;
            let with_r: Vec<(usize, usize)> = list
                .iter()
                .map(|&i| {
                    let e = (i, r);
                    r += dims[i];
                    e
                })
                .collect();
            diag_row.push(r);
            for k in 0..dims[j] {
                for &(i, _) in &with_r {
                    row_idx.extend(offset[i]..offset[i] + dims[i]);
                }
                row_idx.extend(offset[j]..=offset[j] + k);
                col_ptr.push(row_idx.len());
            }
            upper.push(with_r);
        }
        Self {
            offset,
            dim: dims.to_vec(),
            col_ptr,
            row_idx,
            upper,
            diag_row,
        }
    }

    /// Number of scalar unknowns.
    pub fn n(&self) -> usize {
        self.col_ptr.len() - 1
    }

    /// Number of stored entries (upper triangle).
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// r(I, J) for I ≤ J joined by an edge (or I = J).
    pub(crate) fn row_offset(&self, i: usize, j: usize) -> usize {
        if i == j {
            return self.diag_row[j];
        }
        let list = &self.upper[j];
        let at = list.partition_point(|&(b, _)| b < i);
        debug_assert!(
            at < list.len() && list[at].0 == i,
            "blocks {i}, {j} not joined"
        );
        list[at].1
    }

    /// Adds the dim(I)×dim(J) block `m` (column-major) at block pair (I, J), I ≤ J, whose row
    /// offset is `r`; for I = J only the upper triangle of `m` is read.
    #[inline]
    pub(crate) fn add_block(&self, values: &mut [f64], i: usize, j: usize, r: usize, m: &[f64]) {
        let di = self.dim[i];
        for k in 0..self.dim[j] {
            let base = self.col_ptr[self.offset[j] + k] + r;
            let rows = if i == j { k + 1 } else { di };
            for (v, x) in values[base..base + rows].iter_mut().zip(&m[k * di..]) {
                *v += x;
            }
        }
    }

    /// Position in the values of each diagonal entry (the last entry of each column).
    pub(crate) fn diagonal_positions(&self) -> Vec<usize> {
        self.col_ptr[1..].iter().map(|&p| p - 1).collect()
    }
}

/// The approximate-minimum-degree ordering (faer's AMD, its default control) of `nb` blocks
/// joined by `pairs`, computed on the block graph (one scalar per block) rather than on the
/// scalar pattern: `rank[b]` is block b's position in the elimination order. Every system of
/// the same graph (H with 3 unknowns per pose, LAGO's systems with 1 and 2) can be laid out
/// in this order and factorised without a permutation: one ordering instead of one per
/// system, and AMD on a graph with 1/dim² of the scalar pattern's entries.
pub(crate) fn block_amd_rank(
    nb: usize,
    pairs: impl IntoIterator<Item = (usize, usize)>,
) -> Result<Vec<usize>, GraphError> {
    let p = BlockPattern::new(&vec![1; nb], pairs);
    let (n, nnz) = (p.n(), p.nnz());
    let mut perm = vec![0usize; n];
    let mut rank = vec![0usize; n];
    let sym = SymbolicSparseColMatRef::new_checked(n, n, &p.col_ptr, None, &p.row_idx);
    let mut mem = MemBuffer::new(amd::order_maybe_unsorted_scratch::<usize>(n, nnz));
    amd::order_maybe_unsorted(
        &mut perm,
        &mut rank,
        sym,
        amd::Control::default(),
        MemStack::new(&mut mem),
    )
    .map_err(|e| GraphError::Sparse(format!("{e:?}")))?;
    Ok(rank)
}

/// A sparse LLᵀ factorisation of H (upper triangle in CSC) through faer: symbolic analysis
/// (ordering, elimination tree, supernodes) once, numeric factorisation per step.
pub struct SparseLlt {
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<f64>,
    mem: MemBuffer,
    n: usize,
}

impl std::fmt::Debug for SparseLlt {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseLlt")
            .field("n", &self.n)
            .field("factor_nnz", &self.l_values.len())
            .finish()
    }
}

impl SparseLlt {
    /// The symbolic analysis of the pattern.
    pub fn analyse(
        pattern: &BlockPattern,
        ordering: Ordering,
        factorization: Factorization,
    ) -> Result<Self, GraphError> {
        let n = pattern.n();
        let sym =
            SymbolicSparseColMatRef::new_checked(n, n, &pattern.col_ptr, None, &pattern.row_idx);
        let ord = match ordering {
            Ordering::Amd => SymmetricOrdering::Amd,
            Ordering::Natural => SymmetricOrdering::Identity,
        };
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: match factorization {
                Factorization::Auto => SupernodalThreshold::AUTO,
                Factorization::Simplicial => SupernodalThreshold::FORCE_SIMPLICIAL,
                Factorization::Supernodal => SupernodalThreshold::FORCE_SUPERNODAL,
            },
            ..Default::default()
        };
        let symbolic = factorize_symbolic_cholesky(sym, Side::Upper, ord, params)
            .map_err(|e| GraphError::Sparse(format!("{e:?}")))?;
        let req = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, Par::Seq),
        ]);
        let l_values = vec![0.0; symbolic.len_val()];
        Ok(Self {
            symbolic,
            l_values,
            mem: MemBuffer::new(req),
            n,
        })
    }

    /// Number of stored entries of the factor L.
    pub fn factor_nnz(&self) -> usize {
        self.l_values.len()
    }

    /// Factorises H given by its upper-triangle `values` on `pattern`. Returns false when H
    /// is not numerically positive definite.
    pub fn factorize(&mut self, pattern: &BlockPattern, values: &[f64]) -> bool {
        let sym = SymbolicSparseColMatRef::new_checked(
            self.n,
            self.n,
            &pattern.col_ptr,
            None,
            &pattern.row_idx,
        );
        let a = SparseColMatRef::new(sym, values);
        self.symbolic
            .factorize_numeric_llt::<f64>(
                &mut self.l_values,
                a,
                Side::Upper,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut self.mem),
                Default::default(),
            )
            .is_ok()
    }

    /// Overwrites the n × k column-major `rhs` with H⁻¹ rhs, using the last successful
    /// factorisation (scratch for the k columns is allocated here).
    pub fn solve_columns_in_place(&self, rhs: &mut [f64], k: usize) {
        let llt = LltRef::<'_, usize, f64>::new(&self.symbolic, &self.l_values);
        let mut mem = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(k, Par::Seq));
        let x = MatMut::from_column_major_slice_mut(rhs, self.n, k);
        llt.solve_in_place_with_conj(Conj::No, x, Par::Seq, MemStack::new(&mut mem));
    }

    /// Overwrites `rhs` with H⁻¹ rhs, using the last successful factorisation.
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) {
        let llt = LltRef::<'_, usize, f64>::new(&self.symbolic, &self.l_values);
        let x = MatMut::from_column_major_slice_mut(rhs, self.n, 1);
        llt.solve_in_place_with_conj(Conj::No, x, Par::Seq, MemStack::new(&mut self.mem));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random SPD system with the pattern of a small graph, solved against nalgebra's dense
    /// Cholesky, for every ordering and kernel.
    #[test]
    fn sparse_solve_matches_dense() {
        let dims = [3, 3, 2, 3, 2, 3];
        let pairs = [
            (0, 1),
            (1, 3),
            (3, 5),
            (5, 0),
            (1, 2),
            (3, 2),
            (4, 5),
            (1, 0),
        ];
        let p = BlockPattern::new(&dims, pairs);
        let n = p.n();
        assert_eq!(n, 16);
        // Dense SPD matrix restricted to the pattern: A = Σ over pairs of random blocks + dI.
        let mut dense = nalgebra::DMatrix::<f64>::zeros(n, n);
        let mut seed = 1u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        for &(a, b) in &pairs {
            let (oa, ob) = (p.offset[a], p.offset[b]);
            for i in 0..dims[a] {
                for k in 0..dims[b] {
                    let v = rnd();
                    dense[(oa + i, ob + k)] += v;
                    dense[(ob + k, oa + i)] += v;
                }
            }
        }
        for i in 0..n {
            dense[(i, i)] += 10.0;
        }
        let mut values = vec![0.0; p.nnz()];
        for c in 0..n {
            for q in p.col_ptr[c]..p.col_ptr[c + 1] {
                values[q] = dense[(p.row_idx[q], c)];
            }
        }
        // Every nonzero of the upper triangle is in the pattern.
        let stored: f64 = values.iter().map(|v| v.abs()).sum();
        let total: f64 = dense.upper_triangle().iter().map(|v| v.abs()).sum();
        assert!((stored - total).abs() < 1e-12);
        let b: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
        let want = dense
            .clone()
            .cholesky()
            .unwrap()
            .solve(&nalgebra::DVector::from_column_slice(&b));
        for ord in [Ordering::Amd, Ordering::Natural] {
            for f in [
                Factorization::Auto,
                Factorization::Simplicial,
                Factorization::Supernodal,
            ] {
                let mut llt = SparseLlt::analyse(&p, ord, f).unwrap();
                assert!(llt.factorize(&p, &values));
                let mut x = b.clone();
                llt.solve_in_place(&mut x);
                for i in 0..n {
                    assert!((x[i] - want[i]).abs() < 1e-12, "{ord:?} {f:?}");
                }
            }
        }
        // Not positive definite: reported, not a panic.
        let mut neg = values.clone();
        for d in p.diagonal_positions() {
            neg[d] = -1.0;
        }
        let mut llt = SparseLlt::analyse(&p, Ordering::Amd, Factorization::Auto).unwrap();
        assert!(!llt.factorize(&p, &neg));
    }
}
