//! `meshtracer._meshtracer`: the meshtracer library as a Python extension module.
//!
//! A thin layer over the same phases the CLI runs (`src/bin/meshtracer/commands/render.rs`):
//! [`Scene::load_with`](meshtracer::Scene::load_with), the file's first camera or the automatic
//! one, [`setup::lighting`] (the one lighting policy), [`Prepared::build`] (the one build
//! sequence, with the BVH preset `auto` chooses) and [`render`]. With the same model, size and
//! settings the colour is the CLI's image, bit for bit. Nothing here decides anything about
//! the picture that the library does not decide for the CLI too.
//!
//! The Python-facing module is `python/meshtracer/__init__.py`; docs/python.md describes it.

use meshtracer::accel::{AccelKind, BvhPreset};
use meshtracer::camera::{auto_camera, View};
use meshtracer::color::ViewTransform;
use meshtracer::defaults::{DEFAULT_BOUNCES, DEFAULT_SPP, MAX_TEXTURE_MIB};
use meshtracer::integrator::IntegratorKind;
use meshtracer::prepare::{PrepareOptions, Prepared};
use meshtracer::render::{render, RenderSettings};
use meshtracer::scene::{LoadOptions, PoseOptions};
use meshtracer::setup::{self, LightingOptions};
use meshtracer::shading::ShadingModel;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

pyo3::create_exception!(
    meshtracer,
    Error,
    PyException,
    "A model that cannot be loaded or rendered: the message is the one the meshtracer CLI prints after `meshtracer: error: `."
);

/// `error` as the CLI prints it: anyhow's alternate form, the error and its sources joined by
/// ": " (`main.rs` prints `meshtracer: error: {e:#}`).
fn cli_error(error: impl Into<anyhow::Error>) -> PyErr {
    Error::new_err(format!("{:#}", error.into()))
}

/// The arrays a render can return besides colour.
const AOV_NAMES: [&str; 4] = ["depth", "mask", "normal", "segmentation"];

/// A loaded model. It is prepared (tangents, textures, BVH, area lights) by its first render
/// and the prepared scene is kept for the renders after it.
#[pyclass(module = "meshtracer", name = "Scene", frozen)]
struct PyScene {
    /// The file, as given (error messages name it).
    path: PathBuf,
    /// `--strict`: also refuse an image that cannot be decoded when preparing.
    strict: bool,
    state: Mutex<State>,
    /// The warnings of the texture decoding (first render), after the load's.
    prepare_warnings: Mutex<Vec<String>>,
}

/// A scene before and after its first render.
enum State {
    Loaded(Box<meshtracer::Scene>),
    Prepared(Arc<Prepared>),
    /// Only while a preparation is under way (the scene moved into it); a preparation that
    /// failed leaves it, and the scene must be loaded again.
    Empty,
}

impl PyScene {
    /// The prepared scene, preparing it now for about `rays` rays if no render has yet (the BVH
    /// preset `auto` picks for that work, as `render --bvh-preset auto` does).
    fn prepared(&self, py: Python<'_>, rays: f64) -> PyResult<Arc<Prepared>> {
        let mut state = self.lock()?;
        let scene = match std::mem::replace(&mut *state, State::Empty) {
            State::Prepared(p) => {
                *state = State::Prepared(Arc::clone(&p));
                return Ok(p);
            }
            State::Loaded(scene) => scene,
            State::Empty => {
                return Err(Error::new_err(format!(
                    "{}: an earlier preparation of this scene failed: load it again",
                    self.path.display()
                )))
            }
        };
        let options = PrepareOptions {
            accel: AccelKind::Bvh,
            bvh_preset: BvhPreset::Auto.for_work(scene.soup.len(), rays),
            max_texture_bytes: MAX_TEXTURE_MIB.saturating_mul(1 << 20),
            strict: self.strict,
        };
        let mut warnings = Vec::new();
        let prepared = py
            .detach(|| Prepared::new(*scene, &options, &mut warnings))
            .map_err(cli_error)?;
        let prepared = Arc::new(prepared);
        *state = State::Prepared(Arc::clone(&prepared));
        if let Ok(mut kept) = self.prepare_warnings.lock() {
            kept.extend(warnings);
        }
        Ok(prepared)
    }

