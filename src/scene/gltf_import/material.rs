//! glTF materials (§3.9, metallic-roughness) and their extensions -> [`Material`], with the
//! texture references they hold (`KHR_texture_transform` included).

use crate::scene::material::{
    AlphaMode, AnisotropyLayer, ClearcoatLayer, DiffuseTransmissionLayer, IridescenceLayer,
    Material, SheenLayer, SpecularGlossiness, SpecularLayer, TextureRef, TextureTransform,
};
use glam::{Vec3, Vec4};

fn texture_ref(info: Option<gltf::texture::Info>) -> Option<TextureRef> {
    info.map(|info| {
        let transform = info.texture_transform();
        TextureRef {
            texture: info.texture().index(),
            tex_coord: transform
                .as_ref()
                .and_then(|t| t.tex_coord())
                .unwrap_or(info.tex_coord()),
            transform: transform.map(|t| TextureTransform {
                offset: t.offset(),
                rotation: t.rotation(),
                scale: t.scale(),
            }),
        }
    })
}

/// A normal or occlusion texture reference: the `gltf` crate parses `KHR_texture_transform`
/// only on plain texture infos, so it is read from the extension's JSON here (same defaults:
/// offset 0, rotation 0, scale 1; `texCoord` overrides the info's). Malformed fields keep
/// their defaults.
fn extension_texture_ref(
    texture: usize,
    tex_coord: u32,
    transform: Option<&serde_json::Value>,
) -> TextureRef {
    let pair = |v: Option<&serde_json::Value>, default: [f32; 2]| -> [f32; 2] {
        match v.and_then(|v| v.as_array()).map(|a| a.as_slice()) {
            Some([x, y]) => match (x.as_f64(), y.as_f64()) {
                (Some(x), Some(y)) => [x as f32, y as f32],
                _ => default,
            },
            _ => default,
        }
    };
    let Some(t) = transform.filter(|t| t.is_object()) else {
        return TextureRef {
            texture,
            tex_coord,
            transform: None,
        };
    };
    TextureRef {
        texture,
        tex_coord: t
            .get("texCoord")
            .and_then(serde_json::Value::as_u64)
            .and_then(|c| u32::try_from(c).ok())
            .unwrap_or(tex_coord),
        transform: Some(TextureTransform {
            offset: pair(t.get("offset"), [0.0, 0.0]),
            rotation: t
                .get("rotation")
                .and_then(serde_json::Value::as_f64)
                .map_or(0.0, |r| r as f32),
            scale: pair(t.get("scale"), [1.0, 1.0]),
        }),
    }
}

pub(super) fn material(m: &gltf::Material) -> Material {
    let core = core_material(m);
    let Some(sg) = m.pbr_specular_glossiness() else {
        return core;
    };
    // KHR_materials_pbrSpecularGlossiness: "any client implementation that supports the
    // extension should always render the asset using the specular-glossiness material
    // properties", so a metallic-roughness fallback beside it is not drawn. The diffuse colour
    // takes the base colour's place (see `SpecularGlossiness`); the factors are defined on
    // [0, 1] and clamped (reported by `out_of_range`).
    let glossiness = finite_or(sg.glossiness_factor(), 1.0).clamp(0.0, 1.0);
    Material {
        base_color: Vec4::from(sg.diffuse_factor()).clamp(Vec4::ZERO, Vec4::ONE),
        base_color_texture: texture_ref(sg.diffuse_texture()),
        metallic: 0.0,
        roughness: 1.0 - glossiness,
        metallic_roughness_texture: None,
        specular_glossiness: Some(SpecularGlossiness {
            specular: Vec3::from(sg.specular_factor()).clamp(Vec3::ZERO, Vec3::ONE),
            glossiness,
            texture: texture_ref(sg.specular_glossiness_texture()),
        }),
        ..core
    }
}

