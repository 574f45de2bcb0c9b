//! Grids from saved maps, and ray casting on them: what localization on a known map needs
//! (a map_server or `slam run` map loaded back as log-odds; expected ranges for the beam
//! model, Probabilistic Robotics §6.3).

use super::raytrace::Ray;
use super::tiles::split;
use super::OccupancyGrid;
use crate::cell::CellIndex;
use crate::error::{ensure_config, GridError};
use crate::{InverseSensorModel, LikelihoodParams};
use slam_models::{GridMap, Point2};

impl OccupancyGrid {
    /// A grid holding a saved map ([`GridMap`], ROS convention: −1 unknown, else the
    /// occupancy probability p in percent): each known cell gets the log-odds
    /// l = ln(p/(1 − p)) clamped to the model's [`InverseSensorModel::l_min`, `l_max`]
    /// (a trinary map_server map's 0 and 100 land on the clamps), unknown cells stay 0.
    /// The grid has the map's resolution and origin, so cell (ix, iy) of the map is cell
    /// (ix, iy) of the grid, and `params` decide which cells are obstacles (log-odds above
    /// `occupied_threshold`, 0 by default: p > ½). Saved maps keep no hit positions, so
    /// `params.subcell` is turned off (distances are measured to cell centres).
    ///
    /// Errors: a resolution that is not positive and finite, a non-finite origin, a cell
    /// vector whose length is not `width·height`, or a map beyond [`super::MAX_MAP_CELLS`].
    pub fn from_grid_map(
        map: &GridMap,
        model: InverseSensorModel,
        params: LikelihoodParams,
    ) -> Result<Self, GridError> {
        ensure_config(
            map.resolution > 0.0 && map.resolution.is_finite(),
            "map resolution",
            map.resolution,
            "> 0 m and finite",
        )?;
        ensure_config(
            map.cells.len() == map.width * map.height,
            "map cell count",
            map.cells.len() as f64,
            "width × height",
        )?;
        let params = LikelihoodParams {
            subcell: false,
            ..params
        };
        let mut grid = Self::try_new(map.resolution, model)?
            .with_origin(map.origin)?
            .with_likelihood(params)?;
        if map.width == 0 || map.height == 0 {
            return Ok(grid);
        }
        let max = CellIndex::new(map.width as i32 - 1, map.height as i32 - 1);
        grid.ensure_covers(CellIndex::new(0, 0), max)?;
        let (lmin, lmax) = (model.l_min, model.l_max);
        for iy in 0..map.height {
            for ix in 0..map.width {
                let v = map.cells[iy * map.width + ix];
                if v < 0 {
                    continue;
                }
                let p = (v as f64 / 100.0).clamp(1e-6, 1.0 - 1e-6);
                let l = ((p / (1.0 - p)).ln() as f32).clamp(lmin, lmax);
                if l == 0.0 {
                    continue;
                }
                let ((tx, ty), local) = split(CellIndex::new(ix as i32, iy as i32));
                let slot = grid.slot_for_write(tx, ty);
                grid.tile_for_write(slot).set(local, l, lmin);
            }
        }
        Ok(grid)
    }

