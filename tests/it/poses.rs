//! Poses: `--animation` / `--time` and the static pose, on small glTF files written
//! here whose posed geometry is known in closed form (checked through `info --json` bounds,
//! camera and light placement, and a rendered mask), and on the sample models (skipped when
//! `MESHTRACER_SAMPLES` is unset).

use crate::common::{f32_bytes, read_rgba, run, s, samples, stderr, write_gltf};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// Positions and bounds are f32 through a 4x4 matrix product: a few ulps of a unit-sized value.
const POSITION_TOLERANCE: f64 = 1e-4;

/// Builds a glTF buffer: each `add` appends bytes as one buffer view with one accessor.
#[derive(Default)]
struct Buffer {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Buffer {
    /// Appends `bytes` (padded to 4) as a view and an accessor of `count` elements; returns
    /// the accessor index.
    fn add(&mut self, bytes: &[u8], count: usize, accessor: Value) -> usize {
        let mut accessor = accessor;
        self.views
            .push(json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()}));
        self.bin.extend(bytes);
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        accessor["bufferView"] = json!(self.views.len() - 1);
        accessor["count"] = json!(count);
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    fn floats(&mut self, values: &[f32], kind: &str) -> usize {
        let width = match kind {
            "SCALAR" => 1,
            "VEC3" => 3,
            "VEC4" => 4,
            "MAT4" => 16,
            _ => panic!("{kind}"),
        };
        let mut accessor = json!({"componentType": 5126, "type": kind});
        if kind == "SCALAR" {
            let min = values.iter().copied().fold(f32::INFINITY, f32::min);
            let max = values.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            accessor["min"] = json!([min]);
            accessor["max"] = json!([max]);
        }
        if kind == "VEC3" {
            let column = |k: usize| values.iter().skip(k).step_by(3).copied();
            accessor["min"] = json!((0..3)
                .map(|k| column(k).fold(f32::INFINITY, f32::min))
                .collect::<Vec<_>>());
            accessor["max"] = json!((0..3)
                .map(|k| column(k).fold(f32::NEG_INFINITY, f32::max))
                .collect::<Vec<_>>());
        }
        self.add(&f32_bytes(values), values.len() / width, accessor)
    }

    fn indices(&mut self, values: &[u16]) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|i| i.to_le_bytes()).collect();
        self.add(
            &bytes,
            values.len(),
            json!({"componentType": 5123, "type": "SCALAR"}),
        )
    }

    fn joints(&mut self, values: &[[u8; 4]]) -> usize {
        let bytes: Vec<u8> = values.iter().flatten().copied().collect();
        self.add(
            &bytes,
            values.len(),
            json!({"componentType": 5121, "type": "VEC4"}),
        )
    }

    /// Writes `json` with these accessors, views and buffer as `dir/name`.
    fn write(self, dir: &Path, name: &str, mut json: Value) -> PathBuf {
        json["asset"] = json!({"version": "2.0"});
        json["accessors"] = json!(self.accessors);
        json["bufferViews"] = json!(self.views);
        write_gltf(dir, name, json, &self.bin)
    }
}

/// The square [-half, half]² at z = 0 as a mesh primitive's POSITION and indices accessors.
fn square(buffer: &mut Buffer, half: f32) -> (usize, usize) {
    let corners = [
        -half, -half, 0.0, half, -half, 0.0, half, half, 0.0, -half, half, 0.0,
    ];
    (
        buffer.floats(&corners, "VEC3"),
        buffer.indices(&[0, 1, 2, 0, 2, 3]),
    )
}

/// `info --json` of `model` with `extra` options.
fn info(model: &Path, extra: &[&str]) -> Value {
    let mut args = vec!["info", s(model), "--json"];
    args.extend(extra);
    serde_json::from_slice(&run(&args, true).stdout).expect("info prints JSON")
}

/// The bounds (min, max) `info` reports.
fn bounds(v: &Value) -> ([f64; 3], [f64; 3]) {
    let read = |key: &str| {
        let a = v["bounds"][key].as_array().expect("bounds");
        [0, 1, 2].map(|k| a[k].as_f64().expect("number"))
    };
    (read("min"), read("max"))
}

fn assert_close(actual: [f64; 3], expected: [f64; 3], what: &str) {
    let off = (0..3).any(|k| (actual[k] - expected[k]).abs() > POSITION_TOLERANCE);
    assert!(!off, "{what}: {actual:?}, expected {expected:?}");
}

