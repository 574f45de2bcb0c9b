//! PNG pictures of a SLAM result (occupancy map, trajectories, ground truth, landmark 95 %
//! error ellipses, true landmarks, the particle cloud, every particle's path and landmark
//! estimates) and a simple series plot (for NEES curves with their chi-square band).
//!
//! A map picture has a title band on top, the plot framed by axes with ticks labelled in
//! metres (x under it, y on its left), a scale bar under its right end and a legend naming
//! every layer drawn (in the plot's corner that hides the least; left out when the plot is
//! too small to hold it), set in DejaVu Sans (compiled in, see `fonts/`). The view fits every
//! layer (5 % margin; landmark estimates by their means, so the huge ellipses of freshly
//! initialised landmarks are clipped rather than shrinking the map), or a window the caller
//! fixes ([`Picture::fit_to`], for animation frames); it keeps the aspect ratio (one scale
//! for x and y) and puts **y up**. Layers, from bottom to top:
//!
//! | layer | look | legend |
//! |---|---|---|
//! | map | grey levels: white free, black occupied, light grey unknown | occupied / free / unknown |
//! | metric grid (when there is no map) | very light grey lines at the ticks | — |
//! | every particle's path | grey, 1 px | particle paths |
//! | ground truth | green, 2 px | ground truth |
//! | every particle's landmark estimates | small light-blue dots | landmarks of every particle |
//! | landmark estimates | blue 95 % ellipses with a dot at the mean | the caller's label |
//! | true landmarks | black crosses | true landmarks |
//! | estimated trajectories | the caller's colour, 2 px, a disc at the start and an arrow along the final heading | the caller's label |
//! | particles | teal dots | particles, now |
//!
//! Coordinates beyond ±[`MAX_COORDINATE_M`] are an error ([`VizError::Extent`]):
//! there an f64 cannot resolve the axes' metre grid. Non-finite points are skipped.

use crate::error::VizError;
use crate::font::{self, draw_text, text_size};
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

/// Estimated trajectory colour (the course exercise's best particle).
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
/// Colour of every particle's path.
pub const GREY: Rgb = Rgb([165, 165, 165]);
/// Colour of every particle's landmark estimates.
pub const LIGHT_BLUE: Rgb = Rgb([120, 160, 245]);
const WHITE: Px = image::Rgb([255, 255, 255]);
const GRID: Px = image::Rgb([232, 232, 232]);
const FRAME: Px = image::Rgb([60, 60, 60]);
const LABEL: Px = image::Rgb([40, 40, 40]);
const UNKNOWN_GREY: u8 = 205;

/// χ²₂ 95 % quantile: the 95 % ellipse is {x : (x − μ)ᵀΣ⁻¹(x − μ) ≤ 5.991}.
const CHI2_2_95: f64 = 5.991_464_547;

/// The largest |x| or |y| in metres a picture draws: ten times the ±1e6 m the dataset readers
/// accept, so whatever a reader passes can be drawn; beyond it (a diverged filter) f64
/// resolves the world only to about 1e-9 of the coordinate and the axes' ticks would stop
/// being distinct, so it is an error instead.
pub const MAX_COORDINATE_M: f64 = 1e7;

/// The most ticks one axis gets. Ticks are counted by integer index from the first
/// multiple of the step inside the view, so the count is bounded whatever the coordinates
/// (a loop adding a step smaller than one ulp of the coordinate would never end).
pub const MAX_TICKS: usize = 100;

/// Text sizes in pixels.
const TITLE_PX: f32 = 21.0;
const LABEL_PX: f32 = 15.0;
const LEGEND_PX: f32 = 15.0;

/// Margins around the plot: left for the y tick labels, bottom for the x tick labels and
/// the x axis name, top for the title and the y axis name.
const MARGIN_LEFT: u32 = 76;
const MARGIN_RIGHT: u32 = 24;
const MARGIN_BOTTOM: u32 = 48;
const MARGIN_TOP_TITLE: u32 = 52;
const MARGIN_TOP: u32 = 26;

/// Where the plot sits in a rendered picture and how world metres map to its pixels:
/// pixel (u, v) of world point (x, y) is (`left` + (x − `min_x`)·`px_per_m`,
/// `top` + (`max_y` − y)·`px_per_m`), y up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Layout {
    /// Left edge of the plot area, pixels from the image's left.
    pub left: u32,
    /// Top edge of the plot area, pixels from the image's top.
    pub top: u32,
    /// Plot area width, pixels.
    pub width: u32,
    /// Plot area height, pixels.
    pub height: u32,
    /// World x at the plot's left edge, metres.
    pub min_x: f64,
    /// World y at the plot's top edge, metres.
    pub max_y: f64,
    /// Pixels per metre, the same along x and y.
    pub px_per_m: f64,
}

impl Layout {
    /// Image pixel coordinates (fractional) of world point `p`.
    pub fn pixel(&self, p: &Point2) -> (f64, f64) {
        (
            self.left as f64 + (p.x - self.min_x) * self.px_per_m,
            self.top as f64 + (self.max_y - p.y) * self.px_per_m,
        )
    }
}

/// An estimated trajectory layer.
#[derive(Debug, Clone)]
struct Track {
    poses: Vec<Pose2>,
    colour: Rgb,
    label: String,
}

/// A picture under construction (builder style); see the module docs for the layers.
///
/// # Example
///
/// ```
/// use slam_viz::picture::{Picture, RED};
/// use slam_models::Pose2;
/// let path: Vec<Pose2> = (0..50).map(|i| Pose2::new(0.1 * i as f64, (0.1 * i as f64).sin(), 0.0)).collect();
/// let img = Picture::new()
///     .title("a sine")
///     .size(200)
///     .ground_truth(&path)
///     .trajectory(&path, RED, "estimate")
///     .render()?;
/// // The plot is 200 px on its longer side, plus margins for the axes and the title.
/// assert!(img.width() > 200);
/// # Ok::<(), slam_viz::VizError>(())
/// ```
#[derive(Debug, Clone)]
pub struct Picture {
    title: Option<String>,
    map: Option<GridMap>,
    trajectories: Vec<Track>,
    ground_truth: Vec<Pose2>,
    ground_truth_label: String,
    landmarks: Vec<LandmarkEstimate>,
    landmarks_label: String,
    true_landmarks: Vec<Point2>,
    particles: Vec<WeightedPose>,
    particle_paths: Vec<Vec<Pose2>>,
    particle_landmarks: Vec<Point2>,
    fit: Option<Vec<Point2>>,
    square: bool,
    max_size: u32,
}

impl Default for Picture {
    fn default() -> Self {
        Self::new()
    }
}

/// World → plot-pixel mapping with y up (plot pixels: (0, 0) at the plot's top-left).
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
    fn max_x(&self) -> f64 {
        self.min_x + self.w as f64 / self.scale
    }
    fn min_y(&self) -> f64 {
        self.max_y - self.h as f64 / self.scale
    }
}

