//! Decoded textures and how they are sampled (glTF 2.0 §3.8).
//!
//! Every image is decoded once into RGBA8 (4 bytes a texel, shared by every texture and material
//! that uses it) with a box-filtered mip chain (+1/3 memory). Colour textures (base colour,
//! emissive) are sRGB-decoded per texel through a 256-entry table before filtering; data
//! textures (metallic-roughness, normal, occlusion) are used as stored. Mip levels are averaged
//! in stored values, an approximation for sRGB data that only affects minified texels.
//!
//! Texture coordinates follow glTF: (0, 0) is the image's top-left texel corner, u to the right,
//! v down. Wrap modes apply per axis; magnification is NEAREST or LINEAR as the sampler says;
//! minification picks a mip level from the ray footprint (trilinear, or nearest texel on the
//! nearest level for NEAREST samplers), so distant surfaces do not alias.

use super::texture_inputs::TextureInputs;
use crate::scene::{Encoded, Filter, ImageSource, Sampler, Scene, TextureRef, Wrap};
use glam::{Vec2, Vec4};
use rayon::prelude::*;
use std::sync::{Arc, OnceLock};

/// One mip level.
#[derive(Clone, Debug)]
struct Level {
    width: u32,
    height: u32,
    texels: Texels,
}

/// A level's texels: its own, or, for level 0 of an image that the scene holds as pixels
/// ([`Scene::add_texture`], which the Python package's textures go through), the scene's
/// buffer, shared: such an image was held twice, once in the scene and once here.
#[derive(Clone, Debug)]
enum Texels {
    Owned(Vec<[u8; 4]>),
    Shared(Arc<image::RgbaImage>),
}

impl std::ops::Deref for Texels {
    type Target = [[u8; 4]];

    #[inline(always)]
    fn deref(&self) -> &[[u8; 4]] {
        match self {
            Texels::Owned(texels) => texels,
            // Whole texels: `Decoded::into_texels` shares only buffers of exactly 4·w·h bytes.
            Texels::Shared(image) => image.as_raw().as_chunks::<4>().0,
        }
    }
}

/// An image decoded to RGBA8: decoded here, or the scene's own pixels.
enum Decoded {
    Owned(image::RgbaImage),
    Shared(Arc<image::RgbaImage>),
}

impl Decoded {
    fn image(&self) -> &image::RgbaImage {
        match self {
            Decoded::Owned(image) => image,
            Decoded::Shared(image) => image,
        }
    }

    fn dimensions(&self) -> (u32, u32) {
        self.image().dimensions()
    }

    /// The texels of level 0: the decoded buffer reused, or the scene's shared (a copy only
    /// for a shared buffer longer than its pixels, which `Scene::add_texture` refuses).
    fn into_texels(self) -> Texels {
        match self {
            Decoded::Owned(image) => Texels::Owned(texels_of(image)),
            Decoded::Shared(image) => {
                let (w, h) = image.dimensions();
                if image.as_raw().len() as u64 == 4 * u64::from(w) * u64::from(h) {
                    Texels::Shared(image)
                } else {
                    Texels::Owned(texels_of((*image).clone()))
                }
            }
        }
    }
}

/// A decoded image with its mip chain; level 0 is full size.
#[derive(Clone, Debug)]
pub struct MipImage {
    levels: Vec<Level>,
    /// Whether any texel of level 0 is not fully opaque, found when first asked.
    translucent: OnceLock<bool>,
    /// Whether every texel of level 0 is grey (red, green and blue equal), found when first
    /// asked.
    grey: OnceLock<bool>,
}

/// Why textures could not be prepared.
#[derive(Debug, thiserror::Error)]
pub enum TextureError {
    /// An image failed to decode.
    #[error("{file}: image {image} ({origin}): {problem}")]
    Decode {
        /// The model file.
        file: String,
        /// Image index.
        image: usize,
        /// URI or buffer view.
        origin: String,
        /// The decoder's message.
        problem: String,
    },
}

/// Every image of a scene, decoded.
#[derive(Clone, Debug, Default)]
pub struct TextureSet {
    images: Vec<Option<Arc<MipImage>>>,
    /// Decoded bytes in total (all levels).
    pub bytes: usize,
    /// What the images were decoded from, when a later load can tell whether it is the same.
    inputs: Option<TextureInputs>,
    /// The warnings the decoding gave, repeated by a load that keeps this set.
    warnings: Vec<String>,
    /// Whether this set was kept from an earlier load ([`TextureSet::load_reusing`]).
    reused: bool,
}

fn srgb_table() -> &'static [f32; 256] {
    static TABLE: OnceLock<[f32; 256]> = OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| crate::color::srgb_to_linear(i as f32 / 255.0)))
}

impl MipImage {
    /// Builds the mip chain of an RGBA8 image.
    pub fn new(width: u32, height: u32, texels: Vec<[u8; 4]>) -> MipImage {
        MipImage::over(width, height, Texels::Owned(texels))
    }

