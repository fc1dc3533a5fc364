//! Integrators: the radiance arriving along one camera ray. The pixel loop
//! ([`crate::render`]) and the film never know which integrator runs; an integrator never
//! knows about pixels, tiles or output files. Modelled on pbrt-v4's `Integrator::Li` and
//! Mitsuba 3's `SamplingIntegrator::sample`.

pub mod direct;
pub mod path;

pub use direct::Direct;
pub use path::{Estimator, PathTracer};

use crate::accel::Hit;
use crate::geometry::Ray;
use crate::prepare::Prepared;
use crate::sampling::Sampler;
use glam::Vec3;

/// A camera ray with its footprint (ray cone, for texture filtering): the width of the pixel's
/// cone at distance `t` is `spread_base + spread_per_distance · t` (perspective: angle per
/// pixel; orthographic: pixel size).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraRay {
    /// The ray, from the camera through the sample position.
    pub ray: Ray,
    /// Cone width at the camera.
    pub spread_base: f32,
    /// Growth of the cone width per unit distance.
    pub spread_per_distance: f32,
    /// The first surface along `ray` ([`Prepared::intersect_camera`]) when the pixel loop has
    /// already traced it (with its neighbours', in one packet); `None` when it has not.
    pub traced: Option<Option<Hit>>,
}

impl CameraRay {
    /// The cone's width at distance `t` along the ray.
    pub fn footprint(&self, t: f32) -> f32 {
        self.spread_base + self.spread_per_distance * t
    }
}

/// Rays traced, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    /// Camera rays (and their continuations through BLEND layers).
    pub primary: u64,
    /// Shadow rays.
    pub shadow: u64,
    /// Path continuation rays (bounces).
    pub indirect: u64,
}

/// Which integrator renders.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IntegratorKind {
    /// Punctual lights through shadow rays, constant ambient, emission as seen; no bounces.
    #[default]
    Direct,
    /// Path tracing: area lights, the environment, interreflection, MIS.
    Path,
}

/// What the denoiser's guides ([`crate::render::denoise`]) take from one camera sample: the
/// albedo and shading normal of the surface it stops at (the first one, or one behind a BLEND
/// layer it passed through), its first hit's distance, or the background radiance it met.
/// The pixel loop averages them over the pixel's samples, which makes the guides as
/// anti-aliased as the image at no cost in rays.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GuideSample {
    /// Base colour of the surface the sample stopped at (zero on a miss); the pixel loop
    /// clamps it to [0, 1].
    pub albedo: Vec3,
    /// Its shading normal (zero on a miss).
    pub normal: Vec3,
    /// Distance along the camera ray to the first surface, if any.
    pub depth: Option<f32>,
    /// On a miss, the radiance of the visible environment behind (zero when none is seen).
    pub background: Vec3,
    /// How much of the light the punctual lights would bring to that surface arrives past its
    /// shadow rays: Σ T·E / Σ E over the lights, E the luminance of a light's irradiance there
    /// (cosine included) and T its shadow ray's transmittance; `None` when no punctual light
    /// would light it (counted as 1). It shows the denoiser where hard shadows fall, which
    /// the albedo, normal and depth do not.
    pub visibility: Option<f32>,
    /// What the camera ray itself sees emitted: the emission (or a `KHR_materials_unlit`
    /// colour) of the surfaces along its first segment, times their coverage, part of the
    /// sample's radiance with no Monte Carlo noise of its own. The denoiser takes it out of
    /// what it smooths and adds it back, so emissive detail (a lit display, a texture of
    /// lights) stays sharp whatever the albedo guide shows there.
    pub emission: Vec3,
}

/// Computes the radiance along camera rays.
pub trait Integrator: Sync {
    /// Radiance (premultiplied by coverage, linear, photometric units as in [`crate::light`])
    /// and coverage (0 = nothing hit, 1 = opaque) along `camera`. `sampler` gives the pixel's
    /// current sample's numbers (deterministic for a seed, whatever thread runs it); `counts` tallies the rays.
    /// `first` gets the first surface the camera ray meets (the one the AOVs record: at one
    /// sample a pixel, through its centre, they need no ray of their own), left `None` when
    /// the ray meets nothing. `guide`, when given, gets this sample's [`GuideSample`] (it
    /// starts as the default); an integrator that does not fill it leaves `None` in the
    /// pixel's guides, and the denoiser traces its own.
    fn radiance(
        &self,
        scene: &Prepared,
        camera: &CameraRay,
        sampler: &mut Sampler,
        counts: &mut RayCounts,
        first: &mut Option<Hit>,
        guide: Option<&mut GuideSample>,
    ) -> (Vec3, f32);

    /// [`Integrator::radiance`] of each of `lanes`: camera samples of neighbouring pixels at
    /// one sample index (at most [`crate::accel::PACKET`]), each with its own sampler, first
    /// hit and guide, its result into its `radiance` and `coverage`. Each lane's result is
    /// what `radiance` gives it, bit for bit. By default they run one after the other; an
    /// integrator overrides this to trace their rays toward the same lights together, as one
    /// packet (see [`Direct`]).
    #[inline(always)]
    fn radiance_many(&self, scene: &Prepared, lanes: &mut [Lane], counts: &mut RayCounts) {
        for lane in lanes {
            (lane.radiance, lane.coverage) = self.radiance(
                scene,
                &lane.camera,
                &mut lane.sampler,
                counts,
                &mut lane.first,
                lane.guide.as_mut(),
            );
        }
    }
}

/// One camera sample of [`Integrator::radiance_many`]: what [`Integrator::radiance`] takes
/// and gives, held by value (the pixel loop copies its pixel's state in and out).
#[derive(Clone, Debug)]
pub struct Lane {
    /// The camera ray.
    pub camera: CameraRay,
    /// The pixel's sampler, at this sample.
    pub sampler: Sampler,
    /// The pixel's first surface so far (see `first` of [`Integrator::radiance`]).
    pub first: Option<Hit>,
    /// The sample's guide when the denoiser's guides are collected.
    pub guide: Option<GuideSample>,
    /// The result: radiance (premultiplied) ...
    pub radiance: Vec3,
    /// ... and coverage.
    pub coverage: f32,
}
