//! Every default of a render in one named place: the CLI's `--help` prints these values, the
//! library uses them when the caller does not say otherwise, and `VIEW.json` records what was
//! actually used.

use crate::camera::{auto_camera, View};
use crate::render::RenderSettings;
use crate::scene::{Light, LightKind, Scene};
use crate::shading::ShadingModel;
use glam::Vec3;

/// `--bvh-preset auto`: rays a triangle above which the `medium` BVH preset's longer build
/// pays for itself, and below which `very-fast` is chosen. Measured on
/// MetalRoughSpheresNoTextures (1.04M triangles, 2 threads): medium builds in about 0.25 µs a
/// triangle more than very-fast (0.90 s against 0.65 s) and traces at most 3-4% faster
/// (primary 5.06 against 4.89 Mrays/s; diffuse within noise), which repays the build after
/// about 0.25 µs / (0.035 × 0.28 µs a ray) ≈ 25 rays a triangle; 32 leaves some margin.
pub const AUTO_PRESET_RAYS_PER_TRIANGLE: f64 = 32.0;

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

/// Most bounces of a path after the first hit (`--bounces`): Cycles' default total of 12 less
/// what our scenes need; interiors converge to within 1% by 8 on the Cornell box.
pub const DEFAULT_BOUNCES: u32 = 8;

/// Samples per pixel when none is given.
pub const DEFAULT_SPP: u32 = 4;

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
