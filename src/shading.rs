//! Surface shading: the glTF 2.0 metallic-roughness BRDF (the default) and the classic
//! Blinn-Phong model (`--shading phong`), both fed by the same material inputs.
//!
//! # glTF metallic-roughness (glTF 2.0 Appendix B)
//!
//! With α = roughness², h = normalize(l + v):
//!
//! ```text
//! D = α² / (π ((n·h)²(α² - 1) + 1)²)                          GGX / Trowbridge-Reitz (B.3.2)
//! V = 0.5 / (n·l √((n·v)²(1 - α²) + α²) + n·v √((n·l)²(1 - α²) + α²))
//!                                                  height-correlated Smith visibility (B.3.2)
//! F = F0 + (1 - F0)(1 - v·h)⁵,  F0 = mix(0.04, baseColor, metallic)   Schlick (B.3.4)
//! f = (1 - F)·(1/π)·mix(baseColor, 0, metallic) + F·D·V               dielectric/metal mix (B.3.5)
//! L = f · E · (n·l)                                            punctual light of irradiance E
//! ```
//!
//! # Blinn-Phong
//!
//! For a light delivering irradiance E from direction l onto a point with normal n, seen from
//! direction v, with h = normalize(l + v):
//!
//! ```text
//! L = (kd/π + ks·(e + 8)/(8π)·max(n·h, 0)^e) · E · max(n·l, 0)
//! ```
//!
//! - kd = baseColor·(1 - metallic): metals have no diffuse lobe.
//! - ks = the material's own specular colour (OBJ `Ks`) if it has one, else
//!   mix(0.04, baseColor, metallic): the glTF dielectric F0 of 4% (glTF 2.0 Appendix B) and the
//!   base colour for metals.
//! - e = 2/α² - 2 with α = roughness² (the Blinn-Phong exponent whose lobe matches a Beckmann/GGX
//!   lobe of width α, Walter et al. 2007), clamped to [1, 10000].
//! - (e + 8)/(8π) normalises the lobe so highlights keep their energy as they sharpen.
//!
//! Ambient light adds `ambient · baseColor` (unshadowed, for what no light reaches) and emissive
//! adds `emissive · emissiveStrength`.

use glam::Vec3;
use std::f32::consts::PI;

/// A shaded surface point's material inputs (factors times vertex colours).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceMaterial {
    /// Linear base colour.
    pub base_color: Vec3,
    /// Metalness.
    pub metallic: f32,
    /// Perceptual roughness.
    pub roughness: f32,
    /// Explicit specular colour (OBJ `Ks`), if any.
    pub specular: Option<Vec3>,
}

/// A grey test material: base colour `base` in every channel, no explicit specular.
#[cfg(test)]
pub(crate) fn test_material(base: f32, metallic: f32, roughness: f32) -> SurfaceMaterial {
    SurfaceMaterial {
        base_color: Vec3::splat(base),
        metallic,
        roughness,
        specular: None,
    }
}

/// Smallest α: keeps the exponent finite for roughness 0 (a perfect mirror has no Phong lobe).
const MIN_ALPHA: f32 = 0.01;

/// Smallest α for GGX. A perfect mirror (α = 0) reflects a punctual light into one direction
/// only; 0.002 (roughness 0.045) keeps D finite in f32 while looking mirror-sharp.
const MIN_GGX_ALPHA: f32 = 0.002;

/// Smallest cosine used in the visibility term's denominators, against division by zero at
/// grazing angles.
const MIN_COSINE: f32 = 1e-4;

/// Which shading model the renderer uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum ShadingModel {
    /// The glTF 2.0 metallic-roughness BRDF (Appendix B).
    #[default]
    Pbr,
    /// Blinn-Phong, the classic reference.
    Phong,
}

/// The glTF metallic-roughness BRDF value f(l, v) (module docs), without the cosine.
pub fn gltf_brdf(material: &SurfaceMaterial, n: Vec3, to_light: Vec3, to_eye: Vec3) -> Vec3 {
    let n_dot_l = n.dot(to_light).max(MIN_COSINE);
    let n_dot_v = n.dot(to_eye).max(MIN_COSINE);
    let h = (to_light + to_eye).normalize_or_zero();
    let n_dot_h = n.dot(h).max(0.0);
    let v_dot_h = to_eye.dot(h).max(0.0);
    let alpha = (material.roughness * material.roughness).max(MIN_GGX_ALPHA);
    let a2 = alpha * alpha;
    let d_denom = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
    let d = a2 / (PI * d_denom * d_denom);
    let vis = 0.5
        / (n_dot_l * (n_dot_v * n_dot_v * (1.0 - a2) + a2).sqrt()
            + n_dot_v * (n_dot_l * n_dot_l * (1.0 - a2) + a2).sqrt());
    let f0 = Vec3::splat(0.04).lerp(material.base_color, material.metallic);
    let fresnel = f0 + (Vec3::ONE - f0) * (1.0 - v_dot_h).powi(5);
    let c_diff = material.base_color * (1.0 - material.metallic);
    (Vec3::ONE - fresnel) * c_diff / PI + fresnel * (d * vis)
}

/// Reflected radiance for one light under `model`: f · E · max(n·l, 0).
pub fn shade(
    model: ShadingModel,
    material: &SurfaceMaterial,
    n: Vec3,
    to_light: Vec3,
    to_eye: Vec3,
    irradiance: Vec3,
) -> Vec3 {
    match model {
        ShadingModel::Phong => blinn_phong(material, n, to_light, to_eye, irradiance),
        ShadingModel::Pbr => {
            let cos_l = n.dot(to_light);
            if cos_l <= 0.0 {
                return Vec3::ZERO;
            }
            gltf_brdf(material, n, to_light, to_eye) * irradiance * cos_l
        }
    }
}

