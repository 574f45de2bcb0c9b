//! The ROS 2 node: scans and odometry in, the map, `map → odom`, the pose, the trajectory and
//! the particles out, while the robot drives.
//!
//! **Threads.** A receiver thread takes every message off DDS as it arrives and stamps the
//! scans with their arrival time; the filter runs on the caller's thread. Between them is a
//! slot of one scan: a scan that arrives while the previous one still waits is put in its
//! place, and the one it replaces is *skipped* (counted, never queued). So the filter always
//! works on the newest scan, memory does not grow when the filter falls behind, and with a
//! filter that keeps up nothing is skipped.
//!
//! **Odometry** (`odom → base`) comes from `nav_msgs/Odometry`, from `/tf`, or from nowhere
//! (laser only: laser odometry, [`slam_grid::LaserOdometry`], each scan matched against a
//! local map of the scans before it, as `slam run` makes the odometry of a laser-only
//! recording; [`ScanStepper`]). A scan takes the odometry interpolated at its stamp; a scan newer than every
//! odometry message waits for the next one up to `odom_wait_s`, then takes the newest (counted
//! as `odom_held`).
//!
//! **Latency** is measured from a scan's arrival (taken off DDS) to the moment its `map →
//! odom` transform has been written, for every processed scan.
//!
//! **Requests.** A `std_msgs/String` on `save_topic` saves the map (map_server PGM + YAML) and
//! the trajectory (TUM) into the folder it names (empty: the output folder); any message on
//! `map_request_topic` publishes the map at once. At shutdown (the `stop` flag: Ctrl-C) the
//! node publishes and saves the final map and trajectory and writes `node.json`.

use crate::convert::{scan_from_msg, secs, OdomAt, OdomBuffer, StaticTf};
use crate::dds::{self, Participant, Profile, Reader, Writer};
use crate::error::RosError;
use crate::live::LiveServer;
use crate::outputs::{step_messages, trajectory_message, Frames, Include, Out};
use slam_io::ros_msg::{self, Stamp};
use slam_models::{Pose2, ScanRecord, ScanSlam};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Where the odometry comes from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum OdomSource {
    /// A `nav_msgs/msg/Odometry` topic.
    Topic(String),
    /// The `odom → base` transform on `/tf`.
    Tf,
    /// None: laser only.
    None,
}

/// The node's parameters; [`NodeOptions::default`] gives the ROS conventions.
#[derive(Debug, Clone)]
pub struct NodeOptions {
    /// DDS domain (`ROS_DOMAIN_ID`), 0–232.
    pub domain_id: u16,
    /// The `sensor_msgs/msg/LaserScan` topic (sensor-data QoS).
    pub scan_topic: String,
    /// The odometry.
    pub odometry: OdomSource,
    /// The transforms topic (`/tf`).
    pub tf_topic: String,
    /// The static transforms topic (`/tf_static`), for the laser's mounting.
    pub tf_static_topic: String,
    /// Use `/clock` for the time of messages not tied to a scan and for the map interval.
    pub use_sim_time: bool,
    /// The clock topic.
    pub clock_topic: String,
    /// Output topics, by output (default [`Out::default_topic`]); `/scan` is not republished.
    pub map_topic: String,
    /// The pose topic.
    pub pose_topic: String,
    /// The trajectory topic.
    pub trajectory_topic: String,
    /// The particles topic.
    pub particles_topic: String,
    /// Save requests (`std_msgs/msg/String`: a folder, or empty for [`NodeOptions::out`]).
    pub save_topic: String,
    /// Map requests (`std_msgs/msg/String`, any content).
    pub map_request_topic: String,
    /// The frames.
    pub frames: Frames,
    /// Seconds between map publications (> 0).
    pub map_interval_s: f64,
    /// The trajectory is published every this many processed scans (≥ 1).
    pub trajectory_every: usize,
    /// Seconds a scan waits for odometry at its stamp (0–10).
    pub odom_wait_s: f64,
    /// The output folder of the map, the trajectory and `node.json`.
    pub out: PathBuf,
    /// The laser odometry of [`OdomSource::None`] (the `[laser-odometry]` table of the
    /// filter's configuration, as for `slam run` on a laser-only recording).
    pub laser_odometry: slam_grid::LaserOdometryConfig,
    /// The node's name in the ROS graph (`ros2 node list`, `ros_discovery_info`).
    pub node_name: String,
    /// The node's namespace (`/` for the root).
    pub node_namespace: String,
}

impl Default for NodeOptions {
    fn default() -> Self {
        NodeOptions {
            domain_id: 0,
            scan_topic: "/scan".into(),
            odometry: OdomSource::Topic("/odom".into()),
            tf_topic: "/tf".into(),
            tf_static_topic: "/tf_static".into(),
            use_sim_time: false,
            clock_topic: "/clock".into(),
            map_topic: "/map".into(),
            pose_topic: "/pose".into(),
            trajectory_topic: "/trajectory".into(),
            particles_topic: "/particles".into(),
            save_topic: "/slam/save".into(),
            map_request_topic: "/slam/map_request".into(),
            frames: Frames::default(),
            map_interval_s: 5.0,
            trajectory_every: 10,
            odom_wait_s: 0.2,
            out: PathBuf::from("slam-ros-out"),
            laser_odometry: slam_grid::LaserOdometryConfig::default(),
            node_name: "slam".into(),
            node_namespace: "/".into(),
        }
    }
}

