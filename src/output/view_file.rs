//! The view as data: the camera and lights a render actually used, as JSON that
//! `render --view` reads back and the reference scripts (pyrender, Blender) read to render the
//! same view. The schema is documented in the README.
//!
//! Units are glTF's: metres, radians, candela (point, spot), lux (directional). Directions are
//! unit vectors in world space; a light's `direction` is the way its light travels.

use crate::camera::ThinLens;
use crate::integrator::IntegratorKind;
use crate::light::environment::{Environment, EnvironmentSource};
use crate::scene::{Camera, Light, LightKind, Projection};
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Version of the schema written in `meshtracer_view`.
pub const VIEW_VERSION: u32 = 1;

/// Image size (of a view, and of the whole image in a tile's sidecar).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ImageSize {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

/// The camera, as a look-at frame plus projection.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewCamera {
    /// `perspective` or `orthographic`.
    #[serde(rename = "type")]
    pub kind: String,
    /// Eye position.
    pub position: [f32; 3],
    /// A point on the view axis, one unit ahead.
    pub look_at: [f32; 3],
    /// Up vector, orthogonal to the view axis: the camera's own, exactly.
    pub up: [f32; 3],
    /// The unit view direction exactly as rendered (`look_at - position` rounds it in f32).
    /// Used when it agrees with `look_at` (see [`BASIS_AGREEMENT`]); files written before it
    /// was recorded, and an edited `look_at`, give the direction from `look_at`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forward: Option<[f32; 3]>,
    /// Vertical field of view in radians (perspective).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub yfov: Option<f32>,
    /// Half height of the view volume (orthographic).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ymag: Option<f32>,
    /// Half width of the view volume as rendered, `ymag · aspect` (orthographic).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub xmag: Option<f32>,
    /// Width / height of the image.
    pub aspect: f32,
    /// Near clip distance along the view axis.
    pub znear: f32,
    /// Far clip distance; null for infinite.
    pub zfar: Option<f32>,
    /// Depth of field: the thin lens's aperture radius in scene units (absent: a pinhole).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aperture_radius: Option<f32>,
    /// With `aperture_radius`: the distance of the plane in focus along the view axis.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub focus_distance: Option<f32>,
}

/// One light, in glTF units.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewLight {
    /// `point`, `spot` or `directional`.
    #[serde(rename = "type")]
    pub kind: String,
    /// Name, if any.
    #[serde(default)]
    pub name: Option<String>,
    /// World position (ignored for directional lights).
    pub position: [f32; 3],
    /// Direction the light travels.
    pub direction: [f32; 3],
    /// Linear RGB colour.
    pub color: [f32; 3],
    /// Candela (point, spot) or lux (directional).
    pub intensity: f32,
    /// Range, or null for infinite.
    #[serde(default)]
    pub range: Option<f32>,
    /// Spot inner cone angle in radians.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inner_cone_angle: Option<f32>,
    /// Spot outer cone angle in radians.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub outer_cone_angle: Option<f32>,
}

/// Everything needed to render the same view again, here or in another renderer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewFile {
    /// Schema version ([`VIEW_VERSION`]).
    pub meshtracer_view: u32,
    /// Image size.
    pub image: ImageSize,
    /// The camera.
    pub camera: ViewCamera,
    /// Every light used, default rig included.
    pub lights: Vec<ViewLight>,
    /// Ambient radiance factor.
    pub ambient: [f32; 3],
    /// Whether the lights are meshtracer's default rig rather than the file's.
    pub default_lights: bool,
    /// Metres per unit of a 16-bit PNG depth map.
    #[serde(default = "default_depth_scale")]
    pub depth_png_scale: f32,
    /// Segmentation ids: instance id -> glTF node and mesh (OBJ: object index as mesh).
    #[serde(default)]
    pub segmentation: Vec<SegmentId>,
    /// The integrator (files written before the path tracer: `direct`).
    #[serde(default)]
    pub integrator: IntegratorKind,
    /// Path tracer: most bounces after the first hit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bounces: Option<u32>,
    /// Path tracer: the clamp on a sample's indirect light (`--clamp-indirect`), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clamp_indirect: Option<f32>,
    /// Path tracer: the environment that lit the scene.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub environment: Option<ViewEnvironment>,
    /// `--denoise`: how the image was denoised (a record: rendering the view again does not
    /// denoise unless asked).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub denoise: Option<ViewDenoise>,
    /// How the 8-bit image was encoded from linear radiance (files written before view
    /// transforms: none, which is exposure 0 and `standard`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub display: Option<ViewDisplay>,
}

