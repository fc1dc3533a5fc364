//! `EXT_mesh_gpu_instancing`: a node's mesh drawn once per instance at the node's transform
//! times the instance's T·R·S, checked through `info --json` (bounds, triangle and instance
//! counts) and a render; accessors the extension does not allow are refused naming the node.

use crate::common::{add_float_accessor, bounds, run, s, stderr, unit_quad, write_gltf};
use serde_json::{json, Value};

/// Bounds are f32 through a matrix product: a few ulps of values near 1.
const TOLERANCE: f64 = 1e-5;

/// The unit quad (corners ±0.5 in z = 0) at node 0, translated by (0, 0, -1), with the
/// extension's `attributes` built by `attributes` from the JSON and binary.
fn instanced(attributes: impl FnOnce(&mut Value, &mut Vec<u8>) -> Value) -> (Value, Vec<u8>) {
    let (mut json, mut bin) = unit_quad();
    let attributes = attributes(&mut json, &mut bin);
    json["nodes"][0] = json!({"mesh": 0, "translation": [0.0, 0.0, -1.0],
        "extensions": {"EXT_mesh_gpu_instancing": {"attributes": attributes}}});
    json["extensionsUsed"] = json!(["EXT_mesh_gpu_instancing"]);
    json["extensionsRequired"] = json!(["EXT_mesh_gpu_instancing"]);
    (json, bin)
}

fn info_of(json: Value, bin: &[u8], ok: bool) -> (Value, String) {
    let dir = tempfile::tempdir().unwrap();
    let model = write_gltf(dir.path(), "instanced.gltf", json, bin);
    crate::common::copy_to_corpus(&model);
    let out = run(&["info", s(&model), "--json"], ok);
    let info = if ok {
        serde_json::from_slice(&out.stdout).unwrap()
    } else {
        Value::Null
    };
    (info, stderr(&out))
}

/// Three instances: (-2, 0, 0) as it is; (2, 0, 0) turned 45° about z (its corners reach
/// ±√2/2); (0, 3, 0) scaled by 2. Under the node's (0, 0, -1) the bounds are exactly
/// x in [-2.5, 2 + √2/2], y in [-√2/2, 4], z = -1, with 6 triangles in 3 instances; and the
/// file, which requires the extension, renders.
#[test]
fn gpu_instances_are_placed_by_their_translation_rotation_and_scale() {
    let (sin, cos) = (22.5f32.to_radians().sin(), 22.5f32.to_radians().cos());
    let (json, bin) = instanced(|json, bin| {
        let t = add_float_accessor(
            json,
            bin,
            &[-2.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 3.0, 0.0],
            json!({"count": 3, "type": "VEC3"}),
        );
        let r = add_float_accessor(
            json,
            bin,
            &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, sin, cos, 0.0, 0.0, 0.0, 1.0],
            json!({"count": 3, "type": "VEC4"}),
        );
        let sc = add_float_accessor(
            json,
            bin,
            &[1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 2.0, 2.0, 2.0],
            json!({"count": 3, "type": "VEC3"}),
        );
        json!({"TRANSLATION": t, "ROTATION": r, "SCALE": sc})
    });
    let (info, _) = info_of(json.clone(), &bin, true);
    assert_eq!(info["traced_triangles"], 6, "{info}");
    assert_eq!(info["instances"], 3, "{info}");
    let half = std::f64::consts::FRAC_1_SQRT_2;
    let (min, max) = bounds(&info);
    let expected = [
        (min, [-2.5, -half, -1.0], "min"),
        (max, [2.0 + half, 4.0, -1.0], "max"),
    ];
    for (got, want, key) in expected {
        for k in 0..3 {
            assert!(
                (got[k] - want[k]).abs() < TOLERANCE,
                "{key}: {got:?} against {want:?}"
            );
        }
    }
    let status = info["extensions"]
        .as_array()
        .and_then(|list| list.iter().find(|e| e["name"] == "EXT_mesh_gpu_instancing"))
        .map(|e| e["status"].clone());
    assert_eq!(status, Some(json!("supported")), "{info}");
    let dir = tempfile::tempdir().unwrap();
    let model = write_gltf(dir.path(), "instanced.gltf", json, &bin);
    let out = dir.path().join("out.png");
    run(
        &[
            "render",
            s(&model),
            "-o",
            s(&out),
            "-q",
            "--width",
            "64",
            "--height",
            "48",
        ],
        true,
    );
}

