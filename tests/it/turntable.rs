//! Turntables and contact sheets through the real binary: `render --turntable N --gif`
//! (frames, looping, delay, each frame the view's PNG within GIF quantisation, the orbit
//! starting where the plain render stands), `--contact-sheet` of views and of a batch with a
//! failing job (layout, each cell the view's thumbnail, labels), and refusals of bad options.

use crate::common::{root, run, s, small_run, stderr};
use image::{AnimationDecoder, RgbImage, RgbaImage};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Width and height of the test renders: small, the tests check plumbing, not pictures.
const W: u32 = 64;
const H: u32 = 48;
/// Sheet layout constants, as the README documents them (src/output/sheet.rs).
const PADDING: u32 = 4;
const LABEL_HEIGHT: u32 = 20;
const SHEET_BACKGROUND: [u8; 3] = [255, 255, 255];
const CELL_BACKGROUND: [u8; 3] = [96, 96, 96];

/// Mean absolute difference, in 8-bit levels, allowed between a GIF frame and the view's PNG
/// over the pixels both show opaque. NeuQuant's 256 colours a frame: measured 0.0 on
/// shapes.obj (fewer than 256 colours: the palette is exact), 2.05 in the worst of the 4
/// frames of cornell-box at 64x48 and 4 spp (0.51 in the mean), 1.56 in the worst 512x512
/// frame of DamagedHelmet.
const GIF_MEAN_TOLERANCE: f64 = 3.0;
/// Mean difference (levels) allowed between a turntable's frame 0 and the plain render from
/// the same point: the camera is rebuilt from its azimuth and elevation, so its position
/// differs in the last bits of a float, which may move a sample across an edge. Measured: the
/// same bytes at this size; 0.15 levels RMS (PSNR 64.8 dB) at 512x384 and 4 spp.
const PLAIN_VIEW_TOLERANCE: f64 = 0.5;
/// Largest difference allowed between a sheet's cell and the thumbnail the test makes of the
/// view's PNG: the same composite and Lanczos-3 resize, so at most a rounding step.
const CELL_MAX_TOLERANCE: u8 = 1;

fn shapes() -> PathBuf {
    root().join("assets/shapes.obj")
}

/// `render shapes.obj -o OUT` at W x H, 1 spp, quietly, with `extra` options.
fn render(out: &Path, extra: &[&str]) {
    render_model(&shapes(), out, "1", extra);
}

/// `render MODEL -o OUT` at W x H and `spp`, quietly, with `extra` options.
fn render_model(model: &Path, out: &Path, spp: &str, extra: &[&str]) {
    let (w, h) = (W.to_string(), H.to_string());
    run(
        &small_run("render", s(model), s(out), (&w, &h), spp, extra),
        true,
    );
}

fn png(path: &Path) -> RgbaImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgba8()
}

fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

/// The azimuth (degrees from +Z toward +X) of a view file's camera about `target`.
fn azimuth(view_file: &Path, target: [f64; 3]) -> f64 {
    let p = &read_json(view_file)["camera"]["position"];
    let (x, z) = (
        p[0].as_f64().unwrap() - target[0],
        p[2].as_f64().unwrap() - target[2],
    );
    x.atan2(z).to_degrees()
}

fn bounds_centre(model: &Path) -> [f64; 3] {
    let out = run(&["info", s(model), "--json"], true);
    let info: Value = serde_json::from_slice(&out.stdout).unwrap();
    let b = &info["bounds"];
    [0, 1, 2].map(|k| (b["min"][k].as_f64().unwrap() + b["max"][k].as_f64().unwrap()) / 2.0)
}

