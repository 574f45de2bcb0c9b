//! The known map MCL localizes on: the saved occupancy map as a slam-grid grid (for ray
//! casting), its likelihood field (slam-grid's exact distance transform), and the list of
//! free cells that global and random particles are drawn from.

use crate::config::MclConfig;
use crate::error::MclError;
use rand::Rng;
use slam_grid::{CellIndex, InverseSensorModel, LikelihoodField, LikelihoodParams, OccupancyGrid};
use slam_models::{GridMap, Pose2};

/// A map ready for localization. Build once per map with [`MclMap::new`]; it is read-only
/// afterwards and can be shared between filters.
#[derive(Debug, Clone)]
pub struct MclMap {
    map: GridMap,
    grid: OccupancyGrid,
    field: LikelihoodField,
    params: LikelihoodParams,
    /// Indices into `map.cells` of the free cells.
    free: Vec<u32>,
}

impl MclMap {
    /// Prepares `map` (ROS convention, see [`GridMap`]) with the measurement parameters of
    /// `config`: cells above 50 % are obstacles; the likelihood field uses σ = `sigma_hit`,
    /// exact up to `max_distance`; cells at most `free_max` percent are free space.
    ///
    /// Errors: an invalid configuration or map ([`MclError::Map`]), more than 2³² cells,
    /// or no free cell ([`MclError::NoFreeSpace`]).
    pub fn new(map: GridMap, config: &MclConfig) -> Result<Self, MclError> {
        config.validate()?;
        let s = &config.sensor;
        let params = LikelihoodParams {
            sigma: s.sigma_hit,
            max_distance: s.max_distance,
            z_hit: s.z_hit,
            z_rand: s.z_rand,
            z_max: s.max_range,
            subcell: false,
            ..LikelihoodParams::default()
        };
        let grid = OccupancyGrid::from_grid_map(&map, InverseSensorModel::default(), params)?;
        let max = CellIndex::new(map.width as i32 - 1, map.height as i32 - 1);
        let field = LikelihoodField::from_grid(&grid, CellIndex::new(0, 0), max);
        if map.cells.len() > u32::MAX as usize {
            return Err(MclError::Map(slam_grid::GridError::MapTooLarge {
                width: map.width as u64,
                height: map.height as u64,
                resolution: map.resolution,
            }));
        }
        let free: Vec<u32> = map
            .cells
            .iter()
            .enumerate()
            .filter(|(_, &v)| (0..=config.free_max).contains(&v))
            .map(|(i, _)| i as u32)
            .collect();
        if free.is_empty() {
            return Err(MclError::NoFreeSpace {
                free_max: config.free_max,
            });
        }
        Ok(Self {
            map,
            grid,
            field,
            params,
            free,
        })
    }

    /// The map as loaded.
    pub fn grid_map(&self) -> &GridMap {
        &self.map
    }

    /// The occupancy grid (obstacles: p > ½), for ray casting.
    pub fn grid(&self) -> &OccupancyGrid {
        &self.grid
    }

    /// The likelihood field over the map (far value outside it).
    pub fn field(&self) -> &LikelihoodField {
        &self.field
    }

    /// The endpoint model's parameters (σ, z_hit, z_rand, z_max, reach).
    pub fn likelihood_params(&self) -> &LikelihoodParams {
        &self.params
    }

    /// Number of free cells.
    pub fn free_cells(&self) -> usize {
        self.free.len()
    }

    /// True when world point (x, y) lies in a free cell.
    pub fn is_free(&self, x: f64, y: f64, free_max: i8) -> bool {
        self.map
            .cell_of(&slam_models::Point2::new(x, y))
            .and_then(|(ix, iy)| self.map.get(ix, iy))
            .is_some_and(|v| (0..=free_max).contains(&v))
    }

    /// A pose drawn uniformly from the free space: a free cell uniformly, a point uniformly
    /// in it, a heading uniformly in [−π, π).
    pub fn sample_free<R: Rng + ?Sized>(&self, rng: &mut R) -> Pose2 {
        let i = self.free[rng.random_range(0..self.free.len())] as usize;
        let (ix, iy) = (i % self.map.width, i / self.map.width);
        let r = self.map.resolution;
        let x = self.map.origin.x + (ix as f64 + rng.random::<f64>()) * r;
        let y = self.map.origin.y + (iy as f64 + rng.random::<f64>()) * r;
        let theta = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        Pose2::new(x, y, theta)
    }
}
