//! Invalid glTF whose fault changes the picture: each test writes a small file with one
//! fault the Khronos validator reports as an error, and checks the warning that names the node,
//! mesh, accessor or material, and the corrected picture where there is one (bounds from
//! `info --json`). Also which messages `--quiet` and `--no-warnings` keep.

use crate::common::{
    add_float_accessor, bounds, png_data_uri, run, s, stderr, unit_quad, write_gltf,
};
use serde_json::{json, Value};
use std::path::Path;

/// Bounds are f32 through a 4x4 matrix product: a few ulps of a unit-sized value.
const BOUNDS_TOLERANCE: f64 = 1e-5;

/// `info --json` of `json` with `bin` embedded, written into `dir`.
fn info(dir: &Path, json: Value, bin: &[u8]) -> Value {
    let model = write_gltf(dir, "model.gltf", json, bin);
    crate::common::copy_to_corpus(&model);
    let out = run(&["info", s(&model), "--json"], true);
    serde_json::from_slice(&out.stdout).unwrap()
}

fn assert_close(got: [f64; 3], expected: [f64; 3], what: &str) {
    for k in 0..3 {
        assert!(
            (got[k] - expected[k]).abs() < BOUNDS_TOLERANCE,
            "{what}: {got:?} vs {expected:?}"
        );
    }
}

/// Adds `node` to the document and to its first scene's roots.
fn add_root_node(json: &mut Value, node: Value) {
    let index = json["nodes"].as_array().unwrap().len();
    json["nodes"].as_array_mut().unwrap().push(node);
    json["scenes"][0]["nodes"]
        .as_array_mut()
        .unwrap()
        .push(json!(index));
}

/// The warnings of an `info --json`.
fn warnings(info: &Value) -> Vec<String> {
    info["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap().to_string())
        .collect()
}

/// [1, 1, 1, 1] is a rotation of 120° about (1, 1, 1) scaled by 4 if taken as it is; normalised,
/// it maps x to y and y to z, so the unit quad keeps its size and lies in the x = 0 plane.
#[test]
fn a_non_unit_rotation_is_normalised_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = unit_quad();
    json["nodes"][0]["rotation"] = json!([1.0, 1.0, 1.0, 1.0]);
    json["nodes"][0]["name"] = json!("tilted");
    let info = info(dir.path(), json, &bin);
    let (min, max) = bounds(&info);
    assert_close(min, [0.0, -0.5, -0.5], "min");
    assert_close(max, [0.0, 0.5, 0.5], "max");
    assert_eq!(
        warnings(&info),
        ["node 0 ('tilted'): rotation [1.0, 1.0, 1.0, 1.0] is not a unit quaternion (length 2); normalised to [0.500000, 0.500000, 0.500000, 0.500000]"]
    );
}

/// A node with two parents is drawn once, under the parent that reaches it first.
#[test]
fn a_node_with_two_parents_is_drawn_once() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = unit_quad();
    json["nodes"] = json!([
        {"children": [2]},
        {"children": [2], "translation": [5.0, 0.0, 0.0]},
        {"mesh": 0}
    ]);
    json["scenes"] = json!([{"nodes": [0, 1]}]);
    let info = info(dir.path(), json, &bin);
    assert_eq!(info["instances"], 1);
    assert_eq!(info["triangles"], 2);
    let (min, max) = bounds(&info);
    assert_close(min, [-0.5, -0.5, 0.0], "min");
    assert_close(max, [0.5, 0.5, 0.0], "max");
    assert_eq!(
        warnings(&info),
        ["node 2: is a child of node 0 and also a child of node 1 (glTF allows one parent); drawn once, as a child of node 0"]
    );
}

/// A scene root that is also another root's child is drawn once, as the child.
#[test]
fn a_root_that_is_also_a_child_is_drawn_once() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = unit_quad();
    json["nodes"] = json!([{"children": [1], "translation": [3.0, 0.0, 0.0]}, {"mesh": 0}]);
    json["scenes"] = json!([{"nodes": [0, 1]}]);
    let info = info(dir.path(), json, &bin);
    assert_eq!(info["instances"], 1);
    let (min, max) = bounds(&info);
    assert_close(min, [2.5, -0.5, 0.0], "min");
    assert_close(max, [3.5, 0.5, 0.0], "max");
    assert_eq!(
        warnings(&info),
        ["node 1: is a child of node 0 and also a root of scene 0 (glTF allows one parent); drawn once, as a child of node 0"]
    );
}