    /// Builds the mip chain over level 0's `texels`.
    fn over(width: u32, height: u32, texels: Texels) -> MipImage {
        let mut levels = vec![Level {
            width,
            height,
            texels,
        }];
        while let Some(last) = levels.last() {
            if last.width == 1 && last.height == 1 {
                break;
            }
            let (w, h) = ((last.width / 2).max(1), (last.height / 2).max(1));
            let mut texels = Vec::with_capacity((w * h) as usize);
            if last.width % 2 == 0 && last.height % 2 == 0 {
                // Even sides (power-of-two textures, nearly all of them): every 2x2 block is
                // inside the level, so rows are read in pairs without clamping. Same sums,
                // same rounding as the general loop below.
                // Each output row is written in place from its two input rows (no `push`, so
                // the loop vectorises), rows spread over threads: a 2048² level was 16 ms.
                let lw = last.width as usize;
                texels.resize(w as usize * h as usize, [0; 4]);
                texels
                    .par_chunks_mut(w as usize)
                    .zip(last.texels.par_chunks_exact(2 * lw))
                    .with_min_len(16)
                    .for_each(|(out, pair)| {
                        let (top, bottom) = pair.split_at(lw);
                        let blocks = top.chunks_exact(2).zip(bottom.chunks_exact(2));
                        for (o, (t, b)) in out.iter_mut().zip(blocks) {
                            *o = average_of_four([t[0], t[1], b[0], b[1]]);
                        }
                    });
                levels.push(Level {
                    width: w,
                    height: h,
                    texels: Texels::Owned(texels),
                });
                continue;
            }
            for y in 0..h {
                for x in 0..w {
                    let mut sum = [0u32; 4];
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let sx = (2 * x + dx).min(last.width - 1);
                        let sy = (2 * y + dy).min(last.height - 1);
                        let t = last.texels[(sy * last.width + sx) as usize];
                        for c in 0..4 {
                            sum[c] += u32::from(t[c]);
                        }
                    }
                    texels.push(sum.map(|s| ((s + 2) / 4) as u8));
                }
            }
            levels.push(Level {
                width: w,
                height: h,
                texels: Texels::Owned(texels),
            });
        }
        MipImage {
            levels,
            translucent: OnceLock::new(),
            grey: OnceLock::new(),
        }
    }

    /// Whether every texel is grey. A normal map never is (its texels are directions, mostly
    /// blue); a grey image named as one is a height map (MTL's `map_Bump` and `bump` often
    /// name one). The pass stops at the first coloured texel: at once, for a normal map.
    pub fn grey(&self) -> bool {
        *self.grey.get_or_init(|| {
            self.levels[0]
                .texels
                .iter()
                .all(|t| t[0] == t[1] && t[1] == t[2])
        })
    }

    /// Whether the image has any transparency (a texel of alpha below 1). An image without an
    /// alpha channel has none: its decoded alpha is 1 everywhere.
    pub fn translucent(&self) -> bool {
        *self
            .translucent
            .get_or_init(|| self.levels[0].texels.iter().any(|t| t[3] < u8::MAX))
    }

    /// What `MipImage::bytes` is for an image of `width` x `height`: every level of the
    /// chain, down to 1x1, at 4 bytes a texel.
    pub fn chain_bytes(width: u32, height: u32) -> usize {
        let (mut w, mut h) = (width as usize, height as usize);
        let mut bytes = w * h * 4;
        while w > 1 || h > 1 {
            (w, h) = ((w / 2).max(1), (h / 2).max(1));
            bytes += w * h * 4;
        }
        bytes
    }

    /// Size of level 0.
    pub fn size(&self) -> (u32, u32) {
        (self.levels[0].width, self.levels[0].height)
    }

    /// Whether level 0 is `pixels`' own buffer (shared, not copied).
    #[cfg(test)]
    pub(crate) fn level_zero_is(&self, pixels: &image::RgbaImage) -> bool {
        std::ptr::eq(
            self.levels[0].texels.as_ptr().cast(),
            pixels.as_raw().as_ptr(),
        )
    }

    #[cfg(test)]
    fn bytes(&self) -> usize {
        self.levels.iter().map(|l| l.texels.len() * 4).sum()
    }

    #[inline(always)]
    fn texel(&self, level: usize, x: i64, y: i64, sampler: &Sampler, srgb: bool) -> Vec4 {
        let l = &self.levels[level];
        let x = wrap(x, l.width, sampler.wrap_s);
        let y = wrap(y, l.height, sampler.wrap_t);
        decode_texel(l.texels[(y * l.width + x) as usize], srgb)
    }

    #[inline(always)]
    fn sample_level(
        &self,
        level: usize,
        uv: Vec2,
        sampler: &Sampler,
        linear: bool,
        srgb: bool,
    ) -> Vec4 {
        let l = &self.levels[level];
        let x = uv.x * l.width as f32;
        let y = uv.y * l.height as f32;
        if !linear {
            return self.texel(level, x.floor() as i64, y.floor() as i64, sampler, srgb);
        }
        // Texel centres sit at half-integers.
        let (x, y) = (x - 0.5, y - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        // Each column and row wrapped once, the two rows' offsets computed once.
        let (xa, xb) = (
            wrap(x0, l.width, sampler.wrap_s),
            wrap(x0 + 1, l.width, sampler.wrap_s),
        );
        let (ya, yb) = (
            wrap(y0, l.height, sampler.wrap_t),
            wrap(y0 + 1, l.height, sampler.wrap_t),
        );
        let (row_a, row_b) = ((ya * l.width) as usize, (yb * l.width) as usize);
        let at = |row: usize, x: u32| decode_texel(l.texels[row + x as usize], srgb);
        let a = at(row_a, xa);
        let b = at(row_a, xb);
        let c = at(row_b, xa);
        let d = at(row_b, xb);
        a.lerp(b, fx).lerp(c.lerp(d, fx), fy)
    }

    /// Samples at `uv` with mip level of detail `lod` (0 = full size; fractional values blend
    /// levels). `srgb` decodes colour channels to linear.
    pub fn sample(&self, uv: Vec2, lod: f32, sampler: &Sampler, srgb: bool) -> Vec4 {
        #[cfg(target_arch = "x86_64")]
        if crate::cpu::has_v3() {
            // SAFETY: the CPU has every feature `filtered_v3` is compiled for.
            return unsafe { self.filtered_v3(uv, lod, sampler, srgb) };
        }
        self.filtered(uv, lod, sampler, srgb)
    }

    crate::cpu::v3! {
        /// [`MipImage::filtered`] for x86-64-v3 CPUs ([`crate::cpu`]).
        fn filtered_v3(&self, uv: Vec2, lod: f32, sampler: &Sampler, srgb: bool) -> Vec4 = filtered
    }

    /// The body of [`MipImage::sample`], compiled for each CPU level.
    #[inline(always)]
    fn filtered(&self, uv: Vec2, lod: f32, sampler: &Sampler, srgb: bool) -> Vec4 {
        // Coordinates far outside [0, 1] lose precision in f32; wrap them close to it first
        // where the mode is periodic (the result is the same texel).
        let uv = Vec2::new(reduce(uv.x, sampler.wrap_s), reduce(uv.y, sampler.wrap_t));
        if !uv.is_finite() {
            return self.texel(0, 0, 0, sampler, srgb);
        }
        let max_level = (self.levels.len() - 1) as f32;
        // NaN (a degenerate footprint) counts as magnification.
        if lod.is_nan() || lod <= 0.0 {
            return self.sample_level(0, uv, sampler, sampler.mag_filter == Filter::Linear, srgb);
        }
        let lod = lod.min(max_level);
        if sampler.min_filter == Filter::Nearest {
            return self.sample_level(lod.round() as usize, uv, sampler, false, srgb);
        }
        let lo = lod.floor();
        let a = self.sample_level(lo as usize, uv, sampler, true, srgb);
        if lod == lo {
            return a;
        }
        let b = self.sample_level(lo as usize + 1, uv, sampler, true, srgb);
        a.lerp(b, lod - lo)
    }
}

