//! Writes the scenes bundled in `assets/`: `cornell-box.gltf` (the default scene),
//! `shapes.obj` + `shapes.mtl`, and `pendulum.gltf` (an animation, for `render --frames`). Run `cargo run --example make_assets` from the repository root;
//! `tests/it/bundled_assets.rs` checks that the committed files equal what this writes.

use base64::Engine;
use glam::{Quat, Vec3};
use serde_json::{json, Value};
use std::fmt::Write as _;

/// One mesh's vertex data: positions, normals and triangle indices.
#[derive(Default)]
struct MeshData {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    indices: Vec<u32>,
}

impl MeshData {
    /// A quad with corners in counter-clockwise order seen from its front.
    fn quad(&mut self, corners: [Vec3; 4]) {
        let n = (corners[1] - corners[0])
            .cross(corners[2] - corners[0])
            .normalize();
        let base = self.positions.len() as u32;
        self.positions.extend(corners);
        self.normals.extend([n; 4]);
        self.indices
            .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
    }

    /// An axis-aligned box of half-size `h` centred at the origin, faces outward.
    fn cuboid(h: Vec3) -> MeshData {
        let mut m = MeshData::default();
        let p = |x: f32, y: f32, z: f32| Vec3::new(x * h.x, y * h.y, z * h.z);
        m.quad([
            p(-1., -1., 1.),
            p(1., -1., 1.),
            p(1., 1., 1.),
            p(-1., 1., 1.),
        ]); // +Z
        m.quad([
            p(1., -1., -1.),
            p(-1., -1., -1.),
            p(-1., 1., -1.),
            p(1., 1., -1.),
        ]); // -Z
        m.quad([
            p(1., -1., 1.),
            p(1., -1., -1.),
            p(1., 1., -1.),
            p(1., 1., 1.),
        ]); // +X
        m.quad([
            p(-1., -1., -1.),
            p(-1., -1., 1.),
            p(-1., 1., 1.),
            p(-1., 1., -1.),
        ]); // -X
        m.quad([
            p(-1., 1., 1.),
            p(1., 1., 1.),
            p(1., 1., -1.),
            p(-1., 1., -1.),
        ]); // +Y
        m.quad([
            p(-1., -1., -1.),
            p(1., -1., -1.),
            p(1., -1., 1.),
            p(-1., -1., 1.),
        ]); // -Y
        m
    }

    /// A UV sphere of radius `r` with smooth normals.
    fn sphere(r: f32, rings: u32, segments: u32) -> MeshData {
        let mut m = MeshData::default();
        for i in 0..=rings {
            let theta = std::f32::consts::PI * i as f32 / rings as f32;
            for j in 0..=segments {
                let phi = std::f32::consts::TAU * j as f32 / segments as f32;
                let n = Vec3::new(
                    theta.sin() * phi.sin(),
                    theta.cos(),
                    theta.sin() * phi.cos(),
                );
                m.positions.push(n * r);
                m.normals.push(n);
            }
        }
        let row = segments + 1;
        for i in 0..rings {
            for j in 0..segments {
                let (a, b) = (i * row + j, (i + 1) * row + j);
                if i != 0 {
                    m.indices.extend([a, b, a + 1]);
                }
                if i != rings - 1 {
                    m.indices.extend([a + 1, b, b + 1]);
                }
            }
        }
        m
    }
}

/// Accumulates binary data and the glTF objects that describe it.
#[derive(Default)]
struct GltfWriter {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
    meshes: Vec<Value>,
}

