//! Every default and limit of a render in one named place, each with its reason: the CLI's
//! `--help` prints these values, the library uses them when the caller does not say otherwise,
//! and `VIEW.json` records what was actually used. A leaf: it imports nothing of the crate.

/// `--bvh-preset auto`: rays a triangle above which the `medium` BVH preset's longer build
/// pays for itself, and below which `very-fast` is chosen. Measured on
/// MetalRoughSpheresNoTextures (1.04M triangles, 2 threads): medium builds in about 0.25 µs a
/// triangle more than very-fast (0.90 s against 0.65 s) and traces at most 3-4% faster
/// (primary 5.06 against 4.89 Mrays/s; diffuse within noise), which repays the build after
/// about 0.25 µs / (0.035 × 0.28 µs a ray) ≈ 25 rays a triangle; 32 leaves some margin.
pub const AUTO_PRESET_RAYS_PER_TRIANGLE: f64 = 32.0;

/// Most bounces of a path after the first hit (`--bounces`): Cycles' default total of 12 less
/// what our scenes need; interiors converge to within 1% by 8 on the Cornell box.
pub const DEFAULT_BOUNCES: u32 = 8;

/// Samples per pixel of the direct integrator when none is given.
pub const DEFAULT_SPP: u32 = 4;

/// Most samples per pixel of the default render (the path tracer without `--spp`), which
/// samples each pixel adaptively until its noise is under [`DEFAULT_NOISE`]. Measured at
/// 320x240 against 1024-spp references through Khronos PBR Neutral (DamagedHelmet, Avocado,
/// the bunny, in the studio environment): 16 samples already come within mean FLIP 0.008-0.019
/// of the reference, 64 within 0.005-0.011 at 4x the time; 32 leaves noisy pixels room.
pub const DEFAULT_PATH_SPP: u32 = 32;

/// The default render's noise target (`--noise`) without the denoiser (`--no-denoise`, and
/// the renders the filter does not handle: views, turntables, tiles, crops): a pixel stops,
/// after its first 4 samples (checked every 4, [`crate::render::ADAPTIVE_BATCH`]), once the
/// standard error of its luminance is at most this fraction of it. Smooth pixels and the
/// background stop at 4; with the Sobol sampler such a render stays within mean FLIP 0.03 of
/// its own 128-spp image on every shared model at 640x480 (docs/path-tracer.md, "The default
/// render"); 0.05 instead took about as long as a fixed 64 for a FLIP difference under 0.001.
pub const DEFAULT_NOISE: f32 = 0.1;

/// The default render's noise target when it is denoised (as it is unless `--no-denoise`,
/// [`crate::setup::denoises_by_default`]): nearly every pixel stops at its first samples (4
/// when this was measured, 2 since: [`crate::render::DENOISED_BATCH`]) and the built-in
/// filter removes the grain they leave; only pixels whose error is still larger than their
/// value sample on. Measured on every shared model at 640x480 against each
/// one's 128-spp image (docs/path-tracer.md, "The default render"): median FLIP 0.0087, worst
/// 0.0255 (the Cornell box), in 7% less time than 0.5 (0.0103, 0.0267); 0.0084 and 0.0240
/// since the filter's luminance tolerance doubled (docs/denoising.md). More samples in some
/// pixels made the filtered image worse, not better: the filter trusts a pixel more the more
/// its samples agree, so pixels that sampled on kept grain their 4-sample neighbours lost
/// (MultipleScenes' rough metal: 0.0177 at 0.5, 0.0114 at 1.0, with a fifth less time). 2.0
/// gave 1.0's images; 0.25 took twice 0.5's time for the same FLIP. The shared models average
/// 4.0 samples a pixel at 1.0 (2.0 since the first batch is 2): a pixel samples on only while
/// its error exceeds its value.
pub const DEFAULT_DENOISED_NOISE: f32 = 1.0;

/// Image width when none is given.
pub const DEFAULT_WIDTH: u32 = 1024;

/// Image height when none is given and the camera has no aspect ratio.
pub const DEFAULT_HEIGHT: u32 = 768;

/// Vertical field of view of the automatic camera and of `--look-from` cameras, in degrees.
pub const DEFAULT_YFOV_DEGREES: f32 = 45.0;

/// Elevation of `--views orbit:N` above the model's centre, in degrees: high enough to see the
/// top of a model standing on the ground, low enough to see its sides.
pub const DEFAULT_ORBIT_ELEVATION_DEGREES: f32 = 20.0;

/// Most views one `--views` run renders: far more than any dataset of one model needs, few
/// enough that the file names and poses of all of them are planned up front in a few MB.
pub const MAX_VIEWS: usize = 100_000;

/// Ambient factor with the default light rig: enough to show the unlit side of a model.
pub const AMBIENT_WITH_DEFAULT_RIG: f32 = 0.08;

/// Ambient factor when the file brings its own lights: a faint fill, so that shadows are not
/// pitch black but the file's lighting dominates.
pub const AMBIENT_WITH_FILE_LIGHTS: f32 = 0.03;

/// Budget for decoded textures, in MiB (`--max-texture-memory`).
pub const MAX_TEXTURE_MIB: usize = 2048;

/// Illuminance of the default rig's key light (lux): a white diffuse surface facing it reads
/// about 2.5/π ≈ 0.8.
pub const KEY_LIGHT_LUX: f32 = 2.5;

/// Illuminance of the default rig's fill light (lux), about a third of the key.
pub const FILL_LIGHT_LUX: f32 = 0.8;

/// Most BLEND surfaces a camera ray composites before it stops (both integrators, and the
/// denoiser's guides, which follow the same rays).
pub const MAX_BLEND_LAYERS: usize = 16;

/// Largest model, buffer or image file read, in bytes (`LoadLimits::max_file_bytes`): 2 GiB,
/// above every sample and scan we have met (the largest, a 1.04M-triangle model, is 60 MB).
pub const MAX_FILE_BYTES: u64 = 2 << 30;

/// Most triangles a scene may hold after instancing (`--max-triangles`): 50 million is about
/// 9 GB of soup and BVH, more than a workstation renders comfortably.
pub const MAX_TRIANGLES: u64 = 50_000_000;

/// Vertices allowed a triangle of the limit: a primitive may declare at most
/// `MAX_TRIANGLES × VERTICES_PER_TRIANGLE` vertices (150 million by default), as many as its
/// triangles could use without sharing any. The limits are checked against the counts a file
/// declares before anything of that size is allocated.
pub const VERTICES_PER_TRIANGLE: u64 = 3;

/// Largest image a render makes unless told otherwise (`--max-pixels`, Python's
/// `max_pixels`): 8192x8192. Past it the film alone would take gigabytes.
pub const MAX_RENDER_PIXELS: u64 = 8192 * 8192;

/// Most samples a pixel a render takes unless told otherwise (`--max-spp`, Python's `max_spp`).
pub const MAX_SPP: u32 = 4096;

/// Largest decoded image, in pixels: 64 megapixels, e.g. 8192x8192.
pub const MAX_IMAGE_PIXELS: u64 = 64 << 20;