/// The rounded mean of four texels, channel by channel: (a + b + c + d + 2) / 4. Computed on
/// the two pairs of alternate channels at once (16 bits a channel in a u32, where the sum of
/// four bytes fits), which the compiler turns into vector code: written channel by channel the
/// loop was scalar, and mip building took a sixth of DamagedHelmet's texture phase.
#[inline(always)]
fn average_of_four(texels: [[u8; 4]; 4]) -> [u8; 4] {
    const LANES: u32 = 0x00FF_00FF;
    let (mut even, mut odd) = (0x0002_0002u32, 0x0002_0002u32);
    for t in texels {
        let p = u32::from_le_bytes(t);
        even += p & LANES;
        odd += (p >> 8) & LANES;
    }
    (((even >> 2) & LANES) | (((odd >> 2) & LANES) << 8)).to_le_bytes()
}

/// A stored texel as floats in [0, 1]; `srgb` decodes the colour channels to linear (alpha
/// stays linear).
#[inline(always)]
fn decode_texel(t: [u8; 4], srgb: bool) -> Vec4 {
    if srgb {
        let table = srgb_table();
        Vec4::new(
            table[t[0] as usize],
            table[t[1] as usize],
            table[t[2] as usize],
            f32::from(t[3]) / 255.0,
        )
    } else {
        // One vector division: the same correctly rounded quotients as four scalar ones.
        Vec4::new(
            f32::from(t[0]),
            f32::from(t[1]),
            f32::from(t[2]),
            f32::from(t[3]),
        ) / 255.0
    }
}

/// Moves a periodic coordinate into [-2, 2) without changing which texel it selects.
#[inline(always)]
fn reduce(c: f32, mode: Wrap) -> f32 {
    match mode {
        Wrap::Repeat => c - c.floor(),
        Wrap::MirroredRepeat => c - 2.0 * (c * 0.5).floor(),
        Wrap::ClampToEdge => c.clamp(-1.0, 2.0),
    }
}

/// A texel index wrapped into [0, size) by the glTF wrap mode.
#[inline(always)]
fn wrap(i: i64, size: u32, mode: Wrap) -> u32 {
    let n = i64::from(size);
    let r = match mode {
        Wrap::ClampToEdge => i.clamp(0, n - 1),
        // Power-of-two sides (nearly every texture): the mask is rem_euclid without a division
        // (two's complement keeps it right for negative i).
        Wrap::Repeat if size.is_power_of_two() => i & (n - 1),
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::MirroredRepeat => {
            let period = if size.is_power_of_two() {
                i & (2 * n - 1)
            } else {
                i.rem_euclid(2 * n)
            };
            if period < n {
                period
            } else {
                2 * n - 1 - period
            }
        }
    };
    r as u32
}

/// Most bytes a decoder may allocate. The importer has already refused images whose header
/// declares more than its pixel limit (64 Mpixels by default, 256 MB as RGBA8); this bounds
/// what a lying header could still make the decoder allocate.
const MAX_DECODE_BYTES: u64 = 2 << 30;

/// Decodes one image source to RGBA8.
///
/// The decoders (PNG, JPEG, WebP, Basis Universal) are other crates reading bytes from a
/// downloaded file. A panic in one of them is a bug to report, not a reason to end the render:
/// it becomes this image's error, which leaves the image out with a warning (an error under
/// `--strict`) like any image that cannot be decoded. Fuzz builds let it through, so the fuzz
/// targets still find it.
fn decode(source: &ImageSource) -> Result<Decoded, String> {
    if let Encoded::Pixels(pixels) = source.encoded() {
        // Handed over as pixels: shared with the scene, not copied.
        return Ok(Decoded::Shared(Arc::clone(pixels)));
    }
    #[cfg(fuzzing)]
    return decode_encoded(source).map(Decoded::Owned);
    #[cfg(not(fuzzing))]
    crate::scene::catch_quietly(|| decode_encoded(source))
        .unwrap_or_else(|panic| {
            Err(format!(
                "the decoder failed (an internal error; please report this image): {panic}"
            ))
        })
        .map(Decoded::Owned)
}

/// [`decode`] of an encoded source.
fn decode_encoded(source: &ImageSource) -> Result<image::RgbaImage, String> {
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(MAX_DECODE_BYTES);
    let from_bytes = |bytes: &[u8]| -> Result<image::RgbaImage, String> {
        if crate::scene::ktx2::is_ktx2(bytes) {
            return crate::scene::ktx2::decode(bytes);
        }
        if crate::scene::dds::is_dds(bytes) {
            return crate::scene::dds::decode(bytes);
        }
        let mut r = image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| e.to_string())?;
        texture_format(r.format())?;
        r.limits(limits.clone());
        Ok(into_rgba8(r.decode().map_err(|e| e.to_string())?))
    };
    let reader = match source.encoded() {
        // `decode` shares these instead; a copy if reached.
        Encoded::Pixels(pixels) => return Ok((**pixels).clone()),
        Encoded::Bytes(bytes) => return from_bytes(bytes),
        // An image of a GLB that the load left on disk: read now, on the decoding thread.
        Encoded::InFile(part) => return from_bytes(&part.read(u64::MAX)?),
        Encoded::File(path)
            if crate::scene::ktx2::is_ktx2_source(source)
                || crate::scene::dds::is_dds_file(path) =>
        {
            // Read whole, then decoded by the magic (a KTX2 named by its MIME type alone is
            // decoded as KTX2 and refused there if it is not).
            let bytes = std::fs::read(path).map_err(|e| format!("'{}': {e}", path.display()))?;
            if crate::scene::dds::is_dds(&bytes) {
                return crate::scene::dds::decode(&bytes);
            }
            return crate::scene::ktx2::decode(&bytes);
        }
        Encoded::File(path) => {
            let mut r = image::ImageReader::open(path)
                .map_err(|e| e.to_string())?
                .with_guessed_format()
                .map_err(|e| e.to_string())?;
            texture_format(r.format())?;
            r.limits(limits);
            r.decode()
        }
        Encoded::Missing => return Err("no image data".into()),
    };
    Ok(into_rgba8(reader.map_err(|e| e.to_string())?))
}

