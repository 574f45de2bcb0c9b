//! The filters the program knows ([`slam_eval::factory`]'s registry), and building one by
//! name behind `Box<dyn LandmarkSlam>` or `Box<dyn ScanSlam>`.
//!
//! Each filter's configuration comes from its crate's config struct: the `Default` (documented
//! there), then the `--config` TOML file over it, then `--particles` over that. For simulated
//! runs the filter's motion and sensor noise default to the models the data was generated
//! with, unless the file sets `motion` or `sensor` itself
//! ([`slam_sim::NoiseModels::apply_to`]); the run says so in one line.

use crate::error::CliError;
use slam_eval::factory::{self, FactoryError, FilterConfig, ParsedConfig};
use slam_models::{LandmarkSlam, Pose2, ScanSlam};
use slam_sim::NoiseModels;
use std::path::Path;

pub use slam_eval::factory::{filters, names_of, DataKind, FilterInfo};

/// The filter called `name`, whether or not it is available.
pub fn find(name: &str) -> Result<FilterInfo, CliError> {
    factory::find(name).map_err(|e| factory_error(e, None))
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
    pub sim_noise: Option<NoiseModels>,
    /// `--preset` (gridfast).
    pub preset: Option<&'a str>,
    /// The filter is fed laser odometry (the recording has none, it is withheld, or the
    /// node was started with `--odom-topic none`): gridfast is told so
    /// (`[motion] odometry-source = "laser"`), which widens its proposal's window to at
    /// least [`slam_gridfast::LASER_ODOMETRY_SEARCH_RANGE_XY`] unless the configuration
    /// sets `matching.search-range-xy`.
    pub laser_odometry: bool,
}

impl<'a> Setup<'a> {
    /// The setup `slam run`'s arguments ask for, from `initial_pose` with the simulator's
    /// noise models `sim_noise` (simulated data only).
    pub fn of_run(
        args: &'a crate::cli::RunArgs,
        initial_pose: Pose2,
        sim_noise: Option<NoiseModels>,
    ) -> Self {
        Setup {
            config_path: args.config.as_deref(),
            particles: args.particles.map(|p| p as usize),
            seed: args.seed,
            initial_pose,
            sim_noise,
            preset: args.preset.as_deref(),
            laser_odometry: false,
        }
    }
}

/// A built filter and the configuration it runs with (as TOML, written beside the output).
pub(crate) struct Built<F: ?Sized> {
    /// The filter.
    pub filter: Box<F>,
    /// The configuration as given, TOML (a scan filter's effective one is what it reports
    /// after the run: [`FilterConfig::effective`]).
    pub config_toml: String,
    /// The configuration as given.
    pub config: FilterConfig,
    /// One line when the simulator's noise models replaced the filter's.
    pub noise_note: Option<String>,
}

impl<F: ?Sized> Built<F> {
    fn new(filter: Box<F>, parsed: ParsedConfig, noise_note: Option<String>) -> Self {
        Built {
            filter,
            config_toml: parsed.config.table_toml(),
            config: parsed.config,
            noise_note,
        }
    }
}

