//! The glTF metallic-roughness BRDF as a sampled BSDF for the path tracer: evaluation (the same
//! function as [`crate::shading::gltf_brdf`], glTF 2.0 Appendix B), importance sampling and its
//! pdf.
//!
//! Sampling picks one of two lobes with probabilities from their estimated albedo at the view
//! direction, `p_spec = L(F) / (L(F) + L(c_diff)·(1 - L(F)))` (L = luminance, F = Schlick's
//! Fresnel at n·v), then draws
//! - the specular lobe from GGX's distribution of *visible* normals (Heitz, "Sampling the GGX
//!   Distribution of Visible Normals", JCGT 2018): pdf(l) = D(h)·G1(v) / (4·n·v);
//! - the diffuse lobe cosine-weighted: pdf(l) = n·l / π.
//!
//! The returned weight is f·cos / (p_spec·pdf_spec + (1 - p_spec)·pdf_diff), the one-sample MIS
//! of the two lobes, so either choice is unbiased for the whole BRDF. All directions are unit
//! vectors pointing away from the surface; `n` is the shading normal.

use crate::color::luminance;
use crate::sampling::{cosine_hemisphere, frame};
use crate::shading::ggx::{
    ggx_d, sample_visible_normal, sample_visible_normal_xy, smith_g1, smith_lambda,
    visible_normal_pdf,
};
use crate::shading::{
    gltf_brdf, sheen_albedo, Anisotropy, Clearcoat, DiffuseTransmission, SurfaceMaterial,
    MIN_COSINE, MIN_GGX_ALPHA,
};
use glam::{Vec3, Vec3A};
use std::f32::consts::PI;

/// Same floor on α as the direct renderer's BRDF (a mirror-like GGX lobe, finite in f32).
const MIN_ALPHA: f32 = 0.002;

/// A direction drawn from the BSDF.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// The new direction, away from the surface.
    pub direction: Vec3,
    /// f · |n·l| / pdf: what the path throughput is multiplied by.
    pub weight: Vec3,
    /// The pdf of `direction` per steradian (for MIS against light sampling); infinite for a
    /// delta lobe.
    pub pdf: f32,
    /// Drawn from a delta lobe (smooth transmission): no light sample could have found it, so
    /// emission it reaches counts in full.
    pub delta: bool,
}

/// The glTF material at one surface point, ready to evaluate and sample.
#[derive(Clone, Copy, Debug)]
pub struct Bsdf<'a> {
    /// Borrowed from the surface: a copy (112 bytes) per path vertex cost more than the
    /// pointer.
    material: &'a SurfaceMaterial,
    normal: Vec3,
    alpha: f32,
    p_specular: f32,
    /// Whether the specular lobe reflects anything: false when its Fresnel is zero at both
    /// ends (`KHR_materials_specular` with factor 0, an OBJ's `Ks 0 0 0` or `Ni 1`), which
    /// leaves a Lambertian surface.
    reflects: bool,
    /// Chance of drawing the clearcoat's GGX lobe (around the coat's normal), among the
    /// non-delta lobes; 0 without a coat.
    p_coat: f32,
    /// Transmission (glass): the lobe's weight, the chance of drawing it, and how it bends.
    transmission: Option<Transmission>,
    /// The core material's per-point constants, when it has nothing but the core BRDF (and
    /// KHR_materials_specular / _ior, which only change F0 and F90).
    core: Option<Core>,
    /// The chance of drawing `KHR_materials_diffuse_transmission`'s Lambertian lobe through
    /// the wall ([`Bsdf::through_tint`]), drawn as the transmission lobe is (its draws count
    /// emission in full); 0 without it, for metals and where `KHR_materials_transmission`
    /// takes the diffuse base's place. One number, not the lobe: a larger `Bsdf` cost every
    /// other material's path vertices 1% more instructions.
    p_through: f32,
}

/// What [`gltf_brdf`] and [`Bsdf::pdf`] compute again for every light direction at one point
/// of a material with no sheen, clearcoat, iridescence or transmission: the Fresnel ends, the
/// diffuse term, α² and the view direction's factors of the visibility and pdf terms. With
/// them, a light sample costs an unnormalised half vector, two square roots, one division and
/// the Fresnel power; the result is the same function (`core_matches_the_appendix_b_brdf`
/// holds both against an f64 evaluation).
#[derive(Clone, Copy, Debug)]
struct Core {
    /// n·v floored at the BRDF's [`MIN_COSINE`], as [`gltf_brdf`]'s visibility term takes it.
    n_dot_v: f32,
    /// n·v itself (positive), for the half vector's n·h.
    n_dot_v_raw: f32,
    /// α² with α = max(roughness², [`MIN_GGX_ALPHA`]).
    a2: f32,
    /// √((n·v)²(1 - α²) + α²): the view's half of the height-correlated visibility term.
    vis_v: f32,
    /// F0 and F90 of Schlick's Fresnel (metal and dielectric mixed by metalness), times the
    /// lobe's multiple-scattering scale k(v).
    f0: Vec3A,
    f90: Vec3A,
    /// (1 - E_s(v))·c_diff / π: the diffuse base under the specular lobe's albedo.
    diffuse: Vec3A,
    /// p_specular · G1(v) / (4·n·v): the specular lobe's pdf is this times D(h).
    specular_pdf: f32,
    /// (1 - p_specular) / π: the diffuse lobe's pdf is this times n·l.
    diffuse_pdf: f32,
}

/// What [`Bsdf::new`] needs of the specular lobe's multiple scattering at the view: its
/// directional albedo ([`SurfaceMaterial::specular_response`]), what the diffuse base keeps
/// ([`SurfaceMaterial::diffuse_kept`]) and, where it comes from the same evaluation, the
/// scaled Fresnel ends ([`SurfaceMaterial::scaled_fresnel_ends`]).
///
/// For an all-dielectric or all-metal material without a thin film the three come from one
/// [`ggx::multiple_scattering`] of the material's own Fresnel ends (a dielectric's diffuse
/// base is under its own lobe), which the three methods each evaluated again: the same
/// numbers, once instead of three times (the three were 9% of a path-traced Box). A mix of
/// dielectric and metal (0 < metallic < 1) without a film takes its two parts' from one
/// lookup of the tables ([`ggx::AlbedoTerms`]) where the methods made six (6.6% of Suzanne's
/// default render). Thin films take the methods as they are.
struct LobeResponse {
    albedo: Vec3,
    kept: Vec3,
    scaled_ends: Option<(Vec3, Vec3)>,
}

impl LobeResponse {
    #[inline(always)]
    fn of(material: &SurfaceMaterial, n_dot_v: f32) -> Self {
        let filmed = material.iridescence.is_some_and(|film| film.factor > 0.0);
        let (metal, dielectric) = (
            material.metallic == 1.0,
            // +0 exactly: `part(0.0)`, which `diffuse_kept` evaluates, is then the material.
            material.metallic.to_bits() == 0,
        );
        if !filmed && material.iridescence.is_none() && material.is_half_metal() {
            // The mix of the two parts, each compensated for its own Fresnel, from one table
            // lookup: what `specular_response`, `diffuse_kept` and `scaled_fresnel_ends`
            // compute for it, with the same operations, where they took six.
            let terms = material.albedo_terms(n_dot_v);
            let (d0, d90) = material.part(0.0).fresnel_ends();
            let (m0, m90) = material.part(1.0).fresnel_ends();
            let (d90, m90) = (Vec3::splat(d90), Vec3::splat(m90));
            let (scale_d, albedo_d) = terms.multiple_scattering(d0, d90);
            let (scale_m, albedo_m) = terms.multiple_scattering(m0, m90);
            let t = material.metallic;
            return LobeResponse {
                albedo: albedo_d.lerp(albedo_m, t),
                kept: Vec3::ONE - albedo_d,
                scaled_ends: Some((
                    (d0 * scale_d).lerp(m0 * scale_m, t),
                    (d90 * scale_d).lerp(m90 * scale_m, t),
                )),
            };
        }
        if filmed || !(metal || dielectric) {
            return LobeResponse {
                albedo: material.specular_response(n_dot_v).1,
                kept: material.diffuse_kept(n_dot_v),
                scaled_ends: None,
            };
        }
        let (f0, f90) = material.fresnel_ends();
        let f90 = Vec3::splat(f90);
        let (scale, albedo) = material.multiple_scattering(f0, f90, n_dot_v);
        LobeResponse {
            albedo,
            kept: if dielectric {
                Vec3::ONE - albedo
            } else {
                material.diffuse_kept(n_dot_v)
            },
            scaled_ends: Some((f0 * scale, f90 * scale)),
        }
    }
}

/// The specular transmission lobe of `KHR_materials_transmission` (glTF: the dielectric's
/// diffuse lobe replaced, in proportion `factor`, by transmission tinted by the base colour).
/// Smooth glass refracts into one direction. Rough glass (α = roughness² above the mirror
/// floor) spreads it by the material's GGX microfacets, drawn from the visible normals (Heitz
/// 2018) for the view: Walter et al.'s microfacet refraction ("Microfacet Models for Refraction
/// through Rough Surfaces", EGSR 2007) through a volume, and for a thin-walled sheet the
/// reflection about the microfacet mirrored through the surface (the glTF transmission
/// extension's thin-walled BTDF). Either way the sample's weight is (1 - F(v·m))·G2/G1 times
/// the lobe's tint. The lobe is drawn by [`Bsdf::sample`], and evaluated for light samples
/// only for punctual lights through a rough thin sheet ([`Bsdf::thin_transmission_cos`]),
/// which nothing else can find (shadow rays do not pass through glass volumes); its samples
/// count as delta ones: emission they reach is counted in full, which keeps the estimate
/// unbiased.
#[derive(Clone, Copy, Debug)]
struct Transmission {
    /// `transmission` × (1 - metallic).
    factor: f32,
    /// Chance that [`Bsdf::sample`] draws the transmission lobe.
    probability: f32,
    /// Relative index of refraction across the surface in the ray's direction of travel
    /// (outside / inside when entering); 1 for a thin-walled sheet (no bending).
    eta: f32,
    /// What a rough lobe's draws are scaled by so that its albedo is what the specular layer
    /// leaves ([`transmission_scale`]); 1 for smooth ones.
    scale: f32,
    /// `KHR_materials_dispersion` ([`Bsdf::with_dispersion`]): how far the red and blue
    /// channels' indices of refraction lie below and above the material's; 0 without
    /// dispersion (and through thin walls, which do not bend light).
    spread: f32,
    /// The colour channel (0-2) whose index a dispersed path already follows, or
    /// [`ANY_CHANNEL`]: the draw picks one.
    channel: u8,
}

