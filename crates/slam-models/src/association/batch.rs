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
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

/// The association keys of a landmark SLAM configuration: the `[association]` table of
/// EKF-SLAM's (`slam_ekf::EkfConfig`) and the pose graph's
/// (`slam_graph::landmark::GraphLandmarkConfig`) configuration, one struct for both.
///
/// Up to version 0.1 these keys stood flat at the top of those files (`association =
/// "auto"`, `gate-probability = 0.999`, …). A bare mode string is still read
/// ([`options_or_mode`]); any other flat key is refused by its configuration's
/// `deny_unknown_fields`, and [`moved_key_hint`] names the table it moved to.
///
/// ```
/// use slam_models::association::{AssociationMode, AssociationOptions};
/// let a: AssociationOptions = toml::from_str("mode = \"jcbb\"\nmin-sightings = 2").unwrap();
/// assert_eq!((a.mode, a.min_sightings), (AssociationMode::Jcbb, 2));
/// assert_eq!(a.gate_probability, AssociationOptions::default().gate_probability);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct AssociationOptions {
    /// Known ids, or nearest neighbour / JCBB for id-less observations.
    pub mode: AssociationMode,
    /// Individual-compatibility gate: an observation may match a landmark when its
    /// Mahalanobis distance d² = νᵀS⁻¹ν is below the χ²₂ quantile at this probability.
    pub gate_probability: f64,
    /// An id-less observation left unpaired is discarded as ambiguous, rather than starting
    /// a new landmark, when some landmark lies inside this wider χ²₂ gate (at least
    /// `gate_probability`): a duplicate of a mapped landmark costs more than a lost
    /// observation.
    pub new_landmark_gate_probability: f64,
    /// JCBB's joint gate: a hypothesis with k pairings is accepted when its joint d² is
    /// below χ²_{2k} at this probability.
    pub joint_probability: f64,
    /// Outlier gate for known ids (χ²₂ probability); `None` accepts every observation.
    pub known_id_gate_probability: Option<f64>,
    /// k: an id-less observation that matches no landmark starts a provisional landmark,
    /// which joins the map after this many consistent sightings (≥ 1; 1 = at once).
    /// Landmarks with known ids always join at their first sighting.
    pub min_sightings: usize,
    /// A provisional landmark unseen for more than this many updates is dropped (≥ 1), so
    /// its k sightings must come with gaps of at most this many updates.
    pub provisional_max_age: usize,
    /// Gate (χ²₂ probability) matching a sighting to a provisional landmark.
    pub provisional_gate_probability: f64,
    /// JCBB's search budget, interpretation-tree nodes per update (≥ 1); when it runs out
    /// the best hypothesis found so far is used.
    pub jcbb_max_nodes: usize,
}

impl Default for AssociationOptions {
    /// `Auto` association, gates at 99.9 % (individual), 99 % (joint), 99.999 % (no new
    /// landmark inside) and 99.99 % (known-id outliers), k = 4 sightings with gaps of at
    /// most 2 updates (provisional gate 99 %), 100 000 JCBB nodes.
    fn default() -> Self {
        Self {
            mode: AssociationMode::Auto,
            gate_probability: 0.999,
            new_landmark_gate_probability: 0.99999,
            joint_probability: 0.99,
            known_id_gate_probability: Some(0.9999),
            min_sightings: 4,
            provisional_max_age: 2,
            provisional_gate_probability: 0.99,
            jcbb_max_nodes: 100_000,
        }
    }
}

impl From<AssociationMode> for AssociationOptions {
    /// `mode` with every other key at its default.
    fn from(mode: AssociationMode) -> Self {
        Self {
            mode,
            ..Self::default()
        }
    }
}

/// The keys of [`AssociationOptions`] as written in a configuration file.
pub const ASSOCIATION_KEYS: [&str; 9] = [
    "mode",
    "gate-probability",
    "new-landmark-gate-probability",
    "joint-probability",
    "known-id-gate-probability",
    "min-sightings",
    "provisional-max-age",
    "provisional-gate-probability",
    "jcbb-max-nodes",
];

/// For serde's "unknown field `k`" about a key that moved into the `[association]` table
/// (its old flat spelling at the top of an EKF or graph-landmark configuration, in kebab- or
/// snake_case): the sentence saying where to write it now; `None` for any other message.
pub fn moved_key_hint(message: &str) -> Option<String> {
    let key = message
        .strip_prefix("unknown field `")?
        .split('`')
        .next()?
        .replace('_', "-");
    (key != "mode" && ASSOCIATION_KEYS.contains(&key.as_str())).then(|| {
        format!(" (the association keys moved into the [association] table: write `{key} = …` under `[association]`)")
    })
}