/// Mean absolute RGB difference over the pixels opaque in both (alpha 255 in `a` and `b`),
/// and how many pixels that is.
fn opaque_mean_difference(a: &RgbaImage, b: &RgbaImage) -> (f64, usize) {
    assert_eq!(a.dimensions(), b.dimensions());
    let (mut sum, mut count) = (0u64, 0usize);
    for (p, q) in a.pixels().zip(b.pixels()) {
        if p.0[3] == 255 && q.0[3] == 255 {
            sum += (0..3)
                .map(|c| u64::from(p.0[c].abs_diff(q.0[c])))
                .sum::<u64>();
            count += 1;
        }
    }
    (sum as f64 / (3 * count.max(1)) as f64, count)
}

fn decode_gif(
    path: &Path,
) -> (
    image::codecs::gif::GifDecoder<std::io::Cursor<Vec<u8>>>,
    Vec<u8>,
) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let decoder = image::codecs::gif::GifDecoder::new(std::io::Cursor::new(bytes.clone()))
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    (decoder, bytes)
}

/// shapes.obj at 1 spp: fewer than 256 colours a frame, which the GIF keeps exactly.
#[test]
fn turntable_gif_holds_the_orbit_frames_and_loops() {
    let (worst, most_colours) = check_turntable_gif(&shapes(), "1");
    assert!(most_colours <= 256, "{most_colours} colours");
    assert_eq!(worst, 0.0, "an exact palette");
}

/// cornell-box at 4 spp: more than 256 colours a frame, quantised by NeuQuant.
#[test]
fn turntable_gif_quantises_many_colours_closely() {
    let (worst, most_colours) = check_turntable_gif(&root().join("assets/cornell-box.gltf"), "4");
    assert!(
        most_colours > 256,
        "{most_colours} colours: NeuQuant not exercised"
    );
    assert!(worst > 0.0, "quantised, not exact");
}

/// Renders a 4-frame turntable of `model` with a GIF and checks that the GIF has 4 frames of
/// the render's size, loops forever, lasts a 4 s turn, and that each frame is the view's PNG
/// within quantisation: transparent where the PNG is less than half covered, colours within
/// GIF_MEAN_TOLERANCE elsewhere; neighbouring frames differ (it turns). Returns the worst
/// frame's mean difference and the most distinct colours of a PNG frame.
fn check_turntable_gif(model: &Path, spp: &str) -> (f64, usize) {
    let dir = tempfile::tempdir().unwrap();
    let (frames_dir, gif) = (dir.path().join("frames"), dir.path().join("spin.gif"));
    render_model(
        model,
        &frames_dir,
        spp,
        &["--turntable", "4", "--gif", s(&gif)],
    );
    let (mut worst, mut most_colours) = (0f64, 0usize);
    let (decoder, bytes) = decode_gif(&gif);
    assert!(matches!(
        decoder.loop_count(),
        image::metadata::LoopCount::Infinite
    ));
    // The NETSCAPE2.0 extension with a loop count of 0 (forever); without it a GIF plays once.
    let netscape = bytes
        .windows(11)
        .position(|w| w == b"NETSCAPE2.0")
        .expect("a looping extension");
    assert_eq!(&bytes[netscape + 11..netscape + 15], &[3, 1, 0, 0]);
    let frames = decoder.into_frames().collect_frames().unwrap();
    assert_eq!(frames.len(), 4);
    let mut previous: Option<RgbaImage> = None;
    for (k, frame) in frames.iter().enumerate() {
        // A full turn in 4 s: 1 s a frame.
        assert_eq!(frame.delay().numer_denom_ms(), (1000, 1), "frame {k}");
        let gif_frame = frame.buffer();
        assert_eq!(gif_frame.dimensions(), (W, H), "frame {k}");
        let view = png(&frames_dir.join(format!("{k:03}.png")));
        let colours: std::collections::HashSet<[u8; 4]> = view.pixels().map(|p| p.0).collect();
        most_colours = most_colours.max(colours.len());
        let mut opaque = 0;
        for (p, q) in view.pixels().zip(gif_frame.pixels()) {
            let expected_alpha = if p.0[3] >= 128 { 255 } else { 0 };
            assert_eq!(q.0[3], expected_alpha, "frame {k}: 1-bit alpha");
            opaque += usize::from(expected_alpha == 255);
        }
        let mut view_one_bit = view.clone();
        for p in view_one_bit.pixels_mut() {
            p.0[3] = if p.0[3] >= 128 { 255 } else { 0 };
        }
        let (mean, count) = opaque_mean_difference(&view_one_bit, gif_frame);
        assert_eq!(count, opaque);
        assert!(
            opaque > (W * H / 10) as usize,
            "frame {k}: the model covers the frame"
        );
        worst = worst.max(mean);
        assert!(
            mean < GIF_MEAN_TOLERANCE,
            "frame {k}: mean difference {mean:.2} levels against {}",
            frames_dir.join(format!("{k:03}.png")).display()
        );
        if let Some(previous) = &previous {
            let (turned, _) = opaque_mean_difference(previous, gif_frame);
            assert!(
                turned > 5.0,
                "frame {k} differs from frame {}: {turned:.2}",
                k - 1
            );
        }
        previous = Some(gif_frame.clone());
    }
    // Only the named files: no temporary file left beside the GIF.
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["frames", "spin.gif"]);
    (worst, most_colours)
}

