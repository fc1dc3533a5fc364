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

/// The bundled pendulum (README's `--frames` example): one animation of 2 s, no camera, no
/// lights. Four frames are at 0, 0.5, 1 and 1.5 s: at 0.5 and 1.5 s the pendulum hangs
/// straight down (30°·cos of a quarter and three quarters of a turn), so frames 1 and 3 are the
/// same pose under the one shared camera, and the same bytes; at 0 and 1 s it swings out to
/// +30° and -30°, so frames 0 and 2 differ from each other and from the straight pose.
#[test]
fn the_bundled_pendulum_swings_through_its_frames() {
    use crate::common::{run, s};
    let model = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/pendulum.gltf");
    let scene = Scene::load(&model).unwrap();
    assert!(scene.cameras.is_empty() && scene.lights.is_empty());
    assert_eq!(scene.animations.len(), 1);
    assert_eq!(scene.animations[0].name.as_deref(), Some("Swing"));
    assert_eq!(scene.animations[0].duration, 2.0);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("swing");
    run(
        &[
            "render",
            s(&model),
            "-o",
            s(&frames),
            "--frames",
            "4",
            "--width",
            "48",
            "--height",
            "36",
            "--spp",
            "1",
            "-q",
        ],
        true,
    );
    let frame = |k: usize| std::fs::read(frames.join(format!("{k:03}.png"))).unwrap();
    assert_eq!(frame(1), frame(3), "straight down at 0.5 s and 1.5 s");
    assert_ne!(frame(0), frame(2), "+30° and -30°");
    assert_ne!(frame(0), frame(1));
    assert_ne!(frame(2), frame(1));
}
