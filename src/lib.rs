//! meshtracer: a CPU ray tracer for glTF 2.0 and Wavefront OBJ assets.
//!
//! The program is a pipeline of phases that hand over plain data:
//!
//! ```text
//! Scene::load(path)  ->  Accel::build(&soup)  ->  render(&scene, &accel, &options)  ->  Image::save
//! ```
//!
//! Importers ([`scene`]) never call the tracer; the tracer never sees a glTF or OBJ type.
#![deny(missing_docs)]

pub mod scene;

pub use scene::{LoadError, LoadErrorKind, LoadOptions, Scene};
