//! GGX (Trowbridge-Reitz) microfacet primitives shared by the BRDF and its sampler: the normal
//! distribution, Smith's masking for it, and the distribution of visible normals (Heitz,
//! "Sampling the GGX Distribution of Visible Normals", JCGT 2018). All in a local or given
//! frame with unit vectors pointing away from the surface.

use glam::{Vec3, Vec3A};
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
    sample_visible_normal_xy(v, alpha, alpha, u1, u2)
}

/// [`sample_visible_normal`] for an anisotropic lobe: α = `alpha_x` along the local x axis
/// and `alpha_y` along y (Heitz's listing takes both; with equal α it is the same operations).
#[inline(always)]
pub(crate) fn sample_visible_normal_xy(
    v: Vec3,
    alpha_x: f32,
    alpha_y: f32,
    u1: f32,
    u2: f32,
) -> Vec3 {
    let vh = Vec3::new(alpha_x * v.x, alpha_y * v.y, v.z).normalize_or_zero();
    let len2 = vh.x * vh.x + vh.y * vh.y;
    let t1 = if len2 > 0.0 {
        Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt()
    } else {
        Vec3::X
    };
    let t2 = vh.cross(t1);
    let r = u1.sqrt();
    let (sin, cos) = crate::sampling::sin_cos_turns(u2);
    let p1 = r * cos;
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * sin;
    let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
    Vec3::new(alpha_x * nh.x, alpha_y * nh.y, nh.z.max(0.0)).normalize_or_zero()
}

/// Cells of the directional albedo table per axis (cos θ_v and perceptual roughness).
const ALBEDO_TABLE: usize = 32;

/// The directional albedo table of [`directional_albedo`]: entry `j · 32 + i` is
/// [`integrate_albedo`] at cos θ_v = max(i / 31, [`ALBEDO_MIN_COSINE`]) and roughness j / 31.
/// Written by `MESHTRACER_BLESS=1 cargo test --lib ggx::tests::the_baked_albedo_table`.
const ALBEDO: [[f32; 2]; ALBEDO_TABLE * ALBEDO_TABLE] = include!("ggx_albedo.in");

/// Stratified visible-normal draws per table entry, per axis (32 × 32 = 1024 draws).
#[cfg(test)]
const ALBEDO_STRATA: usize = 32;

/// Smallest view cosine the albedo table is integrated at (the lobe is degenerate at 0).
#[cfg(test)]
const ALBEDO_MIN_COSINE: f32 = 0.02;

