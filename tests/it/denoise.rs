//! `render --denoise` through the real binary, in every build: the built-in à-trous filter, or
//! Open Image Denoise in builds with `--features denoise` (docs/denoising.md). A path-traced
//! Cornell box at 4 spp comes out closer to a reference once denoised; an albedo edge
//! stays sharp (built-in filter); the same bytes every run and for any --threads, with either
//! integrator, and recorded in the summary and the view file; each view of --views --denoise
//! denoised as a single render is. (Tiles of a denoised render, merged and denoised:
//! tests/it/tiles.rs.)

use crate::common::{run, s, small_run, stderr};
use meshtracer::tools::compare::{compare_files, Metrics};
use std::path::{Path, PathBuf};

/// A folder under cargo's target dir for this test's images, kept after a failure to look at.
fn scratch(test: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("denoise")
        .join(test);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch folder");
    dir
}

fn cornell() -> String {
    crate::common::root()
        .join("assets/cornell-box.gltf")
        .display()
        .to_string()
}

/// The image size of the quality test: large enough for FLIP's 67-pixel-per-degree filters
/// and the denoiser's reach, small enough for a 64-spp reference in seconds of a dev build.
const SIZE: (&str, &str) = ("160", "120");

/// Renders `model` path-traced at [`SIZE`] and `spp` with seed 7 (unless `extra` names one).
fn path_traced(model: &str, out: &Path, spp: &str, extra: &[&str]) {
    let mut args = vec!["--integrator", "path"];
    if !extra.contains(&"--seed") {
        args.extend(["--seed", "7"]);
    }
    args.extend_from_slice(extra);
    run(&small_run("render", model, s(out), SIZE, spp, &args), true);
}

fn against(reference: &Path, image: &Path) -> Metrics {
    compare_files(
        reference,
        image,
        None,
        meshtracer::color::ViewTransform::Standard,
    )
    .unwrap_or_else(|e| panic!("{e}"))
    .0
}

/// The denoiser's whole point, with the margins it must clear: at 4 spp the denoised image's
/// mean FLIP against a reference (`REFERENCE`: spp and seed) is at most `FLIP_MARGIN` of the
/// noisy image's, and its RMSE at most `RMSE_MARGIN`. Built-in filter, 64 spp and another
/// seed (in a few seconds of a dev build): measured 0.107 against 0.138 (78%) and 0.036
/// against 0.092 (39%) with the Owen-scrambled Sobol sampler. OIDN, 256 spp with the same
/// seed, measured before that sampler: 0.083 against 0.143 (58%), 0.023 against 0.095 (25%).
/// FLIP gains less because the reference's own noise and the box's edges stay in it.
#[test]
fn a_denoised_low_spp_render_is_closer_to_the_reference() {
    #[cfg(feature = "denoise")]
    const FLIP_MARGIN: f64 = 0.7;
    #[cfg(feature = "denoise")]
    const REFERENCE: [&str; 2] = ["256", "7"];
    #[cfg(not(feature = "denoise"))]
    const FLIP_MARGIN: f64 = 0.85;
    #[cfg(not(feature = "denoise"))]
    const REFERENCE: [&str; 2] = ["64", "1"];
    const RMSE_MARGIN: f64 = 0.5;
    let dir = scratch("closer");
    let (reference, noisy, denoised) = (
        dir.join("reference.png"),
        dir.join("noisy-4spp.png"),
        dir.join("denoised-4spp.png"),
    );
    let model = cornell();
    path_traced(&model, &reference, REFERENCE[0], &["--seed", REFERENCE[1]]);
    path_traced(&model, &noisy, "4", &[]);
    path_traced(&model, &denoised, "4", &["--denoise"]);
    let before = against(&reference, &noisy);
    let after = against(&reference, &denoised);
    println!(
        "mean FLIP noisy {:.4} denoised {:.4}; RMSE noisy {:.4} denoised {:.4}",
        before.flip, after.flip, before.rmse, after.rmse
    );
    assert!(
        after.flip <= FLIP_MARGIN * before.flip && after.rmse <= RMSE_MARGIN * before.rmse,
        "denoised FLIP {:.4} / RMSE {:.4} against noisy {:.4} / {:.4}: not under {FLIP_MARGIN} / {RMSE_MARGIN} of it; images in {}",
        after.flip,
        after.rmse,
        before.flip,
        before.rmse,
        dir.display()
    );
    // Coverage is the film's, untouched.
    assert_eq!(after.coverage_iou, 1.0);
}

