//! The one material description for every format (glTF 2.0 metallic-roughness with its
//! extension layers), the texture references it holds, and how materials draw without an
//! image that cannot be used.

use super::error::LoadErrorKind;
use super::texture::Texture;
use glam::{Vec3, Vec4};
use serde::Serialize;

/// How a material treats alpha (glTF 2.0 §3.9.4).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "UPPERCASE")]
pub enum AlphaMode {
    /// Alpha is ignored.
    Opaque,
    /// Alpha below the cutoff is fully transparent, otherwise opaque.
    Mask,
    /// Alpha blends with what is behind.
    Blend,
}

/// A reference from a material to a texture.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TextureRef {
    /// Index into [`Scene::textures`](super::model::Scene::textures).
    pub texture: usize,
    /// Which texture coordinate set (0 or 1) it reads.
    pub tex_coord: u32,
    /// `KHR_texture_transform`, if present.
    pub transform: Option<TextureTransform>,
}

/// `KHR_texture_transform`: uv' = T(offset) · R(rotation) · S(scale) · uv.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TextureTransform {
    /// Translation in uv units.
    pub offset: [f32; 2],
    /// Counter-clockwise rotation in radians.
    pub rotation: f32,
    /// Per-axis scale.
    pub scale: [f32; 2],
}

/// One material description for every format: the glTF 2.0 metallic-roughness model (§3.9.2).
/// OBJ/MTL materials are mapped onto it by the OBJ importer.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Material {
    /// Name from the file, if any.
    pub name: Option<String>,
    /// Linear RGBA base colour factor.
    pub base_color: Vec4,
    /// Base colour texture (sRGB encoded).
    pub base_color_texture: Option<TextureRef>,
    /// Metalness in [0, 1].
    pub metallic: f32,
    /// Perceptual roughness in [0, 1].
    pub roughness: f32,
    /// Metallic (B) and roughness (G) texture, linear.
    pub metallic_roughness_texture: Option<TextureRef>,
    /// Tangent-space normal map.
    pub normal_texture: Option<TextureRef>,
    /// Normal map scale.
    pub normal_scale: f32,
    /// Ambient occlusion texture (R channel).
    pub occlusion_texture: Option<TextureRef>,
    /// Occlusion strength.
    pub occlusion_strength: f32,
    /// Linear emissive colour factor.
    pub emissive: Vec3,
    /// `KHR_materials_emissive_strength` multiplier (1 when absent).
    pub emissive_strength: f32,
    /// Emissive texture (sRGB encoded).
    pub emissive_texture: Option<TextureRef>,
    /// Alpha handling.
    pub alpha_mode: AlphaMode,
    /// Cutoff for [`AlphaMode::Mask`].
    pub alpha_cutoff: f32,
    /// When false the back face is invisible (glTF 2.0 §3.9.6), except on a volume boundary
    /// ([`Material::culls_back_faces`]).
    pub double_sided: bool,
    /// Classic Phong specular colour, when the source had one (OBJ `Ks`); the Blinn-Phong
    /// shader otherwise derives it from metallic/roughness.
    pub specular: Option<Vec3>,
    /// `KHR_materials_transmission` factor: the share of the dielectric base that transmits
    /// light instead of scattering it diffusely (0 = opaque; OBJ `illum` 4, 6, 7: 1).
    pub transmission: f32,
    /// `KHR_materials_transmission`'s `transmissionTexture` (red channel), times the factor.
    pub transmission_texture: Option<TextureRef>,
    /// Index of refraction (`KHR_materials_ior`, OBJ `Ni`; 1.5 when absent).
    pub ior: f32,
    /// True without `KHR_materials_volume` (or with `thicknessFactor` 0): the surface is an
    /// infinitely thin sheet everywhere, so light passes straight through it; false: the mesh
    /// bounds a refracting volume, except where [`Material::thickness_texture`] reads 0.
    pub thin_walled: bool,
    /// `KHR_materials_volume`'s `thicknessTexture` (green channel, times `thicknessFactor`):
    /// where it reads 0 the surface is thin-walled (the extension's switch). A path tracer
    /// measures the path lengths in the geometry, so only that switch matters, not the
    /// thickness itself. `None` when the factor is 0 (thin-walled everywhere anyway).
    pub thickness_texture: Option<TextureRef>,
    /// `KHR_materials_volume` Beer-Lambert attenuation: colour light reaches after
    /// `attenuation_distance` inside the volume (white and infinite: none).
    pub attenuation_color: Vec3,
    /// Distance at which light inside the volume is reduced to `attenuation_color`.
    pub attenuation_distance: f32,
    /// `KHR_materials_dispersion`: 20 / the Abbe number V_d (0, the default: none). The
    /// index of refraction then varies over the spectrum; the path tracer refracts each colour
    /// channel by its own index where a path enters or leaves a volume
    /// ([`crate::shading::bsdf::Bsdf::with_dispersion`]).
    pub dispersion: f32,
    /// `KHR_materials_unlit`: the surface shows its base colour as radiance, unlit (scanned or
    /// baked-lighting models).
    pub unlit: bool,
    /// `KHR_materials_specular` (absent: the core material's specular reflection).
    pub specular_layer: Option<SpecularLayer>,
    /// `KHR_materials_sheen` (absent or black: no sheen).
    pub sheen: Option<SheenLayer>,
    /// `KHR_materials_clearcoat` (absent or weight 0: no coat).
    pub clearcoat: Option<ClearcoatLayer>,
    /// `KHR_materials_iridescence` (absent or factor 0: none).
    pub iridescence: Option<IridescenceLayer>,
    /// `KHR_materials_pbrSpecularGlossiness` (archived, still common in older downloads): when
    /// present it defines the BRDF inputs in place of metallic and roughness.
    pub specular_glossiness: Option<SpecularGlossiness>,
    /// `KHR_materials_anisotropy` (absent or strength 0: an isotropic specular lobe).
    pub anisotropy: Option<AnisotropyLayer>,
    /// `KHR_materials_diffuse_transmission` (absent or factor 0: the diffuse base reflects
    /// only).
    pub diffuse_transmission: Option<DiffuseTransmissionLayer>,
    /// Alpha, roughness and metalness each from one channel of an image of its own (MTL's
    /// `map_d`, `map_Pr`, `map_Pm`), where glTF packs them into the base colour and
    /// metallic-roughness textures.
    pub scalar_maps: Option<ScalarMaps>,
}

