//! Denoising (`render --denoise`) of the linear HDR film, before exposure is encoded into a
//! PNG's sRGB, guided by an albedo, a normal and a depth image of the first surfaces the
//! camera sees. Two filters, one per build ([`Denoiser::of_this_build`]):
//!
//! - [`atrous`], in every build: an edge-avoiding à-trous wavelet filter (Dammertz et al. 2010)
//!   on the radiance divided by the albedo, its edges stopped by normals, depth and luminance
//!   scaled by each pixel's sample variance (SVGF, Schied et al. 2017, without its temporal
//!   part). Pure Rust, no library.
//! - Intel Open Image Denoise's `RT` filter, in builds made with the cargo feature `denoise`
//!   (the `oidn` crate and the library, scripts/oidn/fetch.sh), which then replaces the
//!   built-in one: its neural network keeps detail the wavelet filter blurs.
//!
//! The guides ([`guides`]) are computed here from the prepared scene: each pixel averages an
//! n x n grid of camera rays (n = ⌊√spp⌋, at most [`MAX_GUIDE_GRID`]; with adaptive sampling
//! spp is the fewest samples a pixel takes, [`crate::render::RenderSettings::adaptive_batch`]), so they are
//! anti-aliased like the beauty and free of Monte Carlo noise. That is what OIDN's `cleanAux`
//! asks for ("the auxiliary images are noise-free"), so the filter trusts them fully instead of
//! denoising them too. Following the OIDN documentation: albedo is the surface's base colour
//! (textures and vertex colours applied; for metals that is their reflectance at normal
//! incidence, as OIDN suggests) in [0, 1]; normals are world-space shading normals (normal maps
//! applied) facing the camera, averaged without renormalising. BLEND surfaces are composited
//! front to back by their alpha; rays that miss add the environment's radiance (clamped to 1)
//! where the environment is visible, else nothing.
//!
//! Determinism: the guides and the built-in filter are the same bytes for any thread count
//! (every pixel is computed alone, its sums in a fixed order); OIDN's CPU device gives the same
//! output for the same input on the same machine (it picks kernels by instruction set, so
//! another CPU may differ in the last bits). `tests/it/denoise.rs` checks both.

pub mod atrous;
mod edges;
mod lanes;
#[cfg(feature = "denoise")]
mod open_image_denoise;

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
    /// Distance along the camera ray to the first surface, in scene units, averaged over the
    /// pixel's guide rays that hit one; 0 where none did.
    pub depth: Vec<f32>,
    /// How much of the punctual lights' light reaches the first surface unblocked, averaged
    /// over the pixel's samples ([`crate::integrator::GuideSample::visibility`]): where hard
    /// shadows fall. Empty when the guides do not have it (they were traced for the
    /// denoiser, not taken from the render's samples): every pixel then counts as 1.
    pub visibility: Vec<f32>,
    /// The part of each pixel the camera rays saw emitted at their first surfaces, averaged
    /// over the pixel's samples as the pixel is ([`crate::integrator::GuideSample::emission`]):
    /// the built-in filter smooths the rest only. Empty when the guides do not have it (traced
    /// for the denoiser): then nothing is set apart.
    pub emission: Vec<Vec3>,
    /// Guide rays per pixel (n x n).
    pub samples_per_pixel: u32,
}

impl Guides {
    /// Guides of `width` x `height` pixels to be filled: black, every pixel's visibility 1
    /// and both it and the emission kept when `from_samples` (the path tracer's own guides),
    /// else neither.
    pub fn new(width: u32, height: u32, from_samples: bool, samples_per_pixel: u32) -> Guides {
        let pixels = width as usize * height as usize;
        let if_sampled = |n: usize| if from_samples { n } else { 0 };
        Guides {
            width,
            height,
            albedo: vec![Vec3::ZERO; pixels],
            normal: vec![Vec3::ZERO; pixels],
            depth: vec![0.0; pixels],
            visibility: vec![1.0; if_sampled(pixels)],
            emission: vec![Vec3::ZERO; if_sampled(pixels)],
            samples_per_pixel,
        }
    }

    /// Copies `part`'s guides with its top-left pixel at column `x`, row `y`. `part` must fit
    /// inside these guides there, and have the visibility and emission these have.
    pub fn paste(&mut self, part: &Guides, x: u32, y: u32) {
        use crate::render::film::paste_rows;
        let (whole, width) = (self.width, part.width);
        paste_rows(&mut self.albedo, whole, &part.albedo, width, x, y);
        paste_rows(&mut self.normal, whole, &part.normal, width, x, y);
        paste_rows(&mut self.depth, whole, &part.depth, width, x, y);
        paste_rows(&mut self.visibility, whole, &part.visibility, width, x, y);
        paste_rows(&mut self.emission, whole, &part.emission, width, x, y);
    }
}

