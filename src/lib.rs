//! meshtracer: a CPU ray tracer for glTF 2.0 and Wavefront OBJ assets.
//!
//! The program is a pipeline of phases that hand over plain data:
//!
//! ```text
//! Scene::load(path)  ->  Accel::build(&soup)  ->  render(&scene, &accel, &settings)  ->  PendingOutput::commit
//! ```
//!
//! Importers ([`scene`]) never call the tracer; the tracer never sees a glTF or OBJ type.
#![deny(missing_docs)]

pub mod accel;
pub mod aov;
pub mod app;
pub mod bench;
pub mod camera;
pub mod cli;
pub mod compare;
pub mod geometry;
pub mod image;
pub mod light;
pub mod plot;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod shading;
pub mod texture;
pub mod view;

pub use scene::{LoadError, LoadErrorKind, LoadOptions, Scene};