impl GltfWriter {
    fn view(&mut self, bytes: &[u8], target: u32) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views.push(json!({
            "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len(), "target": target
        }));
        self.bin.extend_from_slice(bytes);
        self.views.len() - 1
    }

    fn vec3_accessor(&mut self, data: &[Vec3], with_bounds: bool) -> usize {
        let bytes: Vec<u8> = data
            .iter()
            .flat_map(|v| v.to_array())
            .flat_map(f32::to_le_bytes)
            .collect();
        let view = self.view(&bytes, 34962);
        let mut accessor = json!({
            "bufferView": view, "componentType": 5126, "count": data.len(), "type": "VEC3"
        });
        if with_bounds {
            let min = data.iter().fold(Vec3::INFINITY, |a, b| a.min(*b));
            let max = data.iter().fold(Vec3::NEG_INFINITY, |a, b| a.max(*b));
            accessor["min"] = json!(min.to_array());
            accessor["max"] = json!(max.to_array());
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// A float accessor of `kind` ("SCALAR", "VEC4") over `data` in a view without a target
    /// (animation data), with its bounds for a scalar (glTF requires them of sampler inputs).
    fn float_accessor(&mut self, data: &[f32], kind: &str, width: usize) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let bytes: Vec<u8> = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.views.push(json!({
            "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()
        }));
        self.bin.extend_from_slice(&bytes);
        let mut accessor = json!({
            "bufferView": self.views.len() - 1, "componentType": 5126,
            "count": data.len() / width, "type": kind
        });
        if kind == "SCALAR" {
            let min = data.iter().copied().fold(f32::INFINITY, f32::min);
            let max = data.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            accessor["min"] = json!([min]);
            accessor["max"] = json!([max]);
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// The glTF document: `scene` (its nodes, materials and the rest) with the asset header
    /// and this writer's meshes, accessors, views and buffer (a data URI), pretty-printed with
    /// a final newline.
    fn finish(self, mut scene: Value) -> String {
        let data_uri = format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&self.bin)
        );
        scene["asset"] = json!({
            "version": "2.0",
            "generator": "meshtracer examples/make_assets.rs",
            "copyright": "meshtracer authors, CC0-1.0"
        });
        scene["meshes"] = json!(self.meshes);
        scene["accessors"] = json!(self.accessors);
        scene["bufferViews"] = json!(self.views);
        scene["buffers"] = json!([{"byteLength": self.bin.len(), "uri": data_uri}]);
        let mut text = serde_json::to_string_pretty(&scene).expect("JSON of plain values");
        text.push('\n');
        text
    }

    fn mesh(&mut self, name: &str, data: &MeshData, material: usize) -> usize {
        let position = self.vec3_accessor(&data.positions, true);
        let normal = self.vec3_accessor(&data.normals, false);
        let bytes: Vec<u8> = data
            .indices
            .iter()
            .flat_map(|i| (*i as u16).to_le_bytes())
            .collect();
        let view = self.view(&bytes, 34963);
        self.accessors.push(json!({
            "bufferView": view, "componentType": 5123, "count": data.indices.len(), "type": "SCALAR"
        }));
        let indices = self.accessors.len() - 1;
        self.meshes.push(json!({
            "name": name,
            "primitives": [{
                "attributes": {"POSITION": position, "NORMAL": normal},
                "indices": indices, "material": material
            }]
        }));
        self.meshes.len() - 1
    }
}

fn rounded(v: Vec3) -> [f32; 3] {
    v.to_array().map(|x| (x * 1e6).round() / 1e6)
}

fn quat(q: Quat) -> [f32; 4] {
    q.to_array().map(|x| (x * 1e6).round() / 1e6)
}

