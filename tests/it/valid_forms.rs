//! Valid glTF 2.0 that strict readers refuse: each form below is valid by the specification
//! (the Khronos validator reports at most a warning), and each test writes a small file of it
//! and checks that it is drawn (pixels covered) or, where there is nothing to draw, that the
//! program says so.

use crate::common::{glb_bytes, read_rgba, run, s, stderr, unit_quad as quad, write_gltf};
use serde_json::{json, Value};
use std::path::Path;

/// Renders `model` at 32x32 from its camera with the direct integrator (colours below are
/// judged under its default rig) and returns the covered pixels (alpha > 0) and
/// standard error (with warnings: no `-q`).
fn covered(model: &Path) -> (usize, String) {
    crate::common::copy_to_corpus(model);
    let out_png = model.with_extension("png");
    let out = run(
        &[
            "render",
            s(model),
            "-o",
            s(&out_png),
            "--width",
            "32",
            "--height",
            "32",
            "--spp",
            "1",
            "--integrator",
            "direct",
        ],
        true,
    );
    let (_, _, pixels) = read_rgba(&out_png);
    (pixels.iter().filter(|p| p[3] > 0.0).count(), stderr(&out))
}

/// The quad covers [-0.5, 0.5]² of the camera's [-1, 1]²: a quarter of the 32x32 pixels.
const QUAD_PIXELS: usize = 256;

/// Writes `json` with `bin` embedded and checks that the quad covers its pixels; returns the
/// render's standard error.
fn quad_is_drawn(test: &str, json: Value, bin: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let model = write_gltf(dir, "model.gltf", json, bin);
    let (pixels, err) = covered(&model);
    assert_eq!(pixels, QUAD_PIXELS, "{test}: {err}");
    err
}

/// glTF 2.0 §3.6.2.3: an accessor without a bufferView is zeros, and with `sparse` the sparse
/// values replace some of them; here the POSITION accessor has no view of its own and all four
/// corners come from its sparse values, and TEXCOORD_0 is all zeros.
#[test]
fn accessors_without_a_buffer_view_are_zeros_and_sparse_values() {
    let (mut json, mut bin) = quad();
    json["bufferViews"]
        .as_array_mut()
        .unwrap()
        .push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": 4}));
    bin.extend([0u8, 1, 2, 3]);
    let positions = &mut json["accessors"][0];
    positions.as_object_mut().unwrap().remove("bufferView");
    positions["sparse"] = json!({"count": 4,
        "indices": {"bufferView": 3, "componentType": 5121},
        "values": {"bufferView": 0}});
    json["accessors"]
        .as_array_mut()
        .unwrap()
        .push(json!({"componentType": 5126, "count": 4, "type": "VEC2"}));
    json["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(3);
    let err = quad_is_drawn("zeros", json, &bin);
    assert!(!err.contains("warning"), "{err}");
}

/// A lossless 2x2 WebP of one colour.
fn webp(rgba: [u8; 4]) -> Vec<u8> {
    let img = image::RgbaImage::from_pixel(2, 2, image::Rgba(rgba));
    let mut bytes = Vec::new();
    image::codecs::webp::WebPEncoder::new_lossless(&mut bytes)
        .encode(img.as_raw(), 2, 2, image::ExtendedColorType::Rgba8)
        .unwrap();
    bytes
}

/// `EXT_texture_webp` and `KHR_texture_basisu`: a texture may have no core `source` when the
/// extension gives the image. The WebP is drawn (a red quad); the KTX2 image here is not a
/// KTX2 file, so its quad is drawn without the texture, with a warning that says so.
#[test]
fn textures_whose_only_source_is_an_extension_are_drawn() {
    use base64::Engine;
    let red = webp([255, 0, 0, 255]);
    for (extension, mime, data) in [
        ("EXT_texture_webp", "image/webp", red),
        (
            "KHR_texture_basisu",
            "image/ktx2",
            b"not a KTX2 file".to_vec(),
        ),
    ] {
        let (mut json, bin) = quad();
        let uri = format!(
            "data:{mime};base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&data)
        );
        json["extensionsUsed"] = json!([extension]);
        json["images"] = json!([{"uri": uri}]);
        json["textures"] = json!([{"extensions": {extension: {"source": 0}}}]);
        json["materials"] = json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]);
        json["meshes"][0]["primitives"][0]["material"] = json!(0);
        json["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(2);
        let dir = tempfile::tempdir().unwrap();
        let dir = dir.path();
        let model = write_gltf(dir, "model.gltf", json, &bin);
        let (pixels, err) = covered(&model);
        assert_eq!(pixels, QUAD_PIXELS, "{extension}: {err}");
        let (_, _, image) = read_rgba(&model.with_extension("png"));
        let centre = image[16 * 32 + 16];
        if extension == "EXT_texture_webp" {
            assert!(!err.contains("warning"), "{err}");
            assert!(
                centre[0] > 0.2 && centre[1] < 0.05 && centre[2] < 0.05,
                "{centre:?}"
            );
        } else {
            assert!(err.contains("drawn without"), "{err}");
            // The default white base colour: grey under the default rig, not red.
            assert!((centre[0] - centre[1]).abs() < 0.02, "{centre:?}");
        }
    }
}

