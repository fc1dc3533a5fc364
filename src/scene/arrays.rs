//! Scenes built in memory from arrays rather than read from a file: the Python package's
//! `Scene.from_arrays` and `add_mesh`, and any library user with vertices in hand.
//!
//! A mesh goes through the [`SoupBuilder`] the importers use, placed by a 4x4 pose as a glTF
//! node places its mesh (§3.7.2.1: normals by the inverse transpose, a mirroring pose flips
//! the winding), so what is rendered is exactly what a glTF file with the same vertices,
//! material and node would give. Unlike an importer, which drops what a file gets wrong with a
//! warning, arrays are refused whole: a caller that computed a NaN wants to hear about it.

use super::builder::{place_vertices, SoupBuilder, VerticesIn};
use super::image_source::ImageSource;
use super::material::{AlphaMode, Material};
use super::model::Scene;
use super::options::Format;
use super::soup::{Bounds, Instance, TriangleSoup};
use super::texture::{Sampler, Texture};
use crate::defaults::MAX_TRIANGLES;
use glam::{Mat4, Vec2, Vec3, Vec4};
use std::path::PathBuf;

/// One mesh as arrays, in its own (local) space: every attribute present has one row per
/// position, triangles index the positions counter-clockwise seen from the front.
#[derive(Clone, Copy, Debug, Default)]
pub struct MeshArrays<'a> {
    /// Vertex positions, metres.
    pub positions: &'a [Vec3],
    /// Triangles: three indices into `positions` each.
    pub indices: &'a [[u32; 3]],
    /// Shading normals (need not be unit length); flat normals without them.
    pub normals: Option<&'a [Vec3]>,
    /// Texture coordinates (set 0), (0, 0) at the image's top-left as in glTF.
    pub uv0: Option<&'a [Vec2]>,
    /// A second set of texture coordinates (glTF `TEXCOORD_1`: an occlusion or light map's
    /// own unwrap), for the textures whose [`crate::scene::TextureRef::tex_coord`] is 1.
    pub uv1: Option<&'a [Vec2]>,
    /// Linear RGBA vertex colours, multiplying the base colour (glTF `COLOR_0`).
    pub colors: Option<&'a [Vec4]>,
}

/// Arrays, a pose or a material that cannot make a mesh: which mesh and part, and what is wrong.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{what}: {problem}")]
pub struct ArraysError {
    /// The mesh and the array, pose or material at fault ("mesh 2 'floor': indices").
    pub what: String,
    /// What is wrong, with the numbers.
    pub problem: String,
}

impl Scene {
    /// A scene with nothing in it yet, named `name` (what [`Scene::source`] and error messages
    /// show; no file is read). Add meshes with [`Scene::add_mesh`], and cameras and lights to
    /// [`Scene::cameras`] and [`Scene::lights`].
    pub fn empty(name: impl Into<PathBuf>) -> Scene {
        Scene {
            source: name.into(),
            format: Format::Memory,
            soup: TriangleSoup::default(),
            materials: Vec::new(),
            textures: Vec::new(),
            images: Vec::new(),
            cameras: Vec::new(),
            lights: Vec::new(),
            instances: Vec::new(),
            mesh_count: 0,
            file_triangles: 0,
            primitive_count: 0,
            bounds: Bounds::EMPTY,
            warnings: Vec::new(),
            variants: Vec::new(),
            variant: None,
            extensions: Vec::new(),
            animations: Vec::new(),
            pose: None,
            load_steps: Vec::new(),
            archive: None,
            inputs: Vec::new(),
        }
    }