/// Forty levels of nodes each listing its one child twice expanded to 2^40 visits; each node
/// is now drawn once, with a warning for each repeated child.
#[test]
fn a_child_listed_twice_at_every_level_is_drawn_once() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = unit_quad();
    let mut nodes: Vec<Value> = (0..40)
        .map(|i| json!({"children": [i + 1, i + 1]}))
        .collect();
    nodes.push(json!({"mesh": 0}));
    json["nodes"] = json!(nodes);
    json["scenes"] = json!([{"nodes": [0]}]);
    let info = info(dir.path(), json, &bin);
    assert_eq!(info["instances"], 1);
    let warnings = warnings(&info);
    assert_eq!(warnings.len(), 40, "{warnings:?}");
    assert_eq!(
        warnings[0],
        "node 40: is listed twice among the children of node 39; drawn once"
    );
}

/// A node with a matrix and TRS is placed by its matrix, as the `gltf` crate reads it.
#[test]
fn a_node_with_matrix_and_trs_uses_the_matrix_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = unit_quad();
    json["nodes"][0]["matrix"] =
        json!([1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 2.0, 0.0, 0.0, 1.0]);
    json["nodes"][0]["translation"] = json!([9.0, 0.0, 0.0]);
    let info = info(dir.path(), json, &bin);
    let (min, max) = bounds(&info);
    assert_close(min, [1.5, -0.5, 0.0], "min");
    assert_close(max, [2.5, 0.5, 0.0], "max");
    assert_eq!(
        warnings(&info),
        ["node 0: has both matrix and translation (glTF allows one or the other); the matrix is used"]
    );
}

/// Keyframe times that start below 0 or repeat are reported per channel.
#[test]
fn negative_and_repeated_keyframe_times_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, mut bin) = unit_quad();
    let mut add =
        |floats: &[f32], accessor: Value| add_float_accessor(&mut json, &mut bin, floats, accessor);
    let negative = add(
        &[-1.0, 0.0],
        json!({"count": 2, "type": "SCALAR", "min": [-1.0], "max": [0.0]}),
    );
    let repeated = add(
        &[0.0, 1.0, 1.0],
        json!({"count": 3, "type": "SCALAR", "min": [0.0], "max": [1.0]}),
    );
    let two = add(&[0.0; 6], json!({"count": 2, "type": "VEC3"}));
    let three = add(&[0.0; 9], json!({"count": 3, "type": "VEC3"}));
    let target = json!({"node": 0, "path": "translation"});
    json["animations"] = json!([{
        "samplers": [{"input": negative, "output": two}, {"input": repeated, "output": three}],
        "channels": [{"sampler": 0, "target": target}, {"sampler": 1, "target": target}]
    }]);
    let info = info(dir.path(), json, &bin);
    assert_eq!(
        warnings(&info),
        [
            "animation 0 channel 0: keyframe time 0 is negative (-1 s); glTF times start at 0",
            "animation 0 channel 1: keyframe times 1 and 2 are equal (1 s); glTF times strictly increase"
        ]
    );
}

/// A material whose texture reads TEXCOORD_1 on a primitive that has only TEXCOORD_0.
#[test]
fn a_material_sampling_a_missing_texcoord_set_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = unit_quad();
    let white = image::RgbaImage::from_pixel(1, 1, image::Rgba([255, 255, 255, 255]));
    json["images"] = json!([{"uri": png_data_uri(&white)}]);
    json["textures"] = json!([{"source": 0}]);
    json["materials"] = json!([{"name": "Paint",
        "pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": 1}}}]);
    json["meshes"][0]["primitives"][0]["material"] = json!(0);
    json["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(2);
    let info = info(dir.path(), json, &bin);
    assert_eq!(
        warnings(&info),
        ["mesh 0 primitive 0: material 0 ('Paint') samples TEXCOORD_1, which the primitive does not have"]
    );
}

/// Two mesh weights for one morph target: the extra one is ignored, with a warning naming the
/// node and mesh. (The target's deltas are an accessor without a bufferView: zeros.)
#[test]
fn mesh_weights_that_disagree_with_the_targets_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = unit_quad();
    json["accessors"]
        .as_array_mut()
        .unwrap()
        .push(json!({"componentType": 5126, "count": 4, "type": "VEC3"}));
    json["meshes"][0]["primitives"][0]["targets"] = json!([{"POSITION": 3}]);
    json["meshes"][0]["weights"] = json!([0.5, 0.5]);
    let info = info(dir.path(), json, &bin);
    assert_eq!(
        warnings(&info),
        ["node 0 (mesh 0): 2 morph weights for 1 morph targets; missing ones are 0, extra ones ignored"]
    );
}