/// How a view's linear radiance became its 8-bit image: the exposure, then the view transform,
/// then the sRGB transfer curve (EXR and HDR outputs stay linear, before both).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewDisplay {
    /// Exposure in stops: radiance was multiplied by 2^exposure.
    pub exposure: f32,
    /// The view transform's name (`--tonemap`): "standard", "khronos-pbr-neutral", "agx" or
    /// "aces" ([`crate::color::ViewTransform::name`]).
    pub view_transform: String,
}

impl ViewDisplay {
    /// The record of `exposure` and `view`.
    pub fn new(exposure: f32, view: crate::color::ViewTransform) -> ViewDisplay {
        ViewDisplay {
            exposure,
            view_transform: view.name().to_string(),
        }
    }
}

/// How a view's image was denoised (`--denoise`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewDenoise {
    /// Who made the filter: "meshtracer" (the built-in one) or "Intel Open Image Denoise".
    pub denoiser: String,
    /// Its version: meshtracer's, or OIDN's as the library reports it ("2.5.1").
    pub version: String,
    /// The filter: "atrous" (the built-in edge-avoiding à-trous wavelets) or OIDN's "RT"
    /// (ray-traced images).
    pub filter: String,
    /// Whether the filter ran on the linear HDR film (always, before any encoding).
    pub hdr: bool,
    /// The guide images given to the filter, in order.
    pub guides: Vec<String>,
    /// Rays a pixel traced for the guides (a jittered grid of first hits).
    pub guide_samples_per_pixel: u32,
    /// Whether the guides are noise-free, so the filter trusts them (OIDN's `cleanAux`; the
    /// built-in filter always does).
    pub clean_aux: bool,
}

/// Most bounces a view file may ask for (as `--bounces`).
pub const MAX_VIEW_BOUNCES: u32 = 1024;

/// The environment of a path-traced view: enough to light another renderer identically.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewEnvironment {
    /// The panorama file, or the built-in studio with its parameters.
    pub source: EnvironmentSource,
    /// Rotation about +Y in degrees (counter-clockwise seen from above).
    pub rotation_degrees: f32,
    /// Radiance multiplier.
    pub intensity: f32,
    /// Whether camera rays that miss showed it.
    pub visible: bool,
    /// The panorama as used (rotation and intensity applied), where `--env-out` wrote one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub panorama: Option<std::path::PathBuf>,
}

impl ViewEnvironment {
    /// The environment this record describes (a file is read again).
    pub fn load(&self) -> Result<Environment, crate::light::environment::EnvironmentError> {
        let base = match &self.source {
            EnvironmentSource::File { path } => Environment::load(path)?,
            EnvironmentSource::Studio { .. } => Environment::studio(),
            EnvironmentSource::Uniform { radiance } => Environment::uniform(Vec3::from(*radiance)),
        };
        Ok(base.with_transform(self.rotation_degrees, self.intensity))
    }
}

fn default_depth_scale() -> f32 {
    0.001
}

/// A key of a JSON document as a path from the top: `camera.yfvo`, `lights[1].colour`
/// (serde_ignored's own form writes `Option` levels as `?`).
fn key_path(key: &serde_ignored::Path) -> String {
    use serde_ignored::Path;
    match key {
        Path::Root => String::new(),
        Path::Seq { parent, index } => format!("{}[{index}]", key_path(parent)),
        Path::Map { parent, key } => match key_path(parent) {
            above if above.is_empty() => key.clone(),
            above => format!("{above}.{key}"),
        },
        Path::Some { parent }
        | Path::NewtypeStruct { parent }
        | Path::NewtypeVariant { parent } => key_path(parent),
    }
}