/// The single-scattering GGX lobe's directional albedo at cos θ_v = `cos` for perceptual
/// `roughness` (α = max(roughness², 0.002), the BRDF's floor), split as (a, b) so
/// that with Schlick's Fresnel F = F0 + (F90 - F0)(1 - v·h)⁵ the lobe D·V reflects
/// `F0·a + (F90 - F0)·b` of the light arriving from the view direction: a = ∫ D·V·cos θ_l dω,
/// b = ∫ (1 - v·h)⁵·D·V·cos θ_l dω (the "split-sum" or DFG table of real-time renderers).
///
/// Bilinear in a 32 × 32 table (baked into the source, src/shading/ggx_albedo.in; a test
/// recomputes every entry): each entry averages the weight G2/G1
/// of 1024 stratified draws from the distribution of visible normals, which is exactly
/// f·cos/pdf for F = 1 (Heitz 2018), so the table has no variance from the lobe's peak. Baked,
/// not integrated at first use: that took 30-40 ms of every render, a tenth of a small
/// model's whole run. Unit-tested against an independent quadrature of the BRDF.
pub fn directional_albedo(cos: f32, roughness: f32) -> (f32, f32) {
    let table = &ALBEDO;
    let n = ALBEDO_TABLE;
    let x = cos.clamp(0.0, 1.0) * (n - 1) as f32;
    let y = roughness.clamp(0.0, 1.0) * (n - 1) as f32;
    let (i, j) = ((x as usize).min(n - 2), (y as usize).min(n - 2));
    let (fx, fy) = (x - i as f32, y - j as f32);
    let lerp =
        |a: [f32; 2], b: [f32; 2], t: f32| [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
    let at = |i: usize, j: usize| table[j * n + i];
    let bottom = lerp(at(i, j), at(i + 1, j), fx);
    let top = lerp(at(i, j + 1), at(i + 1, j + 1), fx);
    let [a, b] = lerp(bottom, top, fy);
    (a, b)
}

/// The view cosine and roughness of entry `k` of [`ALBEDO`] (row-major, cosine fastest).
#[cfg(test)]
fn albedo_entry(k: usize) -> (f32, f32) {
    let n = ALBEDO_TABLE;
    let (i, j) = (k % n, k / n);
    let cos_v = (i as f32 / (n - 1) as f32).max(ALBEDO_MIN_COSINE);
    (cos_v, j as f32 / (n - 1) as f32)
}

/// One entry of [`directional_albedo`]'s table: the mean of G2/G1 (and of (1 - v·h)⁵·G2/G1)
/// over stratified visible-normal draws, where G2/G1 = (1 + Λ(v)) / (1 + Λ(v) + Λ(l)) for
/// the height-correlated masking-shadowing of the glTF BRDF's visibility term. Run by the
/// test that checks the baked table (and writes it anew with `MESHTRACER_BLESS=1`).
#[cfg(test)]
fn integrate_albedo(cos_v: f32, roughness: f32) -> [f32; 2] {
    let alpha = (roughness * roughness).max(crate::shading::MIN_GGX_ALPHA);
    let v = Vec3::new((1.0 - cos_v * cos_v).max(0.0).sqrt(), 0.0, cos_v);
    let lambda_v = smith_lambda(cos_v, alpha);
    let strata = ALBEDO_STRATA;
    let (mut a, mut b) = (0.0f64, 0.0f64);
    for k in 0..strata * strata {
        let u1 = ((k % strata) as f32 + 0.5) / strata as f32;
        let u2 = ((k / strata) as f32 + 0.5) / strata as f32;
        let h = sample_visible_normal(v, alpha, u1, u2);
        let v_dot_h = v.dot(h);
        let l = 2.0 * v_dot_h * h - v;
        if l.z <= 0.0 || v_dot_h <= 0.0 {
            continue;
        }
        let weight = (1.0 + lambda_v) / (1.0 + lambda_v + smith_lambda(l.z, alpha));
        a += f64::from(weight);
        b += f64::from(weight * (1.0 - v_dot_h).powi(5));
    }
    let count = (strata * strata) as f64;
    [(a / count) as f32, (b / count) as f32]
}

/// Multiple scattering for a GGX lobe with Schlick's Fresnel (F0, F90), seen at cos θ_v =
/// `cos`: the factor the single-scattering lobe is scaled by, and the scaled lobe's
/// directional albedo.
///
/// A microsurface reflects the light its single-scattering lobe loses (1 - E(v) for white,
/// E = [`directional_albedo`]'s a) after further bounces, with about the lobe's own shape
/// (Turquin, "Practical multiple scattering compensation for microfacet models", 2019), and
/// each further bounce takes the Fresnel factor again: Kulla and Conty's multiple-bounce
/// Fresnel ("Revisiting Physically Based Shading at Imageworks", 2017)
/// F_ms = F_avg·E_avg / (1 - F_avg·(1 - E_avg)), with F_avg = F0 + (F90 - F0)/21 the
/// cosine-weighted average of Schlick's Fresnel and E_avg = [`average_albedo`], so the lobe
/// is scaled by 1 + F_ms·(1 - E)/E, as Cycles scales its multiscatter GGX. A white metal then
/// reflects all the light at every roughness and angle (the white furnace), and a coloured
/// one saturates and darkens as real rough metals do. Layers under the lobe (the diffuse
/// base, the base under a clearcoat) keep what the scaled lobe leaves: 1 - albedo.
///
/// A lobe with no Fresnel at all (F0 = F90 = 0: `KHR_materials_specular` factor 0 on a
/// dielectric) gives (1, 0) without the tables: F_ms = 0 and the albedo 0, exactly what the
/// general formula gives (it was a tenth of a path-traced diffuse Cornell box). The vector
/// arithmetic runs in SIMD lanes (`Vec3A`): lane by lane the same operations, so the same bits,
/// with one vector division where `Vec3` did three scalar ones.
#[inline]
pub fn multiple_scattering(f0: Vec3, f90: Vec3, cos: f32, roughness: f32) -> (Vec3, Vec3) {
    if f0 == Vec3::ZERO && f90 == Vec3::ZERO {
        return (Vec3::ONE, Vec3::ZERO);
    }
    AlbedoTerms::at(cos, roughness).multiple_scattering(f0, f90)
}

/// The directional albedo terms (a, b) of an anisotropic GGX lobe (α = `alpha_x` along the
/// local x axis, `alpha_y` along y, z the normal; `alpha_x` ≥ `alpha_y`, as
/// `KHR_materials_anisotropy` stretches them) seen from the local unit view `v`: what
/// [`directional_albedo`] gives an isotropic lobe, for a lobe whose albedo also depends on
/// the view's azimuth. Read from a table over (cos θ_v, azimuth, α_y, stretch) built at the
/// first call (12 x 7 x 12 x 12 entries of 144 stratified visible-normal draws each),
/// interpolated in all four.
pub fn anisotropic_albedo(v: Vec3, alpha_x: f32, alpha_y: f32) -> (f32, f32) {
    let table = anisotropic_albedo_table();
    let [n_mu, n_phi, n_b, n_s] = ANISO_TABLE;
    let mu = v.z.clamp(0.0, 1.0);
    // By symmetry of the lobe, the azimuth folds into [0, π/2].
    let phi = if v.x.abs() + v.y.abs() > 0.0 {
        v.y.abs().atan2(v.x.abs())
    } else {
        0.0
    };
    let stretch = if alpha_y < 1.0 {
        ((alpha_x - alpha_y) / (1.0 - alpha_y)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let coordinate = |x: f32, n: usize| {
        let x = x.clamp(0.0, 1.0) * (n - 1) as f32;
        let i = (x as usize).min(n - 2);
        (i, x - i as f32)
    };
    let axes = [
        coordinate(mu.sqrt(), n_mu),
        coordinate(phi / std::f32::consts::FRAC_PI_2, n_phi),
        coordinate(alpha_y.sqrt(), n_b),
        coordinate(stretch, n_s),
    ];
    let (mut a, mut b) = (0.0f32, 0.0f32);
    for corner in 0..16u32 {
        let mut weight = 1.0f32;
        let mut index = 0usize;
        for (axis, &(i, f)) in axes.iter().enumerate() {
            let up = (corner >> axis) & 1 == 1;
            weight *= if up { f } else { 1.0 - f };
            index = index * ANISO_TABLE[axis] + i + usize::from(up);
        }
        let [ea, eb] = table[index];
        a += weight * ea;
        b += weight * eb;
    }
    (a, b)
}

/// Points of [`anisotropic_albedo`]'s table along cos θ_v, the azimuth, α_y and the stretch
/// (α_x - α_y) / (1 - α_y).
const ANISO_TABLE: [usize; 4] = [12, 7, 12, 12];

/// Draws a side of the grid each entry of [`anisotropic_albedo_table`] averages.
const ANISO_STRATA: usize = 12;

/// [`anisotropic_albedo`]'s table, built once in parallel (about 10,000 entries of 144
/// stratified visible-normal draws each: a few tens of milliseconds on two cores, paid only by
/// renders with anisotropic materials). Entry (i, j, k, l), row-major in that order, is the
/// lobe with α_y = (k/(n-1))² (roughness k/(n-1)) and stretch l/(n-1), seen at cos θ_v =
/// (i/(n-1))² (at least 0.01: the albedo changes fastest near grazing) and azimuth
/// j/(n-1)·π/2: the mean of G2/G1 = (1 + Λ(v)) / (1 + Λ(v) + Λ(l)) and of
/// (1 - v·m)⁵·G2/G1 over the midpoints of a grid of the draws' two numbers (0 below the
/// surface), as [`directional_albedo`]'s table averages them for one α.
fn anisotropic_albedo_table() -> &'static [[f32; 2]] {
    use rayon::prelude::*;
    static TABLE: std::sync::OnceLock<Vec<[f32; 2]>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let [n_mu, n_phi, n_b, n_s] = ANISO_TABLE;
        (0..n_mu * n_phi * n_b * n_s)
            .into_par_iter()
            .map(|index| {
                let l = index % n_s;
                let k = (index / n_s) % n_b;
                let j = (index / (n_s * n_b)) % n_phi;
                let i = index / (n_s * n_b * n_phi);
                let mu = (i as f32 / (n_mu - 1) as f32).powi(2).max(0.01);
                let phi = j as f32 / (n_phi - 1) as f32 * std::f32::consts::FRAC_PI_2;
                let alpha_y = (k as f32 / (n_b - 1) as f32)
                    .powi(2)
                    .max(crate::shading::MIN_GGX_ALPHA);
                let stretch = l as f32 / (n_s - 1) as f32;
                let alpha_x = alpha_y + (1.0 - alpha_y) * stretch;
                let sin = (1.0 - mu * mu).max(0.0).sqrt();
                let (sp, cp) = phi.sin_cos();
                integrate_anisotropic(Vec3::new(sin * cp, sin * sp, mu), alpha_x, alpha_y)
            })
            .collect()
    })
}

