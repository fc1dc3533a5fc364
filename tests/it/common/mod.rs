//! Helpers for integration tests: run the real binary, find the sample models, read images.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The compiled `meshtracer` binary ([`program`]).
pub fn bin() -> Command {
    program(env!("CARGO_BIN_EXE_meshtracer"))
}

/// A command that starts with SIGINT, SIGTERM and SIGHUP at their default dispositions,
/// whatever the test runner's are. meshtracer keeps ignoring a signal it was started ignoring
/// (as `nohup`, and a shell starting a background job, ask), so under a runner started in the
/// background (SIGINT ignored) every Ctrl-C test would wait for a render that never stops. A
/// test that wants a signal ignored sets it in its own `pre_exec`, which runs after this one.
pub fn program(path: impl AsRef<std::ffi::OsStr>) -> Command {
    let mut command = Command::new(path);
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt;
        // SAFETY: between fork and exec the closure only calls signal(2), which is
        // async-signal-safe.
        unsafe {
            command.pre_exec(|| {
                for signal in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
                    libc::signal(signal, libc::SIG_DFL);
                }
                Ok(())
            });
        }
    }
    command
}

/// Waits, polling, until `ready` holds while `child` still runs: for a test to signal a run
/// part way (`what` names the moment awaited). Panics if the run ends first or after 2 minutes.
pub fn wait_until(child: &mut std::process::Child, what: &str, ready: impl Fn() -> bool) {
    let start = std::time::Instant::now();
    while !ready() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended before {what}"
        );
        assert!(start.elapsed().as_secs() < 120, "no {what} in 2 minutes");
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
}

/// Render options heavy enough that a test can stop a run of several renders part way: 96x72,
/// 8 spp, path traced (about 60 ms for the bundled box in a debug build on 2 cores).
pub const STOPPABLE: [&str; 8] = [
    "--width",
    "96",
    "--height",
    "72",
    "--spp",
    "8",
    "--integrator",
    "path",
];

/// Runs the binary; on an unexpected outcome, panics with the command, stdout and stderr.
pub fn run(args: &[&str], expect_success: bool) -> Output {
    let out = bin().args(args).output().expect("the binary runs");
    if out.status.success() != expect_success {
        panic!(
            "meshtracer {}\nexpected success = {expect_success}, got {}\n--- stdout\n{}\n--- stderr\n{}",
            args.join(" "),
            out.status,
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    out
}

/// Appends to `args` the direct integrator and the standard (clipping) view transform, each
/// unless `extra` names its own: the settings most tests' expectations are written for (the
/// default render, the path tracer through Khronos PBR Neutral, has tests of its own).
pub fn direct_unless_named<'a>(args: &mut Vec<&'a str>, extra: &[&'a str]) {
    if !extra.contains(&"--integrator") {
        args.extend(["--integrator", "direct"]);
    }
    if !extra.contains(&"--tonemap") {
        args.extend(["--tonemap", "standard"]);
    }
}

/// The arguments of `meshtracer COMMAND INPUT -o OUT` at `width` x `height` and `spp`
/// samples per pixel, quietly, with [`direct_unless_named`], followed by `extra`: the small,
/// fast run most tests want.
pub fn small_run<'a>(
    command: &'a str,
    input: &'a str,
    out: &'a str,
    (width, height): (&'a str, &'a str),
    spp: &'a str,
    extra: &[&'a str],
) -> Vec<&'a str> {
    let mut args = vec![
        command, input, "-o", out, "--width", width, "--height", height, "--spp", spp, "-q",
    ];
    direct_unless_named(&mut args, extra);
    args.extend_from_slice(extra);
    args
}

/// Runs the binary with its standard output and standard error each a pipe whose reader has
/// gone before the first line (as `2>&1 | head -0` leaves them): every write to either fails
/// with a broken pipe. Returns how the run ended.
pub fn run_with_readers_gone(args: &[&str]) -> std::process::ExitStatus {
    let mut child = bin()
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("the binary runs");
    drop(child.stdout.take());
    drop(child.stderr.take());
    child.wait().expect("the binary ends")
}

/// Standard error as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The shared sample models (`MESHTRACER_SAMPLES`), or `None` with a printed notice.
pub fn samples(test: &str) -> Option<PathBuf> {
    match std::env::var_os("MESHTRACER_SAMPLES") {
        Some(dir) if Path::new(&dir).is_dir() => Some(PathBuf::from(dir)),
        _ => {
            // Straight to stderr: the test harness captures eprintln! of passing tests.
            use std::io::Write;
            let _ = writeln!(
                std::io::stderr(),
                "SKIPPED {test}: set MESHTRACER_SAMPLES to the shared sample models folder"
            );
            None
        }
    }
}

/// The repository root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A path as a &str (test paths are UTF-8).
pub fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8 path")
}

