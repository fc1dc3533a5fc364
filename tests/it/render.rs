//! The renderer through the real binary: analytic radiance, a shadow of known shape, camera
//! conventions, determinism, every sample model, and refusals of bad options.

use crate::common::{quads_gltf, read_rgba, run, s, samples, shadow_scene, square, write_gltf};
use serde_json::json;
use std::f32::consts::PI;
use std::path::{Path, PathBuf};

/// Relative tolerance for analytic radiance: the renderer computes in f32 and EXR stores f32,
/// so the only error is rounding in a few dozen operations (~1e-6); 1e-4 leaves margin.
const RADIANCE_TOLERANCE: f32 = 1e-4;

fn white(double_sided: bool) -> serde_json::Value {
    json!({"pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}, "doubleSided": double_sided})
}

/// An orthographic camera node at `z` looking down -Z, seeing [-mag, mag]².
fn ortho_camera_from_above(z: f32, mag: f32) -> serde_json::Value {
    json!({
        "cameras": [{"type": "orthographic", "orthographic": {"xmag": mag, "ymag": mag, "znear": 0.01, "zfar": 100.0}}],
        "nodes": [{"camera": 0, "translation": [0.0, 0.0, z]}]
    })
}

fn merge(mut a: serde_json::Value, b: serde_json::Value) -> serde_json::Value {
    for (k, v) in b.as_object().unwrap() {
        if k == "nodes" {
            let mut list = a
                .get("nodes")
                .and_then(|n| n.as_array().cloned())
                .unwrap_or_default();
            list.extend(v.as_array().unwrap().iter().cloned());
            a["nodes"] = json!(list);
        } else {
            a[k] = v.clone();
        }
    }
    a
}

/// A `size` x `size` render at 1 spp without ambient light, and its normal AOV, as pixels.
fn radiance_and_normals(dir: &Path, model: &Path, size: u32) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
    let normals = dir.join("normal.exr");
    let size = size.to_string();
    let out = render_to(
        dir,
        model,
        "radiance.exr",
        &[
            "--width",
            &size,
            "--height",
            &size,
            "--spp",
            "1",
            "--ambient",
            "0",
            "--normal-out",
            s(&normals),
        ],
    );
    (read_rgba(&out).2, read_rgba(&normals).2)
}

fn render_to(dir: &Path, model: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let out = dir.join(name);
    let mut args = vec!["render", s(model), "-o", s(&out), "--quiet"];
    // The closed forms here are the direct integrator's.
    crate::common::direct_unless_named(&mut args, extra);
    args.extend_from_slice(extra);
    run(&args, true);
    out
}

/// The multiple-scattering scale k and the specular albedo E_s of a GGX lobe at roughness 1
/// seen head-on (n·v = 1, as every pixel of the quads below sees it) for Schlick's (F0, F90):
/// k = 1 + F_ms·(1 - a)/a with Kulla-Conty's F_ms = F_avg·E_avg / (1 - F_avg·(1 - E_avg)),
/// F_avg = F0 + (F90 - F0)/21, and E_s = k·(F0·a + (F90 - F0)·b), with the lobe's albedo
/// (a, b) and average albedo E_avg from the renderer's tables (held against a Monte Carlo
/// estimate by their own unit tests).
fn multiple_scattering(f0: f32, f90: f32) -> (f32, f32) {
    let (a, b) = meshtracer::shading::ggx::directional_albedo(1.0, 1.0);
    let e_avg = meshtracer::shading::ggx::average_albedo(1.0);
    let f_avg = f0 + (f90 - f0) / 21.0;
    let f_ms = f_avg * e_avg / (1.0 - f_avg * (1.0 - e_avg));
    let k = 1.0 + f_ms * (1.0 - a) / a;
    (k, k * (f0 * a + (f90 - f0) * b))
}

/// A white rough dielectric quad 2 m under a 4 cd point light, seen from straight above by an
/// orthographic camera (v = +Z everywhere): every pixel must equal the closed form of each
/// shading model with E = I/d², cosθ = h/d, h = normalize(l + v):
/// - glTF BRDF, roughness 1 (α = 1, so D = 1/π and V = 1/(2(n·l + n·v))), metallic 0:
///   L = ((1 - E_s)/π + k·F·D·V)·E·cosθ with F = 0.04 + 0.96·(1 - v·h)⁵ and the multiple-
///   scattering scale k and specular albedo E_s at n·v = 1 ([`multiple_scattering`]);
/// - Blinn-Phong, exponent 1: L = (1/π + 0.04·9/(8π)·(n·h))·E·cosθ.
#[test]
fn quad_under_a_point_light_matches_the_closed_form() {
    let (k, albedo) = multiple_scattering(0.04, 1.0);
    for shading in ["pbr", "phong"] {
        quad_matches(white(false), shading, |cos, half_z, _| {
            if shading == "pbr" {
                let fresnel = 0.04 + 0.96 * (1.0 - half_z).powi(5);
                (1.0 - albedo) / PI + k * fresnel * (1.0 / PI) * 0.5 / (cos + 1.0)
            } else {
                1.0 / PI + 0.04 * 9.0 / (8.0 * PI) * half_z
            }
        });
    }
}

/// The material extensions on the same quad (roughness 1, so D = 1/π and V = 1/(2(cosθ + 1))
/// as above), each against its closed form, with k and E_s of each Fresnel:
/// - `KHR_materials_specular` (0.5, colour (1, 0.5, 0.25)): per channel F0 = 0.04·colour·0.5,
///   F90 = 0.5, F = F0 + (F90 - F0)(1 - v·h)⁵, f = (1 - E_s)/π + k·F·D·V;
/// - `KHR_materials_ior` 2.0: F0 = (1/3)² instead of 0.04;
/// - `KHR_materials_clearcoat` (1, roughness 1) with v = n: f = f_base·(1 - E_c) + k_c·F_c(v·h)·D·V,
///   E_c and k_c those of the coat's F0 = 0.04.
#[test]
fn material_extensions_on_a_quad_match_their_closed_forms() {
    let schlick = |f0: f32, f90: f32, half_z: f32| f0 + (f90 - f0) * (1.0 - half_z).powi(5);
    let layered = |f0: f32, f90: f32, half_z: f32, cos: f32| {
        let (k, albedo) = multiple_scattering(f0, f90);
        (1.0 - albedo) / PI + k * schlick(f0, f90, half_z) / PI * 0.5 / (cos + 1.0)
    };
    let mut specular = white(false);
    specular["extensions"] = json!({"KHR_materials_specular": {
        "specularFactor": 0.5, "specularColorFactor": [1.0, 0.5, 0.25]}});
    quad_matches(specular, "pbr", |cos, half_z, channel| {
        let f0 = 0.04 * [1.0, 0.5, 0.25][channel] * 0.5;
        layered(f0, 0.5, half_z, cos)
    });
    let mut ior = white(false);
    ior["extensions"] = json!({"KHR_materials_ior": {"ior": 2.0}});
    quad_matches(ior, "pbr", |cos, half_z, _| {
        layered(1.0 / 9.0, 1.0, half_z, cos)
    });
    let mut coat = white(false);
    coat["extensions"] = json!({"KHR_materials_clearcoat": {
        "clearcoatFactor": 1.0, "clearcoatRoughnessFactor": 1.0}});
    let (k_coat, coat_albedo) = multiple_scattering(0.04, 1.0);
    quad_matches(coat, "pbr", |cos, half_z, _| {
        let base = layered(0.04, 1.0, half_z, cos);
        base * (1.0 - coat_albedo) + k_coat * schlick(0.04, 1.0, half_z) / PI * 0.5 / (cos + 1.0)
    });
}

/// A white 4x4 quad of `material` 2 m under a 4 cd point light, seen from straight above by an
/// orthographic camera: every pixel's channel c equals brdf(cosθ, n·h, c)·E·cosθ with E =
/// I/d² (see the test above) within [`RADIANCE_TOLERANCE`].
fn quad_matches(material: serde_json::Value, shading: &str, brdf: impl Fn(f32, f32, usize) -> f32) {
    let dir = tempfile::tempdir().unwrap();
    let (h, intensity) = (2.0f32, 4.0f32);
    let extra = merge(
        ortho_camera_from_above(5.0, 2.0),
        json!({
            "materials": [material],
            "extensionsUsed": ["KHR_lights_punctual"],
            "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": intensity}]}},
            "nodes": [{"translation": [0.0, 0.0, h], "extensions": {"KHR_lights_punctual": {"light": 0}}}]
        }),
    );
    let quad = crate::common::square(2.0, 0.0);
    let (json, bin) = quads_gltf(&[(quad, 0)], extra);
    let model = write_gltf(dir.path(), "quad.gltf", json, &bin);
    let mut args: Vec<&str> = "--width 64 --height 64 --spp 1 --ambient 0"
        .split(' ')
        .collect();
    args.extend(["--shading", shading]);
    let out = render_to(dir.path(), &model, "quad.exr", &args);
    let (w, hgt, pixels) = read_rgba(&out);
    assert_eq!((w, hgt), (64, 64));
    let mut worst = 0.0f32;
    for j in 0..64 {
        for i in 0..64 {
            let x = -2.0 + (i as f32 + 0.5) * 4.0 / 64.0;
            let y = 2.0 - (j as f32 + 0.5) * 4.0 / 64.0;
            let d2 = x * x + y * y + h * h;
            let d = d2.sqrt();
            let cos = h / d;
            let to_light = glam::Vec3::new(-x, -y, h) / d;
            let half = (to_light + glam::Vec3::Z).normalize();
            let got = pixels[(j * 64 + i) as usize];
            assert_eq!(got[3], 1.0, "covered");
            for (c, value) in got[..3].iter().enumerate() {
                let expected = brdf(cos, half.z, c) * intensity / d2 * cos;
                worst = worst.max((value - expected).abs() / expected);
            }
        }
    }
    assert!(
        worst < RADIANCE_TOLERANCE,
        "{shading}: worst relative error {worst}"
    );
}

/// A 1x1 occluder 1 m above a ground plane under a directional light at 45° casts a 1x1 shadow
/// shifted 1 m along +X: pixels clearly inside it are black (no ambient), pixels clearly outside
/// it and the occluder are lit. The same scene at 1e-5 scale (occluder 10 µm up, so shadow rays
/// meet it at t ≈ 1.4e-5) must cast the same shadow: obvhs's box test alone culled hits that
/// close and let the light through.
#[test]
fn occluder_casts_a_shadow_of_known_shape() {
    for scale in [1.0, 1e-5] {
        occluder_shadow_at_scale(scale);
    }
}

fn occluder_shadow_at_scale(scale: f32) {
    let dir = tempfile::tempdir().unwrap();
    let (json, bin) = shadow_scene(scale, 0, json!({"materials": [white(false)]}));
    let model = write_gltf(dir.path(), "shadow.gltf", json, &bin);
    let n = 120u32;
    let out = render_to(
        dir.path(),
        &model,
        "shadow.exr",
        &[
            "--width",
            "120",
            "--height",
            "120",
            "--spp",
            "1",
            "--ambient",
            "0",
        ],
    );
    let (_, _, pixels) = read_rgba(&out);
    let pixel = 6.0 / n as f32;
    let (mut shadowed, mut lit) = (0, 0);
    for j in 0..n {
        for i in 0..n {
            let x = -3.0 + (i as f32 + 0.5) * pixel;
            let y = 3.0 - (j as f32 + 0.5) * pixel;
            let v = pixels[(j * n + i) as usize][0];
            let inside =
                |x0: f32, x1: f32| x > x0 + pixel && x < x1 - pixel && y.abs() < 0.5 - pixel;
            let outside =
                |x0: f32, x1: f32| x < x0 - pixel || x > x1 + pixel || y.abs() > 0.5 + pixel;
            if inside(0.5, 1.5) {
                assert_eq!(
                    v, 0.0,
                    "scale {scale}: pixel ({i},{j}) at x {x} y {y} is in the shadow"
                );
                shadowed += 1;
            } else if outside(0.5, 1.5) && outside(-0.5, 0.5) {
                // E = 2 lux · cos 45° = 1.41 lux on a white rough dielectric: about 0.31.
                assert!(
                    v > 0.25,
                    "scale {scale}: pixel ({i},{j}) at x {x} y {y} is lit, got {v}"
                );
                lit += 1;
            }
        }
    }
    assert!(
        shadowed > 250 && lit > 10_000,
        "scale {scale}: {shadowed} shadowed, {lit} lit"
    );
}

