//! Pose-graph files ↔ [`PoseGraph`]: slam-io reads and writes plain records
//! ([`slam_io::g2o`]); this module resolves them into an optimisable graph and back.
//!
//! * Vertices become nodes in file order; edges join them by id.
//! * `EQUIV a b` merges b into a (union by the smaller id, transitively): b's vertex line is
//!   dropped and every edge naming b names a; an edge that then joins a vertex to itself is
//!   dropped (it constrains nothing).
//! * A file with edges but no vertex lines (some published graphs) gets its poses by
//!   composing the odometry chain: breadth-first from the smallest id along odometry edges
//!   (ids differing by one) first, then along any edge, each pose the composition of its
//!   parent's with the edge's measurement (inverted when walked backwards).
//! * Errors name the file, the line and the element: a duplicate vertex, an edge or FIX
//!   naming an unknown vertex, wrong vertex kinds, a pose an edges-only file cannot reach.

use slam_graph::{Edge, NodeValue, PoseGraph};
use slam_io::g2o::{read_graph_file, write_graph_file, GraphFile, GraphRecord};
use slam_io::IoError;
use slam_models::Pose2;
use std::collections::{BTreeMap, HashMap, VecDeque};
use std::path::Path;

/// Reads a g2o or TORO pose-graph file into a graph (see the module documentation).
pub fn read_pose_graph(path: &Path) -> Result<PoseGraph, IoError> {
    graph_from_file(&read_graph_file(path)?)
}

/// Writes `graph` in g2o format: vertices in node order, then edges in edge order, then one
/// `FIX` line with the fixed nodes; reading it back gives the same graph bit for bit.
/// Range-bearing edges have no g2o 2-D tag and are an error.
pub fn write_pose_graph(path: &Path, graph: &PoseGraph) -> Result<(), IoError> {
    write_graph_file(path, &records_of(path, graph)?)
}

/// The records of `graph`, as [`write_pose_graph`] writes them.
pub fn records_of(path: &Path, g: &PoseGraph) -> Result<Vec<GraphRecord>, IoError> {
    let mut out = Vec::with_capacity(g.nodes().len() + g.edges().len() + 1);
    for n in g.nodes() {
        out.push(match n.value {
            NodeValue::Pose(pose) => GraphRecord::Pose { id: n.id, pose },
            NodeValue::Point(point) => GraphRecord::Point { id: n.id, point },
        });
    }
    let id = |i: usize| g.nodes()[i].id;
    for (k, e) in g.edges().iter().enumerate() {
        out.push(match e {
            Edge::Between(e) => GraphRecord::PoseEdge {
                from: id(e.from),
                to: id(e.to),
                measurement: e.measurement,
                information: e.information,
            },
            Edge::PointXy(e) => GraphRecord::PointEdge {
                pose: id(e.pose),
                point: id(e.point),
                measurement: e.measurement,
                information: e.information,
            },
            Edge::RangeBearing(_) => {
                return Err(IoError::Invalid {
                    path: path.to_path_buf(),
                    reason: format!(
                        "edge {k} is range-bearing, which g2o's 2-D format cannot hold"
                    ),
                })
            }
        });
    }
    let fixed: Vec<u64> = g.nodes().iter().filter(|n| n.fixed).map(|n| n.id).collect();
    if !fixed.is_empty() {
        out.push(GraphRecord::Fix { ids: fixed });
    }
    Ok(out)
}

/// The representative of `v` under the EQUIV merges.
fn find(parent: &mut HashMap<u64, u64>, v: u64) -> u64 {
    let mut r = v;
    while let Some(&p) = parent.get(&r) {
        if p == r {
            break;
        }
        r = p;
    }
    // Path compression.
    let mut c = v;
    while c != r {
        let next = parent.get(&c).copied().unwrap_or(r);
        parent.insert(c, r);
        c = next;
    }
    r
}

