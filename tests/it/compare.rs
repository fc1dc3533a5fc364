//! `meshtracer compare` through the binary: metrics, outputs, thresholds and refusals.

use crate::common::{run, s};

fn write(path: &std::path::Path, img: &image::RgbaImage) {
    img.save(path).unwrap();
}

#[test]
fn compare_reports_metrics_writes_images_and_fails_on_thresholds() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.png");
    let b = dir.path().join("b.png");
    write(
        &a,
        &image::RgbaImage::from_pixel(40, 30, image::Rgba([100, 100, 100, 255])),
    );
    write(
        &b,
        &image::RgbaImage::from_pixel(40, 30, image::Rgba([110, 100, 100, 255])),
    );
    let diff = dir.path().join("diff.png");
    let strip = dir.path().join("strip.png");
    let out = run(
        &[
            "compare",
            s(&a),
            s(&b),
            "--json",
            "--diff-out",
            s(&diff),
            "--side-by-side",
            s(&strip),
        ],
        true,
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in ["psnr", "ssim", "flip", "rmse", "max_abs", "coverage_iou"] {
        assert!(v[key].is_number(), "{key}: {v}");
    }
    // One channel off by 10 codes: RMSE = sqrt((10/255)²/3).
    let rmse = v["rmse"].as_f64().unwrap();
    assert!(
        (rmse - (10.0f64 / 255.0) / 3f64.sqrt()).abs() < 1e-9,
        "{rmse}"
    );
    assert_eq!(image::open(&diff).unwrap().width(), 40);
    assert_eq!(image::open(&strip).unwrap().width(), 120);
    // Thresholds: the same pair fails a strict FLIP bound and passes a loose PSNR one.
    let failed = run(
        &["compare", s(&a), s(&b), "--fail-above", "flip=0.0001"],
        false,
    );
    assert!(crate::common::stderr(&failed).contains("flip"));
    // The verdict does not depend on whether anyone read the metrics (`| head -1`).
    let unread = crate::common::run_with_readers_gone(&[
        "compare",
        s(&a),
        s(&b),
        "--fail-above",
        "flip=0.0001",
    ]);
    assert_eq!(unread.code(), Some(1), "{unread}");
    run(&["compare", s(&a), s(&b), "--fail-below", "psnr=20"], true);
    run(
        &[
            "compare",
            s(&a),
            s(&a),
            "--fail-above",
            "flip=0",
            "--fail-below",
            "ssim=0.999",
        ],
        true,
    );
}

#[test]
fn images_of_different_sizes_are_an_error_not_a_resample() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.png");
    let b = dir.path().join("b.png");
    write(&a, &image::RgbaImage::new(40, 30));
    write(&b, &image::RgbaImage::new(41, 30));
    let out = run(&["compare", s(&a), s(&b)], false);
    let err = crate::common::stderr(&out);
    assert!(err.contains("40x30") && err.contains("41x30"), "{err}");
    let missing = run(&["compare", s(&a), "nope.png"], false);
    assert!(crate::common::stderr(&missing).contains("nope.png"));
}

/// A NaN bound compares false with every metric, so the gate could never fail: NaN, infinite
/// and negative bounds are refused with one line naming the option and the value.
#[test]
fn thresholds_that_can_never_fail_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.png");
    write(&a, &image::RgbaImage::new(8, 8));
    for (option, bound) in [
        ("--fail-above", "flip=nan"),
        ("--fail-above", "rmse=inf"),
        ("--fail-above", "max_abs=-0.5"),
        ("--fail-below", "psnr=nan"),
    ] {
        let out = run(&["compare", s(&a), s(&a), option, bound], false);
        let err = crate::common::stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{bound}: {err}");
        let first = err.lines().next().unwrap_or_default();
        assert!(first.contains(option) && first.contains(bound), "{err}");
        assert!(out.stdout.is_empty(), "{bound}: no metrics printed");
    }
}

/// The heatmap and the strip are PNGs: another extension is refused before any work (it was
/// written as a PNG under that name).
#[test]
fn compare_images_must_be_named_png() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.png");
    write(&a, &image::RgbaImage::new(8, 8));
    for option in ["--diff-out", "--side-by-side"] {
        let out = dir.path().join("x.jpg");
        let result = run(&["compare", s(&a), s(&a), option, s(&out)], false);
        let err = crate::common::stderr(&result);
        assert!(err.contains("must end in .png"), "{option}: {err}");
        assert!(!out.exists());
    }
}

