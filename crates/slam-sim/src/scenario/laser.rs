//! The laser scenarios: `office`, `campus` and `replay`.

use super::ScenarioOptions;
use crate::error::{check_range, check_steps, SimError};
use crate::laser::{simulate_laser, LaserScanner, LaserSimConfig, Segment, World};
use crate::path::Path;
use crate::rng::{stream, tag};
use crate::LaserSimRun;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use slam_models::{GridMap, Point2};
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// The scanner and simulation settings with the options applied.
fn laser_config(
    name: &str,
    opts: &ScenarioOptions,
    max_range: f64,
    scans: usize,
) -> Result<LaserSimConfig, SimError> {
    let defaults = LaserSimConfig::default();
    check_steps("steps", scans.saturating_mul(defaults.odometry_per_scan))?;
    let mut cfg = LaserSimConfig {
        name: name.to_string(),
        scans,
        ..LaserSimConfig::default()
    };
    cfg.scanner = LaserScanner {
        beams: opts.beams.unwrap_or(181),
        max_range: opts.max_range.unwrap_or(max_range),
        sigma: opts.laser_sigma.unwrap_or(0.01),
        short_reading_probability: opts.short_reading_probability.unwrap_or(0.0),
        ..LaserScanner::default()
    };
    if let Some(a) = opts.odometry_alpha {
        cfg.odometry.alpha = a;
    }
    if let Some(k) = opts.noise_scale {
        check_range("noise_scale", k, 0.0, 1e3, "0 <= noise_scale <= 1000")?;
        cfg.odometry.alpha.iter_mut().for_each(|a| *a *= k * k);
        cfg.scanner.sigma *= k;
    }
    cfg.scanner.validate()?;
    Ok(cfg)
}

/// Scans for `laps` of a path of length `len` (or `opts.steps`).
fn scans_for(opts: &ScenarioOptions, len: f64, default_laps: f64) -> Result<usize, SimError> {
    if let Some(s) = opts.steps {
        return Ok(s);
    }
    let laps = opts.laps_or(default_laps)?;
    let c = LaserSimConfig::default();
    let per_scan = c.follower.speed * c.follower.dt * c.odometry_per_scan as f64;
    Ok(((laps * len / per_scan).round() as usize).max(1))
}

/// A straight wall from `a` to `b` with door openings: each `(d, w)` leaves the stretch
/// [d − w/2, d + w/2] (metres along the wall from `a`) open.
fn wall_with_doors(a: Point2, b: Point2, doors: &[(f64, f64)], out: &mut Vec<Segment>) {
    let len = (b - a).norm();
    let dir = (b - a) / len;
    let mut gaps: Vec<(f64, f64)> = doors
        .iter()
        .map(|&(d, w)| ((d - w / 2.0).max(0.0), (d + w / 2.0).min(len)))
        .collect();
    gaps.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut s = 0.0;
    for (g0, g1) in gaps {
        if g0 > s + 1e-9 {
            out.push(Segment {
                a: a + dir * s,
                b: a + dir * g0,
            });
        }
        s = s.max(g1);
    }
    if len > s + 1e-9 {
        out.push(Segment { a: a + dir * s, b });
    }
}

/// An axis-aligned box [x0, x1] × [y0, y1] as four walls.
fn rect(x0: f64, y0: f64, x1: f64, y1: f64, out: &mut Vec<Segment>) {
    out.push(Segment::new(x0, y0, x1, y0));
    out.push(Segment::new(x1, y0, x1, y1));
    out.push(Segment::new(x1, y1, x0, y1));
    out.push(Segment::new(x0, y1, x0, y0));
}