/// The keys of the environment's `source` object in `text` that its type does not have
/// (`{"type": "uniform", "radiance": [1, 1, 1], "intesity": 2}`), as paths from the top
/// (`environment.source.intesity`), in the order of their names. The source is a tagged enum,
/// which serde reads through a buffer of its own, so `serde_ignored` never sees its keys: they
/// are found here instead, as those that the source parsed from `text` does not write back.
fn unknown_source_keys(text: &str, view: &ViewFile) -> Vec<String> {
    let Some(environment) = &view.environment else {
        return Vec::new();
    };
    let (Ok(known), Ok(file)) = (
        serde_json::to_value(&environment.source),
        serde_json::from_str::<serde_json::Value>(text),
    ) else {
        return Vec::new();
    };
    let Some(given) = file["environment"]["source"].as_object() else {
        return Vec::new();
    };
    given
        .keys()
        .filter(|key| known.get(key.as_str()).is_none())
        .map(|key| format!("environment.source.{key}"))
        .collect()
}

/// One id of the segmentation AOV.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SegmentId {
    /// The id in the segmentation image (0 is background).
    pub id: u32,
    /// glTF node index.
    pub node: Option<usize>,
    /// glTF mesh index, or OBJ object index.
    pub mesh: usize,
    /// Node or object name.
    pub name: Option<String>,
}

/// Why a view file was refused.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {problem}")]
pub struct ViewError {
    path: String,
    problem: String,
}

impl ViewFile {
    /// The view of a render.
    pub fn new(
        camera: &Camera,
        width: u32,
        height: u32,
        lights: &[Light],
        ambient: Vec3,
        default_lights: bool,
    ) -> ViewFile {
        let aspect = width as f32 / height as f32;
        let (kind, yfov, xmag, ymag, znear, zfar) = match camera.projection {
            Projection::Perspective {
                yfov, znear, zfar, ..
            } => ("perspective", Some(yfov), None, None, znear, zfar),
            Projection::Orthographic {
                ymag, znear, zfar, ..
            } => (
                "orthographic",
                None,
                Some(ymag * aspect),
                Some(ymag),
                znear,
                Some(zfar),
            ),
        };
        ViewFile {
            meshtracer_view: VIEW_VERSION,
            image: ImageSize { width, height },
            camera: ViewCamera {
                kind: kind.into(),
                position: camera.position.to_array(),
                look_at: (camera.position + camera.forward * look_at_reach(camera.position))
                    .to_array(),
                up: camera.up.to_array(),
                forward: Some(camera.forward.to_array()),
                yfov,
                xmag,
                ymag,
                aspect,
                znear,
                zfar: zfar.filter(|z| z.is_finite()),
                aperture_radius: None,
                focus_distance: None,
            },
            lights: lights.iter().map(view_light).collect(),
            ambient: ambient.to_array(),
            default_lights,
            depth_png_scale: default_depth_scale(),
            segmentation: Vec::new(),
            integrator: IntegratorKind::Direct,
            bounces: None,
            clamp_indirect: None,
            environment: None,
            denoise: None,
            display: None,
        }
    }

    /// Reads and checks a view file, with the keys it holds that no view file has
    /// ([`ViewFile::parse`]).
    pub fn read(path: &Path) -> Result<(ViewFile, Vec<String>), ViewError> {
        let text = std::fs::read_to_string(path).map_err(|e| ViewError {
            path: path.display().to_string(),
            problem: e.to_string(),
        })?;
        ViewFile::parse(&text, path)
    }

    /// Parses and checks the text of a view file; `path` names it in errors. Keys that no view
    /// file has are ignored ([`ViewFile::parse`] lists them).
    pub fn from_json(text: &str, path: &Path) -> Result<ViewFile, ViewError> {
        ViewFile::parse(text, path).map(|(view, _)| view)
    }

