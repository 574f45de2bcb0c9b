//! A world of line segments with a uniform-grid index for ray casting.
//!
//! Ray casting walks the grid cells a ray crosses in order (Amanatides & Woo 1987, "A fast
//! voxel traversal algorithm") and tests only the segments registered in those cells; it
//! stops as soon as the nearest hit found lies within the cells already visited. Cost is
//! O(cells crossed + segments in them), independent of the total number of walls.

use crate::error::{check_range, SimError};
use serde::{Deserialize, Serialize};
use slam_models::detmath;
use slam_models::{GridMap, Point2};

/// A wall: the segment from `a` to `b` (world frame, metres).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Segment {
    /// First end point.
    pub a: Point2,
    /// Second end point.
    pub b: Point2,
}

impl Segment {
    /// The segment from (ax, ay) to (bx, by).
    pub fn new(ax: f64, ay: f64, bx: f64, by: f64) -> Self {
        Self {
            a: Point2::new(ax, ay),
            b: Point2::new(bx, by),
        }
    }

    /// Length, metres.
    pub fn length(&self) -> f64 {
        (self.b - self.a).norm()
    }
}

/// Segment data laid out for the intersection test: start and direction.
#[derive(Debug, Clone, Copy)]
struct Wall {
    ax: f64,
    ay: f64,
    ex: f64,
    ey: f64,
}

/// A 2-D world of line segments (walls), indexed by a uniform grid.
///
/// # Example
///
/// ```
/// use slam_models::Point2;
/// use slam_sim::laser::{Segment, World};
/// // A wall along x = 3; a ray from the origin at 45° meets it after 3·√2 m.
/// let w = World::new(vec![Segment::new(3.0, -10.0, 3.0, 10.0)]).unwrap();
/// let d = w.cast(&Point2::new(0.0, 0.0), std::f64::consts::FRAC_PI_4, 20.0).unwrap();
/// assert!((d - 3.0 * 2f64.sqrt()).abs() < 1e-12);
/// assert!(w.cast(&Point2::new(0.0, 0.0), std::f64::consts::PI, 20.0).is_none()); // no return
/// ```
#[derive(Debug, Clone)]
pub struct World {
    segments: Vec<Segment>,
    walls: Vec<Wall>,
    /// Lower-left corner of the grid.
    ox: f64,
    oy: f64,
    cell: f64,
    inv_cell: f64,
    nx: usize,
    ny: usize,
    /// CSR: segments of cell k are `items[starts[k]..starts[k+1]]`.
    starts: Vec<u32>,
    items: Vec<u32>,
}

/// Segments per cell the automatic cell size aims for (about).
const TARGET_PER_CELL: f64 = 2.0;

impl World {
    /// A world of the given walls. Every end point must be finite and every segment longer
    /// than 1e-9 m; at least one segment is needed. The grid cell size is chosen
    /// automatically (about two segments per occupied cell).
    pub fn new(segments: Vec<Segment>) -> Result<Self, SimError> {
        if segments.is_empty() {
            return Err(SimError::InvalidWorld(
                "a laser world needs at least one wall".into(),
            ));
        }
        let mut total_len = 0.0;
        for (i, s) in segments.iter().enumerate() {
            if ![s.a.x, s.a.y, s.b.x, s.b.y].iter().all(|v| v.is_finite()) {
                return Err(SimError::InvalidWorld(format!(
                    "segment {i} has a non-finite end point"
                )));
            }
            if s.length() <= 1e-9 {
                return Err(SimError::InvalidWorld(format!(
                    "segment {i} has zero length"
                )));
            }
            total_len += s.length();
        }
        let (mut lo, mut hi) = (segments[0].a, segments[0].a);
        for s in &segments {
            for p in [s.a, s.b] {
                lo = Point2::new(lo.x.min(p.x), lo.y.min(p.y));
                hi = Point2::new(hi.x.max(p.x), hi.y.max(p.y));
            }
        }
        // Cell size: a segment of length L crosses about L/c + 1 cells; aim for
        // TARGET_PER_CELL segments per cell over the cells the walls occupy, bounded so the
        // grid stays small.
        let mean_len = total_len / segments.len() as f64;
        let extent = (hi.x - lo.x).max(hi.y - lo.y).max(1e-6);
        let mut cell = (mean_len * 0.5).max(extent / 2048.0).max(1e-3);
        if segments.len() as f64 <= TARGET_PER_CELL {
            cell = cell.max(extent / 4.0);
        }
        Self::with_cell(segments, lo, hi, cell)
    }

