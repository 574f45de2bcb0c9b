//! Named scenarios: `loop`, `figure8`, `city`, `clutter` (landmark worlds), `office`,
//! `campus` and `replay` (laser worlds).
//!
//! [`generate`] builds a scenario from a name and a [`ScenarioOptions`]; every option is
//! optional and falls back to the scenario's documented default (see [`list`] and the
//! per-scenario functions in [`landmarks`] and [`laser`]).

pub mod landmarks;
pub mod laser;

use crate::error::SimError;
use crate::SimOutput;
use serde::{Deserialize, Serialize};
use slam_models::{DataKind, GridMap, Point2};

/// Name, kind and a one-line description of a scenario.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ScenarioInfo {
    /// The name [`generate`] accepts.
    pub name: &'static str,
    /// Landmark or laser.
    pub kind: DataKind,
    /// One line: what the world is and its defaults.
    pub description: &'static str,
}

/// All scenarios, in a fixed order.
pub fn list() -> Vec<ScenarioInfo> {
    vec![
        ScenarioInfo {
            name: "loop",
            kind: DataKind::Landmark,
            description: "closed loop of ~60 m (21 m x 11 m rounded rectangle) with 50 landmarks; 1.1 laps, \
                          odometry controls, range 6 m, 180 deg field of view, ids known",
        },
        ScenarioInfo {
            name: "figure8",
            kind: DataKind::Landmark,
            description: "figure-eight (two lobes crossing at the origin, ~61 m) with 40 landmarks; 1.1 laps, ids known",
        },
        ScenarioInfo {
            name: "city",
            kind: DataKind::Landmark,
            description: "grid of streets (15 m blocks) with landmarks along them; size set by `landmarks` \
                          (default 2000, up to millions), random walk of 1500 steps, range 8 m",
        },
        ScenarioInfo {
            name: "clutter",
            kind: DataKind::Landmark,
            description: "`loop` with hidden ids, detection probability 0.9 and 1 false alarm per scan on average",
        },
        ScenarioInfo {
            name: "office",
            kind: DataKind::Laser,
            description: "office floor (40 m x 20 m, rooms on both sides of a corridor loop); 180 deg 181-beam laser, \
                          range 20 m, two laps of the corridor",
        },
        ScenarioInfo {
            name: "campus",
            kind: DataKind::Laser,
            description: "outdoor campus (250 m x 250 m: roads, buildings, trees, no boundary wall); 180 deg \
                          361-beam laser, range 80 m, 1.5 m/s, two laps of a 1.3 km route with loops",
        },
        ScenarioInfo {
            name: "replay",
            kind: DataKind::Laser,
            description: "laser world built from an occupancy map (`replay_map`), driven along `replay_path` \
                          or a generated path through free space",
        },
    ]
}

/// Options of [`generate`]. Every `None` means "the scenario's default" (listed per field).
/// Irrelevant options (laser options for a landmark scenario and vice versa) are ignored.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields, default)]
pub struct ScenarioOptions {
    /// The seed everything is drawn from (world, noise, clutter). Default 0.
    pub seed: u64,
    /// Number of steps (landmark scenarios) or scans (laser scenarios). Default: see
    /// each scenario (`laps` of its loop, or a fixed count).
    pub steps: Option<usize>,
    /// Number of landmarks (`city` size; also honoured by `loop`, `figure8`, `clutter`).
    pub landmarks: Option<usize>,
    /// The occupancy map of `replay` (slam-io reads PGM/ROS maps into a [`GridMap`]).
    pub replay_map: Option<GridMap>,
    /// Waypoints for `replay` (world frame, metres); default: a path generated through free
    /// space.
    pub replay_path: Option<Vec<Point2>>,
    /// Laps of a closed-loop scenario when `steps` is not given (default 1.1 for the
    /// landmark loops, 2 for `office`).
    pub laps: Option<f64>,
    /// Emit velocity controls (v, ω, Δt) instead of odometry (landmark scenarios).
    pub velocity: bool,
    /// Hide landmark ids (default: true in `clutter`, false elsewhere).
    pub hide_ids: Option<bool>,
    /// Range noise σr, metres (default 0.1).
    pub sigma_range: Option<f64>,
    /// Bearing noise σφ, radians (default 1.5° = 0.0262).
    pub sigma_bearing: Option<f64>,
    /// Sensor max range, metres (default 6 for loop/figure8/clutter, 8 for city; laser: 20
    /// for office, 30 for replay).
    pub max_range: Option<f64>,
    /// Range-bearing field of view, radians (default π).
    pub fov: Option<f64>,
    /// Probability of detecting a visible landmark (default 1, 0.9 in `clutter`).
    pub detection_probability: Option<f64>,
    /// Mean false alarms per scan (default 0, 1 in `clutter`).
    pub clutter_rate: Option<f64>,
    /// Odometry noise α1..α4 (PR table 5.6; default (0.005, 0.0002, 0.005, 0.0002)).
    pub odometry_alpha: Option<[f64; 4]>,
    /// Velocity noise α1..α6 (PR table 5.3; default: the slam-models default).
    pub velocity_alpha: Option<[f64; 6]>,
    /// Model mismatch: draw the noise with all standard deviations multiplied by this factor
    /// (default 1 = the filter's own model). Landmark runs still report the nominal models
    /// in `motion`/`sensor` (the drawn ones in `true_motion`/`true_sensor`); laser runs
    /// report the scaled models actually used.
    pub noise_scale: Option<f64>,
    /// Laser beams per scan (default 181 over 180°).
    pub beams: Option<usize>,
    /// Laser range noise σ, metres (default 0.01).
    pub laser_sigma: Option<f64>,
    /// Probability of a random short reading per beam (people, glass; default 0).
    pub short_reading_probability: Option<f64>,
}

/// The names [`generate`] accepts, comma separated.
impl ScenarioOptions {
    /// The number of laps to drive: `laps` when given, else the scenario's default; an
    /// error outside 0..=10,000.
    pub(crate) fn laps_or(&self, default_laps: f64) -> Result<f64, SimError> {
        crate::error::check_range(
            "laps",
            self.laps.unwrap_or(default_laps),
            0.0,
            1e4,
            "0 <= laps <= 10000",
        )
    }
}

fn names() -> String {
    list().iter().map(|s| s.name).collect::<Vec<_>>().join(", ")
}

/// Builds the named scenario. `replay:<anything>` is accepted as `replay` (the caller loads
/// the map into `opts.replay_map`).
pub fn generate(name: &str, opts: &ScenarioOptions) -> Result<SimOutput, SimError> {
    let base = name.split_once(':').map_or(name, |(b, _)| b);
    match base {
        "loop" => landmarks::loop_scenario(opts).map(SimOutput::Landmark),
        "figure8" => landmarks::figure8(opts).map(SimOutput::Landmark),
        "city" => landmarks::city(opts).map(SimOutput::Landmark),
        "clutter" => landmarks::clutter(opts).map(SimOutput::Landmark),
        "office" => laser::office(opts).map(SimOutput::Laser),
        "campus" => laser::campus(opts).map(SimOutput::Laser),
        "replay" => laser::replay(opts).map(SimOutput::Laser),
        _ => Err(SimError::UnknownScenario {
            name: name.to_string(),
            expected: names(),
        }),
    }
}
