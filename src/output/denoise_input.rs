//! What the denoiser needs of one tile, kept for `merge`: the tile's film (linear radiance
//! after exposure, premultiplied alpha, and each pixel's variance) and its guides, as one
//! OpenEXR file of 32-bit float channels, ZIP-compressed (lossless: every value comes back
//! bit for bit). A tile of a denoised render writes it beside its image (`OUT.denoise.exr`);
//! the merge joins the tiles' into the whole film and denoises that, as a single render does.
//!
//! Channels (OpenEXR sorts them by name): `R`, `G`, `B`, `A` (the film), `variance`,
//! `albedo.R/G/B`, `normal.X/Y/Z`, `depth`, and when the guides have them (the path tracer's
//! own) `visibility` and `emission.R/G/B`. Any EXR viewer shows them as layers.

use crate::render::denoise::Guides;
use crate::render::Image;
use glam::Vec3;

/// A channel's name: `suffix` alone, or `prefix.suffix`.
fn channel_name(prefix: Option<&str>, suffix: &str) -> String {
    prefix.map_or(suffix.to_string(), |p| format!("{p}.{suffix}"))
}

/// Decoded channels, by name.
type Channels = Vec<(String, Vec<f32>)>;

/// Takes channel `name` out of `channels`.
fn take(channels: &mut Channels, name: &str) -> Result<Vec<f32>, String> {
    let at = channels
        .iter()
        .position(|(n, _)| n == name)
        .ok_or_else(|| format!("no '{name}' channel: not a tile's denoise input"))?;
    Ok(channels.swap_remove(at).1)
}

/// Takes the three channels of a vector out of `channels`, as vectors.
fn take_vectors(
    channels: &mut Channels,
    prefix: Option<&str>,
    suffixes: [&str; 3],
) -> Result<Vec<Vec3>, String> {
    let [x, y, z] = suffixes.map(|s| take(channels, &channel_name(prefix, s)));
    let (x, y, z) = (x?, y?, z?);
    Ok(x.iter()
        .zip(&y)
        .zip(&z)
        .map(|((x, y), z)| Vec3::new(*x, *y, *z))
        .collect())
}

