//! Zip archives and folders through the binary: a zipped download (a model and the files it
//! references in a folder, with macOS's resource forks beside them) renders byte for byte as
//! its unzipped files do and is named as `ARCHIVE/PATH` inside; so does the folder it unzips
//! to; an archive or a folder without exactly one model is refused with one message naming
//! it, and nothing is written.

use crate::common::{run, s, stderr};
use std::io::Write;
use std::path::Path;

/// Writes a zip at `path` of `(name in the archive, bytes)`.
pub(crate) fn write_zip(path: &Path, entries: &[(&str, Vec<u8>)]) {
    let file = std::fs::File::create(path).expect("zip file");
    let mut zip = zip::ZipWriter::new(file);
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    for (name, bytes) in entries {
        zip.start_file(*name, options).expect("entry");
        zip.write_all(bytes).expect("entry bytes");
    }
    zip.finish().expect("zip written");
}

#[test]
fn a_zipped_download_renders_as_its_files_do() {
    let dir = tempfile::tempdir().unwrap();
    let assets = crate::common::root().join("assets");
    let read = |name: &str| std::fs::read(assets.join(name)).unwrap();
    let archive = dir.path().join("shapes.zip");
    write_zip(
        &archive,
        &[
            ("shapes/shapes.obj", read("shapes.obj")),
            ("shapes/shapes.mtl", read("shapes.mtl")),
            ("__MACOSX/shapes/._shapes.obj", b"resource fork".to_vec()),
        ],
    );
    let render = |model: &Path, out: &Path| {
        let args = ["--width", "64", "--height", "48", "--spp", "2", "-q"];
        let mut all = vec!["render", s(model), "-o", s(out)];
        all.extend(args);
        run(&all, true);
        std::fs::read(out).unwrap()
    };
    let plain = render(&assets.join("shapes.obj"), &dir.path().join("plain.png"));
    let zipped = render(&archive, &dir.path().join("zipped.png"));
    assert!(
        plain == zipped,
        "the archive renders differently from its files"
    );
    // The summary names the file drawn, inside the archive.
    let out_png = dir.path().join("summary.png");
    let args = ["--width", "8", "--height", "6", "--spp", "1"];
    let mut all = vec!["render", s(&archive), "-o", s(&out_png)];
    all.extend(args);
    let summary = stderr(&run(&all, true));
    let inside = format!("{}: ", archive.join("shapes/shapes.obj").display());
    assert!(summary.starts_with(&inside), "{summary}");
    let out = run(&["info", s(&archive), "--json"], true);
    let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let file = info["file"].as_str().unwrap();
    assert!(file.ends_with("shapes.zip/shapes/shapes.obj"), "{file}");
    let names: Vec<&str> = info["material_list"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|m| m["name"].as_str())
        .collect();
    assert_eq!(
        names,
        ["ground", "blue", "gold"],
        "the MTL beside it was read"
    );
}

#[test]
fn an_archive_without_exactly_one_model_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out_png = dir.path().join("out.png");
    for (name, entries, problem) in [
        (
            "two.zip",
            vec![("a.glb", b"x".to_vec()), ("b/c.obj", b"x".to_vec())],
            "zip archive: holds 2 models ('a.glb', 'b/c.obj'): unzip it and render one",
        ),
        (
            "none.zip",
            vec![("readme.txt", b"x".to_vec())],
            "zip archive: holds no .gltf, .glb or .obj file",
        ),
        // An empty archive starts with its end record, not an entry's header.
        (
            "empty.zip",
            vec![],
            "zip archive: holds no .gltf, .glb or .obj file",
        ),
        // The only model would be unpacked outside the archive's folder: refused as that, not
        // as an archive without a model.
        (
            "up.zip",
            vec![("../evil.gltf", b"{}".to_vec()), ("evil.bin", b"x".to_vec())],
            "zip archive: its model entry '../evil.gltf' is refused: its path leaves the archive (absolute, or through '..')",
        ),
        (
            "root.zip",
            vec![("/tmp/evil.glb", b"x".to_vec())],
            "zip archive: its model entry '/tmp/evil.glb' is refused: its path leaves the archive (absolute, or through '..')",
        ),
        (
            "escape.zip",
            vec![("m.obj", b"v 0 0 0".to_vec()), ("../up.mtl", b"x".to_vec())],
            "zip archive: entry '../up.mtl' would be written outside the archive's folder",
        ),
    ] {
        let archive = dir.path().join(name);
        write_zip(&archive, &entries);
        let out = run(&["render", s(&archive), "-o", s(&out_png), "-q"], false);
        let err = stderr(&out);
        assert_eq!(
            err.trim(),
            format!("meshtracer: error: {}: {problem}", archive.display()),
            "{name}"
        );
        assert!(!out_png.exists(), "{name}: nothing written");
        // The archive is unpacked under the system's temporary folder: `../up.mtl` would land
        // there.
        assert!(!std::env::temp_dir().join("up.mtl").exists());
    }
    // A model whose buffer the zip lacks: named as the file names it, inside the archive, not
    // by the temporary folder it was unpacked into.
    let gltf = serde_json::json!({"asset": {"version": "2.0"},
        "buffers": [{"uri": "mesh.bin", "byteLength": 36}]});
    let archive = dir.path().join("nobin.zip");
    write_zip(&archive, &[("m.gltf", gltf.to_string().into_bytes())]);
    let err = stderr(&run(
        &["render", s(&archive), "-o", s(&out_png), "-q"],
        false,
    ));
    assert!(
        err.contains("nobin.zip/m.gltf: buffer 0: cannot read 'mesh.bin'"),
        "{err}"
    );
    assert!(!err.contains("meshtracer-zip-"), "{err}");
}

