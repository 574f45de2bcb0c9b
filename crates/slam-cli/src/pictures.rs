//! What `slam run`'s pictures show: `map.png` for landmark and laser filters, and the
//! `--frames` animation frames of a landmark run. The drawing itself is
//! [`slam_io::picture::Picture`]; this module picks the layers, their legend labels and the
//! title (filter, data, particle count, seed).

use crate::error::CliError;
use slam_io::picture::{Picture, RED};
use slam_models::{
    GridMap, LandmarkEstimate, LandmarkId, LandmarkSlam, Point2, Pose2, TimedPose, WeightedPose,
};
use std::path::{Path, PathBuf};

/// The title of a picture: "fastslam2 on loop, 100 particles, seed 0" (the particle count
/// only for particle filters, the seed only where it changes the result: a simulated
/// scenario or a particle filter).
pub(crate) fn title(
    filter: &str,
    data: &str,
    particles: Option<usize>,
    seed: Option<u64>,
) -> String {
    let mut t = format!("{filter} on {data}");
    if let Some(n) = particles {
        t += &format!(", {n} particle{}", if n == 1 { "" } else { "s" });
    }
    if let Some(s) = seed {
        t += &format!(", seed {s}");
    }
    t
}

/// The layers of a landmark filter's picture, as plain data.
pub(crate) struct LandmarkLayers<'a> {
    /// The picture's title.
    pub title: String,
    /// The estimated path: the EKF's estimate, or FastSLAM's best particle's path.
    pub estimate: &'a [Pose2],
    /// Its legend label.
    pub estimate_label: &'a str,
    /// Every particle's path x₀:ₜ (FastSLAM's full-SLAM hypotheses); empty when the filter
    /// does not provide them.
    pub particle_paths: &'a [Vec<Pose2>],
    /// Every particle's landmark means; empty when the filter does not provide them.
    pub particle_landmarks: &'a [Point2],
    /// The map drawn with 95 % ellipses: the EKF's, or the best particle's.
    pub landmarks: &'a [LandmarkEstimate],
    /// The particle cloud now (particle filters).
    pub particles: Option<&'a [WeightedPose]>,
    /// Ground truth path, when known.
    pub ground_truth: Option<&'a [Pose2]>,
    /// True landmarks, when known.
    pub true_landmarks: Option<&'a [(LandmarkId, Point2)]>,
}

/// The picture of a landmark filter's run: for FastSLAM as the Freiburg course exercise
/// draws it (every particle's path grey, the best particle's path red with an arrow on its
/// final pose, each particle's landmark means as dots, the best particle's 95 % ellipses,
/// true landmarks as crosses, ground truth green); for the EKF its estimate, its landmarks'
/// ellipses and the truth.
pub(crate) fn landmark_picture(l: &LandmarkLayers<'_>) -> Picture {
    let particle_filter = l.particles.is_some();
    let mut pic = Picture::new().title(l.title.clone());
    pic = pic
        .particle_paths(l.particle_paths)
        .particle_landmarks(l.particle_landmarks);
    if let Some(gt) = l.ground_truth {
        pic = pic.ground_truth(gt);
    }
    if let Some(t) = l.true_landmarks {
        pic = pic.true_landmarks(t);
    }
    let label = if particle_filter {
        "best particle's landmarks, 95 %"
    } else {
        "landmarks, 95 % ellipses"
    };
    pic = pic.landmarks(l.landmarks, label);
    if let Some(p) = l.particles {
        pic = pic.particles(p);
    }
    pic.trajectory(l.estimate, RED, l.estimate_label)
}

