//! One batch of observations through association, in the order EKF-SLAM defined and the
//! pose graph reuses: (1) observations with known ids are paired with their landmarks
//! (outliers beyond the known-id gate rejected), (2) id-less observations are gated
//! against every landmark and associated by nearest neighbour or JCBB; the caller then uses
//! the pairs (an EKF update, graph edges) and adds the landmarks first seen by id; (3) the
//! unpaired id-less observations inside some landmark's wider new-landmark gate are
//! ambiguous and dropped, the others are provisional sightings that join after k
//! consistent ones (at once when k = 1).

use super::{
    candidates, jcbb, linearise, nearest, projected_cov, Association, AssociationMode, Candidate,
    GateTable, JointGaussian, Linearised, ProvisionalList,
};
use crate::chi2::chi2_quantile;
use crate::error::ModelError;
use crate::gaussian::mahalanobis_squared;
use crate::measurement::RangeBearingModel;
use crate::{LandmarkId, Matrix2, Matrix3, Pose2, RangeBearing};
use std::collections::HashMap;

/// The association keys of a landmark SLAM configuration (EKF-SLAM's and the pose graph's
/// share their names, meanings and defaults).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AssociationOptions {
    /// Known ids, or nearest neighbour / JCBB for id-less observations.
    pub mode: AssociationMode,
    /// Individual-compatibility gate, a χ²₂ probability.
    pub gate_probability: f64,
    /// Unpaired id-less observations inside this wider χ²₂ gate are ambiguous.
    pub new_landmark_gate_probability: f64,
    /// JCBB's joint gate, a χ²_{2k} probability.
    pub joint_probability: f64,
    /// Outlier gate for known ids (χ²₂ probability); `None` accepts every observation.
    pub known_id_gate_probability: Option<f64>,
    /// Sightings an id-less landmark needs before it joins the map (≥ 1).
    pub min_sightings: usize,
    /// A provisional landmark unseen for more than this many updates is dropped (≥ 1).
    pub provisional_max_age: usize,
    /// Gate (χ²₂ probability) matching a sighting to a provisional landmark.
    pub provisional_gate_probability: f64,
    /// JCBB's search budget, interpretation-tree nodes per update (≥ 1).
    pub jcbb_max_nodes: usize,
    /// Observations with a range below this (m) are rejected (the bearing of a landmark on
    /// the robot is undefined); ≥ 0.
    pub min_range: f64,
}

impl AssociationOptions {
    /// Checks every field against its documented range; the error names the field.
    pub fn validate(&self) -> Result<(), ModelError> {
        let bad = |name, value: f64, ok: bool, expected| {
            if ok && value.is_finite() {
                Ok(())
            } else {
                Err(ModelError::OutOfRange {
                    name,
                    value,
                    expected,
                })
            }
        };
        let probability =
            |name, p: f64| bad(name, p, p > 0.0 && p < 1.0, "a probability in (0, 1)");
        probability("gate_probability", self.gate_probability)?;
        probability("joint_probability", self.joint_probability)?;
        let p = self.new_landmark_gate_probability;
        bad(
            "new_landmark_gate_probability",
            p,
            p >= self.gate_probability && p < 1.0,
            "a probability in [gate_probability, 1)",
        )?;
        probability(
            "provisional_gate_probability",
            self.provisional_gate_probability,
        )?;
        if let Some(p) = self.known_id_gate_probability {
            probability("known_id_gate_probability", p)?;
        }
        for (name, v) in [
            ("min_sightings", self.min_sightings),
            ("provisional_max_age", self.provisional_max_age),
            ("jcbb_max_nodes", self.jcbb_max_nodes),
        ] {
            bad(name, v as f64, v >= 1, "at least 1")?;
        }
        bad(
            "min_range",
            self.min_range,
            self.min_range >= 0.0,
            "finite and >= 0",
        )
    }
}

/// The outcome of [`Associator::pair`] for one batch.
#[derive(Debug, Clone, Default)]
pub struct Pairing {
    /// What became of each observation, in input order (updated by the later phases).
    pub associations: Vec<Association>,
    /// (observation, its linearisation against the paired landmark), known ids first.
    pub paired: Vec<(usize, Linearised)>,
    /// Observations whose id is not in the map yet (the caller adds them).
    pub new_known: Vec<usize>,
    /// Id-less observations ambiguous between landmarks (dropped).
    pub ambiguous: usize,
    /// Id-less observations held as provisional sightings.
    pub provisional: usize,
    /// JCBB: interpretation-tree nodes visited, and whether the budget ran out.
    pub jcbb_nodes: usize,
    /// True when JCBB's node budget ran out.
    pub jcbb_exhausted: bool,
    /// Id-less observations (indices) and, per each, whether it was paired and whether some
    /// landmark lies inside its new-landmark gate.
    unknown: Vec<(usize, bool, bool)>,
}

/// Association state across batches: the gate thresholds and the provisional landmarks.
#[derive(Debug, Clone)]
pub struct Associator {
    options: AssociationOptions,
    gate: f64,
    new_landmark_gate: f64,
    known_gate: Option<f64>,
    provisional_gate: f64,
    joint: GateTable,
    provisional: ProvisionalList,
}

