//! Python values to the library's scene parts: NumPy rows to [`MeshArrays`], a material dict to
//! a [`Material`], a 4x4 pose to a [`Mat4`], and the keyword arguments of cameras and lights.
//! Everything here only converts and names what it refuses; the checks of the values
//! themselves are the library's ([`meshtracer::Scene::add_mesh`]).

use crate::Error;
use glam::{Mat4, Vec3, Vec4};
use meshtracer::scene::{
    AlphaMode, AnisotropyLayer, ClearcoatLayer, DiffuseTransmissionLayer, Filter, IridescenceLayer,
    LightKind, Material, Sampler, SheenLayer, SpecularLayer, TextureRef, TextureTransform, Wrap,
};
use numpy::{PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The rows of a C-contiguous float32 N x `W` array (the Python side converts and checks the
/// shape first), as glam vectors.
pub fn rows<'a, T: bytemuck::Pod, const W: usize>(
    name: &str,
    array: &'a PyReadonlyArray2<'_, f32>,
) -> PyResult<&'a [T]> {
    if array.shape()[1] != W {
        return Err(Error::new_err(format!(
            "{name}: shape {:?}, expected (N, {W})",
            array.shape()
        )));
    }
    let flat = array
        .as_slice()
        .map_err(|_| Error::new_err(format!("{name}: not a contiguous array")))?;
    Ok(bytemuck::cast_slice(flat))
}

/// The triangles of a C-contiguous uint32 M x 3 array.
pub fn triangles<'a>(array: &'a PyReadonlyArray2<'_, u32>) -> PyResult<&'a [[u32; 3]]> {
    if array.shape()[1] != 3 {
        return Err(Error::new_err(format!(
            "indices: shape {:?}, expected (M, 3)",
            array.shape()
        )));
    }
    let flat = array
        .as_slice()
        .map_err(|_| Error::new_err("indices: not a contiguous array"))?;
    Ok(bytemuck::cast_slice(flat))
}

/// A pose given as 16 numbers of a 4x4 matrix in rows (NumPy's `pose.ravel()`, the
/// convention of pyrender and trimesh), as glam's column-major matrix.
pub fn pose(rows: Option<[f32; 16]>) -> Mat4 {
    match rows {
        Some(m) => Mat4::from_cols_array(&m).transpose(),
        None => Mat4::IDENTITY,
    }
}

