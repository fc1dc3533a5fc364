//! An image's header, read before anything decodes the image: what both importers check of
//! every image source (glTF images, OBJ/MTL texture files), so that a file that is not an
//! image, or one whose declared size is over the pixel budget, is known at load time.

use super::dds;
use super::image_source::{Encoded, ImageSource};
use super::ktx2;
use std::path::Path;

/// Bytes of a JPEG read to learn its size. `image`'s JPEG decoder reads the whole file before
/// it parses the header (DamagedHelmet: 3.2 MB read and copied on every load to learn five
/// sizes, a quarter of the plain file's load time), but the frame header comes in the first
/// kilobytes, after the EXIF and ICC segments. One byte more is read so that a file no longer
/// than this is recognised as whole.
const JPEG_HEADER_PREFIX: usize = 64 << 10;

/// A JPEG's size from the first [`JPEG_HEADER_PREFIX`] bytes of a longer file, when they hold
/// all its headers (up to the start of scan). `None` for anything else (not a JPEG, a file that
/// short, headers that run past the prefix, an error): then the whole image is read as before,
/// and its errors are the ones reported.
fn jpeg_dimensions_from_prefix(bytes: &[u8]) -> Option<(u32, u32)> {
    if bytes.len() <= JPEG_HEADER_PREFIX || !bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        return None;
    }
    let head = std::io::Cursor::new(&bytes[..JPEG_HEADER_PREFIX]);
    image::ImageReader::with_format(head, image::ImageFormat::Jpeg)
        .into_dimensions()
        .ok()
}

/// The first [`JPEG_HEADER_PREFIX`] + 1 bytes of a file, or `None` if it cannot be read (the
/// full read that follows reports why).
fn read_prefix(path: &Path) -> Option<Vec<u8>> {
    let mut head = Vec::with_capacity(JPEG_HEADER_PREFIX + 1);
    let file = std::fs::File::open(path).ok()?;
    std::io::Read::read_to_end(
        &mut std::io::Read::take(file, JPEG_HEADER_PREFIX as u64 + 1),
        &mut head,
    )
    .ok()?;
    Some(head)
}

/// Reads only an image's header: refuses one that is not an image, or whose declared size is
/// over the pixel budget, before anything decodes it.
pub(crate) fn check_image_header(source: &ImageSource, max_pixels: u64) -> Result<(), String> {
    // The size of an image whose encoded bytes (or, for a JPEG, a prefix of them) are here.
    let dims_in = |bytes: &[u8]| -> Result<Result<(u32, u32), image::ImageError>, String> {
        if ktx2::is_ktx2(bytes) {
            return Ok(Ok(ktx2::dimensions(bytes)?));
        }
        if dds::is_dds(bytes) {
            return Ok(Ok(dds::dimensions(bytes)?));
        }
        Ok(match jpeg_dimensions_from_prefix(bytes) {
            Some(dims) => Ok(dims),
            None => image::ImageReader::new(std::io::Cursor::new(bytes))
                .with_guessed_format()
                .map_err(|e| e.to_string())?
                .into_dimensions(),
        })
    };
    let dims = match source.encoded() {
        Encoded::Pixels(pixels) => Ok(pixels.dimensions()),
        Encoded::Bytes(bytes) => dims_in(bytes)?,
        Encoded::InFile(part) => {
            // The header from a prefix where that tells the size (KTX2, most JPEGs), else
            // from the whole image, as for bytes in memory.
            let head = part.read(JPEG_HEADER_PREFIX as u64 + 1)?;
            let whole = head.len() as u64 == part.range.end - part.range.start;
            if !whole && ktx2::is_ktx2(&head) {
                Ok(ktx2::dimensions(&head)?)
            } else if !whole && dds::is_dds(&head) {
                Ok(dds::dimensions(&head)?)
            } else if let (false, Some(dims)) = (whole, jpeg_dimensions_from_prefix(&head)) {
                Ok(dims)
            } else if whole {
                dims_in(&head)?
            } else {
                dims_in(&part.read(u64::MAX)?)?
            }
        }
        Encoded::File(path) if ktx2::is_ktx2_source(source) => {
            let mut header = [0u8; 28];
            let read = std::fs::File::open(path)
                .and_then(|mut f| std::io::Read::read(&mut f, &mut header))
                .map_err(|e| format!("'{}': {e}", path.display()))?;
            Ok(ktx2::dimensions(&header[..read])?)
        }
        Encoded::File(path) => {
            let prefix = read_prefix(path);
            if let Some(head) = prefix.as_deref().filter(|p| dds::is_dds(p)) {
                return check_size(dds::dimensions(head)?, max_pixels);
            }
            match prefix.and_then(|p| jpeg_dimensions_from_prefix(&p)) {
                Some(dims) => Ok(dims),
                None => image::ImageReader::open(path)
                    .map_err(|e| format!("'{}': {e}", path.display()))?
                    .with_guessed_format()
                    .map_err(|e| e.to_string())?
                    .into_dimensions(),
            }
        }
        Encoded::Missing => return Err("no data".to_string()),
    };
    let dims = dims
        .map_err(|e| format!("not a readable PNG, JPEG, WebP, KTX2, TGA, BMP or DDS image: {e}"))?;
    check_size(dims, max_pixels)
}

/// Refuses an image of `w` x `h` pixels that is empty or over `max_pixels`.
fn check_size((w, h): (u32, u32), max_pixels: u64) -> Result<(), String> {
    let pixels = w as u64 * h as u64;
    if pixels == 0 || pixels > max_pixels {
        return Err(format!(
            "declares {w}x{h} pixels, outside the limit of 1..={max_pixels} pixels"
        ));
    }
    Ok(())
}
