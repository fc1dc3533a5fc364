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
    write_triangle_buffer(&outside.join("secret.bin"));
    std::os::unix::fs::symlink(outside.join("secret.bin"), model_dir.join("tri.bin")).unwrap();
    let model = model_dir.join("model.gltf");
    write_triangle_model(&model, "tri.bin");
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

/// One triangle's 36 bytes of positions (and four of padding).
fn write_triangle_buffer(path: &std::path::Path) {
    let mut bin = crate::common::f32_bytes(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    bin.extend([0u8; 4]);
    std::fs::write(path, &bin).unwrap();
}

/// A glTF of one triangle whose positions are in the buffer at `uri`.
fn write_triangle_model(path: &std::path::Path, uri: &str) {
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "buffers": [{"byteLength": 36, "uri": uri}]
    });
    std::fs::write(path, serde_json::to_vec(&json).unwrap()).unwrap();
}

/// A model linked into another folder (`ln -s ~/downloads/box/box.gltf models/`) finds its
/// buffer beside the linked file when the link's folder has none; a file beside the link comes
/// first; and the linked file's folder confines URIs as the model's own folder does.
#[test]
fn a_linked_model_reads_its_files_beside_the_linked_file() {
    let dir = tempfile::tempdir().unwrap();
    let (real, links) = (dir.path().join("real"), dir.path().join("links"));
    std::fs::create_dir_all(&real).unwrap();
    std::fs::create_dir_all(&links).unwrap();
    write_triangle_buffer(&real.join("tri.bin"));
    write_triangle_model(&real.join("model.gltf"), "tri.bin");
    let link = links.join("model.gltf");
    std::os::unix::fs::symlink(real.join("model.gltf"), &link).unwrap();
    let scene = Scene::load(&link).expect("the buffer beside the linked file");
    assert_eq!(scene.soup.len(), 1);
    run(&["info", s(&link)], true);

    // A buffer beside the link is the one read: here a short one, refused for its length.
    std::fs::write(links.join("tri.bin"), [0u8; 8]).unwrap();
    let err = Scene::load(&link).expect_err("the link's own folder comes first");
    assert!(err.to_string().contains("found 8"), "{err}");
    std::fs::remove_file(links.join("tri.bin")).unwrap();

    // Climbing out of the linked file's folder stays refused.
    write_triangle_buffer(&dir.path().join("secret.bin"));
    write_triangle_model(&real.join("model.gltf"), "../secret.bin");
    let err = Scene::load(&link).expect_err("`..` leaves the folder");
    assert!(
        matches!(err.kind, LoadErrorKind::ExternalFile { .. }),
        "{err}"
    );
}

/// Ctrl-C (SIGINT), and the signals a scheduler or a closed terminal sends (SIGTERM: a Slurm
/// time limit or `scancel`, a Kubernetes pod deleted; SIGHUP), stop a render the same way:
/// exit 130, the previous output kept, no temporary file left.
#[test]
fn a_signal_during_a_render_keeps_the_previous_output() {
    for signal in ["INT", "TERM", "HUP"] {
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
        send(&child, signal);
        let output = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(130), "SIG{signal}: {err}");
        assert!(err.contains("interrupted"), "SIG{signal}: {err}");
        assert_eq!(std::fs::read(&out).unwrap(), b"previous image");
        let names = crate::common::file_names(dir.path());
        assert_eq!(
            names.len(),
            1,
            "SIG{signal}: no temporary file left: {names:?}"
        );
    }
}

/// A flat square grid of `n` x `n` cells (2n² triangles) in the unit square, as OBJ text.
fn grid_obj(n: usize) -> String {
    let mut obj = String::new();
    for j in 0..=n {
        for i in 0..=n {
            obj += &format!("v {} {} 0\n", i as f32 / n as f32, j as f32 / n as f32);
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i + 1;
            let (b, c, d) = (a + 1, a + n + 1, a + n + 2);
            obj += &format!("f {a} {b} {d}\nf {a} {d} {c}\n");
        }
    }
    obj
}