/// A legend entry's symbol.
#[derive(Clone, Copy)]
enum Swatch {
    Line(Px, f64),
    Dot(Px, f64),
    Cross(Px),
    Ellipse(Px),
    Square(Px),
}

impl Picture {
    /// An empty picture whose plot is at most 1000 px on its longer side.
    pub fn new() -> Self {
        Self {
            title: None,
            map: None,
            trajectories: Vec::new(),
            ground_truth: Vec::new(),
            ground_truth_label: "ground truth".into(),
            landmarks: Vec::new(),
            landmarks_label: "landmarks, 95 % ellipses".into(),
            true_landmarks: Vec::new(),
            particles: Vec::new(),
            particle_paths: Vec::new(),
            particle_landmarks: Vec::new(),
            fit: None,
            square: false,
            max_size: 1000,
        }
    }

    /// The title, drawn in the band above the plot (e.g. filter, data, particle count).
    pub fn title(mut self, title: impl Into<String>) -> Self {
        self.title = Some(title.into());
        self
    }

    /// The plot's longer side in pixels (clamped to 100…8000); the margins for the axes,
    /// their labels and the title come on top.
    pub fn size(mut self, max_size: u32) -> Self {
        self.max_size = max_size.clamp(100, 8000);
        self
    }

    /// Frames these world points (plus a 5 % margin) instead of the drawn layers; what lies
    /// outside is clipped. Animation frames use it so that every frame shows the same window.
    pub fn fit_to(mut self, points: &[Point2]) -> Self {
        self.fit = Some(points.to_vec());
        self
    }

    /// Widens the view to a square about its centre, so that the image's size in pixels
    /// does not depend on the content (every frame of an animation the same size).
    pub fn square(mut self, square: bool) -> Self {
        self.square = square;
        self
    }

    /// An occupancy map as the background.
    pub fn map(mut self, m: &GridMap) -> Self {
        self.map = Some(m.clone());
        self
    }

    /// An estimated trajectory in `colour`, named `label` in the legend (may be called
    /// several times); a disc marks its start and an arrow its final pose and heading.
    pub fn trajectory(mut self, poses: &[Pose2], colour: Rgb, label: &str) -> Self {
        self.trajectories.push(Track {
            poses: poses.to_vec(),
            colour,
            label: label.to_string(),
        });
        self
    }

    /// The ground-truth trajectory (green).
    pub fn ground_truth(mut self, poses: &[Pose2]) -> Self {
        self.ground_truth = poses.to_vec();
        self
    }

    /// The legend's name for the green path ("ground truth" unless set; e.g. "reference"
    /// for another program's trajectory).
    pub fn ground_truth_label(mut self, label: &str) -> Self {
        self.ground_truth_label = label.to_string();
        self
    }

