//! The path tracer: unidirectional paths from the camera with next-event estimation.
//!
//! At every surface the path meets it estimates direct light three ways: each punctual light
//! through a shadow ray (delta lights: light sampling only), one point on the emissive
//! triangles ([`crate::light::AreaLights`], drawn by power) and one direction of the
//! environment ([`crate::light::environment::Environment`], drawn by luminance); then it continues in
//! a direction drawn from the BSDF ([`crate::shading::bsdf::Bsdf`]: GGX visible normals or cosine).
//! Emission that a BSDF-sampled ray then finds (an emissive triangle, or the environment when it
//! escapes) is weighted against the light-sampling estimate of the same light by the power
//! heuristic (Veach 1997), so neither strategy is counted twice and each covers where the other
//! is poor (small bright lights, sharp highlights). After [`ROULETTE_DEPTH`] bounces a path
//! survives with probability max(throughput) (Russian roulette), at most `max_bounces`.
//!
//! BLEND surfaces are hit with probability alpha and passed through otherwise; MASK cut-outs
//! are skipped in traversal as for camera rays. Materials are the glTF metallic-roughness BRDF
//! with the specular, sheen and clearcoat layers ([`crate::shading`]) and smooth transmission
//! ([`crate::shading::bsdf`]).
//!
//! All randomness comes from the pixel's own stream, in a fixed order, so the image is the same
//! for any number of threads.

use super::{CameraRay, Integrator, RayCounts};
use crate::accel::Hit;
use crate::defaults::MAX_BLEND_LAYERS;
use crate::light::environment::Environment;
use crate::light::PunctualLight;
use crate::prepare::lights::{EmitterHit, LightSample, SceneLight};
use crate::prepare::Prepared;
use crate::sampling::{power_heuristic, Sampler};
use crate::scene::AlphaMode;
use crate::shading::bsdf::Bsdf;
use crate::shading::surface::{Occlusion, Surface};
use glam::Vec3;
use std::sync::Arc;

/// Bounces before Russian roulette may end a path.
pub const ROULETTE_DEPTH: u32 = 3;

/// Lowest survival probability under Russian roulette (keeps the weight 1/q bounded by 20).
const MIN_SURVIVAL: f32 = 0.05;

/// A path tracer with next-event estimation and MIS.
#[derive(Clone, Debug)]
pub struct PathTracer {
    /// Punctual lights.
    pub lights: Vec<PunctualLight>,
    /// The environment that lights the scene, if any.
    pub environment: Option<Arc<Environment>>,
    /// Whether camera rays that miss see the environment (else they are transparent).
    pub environment_visible: bool,
    /// Most surface interactions after the first hit (0 = direct light only).
    pub max_bounces: u32,
    /// How light from emissive triangles and the environment is estimated (MIS by default;
    /// the single strategies are there to test it against).
    pub estimator: Estimator,
    /// `--clamp-indirect`: the most a sample's indirect light (light that reached the first
    /// surface after at least one more bounce) may bring, by its largest channel; brighter
    /// samples are scaled down to it. Removes fireflies from rare bright paths (caustics
    /// through glass, small bright reflections) at the cost of a bias toward darker indirect
    /// light, as Cycles' "Clamp Indirect" does. `None`: unbiased.
    pub clamp_indirect: Option<f32>,
}

/// The strategies that estimate light from emissive triangles and the environment. Punctual
/// lights are found by light sampling alone in every case (a BSDF sample never hits a point).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Estimator {
    /// Light sampling and BSDF sampling, weighted by the power heuristic (Veach 1997).
    #[default]
    Mis,
    /// Light sampling alone: emission found by BSDF-sampled rays counts nothing (camera rays
    /// still see it).
    LightOnly,
    /// BSDF sampling alone: no light samples for emissive triangles or the environment; the
    /// emission a BSDF-sampled ray finds counts in full.
    BsdfOnly,
}

impl Estimator {
    /// The weight of a light sample drawn with density `light_pdf` that the BSDF would have
    /// drawn with density `bsdf_pdf` (both per steradian).
    #[inline(always)]
    fn light_weight(self, light_pdf: f32, bsdf_pdf: f32) -> f32 {
        match self {
            Estimator::Mis => power_heuristic(light_pdf, bsdf_pdf),
            Estimator::LightOnly => 1.0,
            Estimator::BsdfOnly => 0.0,
        }
    }

