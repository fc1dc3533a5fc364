//! Many views in one process (`render --views SPEC -o DIR`), through the real binary: the files
//! of an orbit and its transforms.json, depth reprojected through transforms.json onto a
//! known surface, a view of a run equal to the same view rendered alone, determinism, views
//! files and the file's cameras, and refusals of bad specs.

use crate::common::{read_rgba, root, run, s};
use glam::{Mat4, Vec3, Vec4};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Width and height of the test renders: small, the tests check geometry, not pictures.
const W: u32 = 64;
const H: u32 = 48;

fn shapes() -> PathBuf {
    root().join("assets/shapes.obj")
}

fn cornell() -> PathBuf {
    root().join("assets/cornell-box.gltf")
}

/// Runs `render MODEL --views SPEC -o DIR` at W x H, 1 spp, quietly, with `extra` options.
fn render_views(model: &Path, spec: &str, dir: &Path, extra: &[&str]) {
    let (w, h) = (W.to_string(), H.to_string());
    let mut args = vec![
        "render",
        s(model),
        "--views",
        spec,
        "-o",
        s(dir),
        "--width",
        &w,
        "--height",
        &h,
        "--spp",
        "1",
        "-q",
    ];
    args.extend_from_slice(extra);
    run(&args, true);
}

fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn vec3(v: &Value) -> Vec3 {
    Vec3::new(
        v[0].as_f64().unwrap() as f32,
        v[1].as_f64().unwrap() as f32,
        v[2].as_f64().unwrap() as f32,
    )
}

/// The centre of a model's bounding box, from `info --json`.
fn bounds_centre(model: &Path) -> Vec3 {
    let out = run(&["info", s(model), "--json"], true);
    let info: Value = serde_json::from_slice(&out.stdout).unwrap();
    (vec3(&info["bounds"]["min"]) + vec3(&info["bounds"]["max"])) * 0.5
}

/// A frame's `transform_matrix` (row-major in the file) as a glam matrix.
fn matrix(frame: &Value) -> Mat4 {
    let rows = frame["transform_matrix"]
        .as_array()
        .expect("transform_matrix");
    assert_eq!(rows.len(), 4);
    let mut m = [[0f32; 4]; 4];
    for (r, row) in rows.iter().enumerate() {
        let row = row.as_array().expect("a row");
        assert_eq!(row.len(), 4);
        for (c, x) in row.iter().enumerate() {
            m[r][c] = x.as_f64().unwrap() as f32;
        }
    }
    Mat4::from_cols_array_2d(&m).transpose()
}

/// Reads a little-endian float32 `.npy` of shape (H, W), as the depth AOV writes it.
fn read_npy_f32(path: &Path) -> (usize, usize, Vec<f32>) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
    let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = std::str::from_utf8(&bytes[10..10 + len]).unwrap();
    assert!(header.contains("'descr': '<f4'"), "{header}");
    let shape = header.split("'shape': (").nth(1).unwrap();
    let dims: Vec<usize> = shape
        .split(')')
        .next()
        .unwrap()
        .split(',')
        .filter_map(|d| d.trim().parse().ok())
        .collect();
    let data = bytes[10 + len..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect::<Vec<_>>();
    assert_eq!(data.len(), dims[0] * dims[1]);
    (dims[0], dims[1], data)
}

