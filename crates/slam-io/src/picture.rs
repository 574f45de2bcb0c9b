//! PNG pictures of a SLAM result: occupancy map, trajectories, ground truth, landmark 95 %
//! error ellipses, true landmarks and the particle cloud; and a simple series plot (for
//! NEES curves with their chi-square band).
//!
//! The view fits every layer automatically (5 % margin; landmark estimates by their means,
//! so the huge ellipses of freshly initialised landmarks are clipped rather than shrinking
//! the map), keeps the aspect ratio (one
//! scale for x and y) and puts **y up** (world y grows towards the top of the image). No
//! text is drawn; layers have fixed, distinct colours:
//!
//! | layer | colour |
//! |---|---|
//! | map | grey levels: white free, black occupied, light grey unknown |
//! | metric grid (when there is no map) | very light grey lines at a 1-2-5 step |
//! | estimated trajectory | the caller's colour (e.g. [`RED`]), start marked by a disc |
//! | ground truth | green |
//! | landmark estimates | blue 95 % ellipses with a dot at the mean |
//! | true landmarks | black crosses |
//! | particles | teal dots |

use crate::error::IoError;
use crate::glyphs;
use image::RgbImage;
use slam_models::{GridMap, LandmarkEstimate, LandmarkId, Point2, Pose2, WeightedPose};
use std::path::Path;

/// Pixel type of the rendered image.
type Px = image::Rgb<u8>;

/// An 8-bit sRGB colour `Rgb([r, g, b])`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Rgb(pub [u8; 3]);

impl From<Rgb> for image::Rgb<u8> {
    fn from(c: Rgb) -> Self {
        image::Rgb(c.0)
    }
}

/// Estimated trajectory default colour.
pub const RED: Rgb = Rgb([220, 30, 30]);
/// Ground-truth colour.
pub const GREEN: Rgb = Rgb([0, 160, 0]);
/// Landmark-estimate colour.
pub const BLUE: Rgb = Rgb([30, 60, 230]);
/// True-landmark colour.
pub const BLACK: Rgb = Rgb([0, 0, 0]);
/// Particle colour.
pub const TEAL: Rgb = Rgb([0, 160, 170]);
/// A fourth trajectory colour (e.g. raw odometry).
pub const PURPLE: Rgb = Rgb([150, 50, 180]);
const WHITE: Px = image::Rgb([255, 255, 255]);
const GRID: Px = image::Rgb([232, 232, 232]);

/// χ²₂ 95 % quantile: the 95 % ellipse is {x : (x − μ)ᵀΣ⁻¹(x − μ) ≤ 5.991}.
const CHI2_2_95: f64 = 5.991_464_547;

/// A picture under construction (builder style); see the module docs for the layers.
///
/// # Example
///
/// ```
/// use slam_io::picture::{Picture, RED};
/// use slam_models::Pose2;
/// let path: Vec<Pose2> = (0..50).map(|i| Pose2::new(0.1 * i as f64, (0.1 * i as f64).sin(), 0.0)).collect();
/// let img = Picture::new().size(200).ground_truth(&path).trajectory(&path, RED).render()?;
/// assert_eq!(img.width(), 200);
/// # Ok::<(), slam_io::IoError>(())
/// ```
#[derive(Debug, Clone)]
pub struct Picture {
    map: Option<GridMap>,
    trajectories: Vec<(Vec<Pose2>, Rgb)>,
    ground_truth: Vec<Pose2>,
    landmarks: Vec<LandmarkEstimate>,
    true_landmarks: Vec<Point2>,
    particles: Vec<WeightedPose>,
    max_size: u32,
}

impl Default for Picture {
    fn default() -> Self {
        Self::new()
    }
}

/// World → pixel mapping with y up.
#[derive(Clone, Copy)]
struct View {
    min_x: f64,
    max_y: f64,
    scale: f64,
    w: u32,
    h: u32,
}

impl View {
    fn px(&self, p: &Point2) -> (f64, f64) {
        (
            (p.x - self.min_x) * self.scale,
            (self.max_y - p.y) * self.scale,
        )
    }
    fn world(&self, px: f64, py: f64) -> Point2 {
        Point2::new(self.min_x + px / self.scale, self.max_y - py / self.scale)
    }
}

