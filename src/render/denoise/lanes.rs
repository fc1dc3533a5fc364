//! One pass of the à-trous filter ([`super::atrous`]) eight pixels of a row at a time.
//!
//! The scalar pass computed each output pixel alone, 25 taps of data-dependent branches; the
//! filter took 0.09 s of a 0.33 s default render at 640x480. Here a row is cut into chunks of
//! [`LANES`] neighbouring pixels whose taps are read from contiguous memory (the guides and
//! the illumination as planes, one array per component, each row padded by [`PAD_LEFT`] and
//! [`PAD_RIGHT`] columns of non-surface pixels, so a tap past the image's edge reads padding
//! instead of branching), and every skipped tap becomes a weight of zero. The compiler turns
//! the lane loops into SSE or, on x86-64-v3 CPUs ([`crate::cpu::has_v3`]), AVX2 instructions.
//!
//! The result is the scalar pass's, bit for bit: each lane does the scalar arithmetic in the
//! same order (no fused multiply-adds), and a tap of weight zero adds exactly nothing to the
//! sums. `tests` below hold the two to that on noisy images with edges and background.

use super::atrous::{
    exp_negative, luminance_scale, pow_normal, Pixel, ALBEDO_SIGMA, DEPTH_RELATIVE, DEPTH_SIGMA,
    ITERATIONS, KERNEL, MAX_EXPONENT, MIN_NORMAL_WEIGHT, VARIANCE_BLUR, VISIBILITY_SIGMA,
};
use crate::color::luminance;
use glam::Vec3;
use rayon::prelude::*;

/// Pixels computed together.
pub(super) const LANES: usize = 8;

/// Padding columns left of each row: the farthest tap of the last pass (two steps of
/// 2^(ITERATIONS - 1)).
const PAD_LEFT: usize = 2 << (ITERATIONS - 1);

/// Padding columns right of each row: the farthest tap, plus the lanes of a row's last chunk
/// that lie past its end.
const PAD_RIGHT: usize = PAD_LEFT + LANES;

/// `[f32; LANES]`, the values of one quantity in a chunk's lanes.
type Lanes = [f32; LANES];

/// A width x height image of values as rows padded by [`PAD_LEFT`] and [`PAD_RIGHT`] columns
/// of `fill`.
struct Plane {
    values: Vec<f32>,
}

impl Plane {
    /// The `LANES` values from padded column `column` of the row starting at `row`.
    #[inline(always)]
    fn lanes(&self, row: usize, column: usize) -> Lanes {
        let start = row + column;
        match self.values.get(start..start + LANES) {
            Some(slice) => {
                let mut out = [0.0; LANES];
                out.copy_from_slice(slice);
                out
            }
            // Unreachable: padding covers every tap (see PAD_LEFT, PAD_RIGHT).
            None => [0.0; LANES],
        }
    }
}

/// A plane's rows, `stride` values each, to fill in parallel (the padding stays zero).
fn rows(plane: &mut [f32], stride: usize) -> rayon::slice::ChunksMut<'_, f32> {
    plane.par_chunks_mut(stride)
}

/// The guides as planes: what a pass reads of each tap besides its illumination.
pub(super) struct GuidePlanes {
    width: usize,
    height: usize,
    /// 1 on surface pixels, 0 elsewhere (and in the padding).
    surface: Plane,
    normal: [Plane; 3],
    depth: Plane,
    albedo: [Plane; 3],
    gradient: [Plane; 2],
    visibility: Plane,
}