/// glTF 2.0 §3.10: a camera looks down its local -Z with +Y up. A camera node turned 90° about
/// +Y looks down world -X with world -Z to its right; a quad placed up and to the right must
/// fill exactly the top-right quadrant, for both projections.
#[test]
fn camera_conventions_put_a_quad_where_expected() {
    let dir = tempfile::tempdir().unwrap();
    let rotation = glam::Quat::from_rotation_y(std::f32::consts::FRAC_PI_2).to_array();
    // Seen from +X: right is -Z, up is +Y; corners counter-clockwise in that view.
    let quad = [
        [-2.0, 0.0, 0.0],
        [-2.0, 0.0, -2.0],
        [-2.0, 2.0, -2.0],
        [-2.0, 2.0, 0.0],
    ];
    for (name, camera) in [
        (
            "perspective",
            json!({"type": "perspective", "perspective": {"yfov": std::f32::consts::FRAC_PI_2, "znear": 0.1}}),
        ),
        (
            "orthographic",
            json!({"type": "orthographic", "orthographic": {"xmag": 2.0, "ymag": 2.0, "znear": 0.1, "zfar": 50.0}}),
        ),
    ] {
        let extra = json!({
            "materials": [white(false)],
            "cameras": [camera],
            "nodes": [{"camera": 0, "rotation": rotation}]
        });
        let (json, bin) = quads_gltf(&[(quad, 0)], extra);
        let model = write_gltf(dir.path(), &format!("{name}.gltf"), json, &bin);
        let out = render_to(
            dir.path(),
            &model,
            &format!("{name}.png"),
            &["--width", "64", "--height", "64", "--spp", "1"],
        );
        let (_, _, pixels) = read_rgba(&out);
        for j in 0..64 {
            for i in 0..64 {
                let covered = pixels[j * 64 + i][3] > 0.0;
                let expected = i >= 32 && j < 32;
                assert_eq!(covered, expected, "{name}: pixel ({i},{j})");
            }
        }
    }
}

/// Depth of field (`--aperture-radius`, `--focus-distance`): a thin lens blurs an edge off the
/// plane of focus over the circle of confusion the lens model gives, and leaves an edge on
/// that plane sharp. A half-plane (x < 0) 4 m in front of a camera whose view is 1 m tall at
/// 1 m (so 4 m tall at the edge, 128 pixels: 1/32 m a pixel) is seen through a lens of radius
/// 0.25 focused at 2 m: a point 4 m away spreads over a disk of radius A·(d - f)/f = 0.25 m
/// there, 8 pixels. Each column's coverage, averaged over the rows, must be the fraction of
/// that disk on the half-plane's side (box-filtered over the pixel), within 0.03; focused at
/// 4 m the edge is the pinhole's. The view file records the lens and renders the same bytes.
#[test]
fn a_thin_lens_blurs_an_edge_over_its_circle_of_confusion() {
    let dir = tempfile::tempdir().unwrap();
    // 2.5 m each way reaches past the frame (2 m) and the blur (0.25 m); a larger quad would
    // move its edge by the triangle test's tolerance (1e-4 of its size, a pixel's 0.06 at 20 m).
    let edge = [
        [-2.5, -2.5, -4.0],
        [0.0, -2.5, -4.0],
        [0.0, 2.5, -4.0],
        [-2.5, 2.5, -4.0],
    ];
    let yfov = 2.0 * 0.5f32.atan();
    let extra = json!({
        "materials": [white(true)],
        "cameras": [{"type": "perspective", "perspective": {"yfov": yfov, "znear": 0.1}}],
        "nodes": [{"camera": 0}]
    });
    let (json, bin) = quads_gltf(&[(edge, 0)], extra);
    let model = write_gltf(dir.path(), "edge.gltf", json, &bin);
    // The fraction of a unit disk centred x radii right of the edge that lies left of it
    // (the segment beyond a chord x from the centre).
    let left_of = |x: f32| -> f32 {
        let x = x.clamp(-1.0, 1.0);
        (x.acos() - x * (1.0 - x * x).sqrt()) / PI
    };
    let profile = |out: &Path| -> Vec<f32> {
        let (w, h, pixels) = read_rgba(out);
        (0..w as usize)
            .map(|i| {
                (0..h as usize)
                    .map(|j| pixels[j * w as usize + i][3])
                    .sum::<f32>()
                    / h as f32
            })
            .collect()
    };
    for (focus, radius_px) in [("2", 8.0f32), ("4", 0.0)] {
        let name = format!("focus-{focus}.png");
        let view = dir.path().join(format!("focus-{focus}.view.json"));
        let args = [
            "--width",
            "128",
            "--height",
            "128",
            "--spp",
            "256",
            "--aperture-radius",
            "0.25",
            "--focus-distance",
            focus,
            "--view-out",
            s(&view),
        ];
        let out = render_to(dir.path(), &model, &name, &args);
        // The summary says the picture went through a lens.
        let mut loud = vec!["render", s(&model), "-o"];
        let summary_png = dir.path().join("summary.png");
        loud.extend([
            s(&summary_png),
            "--width",
            "16",
            "--height",
            "16",
            "--spp",
            "4",
        ]);
        loud.extend(["--aperture-radius", "0.25", "--focus-distance", focus]);
        let said = crate::common::stderr(&run(&loud, true));
        assert!(
            said.contains(&format!(
                "16x16 through a lens of radius 0.25 focused at {focus} at 4 spp"
            )),
            "{said}"
        );
        for (i, &measured) in profile(&out).iter().enumerate() {
            // Pixel i spans [i - 64, i - 63] in pixels from the edge: its box, in 16 steps.
            let expected = (0..16)
                .map(|k| {
                    let x = i as f32 - 64.0 + (k as f32 + 0.5) / 16.0;
                    if radius_px == 0.0 {
                        f32::from(u8::from(x < 0.0))
                    } else {
                        left_of(x / radius_px)
                    }
                })
                .sum::<f32>()
                / 16.0;
            assert!(
                (measured - expected).abs() < 0.03,
                "focus {focus}: column {i}: coverage {measured}, the lens model {expected}"
            );
        }
        let recorded: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&view).unwrap()).unwrap();
        assert_eq!(recorded["camera"]["aperture_radius"], json!(0.25));
        assert_eq!(
            recorded["camera"]["focus_distance"].as_f64(),
            focus.parse().ok()
        );
        let again = render_to(
            dir.path(),
            &model,
            &format!("again-{focus}.png"),
            &["--spp", "256", "--view", s(&view)],
        );
        assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&again).unwrap());
    }
}

/// Depth-of-field options that cannot make a lens are refused, each naming the option.
#[test]
fn thin_lens_options_that_cannot_make_a_lens_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let model = crate::common::root().join("assets/cornell-box.gltf");
    let out = dir.path().join("out.png");
    for (extra, message) in [
        (
            &["--aperture-radius", "-1"][..],
            "--aperture-radius -1: must be a finite number, 0 or more",
        ),
        (
            &["--aperture-radius", "NaN"][..],
            "--aperture-radius NaN: must be a finite number",
        ),
        (
            &["--aperture-radius", "0.1", "--focus-distance", "0"][..],
            "--focus-distance 0: must be a finite number above 0",
        ),
        (&["--focus-distance", "2"][..], "--aperture-radius"),
        // The file's camera looks away from the model (below): its centre cannot be the plane
        // in focus, alone or as a view of `--views cameras`.
        (
            &["--aperture-radius", "0.1"][..],
            "the scene's centre is not in front of the camera",
        ),
        (
            &["--aperture-radius", "0.1", "--views", "cameras"][..],
            "view 0 does not face the point it would focus on",
        ),
    ] {
        let model = if extra[..2] == ["--aperture-radius", "0.1"]
            && !extra.contains(&"--focus-distance")
        {
            let behind = json!({
                "materials": [white(true)],
                "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
                "nodes": [{"camera": 0, "rotation": [0.0, 1.0, 0.0, 0.0]}]
            });
            let (json, bin) = quads_gltf(&[(square(1.0, -4.0), 0)], behind);
            write_gltf(dir.path(), "behind.gltf", json, &bin)
        } else {
            model.clone()
        };
        // With --views, -o names a folder.
        let out = match extra.contains(&"--views") {
            true => dir.path().join("views"),
            false => out.clone(),
        };
        let mut args = vec![
            "render",
            s(&model),
            "-o",
            s(&out),
            "--width",
            "8",
            "--height",
            "8",
        ];
        args.extend_from_slice(extra);
        let output = run(&args, false);
        let err = crate::common::stderr(&output);
        assert!(err.contains(message), "{extra:?}: {err}");
        assert!(!out.exists(), "{extra:?} left {}", out.display());
    }
}

fn coverage(path: &Path) -> f32 {
    let (_, _, pixels) = read_rgba(path);
    pixels.iter().map(|p| p[3]).sum::<f32>() / pixels.len() as f32
}

#[test]
fn the_cameras_asset_renders_through_both_of_its_cameras() {
    let Some(samples) = samples("the_cameras_asset_renders_through_both_of_its_cameras") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let model = samples.join("Cameras/glTF/Cameras.gltf");
    // The file: a unit quad in XY turned -45° about X, both cameras at (0.5, 0.5, 3) looking
    // down -Z. Its projected outline is a trapezoid whose area, over the view's, is the
    // expected coverage (computed here from the file's numbers, not from the renderer).
    let rotation = glam::Quat::from_xyzw(-0.383, 0.0, 0.0, 0.92375).normalize();
    let corners = [
        glam::Vec3::ZERO,
        glam::Vec3::X,
        glam::Vec3::new(1.0, 1.0, 0.0),
        glam::Vec3::Y,
    ]
    .map(|c| rotation * c);
    let eye = glam::Vec3::new(0.5, 0.5, 3.0);
    let area = |project: &dyn Fn(glam::Vec3) -> glam::Vec2| {
        let p = corners.map(|c| project(c - eye));
        (0..4)
            .map(|i| p[i].perp_dot(p[(i + 1) % 4]))
            .sum::<f32>()
            .abs()
            / 2.0
    };
    let half = 0.35f32.tan(); // yfov 0.7, aspect 1
    let perspective_expected = area(&|v| glam::Vec2::new(v.x, v.y) / (-v.z * half)) / 4.0;
    let ortho_expected = area(&|v| glam::Vec2::new(v.x, v.y)) / 4.0; // xmag = ymag = 1
    for (name, camera, size, expected) in [
        (
            "perspective",
            "0",
            ["--width", "200"].as_slice(),
            perspective_expected,
        ),
        (
            "orthographic",
            "1",
            &["--width", "200", "--height", "200"],
            ortho_expected,
        ),
    ] {
        let mut args = vec!["--camera", camera, "--spp", "16"];
        args.extend_from_slice(size);
        let c = coverage(&render_to(
            dir.path(),
            &model,
            &format!("{name}.png"),
            &args,
        ));
        assert!(
            (c - expected).abs() < 0.005,
            "{name} coverage {c}, expected {expected}"
        );
    }
    let perspective = dir.path().join("perspective.png");
    // Without --camera the first camera is used.
    let default = render_to(
        dir.path(),
        &model,
        "d.png",
        &["--width", "200", "--spp", "16"],
    );
    assert_eq!(
        std::fs::read(default).unwrap(),
        std::fs::read(perspective).unwrap()
    );
}