/// The office floor (the layout is fixed, independent of the seed).
///
/// A 40 m × 20 m floor. A 2 m wide corridor runs around a loop between the rectangles
/// [5, 35] × [5, 15] and [7, 33] × [7, 13] (centre line [6, 34] × [6, 14], ≈ 70 m around).
/// Outside the corridor: rooms 5 m deep along all four sides (partitions every 5 m along
/// the long sides, at y = 10 on the short ones, closed corner rooms reached through their
/// neighbours); inside: four rooms. Every room has a 1 m door at an irregular position
/// and a desk (a box) at an irregular place, so places along the corridor look alike
/// locally but not exactly: a scan matcher drifts, and loop closure is needed.
pub fn office_world() -> World {
    let mut rng = Pcg64Mcg::seed_from_u64(0x0FF1CE);
    let mut s = Vec::new();
    let door = |lo: f64, hi: f64, rng: &mut Pcg64Mcg| rng.random_range(lo + 0.8..hi - 0.8);
    // Outer walls.
    rect(0.0, 0.0, 40.0, 20.0, &mut s);
    // Corridor outer boundary, long sides: one door per 5 m room between x = 5 and 35.
    for y in [5.0, 15.0] {
        let doors: Vec<(f64, f64)> = (1..7)
            .map(|k| (door(k as f64 * 5.0, k as f64 * 5.0 + 5.0, &mut rng), 1.0))
            .collect();
        wall_with_doors(Point2::new(0.0, y), Point2::new(40.0, y), &doors, &mut s);
    }
    // Corridor outer boundary, short sides (y from 5 to 15): doors to the rooms [5,10], [10,15].
    for x in [5.0, 35.0] {
        let doors = [
            (door(0.0, 5.0, &mut rng), 1.0),
            (door(5.0, 10.0, &mut rng), 1.0),
        ];
        wall_with_doors(Point2::new(x, 5.0), Point2::new(x, 15.0), &doors, &mut s);
        let (x0, x1) = if x < 20.0 { (0.0, 5.0) } else { (35.0, 40.0) };
        s.push(Segment::new(x0, 10.0, x1, 10.0));
    }
    // Partitions of the long-side strips; the corner rooms open into their neighbours.
    for (y0, y1) in [(0.0, 5.0), (15.0, 20.0)] {
        for k in 1..8 {
            let x = k as f64 * 5.0;
            if k == 1 || k == 7 {
                let d = door(0.0, 5.0, &mut rng);
                wall_with_doors(Point2::new(x, y0), Point2::new(x, y1), &[(d, 1.0)], &mut s);
            } else {
                s.push(Segment::new(x, y0, x, y1));
            }
        }
    }
    // Inner block: ring wall with doors into four rooms, alternately on the bottom and top.
    let cuts = [7.0, 13.5, 20.0, 26.5, 33.0];
    let mut bottom = Vec::new();
    let mut top = Vec::new();
    for k in 0..4 {
        let d = door(cuts[k], cuts[k + 1], &mut rng) - 7.0;
        if k % 2 == 0 {
            bottom.push((d, 1.0));
        } else {
            top.push((d, 1.0));
        }
    }
    wall_with_doors(
        Point2::new(7.0, 7.0),
        Point2::new(33.0, 7.0),
        &bottom,
        &mut s,
    );
    wall_with_doors(
        Point2::new(7.0, 13.0),
        Point2::new(33.0, 13.0),
        &top,
        &mut s,
    );
    s.push(Segment::new(7.0, 7.0, 7.0, 13.0));
    s.push(Segment::new(33.0, 7.0, 33.0, 13.0));
    for &x in &cuts[1..4] {
        s.push(Segment::new(x, 7.0, x, 13.0));
    }
    // Desks: one box per room, kept 0.7 m from the room's walls.
    let mut rooms: Vec<(f64, f64, f64, f64)> = Vec::new();
    for k in 0..8 {
        let x = k as f64 * 5.0;
        rooms.push((x, 0.0, x + 5.0, 5.0));
        rooms.push((x, 15.0, x + 5.0, 20.0));
    }
    for (x0, x1) in [(0.0, 5.0), (35.0, 40.0)] {
        rooms.push((x0, 5.0, x1, 10.0));
        rooms.push((x0, 10.0, x1, 15.0));
    }
    for k in 0..4 {
        rooms.push((cuts[k], 7.0, cuts[k + 1], 13.0));
    }
    for (x0, y0, x1, y1) in rooms {
        let (w, h) = (rng.random_range(0.6..1.6), rng.random_range(0.5..1.2));
        let bx = rng.random_range(x0 + 0.7..x1 - 0.7 - w);
        let by = rng.random_range(y0 + 0.7..y1 - 0.7 - h);
        rect(bx, by, bx + w, by + h, &mut s);
    }
    World::new(s).expect("constant office world is valid")
}

