//! Materials through the real binary: alpha MASK lets light through where the texture is
//! transparent, glass shadows follow the transmission texture, a normal map shades like the
//! geometry it imitates, UVs are oriented as glTF says, and the textured sample models render
//! with their textures.

use crate::common::{
    png_data_uri, quads_gltf, read_rgba, run, s, samples, shadow_scene, write_gltf,
};
use serde_json::json;
use std::path::Path;

fn render(dir: &Path, model: &Path, name: &str, extra: &[&str]) -> Vec<[f32; 4]> {
    let out = dir.join(name);
    let mut args = vec![
        "render",
        s(model),
        "-o",
        s(&out),
        "--quiet",
        "--spp",
        "1",
        "--ambient",
        "0",
    ];
    args.extend_from_slice(extra);
    run(&args, true);
    read_rgba(&out).2
}

/// A 1x1 occluder 1 m over the ground, lit at 45° so its shadow falls beside it (x in
/// [0.5, 1.5]). Its MASK texture is transparent on the left half (u < 0.5, x < 0): the left half
/// of the shadow must be lit, the right half dark, and the camera sees the ground through the
/// transparent half.
#[test]
fn alpha_mask_lets_light_and_eye_rays_through_transparent_texels() {
    let dir = tempfile::tempdir().unwrap();
    let texture = image::RgbaImage::from_fn(8, 8, |x, _| {
        if x < 4 {
            image::Rgba([255, 255, 255, 0])
        } else {
            image::Rgba([255, 255, 255, 255])
        }
    });
    let extra = json!({
        "materials": [
            {"pbrMetallicRoughness": {"metallicFactor": 0.0}},
            {"pbrMetallicRoughness": {"metallicFactor": 0.0, "baseColorTexture": {"index": 0}},
             "alphaMode": "MASK", "alphaCutoff": 0.5, "doubleSided": true}
        ],
        "images": [{"uri": png_data_uri(&texture)}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728}],
        "textures": [{"source": 0, "sampler": 0}]
    });
    let (gltf, bin) = shadow_scene(1.0, 1, extra);
    let model = write_gltf(dir.path(), "mask.gltf", gltf, &bin);
    let n = 120usize;
    let pixels = render(
        dir.path(),
        &model,
        "mask.exr",
        &["--width", "120", "--height", "120"],
    );
    let at = |x: f32, y: f32| {
        let i = ((x + 3.0) / 6.0 * n as f32) as usize;
        let j = ((3.0 - y) / 6.0 * n as f32) as usize;
        pixels[j * n + i][0]
    };
    let lit = at(2.5, 0.0);
    assert!(lit > 0.2, "open ground is lit: {lit}");
    // Shadow of the transparent half (x in [0.5, 1.0]): lit like open ground.
    assert!(
        (at(0.75, 0.0) - lit).abs() < 1e-3 * lit,
        "light passes the transparent half: {}",
        at(0.75, 0.0)
    );
    // Shadow of the opaque half (x in [1.0, 1.5]): dark.
    assert_eq!(at(1.25, 0.0), 0.0, "the opaque half casts a shadow");
    // Through the transparent half the camera sees the ground (lit: its shadow is at x > 0.5).
    assert!(
        (at(-0.25, 0.0) - lit).abs() < 1e-3 * lit,
        "the eye sees through: {}",
        at(-0.25, 0.0)
    );
}

/// Share of the open ground's radiance a shadow may differ from the model's prediction by: the
/// model is exact, this covers f32 rounding in the shading of the two regions compared
/// (measured: 1e-6).
const SHADOW_RATIO_TOLERANCE: f32 = 1e-4;

/// What a see-through sheet of base colour (0.9, 0.5, 0.2), transmission 0.8 and ior 1.5 lets
/// a shadow ray through: the luminance of factor × (1 - metallic) × (1 - F0) × base colour =
/// 0.8 × 0.96 × luminance(0.9, 0.5, 0.2) = 0.4327.
fn sheet_transmittance() -> f32 {
    let tint = glam::Vec3::new(0.9, 0.5, 0.2);
    0.8 * (1.0 - 0.04) * tint.dot(glam::Vec3::new(0.2126, 0.7152, 0.0722))
}

/// A 2 x 1 texture: `left` for u < 0.5, `right` for the rest (RGBA8).
fn two_texels(left: [u8; 4], right: [u8; 4]) -> image::RgbaImage {
    image::RgbaImage::from_fn(2, 1, |x, _| image::Rgba(if x == 0 { left } else { right }))
}

/// `patch` merged into `target`: objects member by member, anything else replaced.
fn merge(target: &mut serde_json::Value, patch: &serde_json::Value) {
    match (target.as_object_mut(), patch.as_object()) {
        (Some(target), Some(patch)) => {
            for (k, v) in patch {
                merge(target.entry(k.clone()).or_insert(json!(null)), v);
            }
        }
        _ => *target = patch.clone(),
    }
}

/// The shadow scene with a pane of base colour (0.9, 0.5, 0.2), metallic 0 and
/// `KHR_materials_transmission` 0.8 as the occluder, changed by `edit` (merged into its
/// material, which may use texture 0: `texture`, nearest and clamped), rendered by each
/// integrator (the path tracer with `--bounces 0`: the same direct light through the same
/// shadow rays). The shadow of the pane's left half (u < 0.5) must be black and that of its
/// right half lit at `expected` of the open ground; `halves` names them for the messages.
fn assert_pane_shadows(
    dir: &Path,
    edit: serde_json::Value,
    texture: &image::RgbaImage,
    halves: [&str; 2],
    expected: f32,
) {
    let mut pane = json!({"pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.5, 0.2, 1.0],
            "metallicFactor": 0.0, "roughnessFactor": 0.0},
         "alphaMode": "OPAQUE", "doubleSided": true,
         "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.8}}});
    merge(&mut pane, &edit);
    let alpha_mode = pane["alphaMode"].as_str().unwrap().to_string();
    let mut used = vec!["KHR_lights_punctual".to_string()];
    used.extend(pane["extensions"].as_object().unwrap().keys().cloned());
    let extra = json!({
        "extensionsUsed": used,
        "materials": [{"pbrMetallicRoughness": {"metallicFactor": 0.0}}, pane],
        "images": [{"uri": png_data_uri(texture)}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728, "wrapS": 33071, "wrapT": 33071}],
        "textures": [{"source": 0, "sampler": 0}]
    });
    let (gltf, bin) = shadow_scene(1.0, 1, extra);
    let name = format!("pane-{alpha_mode}-{}", halves[0].replace(' ', "-"));
    let model = write_gltf(dir, &format!("{name}.gltf"), gltf, &bin);
    for integrator in ["direct", "path"] {
        let case = format!("{alpha_mode} pane, {integrator}");
        let name = format!("{name}-{integrator}");
        let (left, right) = pane_shadow_ratios(dir, &model, &name, integrator);
        assert!(
            left < 1e-6,
            "{case}: the {} cast a black shadow: {left}",
            halves[0]
        );
        assert!(
            (right - expected).abs() < SHADOW_RATIO_TOLERANCE,
            "{case}: the {} let {right} through, the model says {expected}",
            halves[1]
        );
    }
}

/// The ground's radiance in the shadow scene `model` rendered by `integrator`, in the shadow of
/// the occluder's left half and of its right half, as shares of the open ground's. Each region
/// stays off the shadow of the occluder's diagonal, where its two triangles' 1e-4 watertight
/// overlap lets a shadow ray cross a see-through sheet twice.
fn pane_shadow_ratios(dir: &Path, model: &Path, name: &str, integrator: &str) -> (f32, f32) {
    let n = 120usize;
    let pixels = render(
        dir,
        model,
        &format!("{name}.exr"),
        &[
            "--width",
            "120",
            "--height",
            "120",
            "--integrator",
            integrator,
            "--bounces",
            "0",
        ],
    );
    // Mean red over the ground x in [x0, x1], y in [y0, y1] (the view shows [-3, 3]²).
    let mean = |(x0, x1): (f32, f32), (y0, y1): (f32, f32)| {
        let (mut sum, mut count) = (0.0, 0.0);
        for (k, p) in pixels.iter().enumerate() {
            let x = -3.0 + ((k % n) as f32 + 0.5) * 6.0 / n as f32;
            let y = 3.0 - ((k / n) as f32 + 0.5) * 6.0 / n as f32;
            if x > x0 && x < x1 && y > y0 && y < y1 {
                sum += p[0];
                count += 1.0;
            }
        }
        sum / count
    };
    let open = mean((2.2, 2.8), (-0.45, 0.45));
    assert!(open > 0.2, "{name}: open ground is lit: {open}");
    // The pane's left half shades x in [0.5, 1.0] (its diagonal's shadow: x - 1 = y), its
    // right half [1.0, 1.5].
    let left = mean((0.6, 0.9), (0.1, 0.45)) / open;
    let right = mean((1.1, 1.4), (-0.45, -0.1)) / open;
    (left, right)
}

