//! Tangents for normal mapping where the file has none, with MikkTSpace (glTF 2.0 §3.7.2.1:
//! "When tangents are not specified, client implementations SHOULD calculate tangents using
//! default MikkTSpace algorithms"), with `mikktspace` (bit-identical to the
//! `bevy_mikktspace` crate, which the tests compare it with, and about 3.5 times faster in a
//! real load: DamagedHelmet's tangents take about 5 ms where the crate took 17-19).

mod mikktspace;

use super::model::Scene;
use super::soup::TriangleSoup;
use glam::Vec4;
use mikktspace::Corners;
use std::borrow::Cow;

/// The MikkTSpace input of triangles `faces` of `soup`, texture coordinates from set
/// `uv_set[k]` for `faces[k]`: the soup's own vertex arrays, indexed, with the texture
/// coordinates of each vertex flipped to MikkTSpace's v-up convention. (Copying the attributes
/// out per corner, as MikkTSpace's callback interface reads them, was 1.5 MB and about 0.4 ms
/// of DamagedHelmet's load.)
pub(crate) struct CornerData<'s> {
    positions: Cow<'s, [[f32; 3]]>,
    normals: Cow<'s, [[f32; 3]]>,
    uvs: Vec<[f32; 2]>,
    indices: Vec<u32>,
}

impl<'s> CornerData<'s> {
    pub(crate) fn gather(soup: &'s TriangleSoup, faces: &[usize], uv_set: &[u32]) -> Self {
        // Set 1 is TEXCOORD_1; any other set reads TEXCOORD_0 (the soup keeps only these two).
        let set_of = |k: usize| u32::from(uv_set.get(k) == Some(&1));
        let first_set = set_of(0);
        let mixed = (0..faces.len()).any(|k| set_of(k) != first_set);
        let vertices = soup.vertex_count();
        let flipped = |set: u32| {
            let uvs = if set == 1 { &soup.uv1 } else { &soup.uv0 };
            (0..vertices).map(move |v| {
                let uv = uvs.get(v).copied().unwrap_or(glam::Vec2::ZERO);
                // MikkTSpace works with v up (OpenGL); glTF's v points down the image, and its
                // normal maps' green channel points up the image.
                [uv.x, 1.0 - uv.y]
            })
        };
        let positions: &[[f32; 3]] = bytemuck::cast_slice(&soup.positions);
        let normals: &[[f32; 3]] = bytemuck::cast_slice(&soup.normals);
        // Triangles that read different sets see every vertex twice: set 0's copies, then set
        // 1's (rare: a normal map on the second set beside one on the first).
        let (positions, normals, uvs) = if mixed {
            let twice = |a: &[[f32; 3]]| Cow::Owned([a, a].concat());
            let uvs = flipped(0).chain(flipped(1)).collect();
            (twice(positions), twice(normals), uvs)
        } else {
            let uvs = flipped(first_set).collect();
            (Cow::Borrowed(positions), Cow::Borrowed(normals), uvs)
        };
        let indices = faces
            .iter()
            .enumerate()
            .flat_map(|(k, &tri)| {
                let offset = if mixed && set_of(k) == 1 {
                    vertices as u32
                } else {
                    0
                };
                soup.indices[tri].map(|v| v + offset)
            })
            .collect();
        CornerData {
            positions,
            normals,
            uvs,
            indices,
        }
    }

    pub(crate) fn corners(&self) -> Corners<'_> {
        Corners {
            positions: &self.positions,
            normals: &self.normals,
            uvs: &self.uvs,
            indices: &self.indices,
        }
    }
}

