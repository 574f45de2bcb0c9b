//! Filters built from a configuration: swapping the filter is a config change.
//!
//! A [`FilterConfig`] is tagged by the filter's name and carries that filter's own config
//! struct (with its documented `Default`). As a TOML file, the tag is the `filter` key and
//! the filter's keys sit beside it, exactly as in `configs/<name>.toml`:
//!
//! ```
//! use slam_eval::factory::FilterConfig;
//! let parsed = FilterConfig::from_toml("filter = \"fastslam2\"\nparticles = 50\n")?;
//! assert_eq!(parsed.config.name(), "fastslam2");
//! let filter = parsed.config.build_landmark(Default::default(), 7)?;
//! assert_eq!(filter.name(), "fastslam2");
//! # Ok::<(), slam_eval::factory::FactoryError>(())
//! ```
//!
//! `graph` names a filter of each kind of data: a file that names its filter says which
//! (`filter = "graph-landmark"` or `"graph-laser"`), or the caller gives the kind
//! ([`FilterConfig::from_toml_for_kind`]); a bare `"graph"` is
//! [`FactoryError::AmbiguousKind`] rather than a silent pick.
//!
//! [`filters`] lists every filter with its data kind and a one-line description (what
//! `slam list` prints). The list is open: a filter family added later (pose graphs) gets a
//! variant, a [`FilterInfo`] and a build arm here, and every front end picks it up.

use serde::{Deserialize, Serialize};
use slam_ekf::{EkfConfig, EkfSlam};
use slam_fastslam::{FastSlam, FastSlamConfig, Variant};
use slam_graph::landmark::{GraphLandmarkConfig, GraphLandmarkSlam};
use slam_graph::laser::{LaserGraphConfig, LaserGraphSlam};
use slam_grid::{
    KnownPoseConfig, KnownPoseMapping, LaserOdometryConfig, ScanMatchConfig, ScanMatchOdometry,
};
use slam_gridfast::{GridFastConfig, GridFastSlam};
use slam_models::{BoxedError, LandmarkSlam, Pose2, ScanSlam};
use slam_sim::{NoiseApplied, NoiseModels};
use thiserror::Error;

/// The two kinds of data (and of filters), slam-models' one enum.
pub use slam_models::DataKind;

/// A filter the factory knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FilterInfo {
    /// The filter's name: the config tag, `slam run --filter`.
    pub name: &'static str,
    /// The data it runs on.
    pub kind: DataKind,
    /// One line: what it is.
    pub description: &'static str,
    /// True for particle filters (a particle count applies).
    pub particle_filter: bool,
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
        },
        FilterInfo {
            name: "fastslam1",
            kind: DataKind::Landmark,
            description:
                "FastSLAM 1.0 (Montemerlo et al. 2002, PR ch. 13), a landmark EKF per particle",
            particle_filter: true,
        },
        FilterInfo {
            name: "fastslam2",
            kind: DataKind::Landmark,
            description:
                "FastSLAM 2.0 (Montemerlo et al. 2003), proposal using the current observations",
            particle_filter: true,
        },
        FilterInfo {
            name: "graph",
            kind: DataKind::Landmark,
            description:
                "graph-based full SLAM (pose graph + LM), range-bearing edges, the EKF's data association",
            particle_filter: false,
        },
        FilterInfo {
            name: "scanmatch",
            kind: DataKind::Laser,
            description: "scan-matching odometry against an occupancy grid (no loop closure)",
            particle_filter: false,
        },
        FilterInfo {
            name: "known-poses",
            kind: DataKind::Laser,
            description:
                "mapping with known poses: each scan written at the log's own pose",
            particle_filter: false,
        },
        FilterInfo {
            name: "gridfast",
            kind: DataKind::Laser,
            description: "grid-based FastSLAM with scan-matched proposals (GMapping family)",
            particle_filter: true,
        },
        FilterInfo {
            name: "graph",
            kind: DataKind::Laser,
            description:
                "pose-graph SLAM: submap matching, branch-and-bound loop closures, smoothed odometry",
            particle_filter: false,
        },
    ]
}