impl Picture {
    /// An empty picture, at most 1000 px on its longer side.
    pub fn new() -> Self {
        Self {
            map: None,
            trajectories: Vec::new(),
            ground_truth: Vec::new(),
            landmarks: Vec::new(),
            true_landmarks: Vec::new(),
            particles: Vec::new(),
            max_size: 1000,
        }
    }

    /// The longer side in pixels (clamped to 100…8000).
    pub fn size(mut self, max_size: u32) -> Self {
        self.max_size = max_size.clamp(100, 8000);
        self
    }

    /// An occupancy map as the background.
    pub fn map(mut self, m: &GridMap) -> Self {
        self.map = Some(m.clone());
        self
    }

    /// An estimated trajectory in `colour` (may be called several times).
    pub fn trajectory(mut self, poses: &[Pose2], colour: Rgb) -> Self {
        self.trajectories.push((poses.to_vec(), colour));
        self
    }

    /// The ground-truth trajectory (green).
    pub fn ground_truth(mut self, poses: &[Pose2]) -> Self {
        self.ground_truth = poses.to_vec();
        self
    }

    /// Landmark estimates, drawn as their 95 % error ellipses (blue).
    pub fn landmarks(mut self, l: &[LandmarkEstimate]) -> Self {
        self.landmarks = l.to_vec();
        self
    }

    /// True landmark positions (black crosses).
    pub fn true_landmarks(mut self, l: &[(LandmarkId, Point2)]) -> Self {
        self.true_landmarks = l.iter().map(|(_, p)| *p).collect();
        self
    }

    /// A particle cloud (teal dots).
    pub fn particles(mut self, p: &[WeightedPose]) -> Self {
        self.particles = p.to_vec();
        self
    }

    /// World bounding box of everything drawn (finite values only).
    fn bounds(&self) -> Option<(f64, f64, f64, f64)> {
        let mut b: Option<(f64, f64, f64, f64)> = None;
        let mut add = |p: Point2| {
            if !(p.x.is_finite() && p.y.is_finite()) {
                return;
            }
            b = Some(match b {
                None => (p.x, p.y, p.x, p.y),
                Some((a, c, d, e)) => (a.min(p.x), c.min(p.y), d.max(p.x), e.max(p.y)),
            });
        };
        if let Some(m) = &self.map {
            // The extent of the known cells (unknown borders are not worth the space).
            let (mut lo, mut hi) = ((usize::MAX, usize::MAX), (0, 0));
            for iy in 0..m.height {
                for ix in 0..m.width {
                    if m.cells.get(iy * m.width + ix).is_some_and(|&v| v >= 0) {
                        lo = (lo.0.min(ix), lo.1.min(iy));
                        hi = (hi.0.max(ix), hi.1.max(iy));
                    }
                }
            }
            if lo.0 != usize::MAX {
                let r = m.resolution;
                add(Point2::new(
                    m.origin.x + lo.0 as f64 * r,
                    m.origin.y + lo.1 as f64 * r,
                ));
                add(Point2::new(
                    m.origin.x + (hi.0 + 1) as f64 * r,
                    m.origin.y + (hi.1 + 1) as f64 * r,
                ));
            }
        }
        for (t, _) in &self.trajectories {
            t.iter().for_each(|p| add(p.translation()));
        }
        self.ground_truth.iter().for_each(|p| add(p.translation()));
        self.true_landmarks.iter().for_each(|p| add(*p));
        self.particles
            .iter()
            .for_each(|p| add(p.pose.translation()));
        for l in &self.landmarks {
            add(l.mean);
        }
        b
    }