/// A thin glass pane whose transmission texture is opaque on the left half (red 0, the other
/// channels 1, which must not count) and clear on the right (red 1, the others 0): shadow rays
/// through a thin sheet are attenuated by what it lets straight through at the point, with
/// transmission = factor × texture red. So the opaque half's shadow is black and the clear
/// half's is lit at 0.4327 of the open ground ([`sheet_transmittance`]), in both integrators.
/// Before the texture was read there, both halves let 0.4327 through. The same pane as a MASK
/// material (alpha 1 over the cutoff: present everywhere) casts the same shadows; before, a
/// MASK sheet's shadow was black throughout.
#[test]
fn shadows_through_glass_follow_its_transmission_texture() {
    let dir = tempfile::tempdir().unwrap();
    let texture = two_texels([0, 255, 255, 255], [255, 0, 0, 255]);
    for mode in ["OPAQUE", "MASK"] {
        let edit = json!({"alphaMode": mode, "extensions": {"KHR_materials_transmission": {
            "transmissionTexture": {"index": 0}}}});
        let halves = ["opaque texels", "clear texels"];
        assert_pane_shadows(dir.path(), edit, &texture, halves, sheet_transmittance());
    }
}

/// The same pane as a `KHR_materials_volume` boundary (thicknessFactor 0.05) whose thickness
/// texture is 0 on the right half (green 0, red 1, which must not count) and full on the left
/// (green 1, red 0): where the thickness is 0 the surface is thin-walled and lets shadow rays
/// through like the thin pane (0.4327 of the open ground); where it is a volume it bends light,
/// which a straight shadow ray cannot follow, so it blocks them (black), in both integrators.
/// Before the texture was read, the whole pane was a volume and both halves were black.
#[test]
fn shadows_through_a_volume_pass_where_its_thickness_texture_is_0() {
    let dir = tempfile::tempdir().unwrap();
    let texture = two_texels([0, 255, 0, 255], [255, 0, 0, 255]);
    let edit = json!({"extensions": {"KHR_materials_volume": {
        "thicknessFactor": 0.05, "thicknessTexture": {"index": 0}}}});
    let halves = ["volume half", "thin-walled half"];
    assert_pane_shadows(dir.path(), edit, &texture, halves, sheet_transmittance());
}

/// Shadows through glass read its base colour and metallic textures as camera rays do. A pane
/// of metallicFactor 1 (the glTF default, which StainedGlassLamp's and LightsPunctualLamp's
/// glass keep) whose metallic-roughness texture is metal on the left (blue 1) and dielectric on
/// the right (blue 0): the metal half blocks, the dielectric half lets 0.4327 through, as the
/// pane of metallic 0 does. And a white pane whose base colour texture is black on the left and
/// sRGB (242, 188, 124) on the right: black, and 0.8 × 0.96 × the luminance of that colour
/// decoded to linear. Before, shadow rays took the factors alone: the first pane blocked
/// everywhere (metal) and the second let 0.8 × 0.96 through everywhere.
#[test]
fn shadows_through_glass_follow_its_base_colour_and_metallic_textures() {
    let dir = tempfile::tempdir().unwrap();
    let metal = two_texels([0, 0, 255, 255], [0, 0, 0, 255]);
    let edit = json!({"pbrMetallicRoughness": {"metallicFactor": 1.0,
        "metallicRoughnessTexture": {"index": 0}}});
    let halves = ["metal half", "dielectric half"];
    assert_pane_shadows(dir.path(), edit, &metal, halves, sheet_transmittance());
    let srgb = [242u8, 188, 124];
    let linear = srgb.map(|c| {
        let c = c as f32 / 255.0;
        ((c + 0.055) / 1.055).powf(2.4)
    });
    let colour = two_texels([0, 0, 0, 255], [srgb[0], srgb[1], srgb[2], 255]);
    let edit = json!({"pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0],
        "baseColorTexture": {"index": 0}}});
    let halves = ["black texels", "coloured texels"];
    let expected =
        0.8 * 0.96 * glam::Vec3::from(linear).dot(glam::Vec3::new(0.2126, 0.7152, 0.0722));
    assert_pane_shadows(dir.path(), edit, &colour, halves, expected);
}