/// The filter called `name`, whether or not it is available.
pub fn find(name: &str) -> Result<FilterInfo, FactoryError> {
    filters()
        .into_iter()
        .find(|f| f.name == name)
        .ok_or_else(|| FactoryError::UnknownFilter {
            name: name.to_string(),
            known: known_names(),
        })
}

/// The filter called `name` for data of `kind`: one name may serve both kinds of data
/// (`graph`), and the data picks which.
pub fn find_for(name: &str, kind: DataKind) -> Option<FilterInfo> {
    filters()
        .into_iter()
        .find(|f| f.name == name && f.kind == kind)
}

/// True when filters of both kinds go by `name` (`graph`): the data decides which runs.
pub fn serves_both_kinds(name: &str) -> bool {
    find_for(name, DataKind::Landmark).is_some() && find_for(name, DataKind::Laser).is_some()
}

/// Names of the filters of one kind, comma separated.
pub fn names_of(kind: DataKind) -> String {
    filters()
        .iter()
        .filter(|f| f.kind == kind)
        .map(|f| f.name)
        .collect::<Vec<_>>()
        .join(", ")
}

fn known_names() -> String {
    filters()
        .iter()
        .map(|f| f.name)
        .collect::<Vec<_>>()
        .join(", ")
}

/// Why a filter could not be configured or built.
#[derive(Debug, Error)]
pub enum FactoryError {
    /// No filter has this name.
    #[error("unknown filter `{name}` (known: {known})")]
    UnknownFilter {
        /// The name asked for.
        name: String,
        /// The known names, comma separated.
        known: String,
    },
    /// The configuration text is not valid: TOML syntax, a missing `filter` tag, an unknown
    /// key, a value of the wrong type.
    #[error("{}{message}", line.map(|l| format!("line {l}: ")).unwrap_or_default())]
    Parse {
        /// 1-based line of the offending text, when known.
        line: Option<usize>,
        /// What was wrong, naming the key.
        message: String,
    },
    /// The FastSLAM table's `variant` contradicts the tag.
    #[error("the config sets variant = {variant:?} but the filter is {filter}; remove `variant` or pick the other filter")]
    VariantMismatch {
        /// The tag.
        filter: &'static str,
        /// The table's variant.
        variant: Variant,
    },
    /// A particle count was given to a filter without particles.
    #[error(
        "a particle count applies to particle filters ({}); `{filter}` has none",
        particle_filter_names()
    )]
    NotAParticleFilter {
        /// The filter.
        filter: &'static str,
    },
    /// A landmark filter was asked for a scan filter's build, or the other way round.
    #[error("`{filter}` is a {kind} filter")]
    WrongKind {
        /// The filter.
        filter: &'static str,
        /// Its kind, `"landmark"` or `"laser"`.
        kind: &'static str,
    },
    /// The filter's constructor rejected its configuration (the filter crate's error
    /// names the field and the bound). The error keeps its type: downcast `source` to the
    /// filter crate's error (`slam_ekf::EkfError`, `slam_gridfast::GridFastError`, …).
    #[error("filter `{filter}`: {source}")]
    Invalid {
        /// The filter.
        filter: &'static str,
        /// The constructor's own error.
        #[source]
        source: BoxedError,
    },
    /// The filter's name serves both kinds of data (`graph`) and the text does not say
    /// which: give the kind with [`FilterConfig::from_toml_for_kind`], or set `filter =
    /// "graph-landmark"` / `"graph-laser"`.
    #[error(
        "filter `{filter}` serves both landmark and laser data; say which: \
         `filter = \"{filter}-landmark\"` or `\"{filter}-laser\"`, or parse with \
         FilterConfig::from_toml_for_kind"
    )]
    AmbiguousKind {
        /// The filter.
        filter: &'static str,
    },
}

impl FactoryError {
    /// [`FactoryError::Invalid`] for `filter`, keeping the constructor's error `e`.
    fn invalid(filter: &'static str, e: impl std::error::Error + Send + Sync + 'static) -> Self {
        FactoryError::Invalid {
            filter,
            source: Box::new(e),
        }
    }
}