    /// Adds `mesh` with its own `material`, placed in the world by `pose` (world from local,
    /// column-major as glam and glTF store it), as instance `name`. Returns the new instance's
    /// index (segmentation ids are this + 1).
    ///
    /// Refuses, naming the mesh and the array: no positions or no triangles, an attribute whose
    /// length differs from the positions', a NaN or infinite value, a colour outside [0, 1],
    /// an index past the last vertex, a pose that is not finite or is singular, a material
    /// factor out of its glTF range, or more triangles than [`MAX_TRIANGLES`] in the scene.
    /// Triangles of zero area are dropped with a warning in [`Scene::warnings`], as the
    /// importers drop them.
    pub fn add_mesh(
        &mut self,
        mesh: &MeshArrays,
        material: Material,
        pose: Mat4,
        name: Option<String>,
    ) -> Result<usize, ArraysError> {
        let instance = self.instances.len();
        let label = match &name {
            Some(n) => format!("mesh {instance} '{n}'"),
            None => format!("mesh {instance}"),
        };
        let fail = |part: &str, problem: String| ArraysError {
            what: format!("{label}: {part}"),
            problem,
        };
        check_arrays(mesh).map_err(|(part, problem)| fail(part, problem))?;
        check_material(&material).map_err(|problem| fail("material", problem))?;
        if let Some(r) = material
            .texture_refs()
            .find(|r| r.texture >= self.textures.len())
        {
            return Err(fail(
                "material",
                format!(
                    "texture {} does not exist (the scene has {}: add_texture returns their indices)",
                    r.texture,
                    self.textures.len()
                ),
            ));
        }
        if let Some(r) = material.texture_refs().find(|r| r.tex_coord > 1) {
            return Err(fail(
                "material",
                format!(
                    "texture {} reads texture coordinate set {}: a mesh from arrays has sets 0 and 1",
                    r.texture, r.tex_coord
                ),
            ));
        }
        let reads = |set: u32| material.texture_refs().any(|r| r.tex_coord == set);
        if mesh.uv0.is_none() && reads(0) {
            return Err(fail(
                "uvs",
                "missing: the material has textures, which are placed by the uvs".into(),
            ));
        }
        if mesh.uv1.is_none() && reads(1) {
            return Err(fail(
                "uvs1",
                "missing: the material has a texture that reads coordinate set 1".into(),
            ));
        }
        if !pose.is_finite() {
            return Err(fail("pose", "not finite (NaN or infinite)".into()));
        }
        let det = pose.determinant();
        if det == 0.0 || !det.is_finite() {
            return Err(fail(
                "pose",
                format!("singular (determinant {det}): it flattens the mesh"),
            ));
        }
        let count = (self.soup.len() + mesh.indices.len()) as u64;
        if count > MAX_TRIANGLES {
            return Err(fail(
                "indices",
                format!("{count} triangles in the scene: at most {MAX_TRIANGLES}"),
            ));
        }

        let mut positions = mesh.positions.to_vec();
        let mut normals = mesh.normals.map(<[Vec3]>::to_vec);
        place_vertices(pose, &mut positions, normals.as_deref_mut(), None);
        // glTF 2.0 §3.7.2.1: a mirroring transform turns counter-clockwise into clockwise.
        let mirrored = det < 0.0;
        let vertices = VerticesIn {
            positions: &positions,
            normals: normals.as_deref(),
            uv0: mesh.uv0,
            uv1: mesh.uv1,
            colors: mesh.colors,
            ..Default::default()
        };
        let mut builder = SoupBuilder::new(MAX_TRIANGLES);
        builder
            .reserve(mesh.indices.len())
            .map_err(|e| fail("indices", e.to_string()))?;
        let material_index = self.materials.len() as u32;
        builder.push_primitive(
            &vertices,
            mesh.indices.len(),
            |t| {
                let [a, b, c] = mesh.indices[t].map(|i| i as usize);
                if mirrored {
                    [a, c, b]
                } else {
                    [a, b, c]
                }
            },
            material_index,
            instance as u32,
        );
        if builder.is_empty() {
            return Err(fail(
                "indices",
                format!(
                    "all {} triangles have zero area or repeat a vertex: nothing to draw",
                    mesh.indices.len()
                ),
            ));
        }
        if let Some(dropped) = builder.dropped_warning() {
            self.warnings.push(format!("{label}: {dropped}"));
        }
        let (soup, bounds) = builder.finish();
        if !bounds.is_empty() {
            self.bounds.grow(bounds.min);
            self.bounds.grow(bounds.max);
        }
        self.soup.append(soup);
        self.materials.push(material);
        self.instances.push(Instance {
            node: None,
            mesh: self.mesh_count,
            name,
        });
        self.mesh_count += 1;
        self.primitive_count += 1;
        self.file_triangles += mesh.indices.len();
        Ok(instance)
    }