/// [`Transmission::channel`] when the path carries every colour: a dispersive draw picks one.
const ANY_CHANNEL: u8 = 3;

impl Transmission {
    /// The lobe as colour channel c sees it, with the weight its draws carry and what is
    /// left of `u` for the draw, where the material disperses light
    /// (`KHR_materials_dispersion`). The extension's per-channel indices (its non-normative
    /// method, which the Khronos Sample Viewer uses): ior - s, ior and ior + s for red, green
    /// and blue with s = (ior - 1)·0.025·dispersion, that is ±½·(n_F - n_C) about the
    /// material's index, which is the green channel's, and red's at least 1.
    ///
    /// A path that carries every colour draws c uniformly from `u` (its remainder stays
    /// uniform for the draw) and weighs 3 in channel c alone, 0 in the others: each channel's
    /// estimate is then its own index's, unbiased. A path that already carries one channel
    /// (it was dispersed before, or its colours are filtered to one) keeps following it,
    /// weight 1, so that leaving a volume bends it by the index it entered by. Green keeps
    /// the lobe's own `eta`, bit for bit.
    #[inline]
    fn dispersed(self, u: f32) -> (Transmission, Vec3, f32) {
        if self.spread == 0.0 {
            return (self, Vec3::ONE, u);
        }
        let (c, u, weight) = if self.channel < ANY_CHANNEL {
            (usize::from(self.channel), u, 1.0)
        } else {
            let x = u * 3.0;
            let c = (x as usize).min(2);
            (c, (x - c as f32).min(1.0 - f32::EPSILON / 2.0), 3.0)
        };
        let eta = if c == 1 {
            self.eta
        } else {
            // eta is 1/ior entering the volume and ior leaving it.
            let entering = self.eta < 1.0;
            let ior = if entering { 1.0 / self.eta } else { self.eta };
            let ior = (ior + (c as f32 - 1.0) * self.spread).max(1.0);
            if entering {
                1.0 / ior
            } else {
                ior
            }
        };
        let mut mask = Vec3::ZERO;
        mask[c] = weight;
        (Transmission { eta, ..self }, mask, u)
    }
}

/// The multiple-scattering scale of a rough transmission lobe at the view (cos θ_v =
/// `n_dot_v`), through a thin sheet (`eta` 1) or into or out of a volume. A draw weighs
/// (1 - F(v·m))·G2/G1, whose mean over the draws is a·(1 - F0) - (F90 - F0)·b: for a thin
/// sheet, whose draws mirror a visible-normal reflection through it, (a, b) of
/// [`ggx::directional_albedo`]; for a volume, of [`ggx::refraction_albedo`]. What
/// microfacets scatter more than once is lost to it: a white thin sheet at roughness 1 kept
/// 0.31 of the light head-on, a white glass surface at roughness 1 (index 1.5) 0.43-0.90.
/// The scale makes the lobe's albedo the share the multiply scattered specular layer leaves
/// to the base (1 - its albedo, as the diffuse base is given it), so that a white sheet or
/// glass surface reflects and transmits all the light that arrives: the albedo scaling the
/// glTF specification uses for layering, applied to transmission.
///
/// `kept` is [`SurfaceMaterial::diffuse_kept`] at the view, which the caller has at hand.
fn transmission_scale(material: &SurfaceMaterial, n_dot_v: f32, eta: f32, kept: Vec3) -> f32 {
    let (a, b) = if eta == 1.0 {
        super::ggx::directional_albedo(n_dot_v, material.roughness)
    } else {
        super::ggx::refraction_albedo(n_dot_v, material.roughness, eta)
    };
    let (f0, f90) = material.fresnel_ends();
    let single = luminance((Vec3::ONE - f0) * a - (Vec3::splat(f90) - f0) * b);
    let kept = luminance(kept);
    if single > 1e-4 {
        kept / single
    } else {
        1.0
    }
}

/// The chance of drawing the specular lobe rather than the diffuse one, from their albedos
/// `fresnel` and `diffuse` at the view: at least 0.05, so that highlights the albedo underrates
/// are still drawn, except for a lobe that reflects nothing, whose draws would all be wasted
/// (the diffuse lobe covers the hemisphere alone, so the estimate stays unbiased).
fn specular_probability(fresnel: f32, diffuse: f32, reflects: bool) -> f32 {
    if !reflects && diffuse > 0.0 {
        0.0
    } else if fresnel + diffuse > 0.0 {
        (fresnel / (fresnel + diffuse)).clamp(0.05, 1.0)
    } else {
        1.0
    }
}

impl<'a> Bsdf<'a> {
    /// The BSDF of `material` around the unit shading normal `normal`, seen from `to_eye`.
    #[inline(always)]
    pub fn new(material: &'a SurfaceMaterial, normal: Vec3, to_eye: Vec3) -> Self {
        let alpha = (material.roughness * material.roughness).max(MIN_ALPHA);
        let n_dot_v = normal.dot(to_eye).clamp(0.0, 1.0);
        // The lobes' albedos at the view: the multiply scattered specular lobe's, and the
        // diffuse base's, which keeps what the specular lobe does not reflect.
        let response = LobeResponse::of(material, n_dot_v);
        let c_diff = material.diffuse_reflectance();
        let fresnel = luminance(response.albedo);
        let kept = response.kept;
        let mut diffuse = luminance(c_diff * kept);
        let through = material
            .diffuse_transmission
            .filter(|_| material.metallic < 1.0)
            .map(|d| luminance(through_tint(material, d, kept)));
        // A sheen is drawn with the cosine lobe: its albedo joins the diffuse one.
        if let Some(sheen) = material.sheen {
            diffuse += sheen.color.max_element() * sheen_albedo(n_dot_v, sheen.roughness);
        }
        // Zero scaled Fresnel ends make the core BRDF's specular term zero for every pair of
        // directions (a thin film, which reflects over them, gives no scaled ends).
        let reflects = response.scaled_ends != Some((Vec3::ZERO, Vec3::ZERO));
        let p_specular = specular_probability(fresnel, diffuse, reflects);
        // The coat's share: its reflectance against what the base below it still reflects.
        let p_coat = material.clearcoat.map_or(0.0, |c| {
            let coat = c.weight * Clearcoat::fresnel(c.normal.dot(to_eye));
            let below = (1.0 - coat) * (fresnel + diffuse);
            if coat + below > 0.0 {
                (coat / (coat + below)).clamp(0.05, 0.95)
            } else {
                0.0
            }
        });
        let plain = material.sheen.is_none()
            && material.clearcoat.is_none()
            && material.anisotropy.is_none()
            && through.is_none()
            && material.iridescence.is_none_or(|film| film.factor <= 0.0);
        let n_dot_v_raw = normal.dot(to_eye);
        let core = (plain && n_dot_v_raw > 0.0).then(|| {
            // The same α as gltf_brdf's GGX (its floor equals MIN_ALPHA).
            let ggx_alpha = (material.roughness * material.roughness).max(MIN_GGX_ALPHA);
            let a2 = ggx_alpha * ggx_alpha;
            // At the clamped view cosine, as the lobe's albedo above.
            let (f0s, f90s) = response
                .scaled_ends
                .unwrap_or_else(|| material.scaled_fresnel_ends(n_dot_v));
            let n_dot_v = n_dot_v_raw.max(MIN_COSINE);
            Core {
                n_dot_v,
                n_dot_v_raw,
                a2,
                vis_v: (n_dot_v * n_dot_v * (1.0 - a2) + a2).sqrt(),
                f0: f0s.into(),
                f90: f90s.into(),
                diffuse: (c_diff * kept / PI).into(),
                specular_pdf: p_specular * smith_g1(n_dot_v_raw, alpha) / (4.0 * n_dot_v_raw),
                diffuse_pdf: (1.0 - p_specular) / PI,
            }
        });
        // The through lobe's share of the draws: its albedo against the reflecting lobes'.
        let p_through = through.map_or(0.0, |t| {
            let total = t + fresnel + diffuse;
            if total > 0.0 {
                t / total
            } else {
                0.0
            }
        });
        Self {
            material,
            normal,
            alpha,
            p_specular,
            reflects,
            p_coat,
            transmission: None,
            core,
            p_through,
        }
    }

    /// The diffuse transmission lobe's albedo at the view `to_eye` (f = tint/π on the far
    /// side); zero without the lobe.
    fn through_tint(&self, to_eye: Vec3) -> Vec3 {
        match self.material.diffuse_transmission {
            Some(d) if self.p_through > 0.0 => {
                let n_dot_v = self.normal.dot(to_eye).clamp(0.0, 1.0);
                through_tint(self.material, d, self.material.diffuse_kept(n_dot_v))
            }
            _ => Vec3::ZERO,
        }
    }