/// A flat quad with a constant normal map tilting its normal 30° toward +X shades, at its
/// centre, like a quad actually turned 30° about +Y (normal (sin 30°, 0, cos 30°)).
#[test]
fn a_normal_mapped_quad_shades_like_the_tilted_geometry() {
    let dir = tempfile::tempdir().unwrap();
    let (sin, cos) = 30f32.to_radians().sin_cos();
    let encode = |c: f32| ((c * 0.5 + 0.5) * 255.0).round() as u8;
    let normal_map = image::RgbaImage::from_pixel(
        1,
        1,
        image::Rgba([encode(sin), encode(0.0), encode(cos), 255]),
    );
    let lights = json!({
        "cameras": [{"type": "orthographic", "orthographic": {"xmag": 1.0, "ymag": 1.0, "znear": 0.01, "zfar": 100.0}}],
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 3.0}]}},
        "nodes": [
            {"camera": 0, "translation": [0.0, 0.0, 5.0]},
            {"rotation": glam::Quat::from_rotation_arc(glam::Vec3::NEG_Z, glam::Vec3::new(-0.6, -0.2, -1.0).normalize()).to_array(),
             "extensions": {"KHR_lights_punctual": {"light": 0}}}
        ]
    });
    let material = json!({"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.6}});
    let mut mapped_material = material.clone();
    mapped_material["normalTexture"] = json!({"index": 0});
    let mut extra = lights.clone();
    extra["materials"] = json!([mapped_material]);
    extra["images"] = json!([{"uri": png_data_uri(&normal_map)}]);
    extra["textures"] = json!([{"source": 0}]);
    let flat = crate::common::square(1.0, 0.0);
    let (gltf, bin) = quads_gltf(&[(flat, 0)], extra);
    let mapped_model = write_gltf(dir.path(), "mapped.gltf", gltf, &bin);
    // The real thing: the same quad turned 30° about +Y (x' = x cos, z' = -x sin).
    let tilted = [
        [-cos, -1.0, sin],
        [cos, -1.0, -sin],
        [cos, 1.0, -sin],
        [-cos, 1.0, sin],
    ];
    let mut extra = lights;
    extra["materials"] = json!([material]);
    let (gltf, bin) = quads_gltf(&[(tilted, 0)], extra);
    let tilted_model = write_gltf(dir.path(), "tilted.gltf", gltf, &bin);
    let size = ["--width", "33", "--height", "33"];
    let a = render(dir.path(), &mapped_model, "mapped.exr", &size)[16 * 33 + 16];
    let b = render(dir.path(), &tilted_model, "tilted.exr", &size)[16 * 33 + 16];
    // 8-bit normal encoding moves the normal by up to ~0.4%: 2% covers it.
    assert!(
        (a[0] - b[0]).abs() < 0.02 * b[0],
        "normal-mapped {} vs tilted {}",
        a[0],
        b[0]
    );
    assert!(b[0] > 0.05, "the tilted quad is lit: {}", b[0]);
}

/// TextureCoordinateTest: the image's top-left corner is mapped to the model's top-left
/// square, which must come out yellow ("Top Left"), and so on around the model.
#[test]
fn texture_coordinates_are_oriented_as_gltf_says() {
    let Some(samples) = samples("texture_coordinates_are_oriented_as_gltf_says") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let model = samples.join("TextureCoordinateTest/glTF/TextureCoordinateTest.gltf");
    let out = dir.path().join("tc.png");
    let look = ["--look-from", "0,0,6", "--look-at", "0,0,0", "--yfov", "40"];
    let mut args = vec![
        "render",
        s(&model),
        "-o",
        s(&out),
        "--quiet",
        "--width",
        "100",
        "--height",
        "100",
        "--spp",
        "4",
    ];
    args.extend_from_slice(&look);
    crate::common::direct_unless_named(&mut args, &[]);
    run(&args, true);
    let (_, _, px) = read_rgba(&out);
    // Each square's colour: the per-channel median of 9x9 pixels around its centre, so that
    // the label written in it (sharp enough to read at this size) does not count.
    let at = |x: usize, y: usize| {
        let mut channels: [Vec<f32>; 4] = Default::default();
        for dy in 0..9 {
            for dx in 0..9 {
                let p = px[(y + dy - 4) * 100 + x + dx - 4];
                for (c, v) in channels.iter_mut().zip(p) {
                    c.push(v);
                }
            }
        }
        channels.map(|mut c| {
            c.sort_by(f32::total_cmp);
            c[c.len() / 2]
        })
    };
    let (tl, tr, bl, br) = (at(32, 32), at(68, 32), at(32, 68), at(68, 68));
    assert!(
        tl[0] > 0.5 && tl[1] > 0.5 && tl[2] < 0.3,
        "top left is yellow: {tl:?}"
    );
    assert!(
        tr[0] > 0.5 && tr[1] < 0.5 && tr[2] < 0.3,
        "top right is red-orange: {tr:?}"
    );
    assert!(bl[2] > 0.5 && bl[0] < 0.3, "bottom left is blue: {bl:?}");
    assert!(
        br[1] > 0.5 && br[0] < 0.3 && br[2] < 0.3,
        "bottom right is green: {br:?}"
    );
}

/// The textured sample models render with their textures: the image differs from the same
/// model whose textures are shrunk to one texel each (--max-texture-memory 0).
#[test]
fn textured_samples_render_with_their_textures() {
    let Some(samples) = samples("textured_samples_render_with_their_textures") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    for model in [
        "DamagedHelmet/glTF/DamagedHelmet.gltf",
        "Suzanne/glTF/Suzanne.gltf",
        "Avocado/glTF/Avocado.gltf",
        "BoxTextured/glTF/BoxTextured.gltf",
        "CesiumMilkTruck/glTF/CesiumMilkTruck.gltf",
        "VikingRoom-OBJ/viking_room.obj",
    ] {
        let path = samples.join(model);
        let full = dir.path().join("full.png");
        let tiny = dir.path().join("tiny.png");
        let base = [
            "render",
            s(&path),
            "--quiet",
            "--width",
            "64",
            "--height",
            "48",
            "--spp",
            "1",
        ];
        let mut a = base.to_vec();
        a.extend(["-o", s(&full)]);
        run(&a, true);
        let mut b = base.to_vec();
        b.extend(["-o", s(&tiny), "--max-texture-memory", "0"]);
        run(&b, true);
        let (_, _, p) = read_rgba(&full);
        let (_, _, q) = read_rgba(&tiny);
        let differing = p
            .iter()
            .zip(&q)
            .filter(|(x, y)| (x[0] - y[0]).abs() + (x[1] - y[1]).abs() + (x[2] - y[2]).abs() > 0.05)
            .count();
        assert!(
            differing > 20,
            "{model}: textures change only {differing} pixels"
        );
    }
}

/// EXT_texture_webp: the WebP source is chosen when present, and the core `source` is the
/// fallback when the WebP image cannot be read (here: bytes that are not an image).
#[test]
fn webp_textures_are_chosen_and_fall_back_to_the_core_source() {
    use base64::Engine;
    let dir = tempfile::tempdir().unwrap();
    let red = image::RgbaImage::from_pixel(2, 2, image::Rgba([255, 0, 0, 255]));
    let mut webp = Vec::new();
    image::DynamicImage::ImageRgba8(image::RgbaImage::from_pixel(
        2,
        2,
        image::Rgba([0, 255, 0, 255]),
    ))
    .write_to(
        &mut std::io::Cursor::new(&mut webp),
        image::ImageFormat::WebP,
    )
    .unwrap();
    let uri = |bytes: &[u8]| {
        format!(
            "data:image/webp;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(bytes)
        )
    };
    let load = |webp_uri: String| {
        let (json, bin) = quads_gltf(
            &[(crate::common::square(1.0, 0.0), 0)],
            json!({
                "extensionsUsed": ["EXT_texture_webp"],
                "extensionsRequired": ["EXT_texture_webp"],
                "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
                "textures": [{"source": 0, "extensions": {"EXT_texture_webp": {"source": 1}}}],
                "images": [{"uri": png_data_uri(&red)}, {"uri": webp_uri}],
            }),
        );
        let model = write_gltf(dir.path(), "webp.gltf", json, &bin);
        meshtracer::Scene::load(&model).unwrap()
    };
    let good = load(uri(&webp));
    assert_eq!(good.textures[0].image, 1, "the WebP source is used");
    assert_eq!(good.textures[0].fallback_image, Some(0));
    assert!(good.warnings.is_empty(), "{:?}", good.warnings);
    let broken = load(uri(b"RIFF\x10\0\0\0WEBPjunk"));
    assert_eq!(
        broken.textures[0].image, 0,
        "the core source is the fallback"
    );
    assert!(
        broken.warnings.iter().any(|w| w.contains("fallback")),
        "{:?}",
        broken.warnings
    );
}

/// A uniform glass pane (transmission 0.8, no texture) casts a uniform shadow, its diagonal
/// included: the pane's two triangles overlap by the triangle test's tolerance along their
/// shared edge, and a shadow ray through that edge used to cross the sheet twice (0.4327² =
/// 0.187 along the diagonal's shadow, the line x - 1 = y, which the pixel centres with
/// column + row = 139 sample exactly). Every pixel of the shadow, the diagonal's too, must be
/// lit at 0.4327 of the open ground, in both integrators.
#[test]
fn a_glass_pane_shadow_has_no_line_along_its_diagonal() {
    let dir = tempfile::tempdir().unwrap();
    let pane = json!({"pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.5, 0.2, 1.0],
            "metallicFactor": 0.0, "roughnessFactor": 0.0},
         "doubleSided": true,
         "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.8}}});
    let extra = json!({
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_transmission"],
        "materials": [{"pbrMetallicRoughness": {"metallicFactor": 0.0}}, pane],
    });
    let (gltf, bin) = shadow_scene(1.0, 1, extra);
    let model = write_gltf(dir.path(), "pane.gltf", gltf, &bin);
    let n = 120usize;
    for integrator in ["direct", "path"] {
        let pixels = render(
            dir.path(),
            &model,
            &format!("pane-{integrator}.exr"),
            &[
                "--width",
                "120",
                "--height",
                "120",
                "--integrator",
                integrator,
                "--bounces",
                "0",
            ],
        );
        let at = |i: usize, j: usize| pixels[j * n + i][0];
        let open = at(110, 60);
        assert!(open > 0.2, "{integrator}: open ground is lit: {open}");
        let mut diagonal = 0;
        for j in 0..n {
            for i in 0..n {
                let x = -3.0 + (i as f32 + 0.5) * 0.05;
                let y = 3.0 - (j as f32 + 0.5) * 0.05;
                // Inside the shadow (x in [0.5, 1.5], |y| < 0.5), a pixel away from its rim.
                if !(x > 0.55 && x < 1.45 && y.abs() < 0.45) {
                    continue;
                }
                diagonal += usize::from(i + j == 139);
                let ratio = at(i, j) / open;
                assert!(
                    (ratio - sheet_transmittance()).abs() < SHADOW_RATIO_TOLERANCE,
                    "{integrator}: pixel ({i}, {j}) at ({x}, {y}) lets {ratio} through, the model says {}",
                    sheet_transmittance()
                );
            }
        }
        assert!(diagonal >= 15, "{diagonal} pixels on the diagonal's shadow");
    }
}

/// `KHR_materials_pbrSpecularGlossiness` by the extension's equations (c_diff = diffuse ·
/// (1 - max(specular)), F0 = specular, roughness = 1 - glossiness): a smooth sphere under a
/// directional light must render as the metallic-roughness material with the same BRDF inputs,
/// with the direct integrator and the path tracer alike. A coloured dielectric three ways
/// (factors alone; factors times a specular-glossiness texture whose sRGB RGB and linear alpha
/// give the same values; the core material with `KHR_materials_specular` for the coloured F0)
/// and a gold metal three ways (specular-glossiness with a black diffuse, alone and beside a
/// green metallic-roughness fallback, which must not be drawn; metallic 1). The same
/// inputs differ only by float rounding (0.04 · 25·L against L), so every pixel must agree with
/// the first rendering of its group within 1e-5 of the brightest pixel (measured: 4e-7, and 0
/// where the inputs are the same floats).
#[test]
fn specular_glossiness_renders_as_its_metallic_roughness_equivalent() {
    let dir = tempfile::tempdir().unwrap();
    let srgb = |c: f32| ((c + 0.055) / 1.055).powf(2.4);
    let l = srgb(188.0 / 255.0);
    let texel = image::RgbaImage::from_pixel(1, 1, image::Rgba([188, 188, 188, 153]));
    let sg = |ext: serde_json::Value| json!({"extensions": {"KHR_materials_pbrSpecularGlossiness": ext}});
    let dielectric = [
        sg(
            json!({"diffuseFactor": [0.8, 0.8, 0.8, 1.0], "specularFactor": [l, 0.6 * l, 0.4 * l], "glossinessFactor": 0.6}),
        ),
        sg(
            json!({"diffuseFactor": [0.8, 0.8, 0.8, 1.0], "specularFactor": [1.0, 0.6, 0.4], "glossinessFactor": 1.0,
                  "specularGlossinessTexture": {"index": 0}}),
        ),
        json!({"pbrMetallicRoughness": {"baseColorFactor": [0.8 * (1.0 - l), 0.8 * (1.0 - l), 0.8 * (1.0 - l), 1.0],
                                        "metallicFactor": 0.0, "roughnessFactor": 0.4},
               "extensions": {"KHR_materials_specular": {"specularColorFactor": [25.0 * l, 15.0 * l, 10.0 * l]}}}),
    ];
    let gold = [
        sg(
            json!({"diffuseFactor": [0.0, 0.0, 0.0, 1.0], "specularFactor": [1.0, 0.766, 0.336], "glossinessFactor": 0.7}),
        ),
        json!({"pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.766, 0.336, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.3}}),
        // A metallic-roughness fallback beside the extension is not what is drawn.
        json!({"pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.9, 0.2, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
               "extensions": {"KHR_materials_pbrSpecularGlossiness":
                   {"diffuseFactor": [0.0, 0.0, 0.0, 1.0], "specularFactor": [1.0, 0.766, 0.336], "glossinessFactor": 0.7}}}),
    ];
    let sphere = |name: &str, material: &serde_json::Value| {
        let to_light = glam::Vec3::new(0.4, 0.5, 0.8).normalize();
        let (mut json, bin) = crate::common::sphere_gltf(
            (32, 64),
            glam::Vec3::ZERO,
            1.0,
            to_light,
            3.0,
            material.clone(),
        );
        // TEXCOORD_0 from the positions' x and y (the texture is one texel: any coordinates do).
        json["bufferViews"][0]["byteStride"] = json!(12);
        let count = json["accessors"][0]["count"].clone();
        json["accessors"]
            .as_array_mut()
            .unwrap()
            .push(json!({"bufferView": 0, "componentType": 5126, "count": count, "type": "VEC2"}));
        json["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(2);
        json["extensionsUsed"] = json!([
            "KHR_lights_punctual",
            "KHR_materials_pbrSpecularGlossiness",
            "KHR_materials_specular"
        ]);
        json["images"] = json!([{"uri": png_data_uri(&texel)}]);
        json["textures"] = json!([{"source": 0}]);
        let model = write_gltf(dir.path(), &format!("{name}.gltf"), json, &bin);
        crate::common::copy_to_corpus(&model);
        model
    };
    for (group, materials) in [("dielectric", &dielectric[..]), ("gold", &gold[..])] {
        for integrator in [
            &["--integrator", "direct", "--ambient", "0", "--spp", "1"][..],
            &["--integrator", "path", "--spp", "4", "--no-denoise"][..],
        ] {
            let images: Vec<Vec<[f32; 4]>> = materials
                .iter()
                .enumerate()
                .map(|(i, m)| {
                    let model = sphere(&format!("{group}-{i}"), m);
                    let out = dir.path().join(format!("{group}-{i}.exr"));
                    let mut args = vec!["render", s(&model), "-o", s(&out), "--quiet"];
                    args.extend(["--width", "48", "--height", "48"]);
                    args.extend_from_slice(integrator);
                    run(&args, true);
                    read_rgba(&out).2
                })
                .collect();
            let brightest = images[0]
                .iter()
                .flat_map(|p| &p[..3])
                .fold(0f32, |a, &b| a.max(b));
            assert!(
                brightest > 0.1,
                "{group} {integrator:?}: dark ({brightest})"
            );
            for (i, image) in images.iter().enumerate().skip(1) {
                let worst = image
                    .iter()
                    .zip(&images[0])
                    .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
                    .fold(0f32, f32::max);
                assert!(
                    worst <= 1e-5 * brightest,
                    "{group} {integrator:?}: material {i} differs from material 0 by {worst} (brightest {brightest})"
                );
            }
        }
    }
}

/// `KHR_materials_anisotropy` stretches a highlight along its direction: a white metal plane
/// (roughness 0.2) seen from above, a point light beside the camera, so the highlight sits
/// around the mirror point. Its spread (the second moments of the pixels' radiance) along x and
/// y: isotropic (no extension, or strength 0) the two agree within 10%; with strength 0.8 along
/// the tangent (texture u, +x here, from MikkTSpace: the quad has no TANGENT) the highlight's
/// spread along x is at least ten times that along y (measured: 67); rotated by π/2
/// (`anisotropyRotation`), or by a texture whose red-green vector points along the bitangent,
/// it is ten times wider along y.
#[test]
fn anisotropy_stretches_the_highlight_along_its_direction() {
    let dir = tempfile::tempdir().unwrap();
    let direction = image::RgbaImage::from_pixel(1, 1, image::Rgba([128, 255, 255, 255]));
    let spread = |name: &str, anisotropy: Option<serde_json::Value>| -> (f64, f64) {
        let mut material = json!({"pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0],
            "metallicFactor": 1.0, "roughnessFactor": 0.2}});
        if let Some(a) = anisotropy {
            material["extensions"] = json!({"KHR_materials_anisotropy": a});
        }
        let extra = json!({
            "materials": [material],
            "images": [{"uri": png_data_uri(&direction)}],
            "textures": [{"source": 0}],
            "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_anisotropy"],
            "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 20.0}]}},
            "nodes": [{"translation": [0.05, 0.0, 2.0], "extensions": {"KHR_lights_punctual": {"light": 0}}}]
        });
        let (gltf, bin) = quads_gltf(&[(crate::common::square(3.0, 0.0), 0)], extra);
        let model = write_gltf(dir.path(), &format!("{name}.gltf"), gltf, &bin);
        crate::common::copy_to_corpus(&model);
        let n = 96;
        let camera = [
            "--look-from",
            "0,0,2",
            "--look-at",
            "0,0,0",
            "--up",
            "0,1,0",
            "--yfov",
            "70",
            "--width",
            "96",
            "--height",
            "96",
            "--integrator",
            "direct",
        ];
        let radiance = render(dir.path(), &model, &format!("{name}.exr"), &camera);
        assert_eq!(radiance.len(), n * n);
        let (mut sum, mut mx, mut my) = (0.0f64, 0.0f64, 0.0f64);
        let weight = |p: &[f32; 4]| f64::from(p[0] + p[1] + p[2]);
        for (i, p) in radiance.iter().enumerate() {
            let (x, y) = ((i % n) as f64, (i / n) as f64);
            sum += weight(p);
            mx += weight(p) * x;
            my += weight(p) * y;
        }
        assert!(sum > 0.0, "{name}: black");
        let (cx, cy) = (mx / sum, my / sum);
        let (mut vx, mut vy) = (0.0f64, 0.0f64);
        for (i, p) in radiance.iter().enumerate() {
            let (x, y) = ((i % n) as f64 - cx, (i / n) as f64 - cy);
            vx += weight(p) * x * x;
            vy += weight(p) * y * y;
        }
        (vx / sum, vy / sum)
    };
    let (ix, iy) = spread("isotropic", None);
    assert!((ix / iy - 1.0).abs() < 0.1, "isotropic: {ix} x {iy}");
    let (zx, zy) = spread("zero", Some(json!({"anisotropyStrength": 0.0})));
    assert!((zx / zy - 1.0).abs() < 0.1, "strength 0: {zx} x {zy}");
    let (ax, ay) = spread("along-u", Some(json!({"anisotropyStrength": 0.8})));
    assert!(ax > 10.0 * ay, "along the tangent: {ax} x {ay}");
    let (rx, ry) = spread(
        "rotated",
        Some(json!({"anisotropyStrength": 0.8, "anisotropyRotation": std::f32::consts::FRAC_PI_2})),
    );
    assert!(ry > 10.0 * rx, "rotated by π/2: {rx} x {ry}");
    let (tx, ty) = spread(
        "textured",
        Some(json!({"anisotropyStrength": 0.8, "anisotropyTexture": {"index": 0}})),
    );
    assert!(ty > 10.0 * tx, "texture along the bitangent: {tx} x {ty}");
}

/// `KHR_materials_diffuse_transmission` against its closed form: a quad (specular factor 0,
/// so the diffuse base keeps all the light) with diffuse transmission 0.5 of colour
/// (1, 0.5, 0.25), seen head-on by an orthographic camera, under a directional light of π lux
/// at normal incidence. Lit from behind, it shows weight · colour · E/π = (0.5, 0.25, 0.125);
/// lit from the front, its white base reflects (1 - weight) · E/π = 0.5 in every channel.
/// Each within 0.1% (a delta light on a flat quad: no noise).
#[test]
fn diffuse_transmission_lets_a_backlit_sheet_glow_by_its_closed_form() {
    let dir = tempfile::tempdir().unwrap();
    for (name, travel, expected) in [
        ("backlit", glam::Vec3::Z, [0.5f32, 0.25, 0.125]),
        ("frontlit", glam::Vec3::NEG_Z, [0.5, 0.5, 0.5]),
    ] {
        let rotation = glam::Quat::from_rotation_arc(glam::Vec3::NEG_Z, travel);
        let extra = json!({
            "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_specular", "KHR_materials_diffuse_transmission"],
            "materials": [{
                "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0},
                "extensions": {
                    "KHR_materials_specular": {"specularFactor": 0.0},
                    "KHR_materials_diffuse_transmission": {
                        "diffuseTransmissionFactor": 0.5,
                        "diffuseTransmissionColorFactor": [1.0, 0.5, 0.25]
                    }
                }
            }],
            "cameras": [{"type": "orthographic", "orthographic": {"xmag": 0.5, "ymag": 0.5, "znear": 0.01, "zfar": 10.0}}],
            "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": std::f32::consts::PI}]}},
            "nodes": [
                {"camera": 0, "translation": [0.0, 0.0, 2.0]},
                {"rotation": rotation.to_array(), "extensions": {"KHR_lights_punctual": {"light": 0}}}
            ]
        });
        let (gltf, bin) = quads_gltf(&[(crate::common::square(1.0, 0.0), 0)], extra);
        let model = write_gltf(dir.path(), &format!("{name}.gltf"), gltf, &bin);
        crate::common::copy_to_corpus(&model);
        // Pixel centres (the helper's one sample a pixel): a delta light on a flat quad.
        let pixels = render(
            dir.path(),
            &model,
            &format!("{name}.exr"),
            &[
                "--width",
                "8",
                "--height",
                "8",
                "--integrator",
                "path",
                "--no-default-lights",
            ],
        );
        for (i, p) in pixels.iter().enumerate() {
            for c in 0..3 {
                assert!(
                    (p[c] - expected[c]).abs() < 1e-3 * expected[c],
                    "{name}, pixel {i}, channel {c}: {} against {}",
                    p[c],
                    expected[c]
                );
            }
        }
    }
}

