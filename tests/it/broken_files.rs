//! The broken-file corpus: small malformed, truncated and hostile files that the test writes
//! itself. Every case must give the exact error kind through the library, and through the binary
//! a non-zero exit with one message that names the file, never a panic. The cases whose only
//! fault is an image are errors only under `--strict`: without it the model is drawn without
//! that texture, with a warning (a missing texture is not a missing model).
//!
//! `MESHTRACER_WRITE_CORPUS=DIR cargo test --test broken_files` also writes every case to DIR
//! (the fuzzers' seed corpus).

use base64::Engine;
use meshtracer::LoadErrorKind as K;
use meshtracer::{LoadOptions, Scene};
use serde_json::{json, Value};
use std::path::Path;

/// One broken input: the files to write, which one to load, and the error kind expected.
struct Case {
    name: &'static str,
    files: Vec<(String, Vec<u8>)>,
    model: String,
    expect: fn(&K) -> bool,
}

/// A valid one-triangle glTF with its buffer in `tri.bin`: the base most cases break.
fn base() -> (Value, Vec<u8>) {
    let mut bin = crate::common::f32_bytes(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    bin.extend([0u16, 1, 2].iter().flat_map(|i| i.to_le_bytes()));
    bin.extend([0, 0]);
    let json = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 6}
        ],
        "buffers": [{"byteLength": 44, "uri": "tri.bin"}]
    });
    (json, bin)
}

fn gltf_case(name: &'static str, json: Value, bin: Vec<u8>, expect: fn(&K) -> bool) -> Case {
    Case {
        name,
        files: vec![
            (
                "model.gltf".into(),
                serde_json::to_vec_pretty(&json).unwrap(),
            ),
            ("tri.bin".into(), bin),
        ],
        model: "model.gltf".into(),
        expect,
    }
}

/// `base()` modified by `edit`.
fn edited(
    name: &'static str,
    edit: impl FnOnce(&mut Value, &mut Vec<u8>),
    expect: fn(&K) -> bool,
) -> Case {
    let (mut json, mut bin) = base();
    edit(&mut json, &mut bin);
    gltf_case(name, json, bin, expect)
}

