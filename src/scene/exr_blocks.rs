//! OpenEXR input (panoramas for `--env`, the images `compare` and `merge` read) decoded on the
//! calling thread, after its DWA blocks' claims are checked against their pixels.

/// Checks an OpenEXR file's DWA blocks before anything decodes it. The `exr` crate's DWA
/// decoder (behind the image crate's too) sizes each section of a block by the counters at the block's
/// start (eleven little-endian u64: version, the sections' sizes, the coefficient counts, the
/// AC coder) and allocates that much before inflating: a hostile file claimed 52 PB, and the
/// process aborted on the failed allocation (found by fuzzing). Each DWA block's counters are
/// checked against its pixels first: 16 times the block's uncompressed size, plus 64 KiB,
/// bounds what its sections can hold even with the DCT's padding to 8x8 (a file of real DWA
/// blocks is far inside it). A block stored raw (exactly its uncompressed size: compression
/// did not help) has no counters.
///
/// It also holds every layer's display and data windows to `max_texels`, before anything is
/// allocated for them (the image crate's reader held them to its 512 MiB allocation limit).
fn check_exr_blocks(
    read: impl std::io::Read + std::io::Seek,
    max_texels: usize,
) -> Result<(), String> {
    use exr::block::chunk::CompressedBlock;
    use exr::compression::Compression;
    let unreadable = |e: exr::error::Error| format!("not a readable OpenEXR file: {e}");
    let reader = exr::block::read(read, false).map_err(unreadable)?;
    for header in reader.headers() {
        for (what, size) in [
            (
                "display window",
                header.shared_attributes.display_window.size,
            ),
            ("data window", header.layer_size),
        ] {
            if size.width().saturating_mul(size.height()) > max_texels {
                return Err(format!(
                    "its {what} is {}x{} texels, more than the {max_texels} this reads",
                    size.width(),
                    size.height()
                ));
            }
        }
    }
    let dwa = |h: &exr::meta::header::Header| {
        matches!(h.compression, Compression::DWAA(_) | Compression::DWAB(_))
    };
    if !reader.headers().iter().any(dwa) {
        return Ok(());
    }
    let headers = reader.headers().to_vec();
    for chunk in reader.all_chunks(false).map_err(unreadable)? {
        let chunk = chunk.map_err(unreadable)?;
        let Some(header) = headers.get(chunk.layer_index).filter(|h| dwa(h)) else {
            continue;
        };
        let pixels = header
            .get_block_data_indices(&chunk.compressed_block)
            .and_then(|indices| header.get_absolute_block_pixel_coordinates(indices))
            .map_err(unreadable)?;
        let raw =
            (header.channels.bytes_per_pixel as u64).saturating_mul(pixels.size.area() as u64);
        let bytes = match &chunk.compressed_block {
            CompressedBlock::ScanLine(b) => &b.compressed_pixels_le,
            CompressedBlock::Tile(t) => &t.compressed_pixels_le,
            _ => continue,
        };
        if bytes.len() as u64 == raw {
            continue;
        }
        let bound = raw.saturating_mul(16).saturating_add(1 << 16);
        // Counters 1 to 9: the sections' sizes and the coefficient counts.
        for counter in bytes.chunks_exact(8).take(10).skip(1) {
            let mut le = [0u8; 8];
            le.copy_from_slice(counter);
            let claimed = u64::from_le_bytes(le);
            if claimed > bound {
                return Err(format!(
                    "a DWA block of {}x{} texels claims a section of {claimed}, more than \
                     such a block can hold ({bound})",
                    pixels.size.width(),
                    pixels.size.height()
                ));
            }
        }
    }
    Ok(())
}

/// `read` after [`check_exr_blocks`] passed it, from its start again, for a decoder.
fn checked<R: std::io::Read + std::io::Seek>(
    mut read: R,
    max_texels: usize,
) -> Result<std::io::BufReader<R>, String> {
    check_exr_blocks(&mut read, max_texels)?;
    read.seek(std::io::SeekFrom::Start(0))
        .map_err(|e| e.to_string())?;
    Ok(std::io::BufReader::new(read))
}

/// The most texels [`decode_exr`] reads for `compare` and `merge`: the image crate's default
/// allocation limit (512 MiB) in RGBA f32, which held them before.
pub const MAX_EXR_TEXELS: usize = 512 << 20 >> 4;