    /// f·cos and the pdf for `to_light` from the per-point constants (see [`Core`]): the same
    /// function as [`gltf_brdf`] and [`Bsdf::pdf`], with what depends only on the view done
    /// once.
    ///
    /// The half vector is never normalised: with the unnormalised k = l + v and s = k·k,
    /// n·h = n·k / √s and v·h = v·k / √s, so GGX's d_denom = n·h²(α² - 1) + 1 is q / s with
    /// q = s - (n·k)²(1 - α²). Then D = α²s² / (π·q²), V = 0.5 / vis_denom, and one division
    /// w = 1 / (π·q²·vis_denom·√s) gives both D·V = 0.5·α²·s²·√s·w and v·h = v·k·π·q²·vis_denom·w.
    /// (A normalised h cost a square root and a division more, in series, on the latency
    /// chain of every light sample.) Both directions are above the surface here, so
    /// n·k > 0, s ≥ (n·k)² > 0 and q ≥ α²(n·k)² > 0.
    #[inline(always)]
    fn core_eval_pdf(&self, core: &Core, to_eye: Vec3, to_light: Vec3) -> (Vec3, f32) {
        // In SIMD lanes (Vec3A): lane by lane the same operations as with Vec3, so the same
        // bits, in fewer instructions (three evaluations a path vertex).
        let n = Vec3A::from(self.normal);
        let (to_eye, to_light) = (Vec3A::from(to_eye), Vec3A::from(to_light));
        let cos = n.dot(to_light);
        if cos <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        if !self.reflects {
            // Lambertian: what the lines below give when the Fresnel ends and the specular
            // pdf (p_specular 0) are zero, bit for bit: diffuse + 0 and 0 + the diffuse pdf.
            return ((core.diffuse * cos).into(), core.diffuse_pdf * cos);
        }
        let k = to_light + to_eye;
        let s = k.dot(k);
        let n_dot_k = cos + core.n_dot_v_raw;
        let v_dot_k = to_eye.dot(k);
        let a2 = core.a2;
        // q = s - (n·k)²(1 - α²) = |n × k|² + α²(n·k)²: written with the cross product it
        // keeps its precision at GGX's peak (h near n), where the difference cancels.
        let tangential = n.cross(k);
        let q = tangential.dot(tangential) + a2 * n_dot_k * n_dot_k;
        let n_dot_l = cos.max(MIN_COSINE);
        let vis_denom =
            n_dot_l * core.vis_v + core.n_dot_v * (n_dot_l * n_dot_l * (1.0 - a2) + a2).sqrt();
        let root_s = s.sqrt();
        let pi_q2_vis = PI * q * q * vis_denom;
        let w = 1.0 / (pi_q2_vis * root_s);
        let s2_root_s_w = s * s * root_s * w;
        let v_dot_h = (v_dot_k * pi_q2_vis * w).clamp(0.0, 1.0);
        let fresnel = core.f0 + (core.f90 - core.f0) * (1.0 - v_dot_h).powi(5);
        let f = core.diffuse + fresnel * (0.5 * a2 * s2_root_s_w);
        // D = α²·s²/(π·q²) = α²·vis_denom·s²·√s·w.
        let d = a2 * vis_denom * s2_root_s_w;
        let pdf = core.specular_pdf * d + core.diffuse_pdf * cos;
        ((f * cos).into(), pdf)
    }

    /// [`Bsdf::eval_cos`] and [`Bsdf::pdf`] of one direction together (a light sample weighed
    /// by MIS needs both; they share the half vector and D).
    ///
    /// The core material's evaluation is inlined into the caller (the path tracer calls this
    /// two or three times a vertex; as calls, their vectors went through memory); the layered
    /// materials' is a call.
    #[inline(always)]
    pub fn eval_pdf(&self, to_eye: Vec3, to_light: Vec3) -> (Vec3, f32) {
        match &self.core {
            Some(core) => self.core_eval_pdf(core, to_eye, to_light),
            None => self.general_eval_pdf(to_eye, to_light),
        }
    }

    /// [`Bsdf::eval_pdf`] without the per-point constants: the layered materials.
    #[inline(never)]
    fn general_eval_pdf(&self, to_eye: Vec3, to_light: Vec3) -> (Vec3, f32) {
        (
            self.general_eval_cos(to_eye, to_light),
            self.pdf(to_eye, to_light),
        )
    }

    /// Adds the transmission lobe: `factor` from `KHR_materials_transmission`, `ior`, whether
    /// the surface is a thin sheet, and whether the ray enters the volume (hit its front face).
    /// The diffuse lobe keeps (1 - factor) of its weight; transmission gets the rest, times
    /// (1 - F) and the base colour.
    pub fn with_transmission(
        mut self,
        to_eye: Vec3,
        factor: f32,
        ior: f32,
        thin_walled: bool,
        entering: bool,
    ) -> Self {
        let factor = factor.clamp(0.0, 1.0) * (1.0 - self.material.metallic);
        if factor <= 0.0 {
            return self;
        }
        let eta = if thin_walled {
            1.0
        } else if entering {
            1.0 / ior
        } else {
            ior
        };
        let n_dot_v = self.normal.dot(to_eye).clamp(0.0, 1.0);
        let albedo = self.material.specular_response(n_dot_v).1;
        let fresnel = luminance(albedo);
        let transmit = factor * luminance(self.material.base_color) * (1.0 - fresnel);
        let diffuse = luminance(self.material.base_color * (1.0 - self.material.metallic))
            * (1.0 - fresnel)
            * (1.0 - factor);
        let total = fresnel + diffuse + transmit;
        let probability = if total > 0.0 { transmit / total } else { 0.0 };
        // The other lobes share what is left in their old proportion.
        self.p_specular = specular_probability(fresnel, diffuse, self.reflects);
        let scale = if self.alpha > MIN_ALPHA {
            // What the base keeps: for a dielectric 1 - the albedo just computed (the same
            // evaluation `diffuse_kept` would repeat), else the dielectric part's.
            let kept = if self.material.metallic == 0.0 {
                Vec3::ONE - albedo
            } else {
                self.material.diffuse_kept(n_dot_v)
            };
            transmission_scale(self.material, n_dot_v, eta, kept)
        } else {
            1.0
        };
        self.transmission = Some(Transmission {
            factor,
            probability,
            eta,
            scale,
            spread: 0.0,
            channel: ANY_CHANNEL,
        });
        self.core = None;
        // KHR_materials_diffuse_transmission: "the transmission effect overrides the diffuse
        // transmission effect" (approximated: its share of the base is not reflected either).
        self.p_through = 0.0;
        self
    }

    /// Adds `KHR_materials_dispersion` (`dispersion` = 20 / the Abbe number, on a material of
    /// index `ior`) to the transmission lobe of a volume's boundary: its draws then refract
    /// one colour channel by that channel's index (ior - s, ior, ior + s for red, green and
    /// blue, s = (ior - 1)·0.025·dispersion): `channel`, the one a path already carries alone
    /// (weight 1), else one drawn at random (weight 3 in it, 0 in the others). Nothing changes
    /// without a transmission lobe or through a thin wall (no bending, so no dispersion).
    /// The rough lobe's multiple-scattering scale stays the material's index's
    /// (approximated: the channels' indices differ by a few percent).
    pub fn with_dispersion(mut self, dispersion: f32, ior: f32, channel: Option<usize>) -> Self {
        if let Some(t) = &mut self.transmission {
            if t.eta != 1.0 && dispersion > 0.0 && dispersion.is_finite() {
                t.spread = (ior - 1.0).max(0.0) * 0.025 * dispersion;
                t.channel = channel.map_or(ANY_CHANNEL, |c| c.min(2) as u8);
            }
        }
        self
    }

    /// The share of the diffuse lobe left after transmission took its part.
    fn diffuse_share(&self) -> f32 {
        1.0 - self.transmission.map_or(0.0, |t| t.factor)
    }

    /// Chance of drawing a non-delta lobe (reflection or diffuse).
    fn p_nondelta(&self) -> f32 {
        1.0 - self.transmission.map_or(0.0, |t| t.probability) - self.p_through
    }

    /// f(v, l) · max(n·l, 0): the reflected radiance per unit incident radiance from `to_light`.
    /// Inlined for the core material, as [`Bsdf::eval_pdf`].
    #[inline(always)]
    pub fn eval_cos(&self, to_eye: Vec3, to_light: Vec3) -> Vec3 {
        match &self.core {
            Some(core) => self.core_eval_pdf(core, to_eye, to_light).0,
            None => self.general_eval_cos(to_eye, to_light),
        }
    }

    /// [`Bsdf::eval_cos`] without the per-point constants: the layered materials (and points
    /// seen from below, which evaluate to zero).
    #[inline(never)]
    fn general_eval_cos(&self, to_eye: Vec3, to_light: Vec3) -> Vec3 {
        let cos = self.normal.dot(to_light);
        if cos <= 0.0 || self.normal.dot(to_eye) <= 0.0 {
            return Vec3::ZERO;
        }
        let share = self.diffuse_share();
        if share >= 1.0 {
            return gltf_brdf(self.material, self.normal, to_light, to_eye) * cos;
        }
        // The diffuse part scaled by its share: f = f_spec + share · f_diffuse, where the full
        // BRDF and its specular part (black base: c_diff = 0) are the Appendix B functions.
        let full = gltf_brdf(self.material, self.normal, to_light, to_eye);
        let specular_only = gltf_brdf(
            &SurfaceMaterial {
                base_color: Vec3::ZERO,
                metallic: 0.0,
                ..*self.material
            },
            self.normal,
            to_light,
            to_eye,
        );
        (specular_only + (full - specular_only) * share) * cos
    }

    /// The pdf per steradian with which [`Bsdf::sample`] draws `to_light`.
    pub fn pdf(&self, to_eye: Vec3, to_light: Vec3) -> f32 {
        let n = self.normal;
        let (n_dot_v, n_dot_l) = (n.dot(to_eye), n.dot(to_light));
        if n_dot_v <= 0.0 || n_dot_l <= 0.0 {
            return 0.0;
        }
        let h = (to_eye + to_light).normalize_or_zero();
        let specular = match &self.material.anisotropy {
            // D(h)·G1(v) / (4·n·v), as for the isotropic lobe.
            Some(a) => a.d(n, h) / ((1.0 + a.lambda(n, to_eye)) * 4.0 * n_dot_v),
            None => visible_normal_pdf(n, h, n_dot_v, self.alpha),
        };
        let base = self.p_specular * specular + (1.0 - self.p_specular) * n_dot_l / PI;
        let coat = match self.material.clearcoat {
            Some(c) if self.p_coat > 0.0 => {
                let (cv, cl) = (c.normal.dot(to_eye), c.normal.dot(to_light));
                if cv > 0.0 && cl > 0.0 {
                    visible_normal_pdf(c.normal, h, cv, coat_alpha(&c))
                } else {
                    0.0
                }
            }
            _ => 0.0,
        };
        self.p_nondelta() * (self.p_coat * coat + (1.0 - self.p_coat) * base)
    }