/// A 4x4 square (half-size 2) on node 0 whose translation animation 0 ("slide", LINEAR) moves
/// from the origin at t = 0 to x = 4 at t = 2; animation 1 ("hop", STEP) moves it to y = 10
/// at t = 1; animation 2 ("ease", CUBICSPLINE, zero tangents) moves it from the origin to
/// x = 8 over 2 s. Node 1 is an orthographic camera at z = 5 framing [-2, 2]², animated by
/// "slide" to z = 9 at t = 2; node 2 a point light animated from y = 0 to y = 6.
fn sliding_square(dir: &Path) -> PathBuf {
    let mut b = Buffer::default();
    let (position, indices) = square(&mut b, 2.0);
    let times = b.floats(&[0.0, 2.0], "SCALAR");
    let slide = b.floats(&[0.0, 0.0, 0.0, 4.0, 0.0, 0.0], "VEC3");
    let camera_path = b.floats(&[0.0, 0.0, 5.0, 0.0, 0.0, 9.0], "VEC3");
    let light_path = b.floats(&[0.0, 0.0, 0.0, 0.0, 6.0, 0.0], "VEC3");
    let hop_times = b.floats(&[0.0, 1.0], "SCALAR");
    let hop = b.floats(&[0.0, 0.0, 0.0, 0.0, 10.0, 0.0], "VEC3");
    // (in-tangent, value, out-tangent) per key, tangents zero: the smoothstep 3s² - 2s³.
    let ease = b.floats(
        &[
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, //
            0.0, 0.0, 0.0, 8.0, 0.0, 0.0, 0.0, 0.0, 0.0,
        ],
        "VEC3",
    );
    let sampler = |input, output, interpolation| json!({"input": input, "output": output, "interpolation": interpolation});
    let channel = |sampler: usize, node: usize| json!({"sampler": sampler, "target": {"node": node, "path": "translation"}});
    b.write(
        dir,
        "sliding.gltf",
        json!({
            "scene": 0,
            "scenes": [{"nodes": [0, 1, 2]}],
            "extensionsUsed": ["KHR_lights_punctual"],
            "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 5.0}]}},
            "nodes": [
                {"mesh": 0},
                {"camera": 0, "translation": [0.0, 0.0, 5.0]},
                {"extensions": {"KHR_lights_punctual": {"light": 0}}}
            ],
            "cameras": [{"type": "orthographic", "orthographic": {"xmag": 2.0, "ymag": 2.0, "znear": 0.1, "zfar": 100.0}}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": position}, "indices": indices}]}],
            "animations": [
                {"name": "slide", "samplers": [
                    sampler(times, slide, "LINEAR"),
                    sampler(times, camera_path, "LINEAR"),
                    sampler(times, light_path, "LINEAR")
                ], "channels": [channel(0, 0), channel(1, 1), channel(2, 2)]},
                {"name": "hop", "samplers": [sampler(hop_times, hop, "STEP")], "channels": [channel(0, 0)]},
                {"name": "ease", "samplers": [sampler(times, ease, "CUBICSPLINE")], "channels": [channel(0, 0)]}
            ]
        }),
    )
}

#[test]
fn node_translation_is_sampled_step_linear_and_cubic_and_clamped() {
    let dir = tempfile::tempdir().unwrap();
    let model = sliding_square(dir.path());
    // The static pose: where the file puts the node.
    assert_close(bounds(&info(&model, &[])).0, [-2.0, -2.0, 0.0], "static");
    // LINEAR: halfway through 0..2 s is x = 2.
    let (min, max) = bounds(&info(&model, &["--animation", "slide", "--time", "1"]));
    assert_close(min, [0.0, -2.0, 0.0], "slide at 1 s");
    assert_close(max, [4.0, 2.0, 0.0], "slide at 1 s");
    // --time alone uses animation 0; past the end it holds the last keyframe (x = 4).
    let late = info(&model, &["--time", "7.5"]);
    assert_close(bounds(&late).0, [2.0, -2.0, 0.0], "slide at 7.5 s");
    let pose = late["pose"].as_str().expect("the pose is reported");
    assert!(
        pose.contains("'slide'") && pose.contains("past its end"),
        "{pose}"
    );
    // --animation alone is time 0.
    assert_close(
        bounds(&info(&model, &["--animation", "0"])).0,
        [-2.0, -2.0, 0.0],
        "slide at 0 s",
    );
    // STEP holds the first key until t = 1, then jumps.
    assert_close(
        bounds(&info(&model, &["--animation", "hop", "--time", "0.99"])).0,
        [-2.0, -2.0, 0.0],
        "hop at 0.99 s",
    );
    assert_close(
        bounds(&info(&model, &["--animation", "hop", "--time", "1"])).0,
        [-2.0, 8.0, 0.0],
        "hop at 1 s",
    );
    // CUBICSPLINE with zero tangents at s = 0.25 (t = 0.5 s): 8 · (3s² - 2s³) = 1.25.
    assert_close(
        bounds(&info(&model, &["--animation", "ease", "--time", "0.5"])).0,
        [-0.75, -2.0, 0.0],
        "ease at 0.5 s",
    );
}

#[test]
fn cameras_and_lights_follow_their_animated_nodes() {
    let dir = tempfile::tempdir().unwrap();
    let model = sliding_square(dir.path());
    let at_rest = info(&model, &[]);
    assert_eq!(at_rest["cameras"][0]["position"], json!([0.0, 0.0, 5.0]));
    let v = info(&model, &["--animation", "slide", "--time", "1.5"]);
    let position = |v: &Value| -> [f64; 3] {
        let a = v["position"].as_array().expect("position");
        [0, 1, 2].map(|k| a[k].as_f64().expect("number"))
    };
    assert_close(
        position(&v["cameras"][0]),
        [0.0, 0.0, 8.0],
        "camera at 1.5 s",
    );
    assert_close(position(&v["lights"][0]), [0.0, 4.5, 0.0], "light at 1.5 s");
}

#[test]
fn a_rendered_animated_square_covers_the_part_of_the_frame_it_moved_to() {
    let dir = tempfile::tempdir().unwrap();
    let model = sliding_square(dir.path());
    let render_mask = |extra: &[&str], name: &str| {
        let mask = dir.path().join(format!("{name}.mask.png"));
        let image = dir.path().join(format!("{name}.png"));
        render(
            &model,
            &image,
            40,
            &[&["--mask-out", s(&mask)][..], extra].concat(),
        );
        // Each column: Some(true) if every pixel is covered, Some(false) if none is.
        let (w, _, pixels) = read_rgba(&mask);
        let w = w as usize;
        (0..w)
            .map(|column| {
                let values: Vec<bool> = pixels
                    .iter()
                    .skip(column)
                    .step_by(w)
                    .map(|p| p[0] > 0.5)
                    .collect();
                if values.iter().all(|&c| c) {
                    Some(true)
                } else if values.iter().all(|&c| !c) {
                    Some(false)
                } else {
                    None
                }
            })
            .collect::<Vec<_>>()
    };
    // "ease" moves only the square (the camera stays at z = 5 framing [-2, 2]²): at 0.5 s
    // it spans x in [-0.75, 3.25]. x = -0.75 is at pixel 12.5 of 40: the 12 columns left of
    // it are empty, those from 13 on covered (column 12's centre is on the edge).
    let columns = render_mask(&["--animation", "ease", "--time", "0.5"], "ease");
    assert!(
        columns[..12].iter().all(|c| *c == Some(false)),
        "{columns:?}"
    );
    assert!(
        columns[13..].iter().all(|c| *c == Some(true)),
        "{columns:?}"
    );
    // At rest the square fills the frame; "hop" at 1 s lifts it out of it.
    let columns = render_mask(&[], "rest");
    assert!(columns.iter().all(|c| *c == Some(true)), "{columns:?}");
    let columns = render_mask(&["--animation", "hop", "--time", "1"], "hop");
    assert!(columns.iter().all(|c| *c == Some(false)), "{columns:?}");
}

/// Half the height of the skinned strip.
const H: f32 = 0.25;

/// A strip along +X from 0 to 2 (height 2H), skinned to two joints: node 1 (joint 0) at the
/// origin and its child node 2 (joint 1) at x = 1, whose inverse bind matrix undoes that
/// translation. The vertices at x = 0 follow joint 0, those at x = 1 and 2 joint 1 (the x = 2
/// pair with weights (2, 0, 0, 0), which must be normalised). The mesh node 0 is moved to
/// x = 100, which a skinned mesh ignores (glTF 2.0 §3.7.3). `joint1` is joint 1's rotation at
/// rest; animation "bend" turns it linearly from none to +90° about Z over 1 s. `joint_of_tip`
/// is the joint the x = 2 pair is bound to, `times` the bend's keyframe times.
fn skinned_strip(
    dir: &Path,
    name: &str,
    joint1: [f32; 4],
    joint_of_tip: u8,
    times: [f32; 2],
) -> PathBuf {
    let mut b = Buffer::default();
    let positions = b.floats(
        &[
            0.0, -H, 0.0, 0.0, H, 0.0, 1.0, -H, 0.0, 1.0, H, 0.0, 2.0, -H, 0.0, 2.0, H, 0.0,
        ],
        "VEC3",
    );
    let indices = b.indices(&[0, 2, 3, 0, 3, 1, 2, 4, 5, 2, 5, 3]);
    let tip = [joint_of_tip, 0, 0, 0];
    let joints = b.joints(&[
        [0, 0, 0, 0],
        [0, 0, 0, 0],
        [1, 0, 0, 0],
        [1, 0, 0, 0],
        tip,
        tip,
    ]);
    let weights = b.floats(
        &[
            1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, //
            2.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0,
        ],
        "VEC4",
    );
    let mut inverse_bind = glam::Mat4::IDENTITY.to_cols_array().to_vec();
    inverse_bind
        .extend(glam::Mat4::from_translation(glam::Vec3::new(-1.0, 0.0, 0.0)).to_cols_array());
    let inverse_bind = b.floats(&inverse_bind, "MAT4");
    let times = b.floats(&times, "SCALAR");
    let quarter = glam::Quat::from_rotation_z(std::f32::consts::FRAC_PI_2).to_array();
    let mut rotations = vec![0.0, 0.0, 0.0, 1.0];
    rotations.extend(quarter);
    let rotations = b.floats(&rotations, "VEC4");
    b.write(
        dir,
        name,
        json!({
            "scene": 0,
            "scenes": [{"nodes": [0, 1]}],
            "nodes": [
                {"mesh": 0, "skin": 0, "translation": [100.0, 0.0, 0.0]},
                {"children": [2]},
                {"translation": [1.0, 0.0, 0.0], "rotation": joint1}
            ],
            "skins": [{"joints": [1, 2], "inverseBindMatrices": inverse_bind}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": positions, "JOINTS_0": joints, "WEIGHTS_0": weights}, "indices": indices}]}],
            "animations": [{"name": "bend",
                "samplers": [{"input": times, "output": rotations}],
                "channels": [{"sampler": 0, "target": {"node": 2, "path": "rotation"}}]}]
        }),
    )
}

#[test]
fn skins_follow_their_joints_in_the_static_and_the_animated_pose() {
    let dir = tempfile::tempdir().unwrap();
    let straight = skinned_strip(
        dir.path(),
        "straight.gltf",
        [0.0, 0.0, 0.0, 1.0],
        1,
        [0.0, 1.0],
    );
    // At rest the strip lies where its vertices are, not at the mesh node's x = 100.
    let (min, max) = bounds(&info(&straight, &[]));
    assert_close(min, [0.0, -0.25, 0.0], "straight strip");
    assert_close(max, [2.0, 0.25, 0.0], "straight strip");
    // Bent by 90° about Z at x = 1: the tip pair (2, ±H) swings to (1 ∓ H, 1).
    let (min, max) = bounds(&info(&straight, &["--animation", "bend", "--time", "1"]));
    assert_close(min, [0.0, -0.25, 0.0], "bent strip");
    assert_close(max, [1.25, 1.0, 0.0], "bent strip");
    // Halfway (slerp, 45°): the tip reaches (1 + cos 45° ∓ H sin 45°, sin 45° ± H cos 45°).
    let (_, max) = bounds(&info(&straight, &["--animation", "bend", "--time", "0.5"]));
    let (c, s45) = (
        std::f64::consts::FRAC_1_SQRT_2,
        std::f64::consts::FRAC_1_SQRT_2,
    );
    let h = f64::from(H);
    assert_close(
        max,
        [1.0 + c + h * s45, s45 + h * c, 0.0],
        "strip bent by 45°",
    );
    // The static pose is skinned through the joints' own transforms: joint 1 already turned
    // by 90° in the file bends the strip without any animation.
    let quarter = glam::Quat::from_rotation_z(std::f32::consts::FRAC_PI_2).to_array();
    let bent = skinned_strip(dir.path(), "bent.gltf", quarter, 1, [0.0, 1.0]);
    let (_, max) = bounds(&info(&bent, &[]));
    assert_close(max, [1.25, 1.0, 0.0], "strip bent at rest");
    // Without inverseBindMatrices every one is the identity (§3.7.3): joint 1's translation to
    // x = 1 then moves the vertices bound to it by 1, so the strip reaches x = 3.
    let mut json: Value = serde_json::from_slice(&std::fs::read(&straight).unwrap()).unwrap();
    json["skins"][0]
        .as_object_mut()
        .unwrap()
        .remove("inverseBindMatrices");
    let unbound = dir.path().join("no-inverse-bind.gltf");
    std::fs::write(&unbound, json.to_string()).unwrap();
    let (min, max) = bounds(&info(&unbound, &[]));
    assert_close(min, [0.0, -0.25, 0.0], "identity inverse bind matrices");
    assert_close(max, [3.0, 0.25, 0.0], "identity inverse bind matrices");
}

#[test]
fn broken_skins_and_animations_are_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let fails = |model: &Path, extra: &[&str], expect: &[&str]| {
        let mut args = vec!["info", s(model)];
        args.extend(extra);
        let message = stderr(&run(&args, false));
        let name = model.file_name().and_then(|n| n.to_str()).unwrap_or("");
        assert!(message.contains(name), "names the file: {message}");
        for e in expect {
            assert!(message.contains(e), "says {e}: {message}");
        }
        assert!(!message.contains("panick"), "{message}");
    };
    let bad_joint = skinned_strip(
        dir.path(),
        "bad-joint.gltf",
        [0.0, 0.0, 0.0, 1.0],
        7,
        [0.0, 1.0],
    );
    fails(&bad_joint, &[], &["skin 0", "joint 7", "2 joints"]);
    let backwards = skinned_strip(
        dir.path(),
        "backwards.gltf",
        [0.0, 0.0, 0.0, 1.0],
        1,
        [1.0, 0.5],
    );
    fails(&backwards, &["--animation", "bend"], &["not increasing"]);
    // Not asked for, a broken animation is only a warning: the static pose still loads.
    let v = info(&backwards, &[]);
    assert!(
        v["warnings"].to_string().contains("not increasing"),
        "{}",
        v["warnings"]
    );
    let model = sliding_square(dir.path());
    fails(
        &model,
        &["--animation", "walk"],
        &["'walk'", "0 'slide'", "1 'hop'", "2 'ease'"],
    );
    fails(&model, &["--animation", "3"], &["'3'", "0 'slide'"]);
    for bad in ["nan", "-1", "inf", "soon"] {
        let out = run(&["info", s(&model), "--time", bad], false);
        let message = stderr(&out);
        assert!(message.contains("--time"), "{bad}: {message}");
    }
    // A file without animations: --time has nothing to sample.
    let still = skinned_strip(
        dir.path(),
        "still.gltf",
        [0.0, 0.0, 0.0, 1.0],
        1,
        [0.0, 1.0],
    );
    let mut json: Value = serde_json::from_slice(&std::fs::read(&still).unwrap()).unwrap();
    json.as_object_mut().unwrap().remove("animations");
    std::fs::write(&still, json.to_string()).unwrap();
    fails(&still, &["--time", "1"], &["no animations"]);
}

/// A square (half-size 1) with one morph target moving every vertex by +2 in x, mesh default
/// weight 0.5; `node_weights` on the node if given; animation "pulse" sets the weight to 1 at
/// t = 1 (STEP).
fn morphing_square(dir: &Path, node_weights: Option<f32>) -> PathBuf {
    let mut b = Buffer::default();
    let (position, indices) = square(&mut b, 1.0);
    let delta = b.floats(&[2.0, 0.0, 0.0].repeat(4), "VEC3");
    let times = b.floats(&[0.0, 1.0], "SCALAR");
    let weights = b.floats(&[0.0, 1.0], "SCALAR");
    let mut node = json!({"mesh": 0});
    if let Some(w) = node_weights {
        node["weights"] = json!([w]);
    }
    b.write(
        dir,
        "morph.gltf",
        json!({
            "scene": 0,
            "scenes": [{"nodes": [0]}],
            "nodes": [node],
            "meshes": [{"weights": [0.5], "primitives": [{"attributes": {"POSITION": position}, "indices": indices, "targets": [{"POSITION": delta}]}]}],
            "animations": [{"name": "pulse",
                "samplers": [{"input": times, "output": weights, "interpolation": "STEP"}],
                "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}]}]
        }),
    )
}

#[test]
fn morph_weights_come_from_the_mesh_the_node_and_the_animation() {
    let dir = tempfile::tempdir().unwrap();
    let model = morphing_square(dir.path(), None);
    // The mesh's default weight 0.5 moves the square halfway: x in [0, 2].
    let v = info(&model, &[]);
    assert_close(bounds(&v).0, [0.0, -1.0, 0.0], "mesh weight 0.5");
    let warnings = v["warnings"].to_string();
    assert!(!warnings.contains("morph"), "{warnings}");
    // The animation overrides it: 0 before t = 1, 1 from t = 1.
    let at = |t: &str| bounds(&info(&model, &["--animation", "pulse", "--time", t])).0;
    assert_close(at("0.5"), [-1.0, -1.0, 0.0], "pulse weight 0");
    assert_close(at("1"), [1.0, -1.0, 0.0], "pulse weight 1");
    // Node weights override the mesh's.
    let model = morphing_square(dir.path(), Some(0.25));
    assert_close(
        bounds(&info(&model, &[])).0,
        [-0.5, -1.0, 0.0],
        "node weight 0.25",
    );
}

/// Mean absolute difference of two images' RGBA channels.
fn mean_abs_diff(a: &Path, b: &Path) -> f64 {
    let (wa, ha, pa) = read_rgba(a);
    let (wb, hb, pb) = read_rgba(b);
    assert_eq!((wa, ha), (wb, hb));
    let sum: f64 = pa
        .iter()
        .zip(&pb)
        .flat_map(|(x, y)| x.iter().zip(y).map(|(x, y)| f64::from((x - y).abs())))
        .sum();
    sum / (pa.len() * 4) as f64
}

/// Renders `model` to `out`, `size` pixels square at one sample per pixel.
fn render(model: &Path, out: &Path, size: u32, extra: &[&str]) {
    let size = size.to_string();
    let mut args = vec!["render", s(model), "-o", s(out), "--spp", "1", "-q"];
    args.extend(["--width", &size, "--height", &size]);
    args.extend(extra);
    run(&args, true);
}

#[test]
fn fox_lists_its_animations_and_moves_between_times() {
    let Some(samples) = samples("fox_lists_its_animations_and_moves_between_times") else {
        return;
    };
    let fox = samples.join("Fox/glTF/Fox.gltf");
    let v = info(&fox, &[]);
    let names: Vec<&str> = v["animations"]
        .as_array()
        .expect("animations listed")
        .iter()
        .map(|a| a["name"].as_str().unwrap_or(""))
        .collect();
    assert_eq!(names, ["Survey", "Walk", "Run"]);
    for a in v["animations"].as_array().unwrap() {
        assert!(a["duration"].as_f64().unwrap() > 0.5, "{a}");
        assert!(a["channels"].as_u64().unwrap() > 0, "{a}");
    }
    let warnings = v["warnings"].to_string();
    assert!(!warnings.contains("bind pose"), "{warnings}");
    let dir = tempfile::tempdir().unwrap();
    let (early, late) = (dir.path().join("early.png"), dir.path().join("late.png"));
    // Fixed framing, so only the pose changes the image.
    let camera = ["--look-from", "150,60,150", "--look-at", "0,40,0"];
    for (out, time) in [(&early, "0"), (&late, "0.3")] {
        let pose = ["--animation", "Run", "--time", time];
        render(&fox, out, 64, &[&pose[..], &camera].concat());
    }
    let diff = mean_abs_diff(&early, &late);
    assert!(diff > 0.005, "the run moves the fox: mean abs diff {diff}");
    let out = run(&["info", s(&fox), "--animation", "Gallop"], false);
    let message = stderr(&out);
    assert!(
        message.contains("'Survey'") && message.contains("'Run'"),
        "{message}"
    );
}

/// The Draco variants decode the same skinned (and the quantized variant the same morphed)
/// meshes: posed, their bounds agree and their images differ by little.
#[test]
fn compressed_variants_pose_like_the_plain_files() {
    let Some(samples) = samples("compressed_variants_pose_like_the_plain_files") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    // Draco quantizes positions to 2^-11..2^-14 of the model's size; normals more coarsely.
    const BOUNDS_TOLERANCE: f64 = 2e-3;
    const IMAGE_TOLERANCE: f64 = 0.01;
    for (plain, packed, options) in [
        (
            "CesiumMan/glTF/CesiumMan.gltf",
            "CesiumMan/glTF-Draco/CesiumMan.gltf",
            vec!["--time", "1"],
        ),
        (
            "CesiumMan/glTF/CesiumMan.gltf",
            "CesiumMan/glTF-Draco/CesiumMan.gltf",
            vec![],
        ),
        (
            "RiggedSimple/glTF/RiggedSimple.gltf",
            "RiggedSimple/glTF-Draco/RiggedSimple.gltf",
            vec!["--time", "2"],
        ),
        (
            "AnimatedMorphCube/glTF/AnimatedMorphCube.gltf",
            "AnimatedMorphCube/glTF-Quantized/AnimatedMorphCube.gltf",
            vec!["--time", "0.5"],
        ),
    ] {
        let (a, b) = (samples.join(plain), samples.join(packed));
        let (va, vb) = (info(&a, &options), info(&b, &options));
        let ((amin, amax), (bmin, bmax)) = (bounds(&va), bounds(&vb));
        let size = (0..3).map(|k| amax[k] - amin[k]).fold(0.0, f64::max);
        for k in 0..3 {
            assert!(
                (amin[k] - bmin[k]).abs() <= BOUNDS_TOLERANCE * size
                    && (amax[k] - bmax[k]).abs() <= BOUNDS_TOLERANCE * size,
                "{packed} {options:?}: bounds {bmin:?}..{bmax:?} vs {amin:?}..{amax:?}"
            );
        }
        let (ia, ib) = (dir.path().join("a.png"), dir.path().join("b.png"));
        render(&a, &ia, 64, &options);
        render(&b, &ib, 64, &options);
        let diff = mean_abs_diff(&ia, &ib);
        if diff >= IMAGE_TOLERANCE {
            let kept = crate::common::keep_failed_images(packed, &ia, &ib);
            panic!(
                "{packed} {options:?}: mean abs diff {diff} (max {IMAGE_TOLERANCE}); images in {}",
                kept.display()
            );
        }
    }
}

/// CesiumMan's static pose is computed through its 19 joints (node transforms and inverse
/// bind matrices), not taken from the raw vertices; its joints rest where they were bound, so
/// the skinned mesh must land where the raw POSITION box, placed by the mesh node's parents
/// (Z_UP · Armature), would: the file's own statement of the bind pose.
#[test]
fn cesium_man_static_pose_matches_its_bind_pose() {
    let Some(samples) = samples("cesium_man_static_pose_matches_its_bind_pose") else {
        return;
    };
    let model = samples.join("CesiumMan/glTF/CesiumMan.gltf");
    let json: Value = serde_json::from_slice(&std::fs::read(&model).unwrap()).unwrap();
    let matrix = |node: usize| {
        let m: Vec<f32> = json["nodes"][node]["matrix"]
            .as_array()
            .expect("a matrix node")
            .iter()
            .map(|x| x.as_f64().unwrap() as f32)
            .collect();
        glam::Mat4::from_cols_slice(&m)
    };
    // Node 0 (Z_UP) is the parent of node 1 (Armature), the parent of the mesh node 2.
    let world = matrix(0) * matrix(1);
    let position = json["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
        .as_u64()
        .unwrap() as usize;
    let corner = |key: &str| {
        let a = json["accessors"][position][key].as_array().unwrap();
        glam::Vec3::new(
            a[0].as_f64().unwrap() as f32,
            a[1].as_f64().unwrap() as f32,
            a[2].as_f64().unwrap() as f32,
        )
    };
    let (lo, hi) = (corner("min"), corner("max"));
    let (mut min, mut max) = (glam::Vec3::INFINITY, glam::Vec3::NEG_INFINITY);
    for i in 0..8 {
        let c = glam::Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        );
        let p = world.transform_point3(c);
        min = min.min(p);
        max = max.max(p);
    }
    let v = info(&model, &[]);
    let (got_min, got_max) = bounds(&v);
    // The matrices are rotations by 90° (axis permutations): the box maps onto a box. 1 mm on
    // a 1.5 m figure leaves room for the f32 joint chain.
    const BIND_TOLERANCE: f64 = 1e-3;
    for k in 0..3 {
        assert!(
            (got_min[k] - f64::from(min[k])).abs() < BIND_TOLERANCE
                && (got_max[k] - f64::from(max[k])).abs() < BIND_TOLERANCE,
            "static pose {got_min:?}..{got_max:?}, bind pose {min}..{max}"
        );
    }
    let warnings = v["warnings"].to_string();
    assert!(!warnings.contains("bind pose"), "{warnings}");
    // Posed at 1 s the figure is a different shape (walking, narrower than the T pose).
    let (min1, max1) = bounds(&info(&model, &["--time", "1"]));
    assert!(
        max1[0] - min1[0] < got_max[0] - got_min[0] - 0.3,
        "{min1:?}..{max1:?}"
    );
}

/// `render --views` and `batch` take the pose options too (they share render's load options):
/// the views of a running fox differ from those at rest, and a batch job equals the single
/// render with the same options.
#[test]
fn views_and_batch_jobs_are_posed_too() {
    let Some(samples) = samples("views_and_batch_jobs_are_posed_too") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let fox = samples.join("Fox/glTF/Fox.gltf");
    let pose = ["--animation", "Run", "--time", "0.3"];
    let views = |folder: &str, extra: &[&str]| {
        let out = dir.path().join(folder);
        let mut args = vec!["render", s(&fox), "--views", "orbit:1", "-o", s(&out)];
        args.extend(["--width", "64", "--height", "64", "--spp", "1", "-q"]);
        args.extend(extra);
        run(&args, true);
        out.join("000.png")
    };
    let diff = mean_abs_diff(&views("rest", &[]), &views("running", &pose));
    assert!(
        diff > 0.005,
        "posed views differ from the rest pose: {diff}"
    );

    let manifest = dir.path().join("models");
    std::fs::create_dir(&manifest).unwrap();
    for file in ["Fox.gltf", "Fox.bin", "Texture.png"] {
        std::fs::copy(samples.join("Fox/glTF").join(file), manifest.join(file)).unwrap();
    }
    let batch_out = dir.path().join("batch");
    let mut args = vec!["batch", s(&manifest), "-o", s(&batch_out)];
    args.extend(["--width", "64", "--height", "64", "--spp", "1", "-q"]);
    args.extend(pose);
    run(&args, true);
    let single = dir.path().join("single.png");
    render(&fox, &single, 64, &pose);
    let job_image = batch_out.join("Fox/image.png");
    assert_eq!(
        read_rgba(&job_image).2,
        read_rgba(&single).2,
        "the batch job draws the same pose as render"
    );

    // A JSONL manifest poses each job its own way (one frame each), over the command line's.
    let jobs = dir.path().join("jobs.jsonl");
    let line = |id: &str, animation: Value, time: f32| {
        json!({"id": id, "model": s(&fox), "animation": animation, "time": time}).to_string()
    };
    let lines = [line("walk", json!("Walk"), 0.2), line("run", json!(2), 0.3)];
    std::fs::write(&jobs, lines.join("\n")).unwrap();
    let frames_out = dir.path().join("frames");
    let mut args = vec!["batch", s(&jobs), "-o", s(&frames_out)];
    args.extend(["--width", "64", "--height", "64", "--spp", "1", "-q"]);
    args.extend(["--animation", "Survey"]);
    run(&args, true);
    let walk = dir.path().join("walk.png");
    render(&fox, &walk, 64, &["--animation", "Walk", "--time", "0.2"]);
    assert_eq!(
        read_rgba(&frames_out.join("walk/image.png")).2,
        read_rgba(&walk).2
    );
    assert_eq!(
        read_rgba(&frames_out.join("run/image.png")).2,
        read_rgba(&single).2,
        "animation 2 is Run"
    );
}

/// Channel targets are checked before the `gltf` crate indexes them (gltf-json 1.4 does not
/// validate them): a missing node or an unknown path is one error naming the file.
#[test]
fn channel_targets_outside_the_file_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let model = sliding_square(dir.path());
    let original: Value = serde_json::from_slice(&std::fs::read(&model).unwrap()).unwrap();
    for (field, value, expect) in [
        ("node", json!(99), "targets node 99"),
        ("path", json!("colour"), "target path"),
    ] {
        let mut json = original.clone();
        json["animations"][0]["channels"][0]["target"][field] = value;
        let broken = dir.path().join(format!("broken-{field}.gltf"));
        std::fs::write(&broken, json.to_string()).unwrap();
        let message = stderr(&run(&["info", s(&broken)], false));
        assert!(
            message.contains(&format!("broken-{field}.gltf")) && message.contains(expect),
            "{message}"
        );
        assert!(!message.contains("internal error"), "{message}");
    }
}

/// An animation accessor whose count its buffer view cannot hold is refused before anything
/// is allocated for it, naming the file and the accessor.
#[test]
fn keyframe_accessors_larger_than_their_view_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let model = sliding_square(dir.path());
    let mut json: Value = serde_json::from_slice(&std::fs::read(&model).unwrap()).unwrap();
    let input = json["animations"][0]["samplers"][0]["input"]
        .as_u64()
        .unwrap() as usize;
    json["accessors"][input]["count"] = json!(4_000_000_000u64);
    let broken = dir.path().join("huge-count.gltf");
    std::fs::write(&broken, json.to_string()).unwrap();
    let message = stderr(&run(&["info", s(&broken), "--time", "1"], false));
    assert!(
        message.contains("huge-count.gltf") && message.contains("do not fit bufferView"),
        "{message}"
    );
}

/// `KHR_animation_pointer`: channels that target properties by JSON pointer are sampled at
/// `--time` like node channels and drawn as if the file held the values. A square's node
/// slides (LINEAR, to x = 4 at 2 s), its base colour goes from red to blue (LINEAR), its
/// emissive strength (an extension object the file does not have) steps to 3 at 1 s, a point
/// light's intensity and an orthographic camera's ymag ramp up. `info` at 1.5 s must show
/// each value at its closed form, and the render the frame the camera's ymag gives; the static pose shows the file's values, without warnings;
/// a pointer meshtracer does not animate (an accessor's count), or a keyframe of the wrong
/// size for the property, is left out with a warning naming it, and the rest still animate.
#[test]
fn animation_pointer_channels_animate_nodes_materials_lights_and_cameras() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Buffer::default();
    let (position, indices) = square(&mut b, 2.0);
    let times = b.floats(&[0.0, 2.0], "SCALAR");
    let step_times = b.floats(&[0.0, 1.0], "SCALAR");
    let slide = b.floats(&[0.0, 0.0, 0.0, 4.0, 0.0, 0.0], "VEC3");
    let colours = b.floats(&[1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0], "VEC4");
    let strength = b.floats(&[1.0, 3.0], "SCALAR");
    let intensity = b.floats(&[10.0, 30.0], "SCALAR");
    let ymag = b.floats(&[2.0, 4.0], "SCALAR");
    let sampler = |input, output, interpolation| json!({"input": input, "output": output, "interpolation": interpolation});
    let channel = |sampler: usize, pointer: &str| json!({"sampler": sampler, "target": {"path": "pointer", "extensions": {"KHR_animation_pointer": {"pointer": pointer}}}});
    let mut channels = vec![
        channel(0, "/nodes/0/translation"),
        channel(1, "/materials/0/pbrMetallicRoughness/baseColorFactor"),
        channel(
            2,
            "/materials/0/extensions/KHR_materials_emissive_strength/emissiveStrength",
        ),
        channel(3, "/extensions/KHR_lights_punctual/lights/0/intensity"),
        channel(4, "/cameras/0/orthographic/ymag"),
    ];
    let write = |name: &str, channels: &[Value]| {
        let b = Buffer {
            bin: b.bin.clone(),
            views: b.views.clone(),
            accessors: b.accessors.clone(),
        };
        b.write(
            dir.path(),
            name,
            json!({
                "scene": 0,
                "scenes": [{"nodes": [0, 1, 2]}],
                "extensionsUsed": ["KHR_lights_punctual", "KHR_animation_pointer"],
                "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 10.0}]}},
                "nodes": [
                    {"mesh": 0},
                    {"camera": 0, "translation": [0.0, 0.0, 5.0]},
                    {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [0.0, 3.0, 0.0]}
                ],
                "cameras": [{"type": "orthographic", "orthographic": {"xmag": 2.0, "ymag": 2.0, "znear": 0.1, "zfar": 100.0}}],
                "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.0, 0.0, 1.0]}, "emissiveFactor": [1.0, 1.0, 1.0]}],
                "meshes": [{"primitives": [{"attributes": {"POSITION": position}, "indices": indices, "material": 0}]}],
                "animations": [{"name": "pointers", "samplers": [
                    sampler(times, slide, "LINEAR"),
                    sampler(times, colours, "LINEAR"),
                    sampler(step_times, strength, "STEP"),
                    sampler(times, intensity, "LINEAR"),
                    sampler(times, ymag, "LINEAR")
                ], "channels": channels}]
            }),
        )
    };
    let model = write("pointers.gltf", &channels);
    crate::common::copy_to_corpus(&model);
    let at_rest = info(&model, &[]);
    assert_eq!(at_rest["warnings"], json!([]), "{}", at_rest["warnings"]);
    assert_close(bounds(&at_rest).0, [-2.0, -2.0, 0.0], "static pose");
    assert_eq!(at_rest["animations"][0]["channels"], 5);
    assert_eq!(at_rest["animations"][0]["duration"], 2.0);
    let check = |v: &Value| {
        assert_close(bounds(v).0, [1.0, -2.0, 0.0], "the square at 1.5 s");
        let material = &v["material_list"][0];
        let colour: Vec<f64> = (0..4)
            .map(|k| material["base_color"][k].as_f64().unwrap())
            .collect();
        for (k, expected) in [0.25, 0.0, 0.75, 1.0].into_iter().enumerate() {
            assert!(
                (colour[k] - expected).abs() < 1e-6,
                "base colour at 1.5 s: {colour:?}"
            );
        }
        assert_eq!(material["emissive_strength"], 3.0, "{material}");
        assert_eq!(v["lights"][0]["intensity"], 25.0, "{}", v["lights"][0]);
    };
    let animated = info(&model, &["--animation", "pointers", "--time", "1.5"]);
    assert_eq!(animated["warnings"], json!([]), "{}", animated["warnings"]);
    check(&animated);
    // The camera: at 1.5 s its ymag is 3.5, so a square image frames x in [-3.5, 3.5], 20
    // pixels a unit, and the square (x from 1 to 5) covers the 50 columns right of x = 1.
    let image = dir.path().join("pointers.png");
    run(
        &[
            "render",
            s(&model),
            "-o",
            s(&image),
            "--animation",
            "pointers",
            "--time",
            "1.5",
            "--width",
            "140",
            "--height",
            "140",
            "--spp",
            "1",
            "--quiet",
        ],
        true,
    );
    let (w, _, pixels) = read_rgba(&image);
    let covered = (0..w as usize)
        .filter(|&x| pixels[70 * w as usize + x][3] > 0.5)
        .count();
    assert_eq!(covered, 50, "columns covered in row 70 at ymag 3.5");
    // A pointer at something meshtracer does not animate is named and left out.
    channels.push(channel(4, "/accessors/0/count"));
    let model = write("unsupported.gltf", &channels);
    crate::common::copy_to_corpus(&model);
    let v = info(&model, &["--animation", "pointers", "--time", "1.5"]);
    assert_eq!(
        v["warnings"],
        json!(["animation 0 channel 5: KHR_animation_pointer: meshtracer does not animate '/accessors/0/count'; left out"]),
        "{}",
        v["warnings"]
    );
    check(&v);
    // So is a keyframe of the wrong size for a property the file leaves out (one number for a
    // colour), which had made the rewritten document unreadable and stopped the load.
    channels.pop();
    let sheen = "/materials/0/extensions/KHR_materials_sheen/sheenColorFactor";
    channels.push(channel(4, sheen));
    let model = write("wrong_shape.gltf", &channels);
    crate::common::copy_to_corpus(&model);
    let v = info(&model, &["--animation", "pointers", "--time", "1.5"]);
    assert_eq!(
        v["warnings"],
        json!([format!("animation 0 channel 5: KHR_animation_pointer '{sheen}': 1 number a keyframe, where the property takes 3 numbers; left out")]),
        "{}",
        v["warnings"]
    );
    check(&v);
}