    /// Parses and checks the text of a view file (`path` names it in errors), and lists the
    /// keys that no view file has, in file order, as paths from the top (`camera.yfvo`,
    /// `lights[1].colour`): a misspelt key would otherwise be dropped unseen, and the render
    /// made without it. Those inside an environment's `source` come last, in the order of
    /// their names (`unknown_source_keys`).
    pub fn parse(text: &str, path: &Path) -> Result<(ViewFile, Vec<String>), ViewError> {
        let mut unknown = Vec::new();
        let mut json = serde_json::Deserializer::from_str(text);
        let view = serde_ignored::deserialize(&mut json, |key| unknown.push(key_path(&key)))
            .and_then(|view| json.end().map(|()| view));
        if let Ok(view) = &view {
            unknown.extend(unknown_source_keys(text, view));
        }
        // A refusal names the unknown keys too: a misspelt key ("yfvo") is often why the
        // field the refusal is about is missing.
        let err = |problem: String| ViewError {
            path: path.display().to_string(),
            problem: match unknown.as_slice() {
                [] => problem,
                keys => format!(
                    "{problem} (unknown key{} '{}': misspelt?)",
                    if keys.len() == 1 { "" } else { "s" },
                    keys.join("', '")
                ),
            },
        };
        let view: ViewFile = view.map_err(|e| err(format!("not a meshtracer view: {e}")))?;
        if view.meshtracer_view != VIEW_VERSION {
            return Err(err(format!(
                "view version {} (this meshtracer reads {VIEW_VERSION})",
                view.meshtracer_view
            )));
        }
        let finite = |v: [f32; 3]| v.iter().all(|x| x.is_finite());
        if !(finite(view.camera.position) && finite(view.camera.look_at) && finite(view.camera.up))
        {
            return Err(err("camera vectors must be finite".into()));
        }
        if view.image.width == 0 || view.image.height == 0 {
            return Err(err("image width and height must be at least 1".into()));
        }
        view.camera.to_camera().map_err(err)?;
        view.camera.thin_lens().map_err(err)?;
        for l in &view.lights {
            to_light(l).map_err(err)?;
        }
        if let Some(env) = &view.environment {
            if !(env.intensity.is_finite() && env.intensity >= 0.0) {
                return Err(err(format!(
                    "environment intensity {}: must be a finite number, 0 or more",
                    env.intensity
                )));
            }
            if !env.rotation_degrees.is_finite() {
                return Err(err("environment rotation must be a finite number".into()));
            }
            if let EnvironmentSource::Uniform { radiance } = env.source {
                if !radiance.iter().all(|c| c.is_finite() && *c >= 0.0) {
                    return Err(err(
                        "uniform environment radiance must be finite, 0 or more".into(),
                    ));
                }
            }
        }
        if view.bounces.is_some_and(|b| b > MAX_VIEW_BOUNCES) {
            return Err(err(format!("bounces: at most {MAX_VIEW_BOUNCES}")));
        }
        Ok((view, unknown))
    }

    /// The camera this view describes.
    pub fn camera(&self) -> Result<Camera, ViewError> {
        self.camera.to_camera().map_err(|problem| ViewError {
            path: "view".into(),
            problem,
        })
    }

    /// The lights this view describes.
    pub fn lights(&self) -> Vec<Light> {
        self.lights
            .iter()
            .filter_map(|l| to_light(l).ok())
            .collect()
    }

    /// The view as the pretty JSON text [`ViewFile::write`] writes.
    pub fn to_json(&self) -> String {
        let mut text = serde_json::to_string_pretty(self).unwrap_or_default();
        text.push('\n');
        text
    }

    /// Writes the view as pretty JSON, atomically.
    pub fn write(&self, path: &Path) -> Result<(), crate::output::SaveError> {
        crate::output::write_atomic(path, self.to_json().as_bytes())
    }
}

impl ViewCamera {
    /// The thin lens this record describes (`None`: a pinhole), or what is wrong with it.
    pub fn thin_lens(&self) -> Result<Option<ThinLens>, String> {
        match (self.aperture_radius, self.focus_distance) {
            (None, None) => Ok(None),
            (Some(r), Some(f)) if r.is_finite() && r >= 0.0 && f.is_finite() && f > 0.0 => {
                Ok((r > 0.0).then_some(ThinLens {
                    aperture_radius: r,
                    focus_distance: f,
                }))
            }
            (Some(_), Some(_)) => Err("aperture_radius must be a finite number, 0 or more, and \
                focus_distance a finite number above 0"
                .into()),
            _ => Err("aperture_radius and focus_distance go together".into()),
        }
    }

    /// This record with `lens` (`None`: a pinhole).
    pub fn set_thin_lens(&mut self, lens: Option<ThinLens>) {
        self.aperture_radius = lens.map(|l| l.aperture_radius);
        self.focus_distance = lens.map(|l| l.focus_distance);
    }

