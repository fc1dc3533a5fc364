//! glTF 2.0 (.gltf and .glb) -> [`Scene`].
//!
//! The `gltf` crate parses and validates the JSON; everything it would index blindly (buffer
//! views, accessor ranges, index values, the GLB header) is checked here first, so that a hostile
//! file gets an error naming the file, mesh and primitive instead of a panic.
//!
//! Conventions (glTF 2.0 specification):
//! - §3.5.3: node transforms are `matrix` or T·R·S, parent · child.
//! - §3.7.2.1: without NORMAL, flat normals; normals transform by the inverse transpose; a
//!   negative determinant mirrors the geometry and so flips the winding.
//! - §3.7.2.1 / §5.24: TRIANGLE_STRIP triangle i = (i, i+1+i%2, i+2-i%2), TRIANGLE_FAN = (i+1, i+2, 0).
//! - §3.10: cameras look down local -Z with +Y up; `yfov` in radians.
//! - KHR_lights_punctual: lights shine along local -Z; candela (point, spot), lux (directional).
//! - §3.7.3, §3.7.2.2, §3.11: skins, morph targets and animations pose the model: see
//!   the `pose` module. Without `--animation`/`--time` the static pose is drawn (the nodes' own
//!   transforms and weights), skinned meshes through their joints.

mod attributes;
mod buffer;
mod container;
mod declared;
mod draco;
mod instancing;
mod lenient;
mod material;
mod meshopt;
mod pointer;
mod pose;
mod textures;
mod validate;
mod vertices;
mod walk;

pub(crate) use container::{read_glb_deferring_images, DeferredImages, LoadedFile};
pub(crate) use declared::check_declared_sizes;

use super::error::{LoadError, LoadErrorKind};
use super::extensions::{known, ExtensionUse};
use super::model::Scene;
use super::options::{Format, LoadOptions};
use super::paths::FileAccess;
use super::soup::Bounds;
use crate::scene::material::draw_without;
use buffer::Buffer;
use container::{check_glb_header, load_buffers, parse};
use std::path::Path;
use textures::{choose_texture_sources, images, textures};
use validate::{check_attribute_indices, check_views, validate};
use walk::Importer;