/// `KHR_node_visibility`: a node whose `visible` is false hides its mesh and light and every
/// node below it, but not the camera of a node below it ("visibility affects neither
/// cameras"); a `KHR_animation_pointer` channel (STEP, unsigned bytes, as the extension asks)
/// shows it again from 1 s on. `info`: at rest only the visible square (x from 8 to 12) and no
/// light, with the hidden node's camera; at 1.5 s both squares and the light.
#[test]
fn node_visibility_hides_a_subtree_and_animates() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Buffer::default();
    let (position, indices) = square(&mut b, 2.0);
    let times = b.floats(&[0.0, 1.0], "SCALAR");
    let shown = b.add(
        &[0u8, 1],
        2,
        json!({"componentType": 5121, "type": "SCALAR"}),
    );
    let model = b.write(
        dir.path(),
        "visibility.gltf",
        json!({
            "scene": 0,
            "scenes": [{"nodes": [0, 3]}],
            "extensionsUsed": ["KHR_lights_punctual", "KHR_node_visibility", "KHR_animation_pointer"],
            "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 5.0}]}},
            "nodes": [
                {"children": [1, 2], "extensions": {"KHR_node_visibility": {"visible": false}}},
                {"mesh": 0, "extensions": {"KHR_lights_punctual": {"light": 0}, "KHR_node_visibility": {"visible": true}}},
                {"camera": 0, "translation": [0.0, 0.0, 5.0]},
                {"mesh": 0, "translation": [10.0, 0.0, 0.0]}
            ],
            "cameras": [{"type": "orthographic", "orthographic": {"xmag": 2.0, "ymag": 2.0, "znear": 0.1, "zfar": 100.0}}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": position}, "indices": indices}]}],
            "animations": [{"name": "show",
                "samplers": [{"input": times, "output": shown, "interpolation": "STEP"}],
                "channels": [{"sampler": 0, "target": {"path": "pointer",
                    "extensions": {"KHR_animation_pointer": {"pointer": "/nodes/0/extensions/KHR_node_visibility/visible"}}}}]}]
        }),
    );
    crate::common::copy_to_corpus(&model);
    let at_rest = info(&model, &[]);
    assert_close(bounds(&at_rest).0, [8.0, -2.0, 0.0], "hidden at rest");
    assert_eq!(at_rest["lights"], json!([]), "{}", at_rest["lights"]);
    assert_eq!(at_rest["cameras"].as_array().map(Vec::len), Some(1));
    assert_eq!(at_rest["warnings"], json!([]), "{}", at_rest["warnings"]);
    let early = info(&model, &["--animation", "show", "--time", "0.5"]);
    assert_close(bounds(&early).0, [8.0, -2.0, 0.0], "still hidden at 0.5 s");
    let shown = info(&model, &["--animation", "show", "--time", "1.5"]);
    assert_close(bounds(&shown).0, [-2.0, -2.0, 0.0], "shown at 1.5 s");
    assert_eq!(shown["lights"].as_array().map(Vec::len), Some(1));
    assert_eq!(shown["warnings"], json!([]), "{}", shown["warnings"]);
}

