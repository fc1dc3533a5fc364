//! Denoising (`render --denoise`, cargo feature `denoise`): Intel Open Image Denoise's `RT`
//! filter on the linear HDR film, before exposure is encoded into a PNG's sRGB, guided by an
//! albedo and a normal image of the first surfaces the camera sees.
//!
//! The guides ([`guides`]) are computed here from the prepared scene, in every build (they need
//! no library): each pixel averages an n x n grid of camera rays (n = ⌊√spp⌋, at most
//! [`MAX_GUIDE_GRID`]), so they are anti-aliased like the beauty and free of Monte Carlo noise.
//! That is what OIDN's `cleanAux` asks for ("the auxiliary images are noise-free"), so the
//! filter trusts them fully instead of denoising them too. Following the OIDN documentation:
//! albedo is the surface's base colour (textures and vertex colours applied; for metals that is
//! their reflectance at normal incidence, as OIDN suggests) in [0, 1]; normals are world-space
//! shading normals (normal maps applied) facing the camera, averaged without renormalising.
//! BLEND surfaces are composited front to back by their alpha; rays that miss add the
//! environment's radiance (clamped to 1) where the environment is visible, else nothing.
//!
//! The filter itself ([`denoise`]) needs the `oidn` crate and the library (scripts/oidn/fetch.sh);
//! a build without the feature returns [`DenoiseError::NotBuilt`].
//!
//! Determinism: the guides are the same bytes for any thread count; OIDN's CPU device gives the
//! same output for the same input on the same machine (it picks kernels by instruction set, so
//! another CPU may differ in the last bits). `tests/it/denoise.rs` checks both.

use crate::camera::Lens;
use crate::defaults::MAX_BLEND_LAYERS;
use crate::geometry::Ray;
use crate::integrator::IntegratorKind;
use crate::prepare::Prepared;
use crate::render::Image;
use crate::render::{Region, RenderSettings};
use crate::scene::AlphaMode;
use crate::shading::surface::Occlusion;
use glam::Vec3;
use rayon::prelude::*;
use std::time::Duration;

/// Whether this build can denoise (it was built with `--features denoise`).
pub const AVAILABLE: bool = cfg!(feature = "denoise");

/// The error a build without the denoiser gives for `--denoise`.
pub const NOT_BUILT: &str =
    "--denoise: this build has no denoiser; rebuild with --features denoise, see docs/denoising.md";

/// Most guide rays per pixel and axis: 4 x 4 = 16 first hits make edges and textures smooth;
/// more change the guides by less than OIDN's own half-precision weights resolve.
pub const MAX_GUIDE_GRID: u32 = 4;

/// The denoiser's guide images: one value per pixel, row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Guides {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Albedo, each channel in [0, 1].
    pub albedo: Vec<Vec3>,
    /// World-space shading normals facing the camera, averaged over the pixel (length at most
    /// 1, zero where nothing was hit).
    pub normal: Vec<Vec3>,
    /// Guide rays per pixel (n x n).
    pub samples_per_pixel: u32,
}

/// Computes the guide images of the part `region` of the image `settings.view` describes,
/// matching what [`crate::render::render_region`] renders for the same arguments. Runs on the
/// current rayon pool.
pub fn guides(scene: &Prepared, settings: &RenderSettings, region: Region) -> Guides {
    let grid = ((settings.spp.max(1) as f32).sqrt().floor() as u32).clamp(1, MAX_GUIDE_GRID);
    let view = &settings.view;
    // The ray cone of a pixel, as the pixel loop computes it (texture level of detail).
    let spread = match view.lens {
        Lens::Perspective { height, .. } => (0.0, height / view.height as f32),
        Lens::Orthographic { height, .. } => (height / view.height as f32, 0.0),
    };
    let background = match (&settings.environment, settings.integrator) {
        (Some(env), IntegratorKind::Path) if settings.environment_visible => {
            Some((env, settings.exposure.exp2()))
        }
        _ => None,
    };
    let rows: Vec<(Vec<Vec3>, Vec<Vec3>)> = (region.y..region.bottom())
        .into_par_iter()
        .map(|y| {
            let mut albedo = Vec::with_capacity(region.width as usize);
            let mut normal = Vec::with_capacity(region.width as usize);
            for x in region.x..region.right() {
                let (mut a, mut n) = (Vec3::ZERO, Vec3::ZERO);
                for s in 0..grid * grid {
                    let dx = ((s % grid) as f32 + 0.5) / grid as f32;
                    let dy = ((s / grid) as f32 + 0.5) / grid as f32;
                    let ray = view.ray(x as f32 + dx, y as f32 + dy);
                    let (sa, sn) = first_surfaces(scene, &ray, spread, background);
                    a += sa;
                    n += sn;
                }
                let samples = (grid * grid) as f32;
                albedo.push((a / samples).clamp(Vec3::ZERO, Vec3::ONE));
                normal.push(n / samples);
            }
            (albedo, normal)
        })
        .collect();
    let (albedo, normal): (Vec<Vec<Vec3>>, Vec<Vec<Vec3>>) = rows.into_iter().unzip();
    Guides {
        width: region.width,
        height: region.height,
        albedo: albedo.concat(),
        normal: normal.concat(),
        samples_per_pixel: grid * grid,
    }
}