/// The office path: the corridor's centre line [6, 34] × [6, 14], corners rounded to 0.8 m,
/// counter-clockwise from (20, 6).
pub fn office_path() -> Path {
    let pts = [
        Point2::new(20.0, 6.0),
        Point2::new(34.0, 6.0),
        Point2::new(34.0, 14.0),
        Point2::new(6.0, 14.0),
        Point2::new(6.0, 6.0),
    ];
    Path::rounded(&pts, true, 0.8, 0.05).expect("constant office path is valid")
}

/// `office`: the [`office_world`] driven along the [`office_path`]. Defaults: 2 laps
/// (≈ 590 scans), CARMEN-like 180° laser with 181 beams (`beams` = 361 for 0.5°), range
/// 20 m, σ = 1 cm, no short readings; 0.8 m/s, odometry every 0.1 s with α = (0.02,
/// 0.002, 0.02, 0.001), a scan on every third odometry record (see [`LaserSimConfig`]).
pub fn office(opts: &ScenarioOptions) -> Result<LaserSimRun, SimError> {
    let world = office_world();
    let path = office_path();
    let cfg = laser_config("office", opts, 20.0, scans_for(opts, path.length(), 2.0)?)?;
    simulate_laser(&world, &path, &cfg, opts.seed)
}

/// Road centre lines of the [`campus_world`], metres, the same along x and y.
pub const CAMPUS_ROADS: [f64; 4] = [20.0, 85.0, 150.0, 215.0];

/// The campus (the layout is fixed, independent of the seed): an outdoor world of
/// 250 m × 250 m for laser SLAM beyond the office, of the kind the grid-FastSLAM lecture shows.
///
/// Roads 10 m wide run along x and y at [`CAMPUS_ROADS`], leaving a ring road and nine
/// 55 m × 55 m blocks. Each block is cut into four lots; three lots in four hold a building
/// (a box of 10–18 m × 8–18 m kept 3 m inside its 27.5 m lot), the others a few trees. Trees (0.6 m
/// squares) line both sides of every road 7 m from its centre, 8–16 m apart, and are
/// scattered in the 15 m margin outside the ring road. There is no boundary wall: many long
/// beams hit nothing, as outdoors.
pub fn campus_world() -> World {
    let mut rng = Pcg64Mcg::seed_from_u64(0xCA4_9005);
    let mut s = Vec::new();
    let tree = |x: f64, y: f64, s: &mut Vec<Segment>| rect(x - 0.3, y - 0.3, x + 0.3, y + 0.3, s);
    let (lo, hi) = (0.0, 250.0);
    let near_crossing = |v: f64| CAMPUS_ROADS.iter().any(|&c| (v - c).abs() < 9.0);
    // Trees along both sides of every road, between the crossings.
    for &c in &CAMPUS_ROADS {
        for side in [-7.0, 7.0] {
            let mut t = lo + 3.0 + rng.random_range(0.0..8.0);
            while t < hi - 3.0 {
                if !near_crossing(t) {
                    tree(t, c + side, &mut s); // along the road parallel to x
                }
                let u = t + rng.random_range(0.0..4.0);
                if u < hi - 3.0 && !near_crossing(u) {
                    tree(c + side, u, &mut s); // along the road parallel to y
                }
                t += rng.random_range(8.0..16.0);
            }
        }
    }
    // Buildings and trees in the four lots of each block.
    for &rx in &CAMPUS_ROADS[..3] {
        for &ry in &CAMPUS_ROADS[..3] {
            let (x0, y0) = (rx + 5.0, ry + 5.0);
            let lot = (CAMPUS_ROADS[1] - CAMPUS_ROADS[0] - 10.0) / 2.0;
            for (lx, ly) in [(0.0, 0.0), (lot, 0.0), (0.0, lot), (lot, lot)] {
                let (ax, ay) = (x0 + lx, y0 + ly);
                if rng.random_range(0.0..1.0) < 0.75 {
                    let (w, h) = (rng.random_range(10.0..18.0), rng.random_range(8.0..18.0));
                    let bx0 = ax + 3.0 + rng.random_range(0.0..lot - 6.0 - w);
                    let by0 = ay + 3.0 + rng.random_range(0.0..lot - 6.0 - h);
                    rect(bx0, by0, bx0 + w, by0 + h, &mut s);
                } else {
                    for _ in 0..4 {
                        let (x, y) = (
                            rng.random_range(3.0..lot - 3.0),
                            rng.random_range(3.0..lot - 3.0),
                        );
                        tree(ax + x, ay + y, &mut s);
                    }
                }
            }
        }
    }
    // Scattered trees outside the ring road.
    for _ in 0..80 {
        let along = rng.random_range(lo + 2.0..hi - 2.0);
        let across = rng.random_range(lo + 2.0..lo + 12.0);
        match rng.random_range(0..4) {
            0 => tree(along, across, &mut s),
            1 => tree(along, hi - across, &mut s),
            2 => tree(across, along, &mut s),
            _ => tree(hi - across, along, &mut s),
        }
    }
    World::new(s).expect("constant campus world is valid")
}