/// The sliding square of [`sliding_square`] without its camera (node 1 keeps its place, empty),
/// so that renders frame it with the automatic camera.
fn sliding_square_without_camera(dir: &Path) -> PathBuf {
    let model = sliding_square(dir);
    let mut json: Value = serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    json["nodes"][1] = json!({"translation": [0.0, 0.0, 5.0]});
    json.as_object_mut().unwrap().remove("cameras");
    let path = dir.join("sliding-no-camera.gltf");
    std::fs::write(&path, serde_json::to_string(&json).unwrap()).unwrap();
    path
}

/// The options of the sliding square's frames and single renders in the tests below.
const SLIDE_OPTIONS: [&str; 8] = [
    "--animation",
    "slide",
    "--width",
    "24",
    "--height",
    "24",
    "--spp",
    "1",
];

/// Asserts that frame k in `frames` (`000.png`, ...) is, byte for byte, the single render of
/// `model` with [`SLIDE_OPTIONS`] at `times[k]` seconds.
fn assert_frames_are_single_renders(model: &Path, frames: &Path, times: &[&str]) {
    let dir = frames.parent().expect("the frames' folder is in a folder");
    for (k, time) in times.iter().enumerate() {
        let single = dir.join(format!("single-{k}.png"));
        let mut args = vec!["render", s(model), "-o", s(&single), "-q", "--time", time];
        args.extend(SLIDE_OPTIONS);
        run(&args, true);
        let frame = frames.join(format!("{k:03}.png"));
        assert_eq!(
            std::fs::read(&frame).unwrap(),
            std::fs::read(&single).unwrap(),
            "frame {k} against the render at {time} s"
        );
    }
}

