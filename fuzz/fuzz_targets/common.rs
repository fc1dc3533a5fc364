//! Shared by the fuzz targets: load bytes through the public `Scene::from_bytes` path.

use meshtracer::scene::{LoadLimits, LoadOptions, PoseOptions};
use meshtracer::Scene;
use std::path::Path;

/// The options every target loads with. Limits are small so that a valid but huge input is
/// refused quickly instead of timing out the fuzzer.
fn options() -> LoadOptions {
    LoadOptions {
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
    }
}

/// Loads `data` as a zip archive on disk (an archive is unpacked from its path into a
/// temporary folder, and its model loaded from there with the files beside it).
pub fn load_archive(data: &[u8]) {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let path = dir.path().join("model.zip");
    std::fs::write(&path, data).expect("the archive written");
    if let Ok(scene) = Scene::load_with(&path, &options()) {
        check(scene);
    }
}

/// Loads `data` as if it were the file `name` in a folder that does not exist, so relative
/// URIs in the input resolve to nothing on this machine.
pub fn load(name: &str, data: &[u8]) {
    let options = options();
    let path = Path::new("/nonexistent-meshtracer-fuzz").join(name);
    let loaded = Scene::from_bytes(&path, data, &options);
    // A file with animations is loaded posed too, each animation at a time inside it: the
    // channels' sampling and the KHR_animation_pointer writes run only then.
    if let Ok(scene) = &loaded {
        for animation in scene.animations.iter().take(4) {
            let posed = LoadOptions {
                pose: PoseOptions {
                    animation: Some(animation.index.to_string()),
                    time: Some(0.37 * animation.duration.min(1e6)),
                },
                ..options.clone()
            };
            let _ = Scene::from_bytes(&path, data, &posed);
        }
    }
    if let Ok(scene) = loaded {
        check(scene);
    }
}

/// What every loaded scene must be: a soup the tracer can trust, also after tangents, and
/// textures that decode or warn.
fn check(mut scene: Scene) {
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