/// The base triangle with its positions and indices meshopt-compressed (`KHR_meshopt_compression`,
/// encoded by meshoptimizer-rs's reference encoder) in `tri.bin`, decoded into fallback buffer 1,
/// which has no data of its own.
fn meshopt_base() -> (Value, Vec<u8>) {
    use meshoptimizer_rs::codec;
    let mut ws = meshoptimizer_rs::Workspace::new(meshoptimizer_rs::Limits::default());
    let positions = crate::common::f32_bytes(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    let vertices =
        codec::encode_vertex_buffer(&positions, 3, 12, codec::VertexEncoding::DEFAULT, &mut ws)
            .unwrap();
    let indices =
        codec::encode_index_buffer(&[0, 1, 2], codec::IndexEncoding::DEFAULT, &mut ws).unwrap();
    let mut bin = vertices.clone();
    bin.extend(&indices);
    let (mut json, _) = base();
    let ext = |offset: usize, length: usize, stride: usize, mode: &str| {
        json!({"KHR_meshopt_compression": {"buffer": 0, "byteOffset": offset,
            "byteLength": length, "byteStride": stride, "count": 3, "mode": mode}})
    };
    json["extensionsUsed"] = json!(["KHR_meshopt_compression"]);
    json["extensionsRequired"] = json!(["KHR_meshopt_compression"]);
    json["bufferViews"] = json!([
        {"buffer": 1, "byteOffset": 0, "byteLength": 36,
         "extensions": ext(0, vertices.len(), 12, "ATTRIBUTES")},
        {"buffer": 1, "byteOffset": 36, "byteLength": 6,
         "extensions": ext(vertices.len(), indices.len(), 2, "TRIANGLES")}
    ]);
    json["buffers"] = json!([
        {"byteLength": bin.len(), "uri": "tri.bin"},
        {"byteLength": 44, "extensions": {"KHR_meshopt_compression": {"fallback": true}}}
    ]);
    (json, bin)
}

/// `meshopt_base()` modified by `edit`.
fn meshopt_edited(
    name: &'static str,
    edit: impl FnOnce(&mut Value, &mut Vec<u8>),
    expect: fn(&K) -> bool,
) -> Case {
    let (mut json, mut bin) = meshopt_base();
    edit(&mut json, &mut bin);
    gltf_case(name, json, bin, expect)
}

/// `base()`'s triangle as a Draco stream: 70 bytes written by draco-core 2.3.3's `MeshEncoder`
/// with default `EncoderOptions` (EdgeBreaker, positions quantized to 11 bits) from one Float32
/// POSITION attribute (unique id 0) and one face. Kept as bytes so that the tests need no
/// Draco encoder (the crate is built decoder-only).
const DRACO_TRIANGLE: [u8; 70] = [
    68, 82, 65, 67, 79, 2, 2, 1, 1, 0, 0, 0, 3, 1, 0, 1, 0, 0, 1, 7, 255, 1, 17, 1, 255, 0, 0, 1,
    0, 9, 3, 0, 0, 0, 0, 0, 128, 63, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 128, 63, 0, 0, 0, 0,
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
];

/// The base triangle compressed with `KHR_draco_mesh_compression`: its POSITION and indices
/// accessors keep count and type but have no bufferView; bufferView 0 holds the stream.
fn draco_base() -> (Value, Vec<u8>) {
    let (mut json, _) = base();
    json["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
    json["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
    json["meshes"][0]["primitives"][0]["extensions"] = json!({"KHR_draco_mesh_compression":
        {"bufferView": 0, "attributes": {"POSITION": 0}}});
    for accessor in json["accessors"].as_array_mut().unwrap() {
        accessor.as_object_mut().unwrap().remove("bufferView");
    }
    json["bufferViews"] = json!([{"buffer": 0, "byteLength": DRACO_TRIANGLE.len()}]);
    json["buffers"] = json!([{"byteLength": DRACO_TRIANGLE.len(), "uri": "tri.bin"}]);
    (json, DRACO_TRIANGLE.to_vec())
}

/// `draco_base()` modified by `edit`.
fn draco_edited(
    name: &'static str,
    edit: impl FnOnce(&mut Value, &mut Vec<u8>),
    expect: fn(&K) -> bool,
) -> Case {
    let (mut json, mut bin) = draco_base();
    edit(&mut json, &mut bin);
    gltf_case(name, json, bin, expect)
}

/// The base triangle as a GLB with the buffer in its BIN chunk.
fn glb() -> Vec<u8> {
    let (mut json, bin) = base();
    json["buffers"] = json!([{"byteLength": 44}]);
    crate::common::glb_bytes(&json, &bin)
}

fn glb_case(name: &'static str, bytes: Vec<u8>, expect: fn(&K) -> bool) -> Case {
    Case {
        name,
        files: vec![("model.glb".into(), bytes)],
        model: "model.glb".into(),
        expect,
    }
}

fn obj_case(
    name: &'static str,
    obj: &[u8],
    extra: Vec<(String, Vec<u8>)>,
    expect: fn(&K) -> bool,
) -> Case {
    let mut files = vec![("model.obj".to_string(), obj.to_vec())];
    files.extend(extra);
    Case {
        name,
        files,
        model: "model.obj".into(),
        expect,
    }
}

/// CRC-32 (IEEE), for writing PNG chunks by hand.
fn crc32(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in data {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// A PNG whose header declares `w` x `h` pixels (the image data itself is absent).
fn png_header(w: u32, h: u32) -> Vec<u8> {
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend(w.to_be_bytes());
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([8, 6, 0, 0, 0]);
    out.extend(13u32.to_be_bytes());
    out.extend(&ihdr);
    out.extend(crc32(&ihdr).to_be_bytes());
    for chunk in [&b"IDAT"[..], &b"IEND"[..]] {
        out.extend(0u32.to_be_bytes());
        out.extend(chunk);
        out.extend(crc32(chunk).to_be_bytes());
    }
    out
}

/// A valid 1x1 PNG.
fn png_1x1() -> Vec<u8> {
    let mut bytes = Vec::new();
    image::RgbaImage::from_pixel(1, 1, image::Rgba([255, 0, 0, 255]))
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .unwrap();
    bytes
}

/// `base()` with a base colour texture of image `uri`, and the TEXCOORD_0 it reads (zeros: an
/// accessor without a bufferView).
fn with_image(json: &mut Value, uri: &str) {
    json["accessors"]
        .as_array_mut()
        .unwrap()
        .push(json!({"componentType": 5126, "count": 3, "type": "VEC2"}));
    json["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(2);
    json["images"] = json!([{"uri": uri}]);
    json["textures"] = json!([{"source": 0}]);
    json["materials"] = json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]);
    json["meshes"][0]["primitives"][0]["material"] = json!(0);
}

fn cases() -> Vec<Case> {
    let glb_bytes = glb();
    let json_len = u32::from_le_bytes(glb_bytes[12..16].try_into().unwrap()) as usize;
    let bin_chunk = 20 + json_len;
    let mut cases = vec![
        // Files that are not models at all.
        Case {
            name: "zero-byte file",
            files: vec![("model.gltf".into(), vec![])],
            model: "model.gltf".into(),
            expect: |k| matches!(k, K::EmptyFile),
        },
        Case {
            name: "text that is not JSON",
            files: vec![("model.gltf".into(), b"hello".to_vec())],
            model: "model.gltf".into(),
            expect: |k| matches!(k, K::UnknownFormat),
        },
        Case {
            name: "JSON that is not glTF",
            files: vec![("model.gltf".into(), b"{\"hello\": 1}".to_vec())],
            model: "model.gltf".into(),
            expect: |k| matches!(k, K::Gltf(_)),
        },
        Case {
            name: "truncated JSON",
            files: vec![(
                "model.gltf".into(),
                b"{\"asset\": {\"version\": \"2.".to_vec(),
            )],
            model: "model.gltf".into(),
            expect: |k| matches!(k, K::Gltf(_)),
        },
        Case {
            name: "a directory without a model given as the model",
            files: vec![("model.gltf/x".into(), vec![1])],
            model: "model.gltf".into(),
            expect: |k| matches!(k, K::Folder(m) if m == "holds no .gltf, .glb or .obj file"),
        },
        Case {
            name: "missing file",
            files: vec![],
            model: "nothing.gltf".into(),
            expect: |k| matches!(k, K::Io(_)),
        },
        // GLB container.
        glb_case(
            "GLB truncated inside the header",
            glb_bytes[..8].to_vec(),
            |k| matches!(k, K::Glb(_)),
        ),
        glb_case(
            "GLB truncated after the header",
            glb_bytes[..12].to_vec(),
            |k| matches!(k, K::Glb(_)),
        ),
        glb_case(
            "GLB truncated inside the JSON chunk header",
            glb_bytes[..16].to_vec(),
            |k| matches!(k, K::Glb(_)),
        ),
        glb_case(
            "GLB truncated inside the JSON chunk",
            glb_bytes[..40].to_vec(),
            |k| matches!(k, K::Glb(_)),
        ),
        glb_case(
            "GLB truncated at the BIN chunk",
            glb_bytes[..bin_chunk].to_vec(),
            |k| matches!(k, K::Glb(m) if m.contains("truncated")),
        ),
        glb_case(
            "GLB truncated inside the BIN chunk header",
            glb_bytes[..bin_chunk + 4].to_vec(),
            |k| matches!(k, K::Glb(_)),
        ),
        glb_case(
            "GLB truncated inside the BIN chunk",
            glb_bytes[..glb_bytes.len() - 10].to_vec(),
            |k| matches!(k, K::Glb(_)),
        ),
        glb_case(
            "GLB with version 1",
            {
                let mut b = glb_bytes.clone();
                b[4] = 1;
                b
            },
            |k| matches!(k, K::Glb(_)),
        ),
        glb_case(
            "GLB length field below the header size",
            {
                let mut b = glb_bytes.clone();
                b[8..12].copy_from_slice(&4u32.to_le_bytes());
                b
            },
            |k| matches!(k, K::Glb(_)),
        ),
        glb_case(
            "GLB length field past the end",
            {
                let mut b = glb_bytes.clone();
                b[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
                b
            },
            |k| matches!(k, K::Glb(_)),
        ),
        glb_case(
            "GLB chunk length past the end",
            {
                let mut b = glb_bytes.clone();
                b[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
                b
            },
            |k| matches!(k, K::Glb(_)),
        ),
        glb_case(
            "GLB with wrong magic",
            {
                let mut b = glb_bytes.clone();
                b[3] = b'X';
                b
            },
            |k| matches!(k, K::UnknownFormat),
        ),
        // Buffers.
        gltf_case("missing .bin", base().0, vec![], |_| false),
        edited(
            "buffer shorter than declared",
            |_, bin| bin.truncate(20),
            |k| {
                matches!(
                    k,
                    K::BufferTooShort {
                        buffer: 0,
                        expected: 44,
                        actual: 20
                    }
                )
            },
        ),
        edited(
            "base64 that does not decode",
            |j, _| j["buffers"][0]["uri"] = json!("data:application/octet-stream;base64,@@@@"),
            |k| matches!(k, K::DataUri { .. }),
        ),
        edited(
            "empty buffer",
            |j, bin| {
                bin.clear();
                j["buffers"][0]["byteLength"] = json!(0);
            },
            |k| matches!(k, K::ViewOutOfRange { len: 0, .. }),
        ),
        edited(
            "buffer URI escaping the folder",
            // No file of its name in the folder either (`tri.bin` would be found by name).
            |j, _| j["buffers"][0]["uri"] = json!("../secret.bin"),
            |k| matches!(k, K::ExternalFile { .. }),
        ),
        edited(
            "absolute buffer URI",
            |j, _| j["buffers"][0]["uri"] = json!("/etc/passwd"),
            |k| matches!(k, K::ExternalFile { .. }),
        ),
        edited(
            "bufferView past the buffer",
            |j, _| j["bufferViews"][1]["byteOffset"] = json!(40),
            |k| matches!(k, K::ViewOutOfRange { view: 1, .. }),
        ),
        // Accessors and indices.
        edited(
            "accessor count past the view",
            |j, _| j["accessors"][0]["count"] = json!(300),
            |k| matches!(k, K::Accessor { accessor: 0, .. }),
        ),
        edited(
            "accessor offset past the view",
            |j, _| j["accessors"][0]["byteOffset"] = json!(32),
            |k| matches!(k, K::Accessor { accessor: 0, .. }),
        ),
        edited(
            "accessor stride smaller than the element",
            |j, _| j["bufferViews"][0]["byteStride"] = json!(4),
            |k| matches!(k, K::Accessor { .. }),
        ),
        edited(
            "accessor count zero",
            |j, _| j["accessors"][1]["count"] = json!(0),
            |k| matches!(k, K::Accessor { .. }),
        ),
        edited(
            "index past the vertex count",
            |_, bin| bin[40..42].copy_from_slice(&7u16.to_le_bytes()),
            |k| {
                matches!(
                    k,
                    K::IndexOutOfRange {
                        index: 7,
                        vertex_count: 3,
                        ..
                    }
                )
            },
        ),
        edited(
            "POSITION with an integer component type",
            |j, _| j["accessors"][0]["componentType"] = json!(5121),
            |k| matches!(k, K::Accessor { .. }),
        ),
        edited(
            "indices of type VEC2",
            |j, _| j["accessors"][1]["type"] = json!("VEC2"),
            |k| matches!(k, K::Accessor { .. }),
        ),
        edited(
            "mesh whose only primitive has no POSITION",
            |j, _| j["meshes"][0]["primitives"][0]["attributes"] = json!({"NORMAL": 0}),
            |k| matches!(k, K::NoTriangles(m) if m.contains("mesh 0 primitive 0: has no POSITION")),
        ),
        // Found by fuzzing: gltf-json's validation indexed accessors[POSITION] unchecked.
        edited(
            "POSITION accessor that does not exist",
            |j, _| j["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(9),
            |k| matches!(k, K::Gltf(m) if m.contains("accessor 9")),
        ),
        edited(
            "accessor index that does not exist",
            |j, _| j["meshes"][0]["primitives"][0]["indices"] = json!(9),
            |k| matches!(k, K::Gltf(_)),
        ),
        // Values.
        edited(
            "NaN positions",
            |_, bin| bin[0..4].copy_from_slice(&f32::NAN.to_le_bytes()),
            |k| matches!(k, K::NoTriangles(d) if d.contains("NaN")),
        ),
        edited(
            "infinite positions",
            |_, bin| bin[12..16].copy_from_slice(&f32::INFINITY.to_le_bytes()),
            |k| matches!(k, K::NoTriangles(_)),
        ),
        edited(
            "degenerate triangle",
            |_, bin| bin[24..36].copy_from_slice(&crate::common::f32_bytes(&[2.0, 0.0, 0.0])),
            |k| matches!(k, K::NoTriangles(d) if d.contains("degenerate")),
        ),
        edited(
            "NaN in a node matrix",
            |j, _| j["nodes"][0]["scale"] = json!([1.0, 1e39, 1.0]),
            |k| matches!(k, K::NoTriangles(d) if d.contains("not finite")),
        ),
        edited(
            "zero-scale node",
            |j, _| j["nodes"][0]["scale"] = json!([0.0, 0.0, 0.0]),
            |k| matches!(k, K::NoTriangles(d) if d.contains("singular")),
        ),
        edited(
            "singular node matrix",
            |j, _| {
                j["nodes"][0]["matrix"] = json!([
                    1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0
                ])
            },
            |k| matches!(k, K::NoTriangles(_)),
        ),
        // Scene structure.
        edited(
            "node that is its own ancestor",
            |j, _| {
                j["nodes"] = json!([{"mesh": 0, "children": [1]}, {"children": [0]}]);
            },
            |k| matches!(k, K::NodeCycle { node: 0 }),
        ),
        edited(
            "node that is its own child",
            |j, _| {
                j["nodes"] = json!([{"mesh": 0, "children": [0]}]);
            },
            |k| matches!(k, K::NodeCycle { node: 0 }),
        ),
        edited(
            "scene index out of range",
            |j, _| j["scene"] = json!(5),
            |k| matches!(k, K::Gltf(_)),
        ),
        edited(
            "required extension meshtracer does not know",
            |j, _| {
                j["extensionsUsed"] = json!(["EXT_made_up_geometry"]);
                j["extensionsRequired"] = json!(["EXT_made_up_geometry"]);
            },
            |k| matches!(k, K::UnsupportedExtension { name, .. } if name == "EXT_made_up_geometry"),
        ),
        // Images.
        edited(
            "missing image file",
            |j, _| with_image(j, "missing.png"),
            |k| matches!(k, K::MissingFile { problem, .. } if matches!(**problem, K::Image { image: 0, .. })),
        ),
        edited(
            "image that is not an image",
            |j, _| with_image(j, "data:image/png;base64,aGVsbG8gd29ybGQ="),
            |k| matches!(k, K::Image { image: 0, .. }),
        ),
        edited(
            "image declaring 100000x100000 pixels",
            |j, _| {
                let png =
                    base64::engine::general_purpose::STANDARD.encode(png_header(100_000, 100_000));
                with_image(j, &format!("data:image/png;base64,{png}"));
            },
            |k| matches!(k, K::Image { problem, .. } if problem.contains("100000x100000")),
        ),
        edited(
            "KTX2 image declaring 60000x60000 pixels",
            |j, _| {
                let mut ktx2 = vec![0xAB, b'K', b'T', b'X', b' ', b'2', b'0', 0xBB, b'\r', b'\n'];
                ktx2.extend([0x1A, b'\n', 0, 0, 0, 0, 0, 0, 0, 0]);
                ktx2.extend(60_000u32.to_le_bytes());
                ktx2.extend(60_000u32.to_le_bytes());
                ktx2.extend([0; 64]);
                let data = base64::engine::general_purpose::STANDARD.encode(ktx2);
                with_image(j, &format!("data:image/ktx2;base64,{data}"));
            },
            |k| matches!(k, K::Image { problem, .. } if problem.contains("60000x60000")),
        ),
        edited(
            "clearcoat texture index past the textures",
            |j, _| {
                let png = base64::engine::general_purpose::STANDARD.encode(png_1x1());
                with_image(j, &format!("data:image/png;base64,{png}"));
                j["materials"][0]["extensions"] = json!({"KHR_materials_clearcoat": {
                    "clearcoatFactor": 1.0, "clearcoatTexture": {"index": 7}}});
            },
            |k| matches!(k, K::BadReference { index: 7, .. }),
        ),
        edited(
            "transmission texture index past the textures",
            |j, _| {
                let png = base64::engine::general_purpose::STANDARD.encode(png_1x1());
                with_image(j, &format!("data:image/png;base64,{png}"));
                j["extensionsUsed"] = json!(["KHR_materials_transmission"]);
                j["materials"][0]["extensions"] = json!({"KHR_materials_transmission": {
                    "transmissionFactor": 1.0, "transmissionTexture": {"index": 7}}});
            },
            |k| matches!(k, K::Gltf(m) if m.contains("transmissionTexture")),
        ),
        edited(
            "volume thickness texture index past the textures",
            |j, _| {
                let png = base64::engine::general_purpose::STANDARD.encode(png_1x1());
                with_image(j, &format!("data:image/png;base64,{png}"));
                j["extensionsUsed"] = json!(["KHR_materials_volume"]);
                j["materials"][0]["extensions"] = json!({"KHR_materials_volume": {
                    "thicknessFactor": 0.5, "thicknessTexture": {"index": 7}}});
            },
            |k| matches!(k, K::Gltf(m) if m.contains("thicknessTexture")),
        ),
        // Found by fuzzing: the gltf crate unwrapped these.
        edited(
            "image with a bufferView but no mimeType",
            |j, _| {
                with_image(j, "x.png");
                j["images"] = json!([{"bufferView": 0}]);
            },
            |k| matches!(k, K::Image { problem, .. } if problem.contains("mimeType")),
        ),
        edited(
            "image with neither uri nor bufferView",
            |j, _| {
                with_image(j, "x.png");
                j["images"] = json!([{"name": "nothing"}]);
            },
            |k| matches!(k, K::Image { problem, .. } if problem.contains("neither")),
        ),
        edited(
            "image URI escaping the folder",
            |j, _| with_image(j, "../../secret.png"),
            |k| matches!(k, K::ExternalFile { .. }),
        ),
        // OBJ.
        obj_case(
            "OBJ index past the vertices",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
            vec![],
            |k| matches!(k, K::Obj(m) if m.starts_with("line 4: face index 9") && m.contains("does not exist")),
        ),
        obj_case(
            "OBJ index zero",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
            vec![],
            |k| matches!(k, K::Obj(_)),
        ),
        obj_case(
            "OBJ negative index past the start",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -9\n",
            vec![],
            |k| matches!(k, K::Obj(m) if m.contains("does not exist")),
        ),
        obj_case(
            "OBJ relative normal index before the first",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//-5\n",
            vec![],
            |k| matches!(k, K::Obj(m) if m.contains("line 5") && m.contains("normal")),
        ),
        // Found by the obj fuzz target: tobj computes (index - 1) * 3 in usize, which wrapped
        // to 2, inside the normal array, and rendered a wrong normal without a word.
        obj_case(
            "OBJ normal index near 2^63",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 1 0\nf 1//1 2//1 3//6148914691236517207\n",
            vec![],
            |k| matches!(k, K::Obj(m) if m.contains("6148914691236517207")),
        ),
        obj_case(
            "OBJ face with two vertices",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n",
            vec![],
            |k| matches!(k, K::NoTriangles(_)),
        ),
        obj_case(
            "OBJ normal index past the normals",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//5\n",
            vec![],
            |k| matches!(k, K::Obj(m) if m.starts_with("line 5: face index 5 refers to a normal")),
        ),
        obj_case(
            "OBJ with a missing MTL",
            b"mtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            vec![],
            |k| {
                matches!(k, K::MissingFile { problem, .. }
                    if matches!(&**problem, K::Mtl { mtl, .. } if mtl == "gone.mtl"))
            },
        ),
        obj_case(
            "OBJ MTL escaping the folder",
            b"mtllib ../x.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            vec![],
            |k| matches!(k, K::Mtl { .. }),
        ),
        obj_case(
            "OBJ with a missing texture",
            b"mtllib m.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            vec![("m.mtl".into(), b"newmtl a\nmap_Kd gone.png\n".to_vec())],
            |k| {
                matches!(k, K::MissingFile { problem, .. }
                    if matches!(&**problem, K::Image { problem, .. } if problem.contains("gone.png")))
            },
        ),
        obj_case(
            "OBJ with a DDS texture declaring 65535x65535 texels",
            b"mtllib m.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            vec![
                ("m.mtl".into(), b"newmtl a\nmap_Kd huge.dds\n".to_vec()),
                ("huge.dds".into(), {
                    let mut dds = crate::materials::quadrants_dds(true);
                    dds[12..20].copy_from_slice(&[0xFF, 0xFF, 0, 0, 0xFF, 0xFF, 0, 0]);
                    dds
                }),
            ],
            |k| matches!(k, K::Image { problem, .. } if problem.contains("declares 65535x65535 pixels")),
        ),
        obj_case(
            "OBJ with a DDS texture cut inside its header",
            b"mtllib m.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            vec![
                ("m.mtl".into(), b"newmtl a\nmap_Kd cut.dds\n".to_vec()),
                (
                    "cut.dds".into(),
                    crate::materials::quadrants_dds(true)[..14].to_vec(),
                ),
            ],
            |k| matches!(k, K::Image { problem, .. } if problem.contains("truncated DDS header")),
        ),
        obj_case(
            "OBJ face index that is not a number",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf a b c\n",
            vec![],
            |k| matches!(k, K::Obj(m) if m.starts_with("line 4: bad face")),
        ),
        obj_case(
            "OBJ that is not UTF-8",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\n# \xff\xfe\nf 1 2 3\n",
            vec![],
            |k| matches!(k, K::Obj(m) if m.contains("UTF-8")),
        ),
        obj_case("OBJ with no faces", b"v 0 0 0\nv 1 0 0\n", vec![], |k| {
            matches!(k, K::NoTriangles(_))
        }),
        obj_case(
            "OBJ with a bad number",
            b"v 0 zero 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            vec![],
            |k| matches!(k, K::Obj(_)),
        ),
        obj_case(
            "OBJ with NaN coordinates",
            b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            vec![],
            |k| matches!(k, K::NoTriangles(d) if d.contains("NaN")),
        ),
    ];
    // Draco-compressed primitives: a truncated or corrupt stream, an attribute id the
    // stream does not have, accessors that disagree with the decoded data.
    let draco_primitive_0 =
        |k: &K| matches!(k, K::Draco { at, .. } if at.mesh == 0 && at.primitive == 0);
    cases.extend([
        draco_edited(
            "Draco stream truncated",
            |j, _| j["bufferViews"][0]["byteLength"] = json!(DRACO_TRIANGLE.len() - 20),
            draco_primitive_0,
        ),
        draco_edited(
            "Draco stream cut after its header",
            |j, _| j["bufferViews"][0]["byteLength"] = json!(12),
            draco_primitive_0,
        ),
        draco_edited(
            "Draco stream that is not Draco",
            |_, bin| bin[..5].copy_from_slice(b"OCARD"),
            draco_primitive_0,
        ),
        draco_edited(
            "Draco attribute id that does not exist",
            |j, _| {
                j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]
                    ["attributes"]["POSITION"] = json!(7)
            },
            |k| matches!(k, K::Draco { problem, .. } if problem.contains("id 7")),
        ),
        draco_edited(
            "Draco attribute the primitive does not have",
            |j, _| {
                j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]
                    ["attributes"]["NORMAL"] = json!(0)
            },
            draco_primitive_0,
        ),
        draco_edited(
            "Draco bufferView that does not exist",
            |j, _| {
                j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]
                    ["bufferView"] = json!(9)
            },
            draco_primitive_0,
        ),
        draco_edited(
            "Draco accessor count that differs from the stream",
            |j, _| j["accessors"][0]["count"] = json!(4),
            |k| matches!(k, K::Draco { problem, .. } if problem.contains("count 4")),
        ),
        draco_edited(
            "Draco accessor componentType that differs from the stream",
            |j, _| {
                j["extensionsUsed"] =
                    json!(["KHR_draco_mesh_compression", "KHR_mesh_quantization"]);
                j["accessors"][0]["componentType"] = json!(5123);
            },
            draco_primitive_0,
        ),
        draco_edited(
            "Draco indices count that differs from the stream",
            |j, _| j["accessors"][1]["count"] = json!(6),
            draco_primitive_0,
        ),
    ]);
    // Meshopt-compressed views: a wrong count, a truncated or lying stream, a
    // stream outside its buffer, a fallback buffer too large to allocate.
    let meshopt_view_0 = |k: &K| matches!(k, K::Meshopt { view: 0, .. });
    cases.extend([
        meshopt_edited(
            "meshopt view whose count disagrees with its byteLength",
            |j, _| j["bufferViews"][0]["extensions"]["KHR_meshopt_compression"]["count"] = json!(4),
            meshopt_view_0,
        ),
        meshopt_edited(
            "meshopt view with a wrong count that still fills the view",
            |j, _| {
                let ext = &mut j["bufferViews"][0]["extensions"]["KHR_meshopt_compression"];
                ext["count"] = json!(9);
                ext["byteStride"] = json!(4);
            },
            meshopt_view_0,
        ),
        meshopt_edited(
            "meshopt vertex stream truncated",
            |j, _| {
                let ext = &mut j["bufferViews"][0]["extensions"]["KHR_meshopt_compression"];
                ext["byteLength"] = json!(ext["byteLength"].as_u64().unwrap() - 8);
            },
            meshopt_view_0,
        ),
        meshopt_edited(
            "meshopt vertex stream overwritten with junk",
            |j, bin| {
                let len = j["bufferViews"][0]["extensions"]["KHR_meshopt_compression"]["byteLength"]
                    .as_u64()
                    .unwrap() as usize;
                bin[1..len].fill(0xff);
            },
            meshopt_view_0,
        ),
        meshopt_edited(
            "meshopt index stream truncated",
            |j, _| {
                let ext = &mut j["bufferViews"][1]["extensions"]["KHR_meshopt_compression"];
                ext["byteLength"] = json!(ext["byteLength"].as_u64().unwrap() - 4);
            },
            |k| matches!(k, K::Meshopt { view: 1, .. }),
        ),
        meshopt_edited(
            "meshopt stream past the end of its buffer",
            |j, _| {
                j["bufferViews"][0]["extensions"]["KHR_meshopt_compression"]["byteOffset"] =
                    json!(1000)
            },
            meshopt_view_0,
        ),
        meshopt_edited(
            "meshopt unknown mode",
            |j, _| {
                j["bufferViews"][0]["extensions"]["KHR_meshopt_compression"]["mode"] =
                    json!("VERTICES")
            },
            meshopt_view_0,
        ),
        meshopt_edited(
            "meshopt fallback buffer of 2^60 bytes",
            |j, _| j["buffers"][1]["byteLength"] = json!(1u64 << 60),
            |k| matches!(k, K::Buffer { buffer: 1, .. }),
        ),
    ]);
    // The missing-.bin case: the base with no tri.bin written.
    cases[18].files.truncate(1);
    // The file is missing: the buffer's error says so (`LoadError::missing_file`).
    cases[18].expect = |k| matches!(k, K::MissingFile { problem, .. } if matches!(**problem, K::Buffer { buffer: 0, .. }));
    cases
}

/// Cases whose only fault is an unusable image: errors under `--strict` (`LoadOptions::strict`),
/// warnings otherwise.
const TEXTURE_CASES: &[&str] = &[
    "missing image file",
    "image that is not an image",
    "image declaring 100000x100000 pixels",
    "KTX2 image declaring 60000x60000 pixels",
    "OBJ with a missing texture",
    "OBJ with a DDS texture declaring 65535x65535 texels",
    "OBJ with a DDS texture cut inside its header",
];

/// The case whose only fault is a missing material library: an error under `--strict`, a
/// warning otherwise (`a_missing_mtl_renders_grey_with_a_warning_and_strict_refuses_it`).
const MISSING_MTL_CASE: &str = "OBJ with a missing MTL";

fn strict() -> LoadOptions {
    LoadOptions {
        strict: true,
        ..Default::default()
    }
}

fn write_case(dir: &Path, case: &Case) {
    for (rel, bytes) in &case.files {
        let path = dir.join(rel);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, bytes).unwrap();
    }
}

#[test]
fn every_broken_file_gets_its_error_kind() {
    let mut failures = Vec::new();
    let cases = cases();
    for case in &cases {
        let dir = tempfile::tempdir().unwrap();
        let inner = dir.path().join("case");
        std::fs::create_dir(&inner).unwrap();
        write_case(&inner, case);
        let model = inner.join(&case.model);
        match Scene::load_with(&model, &strict()) {
            Ok(scene) => failures.push(format!(
                "{}: loaded ({} triangles)",
                case.name,
                scene.soup.len()
            )),
            Err(e) => {
                if !(case.expect)(&e.kind) {
                    failures.push(format!(
                        "{}: unexpected error kind: {e} ({:?})",
                        case.name, e.kind
                    ));
                }
                let message = e.to_string();
                let names_file = message.contains(&*model.to_string_lossy())
                    || e.path.parent() == Some(inner.as_path())
                        && message.contains(&*e.path.to_string_lossy());
                if !names_file {
                    failures.push(format!(
                        "{}: message does not name the file: {message}",
                        case.name
                    ));
                }
            }
        }
        if let Some(out) = std::env::var_os("MESHTRACER_WRITE_CORPUS") {
            let slug: String = case
                .name
                .chars()
                .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
                .collect();
            let target = Path::new(&out).join(slug);
            std::fs::create_dir_all(&target).unwrap();
            write_case(&target, case);
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
    assert!(cases.len() >= 60, "the corpus keeps its size");
}

#[test]
fn the_binary_exits_non_zero_with_one_message_naming_the_file() {
    for case in cases() {
        let dir = tempfile::tempdir().unwrap();
        write_case(dir.path(), &case);
        let model = dir.path().join(&case.model);
        let output = dir.path().join("out.png");
        let out = if TEXTURE_CASES.contains(&case.name) || case.name == MISSING_MTL_CASE {
            let args = ["render", "--strict", "-q", "--width", "8", "--height", "8"];
            let mut args = args.to_vec();
            args.extend([crate::common::s(&model), "-o", crate::common::s(&output)]);
            crate::common::run(&args, false)
        } else {
            crate::common::run(&["info", crate::common::s(&model)], false)
        };
        assert!(!output.exists(), "{}: no output is left", case.name);
        let err = crate::common::stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{}: {err}", case.name);
        assert!(!err.contains("panicked"), "{}: {err}", case.name);
        assert_eq!(
            err.trim_end().lines().count(),
            1,
            "{}: one line: {err}",
            case.name
        );
        assert!(
            err.contains(&*dir.path().to_string_lossy()),
            "{}: names the file: {err}",
            case.name
        );
    }
}

#[test]
fn a_broken_meshopt_view_is_named_with_its_file() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = meshopt_base();
    json["bufferViews"][1]["extensions"]["KHR_meshopt_compression"]["count"] = json!(6);
    json["bufferViews"][1]["byteLength"] = json!(12);
    write_case(dir.path(), &gltf_case("wrong count", json, bin, |_| true));
    let model = dir.path().join("model.gltf");
    let message = Scene::load(&model).unwrap_err().to_string();
    assert!(
        message.starts_with(&*model.to_string_lossy())
            && message.contains("bufferView 1 (KHR_meshopt_compression)"),
        "{message}"
    );
}

#[test]
fn a_broken_draco_primitive_is_named_with_its_file() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = draco_base();
    json["bufferViews"][0]["byteLength"] = json!(30);
    write_case(dir.path(), &gltf_case("truncated", json, bin, |_| true));
    let model = dir.path().join("model.gltf");
    let message = Scene::load(&model).unwrap_err().to_string();
    assert!(
        message.starts_with(&format!(
            "{}: mesh 0 primitive 0 (KHR_draco_mesh_compression): ",
            model.display()
        )),
        "{message}"
    );
}

#[test]
fn every_cut_or_corrupted_draco_stream_is_an_error_or_a_triangle() {
    // Every prefix of the stream, and every byte inverted: the decoder must refuse (a Draco
    // error naming the primitive) or decode something; a panic fails the test.
    let dir = tempfile::tempdir().unwrap();
    let mut variants: Vec<(String, Value, Vec<u8>)> = Vec::new();
    for cut in 0..DRACO_TRIANGLE.len() {
        let (mut json, bin) = draco_base();
        json["bufferViews"][0]["byteLength"] = json!(cut);
        variants.push((format!("cut at {cut}"), json, bin));
    }
    for at in 0..DRACO_TRIANGLE.len() {
        let (json, mut bin) = draco_base();
        bin[at] ^= 0xff;
        variants.push((format!("byte {at} inverted"), json, bin));
    }
    for (what, json, bin) in variants {
        write_case(dir.path(), &gltf_case("draco", json, bin, |_| true));
        match Scene::load(dir.path().join("model.gltf")) {
            Ok(scene) => assert!(scene.soup.len() <= 1, "{what}"),
            Err(e) => assert!(
                matches!(
                    e.kind,
                    K::Draco { .. } | K::NoTriangles(_) | K::TooManyTriangles { .. }
                ),
                "{what}: {e}"
            ),
        }
    }
}

#[test]
fn the_valid_bases_load() {
    let dir = tempfile::tempdir().unwrap();
    let (json, bin) = base();
    write_case(dir.path(), &gltf_case("base", json, bin, |_| true));
    assert_eq!(
        Scene::load(dir.path().join("model.gltf"))
            .unwrap()
            .soup
            .len(),
        1
    );
    std::fs::write(dir.path().join("model.glb"), glb()).unwrap();
    assert_eq!(
        Scene::load(dir.path().join("model.glb"))
            .unwrap()
            .soup
            .len(),
        1
    );
    // The meshopt-compressed triangle decodes to the plain one.
    let (json, bin) = meshopt_base();
    write_case(dir.path(), &gltf_case("meshopt", json, bin, |_| true));
    let meshopt = Scene::load(dir.path().join("model.gltf")).unwrap();
    let (json, bin) = base();
    write_case(dir.path(), &gltf_case("base", json, bin, |_| true));
    let plain = Scene::load(dir.path().join("model.gltf")).unwrap();
    let triangles = |s: &Scene| {
        (0..s.soup.len())
            .map(|t| s.soup.triangle(t))
            .collect::<Vec<_>>()
    };
    assert_eq!(triangles(&meshopt), triangles(&plain));
    // Also when the views decode into the buffer that holds the compressed bytes (after them).
    let (mut json, mut bin) = meshopt_base();
    let at = bin.len().next_multiple_of(4);
    bin.resize(at + 44, 0);
    json["buffers"] = json!([{"byteLength": bin.len(), "uri": "tri.bin"}]);
    for (view, offset) in [(0, at), (1, at + 36)] {
        json["bufferViews"][view]["buffer"] = json!(0);
        json["bufferViews"][view]["byteOffset"] = json!(offset);
    }
    write_case(
        dir.path(),
        &gltf_case("meshopt in place", json, bin, |_| true),
    );
    let in_place = Scene::load(dir.path().join("model.gltf")).unwrap();
    assert_eq!(triangles(&in_place), triangles(&plain));
    // So does the Draco-compressed one (its corners are exact under 11-bit quantization).
    let (json, bin) = draco_base();
    write_case(dir.path(), &gltf_case("draco", json, bin, |_| true));
    let draco = Scene::load(dir.path().join("model.gltf")).unwrap();
    assert_eq!(triangles(&draco), triangles(&plain));
    // A GLB named .gltf and a glTF named .glb still load: the content decides.
    std::fs::write(dir.path().join("swapped.gltf"), glb()).unwrap();
    assert_eq!(
        Scene::load(dir.path().join("swapped.gltf")).unwrap().format,
        meshtracer::scene::Format::Glb
    );
    // A 1-pixel texture is fine.
    let (mut json, bin) = base();
    with_image(&mut json, "one.png");
    write_case(dir.path(), &gltf_case("1px", json, bin, |_| true));
    std::fs::write(dir.path().join("one.png"), png_1x1()).unwrap();
    let scene = Scene::load(dir.path().join("model.gltf")).unwrap();
    assert_eq!(scene.images.len(), 1);
    // A hierarchy 100,000 nodes deep loads without exhausting the stack.
    let (mut json, bin) = base();
    let depth = 100_000;
    let mut nodes: Vec<Value> = (0..depth).map(|i| json!({"children": [i + 1]})).collect();
    nodes.push(json!({"mesh": 0, "translation": [1.0, 0.0, 0.0]}));
    json["nodes"] = json!(nodes);
    write_case(dir.path(), &gltf_case("deep", json, bin, |_| true));
    let scene = Scene::load(dir.path().join("model.gltf")).unwrap();
    assert_eq!(scene.bounds.min.x, 1.0);
}

#[test]
fn an_unusable_image_is_a_warning_without_strict() {
    let cases = cases();
    for name in TEXTURE_CASES {
        let case = cases.iter().find(|c| c.name == *name).expect("listed case");
        let dir = tempfile::tempdir().unwrap();
        write_case(dir.path(), case);
        let scene =
            Scene::load(dir.path().join(&case.model)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            scene
                .materials
                .iter()
                .all(|m| m.texture_refs().count() == 0),
            "{name}: the material falls back to its factors"
        );
        assert_eq!(scene.warnings.len(), 1, "{name}: {:?}", scene.warnings);
        assert!(
            scene.warnings[0].starts_with("image 0 (") && scene.warnings[0].contains("material"),
            "{name}: names the image and the material: {:?}",
            scene.warnings
        );
    }
}

/// The end-to-end promise: a glTF whose PNG is absent renders, warning once with the
/// image, the file and the material; `--strict` refuses it and writes nothing.
#[test]
fn a_missing_png_renders_with_a_warning_and_strict_refuses_it() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = base();
    with_image(&mut json, "missing.png");
    json["materials"][0]["name"] = json!("painted");
    json["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = json!([1.0, 0.0, 0.0, 1.0]);
    write_case(dir.path(), &gltf_case("missing png", json, bin, |_| true));
    let model = dir.path().join("model.gltf");
    let output = dir.path().join("out.png");
    let render = |extra: &[&str], ok: bool| {
        let mut args = vec![
            "render",
            crate::common::s(&model),
            "-o",
            crate::common::s(&output),
        ];
        args.extend([
            "--width",
            "16",
            "--height",
            "16",
            "--look-from",
            "0.3,0.3,2",
        ]);
        args.extend(["--look-at", "0.3,0.3,0"]);
        args.extend(extra);
        crate::common::run(&args, ok)
    };

    let out = render(&[], true);
    let err = crate::common::stderr(&out);
    let warnings: Vec<&str> = err.lines().filter(|l| l.contains("missing.png")).collect();
    assert_eq!(warnings.len(), 1, "one warning: {err}");
    let missing = dir.path().join("missing.png");
    for part in [
        "image 0",
        &*missing.to_string_lossy(),
        "material 'painted' (0)",
        &*model.to_string_lossy(),
    ] {
        assert!(warnings[0].contains(part), "names {part}: {err}");
    }
    // Drawn with its factor: the centre pixel is red.
    let (w, h, pixels) = crate::common::read_rgba(&output);
    let centre = pixels[(h / 2 * w + w / 2) as usize];
    assert!(
        centre[0] > 0.2 && centre[1] < 0.05 && centre[3] == 1.0,
        "{centre:?}"
    );

    strict_refuses(render, &output, "missing.png");
}

/// `render(&["--strict"], false)` (after a render without it wrote `output`) exits 1 naming
/// `missing` and `--strict`, and leaves no output file.
fn strict_refuses(
    render: impl Fn(&[&str], bool) -> std::process::Output,
    output: &Path,
    missing: &str,
) {
    std::fs::remove_file(output).unwrap();
    let out = render(&["--strict"], false);
    let err = crate::common::stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains(missing) && err.contains("--strict"), "{err}");
    assert!(!output.exists(), "--strict leaves no output file");
}