#[test]
fn a_folder_holding_one_model_renders_as_the_model_does() {
    let dir = tempfile::tempdir().unwrap();
    let assets = crate::common::root().join("assets");
    let download = dir.path().join("download");
    std::fs::create_dir_all(download.join("shapes")).unwrap();
    std::fs::create_dir_all(download.join("__MACOSX")).unwrap();
    for name in ["shapes.obj", "shapes.mtl"] {
        std::fs::copy(assets.join(name), download.join("shapes").join(name)).unwrap();
    }
    std::fs::write(download.join("__MACOSX/._shapes.obj"), b"fork").unwrap();
    std::fs::write(download.join(".hidden.obj"), b"v 0 0 0").unwrap();
    let (from_folder, from_file) = (dir.path().join("folder.png"), dir.path().join("file.png"));
    for (model, out) in [
        (&download, &from_folder),
        (&assets.join("shapes.obj"), &from_file),
    ] {
        run(
            &[
                "render",
                s(model),
                "-o",
                s(out),
                "--width",
                "64",
                "--height",
                "48",
                "--spp",
                "2",
                "-q",
            ],
            true,
        );
    }
    assert!(std::fs::read(&from_folder).unwrap() == std::fs::read(&from_file).unwrap());
    // The bundled assets folder holds three models: all named, nothing written.
    let out_png = dir.path().join("none.png");
    let out = run(&["render", s(&assets), "-o", s(&out_png), "-q"], false);
    assert_eq!(
        stderr(&out).trim(),
        format!(
            "meshtracer: error: {}: folder: holds 3 models ('cornell-box.gltf', 'pendulum.gltf', 'shapes.obj'): name the one to render",
            assets.display()
        )
    );
    assert!(!out_png.exists());
}

#[test]
fn a_zip_inside_the_zip_and_an_encrypted_entry_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let inner = dir.path().join("inner.zip");
    write_zip(&inner, &[("m.obj", b"v 0 0 0".to_vec())]);
    let nested = dir.path().join("nested.zip");
    write_zip(&nested, &[("model.glb", std::fs::read(&inner).unwrap())]);
    // An entry marked encrypted (bit 0 of the general-purpose flags, in its local header and
    // in the central directory), as a password-protected download's are.
    let locked = dir.path().join("locked.zip");
    write_zip(&locked, &[("m.obj", b"v 0 0 0".to_vec())]);
    let mut bytes = std::fs::read(&locked).unwrap();
    let at = |signature: &[u8]| bytes.windows(4).position(|w| w == signature).unwrap();
    let (local, central) = (at(b"PK\x03\x04") + 6, at(b"PK\x01\x02") + 8);
    bytes[local] |= 1;
    bytes[central] |= 1;
    std::fs::write(&locked, &bytes).unwrap();
    let out_png = dir.path().join("out.png");
    // The archive given, the file the error names, and the problem.
    for (given, named, problem) in [
        (
            &nested,
            nested.join("model.glb"),
            "zip archive: a zip archive inside the archive",
        ),
        (
            &locked,
            locked.clone(),
            "zip archive: entry 0: unsupported Zip archive: Password required to decrypt file",
        ),
    ] {
        let out = run(&["render", s(given), "-o", s(&out_png), "-q"], false);
        let err = stderr(&out);
        let expected = format!("meshtracer: error: {}: {problem}", named.display());
        assert_eq!(err.trim(), expected);
        assert!(!out_png.exists());
    }
}