impl GuidePlanes {
    /// The planes of the `width` x `height` pixels that `pixel` gives (row-major index), each
    /// pixel computed once, rows in parallel.
    pub(super) fn new(
        width: usize,
        height: usize,
        pixel: impl Fn(usize) -> Pixel + Sync,
    ) -> GuidePlanes {
        let stride = width + PAD_LEFT + PAD_RIGHT;
        let mut planes: [Vec<f32>; 11] = std::array::from_fn(|_| vec![0.0f32; stride * height]);
        let [surface, nx, ny, nz, depth, ax, ay, az, gx, gy, visibility] = &mut planes;
        (
            (
                rows(surface, stride),
                rows(nx, stride),
                rows(ny, stride),
                rows(nz, stride),
            ),
            (
                rows(depth, stride),
                rows(ax, stride),
                rows(ay, stride),
                rows(az, stride),
            ),
            (rows(gx, stride), rows(gy, stride), rows(visibility, stride)),
        )
            .into_par_iter()
            .enumerate()
            .for_each(|(y, ((s, nx, ny, nz), (d, ax, ay, az), (gx, gy, v)))| {
                for x in 0..width {
                    let p = pixel(y * width + x);
                    let at = PAD_LEFT + x;
                    s[at] = if p.surface { 1.0 } else { 0.0 };
                    (nx[at], ny[at], nz[at]) = (p.normal.x, p.normal.y, p.normal.z);
                    d[at] = p.depth;
                    (ax[at], ay[at], az[at]) = (p.albedo.x, p.albedo.y, p.albedo.z);
                    (gx[at], gy[at]) = p.gradient;
                    v[at] = p.visibility;
                }
            });
        let [surface, nx, ny, nz, depth, ax, ay, az, gx, gy, visibility] =
            planes.map(|values| Plane { values });
        GuidePlanes {
            width,
            height,
            surface,
            normal: [nx, ny, nz],
            depth,
            albedo: [ax, ay, az],
            gradient: [gx, gy],
            visibility,
        }
    }

    fn stride(&self) -> usize {
        self.width + PAD_LEFT + PAD_RIGHT
    }

    /// Whether pixel `i` (row-major) is on a surface: what the filter changes.
    pub(super) fn is_surface(&self, i: usize) -> bool {
        self.surface.values[Lit::at(self.width, i)] != 0.0
    }

    /// The albedo guide of pixel `i` (row-major): the [`Pixel::albedo`] it was given.
    pub(super) fn albedo(&self, i: usize) -> Vec3 {
        let at = Lit::at(self.width, i);
        let [x, y, z] = &self.albedo;
        Vec3::new(x.values[at], y.values[at], z.values[at])
    }

    /// Pixel `i` (row-major) as it was given, bit for bit.
    pub(super) fn pixel(&self, i: usize) -> Pixel {
        self.pixel_at(i % self.width, i / self.width)
    }

    /// Pixel (`x`, `y`) as it was given, bit for bit.
    #[inline]
    pub(super) fn pixel_at(&self, x: usize, y: usize) -> Pixel {
        let at = y * self.stride() + PAD_LEFT + x;
        let [nx, ny, nz] = &self.normal;
        let [gx, gy] = &self.gradient;
        Pixel {
            surface: self.surface.values[at] != 0.0,
            normal: Vec3::new(nx.values[at], ny.values[at], nz.values[at]),
            depth: self.depth.values[at],
            albedo: Vec3::new(
                self.albedo[0].values[at],
                self.albedo[1].values[at],
                self.albedo[2].values[at],
            ),
            gradient: (gx.values[at], gy.values[at]),
            visibility: self.visibility.values[at],
        }
    }

    /// The image's width and height.
    pub(super) fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }
}

/// The illumination, its luminance and its variance as planes: what a pass reads of the
/// previous one, and writes for the next. The filter keeps two and swaps them: a pass neither
/// allocates nor converts between slices and planes (which, with the variance blur's own
/// buffers, took the Cornell OBJ's filter from 49 to 55 ms at 640x480, median of 9 runs).
pub(super) struct Lit {
    illumination: [Plane; 3],
    luminance: Plane,
    variance: Plane,
}

impl Lit {
    /// The planes of the illumination (and its luminance) and variance that `pixel` gives
    /// each of the `width` x `height` pixels (row-major index), each pixel computed once,
    /// rows in parallel: no slice of either needs to exist beside the planes.
    pub(super) fn new(
        width: usize,
        height: usize,
        pixel: impl Fn(usize) -> (Vec3, f32) + Sync,
    ) -> Lit {
        let stride = width + PAD_LEFT + PAD_RIGHT;
        let mut planes: [Vec<f32>; 5] = std::array::from_fn(|_| vec![0.0f32; stride * height]);
        let [x, y, z, lum, var] = &mut planes;
        (
            rows(x, stride),
            rows(y, stride),
            rows(z, stride),
            rows(lum, stride),
            rows(var, stride),
        )
            .into_par_iter()
            .enumerate()
            .for_each(|(row, (x, y, z, lum, var))| {
                for column in 0..width {
                    let (c, v) = pixel(row * width + column);
                    let at = PAD_LEFT + column;
                    (x[at], y[at], z[at]) = (c.x, c.y, c.z);
                    lum[at] = luminance(c);
                    var[at] = v;
                }
            });
        let [x, y, z, luminance, variance] = planes.map(|values| Plane { values });
        Lit {
            illumination: [x, y, z],
            luminance,
            variance,
        }
    }

