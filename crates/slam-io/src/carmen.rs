//! CARMEN laser logs, plain or gzip-compressed (recognised by content, not by name).
//!
//! Records read (space separated, one per line; `#` starts a comment):
//!
//! ```text
//! FLASER N r_1 … r_N  x y θ  odom_x odom_y odom_θ  ipc_timestamp hostname logger_timestamp
//! RLASER (same as FLASER, rear laser)
//! ROBOTLASER1 laser_type start_angle fov angular_res max_range accuracy remission_mode
//!             N r_1 … r_N  M rem_1 … rem_M  laser_x laser_y laser_θ  robot_x robot_y robot_θ
//!             tv rv forward_safety_dist side_safety_dist turn_axis
//!             ipc_timestamp hostname logger_timestamp
//! ROBOTLASER2 (same as ROBOTLASER1, second laser)
//! RAWLASER1 … RAWLASER4 laser_type start_angle fov angular_res max_range accuracy
//!             remission_mode N r_1 … r_N  M rem_1 … rem_M  ipc_timestamp hostname logger_timestamp
//! ODOM x y θ tv rv accel ipc_timestamp hostname logger_timestamp
//! TRUEPOS true_x true_y true_θ odom_x odom_y odom_θ ipc_timestamp hostname logger_timestamp
//! PARAM name value [hostname timestamp]
//! ```
//!
//! Every laser or `ODOM` line becomes one [`ScanRecord`] in file order, at its
//! `ipc_timestamp`, with the odometry (robot) pose of the line; `TRUEPOS` lines form the
//! ground truth; `PARAM` lines are collected in [`CarmenLog::params`]. Any other record
//! type (`NEFF`, `SYNC`, …) is counted in [`CarmenLog::unknown_records`], not an error.
//! Times may repeat or step back (kept in file order).
//!
//! **Raw lasers.** A `RAWLASER*` line has no pose. `RAWLASER1` (front laser) and
//! `RAWLASER2` (rear laser) scans get the odometry pose interpolated linearly in time between
//! the `ODOM` records before and after them in file order (the nearer one's pose outside
//! that interval; an error when the log has no `ODOM` record), and the laser offset of the
//! `robot_frontlaser_offset` / `robot_rearlaser_offset` PARAM. CARMEN loggers write the same
//! scan both raw and with poses, so `RAWLASER1` is left out when the log has `ROBOTLASER1`
//! or `FLASER` records, and `RAWLASER2` when it has `ROBOTLASER2` or `RLASER` records.
//! `RAWLASER3`/`RAWLASER4` are read and checked but left out: the log does not say where
//! those lasers are mounted. What is left out is listed in [`CarmenLog::not_used`].
//!
//! **Usable scans.** A log without a single scan with a reading below its max range (only
//! `ODOM`, or only no-return readings) is refused at load, with the count of each record
//! type it holds: a filter would otherwise run on odometry alone and build an empty map.
//!
//! **Beam geometry.** `ROBOTLASER1` states it. `FLASER`/`RLASER` lines do not: beam k
//! points at −90° + k·res with res = 180°/N for N = 180 or 360 and 180°/(N−1) otherwise
//! ([`LaserScan::flaser_geometry`]); a rear laser looks backwards (sensor heading π).
//!
//! **No return.** `ROBOTLASER1` gives `max_range`, and readings ≥ it are no-return. For
//! `FLASER`/`RLASER` the no-return value is inferred from the log: the logger writes the
//! laser's maximum code for every beam without an echo (81.83, 81.91, 51.1, … in the Radish
//! logs), so it is a reading of at least 20 m that **recurs**: the largest far reading
//! (≥ 20 m) that occurs at least twice and at least 1/100 as often as the most frequent far
//! reading: the no-return **code**. A reading that occurs once (a glitch, a corrupted
//! value) therefore never moves the threshold of the whole log. When no far reading recurs
//! that often, the most frequent one is taken (the larger on a tie); when no reading
//! reaches 20 m the log is taken to hold no no-return reading and the code is 81.91 m (the
//! SICK one). Some loggers write the code with **jitter**: the Edmonton log's no-return
//! readings are 51.09 … 51.16 m (2,991 at 51.15, 211 at 51.14, 94 at 51.10, 61 at 51.16),
//! FHW's 51.05 and 51.10 m, Acapulco's 51.09 … 51.16 m, and Freiburg-101 writes 81.83
//! beside 81.91 m; the nearest other reading is 0.2 m or more below such a band on every
//! Radish log. So every far reading within 0.15 m below the code is taken as no return
//! too: `max_range` = the smallest reading in [code − 0.15 m, code]; readings at or above
//! it are no-return, readings below it hits. On the Radish logs the code is the tables'
//! value (except Acapulco, whose largest reading, 51.25 m, occurs once among 9,264 readings
//! of 51.15 m, the code), and `max_range` is 81.83 (Intel, Freiburg-101), 81.91 (CSAIL,
//! Belgioioso), 51.05 (FHW) and 51.09 m (Edmonton, Acapulco).
//!
//! **Bounds** ([`crate::bounds`]): poses within ±10⁶ m and headings within ±10⁴ rad;
//! readings and `max_range` within 0 … 1000 m (`max_range` > 0); a stated start angle within
//! ±2π, field of view within 0 … 2π + 0.1 rad, angular resolution within ±π, non-zero, and
//! consistent with the field of view and N (see `check_geometry`); `tv`, `rv`, `accel`
//! within ±100 m/s, rad/s, m/s²; `ipc_timestamp` within ±10¹⁰ s (no span check: the real
//! GMapping logs hold single records stamped 0, −2.88 or 7e-77 among Unix times, kept in
//! file order as every time is); laser offset PARAMs within
//! ±10 m; every other number within ±10¹²; N and M at most 100,000. A violation is an error naming the file, line, field and bound.
//!
//! **Laser offset.** The sensor pose in the robot frame is the laser pose ⊖ the robot
//! (odometry) pose of the same line. If those two poses are more than 1 m apart they are not
//! in the same frame, and the `robot_frontlaser_offset` / `robot_rearlaser_offset` PARAM
//! (forward offset, metres; 0 when absent) is used instead.

