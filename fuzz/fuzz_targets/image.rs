#![no_main]
//! Fuzzes the image decoders (PNG, JPEG, WebP, KTX2 with Basis Universal) and the load's image
//! header checks with the input as the one texture of a textured triangle in a GLB.
//!
//! The `glb` target reaches the decoders only where a mutation lands inside an embedded image
//! of a seed, and its seeds are small models whose images are small; here every input is an
//! image. The texture is declared as the input's leading bytes suggest (KTX2 through
//! `KHR_texture_basisu`, RIFF through `EXT_texture_webp`, else PNG or JPEG by MIME type), so
//! each decoder is reached through the path a real file takes.

use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;

/// A GLB holding one triangle textured with `image`.
fn glb_with_image(image: &[u8]) -> Vec<u8> {
    let mut bin: Vec<u8> = Vec::new();
    for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    for v in [0.0f32, 1.0, 1.0, 1.0, 0.0, 0.0] {
        bin.extend_from_slice(&v.to_le_bytes());
    }
    bin.extend_from_slice(image);
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let (mime, texture, used) = if image.starts_with(b"\xABKTX 20") {
        (
            "image/ktx2",
            r#"{"extensions": {"KHR_texture_basisu": {"source": 0}}}"#,
            r#", "extensionsUsed": ["KHR_texture_basisu"], "extensionsRequired": ["KHR_texture_basisu"]"#,
        )
    } else if image.starts_with(b"RIFF") {
        (
            "image/webp",
            r#"{"extensions": {"EXT_texture_webp": {"source": 0}}}"#,
            r#", "extensionsUsed": ["EXT_texture_webp"], "extensionsRequired": ["EXT_texture_webp"]"#,
        )
    } else if image.starts_with(b"\xFF\xD8") {
        ("image/jpeg", r#"{"source": 0}"#, "")
    } else {
        ("image/png", r#"{"source": 0}"#, "")
    };
    let json = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
"nodes": [{{"mesh": 0}}],
"meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}}, "material": 0}}]}}],
"materials": [{{"pbrMetallicRoughness": {{"baseColorTexture": {{"index": 0}}}}}}],
"textures": [{texture}],
"images": [{{"bufferView": 2, "mimeType": "{mime}"}}],
"accessors": [
 {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
 {{"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}}],
"bufferViews": [
 {{"buffer": 0, "byteOffset": 0, "byteLength": 36}},
 {{"buffer": 0, "byteOffset": 36, "byteLength": 24}},
 {{"buffer": 0, "byteOffset": 60, "byteLength": {len}}}],
"buffers": [{{"byteLength": {total}}}]{used}}}"#,
        len = image.len(),
        total = bin.len(),
    );
    let mut json = json.into_bytes();
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut glb = Vec::with_capacity(total);
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(total as u32).to_le_bytes());
    glb.extend_from_slice(&(json.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&json);
    glb.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"BIN\0");
    glb.extend_from_slice(&bin);
    glb
}

fuzz_target!(|data: &[u8]| common::load("model.glb", &glb_with_image(data)));
