//! The rendered image (linear RGBA f32, premultiplied alpha) and how it is written.
//!
//! `.png` is 8-bit sRGB (the piecewise IEC 61966-2-1 curve) with straight alpha; `.exr` is linear
//! float RGBA (premultiplied, the OpenEXR convention); `.hdr` is linear RGB over black. Every
//! write goes to a temporary file in the destination folder that is renamed into place, so a
//! failed or interrupted write never leaves a partial file or clobbers an existing one.
//!
//! Every file a render writes is here, written the same way: the image ([`PendingOutput`]),
//! the AOVs ([`aov`], as [`npy`], EXR or PNG), the view file ([`view_file`]), a NeRF-style
//! `transforms.json` ([`dataset`]), turntable GIFs ([`turntable`]), contact sheets ([`sheet`],
//! drawn with [`raster`]) and the terminal preview ([`preview`]).

pub mod aov;
pub mod dataset;
pub mod denoise_input;
pub mod npy;
pub mod preview;
pub mod raster;
pub mod sheet;
pub mod turntable;
pub mod view_file;

use crate::color::{linear_to_srgb, ViewTransform};
pub use crate::render::film::Image;
use glam::{Vec3, Vec4};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Output file formats, chosen by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputFormat {
    /// 8-bit sRGB PNG with alpha.
    Png,
    /// 8-bit sRGB baseline JPEG (quality [`JPEG_QUALITY`]), without alpha: uncovered pixels
    /// over the background, black without one.
    Jpeg,
    /// Linear float OpenEXR.
    Exr,
    /// Linear Radiance RGBE.
    Hdr,
}

/// Why an image could not be written.
#[derive(Debug, thiserror::Error)]
pub enum SaveError {
    /// The extension is not one we write.
    #[error("{}: unknown output format (use .png, .jpg, .exr or .hdr)", .0.display())]
    UnknownFormat(PathBuf),
    /// The destination folder cannot take a file.
    #[error("{}: cannot write here: {error}", path.display())]
    Unwritable {
        /// The output path.
        path: PathBuf,
        /// The underlying error: part of the message, not a source, so that a printed chain
        /// (`{:#}`) says it once.
        error: std::io::Error,
    },
    /// The file exists and clobbering was refused.
    #[error("{}: already exists (--no-clobber)", .0.display())]
    Exists(PathBuf),
    /// Two options name one file: the second would replace the first.
    #[error("{}: named by both {first} and {second}: give each output its own file", path.display())]
    Twice {
        /// The output path, as the second option gives it.
        path: PathBuf,
        /// The option that names it first.
        first: String,
        /// The option that names it again.
        second: String,
    },
    /// An output is a file the run reads.
    #[error("{}: {option} would overwrite {input}: write it elsewhere", path.display())]
    Overwrites {
        /// The output path.
        path: PathBuf,
        /// The option that names the output.
        option: String,
        /// What the file is to the run ("the model this run renders", "the --env panorama").
        input: String,
    },
    /// Encoding failed.
    #[error("{}: encoding failed: {error}", path.display())]
    Encode {
        /// The output path.
        path: PathBuf,
        /// The encoder's error.
        error: image::ImageError,
    },
}

impl OutputFormat {
    /// The format for a path's extension.
    pub fn from_path(path: &Path) -> Result<OutputFormat, SaveError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("png") => Ok(OutputFormat::Png),
            Some("jpg" | "jpeg") => Ok(OutputFormat::Jpeg),
            Some("exr") => Ok(OutputFormat::Exr),
            Some("hdr") => Ok(OutputFormat::Hdr),
            _ => Err(SaveError::UnknownFormat(path.to_path_buf())),
        }
    }
}

/// JPEG quality of rendered images (the `image` crate's baseline encoder, no chroma
/// subsampling): the bundled box's default render is a sixth of its PNG's size and 0.6/255
/// from it on average.
pub const JPEG_QUALITY: u8 = 92;

