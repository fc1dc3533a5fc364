//! From a hit to a surface point: position with its error bound, normals (geometric, smooth,
//! normal-mapped), the material with its textures sampled, alpha. Integrators ask these
//! questions; none of them knows about pixels or lights.
//!
//! Alpha (glTF 2.0 §3.9.4): OPAQUE ignores alpha; MASK surfaces below `alphaCutoff` are absent
//! for camera and shadow rays alike (tested inside traversal); BLEND surfaces are composited by
//! the integrator and attenuate shadow rays by (1 - alpha) each: an approximation that ignores
//! their colour and the order of layers. Thin transmissive sheets (OPAQUE, or MASK where
//! present) attenuate shadow rays by what they let straight through at the point crossed (see
//! [`Prepared::shadow_transmittance`]).

use crate::accel::Hit;
use crate::geometry::{spawn, Ray, SpawnPoint};
use crate::prepare::lights::LightSample;
use crate::prepare::queries::channel_of;
use crate::prepare::textures::transform_uv;
use crate::prepare::Prepared;
use crate::scene::{
    AlphaMode, AnisotropyLayer, DiffuseTransmissionLayer, Material, ScalarMaps, TextureRef,
    TextureTransform,
};
use crate::shading::{
    Anisotropy, Clearcoat, DiffuseTransmission, Iridescence, Sheen, SurfaceMaterial,
};
use glam::{Vec2, Vec3, Vec4};
use std::cell::Cell;

/// Everything shading needs about a hit point.
pub struct Surface<'m> {
    /// The hit point with its error bound: where secondary rays leave from
    /// ([`crate::geometry::spawn`]).
    pub spawn: SpawnPoint,
    /// `spawn`'s origin for rays leaving on the `geometric` side (what
    /// [`SpawnPoint::origin`] gives for any such direction), computed once for the several
    /// rays a path vertex sends out.
    pub exit: Vec3,
    /// The triangle's corners and its vertex normals turned to the `geometric` side: what
    /// [`terminator_lift`] needs, kept so that the lift is computed only for the shadow rays
    /// that use it.
    corners: ([Vec3; 3], [Vec3; 3]),
    /// The hit's barycentric coordinates.
    barycentric: Vec3,
    /// Geometric normal facing the incoming ray.
    pub geometric: Vec3,
    /// Interpolated vertex normal on the geometric normal's side: the smooth surface the
    /// mesh approximates.
    pub smooth: Vec3,
    /// Shading normal (interpolated, normal-mapped) on the geometric normal's side.
    pub normal: Vec3,
    /// The BRDF inputs at the point (textures applied).
    pub material: SurfaceMaterial,
    /// Emitted radiance (emissive factor × texture × strength).
    pub emissive: Vec3,
    /// Ambient occlusion from the occlusion texture (1 = none, and 1 when evaluated with
    /// [`Occlusion::Skip`]).
    pub occlusion: f32,
    /// Coverage (1 for OPAQUE materials).
    pub alpha: f32,
    /// `KHR_materials_transmission` at the point: factor × texture red.
    pub transmission: f32,
    /// Whether the surface is a thin wall here, not a volume boundary: the material's
    /// [`Material::thin_walled`], or `KHR_materials_volume`'s thickness texture reading 0.
    pub thin_walled: bool,
    /// The material hit.
    pub source: &'m Material,
}

/// Whether [`Prepared::surface`] samples the occlusion texture.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Occlusion {
    /// Sample it: the direct renderer darkens its ambient term with it.
    Sample,
    /// Leave it out (`occlusion` = 1): the path tracer finds occlusion by tracing, and one
    /// texture lookup of five on DamagedHelmet, most of them cache misses at 2048², is saved.
    Skip,
}

