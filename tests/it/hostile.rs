//! What a hostile environment must not achieve: reading files outside the model's folder
//! through a symlink, or losing the user's previous output to an interrupted render.

use crate::common::{run, s};
use meshtracer::{LoadErrorKind, Scene};

#[test]
fn a_symlink_out_of_the_model_folder_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let outside = dir.path().join("outside");
    let model_dir = dir.path().join("model");
    std::fs::create_dir_all(&outside).unwrap();
    std::fs::create_dir_all(&model_dir).unwrap();
    // A real triangle buffer, kept outside; the model folder only has a link to it.
    let mut bin = crate::common::f32_bytes(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    bin.extend([0u8; 4]);
    std::fs::write(outside.join("secret.bin"), &bin).unwrap();
    std::os::unix::fs::symlink(outside.join("secret.bin"), model_dir.join("tri.bin")).unwrap();
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "buffers": [{"byteLength": 36, "uri": "tri.bin"}]
    });
    let model = model_dir.join("model.gltf");
    std::fs::write(&model, serde_json::to_vec(&json).unwrap()).unwrap();
    let err = Scene::load(&model).expect_err("the link leaves the folder");
    assert!(
        matches!(err.kind, LoadErrorKind::ExternalFile { .. }),
        "{err}"
    );
    let out = run(&["info", s(&model)], false);
    assert!(crate::common::stderr(&out).contains("--allow-external-files"));
    // The user can allow it.
    run(&["info", s(&model), "--allow-external-files"], true);
}

#[test]
fn ctrl_c_during_a_render_keeps_the_previous_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("image.png");
    std::fs::write(&out, b"previous image").unwrap();
    let model = crate::common::root().join("assets/cornell-box.gltf");
    // Far more work than can finish before the signal: 4096x3072 at 64 spp.
    let child = crate::common::bin()
        .args([
            "render",
            s(&model),
            "-o",
            s(&out),
            "--width",
            "4096",
            "--spp",
            "64",
            "--quiet",
        ])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    interrupt(&child);
    let output = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted"), "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), b"previous image");
    let names = crate::common::file_names(dir.path());
    assert_eq!(names.len(), 1, "no temporary file left: {names:?}");
}

/// Ctrl-C during a multi-view render: every view reported done is on disk whole (image, depth,
/// view file), nothing else is left (no partial image of the interrupted view, no temporary
/// file, no transforms.json), and the exit is 130 with a message saying how many views were
/// written.
#[test]
fn ctrl_c_during_views_keeps_the_finished_views_whole() {
    use std::io::{BufRead, Read};
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("views");
    let model = crate::common::root().join("assets/cornell-box.gltf");
    let depth = out.join("{view:03}.depth.exr");
    let mut child = crate::common::bin()
        .args(["render", s(&model), "--views", "orbit:500", "-o", s(&out)])
        .args(["--width", "160", "--height", "120", "--spp", "16"])
        .args(["--depth-out", s(&depth)])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut err = String::new();
    while !err.contains("[3/") {
        assert!(
            stderr.read_line(&mut err).unwrap() > 0,
            "render ended early: {err}"
        );
    }
    interrupt(&child);
    stderr.read_to_string(&mut err).unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{err}");
    let reported = err.matches("rendered in").count();
    assert!(
        err.contains(&format!("{reported} of 500 views written")),
        "{err}"
    );
    let mut names: Vec<String> = crate::common::file_names(&out)
        .into_iter()
        .map(|n| n.to_string_lossy().into_owned())
        .collect();
    names.sort();
    let mut expected: Vec<String> = (0..reported)
        .flat_map(|k| {
            [
                format!("{k:03}.png"),
                format!("{k:03}.depth.exr"),
                format!("{k:03}.view.json"),
            ]
        })
        .collect();
    expected.sort();
    assert_eq!(names, expected, "{err}");
    for k in 0..reported {
        let (w, h, _) = crate::common::read_rgba(&out.join(format!("{k:03}.png")));
        assert_eq!((w, h), (160, 120));
        image::open(out.join(format!("{k:03}.depth.exr"))).unwrap();
    }
}

/// Starts `meshtracer bench` with `args`, waits until its second measurement has begun (waiting
/// only for the first one's report raced the loop's stop check: CI once saw "1 of 3"), sends
/// it `interrupts` SIGINTs (200 ms apart) and returns its exit code, stdout and stderr.
fn interrupt_bench(args: &[&str], interrupts: usize) -> (Option<i32>, String, String) {
    use std::io::{BufRead, Read};
    let mut child = crate::common::bin()
        .arg("bench")
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut err = String::new();
    while !err.contains("[2/") {
        assert!(
            stderr.read_line(&mut err).unwrap() > 0,
            "bench ended early: {err}"
        );
    }
    for i in 0..interrupts {
        if i > 0 {
            std::thread::sleep(std::time::Duration::from_millis(200));
        }
        interrupt(&child);
    }
    stderr.read_to_string(&mut err).unwrap();
    let output = child.wait_with_output().unwrap();
    let out = String::from_utf8_lossy(&output.stdout).into_owned();
    (output.status.code(), out, err)
}

/// Ctrl-C during a benchmark finishes the measurement under way (1M triangles: over a second),
/// skips the rest, prints and writes what is done, says it stopped early and exits 130.
#[test]
fn ctrl_c_stops_a_benchmark_with_its_finished_measurements() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("report.md");
    let args = ["--sizes", "1000,1000000,1000", "--linear-budget", "0"];
    let (code, out, err) = interrupt_bench(
        &[
            &args[..],
            &["--side", "64", "--runs", "1", "--report", s(&report)],
        ]
        .concat(),
        1,
    );
    assert_eq!(code, Some(130), "{err}");
    assert!(
        err.contains("stopped early: 2 of 3 measurements reported"),
        "{err}"
    );
    for text in [&out, &std::fs::read_to_string(&report).unwrap()] {
        assert!(text.contains("| generated 1000000 |"), "{text}");
        // Once in the measurements table (name, then its 1,024 triangles); the build-steps
        // table names it again.
        assert_eq!(
            text.matches("| generated 1000 | 1024 |").count(),
            1,
            "{text}"
        );
        assert!(text.contains("stopped early: 2 of 3"), "{text}");
    }
}

/// A second Ctrl-C quits at once, in the middle of a long linear scan, and writes nothing
/// (a single one would have finished the scan and written the report).
#[test]
fn a_second_ctrl_c_quits_a_benchmark_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("report.md");
    let (code, _, err) = interrupt_bench(&["--sizes", "1000,1000000", "--report", s(&report)], 2);
    assert_eq!(code, Some(130), "{err}");
    assert!(err.contains("no output written"), "{err}");
    assert!(!report.exists(), "no report after quitting");
    assert!(crate::common::file_names(dir.path()).is_empty());
}

/// Sends SIGINT (what Ctrl-C sends) to a child process.
fn interrupt(child: &std::process::Child) {
    let kill = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
}