/// One entry of [`anisotropic_albedo_table`].
fn integrate_anisotropic(v: Vec3, alpha_x: f32, alpha_y: f32) -> [f32; 2] {
    let lambda = |w: Vec3| {
        let cos2 = (w.z * w.z).max(1e-8);
        let tangential = (alpha_x * w.x).powi(2) + (alpha_y * w.y).powi(2);
        0.5 * ((1.0 + tangential / cos2).sqrt() - 1.0)
    };
    let lambda_v = lambda(v);
    let n = ANISO_STRATA;
    let (mut a, mut b) = (0.0f32, 0.0f32);
    for i in 0..n {
        for j in 0..n {
            let u1 = (i as f32 + 0.5) / n as f32;
            let u2 = (j as f32 + 0.5) / n as f32;
            let m = sample_visible_normal_xy(v, alpha_x, alpha_y, u1, u2);
            let v_dot_m = v.dot(m);
            let l = 2.0 * v_dot_m * m - v;
            if l.z <= 0.0 {
                continue;
            }
            let weight = (1.0 + lambda_v) / (1.0 + lambda_v + lambda(l));
            a += weight;
            b += weight * (1.0 - v_dot_m.clamp(0.0, 1.0)).powi(5);
        }
    }
    let count = (n * n) as f32;
    [a / count, b / count]
}