/// Extension values outside their ranges are corrected, each with a warning naming the
/// material.
#[test]
fn out_of_range_material_extension_values_are_corrected() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = unit_quad();
    json["extensionsUsed"] = json!([
        "KHR_materials_ior",
        "KHR_materials_specular",
        "KHR_materials_emissive_strength",
        "KHR_materials_dispersion"
    ]);
    json["materials"] = json!([{"name": "Odd", "emissiveFactor": [1.0, 1.0, 1.0], "extensions": {
        "KHR_materials_ior": {"ior": 0.5},
        "KHR_materials_dispersion": {"dispersion": -2.0},
        "KHR_materials_specular": {"specularFactor": 2.0, "specularColorFactor": [-1.0, 0.5, 0.5]},
        "KHR_materials_emissive_strength": {"emissiveStrength": -3.0}
    }}]);
    json["meshes"][0]["primitives"][0]["material"] = json!(0);
    let info = info(dir.path(), json, &bin);
    assert_eq!(
        warnings(&info),
        [
            "material 0 ('Odd'): KHR_materials_ior ior 0.5 is not at least 1; the default 1.5 is used",
            "material 0 ('Odd'): KHR_materials_specular specularColorFactor [-1.0, 0.5, 0.5] is negative; clamped to 0",
            "material 0 ('Odd'): KHR_materials_emissive_strength emissiveStrength -3 is negative; 0 is used",
            "material 0 ('Odd'): KHR_materials_dispersion dispersion -2 is negative; 0 (none) is used",
            "material 0 ('Odd'): KHR_materials_specular specularFactor 2 is outside [0, 1]; clamped",
            "extension KHR_materials_dispersion is approximated: each colour channel refracted by its own index into and out of volumes (path tracer); no dispersion in the direct renderer"
        ]
    );
    let material = &info["material_list"][0];
    assert_eq!(material["dispersion"], 0.0, "{material}");
    assert_eq!(material["ior"], 1.5, "{material}");
    assert_eq!(material["emissive_strength"], 0.0, "{material}");
    assert_eq!(material["specular_layer"]["factor"], 1.0, "{material}");
    assert_eq!(
        material["specular_layer"]["color"],
        json!([0.0, 0.5, 0.5]),
        "{material}"
    );
}

/// The core material's factors outside [0, 1] (glTF 2.0 §5.22) are clamped, each with a
/// warning naming the material: a base colour of 50 would reflect fifty times the light that
/// arrives (the path tracer's noise ran to ±3.6e9 on the bundled box with one), a negative
/// emissive factor would take light away.
#[test]
fn out_of_range_core_material_factors_are_clamped() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = unit_quad();
    json["materials"] = json!([{"name": "Hot", "emissiveFactor": [2.0, -1.0, 0.5],
        "pbrMetallicRoughness": {"baseColorFactor": [50.0, 1.0, -1.0, 1.0],
            "metallicFactor": -3.0, "roughnessFactor": 7.0}}]);
    json["meshes"][0]["primitives"][0]["material"] = json!(0);
    let info = info(dir.path(), json, &bin);
    assert_eq!(
        warnings(&info),
        [
            "material 0 ('Hot'): baseColorFactor [50.0, 1.0, -1.0, 1.0] is outside [0, 1]; clamped",
            "material 0 ('Hot'): metallicFactor -3 is outside [0, 1]; clamped",
            "material 0 ('Hot'): roughnessFactor 7 is outside [0, 1]; clamped",
            "material 0 ('Hot'): emissiveFactor [2.0, -1.0, 0.5] is outside [0, 1]; clamped",
        ]
    );
    let material = &info["material_list"][0];
    assert_eq!(
        material["base_color"],
        json!([1.0, 1.0, 0.0, 1.0]),
        "{material}"
    );
    assert_eq!(material["metallic"], 0.0, "{material}");
    assert_eq!(material["roughness"], 1.0, "{material}");
    assert_eq!(material["emissive"], json!([1.0, 0.0, 0.5]), "{material}");
}