fn particle_filter_names() -> String {
    filters()
        .iter()
        .filter(|f| f.particle_filter)
        .map(|f| f.name)
        .collect::<Vec<_>>()
        .join(", ")
}

/// A filter and its configuration: the tag `filter = "<name>"` and that filter's own table.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "filter", rename_all = "kebab-case")]
pub enum FilterConfig {
    /// EKF-SLAM.
    Ekf(EkfConfig),
    /// FastSLAM 1.0 (the table's `variant` is set to match).
    Fastslam1(FastSlamConfig),
    /// FastSLAM 2.0 (the table's `variant` is set to match).
    Fastslam2(FastSlamConfig),
    /// Pose-graph SLAM with range-bearing landmark edges (`filter = "graph"` on landmark
    /// data; its example file is `configs/graph-landmark.toml`). The tag `graph-landmark`
    /// in serde's own form, since one tag cannot name two variants.
    #[serde(rename = "graph-landmark")]
    GraphLandmark(GraphLandmarkConfig),
    /// Scan-matching odometry.
    Scanmatch(ScanMatchConfig),
    /// Grid-based FastSLAM.
    Gridfast(GridFastConfig),
    /// Mapping with known poses (the log's own poses trusted).
    KnownPoses(KnownPoseConfig),
    /// The laser front end of slam-graph (pose-graph SLAM); its example file is
    /// `configs/graph-laser.toml` (`configs/graph.toml` is `slam optimize`'s); `filter =
    /// "graph"` on laser data, the tag `graph-laser` in serde's own form.
    #[serde(rename = "graph-laser")]
    GraphLaser(Box<LaserGraphConfig>),
}

/// A configuration parsed from text, with the top-level keys the text set explicitly (a
/// rule such as the simulator's noise models applies only to keys the user left out).
#[derive(Debug, Clone)]
pub struct ParsedConfig {
    /// The configuration: the text's values over the filter's defaults.
    pub config: FilterConfig,
    /// Top-level keys the text set, besides the `filter` tag.
    pub keys: Vec<String>,
    /// The `[laser-odometry]` table of a laser filter's text over its defaults
    /// ([`slam_grid::LaserOdometryConfig`]): how the odometry is made from the scans when a
    /// recording has none or it is withheld (`--odometry none`).
    pub laser_odometry: LaserOdometryConfig,
}

impl ParsedConfig {
    /// Whether the text set the top-level key `key`.
    pub fn sets(&self, key: &str) -> bool {
        self.keys.iter().any(|k| k == key)
    }

    /// Applies the simulator's noise rule ([`NoiseModels::apply_to`]) to a landmark
    /// filter's `motion` and `sensor`, keeping those the text set; scan filters are left
    /// as they are (nothing applied).
    pub fn apply_sim_noise(&mut self, noise: &NoiseModels) -> NoiseApplied {
        let (motion, sensor) = (self.sets("motion"), self.sets("sensor"));
        match &mut self.config {
            FilterConfig::Ekf(c) => noise.apply_to(&mut c.motion, &mut c.sensor, motion, sensor),
            FilterConfig::Fastslam1(c) | FilterConfig::Fastslam2(c) => {
                noise.apply_to(&mut c.motion, &mut c.sensor, motion, sensor)
            }
            FilterConfig::GraphLandmark(c) => {
                noise.apply_to(&mut c.motion, &mut c.sensor, motion, sensor)
            }
            FilterConfig::Scanmatch(_)
            | FilterConfig::Gridfast(_)
            | FilterConfig::KnownPoses(_)
            | FilterConfig::GraphLaser(_) => NoiseApplied::default(),
        }
    }
}

impl FilterConfig {
    /// The filter called `name` with its default configuration. A name that serves both
    /// kinds of data (`graph`) is [`FactoryError::AmbiguousKind`]: use
    /// [`default_for_kind`](Self::default_for_kind).
    pub fn default_for(name: &str) -> Result<Self, FactoryError> {
        let info = find(name)?;
        if serves_both_kinds(info.name) {
            return Err(FactoryError::AmbiguousKind { filter: info.name });
        }
        Self::default_for_kind(name, info.kind)
    }

