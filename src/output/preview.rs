//! `--preview`: the finished image in the terminal, through the `viuer` crate.
//!
//! In a terminal that speaks a graphics protocol the picture is shown at its own resolution:
//! sixel (DEC's, e.g. foot, mlterm, WezTerm, xterm `-ti vt340`), the iTerm2 inline-image
//! protocol (iTerm2, WezTerm, mintty, Konsole) or the kitty graphics protocol (kitty,
//! Ghostty). `viuer` finds out which by asking the terminal (a device-attributes query and a
//! kitty query, each answered before a status report that every terminal answers) and, for
//! iTerm, from `TERM_PROGRAM`/`LC_TERMINAL`. Everywhere else, and over any pipe, SSH session,
//! tmux or screen without such support, it falls back to Unicode half blocks: each character
//! cell shows two pixels stacked (`▀`/`▄`, 24-bit colour when `COLORTERM` says the terminal
//! has it, the nearest of the 256 colours otherwise).
//!
//! The half blocks are computed here, not by `viuer`'s resampling: each cell pixel is the
//! alpha-weighted box average of the pixels it covers, and it is drawn only when at least
//! half covered, so transparent pixels (nothing hit) keep the terminal's own background and the
//! model's silhouette stands on it with a sharp edge rather than `viuer`'s checkerboard.

use crate::color::ViewTransform;
use crate::output::Image;
use glam::Vec3;
use image::{DynamicImage, RgbaImage};
use std::io::IsTerminal;

/// When `render --preview` prints.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PreviewMode {
    /// Only when standard output is a terminal, in the best protocol it answers for.
    Auto,
    /// Always, as half blocks, with no terminal queries.
    Blocks,
}

/// Alpha at or above which a pixel is drawn (below it, the terminal's background shows).
const OPAQUE_ENOUGH: f32 = 0.5;

/// Terminal size assumed when it cannot be asked (output not a terminal, `--preview=blocks`).
const FALLBACK_COLUMNS: usize = 80;
/// See [`FALLBACK_COLUMNS`].
const FALLBACK_ROWS: usize = 24;

/// Lines left free under the picture for the shell prompt and the summary line.
const SPARE_ROWS: usize = 2;

/// How the picture reaches the terminal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Protocol {
    /// Unicode half blocks with colour escapes: every terminal.
    Blocks,
    /// DEC sixel graphics.
    Sixel,
    /// iTerm2's inline images (`OSC 1337 ; File=`).
    Iterm,
    /// The kitty graphics protocol (`APC G`).
    Kitty,
}

/// The graphics protocol the terminal on standard output speaks, in `viuer`'s order of
/// preference, or half blocks. Asks the terminal (once a process; `viuer` caches the answers),
/// so call it only when standard output is one.
fn detect() -> Protocol {
    if viuer::is_sixel_supported() {
        Protocol::Sixel
    } else if viuer::is_iterm_supported() {
        Protocol::Iterm
    } else if viuer::get_kitty_support() != viuer::KittySupport::None {
        Protocol::Kitty
    } else {
        Protocol::Blocks
    }
}

/// The terminal could not be written to (the message is `viuer`'s).
#[derive(Debug, thiserror::Error)]
#[error("cannot show the image in the terminal: {0}")]
pub struct PreviewError(String);

/// Shows `image` on standard output, through the view transform `view`. `Auto` shows it only when standard output is a terminal
/// (a preview piped into a file or another program would be noise), in the best protocol the
/// terminal speaks; `Blocks` always, as half blocks, without asking the terminal anything.
/// Sized to the terminal, never enlarged beyond one pixel a half cell. Returns the protocol
/// used, or `None` when nothing was shown. A reader that closed standard output early
/// (`meshtracer render ... --preview=blocks | head -3`) ends the preview quietly, also with
/// `None`: the picture was for that reader, and the files written are not spoiled by it.
pub fn show(
    image: &Image,
    background: Option<Vec3>,
    view: ViewTransform,
    mode: PreviewMode,
) -> Result<Option<Protocol>, PreviewError> {
    let rgba = RgbaImage::from_raw(image.width, image.height, image.to_srgb8(background, view))
        .unwrap_or_default();
    show_rgba(&rgba, mode)
}

/// [`show`] for an opaque 8-bit sRGB image (a contact sheet of views or jobs).
pub fn show_rgb(
    image: &image::RgbImage,
    mode: PreviewMode,
) -> Result<Option<Protocol>, PreviewError> {
    show_rgba(&DynamicImage::ImageRgb8(image.clone()).to_rgba8(), mode)
}

/// [`show`] for an 8-bit sRGB image with straight alpha.
pub fn show_rgba(image: &RgbaImage, mode: PreviewMode) -> Result<Option<Protocol>, PreviewError> {
    let terminal = std::io::stdout().is_terminal();
    if mode == PreviewMode::Auto && !terminal {
        return Ok(None);
    }
    let (rows, columns) = console::Term::stdout()
        .size_checked()
        .map_or((FALLBACK_ROWS, FALLBACK_COLUMNS), |(r, c)| {
            (r as usize, c as usize)
        });
    let rows = rows.saturating_sub(SPARE_ROWS).max(1);
    let Some((cell_width, pixel_height)) = fit(image.width(), image.height(), columns, rows) else {
        return Ok(None);
    };
    let protocol = match mode {
        PreviewMode::Auto => detect(),
        PreviewMode::Blocks => Protocol::Blocks,
    };
    let cell_rows = pixel_height.div_ceil(2);
    let config = viuer::Config {
        transparent: true,
        absolute_offset: false,
        width: Some(cell_width as u32),
        height: Some(cell_rows as u32),
        use_kitty: protocol == Protocol::Kitty,
        use_iterm: protocol == Protocol::Iterm,
        use_sixel: protocol == Protocol::Sixel,
        ..viuer::Config::default()
    };
    let picture = match protocol {
        Protocol::Blocks => cells(image, cell_width, pixel_height),
        _ => image.clone(),
    };
    match viuer::print(&DynamicImage::ImageRgba8(picture), &config) {
        Ok(_) => Ok(Some(protocol)),
        Err(viuer::ViuError::Io(e)) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(None),
        Err(e) => Err(PreviewError(e.to_string())),
    }
}