    /// Renders the picture to an image.
    pub fn render(&self) -> Result<RgbImage, IoError> {
        let Some((x0, y0, x1, y1)) = self.bounds() else {
            return Err(IoError::Picture(
                "nothing to draw (all layers empty or non-finite)".into(),
            ));
        };
        let span = (x1 - x0).max(y1 - y0).max(1.0);
        let pad = 0.05 * span;
        let (x0, y0, x1, y1) = (x0 - pad, y0 - pad, x1 + pad, y1 + pad);
        let scale = self.max_size as f64 / (x1 - x0).max(y1 - y0);
        let w = (((x1 - x0) * scale).ceil() as u32).clamp(1, self.max_size);
        let h = (((y1 - y0) * scale).ceil() as u32).clamp(1, self.max_size);
        let view = View {
            min_x: x0,
            max_y: y1,
            scale,
            w,
            h,
        };
        let mut img = RgbImage::from_pixel(w, h, WHITE);
        match &self.map {
            Some(m) => draw_map(&mut img, &view, m),
            None => draw_grid(&mut img, &view),
        }
        for p in &self.particles {
            let (u, v) = view.px(&p.pose.translation());
            disc(&mut img, u, v, 1.5, TEAL.into());
        }
        if !self.ground_truth.is_empty() {
            polyline(&mut img, &view, &self.ground_truth, GREEN.into());
        }
        for (t, c) in &self.trajectories {
            polyline(&mut img, &view, t, (*c).into());
            if let Some(p) = t.first() {
                let (u, v) = view.px(&p.translation());
                disc(&mut img, u, v, 4.0, (*c).into());
            }
        }
        for l in &self.landmarks {
            ellipse(&mut img, &view, l);
        }
        for p in &self.true_landmarks {
            let (u, v) = view.px(p);
            for d in -5..=5 {
                let d = d as f64;
                for o in [-0.5, 0.5] {
                    put(&mut img, u + d, v + d + o, BLACK.into());
                    put(&mut img, u + d, v - d + o, BLACK.into());
                }
            }
        }
        Ok(img)
    }

    /// Renders and writes a PNG.
    pub fn save_png(&self, path: &Path) -> Result<(), IoError> {
        let img = self.render()?;
        img.save_with_format(path, image::ImageFormat::Png)
            .map_err(|e| IoError::invalid(path, format!("cannot write PNG: {e}")))
    }
}

fn put(img: &mut RgbImage, u: f64, v: f64, c: Px) {
    if u >= 0.0 && v >= 0.0 && u < img.width() as f64 && v < img.height() as f64 {
        img.put_pixel(u as u32, v as u32, c);
    }
}

fn disc(img: &mut RgbImage, u: f64, v: f64, r: f64, c: Px) {
    let ri = r.ceil() as i64;
    for dy in -ri..=ri {
        for dx in -ri..=ri {
            if ((dx * dx + dy * dy) as f64) <= r * r {
                put(img, u + dx as f64, v + dy as f64, c);
            }
        }
    }
}

/// A 2-px wide segment (sampled at half-pixel steps).
fn segment(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), c: Px, width: f64) {
    let len = (b.0 - a.0).hypot(b.1 - a.1);
    if !len.is_finite() || len > 1e5 {
        return;
    }
    let n = (len * 2.0).ceil().max(1.0) as usize;
    for i in 0..=n {
        let s = i as f64 / n as f64;
        let (u, v) = (a.0 + s * (b.0 - a.0), a.1 + s * (b.1 - a.1));
        if width <= 1.0 {
            put(img, u, v, c);
        } else {
            disc(img, u, v, width / 2.0, c);
        }
    }
}

fn polyline(img: &mut RgbImage, view: &View, poses: &[Pose2], c: Px) {
    for w in poses.windows(2) {
        segment(
            img,
            view.px(&w[0].translation()),
            view.px(&w[1].translation()),
            c,
            2.0,
        );
    }
}

