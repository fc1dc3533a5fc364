//! Punctual lights (`KHR_lights_punctual`): the irradiance each delivers to a surface point.
//!
//! Units follow the extension: point and spot intensity in candela (lm/sr), so the illuminance
//! at distance d is I/d² lux; directional intensity in lux. The renderer's output is radiance in
//! the same photometric scale: a white Lambertian surface under 1 lux at normal incidence has
//! radiance 1/π ≈ 0.318, which `--exposure 0` writes unchanged (before sRGB encoding).

pub mod environment;

use crate::geometry::SpawnFrame;
use crate::scene::{Light, LightKind};
use glam::Vec3;

/// What one light delivers to one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Incident {
    /// Unit vector from the surface point toward the light.
    pub to_light: Vec3,
    /// Distance to the light (infinite for directional lights): the shadow ray's extent.
    pub distance: f32,
    /// Illuminance on a surface facing the light, per colour channel (lux), before the cosine.
    pub irradiance: Vec3,
}

/// The irradiance `light` delivers at `point`, or `None` where it contributes nothing (outside
/// its range or cone, or at its exact position).
///
/// - Point and spot: inverse square with the extension's recommended range window
///   `clamp(1 - (d/range)⁴, 0, 1)² / d²` (KHR_lights_punctual, "Range Property").
/// - Spot: the extension's smooth cone falloff: with `cd = cos` of the angle off the axis,
///   `scale = 1 / max(0.001, cos(inner) - cos(outer))`, `offset = -cos(outer)·scale`,
///   attenuation = `clamp(cd·scale + offset, 0, 1)²`.
pub fn incident(light: &Light, point: Vec3) -> Option<Incident> {
    PunctualLight::new(light).incident(point)
}

/// A punctual light ready for [`incident`]'s question at many points: what depends only on
/// the light (colour × intensity, a spot's cone scale and offset, which take two cosines) is
/// computed once, when a render starts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PunctualLight {
    /// Colour × intensity: candela per channel (point, spot) or lux (directional).
    radiant: Vec3,
    /// World position (point and spot).
    position: Vec3,
    /// Unit direction the light travels.
    direction: Vec3,
    /// `range`, if any (point and spot).
    range: Option<f32>,
    /// Directional (no position, no falloff).
    directional: bool,
    /// A spot's `(scale, offset)` of the cone falloff; `None` for other lights.
    cone: Option<(f32, f32)>,
}

impl PunctualLight {
    /// `light`'s constants (see [`incident`] for the formulas).
    pub fn new(light: &Light) -> PunctualLight {
        let cone = match light.kind {
            LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => {
                let cos_outer = outer_cone_angle.cos();
                let scale = 1.0 / (inner_cone_angle.cos() - cos_outer).max(0.001);
                Some((scale, -cos_outer * scale))
            }
            _ => None,
        };
        PunctualLight {
            radiant: light.color * light.intensity,
            position: light.position,
            direction: light.direction,
            range: light.range,
            directional: light.kind == LightKind::Directional,
            cone,
        }
    }

    /// Where the light is: `None` for a directional light (at infinity).
    pub fn position(&self) -> Option<Vec3> {
        (!self.directional).then_some(self.position)
    }

    /// The irradiance this light delivers at `point` (see [`incident`]).
    #[inline]
    pub fn incident(&self, point: Vec3) -> Option<Incident> {
        if self.directional {
            return Some(Incident {
                to_light: -self.direction,
                distance: f32::INFINITY,
                irradiance: self.radiant,
            });
        }
        let offset = self.position - point;
        let d2 = offset.length_squared();
        if d2.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let distance = d2.sqrt();
        let to_light = offset / distance;
        let window = match self.range {
            Some(range) => {
                let r = distance / range;
                (1.0 - r * r * r * r).clamp(0.0, 1.0).powi(2)
            }
            None => 1.0,
        };
        let cone = match self.cone {
            Some((scale, offset)) => {
                let cd = self.direction.dot(-to_light);
                (cd * scale + offset).clamp(0.0, 1.0).powi(2)
            }
            None => 1.0,
        };
        let attenuation = window * cone / d2;
        (attenuation > 0.0).then_some(Incident {
            to_light,
            distance,
            irradiance: self.radiant * attenuation,
        })
    }
}

/// Emissive triangles as area lights: every triangle whose material emits
/// (`emissiveFactor` × `KHR_materials_emissive_strength` × texture, OBJ `Ke`), picked for
/// next-event estimation in proportion to its power estimate, luminance(emission) × area, with
/// the emission estimated at the triangle's corners and centroid: a helmet whose emissive
/// texture lights only a few panels spends its light samples there (a triangle estimated black
/// is never light-sampled; BSDF sampling still finds any emission it has, at full MIS weight,
/// so the estimate stays unbiased). Each
/// emits from both faces, as an emission shader on a mesh does in Cycles. Radiance units are
/// those of the rest of the renderer (nits on the photometric scale of [`incident`]).
#[derive(Clone, Debug, Default)]
pub struct AreaLights {
    /// Soup index of each light triangle.
    triangles: Vec<u32>,
    /// Density per unit area of a point drawn on each light triangle: its probability over
    /// its area.
    pdf_areas: Vec<f32>,
    /// Unit normal of each light triangle ((b - a) × (c - a), normalised).
    normals: Vec<Vec3>,
    /// Each light triangle's error bound and normal for the points drawn on it, where shadow
    /// rays toward it stop ([`crate::geometry::spawn`]).
    frames: Vec<Option<SpawnFrame>>,
    /// Which light to sample.
    distribution: crate::sampling::Distribution1D,
    /// For each soup triangle, its light index or `u32::MAX` (empty when there are no lights).
    index_of: Vec<u32>,
}

