//! Tiles: one image rendered in parts (`render --tile I/N` or `--crop X,Y,W,H`), possibly on
//! different machines, and joined again (`merge`) into the image a single render gives, byte
//! for byte.
//!
//! Every pixel's samples are keyed by the seed and the pixel's place in the whole image
//! ([`crate::render::render_region`]), so a tile's pixels are the whole render's pixels. A tile
//! writes its image and AOVs at the tile's size, in the formats asked for, and then a sidecar,
//! `OUT.tile.json` beside its image ([`TileFile`]): where the tile belongs, which files it
//! wrote and a fingerprint of everything that decides a pixel's value, so tiles of different
//! renders are not joined. The merge decodes each tile's files ([`Raster`]), pastes them and
//! encodes the whole with the same encoder the render uses, so the bytes match.
//!
//! A denoised render cannot denoise a tile alone (the filter reaches 30 pixels across the
//! tile's edges), so its tiles keep what the denoiser needs instead: the film and guides of
//! the tile, bit for bit ([`crate::output::denoise_input`], listed as the output
//! [`DENOISE_INPUT`] and described by [`TileDenoise`]). The film and guides of a pixel depend
//! on that pixel alone, so the tiles' joined are the whole render's; the merge denoises them
//! and encodes the image as the render does.

use crate::output::view_file::ImageSize;
use crate::render::Region;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The version of the sidecar format.
pub const TILE_FILE_VERSION: u32 = 1;

/// The version of the sidecar of a denoised render's tile ([`TileFile::denoise`]): a
/// meshtracer that cannot merge such tiles refuses it by its version.
pub const DENOISED_TILE_FILE_VERSION: u32 = 2;

/// The output kind of a denoised render's tile that holds the denoiser's input
/// ([`crate::output::denoise_input`]).
pub const DENOISE_INPUT: &str = "denoise";

/// What the name of a tile's denoise input adds to its image's name: `tile-0.png` ->
/// `tile-0.png.denoise.exr`.
pub const DENOISE_INPUT_SUFFIX: &str = ".denoise.exr";

/// What a sidecar's name adds to its image's name: `tile-0.png` -> `tile-0.png.tile.json`.
pub const SIDECAR_SUFFIX: &str = ".tile.json";

/// The outputs a tile can carry, in the order they are merged: the image, then the AOVs.
pub const OUTPUT_KINDS: [&str; 5] = ["image", "depth", "normal", "mask", "segmentation"];

/// Why tiles could not be cut or joined.
#[derive(Debug, thiserror::Error)]
pub enum TileError {
    /// A `--tile` or `--crop` value that does not describe a part of the image.
    #[error("{0}")]
    Spec(String),
    /// A sidecar that cannot be read or is not one.
    #[error("{}: {message}", path.display())]
    Sidecar {
        /// The sidecar.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A tile's output file that cannot be read or does not fit its tile.
    #[error("{}: {message}", path.display())]
    Output {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Tiles that do not belong to one image, or do not cover it exactly once.
    #[error("{0}")]
    Mismatch(String),
}

/// Tile `index` of `count` (0-based, as Slurm array and Kubernetes Indexed Job indices are):
/// the image cut into `count` bands of whole rows, as even as they can be.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TileIndex {
    /// Which band, 0 to `count - 1`.
    pub index: u32,
    /// How many bands.
    pub count: u32,
}

impl TileIndex {
    /// Parses `I/N`.
    pub fn parse(text: &str) -> Result<TileIndex, TileError> {
        let bad = |why: &str| TileError::Spec(why.to_string());
        let (i, n) = text
            .split_once('/')
            .ok_or_else(|| bad("expected I/N, e.g. 0/4 (tile I of N, counted from 0)"))?;
        let index: u32 = i.trim().parse().map_err(|_| bad("I is not a number"))?;
        let count: u32 = n.trim().parse().map_err(|_| bad("N is not a number"))?;
        if count == 0 {
            return Err(bad("N must be at least 1"));
        }
        if index >= count {
            return Err(bad(&format!(
                "I must be between 0 and {} (tiles are counted from 0)",
                count - 1
            )));
        }
        Ok(TileIndex { index, count })
    }