/// Whether an image of `format` (as its bytes show) may be decoded as a texture: glTF's
/// PNG and JPEG (§3.8.4), WebP (`EXT_texture_webp`; KTX2 is read apart), and GIF, TGA and
/// BMP, which OBJ files name (TGA above all, in game assets). The build's other decoders
/// (Radiance, OpenEXR) are for panoramas and outputs: OpenEXR's decodes blocks on a thread pool of its own, where a panic on a hostile file would
/// end the process instead of becoming this image's error.
fn texture_format(format: Option<image::ImageFormat>) -> Result<(), String> {
    use image::ImageFormat as F;
    match format {
        Some(F::Png | F::Jpeg | F::WebP | F::Gif | F::Tga | F::Bmp) => Ok(()),
        Some(other) => Err(format!(
            "{} images are not textures (use PNG, JPEG, WebP, KTX2, TGA, BMP or DDS)",
            other
                .extensions_str()
                .first()
                .map_or("these", |e| e)
                .to_uppercase()
        )),
        None => Err(
            "not an image format meshtracer reads (use PNG, JPEG, WebP, KTX2, TGA, BMP or DDS)"
                .into(),
        ),
    }
}

/// A decoded image as RGBA8: kept as it is when it already is; JPEG's RGB8 gets alpha 255
/// here, each texel written once into a buffer of the final size (the image crate's
/// `into_rgba8` zeroes the buffer first and converts through its colour-space machinery: 14
/// instructions a texel, a seventh of DamagedHelmet's texture phase). Other layouts go through
/// `into_rgba8`.
fn into_rgba8(image: image::DynamicImage) -> image::RgbaImage {
    match image {
        image::DynamicImage::ImageRgb8(rgb) => {
            let (w, h) = rgb.dimensions();
            let n = w as usize * h as usize;
            let raw = rgb.as_raw();
            let raw = &raw[..(3 * n).min(raw.len())];
            // Zeroed memory of this size comes from the kernel as it is first written: no pass.
            let mut texels = vec![[0u8; 4]; n];
            // Four texels from three little-endian words: r0 g0 b0 r1 | g1 b1 r2 g2 | b2 r3 g3 b3.
            const OPAQUE: u32 = 0xFF00_0000;
            let groups = raw.chunks_exact(12);
            let rest = groups.remainder();
            let mut outs = texels.chunks_exact_mut(4);
            for (out, g) in (&mut outs).zip(groups) {
                let word = |i: usize| u32::from_le_bytes([g[i], g[i + 1], g[i + 2], g[i + 3]]);
                let (a, b, c) = (word(0), word(4), word(8));
                out[0] = (a | OPAQUE).to_le_bytes();
                out[1] = ((a >> 24) | (b << 8) | OPAQUE).to_le_bytes();
                out[2] = ((b >> 16) | (c << 16) | OPAQUE).to_le_bytes();
                out[3] = ((c >> 8) | OPAQUE).to_le_bytes();
            }
            let tail = outs.into_remainder();
            for (out, c) in tail.iter_mut().zip(rest.chunks_exact(3)) {
                *out = [c[0], c[1], c[2], u8::MAX];
            }
            let bytes: Vec<u8> = bytemuck::allocation::cast_vec(texels);
            image::RgbaImage::from_raw(w, h, bytes)
                .unwrap_or_else(|| image::DynamicImage::ImageRgb8(rgb).into_rgba8())
        }
        other => other.into_rgba8(),
    }
}

/// Decodes the used images, biggest encoded file first, each thread taking the next image as
/// it finishes one: the longest decode starts at once instead of queueing behind others
/// (DamagedHelmet's progressive 1.3 MB metal-roughness JPEG takes as long as three of its
/// other images together). Results are returned by image index, whatever the order of work.
fn decode_used(scene: &Scene, used: &[bool]) -> Vec<Option<Result<Decoded, String>>> {
    let encoded_size = |source: &ImageSource| match source.encoded() {
        Encoded::Pixels(pixels) => pixels.as_raw().len() as u64,
        Encoded::Bytes(bytes) => bytes.len() as u64,
        Encoded::InFile(part) => part.range.end - part.range.start,
        Encoded::File(path) => std::fs::metadata(path).map_or(0, |m| m.len()),
        Encoded::Missing => 0,
    };
    let mut order: Vec<(u64, usize)> = (0..scene.images.len())
        .filter(|&i| used.get(i).copied().unwrap_or(false))
        .map(|i| (encoded_size(&scene.images[i]), i))
        .collect();
    order.sort_by_key(|&(size, i)| (std::cmp::Reverse(size), i));
    let results: Vec<OnceLock<Result<Decoded, String>>> =
        (0..scene.images.len()).map(|_| OnceLock::new()).collect();
    let next = std::sync::atomic::AtomicUsize::new(0);
    (0..rayon::current_num_threads().min(order.len()).max(1))
        .into_par_iter()
        .for_each(|_| {
            while let Some(&(_, i)) =
                order.get(next.fetch_add(1, std::sync::atomic::Ordering::Relaxed))
            {
                // Each index is in `order` once, so each cell is set once.
                let _ = results[i].set(decode(&scene.images[i]));
            }
        });
    results.into_iter().map(OnceLock::into_inner).collect()
}

/// An RGBA8 image's texels, reusing its buffer (a copy only if the buffer's capacity is not a
/// whole number of texels): a 2048² texture is 16 MB that need not be allocated, zeroed by the
/// kernel and copied again.
fn texels_of(img: image::RgbaImage) -> Vec<[u8; 4]> {
    bytemuck::allocation::try_cast_vec(img.into_raw()).unwrap_or_else(|(_, raw)| {
        raw.chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect()
    })
}

