//! The film: the linear image a render fills, before any file format is chosen ([`crate::output`]
//! encodes it).

use glam::Vec4;

/// A linear RGBA image with premultiplied alpha, row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` pixels.
    pub pixels: Vec<Vec4>,
    /// Per pixel, the variance of its mean luminance (after exposure), estimated from the
    /// spread of its samples: the squared standard error. 0 where one sample was taken or
    /// nothing was covered. The built-in denoiser weighs neighbours by it
    /// ([`crate::render::denoise::atrous`]).
    pub variance: Vec<f32>,
    /// The denoiser's guides averaged over each pixel's own samples, when the render was asked
    /// for them ([`crate::render::RenderSettings::guides`]) and its integrator gives them.
    pub guides: Option<crate::render::denoise::Guides>,
    /// The fewest samples a pixel took (1 when not known): the number each `variance` was at
    /// least estimated from, which tells the built-in denoiser how far to trust it
    /// ([`crate::render::denoise::atrous::luminance_sigma`]).
    pub samples: u32,
}

impl Image {
    /// A transparent black image, its variance 0.
    pub fn new(width: u32, height: u32) -> Image {
        let count = width as usize * height as usize;
        Image {
            width,
            height,
            pixels: vec![Vec4::ZERO; count],
            variance: vec![0.0; count],
            guides: None,
            samples: 1,
        }
    }

    /// The pixel at column `x`, row `y` (row 0 at the top).
    pub fn get(&self, x: u32, y: u32) -> Vec4 {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Copies `part`'s pixels and variances (not its guides nor its sample count) with its
    /// top-left corner at column `x`, row `y`. `part` must fit inside this image there.
    pub fn paste(&mut self, part: &Image, x: u32, y: u32) {
        paste_rows(&mut self.pixels, self.width, &part.pixels, part.width, x, y);
        paste_rows(
            &mut self.variance,
            self.width,
            &part.variance,
            part.width,
            x,
            y,
        );
    }
}

/// Copies the rows of `part` (`part_width` values a row) into `whole` (`whole_width` values a
/// row) with `part`'s top-left value at column `x`, row `y`: how a region's buffers join the
/// whole image's, in the pixel loop's film and in a merge of tiles. Panics (a bug in the
/// caller) when `part` does not fit.
pub fn paste_rows<T: Copy>(
    whole: &mut [T],
    whole_width: u32,
    part: &[T],
    part_width: u32,
    x: u32,
    y: u32,
) {
    let (whole_width, part_width) = (whole_width as usize, part_width as usize);
    if part_width == 0 {
        return;
    }
    for (row, chunk) in part.chunks(part_width).enumerate() {
        let begin = (y as usize + row) * whole_width + x as usize;
        whole[begin..begin + chunk.len()].copy_from_slice(chunk);
    }
}
