//! The presets of [`super::GridFastConfig`]: the environment the scale-dependent values are
//! chosen for, their values, and the rule by which [`Preset::Auto`] picks one from the data.

use serde::{Deserialize, Serialize};
use slam_models::LaserScan;

/// The environment the scale-dependent values are chosen for (cell size, the endpoint
/// model's lengths, search windows). See `docs/gridfast.md`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Preset {
    /// Chosen from the first processed scan: [`Preset::Outdoor`] when the median range of
    /// its returns is at least [`AUTO_OUTDOOR_MEDIAN_RANGE`], else [`Preset::Indoor`].
    #[default]
    Auto,
    /// Offices and corridors, ranges of a few metres: 5 cm cells (GMapping's `delta`) and
    /// the values tuned on `bench/intel.log` and the simulated office.
    Indoor,
    /// Open ground, returns tens of metres away and metres apart: 20 cm cells (the
    /// grid-FastSLAM lecture's campus run) and every length of the endpoint model and the
    /// searches scaled with the cell (×4); finer rotation steps, since a heading error
    /// moves an end point 25 m away five times as far as one 5 m away.
    Outdoor,
}

/// [`Preset::Auto`] picks [`Preset::Outdoor`] when the median range of the first processed
/// scan's returns is at least this, metres. The bench logs' scans have medians of 1.8–6.6 m
/// (first 50 scans of each), the simulated campus's 10–25 m.
pub const AUTO_OUTDOOR_MEDIAN_RANGE: f64 = 10.0;

/// The preset-dependent values. Every field is the default of the `Option` of the same
/// name in the configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct PresetValues {
    pub(super) resolution: f64,
    pub(super) sigma: f64,
    pub(super) field_radius: f64,
    pub(super) likelihood_radius: f64,
    pub(super) linear_step: f64,
    pub(super) search_range_xy: f64,
    pub(super) search_step_xy: f64,
    pub(super) search_range_theta: f64,
    pub(super) search_step_theta: f64,
    pub(super) sample_range_xy: f64,
    pub(super) recovery_range_xy: f64,
    pub(super) recovery_range_theta: f64,
    pub(super) recovery_step_xy: f64,
    pub(super) recovery_step_theta: f64,
    pub(super) recovery_turn_range_xy: f64,
}

impl Preset {
    /// The preset's values (for [`Preset::Auto`], the indoor ones).
    pub(super) fn values(self) -> PresetValues {
        match self {
            Preset::Auto | Preset::Indoor => PresetValues {
                resolution: 0.05,
                sigma: 0.05,
                field_radius: 0.2,
                likelihood_radius: 0.15,
                linear_step: 0.1,
                search_range_xy: 0.3,
                search_step_xy: 0.05,
                search_range_theta: 0.9,
                search_step_theta: 0.025,
                sample_range_xy: 0.01,
                recovery_range_xy: 1.5,
                recovery_range_theta: 0.9,
                recovery_step_xy: 0.1,
                recovery_step_theta: 0.02,
                recovery_turn_range_xy: 0.3,
            },
            Preset::Outdoor => PresetValues {
                resolution: 0.2,
                sigma: 0.2,
                field_radius: 0.8,
                likelihood_radius: 0.6,
                linear_step: 0.4,
                search_range_xy: 1.2,
                search_step_xy: 0.2,
                search_range_theta: 0.3,
                search_step_theta: 0.01,
                sample_range_xy: 0.04,
                recovery_range_xy: 3.0,
                recovery_range_theta: 0.4,
                recovery_step_xy: 0.4,
                recovery_step_theta: 0.01,
                recovery_turn_range_xy: 1.2,
            },
        }
    }

    /// The preset [`Preset::Auto`] stands for on `scan` (returns below `max_range`);
    /// an explicit preset is returned as it is. A scan without returns counts as indoor.
    pub fn choose(self, scan: &LaserScan, max_range: f64) -> Preset {
        if self != Preset::Auto {
            return self;
        }
        match median_return_range(scan, max_range) {
            Some(m) if m >= AUTO_OUTDOOR_MEDIAN_RANGE => Preset::Outdoor,
            _ => Preset::Indoor,
        }
    }
}

/// The median range of the returns of `scan` (0 < r < min(`max_range`, the scan's own
/// no-return value)), or `None` without any.
pub fn median_return_range(scan: &LaserScan, max_range: f64) -> Option<f64> {
    let limit = max_range.min(scan.max_range);
    let mut r: Vec<f64> = scan
        .ranges
        .iter()
        .copied()
        .filter(|&r| r > 0.0 && r < limit)
        .collect();
    if r.is_empty() {
        return None;
    }
    r.sort_by(f64::total_cmp);
    Some(r[r.len() / 2])
}