/// Frame k of `--frames N` with the file's (animated) camera is the plain render of the pose
/// at k/N of the animation, byte for byte; the GIF holds the N frames, each lasting the
/// animation's duration over N.
#[test]
fn frames_are_the_plain_renders_of_their_poses() {
    let dir = tempfile::tempdir().unwrap();
    let model = sliding_square(dir.path());
    let (frames, gif) = (dir.path().join("frames"), dir.path().join("slide.gif"));
    let mut args = vec!["render", s(&model), "-o", s(&frames), "-q", "--frames", "4"];
    args.extend(["--gif", s(&gif)]);
    args.extend(SLIDE_OPTIONS);
    run(&args, true);
    let names: Vec<String> = std::fs::read_dir(&frames)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    assert_eq!(names, ["000.png", "001.png", "002.png", "003.png"]);
    // "slide" lasts 2 s: the frames are at 0, 0.5, 1 and 1.5 s.
    assert_frames_are_single_renders(&model, &frames, &["0", "0.5", "1", "1.5"]);
    let first = std::fs::read(frames.join("000.png")).unwrap();
    assert_ne!(first, std::fs::read(frames.join("002.png")).unwrap());
    use image::AnimationDecoder;
    let bytes = std::io::Cursor::new(std::fs::read(&gif).unwrap());
    let decoded = image::codecs::gif::GifDecoder::new(bytes).unwrap();
    let gif_frames = decoded.into_frames().collect_frames().unwrap();
    assert_eq!(gif_frames.len(), 4);
    for frame in &gif_frames {
        // Real time: 2 s over 4 frames.
        assert_eq!(frame.delay().numer_denom_ms(), (500, 1));
    }
}

