//! Every integration test in one binary (one link instead of twenty, as ripgrep's
//! `tests/tests.rs` does). Each module is a topic that runs the real `meshtracer` binary, or the
//! library, on real files; `common` holds the helpers. `cargo test --test it batch::` runs one
//! topic. Tests that need the shared sample models (`MESHTRACER_SAMPLES`), the panoramas
//! (`MESHTRACER_ENVIRONMENTS`), pyrender or tmux print a `SKIPPED` notice without them.

// Helpers: not every topic uses every one.
#[allow(dead_code)]
mod common;

/// Zip archives: a zipped download rendered as its files; ambiguous and hostile archives.
mod archives;
/// `batch` and `batch-merge`: manifests, shards, resume, the pinned fingerprint, schedulers.
mod batch;
/// `bench`: the table, the path-tracer row, the plot, refusals.
mod bench_cli;
/// Malformed, truncated and hostile files: one clear error each, never a panic.
mod broken_files;
/// `assets/` is exactly what `examples/make_assets.rs` writes, and it renders.
mod bundled_assets;
/// `compare`: metrics, difference images, thresholds and refusals.
mod compare;
/// `render --denoise`: the built-in filter, or OIDN with the feature `denoise`.
mod denoise;
/// Draco, meshopt, quantized, WebP and KTX2 variants render like their plain sibling.
mod encoded_variants;
/// Files outside the model's folder, devices, absurd sizes: refused.
mod hostile;
/// The importer on every shared sample model.
mod import_samples;
/// `EXT_mesh_gpu_instancing`: instances placed, their accessors checked.
mod instancing;
/// Invalid glTF that changes the picture: a warning naming the place, the corrected picture.
mod invalid_forms;
/// The path tracer against closed forms: furnace, area light, MIS, environment sampling.
mod light_transport;
/// Materials: alpha modes, textures, extensions.
mod materials;
/// The `.npy` AOVs as NumPy reads them, and NumPy's own files.
mod numpy;
/// Poses: `--animation` / `--time`, skins, morph targets and the static pose.
mod poses;
/// `render --preview` inside a real terminal (tmux).
mod preview;
/// Against pyrender from the same view file: coverage and depth.
mod reference_pyrender;
/// The renderer: analytic radiance, shadows of known shape, cameras, determinism, AOVs.
mod render;
/// `render --tile` / `--crop` and `merge`: the single render, byte for byte.
mod tiles;
/// `--turntable` GIFs and contact sheets.
mod turntable;
/// Valid glTF that strict readers refuse: drawn, or "nothing to draw" where that is so.
mod valid_forms;
/// `KHR_materials_variants`: `--variant` and `info`.
mod variants;
/// `render --views`: many views after one load, `transforms.json`.
mod views;
