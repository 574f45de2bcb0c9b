//! slam-rs live: a ROS 2 node for every laser filter (`slam ros2`) and a Foxglove WebSocket
//! view of a run while it happens (`--live`).
//!
//! * [`node`]: the node. It speaks DDS itself through RustDDS ([`dds`]), so building and
//!   running it needs no ROS installation; it meets ROS 2 nodes on any middleware (Fast DDS,
//!   Cyclone DDS) by ROS 2's topic and type naming and QoS.
//! * [`live`]: the Foxglove WebSocket server of `--live`.
//! * [`outputs`]: the filter's state as ROS 2 messages, shared by both.
//! * [`convert`]: ROS messages to the filters' vocabulary.
//!
//! The message encodings are slam-io's ([`slam_io::ros_msg`]), the filters slam-eval's
//! factory's: this crate only moves messages between them and the network.
//!
//! See docs/ros2.md ("Run it on your robot") for the topics, frames, parameters and QoS.

pub mod convert;
pub mod dds;
pub mod error;
pub mod graph;
pub mod live;
pub mod node;
pub mod outputs;

pub use error::RosError;
pub use live::LiveServer;
pub use node::{run_node, NodeOptions, NodeReport, OdomSource, ScanStepper};
pub use outputs::{Frames, Out};
