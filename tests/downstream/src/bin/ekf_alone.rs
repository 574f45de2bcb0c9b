//! slam-ekf alone, no simulator: EKF-SLAM from its re-exports, one predict and one update
//! with a noise-free observation of a landmark at a known place, checked against it.
use slam_ekf::prelude::*;
use slam_ekf::{Control, EkfConfig, EkfSlam, LandmarkId, OdometryControl, Pose2, RangeBearing};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut ekf = EkfSlam::new(EkfConfig::default(), Pose2::IDENTITY, 0)?;
    // One metre straight ahead, then the landmark at (2, 1) seen from (1, 0).
    let step = OdometryControl {
        rot1: 0.0,
        trans: 1.0,
        rot2: 0.0,
    };
    ekf.predict(&Control::Odometry(step))?;
    let z = RangeBearing::new(
        2f64.sqrt(),
        std::f64::consts::FRAC_PI_4,
        Some(LandmarkId(7)),
    )?;
    let info = ekf.update(&[z])?;
    let lm = ekf.landmarks();
    let (p, l) = (ekf.pose(), &lm[0]);
    assert_eq!((info.new_landmarks, lm.len()), (1, 1));
    assert!((p.x - 1.0).abs() < 1e-9 && p.y.abs() < 1e-9, "{p:?}");
    assert!((l.mean.x - 2.0).abs() < 1e-9 && (l.mean.y - 1.0).abs() < 1e-9);
    println!(
        "{}: pose {p:?}, landmark {} at {}",
        ekf.name(),
        l.id,
        l.mean
    );
    Ok(())
}
