//! A tiny bitmap font for axis numbers in the PNG pictures (the `image` crate draws no
//! text): digits, sign, decimal point, space and the letter `m`, 3×5 pixels each, scaled up.

use image::{Rgb, RgbImage};

/// 3×5 glyphs, one row per byte, bit 2 = left column.
fn glyph(c: char) -> Option<[u8; 5]> {
    Some(match c {
        '0' => [0b111, 0b101, 0b101, 0b101, 0b111],
        '1' => [0b010, 0b110, 0b010, 0b010, 0b111],
        '2' => [0b111, 0b001, 0b111, 0b100, 0b111],
        '3' => [0b111, 0b001, 0b111, 0b001, 0b111],
        '4' => [0b101, 0b101, 0b111, 0b001, 0b001],
        '5' => [0b111, 0b100, 0b111, 0b001, 0b111],
        '6' => [0b111, 0b100, 0b111, 0b101, 0b111],
        '7' => [0b111, 0b001, 0b010, 0b010, 0b010],
        '8' => [0b111, 0b101, 0b111, 0b101, 0b111],
        '9' => [0b111, 0b101, 0b111, 0b001, 0b111],
        '-' => [0b000, 0b000, 0b111, 0b000, 0b000],
        '.' => [0b000, 0b000, 0b000, 0b000, 0b010],
        'm' => [0b000, 0b000, 0b111, 0b111, 0b101],
        ' ' => [0; 5],
        _ => return None,
    })
}

/// Width in pixels of `text` drawn at `scale`.
pub(crate) fn text_width(text: &str, scale: u32) -> u32 {
    (text.chars().count() as u32 * 4).saturating_sub(1) * scale
}

/// Draws `text` with its top-left corner at (x, y); characters without a glyph are skipped,
/// pixels outside the image are clipped.
pub(crate) fn draw_text(
    img: &mut RgbImage,
    x: i64,
    y: i64,
    text: &str,
    colour: Rgb<u8>,
    scale: u32,
) {
    let s = scale as i64;
    for (i, c) in text.chars().enumerate() {
        let Some(rows) = glyph(c) else { continue };
        let cx = x + i as i64 * 4 * s;
        for (r, bits) in rows.iter().enumerate() {
            for col in 0..3 {
                if bits & (0b100 >> col) == 0 {
                    continue;
                }
                for dy in 0..s {
                    for dx in 0..s {
                        let (px, py) = (cx + col * s + dx, y + r as i64 * s + dy);
                        if px >= 0
                            && py >= 0
                            && (px as u32) < img.width()
                            && (py as u32) < img.height()
                        {
                            img.put_pixel(px as u32, py as u32, colour);
                        }
                    }
                }
            }
        }
    }
}

/// A grid value printed with no more decimals than the step needs (1-2-5 steps).
pub(crate) fn format_tick(v: f64, step: f64) -> String {
    let decimals = if step >= 1.0 {
        0
    } else {
        (-step.log10()).ceil() as usize
    };
    let v = if v.abs() < step * 1e-9 { 0.0 } else { v };
    format!("{v:.decimals$}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_digits_and_formats_ticks() {
        let mut img = RgbImage::from_pixel(40, 12, Rgb([255, 255, 255]));
        draw_text(&mut img, 1, 1, "10", Rgb([0, 0, 0]), 2);
        // '1' has its top row's middle pixel set: (1 + 1·2, 1) at scale 2.
        assert_eq!(img.get_pixel(3, 1), &Rgb([0, 0, 0]));
        // '0' is hollow in its centre: column 1 of row 2 → (1 + 8 + 2, 1 + 4).
        assert_eq!(img.get_pixel(11, 5), &Rgb([255, 255, 255]));
        assert_eq!(text_width("10", 2), 14);
        assert_eq!(format_tick(2.0, 1.0), "2");
        assert_eq!(format_tick(0.5, 0.5), "0.5");
        assert_eq!(format_tick(-1e-17, 0.2), "0.0");
        assert_eq!(format_tick(0.25, 0.05), "0.25");
    }
}