impl Surface<'_> {
    /// The shadow ray toward a light in direction `to_light` (unit) at `distance` (infinite for
    /// a direction), or `None` where the light cannot reach this point of the surface.
    ///
    /// The light must be above the smooth surface (not the flat facet: near the terminator of
    /// a smooth-shaded mesh the facet test cuts light off facet by facet, a staircase) and above
    /// the shading normal. Flat triangles have smooth = facet.
    ///
    /// Shadow rays leave from the lifted point only where the light grazes or sits below the
    /// facet (cosine under [`TERMINATOR_BAND`], fading in): only there can the facet's own
    /// neighbours block a ray the smooth surface would let through. Elsewhere the lift would
    /// only move the origin off the real geometry and thin contact shadows (it cost the
    /// Avocado's seed its shadow). The same idea as Cycles' "shadow terminator geometry offset".
    #[inline]
    pub fn shadow_ray(&self, to_light: Vec3, distance: f32) -> Option<Ray> {
        let origin = self.shadow_origin(to_light)?;
        Some(Ray::new(origin, to_light, 0.0, spawn::ray_extent(distance)))
    }

    /// Where a shadow ray toward `to_light` leaves from ([`Surface::shadow_ray`] says which
    /// point and why), or `None` where the light cannot reach this point of the surface.
    #[inline]
    fn shadow_origin(&self, to_light: Vec3) -> Option<Vec3> {
        if to_light.dot(self.smooth) <= 0.0 || to_light.dot(self.normal) <= 0.0 {
            return None;
        }
        let toward = to_light.dot(self.geometric);
        let amount = (1.0 - toward / TERMINATOR_BAND).clamp(0.0, 1.0);
        if amount > 0.0 {
            Some(self.lifted_origin(to_light, amount))
        } else {
            // toward ≥ TERMINATOR_BAND > 0: the geometric side.
            Some(self.exit)
        }
    }

    /// The shadow ray toward a light sample on the far side of a thin sheet that lets light
    /// through ([`crate::shading::bsdf::Bsdf::thin_transmission_cos`]): from the sheet's far
    /// side (off it by its error bound), aimed at the light's point or along its direction.
    /// `None` when the light is not behind the sheet (its shading and smooth normals both
    /// point away from it).
    #[inline]
    pub fn shadow_ray_through(&self, sample: &LightSample) -> Option<Ray> {
        let to_light = sample.to_light;
        if to_light.dot(self.smooth) >= 0.0 || to_light.dot(self.normal) >= 0.0 {
            return None;
        }
        let origin = self.spawn.origin(to_light);
        let Some(target) = sample.target else {
            return Some(Ray::new(
                origin,
                to_light,
                0.0,
                spawn::ray_extent(sample.distance),
            ));
        };
        let offset = target - origin;
        let distance = offset.length();
        (distance > 0.0 && distance.is_finite())
            .then(|| Ray::new(origin, offset / distance, 0.0, spawn::ray_extent(distance)))
    }

    /// The shadow ray toward a light sample: aimed at its point where it has one
    /// ([`Surface::shadow_ray_to`]), else along its direction to infinity.
    #[inline(always)]
    pub fn shadow_ray_for(&self, sample: &LightSample) -> Option<Ray> {
        match sample.target {
            Some(target) => self.shadow_ray_to(sample.to_light, target),
            None => self.shadow_ray(sample.to_light, sample.distance),
        }
    }

    /// The shadow ray toward the point `target` of a light, first seen from the surface point
    /// in direction `to_light` (unit): as [`Surface::shadow_ray`], but aimed at `target` from
    /// the origin it actually leaves from. That origin is off the surface by its error bound;
    /// a ray leaving it parallel to `to_light` would meet the light's own plane short of
    /// `target`, by that offset over the cosine at the light, and at grazing incidence that is
    /// more than [`crate::geometry::SHADOW_EPSILON`] of the distance: the light then shadowed
    /// itself (a plane 1 cm beside a panel lost all light sampling, and 60-100% of its
    /// irradiance past 4 cm). pbrt-v4 aims its `SpawnRayTo` the same way. `None` as for
    /// [`Surface::shadow_ray`], or when `target` is at the origin.
    #[inline]
    pub fn shadow_ray_to(&self, to_light: Vec3, target: Vec3) -> Option<Ray> {
        let origin = self.shadow_origin(to_light)?;
        let offset = target - origin;
        let distance = offset.length();
        (distance > 0.0 && distance.is_finite())
            .then(|| Ray::new(origin, offset / distance, 0.0, spawn::ray_extent(distance)))
    }

    /// The origin of a ray toward `to_light` from the point lifted toward the smooth surface
    /// by `amount` of [`terminator_lift`]: the grazing case, out of line.
    #[inline(never)]
    fn lifted_origin(&self, to_light: Vec3, amount: f32) -> Vec3 {
        let (vertices, normals) = self.corners;
        let lift = terminator_lift(self.spawn.point, vertices, normals, self.barycentric);
        self.spawn.moved(lift * amount).origin(to_light)
    }

    /// The ray leaving the surface along `direction` (unit) as far as `distance`:
    /// [`SpawnPoint::ray`], with the origin computed once for the geometric side.
    #[inline]
    pub fn ray(&self, direction: Vec3, distance: f32) -> Ray {
        if direction.dot(self.geometric) > 0.0 {
            self.exit_ray(direction, distance)
        } else {
            self.spawn.ray(direction, distance)
        }
    }

    /// [`SpawnPoint::ray`] from [`Surface::exit`]; `direction` must point to the geometric
    /// side.
    #[inline]
    fn exit_ray(&self, direction: Vec3, distance: f32) -> Ray {
        Ray::new(self.exit, direction, 0.0, spawn::ray_extent(distance))
    }
}

