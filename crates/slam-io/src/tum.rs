//! TUM RGB-D trajectory files (`t x y z qx qy qz qw`), the format `evo` reads.
//!
//! Each data line is a timestamp in seconds, a position in metres and a unit quaternion
//! (Hamilton convention, scalar last). For our planar poses z = 0 and the quaternion is a
//! rotation about z: (0, 0, sin θ/2, cos θ/2). On reading, the heading is the yaw of the
//! quaternion, θ = atan2(2(qw·qz + qx·qy), 1 − 2(qy² + qz²)); z, roll and pitch are
//! ignored. Lines starting with `#` are comments.
//!
//! **Bounds** ([`crate::bounds`]): x, y, z within ±10⁶ m; times within ±10¹⁰ s and within
//! 10⁷ s of the first. A violation is an error naming the file, line, field and bound.

use crate::error::IoError;
use crate::text::{read_text, write_text, TextFile};
use slam_models::{Pose2, TimedPose};
use std::fmt::Write as _;
use std::path::Path;

/// Reads a TUM trajectory. Errors: malformed line, NaN/∞, a quaternion of norm far from 1
/// (|‖q‖ − 1| > 1e-3; short printouts are fine), a value out of bounds (module docs), or an
/// empty file.
pub fn read_tum(path: &Path) -> Result<Vec<TimedPose>, IoError> {
    parse_tum(&read_text(path)?)
}

pub(crate) fn parse_tum(f: &TextFile) -> Result<Vec<TimedPose>, IoError> {
    f.ensure_not_empty("trajectory lines `t x y z qx qy qz qw`")?;
    let mut out = Vec::new();
    let mut span = crate::bounds::TimeSpan::default();
    for mut l in f.data_lines() {
        let t = l.time("timestamp", &mut span)?;
        let x = l.coord("x")?;
        let y = l.coord("y")?;
        let _z = l.coord("z")?;
        let qx = l.f64("qx")?;
        let qy = l.f64("qy")?;
        let qz = l.f64("qz")?;
        let qw = l.f64("qw")?;
        l.end("`t x y z qx qy qz qw`")?;
        let n = (qx * qx + qy * qy + qz * qz + qw * qw).sqrt();
        if (n - 1.0).abs() > 1e-3 {
            return Err(l.error(
                "a unit quaternion qx qy qz qw",
                &format!("norm {n} in {}", l.text.trim()),
            ));
        }
        let yaw = (2.0 * (qw * qz + qx * qy)).atan2(1.0 - 2.0 * (qy * qy + qz * qz));
        out.push(TimedPose {
            t,
            pose: Pose2::new(x, y, yaw),
        });
    }
    Ok(out)
}

/// Writes a TUM trajectory: one line `t x y 0 0 0 sin(θ/2) cos(θ/2)` per pose, numbers in
/// shortest round-trip form. Errors on non-finite values.
pub fn write_tum(path: &Path, traj: &[TimedPose]) -> Result<(), IoError> {
    let mut s = String::with_capacity(traj.len() * 64);
    s.push_str("# timestamp x y z qx qy qz qw\n");
    for (i, p) in traj.iter().enumerate() {
        if !(p.t.is_finite() && p.pose.is_finite()) {
            return Err(IoError::invalid(
                path,
                format!("pose {i} (t = {}) is not finite", p.t),
            ));
        }
        // libm, not std: `slam sim` writes ground truth through here, and its files are
        // promised to be byte-identical on every machine.
        let (sh, ch) = slam_models::detmath::sin_cos(0.5 * p.pose.theta);
        let _ = writeln!(s, "{} {} {} 0 0 0 {} {}", p.t, p.pose.x, p.pose.y, sh, ch);
    }
    write_text(path, &s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::text::from_str;

    #[test]
    fn yaw_from_quaternion() {
        // 90° about z: q = (0, 0, √½, √½).
        let h = 0.5f64.sqrt();
        let f = from_str("a.tum", &format!("# c\n1.5 2 3 0 0 0 {h} {h}\n"));
        let t = parse_tum(&f).unwrap();
        assert_eq!(t.len(), 1);
        assert_eq!(t[0].t, 1.5);
        assert!(t[0]
            .pose
            .approx_eq(&Pose2::new(2.0, 3.0, std::f64::consts::FRAC_PI_2), 1e-12));
    }

    #[test]
    fn error_paths() {
        for (text, want) in [
            ("", "empty"),
            ("1 2 3 0 0 0 0\n", "line ended early"),
            ("1 2 3 0 0 0 0 1 9\n", "end of line"),
            ("1 2 3 0 0 0 0 2\n", "unit quaternion"),
            ("1 nan 3 0 0 0 0 1\n", "not finite"),
            ("1 2 3 0 0 0 0 one\n", "qw (a number)"),
        ] {
            let e = parse_tum(&from_str("a.tum", text)).unwrap_err().to_string();
            assert!(e.contains(want) && e.contains("a.tum"), "{text:?} → {e}");
        }
    }

    #[test]
    fn round_trip_is_exact() {
        let dir = std::env::temp_dir().join(format!("slam-io-tum-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("t.tum");
        let traj: Vec<TimedPose> = (0..50)
            .map(|i| TimedPose {
                t: 1e9 + i as f64 * 0.013,
                pose: Pose2::new(i as f64 * 0.1, -(i as f64).sqrt(), i as f64 * 0.3),
            })
            .collect();
        write_tum(&p, &traj).unwrap();
        let back = read_tum(&p).unwrap();
        for (a, b) in traj.iter().zip(&back) {
            assert_eq!(a.t, b.t);
            assert!(a.pose.approx_eq(&b.pose, 1e-12));
        }
        assert!(write_tum(
            &p,
            &[TimedPose {
                t: f64::NAN,
                pose: Pose2::IDENTITY
            }]
        )
        .is_err());
        std::fs::remove_dir_all(&dir).ok();
    }
}