/// A signal that comes while the model is still loading stops the render as one during the
/// render does (exit 130, no temporary file, the previous output kept) for a single image and
/// for views, instead of killing the process beside the output file it had reserved. The
/// signal is sent as soon as the temporary file exists, which is made before the load.
#[test]
fn a_signal_during_the_load_leaves_no_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    // A 250,000-triangle grid (8 MB of OBJ text): its parse and BVH build take a while.
    let obj = grid_obj(354);
    let model = dir.path().join("grid.obj");
    std::fs::write(&model, obj).unwrap();
    for (many, signal) in [(false, "TERM"), (true, "TERM"), (false, "INT")] {
        let out = dir.path().join("out");
        std::fs::create_dir_all(&out).unwrap();
        let image = out.join("image.png");
        std::fs::write(&image, b"previous image").unwrap();
        let mut command = crate::common::bin();
        command.args(["render", s(&model), "--spp", "64", "--quiet"]);
        if many {
            command.args(["--views", "orbit:4", "-o", s(&out.join("views"))]);
            command.args(["--contact-sheet", s(&out.join("sheet.png"))]);
        } else {
            command.args(["-o", s(&image)]);
        }
        let mut child = command
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        crate::common::wait_until(&mut child, "a temporary file", || {
            crate::common::file_names(&out)
                .iter()
                .any(|n| n.to_string_lossy().starts_with(".meshtracer-"))
        });
        send(&child, signal);
        let output = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&output.stderr);
        let what = format!("SIG{signal}, views {many}");
        assert_eq!(output.status.code(), Some(130), "{what}: {err}");
        assert_eq!(std::fs::read(&image).unwrap(), b"previous image");
        let mut names: Vec<String> = crate::common::file_names(&out)
            .into_iter()
            .map(|n| n.to_string_lossy().into_owned())
            .collect();
        names.sort();
        // The views' folder, made before the load and still empty, is gone too.
        assert_eq!(names, ["image.png"], "{what}: no temporary file left");
        std::fs::remove_dir_all(&out).unwrap();
    }
}