/// `KHR_materials_pbrSpecularGlossiness`'s factors are on [0, 1] too: where the extension is
/// present its factors are the ones drawn, so they are checked and clamped (the core factors
/// beside it are a fallback that is not drawn, and are not reported).
#[test]
fn out_of_range_specular_glossiness_factors_are_clamped() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = unit_quad();
    json["extensionsUsed"] = json!(["KHR_materials_pbrSpecularGlossiness"]);
    json["materials"] = json!([{"name": "Shiny",
        "pbrMetallicRoughness": {"baseColorFactor": [50.0, 1.0, 1.0, 1.0]},
        "extensions": {"KHR_materials_pbrSpecularGlossiness": {
            "diffuseFactor": [2.0, 0.5, 0.5, 1.0], "specularFactor": [1.5, -0.5, 0.5],
            "glossinessFactor": 3.0}}}]);
    json["meshes"][0]["primitives"][0]["material"] = json!(0);
    let info = info(dir.path(), json, &bin);
    let prefix = "material 0 ('Shiny'): KHR_materials_pbrSpecularGlossiness";
    assert_eq!(
        warnings(&info),
        [
            format!("{prefix} diffuseFactor [2.0, 0.5, 0.5, 1.0] is outside [0, 1]; clamped"),
            format!("{prefix} specularFactor [1.5, -0.5, 0.5] is outside [0, 1]; clamped"),
            format!("{prefix} glossinessFactor 3 is outside [0, 1]; clamped"),
        ]
    );
    let material = &info["material_list"][0];
    assert_eq!(
        material["base_color"],
        json!([1.0, 0.5, 0.5, 1.0]),
        "{material}"
    );
    let sg = &material["specular_glossiness"];
    assert_eq!(sg["specular"], json!([1.0, 0.0, 0.5]), "{material}");
    assert_eq!(sg["glossiness"], 1.0, "{material}");
    assert_eq!(material["roughness"], 0.0, "{material}");
    assert_eq!(material["metallic"], 0.0, "{material}");
}

/// KHR_lights_punctual's ranges: a colour outside [0, 1] is clamped (a negative one took light
/// away: the bundled box went from a mean of 86 to 11 of 255 with one channel at -1) and spot
/// cones outside 0 <= inner < outer <= π/2 are corrected, one warning for each light however
/// many nodes place it.
#[test]
fn out_of_range_lights_are_corrected() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = unit_quad();
    json["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    json["extensions"] = json!({"KHR_lights_punctual": {"lights": [
        {"type": "point", "name": "dark", "color": [-1.0, 0.5, 2.0], "intensity": 3.0},
        {"type": "spot", "spot": {"innerConeAngle": 2.0, "outerConeAngle": -1.0}},
        {"type": "spot", "spot": {"innerConeAngle": 0.5, "outerConeAngle": 0.25}},
        {"type": "spot", "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.3}}
    ]}});
    let lit = |light: usize, z: f32| {
        json!({"translation": [0.0, 0.0, z],
        "extensions": {"KHR_lights_punctual": {"light": light}}})
    };
    for (light, z) in [(0, 1.0), (0, 2.0), (1, 1.0), (2, 1.0), (3, 1.0)] {
        add_root_node(&mut json, lit(light, z));
    }
    let info = info(dir.path(), json, &bin);
    assert_eq!(
        warnings(&info),
        [
            "KHR_lights_punctual light 0 ('dark'): color [-1.0, 0.5, 2.0] is outside [0, 1]; clamped",
            "KHR_lights_punctual light 1: spot cones 2..-1 rad are not 0 <= inner < outer <= π/2; corrected",
            "KHR_lights_punctual light 2: spot cones 0.5..0.25 rad are not 0 <= inner < outer <= π/2; corrected",
        ]
    );
    let lights = info["lights"].as_array().unwrap();
    assert_eq!(lights.len(), 5);
    assert_eq!(lights[0]["color"], json!([0.0, 0.5, 1.0]));
    let cones = |l: &Value| {
        let kind = &l["kind"];
        (
            kind["inner_cone_angle"].as_f64().unwrap(),
            kind["outer_cone_angle"].as_f64().unwrap(),
        )
    };
    for spot in &lights[2..4] {
        let (inner, outer) = cones(spot);
        assert!(
            0.0 <= inner && inner < outer && outer <= std::f64::consts::FRAC_PI_2,
            "{spot}"
        );
    }
    // The outer cone kept where it was valid, the inner one brought just inside it.
    let (inner, outer) = cones(&lights[3]);
    assert!(
        (outer - 0.25).abs() < 1e-7 && inner > 0.249,
        "{inner} {outer}"
    );
    assert_eq!(cones(&lights[4]), (0.2f32 as f64, 0.3f32 as f64));
}