    /// Landmark estimates, drawn as their 95 % error ellipses (blue), named `label` in the
    /// legend (e.g. "best particle's landmarks, 95 %").
    pub fn landmarks(mut self, l: &[LandmarkEstimate], label: &str) -> Self {
        self.landmarks = l.to_vec();
        self.landmarks_label = label.to_string();
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

    /// Every particle's path x₀:ₜ (FastSLAM's full-SLAM hypotheses, Montemerlo et al. 2002),
    /// thin grey lines under everything else.
    pub fn particle_paths(mut self, paths: &[Vec<Pose2>]) -> Self {
        self.particle_paths = paths.to_vec();
        self
    }

    /// Every particle's landmark means, all particles' together (small light-blue dots):
    /// the spread shows how far the particles disagree about the map.
    pub fn particle_landmarks(mut self, means: &[Point2]) -> Self {
        self.particle_landmarks = means.to_vec();
        self
    }

    /// Every finite point drawn, with the name of its layer (for the extent check).
    fn points(&self) -> Vec<(String, Point2)> {
        let mut out: Vec<(String, Point2)> = Vec::new();
        let mut add = |layer: &str, p: Point2| out.push((layer.to_string(), p));
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
                add(
                    "map",
                    Point2::new(m.origin.x + lo.0 as f64 * r, m.origin.y + lo.1 as f64 * r),
                );
                add(
                    "map",
                    Point2::new(
                        m.origin.x + (hi.0 + 1) as f64 * r,
                        m.origin.y + (hi.1 + 1) as f64 * r,
                    ),
                );
            }
        }
        for t in &self.trajectories {
            let layer = format!("trajectory `{}`", t.label);
            t.poses.iter().for_each(|p| add(&layer, p.translation()));
        }
        for p in &self.ground_truth {
            add("ground truth", p.translation());
        }
        for p in &self.true_landmarks {
            add("true landmarks", *p);
        }
        for p in &self.particles {
            add("particles", p.pose.translation());
        }
        for path in &self.particle_paths {
            path.iter()
                .for_each(|p| add("particle paths", p.translation()));
        }
        for p in &self.particle_landmarks {
            add("landmarks of every particle", *p);
        }
        for l in &self.landmarks {
            add("landmark estimates", l.mean);
        }
        out.retain(|(_, p)| p.x.is_finite() && p.y.is_finite());
        out
    }

    /// The world window shown, as (min x, min y, max x, max y), after checking every point
    /// against [`MAX_COORDINATE_M`].
    fn window(&self) -> Result<(f64, f64, f64, f64), VizError> {
        let points = self.points();
        let fitted = self
            .fit
            .iter()
            .flatten()
            .map(|p| ("window".to_string(), *p));
        for (layer, p) in points.iter().cloned().chain(fitted) {
            if p.x.abs() > MAX_COORDINATE_M || p.y.abs() > MAX_COORDINATE_M {
                return Err(VizError::Extent {
                    layer,
                    x: p.x,
                    y: p.y,
                    bound: MAX_COORDINATE_M,
                });
            }
        }
        let framed: Vec<Point2> = match &self.fit {
            Some(f) => f
                .iter()
                .copied()
                .filter(|p| p.x.is_finite() && p.y.is_finite())
                .collect(),
            None => points.into_iter().map(|(_, p)| p).collect(),
        };
        let Some(first) = framed.first() else {
            return Err(VizError::Draw(
                "nothing to draw (all layers empty or non-finite)".into(),
            ));
        };
        let (mut x0, mut y0, mut x1, mut y1) = (first.x, first.y, first.x, first.y);
        for p in &framed {
            (x0, y0, x1, y1) = (x0.min(p.x), y0.min(p.y), x1.max(p.x), y1.max(p.y));
        }
        // At least 1 m across, so a single point still gets a metre grid.
        let span = (x1 - x0).max(y1 - y0).max(1.0);
        let pad = 0.05 * span;
        let grow = |lo: f64, hi: f64| {
            let extra = 0.5 * (span - (hi - lo)).max(0.0) * if self.square { 1.0 } else { 0.0 };
            (lo - pad - extra, hi + pad + extra)
        };
        let ((x0, x1), (y0, y1)) = (grow(x0, x1), grow(y0, y1));
        Ok((x0, y0, x1, y1))
    }

    /// Where the plot lies in the picture [`render`](Self::render) makes, and its scale.
    pub fn layout(&self) -> Result<Layout, VizError> {
        let (x0, y0, x1, y1) = self.window()?;
        let scale = self.max_size as f64 / (x1 - x0).max(y1 - y0);
        let w = (((x1 - x0) * scale).round() as u32).clamp(1, self.max_size);
        let h = (((y1 - y0) * scale).round() as u32).clamp(1, self.max_size);
        Ok(Layout {
            left: MARGIN_LEFT,
            top: if self.title.is_some() {
                MARGIN_TOP_TITLE
            } else {
                MARGIN_TOP
            },
            width: w,
            height: h,
            min_x: x0,
            max_y: y1,
            px_per_m: scale,
        })
    }

    /// Renders the picture to an image.
    pub fn render(&self) -> Result<RgbImage, VizError> {
        let layout = self.layout()?;
        let view = View {
            min_x: layout.min_x,
            max_y: layout.max_y,
            scale: layout.px_per_m,
            w: layout.width,
            h: layout.height,
        };
        let (w, h) = (view.w, view.h);
        let xticks = tick_values(view.min_x, view.max_x(), w as f64 / 90.0);
        let yticks = tick_values(view.min_y(), view.max_y, h as f64 / 70.0);

        // The whole picture's size: title band, plot, frame, ticks and their labels; wide
        // enough for the title too (a tall, narrow map would cut it off).
        let title_w = self
            .title
            .as_ref()
            .map_or(0.0, |t| text_size(t, TITLE_PX).0.ceil()) as u32;
        let iw = layout.left + w.max(title_w) + MARGIN_RIGHT;
        let ih = layout.top + h + MARGIN_BOTTOM;

        // The plot, drawn on its own canvas so that every layer is clipped to it, in a
        // buffer with room for the whole picture, into which it is then spread in place:
        // one picture-sized buffer where a plot, a copy of it and the picture took three
        // (for Intel's map, 9 MB at the end of `slam run`).
        let mut buf = Vec::with_capacity(iw as usize * ih as usize * 3);
        for _ in 0..w as usize * h as usize {
            buf.extend_from_slice(&WHITE.0);
        }
        let mut plot = RgbImage::from_raw(w, h, buf)
            .ok_or_else(|| VizError::Draw(format!("no {w} × {h} px plot")))?;
        match &self.map {
            Some(m) => draw_map(&mut plot, &view, m),
            None => draw_grid(&mut plot, &view, &xticks, &yticks),
        }
        // The legend's candidate corners as they are before the layers (all the legend
        // needs of that state).
        let legend = self.legend_box(w, h).map(|b| b.with_background(&plot));
        for path in &self.particle_paths {
            polyline(&mut plot, &view, path, GREY.into(), 1.0);
        }
        if !self.ground_truth.is_empty() {
            polyline(&mut plot, &view, &self.ground_truth, GREEN.into(), 2.0);
        }
        for p in &self.particle_landmarks {
            let (u, v) = view.px(p);
            disc(&mut plot, u, v, 1.2, LIGHT_BLUE.into());
        }
        for l in &self.landmarks {
            ellipse(&mut plot, &view, l);
        }
        for p in &self.true_landmarks {
            let (u, v) = view.px(p);
            cross(&mut plot, u, v, 5.0, BLACK.into());
        }
        for t in &self.trajectories {
            polyline(&mut plot, &view, &t.poses, t.colour.into(), 2.0);
            if let Some(p) = t.poses.first() {
                let (u, v) = view.px(&p.translation());
                disc(&mut plot, u, v, 4.0, t.colour.into());
            }
            if let Some(p) = t.poses.last() {
                arrow(&mut plot, &view, p, t.colour.into());
            }
        }
        // The cloud on top: it gathers about the final pose, under the arrow otherwise.
        for p in &self.particles {
            let (u, v) = view.px(&p.pose.translation());
            disc(&mut plot, u, v, 1.5, TEAL.into());
        }
        if let Some(legend) = legend {
            legend.draw(&mut plot);
        }
        let mut img = place_on_white(plot, iw, ih, layout.left, layout.top);
        let (l, t) = (layout.left as f64, layout.top as f64);
        let (r, b) = (l + w as f64, t + h as f64);
        for (a, c) in [((l - 1.0, t - 1.0), (r, t - 1.0)), ((l - 1.0, b), (r, b))] {
            segment(&mut img, a, c, FRAME, 1.0);
        }
        for (a, c) in [((l - 1.0, t - 1.0), (l - 1.0, b)), ((r, t - 1.0), (r, b))] {
            segment(&mut img, a, c, FRAME, 1.0);
        }
        for (x, text) in &xticks {
            let u = l + (x - view.min_x) * view.scale;
            segment(&mut img, (u, b), (u, b + 5.0), FRAME, 1.0);
            let (tw, _) = text_size(text, LABEL_PX);
            draw_text(&mut img, u - tw / 2.0, b + 7.0, text, LABEL_PX, LABEL);
        }
        for (y, text) in &yticks {
            let v = t + (view.max_y - y) * view.scale;
            segment(&mut img, (l - 6.0, v), (l - 1.0, v), FRAME, 1.0);
            let (tw, th) = text_size(text, LABEL_PX);
            draw_text(&mut img, l - 9.0 - tw, v - th / 2.0, text, LABEL_PX, LABEL);
        }
        draw_text(&mut img, l, b + 25.0, "x (m)", LABEL_PX, LABEL);
        draw_scale_bar(&mut img, r, b + 36.0, w as f64, view.scale);
        let (yw, yh) = text_size("y (m)", LABEL_PX);
        draw_text(
            &mut img,
            l - 9.0 - yw,
            t - 6.0 - yh,
            "y (m)",
            LABEL_PX,
            LABEL,
        );
        if let Some(title) = &self.title {
            draw_text(&mut img, l, 10.0, title, TITLE_PX, image::Rgb([0, 0, 0]));
        }
        Ok(img)
    }

    /// Renders and writes a PNG.
    pub fn save_png(&self, path: &Path) -> Result<(), VizError> {
        let img = self.render()?;
        img.save_with_format(path, image::ImageFormat::Png)
            .map_err(|e| VizError::write(path, e))
    }

    /// The legend's entries: one per layer drawn.
    fn legend(&self) -> Vec<(Swatch, String)> {
        let mut out = Vec::new();
        if self.map.is_some() {
            out.push((Swatch::Square(image::Rgb([0, 0, 0])), "occupied".into()));
            out.push((Swatch::Square(WHITE), "free".into()));
            let u = UNKNOWN_GREY;
            out.push((Swatch::Square(image::Rgb([u, u, u])), "unknown".into()));
        }
        if !self.particle_paths.is_empty() {
            let n = self.particle_paths.len();
            out.push((
                Swatch::Line(GREY.into(), 1.0),
                format!("paths of the {n} particles"),
            ));
        }
        if !self.ground_truth.is_empty() {
            out.push((
                Swatch::Line(GREEN.into(), 2.0),
                self.ground_truth_label.clone(),
            ));
        }
        for t in &self.trajectories {
            out.push((Swatch::Line(t.colour.into(), 2.0), t.label.clone()));
        }
        if !self.particles.is_empty() {
            let n = self.particles.len();
            out.push((Swatch::Dot(TEAL.into(), 1.5), format!("{n} particles, now")));
        }
        if !self.particle_landmarks.is_empty() {
            out.push((
                Swatch::Dot(LIGHT_BLUE.into(), 1.2),
                "landmarks of every particle".into(),
            ));
        }
        if !self.landmarks.is_empty() {
            out.push((Swatch::Ellipse(BLUE.into()), self.landmarks_label.clone()));
        }
        if !self.true_landmarks.is_empty() {
            out.push((Swatch::Cross(BLACK.into()), "true landmarks".into()));
        }
        out
    }

    /// Where the legend could go in a `pw` × `ph` plot: its entries, size and the four
    /// corners (0 top-left, 1 top-right, 2 bottom-left, 3 bottom-right); `None` with no
    /// legend or a plot too small to hold it.
    fn legend_box(&self, pw: u32, ph: u32) -> Option<LegendBox> {
        let entries = self.legend();
        if entries.is_empty() {
            return None;
        }
        let text_w = entries
            .iter()
            .map(|(_, t)| text_size(t, LEGEND_PX).0)
            .fold(0.0, f64::max);
        let bw = (LEGEND_PAD + LEGEND_SWATCH_W + 6.0 + text_w + LEGEND_PAD).ceil();
        let bh = (2.0 * LEGEND_PAD + LEGEND_ROW * entries.len() as f64).ceil();
        let (pw, ph) = (pw as f64, ph as f64);
        if bw + 16.0 > pw || bh + 16.0 > ph {
            return None;
        }
        Some(LegendBox {
            entries,
            bw,
            bh,
            corners: [
                (8.0, 8.0),
                (pw - bw - 8.0, 8.0),
                (8.0, ph - bh - 8.0),
                (pw - bw - 8.0, ph - bh - 8.0),
            ],
            background: Vec::new(),
        })
    }
}

