//! What `meshtracer info --json` prints about a loaded scene, as one JSON object: the CLI and
//! the Python package (`Scene.info()`) both print this, so they cannot drift apart.

use super::Scene;

impl Scene {
    /// The `info --json` object: the file and its format, triangle counts (in the file, traced,
    /// dropped as degenerate or non-finite), meshes, primitives, instances, the optional vertex
    /// attributes (`uv0`, `uv1`, `colors`, `tangents`), materials, textures,
    /// images, cameras, lights, bounds, warnings, variants, animations, the pose drawn, the
    /// extensions with their status, and the material list.
    pub fn info_json(&self) -> serde_json::Value {
        serde_json::json!({
            "file": self.source,
            "format": self.format,
            "triangles": self.file_triangles,
            "traced_triangles": self.soup.len(),
            "dropped_triangles": self.file_triangles - self.soup.len(),
            "meshes": self.mesh_count,
            "primitives": self.primitive_count,
            "instances": self.instances.len(),
            "vertex_attributes": self.soup.attributes(),
            "materials": self.materials.len(),
            "textures": self.textures.len(),
            "images": self.images.len(),
            "cameras": self.cameras,
            "lights": self.lights,
            "bounds": self.bounds,
            "warnings": self.warnings,
            "variants": self.variants,
            "animations": self.animations,
            "pose": self.pose,
            "extensions": self.extensions,
            "material_list": self.materials,
        })
    }
}
