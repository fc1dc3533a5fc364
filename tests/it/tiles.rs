//! Tiles (`render --tile I/N`, `--crop X,Y,W,H`) and `merge`, through the real binary: tiles
//! merged equal the single render byte for byte, the image and every AOV, in every format a
//! tile can be written in; missing, overlapping and mismatched tiles and bad specs are refused
//! with one error and exit 1.

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
    let mut args: Vec<&str> = vec![
        "render",
        s(model),
        "-o",
        s(out),
        "--width",
        W,
        "--height",
        H,
        "--spp",
        "4",
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
/// and checks every output equals the single render's, byte for byte.
fn tiles_equal_whole(model: &Path, image_ext: &str, formats: [&str; 4], parts: &[Vec<&str>]) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = d.join(format!("whole.{image_ext}"));
    render(model, &whole, &aov_args(d, "whole", formats), &[]);
    let mut tiles = Vec::new();
    for (i, part) in parts.iter().enumerate() {
        let tile = d.join(format!("tile-{i}.{image_ext}"));
        render(
            model,
            &tile,
            &aov_args(d, &format!("tile-{i}"), formats),
            part,
        );
        assert!(
            d.join(format!("tile-{i}.{image_ext}.tile.json")).is_file(),
            "tile {i} has its sidecar"
        );
        tiles.push(s(&tile).to_string());
    }
    // Tiles hold their part alone.
    assert!(bytes(&d.join(format!("tile-0.{image_ext}"))).len() < bytes(&whole).len());
    let merged = d.join(format!("merged.{image_ext}"));
    let mut args: Vec<String> = vec!["merge".into(), "-o".into(), s(&merged).into(), "-q".into()];
    args.extend(aov_args(d, "merged", formats));
    args.extend(tiles);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    run(&args, true);
    assert!(
        bytes(&merged) == bytes(&whole),
        "merged image != single render"
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
