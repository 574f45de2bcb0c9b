//! g2o graph files, 2-D subset (Kümmerle et al., "g2o: A general framework for graph
//! optimization", ICRA 2011; the text format of g2o's `types_slam2d`).
//!
//! One element per line, whitespace-separated; `#` starts a comment line:
//!
//! * `VERTEX_SE2 id x y θ`: a pose (metres, radians);
//! * `VERTEX_XY id x y`: a point;
//! * `EDGE_SE2 i j dx dy dθ I11 I12 I13 I22 I23 I33`: pose j measured in pose i's frame, and
//!   the upper triangle of the 3×3 information matrix, row by row (g2o's write order);
//! * `EDGE_SE2_XY i j x y I11 I12 I22`: point j measured in pose i's frame;
//! * `FIX id ...`: nodes held fixed by the optimiser.
//!
//! Any other tag is an error naming the file and line (silently skipping an edge type would
//! change the problem). Ids are g2o's `int`, 0 ..= 2³¹ − 1; a vertex must be declared before
//! an edge uses it; information matrices must be symmetric positive definite.

use crate::error::IoError;
use crate::text::{read_text, write_text, Line, TextFile};
use slam_graph::{Edge, GraphError, NodeValue, PoseGraph};
use slam_models::{Matrix2, Matrix3, Point2, Pose2};
use std::fmt::Write as _;
use std::path::Path;

/// Largest id g2o can hold (its ids are C `int`).
const MAX_ID: u64 = i32::MAX as u64;

/// Reads a g2o file into a pose graph. Errors (each with file and line): an unknown tag, a
/// malformed or non-finite field, an id above 2³¹ − 1, a duplicate vertex, an edge or FIX
/// naming an undeclared vertex or joining the wrong kinds, an information matrix that is not
/// positive definite, or a file without vertices.
pub fn read_g2o(path: &Path) -> Result<PoseGraph, IoError> {
    parse_g2o(&read_text(path)?)
}

fn id(l: &mut Line<'_>, what: &str) -> Result<u64, IoError> {
    let v = l.u64(what)?;
    if v > MAX_ID {
        return Err(l.error(
            format!("{what} ≤ {MAX_ID} (g2o ids are int)"),
            &v.to_string(),
        ));
    }
    Ok(v)
}

/// The graph's error, placed at this line.
fn at(l: &Line<'_>, e: GraphError) -> IoError {
    IoError::Parse {
        path: l.path.to_path_buf(),
        line: l.no,
        expected: "a consistent graph element".into(),
        found: e.to_string(),
    }
}

pub(crate) fn parse_g2o(f: &TextFile) -> Result<PoseGraph, IoError> {
    f.ensure_not_empty("g2o lines (VERTEX_SE2, EDGE_SE2, ...)")?;
    let mut g = PoseGraph::new();
    let mut fixes: Vec<(usize, u64)> = Vec::new();
    for mut l in f.data_lines() {
        let tag = l.word("a tag")?;
        match tag {
            "VERTEX_SE2" => {
                let i = id(&mut l, "vertex id")?;
                let p = Pose2::new(l.f64("x")?, l.f64("y")?, l.f64("theta")?);
                l.end("VERTEX_SE2 id x y theta")?;
                g.add_pose(i, p).map_err(|e| at(&l, e))?;
            }
            "VERTEX_XY" => {
                let i = id(&mut l, "vertex id")?;
                let p = Point2::new(l.f64("x")?, l.f64("y")?);
                l.end("VERTEX_XY id x y")?;
                g.add_point(i, p).map_err(|e| at(&l, e))?;
            }
            "EDGE_SE2" => {
                let a = id(&mut l, "first vertex id")?;
                let b = id(&mut l, "second vertex id")?;
                let z = Pose2::new(l.f64("dx")?, l.f64("dy")?, l.f64("dtheta")?);
                let mut u = [0.0; 6];
                for (k, name) in ["I11", "I12", "I13", "I22", "I23", "I33"]
                    .iter()
                    .enumerate()
                {
                    u[k] = l.f64(name)?;
                }
                l.end("EDGE_SE2 i j dx dy dtheta I11 I12 I13 I22 I23 I33")?;
                let info = Matrix3::new(u[0], u[1], u[2], u[1], u[3], u[4], u[2], u[4], u[5]);
                g.add_between(a, b, z, info).map_err(|e| at(&l, e))?;
            }
            "EDGE_SE2_XY" => {
                let a = id(&mut l, "pose vertex id")?;
                let b = id(&mut l, "point vertex id")?;
                let z = Point2::new(l.f64("x")?, l.f64("y")?);
                let (i11, i12, i22) = (l.f64("I11")?, l.f64("I12")?, l.f64("I22")?);
                l.end("EDGE_SE2_XY i j x y I11 I12 I22")?;
                let info = Matrix2::new(i11, i12, i12, i22);
                g.add_point_xy(a, b, z, info).map_err(|e| at(&l, e))?;
            }
            "FIX" => {
                let mut any = false;
                while let Ok(w) = l.word("a vertex id") {
                    let v: u64 = w
                        .parse()
                        .ok()
                        .filter(|&v| v <= MAX_ID)
                        .ok_or_else(|| l.error(format!("a vertex id ≤ {MAX_ID}"), w))?;
                    fixes.push((l.no, v));
                    any = true;
                }
                if !any {
                    return Err(l.error("FIX followed by vertex ids", l.text.trim()));
                }
            }
            other => {
                return Err(l.error(
                    "a known tag (VERTEX_SE2, VERTEX_XY, EDGE_SE2, EDGE_SE2_XY, FIX)",
                    other,
                ))
            }
        }
    }
    for (line, v) in fixes {
        g.fix(v).map_err(|e| IoError::Parse {
            path: f.path.clone(),
            line,
            expected: "FIX of a declared vertex".into(),
            found: e.to_string(),
        })?;
    }
    if g.nodes().is_empty() {
        return Err(IoError::Empty {
            path: f.path.clone(),
            expected: "at least one VERTEX_SE2 or VERTEX_XY".into(),
        });
    }
    Ok(g)
}

