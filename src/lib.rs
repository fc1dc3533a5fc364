//! meshtracer: a CPU ray tracer for glTF 2.0 and Wavefront OBJ assets.
//!
//! The program is a pipeline of phases that hand over plain data:
//!
//! ```text
//! load         Scene::load(path)                          scene/ (glTF, OBJ importers)
//! prepare      Prepared::new(scene, &options)             prepare.rs: BVH (accel/), textures
//! integrate    render(&prepared, &settings, ...)          render/ (pixel loop, surface), integrator/
//! film         Image (linear RGBA f32) + Aovs             output.rs, render/
//! denoise      denoise::guides, denoise::denoise          denoise.rs (feature `denoise`)
//! outputs      PendingOutput::commit, aov::write_*        output.rs, aov.rs, view.rs
//! ```
//!
//! Many views of one prepared scene (`render --views`): [`views`] turns a spec into cameras
//! and names their files, [`dataset`] writes the `transforms.json` that NeRF tools read.
//! Many models (`batch`): [`batch`] reads manifests, assigns jobs to shards and defines the
//! per-job record of `results.jsonl`. [`turntable`] streams an orbit's views into an
//! animated GIF; [`sheet`] lays views or jobs out as a labelled contact sheet.
//!
//! Every default (image size, field of view, ambient, the light rig) is named in [`defaults`]. Importers
//! ([`scene`]) never call the tracer; the tracer never sees a glTF or OBJ type; only [`cli`] and
//! [`app`] know the command line.
//!
//! Rendering a model to a linear float buffer:
//!
//! ```
//! use meshtracer::prepare::{PrepareOptions, Prepared};
//! use meshtracer::{render::render, setup, Scene};
//! use std::sync::atomic::AtomicBool;
//!
//! let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/cornell-box.gltf"))?;
//! let mut warnings = Vec::new();
//! let prepared = Prepared::new(scene, &PrepareOptions::default(), &mut warnings)?;
//! let settings = setup::default_settings(&prepared.scene, 64, 48);
//! let cancel = AtomicBool::new(false);
//! let (image, stats, _aovs) = render(&prepared, &settings, &cancel, &|_done, _total| {})?;
//! // Row-major from the top-left pixel: linear radiance (RGB) and coverage (A).
//! assert_eq!(image.pixels.len(), 64 * 48);
//! assert!(image.pixels.iter().any(|p| p.x > 0.0 && p.w == 1.0));
//! assert_eq!(stats.primary_rays, 64 * 48 * 4);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

pub mod accel;
pub mod camera;
pub mod color;
mod cpu;
pub mod defaults;
pub mod geometry;
pub mod integrator;
pub mod jobs;
pub mod light;
pub mod measure;
pub mod output;
pub mod prepare;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod setup;
pub mod shading;
pub mod tools;

/// Runs `f` on a rayon pool of `threads` threads: for the tests that demand the same result at
/// any thread count.
#[cfg(test)]
pub(crate) fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool")
        .install(f)
}

pub use scene::{LoadError, LoadErrorKind, LoadOptions, Scene};