/// `orbit:8` writes 8 images, 8 view files and a transforms.json whose frames, file paths,
/// intrinsics and matrices are right: each camera stands on one circle at the default 20°
/// elevation, 45° apart from the front, with its -Z column pointing at the model's centre and
/// +Y column up. The circle's radius fits the model from all eight directions, so it is at
/// least the automatic camera's distance (which fits its one direction) and at most the
/// bounding sphere's framing distance.
#[test]
fn orbit_writes_every_view_and_a_transforms_json() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("orbit");
    render_views(&shapes(), "orbit:8", &out, &[]);
    let t = read_json(&out.join("transforms.json"));
    let frames = t["frames"].as_array().expect("frames");
    assert_eq!(frames.len(), 8);
    assert_eq!((t["w"].as_u64(), t["h"].as_u64()), (Some(64), Some(48)));
    // yfov 45°: fl_y = (h/2) / tan(22.5°), square pixels, centred principal point.
    let fl = 24.0 / 22.5f64.to_radians().tan();
    let (fl_x, fl_y) = (t["fl_x"].as_f64().unwrap(), t["fl_y"].as_f64().unwrap());
    assert!(
        (fl_x - fl).abs() < 1e-3 && (fl_y - fl).abs() < 1e-3,
        "{fl_x} {fl_y} vs {fl}"
    );
    assert_eq!(
        (t["cx"].as_f64(), t["cy"].as_f64()),
        (Some(32.0), Some(24.0))
    );
    let angle_x = 2.0 * (32.0 / fl_x).atan();
    assert!((t["camera_angle_x"].as_f64().unwrap() - angle_x).abs() < 1e-9);

    // The automatic camera's distance: the single render's view file says it.
    let single_view = dir.path().join("auto.view.json");
    let (w, h) = (W.to_string(), H.to_string());
    run(
        &[
            "render",
            s(&shapes()),
            "-o",
            s(&dir.path().join("auto.png")),
            "--width",
            &w,
            "--height",
            &h,
            "--spp",
            "1",
            "-q",
            "--view-out",
            s(&single_view),
        ],
        true,
    );
    let centre = bounds_centre(&shapes());
    let info: Value =
        serde_json::from_slice(&run(&["info", s(&shapes()), "--json"], true).stdout).unwrap();
    let sphere_radius =
        (vec3(&info["bounds"]["max"]) - vec3(&info["bounds"]["min"])).length() * 0.5;
    // The bounding sphere's framing at yfov 45°, 4:3: radius / sin(22.5°) with a 5% margin.
    let sphere_distance = sphere_radius / 22.5f32.to_radians().sin() * 1.05;
    let auto_distance = (vec3(&read_json(&single_view)["camera"]["position"]) - centre).length();

    let mut orbit_radius = None;
    for (k, frame) in frames.iter().enumerate() {
        let name = format!("{k:03}.png");
        assert_eq!(frame["file_path"], name.as_str());
        let (w, h, _) = read_rgba(&out.join(&name));
        assert_eq!((w, h), (W, H));
        let m = matrix(frame);
        assert_eq!(m.row(3), Vec4::W, "view {k}: last row");
        let (right, up, back, eye) = (
            m.x_axis.truncate(),
            m.y_axis.truncate(),
            m.z_axis.truncate(),
            m.w_axis.truncate(),
        );
        for (axis, v) in [("x", right), ("y", up), ("z", back)] {
            assert!(
                (v.length() - 1.0).abs() < 1e-5,
                "view {k}: {axis} column is not unit"
            );
        }
        assert!(
            right.dot(up).abs() < 1e-5 && up.dot(back).abs() < 1e-5,
            "view {k}"
        );
        assert!(
            (right.cross(up) - back).length() < 1e-5,
            "view {k}: right-handed"
        );
        // Camera position = the orbit point.
        let offset = eye - centre;
        let radius = *orbit_radius.get_or_insert(offset.length());
        assert!(
            (offset.length() - radius).abs() < 1e-5 * radius,
            "view {k}: distance {} vs {radius}",
            offset.length()
        );
        assert!(
            radius >= auto_distance * (1.0 - 1e-5),
            "view {k}: {radius} closer than the automatic camera's {auto_distance}"
        );
        assert!(
            radius <= sphere_distance,
            "view {k}: {radius} farther than the sphere's framing {sphere_distance}"
        );
        let elevation = (offset.y / offset.length()).asin().to_degrees();
        assert!(
            (elevation - 20.0).abs() < 1e-3,
            "view {k}: elevation {elevation}"
        );
        let azimuth = offset.x.atan2(offset.z).to_degrees().rem_euclid(360.0);
        let expected = 45.0 * k as f32;
        let diff = (azimuth - expected + 180.0).rem_euclid(360.0) - 180.0;
        assert!(
            diff.abs() < 1e-3,
            "view {k}: azimuth {azimuth} vs {expected}"
        );
        // -Z looks at the centre; +Y is up in the world.
        assert!(
            (-back - (centre - eye).normalize()).length() < 1e-5,
            "view {k}: -Z"
        );
        assert!(up.y > 0.0, "view {k}: up");
        // The view file of the view records the same camera.
        let view = read_json(&out.join(format!("{k:03}.view.json")));
        assert_eq!(view["image"]["width"].as_u64(), Some(u64::from(W)));
        assert!(
            (vec3(&view["camera"]["position"]) - eye).length() < 1e-5,
            "view {k}"
        );
    }
}

/// An OBJ cube [-0.5, 0.5]³ (each face a quad, outward winding).
fn cube_obj(dir: &Path) -> PathBuf {
    let path = dir.join("cube.obj");
    let mut text = String::from("o cube\n");
    for i in 0..8 {
        let c = |bit: i32| if i & bit == 0 { -0.5 } else { 0.5 };
        text += &format!("v {} {} {}\n", c(1), c(2), c(4));
    }
    // Vertex index (1-based) = 1 + x + 2y + 4z.
    text += "f 1 5 7 3\nf 2 4 8 6\nf 1 2 6 5\nf 3 7 8 4\nf 1 3 4 2\nf 5 6 8 7\n";
    std::fs::write(&path, text).unwrap();
    path
}

/// How far a point is from the nearest face plane of the cube [-0.5, 0.5]³, and how far
/// outside the cube's extent it lies along any axis.
fn off_cube(p: Vec3) -> (f32, f32) {
    let a = p.abs();
    let plane = (a - Vec3::splat(0.5)).abs().min_element();
    let beyond = (a.max_element() - 0.5).max(0.0);
    (plane, beyond)
}

/// Hits may lie this far past a face's edge: the triangle test's watertight overlap
/// (`EDGE_EPSILON`, 1e-4 barycentric) on faces 1 unit across.
const EDGE_OVERLAP: f32 = 1e-4;

/// f32 hit points, rays and the test's own unprojection carry about 1e-6 of error at this
/// distance (4e-7 measured); 1e-5 leaves margin.
const FLOAT_TOLERANCE: f32 = 1e-5;

/// Unprojects every covered pixel's depth through `transforms.json` the way nerfstudio does
/// (pixel centre (i + 0.5, j + 0.5), camera-space direction ((x - cx)/fl_x, -(y - cy)/fl_y,
/// -1) scaled by the z-depth, then the camera-to-world matrix) and returns the largest
/// distance from a face plane, the largest distance outside the cube, and the number of
/// pixels checked.
fn reproject(dir: &Path, depth_of: impl Fn(&Value, &Value) -> Vec<f32>) -> (f32, f32, usize) {
    let t = read_json(&dir.join("transforms.json"));
    let (fl_x, fl_y) = (t["fl_x"].as_f64().unwrap(), t["fl_y"].as_f64().unwrap());
    let (cx, cy) = (t["cx"].as_f64().unwrap(), t["cy"].as_f64().unwrap());
    let (w, h) = (
        t["w"].as_u64().unwrap() as usize,
        t["h"].as_u64().unwrap() as usize,
    );
    let (mut off_plane, mut outside, mut checked) = (0f32, 0f32, 0);
    for frame in t["frames"].as_array().unwrap() {
        let m = matrix(frame);
        let depth = depth_of(&t, frame);
        assert_eq!(depth.len(), w * h);
        for j in 0..h {
            for i in 0..w {
                let z = depth[j * w + i];
                if z == 0.0 {
                    continue;
                }
                let (x, y) = (i as f64 + 0.5, j as f64 + 0.5);
                let camera =
                    Vec3::new(((x - cx) / fl_x) as f32, (-(y - cy) / fl_y) as f32, -1.0) * z;
                let world = m.transform_point3(camera);
                let (plane, beyond) = off_cube(world);
                off_plane = off_plane.max(plane);
                outside = outside.max(beyond);
                checked += 1;
            }
        }
    }
    (off_plane, outside, checked)
}