/// A small default render takes the samples the filter needs: its pixels share at least as
/// many samples as a 640x480 image's two a pixel (`render::DENOISED_SAMPLES`), which at
/// 160x120 is the cap of 32, and the bundled box then comes out within FLIP 0.09 and RMSE
/// 0.035 of the 64-spp reference of the test above. Measured: 0.073 and 0.029; with the two
/// samples a pixel the default took at every size before, 0.127 and 0.046 (mottled, the
/// filter unable to tell two samples' grain from the scene).
#[test]
fn a_small_default_render_takes_the_samples_the_filter_needs() {
    let dir = scratch("small-default");
    let (reference, image, stats) = (
        dir.join("reference.png"),
        dir.join("default.png"),
        dir.join("default.stats.json"),
    );
    let model = cornell();
    // Encoded as the default render encodes its PNG.
    let neutral = ["--seed", "1", "--tonemap", "khronos-pbr-neutral"];
    path_traced(&model, &reference, "64", &neutral);
    let (width, height) = SIZE;
    run(
        &[
            "render",
            &model,
            "-o",
            s(&image),
            "--width",
            width,
            "--height",
            height,
            "--stats",
            s(&stats),
            "-q",
        ],
        true,
    );
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&stats).expect("stats written")).expect("JSON");
    assert_eq!(stats["denoised"], true, "{stats}");
    assert_eq!(stats["samples"], 160 * 120 * 32, "{stats}");
    let m = against(&reference, &image);
    println!(
        "default render at 160x120: mean FLIP {:.4}, RMSE {:.4}",
        m.flip, m.rmse
    );
    assert!(
        m.flip <= 0.09 && m.rmse <= 0.035,
        "FLIP {:.4} / RMSE {:.4} against the reference; images in {}",
        m.flip,
        m.rmse,
        dir.display()
    );
}

/// Same input, same bytes: twice in a row, and with one thread against two (the guides and
/// the built-in filter are per pixel; OIDN's CPU kernels do not depend on how TBB splits the
/// image).
#[test]
fn denoising_is_deterministic() {
    let dir = scratch("deterministic");
    let runs = [
        (dir.join("a.exr"), "2"),
        (dir.join("b.exr"), "2"),
        (dir.join("c.exr"), "1"),
    ];
    let model = cornell();
    for (out, threads) in &runs {
        path_traced(&model, out, "4", &["--denoise", "--threads", threads]);
    }
    let bytes: Vec<Vec<u8>> = runs
        .iter()
        .map(|(p, _)| std::fs::read(p).expect("written"))
        .collect();
    assert!(bytes[0] == bytes[1], "two runs differ: {}", dir.display());
    assert!(
        bytes[0] == bytes[2],
        "--threads 1 and 2 differ: {}",
        dir.display()
    );
}