    /// The camera this record describes, or what is wrong with it.
    pub fn to_camera(&self) -> Result<Camera, String> {
        let c = self;
        let err = |problem: &str| problem.to_string();
        let finite = |v: [f32; 3]| v.iter().all(|x| x.is_finite());
        if !(finite(c.position) && finite(c.look_at) && finite(c.up)) {
            return Err(err("camera vectors must be finite"));
        }
        if !(c.znear.is_finite() && c.znear >= 0.0) || c.zfar.is_some_and(f32::is_nan) {
            return Err(err(
                "znear must be a finite number, 0 or more, and zfar a number",
            ));
        }
        let position = Vec3::from(c.position);
        let aimed = (Vec3::from(c.look_at) - position)
            .try_normalize()
            .ok_or_else(|| err("look_at equals position"))?;
        // `look_at` holds the direction only to the rounding of coordinates as large as the
        // position's and its own: a unit in the last place of each, over their distance.
        let look_at = Vec3::from(c.look_at);
        let look_at_rounding = 4.0 * f32::EPSILON * position.abs().max(look_at.abs()).max_element()
            / (look_at - position).length();
        let forward = exact_or(
            c.forward.map(Vec3::from),
            aimed,
            BASIS_AGREEMENT + look_at_rounding,
        );
        let up = Vec3::from(c.up);
        let orthonormal = (up - forward * up.dot(forward))
            .try_normalize()
            .ok_or_else(|| err("up is parallel to the view direction"))?;
        let up = exact_or(Some(up), orthonormal, BASIS_AGREEMENT);
        let projection = match c.kind.as_str() {
            "perspective" => Projection::Perspective {
                yfov: c
                    .yfov
                    .filter(|y| *y > 0.0 && *y < std::f32::consts::PI)
                    .ok_or_else(|| err("perspective camera needs yfov in (0, π)"))?,
                aspect_ratio: Some(c.aspect),
                znear: c.znear,
                zfar: c.zfar,
            },
            "orthographic" => Projection::Orthographic {
                xmag: c.xmag.unwrap_or(1.0),
                ymag: c
                    .ymag
                    .filter(|m| *m > 0.0)
                    .ok_or_else(|| err("orthographic camera needs ymag > 0"))?,
                znear: c.znear,
                zfar: c.zfar.unwrap_or(f32::INFINITY),
            },
            other => return Err(err(&format!("unknown camera type '{other}'"))),
        };
        Ok(Camera {
            name: Some("view".into()),
            position,
            forward,
            up,
            projection,
        })
    }
}

/// How far ahead of `position` a view file's `look_at` is written: one unit, as always, for
/// a camera within 65536 of the origin; as far as its largest coordinate beyond, so that
/// `look_at` still differs from the position in f32 (at 1e10 a unit step rounds away).
fn look_at_reach(position: Vec3) -> f32 {
    let far = position.abs().max_element();
    if far < 65536.0 {
        1.0
    } else {
        far
    }
}

/// How far (in each component) a stored unit vector may be from the one rebuilt from the
/// view's other fields and still be used as stored: rounding in f32 moves the rebuilt one by a
/// few 1e-7 (a unit `up` against its re-orthonormalised copy, a light's direction against its
/// normalised copy), while any edit a person makes moves it far more. The view direction
/// against `look_at - position` is allowed the rounding of the position's coordinates too.
pub const BASIS_AGREEMENT: f32 = 1e-5;

/// `stored` when it is within `tolerance` of `rebuilt` in each component (so the camera that
/// was rendered comes back bit for bit), else `rebuilt`.
fn exact_or(stored: Option<Vec3>, rebuilt: Vec3, tolerance: f32) -> Vec3 {
    stored
        .filter(|v| v.abs_diff_eq(rebuilt, tolerance))
        .unwrap_or(rebuilt)
}

fn view_light(l: &Light) -> ViewLight {
    let (kind, inner, outer) = match l.kind {
        LightKind::Point => ("point", None, None),
        LightKind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        } => ("spot", Some(inner_cone_angle), Some(outer_cone_angle)),
        LightKind::Directional => ("directional", None, None),
    };
    ViewLight {
        kind: kind.into(),
        name: l.name.clone(),
        position: l.position.to_array(),
        direction: l.direction.to_array(),
        color: l.color.to_array(),
        intensity: l.intensity,
        range: l.range,
        inner_cone_angle: inner,
        outer_cone_angle: outer,
    }
}

