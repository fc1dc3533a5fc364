//! Questions asked of a prepared scene at a point, without a ray cone: what a camera ray sees
//! (MASK cut-outs skipped), what a shadow ray lets through (BLEND and see-through sheets
//! attenuate it), the emission, alpha and straight transmittance at a point of a triangle
//! (textures at full resolution). Traversal filters, light sampling and the surface evaluation
//! ([`crate::shading::surface`]) all ask these.

use crate::accel::Hit;
use crate::geometry::Ray;
use crate::prepare::textures::transform_uv;
use crate::prepare::Prepared;
use crate::scene::{AlphaMode, Channel, Material, TextureRef};
use glam::{Vec2, Vec3, Vec4};
use std::cell::Cell;

impl Prepared {
    /// Emitted radiance at barycentrics `b` of soup triangle `tri` (emissive factor × strength
    /// × the emissive texture at full resolution), for either face.
    pub fn emission_at(&self, tri: usize, b: Vec3) -> Vec3 {
        let material = &self.scene.materials[self.scene.soup.material[tri] as usize];
        let mut emission = material.emissive * material.emissive_strength;
        if let Some(t) = self.texel_at(&material.emissive_texture, tri, b, true) {
            emission *= t.truncate();
        }
        emission
    }

    /// Texture `r` (if the material has it and its image loaded) at barycentrics `b` of soup
    /// triangle `tri`, at full resolution: for queries without a ray cone (inside traversal, on
    /// a light), where a mip level cannot be chosen.
    pub(crate) fn texel_at(
        &self,
        r: &Option<TextureRef>,
        tri: usize,
        b: Vec3,
        srgb: bool,
    ) -> Option<Vec4> {
        let r = r.as_ref()?;
        let (image, sampler) = self.textures.lookup(&self.scene, r)?;
        let uv = transform_uv(r, self.uv(tri, r.tex_coord, b));
        Some(image.sample(uv, 0.0, sampler, srgb))
    }

    /// Channel `channel` of texture `r` (a [`crate::scene::ScalarMaps`] map) at barycentrics
    /// `b` of soup triangle `tri`, at full resolution, as [`Prepared::texel_at`] reads it.
    pub(crate) fn scalar_at(
        &self,
        r: &Option<TextureRef>,
        channel: Channel,
        tri: usize,
        b: Vec3,
    ) -> Option<f32> {
        let texel = self.texel_at(r, tri, b, false)?;
        Some(channel_of(texel, channel, || self.translucent(r)))
    }

    /// Whether the image behind texture `r` has any transparency (false without one).
    pub(crate) fn translucent(&self, r: &Option<TextureRef>) -> bool {
        r.as_ref()
            .and_then(|r| self.textures.lookup(&self.scene, r))
            .is_some_and(|(image, _)| image.translucent())
    }

    /// What a see-through sheet made of `material` lets straight through at barycentrics `b`
    /// of soup triangle `tri` ([`Material::straight_transmittance`]), with the inputs camera
    /// rays read there ([`Prepared::surface`]): base colour factor × vertex colour × base
    /// colour texture, transmissionFactor × transmission texture red, metallicFactor ×
    /// metallic-roughness texture blue. Textures at full resolution (shadow rays carry no ray
    /// cone); without textures and vertex colours, the factors bit for bit.
    pub fn straight_transmittance_at(&self, material: &Material, tri: usize, b: Vec3) -> Vec3 {
        let mut base = material.base_color;
        if let Some([ca, cb, cc]) = self.scene.soup.corner_colors(tri) {
            base *= ca * b.x + cb * b.y + cc * b.z;
        }
        if let Some(t) = self.texel_at(&material.base_color_texture, tri, b, true) {
            base *= t;
        }
        let transmission = match self.texel_at(&material.transmission_texture, tri, b, false) {
            Some(t) => (material.transmission * t.x).clamp(0.0, 1.0),
            None => material.transmission,
        };
        let mut metallic = material.metallic;
        if let Some(t) = self.texel_at(&material.metallic_roughness_texture, tri, b, false) {
            // glTF 2.0 §3.9.2: metalness in B.
            metallic *= t.z;
        }
        if let Some(m) = &material.scalar_maps {
            metallic *= self
                .scalar_at(&m.metallic, m.metallic_channel, tri, b)
                .unwrap_or(1.0);
        }
        let metallic = metallic.clamp(0.0, 1.0);
        material.straight_transmittance(base.truncate(), transmission, metallic)
    }

    /// Whether soup triangle `tri` made of `material` is a thin wall at barycentrics `b`:
    /// everywhere for a [`Material::thin_walled`] material, else where
    /// `KHR_materials_volume`'s thickness (factor × texture green) is 0, read as
    /// [`Prepared::surface`] reads it but at full resolution (shadow rays carry no ray cone).
    pub fn thin_walled_at(&self, material: &Material, tri: usize, b: Vec3) -> bool {
        material.thin_walled
            || self
                .texel_at(&material.thickness_texture, tri, b, false)
                .is_some_and(|t| t.y <= 0.0)
    }