/// Loads a glTF or GLB file whose bytes are already read.
/// `file`, when it holds `bytes`, lets images embedded in a GLB share it instead of copying.
/// The flag is true for a file with nothing to draw that `options` let load empty.
pub(crate) fn load(
    path: &Path,
    bytes: &[u8],
    file: Option<LoadedFile>,
    options: &LoadOptions,
) -> Result<(Scene, bool), LoadError> {
    let err = |kind| LoadError::new(path, kind);
    let mut steps = crate::measure::Steps::new();
    let Parsed {
        format,
        document,
        blob,
        extensions,
        webp_fallbacks,
        warnings: json_warnings,
        pointer_channels,
    } = read_document(bytes).map_err(err)?;
    check_declared_sizes(document.as_json(), &options.limits).map_err(err)?;
    let access = FileAccess::new(
        path,
        options.allow_external_files,
        options.limits.max_file_bytes,
    );
    let mut buffers = load_buffers(&document, blob, &access)?;
    meshopt::decode_views(&document, &mut buffers, access.max_bytes).map_err(err)?;
    check_views(&document, &buffers).map_err(err)?;
    let variants: Vec<String> = document
        .variants()
        .map(|v| v.map(|v| v.name().to_string()).collect())
        .unwrap_or_default();
    let variant = match &options.variant {
        None => None,
        Some(name) => Some(choose_variant(&variants, name).map_err(err)?),
    };
    let mut pose_warnings = Vec::new();
    let animations =
        pose::list_animations(&document, &buffers, &pointer_channels, &mut pose_warnings);
    // KHR_animation_pointer: the chosen animation's pointer channels written into the JSON,
    // which is then read as the file.
    let animated = pointer::animate(
        &document,
        &buffers,
        pointer::chosen(&animations, &options.pose),
        &pointer_channels,
        &options.pose,
        &mut pose_warnings,
    )
    .map_err(|p| err(LoadErrorKind::Animation(p)))?;
    let document = match animated {
        Some(root) => validate(root).map_err(|e| err(convert(e)))?,
        None => document,
    };
    let pose = pose::pose(&document, &buffers, &animations, &options.pose)
        .map_err(|p| err(LoadErrorKind::Animation(p)))?;
    let pose_description = pose.description.clone();
    steps.mark("parse");
    let mut importer = Importer::new(
        &document,
        &buffers,
        options.limits,
        pose,
        json_warnings,
        variant,
    );
    importer.warnings.extend(pose_warnings);
    let nothing_to_draw = importer.walk_default_scene().map_err(err)?;
    if let Some(reason) = &nothing_to_draw {
        if !options.allow_nothing_to_draw {
            return Err(err(LoadErrorKind::NothingToDraw(reason.clone())));
        }
        importer.warnings.push(format!("nothing to draw: {reason}"));
    }
    steps.mark("flatten");
    let mut materials = importer.materials();
    let mut textures = textures(&document, &webp_fallbacks);
    let mut image_warnings = Vec::new();
    let (images, unusable) = images(
        &document,
        &buffers,
        file,
        &access,
        options,
        &mut textures,
        &mut image_warnings,
    )?;
    image_warnings
        .extend(draw_without(&mut materials, &textures, &unusable, options.strict).map_err(err)?);
    let Importer {
        builder,
        mut warnings,
        instances,
        cameras,
        lights,
        primitive_count,
        skipped_non_triangle,
        singular_instances,
        ..
    } = importer;
    warnings.extend(extensions.iter().filter_map(ExtensionUse::warning));
    warnings.extend(image_warnings);
    warnings.extend(access.recased_warnings());
    if skipped_non_triangle > 0 {
        warnings.push(format!(
            "skipped {skipped_non_triangle} POINTS/LINES primitives (a ray tracer draws only triangles)"
        ));
    }
    if singular_instances > 0 {
        warnings.push(format!(
            "skipped {singular_instances} mesh instances whose node transform is singular (zero scale) or not finite"
        ));
    }
    warnings.extend(builder.dropped_warning());
    // One line for what every instance of a mesh repeats.
    let mut seen = std::collections::HashSet::new();
    warnings.retain(|w| seen.insert(w.clone()));
    let file_triangles = builder.offered();
    let (soup, bounds) = builder.finish();
    let scene = Scene {
        source: path.to_path_buf(),
        format,
        soup,
        materials,
        textures,
        images,
        cameras,
        lights,
        instances,
        mesh_count: document.meshes().len(),
        file_triangles,
        primitive_count,
        bounds: if bounds.is_empty() {
            Bounds::EMPTY
        } else {
            bounds
        },
        warnings,
        variants,
        variant: options.variant.clone(),
        extensions,
        animations,
        pose: pose_description,
        load_steps: {
            steps.mark("materials and images");
            steps.list().to_vec()
        },
        archive: None,
        inputs: access.resolved(),
    };
    Ok((scene, nothing_to_draw.is_some()))
}

/// The document of a glTF or GLB file, validated, and what its JSON told before validation.
struct Parsed<'a> {
    /// GLB or JSON, by the first bytes.
    format: Format,
    /// The document, validated.
    document: gltf::Document,
    /// A GLB's binary chunk, borrowed from the file's bytes.
    blob: Option<Buffer<'a>>,
    /// Every extension the file uses, with how it is honoured.
    extensions: Vec<ExtensionUse>,
    /// Each texture's fallback image (see [`choose_texture_sources`]).
    webp_fallbacks: Vec<Option<usize>>,
    /// What the JSON's rewriting corrected or left out ([`lenient`]).
    warnings: Vec<String>,
    /// The `KHR_animation_pointer` channels taken out of each animation ([`lenient`]).
    pointer_channels: Vec<Vec<pointer::PointerChannel>>,
}