/// The campus route, ≈ 1.3 km along road centre lines, corners rounded to 4 m: the ring road
/// counter-clockwise from (85, 20), then a loop through the inner roads that crosses and
/// re-drives stretches already seen, back to the start.
pub fn campus_path() -> Path {
    let c = |i: usize, j: usize| Point2::new(CAMPUS_ROADS[i], CAMPUS_ROADS[j]);
    let pts = [
        c(1, 0),
        c(3, 0),
        c(3, 3),
        c(0, 3),
        c(0, 0),
        c(1, 0),
        c(1, 2),
        c(2, 2),
        c(2, 1),
        c(0, 1),
        c(0, 0),
    ];
    Path::rounded(&pts, true, 4.0, 0.1).expect("constant campus path is valid")
}

/// `campus`: the [`campus_world`] driven along the [`campus_path`]. Defaults: 2 laps
/// (≈ 2.6 km, ≈ 5,800 scans), 361 beams over 180° (0.5° apart), range 80 m, σ = 3 cm; the
/// robot at 1.5 m/s (a scan every 0.45 m), look-ahead 3 m; odometry as in [`office`].
pub fn campus(opts: &ScenarioOptions) -> Result<LaserSimRun, SimError> {
    let world = campus_world();
    let path = campus_path();
    let mut base = LaserSimConfig::default();
    base.follower.speed = 1.5;
    let per_scan = base.follower.speed * base.follower.dt * base.odometry_per_scan as f64;
    let scans = match opts.steps {
        Some(s) => s,
        None => ((opts.laps_or(2.0)? * path.length() / per_scan).round() as usize).max(1),
    };
    let mut o = opts.clone();
    o.beams = Some(opts.beams.unwrap_or(361));
    o.laser_sigma = Some(opts.laser_sigma.unwrap_or(0.03));
    let mut cfg = laser_config("campus", &o, 80.0, scans)?;
    cfg.follower.speed = base.follower.speed;
    cfg.follower.lookahead = 3.0;
    simulate_laser(&world, &path, &cfg, opts.seed)
}

/// Clearance (metres) the generated `replay` path keeps from walls and unknown space.
pub const REPLAY_CLEARANCE: f64 = 0.4;
/// Clearance (metres) a straight shortcut of the generated `replay` path must keep.
pub const REPLAY_SHORTCUT_CLEARANCE: f64 = 0.8;