    /// The filter called `name` for data of `kind` with its default configuration (a name
    /// may serve both kinds: `graph`).
    pub fn default_for_kind(name: &str, kind: DataKind) -> Result<Self, FactoryError> {
        let info = find_for(name, kind).map_or_else(|| find(name), Ok)?;
        let kind = info.kind;
        Ok(match info.name {
            "ekf" => FilterConfig::Ekf(EkfConfig::default()),
            "fastslam1" => FilterConfig::Fastslam1(FastSlamConfig {
                variant: Variant::FastSlam1,
                ..FastSlamConfig::default()
            }),
            "fastslam2" => FilterConfig::Fastslam2(FastSlamConfig {
                variant: Variant::FastSlam2,
                ..FastSlamConfig::default()
            }),
            "scanmatch" => FilterConfig::Scanmatch(ScanMatchConfig::default()),
            "gridfast" => FilterConfig::Gridfast(GridFastConfig::default()),
            "known-poses" => FilterConfig::KnownPoses(KnownPoseConfig::default()),
            "graph" if kind == DataKind::Landmark => {
                FilterConfig::GraphLandmark(GraphLandmarkConfig::default())
            }
            "graph" => FilterConfig::GraphLaser(Box::default()),
            other => {
                return Err(FactoryError::UnknownFilter {
                    name: other.to_string(),
                    known: known_names(),
                })
            }
        })
    }

    /// Parses a tagged TOML configuration: `filter = "<name>"` and the filter's keys (any
    /// subset; the rest keep their defaults). An unknown tag, a missing tag, an unknown
    /// key or a wrong type is a [`FactoryError`] naming it.
    ///
    /// `graph` serves both kinds of data, so the text must say which: `filter =
    /// "graph-landmark"` or `"graph-laser"` (the tags [`FilterConfig`] serialises with);
    /// a bare `"graph"` is [`FactoryError::AmbiguousKind`] here, and
    /// [`from_toml_for_kind`](Self::from_toml_for_kind) takes it with the data's kind.
    pub fn from_toml(text: &str) -> Result<ParsedConfig, FactoryError> {
        let table = parse_table(text)?;
        let name = match table.get("filter") {
            Some(toml::Value::String(s)) => s.clone(),
            Some(other) => {
                return Err(FactoryError::Parse {
                    line: None,
                    message: format!("`filter` must be a filter name (a string), not {other}"),
                })
            }
            None => {
                return Err(FactoryError::Parse {
                    line: None,
                    message: format!(
                        "no `filter` key naming the filter (one of {})",
                        known_names()
                    ),
                })
            }
        };
        match name.as_str() {
            "graph-landmark" => Self::from_toml_for_kind("graph", DataKind::Landmark, text),
            "graph-laser" => Self::from_toml_for_kind("graph", DataKind::Laser, text),
            _ => Self::from_toml_for(&name, text),
        }
    }

    /// Parses the TOML table of the filter called `name` (a `configs/<name>.toml` file, the
    /// `--config` of `slam run`): the filter's keys over its defaults. A `filter` key, if
    /// present, must name the same filter. A name that serves both kinds of data (`graph`)
    /// is [`FactoryError::AmbiguousKind`]: use [`from_toml_for_kind`](Self::from_toml_for_kind).
    pub fn from_toml_for(name: &str, text: &str) -> Result<ParsedConfig, FactoryError> {
        let info = find(name)?;
        if serves_both_kinds(info.name) {
            return Err(FactoryError::AmbiguousKind { filter: info.name });
        }
        Self::from_toml_for_kind(name, info.kind, text)
    }