/// What [`multiple_scattering`] reads from the albedo tables for one view and roughness,
/// whatever the Fresnel: [`directional_albedo`]'s (a, b) and [`average_albedo`]. A material
/// that mixes a dielectric and a metal (0 < metallic < 1) compensates both with one lookup.
#[derive(Clone, Copy, Debug)]
pub struct AlbedoTerms {
    a: f32,
    b: f32,
    e_avg: f32,
}

impl AlbedoTerms {
    /// The terms of a lobe whose directional albedo terms at the view are (`a`, `b`) (see
    /// [`directional_albedo`]) and whose hemispherical average albedo is `e_avg`.
    pub fn from_parts(a: f32, b: f32, e_avg: f32) -> Self {
        AlbedoTerms { a, b, e_avg }
    }

    /// The directional albedo terms (a, b).
    pub fn directional(&self) -> (f32, f32) {
        (self.a, self.b)
    }

    /// The terms at cos θ_v = `cos` and perceptual `roughness`.
    #[inline]
    pub fn at(cos: f32, roughness: f32) -> Self {
        let (a, b) = directional_albedo(cos, roughness);
        AlbedoTerms {
            a,
            b,
            e_avg: average_albedo(roughness),
        }
    }

    /// [`multiple_scattering`] of Schlick's Fresnel (F0, F90) with these terms: the same
    /// operations, so the same bits.
    #[inline]
    pub fn multiple_scattering(self, f0: Vec3, f90: Vec3) -> (Vec3, Vec3) {
        if f0 == Vec3::ZERO && f90 == Vec3::ZERO {
            return (Vec3::ONE, Vec3::ZERO);
        }
        let AlbedoTerms { a, b, e_avg } = self;
        let (f0, f90) = (Vec3A::from(f0), Vec3A::from(f90));
        let f_avg = f0 + (f90 - f0) / 21.0;
        // 1 - F_avg·(1 - E_avg), written so that F_avg = 1 gives exactly F_ms = 1.
        let f_ms = f_avg * e_avg / (Vec3A::splat(e_avg) + (Vec3A::ONE - f_avg) * (1.0 - e_avg));
        let scale = Vec3A::ONE + f_ms * ((1.0 - a) / a.max(1e-3));
        (scale.into(), ((f0 * a + (f90 - f0) * b) * scale).into())
    }
}

/// The single-scattering GGX lobe's hemispherical average albedo for perceptual `roughness`
/// (F = 1): E_avg = 2·∫ E(μ)·μ dμ over view cosines μ, with E = [`directional_albedo`]'s a;
/// 1 for a mirror, about 0.45 at roughness 1. Linear in a table of the albedo table's
/// roughness rows, integrated once by the midpoint rule.
pub fn average_albedo(roughness: f32) -> f32 {
    static TABLE: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    let n = ALBEDO_TABLE;
    let table = TABLE.get_or_init(|| {
        const STEPS: usize = 256;
        (0..n)
            .map(|j| {
                let roughness = j as f32 / (n - 1) as f32;
                let sum: f32 = (0..STEPS)
                    .map(|k| {
                        let mu = (k as f32 + 0.5) / STEPS as f32;
                        directional_albedo(mu, roughness).0 * mu
                    })
                    .sum();
                2.0 * sum / STEPS as f32
            })
            .collect()
    });
    let y = roughness.clamp(0.0, 1.0) * (n - 1) as f32;
    let j = (y as usize).min(n - 2);
    table[j] + (table[j + 1] - table[j]) * (y - j as f32)
}