/// Reads an image as linear-or-not f32 RGBA exactly as stored (PNG: 8-bit values / 255;
/// EXR: linear floats).
pub fn read_rgba(path: &Path) -> (u32, u32, Vec<[f32; 4]>) {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgba32f();
    let (w, h) = img.dimensions();
    (w, h, img.pixels().map(|p| p.0).collect())
}

/// Rewrites every diffuse colour (`Kd`) of the MTL file at `path` to green: a material
/// library changed after a render.
pub fn recolour_mtl(path: &Path) {
    let text = std::fs::read_to_string(path).unwrap();
    let recoloured: String = text
        .lines()
        .map(|l| match l.starts_with("Kd ") {
            true => "Kd 0.1 0.9 0.1\n".to_string(),
            false => format!("{l}\n"),
        })
        .collect();
    assert_ne!(recoloured, text, "{} has a Kd", path.display());
    std::fs::write(path, recoloured).unwrap();
}

/// Writes a glTF JSON document with one embedded buffer built from `bin` as `dir/name`, and
/// returns its path.
pub fn write_gltf(dir: &Path, name: &str, mut json: serde_json::Value, bin: &[u8]) -> PathBuf {
    use base64::Engine;
    json["buffers"] = serde_json::json!([{
        "byteLength": bin.len(),
        "uri": format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(bin))
    }]);
    let path = dir.join(name);
    std::fs::write(&path, serde_json::to_string_pretty(&json).unwrap()).unwrap();
    path
}

