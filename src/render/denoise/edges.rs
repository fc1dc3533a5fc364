//! Mixed pixels: where a pixel's samples met two surfaces (a corner's seam, a silhouette), its
//! guides are the mix of both, which matches neither side's neighbours. The filter's
//! edge-stopping weights then give it almost no taps but its own, and it keeps the noise of
//! its few samples: at the default render's two samples a pixel, a line of bright and dark
//! specks along edges of an otherwise smooth image.
//!
//! Such a pixel is found in two steps. Its support is low: the weight its eight neighbours
//! get in the filter's first pass from the guides alone (normals, depth, albedo, visibility,
//! without the luminance) is under [`MIN_SUPPORT`]. And its guides are a mix of two
//! neighbours' that the filter does support: t · p + (1 - t) · q, the raw (averaged, not
//! renormalised) normal, the albedo, the depth and the visibility, each measured in the
//! filter's own tolerance for it, within [`MAX_RESIDUAL`]. After the passes it takes their
//! filtered illumination in the same proportion, remodulated by its own albedo like every
//! pixel: the clean light of the two surfaces its samples saw. A pixel whose own
//! illumination disagrees with that mix by more than the filter's luminance tolerance (its
//! samples agree: a converged image) keeps its own. A pixel on a surface of fine detail (a
//! normal map's grooves), whose guides no two neighbours explain, is left as the filter left
//! it.

use super::atrous::{
    divisor, exp_negative, pow_normal, Pixel, ALBEDO_SIGMA, DEPTH_RELATIVE, DEPTH_SIGMA, KERNEL,
    MAX_EXPONENT, MIN_NORMAL_WEIGHT, NORMAL_POWER, VISIBILITY_SIGMA,
};
use super::lanes::{GuidePlanes, Lit};
use glam::Vec3;
use rayon::prelude::*;

/// Support below which a pixel may be mixed: its eight neighbours' summed first-pass
/// weights (kernel times edge-stopping, without the luminance), of at most 0.625. One
/// neighbour on its surface beside it weighs 0.094 (3/8 · 1/4).
pub(super) const MIN_SUPPORT: f32 = 0.05;

/// The normal difference that counts as one tolerance in a mix's residual: where the filter's
/// normal weight (cos^128) falls to e^-1, 7°.
const NORMAL_TOLERANCE: f32 = 0.125;

/// The largest residual of a mix, squared tolerances summed over the guides' components.
pub(super) const MAX_RESIDUAL: f32 = 0.5;

/// The least share of either neighbour in a mix. At two samples a pixel a mixed pixel's
/// share is a half; a pixel nearly all of one surface has that surface's support.
pub(super) const MIN_SHARE: f32 = 0.2;

/// The eight neighbours' offsets, the four beside a pixel first.
const AROUND: [(isize, isize); 8] = [
    (-1, 0),
    (1, 0),
    (0, -1),
    (0, 1),
    (-1, -1),
    (1, -1),
    (-1, 1),
    (1, 1),
];

/// A mixed pixel: the guides of pixel `pixel` are `t` parts those of `p` and 1 - `t` of `q`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Mix {
    pub(super) pixel: usize,
    p: usize,
    q: usize,
    pub(super) t: f32,
}

/// The mixed pixels of the image whose guides are in `planes` (and whose averaged, not
/// renormalised, normals are `raw_normal`), in row-major order.
pub(super) fn mixed_pixels(planes: &GuidePlanes, raw_normal: &[Vec3]) -> Vec<Mix> {
    let (width, height) = planes.size();
    let unsupported: Vec<usize> = (0..height)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..width).filter_map(move |x| {
                let centre = planes.pixel_at(x, y);
                (centre.surface && !is_supported(planes, &centre, x, y)).then_some(y * width + x)
            })
        })
        .collect();
    unsupported
        .par_iter()
        .filter_map(|&i| mix_of(planes, raw_normal, &unsupported, i))
        .collect()
}

