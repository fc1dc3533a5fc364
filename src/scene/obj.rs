//! Wavefront OBJ (+ MTL) -> [`Scene`], through `tobj`.
//!
//! Conventions: OBJ has no units and no camera; +Y is taken as up, like glTF. Polygons are
//! fan-triangulated. OBJ's `vt` origin is the image's bottom-left; glTF's (and ours) is the
//! top-left, so v is flipped. OBJ files rarely have consistent winding, so every OBJ material is
//! double-sided.
//!
//! MTL mapping onto the glTF metallic-roughness [`Material`]:
//! - `Kd` -> base colour, `map_Kd` -> base colour texture, `d` (or `1 - Tr`, but not for
//!   `Tr 1`, which exporters write for opaque surfaces too) -> alpha (BLEND when below 1), `Ke`
//!   -> emissive.
//! - A map takes the place of its value, as Blender 5.2's importer links it (checked):
//!   `map_Kd` of `Kd` (Blender's exporter leaves `Kd` out when it writes `map_Kd`, and the
//!   0.8 default would darken the texture), `map_Ke` of `Ke`, `map_d` of `d` (the surface is
//!   then BLEND), `map_Pr` of `Pr`, `map_Pm` of `Pm`. The last three are data, one channel each
//!   ([`ScalarMaps`]): `-imfchan`'s, else luminance (the specification's default), and for
//!   `map_d` the alpha of an image that has transparency (what Blender reads, and all it reads:
//!   a grey mask leaves Blender's surface opaque). Blender tags `map_Pr`/`map_Pm` images
//!   sRGB, which reads a texel of 0.5 as 0.21; they are read here as the data they are authored
//!   as. A map whose image is missing or unreadable replaces nothing.
//! - `Ks` is kept as the Blinn-Phong specular colour; `Ns` (a Phong exponent, 0 to 1000)
//!   becomes roughness as Blender's MTL importer maps it, `1 - sqrt(Ns / 1000)` (Ns clamped to
//!   0..1000), so an OBJ looks here as it does in Blender (the exponent <-> GGX match
//!   `alpha² = 2 / (Ns + 2)` made most exporters' Ns 250 a roughness of 0.3 instead of 0.5).
//! - metallic is 0: classic MTL has no metalness (mirrors, `illum 5`, are left to the specular
//!   term). The "PBR extension" that Blender's and other exporters write, `Pr` (roughness) and
//!   `Pm` (metalness), is read as Blender's importer reads it: in place of what `Ns` and
//!   `illum` give.
//! - `illum` 4, 6, 7 and 9 are glass: transmission 1, `Ni` the index of refraction, `Tf` (not
//!   `Kd`) the tint of what passes.
//! - The dielectric's reflection follows `Ni` and `Ks` as Blender's MTL importer reads them
//!   (Blender 5.2, checked): `Ni` is the index of refraction (1.5 when absent) and the mean of
//!   `Ks` its "Specular IOR Level" s, which scales F0 by 2s (0.5: unchanged; 1: doubled; 0: no
//!   reflection at all). So F0 = ((Ni - 1)/(Ni + 1))² · 2·mean(Ks), and the material's ior is
//!   the one with that F0; `Ks 0 0 0` or `Ni 1` (what most exporters write for plain diffuse
//!   surfaces, the Cornell box's walls among them) leave a Lambertian surface, as
//!   `KHR_materials_specular` with factor 0. Without `Ks` the level is 1 for `illum 2` (F0
//!   doubled: 8% at Ni 1.5) and 0 for every other `illum` or none, as Blender 5.2's importer
//!   sets it (checked: `illum` 0, 1, 3 and absent give 0). A white 4%
//!   reflection on every OBJ surface made the OBJ Cornell boxes 4.6-7% brighter than Cycles.
//! - `illum 0` and `illum 1` (colour, or colour and ambient, without highlights) turn the
//!   specular term off: no dielectric reflection, Blinn-Phong specular 0 and roughness 1.
//! - `map_Bump`/`bump`/`norm` -> normal map, `-bm` its strength.
//! - Texture statements' `-s` and `-o` -> a texture transform, `-imfchan` -> a scalar map's
//!   channel; their file is the rest of the line after the options (`TextureStatement`).
//! - A file without normals is shaded as its smoothing groups (`s`) say, as Blender shades it
//!   (`super::obj_smoothing`): faces under `s 1` smooth, the others flat.
//! - Vertex colours (`v x y z r g b`, written by scanning and mesh-generating tools in place of
//!   a texture) -> the soup's colours, which multiply the base colour as glTF's COLOR_0 does.
//!   They are display colours, decoded from sRGB (as Blender 5.2's importer reads them,
//!   checked); faces without an MTL material get white instead of the grey default, so the
//!   colours show as a mesh viewer shows them.

use super::builder::{SoupBuilder, TriangleIn, VerticesIn};
use super::error::{LoadError, LoadErrorKind};
use super::image_source::ImageSource;
use super::material::{
    draw_without, AlphaMode, Channel, Material, ScalarMaps, SpecularLayer, TextureRef,
    UnusableImage,
};
use super::model::Scene;
use super::options::{Format, LoadOptions};
use super::paths::FileAccess;
use super::soup::Instance;
use super::texture::{Sampler, Texture};
use glam::{Vec2, Vec3, Vec4};
use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Loads an OBJ file whose bytes are already read.
pub(crate) fn load(path: &Path, bytes: &[u8], options: &LoadOptions) -> Result<Scene, LoadError> {
    let err = |kind| LoadError::new(path, kind);
    refuse_gltf_options(options).map_err(err)?;
    let mut steps = crate::measure::Steps::new();
    let text = checked_text(bytes).map_err(err)?;
    let access = FileAccess::new(
        path,
        options.allow_external_files,
        options.limits.max_file_bytes,
    );
    // A file without normals whose faces are in smoothing groups is parsed with the normals
    // those give written in (`obj_smoothing`); if that text does not parse, the file as it is
    // is parsed, so that the errors and their line numbers are the file's own.
    let smoothed = |t: &str| {
        super::obj_smoothing::with_smooth_normals(t)
            .and_then(|smooth| parse(path, &smooth, &access, options.strict).ok())
    };
    let (models, mtl_materials, mtl_warnings) = match smoothed(text) {
        Some(parsed) => parsed,
        None => match parse(path, text, &access, options.strict) {
            // tobj refuses a face whose vertex has no colour when others have one: give those
            // white, as a vertex without COLOR_0 is drawn in glTF, and parse again.
            Err(e) => match with_every_vertex_coloured(text) {
                Some(padded) => {
                    let mut parsed = match smoothed(&padded) {
                        Some(parsed) => parsed,
                        None => parse(path, &padded, &access, options.strict)?,
                    };
                    parsed.2.push(
                        "only some vertices have a colour (v x y z r g b); the others are drawn white"
                            .into(),
                    );
                    parsed
                }
                None => return Err(e),
            },
            Ok(parsed) => parsed,
        },
    };
    steps.mark("parse");

    let MtlMaterials {
        mut materials,
        textures,
        images,
        unusable,
    } = map_materials(&mtl_materials, &access, options)?;
    let image_warnings =
        draw_without(&mut materials, &textures, &unusable, options.strict).map_err(err)?;
    // The defaults for faces without an MTL material, appended after the MTL's as first used:
    // grey, or white for a model with vertex colours (its colours are its surface's, as a
    // viewer shows them, where grey would darken them).
    let mut defaults: Vec<Material> = Vec::new();
    let mut default_index = |material: Material| -> u32 {
        let found = defaults.iter().position(|m| m.name == material.name);
        let i = found.unwrap_or_else(|| {
            defaults.push(material);
            defaults.len() - 1
        });
        (materials.len() + i) as u32
    };
    let mut uses_default = false;
    let mut lone_material_fallback = false;

    let mut builder = SoupBuilder::new(options.limits.max_triangles);
    let mut instances = Vec::with_capacity(models.len());
    steps.mark("materials and images");
    for (model_index, model) in models.iter().enumerate() {
        let mesh = &model.mesh;
        let geometry = read_geometry(model_index, model).map_err(err)?;
        let material = match mesh.material_id {
            Some(id) if id < materials.len() => id as u32,
            // A `usemtl` naming nothing in the MTL (VikingRoom says `usemtl Texture1`, its MTL
            // defines only `room`): with a single material in the library, that is the one meant.
            _ if mtl_materials.len() == 1 => {
                lone_material_fallback = true;
                0
            }
            _ => {
                uses_default = true;
                if geometry.colors.is_empty() {
                    default_index(obj_default_material())
                } else {
                    default_index(vertex_color_material())
                }
            }
        };
        let instance = instances.len() as u32;
        instances.push(Instance {
            node: None,
            mesh: model_index,
            name: Some(model.name.clone()),
        });
        push_model(&mut builder, mesh, geometry, material, instance).map_err(err)?;
    }
    materials.extend(defaults);
    let mut warnings = mtl_warnings;
    warnings.extend(mtl_materials.iter().flat_map(mtl_out_of_range));
    warnings.extend(image_warnings);
    warnings.extend(access.recased_warnings());
    warnings.extend(builder.dropped_warning());
    if lone_material_fallback {
        warnings.push(format!(
            "faces use a material the MTL does not define; its only material '{}' is used",
            mtl_materials[0].name.trim()
        ));
    }
    if uses_default && !mtl_materials.is_empty() {
        warnings.push(
            "some faces use no material from the MTL; they get a default (grey, white under vertex colours)"
                .into(),
        );
    }
    let file_triangles = builder.offered();
    let (soup, bounds) = builder.finish();
    steps.mark("flatten");
    Ok(Scene {
        source: path.to_path_buf(),
        format: Format::Obj,
        soup,
        materials,
        textures,
        images,
        cameras: Vec::new(),
        lights: Vec::new(),
        mesh_count: models.len(),
        file_triangles,
        primitive_count: models.len(),
        instances,
        bounds,
        warnings,
        variants: Vec::new(),
        variant: None,
        extensions: Vec::new(),
        animations: Vec::new(),
        pose: None,
        load_steps: steps.list().to_vec(),
        archive: None,
        inputs: access.resolved(),
    })
}