/// A GLB container: `json` in its JSON chunk (padded with spaces) and `bin` as its BIN chunk
/// (the caller pads it to 4 bytes).
pub fn glb_bytes(json: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut text = serde_json::to_vec(json).unwrap();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let total = 12 + 8 + text.len() + 8 + bin.len();
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((text.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&text);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

/// Little-endian bytes of f32s.
pub fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A PNG as a `data:` URI.
pub fn png_data_uri(img: &image::RgbaImage) -> String {
    use base64::Engine;
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .unwrap();
    format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// A glTF scene of quads (each with TEXCOORD_0 spanning the unit square): each quad is (4 corners CCW from the front, material index). Returns
/// the JSON (without buffers) and the binary data. `extra` is merged into the top level.
pub fn quads_gltf(
    quads: &[([[f32; 3]; 4], usize)],
    extra: serde_json::Value,
) -> (serde_json::Value, Vec<u8>) {
    let mut bin = Vec::new();
    let mut accessors = Vec::new();
    let mut views = Vec::new();
    let mut meshes = Vec::new();
    let mut nodes = Vec::new();
    for (i, (corners, material)) in quads.iter().enumerate() {
        let flat: Vec<f32> = corners.iter().flatten().copied().collect();
        let bytes = f32_bytes(&flat);
        views.push(
            serde_json::json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len()}),
        );
        bin.extend(bytes);
        let min: Vec<f32> = (0..3)
            .map(|k| corners.iter().map(|c| c[k]).fold(f32::INFINITY, f32::min))
            .collect();
        let max: Vec<f32> = (0..3)
            .map(|k| {
                corners
                    .iter()
                    .map(|c| c[k])
                    .fold(f32::NEG_INFINITY, f32::max)
            })
            .collect();
        accessors.push(serde_json::json!({"bufferView": views.len() - 1, "componentType": 5126, "count": 4, "type": "VEC3", "min": min, "max": max}));
        // TEXCOORD_0: u along corner 0 -> 1, v from corner 3 (v = 0, top) to corner 0 (v = 1).
        let uv = f32_bytes(&[0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0]);
        views.push(
            serde_json::json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": uv.len()}),
        );
        bin.extend(uv);
        accessors.push(serde_json::json!({"bufferView": views.len() - 1, "componentType": 5126, "count": 4, "type": "VEC2"}));
        let indices: Vec<u8> = [0u16, 1, 2, 0, 2, 3]
            .iter()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        views.push(
            serde_json::json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": indices.len()}),
        );
        bin.extend(indices);
        accessors.push(serde_json::json!({"bufferView": views.len() - 1, "componentType": 5123, "count": 6, "type": "SCALAR"}));
        meshes.push(serde_json::json!({"primitives": [{"attributes": {"POSITION": 3 * i, "TEXCOORD_0": 3 * i + 1}, "indices": 3 * i + 2, "material": material}]}));
        nodes.push(serde_json::json!({"mesh": i}));
    }
    let mut json = serde_json::json!({
        "asset": {"version": "2.0"},
        "accessors": accessors,
        "bufferViews": views,
        "meshes": meshes,
        "nodes": nodes,
    });
    if let serde_json::Value::Object(extra) = extra {
        for (k, v) in extra {
            if k == "nodes" {
                let list = json["nodes"].as_array_mut().unwrap();
                list.extend(v.as_array().unwrap().iter().cloned());
            } else {
                json[k] = v;
            }
        }
    }
    let count = json["nodes"].as_array().unwrap().len();
    json["scenes"] = serde_json::json!([{"nodes": (0..count).collect::<Vec<_>>()}]);
    json["scene"] = serde_json::json!(0);
    (json, bin)
}

/// The shadow scene of the renderer and material tests: a 6 x 6 ground quad at z = 0 (material
/// 0) and a 1 x 1 occluder 1 above its centre (material `occluder`), under a 2 lux directional
/// light travelling along (1, 0, -1), so that the occluder's shadow covers x in [0.5, 1.5],
/// |y| < 0.5. An orthographic camera 5 above looks straight down and frames the ground exactly.
/// Every length is multiplied by `scale`; `extra` (materials, textures...) is merged into the
/// top level.
pub fn shadow_scene(
    scale: f32,
    occluder: usize,
    extra: serde_json::Value,
) -> (serde_json::Value, Vec<u8>) {
    let quad = |half: f32, z: f32| square(half * scale, z * scale);
    let travel = glam::Vec3::new(1.0, 0.0, -1.0).normalize();
    let rotation = glam::Quat::from_rotation_arc(glam::Vec3::NEG_Z, travel);
    let mut top = serde_json::json!({
        "cameras": [{"type": "orthographic", "orthographic": {
            "xmag": 3.0 * scale, "ymag": 3.0 * scale, "znear": 0.01 * scale, "zfar": 100.0 * scale}}],
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 2.0}]}},
        "nodes": [
            {"camera": 0, "translation": [0.0, 0.0, 5.0 * scale]},
            {"rotation": rotation.to_array(), "extensions": {"KHR_lights_punctual": {"light": 0}}}
        ]
    });
    if let serde_json::Value::Object(extra) = extra {
        for (k, v) in extra {
            top[k] = v;
        }
    }
    quads_gltf(&[(quad(3.0, 0.0), 0), (quad(0.5, 1.0), occluder)], top)
}

/// The names of the entries of a folder: to check that a failed or interrupted run left no
/// temporary files behind.
pub fn file_names(dir: &Path) -> Vec<std::ffi::OsString> {
    std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .flatten()
        .map(|e| e.file_name())
        .collect()
}

/// The corners of the square [-half, half]² at height `z`, counter-clockwise seen from +Z.
pub fn square(half: f32, z: f32) -> [[f32; 3]; 4] {
    [[-half, -half], [half, -half], [half, half], [-half, half]].map(|[x, y]| [x, y, z])
}

