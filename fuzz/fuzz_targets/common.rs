//! Shared by the fuzz targets: load bytes through the public `Scene::from_bytes` path.

use meshtracer::scene::{LoadLimits, LoadOptions};
use meshtracer::Scene;
use std::path::Path;

/// Loads `data` as if it were the file `name` in a folder that does not exist, so relative
/// URIs in the input resolve to nothing on this machine. Limits are small so that a valid but
/// huge input is refused quickly instead of timing out the fuzzer.
pub fn load(name: &str, data: &[u8]) {
    let options = LoadOptions {
        limits: LoadLimits {
            max_file_bytes: 16 << 20,
            max_triangles: 1 << 20,
            // A mutated header claiming a big image would be decoded slowly, a pixel at a
            // time with coverage counters, for nothing the decoders do not do on small ones.
            max_image_pixels: 1 << 20,
        },
        allow_external_files: false,
        strict: false,
        // Static pose, default variant: the options a plain load uses.
        ..Default::default()
    };
    let path = Path::new("/nonexistent-meshtracer-fuzz").join(name);
    if let Ok(mut scene) = Scene::from_bytes(&path, data, &options) {
        // Whatever loads must be a soup the tracer can trust.
        assert!(!scene.soup.is_empty());
        assert!(scene.check_references().is_ok());
        // Tangents for normal maps (MikkTSpace) run after the load in a render; they add
        // vertices where a tangent space splits, and the soup must stay sound.
        meshtracer::scene::tangents::generate_missing(&mut scene);
        assert!(scene.check_references().is_ok());
        assert!(scene.soup.positions.iter().all(|p| p.is_finite()));
        assert!(scene.soup.normals.iter().all(|n| n.is_finite()));
        for &m in &scene.soup.material {
            assert!((m as usize) < scene.materials.len());
        }
        // The image decoders (PNG, JPEG, WebP, KTX2/Basis Universal) run in the texture
        // phase, not in the load: decode what the drawn materials use, within a small budget.
        // An image that fails is a warning (or the error of --strict), never a panic.
        let mut warnings = Vec::new();
        let _ = meshtracer::prepare::textures::TextureSet::load(&scene, 64 << 20, false, &mut warnings);
    }
}