/// `m` as the core metallic-roughness material with its extension layers.
fn core_material(m: &gltf::Material) -> Material {
    let pbr = m.pbr_metallic_roughness();
    let normal = m.normal_texture();
    let occlusion = m.occlusion_texture();
    Material {
        name: m.name().map(str::to_string),
        // glTF 2.0 §5.22: every factor of the core material is in [0, 1] (a base colour above 1
        // would reflect more light than arrives); out of range is invalid, clamped here and
        // reported by `out_of_range`.
        base_color: Vec4::from(pbr.base_color_factor()).clamp(Vec4::ZERO, Vec4::ONE),
        base_color_texture: texture_ref(pbr.base_color_texture()),
        metallic: pbr.metallic_factor().clamp(0.0, 1.0),
        roughness: pbr.roughness_factor().clamp(0.0, 1.0),
        metallic_roughness_texture: texture_ref(pbr.metallic_roughness_texture()),
        normal_texture: normal.as_ref().map(|n| {
            extension_texture_ref(
                n.texture().index(),
                n.tex_coord(),
                n.extension_value("KHR_texture_transform"),
            )
        }),
        normal_scale: normal.as_ref().map_or(1.0, |n| n.scale()),
        occlusion_texture: occlusion.as_ref().map(|o| {
            extension_texture_ref(
                o.texture().index(),
                o.tex_coord(),
                o.extension_value("KHR_texture_transform"),
            )
        }),
        occlusion_strength: occlusion
            .as_ref()
            .map_or(1.0, |o| o.strength().clamp(0.0, 1.0)),
        emissive: Vec3::from(m.emissive_factor()).clamp(Vec3::ZERO, Vec3::ONE),
        emissive_strength: m
            .emissive_strength()
            .map_or(1.0, |e| finite_or(e, 1.0).max(0.0)),
        emissive_texture: texture_ref(m.emissive_texture()),
        alpha_mode: match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
            gltf::material::AlphaMode::Mask => AlphaMode::Mask,
            gltf::material::AlphaMode::Blend => AlphaMode::Blend,
        },
        alpha_cutoff: m.alpha_cutoff().unwrap_or(0.5),
        double_sided: m.double_sided(),
        specular: None,
        // KHR_materials_transmission, _ior, _volume (their defaults when absent). Of the
        // thickness only whether it is 0 matters (thin-walled): the path tracer measures path
        // lengths in the geometry.
        transmission: m
            .transmission()
            .map_or(0.0, |t| t.transmission_factor().clamp(0.0, 1.0)),
        transmission_texture: m
            .transmission()
            .and_then(|t| texture_ref(t.transmission_texture())),
        ior: m
            .ior()
            .filter(|i| i.is_finite() && *i >= 1.0)
            .unwrap_or(1.5),
        thin_walled: m.volume().is_none_or(|v| v.thickness_factor() <= 0.0),
        thickness_texture: m
            .volume()
            .filter(|v| v.thickness_factor() > 0.0)
            .and_then(|v| texture_ref(v.thickness_texture())),
        attenuation_color: m
            .volume()
            .map_or(Vec3::ONE, |v| Vec3::from(v.attenuation_color())),
        attenuation_distance: m
            .volume()
            .map_or(f32::INFINITY, |v| v.attenuation_distance()),
        // KHR_materials_dispersion: any value of at least 0 is valid (above 1 exaggerates).
        dispersion: m
            .extension_value("KHR_materials_dispersion")
            .map_or(0.0, |e| json_f32(e.get("dispersion"), 0.0).max(0.0)),
        unlit: m.unlit(),
        specular_layer: m.specular().map(|sp| SpecularLayer {
            factor: finite_or(sp.specular_factor(), 1.0).clamp(0.0, 1.0),
            texture: texture_ref(sp.specular_texture()),
            color: Vec3::from(sp.specular_color_factor()).max(Vec3::ZERO),
            color_texture: texture_ref(sp.specular_color_texture()),
        }),
        sheen: m
            .extension_value("KHR_materials_sheen")
            .map(|e| SheenLayer {
                color: json_vec3(e.get("sheenColorFactor"), Vec3::ZERO).max(Vec3::ZERO),
                color_texture: json_texture_ref(e.get("sheenColorTexture")),
                roughness: json_f32(e.get("sheenRoughnessFactor"), 0.0).clamp(0.0, 1.0),
                roughness_texture: json_texture_ref(e.get("sheenRoughnessTexture")),
            }),
        clearcoat: m
            .extension_value("KHR_materials_clearcoat")
            .map(|e| ClearcoatLayer {
                factor: json_f32(e.get("clearcoatFactor"), 0.0).clamp(0.0, 1.0),
                texture: json_texture_ref(e.get("clearcoatTexture")),
                roughness: json_f32(e.get("clearcoatRoughnessFactor"), 0.0).clamp(0.0, 1.0),
                roughness_texture: json_texture_ref(e.get("clearcoatRoughnessTexture")),
                normal_texture: json_texture_ref(e.get("clearcoatNormalTexture")),
                normal_scale: e
                    .get("clearcoatNormalTexture")
                    .map_or(1.0, |t| json_f32(t.get("scale"), 1.0)),
            }),
        iridescence: m
            .extension_value("KHR_materials_iridescence")
            .map(|e| IridescenceLayer {
                factor: json_f32(e.get("iridescenceFactor"), 0.0).clamp(0.0, 1.0),
                texture: json_texture_ref(e.get("iridescenceTexture")),
                ior: json_f32(e.get("iridescenceIor"), 1.3).max(1.0),
                thickness_min: json_f32(e.get("iridescenceThicknessMinimum"), 100.0).max(0.0),
                thickness_max: json_f32(e.get("iridescenceThicknessMaximum"), 400.0).max(0.0),
                thickness_texture: json_texture_ref(e.get("iridescenceThicknessTexture")),
            }),
        specular_glossiness: None,
        anisotropy: m
            .extension_value("KHR_materials_anisotropy")
            .map(|e| AnisotropyLayer {
                strength: json_f32(e.get("anisotropyStrength"), 0.0).clamp(0.0, 1.0),
                rotation: json_f32(e.get("anisotropyRotation"), 0.0),
                texture: json_texture_ref(e.get("anisotropyTexture")),
            }),
        diffuse_transmission: m
            .extension_value("KHR_materials_diffuse_transmission")
            .map(|e| DiffuseTransmissionLayer {
                factor: json_f32(e.get("diffuseTransmissionFactor"), 0.0).clamp(0.0, 1.0),
                texture: json_texture_ref(e.get("diffuseTransmissionTexture")),
                color: json_vec3(e.get("diffuseTransmissionColorFactor"), Vec3::ONE)
                    .clamp(Vec3::ZERO, Vec3::ONE),
                color_texture: json_texture_ref(e.get("diffuseTransmissionColorTexture")),
            }),
        // glTF packs alpha and roughness/metalness into the base colour and metallic-roughness
        // textures.
        scalar_maps: None,
    }
}

