//! The direct-lighting integrator (the renderer's behaviour before the path tracer): at the
//! first surface a camera ray meets, ambient × base colour × occlusion, emission, and each
//! punctual light through one shadow ray, shaded with the glTF metallic-roughness BRDF or
//! Blinn-Phong. BLEND surfaces are composited front to back along the camera ray (up to
//! [`MAX_BLEND_LAYERS`]).

use super::{CameraRay, Integrator, Lane, RayCounts};
use crate::accel::Hit;
use crate::accel::PACKET;
use crate::defaults::MAX_BLEND_LAYERS;
use crate::geometry::Ray;
use crate::light::PunctualLight;
use crate::prepare::lights::{LightSample, SceneLight};
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
        self.layers(scene, camera, camera.ray, counts, first, Layers::new(), 0)
    }

    /// The lanes' first surfaces are lit together: each light's shadow rays from all of them
    /// go as one packet ([`Prepared::shadow_transmittance_many`]), then each lane goes on
    /// alone through any BLEND layers behind. Every lane adds its lights in the same order
    /// and with the same numbers as [`Direct::radiance`], so its result is the same.
    // Inlined into the pixel loop, hence into its copy for the CPU's vector units.
    #[inline(always)]
    fn radiance_many(&self, scene: &Prepared, lanes: &mut [Lane], counts: &mut RayCounts) {
        if lanes.len() > PACKET {
            for lanes in lanes.chunks_mut(PACKET) {
                self.radiance_many(scene, lanes, counts);
            }
            return;
        }
        // The lanes whose camera ray was traced and met a surface: shaded here.
        let mut lit: [Option<(Hit, Surface)>; PACKET] = std::array::from_fn(|_| None);
        let mut colors = [Vec3::ZERO; PACKET];
        for ((lane, lit), color) in lanes.iter().zip(lit.iter_mut()).zip(colors.iter_mut()) {
            let Some(Some(hit)) = lane.camera.traced else {
                continue;
            };
            let footprint = lane.camera.footprint(hit.t);
            let surface = scene.surface(&lane.camera.ray, &hit, footprint, Occlusion::Sample);
            *color = self.unlit(&surface);
            *lit = Some((hit, surface));
        }
        let mut incoming = [None; PACKET];
        let mut shadows = [Ray::new(Vec3::ZERO, Vec3::Z, 0.0, 1.0); PACKET];
        let mut from = [0usize; PACKET];
        let mut transmittance = [0.0f32; PACKET];
        for light in &self.lights {
            let mut count = 0;
            for (i, lit) in lit.iter().enumerate().take(lanes.len()) {
                let Some((_, surface)) = lit.as_ref().filter(|(_, s)| !s.source.unlit) else {
                    continue;
                };
                let Some((sample, shadow)) = Self::light_sample(scene, light, surface) else {
                    continue;
                };
                (incoming[count], shadows[count], from[count]) = (Some(sample), shadow, i);
                count += 1;
            }
            counts.shadow += count as u64;
            scene.shadow_transmittance_many(&shadows[..count], &mut transmittance[..count]);
            for k in 0..count {
                let (i, t) = (from[k], transmittance[k]);
                if let (Some((_, surface)), Some(sample)) = (&lit[i], &incoming[k]) {
                    let to_eye = -Vec3::from(lanes[i].camera.ray.direction);
                    if let Some(lit) = self.lit_by(scene, surface, sample, to_eye, t) {
                        colors[i] += lit;
                    }
                }
            }
        }
        for ((lane, lit), shaded) in lanes.iter_mut().zip(&lit).zip(colors) {
            let Lane { camera, first, .. } = lane;
            (lane.radiance, lane.coverage) = match lit {
                &Some((hit, ref surface)) => {
                    counts.primary += 1;
                    if first.is_none() {
                        *first = Some(hit);
                    }
                    let mut layers = Layers::new();
                    if layers.add(surface, shaded) {
                        let mut ray = camera.ray;
                        ray.tmin = hit.t;
                        let behind = CameraRay {
                            traced: None,
                            ..*camera
                        };
                        self.layers(scene, &behind, ray, counts, first, layers, 1)
                    } else {
                        layers.result()
                    }
                }
                None => self.layers(scene, camera, camera.ray, counts, first, Layers::new(), 0),
            };
        }
    }
}