/// A coarse smooth-shaded UV sphere (8 rings x 12 segments of 30°, vertex normals = positions)
/// seen from +Z, lit by a directional light from +X turned 8° toward the camera. The
/// terminator then runs 8° inside a column of facets whose centres face away from the light,
/// so a per-facet light test (or a shadow ray leaving the flat facet) darkens an 8° band the
/// smooth normals say is lit: the shadow-terminator staircase. Every pixel whose smooth normal (the normal AOV, same pixel-centre ray) faces
/// the light by more than 0.02 must be lit, and every pixel facing away must be black
/// (ambient 0): no staircase and no light leaking round the back.
#[test]
fn a_coarse_smooth_sphere_has_a_smooth_terminator() {
    let dir = tempfile::tempdir().unwrap();
    let tilt = 8f32.to_radians();
    let to_light = glam::Vec3::new(tilt.cos(), 0.0, tilt.sin());
    let (json, bin) =
        crate::common::sphere_gltf((8, 12), glam::Vec3::ZERO, 1.0, to_light, 3.0, white(false));
    let model = write_gltf(dir.path(), "sphere.gltf", json, &bin);
    let n = 160usize;
    let (radiance, normal) = radiance_and_normals(dir.path(), &model, 160);
    let (mut lit, mut dark, mut near_terminator) = (0, 0, 0);
    for i in 0..n * n {
        if radiance[i][3] == 0.0 {
            continue;
        }
        let facing = glam::Vec3::new(normal[i][0], normal[i][1], normal[i][2]).dot(to_light);
        let value = radiance[i][0];
        if facing > 0.02 {
            assert!(
                value > 0.0,
                "pixel {i}: smooth normal faces the light ({facing}) but it is dark"
            );
            lit += 1;
            near_terminator += usize::from(facing < tilt.sin());
        } else if facing < 0.0 {
            assert_eq!(value, 0.0, "pixel {i}: faces away ({facing}) but is lit");
            dark += 1;
        }
    }
    assert!(
        lit > 5_000 && dark > 5_000 && near_terminator > 1_000,
        "{lit} lit, {dark} dark, {near_terminator} in the band"
    );
}

/// Shadow acne, the case that broke the old rule (shadow rays started 1e-5 of the scene's
/// extent off the surface): a finely tessellated unit sphere (48 x 96, edges about 0.065) whose
/// centre lies 22.5 units from the origin, as MetalRoughSpheresNoTextures's spheres lie about 350
/// triangle edges from its origin. Barycentrics then carry errors of about 1e-4 (the edge planes
/// are evaluated with cancellation against coordinates 350 edges large), and the old hit point
/// `Σ bᵢ·pᵢ`, whose weights no longer summed to 1, moved off the plane by 1e-4 x 22.5: ten
/// times the old offset of 2.3e-4, so about one shadow ray in forty re-hit its own triangle.
/// Now the weights are rescaled and the offset is bounded from the hit point's own error
/// ([`meshtracer::geometry::spawn`]): a convex sphere cannot shadow itself, so every pixel whose
/// normal faces the light by more than 0.05 must be lit: not one dark pixel (ambient 0), and the
/// same at 1e-4 and 1e4 times the size and distance.
#[test]
fn a_sphere_far_from_the_origin_has_no_shadow_acne() {
    let dir = tempfile::tempdir().unwrap();
    let to_light = glam::Vec3::new(0.5, 0.6, 0.8).normalize();
    for scale in [1.0f32, 1e-4, 1e4] {
        let (json, bin) = crate::common::sphere_gltf(
            (48, 96),
            glam::Vec3::splat(13.0 * scale),
            scale,
            to_light,
            2.0,
            white(false),
        );
        let model = write_gltf(dir.path(), "far.gltf", json, &bin);
        let (radiance, normal) = radiance_and_normals(dir.path(), &model, 200);
        let (mut facing, mut dark) = (0, 0);
        for (l, n) in radiance.iter().zip(&normal) {
            let n = glam::Vec3::new(n[0], n[1], n[2]);
            if l[3] > 0.0 && n.dot(to_light) > 0.05 {
                facing += 1;
                dark += usize::from(l[0] <= 0.0);
            }
        }
        assert!(
            facing > 10_000,
            "scale {scale}: only {facing} pixels face the light"
        );
        assert_eq!(
            dark, 0,
            "scale {scale}: {dark} of {facing} lit pixels are shadowed (acne)"
        );
    }
}

fn cornell() -> PathBuf {
    crate::common::root().join("assets/cornell-box.gltf")
}

#[test]
fn bvh_and_linear_scan_give_identical_images() {
    let dir = tempfile::tempdir().unwrap();
    let small = ["--width", "96", "--height", "72", "--spp", "2"];
    let bvh = render_to(dir.path(), &cornell(), "bvh.png", &small);
    let mut linear_args = small.to_vec();
    linear_args.extend(["--accel", "linear"]);
    let linear = render_to(dir.path(), &cornell(), "linear.png", &linear_args);
    assert_eq!(std::fs::read(bvh).unwrap(), std::fs::read(linear).unwrap());
}

/// The pixel loop traces each sample's camera rays for eight pixels of a row in one packet
/// query; the linear scan answers them ray by ray. Rows that end in a part packet (93 pixels:
/// two tiles and 29), pixels that stop sampling while their neighbours go on (adaptive
/// sampling) and the AOVs' own centre rays (more than one sample a pixel) must give the same
/// bytes both ways, in both integrators.
#[test]
fn camera_ray_packets_give_the_linear_scans_images() {
    let dir = tempfile::tempdir().unwrap();
    for integrator in ["path", "direct"] {
        let render = |accel: &str| {
            let depth = dir.path().join(format!("{integrator}-{accel}.npy"));
            let args = [
                "--integrator",
                integrator,
                "--width",
                "93",
                "--height",
                "40",
                "--spp",
                "16",
                "--noise",
                "0.2",
                "--no-denoise",
                "--accel",
                accel,
                "--depth-out",
                s(&depth),
            ];
            let name = format!("{integrator}-{accel}.png");
            let image = render_to(dir.path(), &cornell(), &name, &args);
            (std::fs::read(image).unwrap(), std::fs::read(depth).unwrap())
        };
        let (bvh, linear) = (render("bvh"), render("linear"));
        assert!(
            bvh == linear,
            "{integrator}: the BVH's packets changed the image or depth"
        );
    }
}

#[test]
fn output_is_identical_for_any_thread_count_and_run() {
    let dir = tempfile::tempdir().unwrap();
    let args = |t: &'static str| {
        vec![
            "--width",
            "120",
            "--height",
            "90",
            "--spp",
            "4",
            "--threads",
            t,
        ]
    };
    let one = render_to(dir.path(), &cornell(), "one.png", &args("1"));
    let two = render_to(dir.path(), &cornell(), "two.png", &args("2"));
    let again = render_to(dir.path(), &cornell(), "again.png", &args("2"));
    let one = std::fs::read(one).unwrap();
    assert_eq!(one, std::fs::read(two).unwrap());
    assert_eq!(one, std::fs::read(again).unwrap());
}

/// The ray queries, texture filtering and the tile loop with its shading run as x86-64-v3 code
/// where the CPU has it and as baseline code otherwise (`src/cpu.rs`); `MESHTRACER_BASELINE_CPU=1` forces the baseline.
/// Both must give the same bytes: the bundled room and a ground plane receding under a
/// perspective camera with a repeating noise texture (bilinear taps, wrapping, every mip level
/// blended), in both integrators, beauty and depth.
#[test]
fn both_cpu_code_paths_give_identical_images() {
    let dir = tempfile::tempdir().unwrap();
    let noise = image::RgbaImage::from_fn(64, 64, |x, y| {
        let h =
            (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663)).wrapping_mul(2_654_435_761);
        image::Rgba([(h >> 24) as u8, (h >> 16) as u8, (h >> 8) as u8, 255])
    });
    let ground = [
        [-20.0, 0.0, 20.0],
        [20.0, 0.0, 20.0],
        [20.0, 0.0, -20.0],
        [-20.0, 0.0, -20.0],
    ];
    let (json, bin) = quads_gltf(
        &[(ground, 0)],
        json!({
            "images": [{"uri": crate::common::png_data_uri(&noise)}],
            "samplers": [{"wrapS": 10497, "wrapT": 33648, "minFilter": 9987, "magFilter": 9729}],
            "textures": [{"source": 0, "sampler": 0}],
            "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0,
                "extensions": {"KHR_texture_transform": {"scale": [8.0, 8.0]}}},
                "metallicFactor": 0.0, "roughnessFactor": 0.5}}],
            "extensionsUsed": ["KHR_texture_transform"],
            "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.05}}],
            "nodes": [{"camera": 0, "translation": [0.0, 1.0, 6.0], "rotation": [-0.0998, 0.0, 0.0, 0.995]}]
        }),
    );
    let textured = write_gltf(dir.path(), "ground.gltf", json, &bin);
    for (model, integrator) in [
        (cornell(), "direct"),
        (cornell(), "path"),
        (textured.clone(), "direct"),
        (textured, "path"),
    ] {
        let mut outputs = Vec::new();
        for baseline in ["1", "0"] {
            let stem = format!(
                "{}-{integrator}-{baseline}",
                model.file_stem().unwrap().to_string_lossy()
            );
            let out = dir.path().join(format!("{stem}.png"));
            let depth = dir.path().join(format!("{stem}.depth.exr"));
            let status = crate::common::bin()
                .env("MESHTRACER_BASELINE_CPU", baseline)
                .args([
                    "render",
                    s(&model),
                    "-o",
                    s(&out),
                    "--depth-out",
                    s(&depth),
                    "--quiet",
                ])
                .args([
                    "--width",
                    "96",
                    "--height",
                    "72",
                    "--spp",
                    "4",
                    "--integrator",
                    integrator,
                ])
                .status()
                .unwrap();
            assert!(status.success());
            outputs.push((std::fs::read(out).unwrap(), std::fs::read(depth).unwrap()));
        }
        assert!(
            outputs[0].0 == outputs[1].0,
            "{} {integrator}: the baseline and x86-64-v3 images differ",
            model.display()
        );
        assert!(
            outputs[0].1 == outputs[1].1,
            "{} {integrator}: the baseline and x86-64-v3 depths differ",
            model.display()
        );
    }
}

#[test]
fn the_bundled_scenes_render_with_their_lights_and_shadows() {
    let dir = tempfile::tempdir().unwrap();
    let out = render_to(
        dir.path(),
        &cornell(),
        "cb.png",
        &["--width", "160", "--spp", "1"],
    );
    let (w, h, pixels) = read_rgba(&out);
    assert_eq!(
        (w, h),
        (160, 120),
        "the camera's aspectRatio 4:3 sets the height"
    );
    let covered = pixels.iter().filter(|p| p[3] > 0.0).count();
    assert!(
        covered > (w * h) as usize / 2,
        "the room fills most of the frame"
    );
    // The red wall is red, the green wall green (left and right thirds, mid-height).
    let px = |x: u32, y: u32| pixels[(y * w + x) as usize];
    let left = px(22, 50);
    let right = px(137, 50);
    assert!(left[0] > 2.0 * left[1], "left wall {left:?}");
    assert!(right[1] > 1.5 * right[0], "right wall {right:?}");
    // Somewhere is in shadow: some covered pixel is much darker than the median.
    let mut lum: Vec<f32> = pixels
        .iter()
        .filter(|p| p[3] > 0.0)
        .map(|p| p[0] + p[1] + p[2])
        .collect();
    lum.sort_by(f32::total_cmp);
    assert!(
        lum[lum.len() / 50] < 0.25 * lum[lum.len() / 2],
        "shadows exist"
    );

    let obj = render_to(
        dir.path(),
        &crate::common::root().join("assets/shapes.obj"),
        "shapes.png",
        &["--width", "160", "--spp", "1"],
    );
    assert!(coverage(&obj) > 0.1);
}