/// Many downloaded OBJs lack their .mtl: the model renders with the grey default material and
/// one warning naming the OBJ and the library, as a missing texture does; `--strict` refuses
/// it and writes nothing.
#[test]
fn a_missing_mtl_renders_grey_with_a_warning_and_strict_refuses_it() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("nomtl.obj");
    std::fs::write(
        &model,
        "mtllib nothere.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let output = dir.path().join("o.png");
    let render = |extra: &[&str], ok: bool| {
        let mut args = vec!["render", crate::common::s(&model), "-o"];
        args.extend([crate::common::s(&output), "--width", "16", "--height", "16"]);
        args.extend(["--look-from", "0.3,0.3,2", "--look-at", "0.3,0.3,0"]);
        args.extend(["--integrator", "direct"]);
        args.extend(extra);
        crate::common::run(&args, ok)
    };
    let out = render(&[], true);
    let err = crate::common::stderr(&out);
    let warnings: Vec<&str> = err.lines().filter(|l| l.contains("nothere.mtl")).collect();
    assert_eq!(warnings.len(), 1, "one warning: {err}");
    assert!(
        warnings[0].starts_with(&format!("warning: {}: MTL 'nothere.mtl'", model.display())),
        "names the OBJ and the MTL: {err}"
    );
    // Drawn with the grey default: the centre pixel is lit and neutral.
    let (w, h, pixels) = crate::common::read_rgba(&output);
    let centre = pixels[(h / 2 * w + w / 2) as usize];
    assert!(
        centre[3] == 1.0 && centre[0] > 0.05 && (centre[0] - centre[2]).abs() < 1e-3,
        "{centre:?}"
    );

    strict_refuses(render, &output, "nothere.mtl");
}

