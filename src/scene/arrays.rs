//! Scenes built in memory from arrays rather than read from a file: the Python package's
//! `Scene.from_arrays` and `add_mesh`, and any library user with vertices in hand.
//!
//! A mesh goes through the [`SoupBuilder`] the importers use, placed by a 4x4 pose as a glTF
//! node places its mesh (§3.7.2.1: normals by the inverse transpose, a mirroring pose flips
//! the winding), so what is rendered is exactly what a glTF file with the same vertices,
//! material and node would give. Unlike an importer, which drops what a file gets wrong with a
//! warning, arrays are refused whole: a caller that computed a NaN wants to hear about it.

use super::builder::{place_vertices, SoupBuilder, VerticesIn};
use super::material::{AlphaMode, Material};
use super::model::Scene;
use super::options::Format;
use super::soup::{Bounds, Instance, TriangleSoup};
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
        }
    }

    /// Adds `mesh` with its own `material`, placed in the world by `pose` (world from local,
    /// column-major as glam and glTF store it), as instance `name`. Returns the new instance's
    /// index (segmentation ids are this + 1).
    ///
    /// Refuses, naming the mesh and the array: no positions or no triangles, an attribute whose
    /// length differs from the positions', a NaN or infinite value, an index past the last
    /// vertex, a pose that is not finite or is singular, a material factor out of its glTF
    /// range, or more triangles than [`MAX_TRIANGLES`] in the scene. Triangles of zero area
    /// are dropped with a warning in [`Scene::warnings`], as the importers drop them.
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
    let rows: [(&str, Option<&[f32]>, usize); 4] = [
        ("positions", Some(bytemuck::cast_slice(mesh.positions)), 3),
        (
            "normals",
            mesh.normals.map(bytemuck::cast_slice::<Vec3, f32>),
            3,
        ),
        ("uvs", mesh.uv0.map(bytemuck::cast_slice::<Vec2, f32>), 2),
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
/// (§5.19, §5.22: colour, metallic, roughness and alpha cutoff in [0, 1], emissive at least 0).
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
    if !(material.emissive_strength.is_finite() && material.emissive_strength >= 0.0) {
        return Err(format!(
            "emissive_strength {}: must be a finite number of at least 0",
            material.emissive_strength
        ));
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
            ["mesh 0: dropped 1 degenerate (zero-area) triangles"]
        );
    }
}
