//! Relations files of the Freiburg SLAM benchmark (Kümmerle et al., *On measuring the
//! accuracy of SLAM algorithms*, Autonomous Robots 27, 2009).
//!
//! Each line `t1 t2 x y z roll pitch yaw` is one relation: the robot's pose at `t2`
//! expressed in its frame at `t1` (metres, radians). z, roll and pitch must be 0 (planar
//! data); lines with `t2 < t1` are kept as given (the Intel file has six).
//!
//! **Bounds** ([`crate::bounds`]): t1, t2 within ±10¹⁰ s and |t2 − t1| ≤ 10⁷ s; x, y
//! within ±10⁶ m; yaw within ±2π rad. A violation is an error naming the file, line, field
//! and bound.

use crate::bounds::{TimeSpan, MAX_TIME_SPAN};
use crate::error::IoError;
use crate::text::{read_text, TextFile};
use slam_models::Pose2;
use std::path::Path;

/// One ground-truth relation δ*: the pose at `t2` in the frame of the pose at `t1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Relation {
    /// Time of the first pose, seconds.
    pub t1: f64,
    /// Time of the second pose, seconds.
    pub t2: f64,
    /// The relative pose (x, y in metres, yaw in radians).
    pub delta: Pose2,
}

/// Reads a relations file. Errors: malformed line, NaN/∞, non-zero z/roll/pitch (not a
/// planar relation), a value out of bounds (module docs), empty file.
pub fn read_relations(path: &Path) -> Result<Vec<Relation>, IoError> {
    parse_relations(&read_text(path)?)
}

pub(crate) fn parse_relations(f: &TextFile) -> Result<Vec<Relation>, IoError> {
    f.ensure_not_empty("relation lines `t1 t2 x y z roll pitch yaw`")?;
    let mut out = Vec::new();
    for mut l in f.data_lines() {
        // Each relation's own pair of times; relations are not in time order.
        let t1 = l.time("t1", &mut TimeSpan::default())?;
        let t2 = l.f64_in(
            "t2",
            t1 - MAX_TIME_SPAN,
            t1 + MAX_TIME_SPAN,
            "s (t1 ± 1e7 s)",
        )?;
        let x = l.coord("x")?;
        let y = l.coord("y")?;
        let z = l.f64("z")?;
        let roll = l.f64("roll")?;
        let pitch = l.f64("pitch")?;
        let yaw = l.angle("yaw")?;
        l.end("`t1 t2 x y z roll pitch yaw`")?;
        if z != 0.0 || roll != 0.0 || pitch != 0.0 {
            return Err(l.error("a planar relation (z = roll = pitch = 0)", l.text));
        }
        out.push(Relation {
            t1,
            t2,
            delta: Pose2::new(x, y, yaw),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::text::from_str;

    #[test]
    fn parses_and_rejects() {
        let r = parse_relations(&from_str(
            "r",
            "976052905.167303 976052911.885496 -0.056990 -0.128430 0.000000 0.000000 0.000000 -1.682210\n",
        ))
        .unwrap();
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].t1, 976052905.167303);
        assert!((r[0].delta.theta + 1.68221).abs() < 1e-12);
        for (text, want) in [
            ("", "empty"),
            ("1 2 3 4 0 0 0\n", "line ended early"),
            ("1 2 3 4 0 0 0 5 6\n", "end of line"),
            ("1 2 3 4 1 0 0 5\n", "planar"),
            ("1 2 inf 4 0 0 0 5\n", "not finite"),
        ] {
            let e = parse_relations(&from_str("r.rel", text))
                .unwrap_err()
                .to_string();
            assert!(e.contains(want) && e.contains("r.rel"), "{text:?} → {e}");
        }
    }
}