/// The legend box's inner margin, swatch width and row height, pixels.
const LEGEND_PAD: f64 = 7.0;
const LEGEND_SWATCH_W: f64 = 26.0;
const LEGEND_ROW: f64 = 19.0;

/// A picture's legend: its entries, its size in pixels, the plot's four corners it may go
/// to and, once taken ([`LegendBox::with_background`]), the plot under each corner before
/// the layers were drawn.
struct LegendBox {
    entries: Vec<(Swatch, String)>,
    bw: f64,
    bh: f64,
    corners: [(f64, f64); 4],
    /// The plot's pixels under each corner's box before the layers, row by row.
    background: Vec<Vec<Px>>,
}

impl LegendBox {
    /// The pixels of a corner's box, row by row from its top-left.
    fn pixels(&self, corner: usize) -> impl Iterator<Item = (u32, u32)> + '_ {
        let (x0, y0) = self.corners[corner];
        (y0 as u32..(y0 + self.bh) as u32)
            .flat_map(move |y| (x0 as u32..(x0 + self.bw) as u32).map(move |x| (x, y)))
    }

    /// Keeps `plot`'s pixels under the four corners (the background the legend compares
    /// the drawn plot with): four legend-sized patches rather than a copy of the plot.
    fn with_background(mut self, plot: &RgbImage) -> Self {
        self.background = (0..4)
            .map(|c| self.pixels(c).map(|(x, y)| *plot.get_pixel(x, y)).collect())
            .collect();
        self
    }

    /// Draws the legend in the corner of the plot that covers the fewest drawn pixels
    /// (pixels that differ from the background taken before the layers, and occupied map
    /// cells); returns the corner (0 top-left, 1 top-right, 2 bottom-left, 3 bottom-right).
    fn draw(&self, plot: &mut RgbImage) -> usize {
        let (pad, swatch_w, row) = (LEGEND_PAD, LEGEND_SWATCH_W, LEGEND_ROW);
        let (bw, bh) = (self.bw, self.bh);
        let covered = |c: usize| -> usize {
            self.pixels(c)
                .zip(&self.background[c])
                .filter(|&((x, y), b)| {
                    let p = plot.get_pixel(x, y);
                    p != b || p.0[0] < 100
                })
                .count()
        };
        // Prefer the top-right corner on ties (the usual place of a legend).
        let order = [1usize, 0, 3, 2];
        let corner = order.into_iter().min_by_key(|&c| covered(c)).unwrap_or(1);
        let entries = &self.entries;
        let (x0, y0) = self.corners[corner];
        for y in y0 as u32..(y0 + bh) as u32 {
            for x in x0 as u32..(x0 + bw) as u32 {
                let p = plot.get_pixel_mut(x, y);
                // 85 % white over whatever lies beneath.
                for k in 0..3 {
                    p.0[k] = (0.85 * 255.0 + 0.15 * p.0[k] as f64).round() as u8;
                }
            }
        }
        let border = image::Rgb([150, 150, 150]);
        let (x1, y1) = (x0 + bw - 1.0, y0 + bh - 1.0);
        segment(plot, (x0, y0), (x1, y0), border, 1.0);
        segment(plot, (x0, y1), (x1, y1), border, 1.0);
        segment(plot, (x0, y0), (x0, y1), border, 1.0);
        segment(plot, (x1, y0), (x1, y1), border, 1.0);
        for (i, (swatch, text)) in entries.iter().enumerate() {
            let cy = y0 + pad + row * (i as f64 + 0.5);
            let (sx0, sx1) = (x0 + pad, x0 + pad + swatch_w);
            let mid = 0.5 * (sx0 + sx1);
            match *swatch {
                Swatch::Line(c, width) => segment(plot, (sx0, cy), (sx1, cy), c, width),
                Swatch::Dot(c, r) => {
                    for dx in [-8.0, 0.0, 8.0] {
                        disc(plot, mid + dx, cy, r, c);
                    }
                }
                Swatch::Cross(c) => cross(plot, mid, cy, 5.0, c),
                Swatch::Ellipse(c) => {
                    disc(plot, mid, cy, 2.0, c);
                    let n = 36;
                    for k in 0..n {
                        let a = |k: usize| k as f64 / n as f64 * std::f64::consts::TAU;
                        let p = |t: f64| (mid + 11.0 * t.cos(), cy + 5.5 * t.sin());
                        segment(plot, p(a(k)), p(a(k + 1)), c, 1.0);
                    }
                }
                Swatch::Square(c) => {
                    for y in (cy - 6.0) as u32..(cy + 6.0) as u32 {
                        for x in (mid - 6.0) as u32..(mid + 6.0) as u32 {
                            plot.put_pixel(x, y, c);
                        }
                    }
                    let (a, b) = ((mid - 6.0, cy - 6.0), (mid + 5.0, cy + 5.0));
                    segment(plot, a, (b.0, a.1), border, 1.0);
                    segment(plot, (a.0, b.1), b, border, 1.0);
                    segment(plot, a, (a.0, b.1), border, 1.0);
                    segment(plot, (b.0, a.1), b, border, 1.0);
                }
            }
            let (_, th) = text_size(text, LEGEND_PX);
            draw_text(plot, sx1 + 6.0, cy - th / 2.0, text, LEGEND_PX, LABEL);
        }
        corner
    }
}