use crate::bounds::{MAX_BEAMS, MAX_RANGE, MAX_SPEED, MAX_TIME, MAX_TURN_RATE};
use crate::error::IoError;
use crate::text::{read_text, write_text, Line, TextFile};
use slam_models::{LaserScan, Pose2, ScanDataset, ScanRecord, TimedPose};
use std::collections::{BTreeMap, HashMap};
use std::f64::consts::{PI, TAU};
use std::fmt::Write as _;
use std::path::Path;

/// Largest reading below which a FLASER log is taken to have no no-return readings, m.
const NO_RETURN_MIN: f64 = 20.0;
/// A no-return code occurs at least 1/this as often as the most frequent far reading.
const NO_RETURN_SHARE: usize = 100;
/// The SICK LMS no-return reading, used when a log shows none, m.
const SICK_NO_RETURN: f64 = 81.91;
/// Far readings this close below the no-return code are the code written with jitter, m
/// (the widest band seen, Edmonton's and Acapulco's 51.09 … 51.16 m, is 0.07 m wide).
const NO_RETURN_JITTER: f64 = 0.15;
/// Largest field of view of a stated beam geometry, rad: one turn plus a beam's width.
const MAX_FOV: f64 = TAU + 0.1;
/// Largest `robot_frontlaser_offset` / `robot_rearlaser_offset` PARAM, m.
const MAX_PARAM_OFFSET: f64 = 10.0;
/// Laser and robot poses further apart than this are in different frames, m.
const MAX_LASER_OFFSET: f64 = 1.0;

/// A CARMEN log as read.
#[derive(Debug, Clone, PartialEq)]
pub struct CarmenLog {
    /// The records (one per laser or ODOM line) and the TRUEPOS ground truth, if any.
    pub dataset: ScanDataset,
    /// Record types not understood, with how many lines of each were seen.
    pub unknown_records: BTreeMap<String, usize>,
    /// Lines of each understood record type.
    pub record_counts: BTreeMap<String, usize>,
    /// Understood record types whose records are not in the dataset, with why (`RAWLASER1`
    /// when the log has the same scans as `ROBOTLASER1`/`FLASER`, and likewise `RAWLASER2`;
    /// `RAWLASER3`/`RAWLASER4`, whose mounting the log does not state).
    pub not_used: BTreeMap<String, String>,
    /// PARAM name → value (the last one wins).
    pub params: BTreeMap<String, String>,
    /// The no-return threshold of the FLASER/RLASER scans (their `max_range`: a reading at
    /// or above it is no return), if the log has any; see the module docs.
    pub flaser_max_range: Option<f64>,
}

impl CarmenLog {
    /// A one-line description: record counts, scans, beams, no-return value, ground truth
    /// and unknown record types.
    pub fn summary(&self, path: &Path) -> String {
        let recs = &self.dataset.records;
        let scans: Vec<&LaserScan> = recs.iter().filter_map(|r| r.scan.as_ref()).collect();
        let mut beams: Vec<usize> = scans.iter().map(|s| s.len()).collect();
        beams.sort_unstable();
        beams.dedup();
        let counts: Vec<String> = self
            .record_counts
            .iter()
            .map(|(k, v)| format!("{v} {k}"))
            .collect();
        let mut s = format!(
            "CARMEN log {}: {} records ({}), {} scans with {:?} beams, {}",
            path.display(),
            recs.len(),
            counts.join(", "),
            scans.len(),
            beams,
            match (recs.first(), recs.last()) {
                (Some(a), Some(b)) => format!("t = {} … {} s", a.t, b.t),
                _ => "no records".into(),
            }
        );
        if let Some(m) = self.flaser_max_range {
            s.push_str(&format!(", no return at or above {m} m"));
        }
        s.push_str(match &self.dataset.ground_truth {
            Some(_) => ", TRUEPOS ground truth",
            None => ", no ground truth",
        });
        for (k, why) in &self.not_used {
            s.push_str(&format!("; {k} records not used ({why})"));
        }
        if !self.unknown_records.is_empty() {
            let u: Vec<String> = self
                .unknown_records
                .iter()
                .map(|(k, v)| format!("{v} {k}"))
                .collect();
            s.push_str(&format!("; unknown records ignored: {}", u.join(", ")));
        }
        s
    }
}

/// Reads a CARMEN log (plain or gzip). Errors: malformed line (file, line, expected
/// field), NaN/∞, negative range, truncated or corrupt gzip, a log without any laser or
/// ODOM record.
pub fn read_carmen(path: &Path) -> Result<CarmenLog, IoError> {
    parse_carmen(&read_text(path)?)
}

/// Which laser a FLASER-style line came from.
#[derive(Clone, Copy, PartialEq)]
enum Laser {
    Front,
    Rear,
}