/// The material of a mesh: the glTF metallic-roughness factors in `dict` (every key
/// optional, the glTF default where missing: white, metallic 1, roughness 1) and its textures
/// (indices from `add_texture`: the Python side adds the images given as arrays first),
/// refusing keys it does not know. The library checks the ranges and the indices.
pub fn material(dict: Option<&Bound<'_, PyDict>>) -> PyResult<Material> {
    let mut m = Material::default();
    let Some(dict) = dict else {
        return Ok(m);
    };
    const KEYS: &str = "base_color, metallic, roughness, emissive, emissive_strength, \
        alpha_mode, alpha_cutoff, double_sided, unlit, name, base_color_texture, \
        metallic_roughness_texture, normal_texture, normal_scale, occlusion_texture, \
        occlusion_strength, emissive_texture, transmission, ior, dispersion, thickness, \
        attenuation_color, attenuation_distance, specular, specular_color, sheen_color, \
        sheen_roughness, clearcoat, clearcoat_roughness, iridescence, iridescence_ior, \
        iridescence_thickness, transmission_texture, thickness_texture, specular_texture, \
        specular_color_texture, sheen_color_texture, sheen_roughness_texture, \
        clearcoat_texture, clearcoat_roughness_texture, clearcoat_normal_texture, \
        iridescence_texture, iridescence_thickness_texture, anisotropy, anisotropy_rotation, \
        anisotropy_texture, diffuse_transmission, diffuse_transmission_color, \
        diffuse_transmission_texture, diffuse_transmission_color_texture";
    for (key, value) in dict.iter() {
        let key: String = key.extract()?;
        // Our own errors by their message alone; others (a TypeError) with their type.
        let bad = |e: PyErr| {
            let message = if e.is_instance_of::<Error>(dict.py()) {
                e.value(dict.py()).to_string()
            } else {
                e.to_string()
            };
            Error::new_err(format!("material: {key}: {message}"))
        };
        match key.as_str() {
            "base_color" => {
                let c: Vec<f32> = value.extract().map_err(bad)?;
                m.base_color = match c.as_slice() {
                    [r, g, b] => Vec4::new(*r, *g, *b, 1.0),
                    [r, g, b, a] => Vec4::new(*r, *g, *b, *a),
                    _ => {
                        return Err(Error::new_err(format!(
                            "material: base_color: {} numbers, expected 3 (RGB) or 4 (RGBA)",
                            c.len()
                        )))
                    }
                };
            }
            "metallic" => m.metallic = value.extract().map_err(bad)?,
            "roughness" => m.roughness = value.extract().map_err(bad)?,
            "emissive" => m.emissive = Vec3::from(value.extract::<[f32; 3]>().map_err(bad)?),
            "emissive_strength" => m.emissive_strength = value.extract().map_err(bad)?,
            "alpha_cutoff" => m.alpha_cutoff = value.extract().map_err(bad)?,
            "double_sided" => m.double_sided = value.extract().map_err(bad)?,
            "unlit" => m.unlit = value.extract().map_err(bad)?,
            "name" => m.name = value.extract().map_err(bad)?,
            "normal_scale" => m.normal_scale = value.extract().map_err(bad)?,
            "occlusion_strength" => m.occlusion_strength = value.extract().map_err(bad)?,
            "thickness" => {
                // KHR_materials_volume: 0 is a thin wall, more a volume whose depth the
                // geometry gives.
                let thickness: f32 = value.extract().map_err(bad)?;
                if !(thickness.is_finite() && thickness >= 0.0) {
                    return Err(Error::new_err(format!(
                        "material: thickness {thickness}: must be a finite number of at least 0"
                    )));
                }
                m.thin_walled = thickness == 0.0;
            }
            "base_color_texture"
            | "metallic_roughness_texture"
            | "normal_texture"
            | "occlusion_texture"
            | "emissive_texture" => {
                let texture = Some(texture_ref(&value).map_err(bad)?);
                match key.as_str() {
                    "base_color_texture" => m.base_color_texture = texture,
                    "metallic_roughness_texture" => m.metallic_roughness_texture = texture,
                    "normal_texture" => m.normal_texture = texture,
                    "occlusion_texture" => m.occlusion_texture = texture,
                    _ => m.emissive_texture = texture,
                }
            }
            "alpha_mode" => {
                let mode: String = value.extract().map_err(bad)?;
                m.alpha_mode = match mode.to_ascii_uppercase().as_str() {
                    "OPAQUE" => AlphaMode::Opaque,
                    "MASK" => AlphaMode::Mask,
                    "BLEND" => AlphaMode::Blend,
                    _ => {
                        return Err(Error::new_err(format!(
                            "material: alpha_mode '{mode}': use OPAQUE, MASK or BLEND"
                        )))
                    }
                };
            }
            _ => {
                if !extension(&mut m, &key, &value).map_err(bad)? {
                    return Err(Error::new_err(format!(
                        "material: unknown key '{key}': use {KEYS}"
                    )));
                }
            }
        }
    }
    Ok(m)
}

