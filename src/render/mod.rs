//! The render phase: the pixel loop. Camera rays per pixel (Owen-scrambled Sobol samples),
//! traced eight neighbouring pixels at a time in one packet query, each handed to an
//! [`Integrator`] with its first hit; the samples averaged into the film; AOVs from
//! pixel-centre rays.
//! Surface evaluation lives in [`crate::shading::surface`], light transport in [`crate::integrator`].
//!
//! Work is split into square tiles rendered in parallel with rayon. Every pixel's samples come
//! from a sampler keyed by (seed, x, y) ([`crate::sampling::Sampler`]), so the image is the same, byte for byte, whatever the
//! number of threads or the order tiles finish in.

pub mod denoise;
pub mod film;

pub use film::Image;

use crate::accel::{Hit, PACKET};
use crate::camera::{Lens, View};
use crate::color::luminance;
use crate::geometry::Ray;
use crate::integrator::{
    CameraRay, Direct, GuideSample, Integrator, IntegratorKind, Lane, PathTracer, RayCounts,
};
use crate::light::environment::Environment;
use crate::light::PunctualLight;
use crate::prepare::Prepared;
use crate::sampling::Sampler;
use crate::scene::Light;
use crate::shading::ShadingModel;
use glam::{Vec3, Vec4};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Tile edge in pixels: small enough to balance load over cores, large enough that per-tile
/// overhead vanishes.
pub const TILE_SIZE: u32 = 32;

/// Everything the renderer needs besides the scene and the acceleration structure.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    /// The camera, sized for the image.
    pub view: View,
    /// Samples per pixel: 1 is the pixel centre; more are Owen-scrambled Sobol samples.
    pub spp: u32,
    /// Seed of the sample pattern.
    pub seed: u64,
    /// Lights in use (the file's, or the default rig).
    pub lights: Vec<Light>,
    /// Ambient radiance multiplier for base colour (unshadowed).
    pub ambient: Vec3,
    /// Exposure in stops: radiance is scaled by 2^exposure before output.
    pub exposure: f32,
    /// Shading model.
    pub shading: ShadingModel,
    /// Also compute the per-pixel AOVs (depth, normal, instance id) from pixel-centre rays.
    pub aovs: bool,
    /// Which integrator renders.
    pub integrator: IntegratorKind,
    /// Path tracer: most bounces after the first hit.
    pub bounces: u32,
    /// Path tracer: the environment that lights the scene, if any.
    pub environment: Option<Arc<Environment>>,
    /// Path tracer: camera rays that miss show the environment (else they are transparent).
    pub environment_visible: bool,
    /// Adaptive sampling (`--noise`): each pixel stops taking samples once the standard error
    /// of its mean luminance is at most this fraction of max(mean, [`NOISE_FLOOR`]); `spp` is
    /// then the cap. `None`: every pixel takes `spp` samples.
    pub noise: Option<f32>,
    /// Path tracer: the most a sample's indirect light may bring (`--clamp-indirect`,
    /// [`crate::integrator::PathTracer::clamp_indirect`]); `None`: unbiased.
    pub clamp_indirect: Option<f32>,
    /// Also average the denoiser's guides over each pixel's own samples ([`Image::guides`]):
    /// the path tracer fills them from its camera rays' first surfaces at no cost in rays.
    pub guides: bool,
}

/// Adaptive sampling's first check: a pixel takes at least this many samples (or `spp`, if
/// fewer) before its error is estimated, and checks again after each further batch of as many.
pub const ADAPTIVE_BATCH: u32 = 4;

/// [`ADAPTIVE_BATCH`] when the film will be denoised ([`RenderSettings::guides`]): the filter,
/// not more samples, removes the grain, and it needs fewer. Measured with the default render
/// (noise target 1, the built-in filter at its σl of 24) against each image's own converged
/// one: 2 samples a pixel took 35-50% less time than 4 for a median FLIP of 0.0113 over the 28
/// shared models at 640x480 (4: 0.0084; worst 0.0294 against 0.0240) and the same on the
/// bundled box (0.0573 against 0.0577 at 1024x768), where a wider luminance tolerance now
/// evens out what 4 samples did (docs/denoising.md). A power of two, so that the Sobol
/// prefix a pixel stops at still covers it evenly.
pub const DENOISED_BATCH: u32 = 2;