    /// Builds the grid with a given cell size.
    fn with_cell(
        segments: Vec<Segment>,
        lo: Point2,
        hi: Point2,
        cell: f64,
    ) -> Result<Self, SimError> {
        // Pad by a cell so that walls on the bounding box lie strictly inside.
        let ox = lo.x - cell;
        let oy = lo.y - cell;
        let nx = (((hi.x - ox) / cell).floor() as usize + 2).max(1);
        let ny = (((hi.y - oy) / cell).floor() as usize + 2).max(1);
        if nx.saturating_mul(ny) > 1 << 26 {
            return Err(SimError::InvalidWorld(
                "world too large for its ray-casting grid".into(),
            ));
        }
        let inv_cell = 1.0 / cell;
        // Cells touched by each segment: walk the segment through the grid, adding the
        // 3 × 3 neighbourhood would be wasteful; instead register every cell the segment's
        // slightly inflated bounding box overlaps and that the segment passes within
        // `eps` of (exact box–segment test).
        let eps = 1e-9 * (1.0 + extent_of(lo, hi));
        let mut pairs: Vec<(u32, u32)> = Vec::new();
        for (si, s) in segments.iter().enumerate() {
            let x0 = (((s.a.x.min(s.b.x) - eps - ox) * inv_cell).floor().max(0.0)) as usize;
            let x1 = ((((s.a.x.max(s.b.x) + eps - ox) * inv_cell).floor()) as usize).min(nx - 1);
            let y0 = (((s.a.y.min(s.b.y) - eps - oy) * inv_cell).floor().max(0.0)) as usize;
            let y1 = ((((s.a.y.max(s.b.y) + eps - oy) * inv_cell).floor()) as usize).min(ny - 1);
            for iy in y0..=y1 {
                for ix in x0..=x1 {
                    let bx0 = ox + ix as f64 * cell - eps;
                    let by0 = oy + iy as f64 * cell - eps;
                    if segment_hits_box(s, bx0, by0, bx0 + cell + 2.0 * eps, by0 + cell + 2.0 * eps)
                    {
                        pairs.push(((iy * nx + ix) as u32, si as u32));
                    }
                }
            }
        }
        pairs.sort_unstable();
        let mut starts = vec![0u32; nx * ny + 1];
        for &(c, _) in &pairs {
            starts[c as usize + 1] += 1;
        }
        for k in 0..nx * ny {
            starts[k + 1] += starts[k];
        }
        let items = pairs.iter().map(|&(_, s)| s).collect();
        let walls = segments
            .iter()
            .map(|s| Wall {
                ax: s.a.x,
                ay: s.a.y,
                ex: s.b.x - s.a.x,
                ey: s.b.y - s.a.y,
            })
            .collect();
        Ok(Self {
            segments,
            walls,
            ox,
            oy,
            cell,
            inv_cell,
            nx,
            ny,
            starts,
            items,
        })
    }

    /// Closed polygons (each a list of vertices; the last joins the first) as walls.
    pub fn from_polygons(polygons: &[Vec<Point2>]) -> Result<Self, SimError> {
        let mut segs = Vec::new();
        for poly in polygons {
            for i in 0..poly.len() {
                let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
                if (b - a).norm() > 1e-9 {
                    segs.push(Segment { a, b });
                }
            }
        }
        Self::new(segs)
    }