#[test]
fn linear_float_outputs_are_written() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["cb.exr", "cb.hdr"] {
        let out = render_to(
            dir.path(),
            &cornell(),
            name,
            &["--width", "40", "--spp", "1"],
        );
        let (w, h, pixels) = read_rgba(&out);
        assert_eq!((w, h), (40, 30));
        assert!(pixels.iter().any(|p| p[0] > 0.05), "{name} has content");
    }
}

/// Every sample model renders with visible, non-black content; where the file has a camera,
/// it is the one used.
#[test]
fn every_sample_model_renders_visible_content() {
    let Some(samples) = samples("every_sample_model_renders_visible_content") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let mut problems = Vec::new();
    for (model, _) in MODELS {
        let path = samples.join(model);
        let out = dir.path().join("out.png");
        let result = crate::common::bin()
            .args([
                "render",
                s(&path),
                "-o",
                s(&out),
                "--width",
                "64",
                "--height",
                "48",
                "--spp",
                "1",
                "--quiet",
            ])
            .output()
            .unwrap();
        if !result.status.success() {
            problems.push(format!("{model}: {}", crate::common::stderr(&result)));
            continue;
        }
        let (_, _, pixels) = read_rgba(&out);
        let covered = pixels.iter().filter(|p| p[3] > 0.0).count();
        let bright = pixels
            .iter()
            .filter(|p| p[3] > 0.0 && p[0].max(p[1]).max(p[2]) > 10.0 / 255.0)
            .count();
        if covered < 10 || bright < 5 {
            problems.push(format!(
                "{model}: {covered} covered and {bright} non-black pixels"
            ));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    // Duck has a camera: the default render is the render through camera 0.
    let duck = samples.join("Duck/glTF/Duck.gltf");
    let a = render_to(dir.path(), &duck, "a.png", &["--width", "64", "--spp", "1"]);
    let b = render_to(
        dir.path(),
        &duck,
        "b.png",
        &["--width", "64", "--spp", "1", "--camera", "0"],
    );
    assert_eq!(std::fs::read(a).unwrap(), std::fs::read(b).unwrap());
}

/// Model list shared with the import tests (paths only are used here).
const MODELS: &[(&str, usize)] = &[
    ("Avocado/glTF/Avocado.gltf", 682),
    ("Box/glTF-Binary/Box.glb", 12),
    ("BoxInterleaved/glTF/BoxInterleaved.gltf", 12),
    ("BoxTextured/glTF/BoxTextured.gltf", 12),
    ("Cameras/glTF/Cameras.gltf", 2),
    ("CesiumMilkTruck/glTF-Binary/CesiumMilkTruck.glb", 3624),
    ("CornellBox-OBJ/CornellBox-Mirror.obj", 36),
    ("CornellBox-OBJ/CornellBox-Original.obj", 36),
    ("CornellBox-OBJ/CornellBox-Sphere.obj", 2188),
    ("DamagedHelmet/glTF/DamagedHelmet.gltf", 15452),
    ("Duck/glTF/Duck.gltf", 4212),
    ("Lantern/glTF/Lantern.gltf", 5394),
    ("LightsPunctualLamp/glTF/LightsPunctualLamp.gltf", 6000),
    ("MeshPrimitiveModes/glTF/MeshPrimitiveModes.gltf", 16),
    (
        "MetalRoughSpheresNoTextures/glTF-Binary/MetalRoughSpheresNoTextures.glb",
        1_040_409,
    ),
    ("MultipleScenes/glTF/MultipleScenes.gltf", 2),
    ("OrientationTest/glTF/OrientationTest.gltf", 524),
    ("SimpleSparseAccessor/glTF/SimpleSparseAccessor.gltf", 12),
    ("StanfordBunny-OBJ/stanford-bunny.obj", 69_451),
    ("Suzanne/glTF/Suzanne.gltf", 3936),
    ("TextureCoordinateTest/glTF/TextureCoordinateTest.gltf", 10),
    ("Triangle/glTF/Triangle.gltf", 1),
    ("TriangleWithoutIndices/glTF/TriangleWithoutIndices.gltf", 1),
    ("VikingRoom-OBJ/viking_room.obj", 3828),
];

#[test]
fn bad_options_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let model = cornell();
    let out = |name: &str| dir.path().join(name);
    let refuse = |args: &[&str], needle: &str| {
        let result = run(args, false);
        let err = crate::common::stderr(&result);
        assert!(
            err.contains(needle),
            "{args:?}: expected '{needle}' in: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    };
    // Decided before loading: the model does not even exist.
    refuse(
        &["render", "no-such-model.gltf", "-o", s(&out("x.bmp"))],
        "unknown output format",
    );
    refuse(
        &[
            "render",
            s(&model),
            "-o",
            s(&out("x.png")),
            "--width",
            "0",
            "--height",
            "10",
        ],
        "at least 1",
    );
    refuse(
        &[
            "render",
            s(&model),
            "-o",
            s(&out("x.png")),
            "--width",
            "100000",
            "--height",
            "100000",
        ],
        "over the limit",
    );
    refuse(
        &["render", s(&model), "-o", s(&out("x.png")), "--spp", "0"],
        "--spp",
    );
    refuse(
        &[
            "render",
            s(&model),
            "-o",
            s(&dir.path().join("missing/dir/x.png")),
        ],
        "cannot write here",
    );
    refuse(
        &["render", s(&model), "-o", s(&out("x.png")), "--camera", "7"],
        "--camera 7",
    );
    refuse(
        &[
            "render",
            s(&model),
            "-o",
            s(&out("x.png")),
            "--look-from",
            "1,2",
        ],
        "X,Y,Z",
    );
    // A camera the options cannot make, refused before loading (as a views file's entry is).
    for (camera, needle) in [
        (vec!["--up", "0,0,0"], "must not be zero"),
        (
            vec!["--look-from", "0,1,5", "--look-at", "0,1,5"],
            "are the same point (0,1,5)",
        ),
        (
            vec![
                "--look-from",
                "0,1,5",
                "--look-at",
                "0,1,0",
                "--up",
                "0,0,-2",
            ],
            "--up 0,0,-2: along the view",
        ),
    ] {
        let x = out("x.png");
        let mut args = vec!["render", "no-such-model.gltf", "-o", s(&x)];
        args.extend(camera);
        refuse(&args, needle);
    }
    // The sampling and encoding options: a fraction above 0, a radiance above 0, a known name.
    let png = out("x.png");
    for (option, value, needle) in [
        ("--noise", "0", "not a fraction above 0"),
        ("--noise", "NaN", "not a fraction above 0"),
        ("--clamp-indirect", "0", "not a radiance above 0"),
        ("--clamp-indirect", "inf", "not a radiance above 0"),
        ("--tonemap", "sepia", "khronos-pbr-neutral"),
        ("--yfov", "-10", "--yfov -10: must be between 0 and 180"),
        (
            "--ambient",
            "-0.1",
            "--ambient -0.1,-0.1,-0.1: must be 0 or more",
        ),
    ] {
        refuse(&["render", s(&model), "-o", s(&png), option, value], needle);
    }
    // Nothing was left behind by the refusals.
    let left = crate::common::file_names(dir.path());
    assert!(left.is_empty(), "files left behind: {left:?}");
}

#[test]
fn a_failed_render_keeps_the_existing_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("keep.png");
    std::fs::write(&out, b"previous image").unwrap();
    let broken = dir.path().join("broken.gltf");
    std::fs::write(&broken, b"{\"asset\": 1}").unwrap();
    run(&["render", s(&broken), "-o", s(&out)], false);
    run(
        &["render", s(&cornell()), "-o", s(&out), "--camera", "3"],
        false,
    );
    assert_eq!(std::fs::read(&out).unwrap(), b"previous image");
    // --no-clobber refuses to replace it even when the render would succeed.
    let result = run(
        &[
            "render",
            s(&cornell()),
            "-o",
            s(&out),
            "--no-clobber",
            "--width",
            "8",
        ],
        false,
    );
    assert!(crate::common::stderr(&result).contains("already exists"));
    assert_eq!(std::fs::read(&out).unwrap(), b"previous image");
    let names = crate::common::file_names(dir.path());
    assert_eq!(names.len(), 2, "no temporary files left: {names:?}");
}

/// Every file in `dir` with its bytes, to check that a refused run changed nothing.
fn snapshot(dir: &Path) -> Vec<(std::ffi::OsString, Vec<u8>)> {
    let mut names = crate::common::file_names(dir);
    names.sort();
    names
        .into_iter()
        .filter(|name| dir.join(name).is_file())
        .map(|name| {
            let bytes = std::fs::read(dir.join(&name)).unwrap();
            (name, bytes)
        })
        .collect()
}

#[test]
fn outputs_that_would_destroy_an_input_or_each_other_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = d.join("m.gltf");
    std::fs::copy(cornell(), &model).unwrap();
    // A model read by its content, whatever its extension.
    let as_png = d.join("model.png");
    std::fs::copy(cornell(), &as_png).unwrap();
    std::fs::write(d.join("old.png"), b"previous image").unwrap();
    std::fs::write(d.join("old-depth.png"), b"previous depth").unwrap();
    std::fs::create_dir(d.join("folder.png")).unwrap();
    let before = snapshot(d);
    let p = |name: &str| s(&d.join(name)).to_string();
    let small = ["--width", "16", "--height", "12", "--spp", "1"];
    for (extra, needle) in [
        (
            vec!["-o", &p("m.gltf")],
            "-o would overwrite the model this run renders",
        ),
        (
            vec!["-o", &p("model.png")],
            "-o would overwrite the model this run renders",
        ),
        (
            vec!["-o", &p("x.png"), "--view-out", &p("m.gltf")],
            "--view-out would overwrite the model",
        ),
        (
            vec!["-o", &p("old.png"), "--depth-out", &p("old.png")],
            "named by both -o and --depth-out",
        ),
        (
            vec![
                "-o",
                &p("x.png"),
                "--mask-out",
                &p("a.png"),
                "--normal-out",
                &p("./a.png"),
            ],
            "named by both --normal-out and --mask-out",
        ),
        // A side output that cannot be written stops the run before the image is replaced.
        (
            vec!["-o", &p("old.png"), "--depth-out", &p("no/d.png")],
            "no folder",
        ),
        (
            vec!["-o", &p("old.png"), "--mask-out", &p("folder.png")],
            "is a directory",
        ),
        (
            vec![
                "-o",
                &p("x.png"),
                "--depth-out",
                &p("old-depth.png"),
                "--no-clobber",
            ],
            "old-depth.png: already exists (--no-clobber)",
        ),
    ] {
        let model = if extra[1].ends_with("model.png") {
            &as_png
        } else {
            &model
        };
        let mut args = vec!["render", s(model)];
        args.extend(extra.iter().copied());
        args.extend(small);
        let output = run(&args, false);
        assert_eq!(output.status.code(), Some(1), "{args:?}");
        let err = crate::common::stderr(&output);
        assert!(
            err.contains(needle),
            "{args:?}: expected '{needle}' in: {err}"
        );
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(snapshot(d) == before, "{args:?} changed the folder");
    }
    // The outputs of a textured model may not replace its textures, found once it is loaded.
    if let Some(samples) = samples("outputs_that_would_destroy_an_input") {
        let textured = d.join("bt");
        std::fs::create_dir(&textured).unwrap();
        for name in ["BoxTextured.gltf", "BoxTextured0.bin", "CesiumLogoFlat.png"] {
            std::fs::copy(
                samples.join("BoxTextured/glTF").join(name),
                textured.join(name),
            )
            .unwrap();
        }
        let logo = textured.join("CesiumLogoFlat.png");
        let gltf = textured.join("BoxTextured.gltf");
        let logo_bytes = std::fs::read(&logo).unwrap();
        let mut args = vec!["render", s(&gltf), "-o", s(&logo)];
        args.extend(small);
        let output = run(&args, false);
        let err = crate::common::stderr(&output);
        assert!(
            err.contains("-o would overwrite a file the model refers to"),
            "{err}"
        );
        assert_eq!(std::fs::read(&logo).unwrap(), logo_bytes);
    }
}

/// A depth PNG seen from beyond its 16-bit range says so, and still writes the file.
#[test]
fn a_depth_png_beyond_its_range_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let model = cornell();
    let (out, depth) = (dir.path().join("far.png"), dir.path().join("far-depth.png"));
    let args = [
        "render",
        s(&model),
        "-o",
        s(&out),
        "--depth-out",
        s(&depth),
        "--look-from",
        "0,1,100",
        "--look-at",
        "0,1,0",
        "--yfov",
        "5",
        "--width",
        "16",
        "--height",
        "12",
        "--spp",
        "1",
        "-q",
    ];
    let err = crate::common::stderr(&run(&args, true));
    assert!(err.contains("far-depth.png: "), "{err}");
    assert!(
        err.contains("farther than a 16-bit PNG holds at --depth-scale 0.001"),
        "{err}"
    );
    assert!(depth.exists());
    // In metres the same view fits, and nothing is said.
    let mut metres = args.to_vec();
    metres.extend(["--depth-scale", "1"]);
    let err = crate::common::stderr(&run(&metres, true));
    assert!(!err.contains("16-bit"), "{err}");
}

