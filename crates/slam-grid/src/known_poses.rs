//! Mapping with known poses (Probabilistic Robotics §9.2, table 9.1): every scan written
//! into one occupancy grid at the pose the log gives, nothing estimated. The first half of
//! the mapping-then-localization workflow, for logs whose poses are already right (a
//! corrected log, a motion-capture run written as a log).

use crate::error::{ensure_config, GridError};
use crate::grid::OccupancyGrid;
use crate::InverseSensorModel;
use serde::{Deserialize, Serialize};
use slam_models::{FilterError, GridMap, Pose2, ScanRecord, ScanSlam, ScanUpdateInfo, TimedPose};

/// Finest cell of a known-poses map, metres: the finest resolution a map_server YAML is
/// read back at (`slam localize`; slam-io's `bounds::RESOLUTION_RANGE`). A finer cell
/// (`resolution = 1e-300`) ended the run on a cell-index error naming no key.
pub const MIN_RESOLUTION: f64 = 1e-4;
/// Coarsest cell of a known-poses map, metres, as the laser graph's `resolution`: one cell
/// per ten metres is no longer a map of a building (`resolution = 1e300` ended the run on
/// an error about its picture, naming no key).
pub const MAX_RESOLUTION: f64 = 10.0;

/// The configuration of [`KnownPoseMapping`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct KnownPoseConfig {
    /// Map cell size, metres, in [[`MIN_RESOLUTION`], [`MAX_RESOLUTION`]]. Default 0.05 m.
    pub resolution: f64,
    /// Inverse sensor model of the map updates. Default: [`InverseSensorModel::default`]
    /// with `protect_scan_hits` on (as grid FastSLAM maps: grazing beams do not erase the
    /// walls their neighbours end on).
    pub sensor_model: InverseSensorModel,
}

impl Default for KnownPoseConfig {
    fn default() -> Self {
        Self {
            resolution: 0.05,
            sensor_model: InverseSensorModel {
                protect_scan_hits: true,
                ..InverseSensorModel::default()
            },
        }
    }
}

/// Mapping with known poses (`ScanSlam`, name `"known-poses"`): a record's pose is
/// `initial_pose ⊕ odometry`, trusted as it is, and each scan is integrated there.
///
/// ```
/// use slam_grid::{KnownPoseConfig, KnownPoseMapping};
/// use slam_models::{LaserScan, Pose2, ScanRecord, ScanSlam};
/// let mut f = KnownPoseMapping::new(KnownPoseConfig::default(), Pose2::IDENTITY, 0)?;
/// let scan = LaserScan { angle_min: -0.1, angle_increment: 0.01, ranges: vec![2.0; 21],
///                        max_range: 30.0, sensor_pose: Pose2::IDENTITY };
/// let rec = ScanRecord { t: 0.0, odometry: Pose2::new(1.0, 0.0, 0.0), scan: Some(scan) };
/// f.process(&rec)?;
/// assert_eq!(f.pose(), Pose2::new(1.0, 0.0, 0.0));
/// let m = f.map();
/// let (ix, iy) = m.cell_of(&slam_models::Point2::new(3.01, 0.0)).unwrap();
/// assert!(m.get(ix, iy).unwrap() > 50);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone)]
pub struct KnownPoseMapping {
    grid: OccupancyGrid,
    initial: Pose2,
    trajectory: Vec<TimedPose>,
}

impl KnownPoseMapping {
    /// A mapper placing the odometry frame at `initial_pose`; the seed is unused (nothing
    /// is random). Errors: an invalid resolution or sensor model, a non-finite pose.
    pub fn new(
        config: KnownPoseConfig,
        initial_pose: Pose2,
        _seed: u64,
    ) -> Result<Self, GridError> {
        ensure_config(
            (MIN_RESOLUTION..=MAX_RESOLUTION).contains(&config.resolution),
            "resolution",
            config.resolution,
            "in [1e-4, 10] m (the finest map a map.yaml is read back at; the laser graph's coarsest)",
        )?;
        if !initial_pose.is_finite() {
            return Err(GridError::NonFinite {
                what: "initial pose",
                value: f64::NAN,
            });
        }
        Ok(Self {
            grid: OccupancyGrid::try_new(config.resolution, config.sensor_model)?,
            initial: initial_pose,
            trajectory: Vec::new(),
        })
    }

    /// The grid built so far.
    pub fn grid(&self) -> &OccupancyGrid {
        &self.grid
    }