/// Cameras outside the specification's ranges would render an empty or mirrored picture and
/// write a view file `--view` refuses: each is skipped with a warning that says why, and a
/// valid one beside them is kept.
#[test]
fn cameras_outside_the_specified_ranges_are_skipped_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = unit_quad();
    let perspective = |yfov: f64, znear: f64, zfar: Option<f64>| {
        let mut p = json!({"yfov": yfov, "znear": znear});
        if let Some(far) = zfar {
            p["zfar"] = json!(far);
        }
        json!({"type": "perspective", "perspective": p})
    };
    let orthographic = |xmag: f64, ymag: f64| json!({"type": "orthographic", "orthographic": {"xmag": xmag, "ymag": ymag, "znear": 0.0, "zfar": 10.0}});
    json["cameras"] = json!([
        perspective(0.0, 0.1, None),
        perspective(4.0, 0.1, None),
        perspective(0.8, 0.0, None),
        perspective(0.8, 1.0, Some(0.5)),
        orthographic(0.0, 1.0),
        orthographic(1.0, -1.0),
        perspective(0.8, 0.1, Some(100.0)),
    ]);
    // unit_quad's camera node (node 1) takes the valid camera, new nodes 2-7 the others.
    json["nodes"][1]["camera"] = json!(6);
    for camera in 0..6 {
        add_root_node(
            &mut json,
            json!({"camera": camera, "translation": [0.0, 0.0, 3.0]}),
        );
    }
    let info = info(dir.path(), json, &bin);
    assert_eq!(
        warnings(&info),
        [
            "camera on node 2 skipped: yfov 0 is not in (0, π) radians",
            "camera on node 3 skipped: yfov 4 is not in (0, π) radians",
            "camera on node 4 skipped: znear 0 is out of range",
            "camera on node 5 skipped: zfar 0.5 is not beyond znear 1",
            "camera on node 6 skipped: xmag 0 is zero or not finite",
            "camera on node 7 skipped: ymag -1 is not above 0",
        ]
    );
    assert_eq!(
        info["cameras"].as_array().unwrap().len(),
        1,
        "{}",
        info["cameras"]
    );
}

/// Normals of length 2 are reported, naming the primitive and the accessor.
#[test]
fn normals_that_are_not_unit_length_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, mut bin) = unit_quad();
    let normals = add_float_accessor(
        &mut json,
        &mut bin,
        &[0.0, 0.0, 2.0].repeat(4),
        json!({"count": 4, "type": "VEC3"}),
    );
    json["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = json!(normals);
    let info = info(dir.path(), json, &bin);
    assert_eq!(
        warnings(&info),
        ["mesh 0 primitive 0: accessor 3 (NORMAL): 4 of 4 normals are not unit length (vertex 0 has length 2); they are normalised"]
    );
}

/// `--quiet` hides the summary but not a warning about the picture; `--no-warnings` hides the
/// warnings.
#[test]
fn quiet_keeps_warnings_and_no_warnings_silences_them() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = unit_quad();
    json["images"] = json!([{"uri": "gone.png"}]);
    json["textures"] = json!([{"source": 0}]);
    json["materials"] = json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]);
    json["meshes"][0]["primitives"][0]["material"] = json!(0);
    json["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(2);
    json["nodes"][0]["rotation"] = json!([0.0, 0.0, 0.0, 2.0]);
    let model = write_gltf(dir.path(), "model.gltf", json, &bin);
    let image = dir.path().join("out.png");
    let render = |extra: &[&str]| {
        let mut args = vec![
            "render",
            s(&model),
            "-o",
            s(&image),
            "--width",
            "8",
            "--height",
            "8",
        ];
        args.extend_from_slice(extra);
        stderr(&run(&args, true))
    };
    let normal = render(&[]);
    let quiet = render(&["-q"]);
    let silent = render(&["-q", "--no-warnings"]);
    let warning_lines = |text: &str| -> Vec<String> {
        text.lines()
            .filter(|l| l.starts_with("warning: "))
            .map(str::to_string)
            .collect()
    };
    let expected = warning_lines(&normal);
    assert_eq!(expected.len(), 2, "{normal}");
    assert!(
        expected[0].contains("node 0: rotation [0.0, 0.0, 0.0, 2.0]"),
        "{normal}"
    );
    assert!(expected[1].contains("gone.png"), "{normal}");
    assert!(expected[1].contains("drawn without"), "{normal}");
    assert!(normal.lines().count() > 2, "a summary follows: {normal}");
    assert_eq!(
        quiet.lines().map(str::to_string).collect::<Vec<_>>(),
        expected
    );
    assert_eq!(silent, "");
}