/// `KHR_materials_anisotropy` needs a tangent frame: a mesh with neither TANGENT nor texture
/// coordinates (which the extension forbids) is drawn isotropic, and the render says so once,
/// with the count of such triangles (88: the 6 x 8 sphere but its 8 degenerate pole
/// triangles); a mesh with texture coordinates gets MikkTSpace tangents
/// and no such warning.
#[test]
fn anisotropy_without_tangents_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let material = json!({"pbrMetallicRoughness": {"metallicFactor": 1.0, "roughnessFactor": 0.3},
        "extensions": {"KHR_materials_anisotropy": {"anisotropyStrength": 0.8}}});
    let (json, bin) = crate::common::sphere_gltf(
        (6, 8),
        glam::Vec3::ZERO,
        1.0,
        glam::Vec3::Z,
        3.0,
        material.clone(),
    );
    let sphere = write_gltf(dir.path(), "sphere.gltf", json, &bin);
    let (json, bin) = quads_gltf(
        &[(crate::common::square(1.0, 0.0), 0)],
        json!({"materials": [material]}),
    );
    let quad = write_gltf(dir.path(), "quad.gltf", json, &bin);
    let warned = |model: &Path| {
        let out = dir.path().join("out.png");
        let args = [
            "render",
            s(model),
            "-o",
            s(&out),
            "-q",
            "--width",
            "16",
            "--height",
            "16",
        ];
        crate::common::stderr(&run(&args, true))
    };
    let err = warned(&sphere);
    assert_eq!(
        err.matches("88 triangles with KHR_materials_anisotropy have no tangents")
            .count(),
        1,
        "{err}"
    );
    let err = warned(&quad);
    assert!(!err.contains("have no tangents"), "{err}");
}

