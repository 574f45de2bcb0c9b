//! A run's input, loaded: a simulated scenario or whatever a path holds, with the name,
//! description and clock a run is scored and reported with.
//!
//! * [`simulate`]: a slam-sim scenario by name (`loop`, `office`, …, or
//!   `replay:<map.yaml>`, which drives through a ROS map_server map's free space), with
//!   exactly the steps asked for; landmark runs keep the simulator's noise models, for
//!   [`ParsedConfig::apply_sim_noise`](crate::factory::ParsedConfig::apply_sim_noise).
//! * [`open`]: a dataset path, read by [`slam_io::open_dataset_with`] (CARMEN logs,
//!   Freiburg course data, UTIAS MRCLAM, ROS bags — those slam-io was built to read);
//!   Freiburg course folders without the `times.dat` sidecar have step indices, not a
//!   clock.
//!
//! Both give an [`Input`], whose [`run_options`](Input::run_options) are what
//! [`run_landmarks`](crate::run_landmarks) / [`run_scans`](crate::run_scans) need to label
//! and time the run:
//!
//! ```
//! let input = slam_eval::input::simulate("loop", 7, Some(20))?;
//! let slam_eval::input::InputData::Landmark { dataset, .. } = &input.data else {
//!     unreachable!("loop is a landmark scenario")
//! };
//! assert_eq!((input.name.as_str(), dataset.steps.len()), ("loop", 20));
//! # Ok::<(), slam_eval::input::InputError>(())
//! ```

use crate::factory::DataKind;
use crate::run::RunOptions;
use slam_io::{Dataset, DatasetOptions, IoError};
use slam_models::{LandmarkDataset, ScanDataset};
use slam_sim::scenario::ScenarioOptions;
use slam_sim::{NoiseModels, SimError, SimOutput};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Why an input could not be loaded.
#[derive(Debug, Error)]
pub enum InputError {
    /// Reading the dataset (or a replay scenario's map) failed.
    #[error(transparent)]
    Io(#[from] IoError),
    /// The simulator rejected the scenario or its options.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// `replay` without a map.
    #[error("scenario replay needs a map: replay:<map.yaml> (a ROS map_server YAML)")]
    ReplayNeedsMap,
    /// `replay:<map.pgm>` without the map_server YAML of the same name beside it.
    #[error(
        "replay:{map}: a map image needs its map_server YAML (resolution, origin) beside it, expected {}",
        expected.display()
    )]
    ReplayNeedsYaml {
        /// The map as given.
        map: String,
        /// The YAML file looked for.
        expected: PathBuf,
    },
    /// `name:argument` for a scenario other than `replay`.
    #[error(
        "scenario `{spec}`: only `replay` takes an argument (`replay:<map.yaml>`), not `{name}`"
    )]
    NoArgument {
        /// The spec as given.
        spec: String,
        /// The scenario named before the `:`.
        name: String,
    },
    /// The scenario's path ends before the number of steps asked for.
    #[error(
        "scenario {name} (seed {seed}) gives {got} {what}, not the {want} asked for: its path ends there; ask for at most {got}"
    )]
    TooFewSteps {
        /// The scenario.
        name: String,
        /// Its seed.
        seed: u64,
        /// Steps (landmark) or scans (laser) asked for.
        want: usize,
        /// Steps or scans it gives.
        got: usize,
        /// `"steps"` or `"scans"`.
        what: &'static str,
    },
    /// Laser odometry (the odometry of a laser-only input) failed: its configuration, or a
    /// scan it could not use.
    #[error("laser odometry (scan-to-map matching, for an input without odometry): {0}")]
    LaserOdometry(#[from] slam_grid::GridError),
    /// A scenario parameter given for a scenario that does not use it.
    #[error(
        "scenario {scenario} does not use the parameter `{option}`; it applies to {honoured_by}"
    )]
    NotApplicable {
        /// The parameter (`landmarks`, `laps`).
        option: &'static str,
        /// The scenario.
        scenario: String,
        /// The scenarios that use it.
        honoured_by: String,
    },
}

/// A run's data, by kind.
#[derive(Debug, Clone)]
pub enum InputData {
    /// Range-bearing landmark data.
    Landmark {
        /// The dataset.
        dataset: LandmarkDataset,
        /// The noise models the simulator generated it with (simulated runs only).
        sim_noise: Option<NoiseModels>,
    },
    /// Odometry and laser scans.
    Laser(ScanDataset),
}

