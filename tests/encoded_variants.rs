//! Encoded sample variants (issue 14) render like their plain sibling from the same view: the
//! plain file is rendered with `--view-out`, the encoded one with `--view`, and `meshtracer
//! compare` measures coverage IoU and mean FLIP. Needs `MESHTRACER_SAMPLES`.

mod common;

use common::{run, s, samples};

/// Mesh encodings quantize positions and normals: an edge or a highlight may move slightly.
const MESH_MIN_IOU: f64 = 0.995;
const MESH_MAX_FLIP: f64 = 0.02;
/// Lossy texture encodings re-encode texels; the geometry is the same.
const TEXTURE_MAX_FLIP: f64 = 0.05;

/// (plain, encoded, largest mean FLIP allowed).
const PAIRS: &[(&str, &str, f64)] = &[
    (
        "Duck/glTF/Duck.gltf",
        "Duck/glTF-Quantized/Duck.gltf",
        MESH_MAX_FLIP,
    ),
    (
        "AnimatedMorphCube/glTF/AnimatedMorphCube.gltf",
        "AnimatedMorphCube/glTF-Quantized/AnimatedMorphCube.gltf",
        MESH_MAX_FLIP,
    ),
    (
        "Duck/glTF/Duck.gltf",
        "Duck/glTF-Meshopt/Duck.glb",
        MESH_MAX_FLIP,
    ),
    (
        "DamagedHelmet/glTF/DamagedHelmet.gltf",
        "DamagedHelmet/glTF-Meshopt/DamagedHelmet.glb",
        MESH_MAX_FLIP,
    ),
    (
        "Box/glTF/Box.gltf",
        "Box/glTF-Draco/Box.gltf",
        MESH_MAX_FLIP,
    ),
    (
        "Duck/glTF/Duck.gltf",
        "Duck/glTF-Draco/Duck.gltf",
        MESH_MAX_FLIP,
    ),
    (
        "CesiumMilkTruck/glTF/CesiumMilkTruck.gltf",
        "CesiumMilkTruck/glTF-Draco/CesiumMilkTruck.gltf",
        MESH_MAX_FLIP,
    ),
    (
        "RiggedSimple/glTF/RiggedSimple.gltf",
        "RiggedSimple/glTF-Draco/RiggedSimple.gltf",
        MESH_MAX_FLIP,
    ),
    (
        "CesiumMan/glTF/CesiumMan.gltf",
        "CesiumMan/glTF-Draco/CesiumMan.gltf",
        MESH_MAX_FLIP,
    ),
    (
        "Duck/glTF/Duck.gltf",
        "Duck/glTF-WebP/Duck.glb",
        TEXTURE_MAX_FLIP,
    ),
    (
        "BoxTextured/glTF/BoxTextured.gltf",
        "BoxTextured/glTF-WebP/BoxTextured.glb",
        TEXTURE_MAX_FLIP,
    ),
];

#[test]
fn encoded_variants_render_like_their_plain_sibling() {
    let Some(assets) = samples("encoded_variants_render_like_their_plain_sibling") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    let mut report = Vec::new();
    for (i, (plain, encoded, max_flip)) in PAIRS.iter().enumerate() {
        let view = dir.path().join(format!("{i}-view.json"));
        let a = dir.path().join(format!("{i}-plain.png"));
        let b = dir.path().join(format!("{i}-encoded.png"));
        let size = ["--width", "160", "--height", "120", "--spp", "4", "--quiet"];
        let plain_path = assets.join(plain);
        let encoded_path = assets.join(encoded);
        let mut args = vec![
            "render",
            s(&plain_path),
            "-o",
            s(&a),
            "--view-out",
            s(&view),
        ];
        args.extend(size);
        run(&args, true);
        let mut args = vec!["render", s(&encoded_path), "-o", s(&b), "--view", s(&view)];
        args.extend(size);
        run(&args, true);
        let strip = dir.path().join(format!("{i}-side-by-side.png"));
        let out = run(
            &[
                "compare",
                s(&a),
                s(&b),
                "--json",
                "--side-by-side",
                s(&strip),
            ],
            true,
        );
        let metrics: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let iou = metrics["coverage_iou"].as_f64().unwrap();
        let flip = metrics["flip"].as_f64().unwrap();
        report.push(format!(
            "{encoded}: coverage IoU {iou:.4}, mean FLIP {flip:.4}"
        ));
        if iou < MESH_MIN_IOU || flip > *max_flip {
            failures.push(format!(
                "{encoded}: IoU {iou:.4} (min {MESH_MIN_IOU}), FLIP {flip:.4} (max {max_flip}); see {}",
                strip.display()
            ));
        }
    }
    // Straight to stderr: the figures are part of the report (cargo test -- --nocapture).
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "{}", report.join("\n"));
    if !failures.is_empty() {
        // Keep the images for inspection.
        let kept = dir.keep();
        panic!(
            "{}\n(images kept in {})",
            failures.join("\n"),
            kept.display()
        );
    }
}
