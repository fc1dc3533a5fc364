//! Surface shading: the Blinn-Phong model derived from the glTF material.
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

/// Smallest α: keeps the exponent finite for roughness 0 (a perfect mirror has no Phong lobe).
const MIN_ALPHA: f32 = 0.01;

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

    #[test]
    fn exponent_grows_as_roughness_falls() {
        assert_eq!(phong_exponent(1.0), 1.0);
        assert!(phong_exponent(0.5) > 20.0);
        assert_eq!(phong_exponent(0.0), 10_000.0);
    }
}
