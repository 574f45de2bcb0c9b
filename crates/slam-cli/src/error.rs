//! The one error type of the `slam` program. Every variant prints as one line that says
//! what was wrong and, where it helps, what to do instead.

use slam_models::FilterError;
use std::path::PathBuf;
use thiserror::Error;

/// Why a `slam` command failed.
#[derive(Debug, Error)]
pub enum CliError {
    /// The command line could not be parsed (clap's first error line).
    #[error("{0}")]
    Usage(String),
    /// An argument is well-formed but cannot be used as given.
    #[error("{0}")]
    InvalidArgument(String),
    /// No filter has this name.
    #[error("unknown filter `{name}` (known filters: {known}; see `slam list`)")]
    UnknownFilter {
        /// The name given.
        name: String,
        /// The known names, comma-separated.
        known: String,
    },
    /// The filter works on the other kind of data (landmark vs laser).
    #[error("filter `{filter}` needs {needs} data, but {input} is {found} data (filters for it: {suggest})")]
    WrongDataKind {
        /// The filter's name.
        filter: String,
        /// The kind the filter needs.
        needs: &'static str,
        /// What the input is (dataset path or scenario).
        input: String,
        /// The kind the input has.
        found: &'static str,
        /// Filters that take that kind of data.
        suggest: String,
    },
    /// A configuration file could not be parsed, or has a key the filter does not know.
    #[error("config file {}{}: {message}", path.display(), line.map(|l| format!(" line {l}")).unwrap_or_default())]
    Config {
        /// The file.
        path: PathBuf,
        /// 1-based line of the problem, when known.
        line: Option<usize>,
        /// What was wrong (toml's message, which names the key).
        message: String,
    },
    /// The filter's constructor rejected its configuration.
    #[error("filter `{filter}`: invalid configuration: {message}")]
    FilterConfig {
        /// The filter's name.
        filter: String,
        /// The constructor's error message.
        message: String,
    },
    /// A file could not be read.
    #[error("cannot read {}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// An output file or folder could not be written.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// The file or folder.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// Reading a dataset or writing an output failed in slam-io.
    #[error(transparent)]
    Io(slam_io::IoError),
    /// Monte Carlo localization failed (configuration, map, record).
    #[error(transparent)]
    Localize(#[from] slam_mcl::MclError),
    /// A picture could not be drawn or written (slam-viz).
    #[error(transparent)]
    Viz(#[from] slam_viz::VizError),
    /// A metric could not be computed (slam-eval).
    #[error(transparent)]
    Eval(#[from] slam_eval::EvalError),
    /// The simulator rejected the scenario or its options.
    #[error(transparent)]
    Sim(#[from] slam_sim::SimError),
    /// The ROS 2 node or the live view failed (slam-ros).
    #[error(transparent)]
    Ros(Box<slam_ros::RosError>),
    /// Laser odometry (the odometry of an input without it) failed.
    #[error("{0}")]
    LaserOdometry(String),
    /// No scan of a laser input has a return within range (every beam a no-return or
    /// invalid reading, or no beams at all): there is nothing to match or map.
    #[error("{input}: none of its {scans} scan(s) has a return within range (every beam a no-return or invalid reading, or none): nothing to map")]
    NoReturns {
        /// The input as the user gave it.
        input: String,
        /// Scans in the input.
        scans: usize,
    },
    /// The filter failed while processing the data.
    #[error("filter `{filter}` failed at step {step} (t = {t} s): {source}")]
    FilterStep {
        /// The filter's name.
        filter: String,
        /// 0-based step (or record) index.
        step: usize,
        /// The step's time.
        t: f64,
        /// The filter's error.
        #[source]
        source: FilterError,
    },
    /// The run was stopped by Ctrl-C (SIGINT) or SIGTERM; no output was written.
    #[error("interrupted at step {step} of {steps}; no output written (an earlier complete output in the folder is left as it was)")]
    Interrupted {
        /// Steps done when the stop was seen.
        step: usize,
        /// Steps in the input.
        steps: usize,
    },
    /// The pose-graph optimiser rejected the graph or its configuration, or failed.
    #[error("optimize: {0}")]
    Graph(#[from] slam_graph::GraphError),
    /// The pose-graph optimiser rejected the graph read from a file (nothing to optimise,
    /// normal equations that are not positive definite, ...), or failed on it: the file is
    /// named.
    #[error("optimize {}: {source}", path.display())]
    GraphFile {
        /// The graph file.
        path: PathBuf,
        /// The optimiser's error.
        #[source]
        source: slam_graph::GraphError,
    },
    /// The worker thread pool could not be created.
    #[error("cannot start {threads} worker threads: {message}")]
    Threads {
        /// Threads asked for.
        threads: usize,
        /// rayon's message.
        message: String,
    },
}

/// The command-line flag that sets a dataset option.
pub(crate) fn flag(option: slam_io::DatasetOption) -> &'static str {
    use slam_io::DatasetOption;
    match option {
        DatasetOption::Robot => "--robot",
        DatasetOption::ScanTopic => "--scan-topic",
        DatasetOption::OdomTopic => "--odom-topic",
        DatasetOption::LaserPose => "--laser-pose",
        DatasetOption::OdomFrame => "--odom-frame",
        DatasetOption::BaseFrame => "--base-frame",
        DatasetOption::ImuTopic => "--imu-topic",
        DatasetOption::LaserOnly => "--odometry none",
    }
}

/// A library text (a dataset's description, `slam info`'s report) with every dataset option
/// it names ("option `base_frame`", [`slam_io::DatasetOption`]'s display) replaced by the
/// flag that sets it.
pub(crate) fn with_flags(text: &str) -> String {
    slam_io::DatasetOption::ALL
        .iter()
        .fold(text.to_string(), |t, &o| t.replace(&o.to_string(), flag(o)))
}

impl From<slam_io::IoError> for CliError {
    /// A slam-io error as the program reports it: a dataset option the data does not take
    /// (or needs) is named by its flag (`--robot`, `--scan-topic`, `--odom-topic`,
    /// `--laser-pose`); every other error unchanged.
    fn from(e: slam_io::IoError) -> Self {
        match e {
            slam_io::IoError::DatasetOption {
                path,
                topic,
                option,
                what,
            } => {
                let flag = flag(option);
                let topic = topic.map(|t| format!("topic {t}: ")).unwrap_or_default();
                CliError::InvalidArgument(format!("{}: {topic}{flag} {what}", path.display()))
            }
            e => CliError::Io(e),
        }
    }
}

impl From<slam_eval::InputError> for CliError {
    /// An input error as the program reports it: a scenario too short for `--steps` names
    /// the option.
    fn from(e: slam_eval::InputError) -> Self {
        use slam_eval::InputError;
        match e {
            InputError::Io(e) => e.into(),
            InputError::Sim(e) => CliError::Sim(e),
            e @ InputError::LaserOdometry(_) => CliError::LaserOdometry(e.to_string()),
            InputError::TooFewSteps {
                name,
                seed,
                want,
                got,
                what,
            } => CliError::InvalidArgument(format!(
                "--steps {want}: scenario {name} (seed {seed}) gives {got} {what}, its path ends \
                 there; ask for at most {got}"
            )),
            InputError::NotApplicable {
                option,
                scenario,
                honoured_by,
            } => CliError::InvalidArgument(format!(
                "--{option} does not apply to scenario {scenario}; it applies to {honoured_by}"
            )),
            e @ (InputError::ReplayNeedsMap
            | InputError::ReplayNeedsYaml { .. }
            | InputError::NoArgument { .. }) => CliError::InvalidArgument(e.to_string()),
        }
    }
}

impl CliError {
    /// The process exit code: 2 for command-line mistakes, 130 (128 + SIGINT, the shell's
    /// convention) for an interrupted run, 1 for everything else.
    pub fn exit_code(&self) -> i32 {
        match self {
            CliError::Usage(_) => 2,
            CliError::Interrupted { .. } => 130,
            _ => 1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// slam-io names the option by its field, the program by its flag: `--robot` given for
    /// a Freiburg folder (only MRCLAM folders have robots).
    #[test]
    fn dataset_options_are_named_by_their_flags() {
        let dir = std::env::temp_dir().join(format!("slam-cli-robot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("sensor_data.dat"), "").unwrap();
        let options = slam_io::DatasetOptions {
            robot: Some(2),
            ..Default::default()
        };
        let e = slam_io::open_dataset_with(&dir, &options).unwrap_err();
        let library = e.to_string();
        assert!(
            library
                .ends_with(": option `robot` applies to MRCLAM folders; this is a Freiburg folder"),
            "{library}"
        );
        assert!(!library.contains("--"), "{library}");
        let cli = CliError::from(e).to_string();
        assert_eq!(
            cli,
            format!(
                "{}: --robot applies to MRCLAM folders; this is a Freiburg folder",
                dir.display()
            )
        );
        std::fs::remove_dir_all(&dir).ok();
    }
}
