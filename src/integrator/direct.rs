//! The direct-lighting integrator (the renderer's behaviour before the path tracer): at the
//! first surface a camera ray meets, ambient × base colour × occlusion, emission, and each
//! punctual light through one shadow ray, shaded with the glTF metallic-roughness BRDF or
//! Blinn-Phong. BLEND surfaces are composited front to back along the camera ray (up to
//! [`MAX_BLEND_LAYERS`]).

use super::{CameraRay, Integrator, RayCounts};
use crate::accel::Hit;
use crate::defaults::MAX_BLEND_LAYERS;
use crate::geometry::Ray;
use crate::light::PunctualLight;
use crate::prepare::lights::SceneLight;
use crate::prepare::Prepared;
use crate::sampling::Sampler;
use crate::scene::AlphaMode;
use crate::shading::surface::{Occlusion, Surface};
use crate::shading::{shade, ShadingModel};
use glam::Vec3;

/// Direct lighting from punctual lights and a constant ambient term.
#[derive(Clone, Debug)]
pub struct Direct {
    /// Lights in use (the file's, or the default rig).
    pub lights: Vec<PunctualLight>,
    /// Ambient radiance multiplier for base colour (unshadowed).
    pub ambient: Vec3,
    /// Shading model.
    pub shading: ShadingModel,
}

impl Integrator for Direct {
    /// Radiance and coverage along a camera ray: (premultiplied colour, alpha).
    #[inline(always)]
    fn radiance(
        &self,
        scene: &Prepared,
        camera: &CameraRay,
        _sampler: &mut Sampler,
        counts: &mut RayCounts,
        first: &mut Option<Hit>,
        _guide: Option<&mut crate::integrator::GuideSample>,
    ) -> (Vec3, f32) {
        let mut color = Vec3::ZERO;
        let mut transmittance = 1.0f32;
        let mut tint = Vec3::ONE;
        let mut ray = camera.ray;
        // The first query is the camera ray's, which may come traced.
        let mut traced = camera.traced;
        for _ in 0..MAX_BLEND_LAYERS {
            counts.primary += 1;
            let Some(hit) = traced
                .take()
                .unwrap_or_else(|| scene.intersect_camera(&ray))
            else {
                break;
            };
            if first.is_none() {
                *first = Some(hit);
            }
            let surface = scene.surface(&ray, &hit, camera.footprint(hit.t), Occlusion::Sample);
            let shaded = self.shade(scene, &ray, &surface, &mut counts.shadow);
            let mut alpha = if surface.source.alpha_mode == AlphaMode::Blend {
                surface.alpha
            } else {
                1.0
            };
            // Transmission (glass, KHR_materials_transmission, OBJ illum 4-7) is approximated
            // as see-through: the surface shades with weight 1 - transmission and the rest of
            // the camera ray goes on straight, tinted by the base colour (no refraction, no
            // Fresnel); its shadows let thin sheets through tinted (see shadow_transmittance).
            let transmission = surface.transmission * (1.0 - surface.material.metallic);
            if transmission > 0.0 {
                alpha *= 1.0 - transmission;
            }
            color += shaded * alpha * transmittance * tint;
            if transmission > 0.0 {
                tint *= surface.material.base_color;
            }
            transmittance *= 1.0 - alpha;
            if transmittance < 1e-3 {
                transmittance = 0.0;
                break;
            }
            ray.tmin = hit.t;
        }
        (color, 1.0 - transmittance)
    }
}

impl Direct {
    /// Direct lighting of a surface point: ambient (with occlusion), emission, and each light
    /// through a shadow ray.
    fn shade(&self, scene: &Prepared, ray: &Ray, s: &Surface, shadow_rays: &mut u64) -> Vec3 {
        let to_eye = -Vec3::from(ray.direction);
        // KHR_materials_unlit: the base colour is the radiance; no light is involved.
        if s.source.unlit {
            return s.material.base_color;
        }
        let mut color = self.ambient * s.material.base_color * s.occlusion + s.emissive;
        for light in &self.lights {
            let Some(incoming) = SceneLight::Punctual(light).sample(scene, s.spawn.point, [0.0; 3])
            else {
                continue;
            };
            let Some(shadow) = s.shadow_ray_for(&incoming) else {
                continue;
            };
            *shadow_rays += 1;
            let transmittance = scene.shadow_transmittance(&shadow);
            if transmittance <= 0.0 {
                continue;
            }
            color += transmittance
                * shade(
                    self.shading,
                    &s.material,
                    s.normal,
                    incoming.to_light,
                    to_eye,
                    incoming.arriving(scene),
                );
        }
        color
    }
}
