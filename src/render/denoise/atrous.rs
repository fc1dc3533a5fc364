//! The built-in denoiser: an edge-avoiding à-trous wavelet filter (Dammertz, Sewtz, Hanika and
//! Lensch, "Edge-Avoiding À-Trous Wavelet Transform for fast Global Illumination Filtering",
//! HPG 2010) with the edge-stopping functions of SVGF (Schied et al., "Spatiotemporal
//! Variance-Guided Filtering", HPG 2017), without SVGF's temporal part: one image, no history.
//!
//! 1. **Demodulate.** What the camera saw emitted ([`Guides::emission`], when the guides have
//!    it) is set apart: it has no noise of its own, and the albedo guide knows nothing of its
//!    detail. The rest of the film is divided by the albedo guide, channel by channel, so what
//!    is filtered is the illumination, smooth across textures; multiplying back afterwards
//!    keeps texture and material edges as sharp as the (noise-free, anti-aliased) guide.
//! 2. **Filter** [`ITERATIONS`] times with the 5x5 B3-spline kernel, its taps 2^i pixels apart
//!    in iteration i (1, 2, 4, 8: 61 x 61 pixels reached for 25 taps a pass). Each tap's weight
//!    is the kernel's times four edge-stopping weights against the centre pixel: normals
//!    (cosine to the power [`NORMAL_POWER`]), depth (relative to the depth gradient, so
//!    slanted planes pass and silhouettes stop), albedo ([`ALBEDO_SIGMA`]), and illumination
//!    luminance (relative to the
//!    centre's noise: [`LUMINANCE_SIGMA`] standard errors, more where the pixels took fewer than
//!    4 samples ([`luminance_sigma`]), from the pixel loop's sample
//!    variance, itself blurred 3x3 and carried through the passes as the filtered value's
//!    variance). Where the noise is low the filter keeps detail; where it is high it averages.
//! 3. **Mend** the mixed pixels (`edges.rs`): where a pixel's samples met two surfaces,
//!    its guides match neither side and step 2 leaves it its noise; it takes the filtered
//!    light of the two neighbours its guides are a mix of, in that mix's proportion.
//! 4. **Remodulate** by the albedo, and add the emission back.
//!
//! At one sample a pixel no pixel has a variance of its own; it is then estimated from the
//! spread of the illumination over the 7x7 pixels around each on the same surface.
//!
//! Pixels nothing covers (alpha 0) and pixels whose first ray met no surface (zero normal: the
//! background, a visible environment) are neither filtered nor mixed into their neighbours.
//!
//! The measurements quoted at the constants below were taken with the pixel loop's earlier
//! independent random samples, before the Owen-scrambled Sobol sampler; docs/denoising.md has
//! the current ones.
//!
//! Deterministic: every output pixel is computed alone from the previous pass, its taps summed
//! in a fixed order, rows in parallel (rayon); the same bytes for any thread count.

use super::Guides;
use crate::color::luminance;
use crate::render::Image;
use glam::Vec3;
use rayon::prelude::*;

/// Filter passes. Four reach 30 pixels each way (taps 1, 2, 4, 8 apart, two a side). On the
/// Cornell box at 320x240 and 4 spp, mean FLIP against a 1,024-spp reference was 0.080 with
/// three passes, 0.080 with four, 0.084 with six (σl = 8); the wider passes mix across
/// shadows more than they remove noise. Dammertz et al. use five.
pub const ITERATIONS: u32 = 4;