/// Cells of [`refraction_albedo`]'s table per axis of view cosine and of roughness.
const REFRACTION_TABLE: usize = 16;

/// Indices of refraction [`refraction_albedo`]'s table is integrated at: 1, 1.25, ..., 3.
const REFRACTION_IORS: usize = 9;

/// Stratified visible-normal draws per entry of [`refraction_albedo`]'s table, per axis.
#[cfg(test)]
const REFRACTION_STRATA: usize = 16;

/// [`refraction_albedo`]'s table: entry `((d · 9 + l) · 16 + j) · 16 + i` is
/// [`integrate_refraction`] at cos θ_v = max(i / 15, 0.02), roughness j / 15 and index
/// 1 / √(1 - l/9), entering (d = 0, η = 1/index) or leaving (d = 1, η = index). Written by
/// `MESHTRACER_BLESS=1 cargo test --release --lib ggx::tests::the_baked_refraction_table`.
static REFRACTION: [[f32; 2]; 2 * REFRACTION_IORS * REFRACTION_TABLE * REFRACTION_TABLE] =
    include!("ggx_refraction.in");

/// The rough refraction lobe's mean draw weight at cos θ_v = `cos` for perceptual
/// `roughness`, crossing a surface with relative index `eta` (outside / inside: below 1
/// entering a denser volume, above 1 leaving it), split as [`directional_albedo`] splits the
/// reflection's: with Schlick's Fresnel F = F0 + (F90 - F0)(1 - v·m)⁵ the draws of
/// `Bsdf::sample_transmission` (refraction about a visible normal m, a mirror reflection past
/// the critical angle, weight (1 - F)·G2/G1; leaving, some draws reflect back inside as
/// Fresnel at the outside angle asks) average `a·(1 - F0) - (F90 - F0)·b`. What is
/// missing from 1 - the reflection's share is what microfacets scatter more than once.
///
/// Trilinear in a table (baked into the source, src/shading/ggx_refraction.in; a test
/// recomputes every entry) of view cosine and roughness, 16 each, and 9 indices from 1 to 3
/// spaced evenly in 1 / index² (denser where water and glass lie; the albedo of light
/// leaving a volume bends too much between nodes spaced evenly in the index, which put a
/// white water surface 3% off), per direction; each entry averages 256 stratified draws.
pub fn refraction_albedo(cos: f32, roughness: f32, eta: f32) -> (f32, f32) {
    let table = &REFRACTION;
    let (n, k) = (REFRACTION_TABLE, REFRACTION_IORS);
    let leaving = usize::from(eta > 1.0);
    let ior = if eta > 1.0 { eta } else { 1.0 / eta.max(1e-3) };
    let x = cos.clamp(0.0, 1.0) * (n - 1) as f32;
    let y = roughness.clamp(0.0, 1.0) * (n - 1) as f32;
    // Nodes evenly spaced in 1 / ior², from 1 (ior 1) to 1/9 (ior 3): denser where common
    // glass and water lie, and the albedo is about linear in it between nodes.
    let z = ((1.0 - 1.0 / (ior * ior)) * 9.0).clamp(0.0, (k - 1) as f32);
    let (i, j, l) = (
        (x as usize).min(n - 2),
        (y as usize).min(n - 2),
        (z as usize).min(k - 2),
    );
    let (fx, fy, fz) = (x - i as f32, y - j as f32, z - l as f32);
    let at = |i: usize, j: usize, l: usize| table[((leaving * k + l) * n + j) * n + i];
    let lerp =
        |a: [f32; 2], b: [f32; 2], t: f32| [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
    let plane = |l: usize| {
        let bottom = lerp(at(i, j, l), at(i + 1, j, l), fx);
        let top = lerp(at(i, j + 1, l), at(i + 1, j + 1, l), fx);
        lerp(bottom, top, fy)
    };
    let [a, b] = lerp(plane(l), plane(l + 1), fz);
    (a, b)
}

/// The view cosine, roughness and relative index of entry `e` of [`REFRACTION`] (cosine
/// fastest, then roughness, then index; entering first, then leaving).
#[cfg(test)]
fn refraction_entry(e: usize) -> (f32, f32, f32) {
    let n = REFRACTION_TABLE;
    let (i, j, l, leaving) = (
        e % n,
        (e / n) % n,
        (e / (n * n)) % REFRACTION_IORS,
        e / (n * n * REFRACTION_IORS) == 1,
    );
    let ior = 1.0 / (1.0 - l as f32 / 9.0).sqrt();
    let eta = if leaving { ior } else { 1.0 / ior };
    (
        (i as f32 / (n - 1) as f32).max(0.02),
        j as f32 / (n - 1) as f32,
        eta,
    )
}

/// [`refraction_albedo`]'s (a, b) at one point, by `strata` × `strata` stratified draws of
/// the visible normals, each refracted (or reflected: past the critical angle, and leaving a
/// volume in the share that Fresnel at the outside angle adds) as `Bsdf::sample_transmission`
/// does in the local frame (z = normal).
#[cfg(test)]
fn integrate_refraction(cos_v: f32, roughness: f32, eta: f32, strata: usize) -> [f32; 2] {
    let alpha = (roughness * roughness).max(crate::shading::MIN_GGX_ALPHA);
    let v = Vec3::new((1.0 - cos_v * cos_v).max(0.0).sqrt(), 0.0, cos_v);
    let lambda_v = smith_lambda(cos_v, alpha);
    let (mut a, mut b) = (0.0f64, 0.0f64);
    for k in 0..strata * strata {
        let u1 = ((k % strata) as f32 + 0.5) / strata as f32;
        let u2 = ((k / strata) as f32 + 0.5) / strata as f32;
        let m = sample_visible_normal(v, alpha, u1, u2);
        let cos_i = m.dot(v).clamp(0.0, 1.0);
        let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
        let c_i5 = f64::from((1.0 - cos_i).powi(5));
        let mirrored = 2.0 * cos_i * m - v;
        // G2/G1 of a draw leaving along `l`, 0 when it leaves on the wrong side: through the
        // surface when reflected, back out of it when refracted.
        let kept = |l: Vec3, reflected: bool| {
            if (l.z < 0.0) == reflected || l == Vec3::ZERO {
                0.0
            } else {
                f64::from((1.0 + lambda_v) / (1.0 + lambda_v + smith_lambda(l.z.abs(), alpha)))
            }
        };
        if sin2_t >= 1.0 {
            // Total internal reflection: weight (1 - F(cos θᵢ))·G2/G1.
            let g = kept(mirrored, true);
            a += g;
            b += g * c_i5;
            continue;
        }
        let cos_t = (1.0 - sin2_t).sqrt();
        let g_refracted = kept(
            (-v * eta + m * (eta * cos_i - cos_t)).normalize_or_zero(),
            false,
        );
        if eta > 1.0 {
            // Leaving: the share (F(cos θₜ) - F(cos θᵢ)) / (1 - F(cos θᵢ)) of the draws reflects
            // back inside, so the mean weight is (1 - F(cos θₜ))·G_refracted + (F(cos θₜ) -
            // F(cos θᵢ))·G_reflected, which with Schlick's F is (1 - F0)·a - (F90 - F0)·b for
            // these a and b.
            let c_t5 = f64::from((1.0 - cos_t).powi(5));
            a += g_refracted;
            b += c_t5 * g_refracted - (c_t5 - c_i5) * kept(mirrored, true);
        } else {
            a += g_refracted;
            b += c_i5 * g_refracted;
        }
    }
    let count = (strata * strata) as f64;
    [(a / count) as f32, (b / count) as f32]
}

#[cfg(test)]
mod tests {
    /// The anisotropic albedo table against independent estimates: with no stretch it is the
    /// isotropic table's lobe (within 2%: the two tables interpolate differently near grazing, 1.6% at cos 0.17), and for stretched lobes it agrees with a
    /// 200,000-draw Monte Carlo estimate of E[G2/G1] within 2%, at views head-on, along the
    /// stretch, across it, between, and grazing.
    #[test]
    fn anisotropic_albedo_matches_independent_estimates() {
        use crate::sampling::Rng;
        let mut rng = Rng::new(11);
        let view = |theta: f32, phi: f32| {
            let (s, c) = theta.sin_cos();
            glam::Vec3::new(s * phi.cos(), s * phi.sin(), c)
        };
        for roughness in [0.1f32, 0.4, 0.8] {
            for theta in [0.0f32, 1.0, 1.4] {
                let v = view(theta, 0.3);
                let alpha = roughness * roughness;
                let (a, _) = super::anisotropic_albedo(v, alpha, alpha);
                let (iso, _) = super::directional_albedo(v.z, roughness);
                assert!(
                    (a - iso).abs() < 0.02 * iso,
                    "r {roughness} θ {theta}: {a} against {iso}"
                );
            }
        }
        for (alpha_x, alpha_y) in [(0.3f32, 0.04f32), (0.7, 0.16), (1.0, 0.09), (1.0, 0.5)] {
            for (theta, phi) in [
                (0.0f32, 0.0f32),
                (1.0, 0.0),
                (1.0, std::f32::consts::FRAC_PI_2),
                (1.0, 0.8),
                (1.4, 1.2),
            ] {
                let v = view(theta, phi);
                let lambda = |w: glam::Vec3| {
                    let t =
                        ((alpha_x * w.x).powi(2) + (alpha_y * w.y).powi(2)) / (w.z * w.z).max(1e-8);
                    0.5 * ((1.0 + t).sqrt() - 1.0)
                };
                let draws = 200_000;
                let mut sum = 0.0f64;
                for _ in 0..draws {
                    let m = super::sample_visible_normal_xy(
                        v,
                        alpha_x,
                        alpha_y,
                        rng.next_f32(),
                        rng.next_f32(),
                    );
                    let l = 2.0 * v.dot(m) * m - v;
                    if l.z > 0.0 {
                        sum += f64::from((1.0 + lambda(v)) / (1.0 + lambda(v) + lambda(l)));
                    }
                }
                let reference = sum / f64::from(draws);
                let (a, _) = super::anisotropic_albedo(v, alpha_x, alpha_y);
                assert!(
                    (f64::from(a) - reference).abs() < 0.02 * reference,
                    "α ({alpha_x}, {alpha_y}), θ {theta}, φ {phi}: table {a}, Monte Carlo {reference}"
                );
            }
        }
    }

    use super::*;

    /// Checks that every entry of a baked table is the integral `computed` gives for it (to
    /// 1e-6: the integrals' sums are in f64, their sines and cosines from the platform's
    /// libm), or with `MESHTRACER_BLESS=1` writes `computed` to src/shading/`file` instead.
    fn check_or_bless(baked: &[[f32; 2]], computed: &[[f32; 2]], file: &str) {
        if std::env::var_os("MESHTRACER_BLESS").is_some() {
            let mut text = String::from("[\n");
            for [a, b] in computed {
                text += &format!("    [{a:?}, {b:?}],\n");
            }
            text += "]\n";
            let path = format!("{}/src/shading/{file}", env!("CARGO_MANIFEST_DIR"));
            std::fs::write(path, text).expect("the table file is writable");
            return;
        }
        assert_eq!(baked.len(), computed.len(), "{file}");
        for (k, (baked, fresh)) in baked.iter().zip(computed).enumerate() {
            for c in 0..2 {
                assert!(
                    (baked[c] - fresh[c]).abs() <= 1e-6,
                    "{file} entry {k}: baked {baked:?}, integrated {fresh:?}"
                );
            }
        }
    }

    /// Every entry of the rough refraction table is the integral it stands for.
    #[test]
    fn the_baked_refraction_table_is_the_integral() {
        let computed: Vec<[f32; 2]> = (0..REFRACTION.len())
            .map(|e| {
                let (cos_v, roughness, eta) = refraction_entry(e);
                integrate_refraction(cos_v, roughness, eta, REFRACTION_STRATA)
            })
            .collect();
        check_or_bless(&REFRACTION, &computed, "ggx_refraction.in");
    }

    /// Every entry of the albedo table is the integral it stands for.
    #[test]
    fn the_baked_albedo_table_is_the_integral() {
        let computed: Vec<[f32; 2]> = (0..ALBEDO.len())
            .map(|k| {
                let (cos_v, roughness) = albedo_entry(k);
                integrate_albedo(cos_v, roughness)
            })
            .collect();
        check_or_bless(&ALBEDO, &computed, "ggx_albedo.in");
    }

    /// The table against an independent Monte Carlo estimate: the glTF BRDF's own D·V
    /// (F = 1 and F = (1 - v·h)⁵) integrated by drawing half vectors from D(h)·n·h (not the
    /// visible normals the table uses), 256 × 256 jittered strata summed in f64, at table
    /// entries and between them, from mirror-like to rough and from head-on to grazing
    /// views. Within 1% (or 0.003 absolute where the value is small).
    #[test]
    fn the_albedo_table_matches_a_monte_carlo_estimate() {
        use crate::sampling::Rng;
        use crate::shading::ggx_dv;
        let mut rng = Rng::new(3);
        for roughness in [0.1f32, 0.3, 0.5, 0.62, 0.75, 1.0] {
            let alpha = (roughness * roughness).max(crate::shading::MIN_GGX_ALPHA);
            for cos in [1.0f32, 0.8, 0.5, 0.27, 0.1] {
                let v = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
                let strata = 256;
                let (mut a, mut b) = (0.0f64, 0.0f64);
                for k in 0..strata * strata {
                    let u = ((k % strata) as f32 + rng.next_f32()) / strata as f32;
                    let phi = std::f32::consts::TAU * ((k / strata) as f32 + rng.next_f32())
                        / strata as f32;
                    // GGX's D(h)·n·h inverted: tan²θ_h = α²·u / (1 - u).
                    let tan2 = alpha * alpha * u / (1.0 - u).max(1e-12);
                    let cos_h = 1.0 / (1.0 + tan2).sqrt();
                    let sin_h = (1.0 - cos_h * cos_h).max(0.0).sqrt();
                    let h = Vec3::new(sin_h * phi.cos(), sin_h * phi.sin(), cos_h);
                    let v_dot_h = v.dot(h);
                    let l = 2.0 * v_dot_h * h - v;
                    if v_dot_h <= 0.0 || l.z <= 0.0 {
                        continue;
                    }
                    // f·cos / pdf with pdf(l) = D(h)·n·h / (4·v·h).
                    let weight = f64::from(ggx_dv(roughness, Vec3::Z, l, v, h))
                        * f64::from(l.z * 4.0 * v_dot_h)
                        / f64::from(ggx_d(cos_h, alpha) * cos_h);
                    a += weight;
                    b += weight * f64::from((1.0 - v_dot_h).powi(5));
                }
                let count = f64::from(strata * strata);
                let (want_a, want_b) = ((a / count) as f32, (b / count) as f32);
                let (got_a, got_b) = directional_albedo(cos, roughness);
                for (got, want) in [(got_a, want_a), (got_b, want_b)] {
                    assert!(
                        (got - want).abs() <= (0.01 * want).max(0.003),
                        "roughness {roughness} cos {cos}: table {got} vs Monte Carlo {want}"
                    );
                }
            }
        }
        // A mirror reflects everything at every angle; roughness loses light.
        assert!((directional_albedo(0.7, 0.0).0 - 1.0).abs() < 0.01);
        assert!(directional_albedo(0.7, 1.0).0 < 0.6);
    }

    /// A white lobe (F0 = F90 = 1) reflects all the light once multiply scattered; a black one
    /// (F0 = F90 = 0) is left alone; the scale grows with roughness.
    #[test]
    fn multiple_scattering_restores_a_white_lobe() {
        for roughness in [0.0f32, 0.25, 0.5, 0.75, 1.0] {
            for cos in [1.0f32, 0.6, 0.2] {
                let (scale, albedo) = multiple_scattering(Vec3::ONE, Vec3::ONE, cos, roughness);
                assert!((albedo.x - 1.0).abs() < 1e-4, "{roughness} {cos}: {albedo}");
                assert!(scale.x >= 1.0);
                let (scale, _) = multiple_scattering(Vec3::ZERO, Vec3::ZERO, cos, roughness);
                assert_eq!(scale, Vec3::ONE);
            }
        }
    }

    /// The average albedo is 2·∫E(μ)μ dμ: 1 for a mirror, falling with roughness. A coloured
    /// rough metal's further bounces each take the Fresnel factor again (Kulla-Conty's F_ms),
    /// so it gets less of the lost light back than F0·(1 - E)/E would give it: at F0 = 0.8,
    /// roughness 1, head-on, F_ms = F_avg·E_avg / (1 - F_avg·(1 - E_avg)) exactly.
    #[test]
    fn coloured_lobes_get_the_multiple_bounce_fresnel() {
        assert!((average_albedo(0.0) - 1.0).abs() < 0.01);
        let mut last = 1.01;
        for roughness in [0.0f32, 0.25, 0.5, 0.75, 1.0] {
            let e_avg = average_albedo(roughness);
            assert!(e_avg < last, "{roughness}: {e_avg}");
            last = e_avg;
        }
        let (a, _) = directional_albedo(1.0, 1.0);
        let e_avg = average_albedo(1.0);
        let f_avg = 0.8 + 0.2 / 21.0;
        let f_ms = f_avg * e_avg / (1.0 - f_avg * (1.0 - e_avg));
        let (scale, _) = multiple_scattering(Vec3::splat(0.8), Vec3::ONE, 1.0, 1.0);
        assert!(
            (scale.x - (1.0 + f_ms * (1.0 - a) / a)).abs() < 1e-4,
            "{scale}"
        );
        assert!(scale.x < 1.0 + 0.8 * (1.0 - a) / a);
    }
}