#[test]
fn the_summary_reports_what_the_render_did() {
    let dir = tempfile::tempdir().unwrap();
    let (model, out) = (cornell(), dir.path().join("x.png"));
    let render = |extra: &[&str]| {
        let mut args = vec!["render", s(&model), "-o", s(&out), "--width", "32"];
        if !extra.contains(&"--spp") {
            args.extend(["--spp", "1"]);
        }
        args.extend_from_slice(extra);
        run(&args, true)
    };
    let err = crate::common::stderr(&render(&[]));
    for needle in [
        "2244 triangles",
        "BVH",
        "built in",
        "rendered in",
        "rays",
        "Mrays/s",
        "samples/s",
        "peak memory",
    ] {
        assert!(err.contains(needle), "'{needle}' missing from: {err}");
    }
    // A noise estimate needs more than one sample per pixel.
    assert!(!err.contains("noise"), "{err}");
    let err = crate::common::stderr(&render(&["--spp", "4"]));
    assert!(err.contains("noise ±"), "{err}");
    assert!(render(&["--quiet"]).stderr.is_empty());
    // --stats: every phase with its time and the peak memory after it.
    let stats = out.with_file_name("stats.json");
    render(&["--quiet", "--stats", s(&stats)]);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    let phases: Vec<&str> = json["phases"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["phase"].as_str().unwrap())
        .collect();
    for phase in [
        "parse and flatten",
        "tangents",
        "textures",
        "bvh build",
        "render",
        "write",
    ] {
        assert!(phases.contains(&phase), "{phase} missing from {phases:?}");
    }
    assert!(json["phases"][0]["seconds"].as_f64().unwrap() >= 0.0);
    // The load's own steps, inside its phase.
    let load = &json["phases"][0];
    let (steps, seconds): (Vec<&str>, Vec<f64>) = load["steps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| (s["step"].as_str().unwrap(), s["seconds"].as_f64().unwrap()))
        .unzip();
    assert_eq!(steps, ["read", "parse", "flatten", "materials and images"]);
    assert!(seconds.iter().sum::<f64>() <= load["seconds"].as_f64().unwrap());
    assert!(json["total_seconds"].as_f64().unwrap() > 0.0);
    assert_eq!(json["triangles"], 2244);
    // The rays by kind add up to the total, and the default (the path tracer) traces each kind.
    let kinds =
        ["primary", "shadow", "indirect"].map(|k| json["rays_by_kind"][k].as_u64().unwrap());
    assert_eq!(kinds.iter().sum::<u64>(), json["rays"].as_u64().unwrap());
    assert!(kinds.iter().all(|&n| n > 0), "{kinds:?}");
}

/// `--view-out` then `--view` renders the same image, byte for byte, for a file camera with
/// file lights, and for the automatic camera with the default rig.
#[test]
fn the_view_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    for (name, model) in [
        ("cornell", cornell()),
        ("shapes", crate::common::root().join("assets/shapes.obj")),
    ] {
        let view = dir.path().join(format!("{name}.json"));
        let first = render_to(
            dir.path(),
            &model,
            &format!("{name}-1.png"),
            &["--width", "96", "--spp", "2", "--view-out", s(&view)],
        );
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&view).unwrap()).unwrap();
        assert_eq!(v["meshtracer_view"], 1);
        assert_eq!(v["image"]["width"], 96);
        assert!(!v["lights"].as_array().unwrap().is_empty());
        assert_eq!(v["default_lights"], name == "shapes");
        let second = render_to(
            dir.path(),
            &model,
            &format!("{name}-2.png"),
            &["--spp", "2", "--view", s(&view)],
        );
        assert_eq!(
            std::fs::read(first).unwrap(),
            std::fs::read(second).unwrap(),
            "{name}"
        );
    }
    // The view file sets the size: --width is ignored, and the render says so.
    let view = dir.path().join("cornell.json");
    let resized = dir.path().join("resized.png");
    let model = cornell();
    let args = [
        "render",
        s(&model),
        "-o",
        s(&resized),
        "--view",
        s(&view),
        "--width",
        "40",
    ];
    let err = crate::common::stderr(&run(&[&args[..], &["--spp", "1", "-q"]].concat(), true));
    assert!(err.contains("--width and --height are ignored"), "{err}");
    assert!(err.contains("sets the image size (96x"), "{err}");
    assert_eq!(image::image_dimensions(&resized).unwrap().0, 96);
    // A hand-edited view with nonsense values is refused with the file named, or rendered
    // without NaN leaking into the image.
    let mut v: serde_json::Value = serde_json::from_slice(&std::fs::read(&view).unwrap()).unwrap();
    v["lights"][0]["range"] = json!(-1.0);
    // An up vector along the view direction leaves the camera's roll undefined.
    let axis: Vec<f64> = (0..3)
        .map(|k| {
            v["camera"]["look_at"][k].as_f64().unwrap()
                - v["camera"]["position"][k].as_f64().unwrap()
        })
        .collect();
    v["camera"]["up"] = json!(axis);
    let edited = dir.path().join("edited.json");
    std::fs::write(&edited, serde_json::to_vec(&v).unwrap()).unwrap();
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, b"{\"meshtracer_view\": 1}").unwrap();
    let (model, out) = (cornell(), dir.path().join("refused.png"));
    for (view, needle) in [(&edited, "up"), (&bad, "bad.json")] {
        let args = ["render", s(&model), "-o", s(&out), "--view", s(view)];
        let err = crate::common::stderr(&run(&args, false));
        assert!(err.contains(needle), "{err}");
        assert!(!out.exists());
    }
}

/// A view file as `--view-out` writes it (path tracer, studio environment, denoise record,
/// segmentation table) reads back without a warning; one with a misspelt key (`yfvo`, or
/// `florr` inside the environment's source) renders with a warning naming the file and the
/// key, and under `--strict` is refused, nothing written.
#[test]
fn a_view_file_key_no_view_has_is_warned_of_and_refused_under_strict() {
    let dir = tempfile::tempdir().unwrap();
    let model = crate::common::root().join("assets/shapes.obj");
    let (view, out) = (dir.path().join("view.json"), dir.path().join("out.png"));
    let segmentation = dir.path().join("segmentation.png");
    let written = [
        "--width",
        "32",
        "--height",
        "24",
        "--denoise",
        "--segmentation-out",
        s(&segmentation),
        "--view-out",
        s(&view),
    ];
    let render = |extra: &[&str], ok: bool| {
        let args = [
            &["render", s(&model), "-o", s(&out), "--spp", "1"][..],
            extra,
        ]
        .concat();
        crate::common::stderr(&run(&args, ok))
    };
    render(&written, true);
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&view).unwrap()).unwrap();
    for key in ["environment", "denoise", "segmentation", "display"] {
        assert!(!v[key].is_null(), "the view file has no {key}: {v}");
    }
    let err = render(&["--view", s(&view), "--strict"], true);
    assert!(!err.contains("warning"), "{err}");

    // A misspelt key of the camera, and one inside the environment's source (a tagged enum,
    // which serde reads apart from the rest).
    let typo_in = |key: &str| {
        let mut typo = v.clone();
        match key {
            "camera.yfvo" => typo["camera"]["yfvo"] = json!(0.5),
            _ => typo["environment"]["source"]["florr"] = json!(0.1),
        }
        typo
    };
    for key in ["camera.yfvo", "environment.source.florr"] {
        let misspelt = dir.path().join("misspelt.json");
        std::fs::write(&misspelt, serde_json::to_vec(&typo_in(key)).unwrap()).unwrap();
        let _ = std::fs::remove_file(&out);
        let err = render(&["--view", s(&misspelt)], true);
        let expected = format!(
            "warning: {}: unknown key '{key}' (misspelt?): ignored",
            misspelt.display()
        );
        assert!(err.contains(&expected), "{err}");
        assert!(out.exists());
        std::fs::remove_file(&out).unwrap();
        let err = render(&["--view", s(&misspelt), "--strict"], false);
        let expected = format!(
            "error: {}: unknown key '{key}' (misspelt?): --strict refuses the file",
            misspelt.display()
        );
        assert!(err.contains(&expected), "{err}");
        assert!(!out.exists(), "nothing written");
    }
}

/// The AOVs of the bundled scene: instance ids match the view's table, normals and depth are
/// set exactly where the mask is, and depth is distance along the view axis.
#[test]
fn aovs_are_consistent_with_each_other_and_the_view() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n);
    render_to(
        dir.path(),
        &cornell(),
        "beauty.png",
        &[
            "--width",
            "80",
            "--spp",
            "1",
            "--normal-out",
            s(&p("normal.exr")),
            "--mask-out",
            s(&p("mask.png")),
            "--segmentation-out",
            s(&p("seg.png")),
            "--view-out",
            s(&p("view.json")),
            "--depth-out",
            s(&p("depth.png")),
        ],
    );
    let view: serde_json::Value =
        serde_json::from_slice(&std::fs::read(p("view.json")).unwrap()).unwrap();
    let table = view["segmentation"].as_array().unwrap();
    assert_eq!(table.len(), 7, "seven mesh instances in the bundled scene");
    let seg = image::open(p("seg.png")).unwrap().to_luma16();
    let mask = image::open(p("mask.png")).unwrap().to_luma8();
    let normals = image::open(p("normal.exr")).unwrap().to_rgba32f();
    let mut seen = std::collections::BTreeSet::new();
    for (i, id) in seg.pixels().enumerate() {
        let id = id.0[0];
        seen.insert(id);
        let (x, y) = (i as u32 % 80, i as u32 / 80);
        let covered = mask.get_pixel(x, y).0[0] == 255;
        assert_eq!(id > 0, covered, "pixel {i}: id {id} vs mask");
        let n = normals.get_pixel(x, y).0;
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!(
            if covered {
                (len - 1.0).abs() < 1e-3
            } else {
                len == 0.0
            },
            "pixel {i}: normal {n:?}"
        );
        assert!(id as usize <= table.len());
    }
    assert!(
        seen.len() >= 6,
        "walls, boxes and sphere are all visible: {seen:?}"
    );
    // The back wall is 4.9 m from the camera along the view axis; in millimetres in the PNG.
    let depth = image::open(p("depth.png")).unwrap().to_luma16();
    let max = depth.pixels().map(|p| p.0[0]).max().unwrap();
    assert!((4895..=4905).contains(&max), "deepest point {max} mm");
}