/// The Cornell-box-style default scene.
fn cornell_box() -> String {
    let mut w = GltfWriter::default();
    let (white, red, green, gloss, plaster, lamp) = (0, 1, 2, 3, 4, 5);
    let mut walls = MeshData::default();
    let p = Vec3::new;
    walls.quad([
        p(-1., 0., 1.),
        p(1., 0., 1.),
        p(1., 0., -1.),
        p(-1., 0., -1.),
    ]); // floor, +Y
    walls.quad([
        p(-1., 2., -1.),
        p(1., 2., -1.),
        p(1., 2., 1.),
        p(-1., 2., 1.),
    ]); // ceiling, -Y
    walls.quad([
        p(-1., 0., -1.),
        p(1., 0., -1.),
        p(1., 2., -1.),
        p(-1., 2., -1.),
    ]); // back, +Z
    let mut left = MeshData::default();
    left.quad([
        p(-1., 0., 1.),
        p(-1., 0., -1.),
        p(-1., 2., -1.),
        p(-1., 2., 1.),
    ]); // +X
    let mut right = MeshData::default();
    right.quad([p(1., 0., -1.), p(1., 0., 1.), p(1., 2., 1.), p(1., 2., -1.)]); // -X
    let mut panel = MeshData::default();
    panel.quad([
        p(-0.2, 1.999, -0.2),
        p(0.2, 1.999, -0.2),
        p(0.2, 1.999, 0.2),
        p(-0.2, 1.999, 0.2),
    ]);

    let walls_mesh = w.mesh("walls", &walls, white);
    let left_mesh = w.mesh("left wall", &left, red);
    let right_mesh = w.mesh("right wall", &right, green);
    let tall_mesh = w.mesh(
        "tall box",
        &MeshData::cuboid(Vec3::new(0.3, 0.6, 0.3)),
        plaster,
    );
    let short_mesh = w.mesh("short box", &MeshData::cuboid(Vec3::splat(0.3)), plaster);
    let sphere_mesh = w.mesh("sphere", &MeshData::sphere(0.25, 24, 48), gloss);
    let panel_mesh = w.mesh("lamp panel", &panel, lamp);

    let spot_position = Vec3::new(-0.75, 1.85, 0.85);
    let spot_target = Vec3::new(0.35, 0.85, 0.3);
    let spot_rotation =
        Quat::from_rotation_arc(Vec3::NEG_Z, (spot_target - spot_position).normalize());

    w.finish(json!({
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"name": "ceiling bulb", "type": "point", "color": [1.0, 0.92, 0.8], "intensity": 2.5},
            {"name": "spot on the sphere", "type": "spot", "color": [0.85, 0.9, 1.0], "intensity": 6.0,
             "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.35}}
        ]}},
        "scene": 0,
        "scenes": [{"name": "Cornell box", "nodes": [0, 1, 2, 3, 4, 5, 6, 7, 8, 9]}],
        "nodes": [
            {"name": "walls", "mesh": walls_mesh},
            {"name": "left wall", "mesh": left_mesh},
            {"name": "right wall", "mesh": right_mesh},
            {"name": "tall box", "mesh": tall_mesh, "translation": [-0.35, 0.6, -0.35],
             "rotation": quat(Quat::from_rotation_y(0.3))},
            {"name": "short box", "mesh": short_mesh, "translation": [0.35, 0.3, 0.3],
             "rotation": quat(Quat::from_rotation_y(-0.3))},
            {"name": "sphere", "mesh": sphere_mesh, "translation": [0.35, 0.85, 0.3]},
            {"name": "lamp panel", "mesh": panel_mesh},
            {"name": "camera", "camera": 0, "translation": [0.0, 1.0, 3.9]},
            {"name": "ceiling bulb", "translation": [0.0, 1.55, 0.2],
             "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"name": "spot", "translation": rounded(spot_position), "rotation": quat(spot_rotation),
             "extensions": {"KHR_lights_punctual": {"light": 1}}}
        ],
        "cameras": [{"name": "front", "type": "perspective",
                     "perspective": {"yfov": 0.69, "aspectRatio": 1.3333334, "znear": 0.05}}],
        "materials": [
            {"name": "white", "pbrMetallicRoughness": {"baseColorFactor": [0.73, 0.73, 0.73, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.9}, "doubleSided": true},
            {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [0.63, 0.065, 0.05, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.9}, "doubleSided": true},
            {"name": "green", "pbrMetallicRoughness": {"baseColorFactor": [0.14, 0.45, 0.091, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.9}, "doubleSided": true},
            {"name": "orange gloss", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.45, 0.15, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.3}},
            {"name": "plaster", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.78, 0.74, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.6}},
            {"name": "lamp", "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0}, "emissiveFactor": [1.0, 0.92, 0.8], "doubleSided": true}
        ]
    }))
}

/// Seconds of one swing of the pendulum there and back: the animation's duration.
const SWING_SECONDS: f32 = 2.0;

/// A pendulum on a stand over a floor, without a camera or lights (the automatic camera and,
/// in the path tracer, the studio environment): its animation "Swing" turns the pivot about Z
/// by 30°·cos(2πt / 2 s), from +30° at 0 s through 0 at 0.5 s to -30° at 1 s and back, as
/// LINEAR keys every 1/12 s (slerp between them).
fn pendulum() -> String {
    let mut w = GltfWriter::default();
    let (floor_material, wood, steel, brass) = (0, 1, 2, 3);
    let p = Vec3::new;
    let mut floor = MeshData::default();
    floor.quad([
        p(-1.6, 0., 1.),
        p(1.6, 0., 1.),
        p(1.6, 0., -1.),
        p(-1.6, 0., -1.),
    ]);
    let floor_mesh = w.mesh("floor", &floor, floor_material);
    let post_mesh = w.mesh("post", &MeshData::cuboid(p(0.04, 1.0, 0.04)), wood);
    let beam_mesh = w.mesh("beam", &MeshData::cuboid(p(1.34, 0.04, 0.04)), wood);
    let rod_mesh = w.mesh("rod", &MeshData::cuboid(p(0.012, 0.6, 0.012)), steel);
    let bob_mesh = w.mesh("bob", &MeshData::sphere(0.22, 24, 48), brass);

    let keys = 24;
    let times: Vec<f32> = (0..=keys)
        .map(|k| SWING_SECONDS * k as f32 / keys as f32)
        .collect();
    let rotations: Vec<f32> = times
        .iter()
        .flat_map(|t| {
            let angle = 30f32.to_radians() * (std::f32::consts::TAU * t / SWING_SECONDS).cos();
            quat(Quat::from_rotation_z(angle))
        })
        .collect();
    let input = w.float_accessor(&times, "SCALAR", 1);
    let output = w.float_accessor(&rotations, "VEC4", 4);

    w.finish(json!({
        "scene": 0,
        "scenes": [{"name": "Pendulum", "nodes": [0, 1, 2, 3, 4]}],
        "nodes": [
            {"name": "floor", "mesh": floor_mesh},
            {"name": "left post", "mesh": post_mesh, "translation": [-1.3, 1.0, 0.0]},
            {"name": "right post", "mesh": post_mesh, "translation": [1.3, 1.0, 0.0]},
            {"name": "beam", "mesh": beam_mesh, "translation": [0.0, 2.04, 0.0]},
            {"name": "pivot", "translation": [0.0, 2.0, 0.0], "rotation": rotations[..4],
             "children": [5, 6]},
            {"name": "rod", "mesh": rod_mesh, "translation": [0.0, -0.6, 0.0]},
            {"name": "bob", "mesh": bob_mesh, "translation": [0.0, -1.42, 0.0]}
        ],
        "animations": [{
            "name": "Swing",
            "samplers": [{"input": input, "output": output, "interpolation": "LINEAR"}],
            "channels": [{"sampler": 0, "target": {"node": 4, "path": "rotation"}}]
        }],
        "materials": [
            {"name": "floor", "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.7, 0.7, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.8}},
            {"name": "wood", "pbrMetallicRoughness": {"baseColorFactor": [0.45, 0.28, 0.15, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.7}},
            {"name": "steel", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.82, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.35}},
            {"name": "brass", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.7, 0.35, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.25}}
        ]
    }))
}