/// Refuses the options only glTF files can honour: a material variant, a pose.
fn refuse_gltf_options(options: &LoadOptions) -> Result<(), LoadErrorKind> {
    if let Some(name) = &options.variant {
        return Err(LoadErrorKind::Variant(format!(
            "no variant '{name}': OBJ files have no material variants"
        )));
    }
    if options.pose.animates() {
        return Err(LoadErrorKind::Animation(
            "--animation/--time: OBJ files have no animations".into(),
        ));
    }
    Ok(())
}

/// The file as text: UTF-8, with face indices that tobj can resolve (see
/// [`check_face_indices`]).
fn checked_text(bytes: &[u8]) -> Result<&str, LoadErrorKind> {
    let Ok(text) = std::str::from_utf8(bytes) else {
        // Latin-1 files exist, but tobj reads lines as UTF-8; say so instead of "read error".
        return Err(LoadErrorKind::Obj(
            "the file is not UTF-8 text (is it really an OBJ file?)".into(),
        ));
    };
    check_face_indices(text).map_err(LoadErrorKind::Obj)?;
    Ok(text)
}

/// The OBJ text with `1 1 1` (white) added to every `v x y z` line, when some `v` lines have a
/// colour and others have none; `None` otherwise.
fn with_every_vertex_coloured(text: &str) -> Option<String> {
    let position_words = |line: &str| {
        let mut words = line.split_whitespace();
        (words.next() == Some("v")).then(|| words.count())
    };
    let (mut coloured, mut plain) = (false, false);
    for line in text.lines() {
        match position_words(line) {
            Some(6) => coloured = true,
            Some(3) => plain = true,
            _ => {}
        }
    }
    if !(coloured && plain) {
        return None;
    }
    let mut padded = String::with_capacity(text.len() + text.len() / 4);
    for line in text.lines() {
        padded.push_str(line);
        if position_words(line) == Some(3) {
            padded.push_str(" 1 1 1");
        }
        padded.push('\n');
    }
    Some(padded)
}

/// What [`parse`] reads: the models, the MTL materials, a warning for each unusable library.
type Parsed = (Vec<tobj::Model>, Vec<tobj::Material>, Vec<String>);

/// Parses the OBJ text with tobj (fan-triangulated), reading the MTL libraries it names through
/// `access`: the models, the MTL materials (none without a library) and a warning for each
/// library that is missing or cannot be read or parsed (its faces take the grey default, as
/// a missing texture is drawn without; `strict` makes it an error). A library outside the
/// model's folder (or a FIFO, or one past the file size limit) is refused as a texture is.
fn parse(path: &Path, text: &str, access: &FileAccess, strict: bool) -> Result<Parsed, LoadError> {
    let err = |kind| LoadError::new(path, kind);
    let mtl_error: RefCell<Option<LoadError>> = RefCell::new(None);
    let unread: RefCell<Vec<String>> = RefCell::new(Vec::new());
    // A library that cannot be used: a warning, or with `strict` the error (a missing file's,
    // naming the path looked for, when it does not exist).
    let skip = |mtl: String, problem: String, missing: Option<PathBuf>| {
        if strict {
            let problem = format!("{problem} (--strict refuses a missing MTL)");
            let kind = LoadErrorKind::Mtl { mtl, problem };
            let kind = match missing {
                Some(file) => LoadErrorKind::MissingFile {
                    file,
                    problem: Box::new(kind),
                },
                None => kind,
            };
            let mut first = mtl_error.borrow_mut();
            first.get_or_insert_with(|| err(kind));
        } else {
            unread.borrow_mut().push(format!(
                "MTL '{mtl}': {problem}; the faces using its materials get a grey default"
            ));
        }
    };
    let load_options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let carried = carry_materials_across_objects(text);
    // A byte slice is already a `BufRead`: a `BufReader` around it would copy every byte
    // once more into its 8 KiB buffer (4.5% of the Stanford bunny's load in `perf`).
    let (models, materials) =
        tobj::load_obj_buf(&mut carried.as_bytes(), &load_options, |mtl_path: &Path| {
            let name = mtl_path.to_string_lossy().into_owned();
            let resolved = access.resolve("mtllib", &name);
            let looked_for = resolved.as_ref().ok().cloned();
            match resolved.and_then(|p| access.read(&p)) {
                Ok(bytes) => {
                    let (bytes, dropped) = complete_colours(&bytes);
                    unread.borrow_mut().extend(
                        dropped
                            .into_iter()
                            .map(|problem| format!("MTL '{name}': {problem}")),
                    );
                    tobj::load_mtl_buf(&mut &bytes[..]).inspect_err(|e| {
                        skip(name.clone(), format!("cannot parse it: {e}"), None);
                    })
                }
                Err(e) => {
                    match e.kind {
                        LoadErrorKind::Io(io) => {
                            let missing =
                                looked_for.filter(|_| io.kind() == std::io::ErrorKind::NotFound);
                            skip(name, format!("cannot read it: {io}"), missing)
                        }
                        LoadErrorKind::IsDirectory => skip(name, "it is a folder".into(), None),
                        other => {
                            let problem = other.to_string();
                            let mut first = mtl_error.borrow_mut();
                            first.get_or_insert_with(|| {
                                err(LoadErrorKind::Mtl { mtl: name, problem })
                            });
                        }
                    }
                    Err(tobj::LoadError::OpenFileFailed)
                }
            }
        })
        .map_err(|e| {
            err(locate_face_error(text, &e).map_or_else(|| obj_error(e), LoadErrorKind::Obj))
        })?;
    if let Some(e) = mtl_error.into_inner() {
        return Err(e);
    }
    // tobj returns the error of a library only when no other one gave a material.
    Ok((models, materials.unwrap_or_default(), unread.into_inner()))
}

/// An MTL file's colour statements (`Ka`, `Kd`, `Ks`, `Ke`) as tobj reads them: three
/// numbers. The MTL specification lets a colour give r alone ("if only r is specified, g and b
/// are assumed equal to r"), which tobj cannot read (it panicked); such a statement gets r for
/// its missing channels. One it cannot express (`Kd spectral file.rfl`, `Kd xyz x y z`, or no
/// numbers) is left out (an empty line, so that the lines after it keep their numbers), with a
/// problem said for it, so that the file's other statements still count (tobj refused the
/// whole library). The other lines keep their bytes.
fn complete_colours(mtl: &[u8]) -> (std::borrow::Cow<'_, [u8]>, Vec<String>) {
    let colour = |line: &[u8]| -> Option<(Vec<f32>, bool)> {
        let text = std::str::from_utf8(line).ok()?;
        let mut words = text.split_ascii_whitespace();
        let keyword = words.next()?;
        if !matches!(keyword, "Ka" | "Kd" | "Ks" | "Ke") {
            return None;
        }
        let values: Vec<&str> = words.take(3).collect();
        let numbers: Vec<f32> = values.iter().map_while(|w| w.parse().ok()).collect();
        let readable = !numbers.is_empty() && numbers.len() == values.len();
        (numbers.len() < 3).then_some((numbers, readable))
    };
    if !mtl
        .split(|&b| b == b'\n')
        .any(|line| colour(line).is_some())
    {
        return (std::borrow::Cow::Borrowed(mtl), Vec::new());
    }
    let mut out = Vec::with_capacity(mtl.len() + 64);
    let mut problems = Vec::new();
    for (number, line) in mtl.split(|&b| b == b'\n').enumerate() {
        match colour(line) {
            Some((numbers, true)) => {
                let keyword = String::from_utf8_lossy(line);
                let keyword = keyword.split_ascii_whitespace().next().unwrap_or("Kd");
                let r = numbers[0];
                let [g, b] = [numbers.get(1).copied().unwrap_or(r), r];
                out.extend_from_slice(format!("{keyword} {r} {g} {b}").as_bytes());
            }
            Some((_, false)) => problems.push(format!(
                "line {}: '{}' is not read (only r g b colours are); the material keeps that colour's default",
                number + 1,
                String::from_utf8_lossy(line).trim()
            )),
            None => out.extend_from_slice(line),
        }
        out.push(b'\n');
    }
    out.pop();
    (std::borrow::Cow::Owned(out), problems)
}

/// The MTL materials mapped onto ours (see the module docs), with the textures and images
/// they use (one for each distinct file), each image's header checked; those that fail are
/// listed as unusable.
fn map_materials(
    mtl_materials: &[tobj::Material],
    access: &FileAccess,
    options: &LoadOptions,
) -> Result<MtlMaterials, LoadError> {
    let mut textures: Vec<Texture> = Vec::new();
    let mut images: Vec<ImageSource> = Vec::new();
    // Each file once: by the name as written, then by the file it resolves to (`Wood.png`,
    // `./Wood.png` and `wood.png` found by its letter case are one image, decoded once).
    let mut image_index: HashMap<String, usize> = HashMap::new();
    let mut path_index: HashMap<PathBuf, usize> = HashMap::new();
    let mut unusable = Vec::new();
    let mut texture =
        |what: &str, name: &Option<String>| -> Result<Option<MtlTexture>, LoadError> {
            let Some(name) = name.as_deref().map(str::trim).filter(|n| !n.is_empty()) else {
                return Ok(None);
            };
            let statement = texture_statement(name);
            let file = statement.file;
            let index = match image_index.get(file) {
                Some(&i) => i,
                None => {
                    let resolved = access.resolve(what, file)?;
                    if let Some(&i) = path_index.get(&resolved) {
                        image_index.insert(file.to_string(), i);
                        i
                    } else {
                        path_index.insert(resolved.clone(), textures.len());
                        let source = ImageSource {
                            origin: file.to_string(),
                            mime_type: None,
                            path: Some(resolved),
                            bytes: None,
                            in_file: None,
                            pixels: None,
                        };
                        let checked = match &source.path {
                            Some(path) if !path.is_file() => {
                                Err(format!("{what} texture '{}' not found", path.display()))
                            }
                            _ => super::image_header::check_image_header(
                                &source,
                                options.limits.max_image_pixels,
                            ),
                        };
                        if let Err(problem) = checked {
                            unusable.push(UnusableImage::new(
                                images.len(),
                                file.to_string(),
                                problem,
                                source.path.as_deref(),
                            ));
                        }
                        images.push(source);
                        textures.push(Texture {
                            name: Some(file.to_string()),
                            image: images.len() - 1,
                            fallback_image: None,
                            sampler: Sampler::default(),
                        });
                        image_index.insert(file.to_string(), textures.len() - 1);
                        textures.len() - 1
                    }
                }
            };
            let usable = !unusable.iter().any(|u| u.image == textures[index].image);
            Ok(Some((
                TextureRef {
                    texture: index,
                    tex_coord: 0,
                    transform: statement.transform(),
                },
                TextureStatementExtras {
                    bump_multiplier: statement.bump_multiplier,
                    channel: statement.channel,
                    usable,
                },
            )))
        };
    let mut materials = Vec::with_capacity(mtl_materials.len() + 1);
    for m in mtl_materials {
        let mut mat = mtl_material(m);
        let kd = texture("map_Kd", &m.diffuse_texture)?;
        if let Some((normal, extras)) = texture("map_Bump", &m.normal_texture)? {
            mat.normal_texture = Some(normal);
            // `-bm`: the bump's strength, as Blender's importer reads it for its normal map.
            if let Some(strength) = extras.bump_multiplier.filter(|b| b.is_finite()) {
                mat.normal_scale = strength;
            }
        }
        let maps = MtlMaps {
            kd,
            d: texture("map_d", &m.dissolve_texture)?,
            ke: texture("map_Ke", &unknown_param(m, "map_Ke"))?,
            pr: texture("map_Pr", &unknown_param(m, "map_Pr"))?,
            pm: texture("map_Pm", &unknown_param(m, "map_Pm"))?,
        };
        maps.apply(&mut mat);
        materials.push(mat);
    }
    Ok(MtlMaterials {
        materials,
        textures,
        images,
        unusable,
    })
}