    /// The weight of emission found by a BSDF sample drawn with density `bsdf_pdf` that light
    /// sampling would have drawn with density `light_pdf`. A delta sample (`bsdf_pdf`
    /// infinite: through smooth glass) is one no light sample can find, so it counts in full
    /// whatever the strategy.
    #[inline(always)]
    fn bsdf_weight(self, bsdf_pdf: f32, light_pdf: f32) -> f32 {
        match self {
            Estimator::Mis => power_heuristic(bsdf_pdf, light_pdf),
            Estimator::LightOnly if bsdf_pdf.is_finite() => 0.0,
            Estimator::LightOnly | Estimator::BsdfOnly => 1.0,
        }
    }

    /// Whether emissive triangles and the environment are light-sampled.
    fn samples_lights(self) -> bool {
        self != Estimator::BsdfOnly
    }
}

impl Integrator for PathTracer {
    #[inline(always)]
    fn radiance(
        &self,
        scene: &Prepared,
        camera: &CameraRay,
        sampler: &mut Sampler,
        counts: &mut RayCounts,
        first: &mut Option<Hit>,
        mut guide: Option<&mut super::GuideSample>,
    ) -> (Vec3, f32) {
        let mut ray = camera.ray;
        // The first query is the camera ray's, which may come traced.
        let mut traced = camera.traced;
        let mut throughput = Vec3::ONE;
        let mut radiance = Vec3::ZERO;
        let mut coverage = 0.0;
        // The BSDF pdf of the direction the current ray was drawn with; None for camera rays.
        let mut bsdf_pdf: Option<f32> = None;
        let mut bounces = 0u32;
        let mut pass_throughs = 0usize;
        let mut cone = (camera.spread_base, camera.spread_per_distance);
        // Extinction coefficient of the volume the path is inside, if any.
        let mut medium: Option<Vec3> = None;
        // The radiance of the direct light at the first surface (its light samples and what
        // its BSDF sample found): what follows is indirect.
        let mut direct: Option<Vec3> = None;
        loop {
            if bounces == 0 {
                counts.primary += 1;
            } else {
                counts.indirect += 1;
            }
            let direction = Vec3::from(ray.direction);
            let Some(hit) = traced
                .take()
                .unwrap_or_else(|| scene.intersect_camera(&ray))
            else {
                if let Some((seen, background)) = self.escaped(throughput, direction, bsdf_pdf) {
                    radiance += seen;
                    if let (Some(background), Some(g)) = (background, guide.as_deref_mut()) {
                        g.background = background;
                    }
                }
                if bsdf_pdf.is_none() && self.environment_visible && self.environment.is_some() {
                    coverage = 1.0;
                }
                break;
            };
            if first.is_none() {
                *first = Some(hit);
            }
            if bsdf_pdf.is_none() && pass_throughs == 0 {
                if let Some(g) = guide.as_deref_mut() {
                    g.depth = Some(hit.t);
                }
            }
            if let Some(sigma) = medium {
                // KHR_materials_volume: T = exp(-σ·d) along the segment inside the volume.
                throughput *= (-sigma * hit.t).exp();
            }
            // Occlusion textures darken only the direct renderer's ambient term.
            let surface = scene.surface(&ray, &hit, cone.0 + cone.1 * hit.t, Occlusion::Skip);
            if surface.source.alpha_mode == AlphaMode::Blend
                && sampler.next_f32() >= surface.alpha
                && pass_throughs < MAX_BLEND_LAYERS
            {
                // Not there for this path: go on through, from the far side.
                pass_throughs += 1;
                ray = surface.ray(direction, f32::INFINITY);
                continue;
            }
            if bsdf_pdf.is_none() {
                coverage = 1.0;
                // The surface this camera sample stops at: the guides' albedo and normal.
                if let Some(g) = guide.as_deref_mut() {
                    (g.albedo, g.normal) = (surface.material.base_color, surface.normal);
                }
            }
            let emitted = self.emitted(scene, &hit, &surface, direction, bsdf_pdf, throughput);
            radiance += emitted;
            if let (None, Some(g)) = (bsdf_pdf, guide.as_deref_mut()) {
                g.emission += emitted;
            }
            if surface.source.unlit {
                // KHR_materials_unlit: it neither reflects nor transmits light.
                break;
            }
            if bounces == 1 {
                direct = Some(radiance);
            }
            // Past the last vertex that estimates direct light: this hit only completed the
            // previous vertex's BSDF-sampled half of the MIS pair (its emission, above).
            if bounces > self.max_bounces {
                break;
            }
            let to_eye = -direction;
            let material = surface.source;
            let bsdf = surface_bsdf(&surface, to_eye, hit.front, throughput);
            // The direction to continue in, drawn from the BSDF (three numbers drawn whether or
            // not it is used, so every later number keeps its dimension of the sequence) before the light samples: its
            // evaluation then overlaps their shadow rays' traversal.
            let u_lobe = sampler.next_f32();
            let (u1, u2) = sampler.next_2d();
            let continuation = bsdf.sample(to_eye, u_lobe, u1, u2);
            let vertex = Vertex {
                scene,
                surface: &surface,
                bsdf: &bsdf,
                to_eye,
                throughput,
            };
            let first_guide = guide.as_deref_mut().filter(|_| bounces == 0);
            self.next_event(&vertex, &mut radiance, sampler, counts, first_guide);
            let Some(sample) = continuation else {
                break;
            };
            // A reflected ray may not leave through the geometric surface; a transmitted one
            // goes through it.
            if !sample.delta && sample.direction.dot(surface.geometric) <= 0.0 {
                break;
            }
            throughput *= sample.weight;
            bsdf_pdf = Some(sample.pdf);
            if sample.delta
                && !material.thin_walled
                && sample.direction.dot(surface.geometric) < 0.0
            {
                // Into the volume (Beer-Lambert attenuation until the next surface), or out.
                // Where the thickness texture makes the wall thin, the path crosses it without
                // entering (and leaves, if it was inside).
                medium = (hit.front && !surface.thin_walled)
                    .then(|| extinction(material))
                    .flatten();
            }
            cone = (cone.0 + cone.1 * hit.t, cone.1);
            ray = surface.ray(sample.direction, f32::INFINITY);
            bounces += 1;
            if bounces >= ROULETTE_DEPTH && !survives_roulette(&mut throughput, sampler) {
                break;
            }
            if !throughput.is_finite() || throughput == Vec3::ZERO {
                break;
            }
        }
        (self.clamped(radiance, direct), coverage)
    }
}