impl Prepared {
    /// Samples a texture at a hit with a mip level from the ray cone (Akenine-Möller et al.,
    /// "Texture Level of Detail Strategies for Real-Time Ray Tracing", 2019):
    /// lod = ½·log2(texels · uv area / world area) + log2(cone width / |n·d|).
    ///
    /// `last` remembers the coordinates and level of the previous texture sampled at this hit:
    /// textures that read the same coordinate set with the same transform and have the same
    /// size (DamagedHelmet's five) reuse them, the same numbers computed once.
    #[allow(clippy::too_many_arguments)]
    fn sample(
        &self,
        r: &TextureRef,
        tri: usize,
        b: Vec3,
        cone: f32,
        cos: f32,
        srgb: bool,
        last: &Cell<Option<TexelFootprint>>,
    ) -> Option<Vec4> {
        let (image, sampler) = self.textures.lookup(&self.scene, r)?;
        let size = image.size();
        let footprint = match last.get() {
            Some(f) if f.serves(r, size) => f,
            _ => {
                let f = self.footprint(r, size, tri, b, cone, cos);
                last.set(Some(f));
                f
            }
        };
        Some(image.sample(footprint.uv, footprint.lod, sampler, srgb))
    }

    /// Where texture reference `r` of an image of `size` texels is read at barycentrics `b` of
    /// triangle `tri`, and at which mip level (see [`Prepared::sample`]).
    fn footprint(
        &self,
        r: &TextureRef,
        size: (u32, u32),
        tri: usize,
        b: Vec3,
        cone: f32,
        cos: f32,
    ) -> TexelFootprint {
        let [pa, pb, pc] = self.scene.soup.triangle(tri);
        let lod = match self.scene.soup.corner_uvs(r.tex_coord, tri) {
            Some(corners) => {
                // The footprint is measured in the coordinates that address the texture, after
                // KHR_texture_transform (quantized files scale integer UVs by 1/4096 or so).
                let [ua, ub, uc] = corners.map(|uv| transform_uv(r, uv));
                let world = (pb - pa).cross(pc - pa).length();
                let uv_area = (ub - ua).perp_dot(uc - ua).abs();
                let (w, h) = size;
                let density = (w as f32 * h as f32 * uv_area / world.max(f32::MIN_POSITIVE)).sqrt();
                (density * cone / cos.abs().max(1e-3)).log2()
            }
            None => 0.0,
        };
        TexelFootprint {
            tex_coord: r.tex_coord,
            transform: r.transform,
            size,
            uv: transform_uv(r, self.uv(tri, r.tex_coord, b)),
            lod,
        }
    }