    /// The rows of a `width` x `height` image this tile covers: band `index` of `count`,
    /// rows `index * height / count` up to `(index + 1) * height / count`.
    pub fn region(&self, width: u32, height: u32) -> Result<Region, TileError> {
        if self.count > height {
            return Err(TileError::Spec(format!(
                "--tile {}/{}: the image has only {height} rows, fewer than the {} tiles",
                self.index, self.count, self.count
            )));
        }
        let row = |i: u32| (u64::from(i) * u64::from(height) / u64::from(self.count)) as u32;
        let (top, bottom) = (row(self.index), row(self.index + 1));
        Ok(Region {
            x: 0,
            y: top,
            width,
            height: bottom - top,
        })
    }
}

/// Parses `--crop X,Y,W,H` (pixels, from the top-left corner).
pub fn parse_crop(text: &str) -> Result<Region, TileError> {
    let numbers: Vec<Option<u32>> = text.split(',').map(|p| p.trim().parse().ok()).collect();
    match numbers.as_slice() {
        [Some(x), Some(y), Some(width), Some(height)] if *width > 0 && *height > 0 => Ok(Region {
            x: *x,
            y: *y,
            width: *width,
            height: *height,
        }),
        _ => Err(TileError::Spec(
            "expected X,Y,W,H in whole pixels with W and H at least 1".into(),
        )),
    }
}

/// Checks that a crop lies inside the image.
pub fn check_crop(crop: Region, width: u32, height: u32) -> Result<Region, TileError> {
    if crop.fits(width, height) {
        Ok(crop)
    } else {
        Err(TileError::Spec(format!(
            "--crop {},{},{},{}: does not fit the {width}x{height} image",
            crop.x, crop.y, crop.width, crop.height
        )))
    }
}

/// The sidecar of a tile, `OUT.tile.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TileFile {
    /// Format version, [`TILE_FILE_VERSION`].
    pub meshtracer_tile: u32,
    /// The whole image.
    pub image: ImageSize,
    /// The part this tile covers.
    pub region: Region,
    /// `--tile I/N`, if the tile was cut that way (`None` for `--crop`).
    pub tile: Option<TileIndex>,
    /// Fingerprint of the render ([`fingerprint`]): tiles join only when theirs agree.
    pub render: String,
    /// The files the tile wrote, by kind ([`OUTPUT_KINDS`], and [`DENOISE_INPUT`] for a
    /// denoised render's tile); relative paths are relative to the sidecar's folder.
    pub outputs: BTreeMap<String, PathBuf>,
    /// For a tile of a denoised render: how the merge denoises and encodes the whole image.
    /// Absent otherwise (and in every sidecar of version [`TILE_FILE_VERSION`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub denoise: Option<TileDenoise>,
}

/// What the merge of a denoised render's tiles needs besides their films and guides: the
/// counts the denoiser weighs them by and how the render encodes the denoised image.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TileDenoise {
    /// SHA-256 of the tile's denoise input file as written: a file replaced since is refused.
    pub sha256: String,
    /// The fewest samples a pixel of the render took ([`crate::render::Image::samples`]).
    pub samples: u32,
    /// Guide rays per pixel ([`crate::render::denoise::Guides::samples_per_pixel`]).
    pub guide_samples: u32,
    /// `--background`: the linear colour uncovered pixels are filled with, if any.
    pub background: Option<[f32; 3]>,
    /// `--tonemap`, by its name ([`crate::color::ViewTransform::name`]).
    pub tonemap: String,
    /// The filter the build that rendered the tile runs ([`crate::render::denoise::Denoiser::id`]):
    /// the merge runs its own build's, and says so when they differ.
    pub denoiser: String,
}

impl TileDenoise {
    /// Its view transform; an unknown name is refused.
    pub fn view_transform(&self) -> Result<crate::color::ViewTransform, String> {
        crate::color::ViewTransform::from_name(&self.tonemap)
            .ok_or_else(|| format!("unknown tonemap '{}'", self.tonemap))
    }

