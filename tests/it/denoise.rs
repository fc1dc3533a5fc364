//! `render --denoise` through the real binary. Built with `--features denoise` (docs/denoising.md):
//! a path-traced Cornell box at 4 spp comes out closer to a 256-spp reference
//! once denoised, the same bytes every run and for any --threads, with either integrator, and
//! recorded in the view file. Without the feature: the flag is refused with the way to get it.

use crate::common::{run, s, small_run, stderr};
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

#[cfg(not(feature = "denoise"))]
#[test]
fn a_build_without_the_feature_refuses_denoise_and_says_how() {
    let dir = scratch("without_feature");
    let out = dir.join("out.png");
    let model = cornell();
    let result = run(
        &small_run("render", &model, s(&out), ("16", "12"), "1", &["--denoise"]),
        false,
    );
    let message = stderr(&result);
    assert!(
        message.contains("this build has no denoiser; rebuild with --features denoise"),
        "{message}"
    );
    assert!(!out.exists(), "a refused render writes nothing");
}

#[cfg(feature = "denoise")]
mod with_the_feature {
    use super::*;
    use meshtracer::tools::compare::{compare_files, Metrics};

    /// The image size of the quality test: large enough for FLIP's 67-pixel-per-degree filters
    /// and the denoiser's receptive field, small enough for a 256-spp reference in seconds.
    const SIZE: (&str, &str) = ("160", "120");

    fn path_traced(out: &Path, spp: &str, extra: &[&str]) {
        let model = cornell();
        let mut args = vec!["--integrator", "path", "--seed", "7"];
        args.extend_from_slice(extra);
        run(&small_run("render", &model, s(out), SIZE, spp, &args), true);
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

    /// The denoiser's whole point, with the margins it must clear: at 4 spp the denoised
    /// image's mean FLIP against a 256-spp reference is at most 70% of the noisy image's, and
    /// its RMSE at most 50% (measured 0.083 against 0.143, 58%, and 0.023 against 0.095, 25%;
    /// FLIP gains less because the reference's own noise and the box's edges stay in it).
    #[test]
    fn a_denoised_low_spp_render_is_closer_to_the_reference() {
        const FLIP_MARGIN: f64 = 0.7;
        const RMSE_MARGIN: f64 = 0.5;
        let dir = scratch("closer");
        let (reference, noisy, denoised) = (
            dir.join("reference-256spp.png"),
            dir.join("noisy-4spp.png"),
            dir.join("denoised-4spp.png"),
        );
        path_traced(&reference, "256", &[]);
        path_traced(&noisy, "4", &[]);
        path_traced(&denoised, "4", &["--denoise"]);
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

    /// Same input, same bytes: twice in a row, and with one thread against two (the guides are
    /// per-pixel; OIDN's CPU kernels do not depend on how TBB splits the image).
    #[test]
    fn denoising_is_deterministic() {
        let dir = scratch("deterministic");
        let runs = [
            (dir.join("a.exr"), "2"),
            (dir.join("b.exr"), "2"),
            (dir.join("c.exr"), "1"),
        ];
        for (out, threads) in &runs {
            path_traced(out, "4", &["--denoise", "--threads", threads]);
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

    /// The direct integrator denoises too, and the view file and summary say so.
    #[test]
    fn direct_renders_denoise_and_the_view_file_records_it() {
        let dir = scratch("direct");
        let (out, plain, view) = (
            dir.join("out.png"),
            dir.join("plain.png"),
            dir.join("view.json"),
        );
        let model = cornell();
        let mut args = vec!["render", &model, "-o", s(&out), "--view-out", s(&view)];
        // Not small_run: without --quiet, for the summary.
        args.extend("--width 64 --height 48 --spp 4 --denoise".split(' '));
        let result = run(&args, true);
        let summary = stderr(&result);
        assert!(
            summary.contains("denoised by Open Image Denoise 2."),
            "{summary}"
        );
        run(
            &small_run("render", &model, s(&plain), ("64", "48"), "4", &[]),
            true,
        );
        assert_ne!(
            std::fs::read(&out).expect("written"),
            std::fs::read(&plain).expect("written"),
            "--denoise changed nothing"
        );
        let json: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&view).expect("view written")).expect("JSON");
        let record = &json["denoise"];
        assert_eq!(record["filter"], "RT");
        assert_eq!(record["guides"], serde_json::json!(["albedo", "normal"]));
        assert!(record["version"]
            .as_str()
            .is_some_and(|v| v.starts_with("2.")));
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
            ],
            true,
        );
        assert_eq!(
            std::fs::read(&again).expect("written"),
            std::fs::read(&plain).expect("written")
        );
    }

    /// A tile cannot be denoised alone (the filter sees across its edges): refused up front.
    #[test]
    fn tiles_and_views_are_refused() {
        let dir = scratch("refused");
        let model = cornell();
        for extra in [&["--tile", "0/2"][..], &["--views", "orbit:2"][..]] {
            let out = dir.join("out.png");
            let mut args = small_run("render", &model, s(&out), ("16", "12"), "1", &["--denoise"]);
            args.extend_from_slice(extra);
            let result = run(&args, false);
            assert!(
                stderr(&result).contains("cannot be used with"),
                "{}",
                stderr(&result)
            );
            assert!(!out.exists());
        }
    }
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

    #[test]
    fn guides_are_in_range_and_cover_the_box() {
        let (prepared, settings) = cornell(16);
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
        // environment, both guides are zero.
        let covered = g.normal.iter().filter(|n| **n != Vec3::ZERO).count();
        assert!(covered > 1200 / 2, "{covered} of 1200 pixels see the box");
        assert!(g
            .albedo
            .iter()
            .zip(&g.normal)
            .all(|(a, n)| *n != Vec3::ZERO || *a == Vec3::ZERO));
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