/// The factors and textures of glTF's material extensions (but `thickness`, which
/// [`material`] reads), keyed by their property names in snake case without "Factor"
/// (`transmissionFactor` is `transmission`, `clearcoatTexture` `clearcoat_texture`). A layer
/// one of its keys names starts from its extension's defaults. Returns whether `key` is one
/// of them.
fn extension(m: &mut Material, key: &str, value: &Bound<'_, PyAny>) -> PyResult<bool> {
    // KHR_materials_specular: specularFactor 1, specularColorFactor white.
    fn specular(m: &mut Material) -> &mut SpecularLayer {
        m.specular_layer.get_or_insert(SpecularLayer {
            factor: 1.0,
            texture: None,
            color: Vec3::ONE,
            color_texture: None,
        })
    }
    // KHR_materials_sheen: black (no sheen), roughness 0.
    fn sheen(m: &mut Material) -> &mut SheenLayer {
        m.sheen.get_or_insert(SheenLayer {
            color: Vec3::ZERO,
            color_texture: None,
            roughness: 0.0,
            roughness_texture: None,
        })
    }
    // KHR_materials_clearcoat: no coat, roughness 0.
    fn clearcoat(m: &mut Material) -> &mut ClearcoatLayer {
        m.clearcoat.get_or_insert(ClearcoatLayer {
            factor: 0.0,
            texture: None,
            roughness: 0.0,
            roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
        })
    }
    // KHR_materials_iridescence: no film, ior 1.3, thickness 100-400 nm.
    fn iridescence(m: &mut Material) -> &mut IridescenceLayer {
        m.iridescence.get_or_insert(IridescenceLayer {
            factor: 0.0,
            texture: None,
            ior: 1.3,
            thickness_min: 100.0,
            thickness_max: 400.0,
            thickness_texture: None,
        })
    }
    // KHR_materials_anisotropy: strength 0 (isotropic), rotation 0 (along the tangent).
    fn anisotropy(m: &mut Material) -> &mut AnisotropyLayer {
        m.anisotropy.get_or_insert(AnisotropyLayer {
            strength: 0.0,
            rotation: 0.0,
            texture: None,
        })
    }
    // KHR_materials_diffuse_transmission: factor 0 (none), white.
    fn through(m: &mut Material) -> &mut DiffuseTransmissionLayer {
        m.diffuse_transmission
            .get_or_insert(DiffuseTransmissionLayer {
                factor: 0.0,
                texture: None,
                color: Vec3::ONE,
                color_texture: None,
            })
    }
    let number = || value.extract::<f32>();
    let triple = || value.extract::<[f32; 3]>().map(Vec3::from);
    let texture = || texture_ref(value).map(Some);
    match key {
        "transmission" => m.transmission = number()?,
        "ior" => m.ior = number()?,
        "dispersion" => m.dispersion = number()?,
        "attenuation_color" => m.attenuation_color = triple()?,
        "attenuation_distance" => m.attenuation_distance = number()?,
        "specular" => specular(m).factor = number()?,
        "specular_color" => specular(m).color = triple()?,
        "sheen_color" => sheen(m).color = triple()?,
        "sheen_roughness" => sheen(m).roughness = number()?,
        "clearcoat" => clearcoat(m).factor = number()?,
        "clearcoat_roughness" => clearcoat(m).roughness = number()?,
        "iridescence" => iridescence(m).factor = number()?,
        "iridescence_ior" => iridescence(m).ior = number()?,
        "anisotropy" => anisotropy(m).strength = number()?,
        "anisotropy_rotation" => anisotropy(m).rotation = number()?,
        "diffuse_transmission" => through(m).factor = number()?,
        "diffuse_transmission_color" => through(m).color = triple()?,
        // Their textures: indices from `add_texture`, read with texture coordinates 0.
        "transmission_texture" => m.transmission_texture = texture()?,
        "thickness_texture" => m.thickness_texture = texture()?,
        "specular_texture" => specular(m).texture = texture()?,
        "specular_color_texture" => specular(m).color_texture = texture()?,
        "sheen_color_texture" => sheen(m).color_texture = texture()?,
        "sheen_roughness_texture" => sheen(m).roughness_texture = texture()?,
        "clearcoat_texture" => clearcoat(m).texture = texture()?,
        "clearcoat_roughness_texture" => clearcoat(m).roughness_texture = texture()?,
        "clearcoat_normal_texture" => clearcoat(m).normal_texture = texture()?,
        "iridescence_texture" => iridescence(m).texture = texture()?,
        "iridescence_thickness_texture" => iridescence(m).thickness_texture = texture()?,
        "anisotropy_texture" => anisotropy(m).texture = texture()?,
        "diffuse_transmission_texture" => through(m).texture = texture()?,
        "diffuse_transmission_color_texture" => through(m).color_texture = texture()?,
        "iridescence_thickness" => {
            let [low, high] = value.extract::<[f32; 2]>()?;
            let film = iridescence(m);
            (film.thickness_min, film.thickness_max) = (low, high);
        }
        _ => return Ok(false),
    }
    Ok(true)
}