/// A smooth-shaded UV sphere (`rings` x `segments`, vertex normals = positions, material 0 =
/// `material`) of radius `scale` centred at `centre`, seen by an orthographic camera looking
/// down -Z from 3 radii in front of the centre and framing 1.2 radii, and lit by one directional
/// light of `lux` shining toward `-to_light`. Returns the JSON and the binary buffer.
pub fn sphere_gltf(
    (rings, segments): (u16, u16),
    centre: glam::Vec3,
    scale: f32,
    to_light: glam::Vec3,
    lux: f32,
    material: serde_json::Value,
) -> (serde_json::Value, Vec<u8>) {
    let mut positions = Vec::new();
    for i in 0..=rings {
        let theta = std::f32::consts::PI * f32::from(i) / f32::from(rings);
        for j in 0..=segments {
            let phi = std::f32::consts::TAU * f32::from(j) / f32::from(segments);
            positions.extend([
                theta.sin() * phi.cos(),
                theta.cos(),
                -theta.sin() * phi.sin(),
            ]);
        }
    }
    let mut indices: Vec<u32> = Vec::new();
    let at = |i: u16, j: u16| u32::from(i) * (u32::from(segments) + 1) + u32::from(j);
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            indices.extend([a, b, c, a, c, d]);
        }
    }
    let vertex_bytes = f32_bytes(&positions);
    let mut bin = vertex_bytes.clone();
    bin.extend(indices.iter().flat_map(|x| x.to_le_bytes()));
    let count = positions.len() / 3;
    let light = glam::Quat::from_rotation_arc(glam::Vec3::NEG_Z, -to_light.normalize());
    let camera = centre + glam::Vec3::Z * 3.0 * scale;
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": vertex_bytes.len()},
            {"buffer": 0, "byteOffset": vertex_bytes.len(), "byteLength": indices.len() * 4}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": count, "type": "VEC3",
             "min": [-1.0, -1.0, -1.0], "max": [1.0, 1.0, 1.0]},
            {"bufferView": 1, "componentType": 5125, "count": indices.len(), "type": "SCALAR"}
        ],
        "materials": [material],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 0}, "indices": 1, "material": 0}]}],
        "cameras": [{"type": "orthographic", "orthographic": {
            "xmag": 1.2 * scale, "ymag": 1.2 * scale, "znear": 0.1 * scale, "zfar": 10.0 * scale}}],
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": lux}]}},
        "nodes": [
            {"mesh": 0, "translation": centre.to_array(), "scale": [scale, scale, scale]},
            {"camera": 0, "translation": camera.to_array()},
            {"rotation": light.to_array(), "extensions": {"KHR_lights_punctual": {"light": 0}}}
        ],
        "scenes": [{"nodes": [0, 1, 2]}],
        "scene": 0
    });
    (json, bin)
}

/// Isolated dark pixels ("speckles", the signature of shadow acne) of an 8-bit image: pixels
/// more than `40/255` darker than the median of their 3x3 neighbourhood, counted only where
/// the whole neighbourhood is covered (`mask` nonzero), with brightness the mean of R, G and B.
/// Returns the speckles' positions and the number of covered pixels judged.
pub fn speckles(
    (w, h, rgba): (u32, u32, Vec<[f32; 4]>),
    mask: &[bool],
) -> (Vec<(u32, u32)>, usize) {
    let (w, h) = (w as usize, h as usize);
    let value: Vec<f32> = rgba
        .iter()
        .map(|p| (p[0] + p[1] + p[2]) / 3.0 * 255.0)
        .collect();
    let (mut found, mut judged) = (Vec::new(), 0);
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let mut around = [0.0f32; 9];
            let mut covered = true;
            for (k, (dx, dy)) in (0..3)
                .flat_map(|dy| (0..3).map(move |dx| (dx, dy)))
                .enumerate()
            {
                let i = (y + dy - 1) * w + (x + dx - 1);
                covered &= mask[i];
                around[k] = value[i];
            }
            if !covered {
                continue;
            }
            judged += 1;
            around.sort_by(f32::total_cmp);
            if value[y * w + x] < around[4] - 40.0 {
                found.push((x as u32, y as u32));
            }
        }
    }
    (found, judged)
}