    /// The walls of an occupancy map: every cell with value ≥ 65 (ROS map_server's default
    /// `occupied_thresh` 0.65) is a solid square, and the walls are the edges between
    /// occupied and other cells (free, unknown, or outside the map), merged into maximal
    /// straight runs along rows and columns. Unknown cells count as free: a ray through them
    /// may report "no return". See [`World::from_grid_map_with`] to change either choice.
    pub fn from_grid_map(map: &GridMap) -> Result<Self, SimError> {
        Self::from_grid_map_with(map, 65, false)
    }

    /// As [`World::from_grid_map`], with the occupancy threshold (cells with value ≥
    /// `threshold` are solid) and whether unknown (−1) cells are solid.
    pub fn from_grid_map_with(
        map: &GridMap,
        threshold: i8,
        unknown_solid: bool,
    ) -> Result<Self, SimError> {
        let (w, h) = (map.width, map.height);
        if w == 0 || h == 0 || map.cells.len() != w * h {
            return Err(SimError::InvalidWorld(format!(
                "occupancy map of {w} x {h} cells has {} values",
                map.cells.len()
            )));
        }
        if !(map.resolution.is_finite()
            && map.resolution > 0.0
            && map.origin.x.is_finite()
            && map.origin.y.is_finite())
        {
            return Err(SimError::InvalidWorld(
                "occupancy map resolution/origin must be finite and positive".into(),
            ));
        }
        let solid = |ix: isize, iy: isize| -> bool {
            if ix < 0 || iy < 0 || ix >= w as isize || iy >= h as isize {
                return false;
            }
            let v = map.cells[iy as usize * w + ix as usize];
            v >= threshold || (unknown_solid && v < 0)
        };
        let r = map.resolution;
        let (ox, oy) = (map.origin.x, map.origin.y);
        let mut segs = Vec::new();
        // Horizontal edges: the line y = oy + j·r between rows j−1 and j, for j = 0..=h.
        for j in 0..=h as isize {
            let mut run: Option<usize> = None;
            for i in 0..=w as isize {
                let edge = i < w as isize && solid(i, j - 1) != solid(i, j);
                match (edge, run) {
                    (true, None) => run = Some(i as usize),
                    (false, Some(s)) => {
                        segs.push(Segment::new(
                            ox + s as f64 * r,
                            oy + j as f64 * r,
                            ox + i as f64 * r,
                            oy + j as f64 * r,
                        ));
                        run = None;
                    }
                    _ => {}
                }
            }
        }
        // Vertical edges: x = ox + i·r between columns i−1 and i.
        for i in 0..=w as isize {
            let mut run: Option<usize> = None;
            for j in 0..=h as isize {
                let edge = j < h as isize && solid(i - 1, j) != solid(i, j);
                match (edge, run) {
                    (true, None) => run = Some(j as usize),
                    (false, Some(s)) => {
                        segs.push(Segment::new(
                            ox + i as f64 * r,
                            oy + s as f64 * r,
                            ox + i as f64 * r,
                            oy + j as f64 * r,
                        ));
                        run = None;
                    }
                    _ => {}
                }
            }
        }
        if segs.is_empty() {
            return Err(SimError::InvalidWorld(
                "occupancy map has no occupied cells".into(),
            ));
        }
        Self::new(segs)
    }