/// A run's input, loaded.
#[derive(Debug, Clone)]
pub struct Input {
    /// Name for [`Metrics::dataset`](crate::Metrics::dataset) and output folders: the
    /// scenario (without a `:argument`), or the dataset's own name, else its file or folder
    /// name without `.gz`/`.log`/`.clf`/`.mcap`.
    pub name: String,
    /// What the user gave (`scenario loop`, a path), for messages.
    pub label: String,
    /// One line: what was found.
    pub description: String,
    /// The data's times are step indices, not a clock (Freiburg course data).
    pub times_are_indices: bool,
    /// Made by the simulator (its ground truth is in the same frame as the estimate).
    pub simulated: bool,
    /// The data.
    pub data: InputData,
    /// The laser odometry's configuration when the odometry was made from the scans
    /// ([`withhold_odometry`]), `None` when the recording's own odometry is used.
    pub laser_odometry: Option<slam_grid::LaserOdometryConfig>,
}

impl Input {
    /// The kind of data.
    pub fn kind(&self) -> DataKind {
        match self.data {
            InputData::Landmark { .. } => DataKind::Landmark,
            InputData::Laser(_) => DataKind::Laser,
        }
    }

    /// Run options labelling the run with this input's name and clock; the rest default.
    pub fn run_options(&self) -> RunOptions<'_> {
        RunOptions {
            dataset_name: Some(&self.name),
            times_are_indices: self.times_are_indices,
            ..Default::default()
        }
    }
}

/// Scenario name and options for a scenario spec (`loop`, `replay:<map.yaml>`), seed and
/// exact step count: `replay:` reads the map (a `.pgm` is taken with the map_server YAML
/// of the same name beside it).
pub fn scenario_options(
    spec: &str,
    seed: u64,
    steps: Option<usize>,
) -> Result<(String, ScenarioOptions), InputError> {
    let mut opts = ScenarioOptions {
        seed,
        steps,
        ..Default::default()
    };
    let name = match spec.split_once(':') {
        Some(("replay", "")) => return Err(InputError::ReplayNeedsMap),
        Some(("replay", map)) => {
            let mut path = Path::new(map).to_path_buf();
            if path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("pgm"))
            {
                path.set_extension("yaml");
                if !path.exists() {
                    return Err(InputError::ReplayNeedsYaml {
                        map: map.to_string(),
                        expected: path,
                    });
                }
            }
            opts.replay_map = Some(slam_io::ros_map::read_ros_map(&path)?);
            "replay".to_string()
        }
        Some((other, _)) => {
            return Err(InputError::NoArgument {
                spec: spec.to_string(),
                name: other.to_string(),
            })
        }
        None if spec == "replay" => return Err(InputError::ReplayNeedsMap),
        None => spec.to_string(),
    };
    Ok((name, opts))
}

/// The map file of a `replay:<map>` scenario spec.
pub fn replay_map(spec: &str) -> Option<&Path> {
    match spec.split_once(':') {
        Some(("replay", map)) if !map.is_empty() => Some(Path::new(map)),
        _ => None,
    }
}

/// Generates scenario `name`, checking that it has exactly `opts.steps` (steps for
/// landmark scenarios, scans for laser ones): a scenario whose path ends sooner is
/// [`InputError::TooFewSteps`], saying how many it can give.
pub fn generate_exact(name: &str, opts: &ScenarioOptions) -> Result<SimOutput, InputError> {
    let output = slam_sim::scenario::generate(name, opts)?;
    if let Some(want) = opts.steps {
        let (got, what) = match &output {
            SimOutput::Landmark(run) => (run.dataset.steps.len(), "steps"),
            SimOutput::Laser(run) => (
                run.dataset
                    .records
                    .iter()
                    .filter(|r| r.scan.is_some())
                    .count(),
                "scans",
            ),
        };
        if got != want {
            return Err(InputError::TooFewSteps {
                name: name.to_string(),
                seed: opts.seed,
                want,
                got,
                what,
            });
        }
    }
    Ok(output)
}

/// A scenario spec's name without its `:argument` (`replay:maps/x.yaml` → `replay`).
pub fn scenario_base_name(spec: &str) -> String {
    spec.split_once(':').map_or(spec, |(b, _)| b).to_string()
}

/// The kind of data a `--sim` spec or a `--dataset` path will give, told without generating
/// or reading it (slam-sim's scenario list, [`slam_io::dataset_kind`]), so that a filter of
/// the other kind is refused before a long input is loaded; `None` when it cannot be told
/// (an unknown scenario or path: loading it then says why).
pub fn kind_before_loading(sim: Option<&str>, dataset: Option<&Path>) -> Option<DataKind> {
    if let Some(spec) = sim {
        let name = scenario_base_name(spec);
        return slam_sim::scenario::list()
            .into_iter()
            .find(|s| s.name == name)
            .map(|s| s.kind);
    }
    dataset.and_then(slam_io::dataset_kind)
}