    /// [`from_toml_for`](Self::from_toml_for) for data of `kind` (a name may serve both
    /// kinds: `graph`).
    pub fn from_toml_for_kind(
        name: &str,
        kind: DataKind,
        text: &str,
    ) -> Result<ParsedConfig, FactoryError> {
        let info = find_for(name, kind).map_or_else(|| find(name), Ok)?;
        let mut table = parse_table(text)?;
        if let Some(tag) = table.remove("filter") {
            // `graph-landmark` / `graph-laser`: the kind-qualified tag of a name that
            // serves both kinds, accepted for its own kind.
            let qualified = format!("{}-{}", info.name, info.kind.as_str());
            let same = tag.as_str() == Some(info.name)
                || (serves_both_kinds(info.name) && tag.as_str() == Some(qualified.as_str()));
            if !same {
                return Err(FactoryError::Parse {
                    line: None,
                    message: format!("the config file is for filter {tag}, not `{}`", info.name),
                });
            }
        }
        let keys: Vec<String> = table.keys().cloned().collect();
        // Deserialised from the text (the tag blanked out) rather than the table, so that
        // toml's error spans point into the user's text. A laser filter's text may hold a
        // `[laser-odometry]` table: read on its own, and blanked out of the filter's.
        let (body, laser_odometry) = if info.kind == DataKind::Laser {
            let (filter_text, table_text) = split_laser_odometry(text);
            let table: LaserOdometryTable = de(&table_text)?;
            table
                .laser_odometry
                .validate()
                .map_err(|e| FactoryError::invalid("laser-odometry", e))?;
            (blank_filter_key(&filter_text), table.laser_odometry)
        } else {
            (blank_filter_key(text), LaserOdometryConfig::default())
        };
        let config = match info.name {
            "ekf" => FilterConfig::Ekf(de(&body)?),
            "fastslam1" | "fastslam2" => {
                let mut c: FastSlamConfig = de(&body)?;
                let (variant, filter) = if info.name == "fastslam1" {
                    (Variant::FastSlam1, "fastslam1")
                } else {
                    (Variant::FastSlam2, "fastslam2")
                };
                if keys.iter().any(|k| k == "variant") && c.variant != variant {
                    return Err(FactoryError::VariantMismatch {
                        filter,
                        variant: c.variant,
                    });
                }
                c.variant = variant;
                if info.name == "fastslam1" {
                    FilterConfig::Fastslam1(c)
                } else {
                    FilterConfig::Fastslam2(c)
                }
            }
            "scanmatch" => FilterConfig::Scanmatch(de(&body)?),
            "gridfast" => FilterConfig::Gridfast(de(&body)?),
            "known-poses" => FilterConfig::KnownPoses(de(&body)?),
            "graph" if info.kind == DataKind::Landmark => FilterConfig::GraphLandmark(de(&body)?),
            "graph" => FilterConfig::GraphLaser(Box::new(de(&body)?)),
            other => {
                return Err(FactoryError::UnknownFilter {
                    name: other.to_string(),
                    known: known_names(),
                })
            }
        };
        Ok(ParsedConfig {
            config,
            keys,
            laser_odometry,
        })
    }