/// The film and guides of a `image.width` x `image.height` tile as OpenEXR bytes, the same
/// bytes every run (scan lines in increasing order). The guides must be the image's size (a
/// bug in the caller otherwise: an error).
pub fn encode(image: &Image, guides: &Guides) -> Result<Vec<u8>, exr::error::Error> {
    use exr::prelude::{
        AnyChannel, AnyChannels, Blocks, Compression, Encoding, FlatSamples, Image as Exr, Layer,
        LayerAttributes, LineOrder, SmallVec, WritableImage,
    };
    let pixels = image.pixels.len();
    let optional = |v: usize| v == 0 || v == pixels;
    if (guides.width, guides.height) != (image.width, image.height)
        || [guides.albedo.len(), guides.normal.len(), guides.depth.len()] != [pixels; 3]
        || image.variance.len() != pixels
        || !optional(guides.visibility.len())
        || !optional(guides.emission.len())
    {
        return Err(exr::error::Error::Invalid(
            "the guides or variances differ from the image in size".into(),
        ));
    }
    let mut channels: Vec<(String, Vec<f32>)> = Vec::new();
    let mut vectors = |prefix: Option<&str>, values: &[Vec3], suffixes: [&str; 3]| {
        for (axis, suffix) in suffixes.iter().enumerate() {
            let samples = values.iter().map(|v| v[axis]).collect();
            channels.push((channel_name(prefix, suffix), samples));
        }
    };
    let rgb: Vec<Vec3> = image.pixels.iter().map(|p| p.truncate()).collect();
    vectors(None, &rgb, ["R", "G", "B"]);
    drop(rgb);
    vectors(Some("albedo"), &guides.albedo, ["R", "G", "B"]);
    vectors(Some("normal"), &guides.normal, ["X", "Y", "Z"]);
    if !guides.emission.is_empty() {
        vectors(Some("emission"), &guides.emission, ["R", "G", "B"]);
    }
    channels.push(("A".into(), image.pixels.iter().map(|p| p.w).collect()));
    channels.push(("variance".into(), image.variance.clone()));
    channels.push(("depth".into(), guides.depth.clone()));
    if !guides.visibility.is_empty() {
        channels.push(("visibility".into(), guides.visibility.clone()));
    }
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = channels
        .into_iter()
        .map(|(name, samples)| AnyChannel::new(name.as_str(), FlatSamples::F32(samples)))
        .collect();
    let encoding = Encoding {
        compression: Compression::ZIP16,
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let size = (image.width as usize, image.height as usize);
    let layer = Layer::new(
        size,
        LayerAttributes::default(),
        encoding,
        AnyChannels::sort(list),
    );
    let mut bytes = Vec::new();
    Exr::from_layer(layer)
        .write()
        .to_buffered(std::io::Cursor::new(&mut bytes))?;
    Ok(bytes)
}

/// Decodes what [`encode`] wrote for a `width` x `height` tile: its film (`samples` 1, no
/// guides: the sidecar has the counts) and its guides (`samples_per_pixel` 1), with the
/// visibility and emission channels when the file has them. A file of another size, or
/// without one of the channels every such file has, is refused with what is wrong; a panic in
/// the decoder (a hostile file) is an error too.
pub fn decode(bytes: &[u8], width: u32, height: u32) -> Result<(Image, Guides), String> {
    let pixels = width as usize * height as usize;
    let decoded = crate::scene::catch_quietly(|| {
        crate::scene::decode_exr_channels(std::io::Cursor::new(bytes), pixels.max(1))
    })
    .map_err(|panic| format!("the decoder failed (an internal error): {panic}"))??;
    let crate::scene::ExrChannels {
        width: w,
        height: h,
        mut channels,
    } = decoded;
    if (w, h) != (width as usize, height as usize) {
        return Err(format!(
            "{w}x{h} pixels, but its sidecar says the tile is {width}x{height}"
        ));
    }
    let rgb = take_vectors(&mut channels, None, ["R", "G", "B"])?;
    let albedo = take_vectors(&mut channels, Some("albedo"), ["R", "G", "B"])?;
    let normal = take_vectors(&mut channels, Some("normal"), ["X", "Y", "Z"])?;
    let emission = if channels.iter().any(|(n, _)| n.starts_with("emission.")) {
        take_vectors(&mut channels, Some("emission"), ["R", "G", "B"])?
    } else {
        Vec::new()
    };
    let visibility = if channels.iter().any(|(n, _)| n == "visibility") {
        take(&mut channels, "visibility")?
    } else {
        Vec::new()
    };
    let alpha = take(&mut channels, "A")?;
    let image = Image {
        width,
        height,
        pixels: rgb.iter().zip(&alpha).map(|(c, a)| c.extend(*a)).collect(),
        variance: take(&mut channels, "variance")?,
        guides: None,
        samples: 1,
    };
    let guides = Guides {
        width,
        height,
        albedo,
        normal,
        depth: take(&mut channels, "depth")?,
        visibility,
        emission,
        samples_per_pixel: 1,
    };
    Ok((image, guides))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec4;

    /// A 5 x 3 tile with values no rounding keeps (NaN payloads aside, every bit matters).
    fn tile(visibility: bool) -> (Image, Guides) {
        let (width, height) = (5u32, 3u32);
        let n = (width * height) as usize;
        let value = |i: usize, k: u32| (i as f32 + 0.1) * 1.000_001f32.powi(k as i32) / 3.0;
        let vector = |i: usize, k: u32| Vec3::new(value(i, k), value(i, k + 1), -value(i, k + 2));
        let image = Image {
            width,
            height,
            pixels: (0..n)
                .map(|i| Vec4::new(value(i, 0), 1e30, f32::MIN_POSITIVE, 0.25))
                .collect(),
            variance: (0..n).map(|i| value(i, 7)).collect(),
            guides: None,
            samples: 1,
        };
        let guides = Guides {
            width,
            height,
            albedo: (0..n).map(|i| vector(i, 10)).collect(),
            normal: (0..n).map(|i| vector(i, 20)).collect(),
            depth: (0..n).map(|i| value(i, 30)).collect(),
            visibility: if visibility {
                (0..n).map(|i| value(i, 40)).collect()
            } else {
                Vec::new()
            },
            emission: if visibility {
                (0..n).map(|i| vector(i, 50)).collect()
            } else {
                Vec::new()
            },
            samples_per_pixel: 1,
        };
        (image, guides)
    }

    #[test]
    fn film_and_guides_come_back_bit_for_bit() {
        for with_path_guides in [true, false] {
            let (image, guides) = tile(with_path_guides);
            let bytes = encode(&image, &guides).unwrap();
            assert_eq!(encode(&image, &guides).unwrap(), bytes, "deterministic");
            let (back, back_guides) = decode(&bytes, 5, 3).unwrap();
            assert_eq!(back, image);
            assert_eq!(back_guides, guides);
        }
    }

    #[test]
    fn another_size_or_file_is_refused() {
        let (image, guides) = tile(true);
        let bytes = encode(&image, &guides).unwrap();
        assert!(decode(&bytes, 5, 4).unwrap_err().contains("5x3 pixels"));
        let plain = crate::output::exr_rgba(5, 3, &[0.5; 60]).unwrap();
        assert!(decode(&plain, 5, 3).unwrap_err().contains("'albedo.R'"));
        assert!(decode(b"not an exr", 5, 3).is_err());
    }
}
