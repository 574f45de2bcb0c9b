//! The filters the program knows, and building one by name behind `Box<dyn LandmarkSlam>` or
//! `Box<dyn ScanSlam>`.
//!
//! Each filter's configuration comes from its crate's config struct: the `Default` (documented
//! there), then the `--config` TOML file over it, then `--particles` over that. For simulated
//! runs the filter's motion and sensor noise default to the models the data was generated
//! with, unless the file sets `motion` or `sensor` itself.

use crate::config;
use crate::error::CliError;
use slam_models::measurement::RangeBearingModel;
use slam_models::motion::MotionModels;
use slam_models::{LandmarkSlam, Pose2, ScanSlam};
use std::path::Path;

/// The two kinds of data (and of filters).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DataKind {
    /// Range-bearing observations of point landmarks.
    Landmark,
    /// Odometry and laser scans.
    Laser,
}

impl DataKind {
    /// `"landmark"` or `"laser"`.
    pub fn as_str(self) -> &'static str {
        match self {
            DataKind::Landmark => "landmark",
            DataKind::Laser => "laser",
        }
    }
}

/// A filter the program knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FilterInfo {
    /// The `--filter` name.
    pub name: &'static str,
    /// The data it runs on.
    pub kind: DataKind,
    /// One line: what it is.
    pub description: &'static str,
    /// True for particle filters (`--particles` applies).
    pub particle_filter: bool,
    /// `None` when built into this program; otherwise why not.
    pub unavailable: Option<&'static str>,
}

/// Every filter, in a fixed order.
pub fn filters() -> Vec<FilterInfo> {
    vec![
        FilterInfo {
            name: "ekf",
            kind: DataKind::Landmark,
            description:
                "EKF-SLAM (PR ch. 10), dense covariance, known or unknown data association",
            particle_filter: false,
            unavailable: None,
        },
        FilterInfo {
            name: "fastslam1",
            kind: DataKind::Landmark,
            description:
                "FastSLAM 1.0 (Montemerlo et al. 2002, PR ch. 13), a landmark EKF per particle",
            particle_filter: true,
            unavailable: None,
        },
        FilterInfo {
            name: "fastslam2",
            kind: DataKind::Landmark,
            description:
                "FastSLAM 2.0 (Montemerlo et al. 2003), proposal using the current observations",
            particle_filter: true,
            unavailable: None,
        },
        FilterInfo {
            name: "graph",
            kind: DataKind::Landmark,
            description:
                "graph-based full SLAM (pose graph + LM), range-bearing edges, the EKF's data association",
            particle_filter: false,
            unavailable: None,
        },
        FilterInfo {
            name: "scanmatch",
            kind: DataKind::Laser,
            description: "scan-matching odometry against an occupancy grid (no loop closure)",
            particle_filter: false,
            unavailable: None,
        },
        FilterInfo {
            name: "gridfast",
            kind: DataKind::Laser,
            description: "grid-based FastSLAM with scan-matched proposals (GMapping family)",
            particle_filter: true,
            unavailable: None,
        },
    ]
}

/// The filter called `name`, whether or not it is available.
pub fn find(name: &str) -> Result<FilterInfo, CliError> {
    let all = filters();
    all.iter()
        .find(|f| f.name == name)
        .copied()
        .ok_or_else(|| CliError::UnknownFilter {
            name: name.to_string(),
            known: all.iter().map(|f| f.name).collect::<Vec<_>>().join(", "),
        })
}

/// The filter called `name` for data of `kind`: one name may serve both kinds of data
/// (`graph`), and the data picks which.
pub fn find_for(name: &str, kind: DataKind) -> Option<FilterInfo> {
    filters()
        .into_iter()
        .find(|f| f.name == name && f.kind == kind)
}

/// True when filters of both kinds go by `name`: what the data is decides which one runs,
/// so the kind-specific checks wait until the data is loaded.
pub(crate) fn serves_both_kinds(name: &str) -> bool {
    find_for(name, DataKind::Landmark).is_some() && find_for(name, DataKind::Laser).is_some()
}

/// Names of the filters of one kind, comma separated.
pub(crate) fn names_of(kind: DataKind) -> String {
    filters()
        .iter()
        .filter(|f| f.kind == kind)
        .map(|f| f.name)
        .collect::<Vec<_>>()
        .join(", ")
}