    /// The filter's name (the tag).
    pub fn name(&self) -> &'static str {
        match self {
            FilterConfig::Ekf(_) => "ekf",
            FilterConfig::Fastslam1(_) => "fastslam1",
            FilterConfig::Fastslam2(_) => "fastslam2",
            FilterConfig::GraphLandmark(_) | FilterConfig::GraphLaser(_) => "graph",
            FilterConfig::Scanmatch(_) => "scanmatch",
            FilterConfig::Gridfast(_) => "gridfast",
            FilterConfig::KnownPoses(_) => "known-poses",
        }
    }

    /// The filter's kind.
    pub fn kind(&self) -> DataKind {
        match self {
            FilterConfig::Ekf(_)
            | FilterConfig::Fastslam1(_)
            | FilterConfig::Fastslam2(_)
            | FilterConfig::GraphLandmark(_) => DataKind::Landmark,
            FilterConfig::Scanmatch(_)
            | FilterConfig::Gridfast(_)
            | FilterConfig::KnownPoses(_)
            | FilterConfig::GraphLaser(_) => DataKind::Laser,
        }
    }

    /// Sets the particle count of a particle filter; an error for the others.
    pub fn set_particles(&mut self, n: usize) -> Result<(), FactoryError> {
        match self {
            FilterConfig::Fastslam1(c) | FilterConfig::Fastslam2(c) => c.particles = n,
            FilterConfig::Gridfast(c) => c.particles = n,
            FilterConfig::Ekf(_)
            | FilterConfig::GraphLandmark(_)
            | FilterConfig::GraphLaser(_)
            | FilterConfig::KnownPoses(_)
            | FilterConfig::Scanmatch(_) => {
                return Err(FactoryError::NotAParticleFilter {
                    filter: self.name(),
                })
            }
        }
        Ok(())
    }

    /// The filter's own table as TOML, without the tag (what `slam run` writes as
    /// `config.toml`, and reads back with [`from_toml_for`](Self::from_toml_for)).
    pub fn table_toml(&self) -> String {
        let text = match self {
            FilterConfig::Ekf(c) => toml::to_string_pretty(c),
            FilterConfig::Fastslam1(c) | FilterConfig::Fastslam2(c) => toml::to_string_pretty(c),
            FilterConfig::GraphLandmark(c) => toml::to_string_pretty(c),
            FilterConfig::GraphLaser(c) => toml::to_string_pretty(c),
            FilterConfig::Scanmatch(c) => toml::to_string_pretty(c),
            FilterConfig::Gridfast(c) => toml::to_string_pretty(c),
            FilterConfig::KnownPoses(c) => toml::to_string_pretty(c),
        };
        text.unwrap_or_else(|e| format!("# could not serialise: {e}\n"))
    }

    /// Builds a landmark filter starting at `initial_pose`, its random numbers from `seed`
    /// (particle filters).
    pub fn build_landmark(
        &self,
        initial_pose: Pose2,
        seed: u64,
    ) -> Result<Box<dyn LandmarkSlam>, FactoryError> {
        let name = self.name();
        Ok(match self {
            FilterConfig::Ekf(c) => Box::new(
                EkfSlam::new(c.clone(), initial_pose, seed)
                    .map_err(|e| FactoryError::invalid(name, e))?,
            ),
            FilterConfig::Fastslam1(c) | FilterConfig::Fastslam2(c) => Box::new(
                FastSlam::new(c.clone(), initial_pose, seed)
                    .map_err(|e| FactoryError::invalid(name, e))?,
            ),
            FilterConfig::GraphLandmark(c) => Box::new(
                GraphLandmarkSlam::new(c.clone(), initial_pose, seed)
                    .map_err(|e| FactoryError::invalid(name, e))?,
            ),
            FilterConfig::Scanmatch(_)
            | FilterConfig::Gridfast(_)
            | FilterConfig::KnownPoses(_)
            | FilterConfig::GraphLaser(_) => {
                return Err(FactoryError::WrongKind {
                    filter: self.name(),
                    kind: DataKind::Laser.as_str(),
                })
            }
        })
    }

    /// The configuration `filter` (built from this one) reports it runs with
    /// ([`ScanSlam::effective_config`]: grid FastSLAM's, once its first scan has fixed the
    /// values left to the data), or this one when it reports none.
    pub fn effective(&self, filter: &dyn ScanSlam) -> FilterConfig {
        let reported = filter.effective_config();
        match (
            self,
            reported.and_then(|c| c.downcast_ref::<GridFastConfig>()),
        ) {
            (FilterConfig::Gridfast(_), Some(c)) => FilterConfig::Gridfast(c.clone()),
            _ => self.clone(),
        }
    }

    /// Builds a scan filter whose world is the odometry frame (`initial_pose` the identity:
    /// its first pose is the first odometry pose and its map is in the odometry frame, as
    /// GMapping's; docs/evaluation.md, "The frame of the laser filters"), its random numbers
    /// from `seed` (particle filters).
    pub fn build_scan(&self, seed: u64) -> Result<Box<dyn ScanSlam>, FactoryError> {
        let name = self.name();
        Ok(match self {
            FilterConfig::Scanmatch(c) => Box::new(
                ScanMatchOdometry::new(c.clone(), Pose2::IDENTITY, seed)
                    .map_err(|e| FactoryError::invalid(name, e))?,
            ),
            FilterConfig::Gridfast(c) => Box::new(
                GridFastSlam::new(c.clone(), Pose2::IDENTITY, seed)
                    .map_err(|e| FactoryError::invalid(name, e))?,
            ),
            FilterConfig::KnownPoses(c) => Box::new(
                KnownPoseMapping::new(*c, Pose2::IDENTITY, seed)
                    .map_err(|e| FactoryError::invalid(name, e))?,
            ),
            FilterConfig::GraphLaser(c) => Box::new(
                LaserGraphSlam::new((**c).clone(), Pose2::IDENTITY, seed)
                    .map_err(|e| FactoryError::invalid(name, e))?,
            ),
            FilterConfig::Ekf(_)
            | FilterConfig::Fastslam1(_)
            | FilterConfig::Fastslam2(_)
            | FilterConfig::GraphLandmark(_) => {
                return Err(FactoryError::WrongKind {
                    filter: self.name(),
                    kind: DataKind::Landmark.as_str(),
                })
            }
        })
    }
}