    /// Adds a texture of `width` x `height` pixels given as `rgba` (four bytes a pixel, rows
    /// from the top: texture coordinate (0, 0) is the first row's first pixel, as in glTF),
    /// sampled as `sampler` says. Returns its index, which a material's texture slots take
    /// ([`crate::scene::TextureRef::texture`]); several materials may share it. Colour slots
    /// (base colour, emissive) read its values as sRGB, the others as linear data, as glTF's
    /// do. Refuses an image without pixels, or bytes that are not four a pixel.
    pub fn add_texture(
        &mut self,
        width: u32,
        height: u32,
        rgba: Vec<u8>,
        sampler: Sampler,
        name: Option<String>,
    ) -> Result<usize, ArraysError> {
        let index = self.textures.len();
        let fail = |problem: String| ArraysError {
            what: match &name {
                Some(n) => format!("texture {index} '{n}'"),
                None => format!("texture {index}"),
            },
            problem,
        };
        if width == 0 || height == 0 {
            return Err(fail(format!(
                "{width}x{height} pixels: an image needs at least one"
            )));
        }
        let len = rgba.len();
        let Some(pixels) = image::RgbaImage::from_raw(width, height, rgba)
            .filter(|_| len as u64 == 4 * u64::from(width) * u64::from(height))
        else {
            return Err(fail(format!(
                "{len} bytes for {width}x{height} pixels: need 4 a pixel (RGBA)"
            )));
        };
        self.images.push(ImageSource {
            origin: format!("pixels ({width}x{height})"),
            mime_type: None,
            path: None,
            bytes: None,
            in_file: None,
            pixels: Some(std::sync::Arc::new(pixels)),
        });
        self.textures.push(Texture {
            name,
            image: self.images.len() - 1,
            fallback_image: None,
            sampler,
        });
        Ok(index)
    }
}

/// The part of `mesh` at fault and what is wrong with it, if anything.
fn check_arrays(mesh: &MeshArrays) -> Result<(), (&'static str, String)> {
    let vertices = mesh.positions.len();
    if vertices == 0 {
        return Err((
            "positions",
            "empty: a mesh needs at least 3 vertices".into(),
        ));
    }
    if mesh.indices.is_empty() {
        return Err(("indices", "empty: a mesh needs at least 1 triangle".into()));
    }
    let lengths = [
        ("normals", mesh.normals.map(<[Vec3]>::len)),
        ("uvs", mesh.uv0.map(<[Vec2]>::len)),
        ("uvs1", mesh.uv1.map(<[Vec2]>::len)),
        ("colors", mesh.colors.map(<[Vec4]>::len)),
    ];
    for (part, len) in lengths {
        if let Some(len) = len.filter(|&len| len != vertices) {
            return Err((
                part,
                format!("{len} rows, but there are {vertices} positions (one row a vertex)"),
            ));
        }
    }
    fn first_not_finite(values: &[f32], width: usize) -> Option<usize> {
        values
            .iter()
            .position(|v| !v.is_finite())
            .map(|i| i / width)
    }
    let rows: [(&str, Option<&[f32]>, usize); 5] = [
        ("positions", Some(bytemuck::cast_slice(mesh.positions)), 3),
        (
            "normals",
            mesh.normals.map(bytemuck::cast_slice::<Vec3, f32>),
            3,
        ),
        ("uvs", mesh.uv0.map(bytemuck::cast_slice::<Vec2, f32>), 2),
        ("uvs1", mesh.uv1.map(bytemuck::cast_slice::<Vec2, f32>), 2),
        (
            "colors",
            mesh.colors.map(bytemuck::cast_slice::<Vec4, f32>),
            4,
        ),
    ];
    for (part, values, width) in rows {
        if let Some(row) = values.and_then(|v| first_not_finite(v, width)) {
            return Err((part, format!("row {row} is not finite (NaN or infinite)")));
        }
    }
    // Colours multiply the base colour, which is refused outside [0, 1] too (§5.22).
    let colors = mesh
        .colors
        .map_or(&[][..], bytemuck::cast_slice::<Vec4, f32>);
    if let Some((i, v)) = colors
        .iter()
        .enumerate()
        .find(|(_, v)| !(0.0..=1.0).contains(*v))
    {
        return Err(("colors", format!("row {}: {v} must be from 0 to 1", i / 4)));
    }
    if let Some((t, &v)) = mesh.indices.iter().enumerate().find_map(|(t, tri)| {
        tri.iter()
            .find(|&&v| v as usize >= vertices)
            .map(|v| (t, v))
    }) {
        return Err((
            "indices",
            format!(
                "triangle {t} uses vertex {v}, but there are {vertices} vertices (0 to {})",
                vertices - 1
            ),
        ));
    }
    Ok(())
}