/// Computes the guide images of the part `region` of the image `settings.view` describes,
/// matching what [`crate::render::render_region`] renders for the same arguments. Runs on the
/// current rayon pool.
pub fn guides(scene: &Prepared, settings: &RenderSettings, region: Region) -> Guides {
    // Adaptive sampling takes from its first batch of samples a pixel up to `spp`: the guides
    // follow the fewest, not the cap, which cost many times the rays (at the default cap of
    // 32, 16 guide rays a pixel took longer than the 4-sample render they guided).
    let spp = match settings.noise {
        Some(_) => settings.spp.min(settings.first_batch()),
        None => settings.spp,
    };
    let grid = ((spp.max(1) as f32).sqrt().floor() as u32).clamp(1, MAX_GUIDE_GRID);
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
    let rows: Vec<Vec<(Vec3, Vec3, f32)>> = (region.y..region.bottom())
        .into_par_iter()
        .map(|y| {
            (region.x..region.right())
                .map(|x| {
                    let (mut a, mut n) = (Vec3::ZERO, Vec3::ZERO);
                    let (mut depth, mut hits) = (0.0f32, 0u32);
                    for s in 0..grid * grid {
                        let dx = ((s % grid) as f32 + 0.5) / grid as f32;
                        let dy = ((s / grid) as f32 + 0.5) / grid as f32;
                        // Through a thin lens the grid's samples spread over the lens too,
                        // as a Fibonacci-like lattice of the grid's count.
                        let count = (grid * grid) as f32;
                        let lens = ((s as f32 + 0.5) / count, (s as f32 * 0.618_034).fract());
                        let ray = view.lens_ray(x as f32 + dx, y as f32 + dy, lens);
                        let (sa, sn, st) = first_surfaces(scene, &ray, spread, background);
                        a += sa;
                        n += sn;
                        if let Some(t) = st {
                            depth += t;
                            hits += 1;
                        }
                    }
                    let samples = (grid * grid) as f32;
                    (
                        (a / samples).clamp(Vec3::ZERO, Vec3::ONE),
                        n / samples,
                        if hits > 0 { depth / hits as f32 } else { 0.0 },
                    )
                })
                .collect()
        })
        .collect();
    let pixels = rows.concat();
    Guides {
        width: region.width,
        height: region.height,
        albedo: pixels.iter().map(|p| p.0).collect(),
        normal: pixels.iter().map(|p| p.1).collect(),
        depth: pixels.iter().map(|p| p.2).collect(),
        visibility: Vec::new(),
        emission: Vec::new(),
        samples_per_pixel: grid * grid,
    }
}

/// Albedo, normal and first-hit distance along one camera ray: the first surface, or the first
/// few BLEND layers composited front to back by alpha, then the background behind what they
/// let through. The distance is the first layer's; `None` when the ray hits nothing.
fn first_surfaces(
    scene: &Prepared,
    camera: &Ray,
    spread: (f32, f32),
    background: Option<(&std::sync::Arc<crate::light::environment::Environment>, f32)>,
) -> (Vec3, Vec3, Option<f32>) {
    let direction = Vec3::from(camera.direction);
    let (mut albedo, mut normal) = (Vec3::ZERO, Vec3::ZERO);
    let mut first_hit = None;
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
        first_hit.get_or_insert(travelled);
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
    (albedo, normal, first_hit)
}

/// The filters `--denoise` can run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Denoiser {
    /// The built-in edge-avoiding à-trous filter ([`atrous`]), in every build.
    Atrous,
    /// Intel Open Image Denoise's `RT` filter, in builds with the cargo feature `denoise`.
    Oidn,
}

impl Denoiser {
    /// The filter this build runs for `--denoise`: OIDN with the feature `denoise`, else the
    /// built-in one.
    pub const fn of_this_build() -> Denoiser {
        if cfg!(feature = "denoise") {
            Denoiser::Oidn
        } else {
            Denoiser::Atrous
        }
    }

    /// Its short name, as `--stats` records it: "atrous" or "oidn".
    pub fn id(self) -> &'static str {
        match self {
            Denoiser::Atrous => "atrous",
            Denoiser::Oidn => "oidn",
        }
    }

    /// Who made it, as the view file records it.
    pub fn name(self) -> &'static str {
        match self {
            Denoiser::Atrous => "meshtracer",
            Denoiser::Oidn => "Intel Open Image Denoise",
        }
    }

    /// The filter's name, as the view file records it: "atrous" (edge-avoiding à-trous
    /// wavelets) or OIDN's "RT" (ray-traced images).
    pub fn filter(self) -> &'static str {
        match self {
            Denoiser::Atrous => "atrous",
            Denoiser::Oidn => "RT",
        }
    }

    /// The images that always guide it besides the film, in order (the built-in filter also
    /// takes the punctual lights' visibility when the guides have it: [`Denoised::guides`]).
    pub fn guides(self) -> &'static [&'static str] {
        match self {
            Denoiser::Atrous => &["albedo", "normal", "depth", "variance"],
            Denoiser::Oidn => &["albedo", "normal"],
        }
    }
}