/// Generates the scenario `spec` ([`scenario_options`], [`generate_exact`]) as an input.
pub fn simulate(spec: &str, seed: u64, steps: Option<usize>) -> Result<Input, InputError> {
    simulate_with(spec, seed, steps, ScenarioParams::default())
}

/// Scenario parameters a user sets beside the name, seed and step count (`slam run
/// --landmarks N --laps L`); `None` keeps the scenario's own. slam-sim checks their bounds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ScenarioParams {
    /// Number of landmarks of a landmark scenario ([`ScenarioOptions::landmarks`]).
    pub landmarks: Option<usize>,
    /// Laps of a closed-loop scenario when the step count is not given
    /// ([`ScenarioOptions::laps`]).
    pub laps: Option<f64>,
}

/// [`simulate`] with scenario parameters.
pub fn simulate_with(
    spec: &str,
    seed: u64,
    steps: Option<usize>,
    params: ScenarioParams,
) -> Result<Input, InputError> {
    // Which scenarios read which parameter (slam-sim's scenario builders): a parameter the
    // scenario would ignore is refused rather than dropped.
    let name = scenario_base_name(spec);
    for (option, given, honoured_by) in [
        (
            "landmarks",
            params.landmarks.is_some(),
            &["loop", "figure8", "clutter", "city"][..],
        ),
        (
            "laps",
            params.laps.is_some(),
            &["loop", "figure8", "clutter", "office", "campus"][..],
        ),
    ] {
        if given && !honoured_by.contains(&name.as_str()) {
            return Err(InputError::NotApplicable {
                option,
                scenario: name,
                honoured_by: honoured_by.join(", "),
            });
        }
    }
    let (name, mut opts) = scenario_options(spec, seed, steps)?;
    opts.landmarks = params.landmarks;
    opts.laps = params.laps;
    Ok(match generate_exact(&name, &opts)? {
        SimOutput::Landmark(run) => {
            let d = &run.dataset;
            let obs: usize = d.steps.iter().map(|s| s.observations.len()).sum();
            Input {
                description: format!(
                    "simulated scenario {name} (seed {seed}): {} steps, {obs} observations, {} true landmarks, ground truth",
                    d.steps.len(),
                    d.landmarks.as_ref().map_or(0, Vec::len),
                ),
                name: scenario_base_name(&name),
                label: format!("scenario {spec}"),
                times_are_indices: false,
                simulated: true,
                laser_odometry: None,
                data: InputData::Landmark {
                    sim_noise: Some(run.noise_models()),
                    dataset: run.dataset,
                },
            }
        }
        SimOutput::Laser(run) => {
            let d = &run.dataset;
            let scans = d.records.iter().filter(|r| r.scan.is_some()).count();
            Input {
                description: format!(
                    "simulated scenario {name} (seed {seed}): {} records, {scans} scans, ground truth",
                    d.records.len(),
                ),
                name: scenario_base_name(&name),
                label: format!("scenario {spec}"),
                times_are_indices: false,
                simulated: true,
                laser_odometry: None,
                data: InputData::Laser(run.dataset),
            }
        }
    })
}

/// A dataset path's file or folder name without `.gz`, `.log`, `.clf` and `.mcap` (in
/// that order), `"dataset"` for a path without one.
pub fn dataset_stem(path: &Path) -> String {
    let stem = path
        .file_name()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "dataset".into());
    stem.trim_end_matches(".gz")
        .trim_end_matches(".log")
        .trim_end_matches(".clf")
        .trim_end_matches(".mcap")
        .to_string()
}

/// Why a laser input's odometry is made from its scans ([`withhold_odometry`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoOdometry {
    /// The recording has none (a ROS bag with no odometry topic and no `/tf`).
    InRecording,
    /// It was asked for (the `laser_only` option): the recording's odometry is not used.
    Withheld,
}

