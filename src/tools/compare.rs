//! Comparing two renders: the metrics users check meshtracer against pyrender and Blender with.
//!
//! Colour metrics are computed on 8-bit sRGB values after compositing both images over the
//! same background (black unless given), since that is what a person sees:
//! - PSNR (dB) from the mean squared error over R, G, B; infinite for identical images.
//! - SSIM: mean structural similarity over 8x8 windows per channel (`image-compare`'s MSSIM).
//! - FLIP: NVIDIA's perceptual error for rendered images, mean over pixels in [0, 1]
//!   (`nv-flip`, at its default 67 pixels per degree); its per-pixel map is the difference image.
//! - RMSE and the largest absolute difference, with channels in [0, 1].
//! - Coverage IoU: pixels covered in both over pixels covered in either, where covered means
//!   alpha above zero, or a colour different from `background` (black unless given) for
//!   images without alpha: a JPEG that `render` wrote over its background is compared with a
//!   PNG of the same render by its silhouette, not as if it covered the whole frame.

use crate::color::ViewTransform;
use crate::output::raster::{composite, draw_label, fill_rect};
use image::{Rgb, RgbImage, RgbaImage};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The comparison of two images.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Metrics {
    /// Peak signal-to-noise ratio in dB (infinite, written as null, for identical images).
    pub psnr: f64,
    /// Mean structural similarity, 1 for identical images.
    pub ssim: f64,
    /// Mean ꟻLIP error, 0 for identical images.
    pub flip: f64,
    /// Root-mean-square error, channels in [0, 1].
    pub rmse: f64,
    /// Largest absolute channel difference, in [0, 1].
    pub max_abs: f64,
    /// Intersection over union of the covered pixels (1 when neither covers anything).
    pub coverage_iou: f64,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
}

/// Why two images cannot be compared.
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    /// A file could not be read as an image.
    #[error("{}: {problem}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        problem: String,
    },
    /// The images differ in size.
    #[error("{}: {}x{} but {}: {}x{}: images of different sizes are not compared (re-render at the same size)", a.display(), a_size.0, a_size.1, b.display(), b_size.0, b_size.1)]
    SizeMismatch {
        /// First file.
        a: PathBuf,
        /// Its size.
        a_size: (u32, u32),
        /// Second file.
        b: PathBuf,
        /// Its size.
        b_size: (u32, u32),
    },
}

/// Reads an image file as 8-bit RGBA. EXR and HDR (linear radiance) are encoded as `render`
/// encodes a PNG: un-premultiplied, through the view transform `view`, sRGB.
pub fn read(path: &Path, view: ViewTransform) -> Result<RgbaImage, CompareError> {
    let err = |problem: String| CompareError::Read {
        path: path.to_path_buf(),
        problem,
    };
    let reader = image::ImageReader::open(path)
        .map_err(|e| err(e.to_string()))?
        .with_guessed_format()
        .map_err(|e| err(e.to_string()))?;
    let float = matches!(
        reader.format(),
        Some(image::ImageFormat::OpenExr | image::ImageFormat::Hdr)
    );
    // A panic in a decoder (another crate reading the file) is this file's error; OpenEXR is
    // decoded on this thread for that (scene::decode_exr).
    let decoded = crate::scene::catch_quietly(|| {
        if reader.format() == Some(image::ImageFormat::OpenExr) {
            let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
            crate::scene::decode_exr(std::io::BufReader::new(file), crate::scene::MAX_EXR_TEXELS)
        } else {
            reader
                .decode()
                .map_err(|e| crate::scene::image_error_text(&e))
        }
    });
    let img = decoded
        .map_err(|panic| err(format!("the decoder failed (an internal error): {panic}")))?
        .map_err(err)?;
    if float {
        let linear = img.to_rgba32f();
        let (w, h) = linear.dimensions();
        let mut out = RgbaImage::new(w, h);
        for (o, p) in out.pixels_mut().zip(linear.pixels()) {
            let a = p.0[3].clamp(0.0, 1.0);
            let rgb = glam::Vec3::new(p.0[0], p.0[1], p.0[2]);
            let straight = if a > 0.0 { rgb / a } else { glam::Vec3::ZERO };
            let encode =
                |c: f32| (crate::color::linear_to_srgb(c.clamp(0.0, 1.0)) * 255.0 + 0.5) as u8;
            let [r, g, b] = view.apply(straight).to_array().map(encode);
            *o = image::Rgba([r, g, b, (a * 255.0 + 0.5) as u8]);
        }
        return Ok(out);
    }
    Ok(img.to_rgba8())
}

