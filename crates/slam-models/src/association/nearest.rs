//! Maximum-likelihood nearest neighbour: each observation takes, among its individually
//! compatible landmarks, the one with the largest likelihood N(ν; 0, S), i.e. the smallest
//! d² + ln det S. When two observations want the same landmark the pairing with the higher
//! likelihood wins and the other observation tries its next candidate (greedy, globally
//! sorted).

use super::Candidate;

/// For each observation (outer index), the index into its candidate list that it is
/// assigned, or `None`.
pub fn associate(cands: &[Vec<Candidate>]) -> Vec<Option<usize>> {
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (i, cs) in cands.iter().enumerate() {
        for (c, cand) in cs.iter().enumerate() {
            pairs.push((cand.d2 + cand.log_det, i, c));
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out = vec![None; cands.len()];
    let mut used = std::collections::HashSet::new();
    for (_, i, c) in pairs {
        if out[i].is_none() && used.insert(cands[i][c].lin.landmark) {
            out[i] = Some(c);
        }
    }
    out
}