/// `replay`: the world of `opts.replay_map` ([`World::from_grid_map`]) driven along
/// `opts.replay_path`, or, by default, along a generated path: random goals among the free
/// cells (value 0–19, ROS `free_thresh` 0.196) at least [`REPLAY_CLEARANCE`] from any other
/// cell, in the largest connected such region, joined by shortest paths that prefer
/// clearance (Dijkstra, step cost × (1 + 1 m / clearance)), shortcut where a straight line
/// keeps [`REPLAY_SHORTCUT_CLEARANCE`], corners rounded to 0.3 m. Defaults: 500 scans,
/// laser range 30 m, pure-pursuit look-ahead 0.3 m, otherwise as [`office`].
pub fn replay(opts: &ScenarioOptions) -> Result<LaserSimRun, SimError> {
    let map = opts.replay_map.as_ref().ok_or(SimError::MissingInput {
        scenario: "replay",
        what: "an occupancy map (replay_map)",
    })?;
    let world = World::from_grid_map(map)?;
    let mut cfg = laser_config("replay", opts, 30.0, opts.steps.unwrap_or(500))?;
    // Tighter tracking than in the office corridor: the path threads through doors.
    cfg.follower.lookahead = 0.3;
    let path = match &opts.replay_path {
        Some(pts) => Path::new(pts.clone(), false)?,
        None => {
            let need = cfg.scans as f64
                * cfg.follower.speed
                * cfg.follower.dt
                * cfg.odometry_per_scan as f64
                + 2.0;
            free_space_path(map, need, opts.seed)?
        }
    };
    simulate_laser(&world, &path, &cfg, opts.seed)
}

/// Dijkstra queue entry (min-heap by cost, ties by cell index for determinism).
#[derive(PartialEq)]
struct Entry(f64, usize);
impl Eq for Entry {}
impl Ord for Entry {
    fn cmp(&self, o: &Self) -> Ordering {
        o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
    }
}
impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