fn pose(l: &mut Line<'_>, what: &str) -> Result<Pose2, IoError> {
    let x = l.coord(&format!("{what} x"))?;
    let y = l.coord(&format!("{what} y"))?;
    let th = l.heading(&format!("{what} theta"))?;
    Ok(Pose2::new(x, y, th))
}

/// `ipc_timestamp hostname logger_timestamp` → the ipc timestamp.
fn stamp(l: &mut Line<'_>) -> Result<f64, IoError> {
    let t = l.f64_in("ipc_timestamp", -MAX_TIME, MAX_TIME, "s")?;
    l.word("hostname")?;
    l.f64_in("logger_timestamp", -MAX_TIME, MAX_TIME, "s")?;
    Ok(t)
}

/// `tv rv` (m/s, rad/s) within [`MAX_SPEED`] and [`MAX_TURN_RATE`].
fn velocities(l: &mut Line<'_>) -> Result<(), IoError> {
    l.f64_in("tv", -MAX_SPEED, MAX_SPEED, "m/s")?;
    l.f64_in("rv", -MAX_TURN_RATE, MAX_TURN_RATE, "rad/s")?;
    Ok(())
}

fn count(l: &mut Line<'_>, what: &str) -> Result<usize, IoError> {
    let n = l.u64(what)?;
    usize::try_from(n)
        .ok()
        .filter(|&n| n <= MAX_BEAMS)
        .ok_or_else(|| l.error(format!("{what} ≤ {MAX_BEAMS}"), &n.to_string()))
}

fn ranges(l: &mut Line<'_>, n: usize) -> Result<Vec<f64>, IoError> {
    let mut r = Vec::with_capacity(n);
    for k in 0..n {
        let v = l.range(&format!("range reading {} of {n}", k + 1))?;
        if v < 0.0 {
            return Err(l.error("a non-negative range reading", &v.to_string()));
        }
        r.push(v);
    }
    Ok(r)
}

/// The no-return threshold of a FLASER/RLASER log (see the module docs): the smallest far
/// reading within [`NO_RETURN_JITTER`] below the log's no-return code ([`no_return_code`]),
/// so that a code written with jitter is no return in all its variants; the code itself
/// when no reading is that far. Deterministic: the choice depends on the counts only.
fn no_return_value(far_readings: &HashMap<u64, usize>) -> f64 {
    let code = no_return_code(far_readings);
    far_readings
        .keys()
        .map(|&bits| f64::from_bits(bits))
        .filter(|&v| v <= code && v >= code - NO_RETURN_JITTER)
        .fold(code, f64::min)
}

/// The no-return code of a FLASER/RLASER log: the largest reading of at least
/// [`NO_RETURN_MIN`] that occurs at least `max(2, mode_count / 100)` times, where
/// `mode_count` is how often the most frequent such reading occurs; the most frequent
/// reading itself (the larger on a tie) when none does; [`SICK_NO_RETURN`] when no reading
/// is that far.
fn no_return_code(far_readings: &HashMap<u64, usize>) -> f64 {
    let by_count = |a: &(usize, f64), b: &(usize, f64)| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1));
    let counted = || {
        far_readings
            .iter()
            .map(|(&bits, &n)| (n, f64::from_bits(bits)))
    };
    let Some(mode) = counted().max_by(by_count) else {
        return SICK_NO_RETURN;
    };
    let need = (mode.0 / NO_RETURN_SHARE).max(2);
    counted()
        .filter(|&(n, _)| n >= need)
        .map(|(_, v)| v)
        .max_by(f64::total_cmp)
        .unwrap_or(mode.1)
}

/// Checks a stated beam geometry: for N ≥ 2 beams the angular resolution is non-zero, the
/// N − 1 steps span at most one turn, and the field of view agrees with it to half a beam:
/// (N − 1.5)·|res| ≤ fov ≤ (N + 0.5)·|res|, which admits both the fov = N·|res| and the
/// fov = (N − 1)·|res| conventions of CARMEN loggers.
fn check_geometry(l: &Line<'_>, fov: f64, res: f64, n: usize) -> Result<(), IoError> {
    if n < 2 {
        return Ok(());
    }
    let steps = (n - 1) as f64;
    if res == 0.0 || steps * res.abs() > TAU + 1e-9 {
        return Err(l.out_of_bounds(
            "angular_res",
            res,
            format!(
                "a non-zero resolution whose {} steps span at most 2π rad",
                n - 1
            ),
        ));
    }
    let (lo, hi) = ((steps - 0.5) * res.abs(), (steps + 1.5) * res.abs());
    if !(lo - 1e-9..=hi + 1e-9).contains(&fov) {
        return Err(l.out_of_bounds(
            "fov",
            fov,
            format!(
                "(N − 1.5)·|angular_res| … (N + 0.5)·|angular_res| = {lo} … {hi} rad for N = {n}"
            ),
        ));
    }
    Ok(())
}

