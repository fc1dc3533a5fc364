//! The scene as plain data: a world-space triangle soup with materials, cameras and lights.
//!
//! Importers ([`gltf_import`] and [`obj`]) turn a file into a [`Scene`]; nothing here knows
//! about rays. Units are the glTF ones (glTF 2.0 §3.4): metres, radians, right-handed, +Y up.

mod archive;
mod arrays;
mod builder;
pub(crate) mod dds;
mod error;
mod exr_blocks;
pub mod extensions;
mod file_stamp;
pub mod gltf_import;
mod image_header;
mod image_source;
mod info;
pub(crate) mod ktx2;
mod material;
mod model;
pub mod obj;
mod obj_smoothing;
mod options;
mod paths;
pub mod pose;
mod punctual;
mod read;
mod soup;
pub mod tangents;
mod texture;
mod viewpoint;

pub use archive::{
    holds_a_model as zip_holds_a_model, remove_unpacked as remove_unpacked_archives, Archive,
    MODEL_EXTENSIONS,
};
pub use arrays::{check_material, ArraysError, MeshArrays};
pub use builder::{SoupBuilder, TriangleIn, VerticesIn};
pub use error::{catch_quietly, image_error_text, panic_message, LoadError, LoadErrorKind};
pub use exr_blocks::{decode_exr, decode_exr_channels, ExrChannels, MAX_EXR_TEXELS};
pub use file_stamp::FileStamp;
pub use image_source::{Encoded, FileRange, ImageSource, SharedBytes};
pub use material::{
    AlphaMode, AnisotropyLayer, Channel, ClearcoatLayer, DiffuseTransmissionLayer,
    IridescenceLayer, Material, ScalarMaps, SheenLayer, SpecularGlossiness, SpecularLayer,
    TextureRef, TextureTransform,
};
pub use model::Scene;
pub use options::{Format, LoadLimits, LoadOptions};
pub use paths::{irregular_kind, resolve_relative, FileAccess};
pub use pose::{AnimationInfo, PoseOptions};
pub use punctual::{Light, LightKind};
pub use soup::{Bounds, Instance, TriangleSoup};
pub use texture::{Filter, Sampler, Texture, Wrap};
pub use viewpoint::{Camera, Projection};

use gltf_import::LoadedFile;
use std::path::Path;

impl Scene {
    /// Loads a glTF (.gltf/.glb) or OBJ file with default options.
    pub fn load(path: impl AsRef<Path>) -> Result<Scene, LoadError> {
        Scene::load_with(path, &LoadOptions::default())
    }

    /// Loads a glTF (.gltf/.glb) or OBJ file, or a zip archive or a folder holding one (with
    /// the files it references beside it). The format is decided by content (zip and GLB
    /// magic, JSON), then by the `.obj` extension.
    pub fn load_with(path: impl AsRef<Path>, options: &LoadOptions) -> Result<Scene, LoadError> {
        let path = path.as_ref();
        if path.is_dir() {
            // An unzipped download: its one model.
            let model = archive::folder_model(path).map_err(|kind| LoadError::new(path, kind))?;
            return Scene::load_with(path.join(model), options);
        }
        let len = Scene::checked_len(path, options)?;
        if archive::is_zip(path) {
            return Scene::load_archive(path, options);
        }
        Scene::load_file(path, len, options)
    }

    /// The length of the file at `path`; what is not a regular file, or is larger than the
    /// limit, is refused.
    fn checked_len(path: &Path, options: &LoadOptions) -> Result<u64, LoadError> {
        let err = |kind| LoadError::new(path, kind);
        let meta = paths::regular_file(path).map_err(err)?;
        if meta.len() > options.limits.max_file_bytes {
            return Err(err(LoadErrorKind::FileTooLarge {
                bytes: meta.len(),
                limit: options.limits.max_file_bytes,
            }));
        }
        Ok(meta.len())
    }