/// `--fps` sets the delay; `--background` makes every pixel opaque.
#[test]
fn fps_and_background_reach_the_gif() {
    let dir = tempfile::tempdir().unwrap();
    let gif = dir.path().join("spin.gif");
    let frames = dir.path().join("frames");
    render(
        &frames,
        &[
            "--turntable",
            "2",
            "--gif",
            s(&gif),
            "--fps",
            "25",
            "--background",
            "1,1,1",
        ],
    );
    let (decoder, _) = decode_gif(&gif);
    let frames = decoder.into_frames().collect_frames().unwrap();
    assert_eq!(frames.len(), 2);
    for frame in &frames {
        assert_eq!(frame.delay().numer_denom_ms(), (40, 1), "1/25 s");
        assert!(frame.buffer().pixels().all(|p| p.0[3] == 255));
        // The white background is white in the GIF too (a corner is background here).
        assert!(frame.buffer().get_pixel(0, 0).0[..3]
            .iter()
            .all(|&c| c >= 250));
    }
}

/// The camera position of a view file.
fn position(view_file: &Path) -> [f64; 3] {
    let p = &read_json(view_file)["camera"]["position"];
    [0, 1, 2].map(|k| p[k].as_f64().unwrap())
}

/// `--turntable N` is `--views orbit:N` started where the plain render's camera stands: with
/// the start given as 0 degrees azimuth and 20 elevation, the same files byte for byte; by
/// default, view 0 stands where the plain render's camera does (the automatic camera for
/// shapes.obj, at the same distance) and its image is the plain render's within
/// PLAIN_VIEW_TOLERANCE.
#[test]
fn a_turntable_is_an_orbit_from_the_plain_view() {
    let dir = tempfile::tempdir().unwrap();
    let (tt, orbit, tt0) = (
        dir.path().join("tt"),
        dir.path().join("orbit"),
        dir.path().join("tt0"),
    );
    let start = ["--orbit-azimuth", "0", "--orbit-elevation", "20"];
    render(&tt0, &[&["--turntable", "3"][..], &start].concat());
    render(&orbit, &["--views", "orbit:3"]);
    for k in 0..3 {
        let name = format!("{k:03}.png");
        assert!(
            std::fs::read(tt0.join(&name)).unwrap() == std::fs::read(orbit.join(&name)).unwrap(),
            "{name}: --turntable 3 {start:?} differs from --views orbit:3"
        );
    }
    render(&tt, &["--turntable", "3"]);
    let plain = dir.path().join("plain.png");
    let plain_view = dir.path().join("plain.view.json");
    render(&plain, &["--view-out", s(&plain_view)]);
    let centre = bounds_centre(&shapes());
    let expected = azimuth(&plain_view, centre);
    // The automatic camera looks from (0.55, 0.45, 1): atan(0.55) = 28.81 degrees.
    assert!((expected - 28.8108).abs() < 1e-3, "{expected}");
    // Frame 0 stands on the plain view's ray from the centre: the same direction, at the
    // distance that fits the model from all three frames' directions, so at least the plain
    // view's (which fits its one direction).
    let (from, to) = (position(&plain_view), position(&tt.join("000.view.json")));
    let offset = |p: [f64; 3]| [p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]];
    let length = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let (a, b) = (offset(from), offset(to));
    let (la, lb) = (length(a), length(b));
    let cosine = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (la * lb);
    assert!(
        1.0 - cosine < 1e-10,
        "frame 0 at {to:?}, plain at {from:?}: not on one ray"
    );
    assert!(
        lb >= la * (1.0 - 1e-6),
        "frame 0 at {lb} from the centre, closer than the plain view's {la}"
    );
    let first = azimuth(&tt.join("000.view.json"), centre);
    let second = azimuth(&tt.join("001.view.json"), centre);
    assert!(
        ((second - first).rem_euclid(360.0) - 120.0).abs() < 1e-3,
        "{second}"
    );
    let plain = png(&plain);
    let frame = png(&tt.join("000.png"));
    let (near, _) = opaque_mean_difference(&plain, &frame);
    let differing = plain
        .pixels()
        .zip(frame.pixels())
        .filter(|(p, q)| p != q)
        .count();
    assert!(
        near < PLAIN_VIEW_TOLERANCE && differing * 100 < plain.pixels().len(),
        "frame 0 is {near:.3} levels off the plain render in the mean, {differing} pixels differ"
    );
}