/// Whether the neighbours of `centre`, pixel (`x`, `y`), support it: their first-pass
/// weights from the guides sum to [`MIN_SUPPORT`] or more.
fn is_supported(planes: &GuidePlanes, centre: &Pixel, x: usize, y: usize) -> bool {
    let (width, height) = planes.size();
    let at = |(dx, dy): (isize, isize)| {
        let (qx, qy) = (x as isize + dx, y as isize + dy);
        (qx >= 0 && qy >= 0 && qx < width as isize && qy < height as isize)
            .then(|| planes.pixel_at(qx as usize, qy as usize))
    };
    // Most pixels have a neighbour beside them that supports them alone, which a bound without
    // the exponentials shows.
    let alone = (MIN_SUPPORT / (KERNEL[0] * KERNEL[1])).ln();
    let beside = |d: (isize, isize)| at(d).map(|n| log_weight_bound(centre, &n, d.0, d.1));
    if AROUND[..4]
        .iter()
        .any(|&d| beside(d).is_some_and(|b| b >= alone))
    {
        return true;
    }
    let mut support = 0.0f32;
    for (dx, dy) in AROUND {
        if let Some(neighbour) = at((dx, dy)) {
            let w = KERNEL[dx.unsigned_abs()] * KERNEL[dy.unsigned_abs()];
            support += w * guide_weight(centre, &neighbour, dx, dy);
            if support >= MIN_SUPPORT {
                return true;
            }
        }
    }
    false
}

/// The mix of two supported neighbours (not in `unsupported`) that best explains the guides
/// of pixel `i`, if one does within [`MAX_RESIDUAL`], each taking at least [`MIN_SHARE`].
fn mix_of(
    planes: &GuidePlanes,
    raw_normal: &[Vec3],
    unsupported: &[usize],
    i: usize,
) -> Option<Mix> {
    let (width, height) = planes.size();
    let (x, y) = (i % width, i / width);
    // The unit-free guides of the centre and of its supported neighbours, row by row.
    let centre = planes.pixel(i);
    let own = Guide::of(&centre, raw_normal[i], &centre);
    let mut sides: Vec<(usize, Guide)> = Vec::with_capacity(8);
    for qy in y.saturating_sub(1)..(y + 2).min(height) {
        for qx in x.saturating_sub(1)..(x + 2).min(width) {
            let q = qy * width + qx;
            let p = planes.pixel(q);
            if q != i && p.surface && unsupported.binary_search(&q).is_err() {
                sides.push((q, Guide::of(&p, p.normal, &centre)));
            }
        }
    }
    let mut best: Option<(f32, Mix)> = None;
    for (a, &(p, gp)) in sides.iter().enumerate() {
        for &(q, gq) in &sides[a + 1..] {
            let apart = gp.minus(&gq);
            let span = apart.dot(&apart);
            if span <= MAX_RESIDUAL {
                // One surface, not two.
                continue;
            }
            // The least-squares share of p, and what it leaves unexplained.
            let t = (own.minus(&gq).dot(&apart) / span).clamp(0.0, 1.0);
            let residual = own.minus(&gq.plus_scaled(&apart, t));
            let residual = residual.dot(&residual);
            let shared = (MIN_SHARE..=1.0 - MIN_SHARE).contains(&t);
            if shared && residual <= MAX_RESIDUAL && best.is_none_or(|(r, _)| residual < r) {
                best = Some((residual, Mix { pixel: i, p, q, t }));
            }
        }
    }
    best.map(|(_, mix)| mix)
}

/// A pixel's guides in units of the filter's tolerances around a centre pixel: normal (three
/// components), albedo (three), depth, visibility.
#[derive(Clone, Copy)]
struct Guide([f32; 8]);

impl Guide {
    fn of(p: &Pixel, normal: Vec3, centre: &Pixel) -> Guide {
        let n = normal / NORMAL_TOLERANCE;
        let a = p.albedo / ALBEDO_SIGMA;
        // The depth relative to the centre's, in the filter's tolerance there.
        let depth = p.depth / (DEPTH_RELATIVE * centre.depth).max(f32::MIN_POSITIVE);
        let visibility = p.visibility / VISIBILITY_SIGMA;
        Guide([n.x, n.y, n.z, a.x, a.y, a.z, depth, visibility])
    }

    fn minus(&self, other: &Guide) -> Guide {
        Guide(std::array::from_fn(|k| self.0[k] - other.0[k]))
    }