impl NodeOptions {
    /// Checks the bounds.
    pub fn check(&self) -> Result<(), RosError> {
        let bad = |name, value: String, bound| Err(RosError::Parameter { name, value, bound });
        if self.domain_id > 232 {
            return bad("domain_id", self.domain_id.to_string(), "0–232");
        }
        if !(self.map_interval_s > 0.0 && self.map_interval_s.is_finite()) {
            return bad(
                "map_interval",
                self.map_interval_s.to_string(),
                "> 0 s, finite",
            );
        }
        if self.trajectory_every == 0 {
            return bad("trajectory_every", "0".into(), "≥ 1");
        }
        if !(0.0..=10.0).contains(&self.odom_wait_s) {
            return bad("odom_wait", self.odom_wait_s.to_string(), "0–10 s");
        }
        Ok(())
    }

    /// The topic of output `out`.
    pub fn topic(&self, out: Out) -> String {
        match out {
            Out::Map => self.map_topic.clone(),
            Out::Tf => self.tf_topic.clone(),
            Out::TfStatic => self.tf_static_topic.clone(),
            Out::Pose => self.pose_topic.clone(),
            Out::Trajectory => self.trajectory_topic.clone(),
            Out::Particles => self.particles_topic.clone(),
            Out::Scan => self.scan_topic.clone(),
        }
    }
}

/// Latency figures, milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Latency {
    /// Median.
    pub p50_ms: f64,
    /// 95th percentile.
    pub p95_ms: f64,
    /// Largest.
    pub max_ms: f64,
    /// Mean.
    pub mean_ms: f64,
}

impl Latency {
    /// The figures of `samples` (nearest-rank percentiles); zeros when empty.
    pub fn of(samples: &[f64]) -> Latency {
        if samples.is_empty() {
            return Latency::default();
        }
        let mut s = samples.to_vec();
        s.sort_by(f64::total_cmp);
        let rank = |p: f64| s[((p * s.len() as f64).ceil() as usize).clamp(1, s.len()) - 1];
        Latency {
            p50_ms: rank(0.5),
            p95_ms: rank(0.95),
            max_ms: s[s.len() - 1],
            mean_ms: s.iter().sum::<f64>() / s.len() as f64,
        }
    }
}

/// What the node did (`node.json`).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct NodeReport {
    /// The filter's name.
    pub filter: String,
    /// Scans received.
    pub received: u64,
    /// Scans processed.
    pub processed: u64,
    /// Scans skipped: replaced by a newer one before the filter was free.
    pub skipped: u64,
    /// Scans processed with the newest odometry because none came at their stamp in time.
    pub odom_held: u64,
    /// Scans dropped because no odometry was known at all yet.
    pub no_odometry: u64,
    /// Scans whose frame had no `/tf_static` transform to the base (taken as at the base).
    pub unmounted: u64,
    /// Laser only: ambiguous laser-odometry steps followed as branches
    /// ([`slam_grid::LaserOdometryStream`]); 0 with odometry from a topic.
    pub laser_splits: usize,
    /// Laser only: branch decisions that kept a branch other than the single-decision one.
    pub laser_switches: usize,
    /// Messages not published, by topic: a reliable subscriber had not acknowledged the
    /// topic's history (its QoS depth) within 100 ms ([`dds::write`]).
    pub dropped: std::collections::BTreeMap<String, u64>,
    /// Messages that did not decode.
    pub decode_errors: u64,
    /// The first decoding error.
    pub first_decode_error: Option<String>,
    /// Scan arrival → `map → odom` written (in the laser-only mode including the wait
    /// for the laser odometry's decision, up to `branch-lag` scans).
    pub latency: Latency,
    /// Maps published.
    pub maps_published: u64,
    /// Resident memory, MiB, sampled every 50 processed scans (and at the end).
    pub rss_mb: Vec<f64>,
    /// Stamps (ns) of the processed scans, in order.
    pub processed_stamps_ns: Vec<i64>,
    /// The last `map → odom`: x, y (m), θ (rad).
    pub map_to_odom: [f64; 3],
    /// Seconds from start to shutdown.
    pub wall_s: f64,
    /// Files written at shutdown.
    pub files: Vec<PathBuf>,
}

/// The node's processing core, without DDS: makes each received scan the filter's next
/// record and steps the filter with it. With odometry from a topic the record takes the
/// odometry given, and the filter steps at once. In the laser-only mode
/// ([`OdomSource::None`]) the record takes the pose of the node's own laser odometry
/// ([`slam_grid::LaserOdometryStream`]: each scan matched against a local map of the scans
/// before it, in the frame of the first scan, an ambiguous step followed as branches and
/// decided `branch-lag` scans later), the odometry `slam run` makes for a laser-only
/// recording ([`slam_grid::laser_odometry()`]); a scan waits for its pose, so the filter
/// steps with it up to `branch-lag` scans late, and the node on a stream of scans and
/// `slam run` on the same scans give the same estimates. `branch-lag = 0` decides each
/// step at once (no wait).
pub struct ScanStepper {
    laser: Option<slam_grid::LaserOdometryStream>,
    /// Laser only: the scans given to the laser odometry whose pose has not come out yet,
    /// with their times (s), oldest first.
    waiting: std::collections::VecDeque<(f64, slam_models::LaserScan)>,
    /// Scans taken ([`Self::step`] calls that reached the filter or the laser odometry).
    scans: usize,
    /// Records given to the filter.
    steps: usize,
}