/// The cell of `index` in a sheet of `columns` columns with thumbnail boxes of `cell` (w, h).
fn cell_origin(index: u32, columns: u32, cell: (u32, u32)) -> (u32, u32) {
    (
        PADDING + (index % columns) * (cell.0 + PADDING),
        PADDING + (index / columns) * (cell.1 + LABEL_HEIGHT + PADDING),
    )
}

/// What the README says a cell shows: the view over the cell background, resized to `size`
/// with a Lanczos-3 filter.
fn expected_thumbnail(view: &RgbaImage, size: (u32, u32)) -> RgbImage {
    let over = RgbImage::from_fn(view.width(), view.height(), |x, y| {
        let p = view.get_pixel(x, y).0;
        let a = u32::from(p[3]);
        image::Rgb([0, 1, 2].map(|c| {
            ((u32::from(p[c]) * a + u32::from(CELL_BACKGROUND[c]) * (255 - a) + 127) / 255) as u8
        }))
    });
    image::imageops::resize(&over, size.0, size.1, image::imageops::FilterType::Lanczos3)
}

/// Asserts that the sheet holds `thumb` at `origin` within CELL_MAX_TOLERANCE.
fn assert_cell(sheet: &RgbImage, origin: (u32, u32), thumb: &RgbImage, what: &str) {
    let mut worst = 0;
    for (x, y, p) in thumb.enumerate_pixels() {
        let q = sheet.get_pixel(origin.0 + x, origin.1 + y);
        worst = worst.max((0..3).map(|c| p.0[c].abs_diff(q.0[c])).max().unwrap());
    }
    assert!(
        worst <= CELL_MAX_TOLERANCE,
        "{what}: differs by {worst} levels"
    );
}

/// Pixels of a label strip that are not sheet background.
fn inked(sheet: &RgbImage, origin: (u32, u32), width: u32) -> Vec<[u8; 3]> {
    (0..width)
        .flat_map(|dx| (0..LABEL_HEIGHT).map(move |dy| (origin.0 + dx, origin.1 + dy)))
        .map(|(x, y)| sheet.get_pixel(x, y).0)
        .filter(|p| *p != SHEET_BACKGROUND)
        .collect()
}