    /// The surface point `hit` found along `ray`: material inputs with textures sampled at a
    /// mip level from the ray cone's width `cone` at the hit; the occlusion texture only if
    /// `occlusion` asks for it.
    #[inline(always)]
    pub fn surface(&self, ray: &Ray, hit: &Hit, cone: f32, occlusion: Occlusion) -> Surface<'_> {
        let soup = &self.scene.soup;
        let tri = hit.triangle as usize;
        let b = hit.barycentric;
        let [pa, pb, pc] = soup.triangle(tri);
        let (spawn, facet) = spawn_and_facet([pa, pb, pc], b);
        let direction = Vec3::from(ray.direction);
        // The spawn point's own unit normal, turned to face the ray: negation is exact, so a
        // direction on this side is on the side `SpawnPoint::origin` offsets to (see `exit`).
        let geometric = if facet.dot(direction) > 0.0 {
            -facet
        } else {
            facet
        };
        let exit = spawn.origin(geometric);
        let cos = geometric.dot(direction);
        let [na, nb, nc] = soup.corner_normals(tri);
        let mut normal = (na * b.x + nb * b.y + nc * b.z)
            .try_normalize()
            .unwrap_or(geometric);
        if normal.dot(geometric) < 0.0 {
            normal = -normal;
        }
        let smooth = normal;
        let facing = |n: Vec3| if n.dot(geometric) < 0.0 { -n } else { n };
        let corners = ([pa, pb, pc], [facing(na), facing(nb), facing(nc)]);
        static DEFAULT: std::sync::OnceLock<Material> = std::sync::OnceLock::new();
        let material = self
            .scene
            .materials
            .get(soup.material[tri] as usize)
            .unwrap_or_else(|| DEFAULT.get_or_init(Material::default));
        let mut base = material.base_color;
        if let Some([ca, cb, cc]) = soup.corner_colors(tri) {
            base *= ca * b.x + cb * b.y + cc * b.z;
        }
        let last = Cell::new(None);
        let sample = |r: &Option<TextureRef>, srgb: bool| {
            r.as_ref()
                .and_then(|r| self.sample(r, tri, b, cone, cos, srgb, &last))
        };
        if let Some(t) = sample(&material.base_color_texture, true) {
            base *= t;
        }
        let (mut metallic, mut roughness) = (material.metallic, material.roughness);
        if let Some(t) = sample(&material.metallic_roughness_texture, false) {
            // glTF 2.0 §3.9.2: roughness in G, metalness in B.
            roughness *= t.y;
            metallic *= t.z;
        }
        if let Some(maps) = &material.scalar_maps {
            let [r, m, a] = self.scalar_factors(maps, &sample);
            (roughness, metallic, base.w) = (roughness * r, metallic * m, base.w * a);
        }
        // KHR_materials_pbrSpecularGlossiness: specular (sRGB RGB) and glossiness (linear A)
        // times their factors; c_diff = diffuse · (1 - max(specular)), F0 = specular (set
        // after the layers below), roughness = 1 - glossiness, no metal.
        let specular_glossiness = material.specular_glossiness.as_ref().map(|sg| {
            let (specular, glossiness) = match sample(&sg.texture, true) {
                Some(t) => (sg.specular * t.truncate(), sg.glossiness * t.w),
                None => (sg.specular, sg.glossiness),
            };
            base = (base.truncate() * (1.0 - specular.max_element())).extend(base.w);
            (metallic, roughness) = (0.0, 1.0 - glossiness);
            specular
        });
        let mut emissive = material.emissive * material.emissive_strength;
        if let Some(t) = sample(&material.emissive_texture, true) {
            emissive *= t.truncate();
        }
        let occlusion = match occlusion {
            Occlusion::Sample => match sample(&material.occlusion_texture, false) {
                // glTF 2.0 §3.9.3: occluded = 1 + strength · (sample - 1), from the R channel.
                Some(t) => 1.0 + material.occlusion_strength * (t.x - 1.0),
                None => 1.0,
            },
            Occlusion::Skip => 1.0,
        };
        if let (Some(r), Some(t)) = (
            &material.normal_texture,
            sample(&material.normal_texture, false),
        ) {
            normal = self.normal_mapped(tri, b, r, normal, geometric, t, material.normal_scale);
        }
        let normal = valid_reflection_normal(geometric, -direction, normal);
        let mut shaded = SurfaceMaterial::core(
            base.truncate(),
            metallic.clamp(0.0, 1.0),
            roughness.clamp(0.0, 1.0),
        );
        if material.anisotropy.is_some() || material.diffuse_transmission.is_some() {
            let view = (normal, -direction);
            self.add_lobes(material, &mut shaded, (tri, b, cone, cos), view, &last);
        }
        shaded.specular = material.specular;
        // KHR_materials_ior: the dielectric's F0 = ((ior - 1)/(ior + 1))²; 0.04 at ior 1.5 is
        // kept exactly (the core material's constant).
        let ior_f0 = if material.ior == 1.5 {
            0.04
        } else {
            ((material.ior - 1.0) / (material.ior + 1.0)).powi(2)
        };
        shaded.dielectric_f0 = Vec3::splat(ior_f0);
        self.add_layers(
            material,
            &mut shaded,
            ior_f0,
            &sample,
            (tri, b, smooth, geometric),
        );
        if let Some(specular) = specular_glossiness {
            shaded.dielectric_f0 = specular;
            shaded.specular_weight = 1.0;
            shaded.specular = Some(specular);
        }
        let mut transmission = material.transmission;
        if let Some(t) = sample(&material.transmission_texture, false) {
            transmission *= t.x;
        }
        // KHR_materials_volume: a thickness of 0 (factor × texture green) is a thin wall.
        let thin_walled = material.thin_walled
            || sample(&material.thickness_texture, false).is_some_and(|t| t.y <= 0.0);
        Surface {
            spawn,
            exit,
            corners,
            barycentric: b,
            geometric,
            smooth,
            normal,
            material: shaded,
            emissive,
            occlusion,
            alpha: if material.alpha_mode == AlphaMode::Opaque {
                1.0
            } else {
                base.w.clamp(0.0, 1.0)
            },
            transmission: transmission.clamp(0.0, 1.0),
            thin_walled,
            source: material,
        }
    }

    /// The factors `maps` put on the roughness, metalness and alpha, in that order, read
    /// through `sample` (1 where a map is absent or its image did not load).
    fn scalar_factors(
        &self,
        maps: &ScalarMaps,
        sample: &impl Fn(&Option<TextureRef>, bool) -> Option<Vec4>,
    ) -> [f32; 3] {
        let read = |r: &Option<TextureRef>, channel| {
            sample(r, false).map_or(1.0, |texel| {
                channel_of(texel, channel, || self.translucent(r))
            })
        };
        [
            read(&maps.roughness, maps.roughness_channel),
            read(&maps.metallic, maps.metallic_channel),
            read(&maps.alpha, maps.alpha_channel),
        ]
    }

    /// The extension layers of `material` on `shaded` (the core material with `ior_f0`, the
    /// dielectric's F0 from KHR_materials_ior): KHR_materials_specular, sheen, clearcoat (with
    /// its own normal map, else the interpolated normal `smooth`) and iridescence, their
    /// textures read through `sample` in a fixed order. `at` is the hit's triangle,
    /// barycentrics, interpolated normal and geometric normal.
    #[inline(always)]
    fn add_layers(
        &self,
        material: &Material,
        shaded: &mut SurfaceMaterial,
        ior_f0: f32,
        sample: &impl Fn(&Option<TextureRef>, bool) -> Option<Vec4>,
        (tri, b, smooth, geometric): (usize, Vec3, Vec3, Vec3),
    ) {
        if let Some(layer) = &material.specular_layer {
            // KHR_materials_specular: F0 = min(F0(ior)·colour, 1)·specular, F90 = specular.
            let mut color = layer.color;
            if let Some(t) = sample(&layer.color_texture, true) {
                color *= t.truncate();
            }
            let mut weight = layer.factor;
            if let Some(t) = sample(&layer.texture, false) {
                weight *= t.w;
            }
            shaded.dielectric_f0 = (ior_f0 * color).min(Vec3::ONE);
            shaded.specular_weight = weight.clamp(0.0, 1.0);
        }
        if let Some(layer) = &material.sheen {
            let mut color = layer.color;
            if let Some(t) = sample(&layer.color_texture, true) {
                color *= t.truncate();
            }
            let mut sheen_roughness = layer.roughness;
            if let Some(t) = sample(&layer.roughness_texture, false) {
                sheen_roughness *= t.w;
            }
            if color.max_element() > 0.0 {
                shaded.sheen = Some(Sheen {
                    color: color.min(Vec3::ONE),
                    roughness: sheen_roughness.clamp(0.0, 1.0),
                });
            }
        }
        if let Some(layer) = &material.clearcoat {
            let mut weight = layer.factor;
            if let Some(t) = sample(&layer.texture, false) {
                weight *= t.x;
            }
            let mut coat_roughness = layer.roughness;
            if let Some(t) = sample(&layer.roughness_texture, false) {
                coat_roughness *= t.y;
            }
            // The coat's own normal map, else the interpolated normal (not the base's map).
            let coat_normal = match (&layer.normal_texture, sample(&layer.normal_texture, false)) {
                (Some(r), Some(t)) => {
                    self.normal_mapped(tri, b, r, smooth, geometric, t, layer.normal_scale)
                }
                _ => smooth,
            };
            if weight > 0.0 {
                shaded.clearcoat = Some(Clearcoat {
                    weight: weight.clamp(0.0, 1.0),
                    roughness: coat_roughness.clamp(0.0, 1.0),
                    normal: coat_normal,
                });
            }
        }
        if let Some(layer) = &material.iridescence {
            let mut factor = layer.factor;
            if let Some(t) = sample(&layer.texture, false) {
                factor *= t.x;
            }
            // Without a thickness texture the film is at its maximum thickness.
            let thickness = match sample(&layer.thickness_texture, false) {
                Some(t) => layer.thickness_min + (layer.thickness_max - layer.thickness_min) * t.y,
                None => layer.thickness_max,
            };
            if factor > 0.0 {
                shaded.iridescence = Some(Iridescence {
                    factor: factor.clamp(0.0, 1.0),
                    ior: layer.ior,
                    thickness,
                });
            }
        }
    }

    /// Perturbs the shading normal by a tangent-space normal map (glTF 2.0 §3.9.3): n =
    /// normalize(T·x + B·y + N·z) with (x, y, z) = (2·rgb - 1)·(scale, scale, 1), B = (N × T)·w.
    /// Tangents come from the file's TANGENT, else from MikkTSpace at load
    /// ([`crate::scene::tangents`]), else (degenerate UVs) from the triangle's UV gradient.
    #[allow(clippy::too_many_arguments)]
    fn normal_mapped(
        &self,
        tri: usize,
        b: Vec3,
        r: &TextureRef,
        n: Vec3,
        geometric: Vec3,
        texel: Vec4,
        scale: f32,
    ) -> Vec3 {
        // A grey image is a height map, not directions (`TextureSet` warns of it).
        let height_map = self
            .textures
            .lookup(&self.scene, r)
            .is_some_and(|(image, _)| image.grey());
        let Some((t, bt)) = self
            .tangent_frame(tri, b, r.tex_coord, n)
            .filter(|_| !height_map)
        else {
            return n;
        };
        let m = Vec3::new(
            (2.0 * texel.x - 1.0) * scale,
            (2.0 * texel.y - 1.0) * scale,
            2.0 * texel.z - 1.0,
        );
        let mapped = (t * m.x + bt * m.y + n * m.z).try_normalize().unwrap_or(n);
        if mapped.dot(geometric) <= 0.0 {
            n
        } else {
            mapped
        }
    }

    /// The tangent frame at barycentrics `b` of triangle `tri` around the unit normal `n`: the
    /// unit tangent perpendicular to `n` and the bitangent (n × T)·w (glTF 2.0 §3.7.2.1).
    /// Tangents come from the file's TANGENT, else from MikkTSpace at load
    /// ([`crate::scene::tangents`]), else (degenerate UVs) from the triangle's gradient of
    /// texture coordinate set `tex_coord`; `None` without any.
    fn tangent_frame(&self, tri: usize, b: Vec3, tex_coord: u32, n: Vec3) -> Option<(Vec3, Vec3)> {
        let soup = &self.scene.soup;
        let from_file = soup.corner_tangents(tri).and_then(|[ta, tb, tc]| {
            let t = ta * b.x + tb * b.y + tc * b.z;
            (ta.w != 0.0).then(|| (t.truncate(), if ta.w < 0.0 { -1.0 } else { 1.0 }))
        });
        let frame = from_file.or_else(|| {
            let [ua, ub, uc] = soup.corner_uvs(tex_coord, tri)?;
            let [pa, pb, pc] = soup.triangle(tri);
            let (e1, e2) = (pb - pa, pc - pa);
            let (d1, d2) = (ub - ua, uc - ua);
            let det = d1.x * d2.y - d2.x * d1.y;
            if det.abs() < 1e-20 {
                return None;
            }
            let tangent = (e1 * d2.y - e2 * d1.y) / det;
            let bitangent = (e2 * d1.x - e1 * d2.x) / det;
            // glTF UVs have v down, so the bitangent points along -v in texture terms.
            let w = if n.cross(tangent).dot(bitangent) < 0.0 {
                1.0
            } else {
                -1.0
            };
            Some((tangent, w))
        });
        let (tangent, w) = frame?;
        let t = (tangent - n * n.dot(tangent)).try_normalize()?;
        Some((t, n.cross(t) * w))
    }

    /// The lobes that `KHR_materials_anisotropy` and `KHR_materials_diffuse_transmission` add
    /// to `shaded` (the core material at the point) at the hit `at` (triangle, barycentrics,
    /// ray cone width and cosine) with shading normal `normal`, seen from `to_eye`: a stretched
    /// lobe, whose mean roughness then stands for it where the lobe is taken as isotropic, with
    /// its own albedo at the view for its multiple scattering, and the lobe through the wall. Out of line: code no other material runs, inlined into
    /// [`Prepared::surface`], cost every path vertex about 1% more instructions.
    #[inline(never)]
    fn add_lobes(
        &self,
        material: &Material,
        shaded: &mut SurfaceMaterial,
        at: (usize, Vec3, f32, f32),
        (normal, to_eye): (Vec3, Vec3),
        last: &Cell<Option<TexelFootprint>>,
    ) {
        if let Some(layer) = material.anisotropy.as_ref().filter(|l| l.is_active()) {
            shaded.anisotropy =
                self.anisotropy_at(material, layer, at, normal, shaded.roughness, last);
            if let Some(a) = shaded.anisotropy {
                shaded.roughness = a.mean_roughness();
                shaded.anisotropy = Some(a.seen_from(normal, to_eye));
            }
        }
        if let Some(layer) = material
            .diffuse_transmission
            .as_ref()
            .filter(|l| l.factor > 0.0)
        {
            shaded.diffuse_transmission = self.diffuse_transmission_at(layer, at, last);
        }
    }

    /// `KHR_materials_diffuse_transmission` (`layer`) at barycentrics `b` of triangle `tri`,
    /// its textures read as [`Prepared::sample`] reads them (`cone`, `cos`, `last`): weight =
    /// factor × texture alpha, colour = colour factor × texture (sRGB); `None` where the weight
    /// is 0.
    fn diffuse_transmission_at(
        &self,
        layer: &DiffuseTransmissionLayer,
        (tri, b, cone, cos): (usize, Vec3, f32, f32),
        last: &Cell<Option<TexelFootprint>>,
    ) -> Option<DiffuseTransmission> {
        let sample = |r: &Option<TextureRef>, srgb: bool| {
            r.as_ref()
                .and_then(|r| self.sample(r, tri, b, cone, cos, srgb, last))
        };
        let weight = layer.factor * sample(&layer.texture, false).map_or(1.0, |t| t.w);
        let color =
            layer.color * sample(&layer.color_texture, true).map_or(Vec3::ONE, |t| t.truncate());
        (weight > 0.0).then_some(DiffuseTransmission {
            weight: weight.clamp(0.0, 1.0),
            color: color.clamp(Vec3::ZERO, Vec3::ONE),
        })
    }

    /// `KHR_materials_anisotropy` (`layer` of `material`) at barycentrics `b` of triangle
    /// `tri` with shading normal `normal` and perceptual `roughness`, its texture read as
    /// [`Prepared::sample`] reads one (`cone`, `cos`, `last`): the direction (rotation × the
    /// texture's red-green vector, else the rotation alone) taken from tangent space, the
    /// strength factor × blue. `None` where the lobe stays isotropic: strength 0, a zero
    /// direction, or no tangent frame (no TANGENT and no texture coordinates, which the
    /// extension requires).
    fn anisotropy_at(
        &self,
        material: &Material,
        layer: &AnisotropyLayer,
        (tri, b, cone, cos): (usize, Vec3, f32, f32),
        normal: Vec3,
        roughness: f32,
        last: &Cell<Option<TexelFootprint>>,
    ) -> Option<Anisotropy> {
        let texel = layer
            .texture
            .as_ref()
            .and_then(|r| self.sample(r, tri, b, cone, cos, false, last));
        // The tangent frame follows the normal map's coordinates, as at load.
        let tex_coord = material
            .normal_texture
            .or(layer.texture)
            .map_or(0, |r| r.tex_coord);
        let (sin_r, cos_r) = layer.rotation.sin_cos();
        let (direction, strength) = match texel {
            Some(t) => {
                let d = (Vec2::new(t.x, t.y) * 2.0 - 1.0).try_normalize()?;
                let rotated = Vec2::new(cos_r * d.x - sin_r * d.y, sin_r * d.x + cos_r * d.y);
                (rotated, layer.strength * t.z)
            }
            None => (Vec2::new(cos_r, sin_r), layer.strength),
        };
        let (t, bt) = self.tangent_frame(tri, b, tex_coord, normal)?;
        Anisotropy::new(
            normal,
            t * direction.x + bt * direction.y,
            roughness,
            strength,
        )
    }
}