/// Which of `scene`'s images the drawn materials use: only the materials the triangles use
/// (after a variant is chosen) need their images.
fn used_images(scene: &Scene) -> Vec<bool> {
    let mut drawn = vec![false; scene.materials.len()];
    for &m in &scene.soup.material {
        if let Some(d) = drawn.get_mut(m as usize) {
            *d = true;
        }
    }
    let mut used = vec![false; scene.images.len()];
    for (_, m) in scene
        .materials
        .iter()
        .enumerate()
        .filter(|(i, _)| drawn[*i])
    {
        for r in m.texture_refs() {
            if let Some(t) = scene.textures.get(r.texture) {
                if let Some(u) = used.get_mut(t.image) {
                    *u = true;
                }
            }
        }
    }
    used
}

/// The materials that use an image, for messages: `material 'wood' (2)` or `materials 0, 3`.
fn users_of(scene: &Scene, image: usize) -> String {
    let users: Vec<String> = scene
        .materials
        .iter()
        .enumerate()
        .filter(|(_, m)| {
            m.texture_refs().any(|r| {
                scene
                    .textures
                    .get(r.texture)
                    .is_some_and(|t| t.image == image)
            })
        })
        .map(|(i, m)| m.label(i))
        .collect();
    match users.len() {
        1 => format!("material {}", users[0]),
        _ => format!("materials {}", users.join(", ")),
    }
}

impl TextureSet {
    /// Decodes every image a drawn material uses. Images whose decoded size would push the total
    /// over `budget_bytes` are halved until they fit, with a warning. An image that fails to
    /// decode (and has no fallback image) is left out with a warning naming the image, its file
    /// and the materials, which then draw with their factors; with `strict` it is an error.
    pub fn load(
        scene: &Scene,
        budget_bytes: usize,
        strict: bool,
        warnings: &mut Vec<String>,
    ) -> Result<TextureSet, TextureError> {
        TextureSet::load_reusing(scene, budget_bytes, strict, warnings, None)
    }

    /// [`TextureSet::load`], keeping `previous` (an earlier load's set) when it was decoded
    /// from the same inputs: the same model and files, unchanged on disk (length and
    /// modification time), naming the same images, with the same images drawn and the same
    /// budget. Then the result is the one decoding again would give, bit for bit, with its
    /// warnings. Otherwise `previous` is dropped before anything is decoded. `render --frames`
    /// and a batch's jobs load a model again for each pose; its images do not change with the
    /// pose.
    pub fn load_reusing(
        scene: &Scene,
        budget_bytes: usize,
        strict: bool,
        warnings: &mut Vec<String>,
        previous: Option<TextureSet>,
    ) -> Result<TextureSet, TextureError> {
        let used = used_images(scene);
        let inputs = TextureInputs::of(scene, &used, budget_bytes, strict);
        if let Some(previous) = previous.filter(|p| inputs.is_some() && p.inputs == inputs) {
            warnings.extend(previous.warnings.iter().cloned());
            return Ok(TextureSet {
                reused: true,
                ..previous
            });
        }
        let mut own_warnings = Vec::new();
        let mut set = TextureSet::decode(scene, &used, budget_bytes, strict, &mut own_warnings)?;
        own_warnings.extend(set.height_maps_as_normal_maps(scene));
        warnings.extend(own_warnings.iter().cloned());
        set.inputs = inputs;
        set.warnings = own_warnings;
        Ok(set)
    }

    /// One warning for each grey image that a material names as a normal map
    /// ([`MipImage::grey`]): a height map, which is not read as one; the surface is drawn
    /// without it ([`crate::shading::surface`] skips it) rather than with its greys taken for
    /// directions.
    fn height_maps_as_normal_maps(&self, scene: &Scene) -> Vec<String> {
        let mut seen = Vec::new();
        for material in &scene.materials {
            let coat = material.clearcoat.as_ref().and_then(|c| c.normal_texture);
            for r in [material.normal_texture, coat].into_iter().flatten() {
                let image = scene.textures.get(r.texture).map(|t| t.image);
                let grey = self.lookup(scene, &r).is_some_and(|(i, _)| i.grey());
                if let (Some(image), true) = (image, grey) {
                    if !seen.contains(&image) {
                        seen.push(image);
                    }
                }
            }
        }
        seen.into_iter()
            .map(|image| {
                format!(
                    "image {image} ({}): a grey image named as a normal map is a height (bump) \
                     map, which is not read; {} drawn without it",
                    scene.images.get(image).map_or("", |i| i.origin.as_str()),
                    users_of(scene, image)
                )
            })
            .collect()
    }

    /// Whether this set was kept from an earlier load ([`TextureSet::load_reusing`]) rather
    /// than decoded.
    pub fn reused(&self) -> bool {
        self.reused
    }

