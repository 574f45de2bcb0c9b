//! Joint compatibility branch and bound (J. Neira, J. D. Tardós, "Data association in
//! stochastic mapping using the joint compatibility test", IEEE T-RA 17(6), 2001).
//!
//! A hypothesis H pairs some observations with distinct landmarks. It is jointly
//! compatible when the stacked innovation ν_H and its covariance S_H = H·Σ·Hᵀ + Q satisfy
//! D²_H = ν_Hᵀ·S_H⁻¹·ν_H < χ²_{2k}(p), k the number of pairings; cross-covariances
//! between the pairings (through the pose and between landmarks) are included, which is
//! what rejects spurious pairings that are individually plausible. The interpretation tree
//! is searched depth first; a branch is abandoned when it cannot beat the best hypothesis'
//! number of pairings (the paper's bound). D²_H and S_H⁻¹ are updated incrementally by the
//! block-inverse (Schur complement) formula, O(k²) per node:
//!
//! ```text
//! S' = [S B; Bᵀ C],  t = S⁻¹B,  Z = (C − Bᵀt)⁻¹,
//! D²' = D² + (ν_new − tᵀν)ᵀ Z (ν_new − tᵀν),
//! S'⁻¹ = [S⁻¹ + tZtᵀ, −tZ; −Ztᵀ, Z]
//! ```
//!
//! Among hypotheses with equally many pairings the one with the smaller D² is kept.

use super::compatibility::cross_cov;
use super::{Candidate, GateTable, JointGaussian};
use nalgebra::{DMatrix, DVector};

/// The outcome of one JCBB search.
#[derive(Debug, Clone)]
pub struct JcbbResult {
    /// Per observation, the index into its candidate list, or `None` (unpaired).
    pub assignment: Vec<Option<usize>>,
    /// Nodes of the interpretation tree visited.
    pub nodes: usize,
    /// True when the node budget ran out before the search finished.
    pub exhausted: bool,
}

struct Hyp {
    /// (observation, candidate) of each pairing, in order.
    pairs: Vec<(usize, usize)>,
    nu: DVector<f64>,
    s_inv: DMatrix<f64>,
    d2: f64,
}

struct Search<'a, B: ?Sized> {
    state: &'a B,
    cands: &'a [Vec<Candidate>],
    order: Vec<usize>,
    gates: &'a mut GateTable,
    max_nodes: usize,
    nodes: usize,
    cur: Vec<Option<usize>>,
    best: Vec<Option<usize>>,
    best_pairs: usize,
    best_d2: f64,
}

impl<B: JointGaussian + ?Sized> Search<'_, B> {
    fn extend(&mut self, h: &Hyp, i: usize, c: usize) -> Option<Hyp> {
        let cand = &self.cands[i][c];
        let k = h.pairs.len();
        let mut b = DMatrix::<f64>::zeros(2 * k, 2);
        for (p, &(pi, pc)) in h.pairs.iter().enumerate() {
            let x = cross_cov(self.state, &self.cands[pi][pc].lin, &cand.lin);
            b.view_mut((2 * p, 0), (2, 2)).copy_from(&x);
        }
        let t = &h.s_inv * &b;
        let c_mat = DMatrix::from_fn(2, 2, |r, q| cand.s[(r, q)]);
        let schur = &c_mat - b.transpose() * &t;
        let z = schur.try_inverse()?;
        let nu_new = DVector::from_column_slice(cand.lin.nu.as_slice());
        let e = &nu_new - t.transpose() * &h.nu;
        let d2 = h.d2 + (e.transpose() * &z * &e)[(0, 0)];
        if !(d2.is_finite() && d2 >= 0.0) || d2 >= self.gates.threshold(k + 1) {
            return None;
        }
        let mut s_inv = DMatrix::<f64>::zeros(2 * k + 2, 2 * k + 2);
        let tz = &t * &z;
        s_inv
            .view_mut((0, 0), (2 * k, 2 * k))
            .copy_from(&(&h.s_inv + &tz * t.transpose()));
        s_inv.view_mut((0, 2 * k), (2 * k, 2)).copy_from(&(-&tz));
        s_inv
            .view_mut((2 * k, 0), (2, 2 * k))
            .copy_from(&(-tz.transpose()));
        s_inv.view_mut((2 * k, 2 * k), (2, 2)).copy_from(&z);
        let mut nu = DVector::<f64>::zeros(2 * k + 2);
        nu.rows_mut(0, 2 * k).copy_from(&h.nu);
        nu.rows_mut(2 * k, 2).copy_from(&nu_new);
        let mut pairs = h.pairs.clone();
        pairs.push((i, c));
        Some(Hyp {
            pairs,
            nu,
            s_inv,
            d2,
        })
    }

    fn recurse(&mut self, level: usize, h: &Hyp) {
        if self.nodes >= self.max_nodes {
            return;
        }
        self.nodes += 1;
        if level == self.order.len() {
            let k = h.pairs.len();
            if k > self.best_pairs || (k == self.best_pairs && h.d2 < self.best_d2) {
                self.best_pairs = k;
                self.best_d2 = h.d2;
                self.best.clone_from(&self.cur);
            }
            return;
        }
        let i = self.order[level];
        for c in 0..self.cands[i].len() {
            let lm = self.cands[i][c].lin.landmark;
            if h.pairs
                .iter()
                .any(|&(pi, pc)| self.cands[pi][pc].lin.landmark == lm)
            {
                continue;
            }
            if let Some(h2) = self.extend(h, i, c) {
                self.cur[i] = Some(c);
                self.recurse(level + 1, &h2);
                self.cur[i] = None;
            }
        }
        let remaining = self.order.len() - level - 1;
        if h.pairs.len() + remaining > self.best_pairs
            || (self.best_pairs == 0 && level + 1 == self.order.len())
        {
            self.recurse(level + 1, h);
        }
    }
}

