//! Parameters of the likelihood field (Thrun's endpoint model).

use crate::error::{ensure_config, GridError};
use serde::{Deserialize, Serialize};

/// The likelihood-field ("endpoint") measurement model, Probabilistic Robotics §6.4,
/// table 6.3: an end point at distance d from the nearest obstacle has likelihood
///
/// ```text
/// p(z | x, m) = z_hit · N(d; 0, σ²) + z_rand / z_max
/// ```
///
/// The field stores the unnormalised Gaussian part s = exp(−d²/(2σ²)) ∈ (0, 1] per cell, with
/// d clamped to `max_distance` (so the field is exact within `max_distance` and constant
/// beyond). A cell is an obstacle when its log-odds exceed `occupied_threshold`; d is
/// measured to the obstacle cell's mean hit position when `subcell` is on.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct LikelihoodParams {
    /// σ of the end-point Gaussian, metres. Default 0.05 m (one 5 cm cell).
    pub sigma: f64,
    /// Distances are computed exactly up to this, metres; beyond it s is constant.
    /// Default 0.3 m (6σ).
    pub max_distance: f64,
    /// Cells with log-odds above this are obstacles. Default 0.0 (p > ½).
    pub occupied_threshold: f32,
    /// Weight of the Gaussian (hit) component. Default 0.9.
    pub z_hit: f64,
    /// Weight of the uniform (random) component. Default 0.1.
    pub z_rand: f64,
    /// Range over which random readings are spread, metres (z_max in PR). Default 30 m.
    pub z_max: f64,
    /// Measure distances to the mean hit position of the nearest obstacle cell (sub-cell
    /// accuracy, as GMapping's per-cell hit mean) instead of to its centre. Default true.
    pub subcell: bool,
    /// With `subcell`: where the mean hit positions of the obstacle cells around the nearest
    /// one lie on a straight line (total least squares through their hit-count-weighted
    /// means, scatter eigenvalue ratio λ₂/λ₁ ≤ 0.15), measure the distance to that line
    /// (cut to the means' extent) instead of to their mean point. A wall's zero set is then
    /// its fitted line, not circles around a few points: end points between two mapped
    /// cells, or in a cell the wall crosses but that holds no obstacle (a wall along a cell
    /// boundary scatters its hits between the two sides), are not pushed off the wall.
    /// The same idea as point-to-line ICP (Censi, "An ICP variant using a point-to-line
    /// metric", ICRA 2008) with the lines taken from the map's hit means. Default false:
    /// it removes the refinement's bias on clean simulated walls but was no clear gain on
    /// real data (docs/results/defaults.md).
    pub surface_lines: bool,
}

impl Default for LikelihoodParams {
    fn default() -> Self {
        Self {
            sigma: 0.05,
            max_distance: 0.3,
            occupied_threshold: 0.0,
            z_hit: 0.9,
            z_rand: 0.1,
            z_max: 30.0,
            subcell: true,
            surface_lines: false,
        }
    }
}

impl LikelihoodParams {
    /// Checks σ > 0, max_distance > 0, weights ≥ 0 with z_hit > 0, z_max > 0.
    pub fn validate(&self) -> Result<(), GridError> {
        ensure_config(self.sigma > 0.0, "sigma", self.sigma, "> 0 m")?;
        ensure_config(
            self.max_distance > 0.0,
            "max_distance",
            self.max_distance,
            "> 0 m",
        )?;
        ensure_config(
            self.occupied_threshold.is_finite(),
            "occupied_threshold",
            self.occupied_threshold as f64,
            "finite",
        )?;
        ensure_config(self.z_hit > 0.0, "z_hit", self.z_hit, "> 0")?;
        ensure_config(self.z_rand >= 0.0, "z_rand", self.z_rand, ">= 0")?;
        ensure_config(self.z_max > 0.0, "z_max", self.z_max, "> 0 m")?;
        Ok(())
    }

    /// The field value s = exp(−min(d, max_distance)²/(2σ²)) for a distance d in metres.
    #[inline]
    pub fn field_value(&self, d: f64) -> f32 {
        let d = d.min(self.max_distance);
        (-(d * d) / (2.0 * self.sigma * self.sigma)).exp() as f32
    }

    /// The field value far from every obstacle (at `max_distance`).
    #[inline]
    pub fn far_value(&self) -> f32 {
        self.field_value(self.max_distance)
    }

    /// ln p(z | x, m) of one end point from its field value s (PR table 6.3, one factor):
    /// ln(z_hit · s / (√(2π)·σ) + z_rand / z_max).
    #[inline]
    pub fn log_likelihood(&self, s: f32) -> f64 {
        const INV_SQRT_2PI: f64 = 0.398_942_280_401_432_7;
        (self.z_hit * s as f64 * INV_SQRT_2PI / self.sigma + self.z_rand / self.z_max).ln()
    }
}