/// Everything a filter needs besides its name.
pub(crate) struct Setup<'a> {
    /// `--config`.
    pub config_path: Option<&'a Path>,
    /// `--particles`.
    pub particles: Option<usize>,
    /// Seed of the filter's random numbers.
    pub seed: u64,
    /// The robot's initial pose (landmark data).
    pub initial_pose: Pose2,
    /// The noise models simulated data was generated with.
    pub sim_models: Option<(MotionModels, RangeBearingModel)>,
}

/// A built filter and the configuration it runs with (as TOML, written beside the output).
pub(crate) struct Built<F: ?Sized> {
    /// The filter.
    pub filter: Box<F>,
    /// The effective configuration, TOML.
    pub config_toml: String,
}

fn unavailable(info: &FilterInfo) -> CliError {
    CliError::FilterUnavailable {
        name: info.name.to_string(),
        reason: info.unavailable.unwrap_or("not built in").to_string(),
    }
}

/// `--particles` (`given`) applies to particle filters only; `slam run` asks before it loads
/// the data.
pub(crate) fn check_particles(info: &FilterInfo, given: bool) -> Result<(), CliError> {
    if given && !info.particle_filter {
        return Err(CliError::InvalidArgument(format!(
            "--particles applies to particle filters (fastslam1, fastslam2, gridfast); `{}` has none",
            info.name
        )));
    }
    Ok(())
}

/// The checks every filter build starts with: `--particles` only for particle filters, and
/// the filter must be available in this build.
fn check_buildable(info: &FilterInfo, setup: &Setup<'_>) -> Result<(), CliError> {
    check_particles(info, setup.particles.is_some())?;
    if info.unavailable.is_some() {
        return Err(unavailable(info));
    }
    Ok(())
}

/// A filter's constructor rejected its configuration.
fn config_error(info: &FilterInfo, e: &dyn std::fmt::Display) -> CliError {
    CliError::FilterConfig {
        filter: info.name.to_string(),
        message: e.to_string(),
    }
}

/// On simulated data, a filter uses the simulator's own noise models (its "true" model),
/// except where the config file sets `motion` or `sensor` itself.
fn apply_sim_noise(
    config_keys: &[String],
    setup: &Setup<'_>,
    motion: &mut MotionModels,
    sensor: &mut RangeBearingModel,
) {
    let Some((sim_motion, sim_sensor)) = setup.sim_models else {
        return;
    };
    let has = |k: &str| config_keys.iter().any(|x| x == k);
    if !has("motion") {
        *motion = sim_motion;
    }
    if !has("sensor") {
        *sensor = sim_sensor;
    }
}

/// Builds a landmark filter.
pub(crate) fn build_landmark(
    info: &FilterInfo,
    setup: &Setup<'_>,
) -> Result<Built<dyn LandmarkSlam>, CliError> {
    check_buildable(info, setup)?;
    let invalid = |e: &dyn std::fmt::Display| config_error(info, e);
    match info.name {
        "ekf" => {
            use slam_ekf::{EkfConfig, EkfSlam};
            let mut loaded = config::load::<EkfConfig>(setup.config_path)?;
            let c = &mut loaded.config;
            apply_sim_noise(&loaded.keys, setup, &mut c.motion, &mut c.sensor);
            let config_toml = config::to_toml(&loaded.config);
            let f = EkfSlam::new(loaded.config, setup.initial_pose).map_err(|e| invalid(&e))?;
            Ok(Built {
                filter: Box::new(f),
                config_toml,
            })
        }
        "fastslam1" | "fastslam2" => {
            use slam_fastslam::{FastSlam, FastSlamConfig, Variant};
            let mut loaded = config::load::<FastSlamConfig>(setup.config_path)?;
            let variant = if info.name == "fastslam1" {
                Variant::FastSlam1
            } else {
                Variant::FastSlam2
            };
            if loaded.keys.iter().any(|k| k == "variant") && loaded.config.variant != variant {
                return Err(CliError::InvalidArgument(format!(
                    "the config file sets variant = {:?} but --filter is {}; remove `variant` or pick the other filter",
                    loaded.config.variant, info.name
                )));
            }
            let c = &mut loaded.config;
            c.variant = variant;
            apply_sim_noise(&loaded.keys, setup, &mut c.motion, &mut c.sensor);
            if let Some(n) = setup.particles {
                c.particles = n;
            }
            let config_toml = config::to_toml(&loaded.config);
            let f = FastSlam::new(loaded.config, setup.initial_pose, setup.seed)
                .map_err(|e| invalid(&e))?;
            Ok(Built {
                filter: Box::new(f),
                config_toml,
            })
        }
        "graph" => {
            use slam_graph::landmark::{GraphLandmarkConfig, GraphLandmarkSlam};
            let mut loaded = config::load::<GraphLandmarkConfig>(setup.config_path)?;
            let c = &mut loaded.config;
            apply_sim_noise(&loaded.keys, setup, &mut c.motion, &mut c.sensor);
            let config_toml = config::to_toml(&loaded.config);
            let f = GraphLandmarkSlam::new(loaded.config, setup.initial_pose, setup.seed)
                .map_err(|e| invalid(&e))?;
            Ok(Built {
                filter: Box::new(f),
                config_toml,
            })
        }
        _ => Err(unavailable(info)),
    }
}