/// Replaces the odometry of a laser input by laser odometry
/// ([`slam_grid::laser_odometry()`] with `config`, the `[laser-odometry]` table of a run's
/// configuration): each scan matched against a local map of the scans before it, around
/// zero-motion and constant-velocity predictions, with `yaw_rates` (an IMU's, time order)
/// as one more (rotation) prediction when given; every laser filter then takes it as wheel
/// odometry. Records without a scan get the time interpolation of the scan poses around
/// them. The ground truth is kept; the description line gains what was done, and
/// [`Input::laser_odometry`] the configuration. A landmark input is left as it is.
pub fn withhold_odometry(
    input: &mut Input,
    yaw_rates: &[slam_models::YawRate],
    why: NoOdometry,
    config: &slam_grid::LaserOdometryConfig,
) -> Result<(), InputError> {
    let InputData::Laser(d) = &mut input.data else {
        return Ok(());
    };
    let rates = (!yaw_rates.is_empty()).then_some(yaw_rates);
    let run = slam_grid::laser_odometry(&d.records, rates, config.clone())?;
    input.laser_odometry = Some(config.clone());
    for (r, pose) in d.records.iter_mut().zip(run.odometry) {
        r.odometry = pose;
    }
    let prior = if rates.is_some() {
        format!(
            ", the IMU's yaw rate as rotation prior on {} scans",
            run.with_prior
        )
    } else {
        String::new()
    };
    input.description.push_str(&format!(
        "; odometry: {} — laser odometry (each scan matched against the map of those before \
         it) over {} scans, {} unmatched, {} local maps, {} wide searches{prior}",
        match why {
            NoOdometry::InRecording => "none in the recording",
            NoOdometry::Withheld => "withheld (option `laser_only`)",
        },
        run.scans,
        run.failures,
        run.submaps,
        run.wide_searches,
    ));
    Ok(())
}

/// Reads the dataset at `path` ([`slam_io::open_dataset_report`]) as an input, named by the
/// dataset's own name or else [`dataset_stem`]. Laser data without odometry (a ROS bag
/// that has none, or any laser data opened with [`DatasetOptions::laser_only`]) gets laser
/// odometry ([`withhold_odometry`] with the default configuration, and the IMU's yaw rates
/// of [`DatasetOptions::imu_topic`]).
pub fn open(path: &Path, options: &DatasetOptions) -> Result<Input, InputError> {
    open_with(path, options, &slam_grid::LaserOdometryConfig::default())
}

/// [`open`] with the laser odometry's configuration `laser_odometry` (used only when the
/// odometry is made from the scans).
pub fn open_with(
    path: &Path,
    options: &DatasetOptions,
    laser_odometry: &slam_grid::LaserOdometryConfig,
) -> Result<Input, InputError> {
    let opened = slam_io::open_dataset_report(path, options)?;
    let (has_odometry, yaw_rates) = (opened.has_odometry, opened.yaw_rates);
    let mut input = open_parts(path, opened.dataset, opened.description);
    if !has_odometry {
        let why = if options.laser_only {
            NoOdometry::Withheld
        } else {
            NoOdometry::InRecording
        };
        withhold_odometry(&mut input, &yaw_rates, why, laser_odometry)?;
    }
    Ok(input)
}

