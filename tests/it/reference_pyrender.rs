//! meshtracer against pyrender from the same VIEW.json: coverage and depth must agree.
//!
//! Needs the shared samples and a Python with pyrender (`MESHTRACER_PYRENDER_PYTHON`, which
//! `.ci/run` sets after installing it as `scripts/reference/README.md` describes); skipped with a
//! notice otherwise. Coverage compares the hit masks of the two depth maps (pixel-centre rays on
//! both sides, so anti-aliased edges do not count) and must reach IoU 0.99; depth, where both
//! hit, must agree to a median relative error of 1%.

use crate::common::{run, s, samples};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Reads a float32 .npy (C order) as numpy.save writes it.
fn read_npy_f32(path: &Path) -> Vec<f32> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(&bytes[..6], b"\x93NUMPY", "{}", path.display());
    let (header_len, start) = if bytes[6] == 1 {
        (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10)
    } else {
        (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        )
    };
    let header = std::str::from_utf8(&bytes[start..start + header_len]).unwrap();
    assert!(
        header.contains("'<f4'") && header.contains("'fortran_order': False"),
        "{header}"
    );
    bytes[start + header_len..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

fn python() -> Option<PathBuf> {
    let python = std::env::var_os("MESHTRACER_PYRENDER_PYTHON").map(PathBuf::from);
    let usable = python.as_ref().is_some_and(|p| {
        std::process::Command::new(p)
            .args([
                "-c",
                "import os; os.environ.setdefault('PYOPENGL_PLATFORM', 'osmesa'); import pyrender",
            ])
            .output()
            .is_ok_and(|o| o.status.success())
    });
    if !usable {
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED pyrender comparison: set MESHTRACER_PYRENDER_PYTHON to a Python with pyrender (scripts/reference/README.md)"
        );
        return None;
    }
    python
}

#[test]
fn meshtracer_and_pyrender_agree_on_coverage_and_depth() {
    let Some(samples) = samples("meshtracer_and_pyrender_agree_on_coverage_and_depth") else {
        return;
    };
    let Some(python) = python() else { return };
    let script = crate::common::root().join("scripts/reference/pyrender_render.py");
    let dir = tempfile::tempdir().unwrap();
    // A file camera, file lights, and neither (automatic camera and default rig).
    for model in [
        "Duck/glTF/Duck.gltf",
        "LightsPunctualLamp/glTF/LightsPunctualLamp.gltf",
        "StanfordBunny-OBJ/stanford-bunny.obj",
    ] {
        let path = samples.join(model);
        let view = dir.path().join("view.json");
        let ours = dir.path().join("ours.npy");
        let theirs = dir.path().join("theirs.npy");
        run(
            &[
                "render",
                s(&path),
                "-o",
                s(&dir.path().join("ours.png")),
                "--width",
                "160",
                "--height",
                "120",
                "--spp",
                "1",
                "--integrator",
                "direct",
                "--quiet",
                "--view-out",
                s(&view),
                "--depth-out",
                s(&ours),
            ],
            true,
        );
        let out = std::process::Command::new(&python)
            .env("PYOPENGL_PLATFORM", "osmesa")
            .args([
                s(&script),
                s(&view),
                s(&path),
                s(&dir.path().join("theirs.png")),
                "--depth-out",
                s(&theirs),
            ])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{model}: pyrender failed:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let (a, b) = (read_npy_f32(&ours), read_npy_f32(&theirs));
        assert_eq!(a.len(), b.len());
        let both = a
            .iter()
            .zip(&b)
            .filter(|(x, y)| **x > 0.0 && **y > 0.0)
            .count();
        let either = a
            .iter()
            .zip(&b)
            .filter(|(x, y)| **x > 0.0 || **y > 0.0)
            .count();
        let iou = both as f64 / either.max(1) as f64;
        let mut rel: Vec<f32> = a
            .iter()
            .zip(&b)
            .filter(|(x, y)| **x > 0.0 && **y > 0.0)
            .map(|(x, y)| (x - y).abs() / y)
            .collect();
        rel.sort_by(f32::total_cmp);
        let median = rel.get(rel.len() / 2).copied().unwrap_or(f32::INFINITY);
        eprintln!("{model}: coverage IoU {iou:.4}, median relative depth error {median:.2e}");
        assert!(both > 100, "{model}: the model is in view ({both} pixels)");
        assert!(iou >= 0.99, "{model}: coverage IoU {iou}");
        assert!(
            median <= 0.01,
            "{model}: median relative depth error {median}"
        );
    }
}
