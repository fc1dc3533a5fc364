//! Tiles (`render --tile I/N`, `--crop X,Y,W,H`) and `merge`, through the real binary: tiles
//! merged equal the single render byte for byte, the image and every AOV, in every format a
//! tile can be written in; a denoised render's tiles (the default render's) merged and
//! denoised equal the single denoised render; missing, overlapping and mismatched tiles, a
//! missing or replaced denoise input and bad specs are refused with one error and exit 1.

use crate::common::{root, run, s, stderr};
use std::path::{Path, PathBuf};

/// The test renders' size: small, and 32 rows cut into 4 bands of 8.
const W: &str = "48";
const H: &str = "32";

fn cornell() -> PathBuf {
    root().join("assets/cornell-box.gltf")
}

fn shapes() -> PathBuf {
    root().join("assets/shapes.obj")
}

/// The AOV options with a file name each, `{}` replaced by `tag`.
fn aov_args(dir: &Path, tag: &str, formats: [&str; 4]) -> Vec<String> {
    let names = ["depth", "normal", "mask", "segmentation"];
    names
        .iter()
        .zip(formats)
        .flat_map(|(name, ext)| {
            [
                format!("--{name}-out"),
                s(&dir.join(format!("{name}-{tag}.{ext}"))).to_string(),
            ]
        })
        .collect()
}

/// Renders `model` at W x H, 4 spp (jittered samples, so the per-pixel streams matter), with
/// the AOVs and `extra` options.
fn render(model: &Path, out: &Path, aovs: &[String], extra: &[&str]) {
    let mut options = vec!["--spp", "4"];
    options.extend_from_slice(extra);
    render_sized(model, out, (W, H), aovs, &options);
}

/// Renders `model` at `size` with the AOVs and `extra` options (the render's own sampling
/// unless they give one).
fn render_sized(model: &Path, out: &Path, size: (&str, &str), aovs: &[String], extra: &[&str]) {
    let mut args: Vec<&str> = vec![
        "render",
        s(model),
        "-o",
        s(out),
        "--width",
        size.0,
        "--height",
        size.1,
        "-q",
    ];
    args.extend(aovs.iter().map(String::as_str));
    args.extend_from_slice(extra);
    run(&args, true);
}

fn bytes(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Renders the whole image and `parts` (each the options that cut one tile), merges the tiles
/// and checks every output equals the single render's, byte for byte: at W x H and 4 spp.
fn tiles_equal_whole(model: &Path, image_ext: &str, formats: [&str; 4], parts: &[Vec<&str>]) {
    let render = Render {
        size: (W, H),
        options: &["--spp", "4"],
        denoised: false,
    };
    render.tiles_equal_whole(model, image_ext, formats, parts);
}

/// How the whole image and its tiles are rendered.
struct Render<'a> {
    size: (&'a str, &'a str),
    /// The options besides the size, AOVs and tile.
    options: &'a [&'a str],
    /// Whether the render is denoised: its tiles then keep their film and guides for merge.
    denoised: bool,
}

