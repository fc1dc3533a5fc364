//! `render --tile I/N` / `--crop X,Y,W,H` (the part of the image a render covers, and the
//! sidecar it leaves) and `merge` (tiles joined into the whole image). The formats and checks
//! are in [`meshtracer::jobs::tiles`].

use crate::cli::{MergeArgs, RenderArgs};
use anyhow::{bail, Context, Result};
use meshtracer::jobs::batch::model_digest;
use meshtracer::jobs::tiles::{
    check_cover, extension, fingerprint, Raster, TileFile, TILE_FILE_VERSION,
};
use meshtracer::render::{Region, RenderSettings};
use meshtracer::scene::Scene;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Whether this render is a tile.
fn tiled(args: &RenderArgs) -> bool {
    args.tile.is_some() || args.crop.is_some()
}

/// Refusals a tiled render makes before any work: tiles are merged exactly only from formats
/// that keep the pixels as written (PNG, EXR, `.npy`), not from RGBE `.hdr` or lossy JPEG.
pub(super) fn check_render(args: &RenderArgs) -> Result<()> {
    let ext = extension(&args.output);
    if tiled(args) && ["hdr", "jpg", "jpeg"].contains(&ext.as_str()) {
        bail!(
            "{}: a tile's image must be .png or .exr (an .{ext} tile cannot be merged exactly)",
            args.output.display()
        );
    }
    Ok(())
}

/// The part of the `width` x `height` image this render covers: the whole image unless
/// `--tile` or `--crop` says otherwise.
pub(super) fn region(args: &RenderArgs, width: u32, height: u32) -> Result<Region> {
    Ok(match (args.tile, args.crop) {
        (Some(tile), _) => tile.region(width, height)?,
        (None, Some(crop)) => meshtracer::jobs::tiles::check_crop(crop, width, height)?,
        (None, None) => Region::full(width, height),
    })
}

/// Everything that decides a pixel's value, as text: tiles join only when this agrees.
pub(super) fn render_fingerprint(
    args: &RenderArgs,
    settings: &RenderSettings,
    scene: &Scene,
) -> String {
    let environment = settings
        .environment
        .as_ref()
        .map(|e| format!("{:?} {} {}", e.source, e.rotation_degrees(), e.intensity()));
    // Options added later join the text only when set, so tiles of earlier renders still join.
    let mut later = String::new();
    if args.tonemap != meshtracer::color::ViewTransform::default() {
        later += &format!("; tonemap {:?}", args.tonemap);
    }
    if let Some(noise) = settings.noise {
        later += &format!("; noise {noise}");
    }
    if let Some(clamp) = settings.clamp_indirect {
        later += &format!("; clamp indirect {clamp}");
    }
    fingerprint(&format!(
        "view {:?}; spp {}; seed {}; lights {:?}; ambient {:?}; exposure {}; shading {:?}; integrator {:?}; bounces {}; environment {environment:?} visible {}; background {:?}; depth scale {}; triangles {}; bounds {:?}{later}",
        settings.view,
        settings.spp,
        settings.seed,
        settings.lights,
        settings.ambient,
        settings.exposure,
        settings.shading,
        settings.integrator,
        settings.bounces,
        settings.environment_visible,
        args.background,
        args.depth_scale,
        scene.soup.len(),
        scene.bounds,
    ))
}

/// A tile's fingerprint: the render's ([`render_fingerprint`]) and the model's bytes with
/// those of every file it refers to ([`model_digest`]), so that tiles rendered before and after
/// an edit of the model, a texture or an `.mtl` do not join, where the triangle count and
/// bounds alone would let them. (A view's fingerprint holds the digest apart.)
fn tile_fingerprint(args: &RenderArgs, settings: &RenderSettings, scene: &Scene) -> String {
    fingerprint(&format!(
        "{}\nmodel {}",
        render_fingerprint(args, settings, scene),
        model_digest(&args.model, &scene.inputs)
    ))
}

/// A path as the sidecar in `dir` records it: relative to `dir` when the file is inside it,
/// else absolute.
fn relative_to(file: &Path, dir: &Path) -> PathBuf {
    let (Ok(file), Ok(dir)) = (file.canonicalize(), dir.canonicalize()) else {
        return file.to_path_buf();
    };
    file.strip_prefix(&dir)
        .map(Path::to_path_buf)
        .unwrap_or(file)
}

/// Writes the sidecar of a tiled render, after its outputs: a sidecar means a complete tile.
pub(super) fn write_sidecar(
    args: &RenderArgs,
    region: Region,
    settings: &RenderSettings,
    scene: &Scene,
) -> Result<()> {
    if !tiled(args) {
        return Ok(());
    }
    let sidecar = TileFile::sidecar_path(&args.output);
    let dir = match sidecar.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let outputs: BTreeMap<String, PathBuf> = [
        ("image", Some(&args.output)),
        ("depth", args.depth_out.as_ref()),
        ("normal", args.normal_out.as_ref()),
        ("mask", args.mask_out.as_ref()),
        ("segmentation", args.segmentation_out.as_ref()),
    ]
    .into_iter()
    .filter_map(|(kind, path)| path.map(|p| (kind.to_string(), relative_to(p, &dir))))
    .collect();
    let file = TileFile {
        meshtracer_tile: TILE_FILE_VERSION,
        image: meshtracer::output::view_file::ImageSize {
            width: settings.view.width,
            height: settings.view.height,
        },
        region,
        tile: args.tile,
        render: tile_fingerprint(args, settings, scene),
        outputs,
    };
    let text = serde_json::to_string_pretty(&file)?;
    meshtracer::output::write_atomic(&sidecar, text.as_bytes())?;
    Ok(())
}

