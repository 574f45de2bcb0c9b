//! The Freiburg/Bonn *Robot Mapping* course landmark format: a folder with `world.dat` and
//! `sensor_data.dat`.
//!
//! * `world.dat`: one `id x y` per line, the true landmark map (metres, world frame).
//! * `sensor_data.dat`: `ODOMETRY r1 t r2` (rotation–translation–rotation, PR table 5.6;
//!   radians and metres) starts a time step, and the `SENSOR id range bearing` lines that
//!   follow are the observations taken after that motion (bearing CCW from the heading).
//!
//! The course files have no clock and no ground-truth trajectory; the robot starts at
//! (0, 0, 0). Step `k` (0-based) gets time `t = k`. Three optional sidecar files, written by
//! [`write_freiburg`] so that simulated data round-trips without changing the course format,
//! are read when present:
//!
//! * `initial_pose.dat`: one line `x y θ`;
//! * `times.dat`: one time per step, in seconds;
//! * `ground_truth.tum`: the true trajectory in TUM format (see [`crate::tum`]).
//!
//! **Unknown ids.** The course format always names the landmark. For data whose association
//! is unknown (simulated clutter scenes with hidden ids), `SENSOR -1 range bearing` stands
//! for "no id": [`write_freiburg`] writes it and the reader gives `id: None`. `-1` is never a
//! course-data id (those are positive).
//!
//! **Invalid observations.** The course data holds one negative range
//! (`SENSOR 7 -0.035065641258 0.975887269646`). A negative range is not a measurement a
//! range-bearing model can explain, so such an observation is **kept out of the dataset and
//! listed** in [`FreiburgData::skipped`] with its line number; [`crate::open_dataset`]
//! prints the count in its one-line summary. Malformed lines and NaN/∞ values are errors.
//! Bearings outside [−π, π] are kept as given (innovations normalise angle differences).
//!
//! **Bounds** ([`crate::bounds`]): landmark and initial-pose coordinates and the odometry
//! translation within ±10⁶ m; `r1`, `r2` and bearings within ±2π rad; ranges at most
//! 1000 m; the initial heading within ±10⁴ rad; step times within ±10¹⁰ s, within 10⁷ s of
//! the first. A violation is an error naming the file, line, field and bound.

use crate::error::IoError;
use crate::report::Skipped;
use crate::text::{read_text, write_text, TextFile};
use slam_models::{
    Control, LandmarkDataset, LandmarkId, LandmarkStep, OdometryControl, Point2, Pose2,
    RangeBearing,
};
use std::fmt::Write as _;
use std::path::Path;

/// A Freiburg dataset and the observations kept out of it.
#[derive(Debug, Clone, PartialEq)]
pub struct FreiburgData {
    /// The data: `Control::Odometry` steps, ids known, true landmarks from `world.dat`.
    pub dataset: LandmarkDataset,
    /// Observations that were read but are invalid (negative range), with their lines.
    pub skipped: Vec<Skipped>,
}

/// Reads a Freiburg folder; invalid observations are left out (see the module docs and
/// [`read_freiburg_report`], which lists them).
pub fn read_freiburg(dir: &Path) -> Result<LandmarkDataset, IoError> {
    read_freiburg_report(dir).map(|d| d.dataset)
}

