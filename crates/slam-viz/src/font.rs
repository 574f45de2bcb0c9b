//! Text in the PNG pictures (titles, legends, axis labels), rasterised with `ab_glyph` from
//! DejaVu Sans compiled into the crate (`fonts/DejaVuSans-subset.ttf`, licence beside it), so
//! no system font library is needed. Glyphs are anti-aliased: each pixel is blended with
//! the text colour by the glyph's coverage of it.

use ab_glyph::{point, Font, FontRef, PxScale, ScaleFont};
use image::{Rgb, RgbImage};
use std::sync::OnceLock;

/// The font file, a subset of DejaVu Sans (see `fonts/README.md`).
const FONT_BYTES: &[u8] = include_bytes!("../fonts/DejaVuSans-subset.ttf");

/// The parsed font; `None` only if the compiled-in file were corrupt (a unit test checks
/// it is not), in which case pictures are drawn without text rather than failing.
fn font() -> Option<&'static FontRef<'static>> {
    static FONT: OnceLock<Option<FontRef<'static>>> = OnceLock::new();
    FONT.get_or_init(|| FontRef::try_from_slice(FONT_BYTES).ok())
        .as_ref()
}

/// Width and height in pixels of `text` set at `size` px, advances and kerning included.
/// As in `ab_glyph`, `size` is the height from the font's descent to its ascent (the em is
/// 1/1.164 of it for DejaVu Sans).
pub(crate) fn text_size(text: &str, size: f32) -> (f64, f64) {
    let Some(font) = font() else {
        return (0.0, 0.0);
    };
    let sf = font.as_scaled(PxScale::from(size));
    let mut width = 0.0f32;
    let mut last = None;
    for c in text.chars() {
        let id = sf.glyph_id(c);
        if let Some(prev) = last {
            width += sf.kern(prev, id);
        }
        width += sf.h_advance(id);
        last = Some(id);
    }
    (width as f64, (sf.ascent() - sf.descent()) as f64)
}

/// Draws `text` at `size` px with its box's top-left corner at (`x`, `y`) pixels; pixels
/// outside the image are skipped.
pub(crate) fn draw_text(
    img: &mut RgbImage,
    x: f64,
    y: f64,
    text: &str,
    size: f32,
    colour: Rgb<u8>,
) {
    let Some(font) = font() else {
        return;
    };
    let scale = PxScale::from(size);
    let sf = font.as_scaled(scale);
    let baseline = y as f32 + sf.ascent();
    let mut caret = x as f32;
    let mut last = None;
    let (w, h) = (img.width() as i64, img.height() as i64);
    for c in text.chars() {
        let id = sf.glyph_id(c);
        if let Some(prev) = last {
            caret += sf.kern(prev, id);
        }
        let glyph = id.with_scale_and_position(scale, point(caret, baseline));
        caret += sf.h_advance(id);
        last = Some(id);
        let Some(outline) = font.outline_glyph(glyph) else {
            continue;
        };
        let bounds = outline.px_bounds();
        outline.draw(|gx, gy, coverage| {
            let px = bounds.min.x as i64 + gx as i64;
            let py = bounds.min.y as i64 + gy as i64;
            if px < 0 || py < 0 || px >= w || py >= h {
                return;
            }
            let a = coverage.clamp(0.0, 1.0);
            let p = img.get_pixel_mut(px as u32, py as u32);
            for k in 0..3 {
                let blended = p.0[k] as f32 * (1.0 - a) + colour.0[k] as f32 * a;
                p.0[k] = blended.round() as u8;
            }
        });
    }
}

/// An axis label for the value `v` on a grid of spacing `step`: as many decimals as the
/// step needs (at most 9), and −0 shown as 0.
pub(crate) fn format_tick(v: f64, step: f64) -> String {
    let decimals = if step >= 1.0 || !step.is_finite() || step <= 0.0 {
        0
    } else {
        ((-step.log10()).ceil() as usize).min(9)
    };
    let v = if v.abs() < step.abs() * 1e-9 { 0.0 } else { v };
    format!("{v:.decimals$}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_compiled_in_font_parses_and_has_the_picture_characters() {
        let f = font().expect("DejaVu Sans subset parses");
        // Every character the pictures write has its own glyph (id 0 is .notdef).
        for c in "AZaz09.,:()−-–×±°²χσθΔ%/→".chars() {
            assert_ne!(f.glyph_id(c).0, 0, "no glyph for {c:?}");
        }
    }

    #[test]
    fn text_is_drawn_inside_its_measured_box() {
        let mut img = RgbImage::from_pixel(200, 40, Rgb([255, 255, 255]));
        let (w, h) = text_size("Wide 10 m", 16.0);
        // The height is the size; DejaVu Sans' em is 16/1.164 = 13.7 px there, and the
        // string is about 4.5 em wide.
        assert!((h - 16.0).abs() < 0.5, "{h}");
        let em = 16.0 / 1.164;
        assert!(w > 3.5 * em && w < 5.5 * em, "{w}");
        draw_text(&mut img, 10.0, 5.0, "Wide 10 m", 16.0, Rgb([0, 0, 0]));
        let inked: Vec<(u32, u32)> = img
            .enumerate_pixels()
            .filter(|(_, _, p)| p.0[0] < 128)
            .map(|(x, y, _)| (x, y))
            .collect();
        assert!(inked.len() > 100, "{} dark pixels", inked.len());
        for (x, y) in &inked {
            assert!(*x as f64 >= 10.0 - 1.0 && (*x as f64) <= 10.0 + w + 1.0);
            assert!(*y as f64 >= 5.0 - 1.0 && (*y as f64) <= 5.0 + h + 1.0);
        }
        // Anti-aliased: some pixels are neither white nor black.
        assert!(img.pixels().any(|p| p.0[0] > 30 && p.0[0] < 225));
        // Text off the image is clipped, not a panic.
        draw_text(&mut img, -50.0, -50.0, "clipped", 30.0, Rgb([0, 0, 0]));
        draw_text(&mut img, 1e9, 1e9, "far", 30.0, Rgb([0, 0, 0]));
    }

    #[test]
    fn ticks_are_formatted_to_their_step() {
        assert_eq!(format_tick(2.0, 1.0), "2");
        assert_eq!(format_tick(0.5, 0.5), "0.5");
        assert_eq!(format_tick(-1e-17, 0.2), "0.0");
        assert_eq!(format_tick(0.25, 0.05), "0.25");
        // A degenerate step gives a bounded label, not 300 decimals.
        assert!(format_tick(1.0, 1e-300).len() <= 12);
    }
}
