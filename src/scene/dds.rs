//! DirectDraw Surface (DDS) textures: what game assets and their OBJ exports ship (and glTF's
//! `MSFT_texture_dds`), read by `ddsfile` and decoded to RGBA8 by `bcdec_rs` (a pure-Rust port
//! of the `bcdec` block decoders).
//!
//! Read: BC1 (DXT1), BC2 (DXT2/3), BC3 (DXT4/5), BC4 (ATI1), BC5 (ATI2), BC7, and 8-bit RGBA,
//! BGRA and BGR. Only the base level of the first layer is used (meshtracer builds its own mip
//! levels). Rows are stored top row first, as in PNG. The texels are taken as stored: the
//! material slot decides whether they are sRGB, as for PNG and JPEG. BC4 (one channel) becomes
//! grey; BC5 holds a normal map's x and y, so z is rebuilt as sqrt(1 - x² - y²), as the
//! engines that write it read it. BC6H (HDR) and the rest are refused with a message naming
//! the format.

use ddsfile::{D3DFormat, Dds, DxgiFormat};

/// The four bytes every DDS file starts with.
const MAGIC: &[u8; 4] = b"DDS ";

/// Whether `bytes` start like a DDS file.
pub(crate) fn is_dds(bytes: &[u8]) -> bool {
    bytes.starts_with(MAGIC)
}

/// Whether the file at `path` starts like a DDS file (reads its first four bytes).
pub(crate) fn is_dds_file(path: &std::path::Path) -> bool {
    let mut head = [0u8; 4];
    std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head))
        .is_ok_and(|()| is_dds(&head))
}

/// Width and height from a DDS header (the first 20 bytes): height at byte 12, width at 16.
pub(crate) fn dimensions(bytes: &[u8]) -> Result<(u32, u32), String> {
    let word = |at: usize| {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    match (is_dds(bytes), word(16), word(12)) {
        (true, Some(width), Some(height)) => Ok((width, height)),
        _ => Err("truncated DDS header".to_string()),
    }
}

/// How a format's texels are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Layout {
    Bc1,
    Bc2,
    Bc3,
    Bc4,
    Bc5,
    Bc7,
    Rgba8,
    Bgra8,
    Bgrx8,
    Bgr8,
}

impl Layout {
    /// Bytes a 4x4 block takes (block formats), or a texel (the others).
    fn unit_bytes(self) -> usize {
        match self {
            Layout::Bc1 | Layout::Bc4 => 8,
            Layout::Bc2 | Layout::Bc3 | Layout::Bc5 | Layout::Bc7 => 16,
            Layout::Rgba8 | Layout::Bgra8 | Layout::Bgrx8 => 4,
            Layout::Bgr8 => 3,
        }
    }

    fn is_block(self) -> bool {
        !matches!(
            self,
            Layout::Rgba8 | Layout::Bgra8 | Layout::Bgrx8 | Layout::Bgr8
        )
    }
}

/// The layout of a file's format, or a message naming the format.
fn layout(dds: &Dds) -> Result<Layout, String> {
    use DxgiFormat as X;
    if let Some(format) = dds.get_dxgi_format() {
        return match format {
            X::BC1_Typeless | X::BC1_UNorm | X::BC1_UNorm_sRGB => Ok(Layout::Bc1),
            X::BC2_Typeless | X::BC2_UNorm | X::BC2_UNorm_sRGB => Ok(Layout::Bc2),
            X::BC3_Typeless | X::BC3_UNorm | X::BC3_UNorm_sRGB => Ok(Layout::Bc3),
            X::BC4_Typeless | X::BC4_UNorm => Ok(Layout::Bc4),
            X::BC5_Typeless | X::BC5_UNorm => Ok(Layout::Bc5),
            X::BC7_Typeless | X::BC7_UNorm | X::BC7_UNorm_sRGB => Ok(Layout::Bc7),
            X::R8G8B8A8_Typeless | X::R8G8B8A8_UNorm | X::R8G8B8A8_UNorm_sRGB => Ok(Layout::Rgba8),
            X::B8G8R8A8_Typeless | X::B8G8R8A8_UNorm | X::B8G8R8A8_UNorm_sRGB => Ok(Layout::Bgra8),
            X::B8G8R8X8_Typeless | X::B8G8R8X8_UNorm | X::B8G8R8X8_UNorm_sRGB => Ok(Layout::Bgrx8),
            other => Err(unread(&format!("{other:?}"))),
        };
    }
    match dds.get_d3d_format() {
        Some(D3DFormat::DXT1) => Ok(Layout::Bc1),
        Some(D3DFormat::DXT2 | D3DFormat::DXT3) => Ok(Layout::Bc2),
        Some(D3DFormat::DXT4 | D3DFormat::DXT5) => Ok(Layout::Bc3),
        Some(D3DFormat::A8B8G8R8) => Ok(Layout::Rgba8),
        Some(D3DFormat::A8R8G8B8) => Ok(Layout::Bgra8),
        Some(D3DFormat::X8R8G8B8) => Ok(Layout::Bgrx8),
        Some(D3DFormat::R8G8B8) => Ok(Layout::Bgr8),
        Some(other) => Err(unread(&format!("{other:?}"))),
        None => Err(unread("of this pixel format")),
    }
}