/// Textures whose one channel scales one number of the material (linear data, times the
/// factor): the form OBJ's MTL gives them, one grey image a property.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ScalarMaps {
    /// Scales the alpha (MTL `map_d`).
    pub alpha: Option<TextureRef>,
    /// The channel `alpha` is read from.
    pub alpha_channel: Channel,
    /// Scales the roughness (MTL `map_Pr`).
    pub roughness: Option<TextureRef>,
    /// The channel `roughness` is read from.
    pub roughness_channel: Channel,
    /// Scales the metalness (MTL `map_Pm`).
    pub metallic: Option<TextureRef>,
    /// The channel `metallic` is read from.
    pub metallic_channel: Channel,
}

/// Which channel of a texel a [`ScalarMaps`] texture gives (MTL's `-imfchan`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Channel {
    /// Red (`-imfchan r`).
    Red,
    /// Green (`-imfchan g`).
    Green,
    /// Blue (`-imfchan b`).
    Blue,
    /// Alpha, MTL's "matte" (`-imfchan m`).
    Alpha,
    /// Rec. 709 luminance of the stored values (`-imfchan l`, the MTL specification's default
    /// for scalar textures).
    #[default]
    Luminance,
    /// Alpha where the image has any transparency, else luminance: `map_d`'s default. A mask
    /// is a grey image (the specification's luminance) or, from Blender's exporter and many
    /// others, the colour texture's own alpha channel (Blender's importer reads alpha only,
    /// so a grey mask leaves its surfaces opaque there).
    AlphaOrLuminance,
}

/// `KHR_materials_diffuse_transmission`: a Lambertian BTDF that takes the share `factor` of
/// the diffuse base (leaves, paper, lamp shades): base = mix(diffuse BRDF of the base colour,
/// diffuse BTDF of `color`, factor), under the specular layer's Fresnel as before.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DiffuseTransmissionLayer {
    /// `diffuseTransmissionFactor` in [0, 1].
    pub factor: f32,
    /// `diffuseTransmissionTexture` (alpha channel), times the factor.
    pub texture: Option<TextureRef>,
    /// `diffuseTransmissionColorFactor` (linear).
    pub color: Vec3,
    /// `diffuseTransmissionColorTexture` (sRGB RGB), times the colour factor.
    pub color_texture: Option<TextureRef>,
}

/// `KHR_materials_anisotropy`: the specular lobe stretched along a direction in the tangent
/// plane (brushed metal). Along that direction GGX's α is mix(α, 1, strength²), across it the
/// material's α = roughness².
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AnisotropyLayer {
    /// `anisotropyStrength` in [0, 1].
    pub strength: f32,
    /// `anisotropyRotation`: radians counter-clockwise from the tangent, toward the bitangent.
    pub rotation: f32,
    /// `anisotropyTexture` (linear): direction in red and green ([0, 1] to [-1, 1] in the
    /// tangent-bitangent plane, then rotated by `rotation`), strength in blue (times the
    /// factor).
    pub texture: Option<TextureRef>,
}