impl ScanStepper {
    /// A stepper for `odometry`; `laser` configures the laser odometry of
    /// [`OdomSource::None`] (rejected when invalid, by key).
    pub fn new(
        odometry: &OdomSource,
        laser: &slam_grid::LaserOdometryConfig,
    ) -> Result<Self, RosError> {
        let laser = match odometry {
            OdomSource::None => Some(
                slam_grid::LaserOdometryStream::new(laser.clone())
                    .map_err(|source| RosError::LaserOdometry { scan: None, source })?,
            ),
            _ => None,
        };
        Ok(ScanStepper {
            laser,
            waiting: Default::default(),
            scans: 0,
            steps: 0,
        })
    }

    /// Whether the odometry is made from the scans.
    pub fn laser_only(&self) -> bool {
        self.laser.is_some()
    }

    /// Scans taken whose record has not been given to the filter yet: in the laser-only
    /// mode, those waiting for the laser odometry's decision (at most `branch-lag`); else 0.
    pub fn waiting(&self) -> usize {
        self.waiting.len()
    }

    /// Ambiguous laser-odometry steps followed as branches, and decisions that kept a
    /// branch other than the single-decision one (0, 0 with odometry from a topic).
    pub fn splits_and_switches(&self) -> (usize, usize) {
        self.laser
            .as_ref()
            .map_or((0, 0), |l| (l.splits(), l.switches()))
    }

    /// Takes scan message `msg`, its sensor at `sensor_pose` in the base frame (metres,
    /// radians), at odometry `odometry` (`odom → base`; ignored in the laser-only mode,
    /// where the laser odometry's pose is taken), and steps `filter` with every record
    /// that is ready, in order. Returns those records: this scan's with odometry from a
    /// topic; in the laser-only mode none while the laser odometry follows branches, then
    /// every waiting scan's.
    pub fn step(
        &mut self,
        filter: &mut dyn ScanSlam,
        msg: &ros_msg::ScanMsg,
        odometry: Pose2,
        sensor_pose: Pose2,
    ) -> Result<Vec<ScanRecord>, RosError> {
        let scan = scan_from_msg(msg, sensor_pose);
        let t = secs(msg.header.stamp_ns);
        let index = self.scans;
        self.scans += 1;
        let Some(lo) = &mut self.laser else {
            let record = ScanRecord {
                t,
                odometry,
                scan: Some(scan),
            };
            self.give(filter, &record)?;
            return Ok(vec![record]);
        };
        let poses = lo
            .push(&scan, None)
            .map_err(|source| RosError::LaserOdometry {
                scan: Some(index),
                source,
            })?;
        self.waiting.push_back((t, scan));
        self.release(filter, poses)
    }

    /// Decides the laser odometry's open branches now (the best so far, as `slam run` does
    /// at the end of a recording) and steps `filter` with every waiting scan; none is left
    /// waiting. For shutdown; nothing to do with odometry from a topic.
    pub fn finish(&mut self, filter: &mut dyn ScanSlam) -> Result<Vec<ScanRecord>, RosError> {
        let Some(lo) = &mut self.laser else {
            return Ok(Vec::new());
        };
        let poses = lo.finish();
        self.release(filter, poses)
    }

    /// Gives the oldest waiting scans, one per pose of `poses`, to `filter`.
    fn release(
        &mut self,
        filter: &mut dyn ScanSlam,
        poses: Vec<Pose2>,
    ) -> Result<Vec<ScanRecord>, RosError> {
        let mut records = Vec::with_capacity(poses.len());
        for odometry in poses {
            // The stream gives one pose per scan pushed, in order.
            let Some((t, scan)) = self.waiting.pop_front() else {
                break;
            };
            let record = ScanRecord {
                t,
                odometry,
                scan: Some(scan),
            };
            self.give(filter, &record)?;
            records.push(record);
        }
        Ok(records)
    }

    fn give(&mut self, filter: &mut dyn ScanSlam, record: &ScanRecord) -> Result<(), RosError> {
        filter.process(record).map_err(|source| RosError::Filter {
            filter: filter.name().to_string(),
            scan: self.steps,
            t: record.t,
            source,
        })?;
        self.steps += 1;
        Ok(())
    }
}

/// A scan off the wire with its arrival time.
struct Arrived {
    msg: ros_msg::ScanMsg,
    at: Instant,
}

/// What the receiver thread hands the filter's thread.
#[derive(Default)]
struct Inbox {
    scan: Option<Arrived>,
    received: u64,
    skipped: u64,
    odom: Option<OdomBuffer>,
    statics: StaticTf,
    clock_ns: Option<i64>,
    saves: Vec<String>,
    map_requests: u64,
    decode_errors: u64,
    first_decode_error: Option<String>,
    failed: Option<String>,
}