/// The message for a format not read.
fn unread(format: &str) -> String {
    format!("DDS {format} is not read (BC1-BC5, BC7 and 8-bit RGBA/BGRA/BGR are)")
}

/// Decodes the base level of a DDS file to RGBA8; a message for anything it cannot.
pub(crate) fn decode(bytes: &[u8]) -> Result<image::RgbaImage, String> {
    let dds = Dds::read(bytes).map_err(|e| format!("not a readable DDS file ({e})"))?;
    let (width, height) = (dds.get_width(), dds.get_height());
    if width == 0 || height == 0 || dds.get_depth() > 1 {
        return Err(format!(
            "DDS of {width}x{height}x{} texels: only 2D images are textures",
            dds.get_depth()
        ));
    }
    let layout = layout(&dds)?;
    let (w, h) = (width as usize, height as usize);
    let (units_x, units_y) = if layout.is_block() {
        (w.div_ceil(4), h.div_ceil(4))
    } else {
        (w, h)
    };
    let needed = units_x
        .checked_mul(units_y)
        .and_then(|n| n.checked_mul(layout.unit_bytes()))
        .ok_or_else(|| format!("DDS of {width}x{height} texels is too large"))?;
    let data = dds.data.get(..needed).ok_or_else(|| {
        format!(
            "truncated DDS: {width}x{height} needs {needed} bytes of texels, the file holds {}",
            dds.data.len()
        )
    })?;
    let texels = if layout.is_block() {
        blocks(data, layout, (w, h), units_x)
    } else {
        plain(data, layout)
    };
    image::RgbaImage::from_raw(width, height, texels)
        .ok_or_else(|| format!("DDS decoding gave too few texels for {width}x{height}"))
}

/// The texels of an uncompressed layout, as RGBA8.
fn plain(data: &[u8], layout: Layout) -> Vec<u8> {
    let mut out = Vec::with_capacity(data.len() / layout.unit_bytes() * 4);
    for t in data.chunks_exact(layout.unit_bytes()) {
        out.extend_from_slice(&match layout {
            Layout::Rgba8 => [t[0], t[1], t[2], t[3]],
            Layout::Bgra8 => [t[2], t[1], t[0], t[3]],
            _ => [t[2], t[1], t[0], u8::MAX],
        });
    }
    out
}

/// The texels of a block-compressed layout, as RGBA8: each 4x4 block decoded, the blocks
/// past the image's right and bottom edges cut off.
fn blocks(data: &[u8], layout: Layout, (w, h): (usize, usize), blocks_x: usize) -> Vec<u8> {
    let mut out = vec![0u8; w * h * 4];
    // One block as the decoder writes it: 4 rows of 4 texels of up to 4 bytes.
    let mut block = [0u8; 64];
    let channels = match layout {
        Layout::Bc4 => 1,
        Layout::Bc5 => 2,
        _ => 4,
    };
    for (index, source) in data.chunks_exact(layout.unit_bytes()).enumerate() {
        let pitch = 4 * channels;
        match layout {
            Layout::Bc1 => bcdec_rs::bc1(source, &mut block, pitch),
            Layout::Bc2 => bcdec_rs::bc2(source, &mut block, pitch),
            Layout::Bc3 => bcdec_rs::bc3(source, &mut block, pitch),
            Layout::Bc4 => bcdec_rs::bc4(source, &mut block, pitch, false),
            Layout::Bc5 => bcdec_rs::bc5(source, &mut block, pitch, false),
            _ => bcdec_rs::bc7(source, &mut block, pitch),
        }
        let (bx, by) = (index % blocks_x * 4, index / blocks_x * 4);
        for y in 0..4.min(h - by) {
            for x in 0..4.min(w - bx) {
                let t = &block[(y * 4 + x) * channels..][..channels];
                let rgba = match channels {
                    1 => [t[0], t[0], t[0], u8::MAX],
                    2 => [t[0], t[1], normal_z(t[0], t[1]), u8::MAX],
                    _ => [t[0], t[1], t[2], t[3]],
                };
                let at = ((by + y) * w + bx + x) * 4;
                out[at..at + 4].copy_from_slice(&rgba);
            }
        }
    }
    out
}