/// The direct integrator denoises too, and the view file, `--stats` and the summary say with
/// what.
#[test]
fn direct_renders_denoise_and_the_view_file_records_it() {
    #[cfg(feature = "denoise")]
    let (summary_note, filter, guides, stats_id) = (
        "denoised by Open Image Denoise 2.",
        "RT",
        serde_json::json!(["albedo", "normal"]),
        "oidn",
    );
    #[cfg(not(feature = "denoise"))]
    let (summary_note, filter, guides, stats_id) = (
        "denoised by the built-in à-trous filter in",
        "atrous",
        serde_json::json!(["albedo", "normal", "depth", "variance"]),
        "atrous",
    );
    let dir = scratch("direct");
    let (out, plain, view, stats) = (
        dir.join("out.png"),
        dir.join("plain.png"),
        dir.join("view.json"),
        dir.join("stats.json"),
    );
    let model = cornell();
    let mut args = vec![
        "render",
        &model,
        "-o",
        s(&out),
        "--view-out",
        s(&view),
        "--stats",
        s(&stats),
    ];
    // Not small_run: without --quiet, for the summary.
    args.extend(
        "--width 64 --height 48 --spp 4 --denoise --integrator direct --tonemap standard"
            .split(' '),
    );
    let result = run(&args, true);
    let summary = stderr(&result);
    assert!(summary.contains(summary_note), "{summary}");
    run(
        &small_run("render", &model, s(&plain), ("64", "48"), "4", &[]),
        true,
    );
    assert_ne!(
        std::fs::read(&out).expect("written"),
        std::fs::read(&plain).expect("written"),
        "--denoise changed nothing"
    );
    let json = |path: &Path| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(path).expect("written")).expect("JSON")
    };
    let stats = json(&stats);
    assert_eq!(stats["denoised"], true);
    assert_eq!(stats["denoiser"], stats_id);
    let record = &json(&view)["denoise"];
    assert_eq!(record["filter"], filter);
    assert_eq!(record["guides"], guides);
    assert!(record["version"].as_str().is_some_and(|v| !v.is_empty()));
    // The view file still renders the same view (readers ignore the extra key).
    let again = dir.join("again.png");
    run(
        &[
            "render",
            &model,
            "-o",
            s(&again),
            "--view",
            s(&view),
            "--spp",
            "4",
            "-q",
            "--tonemap",
            "standard",
            // `--view` reads the view, not the integrator the file records.
            "--integrator",
            "direct",
        ],
        true,
    );
    assert_eq!(
        std::fs::read(&again).expect("written"),
        std::fs::read(&plain).expect("written")
    );
}

/// Each view of a `--denoise` run is a whole image denoised as a single render is: with the
/// default sampling it is byte for byte the same view rendered alone from its view file (a
/// single render is denoised by default), and its view file records the filter. Without
/// `--denoise` views are not denoised (the default), and differ.
#[test]
fn views_are_denoised_as_single_renders_are() {
    let dir = scratch("views");
    let model = cornell();
    let views = dir.join("views");
    let size = ["--width", "80", "--height", "60", "-q"];
    let base = [
        &["render", model.as_str(), "--views", "orbit:3"][..],
        &size[..],
    ]
    .concat();
    run(&[&base[..], &["-o", s(&views), "--denoise"]].concat(), true);
    for k in 0..3 {
        let view_file = views.join(format!("{k:03}.view.json"));
        let record: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&view_file).unwrap()).unwrap();
        assert_eq!(record["denoise"]["hdr"], true, "view {k}");
        let alone = dir.join(format!("alone-{k}.png"));
        let single = [
            "render",
            model.as_str(),
            "--view",
            s(&view_file),
            "-o",
            s(&alone),
            "-q",
        ];
        run(&single, true);
        assert!(
            std::fs::read(&alone).unwrap()
                == std::fs::read(views.join(format!("{k:03}.png"))).unwrap(),
            "view {k} differs from the same view rendered alone"
        );
    }
    let noisy = dir.join("noisy");
    run(&[&base[..], &["-o", s(&noisy)]].concat(), true);
    let record = std::fs::read_to_string(noisy.join("000.view.json")).unwrap();
    assert!(!record.contains("\"denoise\""), "{record}");
    assert!(
        std::fs::read(noisy.join("000.png")).unwrap()
            != std::fs::read(views.join("000.png")).unwrap()
    );
}

