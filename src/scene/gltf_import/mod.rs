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
mod draco;
mod material;
mod meshopt;
mod pose;
mod textures;
mod validate;

pub(crate) use container::{read_glb_deferring_images, DeferredImages};

use super::builder::VerticesIn;
use super::error::PrimitiveAt;
use super::extensions::{known, ExtensionUse};
use super::{
    Bounds, Camera, FileAccess, Format, Instance, Light, LightKind, LoadError, LoadErrorKind,
    LoadOptions, LoadedFile, Material, Projection, Scene, SoupBuilder,
};
use buffer::Buffer;
use container::{check_glb_header, load_buffers, parse};
use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
use gltf::accessor::Dimensions;
use gltf::mesh::Mode;
use material::material;
use pose::{skin_vertices, Pose, Skinning};
use std::collections::HashMap;
use std::path::Path;
use std::rc::Rc;
use textures::{choose_texture_sources, images, textures};
use validate::{
    accessor_error, check_accessor, check_accessor_type, check_attribute_indices, check_views,
    validate, Expect, COLOR, INDICES, JOINTS, MORPH_NORMAL, MORPH_POSITION, MORPH_TANGENT, NORMAL,
    POSITION, TANGENT, TEXCOORD, WEIGHTS,
};

/// Most node visits a hierarchy may expand to. A node shared by two parents is instanced twice,
/// so 30 levels of sharing would be 2^30 visits: refuse such files instead of hanging.
const MAX_NODE_VISITS: usize = 1_000_000;

