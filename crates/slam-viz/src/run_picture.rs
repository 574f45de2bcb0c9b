//! What a SLAM run's picture shows: the layers of a landmark filter's picture (as the
//! Freiburg course exercise draws FastSLAM, or an EKF's estimate with its ellipses) and of a
//! laser filter's map picture, their legend labels and the title (filter, data, particle
//! count, seed). The drawing itself is [`Picture`]; gathering the layers from a filter and
//! writing the files is the caller's (the `slam` program's `map.png` and `--frames`).

use crate::picture::{Picture, RED};
use slam_models::{GridMap, LandmarkEstimate, LandmarkId, Point2, Pose2, WeightedPose};

/// The title of a picture: "fastslam2 on loop, 100 particles, seed 0" (the particle count
/// only for particle filters, the seed only where it changes the result: a simulated
/// scenario or a particle filter).
pub fn title(filter: &str, data: &str, particles: Option<usize>, seed: Option<u64>) -> String {
    let mut t = format!("{filter} on {data}");
    if let Some(n) = particles {
        t += &format!(", {n} particle{}", if n == 1 { "" } else { "s" });
    }
    if let Some(s) = seed {
        t += &format!(", seed {s}");
    }
    t
}

/// The layers of a landmark filter's picture, as plain data (world frame, metres, radians).
#[derive(Debug, Clone, Copy)]
pub struct LandmarkLayers<'a> {
    /// The picture's title.
    pub title: &'a str,
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
    /// The particle cloud now (particle filters; `None` for the EKF, which also picks the
    /// landmarks' legend label).
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
pub fn landmark_picture(l: &LandmarkLayers<'_>) -> Picture {
    let particle_filter = l.particles.is_some();
    let mut pic = Picture::new().title(l.title);
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

/// The picture of a laser filter's run: the map, the estimated trajectory (red, an arrow on
/// its final pose), the ground truth with its legend label (green; a reference trajectory
/// such as GMapping's for the bench logs is labelled as such rather than as the truth) and
/// the particles, if any.
pub fn laser_picture(
    title: &str,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::picture::GREY;

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

    /// A particle filter's picture draws its particle paths grey and its estimate red; the
    /// EKF's (no particles) draws the estimate alone.
    #[test]
    fn landmark_layers_reach_the_picture() {
        let path: Vec<Pose2> = (0..20).map(|i| Pose2::new(i as f64, 0.0, 0.0)).collect();
        let other: Vec<Pose2> = (0..20).map(|i| Pose2::new(i as f64, 5.0, 0.0)).collect();
        let paths = vec![other];
        let cloud = [WeightedPose {
            pose: Pose2::new(19.0, 0.0, 0.0),
            weight: 1.0,
        }];
        let mut layers = LandmarkLayers {
            title: "t",
            estimate: &path,
            estimate_label: "estimate",
            particle_paths: &paths,
            particle_landmarks: &[],
            landmarks: &[],
            particles: Some(&cloud),
            ground_truth: None,
            true_landmarks: None,
        };
        let count = |l: &LandmarkLayers<'_>, c: crate::picture::Rgb| {
            let img = landmark_picture(l).size(200).render().unwrap();
            img.pixels().filter(|p| p.0 == c.0).count()
        };
        // (Anti-aliased text has a few pixels of every grey, so the paths are told by the
        // difference: a 19 m path over 200 px for about 21 m is over 150 px long.)
        let (grey, red) = (count(&layers, GREY), count(&layers, RED));
        assert!(red > 150, "{red}");
        layers.particle_paths = &[];
        layers.particles = None;
        let without = count(&layers, GREY);
        assert!(grey > without + 150, "{grey} {without}");
    }
}