/// The sliding square of [`sliding_square`] with a 4x4 orange texture (`orange.png`) as its
/// base colour and emission (the animated point light stays in the square's plane, lighting
/// nothing), as `textured.gltf`.
fn textured_sliding_square(dir: &Path) -> PathBuf {
    let model = sliding_square(dir);
    let mut json: Value = serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    image::RgbImage::from_pixel(4, 4, image::Rgb([220, 60, 20]))
        .save(dir.join("orange.png"))
        .unwrap();
    json["images"] = json!([{"uri": "orange.png"}]);
    json["textures"] = json!([{"source": 0}]);
    json["materials"] = json!([{
        "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}},
        "emissiveTexture": {"index": 0},
        "emissiveFactor": [1.0, 1.0, 1.0]
    }]);
    json["meshes"][0]["primitives"][0]["material"] = json!(0);
    let path = dir.join("textured.gltf");
    std::fs::write(&path, serde_json::to_string(&json).unwrap()).unwrap();
    path
}

/// The frames of a textured model decode its texture once: later frames keep the first's
/// images (their summary lines say so), and each is still the plain render of its pose, byte
/// for byte. (A texture changed on disk is decoded again: the library's unit tests.)
#[test]
fn frames_keep_the_textures_they_share_and_stay_the_plain_renders() {
    let dir = tempfile::tempdir().unwrap();
    let model = textured_sliding_square(dir.path());
    let frames = dir.path().join("frames");
    let mut args = vec!["render", s(&model), "-o", s(&frames), "--frames", "3"];
    args.extend(SLIDE_OPTIONS);
    let out = stderr(&run(&args, true));
    let lines: Vec<&str> = out.lines().filter(|l| l.contains("of textures")).collect();
    assert_eq!(lines.len(), 3, "{out}");
    assert!(lines[0].contains("KB of textures in "), "{}", lines[0]);
    for line in &lines[1..] {
        assert!(
            line.contains("KB of textures kept from the last frame"),
            "{line}"
        );
    }
    // "slide" lasts 2 s: the frames are at 0, 2/3 and 4/3 s (as f32, printed exactly).
    let times = [0.0f32, 2.0 / 3.0, 4.0 / 3.0].map(|t| t.to_string());
    let times: Vec<&str> = times.iter().map(String::as_str).collect();
    assert_frames_are_single_renders(&model, &frames, &times);
    // The texture is drawn: the square's centre glows orange.
    let (width, _, pixels) = read_rgba(&frames.join("000.png"));
    let [r, g, b, _] = pixels[(12 * width + 12) as usize];
    assert!(r > 2.0 * g && g > b, "{r} {g} {b}");
}

