//! `slam ros2`: the ROS 2 node ([`slam_ros::node`]) with a filter built like `slam run`'s
//! (the same `--config` TOML, `--particles`, `--preset`, `--seed`), until Ctrl-C, which
//! publishes and saves the final map and trajectory. See docs/ros2.md.

use crate::error::CliError;
use crate::filters::{self, DataKind, Setup};
use clap::Args;
use slam_ros::{Frames, NodeOptions, NodeReport, OdomSource};
use std::io::Write;
use std::path::PathBuf;

/// `slam ros2`.
#[derive(Debug, Clone, Args)]
pub struct Ros2Args {
    /// Laser filter to run (see `slam list`): gridfast, scanmatch, graph, known-poses.
    #[arg(long, value_name = "NAME", default_value = "gridfast")]
    pub filter: String,
    /// Filter configuration, a TOML file (as for `slam run`).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Number of particles (particle filters); overrides the config file.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub particles: Option<u64>,
    /// gridfast: the environment preset (auto, indoor, outdoor).
    #[arg(long, value_name = "PRESET", value_parser = ["auto", "indoor", "outdoor"])]
    pub preset: Option<String>,
    /// Seed of the filter's random numbers.
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub seed: u64,
    /// DDS domain (ROS_DOMAIN_ID).
    #[arg(long, value_name = "ID", default_value_t = 0,
          value_parser = clap::value_parser!(u16).range(0..=232))]
    pub domain_id: u16,
    /// The node's name in the ROS graph (`ros2 node list`).
    #[arg(long, value_name = "NAME", default_value = "slam")]
    pub node_name: String,
    /// The sensor_msgs/msg/LaserScan topic.
    #[arg(long, value_name = "TOPIC", default_value = "/scan")]
    pub scan_topic: String,
    /// The nav_msgs/msg/Odometry topic, `/tf` for the odom → base transform, or `none`
    /// (laser only).
    #[arg(long, value_name = "TOPIC", default_value = "/odom")]
    pub odom_topic: String,
    /// Stamp outputs not tied to a scan, and time the map interval, by /clock (bag replays).
    #[arg(long)]
    pub use_sim_time: bool,
    /// Frames: map, odometry and base (REP 105).
    #[arg(long, value_name = "FRAME", default_value = "map")]
    pub map_frame: String,
    /// The odometry frame.
    #[arg(long, value_name = "FRAME", default_value = "odom")]
    pub odom_frame: String,
    /// The robot's base frame.
    #[arg(long, value_name = "FRAME", default_value = "base_link")]
    pub base_frame: String,
    /// Output topics, `NAME=TOPIC` for map, pose, trajectory, particles, tf, tf_static,
    /// clock, save, map_request (repeatable), e.g. `--topic map=/slam/map`.
    #[arg(long = "topic", value_name = "NAME=TOPIC")]
    pub topics: Vec<String>,
    /// Seconds between two publications of the map.
    #[arg(long, value_name = "S", default_value_t = 5.0)]
    pub map_interval: f64,
    /// Processed scans between two publications of the trajectory.
    #[arg(long, value_name = "N", default_value_t = 10)]
    pub trajectory_every: usize,
    /// Seconds a scan waits for odometry at its stamp.
    #[arg(long, value_name = "S", default_value_t = 0.2)]
    pub odom_wait: f64,
    /// Folder of the saved map (map.pgm, map.yaml), trajectory.tum and node.json.
    #[arg(long, value_name = "DIR", default_value = "slam-ros-out")]
    pub out: PathBuf,
    /// Serve the run to Foxglove over its WebSocket protocol on ADDRESS (default
    /// 127.0.0.1:8765).
    #[arg(long, value_name = "ADDRESS", num_args = 0..=1, default_missing_value = slam_ros::live::DEFAULT_ADDRESS)]
    pub live: Option<String>,
}

/// The node's options from the arguments.
fn options(a: &Ros2Args) -> Result<NodeOptions, CliError> {
    let mut o = NodeOptions {
        domain_id: a.domain_id,
        node_name: a.node_name.clone(),
        scan_topic: a.scan_topic.clone(),
        odometry: match a.odom_topic.as_str() {
            "none" => OdomSource::None,
            "/tf" | "tf" => OdomSource::Tf,
            t => OdomSource::Topic(t.to_string()),
        },
        use_sim_time: a.use_sim_time,
        frames: Frames {
            map: a.map_frame.clone(),
            odom: a.odom_frame.clone(),
            base: a.base_frame.clone(),
            ..Frames::default()
        },
        map_interval_s: a.map_interval,
        trajectory_every: a.trajectory_every,
        odom_wait_s: a.odom_wait,
        out: a.out.clone(),
        ..NodeOptions::default()
    };
    for t in &a.topics {
        let (name, topic) = t.split_once('=').ok_or_else(|| {
            CliError::InvalidArgument(format!("--topic {t}: expected NAME=TOPIC"))
        })?;
        let slot = match name {
            "map" => &mut o.map_topic,
            "pose" => &mut o.pose_topic,
            "trajectory" => &mut o.trajectory_topic,
            "particles" => &mut o.particles_topic,
            "tf" => &mut o.tf_topic,
            "tf_static" => &mut o.tf_static_topic,
            "clock" => &mut o.clock_topic,
            "save" => &mut o.save_topic,
            "map_request" => &mut o.map_request_topic,
            _ => {
                return Err(CliError::InvalidArgument(format!(
                    "--topic {t}: NAME is one of map, pose, trajectory, particles, tf, tf_static, clock, save, map_request"
                )))
            }
        };
        *slot = topic.to_string();
    }
    o.check()
        .map_err(|e| CliError::InvalidArgument(e.to_string()))?;
    Ok(o)
}