/// Albedo and normal along one camera ray: the first surface, or the first few BLEND layers
/// composited front to back by alpha, then the background behind what they let through.
fn first_surfaces(
    scene: &Prepared,
    camera: &Ray,
    spread: (f32, f32),
    background: Option<(&std::sync::Arc<crate::light::environment::Environment>, f32)>,
) -> (Vec3, Vec3) {
    let direction = Vec3::from(camera.direction);
    let (mut albedo, mut normal) = (Vec3::ZERO, Vec3::ZERO);
    let mut through = 1.0f32;
    let mut ray = *camera;
    let mut travelled = 0.0f32;
    for _ in 0..=MAX_BLEND_LAYERS {
        let Some(hit) = scene.intersect_camera(&ray) else {
            if let Some((env, scale)) = background {
                let radiance = env.radiance(direction) * scale;
                albedo += through * radiance.clamp(Vec3::ZERO, Vec3::ONE);
            }
            break;
        };
        travelled += hit.t;
        // The guides are albedo and normals: occlusion plays no part.
        let surface = scene.surface(&ray, &hit, spread.0 + spread.1 * travelled, Occlusion::Skip);
        let alpha = if surface.source.alpha_mode == AlphaMode::Blend {
            surface.alpha.clamp(0.0, 1.0)
        } else {
            1.0
        };
        albedo += through * alpha * surface.material.base_color.clamp(Vec3::ZERO, Vec3::ONE);
        normal += through * alpha * surface.normal;
        through *= 1.0 - alpha;
        if through <= 0.0 {
            break;
        }
        ray = surface.spawn.ray(direction, f32::INFINITY);
    }
    (albedo, normal)
}

/// What a denoiser run did.
#[derive(Clone, Debug, PartialEq)]
pub struct Denoised {
    /// The library's version as it reports it, e.g. "2.5.1".
    pub library_version: String,
    /// Wall time of the filter (device creation, filtering, copies).
    pub time: Duration,
}

/// Why denoising failed.
#[derive(Debug, thiserror::Error)]
pub enum DenoiseError {
    /// The build has no denoiser.
    #[error("{NOT_BUILT}")]
    NotBuilt,
    /// The guides do not match the image (a bug in the caller).
    #[error("denoise: guides of {guides_width}x{guides_height} for an image of {width}x{height}")]
    GuideSize {
        /// Image columns.
        width: u32,
        /// Image rows.
        height: u32,
        /// Guide columns.
        guides_width: u32,
        /// Guide rows.
        guides_height: u32,
    },
    /// Open Image Denoise refused or failed.
    #[error("Open Image Denoise: {step}: {message}")]
    Library {
        /// What was being done.
        step: &'static str,
        /// OIDN's message.
        message: String,
    },
}