/// A sheet of 5 views: 3 columns by default (about square), 2 rows; size from the layout;
/// each cell is the view's PNG downscaled; each label strip is inked, the sixth cell blank.
/// With --sheet-columns 5, one row.
#[test]
fn contact_sheet_of_views_is_a_labelled_grid_of_thumbnails() {
    let dir = tempfile::tempdir().unwrap();
    let (views, sheet_path) = (dir.path().join("views"), dir.path().join("sheet.png"));
    let cell = (32, 24);
    render(
        &views,
        &[
            "--views",
            "orbit:5",
            "--contact-sheet",
            s(&sheet_path),
            "--sheet-cell-width",
            "32",
        ],
    );
    let sheet = image::open(&sheet_path).unwrap().to_rgb8();
    let (columns, rows) = (3, 2);
    assert_eq!(
        sheet.dimensions(),
        (
            columns * (cell.0 + PADDING) + PADDING,
            rows * (cell.1 + LABEL_HEIGHT + PADDING) + PADDING
        )
    );
    for k in 0..5u32 {
        let view = png(&views.join(format!("{k:03}.png")));
        let origin = cell_origin(k, columns, cell);
        assert_cell(
            &sheet,
            origin,
            &expected_thumbnail(&view, cell),
            &format!("view {k}"),
        );
        let strip = (origin.0, origin.1 + cell.1);
        let ink = inked(&sheet, strip, cell.0);
        assert!(
            ink.len() > 10,
            "view {k}: label drawn ({} pixels)",
            ink.len()
        );
    }
    let empty = cell_origin(5, columns, cell);
    assert!(inked(&sheet, empty, cell.0).is_empty(), "no sixth cell");

    let wide = dir.path().join("wide.png");
    render(
        &dir.path().join("tt"),
        &[
            "--turntable",
            "5",
            "--contact-sheet",
            s(&wide),
            "--sheet-cell-width",
            "32",
            "--sheet-columns",
            "5",
        ],
    );
    let wide = image::open(&wide).unwrap().to_rgb8();
    assert_eq!(
        wide.dimensions(),
        (
            5 * (32 + PADDING) + PADDING,
            24 + LABEL_HEIGHT + 2 * PADDING
        )
    );
}