    /// Draws a direction from two uniform numbers in [0, 1) and a third choosing the lobe.
    /// `None` when the draw falls below the surface (the sample is then worth nothing).
    #[inline(always)]
    pub fn sample(&self, to_eye: Vec3, u_lobe: f32, u1: f32, u2: f32) -> Option<BsdfSample> {
        let n = self.normal;
        if n.dot(to_eye) <= 0.0 {
            return None;
        }
        if let Some(transmission) = self.transmission {
            if u_lobe < transmission.probability {
                // The lobe number within this lobe: uniform again, for its own choice.
                let u_inside = u_lobe / transmission.probability;
                return self.sample_transmission(to_eye, transmission, [u1, u2, u_inside]);
            }
        }
        if u_lobe < self.p_through {
            // A cosine-weighted direction on the far side: f·|cos|/pdf = tint / probability.
            let (t, b) = frame(n);
            let d = cosine_hemisphere(u1, u2);
            return Some(BsdfSample {
                direction: t * d.x + b * d.y - n * d.z,
                weight: self.through_tint(to_eye) / self.p_through,
                pdf: f32::INFINITY,
                delta: true,
            });
        }
        // Reuse the lobe number within the non-delta lobes.
        let delta = self.transmission.map_or(0.0, |t| t.probability) + self.p_through;
        let u_lobe = if delta > 0.0 && delta < 1.0 {
            (u_lobe - delta) / (1.0 - delta)
        } else {
            u_lobe
        };
        let direction = match self.material.clearcoat {
            Some(c) if u_lobe < self.p_coat => reflect(to_eye, c.normal, coat_alpha(&c), u1, u2)?,
            _ => {
                // Reuse the lobe number within the base's lobes.
                let u_lobe = (u_lobe - self.p_coat) / (1.0 - self.p_coat);
                if u_lobe < self.p_specular {
                    match (&self.core, &self.material.anisotropy) {
                        // A plain material (`core`) is never anisotropic: its draws do not
                        // read the material.
                        (None, Some(a)) => reflect_anisotropic(to_eye, n, a, u1, u2)?,
                        _ => reflect(to_eye, n, self.alpha, u1, u2)?,
                    }
                } else {
                    let (t, b) = frame(n);
                    let d = cosine_hemisphere(u1, u2);
                    t * d.x + b * d.y + n * d.z
                }
            }
        };
        let (f, pdf) = self.eval_pdf(to_eye, direction);
        if pdf <= 0.0 || !pdf.is_finite() {
            return None;
        }
        let weight = f / pdf;
        weight.is_finite().then_some(BsdfSample {
            direction,
            weight,
            pdf,
            delta: false,
        })
    }

    /// Whether light passes through this point as through a rough thin-walled sheet (a
    /// transmission lobe, no bending, roughness above the mirror floor): what
    /// [`Bsdf::thin_transmission_cos`] evaluates.
    #[inline]
    pub fn transmits_thin_rough(&self) -> bool {
        self.transmission.is_some_and(|t| t.eta == 1.0) && self.alpha > MIN_ALPHA
    }

    /// Whether a punctual light on the far side reaches the eye through this point: a rough
    /// thin sheet, or a diffuse transmission lobe. [`Bsdf::thin_transmission_cos`] evaluates
    /// both.
    #[inline]
    pub fn shines_through(&self) -> bool {
        self.p_through > 0.0 || self.transmits_thin_rough()
    }

    /// f(v, l) · |n·l| of the transmission lobe of a rough thin-walled sheet, and of
    /// `KHR_materials_diffuse_transmission`'s Lambertian lobe (`tint`/π), for `to_light` on
    /// the far side of the sheet (zero otherwise, and for smooth sheets and volumes). The lobe
    /// `Bsdf::sample_transmission` draws mirrors a GGX reflection through the sheet, so its
    /// value is the reflection's with the light mirrored back to the eye's side, l' = l -
    /// 2(n·l)n, h = normalize(v + l'), (1 - F(v·h)) for F and the base colour as tint:
    /// factor · base · (1 - F) · D(h) · G2(v, l') / (4 n·v). Its ratio to the density of the
    /// draw (the visible normals' D·G1/(4 n·v)) is the draw's weight, (1 - F) · G2/G1.
    ///
    /// Only punctual lights use it ([`crate::integrator::PathTracer`]): BSDF samples never
    /// find them, so light through a frosted sheet (a lamp's shade around its bulb) reaches
    /// the eye by this term or not at all. Area lights and the environment behind a sheet are
    /// found by the drawn lobe, counted in full, and need no second estimate.
    pub fn thin_transmission_cos(&self, to_eye: Vec3, to_light: Vec3) -> Vec3 {
        let n = self.normal;
        let (n_dot_v, n_dot_l) = (n.dot(to_eye), n.dot(to_light));
        // KHR_materials_diffuse_transmission: the Lambertian lobe on the far side.
        let through = if n_dot_v > 0.0 && n_dot_l < 0.0 {
            self.through_tint(to_eye) * (-n_dot_l / PI)
        } else {
            Vec3::ZERO
        };
        through + self.rough_sheet_cos(to_eye, to_light)
    }

    /// [`Bsdf::thin_transmission_cos`]'s rough thin sheet.
    fn rough_sheet_cos(&self, to_eye: Vec3, to_light: Vec3) -> Vec3 {
        if !self.transmits_thin_rough() {
            return Vec3::ZERO;
        }
        let Some(t) = self.transmission else {
            return Vec3::ZERO;
        };
        let n = self.normal;
        let (n_dot_v, n_dot_l) = (n.dot(to_eye), n.dot(to_light));
        if n_dot_v <= 0.0 || n_dot_l >= 0.0 {
            return Vec3::ZERO;
        }
        let mirrored = to_light - 2.0 * n_dot_l * n;
        let h = (to_eye + mirrored).normalize_or_zero();
        let n_dot_h = n.dot(h);
        if n_dot_h <= 0.0 {
            return Vec3::ZERO;
        }
        let v_dot_h = to_eye.dot(h).clamp(0.0, 1.0);
        let fresnel = luminance(self.material.reflectance(v_dot_h, n_dot_v));
        let g2 =
            1.0 / (1.0 + smith_lambda(n_dot_v, self.alpha) + smith_lambda(-n_dot_l, self.alpha));
        let d = ggx_d(n_dot_h, self.alpha);
        self.material.base_color * (t.factor * t.scale * (1.0 - fresnel) * d * g2 / (4.0 * n_dot_v))
    }

    /// The transmission lobe: straight through a thin sheet, refracted by Snell's law into or
    /// out of a volume (total internal reflection turns it into a mirror reflection), about
    /// the surface normal when smooth and about a drawn microfacet normal when rough.
    ///
    /// Leaving a volume, `u_inside` (uniform in [0, 1)) sends a share of the draws back in as
    /// internal reflections. Schlick's Fresnel is written for light arriving from the less
    /// dense side; Fresnel's equations give the same reflectance for the angles on either side
    /// of the surface (θᵢ inside, θₜ outside, related by Snell's law), so from inside the
    /// reflectance at θᵢ is Schlick's at cos θₜ, which rises to 1 at the critical angle as
    /// total internal reflection requires (the usual dense-side form of the approximation,
    /// e.g. Lagarde's "Memo on Fresnel equations", 2013). The reflection lobe reflects
    /// F(cos θᵢ) (Schlick at the inside angle: 0.040 at cos θᵢ = 0.8 in glass of index 1.5,
    /// where F(cos θₜ) is 0.095 and the exact value 0.114); this lobe turns the difference
    /// back, the share (F(cos θₜ) - F(cos θᵢ)) / (1 - F(cos θᵢ)) of its draws (at the drawn
    /// microfacet, for rough glass), without changing their Fresnel factor, so the two lobes
    /// together reflect F(cos θₜ) and transmit the rest. These reflections, like those past
    /// the critical angle, are not tinted by the base colour. Rough glass's draws' mean
    /// weight, which [`ggx::refraction_albedo`] tabulates, includes these reflections.
    fn sample_transmission(
        &self,
        to_eye: Vec3,
        t: Transmission,
        [u1, u2, u_inside]: [f32; 3],
    ) -> Option<BsdfSample> {
        let (t, channels, u_inside) = t.dispersed(u_inside);
        let n = self.normal;
        let rough = self.alpha > MIN_ALPHA;
        // The facet that refracts: the surface itself, or a visible GGX normal.
        let (m, shadowing) = if rough {
            let (tx, ty) = frame(n);
            let local = Vec3::new(to_eye.dot(tx), to_eye.dot(ty), to_eye.dot(n));
            let h = sample_visible_normal(local, self.alpha, u1, u2);
            (tx * h.x + ty * h.y + n * h.z, true)
        } else {
            (n, false)
        };
        let cos_i = m.dot(to_eye).clamp(0.0, 1.0);
        let fresnel = luminance(self.material.reflectance(cos_i, n.dot(to_eye)));
        let sin2_t = t.eta * t.eta * (1.0 - cos_i * cos_i);
        let mirrored = 2.0 * cos_i * m - to_eye;
        // The direction, and whether it reflects back off the facet (inside a volume).
        let (direction, reflected) = if t.eta == 1.0 {
            if rough {
                // Thin-walled: the reflection about the facet, mirrored through the sheet.
                (mirrored - 2.0 * mirrored.dot(n) * n, false)
            } else {
                (-to_eye, false)
            }
        } else if sin2_t >= 1.0 {
            (mirrored, true)
        } else {
            let cos_t = (1.0 - sin2_t).sqrt();
            if t.eta > 1.0 && u_inside < self.internal_share(fresnel, cos_t, n, to_eye) {
                (mirrored, true)
            } else {
                let refracted = -to_eye * t.eta + m * (t.eta * cos_i - cos_t);
                (refracted.normalize_or_zero(), false)
            }
        };
        if direction == Vec3::ZERO || t.probability <= 0.0 {
            return None;
        }
        // The base colour tints what goes through (glTF's BTDF), not what reflects back inside:
        // that is Fresnel reflection, the specular BRDF's share, which glTF leaves untinted.
        let tint = if reflected {
            Vec3::ONE
        } else {
            self.material.base_color
        };
        let mut weight = tint * (t.factor * (1.0 - fresnel) / t.probability);
        if shadowing {
            // Through the surface (or, reflected back inside, back out of it): on the wrong
            // side the draw is lost. G2/G1 = (1 + Λ(v)) / (1 + Λ(v) + Λ(l)).
            let through = direction.dot(n) < 0.0;
            if through == reflected {
                return None;
            }
            let (lv, ll) = (
                smith_lambda(n.dot(to_eye), self.alpha),
                smith_lambda(direction.dot(n).abs(), self.alpha),
            );
            weight *= t.scale * (1.0 + lv) / (1.0 + lv + ll);
        }
        weight *= channels;
        weight.is_finite().then_some(BsdfSample {
            direction,
            weight,
            pdf: f32::INFINITY,
            delta: true,
        })
    }