    fn plus_scaled(&self, other: &Guide, t: f32) -> Guide {
        Guide(std::array::from_fn(|k| self.0[k] + t * other.0[k]))
    }

    fn dot(&self, other: &Guide) -> f32 {
        self.0.iter().zip(&other.0).map(|(a, b)| a * b).sum()
    }
}

/// Gives each of the `mixes` its two neighbours' illumination in `lit` in its proportion,
/// unless its own illumination's luminance differs from that by more than the filter's
/// tolerance (`scales`, each mixed pixel's luminance scale of the first pass, in the order of
/// `mixes`).
pub(super) fn mend(planes: &GuidePlanes, lit: &mut Lit, mixes: &[Mix], scales: &[f32]) {
    let (width, _) = planes.size();
    let mended: Vec<Option<Vec3>> = mixes
        .par_iter()
        .zip(scales)
        .map(|(m, &scale)| {
            // The two sides' radiance (illumination times albedo) mixed, as the pixel's
            // illumination: remodulated by its own albedo, the mix of the two sides' albedo,
            // it gives that radiance back. (Mixing illumination alone and multiplying by the
            // mixed albedo would add t(1 - t)(a_p - a_q)(i_q - i_p) where both differ.)
            let radiance = |k: usize| lit.illumination(width, k) * divisor(planes.albedo(k));
            let rgb = (radiance(m.p) * m.t + radiance(m.q) * (1.0 - m.t))
                / divisor(planes.albedo(m.pixel));
            let term = (crate::color::luminance(rgb) - lit.luminance(width, m.pixel)).abs() * scale;
            (term <= 1.0).then_some(rgb)
        })
        .collect();
    for (m, rgb) in mixes.iter().zip(mended) {
        if let Some(rgb) = rgb {
            lit.set_illumination(width, m.pixel, rgb);
        }
    }
}

/// A lower bound of the logarithm of [`guide_weight`], without its exponentials: with
/// ln f ≥ 1 - 1/f, ln(f^128 · e^-x) ≥ 128 (1 - 1/f) - x.
#[inline(always)]
fn log_weight_bound(centre: &Pixel, neighbour: &Pixel, dx: isize, dy: isize) -> f32 {
    let facing = centre.normal.dot(neighbour.normal);
    if !neighbour.surface || facing <= 0.0 {
        return f32::NEG_INFINITY;
    }
    NORMAL_POWER as f32 * (1.0 - 1.0 / facing) - guide_exponent(centre, neighbour, dx, dy)
}

/// The filter's edge-stopping weight of `neighbour` (at offset `dx`, `dy`) against `centre`
/// from the guides alone (no luminance); 0 off the surfaces.
#[inline(always)]
fn guide_weight(centre: &Pixel, neighbour: &Pixel, dx: isize, dy: isize) -> f32 {
    if !neighbour.surface {
        return 0.0;
    }
    let normal_weight = pow_normal(centre.normal.dot(neighbour.normal).max(0.0));
    if normal_weight < MIN_NORMAL_WEIGHT {
        return 0.0;
    }
    let exponent = guide_exponent(centre, neighbour, dx, dy);
    if exponent >= MAX_EXPONENT {
        return 0.0;
    }
    normal_weight * exp_negative(exponent)
}

/// The depth, albedo and visibility terms of the filter's edge-stopping exponent.
#[inline(always)]
fn guide_exponent(centre: &Pixel, neighbour: &Pixel, dx: isize, dy: isize) -> f32 {
    let expected = DEPTH_SIGMA
        * (centre.gradient.0 * dx.unsigned_abs() as f32
            + centre.gradient.1 * dy.unsigned_abs() as f32)
        + DEPTH_RELATIVE * centre.depth;
    let depth_term = (centre.depth - neighbour.depth).abs() / expected;
    let albedo_term = (centre.albedo - neighbour.albedo).abs().max_element() * (1.0 / ALBEDO_SIGMA);
    let visibility_term =
        (centre.visibility - neighbour.visibility).abs() * (1.0 / VISIBILITY_SIGMA);
    depth_term + albedo_term + visibility_term
}