/// What [`material`] corrects in `m`'s extension values that are outside the ranges their
/// extensions define (an invalid file: the validator reports each), one warning each, naming
/// the material.
pub(super) fn out_of_range(m: &gltf::Material) -> Vec<String> {
    let mut problems = Vec::new();
    let pbr = m.pbr_metallic_roughness();
    let unit = |v: &[f32]| v.iter().all(|x| (0.0..=1.0).contains(x));
    // (property, its values) of the drawn material's factors, each defined on [0, 1]: the
    // specular-glossiness ones in place of the core colour, metalness and roughness where that
    // extension is present (the core ones are then not drawn).
    let sg = m.pbr_specular_glossiness();
    let drawn: [(&str, Vec<f32>); 3] = match &sg {
        Some(sg) => [
            ("diffuseFactor", sg.diffuse_factor().to_vec()),
            ("specularFactor", sg.specular_factor().to_vec()),
            ("glossinessFactor", vec![sg.glossiness_factor()]),
        ],
        None => [
            ("baseColorFactor", pbr.base_color_factor().to_vec()),
            ("metallicFactor", vec![pbr.metallic_factor()]),
            ("roughnessFactor", vec![pbr.roughness_factor()]),
        ],
    };
    let prefix = if sg.is_some() {
        "KHR_materials_pbrSpecularGlossiness "
    } else {
        ""
    };
    let shared = [
        ("emissiveFactor", m.emissive_factor().to_vec()),
        (
            "occlusionTexture strength",
            vec![m.occlusion_texture().map_or(1.0, |o| o.strength())],
        ),
    ];
    let named = drawn
        .into_iter()
        .map(|(p, v)| (format!("{prefix}{p}"), v))
        .chain(shared.into_iter().map(|(p, v)| (p.to_string(), v)));
    for (property, values) in named {
        let values = values.as_slice();
        if !unit(values) {
            let shown = match values {
                [one] => one.to_string(),
                many => format!("{many:?}"),
            };
            problems.push(format!("{property} {shown} is outside [0, 1]; clamped"));
        }
    }
    if let Some(ior) = m.ior().filter(|i| !(i.is_finite() && *i >= 1.0)) {
        problems.push(format!(
            "KHR_materials_ior ior {ior} is not at least 1; the default 1.5 is used"
        ));
    }
    // (extension, property, value) of the factors defined on [0, 1].
    let mut factors = Vec::new();
    if let Some(sp) = m.specular() {
        factors.push((
            "KHR_materials_specular",
            "specularFactor",
            sp.specular_factor(),
        ));
        let color = sp.specular_color_factor();
        if color.iter().any(|c| *c < 0.0) {
            problems.push(format!(
                "KHR_materials_specular specularColorFactor {color:?} is negative; clamped to 0"
            ));
        }
    }
    if let Some(strength) = m.emissive_strength().filter(|e| *e < 0.0) {
        problems.push(format!(
            "KHR_materials_emissive_strength emissiveStrength {strength} is negative; 0 is used"
        ));
    }
    if let Some(e) = m.extension_value("KHR_materials_dispersion") {
        let dispersion = json_f32(e.get("dispersion"), 0.0);
        if dispersion < 0.0 {
            problems.push(format!(
                "KHR_materials_dispersion dispersion {dispersion} is negative; 0 (none) is used"
            ));
        }
    }
    if let Some(e) = m.extension_value("KHR_materials_diffuse_transmission") {
        let factor = json_f32(e.get("diffuseTransmissionFactor"), 0.0);
        factors.push((
            "KHR_materials_diffuse_transmission",
            "diffuseTransmissionFactor",
            factor,
        ));
    }
    if let Some(e) = m.extension_value("KHR_materials_anisotropy") {
        let strength = json_f32(e.get("anisotropyStrength"), 0.0);
        factors.push(("KHR_materials_anisotropy", "anisotropyStrength", strength));
    }
    if let Some(t) = m.transmission() {
        let factor = t.transmission_factor();
        factors.push(("KHR_materials_transmission", "transmissionFactor", factor));
    }
    for (extension, property, value) in factors {
        if !(0.0..=1.0).contains(&value) {
            problems.push(format!(
                "{extension} {property} {value} is outside [0, 1]; clamped"
            ));
        }
    }
    let name = m.name().map_or(String::new(), |n| format!(" ('{n}')"));
    let index = m.index().map_or("default".to_string(), |i| i.to_string());
    problems
        .into_iter()
        .map(|p| format!("material {index}{name}: {p}"))
        .collect()
}