/// Denoises `image` in place: OIDN's `RT` filter with `hdr` (the film is linear radiance, any
/// range) and `cleanAux` (the [`Guides`] are noise-free), on the CPU device. Alpha is kept;
/// pixels nothing covers stay black (premultiplied), and the filter's rare negative outputs are
/// clamped to 0. Non-finite film values (none are expected) enter the filter as 0, since OIDN
/// would spread one NaN over its whole receptive field.
///
/// On error `image` is unchanged.
pub fn denoise(image: &mut Image, guides: &Guides) -> Result<Denoised, DenoiseError> {
    if (guides.width, guides.height) != (image.width, image.height)
        || guides.albedo.len() != image.pixels.len()
        || guides.normal.len() != image.pixels.len()
    {
        return Err(DenoiseError::GuideSize {
            width: image.width,
            height: image.height,
            guides_width: guides.width,
            guides_height: guides.height,
        });
    }
    run_filter(image, guides)
}

#[cfg(not(feature = "denoise"))]
fn run_filter(_image: &mut Image, _guides: &Guides) -> Result<Denoised, DenoiseError> {
    Err(DenoiseError::NotBuilt)
}

#[cfg(feature = "denoise")]
fn run_filter(image: &mut Image, guides: &Guides) -> Result<Denoised, DenoiseError> {
    let start = std::time::Instant::now();
    let fail = |step: &'static str| {
        move |e: oidn::Error| DenoiseError::Library {
            step,
            message: e.to_string(),
        }
    };
    let flat = |v: &[Vec3]| -> Vec<f32> { v.iter().flat_map(|c| c.to_array()).collect() };
    let color: Vec<f32> = image
        .pixels
        .iter()
        .flat_map(|p| p.truncate().to_array())
        .map(|c| if c.is_finite() { c } else { 0.0 })
        .collect();
    let device = oidn::Device::cpu().map_err(fail("cannot create the CPU device"))?;
    let library_version = library_version(&device);
    let albedo = device
        .create_buffer(&flat(&guides.albedo))
        .map_err(fail("albedo buffer"))?;
    let normal = device
        .create_buffer(&flat(&guides.normal))
        .map_err(fail("normal buffer"))?;
    let mut filter = oidn::RayTracing::try_new(&device).map_err(fail("RT filter"))?;
    filter
        .image_dimensions(image.width as usize, image.height as usize)
        .hdr(true)
        .clean_aux(true)
        .albedo_normal_buffer(albedo, normal)
        .map_err(fail("guide images"))?;
    let mut output = vec![0.0f32; color.len()];
    filter
        .filter(&color, &mut output)
        .map_err(fail("filtering"))?;
    device.get_error().map_err(fail("filtering"))?;
    for (pixel, rgb) in image.pixels.iter_mut().zip(output.chunks_exact(3)) {
        if pixel.w > 0.0 {
            pixel.x = rgb[0].max(0.0);
            pixel.y = rgb[1].max(0.0);
            pixel.z = rgb[2].max(0.0);
        }
    }
    Ok(Denoised {
        library_version,
        time: start.elapsed(),
    })
}

/// The library's `version` parameter (major·10000 + minor·100 + patch) as "major.minor.patch":
/// what actually ran, which the view file records.
#[cfg(feature = "denoise")]
fn library_version(device: &oidn::Device) -> String {
    // SAFETY: the device handle is valid and committed for as long as `device` lives, and
    // "version" is a NUL-terminated parameter name every OIDN 2.x device reads.
    let version = unsafe { oidn::sys::oidnGetDeviceInt(device.raw(), c"version".as_ptr()) };
    format!(
        "{}.{}.{}",
        version / 10000,
        version / 100 % 100,
        version % 100
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    /// Black guides of `width` x `height`.
    fn blank(width: u32, height: u32) -> Guides {
        let pixels = (width * height) as usize;
        Guides {
            width,
            height,
            albedo: vec![Vec3::ZERO; pixels],
            normal: vec![Vec3::ZERO; pixels],
            samples_per_pixel: 1,
        }
    }

    #[test]
    fn mismatched_guides_are_refused() {
        let mut image = Image::new(4, 4);
        assert!(matches!(
            denoise(&mut image, &blank(2, 2)),
            Err(DenoiseError::GuideSize { .. })
        ));
    }

    #[cfg(not(feature = "denoise"))]
    #[test]
    fn a_build_without_the_feature_says_how_to_get_it() {
        let mut image = Image::new(2, 2);
        let error = denoise(&mut image, &blank(2, 2)).expect_err("no denoiser in this build");
        assert!(error.to_string().contains("--features denoise"));
    }
}