    /// Rasterises the walls into an occupancy map of cell size `resolution` covering the
    /// walls' bounds plus `margin` metres on every side: cells a wall passes through are
    /// occupied (100), all others free (0). This is the true map of a simulated world, for
    /// pictures, map-quality comparisons, and `replay` round trips.
    pub fn rasterize(&self, resolution: f64, margin: f64) -> Result<GridMap, SimError> {
        check_range(
            "resolution",
            resolution,
            1e-4,
            1e3,
            "0 < resolution <= 1000 m",
        )?;
        check_range("margin", margin, 0.0, 1e4, "0 <= margin <= 10000 m")?;
        let (lo, hi) = self.bounds();
        let origin = Point2::new(lo.x - margin, lo.y - margin);
        let width = ((hi.x - lo.x + 2.0 * margin) / resolution).ceil() as usize + 1;
        let height = ((hi.y - lo.y + 2.0 * margin) / resolution).ceil() as usize + 1;
        if width.saturating_mul(height) > 1 << 28 {
            return Err(SimError::InvalidParameter {
                name: "resolution",
                value: resolution.to_string(),
                expected: "a resolution giving at most 2^28 cells for this world",
            });
        }
        let mut map = GridMap {
            resolution,
            origin,
            width,
            height,
            cells: vec![0; width * height],
        };
        for s in &self.segments {
            // Sample every quarter cell: every cell the wall crosses by more than a
            // quarter cell is marked.
            let n = (s.length() / (0.25 * resolution)).ceil() as usize;
            for i in 0..=n {
                let p = s.a + (s.b - s.a) * (i as f64 / n.max(1) as f64);
                if let Some((ix, iy)) = map.cell_of(&p) {
                    map.cells[iy * width + ix] = 100;
                }
            }
        }
        Ok(map)
    }

    /// The walls.
    pub fn segments(&self) -> &[Segment] {
        &self.segments
    }

    /// Axis-aligned bounds of the walls: (min corner, max corner).
    pub fn bounds(&self) -> (Point2, Point2) {
        let c = self.cell;
        (
            Point2::new(self.ox + c, self.oy + c),
            Point2::new(
                self.ox + (self.nx as f64 - 1.0) * c,
                self.oy + (self.ny as f64 - 1.0) * c,
            ),
        )
    }

    /// Distance along the ray from `origin` in direction `angle` (radians, world frame) to
    /// the nearest wall, if one is hit within `max_range`. A ray starting exactly on a wall
    /// returns 0.
    pub fn cast(&self, origin: &Point2, angle: f64, max_range: f64) -> Option<f64> {
        let (dy, dx) = detmath::sin_cos(angle);
        self.cast_dir(origin.x, origin.y, dx, dy, max_range)
    }

