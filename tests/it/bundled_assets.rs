//! The scenes in `assets/` are exactly what `examples/make_assets.rs` writes, and they load
//! with the cameras and lights the README promises.

#[path = "../../examples/make_assets.rs"]
mod make_assets;

use meshtracer::scene::LightKind;
use meshtracer::Scene;

#[test]
fn committed_assets_match_their_generator() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    for (path, expected) in make_assets::assets() {
        let actual = std::fs::read_to_string(root.join(path)).unwrap_or_default();
        assert!(
            actual == expected,
            "{path} differs from what examples/make_assets.rs writes: run `cargo run --example make_assets`"
        );
    }
}

#[test]
fn the_default_scene_has_a_camera_a_point_and_a_spot_light() {
    let scene = Scene::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/cornell-box.gltf"
    ))
    .unwrap();
    assert_eq!(scene.cameras.len(), 1);
    assert!(scene.lights.iter().any(|l| l.kind == LightKind::Point));
    assert!(scene
        .lights
        .iter()
        .any(|l| matches!(l.kind, LightKind::Spot { .. })));
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let obj = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/shapes.obj")).unwrap();
    assert_eq!(obj.soup.len(), 2 + 12 + 6);
    assert_eq!(obj.materials.len(), 3);
}
