//! What a load is asked for: its limits and options, and the file formats it reads.

use super::pose::PoseOptions;
use serde::Serialize;
use std::path::Path;

/// Limits that keep a hostile file from exhausting the machine. Each has a documented default
/// and can be raised by the user.
#[derive(Clone, Copy, Debug)]
pub struct LoadLimits {
    /// Largest model or buffer file read, in bytes (default 2 GiB).
    pub max_file_bytes: u64,
    /// Most triangles the soup may hold after instancing (default 50 million: about 9 GB of soup).
    pub max_triangles: u64,
    /// Largest decoded image, in pixels (default 64 megapixels, e.g. 8192x8192).
    pub max_image_pixels: u64,
}

impl Default for LoadLimits {
    fn default() -> Self {
        Self {
            max_file_bytes: crate::defaults::MAX_FILE_BYTES,
            max_triangles: crate::defaults::MAX_TRIANGLES,
            max_image_pixels: crate::defaults::MAX_IMAGE_PIXELS,
        }
    }
}

impl LoadLimits {
    /// Most vertices one primitive may declare: [`crate::defaults::VERTICES_PER_TRIANGLE`]
    /// for each triangle of the limit, so raising `--max-triangles` raises it too.
    pub fn max_vertices(&self) -> u64 {
        self.max_triangles
            .saturating_mul(crate::defaults::VERTICES_PER_TRIANGLE)
    }
}

/// Options for [`Scene::load_with`](super::model::Scene::load_with).
#[derive(Clone, Debug, Default)]
pub struct LoadOptions {
    /// Resource limits.
    pub limits: LoadLimits,
    /// Allow URIs that are absolute or escape the model's folder (`--allow-external-files`).
    pub allow_external_files: bool,
    /// Refuse the file when an image, or an OBJ's material library, cannot be used
    /// (`--strict`), instead of drawing the materials that use it with their factors (the
    /// faces of a missing library with a grey default) and a warning.
    pub strict: bool,
    /// The `KHR_materials_variants` variant to draw, by name (`--variant`); `None` draws each
    /// primitive's default material.
    pub variant: Option<String>,
    /// The pose to draw (`--animation`, `--time`); the default is the file's static pose.
    pub pose: PoseOptions,
    /// Load a glTF file that has nothing to draw (no scene, or a scene without nodes: both
    /// valid) as an empty scene with a warning, instead of refusing it with
    /// [`LoadErrorKind::NothingToDraw`](super::error::LoadErrorKind::NothingToDraw): for a
    /// caller that describes the file rather than draws it (`info`).
    pub allow_nothing_to_draw: bool,
}

/// The file formats meshtracer reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// glTF 2.0 JSON (`.gltf`), with external or embedded buffers.
    Gltf,
    /// glTF 2.0 binary container (`.glb`).
    Glb,
    /// Wavefront OBJ with optional MTL.
    Obj,
    /// No file: built in memory ([`Scene::empty`](super::model::Scene::empty) and
    /// [`Scene::add_mesh`](super::model::Scene::add_mesh)). [`Format::sniff`] never returns it.
    Memory,
}

impl Format {
    /// Guesses the format from the first bytes, falling back on the extension only for OBJ,
    /// which has no magic number. A `.gltf` that is really a GLB (or the reverse) still loads.
    pub fn sniff(path: &Path, head: &[u8]) -> Option<Format> {
        if head.starts_with(b"glTF") {
            return Some(Format::Glb);
        }
        let first = head
            .iter()
            .copied()
            .find(|b| !(b.is_ascii_whitespace() || *b == 0xEF || *b == 0xBB || *b == 0xBF));
        if first == Some(b'{') {
            return Some(Format::Gltf);
        }
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        match ext.as_deref() {
            Some("obj") => Some(Format::Obj),
            _ => None,
        }
    }
}