    /// Planes of zeros, `width` x `height`: what a pass writes into.
    pub(super) fn zeros(width: usize, height: usize) -> Lit {
        let zeros = || Plane {
            values: vec![0.0; (width + PAD_LEFT + PAD_RIGHT) * height],
        };
        Lit {
            illumination: [zeros(), zeros(), zeros()],
            luminance: zeros(),
            variance: zeros(),
        }
    }

    /// Where pixel `i` of a `width`-wide image is in the planes.
    fn at(width: usize, i: usize) -> usize {
        (i / width) * (width + PAD_LEFT + PAD_RIGHT) + PAD_LEFT + i % width
    }

    /// The illumination of pixel `i` of a `width`-wide image.
    pub(super) fn illumination(&self, width: usize, i: usize) -> Vec3 {
        let at = Lit::at(width, i);
        let [x, y, z] = &self.illumination;
        Vec3::new(x.values[at], y.values[at], z.values[at])
    }

    /// The variance of pixel `i` of a `width`-wide image.
    #[cfg(test)]
    pub(super) fn variance(&self, width: usize, i: usize) -> f32 {
        self.variance.values[Lit::at(width, i)]
    }

    /// The luminance of pixel `i`'s illumination, as the passes compare it.
    pub(super) fn luminance(&self, width: usize, i: usize) -> f32 {
        self.luminance.values[Lit::at(width, i)]
    }

    /// Sets pixel `i`'s illumination (and its luminance) to `rgb`.
    pub(super) fn set_illumination(&mut self, width: usize, i: usize, rgb: Vec3) {
        let at = Lit::at(width, i);
        let [x, y, z] = &mut self.illumination;
        (x.values[at], y.values[at], z.values[at]) = (rgb.x, rgb.y, rgb.z);
        self.luminance.values[at] = luminance(rgb);
    }
}

/// Each pixel's luminance scale 1 / (σl · standard error) for a pass
/// ([`super::atrous::luminance_scale`] of `sigma`), from its variance in `lit` blurred by
/// [`super::atrous::VARIANCE_BLUR`] over its surface neighbours (a few samples' variance is
/// itself noisy, and one pixel's lucky zero must not freeze it), written to `scales`.
pub(super) fn luminance_scales(guides: &GuidePlanes, lit: &Lit, sigma: f32, scales: &mut [f32]) {
    let (width, height, stride) = (guides.width, guides.height, guides.stride());
    let (surface, variance) = (&guides.surface.values, &lit.variance.values);
    scales
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, scale) in row.iter_mut().enumerate() {
                let centre = y * stride + PAD_LEFT + x;
                let blurred = if surface[centre] == 0.0 {
                    variance[centre]
                } else {
                    let (mut sum, mut weights) = (0.0f32, 0.0f32);
                    for dy in -1isize..=1 {
                        let qy = y as isize + dy;
                        if qy < 0 || qy >= height as isize {
                            continue;
                        }
                        for dx in -1isize..=1 {
                            // Past the left or right edge: padding, no surface.
                            let q = (qy as usize * stride + PAD_LEFT + x).wrapping_add_signed(dx);
                            if surface[q] == 0.0 {
                                continue;
                            }
                            let w =
                                VARIANCE_BLUR[dx.unsigned_abs()] * VARIANCE_BLUR[dy.unsigned_abs()];
                            sum += w * variance[q];
                            weights += w;
                        }
                    }
                    sum / weights
                };
                *scale = luminance_scale(blurred, sigma);
            }
        });
}