    /// What every tile of one render agrees on: all but the file's digest and the build's
    /// filter (tiles of builds with different filters hold the same film and guides).
    fn shared(&self) -> TileDenoise {
        TileDenoise {
            sha256: String::new(),
            denoiser: String::new(),
            ..self.clone()
        }
    }
}

impl TileFile {
    /// The sidecar of the tile whose image is `image` (or `image` itself, if it names one).
    pub fn sidecar_path(image: &Path) -> PathBuf {
        if image.to_string_lossy().ends_with(SIDECAR_SUFFIX) {
            image.to_path_buf()
        } else {
            let mut name = image.as_os_str().to_os_string();
            name.push(SIDECAR_SUFFIX);
            PathBuf::from(name)
        }
    }

    /// Where the tile whose image is `image` keeps its denoise input: `IMAGE.denoise.exr`.
    pub fn denoise_input_path(image: &Path) -> PathBuf {
        let mut name = image.as_os_str().to_os_string();
        name.push(DENOISE_INPUT_SUFFIX);
        PathBuf::from(name)
    }

    /// Reads and checks a sidecar.
    pub fn read(path: &Path) -> Result<TileFile, TileError> {
        let bad = |message: String| TileError::Sidecar {
            path: path.to_path_buf(),
            message,
        };
        let text = std::fs::read_to_string(path).map_err(|e| {
            bad(format!(
                "cannot read the tile's sidecar ({e}); a tile is the image or the .tile.json that `render --tile` or `--crop` wrote"
            ))
        })?;
        let file: TileFile = serde_json::from_str(&text)
            .map_err(|e| bad(format!("not a meshtracer tile sidecar: {e}")))?;
        if ![TILE_FILE_VERSION, DENOISED_TILE_FILE_VERSION].contains(&file.meshtracer_tile) {
            return Err(bad(format!(
                "tile format version {} (this meshtracer reads {TILE_FILE_VERSION} and {DENOISED_TILE_FILE_VERSION})",
                file.meshtracer_tile
            )));
        }
        let denoised = file.meshtracer_tile == DENOISED_TILE_FILE_VERSION;
        if denoised != file.denoise.is_some()
            || denoised != file.outputs.contains_key(DENOISE_INPUT)
        {
            return Err(bad(format!(
                "a sidecar of version {} {} a 'denoise' record and output",
                file.meshtracer_tile,
                if denoised { "needs" } else { "has no" }
            )));
        }
        if let Some(denoise) = &file.denoise {
            denoise.view_transform().map_err(bad)?;
        }
        if !file.region.fits(file.image.width, file.image.height) {
            return Err(bad(format!(
                "region {}x{} at ({}, {}) does not fit the {}x{} image",
                file.region.width,
                file.region.height,
                file.region.x,
                file.region.y,
                file.image.width,
                file.image.height
            )));
        }
        if !file.outputs.contains_key("image") {
            return Err(bad("lists no image".into()));
        }
        if let Some(kind) = file
            .outputs
            .keys()
            .find(|k| !OUTPUT_KINDS.contains(&k.as_str()) && k.as_str() != DENOISE_INPUT)
        {
            return Err(bad(format!("unknown output kind '{kind}'")));
        }
        Ok(file)
    }

    /// Where output `kind` is, resolved against the sidecar's folder.
    pub fn output_path(&self, sidecar: &Path, kind: &str) -> Option<PathBuf> {
        let path = self.outputs.get(kind)?;
        Some(match sidecar.parent() {
            Some(dir) if path.is_relative() => dir.join(path),
            _ => path.clone(),
        })
    }
}