fn ellipse(img: &mut RgbImage, view: &View, l: &LandmarkEstimate) {
    let (u, v) = view.px(&l.mean);
    disc(img, u, v, 2.0, BLUE.into());
    // Σ = R diag(λ1, λ2) Rᵀ (closed form for a symmetric 2×2 matrix).
    let c = l.covariance;
    let (a, b, d) = (c[(0, 0)], 0.5 * (c[(0, 1)] + c[(1, 0)]), c[(1, 1)]);
    let tr = 0.5 * (a + d);
    let disc_ = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    let (l1, l2) = (tr + disc_, tr - disc_);
    if !(l1.is_finite() && l2 >= 0.0) {
        return;
    }
    let phi = 0.5 * (2.0 * b).atan2(a - d);
    let (r1, r2) = ((CHI2_2_95 * l1).sqrt(), (CHI2_2_95 * l2).sqrt());
    let (s, co) = phi.sin_cos();
    let pt = |t: f64| {
        let (x, y) = (r1 * t.cos(), r2 * t.sin());
        view.px(&Point2::new(
            l.mean.x + co * x - s * y,
            l.mean.y + s * x + co * y,
        ))
    };
    let n = 72;
    for k in 0..n {
        let t0 = k as f64 / n as f64 * std::f64::consts::TAU;
        let t1 = (k + 1) as f64 / n as f64 * std::f64::consts::TAU;
        segment(img, pt(t0), pt(t1), BLUE.into(), 1.0);
    }
}

/// Paints the map under the other layers. Where a pixel is at least two cells wide (a 1 cm
/// map in a 1000 px picture of a 40 m building), the pixel pools the cells whose centres
/// fall inside it ([`pooled_value`]: occupied if any is, else their mean), so that
/// one-cell-thick walls and the free space between sparse beams stay visible; coarser maps
/// are sampled at each pixel's centre.
fn draw_map(img: &mut RgbImage, view: &View, m: &GridMap) {
    let grey = |v: i8| {
        let g = if v < 0 {
            205
        } else {
            255 - (v.min(100) as u32 * 255 / 100) as u8
        };
        image::Rgb([g, g, g])
    };
    let pixel = 1.0 / view.scale;
    let pooled = m.resolution > 0.0 && 2.0 * m.resolution <= pixel;
    for py in 0..view.h {
        for px in 0..view.w {
            let v = if pooled {
                pooled_value(m, view.world(px as f64, py as f64 + 1.0), pixel)
            } else {
                let p = view.world(px as f64 + 0.5, py as f64 + 0.5);
                m.cell_of(&p)
                    .map(|(ix, iy)| m.cells.get(iy * m.width + ix).copied().unwrap_or(-1))
            };
            if let Some(v) = v {
                img.put_pixel(px, py, grey(v));
            }
        }
    }
}

/// The value a pixel shows for the cells of `m` whose centres lie in the square of side
/// `side` with lower-left corner `corner` (world metres): the most occupied value when any
/// cell is occupied (≥ 65, map_server's `occupied_thresh`), otherwise the mean of the known
/// cells; −1 when all are unknown; `None` when no cell centre lies inside.
fn pooled_value(m: &GridMap, corner: Point2, side: f64) -> Option<i8> {
    // Cell i has its centre at origin + (i + ½)·res: the ones in [c, c + side).
    let first = |c: f64, o: f64| ((c - o) / m.resolution - 0.5).ceil().max(0.0);
    let (fx, fy) = (first(corner.x, m.origin.x), first(corner.y, m.origin.y));
    let (lx, ly) = (
        first(corner.x + side, m.origin.x).min(m.width as f64),
        first(corner.y + side, m.origin.y).min(m.height as f64),
    );
    if !(fx < lx && fy < ly) {
        return None;
    }
    let (mut most, mut sum, mut known) = (-1i8, 0i64, 0i64);
    for iy in fy as usize..ly as usize {
        let row = &m.cells[iy * m.width..(iy + 1) * m.width];
        for &v in &row[fx as usize..lx as usize] {
            if v >= 0 {
                most = most.max(v);
                sum += v as i64;
                known += 1;
            }
        }
    }
    Some(match known {
        0 => -1,
        _ if most >= 65 => most,
        _ => (sum / known) as i8,
    })
}

/// The 1-2-5 step giving about `target` intervals over `span`.
fn nice_step(span: f64, target: f64) -> f64 {
    let raw = span / target;
    let mag = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|k| k * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag)
}