fn open_parts(path: &Path, dataset: Dataset, description: String) -> Input {
    let name_of = |n: &str| {
        if n.is_empty() {
            dataset_stem(path)
        } else {
            n.to_string()
        }
    };
    // Freiburg course data has no clock: its step times are indices, unless the folder
    // carries the `times.dat` sidecar that simulated data is written with.
    let freiburg_without_clock =
        path.join("sensor_data.dat").is_file() && !path.join("times.dat").is_file();
    match dataset {
        Dataset::Landmark(d) => Input {
            name: name_of(&d.name),
            label: path.display().to_string(),
            description,
            times_are_indices: freiburg_without_clock,
            simulated: false,
            laser_odometry: None,
            data: InputData::Landmark {
                dataset: d,
                sim_noise: None,
            },
        },
        Dataset::Scan(d) => Input {
            name: name_of(&d.name),
            label: path.display().to_string(),
            description,
            times_are_indices: false,
            simulated: false,
            laser_odometry: None,
            data: InputData::Laser(d),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_and_stems() {
        assert_eq!(scenario_base_name("replay:maps/x.yaml"), "replay");
        assert_eq!(
            replay_map("replay:maps/x.yaml"),
            Some(Path::new("maps/x.yaml"))
        );
        assert_eq!(replay_map("replay:"), None);
        assert!(matches!(
            scenario_options("replay", 0, None),
            Err(InputError::ReplayNeedsMap)
        ));
        assert!(matches!(
            scenario_options("loop:x", 0, None),
            Err(InputError::NoArgument { .. })
        ));
        let missing = std::env::temp_dir().join("slam-eval-no-such-map.pgm");
        let e = scenario_options(&format!("replay:{}", missing.display()), 0, None).unwrap_err();
        assert!(matches!(e, InputError::ReplayNeedsYaml { .. }), "{e}");
        assert_eq!(dataset_stem(Path::new("/d/intel.log.gz")), "intel");
        assert_eq!(dataset_stem(Path::new("/d/run.mcap")), "run");
        assert_eq!(dataset_stem(Path::new("/")), "dataset");
    }

    /// The data kind is told before loading: scenarios by slam-sim's list, folders by their
    /// files, anything else as a CARMEN log; unknown names and missing paths are `None`.
    #[test]
    fn kind_before_loading_matches_what_loading_gives() {
        assert_eq!(
            kind_before_loading(Some("loop"), None),
            Some(DataKind::Landmark)
        );
        assert_eq!(
            kind_before_loading(Some("office"), None),
            Some(DataKind::Laser)
        );
        assert_eq!(
            kind_before_loading(Some("replay:x.yaml"), None),
            Some(DataKind::Laser)
        );
        assert_eq!(kind_before_loading(Some("nowhere"), None), None);
        let dir = std::env::temp_dir().join(format!("slam-eval-kind-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        assert_eq!(kind_before_loading(None, Some(&dir)), None);
        std::fs::write(dir.join("sensor_data.dat"), "").unwrap();
        assert_eq!(
            kind_before_loading(None, Some(&dir)),
            Some(DataKind::Landmark)
        );
        let log = dir.join("a.log");
        std::fs::write(&log, "ODOM 0 0 0 0 0 0 0 host 0\n").unwrap();
        assert_eq!(kind_before_loading(None, Some(&log)), Some(DataKind::Laser));
        assert_eq!(
            kind_before_loading(None, Some(&dir.join("missing.log"))),
            None
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// `--landmarks` and `--laps` reach the simulator (the truth has that many landmarks,
    /// the run that many laps' steps), and a parameter the scenario would ignore is refused.
    #[test]
    fn scenario_params_reach_the_simulator_or_are_refused() {
        let count = |p: ScenarioParams| {
            let InputData::Landmark { dataset, .. } =
                simulate_with("loop", 1, None, p).unwrap().data
            else {
                panic!("loop is landmark data")
            };
            (
                dataset.landmarks.map_or(0, |l| l.len()),
                dataset.steps.len(),
            )
        };
        let (n, steps_default) = count(ScenarioParams::default());
        let (n17, _) = count(ScenarioParams {
            landmarks: Some(17),
            laps: None,
        });
        let (_, steps_two) = count(ScenarioParams {
            landmarks: None,
            laps: Some(2.2),
        });
        assert_eq!((n, n17), (50, 17));
        assert!(
            steps_two.abs_diff(2 * steps_default) <= 2,
            "{steps_two} vs 2 × {steps_default}"
        );
        let e = simulate_with(
            "office",
            1,
            None,
            ScenarioParams {
                landmarks: Some(5),
                laps: None,
            },
        )
        .unwrap_err();
        assert!(
            matches!(
                e,
                InputError::NotApplicable {
                    option: "landmarks",
                    ..
                }
            ),
            "{e}"
        );
        let e = simulate_with(
            "city",
            1,
            None,
            ScenarioParams {
                landmarks: None,
                laps: Some(1.0),
            },
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("scenario city does not use the parameter `laps`"),
            "{e}"
        );
    }

    #[test]
    fn a_scenario_gives_exactly_the_steps_asked_for() {
        // With the simulator's noise models, for the filter.
        let input = simulate("loop", 2, Some(15)).unwrap();
        assert_eq!(input.kind(), DataKind::Landmark);
        let InputData::Landmark { dataset, sim_noise } = &input.data else {
            unreachable!()
        };
        assert_eq!(dataset.steps.len(), 15);
        assert!(sim_noise.is_some() && input.simulated && !input.times_are_indices);
    }

    /// A Freiburg course folder has a clock only with the `times.dat` sidecar; the folder
    /// is found as landmark data and holds the steps written into it.
    #[test]
    fn a_freiburg_folder_without_times_has_step_indices() {
        let InputData::Landmark { dataset, .. } = simulate("loop", 4, Some(12)).unwrap().data
        else {
            unreachable!()
        };
        let dir = std::env::temp_dir().join(format!("slam-eval-input-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        slam_io::freiburg::write_freiburg(&dir, &dataset).unwrap();
        let with_clock = open(&dir, &DatasetOptions::default()).unwrap();
        std::fs::remove_file(dir.join("times.dat")).unwrap();
        let without = open(&dir, &DatasetOptions::default()).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(!with_clock.times_are_indices && without.times_are_indices);
        assert!(!with_clock.simulated && with_clock.kind() == DataKind::Landmark);
        let InputData::Landmark { dataset: read, .. } = &with_clock.data else {
            unreachable!()
        };
        assert_eq!(read.steps.len(), 12);
        assert_eq!(
            with_clock.run_options().dataset_name,
            Some(with_clock.name.as_str())
        );
    }
}