/// The B3-spline kernel's weights by distance in taps, 0, 1, 2: (1, 4, 6, 4, 1) / 16.
pub(super) const KERNEL: [f32; 3] = [3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// The 3x3 Gaussian that blurs the variance before it scales the luminance weight (SVGF):
/// weights by distance 0 and 1 along each axis.
pub(super) const VARIANCE_BLUR: [f32; 2] = [1.0 / 2.0, 1.0 / 4.0];

/// Exponent of the normal weight max(0, n_p·n_q)^128 (SVGF's σn): 10° apart weigh 0.14,
/// 20° apart 4e-4, so walls meeting at a corner do not mix.
pub const NORMAL_POWER: u32 = 128;

/// Depth weight exp(-|z_p - z_q| / (σz · |∇z · offset|)) with σz = 1 (SVGF): a neighbour on
/// the centre's plane differs by about the gradient times the offset and weighs e^-1.
pub(super) const DEPTH_SIGMA: f32 = 1.0;

/// Depth tolerance beside the gradient, relative to the centre's depth: 1% of the distance,
/// so a plane seen face on (zero gradient) is not cut by rounding.
pub(super) const DEPTH_RELATIVE: f32 = 0.01;

/// Luminance weight exp(-|l_p - l_q| / (σl · standard error)) with σl = 8 (SVGF has 4) where
/// each pixel's error was estimated from at least 4 samples ([`luminance_sigma`] for fewer). A
/// trade, measured with the default render (Sobol samples, about 4 a pixel, noise target 1)
/// against each image's own converged one: at 4 the standard error of 4 samples is itself so
/// noisy that clumps of noise stopped the filter and stayed as a mottle on smooth walls. At 8
/// the bundled Cornell box (1024x768) went from mean FLIP 0.077 to 0.059 against its 256-spp
/// image, and over the 28 shared models at 640x480 the median from 0.0087 to 0.0084 and the
/// worst from 0.0255 to 0.0240; where lighting detail the guides do not show matters it blurs
/// some: LightsPunctualLamp's hard shadows 0.0142 -> 0.0157. 16 blurred those further (0.0176)
/// for little more on the walls; growing σl pass by pass instead (×2 each pass from 6) lost
/// more on DamagedHelmet (0.0216 against 0.0176).
pub const LUMINANCE_SIGMA: f32 = 8.0;

/// σl for an image whose pixels took at least `samples` samples: [`LUMINANCE_SIGMA`] from 4
/// up, widened as 3 / (n - 1) below it, to 24 at 2 samples. The standard error a pixel
/// estimates from n samples has n - 1 degrees of freedom: from 2 samples it falls below a
/// seventh of the true one a tenth of the time (from 4, below 0.44 of it), and the clumps of
/// such pixels, which believe themselves exact, survive a narrow tolerance. Measured with the
/// default render at 2 samples a pixel ([`crate::render::DENOISED_BATCH`]) against each
/// image's converged one: the bundled box (1024x768) at mean FLIP 0.079 with σl 8, 0.062 with
/// 16, **0.057 with 24**, 0.055 with 32; the 28 shared models at 640x480 hardly moved (median
/// 0.0114-0.0113, worst 0.0295-0.0294), while lighting detail the guides do not show blurs a
/// little more the wider σl is (LightsPunctualLamp 0.0195, 0.0207, 0.0216). At 4 samples, 24
/// instead of 8 blurred more than it smoothed (a 160x120 box at 4 spp, mean FLIP 0.107 ->
/// 0.120). One sample a pixel (no spread of its own: the spatial estimate over 49 pixels)
/// keeps [`LUMINANCE_SIGMA`].
pub fn luminance_sigma(samples: u32) -> f32 {
    match samples {
        2 | 3 => LUMINANCE_SIGMA * 3.0 / (samples - 1) as f32,
        _ => LUMINANCE_SIGMA,
    }
}

/// 1 / (σl · standard error) of a pixel whose variance, blurred, is `blurred_variance`: the
/// luminance weight's scale, computed once per pixel and pass for both the eight-lane pass and
/// the scalar reference.
pub(super) fn luminance_scale(blurred_variance: f32, sigma: f32) -> f32 {
    1.0 / (sigma * blurred_variance.max(0.0).sqrt()).max(MIN_LUMINANCE_SIGMA)
}

/// The least albedo a channel is divided by: black or near-black surfaces (and emissive ones
/// seen without albedo) would otherwise blow their illumination up without bound. A floor,
/// not a switch: dividing some pixels by their albedo and others by 1 put their illumination
/// on different scales, and mixing them painted red streaks on DamagedHelmet's dark parts.
const MIN_ALBEDO: f32 = 0.02;

/// What the illumination of a pixel of albedo guide `albedo` is divided by, channel by
/// channel (and multiplied by again after the passes).
#[inline(always)]
pub(super) fn divisor(albedo: Vec3) -> Vec3 {
    albedo.max(Vec3::splat(MIN_ALBEDO))
}

/// Albedo weight exp(-max channel |a_p - a_q| / σa): neighbours whose albedo differs by 0.03
/// weigh e^-1. Demodulation alone keeps albedo edges sharp where the light is diffuse, but
/// not where it is not (a dielectric's white highlight divided by a red albedo); on
/// DamagedHelmet at 8 spp mean FLIP was 0.0135 without this weight, 0.0119 with σa = 0.03 and
/// 0.0122 with 0.1, the Cornell box's unchanged.
pub const ALBEDO_SIGMA: f32 = 0.03;

/// Visibility weight exp(-|v_p - v_q| / σv) on the punctual lights' visibility guide
/// ([`super::Guides::visibility`]): a pixel in a hard shadow and one beside it in the light
/// differ by 1 and weigh e^-(1/σv), so the filter does not smear the edge; pixels of a
/// penumbra, whose samples saw the light in part, mix with neighbours of about the same share.
pub const VISIBILITY_SIGMA: f32 = 0.1;

/// At one sample a pixel, the noise is estimated over the (2 · 3 + 1)² = 49 pixels around each
/// (SVGF's 7x7 window for pixels without history).
const SPATIAL_RADIUS: isize = 3;

/// Neighbours whose normals are within 25° (cosine 0.9) count as the same surface for the
/// spatial noise estimate.
const SAME_SURFACE_COSINE: f32 = 0.9;

/// Luminance tolerance where the variance is 0 (one sample, or every sample equal): the
/// filter then mixes only neighbours equal to within this, in linear radiance.
pub(super) const MIN_LUMINANCE_SIGMA: f32 = 1e-4;

/// Taps whose normal weight is below this are skipped: against the centre tap's own weight
/// (at least 1/16 of the kernel's, times 1) they would change the result by less than f32
/// resolves. Most of a silhouette's or a corner's taps end here, before any exponential.
pub(super) const MIN_NORMAL_WEIGHT: f32 = 1e-8;

/// Taps whose edge-stopping exponent is this or more (weight e^-18 = 1.5e-8) are skipped,
/// for the same reason.
pub(super) const MAX_EXPONENT: f32 = 18.0;

/// e^-x for x in [0, [`MAX_EXPONENT`]] (below 0 as 0, above it as it), to about 1e-6 relative:
/// 2^(-x·log2 e) split into an integer power (the exponent bits) and a fraction within 1/2 (a
/// degree-6 polynomial). The filter's
/// hundred weights a pixel and pass spent most of their time in libm's `expf`; this is
/// several times cheaper and deterministic on every platform (no libm).
#[inline(always)]
// `clamp` would pass a NaN through, and the unchecked conversion below must never see one.
#[allow(clippy::manual_clamp)]
pub(super) fn exp_negative(x: f32) -> f32 {
    // NaN and values out of the range count as its ends (`max` returns 0 for NaN).
    let y = -x.max(0.0).min(MAX_EXPONENT) * std::f32::consts::LOG2_E;
    // Rounded to the nearest integer by a truncating conversion of a number in [0.5, 26.5]
    // (one instruction, where `round` is a libm call on baseline x86-64; the saturating `as`
    // would add range checks that keep the filter's eight lanes from running as one).
    // SAFETY: 0.5 - y is finite and within i32's range (y is in [-26, 0]).
    let negated = unsafe { (0.5 - y).to_int_unchecked::<i32>() };
    let whole = -negated as f32;
    let f = y - whole;
    // 2^f on [-1/2, 1/2]: Taylor series of e^(f ln 2), Horner form.
    const L: f32 = std::f32::consts::LN_2;
    let p = 1.0
        + f * (L + f
            * (L * L / 2.0
                + f * (L * L * L / 6.0
                    + f * (L * L * L * L / 24.0
                        + f * (L * L * L * L * L / 120.0 + f * (L * L * L * L * L * L / 720.0))))));
    // `whole` is in [-26, 0]: a normal float's exponent.
    p * f32::from_bits(((127 - negated) as u32) << 23)
}

/// `facing` to the power [`NORMAL_POWER`] (128) by seven squarings: `powi` with a constant
/// exponent is a loop in a runtime library call on some targets.
#[inline(always)]
pub(super) fn pow_normal(facing: f32) -> f32 {
    const _: () = assert!(NORMAL_POWER == 128);
    let mut p = facing;
    for _ in 0..7 {
        p *= p;
    }
    p
}

/// What every pass reads of a pixel besides its illumination and variance.
#[derive(Clone, Copy)]
pub(super) struct Pixel {
    /// Whether the pixel is filtered: covered, and its first ray met a surface.
    pub(super) surface: bool,
    /// Unit normal (zero off surfaces).
    pub(super) normal: Vec3,
    /// First-hit distance.
    pub(super) depth: f32,
    /// Albedo guide.
    pub(super) albedo: Vec3,
    /// Depth change to the next pixel along x and y (the smaller one-sided difference, so a
    /// silhouette beside the pixel does not count).
    pub(super) gradient: (f32, f32),
    /// Punctual-light visibility guide (1 without one).
    pub(super) visibility: f32,
}

/// Denoises `image` in place with the built-in filter. Preconditions (checked by
/// [`super::denoise`]): `guides` and `image.variance` are of the image's size.
///
/// The guides are taken, not borrowed: each is dropped once copied into the planes the passes
/// read (at 4K the normal, depth and visibility are 166 MB, the albedo 100 MB more), and only
/// the emission, added back at the end, is kept through the passes.
pub fn filter(image: &mut Image, guides: Guides) {
    let (width, height) = (image.width as usize, image.height as usize);
    if width == 0 || height == 0 {
        return;
    }
    let Guides {
        albedo,
        normal,
        depth,
        visibility,
        emission: emitted,
        ..
    } = guides;
    // What the camera saw emitted: set apart, added back unfiltered.
    let emission = |i: usize| emitted.get(i).copied().map_or(Vec3::ZERO, sanitize);
    let (planes, mut lit, mixes) = {
        // What albedo divides each channel by (computed again where it multiplies back
        // rather than kept through the passes: at 4K each float a pixel is 33 MB).
        let divisor = |i: usize| divisor(albedo[i]);
        let illumination = |i: usize| {
            (sanitize(image.pixels[i].truncate()) - emission(i)).max(Vec3::ZERO) / divisor(i)
        };
        // Luminance variance of the illumination: the film's, scaled as the division scales it.
        let variance = |i: usize| {
            let v = image.variance[i];
            (if v.is_finite() { v } else { 0.0 }) / luminance(divisor(i)).powi(2)
        };
        let geometry = Geometry {
            normal: &normal,
            depth: &depth,
            albedo: &albedo,
            visibility: &visibility,
        };
        let count = width * height;
        // One sample a pixel (or nothing noisy): no pixel knows its noise, so its neighbours
        // tell.
        if (0..count).all(|i| variance(i) == 0.0) {
            let pixel = geometry.of(image);
            let pixels: Vec<Pixel> = (0..count).into_par_iter().map(&pixel).collect();
            let illumination: Vec<Vec3> = (0..count).map(illumination).collect();
            let variance = spatial_variance(&illumination, &pixels, width, height);
            (
                super::lanes::GuidePlanes::new(width, height, |i| pixels[i]),
                super::lanes::Lit::new(width, height, |i| (illumination[i], variance[i])),
                Vec::new(),
            )
        } else {
            // Straight from each pixel's guides into the planes, which the passes read; the
            // guides they came from are dropped before the illumination's planes are made.
            let planes = super::lanes::GuidePlanes::new(width, height, geometry.of(image));
            let mixes = super::edges::mixed_pixels(&planes, &normal);
            drop((normal, depth, visibility));
            let lit = super::lanes::Lit::new(width, height, |i| (illumination(i), variance(i)));
            (planes, lit, mixes)
        }
    };
    // The planes hold it, bit for bit, where the result needs it (surface pixels).
    drop(albedo);
    let sigma = luminance_sigma(image.samples);
    // Two sets of planes, read and written in turn: the passes allocate nothing.
    let mut next = super::lanes::Lit::zeros(width, height);
    let mut scales = vec![0.0f32; width * height];
    // The mixed pixels' luminance scales of the first pass (their own noise), for the mending.
    let mut mix_scales = Vec::new();
    for pass in 0..ITERATIONS {
        let step = 1usize << pass;
        super::lanes::luminance_scales(&planes, &lit, sigma, &mut scales);
        if pass == 0 {
            mix_scales = mixes.iter().map(|m| scales[m.pixel]).collect();
        }
        super::lanes::pass(&planes, step, &lit, &scales, &mut next);
        std::mem::swap(&mut lit, &mut next);
    }
    drop((next, scales));
    super::edges::mend(&planes, &mut lit, &mixes, &mix_scales);
    for (i, pixel) in image.pixels.iter_mut().enumerate() {
        if planes.is_surface(i) {
            let rgb = (lit.illumination(width, i) * divisor(planes.albedo(i))).max(Vec3::ZERO)
                + emission(i);
            *pixel = rgb.extend(pixel.w);
        }
    }
}

/// Non-finite values (none are expected) as 0, so that one cannot spread.
fn sanitize(v: Vec3) -> Vec3 {
    Vec3::select(v.is_finite_mask(), v, Vec3::ZERO)
}

/// The guides that [`Geometry::of`] turns into each pixel's [`Pixel`].
#[derive(Clone, Copy)]
struct Geometry<'a> {
    normal: &'a [Vec3],
    depth: &'a [f32],
    albedo: &'a [Vec3],
    /// Empty without a visibility guide.
    visibility: &'a [f32],
}