/// The samples a denoised image's pixels take between them before adaptive sampling first
/// checks any: [`DENOISED_BATCH`] a pixel at 640x480 and above, more for smaller images (8 a
/// pixel at 320x240, 32 at 128x128; see [`RenderSettings::first_batch`]). Two samples leave
/// the filter too little to tell grain from detail: at 320x240 a textured model came out
/// mottled (docs/path-tracer.md, "Small images"), while the render's time there is a few
/// tens of milliseconds beside the load's.
pub const DENOISED_SAMPLES: u64 = 2 * 640 * 480;

/// The least share of a pixel's footprint one sample's texture filter covers (pbrt-v4's
/// 1/8): beyond 64 samples a pixel, finer mip levels than an eighth of a pixel would only
/// cost memory traffic.
pub const MIN_CONE_SHARE: f32 = 0.125;

/// Adaptive sampling's luminance floor: below it the target error is absolute (this times the
/// target), so dark pixels, where a relative error means little to the eye, do not take every
/// sample.
pub const NOISE_FLOOR: f32 = 0.05;

impl RenderSettings {
    /// Samples a pixel takes before adaptive sampling first estimates its error, and takes
    /// between checks: [`DENOISED_BATCH`] when the film will be denoised ([`Self::guides`]),
    /// else [`ADAPTIVE_BATCH`].
    pub fn adaptive_batch(&self) -> u32 {
        if self.guides {
            DENOISED_BATCH
        } else {
            ADAPTIVE_BATCH
        }
    }

    /// Samples a pixel takes before adaptive sampling first estimates its error (or `spp`, if
    /// fewer): [`Self::adaptive_batch`], and for a denoised image at least its share of
    /// [`DENOISED_SAMPLES`], rounded down to a power of two (so that the Sobol prefix a pixel
    /// stops at still covers it evenly). Checks then follow every [`Self::adaptive_batch`].
    pub fn first_batch(&self) -> u32 {
        first_batch(self.view.width, self.view.height, self.guides)
    }
}

/// [`RenderSettings::first_batch`] of a `width` x `height` image, denoised when `guides`.
pub fn first_batch(width: u32, height: u32, guides: bool) -> u32 {
    if !guides {
        return ADAPTIVE_BATCH;
    }
    let pixels = u64::from(width) * u64::from(height);
    let share = (DENOISED_SAMPLES / pixels.max(1)).clamp(1, 1 << 16);
    let power_of_two = 1u32 << share.ilog2();
    power_of_two.max(DENOISED_BATCH)
}

/// Arbitrary output variables, from one ray through each pixel's centre (no anti-aliasing,
/// so ids never blend across boundaries), row-major from the top-left pixel.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Aovs {
    /// Camera-space depth: distance along the view axis (as pyrender's), 0 where nothing is hit.
    pub depth: Vec<f32>,
    /// World-space unit shading normal facing the camera (interpolated, before normal maps);
    /// zero where nothing is hit.
    pub normal: Vec<Vec3>,
    /// Mesh instance id + 1 (index into `Scene::instances`), 0 where nothing is hit.
    pub instance: Vec<u32>,
}

/// What a render did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderStats {
    /// Camera rays traced.
    pub primary_rays: u64,
    /// Shadow rays traced.
    pub shadow_rays: u64,
    /// Path continuation rays (bounces) traced.
    pub indirect_rays: u64,
    /// Wall time of the render (not the BVH build).
    pub time: Duration,
    /// Camera samples taken (pixels × spp, or fewer with adaptive sampling).
    pub samples: u64,
    /// Noise estimate: the standard error of the pixel mean's luminance (after exposure),
    /// averaged over covered pixels; `None` at 1 spp (no spread to measure).
    pub noise: Option<f32>,
}

impl RenderStats {
    /// All rays traced.
    pub fn rays(&self) -> u64 {
        self.primary_rays + self.shadow_rays + self.indirect_rays
    }

    /// Camera samples per second over the render's wall time.
    pub fn samples_per_second(&self) -> f64 {
        self.samples as f64 / self.time.as_secs_f64().max(1e-9)
    }

    /// Millions of rays per second over the render's wall time.
    pub fn mrays_per_second(&self) -> f64 {
        self.rays() as f64 / self.time.as_secs_f64().max(1e-9) / 1e6
    }
}

