//! The scene as plain data: a world-space triangle soup with materials, cameras and lights.
//!
//! Importers ([`gltf_import`] and [`obj`]) turn a file into a [`Scene`]; nothing here knows
//! about rays. Units are the glTF ones (glTF 2.0 §3.4): metres, radians, right-handed, +Y up.

mod builder;
mod error;
pub mod extensions;
pub mod gltf_import;
mod image_header;
mod image_source;
pub(crate) mod ktx2;
mod model;
pub mod obj;
mod options;
mod paths;
pub mod pose;
mod soup;
pub mod tangents;
mod texture;

pub use builder::{SoupBuilder, TriangleIn, VerticesIn};
pub use error::{LoadError, LoadErrorKind};
pub use image_source::{Encoded, FileRange, ImageSource, SharedBytes};
pub use model::Scene;
pub use options::{Format, LoadLimits, LoadOptions};
pub use paths::{resolve_relative, FileAccess};
pub use pose::{AnimationInfo, PoseOptions};
pub use soup::{Bounds, Instance, TriangleSoup};
pub use texture::{Filter, Sampler, Texture, Wrap};

use glam::{Vec3, Vec4};
use serde::Serialize;
use std::path::Path;

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
    /// Index into [`Scene::textures`].
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
    /// When false the back face is invisible (glTF 2.0 §3.9.6).
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
    /// clearcoat and iridescence layers' ones), in that order, skipping those it lacks.
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
    /// Index into [`Scene::images`].
    pub image: usize,
    /// What the file says (URI, `bufferView N`).
    pub origin: String,
    /// What is wrong, naming the resolved file where there is one.
    pub problem: String,
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
            return Err(LoadErrorKind::Image {
                image: bad.image,
                problem: format!(
                    "{}: {}; used by {used_by} (--strict refuses a missing texture)",
                    bad.origin, bad.problem
                ),
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
            unlit: false,
            specular_layer: None,
            sheen: None,
            clearcoat: None,
            iridescence: None,
        }
    }
}

/// The file [`Scene::load_with`] read: its bytes, and the images it left on disk.
#[derive(Clone, Copy)]
pub(crate) struct LoadedFile<'a> {
    pub bytes: &'a std::sync::Arc<Vec<u8>>,
    pub deferred: Option<&'a gltf_import::DeferredImages>,
}

/// Camera projection (glTF 2.0 §3.10).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum Projection {
    /// Perspective: `yfov` is the vertical field of view in radians (glTF 2.0 §5.14).
    Perspective {
        /// Vertical field of view, radians.
        yfov: f32,
        /// Width / height, if the file sets it.
        aspect_ratio: Option<f32>,
        /// Near clip distance.
        znear: f32,
        /// Far clip distance; infinite when absent.
        zfar: Option<f32>,
    },
    /// Orthographic: `xmag`/`ymag` are half the width/height of the view volume.
    Orthographic {
        /// Half width of the view, metres.
        xmag: f32,
        /// Half height of the view, metres.
        ymag: f32,
        /// Near clip distance.
        znear: f32,
        /// Far clip distance.
        zfar: f32,
    },
}

/// A camera placed in the world. glTF 2.0 §3.10.1: a camera looks down its node's local -Z with
/// +Y up; node scale is removed.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Camera {
    /// Name of the camera or its node.
    pub name: Option<String>,
    /// Eye position, world space.
    pub position: Vec3,
    /// Unit view direction (world-space image of local -Z).
    pub forward: Vec3,
    /// Unit up vector, orthogonal to `forward` (world-space image of local +Y).
    pub up: Vec3,
    /// Projection.
    pub projection: Projection,
}

/// Type of a punctual light (`KHR_lights_punctual`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum LightKind {
    /// Omnidirectional point light; intensity in candela.
    Point,
    /// Spot light; intensity in candela; cone angles in radians from the axis.
    Spot {
        /// Angle where falloff starts.
        inner_cone_angle: f32,
        /// Angle where the light reaches zero.
        outer_cone_angle: f32,
    },
    /// Directional light; intensity in lux.
    Directional,
}

/// A punctual light in world space (`KHR_lights_punctual`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Light {
    /// Name from the file, if any.
    pub name: Option<String>,
    /// Type and cone.
    pub kind: LightKind,
    /// Linear RGB colour.
    pub color: Vec3,
    /// Candela for point and spot lights, lux for directional lights.
    pub intensity: f32,
    /// Distance beyond which the light has no effect (point and spot only).
    pub range: Option<f32>,
    /// World position (unused for directional lights).
    pub position: Vec3,
    /// Unit direction the light travels, world space (local -Z of its node).
    pub direction: Vec3,
}

impl Scene {
    /// Loads a glTF (.gltf/.glb) or OBJ file with default options.
    pub fn load(path: impl AsRef<Path>) -> Result<Scene, LoadError> {
        Scene::load_with(path, &LoadOptions::default())
    }