/// Writes a graph in g2o format: vertices in node order, then edges in edge order, then one
/// `FIX` line with the fixed nodes; numbers in shortest round-trip form, so reading the file
/// back gives the same graph bit for bit. Range-bearing edges have no g2o 2-D tag and are an
/// error, as are non-finite values.
pub fn write_g2o(path: &Path, g: &PoseGraph) -> Result<(), IoError> {
    write_text(path, &g2o_string(path, g)?)
}

fn g2o_string(path: &Path, g: &PoseGraph) -> Result<String, IoError> {
    let mut s = String::with_capacity(64 * (g.nodes().len() + 2 * g.edges().len()));
    let finite = |vals: &[f64], what: &str| {
        if vals.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(IoError::invalid(path, format!("{what} is not finite")))
        }
    };
    for n in g.nodes() {
        match n.value {
            NodeValue::Pose(p) => {
                finite(&[p.x, p.y, p.theta], &format!("vertex {}", n.id))?;
                let _ = writeln!(s, "VERTEX_SE2 {} {} {} {}", n.id, p.x, p.y, p.theta);
            }
            NodeValue::Point(p) => {
                finite(&[p.x, p.y], &format!("vertex {}", n.id))?;
                let _ = writeln!(s, "VERTEX_XY {} {} {}", n.id, p.x, p.y);
            }
        }
    }
    let id = |i: usize| g.nodes()[i].id;
    for (k, e) in g.edges().iter().enumerate() {
        match e {
            Edge::Between(e) => {
                let (z, m) = (e.measurement, e.information);
                let _ = writeln!(
                    s,
                    "EDGE_SE2 {} {} {} {} {} {} {} {} {} {} {}",
                    id(e.from),
                    id(e.to),
                    z.x,
                    z.y,
                    z.theta,
                    m[(0, 0)],
                    m[(0, 1)],
                    m[(0, 2)],
                    m[(1, 1)],
                    m[(1, 2)],
                    m[(2, 2)]
                );
            }
            Edge::PointXy(e) => {
                let (z, m) = (e.measurement, e.information);
                let _ = writeln!(
                    s,
                    "EDGE_SE2_XY {} {} {} {} {} {} {}",
                    id(e.pose),
                    id(e.point),
                    z.x,
                    z.y,
                    m[(0, 0)],
                    m[(0, 1)],
                    m[(1, 1)]
                );
            }
            Edge::RangeBearing(_) => {
                return Err(IoError::invalid(
                    path,
                    format!("edge {k} is range-bearing, which g2o's 2-D format cannot hold"),
                ))
            }
        }
    }
    let fixed: Vec<String> = g
        .nodes()
        .iter()
        .filter(|n| n.fixed)
        .map(|n| n.id.to_string())
        .collect();
    if !fixed.is_empty() {
        let _ = writeln!(s, "FIX {}", fixed.join(" "));
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::text::from_str;

    const SMALL: &str = "# a comment\n\
        VERTEX_SE2 0 0 0 0\n\
        VERTEX_SE2 1 1.5 -0.25 3.0\n\
        VERTEX_XY 7 2 3\n\
        EDGE_SE2 0 1 1.5 -0.25 3.0 10 1 2 20 3 30\n\
        EDGE_SE2_XY 1 7 0.5 0.5 4 0.5 5\n\
        FIX 0\n";

    #[test]
    fn reads_every_tag_and_the_upper_triangle_order() {
        let g = parse_g2o(&from_str("s.g2o", SMALL)).unwrap();
        assert_eq!(g.nodes().len(), 3);
        assert!(g.nodes()[0].fixed && !g.nodes()[1].fixed);
        assert_eq!(g.point(7), Some(Point2::new(2.0, 3.0)));
        let Edge::Between(e) = g.edges()[0] else {
            panic!("{:?}", g.edges()[0])
        };
        // I11 I12 I13 I22 I23 I33 row by row.
        let want = Matrix3::new(10.0, 1.0, 2.0, 1.0, 20.0, 3.0, 2.0, 3.0, 30.0);
        assert_eq!(e.information, want);
        assert_eq!(e.measurement, Pose2::new(1.5, -0.25, 3.0));
        let Edge::PointXy(e) = g.edges()[1] else {
            panic!("{:?}", g.edges()[1])
        };
        assert_eq!(e.information, Matrix2::new(4.0, 0.5, 0.5, 5.0));
    }

    #[test]
    fn errors_name_file_and_line() {
        for (text, line, want) in [
            ("", 0, "empty"),
            ("# c\n", 0, "empty"),
            ("VERTEX_SE2 0 0 0 0\nEDGE_SE3 0 1\n", 2, "known tag"),
            ("VERTEX_SE2 0 0 0\n", 1, "line ended early"),
            ("VERTEX_SE2 0 0 0 0 9\n", 1, "end of line"),
            ("VERTEX_SE2 -1 0 0 0\n", 1, "non-negative integer"),
            ("VERTEX_SE2 2147483648 0 0 0\n", 1, "g2o ids are int"),
            ("VERTEX_SE2 0 0 nan 0\n", 1, "not finite"),
            (
                "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 0 1 0 0\n",
                2,
                "already exists",
            ),
            (
                "VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n",
                2,
                "unknown node 1",
            ),
            (
                "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 0 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 -1 0 1\n",
                3,
                "positive definite",
            ),
            (
                "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 0 0 0\nEDGE_SE2_XY 0 1 1 0 1 0 1\n",
                3,
                "a pose then a point",
            ),
            ("VERTEX_SE2 0 0 0 0\nFIX\n", 2, "FIX followed by"),
            ("VERTEX_SE2 0 0 0 0\nFIX 0 x\n", 2, "vertex id"),
            ("VERTEX_SE2 0 0 0 0\nFIX 3\n", 2, "unknown node 3"),
            ("FIX 3\n", 1, "unknown node 3"),
        ] {
            let e = parse_g2o(&from_str("g.g2o", text)).unwrap_err().to_string();
            let place = if line > 0 {
                format!("g.g2o:{line}:")
            } else {
                "g.g2o".to_string()
            };
            assert!(e.contains(want) && e.contains(&place), "{text:?} → {e}");
        }
    }

    #[test]
    fn round_trip_is_exact() {
        let dir = std::env::temp_dir().join(format!("slam-io-g2o-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("g.g2o");
        let mut g = parse_g2o(&from_str("s.g2o", SMALL)).unwrap();
        // Awkward values: many digits, tiny and large magnitudes, heading at π.
        g.add_pose(12, Pose2::new(0.1 + 0.2, -1e-300, std::f64::consts::PI))
            .unwrap();
        g.add_between(
            1,
            12,
            Pose2::new(1.0 / 3.0, 2e10, -2.0),
            Matrix3::new(1e6, 0.1, 0.0, 0.1, 1e-3, 0.0, 0.0, 0.0, 7.0),
        )
        .unwrap();
        g.fix(12).unwrap();
        write_g2o(&p, &g).unwrap();
        let back = read_g2o(&p).unwrap();
        assert_eq!(back.nodes(), g.nodes());
        assert_eq!(back.edges(), g.edges());
        // Range-bearing edges cannot be written.
        g.add_range_bearing(1, 7, 1.0, 0.5, Matrix2::identity())
            .unwrap();
        let e = write_g2o(&p, &g).unwrap_err().to_string();
        assert!(e.contains("range-bearing"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