impl<'a> Geometry<'a> {
    /// The unit normal, depth and depth gradients of pixel `i` (row-major) of `image`.
    fn of(self, image: &'a Image) -> impl Fn(usize) -> Pixel + Sync + 'a {
        let guides = self;
        let (width, height) = (image.width as usize, image.height as usize);
        let surface = move |i: usize| {
            image.pixels[i].w > 0.0 && guides.normal[i] != Vec3::ZERO && guides.depth[i] > 0.0
        };
        // The smaller one-sided depth difference at `i` to its neighbours `before` and `after`
        // (infinite when neither is on a surface).
        let one_sided = move |i: usize, before: Option<usize>, after: Option<usize>| {
            let side = |j: Option<usize>| match j {
                Some(j) if surface(j) => (guides.depth[j] - guides.depth[i]).abs(),
                _ => f32::INFINITY,
            };
            side(before).min(side(after))
        };
        move |i| {
            let (x, y) = (i % width, i / width);
            if !surface(i) {
                return Pixel {
                    surface: false,
                    normal: Vec3::ZERO,
                    depth: 0.0,
                    albedo: Vec3::ZERO,
                    gradient: (0.0, 0.0),
                    visibility: 1.0,
                };
            }
            let gx = one_sided(i, (x > 0).then(|| i - 1), (x + 1 < width).then_some(i + 1));
            let gy = one_sided(
                i,
                (y > 0).then(|| i - width),
                (y + 1 < height).then_some(i + width),
            );
            let finite = |g: f32| if g.is_finite() { g } else { 0.0 };
            Pixel {
                surface: true,
                normal: guides.normal[i].normalize_or_zero(),
                depth: guides.depth[i],
                albedo: guides.albedo[i],
                gradient: (finite(gx), finite(gy)),
                visibility: guides.visibility.get(i).copied().unwrap_or(1.0),
            }
        }
    }
}

/// The variance of the illumination's luminance over each surface pixel's neighbours within
/// [`SPATIAL_RADIUS`] on the same surface (normals within [`SAME_SURFACE_COSINE`], albedo
/// within 3 [`ALBEDO_SIGMA`]): the noise of one-sample pixels, which have no spread of their
/// own (SVGF estimates it so for pixels without history). On a smooth surface that is the
/// noise; across lighting detail it counts the detail too, so a noise-free image loses some.
fn spatial_variance(
    illumination: &[Vec3],
    pixels: &[Pixel],
    width: usize,
    height: usize,
) -> Vec<f32> {
    (0..width * height)
        .into_par_iter()
        .map(|i| {
            let centre = &pixels[i];
            if !centre.surface {
                return 0.0;
            }
            let (x, y) = ((i % width) as isize, (i / width) as isize);
            let (mut sum, mut squares, mut count) = (0.0f64, 0.0f64, 0u32);
            for qy in (y - SPATIAL_RADIUS).max(0)..(y + SPATIAL_RADIUS + 1).min(height as isize) {
                for qx in (x - SPATIAL_RADIUS).max(0)..(x + SPATIAL_RADIUS + 1).min(width as isize)
                {
                    let q = qy as usize * width + qx as usize;
                    let neighbour = &pixels[q];
                    if neighbour.surface
                        && centre.normal.dot(neighbour.normal) >= SAME_SURFACE_COSINE
                        && (centre.albedo - neighbour.albedo).abs().max_element()
                            <= 3.0 * ALBEDO_SIGMA
                    {
                        let l = f64::from(luminance(illumination[q]));
                        sum += l;
                        squares += l * l;
                        count += 1;
                    }
                }
            }
            // The centre always counts, so `count` >= 1.
            let n = f64::from(count);
            ((squares / n - (sum / n).powi(2)).max(0.0)) as f32
        })
        .collect()
}

/// One output pixel of a pass, as [`super::lanes::pass`] computes it eight at a time (the
/// reference its tests compare with): the weighted mean of the 5x5 taps `step` apart around (`x`,
/// `y`), and its variance (the taps' variances weighted by the squared normalised weights).
#[cfg(test)]
pub(super) fn tap_sum(
    (x, y): (usize, usize),
    step: usize,
    (width, height): (usize, usize),
    pixels: &[Pixel],
    (illumination, luminances): (&[Vec3], &[f32]),
    variance: &[f32],
    luminance_scale: f32,
) -> (Vec3, f32) {
    let i = y * width + x;
    let centre = pixels[i];
    if !centre.surface {
        return (illumination[i], variance[i]);
    }
    let centre_luminance = luminances[i];
    let depth_tolerance = DEPTH_RELATIVE * centre.depth;
    // 1 / the depth change expected at tap offset (|tx|, |ty|): the centre's plane, plus the
    // tolerance. Nine reciprocals instead of 25 divisions.
    let mut depth_scale = [[0.0f32; 3]; 3];
    for (ay, row) in depth_scale.iter_mut().enumerate() {
        for (ax, scale) in row.iter_mut().enumerate() {
            let expected = DEPTH_SIGMA
                * (centre.gradient.0 * (ax * step) as f32 + centre.gradient.1 * (ay * step) as f32)
                + depth_tolerance;
            *scale = 1.0 / expected;
        }
    }
    let (mut sum, mut sum_variance, mut weights) = (Vec3::ZERO, 0.0f32, 0.0f32);
    for ty in -2isize..=2 {
        let qy = y as isize + ty * step as isize;
        if qy < 0 || qy >= height as isize {
            continue;
        }
        for tx in -2isize..=2 {
            let qx = x as isize + tx * step as isize;
            if qx < 0 || qx >= width as isize {
                continue;
            }
            let q = qy as usize * width + qx as usize;
            let neighbour = &pixels[q];
            if !neighbour.surface {
                continue;
            }
            let facing = centre.normal.dot(neighbour.normal).max(0.0);
            let normal_weight = pow_normal(facing);
            if normal_weight < MIN_NORMAL_WEIGHT {
                // Another surface: its weight would vanish against the centre's own.
                continue;
            }
            let depth_term = (centre.depth - neighbour.depth).abs()
                * depth_scale[ty.unsigned_abs()][tx.unsigned_abs()];
            let luminance_term = (centre_luminance - luminances[q]).abs() * luminance_scale;
            let albedo_term =
                (centre.albedo - neighbour.albedo).abs().max_element() * (1.0 / ALBEDO_SIGMA);
            let visibility_term =
                (centre.visibility - neighbour.visibility).abs() * (1.0 / VISIBILITY_SIGMA);
            let exponent = depth_term + luminance_term + albedo_term + visibility_term;
            if exponent >= MAX_EXPONENT {
                continue;
            }
            let w = KERNEL[tx.unsigned_abs()]
                * KERNEL[ty.unsigned_abs()]
                * normal_weight
                * exp_negative(exponent);
            sum += w * illumination[q];
            sum_variance += w * w * variance[q];
            weights += w;
        }
    }
    // The centre tap weighs KERNEL[0]² > 0 (its own normal, depth and luminance match), so
    // `weights` is positive, unless the normal guide averaged to nothing (opposite faces
    // within one pixel): such a pixel is left as it is.
    if weights <= 0.0 {
        return (illumination[i], variance[i]);
    }
    (sum / weights, sum_variance / (weights * weights))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fast_exponential_matches_libm() {
        let mut x = 0.0f32;
        while x < MAX_EXPONENT {
            let (fast, exact) = (exp_negative(x), (-x).exp());
            assert!(
                (fast - exact).abs() <= 2e-6 * exact,
                "e^-{x}: {fast} against {exact}"
            );
            x += 0.001;
        }
    }

    /// Inputs outside [0, MAX_EXPONENT] count as its ends, NaN as 0: the unchecked conversion
    /// inside only ever sees a finite number in range, whatever a pixel held (an infinite or
    /// NaN radiance gives such exponents).
    #[test]
    fn the_fast_exponential_clamps_what_is_out_of_range() {
        let (one, floor) = (exp_negative(0.0), exp_negative(MAX_EXPONENT));
        for x in [f32::NAN, -f32::NAN, f32::NEG_INFINITY, -1.0, -1e30, -0.0] {
            assert_eq!(exp_negative(x).to_bits(), one.to_bits(), "{x}");
        }
        for x in [f32::INFINITY, 1e30, MAX_EXPONENT + 1.0, f32::MAX] {
            assert_eq!(exp_negative(x).to_bits(), floor.to_bits(), "{x}");
        }
        assert!((one - 1.0).abs() < 1e-6 && floor > 0.0 && floor < 2e-8);
    }
    use crate::sampling::Rng;
    use glam::Vec4;

    /// A `width` x `height` plane facing the camera at depth 2, white albedo, its left half
    /// `left` and its right half `right` in albedo.
    fn plane(width: u32, height: u32, left: Vec3, right: Vec3) -> Guides {
        let count = (width * height) as usize;
        Guides {
            width,
            height,
            albedo: (0..count)
                .map(|i| {
                    if (i as u32 % width) < width / 2 {
                        left
                    } else {
                        right
                    }
                })
                .collect(),
            normal: vec![Vec3::Z; count],
            depth: vec![2.0; count],
            visibility: Vec::new(),
            emission: Vec::new(),
            samples_per_pixel: 1,
        }
    }

    /// `truth` (per pixel) with noise of relative standard error `error`, and that variance.
    fn noisy(width: u32, height: u32, truth: impl Fn(usize) -> Vec3, error: f32) -> Image {
        let mut image = Image::new(width, height);
        let mut rng = Rng::new(7);
        for (i, (pixel, variance)) in image
            .pixels
            .iter_mut()
            .zip(image.variance.iter_mut())
            .enumerate()
        {
            let t = truth(i);
            // Uniform noise of standard deviation `error` · t: √3 · error wide each side.
            let n = (rng.next_f32() * 2.0 - 1.0) * 3f32.sqrt() * error;
            *pixel = (t * (1.0 + n)).extend(1.0);
            *variance = (error * luminance(t)).powi(2);
        }
        image
    }

    fn rmse(a: &Image, truth: impl Fn(usize) -> Vec3) -> f32 {
        let sum: f32 = a
            .pixels
            .iter()
            .enumerate()
            .map(|(i, p)| (p.truncate() - truth(i)).length_squared() / 3.0)
            .sum();
        (sum / a.pixels.len() as f32).sqrt()
    }

    /// Noise on a flat, evenly lit plane is removed: RMSE down to under a tenth.
    #[test]
    fn noise_on_a_plane_is_averaged_away() {
        let truth = |_| Vec3::splat(0.5);
        let guides = plane(64, 48, Vec3::ONE, Vec3::ONE);
        let mut image = noisy(64, 48, truth, 0.3);
        let before = rmse(&image, truth);
        filter(&mut image, guides);
        let after = rmse(&image, truth);
        assert!(after < 0.1 * before, "RMSE {before} -> {after}");
    }

    /// A NaN and an infinite pixel (and an infinite variance) in the image neither panic the
    /// filter nor spread: pixels more than one tap reach (30 pixels) away stay finite and close
    /// to the truth.
    #[test]
    fn non_finite_pixels_do_not_panic_or_spread() {
        let truth = |_| Vec3::splat(0.5);
        let guides = plane(96, 64, Vec3::ONE, Vec3::ONE);
        let mut image = noisy(96, 64, truth, 0.1);
        image.pixels[10 * 96 + 10] = Vec4::new(f32::NAN, 0.5, 0.5, 1.0);
        image.pixels[12 * 96 + 14] = Vec4::new(f32::INFINITY, 0.5, 0.5, 1.0);
        image.variance[12 * 96 + 14] = f32::INFINITY;
        filter(&mut image, guides);
        for y in 0..64 {
            for x in 50..96 {
                let p = image.pixels[y * 96 + x];
                assert!(
                    p.is_finite() && (p.truncate() - Vec3::splat(0.5)).abs().max_element() < 0.2,
                    "({x}, {y}): {p}"
                );
            }
        }
    }

    /// At one sample a pixel the film has no variance; the filter estimates it from the
    /// neighbours and still removes the noise: RMSE down to under a fifth.
    #[test]
    fn one_sample_images_take_their_noise_from_the_neighbours() {
        let truth = |_| Vec3::splat(0.5);
        let guides = plane(64, 48, Vec3::ONE, Vec3::ONE);
        let mut image = noisy(64, 48, truth, 0.3);
        image.variance.fill(0.0);
        let before = rmse(&image, truth);
        filter(&mut image, guides);
        let after = rmse(&image, truth);
        assert!(after < 0.2 * before, "RMSE {before} -> {after}");
    }

    /// An albedo edge (a red and a blue half under the same light) stays sharp, since the
    /// filter works on illumination and multiplies the albedo back: in the columns beside it
    /// every pixel keeps its side's hue (the other colour's channel to the own one as in the
    /// albedo, to within 2%), and the column's mean its side's value to within 3% (what noise
    /// is left), where a blur across the edge would be off by up to 44%.
    #[test]
    fn an_albedo_edge_stays_sharp() {
        let (red, blue) = (Vec3::new(0.8, 0.1, 0.1), Vec3::new(0.1, 0.1, 0.8));
        let guides = plane(64, 48, red, blue);
        let truth = |i: usize| guides.albedo[i] * 0.7;
        let mut image = noisy(64, 48, truth, 0.3);
        filter(&mut image, guides.clone());
        let ratio = |c: Vec3| c.x.min(c.z) / c.x.max(c.z);
        for x in [31usize, 32] {
            let mut column = Vec3::ZERO;
            for y in 0..48 {
                let i = y * 64 + x;
                let got = image.pixels[i].truncate();
                assert!(
                    (ratio(got) - ratio(truth(i))).abs() < 0.02 * ratio(truth(i)),
                    "pixel ({x}, {y}): {got} for {}",
                    truth(i)
                );
                column += got / 48.0;
            }
            let expected = truth(x);
            let relative = (column - expected).abs().max_element() / expected.max_element();
            assert!(relative < 0.03, "column {x}: {column} for {expected}");
        }
    }

    /// A shadow edge (illumination, not albedo: one albedo, two light levels of 0.1 and 1.0,
    /// noise of 5%) survives where the noise is small against it. From errors of 4 samples a
    /// pixel (σl 8) every pixel stays within 10% of its side. From 2 (σl 24) every pixel two or
    /// more columns from the edge stays within 5% of its side (3% when written), and the two
    /// columns beside it move less than a fifth of the step toward each other (each pixel;
    /// 12% when written). That one pixel is the wider σl's price: at 24 standard errors the
    /// lit side's tolerance (1.2) is above the step (0.9), and the dark column's variance,
    /// blurred 3x3, takes the lit one's.
    #[test]
    fn a_lighting_edge_with_little_noise_stays() {
        let guides = plane(64, 48, Vec3::ONE, Vec3::ONE);
        let truth = |i: usize| Vec3::splat(if i % 64 < 32 { 0.1 } else { 1.0 });
        for samples in [4, 2] {
            let mut image = noisy(64, 48, truth, 0.05);
            image.samples = samples;
            filter(&mut image, guides.clone());
            for y in 0..48 {
                for x in 0..64usize {
                    let i = y * 64 + x;
                    let (got, want) = (image.pixels[i].x, truth(i).x);
                    let tolerance = match (samples, x) {
                        (2, 31 | 32) => 0.2 * 0.9,
                        (2, _) => 0.05 * want,
                        _ => 0.1 * want,
                    };
                    assert!(
                        (got - want).abs() < tolerance,
                        "{samples} samples, pixel ({x}, {y}): {got} for {want}"
                    );
                }
            }
        }
    }

    /// A hard shadow's edge under heavy noise: the luminance weight alone lets the lit side
    /// bleed into the shadow, the punctual lights' visibility guide (0 in the shadow, 1 in
    /// the light) keeps the two apart: the columns beside the edge stay within 5% of their
    /// side's value on average (1.5% when written), where without the guide the shadow's last
    /// column is off by more than 50% (112%).
    #[test]
    fn the_visibility_guide_keeps_a_noisy_shadow_edge() {
        let truth = |i: usize| Vec3::splat(if i % 64 < 32 { 0.1 } else { 1.0 });
        let column_error = |image: &Image, x: usize| {
            let mean = (0..48).map(|y| image.pixels[y * 64 + x].x).sum::<f32>() / 48.0;
            (mean - truth(x).x).abs() / truth(x).x
        };
        let mut guides = plane(64, 48, Vec3::ONE, Vec3::ONE);
        let mut blind = noisy(64, 48, truth, 0.3);
        let mut guided = blind.clone();
        filter(&mut blind, guides.clone());
        guides.visibility = (0..64 * 48)
            .map(|i| if i % 64 < 32 { 0.0 } else { 1.0 })
            .collect();
        filter(&mut guided, guides);
        for x in [30usize, 31, 32, 33] {
            let error = column_error(&guided, x);
            assert!(error < 0.05, "column {x}: {error} off with the guide");
        }
        let error = column_error(&blind, 31);
        assert!(error > 0.5, "column 31: {error} off without the guide");
    }

    /// Emissive detail the albedo guide does not show (thin lines of light on a uniform,
    /// noisily lit surface, as on a display) comes back as it was when the guides set the
    /// emission apart: the lines stand 0.5 above the surface beside them within 0.02 (0.0002
    /// when written). Filtered with the rest they are smeared into their neighbours: less
    /// than half of that stays (0.165).
    #[test]
    fn emission_set_apart_keeps_its_detail() {
        let glow = |i: usize| Vec3::splat(if (i % 64).is_multiple_of(4) { 0.5 } else { 0.0 });
        let mut image = noisy(64, 48, |_| Vec3::splat(0.5), 0.3);
        for (i, p) in image.pixels.iter_mut().enumerate() {
            *p += glow(i).extend(0.0);
        }
        let mut guides = plane(64, 48, Vec3::ONE, Vec3::ONE);
        let mut blind = image.clone();
        filter(&mut blind, guides.clone());
        guides.emission = (0..64 * 48).map(glow).collect();
        filter(&mut image, guides);
        // Each line against the surface two columns on, over the rows and lines away from the
        // edges.
        let contrast = |image: &Image| {
            let (mut sum, mut count) = (0.0f32, 0u32);
            for y in 8..40 {
                for x in (8..56).step_by(4) {
                    sum += image.pixels[y * 64 + x].x - image.pixels[y * 64 + x + 2].x;
                    count += 1;
                }
            }
            sum / count as f32
        };
        let (apart, blind) = (contrast(&image), contrast(&blind));
        assert!(
            (apart - 0.5).abs() < 0.02,
            "lines {apart} above the surface"
        );
        assert!(
            blind < 0.25,
            "lines {blind} above the surface without the emission apart"
        );
    }

    /// Two walls meeting at a right angle along column 32 of a 64 x 48 image, seen at the
    /// default render's two samples a pixel: the left one (albedo 0.8) lit at 1, the right one
    /// (albedo 0.4) at 0.5. In the seam's column a pixel's two samples met the left wall
    /// (rows 0, 3, 6, ...), the right one (rows 2, 5, ...), or one each (rows 1, 4, ...): then
    /// its guides are the mix of both (the normals averaged, not renormalised) and its
    /// radiance the mean of the walls' (0.5, or `mixed`). Every pixel has noise of relative
    /// standard error `error`.
    fn corner(mixed: f32, error: f32) -> (Image, Guides, impl Fn(usize) -> Vec3) {
        use std::cmp::Ordering;
        let (width, height) = (64u32, 48u32);
        let count = (width * height) as usize;
        let side = |i: usize| match (i % 64).cmp(&32) {
            Ordering::Equal => [Ordering::Less, Ordering::Equal, Ordering::Greater][i / 64 % 3],
            other => other,
        };
        let (left, right) = (Vec3::new(1.0, 0.0, 1.0), Vec3::new(-1.0, 0.0, 1.0));
        let pick = |i: usize, l: Vec3, r: Vec3| match side(i) {
            Ordering::Less => l,
            Ordering::Greater => r,
            Ordering::Equal => (l + r) / 2.0,
        };
        let guides = Guides {
            width,
            height,
            albedo: (0..count)
                .map(|i| pick(i, Vec3::splat(0.8), Vec3::splat(0.4)))
                .collect(),
            normal: (0..count)
                .map(|i| pick(i, left.normalize(), right.normalize()))
                .collect(),
            depth: vec![2.0; count],
            visibility: Vec::new(),
            emission: Vec::new(),
            samples_per_pixel: 2,
        };
        let truth = move |i: usize| match side(i) {
            Ordering::Less => Vec3::splat(0.8),
            Ordering::Greater => Vec3::splat(0.2),
            Ordering::Equal => Vec3::splat(mixed),
        };
        let mut image = noisy(width, height, truth, error);
        image.samples = 2;
        (image, guides, truth)
    }

    /// The mixed pixels [`super::super::edges::mixed_pixels`] finds in `guides` over `image`.
    fn mixes(image: &Image, guides: &Guides) -> Vec<(usize, f32)> {
        let geometry = Geometry {
            normal: &guides.normal,
            depth: &guides.depth,
            albedo: &guides.albedo,
            visibility: &guides.visibility,
        };
        let planes = super::super::lanes::GuidePlanes::new(64, 48, geometry.of(image));
        super::super::edges::mixed_pixels(&planes, &guides.normal)
            .iter()
            .map(|m| (m.pixel, m.t))
            .collect()
    }

    /// The seam's mixed pixels match neither wall, so the passes leave them their noise (0.26
    /// off at worst when written); they take the walls' filtered light in the proportion
    /// their guides show (half each), their radiance the mix of the walls' (0.5), not the
    /// walls' mixed light times the mixed albedo (0.45): every one within 0.03 of 0.5 (0.003
    /// when written). They are the only mixed pixels found, each half of either wall.
    #[test]
    fn a_seams_mixed_pixels_take_the_light_of_their_two_walls() {
        let (mut image, guides, _) = corner(0.5, 0.3);
        let found = mixes(&image, &guides);
        let seam: Vec<usize> = (0..48)
            .filter(|y| y % 3 == 1)
            .map(|y| y * 64 + 32)
            .collect();
        assert_eq!(found.iter().map(|m| m.0).collect::<Vec<_>>(), seam);
        assert!(found.iter().all(|m| (m.1 - 0.5).abs() < 0.01), "{found:?}");
        let worst = |image: &Image| {
            seam.iter()
                .map(|&i| (image.pixels[i].x - 0.5).abs())
                .fold(0.0f32, f32::max)
        };
        let before = worst(&image);
        filter(&mut image, guides);
        let after = worst(&image);
        assert!(before > 0.2, "the seam's noise before: {before}");
        assert!(after < 0.03, "the seam's pixels {after} off 0.5");
    }

    /// Where the seam's samples agree (1% noise), its own light stands even when the walls'
    /// mix says otherwise (0.7 against 0.5): every mixed pixel within 0.02 of 0.7.
    #[test]
    fn a_converged_seam_keeps_its_own_light() {
        let (mut image, guides, _) = corner(0.7, 0.01);
        filter(&mut image, guides);
        for y in (1..48).step_by(3) {
            let got = image.pixels[y * 64 + 32].x;
            assert!((got - 0.7).abs() < 0.02, "seam pixel {y}: {got}");
        }
    }

    /// A groove where the seam was (its normal facing up, no mix of the walls') is no mixed
    /// pixel: nothing is found.
    #[test]
    fn a_groove_is_no_mix_of_its_neighbours() {
        let (image, mut guides, _) = corner(0.5, 0.3);
        for y in (1..48).step_by(3) {
            guides.normal[y * 64 + 32] = Vec3::Y;
        }
        assert_eq!(mixes(&image, &guides), []);
    }

    /// Two planes at a corner (normals 90° apart) do not mix, and neither do uncovered pixels
    /// or pixels that saw no surface: those are returned as they came.
    #[test]
    fn corners_and_the_background_are_kept_apart() {
        let mut guides = plane(32, 16, Vec3::ONE, Vec3::ONE);
        for (i, n) in guides.normal.iter_mut().enumerate() {
            if i % 32 >= 16 {
                *n = Vec3::X;
            }
        }
        let truth = |i: usize| Vec3::splat(if i % 32 < 16 { 0.2 } else { 0.9 });
        let mut image = noisy(32, 16, truth, 0.0);
        // A background pixel (no surface) and an uncovered one.
        guides.normal[5] = Vec3::ZERO;
        image.pixels[5] = Vec4::new(3.0, 3.0, 3.0, 1.0);
        image.pixels[6] = Vec4::ZERO;
        let before = image.clone();
        filter(&mut image, guides);
        for i in 0..image.pixels.len() {
            let expected = before.pixels[i];
            let got = image.pixels[i];
            assert!(
                (got - expected).abs().max_element() < 1e-5,
                "pixel {i}: {got} for {expected}"
            );
        }
    }
}