/// Quantises [0, 1] to 8 bits, clamping (never wrapping) out-of-range and NaN values.
fn to_u8(c: f32) -> u8 {
    // NaN.clamp gives NaN, and `as u8` turns NaN into 0.
    (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// An output file reserved before rendering: the temporary file is created in the destination
/// folder up front, so an unwritable destination fails before any work, and the finished image
/// is renamed over the destination in one step.
pub struct PendingOutput {
    format: OutputFormat,
    file: PendingFile,
}

/// Any output file reserved before the work that fills it (an image, a GIF, a contact sheet):
/// a temporary file in the destination folder, renamed over the destination by
/// [`PendingFile::commit`]. Dropped without a commit, it leaves nothing behind.
pub struct PendingFile {
    path: PathBuf,
    file: tempfile::NamedTempFile,
    no_clobber: bool,
}

impl PendingFile {
    /// Reserves a temporary file beside `path`: fails now if the folder cannot take a file,
    /// `path` is a folder, or it exists under `no_clobber`.
    pub fn reserve(path: &Path, no_clobber: bool) -> Result<PendingFile, SaveError> {
        if no_clobber && path.exists() {
            return Err(SaveError::Exists(path.to_path_buf()));
        }
        if path.is_dir() {
            return Err(SaveError::Unwritable {
                path: path.to_path_buf(),
                error: std::io::Error::other("is a directory"),
            });
        }
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let file = temporary_beside(&dir).map_err(|e| SaveError::Unwritable {
            path: path.to_path_buf(),
            // tempfile's message names its temporary file, which the user never asked for.
            error: if dir.is_dir() {
                std::io::Error::new(e.kind(), e.kind().to_string())
            } else {
                std::io::Error::new(e.kind(), format!("no folder {}", dir.display()))
            },
        })?;
        Ok(PendingFile {
            path: path.to_path_buf(),
            file,
            no_clobber,
        })
    }

    /// The destination path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The temporary file, to write the content into.
    pub fn file(&self) -> &std::fs::File {
        self.file.as_file()
    }

    /// An error about this output's destination.
    pub fn unwritable(&self, source: std::io::Error) -> SaveError {
        SaveError::Unwritable {
            path: self.path.clone(),
            error: source,
        }
    }

    /// Flushes the temporary file to disk and renames it over the destination.
    pub fn commit(self) -> Result<(), SaveError> {
        self.file().sync_all().map_err(|e| self.unwritable(e))?;
        let result = if self.no_clobber {
            self.file.persist_noclobber(&self.path)
        } else {
            self.file.persist(&self.path)
        };
        result.map_err(|e| SaveError::Unwritable {
            path: self.path,
            error: e.error,
        })?;
        Ok(())
    }
}

impl PendingOutput {
    /// Checks the extension and reserves a temporary file beside `path`.
    pub fn reserve(path: &Path, no_clobber: bool) -> Result<PendingOutput, SaveError> {
        let format = OutputFormat::from_path(path)?;
        let file = PendingFile::reserve(path, no_clobber)?;
        Ok(PendingOutput { format, file })
    }

    /// The destination path.
    pub fn path(&self) -> &Path {
        self.file.path()
    }

    /// Encodes `image`, flushes it to disk and renames it over the destination. `background`
    /// fills uncovered pixels (PNG and HDR) instead of leaving them transparent.
    pub fn commit(
        self,
        image: &Image,
        background: Option<Vec3>,
        view: ViewTransform,
    ) -> Result<(), SaveError> {
        let path = self.path().to_path_buf();
        {
            let mut out = BufWriter::new(self.file.file());
            encode_into(&mut out, &path, self.format, image, background, view)?;
            out.flush()
                .map_err(|error| SaveError::Unwritable { path, error })?;
        }
        self.file.commit()
    }
}

/// `image` encoded for `path`'s format ([`OutputFormat::from_path`]) as a render writes it
/// ([`PendingOutput::commit`]): for a caller that writes several files only once all are
/// encoded (`merge`).
pub fn encode_image(
    path: &Path,
    image: &Image,
    background: Option<Vec3>,
    view: ViewTransform,
) -> Result<Vec<u8>, SaveError> {
    let format = OutputFormat::from_path(path)?;
    let mut bytes = Vec::new();
    encode_into(&mut bytes, path, format, image, background, view)?;
    Ok(bytes)
}

/// Encodes `image` as `format` into `out`; `path` names the output in errors.
fn encode_into(
    mut out: impl Write,
    path: &Path,
    format: OutputFormat,
    image: &Image,
    background: Option<Vec3>,
    view: ViewTransform,
) -> Result<(), SaveError> {
    let io_err = |source: std::io::Error| SaveError::Unwritable {
        path: path.to_path_buf(),
        error: source,
    };
    let enc_err = |source: image::ImageError| SaveError::Encode {
        path: path.to_path_buf(),
        error: source,
    };
    let (w, h) = (image.width, image.height);
    match format {
        OutputFormat::Png => {
            let bytes = image.to_srgb8(background, view);
            image::ImageEncoder::write_image(
                image::codecs::png::PngEncoder::new(&mut out),
                &bytes,
                w,
                h,
                image::ExtendedColorType::Rgba8,
            )
            .map_err(enc_err)?;
        }
        OutputFormat::Jpeg => {
            // JPEG has no alpha: composited over the background (black without one),
            // then the opaque alpha dropped.
            let rgba = image.to_srgb8(Some(background.unwrap_or(Vec3::ZERO)), view);
            let rgb: Vec<u8> = rgba
                .chunks_exact(4)
                .flat_map(|p| [p[0], p[1], p[2]])
                .collect();
            image::ImageEncoder::write_image(
                image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, JPEG_QUALITY),
                &rgb,
                w,
                h,
                image::ExtendedColorType::Rgb8,
            )
            .map_err(enc_err)?;
        }
        OutputFormat::Exr => {
            let floats: Vec<f32> = image
                .pixels
                .iter()
                .flat_map(|p| composite(*p, background).to_array())
                .collect();
            let bytes = exr_rgba(w, h, &floats).map_err(|e| SaveError::Encode {
                path: path.to_path_buf(),
                error: image::ImageError::Encoding(image::error::EncodingError::new(
                    image::ImageFormat::OpenExr.into(),
                    e,
                )),
            })?;
            out.write_all(&bytes).map_err(io_err)?;
        }
        OutputFormat::Hdr => {
            let rgb: Vec<image::Rgb<f32>> = image
                .pixels
                .iter()
                .map(|p| image::Rgb(composite(*p, background).truncate().to_array()))
                .collect();
            image::codecs::hdr::HdrEncoder::new(&mut out)
                .encode(&rgb, w as usize, h as usize)
                .map_err(enc_err)?;
        }
    }
    Ok(())
}

/// A file a run writes or reads, with what names it: an option (`-o`, `--depth-out`) for an
/// output, a description ("the model") for an input.
pub type NamedPath<'a> = (&'a str, &'a Path);

/// Refuses, before any work, outputs that could not be written whole or that would destroy
/// something: two outputs that are one file ([`SaveError::Twice`]), an output that is one of
/// the run's `inputs` ([`SaveError::Overwrites`]), and, as [`PendingFile::reserve`] does, an
/// existing output under `no_clobber`, an output that is a folder, or one whose folder is
/// missing or cannot take a file. Nothing is left behind.
pub fn check_destinations(
    outputs: &[NamedPath],
    inputs: &[NamedPath],
    no_clobber: bool,
) -> Result<(), SaveError> {
    check_not_inputs(outputs, inputs)?;
    for (i, &(second, path)) in outputs.iter().enumerate() {
        if let Some(&(first, _)) = outputs[..i].iter().find(|(_, p)| same_file(p, path)) {
            return Err(SaveError::Twice {
                path: path.to_path_buf(),
                first: first.to_string(),
                second: second.to_string(),
            });
        }
    }
    for &(_, path) in outputs {
        // Reserved and dropped: the temporary file is removed at once.
        drop(PendingFile::reserve(path, no_clobber)?);
    }
    Ok(())
}

/// Refuses an output that is one of `inputs` (see [`check_destinations`]); for inputs known
/// only once the model is loaded, its buffers, textures and `.mtl`.
pub fn check_not_inputs(outputs: &[NamedPath], inputs: &[NamedPath]) -> Result<(), SaveError> {
    for &(option, path) in outputs {
        let target = entry(path);
        // An output replaces its folder's entry (a rename): the input's own entry, or the
        // file a symbolic link of the input leads to.
        let is_input = |input: &Path| {
            entry(input) == target || input.canonicalize().is_ok_and(|c| c == target)
        };
        if let Some(&(input, _)) = inputs.iter().find(|(_, p)| is_input(p)) {
            return Err(SaveError::Overwrites {
                path: path.to_path_buf(),
                option: option.to_string(),
                input: input.to_string(),
            });
        }
    }
    Ok(())
}

/// Whether two outputs are one file: the same entry of the same folder once the folder is
/// resolved (`out.png`, `./out.png` and `sub/../out.png` are one). An output is written by a
/// rename over its entry, so two links to one file are two outputs.
pub fn same_file(a: &Path, b: &Path) -> bool {
    entry(a) == entry(b)
}

/// The folder entry `path` names: its folder made canonical where it exists, then its name
/// (not followed if it is a symbolic link).
fn entry(path: &Path) -> PathBuf {
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    match (folder.canonicalize(), path.file_name()) {
        (Ok(folder), Some(name)) => folder.join(name),
        _ => path.canonicalize().unwrap_or_else(|_| path.to_path_buf()),
    }
}

/// A temporary file in `dir`, renamed over the output once complete. It is created with the
/// permissions any new file gets (0666 less the umask: 0644 usually), not tempfile's private
/// 0600, since it becomes the user's output (an image served or shared must be readable).
fn temporary_beside(dir: &Path) -> std::io::Result<tempfile::NamedTempFile> {
    let mut builder = tempfile::Builder::new();
    builder.prefix(".meshtracer-").suffix(".partial");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    builder.tempfile_in(dir)
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename, so the
/// destination is either untouched or complete.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), SaveError> {
    let pending = PendingFile::reserve(path, false)?;
    pending
        .file()
        .write_all(bytes)
        .map_err(|e| pending.unwritable(e))?;
    pending.commit()
}

/// A premultiplied pixel over an optional opaque background.
fn composite(p: Vec4, background: Option<Vec3>) -> Vec4 {
    match background {
        Some(bg) => (p.truncate() + bg * (1.0 - p.w)).extend(1.0),
        None => p,
    }
}

/// An RGBA float image (`rgba`: 4 floats a pixel, rows top to bottom) as OpenEXR bytes: 32-bit
/// float channels, RLE-compressed scan lines, as the image crate writes them, but with the
/// scan-line blocks in increasing order. exr's parallel compressor otherwise writes blocks in
/// the order they finish (`LineOrder::Unspecified`), so the same image gave different bytes
/// from run to run, and hashes and byte-for-byte comparisons of outputs failed at random.
pub(crate) fn exr_rgba(
    width: u32,
    height: u32,
    rgba: &[f32],
) -> Result<Vec<u8>, exr::error::Error> {
    use exr::prelude::{
        Blocks, Compression, Encoding, Image, LineOrder, SpecificChannels, Vec2, WritableImage,
    };
    let w = width as usize;
    if rgba.len() != w * height as usize * 4 {
        return Err(exr::error::Error::Invalid(
            "pixel count differs from the size".into(),
        ));
    }
    let encoding = Encoding {
        compression: Compression::RLE,
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let channels = SpecificChannels::rgba(|Vec2(x, y): Vec2<usize>| {
        let i = (y * w + x) * 4;
        (rgba[i], rgba[i + 1], rgba[i + 2], rgba[i + 3])
    });
    let mut bytes = Vec::new();
    Image::from_encoded_channels((w, height as usize), encoding, channels)
        .write()
        .to_buffered(std::io::Cursor::new(&mut bytes))?;
    Ok(bytes)
}

impl Image {
    /// 8-bit sRGB RGBA with straight alpha: colour is un-premultiplied and passed through the
    /// view transform `view` before encoding, or composited over `background` (then alpha is
    /// 255). The background is a display colour: it is blended after the view transform, so
    /// `--background 1,1,1` stays white under every transform. (With
    /// [`ViewTransform::Standard`], a clip, the pixel is composited in linear light first,
    /// as before view transforms existed: the bytes are the same.)
    pub fn to_srgb8(&self, background: Option<Vec3>, view: ViewTransform) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.pixels.len() * 4);
        for &p in &self.pixels {
            let (rgb, alpha) = if view == ViewTransform::Standard {
                let p = composite(p, background);
                let rgb = if p.w > 0.0 {
                    p.truncate() / p.w
                } else {
                    Vec3::ZERO
                };
                (rgb.clamp(Vec3::ZERO, Vec3::ONE), p.w)
            } else {
                let straight = if p.w > 0.0 {
                    view.apply(p.truncate() / p.w)
                } else {
                    Vec3::ZERO
                };
                match background {
                    Some(bg) => (straight * p.w + bg * (1.0 - p.w), 1.0),
                    None => (straight, p.w),
                }
            };
            out.extend(
                rgb.to_array()
                    .map(|c| to_u8(linear_to_srgb(c.clamp(0.0, 1.0)))),
            );
            out.push(to_u8(alpha));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An output is refused where its rename would replace an input's entry or the file an
    /// input's link leads to, and allowed where it replaces only a link to the input.
    #[cfg(unix)]
    #[test]
    fn an_output_is_an_input_when_writing_it_would_replace_the_input() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let model = d.join("m.gltf");
        std::fs::write(&model, b"{}").unwrap();
        std::os::unix::fs::symlink(&model, d.join("link.gltf")).unwrap();
        let inputs = |p: &Path| check_not_inputs(&[("-o", p)], &[("the model", &model)]).is_err();
        assert!(inputs(&model));
        assert!(inputs(&d.join(".").join("m.gltf")));
        assert!(
            !inputs(&d.join("link.gltf")),
            "the rename replaces the link, not the model"
        );
        let via_link = check_not_inputs(
            &[("-o", model.as_path())],
            &[("the model", &d.join("link.gltf"))],
        );
        assert!(via_link.is_err(), "the link's file would be replaced");
        std::fs::create_dir(d.join("sub")).unwrap();
        assert!(same_file(&d.join("new.png"), &d.join("sub/../new.png")));
        assert!(!same_file(&d.join("a.png"), &d.join("b.png")));
        // Nothing is left behind by a check that passes.
        let out = d.join("out.png");
        check_destinations(&[("-o", out.as_path())], &[("the model", &model)], true).unwrap();
        assert_eq!(
            std::fs::read_dir(d).unwrap().count(),
            3,
            "m.gltf, link.gltf, sub"
        );
    }

    /// An EXR is the same bytes every time (many scan-line blocks, compressed in parallel) and
    /// reads back to exactly the floats written; a wrong pixel count is an error.
    #[test]
    fn exr_bytes_are_deterministic_and_exact() {
        let (w, h) = (37u32, 301u32);
        let rgba: Vec<f32> = (0..w * h * 4)
            .map(|i| (i as f32 * 0.37).sin() * 1e3 + if i % 7 == 0 { 0.0 } else { 1.0 })
            .collect();
        let first = exr_rgba(w, h, &rgba).unwrap();
        for _ in 0..5 {
            assert_eq!(exr_rgba(w, h, &rgba).unwrap(), first);
        }
        let back = image::load_from_memory_with_format(&first, image::ImageFormat::OpenExr)
            .unwrap()
            .into_rgba32f();
        assert_eq!((back.width(), back.height()), (w, h));
        assert_eq!(back.as_raw(), &rgba);
        assert!(exr_rgba(w, h + 1, &rgba).is_err());
    }

    #[cfg(unix)]
    #[test]
    fn outputs_get_the_permissions_of_any_new_file() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("plain");
        std::fs::write(&plain, b"x").unwrap();
        let ours = dir.path().join("ours.png");
        write_atomic(&ours, b"x").unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&ours), mode(&plain), "umask applies as to any file");
    }

    #[test]
    fn srgb_round_trips_and_clamps() {
        use crate::color::srgb_to_linear;
        for i in 0..=255 {
            let c = i as f32 / 255.0;
            assert!((srgb_to_linear(linear_to_srgb(c)) - c).abs() < 1e-5);
        }
        assert_eq!(to_u8(linear_to_srgb(0.5)), 188);
        assert_eq!(to_u8(2.0), 255);
        assert_eq!(to_u8(-1.0), 0);
        assert_eq!(to_u8(f32::NAN), 0);
    }

    #[test]
    fn png_alpha_is_straight_and_background_fills() {
        let mut img = Image::new(2, 1);
        img.pixels[0] = Vec4::new(0.5, 0.5, 0.5, 0.5);
        let bytes = img.to_srgb8(None, ViewTransform::Standard);
        assert_eq!(&bytes[..4], &[255, 255, 255, 128]);
        assert_eq!(&bytes[4..], &[0, 0, 0, 0]);
        let filled = img.to_srgb8(Some(Vec3::ONE), ViewTransform::Standard);
        assert_eq!(&filled[4..], &[255, 255, 255, 255]);
    }

    #[test]
    fn failed_reservation_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        assert!(matches!(
            PendingOutput::reserve(&dir.path().join("x.bmp"), false),
            Err(SaveError::UnknownFormat(_))
        ));
        assert!(PendingOutput::reserve(&dir.path().join("missing/x.png"), false).is_err());
        let pending = PendingOutput::reserve(&dir.path().join("x.png"), false).unwrap();
        drop(pending);
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            0,
            "temp file removed"
        );
    }
}