/// Depth reprojected through transforms.json lands on the mesh: every covered pixel of six
/// views spread over a sphere around a unit cube, with float depth (.npy, metres), lies on a
/// face plane within [`FLOAT_TOLERANCE`] and inside the cube up to [`EDGE_OVERLAP`]; with
/// 16-bit PNG depth in units of --depth-scale 0.0001 (the scale transforms.json records),
/// rounding adds at most half a unit along the ray: 0.5 × 1.21 (the longest camera-space
/// direction at this field of view) < 0.61 units.
#[test]
fn depth_reprojects_through_transforms_json_onto_the_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let cube = cube_obj(dir.path());
    let float_dir = dir.path().join("float");
    render_views(
        &cube,
        "sphere:6",
        &float_dir,
        &["--depth-out", "depth/{view:03}.npy"],
    );
    let t = read_json(&float_dir.join("transforms.json"));
    assert_eq!(
        t["depth_unit_scale_factor"].as_f64(),
        Some(1.0),
        "npy depth is in metres"
    );
    let (off_plane, outside, checked) = reproject(&float_dir, |t, frame| {
        let scale = t["depth_unit_scale_factor"].as_f64().unwrap() as f32;
        let path = float_dir.join(frame["depth_file_path"].as_str().unwrap());
        let (h, w, depth) = read_npy_f32(&path);
        assert_eq!((w, h), (W as usize, H as usize));
        depth.into_iter().map(|d| d * scale).collect()
    });
    assert!(checked > 6 * 64 * 48 / 10, "only {checked} covered pixels");
    assert!(
        off_plane < FLOAT_TOLERANCE,
        "a point is {off_plane} off the faces"
    );
    assert!(
        outside < EDGE_OVERLAP + FLOAT_TOLERANCE,
        "a point is {outside} outside the cube"
    );

    let png_dir = dir.path().join("png");
    let scale = 1e-4f64;
    render_views(
        &cube,
        "orbit:3",
        &png_dir,
        &[
            "--depth-out",
            "d{view}.png",
            "--depth-scale",
            "0.0001",
            "--orbit-elevation",
            "35",
        ],
    );
    let t = read_json(&png_dir.join("transforms.json"));
    assert_eq!(t["depth_unit_scale_factor"].as_f64(), Some(scale));
    let (off_plane, outside, checked) = reproject(&png_dir, |t, frame| {
        let scale = t["depth_unit_scale_factor"].as_f64().unwrap() as f32;
        let path = png_dir.join(frame["depth_file_path"].as_str().unwrap());
        let img = image::open(&path).unwrap().to_luma16();
        img.pixels().map(|p| f32::from(p.0[0]) * scale).collect()
    });
    let rounding = (0.61 * scale) as f32;
    assert!(checked > 3 * 64 * 48 / 10, "only {checked} covered pixels");
    assert!(
        off_plane < rounding + FLOAT_TOLERANCE,
        "a point is {off_plane} off the faces"
    );
    assert!(
        outside < EDGE_OVERLAP + rounding + FLOAT_TOLERANCE,
        "a point is {outside} outside the cube"
    );
}

/// View k of a multi-view run equals the same view rendered alone from its view file, byte
/// for byte (image and depth): with the default rig (shapes.obj has no lights) and with the
/// file's lights (the Cornell box).
#[test]
fn a_view_of_the_run_equals_the_view_rendered_alone() {
    let dir = tempfile::tempdir().unwrap();
    for (model, spec) in [(shapes(), "orbit:4"), (cornell(), "random:3")] {
        let out = dir.path().join(spec.replace(':', "-"));
        render_views(
            &model,
            spec,
            &out,
            &["--depth-out", "{view:03}.depth.npy", "--seed", "5"],
        );
        let k = 2;
        let alone = dir.path().join("alone.png");
        let alone_depth = dir.path().join("alone.npy");
        run(
            &[
                "render",
                s(&model),
                "--view",
                s(&out.join(format!("{k:03}.view.json"))),
                "-o",
                s(&alone),
                "--spp",
                "1",
                "--seed",
                "5",
                "--depth-out",
                s(&alone_depth),
                "-q",
            ],
            true,
        );
        let bytes = |p: &Path| std::fs::read(p).unwrap();
        assert!(
            bytes(&alone) == bytes(&out.join(format!("{k:03}.png"))),
            "{spec}: view {k} alone differs from the run's"
        );
        assert!(
            bytes(&alone_depth) == bytes(&out.join(format!("{k:03}.depth.npy"))),
            "{spec}: depth of view {k} alone differs from the run's"
        );
    }
}

