//! The inverse sensor model of a range beam (Probabilistic Robotics, table 9.2).

use crate::error::{ensure_config, GridError};
use serde::{Deserialize, Serialize};

/// Log-odds increments applied along a beam, and their clamping (PR §9.2, eq. 9.7).
///
/// Along each beam the cells strictly between the sensor and the end point receive
/// `l_free`, the end-point cell receives `l_occ` (hits only); the prior log-odds l₀ is 0
/// (p = ½), so the update is l ← clamp(l + l_inv, `l_min`, `l_max`). Clamping keeps the map
/// able to change its mind (a door opens) and bounds the floating-point range.
///
/// Beam cases:
/// * a hit at range r ≤ `max_range`: free up to r − `hit_margin`, occupied at the hit;
/// * a hit beyond `max_range`: free up to `max_range`, nothing occupied (GMapping's
///   `maxUrange`: far end points are too unreliable to mark); with `far_hits_clear` off,
///   a hit at or beyond `max_range` counts as a no return instead;
/// * no return (r ≥ the scan's `max_range`): free up to `no_return_range` (0 disables).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct InverseSensorModel {
    /// Log-odds added to the end-point cell of a hit. Default 0.85 (p ≈ 0.70).
    pub l_occ: f32,
    /// Log-odds added to each cell a beam passes through. Default −0.4 (p ≈ 0.40).
    pub l_free: f32,
    /// Lower clamp. Default −2.0 (p ≈ 0.12).
    pub l_min: f32,
    /// Upper clamp. Default 3.5 (p ≈ 0.97).
    pub l_max: f32,
    /// Usable range, metres: hits beyond it only clear space up to it. Default 30 m.
    pub max_range: f64,
    /// How far a "no return" beam clears space, metres (0: not at all). Default 5 m.
    pub no_return_range: f64,
    /// Readings below this are ignored (the robot's own body, dust), metres. Default 0.05 m.
    pub min_range: f64,
    /// A hit clears space only up to this distance before its end point, metres (the
    /// cells in between are left alone). Without it, beams that end just behind a wall
    /// (range noise) erase the wall's front cells while its back cells are never crossed,
    /// so the mapped surface drifts behind the true one. Default 0.05 m (≈ 5σ of a SICK
    /// LMS range error).
    pub hit_margin: f64,
    /// Treat the cells the beams of one scan end in as that scan's evidence of an
    /// obstacle: each gets `l_occ` once per scan however many beams end in it, and the
    /// other beams of the same scan do not clear it. On a grid, the beams that see a wall
    /// at a grazing angle cross the cells where their neighbours end on it; without this
    /// they erase it. Off (every crossing and every end point counts) by default; grid
    /// FastSLAM (slam-gridfast) turns it on.
    pub protect_scan_hits: bool,
    /// Whether a hit beyond `max_range` clears space up to `max_range` (true, GMapping's
    /// `maxUrange`) or counts as a no return (false: readings at or beyond `max_range`,
    /// the limit itself included as for the scan's own no-return value, neither mark nor
    /// clear anything beyond what `no_return_range` allows). Default true; grid FastSLAM
    /// turns it off (clearing up to 50 m made acapulco's maps grow to 290 MB for 30
    /// particles and its ATE worse).
    pub far_hits_clear: bool,
}

impl Default for InverseSensorModel {
    fn default() -> Self {
        Self {
            l_occ: 0.85,
            l_free: -0.4,
            l_min: -2.0,
            l_max: 3.5,
            max_range: 30.0,
            no_return_range: 5.0,
            min_range: 0.05,
            hit_margin: 0.05,
            protect_scan_hits: false,
            far_hits_clear: true,
        }
    }
}

impl InverseSensorModel {
    /// Checks signs and finiteness: `l_occ > 0`, `l_free < 0`, `l_min < 0 < l_max`, ranges ≥ 0.
    pub fn validate(&self) -> Result<(), GridError> {
        ensure_config(self.l_occ > 0.0, "l_occ", self.l_occ as f64, "> 0")?;
        ensure_config(self.l_free < 0.0, "l_free", self.l_free as f64, "< 0")?;
        ensure_config(self.l_min < 0.0, "l_min", self.l_min as f64, "< 0")?;
        ensure_config(self.l_max > 0.0, "l_max", self.l_max as f64, "> 0")?;
        ensure_config(self.max_range > 0.0, "max_range", self.max_range, "> 0 m")?;
        ensure_config(
            self.no_return_range >= 0.0,
            "no_return_range",
            self.no_return_range,
            ">= 0 m",
        )?;
        ensure_config(self.min_range >= 0.0, "min_range", self.min_range, ">= 0 m")?;
        // Jointly: a reading is used only between the two, so min_range ≥ max_range leaves
        // no reading to map (the run ended on an error about its empty map.pgm, a file of
        // the output's staging folder, naming no key).
        ensure_config(
            self.min_range < self.max_range,
            "min_range",
            self.min_range,
            "below max_range (no reading lies between them otherwise)",
        )?;
        ensure_config(
            self.hit_margin >= 0.0,
            "hit_margin",
            self.hit_margin,
            ">= 0 m",
        )?;
        Ok(())
    }
}