impl Render<'_> {
    /// [`tiles_equal_whole`] for this render.
    fn tiles_equal_whole(
        &self,
        model: &Path,
        image_ext: &str,
        formats: [&str; 4],
        parts: &[Vec<impl AsRef<str> + std::fmt::Debug>],
    ) {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let whole = d.join(format!("whole.{image_ext}"));
        let aovs = aov_args(d, "whole", formats);
        render_sized(model, &whole, self.size, &aovs, self.options);
        let mut tiles = Vec::new();
        for (i, part) in parts.iter().enumerate() {
            let tile = d.join(format!("tile-{i}.{image_ext}"));
            let mut options = self.options.to_vec();
            options.extend(part.iter().map(AsRef::as_ref));
            let aovs = aov_args(d, &format!("tile-{i}"), formats);
            render_sized(model, &tile, self.size, &aovs, &options);
            let sidecar = d.join(format!("tile-{i}.{image_ext}.tile.json"));
            assert!(sidecar.is_file(), "tile {i} has its sidecar");
            let denoise_input = d.join(format!("tile-{i}.{image_ext}.denoise.exr"));
            assert_eq!(denoise_input.is_file(), self.denoised, "tile {i}");
            let listed: serde_json::Value = serde_json::from_slice(&bytes(&sidecar)).unwrap();
            let version = if self.denoised { 2 } else { 1 };
            assert_eq!(listed["meshtracer_tile"], version, "tile {i}");
            assert_eq!(listed["outputs"]["denoise"].is_string(), self.denoised);
            tiles.push(s(&tile).to_string());
        }
        // Tiles hold their part alone.
        assert!(bytes(&d.join(format!("tile-0.{image_ext}"))).len() < bytes(&whole).len());
        let merged = d.join(format!("merged.{image_ext}"));
        let mut args: Vec<String> =
            vec!["merge".into(), "-o".into(), s(&merged).into(), "-q".into()];
        args.extend(aov_args(d, "merged", formats));
        args.extend(tiles);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        run(&args, true);
        assert!(
            bytes(&merged) == bytes(&whole),
            "merged image != single render ({:?}, {parts:?})",
            self.options
        );
        for (name, ext) in ["depth", "normal", "mask", "segmentation"]
            .iter()
            .zip(formats)
        {
            let a = bytes(&d.join(format!("{name}-whole.{ext}")));
            let b = bytes(&d.join(format!("{name}-merged.{ext}")));
            assert!(a == b, "merged {name}.{ext} != single render's");
        }
    }
}

/// `--tile I/N` for every I.
fn bands(count: u32) -> Vec<Vec<String>> {
    (0..count)
        .map(|i| vec!["--tile".to_string(), format!("{i}/{count}")])
        .collect()
}

/// The default render (no --spp) at 64 x 48, denoised.
const DEFAULT_RENDER: Render = Render {
    size: ("64", "48"),
    options: &[],
    denoised: true,
};

/// The default render (no --spp) is denoised: its tiles keep their film and guides, and merge
/// denoises the whole, into the single default render byte for byte, image and AOVs, whether
/// cut into 2 or 3 bands.
#[test]
fn default_render_bands_merge_into_the_denoised_single_render() {
    for count in [2, 3] {
        DEFAULT_RENDER.tiles_equal_whole(
            &cornell(),
            "png",
            ["png", "exr", "png", "npy"],
            &bands(count),
        );
    }
}

/// As the bands: crops of uneven size, given in no particular order, into an EXR.
#[test]
fn default_render_crops_merge_into_the_denoised_single_render() {
    let parts: Vec<Vec<&str>> = ["40,0,24,20", "0,20,64,28", "0,0,40,20"]
        .iter()
        .map(|c| vec!["--crop", *c])
        .collect();
    DEFAULT_RENDER.tiles_equal_whole(&shapes(), "exr", ["npy", "npy", "png", "png"], &parts);
}

/// `--denoise` with `--spp` denoises the tiles' merge the same way, the direct integrator's
/// traced guides too; `--no-denoise` tiles of the default sampling are merged as before
/// (pasted, no denoise input) into the `--no-denoise` single render.
#[test]
fn denoised_and_undenoised_tiles_merge_into_their_single_renders() {
    for (options, denoised) in [
        (
            &["--spp", "4", "--denoise", "--integrator", "direct"][..],
            true,
        ),
        (&["--spp", "2", "--denoise"][..], true),
        (&["--no-denoise"][..], false),
    ] {
        let render = Render {
            size: ("64", "48"),
            options,
            denoised,
        };
        render.tiles_equal_whole(&cornell(), "png", ["png", "png", "png", "png"], &bands(2));
    }
}

#[test]
fn four_bands_merge_into_the_single_render_png() {
    let parts: Vec<Vec<&str>> = ["0/4", "1/4", "2/4", "3/4"]
        .iter()
        .map(|t| vec!["--tile", *t])
        .collect();
    tiles_equal_whole(&cornell(), "png", ["png", "png", "png", "png"], &parts);
}

#[test]
fn four_crops_merge_into_the_single_render_exr_and_npy() {
    // Quadrants of uneven size, given to merge in no particular order.
    let parts: Vec<Vec<&str>> = ["20,13,28,19", "0,0,20,13", "20,0,28,13", "0,13,20,19"]
        .iter()
        .map(|c| vec!["--crop", *c])
        .collect();
    tiles_equal_whole(&shapes(), "exr", ["npy", "exr", "npy", "npy"], &parts);
}