/// Reads a Freiburg folder and reports the observations kept out of the dataset.
pub fn read_freiburg_report(dir: &Path) -> Result<FreiburgData, IoError> {
    let sensor = dir.join("sensor_data.dat");
    if !sensor.is_file() {
        return Err(IoError::NotFound {
            path: dir.to_path_buf(),
            what: "not a Freiburg folder: sensor_data.dat is missing".into(),
        });
    }
    let (mut dataset, skipped) = parse_sensor_data(&read_text(&sensor)?)?;
    let world = dir.join("world.dat");
    if world.is_file() {
        dataset.landmarks = Some(parse_world(&read_text(&world)?)?);
    }
    let init = dir.join("initial_pose.dat");
    if init.is_file() {
        let f = read_text(&init)?;
        f.ensure_not_empty("one line `x y theta`")?;
        let mut lines = f.data_lines();
        if let Some(mut l) = lines.next() {
            let p = Pose2::new(l.coord("x")?, l.coord("y")?, l.heading("theta")?);
            l.end("x y theta")?;
            dataset.initial_pose = p;
        }
        if let Some(l) = lines.next() {
            return Err(l.error("a single line `x y theta`", l.text));
        }
    }
    let times = dir.join("times.dat");
    if times.is_file() {
        let f = read_text(&times)?;
        let mut ts = Vec::with_capacity(dataset.steps.len());
        let mut span = crate::bounds::TimeSpan::default();
        for mut l in f.data_lines() {
            ts.push(l.time("time", &mut span)?);
            l.end("time")?;
        }
        if ts.len() != dataset.steps.len() {
            return Err(IoError::invalid(
                &times,
                format!(
                    "expected one time per step ({} steps), found {}",
                    dataset.steps.len(),
                    ts.len()
                ),
            ));
        }
        for (s, t) in dataset.steps.iter_mut().zip(ts) {
            s.t = t;
        }
    }
    let gt = dir.join("ground_truth.tum");
    if gt.is_file() {
        dataset.ground_truth = Some(crate::tum::read_tum(&gt)?);
    }
    dataset.name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "freiburg".into());
    Ok(FreiburgData { dataset, skipped })
}

/// Parses `world.dat`: `id x y` per line.
pub(crate) fn parse_world(f: &TextFile) -> Result<Vec<(LandmarkId, Point2)>, IoError> {
    f.ensure_not_empty("landmark lines `id x y`")?;
    let mut out: Vec<(LandmarkId, Point2)> = Vec::new();
    for mut l in f.data_lines() {
        let id = parse_id(&mut l)?;
        let p = Point2::new(l.coord("landmark x")?, l.coord("landmark y")?);
        l.end("`id x y`")?;
        if out.iter().any(|(i, _)| *i == id) {
            return Err(l.error("a landmark id not listed before", l.text));
        }
        out.push((id, p));
    }
    Ok(out)
}

/// A `SENSOR` id: a landmark id, or `-1` for "no id" (see the module docs).
fn parse_sensor_id(l: &mut crate::text::Line<'_>) -> Result<Option<LandmarkId>, IoError> {
    let word = l.word("a landmark id or -1")?;
    if word == "-1" {
        return Ok(None);
    }
    word.parse::<u32>()
        .map(|v| Some(LandmarkId(v)))
        .map_err(|_| l.error("a landmark id (0 .. 2^32) or -1 for no id", word))
}

fn parse_id(l: &mut crate::text::Line<'_>) -> Result<LandmarkId, IoError> {
    let v = l.u64("landmark id")?;
    u32::try_from(v)
        .map(LandmarkId)
        .map_err(|_| l.error("a landmark id below 2^32", &v.to_string()))
}