fn finite_or(v: f32, default: f32) -> f32 {
    if v.is_finite() {
        v
    } else {
        default
    }
}

/// A number of an extension's JSON, or `default` when absent, not a number or not finite.
fn json_f32(v: Option<&serde_json::Value>, default: f32) -> f32 {
    v.and_then(serde_json::Value::as_f64)
        .map_or(default, |x| finite_or(x as f32, default))
}

/// A 3-vector of an extension's JSON, or `default` unless it is three finite numbers.
fn json_vec3(v: Option<&serde_json::Value>, default: Vec3) -> Vec3 {
    match v.and_then(serde_json::Value::as_array).map(Vec::as_slice) {
        Some([x, y, z]) => match (x.as_f64(), y.as_f64(), z.as_f64()) {
            (Some(x), Some(y), Some(z)) => {
                let v = Vec3::new(x as f32, y as f32, z as f32);
                if v.is_finite() {
                    v
                } else {
                    default
                }
            }
            _ => default,
        },
        _ => default,
    }
}

/// A texture info of an extension the `gltf` crate does not parse (`KHR_materials_sheen`,
/// `KHR_materials_clearcoat`): `index`, `texCoord` and `KHR_texture_transform`. One without a
/// usable index is ignored; an index past the file's textures is refused by the scene's
/// reference check, like any other.
fn json_texture_ref(v: Option<&serde_json::Value>) -> Option<TextureRef> {
    let v = v?;
    let texture = usize::try_from(v.get("index")?.as_u64()?).ok()?;
    let tex_coord = v
        .get("texCoord")
        .and_then(serde_json::Value::as_u64)
        .and_then(|c| u32::try_from(c).ok())
        .unwrap_or(0);
    let transform = v
        .get("extensions")
        .and_then(|e| e.get("KHR_texture_transform"));
    Some(extension_texture_ref(texture, tex_coord, transform))
}
