//! The node walk: the default scene's node tree from its roots, each node's world transform
//! (parent · child, §3.5.3), and what its nodes place in the world: cameras (§3.10), lights
//! (`KHR_lights_punctual`) and mesh instances, whose triangles go into the soup.

use super::attributes;
use super::buffer::Buffer;
use super::draco;
use super::instancing;
use super::material::{material, out_of_range};
use super::pose::{self, Pose, Skinning};
use super::validate::{check_accessor, check_accessor_type, INDICES};
use super::vertices::{Deform, VertexReader};
use crate::scene::builder::{SoupBuilder, VerticesIn};
use crate::scene::error::{LoadErrorKind, PrimitiveAt};
use crate::scene::material::Material;
use crate::scene::options::LoadLimits;
use crate::scene::punctual::{Light, LightKind};
use crate::scene::soup::Instance;
use crate::scene::viewpoint::{Camera, Projection};
use glam::{Mat4, Vec3};
use gltf::mesh::Mode;
use std::collections::{HashMap, HashSet};
use std::rc::Rc;

/// The node walk's state.
pub(super) struct Importer<'a> {
    document: &'a gltf::Document,
    buffers: &'a [Buffer<'a>],
    pub(super) builder: SoupBuilder,
    pub(super) warnings: Vec<String>,
    pub(super) instances: Vec<Instance>,
    pub(super) cameras: Vec<Camera>,
    pub(super) lights: Vec<Light>,
    default_material: u32,
    uses_default_material: bool,
    pub(super) primitive_count: usize,
    pub(super) skipped_non_triangle: usize,
    pub(super) singular_instances: usize,
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
    limits: LoadLimits,
    /// Draco primitives decoded so far, by (mesh, primitive): instanced meshes decode once.
    draco: HashMap<(usize, usize), Rc<draco::Decoded>>,
    /// The (mesh, primitive, material) triples whose texture coordinates were checked.
    tex_coords_checked: HashSet<(usize, usize, usize)>,
}

