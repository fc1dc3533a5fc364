//! The `.npy` AOVs as NumPy itself reads them, and NumPy's own `.npy` files as the tile
//! merger reads them (src/output/npy.rs writes and reads the format by hand; this is its check).
//!
//! Needs a Python with NumPy: `MESHTRACER_PYRENDER_PYTHON` (the pyrender environment that
//! `.ci/run` makes has it) or `python3`; skips with a notice when neither imports numpy.

use crate::common::{root, run, s};
use std::path::PathBuf;
use std::process::Command;

/// A Python that imports numpy, if there is one.
fn numpy_python() -> Option<PathBuf> {
    let candidates = std::env::var_os("MESHTRACER_PYRENDER_PYTHON")
        .map(PathBuf::from)
        .into_iter()
        .chain([PathBuf::from("python3")]);
    for python in candidates {
        let ok = Command::new(&python)
            .args(["-c", "import numpy"])
            .output()
            .is_ok_and(|o| o.status.success());
        if ok {
            return Some(python);
        }
    }
    None
}

/// Loads each file with `numpy.load`, saves it again with `numpy.save` beside it
/// (`NAME.numpy.npy`) and prints one line a file: dtype, shape, and the C-order bytes in hex.
const SCRIPT: &str = r#"
import sys, numpy as np
for path in sys.argv[1:]:
    a = np.load(path, allow_pickle=False)
    np.save(path[:-4] + ".numpy.npy", a)
    print(a.dtype.str, ",".join(map(str, a.shape)), np.ascontiguousarray(a).tobytes().hex())
"#;

#[test]
fn numpy_reads_the_aovs_and_the_merger_reads_numpys_files() {
    let Some(python) = numpy_python() else {
        use std::io::Write;
        // Straight to stderr: the test harness captures eprintln! of a passing test.
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED numpy_reads_the_aovs_and_the_merger_reads_numpys_files: no Python with numpy (set MESHTRACER_PYRENDER_PYTHON, scripts/reference/README.md)"
        );
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let file = |name: &str| dir.path().join(name);
    run(
        &[
            "render",
            s(&root().join("assets/shapes.obj")),
            "-o",
            s(&file("beauty.png")),
            "--width",
            "24",
            "--height",
            "16",
            "--spp",
            "1",
            "-q",
            "--depth-out",
            s(&file("depth.npy")),
            "--normal-out",
            s(&file("normal.npy")),
            "--mask-out",
            s(&file("mask.npy")),
            "--segmentation-out",
            s(&file("segmentation.npy")),
        ],
        true,
    );
    let names = ["depth", "normal", "mask", "segmentation"];
    let paths: Vec<PathBuf> = names.iter().map(|n| file(&format!("{n}.npy"))).collect();
    let out = Command::new(&python)
        .args(["-c", SCRIPT])
        .args(&paths)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 4, "{text}");
    let expected = [
        ("<f4", "16,24"),
        ("<f4", "16,24,3"),
        ("<f4", "16,24"),
        ("<u4", "16,24"),
    ];
    for ((name, path), (line, (dtype, shape))) in
        names.iter().zip(&paths).zip(lines.iter().zip(expected))
    {
        let ours = meshtracer::output::npy::decode(&std::fs::read(path).unwrap()).unwrap();
        let fields: Vec<&str> = line.split(' ').collect();
        assert_eq!(
            (fields[0], fields[1]),
            (dtype, shape),
            "{name}: what numpy read"
        );
        let hex: String = ours.data.iter().map(|b| format!("{b:02x}")).collect();
        assert_eq!(
            fields[2], hex,
            "{name}: numpy's elements are the ones written"
        );
        // NumPy's own file of the same array (its padding, its header) reads back the same.
        let theirs = std::fs::read(file(&format!("{name}.numpy.npy"))).unwrap();
        assert_eq!(
            meshtracer::output::npy::decode(&theirs).unwrap(),
            ours,
            "{name}"
        );
    }
    // The AOVs are not all empty: the depth has finite values where the mask covers.
    let mask = meshtracer::output::npy::decode(&std::fs::read(&paths[2]).unwrap()).unwrap();
    assert!(mask
        .data
        .chunks(4)
        .any(|c| f32::from_le_bytes(c.try_into().unwrap()) > 0.5));
}