/// Views through a thin lens (`--aperture-radius`): each view focuses at its distance to the
/// model's centre, which it looks at, and records the lens in its view file and its
/// transforms.json frame; a view rendered alone from its file is the run's, byte for byte,
/// and differs from the pinhole's.
#[test]
fn views_through_a_thin_lens_record_it_and_render_alone_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let model = cornell();
    let lens = dir.path().join("lens");
    let pinhole = dir.path().join("pinhole");
    // Four samples a pixel (`render_views` takes one, which goes through the lens centre).
    let views = |out: &Path, extra: &[&str]| {
        let mut args = vec![
            "render",
            s(&model),
            "--views",
            "orbit:2",
            "-o",
            s(out),
            "-q",
        ];
        args.extend_from_slice(&["--width", "64", "--height", "48", "--spp", "4"]);
        args.extend_from_slice(extra);
        run(&args, true);
    };
    views(&lens, &["--aperture-radius", "0.2"]);
    views(&pinhole, &[]);
    let spp = ["--spp", "4"];
    let transforms = read_json(&lens.join("transforms.json"));
    let centre = bounds_centre(&model);
    for (k, frame) in transforms["frames"].as_array().unwrap().iter().enumerate() {
        assert_eq!(frame["aperture_radius"].as_f64(), Some(0.2));
        let m = matrix(frame);
        let eye = m.w_axis.truncate();
        let forward = -m.z_axis.truncate();
        let focus = frame["focus_distance"].as_f64().unwrap() as f32;
        assert!(
            ((centre - eye).dot(forward) - focus).abs() < 1e-4 * focus,
            "view {k}"
        );
        let view_file = read_json(&lens.join(format!("{k:03}.view.json")));
        assert_eq!(
            view_file["camera"]["focus_distance"],
            frame["focus_distance"]
        );
    }
    // A views file's view focuses at its own look_at: 2 m ahead here, where the scene's
    // centre (0, 1, 0) is 3 m ahead.
    let file = dir.path().join("views.json");
    std::fs::write(
        &file,
        r#"[{"look_from": [0.5, 1, 3], "look_at": [0.5, 1, 1]}]"#,
    )
    .unwrap();
    let explicit = dir.path().join("explicit");
    let mut args = vec![
        "render",
        s(&model),
        "--views",
        s(&file),
        "-o",
        s(&explicit),
        "-q",
    ];
    args.extend_from_slice(&[
        "--width",
        "16",
        "--height",
        "12",
        "--aperture-radius",
        "0.2",
    ]);
    run(&args, true);
    let frame = &read_json(&explicit.join("transforms.json"))["frames"][0];
    assert_eq!(frame["focus_distance"].as_f64(), Some(2.0));
    let alone = dir.path().join("alone.png");
    let view = lens.join("001.view.json");
    let mut args = vec![
        "render",
        s(&model),
        "--view",
        s(&view),
        "-o",
        s(&alone),
        "-q",
    ];
    args.extend_from_slice(&spp);
    run(&args, true);
    let bytes = |p: &Path| std::fs::read(p).unwrap();
    assert!(
        bytes(&alone) == bytes(&lens.join("001.png")),
        "view 1 alone differs"
    );
    assert!(
        bytes(&alone) != bytes(&pinhole.join("001.png")),
        "the lens changed nothing"
    );
}

/// The same command writes the same bytes: images, AOVs, view files and transforms.json.
#[test]
fn the_same_command_writes_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let options = [
        "--mask-out",
        "m/{view}.png",
        "--normal-out",
        "n/{view}.npy",
        "--seed",
        "9",
    ];
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    render_views(&cornell(), "random:3", &a, &options);
    render_views(&cornell(), "random:3", &b, &options);
    let mut files = Vec::new();
    for sub in ["", "m", "n"] {
        for entry in std::fs::read_dir(a.join(sub)).unwrap().flatten() {
            if entry.path().is_file() {
                files.push(Path::new(sub).join(entry.file_name()));
            }
        }
    }
    assert_eq!(files.len(), 3 * 2 + 3 + 3 + 2, "{files:?}");
    for f in &files {
        assert!(
            std::fs::read(a.join(f)).unwrap() == std::fs::read(b.join(f)).unwrap(),
            "{} differs between two runs",
            f.display()
        );
    }
    // Another seed draws other directions.
    let c = dir.path().join("c");
    render_views(&cornell(), "random:3", &c, &["--seed", "10"]);
    assert_ne!(
        read_json(&a.join("transforms.json"))["frames"],
        read_json(&c.join("transforms.json"))["frames"]
    );
}

