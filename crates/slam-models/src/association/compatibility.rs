//! Individual compatibility (Neira & Tardós 2001, §2): observation zᵢ and landmark mⱼ are
//! compatible when d²ᵢⱼ = νᵢⱼᵀ·Sᵢⱼ⁻¹·νᵢⱼ < χ²₂(p), with νᵢⱼ = zᵢ − h(x, mⱼ) and
//! Sᵢⱼ = Hᵢⱼ·Σ·Hᵢⱼᵀ + Q, Hᵢⱼ touching only the pose and mⱼ.

use super::{JointGaussian, Linearised};
use crate::gaussian::mahalanobis_and_log_det;
use crate::measurement::RangeBearingModel;
use crate::{Matrix2, Matrix2x3, RangeBearing};

/// A gated pairing of one observation with one landmark.
#[derive(Debug, Clone, Copy)]
pub struct Candidate {
    /// The observation linearised against this landmark.
    pub lin: Linearised,
    /// Innovation covariance Sᵢⱼ (Q included).
    pub s: Matrix2,
    /// d² = νᵀS⁻¹ν.
    pub d2: f64,
    /// ln det S (for the maximum-likelihood choice).
    pub log_det: f64,
}

/// H·Σ·Hᵀ for the pose–landmark pair of `lin` (no Q).
pub fn projected_cov<B: JointGaussian + ?Sized>(state: &B, lin: &Linearised) -> Matrix2 {
    let j = lin.landmark;
    let pxx = state.pose_cov();
    let pxm = state.pose_landmark_cov(j);
    let pmm = state.landmark_cov(j);
    let hp: &Matrix2x3 = &lin.h_pose;
    let hl = &lin.h_landmark;
    let cross = hp * pxm * hl.transpose();
    hp * pxx * hp.transpose() + cross + cross.transpose() + hl * pmm * hl.transpose()
}

/// Cov(h_a, h_b) between two predicted measurements of different landmarks (no Q):
/// [Hp_a Hl_a]·Σ[(x, m_a), (x, m_b)]·[Hp_b Hl_b]ᵀ.
pub fn cross_cov<B: JointGaussian + ?Sized>(state: &B, a: &Linearised, b: &Linearised) -> Matrix2 {
    let pxx = state.pose_cov();
    let pxa = state.pose_landmark_cov(a.landmark);
    let pxb = state.pose_landmark_cov(b.landmark);
    let pab = state.landmark_landmark_cov(a.landmark, b.landmark);
    a.h_pose * pxx * b.h_pose.transpose()
        + a.h_pose * pxb * b.h_landmark.transpose()
        + a.h_landmark * pxa.transpose() * b.h_pose.transpose()
        + a.h_landmark * pab * b.h_landmark.transpose()
}

/// Linearises observation `z` against landmark slot `j` at the current mean; `None` when
/// the landmark sits on the robot (degenerate geometry).
pub fn linearise<B: JointGaussian + ?Sized>(
    state: &B,
    sensor: &RangeBearingModel,
    z: &RangeBearing,
    j: usize,
) -> Option<Linearised> {
    let pred = sensor.predict(&state.pose(), &state.landmark(j)).ok()?;
    Some(Linearised {
        landmark: j,
        nu: RangeBearingModel::innovation(&z.to_vector(), &pred.z),
        h_pose: pred.h_pose,
        h_landmark: pred.h_landmark,
        q: sensor.noise_covariance(),
    })
}

/// Every landmark individually compatible with `z` at threshold `gate` (a χ²₂ value),
/// sorted by increasing d². O(n).
pub fn candidates<B: JointGaussian + ?Sized>(
    state: &B,
    sensor: &RangeBearingModel,
    z: &RangeBearing,
    gate: f64,
) -> Vec<Candidate> {
    let mut out = Vec::new();
    for j in 0..state.landmark_count() {
        let Some(lin) = linearise(state, sensor, z, j) else {
            continue;
        };
        let s = projected_cov(state, &lin) + lin.q;
        let Ok((d2, log_det)) = mahalanobis_and_log_det(&lin.nu, &s) else {
            continue;
        };
        if d2 < gate {
            out.push(Candidate {
                lin,
                s,
                d2,
                log_det,
            });
        }
    }
    out.sort_by(|a, b| a.d2.total_cmp(&b.d2));
    out
}