/// Statement `key` of an MTL material that tobj does not read itself (`map_Ke`, `map_Pr`),
/// its case ignored (`map_ke`), as written after the keyword.
fn unknown_param(m: &tobj::Material, key: &str) -> Option<String> {
    m.unknown_param.get(key).cloned().or_else(|| {
        m.unknown_param
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(key))
            .map(|(_, v)| v.clone())
    })
}

/// An MTL material's colour and scalar texture maps.
struct MtlMaps {
    kd: Option<MtlTexture>,
    d: Option<MtlTexture>,
    ke: Option<MtlTexture>,
    pr: Option<MtlTexture>,
    pm: Option<MtlTexture>,
}

impl MtlMaps {
    /// Puts the maps on `mat` as Blender 5.2's importer links them (checked): each texture
    /// takes the place of its property's value (`map_Kd` of `Kd`, which Blender's exporter
    /// leaves out when it writes `map_Kd`, so a default of 0.8 would darken every such
    /// texture; `map_d` of `d`; `map_Ke` of `Ke`; `map_Pr` of `Pr`; `map_Pm` of `Pm`).
    /// `map_Kd` and `map_Ke` are colour (sRGB); `map_d`, `map_Pr` and `map_Pm` are data, one
    /// channel each (`-imfchan`; by default luminance, and for `map_d` the image's alpha
    /// where it has transparency). A surface with `map_d` is blended, as Blender's is. A
    /// texture whose image is missing or unreadable replaces nothing: the material keeps the
    /// value, and draws without the texture.
    fn apply(self, mat: &mut Material) {
        if let Some((t, extras)) = self.kd {
            mat.base_color_texture = Some(t);
            if extras.usable {
                mat.base_color = Vec4::ONE.with_w(mat.base_color.w);
            }
        }
        if let Some((t, extras)) = self.ke {
            mat.emissive_texture = Some(t);
            if extras.usable {
                mat.emissive = Vec3::ONE;
            }
        }
        let mut scalar = ScalarMaps::default();
        if let Some((t, extras)) = self.d {
            scalar.alpha = Some(t);
            scalar.alpha_channel = extras.channel.unwrap_or(Channel::AlphaOrLuminance);
            if extras.usable {
                mat.base_color.w = 1.0;
                mat.alpha_mode = AlphaMode::Blend;
            }
        }
        if let Some((t, extras)) = self.pr {
            scalar.roughness = Some(t);
            scalar.roughness_channel = extras.channel.unwrap_or_default();
            if extras.usable {
                mat.roughness = 1.0;
            }
        }
        if let Some((t, extras)) = self.pm {
            scalar.metallic = Some(t);
            scalar.metallic_channel = extras.channel.unwrap_or_default();
            if extras.usable {
                mat.metallic = 1.0;
            }
        }
        if scalar != ScalarMaps::default() {
            mat.scalar_maps = Some(scalar);
        }
    }
}

/// A texture statement of an MTL file (`map_Kd -s 2 2 1 wood grain.png`) read as the MTL
/// specification and Blender's importer read it: options first, each with its arguments,
/// then the file, which is the rest of the line (spaces included: a name with a space is not
/// cut to its last word). Options other than those kept here are skipped with their
/// arguments; an unknown one ends the options.
struct TextureStatement<'a> {
    /// The image file, as written (relative to the MTL's folder).
    file: &'a str,
    /// `-s u v w`: the texture coordinates' scale (u and v; w, for 3D textures, is ignored).
    scale: Option<[f32; 2]>,
    /// `-o u v w`: their offset.
    offset: Option<[f32; 2]>,
    /// `-bm m`: the bump multiplier (a normal map's strength).
    bump_multiplier: Option<f32>,
    /// `-imfchan r|g|b|m|l`: the channel a scalar texture (`map_d`, `map_Pr`, `map_Pm`) reads.
    channel: Option<Channel>,
}

impl TextureStatement<'_> {
    /// `-s` and `-o` as a [`TextureTransform`] in glTF's texture space. MTL's apply to OBJ's
    /// coordinates (origin bottom-left), u' = s·u + o; the importer flips v to glTF's top-left
    /// origin (v_gltf = 1 - v), where the same map is v_gltf' = s·v_gltf + (1 - s - o).
    fn transform(&self) -> Option<super::material::TextureTransform> {
        if self.scale.is_none() && self.offset.is_none() {
            return None;
        }
        let [su, sv] = self.scale.unwrap_or([1.0, 1.0]);
        let [ou, ov] = self.offset.unwrap_or([0.0, 0.0]);
        Some(super::material::TextureTransform {
            offset: [ou, 1.0 - sv - ov],
            rotation: 0.0,
            scale: [su, sv],
        })
    }
}

/// The channel `-imfchan` names (`z`, a depth channel, is no channel of an image: `None`).
fn imfchan(word: &str) -> Option<Channel> {
    match word {
        "r" => Some(Channel::Red),
        "g" => Some(Channel::Green),
        "b" => Some(Channel::Blue),
        "m" => Some(Channel::Alpha),
        "l" => Some(Channel::Luminance),
        _ => None,
    }
}

/// Reads an MTL texture statement's options and file ([`TextureStatement`]).
fn texture_statement(statement: &str) -> TextureStatement<'_> {
    let mut out = TextureStatement {
        file: statement.trim(),
        scale: None,
        offset: None,
        bump_multiplier: None,
        channel: None,
    };
    let mut rest = statement.trim_start();
    // Where the first word of `s` ends.
    let word_end = |s: &str| s.find(|c: char| c.is_ascii_whitespace()).unwrap_or(s.len());
    while rest.starts_with('-') {
        let end = word_end(rest);
        let option = &rest[..end];
        let fixed = match option {
            "-blendu" | "-blendv" | "-cc" | "-clamp" | "-imfchan" | "-texres" | "-bm"
            | "-boost" | "-type" => Some(1),
            "-mm" => Some(2),
            // One to three numbers.
            "-o" | "-s" | "-t" => None,
            _ => break,
        };
        let mut after = rest[end..].trim_start();
        let mut numbers = Vec::new();
        loop {
            let wanted = fixed.map_or(numbers.len() < 3, |n| numbers.len() < n);
            let end = word_end(after);
            if !wanted || end == 0 {
                break;
            }
            let word = &after[..end];
            let number = word.parse::<f32>().ok();
            // A variable count stops at the first word that is not a number (the file).
            if fixed.is_none() && number.is_none() {
                break;
            }
            numbers.push(number.unwrap_or(f32::NAN));
            if option == "-imfchan" {
                out.channel = imfchan(word);
            }
            after = after[end..].trim_start();
        }
        if fixed.is_some_and(|n| numbers.len() < n) || numbers.is_empty() {
            // Arguments missing: what is left is taken as the file, as written.
            break;
        }
        // v, when not given, is the option's default (1 for the scale, 0 for the offset), as
        // the specification and Blender's importer have it.
        let uv = |default: f32| [numbers[0], numbers.get(1).copied().unwrap_or(default)];
        match option {
            "-s" => out.scale = Some(uv(1.0)),
            "-o" => out.offset = Some(uv(0.0)),
            "-bm" => out.bump_multiplier = Some(numbers[0]),
            _ => {}
        }
        rest = after;
    }
    let file = rest.trim();
    if !file.is_empty() {
        out.file = file;
    }
    out.scale = out.scale.filter(|s| s.iter().all(|v| v.is_finite()));
    out.offset = out.offset.filter(|o| o.iter().all(|v| v.is_finite()));
    out
}

/// A texture reference of an MTL material, with its statement's `-bm` (bump multiplier).
type MtlTexture = (TextureRef, TextureStatementExtras);

/// What a texture statement says beyond its file and transform (`-bm` and `-imfchan`), and
/// whether its image passed the load's checks (a missing or unreadable one leaves the
/// material with the value the texture would have replaced).
#[derive(Clone, Copy)]
struct TextureStatementExtras {
    bump_multiplier: Option<f32>,
    channel: Option<Channel>,
    usable: bool,
}

/// What [`map_materials`] maps: materials, textures, images, and the images it cannot use.
struct MtlMaterials {
    materials: Vec<Material>,
    textures: Vec<Texture>,
    images: Vec<ImageSource>,
    unusable: Vec<UnusableImage>,
}