/// Which pixels of `img` are covered: alpha above zero, or for an image without alpha (every
/// pixel opaque) a colour other than `background`.
fn covered(img: &RgbaImage, background: [u8; 3]) -> Vec<bool> {
    let has_alpha = img.pixels().any(|p| p.0[3] < 255);
    img.pixels()
        .map(|p| {
            if has_alpha {
                p.0[3] > 0
            } else {
                [p.0[0], p.0[1], p.0[2]] != background
            }
        })
        .collect()
}

/// Compares `a` (the reference) with `b`. `background` is the sRGB byte colour both are
/// composited over and that marks the uncovered pixels of opaque images: black when `None`,
/// exactly as `Some([0, 0, 0])`.
pub fn compare(a: &RgbaImage, b: &RgbaImage, background: Option<[u8; 3]>) -> (Metrics, RgbImage) {
    let bg = background.unwrap_or([0, 0, 0]);
    let (ca, cb) = (composite(a, bg), composite(b, bg));
    let (mut sum2, mut max_abs) = (0.0f64, 0.0f64);
    for (p, q) in ca.pixels().zip(cb.pixels()) {
        for c in 0..3 {
            let d = (f64::from(p.0[c]) - f64::from(q.0[c])) / 255.0;
            sum2 += d * d;
            max_abs = max_abs.max(d.abs());
        }
    }
    let mse = sum2 / (3.0 * f64::from(a.width()) * f64::from(a.height())).max(1.0);
    let psnr = if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (1.0 / mse).log10()
    };
    let ssim =
        image_compare::rgb_similarity_structure(&image_compare::Algorithm::MSSIMSimple, &ca, &cb)
            .map_or(f64::NAN, |s| s.score);
    let reference = nv_flip::FlipImageRgb8::with_data(a.width(), a.height(), ca.as_raw());
    let test = nv_flip::FlipImageRgb8::with_data(b.width(), b.height(), cb.as_raw());
    let error_map = nv_flip::flip(reference, test, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    let flip = f64::from(nv_flip::FlipPool::from_image(&error_map).mean());
    let heat = error_map.apply_color_lut(&nv_flip::magma_lut());
    let heatmap = RgbImage::from_raw(a.width(), a.height(), heat.to_vec())
        .unwrap_or_else(|| RgbImage::new(a.width(), a.height()));
    let (ma, mb) = (covered(a, bg), covered(b, bg));
    let both = ma.iter().zip(&mb).filter(|(x, y)| **x && **y).count();
    let either = ma.iter().zip(&mb).filter(|(x, y)| **x || **y).count();
    let coverage_iou = if either == 0 {
        1.0
    } else {
        both as f64 / either as f64
    };
    (
        Metrics {
            psnr,
            ssim,
            flip,
            rmse: mse.sqrt(),
            max_abs,
            coverage_iou,
            width: a.width(),
            height: a.height(),
        },
        heatmap,
    )
}

/// Compares two files: both must read and have the same size.
pub fn compare_files(
    a: &Path,
    b: &Path,
    background: Option<[u8; 3]>,
    view: ViewTransform,
) -> Result<(Metrics, RgbaImage, RgbaImage, RgbImage), CompareError> {
    let (ia, ib) = (read(a, view)?, read(b, view)?);
    if ia.dimensions() != ib.dimensions() {
        return Err(CompareError::SizeMismatch {
            a: a.to_path_buf(),
            a_size: ia.dimensions(),
            b: b.to_path_buf(),
            b_size: ib.dimensions(),
        });
    }
    let (metrics, heat) = compare(&ia, &ib, background);
    Ok((metrics, ia, ib, heat))
}