/// One filter pass with taps `step` apart: the new illumination, luminance and variance of
/// every pixel of `lit` into `next` (whose padding stays as it is: zero), as
/// [`super::atrous`]'s scalar `tap_sum` computes them. `luminance_scale` is each pixel's
/// 1 / (σl · standard error) ([`luminance_scales`]), the luminance weights' scale.
pub(super) fn pass(
    guides: &GuidePlanes,
    step: usize,
    lit: &Lit,
    luminance_scale: &[f32],
    next: &mut Lit,
) {
    let (width, stride) = (guides.width, guides.stride());
    let v3 = crate::cpu::has_v3();
    let [x, y, z] = &mut next.illumination;
    x.values
        .par_chunks_mut(stride)
        .zip(y.values.par_chunks_mut(stride))
        .zip(z.values.par_chunks_mut(stride))
        .zip(next.luminance.values.par_chunks_mut(stride))
        .zip(next.variance.values.par_chunks_mut(stride))
        .enumerate()
        .for_each(|(row_index, ((((x, y), z), luminance), variance))| {
            let row = Row {
                y: row_index,
                step,
                guides,
                lit,
                luminance_scale: &luminance_scale[row_index * width..(row_index + 1) * width],
            };
            let out = RowOut {
                illumination: [
                    &mut x[PAD_LEFT..PAD_LEFT + width],
                    &mut y[PAD_LEFT..PAD_LEFT + width],
                    &mut z[PAD_LEFT..PAD_LEFT + width],
                ],
                luminance: &mut luminance[PAD_LEFT..PAD_LEFT + width],
                variance: &mut variance[PAD_LEFT..PAD_LEFT + width],
            };
            #[cfg(target_arch = "x86_64")]
            if v3 {
                // SAFETY: has_v3 checked that this CPU runs the x86-64-v3 instructions.
                unsafe { row.run_v3(out) };
                return;
            }
            let _ = v3;
            row.run(out);
        });
}

/// One row of a pass's output planes (without their padding).
struct RowOut<'a> {
    illumination: [&'a mut [f32]; 3],
    luminance: &'a mut [f32],
    variance: &'a mut [f32],
}

/// One output row of a pass.
/// Eight pixels' guides and lighting, read from the planes at one offset (row start plus
/// padded column): the centre pixels of a chunk, or one of their taps.
struct Gathered {
    surface: Lanes,
    normal: [Lanes; 3],
    depth: Lanes,
    albedo: [Lanes; 3],
    visibility: Lanes,
    luminance: Lanes,
    illumination: [Lanes; 3],
    variance: Lanes,
}

impl Gathered {
    #[inline(always)]
    fn at(g: &GuidePlanes, lit: &Lit, offset: usize) -> Gathered {
        let read = |plane: &Plane| plane.lanes(offset, 0);
        let three = |planes: &[Plane; 3]| [read(&planes[0]), read(&planes[1]), read(&planes[2])];
        Gathered {
            surface: read(&g.surface),
            normal: three(&g.normal),
            depth: read(&g.depth),
            albedo: three(&g.albedo),
            visibility: read(&g.visibility),
            luminance: read(&lit.luminance),
            illumination: three(&lit.illumination),
            variance: read(&lit.variance),
        }
    }
}

struct Row<'a> {
    y: usize,
    step: usize,
    guides: &'a GuidePlanes,
    lit: &'a Lit,
    /// The row's luminance scales.
    luminance_scale: &'a [f32],
}