/// What is wrong with a material given as factors, if anything: the glTF ranges
/// (§5.19, §5.22: colour, metallic, roughness and alpha cutoff in [0, 1], emissive at least 0;
/// the occlusion texture's strength in [0, 1]; a finite normal scale; finite texture
/// transforms), and those of the material extensions (`check_extensions`: transmission, ior,
/// volume, specular, sheen, clearcoat, iridescence).
pub fn check_material(material: &Material) -> Result<(), String> {
    let unit = |name: &str, v: f32| {
        if (0.0..=1.0).contains(&v) {
            Ok(())
        } else {
            Err(format!("{name} {v}: must be from 0 to 1"))
        }
    };
    for (i, c) in material.base_color.to_array().into_iter().enumerate() {
        unit(&format!("base_color[{i}]"), c)?;
    }
    unit("metallic", material.metallic)?;
    unit("roughness", material.roughness)?;
    if material.alpha_mode == AlphaMode::Mask {
        unit("alpha_cutoff", material.alpha_cutoff)?;
    }
    for (i, e) in material.emissive.to_array().into_iter().enumerate() {
        if !(e.is_finite() && e >= 0.0) {
            return Err(format!(
                "emissive[{i}] {e}: must be a finite number of at least 0"
            ));
        }
    }
    if !material.normal_scale.is_finite() {
        return Err(format!(
            "normal_scale {}: must be a finite number",
            material.normal_scale
        ));
    }
    unit("occlusion_strength", material.occlusion_strength)?;
    if !(material.emissive_strength.is_finite() && material.emissive_strength >= 0.0) {
        return Err(format!(
            "emissive_strength {}: must be a finite number of at least 0",
            material.emissive_strength
        ));
    }
    for r in material.texture_refs() {
        if let Some(t) = r.transform {
            let numbers = [t.offset[0], t.offset[1], t.rotation, t.scale[0], t.scale[1]];
            if !numbers.iter().all(|v| v.is_finite()) {
                return Err(format!(
                    "texture {}: transform offset {:?}, rotation {}, scale {:?}: must be finite numbers",
                    r.texture, t.offset, t.rotation, t.scale
                ));
            }
        }
    }
    check_extensions(material)
}