    /// The one model of the zip archive at `path`, unpacked with its files ([`archive`]); what
    /// names a file inside it (errors, warnings, [`Scene::source`]) names it as
    /// `ARCHIVE/PATH-INSIDE`. A model inside may not be an archive itself.
    fn load_archive(path: &Path, options: &LoadOptions) -> Result<Scene, LoadError> {
        let mut steps = crate::measure::Steps::new();
        let (archive, model) = archive::unpack(path, options.limits.max_file_bytes)
            .map_err(|kind| LoadError::new(path, kind))?;
        steps.mark("unpack");
        let folder = archive.folder().to_path_buf();
        let outside = |p: &Path| match p.strip_prefix(&folder) {
            Ok(inner) => path.join(inner),
            Err(_) => p.to_path_buf(),
        };
        let inner = folder.join(&model);
        if archive::is_zip(&inner) {
            return Err(LoadError::new(
                &path.join(&model),
                LoadErrorKind::Archive("a zip archive inside the archive".to_string()),
            ));
        }
        let relabel = |mut e: LoadError| {
            e.path = outside(&e.path);
            e
        };
        let len = Scene::checked_len(&inner, options).map_err(relabel)?;
        let mut scene = Scene::load_file(&inner, len, options).map_err(relabel)?;
        let (from, to) = (folder.display().to_string(), path.display().to_string());
        for warning in &mut scene.warnings {
            *warning = warning.replace(&from, &to);
        }
        scene.source = outside(&scene.source);
        scene.archive = Some(archive);
        scene.inputs.clear();
        scene.load_steps.splice(0..0, steps.list().iter().cloned());
        Ok(scene)
    }

    /// Loads a glTF (.gltf/.glb) or OBJ file of `len` bytes, checked by
    /// [`Scene::checked_len`].
    fn load_file(path: &Path, len: u64, options: &LoadOptions) -> Result<Scene, LoadError> {
        let mut steps = crate::measure::Steps::new();
        let (bytes, deferred) = read::read_model(path, len, options)?;
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
        // `nothing_to_draw`: an empty scene the options accept (see `allow_nothing_to_draw`).
        let (scene, nothing_to_draw) = match Format::sniff(path, head) {
            Some(Format::Glb) | Some(Format::Gltf) => {
                gltf_import::load(path, bytes, file, options)?
            }
            Some(Format::Obj) => (obj::load(path, bytes, options)?, false),
            Some(Format::Memory) | None => {
                return Err(LoadError::new(path, LoadErrorKind::UnknownFormat))
            }
        };
        if scene.soup.is_empty() && !nothing_to_draw {
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

    /// A scene lists the files its model refers to, once each: an OBJ its material library,
    /// a glTF its buffer and image files; a self-contained glTF none.
    #[test]
    fn a_scene_lists_the_files_its_model_refers_to() {
        let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
        let obj = Scene::load(assets.join("shapes.obj")).expect("the bundled OBJ loads");
        assert_eq!(obj.inputs, [assets.join("shapes.mtl")]);
        let gltf = Scene::load(assets.join("cornell-box.gltf")).expect("the bundled scene loads");
        assert!(gltf.inputs.is_empty(), "{:?}", gltf.inputs);
        let Some(samples) = std::env::var_os("MESHTRACER_SAMPLES") else {
            eprintln!("SKIPPED the glTF half of a_scene_lists_the_files_its_model_refers_to: set MESHTRACER_SAMPLES");
            return;
        };
        let folder = Path::new(&samples).join("BoxTextured/glTF");
        let textured = Scene::load(folder.join("BoxTextured.gltf")).expect("BoxTextured loads");
        assert_eq!(
            textured.inputs,
            [
                folder.join("BoxTextured0.bin"),
                folder.join("CesiumLogoFlat.png")
            ]
        );
        let glb = Path::new(&samples).join("BoxTextured/glTF-Binary/BoxTextured.glb");
        assert!(Scene::load(glb).expect("the GLB loads").inputs.is_empty());
    }

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