/// Runs JCBB over the candidate lists (one per observation, each individually gated).
/// `gates` gives χ²_{2k}(p) for the joint test.
pub fn associate<B: JointGaussian + ?Sized>(
    state: &B,
    cands: &[Vec<Candidate>],
    gates: &mut GateTable,
    max_nodes: usize,
) -> JcbbResult {
    let order: Vec<usize> = (0..cands.len()).filter(|&i| !cands[i].is_empty()).collect();
    let mut search = Search {
        state,
        cands,
        order,
        gates,
        max_nodes,
        nodes: 0,
        cur: vec![None; cands.len()],
        best: vec![None; cands.len()],
        best_pairs: 0,
        best_d2: f64::INFINITY,
    };
    let root = Hyp {
        pairs: Vec::new(),
        nu: DVector::zeros(0),
        s_inv: DMatrix::zeros(0, 0),
        d2: 0.0,
    };
    search.recurse(0, &root);
    JcbbResult {
        exhausted: search.nodes >= search.max_nodes,
        nodes: search.nodes,
        assignment: search.best,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::association::{candidates, nearest, DenseGaussian};
    use crate::chi2::chi2_quantile;
    use crate::measurement::RangeBearingModel;
    use crate::{Matrix3, Pose2, RangeBearing, Vector3};

    /// Five landmarks on an arc 0.2 rad apart at 5 m; the robot's heading is uncertain
    /// (σθ = 0.2 rad) and in truth off by +0.2 rad, so every observation lands on the
    /// neighbouring landmark. Nearest neighbour takes the neighbour; JCBB prefers the
    /// hypothesis that pairs all five, which is the true one.
    #[test]
    fn jcbb_resolves_a_common_heading_error_that_fools_nearest_neighbour() {
        let sensor = RangeBearingModel::new(0.05, 0.01);
        let mut st = DenseGaussian::new(Pose2::IDENTITY, Matrix3::zeros());
        let precise = RangeBearingModel::new(1e-3, 1e-4).noise_covariance();
        let bearings = [-0.4, -0.2, 0.0, 0.2, 0.4];
        for b in bearings {
            let z = RangeBearing {
                range: 5.0,
                bearing: b,
                id: None,
            };
            st.add_landmark(&sensor.inverse(&Pose2::IDENTITY, &z), &precise);
        }
        st.predict(
            &Pose2::IDENTITY,
            &Matrix3::identity(),
            &Matrix3::from_diagonal(&Vector3::new(1e-4, 1e-4, 0.04)),
        );
        let obs: Vec<RangeBearing> = bearings
            .iter()
            .map(|b| RangeBearing {
                range: 5.0,
                bearing: b - 0.2,
                id: None,
            })
            .collect();
        let gate = chi2_quantile(2, 0.999);
        let cands: Vec<Vec<Candidate>> = obs
            .iter()
            .map(|z| candidates(&st, &sensor, z, gate))
            .collect();
        let pick = |a: &[Option<usize>]| -> Vec<Option<usize>> {
            a.iter()
                .zip(&cands)
                .map(|(c, cs)| c.map(|c| cs[c].lin.landmark))
                .collect()
        };
        let nn = pick(&nearest::associate(&cands));
        assert_ne!(nn, vec![Some(0), Some(1), Some(2), Some(3), Some(4)]);
        let mut gates = GateTable::new(0.99);
        let r = associate(&st, &cands, &mut gates, 100_000);
        assert!(!r.exhausted);
        assert_eq!(
            pick(&r.assignment),
            vec![Some(0), Some(1), Some(2), Some(3), Some(4)]
        );
    }

    /// The incremental joint d² equals the batch νᵀS⁻¹ν of the stacked hypothesis.
    #[test]
    fn incremental_joint_distance_matches_batch() {
        let sensor = RangeBearingModel::new(0.1, 0.03);
        let mut st = DenseGaussian::new(
            Pose2::new(0.5, -0.3, 0.2),
            Matrix3::from_diagonal(&Vector3::new(0.02, 0.01, 0.005)),
        );
        for (r, b) in [(3.0, 0.5), (4.0, -0.7), (2.5, 1.2)] {
            let z = RangeBearing {
                range: r,
                bearing: b,
                id: None,
            };
            st.add_landmark(&sensor.inverse(&st.pose(), &z), &sensor.noise_covariance());
        }
        let obs = [(3.1, 0.52), (3.9, -0.68), (2.45, 1.18)];
        let cands: Vec<Vec<Candidate>> = obs
            .iter()
            .map(|&(r, b)| {
                candidates(
                    &st,
                    &sensor,
                    &RangeBearing {
                        range: r,
                        bearing: b,
                        id: None,
                    },
                    1e9,
                )
            })
            .collect();
        let mut gates = GateTable::new(0.999_999);
        let mut s = Search {
            state: &st,
            cands: &cands,
            order: vec![0, 1, 2],
            gates: &mut gates,
            max_nodes: 10,
            nodes: 0,
            cur: vec![None; 3],
            best: vec![None; 3],
            best_pairs: 0,
            best_d2: f64::INFINITY,
        };
        let mut h = Hyp {
            pairs: Vec::new(),
            nu: DVector::zeros(0),
            s_inv: DMatrix::zeros(0, 0),
            d2: 0.0,
        };
        // Pair observation i with landmark i.
        for (i, cs) in cands.iter().enumerate() {
            let c = cs.iter().position(|c| c.lin.landmark == i).unwrap();
            h = s.extend(&h, i, c).expect("jointly compatible");
        }
        // Batch: S = H Σ Hᵀ + Q over the three pairings, from the dense covariance.
        let n = st.mean.len();
        let mut hm = DMatrix::<f64>::zeros(6, n);
        let mut q = DMatrix::<f64>::zeros(6, 6);
        let mut nu = DVector::<f64>::zeros(6);
        for (a, &(i, c)) in h.pairs.iter().enumerate() {
            let lin = &cands[i][c].lin;
            let l = 3 + 2 * lin.landmark;
            for r in 0..2 {
                for k in 0..3 {
                    hm[(2 * a + r, k)] = lin.h_pose[(r, k)];
                }
                for k in 0..2 {
                    hm[(2 * a + r, l + k)] = lin.h_landmark[(r, k)];
                    q[(2 * a + r, 2 * a + k)] = lin.q[(r, k)];
                }
                nu[2 * a + r] = lin.nu[r];
            }
        }
        let p = st.cov.clone();
        let sm = &hm * p * hm.transpose() + q;
        let d2 = (nu.transpose() * sm.try_inverse().unwrap() * &nu)[(0, 0)];
        assert!((h.d2 - d2).abs() < 1e-9 * d2.max(1.0), "{} vs {d2}", h.d2);
    }
}
