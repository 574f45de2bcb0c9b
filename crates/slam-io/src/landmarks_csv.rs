//! Landmark maps as CSV: header `id,x,y,cxx,cxy,cyy`, one estimated landmark per line
//! (metres, covariance entries in m²).
//!
//! **Bounds** ([`crate::bounds`]): x, y within ±10⁶ m; variances `cxx`, `cyy` within
//! 0 … 10¹² m² and `cxy` within ±10¹² m². A violation is an error naming the file, line,
//! field and bound.

use crate::bounds::MAX_MAGNITUDE;
use crate::error::IoError;
use crate::text::{read_text, rows_after_header, write_text};
use slam_models::{LandmarkEstimate, LandmarkId, Matrix2, Point2};
use std::fmt::Write as _;
use std::path::Path;

/// The header line.
pub const HEADER: &str = "id,x,y,cxx,cxy,cyy";

/// Writes the landmarks (mean and the 2×2 covariance's three distinct entries; the
/// covariance is symmetrised). Errors on non-finite values.
pub fn write_landmarks_csv(path: &Path, l: &[LandmarkEstimate]) -> Result<(), IoError> {
    let mut s = String::with_capacity(64 * (l.len() + 1));
    s.push_str(HEADER);
    s.push('\n');
    for e in l {
        let c = e.covariance;
        let cxy = 0.5 * (c[(0, 1)] + c[(1, 0)]);
        let v = [e.mean.x, e.mean.y, c[(0, 0)], cxy, c[(1, 1)]];
        if v.iter().any(|x| !x.is_finite()) {
            return Err(IoError::invalid(
                path,
                format!("landmark {} has a non-finite value", e.id),
            ));
        }
        let _ = writeln!(s, "{},{},{},{},{},{}", e.id.0, v[0], v[1], v[2], v[3], v[4]);
    }
    write_text(path, &s)
}

/// Reads a file written by [`write_landmarks_csv`]. Errors name the line and field.
pub fn read_landmarks_csv(path: &Path) -> Result<Vec<LandmarkEstimate>, IoError> {
    let f = read_text(path)?;
    let lines = rows_after_header(path, &f.text, HEADER)?;
    let mut out = Vec::new();
    for (i, l) in lines {
        let spaced = l.replace(',', " ");
        let mut line = crate::text::Line::new(path, i + 1, &spaced);
        let id = line.u64("landmark id")?;
        let id = u32::try_from(id).map_err(|_| line.error("an id below 2^32", l))?;
        let x = line.coord("x")?;
        let y = line.coord("y")?;
        let cxx = line.f64_in("cxx", 0.0, MAX_MAGNITUDE, "m²")?;
        let cxy = line.f64("cxy")?;
        let cyy = line.f64_in("cyy", 0.0, MAX_MAGNITUDE, "m²")?;
        line.end(HEADER)?;
        out.push(LandmarkEstimate {
            id: LandmarkId(id),
            mean: Point2::new(x, y),
            covariance: Matrix2::new(cxx, cxy, cxy, cyy),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_errors() {
        let d = std::env::temp_dir().join(format!("slam-io-csv-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join("l.csv");
        let l = vec![
            LandmarkEstimate {
                id: LandmarkId(3),
                mean: Point2::new(1.25, -2.5),
                covariance: Matrix2::new(0.1, 0.02, 0.02, 0.3),
            },
            LandmarkEstimate {
                id: LandmarkId(9),
                mean: Point2::new(1e-7, 7.0),
                covariance: Matrix2::identity(),
            },
        ];
        write_landmarks_csv(&p, &l).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(
            text.starts_with("id,x,y,cxx,cxy,cyy\n3,1.25,-2.5,0.1,0.02,0.3\n"),
            "{text}"
        );
        assert_eq!(read_landmarks_csv(&p).unwrap(), l);
        for (text, want) in [
            ("", "empty"),
            ("a,b\n", "header"),
            ("id,x,y,cxx,cxy,cyy\n1,2,3\n", "line ended early"),
            ("id,x,y,cxx,cxy,cyy\n1,2,3,4,nan,6\n", "not finite"),
        ] {
            std::fs::write(&p, text).unwrap();
            let e = read_landmarks_csv(&p).unwrap_err().to_string();
            assert!(e.contains(want), "{text:?} → {e}");
        }
        let mut bad = l.clone();
        bad[0].mean.x = f64::INFINITY;
        assert!(write_landmarks_csv(&p, &bad).is_err());
        std::fs::remove_dir_all(&d).ok();
    }
}