    /// The range (metres) at which a beam from world point `origin` in direction `angle`
    /// (radians, world frame) first enters an obstacle cell ([`OccupancyGrid::is_obstacle`]),
    /// measured to where the beam crosses into that cell, or `None` when it meets none within
    /// `max_range`. The cells are walked exactly (Amanatides–Woo, the traversal the scan
    /// integration uses); a beam starting inside an obstacle cell has range 0. This is the
    /// expected range z* of the beam model (Probabilistic Robotics §6.3).
    pub fn cast_ray(&self, origin: &Point2, angle: f64, max_range: f64) -> Option<f64> {
        if !(max_range > 0.0 && max_range.is_finite()) {
            return None;
        }
        let res = self.resolution();
        let (dx, dy) = (angle.cos(), angle.sin());
        let start = self.frame.world_to_continuous(origin);
        let end = (
            start.0 + max_range * dx / res,
            start.1 + max_range * dy / res,
        );
        if !(start.0.is_finite() && start.1.is_finite() && end.0.is_finite() && end.1.is_finite()) {
            return None;
        }
        let mut ray = Ray::new(start, end);
        loop {
            if self.is_obstacle(CellIndex::new(ray.x, ray.y)) {
                // Distance along the beam to the boundary crossed into this cell: the
                // parameter t of the last boundary, t ∈ [0, 1] of the segment.
                return Some((ray.entry_t() * max_range).max(0.0));
            }
            if ray.steps_left() == 0 {
                return None;
            }
            ray.step();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4 m × 2 m room at 0.1 m: free inside, a wall column at x ∈ [3.0, 3.1), a row of
    /// unknown cells at the top.
    fn room() -> GridMap {
        let mut m = GridMap::unknown(0.1, Point2::new(-1.0, -1.0), 40, 20);
        for iy in 0..19 {
            for ix in 0..40 {
                m.cells[iy * 40 + ix] = if ix == 40 - 10 { 100 } else { 0 };
            }
        }
        m
    }

    #[test]
    fn a_loaded_map_keeps_its_cells_and_frame() {
        let m = room();
        let g = OccupancyGrid::from_grid_map(
            &m,
            InverseSensorModel::default(),
            LikelihoodParams::default(),
        )
        .unwrap();
        let wall = g.world_to_cell(&Point2::new(2.05, 0.0));
        assert!(g.is_obstacle(wall));
        assert!(!g.is_obstacle(g.world_to_cell(&Point2::new(1.95, 0.0))));
        // Unknown top row stays unknown (log-odds 0); the export gives the map back with
        // the clamps' probabilities (0.12 and 0.97 for the default model).
        assert_eq!(g.log_odds(g.world_to_cell(&Point2::new(0.0, 0.95))), 0.0);
        let back = g.to_grid_map();
        assert_eq!((back.width, back.height), (40, 19));
        assert!((back.origin.x + 1.0).abs() < 1e-12 && (back.origin.y + 1.0).abs() < 1e-12);
        assert_eq!(back.cells[30], 97);
        assert_eq!(back.cells[0], 12);
        assert!(!g.likelihood_params().subcell);
    }

    #[test]
    fn rays_stop_at_the_wall_face() {
        let g = OccupancyGrid::from_grid_map(
            &room(),
            InverseSensorModel::default(),
            LikelihoodParams::default(),
        )
        .unwrap();
        // The wall's face is x = 2.0 (cell 30 starts at −1 + 3.0).
        let o = Point2::new(0.03, 0.02);
        let r = g.cast_ray(&o, 0.0, 10.0).unwrap();
        assert!((r - 1.97).abs() < 1e-9, "{r}");
        // At 20°: the face is met after 1.97 / cos 20° (at y ≈ 0.74, inside the room).
        let a = 20f64.to_radians();
        let r = g.cast_ray(&o, a, 10.0).unwrap();
        assert!((r - 1.97 / a.cos()).abs() < 1e-9, "{r}");
        // Backwards: nothing within range (the map has no wall at the left).
        assert_eq!(g.cast_ray(&o, std::f64::consts::PI, 10.0), None);
        // Too short to reach the wall.
        assert_eq!(g.cast_ray(&o, 0.0, 1.5), None);
        // Starting in the wall.
        assert_eq!(g.cast_ray(&Point2::new(2.05, 0.0), 1.0, 3.0), Some(0.0));
        assert_eq!(g.cast_ray(&o, 0.0, f64::NAN), None);
    }

    #[test]
    fn bad_maps_are_refused() {
        let mut m = room();
        m.cells.pop();
        let e = OccupancyGrid::from_grid_map(
            &m,
            InverseSensorModel::default(),
            LikelihoodParams::default(),
        );
        assert!(e.is_err());
        let mut m = room();
        m.resolution = 0.0;
        assert!(OccupancyGrid::from_grid_map(
            &m,
            InverseSensorModel::default(),
            LikelihoodParams::default()
        )
        .is_err());
    }
}
