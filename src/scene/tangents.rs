//! Tangents for normal mapping where the file has none, with MikkTSpace (glTF 2.0 §3.7.2.1:
//! "When tangents are not specified, client implementations SHOULD calculate tangents using
//! default MikkTSpace algorithms"), through the `bevy_mikktspace` crate.

use super::{Scene, TriangleSoup};
use glam::Vec4;

/// The triangles to process, as MikkTSpace geometry: faces are soup triangles.
struct Faces<'a> {
    soup: &'a TriangleSoup,
    faces: &'a [usize],
    uv_set: &'a [u32],
    out: Vec<[Vec4; 3]>,
}

impl Faces<'_> {
    /// The soup vertex at corner `vert` of face `face`.
    #[inline]
    fn vertex(&self, face: usize, vert: usize) -> usize {
        self.soup.indices[self.faces[face]][vert] as usize
    }
}

impl bevy_mikktspace::Geometry for Faces<'_> {
    fn num_faces(&self) -> usize {
        self.faces.len()
    }
    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }
    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.soup.positions[self.vertex(face, vert)].to_array()
    }
    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        self.soup.normals[self.vertex(face, vert)].to_array()
    }
    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        let uvs = if self.uv_set[face] == 1 {
            &self.soup.uv1
        } else {
            &self.soup.uv0
        };
        let uv = uvs
            .get(self.vertex(face, vert))
            .copied()
            .unwrap_or(glam::Vec2::ZERO);
        // MikkTSpace works with v up (OpenGL); glTF's v points down the image, and its normal
        // maps' green channel points up the image.
        [uv.x, 1.0 - uv.y]
    }
    fn set_tangent(
        &mut self,
        tangent_space: Option<bevy_mikktspace::TangentSpace>,
        face: usize,
        vert: usize,
    ) {
        if let Some(ts) = tangent_space {
            self.out[face][vert] = Vec4::from_array(ts.tangent_encoded());
        }
    }
}

/// Generates tangents for the triangles whose material has a normal map and whose tangents
/// the file did not give. Returns how many triangles got tangents.
pub fn generate_missing(scene: &mut Scene) -> usize {
    let soup = &scene.soup;
    let mut faces = Vec::new();
    let mut uv_set = Vec::new();
    for tri in 0..soup.len() {
        let Some(material) = scene.materials.get(soup.material[tri] as usize) else {
            continue;
        };
        let Some(normal_map) = material.normal_texture else {
            continue;
        };
        if soup.corner_tangents(tri).is_some_and(|t| t[0].w != 0.0) {
            continue;
        }
        faces.push(tri);
        uv_set.push(normal_map.tex_coord);
    }
    if faces.is_empty() {
        return 0;
    }
    let mut geometry = Faces {
        soup,
        faces: &faces,
        uv_set: &uv_set,
        out: vec![[Vec4::ZERO; 3]; faces.len()],
    };
    if bevy_mikktspace::generate_tangents(&mut geometry).is_err() {
        return 0;
    }
    let out = geometry.out;
    let soup = &mut scene.soup;
    let vertices = soup.vertex_count();
    if soup.tangents.len() < vertices {
        soup.tangents.resize(vertices, Vec4::ZERO);
    }
    // Tangents are stored per vertex. MikkTSpace gives one per triangle corner, the same at
    // every corner of a vertex except where it splits the tangent space (a mirrored UV seam
    // inside one vertex, say): there the corner gets a copy of the vertex of its own.
    let mut assigned = vec![false; vertices];
    for (face, &tri) in faces.iter().enumerate() {
        for (corner, &tangent) in out[face].iter().enumerate() {
            let v = soup.indices[tri][corner] as usize;
            if !assigned.get(v).copied().unwrap_or(true) {
                assigned[v] = true;
                soup.tangents[v] = tangent;
            } else if soup.tangents[v] != tangent {
                soup.indices[tri][corner] = duplicate_vertex(soup, v);
                soup.tangents.push(tangent);
            }
        }
    }
    faces.len()
}

/// Appends a copy of vertex `v` (every attribute but the tangent, which the caller pushes)
/// and returns its index.
fn duplicate_vertex(soup: &mut TriangleSoup, v: usize) -> u32 {
    let new = soup.positions.len() as u32;
    soup.positions.push(soup.positions[v]);
    soup.normals.push(soup.normals[v]);
    for uvs in [&mut soup.uv0, &mut soup.uv1] {
        if let Some(&uv) = uvs.get(v) {
            uvs.push(uv);
        }
    }
    if let Some(&c) = soup.colors.get(v) {
        soup.colors.push(c);
    }
    new
}