impl TileFile {
    /// The film and guides of a denoised render's tile ([`crate::output::denoise_input`]),
    /// checked against this sidecar (read from `sidecar`): the file's SHA-256, its size, the
    /// guides' channels; the counts set from [`TileDenoise`].
    pub fn read_denoise_input(
        &self,
        sidecar: &Path,
    ) -> Result<(crate::render::Image, crate::render::denoise::Guides), TileError> {
        let not_denoised = || TileError::Sidecar {
            path: sidecar.to_path_buf(),
            message: "lists no denoise input (the tile of a render that was not denoised)".into(),
        };
        let (Some(denoise), Some(path)) = (&self.denoise, self.output_path(sidecar, DENOISE_INPUT))
        else {
            return Err(not_denoised());
        };
        let bad = |message: String| TileError::Output {
            path: path.clone(),
            message,
        };
        let bytes = std::fs::read(&path).map_err(|e| {
            bad(format!(
                "cannot read the tile's denoise input ({e}); a denoised render's tile keeps it beside its image for merge"
            ))
        })?;
        if crate::jobs::batch::sha256_hex(&bytes) != denoise.sha256 {
            return Err(bad(format!(
                "not the denoise input its sidecar {} lists (its SHA-256 differs): replaced after the tile was rendered? Render the tile again",
                sidecar.display()
            )));
        }
        let (mut image, mut guides) =
            crate::output::denoise_input::decode(&bytes, self.region.width, self.region.height)
                .map_err(bad)?;
        image.samples = denoise.samples;
        guides.samples_per_pixel = denoise.guide_samples;
        Ok((image, guides))
    }
}