    /// Decodes the `used` images of `scene` (see [`TextureSet::load`]).
    fn decode(
        scene: &Scene,
        used: &[bool],
        budget_bytes: usize,
        strict: bool,
        warnings: &mut Vec<String>,
    ) -> Result<TextureSet, TextureError> {
        // Decoding is most of the work (DamagedHelmet: five 2048² images, 106 MB): the images
        // are decoded in parallel, each once, and then sized to the budget in index order so
        // that what is halved does not depend on which decoder finished first.
        let decoded = decode_used(scene, used);
        let mut set = TextureSet {
            images: vec![None; scene.images.len()],
            ..TextureSet::default()
        };
        let mut chosen = Vec::new();
        for (index, (source, decoded)) in scene.images.iter().zip(decoded).enumerate() {
            let Some(decoded) = decoded else {
                continue;
            };
            let decoded = match decoded {
                Ok(decoded) => decoded,
                Err(problem) => {
                    // EXT_texture_webp: textures whose WebP image cannot be decoded use their
                    // core source when every texture of this image has one (the same for all).
                    let fallbacks: Vec<Option<usize>> = scene
                        .textures
                        .iter()
                        .filter(|t| t.image == index)
                        .map(|t| t.fallback_image)
                        .collect();
                    let fallback = match fallbacks.first() {
                        Some(&Some(f)) if fallbacks.iter().all(|&g| g == Some(f)) => {
                            scene.images.get(f).map(|s| (f, s))
                        }
                        _ => None,
                    };
                    let error = |problem: String| TextureError::Decode {
                        file: scene.source.display().to_string(),
                        image: index,
                        origin: source.origin.clone(),
                        problem,
                    };
                    let decoded_fallback = match fallback {
                        Some((f, fallback)) => match decode(fallback) {
                            Ok(decoded) => {
                                warnings.push(format!(
                                    "image {index} ({}): {problem}; using fallback image {f} ({})",
                                    source.origin, fallback.origin
                                ));
                                Ok(decoded)
                            }
                            Err(p) => Err(format!("{problem}; fallback image {f}: {p}")),
                        },
                        None => Err(problem),
                    };
                    match decoded_fallback {
                        Ok(decoded) => decoded,
                        Err(problem) => {
                            let users = users_of(scene, index);
                            if strict {
                                return Err(error(format!(
                                    "{problem}; used by {users} (--strict refuses a missing texture)"
                                )));
                            }
                            warnings.push(format!(
                                "image {index} ({}): {problem}; {users} drawn without it, with its factors",
                                source.origin
                            ));
                            continue;
                        }
                    }
                }
            };
            let (mut w, mut h) = decoded.dimensions();
            let mut img = decoded;
            let remaining = budget_bytes.saturating_sub(set.bytes);
            let mut halvings = 0;
            // Level 0 plus the chain is at most 4/3 of level 0.
            while (w as usize * h as usize * 4 * 4 / 3) > remaining && (w > 1 || h > 1) {
                w = (w / 2).max(1);
                h = (h / 2).max(1);
                let halved = image::imageops::resize(
                    img.image(),
                    w,
                    h,
                    image::imageops::FilterType::Triangle,
                );
                img = Decoded::Owned(halved);
                halvings += 1;
            }
            if halvings > 0 {
                warnings.push(format!(
                    "image {index} ({}) downscaled {halvings}x by half to fit the texture memory budget of {} MB",
                    source.origin,
                    budget_bytes >> 20
                ));
            }
            set.bytes += MipImage::chain_bytes(w, h);
            chosen.push((index, img));
        }
        // The mip chains, in parallel too.
        let built: Vec<(usize, MipImage)> = chosen
            .into_par_iter()
            .map(|(index, img)| {
                let (w, h) = img.dimensions();
                (index, MipImage::over(w, h, img.into_texels()))
            })
            .collect();
        for (index, mip) in built {
            set.images[index] = Some(Arc::new(mip));
        }
        Ok(set)
    }

    /// The decoded image behind a texture reference, with its sampler.
    pub fn lookup<'a>(
        &'a self,
        scene: &'a Scene,
        r: &TextureRef,
    ) -> Option<(&'a MipImage, &'a Sampler)> {
        let texture = scene.textures.get(r.texture)?;
        let image = self.images.get(texture.image)?.as_deref()?;
        Some((image, &texture.sampler))
    }
}