/// Blinn-Phong exponent for a perceptual roughness.
pub fn phong_exponent(roughness: f32) -> f32 {
    let alpha = (roughness * roughness).max(MIN_ALPHA);
    (2.0 / (alpha * alpha) - 2.0).clamp(1.0, 10_000.0)
}

/// Reflected radiance for one light (see the module docs). `n`, `to_light` and `to_eye` are unit
/// vectors; `irradiance` is the light's illuminance on a surface facing it.
pub fn blinn_phong(
    material: &SurfaceMaterial,
    n: Vec3,
    to_light: Vec3,
    to_eye: Vec3,
    irradiance: Vec3,
) -> Vec3 {
    let cos_l = n.dot(to_light);
    if cos_l <= 0.0 {
        return Vec3::ZERO;
    }
    let kd = material.base_color * (1.0 - material.metallic);
    let ks = material
        .specular
        .unwrap_or_else(|| Vec3::splat(0.04).lerp(material.base_color, material.metallic));
    let h = (to_light + to_eye).normalize_or_zero();
    let e = phong_exponent(material.roughness);
    let lobe = (e + 8.0) / (8.0 * PI) * n.dot(h).max(0.0).powf(e);
    (kd / PI + ks * lobe) * irradiance * cos_l
}

#[cfg(test)]
mod tests {
    use super::*;

    fn white_lambert() -> SurfaceMaterial {
        SurfaceMaterial {
            base_color: Vec3::ONE,
            metallic: 0.0,
            roughness: 1.0,
            specular: Some(Vec3::ZERO),
        }
    }

    #[test]
    fn lambertian_radiance_is_albedo_over_pi_times_irradiance() {
        let l = blinn_phong(&white_lambert(), Vec3::Z, Vec3::Z, Vec3::Z, Vec3::ONE);
        assert!((l.x - 1.0 / PI).abs() < 1e-6);
        let tilted = Vec3::new(0.0, 0.6, 0.8);
        let l = blinn_phong(&white_lambert(), Vec3::Z, tilted, Vec3::Z, Vec3::ONE);
        assert!((l.x - 0.8 / PI).abs() < 1e-6, "cosine law");
        assert_eq!(
            blinn_phong(&white_lambert(), Vec3::Z, -Vec3::Z, Vec3::Z, Vec3::ONE),
            Vec3::ZERO
        );
    }

    use super::test_material as material;

    /// At normal incidence (n = l = v): D = 1/(πα²), V = 1/4, F = F0, so
    /// f = (1 - F0)·c_diff/π + F0/(4πα²).
    #[test]
    fn gltf_brdf_has_the_closed_form_value_at_normal_incidence() {
        for (base, metallic, roughness) in [(0.8, 0.0, 0.5), (0.5, 1.0, 0.3), (0.2, 0.5, 1.0)] {
            let m = material(base, metallic, roughness);
            let alpha = roughness * roughness;
            let f0 = 0.04 * (1.0 - metallic) + base * metallic;
            let expected =
                (1.0 - f0) * base * (1.0 - metallic) / PI + f0 / (4.0 * PI * alpha * alpha);
            let got = gltf_brdf(&m, Vec3::Z, Vec3::Z, Vec3::Z).x;
            assert!(
                (got - expected).abs() < 1e-5 * expected.max(1.0),
                "{base} {metallic} {roughness}: {got} vs {expected}"
            );
        }
    }

    /// White furnace: a white metal's directional albedo ∫ f·cosθ dω never exceeds 1, and is
    /// close to 1 where single scattering loses little (smooth surfaces, any angle but grazing).
    #[test]
    fn white_furnace_energy_is_conserved() {
        let (steps_t, steps_p) = (2048, 256);
        for roughness in [0.3f32, 0.5, 1.0] {
            for view_angle in [0.0f32, 0.5, 1.0, 1.3] {
                let to_eye = Vec3::new(view_angle.sin(), 0.0, view_angle.cos());
                let m = material(1.0, 1.0, roughness);
                let mut albedo = 0.0;
                // Midpoint rule over the hemisphere in (cosθ, φ): dω = d(cosθ) dφ.
                for i in 0..steps_t {
                    let cos_t = (i as f32 + 0.5) / steps_t as f32;
                    let sin_t = (1.0 - cos_t * cos_t).sqrt();
                    for j in 0..steps_p {
                        let phi = std::f32::consts::TAU * (j as f32 + 0.5) / steps_p as f32;
                        let l = Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t);
                        albedo += gltf_brdf(&m, Vec3::Z, l, to_eye).x * cos_t;
                    }
                }
                albedo *= std::f32::consts::TAU / (steps_t * steps_p) as f32;
                assert!(
                    albedo <= 1.01,
                    "roughness {roughness} angle {view_angle}: albedo {albedo} > 1"
                );
                if roughness <= 0.5 && view_angle <= 1.0 {
                    assert!(
                        albedo > 0.85,
                        "roughness {roughness} angle {view_angle}: albedo {albedo}"
                    );
                }
            }
        }
    }

    #[test]
    fn exponent_grows_as_roughness_falls() {
        assert_eq!(phong_exponent(1.0), 1.0);
        assert!(phong_exponent(0.5) > 20.0);
        assert_eq!(phong_exponent(0.0), 10_000.0);
    }
}