    /// [`World::cast`] with a unit direction vector (dx, dy).
    pub fn cast_dir(&self, px: f64, py: f64, dx: f64, dy: f64, max_range: f64) -> Option<f64> {
        if max_range.is_nan() || max_range <= 0.0 || !px.is_finite() || !py.is_finite() {
            return None;
        }
        // Clip the ray [0, max_range] to the grid box (slab test).
        let (gx0, gy0) = (self.ox, self.oy);
        let (gx1, gy1) = (
            self.ox + self.nx as f64 * self.cell,
            self.oy + self.ny as f64 * self.cell,
        );
        let mut t0 = 0.0f64;
        let mut t1 = max_range;
        for (p, d, lo, hi) in [(px, dx, gx0, gx1), (py, dy, gy0, gy1)] {
            if d.abs() < 1e-300 {
                if p < lo || p > hi {
                    return None;
                }
            } else {
                let inv = 1.0 / d;
                let (mut a, mut b) = ((lo - p) * inv, (hi - p) * inv);
                if a > b {
                    std::mem::swap(&mut a, &mut b);
                }
                t0 = t0.max(a);
                t1 = t1.min(b);
            }
        }
        if t0 > t1 {
            return None;
        }
        // Start cell at the entry point.
        let sx = px + dx * t0;
        let sy = py + dy * t0;
        let mut ix =
            (((sx - self.ox) * self.inv_cell).floor() as isize).clamp(0, self.nx as isize - 1);
        let mut iy =
            (((sy - self.oy) * self.inv_cell).floor() as isize).clamp(0, self.ny as isize - 1);
        let step_x: isize = if dx > 0.0 { 1 } else { -1 };
        let step_y: isize = if dy > 0.0 { 1 } else { -1 };
        // Ray parameter at which the next x / y cell boundary is crossed.
        let next_boundary = |i: isize, o: f64, step: isize| -> f64 {
            o + (i + if step > 0 { 1 } else { 0 }) as f64 * self.cell
        };
        let (mut tmx, tdx) = if dx.abs() < 1e-300 {
            (f64::INFINITY, f64::INFINITY)
        } else {
            (
                (next_boundary(ix, self.ox, step_x) - px) / dx,
                self.cell / dx.abs(),
            )
        };
        let (mut tmy, tdy) = if dy.abs() < 1e-300 {
            (f64::INFINITY, f64::INFINITY)
        } else {
            (
                (next_boundary(iy, self.oy, step_y) - py) / dy,
                self.cell / dy.abs(),
            )
        };
        let mut best = f64::INFINITY;
        loop {
            let k = iy as usize * self.nx + ix as usize;
            let (s, e) = (self.starts[k] as usize, self.starts[k + 1] as usize);
            for &si in &self.items[s..e] {
                let w = &self.walls[si as usize];
                // o + t·d = a + u·e  ⇒  t = ((a − o) × e) / (d × e),  u = ((a − o) × d) / (d × e).
                let den = dx * w.ey - dy * w.ex;
                if den.abs() < 1e-15 {
                    continue; // parallel (or collinear: grazing, not a hit)
                }
                let (qx, qy) = (w.ax - px, w.ay - py);
                let t = (qx * w.ey - qy * w.ex) / den;
                let u = (qx * dy - qy * dx) / den;
                if t >= 0.0 && t < best && (0.0..=1.0).contains(&u) {
                    best = t;
                }
            }
            let t_exit = tmx.min(tmy);
            if best <= t_exit || t_exit > t1 {
                break;
            }
            if tmx < tmy {
                ix += step_x;
                tmx += tdx;
                if ix < 0 || ix >= self.nx as isize {
                    break;
                }
            } else {
                iy += step_y;
                tmy += tdy;
                if iy < 0 || iy >= self.ny as isize {
                    break;
                }
            }
        }
        (best <= max_range).then_some(best)
    }

    /// Reference ray cast by testing every wall (O(walls)); for tests and benchmarks.
    pub fn cast_brute_force(&self, origin: &Point2, angle: f64, max_range: f64) -> Option<f64> {
        let (dy, dx) = detmath::sin_cos(angle);
        let mut best = f64::INFINITY;
        for w in &self.walls {
            let den = dx * w.ey - dy * w.ex;
            if den.abs() < 1e-15 {
                continue;
            }
            let (qx, qy) = (w.ax - origin.x, w.ay - origin.y);
            let t = (qx * w.ey - qy * w.ex) / den;
            let u = (qx * dy - qy * dx) / den;
            if t >= 0.0 && t < best && (0.0..=1.0).contains(&u) {
                best = t;
            }
        }
        (best <= max_range).then_some(best)
    }

    /// True when the straight segment p → q crosses no wall (line of sight).
    pub fn line_of_sight(&self, p: &Point2, q: &Point2) -> bool {
        let d = q - p;
        let len = d.norm();
        if len <= 0.0 {
            return true;
        }
        self.cast_dir(p.x, p.y, d.x / len, d.y / len, len).is_none()
    }
}

/// Largest absolute coordinate scale of a box (for tolerances).
fn extent_of(lo: Point2, hi: Point2) -> f64 {
    lo.x.abs().max(lo.y.abs()).max(hi.x.abs()).max(hi.y.abs())
}