/// `plot` placed with its top-left corner at pixel (`left`, `top`) of a white `iw` × `ih`
/// picture (`iw` ≥ `left` + the plot's width, `ih` ≥ `top` + its height), in the plot's own
/// buffer: it grows to the picture's size (without moving when [`Picture::render`] made
/// it large enough) and every row moves to its place, the last one first so that no row
/// is overwritten before it has moved.
fn place_on_white(plot: RgbImage, iw: u32, ih: u32, left: u32, top: u32) -> RgbImage {
    let (w, h) = (plot.width() as usize, plot.height() as usize);
    let (iw, ih, left, top) = (iw as usize, ih as usize, left as usize, top as usize);
    debug_assert!(left + w <= iw && top + h <= ih);
    let mut buf = plot.into_raw();
    buf.resize(iw * ih * 3, 255);
    let (row, wide_row) = (w * 3, iw * 3);
    for y in (0..h).rev() {
        let to = (top + y) * wide_row + left * 3;
        buf.copy_within(y * row..(y + 1) * row, to);
    }
    // Every byte outside the plot's new place is white; those of the rows moved away from
    // are the old rows' (the place's own bytes were all written above).
    for y in 0..ih {
        let line = &mut buf[y * wide_row..(y + 1) * wide_row];
        if (top..top + h).contains(&y) {
            line[..left * 3].fill(255);
            line[(left + w) * 3..].fill(255);
        } else {
            line.fill(255);
        }
    }
    RgbImage::from_raw(iw as u32, ih as u32, buf).expect("the buffer holds iw × ih pixels")
}