    fn lock(&self) -> PyResult<std::sync::MutexGuard<'_, State>> {
        self.state
            .lock()
            .map_err(|_| Error::new_err("the scene was poisoned by a panic in an earlier call"))
    }

    /// Runs `f` on the scene as loaded (or as prepared).
    fn with_scene<T>(&self, f: impl FnOnce(&meshtracer::Scene) -> T) -> PyResult<T> {
        match &*self.lock()? {
            State::Loaded(scene) => Ok(f(scene)),
            State::Prepared(p) => Ok(f(&p.scene)),
            State::Empty => Err(Error::new_err(format!(
                "{}: an earlier preparation of this scene failed: load it again",
                self.path.display()
            ))),
        }
    }
}

#[pymethods]
impl PyScene {
    /// What `meshtracer info --json` prints about the model, as a dict.
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let text = self.with_scene(|s| s.info_json().to_string())?;
        py.import("json")?.call_method1("loads", (text,))
    }

    /// The file the scene was loaded from.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// The warnings of the load and, once rendered, of the texture decoding: what the CLI
    /// prints as `warning: FILE: ...`.
    #[getter]
    fn warnings(&self) -> PyResult<Vec<String>> {
        let mut all = self.with_scene(|s| s.warnings.clone())?;
        if let Ok(kept) = self.prepare_warnings.lock() {
            all.extend(kept.iter().cloned());
        }
        Ok(all)
    }

    /// Renders one view; see `meshtracer.Scene.render` in `__init__.py` for the arguments.
    #[pyo3(signature = (width, height, *, spp=DEFAULT_SPP, integrator="direct", seed=0,
        bounces=DEFAULT_BOUNCES, exposure=0.0, camera=None, aovs=vec!["depth".to_string(), "mask".to_string()],
        srgb8=false, tonemap="standard", noise=None, clamp_indirect=None))]
    #[allow(clippy::too_many_arguments)]
    fn render<'py>(
        &self,
        py: Python<'py>,
        width: u32,
        height: u32,
        spp: u32,
        integrator: &str,
        seed: u64,
        bounces: u32,
        exposure: f32,
        camera: Option<usize>,
        aovs: Vec<String>,
        srgb8: bool,
        tonemap: &str,
        noise: Option<f32>,
        clamp_indirect: Option<f32>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let tonemap = ViewTransform::from_name(tonemap).ok_or_else(|| {
            let names: Vec<&str> = ViewTransform::ALL.iter().map(|v| v.name()).collect();
            Error::new_err(format!("tonemap '{tonemap}': use {}", names.join(", ")))
        })?;
        for (name, value) in [("noise", noise), ("clamp_indirect", clamp_indirect)] {
            if value.is_some_and(|v| !(v.is_finite() && v > 0.0)) {
                return Err(Error::new_err(format!("{name} must be a number above 0")));
            }
        }
        if width == 0 || height == 0 {
            return Err(Error::new_err(format!(
                "image size {width}x{height}: width and height must be at least 1"
            )));
        }
        if spp == 0 {
            return Err(Error::new_err("spp 0: must be at least 1"));
        }
        if !exposure.is_finite() {
            return Err(Error::new_err("exposure must be a finite number"));
        }
        let integrator = match integrator {
            "direct" => IntegratorKind::Direct,
            "path" => IntegratorKind::Path,
            other => {
                return Err(Error::new_err(format!(
                    "integrator '{other}': use 'direct' or 'path'"
                )))
            }
        };
        if let Some(unknown) = aovs.iter().find(|a| !AOV_NAMES.contains(&a.as_str())) {
            return Err(Error::new_err(format!(
                "aov '{unknown}': use {}",
                AOV_NAMES.join(", ")
            )));
        }
        let wants = |name: &str| aovs.iter().any(|a| a == name);
        let mut settings = self.with_scene(|scene| {
            settings_for(scene, &self.path, width, height, camera, integrator)
        })??;
        settings.spp = spp;
        settings.seed = seed;
        settings.bounces = bounces;
        settings.exposure = exposure;
        settings.noise = noise;
        settings.clamp_indirect = clamp_indirect;
        settings.aovs = wants("depth") || wants("normal") || wants("segmentation");
        let rays = setup::expected_rays(
            u64::from(width) * u64::from(height),
            settings.spp,
            settings.lights.len(),
            settings.integrator,
            settings.bounces,
        );
        let prepared = self.prepared(py, rays)?;
        let cancel = AtomicBool::new(false);
        let (image, _stats, rendered_aovs) = py
            .detach(|| render(&prepared, &settings, &cancel, &|_, _| {}))
            .map_err(cli_error)?;

        let (h, w) = (height as usize, width as usize);
        let out = PyDict::new(py);
        let color: Vec<f32> = image.pixels.iter().flat_map(|p| p.to_array()).collect();
        out.set_item("color", PyArray1::from_vec(py, color).reshape([h, w, 4])?)?;
        if srgb8 {
            let bytes = image.to_srgb8(None, tonemap);
            out.set_item("srgb8", PyArray1::from_vec(py, bytes).reshape([h, w, 4])?)?;
        }
        if wants("mask") {
            let mask: Vec<f32> = image.pixels.iter().map(|p| p.w).collect();
            out.set_item("mask", PyArray1::from_vec(py, mask).reshape([h, w])?)?;
        }
        if let Some(a) = rendered_aovs {
            if wants("depth") {
                out.set_item("depth", PyArray1::from_vec(py, a.depth).reshape([h, w])?)?;
            }
            if wants("normal") {
                let normal: Vec<f32> = a.normal.iter().flat_map(|n| n.to_array()).collect();
                out.set_item("normal", PyArray1::from_vec(py, normal).reshape([h, w, 3])?)?;
            }
            if wants("segmentation") {
                out.set_item(
                    "segmentation",
                    PyArray1::from_vec(py, a.instance).reshape([h, w])?,
                )?;
            }
        }
        Ok(out)
    }

    fn __repr__(&self) -> PyResult<String> {
        let triangles = self.with_scene(|s| s.soup.len())?;
        Ok(format!(
            "meshtracer.Scene('{}', {triangles} triangles)",
            self.path.display()
        ))
    }
}

