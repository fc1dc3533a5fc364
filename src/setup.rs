//! Options to render settings: the default light rig and the default render of a scene. The
//! values themselves are named in [`crate::defaults`].

use crate::camera::{auto_camera, View};
use crate::color::ViewTransform;
use crate::defaults::{
    AMBIENT_WITH_DEFAULT_RIG, AMBIENT_WITH_FILE_LIGHTS, DEFAULT_BOUNCES, DEFAULT_DENOISED_NOISE,
    DEFAULT_NOISE, DEFAULT_PATH_SPP, DEFAULT_SPP, FILL_LIGHT_LUX, KEY_LIGHT_LUX,
};
use crate::integrator::IntegratorKind;
use crate::light::environment::Environment;
use crate::render::RenderSettings;
use crate::scene::{Light, LightKind, Scene};
use crate::shading::ShadingModel;
use glam::Vec3;
use std::sync::Arc;

/// About how many rays a render traces: a camera ray per sample, one shadow ray per light at
/// each hit and, for the path tracer, about two rays (a bounce and a light sample) for each of
/// the first few bounces (Russian roulette and escaping paths end most paths by then).
///
/// With adaptive sampling, `spp` is only the cap: pixels take from `adaptive_batch` samples up
/// ([`RenderSettings::adaptive_batch`]: [`crate::render::ADAPTIVE_BATCH`], or
/// [`crate::render::DENOISED_BATCH`] for a denoised film), most of them stopping at the first
/// check (a mean of 4-6 samples on the shared models at noise 1.0 without the filter, 2 with
/// it), so twice the batch stands for the count; `None` without adaptive sampling. Counting the
/// cap chose the slower BVH build for the default render of MetalRoughSpheresNoTextures (1.04M
/// triangles), which spent half its time on it.
pub fn expected_rays(
    pixels: u64,
    spp: u32,
    adaptive_batch: Option<u32>,
    lights: usize,
    integrator: IntegratorKind,
    bounces: u32,
) -> f64 {
    let spp = match adaptive_batch {
        Some(batch) => spp.min(2 * batch),
        None => spp,
    };
    let samples = pixels as f64 * f64::from(spp.max(1));
    match integrator {
        IntegratorKind::Direct => samples * (1 + lights) as f64,
        IntegratorKind::Path => samples * (1.0 + 2.0 * f64::from(bounces.min(3))),
    }
}

/// The default light rig for scenes without lights, in the camera's frame: a key light from
/// above-left behind the camera, a fill from the right, and [`AMBIENT_WITH_DEFAULT_RIG`]. Both
/// are directional, so the rig does not depend on the scene's scale.
pub fn default_rig(view: &View) -> (Vec<Light>, Vec3) {
    let directional = |name: &str, to_light: Vec3, lux: f32| Light {
        name: Some(name.to_string()),
        kind: LightKind::Directional,
        color: Vec3::ONE,
        intensity: lux,
        range: None,
        position: Vec3::ZERO,
        direction: -to_light.normalize(),
    };
    let key = directional(
        "default key",
        view.w + 0.8 * view.v - 0.6 * view.u,
        KEY_LIGHT_LUX,
    );
    let fill = directional(
        "default fill",
        0.6 * view.w + 0.2 * view.v + 1.0 * view.u,
        FILL_LIGHT_LUX,
    );
    (vec![key, fill], Vec3::splat(AMBIENT_WITH_DEFAULT_RIG))
}

/// What a command asks of a view's lighting (the render options that decide it).
#[derive(Clone, Debug)]
pub struct LightingOptions {
    /// The direct integrator is lit by the default rig when the file has no lights; the path
    /// tracer by the built-in studio environment.
    pub integrator: IntegratorKind,
    /// Neither the rig nor the studio environment (`--no-default-lights`).
    pub no_default_lights: bool,
    /// A panorama to light with (`--env`), already rotated and scaled (shared: the views of
    /// one render all take it).
    pub environment: Option<Arc<Environment>>,
    /// `--env-rotation` in degrees, applied to the built-in studio environment.
    pub studio_rotation_degrees: f32,
    /// `--env-intensity`, applied to the built-in studio environment.
    pub studio_intensity: f32,
}

impl LightingOptions {
    /// The lighting options of `integrator` with no option given.
    pub fn new(integrator: IntegratorKind) -> LightingOptions {
        LightingOptions {
            integrator,
            no_default_lights: false,
            environment: None,
            studio_rotation_degrees: 0.0,
            studio_intensity: 1.0,
        }
    }
}