/// Builds the graph of a file's records (see the module documentation).
pub fn graph_from_file(f: &GraphFile) -> Result<PoseGraph, IoError> {
    // EQUIV: union by the smaller id.
    let mut parent: HashMap<u64, u64> = HashMap::new();
    for r in &f.records {
        if let GraphRecord::Equiv { a, b } = r.record {
            let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
            let (keep, drop) = (ra.min(rb), ra.max(rb));
            if keep != drop {
                parent.insert(drop, keep);
            }
        }
    }
    let mut rep = |v: u64| find(&mut parent, v);
    let has_vertices = f.records.iter().any(|r| {
        matches!(
            r.record,
            GraphRecord::Pose { .. } | GraphRecord::Point { .. }
        )
    });
    let at = |line: usize, e: slam_graph::GraphError| {
        f.error(line, "a consistent graph element", e.to_string())
    };
    let mut g = PoseGraph::new();
    if has_vertices {
        for r in &f.records {
            match r.record {
                GraphRecord::Pose { id, pose } if rep(id) == id => {
                    g.add_pose(id, pose).map_err(|e| at(r.line, e))?;
                }
                GraphRecord::Point { id, point } if rep(id) == id => {
                    g.add_point(id, point).map_err(|e| at(r.line, e))?;
                }
                _ => {}
            }
        }
    } else {
        for (id, pose) in compose_chain(f, &mut rep)? {
            g.add_pose(id, pose).map_err(|e| at(0, e))?;
        }
    }
    let mut fixes = Vec::new();
    for r in &f.records {
        match r.record {
            GraphRecord::PoseEdge {
                from,
                to,
                measurement,
                information,
            } => {
                let (a, b) = (rep(from), rep(to));
                if a != b || from == to {
                    g.add_between(a, b, measurement, information)
                        .map_err(|e| at(r.line, e))?;
                }
            }
            GraphRecord::PointEdge {
                pose,
                point,
                measurement,
                information,
            } => {
                let (a, b) = (rep(pose), rep(point));
                g.add_point_xy(a, b, measurement, information)
                    .map_err(|e| at(r.line, e))?;
            }
            GraphRecord::Fix { ref ids } => {
                fixes.extend(ids.iter().map(|&v| (r.line, v)));
            }
            _ => {}
        }
    }
    for (line, v) in fixes {
        let v = rep(v);
        g.fix(v)
            .map_err(|e| f.error(line, "FIX of a declared vertex", e.to_string()))?;
    }
    if g.nodes().is_empty() {
        return Err(IoError::Empty {
            path: f.path.clone(),
            expected: "at least one VERTEX_SE2, VERTEX2, VERTEX_XY or EDGE_SE2".into(),
        });
    }
    Ok(g)
}