/// An image whose header reads but whose data does not decode fails later, when textures are
/// decoded: the same fallback and the same --strict refusal.
#[test]
fn an_undecodable_png_falls_back_when_textures_decode() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = base();
    with_image(&mut json, "empty.png");
    write_case(dir.path(), &gltf_case("undecodable", json, bin, |_| true));
    std::fs::write(dir.path().join("empty.png"), png_header(4, 4)).unwrap();
    renders_without_the_image_and_strict_refuses(
        dir.path(),
        "empty.png",
        &["image 0 (empty.png)", "material 0 drawn without it"],
    );
}

/// Renders `model.gltf` in `dir`, which succeeds with a warning holding each of `warning`;
/// then with `--strict`, which fails naming `image` and writes nothing.
fn renders_without_the_image_and_strict_refuses(dir: &Path, image: &str, warning: &[&str]) {
    let model = dir.join("model.gltf");
    let output = dir.join("out.png");
    let args = [
        "render",
        crate::common::s(&model),
        "-o",
        crate::common::s(&output),
        "--width",
        "8",
        "--height",
        "8",
    ];
    let out = crate::common::run(&args, true);
    let err = crate::common::stderr(&out);
    assert!(warning.iter().all(|part| err.contains(part)), "{err}");
    std::fs::remove_file(&output).unwrap();
    let mut strict_args = args.to_vec();
    strict_args.push("--strict");
    let out = crate::common::run(&strict_args, false);
    let err = crate::common::stderr(&out);
    assert!(err.contains(image), "{err}");
    assert!(!output.exists());
}