impl AnisotropyLayer {
    /// Whether it stretches the lobe anywhere (a strength of 0 leaves it isotropic).
    pub fn is_active(&self) -> bool {
        self.strength > 0.0
    }
}

/// `KHR_materials_pbrSpecularGlossiness`: the specular-glossiness model. Its diffuse colour
/// (`diffuseFactor`, `diffuseTexture`) is held as [`Material::base_color`] and
/// [`Material::base_color_texture`], so alpha, vertex colours and alpha MASK read it as they
/// read a base colour; the BRDF inputs are then, by the extension's equations,
/// c_diff = diffuse.rgb · (1 - max(specular)), F0 = specular, roughness = 1 - glossiness
/// (α = (1 - glossiness)²), with F90 = 1 and no metal.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SpecularGlossiness {
    /// `specularFactor` (linear): F0.
    pub specular: Vec3,
    /// `glossinessFactor`: 1 - perceptual roughness.
    pub glossiness: f32,
    /// `specularGlossinessTexture`: specular in RGB (sRGB), glossiness in A (linear), times
    /// the factors.
    pub texture: Option<TextureRef>,
}

/// `KHR_materials_iridescence`: a thin film over the surface (soap bubbles, oil, anodised
/// metal) whose interference tints the specular reflection by angle.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IridescenceLayer {
    /// `iridescenceFactor`: how much of the specular Fresnel the film replaces.
    pub factor: f32,
    /// `iridescenceTexture` (red channel), times the factor.
    pub texture: Option<TextureRef>,
    /// `iridescenceIor`: the film's index of refraction (1.3 by default).
    pub ior: f32,
    /// `iridescenceThicknessMinimum` in nanometres (100 by default).
    pub thickness_min: f32,
    /// `iridescenceThicknessMaximum` in nanometres (400 by default): the thickness without a
    /// texture.
    pub thickness_max: f32,
    /// `iridescenceThicknessTexture` (green channel): mixes from the minimum to the maximum.
    pub thickness_texture: Option<TextureRef>,
}

/// `KHR_materials_specular`: the strength and colour of a dielectric's specular reflection.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SpecularLayer {
    /// `specularFactor`: scales the reflection (F0 and F90).
    pub factor: f32,
    /// `specularTexture` (alpha channel), times the factor.
    pub texture: Option<TextureRef>,
    /// `specularColorFactor` (linear): tints F0.
    pub color: Vec3,
    /// `specularColorTexture` (sRGB RGB), times the colour factor.
    pub color_texture: Option<TextureRef>,
}

/// `KHR_materials_sheen`: a cloth-like retro-reflective layer (velvet, fabric).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SheenLayer {
    /// `sheenColorFactor` (linear).
    pub color: Vec3,
    /// `sheenColorTexture` (sRGB RGB), times the factor.
    pub color_texture: Option<TextureRef>,
    /// `sheenRoughnessFactor`.
    pub roughness: f32,
    /// `sheenRoughnessTexture` (alpha channel), times the factor.
    pub roughness_texture: Option<TextureRef>,
}

/// `KHR_materials_clearcoat`: a clear varnish layer (car paint, lacquer) with its own
/// roughness and normal.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ClearcoatLayer {
    /// `clearcoatFactor`: the coat's weight.
    pub factor: f32,
    /// `clearcoatTexture` (red channel), times the factor.
    pub texture: Option<TextureRef>,
    /// `clearcoatRoughnessFactor`.
    pub roughness: f32,
    /// `clearcoatRoughnessTexture` (green channel), times the factor.
    pub roughness_texture: Option<TextureRef>,
    /// `clearcoatNormalTexture`: the coat's own normal map (without one the coat follows the
    /// interpolated vertex normal, not the base layer's normal map).
    pub normal_texture: Option<TextureRef>,
    /// Scale of the coat's normal map.
    pub normal_scale: f32,
}

impl Material {
    /// Whether rays do not see this material's back faces: `doubleSided` false (glTF 2.0
    /// §3.9.6), unless the surface bounds a transmissive volume. `KHR_materials_volume`: "The
    /// doubleSided property has no effect on volume boundaries": light that refracted into a
    /// closed glass mesh leaves it through the back of the far side (culled, a glass ball
    /// bent light at its near side only and imaged the world as a lens of index 1.2 would).
    pub fn culls_back_faces(&self) -> bool {
        !self.double_sided && (self.transmission <= 0.0 || self.thin_walled)
    }

