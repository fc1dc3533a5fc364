//! `--preview`: the finished image in the terminal, as Unicode half blocks.
//!
//! Each character cell shows two pixels stacked: `▀` (U+2580) with the top pixel as the 24-bit
//! foreground colour and the bottom pixel as the background (`ESC[38;2;R;G;Bm`,
//! `ESC[48;2;R;G;Bm`). Transparent pixels (nothing hit) keep the terminal's own background, so
//! the model's silhouette stands on it. Every terminal that shows colour shows this, locally or
//! over SSH, inside tmux or screen; the kitty, iTerm and sixel graphics protocols would show
//! more detail but are not spoken here yet.

use crate::output::Image;
use glam::Vec3;
use std::io::{IsTerminal, Write};

/// Alpha at or above which a pixel is drawn (below it, the terminal's background shows).
const OPAQUE_ENOUGH: f32 = 0.5;

/// Terminal size assumed when it cannot be asked (output not a terminal, `--preview=blocks`).
const FALLBACK_COLUMNS: usize = 80;
/// See [`FALLBACK_COLUMNS`].
const FALLBACK_ROWS: usize = 24;

/// Lines left free under the picture for the shell prompt and the summary line.
const SPARE_ROWS: usize = 2;

/// Shows `image` on standard output: always when `force`, else only when standard output is
/// a terminal (a preview piped into a file or another program would be noise). Sized to the
/// terminal, never enlarged beyond one pixel a half cell.
pub fn show(image: &Image, background: Option<Vec3>, force: bool) -> std::io::Result<()> {
    let stdout = std::io::stdout();
    if !force && !stdout.is_terminal() {
        return Ok(());
    }
    let (rows, columns) = console::Term::stdout()
        .size_checked()
        .map_or((FALLBACK_ROWS, FALLBACK_COLUMNS), |(r, c)| {
            (r as usize, c as usize)
        });
    let text = half_blocks(
        image,
        background,
        columns,
        rows.saturating_sub(SPARE_ROWS).max(1),
    );
    let mut out = stdout.lock();
    out.write_all(text.as_bytes())?;
    out.flush()
}

/// The image as lines of half blocks fitting `columns` x `rows` cells, aspect kept (a cell is
/// about twice as tall as wide, so one cell of two stacked pixels is about square). Each line
/// ends with a colour reset and a newline.
pub fn half_blocks(image: &Image, background: Option<Vec3>, columns: usize, rows: usize) -> String {
    let (width, height) = (image.width as usize, image.height as usize);
    if width == 0 || height == 0 || columns == 0 || rows == 0 {
        return String::new();
    }
    let scale = (columns as f64 / width as f64)
        .min((2 * rows) as f64 / height as f64)
        .min(1.0);
    let out_width = ((width as f64 * scale).floor() as usize).max(1);
    let out_height = ((height as f64 * scale).floor() as usize).max(1);
    let srgb = image.to_srgb8(background);
    // Each output pixel averages the source pixels it covers (a box filter), colour weighted
    // by alpha so that transparent pixels do not darken edges.
    let pixel = |ox: usize, oy: usize| -> Option<[u8; 3]> {
        let (x0, x1) = (
            ox * width / out_width,
            ((ox + 1) * width / out_width).max(ox * width / out_width + 1),
        );
        let (y0, y1) = (
            oy * height / out_height,
            ((oy + 1) * height / out_height).max(oy * height / out_height + 1),
        );
        let (mut rgb, mut alpha, mut count) = ([0u64; 3], 0u64, 0u64);
        for y in y0..y1.min(height) {
            for x in x0..x1.min(width) {
                let p = &srgb[(y * width + x) * 4..][..4];
                for c in 0..3 {
                    rgb[c] += u64::from(p[c]) * u64::from(p[3]);
                }
                alpha += u64::from(p[3]);
                count += 1;
            }
        }
        let coverage = alpha as f32 / (255.0 * count.max(1) as f32);
        (coverage >= OPAQUE_ENOUGH && alpha > 0).then(|| rgb.map(|c| (c / alpha) as u8))
    };
    let mut text = String::new();
    for line in 0..out_height.div_ceil(2) {
        for x in 0..out_width {
            let top = pixel(x, 2 * line);
            let bottom = (2 * line + 1 < out_height)
                .then(|| pixel(x, 2 * line + 1))
                .flatten();
            match (top, bottom) {
                (Some(t), Some(b)) => text.push_str(&format!(
                    "\x1b[38;2;{};{};{}m\x1b[48;2;{};{};{}m▀",
                    t[0], t[1], t[2], b[0], b[1], b[2]
                )),
                (Some(t), None) => {
                    text.push_str(&format!("\x1b[49m\x1b[38;2;{};{};{}m▀", t[0], t[1], t[2]))
                }
                (None, Some(b)) => {
                    text.push_str(&format!("\x1b[49m\x1b[38;2;{};{};{}m▄", b[0], b[1], b[2]))
                }
                (None, None) => text.push_str("\x1b[0m "),
            }
        }
        text.push_str("\x1b[0m\n");
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec4;

    #[test]
    fn a_covered_pixel_is_a_coloured_cell_and_the_rest_the_terminal_background() {
        // 4 x 4: the top-left 2 x 2 pixels opaque red, the rest transparent.
        let mut image = Image::new(4, 4);
        for (x, y) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            image.pixels[y * 4 + x] = Vec4::new(1.0, 0.0, 0.0, 1.0);
        }
        let text = half_blocks(&image, None, 80, 24);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 2, "4 pixel rows are 2 lines");
        assert!(lines[0].starts_with("\x1b[38;2;255;0;0m\x1b[48;2;255;0;0m▀"));
        assert_eq!(lines[0].matches('▀').count(), 2);
        assert_eq!(lines[1].matches('▀').count(), 0);
        assert!(lines.iter().all(|l| l.ends_with("\x1b[0m")));
    }

    #[test]
    fn the_picture_fits_the_terminal_and_keeps_its_aspect() {
        let image = Image::new(1024, 768);
        let text = half_blocks(&image, Some(Vec3::ONE), 80, 38);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 30, "80 columns x 60 pixel rows");
        assert!(lines.iter().all(|l| l.matches('▀').count() == 80));
    }
}