/// A views file mixes look-at views and view-file cameras; differing fields of view put the
/// intrinsics on each frame. `cameras` renders every camera of the file from where it stands.
#[test]
fn views_files_and_the_files_cameras() {
    let dir = tempfile::tempdir().unwrap();
    let views = dir.path().join("views.json");
    std::fs::write(
        &views,
        r#"[
            {"look_from": [0, 1, 6], "look_at": [0, 1, 0]},
            {"look_from": [6, 1, 0], "look_at": [0, 1, 0], "yfov_degrees": 30},
            {"camera": {"type": "perspective", "position": [0, 5, 0.5], "look_at": [0, 4, 0.5],
                        "up": [0, 0, -1], "yfov": 0.8, "aspect": 1.0, "znear": 0.01, "zfar": null}}
        ]"#,
    )
    .unwrap();
    let out = dir.path().join("out");
    render_views(&cornell(), s(&views), &out, &[]);
    let t = read_json(&out.join("transforms.json"));
    assert!(
        t.get("fl_x").is_none(),
        "intrinsics differ: they go per frame"
    );
    let frames = t["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 3);
    let eyes = [
        Vec3::new(0.0, 1.0, 6.0),
        Vec3::new(6.0, 1.0, 0.0),
        Vec3::new(0.0, 5.0, 0.5),
    ];
    for (k, (frame, eye)) in frames.iter().zip(eyes).enumerate() {
        let m = matrix(frame);
        assert!((m.w_axis.truncate() - eye).length() < 1e-5, "view {k}");
        let fl_y = frame["fl_y"].as_f64().unwrap();
        let yfov = [45f64, 30.0, 0.8f64.to_degrees()][k].to_radians();
        assert!(
            (fl_y - 24.0 / (yfov / 2.0).tan()).abs() < 1e-2,
            "view {k}: fl_y {fl_y}"
        );
    }
    let looking_down = matrix(&frames[2]);
    assert!(
        (looking_down.z_axis.truncate() - Vec3::Y).length() < 1e-5,
        "camera 2 looks down"
    );

    let out = dir.path().join("cameras");
    render_views(&cornell(), "cameras", &out, &[]);
    let t = read_json(&out.join("transforms.json"));
    let frames = t["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 1);
    let m = matrix(&frames[0]);
    assert!((m.w_axis.truncate() - Vec3::new(0.0, 1.0, 3.9)).length() < 1e-5);
    assert!(
        (m.z_axis.truncate() - Vec3::Z).length() < 1e-5,
        "looks down -Z"
    );
}

/// Bad specs and names give one clear error naming the problem, exit 1 (not a panic), and
/// leave no output folder behind.
#[test]
fn bad_specs_give_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let malformed = dir.path().join("malformed.json");
    std::fs::write(&malformed, r#"[{"look_from": [0, 0, 1], "look_at": "#).unwrap();
    let incomplete = dir.path().join("incomplete.json");
    std::fs::write(
        &incomplete,
        r#"[{"look_from": [0, 0, 5], "look_at": [0, 0, 0]}, {"look_from": [1, 2, 3]}]"#,
    )
    .unwrap();
    let missing = dir.path().join("missing.json");
    let cases: Vec<(Vec<&str>, String)> = vec![
        (
            vec!["orbit:0"],
            "--views orbit:0: the number of views must be at least 1".into(),
        ),
        (
            vec!["orbit:abc"],
            "--views orbit:abc: 'abc' is not a whole number of views".into(),
        ),
        (
            vec!["sphere:-2"],
            "'-2' is not a whole number of views".into(),
        ),
        (vec!["random:100001"], "100001 views: at most 100000".into()),
        (vec!["orbit"], "give the number of views: orbit:N".into()),
        (
            vec![s(&missing)],
            "not orbit:N, sphere:N, random:N or cameras, and not a readable file".into(),
        ),
        (
            vec![s(&malformed)],
            format!("{}: not JSON", malformed.display()),
        ),
        (
            vec![s(&incomplete)],
            format!("{}: view 1: missing field `look_at`", incomplete.display()),
        ),
        (
            vec!["orbit:2", "--depth-out", "depth.npy"],
            "--depth-out depth.npy: with --views, a name needs {view}".into(),
        ),
        (
            vec!["orbit:2", "--view-name", "{frame}.png"],
            "unknown placeholder {frame}".into(),
        ),
        (
            vec!["orbit:2", "--view-name", "{view}.bmp"],
            "unknown output format".into(),
        ),
        (
            vec!["orbit:2", "--mask-out", "{view:03}.png"],
            "would be written twice".into(),
        ),
        (
            vec!["orbit:2", "--orbit-elevation", "91"],
            "--orbit-elevation 91: must be between -90 and 90".into(),
        ),
        (
            vec!["orbit:2", "--orbit-radius", "-1"],
            "--orbit-radius -1: must be a positive distance".into(),
        ),
        (
            vec!["cameras"],
            "--views cameras: the file has no cameras".into(),
        ),
    ];
    let model = shapes();
    for (views, expected) in cases {
        let out = dir.path().join("out");
        let mut args = vec!["render", s(&model), "-o", s(&out), "--views"];
        args.extend(views.iter().copied());
        let result = run(&args, false);
        let err = crate::common::stderr(&result);
        assert_eq!(result.status.code(), Some(1), "{views:?}: {err}");
        assert!(
            err.contains(&expected),
            "{views:?}: expected '{expected}' in: {err}"
        );
        assert!(
            err.starts_with("meshtracer: error: ") && err.trim_end().lines().count() == 1,
            "{views:?}: {err}"
        );
        assert!(!out.exists(), "{views:?}: the output folder was created");
    }

    // An image name for the folder, and --no-clobber over a finished run.
    let err = crate::common::stderr(&run(
        &[
            "render",
            s(&shapes()),
            "-o",
            s(&dir.path().join("out.png")),
            "--views",
            "orbit:2",
        ],
        false,
    ));
    assert!(
        err.contains("names the folder the views are written to"),
        "{err}"
    );
    let out = dir.path().join("done");
    render_views(&shapes(), "orbit:2", &out, &[]);
    let before = std::fs::read(out.join("000.png")).unwrap();
    let result = run(
        &[
            "render",
            s(&shapes()),
            "-o",
            s(&out),
            "--views",
            "orbit:2",
            "--no-clobber",
            "--seed",
            "3",
        ],
        false,
    );
    assert!(crate::common::stderr(&result).contains("already exists (--no-clobber)"));
    assert_eq!(std::fs::read(out.join("000.png")).unwrap(), before);
}

/// A view whose depth file cannot be written (its name is taken by a folder) fails the run
/// after the views before it were written whole: exit 1 with one message naming the failed
/// view and the views written, `transforms.json` listing exactly those, and none of the failed
/// view's files left (no image without its depth).
#[test]
fn a_run_failing_part_way_records_the_views_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("views");
    std::fs::create_dir_all(out.join("depth/002.npy")).unwrap();
    let depth = out.join("depth/{view:03}.npy");
    let model = cornell();
    let args = [
        "render",
        s(&model),
        "--views",
        "orbit:4",
        "-o",
        s(&out),
        "--width",
        "32",
        "--height",
        "24",
        "--spp",
        "1",
        "-q",
        "--depth-out",
        s(&depth),
    ];
    let result = run(&args, false);
    let err = crate::common::stderr(&result);
    assert!(
        err.contains("view 2 failed; views 0 to 1 of 4 are written whole"),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
    let frames = read_json(&out.join("transforms.json"))["frames"].clone();
    let listed: Vec<&str> = frames
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["file_path"].as_str().unwrap())
        .collect();
    assert_eq!(listed, ["000.png", "001.png"]);
    for k in 0..2 {
        assert!(out.join(format!("{k:03}.png")).exists());
        assert!(out.join(format!("depth/{k:03}.npy")).is_file());
    }
    for name in ["002.png", "002.view.json", "003.png"] {
        assert!(!out.join(name).exists(), "{name}");
    }
}