/// Parses `sensor_data.dat`.
pub(crate) fn parse_sensor_data(f: &TextFile) -> Result<(LandmarkDataset, Vec<Skipped>), IoError> {
    f.ensure_not_empty("ODOMETRY and SENSOR lines")?;
    let mut steps: Vec<LandmarkStep> = Vec::new();
    let mut skipped = Vec::new();
    for mut l in f.data_lines() {
        match l.word("a record type")? {
            "ODOMETRY" => {
                let u = OdometryControl {
                    rot1: l.angle("odometry r1")?,
                    trans: l.coord("odometry t")?,
                    rot2: l.angle("odometry r2")?,
                };
                l.end("`ODOMETRY r1 t r2`")?;
                steps.push(LandmarkStep {
                    t: steps.len() as f64,
                    control: Control::Odometry(u),
                    observations: Vec::new(),
                });
            }
            "SENSOR" => {
                let id = parse_sensor_id(&mut l)?;
                let range = l.range("range")?;
                let bearing = l.angle("bearing")?;
                l.end("`SENSOR id range bearing`")?;
                let Some(step) = steps.last_mut() else {
                    return Err(l.error("an ODOMETRY line before the first SENSOR line", l.text));
                };
                match RangeBearing::new(range, bearing, id) {
                    Ok(z) => step.observations.push(z),
                    Err(e) => skipped.push(Skipped {
                        path: f.path.clone(),
                        line: l.no,
                        reason: match id {
                            Some(id) => format!("observation of landmark {id} left out: {e}"),
                            None => format!("observation without id left out: {e}"),
                        },
                    }),
                }
            }
            other => return Err(l.error("ODOMETRY or SENSOR", other)),
        }
    }
    let dataset = LandmarkDataset {
        name: "freiburg".into(),
        initial_pose: Pose2::IDENTITY,
        steps,
        landmarks: None,
        ground_truth: None,
    };
    Ok((dataset, skipped))
}

/// The exact rotation–translation–rotation form of a control: odometry controls are kept
/// as they are; a velocity control is replaced by the (rot1, trans, rot2) that reaches the
/// same end pose from the origin (so dead reckoning is unchanged).
fn as_odometry(c: &Control) -> OdometryControl {
    match c {
        Control::Odometry(u) => *u,
        Control::Velocity(u) => {
            let model = slam_models::motion::VelocityModel::default();
            let p = slam_models::motion::MotionModel::predict(&model, &Pose2::IDENTITY, u);
            // libm, not std: `slam sim` output must be byte-identical on every machine.
            let trans = slam_models::detmath::hypot(p.x, p.y);
            let rot1 = if trans > 0.0 {
                slam_models::detmath::atan2(p.y, p.x)
            } else {
                0.0
            };
            OdometryControl {
                rot1,
                trans,
                rot2: slam_models::normalize_angle(p.theta - rot1),
            }
        }
    }
}