/// A signal the render was started ignoring stays ignored: `nohup` ignores SIGHUP (closing
/// the terminal must not stop the render), and a shell starts a background job with SIGINT
/// ignored. The render, signalled once it has begun, finishes and writes its image.
#[test]
fn a_signal_ignored_at_start_stays_ignored() {
    use std::os::unix::process::CommandExt;
    for (signal, number) in [("HUP", libc::SIGHUP), ("INT", libc::SIGINT)] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("image.png");
        let model = crate::common::root().join("assets/cornell-box.gltf");
        let mut command = crate::common::bin();
        command
            .args(["render", s(&model), "-o", s(&out), "--quiet"])
            .args(["--width", "320", "--height", "240", "--spp", "64"])
            .stderr(std::process::Stdio::piped());
        // SAFETY: between fork and exec the closure only calls signal(2), which is
        // async-signal-safe.
        unsafe {
            command.pre_exec(move || {
                libc::signal(number, libc::SIG_IGN);
                Ok(())
            });
        }
        let mut child = command.spawn().unwrap();
        // Signalled once the render is under way: its output file is reserved by then.
        let start = std::time::Instant::now();
        while crate::common::file_names(dir.path()).is_empty() {
            assert!(
                child.try_wait().unwrap().is_none(),
                "ended before the signal"
            );
            assert!(start.elapsed().as_secs() < 60, "no output reserved in 60 s");
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        send(&child, signal);
        let output = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(0), "SIG{signal}: {err}");
        let (w, h, _) = crate::common::read_rgba(&out);
        assert_eq!((w, h), (320, 240), "SIG{signal}");
    }
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
        .chain(std::iter::once("rendered.jsonl".to_string()))
        .collect();
    expected.sort();
    assert_eq!(names, expected, "{err}");
    // Each view written is recorded, for --resume.
    let record = std::fs::read_to_string(out.join("rendered.jsonl")).unwrap();
    assert_eq!(record.lines().count(), reported, "{record}");
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
        // Once in the measurements table (name, ray kind, then its 1,024 triangles); the
        // build-steps table names it again.
        assert_eq!(
            text.matches("| generated 1000 | primary | 1024 |").count(),
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

/// A second Ctrl-C quits at once, and removes the folder a zipped model was unpacked into
/// (quitting at once runs no destructors, so the scene holding it is never dropped).
#[test]
fn a_second_ctrl_c_leaves_no_unpacked_archive() {
    let dir = tempfile::tempdir().unwrap();
    // A 200,000-triangle grid, whose linear scan takes seconds.
    let obj = grid_obj(316);
    let archive = dir.path().join("grid.zip");
    let mut zip = zip::ZipWriter::new(std::fs::File::create(&archive).unwrap());
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    zip.start_file("grid/grid.obj", options).unwrap();
    std::io::Write::write_all(&mut zip, obj.as_bytes()).unwrap();
    zip.finish().unwrap();
    let temporary = dir.path().join("tmp");
    std::fs::create_dir(&temporary).unwrap();
    let unpacked = || crate::common::file_names(&temporary);
    let mut child = crate::common::bin()
        .args(["bench", s(&archive), "--sizes="])
        .env("TMPDIR", &temporary)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Signalled while the archive is unpacked and the bench measures the model.
    let start = std::time::Instant::now();
    while unpacked().is_empty() {
        assert!(child.try_wait().unwrap().is_none(), "bench ended early");
        assert!(start.elapsed().as_secs() < 60, "nothing unpacked in 60 s");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    std::thread::sleep(std::time::Duration::from_millis(300));
    interrupt(&child);
    std::thread::sleep(std::time::Duration::from_millis(200));
    interrupt(&child);
    let output = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(130), "{err}");
    assert!(err.contains("no output written"), "{err}");
    assert_eq!(unpacked(), Vec::<std::ffi::OsString>::new(), "{err}");
}

/// Sends SIGINT (what Ctrl-C sends) to a child process.
fn interrupt(child: &std::process::Child) {
    send(child, "INT");
}

/// Sends the signal `SIG<name>` to a child process.
pub(crate) fn send(child: &std::process::Child, name: &str) {
    let kill = std::process::Command::new("kill")
        .args([&format!("-{name}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
}

/// `info` and `render` (into `out`) of each model of `cases`, run by `run`: exit 1 and one
/// message naming the model and its problem; nothing written.
fn assert_each_refused(
    cases: &[(&std::path::Path, &str)],
    out: &std::path::Path,
    run: fn(&[&str]) -> (Option<i32>, String),
) {
    for &(model, problem) in cases {
        for command in ["info", "render"] {
            let mut args = vec![command, s(model)];
            if command == "render" {
                args.extend(["-o", s(out), "-q"]);
            }
            let (code, err) = run(&args);
            assert_eq!(code, Some(1), "{args:?}: {err}");
            assert!(
                err.contains(s(model)) && err.contains(problem),
                "{args:?}: {err}"
            );
            assert_eq!(err.lines().count(), 1, "one message: {err}");
        }
    }
    assert!(!out.exists(), "nothing written");
}

/// Runs the binary with `args`, and fails the test if it is still running after 20 s (what a
/// FIFO read used to do forever): returns its exit code and standard error.
fn run_bounded(args: &[&str]) -> (Option<i32>, String) {
    run_bounded_program(env!("CARGO_BIN_EXE_meshtracer"), args)
}

/// [`run_bounded`] for any program.
fn run_bounded_program(program: &str, args: &[&str]) -> (Option<i32>, String) {
    use std::io::Read;
    let mut child = std::process::Command::new(program)
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("the binary starts");
    let start = std::time::Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            let mut err = String::new();
            let _ = child.stderr.take().map(|mut e| e.read_to_string(&mut err));
            return (status.code(), err);
        }
        if start.elapsed() > std::time::Duration::from_secs(20) {
            let _ = child.kill();
            panic!("{program} {} did not finish in 20 s", args.join(" "));
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// A named pipe at `path` (nothing ever writes to it: opening it for reading blocks).
fn fifo(path: &std::path::Path) {
    let name = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path; mkfifo only creates a file system entry.
    assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o600) }, 0, "mkfifo");
}

/// A FIFO or a character device as the model, as a buffer or as an image is refused at once
/// with one message that names it and what it is (a FIFO once hung forever, `/dev/zero` took
/// 2 GiB to say "out of memory"); `info` and `render` alike, and a batch fails that job only.
#[test]
fn fifos_and_devices_are_refused_before_they_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.png");
    let pipe = dir.path().join("pipe.glb");
    fifo(&pipe);
    let cases = [
        (pipe.as_path(), "a FIFO"),
        (std::path::Path::new("/dev/zero"), "a character device"),
    ];
    assert_each_refused(&cases, &out, run_bounded);

    // A buffer and an image that are FIFOs, in the model's own folder.
    let buffer = dir.path().join("tri.bin");
    fifo(&buffer);
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "buffers": [{"byteLength": 36, "uri": "tri.bin"}]
    });
    let model = dir.path().join("buffer-fifo.gltf");
    std::fs::write(&model, serde_json::to_vec(&json).unwrap()).unwrap();
    let (code, err) = run_bounded(&["render", s(&model), "-o", s(&out), "-q"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("tri.bin") && err.contains("a FIFO"), "{err}");
    // Named as the model refers to it: the model, then the buffer and its URI.
    assert!(
        err.contains("buffer-fifo.gltf: buffer 0 URI 'tri.bin' names a FIFO"),
        "{err}"
    );

    let image = dir.path().join("texture.png");
    fifo(&image);
    let (json, bin) = crate::common::quads_gltf(
        &[(crate::common::square(0.5, 0.0), 0)],
        serde_json::json!({
            "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
            "textures": [{"source": 0}],
            "images": [{"uri": "texture.png"}]
        }),
    );
    let model = crate::common::write_gltf(dir.path(), "image-fifo.gltf", json, &bin);
    let (code, err) = run_bounded(&["render", s(&model), "-o", s(&out), "-q", "--strict"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("texture.png") && err.contains("a FIFO"),
        "{err}"
    );
    // An empty URI and a folder where an image should be are said to be what they are.
    for (uri, needle) in [
        ("", "image 0 URI '' is empty: it names no file"),
        ("folder.png", "folder.png' is a folder, not a file"),
    ] {
        std::fs::create_dir_all(dir.path().join("folder.png")).unwrap();
        let (json, bin) = crate::common::quads_gltf(
            &[(crate::common::square(0.5, 0.0), 0)],
            serde_json::json!({
                "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
                "textures": [{"source": 0}],
                "images": [{"uri": uri}]
            }),
        );
        let model = crate::common::write_gltf(dir.path(), "odd-uri.gltf", json, &bin);
        let (_, err) = run_bounded(&["render", s(&model), "-o", s(&out), "-q", "--strict"]);
        assert!(err.contains(needle), "{uri:?}: {err}");
    }

    // A batch naming the FIFO as a job's model: that job fails, the other is rendered.
    let (json, bin) = crate::common::quads_gltf(
        &[(crate::common::square(0.5, 0.0), 0)],
        serde_json::json!({"materials": [{}]}),
    );
    crate::common::write_gltf(dir.path(), "ok.gltf", json, &bin);
    let manifest = dir.path().join("jobs.jsonl");
    std::fs::write(
        &manifest,
        "{\"id\": \"pipe\", \"model\": \"pipe.glb\"}\n{\"id\": \"ok\", \"model\": \"ok.gltf\"}\n",
    )
    .unwrap();
    let batch_out = dir.path().join("batch");
    let (code, err) = run_bounded(&[
        "batch",
        s(&manifest),
        "-o",
        s(&batch_out),
        "-q",
        "--width",
        "16",
        "--height",
        "12",
    ]);
    assert_eq!(code, Some(1), "{err}");
    let results = std::fs::read_to_string(batch_out.join("results.jsonl")).unwrap();
    let job = |id: &str| {
        results
            .lines()
            .find(|l| l.contains(&format!("\"id\":\"{id}\"")))
            .unwrap_or_else(|| panic!("job {id} in {results}"))
            .to_string()
    };
    let pipe_job = job("pipe");
    assert!(
        pipe_job.contains("\"failed\"") && pipe_job.contains("a FIFO"),
        "{pipe_job}"
    );
    assert!(job("ok").contains("\"ok\""), "{results}");
}

/// `run_bounded` under `ulimit -v` of 1 GiB (through `sh`): an allocation past it fails, so
/// a command that would read or allocate a file's declared size aborts, or errors, there.
fn run_under_1_gib(args: &[&str]) -> (Option<i32>, String) {
    let script = "ulimit -v 1048576 && exec \"$0\" \"$@\"";
    let bin = env!("CARGO_BIN_EXE_meshtracer");
    run_bounded_program("sh", &[&["-c", script, bin], args].concat())
}

/// A GLB of `bin_len` bytes of binary chunk declaring `vertices` float positions in one
/// primitive, written sparse (the file system stores none of the zeros).
fn declared_glb(path: &std::path::Path, vertices: u64, bin_len: u64) {
    use std::io::Write;
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": vertices, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 1.0]}],
        "bufferViews": [{"buffer": 0, "byteLength": bin_len}],
        "buffers": [{"byteLength": bin_len}]
    });
    let mut head = crate::common::glb_bytes(&json, &[]);
    let total = head.len() as u64 + bin_len;
    head[8..12].copy_from_slice(&(total as u32).to_le_bytes());
    let at = head.len() - 8;
    head[at..at + 4].copy_from_slice(&(bin_len as u32).to_le_bytes());
    let mut file = std::fs::File::create(path).unwrap();
    file.write_all(&head).unwrap();
    file.set_len(total).unwrap();
}

