//! The triangles of a scene in world space, their bounds, and the mesh instances they belong to.

use glam::{Vec2, Vec3, Vec4};
use serde::Serialize;

/// Every triangle of the scene in world space: shared vertices, and triangles that index them.
///
/// Vertex attributes are stored once per vertex (a vertex shared by six triangles, as in most
/// meshes, is stored once, not six times); the intersection test reads its own packed copy of
/// the positions ([`crate::accel`]), so the soup serves shading and building only.
///
/// Optional vertex attributes (`uv0`, `uv1`, `colors`, `tangents`) are either empty, when no
/// primitive had them, or exactly as long as `positions`, with defaults where a primitive
/// lacked them. [`Scene::check_references`] checks all of this once, at load.
///
/// [`Scene::check_references`]: super::model::Scene::check_references
#[derive(Clone, Debug, Default)]
pub struct TriangleSoup {
    /// World-space vertex positions.
    pub positions: Vec<Vec3>,
    /// World-space unit shading normals (a triangle with no usable normals in the file gets
    /// vertices of its own, with its flat normal).
    pub normals: Vec<Vec3>,
    /// Texture coordinate set 0 (glTF `TEXCOORD_0`; OBJ `vt`), (0,0) = image top-left.
    pub uv0: Vec<Vec2>,
    /// Texture coordinate set 1 (glTF `TEXCOORD_1`).
    pub uv1: Vec<Vec2>,
    /// Linear RGBA vertex colours (glTF `COLOR_0`), white where absent.
    pub colors: Vec<Vec4>,
    /// World-space tangents with handedness in w (glTF `TANGENT`), zero where absent.
    pub tangents: Vec<Vec4>,
    /// The three vertices of each triangle, counter-clockwise seen from its front face.
    pub indices: Vec<[u32; 3]>,
    /// Index into [`Scene::materials`](super::model::Scene::materials) for each triangle.
    pub material: Vec<u32>,
    /// Index into [`Scene::instances`](super::model::Scene::instances) for each triangle.
    pub instance: Vec<u32>,
}

impl TriangleSoup {
    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.indices.len()
    }

    /// The optional vertex attributes the soup holds, by field name (`uv0`, `uv1`, `colors`,
    /// `tangents`): what a file gave beyond positions and normals, which every soup has.
    pub fn attributes(&self) -> Vec<&'static str> {
        [
            ("uv0", self.uv0.is_empty()),
            ("uv1", self.uv1.is_empty()),
            ("colors", self.colors.is_empty()),
            ("tangents", self.tangents.is_empty()),
        ]
        .into_iter()
        .filter_map(|(name, empty)| (!empty).then_some(name))
        .collect()
    }

    /// True when the soup holds no triangle.
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// An attribute at the three corners of triangle `t`.
    #[inline]
    fn corners<T: Copy>(&self, values: &[T], t: usize) -> [T; 3] {
        self.indices[t].map(|v| values[v as usize])
    }

    /// The three vertex positions of triangle `t`.
    #[inline]
    pub fn triangle(&self, t: usize) -> [Vec3; 3] {
        self.corners(&self.positions, t)
    }

    /// The shading normals at the corners of triangle `t`.
    #[inline]
    pub fn corner_normals(&self, t: usize) -> [Vec3; 3] {
        self.corners(&self.normals, t)
    }

    /// Texture coordinates of set `set` (1: `TEXCOORD_1`, otherwise `TEXCOORD_0`) at the
    /// corners of triangle `t`; `None` when no primitive had that set.
    #[inline]
    pub fn corner_uvs(&self, set: u32, t: usize) -> Option<[Vec2; 3]> {
        let uvs = if set == 1 { &self.uv1 } else { &self.uv0 };
        (!uvs.is_empty()).then(|| self.corners(uvs, t))
    }

    /// Vertex colours at the corners of triangle `t`; `None` when no primitive had colours.
    #[inline]
    pub fn corner_colors(&self, t: usize) -> Option<[Vec4; 3]> {
        (!self.colors.is_empty()).then(|| self.corners(&self.colors, t))
    }

    /// Tangents at the corners of triangle `t`; `None` when no primitive had (or was given)
    /// tangents. A zero `w` marks a vertex without one.
    #[inline]
    pub fn corner_tangents(&self, t: usize) -> Option<[Vec4; 3]> {
        (!self.tangents.is_empty()).then(|| self.corners(&self.tangents, t))
    }

    /// Appends the triangles of `other` after this soup's, their vertex indices shifted past
    /// this soup's vertices. Optional attributes stay either empty or as long as the positions:
    /// one side's missing attribute is padded with the builder's defaults (uv 0, white, no
    /// tangent). `other`'s material and instance indices are kept as they are.
    pub fn append(&mut self, other: TriangleSoup) {
        let (mine, theirs) = (self.positions.len(), other.positions.len());
        fn pad<T: Copy>(a: &mut Vec<T>, b: Vec<T>, mine: usize, theirs: usize, default: T) {
            if a.is_empty() && b.is_empty() {
                return;
            }
            a.resize(mine, default);
            if b.is_empty() {
                a.resize(mine + theirs, default);
            } else {
                a.extend(b);
            }
        }
        pad(&mut self.uv0, other.uv0, mine, theirs, Vec2::ZERO);
        pad(&mut self.uv1, other.uv1, mine, theirs, Vec2::ZERO);
        pad(&mut self.colors, other.colors, mine, theirs, Vec4::ONE);
        pad(&mut self.tangents, other.tangents, mine, theirs, Vec4::ZERO);
        self.positions.extend(other.positions);
        self.normals.extend(other.normals);
        let shift = mine as u32;
        self.indices
            .extend(other.indices.iter().map(|t| t.map(|v| v + shift)));
        self.material.extend(other.material);
        self.instance.extend(other.instance);
    }

    /// Approximate heap size in bytes.
    pub fn heap_bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(self.positions.as_slice())
            + size_of_val(self.normals.as_slice())
            + size_of_val(self.uv0.as_slice())
            + size_of_val(self.uv1.as_slice())
            + size_of_val(self.colors.as_slice())
            + size_of_val(self.tangents.as_slice())
            + size_of_val(self.indices.as_slice())
            + size_of_val(self.material.as_slice())
            + size_of_val(self.instance.as_slice())
    }
}

/// Axis-aligned bounds in world space.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Bounds {
    /// Smallest corner.
    pub min: Vec3,
    /// Largest corner.
    pub max: Vec3,
}

impl Bounds {
    /// Bounds that contain nothing: growing them by a point gives that point.
    pub const EMPTY: Bounds = Bounds {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// Grows the box to contain `p`.
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// Centre of the box.
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Radius of the bounding sphere around [`Bounds::center`].
    pub fn radius(&self) -> f32 {
        (self.max - self.min).length() * 0.5
    }

    /// True when the box contains no point.
    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }
}

/// One placement of a mesh in the scene: a node that references a mesh (glTF) or one OBJ object.
#[derive(Clone, Debug, Serialize)]
pub struct Instance {
    /// glTF node index, if the instance comes from a node.
    pub node: Option<usize>,
    /// glTF mesh index, or the OBJ model index.
    pub mesh: usize,
    /// Node or object name.
    pub name: Option<String>,
}