/// Where an orthographic ray straight down at `x` meets the plane z = -3 after refracting
/// through the wedge of [`dispersion_splits_an_edge_seen_through_a_glass_wedge`] (top face
/// z = 1 + x·tan A, bottom face z = 0) of index `ior`, by Snell's law in the xz-plane.
fn through_wedge(x: f64, ior: f64, tilt: f64) -> f64 {
    // d refracted at a surface whose normal n faces against it, from index 1 to `eta`·… :
    // t = eta·d + (eta·cos_i - cos_t)·n.
    let refract = |d: (f64, f64), n: (f64, f64), eta: f64| {
        let cos_i = -(d.0 * n.0 + d.1 * n.1);
        let cos_t = (1.0 - eta * eta * (1.0 - cos_i * cos_i)).sqrt();
        let k = eta * cos_i - cos_t;
        (eta * d.0 + k * n.0, eta * d.1 + k * n.1)
    };
    let z_top = 1.0 + x * tilt.tan();
    let inside = refract((0.0, -1.0), (-tilt.sin(), tilt.cos()), 1.0 / ior);
    let x_bottom = x + z_top / -inside.1 * inside.0;
    let out = refract(inside, (0.0, 1.0), ior);
    x_bottom + 3.0 / -out.1 * out.0
}