/// Where one texture is read at a hit: its coordinates and mip level of detail, with what
/// they depend on besides the hit (coordinate set, transform, image size).
#[derive(Clone, Copy, Debug)]
struct TexelFootprint {
    tex_coord: u32,
    transform: Option<TextureTransform>,
    size: (u32, u32),
    uv: Vec2,
    lod: f32,
}

impl TexelFootprint {
    /// Whether texture reference `r` of an image of `size` texels is read here too: the same
    /// coordinate set, the same transform bit for bit, the same size.
    fn serves(&self, r: &TextureRef, size: (u32, u32)) -> bool {
        let bits = |t: &Option<TextureTransform>| {
            t.map(|t| {
                [
                    t.offset[0].to_bits(),
                    t.offset[1].to_bits(),
                    t.rotation.to_bits(),
                    t.scale[0].to_bits(),
                    t.scale[1].to_bits(),
                ]
            })
        };
        self.tex_coord == r.tex_coord
            && self.size == size
            && bits(&self.transform) == bits(&r.transform)
    }
}

/// Below this cosine between the light and the facet normal, shadow rays start from the
/// terminator-lifted point (fading in from here to 0).
pub const TERMINATOR_BAND: f32 = 0.1;

/// The shadow-terminator offset of Hanika, "Hacking the shadow terminator" (Ray Tracing Gems
/// II, ch. 4, 2021). A smooth-shaded mesh is flat between its vertices, so near the terminator
/// a shadow ray leaving the flat facet is blocked by the neighbouring facets (or the facet
/// itself) although the shading normal says the point is lit: the terminator turns into a
/// staircase along the tessellation. Project `point` onto the tangent plane of each vertex
/// (the plane through the vertex, normal to its shading normal) when it lies below it, and
/// blend the three projections with the barycentric weights: the result lies on a smooth
/// surface through the vertices, above the facets that caused the staircase. Flat triangles
/// (vertex normals equal to the face normal) are not moved. Returns the offset from `point`.
/// `normals` must face the side the ray arrived from.
pub fn terminator_lift(point: Vec3, vertices: [Vec3; 3], normals: [Vec3; 3], b: Vec3) -> Vec3 {
    let below = |i: usize| (point - vertices[i]).dot(normals[i]).min(0.0) * normals[i];
    -(below(0) * b.x + below(1) * b.y + below(2) * b.z)
}