impl Associator {
    /// Thresholds from validated `options`.
    pub fn new(options: AssociationOptions) -> Self {
        Self {
            gate: chi2_quantile(2, options.gate_probability),
            new_landmark_gate: chi2_quantile(2, options.new_landmark_gate_probability),
            known_gate: options
                .known_id_gate_probability
                .map(|p| chi2_quantile(2, p)),
            provisional_gate: chi2_quantile(2, options.provisional_gate_probability),
            joint: GateTable::new(options.joint_probability),
            provisional: ProvisionalList::default(),
            options,
        }
    }

    /// Number of provisional landmarks waiting for more sightings.
    pub fn provisional_count(&self) -> usize {
        self.provisional.len()
    }

    /// Phases (1) and (2) of the module documentation against `belief`, whose landmark j
    /// has id `ids[j]` (`index` the inverse map). Errors with the observation's index when
    /// the mode is `KnownIds` and it has no id.
    pub fn pair<B: JointGaussian + ?Sized>(
        &mut self,
        belief: &B,
        sensor: &RangeBearingModel,
        ids: &[LandmarkId],
        index: &HashMap<LandmarkId, usize>,
        observations: &[RangeBearing],
    ) -> Result<Pairing, usize> {
        let mode = self.options.mode;
        let mut out = Pairing {
            associations: vec![Association::Rejected; observations.len()],
            ..Pairing::default()
        };
        let mut unknown: Vec<usize> = Vec::new();
        for (i, z) in observations.iter().enumerate() {
            if z.range < 0.0 || z.range < self.options.min_range {
                continue; // Rejected: a sensor glitch, or a landmark on the robot.
            }
            let id = match mode {
                AssociationMode::KnownIds => Some(z.id.ok_or(i)?),
                AssociationMode::Auto => z.id,
                AssociationMode::NearestNeighbour | AssociationMode::Jcbb => None,
            };
            let Some(id) = id else {
                unknown.push(i);
                continue;
            };
            let Some(&slot) = index.get(&id) else {
                out.new_known.push(i);
                continue;
            };
            let Some(lin) = linearise(belief, sensor, z, slot) else {
                continue;
            };
            if let Some(gate) = self.known_gate {
                let s = projected_cov(belief, &lin) + lin.q;
                match mahalanobis_squared(&lin.nu, &s) {
                    Ok(d2) if d2 < gate => {}
                    _ => continue,
                }
            }
            out.paired.push((i, lin));
            out.associations[i] = Association::Landmark(id);
        }
        let mut near = vec![false; unknown.len()];
        let cands: Vec<Vec<Candidate>> = unknown
            .iter()
            .enumerate()
            .map(|(u, &i)| {
                let mut c = candidates(belief, sensor, &observations[i], self.new_landmark_gate);
                near[u] = !c.is_empty();
                c.retain(|c| c.d2 < self.gate);
                c
            })
            .collect();
        let chosen: Vec<Option<usize>> = if cands.iter().all(|c| c.is_empty()) {
            vec![None; cands.len()]
        } else if mode == AssociationMode::NearestNeighbour {
            nearest::associate(&cands)
        } else {
            let r = jcbb::associate(belief, &cands, &mut self.joint, self.options.jcbb_max_nodes);
            out.jcbb_nodes = r.nodes;
            out.jcbb_exhausted = r.exhausted;
            r.assignment
        };
        for (u, &i) in unknown.iter().enumerate() {
            if let Some(c) = chosen[u] {
                let lin = cands[u][c].lin;
                out.associations[i] = Association::Landmark(ids[lin.landmark]);
                out.paired.push((i, lin));
            }
            out.unknown.push((i, chosen[u].is_some(), near[u]));
        }
        Ok(out)
    }

    /// Phase (3) at `step` (one count per batch), from the robot pose `pose` with covariance
    /// `pose_cov` after the caller's use of the pairs: returns the id-less observations that
    /// are to join the map now, in input order (the caller gives them ids and records them
    /// as [`Association::New`]); the ambiguous and provisional ones are counted and marked in
    /// `pairing`.
    pub fn unpaired(
        &mut self,
        pairing: &mut Pairing,
        pose: &Pose2,
        pose_cov: &Matrix3,
        sensor: &RangeBearingModel,
        observations: &[RangeBearing],
        step: u64,
    ) -> Vec<usize> {
        let q = sensor.noise_covariance();
        let mut ready = Vec::new();
        for &(i, paired, near) in &pairing.unknown {
            if paired {
                continue;
            }
            if near {
                pairing.ambiguous += 1;
                continue;
            }
            if self.options.min_sightings <= 1 {
                ready.push(i);
                continue;
            }
            let inv = sensor.inverse(pose, &observations[i]);
            let cov: Matrix2 =
                inv.g_pose * pose_cov * inv.g_pose.transpose() + inv.g_z * q * inv.g_z.transpose();
            let (n, k) = self
                .provisional
                .sight(inv.landmark, cov, step, self.provisional_gate);
            if n >= self.options.min_sightings {
                self.provisional.remove(k);
                ready.push(i);
            } else {
                pairing.associations[i] = Association::Provisional;
                pairing.provisional += 1;
            }
        }
        ready
    }

    /// Drops provisional landmarks not seen for more than `provisional_max_age` batches
    /// before `step`; returns how many.
    pub fn expire(&mut self, step: u64) -> usize {
        self.provisional
            .expire(step, self.options.provisional_max_age)
    }
}