/// A reader with the ROS topic it reads (for the errors) and its count of messages taken.
struct Named {
    reader: Reader,
    topic: String,
    taken: u64,
}

impl Named {
    fn new(dp: &Participant, topic: &str, ros_type: &str, p: Profile) -> Result<Self, RosError> {
        Ok(Named {
            reader: dp.reader(topic, ros_type, p)?,
            topic: topic.to_string(),
            taken: 0,
        })
    }
}

struct Readers {
    scan: Named,
    /// The odometry, and whether it is `/tf` (else `nav_msgs/Odometry`).
    odom: Option<(Named, bool)>,
    tf_static: Named,
    clock: Option<Named>,
    save: Named,
    map_request: Named,
}

impl Readers {
    /// Every reader, in a fixed order (the poll tokens).
    fn all(&mut self) -> Vec<&mut Named> {
        let mut v = vec![
            &mut self.scan,
            &mut self.tf_static,
            &mut self.save,
            &mut self.map_request,
        ];
        v.extend(self.odom.as_mut().map(|(n, _)| n));
        v.extend(self.clock.as_mut());
        v
    }
}

struct Writers {
    tf: Writer,
    map: Writer,
    pose: Writer,
    trajectory: Writer,
    particles: Writer,
}

impl Writers {
    fn of(&self, out: Out) -> Option<&Writer> {
        match out {
            Out::Tf => Some(&self.tf),
            Out::Map => Some(&self.map),
            Out::Pose => Some(&self.pose),
            Out::Trajectory => Some(&self.trajectory),
            Out::Particles => Some(&self.particles),
            Out::TfStatic | Out::Scan => None,
        }
    }
}

const LASER_SCAN: &str = "sensor_msgs/msg/LaserScan";
const ODOMETRY: &str = "nav_msgs/msg/Odometry";
const TF: &str = "tf2_msgs/msg/TFMessage";
const CLOCK: &str = "rosgraph_msgs/msg/Clock";
const STRING: &str = "std_msgs/msg/String";

/// Odometry poses kept for interpolation (about 40 s at 100 Hz).
const ODOM_KEPT: usize = 4096;

