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
}

impl Image {
    /// A transparent black image.
    pub fn new(width: u32, height: u32) -> Image {
        Image {
            width,
            height,
            pixels: vec![Vec4::ZERO; width as usize * height as usize],
        }
    }

    /// The pixel at column `x`, row `y` (row 0 at the top).
    pub fn get(&self, x: u32, y: u32) -> Vec4 {
        self.pixels[(y * self.width + x) as usize]
    }
}