/// A path of at least `need` metres through the free space of `map` (see [`replay`]).
fn free_space_path(map: &GridMap, need: f64, seed: u64) -> Result<Path, SimError> {
    let (w, h, res) = (map.width, map.height, map.resolution);
    let n = w * h;
    // Clearance in cells: 8-connected chamfer distance (1, √2) to the nearest non-free
    // cell or the map border.
    let free = |k: usize| (0..20).contains(&map.cells[k]);
    let mut dist = vec![f64::INFINITY; n];
    for (k, d) in dist.iter_mut().enumerate() {
        let (x, y) = (k % w, k / w);
        if !free(k) {
            *d = 0.0;
        } else if x == 0 || y == 0 || x + 1 == w || y + 1 == h {
            *d = 1.0;
        }
    }
    let d2 = std::f64::consts::SQRT_2;
    for y in 0..h {
        for x in 0..w {
            let k = y * w + x;
            let mut d = dist[k];
            if x > 0 {
                d = d.min(dist[k - 1] + 1.0);
            }
            if y > 0 {
                d = d.min(dist[k - w] + 1.0);
                if x > 0 {
                    d = d.min(dist[k - w - 1] + d2);
                }
                if x + 1 < w {
                    d = d.min(dist[k - w + 1] + d2);
                }
            }
            dist[k] = d;
        }
    }
    for y in (0..h).rev() {
        for x in (0..w).rev() {
            let k = y * w + x;
            let mut d = dist[k];
            if x + 1 < w {
                d = d.min(dist[k + 1] + 1.0);
            }
            if y + 1 < h {
                d = d.min(dist[k + w] + 1.0);
                if x + 1 < w {
                    d = d.min(dist[k + w + 1] + d2);
                }
                if x > 0 {
                    d = d.min(dist[k + w - 1] + d2);
                }
            }
            dist[k] = d;
        }
    }
    let min_cells = REPLAY_CLEARANCE / res;
    let safe: Vec<bool> = dist.iter().map(|&d| d >= min_cells).collect();
    // Largest 4-connected safe region.
    let mut label = vec![u32::MAX; n];
    let (mut best, mut best_size, mut next) = (u32::MAX, 0usize, 0u32);
    let mut stack = Vec::new();
    for k in 0..n {
        if !safe[k] || label[k] != u32::MAX {
            continue;
        }
        let mut size = 0;
        label[k] = next;
        stack.push(k);
        while let Some(c) = stack.pop() {
            size += 1;
            let (x, y) = (c % w, c / w);
            let nb = [
                (x > 0).then(|| c - 1),
                (x + 1 < w).then(|| c + 1),
                (y > 0).then(|| c - w),
                (y + 1 < h).then(|| c + w),
            ];
            for m in nb.into_iter().flatten() {
                if safe[m] && label[m] == u32::MAX {
                    label[m] = next;
                    stack.push(m);
                }
            }
        }
        if size > best_size {
            (best, best_size) = (next, size);
        }
        next += 1;
    }
    if best_size < 4 {
        return Err(SimError::InvalidWorld(format!(
            "occupancy map has no free region with {REPLAY_CLEARANCE} m clearance to drive through"
        )));
    }
    let region: Vec<usize> = (0..n).filter(|&k| label[k] == best).collect();
    let mut rng = stream(seed, tag::PATH);
    let center = |k: usize| map.cell_center(k % w, k / w);
    // Shortcuts must keep the wider [`REPLAY_SHORTCUT_CLEARANCE`]: through narrow passages
    // (doors) the path keeps the Dijkstra cells, which follow the middle of the passage.
    let wide_cells = REPLAY_SHORTCUT_CLEARANCE / res;
    // Straight line between two cell centres stays within wide cells (sampled every ¼ cell).
    let clear = |a: usize, b: usize| -> bool {
        let (pa, pb) = (center(a), center(b));
        let steps = ((pb - pa).norm() / (0.25 * res)).ceil() as usize;
        (0..=steps).all(|i| {
            let p = pa + (pb - pa) * (i as f64 / steps.max(1) as f64);
            map.cell_of(&p)
                .is_some_and(|(x, y)| dist[y * w + x] >= wide_cells)
        })
    };
    let mut cur = region[rng.random_range(0..region.len())];
    let mut cells = vec![cur];
    let mut len = 0.0;
    let mut cost = vec![f64::INFINITY; n];
    let mut prev = vec![usize::MAX; n];
    let mut touched: Vec<usize> = Vec::new();
    let mut attempts = 0;
    // Rounding the corners shortens the path a little: plan 10 % + 5 m more than needed.
    while len < 1.1 * need + 5.0 {
        attempts += 1;
        if attempts > 200 {
            return Err(SimError::InvalidPath(format!(
                "could not plan {need:.0} m of path through the map's free space (got {len:.0} m)"
            )));
        }
        let goal = region[rng.random_range(0..region.len())];
        if (center(goal) - center(cur)).norm() < 3.0 {
            continue;
        }
        // Dijkstra from cur to goal over safe cells, 8-connected.
        for &k in &touched {
            cost[k] = f64::INFINITY;
            prev[k] = usize::MAX;
        }
        touched.clear();
        let mut heap = BinaryHeap::new();
        cost[cur] = 0.0;
        touched.push(cur);
        heap.push(Entry(0.0, cur));
        while let Some(Entry(c, k)) = heap.pop() {
            if k == goal {
                break;
            }
            if c > cost[k] {
                continue;
            }
            let (x, y) = ((k % w) as isize, (k / w) as isize);
            for (dx, dy) in [
                (1, 0),
                (-1, 0),
                (0, 1),
                (0, -1),
                (1, 1),
                (1, -1),
                (-1, 1),
                (-1, -1),
            ] {
                let (nx, ny) = (x + dx, y + dy);
                if nx < 0 || ny < 0 || nx >= w as isize || ny >= h as isize {
                    continue;
                }
                let m = ny as usize * w + nx as usize;
                if !safe[m] {
                    continue;
                }
                let step = if dx != 0 && dy != 0 { d2 } else { 1.0 } * res;
                let nc = c + step * (1.0 + 1.0 / (dist[m] * res));
                if nc < cost[m] {
                    if cost[m].is_infinite() {
                        touched.push(m);
                    }
                    cost[m] = nc;
                    prev[m] = k;
                    heap.push(Entry(nc, m));
                }
            }
        }
        if prev[goal] == usize::MAX {
            continue;
        }
        let mut leg = vec![goal];
        while let Some(&last) = leg.last() {
            if last == cur {
                break;
            }
            leg.push(prev[last]);
        }
        leg.reverse();
        // Shortcut: from each kept cell jump to the farthest cell still in line of sight.
        let mut i = 0;
        while i + 1 < leg.len() {
            let mut j = i + 1;
            // Exponential then linear search keeps this near O(leg) line checks.
            while j + 1 < leg.len() && clear(leg[i], leg[j + 1]) {
                j += 1;
            }
            len += (center(leg[j]) - center(leg[i])).norm();
            cells.push(leg[j]);
            i = j;
        }
        cur = goal;
    }
    let pts: Vec<Point2> = cells.iter().map(|&k| center(k)).collect();
    Path::rounded(&pts, false, 0.3, 0.05)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::generate;
    use crate::SimOutput;

    fn run(name: &str, opts: &ScenarioOptions) -> LaserSimRun {
        match generate(name, opts).unwrap() {
            SimOutput::Laser(r) => r,
            SimOutput::Landmark(_) => panic!("{name} is a laser scenario"),
        }
    }

    #[test]
    fn office_defaults() {
        let w = office_world();
        assert!(
            w.segments().len() > 100 && w.segments().len() < 300,
            "{}",
            w.segments().len()
        );
        let r = run(
            "office",
            &ScenarioOptions {
                seed: 1,
                steps: Some(60),
                ..Default::default()
            },
        );
        let recs = &r.dataset.records;
        let gt = r.dataset.ground_truth.as_ref().unwrap();
        assert_eq!(recs.len(), gt.len());
        assert_eq!(recs.iter().filter(|r| r.scan.is_some()).count(), 60);
        for (rec, g) in recs.iter().zip(gt) {
            assert_eq!(rec.t, g.t);
            if let Some(s) = &rec.scan {
                assert_eq!(s.len(), 181);
                s.validate().unwrap();
                // In a 2 m corridor something is always within reach on both sides.
                let hits = (0..s.len()).filter(|&k| s.is_hit(k)).count();
                assert!(hits > 90, "{hits} hits");
            }
        }
        // The path stays in the corridor: every true pose is ≥ 0.3 m from every wall.
        for g in gt {
            for k in 0..36 {
                let a = k as f64 * 10f64.to_radians();
                assert!(
                    w.cast(&g.pose.translation(), a, 0.3).is_none(),
                    "pose {:?} touches a wall",
                    g.pose
                );
            }
        }
    }

    #[test]
    fn campus_defaults() {
        let w = campus_world();
        let (lo, hi) = w.bounds();
        assert!(
            lo.x > -1.0 && lo.y > -1.0 && hi.x < 251.0 && hi.y < 251.0,
            "{lo:?} {hi:?}"
        );
        assert!(hi.x - lo.x > 240.0 && hi.y - lo.y > 240.0, "{lo:?} {hi:?}");
        let path = campus_path();
        assert!((path.length() - 1300.0).abs() < 30.0, "{}", path.length());
        let r = run(
            "campus",
            &ScenarioOptions {
                seed: 2,
                steps: Some(400),
                ..Default::default()
            },
        );
        let recs = &r.dataset.records;
        let gt = r.dataset.ground_truth.as_ref().unwrap();
        assert_eq!(recs.iter().filter(|r| r.scan.is_some()).count(), 400);
        let (mut beams, mut hits, mut far) = (0, 0, 0);
        for rec in recs {
            if let Some(s) = &rec.scan {
                assert_eq!(s.len(), 361);
                s.validate().unwrap();
                beams += s.len();
                for k in (0..s.len()).filter(|&k| s.is_hit(k)) {
                    hits += 1;
                    far += usize::from(s.ranges[k] > 20.0);
                }
            }
        }
        // Outdoors: many beams hit nothing, and many hits lie beyond an indoor laser's reach.
        assert!(
            hits * 10 > beams && hits * 10 < beams * 9,
            "{hits} of {beams}"
        );
        assert!(far * 5 > hits, "{far} of {hits} hits beyond 20 m");
        // The robot keeps to the roads: every true pose is ≥ 3 m from every tree and wall.
        for g in gt {
            for k in 0..36 {
                let a = k as f64 * 10f64.to_radians();
                assert!(
                    w.cast(&g.pose.translation(), a, 3.0).is_none(),
                    "{:?}",
                    g.pose
                );
            }
        }
    }

    #[test]
    fn office_is_deterministic_and_noise_free_odometry_is_the_truth() {
        let o = ScenarioOptions {
            seed: 9,
            steps: Some(40),
            ..Default::default()
        };
        assert_eq!(run("office", &o).dataset, run("office", &o).dataset);
        assert_ne!(
            run("office", &o).dataset,
            run(
                "office",
                &ScenarioOptions {
                    seed: 10,
                    ..o.clone()
                }
            )
            .dataset
        );
        let exact = ScenarioOptions {
            odometry_alpha: Some([0.0; 4]),
            ..o
        };
        let r = run("office", &exact);
        for (rec, g) in r
            .dataset
            .records
            .iter()
            .zip(r.dataset.ground_truth.as_ref().unwrap())
        {
            assert!(rec.odometry.approx_eq(&g.pose, 1e-9));
        }
    }

    #[test]
    fn odometry_noise_matches_the_reported_model() {
        // The increment between consecutive odometry readings is the reported control ū;
        // the true pose is drawn from p(x_k | ū, x_{k−1}), so the normalised squared error
        // against the linearised model is chi-square with 3 dof (mean 3, s.e. √(6/n)).
        use slam_models::motion::MotionModel;
        let r = run(
            "office",
            &ScenarioOptions {
                seed: 6,
                steps: Some(700),
                ..Default::default()
            },
        );
        let gt = r.dataset.ground_truth.as_ref().unwrap();
        let (mut sum, mut n) = (0.0, 0.0);
        for k in 1..gt.len() {
            let recs = &r.dataset.records;
            let u = r
                .odometry
                .control_from_poses(&recs[k - 1].odometry, &recs[k].odometry);
            let prev = gt[k - 1].pose;
            let pred = r.odometry.predict(&prev, &u);
            let cov = r.odometry.noise_covariance(&prev, &u);
            let t = gt[k].pose;
            let e = slam_models::Vector3::new(
                t.x - pred.x,
                t.y - pred.y,
                slam_models::normalize_angle(t.theta - pred.theta),
            );
            if cov.determinant() > 1e-30 {
                sum += (e.transpose() * cov.try_inverse().unwrap() * e)[0];
                n += 1.0;
            }
        }
        let mean = sum / n;
        assert!(
            (mean - 3.0).abs() < 5.0 * (6.0 / n).sqrt() + 0.06,
            "mean NEES {mean} over {n}"
        );
    }

    #[test]
    fn replay_from_a_grid_map() {
        // Rasterise the office into a 0.1 m map, and replay it.
        let w = office_world();
        let res = 0.1;
        let (wd, ht) = (400 + 2, 200 + 2);
        let mut m = GridMap::unknown(res, Point2::new(-0.1, -0.1), wd, ht);
        for iy in 0..ht {
            for ix in 0..wd {
                let c = m.cell_center(ix, iy);
                // Occupied when a wall passes within half a cell (diagonal).
                let near = w.segments().iter().any(|s| {
                    let ab = s.b - s.a;
                    let t = ((c - s.a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
                    (c - (s.a + ab * t)).norm() <= res * 0.71
                });
                let inside = c.x > 0.0 && c.y > 0.0 && c.x < 40.0 && c.y < 20.0;
                m.cells[iy * wd + ix] = if near {
                    100
                } else if inside {
                    0
                } else {
                    -1
                };
            }
        }
        let o = ScenarioOptions {
            seed: 3,
            steps: Some(80),
            replay_map: Some(m.clone()),
            ..Default::default()
        };
        let r = run("replay", &o);
        assert_eq!(
            r.dataset
                .records
                .iter()
                .filter(|r| r.scan.is_some())
                .count(),
            80
        );
        assert_eq!(r.dataset.records.len(), 240);
        // True poses stay in free space with clearance.
        for g in r.dataset.ground_truth.as_ref().unwrap() {
            let (ix, iy) = m.cell_of(&g.pose.translation()).unwrap();
            assert_eq!(m.cells[iy * wd + ix], 0);
        }
        assert_eq!(r.dataset, run("replay", &o).dataset);
        assert!(matches!(
            generate("replay", &ScenarioOptions::default()),
            Err(SimError::MissingInput { .. })
        ));
    }
}