/// Parses the GLB container or JSON, refuses required extensions that are not supported,
/// lists the extensions used, and checks the JSON for what the `gltf` crate would index
/// blindly before its validation (which lets `KHR_draco_mesh_compression` accessors go
/// without a bufferView).
fn read_document(bytes: &[u8]) -> Result<Parsed<'_>, LoadErrorKind> {
    check_glb_header(bytes)?;
    let format = if bytes.starts_with(b"glTF") {
        Format::Glb
    } else {
        Format::Gltf
    };
    let (rewritten, blob) = parse(bytes, format)?;
    let mut root = rewritten.root;
    let required = std::mem::take(&mut root.extensions_required);
    for name in &required {
        if known(name).is_none_or(|e| e.refused_when_required) {
            return Err(unsupported_extension(name));
        }
    }
    // extensionsUsed should list every required one; a file that forgets is still reported.
    // The required list is taken out of the JSON: gltf-json's validation refuses required
    // extensions it does not know itself (KHR_mesh_quantization, the meshopt ones,
    // EXT_texture_webp), which are decoded here.
    let mut extensions: Vec<ExtensionUse> = root
        .extensions_used
        .iter()
        .map(|name| ExtensionUse::new(name, required.contains(name)))
        .collect();
    for name in &required {
        if !extensions.iter().any(|e| e.name == *name) {
            extensions.push(ExtensionUse::new(name, true));
        }
    }
    let webp_fallbacks = choose_texture_sources(&mut root);
    check_attribute_indices(&root)?;
    pose::check_channel_targets(&root).map_err(LoadErrorKind::Gltf)?;
    let document = validate(root).map_err(convert)?;
    Ok(Parsed {
        format,
        document,
        blob,
        extensions,
        webp_fallbacks,
        warnings: rewritten.warnings,
        pointer_channels: rewritten.pointer_channels,
    })
}

/// The index of the variant called `name`, or an error listing the variants there are.
fn choose_variant(variants: &[String], name: &str) -> Result<(u32, String), LoadErrorKind> {
    match variants.iter().position(|v| v == name) {
        Some(i) => Ok((i as u32, name.to_string())),
        None if variants.is_empty() => Err(LoadErrorKind::Variant(format!(
            "no variant '{name}': the file defines no material variants"
        ))),
        None => {
            let list: Vec<String> = variants.iter().map(|v| format!("'{v}'")).collect();
            Err(LoadErrorKind::Variant(format!(
                "no variant '{name}'; the file has {}",
                list.join(", ")
            )))
        }
    }
}

fn unsupported_extension(name: &str) -> LoadErrorKind {
    let what = match name {
        "EXT_meshopt_compression" | "KHR_meshopt_compression" => " (meshoptimizer compression)",
        "KHR_mesh_quantization" => " (quantized vertex attributes)",
        "KHR_texture_basisu" => " (Basis Universal / KTX2 textures)",
        "EXT_texture_webp" => " (WebP textures)",
        "MSFT_texture_dds" => " (DDS textures)",
        _ => "",
    };
    LoadErrorKind::UnsupportedExtension {
        name: name.to_string(),
        what: what.to_string(),
    }
}

fn convert(e: gltf::Error) -> LoadErrorKind {
    match e {
        gltf::Error::Deserialize(d) => LoadErrorKind::Gltf(format!("JSON: {d}")),
        gltf::Error::Validation(list) => {
            let mut shown: Vec<String> = list
                .iter()
                .take(3)
                .map(|(p, e)| format!("{}: {e}", p.as_str()))
                .collect();
            if list.len() > 3 {
                shown.push(format!("and {} more", list.len() - 3));
            }
            LoadErrorKind::Gltf(shown.join("; "))
        }
        other => LoadErrorKind::Gltf(other.to_string()),
    }
}