/// A KTX2 texture whose level claims 30 GB uncompressed (found by fuzzing: the transcoder
/// allocated it whole, and the process aborted on the failed allocation) is left out when
/// textures decode, with a warning that gives the claim; `--strict` refuses it.
#[test]
fn a_ktx2_level_claiming_30_gb_falls_back_when_textures_decode() {
    let dir = tempfile::tempdir().unwrap();
    let (mut json, bin) = base();
    with_image(&mut json, "huge.ktx2");
    write_case(dir.path(), &gltf_case("huge ktx2", json, bin, |_| true));
    let mut ktx2 = vec![
        0xAB, b'K', b'T', b'X', b' ', b'2', b'0', 0xBB, b'\r', b'\n', 0x1A, b'\n',
    ];
    // vkFormat, typeSize, 256x256, depth, layers, faces, levels, Zstandard supercompression.
    for word in [0u32, 1, 256, 256, 0, 0, 1, 1, 2] {
        ktx2.extend(word.to_le_bytes());
    }
    ktx2.extend([0u8; 32]);
    for field in [104u64, 16, 0x7_0001_0000] {
        ktx2.extend(field.to_le_bytes());
    }
    ktx2.extend([0u8; 16]);
    std::fs::write(dir.path().join("huge.ktx2"), ktx2).unwrap();
    renders_without_the_image_and_strict_refuses(
        dir.path(),
        "huge.ktx2",
        &["image 0 (huge.ktx2)", "claims 30064836608 bytes"],
    );
}