    /// A thin-walled transmissive sheet (`KHR_materials_transmission` without a volume), at
    /// least where its thickness texture reads 0: light passes straight through it, so shadow
    /// rays do too (tinted). A glass *volume* bends light, which a straight shadow ray cannot
    /// follow: it blocks them (as in Cycles). Which points of a material with a thickness
    /// texture are thin is decided per hit ([`crate::prepare::Prepared::thin_walled_at`]).
    /// A metallic factor of 1 with a metallic-roughness texture may still be a dielectric in
    /// places (StainedGlassLamp's and LightsPunctualLamp's glass: the default factor 1 times
    /// the texture), as camera rays see it.
    pub fn see_through(&self) -> bool {
        self.transmission > 0.0
            && (self.thin_walled || self.thickness_texture.is_some())
            && (self.metallic < 1.0 || self.metallic_roughness_texture.is_some())
    }

    /// The share of light a see-through sheet lets pass straight through (0 for any other
    /// material): transmission × (1 - metallic) × (1 - F0) × base colour, with the `base`
    /// colour, `transmission` and `metallic` at the point (textures applied, as
    /// [`crate::prepare::Prepared::straight_transmittance_at`] reads them).
    pub fn straight_transmittance(&self, base: Vec3, transmission: f32, metallic: f32) -> Vec3 {
        if !self.see_through() {
            return Vec3::ZERO;
        }
        let f0 = ((self.ior - 1.0) / (self.ior + 1.0)).powi(2);
        base * (transmission * (1.0 - metallic) * (1.0 - f0))
    }

    /// Every texture the material references (base colour, metallic-roughness, normal,
    /// occlusion, emissive, transmission, volume thickness, then the specular, sheen,
    /// clearcoat and iridescence layers' ones, then the specular-glossiness, anisotropy and
    /// diffuse transmission textures, then the scalar maps), in that order, skipping those it
    /// lacks.
    pub fn texture_refs(&self) -> impl Iterator<Item = TextureRef> {
        let mut refs = vec![
            self.base_color_texture,
            self.metallic_roughness_texture,
            self.normal_texture,
            self.occlusion_texture,
            self.emissive_texture,
        ];
        refs.extend([self.transmission_texture, self.thickness_texture]);
        if let Some(l) = &self.specular_layer {
            refs.extend([l.texture, l.color_texture]);
        }
        if let Some(l) = &self.sheen {
            refs.extend([l.color_texture, l.roughness_texture]);
        }
        if let Some(l) = &self.clearcoat {
            refs.extend([l.texture, l.roughness_texture, l.normal_texture]);
        }
        if let Some(l) = &self.iridescence {
            refs.extend([l.texture, l.thickness_texture]);
        }
        if let Some(l) = &self.specular_glossiness {
            refs.push(l.texture);
        }
        if let Some(l) = &self.anisotropy {
            refs.push(l.texture);
        }
        if let Some(l) = &self.diffuse_transmission {
            refs.extend([l.texture, l.color_texture]);
        }
        if let Some(m) = &self.scalar_maps {
            refs.extend([m.alpha, m.roughness, m.metallic]);
        }
        refs.into_iter().flatten()
    }

    /// The texture slots, in the order of [`Material::texture_refs`].
    fn texture_slots_mut(&mut self) -> Vec<&mut Option<TextureRef>> {
        let mut slots = vec![
            &mut self.base_color_texture,
            &mut self.metallic_roughness_texture,
            &mut self.normal_texture,
            &mut self.occlusion_texture,
            &mut self.emissive_texture,
        ];
        slots.extend([&mut self.transmission_texture, &mut self.thickness_texture]);
        if let Some(l) = &mut self.specular_layer {
            slots.extend([&mut l.texture, &mut l.color_texture]);
        }
        if let Some(l) = &mut self.sheen {
            slots.extend([&mut l.color_texture, &mut l.roughness_texture]);
        }
        if let Some(l) = &mut self.clearcoat {
            slots.extend([
                &mut l.texture,
                &mut l.roughness_texture,
                &mut l.normal_texture,
            ]);
        }
        if let Some(l) = &mut self.iridescence {
            slots.extend([&mut l.texture, &mut l.thickness_texture]);
        }
        if let Some(l) = &mut self.specular_glossiness {
            slots.push(&mut l.texture);
        }
        if let Some(l) = &mut self.anisotropy {
            slots.push(&mut l.texture);
        }
        if let Some(l) = &mut self.diffuse_transmission {
            slots.extend([&mut l.texture, &mut l.color_texture]);
        }
        if let Some(m) = &mut self.scalar_maps {
            slots.extend([&mut m.alpha, &mut m.roughness, &mut m.metallic]);
        }
        slots
    }

