//! `KHR_texture_basisu`: KTX2 images with Basis Universal payloads (ETC1S/BasisLZ and UASTC,
//! plain or Zstandard-supercompressed), transcoded to RGBA8 by the pure-Rust `basisu` crate
//! (a port of the reference transcoder, byte-identical to it).
//!
//! Only the base level of the first layer and face is used (meshtracer builds its own mip
//! levels). The texels are taken as stored: the glTF extension requires the KTX2 transfer
//! function to match the texture's use (sRGB for colour, linear for data), and the material
//! slot decides how they are read, as for PNG and JPEG.

/// The 12-byte identifier every KTX2 file starts with.
const IDENTIFIER: [u8; 12] = [
    0xAB, b'K', b'T', b'X', b' ', b'2', b'0', 0xBB, b'\r', b'\n', 0x1A, b'\n',
];

/// Whether `bytes` start like a KTX2 file.
pub(crate) fn is_ktx2(bytes: &[u8]) -> bool {
    bytes.starts_with(&IDENTIFIER)
}

/// Whether an image source is KTX2: embedded bytes by their identifier, a file by its MIME
/// type or its `.ktx2` extension (its bytes are read only when decoded).
pub(crate) fn is_ktx2_source(source: &super::image_source::ImageSource) -> bool {
    let ktx2_mime = source.mime_type.as_deref() == Some("image/ktx2");
    match source.encoded() {
        super::image_source::Encoded::Bytes(bytes) => is_ktx2(bytes),
        super::image_source::Encoded::File(path) => {
            ktx2_mime
                || path
                    .extension()
                    .is_some_and(|e| e.eq_ignore_ascii_case("ktx2"))
        }
        super::image_source::Encoded::InFile(_) => ktx2_mime,
        super::image_source::Encoded::Missing | super::image_source::Encoded::Pixels(_) => false,
    }
}

/// The base level's size from a KTX2 header (`pixelWidth` and `pixelHeight` at bytes 20 and
/// 24, little-endian), without reading the rest; a height of 0 (a 1-D texture) counts as 1.
pub(crate) fn dimensions(header: &[u8]) -> Result<(u32, u32), String> {
    if !is_ktx2(header) {
        return Err("not a KTX2 file (no KTX2 identifier)".into());
    }
    let word = |at: usize| {
        header
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .ok_or_else(|| "truncated KTX2 header".to_string())
    };
    Ok((word(20)?, word(24)?.max(1)))
}

/// Transcodes a Basis Universal KTX2 file's base level to RGBA8.
pub(crate) fn decode(bytes: &[u8]) -> Result<image::RgbaImage, String> {
    use basisu::{DecodeFlags, TargetFormat, Transcoder};
    let texture =
        Transcoder::new(bytes).map_err(|e| format!("not a Basis Universal KTX2 file ({e:?})"))?;
    let (width, height) = texture.base_dimensions();
    let texels = texture
        .transcode_image(0, 0, 0, TargetFormat::Rgba32, DecodeFlags::NONE)
        .map_err(|e| format!("KTX2 transcoding failed ({e:?})"))?;
    image::RgbaImage::from_raw(width, height.max(1), texels)
        .ok_or_else(|| format!("KTX2 transcoder returned too few texels for {width}x{height}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headers_are_recognised_and_bounded() {
        let mut header = IDENTIFIER.to_vec();
        header.extend([0u8; 8]);
        header.extend(2048u32.to_le_bytes());
        header.extend(1024u32.to_le_bytes());
        assert!(is_ktx2(&header));
        assert_eq!(dimensions(&header), Ok((2048, 1024)));
        assert!(dimensions(&header[..22]).is_err());
        assert!(dimensions(b"\x89PNG\r\n\x1a\n").is_err());
        assert!(decode(&header).is_err());
        assert!(decode(b"").is_err());
    }
}