fn to_light(l: &ViewLight) -> Result<Light, String> {
    let kind = match l.kind.as_str() {
        "point" => LightKind::Point,
        "directional" => LightKind::Directional,
        "spot" => {
            let inner = l.inner_cone_angle.unwrap_or(0.0);
            let outer = l.outer_cone_angle.unwrap_or(std::f32::consts::FRAC_PI_4);
            // KHR_lights_punctual's ranges, as the importer holds a file's lights to them.
            if !(0.0 <= inner && inner < outer && outer <= std::f32::consts::FRAC_PI_2) {
                return Err(format!(
                    "spot light cones {inner}..{outer} rad: need 0 <= inner < outer <= π/2"
                ));
            }
            LightKind::Spot {
                inner_cone_angle: inner,
                outer_cone_angle: outer,
            }
        }
        other => return Err(format!("unknown light type '{other}'")),
    };
    let stored = Vec3::from(l.direction);
    let unit = stored
        .try_normalize()
        .ok_or_else(|| "a light direction is zero or not finite".to_string())?;
    let direction = exact_or(Some(stored), unit, BASIS_AGREEMENT);
    let valid = l.intensity.is_finite()
        && l.intensity >= 0.0
        && Vec3::from(l.position).is_finite()
        && Vec3::from(l.color).is_finite()
        && Vec3::from(l.color).min_element() >= 0.0;
    if !valid {
        return Err("a light has a non-finite or negative value".into());
    }
    Ok(Light {
        name: l.name.clone(),
        kind,
        color: Vec3::from(l.color),
        intensity: l.intensity,
        // A non-positive or non-finite range means no range window, as in the importer.
        range: l.range.filter(|r| *r > 0.0 && r.is_finite()),
        position: Vec3::from(l.position),
        direction,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Bounds;

    /// The automatic camera of a 2 m cube at the origin, for a 4:3 image.
    fn framing_camera() -> Camera {
        let bounds = Bounds {
            min: Vec3::splat(-1.0),
            max: Vec3::splat(1.0),
        };
        crate::camera::auto_camera(&bounds, &[], 4.0 / 3.0)
    }

    /// A spot light at the origin shining down -Z, its cones 0.2 and 0.4 rad.
    fn spot_light() -> Light {
        Light {
            name: None,
            kind: LightKind::Spot {
                inner_cone_angle: 0.2,
                outer_cone_angle: 0.4,
            },
            color: Vec3::ONE,
            intensity: 2.0,
            range: None,
            position: Vec3::ZERO,
            direction: Vec3::NEG_Z,
        }
    }

    /// A camera written to a view file and read back is the same camera, bit for bit: from
    /// quaternion rotations (as TRS nodes and matrices give) and from the automatic camera,
    /// over many directions; so are the lights' directions. A file without `forward` (written
    /// before it was recorded) still reads, and an edited `look_at` moves the camera.
    #[test]
    fn cameras_and_lights_come_back_exactly() {
        use glam::Quat;
        let path = Path::new("view.json");
        let mut cameras = Vec::new();
        for k in 0..200 {
            let t = k as f32;
            let rotation =
                Quat::from_euler(glam::EulerRot::YXZ, t * 0.731, (t * 0.377).sin(), t * 0.013);
            cameras.push(Camera {
                name: None,
                position: Vec3::new(t.sin() * 3.1, 0.7 + t * 0.01, t.cos() * 2.3),
                forward: rotation * Vec3::NEG_Z,
                up: rotation * Vec3::Y,
                projection: Projection::Perspective {
                    yfov: 0.6,
                    aspect_ratio: None,
                    znear: 0.01,
                    zfar: None,
                },
            });
            let bounds = Bounds {
                min: Vec3::new(-t * 0.37, -1.3, -0.2 * t),
                max: Vec3::new(1.0 + t, 2.9, 0.5 + t * 0.11),
            };
            cameras.push(crate::camera::auto_camera(&bounds, &[], 4.0 / 3.0));
            // Far from the origin, where a unit step ahead rounds away in f32.
            cameras.push(Camera {
                position: Vec3::new(1e10, t * 1e7, -3e9),
                ..cameras[cameras.len() - 2].clone()
            });
        }
        let light = |direction: Vec3| Light {
            name: None,
            kind: LightKind::Directional,
            color: Vec3::ONE,
            intensity: 2.0,
            range: None,
            position: Vec3::ZERO,
            direction,
        };
        for camera in &cameras {
            let lights = [light(-camera.forward), light(camera.up)];
            let view = ViewFile::new(camera, 64, 48, &lights, Vec3::splat(0.1), true);
            let read = ViewFile::from_json(&view.to_json(), path).unwrap();
            let back = read.camera().unwrap();
            assert_eq!(
                (back.position, back.forward, back.up),
                (camera.position, camera.forward, camera.up)
            );
            let directions: Vec<Vec3> = read.lights().iter().map(|l| l.direction).collect();
            assert_eq!(directions, [lights[0].direction, lights[1].direction]);
        }
        let mut old = ViewFile::new(&cameras[0], 64, 48, &[], Vec3::ZERO, true);
        old.camera.forward = None;
        let back = ViewFile::from_json(&old.to_json(), path).unwrap();
        let forward = back.camera().unwrap().forward;
        assert!(forward.abs_diff_eq(cameras[0].forward, 1e-6), "{forward}");
        let mut edited = ViewFile::new(&cameras[0], 64, 48, &[], Vec3::ZERO, true);
        edited.camera.look_at = (cameras[0].position + Vec3::X).to_array();
        assert_eq!(edited.camera().unwrap().forward, Vec3::X);
    }

    /// A view file someone edited is held to what a render needs: each refusal names the
    /// file (the camera's too), a light with a negative colour (it would take light away)
    /// and spot cones outside 0 <= inner < outer <= π/2 included.
    #[test]
    fn edited_views_are_refused_naming_the_file_and_the_fault() {
        let camera = framing_camera();
        let view = ViewFile::new(&camera, 64, 48, &[spot_light()], Vec3::ZERO, true);
        let path = Path::new("edited.json");
        assert!(ViewFile::from_json(&view.to_json(), path).is_ok());
        let refusal = |edit: &dyn Fn(&mut ViewFile)| {
            let mut edited = view.clone();
            edit(&mut edited);
            ViewFile::from_json(&edited.to_json(), path)
                .expect_err("an edited view")
                .to_string()
        };
        assert_eq!(
            refusal(&|v| v.camera.yfov = Some(0.0)),
            "edited.json: perspective camera needs yfov in (0, π)"
        );
        assert_eq!(
            refusal(&|v| v.lights[0].color = [-1.0, 0.5, 0.5]),
            "edited.json: a light has a non-finite or negative value"
        );
        for (inner, outer) in [(0.5, 0.4), (-0.1, 0.4), (0.2, 1.6)] {
            assert_eq!(
                refusal(&|v| {
                    v.lights[0].inner_cone_angle = Some(inner);
                    v.lights[0].outer_cone_angle = Some(outer);
                }),
                format!(
                    "edited.json: spot light cones {inner}..{outer} rad: need 0 <= inner < outer <= π/2"
                )
            );
        }
        // A thin lens: both keys or neither, a radius of 0 or more and a focus above 0.
        let lens = |r: Option<f32>, f: Option<f32>| {
            move |v: &mut ViewFile| {
                v.camera.aperture_radius = r;
                v.camera.focus_distance = f;
            }
        };
        assert_eq!(
            refusal(&lens(Some(0.1), None)),
            "edited.json: aperture_radius and focus_distance go together"
        );
        for (r, f) in [(-0.1, 2.0), (0.1, 0.0), (0.1, -1.0)] {
            assert_eq!(
                refusal(&lens(Some(r), Some(f))),
                "edited.json: aperture_radius must be a finite number, 0 or more, and \
                 focus_distance a finite number above 0"
            );
        }
        let mut through = view.clone();
        lens(Some(0.1), Some(2.0))(&mut through);
        let read = ViewFile::from_json(&through.to_json(), path).unwrap();
        assert_eq!(
            read.camera.thin_lens(),
            Ok(Some(ThinLens {
                aperture_radius: 0.1,
                focus_distance: 2.0
            }))
        );
    }

    /// Every key the writer writes, each optional record included, reads back as known; keys
    /// no view file has (misspelt ones, at any depth) are listed as paths, in file order, and
    /// the view is read as without them.
    #[test]
    fn keys_no_view_file_has_are_listed_with_their_place() {
        let camera = framing_camera();
        let spot = Light {
            name: Some("key".into()),
            range: Some(5.0),
            ..spot_light()
        };
        let mut full = ViewFile::new(&camera, 64, 48, &[spot], Vec3::ZERO, false);
        full.segmentation = vec![SegmentId {
            id: 1,
            node: Some(0),
            mesh: 0,
            name: Some("walls".into()),
        }];
        full.integrator = IntegratorKind::Path;
        full.bounces = Some(4);
        full.clamp_indirect = Some(10.0);
        full.environment = Some(ViewEnvironment {
            source: EnvironmentSource::Uniform { radiance: [1.0; 3] },
            rotation_degrees: 30.0,
            intensity: 2.0,
            visible: true,
            panorama: Some("env.hdr".into()),
        });
        full.denoise = Some(ViewDenoise {
            denoiser: "meshtracer".into(),
            version: "0.1.0".into(),
            filter: "atrous".into(),
            hdr: true,
            guides: vec!["albedo".into()],
            guide_samples_per_pixel: 4,
            clean_aux: true,
        });
        full.display = Some(ViewDisplay::new(0.5, crate::color::ViewTransform::Standard));
        let path = Path::new("view.json");
        let (read, unknown) = ViewFile::parse(&full.to_json(), path).unwrap();
        assert_eq!((read, unknown), (full.clone(), Vec::<String>::new()));

        let mut edited: serde_json::Value = serde_json::from_str(&full.to_json()).unwrap();
        edited["exposur"] = 1.into();
        edited["camera"]["yfvo"] = 0.5.into();
        edited["lights"][0]["colour"] = serde_json::json!([1, 0, 0]);
        edited["environment"]["rotaton"] = 90.into();
        // Inside the source: a typo, and a key of another type of source (a file's).
        edited["environment"]["source"]["radiance_"] = serde_json::json!([2, 2, 2]);
        edited["environment"]["source"]["path"] = "studio.hdr".into();
        let (read, unknown) = ViewFile::parse(&edited.to_string(), path).unwrap();
        assert_eq!(read, full);
        assert_eq!(
            unknown,
            [
                "camera.yfvo",
                "environment.rotaton",
                "exposur",
                "lights[0].colour",
                "environment.source.path",
                "environment.source.radiance_"
            ]
        );

        // The key misspelt in place of a required one: the refusal names it.
        let mut misspelt: serde_json::Value = serde_json::from_str(&full.to_json()).unwrap();
        let yfov = misspelt["camera"]["yfov"].take();
        misspelt["camera"]["yfvo"] = yfov;
        misspelt["camera"].as_object_mut().unwrap().remove("yfov");
        let refusal = ViewFile::parse(&misspelt.to_string(), path).unwrap_err();
        assert!(
            refusal.problem.contains("yfov") && refusal.problem.contains("'camera.yfvo'"),
            "{}",
            refusal.problem
        );
    }

    /// A denoised view's record survives writing and reading; a view file without one (every
    /// file written before `--denoise`) reads as not denoised.
    #[test]
    fn the_denoise_record_round_trips_and_is_optional() {
        let camera = framing_camera();
        let plain = ViewFile::new(&camera, 64, 48, &[], Vec3::splat(0.1), true);
        let path = Path::new("view.json");
        let read = ViewFile::from_json(&plain.to_json(), path).unwrap();
        assert_eq!(read.denoise, None);
        let mut denoised = plain.clone();
        denoised.denoise = Some(ViewDenoise {
            denoiser: "Intel Open Image Denoise".into(),
            version: "2.5.1".into(),
            filter: "RT".into(),
            hdr: true,
            guides: vec!["albedo".into(), "normal".into()],
            guide_samples_per_pixel: 16,
            clean_aux: true,
        });
        let text = denoised.to_json();
        assert!(text.contains("\"guide_samples_per_pixel\": 16"), "{text}");
        assert_eq!(ViewFile::from_json(&text, path).unwrap(), denoised);
    }
}