/// Under a 1 GiB address-space limit every hostile size gives one clean error naming the file
/// (never an abort on allocation, never a read of the whole file): a GLB of 2 GB declaring 170
/// million vertices, from its JSON, for `info` and `render` alike; a 1.9 GB file of zeros, from
/// its first bytes; a FIFO and `/dev/zero`. A buffer file far larger than its `byteLength` is
/// read to the `byteLength` only, so the model it belongs to loads.
#[test]
fn declared_and_actual_sizes_are_checked_before_they_are_allocated() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.png");
    let huge = dir.path().join("huge.glb");
    declared_glb(&huge, 170_000_000, 2_040_000_000);
    let zeros = dir.path().join("zeros.glb");
    std::fs::File::create(&zeros)
        .unwrap()
        .set_len(1900 << 20)
        .unwrap();
    let pipe = dir.path().join("pipe.gltf");
    fifo(&pipe);
    let dev_zero = std::path::Path::new("/dev/zero");
    let cases = [
        (
            huge.as_path(),
            "declares 170000000 vertices, over the limit of 150000000",
        ),
        (zeros.as_path(), "unknown format"),
        (pipe.as_path(), "a FIFO"),
        (dev_zero, "a character device"),
    ];
    assert_each_refused(&cases, &out, run_under_1_gib);

    // A quad's bytes at the start of a 1.9 GB buffer file.
    let (json, bin) = crate::common::quads_gltf(
        &[(crate::common::square(0.5, 0.0), 0)],
        serde_json::json!({"materials": [{}]}),
    );
    let mut json = json;
    json["buffers"] = serde_json::json!([{"byteLength": bin.len(), "uri": "big.bin"}]);
    let mut file = std::fs::File::create(dir.path().join("big.bin")).unwrap();
    std::io::Write::write_all(&mut file, &bin).unwrap();
    file.set_len(1900 << 20).unwrap();
    let model = dir.path().join("big-buffer.gltf");
    std::fs::write(&model, serde_json::to_vec(&json).unwrap()).unwrap();
    // Small: the point is the read, not the render's time.
    let small = ["--width", "64", "--height", "48", "--spp", "4"];
    let (code, err) =
        run_under_1_gib(&[&["render", s(&model), "-o", s(&out), "-q"][..], &small].concat());
    assert_eq!(code, Some(0), "{err}");
    assert!(out.exists());
}