/// Lighting recorded in a view file (`--view`): used as it is.
#[derive(Clone, Debug)]
pub struct RecordedLighting {
    /// The lights, in world space.
    pub lights: Vec<Light>,
    /// The ambient factor.
    pub ambient: Vec3,
    /// The environment the recorded render was lit by, if any.
    pub environment: Option<Environment>,
}

/// A view's lighting, as [`lighting`] decides it.
#[derive(Clone, Debug)]
pub struct Lighting {
    /// Punctual lights.
    pub lights: Vec<Light>,
    /// The ambient factor that goes with them (the caller's `--ambient` overrides it).
    pub ambient: Vec3,
    /// The environment (path tracer).
    pub environment: Option<Arc<Environment>>,
    /// Whether `lights` is the default rig.
    pub default_rig: bool,
}

/// The one lighting policy, used by every command and by [`default_settings`]:
/// - a view file's recorded lights and ambient are used as they are;
/// - else the file's lights, with [`AMBIENT_WITH_FILE_LIGHTS`];
/// - else, for the direct integrator, the default rig placed for `rig_view` (the view itself,
///   or for many views one camera they share, so lights stay put from view to view);
/// - else (path tracer, or `--no-default-lights`) no punctual light and no ambient.
///
/// The environment is `--env`; else, for the path tracer, the view file's recorded one; else,
/// for the path tracer of a file without lights, the built-in studio environment (turned and
/// scaled by the options); else none.
pub fn lighting(
    scene_lights: &[Light],
    recorded: Option<RecordedLighting>,
    rig_view: &View,
    options: LightingOptions,
) -> Lighting {
    let path_tracing = options.integrator == IntegratorKind::Path;
    let default_rig_wanted = !options.no_default_lights && scene_lights.is_empty();
    let default_rig = recorded.is_none() && default_rig_wanted && !path_tracing;
    let studio = recorded.is_none() && default_rig_wanted && path_tracing;
    let (lights, ambient, recorded_environment) = match recorded {
        Some(r) => (r.lights, r.ambient, r.environment),
        None if !scene_lights.is_empty() => (
            scene_lights.to_vec(),
            Vec3::splat(AMBIENT_WITH_FILE_LIGHTS),
            None,
        ),
        None if default_rig => {
            let (lights, ambient) = self::default_rig(rig_view);
            (lights, ambient, None)
        }
        None => (Vec::new(), Vec3::ZERO, None),
    };
    let recorded_environment = recorded_environment.filter(|_| path_tracing);
    let environment = match options.environment {
        Some(env) => Some(env),
        None => match recorded_environment {
            Some(env) => Some(Arc::new(env)),
            None if studio => Some(Arc::new(
                Environment::studio()
                    .with_transform(options.studio_rotation_degrees, options.studio_intensity),
            )),
            None => None,
        },
    };
    Lighting {
        lights,
        ambient,
        environment,
        default_rig,
    }
}

/// The view transform of the default render's 8-bit outputs (`--tonemap`): Khronos PBR
/// Neutral keeps authored base colours as they are below its knee and rolls highlights off,
/// as glTF viewers show them. (A view file without a `display` record was encoded with
/// [`ViewTransform::default`], the clipping `standard`.)
pub const DEFAULT_VIEW_TRANSFORM: ViewTransform = ViewTransform::KhronosPbrNeutral;

/// The samples per pixel and the adaptive noise target (`None`: fixed spp) of a render given
/// samples (`--spp`, if given) and `noise` (`--noise`) with `integrator`, with
/// `time_limited` when a time budget picks the count, and `denoised` when the image will be
/// denoised: `spp` is exact when given; else the path tracer takes up to [`DEFAULT_PATH_SPP`]
/// adaptively to [`DEFAULT_NOISE`], or to [`DEFAULT_DENOISED_NOISE`] when denoised (unless a
/// time budget decides), the direct integrator [`DEFAULT_SPP`]. The CLI and the Python
/// package both decide this way.
pub fn sampling(
    integrator: IntegratorKind,
    spp: Option<u32>,
    noise: Option<f32>,
    time_limited: bool,
    denoised: bool,
) -> (u32, Option<f32>) {
    let default_noise = if denoised {
        DEFAULT_DENOISED_NOISE
    } else {
        DEFAULT_NOISE
    };
    match (spp, integrator) {
        (Some(spp), _) => (spp, noise),
        (None, IntegratorKind::Direct) => (DEFAULT_SPP, noise),
        (None, IntegratorKind::Path) => (
            DEFAULT_PATH_SPP,
            noise.or((!time_limited).then_some(default_noise)),
        ),
    }
}

