//! Punctual lights (`KHR_lights_punctual`): the irradiance each delivers to a surface point.
//!
//! Units follow the extension: point and spot intensity in candela (lm/sr), so the illuminance
//! at distance d is I/d² lux; directional intensity in lux. The renderer's output is radiance in
//! the same photometric scale: a white Lambertian surface under 1 lux at normal incidence has
//! radiance 1/π ≈ 0.318, which `--exposure 0` writes unchanged (before sRGB encoding).

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
    let radiant = light.color * light.intensity;
    match light.kind {
        LightKind::Directional => Some(Incident {
            to_light: -light.direction,
            distance: f32::INFINITY,
            irradiance: radiant,
        }),
        LightKind::Point | LightKind::Spot { .. } => {
            let offset = light.position - point;
            let d2 = offset.length_squared();
            if d2.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                return None;
            }
            let distance = d2.sqrt();
            let to_light = offset / distance;
            let window = match light.range {
                Some(range) => {
                    let r = distance / range;
                    (1.0 - r * r * r * r).clamp(0.0, 1.0).powi(2)
                }
                None => 1.0,
            };
            let cone = match light.kind {
                LightKind::Spot {
                    inner_cone_angle,
                    outer_cone_angle,
                } => {
                    let cos_outer = outer_cone_angle.cos();
                    let scale = 1.0 / (inner_cone_angle.cos() - cos_outer).max(0.001);
                    let cd = light.direction.dot(-to_light);
                    (cd * scale - cos_outer * scale).clamp(0.0, 1.0).powi(2)
                }
                _ => 1.0,
            };
            let attenuation = window * cone / d2;
            (attenuation > 0.0).then_some(Incident {
                to_light,
                distance,
                irradiance: radiant * attenuation,
            })
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