/// A small OBJ scene with an MTL: ground, cube, pyramid, in three materials.
fn shapes_obj() -> (String, String) {
    let mut obj = String::from("# meshtracer bundled OBJ scene (CC0-1.0), written by examples/make_assets.rs\nmtllib shapes.mtl\n");
    let mut vertex_count = 0;
    let mut object =
        |obj: &mut String, name: &str, material: &str, verts: &[[f32; 3]], faces: &[&[usize]]| {
            let _ = writeln!(obj, "o {name}\nusemtl {material}");
            for v in verts {
                let _ = writeln!(obj, "v {} {} {}", v[0], v[1], v[2]);
            }
            for f in faces {
                let idx: Vec<String> = f
                    .iter()
                    .map(|i| (i + 1 + vertex_count).to_string())
                    .collect();
                let _ = writeln!(obj, "f {}", idx.join(" "));
            }
            vertex_count += verts.len();
        };
    object(
        &mut obj,
        "ground",
        "ground",
        &[[-3., 0., -3.], [-3., 0., 3.], [3., 0., 3.], [3., 0., -3.]],
        &[&[0, 1, 2, 3]],
    );
    let c = |x: f32, y: f32, z: f32| [x * 0.5 - 0.8, y * 0.5 + 0.5, z * 0.5];
    object(
        &mut obj,
        "cube",
        "blue",
        &[
            c(-1., -1., -1.),
            c(1., -1., -1.),
            c(1., 1., -1.),
            c(-1., 1., -1.),
            c(-1., -1., 1.),
            c(1., -1., 1.),
            c(1., 1., 1.),
            c(-1., 1., 1.),
        ],
        &[
            &[4, 5, 6, 7],
            &[1, 0, 3, 2],
            &[5, 1, 2, 6],
            &[0, 4, 7, 3],
            &[7, 6, 2, 3],
            &[0, 1, 5, 4],
        ],
    );
    object(
        &mut obj,
        "pyramid",
        "gold",
        &[
            [0.4, 0., -0.5],
            [1.4, 0., -0.5],
            [1.4, 0., 0.5],
            [0.4, 0., 0.5],
            [0.9, 1.2, 0.],
        ],
        &[
            &[0, 1, 2, 3],
            &[3, 2, 4],
            &[2, 1, 4],
            &[1, 0, 4],
            &[0, 3, 4],
        ],
    );
    let mtl = "# meshtracer bundled OBJ materials (CC0-1.0)\n\
newmtl ground\nKd 0.6 0.6 0.6\nKs 0.0 0.0 0.0\nNs 1\nillum 1\n\n\
newmtl blue\nKd 0.1 0.25 0.7\nKs 0.3 0.3 0.3\nNs 80\nillum 2\n\n\
newmtl gold\nKd 0.8 0.6 0.2\nKs 0.6 0.5 0.3\nNs 200\nillum 2\n"
        .to_string();
    (obj, mtl)
}

/// The bundled files, as (path under the repository root, contents).
pub fn assets() -> Vec<(&'static str, String)> {
    let (obj, mtl) = shapes_obj();
    vec![
        ("assets/cornell-box.gltf", cornell_box()),
        ("assets/shapes.obj", obj),
        ("assets/shapes.mtl", mtl),
        ("assets/pendulum.gltf", pendulum()),
    ]
}

#[allow(dead_code)]
fn main() -> std::io::Result<()> {
    for (path, text) in assets() {
        std::fs::write(path, text)?;
        println!("wrote {path}");
    }
    Ok(())
}