/// A square PNG of hashed noise (it does not compress), each texel `texel(hash)`.
fn noise_png(side: u32, texel: fn(u32) -> [u8; 4]) -> Vec<u8> {
    let mut png = Vec::new();
    image::RgbaImage::from_fn(side, side, |x, y| {
        let h =
            (x.wrapping_mul(2_654_435_761) ^ y.wrapping_mul(40_503)).wrapping_mul(2_246_822_519);
        image::Rgba(texel(h))
    })
    .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
    .unwrap();
    png
}

/// A BIN chunk: `floats`, then `image` from the returned offset, padded to 4 bytes.
fn bin_then_image(floats: &[f32], image: &[u8]) -> (Vec<u8>, usize) {
    let mut bin = crate::common::f32_bytes(floats);
    let image_at = bin.len();
    bin.extend(image);
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    (bin, image_at)
}

/// A GLB of one triangle and one embedded PNG of about 16 KB (noise, so that it stays that
/// large next to the JSON chunk), its BIN chunk padded with `padding` unused bytes.
fn glb_with_image(padding: usize) -> Vec<u8> {
    let png = noise_png(64, |h| h.to_le_bytes());
    let (mut bin, image_at) = bin_then_image(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], &png);
    bin.resize(bin.len() + padding, 0);
    let json = json!({
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": image_at, "byteLength": png.len()}
        ],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]}],
        "images": [{"bufferView": 1, "mimeType": "image/png"}],
        "textures": [{"source": 0}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "material": 0}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}]
    });
    crate::common::glb_bytes(&json, &bin)
}

