//! Drawing on 8-bit raster images: filled rectangles, thick lines and text labels from the
//! `font8x8` bitmap font. The labels of contact sheets and comparison strips, which are PNGs
//! themselves; vector plots go through `plotters` instead (see [`crate::tools::plot`]).

use image::{Rgb, RgbImage, RgbaImage};

/// Draws `text` with its top-left corner at (x, y), each font pixel `scale` pixels wide
/// (printable ASCII; other characters draw blank).
pub fn draw_text(img: &mut RgbImage, x: i32, y: i32, text: &str, scale: i32, color: Rgb<u8>) {
    for (i, ch) in text.chars().enumerate() {
        let glyph = font8x8::legacy::BASIC_LEGACY
            .get(ch as usize)
            .copied()
            .unwrap_or([0; 8]);
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8 {
                if bits & (1 << col) != 0 {
                    let gx = x + (i as i32 * 8 + col) * scale;
                    let gy = y + row as i32 * scale;
                    fill_rect(img, gx, gy, scale, scale, color);
                }
            }
        }
    }
}

/// Space left of and right of a label in its strip, pixels.
const LABEL_MARGIN: u32 = 6;

/// Draws `label` inside the strip of `size` (width, height) pixels whose top-left corner is
/// `origin`, vertically centred, `LABEL_MARGIN` from its left edge: at twice the font size
/// when it fits (and the strip is tall enough), else at the font size, cut to "..." and its
/// end when still too long (a file name differs at its end: "-old.png", "-new.png").
pub fn draw_label(
    img: &mut RgbImage,
    origin: (i32, i32),
    size: (u32, u32),
    label: &str,
    color: Rgb<u8>,
) {
    let (width, height) = size;
    let room = width.saturating_sub(2 * LABEL_MARGIN) as usize / 8;
    let scale = if label.chars().count() * 2 <= room && height >= 16 {
        2
    } else {
        1
    };
    draw_label_at(img, origin, size, label, color, scale);
}

/// [`draw_label`] at a given font `scale` (1: 8 pixels a character), cut to "..." and its end
/// when too long: for labels that must all be drawn at one size, as a contact sheet's are.
pub fn draw_label_at(
    img: &mut RgbImage,
    origin: (i32, i32),
    size: (u32, u32),
    label: &str,
    color: Rgb<u8>,
    scale: i32,
) {
    let (width, height) = size;
    let room = width.saturating_sub(2 * LABEL_MARGIN) as usize / (8 * scale.max(1) as usize);
    let text = fit_label(label, room);
    let y = origin.1 + (height as i32 - 8 * scale).max(0) / 2;
    draw_text(img, origin.0 + LABEL_MARGIN as i32, y, &text, scale, color);
}

/// `label` in at most `max_chars` characters: whole if it fits, else "..." and its end.
pub fn fit_label(label: &str, max_chars: usize) -> String {
    let chars: Vec<char> = label.chars().collect();
    if chars.len() <= max_chars {
        return label.to_string();
    }
    if max_chars <= 3 {
        return ".".repeat(max_chars);
    }
    let tail: String = chars[chars.len() - (max_chars - 3)..].iter().collect();
    format!("...{tail}")
}

/// Fills a rectangle, clipped to the image.
pub fn fill_rect(img: &mut RgbImage, x: i32, y: i32, w: i32, h: i32, color: Rgb<u8>) {
    for yy in y.max(0)..(y + h).min(img.height() as i32) {
        for xx in x.max(0)..(x + w).min(img.width() as i32) {
            img.put_pixel(xx as u32, yy as u32, color);
        }
    }
}

/// A line of the given thickness, by stepping along its longer axis.
pub fn line(
    img: &mut RgbImage,
    (x0, y0): (f32, f32),
    (x1, y1): (f32, f32),
    thick: i32,
    color: Rgb<u8>,
) {
    let steps = (x1 - x0).abs().max((y1 - y0).abs()).ceil().max(1.0) as i32;
    for s in 0..=steps {
        let t = s as f32 / steps as f32;
        let (x, y) = (x0 + (x1 - x0) * t, y0 + (y1 - y0) * t);
        fill_rect(
            img,
            x as i32 - thick / 2,
            y as i32 - thick / 2,
            thick,
            thick,
            color,
        );
    }
}

/// An image with straight alpha composited over an opaque `background`, in 8-bit sRGB as the
/// PNG holds it (the blend a viewer shows).
pub fn composite(img: &RgbaImage, background: [u8; 3]) -> RgbImage {
    let mut out = RgbImage::new(img.width(), img.height());
    for (o, p) in out.pixels_mut().zip(img.pixels()) {
        let a = u32::from(p.0[3]);
        let mix = |c: u8, b: u8| ((u32::from(c) * a + u32::from(b) * (255 - a) + 127) / 255) as u8;
        *o = Rgb([
            mix(p.0[0], background[0]),
            mix(p.0[1], background[1]),
            mix(p.0[2], background[2]),
        ]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_labels_keep_their_end() {
        assert_eq!(fit_label("short.png", 20), "short.png");
        assert_eq!(fit_label("LightsPunctualLamp-old.png", 12), "...p-old.png");
        assert_eq!(fit_label("abcdef", 2), "..");
    }

    /// A label is drawn inside its strip, centred vertically, at double size when it fits.
    #[test]
    fn labels_stay_inside_their_strip() {
        let white = Rgb([255, 255, 255]);
        let ink = Rgb([0, 0, 0]);
        for (label, strip_width, scale) in [("ab", 64u32, 2), ("a-long-label", 64, 1)] {
            let mut img = RgbImage::from_pixel(100, 40, white);
            draw_label(&mut img, (10, 5), (strip_width, 20), label, ink);
            let inked: Vec<(u32, u32)> = img
                .enumerate_pixels()
                .filter(|(_, _, p)| **p == ink)
                .map(|(x, y, _)| (x, y))
                .collect();
            assert!(!inked.is_empty(), "{label}: drawn");
            for &(x, y) in &inked {
                assert!(
                    (10 + LABEL_MARGIN..10 + strip_width - LABEL_MARGIN).contains(&x),
                    "{label}: x {x}"
                );
                assert!((5..25).contains(&y), "{label}: y {y}");
            }
            let (top, bottom) = (
                inked.iter().map(|p| p.1).min().unwrap(),
                inked.iter().map(|p| p.1).max().unwrap(),
            );
            // Glyphs use rows 0..7 of their 8 (scaled); centred means 2 px of strip above
            // the glyph box at scale 2 (20 - 16) / 2, 6 at scale 1.
            let box_top = 5 + (20 - 8 * scale) / 2;
            assert!(
                top >= box_top && bottom < box_top + 8 * scale,
                "{label}: rows {top}..{bottom}"
            );
        }
    }
}
