//! Colour arithmetic shared by every phase: luminance and the sRGB transfer curves. A leaf:
//! it imports nothing of the crate.

use glam::Vec3;

/// Luminance weights of linear Rec. 709.
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// Linear -> sRGB transfer function (IEC 61966-2-1), for values in [0, 1].
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// sRGB -> linear transfer function (IEC 61966-2-1), for values in [0, 1].
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}