/// One OBJ model's positions, normals and texture coordinates (v flipped to glTF's top-left
/// origin), its face indices checked against them; normals and texture coordinates count only
/// when every face corner has one.
fn read_geometry(model_index: usize, model: &tobj::Model) -> Result<ObjGeometry, LoadErrorKind> {
    let mesh = &model.mesh;
    let positions: Vec<Vec3> = mesh
        .positions
        .chunks_exact(3)
        .map(|p| Vec3::new(p[0], p[1], p[2]))
        .collect();
    let normals: Vec<Vec3> = mesh
        .normals
        .chunks_exact(3)
        .map(|n| Vec3::new(n[0], n[1], n[2]))
        .collect();
    let texcoords: Vec<Vec2> = mesh
        .texcoords
        .chunks_exact(2)
        .map(|t| Vec2::new(t[0], 1.0 - t[1]))
        .collect();
    let colors = vertex_colors(&mesh.vertex_color, positions.len());
    let check = |what: &'static str, indices: &[u32], count: usize| match indices
        .iter()
        .find(|&&i| i as usize >= count)
    {
        Some(&index) => Err(LoadErrorKind::ObjIndexOutOfRange {
            model: model_index,
            name: model.name.clone(),
            what,
            index,
            count,
        }),
        None => Ok(()),
    };
    check("position", &mesh.indices, positions.len())?;
    let has_normals = mesh.normal_indices.len() == mesh.indices.len() && !normals.is_empty();
    let has_uvs = mesh.texcoord_indices.len() == mesh.indices.len() && !texcoords.is_empty();
    if has_normals {
        check("normal", &mesh.normal_indices, normals.len())?;
    }
    if has_uvs {
        check("texcoord", &mesh.texcoord_indices, texcoords.len())?;
    }
    Ok(ObjGeometry {
        positions,
        normals,
        texcoords,
        colors,
        has_normals,
        has_uvs,
    })
}

/// A model's vertex colours (the common extension `v x y z r g b`, which photogrammetry and
/// mesh-generating tools write in place of a texture), as linear RGBA, one a position; empty
/// when the model has none, or not one for every position (a file with only some coloured is
/// parsed again with the others white: [`with_every_vertex_coloured`]). They are display
/// colours, as 8-bit ones divided by 255 are: decoded from sRGB as a base colour texture is
/// (Blender's OBJ importer reads them so too). Channels are clamped to 0..1 (a NaN to 0); a
/// file whose colours go above 1 is taken to be in 0..255.
fn vertex_colors(rgb: &[f32], positions: usize) -> Vec<Vec4> {
    if rgb.is_empty() || rgb.len() != positions * 3 {
        return Vec::new();
    }
    let scale = if rgb.iter().any(|&c| c > 1.0) {
        1.0 / 255.0
    } else {
        1.0
    };
    let channel = |c: f32| {
        let c = c * scale;
        // A NaN becomes 0 (`clamp` would keep it).
        crate::color::srgb_to_linear(if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) })
    };
    rgb.chunks_exact(3)
        .map(|c| Vec4::new(channel(c[0]), channel(c[1]), channel(c[2]), 1.0))
        .collect()
}

/// Adds one OBJ model's triangles to the soup: each with vertices of its own and its flat
/// normal when the model has no normals, else indexed, a vertex for each distinct (position,
/// normal, uv) triple.
fn push_model(
    builder: &mut SoupBuilder,
    mesh: &tobj::Mesh,
    geometry: ObjGeometry,
    material: u32,
    instance: u32,
) -> Result<(), LoadErrorKind> {
    let ObjGeometry {
        positions,
        normals,
        texcoords,
        colors,
        has_normals,
        has_uvs,
    } = geometry;
    let has_colors = !colors.is_empty();
    let triangles = mesh.indices.len() / 3;
    builder.reserve(triangles)?;
    if !has_normals {
        // Flat shading: every triangle gets its own vertices with its face normal anyway,
        // so there is nothing to weld.
        for t in 0..triangles {
            let corner = [3 * t, 3 * t + 1, 3 * t + 2];
            let tri = TriangleIn {
                positions: corner.map(|k| positions[mesh.indices[k] as usize]),
                uv0: has_uvs.then(|| corner.map(|k| texcoords[mesh.texcoord_indices[k] as usize])),
                colors: has_colors.then(|| corner.map(|k| colors[mesh.indices[k] as usize])),
                ..Default::default()
            };
            builder.push(&tri, material, instance);
        }
        return Ok(());
    }
    // OBJ indexes positions, normals and texture coordinates separately; a vertex is one
    // distinct (position, normal, uv) triple, stored once however many faces share it.
    let mut vertex_of = std::collections::HashMap::with_capacity(positions.len());
    let mut vertices = ObjVertices::default();
    let mut corners = Vec::with_capacity(mesh.indices.len());
    for k in 0..triangles * 3 {
        let p = mesh.indices[k];
        let n = if has_normals {
            mesh.normal_indices[k]
        } else {
            0
        };
        let t = if has_uvs { mesh.texcoord_indices[k] } else { 0 };
        let next = vertices.positions.len();
        let v = *vertex_of.entry((p, n, t)).or_insert_with(|| {
            vertices.positions.push(positions[p as usize]);
            vertices.normals.push(normals[n as usize]);
            if has_uvs {
                vertices.uv0.push(texcoords[t as usize]);
            }
            if has_colors {
                vertices.colors.push(colors[p as usize]);
            }
            next
        });
        corners.push(v);
    }
    let vertices_in = VerticesIn {
        positions: &vertices.positions,
        normals: Some(vertices.normals.as_slice()),
        uv0: has_uvs.then_some(vertices.uv0.as_slice()),
        colors: has_colors.then_some(vertices.colors.as_slice()),
        ..Default::default()
    };
    builder.push_primitive(
        &vertices_in,
        corners.len() / 3,
        |t| [corners[3 * t], corners[3 * t + 1], corners[3 * t + 2]],
        material,
        instance,
    );
    Ok(())
}

/// OBJ material state persists across `o` and `g` statements (as in Blender and
/// tinyobjloader), but tobj starts every object without a material: VikingRoom's
/// `usemtl room` precedes its `o room` and would be lost. Repeating the current `usemtl`
/// after each `o`/`g` line makes tobj see the state the file means.
fn carry_materials_across_objects(text: &str) -> std::borrow::Cow<'_, str> {
    if !text.contains("usemtl") {
        return std::borrow::Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len() + 256);
    let mut current: Option<&str> = None;
    for line in text.lines() {
        out.push_str(line);
        out.push('\n');
        let trimmed = line.trim_start();
        if let Some(name) = trimmed.strip_prefix("usemtl") {
            let name = name.trim();
            current = (!name.is_empty()).then_some(name);
        } else if trimmed.starts_with("o ")
            || trimmed.starts_with("g ")
            || trimmed == "o"
            || trimmed == "g"
        {
            if let Some(name) = current {
                out.push_str("usemtl ");
                out.push_str(name);
                out.push('\n');
            }
        }
    }
    std::borrow::Cow::Owned(out)
}

/// Refuses face indices that tobj would resolve past the ends of `usize`: it turns an index x
/// into `count + x` (negative, relative) or `x - 1` (positive) as a `usize` and multiplies it by
/// three, so a relative index reaching before the first element, or a zero, or one near
/// 2⁶³, overflowed: a panic in builds with overflow checks, and without them a wrapped index
/// that could land inside the array and silently take the wrong normal (found by the `obj`
/// fuzz target). Relative indices are checked against the elements read so far (what they
/// count back from); absolute ones only against `u32::MAX` (tobj resolves them after the
/// whole file, so a face may name a vertex that comes later, and reports those past the end).
fn check_face_indices(text: &str) -> Result<(), String> {
    // One pass over the bytes, lines found with memchr and only their first bytes looked at,
    // each face part read in one pass by hand. It costs the Stanford bunny's `info` 14% more
    // instructions (callgrind, 269M -> 308M); with `str::lines`, `split_whitespace`,
    // `split('/')` and `str::parse` it was 25%. A line whose first word might start after
    // Unicode whitespace (tobj splits on it) takes the `str` path.
    let bytes = text.as_bytes();
    let ends_word = |b: Option<&u8>| b.is_none_or(is_blank);
    let mut read = [0u64; 3];
    let mut start = 0;
    let mut number = 0;
    while start < bytes.len() {
        let end = memchr::memchr(b'\n', &bytes[start..]).map_or(bytes.len(), |n| start + n);
        let line = &bytes[start..end];
        let first = line.iter().position(|b| !is_blank(b)).unwrap_or(line.len());
        match &line[first..] {
            [b'v', rest @ ..] if ends_word(rest.first()) => read[0] += 1,
            [b'v', b't', rest @ ..] if ends_word(rest.first()) => read[1] += 1,
            [b'v', b'n', rest @ ..] if ends_word(rest.first()) => read[2] += 1,
            [b'f', rest @ ..] if ends_word(rest.first()) => check_face(rest, number, &read)?,
            [lead, ..] if *lead >= 0x80 => {
                // Split at '\n', an ASCII byte: whole characters.
                let line = std::str::from_utf8(line).unwrap_or_default();
                let mut words = line.split_whitespace();
                match words.next() {
                    Some("v") => read[0] += 1,
                    Some("vt") => read[1] += 1,
                    Some("vn") => read[2] += 1,
                    Some("f") => {
                        let rest = words.collect::<Vec<_>>().join(" ");
                        check_face(rest.as_bytes(), number, &read)?;
                    }
                    _ => {}
                }
            }
            _ => {}
        }
        start = end + 1;
        number += 1;
    }
    Ok(())
}

/// ASCII whitespace as `str::split_whitespace` sees it.
fn is_blank(b: &u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\r' | 0x0b | 0x0c)
}

