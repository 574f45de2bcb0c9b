//! A before/after picture of a pose graph: two panels side by side at one scale, each edge a
//! one-pixel line between its nodes' positions (odometry, i.e. edges between consecutive
//! pose ids, dark; other pose-pose edges, the loop closures, red; pose-point edges green).
//! Kept apart from [`crate::picture`] on purpose: it draws nothing but straight lines, in five
//! colours, so it is drawn as palette indices and written as an indexed PNG (one byte a pixel,
//! no filter, fast deflate): a third of the bytes of an RGB image and no filter search, which
//! matters when `slam optimize`'s whole run takes a tenth of a second.

use crate::error::VizError;
use slam_graph::{Edge, NodeValue, PoseGraph};
use std::path::Path;

/// Width and height of one panel, pixels.
const PANEL: u32 = 800;
/// Margin around the drawing, pixels.
const MARGIN: f64 = 10.0;

/// The palette (RGB), indexed by the colour constants below.
const PALETTE: [[u8; 3]; 5] = [
    [255, 255, 255],
    [40, 40, 40],
    [230, 90, 90],
    [60, 170, 60],
    [0, 0, 0],
];
/// Background.
const WHITE: u8 = 0;
/// Odometry edges (between consecutive pose ids).
const DARK: u8 = 1;
/// Other pose-pose edges (loop closures).
const RED: u8 = 2;
/// Pose-point edges.
const GREEN: u8 = 3;
/// The line between the panels.
const BLACK: u8 = 4;

/// An image of palette indices, row by row.
struct Indexed {
    width: u32,
    height: u32,
    pixels: Vec<u8>,
}

fn position(v: &NodeValue) -> (f64, f64) {
    match v {
        NodeValue::Pose(p) => (p.x, p.y),
        NodeValue::Point(p) => (p.x, p.y),
    }
}

/// Draws `before` (left) and `after` (right), which must have the same edges, into a PNG at
/// `path`. Errors when no node position is finite or the file cannot be written.
pub fn save_before_after(
    before: &PoseGraph,
    after: &PoseGraph,
    path: &Path,
) -> Result<(), VizError> {
    let (mut lo, mut hi) = (
        (f64::INFINITY, f64::INFINITY),
        (f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for n in before.nodes().iter().chain(after.nodes()) {
        let (x, y) = position(&n.value);
        if x.is_finite() && y.is_finite() {
            lo = (lo.0.min(x), lo.1.min(y));
            hi = (hi.0.max(x), hi.1.max(y));
        }
    }
    if lo.0 > hi.0 {
        return Err(VizError::Draw("no finite node position to draw".into()));
    }
    let span = (hi.0 - lo.0).max(hi.1 - lo.1).max(1e-9);
    let scale = (PANEL as f64 - 2.0 * MARGIN) / span;
    let mut img = Indexed {
        width: 2 * PANEL,
        height: PANEL,
        pixels: vec![WHITE; (2 * PANEL * PANEL) as usize],
    };
    for (panel, g) in [before, after].into_iter().enumerate() {
        let dx = panel as f64 * PANEL as f64 + MARGIN;
        let px = |v: &NodeValue| {
            let (x, y) = position(v);
            (
                dx + (x - lo.0) * scale,
                PANEL as f64 - MARGIN - (y - lo.1) * scale,
            )
        };
        let nodes = g.nodes();
        // Loop closures first, so the odometry chain stays visible on top.
        for pass in 0..2 {
            for e in g.edges() {
                let (a, b) = e.nodes();
                let colour = match e {
                    Edge::Between(_) if nodes[a].id.abs_diff(nodes[b].id) == 1 => DARK,
                    Edge::Between(_) => RED,
                    _ => GREEN,
                };
                if (colour == DARK) == (pass == 1) {
                    line(&mut img, px(&nodes[a].value), px(&nodes[b].value), colour);
                }
            }
        }
    }
    for y in 0..PANEL {
        img.pixels[(y * img.width + PANEL) as usize] = BLACK;
    }
    write_png(&img, path)
}

/// Writes `img` as an 8-bit indexed PNG with [`PALETTE`].
fn write_png(img: &Indexed, path: &Path) -> Result<(), VizError> {
    let fail = |message: String| VizError::Write {
        path: path.to_path_buf(),
        message,
    };
    let file = std::fs::File::create(path).map_err(|e| fail(e.to_string()))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), img.width, img.height);
    enc.set_color(png::ColorType::Indexed);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_palette(PALETTE.concat());
    enc.set_compression(png::Compression::Fast);
    enc.set_filter(png::Filter::NoFilter);
    let mut w = enc.write_header().map_err(|e| fail(e.to_string()))?;
    w.write_image_data(&img.pixels)
        .map_err(|e| fail(e.to_string()))?;
    w.finish().map_err(|e| fail(e.to_string()))
}

/// A straight line by uniform steps along its longer axis (DDA), clipped to the image.
fn line(img: &mut Indexed, a: (f64, f64), b: (f64, f64), c: u8) {
    if !(a.0.is_finite() && a.1.is_finite() && b.0.is_finite() && b.1.is_finite()) {
        return;
    }
    let steps = (b.0 - a.0)
        .abs()
        .max((b.1 - a.1).abs())
        .ceil()
        .clamp(1.0, 4.0 * PANEL as f64);
    let n = steps as usize;
    for k in 0..=n {
        let t = k as f64 / steps;
        let (x, y) = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
        if x >= 0.0 && y >= 0.0 && (x as u32) < img.width && (y as u32) < img.height {
            img.pixels[(y as u32 * img.width + x as u32) as usize] = c;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::{Matrix3, Pose2};

    #[test]
    fn draws_both_panels() {
        let mut g = PoseGraph::new();
        for i in 0..4 {
            g.add_pose(i, Pose2::new(i as f64, (i % 2) as f64, 0.0))
                .unwrap();
        }
        for i in 0..3 {
            g.add_between(i, i + 1, Pose2::new(1.0, 0.0, 0.0), Matrix3::identity())
                .unwrap();
        }
        g.add_between(0, 3, Pose2::new(3.0, 0.0, 0.0), Matrix3::identity())
            .unwrap();
        let dir = std::env::temp_dir().join(format!("slam-viz-gp-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("g.png");
        save_before_after(&g, &g, &p).unwrap();
        let img = image::open(&p).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (2 * PANEL, PANEL));
        let red = img.pixels().filter(|p| p.0 == [230, 90, 90]).count();
        let dark = img.pixels().filter(|p| p.0 == [40, 40, 40]).count();
        assert!(red > 100 && dark > 100, "{red} {dark}");
        std::fs::remove_dir_all(&dir).ok();
        assert!(save_before_after(&PoseGraph::new(), &PoseGraph::new(), &p).is_err());
    }
}