/// The settings `meshtracer render MODEL --width W --height H [--camera I] [--integrator K]`
/// starts from: the file's camera `camera` (default its first; else the automatic camera
/// framing the bounds), lit as [`setup::lighting`] decides with no lighting option given.
fn settings_for(
    scene: &meshtracer::Scene,
    path: &std::path::Path,
    width: u32,
    height: u32,
    camera: Option<usize>,
    integrator: IntegratorKind,
) -> PyResult<RenderSettings> {
    let file_camera = match camera {
        Some(i) => Some(scene.cameras.get(i).ok_or_else(|| {
            Error::new_err(format!(
                "{}: --camera {i}: the file has {} camera(s)",
                path.display(),
                scene.cameras.len()
            ))
        })?),
        None => scene.cameras.first(),
    };
    let camera = match file_camera {
        Some(c) => c.clone(),
        None => auto_camera(&scene.bounds, &scene.soup.positions, width as f32 / height as f32),
    };
    let view = View::from_camera(&camera, width, height);
    let lit = setup::lighting(&scene.lights, None, &view, LightingOptions::new(integrator));
    Ok(RenderSettings {
        view,
        spp: DEFAULT_SPP,
        seed: 0,
        lights: lit.lights,
        ambient: lit.ambient,
        exposure: 0.0,
        shading: ShadingModel::Pbr,
        aovs: false,
        integrator,
        bounces: DEFAULT_BOUNCES,
        environment: lit.environment,
        environment_visible: false,
        noise: None,
        clamp_indirect: None,
    })
}

/// Loads a model (glTF, GLB or OBJ) as `meshtracer render` and `info` load it; see
/// `meshtracer.load` in `__init__.py`.
#[pyfunction]
#[pyo3(signature = (path, *, animation=None, time=None, variant=None, strict=false, allow_external_files=false))]
fn load(
    py: Python<'_>,
    path: PathBuf,
    animation: Option<String>,
    time: Option<f32>,
    variant: Option<String>,
    strict: bool,
    allow_external_files: bool,
) -> PyResult<PyScene> {
    let pose = PoseOptions { animation, time };
    pose.check().map_err(Error::new_err)?;
    let options = LoadOptions {
        allow_external_files,
        strict,
        variant,
        pose,
        ..LoadOptions::default()
    };
    let scene = py
        .detach(|| meshtracer::Scene::load_with(&path, &options))
        .map_err(cli_error)?;
    Ok(PyScene {
        path,
        strict,
        state: Mutex::new(State::Loaded(Box::new(scene))),
        prepare_warnings: Mutex::new(Vec::new()),
    })
}

#[pymodule]
fn _meshtracer(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Error", m.py().get_type::<Error>())?;
    m.add_class::<PyScene>()?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    Ok(())
}