/// A 64-bit FNV-1a hash of `text`, as 16 hex digits: stable across machines, platforms and
/// versions of Rust (unlike `std`'s hasher), which is what tiles rendered apart need.
pub fn fingerprint(text: &str) -> String {
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for byte in text.bytes() {
        hash ^= u64::from(byte);
        hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{hash:016x}")
}

/// Checks that `tiles` (sidecar path, contents) belong to one image and cover it exactly
/// once; returns the image size.
pub fn check_cover(tiles: &[(PathBuf, TileFile)]) -> Result<ImageSize, TileError> {
    let Some((first_path, first)) = tiles.first() else {
        return Err(TileError::Mismatch("no tiles given".into()));
    };
    for (path, tile) in &tiles[1..] {
        let differ = |what: &str| {
            TileError::Mismatch(format!(
                "{} and {}: different {what}: tiles of different renders cannot be merged",
                first_path.display(),
                path.display()
            ))
        };
        if tile.image != first.image {
            return Err(differ(&format!(
                "image sizes ({}x{} and {}x{})",
                first.image.width, first.image.height, tile.image.width, tile.image.height
            )));
        }
        if tile.render != first.render {
            return Err(differ(
                "render settings (model or a file it refers to, camera, lights, spp, seed, \
                 shading or AOV scale)",
            ));
        }
        let kinds = |t: &TileFile| -> Vec<(String, String)> {
            t.outputs
                .iter()
                .map(|(k, p)| (k.clone(), extension(p)))
                .collect()
        };
        if kinds(tile) != kinds(first) {
            return Err(differ("outputs (kinds or formats)"));
        }
        if tile.denoise.as_ref().map(TileDenoise::shared)
            != first.denoise.as_ref().map(TileDenoise::shared)
        {
            return Err(differ(
                "denoising (samples, guide rays, background or tonemap)",
            ));
        }
    }
    for (i, (path_a, a)) in tiles.iter().enumerate() {
        for (path_b, b) in &tiles[i + 1..] {
            if let Some(both) = a.region.intersection(&b.region) {
                return Err(TileError::Mismatch(format!(
                    "{} and {} overlap (both cover pixel {},{}): give each tile once",
                    path_a.display(),
                    path_b.display(),
                    both.x,
                    both.y
                )));
            }
        }
    }
    let size = first.image;
    let covered: u64 = tiles.iter().map(|(_, t)| t.region.pixels()).sum();
    let whole = u64::from(size.width) * u64::from(size.height);
    if covered != whole {
        // Name the missing tiles when they were cut as I/N, else the first pixel not covered.
        let counts: Vec<Option<u32>> = tiles.iter().map(|(_, t)| t.tile.map(|i| i.count)).collect();
        let missing = match counts.first() {
            Some(Some(n)) if counts.iter().all(|c| *c == Some(*n)) => {
                let have: Vec<u32> = tiles
                    .iter()
                    .filter_map(|(_, t)| t.tile.map(|i| i.index))
                    .collect();
                let absent: Vec<String> = (0..*n)
                    .filter(|i| !have.contains(i))
                    .map(|i| format!("{i}/{n}"))
                    .collect();
                format!("missing tile(s) {}", absent.join(", "))
            }
            _ => {
                let pixel = first_uncovered(tiles.iter().map(|(_, t)| t.region), size)
                    .map_or(String::new(), |(x, y)| format!(", e.g. pixel {x},{y}"));
                format!("some pixels are not covered{pixel}")
            }
        };
        return Err(TileError::Mismatch(format!(
            "the tiles cover {covered} of the {whole} pixels of the {}x{} image: {missing}",
            size.width, size.height
        )));
    }
    Ok(size)
}

/// The first pixel (in row order of candidates) no region covers. An uncovered area's
/// top-left pixel lies on column 0 or a region's right edge, and row 0 or a region's bottom
/// edge, so those candidates suffice.
fn first_uncovered(
    regions: impl Iterator<Item = Region> + Clone,
    size: ImageSize,
) -> Option<(u32, u32)> {
    let xs = std::iter::once(0).chain(regions.clone().map(|r| r.right()));
    let ys: Vec<u32> = std::iter::once(0)
        .chain(regions.clone().map(|r| r.bottom()))
        .collect();
    let mut candidates: Vec<(u32, u32)> = xs
        .flat_map(|x| ys.iter().map(move |&y| (x, y)))
        .filter(|&(x, y)| x < size.width && y < size.height)
        .collect();
    candidates.sort_by_key(|&(x, y)| (y, x));
    candidates.into_iter().find(|&(x, y)| {
        !regions
            .clone()
            .any(|r| x >= r.x && x < r.right() && y >= r.y && y < r.bottom())
    })
}

/// A file's extension, lower case.
pub fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// The decoded contents of one output file, at its own size: what a merge pastes.
#[derive(Clone, Debug)]
pub enum Raster {
    /// A PNG or EXR image, in the layout it was written with (8- or 16-bit, float).
    Image(image::DynamicImage),
    /// A NumPy array of shape (rows, columns, ...) as [`crate::output::aov`] writes it.
    Npy {
        /// The element type, e.g. `<f4`.
        descr: String,
        /// The shape; the first two are rows and columns.
        shape: Vec<usize>,
        /// Little-endian elements, row-major.
        data: Vec<u8>,
    },
}

impl Raster {
    /// Reads `.png`, `.exr` or `.npy`.
    pub fn read(path: &Path) -> Result<Raster, TileError> {
        let bad = |message: String| TileError::Output {
            path: path.to_path_buf(),
            message,
        };
        let bytes = std::fs::read(path).map_err(|e| bad(format!("cannot read: {e}")))?;
        match extension(path).as_str() {
            "png" | "exr" => {
                let format = if extension(path) == "png" {
                    image::ImageFormat::Png
                } else {
                    image::ImageFormat::OpenExr
                };
                // A panic in a decoder (another crate reading the file) is this file's error;
                // OpenEXR is decoded on this thread for that (scene::decode_exr).
                let decoded = crate::scene::catch_quietly(|| match format {
                    image::ImageFormat::OpenExr => crate::scene::decode_exr(
                        std::io::Cursor::new(&bytes),
                        crate::scene::MAX_EXR_TEXELS,
                    ),
                    _ => image::load_from_memory_with_format(&bytes, format)
                        .map_err(|e| e.to_string()),
                });
                decoded
                    .map_err(|panic| {
                        bad(format!("the decoder failed (an internal error): {panic}"))
                    })?
                    .map(Raster::Image)
                    .map_err(|e| bad(format!("cannot decode: {e}")))
            }
            "npy" => crate::output::npy::decode(&bytes)
                .map(|a| Raster::Npy {
                    descr: a.descr,
                    shape: a.shape,
                    data: a.data,
                })
                .map_err(bad),
            other => Err(bad(format!(
                "tiles in .{other} cannot be merged exactly (use .png, .exr or .npy)"
            ))),
        }
    }

    /// Columns and rows.
    pub fn size(&self) -> (u64, u64) {
        match self {
            Raster::Image(i) => (u64::from(i.width()), u64::from(i.height())),
            Raster::Npy { shape, .. } => (
                shape.get(1).copied().unwrap_or(0) as u64,
                shape.first().copied().unwrap_or(0) as u64,
            ),
        }
    }

    /// The pixel layout, to compare tiles: "Rgba8", "npy <f4 (3)".
    pub fn layout(&self) -> String {
        match self {
            Raster::Image(i) => format!("{:?}", i.color()),
            Raster::Npy { descr, shape, .. } => format!("npy {descr} {:?}", &shape[2..]),
        }
    }

    /// A blank raster of this one's layout at `width` x `height`.
    pub fn blank_like(&self, width: u32, height: u32) -> Raster {
        match self {
            Raster::Image(i) => Raster::Image(image::DynamicImage::new(width, height, i.color())),
            Raster::Npy { descr, shape, .. } => {
                let mut whole = vec![height as usize, width as usize];
                whole.extend(&shape[2..]);
                let bytes = whole.iter().product::<usize>() * crate::output::npy::item_size(descr);
                Raster::Npy {
                    descr: descr.clone(),
                    shape: whole,
                    data: vec![0; bytes],
                }
            }
        }
    }

    /// Copies `tile` (of the same layout, checked by the caller) with its top-left corner at
    /// column `x`, row `y`.
    pub fn paste(&mut self, tile: &Raster, x: u32, y: u32) -> Result<(), TileError> {
        use image::{DynamicImage as D, GenericImage};
        let layout_error = || TileError::Mismatch("tiles of different pixel layouts".into());
        match (self, tile) {
            (Raster::Image(whole), Raster::Image(part)) => {
                let pasted = match (whole, part) {
                    (D::ImageLuma8(w), D::ImageLuma8(p)) => w.copy_from(p, x, y),
                    (D::ImageLuma16(w), D::ImageLuma16(p)) => w.copy_from(p, x, y),
                    (D::ImageRgb8(w), D::ImageRgb8(p)) => w.copy_from(p, x, y),
                    (D::ImageRgba8(w), D::ImageRgba8(p)) => w.copy_from(p, x, y),
                    (D::ImageRgb16(w), D::ImageRgb16(p)) => w.copy_from(p, x, y),
                    (D::ImageRgba16(w), D::ImageRgba16(p)) => w.copy_from(p, x, y),
                    (D::ImageRgb32F(w), D::ImageRgb32F(p)) => w.copy_from(p, x, y),
                    (D::ImageRgba32F(w), D::ImageRgba32F(p)) => w.copy_from(p, x, y),
                    _ => return Err(layout_error()),
                };
                pasted.map_err(|e| TileError::Mismatch(format!("a tile does not fit: {e}")))
            }
            (
                Raster::Npy {
                    descr, shape, data, ..
                },
                Raster::Npy {
                    shape: part_shape,
                    data: part_data,
                    ..
                },
            ) => {
                let pixel =
                    shape[2..].iter().product::<usize>() * crate::output::npy::item_size(descr);
                let (columns, part_rows, part_columns) = (shape[1], part_shape[0], part_shape[1]);
                let row_bytes = part_columns * pixel;
                for row in 0..part_rows {
                    let at = ((y as usize + row) * columns + x as usize) * pixel;
                    data[at..at + row_bytes]
                        .copy_from_slice(&part_data[row * row_bytes..(row + 1) * row_bytes]);
                }
                Ok(())
            }
            _ => Err(layout_error()),
        }
    }

    /// Encodes the raster for `path`'s format, as the render's writers do.
    pub fn encode(&self, path: &Path) -> Result<Vec<u8>, TileError> {
        let bad = |message: String| TileError::Output {
            path: path.to_path_buf(),
            message,
        };
        match self {
            Raster::Image(i) => match extension(path).as_str() {
                "png" => {
                    let mut bytes = Vec::new();
                    i.write_to(
                        &mut std::io::Cursor::new(&mut bytes),
                        image::ImageFormat::Png,
                    )
                    .map_err(|e| bad(format!("encoding failed: {e}")))?;
                    Ok(bytes)
                }
                "exr" => {
                    let rgba = i.to_rgba32f();
                    crate::output::exr_rgba(rgba.width(), rgba.height(), rgba.as_raw())
                        .map_err(|e| bad(format!("encoding failed: {e}")))
                }
                other => Err(bad(format!("cannot write an image as .{other}"))),
            },
            Raster::Npy { descr, shape, data } => {
                Ok(crate::output::npy::encode(descr, shape, data))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bands_cover_the_image_once() {
        for (height, count) in [(32, 4), (33, 4), (7, 7), (100, 3)] {
            let mut next = 0;
            for index in 0..count {
                let r = TileIndex { index, count }.region(48, height).unwrap();
                assert_eq!((r.x, r.width, r.y), (0, 48, next));
                next = r.bottom();
            }
            assert_eq!(next, height);
        }
        assert!(TileIndex { index: 0, count: 9 }.region(8, 8).is_err());
    }

    #[test]
    fn specs_parse_strictly() {
        assert_eq!(
            TileIndex::parse("3/4").unwrap(),
            TileIndex { index: 3, count: 4 }
        );
        for bad in ["4/4", "1/0", "a/4", "1", "-1/4", ""] {
            assert!(TileIndex::parse(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_crop("1, 2,3,4").unwrap().right(), 4);
        for bad in ["1,2,0,4", "1,2,3", "1,2,3,4,5", "a,b,c,d", "-1,0,2,2"] {
            assert!(parse_crop(bad).is_err(), "{bad}");
        }
        assert!(check_crop(parse_crop("40,0,9,1").unwrap(), 48, 32).is_err());
    }

    #[test]
    fn an_npy_tile_is_written_back_as_it_was_read() {
        let data: Vec<u8> = (0..2 * 3 * 3 * 4).map(|i| i as u8).collect();
        let bytes = crate::output::npy::encode("<f4", &[2, 3, 3], &data);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.npy");
        std::fs::write(&path, &bytes).unwrap();
        let raster = Raster::read(&path).unwrap();
        assert_eq!(raster.size(), (3, 2));
        assert_eq!(raster.encode(Path::new("x.npy")).unwrap(), bytes);
    }

    /// A sidecar of version 1 (every sidecar before denoised tiles) reads as before; one of
    /// version 2 needs its denoise record and output, and version 1 may have neither.
    #[test]
    fn sidecar_versions_go_with_the_denoise_record() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.png.tile.json");
        let read = |json: serde_json::Value| {
            std::fs::write(&path, json.to_string()).unwrap();
            TileFile::read(&path)
        };
        let mut json = serde_json::json!({
            "meshtracer_tile": 1,
            "image": {"width": 4, "height": 2},
            "region": {"x": 0, "y": 0, "width": 4, "height": 1},
            "tile": {"index": 0, "count": 2},
            "render": "0123456789abcdef",
            "outputs": {"image": "t.png"}
        });
        assert_eq!(read(json.clone()).unwrap().denoise, None);
        json["meshtracer_tile"] = 2.into();
        assert!(read(json.clone())
            .unwrap_err()
            .to_string()
            .contains("needs"));
        json["outputs"]["denoise"] = "t.png.denoise.exr".into();
        json["denoise"] = serde_json::json!({
            "sha256": "00", "samples": 2, "guide_samples": 2, "background": null,
            "tonemap": "agx", "denoiser": "atrous"
        });
        let file = read(json.clone()).unwrap();
        assert_eq!(file.denoise.unwrap().samples, 2);
        json["meshtracer_tile"] = 1.into();
        assert!(read(json.clone())
            .unwrap_err()
            .to_string()
            .contains("has no"));
        json["meshtracer_tile"] = 3.into();
        assert!(read(json).unwrap_err().to_string().contains("version 3"));
    }

    #[test]
    fn uncovered_pixels_are_found() {
        let size = ImageSize {
            width: 4,
            height: 4,
        };
        let top = Region {
            x: 0,
            y: 0,
            width: 4,
            height: 2,
        };
        let left = Region {
            x: 0,
            y: 2,
            width: 2,
            height: 2,
        };
        assert_eq!(first_uncovered([top, left].into_iter(), size), Some((2, 2)));
        let right = Region { x: 2, ..left };
        assert_eq!(first_uncovered([top, left, right].into_iter(), size), None);
    }
}