/// The built-in filter keeps an albedo edge sharp: a plane seen from above, its left half red
/// and its right half white, under the default studio environment. At 4 spp, denoised, the
/// mean of each of the six columns around the edge (rows averaged, so little noise is left)
/// is within `EDGE_TOLERANCE` of a 64-spp reference's in every channel (8-bit sRGB as 0-1),
/// where the edge's own step is over 0.25 in green and blue (measured 0.33; a blur over two
/// pixels each side would miss by a quarter of it next to the edge); the image as a whole is
/// closer to the reference than the noisy one.
#[cfg(not(feature = "denoise"))]
#[test]
fn the_built_in_filter_keeps_an_albedo_edge_sharp() {
    use crate::common::{quads_gltf, read_rgba, write_gltf};
    const EDGE_TOLERANCE: f32 = 0.04;
    let dir = scratch("albedo_edge");
    let half = |x0: f32, x1: f32| {
        [
            [x0, -3.0, 0.0],
            [x1, -3.0, 0.0],
            [x1, 3.0, 0.0],
            [x0, 3.0, 0.0],
        ]
    };
    let (json, bin) = quads_gltf(
        &[(half(-3.0, 0.0), 0), (half(0.0, 3.0), 1)],
        serde_json::json!({
            "materials": [
                {"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.1, 0.1, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}},
                {"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}}
            ],
            "cameras": [{"type": "orthographic", "orthographic": {"xmag": 3.0, "ymag": 3.0, "znear": 0.1, "zfar": 100.0}}],
            "nodes": [{"camera": 0, "translation": [0.0, 0.0, 5.0]}]
        }),
    );
    let model = write_gltf(&dir, "halves.gltf", json, &bin);
    let model = s(&model);
    let (reference, noisy, denoised) = (
        dir.join("reference.png"),
        dir.join("noisy.png"),
        dir.join("denoised.png"),
    );
    let size = ("64", "64");
    let render = |out: &Path, spp: &str, extra: &[&str]| {
        let mut args = vec!["--integrator", "path", "--seed", "7"];
        args.extend_from_slice(extra);
        run(&small_run("render", model, s(out), size, spp, &args), true);
    };
    render(&reference, "64", &[]);
    render(&noisy, "4", &[]);
    render(&denoised, "4", &["--denoise"]);
    let column_means = |path: &Path| -> Vec<[f32; 3]> {
        let (width, height, pixels) = read_rgba(path);
        (0..width as usize)
            .map(|x| {
                let mut sum = [0.0f32; 3];
                for y in 0..height as usize {
                    let p = pixels[y * width as usize + x];
                    for c in 0..3 {
                        sum[c] += p[c] / height as f32;
                    }
                }
                sum
            })
            .collect()
    };
    let (expected, got) = (column_means(&reference), column_means(&denoised));
    let step = expected[34][1] - expected[29][1];
    assert!(
        step > 0.25,
        "the reference's edge is {step} in green: {}",
        dir.display()
    );
    for x in 29..35 {
        for c in 0..3 {
            assert!(
                (got[x][c] - expected[x][c]).abs() < EDGE_TOLERANCE,
                "column {x} channel {c}: {} against the reference's {}; images in {}",
                got[x][c],
                expected[x][c],
                dir.display()
            );
        }
    }
    let (before, after) = (against(&reference, &noisy), against(&reference, &denoised));
    assert!(
        after.rmse < before.rmse,
        "denoised RMSE {} against noisy {}: {}",
        after.rmse,
        before.rmse,
        dir.display()
    );
}

/// The denoiser's guides through the library (any build): what the filter is fed.
mod guides {
    use glam::Vec3;
    use meshtracer::prepare::{PrepareOptions, Prepared};
    use meshtracer::render::denoise::guides;
    use meshtracer::render::{Region, RenderSettings};
    use meshtracer::Scene;

    fn cornell(spp: u32) -> (Prepared, RenderSettings) {
        let scene = Scene::load(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/assets/cornell-box.gltf"
        ))
        .expect("bundled scene loads");
        let mut warnings = Vec::new();
        let prepared = Prepared::new(scene, &PrepareOptions::default(), &mut warnings)
            .expect("bundled scene prepares");
        let mut settings = meshtracer::setup::default_settings(&prepared.scene, 40, 30);
        settings.spp = spp;
        (prepared, settings)
    }

    /// A render cancelled before it starts, or after its first tile (each finished tile goes
    /// into the film at once), ends with `Cancelled`, not with a part of an image.
    #[test]
    fn a_cancelled_render_returns_cancelled() {
        use meshtracer::render::{render, Cancelled};
        use std::sync::atomic::{AtomicBool, Ordering};
        let (prepared, mut settings) = cornell(1);
        settings.view.width = 160;
        settings.view.height = 120;
        let at_once = AtomicBool::new(true);
        assert!(matches!(
            render(&prepared, &settings, &at_once, &|_, _| {}),
            Err(Cancelled)
        ));
        let later = AtomicBool::new(false);
        let finished = std::sync::atomic::AtomicU64::new(0);
        let stop_after_first = |done: u64, total: u64| {
            assert!(done <= total);
            finished.fetch_add(1, Ordering::Relaxed);
            later.store(true, Ordering::Relaxed);
        };
        assert!(matches!(
            render(&prepared, &settings, &later, &stop_after_first),
            Err(Cancelled)
        ));
        // 20 tiles of 32 x 32; each thread stops before its next one.
        let finished = finished.load(Ordering::Relaxed);
        assert!((1..20).contains(&finished), "{finished} tiles finished");
    }

    /// Adaptive sampling takes 4 to `spp` samples a pixel: the guides follow the 4 (2 x 2).
    #[test]
    fn adaptive_guides_follow_the_fewest_samples() {
        let (prepared, mut settings) = cornell(32);
        settings.noise = Some(0.1);
        assert_eq!(
            guides(&prepared, &settings, Region::full(8, 6)).samples_per_pixel,
            4
        );
        settings.noise = None;
        assert_eq!(
            guides(&prepared, &settings, Region::full(8, 6)).samples_per_pixel,
            16
        );
    }

    #[test]
    fn guides_are_in_range_and_cover_the_box() {
        let (prepared, mut settings) = cornell(16);
        settings.noise = None;
        let g = guides(&prepared, &settings, Region::full(40, 30));
        assert_eq!(g.samples_per_pixel, 16);
        assert_eq!((g.albedo.len(), g.normal.len()), (1200, 1200));
        assert!(g
            .albedo
            .iter()
            .all(|a| a.min_element() >= 0.0 && a.max_element() <= 1.0));
        // Averages of unit vectors: never longer than 1 (plus rounding).
        assert!(g.normal.iter().all(|n| n.length() <= 1.0 + 1e-5));
        // The box fills most of the frame; around it nothing is hit and, without a visible
        // environment, the guides are zero; depth is positive exactly where a surface is.
        assert!(g
            .depth
            .iter()
            .zip(&g.normal)
            .all(|(d, n)| (*d > 0.0) == (*n != Vec3::ZERO)));
        let covered = g.normal.iter().filter(|n| **n != Vec3::ZERO).count();
        assert!(covered > 1200 / 2, "{covered} of 1200 pixels see the box");
        assert!(g
            .albedo
            .iter()
            .zip(&g.normal)
            .all(|(a, n)| *n != Vec3::ZERO || *a == Vec3::ZERO));
    }

    /// The path tracer's own guides (averaged over each pixel's samples, what the default
    /// render denoises with) agree with the traced ones: they see the same surfaces, only
    /// through other positions in the pixel (Sobol samples, not a grid). Mean albedo
    /// difference under 0.02 and at most 3% of the pixels disagreeing about being covered.
    #[test]
    fn the_path_tracers_guides_agree_with_the_traced_ones() {
        use std::sync::atomic::AtomicBool;
        let (prepared, mut settings) = cornell(16);
        settings.noise = None;
        settings.guides = true;
        let traced = guides(&prepared, &settings, Region::full(40, 30));
        let (image, _, _) =
            meshtracer::render::render(&prepared, &settings, &AtomicBool::new(false), &|_, _| {})
                .unwrap();
        let own = image.guides.expect("the path tracer collects guides");
        assert_eq!(own.albedo.len(), 1200);
        let albedo_error: f32 = own
            .albedo
            .iter()
            .zip(&traced.albedo)
            .map(|(a, b)| (*a - *b).abs().max_element())
            .sum::<f32>()
            / 1200.0;
        assert!(albedo_error < 0.02, "mean albedo difference {albedo_error}");
        let disagree = own
            .depth
            .iter()
            .zip(&traced.depth)
            .filter(|(a, b)| (**a > 0.0) != (**b > 0.0))
            .count();
        assert!(disagree <= 36, "{disagree} pixels disagree about coverage");
        let normal_error: f32 = own
            .normal
            .iter()
            .zip(&traced.normal)
            .map(|(a, b)| (*a - *b).length())
            .sum::<f32>()
            / 1200.0;
        assert!(normal_error < 0.05, "mean normal difference {normal_error}");
        // Without the flag, no guides are kept.
        settings.guides = false;
        let (image, _, _) =
            meshtracer::render::render(&prepared, &settings, &AtomicBool::new(false), &|_, _| {})
                .unwrap();
        assert!(image.guides.is_none());
    }

    /// The path tracer's emission guide is the part of each pixel its camera rays saw
    /// emitted: more than nothing where the ceiling's light panel is seen (a few pixels of
    /// the 40x30 image, and not the walls), and never more than the pixel itself.
    #[test]
    fn the_emission_guide_is_what_the_camera_saw_emitted() {
        use std::sync::atomic::AtomicBool;
        let (prepared, mut settings) = cornell(16);
        settings.noise = None;
        settings.guides = true;
        let (image, _, _) =
            meshtracer::render::render(&prepared, &settings, &AtomicBool::new(false), &|_, _| {})
                .unwrap();
        let g = image.guides.expect("the path tracer collects guides");
        assert_eq!(g.emission.len(), 1200);
        let seen = g.emission.iter().filter(|e| **e != Vec3::ZERO).count();
        assert!(
            (1..=60).contains(&seen),
            "{seen} pixels see the light panel"
        );
        for (i, (e, p)) in g.emission.iter().zip(&image.pixels).enumerate() {
            let excess = (*e - p.truncate()).max_element();
            assert!(
                e.min_element() >= 0.0 && excess <= 1e-5 * p.max_element().max(1.0),
                "pixel {i}: {e} emitted of {p}"
            );
        }
    }

    #[test]
    fn guides_of_a_region_are_the_same_pixels() {
        let (prepared, settings) = cornell(4);
        let whole = guides(&prepared, &settings, Region::full(40, 30));
        let region = Region {
            x: 10,
            y: 5,
            width: 7,
            height: 3,
        };
        let part = guides(&prepared, &settings, region);
        for row in 0..3 {
            let begin = (5 + row) * 40 + 10;
            assert_eq!(
                part.albedo[row * 7..row * 7 + 7],
                whole.albedo[begin..begin + 7]
            );
            assert_eq!(
                part.normal[row * 7..row * 7 + 7],
                whole.normal[begin..begin + 7]
            );
        }
    }
}

/// The default render (the path tracer with its own guides) of a scene with punctual lights
/// is guided by their visibility too and keeps what the camera saw emitted out of the
/// smoothing, and its view file says so; OIDN takes albedo and normal only.
#[test]
fn the_default_render_is_guided_by_the_lights_visibility_and_keeps_emission_apart() {
    #[cfg(feature = "denoise")]
    let guides = serde_json::json!(["albedo", "normal"]);
    #[cfg(not(feature = "denoise"))]
    let guides = serde_json::json!([
        "albedo",
        "normal",
        "depth",
        "variance",
        "visibility",
        "emission"
    ]);
    let dir = scratch("visibility");
    let (out, view) = (dir.join("out.png"), dir.join("view.json"));
    // The default render: nothing but the size besides the model and the outputs.
    let model = cornell();
    let mut args = vec!["render", &model, "-q", "--width", "48", "--height", "36"];
    args.extend(["-o", s(&out), "--view-out", s(&view)]);
    run(&args, true);
    let view: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&view).expect("written")).expect("JSON");
    assert_eq!(view["denoise"]["guides"], guides);
}