    /// `'name' (index)` or `index`, for messages.
    pub fn label(&self, index: usize) -> String {
        match &self.name {
            Some(name) => format!("'{name}' ({index})"),
            None => index.to_string(),
        }
    }
}

/// An image the importer could not use: absent, unreadable, or not an image it can decode.
#[derive(Clone, Debug)]
pub(crate) struct UnusableImage {
    /// Index into [`Scene::images`](super::model::Scene::images).
    pub image: usize,
    /// What the file says (URI, `bufferView N`).
    pub origin: String,
    /// What is wrong, naming the resolved file where there is one.
    pub problem: String,
    /// The file looked for, when what is wrong is that it does not exist.
    pub missing: Option<std::path::PathBuf>,
}

impl UnusableImage {
    /// The image `image` (`origin` as the file gives it) that cannot be used because of
    /// `problem`; `path`, the file it was looked for in, is recorded as missing when no file
    /// is there.
    pub(crate) fn new(
        image: usize,
        origin: String,
        problem: String,
        path: Option<&std::path::Path>,
    ) -> UnusableImage {
        let missing = path.filter(|p| matches!(p.try_exists(), Ok(false)));
        UnusableImage {
            image,
            origin,
            problem,
            missing: missing.map(std::path::Path::to_path_buf),
        }
    }
}

/// A missing texture is not a missing model (what Blender and the web viewers do): every
/// material slot whose texture uses an unusable image is emptied, so the material draws with
/// its factors. Returns one warning per image, naming the image, its file and the materials;
/// with `strict` the first such image is an error instead.
pub(crate) fn draw_without(
    materials: &mut [Material],
    textures: &[Texture],
    unusable: &[UnusableImage],
    strict: bool,
) -> Result<Vec<String>, LoadErrorKind> {
    let mut warnings = Vec::with_capacity(unusable.len());
    for bad in unusable {
        let mut users = Vec::new();
        for (index, material) in materials.iter_mut().enumerate() {
            let mut uses = false;
            for slot in material.texture_slots_mut() {
                let hit = slot
                    .as_ref()
                    .and_then(|r| textures.get(r.texture))
                    .is_some_and(|t| t.image == bad.image);
                if hit {
                    *slot = None;
                    uses = true;
                }
            }
            if uses {
                users.push(material.label(index));
            }
        }
        let used_by = match users.len() {
            0 => "no material".to_string(),
            1 => format!("material {}", users[0]),
            _ => format!("materials {}", users.join(", ")),
        };
        if strict {
            let problem = LoadErrorKind::Image {
                image: bad.image,
                problem: format!(
                    "{}: {}; used by {used_by} (--strict refuses a missing texture)",
                    bad.origin, bad.problem
                ),
            };
            return Err(match &bad.missing {
                Some(file) => LoadErrorKind::MissingFile {
                    file: file.clone(),
                    problem: Box::new(problem),
                },
                None => problem,
            });
        }
        let consequence = match users.len() {
            0 => "no material uses it".to_string(),
            1 => format!("{used_by} is drawn without it, with its factors"),
            _ => format!("{used_by} are drawn without it, with their factors"),
        };
        warnings.push(format!(
            "image {} ({}): {}; {consequence}",
            bad.image, bad.origin, bad.problem
        ));
    }
    Ok(warnings)
}

impl Default for Material {
    /// The glTF default material (§3.9.1): white, fully metallic and fully rough, single-sided.
    /// A metallic white with no environment renders black under punctual lights in a PBR shader,
    /// but it is what the specification defines and what Blender's importer does too.
    fn default() -> Self {
        Self {
            name: None,
            base_color: Vec4::ONE,
            base_color_texture: None,
            metallic: 1.0,
            roughness: 1.0,
            metallic_roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            occlusion_texture: None,
            occlusion_strength: 1.0,
            emissive: Vec3::ZERO,
            emissive_strength: 1.0,
            emissive_texture: None,
            alpha_mode: AlphaMode::Opaque,
            alpha_cutoff: 0.5,
            double_sided: false,
            specular: None,
            transmission: 0.0,
            transmission_texture: None,
            ior: 1.5,
            thin_walled: true,
            thickness_texture: None,
            attenuation_color: Vec3::ONE,
            attenuation_distance: f32::INFINITY,
            dispersion: 0.0,
            unlit: false,
            specular_layer: None,
            sheen: None,
            clearcoat: None,
            iridescence: None,
            specular_glossiness: None,
            anisotropy: None,
            diffuse_transmission: None,
            scalar_maps: None,
        }
    }
}
