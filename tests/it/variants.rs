//! KHR_materials_variants: `--variant NAME` draws the variant's materials, `info` lists the
//! variants, and an unknown name is refused with the list of the file's variants.

use meshtracer::{LoadOptions, Scene};
use serde_json::json;
use std::path::PathBuf;

/// One triangle whose material is red by default and under "red", green under "green".
fn two_variant_triangle(dir: &std::path::Path) -> PathBuf {
    let mut bin = crate::common::f32_bytes(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    bin.extend([0u16, 1, 2].iter().flat_map(|i| i.to_le_bytes()));
    bin.extend([0, 0]);
    let json = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_materials_variants"],
        "extensions": {"KHR_materials_variants": {"variants": [{"name": "red"}, {"name": "green"}]}},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0}, "indices": 1, "material": 0,
            "extensions": {"KHR_materials_variants": {"mappings": [
                {"material": 0, "variants": [0]}, {"material": 1, "variants": [1]}
            ]}}
        }]}],
        "materials": [
            {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1]}},
            {"name": "green", "pbrMetallicRoughness": {"baseColorFactor": [0, 1, 0, 1]}}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 6}
        ]
    });
    crate::common::write_gltf(dir, "variants.gltf", json, &bin)
}

fn with_variant(name: &str) -> LoadOptions {
    LoadOptions {
        variant: Some(name.to_string()),
        ..Default::default()
    }
}

#[test]
fn a_variant_replaces_the_materials_it_maps() {
    let dir = tempfile::tempdir().unwrap();
    let model = two_variant_triangle(dir.path());
    let plain = Scene::load(&model).unwrap();
    assert_eq!(plain.variants, ["red", "green"]);
    assert_eq!(plain.soup.material, [0]);
    let green = Scene::load_with(&model, &with_variant("green")).unwrap();
    assert_eq!(green.soup.material, [1]);
    assert_eq!(green.variant.as_deref(), Some("green"));
    let red = Scene::load_with(&model, &with_variant("red")).unwrap();
    assert_eq!(red.soup.material, [0]);

    let message = Scene::load_with(&model, &with_variant("blue"))
        .unwrap_err()
        .to_string();
    for part in [&*model.to_string_lossy(), "'blue'", "'red', 'green'"] {
        assert!(message.contains(part), "names {part}: {message}");
    }

    // Through the binary: info lists them, render draws the chosen one.
    let out = crate::common::run(&["info", crate::common::s(&model)], true);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("variants    2") && text.contains("'red', 'green'"),
        "{text}"
    );
    let out = crate::common::run(&["info", "--json", crate::common::s(&model)], true);
    let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(info["variants"], json!(["red", "green"]));
    let output = dir.path().join("green.png");
    crate::common::run(
        &[
            "render",
            crate::common::s(&model),
            "-o",
            crate::common::s(&output),
            "--variant",
            "green",
            "--width",
            "16",
            "--height",
            "16",
            "--look-from",
            "0.3,0.3,2",
            "--look-at",
            "0.3,0.3,0",
            "-q",
        ],
        true,
    );
    let (w, h, pixels) = crate::common::read_rgba(&output);
    let centre = pixels[(h / 2 * w + w / 2) as usize];
    assert!(centre[1] > 0.2 && centre[0] < 0.05, "green: {centre:?}");
    let out = crate::common::run(
        &[
            "render",
            crate::common::s(&model),
            "-o",
            crate::common::s(&output),
            "--variant",
            "blue",
        ],
        false,
    );
    assert!(
        crate::common::stderr(&out).contains("'red', 'green'"),
        "{}",
        crate::common::stderr(&out)
    );
}

/// StainedGlassLamp: of the shared folders only glTF-KTX-BasisU declares the variants ("Lamp on",
/// "Lamp off"; glTF-JPG-PNG has none). The "on" materials glow.
#[test]
fn stained_glass_lamp_variants_draw_their_own_materials() {
    let Some(dir) = crate::common::samples("stained_glass_lamp_variants_draw_their_own_materials")
    else {
        return;
    };
    let model = dir.join("StainedGlassLamp/glTF-KTX-BasisU/StainedGlassLamp.gltf");
    // The mappings, read from the JSON independently of the importer.
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&model).unwrap()).unwrap();
    let expected = |variant: u64| -> std::collections::BTreeSet<u32> {
        let mut set = std::collections::BTreeSet::new();
        for mesh in json["meshes"].as_array().unwrap() {
            for p in mesh["primitives"].as_array().unwrap() {
                let mapped = p["extensions"]["KHR_materials_variants"]["mappings"]
                    .as_array()
                    .and_then(|m| {
                        m.iter()
                            .find(|m| m["variants"].as_array().unwrap().contains(&json!(variant)))
                    })
                    .map(|m| &m["material"]);
                set.insert(mapped.unwrap_or(&p["material"]).as_u64().unwrap() as u32);
            }
        }
        set
    };
    let drawn = |name: &str| -> std::collections::BTreeSet<u32> {
        let scene = Scene::load_with(&model, &with_variant(name)).unwrap();
        scene.soup.material.iter().copied().collect()
    };
    let (on, off) = (drawn("Lamp on"), drawn("Lamp off"));
    assert_eq!(on, expected(0));
    assert_eq!(off, expected(1));
    assert_ne!(on, off);

    let out_dir = tempfile::tempdir().unwrap();
    let render = |name: &str| {
        let output = out_dir.path().join(format!("{name}.png"));
        crate::common::run(
            &[
                "render",
                crate::common::s(&model),
                "-o",
                crate::common::s(&output),
                "--variant",
                name,
                "--width",
                "64",
                "--height",
                "64",
                "--spp",
                "1",
                "-q",
            ],
            true,
        );
        crate::common::read_rgba(&output).2
    };
    let (a, b) = (render("Lamp on"), render("Lamp off"));
    // Over the pixels the lamp covers (it fills about a quarter of the frame).
    let covered: Vec<(&[f32; 4], &[f32; 4])> = a
        .iter()
        .zip(&b)
        .filter(|(p, q)| p[3] > 0.0 || q[3] > 0.0)
        .collect();
    let mean_difference: f32 = covered
        .iter()
        .map(|(p, q)| (0..3).map(|c| (p[c] - q[c]).abs()).sum::<f32>() / 3.0)
        .sum::<f32>()
        / covered.len().max(1) as f32;
    eprintln!("StainedGlassLamp: mean |on - off| = {mean_difference:.4}");
    assert!(
        mean_difference > 0.01,
        "the variants look different: {mean_difference}"
    );
}
