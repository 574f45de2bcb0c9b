//! `slam run --mcap FILE` and `slam localize --mcap FILE`: the run as an MCAP file of ROS 2
//! messages (slam-io's [`McapRunWriter`]), fed by the run loops one step at a time.
//!
//! [`McapRecorder`] is the whole hook: the run loops call [`McapRecorder::scan_step`],
//! [`McapRecorder::landmark_step`] or [`McapRecorder::localize_step`] after each filter step
//! and [`McapRecorder::finish`] with the run's result. Snapshots (`/trajectory`, `/map`, `/landmarks`) are taken every
//! `--mcap-every` steps, by default about 100 per run; the time spent writing is output,
//! not filtering, and is taken off the run's wall time (the recorder runs in the run's
//! observer, whose time slam-eval does not count).
//!
//! The file is refused, before any data is loaded ([`check_path`]), when it is one of the
//! run's inputs or lies inside an input folder, lies inside the output folder (whose contents the run replaces), or exists
//! and is not an MCAP file slam wrote (its header's `library` field does not start with
//! `slam-rs`); with `--force` any existing MCAP file is replaced, never another kind of file.
//! An MCAP file slam wrote is replaced. The file appears only when the run completes
//! (slam-io writes `FILE.partial` and renames it).

use crate::cli::RunArgs;
use crate::error::CliError;
use slam_io::mcap_out::{McapRunOptions, McapRunWriter, RunEnd, RunStep};
use slam_models::TimedPose;
use slam_models::{GridMap, LandmarkEstimate, LandmarkSlam, Point2, Pose2, ScanRecord, ScanSlam};
use std::path::{Path, PathBuf};

/// Snapshots per run when `--mcap-every` is not given.
const DEFAULT_SNAPSHOTS: usize = 100;

/// The `library` an MCAP file's header names (the string after the 8 magic bytes, the
/// header record's opcode and length, and its `profile` string), up to 256 bytes of it;
/// `None` when the file is not an MCAP file.
fn mcap_library(path: &Path) -> Option<String> {
    use std::io::Read as _;
    let mut head = Vec::new();
    std::fs::File::open(path)
        .ok()?
        .take(8 + 9 + 4 + 256 + 4 + 256)
        .read_to_end(&mut head)
        .ok()?;
    if !head.starts_with(b"\x89MCAP0\r\n") || head.get(8) != Some(&0x01) {
        return None;
    }
    let string = |at: usize| -> Option<(&[u8], usize)> {
        let n = u32::from_le_bytes(head.get(at..at + 4)?.try_into().ok()?) as usize;
        let end = (at + 4).checked_add(n)?;
        Some((head.get(at + 4..end.min(head.len()))?, end))
    };
    let (_, after_profile) = string(17)?;
    let (library, _) = string(after_profile)?;
    Some(String::from_utf8_lossy(library).into_owned())
}

/// Checks `--mcap` against the inputs and the output folder (module doc); `force` allows
/// replacing an MCAP file slam did not write.
pub(crate) fn check_path(
    mcap: &Path,
    inputs: &[(&str, &Path)],
    out_dir: &Path,
    force: bool,
) -> Result<(), CliError> {
    let refuse =
        |why: String| CliError::InvalidArgument(format!("--mcap {}: {why}", mcap.display()));
    let parent = match mcap.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if mcap.file_name().is_none() || mcap.is_dir() {
        return Err(refuse("a file name is needed".into()));
    }
    // Inside the output folder, lexically (the folder may not exist yet) or through links.
    let inside_out = |p: &Path| {
        let out = out_dir.canonicalize().ok();
        std::path::absolute(out_dir).is_ok_and(|o| p.starts_with(o))
            || out.is_some_and(|o| p.starts_with(o))
    };
    let inside = |p: &Path| {
        inside_out(p).then(|| {
            refuse(format!(
                "it lies inside the output folder {} (whose contents the run replaces); write \
                 it beside the folder",
                out_dir.display()
            ))
        })
    };
    if let Some(e) = std::path::absolute(mcap).ok().and_then(|p| inside(&p)) {
        return Err(e);
    }
    let parent = parent
        .canonicalize()
        .map_err(|e| refuse(format!("its folder cannot be used ({e})")))?;
    let target = parent.join(mcap.file_name().unwrap_or_default());
    for (option, input) in inputs {
        match input.canonicalize() {
            Ok(p) if p == target => return Err(refuse(format!("it is the {option} input"))),
            // A rosbag2 or Freiburg folder: its files are the input too.
            Ok(p) if p.is_dir() && target.starts_with(&p) => {
                return Err(refuse(format!(
                    "it lies inside the {option} input folder {}",
                    input.display()
                )))
            }
            _ => {}
        }
    }
    if let Some(e) = inside(&target) {
        return Err(e);
    }
    if target.exists() {
        match mcap_library(&target) {
            None => {
                return Err(refuse(
                    "the file exists and is not an MCAP file; it is left alone".into(),
                ))
            }
            Some(lib) if !lib.starts_with("slam-rs") && !force => {
                return Err(refuse(format!(
                    "the file exists and is an MCAP file slam did not write (library {:?}); \
                     it is left alone (--force replaces it)",
                    lib.chars().take(60).collect::<String>()
                )))
            }
            Some(_) => {}
        }
    }
    Ok(())
}