/// The heatmap and the strip may not replace an image compared, nor each other.
#[test]
fn compare_outputs_may_not_replace_its_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
    write(&a, &image::RgbaImage::new(8, 8));
    write(
        &b,
        &image::RgbaImage::from_pixel(8, 8, image::Rgba([9, 9, 9, 255])),
    );
    let before = std::fs::read(&a).unwrap();
    let out = dir.path().join("d.png");
    for (options, needle) in [
        (
            vec!["--diff-out", s(&a)],
            "--diff-out would overwrite the first image compared",
        ),
        (
            vec!["--side-by-side", s(&b)],
            "would overwrite the second image compared",
        ),
        (
            vec!["--diff-out", s(&out), "--side-by-side", s(&out)],
            "named by both --diff-out and --side-by-side",
        ),
    ] {
        let mut args = vec!["compare", s(&a), s(&b)];
        args.extend(options);
        let err = crate::common::stderr(&run(&args, false));
        assert!(err.contains(needle), "{args:?}: {err}");
    }
    assert_eq!(std::fs::read(&a).unwrap(), before);
    assert!(!out.exists());
}

/// A PNG (with alpha) against a JPEG of the same render (no alpha, over black): the default
/// background is black for coverage as `--help` says, so leaving it out gives the metrics of
/// `--background 0,0,0`, and the JPEG is covered by its silhouette, not the whole frame.
#[test]
fn the_default_background_is_the_black_one_typed_out() {
    let dir = tempfile::tempdir().unwrap();
    let model = crate::common::root().join("assets/cornell-box.gltf");
    let (png, jpg) = (dir.path().join("fmt.png"), dir.path().join("fmt.jpg"));
    for out in [&png, &jpg] {
        let size = ["--width", "64", "--height", "48", "--spp", "1", "-q"];
        run(
            &[&["render", s(&model), "-o", s(out)][..], &size].concat(),
            true,
        );
    }
    let metrics = |extra: &[&str]| {
        let out = run(
            &[&["compare", s(&png), s(&jpg), "--json"][..], extra].concat(),
            true,
        );
        serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap()
    };
    let (default, black) = (metrics(&[]), metrics(&["--background", "0,0,0"]));
    assert_eq!(default, black);
    let iou = default["coverage_iou"].as_f64().unwrap();
    assert!(iou > 0.85, "coverage IoU {iou}");
}

#[test]
fn a_render_compared_with_itself_across_accelerators_is_perfect() {
    let dir = tempfile::tempdir().unwrap();
    let model = crate::common::root().join("assets/cornell-box.gltf");
    let a = dir.path().join("bvh.png");
    let b = dir.path().join("linear.png");
    run(
        &[
            "render",
            s(&model),
            "-o",
            s(&a),
            "--width",
            "64",
            "--spp",
            "1",
            "-q",
        ],
        true,
    );
    run(
        &[
            "render",
            s(&model),
            "-o",
            s(&b),
            "--width",
            "64",
            "--spp",
            "1",
            "-q",
            "--accel",
            "linear",
        ],
        true,
    );
    run(
        &[
            "compare",
            s(&a),
            s(&b),
            "--fail-above",
            "max_abs=0",
            "--fail-below",
            "coverage_iou=1",
        ],
        true,
    );
}

/// A reader that stops early (`meshtracer info MODEL | head -1`) closes the pipe before the
/// command has written: the command ends quietly with success, as other tools do, instead of
/// panicking on the failed write (it did: "failed printing to stdout: Broken pipe").
#[test]
fn a_closed_pipe_ends_a_command_quietly() {
    let model = crate::common::root().join("assets/cornell-box.gltf");
    for args in [
        vec!["info", crate::common::s(&model)],
        vec!["info", crate::common::s(&model), "--json"],
    ] {
        let mut child = crate::common::bin()
            .args(&args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // Close the reading end at once: the command's first write meets a closed pipe.
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{args:?}: {}: {stderr}", out.status);
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}

/// A comparison stopped by SIGTERM part way exits 130 and writes nothing: neither the images
/// asked for nor a temporary file. (Should the host finish the comparison before the signal,
/// both images are whole; either way nothing half-written is left.)
#[test]
fn a_comparison_stopped_by_a_signal_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.png");
    let b = dir.path().join("b.png");
    // Large enough that the metrics take a second or more (FLIP at 2500x2500).
    let side = 2500;
    write(
        &a,
        &image::RgbaImage::from_fn(side, side, |x, y| {
            image::Rgba([(x % 256) as u8, (y % 256) as u8, 60, 255])
        }),
    );
    write(
        &b,
        &image::RgbaImage::from_fn(side, side, |x, y| {
            image::Rgba([(y % 256) as u8, (x % 256) as u8, 60, 255])
        }),
    );
    let diff = dir.path().join("diff.png");
    let strip = dir.path().join("strip.png");
    let child = crate::common::bin()
        .args(["compare", s(&a), s(&b), "--diff-out", s(&diff)])
        .args(["--side-by-side", s(&strip)])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(300));
    crate::hostile::send(&child, "TERM");
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    match out.status.code() {
        Some(130) => {
            assert!(err.contains("interrupted; no output written"), "{err}");
            assert_eq!(names, ["a.png", "b.png"], "{err}");
        }
        Some(0) => {
            assert_eq!(names, ["a.png", "b.png", "diff.png", "strip.png"]);
            for path in [&diff, &strip] {
                image::open(path).unwrap();
            }
        }
        _ => panic!("{}: {err}", out.status),
    }
}