/// Runs the node with `filter` until `stop` is set, then saves and reports. `live` also
/// serves every output (and the scans) to Foxglove; `log` receives one line per event worth
/// telling (start, first scan, saves, shutdown).
pub fn run_node(
    opts: &NodeOptions,
    mut filter: Box<dyn ScanSlam>,
    stop: &AtomicBool,
    live: Option<&LiveServer>,
    log: &mut dyn FnMut(&str),
) -> Result<NodeReport, RosError> {
    opts.check()?;
    let started = Instant::now();
    let stepper = ScanStepper::new(&opts.odometry, &opts.laser_odometry)?;
    let dp = Participant::new(opts.domain_id)?;
    let writers = Writers {
        tf: dp.writer(&opts.tf_topic, TF, Profile::Tf)?,
        map: dp.writer(&opts.map_topic, Out::Map.ros_type(), Profile::Latched)?,
        pose: dp.writer(&opts.pose_topic, Out::Pose.ros_type(), Profile::Default)?,
        trajectory: dp.writer(
            &opts.trajectory_topic,
            Out::Trajectory.ros_type(),
            Profile::Latched,
        )?,
        particles: dp.writer(
            &opts.particles_topic,
            Out::Particles.ros_type(),
            Profile::Default,
        )?,
    };
    let readers = Readers {
        scan: Named::new(&dp, &opts.scan_topic, LASER_SCAN, Profile::SensorData)?,
        odom: match &opts.odometry {
            OdomSource::Topic(t) => Some((Named::new(&dp, t, ODOMETRY, Profile::Default)?, false)),
            OdomSource::Tf if opts.tf_topic.is_empty() => None,
            OdomSource::Tf => Some((Named::new(&dp, &opts.tf_topic, TF, Profile::Tf)?, true)),
            OdomSource::None => None,
        },
        tf_static: Named::new(&dp, &opts.tf_static_topic, TF, Profile::Latched)?,
        clock: if opts.use_sim_time {
            Some(Named::new(
                &dp,
                &opts.clock_topic,
                CLOCK,
                Profile::SensorData,
            )?)
        } else {
            None
        },
        save: Named::new(&dp, &opts.save_topic, STRING, Profile::Default)?,
        map_request: Named::new(&dp, &opts.map_request_topic, STRING, Profile::Default)?,
    };
    // The node in the ROS graph (`ros2 node list`): its readers and writers by gid.
    let mut readers = readers;
    let graph_node = crate::graph::NodeEntities {
        namespace: opts.node_namespace.clone(),
        name: opts.node_name.clone(),
        readers: readers
            .all()
            .into_iter()
            .map(|n| dds::gid_of(&n.reader))
            .collect(),
        writers: [
            &writers.tf,
            &writers.map,
            &writers.pose,
            &writers.trajectory,
            &writers.particles,
        ]
        .into_iter()
        .map(|w| dds::gid_of(w))
        .collect(),
    };
    let graph = dp.discovery_info_writer()?;
    dds::write(
        &graph,
        crate::graph::DISCOVERY_TOPIC,
        crate::graph::encode_participant_entities_info(&dp.gid(), &[graph_node]),
    )?;
    // No buffer: no odometry yet (laser only: none expected, the scans make it).
    let odom = None;
    let inbox = Arc::new((
        Mutex::new(Inbox {
            odom,
            ..Inbox::default()
        }),
        Condvar::new(),
    ));
    let quit = Arc::new(AtomicBool::new(false));
    let receiver = {
        let inbox = Arc::clone(&inbox);
        let quit = Arc::clone(&quit);
        let frames = opts.frames.clone();
        std::thread::Builder::new()
            .name("ros-receive".into())
            .spawn(move || {
                if let Err(e) = receive(readers, &inbox, &quit, &frames) {
                    if let Ok(mut inb) = inbox.0.lock() {
                        inb.failed = Some(e.to_string());
                    }
                    inbox.1.notify_all();
                }
            })
            .map_err(|e| RosError::Dds(format!("receiver thread: {e}")))?
    };
    log(&format!(
        "slam ros2: filter {} on DDS domain {}, scans from {}, odometry {}; Ctrl-C saves and stops",
        filter.name(),
        opts.domain_id,
        opts.scan_topic,
        match &opts.odometry {
            OdomSource::Topic(t) => t.clone(),
            OdomSource::Tf => format!(
                "{} ({} → {})",
                opts.tf_topic, opts.frames.odom, opts.frames.base
            ),
            OdomSource::None => "none (laser only)".into(),
        }
    ));
    let mut node = Running {
        opts,
        writers: &writers,
        live,
        report: NodeReport {
            filter: filter.name().to_string(),
            ..NodeReport::default()
        },
        latencies: Vec::new(),
        last_map: None,
        last_odom: Pose2::IDENTITY,
        last_stamp: None,
        stepper,
        arrivals: Default::default(),
    };
    let result = node.spin(filter.as_mut(), &inbox, stop, log);
    quit.store(true, Ordering::Relaxed);
    let _ = receiver.join();
    let (lock, _) = &*inbox;
    if let Ok(inb) = lock.lock() {
        node.report.received = inb.received;
        node.report.skipped = inb.skipped + u64::from(inb.scan.is_some());
        node.report.decode_errors = inb.decode_errors;
        node.report.first_decode_error = inb.first_decode_error.clone();
    }
    // Leaving the graph (as rmw does when a node is destroyed).
    let _ = dds::write(
        &graph,
        crate::graph::DISCOVERY_TOPIC,
        crate::graph::encode_participant_entities_info(&dp.gid(), &[]),
    );
    result?;
    // Shutdown: the scans still waiting for the laser odometry's decision go to the filter
    // (decided as `slam run` decides at the end of a recording), then the final map out,
    // and everything on disk (no map exists before the first scan: then only node.json,
    // and the log says so).
    let released = node.stepper.finish(filter.as_mut())?;
    node.publish_released(filter.as_mut(), &released)?;
    (node.report.laser_splits, node.report.laser_switches) = node.stepper.splits_and_switches();
    if node.report.processed > 0 {
        let stamp = node.now_stamp(&inbox);
        node.publish_map(filter.as_ref(), stamp)?;
        node.report.files = save(filter.as_ref(), &opts.out)?;
    } else {
        std::fs::create_dir_all(&opts.out).map_err(|e| RosError::Write {
            path: opts.out.clone(),
            source: Box::new(e),
        })?;
        log("slam ros2: no scan processed, so no map or trajectory to save");
    }
    node.report.latency = Latency::of(&node.latencies);
    if let Some(rss) = current_rss_mb() {
        node.report.rss_mb.push(rss);
    }
    node.report.wall_s = started.elapsed().as_secs_f64();
    let json = opts.out.join("node.json");
    let text = serde_json::to_string_pretty(&node.report).unwrap_or_default();
    std::fs::write(&json, text + "\n").map_err(|e| RosError::Write {
        path: json.clone(),
        source: Box::new(e),
    })?;
    node.report.files.push(json);
    log(&format!(
        "slam ros2: {} scans received, {} processed, {} skipped; latency p50 {:.1} ms, p95 {:.1} ms, max {:.1} ms; saved to {}",
        node.report.received,
        node.report.processed,
        node.report.skipped,
        node.report.latency.p50_ms,
        node.report.latency.p95_ms,
        node.report.latency.max_ms,
        opts.out.display()
    ));
    Ok(node.report)
}

/// Saves the filter's map (`map.pgm` + `map.yaml`) and trajectory (`trajectory.tum`) in `dir`.
pub fn save(filter: &dyn ScanSlam, dir: &Path) -> Result<Vec<PathBuf>, RosError> {
    let write = |path: &Path, source: Box<dyn std::error::Error + Send + Sync>| RosError::Write {
        path: path.to_path_buf(),
        source,
    };
    std::fs::create_dir_all(dir).map_err(|e| write(dir, Box::new(e)))?;
    slam_io::ros_map::write_ros_map(dir, "map", &filter.map())
        .map_err(|e| write(dir, Box::new(e)))?;
    let tum = dir.join("trajectory.tum");
    slam_io::tum::write_tum(&tum, &filter.trajectory()).map_err(|e| write(&tum, Box::new(e)))?;
    Ok(vec![dir.join("map.pgm"), dir.join("map.yaml"), tum])
}

