//! [`Scene`]: what an importer makes of a file, as plain data.

use super::extensions;
use super::image_source::ImageSource;
use super::material::Material;
use super::options::Format;
use super::pose::AnimationInfo;
use super::punctual::Light;
use super::soup::{Bounds, Instance, TriangleSoup};
use super::texture::Texture;
use super::viewpoint::Camera;
use std::path::PathBuf;

/// A scene ready to trace: plain data, printable and testable without rendering.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The file it was loaded from.
    pub source: PathBuf,
    /// Detected format.
    pub format: Format,
    /// The triangles.
    pub soup: TriangleSoup,
    /// Materials; the last one is the default material when some primitive had none.
    pub materials: Vec<Material>,
    /// Textures referenced by materials.
    pub textures: Vec<Texture>,
    /// Encoded image sources referenced by textures.
    pub images: Vec<ImageSource>,
    /// Cameras in node order.
    pub cameras: Vec<Camera>,
    /// Lights in node order.
    pub lights: Vec<Light>,
    /// Mesh instances in node order.
    pub instances: Vec<Instance>,
    /// Number of distinct meshes in the file.
    pub mesh_count: usize,
    /// Triangles in the file after instancing, by the counting rules of glTF primitives
    /// (TRIANGLES: count/3, strips and fans: count - 2) and OBJ fan triangulation, before
    /// degenerate and non-finite ones are dropped. `soup.len()` is what is traced.
    pub file_triangles: usize,
    /// Number of primitives flattened (over all instances).
    pub primitive_count: usize,
    /// Bounds of all triangles.
    pub bounds: Bounds,
    /// Problems that did not stop loading.
    pub warnings: Vec<String>,
    /// Names of the file's `KHR_materials_variants` variants, in file order.
    pub variants: Vec<String>,
    /// The variant drawn, if one was chosen.
    pub variant: Option<String>,
    /// Every glTF extension the file uses (`extensionsUsed`), with how it is honoured.
    pub extensions: Vec<extensions::ExtensionUse>,
    /// The file's animations (glTF), in file order.
    pub animations: Vec<AnimationInfo>,
    /// The animation and time drawn ("animation 1 'Walk' at 0.5 s"); `None`: the static pose.
    pub pose: Option<String>,
    /// How long each step of the load took ("read", "parse", "flatten", ...), for `--stats`.
    pub load_steps: Vec<crate::measure::Step>,
    /// For a model loaded from a zip archive, the folder it was unpacked into, kept while the
    /// scene lives (its textures are read after the load).
    pub archive: Option<super::archive::Archive>,
    /// The files the model refers to besides itself (a glTF's buffers and images, an OBJ's
    /// material libraries and textures), each once, in the order the load met them, missing
    /// ones included; empty for a model from a zip archive, whose own bytes hold them. What
    /// a record of a render must hash to know the render's inputs are unchanged.
    pub inputs: Vec<PathBuf>,
}