/// Builds a laser (scan) filter.
pub(crate) fn build_scan(
    info: &FilterInfo,
    setup: &Setup<'_>,
) -> Result<Built<dyn ScanSlam>, CliError> {
    check_buildable(info, setup)?;
    let invalid = |e: &dyn std::fmt::Display| config_error(info, e);
    match info.name {
        "scanmatch" => {
            use slam_grid::{ScanMatchConfig, ScanMatchOdometry};
            let loaded = config::load::<ScanMatchConfig>(setup.config_path)?;
            let config_toml = config::to_toml(&loaded.config);
            let f = ScanMatchOdometry::new(loaded.config).map_err(|e| invalid(&e))?;
            Ok(Built {
                filter: Box::new(f),
                config_toml,
            })
        }
        "gridfast" => {
            use slam_gridfast::{GridFastConfig, GridFastSlam};
            let mut loaded = config::load::<GridFastConfig>(setup.config_path)?;
            if let Some(n) = setup.particles {
                loaded.config.particles = n;
            }
            let config_toml = config::to_toml(&loaded.config);
            let f = GridFastSlam::new(loaded.config, setup.seed).map_err(|e| invalid(&e))?;
            Ok(Built {
                filter: Box::new(f),
                config_toml,
            })
        }
        _ => Err(unavailable(info)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::de::DeserializeOwned;
    use serde::Serialize;
    use std::collections::BTreeSet;

    /// Every key path of a TOML value (`motion.odometry.alpha`, …).
    fn key_paths(v: &toml::Value, prefix: &str, out: &mut BTreeSet<String>) {
        if let toml::Value::Table(t) = v {
            for (k, v) in t {
                let path = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                key_paths(v, &path, out);
                out.insert(path);
            }
        }
    }

    /// `configs/<name>.toml` sets every key of `C` (those with a value by default) to its
    /// default, so the example files document exactly what a run uses without `--config`.
    fn example_is_complete_and_default<C: DeserializeOwned + Serialize + Default>(
        name: &str,
        patch: impl Fn(&mut C),
    ) {
        // `graph` serves both kinds of data; configs/graph.toml is `slam optimize`'s.
        let name = if name == "graph" {
            "graph-landmark"
        } else {
            name
        };
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../configs/{name}.toml"));
        let text = std::fs::read_to_string(&path).unwrap();
        let raw: toml::Value = toml::from_str(&text).unwrap();
        let mut parsed: C =
            toml::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        patch(&mut parsed);
        let parsed = toml::Value::try_from(&parsed).unwrap();
        let default = toml::Value::try_from(C::default()).unwrap();
        let (mut a, mut b) = (BTreeSet::new(), BTreeSet::new());
        key_paths(&raw, "", &mut a);
        key_paths(&default, "", &mut b);
        assert_eq!(
            a, b,
            "configs/{name}.toml: keys differ from the config struct's"
        );
        assert_eq!(
            parsed, default,
            "configs/{name}.toml: values differ from the defaults"
        );
    }

    #[test]
    fn example_configs_match_the_defaults() {
        for f in filters().iter().filter(|f| f.unavailable.is_none()) {
            match f.name {
                "fastslam1" | "fastslam2" => {
                    example_is_complete_and_default::<slam_fastslam::FastSlamConfig>(f.name, |c| {
                        c.variant = Default::default()
                    })
                }
                "scanmatch" => {
                    example_is_complete_and_default::<slam_grid::ScanMatchConfig>(f.name, |_| ())
                }
                "ekf" => example_is_complete_and_default::<slam_ekf::EkfConfig>(f.name, |_| ()),
                "graph" if f.kind == DataKind::Landmark => example_is_complete_and_default::<
                    slam_graph::landmark::GraphLandmarkConfig,
                >(f.name, |_| ()),
                "gridfast" => {
                    example_is_complete_and_default::<slam_gridfast::GridFastConfig>(f.name, |_| ())
                }
                other => panic!("no example-config check for {other}"),
            }
        }
    }
}