/// A batch's consecutive jobs of one textured model (an animation's frames as jobs) keep its
/// decoded texture from job to job, and a job of another model between them does not disturb
/// that: every job's image is the single render of its pose, byte for byte.
#[test]
fn batch_jobs_of_one_textured_model_are_its_single_renders() {
    let dir = tempfile::tempdir().unwrap();
    let model = textured_sliding_square(dir.path());
    let other = sliding_square(dir.path());
    let job = |id: &str, model: &Path, time: &str| {
        json!({"id": id, "model": model, "animation": "slide", "time": time.parse::<f32>().unwrap()})
            .to_string()
    };
    let jobs = [
        job("t0", &model, "0"),
        job("t1", &model, "0.5"),
        job("plain", &other, "0.5"),
        job("t2", &model, "1"),
    ];
    let manifest = dir.path().join("jobs.jsonl");
    std::fs::write(&manifest, jobs.join("\n")).unwrap();
    let out = dir.path().join("out");
    let size = ["--width", "24", "--height", "24", "--spp", "1"];
    let mut args = vec!["batch", s(&manifest), "-o", s(&out), "-q"];
    args.extend(size);
    run(&args, true);
    for (id, model, time) in [
        ("t0", &model, "0"),
        ("t1", &model, "0.5"),
        ("plain", &other, "0.5"),
        ("t2", &model, "1"),
    ] {
        let single = dir.path().join(format!("single-{id}.png"));
        let mut args = vec!["render", s(model), "-o", s(&single), "-q"];
        args.extend(["--animation", "slide", "--time", time]);
        args.extend(size);
        run(&args, true);
        assert_eq!(
            std::fs::read(out.join(id).join("image.png")).unwrap(),
            std::fs::read(&single).unwrap(),
            "job {id}"
        );
    }
}