impl Row<'_> {
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,sse4.1,sse4.2,ssse3")]
    fn run_v3(&self, out: RowOut) {
        self.run(out);
    }

    #[inline(always)]
    fn run(&self, out: RowOut) {
        let width = self.guides.width;
        let RowOut {
            illumination: [x, y, z],
            luminance: row_luminance,
            variance,
        } = out;
        for x0 in (0..width).step_by(LANES) {
            let (c, v) = self.chunk(x0);
            for l in 0..LANES.min(width - x0) {
                let rgb = Vec3::new(c[0][l], c[1][l], c[2][l]);
                (x[x0 + l], y[x0 + l], z[x0 + l]) = (rgb.x, rgb.y, rgb.z);
                row_luminance[x0 + l] = luminance(rgb);
                variance[x0 + l] = v[l];
            }
        }
    }

    /// The pixels `x0..x0 + LANES` of the row (those past its end are garbage).
    #[inline(always)]
    fn chunk(&self, x0: usize) -> ([Lanes; 3], Lanes) {
        let g = self.guides;
        let lit = self.lit;
        let stride = g.stride();
        let (height, step) = (g.height, self.step);
        let centre_row = self.y * stride;
        let centre_column = PAD_LEFT + x0;
        let Gathered {
            surface,
            normal,
            depth,
            albedo,
            visibility,
            luminance,
            illumination: own_illumination,
            variance: own_variance,
        } = Gathered::at(g, lit, centre_row + centre_column);
        let at = |plane: &Plane| plane.lanes(centre_row, centre_column);
        let gradient = [at(&g.gradient[0]), at(&g.gradient[1])];
        if surface.iter().all(|s| *s == 0.0) {
            // The background, which no pass changes.
            return (own_illumination, own_variance);
        }
        let mut luminance_scale = [0.0f32; LANES];
        for (l, scale) in luminance_scale.iter_mut().enumerate() {
            *scale = self.luminance_scale.get(x0 + l).copied().unwrap_or(0.0);
        }
        let mut depth_scale = [[[0.0f32; LANES]; 3]; 3];
        for l in 0..LANES {
            let tolerance = DEPTH_RELATIVE * depth[l];
            for (ay, row) in depth_scale.iter_mut().enumerate() {
                for (ax, scale) in row.iter_mut().enumerate() {
                    let expected = DEPTH_SIGMA
                        * (gradient[0][l] * (ax * step) as f32
                            + gradient[1][l] * (ay * step) as f32)
                        + tolerance;
                    scale[l] = 1.0 / expected;
                }
            }
        }
        let mut sum = [[0.0f32; LANES]; 3];
        let mut sum_variance = [0.0f32; LANES];
        let mut weights = [0.0f32; LANES];
        for ty in -2isize..=2 {
            let qy = self.y as isize + ty * step as isize;
            if qy < 0 || qy >= height as isize {
                continue;
            }
            let tap_row = qy as usize * stride;
            for tx in -2isize..=2 {
                // In the padding when the tap is past the left or right edge.
                let column = (centre_column as isize + tx * step as isize) as usize;
                let Gathered {
                    surface: n_surface,
                    normal: n_normal,
                    depth: n_depth,
                    albedo: n_albedo,
                    visibility: n_visibility,
                    luminance: n_luminance,
                    illumination: n_illumination,
                    variance: n_variance,
                } = Gathered::at(g, lit, tap_row + column);
                let kernel = KERNEL[tx.unsigned_abs()] * KERNEL[ty.unsigned_abs()];
                let scales = &depth_scale[ty.unsigned_abs()][tx.unsigned_abs()];
                for l in 0..LANES {
                    let facing = (normal[0][l] * n_normal[0][l]
                        + normal[1][l] * n_normal[1][l]
                        + normal[2][l] * n_normal[2][l])
                        .max(0.0);
                    let normal_weight = pow_normal(facing);
                    let depth_term = (depth[l] - n_depth[l]).abs() * scales[l];
                    let luminance_term = (luminance[l] - n_luminance[l]).abs() * luminance_scale[l];
                    let albedo_term = (albedo[0][l] - n_albedo[0][l]).abs().max(
                        (albedo[1][l] - n_albedo[1][l])
                            .abs()
                            .max((albedo[2][l] - n_albedo[2][l]).abs()),
                    ) * (1.0 / ALBEDO_SIGMA);
                    let visibility_term =
                        (visibility[l] - n_visibility[l]).abs() * (1.0 / VISIBILITY_SIGMA);
                    let exponent = depth_term + luminance_term + albedo_term + visibility_term;
                    let keep = n_surface[l] != 0.0
                        && normal_weight >= MIN_NORMAL_WEIGHT
                        && exponent < MAX_EXPONENT;
                    let w = kernel * normal_weight * exp_negative(exponent);
                    let w = if keep { w } else { 0.0 };
                    sum[0][l] += w * n_illumination[0][l];
                    sum[1][l] += w * n_illumination[1][l];
                    sum[2][l] += w * n_illumination[2][l];
                    sum_variance[l] += w * w * n_variance[l];
                    weights[l] += w;
                }
            }
        }
        let mut out = [[0.0f32; LANES]; 3];
        let mut out_variance = [0.0f32; LANES];
        for l in 0..LANES {
            // As the scalar pass: a pixel off the surfaces, or one whose normal guide averaged
            // to nothing (no tap, not even the centre, weighs anything), is left as it is.
            let keep = surface[l] == 0.0 || weights[l] <= 0.0;
            for c in 0..3 {
                out[c][l] = if keep {
                    own_illumination[c][l]
                } else {
                    sum[c][l] / weights[l]
                };
            }
            out_variance[l] = if keep {
                own_variance[l]
            } else {
                sum_variance[l] / (weights[l] * weights[l])
            };
        }
        (out, out_variance)
    }
}

#[cfg(test)]
mod tests {
    use super::super::atrous::{luminance_scale, tap_sum, LUMINANCE_SIGMA};
    use super::*;

    /// A little generator of numbers in [0, 1) (64-bit LCG, top bits).
    struct Numbers(u64);

