//! A log-log line plot of time per ray against triangle count, as a PNG.
//!
//! One plot with two series does not justify a plotting stack (plotters needs system fonts or a
//! bundled TTF); lines and axes are drawn here, glyphs come from the `font8x8` bitmap font.

use crate::bench::Row;
use image::{Rgb, RgbImage};

const WIDTH: u32 = 880;
const HEIGHT: u32 = 600;
const LEFT: i32 = 100;
const RIGHT: i32 = 30;
const TOP: i32 = 60;
const BOTTOM: i32 = 80;
const BVH_COLOR: Rgb<u8> = Rgb([30, 90, 200]);
const LINEAR_COLOR: Rgb<u8> = Rgb([210, 60, 40]);
const GRID: Rgb<u8> = Rgb([225, 225, 225]);
const INK: Rgb<u8> = Rgb([20, 20, 20]);

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
/// `origin`, vertically centred, [`LABEL_MARGIN`] from its left edge: at twice the font size
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
    let (text, scale) = if label.chars().count() * 2 <= room && height >= 16 {
        (label.to_string(), 2)
    } else {
        (fit_label(label, room), 1)
    };
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

/// Renders the plot of nanoseconds per ray (per thread) against triangles for the BVH and the
/// linear scan, both axes logarithmic, and returns the PNG bytes.
pub fn scaling_plot(rows: &[Row], title: &str) -> Vec<u8> {
    let mut img = RgbImage::from_pixel(WIDTH, HEIGHT, Rgb([255, 255, 255]));
    let points = |f: &dyn Fn(&Row) -> Option<f64>| -> Vec<(f64, f64)> {
        rows.iter()
            .filter_map(|r| {
                f(r).map(|v| ((r.triangles.max(1) as f64).log10(), v.max(1e-3).log10()))
            })
            .collect()
    };
    let bvh = points(&|r| Some(r.bvh_ns_per_ray()));
    let linear = points(&|r| r.linear_ns_per_ray());
    let all: Vec<&(f64, f64)> = bvh.iter().chain(&linear).collect();
    let (x_lo, x_hi) = bounds(all.iter().map(|p| p.0));
    let (y_lo, y_hi) = bounds(all.iter().map(|p| p.1));
    let (pw, ph) = (
        (WIDTH as i32 - LEFT - RIGHT) as f64,
        (HEIGHT as i32 - TOP - BOTTOM) as f64,
    );
    let map = |(x, y): (f64, f64)| {
        (
            (LEFT as f64 + (x - x_lo) / (x_hi - x_lo) * pw) as f32,
            (TOP as f64 + (y_hi - y) / (y_hi - y_lo) * ph) as f32,
        )
    };
    for d in x_lo as i32..=x_hi as i32 {
        let (x, _) = map((d as f64, y_lo));
        line(
            &mut img,
            (x, TOP as f32),
            (x, (HEIGHT as i32 - BOTTOM) as f32),
            1,
            GRID,
        );
        draw_text(
            &mut img,
            x as i32 - 16,
            HEIGHT as i32 - BOTTOM + 10,
            &format!("1e{d}"),
            2,
            INK,
        );
    }
    for d in y_lo as i32..=y_hi as i32 {
        let (_, y) = map((x_lo, d as f64));
        line(
            &mut img,
            (LEFT as f32, y),
            ((WIDTH as i32 - RIGHT) as f32, y),
            1,
            GRID,
        );
        draw_text(&mut img, LEFT - 70, y as i32 - 8, &format!("1e{d}"), 2, INK);
    }
    let (x0, y0) = map((x_lo, y_lo));
    let (x1, y1) = map((x_hi, y_hi));
    line(&mut img, (x0, y0), (x1, y0), 2, INK);
    line(&mut img, (x0, y0), (x0, y1), 2, INK);
    for (series, color) in [(&linear, LINEAR_COLOR), (&bvh, BVH_COLOR)] {
        for pair in series.windows(2) {
            line(&mut img, map(pair[0]), map(pair[1]), 3, color);
        }
        for &p in series.iter() {
            let (x, y) = map(p);
            fill_rect(&mut img, x as i32 - 5, y as i32 - 5, 10, 10, color);
        }
    }
    draw_text(&mut img, LEFT, 6, title, 2, INK);
    draw_text(
        &mut img,
        LEFT + (pw as i32) / 2 - 120,
        HEIGHT as i32 - 36,
        "triangles (log)",
        2,
        INK,
    );
    draw_text(&mut img, 8, TOP - 26, "ns per ray per thread (log)", 2, INK);
    fill_rect(&mut img, WIDTH as i32 - 260, TOP + 10, 16, 16, LINEAR_COLOR);
    draw_text(
        &mut img,
        WIDTH as i32 - 236,
        TOP + 10,
        "linear O(n)",
        2,
        INK,
    );
    fill_rect(&mut img, WIDTH as i32 - 260, TOP + 36, 16, 16, BVH_COLOR);
    draw_text(
        &mut img,
        WIDTH as i32 - 236,
        TOP + 36,
        "BVH O(log n)",
        2,
        INK,
    );
    let mut bytes = Vec::new();
    // Encoding an in-memory RGB image into a Vec cannot fail.
    let _ = img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    );
    bytes
}

/// Whole decades around the values, at least one decade wide.
fn bounds(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let (lo, hi) = (lo.floor(), hi.ceil());
    (lo, if hi > lo { hi } else { lo + 1.0 })
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