    /// The share of a volume's transmitted draws that reflect back inside (see
    /// [`Bsdf::sample_transmission`]): `fresnel`, the reflectance at the inside angle, against
    /// Schlick's at the outside one (cosine `cos_t`).
    #[inline]
    fn internal_share(&self, fresnel: f32, cos_t: f32, n: Vec3, to_eye: Vec3) -> f32 {
        let outside = luminance(self.material.reflectance(cos_t, n.dot(to_eye)));
        if fresnel < 1.0 {
            ((outside - fresnel) / (1.0 - fresnel)).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }
}

/// The diffuse transmission lobe's albedo: what the base keeps under the specular layer
/// (`kept`) × weight × (1 - metallic) × colour.
#[inline]
fn through_tint(material: &SurfaceMaterial, d: DiffuseTransmission, kept: Vec3) -> Vec3 {
    kept * d.color * (d.weight * (1.0 - material.metallic))
}

/// `to_eye` mirrored about a GGX visible normal drawn around `n` with roughness `alpha` from
/// (`u1`, `u2`); `None` when the result is not a direction.
#[inline(always)]
fn reflect(to_eye: Vec3, n: Vec3, alpha: f32, u1: f32, u2: f32) -> Option<Vec3> {
    let (t, b) = frame(n);
    let local = Vec3::new(to_eye.dot(t), to_eye.dot(b), to_eye.dot(n));
    let m = sample_visible_normal(local, alpha, u1, u2);
    let h = t * m.x + b * m.y + n * m.z;
    (2.0 * to_eye.dot(h) * h - to_eye).try_normalize()
}

/// [`reflect`] about a visible normal of the anisotropic lobe `a` around `n`, drawn in its
/// own frame (tangent, n × tangent, n).
#[inline(never)]
fn reflect_anisotropic(to_eye: Vec3, n: Vec3, a: &Anisotropy, u1: f32, u2: f32) -> Option<Vec3> {
    let (t, b) = a.axes(n);
    let local = Vec3::new(to_eye.dot(t), to_eye.dot(b), to_eye.dot(n));
    let m = sample_visible_normal_xy(local, a.alpha_t, a.alpha_b, u1, u2);
    let h = t * m.x + b * m.y + n * m.z;
    (2.0 * to_eye.dot(h) * h - to_eye).try_normalize()
}

/// The clearcoat lobe's α (its roughness squared, floored as the base lobe's).
fn coat_alpha(c: &Clearcoat) -> f32 {
    (c.roughness * c.roughness).max(MIN_ALPHA)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    use crate::shading::test_material as material;
    use crate::shading::test_views;

    /// The glTF Appendix B metallic-roughness BRDF, multiply scattered, times n·l for a
    /// material without layers, in f64: the same floors (MIN_COSINE, MIN_GGX_ALPHA) as [`gltf_brdf`], a normalised half
    /// vector, no rearrangement. Also returns GGX's D(h), for the pdf, and its denominator
    /// n·h²(α² - 1) + 1.
    fn appendix_b_f64(m: &SurfaceMaterial, n: Vec3, v: Vec3, l: Vec3) -> ([f64; 3], f64, f64) {
        use glam::DVec3;
        let (n, v, l) = (n.as_dvec3(), v.as_dvec3(), l.as_dvec3());
        let cos = n.dot(l);
        if cos <= 0.0 || n.dot(v) <= 0.0 {
            return ([0.0; 3], 0.0, 1.0);
        }
        let h = (l + v).normalize();
        let (n_dot_l, n_dot_v) = (
            cos.max(f64::from(MIN_COSINE)),
            n.dot(v).max(f64::from(MIN_COSINE)),
        );
        let alpha = f64::from(m.roughness * m.roughness).max(f64::from(MIN_GGX_ALPHA));
        let a2 = alpha * alpha;
        let n_dot_h = n.dot(h);
        let d_denom = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
        let d = a2 / (std::f64::consts::PI * d_denom * d_denom);
        let vis = 0.5
            / (n_dot_l * (n_dot_v * n_dot_v * (1.0 - a2) + a2).sqrt()
                + n_dot_v * (n_dot_l * n_dot_l * (1.0 - a2) + a2).sqrt());
        // Fresnel times the multiple-scattering scale, each part of a half-metal compensated
        // for its own Fresnel (crate::shading's docs), from the same table.
        let (f0s, f90s) = m.scaled_fresnel_ends(n.dot(v).clamp(0.0, 1.0) as f32);
        let (f0s, f90s) = (f0s.as_dvec3(), f90s.as_dvec3());
        let fresnel = f0s + (f90s - f0s) * (1.0 - v.dot(h)).powi(5);
        let c_diff = (m.base_color * (1.0 - m.metallic)).as_dvec3();
        // Multiple scattering and albedo scaling (crate::shading's docs), from the same table;
        // the diffuse base lies under the dielectric's specular albedo (metallic 0).
        let dielectric = SurfaceMaterial {
            metallic: 0.0,
            ..*m
        };
        let albedo = dielectric.specular_response(n.dot(v) as f32).1;
        let f =
            (DVec3::ONE - albedo.as_dvec3()) * c_diff / std::f64::consts::PI + fresnel * (d * vis);
        ((f * cos).to_array(), d, d_denom)
    }

    /// The per-point constants and the general path both give the Appendix B BRDF times the
    /// cosine, and the two-lobe pdf, as an f64 evaluation does: to 1e-5 relative plus the
    /// rounding that GGX's peak amplifies (below), for metals and dielectrics from mirror-like
    /// to rough, with KHR_materials_specular's F0 and weight, over random view and light
    /// directions (grazing ones included).
    #[test]
    fn core_matches_the_appendix_b_brdf() {
        let mut rng = Rng::new(17);
        let mut unit = || {
            let (u1, u2) = (rng.next_f32(), rng.next_f32());
            let z = 1.0 - 2.0 * u1;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = std::f32::consts::TAU * u2;
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        };
        // Both f32 paths are held to the f64 value of the formula. Near a sharp GGX peak
        // (roughness 0: α² = 4e-6) D = α²/(π·d_denom²) turns a rounding of a few ulp in n·h
        // into a relative error of about 4·ε/d_denom, so that is allowed on top of 1e-5 (the
        // core path measured at most 0.9·ε/d_denom, the general one 3.8·ε/d_denom).
        let tolerance = |d_denom: f64, ulps: f64| 1e-5 + ulps * f64::from(f32::EPSILON) / d_denom;
        let (mut worst_core, mut worst_general) = (0.0f64, 0.0f64);
        let mut checked = 0;
        for (base, metallic, roughness) in [
            (0.8, 0.0, 0.9),
            (0.5, 1.0, 0.3),
            (0.9, 0.0, 0.0),
            (0.2, 0.4, 0.05),
            (1.0, 1.0, 1.0),
        ] {
            // None: the material's own; weight 0: a Lambertian surface (no specular lobe).
            for specular in [
                None,
                Some((Vec3::new(0.1, 0.05, 0.02), 0.6)),
                Some((Vec3::new(0.04, 0.04, 0.04), 0.0)),
            ] {
                let mut m = material(base, metallic, roughness);
                if let Some((f0, weight)) = specular {
                    m.dielectric_f0 = f0;
                    m.specular_weight = weight;
                }
                for _ in 0..2000 {
                    let (n, v, l) = (unit(), unit(), unit());
                    let bsdf = Bsdf::new(&m, n, v);
                    let (f, pdf) = bsdf.eval_pdf(v, l);
                    let general = Bsdf { core: None, ..bsdf };
                    let (f_ref, pdf_ref) = (general.eval_cos(v, l), general.pdf(v, l));
                    let (exact, d, d_denom) = appendix_b_f64(&m, n, v, l);
                    let pdf_exact = bsdf.core.map_or(0.0, |c| {
                        f64::from(c.specular_pdf) * d
                            + f64::from(c.diffuse_pdf) * f64::from(n.dot(l).max(0.0))
                    });
                    let rel = |a: f32, b: f64| (f64::from(a) - b).abs() / b.abs().max(1e-3);
                    let core_error = (0..3)
                        .map(|i| rel(f[i], exact[i]))
                        .fold(rel(pdf, pdf_exact), f64::max);
                    let general_error = (0..3)
                        .map(|i| rel(f_ref[i], exact[i]))
                        .fold(rel(pdf_ref, pdf_exact), f64::max);
                    assert!(
                        core_error <= tolerance(d_denom, 4.0)
                            && general_error <= tolerance(d_denom, 8.0),
                        "{m:?} n {n} v {v} l {l}: core {f} {pdf}, general {f_ref} {pdf_ref}, \
                         f64 {exact:?} {pdf_exact}"
                    );
                    worst_core = worst_core.max(core_error);
                    worst_general = worst_general.max(general_error);
                    checked += usize::from(pdf_ref > 0.0);
                }
            }
        }
        eprintln!("worst relative error: core {worst_core:.2e}, general {worst_general:.2e}");
        assert!(checked > 2000, "{checked} directions above the surface");
    }

    /// The sampler's pdf integrates to (nearly) 1 over the hemisphere (checked by uniform-sphere Monte
    /// Carlo), and the mean sample weight equals the directional albedo computed by uniform
    /// sampling: sampling and evaluation agree.
    #[test]
    fn sampling_matches_evaluation() {
        let to_eye = Vec3::new(0.6, 0.0, 0.8);
        let coated = |m: SurfaceMaterial| SurfaceMaterial {
            clearcoat: Some(crate::shading::Clearcoat {
                weight: 0.8,
                roughness: 0.2,
                normal: Vec3::new(0.1, 0.0, 1.0).normalize(),
            }),
            ..m
        };
        let sheened = |m: SurfaceMaterial| SurfaceMaterial {
            sheen: Some(crate::shading::Sheen {
                color: Vec3::new(0.9, 0.5, 0.3),
                roughness: 0.4,
            }),
            dielectric_f0: Vec3::new(0.06, 0.04, 0.02),
            specular_weight: 0.7,
            ..m
        };
        let materials = [
            material(0.8, 0.0, 0.5),
            material(0.9, 1.0, 0.3),
            material(0.5, 0.0, 1.0),
            coated(material(0.3, 0.0, 0.7)),
            sheened(material(0.4, 0.0, 0.6)),
            coated(sheened(material(0.2, 0.5, 0.9))),
            stretched(material(0.9, 1.0, 0.3), Vec3::X, 0.8),
            stretched(material(0.6, 0.0, 0.4), Vec3::new(1.0, 1.0, 0.0), 0.6),
            stretched(coated(material(0.5, 0.5, 0.2)), Vec3::Y, 1.0),
        ];
        for m in materials {
            let bsdf = Bsdf::new(&m, Vec3::Z, to_eye);
            let mut rng = Rng::new(9);
            let n = 400_000;
            let (mut pdf_integral, mut albedo_uniform, mut albedo_sampled) =
                (0.0f64, 0.0f64, 0.0f64);
            for _ in 0..n {
                let d = crate::sampling::cosine_hemisphere(rng.next_f32(), rng.next_f32());
                // Uniform hemisphere via the cosine warp's pdf.
                let p = f64::from(d.z / PI);
                if p > 0.0 {
                    pdf_integral += f64::from(bsdf.pdf(to_eye, d)) / p;
                    albedo_uniform += f64::from(bsdf.eval_cos(to_eye, d).x) / p;
                }
                if let Some(s) = bsdf.sample(to_eye, rng.next_f32(), rng.next_f32(), rng.next_f32())
                {
                    albedo_sampled += f64::from(s.weight.x);
                }
            }
            let n = f64::from(n);
            let (pdf_integral, a, b) = (pdf_integral / n, albedo_uniform / n, albedo_sampled / n);
            // Below 1 only by the specular draws that reflect below the horizon (rejected):
            // most for a rough lobe or a coat whose normal is tilted from the base's.
            assert!(
                (0.8..1.01).contains(&pdf_integral),
                "{m:?}: pdf integrates to {pdf_integral}"
            );
            assert!(
                (a - b).abs() < 0.02 * a.max(0.1),
                "{m:?}: albedo {a} (uniform) vs {b} (sampled)"
            );
        }
    }

    /// A dielectric whose specular lobe reflects nothing (`KHR_materials_specular` factor 0,
    /// an OBJ's `Ks 0 0 0`) is drawn from the cosine lobe alone: every draw weighs its base
    /// colour (f·cos / pdf = (c/π)·cos / (cos/π)), where draws from the empty GGX lobe weighed
    /// something else. Its shortcut evaluation agrees with the general path.
    #[test]
    fn a_lambertian_surface_draws_only_the_cosine_lobe() {
        let base = Vec3::new(0.7, 0.4, 0.2);
        for roughness in [0.0, 0.5, 1.0] {
            let mut m = material(0.5, 0.0, roughness);
            m.base_color = base;
            m.specular_weight = 0.0;
            let to_eye = Vec3::new(0.3, -0.2, 0.9).normalize();
            let bsdf = Bsdf::new(&m, Vec3::Z, to_eye);
            assert_eq!(bsdf.p_specular, 0.0, "{m:?}");
            let mut rng = Rng::new(5);
            for _ in 0..10_000 {
                let (u, u1, u2) = (rng.next_f32(), rng.next_f32(), rng.next_f32());
                let Some(s) = bsdf.sample(to_eye, u, u1, u2) else {
                    panic!("{m:?}: a cosine draw above the surface was rejected");
                };
                assert!(
                    (s.weight - base).abs().max_element() < 1e-5,
                    "{m:?}: weight {} for {}",
                    s.weight,
                    s.direction
                );
                let general = Bsdf { core: None, ..bsdf };
                let fast = bsdf.eval_pdf(to_eye, s.direction);
                let slow = (
                    general.eval_cos(to_eye, s.direction),
                    general.pdf(to_eye, s.direction),
                );
                assert!(
                    (fast.0 - slow.0).abs().max_element() <= 1e-6
                        && (fast.1 - slow.1).abs() <= 1e-6,
                    "{m:?}: {fast:?} against {slow:?}"
                );
            }
        }
    }

    /// The half-metal shortcut of [`LobeResponse::of`] gives what the three methods it stands
    /// for give, bit for bit, and so does the one-material shortcut.
    #[test]
    fn lobe_response_is_the_methods_bit_for_bit() {
        let mut rng = Rng::new(23);
        for metallic in [0.0f32, 0.3, 0.5, 0.97, 1.0] {
            for _ in 0..200 {
                let mut m = material(rng.next_f32(), metallic, rng.next_f32());
                m.base_color = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                m.specular_weight = rng.next_f32();
                let n_dot_v = rng.next_f32();
                let r = LobeResponse::of(&m, n_dot_v);
                assert_eq!(r.albedo, m.specular_response(n_dot_v).1, "{m:?}");
                assert_eq!(r.kept, m.diffuse_kept(n_dot_v), "{m:?}");
                assert_eq!(r.scaled_ends, Some(m.scaled_fresnel_ends(n_dot_v)), "{m:?}");
            }
        }
    }

    /// The mean weight (red) of 300 × 300 stratified draws of `bsdf` seen from `to_eye`: its
    /// directional albedo as the path tracer sees it.
    fn sampled_albedo(bsdf: &Bsdf, to_eye: Vec3, rng: &mut Rng) -> f64 {
        let strata = 300;
        let mut sum = 0.0f64;
        for k in 0..strata * strata {
            let u1 = ((k % strata) as f32 + rng.next_f32()) / strata as f32;
            let u2 = ((k / strata) as f32 + rng.next_f32()) / strata as f32;
            if let Some(s) = bsdf.sample(to_eye, rng.next_f32(), u1, u2) {
                sum += f64::from(s.weight.x);
            }
        }
        sum / f64::from(strata * strata)
    }

    /// White furnace through the sampler (what the path tracer sees): a white metal and a white
    /// dielectric reflect all the light, within 2%, at roughness 0, 0.25, 0.5, 0.75 and 1 and
    /// at views from head-on to 75° (the mean weight of stratified draws is the directional
    /// albedo). Single-scattering GGX returned 0.31-0.39 for the rough white metal.
    #[test]
    fn white_furnace_returns_the_light_at_every_roughness() {
        let mut rng = Rng::new(5);
        for metallic in [1.0f32, 0.0] {
            for roughness in [0.0f32, 0.25, 0.5, 0.75, 1.0] {
                for angle in [0.0f32, 0.5, 1.0, 1.3] {
                    let to_eye = Vec3::new(angle.sin(), 0.0, angle.cos());
                    let m = material(1.0, metallic, roughness);
                    let bsdf = Bsdf::new(&m, Vec3::Z, to_eye);
                    let albedo = sampled_albedo(&bsdf, to_eye, &mut rng);
                    assert!(
                        (albedo - 1.0).abs() < 0.02,
                        "metallic {metallic} roughness {roughness} view {angle}: {albedo}"
                    );
                }
            }
        }
    }

    /// `m` with its specular lobe stretched along `direction` (`KHR_materials_anisotropy`,
    /// normal +Z), as [`Prepared::surface`](crate::prepare::Prepared::surface) sets it.
    fn stretched(m: SurfaceMaterial, direction: Vec3, strength: f32) -> SurfaceMaterial {
        let a = Anisotropy::new(Vec3::Z, direction, m.roughness, strength).unwrap();
        SurfaceMaterial {
            roughness: a.mean_roughness(),
            anisotropy: Some(a),
            ..m
        }
    }

    /// White furnace for anisotropic lobes: a white metal stretched along x returns the light
    /// that arrives within 2% (measured 0.989-1.009), viewed head-on, along the stretch, across it and between, at
    /// grazing angles too. Its multiple scattering is compensated by the stretched lobe's own
    /// directional albedo at the view ([`Anisotropy::seen_from`]). With the isotropic lobe of
    /// the two α's geometric mean standing in (MaterialX's `mx_average_alpha`, Cycles'
    /// choice too), these lobes returned 0.61-1.03: at strength 1 the lobe's albedo depends
    /// on the view's azimuth and is far below the mean roughness's.
    /// White furnace for anisotropic lobes: a white metal stretched along x returns the light
    /// that arrives within 2% (measured 0.989-1.009), viewed head-on, along the stretch, across it and between, at
    /// grazing angles too. Its multiple scattering is compensated by the stretched lobe's own
    /// directional albedo at the view ([`Anisotropy::seen_from`]). With the isotropic lobe of
    /// the two α's geometric mean standing in (MaterialX's `mx_average_alpha`, Cycles'
    /// choice too), these lobes returned 0.61-1.03: at strength 1 the lobe's albedo depends
    /// on the view's azimuth and is far below the mean roughness's.
    #[test]
    fn probe_iso_grazing() {
        let mut rng = Rng::new(5);
        for roughness in [0.1f32, 0.2, 0.3, 0.5] {
            let to_eye = test_views(1.5)[2];
            let m = material(1.0, 1.0, roughness);
            let albedo = sampled_albedo(&Bsdf::new(&m, Vec3::Z, to_eye), to_eye, &mut rng);
            let a = Anisotropy::new(Vec3::Z, Vec3::X, roughness, 0.5)
                .unwrap()
                .seen_from(Vec3::Z, to_eye);
            let iso = crate::shading::ggx::directional_albedo(to_eye.z, roughness);
            eprintln!(
                "ISO r {roughness} v {to_eye}: furnace {albedo:.4} table {:?} aniso-table {:?}",
                iso, a.albedo
            );
        }
    }

    #[test]
    fn white_furnace_holds_for_anisotropic_metal() {
        let mut rng = Rng::new(5);
        for (roughness, strength) in [
            (0.2f32, 0.5f32),
            (0.4, 0.8),
            (0.6, 1.0),
            (0.0, 0.6),
            (0.3, 1.0),
            (0.05, 1.0),
            (0.8, 1.0),
        ] {
            for to_eye in test_views(1.0)
                .into_iter()
                .chain([test_views(1.3)[3], test_views(1.5)[2]])
            {
                let m = stretched(material(1.0, 1.0, roughness), Vec3::X, strength);
                let m = SurfaceMaterial {
                    anisotropy: m.anisotropy.map(|a| a.seen_from(Vec3::Z, to_eye)),
                    ..m
                };
                let bsdf = Bsdf::new(&m, Vec3::Z, to_eye);
                let albedo = sampled_albedo(&bsdf, to_eye, &mut rng);
                assert!(
                    (0.98..=1.02).contains(&albedo),
                    "roughness {roughness} strength {strength} view {to_eye}: {albedo}"
                );
            }
        }
    }

    /// `KHR_materials_diffuse_transmission`: a white dielectric whose diffuse base transmits
    /// the share `weight` of its light (white) still returns all the light, reflected and
    /// transmitted together, within 2% (the through lobe takes from the diffuse reflection,
    /// not from the specular layer), at views from head-on to 75°. The through lobe's draws
    /// agree with its evaluation (what punctual lights behind the wall use): the mean of
    /// f·|cos| over the far hemisphere is the draws' mean weight times their share, within 1%.
    #[test]
    fn diffuse_transmission_returns_the_light_and_evaluates_as_it_samples() {
        let mut rng = Rng::new(3);
        for weight in [0.3f32, 1.0] {
            for angle in [0.0f32, 0.5, 1.0, 1.3] {
                let to_eye = Vec3::new(angle.sin(), 0.0, angle.cos());
                let m = SurfaceMaterial {
                    diffuse_transmission: Some(crate::shading::DiffuseTransmission {
                        weight,
                        color: Vec3::ONE,
                    }),
                    ..material(1.0, 0.0, 0.5)
                };
                let bsdf = Bsdf::new(&m, Vec3::Z, to_eye);
                let albedo = sampled_albedo(&bsdf, to_eye, &mut rng);
                assert!(
                    (albedo - 1.0).abs() < 0.02,
                    "weight {weight} view {angle}: {albedo}"
                );
                assert!(bsdf.p_through > 0.0);
                let n = 200_000;
                let mut eval = 0.0f64;
                for _ in 0..n {
                    // Uniform on the lower hemisphere: pdf 1/(2π).
                    let z = -rng.next_f32();
                    let phi = std::f32::consts::TAU * rng.next_f32();
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                    eval +=
                        f64::from(bsdf.thin_transmission_cos(to_eye, d).x) * std::f64::consts::TAU;
                }
                let eval = eval / f64::from(n);
                let drawn = f64::from(bsdf.through_tint(to_eye).x);
                assert!(
                    (eval - drawn).abs() < 0.01 * drawn,
                    "weight {weight} view {angle}: evaluated {eval}, drawn {drawn}"
                );
                assert_eq!(bsdf.thin_transmission_cos(to_eye, Vec3::Z), Vec3::ZERO);
            }
        }
    }

    /// White furnace for white transmission (factor 1): what a thin-walled sheet, or a glass
    /// surface crossed into or out of its volume (indices 1.33, 1.5 and 2.4), reflects and
    /// transmits adds up to the light that arrived, within 2%, at roughness 0, 0.25, 0.5, 0.75
    /// and 1 and views from head-on to 75°. With single scattering alone a sheet returned
    /// 0.63 of the light at roughness 0.75 and 0.31 at 1, head-on, and glass of index 1.5 at
    /// roughness 1 0.70-0.90 entering and 0.43-0.51 leaving.
    #[test]
    fn white_transmission_reflects_or_passes_all_the_light() {
        let mut rng = Rng::new(9);
        let cases = [
            (true, true, 1.5f32),
            (false, true, 1.5),
            (false, false, 1.5),
            (false, true, 1.33),
            (false, false, 1.33),
            (false, true, 2.4),
            (false, false, 2.4),
        ];
        for (thin, entering, ior) in cases {
            for roughness in [0.0f32, 0.25, 0.5, 0.75, 1.0] {
                for angle in [0.0f32, 0.5, 1.0, 1.3] {
                    let to_eye = Vec3::new(angle.sin(), 0.0, angle.cos());
                    let mut m = material(1.0, 0.0, roughness);
                    m.dielectric_f0 = Vec3::splat(((ior - 1.0) / (ior + 1.0)).powi(2));
                    let bsdf = Bsdf::new(&m, Vec3::Z, to_eye)
                        .with_transmission(to_eye, 1.0, ior, thin, entering);
                    let albedo = sampled_albedo(&bsdf, to_eye, &mut rng);
                    assert!(
                        (albedo - 1.0).abs() < 0.02,
                        "thin {thin}, entering {entering}, ior {ior}, roughness {roughness}, \
                         view {angle}: {albedo}"
                    );
                }
            }
        }
    }

    /// Smooth white glass (index 1.5) reflects Schlick's Fresnel of the angle outside it, from
    /// either side: entering at θ, F(cos θ); leaving at θᵢ, F(cos θₜ) with sin θₜ = 1.5 sin θᵢ,
    /// which reaches 1 at the critical angle (41.8°). What the draws reflect and transmit is
    /// each within 3% (or 0.003) of that, and adds up to the light that arrived. With Schlick
    /// at the inside angle, leaving at cos θᵢ = 0.8 reflected 0.040 where this asks 0.095.
    #[test]
    fn smooth_glass_reflects_the_outside_angles_fresnel_from_either_side() {
        let schlick = |cos: f32| 0.04 + 0.96 * (1.0 - cos).powi(5);
        let mut rng = Rng::new(17);
        for (entering, cos_v) in [
            (true, 0.8f32),
            (true, 0.3),
            (false, 1.0),
            (false, 0.8),
            (false, 0.76),
        ] {
            let to_eye = Vec3::new((1.0 - cos_v * cos_v).sqrt(), 0.0, cos_v);
            let mut m = material(1.0, 0.0, 0.0);
            m.dielectric_f0 = Vec3::splat(0.04);
            let bsdf =
                Bsdf::new(&m, Vec3::Z, to_eye).with_transmission(to_eye, 1.0, 1.5, false, entering);
            let expected = if entering {
                schlick(cos_v)
            } else {
                let sin2_t = 2.25 * (1.0 - cos_v * cos_v);
                schlick((1.0 - sin2_t).sqrt())
            };
            let (mut reflected, mut transmitted) = (0.0f64, 0.0f64);
            let draws = 200_000;
            for k in 0..draws {
                let u_lobe = (k as f32 + rng.next_f32()) / draws as f32;
                if let Some(s) = bsdf.sample(to_eye, u_lobe, rng.next_f32(), rng.next_f32()) {
                    let w = f64::from(s.weight.x) / f64::from(draws);
                    if s.direction.z > 0.0 {
                        reflected += w;
                    } else {
                        transmitted += w;
                    }
                }
            }
            let expected = f64::from(expected);
            for (what, got, want) in [
                ("reflected", reflected, expected),
                ("transmitted", transmitted, 1.0 - expected),
            ] {
                assert!(
                    (got - want).abs() <= (0.03 * want).max(0.003),
                    "entering {entering}, cos {cos_v}: {what} {got}, expected {want}"
                );
            }
        }
    }

    /// `KHR_materials_dispersion` on smooth glass (index 1.5, dispersion 2: the channels'
    /// indices 1.475, 1.5 and 1.525): a draw that passes into (or out of) the volume follows
    /// Snell's law with one channel's index and carries weight in that channel alone, three
    /// times its share; the three channels are drawn a third of the time each, so the mean
    /// transmitted weight is the undispersed glass's in every channel. A path that carries one
    /// channel keeps it, at weight 1. Without dispersion, or through a thin wall, the draws
    /// are the plain glass's, bit for bit.
    #[test]
    fn dispersion_refracts_each_channel_by_its_own_index() {
        let mut m = material(1.0, 0.0, 0.0);
        m.dielectric_f0 = Vec3::splat(0.04);
        for entering in [true, false] {
            let cos_v = if entering { 0.6f32 } else { 0.9 };
            let to_eye = Vec3::new((1.0 - cos_v * cos_v).sqrt(), 0.0, cos_v);
            let plain =
                Bsdf::new(&m, Vec3::Z, to_eye).with_transmission(to_eye, 1.0, 1.5, false, entering);
            let dispersed = plain.with_dispersion(2.0, 1.5, None);
            let sin_v = (1.0 - cos_v * cos_v).sqrt();
            let (mut sums, mut plain_sum) = ([0.0f64; 3], 0.0f64);
            let draws = 30_000;
            for k in 0..draws {
                // Lobe numbers spread evenly over the transmission lobe's share; the same
                // numbers for both BSDFs.
                let share = plain.transmission.map_or(0.0, |t| t.probability);
                let u_lobe = (k as f32 + 0.5) / draws as f32 * share;
                let Some(s) = dispersed.sample(to_eye, u_lobe, 0.5, 0.5) else {
                    continue;
                };
                if s.direction.z >= 0.0 {
                    continue;
                }
                let lit: Vec<usize> = (0..3).filter(|&c| s.weight[c] > 0.0).collect();
                assert_eq!(lit.len(), 1, "one channel a draw: {:?}", s.weight);
                let c = lit[0];
                let ior = [1.475f32, 1.5, 1.525][c];
                let (n1, n2) = if entering { (1.0, ior) } else { (ior, 1.0) };
                let sin_t = (s.direction.x.powi(2) + s.direction.y.powi(2)).sqrt();
                assert!(
                    (n1 * sin_v - n2 * sin_t).abs() < 1e-5,
                    "entering {entering}, channel {c}: Snell's law broken, {n1}·{sin_v} against {n2}·{sin_t}"
                );
                sums[c] += f64::from(s.weight[c]) / f64::from(draws);
                if let Some(p) = plain.sample(to_eye, u_lobe, 0.5, 0.5) {
                    if p.direction.z < 0.0 {
                        plain_sum += f64::from(p.weight.y) / f64::from(draws);
                    }
                }
            }
            for (c, sum) in sums.iter().enumerate() {
                assert!(
                    (sum - plain_sum).abs() < 0.01 * plain_sum,
                    "entering {entering}, channel {c}: mean {sum} against the plain glass's {plain_sum}"
                );
            }
            // A path carrying blue alone refracts by blue's index at weight 1.
            let blue = plain.with_dispersion(2.0, 1.5, Some(2));
            let s = blue.sample(to_eye, 0.45, 0.5, 0.5).unwrap();
            assert_eq!(s.weight.x, 0.0);
            assert_eq!(s.weight.y, 0.0);
            let p = plain.sample(to_eye, 0.45, 0.5, 0.5).unwrap();
            assert!(
                (s.weight.z - p.weight.z).abs() < 0.02 * p.weight.z,
                "{s:?} {p:?}"
            );
            // No dispersion, or a thin wall: the plain lobe's draws.
            let thin =
                Bsdf::new(&m, Vec3::Z, to_eye).with_transmission(to_eye, 1.0, 1.5, true, entering);
            for (other, reference) in [
                (plain.with_dispersion(0.0, 1.5, None), plain),
                (thin.with_dispersion(2.0, 1.5, None), thin),
            ] {
                for u in [0.1f32, 0.5, 0.93] {
                    let (a, b) = (
                        other.sample(to_eye, u, 0.3, 0.7),
                        reference.sample(to_eye, u, 0.3, 0.7),
                    );
                    assert_eq!(format!("{a:?}"), format!("{b:?}"));
                }
            }
        }
    }

    /// Light reflected back inside coloured glass is not tinted: glTF's base colour tints the
    /// transmission (its BTDF), and a reflection is the specular BRDF's share. Leaving at cos
    /// 0.5 (past the critical angle of index 1.5), every draw of the smooth lobe reflects and
    /// most of the rough one's do, with the same weight in every channel; the rough lobe's
    /// draws that get through (microfacets tilted toward the view) are tinted, and so is the
    /// light entering.
    #[test]
    fn light_reflected_inside_coloured_glass_is_not_tinted() {
        let mut m = material(1.0, 0.0, 0.0);
        m.base_color = Vec3::new(0.9, 0.2, 0.1);
        for roughness in [0.0f32, 0.3] {
            m.roughness = roughness;
            let to_eye = Vec3::new(0.866, 0.0, 0.5);
            let leaving =
                Bsdf::new(&m, Vec3::Z, to_eye).with_transmission(to_eye, 1.0, 1.5, false, false);
            let t = leaving.transmission.expect("a transmission lobe");
            let mut rng = Rng::new(23);
            let mut drawn = 0;
            for _ in 0..1000 {
                let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
                if let Some(s) = leaving.sample_transmission(to_eye, t, u) {
                    if s.direction.z > 0.0 {
                        assert!(
                            s.weight.x == s.weight.y && s.weight.y == s.weight.z,
                            "{s:?}"
                        );
                        drawn += 1;
                    } else {
                        assert!(roughness > 0.0 && s.weight.x > 4.0 * s.weight.y, "{s:?}");
                    }
                }
            }
            assert!(drawn > 500, "{roughness}: {drawn} reflected draws");
            let entering =
                Bsdf::new(&m, Vec3::Z, to_eye).with_transmission(to_eye, 1.0, 1.5, false, true);
            let t = entering.transmission.expect("a transmission lobe");
            let s = entering
                .sample_transmission(to_eye, t, [0.3, 0.7, 0.5])
                .expect("glass refracts");
            assert!(
                s.direction.z < 0.0 && s.weight.x > 4.0 * s.weight.y,
                "{s:?}"
            );
        }
    }

    /// Rough transmission: every sample goes through the surface (or, inside a volume past the
    /// critical angle, back in), a roughness below the mirror floor refracts exactly like
    /// smooth glass, the spread about the smooth direction grows with roughness, and the mean
    /// weight stays at most the smooth lobe's (single scattering only loses energy), close to
    /// it for slight roughness.
    #[test]
    fn rough_transmission_spreads_about_the_smooth_direction() {
        let to_eye = Vec3::new(0.5, 0.0, 0.866).normalize();
        fn glass(m: &SurfaceMaterial, to_eye: Vec3, thin: bool) -> Bsdf<'_> {
            Bsdf::new(m, Vec3::Z, to_eye).with_transmission(to_eye, 1.0, 1.5, thin, true)
        }
        let white = |roughness: f32| material(1.0, 0.0, roughness);
        for thin in [true, false] {
            let (m_smooth, m_almost) = (white(0.0), white(0.04));
            let smooth = glass(&m_smooth, to_eye, thin);
            let t = smooth.transmission.expect("a transmission lobe");
            let exact = smooth
                .sample_transmission(to_eye, t, [0.3, 0.7, 0.5])
                .expect("smooth glass transmits");
            let almost = glass(&m_almost, to_eye, thin)
                .sample_transmission(to_eye, t, [0.3, 0.7, 0.5])
                .expect("smooth enough glass transmits");
            assert_eq!(exact.direction, almost.direction);
            let mut previous_spread = 0.0;
            for roughness in [0.1f32, 0.4, 0.8] {
                let m = white(roughness);
                let bsdf = glass(&m, to_eye, thin);
                let t = bsdf.transmission.expect("a transmission lobe");
                let mut rng = Rng::new(3);
                let (mut spread, mut weight, mut n) = (0.0f64, 0.0f64, 0);
                let draws = 20_000;
                for _ in 0..draws {
                    let Some(s) =
                        bsdf.sample_transmission(to_eye, t, [rng.next_f32(), rng.next_f32(), 0.5])
                    else {
                        continue;
                    };
                    assert!(s.delta && s.direction.z < 0.0, "{roughness}: {s:?}");
                    spread += f64::from(1.0 - s.direction.dot(exact.direction));
                    weight += f64::from(s.weight.x);
                    n += 1;
                }
                let (spread, mean) = (spread / f64::from(n), weight / f64::from(draws));
                let smooth_weight = f64::from(exact.weight.x);
                assert!(spread > previous_spread, "{roughness}: spread {spread}");
                previous_spread = spread;
                assert!(
                    mean <= smooth_weight * 1.01,
                    "thin {thin}, roughness {roughness}: mean weight {mean} > {smooth_weight}"
                );
                if roughness <= 0.1 {
                    assert!(mean > 0.95 * smooth_weight, "{roughness}: {mean}");
                }
            }
        }
    }