/// The BSDF of `surface` seen from `to_eye`, with its transmission lobe where it has one
/// (`front`: the ray arrived on the front face, so a volume's boundary is entered), dispersed
/// where the material says so (`KHR_materials_dispersion`), following the one colour channel
/// the path's `throughput` carries, if it carries only one.
#[inline(always)]
fn surface_bsdf<'a>(surface: &'a Surface, to_eye: Vec3, front: bool, throughput: Vec3) -> Bsdf<'a> {
    let bsdf = Bsdf::new(&surface.material, surface.normal, to_eye);
    if surface.transmission > 0.0 {
        let material = surface.source;
        let bsdf = bsdf.with_transmission(
            to_eye,
            surface.transmission,
            material.ior,
            surface.thin_walled,
            front,
        );
        if material.dispersion > 0.0 {
            return bsdf.with_dispersion(
                material.dispersion,
                material.ior,
                lone_channel(throughput),
            );
        }
        return bsdf;
    }
    bsdf
}

/// The one colour channel `throughput` carries (the others 0), if it carries exactly one.
fn lone_channel(throughput: Vec3) -> Option<usize> {
    let carried = throughput.cmpgt(Vec3::ZERO).bitmask();
    (carried.count_ones() == 1).then(|| carried.trailing_zeros() as usize)
}

/// A path vertex as next-event estimation sees it.
struct Vertex<'a> {
    scene: &'a Prepared,
    surface: &'a Surface<'a>,
    bsdf: &'a Bsdf<'a>,
    /// Unit vector toward where the path came from.
    to_eye: Vec3,
    /// The path's throughput up to this vertex.
    throughput: Vec3,
}

impl PathTracer {
    /// What `surface` sends back along the path (reached along `direction` at `hit`, with
    /// `throughput`): a `KHR_materials_unlit` surface's base colour, which is what the camera
    /// (or a path) sees of it, or the emission, MIS-weighted: in full for a camera ray
    /// (`bsdf_pdf` None: no light sample could have found it), else by the estimator's BSDF
    /// weight against the area light's pdf of the same direction.
    #[inline(always)]
    fn emitted(
        &self,
        scene: &Prepared,
        hit: &Hit,
        surface: &Surface,
        direction: Vec3,
        bsdf_pdf: Option<f32>,
        throughput: Vec3,
    ) -> Vec3 {
        if surface.source.unlit {
            return throughput * surface.material.base_color;
        }
        if surface.emissive == Vec3::ZERO {
            return Vec3::ZERO;
        }
        let weight = match bsdf_pdf {
            None => 1.0,
            Some(pdf) => {
                let at = EmitterHit {
                    triangle: hit.triangle,
                    distance: hit.t,
                    cos: surface.geometric.dot(direction).abs(),
                };
                let light_pdf = SceneLight::Area.pdf(scene, direction, Some(at));
                self.estimator.bsdf_weight(pdf, light_pdf)
            }
        };
        throughput * surface.emissive * weight
    }