/// Generates tangents for the triangles whose material has a normal map or an anisotropic
/// lobe (`KHR_materials_anisotropy` sets its direction in tangent space) and whose tangents
/// the file did not give. They follow the normal map's texture coordinates, else the
/// anisotropy texture's, else set 0. Returns how many triangles got tangents.
pub fn generate_missing(scene: &mut Scene) -> usize {
    let soup = &scene.soup;
    let mut faces = Vec::new();
    let mut uv_set = Vec::new();
    for tri in 0..soup.len() {
        let Some(material) = scene.materials.get(soup.material[tri] as usize) else {
            continue;
        };
        let anisotropic = material.anisotropy.as_ref().filter(|a| a.is_active());
        let tex_coord = match (&material.normal_texture, anisotropic) {
            (Some(normal_map), _) => normal_map.tex_coord,
            (None, Some(a)) => a.texture.map_or(0, |t| t.tex_coord),
            (None, None) => continue,
        };
        if soup.corner_tangents(tri).is_some_and(|t| t[0].w != 0.0) {
            continue;
        }
        faces.push(tri);
        uv_set.push(tex_coord);
    }
    if faces.is_empty() {
        return 0;
    }
    let out = mikktspace::generate(&CornerData::gather(soup, &faces, &uv_set).corners());
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
        for corner in 0..3 {
            // A corner MikkTSpace gives no tangent (a degenerate triangle without a good
            // neighbour) keeps zero, which marks "none".
            let tangent = out
                .get(3 * face + corner)
                .map_or(Vec4::ZERO, Vec4::from_array);
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

/// A warning when triangles whose material stretches its specular lobe
/// (`KHR_materials_anisotropy`) have no tangent after [`generate_missing`]: no TANGENT and no
/// texture coordinates to build one from (which the extension requires). Those are drawn
/// isotropic.
pub fn anisotropy_without_tangents(scene: &Scene) -> Option<String> {
    let soup = &scene.soup;
    let missing = (0..soup.len())
        .filter(|&tri| {
            scene
                .materials
                .get(soup.material[tri] as usize)
                .and_then(|m| m.anisotropy.as_ref())
                .is_some_and(|a| a.is_active())
        })
        .filter(|&tri| !soup.corner_tangents(tri).is_some_and(|t| t[0].w != 0.0))
        .count();
    (missing > 0).then(|| {
        format!(
            "{missing} triangles with KHR_materials_anisotropy have no tangents (no TANGENT and no texture coordinates to build them from); they are drawn isotropic"
        )
    })
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Vec2, Vec3};

    /// Each corner reads its vertex's position and normal and its face's texture coordinate set
    /// (v flipped), through the indices; with both sets in use too, and a set past 1 reading
    /// TEXCOORD_0.
    #[test]
    fn corners_read_their_vertex_and_their_faces_set() {
        let soup = TriangleSoup {
            positions: (0..5).map(|v| Vec3::new(v as f32, 1.0, 2.0)).collect(),
            normals: (0..5).map(|v| Vec3::new(0.0, v as f32, 1.0)).collect(),
            uv0: (0..5).map(|v| Vec2::new(v as f32, 0.25)).collect(),
            uv1: (0..5).map(|v| Vec2::new(-(v as f32), 0.75)).collect(),
            indices: vec![[0, 1, 2], [2, 1, 3], [3, 4, 0]],
            ..Default::default()
        };
        for (faces, sets) in [
            (vec![0, 1, 2], vec![0, 0, 0]),
            (vec![2, 0], vec![1, 1]),
            (vec![0, 1, 2], vec![0, 1, 2]),
        ] {
            let data = CornerData::gather(&soup, &faces, &sets);
            let corners = data.corners();
            assert_eq!(corners.indices.len(), 3 * faces.len());
            for (k, &face) in faces.iter().enumerate() {
                for c in 0..3 {
                    let at = corners.indices[3 * k + c] as usize;
                    let v = soup.indices[face][c] as usize;
                    assert_eq!(corners.positions[at], soup.positions[v].to_array());
                    assert_eq!(corners.normals[at], soup.normals[v].to_array());
                    let uv = if sets[k] == 1 {
                        soup.uv1[v]
                    } else {
                        soup.uv0[v]
                    };
                    assert_eq!(
                        corners.uvs[at],
                        [uv.x, 1.0 - uv.y],
                        "face {face} corner {c}"
                    );
                }
            }
        }
    }
    /// DamagedHelmet's corners, as [`CornerData::gather`] gathers them from the loaded scene,
    /// get the reference's tangents bit for bit, through the fast weld.
    #[test]
    fn damaged_helmet_matches_the_reference() {
        let Some(root) = std::env::var_os("MESHTRACER_SAMPLES") else {
            eprintln!("SKIPPED damaged_helmet_matches_the_reference: set MESHTRACER_SAMPLES");
            return;
        };
        let path = std::path::Path::new(&root).join("DamagedHelmet/glTF/DamagedHelmet.gltf");
        let scene = Scene::load(&path).expect("DamagedHelmet loads");
        let faces: Vec<usize> = (0..scene.soup.len()).collect();
        let uv_set = vec![0; faces.len()];
        let data = CornerData::gather(&scene.soup, &faces, &uv_set);
        let got = mikktspace::tests::assert_matches("DamagedHelmet", &data.corners());
        // It takes the fast weld (no degenerate triangle, so every triangle is a good one).
        mikktspace::tests::assert_fast_weld(&data.corners());
        assert_eq!(faces.len(), 15_452);
        assert!(got > 40_000, "{got} corners with a tangent");
    }
}