/// `KHR_materials_dispersion` through the real binary, against Snell's law. An orthographic
/// camera looks straight down through a glass wedge (index 1.5, its top face tilted by 20°)
/// at an emitter that ends at x = 0, 3 below. Refraction moves the emitter's edge in the
/// image; with dispersion 2 (the channels' indices 1.475, 1.5 and 1.525) each colour channel's
/// edge lies where that channel's index puts it (computed by [`through_wedge`]), red and blue
/// about 6 pixels apart, each within a pixel; with dispersion 0 all three lie at the
/// index 1.5 edge. A dispersed path keeps its channel when it leaves the glass, so the lit
/// side is as bright in each channel as without dispersion (within 5%).
#[test]
fn dispersion_splits_an_edge_seen_through_a_glass_wedge() {
    let dir = tempfile::tempdir().unwrap();
    let tilt = 20f64.to_radians();
    let (width, height) = (200usize, 20usize);
    let top = |x: f32| 1.0 + x * (tilt.tan() as f32);
    let quads = [
        (
            [
                [-2.0, -1.0, top(-2.0)],
                [2.0, -1.0, top(2.0)],
                [2.0, 1.0, top(2.0)],
                [-2.0, 1.0, top(-2.0)],
            ],
            0,
        ),
        (
            [
                [-2.0, 1.0, 0.0],
                [2.0, 1.0, 0.0],
                [2.0, -1.0, 0.0],
                [-2.0, -1.0, 0.0],
            ],
            0,
        ),
        (
            [
                [-10.0, -10.0, -3.0],
                [0.0, -10.0, -3.0],
                [0.0, 10.0, -3.0],
                [-10.0, 10.0, -3.0],
            ],
            1,
        ),
    ];
    let mut levels = Vec::new();
    for dispersion in [2.0f64, 0.0] {
        let extra = json!({
            "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_volume", "KHR_materials_dispersion"],
            "materials": [
                {
                    "doubleSided": true,
                    "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.0},
                    "extensions": {
                        "KHR_materials_transmission": {"transmissionFactor": 1.0},
                        "KHR_materials_volume": {"thicknessFactor": 1.0},
                        "KHR_materials_dispersion": {"dispersion": dispersion}
                    }
                },
                {"pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0]}, "emissiveFactor": [1.0, 1.0, 1.0]}
            ],
            "cameras": [{"type": "orthographic", "orthographic": {"xmag": 1.0, "ymag": 0.1, "znear": 0.01, "zfar": 20.0}}],
            "nodes": [{"camera": 0, "translation": [0.0, 0.0, 5.0]}]
        });
        let (gltf, bin) = quads_gltf(&quads, extra);
        let name = format!("wedge-{dispersion}");
        let model = write_gltf(dir.path(), &format!("{name}.gltf"), gltf, &bin);
        crate::common::copy_to_corpus(&model);
        let out = dir.path().join(format!("{name}.exr"));
        let (w, h) = (width.to_string(), height.to_string());
        run(
            &[
                "render",
                s(&model),
                "-o",
                s(&out),
                "--quiet",
                "--integrator",
                "path",
                "--spp",
                "64",
                "--width",
                &w,
                "--height",
                &h,
                "--no-default-lights",
            ],
            true,
        );
        let pixels = read_rgba(&out).2;
        for c in [0usize, 1, 2] {
            // The column means over the rows (the scene does not change along y); the lit
            // level from the leftmost 15 columns; the edge where the lit columns' sum ends.
            let column = |i: usize| {
                (0..height).map(|r| pixels[r * width + i][c]).sum::<f32>() / height as f32
            };
            let lit = (0..15).map(column).sum::<f32>() / 15.0;
            let edge = -1.0 + (0..width).map(column).sum::<f32>() / lit * 2.0 / width as f32;
            let ior = 1.5 + (c as f64 - 1.0) * 0.5 * 0.025 * dispersion;
            // The pixel column x where the ray lands on the emitter's edge (x_hit rises with x).
            let (mut lo, mut hi) = (-1.0f64, 1.0f64);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if through_wedge(mid, ior, tilt) < 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let expected = 0.5 * (lo + hi);
            assert!(
                (f64::from(edge) - expected).abs() < 2.0 / width as f64,
                "dispersion {dispersion}, channel {c} (index {ior}): the edge at x = {edge}, Snell's law puts it at {expected}"
            );
            levels.push(lit);
        }
    }
    for c in 0..3 {
        let (dispersed, plain) = (levels[c], levels[3 + c]);
        assert!(
            (dispersed - plain).abs() < 0.05 * plain,
            "channel {c}: lit at {dispersed} with dispersion, {plain} without"
        );
    }
}

/// OBJ vertex colours (`v x y z r g b`, what mesh-generating and scanning tools write instead
/// of a texture) are display colours that multiply the material's `Kd`: a quad with `Kd 1 1 1`
/// and colours (1, 0.5, 0.2) renders as the same quad without colours and with `Kd` set to
/// those colours decoded from sRGB (within a level of the 8-bit image), and not as the plain
/// quad; 8-bit colours (0..255) render as 0..1 ones.
#[test]
fn obj_vertex_colours_multiply_the_diffuse_colour() {
    let dir = tempfile::tempdir().unwrap();
    let srgb = |c: f32| {
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    let quad = |name: &str, kd: [f32; 3], colour: Option<[f32; 3]>| {
        let mtl = format!("{name}.mtl");
        std::fs::write(
            dir.path().join(&mtl),
            format!("newmtl m\nKd {} {} {}\n", kd[0], kd[1], kd[2]),
        )
        .unwrap();
        let rgb = colour.map_or(String::new(), |c| format!(" {} {} {}", c[0], c[1], c[2]));
        let mut obj = format!("mtllib {mtl}\nusemtl m\n");
        for (x, y) in [(-1, -1), (1, -1), (1, 1), (-1, 1)] {
            obj += &format!("v {x} {y} 0{rgb}\n");
        }
        obj += "vn 0 0 1\nf 1//1 2//1 3//1 4//1\n";
        let path = dir.path().join(format!("{name}.obj"));
        std::fs::write(&path, obj).unwrap();
        path
    };
    let colour = [1.0, 0.5, 0.2];
    let coloured = quad("coloured", [1.0; 3], Some(colour));
    let bytes = quad("bytes", [1.0; 3], Some(colour.map(|c| c * 255.0)));
    let kd = quad("kd", colour.map(srgb), None);
    let plain = quad("plain", [1.0; 3], None);
    let view = [
        "--integrator",
        "direct",
        "--tonemap",
        "standard",
        "--width",
        "32",
        "--height",
        "32",
        "--look-from",
        "0,0,3",
        "--look-at",
        "0,0,0",
    ];
    let image = |model: &Path, name: &str| render(dir.path(), model, name, &view);
    let coloured = image(&coloured, "coloured.png");
    let by_kd = image(&kd, "kd.png");
    let largest = coloured
        .iter()
        .zip(&by_kd)
        .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
        .fold(0.0f32, f32::max);
    assert!(
        largest <= 1.0 / 255.0 + 1e-6,
        "largest difference {largest}"
    );
    assert_eq!(
        coloured,
        image(&bytes, "bytes.png"),
        "0..255 colours as 0..1"
    );
    // The centre: orange under the colours, white without.
    let centre = 16 * 32 + 16;
    let (c, p) = (coloured[centre], image(&plain, "plain.png")[centre]);
    assert!(c[0] > 0.5 && c[2] < 0.5 * c[0], "{c:?}");
    assert!((p[0] - p[2]).abs() < 0.01, "{p:?}");
}

/// MTL texture statements as Blender's importer reads them: options first (`-s`, `-o` as the
/// texture coordinates' scale and offset, applied in OBJ's bottom-left texture space), then
/// the file as the rest of the line, its name with a space and a Windows path separator, and
/// written in another letter case than the file on disk (found, with a warning naming both).
/// An 8x8 texture of four coloured quadrants on a quad that fills the view: plain, it shows
/// as drawn; `-s 0.5 0.5` shows only its bottom-left quadrant; `-o 0.5 0` swaps its halves
/// left and right; `-o 0 0.5` top and bottom.
#[test]
fn obj_texture_statements_read_as_blender_reads_them() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("Maps")).unwrap();
    let (red, blue, green, yellow) = ([255, 0, 0], [0, 0, 255], [0, 255, 0], [255, 255, 0]);
    let texture = image::RgbImage::from_fn(8, 8, |x, y| {
        image::Rgb(match (x < 4, y < 4) {
            (true, true) => red,
            (false, true) => blue,
            (true, false) => green,
            (false, false) => yellow,
        })
    });
    texture.save(dir.path().join("Maps/Quad Tex.PNG")).unwrap();
    let quad = |name: &str, options: &str| {
        let mtl = format!("{name}.mtl");
        std::fs::write(
            dir.path().join(&mtl),
            format!("newmtl m\nKd 1 1 1\nmap_Kd {options} maps\\quad tex.png\n"),
        )
        .unwrap();
        let obj = format!(
            "mtllib {mtl}\nusemtl m\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n\
             vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1 4/4/1\n"
        );
        let path = dir.path().join(format!("{name}.obj"));
        std::fs::write(&path, obj).unwrap();
        path
    };
    // The colours at the quad's four quadrants (top-left, top-right, bottom-left,
    // bottom-right of the image), each named by which channels are lit.
    let quadrants = |name: &str, options: &str| {
        let model = quad(name, options);
        let out = dir.path().join(format!("{name}.png"));
        let view = ["--look-from", "0,0,2", "--look-at", "0,0,0", "--yfov", "40"];
        let args = crate::common::small_run("render", s(&model), s(&out), ("64", "64"), "1", &view);
        let output = run(&args, true);
        let warnings = crate::common::stderr(&output);
        assert!(
            warnings.contains("'maps\\quad tex.png' names no file; 'Maps/Quad Tex.PNG' differs from it only in letter case"),
            "{warnings}"
        );
        let (width, _, pixels) = read_rgba(&out);
        let at = |x: usize, y: usize| {
            let p = pixels[y * width as usize + x];
            let lit = |c: f32| if c > 0.25 { 255u8 } else { 0 };
            [lit(p[0]), lit(p[1]), lit(p[2])]
        };
        [at(20, 20), at(44, 20), at(20, 44), at(44, 44)]
    };
    assert_eq!(quadrants("plain", ""), [red, blue, green, yellow]);
    assert_eq!(quadrants("scaled", "-s 0.5 0.5 1"), [green; 4]);
    assert_eq!(
        quadrants("shifted-u", "-o 0.5 0 0 -clamp off"),
        [blue, red, yellow, green]
    );
    assert_eq!(
        quadrants("shifted-v", "-bm 1 -o 0 0.5"),
        [green, yellow, red, blue]
    );
}