/// An image that is most of its GLB shares the file's buffer instead of being copied out of
/// it; one that is a small part of it is copied, so that the rest of the file (geometry) is not
/// kept alive through the render. The same bytes either way.
#[test]
fn glb_images_share_the_file_only_when_they_are_most_of_it() {
    let dir = tempfile::tempdir().unwrap();
    for (padding, shared) in [(0, true), (64 << 10, false)] {
        let path = dir.path().join(format!("image-{padding}.glb"));
        let glb = glb_with_image(padding);
        std::fs::write(&path, &glb).unwrap();
        let scene = Scene::load(&path).unwrap();
        let bytes = scene.images[0].bytes.as_ref().expect("embedded bytes");
        assert!(bytes.starts_with(b"\x89PNG"), "padding {padding}");
        if shared {
            assert_eq!(bytes.held(), glb.len(), "the whole file, shared");
        } else {
            assert_eq!(bytes.held(), bytes.len(), "a copy of the image alone");
        }
    }
}

/// A GLB of one textured triangle whose 300x300 noise PNG (about 360 KB, enough to be left on
/// disk by the load) follows the triangle in the BIN chunk; `edit` changes the JSON first.
/// Returns the file and the PNG's bytes.
fn glb_with_big_image(edit: impl FnOnce(&mut Value)) -> (Vec<u8>, Vec<u8>) {
    let png = noise_png(300, |h| [h as u8, (h >> 8) as u8, (h >> 16) as u8, 255]);
    let (bin, image_at) = bin_then_image(
        &[
            -1.0, -1.0, 0.0, 1.0, -1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.5, 1.0,
        ],
        &png,
    );
    let mut json = json!({
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 24},
            {"buffer": 0, "byteOffset": image_at, "byteLength": png.len()}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
             "min": [-1.0, -1.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}
        ],
        "images": [{"bufferView": 2, "mimeType": "image/png"}],
        "textures": [{"source": 0}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1},
                                    "material": 0}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}]
    });
    edit(&mut json);
    (crate::common::glb_bytes(&json, &bin), png)
}