/// The z of a unit normal whose x and y are stored as `x` and `y` (0..255 for -1..1), stored
/// the same way.
fn normal_z(x: u8, y: u8) -> u8 {
    let unit = |c: u8| f32::from(c) / 127.5 - 1.0;
    let z = (1.0 - unit(x).powi(2) - unit(y).powi(2)).max(0.0).sqrt();
    ((z + 1.0) * 127.5).round().clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A DDS file of `width` x `height` with the legacy FourCC `fourcc` (or, with `None`, 32-bit
    /// BGRA masks) and `data` after the header.
    pub(crate) fn dds_file(
        width: u32,
        height: u32,
        fourcc: Option<&[u8; 4]>,
        data: &[u8],
    ) -> Vec<u8> {
        let mut b = MAGIC.to_vec();
        // Header: size, flags (caps, height, width, pixel format), height, width, pitch, depth,
        // mip count, 11 reserved.
        for word in [124u32, 0x1007, height, width, 0, 0, 1] {
            b.extend(word.to_le_bytes());
        }
        b.extend([0u8; 44]);
        // Pixel format: size, flags, FourCC, bit count, R, G, B, A masks.
        let pf: [u32; 8] = match fourcc {
            Some(code) => [32, 0x4, u32::from_le_bytes(*code), 0, 0, 0, 0, 0],
            None => [
                32,
                0x41,
                0,
                32,
                0x00FF_0000,
                0x0000_FF00,
                0x0000_00FF,
                0xFF00_0000,
            ],
        };
        for word in pf {
            b.extend(word.to_le_bytes());
        }
        // Caps (texture), caps 2-4, reserved.
        for word in [0x1000u32, 0, 0, 0, 0] {
            b.extend(word.to_le_bytes());
        }
        b.extend_from_slice(data);
        b
    }

    #[test]
    fn uncompressed_bgra_is_swizzled() {
        let file = dds_file(2, 1, None, &[10, 20, 30, 40, 50, 60, 70, 80]);
        assert!(is_dds(&file));
        assert_eq!(dimensions(&file), Ok((2, 1)));
        let image = decode(&file).unwrap();
        assert_eq!(image.as_raw(), &[30, 20, 10, 40, 70, 60, 50, 80]);
    }

    /// A BC1 block of one colour (both endpoints red, every index 0) fills the 6x5 image's
    /// blocks, cut at its edges; truncated data and unread formats are errors that say so.
    #[test]
    fn bc1_blocks_decode_and_bad_files_are_refused() {
        // Endpoint 0 = endpoint 1 = pure red in RGB565; indices all 0.
        let red_block = [0x00, 0xF8, 0x00, 0xF8, 0, 0, 0, 0];
        let data: Vec<u8> = red_block.repeat(4);
        let image = decode(&dds_file(6, 5, Some(b"DXT1"), &data)).unwrap();
        assert_eq!(image.dimensions(), (6, 5));
        assert!(image.pixels().all(|p| p.0 == [255, 0, 0, 255]));
        let short = decode(&dds_file(6, 5, Some(b"DXT1"), &data[..24])).unwrap_err();
        assert!(short.contains("truncated DDS"), "{short}");
        let unread = decode(&dds_file(4, 4, Some(b"UYVY"), &data)).unwrap_err();
        assert!(unread.contains("is not read"), "{unread}");
        assert!(decode(b"DDS ").is_err());
        assert!(dimensions(b"DDS \x7c\0\0\0").is_err());
    }

    #[test]
    fn bc5_rebuilds_the_normal_z() {
        assert_eq!(normal_z(128, 128), 255);
        assert_eq!(normal_z(255, 128), 128);
    }
}