/// A texture slot's value: an index from `add_texture`, or a dict of that index (`texture`)
/// with the texture coordinate set it reads (`tex_coord`: 0, the default, or 1, the mesh's
/// `uvs1`) and a `KHR_texture_transform` (`offset` and `scale` as (u, v), `rotation` in
/// radians, counter-clockwise; the extension's defaults where missing).
fn texture_ref(value: &Bound<'_, PyAny>) -> PyResult<TextureRef> {
    let Ok(dict) = value.cast::<PyDict>() else {
        return Ok(TextureRef {
            texture: value.extract()?,
            tex_coord: 0,
            transform: None,
        });
    };
    let mut texture = None;
    let mut tex_coord = 0;
    let mut transform: Option<TextureTransform> = None;
    let identity = TextureTransform {
        offset: [0.0, 0.0],
        rotation: 0.0,
        scale: [1.0, 1.0],
    };
    for (key, v) in dict.iter() {
        let key: String = key.extract()?;
        match key.as_str() {
            "texture" => texture = Some(v.extract()?),
            "tex_coord" => tex_coord = v.extract()?,
            "offset" => transform.get_or_insert(identity).offset = v.extract()?,
            "scale" => transform.get_or_insert(identity).scale = v.extract()?,
            "rotation" => transform.get_or_insert(identity).rotation = v.extract()?,
            _ => {
                return Err(Error::new_err(format!(
                    "unknown key '{key}': use texture, tex_coord, offset, scale, rotation"
                )))
            }
        }
    }
    Ok(TextureRef {
        texture: texture
            .ok_or_else(|| Error::new_err("a dict needs 'texture' (an index from add_texture)"))?,
        tex_coord,
        transform,
    })
}

/// A texture's sampler from glTF's names for its wrap modes (`repeat`, `clamp_to_edge`,
/// `mirrored_repeat`) and filters (`linear`, `nearest`).
pub fn sampler(wrap_s: &str, wrap_t: &str, mag: &str, min: &str) -> PyResult<Sampler> {
    let wrap = |name: &str, value: &str| match value {
        "repeat" => Ok(Wrap::Repeat),
        "clamp_to_edge" => Ok(Wrap::ClampToEdge),
        "mirrored_repeat" => Ok(Wrap::MirroredRepeat),
        other => Err(Error::new_err(format!(
            "{name} '{other}': use repeat, clamp_to_edge or mirrored_repeat"
        ))),
    };
    let filter = |name: &str, value: &str| match value {
        "linear" => Ok(Filter::Linear),
        "nearest" => Ok(Filter::Nearest),
        other => Err(Error::new_err(format!(
            "{name} '{other}': use linear or nearest"
        ))),
    };
    Ok(Sampler {
        mag_filter: filter("mag_filter", mag)?,
        min_filter: filter("min_filter", min)?,
        wrap_s: wrap("wrap_s", wrap_s)?,
        wrap_t: wrap("wrap_t", wrap_t)?,
    })
}

/// A light kind from its name and cone angles (radians), as `KHR_lights_punctual` has them.
pub fn light_kind(kind: &str, inner: f32, outer: f32) -> PyResult<LightKind> {
    match kind {
        "directional" => Ok(LightKind::Directional),
        "point" => Ok(LightKind::Point),
        "spot" => {
            let right = std::f32::consts::FRAC_PI_2;
            if !(0.0 <= inner && inner < outer && outer <= right) {
                return Err(Error::new_err(format!(
                    "spot light cone: inner {inner}, outer {outer}: need 0 <= inner < outer <= pi/2"
                )));
            }
            Ok(LightKind::Spot {
                inner_cone_angle: inner,
                outer_cone_angle: outer,
            })
        }
        other => Err(Error::new_err(format!(
            "light kind '{other}': use directional, point or spot"
        ))),
    }
}