/// The ranges of the material extensions' factors, as their specifications define them:
/// `KHR_materials_transmission`, `_specular`, `_sheen`, `_clearcoat`, `_iridescence`,
/// `_anisotropy` and `_diffuse_transmission` factors and `_volume`'s attenuation and
/// `_diffuse_transmission`'s colours in [0, 1] (the anisotropy's rotation
/// finite); `_ior` (and the film's) at least 1; an
/// attenuation distance above 0 (infinite: none); a specular colour and film thicknesses (nm)
/// finite and at least 0. Names are the Python package's keys.
fn check_extensions(material: &Material) -> Result<(), String> {
    let unit = |name: &str, v: f32| {
        if (0.0..=1.0).contains(&v) {
            Ok(())
        } else {
            Err(format!("{name} {v}: must be from 0 to 1"))
        }
    };
    let at_least = |name: &str, v: f32, low: f32| {
        if v.is_finite() && v >= low {
            Ok(())
        } else {
            Err(format!(
                "{name} {v}: must be a finite number of at least {low}"
            ))
        }
    };
    let each = |name: &str, c: Vec3, check: &dyn Fn(&str, f32) -> Result<(), String>| {
        (0..3).try_for_each(|i| check(&format!("{name}[{i}]"), c[i]))
    };
    unit("transmission", material.transmission)?;
    at_least("ior", material.ior, 1.0)?;
    at_least("dispersion", material.dispersion, 0.0)?;
    each("attenuation_color", material.attenuation_color, &unit)?;
    let distance = material.attenuation_distance;
    if distance.is_nan() || distance <= 0.0 {
        return Err(format!(
            "attenuation_distance {distance}: must be above 0 (infinite for no attenuation)"
        ));
    }
    if let Some(layer) = &material.specular_layer {
        unit("specular", layer.factor)?;
        each("specular_color", layer.color, &|n, v| at_least(n, v, 0.0))?;
    }
    if let Some(layer) = &material.sheen {
        each("sheen_color", layer.color, &unit)?;
        unit("sheen_roughness", layer.roughness)?;
    }
    if let Some(layer) = &material.clearcoat {
        unit("clearcoat", layer.factor)?;
        unit("clearcoat_roughness", layer.roughness)?;
    }
    if let Some(film) = &material.iridescence {
        unit("iridescence", film.factor)?;
        at_least("iridescence_ior", film.ior, 1.0)?;
        at_least("iridescence_thickness[0]", film.thickness_min, 0.0)?;
        at_least("iridescence_thickness[1]", film.thickness_max, 0.0)?;
    }
    if let Some(layer) = &material.diffuse_transmission {
        unit("diffuse_transmission", layer.factor)?;
        each("diffuse_transmission_color", layer.color, &unit)?;
    }
    if let Some(layer) = &material.anisotropy {
        unit("anisotropy", layer.strength)?;
        if !layer.rotation.is_finite() {
            return Err(format!(
                "anisotropy_rotation {}: must be a finite angle in radians",
                layer.rotation
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const QUAD: [Vec3; 4] = [
        Vec3::new(-0.5, -0.5, 0.0),
        Vec3::new(0.5, -0.5, 0.0),
        Vec3::new(0.5, 0.5, 0.0),
        Vec3::new(-0.5, 0.5, 0.0),
    ];
    const QUAD_TRIANGLES: [[u32; 3]; 2] = [[0, 1, 2], [0, 2, 3]];

    fn quad() -> MeshArrays<'static> {
        MeshArrays {
            positions: &QUAD,
            indices: &QUAD_TRIANGLES,
            ..Default::default()
        }
    }

    #[test]
    fn meshes_are_placed_by_their_pose_and_keep_their_materials() {
        let mut scene = Scene::empty("<arrays>");
        let red = Material {
            base_color: Vec4::new(1.0, 0.0, 0.0, 1.0),
            ..Material::default()
        };
        assert_eq!(scene.add_mesh(&quad(), red, Mat4::IDENTITY, None), Ok(0));
        let moved = Mat4::from_translation(Vec3::new(0.0, 0.0, -2.0));
        let named = Some("far".to_string());
        assert_eq!(
            scene.add_mesh(&quad(), Material::default(), moved, named),
            Ok(1)
        );
        assert_eq!(scene.soup.len(), 4);
        assert_eq!(scene.soup.material, [0, 0, 1, 1]);
        assert_eq!(scene.soup.instance, [0, 0, 1, 1]);
        assert_eq!(scene.soup.triangle(2)[0], Vec3::new(-0.5, -0.5, -2.0));
        assert_eq!(scene.bounds.min, Vec3::new(-0.5, -0.5, -2.0));
        assert_eq!(scene.bounds.max, Vec3::new(0.5, 0.5, 0.0));
        assert_eq!(
            scene.soup.corner_normals(0),
            [Vec3::Z; 3],
            "flat, facing +Z"
        );
        assert_eq!(scene.instances[1].name.as_deref(), Some("far"));
        assert_eq!(scene.materials[0].base_color.x, 1.0);
        assert!(scene.check_references().is_ok());
    }

    #[test]
    fn a_mirroring_pose_keeps_the_front_face_facing_out() {
        let mut scene = Scene::empty("<arrays>");
        let mirror = Mat4::from_scale(Vec3::new(1.0, 1.0, -1.0));
        scene
            .add_mesh(&quad(), Material::default(), mirror, None)
            .expect("a mirror is a valid pose");
        // The quad faced +Z; mirrored in z it faces -Z, and the winding says so.
        assert_eq!(scene.soup.corner_normals(0), [Vec3::NEG_Z; 3]);
    }

    #[test]
    fn bad_arrays_are_refused_naming_the_mesh_and_the_part() {
        let refused = |mesh: MeshArrays, pose: Mat4| {
            let mut scene = Scene::empty("<arrays>");
            scene.add_mesh(&quad(), Material::default(), Mat4::IDENTITY, None)?;
            scene
                .add_mesh(&mesh, Material::default(), pose, Some("bad".into()))
                .map(|_| ())
        };
        let message = |mesh, pose| refused(mesh, pose).unwrap_err().to_string();
        let out_of_range = [[0, 1, 4]];
        assert_eq!(
            message(
                MeshArrays {
                    indices: &out_of_range,
                    ..quad()
                },
                Mat4::IDENTITY
            ),
            "mesh 1 'bad': indices: triangle 0 uses vertex 4, but there are 4 vertices (0 to 3)"
        );
        let mut nan = QUAD;
        nan[2].y = f32::NAN;
        assert_eq!(
            message(
                MeshArrays {
                    positions: &nan,
                    ..quad()
                },
                Mat4::IDENTITY
            ),
            "mesh 1 'bad': positions: row 2 is not finite (NaN or infinite)"
        );
        let short = [Vec3::Z; 3];
        assert_eq!(
            message(
                MeshArrays {
                    normals: Some(&short),
                    ..quad()
                },
                Mat4::IDENTITY
            ),
            "mesh 1 'bad': normals: 3 rows, but there are 4 positions (one row a vertex)"
        );
        assert_eq!(
            message(quad(), Mat4::from_scale(Vec3::new(1.0, 0.0, 1.0))),
            "mesh 1 'bad': pose: singular (determinant 0): it flattens the mesh"
        );
        assert_eq!(
            message(
                MeshArrays {
                    indices: &[],
                    ..quad()
                },
                Mat4::IDENTITY
            ),
            "mesh 1 'bad': indices: empty: a mesh needs at least 1 triangle"
        );
        let mut scene = Scene::empty("<arrays>");
        let shiny = Material {
            roughness: 1.5,
            ..Material::default()
        };
        assert_eq!(
            scene
                .add_mesh(&quad(), shiny, Mat4::IDENTITY, None)
                .unwrap_err()
                .to_string(),
            "mesh 0: material: roughness 1.5: must be from 0 to 1"
        );
        assert!(scene.soup.is_empty() && scene.instances.is_empty());
    }

    #[test]
    fn zero_area_triangles_are_dropped_with_a_warning() {
        let mut scene = Scene::empty("<arrays>");
        let triangles = [[0, 1, 2], [0, 0, 1]];
        let mesh = MeshArrays {
            indices: &triangles,
            ..quad()
        };
        scene
            .add_mesh(&mesh, Material::default(), Mat4::IDENTITY, None)
            .expect("one triangle is left");
        assert_eq!(scene.soup.len(), 1);
        assert_eq!(
            scene.warnings,
            ["mesh 0: dropped 1 degenerate (zero-area) triangle"]
        );
    }

    /// A 2x1 image: red on the left, blue on the right.
    const RED_BLUE: [u8; 8] = [255, 0, 0, 255, 0, 0, 255, 255];

    const QUAD_UVS: [Vec2; 4] = [
        Vec2::new(0.0, 1.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(0.0, 0.0),
    ];

    #[test]
    fn a_texture_of_pixels_is_drawn_by_the_materials_that_name_it() {
        let mut scene = Scene::empty("<arrays>");
        let t = scene
            .add_texture(
                2,
                1,
                RED_BLUE.to_vec(),
                Sampler::default(),
                Some("rb".into()),
            )
            .expect("a 2x1 image");
        assert_eq!(t, 0);
        let textured = Material {
            base_color_texture: Some(crate::scene::TextureRef {
                texture: t,
                tex_coord: 0,
                transform: None,
            }),
            ..Material::default()
        };
        let mesh = MeshArrays {
            uv0: Some(&QUAD_UVS),
            ..quad()
        };
        scene
            .add_mesh(&mesh, textured.clone(), Mat4::IDENTITY, None)
            .expect("uvs and an existing texture");
        // A second mesh shares the texture.
        scene
            .add_mesh(&mesh, textured, Mat4::IDENTITY, None)
            .expect("textures can be shared");
        assert_eq!((scene.images.len(), scene.textures.len()), (1, 1));
        assert!(scene.check_references().is_ok());
        // The prepare phase takes the pixels as they are: the texture's left half is red.
        let mut warnings = Vec::new();
        let set =
            crate::prepare::textures::TextureSet::load(&scene, usize::MAX, true, &mut warnings)
                .expect("pixels need no decoding");
        assert!(warnings.is_empty(), "{warnings:?}");
        let r = scene.materials[0].base_color_texture.expect("set above");
        let (image, sampler) = set.lookup(&scene, &r).expect("the image is loaded");
        assert_eq!(image.size(), (2, 1));
        let nearest = Sampler {
            mag_filter: super::super::texture::Filter::Nearest,
            ..*sampler
        };
        let left = image.sample(Vec2::new(0.25, 0.5), 0.0, &nearest, false);
        let right = image.sample(Vec2::new(0.75, 0.5), 0.0, &nearest, false);
        assert_eq!((left.x, left.z), (1.0, 0.0));
        assert_eq!((right.x, right.z), (0.0, 1.0));
        // Held once: the full-size level is the scene's own buffer, not a copy of it.
        let pixels = scene.images[0].pixels.as_deref().expect("added as pixels");
        assert!(image.level_zero_is(pixels));
    }

    /// A second uv set is kept beside the first, corner for corner, for the textures that read
    /// set 1; a later mesh without it gets zeros there (none of its textures reads them).
    #[test]
    fn a_second_uv_set_is_kept_for_the_textures_that_read_it() {
        let mut scene = Scene::empty("<arrays>");
        let t = scene
            .add_texture(2, 1, RED_BLUE.to_vec(), Sampler::default(), None)
            .expect("2x1");
        let flipped = QUAD_UVS.map(|uv| Vec2::new(1.0 - uv.x, uv.y));
        let mesh = MeshArrays {
            uv0: Some(&QUAD_UVS),
            uv1: Some(&flipped),
            ..quad()
        };
        let occlusion_on_set_1 = Material {
            occlusion_texture: Some(crate::scene::TextureRef {
                texture: t,
                tex_coord: 1,
                transform: None,
            }),
            ..Material::default()
        };
        scene
            .add_mesh(&mesh, occlusion_on_set_1, Mat4::IDENTITY, None)
            .expect("set 1 is given");
        assert_eq!(scene.soup.len(), 2);
        for tri in 0..2 {
            let zero = scene.soup.corner_uvs(0, tri).expect("set 0");
            let one = scene.soup.corner_uvs(1, tri).expect("set 1");
            assert_eq!(one, zero.map(|uv| Vec2::new(1.0 - uv.x, uv.y)));
        }
        scene
            .add_mesh(&quad(), Material::default(), Mat4::IDENTITY, None)
            .expect("no uvs, no textures");
        assert_eq!(scene.soup.corner_uvs(1, 2), Some([Vec2::ZERO; 3]));
    }

    /// The extensions' factors are held to their specifications' ranges, each refusal naming
    /// the factor (as the Python package's key) and its value; glTF's defaults pass.
    #[test]
    fn extension_factors_outside_their_ranges_are_refused_by_name() {
        use crate::scene::material::{ClearcoatLayer, IridescenceLayer, SheenLayer};
        let base = Material::default();
        assert_eq!(check_material(&base), Ok(()));
        let refused = |change: &dyn Fn(&mut Material)| {
            let mut m = base.clone();
            change(&mut m);
            check_material(&m).unwrap_err()
        };
        assert_eq!(
            refused(&|m| m.transmission = 1.5),
            "transmission 1.5: must be from 0 to 1"
        );
        assert_eq!(
            refused(&|m| m.ior = 0.5),
            "ior 0.5: must be a finite number of at least 1"
        );
        assert_eq!(
            refused(&|m| m.dispersion = -1.0),
            "dispersion -1: must be a finite number of at least 0"
        );
        assert_eq!(
            refused(&|m| m.attenuation_color = Vec3::new(1.0, -0.5, 1.0)),
            "attenuation_color[1] -0.5: must be from 0 to 1"
        );
        assert_eq!(
            refused(&|m| m.attenuation_distance = 0.0),
            "attenuation_distance 0: must be above 0 (infinite for no attenuation)"
        );
        assert_eq!(
            refused(&|m| {
                m.sheen = Some(SheenLayer {
                    color: Vec3::new(2.0, 0.0, 0.0),
                    color_texture: None,
                    roughness: 0.5,
                    roughness_texture: None,
                })
            }),
            "sheen_color[0] 2: must be from 0 to 1"
        );
        let coat = |roughness| ClearcoatLayer {
            factor: 1.0,
            texture: None,
            roughness,
            roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
        };
        assert_eq!(
            refused(&|m| m.clearcoat = Some(coat(f32::NAN))),
            "clearcoat_roughness NaN: must be from 0 to 1"
        );
        assert_eq!(
            refused(&|m| {
                m.iridescence = Some(IridescenceLayer {
                    factor: 1.0,
                    texture: None,
                    ior: 1.3,
                    thickness_min: 100.0,
                    thickness_max: f32::INFINITY,
                    thickness_texture: None,
                })
            }),
            "iridescence_thickness[1] inf: must be a finite number of at least 0"
        );
        let mut glass = base.clone();
        (glass.transmission, glass.ior, glass.thin_walled) = (1.0, 1.0, false);
        glass.attenuation_distance = 0.3;
        glass.clearcoat = Some(coat(0.0));
        assert_eq!(check_material(&glass), Ok(()));
    }

    #[test]
    fn textures_are_refused_without_pixels_uvs_or_an_index_that_exists() {
        let mut scene = Scene::empty("<arrays>");
        let mut refused = |width, height, rgba: &[u8]| {
            scene
                .add_texture(
                    width,
                    height,
                    rgba.to_vec(),
                    Sampler::default(),
                    Some("t".into()),
                )
                .unwrap_err()
                .to_string()
        };
        assert_eq!(
            refused(0, 3, &[]),
            "texture 0 't': 0x3 pixels: an image needs at least one"
        );
        assert_eq!(
            refused(2, 1, &RED_BLUE[..6]),
            "texture 0 't': 6 bytes for 2x1 pixels: need 4 a pixel (RGBA)"
        );
        assert_eq!(
            refused(1, 1, &RED_BLUE),
            "texture 0 't': 8 bytes for 1x1 pixels: need 4 a pixel (RGBA)"
        );
        assert!(scene.textures.is_empty() && scene.images.is_empty());
        let at = |texture, tex_coord| Material {
            emissive_texture: Some(crate::scene::TextureRef {
                texture,
                tex_coord,
                transform: None,
            }),
            ..Material::default()
        };
        let with_uvs = MeshArrays {
            uv0: Some(&QUAD_UVS),
            ..quad()
        };
        let message = |scene: &mut Scene, mesh: &MeshArrays, material| {
            scene
                .add_mesh(mesh, material, Mat4::IDENTITY, None)
                .unwrap_err()
                .to_string()
        };
        assert_eq!(
            message(&mut scene, &with_uvs, at(0, 0)),
            "mesh 0: material: texture 0 does not exist (the scene has 0: add_texture returns their indices)"
        );
        let t = scene
            .add_texture(2, 1, RED_BLUE.to_vec(), Sampler::default(), None)
            .expect("2x1");
        assert_eq!(
            message(&mut scene, &with_uvs, at(t, 2)),
            "mesh 0: material: texture 0 reads texture coordinate set 2: a mesh from arrays has sets 0 and 1"
        );
        assert_eq!(
            message(&mut scene, &with_uvs, at(t, 1)),
            "mesh 0: uvs1: missing: the material has a texture that reads coordinate set 1"
        );
        let short = MeshArrays {
            uv1: Some(&QUAD_UVS[..3]),
            ..with_uvs
        };
        assert_eq!(
            message(&mut scene, &short, at(t, 1)),
            "mesh 0: uvs1: 3 rows, but there are 4 positions (one row a vertex)"
        );
        assert_eq!(
            message(&mut scene, &quad(), at(t, 0)),
            "mesh 0: uvs: missing: the material has textures, which are placed by the uvs"
        );
        assert!(scene.soup.is_empty() && scene.materials.is_empty());
    }
}