/// What a denoiser run did.
#[derive(Clone, Debug, PartialEq)]
pub struct Denoised {
    /// The filter that ran.
    pub denoiser: Denoiser,
    /// Its version: the library's as it reports it for OIDN ("2.5.1"), meshtracer's for the
    /// built-in filter.
    pub version: String,
    /// Wall time of the filter (for OIDN: device creation, filtering, copies).
    pub time: Duration,
    /// Whether the punctual lights' visibility guided it ([`Guides::visibility`]: the
    /// built-in filter, given the path tracer's own guides).
    pub visibility_guide: bool,
    /// Whether what the camera saw emitted was kept out of the smoothing
    /// ([`Guides::emission`]: the built-in filter, given the path tracer's own guides).
    pub emission_apart: bool,
}

impl Denoised {
    /// The images that guided it besides the film, in order, as the view file records them.
    pub fn guides(&self) -> Vec<&'static str> {
        let mut guides = self.denoiser.guides().to_vec();
        if self.visibility_guide {
            guides.push("visibility");
        }
        if self.emission_apart {
            guides.push("emission");
        }
        guides
    }
}

/// Why denoising failed.
#[derive(Debug, thiserror::Error)]
pub enum DenoiseError {
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
    /// The image's per-pixel variance does not match its pixels (a bug in the caller: an
    /// [`Image`] built by hand rather than by the renderer or [`Image::new`]).
    #[error("denoise: {variances} variances for an image of {pixels} pixels")]
    VarianceSize {
        /// Pixels in the image.
        pixels: usize,
        /// Entries of [`Image::variance`].
        variances: usize,
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

/// Denoises `image` in place with this build's filter ([`Denoiser::of_this_build`]): with the
/// feature `denoise`, OIDN's `RT` filter with `hdr` (the film is linear radiance, any range)
/// and `cleanAux` (the [`Guides`] are noise-free) on the CPU device; else [`atrous::filter`].
/// Alpha is kept; pixels nothing covers stay black (premultiplied); outputs are never
/// negative.
///
/// The guides are taken: the built-in filter drops each once it has copied it (see
/// [`atrous::filter`]). On error `image` is unchanged.
pub fn denoise(image: &mut Image, guides: Guides) -> Result<Denoised, DenoiseError> {
    let pixels = image.pixels.len();
    if (guides.width, guides.height) != (image.width, image.height)
        || guides.albedo.len() != pixels
        || guides.normal.len() != pixels
        || guides.depth.len() != pixels
        || !(guides.visibility.is_empty() || guides.visibility.len() == pixels)
        || !(guides.emission.is_empty() || guides.emission.len() == pixels)
    {
        return Err(DenoiseError::GuideSize {
            width: image.width,
            height: image.height,
            guides_width: guides.width,
            guides_height: guides.height,
        });
    }
    if image.variance.len() != pixels {
        return Err(DenoiseError::VarianceSize {
            pixels,
            variances: image.variance.len(),
        });
    }
    #[cfg(feature = "denoise")]
    let denoised = open_image_denoise::filter(image, &guides)?;
    #[cfg(not(feature = "denoise"))]
    let denoised = {
        let start = std::time::Instant::now();
        let (visibility_guide, emission_apart) =
            (!guides.visibility.is_empty(), !guides.emission.is_empty());
        atrous::filter(image, guides);
        Denoised {
            denoiser: Denoiser::Atrous,
            version: env!("CARGO_PKG_VERSION").to_string(),
            time: start.elapsed(),
            visibility_guide,
            emission_apart,
        }
    };
    Ok(denoised)
}

#[cfg(test)]
mod tests {
    use super::*;
    /// Black guides of `width` x `height`.
    fn blank(width: u32, height: u32) -> Guides {
        Guides::new(width, height, false, 1)
    }

    #[test]
    fn mismatched_guides_are_refused() {
        let mut image = Image::new(4, 4);
        assert!(matches!(
            denoise(&mut image, blank(2, 2)),
            Err(DenoiseError::GuideSize { .. })
        ));
    }

    #[test]
    fn a_missing_variance_is_refused() {
        let mut image = Image::new(2, 2);
        image.variance.clear();
        assert!(matches!(
            denoise(&mut image, blank(2, 2)),
            Err(DenoiseError::VarianceSize {
                pixels: 4,
                variances: 0
            })
        ));
    }

    /// Every build denoises: this one says which filter ran, and an image nothing covers
    /// stays transparent black.
    #[test]
    fn every_build_denoises_and_says_with_what() {
        let mut image = Image::new(3, 2);
        let denoised = denoise(&mut image, blank(3, 2)).expect("denoises");
        assert_eq!(denoised.denoiser, Denoiser::of_this_build());
        assert_eq!(
            denoised.denoiser == Denoiser::Oidn,
            cfg!(feature = "denoise")
        );
        assert_eq!(image, Image::new(3, 2));
    }
}