/// The filter's side of the node.
struct Running<'a> {
    opts: &'a NodeOptions,
    writers: &'a Writers,
    live: Option<&'a LiveServer>,
    report: NodeReport,
    latencies: Vec<f64>,
    /// When the map was last published: sim-time ns or wall clock.
    last_map: Option<(Option<i64>, Instant)>,
    last_odom: Pose2,
    last_stamp: Option<Stamp>,
    stepper: ScanStepper,
    /// Arrival and frame of each scan taken whose record the stepper has not released.
    arrivals: std::collections::VecDeque<(Instant, String)>,
}

impl Running<'_> {
    fn spin(
        &mut self,
        filter: &mut dyn ScanSlam,
        inbox: &(Mutex<Inbox>, Condvar),
        stop: &AtomicBool,
        log: &mut dyn FnMut(&str),
    ) -> Result<(), RosError> {
        let (lock, cvar) = inbox;
        while !stop.load(Ordering::Relaxed) {
            let (scan, saves, map_requests, clock_ns) = {
                let mut inb = lock
                    .lock()
                    .map_err(|_| RosError::Dds("receiver thread panicked".into()))?;
                if inb.scan.is_none() {
                    inb = cvar
                        .wait_timeout(inb, Duration::from_millis(50))
                        .map_err(|_| RosError::Dds("receiver thread panicked".into()))?
                        .0;
                }
                if let Some(f) = inb.failed.take() {
                    return Err(RosError::Dds(f));
                }
                let req = std::mem::take(&mut inb.map_requests);
                (
                    inb.scan.take(),
                    std::mem::take(&mut inb.saves),
                    req,
                    inb.clock_ns,
                )
            };
            if let Some(arrived) = scan {
                self.process(filter, arrived, inbox, stop)?;
            }
            for dir in saves {
                let dir = if dir.trim().is_empty() {
                    self.opts.out.clone()
                } else {
                    PathBuf::from(dir.trim())
                };
                match save(filter, &dir) {
                    Ok(_) => log(&format!(
                        "slam ros2: saved the map and trajectory to {}",
                        dir.display()
                    )),
                    Err(e) => log(&format!("slam ros2: save request failed: {e}")),
                }
            }
            let due = match (self.last_map, self.opts.use_sim_time) {
                (None, _) => self.report.processed > 0,
                (Some((Some(t0), _)), true) => {
                    clock_ns.is_some_and(|t| secs(t - t0) >= self.opts.map_interval_s)
                }
                (Some((_, at)), _) => at.elapsed().as_secs_f64() >= self.opts.map_interval_s,
            };
            if (map_requests > 0 || due) && self.report.processed > 0 {
                let stamp = self.now_stamp(inbox);
                self.publish_map(filter, stamp)?;
            }
        }
        Ok(())
    }

    /// Now: the sim clock with `use_sim_time`, else the system clock (falling back to the
    /// last scan's stamp).
    fn now_stamp(&self, inbox: &(Mutex<Inbox>, Condvar)) -> Stamp {
        let clock = inbox.0.lock().ok().and_then(|i| i.clock_ns);
        let t = if self.opts.use_sim_time {
            clock.map(secs)
        } else {
            SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .ok()
                .map(|d| d.as_secs_f64())
        };
        t.and_then(ros_msg::stamp)
            .or(self.last_stamp)
            .unwrap_or(Stamp { sec: 0, nanosec: 0 })
    }

    fn publish_map(&mut self, filter: &dyn ScanSlam, stamp: Stamp) -> Result<(), RosError> {
        let map = ros_msg::encode_occupancy_grid(stamp, &self.opts.frames.map, &filter.map());
        self.send(Out::Map, stamp, map)?;
        let path = trajectory_message(stamp, filter, &self.opts.frames);
        self.send(Out::Trajectory, stamp, path)?;
        self.report.maps_published += 1;
        let sim = if self.opts.use_sim_time {
            Some(i64::from(stamp.sec) * 1_000_000_000 + i64::from(stamp.nanosec))
        } else {
            None
        };
        self.last_map = Some((sim, Instant::now()));
        Ok(())
    }

    fn send(&mut self, out: Out, stamp: Stamp, bytes: Vec<u8>) -> Result<(), RosError> {
        if let Some(live) = self.live {
            live.publish(out, stamp.ns(), bytes.clone());
        }
        let Some(w) = self.writers.of(out) else {
            return Ok(());
        };
        let topic = self.opts.topic(out);
        if !dds::write(w, &topic, bytes)? {
            *self.report.dropped.entry(topic).or_default() += 1;
        }
        Ok(())
    }

    /// The odometry at `ns`, waiting up to `odom_wait_s` for it to arrive.
    fn odometry_at(
        &mut self,
        ns: i64,
        inbox: &(Mutex<Inbox>, Condvar),
        stop: &AtomicBool,
    ) -> Option<Pose2> {
        let (lock, cvar) = inbox;
        let deadline = Instant::now() + Duration::from_secs_f64(self.opts.odom_wait_s);
        let mut inb = lock.lock().ok()?;
        loop {
            let found = match &inb.odom {
                None => OdomAt::Missing,
                Some(buf) => buf.at(ns),
            };
            let now = Instant::now();
            match found {
                OdomAt::Pose(p) => return Some(p),
                OdomAt::Ahead(p) if now >= deadline || stop.load(Ordering::Relaxed) => {
                    self.report.odom_held += 1;
                    return Some(p);
                }
                OdomAt::Missing if now >= deadline || stop.load(Ordering::Relaxed) => return None,
                _ => {
                    inb = cvar.wait_timeout(inb, deadline - now).ok()?.0;
                }
            }
        }
    }

    fn process(
        &mut self,
        filter: &mut dyn ScanSlam,
        arrived: Arrived,
        inbox: &(Mutex<Inbox>, Condvar),
        stop: &AtomicBool,
    ) -> Result<(), RosError> {
        let ns = arrived.msg.header.stamp_ns;
        let odom = if self.stepper.laser_only() {
            Pose2::IDENTITY
        } else {
            let Some(odom) = self.odometry_at(ns, inbox, stop) else {
                self.report.no_odometry += 1;
                return Ok(());
            };
            odom
        };
        let frame = &arrived.msg.header.frame_id;
        let mount = inbox
            .0
            .lock()
            .ok()
            .and_then(|i| i.statics.pose_in(&self.opts.frames.base, frame));
        let sensor_pose = mount.unwrap_or_else(|| {
            self.report.unmounted += 1;
            Pose2::IDENTITY
        });
        let records = self.stepper.step(filter, &arrived.msg, odom, sensor_pose)?;
        self.report.processed += 1;
        self.report.processed_stamps_ns.push(ns);
        self.arrivals.push_back((arrived.at, frame.clone()));
        self.publish_released(filter, &records)?;
        if self.report.processed % 50 == 0 {
            if let Some(rss) = current_rss_mb() {
                self.report.rss_mb.push(rss);
            }
        }
        Ok(())
    }

    /// Publishes the outputs of the last of `records`, the records the stepper just gave
    /// the filter (none while the laser odometry waits on branches; several when it
    /// decides): the filter's state is that of the last, so the earlier ones' `map → odom`
    /// would be stale. Every released scan's latency (its arrival to this `map → odom`) is
    /// counted, so a scan that waited for the laser odometry shows its wait.
    fn publish_released(
        &mut self,
        filter: &mut dyn ScanSlam,
        records: &[ScanRecord],
    ) -> Result<(), RosError> {
        let arrivals: Vec<(Instant, String)> = (0..records.len())
            .filter_map(|_| self.arrivals.pop_front())
            .collect();
        let (Some(record), Some((_, frame))) = (records.last(), arrivals.last()) else {
            return Ok(());
        };
        let frame = frame.clone();
        let (t, odom) = (record.t, record.odometry);
        let stamp = ros_msg::stamp(t).unwrap_or(Stamp { sec: 0, nanosec: 0 });
        self.last_stamp = Some(stamp);
        self.last_odom = odom;
        let trajectory = self.report.processed as usize % self.opts.trajectory_every == 0;
        let include = Include {
            map: false,
            trajectory,
            // Laser only: no robot publishes `odom → base`; the laser odometry is it.
            odom_tf: self.stepper.laser_only(),
            scan: None,
        };
        let mut latency_done = false;
        for (out, bytes) in step_messages(stamp, filter, &odom, &self.opts.frames, include) {
            self.send(out, stamp, bytes)?;
            if out == Out::Tf && !latency_done {
                self.latencies.extend(
                    arrivals
                        .iter()
                        .map(|(at, _)| at.elapsed().as_secs_f64() * 1e3),
                );
                latency_done = true;
            }
        }
        let pose = filter.pose();
        let c = crate::outputs::map_to_odom(&pose, &odom);
        self.report.map_to_odom = [c.x, c.y, c.theta];
        if let Some(live) = self.live {
            // The view also gets the scan in its own frame and the mounting.
            let scan = record.scan.as_ref();
            if let Some(scan) = scan {
                let frames = Frames {
                    laser: frame.clone(),
                    ..self.opts.frames.clone()
                };
                live.publish(
                    Out::Scan,
                    stamp.ns(),
                    ros_msg::encode_laser_scan(stamp, &frames.laser, scan),
                );
                live.publish(
                    Out::TfStatic,
                    stamp.ns(),
                    ros_msg::encode_tf_message(&[ros_msg::Transform {
                        stamp,
                        parent: &frames.base,
                        child: &frames.laser,
                        pose: scan.sensor_pose,
                    }]),
                );
            }
        }
        Ok(())
    }
}