/// What a camera ray has gathered through the BLEND layers it passed, front to back.
struct Layers {
    color: Vec3,
    /// What the layers so far let through.
    transmittance: f32,
    /// The tint of the see-through (transmissive) layers so far.
    tint: Vec3,
}

impl Layers {
    fn new() -> Self {
        Self {
            color: Vec3::ZERO,
            transmittance: 1.0,
            tint: Vec3::ONE,
        }
    }

    /// Adds the layer `surface`, which shaded to `shaded`; whether the ray goes on behind it.
    fn add(&mut self, surface: &Surface, shaded: Vec3) -> bool {
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
        self.color += shaded * alpha * self.transmittance * self.tint;
        if transmission > 0.0 {
            self.tint *= surface.material.base_color;
        }
        self.transmittance *= 1.0 - alpha;
        if self.transmittance < 1e-3 {
            self.transmittance = 0.0;
            return false;
        }
        true
    }

    /// (premultiplied colour, alpha).
    fn result(&self) -> (Vec3, f32) {
        (self.color, 1.0 - self.transmittance)
    }
}

impl Direct {
    /// The layers along `ray` (the rest of `camera`'s, after `done` of them gathered into
    /// `layers`), each shaded by [`Direct::shade`].
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn layers(
        &self,
        scene: &Prepared,
        camera: &CameraRay,
        mut ray: Ray,
        counts: &mut RayCounts,
        first: &mut Option<Hit>,
        mut layers: Layers,
        done: usize,
    ) -> (Vec3, f32) {
        // The first query is the camera ray's, which may come traced.
        let mut traced = camera.traced;
        for _ in done..MAX_BLEND_LAYERS {
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
            if !layers.add(&surface, shaded) {
                break;
            }
            ray.tmin = hit.t;
        }
        layers.result()
    }

    /// Direct lighting of a surface point: ambient (with occlusion), emission, and each light
    /// through a shadow ray.
    fn shade(&self, scene: &Prepared, ray: &Ray, s: &Surface, shadow_rays: &mut u64) -> Vec3 {
        let to_eye = -Vec3::from(ray.direction);
        let mut color = self.unlit(s);
        // KHR_materials_unlit: the base colour is the radiance; no light is involved.
        if s.source.unlit {
            return color;
        }
        for light in &self.lights {
            let Some((incoming, shadow)) = Self::light_sample(scene, light, s) else {
                continue;
            };
            *shadow_rays += 1;
            let transmittance = scene.shadow_transmittance(&shadow);
            if let Some(lit) = self.lit_by(scene, s, &incoming, to_eye, transmittance) {
                color += lit;
            }
        }
        color
    }

    /// What a surface shows without its lights: the base colour of a `KHR_materials_unlit`
    /// one; else ambient × base colour × occlusion, plus emission.
    #[inline(always)]
    fn unlit(&self, s: &Surface) -> Vec3 {
        if s.source.unlit {
            return s.material.base_color;
        }
        self.ambient * s.material.base_color * s.occlusion + s.emissive
    }

    /// `light` as seen from `s`, with the shadow ray to ask whether it arrives; `None` when it
    /// cannot light the point.
    #[inline(always)]
    fn light_sample<'a>(
        scene: &Prepared,
        light: &'a PunctualLight,
        s: &Surface,
    ) -> Option<(LightSample<'a>, Ray)> {
        let incoming = SceneLight::Punctual(light).sample(scene, s.spawn.point, [0.0; 3])?;
        let shadow = s.shadow_ray_for(&incoming)?;
        Some((incoming, shadow))
    }

    /// What the light sample `incoming`, whose shadow ray let `transmittance` through, adds to
    /// `s` seen from `to_eye`; `None` when its shadow ray was blocked.
    #[inline(always)]
    fn lit_by(
        &self,
        scene: &Prepared,
        s: &Surface,
        incoming: &LightSample,
        to_eye: Vec3,
        transmittance: f32,
    ) -> Option<Vec3> {
        if transmittance <= 0.0 {
            return None;
        }
        Some(
            transmittance
                * shade(
                    self.shading,
                    &s.material,
                    s.normal,
                    incoming.to_light,
                    to_eye,
                    incoming.arriving(scene),
                ),
        )
    }
}