/// The AOVs describe the pixel centre whatever the sample count: at 1 spp they reuse the
/// camera sample's first hit (which goes through the centre), at 4 spp they trace the centre
/// ray of their own. Both must give the same bytes, with either integrator. (The mask is the
/// beauty's coverage, anti-aliased at 4 spp, so it is not one of them.)
#[test]
fn aovs_at_one_sample_equal_those_of_their_own_centre_ray() {
    let dir = tempfile::tempdir().unwrap();
    let outputs = ["depth.exr", "normal.exr", "seg.png"];
    for integrator in ["direct", "path"] {
        let mut files = Vec::new();
        for spp in ["1", "4"] {
            let p = |n: &str| dir.path().join(format!("{integrator}-{spp}-{n}"));
            let names: Vec<PathBuf> = outputs.iter().map(|n| p(n)).collect();
            render_to(
                dir.path(),
                &cornell(),
                &format!("{integrator}-{spp}.png"),
                &[
                    "--width",
                    "64",
                    "--spp",
                    spp,
                    "--integrator",
                    integrator,
                    "--depth-out",
                    s(&names[0]),
                    "--normal-out",
                    s(&names[1]),
                    "--segmentation-out",
                    s(&names[2]),
                ],
            );
            files.push(
                names
                    .iter()
                    .map(|n| std::fs::read(n).unwrap())
                    .collect::<Vec<_>>(),
            );
        }
        for (k, name) in outputs.iter().enumerate() {
            assert!(
                files[0][k] == files[1][k],
                "{integrator}: {name} differs between 1 and 4 spp"
            );
        }
    }
}

/// Issue 12's measure on the model that showed the acne: MetalRoughSpheresNoTextures at
/// 1024x768, 1 spp, default view and lights, counting isolated dark pixels
/// ([`crate::common::speckles`]: more than 40/255 darker than their 3x3 median) per 10,000 covered
/// pixels, also with a root node scaling the whole model by 1e-4 and 1e4 (the camera fits the
/// model). Before the per-hit offset bound there were about 240; now at most 2 once the four
/// label meshes are hidden (scaled to nothing, same view). With the labels about 30 more
/// remain, and they are real: the key light casts the thin letters' shadows onto a golden
/// sphere behind them, and a stroke thinner than a pixel shadows isolated pixels at 1 spp.
/// The test checks that too: every speckle that the labels add is a pixel they darken.
#[test]
fn metal_rough_spheres_have_no_shadow_acne_at_any_scale() {
    let Some(samples) =
        crate::common::samples("metal_rough_spheres_have_no_shadow_acne_at_any_scale")
    else {
        return;
    };
    let folder = samples.join("MetalRoughSpheresNoTextures/glTF");
    let source = folder.join("MetalRoughSpheresNoTextures.gltf");
    let dir = tempfile::tempdir().unwrap();
    let bin = "MetalRoughSpheresNoTextures.bin";
    std::fs::copy(folder.join(bin), dir.path().join(bin)).unwrap();
    let original: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&source).unwrap()).unwrap();
    let brightness = |p: &[f32; 4]| (p[0] + p[1] + p[2]) / 3.0;
    for scale in [1.0f32, 1e-4, 1e4] {
        let view = dir.path().join("view.json");
        let mut renders = Vec::new();
        for labels in [true, false] {
            let mut json = original.clone();
            let roots = json["scenes"][0]["nodes"].clone();
            let nodes = json["nodes"].as_array_mut().unwrap();
            if !labels {
                let label_group = nodes
                    .iter()
                    .position(|n| n["name"] == "Labels")
                    .expect("the Labels node");
                nodes[label_group]["scale"] = serde_json::json!([1e-6, 1e-6, 1e-6]);
            }
            nodes.push(serde_json::json!({ "children": roots, "scale": [scale, scale, scale] }));
            let root = nodes.len() - 1;
            json["scenes"][0]["nodes"] = serde_json::json!([root]);
            let model = dir.path().join("scaled.gltf");
            std::fs::write(&model, serde_json::to_vec(&json).unwrap()).unwrap();
            let mask = dir.path().join("mask.png");
            let mut args = vec!["--width", "1024", "--height", "768", "--spp", "1"];
            args.extend(["--mask-out", s(&mask)]);
            // The view with labels, kept when they are hidden (the fit would change).
            args.extend([if labels { "--view-out" } else { "--view" }, s(&view)]);
            let image = read_rgba(&render_to(dir.path(), &model, "spheres.png", &args));
            let covered: Vec<bool> = read_rgba(&mask).2.iter().map(|p| p[0] > 0.5).collect();
            let (found, judged) = crate::common::speckles(image.clone(), &covered);
            let per_10k = found.len() as f64 * 1e4 / judged as f64;
            eprintln!(
                "scale {scale}, labels {labels}: {} speckles in {judged} covered pixels \
                 ({per_10k:.2} per 10,000)",
                found.len()
            );
            assert!(judged > 100_000, "scale {scale}: only {judged} covered");
            renders.push((image, found, per_10k));
        }
        let [(with, with_found, _), (without, without_found, per_10k)] = &renders[..] else {
            unreachable!()
        };
        assert!(
            *per_10k <= 2.0,
            "scale {scale}: {per_10k:.2} speckles per 10,000 covered pixels without labels"
        );
        for &(x, y) in with_found {
            let i = (y * with.0 + x) as usize;
            assert!(
                without_found.contains(&(x, y))
                    || brightness(&with.2[i]) < brightness(&without.2[i]) - 0.1,
                "scale {scale}: the speckle at {x},{y} is not a shadow of the labels"
            );
        }
    }
}

/// The near clip plane follows the scene, not the point looked at: a camera 1.0 in front of a
/// unit quad looking through it at a point 100 away covers exactly the pixels it covers
/// looking at a point just behind the quad (the same direction). It once covered none: the
/// near plane was put half way to the look-at point.
#[test]
fn a_far_look_at_point_does_not_clip_a_near_model() {
    let dir = tempfile::tempdir().unwrap();
    let quad = crate::common::square(0.5, 0.0);
    let (json, bin) = quads_gltf(&[(quad, 0)], json!({"materials": [{}]}));
    let model = write_gltf(dir.path(), "quad.gltf", json, &bin);
    let mask = |at: &str| {
        let image = dir.path().join("image.png");
        let mask = dir.path().join(format!("mask-{at}.png"));
        run(
            &[
                "render",
                s(&model),
                "-o",
                s(&image),
                "--width",
                "64",
                "--height",
                "48",
                "--spp",
                "1",
                "-q",
                "--look-from",
                "0.1,0.05,1.0",
                "--look-at",
                at,
                "--mask-out",
                s(&mask),
            ],
            true,
        );
        let (_, _, pixels) = read_rgba(&mask);
        pixels.iter().map(|p| p[0] > 0.5).collect::<Vec<bool>>()
    };
    let near = mask("0.1,0.05,-0.1");
    let far = mask("0.1,0.05,-100");
    let covered = near.iter().filter(|&&c| c).count();
    assert!(
        covered > 64 * 48 / 2,
        "the quad fills most of the frame: {covered}"
    );
    let differing = near.iter().zip(&far).filter(|(a, b)| a != b).count();
    let far_covered = far.iter().filter(|&&c| c).count();
    assert_eq!(
        differing, 0,
        "the same pixels are covered: {covered} looking near, {far_covered} looking far"
    );
}

/// A white rough 4x4 quad 2 m under a point light of `candela`, seen from above by an
/// orthographic camera that sees [-`mag`, `mag`]², written into `dir`.
fn lit_quad(dir: &Path, mag: f32, candela: f32) -> PathBuf {
    let extra = merge(
        ortho_camera_from_above(5.0, mag),
        json!({
            "materials": [white(false)],
            "extensionsUsed": ["KHR_lights_punctual"],
            "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": candela}]}},
            "nodes": [{"translation": [0.0, 0.0, 2.0], "extensions": {"KHR_lights_punctual": {"light": 0}}}]
        }),
    );
    let (json, bin) = quads_gltf(&[(crate::common::square(2.0, 0.0), 0)], extra);
    write_gltf(dir, "quad.gltf", json, &bin)
}

/// `--tonemap`: a quad under a point light bright enough to burn out at its centre (radiance
/// up to about 6), rendered with each view transform. The EXR is the same linear radiance
/// whatever the transform; the PNG is that radiance through the transform (the library's
/// curves, held to their published definitions by a unit test) and the sRGB curve, to within
/// one 8-bit step; the view file records the transform and the exposure; and `compare
/// --tonemap` encodes the EXR as the PNG was encoded (max_abs at most one step).
#[test]
fn tonemap_encodes_the_8_bit_image_and_nothing_else() {
    use meshtracer::color::{linear_to_srgb, ViewTransform};
    let dir = tempfile::tempdir().unwrap();
    let model = lit_quad(dir.path(), 2.0, 80.0);
    let base = [
        "--width",
        "32",
        "--height",
        "32",
        "--spp",
        "1",
        "--ambient",
        "0",
    ];
    let linear = render_to(dir.path(), &model, "linear.exr", &base);
    let (_, _, radiance) = read_rgba(&linear);
    assert!(radiance.iter().any(|p| p[0] > 2.0), "the centre burns out");
    for view in ViewTransform::ALL {
        let mut args = base.to_vec();
        args.extend(["--tonemap", view.name()]);
        let exr = render_to(dir.path(), &model, &format!("{}.exr", view.name()), &args);
        assert_eq!(
            std::fs::read(&exr).unwrap(),
            std::fs::read(&linear).unwrap(),
            "{view:?}: the EXR stays linear"
        );
        let view_file = dir.path().join(format!("{}.view.json", view.name()));
        let view_out = ["--view-out", s(&view_file)];
        args.extend(view_out);
        let png = render_to(dir.path(), &model, &format!("{}.png", view.name()), &args);
        let bytes = image::open(&png).unwrap().to_rgba8();
        for (p, l) in bytes.pixels().zip(&radiance) {
            let expected = view
                .apply(glam::Vec3::new(l[0], l[1], l[2]))
                .to_array()
                .map(|c| linear_to_srgb(c) * 255.0);
            for (got, want) in p.0.iter().zip(expected) {
                assert!(
                    (f32::from(*got) - want).abs() <= 1.0,
                    "{view:?}: {:?} for radiance {l:?}",
                    p.0
                );
            }
        }
        let record: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&view_file).unwrap()).unwrap();
        assert_eq!(record["display"]["view_transform"], view.name());
        assert_eq!(record["display"]["exposure"], 0.0);
        let out = run(
            &[
                "compare",
                s(&exr),
                s(&png),
                "--tonemap",
                view.name(),
                "--json",
            ],
            true,
        );
        let metrics: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert!(
            metrics["max_abs"].as_f64().unwrap() <= 1.0 / 255.0 + 1e-9,
            "{view:?}: {metrics}"
        );
    }
}