/// Writes `d` as a Freiburg folder (created if needed): `sensor_data.dat`, `world.dat` when
/// landmarks are known, and the sidecars `initial_pose.dat` (when not the origin),
/// `times.dat` (when the step times are not 0, 1, 2, …) and `ground_truth.tum` (when known).
/// Velocity controls are converted to the odometry increment with the same end pose.
/// Numbers are written with Rust's shortest round-trip formatting, so
/// [`read_freiburg`] gives back exactly the same values.
///
/// Observations without an id are written with the id `-1` (see the module docs).
///
/// Errors: a non-finite value.
pub fn write_freiburg(dir: &Path, d: &LandmarkDataset) -> Result<(), IoError> {
    std::fs::create_dir_all(dir).map_err(|e| IoError::io(dir, e))?;
    let sensor = dir.join("sensor_data.dat");
    let mut s = String::new();
    for (k, step) in d.steps.iter().enumerate() {
        step.control
            .validate()
            .map_err(|e| IoError::invalid(&sensor, format!("step {k}: {e}")))?;
        let u = as_odometry(&step.control);
        let _ = writeln!(s, "ODOMETRY {} {} {}", u.rot1, u.trans, u.rot2);
        for z in &step.observations {
            if !(z.range.is_finite() && z.bearing.is_finite()) {
                return Err(IoError::invalid(
                    &sensor,
                    format!("step {k}: non-finite observation"),
                ));
            }
            match z.id {
                Some(id) => {
                    let _ = writeln!(s, "SENSOR {} {} {}", id.0, z.range, z.bearing);
                }
                None => {
                    let _ = writeln!(s, "SENSOR -1 {} {}", z.range, z.bearing);
                }
            }
        }
    }
    write_text(&sensor, &s)?;
    if let Some(lms) = &d.landmarks {
        let mut w = String::new();
        for (id, p) in lms {
            let _ = writeln!(w, "{} {} {}", id.0, p.x, p.y);
        }
        write_text(&dir.join("world.dat"), &w)?;
    }
    if d.initial_pose != Pose2::IDENTITY {
        let p = d.initial_pose;
        write_text(
            &dir.join("initial_pose.dat"),
            &format!("{} {} {}\n", p.x, p.y, p.theta),
        )?;
    }
    if d.steps.iter().enumerate().any(|(k, s)| s.t != k as f64) {
        let mut w = String::new();
        for st in &d.steps {
            let _ = writeln!(w, "{}", st.t);
        }
        write_text(&dir.join("times.dat"), &w)?;
    }
    if let Some(gt) = &d.ground_truth {
        crate::tum::write_tum(&dir.join("ground_truth.tum"), gt)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::text::from_str;

    #[test]
    fn parses_steps_and_skips_negative_range() {
        let f = from_str(
            "s.dat",
            "ODOMETRY 0.1 1.0 -0.1\nSENSOR 1 2.0 0.5\nSENSOR 7 -0.03 0.9\nODOMETRY 0 0 0\n",
        );
        let (d, skipped) = parse_sensor_data(&f).unwrap();
        assert_eq!(d.steps.len(), 2);
        assert_eq!(d.steps[0].observations.len(), 1);
        assert_eq!(d.steps[0].observations[0].id, Some(LandmarkId(1)));
        assert_eq!(d.steps[1].t, 1.0);
        assert_eq!(skipped.len(), 1);
        assert_eq!(skipped[0].line, 3);
        // `-1` is "no id".
        let f = from_str("s.dat", "ODOMETRY 0 1 0\nSENSOR -1 2.0 0.5\n");
        let (d, _) = parse_sensor_data(&f).unwrap();
        assert_eq!(d.steps[0].observations[0].id, None);
    }

    #[test]
    fn error_paths() {
        let cases = [
            ("", "empty"),
            ("SENSOR 1 2 3\n", "ODOMETRY line before"),
            ("ODOMETRY 1 2\n", "line ended early"),
            ("ODOMETRY 1 2 3 4\n", "end of line"),
            ("ODOMETRY 1 x 3\n", "odometry t (a number)"),
            ("ODOMETRY 1 inf 3\n", "not finite"),
            ("ODOMETRY 1 2 3\nSENSOR -2 2 3\n", "landmark id"),
            ("ODOMETRY 1 2 3\nSENSOR 1.5 2 3\n", "landmark id"),
            ("ODOMETRY 1 2 3\nSENSOR 1 NaN 3\n", "not finite"),
            ("ODOMETRY 1 2 3\nLASER 1 2 3\n", "ODOMETRY or SENSOR"),
        ];
        for (text, want) in cases {
            let e = parse_sensor_data(&from_str("s.dat", text))
                .unwrap_err()
                .to_string();
            assert!(e.contains(want) && e.contains("s.dat"), "{text:?} → {e}");
        }
        for (text, want) in [
            ("1 2\n", "line ended early"),
            ("1 2 3\n1 4 5\n", "not listed before"),
            ("", "empty"),
        ] {
            let e = parse_world(&from_str("w.dat", text))
                .unwrap_err()
                .to_string();
            assert!(e.contains(want), "{text:?} → {e}");
        }
    }

    #[test]
    fn velocity_control_converts_to_same_end_pose() {
        let u = slam_models::VelocityControl {
            v: 1.0,
            omega: 0.5,
            dt: 0.7,
        };
        let o = as_odometry(&Control::Velocity(u));
        let m = slam_models::motion::MotionModels::default();
        let start = Pose2::new(1.0, -2.0, 0.3);
        let a = m.predict(&start, &Control::Velocity(u));
        let b = m.predict(&start, &Control::Odometry(o));
        assert!(a.approx_eq(&b, 1e-12));
    }
}