/// A | B | ꟻLIP heatmap, labelled, over `background`.
pub fn side_by_side(
    a: &RgbaImage,
    b: &RgbaImage,
    heat: &RgbImage,
    labels: [&str; 3],
    background: Option<[u8; 3]>,
) -> RgbImage {
    let bg = background.unwrap_or([0, 0, 0]);
    let (w, h) = a.dimensions();
    let band = 28u32;
    let mut out = RgbImage::from_pixel(3 * w, h + band, Rgb([255, 255, 255]));
    for (k, img) in [composite(a, bg), composite(b, bg), heat.clone()]
        .iter()
        .enumerate()
    {
        image::imageops::replace(&mut out, img, i64::from(k as u32 * w), i64::from(band));
    }
    for (k, label) in labels.iter().enumerate() {
        fill_rect(
            &mut out,
            k as i32 * w as i32,
            0,
            1,
            band as i32,
            Rgb([200, 200, 200]),
        );
        // Each label stays inside its panel (a long file name keeps its end, where "-old.png"
        // and "-new.png" differ).
        draw_label(
            &mut out,
            (k as i32 * w as i32, 0),
            (w, band),
            label,
            Rgb([20, 20, 20]),
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn disc(w: u32, h: u32, r: f32, color: [u8; 3]) -> RgbaImage {
        RgbaImage::from_fn(w, h, |x, y| {
            let (dx, dy) = (x as f32 - w as f32 / 2.0, y as f32 - h as f32 / 2.0);
            if dx * dx + dy * dy < r * r {
                image::Rgba([color[0], color[1], color[2], 255])
            } else {
                image::Rgba([0, 0, 0, 0])
            }
        })
    }

    #[test]
    fn long_labels_stay_inside_their_panels() {
        let a = disc(120, 40, 10.0, [200, 100, 50]);
        let heat = RgbImage::new(120, 40);
        let long = "a-very-long-file-name-of-a-reference-render.png";
        let out = side_by_side(&a, &a, &heat, [long, long, long], None);
        // The strip between panel 0's right edge and where panel 1's label starts stays
        // blank but for the separator line: panel 0's label did not run into panel 1.
        for y in 0..28 {
            for x in 121..126 {
                assert_eq!(out.get_pixel(x, y).0, [255, 255, 255], "({x},{y})");
            }
        }
    }

    /// An opaque image (a JPEG) is covered where it differs from the background, black when
    /// none is given, exactly as when black is given: the default `--help` states.
    #[test]
    fn the_default_background_is_black_for_coverage_too() {
        let png = disc(64, 48, 15.0, [200, 100, 50]);
        let mut jpeg = png.clone();
        for p in jpeg.pixels_mut() {
            p.0[3] = 255;
        }
        let (default, _) = compare(&png, &jpeg, None);
        let (black, _) = compare(&png, &jpeg, Some([0, 0, 0]));
        assert_eq!(default, black);
        assert_eq!(default.coverage_iou, 1.0);
        // Over another colour, the opaque image's black surround counts as covered.
        let (white, _) = compare(&png, &jpeg, Some([255, 255, 255]));
        assert!(white.coverage_iou < 0.5, "{}", white.coverage_iou);
    }

    #[test]
    fn identical_images_are_perfect() {
        let a = disc(64, 48, 15.0, [200, 100, 50]);
        let (m, _) = compare(&a, &a, None);
        assert!(m.psnr.is_infinite());
        assert!((m.ssim - 1.0).abs() < 1e-9);
        assert_eq!(
            (m.flip, m.rmse, m.max_abs, m.coverage_iou),
            (0.0, 0.0, 0.0, 1.0)
        );
    }

    #[test]
    fn known_differences_give_known_numbers() {
        // Two discs of radius 10 and 12 with the same colour: IoU = 10²/12².
        let a = disc(100, 100, 10.0, [255, 255, 255]);
        let b = disc(100, 100, 12.0, [255, 255, 255]);
        let (m, _) = compare(&a, &b, None);
        assert!(
            (m.coverage_iou - 100.0 / 144.0).abs() < 0.03,
            "{}",
            m.coverage_iou
        );
        assert_eq!(m.max_abs, 1.0);
        // A uniform offset of 10 codes everywhere: RMSE = 10/255, PSNR = 20·log10(255/10).
        let c = RgbaImage::from_pixel(32, 32, image::Rgba([100, 100, 100, 255]));
        let d = RgbaImage::from_pixel(32, 32, image::Rgba([110, 110, 110, 255]));
        let (m, _) = compare(&c, &d, None);
        assert!((m.rmse - 10.0 / 255.0).abs() < 1e-9);
        assert!((m.psnr - 20.0 * (25.5f64).log10()).abs() < 1e-9);
        assert!(m.flip > 0.0 && m.flip < 0.2);
    }
}
