//! What meshtracer does with each glTF extension: one table, read by the importer (which
//! required extensions to refuse), by `info --json` and by `render`'s warnings.

use serde::Serialize;

/// How an extension is honoured.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ExtensionStatus {
    /// Implemented as the extension specifies.
    Supported,
    /// Drawn, but not exactly as the extension specifies (the note says how).
    Approximated,
    /// Not implemented: the file is drawn as if the extension were absent.
    Ignored,
}

/// One extension of the table.
#[derive(Clone, Copy, Debug)]
pub struct KnownExtension {
    /// The extension's name.
    pub name: &'static str,
    /// How it is honoured.
    pub status: ExtensionStatus,
    /// When listed in `extensionsRequired`, the file cannot be drawn without it: refused.
    pub refused_when_required: bool,
    /// What meshtracer does, for warnings and the README.
    pub note: &'static str,
}

const fn ext(
    name: &'static str,
    status: ExtensionStatus,
    refused_when_required: bool,
    note: &'static str,
) -> KnownExtension {
    KnownExtension {
        name,
        status,
        refused_when_required,
        note,
    }
}

use ExtensionStatus::{Approximated, Supported};

/// Every extension meshtracer knows. One not listed is ignored when used and refused when
/// required (it may change what the geometry is).
pub const EXTENSIONS: &[KnownExtension] = &[
    ext(
        "KHR_lights_punctual",
        Supported,
        false,
        "point, spot and directional lights",
    ),
    ext(
        "KHR_texture_transform",
        Supported,
        false,
        "offset, rotation, scale, texCoord override",
    ),
    ext(
        "KHR_materials_emissive_strength",
        Supported,
        false,
        "multiplies the emissive factor",
    ),
    ext(
        "KHR_materials_variants",
        Supported,
        false,
        "--variant NAME; info lists the variants",
    ),
    ext(
        "KHR_mesh_quantization",
        Supported,
        false,
        "integer and normalized attributes",
    ),
    ext(
        "EXT_meshopt_compression",
        Supported,
        false,
        "every mode and filter",
    ),
    ext(
        "KHR_meshopt_compression",
        Supported,
        false,
        "every mode and filter",
    ),
    ext(
        "EXT_mesh_gpu_instancing",
        Supported,
        false,
        "each instance drawn at the node's transform times its TRANSLATION, ROTATION and SCALE",
    ),
    ext(
        "KHR_draco_mesh_compression",
        Supported,
        false,
        "decoded by draco-core; Draco dequantizes",
    ),
    ext(
        "EXT_texture_webp",
        Supported,
        false,
        "the core source is the fallback",
    ),
    ext(
        "KHR_texture_basisu",
        Supported,
        false,
        "ETC1S and UASTC KTX2 transcoded by basisu; the core source is the fallback",
    ),
    ext(
        "MSFT_texture_dds",
        Supported,
        false,
        "BC1-BC5, BC7 and 8-bit DDS decoded by bcdec_rs; the core source is the fallback",
    ),
    ext(
        "KHR_materials_ior",
        Supported,
        false,
        "refraction index of transmission (path tracer)",
    ),
    ext(
        "KHR_materials_specular",
        Supported,
        false,
        "specular and specular colour (factors and textures) set the dielectric's Fresnel",
    ),
    ext(
        "KHR_materials_transmission",
        Approximated,
        false,
        "GGX refraction (path), see-through (direct); thin sheets pass textured shadows",
    ),
    ext(
        "KHR_materials_volume",
        Approximated,
        false,
        "thickness (factor x texture) 0 is thin-walled; Beer-Lambert over traced paths (path)",
    ),
    ext(
        "KHR_materials_clearcoat",
        Supported,
        false,
        "a GGX coat (F0 4%) with its own roughness and normal map, factors and textures",
    ),
    ext(
        "KHR_materials_sheen",
        Supported,
        false,
        "Charlie sheen with Neubelt-Pettineo visibility and albedo scaling of the base",
    ),
    ext(
        "KHR_materials_iridescence",
        Approximated,
        false,
        "thin-film Fresnel at the view angle (Belcour-Barla as the Sample Viewer evaluates it)",
    ),
    ext(
        "KHR_materials_diffuse_transmission",
        Approximated,
        false,
        "a Lambertian BTDF through a thin wall (path tracer); the direct renderer draws the diffuse reflection only",
    ),
    ext(
        "KHR_materials_anisotropy",
        Supported,
        false,
        "the specular lobe stretched along the tangent-space direction (strength, rotation, texture)",
    ),
    ext(
        "KHR_materials_dispersion",
        Approximated,
        false,
        "each colour channel refracted by its own index into and out of volumes (path tracer); no dispersion in the direct renderer",
    ),
    ext(
        "KHR_materials_unlit",
        Supported,
        false,
        "the base colour is the radiance",
    ),
    ext(
        "KHR_materials_pbrSpecularGlossiness",
        Supported,
        false,
        "diffuse, specular (F0) and glossiness with their textures, by the extension's equations",
    ),
    ext(
        "KHR_xmp_json_ld",
        Supported,
        false,
        "metadata only: nothing to draw",
    ),
    ext(
        "KHR_node_visibility",
        Supported,
        false,
        "a node whose visible is false draws no mesh or light, nor do the nodes below it (cameras stay)",
    ),
    ext(
        "KHR_animation_pointer",
        Supported,
        false,
        "with --animation/--time: node transforms and weights, material factors, texture transforms, lights and cameras",
    ),
];

/// The table's entry for `name`, if meshtracer knows it.
pub fn known(name: &str) -> Option<&'static KnownExtension> {
    EXTENSIONS.iter().find(|e| e.name == name)
}

/// One extension a file uses, as `info --json` reports it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct ExtensionUse {
    /// The extension's name.
    pub name: String,
    /// Listed in `extensionsRequired`.
    pub required: bool,
    /// How meshtracer honours it.
    pub status: ExtensionStatus,
}

impl ExtensionUse {
    /// The status of `name` as used by a file (unknown extensions are ignored).
    pub fn new(name: &str, required: bool) -> ExtensionUse {
        ExtensionUse {
            name: name.to_string(),
            required,
            status: known(name).map_or(ExtensionStatus::Ignored, |e| e.status),
        }
    }

    /// The warning `render` prints for an extension not fully supported, else `None`.
    pub fn warning(&self) -> Option<String> {
        if self.status == ExtensionStatus::Supported {
            return None;
        }
        let note =
            known(&self.name).map_or("unknown to meshtracer: drawn as if absent", |e| e.note);
        let status = match self.status {
            ExtensionStatus::Approximated => "approximated",
            _ => "ignored",
        };
        Some(format!("extension {} is {status}: {note}", self.name))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_lists_each_extension_once() {
        for (i, e) in EXTENSIONS.iter().enumerate() {
            assert!(
                EXTENSIONS[i + 1..].iter().all(|f| f.name != e.name),
                "{} twice",
                e.name
            );
        }
        assert!(ExtensionUse::new("KHR_lights_punctual", false)
            .warning()
            .is_none());
        let w = ExtensionUse::new("EXT_made_up", false).warning().unwrap();
        assert_eq!(
            w,
            "extension EXT_made_up is ignored: unknown to meshtracer: drawn as if absent"
        );
        assert_eq!(
            ExtensionUse::new("EXT_made_up", true).status,
            ExtensionStatus::Ignored
        );
    }
}