impl<'a> Importer<'a> {
    /// The walk of `document`'s nodes, nothing placed yet: in `pose`, whose problems start the
    /// `warnings`, with the `variant` chosen, within `limits`.
    pub(super) fn new(
        document: &'a gltf::Document,
        buffers: &'a [Buffer<'a>],
        limits: LoadLimits,
        pose: Pose,
        warnings: Vec<String>,
        variant: Option<(u32, String)>,
    ) -> Self {
        Importer {
            document,
            buffers,
            builder: SoupBuilder::new(limits.max_triangles),
            warnings,
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
            limits,
            draco: HashMap::new(),
            tex_coords_checked: HashSet::new(),
        }
    }

    /// Walks the default scene (or scene 0) from its roots, visiting each node once. glTF 2.0
    /// §3.5.2 gives a node at most one parent and makes a scene's nodes roots; a node reached a
    /// second time (a second parent, a root that is also a child, a child listed twice) is
    /// drawn only where it was first reached, with a warning. A file with no scene, or a scene
    /// with no nodes, leaves nothing to draw: `NothingToDraw`'s reason is returned.
    pub(super) fn walk_default_scene(&mut self) -> Result<Option<String>, LoadErrorKind> {
        // glTF 2.0 §3.5.1: `scene` names the default; without it, scene 0 is a reasonable choice.
        let Some(scene) = self
            .document
            .default_scene()
            .or_else(|| self.document.scenes().next())
        else {
            return Ok(Some("the file defines no scene".to_string()));
        };
        if scene.nodes().len() == 0 {
            return Ok(Some(format!("scene {} has no nodes", scene.index())));
        }
        let nodes: Vec<gltf::Node> = self.document.nodes().collect();
        let mut on_path = vec![false; nodes.len()];
        // Where each node was first reached: `Some(None)` as a root, `Some(Some(p))` under p.
        let mut reached: Vec<Option<Option<usize>>> = vec![None; nodes.len()];
        // An explicit stack: a hostile hierarchy a million levels deep must not overflow ours.
        // Enter: the node, its parent, the parent's world transform, whether the parent is
        // visible (KHR_node_visibility).
        enum Step {
            Enter(usize, Option<usize>, Mat4, bool),
            Leave(usize),
        }
        let mut stack: Vec<Step> = scene
            .nodes()
            .map(|n| Step::Enter(n.index(), None, Mat4::IDENTITY, true))
            .collect();
        stack.reverse();
        while let Some(step) = stack.pop() {
            let (index, parent, parent_world, parent_visible) = match step {
                Step::Leave(index) => {
                    on_path[index] = false;
                    continue;
                }
                Step::Enter(index, parent, world, visible) => (index, parent, world, visible),
            };
            let Some(node) = nodes.get(index) else {
                continue;
            };
            if on_path[index] {
                return Err(LoadErrorKind::NodeCycle { node: index });
            }
            if let Some(first) = reached[index] {
                let place = |p: Option<usize>| match p {
                    None => format!("a root of scene {}", scene.index()),
                    Some(p) => format!("a child of node {p}"),
                };
                self.warnings.push(match (first, parent) {
                    (Some(a), Some(b)) if a == b => format!(
                        "node {index}: is listed twice among the children of node {a}; drawn once"
                    ),
                    (None, None) => format!(
                        "node {index}: is listed twice among the roots of scene {}; drawn once",
                        scene.index()
                    ),
                    _ => format!(
                        "node {index}: is {} and also {} (glTF allows one parent); drawn once, as {}",
                        place(first),
                        place(parent),
                        place(first)
                    ),
                });
                continue;
            }
            reached[index] = Some(parent);
            let local = self
                .pose
                .local
                .get(index)
                .copied()
                .unwrap_or(Mat4::IDENTITY);
            let world = parent_world * local;
            let visible = parent_visible && visible_by_itself(node);
            self.visit(node, world, visible)?;
            on_path[index] = true;
            stack.push(Step::Leave(index));
            let children: Vec<usize> = node.children().map(|c| c.index()).collect();
            for child in children.into_iter().rev() {
                stack.push(Step::Enter(child, Some(index), world, visible));
            }
        }
        Ok(None)
    }

    /// Places `node`'s camera, light and mesh at `world`; a node that is not `visible`
    /// (`KHR_node_visibility`) keeps its camera only: "visibility affects neither cameras".
    fn visit(
        &mut self,
        node: &gltf::Node,
        world: Mat4,
        visible: bool,
    ) -> Result<(), LoadErrorKind> {
        let name = node.name().map(str::to_string);
        if let Some(camera) = node.camera() {
            match place_camera(&camera, world, name.clone()) {
                Ok(c) => self.cameras.push(c),
                Err(why) => self
                    .warnings
                    .push(format!("camera on node {} skipped: {why}", node.index())),
            }
        }
        if !visible {
            return Ok(());
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
            let deform = Deform {
                weights: &weights,
                skin: node.skin().map(|s| s.index()).zip(skinning.as_deref()),
            };
            let name = name.or_else(|| mesh.name().map(str::to_string));
            // EXT_mesh_gpu_instancing: the mesh once per instance, at world · its T·R·S.
            let instanced =
                instancing::transforms(node, self.document, self.buffers, self.quantization)?;
            let worlds = match instanced {
                Some(_) if skinning.is_some() => {
                    self.warnings.push(format!(
                        "node {}: a skinned mesh with {}: drawn once, where its joints place it",
                        node.index(),
                        instancing::EXTENSION
                    ));
                    vec![world]
                }
                Some(locals) => locals.into_iter().map(|local| world * local).collect(),
                None => vec![world],
            };
            for world in worlds {
                self.place_mesh(node, &mesh, world, name.clone(), &deform)?;
            }
        }
        Ok(())
    }

    /// One instance of `node`'s `mesh` at `world`, deformed by `deform`: its triangles go
    /// into the soup as instance `name`.
    fn place_mesh(
        &mut self,
        node: &gltf::Node,
        mesh: &gltf::Mesh,
        world: Mat4,
        name: Option<String>,
        deform: &Deform,
    ) -> Result<(), LoadErrorKind> {
        let instance = self.instances.len() as u32;
        self.instances.push(Instance {
            node: Some(node.index()),
            mesh: mesh.index(),
            name,
        });
        let det = world.determinant();
        // §3.7.3: a skinned mesh is placed by its joints alone, whatever its node's transform.
        if deform.skin.is_none() && (!world.is_finite() || det == 0.0 || !det.is_finite()) {
            self.singular_instances += 1;
            return Ok(());
        }
        for primitive in mesh.primitives() {
            let at = PrimitiveAt {
                mesh: mesh.index(),
                primitive: primitive.index(),
            };
            self.add_primitive(&primitive, at, world, instance, deform)?;
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
        if primitive.get(&gltf::Semantic::Positions).is_none() {
            self.warnings.push(format!(
                "{at}: has no POSITION attribute; the primitive is skipped"
            ));
            return Ok(());
        }
        self.primitive_count += 1;
        let draco = self.decode_draco(primitive, at)?;
        let reader = VertexReader {
            buffers: self.buffers,
            quantization: self.quantization,
        };
        let mut vertices = reader.read_vertices(primitive, at, world, draco.as_deref(), deform)?;
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
        if let Some(m) = chosen.index() {
            self.check_tex_coords(primitive, at, &chosen, m);
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

    /// Warns, once per primitive and material, when the material samples a `TEXCOORD_n` the
    /// primitive does not have (glTF 2.0 §3.9.2 requires it): such a texture cannot be placed
    /// as the file means.
    fn check_tex_coords(
        &mut self,
        primitive: &gltf::Primitive,
        at: PrimitiveAt,
        chosen: &gltf::Material,
        index: usize,
    ) {
        if !self
            .tex_coords_checked
            .insert((at.mesh, at.primitive, index))
        {
            return;
        }
        let mut sets: Vec<u32> = material(chosen)
            .texture_refs()
            .map(|r| r.tex_coord)
            .filter(|&set| primitive.get(&gltf::Semantic::TexCoords(set)).is_none())
            .collect();
        sets.sort_unstable();
        sets.dedup();
        for set in sets {
            self.warnings.push(format!(
                "{at}: material {index}{} samples TEXCOORD_{set}, which the primitive does not have",
                chosen
                    .name()
                    .map_or(String::new(), |n| format!(" ('{n}')"))
            ));
        }
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

    /// The file's materials (and the default material, if a primitive has none), with a
    /// warning for each value corrected ([`out_of_range`]); the lights' corrections are
    /// reported here too ([`light_out_of_range`]), once for each light however many nodes
    /// place it.
    pub(super) fn materials(&mut self) -> Vec<Material> {
        for m in self.document.materials() {
            self.warnings.extend(out_of_range(&m));
        }
        for light in self.document.lights().into_iter().flatten() {
            self.warnings.extend(light_out_of_range(&light));
        }
        let mut out: Vec<Material> = self.document.materials().map(|m| material(&m)).collect();
        if self.uses_default_material {
            out.push(Material::default());
        }
        out
    }
}

/// `KHR_node_visibility`: a node whose `visible` is false is hidden with everything below it
/// (its meshes and lights, not its camera); absent, or anything but `false`, is visible.
fn visible_by_itself(node: &gltf::Node) -> bool {
    node.extension_value("KHR_node_visibility")
        .and_then(|e| e.get("visible"))
        .and_then(serde_json::Value::as_bool)
        != Some(false)
}

/// The camera of a node at `world`, or why it cannot be used: a transform that is not finite
/// or is singular, or a projection outside glTF 2.0 §5.12-5.14's ranges (`yfov` in (0, π)
/// radians, `xmag` not zero, `ymag` above 0, `znear` above 0 for a perspective camera and not
/// below 0 for an orthographic one, `zfar` beyond `znear`), which would render an empty or
/// mirrored image and write a view file that `--view` refuses.
fn place_camera(
    camera: &gltf::Camera,
    world: Mat4,
    node_name: Option<String>,
) -> Result<Camera, String> {
    let problem = projection_problem(camera);
    if let Some(problem) = problem {
        return Err(problem);
    }
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
    Camera::from_pose(
        world,
        projection,
        camera.name().map(str::to_string).or(node_name),
    )
    .ok_or_else(|| "its transform is not finite or is singular".to_string())
}

/// What in `camera`'s projection is outside the specification's ranges (see
/// [`place_camera`]), in words; `None` when nothing is.
fn projection_problem(camera: &gltf::Camera) -> Option<String> {
    let positive = |x: f32| x > 0.0 && x.is_finite();
    let (znear, zfar, near_ok) = match camera.projection() {
        gltf::camera::Projection::Perspective(p) => {
            let yfov = p.yfov();
            if !(positive(yfov) && yfov < std::f32::consts::PI) {
                return Some(format!("yfov {yfov} is not in (0, π) radians"));
            }
            if let Some(aspect) = p.aspect_ratio().filter(|a| !positive(*a)) {
                return Some(format!("aspectRatio {aspect} is not above 0"));
            }
            (p.znear(), p.zfar(), positive(p.znear()))
        }
        gltf::camera::Projection::Orthographic(o) => {
            // A negative `xmag` only mirrors the image (the specification advises against
            // it); the height `ymag` must be above 0, as a view file's.
            if o.xmag() == 0.0 || !o.xmag().is_finite() {
                return Some(format!("xmag {} is zero or not finite", o.xmag()));
            }
            if !positive(o.ymag()) {
                return Some(format!("ymag {} is not above 0", o.ymag()));
            }
            (
                o.znear(),
                Some(o.zfar()),
                o.znear() >= 0.0 && o.znear().is_finite(),
            )
        }
    };
    if !near_ok {
        return Some(format!("znear {znear} is out of range"));
    }
    match zfar {
        Some(far) if far.is_nan() || far <= znear => {
            Some(format!("zfar {far} is not beyond znear {znear}"))
        }
        _ => None,
    }
}

/// KHR_lights_punctual's ranges: `color` in [0, 1] per channel (a negative one would take light
/// away), `outerConeAngle` in (0, π/2], `innerConeAngle` in [0, outerConeAngle).
const OUTER_CONE_MAX: f32 = std::f32::consts::FRAC_PI_2;

/// A spot light's cones brought into the extension's ranges: the outer one into (0, π/2],
/// the inner one into [0, outer), so that the cone's falloff has a width.
fn spot_cones(inner: f32, outer: f32) -> (f32, f32) {
    let outer = outer.clamp(1e-4, OUTER_CONE_MAX);
    if (0.0..outer).contains(&inner) {
        return (inner, outer);
    }
    (inner.clamp(0.0, outer * (1.0 - 1e-3)), outer)
}

/// What [`place_light`] corrects in a light whose values are outside the ranges
/// KHR_lights_punctual defines (an invalid file), one warning each, naming the light.
pub(super) fn light_out_of_range(light: &gltf::khr_lights_punctual::Light) -> Vec<String> {
    let mut problems = Vec::new();
    let color = light.color();
    if !color.iter().all(|c| (0.0..=1.0).contains(c)) {
        problems.push(format!("color {color:?} is outside [0, 1]; clamped"));
    }
    if let gltf::khr_lights_punctual::Kind::Spot {
        inner_cone_angle: inner,
        outer_cone_angle: outer,
    } = light.kind()
    {
        if spot_cones(inner, outer) != (inner, outer) {
            problems.push(format!(
                "spot cones {inner}..{outer} rad are not 0 <= inner < outer <= π/2; corrected"
            ));
        }
    }
    let name = light.name().map_or(String::new(), |n| format!(" ('{n}')"));
    problems
        .into_iter()
        .map(|p| format!("KHR_lights_punctual light {}{name}: {p}", light.index()))
        .collect()
}

fn place_light(light: &gltf::khr_lights_punctual::Light, world: Mat4) -> Option<Light> {
    use gltf::khr_lights_punctual::Kind;
    let kind = match light.kind() {
        Kind::Directional => LightKind::Directional,
        Kind::Point => LightKind::Point,
        Kind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        } => {
            let (inner_cone_angle, outer_cone_angle) =
                spot_cones(inner_cone_angle, outer_cone_angle);
            LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            }
        }
    };
    Light::from_pose(
        kind,
        Vec3::from(light.color()).clamp(Vec3::ZERO, Vec3::ONE),
        light.intensity(),
        light.range(),
        world,
        light.name().map(str::to_string),
    )
}
