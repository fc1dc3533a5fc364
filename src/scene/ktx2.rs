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

/// Checks what the transcoder would allocate by before it does: `KHR_texture_basisu` asks for
/// a 2D image (`pixelDepth` 0, `layerCount` 0, `faceCount` 1), and no level's
/// `uncompressedByteLength` may exceed the base level's size in 4x4 blocks of 16 bytes (what
/// UASTC, the one payload that is Zstandard-inflated to that length, takes). A hostile length
/// made `basisu` allocate it whole (found by fuzzing: 30 GB claimed in a 27 KB file, and the
/// process aborted on the failed allocation, which no panic handler can catch).
fn check_sizes(bytes: &[u8]) -> Result<(), String> {
    let word = |at: usize| {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .ok_or_else(|| "truncated KTX2 header".to_string())
    };
    let (width, height) = (u64::from(word(20)?), u64::from(word(24)?.max(1)));
    let (depth, layers, faces, levels) = (word(28)?, word(32)?, word(36)?, word(40)?);
    if depth > 1 || layers > 1 || faces != 1 {
        return Err(format!(
            "a {depth}-deep KTX2 image of {layers} layers and {faces} faces: KHR_texture_basisu \
             takes 2D images only"
        ));
    }
    let base_bytes = width.div_ceil(4) * height.div_ceil(4) * 16;
    // The level index follows the 80-byte header: byteOffset, byteLength and
    // uncompressedByteLength, 8 bytes each, for every level.
    for level in 0..u64::from(levels.max(1)) {
        let at = usize::try_from(80 + level * 24 + 16).map_err(|_| "too many levels")?;
        let field = bytes
            .get(at..at + 8)
            .ok_or_else(|| "truncated KTX2 level index".to_string())?;
        let mut le = [0u8; 8];
        le.copy_from_slice(field);
        let uncompressed = u64::from_le_bytes(le);
        if uncompressed > base_bytes {
            return Err(format!(
                "KTX2 level {level} claims {uncompressed} bytes uncompressed, more than a \
                 {width}x{height} image takes ({base_bytes})"
            ));
        }
    }
    Ok(())
}

/// Transcodes a Basis Universal KTX2 file's base level to RGBA8.
pub(crate) fn decode(bytes: &[u8]) -> Result<image::RgbaImage, String> {
    use basisu::{DecodeFlags, TargetFormat, Transcoder};
    check_sizes(bytes)?;
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

    /// A 256x256 UASTC level takes 64x64 blocks of 16 bytes: 65,536. Claiming more than that
    /// uncompressed (the fuzzer's 30 GB), or layers, faces or depth, is refused before the
    /// transcoder allocates anything.
    #[test]
    fn level_sizes_are_bounded_before_transcoding() {
        let ktx2 = |layers: u32, uncompressed: u64| {
            let mut b = IDENTIFIER.to_vec();
            // vkFormat, typeSize, width, height, depth, layers, faces, levels, Zstandard.
            for w in [0u32, 1, 256, 256, 0, layers, 1, 1, 2] {
                b.extend(w.to_le_bytes());
            }
            b.extend([0u8; 32]);
            for d in [112u64, 16, uncompressed] {
                b.extend(d.to_le_bytes());
            }
            b.extend([0u8; 16]);
            b
        };
        assert_eq!(check_sizes(&ktx2(0, 65_536)), Ok(()));
        assert_eq!(
            decode(&ktx2(0, 0x7_0001_0000)).unwrap_err(),
            "KTX2 level 0 claims 30064836608 bytes uncompressed, more than a 256x256 image \
             takes (65536)"
        );
        assert!(decode(&ktx2(6, 65_536))
            .unwrap_err()
            .contains("KHR_texture_basisu takes 2D images only"));
        assert!(decode(&ktx2(0, 65_536)[..100])
            .unwrap_err()
            .contains("truncated KTX2 level index"));
    }
}
