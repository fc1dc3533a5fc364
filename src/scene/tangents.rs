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

impl bevy_mikktspace::Geometry for Faces<'_> {
    fn num_faces(&self) -> usize {
        self.faces.len()
    }
    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }
    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.soup.positions[self.faces[face]][vert].to_array()
    }
    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        self.soup.normals[self.faces[face]][vert].to_array()
    }
    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        let tri = self.faces[face];
        let uvs = if self.uv_set[face] == 1 {
            &self.soup.uv1
        } else {
            &self.soup.uv0
        };
        let uv = uvs.get(tri).map_or(glam::Vec2::ZERO, |t| t[vert]);
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
        if soup.tangents.get(tri).is_some_and(|t| t[0].w != 0.0) {
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
    let count = soup.len();
    let tangents = &mut scene.soup.tangents;
    if tangents.len() < count {
        tangents.resize(count, [Vec4::ZERO; 3]);
    }
    for (face, tri) in faces.iter().enumerate() {
        tangents[*tri] = out[face];
    }
    faces.len()
}
