//! Mutual consistency of a group of loop-closure hypotheses (Olson, "Recognizing places
//! using spectrally clustered local matches", Robotics and Autonomous Systems 57, 2009, §3).
//!
//! Two closures i: aᵢ → bᵢ (measured zᵢ) and j: aⱼ → bⱼ, found close together in time, are
//! consistent when the loop they form with the scan-matching chain between their ends
//! closes:
//!
//! ```text
//! Tᵢⱼ = zᵢ ⊕ (bᵢ⁻¹ ⊕ bⱼ) ⊕ zⱼ⁻¹ ⊕ (aⱼ⁻¹ ⊕ aᵢ)  ≈ identity,
//! ```
//!
//! with a and b the keyframes' poses in the local (scan-matching) frame, which loop closures
//! never move. With e = (x, y, θ) of Tᵢⱼ and Σᵢⱼ the sum of the two closures' covariances and
//! of the two chains' drift covariances (isotropic, growing linearly with the path length
//! between the chain's ends), χ²ᵢⱼ = eᵀΣᵢⱼ⁻¹e and the consistency Aᵢⱼ = exp(−χ²ᵢⱼ / (2·3))
//! (a typical pair of true closures, χ² ≈ 3, scores e^{−½}; a pair 3σ apart in each
//! component, χ² = 27, scores 0.011); Aᵢᵢ = 1. The group's dominant eigenvector v₁ of A
//! gives every hypothesis's membership in the largest consistent cluster; the cluster is the
//! prefix of the hypotheses sorted by v₁ that maximises the Rayleigh quotient uᵀAu / uᵀu of
//! its indicator u (Olson eq. 6). It is accepted only when it is clearly dominant,
//! λ₁ / λ₂ ≥ `min_ratio` (Olson's confidence test: a second, competing explanation of the
//! place, e.g. a corridor matched at two offsets, makes λ₂ close to λ₁), and has at least
//! `min_size` members.

use slam_models::{normalize_angle, Matrix3, Pose2};

/// One loop-closure hypothesis of a group: the measured pose `z` of keyframe `b` in the frame
/// of keyframe `a`, its covariance (in `a`'s frame), and both keyframes' local poses and
/// path lengths (metres travelled from the first keyframe).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Hypothesis {
    pub z: Pose2,
    pub covariance: Matrix3,
    pub a: Pose2,
    pub b: Pose2,
    pub a_path: f64,
    pub b_path: f64,
}

/// The settings of [`dominant_group`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GroupTest {
    /// Standard deviation of the scan-matching chain's drift per metre of path, (m/m, rad/m).
    pub drift: [f64; 2],
    /// Fewest members of an accepted cluster.
    pub min_size: usize,
    /// Least λ₁ / λ₂ of an accepted cluster.
    pub min_ratio: f64,
}

/// What [`dominant_group`] decided: the accepted members' indices (empty when the group is
/// rejected), λ₁ and λ₂.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct GroupDecision {
    pub accepted: Vec<usize>,
    pub lambda1: f64,
    pub lambda2: f64,
}

/// χ² of the loop formed by hypotheses `h` and `g` (see the module documentation).
pub(crate) fn pair_chi2(h: &Hypothesis, g: &Hypothesis, drift: [f64; 2]) -> f64 {
    let t =
        h.z.compose(&h.b.between(&g.b))
            .compose(&g.z.inverse())
            .compose(&g.a.between(&h.a));
    // The closures' covariances are added as they are (their frames differ by the small
    // rotation between aᵢ and aⱼ, neglected), the chains' as isotropic drift.
    let chain = |len: f64| {
        let (st, sr) = (drift[0] * len, drift[1] * len);
        Matrix3::from_diagonal(&slam_models::Vector3::new(st * st, st * st, sr * sr))
    };
    let cov = h.covariance
        + g.covariance
        + chain((h.b_path - g.b_path).abs())
        + chain((h.a_path - g.a_path).abs());
    let e = slam_models::Vector3::new(t.x, t.y, normalize_angle(t.theta));
    match cov.try_inverse() {
        Some(info) => (e.transpose() * info * e)[(0, 0)].max(0.0),
        None => f64::INFINITY,
    }
}