/// The shading normal `n` raised toward the geometric normal `ng` just enough that the mirror
/// reflection of the direction to the eye `i` leaves the surface (by at least min(0.9·i·ng,
/// 0.01) in cosine): Cycles' `ensure_valid_specular_reflection` (Blender's "bump map
/// correction", on by default), which its Principled BSDF applies to every lobe. Interpolated
/// and normal-mapped normals tilt away from the eye near silhouettes; uncorrected, such a point
/// is seen from below its shading normal and reflects nothing (black rims on smooth meshes:
/// Suzanne's silhouette pixels were 18% darker than Cycles'). `n` is returned unchanged when
/// its reflection is already valid. `ng` faces the eye (i·ng >= 0); all three are unit vectors.
///
/// In the plane of `ng` and `n` (x along n's part across ng), the n' = (√(1 - z²), z) whose
/// reflection has ng-component t solves 4a·z⁴ - 2b·z² + c = 0 with a = i_x² + i_z²,
/// b = 2(a + i_z·t), c = (i_z + t)²; the root that also solves the unsquared equation is
/// taken by the sign of i_x.
pub(crate) fn valid_reflection_normal(ng: Vec3, i: Vec3, n: Vec3) -> Vec3 {
    let reflected = 2.0 * n.dot(i) * n - i;
    let iz = i.dot(ng).max(0.0);
    let threshold = (0.9 * iz).min(0.01);
    if ng.dot(reflected) >= threshold {
        return n;
    }
    let x = (n - n.dot(ng) * ng).try_normalize().unwrap_or(n);
    let ix = i.dot(x);
    let a = ix * ix + iz * iz;
    if a <= 0.0 {
        return n;
    }
    let b = 2.0 * (a + iz * threshold);
    let c = (threshold + iz) * (threshold + iz);
    let root = (b * b - 4.0 * a * c).max(0.0).sqrt();
    let nz2 = if ix < 0.0 {
        0.25 * (b + root) / a
    } else {
        0.25 * (b - root) / a
    };
    let (nx, nz) = ((1.0 - nz2).max(0.0).sqrt(), nz2.max(0.0).sqrt());
    (nx * x + nz * ng).normalize_or(n)
}