/// Renders tiles I/4 of the Cornell box (beauty only) into `dir`, with `extra` options.
fn band(dir: &Path, index: u32, extra: &[&str]) -> String {
    let tile = dir.join(format!("band-{index}.png"));
    let spec = format!("{index}/4");
    let mut options = vec!["--tile", spec.as_str()];
    options.extend_from_slice(extra);
    render(&cornell(), &tile, &[], &options);
    s(&tile).to_string()
}

/// Runs `merge` expecting failure with one error line containing `needle`; checks nothing was
/// written.
fn merge_fails(dir: &Path, tiles: &[&str], extra: &[&str], needle: &str) {
    let out = dir.join("refused.png");
    let mut args = vec!["merge", "-o", s(&out)];
    args.extend_from_slice(extra);
    args.extend_from_slice(tiles);
    let output = run(&args, false);
    assert_eq!(output.status.code(), Some(1));
    let err = stderr(&output);
    assert!(err.contains(needle), "expected '{needle}' in: {err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(err.lines().count(), 1, "one error line: {err}");
    assert!(!out.exists(), "nothing written");
}

#[test]
fn missing_overlapping_and_mismatched_tiles_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let t: Vec<String> = (0..4).map(|i| band(d, i, &[])).collect();
    let t: Vec<&str> = t.iter().map(String::as_str).collect();
    merge_fails(d, &t[..3], &[], "missing tile(s) 3/4");
    merge_fails(d, &[t[0], t[1], t[2], t[3], t[0]], &[], "overlap");
    let other_seed = {
        let dir = d.join("seed");
        std::fs::create_dir(&dir).unwrap();
        band(&dir, 3, &["--seed", "7"])
    };
    merge_fails(d, &[t[0], t[1], t[2], &other_seed], &[], "different render");
    merge_fails(
        d,
        &t,
        &["--depth-out", s(&d.join("depth.png"))],
        "the tiles have no depth output",
    );
    let not_a_tile = d.join("plain.png");
    std::fs::write(d.join("plain.png.tile.json"), "{\"hello\": 1}").unwrap();
    merge_fails(d, &[s(&not_a_tile)], &[], "not a meshtracer tile sidecar");
    merge_fails(
        d,
        &[s(&d.join("absent.png"))],
        &[],
        "cannot read the tile's sidecar",
    );
    // The merged image may not replace a tile.
    let tile_bytes = std::fs::read(t[0]).unwrap();
    let output = run(&["merge", "-o", t[0], t[0], t[1], t[2], t[3]], false);
    let err = stderr(&output);
    assert!(err.contains("-o would overwrite a tile's file"), "{err}");
    assert_eq!(std::fs::read(t[0]).unwrap(), tile_bytes);
    // A tile whose image was replaced by one of another size.
    let resized = image::RgbaImage::new(48, 9);
    resized.save(d.join("band-3.png")).unwrap();
    merge_fails(d, &t, &[], "but its sidecar");
}

/// A denoised render's tile whose denoise input is missing or was replaced is refused, as is
/// a merge of denoised and undenoised tiles of one render.
#[test]
fn a_missing_or_replaced_denoise_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let half = |i: u32, extra: &[&str]| {
        let out = d.join(format!("half-{i}{}.png", extra.len()));
        let spec = format!("{i}/2");
        let mut options = vec!["--tile", spec.as_str()];
        options.extend_from_slice(extra);
        render_sized(&cornell(), &out, ("64", "48"), &[], &options);
        s(&out).to_string()
    };
    let (first, second) = (half(0, &[]), half(1, &[]));
    let plain = half(1, &["--no-denoise"]);
    merge_fails(d, &[&first, &plain], &[], "different render");
    let input = |tile: &str| PathBuf::from(format!("{tile}.denoise.exr"));
    std::fs::rename(input(&second), d.join("aside.exr")).unwrap();
    merge_fails(
        d,
        &[&first, &second],
        &[],
        "cannot read the tile's denoise input",
    );
    std::fs::copy(input(&first), input(&second)).unwrap();
    merge_fails(d, &[&first, &second], &[], "its SHA-256 differs");
    std::fs::rename(d.join("aside.exr"), input(&second)).unwrap();
    run(
        &[
            "merge",
            "-q",
            "-o",
            s(&d.join("whole.png")),
            &first,
            &second,
        ],
        true,
    );
}