/// Loads a glTF or GLB file whose bytes are already read.
/// `file`, when it holds `bytes`, lets images embedded in a GLB share it instead of copying.
pub(crate) fn load(
    path: &Path,
    bytes: &[u8],
    file: Option<LoadedFile>,
    options: &LoadOptions,
) -> Result<Scene, LoadError> {
    let err = |kind| LoadError::new(path, kind);
    let mut steps = crate::measure::Steps::new();
    check_glb_header(bytes).map_err(err)?;
    let format = if bytes.starts_with(b"glTF") {
        Format::Glb
    } else {
        Format::Gltf
    };
    let (document, blob) = parse(bytes, format).map_err(|e| err(convert(e)))?;
    let required: Vec<&str> = document.extensions_required().collect();
    for name in &required {
        if known(name).is_none_or(|e| e.refused_when_required) {
            return Err(err(unsupported_extension(name)));
        }
    }
    // extensionsUsed should list every required one; a file that forgets is still reported.
    let mut extensions: Vec<ExtensionUse> = document
        .extensions_used()
        .map(|name| ExtensionUse::new(name, required.contains(&name)))
        .collect();
    for name in &required {
        if !extensions.iter().any(|e| e.name == *name) {
            extensions.push(ExtensionUse::new(name, true));
        }
    }
    let mut root = document.into_json();
    // Checked above; gltf-json's validation refuses required extensions it does not know
    // itself (KHR_mesh_quantization, the meshopt ones, EXT_texture_webp), which we decode here.
    root.extensions_required.clear();
    let webp_fallbacks = choose_texture_sources(&mut root);
    check_attribute_indices(&root).map_err(err)?;
    pose::check_channel_targets(&root).map_err(|p| err(LoadErrorKind::Gltf(p)))?;
    let document = validate(root).map_err(|e| err(convert(e)))?;
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
    let animations = pose::list_animations(&document, &buffers, &mut pose_warnings);
    let pose = pose::pose(&document, &buffers, &animations, &options.pose)
        .map_err(|p| err(LoadErrorKind::Animation(p)))?;
    let pose_description = pose.description.clone();
    steps.mark("parse");
    let mut importer = Importer {
        document: &document,
        buffers: &buffers,
        builder: SoupBuilder::new(options.limits.max_triangles),
        warnings: pose_warnings,
        instances: Vec::new(),
        cameras: Vec::new(),
        lights: Vec::new(),
        default_material: document.materials().len() as u32,
        uses_default_material: false,
        primitive_count: 0,
        skipped_non_triangle: 0,
        singular_instances: 0,
        pose,
        world: None,
        skins: HashMap::new(),
        variant,
        quantization: document
            .extensions_used()
            .any(|name| name == "KHR_mesh_quantization"),
        limits: options.limits,
        draco: HashMap::new(),
    };
    importer.walk_default_scene().map_err(err)?;
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
    image_warnings.extend(
        super::draw_without(&mut materials, &textures, &unusable, options.strict).map_err(err)?,
    );
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
    let file_triangles = builder.offered();
    let (soup, bounds) = builder.finish();
    Ok(Scene {
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
        _ => "",
    };
    LoadErrorKind::UnsupportedExtension {
        name: name.to_string(),
        what: what.to_string(),
    }
}

fn convert(e: gltf::Error) -> LoadErrorKind {
    match e {
        gltf::Error::Binary(b) => LoadErrorKind::Glb(glb_error(&b)),
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

fn glb_error(e: &gltf::binary::Error) -> String {
    use gltf::binary::Error as E;
    match e {
        E::Io(io) => format!("truncated: {io}"),
        E::Version(v) => format!("version {v}, only glTF 2 is supported"),
        E::Magic(m) => format!("bad magic {m:?}"),
        E::Length {
            length,
            length_read,
        } => format!("header declares {length} bytes of content but only {length_read} follow"),
        E::ChunkLength {
            ty,
            length,
            length_read,
        } => format!(
            "{ty:?} chunk declares {length} bytes but only {length_read} follow (truncated)"
        ),
        E::ChunkType(ty) => format!("unexpected {ty:?} chunk"),
        E::UnknownChunkType(ty) => format!("unknown chunk type {ty:?}"),
    }
}

/// The node walk's state.
struct Importer<'a> {
    document: &'a gltf::Document,
    buffers: &'a [Buffer<'a>],
    builder: SoupBuilder,
    warnings: Vec<String>,
    instances: Vec<Instance>,
    cameras: Vec<Camera>,
    lights: Vec<Light>,
    default_material: u32,
    uses_default_material: bool,
    primitive_count: usize,
    skipped_non_triangle: usize,
    singular_instances: usize,
    /// Every node's local transform and morph weights in the pose drawn.
    pose: Pose,
    /// World transforms of every node in that pose, computed for the first skin.
    world: Option<Vec<Mat4>>,
    /// Joint matrices by skin index, computed on the skin's first use.
    skins: HashMap<usize, Rc<Skinning>>,
    /// The chosen `KHR_materials_variants` variant (index, name).
    variant: Option<(u32, String)>,
    /// The file declares `KHR_mesh_quantization`: integer attribute types are allowed.
    quantization: bool,
    /// Bounds for decoders (Draco).
    limits: super::LoadLimits,
    /// Draco primitives decoded so far, by (mesh, primitive): instanced meshes decode once.
    draco: HashMap<(usize, usize), Rc<draco::Decoded>>,
}

/// One primitive's vertex data in world space.
struct WorldVertices {
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    tangents: Option<Vec<Vec4>>,
    uv0: Option<Vec<Vec2>>,
    uv1: Option<Vec<Vec2>>,
    colors: Option<Vec<Vec4>>,
    /// Placed by a skin's joints rather than by the node's world transform.
    skinned: bool,
    /// Problems met while posing, for the scene's warnings.
    warnings: Vec<String>,
}

/// How one mesh instance is deformed: its morph weights, and the skin of its node.
struct Deform<'a> {
    /// One weight per morph target (§3.7.2.2), resolved for this node and pose.
    weights: &'a [f32],
    /// The node's skin (index, joint matrices), if it has one.
    skin: Option<(usize, &'a Skinning)>,
}

impl Importer<'_> {
    fn walk_default_scene(&mut self) -> Result<(), LoadErrorKind> {
        // glTF 2.0 §3.5.1: `scene` names the default; without it, scene 0 is a reasonable choice.
        let scene = self
            .document
            .default_scene()
            .or_else(|| self.document.scenes().next())
            .ok_or(LoadErrorKind::NoScene)?;
        let nodes: Vec<gltf::Node> = self.document.nodes().collect();
        let mut on_path = vec![false; nodes.len()];
        let mut visits = 0usize;
        // An explicit stack: a hostile hierarchy a million levels deep must not overflow ours.
        enum Step {
            Enter(usize, Mat4),
            Leave(usize),
        }
        let mut stack: Vec<Step> = scene
            .nodes()
            .map(|n| Step::Enter(n.index(), Mat4::IDENTITY))
            .collect();
        stack.reverse();
        while let Some(step) = stack.pop() {
            let (index, parent) = match step {
                Step::Leave(index) => {
                    on_path[index] = false;
                    continue;
                }
                Step::Enter(index, parent) => (index, parent),
            };
            let Some(node) = nodes.get(index) else {
                continue;
            };
            if on_path[index] {
                return Err(LoadErrorKind::NodeCycle { node: index });
            }
            visits += 1;
            if visits > MAX_NODE_VISITS {
                return Err(LoadErrorKind::Gltf(format!(
                    "the node hierarchy expands to more than {MAX_NODE_VISITS} node instances (nodes shared by several parents)"
                )));
            }
            let local = self
                .pose
                .local
                .get(index)
                .copied()
                .unwrap_or(Mat4::IDENTITY);
            let world = parent * local;
            self.visit(node, world)?;
            on_path[index] = true;
            stack.push(Step::Leave(index));
            let children: Vec<usize> = node.children().map(|c| c.index()).collect();
            for child in children.into_iter().rev() {
                stack.push(Step::Enter(child, world));
            }
        }
        Ok(())
    }

    fn visit(&mut self, node: &gltf::Node, world: Mat4) -> Result<(), LoadErrorKind> {
        let name = node.name().map(str::to_string);
        if let Some(camera) = node.camera() {
            match place_camera(&camera, world, name.clone()) {
                Some(c) => self.cameras.push(c),
                None => self.warnings.push(format!(
                    "camera on node {} skipped: its transform is not finite or is singular",
                    node.index()
                )),
            }
        }
        if let Some(light) = node.light() {
            match place_light(&light, world) {
                Some(l) => self.lights.push(l),
                None => self.warnings.push(format!(
                    "light on node {} skipped: bad transform or parameters",
                    node.index()
                )),
            }
        }
        if let Some(mesh) = node.mesh() {
            let skinning = match node.skin() {
                Some(skin) => Some(self.skinning(&skin)?),
                None => None,
            };
            let targets = mesh
                .primitives()
                .map(|p| p.morph_targets().len())
                .max()
                .unwrap_or(0);
            let weights = self
                .pose
                .morph_weights(node, &mesh, targets, &mut self.warnings);
            let instance = self.instances.len() as u32;
            self.instances.push(Instance {
                node: Some(node.index()),
                mesh: mesh.index(),
                name: name.or_else(|| mesh.name().map(str::to_string)),
            });
            let det = world.determinant();
            // §3.7.3: a skinned mesh is placed by its joints alone, whatever its node's transform.
            if skinning.is_none() && (!world.is_finite() || det == 0.0 || !det.is_finite()) {
                self.singular_instances += 1;
                return Ok(());
            }
            let deform = Deform {
                weights: &weights,
                skin: node.skin().map(|s| s.index()).zip(skinning.as_deref()),
            };
            for primitive in mesh.primitives() {
                let at = PrimitiveAt {
                    mesh: mesh.index(),
                    primitive: primitive.index(),
                };
                self.add_primitive(&primitive, at, world, instance, &deform)?;
            }
        }
        Ok(())
    }

    /// The joint matrices of `skin` in the pose drawn (computed once per skin).
    fn skinning(&mut self, skin: &gltf::Skin) -> Result<Rc<Skinning>, LoadErrorKind> {
        if let Some(done) = self.skins.get(&skin.index()) {
            return Ok(Rc::clone(done));
        }
        if self.world.is_none() {
            let world = self
                .pose
                .world(self.document)
                .map_err(|node| LoadErrorKind::NodeCycle { node })?;
            self.world = Some(world);
        }
        let world = self.world.as_deref().unwrap_or(&[]);
        let inverse_bind = pose::inverse_bind_matrices(skin, self.buffers).map_err(|problem| {
            LoadErrorKind::Skin {
                skin: skin.index(),
                problem,
            }
        })?;
        let joints: Vec<Mat4> = skin
            .joints()
            .map(|j| world.get(j.index()).copied().unwrap_or(Mat4::IDENTITY))
            .collect();
        let skinning = Rc::new(Skinning::new(&joints, &inverse_bind));
        self.skins.insert(skin.index(), Rc::clone(&skinning));
        Ok(skinning)
    }

    fn add_primitive(
        &mut self,
        primitive: &gltf::Primitive,
        at: PrimitiveAt,
        world: Mat4,
        instance: u32,
        deform: &Deform,
    ) -> Result<(), LoadErrorKind> {
        let mode = primitive.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            self.skipped_non_triangle += 1;
            return Ok(());
        }
        self.primitive_count += 1;
        let draco = self.decode_draco(primitive, at)?;
        let mut vertices = self.read_vertices(primitive, at, world, draco.as_deref(), deform)?;
        self.warnings.append(&mut vertices.warnings);
        let vertex_count = vertices.positions.len();
        let indices: Vec<u32> = match (&draco, primitive.indices()) {
            // Checked against the point count and the indices accessor by draco::decode.
            (Some(decoded), indices) => {
                if let Some(accessor) = indices {
                    check_accessor_type(&accessor, at, &INDICES, self.quantization)?;
                }
                decoded.indices.clone()
            }
            (None, Some(accessor)) => {
                check_accessor(&accessor, at, &INDICES, self.quantization)?;
                let indices: Vec<u32> = attributes::read_indices(&accessor, self.buffers)
                    .unwrap_or_else(|| {
                        primitive
                            .reader(|b| self.buffers.get(b.index()).map(|b| &b[..]))
                            .read_indices()
                            .map(|r| r.into_u32().collect())
                            .unwrap_or_default()
                    });
                if let Some(&bad) = indices.iter().find(|&&i| i as usize >= vertex_count) {
                    return Err(LoadErrorKind::IndexOutOfRange {
                        at,
                        index: bad,
                        vertex_count,
                    });
                }
                indices
            }
            (None, None) => (0..vertex_count as u32).collect(),
        };
        // Draco decodes to a triangle list whatever the mode says (the extension allows
        // TRIANGLES and TRIANGLE_STRIP; a strip's triangles are already unrolled).
        let mode = if draco.is_some() {
            Mode::Triangles
        } else {
            mode
        };
        let n = indices.len();
        let triangle_count = match mode {
            Mode::Triangles => n / 3,
            _ => n.saturating_sub(2),
        };
        self.builder.reserve(triangle_count)?;
        // glTF 2.0 §3.7.2.1: a mirroring transform turns counter-clockwise into clockwise.
        // Skinned vertices are placed by their joints, not by `world`; joint matrices that
        // mirror are not looked for (no sample model has one).
        let flip = !vertices.skinned && world.determinant() < 0.0;
        let mut chosen = primitive.material();
        if let Some((variant, name)) = &self.variant {
            // KHR_materials_variants: the mapping that lists the variant replaces the material;
            // a primitive without one keeps its default.
            if let Some(mapping) = primitive
                .mappings()
                .find(|m| m.variants().contains(variant))
            {
                chosen = mapping.material();
                if chosen.index().is_none() {
                    return Err(LoadErrorKind::Variant(format!(
                        "{at}: the mapping for variant '{name}' names a material the file does not have"
                    )));
                }
            }
        }
        let material = match chosen.index() {
            Some(i) => i as u32,
            None => {
                self.uses_default_material = true;
                self.default_material
            }
        };
        let corners = |t: usize| {
            let [a, b, c] = match mode {
                Mode::Triangles => [3 * t, 3 * t + 1, 3 * t + 2],
                Mode::TriangleStrip => [t, t + 1 + t % 2, t + 2 - t % 2],
                _ => [t + 1, t + 2, 0],
            };
            let corners = if flip { [a, c, b] } else { [a, b, c] };
            corners.map(|k| indices[k] as usize)
        };
        let vertices_in = VerticesIn {
            positions: &vertices.positions,
            normals: vertices.normals.as_deref(),
            uv0: vertices.uv0.as_deref(),
            uv1: vertices.uv1.as_deref(),
            colors: vertices.colors.as_deref(),
            tangents: vertices.tangents.as_deref(),
        };
        self.builder
            .push_primitive(&vertices_in, triangle_count, corners, material, instance);
        Ok(())
    }

    /// The primitive's Draco stream decoded, if it has `KHR_draco_mesh_compression` (decoded
    /// on its first instance, shared by the others).
    fn decode_draco(
        &mut self,
        primitive: &gltf::Primitive,
        at: PrimitiveAt,
    ) -> Result<Option<Rc<draco::Decoded>>, LoadErrorKind> {
        let Some(ext) = draco::extension(primitive) else {
            return Ok(None);
        };
        let key = (at.mesh, at.primitive);
        if let Some(decoded) = self.draco.get(&key) {
            return Ok(Some(Rc::clone(decoded)));
        }
        let decoded = draco::decode(primitive, ext, self.document, self.buffers, &self.limits)
            .map_err(|problem| LoadErrorKind::Draco { at, problem })?;
        let decoded = Rc::new(decoded);
        self.draco.insert(key, Rc::clone(&decoded));
        Ok(Some(decoded))
    }

    /// Reads (and transforms to world space) the attributes the soup uses. With `draco`, the
    /// attributes its extension maps come from the decoded stream, the others from their
    /// accessors.
    fn read_vertices(
        &self,
        primitive: &gltf::Primitive,
        at: PrimitiveAt,
        world: Mat4,
        draco: Option<&draco::Decoded>,
        deform: &Deform,
    ) -> Result<WorldVertices, LoadErrorKind> {
        use gltf::Semantic;
        let decoded = |semantic: &Semantic| draco.filter(|d| d.has(&semantic.to_string()));
        let check = |accessor: &gltf::Accessor,
                     semantic: &Semantic,
                     expect: &Expect|
         -> Result<(), LoadErrorKind> {
            match decoded(semantic) {
                // draco::decode checked count, type and componentType against the stream.
                Some(_) => check_accessor_type(accessor, at, expect, self.quantization),
                None => check_accessor(accessor, at, expect, self.quantization),
            }
        };
        let position_accessor = primitive
            .get(&Semantic::Positions)
            .ok_or(LoadErrorKind::MissingPositions { at })?;
        check(&position_accessor, &Semantic::Positions, &POSITION)?;
        let count = position_accessor.count();
        let optional = |semantic: Semantic, expect: &Expect| -> Result<(), LoadErrorKind> {
            match primitive.get(&semantic) {
                None => Ok(()),
                Some(accessor) => {
                    check(&accessor, &semantic, expect)?;
                    if accessor.count() != count {
                        return Err(LoadErrorKind::Accessor {
                            at,
                            accessor: accessor.index(),
                            semantic: expect.semantic.to_string(),
                            problem: format!(
                                "count {} differs from POSITION's {count}",
                                accessor.count()
                            ),
                        });
                    }
                    Ok(())
                }
            }
        };
        // Every attribute is checked before any is read.
        optional(Semantic::Normals, &NORMAL)?;
        optional(Semantic::Tangents, &TANGENT)?;
        optional(Semantic::TexCoords(0), &TEXCOORD)?;
        optional(Semantic::TexCoords(1), &TEXCOORD)?;
        optional(Semantic::Colors(0), &COLOR)?;
        // Skinning influences, as many sets as the file gives (JOINTS_0/WEIGHTS_0, _1...).
        let mut influence_sets = 0;
        if deform.skin.is_some() {
            while primitive.get(&Semantic::Joints(influence_sets)).is_some()
                && primitive.get(&Semantic::Weights(influence_sets)).is_some()
            {
                optional(Semantic::Joints(influence_sets), &JOINTS)?;
                optional(Semantic::Weights(influence_sets), &WEIGHTS)?;
                influence_sets += 1;
            }
        }

        // Each attribute is read straight into the type the soup keeps (the vectors of
        // [f32; N] become Vec3 and Vec2 in place); three-component colours get alpha 1.
        let read =
            |semantic: Semantic, expect: &Expect| -> Result<Option<Vec<Vec4>>, LoadErrorKind> {
                let three = primitive
                    .get(&semantic)
                    .is_some_and(|a| a.dimensions() == Dimensions::Vec3);
                Ok(if three {
                    self.read_attribute::<3>(primitive, at, draco, semantic, expect, count)?
                        .map(|v| {
                            v.into_iter()
                                .map(|[x, y, z]| Vec4::new(x, y, z, 1.0))
                                .collect()
                        })
                } else {
                    self.read_attribute::<4>(primitive, at, draco, semantic, expect, count)?
                        .map(|v| v.into_iter().map(Vec4::from).collect())
                })
            };
        let read3 =
            |semantic: Semantic, expect: &Expect| -> Result<Option<Vec<Vec3>>, LoadErrorKind> {
                Ok(self
                    .read_attribute::<3>(primitive, at, draco, semantic, expect, count)?
                    .map(|v| v.into_iter().map(Vec3::from).collect()))
            };
        let mut positions = read3(Semantic::Positions, &POSITION)?.unwrap_or_default();
        let mut normals = read3(Semantic::Normals, &NORMAL)?;
        let mut tangents = read(Semantic::Tangents, &TANGENT)?;
        self.morph(
            primitive,
            at,
            deform.weights,
            &mut positions,
            normals.as_deref_mut(),
            tangents.as_deref_mut(),
        )?;
        let mut warnings = Vec::new();
        let mut influences = Vec::with_capacity(influence_sets as usize);
        for set in 0..influence_sets {
            let joints = read(Semantic::Joints(set), &JOINTS)?.unwrap_or_default();
            let weights = read(Semantic::Weights(set), &WEIGHTS)?.unwrap_or_default();
            influences.push((joints, weights));
        }
        let skinned = match deform.skin {
            Some((skin, skinning)) if !influences.is_empty() => {
                let unweighted = skin_vertices(
                    skinning,
                    &influences,
                    world,
                    &mut positions,
                    normals.as_deref_mut(),
                    tangents.as_deref_mut(),
                )
                .map_err(|problem| LoadErrorKind::Skin {
                    skin,
                    problem: format!("{at}: {problem}"),
                })?;
                if unweighted > 0 {
                    warnings.push(format!(
                        "{at}: {unweighted} skinned vertices have no joint weight; they are placed by their node's transform"
                    ));
                }
                true
            }
            Some((skin, _)) => {
                warnings.push(format!(
                    "{at}: the node's skin {skin} has no JOINTS_0/WEIGHTS_0 to apply; drawn by the node's transform"
                ));
                false
            }
            None => false,
        };
        if !skinned {
            let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
            let linear = Mat3::from_mat4(world);
            let mirror = if world.determinant() < 0.0 { -1.0 } else { 1.0 };
            for p in &mut positions {
                *p = world.transform_point3(*p);
            }
            for n in normals.iter_mut().flatten() {
                *n = normal_matrix * *n;
            }
            for t in tangents.iter_mut().flatten() {
                let xyz = (linear * t.truncate()).normalize_or_zero();
                *t = xyz.extend(t.w * mirror);
            }
        }
        let uv = |set: u32| -> Result<Option<Vec<Vec2>>, LoadErrorKind> {
            Ok(self
                .read_attribute::<2>(
                    primitive,
                    at,
                    draco,
                    Semantic::TexCoords(set),
                    &TEXCOORD,
                    count,
                )?
                .map(|v| v.into_iter().map(Vec2::from).collect()))
        };
        let uv0 = uv(0)?;
        let uv1 = uv(1)?;
        let colors = read(Semantic::Colors(0), &COLOR)?;
        Ok(WorldVertices {
            positions,
            normals,
            tangents,
            uv0,
            uv1,
            colors,
            skinned,
            warnings,
        })
    }

    /// Adds each morph target's deltas, times its weight, to the primitive's positions,
    /// normals and tangents in place (§3.7.2.2); targets of weight 0 are not read.
    /// Attribute `semantic` of `primitive` as `count` elements of `N` components (its
    /// accessor already checked against `expect`), from the Draco stream where the extension
    /// maps it; `None` when the primitive does not have it.
    fn read_attribute<const N: usize>(
        &self,
        primitive: &gltf::Primitive,
        at: PrimitiveAt,
        draco: Option<&draco::Decoded>,
        semantic: gltf::Semantic,
        expect: &Expect,
        count: usize,
    ) -> Result<Option<Vec<[f32; N]>>, LoadErrorKind> {
        let Some(accessor) = primitive.get(&semantic) else {
            return Ok(None);
        };
        let normalized = expect.reads_normalized(accessor.normalized(), self.quantization);
        let fail = accessor_error(at, &accessor, expect);
        let name = semantic.to_string();
        let values = match draco.filter(|d| d.has(&name)) {
            Some(d) => d.read::<N>(&name, normalized),
            None => attributes::read::<N>(&accessor, self.buffers, normalized),
        }
        .map_err(&fail)?;
        if values.len() != count {
            return Err(fail(format!("read {} of {count} elements", values.len())));
        }
        Ok(Some(values))
    }

    fn morph(
        &self,
        primitive: &gltf::Primitive,
        at: PrimitiveAt,
        weights: &[f32],
        positions: &mut [Vec3],
        mut normals: Option<&mut [Vec3]>,
        mut tangents: Option<&mut [Vec4]>,
    ) -> Result<(), LoadErrorKind> {
        let count = positions.len();
        for (i, target) in primitive.morph_targets().enumerate() {
            let weight = weights.get(i).copied().unwrap_or(0.0);
            if weight == 0.0 || !weight.is_finite() {
                continue;
            }
            let read = |accessor: Option<gltf::Accessor>,
                        expect: &Expect|
             -> Result<Option<Vec<Vec3>>, LoadErrorKind> {
                let Some(accessor) = accessor else {
                    return Ok(None);
                };
                let fail = |problem: String| LoadErrorKind::Accessor {
                    at,
                    accessor: accessor.index(),
                    semantic: format!("targets[{i}].{}", expect.semantic),
                    problem,
                };
                check_accessor(&accessor, at, expect, self.quantization).map_err(|e| match e {
                    LoadErrorKind::Accessor { problem, .. } => fail(problem),
                    other => other,
                })?;
                if accessor.count() != count {
                    return Err(fail(format!(
                        "count {} differs from POSITION's {count}",
                        accessor.count()
                    )));
                }
                let values = attributes::read::<3>(&accessor, self.buffers, accessor.normalized())
                    .map_err(fail)?;
                Ok(Some(values.into_iter().map(Vec3::from).collect()))
            };
            if let Some(delta) = read(target.positions(), &MORPH_POSITION)? {
                pose::morph(positions, &delta, weight);
            }
            if let (Some(delta), Some(normals)) = (
                read(target.normals(), &MORPH_NORMAL)?,
                normals.as_deref_mut(),
            ) {
                pose::morph(normals, &delta, weight);
            }
            if let (Some(delta), Some(tangents)) = (
                read(target.tangents(), &MORPH_TANGENT)?,
                tangents.as_deref_mut(),
            ) {
                pose::morph_tangents(tangents, &delta, weight);
            }
        }
        Ok(())
    }

    fn materials(&self) -> Vec<Material> {
        let mut out: Vec<Material> = self.document.materials().map(|m| material(&m)).collect();
        if self.uses_default_material {
            out.push(Material::default());
        }
        out
    }
}

