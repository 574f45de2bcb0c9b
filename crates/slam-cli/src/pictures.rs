//! `slam run`'s pictures: `map.png` of a landmark run and the `--frames` animation frames,
//! gathered from the filter and the run and written here; which layers they show, their
//! labels and the title, and the drawing itself, are slam-viz's ([`slam_viz::run_picture`]).

use crate::error::CliError;
use slam_models::{LandmarkId, LandmarkSlam, Point2, Pose2, TimedPose};
pub(crate) use slam_viz::run_picture::{laser_picture, title};
use slam_viz::{
    picture::Picture,
    run_picture::{landmark_picture, LandmarkLayers},
};
use std::path::{Path, PathBuf};

/// `map.png` of a landmark run ([`landmark_picture`]): the run's trajectory (the path
/// written to `trajectory.tum`) and map, and for particle filters every particle's path
/// (grey) and landmark means (dots) from the filter's path tree and maps. Paths are drawn
/// only while they fit a bounded number of poses (shared history is repeated once per
/// particle when flattened); otherwise a line in `notes` says so.
pub(crate) fn landmark_run_picture(
    title: &str,
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
        let title = format!("{title}, step {} of {steps}", k + 1);
        let mut pic = landmark_picture(&LandmarkLayers {
            title: &title,
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
}