/// A batch of four jobs, one broken: the sheet has a cell per job in manifest order, the
/// broken job's cell crossed out in red with a red label, the others the thumbnails of the
/// images the jobs wrote (a job's square image centred in the batch's 4:3 box; a job with
/// views, its first view).
#[test]
fn batch_contact_sheet_marks_the_failed_job() {
    let dir = tempfile::tempdir().unwrap();
    let models = dir.path().join("models");
    std::fs::create_dir(&models).unwrap();
    for name in ["shapes.obj", "shapes.mtl", "cornell-box.gltf"] {
        std::fs::copy(root().join("assets").join(name), models.join(name)).unwrap();
    }
    // A face that refers to a vertex the file does not have.
    std::fs::write(models.join("broken.obj"), "v 0 0 0\nf 1 2 3\n").unwrap();
    let manifest = models.join("jobs.jsonl");
    std::fs::write(
        &manifest,
        "{\"id\": \"broken\", \"model\": \"broken.obj\"}\n\
         {\"id\": \"cornell\", \"model\": \"cornell-box.gltf\", \"height\": 64}\n\
         {\"id\": \"shapes\", \"model\": \"shapes.obj\"}\n\
         {\"id\": \"orbit\", \"model\": \"shapes.obj\", \"views\": \"orbit:2\"}\n",
    )
    .unwrap();
    let (out, sheet_path) = (dir.path().join("out"), dir.path().join("sheet.png"));
    let (w, h) = (W.to_string(), H.to_string());
    let extra = [
        "--contact-sheet",
        s(&sheet_path),
        "--sheet-cell-width",
        "48",
    ];
    let args = small_run("batch", s(&manifest), s(&out), (&w, &h), "1", &extra);
    let result = run(&args, false);
    assert!(
        stderr(&result).contains("1 of 4 jobs failed"),
        "{}",
        stderr(&result)
    );
    let sheet = image::open(&sheet_path).unwrap().to_rgb8();
    // 48 px cells: a job id's first characters fit its label strip.
    let cell = (48, 36);
    assert_eq!(
        sheet.dimensions(),
        (
            2 * (48 + PADDING) + PADDING,
            2 * (36 + LABEL_HEIGHT + PADDING) + PADDING
        )
    );
    let is_red = |p: &[u8; 3]| p[0] > 150 && p[1] < 90 && p[2] < 90;
    // Cell 0, broken: a red cross through the box (its corners are on it) and a red label.
    let (x, y) = cell_origin(0, 2, cell);
    for (cx, cy) in [(x, y), (x + cell.0 - 1, y), (x, y + cell.1 - 1)] {
        assert!(is_red(&sheet.get_pixel(cx, cy).0), "cross at ({cx},{cy})");
    }
    let label = inked(&sheet, (x, y + cell.1), cell.0);
    assert!(label.iter().any(is_red), "the failed job's label is red");
    // Cell 1, cornell: a square image (the job's height), fitted 36x36 and centred.
    let cornell = png(&out.join("cornell/image.png"));
    assert_eq!(cornell.width(), cornell.height());
    let (x, y) = cell_origin(1, 2, cell);
    assert_cell(
        &sheet,
        (x + 6, y),
        &expected_thumbnail(&cornell, (36, 36)),
        "cornell",
    );
    assert_eq!(
        sheet.get_pixel(x + 2, y + 18).0,
        SHEET_BACKGROUND,
        "beside the square"
    );
    // Cells 2 and 3 fill their boxes: shapes, and a job with views by its first view.
    for (k, image) in [(2, "shapes/image.png"), (3, "orbit/000.png")] {
        let view = png(&out.join(image));
        let origin = cell_origin(k, 2, cell);
        assert_cell(&sheet, origin, &expected_thumbnail(&view, cell), image);
    }
    for k in 1..4 {
        let (x, y) = cell_origin(k, 2, cell);
        let label = inked(&sheet, (x, y + cell.1), cell.0);
        assert!(
            label.len() > 10 && !label.iter().any(is_red),
            "cell {k}: dark label"
        );
    }
}

