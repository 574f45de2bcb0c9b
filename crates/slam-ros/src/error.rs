//! The crate's one error type.

use std::path::PathBuf;

/// Why the node or the live view failed.
#[derive(Debug, thiserror::Error)]
pub enum RosError {
    /// The DDS layer refused (joining the domain, creating a topic, reading, writing).
    #[error("DDS: {0}")]
    Dds(String),
    /// A received message did not decode.
    #[error("topic {topic}: message {index} ({ros_type}) did not decode: {source}")]
    Decode {
        /// The ROS topic.
        topic: String,
        /// The message type.
        ros_type: &'static str,
        /// 0-based index of the message on its topic.
        index: u64,
        /// The decoder's error (byte offset and field).
        #[source]
        source: slam_io::ros_msg::DecodeError,
    },
    /// A parameter is out of its bounds.
    #[error("parameter {name} = {value}: {bound}")]
    Parameter {
        /// The parameter's name.
        name: &'static str,
        /// The value given.
        value: String,
        /// The bound it breaks.
        bound: &'static str,
    },
    /// The filter failed on a scan.
    #[error("filter `{filter}` failed on scan {scan} (stamp {t} s): {source}")]
    Filter {
        /// The filter's name.
        filter: String,
        /// 0-based index of the processed scan.
        scan: usize,
        /// The scan's stamp, seconds.
        t: f64,
        /// The filter's error.
        #[source]
        source: slam_models::FilterError,
    },
    /// The laser odometry of the laser-only mode refused its configuration (`scan` none)
    /// or failed on a scan.
    #[error("laser odometry{}: {source}", scan.map(|s| format!(" on scan {s}")).unwrap_or_default())]
    LaserOdometry {
        /// 0-based index of the scan stepped, if it was a scan.
        scan: Option<usize>,
        /// The laser odometry's error.
        #[source]
        source: slam_grid::GridError,
    },
    /// Writing the map, the trajectory or the report failed.
    #[error("writing {path}: {source}")]
    Write {
        /// The file or folder.
        path: PathBuf,
        /// What failed.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The live view could not listen.
    #[error("live view on {address}: {source}")]
    Listen {
        /// The address asked for.
        address: String,
        /// The socket error.
        #[source]
        source: std::io::Error,
    },
}