/// A scene without nodes and a file without scenes are valid: `info` describes the file and
/// says there is nothing to draw (exit 0); `render` refuses with that reason and writes nothing.
#[test]
fn files_with_nothing_to_draw_are_described_and_not_rendered() {
    for (name, edit, reason) in [
        (
            "empty-scene",
            (|j: &mut Value| j["scenes"] = json!([{"name": "empty"}])) as fn(&mut Value),
            "nothing to draw: scene 0 has no nodes",
        ),
        (
            "no-scene",
            |j: &mut Value| {
                let top = j.as_object_mut().unwrap();
                top.remove("scenes");
                top.remove("scene");
            },
            "nothing to draw: the file defines no scene",
        ),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let dir = dir.path();
        let (mut json, bin) = quad();
        edit(&mut json);
        let model = write_gltf(dir, "model.gltf", json, &bin);
        crate::common::copy_to_corpus(&model);
        let info = run(&["info", s(&model), "--json"], true);
        let info: Value = serde_json::from_slice(&info.stdout).unwrap();
        assert_eq!(info["triangles"], 0, "{name}");
        assert_eq!(info["meshes"], 1, "{name}");
        assert_eq!(info["warnings"], json!([reason]), "{name}");
        let image = dir.join("out.png");
        let out = run(&["render", s(&model), "-o", s(&image), "-q"], false);
        let err = stderr(&out);
        assert_eq!(
            err.trim_end(),
            format!("meshtracer: error: {}: {reason}", model.display()),
            "{name}"
        );
        assert!(!image.exists(), "{name}");
    }
}

/// `extras` may be any JSON value (§5.27), and JSON Schema's integers may be written `1.0`.
#[test]
fn extras_of_any_type_and_integers_written_as_floats_are_read() {
    let (mut json, bin) = quad();
    json["asset"]["extras"] = json!("exported by hand");
    json["nodes"][0]["extras"] = json!(5);
    json["meshes"][0]["extras"] = json!([1, 2]);
    json["scene"] = json!(0.0);
    json["nodes"][0]["mesh"] = json!(0.0);
    json["meshes"][0]["primitives"][0] = json!({"attributes": {"POSITION": 0.0}, "indices": 1.0});
    json["accessors"][0]["componentType"] = json!(5126.0);
    json["accessors"][1]["count"] = json!(6.0);
    json["bufferViews"][0]["byteLength"] = json!(48.0);
    let err = quad_is_drawn("extras-and-floats", json, &bin);
    assert!(!err.contains("warning"), "{err}");
}

/// A primitive without POSITION is skipped with a warning naming it; the mesh's other
/// primitive is drawn.
#[test]
fn a_primitive_without_positions_is_skipped_and_the_rest_drawn() {
    let (mut json, bin) = quad();
    let drawn = json["meshes"][0]["primitives"][0].clone();
    json["meshes"][0]["primitives"] = json!([{"attributes": {"TEXCOORD_0": 2}}, drawn]);
    let err = quad_is_drawn("no-position", json, &bin);
    assert!(
        err.contains("mesh 0 primitive 0: has no POSITION attribute; the primitive is skipped"),
        "{err}"
    );
}