/// `laser_type start_angle fov angular_res max_range accuracy remission_mode N r_1 … r_N
/// M rem_1 … rem_M`, the laser part of `ROBOTLASER*` and `RAWLASER*` records, as a scan in
/// the sensor frame (sensor pose identity).
fn stated_scan(l: &mut Line<'_>) -> Result<LaserScan, IoError> {
    l.f64("laser_type")?;
    let angle_min = l.angle("start_angle")?;
    let fov = l.f64_in("fov", 0.0, MAX_FOV, "rad")?;
    let angle_increment = l.f64_in("angular_res", -PI, PI, "rad")?;
    let max_range = l.f64_in("max_range", 0.0, MAX_RANGE, "m")?;
    l.f64("accuracy")?;
    l.f64("remission_mode")?;
    let n = count(l, "number of readings N")?;
    check_geometry(l, fov, angle_increment, n)?;
    let r = ranges(l, n)?;
    let m = count(l, "number of remissions M")?;
    for k in 0..m {
        l.f64(&format!("remission {} of {m}", k + 1))?;
    }
    if max_range <= 0.0 {
        return Err(l.error("max_range > 0", &max_range.to_string()));
    }
    Ok(LaserScan {
        angle_min,
        angle_increment,
        ranges: r,
        max_range,
        sensor_pose: Pose2::IDENTITY,
    })
}

/// A `RAWLASER*` scan: no pose of its own; placed (or dropped) after the whole log is read.
struct RawPending {
    record: usize,
    kind: String,
    line: usize,
}

/// The odometry pose at time `t` between two ODOM records `a` (before) and `b` (after, in
/// file order): linear in x, y and in the normalised heading difference when
/// `a.t ≤ t ≤ b.t` and `a.t < b.t`, otherwise `a`'s pose.
fn interpolate(a: &ScanRecord, b: &ScanRecord, t: f64) -> Pose2 {
    if !(a.t < b.t && (a.t..=b.t).contains(&t)) {
        return a.odometry;
    }
    let s = (t - a.t) / (b.t - a.t);
    let (p, q) = (a.odometry, b.odometry);
    Pose2::new(
        p.x + s * (q.x - p.x),
        p.y + s * (q.y - p.y),
        p.theta + s * slam_models::normalize_angle(q.theta - p.theta),
    )
}

/// A pending FLASER/RLASER scan whose `max_range` is set after the whole log is read.
struct Pending {
    record: usize,
    laser: Laser,
    laser_pose: Pose2,
}