    impl Numbers {
        fn next(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// Every pixel of every pass's step equals the scalar reference bit for bit, on an image
    /// whose width is no multiple of the lanes, with background pixels, two facing
    /// directions, depth steps, albedo edges, zero and large variances.
    #[test]
    fn the_lanes_compute_the_scalar_pass_bit_for_bit() {
        let (width, height) = (37usize, 23usize);
        let mut r = Numbers(7);
        let pixels: Vec<Pixel> = (0..width * height)
            .map(|i| {
                let surface = r.next() > 0.15;
                let turned = (i % width) > 20;
                let normal = Vec3::new(r.next() * 0.2, 1.0, if turned { 1.0 } else { 0.1 });
                Pixel {
                    surface,
                    normal: if surface {
                        normal.normalize()
                    } else {
                        Vec3::ZERO
                    },
                    depth: if surface {
                        2.0 + r.next() * if turned { 3.0 } else { 0.05 }
                    } else {
                        0.0
                    },
                    albedo: if surface {
                        Vec3::splat(if i % 5 == 0 { 0.9 } else { 0.5 }) + r.next() * 0.02
                    } else {
                        Vec3::ZERO
                    },
                    gradient: (r.next() * 0.1, r.next() * 0.1),
                    // Lit, shadowed, and a penumbra between.
                    visibility: match i % 3 {
                        0 => 1.0,
                        1 => 0.0,
                        _ => r.next(),
                    },
                }
            })
            .collect();
        let illumination: Vec<Vec3> = (0..width * height)
            .map(|_| Vec3::new(r.next(), r.next() * 4.0, r.next() * 0.5))
            .collect();
        let luminances: Vec<f32> = illumination
            .iter()
            .map(|c| crate::color::luminance(*c))
            .collect();
        let variance: Vec<f32> = (0..width * height)
            .map(|i| {
                if i % 7 == 0 {
                    0.0
                } else {
                    r.next() * r.next() * 3.0
                }
            })
            .collect();
        let scales: Vec<f32> = variance
            .iter()
            .map(|v| luminance_scale(v * 0.9, LUMINANCE_SIGMA))
            .collect();
        let planes = GuidePlanes::new(width, height, |i| pixels[i]);
        let lit = Lit::new(width, height, |i| (illumination[i], variance[i]));
        let mut next = Lit::zeros(width, height);
        let mut filtered = 0;
        for pass_index in 0..ITERATIONS {
            let step = 1usize << pass_index;
            pass(&planes, step, &lit, &scales, &mut next);
            for y in 0..height {
                for x in 0..width {
                    let i = y * width + x;
                    let (c, v) = tap_sum(
                        (x, y),
                        step,
                        (width, height),
                        &pixels,
                        (&illumination, &luminances),
                        &variance,
                        scales[i],
                    );
                    assert_eq!(
                        next.illumination(width, i).to_array().map(f32::to_bits),
                        c.to_array().map(f32::to_bits),
                        "({x}, {y}) step {step}"
                    );
                    assert_eq!(
                        next.variance(width, i).to_bits(),
                        v.to_bits(),
                        "({x}, {y}) step {step}"
                    );
                    filtered += usize::from(c != illumination[i]);
                }
            }
        }
        // The comparison covered filtered pixels, not only pixels left as they were.
        assert!(
            filtered > width * height * ITERATIONS as usize / 2,
            "{filtered}"
        );
        // The luminance scales: the variance blurred 3x3 over each surface pixel's surface
        // neighbours inside the image (a background pixel keeps its own), computed plainly.
        let mut lanes_scales = vec![0.0f32; width * height];
        luminance_scales(&planes, &lit, 24.0, &mut lanes_scales);
        for y in 0..height {
            for x in 0..width {
                let i = y * width + x;
                let blurred = if !pixels[i].surface {
                    variance[i]
                } else {
                    let (mut sum, mut weights) = (0.0f32, 0.0f32);
                    for dy in -1isize..=1 {
                        for dx in -1isize..=1 {
                            let (qx, qy) = (x as isize + dx, y as isize + dy);
                            if qx < 0 || qy < 0 || qx >= width as isize || qy >= height as isize {
                                continue;
                            }
                            let q = qy as usize * width + qx as usize;
                            if pixels[q].surface {
                                let w = VARIANCE_BLUR[dx.unsigned_abs()]
                                    * VARIANCE_BLUR[dy.unsigned_abs()];
                                sum += w * variance[q];
                                weights += w;
                            }
                        }
                    }
                    sum / weights
                };
                assert_eq!(
                    lanes_scales[i].to_bits(),
                    luminance_scale(blurred, 24.0).to_bits(),
                    "({x}, {y})"
                );
            }
        }
    }
}