    /// Loads a glTF (.gltf/.glb) or OBJ file. The format is decided by content (GLB magic, JSON),
    /// then by the `.obj` extension.
    pub fn load_with(path: impl AsRef<Path>, options: &LoadOptions) -> Result<Scene, LoadError> {
        let path = path.as_ref();
        let err = |kind| LoadError::new(path, kind);
        let meta = std::fs::metadata(path).map_err(|e| err(LoadErrorKind::Io(e)))?;
        if meta.is_dir() {
            return Err(err(LoadErrorKind::IsDirectory));
        }
        if meta.len() > options.limits.max_file_bytes {
            return Err(err(LoadErrorKind::FileTooLarge {
                bytes: meta.len(),
                limit: options.limits.max_file_bytes,
            }));
        }
        let mut steps = crate::measure::Steps::new();
        let io = |e| err(LoadErrorKind::Io(e));
        let mut file = std::fs::File::open(path).map_err(io)?;
        // A GLB's images stay on disk until the texture phase reads them.
        let (bytes, deferred) =
            match gltf_import::read_glb_deferring_images(&mut file, meta.len()).map_err(io)? {
                Some((bytes, deferred)) => (bytes, Some(deferred)),
                None => {
                    // From the start again, whatever the GLB reader had read.
                    std::io::Seek::rewind(&mut file).map_err(io)?;
                    let mut bytes = Vec::with_capacity(meta.len() as usize);
                    std::io::Read::read_to_end(&mut file, &mut bytes).map_err(io)?;
                    (bytes, None)
                }
            };
        drop(file);
        let bytes = std::sync::Arc::new(bytes);
        steps.mark("read");
        let file = LoadedFile {
            bytes: &bytes,
            deferred: deferred.as_ref(),
        };
        let mut scene = Scene::parse(path, &bytes, Some(file), options)?;
        scene.load_steps.splice(0..0, steps.list().iter().cloned());
        Ok(scene)
    }

    /// Checks that every index between the scene's lists is in range: triangle -> material,
    /// material -> texture, texture -> image, and that the soup's per-triangle arrays agree in
    /// length. After this the renderer indexes them without checking.
    pub fn check_references(&self) -> Result<(), LoadErrorKind> {
        let bad =
            |what, index: usize, count| Err(LoadErrorKind::BadReference { what, index, count });
        let soup = &self.soup;
        let triangles = soup.indices.len();
        for (what, len) in [
            ("triangle materials", soup.material.len()),
            ("triangle instances", soup.instance.len()),
        ] {
            if len != triangles {
                return bad(what, len, triangles);
            }
        }
        let vertices = soup.positions.len();
        if soup.normals.len() != vertices {
            return bad("vertex normals", soup.normals.len(), vertices);
        }
        for (what, len) in [
            ("vertex uv0", soup.uv0.len()),
            ("vertex uv1", soup.uv1.len()),
            ("vertex colours", soup.colors.len()),
            ("vertex tangents", soup.tangents.len()),
        ] {
            if len != 0 && len != vertices {
                return bad(what, len, vertices);
            }
        }
        if let Some(&v) = soup
            .indices
            .iter()
            .flatten()
            .find(|&&v| v as usize >= vertices)
        {
            return bad("triangle vertex", v as usize, vertices);
        }
        if let Some(&m) = self
            .soup
            .material
            .iter()
            .find(|&&m| m as usize >= self.materials.len())
        {
            return bad("triangle material", m as usize, self.materials.len());
        }
        for material in &self.materials {
            for r in material.texture_refs() {
                if r.texture >= self.textures.len() {
                    return bad("material texture", r.texture, self.textures.len());
                }
            }
        }
        for texture in &self.textures {
            if texture.image >= self.images.len() {
                return bad("texture image", texture.image, self.images.len());
            }
        }
        Ok(())
    }

    /// Loads a scene from bytes already in memory; `path` names the file in errors and anchors
    /// relative URIs. This is the entry point the fuzz targets use.
    pub fn from_bytes(
        path: &Path,
        bytes: &[u8],
        options: &LoadOptions,
    ) -> Result<Scene, LoadError> {
        Scene::parse(path, bytes, None, options)
    }

    /// [`Scene::from_bytes`]; `file`, when it holds `bytes`, lets embedded images share it (or
    /// stay on disk).
    fn parse(
        path: &Path,
        bytes: &[u8],
        file: Option<LoadedFile>,
        options: &LoadOptions,
    ) -> Result<Scene, LoadError> {
        if bytes.is_empty() {
            return Err(LoadError::new(path, LoadErrorKind::EmptyFile));
        }
        let head = &bytes[..bytes.len().min(64)];
        let scene = match Format::sniff(path, head) {
            Some(Format::Glb) | Some(Format::Gltf) => {
                gltf_import::load(path, bytes, file, options)?
            }
            Some(Format::Obj) => obj::load(path, bytes, options)?,
            None => return Err(LoadError::new(path, LoadErrorKind::UnknownFormat)),
        };
        if scene.soup.is_empty() {
            let detail = if scene.warnings.is_empty() {
                String::new()
            } else {
                format!(" ({})", scene.warnings.join("; "))
            };
            return Err(LoadError::new(path, LoadErrorKind::NoTriangles(detail)));
        }
        scene
            .check_references()
            .map_err(|kind| LoadError::new(path, kind))?;
        Ok(scene)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every cross-reference the renderer indexes by is checked: a triangle's material, a
    /// material's texture and a texture's image, each one past the end is refused by name.
    #[test]
    fn out_of_range_references_are_refused() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/cornell-box.gltf");
        let scene = Scene::load(path).expect("the bundled scene loads");
        assert!(scene.check_references().is_ok());

        let mut bad = scene.clone();
        bad.soup.material[0] = bad.materials.len() as u32;
        let message = bad.check_references().unwrap_err().to_string();
        assert!(message.contains("triangle material"), "{message}");

        let mut bad = scene.clone();
        bad.materials[0].base_color_texture = Some(TextureRef {
            texture: 7,
            tex_coord: 0,
            transform: None,
        });
        let message = bad.check_references().unwrap_err().to_string();
        assert!(message.contains("material texture 7"), "{message}");

        let mut bad = scene;
        bad.soup.normals.pop();
        assert!(bad.check_references().is_err());
    }
}