/// The render was stopped through its cancel flag.
#[derive(Debug, thiserror::Error)]
#[error("render interrupted")]
pub struct Cancelled;

/// A rectangle of the image in pixels: columns `x..x + width`, rows `y..y + height`, row 0 at
/// the top.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Region {
    /// First column.
    pub x: u32,
    /// First row.
    pub y: u32,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
}

impl Region {
    /// The whole of a `width` x `height` image.
    pub fn full(width: u32, height: u32) -> Region {
        Region {
            x: 0,
            y: 0,
            width,
            height,
        }
    }

    /// One past the last column.
    pub fn right(&self) -> u32 {
        self.x + self.width
    }

    /// One past the last row.
    pub fn bottom(&self) -> u32 {
        self.y + self.height
    }

    /// Pixels in the region.
    pub fn pixels(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// Whether the region is non-empty and lies inside a `width` x `height` image.
    pub fn fits(&self, width: u32, height: u32) -> bool {
        self.width > 0
            && self.height > 0
            && u64::from(self.x) + u64::from(self.width) <= u64::from(width)
            && u64::from(self.y) + u64::from(self.height) <= u64::from(height)
    }

    /// The rectangle both regions cover, if any.
    pub fn intersection(&self, other: &Region) -> Option<Region> {
        let x = self.x.max(other.x);
        let y = self.y.max(other.y);
        let right = self.right().min(other.right());
        let bottom = self.bottom().min(other.bottom());
        (x < right && y < bottom).then(|| Region {
            x,
            y,
            width: right - x,
            height: bottom - y,
        })
    }
}

/// Renders a prepared scene. `progress` is called with the number of finished tiles and the
/// total; setting `cancel` stops the render at the next tile.
pub fn render(
    scene: &Prepared,
    settings: &RenderSettings,
    cancel: &AtomicBool,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<(Image, RenderStats, Option<Aovs>), Cancelled> {
    let full = Region::full(settings.view.width, settings.view.height);
    render_region(scene, settings, full, cancel, progress)
}

/// Renders the part `region` of the image `settings.view` describes: the image and AOVs are
/// `region.width` x `region.height`, and each pixel is the same, bit for bit, as the pixel at
/// that place of the whole render (every pixel's samples are keyed by its position in the
/// whole image and the seed, never by the region). `region` must fit the view's image.
pub fn render_region(
    scene: &Prepared,
    settings: &RenderSettings,
    region: Region,
    cancel: &AtomicBool,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<(Image, RenderStats, Option<Aovs>), Cancelled> {
    let start = Instant::now();
    debug_assert!(region.fits(settings.view.width, settings.view.height));
    let (width, height) = (region.width, region.height);
    let mut image = Image::new(width, height);
    // Adaptive sampling stops no pixel before its first batch.
    image.samples = match settings.noise {
        Some(_) => settings.spp.clamp(1, settings.first_batch()),
        None => settings.spp.max(1),
    };
    let pixel_count = width as usize * height as usize;
    let guides = (settings.guides && settings.integrator == IntegratorKind::Path)
        .then(|| denoise::Guides::new(width, height, true, image.samples));
    let aovs = settings.aovs.then(|| Aovs {
        depth: vec![0.0; pixel_count],
        normal: vec![Vec3::ZERO; pixel_count],
        instance: vec![0; pixel_count],
    });
    // Each tile goes into the film as it is finished, so that the tiles' buffers are never all
    // held at once beside the film's (at 4K they were 530 MB more at the render's end).
    let film = std::sync::Mutex::new(Film {
        region,
        image,
        guides,
        aovs,
    });
    let deliver = |tile: Tile| {
        // Poisoned only if placing a tile panicked (tiles lie inside the region, so none
        // does); rayon then hands that panic to the caller, and this film is never used.
        let mut film = film.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        film.place(&tile);
        TileSums {
            counts: tile.counts,
            noise_sum: tile.noise_sum,
            noise_pixels: tile.noise_pixels,
            samples: tile.samples,
        }
    };
    let lights = || settings.lights.iter().map(PunctualLight::new).collect();
    // The pixel loop is generic over the integrator (a closed set, matched once here), so
    // that its tile body, with the integrator's vertex work inlined, is compiled for each CPU
    // level (see `PixelLoop::tile`).
    let results = match settings.integrator {
        IntegratorKind::Direct => {
            let direct = Direct {
                lights: lights(),
                ambient: settings.ambient,
                shading: settings.shading,
            };
            render_tiles(scene, &direct, settings, region, cancel, progress, &deliver)
        }
        IntegratorKind::Path => {
            let path = PathTracer {
                lights: lights(),
                environment: settings.environment.clone(),
                environment_visible: settings.environment_visible,
                max_bounces: settings.bounces,
                estimator: crate::integrator::Estimator::Mis,
                clamp_indirect: settings.clamp_indirect,
            };
            render_tiles(scene, &path, settings, region, cancel, progress, &deliver)
        }
    };
    let Film {
        mut image,
        guides,
        aovs,
        ..
    } = film
        .into_inner()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    // The sums in tile order, whichever finished first: the same statistics every run.
    let mut stats = RenderStats::default();
    let (mut noise_sum, mut noise_pixels) = (0.0f64, 0u64);
    for tile in results {
        let tile = tile.ok_or(Cancelled)?;
        stats.primary_rays += tile.counts.primary;
        stats.shadow_rays += tile.counts.shadow;
        stats.indirect_rays += tile.counts.indirect;
        noise_sum += tile.noise_sum;
        noise_pixels += tile.noise_pixels;
        stats.samples += tile.samples;
    }
    image.guides = guides;
    stats.time = start.elapsed();
    stats.noise = (noise_pixels > 0).then(|| (noise_sum / noise_pixels as f64) as f32);
    Ok((image, stats, aovs))
}

/// The image, guides and AOVs of a render's region while its tiles come in.
struct Film {
    region: Region,
    image: Image,
    guides: Option<denoise::Guides>,
    aovs: Option<Aovs>,
}

impl Film {
    /// Copies `tile`'s pixels, variances, guides and AOVs to their places.
    fn place(&mut self, tile: &Tile) {
        use film::paste_rows;
        let (width, x, y) = (
            self.region.width,
            tile.x - self.region.x,
            tile.y - self.region.y,
        );
        let image = &mut self.image;
        paste_rows(&mut image.pixels, width, &tile.pixels, tile.width, x, y);
        paste_rows(&mut image.variance, width, &tile.variance, tile.width, x, y);
        if let (Some(g), Some(t)) = (self.guides.as_mut(), tile.guides.as_ref()) {
            g.paste(t, x, y);
        }
        if let Some(a) = self.aovs.as_mut() {
            paste_rows(&mut a.depth, width, &tile.aovs.depth, tile.width, x, y);
            paste_rows(&mut a.normal, width, &tile.aovs.normal, tile.width, x, y);
            paste_rows(
                &mut a.instance,
                width,
                &tile.aovs.instance,
                tile.width,
                x,
                y,
            );
        }
    }
}

/// What a finished tile adds to the render's statistics.
struct TileSums {
    counts: RayCounts,
    noise_sum: f64,
    noise_pixels: u64,
    samples: u64,
}

/// Renders every tile of `region` with `integrator`, in parallel, handing each to `deliver`
/// as it is finished: what it returns for each tile, in tile order; `None` for tiles skipped
/// after `cancel` was set.
fn render_tiles<I: Integrator>(
    scene: &Prepared,
    integrator: &I,
    settings: &RenderSettings,
    region: Region,
    cancel: &AtomicBool,
    progress: &(dyn Fn(u64, u64) + Sync),
    deliver: &(dyn Fn(Tile) -> TileSums + Sync),
) -> Vec<Option<TileSums>> {
    let tiles_x = region.width.div_ceil(TILE_SIZE);
    let tiles_y = region.height.div_ceil(TILE_SIZE);
    let total = u64::from(tiles_x) * u64::from(tiles_y);
    let done = std::sync::atomic::AtomicU64::new(0);
    let tracer = PixelLoop::new(scene, integrator, settings, region);
    let tiles: Vec<(u32, u32)> = (0..tiles_y)
        .flat_map(|ty| (0..tiles_x).map(move |tx| (tx, ty)))
        .collect();
    tiles
        .par_iter()
        .map(|&(tx, ty)| {
            if cancel.load(Ordering::Relaxed) {
                return None;
            }
            let tile = tracer.tile(region.x + tx * TILE_SIZE, region.y + ty * TILE_SIZE);
            let sums = deliver(tile);
            progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            Some(sums)
        })
        .collect()
}

/// The standard error of a mean `mean` of `n` (> 1) samples whose squares sum to `squares`.
fn standard_error(squares: f64, mean: f64, n: u32) -> f64 {
    let n = f64::from(n);
    let variance = (squares / n - mean * mean).max(0.0) * n / (n - 1.0);
    (variance / n).sqrt()
}

/// One finished tile.
struct Tile {
    x: u32,
    y: u32,
    width: u32,
    pixels: Vec<Vec4>,
    /// Per pixel, the variance of its mean luminance ([`Image::variance`]).
    variance: Vec<f32>,
    /// The denoiser's guides of the tile's pixels, when asked for (`samples_per_pixel` unused).
    guides: Option<denoise::Guides>,
    aovs: Aovs,
    counts: RayCounts,
    /// Sum over covered pixels of the standard error of their mean luminance.
    noise_sum: f64,
    /// Covered pixels counted in `noise_sum`.
    noise_pixels: u64,
    /// Camera samples taken.
    samples: u64,
}

/// One pixel's sums while its samples are taken ([`PixelLoop::pixel_run`]).
struct Pixel {
    x: u32,
    sampler: Sampler,
    /// Radiance (after exposure) and coverage, summed over the samples taken.
    sum: Vec4,
    /// Sum of the squared luminances, for the standard error.
    luminance_squares: f64,
    /// The first surface a camera ray met (the AOVs' at one sample a pixel).
    first: Option<Hit>,
    /// Samples the pixel takes: `spp`, or fewer once adaptive sampling stops it.
    taken: u32,
    /// Whether it has taken them all.
    done: bool,
    /// The denoiser's guides, summed.
    albedo: Vec3,
    normal: Vec3,
    depth: f32,
    depth_hits: u32,
    visibility: f32,
    emission: Vec3,
}

impl Pixel {
    fn new(seed: u64, x: u32, y: u32, spp: u32) -> Pixel {
        Pixel {
            x,
            sampler: Sampler::for_pixel(seed, x, y),
            sum: Vec4::ZERO,
            luminance_squares: 0.0,
            first: None,
            taken: spp,
            done: false,
            albedo: Vec3::ZERO,
            normal: Vec3::ZERO,
            depth: 0.0,
            depth_hits: 0,
            visibility: 0.0,
            emission: Vec3::ZERO,
        }
    }

    /// The pixel's mean, variance and guides into `tile`.
    fn finish(&self, tile: &mut Tile) {
        let taken = self.taken;
        tile.samples += u64::from(taken);
        tile.pixels.push(self.sum / taken as f32);
        let mut variance = 0.0f32;
        if taken > 1 && self.sum.w > 0.0 {
            let n = f64::from(taken);
            let mean = f64::from(luminance(self.sum.truncate())) / n;
            let error = standard_error(self.luminance_squares, mean, taken);
            tile.noise_sum += error;
            tile.noise_pixels += 1;
            variance = (error * error) as f32;
        }
        tile.variance.push(variance);
        if let Some(g) = tile.guides.as_mut() {
            let n = taken as f32;
            g.albedo
                .push((self.albedo / n).clamp(Vec3::ZERO, Vec3::ONE));
            g.normal.push(self.normal / n);
            g.visibility.push(self.visibility / n);
            g.emission.push(self.emission / n);
            g.depth.push(if self.depth_hits > 0 {
                self.depth / self.depth_hits as f32
            } else {
                0.0
            });
        }
    }
}

/// Per-render constants shared by all tiles.
struct PixelLoop<'a, I> {
    scene: &'a Prepared,
    integrator: &'a I,
    settings: &'a RenderSettings,
    /// The part of the image rendered.
    region: Region,
    /// 2^exposure.
    scale: f32,
    /// Ray-cone footprint of a pixel: width at distance t is `spread.0 + spread.1 · t`
    /// (perspective: angle per pixel; orthographic: pixel size).
    spread: (f32, f32),
    /// Whether the tiles average the denoiser's guides ([`RenderSettings::guides`], path
    /// tracer only).
    collect_guides: bool,
    /// [`RenderSettings::first_batch`], computed once.
    first_batch: u32,
}

impl<'a, I: Integrator> PixelLoop<'a, I> {
    fn new(
        scene: &'a Prepared,
        integrator: &'a I,
        settings: &'a RenderSettings,
        region: Region,
    ) -> Self {
        let view = &settings.view;
        // The cone of one sample, not of the whole pixel: the pixel's samples already average
        // the texture over the pixel, so each filters over a footprint shrunk by 1/√spp (at
        // least 1/8 of the pixel), as pbrt-v4 scales its camera ray differentials. Filtering
        // each sample over the whole pixel blurred textures twice: against Cycles, which reads
        // full-resolution texels, Lantern's covered FLIP was 0.13 and BoxTextured's 0.053.
        let sample_share = (1.0 / (settings.spp.max(1) as f32).sqrt()).max(MIN_CONE_SHARE);
        let spread = match view.lens {
            Lens::Perspective { height, .. } => (0.0, sample_share * height / view.height as f32),
            Lens::Orthographic { height, .. } => (sample_share * height / view.height as f32, 0.0),
        };
        Self {
            scene,
            integrator,
            settings,
            region,
            scale: settings.exposure.exp2(),
            spread,
            collect_guides: settings.guides && settings.integrator == IntegratorKind::Path,
            first_batch: settings.first_batch(),
        }
    }

    /// Renders the tile whose top-left pixel is (`x0`, `y0`): [`PixelLoop::tile_body`],
    /// compiled for x86-64-v3 where the CPU runs it ([`crate::cpu`]). The integrator's work
    /// at a path vertex (surface setup, BSDF, light samples) is inlined into the body, so all
    /// of it gets the wider instruction set: three-operand AVX forms instead of SSE's register
    /// copies, `roundss`, `popcnt`. The path tracer on the bundled Cornell box traced 13-15%
    /// more rays a second on one thread so (README, "Light transport"); the bits are the same
    /// on either path (see `crate::cpu`).
    fn tile(&self, x0: u32, y0: u32) -> Tile {
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::has_v3() {
            // SAFETY: the CPU has every feature `tile_v3` is compiled for.
            return unsafe { self.tile_v3(x0, y0) };
        }
        self.tile_body(x0, y0)
    }

    crate::cpu::v3! {
        /// [`PixelLoop::tile_body`] for x86-64-v3 CPUs.
        fn tile_v3(&self, x0: u32, y0: u32) -> Tile = tile_body
    }

    /// The body of [`PixelLoop::tile`], compiled for each CPU level.
    #[inline(always)]
    fn tile_body(&self, x0: u32, y0: u32) -> Tile {
        let x1 = (x0 + TILE_SIZE).min(self.region.right());
        let y1 = (y0 + TILE_SIZE).min(self.region.bottom());
        let mut tile = Tile {
            x: x0,
            y: y0,
            width: x1 - x0,
            pixels: Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize),
            variance: Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize),
            guides: self.collect_guides.then(|| denoise::Guides {
                width: x1 - x0,
                height: y1 - y0,
                albedo: Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize),
                normal: Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize),
                depth: Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize),
                visibility: Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize),
                emission: Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize),
                samples_per_pixel: 0,
            }),
            aovs: Aovs::default(),
            counts: RayCounts::default(),
            noise_sum: 0.0,
            noise_pixels: 0,
            samples: 0,
        };
        for y in y0..y1 {
            for x in (x0..x1).step_by(PACKET) {
                self.pixel_run(x..(x + PACKET as u32).min(x1), y, &mut tile);
            }
        }
        tile
    }

    /// The pixels `xs` (at most [`PACKET`]) of row `y`, side by side: at each sample index the
    /// camera rays of those still sampling are traced together in one packet query (they
    /// mostly enter the same nodes), then each goes to the integrator with its first hit.
    /// Each pixel takes its samples and their numbers in the same order as alone, and the
    /// packet's answers are the single-ray ones, so the image is the same.
    #[inline(always)]
    fn pixel_run(&self, xs: std::ops::Range<u32>, y: u32, tile: &mut Tile) {
        let view = &self.settings.view;
        let spp = self.settings.spp.max(1);
        let mut pixels: [Pixel; PACKET] =
            std::array::from_fn(|i| Pixel::new(self.settings.seed, xs.start + i as u32, y, spp));
        let pixels = &mut pixels[..xs.len()];
        let mut rays = [view.ray(0.5, 0.5); PACKET];
        let mut hits = [None; PACKET];
        let mut sampling = [0usize; PACKET];
        let mut lanes: [Lane; PACKET] = std::array::from_fn(|i| Lane {
            camera: CameraRay {
                ray: rays[i],
                spread_base: self.spread.0,
                spread_per_distance: self.spread.1,
                traced: None,
            },
            // Each sample takes its pixel's sampler (below).
            sampler: crate::sampling::Sampler::for_pixel(0, 0, 0),
            first: None,
            guide: None,
            radiance: Vec3::ZERO,
            coverage: 0.0,
        });
        for s in 0..spp {
            let mut count = 0;
            for (i, pixel) in pixels.iter_mut().enumerate() {
                if pixel.done {
                    continue;
                }
                pixel.sampler.start_sample(s);
                // The pixel position is the sample's first two numbers: any prefix of 2^m
                // samples covers the pixel evenly (see crate::sampling::Sampler), which
                // adaptive sampling's early stops need.
                let (dx, dy) = if spp == 1 {
                    (0.5, 0.5)
                } else {
                    pixel.sampler.next_2d()
                };
                // A thin lens takes the next two (a pinhole view draws none, so its numbers
                // stay where they were); one sample a pixel goes through the lens centre.
                let lens = if view.thin_lens.is_some() && spp != 1 {
                    pixel.sampler.next_2d()
                } else {
                    (0.5, 0.5)
                };
                rays[count] = view.lens_ray(pixel.x as f32 + dx, y as f32 + dy, lens);
                sampling[count] = i;
                count += 1;
            }
            if count == 0 {
                break;
            }
            self.scene
                .intersect_camera_many(&rays[..count], &mut hits[..count]);
            // The samples go to the integrator together (it may trace their shadow rays as
            // packets), each with its pixel's state, which comes back after.
            let active = lanes
                .iter_mut()
                .zip(&rays)
                .zip(hits)
                .zip(&sampling)
                .take(count);
            for (((lane, ray), hit), &i) in active {
                let pixel = &pixels[i];
                lane.camera.ray = *ray;
                lane.camera.traced = Some(hit);
                lane.sampler.clone_from(&pixel.sampler);
                lane.first = pixel.first;
                lane.guide = self.collect_guides.then(GuideSample::default);
            }
            let lanes = &mut lanes[..count];
            self.integrator
                .radiance_many(self.scene, lanes, &mut tile.counts);
            for (lane, &i) in lanes.iter().zip(&sampling) {
                let pixel = &mut pixels[i];
                pixel.sampler.clone_from(&lane.sampler);
                pixel.first = lane.first;
                self.record(pixel, lane, s);
            }
        }
        // One sample a pixel went through the centre: its first surface is the AOVs'.
        // Otherwise they trace the centre rays themselves, again as one packet.
        let centre = |pixel: &Pixel| view.ray(pixel.x as f32 + 0.5, y as f32 + 0.5);
        if self.settings.aovs && spp != 1 {
            for (ray, pixel) in rays.iter_mut().zip(pixels.iter()) {
                *ray = centre(pixel);
            }
            self.scene
                .intersect_camera_many(&rays[..pixels.len()], &mut hits[..pixels.len()]);
            for (pixel, hit) in pixels.iter_mut().zip(hits) {
                pixel.first = hit;
            }
        }
        for pixel in pixels.iter() {
            pixel.finish(tile);
            if self.settings.aovs {
                self.aov(&centre(pixel), pixel.first, &mut tile.aovs);
            }
        }
    }

    /// Sample `s` of `pixel`, traced in `lane`: its radiance into the pixel's sums, and its
    /// guides when they are collected. Stops the pixel when adaptive sampling finds it
    /// converged.
    #[inline(always)]
    fn record(&self, pixel: &mut Pixel, lane: &Lane, s: u32) {
        let (color, coverage) = (lane.radiance, lane.coverage);
        if let Some(guide) = &lane.guide {
            // As the denoiser's own guide rays: albedo in [0, 1], a visible background's
            // radiance (after exposure, clamped) as its albedo.
            pixel.albedo += guide.albedo.clamp(Vec3::ZERO, Vec3::ONE)
                + (guide.background * self.scale).clamp(Vec3::ZERO, Vec3::ONE);
            pixel.normal += guide.normal;
            pixel.visibility += guide.visibility.unwrap_or(1.0);
            pixel.emission += guide.emission * self.scale;
            if let Some(t) = guide.depth {
                pixel.depth += t;
                pixel.depth_hits += 1;
            }
        }
        pixel.sum += (color * self.scale).extend(coverage);
        pixel.luminance_squares += f64::from(luminance(color * self.scale)).powi(2);
        if let Some(target) = self.settings.noise {
            let n = s + 1;
            if n < pixel.taken
                && n.is_multiple_of(self.settings.adaptive_batch())
                && n >= self.first_batch
            {
                let mean = f64::from(luminance(pixel.sum.truncate())) / f64::from(n);
                let error = standard_error(pixel.luminance_squares, mean, n);
                if error <= f64::from(target) * mean.max(f64::from(NOISE_FLOOR)) {
                    pixel.taken = n;
                    pixel.done = true;
                }
            }
        }
        if s + 1 == pixel.taken {
            pixel.done = true;
        }
    }

    /// Depth, normal and instance id of `hit`, the first surface along pixel-centre `ray`.
    fn aov(&self, ray: &Ray, hit: Option<Hit>, out: &mut Aovs) {
        match hit {
            Some(hit) => {
                let soup = &self.scene.scene.soup;
                let tri = hit.triangle as usize;
                let b = hit.barycentric;
                let [na, nb, nc] = soup.corner_normals(tri);
                let [pa, pb, pc] = soup.triangle(tri);
                let direction = Vec3::from(ray.direction);
                let mut n = (na * b.x + nb * b.y + nc * b.z)
                    .try_normalize()
                    .unwrap_or((pb - pa).cross(pc - pa).normalize_or_zero());
                if n.dot(direction) > 0.0 {
                    n = -n;
                }
                out.depth.push(hit.t * direction.dot(-self.settings.view.w));
                out.normal.push(n);
                out.instance
                    .push(soup.instance.get(tri).map_or(0, |i| i + 1));
            }
            None => {
                out.depth.push(0.0);
                out.normal.push(Vec3::ZERO);
                out.instance.push(0);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::IntegratorKind;

    fn settings(width: u32, height: u32, denoised: bool) -> RenderSettings {
        let camera = crate::camera::look_at(Vec3::Z, Vec3::ZERO, Vec3::Y, 0.8, 1.0, 1.0);
        RenderSettings {
            view: View::from_camera(&camera, width, height),
            spp: 32,
            seed: 0,
            lights: Vec::new(),
            ambient: Vec3::ZERO,
            exposure: 0.0,
            shading: ShadingModel::Pbr,
            aovs: false,
            integrator: IntegratorKind::Path,
            bounces: 8,
            environment: None,
            environment_visible: false,
            noise: Some(1.0),
            clamp_indirect: None,
            guides: denoised,
        }
    }

    /// A denoised image's pixels take their share of [`DENOISED_SAMPLES`] (a power of two)
    /// before the first check, never fewer than [`DENOISED_BATCH`]: the default render at
    /// 640x480 and above is unchanged, 320x240 takes 8, a thumbnail more (the render caps it
    /// at `spp`). An image that is not denoised checks after [`ADAPTIVE_BATCH`] at any size.
    #[test]
    fn small_denoised_images_take_more_samples_before_the_first_check() {
        for (width, height, first) in [
            (1920, 1080, 2),
            (1024, 768, 2),
            (640, 480, 2),
            (400, 300, 4),
            (320, 240, 8),
            (256, 256, 8),
            (128, 128, 32),
            (1, 1, 1 << 16),
        ] {
            let s = settings(width, height, true);
            assert_eq!(s.first_batch(), first, "{width}x{height}");
            assert_eq!(s.adaptive_batch(), DENOISED_BATCH);
            let plain = settings(width, height, false);
            assert_eq!(plain.first_batch(), ADAPTIVE_BATCH, "{width}x{height}");
        }
    }
}