/// Writes a run to `--mcap` (module doc).
pub(crate) struct McapRecorder {
    writer: McapRunWriter,
    path: PathBuf,
}

impl McapRecorder {
    /// The recorder of a run of `steps` steps, or `None` without `--mcap`.
    pub fn create(
        args: &RunArgs,
        steps: usize,
        true_landmarks: Option<&[Point2]>,
    ) -> Result<Option<Self>, CliError> {
        match &args.mcap {
            Some(path) => Self::open(path, args.mcap_every, steps, true_landmarks).map(Some),
            None => Ok(None),
        }
    }

    /// The recorder of a run of `steps` steps written to `path`, a snapshot every `every`
    /// steps (default: about [`DEFAULT_SNAPSHOTS`] per run).
    pub fn open(
        path: &Path,
        every: Option<u64>,
        steps: usize,
        true_landmarks: Option<&[Point2]>,
    ) -> Result<Self, CliError> {
        let every = match every {
            Some(k) => k as usize,
            None => steps.div_ceil(DEFAULT_SNAPSHOTS).max(1),
        };
        let options = McapRunOptions {
            snapshot_every: every,
            true_landmarks: true_landmarks.map(<[Point2]>::to_vec).unwrap_or_default(),
        };
        Ok(McapRecorder {
            writer: McapRunWriter::create(path, options)?,
            path: path.to_path_buf(),
        })
    }

    /// After `slam localize`'s filter processed `record`: the estimate, the odometry, the
    /// scan; the particle cloud `particles` when the filter updated at this record (the
    /// cloud changes only then); the known `map` at the first step (it does not change).
    pub fn localize_step(
        &mut self,
        record: &ScanRecord,
        pose: Pose2,
        particles: Option<&[slam_models::WeightedPose]>,
        map: &GridMap,
    ) -> Result<(), CliError> {
        let first = self.writer.steps() == 0;
        self.writer.step(&RunStep {
            t: record.t,
            pose,
            odometry: Some(record.odometry),
            scan: record.scan.as_ref(),
            particles,
            map: first.then_some(map),
            landmarks: None,
        })?;
        Ok(())
    }

    /// After a laser filter's `process(record)`: pose, odometry, scan, particles, and at
    /// snapshot steps the map.
    pub fn scan_step(
        &mut self,
        record: &ScanRecord,
        filter: &dyn ScanSlam,
    ) -> Result<(), CliError> {
        let map = self.writer.snapshot_due().then(|| filter.map());
        let particles = filter.particles();
        self.writer.step(&RunStep {
            t: record.t,
            pose: filter.pose(),
            odometry: Some(record.odometry),
            scan: record.scan.as_ref(),
            particles: particles.as_deref(),
            map: map.as_ref(),
            landmarks: None,
        })?;
        Ok(())
    }

    /// After a landmark filter's `predict` + `update` at time `t`: pose, the dead-reckoned
    /// odometry, particles, and at snapshot steps the landmarks.
    pub fn landmark_step(
        &mut self,
        t: f64,
        odometry: Option<Pose2>,
        filter: &dyn LandmarkSlam,
    ) -> Result<(), CliError> {
        let landmarks = self.writer.snapshot_due().then(|| filter.landmarks());
        let particles = filter.particles();
        self.writer.step(&RunStep {
            t,
            pose: filter.pose(),
            odometry,
            scan: None,
            particles: particles.as_deref(),
            map: None,
            landmarks: landmarks.as_deref(),
        })?;
        Ok(())
    }

    /// Writes the end (the run's trajectory, final map or landmarks, ground truth in the
    /// estimate's frame) and closes the file; returns the line for the run's summary.
    pub fn finish(
        self,
        trajectory: &[TimedPose],
        map: Option<&GridMap>,
        landmarks: Option<&[LandmarkEstimate]>,
        ground_truth: Option<&[TimedPose]>,
    ) -> Result<String, CliError> {
        let counts = self.writer.finish(&RunEnd {
            trajectory,
            map,
            landmarks,
            ground_truth,
        })?;
        let total: u64 = counts.values().sum();
        let topics: Vec<String> = counts.iter().map(|(t, n)| format!("{t} {n}")).collect();
        Ok(format!(
            "wrote {} ({total} ROS 2 messages: {})",
            self.path.display(),
            topics.join(", ")
        ))
    }
}