/// Applies `KHR_texture_transform` to a texture coordinate: uv' = T(offset)·R(rotation)·S(scale)·uv,
/// with R = [[cos, sin], [-sin, cos]] as the extension defines it.
pub fn transform_uv(r: &TextureRef, uv: Vec2) -> Vec2 {
    match &r.transform {
        None => uv,
        Some(t) => {
            let s = Vec2::from(t.scale) * uv;
            let (sin, cos) = t.rotation.sin_cos();
            Vec2::new(cos * s.x + sin * s.y, -sin * s.x + cos * s.y) + Vec2::from(t.offset)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Grey images are told from colour ones, and an image without transparency from one with.
    #[test]
    fn grey_and_translucent_images_are_told_apart() {
        let grey = MipImage::new(2, 1, vec![[7, 7, 7, 255], [200, 200, 200, 255]]);
        assert!(grey.grey() && !grey.translucent());
        let normals = MipImage::new(2, 1, vec![[128, 128, 255, 255], [128, 128, 255, 0]]);
        assert!(!normals.grey() && normals.translucent());
    }

    #[test]
    fn even_levels_average_like_odd_ones() {
        // A 4x4 level takes the even fast path; the same texels inside a 5x4 image (odd width)
        // take the clamping loop, whose first two blocks see the same 2x2 texels.
        let texel = |x: u32, y: u32| [(x * 60 + y) as u8, (y * 50) as u8, (x * y * 9) as u8, 255];
        let even = MipImage::new(4, 4, (0..16).map(|i| texel(i % 4, i / 4)).collect());
        let odd = MipImage::new(5, 4, (0..20).map(|i| texel(i % 5, i / 5)).collect());
        for y in 0..2 {
            for x in 0..2 {
                let at = |m: &MipImage| m.levels[1].texels[(y * m.levels[1].width + x) as usize];
                assert_eq!(at(&even), at(&odd), "{x},{y}");
            }
        }
    }

    /// The packed average equals (a + b + c + d + 2) / 4 per channel, extremes included.
    #[test]
    fn packed_average_is_the_rounded_mean_of_each_channel() {
        let mut rng = crate::sampling::Rng::new(7);
        let mut byte = || (rng.next_f32() * 256.0) as u8;
        let mut cases: Vec<[[u8; 4]; 4]> = vec![[[255; 4]; 4], [[0; 4]; 4], [[1, 2, 3, 255]; 4]];
        for _ in 0..20_000 {
            cases.push(std::array::from_fn(|_| std::array::from_fn(|_| byte())));
        }
        for t in cases {
            let expected: [u8; 4] = std::array::from_fn(|c| {
                ((t.iter().map(|p| u32::from(p[c])).sum::<u32>() + 2) / 4) as u8
            });
            assert_eq!(average_of_four(t), expected, "{t:?}");
        }
    }

    /// Textures decode from PNG, JPEG, WebP and GIF bytes; OpenEXR and Radiance bytes (which the
    /// build decodes for panoramas) are refused by name, and unknown bytes too.
    #[test]
    fn textures_are_png_jpeg_webp_or_gif() {
        let encoded = |format: image::ImageFormat| {
            let mut bytes = Vec::new();
            let pixels = image::Rgb32FImage::from_pixel(2, 2, image::Rgb([0.5, 0.25, 1.0]));
            let image = match format {
                image::ImageFormat::OpenExr | image::ImageFormat::Hdr => {
                    image::DynamicImage::ImageRgb32F(pixels)
                }
                _ => image::DynamicImage::ImageRgb32F(pixels).into_rgb8().into(),
            };
            image
                .write_to(&mut std::io::Cursor::new(&mut bytes), format)
                .expect("encodes");
            ImageSource {
                origin: "test".into(),
                mime_type: None,
                path: None,
                bytes: Some(crate::scene::SharedBytes::whole(bytes)),
                in_file: None,
                pixels: None,
            }
        };
        for format in [
            image::ImageFormat::Png,
            image::ImageFormat::Jpeg,
            image::ImageFormat::Bmp,
        ] {
            let decoded = decode(&encoded(format)).expect("a texture format");
            assert_eq!(decoded.dimensions(), (2, 2));
        }
        // TGA has no signature: a file is known by its extension.
        let dir = tempfile::tempdir().expect("a temporary folder");
        let tga = dir.path().join("wood.tga");
        image::RgbImage::from_pixel(2, 2, image::Rgb([200, 100, 50]))
            .save(&tga)
            .expect("writes the TGA");
        let from_file = ImageSource {
            origin: "wood.tga".into(),
            mime_type: None,
            path: Some(tga),
            bytes: None,
            in_file: None,
            pixels: None,
        };
        let decoded = decode(&from_file).expect("TGA is a texture format");
        assert_eq!(decoded.image().get_pixel(1, 1).0, [200, 100, 50, 255]);
        for (format, name) in [
            (image::ImageFormat::OpenExr, "EXR"),
            (image::ImageFormat::Hdr, "HDR"),
        ] {
            let refused = decode(&encoded(format))
                .err()
                .expect("not a texture format");
            assert_eq!(
                refused,
                format!(
                    "{name} images are not textures (use PNG, JPEG, WebP, KTX2, TGA, BMP or DDS)"
                )
            );
        }
        let mut unknown = encoded(image::ImageFormat::Png);
        unknown.bytes = Some(crate::scene::SharedBytes::whole(vec![7; 64]));
        assert!(decode(&unknown)
            .err()
            .expect("no format")
            .starts_with("not an image format"));
    }

    /// RGB8 images become RGBA8 with alpha 255, exactly as the image crate converts them, for
    /// sizes that are and are not whole groups of four texels.
    #[test]
    fn rgb_to_rgba_matches_the_image_crate() {
        for (w, h) in [(1, 1), (3, 1), (4, 1), (5, 3), (64, 63)] {
            let rgb = image::RgbImage::from_fn(w, h, |x, y| {
                image::Rgb([(x * 7 + y) as u8, (y * 13) as u8, (x ^ y) as u8])
            });
            let expected = image::DynamicImage::ImageRgb8(rgb.clone()).into_rgba8();
            assert_eq!(into_rgba8(image::DynamicImage::ImageRgb8(rgb)), expected);
        }
    }

    #[test]
    fn chain_bytes_is_what_the_chain_takes() {
        for (w, h) in [(1, 1), (2, 1), (5, 3), (64, 64), (1000, 7)] {
            let mip = MipImage::new(w, h, vec![[0; 4]; (w * h) as usize]);
            assert_eq!(MipImage::chain_bytes(w, h), mip.bytes(), "{w}x{h}");
        }
    }

    fn sampler(wrap_mode: Wrap, filter: Filter) -> Sampler {
        Sampler {
            mag_filter: filter,
            min_filter: filter,
            wrap_s: wrap_mode,
            wrap_t: wrap_mode,
        }
    }

    /// A 4x2 image whose texel (x, y) has red = 10x + 100y, generated so every texel is distinct.
    fn ramp() -> MipImage {
        let texels = (0..2)
            .flat_map(|y| (0..4).map(move |x| [(10 * x + 100 * y) as u8, 0, 0, 255]))
            .collect();
        MipImage::new(4, 2, texels)
    }

    fn red(img: &MipImage, u: f32, v: f32, s: &Sampler) -> u8 {
        (img.sample(Vec2::new(u, v), 0.0, s, false).x * 255.0).round() as u8
    }

    #[test]
    fn texel_exact_orientation_and_wrap_modes() {
        let img = ramp();
        let nearest = |w| sampler(w, Filter::Nearest);
        // (0, 0) is the top-left texel; v grows downward.
        assert_eq!(red(&img, 0.1, 0.1, &nearest(Wrap::Repeat)), 0);
        assert_eq!(red(&img, 0.9, 0.1, &nearest(Wrap::Repeat)), 30);
        assert_eq!(red(&img, 0.1, 0.9, &nearest(Wrap::Repeat)), 100);
        // REPEAT tiles, CLAMP_TO_EDGE holds the edge, MIRRORED_REPEAT reflects.
        assert_eq!(red(&img, 1.1, 0.1, &nearest(Wrap::Repeat)), 0);
        assert_eq!(red(&img, 1.1, 0.1, &nearest(Wrap::ClampToEdge)), 30);
        assert_eq!(red(&img, 1.1, 0.1, &nearest(Wrap::MirroredRepeat)), 30);
        assert_eq!(red(&img, 1.3, 0.1, &nearest(Wrap::MirroredRepeat)), 20);
        assert_eq!(red(&img, -0.1, 0.1, &nearest(Wrap::MirroredRepeat)), 0);
        assert_eq!(red(&img, -0.1, 0.1, &nearest(Wrap::Repeat)), 30);
        assert_eq!(red(&img, -0.1, -0.4, &nearest(Wrap::ClampToEdge)), 0);
    }

    /// The power-of-two shortcut gives what the general rule gives, negative indices included.
    #[test]
    fn power_of_two_wrap_equals_the_general_rule() {
        for size in [1u32, 2, 4, 64, 2048] {
            let n = i64::from(size);
            for i in -3 * n - 5..3 * n + 5 {
                assert_eq!(
                    wrap(i, size, Wrap::Repeat),
                    i.rem_euclid(n) as u32,
                    "{i} {size}"
                );
                let period = i.rem_euclid(2 * n);
                let mirrored = if period < n {
                    period
                } else {
                    2 * n - 1 - period
                };
                assert_eq!(
                    wrap(i, size, Wrap::MirroredRepeat),
                    mirrored as u32,
                    "{i} {size}"
                );
            }
        }
    }

    #[test]
    fn bilinear_blends_between_texel_centres() {
        let img = ramp();
        let s = sampler(Wrap::ClampToEdge, Filter::Linear);
        // Halfway between the centres of texels 0 and 1 (u = 0.25 is their shared edge).
        assert_eq!(red(&img, 0.25, 0.25, &s), 5);
        // At a texel centre, exactly that texel.
        assert_eq!(red(&img, 0.375, 0.25, &s), 10);
    }

    #[test]
    fn mip_chain_averages_and_minification_blurs() {
        let texels = (0..16)
            .map(|i| {
                if i % 2 == 0 {
                    [255, 255, 255, 255]
                } else {
                    [0, 0, 0, 255]
                }
            })
            .collect();
        let img = MipImage::new(4, 4, texels);
        assert_eq!(img.levels.len(), 3);
        let s = sampler(Wrap::Repeat, Filter::Linear);
        let far = img.sample(Vec2::new(0.3, 0.3), 2.0, &s, false);
        assert!(
            (far.x - 0.5).abs() < 0.01,
            "a checkerboard seen from afar is grey: {far}"
        );
    }

    #[test]
    fn srgb_textures_decode_to_linear() {
        let img = MipImage::new(1, 1, vec![[188, 255, 0, 128]]);
        let s = sampler(Wrap::Repeat, Filter::Nearest);
        let c = img.sample(Vec2::new(0.5, 0.5), 0.0, &s, true);
        assert!((c.x - 0.5).abs() < 0.003 && c.y == 1.0 && c.z == 0.0);
        assert!((c.w - 128.0 / 255.0).abs() < 1e-6, "alpha stays linear");
    }

    #[test]
    fn texture_transform_follows_the_extension() {
        let r = TextureRef {
            texture: 0,
            tex_coord: 0,
            transform: Some(crate::scene::TextureTransform {
                offset: [0.5, 0.0],
                rotation: std::f32::consts::FRAC_PI_2,
                scale: [2.0, 2.0],
            }),
        };
        // S: (1, 0) -> (2, 0); R(90°): (cos·2, -sin·2) = (0, -2); T: (0.5, -2).
        let uv = transform_uv(&r, Vec2::new(1.0, 0.0));
        assert!((uv - Vec2::new(0.5, -2.0)).length() < 1e-5, "{uv}");
    }

    /// A model with one base-colour texture `texture.png` of `size`² texels of `rgb`, drawn
    /// by its one triangle.
    fn textured_model(dir: &std::path::Path, size: u32, rgb: [u8; 3]) -> std::path::PathBuf {
        let [r, g, b] = rgb;
        image::RgbImage::from_pixel(size, size, image::Rgb([r, g, b]))
            .save(dir.join("texture.png"))
            .expect("writes the PNG");
        let positions: Vec<u8> = [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        std::fs::write(dir.join("triangle.bin"), &positions).expect("writes the buffer");
        let gltf = serde_json::json!({
            "asset": {"version": "2.0"},
            "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "material": 0}]}],
            "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
            "textures": [{"source": 0}],
            "images": [{"uri": "texture.png"}],
            "buffers": [{"uri": "triangle.bin", "byteLength": 36}],
            "bufferViews": [{"buffer": 0, "byteLength": 36}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]}]
        });
        let path = dir.join("triangle.gltf");
        std::fs::write(&path, gltf.to_string()).expect("writes the model");
        path
    }

    /// A second load of an unchanged model keeps the first's decoded images (the same memory,
    /// not a copy); a changed image file, another budget or another strictness decodes again.
    #[test]
    fn unchanged_textures_are_kept_from_an_earlier_load() {
        let dir = tempfile::tempdir().expect("a temporary folder");
        let model = textured_model(dir.path(), 4, [200, 40, 40]);
        let load = |previous: Option<TextureSet>, budget: usize, strict: bool| {
            let scene = Scene::load(&model).expect("loads");
            let mut warnings = Vec::new();
            let set = TextureSet::load_reusing(&scene, budget, strict, &mut warnings, previous)
                .expect("decodes");
            (set, scene)
        };
        let image = |set: &TextureSet| set.images[0].clone().expect("image 0 decoded");
        let (first, _) = load(None, usize::MAX, false);
        assert!(!first.reused());
        let (second, _) = load(Some(first.clone()), usize::MAX, false);
        assert!(second.reused());
        assert!(Arc::ptr_eq(&image(&first), &image(&second)));
        // Kept again from a kept set.
        let (third, _) = load(Some(second), usize::MAX, false);
        assert!(third.reused() && Arc::ptr_eq(&image(&first), &image(&third)));
        for (budget, strict) in [(1 << 20, false), (usize::MAX, true)] {
            let (other, _) = load(Some(first.clone()), budget, strict);
            assert!(!other.reused(), "budget {budget}, strict {strict}");
        }
        // The texture rewritten (another size, so another length whatever the clock says).
        textured_model(dir.path(), 8, [10, 220, 10]);
        let (changed, scene) = load(Some(first), usize::MAX, false);
        assert!(!changed.reused());
        assert_eq!(image(&changed).size(), (8, 8));
        let sampler = &scene.textures[0].sampler;
        let green = image(&changed).sample(Vec2::splat(0.5), 0.0, sampler, false);
        assert_eq!((green.x * 255.0).round(), 10.0);
    }

    /// Images handed over as pixels are never taken for an earlier load's: their identity is
    /// not a file's.
    #[test]
    fn textures_given_as_pixels_are_decoded_every_time() {
        let mut scene = Scene::empty("arrays");
        scene
            .add_texture(2, 2, vec![7; 16], Sampler::default(), None)
            .expect("a 2x2 texture");
        let mut warnings = Vec::new();
        let first = TextureSet::load_reusing(&scene, usize::MAX, false, &mut warnings, None)
            .expect("decodes");
        assert!(first.inputs.is_none());
        let second =
            TextureSet::load_reusing(&scene, usize::MAX, false, &mut warnings, Some(first))
                .expect("decodes");
        assert!(!second.reused());
    }
}