fn place_camera(camera: &gltf::Camera, world: Mat4, node_name: Option<String>) -> Option<Camera> {
    let (position, forward, up) = frame(world)?;
    let projection = match camera.projection() {
        gltf::camera::Projection::Perspective(p) => Projection::Perspective {
            yfov: p.yfov(),
            aspect_ratio: p.aspect_ratio(),
            znear: p.znear(),
            zfar: p.zfar(),
        },
        gltf::camera::Projection::Orthographic(o) => Projection::Orthographic {
            xmag: o.xmag(),
            ymag: o.ymag(),
            znear: o.znear(),
            zfar: o.zfar(),
        },
    };
    Some(Camera {
        name: camera.name().map(str::to_string).or(node_name),
        position,
        forward,
        up,
        projection,
    })
}

/// Position, forward (local -Z) and up (local +Y) of a node, with scale removed and up made
/// orthogonal to forward. `None` when the transform is degenerate.
fn frame(world: Mat4) -> Option<(Vec3, Vec3, Vec3)> {
    let position = world.transform_point3(Vec3::ZERO);
    let forward = world.transform_vector3(Vec3::NEG_Z).try_normalize()?;
    let up_raw = world.transform_vector3(Vec3::Y);
    let up = (up_raw - forward * up_raw.dot(forward)).try_normalize()?;
    position.is_finite().then_some((position, forward, up))
}