/// The indices of one face's words (`v`, `v/vt`, `v//vn`, `v/vt/vn`), separated by ASCII
/// whitespace or any non-ASCII byte, against `read` = the (vertices, texture coordinates,
/// normals) read before line `number` (from 0). A number is read as tobj reads it
/// (`isize::from_str`: an optional sign, digits); a part that is not one is tobj's to report.
fn check_face(words: &[u8], number: usize, read: &[u64; 3]) -> Result<(), String> {
    const WHAT: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    let separator = |b: u8| is_blank(&b) || b >= 0x80;
    let n = words.len();
    // Which of a word's parts the next number is: 0, 1 or 2 after as many slashes.
    let mut slot = 0;
    let mut i = 0;
    while i < n {
        let b = words[i];
        if b == b'/' {
            slot += 1;
            i += 1;
            continue;
        }
        if separator(b) {
            slot = 0;
            i += 1;
            continue;
        }
        // One part, in one pass: sign, digits (saturating: anything past u32::MAX fails
        // either way), and whether it ends where the part ends.
        let from = i;
        let negative = b == b'-';
        if b == b'-' || b == b'+' {
            i += 1;
        }
        let digits = i;
        let mut value = 0u64;
        while i < n && words[i].is_ascii_digit() {
            value = value
                .saturating_mul(10)
                .saturating_add(u64::from(words[i] - b'0'));
            i += 1;
        }
        let number_ends = i > digits && (i == n || words[i] == b'/' || separator(words[i]));
        while i < n && words[i] != b'/' && !separator(words[i]) {
            i += 1;
        }
        let Some(&count) = read.get(slot).filter(|_| number_ends) else {
            continue;
        };
        let fits = value != 0
            && if negative {
                value <= count
            } else {
                value <= u64::from(u32::MAX)
            };
        if !fits {
            return Err(format!(
                "line {}: face index {} refers to a {} that does not exist ({count} read \
                 before it; OBJ indices start at 1, or count back from -1)",
                number + 1,
                String::from_utf8_lossy(&words[from..i]),
                WHAT[slot],
            ));
        }
    }
    Ok(())
}

fn obj_error(e: tobj::LoadError) -> LoadErrorKind {
    use tobj::LoadError as E;
    let what = match e {
        E::OpenFileFailed => "cannot open the file",
        E::ReadError => "read error (is it text?)",
        E::UnrecognizedCharacter => "unrecognized character",
        E::PositionParseError => "bad vertex position ('v' line)",
        E::NormalParseError => "bad normal ('vn' line)",
        E::TexcoordParseError => "bad texture coordinate ('vt' line)",
        E::FaceParseError => {
            "bad face ('f' line): index zero, not a number, or past the vertices read so far"
        }
        E::MaterialParseError => "bad material statement",
        E::InvalidObjectName => "bad object name",
        E::FaceVertexOutOfBounds => "a face refers to a vertex that does not exist",
        E::FaceTexCoordOutOfBounds => "a face refers to a texture coordinate that does not exist",
        E::FaceNormalOutOfBounds => "a face refers to a normal that does not exist",
        E::FaceColorOutOfBounds => "a face refers to a vertex colour that does not exist",
        E::InvalidPolygon => "a face has fewer than three vertices",
        _ => return LoadErrorKind::Obj(format!("{e}")),
    };
    LoadErrorKind::Obj(what.to_string())
}

/// tobj's face errors say neither line nor index: this finds the face again in `text` (only on
/// that error path) and says both, numbering lines from 1 as [`check_face_indices`] does. For
/// `FaceParseError` the first face part that is not a number (or a fourth `/` part); for an
/// index out of bounds the first absolute index past what the whole file holds (tobj resolves
/// them after the last line; zero and relative indices were refused by `check_face_indices`).
/// `None` for other errors, or when no face matches (then tobj's own words are used).
fn locate_face_error(text: &str, error: &tobj::LoadError) -> Option<String> {
    use tobj::LoadError as E;
    const WHAT: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    let slot = match error {
        E::FaceParseError => None,
        E::FaceVertexOutOfBounds | E::FaceColorOutOfBounds => Some(0),
        E::FaceTexCoordOutOfBounds => Some(1),
        E::FaceNormalOutOfBounds => Some(2),
        _ => return None,
    };
    let mut count = [0u64; 3];
    if slot.is_some() {
        for line in text.lines() {
            match line.split_whitespace().next() {
                Some("v") => count[0] += 1,
                Some("vt") => count[1] += 1,
                Some("vn") => count[2] += 1,
                _ => {}
            }
        }
    }
    text.lines().enumerate().find_map(|(index, line)| {
        let mut words = line.split_whitespace();
        let keyword = words.next()?;
        // tobj parses `l` lines as faces too (and drops them later), but resolves only faces.
        if !(keyword == "f" || keyword == "l" && slot.is_none()) {
            return None;
        }
        let number = index + 1;
        words.find_map(|word| {
            let parts: Vec<&str> = word.split('/').collect();
            match slot {
                None => {
                    let bad = parts.len() > 3
                        || parts
                            .iter()
                            .any(|p| !p.is_empty() && p.parse::<isize>().is_err());
                    bad.then(|| {
                        format!(
                            "line {number}: bad face ('{keyword}' line): '{word}' is not an index \
                             (v, v/vt, v//vn or v/vt/vn, each a whole number)"
                        )
                    })
                }
                Some(k) => {
                    let part = parts.get(k)?;
                    let past = part
                        .parse::<i64>()
                        .ok()
                        .filter(|&i| i > 0 && i as u64 > count[k]);
                    past.map(|_| {
                        format!(
                            "line {number}: face index {part} refers to a {} that does not exist \
                             (the file has {})",
                            WHAT[k], count[k]
                        )
                    })
                }
            }
        })
    })
}

/// Grey, rough, double-sided: what an OBJ face without a material looks like.
/// The material of faces with vertex colours and no MTL material: the grey default's, white,
/// so that the colours are drawn as they are.
fn vertex_color_material() -> Material {
    Material {
        name: Some("vertex colours".into()),
        base_color: Vec4::ONE,
        ..obj_default_material()
    }
}

fn obj_default_material() -> Material {
    Material {
        name: Some("default".into()),
        base_color: Vec4::new(0.8, 0.8, 0.8, 1.0),
        metallic: 0.0,
        roughness: 1.0,
        double_sided: true,
        ..Material::default()
    }
}

/// Maps one MTL material onto the glTF model, as the module docs describe.
fn mtl_material(m: &tobj::Material) -> Material {
    let alpha = m
        .dissolve
        .or_else(|| transparency(m).map(|tr| 1.0 - tr))
        .unwrap_or(1.0)
        .clamp(0.0, 1.0);
    // A diffuse colour reflects at most what arrives: Kd in [0, 1] (`mtl_out_of_range` warns).
    let kd =
        m.diffuse
            .unwrap_or([0.8, 0.8, 0.8])
            .map(|c| if c.is_nan() { 0.8 } else { c.clamp(0.0, 1.0) });
    let roughness = m
        .shininess
        .filter(|ns| ns.is_finite() && *ns >= 0.0)
        .map_or(1.0, |ns| 1.0 - (ns.min(1000.0) / 1000.0).sqrt());
    let no_highlights = matches!(m.illumination_model, Some(0 | 1));
    // The MTL "PBR extension" (Blender's exporter writes it when asked, as do Substance and
    // others): Pr, the roughness, and Pm, the metalness, as Blender's importer reads them
    // (each in place of what Ns and illum would give).
    let pbr = |key: &str| {
        m.unknown_param
            .get(key)
            .and_then(|v| v.split_whitespace().next()?.parse::<f32>().ok())
            .filter(|v| v.is_finite())
            .map(|v| v.clamp(0.0, 1.0))
    };
    // Ni, the index of refraction (1.5 when absent or unusable).
    let index = m
        .optical_density
        .filter(|n| n.is_finite() && *n >= 1.0)
        .unwrap_or(1.5);
    let reflection = opaque_reflection(
        index,
        m.specular,
        m.illumination_model == Some(2),
        no_highlights,
    );
    // illum 4 and 9 are glass, 6 and 7 refraction (Blender's MTL importer reads all four as
    // transparent).
    let glass = matches!(m.illumination_model, Some(4 | 6 | 7 | 9));
    // Glass passes light through its transmission filter Tf (white when absent), not Kd: that is
    // what tints the transmission lobe, as base colour does in glTF.
    let tint = if glass {
        m.unknown_param
            .get("Tf")
            .and_then(|tf| {
                let v: Vec<f32> = tf
                    .split_whitespace()
                    .filter_map(|x| x.parse().ok())
                    .collect();
                match v.as_slice() {
                    [r, g, b] => Some([*r, *g, *b]),
                    [x] => Some([*x; 3]),
                    _ => None,
                }
            })
            .unwrap_or([1.0; 3])
            .map(|c| {
                if c.is_finite() {
                    c.clamp(0.0, 1.0)
                } else {
                    1.0
                }
            })
    } else {
        kd
    };
    Material {
        name: Some(m.name.trim().to_string()),
        base_color: Vec4::new(tint[0], tint[1], tint[2], alpha),
        metallic: pbr("Pm").unwrap_or(0.0),
        roughness: pbr("Pr").unwrap_or(if no_highlights { 1.0 } else { roughness }),
        // Ke has no upper bound (an area light's is often above 1), but a negative or
        // non-finite one is no emission.
        emissive: m
            .emissive
            .map_or(Vec3::ZERO, |ke| Vec3::from(ke.map(usable_emission))),
        alpha_mode: if alpha < 1.0 {
            AlphaMode::Blend
        } else {
            AlphaMode::Opaque
        },
        // illum 4, 6, 7 and 9 are glass (refraction, with Ni as the index); Tf tints what passes.
        // Other illumination models reflect as Blender reads Ni and Ks (module docs).
        transmission: if glass { 1.0 } else { 0.0 },
        ior: if glass { index } else { reflection.0 },
        specular_layer: reflection.1,
        thin_walled: false,
        attenuation_color: Vec3::ONE,
        attenuation_distance: f32::INFINITY,
        dispersion: 0.0,
        double_sided: true,
        specular: if no_highlights {
            Some(Vec3::ZERO)
        } else {
            m.specular.map(Vec3::from)
        },
        ..Material::default()
    }
}