/// `meshtracer merge -o OUT TILE...`.
pub(super) fn merge_command(args: &MergeArgs) -> Result<()> {
    // A signal stops the merge between tiles, before any file is written; once the writing
    // starts, every file asked for is written.
    let cancel = super::interrupt_flag();
    let tiles: Vec<(PathBuf, TileFile)> = args
        .tiles
        .iter()
        .map(|t| {
            let sidecar = TileFile::sidecar_path(t);
            TileFile::read(&sidecar).map(|file| (sidecar, file))
        })
        .collect::<Result<_, _>>()?;
    let size = check_cover(&tiles)?;
    let (_, first) = &tiles[0];
    let asked = [
        ("image", Some(&args.output), "-o"),
        ("depth", args.depth_out.as_ref(), "--depth-out"),
        ("normal", args.normal_out.as_ref(), "--normal-out"),
        ("mask", args.mask_out.as_ref(), "--mask-out"),
        (
            "segmentation",
            args.segmentation_out.as_ref(),
            "--segmentation-out",
        ),
    ];
    // Every refusal before any file is read or written.
    let mut jobs = Vec::new();
    for (kind, out, option) in asked {
        let tile_file = first.outputs.get(kind);
        match (out, tile_file) {
            (Some(out), Some(tile_file)) => {
                if extension(out) != extension(tile_file) {
                    bail!(
                        "{option} {}: the tiles' {kind} files are .{}: merge into the same format (no conversion, so the pixels stay exact)",
                        out.display(),
                        extension(tile_file)
                    );
                }
                if args.no_clobber && out.exists() {
                    bail!("{}: already exists (--no-clobber)", out.display());
                }
                jobs.push((kind, out));
            }
            (Some(out), None) => bail!(
                "{option} {}: the tiles have no {kind} output (render them with {option})",
                out.display()
            ),
            (None, Some(_)) if !args.quiet => {
                eprintln!("note: the tiles also have {kind} files; add {option} FILE to merge them")
            }
            (None, _) => {}
        }
    }
    // No output may be one of the tiles' files, nor two outputs one file.
    let tile_files: Vec<PathBuf> = tiles
        .iter()
        .flat_map(|(sidecar, tile)| {
            let files = tile
                .outputs
                .keys()
                .filter_map(|k| tile.output_path(sidecar, k));
            files
                .chain(std::iter::once(sidecar.clone()))
                .collect::<Vec<_>>()
        })
        .collect();
    let inputs: Vec<_> = tile_files
        .iter()
        .map(|p| ("a tile's file", p.as_path()))
        .collect();
    let outputs: Vec<_> = asked
        .iter()
        .filter_map(|&(_, out, option)| out.map(|p| (option, p.as_path())))
        .collect();
    meshtracer::output::check_destinations(&outputs, &inputs, args.no_clobber)?;
    let mut encoded = Vec::new();
    for (kind, out) in jobs {
        let mut whole: Option<Raster> = None;
        let mut first_layout = String::new();
        for (sidecar, tile) in &tiles {
            let path = tile
                .output_path(sidecar, kind)
                .with_context(|| format!("{}: lists no {kind} file", sidecar.display()))?;
            let part = Raster::read(&path)?;
            let region = tile.region;
            if part.size() != (u64::from(region.width), u64::from(region.height)) {
                bail!(
                    "{}: {}x{} pixels, but its sidecar {} says the tile is {}x{}",
                    path.display(),
                    part.size().0,
                    part.size().1,
                    sidecar.display(),
                    region.width,
                    region.height
                );
            }
            let whole = whole.get_or_insert_with(|| {
                first_layout = part.layout();
                part.blank_like(size.width, size.height)
            });
            if part.layout() != first_layout {
                bail!(
                    "{}: pixel layout {}, the other tiles' {kind} files are {first_layout}",
                    path.display(),
                    part.layout()
                );
            }
            whole.paste(&part, region.x, region.y)?;
            super::render::stop_if_cancelled(&cancel)?;
        }
        if let Some(whole) = whole {
            encoded.push((out, whole.encode(out)?));
        }
    }
    super::render::stop_if_cancelled(&cancel)?;
    for (out, bytes) in encoded {
        meshtracer::output::write_atomic(out, &bytes)?;
    }
    if !args.quiet {
        eprintln!(
            "merged {} tiles into {}x{} -> {}",
            tiles.len(),
            size.width,
            size.height,
            args.output.display()
        );
    }
    Ok(())
}
