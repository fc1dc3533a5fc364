//! Writing AOVs (depth, normals, coverage mask, instance segmentation), by file extension.
//!
//! - Depth: `.exr` (float, depth in R, G and B), `.npy` (float32, H x W) or `.png` (16-bit grey,
//!   value = depth / scale, rounded and clamped to 65535, which the render warns of
//!   ([`depth_png_loss`]); the scale is `--depth-scale`, metres
//!   per unit, 0.001 by default: millimetres). 0 means nothing was hit, as in pyrender.
//! - Normals: `.exr` / `.npy` (float xyz, H x W x 3) or `.png` (8-bit, (n + 1)/2).
//! - Mask: `.png` (8-bit coverage, 255 = fully covered) or `.npy` (float32).
//! - Segmentation: `.png` (16-bit grey instance id, 0 = background) or `.npy` (uint32); the ids
//!   are listed with their glTF node and mesh in the `--view-out` JSON.
//!
//! Every file is written atomically like the image.

use crate::output::{write_atomic, SaveError};
use glam::Vec3;
use std::path::Path;

fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

fn unknown(path: &Path, allowed: &str) -> SaveError {
    SaveError::Unwritable {
        path: path.to_path_buf(),
        error: std::io::Error::other(format!("unknown extension for this output (use {allowed})")),
    }
}

/// Checks an AOV path's extension before rendering.
pub fn check(path: &Path, allowed: &[&str]) -> Result<(), SaveError> {
    if allowed.contains(&extension(path).as_str()) {
        Ok(())
    } else {
        Err(unknown(path, &allowed.join(", ")))
    }
}

fn f32_bytes(v: impl Iterator<Item = f32>) -> Vec<u8> {
    v.flat_map(f32::to_le_bytes).collect()
}

fn png<P: image::PixelWithColorType>(buffer: &image::ImageBuffer<P, Vec<P::Subpixel>>) -> Vec<u8>
where
    [P::Subpixel]: image::EncodableLayout,
{
    let mut bytes = Vec::new();
    // Encoding an in-memory buffer into a Vec cannot fail.
    let _ = buffer.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    );
    bytes
}

fn exr_rgba(width: u32, height: u32, rgba: Vec<f32>) -> Vec<u8> {
    // Encoding an in-memory buffer of the right size into a Vec cannot fail.
    crate::output::exr_rgba(width, height, &rgba).unwrap_or_default()
}

/// The largest value a 16-bit PNG holds: depths beyond this many `--depth-scale` units and
/// segmentation ids above it are written as it.
const PNG_MAX: f32 = 65535.0;

/// What a 16-bit PNG depth file at `path` loses, in words naming it: the pixels farther than
/// 65535 units of `scale`, written as 65535. `None` for other formats or when every depth fits.
pub fn depth_png_loss(path: &Path, depth: &[f32], scale: f32) -> Option<String> {
    if extension(path) != "png" {
        return None;
    }
    let beyond = depth
        .iter()
        .filter(|&&d| (d / scale).round() > PNG_MAX)
        .count();
    (beyond > 0).then(|| {
        format!(
            "{}: {} farther than a 16-bit PNG holds at --depth-scale {scale} ({} scene units), written as 65535; raise --depth-scale, or write .exr or .npy",
            path.display(),
            pixels_are(beyond),
            PNG_MAX * scale
        )
    })
}

/// What a 16-bit PNG segmentation file at `path` loses, in words naming it: the pixels of
/// instances whose id is above 65535, written as 65535. `None` for `.npy` or when every id
/// fits.
pub fn segmentation_png_loss(path: &Path, ids: &[u32]) -> Option<String> {
    if extension(path) != "png" {
        return None;
    }
    let beyond = ids.iter().filter(|&&id| id > u32::from(u16::MAX)).count();
    (beyond > 0).then(|| {
        format!(
            "{}: {} of mesh instances whose id is above 65535, the most a 16-bit PNG holds, written as 65535; write .npy for every id",
            path.display(),
            pixels_are(beyond)
        )
    })
}

/// "1 pixel is" or "N pixels are".
fn pixels_are(n: usize) -> String {
    match n {
        1 => "1 pixel is".to_string(),
        n => format!("{n} pixels are"),
    }
}