/// A big image that only images use stays on disk through the load, as exactly its own bytes
/// of the file, and renders as the same PNG beside a .gltf does. Anything else that may read
/// its bytes (an accessor, an extension's range, an overlapping view) keeps it in memory (a
/// Draco primitive's view: the unit test of `image_only_ranges`).
#[test]
fn glb_images_stay_on_disk_until_the_textures_are_decoded() {
    let dir = tempfile::tempdir().unwrap();
    let (glb, png) = glb_with_big_image(|_| {});
    let path = dir.path().join("big.glb");
    std::fs::write(&path, &glb).unwrap();
    let scene = Scene::load(&path).unwrap();
    let image = &scene.images[0];
    assert!(image.bytes.is_none(), "not read by the load");
    let part = image.in_file.as_ref().expect("left in the file");
    assert_eq!(part.path, path);
    let range = part.range.start as usize..part.range.end as usize;
    assert_eq!(&glb[range], &png[..], "exactly the image's bytes");
    assert_eq!(part.read(u64::MAX).unwrap(), png);

    // The same scene as a .gltf with the PNG beside it renders to the same bytes.
    let json_start = 20;
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let mut json: Value = serde_json::from_slice(&glb[json_start..json_start + json_len]).unwrap();
    let bin_start = json_start + json_len + 8;
    std::fs::write(dir.path().join("big.bin"), &glb[bin_start..]).unwrap();
    std::fs::write(dir.path().join("big.png"), &png).unwrap();
    json["buffers"][0]["uri"] = json!("big.bin");
    json["images"][0] = json!({"uri": "big.png"});
    let gltf = dir.path().join("big.gltf");
    std::fs::write(&gltf, serde_json::to_vec(&json).unwrap()).unwrap();
    let render = |model: &Path, out: &str| {
        let out = dir.path().join(out);
        let args = crate::common::small_run(
            "render",
            crate::common::s(model),
            crate::common::s(&out),
            ("64", "48"),
            "1",
            &[],
        );
        crate::common::run(&args, true);
        std::fs::read(out).unwrap()
    };
    assert_eq!(render(&path, "glb.png"), render(&gltf, "gltf.png"));

    type Edit = fn(&mut Value);
    let kept: [(&str, Edit); 3] = [
        ("an accessor on the image's view", |j| {
            j["accessors"]
                .as_array_mut()
                .unwrap()
                .push(json!({"bufferView": 2, "componentType": 5121, "count": 4, "type": "SCALAR"}))
        }),
        ("a view overlapping it", |j| {
            let at = j["bufferViews"][2]["byteOffset"].as_u64().unwrap();
            j["bufferViews"]
                .as_array_mut()
                .unwrap()
                .push(json!({"buffer": 0, "byteOffset": at + 100, "byteLength": 8}))
        }),
        ("an extension's range inside it", |j| {
            let at = j["bufferViews"][2]["byteOffset"].as_u64().unwrap();
            j["bufferViews"][0]["extensions"] =
                json!({"EXT_example": {"buffer": 0, "byteOffset": at + 8, "byteLength": 4}})
        }),
    ];
    for (what, edit) in kept {
        let (glb, png) = glb_with_big_image(edit);
        let path = dir.path().join("kept.glb");
        std::fs::write(&path, &glb).unwrap();
        let scene = Scene::load(&path).unwrap();
        let image = &scene.images[0];
        assert!(image.in_file.is_none(), "{what}");
        assert_eq!(image.bytes.as_deref(), Some(&png[..]), "{what}");
    }
}

/// An image left on disk that is gone or cut short when the textures are decoded is a warning
/// naming the file (the model draws with its factors), and with `--strict` an error.
#[test]
fn a_glb_cut_short_after_its_load_loses_only_its_image() {
    let dir = tempfile::tempdir().unwrap();
    let (glb, _) = glb_with_big_image(|_| {});
    let path = dir.path().join("cut.glb");
    std::fs::write(&path, &glb).unwrap();
    let scene = Scene::load(&path).unwrap();
    std::fs::write(&path, &glb[..glb.len() - 1000]).unwrap();
    let mut warnings = Vec::new();
    let set =
        meshtracer::prepare::textures::TextureSet::load(&scene, usize::MAX, false, &mut warnings);
    assert!(set.is_ok());
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("cut.glb") && w.contains("ends inside")),
        "{warnings:?}"
    );
    let strict =
        meshtracer::prepare::textures::TextureSet::load(&scene, usize::MAX, true, &mut Vec::new());
    assert!(strict.is_err());
}

/// A big GLB that the image-deferring read gives up on part way (a JSON chunk that does not
/// parse, a BIN chunk longer than the file, no BIN chunk) is read again whole: the load says
/// what the same bytes in memory say.
#[test]
fn a_big_glb_the_deferring_read_gives_up_on_is_reported_as_from_memory() {
    let dir = tempfile::tempdir().unwrap();
    let (glb, _) = glb_with_big_image(|_| {});
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let bin_header = 20 + json_len;
    type Cut = fn(&mut Vec<u8>, usize);
    let cases: [(&str, Cut); 3] = [
        ("JSON that does not parse", |g, _| g[20] = b'!'),
        ("a BIN chunk past the end", |g, at| {
            g[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes())
        }),
        ("no BIN chunk", |g, at| {
            g[at + 4..at + 8].copy_from_slice(b"XYZ\0")
        }),
    ];
    for (what, cut) in cases {
        let mut bytes = glb.clone();
        cut(&mut bytes, bin_header);
        let path = dir.path().join("odd.glb");
        std::fs::write(&path, &bytes).unwrap();
        let from_disk = Scene::load(&path)
            .map(|s| s.soup.len())
            .map_err(|e| e.to_string());
        let in_memory = Scene::from_bytes(&path, &bytes, &LoadOptions::default())
            .map(|s| s.soup.len())
            .map_err(|e| e.to_string());
        assert_eq!(from_disk, in_memory, "{what}");
        assert!(from_disk.is_err(), "{what}");
    }
}