/// A factory error as the program reports it (a config file's errors name the file).
fn factory_error(e: FactoryError, path: Option<&Path>) -> CliError {
    match e {
        FactoryError::UnknownFilter { name, known } => CliError::UnknownFilter { name, known },
        FactoryError::Parse { line, message } => match path {
            Some(path) => CliError::Config {
                path: path.to_path_buf(),
                line,
                message,
            },
            None => CliError::InvalidArgument(message),
        },
        FactoryError::Invalid { filter, source } => CliError::FilterConfig {
            filter: filter.to_string(),
            message: source.to_string(),
        },
        e @ (FactoryError::VariantMismatch { .. }
        | FactoryError::NotAParticleFilter { .. }
        | FactoryError::WrongKind { .. }
        | FactoryError::AmbiguousKind { .. }) => CliError::InvalidArgument(e.to_string()),
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

/// The configuration: `--config` over the defaults, `--particles` over that, and on
/// simulated data the simulator's noise models where the file sets none.
fn configure(
    info: &FilterInfo,
    setup: &Setup<'_>,
) -> Result<(ParsedConfig, Option<String>), CliError> {
    check_particles(info, setup.particles.is_some())?;
    if setup.preset.is_some() && info.name != "gridfast" {
        return Err(CliError::InvalidArgument(format!(
            "--preset applies to gridfast; `{}` has none",
            info.name
        )));
    }
    let mut parsed = match setup.config_path {
        Some(path) => {
            let text = std::fs::read_to_string(path).map_err(|e| CliError::Read {
                path: path.to_path_buf(),
                source: e,
            })?;
            FilterConfig::from_toml_for_kind(info.name, info.kind, &text)
                .map_err(|e| factory_error(e, Some(path)))?
        }
        None => ParsedConfig {
            config: FilterConfig::default_for_kind(info.name, info.kind)
                .map_err(|e| factory_error(e, None))?,
            keys: Vec::new(),
            laser_odometry: Default::default(),
        },
    };
    if let Some(n) = setup.particles {
        parsed
            .config
            .set_particles(n)
            .map_err(|e| factory_error(e, None))?;
    }
    let note = setup.sim_noise.and_then(|noise| {
        let applied = parsed.apply_sim_noise(&noise);
        let which = match (applied.motion, applied.sensor) {
            (true, true) => "motion and sensor noise models",
            (true, false) => "motion noise model (the config file sets `sensor`)",
            (false, true) => "sensor noise model (the config file sets `motion`)",
            (false, false) => return None,
        };
        Some(format!("the filter uses the simulator's {which}"))
    });
    Ok((parsed, note))
}

/// The `[laser-odometry]` table of the `--config` file over its defaults (the defaults
/// without a file, or for a filter of landmark data), for laser data whose odometry is made
/// from the scans.
pub(crate) fn laser_odometry_config(
    info: &FilterInfo,
    config_path: Option<&Path>,
) -> Result<slam_grid::LaserOdometryConfig, CliError> {
    let laser = info.kind == DataKind::Laser || factory::serves_both_kinds(info.name);
    let Some(path) = config_path.filter(|_| laser) else {
        return Ok(Default::default());
    };
    let text = std::fs::read_to_string(path).map_err(|e| CliError::Read {
        path: path.to_path_buf(),
        source: e,
    })?;
    match FilterConfig::from_toml_for_kind(info.name, DataKind::Laser, &text) {
        Ok(parsed) => Ok(parsed.laser_odometry),
        // A filter serving both kinds (graph) is configured for landmarks by a landmark
        // config: the input is not read yet, so the kind is not known here. The full parse,
        // for the input's kind, reports any error once the input is read.
        Err(_) if info.kind != DataKind::Laser => Ok(Default::default()),
        Err(e) => Err(factory_error(e, Some(path))),
    }
}

/// Builds a landmark filter.
pub(crate) fn build_landmark(
    info: &FilterInfo,
    setup: &Setup<'_>,
) -> Result<Built<dyn LandmarkSlam>, CliError> {
    let (parsed, noise_note) = configure(info, setup)?;
    let filter = parsed
        .config
        .build_landmark(setup.initial_pose, setup.seed)
        .map_err(|e| factory_error(e, None))?;
    Ok(Built::new(filter, parsed, noise_note))
}

/// Builds a laser (scan) filter.
pub(crate) fn build_scan(
    info: &FilterInfo,
    setup: &Setup<'_>,
) -> Result<Built<dyn ScanSlam>, CliError> {
    let (mut parsed, noise_note) = configure(info, setup)?;
    if let FilterConfig::Gridfast(c) = &mut parsed.config {
        c.preset = match setup.preset {
            Some("indoor") => slam_gridfast::Preset::Indoor,
            Some("outdoor") => slam_gridfast::Preset::Outdoor,
            Some(_) => slam_gridfast::Preset::Auto,
            None => c.preset,
        };
        // Laser odometry's wrong steps are up to about a metre: gridfast's proposal
        // window reaches at least that far (the preset's when wider), unless the file sets
        // it (`slam_gridfast::OdometrySource::Laser`).
        if setup.laser_odometry {
            c.motion.odometry_source = slam_gridfast::OdometrySource::Laser;
        }
    }
    let filter = parsed
        .config
        .build_scan(setup.seed)
        .map_err(|e| factory_error(e, None))?;
    Ok(Built::new(filter, parsed, noise_note))
}

/// gridfast: the values the given configuration left to the data and the filter took from
/// its first scan (`effective`, what the filter reports), as one line for stderr.
pub(crate) fn gridfast_settings(
    given: &FilterConfig,
    effective: &FilterConfig,
    scan: &slam_models::LaserScan,
) -> Option<String> {
    use slam_gridfast::Preset;
    let (FilterConfig::Gridfast(c), FilterConfig::Gridfast(effective)) = (given, effective) else {
        return None;
    };
    let from = |given: bool| if given { "configured" } else { "from the data" };
    let max_range = effective.sensor.max_range.unwrap_or(scan.max_range);
    let median = slam_gridfast::median_return_range(scan, max_range)
        .map_or("no returns".to_string(), |m| {
            format!("median return {m:.1} m")
        });
    Some(format!(
        "gridfast: max-range {max_range} m ({}; no return at or above the scan's {} m), preset {} ({}; first scan: {} beams, {median}), cells {} m",
        from(c.sensor.max_range.is_some()),
        scan.max_range,
        if effective.preset == Preset::Outdoor { "outdoor" } else { "indoor" },
        from(c.preset != Preset::Auto),
        scan.ranges.len(),
        effective.map.resolution.unwrap_or(f64::NAN),
    ))
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
        for f in filters().iter() {
            match f.name {
                "fastslam1" | "fastslam2" => {
                    example_is_complete_and_default::<slam_fastslam::FastSlamConfig>(f.name, |c| {
                        c.variant = Default::default()
                    })
                }
                "scanmatch" => {
                    example_is_complete_and_default::<slam_grid::ScanMatchConfig>(f.name, |_| ())
                }
                "known-poses" => {
                    example_is_complete_and_default::<slam_grid::KnownPoseConfig>(f.name, |_| ())
                }
                "ekf" => example_is_complete_and_default::<slam_ekf::EkfConfig>(f.name, |_| ()),
                // `graph` on landmark data; configs/graph.toml is `slam optimize`'s.
                "graph" if f.kind == DataKind::Landmark => example_is_complete_and_default::<
                    slam_graph::landmark::GraphLandmarkConfig,
                >(
                    "graph-landmark", |_| ()
                ),
                "gridfast" => {
                    example_is_complete_and_default::<slam_gridfast::GridFastConfig>(f.name, |_| ())
                }
                "graph" => example_is_complete_and_default::<slam_graph::laser::LaserGraphConfig>(
                    "graph-laser",
                    |_| (),
                ),
                other => panic!("no example-config check for {other}"),
            }
        }
    }
}
