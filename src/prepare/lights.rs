//! One interface for every kind of light, as pbrt-v4's `Light::SampleLi` / `PDF_Li` and
//! Mitsuba 3's `sample_emitter_direction` / `pdf_emitter_direction`: an integrator asks a
//! [`SceneLight`] for a [`LightSample`] seen from a shading point (direction, distance, density,
//! what arrives) without knowing whether it came from a punctual light, an emissive triangle or
//! the environment, and asks [`SceneLight::pdf`] how likely light sampling was to find what a
//! BSDF-sampled ray found (for multiple importance sampling).
//!
//! Units (glTF 2.0 `KHR_lights_punctual`): a punctual light delivers irradiance (candela / d²
//! for point and spot, lux for directional); emissive triangles and the environment radiance.

use crate::light::environment::{Environment, MapPoint};
use crate::light::PunctualLight;
use crate::prepare::Prepared;
use glam::Vec3;

/// A light of a render, of any kind.
#[derive(Clone, Copy, Debug)]
pub enum SceneLight<'a> {
    /// A `KHR_lights_punctual` light (or the default rig's): a delta light, found by light
    /// sampling only.
    Punctual(&'a PunctualLight),
    /// Every emissive triangle of the prepared scene ([`Prepared::area_lights`]), one point
    /// drawn by power.
    Area,
    /// The environment, one direction drawn by luminance.
    Environment(&'a Environment),
}

/// One light sample as seen from a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample<'a> {
    /// Unit vector from the shading point toward the sampled point of the light.
    pub to_light: Vec3,
    /// Distance to the sampled point; infinite for the environment and directional lights.
    pub distance: f32,
    /// The sampled point itself, where there is one (a point or spot light's position; a
    /// point of an emissive triangle, moved off it toward the shading point by its error
    /// bound): shadow rays are aimed at it.
    pub target: Option<Vec3>,
    /// Density per solid angle with which the direction was drawn; `None` for a delta light
    /// (a punctual one), which no BSDF sample can find.
    pub pdf: Option<f32>,
    /// Where what arrives comes from.
    emitter: Emitter<'a>,
}

/// What arrives along a light sample, known at once or looked up on demand.
#[derive(Clone, Copy, Debug)]
enum Emitter<'a> {
    /// Irradiance of a delta light.
    Known(Vec3),
    /// A point of the environment: its radiance (a bilinear lookup in the panorama) is read
    /// only for samples that arrive unblocked, as an emissive triangle's.
    Environment {
        /// The environment.
        environment: &'a Environment,
        /// Where in its panorama.
        at: MapPoint,
    },
    /// A point of an emissive triangle: its radiance needs the emissive texture, read only for
    /// samples whose shadow ray found the light visible.
    Triangle {
        /// Soup index of the triangle.
        triangle: usize,
        /// Barycentric coordinates of the point.
        barycentric: Vec3,
    },
}

impl LightSample<'_> {
    /// What arrives at the shading point along [`LightSample::to_light`], before shadowing:
    /// irradiance for a delta light, radiance otherwise.
    #[inline(always)]
    pub fn arriving(&self, scene: &Prepared) -> Vec3 {
        match self.emitter {
            Emitter::Known(value) => value,
            Emitter::Triangle {
                triangle,
                barycentric,
            } => scene.emission_at(triangle, barycentric),
            Emitter::Environment { environment, at } => environment.radiance_at(at),
        }
    }
}

/// Where a BSDF-sampled ray met an emissive triangle, for [`SceneLight::pdf`].
#[derive(Clone, Copy, Debug)]
pub struct EmitterHit {
    /// Soup index of the triangle hit.
    pub triangle: u32,
    /// Distance along the ray.
    pub distance: f32,
    /// |cos| between the ray and the triangle's geometric normal.
    pub cos: f32,
}

impl<'a> SceneLight<'a> {
    /// A sample of this light seen from `point`, drawn with the uniform numbers `u` (punctual
    /// lights use none, the environment the first two, the emissive triangles all three: one
    /// to pick a triangle by power, two for the point on it). `None` when the light delivers
    /// nothing there (behind a spot's cone, past its range, no emissive triangle, a point on
    /// the light at the shading point itself).
    #[inline(always)]
    pub fn sample(&self, scene: &Prepared, point: Vec3, u: [f32; 3]) -> Option<LightSample<'a>> {
        match *self {
            SceneLight::Punctual(light) => {
                let incident = light.incident(point)?;
                Some(LightSample {
                    to_light: incident.to_light,
                    distance: incident.distance,
                    target: light.position(),
                    pdf: None,
                    emitter: Emitter::Known(incident.irradiance),
                })
            }
            SceneLight::Area => {
                let sample = scene.area_lights.sample(u[0], u[1], u[2])?;
                let triangle = sample.triangle as usize;
                let [a, b, c] = scene.scene.soup.triangle(triangle);
                let barycentric = sample.barycentric;
                let on_light = a * barycentric.x + b * barycentric.y + c * barycentric.z;
                let offset = on_light - point;
                // Off the light by its error bound, toward the shading point (pbrt-v4's
                // SpawnRayTo between two surfaces): the shadow ray then stops before the light.
                let target = match sample.frame.and_then(|f| f.at([a, b, c], barycentric)) {
                    Some(spawn) => spawn.origin(-offset),
                    None => on_light,
                };
                let distance = offset.length();
                let to_light = offset / distance.max(f32::MIN_POSITIVE);
                // The triangle emits from both faces.
                let cos_light = sample.normal.dot(to_light).abs();
                if !(distance > 0.0 && distance.is_finite() && cos_light > 0.0) {
                    return None;
                }
                Some(LightSample {
                    to_light,
                    distance,
                    target: Some(target),
                    // Area density to solid angle: p_ω = p_A · d² / |cos θ_light|.
                    pdf: Some(sample.pdf_area * distance * distance / cos_light),
                    emitter: Emitter::Triangle {
                        triangle,
                        barycentric,
                    },
                })
            }
            SceneLight::Environment(environment) => {
                let (to_light, pdf, at) = environment.sample_direction(u[0], u[1])?;
                Some(LightSample {
                    to_light,
                    distance: f32::INFINITY,
                    target: None,
                    pdf: Some(pdf),
                    emitter: Emitter::Environment { environment, at },
                })
            }
        }
    }

    /// The density per solid angle with which [`SceneLight::sample`] draws `direction`: what a
    /// BSDF-sampled ray in that direction found of this light is weighed against it. `hit`
    /// says where the ray met an emissive triangle (for [`SceneLight::Area`]); zero for a
    /// punctual light (no direction meets a point) and for an area light without `hit`.
    #[inline(always)]
    pub fn pdf(&self, scene: &Prepared, direction: Vec3, hit: Option<EmitterHit>) -> f32 {
        match *self {
            SceneLight::Punctual(_) => 0.0,
            SceneLight::Area => hit.map_or(0.0, |hit| {
                scene.area_lights.pdf_area(hit.triangle) * hit.distance * hit.distance
                    / hit.cos.max(1e-8)
            }),
            SceneLight::Environment(environment) => environment.pdf(direction),
        }
    }
}