/// Bad options: one message naming the problem, exit status 1 (ours) or 2 (the option
/// parser's), no panic, and nothing written where the run was refused.
#[test]
fn bad_turntable_and_sheet_options_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("out");
    let gif = d.join("spin.gif");
    let model = shapes();
    let sheet = d.join("sheet.png");
    let (sheet, jpg, spin_png) = (
        s(&sheet).to_string(),
        s(&d.join("sheet.jpg")).to_string(),
        s(&d.join("spin.png")).to_string(),
    );
    let models = d.join("models");
    std::fs::create_dir(&models).unwrap();
    std::fs::copy(&model, models.join("a.obj")).unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["--turntable", "0", "--gif", s(&gif)],
            "0 is not in 1..=3600",
        ),
        (
            vec!["--turntable", "10001", "--gif", s(&gif)],
            "10001 is not in 1..=3600",
        ),
        (vec!["--turntable", "many"], "invalid value 'many'"),
        (vec!["--gif", s(&gif)], "--turntable"),
        (
            vec!["--turntable", "3", "--gif", &spin_png],
            "spin.png: the file name must end in .gif",
        ),
        (
            vec!["--turntable", "3", "--gif", "/nonexistent-folder/spin.gif"],
            "/nonexistent-folder/spin.gif: cannot write here: no folder /nonexistent-folder",
        ),
        (
            vec!["--turntable", "3", "--gif", s(&gif), "--fps", "0"],
            "--fps 0: must be between 0.0015 and 50",
        ),
        (
            vec!["--turntable", "3", "--gif", s(&gif), "--fps", "100"],
            "--fps 100",
        ),
        (
            vec!["--turntable", "3", "--gif", s(&gif), "--fps", "0.001"],
            "at most 655.35 s",
        ),
        (vec!["--turntable", "3", "--fps", "10"], "--gif"),
        (
            vec!["--turntable", "3", "--views", "orbit:3"],
            "cannot be used with",
        ),
        (
            vec!["--views", "sphere:3", "--orbit-azimuth", "10"],
            "only orbits",
        ),
        (
            vec![
                "--views",
                "orbit:3",
                "--contact-sheet",
                "/nonexistent-folder/sheet.png",
            ],
            "/nonexistent-folder/sheet.png: cannot write here: no folder /nonexistent-folder",
        ),
        (
            vec!["--contact-sheet", &sheet],
            "--contact-sheet lays out many views",
        ),
        (
            vec!["--views", "orbit:3", "--contact-sheet", &jpg],
            "must end in .png",
        ),
        (
            vec![
                "--views",
                "orbit:3",
                "--contact-sheet",
                &sheet,
                "--sheet-columns",
                "0",
            ],
            "--sheet-columns 0: must be at least 1",
        ),
        (
            vec![
                "--views",
                "orbit:3",
                "--contact-sheet",
                &sheet,
                "--sheet-cell-width",
                "0",
            ],
            "--sheet-cell-width 0",
        ),
        (
            vec![
                "--views",
                "orbit:400",
                "--contact-sheet",
                &sheet,
                "--max-pixels",
                "1000000",
            ],
            "over the limit of 1000000 pixels",
        ),
    ];
    for (extra, words) in cases {
        let args = small_run("render", s(&model), s(&out), ("16", "12"), "1", &extra);
        let result = run(&args, false);
        let text = stderr(&result);
        let code = result.status.code();
        assert!(
            matches!(code, Some(1 | 2)),
            "{extra:?}: exit {code:?}\n{text}"
        );
        assert!(text.contains(words), "{extra:?}: {text}");
        assert!(!text.contains("panicked"), "{extra:?}: {text}");
        if code == Some(1) {
            assert_eq!(text.lines().count(), 1, "{extra:?}: one line\n{text}");
        }
        assert!(!gif.exists(), "{extra:?}: no GIF written");
        assert!(!out.exists(), "{extra:?}: no -o folder left");
    }
    // No view was rendered and nothing temporary is left by any refusal.
    let leftovers: Vec<_> = walk(d)
        .into_iter()
        .filter(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            name.ends_with(".png") || name.ends_with(".partial")
        })
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

/// A GIF given as -o, a batch's contact sheet that is not a PNG and a batch turntable are
/// refused with what to do instead.
#[test]
fn misplaced_gif_and_batch_sheet_options_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (out, gif, model) = (d.join("out"), d.join("spin.gif"), shapes());
    let jpg = s(&d.join("sheet.jpg")).to_string();
    let models = d.join("models");
    std::fs::create_dir(&models).unwrap();
    std::fs::copy(&model, models.join("a.obj")).unwrap();
    let result = run(
        &["render", s(&model), "--turntable", "4", "-o", s(&gif), "-q"],
        false,
    );
    assert!(
        stderr(&result).contains("-o names the folder of the frames; write the GIF with"),
        "{}",
        stderr(&result)
    );
    assert!(!gif.exists());
    let result = run(
        &[
            "batch",
            s(&models),
            "-o",
            s(&out),
            "--contact-sheet",
            &jpg,
            "-q",
        ],
        false,
    );
    assert!(stderr(&result).contains("sheet.jpg: the file name must end in .png"));
    let result = run(
        &["batch", s(&models), "-o", s(&out), "--turntable", "4", "-q"],
        false,
    );
    assert!(
        stderr(&result).contains("\"views\": \"orbit:4\""),
        "{}",
        stderr(&result)
    );
}

/// Every file below `dir`.
fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files.extend(walk(&path));
        } else {
            files.push(path);
        }
    }
    files
}
