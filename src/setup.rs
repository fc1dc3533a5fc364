//! Options to render settings: the default light rig and the default render of a scene. The
//! values themselves are named in [`crate::defaults`].

use crate::camera::{auto_camera, View};
use crate::defaults::{
    AMBIENT_WITH_DEFAULT_RIG, AMBIENT_WITH_FILE_LIGHTS, DEFAULT_BOUNCES, DEFAULT_SPP,
    FILL_LIGHT_LUX, KEY_LIGHT_LUX,
};
use crate::render::RenderSettings;
use crate::scene::{Light, LightKind, Scene};
use crate::shading::ShadingModel;
use glam::Vec3;

/// About how many rays a render traces: a camera ray per sample, one shadow ray per light at
/// each hit and, for the path tracer, about two rays (a bounce and a light sample) for each of
/// the first few bounces (Russian roulette and escaping paths end most paths by then).
pub fn expected_rays(
    pixels: u64,
    spp: u32,
    lights: usize,
    integrator: crate::integrator::IntegratorKind,
    bounces: u32,
) -> f64 {
    let samples = pixels as f64 * f64::from(spp.max(1));
    match integrator {
        crate::integrator::IntegratorKind::Direct => samples * (1 + lights) as f64,
        crate::integrator::IntegratorKind::Path => {
            samples * (1.0 + 2.0 * f64::from(bounces.min(3)))
        }
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

/// The default render of `scene` at `width` x `height`: its first camera (else the automatic
/// one framing its bounds), its lights with [`AMBIENT_WITH_FILE_LIGHTS`] (else the default
/// rig), [`DEFAULT_SPP`] samples per pixel, seed 0, the glTF BRDF, no exposure change, no AOVs.
/// What `meshtracer render MODEL` does with no options.
pub fn default_settings(scene: &Scene, width: u32, height: u32) -> RenderSettings {
    let aspect = width as f32 / height.max(1) as f32;
    let camera = scene
        .cameras
        .first()
        .cloned()
        .unwrap_or_else(|| auto_camera(&scene.bounds, aspect));
    let view = View::from_camera(&camera, width, height);
    let (lights, ambient) = if scene.lights.is_empty() {
        default_rig(&view)
    } else {
        (scene.lights.clone(), Vec3::splat(AMBIENT_WITH_FILE_LIGHTS))
    };
    RenderSettings {
        view,
        spp: DEFAULT_SPP,
        seed: 0,
        lights,
        ambient,
        exposure: 0.0,
        shading: ShadingModel::Pbr,
        aovs: false,
        integrator: crate::integrator::IntegratorKind::Direct,
        bounces: DEFAULT_BOUNCES,
        environment: None,
        environment_visible: false,
    }
}