/// Whether a render that neither asks for denoising nor refuses it (`--denoise`,
/// `--no-denoise`) is denoised: the default render is, that is the path tracer with its
/// default sampling (no `--spp`, `--noise` or time budget) making one whole image
/// (`single_image`: not several views, which are denoised only when asked, nor a tile or a
/// crop, which the filter does not handle). Asking for a sampling is asking for exactly that
/// image.
pub fn denoises_by_default(
    integrator: IntegratorKind,
    spp: Option<u32>,
    noise: Option<f32>,
    time_limited: bool,
    single_image: bool,
) -> bool {
    integrator == IntegratorKind::Path
        && spp.is_none()
        && noise.is_none()
        && !time_limited
        && single_image
}

/// The default render of `scene` at `width` x `height`: its first camera (else the automatic
/// one framing its vertices), the path tracer lit by the file's lights (else the built-in
/// studio environment), up to [`DEFAULT_PATH_SPP`] samples per pixel taken adaptively until
/// the noise is under [`DEFAULT_NOISE`], [`DEFAULT_BOUNCES`] bounces, seed 0, the glTF BRDF, no
/// exposure change, no AOVs. What `meshtracer render MODEL` does with no options (which then
/// encodes the image with the Khronos PBR Neutral view transform).
pub fn default_settings(scene: &Scene, width: u32, height: u32) -> RenderSettings {
    let aspect = width as f32 / height.max(1) as f32;
    let camera = scene
        .cameras
        .first()
        .cloned()
        .unwrap_or_else(|| auto_camera(&scene.bounds, &scene.soup.positions, aspect));
    let view = View::from_camera(&camera, width, height);
    let lighting = lighting(
        &scene.lights,
        None,
        &view,
        LightingOptions::new(IntegratorKind::Path),
    );
    RenderSettings {
        view,
        spp: DEFAULT_PATH_SPP,
        seed: 0,
        lights: lighting.lights,
        ambient: lighting.ambient,
        exposure: 0.0,
        shading: ShadingModel::Pbr,
        aovs: false,
        integrator: IntegratorKind::Path,
        bounces: DEFAULT_BOUNCES,
        environment: lighting.environment,
        environment_visible: false,
        noise: Some(DEFAULT_NOISE),
        clamp_indirect: None,
        guides: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::BvhPreset;

    /// An adaptive render counts twice the first batch of samples, not its cap, so `auto`
    /// builds the quick BVH for a million triangles at 640x480 (MetalRoughSpheresNoTextures'
    /// default render: the medium build was half its time) and the medium one for the bunny's
    /// 69k; a fixed `--spp` counts every sample.
    #[test]
    fn an_adaptive_render_expects_its_first_samples_not_its_cap() {
        use crate::render::ADAPTIVE_BATCH;
        let pixels = 640 * 480;
        let path = |batch| expected_rays(pixels, 32, batch, 0, IntegratorKind::Path, 8);
        assert_eq!(path(Some(ADAPTIVE_BATCH)), path(None) / 4.0);
        let auto = |triangles| BvhPreset::Auto.for_work(triangles, path(Some(ADAPTIVE_BATCH)));
        assert_eq!(auto(1_040_213), BvhPreset::VeryFast);
        assert_eq!(auto(69_451), BvhPreset::Medium);
        // Below the batch the cap still counts.
        let two = expected_rays(pixels, 2, Some(ADAPTIVE_BATCH), 0, IntegratorKind::Path, 8);
        assert_eq!(two, path(None) / 16.0);
    }

    /// The denoised default takes its first batch of two samples a pixel, so the default
    /// render of a million triangles at 1024x768 (the CLI's default size) expects the quick
    /// build; counting the undenoised batch of four, it built the medium tree, 0.65 s of a
    /// 1.5 s run for MetalRoughSpheresNoTextures.
    #[test]
    fn the_denoised_default_expects_its_two_samples() {
        use crate::render::{ADAPTIVE_BATCH, DENOISED_BATCH};
        let pixels = 1024 * 768;
        let rays = |batch| expected_rays(pixels, 32, Some(batch), 0, IntegratorKind::Path, 8);
        assert_eq!(rays(DENOISED_BATCH), rays(ADAPTIVE_BATCH) / 2.0);
        let auto = |batch| BvhPreset::Auto.for_work(1_040_213, rays(batch));
        assert_eq!(auto(DENOISED_BATCH), BvhPreset::VeryFast);
        assert_eq!(auto(ADAPTIVE_BATCH), BvhPreset::Medium);
    }
}