/// Resident memory of this process now, MiB (`VmRSS` of `/proc/self/status`).
pub fn current_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// Takes every waiting message of `r`, decodes it with `decode` and hands it to `apply`
/// under the inbox lock. A message that does not decode is counted, the first such error
/// kept (naming `r`'s topic, `ros_type` and the message's index on it). `Err`: the DDS read
/// failed, or the filter's thread panicked.
fn drain<T>(
    r: &mut Named,
    ros_type: &'static str,
    lock: &Mutex<Inbox>,
    decode: impl Fn(&[u8]) -> Result<T, slam_io::ros_msg::DecodeError>,
    mut apply: impl FnMut(&mut Inbox, T),
) -> Result<(), RosError> {
    while let Some(m) = dds::take(&mut r.reader, &r.topic)? {
        let index = r.taken;
        r.taken += 1;
        let decoded = decode(&m.0);
        let mut inb = lock
            .lock()
            .map_err(|_| RosError::Dds("the filter's thread panicked".into()))?;
        match decoded {
            Ok(v) => apply(&mut inb, v),
            Err(source) => {
                inb.decode_errors += 1;
                if inb.first_decode_error.is_none() {
                    let e = RosError::Decode {
                        topic: r.topic.clone(),
                        ros_type,
                        index,
                        source,
                    };
                    inb.first_decode_error = Some(e.to_string());
                }
            }
        }
    }
    Ok(())
}