/// Poses of an edges-only file: every id an edge names, composed breadth-first from the
/// smallest (at the origin), odometry edges first.
fn compose_chain(
    f: &GraphFile,
    rep: &mut impl FnMut(u64) -> u64,
) -> Result<BTreeMap<u64, Pose2>, IoError> {
    // (line, from, to, z) of every pose edge; a point edge in an edges-only file names a
    // point no line declares.
    let mut edges = Vec::new();
    for r in &f.records {
        match r.record {
            GraphRecord::PoseEdge {
                from,
                to,
                measurement,
                ..
            } => edges.push((r.line, rep(from), rep(to), measurement)),
            GraphRecord::PointEdge { point, .. } => {
                return Err(f.error(
                    r.line,
                    "a VERTEX_XY line for every point (an edges-only file can hold poses only)",
                    format!("EDGE_SE2_XY to undeclared point {point}"),
                ))
            }
            _ => {}
        }
    }
    let mut adj: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
    for (k, &(_, a, b, _)) in edges.iter().enumerate() {
        adj.entry(a).or_default().push(k);
        adj.entry(b).or_default().push(k);
    }
    let mut poses: BTreeMap<u64, Pose2> = BTreeMap::new();
    let Some(&root) = adj.keys().next() else {
        return Ok(poses);
    };
    poses.insert(root, Pose2::IDENTITY);
    // Pass 1 walks odometry edges only; pass 2 any edge, from every pose placed so far.
    for odometry_only in [true, false] {
        let mut queue: VecDeque<u64> = poses.keys().copied().collect();
        while let Some(v) = queue.pop_front() {
            let here = poses[&v];
            for &k in &adj[&v] {
                let (_, a, b, z) = edges[k];
                if odometry_only && a.abs_diff(b) != 1 {
                    continue;
                }
                let (other, p) = if a == v {
                    (b, here.compose(&z))
                } else {
                    (a, here.compose(&z.inverse()))
                };
                if let std::collections::btree_map::Entry::Vacant(e) = poses.entry(other) {
                    e.insert(p);
                    queue.push_back(other);
                }
            }
        }
    }
    if let Some((&v, _)) = adj.iter().find(|(v, _)| !poses.contains_key(v)) {
        let line = edges
            .iter()
            .find(|&&(_, a, b, _)| a == v || b == v)
            .map_or(0, |e| e.0);
        return Err(f.error(
            line,
            format!("vertex {v} joined by edges to vertex {root} (the file has no vertex lines, so poses are composed along edges)"),
            format!("vertex {v} in a separate component"),
        ));
    }
    Ok(poses)
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::Matrix3;

    fn graph(text: &str) -> Result<PoseGraph, IoError> {
        let dir = std::env::temp_dir().join(format!("slam-eval-pg-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(format!("g{}.g2o", text.len()));
        std::fs::write(&p, text).unwrap();
        let g = read_pose_graph(&p);
        std::fs::remove_file(&p).ok();
        g
    }

    /// Edges only: poses composed along the odometry chain (not the closure 0 → 2, which
    /// disagrees with it), each the composition of the measured steps by hand.
    #[test]
    fn edges_only_composes_the_odometry_chain() {
        let g = graph(
            "EDGE_SE2 0 2 5 5 0 1 0 0 1 0 1\n\
             EDGE_SE2 0 1 1 0 1.5707963267948966 1 0 0 1 0 1\n\
             EDGE_SE2 2 1 -1 0 0 1 0 0 1 0 1\n\
             EDGE_SE2 3 2 0 -2 0 1 0 0 1 0 1\n",
        )
        .unwrap();
        assert_eq!(g.nodes().len(), 4);
        // 1 = (1, 0, π/2); 2 = 1 ∘ (−1, 0, 0)⁻¹ = 1 ∘ (1, 0, 0) = (1, 1, π/2);
        // 3 = 2 ∘ (0, −2, 0)⁻¹ = 2 ∘ (0, 2, 0) = (−1, 1, π/2).
        let h = std::f64::consts::FRAC_PI_2;
        assert!(g
            .pose(1)
            .unwrap()
            .approx_eq(&Pose2::new(1.0, 0.0, h), 1e-12));
        assert!(g
            .pose(2)
            .unwrap()
            .approx_eq(&Pose2::new(1.0, 1.0, h), 1e-12));
        assert!(g
            .pose(3)
            .unwrap()
            .approx_eq(&Pose2::new(-1.0, 1.0, h), 1e-12));
        assert_eq!(g.edges().len(), 4);
        // A vertex no edge path reaches: an error naming it and its line.
        let e = graph("EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\nEDGE_SE2 5 6 1 0 0 1 0 0 1 0 1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains(":2:") && e.contains("vertex 5"), "{e}");
    }

    /// EQUIV merges the larger id into the smaller: its vertex and the edge between the two
    /// disappear, its edges move.
    #[test]
    fn equiv_merges_vertices() {
        let g = graph(
            "VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\nVERTEX2 2 1.1 0 0\nVERTEX2 3 2 0 0\n\
             EDGE2 0 1 1 0 0 1 0 1 1 0 0\nEDGE2 1 2 0 0 0 1 0 1 1 0 0\n\
             EDGE2 2 3 1 0 0 1 0 1 1 0 0\nEQUIV 2 1\n",
        )
        .unwrap();
        let ids: Vec<u64> = g.nodes().iter().map(|n| n.id).collect();
        assert_eq!(ids, [0, 1, 3]);
        assert_eq!(g.edges().len(), 2);
        let (a, b) = g.edges()[1].nodes();
        assert_eq!((g.nodes()[a].id, g.nodes()[b].id), (1, 3));
    }

    #[test]
    fn graph_errors_name_file_and_line() {
        for (text, want) in [
            (
                "VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n",
                ":2:",
            ),
            ("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 0 1 0 0\n", "already exists"),
            (
                "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 0 0 0\nEDGE_SE2_XY 0 1 1 0 1 0 1\n",
                "a pose then a point",
            ),
            ("VERTEX_SE2 0 0 0 0\nFIX 3\n", "unknown node 3"),
            ("EDGE_SE2_XY 0 1 1 0 1 0 1\n", "VERTEX_XY"),
        ] {
            let e = graph(text).unwrap_err().to_string();
            assert!(e.contains(want), "{text:?} → {e}");
        }
    }

    #[test]
    fn round_trip_is_exact() {
        let dir = std::env::temp_dir().join(format!("slam-eval-pg-rt-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("g.g2o");
        let mut g = PoseGraph::new();
        g.add_pose(0, Pose2::IDENTITY).unwrap();
        g.add_pose(12, Pose2::new(0.1 + 0.2, -1e-300, std::f64::consts::PI))
            .unwrap();
        g.add_point(7, slam_models::Point2::new(2.0, 3.0)).unwrap();
        g.add_between(
            0,
            12,
            Pose2::new(1.0 / 3.0, 987_654.321_098_765_4, -2.0),
            Matrix3::new(1e6, 0.1, 0.0, 0.1, 1e-3, 0.0, 0.0, 0.0, 7.0),
        )
        .unwrap();
        g.add_point_xy(
            12,
            7,
            slam_models::Point2::new(0.5, 0.5),
            slam_models::Matrix2::identity(),
        )
        .unwrap();
        g.fix(12).unwrap();
        write_pose_graph(&p, &g).unwrap();
        let back = read_pose_graph(&p).unwrap();
        assert_eq!(back.nodes(), g.nodes());
        assert_eq!(back.edges(), g.edges());
        g.add_range_bearing(0, 7, 1.0, 0.5, slam_models::Matrix2::identity())
            .unwrap();
        let e = write_pose_graph(&p, &g).unwrap_err().to_string();
        assert!(e.contains("range-bearing"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