/// The scale bar, under the plot's right end (so that it never hides data): a black bar of
/// a 1-2-5 length near an eighth of the plot's width, `len` px long at `px_per_m`, ending at
/// pixel column `right`, its label ("5 m") on its left, in the row of pixels `y`.
fn draw_scale_bar(img: &mut RgbImage, right: f64, y: f64, plot_w: f64, px_per_m: f64) {
    let metres = nice_step(plot_w / px_per_m, 8.0);
    let len = metres * px_per_m;
    if !(len.is_finite() && len >= 10.0 && len < plot_w) {
        return;
    }
    let black = image::Rgb([0, 0, 0]);
    let x0 = right - len;
    // The bar: rows y − 1 and y, exactly `len` pixels from x0; end marks 5 px high.
    for row in [y - 1.0, y] {
        for px in x0.round() as u32..right.round() as u32 {
            put(img, px as f64, row, black);
        }
    }
    for end in [x0, right - 1.0] {
        segment(img, (end, y - 5.0), (end, y), black, 1.0);
    }
    let label = format!("{} m", font::format_tick(metres, metres));
    let (tw, th) = text_size(&label, LABEL_PX);
    draw_text(img, x0 - 6.0 - tw, y - 0.6 * th, &label, LABEL_PX, LABEL);
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

/// A cross (×) of half-size `r` pixels, 2 px thick.
fn cross(img: &mut RgbImage, u: f64, v: f64, r: f64, c: Px) {
    let n = r as i64;
    for d in -n..=n {
        let d = d as f64;
        for o in [-0.5, 0.5] {
            put(img, u + d, v + d + o, c);
            put(img, u + d, v - d + o, c);
        }
    }
}

/// A segment `width` px wide (sampled at half-pixel steps); segments longer than 1e5 px
/// (far outside the image) are skipped, which bounds the work.
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

fn polyline(img: &mut RgbImage, view: &View, poses: &[Pose2], c: Px, width: f64) {
    for w in poses.windows(2) {
        segment(
            img,
            view.px(&w[0].translation()),
            view.px(&w[1].translation()),
            c,
            width,
        );
    }
}

/// A filled arrowhead on `pose`, pointing along its heading θ (counter-clockwise from +x;
/// y is up in the world and down in the image, hence the sign of the v component): the tip
/// 20 px ahead of the pose, the base 7 px behind it and 16 px wide.
fn arrow(img: &mut RgbImage, view: &View, pose: &Pose2, c: Px) {
    let (u, v) = view.px(&pose.translation());
    if !(u.is_finite() && v.is_finite() && pose.theta.is_finite()) {
        return;
    }
    let (s, co) = pose.theta.sin_cos();
    let (fx, fy) = (co, -s);
    let (lx, ly) = (-fy, fx);
    let tip = (u + 20.0 * fx, v + 20.0 * fy);
    let b1 = (u - 7.0 * fx + 8.0 * lx, v - 7.0 * fy + 8.0 * ly);
    let b2 = (u - 7.0 * fx - 8.0 * lx, v - 7.0 * fy - 8.0 * ly);
    let edge = |a: (f64, f64), b: (f64, f64), p: (f64, f64)| {
        (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0)
    };
    let (x0, x1) = (u - 21.0, u + 21.0);
    let (y0, y1) = (v - 21.0, v + 21.0);
    for py in y0.floor() as i64..=y1.ceil() as i64 {
        for px in x0.floor() as i64..=x1.ceil() as i64 {
            let p = (px as f64 + 0.5, py as f64 + 0.5);
            let (e1, e2, e3) = (edge(tip, b1, p), edge(b1, b2, p), edge(b2, tip, p));
            if (e1 >= 0.0 && e2 >= 0.0 && e3 >= 0.0) || (e1 <= 0.0 && e2 <= 0.0 && e3 <= 0.0) {
                put(img, p.0, p.1, c);
            }
        }
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
            UNKNOWN_GREY
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

/// The 1-2-5 step giving about `target` intervals over `span`; `None` when span or target
/// is not a positive finite number.
fn nice_step_checked(span: f64, target: f64) -> Option<f64> {
    let raw = span / target.max(1.0);
    if !(raw.is_finite() && raw > 0.0) {
        return None;
    }
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|k| k * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    (step.is_finite() && step > 0.0).then_some(step)
}

/// [`nice_step_checked`], with NaN for no step (whose uses then draw nothing).
fn nice_step(span: f64, target: f64) -> f64 {
    nice_step_checked(span, target).unwrap_or(f64::NAN)
}

/// Ticks on [lo, hi] at a 1-2-5 step giving about `target` intervals, as (value, label).
/// The k-th tick is (k₀ + k)·step with k counted as an integer, and there are at most
/// [`MAX_TICKS`]; none when the step does not resolve the range (the ticks would not be
/// distinct) or the range is not finite.
fn tick_values(lo: f64, hi: f64, target: f64) -> Vec<(f64, String)> {
    let Some(step) = nice_step_checked(hi - lo, target) else {
        return Vec::new();
    };
    let (k0, k1) = ((lo / step).ceil(), (hi / step + 1e-9).floor());
    // Beyond 2^52 consecutive multiples of the step are no longer distinct f64 values.
    if !(k0.is_finite() && k1.is_finite() && k0.abs() < 4.5e15 && k1.abs() < 4.5e15) {
        return Vec::new();
    }
    let (k0, k1) = (k0 as i64, k1 as i64);
    (k0..=k1)
        .take(MAX_TICKS)
        .map(|k| {
            let v = k as f64 * step;
            (v, font::format_tick(v, step))
        })
        .collect()
}

fn draw_grid(img: &mut RgbImage, view: &View, xticks: &[(f64, String)], yticks: &[(f64, String)]) {
    let (w, h) = (view.w as f64, view.h as f64);
    for (x, _) in xticks {
        let (u, _) = view.px(&Point2::new(*x, 0.0));
        segment(img, (u, 0.0), (u, h), GRID, 1.0);
    }
    for (y, _) in yticks {
        let (_, v) = view.px(&Point2::new(0.0, *y));
        segment(img, (0.0, v), (w, v), GRID, 1.0);
    }
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
/// average NEES, from `slam_eval::metrics::chi2_band`). Bounds fit the data and the band; light
/// grey lines mark a 1-2-5 grid in y, labelled with its values, and the x axis carries
/// 1-2-5 tick values. Non-finite points break the line. Errors
/// when a series' length differs from `x`'s or nothing is finite.
pub fn plot_series(
    path: &Path,
    x: &[f64],
    series: &[Series<'_>],
    band: Option<(f64, f64)>,
) -> Result<(), VizError> {
    plot_series_with(path, x, series, band, Axes::default())
}

/// Tick values of an axis spanning [lo, hi] in plotted units (log10 of the value on a log
/// axis), as (plotted position, label).
fn ticks(scale: Scale, lo: f64, hi: f64, target: f64) -> Vec<(f64, String)> {
    let mut out = Vec::new();
    match scale {
        Scale::Linear => out = tick_values(lo, hi, target),
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
                        out.push((p, font::format_tick(v, decade)));
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
) -> Result<(), VizError> {
    let (w, h, m) = (900u32, 450u32, 20.0);
    // Room on the left for the y labels, below for the x labels.
    let (ml, mb) = (56.0, 30.0);
    for s in series {
        if s.y.len() != x.len() {
            return Err(VizError::invalid(
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
        return Err(VizError::invalid(path, "nothing finite to plot"));
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
        let (tw, th) = text_size(&text, LABEL_PX);
        draw_text(
            &mut img,
            ml - 6.0 - tw,
            v - th / 2.0,
            &text,
            LABEL_PX,
            label,
        );
    }
    // x labels: a 1-2-5 grid of ticks under the axis.
    for (gx, text) in ticks(axes.x, x0, x1, 8.0) {
        let (u, _) = to_px(gx, y0);
        let (tw, _) = text_size(&text, LABEL_PX);
        draw_text(
            &mut img,
            u - tw / 2.0,
            h as f64 - mb + 6.0,
            &text,
            LABEL_PX,
            label,
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
        .map_err(|e| VizError::write(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::Matrix2;

    /// Pixels of exactly colour `c` in the plot area of `img`.
    fn plot_pixels(img: &RgbImage, l: &Layout, c: Rgb) -> Vec<(u32, u32)> {
        img.enumerate_pixels()
            .filter(|(x, y, p)| {
                p.0 == c.0
                    && (l.left..l.left + l.width).contains(x)
                    && (l.top..l.top + l.height).contains(y)
            })
            .map(|(x, y, _)| (x, y))
            .collect()
    }

    /// Whether a pixel of colour `c` lies within `r` px of (u, v).
    fn has_colour_near(img: &RgbImage, (u, v): (f64, f64), r: i64, c: Rgb) -> bool {
        (-r..=r).any(|dy| {
            (-r..=r).any(|dx| {
                let (x, y) = (u as i64 + dx, v as i64 + dy);
                x >= 0
                    && y >= 0
                    && (x as u32) < img.width()
                    && (y as u32) < img.height()
                    && img.get_pixel(x as u32, y as u32).0 == c.0
            })
        })
    }

    #[test]
    fn y_is_up_and_layers_have_their_colours() {
        // A trajectory going up (y grows), heading +x: its end must be near the top of the
        // plot with the arrow pointing right, its start disc near the bottom. With a landmark
        // at (10, 0) the window is x and y −0.5…10.5 m over 200 px.
        let traj: Vec<Pose2> = (0..=10).map(|i| Pose2::new(0.0, i as f64, 0.0)).collect();
        let pic = Picture::new()
            .size(200)
            .true_landmarks(&[(LandmarkId(0), Point2::new(10.0, 0.0))])
            .trajectory(&traj, RED, "up");
        let (img, l) = (pic.render().unwrap(), pic.layout().unwrap());
        let scale = 200.0 / 11.0;
        let u = l.left as f64 + 0.5 * scale;
        let (v_end, v_start) = (l.top as f64 + 0.5 * scale, l.top as f64 + 10.5 * scale);
        assert!(has_colour_near(&img, (u, v_end), 0, RED));
        assert!(has_colour_near(&img, (u + 12.0, v_end), 0, RED));
        assert!(!has_colour_near(&img, (u - 12.0, v_end), 1, RED));
        // The start disc is 4 px in radius; the line alone is 2 px wide.
        assert!(has_colour_near(&img, (u + 3.0, v_start), 0, RED));
        assert!(!has_colour_near(&img, (u + 3.0, v_start - 30.0), 0, RED));
        assert!(plot_pixels(&img, &l, GREEN).is_empty());
    }

    /// The world-to-pixel mapping checked against the picture's own frame and ticks: the
    /// points (0, 0) and (20, 10) in a 500 px plot give a window of x −1…21 m and y −1…11 m
    /// (5 % of the longer, 20 m span on each side), 500/22 px per metre, and ticks every 5 m
    /// on both axes (about one every 90 and 70 px).
    #[test]
    fn axes_frame_and_ticks_sit_at_their_world_positions() {
        let pts = [
            (LandmarkId(0), Point2::new(0.0, 0.0)),
            (LandmarkId(1), Point2::new(20.0, 10.0)),
        ];
        let pic = Picture::new().size(500).true_landmarks(&pts);
        let img = pic.render().unwrap();
        let scale = 500.0 / 22.0;
        let l = pic.layout().unwrap();
        assert!((l.px_per_m - scale).abs() < 1e-9);
        assert_eq!(l.width, 500);
        assert_eq!(l.height, (12.0f64 * scale).round() as u32);
        // The frame: dark columns just left and right of the plot, dark rows above and below.
        // (Half-way down is y = 5 m, a tick: look 7 px below it.)
        let mid_y = l.top + l.height / 2 + 7;
        let dark = |x: u32, y: u32| img.get_pixel(x, y).0 == FRAME.0;
        assert!(dark(l.left - 1, mid_y) && dark(l.left + l.width, mid_y));
        assert!(!dark(l.left + 3, mid_y) && !dark(l.left - 4, mid_y));
        let bottom = l.top + l.height;
        // x ticks under the frame at x = 0, 5, …, 20 m; none in between.
        for k in 0..=4 {
            let u = l.left as f64 + (5.0 * k as f64 + 1.0) * scale;
            assert!(dark(u as u32, bottom + 3), "no tick at x = {} m", 5 * k);
            if k < 4 {
                assert!(!dark((u + 0.5 * 5.0 * scale) as u32, bottom + 3));
            }
        }
        // y ticks left of the frame at y = 0, 5, 10 m; none in between.
        for k in 0..=2 {
            let v = l.top as f64 + (11.0 - 5.0 * k as f64) * scale;
            assert!(dark(l.left - 4, v as u32), "no tick at y = {} m", 5 * k);
            assert!(!dark(l.left - 4, (v - 2.5 * scale) as u32));
        }
        // The crosses at their world positions.
        for (_, p) in &pts {
            let (u, v) = l.pixel(p);
            assert_eq!(img.get_pixel(u as u32, v as u32).0, BLACK.0);
        }
        // Tick labels: dark text pixels under the x ticks.
        let label_ink = (bottom + 8..bottom + 24)
            .flat_map(|y| (l.left..l.left + l.width).map(move |x| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y).0[0] < 128)
            .count();
        assert!(label_ink > 50, "{label_ink}");
    }

    /// The scale bar: for the 22 m wide window of 500 px above, a 1-2-5 length near an
    /// eighth of the width is 5 m, 5·500/22 = 113.6 px long, ending under the plot's right
    /// edge.
    #[test]
    fn scale_bar_has_the_length_of_its_label() {
        let pts = [
            (LandmarkId(0), Point2::new(0.0, 0.0)),
            (LandmarkId(1), Point2::new(20.0, 10.0)),
        ];
        let pic = Picture::new().size(500).true_landmarks(&pts);
        let (img, l) = (pic.render().unwrap(), pic.layout().unwrap());
        let y = l.top + l.height + 36;
        let (mut best, mut run, mut end) = (0, 0, 0);
        for x in 0..img.width() {
            run = if img.get_pixel(x, y).0 == [0, 0, 0] {
                run + 1
            } else {
                0
            };
            if run > best {
                (best, end) = (run, x + 1);
            }
        }
        let expected = 5.0 * 500.0 / 22.0;
        assert!((best as f64 - expected).abs() <= 1.5, "bar {best} px");
        assert!(end.abs_diff(l.left + l.width) <= 1, "bar ends at {end}");
        // Its label ("5 m") on its left.
        let x0 = end - best;
        let ink = (y - 12..y + 10)
            .flat_map(|yy| (x0 - 40..x0 - 2).map(move |x| (x, yy)))
            .filter(|&(x, yy)| img.get_pixel(x, yy).0[0] < 128)
            .count();
        assert!(ink > 15, "{ink}");
    }

    #[test]
    fn the_title_band_holds_text_only_when_there_is_a_title() {
        let traj: Vec<Pose2> = (0..=10).map(|i| Pose2::new(i as f64, 0.0, 0.0)).collect();
        let ink = |pic: &Picture| {
            let (img, l) = (pic.render().unwrap(), pic.layout().unwrap());
            // Above the plot's frame, from its left edge to its right: the y axis name is
            // further left.
            (0..l.top - 1)
                .flat_map(|y| (l.left..l.left + l.width).map(move |x| (x, y)))
                .filter(|&(x, y)| img.get_pixel(x, y).0[0] < 128)
                .count()
        };
        let plain = Picture::new().size(300).trajectory(&traj, RED, "e");
        let titled = plain.clone().title("fastslam2 on loop, 100 particles");
        assert_eq!(ink(&plain), 0);
        assert!(ink(&titled) > 150, "{}", ink(&titled));
        // A tall, narrow plot (1 m wide, 10 m high: 100 px wide) widens the image for a
        // long title rather than cutting it.
        let up: Vec<Pose2> = (0..=10).map(|i| Pose2::new(0.0, i as f64, 0.0)).collect();
        let long = "gridfast on belgioioso, 30 particles, seed 0";
        let (tw, _) = text_size(long, TITLE_PX);
        let narrow = Picture::new()
            .size(300)
            .title(long)
            .trajectory(&up, RED, "e");
        let (img, l) = (narrow.render().unwrap(), narrow.layout().unwrap());
        assert!(l.width < 60, "{}", l.width);
        assert!(
            img.width() as f64 >= l.left as f64 + tw,
            "{} {tw}",
            img.width()
        );
    }

    /// The course's FastSLAM picture: the best path red with an arrow along its final
    /// heading, every particle's path grey, the truth green, every particle's landmarks as
    /// light-blue dots, true landmarks as crosses; the legend names each layer.
    #[test]
    fn fastslam_picture_draws_each_layer_at_its_geometry() {
        // Best path along +x to (10, 0), turning to face +y (θ = π/2) at the end.
        let mut best: Vec<Pose2> = (0..=10).map(|i| Pose2::new(i as f64, 0.0, 0.0)).collect();
        best.push(Pose2::new(10.0, 0.0, std::f64::consts::FRAC_PI_2));
        let truth: Vec<Pose2> = (0..=10).map(|i| Pose2::new(i as f64, -3.0, 0.0)).collect();
        let other: Vec<Pose2> = (0..=10).map(|i| Pose2::new(i as f64, 4.0, 0.0)).collect();
        let tl = [(LandmarkId(0), Point2::new(5.0, 8.0))];
        let dots = [Point2::new(2.0, 6.0), Point2::new(8.0, 6.0)];
        let pic = Picture::new()
            .size(600)
            .title("fastslam2 on test, 2 particles")
            .particle_paths(&[best.clone(), other.clone()])
            .ground_truth(&truth)
            .particle_landmarks(&dots)
            .true_landmarks(&tl)
            .trajectory(&best, RED, "best particle");
        let (img, l) = (pic.render().unwrap(), pic.layout().unwrap());
        // Red at the final pose, and along its heading (up in the image) up to the tip
        // 20 px ahead; not behind it (below), where no layer is drawn.
        let (u, v) = l.pixel(&Point2::new(10.0, 0.0));
        assert_eq!(img.get_pixel(u as u32, v as u32).0, RED.0);
        assert_eq!(img.get_pixel(u as u32, (v - 16.0) as u32).0, RED.0);
        assert_ne!(img.get_pixel(u as u32, (v + 12.0) as u32).0, RED.0);
        // Along +x the path is red before the end, but the arrow is narrow: 12 px to the
        // right of the final pose is not red.
        assert_ne!(img.get_pixel((u + 12.0) as u32, v as u32).0, RED.0);
        // Green along the truth, grey along the other particle's path.
        for i in 0..10 {
            let x = i as f64 + 0.5;
            assert!(has_colour_near(
                &img,
                l.pixel(&Point2::new(x, -3.0)),
                1,
                GREEN
            ));
            assert!(has_colour_near(
                &img,
                l.pixel(&Point2::new(x, 4.0)),
                1,
                GREY
            ));
        }
        for p in &dots {
            assert!(has_colour_near(&img, l.pixel(p), 0, LIGHT_BLUE));
        }
        assert_eq!(
            img.get_pixel(l.pixel(&tl[0].1).0 as u32, l.pixel(&tl[0].1).1 as u32)
                .0,
            BLACK.0
        );
        let names: Vec<String> = pic.legend().into_iter().map(|(_, t)| t).collect();
        assert_eq!(
            names,
            [
                "paths of the 2 particles",
                "ground truth",
                "best particle",
                "landmarks of every particle",
                "true landmarks"
            ]
        );
    }

    #[test]
    fn the_legend_avoids_the_data() {
        // Data fills the top-right quarter (and a point at the origin): the legend goes to
        // another corner, whose plot pixels then show its swatches.
        let mut cloud = vec![(LandmarkId(0), Point2::new(0.0, 0.0))];
        for i in 0..20 {
            for j in 0..20 {
                let p = Point2::new(5.0 + 0.25 * i as f64, 5.0 + 0.25 * j as f64);
                cloud.push((LandmarkId(1), p));
            }
        }
        let pic = Picture::new().size(400).true_landmarks(&cloud);
        let mut plot = RgbImage::from_pixel(400, 400, WHITE);
        let view = View {
            min_x: -0.5,
            max_y: 10.5,
            scale: 400.0 / 11.0,
            w: 400,
            h: 400,
        };
        let legend = pic.legend_box(400, 400).unwrap().with_background(&plot);
        for (_, p) in &cloud {
            let (u, v) = view.px(p);
            cross(&mut plot, u, v, 5.0, BLACK.into());
        }
        assert_ne!(legend.draw(&mut plot), 1);
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
            .landmarks(&[l], "estimates")
            .true_landmarks(&corners);
        let (img, lay) = (pic.render().unwrap(), pic.layout().unwrap());
        // 11 m span (10 + 5 % margins) over 500 px: 45.45 px/m. Only the blue within 3 m
        // of the mean (the legend's swatch lies in a corner).
        let scale = 500.0 / 11.0;
        let (cu, cv) = lay.pixel(&l.mean);
        let blue: Vec<(u32, u32)> = plot_pixels(&img, &lay, BLUE)
            .into_iter()
            .filter(|&(x, y)| (x as f64 - cu).hypot(y as f64 - cv) < 3.0 * scale)
            .collect();
        let (min_x, max_x) = (
            blue.iter().map(|b| b.0).min().unwrap(),
            blue.iter().map(|b| b.0).max().unwrap(),
        );
        let (min_y, max_y) = (
            blue.iter().map(|b| b.1).min().unwrap(),
            blue.iter().map(|b| b.1).max().unwrap(),
        );
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
        let pic = Picture::new().size(100).map(&m);
        let (img, l) = (pic.render().unwrap(), pic.layout().unwrap());
        // The picture spans the known cells (x 0–5 m, y 0–10 m) padded by 5 % of the longer
        // side: 11 m over the 100 px plot height.
        let view_x = |x: f64| l.left + ((x + 0.5) / 11.0 * l.height as f64) as u32;
        let wall_px = view_x(2.505);
        let dark_rows = (l.top + 10..l.top + l.height - 10)
            .filter(|&py| img.get_pixel(wall_px, py).0 == [0, 0, 0])
            .count();
        assert_eq!(dark_rows, (l.height - 20) as usize, "the wall has gaps");
        let mid = l.top + l.height / 2;
        assert_eq!(*img.get_pixel(view_x(1.0), mid), WHITE);
        assert_eq!(img.get_pixel(view_x(5.3), mid).0, [205, 205, 205]);
    }

    #[test]
    fn map_grey_levels_and_errors() {
        let mut m = GridMap::unknown(1.0, Point2::new(0.0, 0.0), 2, 1);
        m.cells = vec![0, 100];
        let pic = Picture::new().size(100).map(&m);
        let (img, l) = (pic.render().unwrap(), pic.layout().unwrap());
        // Left half free (white), right half occupied (black), y up irrelevant here.
        let mid = l.top + l.height / 2;
        assert_eq!(*img.get_pixel(l.left + 20, mid), WHITE);
        assert_eq!(img.get_pixel(l.left + l.width - 20, mid).0, [0, 0, 0]);
        assert!(Picture::new().render().is_err());
        let p = std::env::temp_dir().join(format!("slam-viz-plot-{}.png", std::process::id()));
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

    /// Issue 17: with every point about 1e16 m from the origin the old tick loop
    /// (`x += step` with a step below one ulp of x) never ended. The tick count is now
    /// bounded for any range, and such a picture is a clear error, returned in time.
    #[test]
    fn huge_coordinates_give_bounded_ticks_and_an_error_not_a_hang() {
        for (lo, hi) in [
            (1e16, 1e16 + 4.0),
            (-1e300, 1e300),
            (0.0, f64::MAX),
            (1e16, 1e16),
            (5.0, f64::NAN),
        ] {
            assert!(tick_values(lo, hi, 8.0).len() <= MAX_TICKS, "{lo} {hi}");
        }
        // 1e16 + 4 m over 8 intervals: multiples of 0.5 m are not distinct f64 values there.
        assert!(tick_values(1e16, 1e16 + 4.0, 8.0).is_empty());
        // Ordinary ranges still get every tick.
        let t: Vec<f64> = tick_values(-1.0, 21.0, 5.5)
            .into_iter()
            .map(|(v, _)| v)
            .collect();
        assert_eq!(t, [0.0, 5.0, 10.0, 15.0, 20.0]);

        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let far: Vec<Pose2> = (0..10)
                .map(|i| Pose2::new(1e16 + i as f64, 1e16, 0.0))
                .collect();
            let r = Picture::new().trajectory(&far, RED, "far").render();
            tx.send(r.map(|_| ())).ok();
        });
        let r = rx
            .recv_timeout(std::time::Duration::from_secs(60))
            .expect("drawing a 1e16 m trajectory did not finish within 60 s");
        let e = r.expect_err("1e16 m is beyond the drawable extent");
        assert!(matches!(e, VizError::Extent { .. }), "{e}");
        assert!(e.to_string().contains("trajectory `far`"), "{e}");
        // Just inside the bound, a 10 m trajectory is drawn with its ticks.
        let near: Vec<Pose2> = (0..10)
            .map(|i| Pose2::new(9e6 + i as f64, -9e6, 0.0))
            .collect();
        let pic = Picture::new().size(300).trajectory(&near, RED, "near");
        pic.render().unwrap();
        let l = pic.layout().unwrap();
        assert!(tick_values(l.min_x, l.min_x + 300.0 / l.px_per_m, 3.3).len() >= 2);
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
        let p = std::env::temp_dir().join(format!("slam-viz-loglog-{}.png", std::process::id()));
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