    fn step(&mut self, record: &ScanRecord) -> Result<ScanUpdateInfo, GridError> {
        let pose = self.initial.compose(&record.odometry);
        if !pose.is_finite() || !record.t.is_finite() {
            return Err(GridError::NonFinite {
                what: "record pose or time",
                value: f64::NAN,
            });
        }
        let mut info = ScanUpdateInfo::default();
        if let Some(scan) = &record.scan {
            self.grid.try_integrate_scan(&pose, scan)?;
            info.processed_scan = true;
        }
        self.trajectory.push(TimedPose { t: record.t, pose });
        Ok(info)
    }
}

slam_models::from_config_by_new!(KnownPoseMapping, KnownPoseConfig, GridError);

impl ScanSlam for KnownPoseMapping {
    fn name(&self) -> &str {
        "known-poses"
    }

    /// Errors keep their type: `FilterError::downcast_ref::<GridError>()` gives them back.
    fn process(&mut self, record: &ScanRecord) -> Result<ScanUpdateInfo, FilterError> {
        self.step(record).map_err(FilterError::from)
    }

    fn pose(&self) -> Pose2 {
        self.trajectory.last().map_or(self.initial, |p| p.pose)
    }

    fn trajectory(&self) -> Vec<TimedPose> {
        self.trajectory.clone()
    }

    fn map(&self) -> GridMap {
        self.grid.to_grid_map()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::SegmentWorld;

    fn distance_to_walls(world: &SegmentWorld, p: &slam_models::Point2) -> f64 {
        world
            .segments
            .iter()
            .map(|(a, b)| {
                let (ab, ap) = (b - a, p - a);
                let t = (ab.dot(&ap) / ab.norm_squared()).clamp(0.0, 1.0);
                (ap - t * ab).norm()
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// A cell size outside [1e-4, 10] m is refused naming `resolution` (1e-300 and 1e300
    /// were taken and the run ended on errors about cell indices or its picture).
    #[test]
    fn resolution_outside_its_range_is_refused() {
        for resolution in [1e-300, 5e-5, 10.5, 1e300, f64::NAN, 0.0] {
            let config = KnownPoseConfig {
                resolution,
                ..KnownPoseConfig::default()
            };
            match KnownPoseMapping::new(config, Pose2::IDENTITY, 0) {
                Err(GridError::InvalidConfig(e)) => assert_eq!(e.field, "resolution"),
                other => panic!("{resolution}: {:?}", other.err()),
            }
        }
        for resolution in [MIN_RESOLUTION, 0.05, MAX_RESOLUTION] {
            let config = KnownPoseConfig {
                resolution,
                ..KnownPoseConfig::default()
            };
            KnownPoseMapping::new(config, Pose2::IDENTITY, 0).unwrap();
        }
    }

    /// Scans simulated from true poses in the synthetic office, given as the odometry:
    /// the map's walls are where the world's segments are (within a cell).
    #[test]
    fn walls_land_where_the_world_has_them() {
        let world = SegmentWorld::office();
        let mut f = KnownPoseMapping::new(KnownPoseConfig::default(), Pose2::IDENTITY, 0).unwrap();
        for k in 0..60 {
            let truth = Pose2::new(1.5 + 0.15 * k as f64, 3.0, 0.02 * k as f64);
            let scan = world.scan(&truth, 361, std::f64::consts::PI, 20.0);
            let rec = ScanRecord {
                t: k as f64,
                odometry: truth,
                scan: Some(scan),
            };
            assert!(f.process(&rec).unwrap().processed_scan);
        }
        assert_eq!(f.trajectory().len(), 60);
        // Every obstacle cell lies within 1.5 cells of a segment.
        let g = f.grid();
        let (lo, hi) = g.known_bounds().unwrap();
        let mut obstacles = 0;
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                let c = crate::CellIndex::new(x, y);
                if g.is_obstacle(c) {
                    obstacles += 1;
                    let d = distance_to_walls(&world, &g.cell_center(c));
                    assert!(d < 0.075, "obstacle cell {c:?} is {d} m from every wall");
                }
            }
        }
        assert!(obstacles > 200, "{obstacles}");
        let bad = ScanRecord {
            t: 0.0,
            odometry: Pose2::new(f64::NAN, 0.0, 0.0),
            scan: None,
        };
        assert!(f.process(&bad).is_err());
    }
}