/// `map.png` of a landmark run ([`landmark_picture`]): the run's trajectory (the path
/// written to `trajectory.tum`) and map, and for particle filters every particle's path
/// (grey) and landmark means (dots) from the filter's path tree and maps. Paths are drawn
/// only while they fit a bounded number of poses (shared history is repeated once per
/// particle when flattened); otherwise a line in `notes` says so.
pub(crate) fn landmark_run_picture(
    title: String,
    filter: &dyn LandmarkSlam,
    run: &slam_eval::LandmarkRun,
    ground_truth: Option<&[TimedPose]>,
    true_landmarks: Option<&[(LandmarkId, Point2)]>,
    notes: &mut Vec<String>,
) -> Picture {
    const MAX_DRAWN_POSES: usize = 2_000_000;
    let particles = filter.particles();
    let poses: Vec<_> = run.trajectory().iter().map(|t| t.pose).collect();
    let gt_poses: Option<Vec<_>> = ground_truth.map(|g| g.iter().map(|t| t.pose).collect());
    let steps = run.online.len();
    let particle_paths: Vec<Vec<Pose2>> = match filter.particle_paths() {
        Some(pp) if pp.leaves.len().saturating_mul(steps + 1) <= MAX_DRAWN_POSES => {
            (0..pp.leaves.len()).map(|k| pp.path_of(k)).collect()
        }
        Some(_) => {
            notes.push(format!(
                "map.png: particle paths not drawn (more than {MAX_DRAWN_POSES} poses)"
            ));
            Vec::new()
        }
        None => Vec::new(),
    };
    let particle_landmarks: Vec<Point2> = filter
        .particle_landmarks()
        .map(|maps| maps.iter().flatten().map(|l| l.mean).collect())
        .unwrap_or_default();
    landmark_picture(&LandmarkLayers {
        title,
        estimate: &poses,
        estimate_label: if run.full_path.is_some() {
            "best particle's path (full SLAM)"
        } else if particles.is_some() {
            "online estimate (best particle at each step)"
        } else {
            "estimate"
        },
        particle_paths: &particle_paths,
        particle_landmarks: &particle_landmarks,
        landmarks: &run.landmarks,
        particles: particles.as_deref(),
        ground_truth: gt_poses.as_deref(),
        true_landmarks,
    })
}

/// The picture of a laser filter's run: the map, the estimated trajectory (red, an arrow on
/// its final pose), the ground truth with its legend label (green; a `--ground-truth` file
/// for the bench logs is GMapping's trajectory, a reference rather than the truth) and the
/// particles, if any.
pub(crate) fn laser_picture(
    title: String,
    map: &GridMap,
    trajectory: &[Pose2],
    ground_truth: Option<(&[Pose2], &str)>,
    particles: Option<&[WeightedPose]>,
) -> Picture {
    let mut pic = Picture::new().title(title).map(map);
    if let Some((gt, label)) = ground_truth {
        pic = pic.ground_truth(gt).ground_truth_label(label);
    }
    if let Some(p) = particles {
        pic = pic.particles(p);
    }
    pic.trajectory(trajectory, RED, "estimate")
}

/// The file that marks a `--frames` folder as partial while its run is not complete.
pub(crate) const FRAMES_INCOMPLETE: &str = "INCOMPLETE.txt";

/// `--frames DIR --frame-every K`: one PNG every K steps of a landmark run (and after the
/// last step), `DIR/frame-000001.png`, `frame-000002.png`, … numbered consecutively (as
/// video tools expect; the step is in each frame's title), for making an animation. Every frame
/// shows the same square window (the ground truth and true landmarks when known, otherwise
/// whatever has been drawn so far) so that the images all have one size.
pub(crate) struct Frames {
    dir: PathBuf,
    every: usize,
    /// The points framed by every frame's window (ground truth and true landmarks).
    window: Vec<Point2>,
    /// Frames written so far.
    written: usize,
}