/// `Tr`, the transparency (1 - `d`), where `d` is absent and `Tr` leaves some of the surface:
/// `Tr 1` alone is read as no statement, as Blender 5.2 reads every `Tr` (checked), since
/// exporters write it for opaque surfaces (taking Tr for an opacity) as well as for invisible
/// ones, and an invisible model is the worse guess ([`mtl_out_of_range`] warns).
fn transparency(m: &tobj::Material) -> Option<f32> {
    m.unknown_param
        .get("Tr")
        .and_then(|t| t.split_whitespace().next()?.parse::<f32>().ok())
        .filter(|tr| *tr < 1.0)
}

/// A channel of `Ke` as emitted: itself when finite and not negative, else 0.
fn usable_emission(c: f32) -> f32 {
    if c.is_finite() && c >= 0.0 {
        c
    } else {
        0.0
    }
}

/// What [`mtl_material`] corrects in `m` (values no MTL writer means: a `Kd` outside [0, 1],
/// which would reflect more light than arrives, or a negative or non-finite `Ke`), one warning
/// each, naming the material.
fn mtl_out_of_range(m: &tobj::Material) -> Vec<String> {
    let mut problems = Vec::new();
    if let Some(kd) = m
        .diffuse
        .filter(|kd| !kd.iter().all(|c| (0.0..=1.0).contains(c)))
    {
        problems.push(format!("Kd {kd:?} is outside [0, 1]; clamped"));
    }
    let tr = m.unknown_param.get("Tr").map(|t| t.trim());
    if let (None, Some(tr)) = (
        m.dissolve,
        tr.filter(|t| t.parse::<f32>().is_ok_and(|v| v >= 1.0)),
    ) {
        problems.push(format!(
            "Tr {tr} (fully transparent) without d is read as opaque, as Blender reads it: \
             exporters write it for opaque surfaces too; write d 0 for an invisible one"
        ));
    }
    if let Some(ke) = m
        .emissive
        .filter(|ke| ke.iter().any(|&c| usable_emission(c) != c))
    {
        problems.push(format!(
            "Ke {ke:?} has a negative or non-finite channel; it emits nothing there"
        ));
    }
    let name = m.name.trim();
    problems
        .into_iter()
        .map(|p| format!("MTL material '{name}': {p}"))
        .collect()
}