    /// The closest surface a camera ray sees: MASK cut-outs are skipped, BLEND surfaces count.
    pub fn intersect_camera(&self, ray: &Ray) -> Option<Hit> {
        if self.any_alpha() {
            let accept = |tri: u32, b: Vec3| self.accept_for_camera(tri, b);
            self.accel.intersect_filtered(ray, Some(&accept))
        } else {
            self.accel.intersect(ray)
        }
    }

    /// [`Prepared::intersect_camera`] of each ray of `rays`, into `hits` (as many as both
    /// hold): the same answers, found for eight consecutive rays at a time in one walk of the
    /// BVH ([`crate::accel::Accel::intersect_many`]). For camera rays of neighbouring pixels,
    /// which mostly enter the same nodes.
    pub fn intersect_camera_many(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        if self.any_alpha() {
            let accept = |tri: u32, b: Vec3| self.accept_for_camera(tri, b);
            self.accel.intersect_many(rays, Some(&accept), hits);
        } else {
            self.accel.intersect_many(rays, None, hits);
        }
    }

    /// Alpha of a MASK or BLEND surface at a candidate hit: base colour factor × texture ×
    /// vertex colour (the texture at full resolution: this runs inside traversal).
    pub fn alpha_at(&self, triangle: u32, barycentric: Vec3) -> f32 {
        let soup = &self.scene.soup;
        let tri = triangle as usize;
        let Some(material) = self.scene.materials.get(soup.material[tri] as usize) else {
            return 1.0;
        };
        let mut alpha = material.base_color.w;
        if let Some([a, b, c]) = soup.corner_colors(tri) {
            alpha *= a.w * barycentric.x + b.w * barycentric.y + c.w * barycentric.z;
        }
        if let Some(t) = self.texel_at(&material.base_color_texture, tri, barycentric, false) {
            alpha *= t.w;
        }
        if let Some(m) = &material.scalar_maps {
            alpha *= self
                .scalar_at(&m.alpha, m.alpha_channel, tri, barycentric)
                .unwrap_or(1.0);
        }
        alpha
    }

    /// MASK surfaces exist where alpha reaches the cutoff; BLEND surfaces are always hit by
    /// eye rays (and composited).
    pub fn accept_for_camera(&self, triangle: u32, barycentric: Vec3) -> bool {
        // In range: Scene::check_references ran at load.
        let material = &self.scene.materials[self.scene.soup.material[triangle as usize] as usize];
        material.alpha_mode != AlphaMode::Mask
            || self.alpha_at(triangle, barycentric) >= material.alpha_cutoff
    }

    pub(crate) fn uv(&self, tri: usize, set: u32, b: Vec3) -> Vec2 {
        match self.scene.soup.corner_uvs(set, tri) {
            Some([ua, ub, uc]) => ua * b.x + ub * b.y + uc * b.z,
            None => Vec2::ZERO,
        }
    }

    /// [`Prepared::shadow_transmittance`] of each ray of `rays`, into `out` (as many as both
    /// hold): the same answers. The rays go eight at a time through one walk of the BVH
    /// ([`crate::accel::Accel::occluded_many`]), which pays where they enter the same nodes:
    /// shadow rays from neighbouring pixels' surfaces toward one light.
    ///
    /// With alpha-tested surfaces in the scene the packet looks for opaque blockers alone (an
    /// alpha-tested triangle never blocks there): a ray that meets one gets 0, as the exact
    /// query gives it whatever it crossed before. If no ray of the packet met an alpha-tested
    /// triangle, the others are clear (1); otherwise they take the exact query one by one.
    pub fn shadow_transmittance_many(&self, rays: &[Ray], out: &mut [f32]) {
        let crossed = Cell::new(false);
        let opaque_only = |_: u32, _: Vec3| {
            crossed.set(true);
            false
        };
        let accept: Option<&crate::accel::Accept> = self.any_alpha().then_some(&opaque_only);
        let mut blocked = [false; crate::accel::PACKET];
        for (rays, out) in rays
            .chunks(crate::accel::PACKET)
            .zip(out.chunks_mut(crate::accel::PACKET))
        {
            let blocked = &mut blocked[..rays.len()];
            crossed.set(false);
            self.accel.occluded_many(rays, accept, blocked);
            for ((ray, out), &blocked) in rays.iter().zip(out.iter_mut()).zip(blocked.iter()) {
                *out = match (blocked, crossed.get()) {
                    (true, _) => 0.0,
                    (false, false) => 1.0,
                    (false, true) => self.shadow_transmittance(ray),
                };
            }
        }
    }