/// A `KHR_lights_punctual` light of a type the extension does not define is skipped with a
/// warning; the other light keeps its node.
#[test]
fn a_light_of_an_unknown_type_is_skipped() {
    let (mut json, bin) = quad();
    json["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    json["extensions"] = json!({"KHR_lights_punctual": {"lights": [
        {"type": "area", "intensity": 5.0, "width": 1.0},
        {"type": "point", "intensity": 7.0}
    ]}});
    json["nodes"].as_array_mut().unwrap().extend([
        json!({"translation": [0.0, 0.0, 1.0], "extensions": {"KHR_lights_punctual": {"light": 0}}}),
        json!({"translation": [0.0, 0.0, 3.0], "extensions": {"KHR_lights_punctual": {"light": 1}}}),
    ]);
    json["scenes"][0]["nodes"] = json!([0, 1, 2, 3]);
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    let model = write_gltf(dir, "model.gltf", json.clone(), &bin);
    let info = run(&["info", s(&model), "--json"], true);
    let info: Value = serde_json::from_slice(&info.stdout).unwrap();
    let lights = info["lights"].as_array().unwrap();
    assert_eq!(lights.len(), 1, "{info}");
    assert_eq!(lights[0]["intensity"], 7.0);
    assert_eq!(lights[0]["position"], json!([0.0, 0.0, 3.0]));
    let err = quad_is_drawn("unknown-light-render", json, &bin);
    assert!(
        err.contains("KHR_lights_punctual light 0: type 'area' is not one of directional, point, spot; the light is skipped"),
        "{err}"
    );
}

/// A GLB may end with padding or other bytes after its last chunk, and may hold chunks of
/// types glTF does not define, which readers ignore (§4.4.3).
#[test]
fn glb_padding_trailing_bytes_and_unknown_chunks_are_ignored() {
    let (mut json, bin) = quad();
    json["buffers"] = json!([{"byteLength": bin.len()}]);
    let plain = glb_bytes(&json, &bin);
    let set_length = |bytes: &mut Vec<u8>| {
        let length = bytes.len() as u32;
        bytes[8..12].copy_from_slice(&length.to_le_bytes());
    };
    let mut trailing = plain.clone();
    trailing.extend(b"trailing bytes after the GLB");
    let mut padded = plain.clone();
    padded.extend([0u8; 4]);
    set_length(&mut padded);
    // An unknown chunk between the JSON and the BIN chunk.
    let json_end = 20 + u32::from_le_bytes(plain[12..16].try_into().unwrap()) as usize;
    let mut unknown = plain[..json_end].to_vec();
    unknown.extend(8u32.to_le_bytes());
    unknown.extend(b"XTRA12345678");
    unknown.extend(&plain[json_end..]);
    set_length(&mut unknown);
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    for (name, bytes) in [
        ("trailing", trailing),
        ("padded", padded),
        ("unknown", unknown),
    ] {
        let model = dir.join(format!("{name}.glb"));
        std::fs::write(&model, bytes).unwrap();
        let (pixels, err) = covered(&model);
        assert_eq!(pixels, QUAD_PIXELS, "{name}: {err}");
    }
}

/// RFC 2397: a `data:` URI without `;base64` holds its bytes percent-encoded.
#[test]
fn percent_encoded_data_uris_are_decoded() {
    let (mut json, bin) = quad();
    let encoded: String = bin.iter().map(|b| format!("%{b:02X}")).collect();
    let dir = tempfile::tempdir().unwrap();
    let dir = dir.path();
    json["buffers"] = json!([{"byteLength": bin.len(),
        "uri": format!("data:application/octet-stream,{encoded}")}]);
    let model = dir.join("model.gltf");
    std::fs::write(&model, serde_json::to_vec(&json).unwrap()).unwrap();
    let (pixels, err) = covered(&model);
    assert_eq!(pixels, QUAD_PIXELS, "{err}");
}