/// Reads a configuration's `association` value: the `[association]` table
/// ([`AssociationOptions`]), or, as files before the table did, a bare mode string
/// (`association = "known-ids"`), which sets `mode` and keeps every other key's default.
/// For `#[serde(deserialize_with = …)]`.
pub fn options_or_mode<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> Result<AssociationOptions, D::Error> {
    use serde::de::{value::MapAccessDeserializer, IntoDeserializer, MapAccess, Visitor};
    struct OptionsOrMode;
    impl<'de> Visitor<'de> for OptionsOrMode {
        type Value = AssociationOptions;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("an [association] table, or a mode name such as \"known-ids\"")
        }
        fn visit_str<E: serde::de::Error>(self, s: &str) -> Result<Self::Value, E> {
            AssociationMode::deserialize(s.into_deserializer()).map(AssociationOptions::from)
        }
        fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<Self::Value, A::Error> {
            AssociationOptions::deserialize(MapAccessDeserializer::new(map))
        }
    }
    d.deserialize_any(OptionsOrMode)
}

impl AssociationOptions {
    /// Checks every field against its documented range; the error names the field (as
    /// `association.<field>`).
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
        probability("association.gate_probability", self.gate_probability)?;
        probability("association.joint_probability", self.joint_probability)?;
        let p = self.new_landmark_gate_probability;
        bad(
            "association.new_landmark_gate_probability",
            p,
            p >= self.gate_probability && p < 1.0,
            "a probability in [gate_probability, 1)",
        )?;
        probability(
            "association.provisional_gate_probability",
            self.provisional_gate_probability,
        )?;
        if let Some(p) = self.known_id_gate_probability {
            probability("association.known_id_gate_probability", p)?;
        }
        for (name, v) in [
            ("association.min_sightings", self.min_sightings),
            ("association.provisional_max_age", self.provisional_max_age),
            ("association.jcbb_max_nodes", self.jcbb_max_nodes),
        ] {
            bad(name, v as f64, v >= 1, "at least 1")?;
        }
        Ok(())
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
    min_range: f64,
    gate: f64,
    new_landmark_gate: f64,
    known_gate: Option<f64>,
    provisional_gate: f64,
    joint: GateTable,
    provisional: ProvisionalList,
}

impl Associator {
    /// Thresholds from validated `options`; observations with a range below `min_range`
    /// (m, ≥ 0) are rejected (the bearing of a landmark on the robot is undefined), as are
    /// negative ranges.
    pub fn new(options: AssociationOptions, min_range: f64) -> Self {
        Self {
            min_range,
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
            if z.range < 0.0 || z.range < self.min_range {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A configuration holding the table as EKF-SLAM's and the graph's do.
    #[derive(Debug, Default, Deserialize)]
    #[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
    struct Holder {
        #[serde(deserialize_with = "options_or_mode")]
        association: AssociationOptions,
        max_landmarks: usize,
    }

    #[test]
    fn the_table_and_the_old_mode_string_both_read() {
        let h: Holder =
            toml::from_str("[association]\nmode = \"jcbb\"\njcbb-max-nodes = 7\n").unwrap();
        assert_eq!(h.association.mode, AssociationMode::Jcbb);
        assert_eq!(h.association.jcbb_max_nodes, 7);
        assert_eq!(h.association.min_sightings, 4);
        let h: Holder = toml::from_str("association = \"known-ids\"\n").unwrap();
        assert_eq!(
            h.association,
            AssociationOptions {
                mode: AssociationMode::KnownIds,
                ..AssociationOptions::default()
            }
        );
        assert!(toml::from_str::<Holder>("association = \"telepathy\"\n").is_err());
        assert!(toml::from_str::<Holder>("[association]\nno-such-key = 1\n").is_err());
    }

    /// An old flat key is never silently ignored: the configuration refuses it and the hint
    /// names the table to move it to.
    #[test]
    fn an_old_flat_key_is_refused_with_a_hint_naming_the_table() {
        let e = toml::from_str::<Holder>("gate-probability = 0.99\n").unwrap_err();
        let hint = moved_key_hint(e.message()).unwrap_or_else(|| panic!("{}", e.message()));
        assert!(
            hint.contains("[association]") && hint.contains("gate-probability"),
            "{hint}"
        );
        let e = toml::from_str::<Holder>("min_sightings = 2\n").unwrap_err();
        assert!(moved_key_hint(e.message())
            .unwrap()
            .contains("`min-sightings = …`"));
        let e = toml::from_str::<Holder>("max-landmark = 2\n").unwrap_err();
        assert_eq!(moved_key_hint(e.message()), None);
    }

    #[test]
    fn keys_name_every_field() {
        let text = toml::to_string(&AssociationOptions::default()).unwrap();
        let written: Vec<&str> = text.lines().filter_map(|l| l.split(" =").next()).collect();
        assert_eq!(written, ASSOCIATION_KEYS);
    }
}