/// How long the receiver blocks on its readers before it looks at the quit flag.
const RECEIVE_WAKE: Duration = Duration::from_millis(100);

/// The receiver thread: blocks until one of the readers has data (mio's poll on their
/// readiness, at most [`RECEIVE_WAKE`]), then takes every waiting message of every reader.
fn receive(
    mut r: Readers,
    inbox: &(Mutex<Inbox>, Condvar),
    quit: &AtomicBool,
    frames: &Frames,
) -> Result<(), RosError> {
    let (lock, cvar) = inbox;
    let poll_error = |e: std::io::Error| RosError::Dds(format!("poll of the readers: {e}"));
    let mut poll = mio::Poll::new().map_err(poll_error)?;
    for (i, n) in r.all().into_iter().enumerate() {
        poll.registry()
            .register(&mut n.reader, mio::Token(i), mio::Interest::READABLE)
            .map_err(poll_error)?;
    }
    let mut events = mio::Events::with_capacity(16);
    while !quit.load(Ordering::Relaxed) {
        match poll.poll(&mut events, Some(RECEIVE_WAKE)) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(poll_error(e)),
        }
        // Every reader is drained on every wake (a reader's readiness is edge-triggered:
        // what one wake announces may hold several messages, and a timeout costs nothing).
        drain(
            &mut r.tf_static,
            TF,
            lock,
            ros_msg::decode_tf_message,
            |inb, ts| ts.into_iter().for_each(|t| inb.statics.insert(t)),
        )?;
        if let Some((reader, is_tf)) = &mut r.odom {
            let is_tf = *is_tf;
            let decode = |b: &[u8]| {
                if is_tf {
                    ros_msg::decode_tf_message(b).map(|ts| {
                        ts.into_iter()
                            .filter(|t| t.parent == frames.odom && t.child == frames.base)
                            .collect::<Vec<_>>()
                    })
                } else {
                    ros_msg::decode_odometry(b).map(|o| vec![o])
                }
            };
            drain(
                reader,
                if is_tf { TF } else { ODOMETRY },
                lock,
                decode,
                |inb, poses| {
                    let buf = inb.odom.get_or_insert_with(|| OdomBuffer::new(ODOM_KEPT));
                    for p in poses {
                        buf.push(p.stamp_ns, p.pose);
                    }
                    cvar.notify_all();
                },
            )?;
        }
        if let Some(reader) = &mut r.clock {
            drain(reader, CLOCK, lock, ros_msg::decode_clock, |inb, ns| {
                inb.clock_ns = Some(ns)
            })?;
        }
        drain(
            &mut r.scan,
            LASER_SCAN,
            lock,
            ros_msg::decode_laser_scan,
            |inb, msg| {
                inb.received += 1;
                let replaced = inb.scan.replace(Arrived {
                    msg,
                    at: Instant::now(),
                });
                if replaced.is_some() {
                    inb.skipped += 1;
                }
                cvar.notify_all();
            },
        )?;
        drain(
            &mut r.save,
            STRING,
            lock,
            ros_msg::decode_string,
            |inb, s| inb.saves.push(s),
        )?;
        drain(
            &mut r.map_request,
            STRING,
            lock,
            |_| Ok(()),
            |inb, ()| inb.map_requests += 1,
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latency_percentiles_are_nearest_rank() {
        let l = Latency::of(&[5.0, 1.0, 3.0, 2.0, 4.0]);
        assert_eq!(l.p50_ms, 3.0);
        assert_eq!(l.p95_ms, 5.0);
        assert_eq!(l.max_ms, 5.0);
        assert_eq!(l.mean_ms, 3.0);
        assert_eq!(Latency::of(&[]), Latency::default());
    }

    #[test]
    fn parameters_out_of_bounds_are_refused() {
        let mut o = NodeOptions::default();
        assert!(o.check().is_ok());
        o.map_interval_s = 0.0;
        assert!(matches!(
            o.check(),
            Err(RosError::Parameter {
                name: "map_interval",
                ..
            })
        ));
        let o = NodeOptions {
            domain_id: 233,
            ..NodeOptions::default()
        };
        assert!(o.check().is_err());
    }
}