#[test]
fn tiles_of_a_model_whose_mtl_changed_between_them_are_refused() {
    // Same triangles and bounds, another colour: only the model's files tell the tiles apart.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for name in ["shapes.obj", "shapes.mtl"] {
        std::fs::copy(root().join("assets").join(name), d.join(name)).unwrap();
    }
    let model = d.join("shapes.obj");
    let tile = |i: u32| {
        let out = d.join(format!("half-{i}.png"));
        render(&model, &out, &[], &["--tile", &format!("{i}/2")]);
        s(&out).to_string()
    };
    let first = tile(0);
    let second = tile(1);
    // Unchanged, the halves join.
    let whole = d.join("whole.png");
    run(&["merge", "-q", "-o", s(&whole), &first, &second], true);
    std::fs::remove_file(&whole).unwrap();
    crate::common::recolour_mtl(&d.join("shapes.mtl"));
    let recoloured = tile(1);
    merge_fails(
        d,
        &[&first, &recoloured],
        &[],
        "model or a file it refers to",
    );
}

#[test]
fn bad_tile_options_are_refused_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.png");
    let model = cornell();
    for (options, needle) in [
        (vec!["--tile", "4/4"], "between 0 and 3"),
        (vec!["--tile", "1/0"], "at least 1"),
        (vec!["--tile", "x"], "expected I/N"),
        (vec!["--tile", "0/33"], "only 32 rows"),
        (vec!["--crop", "40,0,9,1"], "does not fit the 48x32 image"),
        (vec!["--crop", "1,2,3"], "expected X,Y,W,H"),
        (
            vec!["--tile", "0/2", "--crop", "0,0,1,1"],
            "cannot be used with",
        ),
    ] {
        let mut args = vec![
            "render",
            s(&model),
            "-o",
            s(&out),
            "--width",
            W,
            "--height",
            H,
            "-q",
        ];
        args.extend_from_slice(&options);
        let output = run(&args, false);
        let err = stderr(&output);
        assert!(
            err.contains(needle),
            "{options:?}: expected '{needle}' in: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
        assert!(!out.exists());
    }
    // Formats that do not keep the pixels as rendered cannot be merged exactly.
    for name in ["t.hdr", "t.jpg"] {
        let lossy = dir.path().join(name);
        let output = run(
            &[
                "render",
                s(&cornell()),
                "-o",
                s(&lossy),
                "--tile",
                "0/2",
                "-q",
            ],
            false,
        );
        assert!(stderr(&output).contains("must be .png or .exr"), "{name}");
        assert!(!lossy.exists());
    }
}

/// A tile's summary line names the tile (its size, the whole image's and where it starts) and
/// the adaptive sampler's mean over the tile's own pixels: at 64x48 every pixel takes the cap
/// of 4 samples, so the tile says 4.0 spp as the whole image does (2.0 when its samples were
/// divided by the whole image's pixels).
#[test]
fn a_tiles_summary_names_the_tile_and_its_own_spp() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.png");
    let output = run(
        &[
            "render",
            s(&cornell()),
            "-o",
            s(&out),
            "--width",
            "64",
            "--height",
            "48",
            "--spp",
            "4",
            "--noise",
            "1",
            "--no-denoise",
            "--tile",
            "1/2",
        ],
        true,
    );
    let err = stderr(&output);
    assert!(
        err.contains(", 64x24 of 64x48 from (0, 24) at 4.0 spp (adaptive"),
        "{err}"
    );
    let whole = run(
        &[
            "render",
            s(&cornell()),
            "-o",
            s(&dir.path().join("w.png")),
            "--width",
            "64",
            "--height",
            "48",
            "--spp",
            "4",
            "--noise",
            "1",
            "--no-denoise",
        ],
        true,
    );
    assert!(
        stderr(&whole).contains(", 64x48 at 4.0 spp (adaptive"),
        "{}",
        stderr(&whole)
    );
}