/// The `[laser-odometry]` table of a laser filter's configuration, on its own.
#[derive(Debug, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
struct LaserOdometryTable {
    laser_odometry: LaserOdometryConfig,
}

/// `config` as the `[laser-odometry]` table of a run's configuration, TOML (appended to
/// the filter's table in the `config.toml` a run writes when its odometry was made from
/// the scans; read back by [`FilterConfig::from_toml_for`]).
pub fn laser_odometry_toml(config: &LaserOdometryConfig) -> String {
    let table = LaserOdometryTable {
        laser_odometry: config.clone(),
    };
    toml::to_string_pretty(&table).unwrap_or_else(|e| format!("# could not serialise: {e}\n"))
}

/// Splits a configuration's text into the filter's lines and those of its
/// `[laser-odometry]` table (its header, its sub-tables, and top-level `laser-odometry…`
/// keys before the first header); each text keeps every line, the other's commented out,
/// so that error lines stay right.
fn split_laser_odometry(text: &str) -> (String, String) {
    let is_ours = |name: &str| {
        name.strip_prefix("laser-odometry")
            .is_some_and(|rest| rest.is_empty() || rest.starts_with('.'))
    };
    let mut in_ours = false;
    let mut in_root = true;
    let (mut filter, mut table) = (Vec::new(), Vec::new());
    for l in text.lines() {
        let t = l.trim_start();
        if t.starts_with('[') {
            in_root = false;
            let name = t.trim_start_matches('[').split(']').next().unwrap_or("");
            in_ours = is_ours(name.trim().trim_matches('"'));
        }
        let ours = in_ours
            || (in_root
                && is_ours(
                    t.split(|c: char| c == '=' || c.is_whitespace())
                        .next()
                        .unwrap_or(""),
                ));
        let comment = format!("# {l}");
        if ours {
            filter.push(comment);
            table.push(l.to_string());
        } else {
            filter.push(l.to_string());
            table.push(comment);
        }
    }
    (filter.join("\n"), table.join("\n"))
}

fn parse_table(text: &str) -> Result<toml::Table, FactoryError> {
    toml::from_str::<toml::Table>(text).map_err(|e| toml_error(text, &e))
}

/// `text` read into `C`, and refused when an array of it is longer than its fixed-size
/// setting ([`crate::config_text::overlong_array`]: toml drops the extra values silently).
fn de<C: serde::de::DeserializeOwned + serde::Serialize>(text: &str) -> Result<C, FactoryError> {
    let config = toml::from_str::<C>(text).map_err(|e| toml_error(text, &e))?;
    match crate::config_text::overlong_array(text, &config) {
        Some(long) => Err(FactoryError::Parse {
            line: Some(long.line),
            message: long.to_string(),
        }),
        None => Ok(config),
    }
}