/// Renders to `out` (64x64, one sample, the direct integrator) an OBJ quad of 2x2 facing +z,
/// its UVs spanning the texture, whose one material `m` is `mtl` (the MTL's lines after
/// `newmtl`), written as `{name}.obj` and `{name}.mtl` into `dir`, seen from 2 units away
/// with a vertical field of view of 40° (the quad fills the frame). Returns the standard error.
fn render_quad_obj(dir: &Path, name: &str, mtl: &str, out: &Path) -> String {
    std::fs::write(
        dir.join(format!("{name}.mtl")),
        format!("newmtl m\n{mtl}\n"),
    )
    .unwrap();
    let obj = format!(
        "mtllib {name}.mtl\nusemtl m\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n\
         vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1 4/4/1\n"
    );
    let model = dir.join(format!("{name}.obj"));
    std::fs::write(&model, obj).unwrap();
    let view = ["--look-from", "0,0,2", "--look-at", "0,0,0", "--yfov", "40"];
    let args = crate::common::small_run("render", s(&model), s(out), ("64", "64"), "1", &view);
    crate::common::stderr(&run(&args, true))
}

/// MTL's maps as Blender 5.2's importer links them: each texture takes the place of its
/// property (`map_Kd` of `Kd`, `map_Ke` of `Ke`, `map_d` of `d`, `map_Pr` of `Pr`, `map_Pm`
/// of `Pm`), and the scalar ones read one channel of the image (luminance, or for `map_d` the
/// alpha of an image with transparency; `-imfchan` names another). Each map is an 8x8 image
/// whose left half reads 0 and right half 1, on a quad that fills the view: the left half of
/// the render must be the render of the property set to 0 and the right half the render of
/// it set to 1 (within 2/255, away from the seam), and those two must differ.
#[test]
fn obj_scalar_and_colour_maps_replace_their_property() {
    let dir = tempfile::tempdir().unwrap();
    let halves = |name: &str, left: [u8; 4], right: [u8; 4]| {
        image::RgbaImage::from_fn(8, 8, |x, _| image::Rgba(if x < 4 { left } else { right }))
            .save(dir.path().join(name))
            .unwrap();
    };
    image::GrayImage::from_fn(8, 8, |x, _| image::Luma([if x < 4 { 0 } else { 255 }]))
        .save(dir.path().join("grey.png"))
        .unwrap();
    // Colour everywhere, its transparency on the left: alpha is what map_d reads.
    halves("cutout.png", [255, 255, 255, 0], [0, 0, 0, 255]);
    // Opaque: luminance is what it reads. Red is the mask, green its inverse.
    halves("red.png", [0, 255, 0, 255], [255, 0, 0, 255]);
    halves("white.png", [255; 4], [255; 4]);
    let render = |name: &str, mtl: &str| {
        let out = dir.path().join(format!("{name}.png"));
        render_quad_obj(dir.path(), name, mtl, &out);
        read_rgba(&out).2
    };
    let differ = |a: &[[f32; 4]], b: &[[f32; 4]], x: std::ops::Range<usize>| {
        (4..60)
            .flat_map(|y| x.clone().map(move |x| y * 64 + x))
            .map(|i| {
                (0..4)
                    .map(|c| (a[i][c] - b[i][c]).abs())
                    .fold(0.0, f32::max)
            })
            .fold(0.0, f32::max)
    };
    let cases = [
        (
            "kd",
            "Kd 0.2 0.5 0.9\nmap_Kd grey.png",
            "Kd 0 0 0",
            "Kd 1 1 1",
        ),
        (
            "ke",
            "Kd 0 0 0\nmap_Ke grey.png",
            "Kd 0 0 0\nKe 0 0 0",
            "Kd 0 0 0\nKe 1 1 1",
        ),
        ("d-grey", "d 0.5\nmap_d grey.png", "d 0", "d 1"),
        ("d-alpha", "map_d cutout.png", "d 0", "d 1"),
        ("d-imfchan", "map_d -imfchan r red.png", "d 0", "d 1"),
        (
            "pr",
            "Kd 0.9 0.3 0.2\nPm 1\nPr 0.5\nmap_Pr grey.png",
            "Kd 0.9 0.3 0.2\nPm 1\nPr 0",
            "Kd 0.9 0.3 0.2\nPm 1\nPr 1",
        ),
        (
            "pm",
            "Kd 0.9 0.3 0.2\nPr 0.4\nmap_Pm -imfchan r red.png",
            "Kd 0.9 0.3 0.2\nPr 0.4\nPm 0",
            "Kd 0.9 0.3 0.2\nPr 0.4\nPm 1",
        ),
    ];
    for (name, mapped, zero, one) in cases {
        let mapped = render(name, mapped);
        let (zero, one) = (
            render(&format!("{name}-0"), zero),
            render(&format!("{name}-1"), one),
        );
        assert!(
            differ(&zero, &one, 0..64) > 0.1,
            "{name}: the two values look alike"
        );
        let tolerance = 2.0 / 255.0;
        assert!(
            differ(&mapped, &zero, 4..24) <= tolerance,
            "{name}: left half is not the 0 render"
        );
        assert!(
            differ(&mapped, &one, 40..60) <= tolerance,
            "{name}: right half is not the 1 render"
        );
    }
}

