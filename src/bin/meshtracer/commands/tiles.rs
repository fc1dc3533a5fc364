//! `render --tile I/N` / `--crop X,Y,W,H` (the part of the image a render covers, and the
//! sidecar it leaves) and `merge` (tiles joined into the whole image). The formats and checks
//! are in [`meshtracer::jobs::tiles`].

use crate::cli::{MergeArgs, RenderArgs};
use anyhow::{bail, Context, Result};
use meshtracer::jobs::batch::{model_digest, sha256_hex};
use meshtracer::jobs::tiles::{
    check_cover, extension, fingerprint, Raster, TileDenoise, TileFile, DENOISED_TILE_FILE_VERSION,
    DENOISE_INPUT, TILE_FILE_VERSION,
};
use meshtracer::output::view_file::ImageSize;
use meshtracer::render::denoise::{Denoised, Denoiser, Guides};
use meshtracer::render::{Image, Region, RenderSettings};
use meshtracer::scene::Scene;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

/// Whether this render is a tile.
pub(super) fn tiled(args: &RenderArgs) -> bool {
    args.tile.is_some() || args.crop.is_some()
}

/// The file a denoised render's tile keeps its film and guides in, for `merge`
/// ([`TileFile::denoise_input_path`]), named as an output; `None` for other renders.
pub(super) fn denoise_input(args: &RenderArgs) -> Option<(&'static str, PathBuf)> {
    (tiled(args) && args.denoises()).then(|| {
        (
            "the tile's denoise input (beside -o)",
            TileFile::denoise_input_path(&args.output),
        )
    })
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
/// A denoised render's tiles add that they are, so that they never join tiles of the same
/// render not denoised (whose image merge pastes as it is).
fn tile_fingerprint(args: &RenderArgs, settings: &RenderSettings, scene: &Scene) -> String {
    fingerprint(&format!(
        "{}\nmodel {}{}",
        render_fingerprint(args, settings, scene),
        model_digest(&args.model, &scene.inputs),
        if args.denoises() { "\ndenoised" } else { "" }
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
/// A denoised render's tile writes its film and guides (`denoise_input`: the tile's image,
/// not denoised, and its guides) first, into [`denoise_input`]'s file.
pub(super) fn write_sidecar(
    args: &RenderArgs,
    region: Region,
    settings: &RenderSettings,
    scene: &Scene,
    denoise_input: Option<(&Image, &Guides)>,
) -> Result<()> {
    if !tiled(args) {
        return Ok(());
    }
    let sidecar = TileFile::sidecar_path(&args.output);
    let dir = match sidecar.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let denoise = match denoise_input {
        Some((image, guides)) => Some(write_denoise_input(args, image, guides)?),
        None => None,
    };
    let denoise_path = denoise
        .as_ref()
        .map(|_| TileFile::denoise_input_path(&args.output));
    let outputs: BTreeMap<String, PathBuf> = [
        ("image", Some(&args.output)),
        ("depth", args.depth_out.as_ref()),
        ("normal", args.normal_out.as_ref()),
        ("mask", args.mask_out.as_ref()),
        ("segmentation", args.segmentation_out.as_ref()),
        (DENOISE_INPUT, denoise_path.as_ref()),
    ]
    .into_iter()
    .filter_map(|(kind, path)| path.map(|p| (kind.to_string(), relative_to(p, &dir))))
    .collect();
    let file = TileFile {
        meshtracer_tile: if denoise.is_some() {
            DENOISED_TILE_FILE_VERSION
        } else {
            TILE_FILE_VERSION
        },
        image: meshtracer::output::view_file::ImageSize {
            width: settings.view.width,
            height: settings.view.height,
        },
        region,
        tile: args.tile,
        render: tile_fingerprint(args, settings, scene),
        outputs,
        denoise,
    };
    let text = serde_json::to_string_pretty(&file)?;
    meshtracer::output::write_atomic(&sidecar, text.as_bytes())?;
    Ok(())
}

/// Writes a denoised render's tile's film and guides ([`meshtracer::output::denoise_input`])
/// beside its image; returns the sidecar's record of them.
fn write_denoise_input(args: &RenderArgs, image: &Image, guides: &Guides) -> Result<TileDenoise> {
    let path = TileFile::denoise_input_path(&args.output);
    let bytes = meshtracer::output::denoise_input::encode(image, guides)
        .with_context(|| format!("{}: encoding failed", path.display()))?;
    meshtracer::output::write_atomic(&path, &bytes)?;
    Ok(TileDenoise {
        sha256: sha256_hex(&bytes),
        samples: image.samples,
        guide_samples: guides.samples_per_pixel,
        background: args.background.map(|b| b.to_array()),
        tonemap: args.tonemap.name().to_string(),
        denoiser: Denoiser::of_this_build().id().to_string(),
    })
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
                note!("note: the tiles also have {kind} files; add {option} FILE to merge them")
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
    let mut denoised = None;
    for (kind, out) in jobs {
        let bytes = match &first.denoise {
            Some(denoise) if kind == "image" => {
                let (image, report) = denoise_whole(&tiles, size, &cancel)?;
                denoised = Some(report);
                let background = denoise.background.map(glam::Vec3::from);
                let view = denoise.view_transform().map_err(anyhow::Error::msg)?;
                meshtracer::output::encode_image(out, &image, background, view)?
            }
            _ => paste_whole(kind, &tiles, size, &cancel)?.encode(out)?,
        };
        encoded.push((out, bytes));
    }
    super::render::stop_if_cancelled(&cancel)?;
    for (out, bytes) in encoded {
        meshtracer::output::write_atomic(out, &bytes)?;
    }
    if !args.quiet {
        let denoise_note = match (&denoised, &first.denoise) {
            (Some(report), Some(denoise)) => {
                if denoise.denoiser != report.denoiser.id() {
                    note!(
                        "note: the tiles were rendered by a build that denoises with '{}'; this one denoised with '{}' (the result is this build's single render)",
                        denoise.denoiser,
                        report.denoiser.id()
                    );
                }
                format!(", denoised by {}", super::render::denoiser_label(report))
            }
            _ => String::new(),
        };
        note!(
            "merged {} into {}x{}{denoise_note} -> {}",
            super::counted(tiles.len(), "tile"),
            size.width,
            size.height,
            args.output.display()
        );
    }
    Ok(())
}

/// The tiles' `kind` files pasted into the whole `size` image; each checked against its
/// sidecar's tile (size) and the first tile (pixel layout).
fn paste_whole(
    kind: &str,
    tiles: &[(PathBuf, TileFile)],
    size: ImageSize,
    cancel: &AtomicBool,
) -> Result<Raster> {
    let mut whole: Option<Raster> = None;
    let mut first_layout = String::new();
    for (sidecar, tile) in tiles {
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
        super::render::stop_if_cancelled(cancel)?;
    }
    whole.context("no tiles given")
}

/// A denoised render's tiles' films and guides joined into the whole `size` image's and
/// denoised as the render denoises its film ([`meshtracer::render::denoise::denoise`]): the
/// linear image a single render encodes, and what the denoiser did. One tile's film and
/// guides are held at a time beside the whole's.
fn denoise_whole(
    tiles: &[(PathBuf, TileFile)],
    size: ImageSize,
    cancel: &AtomicBool,
) -> Result<(Image, Denoised)> {
    let mut whole: Option<(Image, Guides)> = None;
    for (sidecar, tile) in tiles {
        let (part, part_guides) = tile.read_denoise_input(sidecar)?;
        let (image, guides) = whole.get_or_insert_with(|| {
            let mut image = Image::new(size.width, size.height);
            image.samples = part.samples;
            let from_samples = !part_guides.visibility.is_empty();
            let guides = Guides::new(
                size.width,
                size.height,
                from_samples,
                part_guides.samples_per_pixel,
            );
            (image, guides)
        });
        let kept = |g: &Guides| (g.visibility.is_empty(), g.emission.is_empty());
        if kept(&part_guides) != kept(guides) {
            bail!(
                "{}: its denoise input's guides have other channels than the first tile's (visibility, emission): tiles of different renders cannot be merged",
                sidecar.display()
            );
        }
        let region = tile.region;
        image.paste(&part, region.x, region.y);
        guides.paste(&part_guides, region.x, region.y);
        super::render::stop_if_cancelled(cancel)?;
    }
    let (mut image, guides) = whole.context("no tiles given")?;
    let report = meshtracer::render::denoise::denoise(&mut image, guides)?;
    super::render::stop_if_cancelled(cancel)?;
    Ok((image, report))
}