    /// 1 for an unblocked shadow ray, 0 for a blocked one, otherwise the product over what it
    /// passes: (1 - alpha) for each BLEND surface, and for each see-through sheet
    /// ([`Material::see_through`]) the luminance of its straight transmittance at the point
    /// crossed, with the textures read there as camera rays read them (so a sheet's opaque
    /// texels cast full shadows). Both integrators' shadow rays (punctual lights, area and
    /// environment light samples) ask this.
    pub fn shadow_transmittance(&self, shadow: &Ray) -> f32 {
        if !self.any_alpha() {
            return if self.accel.occluded(shadow) {
                0.0
            } else {
                1.0
            };
        }
        let transmittance = Cell::new(1.0f32);
        // The attenuating crossings counted so far (triangle, distance along the ray).
        let crossed = Cell::new([None::<(u32, f32)>; 4]);
        let accept = |tri: u32, b: Vec3| {
            // In range: Scene::check_references ran at load.
            let material = &self.scene.materials[self.scene.soup.material[tri as usize] as usize];
            let attenuates = material.alpha_mode == AlphaMode::Blend
                || (material.see_through()
                    && !(material.alpha_mode == AlphaMode::Mask
                        && self.alpha_at(tri, b) < material.alpha_cutoff));
            if attenuates && self.crossed_before(shadow, tri, b, &crossed) {
                return false;
            }
            match material.alpha_mode {
                AlphaMode::Mask if self.alpha_at(tri, b) < material.alpha_cutoff => false,
                AlphaMode::Blend => {
                    let alpha = self.alpha_at(tri, b).clamp(0.0, 1.0);
                    transmittance.set(transmittance.get() * (1.0 - alpha));
                    transmittance.get() < 1e-3
                }
                // Where a MASK surface is there, it is what an OPAQUE one is (camera rays
                // shade it so): a see-through sheet lets shadow rays through too.
                AlphaMode::Opaque | AlphaMode::Mask if material.see_through() => {
                    // A volume boundary here (its thickness texture is not 0): it bends light,
                    // so it blocks, as a volume without the texture does.
                    if !self.thin_walled_at(material, tri as usize, b) {
                        return true;
                    }
                    // Luminance of the straight-through share at this point (textures read):
                    // a scalar attenuation (the tint is lost in shadows; the camera sees it).
                    let through = self.straight_transmittance_at(material, tri as usize, b);
                    let pass = crate::color::luminance(through);
                    transmittance.set(transmittance.get() * pass.clamp(0.0, 1.0));
                    transmittance.get() < 1e-3
                }
                AlphaMode::Opaque | AlphaMode::Mask => true,
            }
        };
        if self.accel.occluded_filtered(shadow, Some(&accept)) {
            0.0
        } else {
            transmittance.get()
        }
    }

    /// Whether a shadow ray's crossing of soup triangle `tri` at barycentrics `b` is one it
    /// has already counted, and if not, records it in `seen`. Two triangles sharing an edge
    /// overlap by the triangle test's tolerance along it (what keeps meshes watertight), so a
    /// ray through that edge of a glass or BLEND sheet met both and was attenuated twice
    /// (0.19 instead of 0.43 along a pane's diagonal). The same crossing is another triangle
    /// of the same material with a vertex at the same position, met at the same distance along
    /// the ray to within a thousandth of the triangle's size.
    fn crossed_before(
        &self,
        shadow: &Ray,
        tri: u32,
        b: Vec3,
        seen: &Cell<[Option<(u32, f32)>; 4]>,
    ) -> bool {
        let soup = &self.scene.soup;
        let corners = soup.triangle(tri as usize);
        let point = corners[0] * b.x + corners[1] * b.y + corners[2] * b.z;
        let direction = Vec3::from(shadow.direction);
        let distance = (point - Vec3::from(shadow.origin)).dot(direction) / direction.length();
        let size = (corners[1] - corners[0])
            .length()
            .max((corners[2] - corners[1]).length())
            .max((corners[0] - corners[2]).length());
        let mut list = seen.get();
        let same = list.iter().flatten().any(|&(other, d)| {
            soup.material[other as usize] == soup.material[tri as usize]
                && (d - distance).abs() <= 1e-3 * size
                && soup
                    .triangle(other as usize)
                    .iter()
                    .any(|v| corners.contains(v))
        });
        if !same {
            if let Some(slot) = list.iter_mut().find(|s| s.is_none()) {
                *slot = Some((tri, distance));
                seen.set(list);
            }
        }
        same
    }
}

/// Channel `channel` of a texel of stored (not sRGB-decoded) values; `translucent` tells
/// whether its image has any transparency, which [`Channel::AlphaOrLuminance`] asks (only
/// that channel calls it: the answer is found by a pass over the image the first time).
#[inline]
pub(crate) fn channel_of(texel: Vec4, channel: Channel, translucent: impl FnOnce() -> bool) -> f32 {
    match channel {
        Channel::Red => texel.x,
        Channel::Green => texel.y,
        Channel::Blue => texel.z,
        Channel::Alpha => texel.w,
        Channel::Luminance => crate::color::luminance(texel.truncate()),
        Channel::AlphaOrLuminance if translucent() => texel.w,
        Channel::AlphaOrLuminance => crate::color::luminance(texel.truncate()),
    }
}