/// Keeps the images of a failed image comparison for inspection, as the failure message should
/// say: copies `reference` and `actual` into `target/tmp/failed-images/<test>/` with the
/// difference image `meshtracer compare` draws of them (`diff.png`, when their sizes agree),
/// and returns the folder. The test's own temporary folder is deleted when it panics.
pub fn keep_failed_images(test: &str, reference: &Path, actual: &Path) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("failed-images")
        .join(test);
    let _ = std::fs::create_dir_all(&dir);
    let name = |p: &Path, fallback: &str| {
        p.file_name()
            .map_or_else(|| fallback.into(), |n| n.to_os_string())
    };
    let kept_reference = dir.join(format!(
        "reference-{}",
        name(reference, "reference.png").to_string_lossy()
    ));
    let kept_actual = dir.join(format!(
        "actual-{}",
        name(actual, "actual.png").to_string_lossy()
    ));
    let _ = std::fs::copy(reference, &kept_reference);
    let _ = std::fs::copy(actual, &kept_actual);
    let diff = dir.join("diff.png");
    let _ = bin()
        .args(["compare", s(reference), s(actual), "--diff-out", s(&diff)])
        .output();
    dir
}

/// A unit quad in the z = 0 plane, [-0.5, 0.5]², facing +Z, with its positions (accessor 0),
/// indices (accessor 1) and texture coordinates (accessor 2, not used by the mesh) in one
/// buffer of 92 bytes, seen by an orthographic camera 2 above looking down and framing
/// [-1, 1]², lit by the default rig.
pub fn unit_quad() -> (serde_json::Value, Vec<u8>) {
    let mut bin = f32_bytes(&[
        -0.5, -0.5, 0.0, 0.5, -0.5, 0.0, 0.5, 0.5, 0.0, -0.5, 0.5, 0.0,
    ]);
    bin.extend([0u16, 1, 2, 0, 2, 3].iter().flat_map(|i| i.to_le_bytes()));
    bin.extend(f32_bytes(&[0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0]));
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"camera": 0, "translation": [0.0, 0.0, 2.0]}],
        "cameras": [{"type": "orthographic",
            "orthographic": {"xmag": 1.0, "ymag": 1.0, "znear": 0.1, "zfar": 10.0}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [-0.5, -0.5, 0.0], "max": [0.5, 0.5, 0.0]},
            {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 12},
            {"buffer": 0, "byteOffset": 60, "byteLength": 32}
        ]
    });
    (json, bin)
}

/// Appends `floats` to `bin` as a new buffer view of buffer 0 and adds `accessor` (its
/// `bufferView` set to that view; `componentType` float) to the JSON's accessors. Returns the
/// accessor's index.
pub fn add_float_accessor(
    json: &mut serde_json::Value,
    bin: &mut Vec<u8>,
    floats: &[f32],
    mut accessor: serde_json::Value,
) -> usize {
    let view =
        serde_json::json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": 4 * floats.len()});
    bin.extend(f32_bytes(floats));
    let views = json["bufferViews"].as_array_mut().expect("bufferViews");
    views.push(view);
    accessor["bufferView"] = serde_json::json!(views.len() - 1);
    accessor["componentType"] = serde_json::json!(5126);
    let accessors = json["accessors"].as_array_mut().expect("accessors");
    accessors.push(accessor);
    accessors.len() - 1
}

/// With `MESHTRACER_WRITE_CORPUS=DIR`, copies `model` to DIR/<test>-<file stem>/model.<ext>
/// the layout `fuzz/seed.sh` collects seeds from (the test is the running test's name).
pub fn copy_to_corpus(model: &Path) {
    let Some(out) = std::env::var_os("MESHTRACER_WRITE_CORPUS") else {
        return;
    };
    let test = std::thread::current().name().unwrap_or("test").to_string();
    let stem = model
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("model");
    let slug: String = format!("{test}-{stem}")
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect();
    let ext = model.extension().and_then(|e| e.to_str()).unwrap_or("gltf");
    // A test that writes several files of one name keeps each (slug, slug-2, ...).
    let dir = (1..)
        .map(|k| match k {
            1 => Path::new(&out).join(&slug),
            _ => Path::new(&out).join(format!("{slug}-{k}")),
        })
        .find(|d| !d.exists())
        .unwrap();
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(model, dir.join(format!("model.{ext}"))).unwrap();
}

/// The scene's bounds as ([min x, y, z], [max x, y, z]).
pub fn bounds(info: &serde_json::Value) -> ([f64; 3], [f64; 3]) {
    let v = |key: &str| {
        let list: Vec<f64> = info["bounds"][key]
            .as_array()
            .unwrap_or_else(|| panic!("bounds.{key}: {info}"))
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        [list[0], list[1], list[2]]
    };
    (v("min"), v("max"))
}
