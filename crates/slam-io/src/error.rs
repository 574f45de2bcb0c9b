//! The one error type of slam-io.

use std::path::PathBuf;
use thiserror::Error;

/// An option of [`crate::DatasetOptions`] (or of `rosbag::BagOptions`) named in an
/// [`IoError::DatasetOption`], so that a program can name it in its own terms (the `slam`
/// program: its `--robot`, `--scan-topic`, `--odom-topic`, `--laser-pose` flags).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DatasetOption {
    /// `robot`: the MRCLAM robot number.
    Robot,
    /// `scan_topic`: a ROS bag's `sensor_msgs/msg/LaserScan` topic.
    ScanTopic,
    /// `odom_topic`: a ROS bag's `nav_msgs/msg/Odometry` topic, or `/tf`.
    OdomTopic,
    /// `laser_pose`: the laser's pose in the robot's base frame.
    LaserPose,
    /// `odom_frame`: the odometry frame of a ROS bag's `/tf` odometry chain.
    OdomFrame,
    /// `base_frame`: the base frame of a ROS bag's `/tf` odometry chain.
    BaseFrame,
    /// `imu_topic`: a ROS bag's `sensor_msgs/msg/Imu` topic.
    ImuTopic,
    /// `laser_only`: the recording's odometry withheld, the scans alone.
    LaserOnly,
}

impl DatasetOption {
    /// Every option, in declaration order (for a front end naming each its own way).
    pub const ALL: [DatasetOption; 8] = [
        DatasetOption::Robot,
        DatasetOption::ScanTopic,
        DatasetOption::OdomTopic,
        DatasetOption::LaserPose,
        DatasetOption::OdomFrame,
        DatasetOption::BaseFrame,
        DatasetOption::ImuTopic,
        DatasetOption::LaserOnly,
    ];
}

impl std::fmt::Display for DatasetOption {
    /// "option `robot`" (the field's name in [`crate::DatasetOptions`]).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = match self {
            DatasetOption::Robot => "robot",
            DatasetOption::ScanTopic => "scan_topic",
            DatasetOption::OdomTopic => "odom_topic",
            DatasetOption::LaserPose => "laser_pose",
            DatasetOption::OdomFrame => "odom_frame",
            DatasetOption::BaseFrame => "base_frame",
            DatasetOption::ImuTopic => "imu_topic",
            DatasetOption::LaserOnly => "laser_only",
        };
        write!(f, "option `{name}`")
    }
}

/// What went wrong while reading or writing. File errors always name the file,
/// and parse errors the 1-based line number and what was expected there.
#[derive(Debug, Error)]
pub enum IoError {
    /// The operating system refused to open, read or write a file.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A compressed (`.gz`) file could not be decompressed: truncated or corrupt.
    #[error("{path}: cannot decompress gzip data (truncated or corrupt file): {source}")]
    Decompress {
        /// The file.
        path: PathBuf,
        /// The decoder's error.
        #[source]
        source: std::io::Error,
    },
    /// A line did not have the expected form.
    #[error("{path}:{line}: expected {expected}, found {found:?}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What the reader expected, in words.
        expected: String,
        /// The offending text (a field or the whole line, shortened).
        found: String,
    },
    /// A number was NaN or infinite.
    #[error("{path}:{line}: {what} is not finite ({value})")]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Which quantity.
        what: String,
        /// The value read.
        value: f64,
    },
    /// A finite number outside the physical bound of its field (see [`crate::bounds`]).
    #[error("{path}:{line}: {what} = {value:?} is out of bounds: expected {bound}")]
    OutOfBounds {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Which field.
        what: String,
        /// The value read.
        value: f64,
        /// The bound, in words (with units).
        bound: String,
    },
    /// A file is larger than the reader accepts (see [`crate::bounds::MAX_TEXT_BYTES`]).
    #[error("{path}: {what} is larger than the limit of {limit} bytes")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// What was too large ("file", "decompressed gzip data").
        what: String,
        /// The limit, bytes.
        limit: u64,
    },
    /// The file held no data (only blank lines or comments, or nothing).
    #[error("{path}: file is empty (expected {expected})")]
    Empty {
        /// The file.
        path: PathBuf,
        /// What the file should have held.
        expected: String,
    },
    /// A folder did not hold a file the format needs, or a path is not what was expected.
    #[error("{path}: {what}")]
    NotFound {
        /// The path looked at.
        path: PathBuf,
        /// What was missing, in words.
        what: String,
    },
    /// The data cannot be written in the requested format, or a whole-file check failed.
    #[error("{path}: {reason}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Why, in words.
        reason: String,
    },
    /// A dataset option does not apply to the dataset found (a robot number for a ROS bag),
    /// names what the dataset does not have (a topic of another type), or is needed (two
    /// candidate topics, no static transform to the laser). The message starts with the
    /// option, which a program may name as it calls it: `{path}: [topic {topic}: ]{option}
    /// {what}`.
    #[error("{path}: {}{option} {what}", topic.as_ref().map(|t| format!("topic {t}: ")).unwrap_or_default())]
    DatasetOption {
        /// The dataset.
        path: PathBuf,
        /// The ROS bag topic concerned, if any.
        topic: Option<String>,
        /// The option.
        option: DatasetOption,
        /// What is wrong, a sentence continuing after the option's name.
        what: String,
    },
    /// A ROS bag's topic or message is not what the reader expects (a message that does not
    /// decode, a value out of bounds, a missing transform).
    #[error("{path}: topic {topic}: {what}")]
    Bag {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// What was wrong and what was expected, in words.
        what: String,
    },
}

impl IoError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        IoError::Io {
            path: path.into(),
            source,
        }
    }

    pub(crate) fn option(
        path: impl Into<PathBuf>,
        topic: Option<&str>,
        option: DatasetOption,
        what: impl Into<String>,
    ) -> Self {
        IoError::DatasetOption {
            path: path.into(),
            topic: topic.map(str::to_string),
            option,
            what: what.into(),
        }
    }

    pub(crate) fn invalid(path: impl Into<PathBuf>, reason: impl Into<String>) -> Self {
        IoError::Invalid {
            path: path.into(),
            reason: reason.into(),
        }
    }
}