/// The spawn point at barycentrics `b` of the triangle with corners `corners`, with its unit
/// normal. The importer drops degenerate triangles, so [`SpawnPoint::on_triangle`] always
/// succeeds; the fallback keeps a bad triangle from panicking (its shadow rays start at the
/// interpolated point, and its normal is zero).
#[inline(always)]
fn spawn_and_facet([pa, pb, pc]: [Vec3; 3], b: Vec3) -> (SpawnPoint, Vec3) {
    match SpawnPoint::on_triangle([pa, pb, pc], b) {
        Some(spawn) => (spawn, spawn.normal),
        None => (
            SpawnPoint {
                point: pa * b.x + pb * b.y + pc * b.z,
                error: Vec3::ZERO,
                normal: Vec3::Z,
            },
            Vec3::ZERO,
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::{terminator_lift, valid_reflection_normal};
    use glam::{vec3, Vec3};

    /// A normal whose mirror reflection of the eye direction dips below the surface is raised
    /// toward the geometric normal, in their plane, until the reflection clears the surface by
    /// Cycles' threshold (to 2e-3 in cosine); a valid one is left alone.
    #[test]
    fn shading_normals_are_raised_until_the_reflection_leaves_the_surface() {
        use crate::sampling::Rng;
        let ng = Vec3::Z;
        let mut rng = Rng::new(5);
        let mut raised = 0;
        for _ in 0..10_000 {
            let (u, v, w, s) = (
                rng.next_f32(),
                rng.next_f32(),
                rng.next_f32(),
                rng.next_f32(),
            );
            // Eye directions over the upper hemisphere, grazing ones included.
            let phi = std::f32::consts::TAU * u;
            let iz = v.max(1e-3);
            let r = (1.0 - iz * iz).sqrt();
            let i = Vec3::new(r * phi.cos(), r * phi.sin(), iz);
            // Shading normals tilted up to 80 degrees from ng.
            let (tilt, psi) = (1.4 * w, std::f32::consts::TAU * s);
            let n = Vec3::new(tilt.sin() * psi.cos(), tilt.sin() * psi.sin(), tilt.cos());
            let corrected = valid_reflection_normal(ng, i, n);
            assert!((corrected.length() - 1.0).abs() < 1e-4);
            let reflected = 2.0 * corrected.dot(i) * corrected - i;
            let threshold = (0.9 * iz).min(0.01);
            assert!(
                ng.dot(reflected) >= threshold - 2e-3,
                "i {i} n {n}: reflection {reflected} below the threshold {threshold}"
            );
            assert!(
                corrected.dot(i) > 0.0,
                "the eye is above the corrected normal"
            );
            if (2.0 * n.dot(i) * n - i).dot(ng) >= threshold {
                assert_eq!(corrected, n, "a valid normal is kept");
            } else {
                raised += 1;
                assert!(corrected.dot(ng) > n.dot(ng), "raised toward ng");
                // In the plane of n and ng: no component along their common perpendicular.
                let across = n.cross(ng).normalize();
                assert!(corrected.dot(across).abs() < 1e-3);
            }
        }
        assert!(raised > 1000, "the grazing cases were exercised ({raised})");
    }

    #[test]
    fn terminator_lift_leaves_flat_triangles_alone() {
        let vertices = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let b = vec3(0.2, 0.3, 0.5);
        let point = vertices[0] * b.x + vertices[1] * b.y + vertices[2] * b.z;
        assert_eq!(
            terminator_lift(point, vertices, [Vec3::Z; 3], b),
            Vec3::ZERO
        );
    }

    /// A facet of a unit sphere with vertex normals pointing out of the sphere: the lifted
    /// centroid lies outside the facet, most of the way to the sphere, and not beyond it.
    #[test]
    fn terminator_lift_moves_toward_the_smooth_surface() {
        let vertices = [
            vec3(1.0, 0.0, 0.0),
            vec3(0.0, 1.0, 0.0),
            vec3(0.0, 0.0, 1.0),
        ];
        let b = Vec3::splat(1.0 / 3.0);
        let point = (vertices[0] + vertices[1] + vertices[2]) / 3.0;
        let lifted = point + terminator_lift(point, vertices, vertices, b);
        let (before, after) = (point.length(), lifted.length());
        assert!((before - 0.577).abs() < 1e-3, "{before}");
        assert!(
            after > before + 0.5 * (1.0 - before) && after <= 1.0 + 1e-6,
            "|lifted| = {after}"
        );
    }
}