fn draw_grid(img: &mut RgbImage, view: &View) {
    let (w, h) = (view.w as f64, view.h as f64);
    let tl = view.world(0.0, 0.0);
    let br = view.world(w, h);
    let step = nice_step((br.x - tl.x).max(tl.y - br.y), 8.0);
    let label = image::Rgb([120, 120, 120]);
    let mut x = (tl.x / step).ceil() * step;
    while x <= br.x {
        let (u, _) = view.px(&Point2::new(x, 0.0));
        segment(img, (u, 0.0), (u, h), GRID, 1.0);
        // World x in metres along the bottom edge.
        let text = glyphs::format_tick(x, step);
        glyphs::draw_text(img, u as i64 + 3, h as i64 - 13, &text, label, 2);
        x += step;
    }
    let mut y = (br.y / step).ceil() * step;
    while y <= tl.y {
        let (_, v) = view.px(&Point2::new(0.0, y));
        segment(img, (0.0, v), (w, v), GRID, 1.0);
        // World y in metres along the left edge.
        let text = glyphs::format_tick(y, step);
        glyphs::draw_text(img, 3, v as i64 - 12, &text, label, 2);
        y += step;
    }
    glyphs::draw_text(img, w as i64 - 12, h as i64 - 26, "m", label, 2);
}

/// One curve of a [`plot_series`] plot.
#[derive(Debug, Clone, Copy)]
pub struct Series<'a> {
    /// y values, one per x.
    pub y: &'a [f64],
    /// Line colour.
    pub colour: Rgb,
}

/// How a [`plot_series_with`] axis maps values to pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    /// Linear; the y axis always includes 0.
    #[default]
    Linear,
    /// Base-10 logarithmic, ticks at 1-2-5 × 10ᵏ (only 10ᵏ beyond three decades);
    /// non-positive values are not drawn.
    Log10,
}

/// The scales of a plot's two axes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Axes {
    /// Horizontal axis scale.
    pub x: Scale,
    /// Vertical axis scale.
    pub y: Scale,
}