    /// The thin sheet's transmission lobe evaluated for light samples agrees with the lobe it
    /// draws: for each of several views and roughnesses, the integral of
    /// [`Bsdf::thin_transmission_cos`] over the far hemisphere (uniform directions) equals
    /// the mean weight of the drawn transmission samples (times the chance of drawing that
    /// lobe), within 2%; so does the integral over a cone (the lobe's shape, not only its
    /// total). Volumes, smooth sheets and directions on the eye's side evaluate to zero.
    #[test]
    fn thin_sheet_transmission_evaluates_as_it_samples() {
        for (cos_v, roughness) in [(0.9f32, 0.3f32), (0.6, 0.5), (0.3, 0.8)] {
            let to_eye = Vec3::new((1.0 - cos_v * cos_v).sqrt(), 0.0, cos_v);
            let m = material(0.8, 0.0, roughness);
            let bsdf =
                Bsdf::new(&m, Vec3::Z, to_eye).with_transmission(to_eye, 1.0, 1.5, true, true);
            let t = bsdf.transmission.expect("a transmission lobe");
            // The cone about the straight-through direction that the check also integrates.
            let axis = -to_eye;
            let in_cone = |d: Vec3| d.dot(axis) > 0.8;
            let mut rng = Rng::new(11);
            let n = 400_000;
            let (mut eval_all, mut eval_cone) = (0.0f64, 0.0f64);
            for _ in 0..n {
                // Uniform on the lower hemisphere: pdf 1/(2π).
                let z = -rng.next_f32();
                let phi = std::f32::consts::TAU * rng.next_f32();
                let r = (1.0 - z * z).max(0.0).sqrt();
                let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                let f = f64::from(bsdf.thin_transmission_cos(to_eye, d).x) * std::f64::consts::TAU;
                eval_all += f;
                if in_cone(d) {
                    eval_cone += f;
                }
            }
            let (mut drawn_all, mut drawn_cone) = (0.0f64, 0.0f64);
            for _ in 0..n {
                if let Some(s) =
                    bsdf.sample_transmission(to_eye, t, [rng.next_f32(), rng.next_f32(), 0.5])
                {
                    let w = f64::from(s.weight.x * t.probability);
                    drawn_all += w;
                    if in_cone(s.direction) {
                        drawn_cone += w;
                    }
                }
            }
            let n = f64::from(n);
            for (what, eval, drawn) in [
                ("all", eval_all / n, drawn_all / n),
                ("cone", eval_cone / n, drawn_cone / n),
            ] {
                assert!(
                    (eval - drawn).abs() < 0.02 * drawn.max(1e-3),
                    "cos {cos_v}, roughness {roughness}, {what}: evaluated {eval}, drawn {drawn}"
                );
            }
            let below = Vec3::new(0.1, 0.2, -0.97).normalize();
            assert!(bsdf.thin_transmission_cos(to_eye, below).x > 0.0);
            assert_eq!(bsdf.thin_transmission_cos(to_eye, Vec3::Z), Vec3::ZERO);
            let m = material(0.8, 0.0, roughness);
            let volume =
                Bsdf::new(&m, Vec3::Z, to_eye).with_transmission(to_eye, 1.0, 1.5, false, true);
            assert_eq!(volume.thin_transmission_cos(to_eye, below), Vec3::ZERO);
            let m_smooth = material(0.8, 0.0, 0.0);
            let smooth = Bsdf::new(&m_smooth, Vec3::Z, to_eye)
                .with_transmission(to_eye, 1.0, 1.5, true, true);
            assert_eq!(smooth.thin_transmission_cos(to_eye, below), Vec3::ZERO);
        }
    }
}