/// The text with a top-level `filter = …` line turned into a comment (same line count, so
/// error lines stay right).
fn blank_filter_key(text: &str) -> String {
    let mut in_root = true;
    text.lines()
        .map(|l| {
            let t = l.trim_start();
            if t.starts_with('[') {
                in_root = false;
            }
            let is_tag = in_root
                && t.strip_prefix("filter")
                    .is_some_and(|rest| rest.trim_start().starts_with('='));
            if is_tag {
                format!("# {l}")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// A TOML error as one line: the line it is on and toml's own message (which names an
/// unknown key and lists the expected ones).
fn toml_error(text: &str, e: &toml::de::Error) -> FactoryError {
    let line = e
        .span()
        .map(|span| text[..span.start.min(text.len())].matches('\n').count() + 1);
    FactoryError::Parse {
        line,
        message: format!(
            "{}{}",
            e.message().trim().replace('\n', " "),
            slam_models::association::moved_key_hint(e.message()).unwrap_or_default()
        ),
    }
}

#[cfg(test)]
mod laser_odometry_tests {
    use super::*;
    use slam_grid::MotionPrediction;

    /// The `[laser-odometry]` table of a laser filter's file is read over its defaults,
    /// beside the filter's own keys and tables, and written back the same
    /// ([`laser_odometry_toml`]); without it the defaults hold.
    #[test]
    fn the_laser_odometry_table_is_read_and_written() {
        let text = "filter = \"scanmatch\"\nresolution = 0.1\n\n[laser-odometry]\n\
                    submap-scans = 7\nhypotheses = [\"constant-velocity\"]\n\
                    search-range-xy = 1.0\n\n\
                    [laser-odometry.matcher.matching]\nsigma = 0.06\n\n\
                    [matching]\nsigma = 0.07\n";
        let parsed = FilterConfig::from_toml(text).unwrap();
        let lo = &parsed.laser_odometry;
        assert_eq!(lo.submap_scans, 7);
        assert_eq!(lo.hypotheses, vec![MotionPrediction::ConstantVelocity]);
        let m = lo.matcher_config().matching;
        assert_eq!((m.search_range_xy, m.sigma), (1.0, 0.06));
        // Left to its default: laser odometry's, not scan-matching odometry's.
        assert_eq!(m.search_range_theta, 0.8);
        let FilterConfig::Scanmatch(c) = &parsed.config else {
            panic!("{:?}", parsed.config)
        };
        assert_eq!((c.resolution, c.matching.sigma), (0.1, 0.07));
        // Written and read back: the same table.
        let written = format!(
            "filter = \"scanmatch\"\n{}",
            laser_odometry_toml(&parsed.laser_odometry)
        );
        let again = FilterConfig::from_toml(&written).unwrap().laser_odometry;
        assert_eq!(laser_odometry_toml(&again), laser_odometry_toml(lo));
        let plain = FilterConfig::from_toml("filter = \"gridfast\"\n").unwrap();
        assert_eq!(
            laser_odometry_toml(&plain.laser_odometry),
            laser_odometry_toml(&LaserOdometryConfig::default())
        );
    }

    /// An unknown key of the table is an error on its line; a value out of range names
    /// the key; a landmark filter's file has no such table.
    #[test]
    fn a_bad_laser_odometry_table_is_refused() {
        let text = "filter = \"graph-laser\"\n[laser-odometry]\nsubmap-scans = 3\nsubmaps = 4\n";
        match FilterConfig::from_toml(text) {
            Err(FactoryError::Parse { line, message }) => {
                assert_eq!(line, Some(4), "{message}");
                assert!(message.contains("submaps"), "{message}");
            }
            other => panic!("{other:?}"),
        }
        let text = "filter = \"gridfast\"\n[laser-odometry]\nhypotheses = []\n";
        let e = FilterConfig::from_toml(text).unwrap_err();
        assert!(e.to_string().contains("hypotheses"), "{e}");
        let text = "filter = \"ekf\"\n[laser-odometry]\nsubmap-scans = 3\n";
        assert!(matches!(
            FilterConfig::from_toml(text),
            Err(FactoryError::Parse { .. })
        ));
    }
}