pub(crate) fn parse_carmen(f: &TextFile) -> Result<CarmenLog, IoError> {
    f.ensure_not_empty("CARMEN records")?;
    let mut records: Vec<ScanRecord> = Vec::new();
    let mut truth: Vec<TimedPose> = Vec::new();
    let mut unknown: BTreeMap<String, usize> = BTreeMap::new();
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    let mut params: BTreeMap<String, String> = BTreeMap::new();
    let mut pending: Vec<Pending> = Vec::new();
    let mut raw: Vec<RawPending> = Vec::new();
    // FLASER/RLASER readings ≥ NO_RETURN_MIN: bit pattern → count (for the mode).
    let mut far_readings: HashMap<u64, usize> = HashMap::new();
    for mut l in f.data_lines() {
        let kind = l.word("a record type")?;
        match kind {
            "FLASER" | "RLASER" => {
                let n = count(&mut l, "number of readings N")?;
                let r = ranges(&mut l, n)?;
                let laser_pose = pose(&mut l, "laser pose")?;
                let odom = pose(&mut l, "odometry pose")?;
                let t = stamp(&mut l)?;
                l.end("the FLASER fields")?;
                for &v in r.iter().filter(|&&v| v >= NO_RETURN_MIN) {
                    *far_readings.entry(v.to_bits()).or_insert(0) += 1;
                }
                let (angle_min, angle_increment) = LaserScan::flaser_geometry(n);
                pending.push(Pending {
                    record: records.len(),
                    laser: if kind == "FLASER" {
                        Laser::Front
                    } else {
                        Laser::Rear
                    },
                    laser_pose,
                });
                records.push(ScanRecord {
                    t,
                    odometry: odom,
                    scan: Some(LaserScan {
                        angle_min,
                        angle_increment,
                        ranges: r,
                        max_range: SICK_NO_RETURN,
                        sensor_pose: Pose2::IDENTITY,
                    }),
                });
            }
            "ROBOTLASER1" | "ROBOTLASER2" => {
                let mut scan = stated_scan(&mut l)?;
                let laser_pose = pose(&mut l, "laser pose")?;
                let robot = pose(&mut l, "robot pose")?;
                velocities(&mut l)?;
                for w in ["forward_safety_dist", "side_safety_dist", "turn_axis"] {
                    l.f64(w)?;
                }
                let t = stamp(&mut l)?;
                l.end(&format!("the {kind} fields"))?;
                scan.sensor_pose = robot.between(&laser_pose);
                records.push(ScanRecord {
                    t,
                    odometry: robot,
                    scan: Some(scan),
                });
            }
            "RAWLASER1" | "RAWLASER2" | "RAWLASER3" | "RAWLASER4" => {
                let scan = stated_scan(&mut l)?;
                let t = stamp(&mut l)?;
                l.end(&format!("the {kind} fields"))?;
                raw.push(RawPending {
                    record: records.len(),
                    kind: kind.to_string(),
                    line: l.no,
                });
                records.push(ScanRecord {
                    t,
                    odometry: Pose2::IDENTITY,
                    scan: Some(scan),
                });
            }
            "ODOM" => {
                let odom = pose(&mut l, "odometry pose")?;
                velocities(&mut l)?;
                l.f64_in("accel", -MAX_SPEED, MAX_SPEED, "m/s²")?;
                let t = stamp(&mut l)?;
                l.end("the ODOM fields")?;
                records.push(ScanRecord {
                    t,
                    odometry: odom,
                    scan: None,
                });
            }
            "TRUEPOS" => {
                let p = pose(&mut l, "true pose")?;
                pose(&mut l, "odometry pose")?;
                let t = stamp(&mut l)?;
                l.end("the TRUEPOS fields")?;
                truth.push(TimedPose { t, pose: p });
            }
            "PARAM" => {
                let name = l.word("parameter name")?;
                let value = l.word("parameter value")?;
                if name == "robot_frontlaser_offset" || name == "robot_rearlaser_offset" {
                    let v: f64 = value
                        .parse()
                        .map_err(|_| l.error(format!("{name} (a number, m)"), value))?;
                    if !v.is_finite() || v.abs() > MAX_PARAM_OFFSET {
                        return Err(l.out_of_bounds(
                            name,
                            v,
                            format!("-{MAX_PARAM_OFFSET} … {MAX_PARAM_OFFSET} m"),
                        ));
                    }
                }
                params.insert(name.to_string(), value.to_string());
            }
            other => {
                // Kept shortened: a "record type" can be a whole line of gigabytes (a gzip of
                // zeros), which must not be copied, listed or echoed whole.
                *unknown.entry(crate::text::shorten(other)).or_insert(0) += 1;
                continue;
            }
        }
        *counts.entry(kind.to_string()).or_insert(0) += 1;
    }
    if records.is_empty() && !unknown.is_empty() {
        let seen: Vec<String> = unknown
            .iter()
            .take(5)
            .map(|(k, v)| format!("{v}× {k:?}"))
            .collect();
        return Err(IoError::invalid(
            &f.path,
            format!(
                "not a CARMEN log: no FLASER, RLASER, ROBOTLASER1 or ODOM record; line types seen: {}",
                seen.join(", ")
            ),
        ));
    }
    if records.is_empty() {
        return Err(IoError::Empty {
            path: f.path.clone(),
            expected: "at least one FLASER, RLASER, ROBOTLASER1 or ODOM record".into(),
        });
    }
    let flaser_max_range = (!pending.is_empty()).then(|| no_return_value(&far_readings));
    // Checked on their PARAM lines: numbers within ±MAX_PARAM_OFFSET.
    let param_offset = |name: &str| -> f64 {
        params
            .get(name)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    let front = Pose2::new(param_offset("robot_frontlaser_offset"), 0.0, 0.0);
    let rear = Pose2::new(
        param_offset("robot_rearlaser_offset"),
        0.0,
        std::f64::consts::PI,
    );
    // RAWLASER scans: placed by the ODOM records around them, or left out (see module docs).
    let count_of = |k: &str| counts.get(k).copied().unwrap_or(0);
    let mut not_used: BTreeMap<String, String> = BTreeMap::new();
    let mut keep = vec![true; records.len()];
    let odom_at: Vec<usize> = (0..records.len())
        .filter(|&i| records[i].scan.is_none())
        .collect();
    for p in &raw {
        let why = match p.kind.as_str() {
            "RAWLASER1" if count_of("ROBOTLASER1") + count_of("FLASER") > 0 => {
                Some("the same scans as the log's ROBOTLASER1/FLASER records, which carry poses")
            }
            "RAWLASER2" if count_of("ROBOTLASER2") + count_of("RLASER") > 0 => {
                Some("the same scans as the log's ROBOTLASER2/RLASER records, which carry poses")
            }
            "RAWLASER3" | "RAWLASER4" => Some("the log does not say where this laser is mounted"),
            _ => None,
        };
        if let Some(why) = why {
            keep[p.record] = false;
            not_used.insert(p.kind.clone(), why.to_string());
            continue;
        }
        let k = odom_at.partition_point(|&i| i < p.record);
        let before = k.checked_sub(1).map(|j| &records[odom_at[j]]);
        let after = odom_at.get(k).map(|&i| &records[i]);
        let t = records[p.record].t;
        let odometry = match (before, after) {
            (Some(a), Some(b)) => interpolate(a, b, t),
            (Some(a), None) => a.odometry,
            (None, Some(b)) => b.odometry,
            (None, None) => {
                return Err(IoError::Parse {
                    path: f.path.clone(),
                    line: p.line,
                    expected: format!("ODOM records in the log to give the {} scan a pose", p.kind),
                    found: "a log without ODOM records".into(),
                })
            }
        };
        let rec = &mut records[p.record];
        rec.odometry = odometry;
        if let Some(scan) = rec.scan.as_mut() {
            scan.sensor_pose = if p.kind == "RAWLASER1" { front } else { rear };
        }
    }
    for p in pending {
        let rec = &mut records[p.record];
        let mut sensor = rec.odometry.between(&p.laser_pose);
        if sensor.x.hypot(sensor.y) > MAX_LASER_OFFSET {
            sensor = if p.laser == Laser::Front { front } else { rear };
        } else if p.laser == Laser::Rear && sensor.theta.abs() < std::f64::consts::FRAC_PI_2 {
            // A rear laser whose logged pose carries the robot heading looks backwards.
            sensor = sensor.compose(&Pose2::new(0.0, 0.0, std::f64::consts::PI));
        }
        if let Some(scan) = rec.scan.as_mut() {
            scan.sensor_pose = sensor;
            scan.max_range = flaser_max_range.unwrap_or(SICK_NO_RETURN);
        }
    }
    let mut k = 0;
    records.retain(|_| {
        k += 1;
        keep[k - 1]
    });
    let usable = records
        .iter()
        .filter_map(|r| r.scan.as_ref())
        .filter(|s| (0..s.len()).any(|k| s.is_hit(k)))
        .count();
    if usable == 0 {
        let mut held: Vec<String> = counts
            .iter()
            .chain(unknown.iter())
            .map(|(k, v)| format!("{v} {k}"))
            .collect();
        held.extend(
            not_used
                .iter()
                .map(|(k, why)| format!("({k} not used: {why})")),
        );
        return Err(IoError::invalid(
            &f.path,
            format!(
                "no usable laser scan (a FLASER, RLASER, ROBOTLASER1/2 or RAWLASER1/2 record with \
                 a reading below its max range); the log holds {}",
                held.join(", ")
            ),
        ));
    }
    let name = f
        .path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = name
        .trim_end_matches(".gz")
        .trim_end_matches(".log")
        .trim_end_matches(".clf")
        .to_string();
    Ok(CarmenLog {
        dataset: ScanDataset {
            name,
            records,
            ground_truth: (!truth.is_empty()).then_some(truth),
        },
        unknown_records: unknown,
        record_counts: counts,
        not_used,
        params,
        flaser_max_range,
    })
}

/// Writes a scan dataset as a CARMEN log (gzip-compressed when the name ends in `.gz`):
/// records with a scan as `ROBOTLASER1` (which states the beam geometry, `max_range` and,
/// through the laser pose = odometry ⊕ sensor pose, the laser offset), records without as
/// `ODOM`, and the ground truth as `TRUEPOS` lines merged in by time. Numbers use shortest
/// round-trip formatting, so [`read_carmen`] gives back the same data (the sensor pose up
/// to floating-point rounding, ~1e-15). Errors on non-finite values.
pub fn write_carmen(path: &Path, d: &ScanDataset) -> Result<(), IoError> {
    let mut s = String::new();
    s.push_str("# CARMEN log written by slam-rs (slam-io)\n");
    s.push_str("# message formats used: ROBOTLASER1 ODOM TRUEPOS\n");
    let truth = d.ground_truth.as_deref().unwrap_or(&[]);
    let mut g = 0;
    let bad = |what: String| IoError::invalid(path, what);
    for (i, r) in d.records.iter().enumerate() {
        if !(r.t.is_finite() && r.odometry.is_finite()) {
            return Err(bad(format!("record {i} has a non-finite time or pose")));
        }
        while g < truth.len() && truth[g].t <= r.t {
            write_truepos(&mut s, &truth[g], &r.odometry);
            g += 1;
        }
        let o = r.odometry;
        match &r.scan {
            None => {
                let _ = writeln!(
                    s,
                    "ODOM {} {} {} 0 0 0 {} slam-rs {}",
                    o.x, o.y, o.theta, r.t, r.t
                );
            }
            Some(scan) => {
                scan.validate()
                    .map_err(|e| bad(format!("record {i}: {e}")))?;
                if !scan.sensor_pose.is_finite() {
                    return Err(bad(format!("record {i}: non-finite sensor pose")));
                }
                let lp = o.compose(&scan.sensor_pose);
                let fov = scan.angle_increment * (scan.len().max(1) - 1) as f64;
                let _ = write!(
                    s,
                    "ROBOTLASER1 0 {} {} {} {} 0.01 0 {}",
                    scan.angle_min,
                    fov,
                    scan.angle_increment,
                    scan.max_range,
                    scan.len()
                );
                for v in &scan.ranges {
                    let _ = write!(s, " {v}");
                }
                let _ = writeln!(
                    s,
                    " 0 {} {} {} {} {} {} 0 0 0 0 0 {} slam-rs {}",
                    lp.x, lp.y, lp.theta, o.x, o.y, o.theta, r.t, r.t
                );
            }
        }
    }
    let last = d.records.last().map(|r| r.odometry).unwrap_or_default();
    for p in &truth[g..] {
        write_truepos(&mut s, p, &last);
    }
    write_text(path, &s)
}

fn write_truepos(s: &mut String, p: &TimedPose, odom: &Pose2) {
    let _ = writeln!(
        s,
        "TRUEPOS {} {} {} {} {} {} {} slam-rs {}",
        p.pose.x, p.pose.y, p.pose.theta, odom.x, odom.y, odom.theta, p.t, p.t
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::text::from_str;

    #[test]
    fn flaser_geometry_no_return_and_unknowns() {
        let text = "# c\nPARAM robot_frontlaser_offset 0.0 nohost 0\n\
            ODOM 1 2 0.5 0 0 0 10.0 h 10.0\n\
            FLASER 3 1.0 81.91 2.5 1 2 0.5 1 2 0.5 10.1 h 10.1\n\
            NEFF 12.5\nNEFF 3\nSYNC x\n\
            FLASER 3 80.0 1 2 1 2 0.5 1 2 0.5 10.2 h 10.2\n";
        let log = parse_carmen(&from_str("a.log", text)).unwrap();
        let r = &log.dataset.records;
        assert_eq!(r.len(), 3);
        assert_eq!(r[0].t, 10.0);
        assert!(r[0].scan.is_none());
        let s = r[1].scan.as_ref().unwrap();
        // 3 beams: −90°, 0°, +90°.
        assert!((s.beam_angle(0) + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!(s.beam_angle(1).abs() < 1e-12);
        assert_eq!(s.max_range, 81.91);
        assert!(s.is_hit(0) && !s.is_hit(1) && s.is_hit(2));
        assert!(r[2].scan.as_ref().unwrap().is_hit(0));
        assert_eq!(s.sensor_pose, Pose2::IDENTITY);
        assert_eq!(log.unknown_records.get("NEFF"), Some(&2));
        assert_eq!(log.unknown_records.get("SYNC"), Some(&1));
        assert_eq!(
            log.params
                .get("robot_frontlaser_offset")
                .map(String::as_str),
            Some("0.0")
        );
        assert_eq!(log.record_counts.get("FLASER"), Some(&2));
    }

    /// A no-return code written with jitter (as in the Edmonton and FHW logs): every far
    /// reading within 0.15 m below the code is no return, the readings further below are
    /// hits, and a single larger reading moves nothing.
    #[test]
    fn a_jittered_no_return_code_is_no_return_in_all_its_variants() {
        // Code 51.15 (40 times), jitter 51.09 … 51.16 below and above it; genuine returns
        // at 50.95 and 50.75 (0.20 and 0.40 m below the code); one glitch at 51.25.
        let mut text = String::new();
        for k in 0..10 {
            let far = if k == 0 { "51.25" } else { "51.16" };
            let _ = writeln!(
                text,
                "FLASER 6 51.15 51.15 51.15 51.15 {} {} 0 0 0 0 0 0 {k} h {k}",
                ["51.14", "51.09", "51.1", "50.95", "50.75"][k % 5],
                far
            );
        }
        let log = parse_carmen(&from_str("j.log", &text)).unwrap();
        assert_eq!(log.flaser_max_range, Some(51.09));
        let hits: Vec<(f64, bool)> = log
            .dataset
            .records
            .iter()
            .filter_map(|r| r.scan.as_ref())
            .flat_map(|s| (0..s.len()).map(move |k| (s.ranges[k], s.is_hit(k))))
            .collect();
        for (r, hit) in hits {
            assert_eq!(hit, r < 51.0, "reading {r}");
        }
        // Without jitter the code itself is the threshold (Intel: 81.83, nothing near it).
        let text = "FLASER 3 81.83 81.83 24.07 0 0 0 0 0 0 1 h 1\n\
            FLASER 3 81.83 81.6 81.83 0 0 0 0 0 0 2 h 2\n";
        let log = parse_carmen(&from_str("i.log", text)).unwrap();
        assert_eq!(log.flaser_max_range, Some(81.83));
        assert!(log.dataset.records[1].scan.as_ref().unwrap().is_hit(1));
    }

    #[test]
    fn rear_laser_and_offsets() {
        // RLASER with the robot's heading in its pose: the sensor looks backwards.
        // FLASER whose laser pose is 0.2 m ahead of the robot (heading 90°): offset (0.2, 0).
        // FLASER in another frame (laser pose 50 m away): the PARAM offset is used.
        let text = "PARAM robot_frontlaser_offset 0.1\n\
            RLASER 2 1 2 0 0 0 0 0 0 1 h 1\n\
            FLASER 2 1 2 1 2.2 1.5707963267948966 1 2 1.5707963267948966 2 h 2\n\
            FLASER 2 1 2 50 50 0 0 0 0 3 h 3\n";
        let log = parse_carmen(&from_str("r.log", text)).unwrap();
        let s: Vec<&LaserScan> = log
            .dataset
            .records
            .iter()
            .map(|r| r.scan.as_ref().unwrap())
            .collect();
        assert!(s[0]
            .sensor_pose
            .approx_eq(&Pose2::new(0.0, 0.0, std::f64::consts::PI), 1e-12));
        assert!(s[1]
            .sensor_pose
            .approx_eq(&Pose2::new(0.2, 0.0, 0.0), 1e-12));
        assert!(s[2]
            .sensor_pose
            .approx_eq(&Pose2::new(0.1, 0.0, 0.0), 1e-12));
        // Largest reading 2 m < 20 m: no reading is taken as "no return".
        assert_eq!(log.flaser_max_range, Some(81.91));
        assert!(s[0].is_hit(1));
    }

    #[test]
    fn raw_lasers_are_placed_by_odometry_or_left_out() {
        let raw = |t: f64| {
            format!("RAWLASER1 0 -1.5707963 3.1415926 1.5707963 30 0.01 0 3 1 2 30 0 {t} h {t}\n")
        };
        // Odometry at t = 10 (x = 0) and t = 12 (x = 2, heading 0.2): a scan at t = 11 sits
        // half-way; one before the first ODOM takes the first pose.
        let text = format!(
            "PARAM robot_frontlaser_offset 0.25\n{}ODOM 0 0 0 0 0 0 10 h 10\n{}\
             ODOM 2 0 0.2 0 0 0 12 h 12\n{}",
            raw(9.0),
            raw(11.0),
            raw(13.0)
        );
        let log = parse_carmen(&from_str("raw.log", &text)).unwrap();
        let r = &log.dataset.records;
        assert_eq!(r.len(), 5);
        assert!(r[0].odometry.approx_eq(&Pose2::IDENTITY, 1e-12));
        assert!(r[2].odometry.approx_eq(&Pose2::new(1.0, 0.0, 0.1), 1e-12));
        assert!(r[4].odometry.approx_eq(&Pose2::new(2.0, 0.0, 0.2), 1e-12));
        let s = r[2].scan.as_ref().unwrap();
        assert_eq!((s.len(), s.max_range), (3, 30.0));
        assert!(s.is_hit(1) && !s.is_hit(2));
        assert_eq!(s.sensor_pose, Pose2::new(0.25, 0.0, 0.0));
        assert!(log.not_used.is_empty());
        // With ROBOTLASER1 records (the same scans with poses) RAWLASER1 is left out, and
        // RAWLASER3 always is; both are said.
        let text = format!(
            "{}ROBOTLASER1 0 -1.5 0.02 0.01 80 0.01 0 2 1 2 0 0 0 0 0 0 0 0 0 0 0 0 5 h 5\n\
             RAWLASER3 0 -1.5 0.02 0.01 80 0.01 0 2 1 2 0 5 h 5\nODOM 0 0 0 0 0 0 5 h 5\n",
            raw(5.0)
        );
        let log = parse_carmen(&from_str("both.log", &text)).unwrap();
        assert_eq!(log.dataset.records.len(), 2);
        assert_eq!(log.record_counts.get("RAWLASER1"), Some(&1));
        let summary = log.summary(Path::new("both.log"));
        assert!(
            summary.contains("RAWLASER1 records not used")
                && summary.contains("RAWLASER3 records not used"),
            "{summary}"
        );
        // Raw scans and no ODOM: nothing gives them a pose.
        let e = parse_carmen(&from_str("x.log", &raw(1.0)))
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.log:1") && e.contains("ODOM records"), "{e}");
    }

    #[test]
    fn a_log_without_usable_scans_is_refused_with_what_it_holds() {
        for (text, want) in [
            (
                "ODOM 0 0 0 0 0 0 1 h 1\nODOM 1 0 0 0 0 0 2 h 2\nNEFF 3\n",
                "the log holds 2 ODOM, 1 NEFF",
            ),
            (
                "ODOM 0 0 0 0 0 0 1 h 1\nRAWLASER3 0 -1.5 0.02 0.01 80 0.01 0 2 1 2 0 1 h 1\n",
                "(RAWLASER3 not used: the log does not say where",
            ),
            // Every reading a no-return (≥ max_range 80).
            (
                "ROBOTLASER1 0 -1.5 0.02 0.01 80 0.01 0 2 80 81 0 0 0 0 0 0 0 0 0 0 0 0 5 h 5\n",
                "1 ROBOTLASER1",
            ),
        ] {
            let e = parse_carmen(&from_str("o.log", text))
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("o.log: no usable laser scan") && e.contains(want),
                "{e}"
            );
        }
    }

    #[test]
    fn error_paths() {
        for (text, want) in [
            ("", "empty"),
            ("# only a comment\n", "empty"),
            ("NEFF 1\n", "not a CARMEN log"),
            ("PARAM a b\n", "at least one"),
            ("ODOM 1 2 3 0 0 0 5 h\n", "logger_timestamp"),
            ("ODOM 1 2 3 0 0 0 5 h 5 extra\n", "end of line"),
            ("ODOM 1 2 nan 0 0 0 5 h 5\n", "not finite"),
            ("FLASER 3 1 2\n", "range reading 3 of 3"),
            ("FLASER 2 1 -2 0 0 0 0 0 0 1 h 1\n", "non-negative range"),
            ("FLASER x\n", "number of readings N"),
            (
                "ROBOTLASER1 0 -1.5 0.02 0.01 80 0.01 0 2 1 2 0 0 0 0 0 0 0\n",
                "tv",
            ),
        ] {
            let e = parse_carmen(&from_str("b.log", text))
                .unwrap_err()
                .to_string();
            assert!(e.contains(want) && e.contains("b.log"), "{text:?} → {e}");
        }
    }

    #[test]
    fn write_read_round_trip() {
        let dir = std::env::temp_dir().join(format!("slam-io-carmen-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let scan = LaserScan {
            angle_min: -1.2,
            angle_increment: 0.01,
            ranges: (0..241)
                .map(|k| 0.5 + k as f64 * 0.013)
                .chain([30.0])
                .collect(),
            max_range: 30.0,
            sensor_pose: Pose2::new(0.2, -0.05, 0.1),
        };
        let d = ScanDataset {
            name: "sim".into(),
            records: (0..20)
                .map(|i| ScanRecord {
                    t: i as f64 * 0.1,
                    odometry: Pose2::new(i as f64 * 0.3, (i as f64).sin(), i as f64 * 0.4),
                    scan: (i % 3 == 0).then(|| scan.clone()),
                })
                .collect(),
            ground_truth: Some(
                (0..25)
                    .map(|i| TimedPose {
                        t: i as f64 * 0.09,
                        pose: Pose2::new(i as f64, 1.0, -0.2),
                    })
                    .collect(),
            ),
        };
        for name in ["sim.log", "sim.log.gz"] {
            let p = dir.join(name);
            write_carmen(&p, &d).unwrap();
            let back = read_carmen(&p).unwrap();
            assert!(back.unknown_records.is_empty());
            assert_eq!(back.dataset.ground_truth, d.ground_truth);
            assert_eq!(back.dataset.records.len(), d.records.len());
            for (a, b) in d.records.iter().zip(&back.dataset.records) {
                assert_eq!(a.t, b.t);
                assert_eq!(a.odometry, b.odometry);
                match (&a.scan, &b.scan) {
                    (None, None) => {}
                    (Some(x), Some(y)) => {
                        assert_eq!(x.ranges, y.ranges);
                        assert_eq!(
                            (x.angle_min, x.angle_increment, x.max_range),
                            (y.angle_min, y.angle_increment, y.max_range)
                        );
                        assert!(x.sensor_pose.approx_eq(&y.sensor_pose, 1e-12));
                        assert!(!y.is_hit(y.len() - 1));
                    }
                    _ => panic!("scan presence differs"),
                }
            }
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}