    /// A sample's `radiance` with its indirect part (what it holds beyond `direct`, the first
    /// surface's direct light) scaled down to [`PathTracer::clamp_indirect`] in its largest
    /// channel; as it is without a clamp or without indirect light.
    fn clamped(&self, radiance: Vec3, direct: Option<Vec3>) -> Vec3 {
        let (Some(limit), Some(direct)) = (self.clamp_indirect, direct) else {
            return radiance;
        };
        let indirect = radiance - direct;
        let peak = indirect.max_element();
        if peak > limit {
            direct + indirect * (limit / peak)
        } else {
            radiance
        }
    }

    /// What a ray that meets no surface brings back: the environment's radiance, seen directly
    /// by a camera ray when it is visible, or found by a BSDF sample (drawn with density
    /// `bsdf_pdf`) and weighed against light sampling; with, for a camera ray, the radiance it
    /// sees (the denoiser's background guide). `None` without an environment.
    #[inline(always)]
    fn escaped(
        &self,
        throughput: Vec3,
        direction: Vec3,
        bsdf_pdf: Option<f32>,
    ) -> Option<(Vec3, Option<Vec3>)> {
        let env = self.environment.as_deref()?;
        match bsdf_pdf {
            None if self.environment_visible => {
                let seen = env.radiance(direction);
                Some((throughput * seen, Some(seen)))
            }
            None => None,
            Some(pdf) => {
                // SceneLight::Environment's pdf, with the radiance from one mapping of the
                // direction to the panorama.
                let (seen, light_pdf) = env.radiance_and_pdf(direction);
                let weight = self.estimator.bsdf_weight(pdf, light_pdf);
                Some((throughput * seen * weight, None))
            }
        }
    }

    /// Next-event estimation at `vertex`, added to `radiance`: every punctual light, one point on
    /// the emissive triangles and one direction of the environment, each through a shadow ray
    /// ([`PathTracer::light_sample`]). The area-light point and the environment direction are
    /// drawn (three dimensions of the sampler, taken or skipped in any case so every later
    /// number keeps its dimension) before any shadow ray is traced, so their arithmetic (and the environment's table lookups) overlaps the
    /// traversal of the punctual lights' shadow rays. Seen from below its shading normal, the
    /// BSDF reflects nothing toward the eye ([`Bsdf::eval_pdf`] is zero for every light
    /// direction), so no light is sampled there.
    ///
    /// With `guide` (at the camera ray's surface), the punctual lights' visibility there goes
    /// into it ([`super::GuideSample::visibility`]).
    #[inline(always)]
    fn next_event(
        &self,
        vertex: &Vertex,
        radiance: &mut Vec3,
        sampler: &mut Sampler,
        counts: &mut RayCounts,
        guide: Option<&mut super::GuideSample>,
    ) {
        // The punctual lights' unblocked and total irradiance luminance, for `guide`.
        let mut seen = (0.0f32, 0.0f32);
        let track = guide.is_some() && !self.lights.is_empty();
        let (scene, point) = (vertex.scene, vertex.surface.spawn.point);
        let lit = vertex.surface.normal.dot(vertex.to_eye) > 0.0;
        let sample_lights = lit && self.estimator.samples_lights();
        // Numbers a light does not need are skipped, not drawn: their dimensions stay theirs.
        let area = if sample_lights && !scene.area_lights.is_empty() {
            let u_light = sampler.next_f32();
            let (u1, u2) = sampler.next_2d();
            SceneLight::Area.sample(scene, point, [u_light, u1, u2])
        } else {
            sampler.skip(2);
            None
        };
        let environment = match self.environment.as_deref().filter(|_| sample_lights) {
            Some(env) => {
                let (u1, u2) = sampler.next_2d();
                SceneLight::Environment(env).sample(scene, point, [u1, u2, 0.0])
            }
            None => {
                sampler.skip(1);
                None
            }
        };
        for light in self.lights.iter().filter(|_| lit) {
            let Some(sample) = SceneLight::Punctual(light).sample(scene, point, [0.0; 3]) else {
                continue;
            };
            let transmittance = self.light_sample(vertex, &sample, radiance, counts);
            if let (true, Some(t)) = (track, transmittance) {
                let cos = vertex.surface.normal.dot(sample.to_light).max(0.0);
                let e = crate::color::luminance(sample.arriving(scene)) * cos;
                seen.0 += e * t;
                seen.1 += e;
            }
        }
        if let (true, Some(g)) = (track, guide) {
            g.visibility = (seen.1 > 0.0).then(|| seen.0 / seen.1);
        }
        if let Some(sample) = area {
            self.light_sample(vertex, &sample, radiance, counts);
        }
        if let Some(sample) = environment {
            self.light_sample(vertex, &sample, radiance, counts);
        }
    }