/// A point drawn on an area light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AreaSample {
    /// Soup index of the triangle.
    pub triangle: u32,
    /// Barycentric coordinates of the point.
    pub barycentric: Vec3,
    /// Probability density of the point per unit area (over all lights).
    pub pdf_area: f32,
    /// The triangle's unit normal (it emits from both faces).
    pub normal: Vec3,
    /// The triangle's [`SpawnFrame`] (`None` if degenerate).
    pub frame: Option<SpawnFrame>,
}

impl AreaLights {
    /// The emissive triangles of `scene`; `estimate(triangle)` is the emitted radiance's
    /// luminance averaged over the triangle (called only for triangles whose material emits).
    pub fn new(scene: &crate::Scene, estimate: impl Fn(usize) -> f32) -> AreaLights {
        let soup = &scene.soup;
        let emits: Vec<bool> = scene
            .materials
            .iter()
            .map(|m| crate::color::luminance(m.emissive * m.emissive_strength) > 0.0)
            .collect();
        let mut lights = AreaLights::default();
        let mut weights = Vec::new();
        for (tri, &m) in soup.material.iter().enumerate() {
            if !emits.get(m as usize).copied().unwrap_or(false) {
                continue;
            }
            let power = estimate(tri);
            if power > 0.0 && power.is_finite() {
                let [a, b, c] = soup.triangle(tri);
                let n = (b - a).cross(c - a);
                let area = 0.5 * n.length();
                if area > 0.0 && area.is_finite() {
                    lights.triangles.push(tri as u32);
                    lights.pdf_areas.push(area);
                    lights.normals.push(n / (2.0 * area));
                    lights.frames.push(SpawnFrame::of([a, b, c]));
                    weights.push(power * area);
                }
            }
        }
        if !lights.triangles.is_empty() {
            lights.index_of = vec![u32::MAX; soup.len()];
            for (i, &tri) in lights.triangles.iter().enumerate() {
                lights.index_of[tri as usize] = i as u32;
            }
        }
        lights.distribution = crate::sampling::Distribution1D::new(weights);
        // (The areas were kept here until the probabilities were known.)
        for (i, pdf) in lights.pdf_areas.iter_mut().enumerate() {
            *pdf = lights.distribution.probability(i) / *pdf;
        }
        lights
    }

    /// Number of emissive triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// True when the scene emits nothing.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// A point on the lights from three uniform numbers: a light in proportion to its power,
    /// then a uniform point on it.
    #[inline(always)]
    pub fn sample(&self, u_light: f32, u1: f32, u2: f32) -> Option<AreaSample> {
        let i = self.distribution.sample_index(u_light)?;
        let pdf_area = self.pdf_areas[i];
        Some(AreaSample {
            triangle: self.triangles[i],
            barycentric: crate::sampling::uniform_triangle(u1, u2),
            pdf_area,
            normal: self.normals[i],
            frame: self.frames[i],
        })
    }

    /// The density per unit area with which [`AreaLights::sample`] draws a point on soup
    /// triangle `triangle` (0 for a triangle that does not emit).
    pub fn pdf_area(&self, triangle: u32) -> f32 {
        match self.index_of.get(triangle as usize) {
            Some(&i) if i != u32::MAX => self.pdf_areas[i as usize],
            _ => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn light(kind: LightKind) -> Light {
        Light {
            name: None,
            kind,
            color: Vec3::ONE,
            intensity: 100.0,
            range: None,
            position: Vec3::new(0.0, 10.0, 0.0),
            direction: Vec3::NEG_Y,
        }
    }

    #[test]
    fn point_light_falls_off_with_inverse_square() {
        let l = light(LightKind::Point);
        let e = incident(&l, Vec3::ZERO).unwrap();
        assert!(
            (e.irradiance.x - 1.0).abs() < 1e-6,
            "100 cd at 10 m is 1 lux"
        );
        assert_eq!(e.to_light, Vec3::Y);
        assert!((e.distance - 10.0).abs() < 1e-6);
    }

    #[test]
    fn range_window_reaches_zero_at_range() {
        let mut l = light(LightKind::Point);
        l.range = Some(10.0);
        assert!(incident(&l, Vec3::ZERO).is_none());
        l.range = Some(20.0);
        let e = incident(&l, Vec3::ZERO).unwrap();
        assert!((e.irradiance.x - (1.0 - 0.0625f32).powi(2)).abs() < 1e-6);
    }

    #[test]
    fn spot_cone_is_full_inside_and_zero_outside() {
        let l = light(LightKind::Spot {
            inner_cone_angle: 0.2,
            outer_cone_angle: 0.4,
        });
        let on_axis = incident(&l, Vec3::ZERO).unwrap();
        assert!((on_axis.irradiance.x - 1.0).abs() < 1e-5);
        // 0.5 rad off the axis is outside the outer cone.
        let p = Vec3::new(10.0 * 0.5f32.tan(), 0.0, 0.0);
        assert!(incident(&l, p).is_none());
    }

    #[test]
    fn directional_light_is_lux_everywhere() {
        let l = light(LightKind::Directional);
        let e = incident(&l, Vec3::new(123.0, -4.0, 5.0)).unwrap();
        assert_eq!(e.irradiance, Vec3::splat(100.0));
        assert_eq!(e.to_light, Vec3::Y);
        assert!(e.distance.is_infinite());
    }
}