/// The dominant consistent cluster of `hyps` (see the module documentation).
pub(crate) fn dominant_group(hyps: &[Hypothesis], test: &GroupTest) -> GroupDecision {
    let n = hyps.len();
    if n == 0 {
        return GroupDecision {
            accepted: Vec::new(),
            lambda1: 0.0,
            lambda2: 0.0,
        };
    }
    let mut a = vec![0.0; n * n];
    for i in 0..n {
        a[i * n + i] = 1.0;
        for j in i + 1..n {
            let s = (-pair_chi2(&hyps[i], &hyps[j], test.drift) / 6.0).exp();
            a[i * n + j] = s;
            a[j * n + i] = s;
        }
    }
    // A is symmetric: its eigen-decomposition (nalgebra's symmetric QR), eigenvalues sorted
    // decreasing; v₁ is taken with a non-negative sum (Perron-Frobenius: the dominant
    // eigenvector of a non-negative matrix can be chosen non-negative).
    let eig = nalgebra::DMatrix::from_row_slice(n, n, &a).symmetric_eigen();
    let mut by_value: Vec<usize> = (0..n).collect();
    by_value.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let lambda1 = eig.eigenvalues[by_value[0]];
    let lambda2 = by_value
        .get(1)
        .map_or(0.0, |&i| eig.eigenvalues[i].max(0.0));
    let col = eig.eigenvectors.column(by_value[0]);
    let sign = if col.sum() < 0.0 { -1.0 } else { 1.0 };
    let v: Vec<f64> = col.iter().map(|x| sign * x).collect();
    // The indicator: the prefix of the hypotheses by decreasing v₁ with the largest
    // Rayleigh quotient uᵀAu / uᵀu.
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| v[j].total_cmp(&v[i]).then(i.cmp(&j)));
    let (mut best, mut best_k, mut sum) = (f64::NEG_INFINITY, 0, 0.0);
    for k in 0..n {
        let new = order[k];
        sum += a[new * n + new];
        for &old in &order[..k] {
            sum += 2.0 * a[new * n + old];
        }
        let q = sum / (k + 1) as f64;
        if q > best {
            (best, best_k) = (q, k + 1);
        }
    }
    let mut accepted: Vec<usize> = order[..best_k].to_vec();
    accepted.sort_unstable();
    let dominant = lambda2 <= 0.0 || lambda1 / lambda2 >= test.min_ratio;
    if !dominant || accepted.len() < test.min_size {
        accepted.clear();
    }
    GroupDecision {
        accepted,
        lambda1,
        lambda2,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEST: GroupTest = GroupTest {
        drift: [0.02, 0.005],
        min_size: 2,
        min_ratio: 2.0,
    };

    /// True closures of a robot revisiting a straight stretch 30 m after it first drove it
    /// (local frame), keyframes every 0.2 m; the local frame has drifted by `drift` between
    /// the two passes (the closures measure the true relative poses, which the drifted local
    /// poses do not satisfy). Closure k joins first-pass keyframe k to second-pass keyframe
    /// k; `offset` is added to the measured z of the closures listed in `wrong`.
    fn group(n: usize, wrong: &[usize], offset: Pose2) -> Vec<Hypothesis> {
        let drift = Pose2::new(0.7, -0.4, 0.05);
        let cov = Matrix3::from_diagonal(&slam_models::Vector3::new(4e-4, 4e-4, 1e-5));
        (0..n)
            .map(|k| {
                let truth_a = Pose2::new(0.2 * k as f64, 0.0, 0.0);
                // Second pass: the same place 0.1 m to the side, heading 0.02 rad off.
                let truth_b = truth_a.compose(&Pose2::new(0.03, 0.1, 0.02));
                let mut z = truth_a.between(&truth_b);
                if wrong.contains(&k) {
                    z = z.compose(&offset);
                }
                Hypothesis {
                    z,
                    covariance: cov,
                    a: truth_a,
                    b: drift.compose(&truth_b),
                    a_path: 0.2 * k as f64,
                    b_path: 30.0 + 0.2 * k as f64,
                }
            })
            .collect()
    }

    /// A group of correct closures is accepted whole, however far the local frame drifted
    /// between the passes (the test compares closures with each other, not with the graph).
    #[test]
    fn a_correct_group_is_accepted() {
        let hyps = group(6, &[], Pose2::IDENTITY);
        let d = dominant_group(&hyps, &TEST);
        assert_eq!(d.accepted, vec![0, 1, 2, 3, 4, 5], "{d:?}");
        // Every pair closes to numerical precision: A is all ones, λ₁ = n.
        assert!((d.lambda1 - 6.0).abs() < 1e-6, "{d:?}");
    }

    /// One planted wrong closure (a corridor match 1.5 m along the axis) among five correct
    /// ones is left out, the rest accepted.
    #[test]
    fn a_planted_outlier_is_left_out() {
        let hyps = group(6, &[2], Pose2::new(1.5, 0.0, 0.0));
        let d = dominant_group(&hyps, &TEST);
        assert_eq!(d.accepted, vec![0, 1, 3, 4, 5], "{d:?}");
    }

    /// Two explanations of equal weight (three closures at one offset, three at another 1 m
    /// away, as an aliased corridor gives) are rejected together: neither is dominant.
    #[test]
    fn a_planted_wrong_group_competing_with_a_right_one_is_rejected() {
        let hyps = group(6, &[3, 4, 5], Pose2::new(1.0, 0.0, 0.0));
        let d = dominant_group(&hyps, &TEST);
        assert!(d.accepted.is_empty(), "{d:?}");
        assert!(d.lambda1 / d.lambda2 < TEST.min_ratio, "{d:?}");
    }

    /// A wrong group whose members disagree with each other (each matched at a different
    /// wrong place) is rejected; so is a single closure (nothing confirms it).
    #[test]
    fn an_inconsistent_group_and_a_lone_closure_are_rejected() {
        let mut hyps = group(4, &[], Pose2::IDENTITY);
        for (k, h) in hyps.iter_mut().enumerate() {
            h.z =
                h.z.compose(&Pose2::new(0.8 * k as f64, -0.6 * k as f64, 0.1 * k as f64));
        }
        let d = dominant_group(&hyps, &TEST);
        assert!(d.accepted.len() < 2, "{d:?}");
        let lone = group(1, &[], Pose2::IDENTITY);
        assert!(dominant_group(&lone, &TEST).accepted.is_empty());
    }

    /// λ₂ from deflation matches the closed form of a 2 × 2 block: [[1, s], [s, 1]] has
    /// eigenvalues 1 ± s.
    #[test]
    fn second_eigenvalue_of_a_pair() {
        let mut hyps = group(2, &[1], Pose2::new(0.05, 0.0, 0.0));
        hyps[0].covariance *= 1.0;
        let chi2 = pair_chi2(&hyps[0], &hyps[1], TEST.drift);
        let s = (-chi2 / 6.0).exp();
        let d = dominant_group(&hyps, &TEST);
        assert!((d.lambda1 - (1.0 + s)).abs() < 1e-9, "{d:?} s = {s}");
        assert!((d.lambda2 - (1.0 - s)).abs() < 1e-6, "{d:?} s = {s}");
    }
}