/// The ior and `KHR_materials_specular` layer of a non-glass MTL material of index `index`
/// (`Ni`) and specular colour `ks` (`Ks`), as Blender's importer reads them (module docs):
/// F0 = F0(index) · 2·mean(Ks), or no reflection at all when that is 0 or the material has no
/// highlights. Without `Ks` the level is 1 for `illum 2` (`illum_2`) and 0 otherwise.
fn opaque_reflection(
    index: f32,
    ks: Option<[f32; 3]>,
    illum_2: bool,
    no_highlights: bool,
) -> (f32, Option<SpecularLayer>) {
    let absent = if illum_2 { 1.0 } else { 0.0 };
    let level = ks.map_or(absent, |k| {
        let mean = (k[0] + k[1] + k[2]) / 3.0;
        if mean.is_finite() {
            mean.clamp(0.0, 1.0)
        } else {
            absent
        }
    });
    let f0 = ((index - 1.0) / (index + 1.0)).powi(2) * 2.0 * level;
    if no_highlights || f0 <= 0.0 {
        let none = SpecularLayer {
            factor: 0.0,
            texture: None,
            color: Vec3::ONE,
            color_texture: None,
        };
        return (index, Some(none));
    }
    // The index whose F0 is f0: (1 + √F0) / (1 - √F0), F0 capped at 0.9 (an index of 37) so
    // that the denominator stays positive.
    let root = f0.min(0.9).sqrt();
    ((1.0 + root) / (1.0 - root), None)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Relative indices count back over what was read before their line, per kind;
    /// absolute ones may point forward (tobj resolves them at the end); zero, a relative
    /// index before the first element and one too big for tobj's arithmetic are refused,
    /// naming the line and the index as written, on the byte path and on the Unicode one.
    /// MTL texture statements: options with their arguments (a fixed count, or one to three
    /// numbers), then the file as the rest of the line; `-s` and `-o` as a glTF texture
    /// transform that maps every point as MTL's does in OBJ's flipped v.
    #[test]
    fn texture_statements_split_options_from_the_file() {
        let read = |line: &str| {
            let t = texture_statement(line);
            (t.file.to_string(), t.scale, t.offset, t.bump_multiplier)
        };
        assert_eq!(read("wood.png"), ("wood.png".into(), None, None, None));
        assert_eq!(
            read("  -s 2 3 1 wood grain.png "),
            ("wood grain.png".into(), Some([2.0, 3.0]), None, None)
        );
        assert_eq!(
            read("-o 0.5 -bm 0.3 -clamp on -mm 0 1 n.png"),
            ("n.png".into(), None, Some([0.5, 0.0]), Some(0.3))
        );
        assert_eq!(read("-s 4 tiles.png").1, Some([4.0, 1.0]));
        // Arguments missing, or an option not in the specification: the rest is the file.
        assert_eq!(read("-bm").0, "-bm");
        assert_eq!(read("-blendu").0, "-blendu");
        assert_eq!(read("-zoom 2 x.png").0, "-zoom 2 x.png");
        assert_eq!(read("-s nan 1 x.png"), ("x.png".into(), None, None, None));
        // The transform maps (u, 1 - v) to (s·u + o, 1 - (s·v + o)).
        let t = texture_statement("-s 2 0.5 -o 0.25 0.125 x.png")
            .transform()
            .unwrap();
        for (u, v) in [(0.0f32, 0.0f32), (0.3, 0.7), (1.0, 1.0)] {
            let (u2, v2) = (2.0 * u + 0.25, 0.5 * v + 0.125);
            let mapped = [
                t.scale[0] * u + t.offset[0],
                t.scale[1] * (1.0 - v) + t.offset[1],
            ];
            assert!((mapped[0] - u2).abs() < 1e-6 && (mapped[1] - (1.0 - v2)).abs() < 1e-6);
        }
        assert!(texture_statement("-clamp on x.png").transform().is_none());
        // -imfchan: the channel, which 'z' (depth) is not.
        let channel = |line: &str| texture_statement(line).channel;
        assert_eq!(channel("-imfchan m mask.png"), Some(Channel::Alpha));
        assert_eq!(
            channel("-clamp on -imfchan g -bm 1 m.png"),
            Some(Channel::Green)
        );
        assert_eq!(channel("-imfchan z m.png"), None);
        assert_eq!(texture_statement("-imfchan l m.png").file, "m.png");
    }

    /// Colours given by r alone (valid MTL, which tobj panicked on) get r for g and b; those
    /// in forms tobj cannot read are left out with a problem each, and the rest of the file
    /// still counts; other lines keep their bytes.
    #[test]
    fn mtl_colours_given_by_r_alone_are_completed() {
        let mtl =
            b"newmtl a\r\nKd 0.5\nKs 0.2 0.3\n# \xff\nKe spectral sun.rfl\nKa\nKd 1 0 0\nNs 10";
        let (completed, problems) = complete_colours(mtl);
        assert_eq!(
            &completed[..],
            &b"newmtl a\r\nKd 0.5 0.5 0.5\nKs 0.2 0.3 0.2\n# \xff\n\n\nKd 1 0 0\nNs 10"[..]
        );
        assert_eq!(problems.len(), 2, "{problems:?}");
        assert!(problems[0].starts_with("line 5: 'Ke spectral sun.rfl' is not read"));
        assert!(problems[1].starts_with("line 6: 'Ka' is not read"));
        let plain = b"newmtl a\nKd 1 1 1\n";
        assert!(matches!(
            complete_colours(plain).0,
            std::borrow::Cow::Borrowed(_)
        ));
        // Through the loader: the grey material, and a warning for the spectral colour.
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join("m.mtl"),
            "newmtl grey\nKd 0.5\nKe spectral sun.rfl\n",
        )
        .unwrap();
        let model = dir.path().join("m.obj");
        let obj = "mtllib m.mtl\nusemtl grey\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let scene = load(&model, obj.as_bytes(), &LoadOptions::default()).unwrap();
        assert_eq!(
            scene.materials[0].base_color,
            glam::Vec4::new(0.5, 0.5, 0.5, 1.0)
        );
        assert!(
            scene
                .warnings
                .iter()
                .any(|w| w.starts_with("MTL 'm.mtl': line 3:")),
            "{:?}",
            scene.warnings
        );
    }

    /// The MTL PBR extension's `Pr` and `Pm` set roughness and metalness (clamped to 0..1),
    /// over what `Ns` and `illum` would give; without them, Ns's roughness and no metal.
    #[test]
    fn pbr_roughness_and_metalness_are_read() {
        let material = |text: &str| {
            let mtl = tobj::load_mtl_buf(&mut text.as_bytes()).unwrap().0;
            mtl_material(&mtl[0])
        };
        let pbr = material("newmtl a\nNs 250\nillum 1\nPr 0.3\nPm 1\n");
        assert_eq!((pbr.roughness, pbr.metallic), (0.3, 1.0));
        let classic = material("newmtl a\nNs 250\nillum 2\n");
        assert_eq!((classic.roughness, classic.metallic), (0.5, 0.0));
        let outside = material("newmtl a\nPr 2\nPm -1\n");
        assert_eq!((outside.roughness, outside.metallic), (1.0, 0.0));
    }

    /// A map takes its property's place only when its image is there: a missing `map_Kd`,
    /// `map_d`, `map_Ke`, `map_Pr` or `map_Pm` leaves `Kd`, `d`, `Ke`, `Pr` and `Pm` as
    /// written (and a warning naming the material that draws without it), where a present one
    /// replaces them.
    #[test]
    fn maps_replace_their_property_only_when_their_image_is_there() {
        let dir = tempfile::tempdir().unwrap();
        let png = dir.path().join("there.png");
        image::GrayImage::from_pixel(2, 2, image::Luma([128]))
            .save(&png)
            .unwrap();
        let props = "Kd 0.2 0.5 0.9\nd 0.5\nKe 0.1 0.2 0.3\nPr 0.3\nPm 0.7\n";
        let maps = |file: &str| {
            ["Kd", "d", "Ke", "Pr", "Pm"]
                .map(|key| format!("map_{key} {file}\n"))
                .concat()
        };
        std::fs::write(
            dir.path().join("m.mtl"),
            format!(
                "newmtl gone\n{props}{}newmtl there\n{props}{}",
                maps("gone.png"),
                maps("there.png")
            ),
        )
        .unwrap();
        let model = dir.path().join("m.obj");
        let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl gone\nf 1 2 3\nusemtl there\nf 1 2 3\n";
        let scene = load(&model, obj.as_bytes(), &LoadOptions::default()).unwrap();
        let [gone, there] = [0, 1].map(|i| &scene.materials[i]);
        let values = |m: &Material| {
            (
                m.base_color,
                m.emissive,
                m.roughness,
                m.metallic,
                m.alpha_mode,
            )
        };
        assert_eq!(
            values(gone),
            (
                Vec4::new(0.2, 0.5, 0.9, 0.5),
                Vec3::new(0.1, 0.2, 0.3),
                0.3,
                0.7,
                AlphaMode::Blend
            )
        );
        assert!(
            gone.base_color_texture.is_none()
                && gone.scalar_maps.as_ref().is_none_or(|m| m.alpha.is_none())
        );
        assert!(
            scene
                .warnings
                .iter()
                .any(|w| w.contains("gone.png") && w.contains("'gone'")),
            "{:?}",
            scene.warnings
        );
        assert_eq!(
            values(there),
            (Vec4::ONE, Vec3::ONE, 1.0, 1.0, AlphaMode::Blend)
        );
        let maps = there.scalar_maps.as_ref().unwrap();
        assert!(maps.alpha.is_some() && maps.roughness.is_some() && maps.metallic.is_some());
        assert_eq!(
            (
                maps.alpha_channel,
                maps.roughness_channel,
                maps.metallic_channel
            ),
            (
                Channel::AlphaOrLuminance,
                Channel::Luminance,
                Channel::Luminance
            )
        );
    }

    /// Two spellings of one file (another letter case, a `./` prefix) are one image: the
    /// texture is decoded once however the MTL names it.
    #[test]
    fn one_file_named_two_ways_is_one_image() {
        let dir = tempfile::tempdir().unwrap();
        image::GrayImage::from_pixel(2, 2, image::Luma([9]))
            .save(dir.path().join("Wood.png"))
            .unwrap();
        std::fs::write(
            dir.path().join("m.mtl"),
            "newmtl a\nmap_Kd Wood.png\nnewmtl b\nmap_Kd wood.png\nnewmtl c\nmap_Kd ./Wood.png\n",
        )
        .unwrap();
        let model = dir.path().join("m.obj");
        let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n\
                   usemtl a\nf 1 2 3\nusemtl b\nf 1 2 3\nusemtl c\nf 1 2 3\n";
        let scene = load(&model, obj.as_bytes(), &LoadOptions::default()).unwrap();
        assert_eq!(scene.images.len(), 1, "{:?}", scene.images);
        let textures: Vec<_> = scene.materials[..3]
            .iter()
            .map(|m| m.base_color_texture.map(|t| t.texture))
            .collect();
        assert_eq!(textures, [Some(0); 3]);
    }

    #[test]
    fn face_indices_are_checked_before_tobj() {
        use super::check_face_indices as check;
        let ok = "v 0 0 0\nv 1 0 0\nvt 0 0\nvn 0 0 1\nf -2/-1/-1 -1/1/1 3\nv 0 1 0\nf 1 2 +3\n";
        assert_eq!(check(ok), Ok(()));
        for (text, line, token) in [
            ("v 0 0 0\nf 0 1 2\n", 2, "0"),
            ("v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n", 3, "-3"),
            ("v 0 0 0\nvt 0 0\nf 1/-2 1/1 1/1\n", 3, "-2"),
            ("vn 0 0 1\nv 0 0 0\nf 1//1 1//-2 1//1\n", 3, "-2"),
            ("v 0 0 0\nf 1 1 4294967296\n", 2, "4294967296"),
            (
                "v 0 0 0\nf 1 1 12345678901234567890123\n",
                2,
                "12345678901234567890123",
            ),
            ("v 0 0 0\n\u{3000}f 1 1 -7\n", 2, "-7"),
        ] {
            let problem = check(text).expect_err(text);
            assert!(
                problem.starts_with(&format!("line {line}: face index {token} ")),
                "{text:?}: {problem}"
            );
        }
    }

    /// Vertex colours are display colours: decoded from sRGB, 0..255 files scaled, channels
    /// clamped (a NaN to 0), and none when not every position has one.
    #[test]
    fn vertex_colours_are_decoded_from_srgb() {
        let half = crate::color::srgb_to_linear(0.5);
        assert_eq!(
            vertex_colors(&[1.0, 0.5, 0.0], 1),
            [Vec4::new(1.0, half, 0.0, 1.0)]
        );
        assert_eq!(
            vertex_colors(&[255.0, 127.5, 0.0], 1),
            vertex_colors(&[1.0, 0.5, 0.0], 1)
        );
        assert_eq!(
            vertex_colors(&[f32::NAN, -1.0, 0.5, 0.0, 0.0, 0.0], 2)[0],
            Vec4::new(0.0, 0.0, half, 1.0)
        );
        assert!(vertex_colors(&[1.0, 1.0, 1.0], 2).is_empty());
        assert!(vertex_colors(&[], 2).is_empty());
    }

    /// A model with vertex colours carries them into the soup. Without an MTL material its
    /// faces get a white default (the colours drawn as they are), not the grey one; with one,
    /// the colours multiply its `Kd`, as glTF's COLOR_0 multiplies the base colour.
    #[test]
    fn vertex_colours_reach_the_soup_over_a_white_default() {
        let dir = tempfile::tempdir().unwrap();
        let model = dir.path().join("coloured.obj");
        let text = "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n";
        let scene = load(&model, text.as_bytes(), &LoadOptions::default()).unwrap();
        assert_eq!(
            scene.soup.corner_colors(0),
            Some([
                Vec4::new(1.0, 0.0, 0.0, 1.0),
                Vec4::new(0.0, 1.0, 0.0, 1.0),
                Vec4::new(0.0, 0.0, 1.0, 1.0)
            ])
        );
        assert_eq!(scene.materials.len(), 1);
        assert_eq!(scene.materials[0].base_color, Vec4::ONE);
        assert_eq!(scene.soup.attributes(), ["colors"]);

        // A coloured model and a plain one in one file.
        let text = "o a\nv 0 0 0 1 1 1\nv 1 0 0 1 1 1\nv 0 1 0 1 1 1\nf 1 2 3\n\
                    o b\nv 0 0 1\nv 1 0 1\nv 0 1 1\nf 4 5 6\n";
        let scene = load(&model, text.as_bytes(), &LoadOptions::default()).unwrap();
        // The vertices without a colour are white, with a warning.
        assert_eq!(scene.soup.corner_colors(1).map(|c| c[0]), Some(Vec4::ONE));
        assert!(
            scene
                .warnings
                .iter()
                .any(|w| w.starts_with("only some vertices have a colour")),
            "{:?}",
            scene.warnings
        );

        std::fs::write(dir.path().join("m.mtl"), "newmtl m\nKd 0.5 0.5 0.5\n").unwrap();
        let text = "mtllib m.mtl\nusemtl m\nv 0 0 0 1 0 0\nv 1 0 0 1 0 0\nv 0 1 0 1 0 0\nf 1 2 3\n";
        let scene = load(&model, text.as_bytes(), &LoadOptions::default()).unwrap();
        assert_eq!(scene.materials.len(), 1);
        assert_eq!(scene.materials[0].base_color.truncate(), Vec3::splat(0.5));
        assert_eq!(
            scene.soup.corner_colors(0).map(|c| c[0]),
            Some(Vec4::new(1.0, 0.0, 0.0, 1.0))
        );

        let plain = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let scene = load(&model, plain.as_bytes(), &LoadOptions::default()).unwrap();
        assert_eq!(scene.soup.corner_colors(0), None);
        assert!(scene.soup.attributes().is_empty());
        assert_eq!(
            scene.materials[0].base_color,
            obj_default_material().base_color
        );
    }

    /// A missing material library is a warning naming it, its faces grey; `--strict` refuses
    /// it, and a library outside the model's folder is refused either way.
    #[test]
    fn a_missing_mtl_is_a_warning_unless_strict() {
        let dir = tempfile::tempdir().unwrap();
        let model = dir.path().join("m").join("nomtl.obj");
        std::fs::create_dir(dir.path().join("m")).unwrap();
        std::fs::write(dir.path().join("outside.mtl"), "newmtl a\nKd 1 0 0\n").unwrap();
        let text =
            |mtl: &str| format!("mtllib {mtl}\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let lenient = LoadOptions::default();
        let scene = load(&model, text("gone.mtl").as_bytes(), &lenient).unwrap();
        assert_eq!(scene.materials.len(), 1);
        assert_eq!(
            scene.materials[0].base_color,
            obj_default_material().base_color
        );
        assert!(
            scene
                .warnings
                .iter()
                .any(|w| w.starts_with("MTL 'gone.mtl': cannot read it")),
            "{:?}",
            scene.warnings
        );
        let strict = LoadOptions {
            strict: true,
            ..LoadOptions::default()
        };
        let refused = load(&model, text("gone.mtl").as_bytes(), &strict).unwrap_err();
        assert!(
            matches!(&refused.kind, LoadErrorKind::MissingFile { problem, .. }
                if matches!(problem.as_ref(), LoadErrorKind::Mtl { mtl, problem }
                    if mtl == "gone.mtl" && problem.contains("--strict"))),
            "{refused}"
        );
        // A missing library is a missing file, named as the path looked for.
        assert_eq!(
            refused.missing_file(),
            Some(dir.path().join("m").join("gone.mtl").as_path())
        );
        let outside = load(&model, text("../outside.mtl").as_bytes(), &lenient).unwrap_err();
        assert!(
            matches!(&outside.kind, LoadErrorKind::Mtl { problem, .. } if problem.contains("outside")),
            "{outside}"
        );
    }

    /// Face errors tobj reports without a position get their line and index: an index past
    /// the file's vertices, texture coordinates or normals, and a part that is not a number.
    #[test]
    fn face_errors_from_tobj_name_their_line() {
        let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
        for (body, expected) in [
            (
                "f 1 2 4\n",
                "line 4: face index 4 refers to a vertex that does not exist (the file has 3)",
            ),
            (
                "f 1 2 3\n# two\nf 1 2 3 7\n",
                "line 6: face index 7 refers to a vertex",
            ),
            (
                "vt 0 0\nf 1/1 2/1 3/2\n",
                "line 5: face index 2 refers to a texture coordinate",
            ),
            (
                "vn 0 0 1\nf 1//1 2//1 3//5\n",
                "line 5: face index 5 refers to a normal",
            ),
            (
                "f a b c\n",
                "line 4: bad face ('f' line): 'a' is not an index",
            ),
            (
                "f 1 2 3\r\nf 1 2/x 3\r\n",
                "line 5: bad face ('f' line): '2/x' is not an index",
            ),
            (
                "f 1/1/1/1 2 3\n",
                "line 4: bad face ('f' line): '1/1/1/1' is not an index",
            ),
            // Under a smoothing group (whose normals are written into the text before tobj
            // reads it), the errors still name the file's own lines.
            (
                "s 1\nf 1 2 3\nf 1 2 4\n",
                "line 6: face index 4 refers to a vertex",
            ),
            (
                "s 1\nvt 0 0\nf 1/1 2/1 3/2\n",
                "line 6: face index 2 refers to a texture",
            ),
        ] {
            let text = format!("{tri}{body}");
            let e = load(Path::new("m.obj"), text.as_bytes(), &LoadOptions::default()).unwrap_err();
            assert!(
                matches!(&e.kind, LoadErrorKind::Obj(m) if m.starts_with(expected)),
                "{body:?}: {e}"
            );
        }
    }

    /// Every glass `illum` refracts with `Ni` (water: 1.33) and is tinted by `Tf`, not `Kd`;
    /// other models do not transmit.
    #[test]
    fn glass_illumination_models_refract_with_ni() {
        for illum in [4, 6, 7, 9] {
            let m = tobj::Material {
                illumination_model: Some(illum),
                optical_density: Some(1.33),
                diffuse: Some([0.2, 0.3, 0.4]),
                ..Default::default()
            };
            let mat = mtl_material(&m);
            assert_eq!((mat.transmission, mat.ior), (1.0, 1.33), "illum {illum}");
            assert_eq!(
                mat.base_color,
                Vec4::ONE,
                "illum {illum}: Tf (absent) tints, not Kd"
            );
        }
        let plain = tobj::Material {
            illumination_model: Some(2),
            optical_density: Some(1.0),
            ..Default::default()
        };
        assert_eq!(mtl_material(&plain).transmission, 0.0);
    }

    /// Opaque materials reflect as Blender reads `Ni` and `Ks`: F0 = F0(Ni)·2·mean(Ks) through
    /// the ior; `Ks 0`, `Ni 1` and `illum 1` reflect nothing (a specular layer of factor 0);
    /// without `Ks`, `illum 2` doubles the index's F0 and any other `illum` (or none) reflects
    /// nothing, as Blender 5.2's importer sets the "Specular IOR Level" (1 and 0).
    #[test]
    fn opaque_reflection_follows_ni_and_ks_as_blender_reads_them() {
        let f0 = |ior: f32| ((ior - 1.0) / (ior + 1.0)).powi(2);
        let material = |ni: Option<f32>, ks: Option<[f32; 3]>, illum: Option<u8>| {
            mtl_material(&tobj::Material {
                illumination_model: illum,
                optical_density: ni,
                specular: ks,
                ..Default::default()
            })
        };
        let no_reflection = Some(0.0);
        let factor = |m: &Material| m.specular_layer.as_ref().map(|l| l.factor);
        let doubled = material(None, None, Some(2));
        assert!(doubled.specular_layer.is_none());
        assert!(
            (f0(doubled.ior) - 0.08).abs() < 1e-5,
            "F0 {}",
            f0(doubled.ior)
        );
        for illum in [None, Some(0), Some(1), Some(3), Some(5)] {
            let m = material(None, None, illum);
            assert_eq!(factor(&m), no_reflection, "illum {illum:?} without Ks");
        }
        // Unusable values (a hostile MTL) fall back to the defaults: Ni 1.5, Ks as if absent.
        let hostile = material(Some(f32::NAN), Some([0.5; 3]), Some(2));
        assert!((hostile.ior - 1.5).abs() < 1e-5 && hostile.specular_layer.is_none());
        let hostile = material(None, Some([f32::NAN, 0.5, 0.5]), Some(2));
        assert!((hostile.ior - doubled.ior).abs() < 1e-5 && hostile.specular_layer.is_none());
        let m = material(Some(f32::INFINITY), Some([f32::INFINITY; 3]), Some(2));
        assert!(m.ior.is_finite() && m.ior >= 1.0, "ior {}", m.ior);
        for (ni, ks, expected) in [
            (Some(1.5), [0.5; 3], 0.04),
            (Some(1.5), [1.0; 3], 0.08),
            (Some(1.5), [0.2, 0.4, 0.6], 0.032),
            (Some(2.0), [0.25; 3], f0(2.0) * 0.5),
        ] {
            let m = material(ni, Some(ks), Some(2));
            assert!(m.specular_layer.is_none());
            assert!(
                (f0(m.ior) - expected).abs() < 1e-5,
                "Ni {ni:?} Ks {ks:?}: F0 {} against {expected}",
                f0(m.ior)
            );
        }
        for (ni, ks, illum) in [
            (Some(1.5), Some([0.0; 3]), 2),
            (Some(1.0), Some([0.5; 3]), 2),
            (Some(1.0), None, 2),
            (None, Some([1.0; 3]), 1),
        ] {
            let m = material(ni, ks, Some(illum));
            assert_eq!(
                factor(&m),
                no_reflection,
                "Ni {ni:?} Ks {ks:?} illum {illum}: no reflection"
            );
        }
    }

    #[test]
    fn phong_exponent_maps_to_roughness() {
        let mut m = tobj::Material {
            shininess: Some(0.0),
            ..Default::default()
        };
        assert!((mtl_material(&m).roughness - 1.0).abs() < 1e-6);
        // Blender's importer: 1 - sqrt(Ns / 1000).
        for (ns, roughness) in [(1000.0, 0.0), (250.0, 0.5), (90.0, 0.7), (5000.0, 0.0)] {
            m.shininess = Some(ns);
            let r = mtl_material(&m).roughness;
            assert!(
                (r - roughness).abs() < 1e-6,
                "Ns {ns}: {r}, not {roughness}"
            );
        }
    }

    #[test]
    fn material_state_carries_across_objects() {
        let text = carry_materials_across_objects("usemtl a\no x\nf 1 2 3\ng y\nusemtl b\n");
        assert_eq!(
            text,
            "usemtl a\no x\nusemtl a\nf 1 2 3\ng y\nusemtl a\nusemtl b\n"
        );
    }

    #[test]
    fn illum_1_has_no_highlights() {
        let m = tobj::Material {
            shininess: Some(500.0),
            specular: Some([1.0; 3]),
            illumination_model: Some(1),
            ..Default::default()
        };
        let mat = mtl_material(&m);
        assert_eq!((mat.roughness, mat.specular), (1.0, Some(Vec3::ZERO)));
    }

    /// A `Kd` outside [0, 1] is clamped (NaN: the default 0.8), a negative or non-finite
    /// `Ke` channel emits nothing while a bright one (an area light's 17) is kept; each
    /// correction is one warning naming the material, and a valid material has none.
    #[test]
    fn kd_and_ke_out_of_range_are_corrected_with_warnings() {
        let m = tobj::Material {
            name: "lamp ".into(),
            diffuse: Some([50.0, -1.0, f32::NAN]),
            emissive: Some([-1.0, f32::INFINITY, 17.0]),
            ..Default::default()
        };
        let mat = mtl_material(&m);
        assert_eq!(mat.base_color, Vec4::new(1.0, 0.0, 0.8, 1.0));
        assert_eq!(mat.emissive, Vec3::new(0.0, 0.0, 17.0));
        assert_eq!(
            mtl_out_of_range(&m),
            [
                "MTL material 'lamp': Kd [50.0, -1.0, NaN] is outside [0, 1]; clamped",
                "MTL material 'lamp': Ke [-1.0, inf, 17.0] has a negative or non-finite channel; it emits nothing there",
            ]
        );
        let valid = tobj::Material {
            diffuse: Some([0.0, 0.5, 1.0]),
            emissive: Some([17.0, 12.0, 4.0]),
            ..Default::default()
        };
        assert!(mtl_out_of_range(&valid).is_empty());
        assert_eq!(mtl_material(&valid).emissive, Vec3::new(17.0, 12.0, 4.0));
    }

    #[test]
    fn transparency_from_tr() {
        let mut m = tobj::Material::default();
        m.unknown_param.insert("Tr".into(), "0.25".into());
        let mat = mtl_material(&m);
        assert_eq!(mat.base_color.w, 0.75);
        assert_eq!(mat.alpha_mode, AlphaMode::Blend);
        // Tr 1 alone: opaque, with a warning; d, when given, decides.
        m.unknown_param.insert("Tr".into(), "1".into());
        assert_eq!(mtl_material(&m).alpha_mode, AlphaMode::Opaque);
        assert!(mtl_out_of_range(&m)[0].contains("Tr 1 (fully transparent) without d"));
        m.dissolve = Some(0.5);
        assert_eq!(mtl_material(&m).base_color.w, 0.5);
        assert!(mtl_out_of_range(&m).is_empty());
    }
}

/// One OBJ mesh's distinct vertices.
#[derive(Default)]
struct ObjVertices {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uv0: Vec<Vec2>,
    colors: Vec<Vec4>,
}

/// One OBJ model's vertex attributes as read, before they are welded into vertices.
struct ObjGeometry {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    texcoords: Vec<Vec2>,
    /// The vertex colours (`v x y z r g b`), linear, one a position; empty without them.
    colors: Vec<Vec4>,
    /// Every face corner has a normal.
    has_normals: bool,
    /// Every face corner has texture coordinates.
    has_uvs: bool,
}