/// Every file under `dir` (relative path -> bytes).
fn tree(dir: &Path) -> std::collections::BTreeMap<String, Vec<u8>> {
    let mut files = std::collections::BTreeMap::new();
    let mut folders = vec![dir.to_path_buf()];
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(&folder).unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                folders.push(path);
            } else {
                let name = path
                    .strip_prefix(dir)
                    .unwrap()
                    .to_string_lossy()
                    .into_owned();
                files.insert(name, std::fs::read(&path).unwrap());
            }
        }
    }
    files
}

/// The options of the resume tests: 12 path-traced views (more than it takes to stop a run
/// before its end in a release build) of the box with depth, masks, a GIF
/// and a contact sheet (named after `tag`, beside the folder `out`).
fn resume_args(out: &Path, tag: &str) -> Vec<String> {
    let beside = out.parent().unwrap();
    let mut args: Vec<String> = [
        "render",
        s(&cornell()),
        "--views",
        "orbit:12",
        "-o",
        s(out),
        "--depth-out",
        "d/{view:03}.exr",
        "--mask-out",
        "m/{view}.png",
    ]
    .map(String::from)
    .to_vec();
    args.extend(crate::common::STOPPABLE.map(String::from));
    args.push("--gif".into());
    args.push(s(&beside.join(format!("{tag}.gif"))).into());
    args.push("--contact-sheet".into());
    args.push(s(&beside.join(format!("{tag}.png"))).into());
    args
}

/// Runs [`resume_args`]'s render uninterrupted into `dir/whole` (GIF and sheet beside it);
/// returns the folder and the arguments.
fn whole_run(dir: &Path) -> (PathBuf, Vec<String>) {
    let whole = dir.join("whole");
    let args = resume_args(&whole, "whole");
    let quiet: Vec<&str> = args.iter().map(String::as_str).chain(["-q"]).collect();
    run(&quiet, true);
    (whole, args)
}

/// The folder, GIF and contact sheet of [`resume_args`]'s run `tag` in `dir` are those of
/// run `reference`, byte for byte.
fn assert_same_run(dir: &Path, tag: &str, reference: &str) {
    assert_eq!(
        tree(&dir.join(tag)),
        tree(&dir.join(reference)),
        "{tag}: the folder differs"
    );
    for ext in ["gif", "png"] {
        assert!(
            std::fs::read(dir.join(format!("{tag}.{ext}"))).unwrap()
                == std::fs::read(dir.join(format!("{reference}.{ext}"))).unwrap(),
            "{tag}: the {ext} differs"
        );
    }
}

/// A `--views` run stopped by `signal` once 3 views are written keeps those views on
/// `--resume` and renders only the rest, ending with the files of an uninterrupted run byte
/// for byte: images, AOVs, view files, transforms.json, the record of finished views, and the
/// GIF and the contact sheet made again with the kept views' images read back.
fn stop_and_resume_views(signal: &str) {
    let dir = tempfile::tempdir().unwrap();
    whole_run(dir.path());

    let cut = dir.path().join("cut");
    let cut_args = resume_args(&cut, "cut");
    let cut_args: Vec<&str> = cut_args.iter().map(String::as_str).collect();
    let mut child = crate::common::bin()
        .args(&cut_args)
        .arg("-q")
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    crate::common::wait_until(&mut child, "view 2", || cut.join("002.view.json").is_file());
    crate::hostile::send(&child, signal);
    let stopped = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&stopped.stderr);
    if signal != "KILL" {
        assert_eq!(stopped.status.code(), Some(130), "{err}");
        assert!(err.contains("run the same command with --resume"), "{err}");
    }
    let finished = (0..12)
        .filter(|k| cut.join(format!("{k:03}.view.json")).is_file())
        .count();
    assert!(
        (3..12).contains(&finished),
        "{finished} views before the stop"
    );
    assert!(!cut.join("transforms.json").exists());
    if signal == "KILL" {
        // SIGKILL leaves the temporary file of the view it stopped in (when it lands during a
        // render): planted here so that the resume's clean-up is always tested.
        for folder in [cut.clone(), cut.join("d")] {
            std::fs::create_dir_all(&folder).unwrap();
            std::fs::write(folder.join(".meshtracer-killed.partial"), b"half").unwrap();
        }
    }

    let resumed = run(&[&cut_args[..], &["--resume"]].concat(), true);
    let err = crate::common::stderr(&resumed);
    assert!(
        err.contains(&format!("--resume: {finished} of 12 views finished before")),
        "{err}"
    );
    assert_eq!(
        err.matches(" kept: finished by an earlier run").count(),
        finished,
        "{err}"
    );
    assert_eq!(
        err.matches(".png rendered in ").count(),
        12 - finished,
        "{err}"
    );
    let summary = format!(
        "; {} view{} of ",
        12 - finished,
        if finished == 11 { "" } else { "s" }
    );
    assert!(err.contains(&summary), "{summary}: {err}");
    assert!(
        err.contains(&format!(" s a view, {finished} kept from an earlier run)")),
        "{err}"
    );
    assert_same_run(dir.path(), "cut", "whole");
}