/// `render --view` of the view `--view-out` wrote gives the same bytes for cameras whose
/// basis does not survive `look_at - position` in f32: a camera node with a rotated matrix,
/// one with a TRS rotation, the automatic camera of the same scene without them, and (with the
/// samples) the Duck's own camera and a `--look-from` one.
#[test]
fn the_exact_view_round_trips_for_matrix_trs_and_automatic_cameras() {
    let dir = tempfile::tempdir().unwrap();
    // A node rotated 0.7 rad about (1, 2, 3)/√14 and 0.3 rad about y, placed off the axes.
    let (qx, qy, qz, qw) = (0.0642_f64, 0.1284, 0.1926, 0.9699);
    let norm = (qx * qx + qy * qy + qz * qz + qw * qw).sqrt();
    let (x, y, z, w) = (qx / norm, qy / norm, qz / norm, qw / norm);
    let matrix = [
        1.0 - 2.0 * (y * y + z * z),
        2.0 * (x * y + z * w),
        2.0 * (x * z - y * w),
        0.0,
        2.0 * (x * y - z * w),
        1.0 - 2.0 * (x * x + z * z),
        2.0 * (y * z + x * w),
        0.0,
        2.0 * (x * z + y * w),
        2.0 * (y * z - x * w),
        1.0 - 2.0 * (x * x + y * y),
        0.0,
        0.31,
        0.47,
        3.13,
        1.0,
    ];
    let quads = [
        (crate::common::square(0.9, 0.0), 0),
        (crate::common::square(0.3, 0.4), 0),
    ];
    let camera = json!([{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.01}}]);
    let mut models = vec![];
    for (name, node) in [
        ("matrix", json!({"camera": 0, "matrix": matrix})),
        (
            "trs",
            json!({"camera": 0, "translation": [-0.23, 0.61, 2.87], "rotation": [-0.0871, -0.0436, 0.0038, 0.9952]}),
        ),
    ] {
        let (json, bin) = crate::common::quads_gltf(
            &quads,
            json!({"materials": [{}], "cameras": camera, "nodes": [node]}),
        );
        models.push((
            name.to_string(),
            crate::common::write_gltf(dir.path(), &format!("{name}.gltf"), json, &bin),
            vec![],
        ));
    }
    let (json, bin) = crate::common::quads_gltf(&quads, json!({"materials": [{}]}));
    let automatic = crate::common::write_gltf(dir.path(), "auto.gltf", json, &bin);
    models.push(("auto".into(), automatic, vec![]));
    if let Some(samples) = crate::common::samples("the_exact_view_round_trips") {
        let duck = samples.join("Duck/glTF/Duck.gltf");
        models.push(("duck".into(), duck.clone(), vec![]));
        let placed = vec!["--look-from", "1.3,2.1,3.7"];
        models.push(("duck-look-from".into(), duck, placed));
    }
    for (name, model, options) in &models {
        let view = dir.path().join(format!("{name}.view.json"));
        // At 400x300 the Duck's view rebuilt from look_at (files without `forward`) differs.
        let mut args = vec!["--width", "400", "--height", "300", "--spp", "2"];
        args.extend(options.iter().copied());
        let mut first_args = args.clone();
        first_args.extend(["--view-out", s(&view)]);
        let first = render_to(dir.path(), model, &format!("{name}-1.png"), &first_args);
        let second = render_to(
            dir.path(),
            model,
            &format!("{name}-2.png"),
            &["--spp", "2", "--view", s(&view)],
        );
        assert_eq!(
            std::fs::read(first).unwrap(),
            std::fs::read(second).unwrap(),
            "{name}"
        );
    }
}

/// `--noise`: adaptive sampling. A white quad under a point light (the direct integrator), seen
/// from above with a margin: inside the quad every sample of a pixel has the same radiance, so
/// those pixels stop at the first check (4 samples); pixels the quad's edge crosses vary
/// (covered or not) and take more. The render takes far fewer samples than the cap (from
/// `--stats`), agrees with the full `--spp` render (mean radiance within 0.5%, alpha within
/// 2% per edge pixel on average), and is the same bytes with 1 and 2 threads.
#[test]
fn adaptive_sampling_stops_converged_pixels_early() {
    let dir = tempfile::tempdir().unwrap();
    let model = lit_quad(dir.path(), 3.0, 4.0);
    let base = [
        "--width",
        "64",
        "--height",
        "64",
        "--spp",
        "256",
        "--ambient",
        "0",
    ];
    let full = render_to(dir.path(), &model, "full.exr", &base);
    let mut runs = Vec::new();
    for threads in ["1", "2"] {
        let stats = dir.path().join(format!("stats-{threads}.json"));
        let mut args = base.to_vec();
        args.extend([
            "--noise",
            "0.01",
            "--threads",
            threads,
            "--stats",
            s(&stats),
        ]);
        let out = render_to(
            dir.path(),
            &model,
            &format!("adaptive-{threads}.exr"),
            &args,
        );
        let stats: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
        runs.push((std::fs::read(&out).unwrap(), stats, out));
    }
    assert_eq!(runs[0].0, runs[1].0, "1 and 2 threads: the same bytes");
    let samples = runs[0].1["samples"].as_u64().unwrap();
    let cap = 64 * 64 * 256;
    // Inside pixels stop at 4 samples; about 4·64·(4/6) edge pixels may take up to 256.
    assert!(
        samples < cap / 8,
        "{samples} samples of at most {cap}: adaptive sampling stopped too few pixels"
    );
    let (_, _, reference) = read_rgba(&full);
    let (_, _, adaptive) = read_rgba(&runs[0].2);
    let mean = |p: &[[f32; 4]], c: usize| p.iter().map(|v| f64::from(v[c])).sum::<f64>();
    let (a, b) = (mean(&reference, 0), mean(&adaptive, 0));
    assert!((a - b).abs() < 0.005 * a, "mean radiance {b} vs {a}");
    let edge: Vec<(f32, f32)> = reference
        .iter()
        .zip(&adaptive)
        .filter(|(r, _)| r[3] > 0.0 && r[3] < 1.0)
        .map(|(r, a)| (r[3], a[3]))
        .collect();
    assert!(edge.len() > 100, "{} edge pixels", edge.len());
    let alpha_error = edge.iter().map(|(r, a)| (r - a).abs()).sum::<f32>() / edge.len() as f32;
    assert!(
        alpha_error < 0.02,
        "edge coverage off by {alpha_error} on average"
    );
}

/// The default render (no option but the model, the size and the outputs) is the path tracer
/// lit by the built-in studio (shapes.obj has no lights), sampled adaptively to --noise 1 with
/// at most 32 samples a pixel (and at 48x36 all 32), denoised by the built-in filter, and encoded with Khronos
/// PBR Neutral: the view file and the statistics say so, and the image is byte for byte the
/// render that asks for exactly that. `--no-denoise` is the same render to --noise 0.1 without
/// the filter.
#[test]
fn the_default_render_is_the_adaptive_denoised_path_tracer_through_pbr_neutral() {
    let dir = tempfile::tempdir().unwrap();
    let model = crate::common::root().join("assets/shapes.obj");
    let (plain, view, stats) = (
        dir.path().join("default.png"),
        dir.path().join("default.view.json"),
        dir.path().join("default.stats.json"),
    );
    let size = ["--width", "48", "--height", "36", "-q"];
    let mut args = vec!["render", s(&model), "-o", s(&plain), "--view-out", s(&view)];
    args.extend(["--stats", s(&stats)]);
    args.extend(size);
    run(&args, true);
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
    };
    let (view, stats) = (read(&view), read(&stats));
    assert_eq!(view["integrator"], "path", "{view}");
    assert_eq!(view["display"]["view_transform"], "khronos-pbr-neutral");
    assert!(view["environment"].is_object(), "lit by the studio: {view}");
    assert_eq!(view["denoise"]["filter"], "atrous", "{view}");
    assert_eq!(stats["spp"], 32, "the cap");
    assert_eq!(stats["denoised"], true, "{stats}");
    // So small an image takes the cap from the first batch on (its share of the denoised
    // samples, `render::DENOISED_SAMPLES`, is above it).
    let pixels = 48.0 * 36.0;
    let mean = stats["samples"].as_f64().unwrap() / pixels;
    assert_eq!(mean, 32.0, "mean spp");

    let same = |a: &Path, b: &Path| std::fs::read(a).unwrap() == std::fs::read(b).unwrap();
    let explicit = dir.path().join("explicit.png");
    let mut args = vec!["render", s(&model), "-o", s(&explicit)];
    args.extend([
        "--integrator",
        "path",
        "--spp",
        "32",
        "--noise",
        "1",
        "--denoise",
    ]);
    args.extend(["--tonemap", "khronos-pbr-neutral"]);
    args.extend(size);
    run(&args, true);
    assert!(
        same(&plain, &explicit),
        "the default render differs from the settings it documents"
    );

    let (undenoised, its_stats) = (
        dir.path().join("no-denoise.png"),
        dir.path().join("no-denoise.stats.json"),
    );
    let mut args = vec!["render", s(&model), "-o", s(&undenoised), "--no-denoise"];
    args.extend(["--stats", s(&its_stats)]);
    args.extend(size);
    run(&args, true);
    assert_eq!(read(&its_stats)["denoised"], false);
    let mut args = vec!["render", s(&model), "-o", s(&explicit)];
    args.extend(["--integrator", "path", "--spp", "32", "--noise", "0.1"]);
    args.extend(size);
    run(&args, true);
    assert!(
        same(&undenoised, &explicit),
        "--no-denoise differs from the settings it documents"
    );
}

/// Only a whole single image is denoised by default: a crop (like a tile, several views or a
/// turntable, which the filter does not handle) renders to --noise 0.1 without it, and asking
/// for a sampling asks for exactly that image.
#[test]
fn a_crop_or_an_explicit_sampling_is_not_denoised_by_default() {
    let dir = tempfile::tempdir().unwrap();
    let model = crate::common::root().join("assets/shapes.obj");
    let size = ["--width", "48", "--height", "36", "-q"];
    for extra in [
        &["--crop", "0,0,24,18"][..],
        &["--spp", "4"],
        &["--noise", "0.2"],
    ] {
        let (out, stats) = (dir.path().join("out.png"), dir.path().join("stats.json"));
        let mut args = vec!["render", s(&model), "-o", s(&out), "--stats", s(&stats)];
        args.extend(size);
        args.extend(extra);
        run(&args, true);
        let stats: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&stats).unwrap()).unwrap();
        assert_eq!(stats["denoised"], false, "{extra:?}: {stats}");
    }
}