/// TRANSLATION alone places copies; a ROTATION of normalized shorts (which the extension
/// allows) is read as its quaternion: 45° about z takes the quad's corners to ±√2/2, which the
/// node's scale (2, 1, 1), applied after the instance's transform (world = node · instance),
/// stretches to x in ±√2, y in ±√2/2 (unturned it would be ±1 and ±0.5).
#[test]
fn translation_alone_and_quantized_rotation_are_read() {
    let (json, bin) = instanced(|json, bin| {
        let t = add_float_accessor(
            json,
            bin,
            &[0.0, 0.0, 0.0, 5.0, 0.0, 0.0],
            json!({"count": 2, "type": "VEC3"}),
        );
        json!({"TRANSLATION": t})
    });
    let (info, _) = info_of(json, &bin, true);
    assert_eq!(info["traced_triangles"], 4, "{info}");
    assert!((bounds(&info).1[0] - 5.5).abs() < TOLERANCE, "{info}");
    let (mut json, bin) = instanced(|json, bin| {
        // (0, 0, sin 22.5°, cos 22.5°) as normalized i16 (x 32767).
        let q: Vec<u8> = [0i16, 0, 12540, 30273]
            .iter()
            .flat_map(|c| c.to_le_bytes())
            .collect();
        let view = json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": q.len()});
        bin.extend(q);
        json["bufferViews"].as_array_mut().unwrap().push(view);
        let views = json["bufferViews"].as_array().unwrap().len();
        json["accessors"]
            .as_array_mut()
            .unwrap()
            .push(json!({"bufferView": views - 1,
            "componentType": 5122, "normalized": true, "count": 1, "type": "VEC4"}));
        let accessors = json["accessors"].as_array().unwrap().len();
        json!({"ROTATION": accessors - 1})
    });
    json["nodes"][0]["scale"] = json!([2.0, 1.0, 1.0]);
    let (info, _) = info_of(json, &bin, true);
    let (_, max) = bounds(&info);
    let half = std::f64::consts::FRAC_1_SQRT_2;
    // The quantised quaternion is unit to about 1e-4.
    assert!(
        (max[0] - 2.0 * half).abs() < 1e-3 && (max[1] - half).abs() < 1e-3,
        "{max:?}"
    );
}

/// What the extension does not allow is refused with one message naming the node: counts
/// that disagree, an accessor that does not exist, an integer TRANSLATION without
/// `KHR_mesh_quantization`, no attribute at all.
#[test]
fn bad_instancing_attributes_are_refused_naming_the_node() {
    type Attributes = Box<dyn Fn(&mut Value, &mut Vec<u8>) -> Value>;
    let cases: Vec<(&str, Attributes)> = vec![
        (
            "SCALE has 1 instances where TRANSLATION has 2",
            Box::new(|json, bin| {
                let t =
                    add_float_accessor(json, bin, &[0.0; 6], json!({"count": 2, "type": "VEC3"}));
                let sc =
                    add_float_accessor(json, bin, &[1.0; 3], json!({"count": 1, "type": "VEC3"}));
                json!({"TRANSLATION": t, "SCALE": sc})
            }),
        ),
        (
            "TRANSLATION names accessor 99, which does not exist",
            Box::new(|_, _| json!({"TRANSLATION": 99})),
        ),
        (
            "which the extension does not allow",
            // The quad's index accessor: SCALAR unsigned shorts.
            Box::new(|_, _| json!({"TRANSLATION": 1})),
        ),
        (
            "names none of TRANSLATION, ROTATION and SCALE",
            Box::new(|_, _| json!({"_ID": 0})),
        ),
    ];
    for (message, attributes) in cases {
        let (json, bin) = instanced(|json, bin| attributes(json, bin));
        let (_, err) = info_of(json, &bin, false);
        assert!(
            err.contains("node 0: EXT_mesh_gpu_instancing: ") && err.contains(message),
            "{message}: {err}"
        );
        assert_eq!(err.trim().lines().count(), 1, "{err}");
    }
}