/// With no camera in the file, the frames share one automatic camera that frames every pose:
/// "ease" moves the square from x = 0 to x = 6.75 (at 1.5 s, the last of four frames); the
/// square never touches the image's border, and moves right from frame to frame (a camera
/// fitted to each pose would keep it centred).
#[test]
fn the_automatic_camera_frames_every_pose_of_the_frames() {
    let dir = tempfile::tempdir().unwrap();
    let model = sliding_square_without_camera(dir.path());
    let frames = dir.path().join("frames");
    let mut args = vec!["render", s(&model), "-o", s(&frames), "-q", "--frames", "4"];
    args.extend(["--animation", "ease", "--width", "64", "--height", "32"]);
    args.extend(["--spp", "1", "--integrator", "direct"]);
    run(&args, true);
    let mut centres = Vec::new();
    for k in 0..4 {
        let (w, h, pixels) = read_rgba(&frames.join(format!("{k:03}.png")));
        let covered = |x: u32, y: u32| pixels[(y * w + x) as usize][3] > 0.5;
        let border = (0..w).flat_map(|x| [(x, 0), (x, h - 1)]);
        let border = border.chain((0..h).flat_map(|y| [(0, y), (w - 1, y)]));
        assert!(
            border.into_iter().all(|(x, y)| !covered(x, y)),
            "frame {k} touches the border"
        );
        let xs: Vec<u32> = (0..w).filter(|&x| (0..h).any(|y| covered(x, y))).collect();
        assert!(!xs.is_empty(), "frame {k} shows the square");
        centres.push(xs.iter().sum::<u32>() as f64 / xs.len() as f64);
    }
    assert!(
        centres.windows(2).all(|c| c[1] > c[0] + 3.0),
        "the square moves right: {centres:?}"
    );
    // The plain render of the last pose frames that pose alone: it differs.
    let single = dir.path().join("single.png");
    let mut args = vec!["render", s(&model), "-o", s(&single), "-q", "--time", "1.5"];
    args.extend(["--animation", "ease", "--width", "64", "--height", "32"]);
    args.extend(["--spp", "1", "--integrator", "direct"]);
    run(&args, true);
    assert_ne!(
        std::fs::read(&single).unwrap(),
        std::fs::read(frames.join("003.png")).unwrap()
    );
}

/// What --frames cannot do is refused with one message, before any frame is written: a file
/// without animations, an animation that does not last, an -o that names an image, options it
/// conflicts with, and a batch.
#[test]
fn frames_that_cannot_be_made_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    // A square whose one animation has a single keyframe at 0 s, and one with none.
    let mut b = Buffer::default();
    let (position, indices) = square(&mut b, 1.0);
    let times = b.floats(&[0.0], "SCALAR");
    let still = b.floats(&[0.0, 1.0, 0.0], "VEC3");
    let mut json = json!({
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": position}, "indices": indices}]}],
        "animations": [{"name": "still", "samplers": [{"input": times, "output": still}],
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}}]}]
    });
    let still_model = {
        let b2 = Buffer {
            bin: b.bin.clone(),
            views: b.views.clone(),
            accessors: b.accessors.clone(),
        };
        b2.write(dir.path(), "still.gltf", json.clone())
    };
    json.as_object_mut().unwrap().remove("animations");
    let plain_model = b.write(dir.path(), "plain.gltf", json);
    let out = dir.path().join("frames");
    let refused = |args: &[&str], expected: &str| {
        let mut full = vec!["render", "-q"];
        full.extend(args);
        let message = stderr(&run(&full, false));
        assert!(message.contains(expected), "{args:?}: {message}");
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    };
    refused(
        &[s(&plain_model), "-o", s(&out), "--frames", "4"],
        "the file has no animations",
    );
    refused(
        &[s(&still_model), "-o", s(&out), "--frames", "4"],
        "animation 0 'still' lasts 0 s",
    );
    let sliding = sliding_square(dir.path());
    let image = dir.path().join("frames.png");
    refused(
        &[s(&sliding), "-o", s(&image), "--frames", "4"],
        "with --frames, -o names the folder",
    );
    assert!(!image.exists());
    refused(
        &[
            s(&sliding),
            "-o",
            s(&out),
            "--frames",
            "4",
            "--animation",
            "gallop",
        ],
        "no animation 'gallop'",
    );
    refused(
        &[s(&sliding), "-o", s(&out), "--frames", "4", "--time", "1"],
        "cannot be used with",
    );
    refused(&[s(&sliding), "-o", s(&out), "--frames", "0"], "--frames");
    refused(
        &[
            s(&sliding),
            "-o",
            s(&out),
            "--frames",
            "2",
            "--gif",
            "x.png",
        ],
        "must end in .gif",
    );
    let message = stderr(&run(
        &["batch", s(dir.path()), "-o", s(&out), "--frames", "4", "-q"],
        false,
    ));
    assert!(message.contains("made by render"), "{message}");
}