/// Runs `slam ros2` until Ctrl-C.
pub fn ros2(a: &Ros2Args, out: &mut dyn Write) -> Result<NodeReport, CliError> {
    let (opts, built) = node_and_filter(a)?;
    let live = crate::start_live(a.live.as_deref(), |o| opts.topic(o), out)?;
    let mut log = |line: &str| {
        let _ = writeln!(out, "{line}");
        let _ = out.flush();
    };
    slam_ros::run_node(&opts, built.filter, &crate::STOP, live.as_ref(), &mut log)
        .map_err(|e| CliError::Ros(Box::new(e)))
}

/// The node's options and its filter, built as `slam run` builds a filter for a recording
/// (with `--odom-topic none`, as for a recording without odometry).
fn node_and_filter(
    a: &Ros2Args,
) -> Result<(NodeOptions, filters::Built<dyn slam_models::ScanSlam>), CliError> {
    let info = filters::find(&a.filter)?;
    let info = slam_eval::factory::find_for(info.name, DataKind::Laser).ok_or_else(|| {
        CliError::InvalidArgument(format!(
            "`{}` maps landmarks; the node runs laser filters ({})",
            a.filter,
            filters::names_of(DataKind::Laser)
        ))
    })?;
    let mut opts = options(a)?;
    // Laser only: the `[laser-odometry]` table of the config, as `slam run` takes it.
    opts.laser_odometry = filters::laser_odometry_config(&info, a.config.as_deref())?;
    let setup = Setup {
        config_path: a.config.as_deref(),
        particles: a.particles.map(|p| p as usize),
        seed: a.seed,
        initial_pose: slam_models::Pose2::default(),
        sim_noise: None,
        preset: a.preset.as_deref(),
        // `--odom-topic none`: the node makes laser odometry from the scans, as `slam run`
        // does for a recording without odometry, and tells the filter so.
        laser_odometry: opts.odometry == OdomSource::None,
    };
    let built = filters::build_scan(&info, &setup)?;
    Ok((opts, built))
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Wrap {
        #[command(flatten)]
        a: Ros2Args,
    }

    fn parse(args: &[&str]) -> Ros2Args {
        Wrap::try_parse_from(std::iter::once("ros2").chain(args.iter().copied()))
            .unwrap()
            .a
    }

    #[test]
    fn defaults_follow_the_ros_conventions() {
        let o = options(&parse(&[])).unwrap();
        assert_eq!(o.scan_topic, "/scan");
        assert_eq!(o.odometry, OdomSource::Topic("/odom".into()));
        assert_eq!(o.map_topic, "/map");
        assert_eq!(o.frames, Frames::default());
        assert!(!o.use_sim_time);
    }

    #[test]
    fn topics_and_odometry_sources_are_parameters() {
        let o = options(&parse(&["--topic", "map=/slam/map", "--odom-topic", "/tf"])).unwrap();
        assert_eq!(
            (o.map_topic.as_str(), o.odometry),
            ("/slam/map", OdomSource::Tf)
        );
        let o = options(&parse(&["--odom-topic", "none"])).unwrap();
        assert_eq!(o.odometry, OdomSource::None);
        let e = options(&parse(&["--topic", "mapp=/x"])).unwrap_err();
        assert!(e.to_string().contains("NAME is one of"), "{e}");
        assert!(options(&parse(&["--topic", "nothing"])).is_err());
        assert!(options(&parse(&["--map-interval", "0"])).is_err());
    }

    /// `--odom-topic none` feeds the filter laser odometry, as `slam run` does for a
    /// recording without odometry: grid FastSLAM is told so and its proposal's window is
    /// then as wide as `slam run`'s (at least ±1 m on an indoor scan, not the preset's
    /// ±0.3 m); with odometry from a topic it keeps the preset's.
    #[test]
    fn a_laser_only_node_widens_gridfast_like_slam_run() {
        let indoor = slam_models::LaserScan {
            angle_min: -1.5,
            angle_increment: 0.01,
            ranges: vec![2.0; 301],
            max_range: 30.0,
            sensor_pose: slam_models::Pose2::default(),
        };
        let window = |args: &[&str]| {
            let (_, built) = node_and_filter(&parse(args)).unwrap();
            let slam_eval::factory::FilterConfig::Gridfast(c) = built.config else {
                panic!("gridfast expected")
            };
            c.resolve(Some(&indoor)).unwrap().matching.search_range_xy
        };
        let laser_only = ["--filter", "gridfast", "--odom-topic", "none"];
        assert_eq!(window(&laser_only), Some(1.0));
        assert_eq!(window(&["--filter", "gridfast"]), Some(0.3));
    }
}