/// The scene of [`direct_lanes_together_give_each_lanes_own_radiance`], prepared, with its
/// direct integrator: a white ground, an occluder above it (BLEND or opaque) and an unlit
/// patch, under a directional and a point light; and its 24 x 24 grid of rays down from z = 5
/// over [-3.5, 3.5]², slightly tilted: the ground's edge (x or y = ±3) falls between grid
/// columns, some rays miss.
fn direct_lanes_scene(
    dir: &Path,
    blend: bool,
) -> (
    meshtracer::prepare::Prepared,
    meshtracer::integrator::Direct,
    Vec<meshtracer::geometry::Ray>,
) {
    use glam::Vec3;
    use meshtracer::geometry::Ray;
    use meshtracer::integrator::Direct;
    use meshtracer::light::PunctualLight;
    use meshtracer::prepare::{PrepareOptions, Prepared};
    let occluder = if blend {
        json!({"pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.2, 0.2, 0.5]}, "alphaMode": "BLEND"})
    } else {
        json!({"pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.2, 0.2, 1.0]}})
    };
    let unlit = json!({"pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.7, 0.3, 1.0]},
        "extensions": {"KHR_materials_unlit": {}}});
    let patch = square(0.5, 0.5).map(|[x, y, z]| [x - 2.0, y + 2.0, z]);
    let extra = json!({
        "materials": [white(true), occluder, unlit],
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_unlit"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "directional", "intensity": 2.0},
            {"type": "point", "intensity": 30.0, "color": [1.0, 0.8, 0.6]}
        ]}},
        "nodes": [
            {"rotation": glam::Quat::from_rotation_arc(Vec3::NEG_Z, Vec3::new(1.0, 0.3, -1.0).normalize()).to_array(),
             "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"translation": [-1.0, 1.5, 2.5], "extensions": {"KHR_lights_punctual": {"light": 1}}}
        ]
    });
    let (json, bin) = quads_gltf(
        &[(square(3.0, 0.0), 0), (square(0.5, 1.0), 1), (patch, 2)],
        extra,
    );
    let model = write_gltf(dir, &format!("lanes-{blend}.gltf"), json, &bin);
    let scene = meshtracer::Scene::load(&model).unwrap();
    let prepared = Prepared::new(scene, &PrepareOptions::default(), &mut Vec::new()).unwrap();
    assert_eq!(prepared.any_alpha(), blend);
    let direct = Direct {
        lights: prepared
            .scene
            .lights
            .iter()
            .map(PunctualLight::new)
            .collect(),
        ambient: Vec3::splat(0.05),
        shading: Default::default(),
    };
    assert_eq!(direct.lights.len(), 2);
    let rays: Vec<Ray> = (0..24 * 24)
        .map(|i| {
            let (x, y) = (
                (i % 24) as f32 / 23.0 * 7.0 - 3.5,
                (i / 24) as f32 / 23.0 * 7.0 - 3.5,
            );
            Ray::new(
                Vec3::new(x, y, 5.0),
                Vec3::new(0.01, -0.02, -1.0).normalize(),
                0.0,
                f32::INFINITY,
            )
        })
        .collect();
    (prepared, direct, rays)
}

/// The direct integrator's samples taken eight at a time (`radiance_many`, which traces each
/// light's shadow rays from all of them as one packet) give what each gives alone, bit for
/// bit, with the same first hits and ray counts: on a ground with an occluder above it and an
/// unlit patch, under a directional and a point light, seen by rays that hit it, miss it or
/// graze its edge, with their first hit traced beforehand (as the pixel loop does) or not; and
/// with the occluder BLEND (shadow rays then cross it attenuated, one at a time, and camera
/// rays go on behind it) and opaque (the packet path).
#[test]
fn direct_lanes_together_give_each_lanes_own_radiance() {
    use glam::Vec3;
    use meshtracer::geometry::Ray;
    use meshtracer::integrator::{CameraRay, Integrator, Lane, RayCounts};
    use meshtracer::sampling::Sampler;
    let dir = tempfile::tempdir().unwrap();
    for blend in [false, true] {
        let (prepared, direct, rays) = direct_lanes_scene(dir.path(), blend);
        let (mut shadows_alone, mut shadows_together) = (0, 0);
        let (mut misses, mut unlit_hits) = (0, 0);
        for (packet, chunk) in rays.chunks(8).enumerate() {
            let mut hits = [None; 8];
            prepared.intersect_camera_many(chunk, &mut hits[..chunk.len()]);
            let lane = |(i, ray): (usize, &Ray)| Lane {
                camera: CameraRay {
                    ray: *ray,
                    spread_base: 0.0,
                    spread_per_distance: 0.0,
                    // Every third packet comes untraced; in the others every fifth ray.
                    traced: (packet % 3 != 0 && i % 5 != 4).then_some(hits[i]),
                },
                sampler: Sampler::for_pixel(1, i as u32, packet as u32),
                first: None,
                guide: None,
                radiance: Vec3::NAN,
                coverage: f32::NAN,
            };
            let mut lanes: Vec<Lane> = chunk.iter().enumerate().map(lane).collect();
            let mut alone = lanes.clone();
            let mut counts = RayCounts::default();
            direct.radiance_many(&prepared, &mut lanes, &mut counts);
            shadows_together += counts.shadow;
            let mut counts_alone = RayCounts::default();
            for l in &mut alone {
                (l.radiance, l.coverage) = direct.radiance(
                    &prepared,
                    &l.camera,
                    &mut l.sampler,
                    &mut counts_alone,
                    &mut l.first,
                    None,
                );
            }
            shadows_alone += counts_alone.shadow;
            assert_eq!(counts, counts_alone, "blend {blend}, packet {packet}");
            for (i, (a, b)) in lanes.iter().zip(&alone).enumerate() {
                let at = format!("blend {blend}, packet {packet}, lane {i}");
                assert_eq!(
                    a.radiance.to_array().map(f32::to_bits),
                    b.radiance.to_array().map(f32::to_bits),
                    "{at}"
                );
                assert_eq!(a.coverage.to_bits(), b.coverage.to_bits(), "{at}");
                assert_eq!(
                    a.first.map(|h| (h.triangle, h.t.to_bits())),
                    b.first.map(|h| (h.triangle, h.t.to_bits())),
                    "{at}"
                );
                misses += usize::from(a.first.is_none());
                // The patch is the third quad: soup triangles 4 and 5.
                unlit_hits += usize::from(a.first.is_some_and(|h| h.triangle >= 4));
            }
        }
        // More lanes than a packet holds: taken eight at a time.
        let mut many: Vec<Lane> = rays[290..310]
            .iter()
            .map(|ray| Lane {
                camera: CameraRay {
                    ray: *ray,
                    spread_base: 0.0,
                    spread_per_distance: 0.0,
                    traced: None,
                },
                sampler: Sampler::for_pixel(1, 0, 0),
                first: None,
                guide: None,
                radiance: Vec3::NAN,
                coverage: f32::NAN,
            })
            .collect();
        let mut counts = RayCounts::default();
        direct.radiance_many(&prepared, &mut many, &mut counts);
        for (lane, ray) in many.iter().zip(&rays[290..]) {
            let camera = CameraRay {
                traced: None,
                ..lane.camera
            };
            let alone = direct.radiance(
                &prepared,
                &camera,
                &mut Sampler::for_pixel(1, 0, 0),
                &mut counts,
                &mut None,
                None,
            );
            assert_eq!((lane.radiance, lane.coverage), alone, "{ray:?}");
        }
        assert!(many.iter().all(|l| l.coverage == 1.0));
        // The scene did what it is here for: lit and shadowed points, misses, the unlit patch.
        assert!(shadows_alone > 500, "{shadows_alone}");
        assert!(
            misses > 20 && unlit_hits > 5,
            "{misses} misses, {unlit_hits} on the patch"
        );
        assert_eq!(shadows_alone, shadows_together);
    }
}

/// `-o F.jpg` writes a baseline JPEG of the PNG's picture over black (JPEG has no alpha), or
/// over `--background`: a quad filling the middle of the frame, its corners uncovered. Held to
/// the PNG over the same background within JPEG's loss at quality 92 (mean 1/255 a channel).
#[test]
fn jpeg_output_is_the_picture_over_the_background() {
    let dir = tempfile::tempdir().unwrap();
    let (json, bin) = crate::common::unit_quad();
    let model = write_gltf(dir.path(), "quad.gltf", json, &bin);
    let size = ["--width", "48", "--height", "32", "--spp", "4"];
    let over = |name: &str, background: &str| {
        let mut extra = size.to_vec();
        if !background.is_empty() {
            extra.extend(["--background", background]);
        }
        read_rgba(&render_to(dir.path(), &model, name, &extra))
    };
    for (background, corner) in [("", 0.0), ("0.2,0.2,0.2", 0.4845)] {
        let (w, h, jpeg) = over("quad.jpg", background);
        let bytes = std::fs::read(dir.path().join("quad.jpg")).unwrap();
        assert_eq!(bytes[..3], [0xFF, 0xD8, 0xFF], "a JPEG file");
        let png_background = if background.is_empty() {
            "0,0,0"
        } else {
            background
        };
        let (pw, ph, png) = over("quad.png", png_background);
        assert_eq!((w, h), (pw, ph));
        assert!(jpeg.iter().all(|p| p[3] == 1.0), "opaque");
        let mean_error = jpeg
            .iter()
            .zip(&png)
            .map(|(a, b)| (0..3).map(|c| (a[c] - b[c]).abs()).sum::<f32>() / 3.0)
            .sum::<f32>()
            / jpeg.len() as f32;
        assert!(mean_error < 1.0 / 255.0, "{background}: {mean_error}");
        // The top-left pixel is background: black, or sRGB(0.2) = 0.4845.
        assert!((jpeg[0][0] - corner).abs() < 2.0 / 255.0, "{:?}", jpeg[0]);
    }
}

/// A UV sphere (16 x 8 segments) as an OBJ file, its faces under smoothing group `group`;
/// with `normals`, each vertex with its exact (radial) normal.
fn uv_sphere_obj(normals: bool, group: &str) -> String {
    let (rings, segments) = (8usize, 16usize);
    let mut v = vec![[0.0f32, 1.0, 0.0]];
    for i in 1..rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let phi = std::f32::consts::TAU * j as f32 / segments as f32;
            v.push([
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            ]);
        }
    }
    v.push([0.0, -1.0, 0.0]);
    let mut text: String = v
        .iter()
        .map(|p| format!("v {} {} {}\n", p[0], p[1], p[2]))
        .collect();
    if normals {
        text.extend(v.iter().map(|p| format!("vn {} {} {}\n", p[0], p[1], p[2])));
    }
    text.push_str(&format!("s {group}\n"));
    let ring = |i: usize, j: usize| 2 + (i - 1) * segments + j % segments;
    let mut face = |corners: &[usize]| {
        let words: Vec<String> = corners
            .iter()
            .map(|c| {
                if normals {
                    format!("{c}//{c}")
                } else {
                    c.to_string()
                }
            })
            .collect();
        text.push_str(&format!("f {}\n", words.join(" ")));
    };
    for j in 0..segments {
        face(&[1, ring(1, j + 1), ring(1, j)]);
        face(&[v.len(), ring(rings - 1, j), ring(rings - 1, j + 1)]);
        for i in 1..rings - 1 {
            face(&[
                ring(i, j),
                ring(i, j + 1),
                ring(i + 1, j + 1),
                ring(i + 1, j),
            ]);
        }
    }
    text
}

/// An OBJ without normals is shaded as its smoothing groups say, as Blender shades it: under
/// `s 1` a UV sphere renders as the same sphere with exact radial normals (RMSE 0.0025
/// measured, threshold 0.01); under `s off` it is faceted (RMSE 0.031 measured, more than
/// 0.02 required).
#[test]
fn obj_smoothing_groups_shade_a_sphere_without_normals_smooth() {
    let dir = tempfile::tempdir().unwrap();
    let render = |name: &str, text: String| {
        let model = dir.path().join(format!("{name}.obj"));
        std::fs::write(&model, text).unwrap();
        let out = dir.path().join(format!("{name}.png"));
        let args = crate::common::small_run("render", s(&model), s(&out), ("96", "96"), "4", &[]);
        run(&args, true);
        read_rgba(&out).2
    };
    let exact = render("exact", uv_sphere_obj(true, "1"));
    let rmse = |pixels: &[[f32; 4]]| {
        let sum: f32 = pixels
            .iter()
            .zip(&exact)
            .map(|(a, b)| (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f32>() / 3.0)
            .sum();
        (sum / pixels.len() as f32).sqrt()
    };
    let smooth = rmse(&render("smooth", uv_sphere_obj(false, "1")));
    let flat = rmse(&render("flat", uv_sphere_obj(false, "off")));
    assert!(
        smooth < 0.01,
        "s 1 without normals: RMSE {smooth} against exact normals"
    );
    assert!(flat > 0.02, "s off: RMSE {flat}, not faceted");
}