fn place_light(light: &gltf::khr_lights_punctual::Light, world: Mat4) -> Option<Light> {
    use gltf::khr_lights_punctual::Kind;
    let position = world.transform_point3(Vec3::ZERO);
    let direction = world.transform_vector3(Vec3::NEG_Z).try_normalize()?;
    let intensity = light.intensity();
    if !position.is_finite() || !intensity.is_finite() || intensity < 0.0 {
        return None;
    }
    let kind = match light.kind() {
        Kind::Directional => LightKind::Directional,
        Kind::Point => LightKind::Point,
        Kind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        } => LightKind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        },
    };
    Some(Light {
        name: light.name().map(str::to_string),
        kind,
        color: Vec3::from(light.color()),
        intensity,
        range: light.range().filter(|r| *r > 0.0 && r.is_finite()),
        position,
        direction,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_frame_removes_scale_and_keeps_minus_z() {
        let world = Mat4::from_scale_rotation_translation(
            Vec3::splat(3.0),
            glam::Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
            Vec3::new(1.0, 2.0, 3.0),
        );
        let (p, f, u) = frame(world).unwrap();
        assert!((p - Vec3::new(1.0, 2.0, 3.0)).length() < 1e-6);
        // Rotating -Z by +90° about Y gives -X.
        assert!((f - Vec3::NEG_X).length() < 1e-6);
        assert!((u - Vec3::Y).length() < 1e-6);
        assert!(frame(Mat4::ZERO).is_none());
    }
}