/// Writes camera-space depth.
pub fn write_depth(
    path: &Path,
    width: u32,
    height: u32,
    depth: &[f32],
    scale: f32,
) -> Result<(), SaveError> {
    let bytes = match extension(path).as_str() {
        "exr" => exr_rgba(
            width,
            height,
            depth.iter().flat_map(|&d| [d, d, d, 1.0]).collect(),
        ),
        "npy" => crate::output::npy::encode(
            "<f4",
            &[height as usize, width as usize],
            &f32_bytes(depth.iter().copied()),
        ),
        "png" => {
            let values: Vec<u16> = depth
                .iter()
                .map(|&d| (d / scale).round().clamp(0.0, 65535.0) as u16)
                .collect();
            match image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(width, height, values)
            {
                Some(img) => png(&img),
                None => Vec::new(),
            }
        }
        _ => return Err(unknown(path, "exr, npy, png")),
    };
    write_atomic(path, &bytes)
}

/// Writes world-space normals.
pub fn write_normals(
    path: &Path,
    width: u32,
    height: u32,
    normals: &[Vec3],
) -> Result<(), SaveError> {
    let bytes = match extension(path).as_str() {
        "exr" => exr_rgba(
            width,
            height,
            normals.iter().flat_map(|n| [n.x, n.y, n.z, 1.0]).collect(),
        ),
        "npy" => crate::output::npy::encode(
            "<f4",
            &[height as usize, width as usize, 3],
            &f32_bytes(normals.iter().flat_map(|n| n.to_array())),
        ),
        "png" => {
            let values: Vec<u8> = normals
                .iter()
                .flat_map(|n| {
                    if *n == Vec3::ZERO {
                        [0, 0, 0]
                    } else {
                        n.to_array()
                            .map(|c| ((c * 0.5 + 0.5) * 255.0).round().clamp(0.0, 255.0) as u8)
                    }
                })
                .collect();
            match image::RgbImage::from_raw(width, height, values) {
                Some(img) => png(&img),
                None => Vec::new(),
            }
        }
        _ => return Err(unknown(path, "exr, npy, png")),
    };
    write_atomic(path, &bytes)
}

/// Writes coverage (the image's alpha).
pub fn write_mask(path: &Path, width: u32, height: u32, coverage: &[f32]) -> Result<(), SaveError> {
    let bytes = match extension(path).as_str() {
        "npy" => crate::output::npy::encode(
            "<f4",
            &[height as usize, width as usize],
            &f32_bytes(coverage.iter().copied()),
        ),
        "png" => {
            let values: Vec<u8> = coverage
                .iter()
                .map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)
                .collect();
            match image::GrayImage::from_raw(width, height, values) {
                Some(img) => png(&img),
                None => Vec::new(),
            }
        }
        _ => return Err(unknown(path, "npy, png")),
    };
    write_atomic(path, &bytes)
}

/// Writes instance ids.
pub fn write_segmentation(
    path: &Path,
    width: u32,
    height: u32,
    ids: &[u32],
) -> Result<(), SaveError> {
    let bytes = match extension(path).as_str() {
        "npy" => crate::output::npy::encode(
            "<u4",
            &[height as usize, width as usize],
            &ids.iter()
                .flat_map(|i| i.to_le_bytes())
                .collect::<Vec<u8>>(),
        ),
        "png" => {
            let values: Vec<u16> = ids.iter().map(|&i| i.min(65535) as u16).collect();
            match image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(width, height, values)
            {
                Some(img) => png(&img),
                None => Vec::new(),
            }
        }
        _ => return Err(unknown(path, "npy, png")),
    };
    write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A PNG's loss is counted where rounding would pass 65535, and only for PNGs.
    #[test]
    fn png_losses_count_the_pixels_beyond_sixteen_bits() {
        let png = Path::new("d.png");
        // At millimetres, 65.5354 m rounds to 65535 and fits; 65.5356 m does not.
        let depth = [0.0, 1.0, 65.5354, 65.5356, 1e9];
        let loss = depth_png_loss(png, &depth, 0.001).unwrap();
        assert!(loss.starts_with("d.png: 2 pixels are farther"), "{loss}");
        // At metres only the 1e9 fits no more.
        let loss = depth_png_loss(png, &depth, 1.0).unwrap();
        assert!(loss.starts_with("d.png: 1 pixel is farther"), "{loss}");
        assert!(depth_png_loss(png, &depth[..3], 0.001).is_none());
        assert!(depth_png_loss(Path::new("d.exr"), &depth, 0.001).is_none());
        let ids = [0, 65535, 65536, 70000];
        let loss = segmentation_png_loss(Path::new("s.png"), &ids).unwrap();
        assert!(
            loss.starts_with("s.png: 2 pixels are of mesh instances"),
            "{loss}"
        );
        assert!(segmentation_png_loss(Path::new("s.png"), &ids[..2]).is_none());
        assert!(segmentation_png_loss(Path::new("s.npy"), &ids).is_none());
    }
}