    /// Adds to `radiance` what one light sample brings to `vertex` (times its throughput): a
    /// shadow ray first, the BSDF only where light arrives (a blocked sample costs no
    /// evaluation), weighed against BSDF sampling for lights that it can find too. Returns the
    /// shadow ray's transmittance, `None` when the light is not on a side it can reach.
    #[inline(always)]
    fn light_sample(
        &self,
        vertex: &Vertex,
        sample: &LightSample,
        radiance: &mut Vec3,
        counts: &mut RayCounts,
    ) -> Option<f32> {
        // A punctual light behind a rough thin sheet or a diffusely transmitting wall shines
        // through it (below); any other light must be on the eye's side.
        let through = sample.pdf.is_none() && vertex.bsdf.shines_through();
        let shadow = match vertex.surface.shadow_ray_for(sample) {
            None if through => vertex.surface.shadow_ray_through(sample),
            shadow => shadow,
        };
        let shadow = shadow?;
        counts.shadow += 1;
        let transmittance = vertex.scene.shadow_transmittance(&shadow);
        let (to_eye, throughput) = (vertex.to_eye, vertex.throughput);
        match sample.pdf {
            // A delta light: light sampling alone finds it.
            None => {
                if transmittance > 0.0 {
                    // Reflected, or (a rough thin sheet) transmitted toward the eye: BSDF
                    // samples never find a punctual light, so both lobes are evaluated here.
                    let f = vertex.bsdf.eval_cos(to_eye, sample.to_light)
                        + vertex.bsdf.thin_transmission_cos(to_eye, sample.to_light);
                    *radiance += throughput * f * sample.arriving(vertex.scene) * transmittance;
                }
            }
            Some(light_pdf) => {
                let (f, bsdf_pdf) = if transmittance > 0.0 {
                    vertex.bsdf.eval_pdf(to_eye, sample.to_light)
                } else {
                    (Vec3::ZERO, 0.0)
                };
                if f != Vec3::ZERO {
                    let arriving = sample.arriving(vertex.scene);
                    let weight = self.estimator.light_weight(light_pdf, bsdf_pdf);
                    *radiance += throughput * f * arriving * transmittance * weight / light_pdf;
                }
            }
        }
        Some(transmittance)
    }
}

/// Russian roulette after [`ROULETTE_DEPTH`] bounces: the path goes on with probability
/// max(throughput) (clamped to [`MIN_SURVIVAL`], 1), its throughput divided by that
/// probability so the estimate stays unbiased. Draws one number of the sample.
#[inline(always)]
fn survives_roulette(throughput: &mut Vec3, sampler: &mut Sampler) -> bool {
    let survive = throughput.max_element().clamp(MIN_SURVIVAL, 1.0);
    if sampler.next_f32() >= survive {
        return false;
    }
    *throughput /= survive;
    true
}

/// The extinction coefficient σ of a `KHR_materials_volume`: light keeps
/// `attenuation_color` after `attenuation_distance`, so σ = -ln(color) / distance per channel.
/// `None` without attenuation (infinite distance or white).
fn extinction(material: &crate::scene::Material) -> Option<Vec3> {
    let d = material.attenuation_distance;
    if !(d.is_finite() && d > 0.0) || material.attenuation_color == Vec3::ONE {
        return None;
    }
    let c = material
        .attenuation_color
        .clamp(Vec3::splat(1e-6), Vec3::ONE);
    Some(Vec3::new(-c.x.ln(), -c.y.ln(), -c.z.ln()) / d)
}
