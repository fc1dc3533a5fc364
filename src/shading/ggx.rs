//! GGX (Trowbridge-Reitz) microfacet primitives shared by the BRDF and its sampler: the normal
//! distribution, Smith's masking for it, and the distribution of visible normals (Heitz,
//! "Sampling the GGX Distribution of Visible Normals", JCGT 2018). All in a local or given
//! frame with unit vectors pointing away from the surface.

use glam::Vec3;
use std::f32::consts::PI;

/// The pdf per steradian of a direction reflected about a GGX visible normal `h` drawn around
/// `n`: D(h)·G1(v) / (4·n·v).
pub(crate) fn visible_normal_pdf(n: Vec3, h: Vec3, n_dot_v: f32, alpha: f32) -> f32 {
    ggx_d(n.dot(h), alpha) * smith_g1(n_dot_v, alpha) / (4.0 * n_dot_v)
}

/// GGX / Trowbridge-Reitz normal distribution D(h) for cos θ_h = `n_dot_h`.
pub(crate) fn ggx_d(n_dot_h: f32, alpha: f32) -> f32 {
    if n_dot_h <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let d = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
    a2 / (PI * d * d)
}

/// Smith's Λ for GGX at cos θ = `cos`: (√(1 + α²·tan²θ) - 1) / 2, so G1 = 1 / (1 + Λ).
pub(crate) fn smith_lambda(cos: f32, alpha: f32) -> f32 {
    let cos2 = (cos * cos).max(1e-8);
    let tan2 = (1.0 - cos2).max(0.0) / cos2;
    0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0)
}

/// Smith's masking function for GGX, G1(v) = 2·n·v / (n·v + √(α² + (1 - α²)(n·v)²)).
pub(crate) fn smith_g1(n_dot_v: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    2.0 * n_dot_v / (n_dot_v + (a2 + (1.0 - a2) * n_dot_v * n_dot_v).sqrt())
}

/// A microfacet normal drawn from GGX's visible normals for view `v` (local frame, z = normal),
/// Heitz 2018, listing 1.
#[inline(always)]
pub(crate) fn sample_visible_normal(v: Vec3, alpha: f32, u1: f32, u2: f32) -> Vec3 {
    let vh = Vec3::new(alpha * v.x, alpha * v.y, v.z).normalize_or_zero();
    let len2 = vh.x * vh.x + vh.y * vh.y;
    let t1 = if len2 > 0.0 {
        Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt()
    } else {
        Vec3::X
    };
    let t2 = vh.cross(t1);
    let r = u1.sqrt();
    let phi = std::f32::consts::TAU * u2;
    let p1 = r * phi.cos();
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
    let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
    Vec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(0.0)).normalize_or_zero()
}