/// True when segment `s` intersects the closed box [x0, x1] × [y0, y1] (Liang–Barsky
/// clipping).
fn segment_hits_box(s: &Segment, x0: f64, y0: f64, x1: f64, y1: f64) -> bool {
    let (dx, dy) = (s.b.x - s.a.x, s.b.y - s.a.y);
    let mut t0 = 0.0f64;
    let mut t1 = 1.0f64;
    for (p, q) in [
        (-dx, s.a.x - x0),
        (dx, x1 - s.a.x),
        (-dy, s.a.y - y0),
        (dy, y1 - s.a.y),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return false;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    t0 <= t1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::stream;
    use rand::Rng;
    use std::f64::consts::PI;

    fn square_room(half: f64) -> World {
        World::from_polygons(&[vec![
            Point2::new(-half, -half),
            Point2::new(half, -half),
            Point2::new(half, half),
            Point2::new(-half, half),
        ]])
        .unwrap()
    }

    #[test]
    fn analytic_distances_in_a_square_room() {
        // From (x, y) inside the square |x|, |y| < h, the ray at angle a hits the wall at
        // t = min over the walls it heads to of (h − x)/cos a, (h − y)/sin a, … .
        let h = 5.0;
        let w = square_room(h);
        let mut rng = stream(1, 50);
        for _ in 0..2000 {
            let p = Point2::new(rng.random_range(-4.9..4.9), rng.random_range(-4.9..4.9));
            let a: f64 = rng.random_range(-PI..PI);
            let (s, c) = a.sin_cos();
            let tx = if c > 0.0 {
                (h - p.x) / c
            } else if c < 0.0 {
                (-h - p.x) / c
            } else {
                f64::INFINITY
            };
            let ty = if s > 0.0 {
                (h - p.y) / s
            } else if s < 0.0 {
                (-h - p.y) / s
            } else {
                f64::INFINITY
            };
            let expect = tx.min(ty);
            let got = w.cast(&p, a, 100.0).unwrap();
            assert!((got - expect).abs() < 1e-9, "{got} vs {expect}");
            // Out of range: no return.
            assert!(w.cast(&p, a, expect * 0.99).is_none());
        }
        // Axis-aligned rays exactly along the grid lines.
        let o = Point2::new(0.0, 0.0);
        for (a, d) in [(0.0, 5.0), (PI / 2.0, 5.0), (PI, 5.0), (-PI / 2.0, 5.0)] {
            assert!((w.cast(&o, a, 10.0).unwrap() - d).abs() < 1e-12);
        }
        // Corner at 45°: distance h·√2.
        assert!((w.cast(&o, PI / 4.0, 10.0).unwrap() - h * 2f64.sqrt()).abs() < 1e-9);
    }

    #[test]
    fn circle_of_segments_and_outside_origins() {
        // A 64-gon inscribed in a circle of radius R, seen from the centre: every ray hits
        // at a distance between R·cos(π/64) and R.
        let r = 7.0;
        let poly: Vec<Point2> = (0..64)
            .map(|k| {
                let a = k as f64 * 2.0 * PI / 64.0;
                Point2::new(r * a.cos(), r * a.sin())
            })
            .collect();
        let w = World::from_polygons(&[poly]).unwrap();
        for k in 0..720 {
            let a = k as f64 * PI / 360.0 - PI;
            let d = w.cast(&Point2::new(0.0, 0.0), a, 20.0).unwrap();
            assert!(d <= r + 1e-9 && d >= r * (PI / 64.0).cos() - 1e-9);
        }
        // From far outside, aimed at the centre: hits the near side at ≈ 30 − R.
        let d = w.cast(&Point2::new(30.0, 0.0), PI, 100.0).unwrap();
        assert!((d - (30.0 - r)).abs() < 1e-9);
        // From outside, aimed away: nothing.
        assert!(w.cast(&Point2::new(30.0, 0.0), 0.0, 100.0).is_none());
    }

    #[test]
    fn grid_cast_equals_brute_force_on_random_walls() {
        let mut rng = stream(2, 51);
        let segs: Vec<Segment> = (0..200)
            .map(|_| {
                let (x, y) = (rng.random_range(-25.0..25.0), rng.random_range(-25.0..25.0));
                let (a, l) = (rng.random_range(-PI..PI), rng.random_range(0.3..6.0));
                Segment::new(x, y, x + l * f64::cos(a), y + l * f64::sin(a))
            })
            .collect();
        let w = World::new(segs).unwrap();
        for _ in 0..20_000 {
            let p = Point2::new(rng.random_range(-30.0..30.0), rng.random_range(-30.0..30.0));
            let a = rng.random_range(-PI..PI);
            let m = rng.random_range(1.0..40.0);
            let (g, b) = (w.cast(&p, a, m), w.cast_brute_force(&p, a, m));
            match (g, b) {
                (Some(g), Some(b)) => assert!((g - b).abs() < 1e-9),
                (None, None) => {}
                _ => panic!("grid {g:?} vs brute force {b:?}"),
            }
        }
    }

    #[test]
    fn grid_map_walls() {
        // A 10 × 10 map at 0.1 m with a solid border ring one cell thick and one solid cell
        // at (5, 5): the inside is the square [0.1, 0.9]², the pillar [0.5, 0.6]².
        let mut m = GridMap::unknown(0.1, Point2::new(0.0, 0.0), 10, 10);
        for iy in 0..10 {
            for ix in 0..10 {
                let border = ix == 0 || iy == 0 || ix == 9 || iy == 9;
                m.cells[iy * 10 + ix] = if border || (ix, iy) == (5, 5) { 100 } else { 0 };
            }
        }
        let w = World::from_grid_map(&m).unwrap();
        // Runs are merged: outer 4 + inner 4 + pillar 4 edges.
        assert_eq!(w.segments().len(), 12);
        let p = Point2::new(0.25, 0.55);
        assert!((w.cast(&p, 0.0, 5.0).unwrap() - 0.25).abs() < 1e-9); // pillar face x = 0.5
        assert!((w.cast(&p, PI, 5.0).unwrap() - 0.15).abs() < 1e-9); // inner wall x = 0.1
        assert!((w.cast(&p, PI / 2.0, 5.0).unwrap() - 0.35).abs() < 1e-9); // y = 0.9
        assert!(World::from_grid_map(&GridMap::unknown(0.1, Point2::new(0.0, 0.0), 4, 4)).is_err());
        assert!(World::from_grid_map_with(
            &GridMap::unknown(0.1, Point2::new(0.0, 0.0), 4, 4),
            65,
            true
        )
        .is_ok());
    }

    #[test]
    fn rasterize_then_reload_keeps_the_geometry() {
        // A 10 m square room rasterised at 5 cm and turned back into walls: ranges from
        // inside agree with the analytic ones to within a cell.
        let w = square_room(5.0);
        let m = w.rasterize(0.05, 0.5).unwrap();
        assert!(m.cells.iter().filter(|&&c| c == 100).count() >= 4 * 200);
        let back = World::from_grid_map(&m).unwrap();
        for k in 0..36 {
            let a = k as f64 * 10f64.to_radians();
            let (d0, d1) = (
                w.cast(&Point2::new(0.3, -0.2), a, 20.0).unwrap(),
                back.cast(&Point2::new(0.3, -0.2), a, 20.0).unwrap(),
            );
            assert!(
                (d0 - d1).abs() < 0.05 * 1.5 / a.cos().abs().max(a.sin().abs()),
                "{a}: {d0} vs {d1}"
            );
        }
        assert!(w.rasterize(0.0, 1.0).is_err());
    }

    #[test]
    fn invalid_worlds_are_errors() {
        assert!(World::new(Vec::new()).is_err());
        assert!(World::new(vec![Segment::new(0.0, 0.0, 0.0, 0.0)]).is_err());
        assert!(World::new(vec![Segment::new(0.0, f64::NAN, 1.0, 0.0)]).is_err());
    }
}
