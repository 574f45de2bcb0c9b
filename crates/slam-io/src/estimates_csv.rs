//! Per-step pose estimates as CSV, for consistency plots: header
//! `step,time,x,y,theta,cxx,cxy,cxtheta,cyy,cytheta,cthetatheta,nees`, one line per step.
//!
//! * `step`: the 0-based index of the data step (file order); `time`: its time stamp, s.
//! * `x, y, theta`: the mean μ of the filter's Gaussian summary of the pose posterior
//!   (metres, radians in (−π, π]) — for particle filters the weighted mean of the
//!   particles, not the best particle.
//! * `cxx … cthetatheta`: the six distinct entries of its 3×3 covariance Σ (m², m·rad,
//!   rad²), row by row of the upper triangle; the matrix is symmetrised on writing.
//! * `nees`: ε = eᵀΣ⁻¹e with e = x_true ⊖ μ (angle difference normalised), χ²(3) for a
//!   consistent filter; empty when there is no true pose for the step, `NaN` when Σ is
//!   not positive definite (a collapsed particle cloud).
//!
//! Numbers are written in Rust's shortest round-trip form, so reading gives back the same
//! bits.

use crate::error::IoError;
use crate::text::{read_text, rows_after_header, write_text, Line};
use slam_models::{Matrix3, Pose2};
use std::fmt::Write as _;
use std::path::Path;

/// The header line.
pub const HEADER: &str = "step,time,x,y,theta,cxx,cxy,cxtheta,cyy,cytheta,cthetatheta,nees";

/// One line of the file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseEstimateRow {
    /// 0-based index of the data step.
    pub step: usize,
    /// Time stamp of the step, seconds.
    pub t: f64,
    /// Mean of the pose posterior's Gaussian summary.
    pub pose: Pose2,
    /// Its covariance (symmetric).
    pub covariance: Matrix3,
    /// Pose NEES against the true pose; `None` without a true pose, NaN when the
    /// covariance is not positive definite.
    pub nees: Option<f64>,
}

/// Writes `rows` under [`HEADER`]. Errors on a non-finite time, pose or covariance entry
/// (naming the step); the NEES may be NaN or ∞.
pub fn write_estimates_csv(path: &Path, rows: &[PoseEstimateRow]) -> Result<(), IoError> {
    let mut s = String::with_capacity(160 * (rows.len() + 1));
    s.push_str(HEADER);
    s.push('\n');
    for r in rows {
        let c = r.covariance;
        let sym = |i: usize, j: usize| 0.5 * (c[(i, j)] + c[(j, i)]);
        let v = [
            r.t,
            r.pose.x,
            r.pose.y,
            r.pose.theta,
            c[(0, 0)],
            sym(0, 1),
            sym(0, 2),
            c[(1, 1)],
            sym(1, 2),
            c[(2, 2)],
        ];
        if v.iter().any(|x| !x.is_finite()) {
            return Err(IoError::invalid(
                path,
                format!("step {}: non-finite time, pose or covariance", r.step),
            ));
        }
        let _ = write!(s, "{}", r.step);
        for x in v {
            let _ = write!(s, ",{x}");
        }
        match r.nees {
            Some(e) => {
                let _ = writeln!(s, ",{e}");
            }
            None => s.push_str(",\n"),
        }
    }
    write_text(path, &s)
}

/// Reads a file written by [`write_estimates_csv`]. Errors name the line and field.
pub fn read_estimates_csv(path: &Path) -> Result<Vec<PoseEstimateRow>, IoError> {
    let f = read_text(path)?;
    let lines = rows_after_header(path, &f.text, HEADER)?;
    let mut out = Vec::new();
    for (i, l) in lines {
        let (head, nees) = l.trim_end().rsplit_once(',').unwrap_or((l, ""));
        let spaced = head.replace(',', " ");
        let mut line = Line::new(path, i + 1, &spaced);
        let step = line.u64("step")?;
        let step = usize::try_from(step).map_err(|_| line.error("a step index", head))?;
        let t = line.f64("time")?;
        let pose = Pose2 {
            x: line.f64("x")?,
            y: line.f64("y")?,
            theta: line.f64("theta")?,
        };
        let mut e = [0.0; 6];
        for (v, what) in
            e.iter_mut()
                .zip(["cxx", "cxy", "cxtheta", "cyy", "cytheta", "cthetatheta"])
        {
            *v = line.f64(what)?;
        }
        line.end("cthetatheta")?;
        let nees = match nees.trim() {
            "" => None,
            w => Some(
                w.parse::<f64>()
                    .map_err(|_| line.error("nees (a number, NaN, inf or empty)", w))?,
            ),
        };
        out.push(PoseEstimateRow {
            step,
            t,
            pose,
            covariance: Matrix3::new(e[0], e[1], e[2], e[1], e[3], e[4], e[2], e[4], e[5]),
            nees,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_errors() {
        let d = std::env::temp_dir().join(format!("slam-io-estimates-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join("e.csv");
        let c = Matrix3::new(0.1, 0.02, 0.003, 0.02, 0.3, -0.004, 0.003, -0.004, 0.01);
        let rows = vec![
            PoseEstimateRow {
                step: 0,
                t: 0.1,
                pose: Pose2::new(1.25, -2.5, 0.5),
                covariance: c,
                nees: Some(2.75),
            },
            PoseEstimateRow {
                step: 1,
                t: 0.2,
                pose: Pose2::new(1e-7, 7.0, -3.0),
                covariance: c * 2.0,
                nees: None,
            },
            PoseEstimateRow {
                step: 2,
                t: 0.3,
                pose: Pose2::IDENTITY,
                covariance: Matrix3::zeros(),
                nees: Some(f64::INFINITY),
            },
        ];
        write_estimates_csv(&p, &rows).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        let want = format!(
            "{HEADER}\n0,0.1,1.25,-2.5,0.5,0.1,0.02,0.003,0.3,-0.004,0.01,2.75\n\
             1,0.2,0.0000001,7,-3,0.2,0.04,0.006,0.6,-0.008,0.02,\n"
        );
        assert!(text.starts_with(&want), "{text}");
        assert_eq!(read_estimates_csv(&p).unwrap(), rows);
        // NaN NEES (covariance not positive definite) survives the round trip as NaN.
        let mut nan = rows[..1].to_vec();
        nan[0].nees = Some(f64::NAN);
        write_estimates_csv(&p, &nan).unwrap();
        assert!(read_estimates_csv(&p).unwrap()[0].nees.unwrap().is_nan());
        for (text, want) in [
            ("", "empty"),
            ("a,b\n", "header"),
            (&format!("{HEADER}\n1,2,3\n") as &str, "line ended early"),
            (&format!("{HEADER}\n0,0,0,0,0,1,0,0,1,0,1,x\n"), "nees"),
            (
                &format!("{HEADER}\n0,0,nan,0,0,1,0,0,1,0,1,\n"),
                "not finite",
            ),
        ] {
            std::fs::write(&p, text).unwrap();
            let e = read_estimates_csv(&p).unwrap_err().to_string();
            assert!(e.contains(want), "{text:?} → {e}");
        }
        let mut bad = rows.clone();
        bad[1].covariance[(2, 2)] = f64::NAN;
        let e = write_estimates_csv(&p, &bad).unwrap_err().to_string();
        assert!(e.contains("step 1"), "{e}");
        std::fs::remove_dir_all(&d).ok();
    }
}