/// A line plot of one or more series over shared `x` values, with an optional horizontal
/// band [lo, hi] shaded light blue and outlined (e.g. the chi-square 95 % band of an
/// average NEES, from [`crate::eval::chi2_band`]). Bounds fit the data and the band; light
/// grey lines mark a 1-2-5 grid in y, labelled with its values, and the x axis carries
/// 1-2-5 tick values. Non-finite points break the line. Errors
/// when a series' length differs from `x`'s or nothing is finite.
pub fn plot_series(
    path: &Path,
    x: &[f64],
    series: &[Series<'_>],
    band: Option<(f64, f64)>,
) -> Result<(), IoError> {
    plot_series_with(path, x, series, band, Axes::default())
}

/// Tick values of an axis spanning [lo, hi] in plotted units (log10 of the value on a log
/// axis), as (plotted position, label).
fn ticks(scale: Scale, lo: f64, hi: f64, target: f64) -> Vec<(f64, String)> {
    let mut out = Vec::new();
    match scale {
        Scale::Linear => {
            let step = nice_step(hi - lo, target);
            let mut g = (lo / step).ceil() * step;
            while g <= hi + 1e-9 * step {
                out.push((g, glyphs::format_tick(g, step)));
                g += step;
            }
        }
        Scale::Log10 => {
            let mults: &[f64] = if hi - lo > 3.0 {
                &[1.0]
            } else {
                &[1.0, 2.0, 5.0]
            };
            for k in (lo.floor() as i32)..=(hi.ceil() as i32) {
                let decade = 10f64.powi(k);
                for &m in mults {
                    let v = m * decade;
                    let p = v.log10();
                    if p >= lo - 1e-9 && p <= hi + 1e-9 {
                        out.push((p, glyphs::format_tick(v, decade)));
                    }
                }
            }
        }
    }
    out
}

/// [`plot_series`] with a choice of linear or logarithmic axes (e.g. error against particle
/// count on log–log axes).
pub fn plot_series_with(
    path: &Path,
    x: &[f64],
    series: &[Series<'_>],
    band: Option<(f64, f64)>,
    axes: Axes,
) -> Result<(), IoError> {
    let (w, h, m) = (900u32, 450u32, 20.0);
    // Room on the left for the y labels, below for the x labels.
    let (ml, mb) = (56.0, 30.0);
    for s in series {
        if s.y.len() != x.len() {
            return Err(IoError::invalid(
                path,
                format!("series of {} values for {} x values", s.y.len(), x.len()),
            ));
        }
    }
    // Values in plotted units: log10 on a log axis (non-positive values become NaN).
    let tf = |scale: Scale, v: f64| match scale {
        Scale::Linear => v,
        Scale::Log10 if v > 0.0 => v.log10(),
        Scale::Log10 => f64::NAN,
    };
    let x: Vec<f64> = x.iter().map(|&v| tf(axes.x, v)).collect();
    let ys_plotted: Vec<Vec<f64>> = series
        .iter()
        .map(|s| s.y.iter().map(|&v| tf(axes.y, v)).collect())
        .collect();
    let band = band.map(|(lo, hi)| (tf(axes.y, lo), tf(axes.y, hi)));
    let xs: Vec<f64> = x.iter().copied().filter(|v| v.is_finite()).collect();
    let mut ys: Vec<f64> = ys_plotted
        .iter()
        .flatten()
        .copied()
        .filter(|v| v.is_finite())
        .collect();
    if let Some((lo, hi)) = band {
        ys.extend([lo, hi].into_iter().filter(|v| v.is_finite()));
    }
    if xs.is_empty() || ys.is_empty() {
        return Err(IoError::invalid(path, "nothing finite to plot"));
    }
    let (x0, x1) = xs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let (mut y0, mut y1) = ys
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if axes.y == Scale::Linear {
        y0 = y0.min(0.0);
    }
    if y1 - y0 < 1e-12 {
        y1 = y0 + 1.0;
    }
    let x1 = if x1 - x0 < 1e-12 { x0 + 1.0 } else { x1 };
    let y1 = y1 + 0.05 * (y1 - y0);
    if axes.y == Scale::Log10 {
        y0 -= 0.05 * (y1 - y0);
    }
    let to_px = |xv: f64, yv: f64| {
        (
            ml + (xv - x0) / (x1 - x0) * (w as f64 - ml - m),
            (h as f64 - mb) - (yv - y0) / (y1 - y0) * (h as f64 - mb - m),
        )
    };
    let label = image::Rgb([90, 90, 90]);
    let mut img = RgbImage::from_pixel(w, h, WHITE);
    for (g, text) in ticks(axes.y, y0, y1, 6.0) {
        let (_, v) = to_px(x0, g);
        segment(&mut img, (ml, v), (w as f64 - m, v), GRID, 1.0);
        let tw = glyphs::text_width(&text, 2) as i64;
        glyphs::draw_text(&mut img, ml as i64 - 6 - tw, v as i64 - 5, &text, label, 2);
    }
    // x labels: a 1-2-5 grid of ticks under the axis.
    for (gx, text) in ticks(axes.x, x0, x1, 8.0) {
        let (u, _) = to_px(gx, y0);
        let tw = glyphs::text_width(&text, 2) as i64;
        glyphs::draw_text(
            &mut img,
            u as i64 - tw / 2,
            h as i64 - mb as i64 + 8,
            &text,
            label,
            2,
        );
    }
    if let Some((lo, hi)) = band.filter(|(lo, hi)| lo.is_finite() && hi.is_finite() && lo <= hi) {
        let (_, vlo) = to_px(x0, lo);
        let (_, vhi) = to_px(x0, hi);
        for py in vhi.max(0.0) as u32..=(vlo.min(h as f64 - 1.0) as u32) {
            for px in ml as u32..(w - m as u32) {
                img.put_pixel(px, py, image::Rgb([215, 230, 250]));
            }
        }
        segment(&mut img, (ml, vlo), (w as f64 - m, vlo), BLUE.into(), 1.0);
        segment(&mut img, (ml, vhi), (w as f64 - m, vhi), BLUE.into(), 1.0);
    }
    // Axes: left and bottom.
    segment(&mut img, (ml, m), (ml, h as f64 - mb), BLACK.into(), 1.0);
    let (_, v0) = to_px(x0, y0.max(0.0).min(y1));
    let v0 = if axes.y == Scale::Log10 {
        h as f64 - mb
    } else {
        v0
    };
    segment(&mut img, (ml, v0), (w as f64 - m, v0), BLACK.into(), 1.0);
    for (s, y) in series.iter().zip(&ys_plotted) {
        for i in 1..x.len() {
            let (a, b) = ((x[i - 1], y[i - 1]), (x[i], y[i]));
            if [a.0, a.1, b.0, b.1].iter().all(|v| v.is_finite()) {
                segment(
                    &mut img,
                    to_px(a.0, a.1),
                    to_px(b.0, b.1),
                    s.colour.into(),
                    2.0,
                );
            }
        }
    }
    img.save_with_format(path, image::ImageFormat::Png)
        .map_err(|e| IoError::invalid(path, format!("cannot write PNG: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::Matrix2;

    #[test]
    fn y_is_up_and_layers_have_their_colours() {
        // A trajectory going up (y grows): its end must be near the top of the image.
        let traj: Vec<Pose2> = (0..=10).map(|i| Pose2::new(0.0, i as f64, 0.0)).collect();
        let img = Picture::new()
            .size(200)
            .trajectory(&traj, RED)
            .render()
            .unwrap();
        let red_rows: Vec<u32> = img
            .enumerate_pixels()
            .filter(|(_, _, p)| p.0 == RED.0)
            .map(|(_, y, _)| y)
            .collect();
        assert!(!red_rows.is_empty());
        // The start disc (bigger) is at the bottom: more red pixels in the lower part.
        let lower = red_rows.iter().filter(|&&y| y > img.height() / 2).count();
        let upper = red_rows.len() - lower;
        assert!(lower > upper);
        assert!(red_rows.iter().min().unwrap() < &(img.height() / 10 + 2));
    }

    #[test]
    fn ellipse_is_drawn_to_the_95_percent_radius() {
        // Σ = diag(1, 0.01): semi-axes √(5.991) ≈ 2.45 m along x and 0.245 m along y.
        let l = LandmarkEstimate {
            id: LandmarkId(1),
            mean: Point2::new(0.0, 0.0),
            covariance: Matrix2::new(1.0, 0.0, 0.0, 0.01),
        };
        let corners = [
            (LandmarkId(0), Point2::new(-5.0, -5.0)),
            (LandmarkId(0), Point2::new(5.0, 5.0)),
        ];
        let pic = Picture::new()
            .size(500)
            .landmarks(&[l])
            .true_landmarks(&corners);
        let img = pic.render().unwrap();
        let blue: Vec<(u32, u32)> = img
            .enumerate_pixels()
            .filter(|(_, _, p)| p.0 == BLUE.0)
            .map(|(x, y, _)| (x, y))
            .collect();
        let (min_x, max_x) = (
            blue.iter().map(|b| b.0).min().unwrap(),
            blue.iter().map(|b| b.0).max().unwrap(),
        );
        let (min_y, max_y) = (
            blue.iter().map(|b| b.1).min().unwrap(),
            blue.iter().map(|b| b.1).max().unwrap(),
        );
        // 11 m span (10 + 5 % margins) over 500 px: 45.45 px/m.
        let scale = 500.0 / 11.0;
        let wx = (max_x - min_x) as f64 / scale;
        let wy = (max_y - min_y) as f64 / scale;
        assert!((wx - 2.0 * CHI2_2_95.sqrt()).abs() < 0.1, "{wx}");
        assert!((wy - 0.2 * CHI2_2_95.sqrt()).abs() < 0.1, "{wy}");
    }

    /// A 1 cm map drawn into 100 px (≈ 10 cm per pixel): a one-cell-thick wall is dark in
    /// every pixel it crosses (centre sampling would hit it in about one pixel of ten), free
    /// cells show white, and all-unknown stays grey.
    #[test]
    fn fine_maps_are_pooled_so_thin_walls_stay_visible() {
        let n = 1000;
        let mut m = GridMap::unknown(0.01, Point2::new(0.0, 0.0), n, n);
        for iy in 0..n {
            for ix in 0..n / 2 {
                m.cells[iy * n + ix] = 0;
            }
            // A wall one cell thick at x = 2.505 m.
            m.cells[iy * n + 250] = 100;
        }
        let img = Picture::new().size(100).map(&m).render().unwrap();
        // The picture spans the known cells (x 0–5 m, y 0–10 m) padded by 5 % of the longer
        // side: 11 m over the 100 px height.
        let view_x = |x: f64| ((x + 0.5) / 11.0 * img.height() as f64) as u32;
        let wall_px = view_x(2.505);
        let dark_rows = (10..img.height() - 10)
            .filter(|&py| img.get_pixel(wall_px, py).0 == [0, 0, 0])
            .count();
        assert_eq!(dark_rows, (img.height() - 20) as usize, "the wall has gaps");
        let mid = img.height() / 2;
        assert_eq!(*img.get_pixel(view_x(1.0), mid), WHITE);
        assert_eq!(img.get_pixel(view_x(5.3), mid).0, [205, 205, 205]);
    }

    #[test]
    fn map_grey_levels_and_errors() {
        let mut m = GridMap::unknown(1.0, Point2::new(0.0, 0.0), 2, 1);
        m.cells = vec![0, 100];
        let img = Picture::new().size(100).map(&m).render().unwrap();
        // Left half free (white), right half occupied (black), y up irrelevant here.
        let mid = img.height() / 2;
        assert_eq!(*img.get_pixel(20, mid), WHITE);
        assert_eq!(img.get_pixel(img.width() - 20, mid).0, [0, 0, 0]);
        assert!(Picture::new().render().is_err());
        let p = std::env::temp_dir().join(format!("slam-io-plot-{}.png", std::process::id()));
        assert!(plot_series(
            &p,
            &[0.0, 1.0],
            &[Series {
                y: &[1.0],
                colour: RED
            }],
            None
        )
        .is_err());
        plot_series(
            &p,
            &[0.0, 1.0, 2.0],
            &[Series {
                y: &[1.0, 3.0, 2.0],
                colour: RED,
            }],
            Some((0.5, 2.5)),
        )
        .unwrap();
        std::fs::remove_file(&p).ok();
    }

    #[test]
    fn log_axes_tick_at_decades_and_straighten_power_laws() {
        let labels: Vec<String> = ticks(Scale::Log10, 0.0, 2.0, 8.0)
            .into_iter()
            .map(|(_, t)| t)
            .collect();
        assert_eq!(labels, ["1", "2", "5", "10", "20", "50", "100"]);
        let wide: Vec<String> = ticks(Scale::Log10, -2.0, 2.0, 8.0)
            .into_iter()
            .map(|(_, t)| t)
            .collect();
        assert_eq!(wide, ["0.01", "0.1", "1", "10", "100"]);
        // y = 1/x over 1..100 on log–log axes is a straight line: the red pixel of the
        // middle column lies halfway between the red pixels of the first and last columns.
        let x: Vec<f64> = (0..=20).map(|k| 10f64.powf(k as f64 / 10.0)).collect();
        let y: Vec<f64> = x.iter().map(|v| 1.0 / v).collect();
        let p = std::env::temp_dir().join(format!("slam-io-loglog-{}.png", std::process::id()));
        let axes = Axes {
            x: Scale::Log10,
            y: Scale::Log10,
        };
        let curve = [Series { y: &y, colour: RED }];
        plot_series_with(&p, &x, &curve, None, axes).unwrap();
        let img = image::open(&p).unwrap().to_rgb8();
        std::fs::remove_file(&p).ok();
        let red_row = |col: u32| -> Option<f64> {
            let rows: Vec<u32> = (0..img.height())
                .filter(|&r| img.get_pixel(col, r).0 == RED.0)
                .collect();
            (!rows.is_empty()).then(|| rows.iter().sum::<u32>() as f64 / rows.len() as f64)
        };
        let (first, last) = (58, img.width() - 22);
        let (a, b) = (red_row(first).unwrap(), red_row(last).unwrap());
        let mid = red_row((first + last) / 2).unwrap();
        assert!(a < b, "falling curve: top-left to bottom-right");
        assert!((mid - (a + b) / 2.0).abs() < 3.0, "{a} {mid} {b}");
        // Non-positive values are skipped on a log axis, not an error.
        plot_series_with(
            &p,
            &[1.0, 2.0],
            &[Series {
                y: &[0.0, 1.0],
                colour: RED,
            }],
            None,
            axes,
        )
        .unwrap();
        std::fs::remove_file(&p).ok();
    }
}