/// Decodes an OpenEXR file's first layer with R, G and B (and A, when it has one), at most
/// `max_texels` in either window, as the
/// image crate does (`Rgba32F` with alpha, else `Rgb32F`, over the display window, black where
/// the data window does not reach), after checking its DWA blocks' counters, and on the
/// calling thread.
/// The image crate's reader hands the blocks to the `exr` crate's parallel decompressor, whose
/// thread pool aborts the process when a decoder panics on a hostile file (found by fuzzing:
/// an overflow in its B44 decoder); here such a panic reaches the caller, where
/// [`super::catch_quietly`] makes it an error.
pub fn decode_exr(
    read: impl std::io::Read + std::io::Seek,
    max_texels: usize,
) -> Result<image::DynamicImage, String> {
    use exr::prelude::{read as read_exr, ReadChannels, ReadLayers};
    let read = checked(read, max_texels)?;
    let image = read_exr()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |size, channels: &exr::image::RgbaChannels| {
                (
                    size.width(),
                    channels.3.is_some(),
                    vec![0.0f32; size.area() * 4],
                )
            },
            |(width, _, texels), at, (r, g, b, a): (f32, f32, f32, f32)| {
                let i = (at.y() * *width + at.x()) * 4;
                texels[i..i + 4].copy_from_slice(&[r, g, b, a]);
            },
        )
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(read)
        .map_err(|e| format!("cannot decode the OpenEXR image: {e}"))?;
    let display = image.attributes.display_window;
    let (width, height) = (display.size.width(), display.size.height());
    let layer = &image.layer_data;
    let (data_width, alpha, data) = &layer.channel_data.pixels;
    let offset = layer.attributes.layer_position - display.position;
    let channels = if *alpha { 4 } else { 3 };
    let mut out = vec![0.0f32; width * height * channels];
    for (i, texel) in data.chunks_exact(4).enumerate() {
        let x = (i % data_width) as i64 + i64::from(offset.x());
        let y = (i / data_width) as i64 + i64::from(offset.y());
        if (0..width as i64).contains(&x) && (0..height as i64).contains(&y) {
            let at = (y as usize * width + x as usize) * channels;
            out[at..at + channels].copy_from_slice(&texel[..channels]);
        }
    }
    let (w, h) = (width as u32, height as u32);
    let too_large = || "the OpenEXR image is too large".to_string();
    Ok(if *alpha {
        image::DynamicImage::ImageRgba32F(
            image::Rgba32FImage::from_raw(w, h, out).ok_or_else(too_large)?,
        )
    } else {
        image::DynamicImage::ImageRgb32F(
            image::Rgb32FImage::from_raw(w, h, out).ok_or_else(too_large)?,
        )
    })
}

/// The float32 channels of an OpenEXR image ([`decode_exr_channels`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ExrChannels {
    /// Columns of the data window.
    pub width: usize,
    /// Rows of the data window.
    pub height: usize,
    /// Each channel's name and its samples, row-major, in the file's order (by name).
    pub channels: Vec<(String, Vec<f32>)>,
}

/// Decodes an OpenEXR file's first layer channel by channel, at most `max_texels`, as
/// [`decode_exr`] does (its DWA blocks' counters checked first, on the calling thread): each
/// channel's name and its samples as f32, row-major over the layer's data window, which must
/// start at the display window's corner. Channels stored as f16 or u32 are refused (a file
/// that holds exact float32 data, as a tile's denoise input does, has none).
pub fn decode_exr_channels(
    read: impl std::io::Read + std::io::Seek,
    max_texels: usize,
) -> Result<ExrChannels, String> {
    use exr::prelude::{read as read_exr, FlatSamples, ReadChannels, ReadLayers};
    let read = checked(read, max_texels)?;
    let image = read_exr()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(read)
        .map_err(|e| format!("cannot decode the OpenEXR image: {e}"))?;
    let layer = image.layer_data;
    if layer.attributes.layer_position != image.attributes.display_window.position {
        return Err("its data window does not start at the display window's corner".into());
    }
    let mut channels = Vec::new();
    for channel in layer.channel_data.list {
        let name = channel.name.to_string();
        match channel.sample_data {
            FlatSamples::F32(samples) => channels.push((name, samples)),
            _ => return Err(format!("channel '{name}' is not 32-bit float")),
        }
    }
    Ok(ExrChannels {
        width: layer.size.width(),
        height: layer.size.height(),
        channels,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An RGBA EXR written by the exr crate decodes to what the image crate's reader gives,
    /// texel for texel, within the texel limit; over it, it is refused naming the window.
    #[test]
    fn decodes_as_the_image_crate_within_the_texel_limit() {
        use exr::prelude::*;
        let channels = SpecificChannels::rgba(|at: Vec2<usize>| {
            let (x, y) = (at.x() as f32, at.y() as f32);
            (x / 64.0, y / 32.0, (x + y).sin(), 0.5)
        });
        let mut bytes = Vec::new();
        Image::from_channels((64, 32), channels)
            .write()
            .to_buffered(std::io::Cursor::new(&mut bytes))
            .expect("writes");
        let ours = decode_exr(std::io::Cursor::new(&bytes), 64 * 32).expect("decodes");
        let theirs = image::load_from_memory_with_format(&bytes, image::ImageFormat::OpenExr)
            .expect("the image crate decodes it");
        assert!(ours == theirs, "the two readers differ");
        let refused = decode_exr(std::io::Cursor::new(&bytes), 64 * 32 - 1).unwrap_err();
        assert_eq!(
            refused,
            "its display window is 64x32 texels, more than the 2047 this reads"
        );
    }
}