impl Frames {
    /// Prepares `dir`: it is created if missing, and must otherwise be empty (frames of an
    /// earlier run would mix with this one's, and nothing of the user's is overwritten).
    pub(crate) fn new(
        dir: &Path,
        every: usize,
        ground_truth: Option<&[TimedPose]>,
        true_landmarks: Option<&[(LandmarkId, Point2)]>,
    ) -> Result<Self, CliError> {
        let write_err = |source| CliError::Write {
            path: dir.to_path_buf(),
            source,
        };
        if dir.exists() {
            let mut entries = std::fs::read_dir(dir).map_err(write_err)?;
            if entries.next().is_some() {
                return Err(CliError::InvalidArgument(format!(
                    "--frames {}: the folder is not empty (give a new or empty folder)",
                    dir.display()
                )));
            }
        } else {
            std::fs::create_dir_all(dir).map_err(write_err)?;
        }
        // Marks the frames as partial until the run completes (Ctrl-C, an error): a folder
        // with this file is not a whole animation. [`Frames::finish`] removes it.
        let marker = dir.join(FRAMES_INCOMPLETE);
        std::fs::write(
            &marker,
            "The run writing these frames did not complete (interrupted or failed): \
             the frames here are partial.\n",
        )
        .map_err(|source| CliError::Write {
            path: marker.clone(),
            source,
        })?;
        let mut window: Vec<Point2> = ground_truth
            .unwrap_or(&[])
            .iter()
            .map(|p| p.pose.translation())
            .collect();
        window.extend(true_landmarks.unwrap_or(&[]).iter().map(|(_, p)| *p));
        Ok(Self {
            dir: dir.to_path_buf(),
            every: every.max(1),
            window,
            written: 0,
        })
    }

    /// The run completed: the frames are whole, so the partial marker goes.
    pub(crate) fn finish(self) -> Result<(), CliError> {
        let marker = self.dir.join(FRAMES_INCOMPLETE);
        std::fs::remove_file(&marker).map_err(|source| CliError::Write {
            path: marker,
            source,
        })
    }

    /// Writes the frame of step `k` (0-based) of `steps` when it is due: every `every`
    /// steps and after the last. `trajectory` holds the online estimates up to step k, and
    /// the ground truth is drawn up to step k's time `t`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn step(
        &mut self,
        k: usize,
        steps: usize,
        title: &str,
        filter: &dyn LandmarkSlam,
        trajectory: &[TimedPose],
        ground_truth: Option<&[TimedPose]>,
        true_landmarks: Option<&[(LandmarkId, Point2)]>,
    ) -> Result<(), CliError> {
        if (k + 1) % self.every != 0 && k + 1 != steps {
            return Ok(());
        }
        let t = trajectory.last().map_or(f64::NEG_INFINITY, |p| p.t);
        let estimate: Vec<Pose2> = trajectory.iter().map(|p| p.pose).collect();
        let truth: Option<Vec<Pose2>> = ground_truth.map(|g| {
            g.iter()
                .filter(|p| p.t <= t + 1e-9)
                .map(|p| p.pose)
                .collect()
        });
        let landmarks = filter.landmarks();
        let particles = filter.particles();
        let label = if particles.is_some() {
            "online estimate (best particle at each step)"
        } else {
            "estimate"
        };
        let mut pic = landmark_picture(&LandmarkLayers {
            title: format!("{title}, step {} of {steps}", k + 1),
            estimate: &estimate,
            estimate_label: label,
            particle_paths: &[],
            particle_landmarks: &[],
            landmarks: &landmarks,
            particles: particles.as_deref(),
            ground_truth: truth.as_deref(),
            true_landmarks,
        })
        .square(true)
        .size(800);
        if !self.window.is_empty() {
            pic = pic.fit_to(&self.window);
        }
        self.written += 1;
        let path = self.dir.join(format!("frame-{:06}.png", self.written));
        pic.save_png(&path)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Until the run completes, a frames folder says it is partial; `finish` clears that
    /// (a run stopped by Ctrl-C or an error never calls it).
    #[test]
    fn frames_are_marked_partial_until_finished() {
        let dir = std::env::temp_dir().join(format!("slam-frames-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let frames = Frames::new(&dir, 10, None, None).unwrap();
        assert!(dir.join(FRAMES_INCOMPLETE).is_file());
        frames.finish().unwrap();
        assert!(std::fs::read_dir(&dir).unwrap().next().is_none());
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn titles_name_filter_data_particles_and_seed() {
        assert_eq!(title("ekf", "loop", None, None), "ekf on loop");
        assert_eq!(
            title("fastslam2", "loop", Some(100), Some(0)),
            "fastslam2 on loop, 100 particles, seed 0"
        );
        assert_eq!(
            title("gridfast", "intel", Some(1), None),
            "gridfast on intel, 1 particle"
        );
    }
}