/// The size in half-block pixels (columns, pixel rows: two a line) that an image of
/// `width` x `height` takes in `columns` x `rows` cells, aspect kept (a cell is about twice as
/// tall as wide, so one cell of two stacked pixels is about square) and never enlarged.
/// `None` for an empty image or terminal.
pub fn fit(width: u32, height: u32, columns: usize, rows: usize) -> Option<(usize, usize)> {
    let (width, height) = (width as usize, height as usize);
    if width == 0 || height == 0 || columns == 0 || rows == 0 {
        return None;
    }
    let scale = (columns as f64 / width as f64)
        .min((2 * rows) as f64 / height as f64)
        .min(1.0);
    Some((
        ((width as f64 * scale).floor() as usize).max(1),
        ((height as f64 * scale).floor() as usize).max(1),
    ))
}

/// The image box-filtered down to `out_width` x `out_height` half-block pixels, each opaque
/// (its covered source pixels' alpha-weighted mean colour) or fully transparent.
pub fn cells(image: &RgbaImage, out_width: usize, out_height: usize) -> RgbaImage {
    let (width, height) = (image.width() as usize, image.height() as usize);
    let srgb = image.as_raw();
    let mut out = RgbaImage::new(out_width as u32, out_height as u32);
    for (ox, oy, cell) in out.enumerate_pixels_mut() {
        let (ox, oy) = (ox as usize, oy as usize);
        let x0 = ox * width / out_width;
        let x1 = ((ox + 1) * width / out_width).max(x0 + 1).min(width);
        let y0 = oy * height / out_height;
        let y1 = ((oy + 1) * height / out_height).max(y0 + 1).min(height);
        let (mut rgb, mut alpha, mut count) = ([0u64; 3], 0u64, 0u64);
        for y in y0..y1 {
            for x in x0..x1 {
                let p = &srgb[(y * width + x) * 4..][..4];
                for c in 0..3 {
                    rgb[c] += u64::from(p[c]) * u64::from(p[3]);
                }
                alpha += u64::from(p[3]);
                count += 1;
            }
        }
        let coverage = alpha as f32 / (255.0 * count.max(1) as f32);
        if coverage >= OPAQUE_ENOUGH && alpha > 0 {
            let [r, g, b] = rgb.map(|c| (c / alpha) as u8);
            *cell = image::Rgba([r, g, b, 255]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec4;

    fn rgba(image: &Image) -> RgbaImage {
        RgbaImage::from_raw(
            image.width,
            image.height,
            image.to_srgb8(None, ViewTransform::Standard),
        )
        .unwrap()
    }

    #[test]
    fn a_covered_pixel_is_an_opaque_cell_and_the_rest_transparent() {
        // 4 x 4: the top-left 2 x 2 pixels opaque red, the rest transparent.
        let mut image = Image::new(4, 4);
        for (x, y) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            image.pixels[y * 4 + x] = Vec4::new(1.0, 0.0, 0.0, 1.0);
        }
        assert_eq!(fit(4, 4, 80, 24), Some((4, 4)), "never enlarged");
        let image = rgba(&image);
        let cells = cells(&image, 4, 4);
        for (x, y, p) in cells.enumerate_pixels() {
            let expected = if x < 2 && y < 2 {
                [255, 0, 0, 255]
            } else {
                [0; 4]
            };
            assert_eq!(p.0, expected, "pixel ({x}, {y})");
        }
        // Halved: the top-left cell averages four red pixels, the rest four transparent ones.
        let half = super::cells(&image, 2, 2);
        assert_eq!(half.get_pixel(0, 0).0, [255, 0, 0, 255]);
        assert_eq!(half.get_pixel(1, 1).0, [0; 4]);
    }

    #[test]
    fn a_cell_at_least_half_covered_is_drawn_in_the_covered_pixels_colour() {
        // 2 x 1 into one cell pixel: one opaque green and one transparent pixel (half covered,
        // drawn pure green, not darkened by the empty one); then one of four (not drawn).
        let mut image = Image::new(2, 1);
        image.pixels[0] = Vec4::new(0.0, 1.0, 0.0, 1.0);
        assert_eq!(
            cells(&rgba(&image), 1, 1).get_pixel(0, 0).0,
            [0, 255, 0, 255]
        );
        let mut image = Image::new(2, 2);
        image.pixels[0] = Vec4::new(0.0, 1.0, 0.0, 1.0);
        assert_eq!(cells(&rgba(&image), 1, 1).get_pixel(0, 0).0, [0; 4]);
    }

    #[test]
    fn the_picture_fits_the_terminal_and_keeps_its_aspect() {
        // 80 columns x 38 rows: 1024 x 768 becomes 80 x 60 pixels (30 lines of half blocks).
        assert_eq!(fit(1024, 768, 80, 38), Some((80, 60)));
        // A tall image is bound by the rows: 2 x 38 = 76 pixel rows.
        assert_eq!(fit(100, 400, 80, 38), Some((19, 76)));
        assert_eq!(fit(0, 10, 80, 38), None);
        assert_eq!(fit(10, 10, 0, 38), None);
    }
}