/// An 8x8 texture of four coloured quadrants (red, blue / green, yellow) as a DDS file: BC1
/// blocks of one colour each (`bc1: true`, the legacy `DXT1` FourCC) or 32-bit BGRA.
pub(crate) fn quadrants_dds(bc1: bool) -> Vec<u8> {
    let colours: [[u8; 3]; 4] = [[255, 0, 0], [0, 0, 255], [0, 255, 0], [255, 255, 0]];
    let mut b = b"DDS ".to_vec();
    // Header: size, flags, height, width, pitch, depth, mip count, 11 reserved words.
    for word in [124u32, 0x1007, 8, 8, 0, 0, 1].into_iter().chain([0; 11]) {
        b.extend(word.to_le_bytes());
    }
    // Pixel format (size, flags, FourCC, bits, R, G, B, A masks), then caps 1-4 and reserved.
    let format = match bc1 {
        true => [32, 0x4, u32::from_le_bytes(*b"DXT1"), 0, 0, 0, 0, 0],
        false => [32, 0x41, 0, 32, 0xFF_0000, 0xFF00, 0xFF, 0xFF00_0000],
    };
    for word in format.into_iter().chain([0x1000, 0, 0, 0, 0]) {
        b.extend(word.to_le_bytes());
    }
    if bc1 {
        for [r, g, bl] in colours {
            // Both endpoints the colour in RGB565, every texel index 0.
            let c565 = (u16::from(r >> 3) << 11) | (u16::from(g >> 2) << 5) | u16::from(bl >> 3);
            b.extend(c565.to_le_bytes().repeat(2));
            b.extend([0u8; 4]);
        }
    } else {
        for y in 0..8 {
            for x in 0..8 {
                let [r, g, bl] = colours[(y / 4) * 2 + x / 4];
                b.extend([bl, g, r, 255]);
            }
        }
    }
    b
}

/// DDS textures (game assets' format, and glTF's `MSFT_texture_dds`): the same quadrants as
/// BC1 blocks and as BGRA texels, named by an OBJ's `map_Kd`, render byte for byte as the PNG
/// of them does; a glTF texture whose only source is the DDS (through the extension) draws
/// its quadrants where they are.
#[test]
fn dds_textures_render_as_their_png() {
    let dir = tempfile::tempdir().unwrap();
    let colours: [[u8; 3]; 4] = [[255, 0, 0], [0, 0, 255], [0, 255, 0], [255, 255, 0]];
    image::RgbImage::from_fn(8, 8, |x, y| {
        image::Rgb(colours[(y as usize / 4) * 2 + x as usize / 4])
    })
    .save(dir.path().join("quadrants.png"))
    .unwrap();
    std::fs::write(dir.path().join("bc1.dds"), quadrants_dds(true)).unwrap();
    std::fs::write(dir.path().join("bgra.dds"), quadrants_dds(false)).unwrap();
    let render_obj = |texture: &str| {
        let stem = texture.replace('.', "-");
        let out = dir.path().join(format!("{stem}.png"));
        let warnings = render_quad_obj(dir.path(), &stem, &format!("map_Kd {texture}"), &out);
        assert!(!warnings.contains("warning"), "{texture}: {warnings}");
        std::fs::read(&out).unwrap()
    };
    let png = render_obj("quadrants.png");
    assert!(png == render_obj("bc1.dds"), "BC1 differs from the PNG");
    assert!(png == render_obj("bgra.dds"), "BGRA differs from the PNG");

    // glTF: an unlit quad filling an orthographic view, its texture's only source the DDS.
    let (json, bin) = crate::common::quads_gltf(
        &[(crate::common::square(1.0, 0.0), 0)],
        json!({
            "extensionsUsed": ["KHR_materials_unlit", "MSFT_texture_dds"],
            "extensionsRequired": ["MSFT_texture_dds"],
            "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}},
                "extensions": {"KHR_materials_unlit": {}}}],
            "textures": [{"extensions": {"MSFT_texture_dds": {"source": 0}}}],
            "images": [{"uri": "bc1.dds"}],
            "cameras": [{"type": "orthographic", "orthographic": {"xmag": 1.0, "ymag": 1.0, "znear": 0.1, "zfar": 10.0}}],
            "nodes": [{"camera": 0, "translation": [0.0, 0.0, 2.0]}]
        }),
    );
    let model = crate::common::write_gltf(dir.path(), "dds.gltf", json, &bin);
    let out = dir.path().join("dds-gltf.png");
    run(
        &[
            "render",
            s(&model),
            "-o",
            s(&out),
            "--width",
            "32",
            "--height",
            "32",
            "-q",
        ],
        true,
    );
    let (_, _, pixels) = read_rgba(&out);
    let at = |x: usize, y: usize| pixels[y * 32 + x].map(|c| u8::from(c > 0.5))[..3].to_vec();
    assert_eq!(
        [at(8, 8), at(24, 8), at(8, 24), at(24, 24)],
        colours.map(|c| c.map(|v| u8::from(v > 128)).to_vec())
    );
}

/// A grey image named as a normal map (MTL's `map_Bump` and `bump` often name a height map)
/// is not read as directions: the surface renders byte for byte as without it, with a warning
/// naming the image; a real normal map (bluish, tilted) still changes the shading.
#[test]
fn a_grey_bump_map_is_not_read_as_normals() {
    let dir = tempfile::tempdir().unwrap();
    image::GrayImage::from_fn(8, 8, |x, _| image::Luma([if x < 4 { 60 } else { 220 }]))
        .save(dir.path().join("height.png"))
        .unwrap();
    // Every texel the normal (0.5, 0, 0.87) of a surface tilted 30° about v.
    image::RgbImage::from_pixel(8, 8, image::Rgb([191, 128, 238]))
        .save(dir.path().join("normals.png"))
        .unwrap();
    let render = |name: &str, mtl: &str| {
        let out = dir.path().join(format!("{name}.png"));
        let warnings = render_quad_obj(dir.path(), name, mtl, &out);
        (std::fs::read(&out).unwrap(), warnings)
    };
    let (plain, _) = render("plain", "Kd 0.8 0.8 0.8");
    let (grey, warnings) = render("grey", "Kd 0.8 0.8 0.8\nmap_Bump -bm 2 height.png");
    assert!(grey == plain, "the grey bump map changed the shading");
    assert!(
        warnings
            .contains("(height.png): a grey image named as a normal map is a height (bump) map"),
        "{warnings}"
    );
    let (tilted, warnings) = render("tilted", "Kd 0.8 0.8 0.8\nmap_Bump normals.png");
    assert!(tilted != plain, "the normal map did not change the shading");
    assert!(!warnings.contains("warning"), "{warnings}");
}

/// DDS files whose header reads but whose texels do not decode (cut short, or BC6H, which is
/// not read) are found when the textures are decoded: the render goes on without the texture,
/// with one warning naming the file and the problem; with `--strict` it stops with that
/// message, a non-zero exit and no image written.
#[test]
fn dds_textures_that_do_not_decode_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let whole = quadrants_dds(true);
    std::fs::write(dir.path().join("short.dds"), &whole[..whole.len() - 8]).unwrap();
    // The DX10 header (FourCC DX10, then DXGI format 95, BC6H_UF16; 2D; one layer).
    let mut bc6h = whole[..128].to_vec();
    bc6h[84..88].copy_from_slice(b"DX10");
    for word in [95u32, 3, 0, 1, 0] {
        bc6h.extend(word.to_le_bytes());
    }
    bc6h.extend([0u8; 64]);
    std::fs::write(dir.path().join("bc6h.dds"), bc6h).unwrap();
    for (file, problem) in [
        (
            "short.dds",
            "truncated DDS: 8x8 needs 32 bytes of texels, the file holds 24",
        ),
        ("bc6h.dds", "DDS BC6H_UF16 is not read"),
    ] {
        let stem = file.replace('.', "-");
        let out = dir.path().join(format!("{stem}.png"));
        let warnings = render_quad_obj(dir.path(), &stem, &format!("map_Kd {file}"), &out);
        assert!(
            warnings.contains(&format!("({file}): {problem}")),
            "{warnings}"
        );
        let strict_out = dir.path().join(format!("{stem}-strict.png"));
        let model = dir.path().join(format!("{stem}.obj"));
        let args = ["render", s(&model), "-o", s(&strict_out), "--strict", "-q"];
        let message = crate::common::stderr(&run(&args, false));
        assert!(
            message.contains(file) && message.contains(problem),
            "{message}"
        );
        assert_eq!(message.trim().lines().count(), 1, "{message}");
        assert!(
            !strict_out.exists(),
            "--strict wrote {}",
            strict_out.display()
        );
    }
}
