//! meshtracer: a CPU ray tracer for glTF 2.0 and Wavefront OBJ assets.
//!
//! The program is a pipeline of phases that hand over plain data, each a module; data flows
//! one way, from the leaves up, and no module imports one above it:
//!
//! ```text
//! leaves     defaults, color, sampling, cpu, measure     named defaults, colour, random numbers
//! load       Scene::load(path)                           scene/ (glTF, OBJ importers)
//! accel      Accel::build(&soup, ...)                    accel/ (obvhs BVH, linear scan)
//! lights     PunctualLight, AreaLights, Environment      light/
//! prepare    Prepared::build(scene, &options, ...)       prepare/ (the one build sequence,
//!                                                        the light interface, point queries)
//! shading    Prepared::surface -> Surface -> Bsdf        shading/
//! integrate  Integrator::radiance along a camera ray     integrator/ (direct, path)
//! render     render(&prepared, &settings, ...)           render/ (pixel loop, film, denoise)
//! settings   setup::default_settings, setup::lighting    setup (the one lighting policy)
//! outputs    PendingOutput::commit, aov::write_*         output/ (every file, atomically)
//! jobs       views, batches, tiles planned as data       jobs/
//! tools      compare, bench, plot                        tools/
//! ```
//!
//! The command line is the binary's alone (`src/bin/meshtracer/`); the library knows nothing
//! of clap and never exits the process. Every default (image size, field of view, ambient, the
//! light rig) is named in [`defaults`]. Importers ([`scene`]) never call the tracer; the tracer
//! never sees a glTF or OBJ type.
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
//! // The default render samples each pixel adaptively: at least 4 camera rays, at most 32.
//! assert!((64 * 48 * 4..=64 * 48 * 32).contains(&stats.primary_rays));
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