#[test]
fn a_views_run_killed_part_way_resumes_to_the_files_of_a_whole_run() {
    stop_and_resume_views("KILL");
}

#[test]
fn a_views_run_stopped_by_sigterm_resumes_to_the_files_of_a_whole_run() {
    stop_and_resume_views("TERM");
}

/// `--resume` keeps only what still vouches for itself: a view whose image changed or whose
/// depth is gone, and every view once an option changes, is rendered again, saying why; a torn
/// last line of the record costs its view only. Bad combinations are refused up front.
#[test]
fn resume_renders_again_what_changed_and_refuses_what_it_cannot_keep() {
    let dir = tempfile::tempdir().unwrap();
    let (whole, args) = whole_run(dir.path());
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let expected = tree(&whole);

    // Nothing changed: every view is kept, and the summary says so instead of a rate of no rays.
    let err = crate::common::stderr(&run(&[&args[..], &["--resume"]].concat(), true));
    assert!(
        err.contains("; no view rendered (12 kept from an earlier run); "),
        "{err}"
    );
    assert_eq!(tree(&whole), expected);

    std::fs::write(whole.join("001.png"), b"not the image").unwrap();
    std::fs::remove_file(whole.join("d/002.exr")).unwrap();
    // A line torn by a kill as it was appended: view 11's record is lost, not the others'.
    let record = whole.join("rendered.jsonl");
    let text = std::fs::read_to_string(&record).unwrap();
    std::fs::write(&record, &text[..text.len() - 40]).unwrap();
    let out = run(&[&args[..], &["--resume"]].concat(), true);
    let err = crate::common::stderr(&out);
    assert!(
        err.contains("--resume: 9 of 12 views finished before"),
        "{err}"
    );
    assert!(
        err.contains("view 1: rendered again: 001.png changed since it was written"),
        "{err}"
    );
    assert!(err.contains("view 2: rendered again: d/002.exr: "), "{err}");
    for k in [1, 2, 11] {
        let line = format!(
            "[{}/12] {} rendered in",
            k + 1,
            s(&whole.join(format!("{k:03}.png")))
        );
        assert!(err.contains(&line), "{line}: {err}");
    }
    assert_eq!(err.matches(".png rendered in ").count(), 3, "{err}");
    assert_eq!(tree(&whole), expected);

    // Other samples: nothing is kept.
    let mut more = args.clone();
    let spp = more.iter().position(|a| *a == "--spp").unwrap();
    more[spp + 1] = "4";
    let out = run(&[&more[..], &["--resume"]].concat(), true);
    let err = crate::common::stderr(&out);
    assert!(
        err.contains("--resume: 0 of 12 views finished before"),
        "{err}"
    );
    assert_eq!(
        err.matches(
            "rendered again: the options, the model (or a file it refers to) or meshtracer changed"
        )
        .count(),
        12,
        "{err}"
    );

    for (extra, words) in [
        (&["--no-clobber"][..], "not with --no-clobber"),
        (&["--view-name", "{view}.exr"][..], "needs the views as PNG"),
    ] {
        let out = run(&[&args[..], &["--resume"], extra].concat(), false);
        assert!(crate::common::stderr(&out).contains(words), "{extra:?}");
    }
    // A record that cannot be read is an error naming it, not a run that starts over.
    let record = whole.join("rendered.jsonl");
    std::fs::remove_file(&record).unwrap();
    std::fs::create_dir(&record).unwrap();
    let out = run(&[&args[..], &["--resume"]].concat(), false);
    let err = crate::common::stderr(&out);
    assert!(err.contains(&format!("{}: ", s(&record))), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    std::fs::remove_dir(&record).unwrap();
    let single = dir.path().join("one.png");
    let out = run(
        &["render", s(&cornell()), "-o", s(&single), "--resume"],
        false,
    );
    assert!(crate::common::stderr(&out).contains("a single render has nothing to keep"));
    assert!(!single.exists());
}

/// Three shards of a run, started together into one folder (as the tasks of a Slurm array or
/// a Kubernetes Indexed Job), each render only their views and record them apart; the same
/// command without `--shard` and with `--resume` joins them, rendering nothing, into the files
/// of an unsharded run byte for byte (the GIF and the sheet made there), with no shard's record
/// left. What a shard cannot make is refused.
#[test]
fn shards_of_a_views_run_join_into_the_whole_run() {
    let dir = tempfile::tempdir().unwrap();
    whole_run(dir.path());

    let joined = dir.path().join("joined");
    let join_args = resume_args(&joined, "joined");
    let join_args: Vec<&str> = join_args.iter().map(String::as_str).collect();
    // The options of a shard: the run's, without the GIF and the sheet.
    let gif = join_args.iter().position(|a| *a == "--gif").unwrap();
    let shard_args = &join_args[..gif];
    let shards: Vec<_> = (0..3)
        .map(|i| {
            let shard = format!("{i}/3");
            crate::common::bin()
                .args(shard_args)
                .args(["--shard", &shard, "-q"])
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for child in shards {
        let out = child.wait_with_output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let mut records: Vec<String> = crate::common::file_names(&joined)
        .into_iter()
        .map(|n| n.to_string_lossy().into_owned())
        .filter(|n| n.starts_with("rendered"))
        .collect();
    records.sort();
    assert_eq!(
        records,
        [
            "rendered.0-of-3.jsonl",
            "rendered.1-of-3.jsonl",
            "rendered.2-of-3.jsonl"
        ]
    );
    assert!(!joined.join("transforms.json").exists());
    let shard_1 = std::fs::read_to_string(joined.join("rendered.1-of-3.jsonl")).unwrap();
    let views: Vec<u64> = shard_1
        .lines()
        .map(|l| {
            serde_json::from_str::<Value>(l).unwrap()["view"]
                .as_u64()
                .unwrap()
        })
        .collect();
    assert_eq!(views, [1, 4, 7, 10]);

    let out = run(&[&join_args[..], &["--resume"]].concat(), true);
    let err = crate::common::stderr(&out);
    assert!(
        err.contains("--resume: 12 of 12 views finished before"),
        "{err}"
    );
    assert_eq!(err.matches(".png rendered in").count(), 0, "{err}");
    assert_same_run(dir.path(), "joined", "whole");

    for (extra, words) in [
        (
            &["--shard", "1/3", "--gif", "x.gif"][..],
            "--gif needs every view",
        ),
        (
            &["--shard", "1/3", "--no-clobber"][..],
            "not with --no-clobber",
        ),
        (&["--shard", "3/3"][..], "must be below the count"),
    ] {
        let out = run(&[shard_args, extra].concat(), false);
        assert!(crate::common::stderr(&out).contains(words), "{extra:?}");
    }
    let single = dir.path().join("one.png");
    let out = run(
        &["render", s(&cornell()), "-o", s(&single), "--shard", "0/2"],
        false,
    );
    assert!(crate::common::stderr(&out).contains("splits the views"));
}

/// `examples/slurm/views_array.sbatch`, run for every task of its array with the variables
/// Slurm sets (half the tasks given only MIN and MAX, not COUNT), then the join its header
/// gives: the folder of one process rendering every view, byte for byte.
#[test]
fn the_slurm_views_example_covers_every_view() {
    let dir = tempfile::tempdir().unwrap();
    let exe = env!("CARGO_BIN_EXE_meshtracer");
    let options = ["--width", "48", "--height", "36", "--spp", "2"];
    let options = [&options[..], &["--depth-out", "depth/{view:03}.exr"]].concat();
    let (model, views) = (cornell(), "orbit:7");
    let render = |out: &Path, extra: &[&str]| {
        let args = [
            &["render", s(&model), "--views", views, "-o", s(out), "-q"],
            &options[..],
            extra,
        ];
        run(&args.concat(), true);
    };
    let whole = dir.path().join("whole");
    render(&whole, &[]);

    let script = root().join("examples/slurm/views_array.sbatch");
    let text = std::fs::read_to_string(&script).unwrap();
    let array = text
        .lines()
        .find_map(|l| l.strip_prefix("#SBATCH --array="))
        .expect("an #SBATCH --array line");
    let (min, max) = array.split_once('-').expect("--array=MIN-MAX");
    let (min, max): (usize, usize) = (min.parse().unwrap(), max.parse().unwrap());
    assert!(max > min, "an array of several tasks");
    let out = dir.path().join("slurm");
    let joined_options = options.join(" ");
    for task in min..=max {
        let mut command = std::process::Command::new("bash");
        command
            .args([s(&script), s(&model), s(&out)])
            .env("SLURM_ARRAY_TASK_ID", task.to_string())
            .env("SLURM_ARRAY_TASK_MIN", min.to_string())
            .env("SLURM_ARRAY_TASK_MAX", max.to_string())
            .env("SLURM_CPUS_PER_TASK", "1")
            .env("MESHTRACER", exe)
            .env("MESHTRACER_VIEWS", views)
            .env("MESHTRACER_OPTIONS", &joined_options);
        if task % 2 == 0 {
            command.env("SLURM_ARRAY_TASK_COUNT", (max - min + 1).to_string());
        }
        let result = command.output().unwrap();
        assert!(
            result.status.success(),
            "task {task}: {}",
            String::from_utf8_lossy(&result.stderr)
        );
    }
    let records = crate::common::file_names(&out)
        .into_iter()
        .filter(|n| n.to_string_lossy().starts_with("rendered."))
        .count();
    assert_eq!(records, max - min + 1, "one record a task");
    render(&out, &["--resume"]);
    assert_eq!(tree(&out), tree(&whole));
}

/// A view's fingerprint holds the files the model refers to: after an OBJ's material library
/// changes, `--resume` renders every view again, in the new colour.
#[test]
fn resume_renders_again_the_views_of_a_model_whose_material_library_changed() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["shapes.obj", "shapes.mtl"] {
        std::fs::copy(root().join("assets").join(name), dir.path().join(name)).unwrap();
    }
    let model = dir.path().join("shapes.obj");
    let out = dir.path().join("views");
    let mut args = vec![
        "render",
        s(&model),
        "--turntable",
        "2",
        "-o",
        s(&out),
        "--resume",
    ];
    args.extend(["--width", "32", "--height", "24", "--spp", "1"]);
    run(&args, true);
    let err = crate::common::stderr(&run(&args, true));
    assert!(err.contains("no view rendered (2 kept"), "{err}");
    let before = std::fs::read(out.join("000.png")).unwrap();

    let mtl = dir.path().join("shapes.mtl");
    crate::common::recolour_mtl(&mtl);
    let err = crate::common::stderr(&run(&args, true));
    assert_eq!(
        err.matches(
            "rendered again: the options, the model (or a file it refers to) or meshtracer changed"
        )
        .count(),
        2,
        "{err}"
    );
    assert_ne!(std::fs::read(out.join("000.png")).unwrap(), before);
}
