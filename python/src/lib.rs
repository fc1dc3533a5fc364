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

mod build;
mod progress;

use glam::{Vec2, Vec3, Vec4};
use meshtracer::accel::{AccelKind, BvhPreset};
use meshtracer::camera::{auto_camera, View};
use meshtracer::color::ViewTransform;
use meshtracer::defaults::{DEFAULT_BOUNCES, MAX_RENDER_PIXELS, MAX_SPP, MAX_TEXTURE_MIB};
use meshtracer::integrator::IntegratorKind;
use meshtracer::jobs::views::{
    parse_views, plan_cameras, read_views_file, ExplicitView, PlanOptions, ViewSpec, ViewsError,
};
use meshtracer::light::environment::Environment;
use meshtracer::output::dataset::{camera_to_world, Intrinsics};
use meshtracer::output::view_file::MAX_VIEW_BOUNCES;
use meshtracer::prepare::textures::TextureSet;
use meshtracer::prepare::{PrepareOptions, Prepared};
use meshtracer::render::{render, Region, RenderSettings};
use meshtracer::scene::{
    Camera, FileStamp, Light, LoadError, LoadOptions, MeshArrays, PoseOptions, Projection,
};
use meshtracer::setup::{self, LightingOptions};
use meshtracer::shading::ShadingModel;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::{PyException, PyFileNotFoundError, PyMemoryError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyType};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, Weak};

pyo3::create_exception!(
    meshtracer,
    Error,
    PyException,
    "A model that cannot be loaded or rendered: the message is the one the meshtracer CLI prints after `meshtracer: error: `."
);

/// `meshtracer.MissingFileError`, made when the module is imported. Its bases are `Error` and
/// the built-in `FileNotFoundError`, so that both `except meshtracer.Error` and `except
/// FileNotFoundError` (or `OSError`) catch a missing file. `create_exception!` takes one base,
/// so the class is made as Python makes one: `type(name, bases, namespace)`.
static MISSING_FILE_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();

/// The class [`MISSING_FILE_ERROR`] holds, made by the first call (the module's import).
fn missing_file_error_type(py: Python<'_>) -> PyResult<&Bound<'_, PyType>> {
    let made = MISSING_FILE_ERROR.get_or_try_init(py, || -> PyResult<Py<PyType>> {
        let namespace = PyDict::new(py);
        namespace.set_item("__module__", "meshtracer")?;
        namespace.set_item(
            "__doc__",
            "A file to read does not exist (the model, a buffer or, with strict=True, a \
             texture it refers to, or the panorama of `env`): both a meshtracer.Error, with \
             the CLI's message naming the file, and a FileNotFoundError.",
        )?;
        let bases = (py.get_type::<Error>(), py.get_type::<PyFileNotFoundError>());
        let class = py
            .get_type::<PyType>()
            .call1(("MissingFileError", bases, namespace))?;
        Ok(class.cast_into::<PyType>()?.unbind())
    })?;
    Ok(made.bind(py))
}

/// `message` as a [`MISSING_FILE_ERROR`] when `missing` (the file it names does not exist),
/// else as an `Error`.
fn file_error(py: Python<'_>, message: String, missing: bool) -> PyErr {
    if !missing {
        return Error::new_err(message);
    }
    match missing_file_error_type(py) {
        Ok(class) => PyErr::from_type(class.clone(), message),
        Err(e) => e,
    }
}

/// A load error as the CLI prints it (anyhow's alternate form, the error and its sources
/// joined by ": ", as `main.rs` prints `meshtracer: error: {e:#}`), a [`MISSING_FILE_ERROR`]
/// when a file it needs does not exist: the model, a buffer, or (with `strict=True`) a
/// texture ([`LoadError::missing_file`]); the message names that file.
fn load_error(py: Python<'_>, error: LoadError) -> PyErr {
    let missing = error.missing_file().is_some();
    file_error(py, format!("{:#}", anyhow::Error::from(error)), missing)
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
    /// Notified when a preparation ends (`State::Preparing` left).
    ready: Condvar,
    /// The warnings of the texture decoding (first render), after the load's.
    prepare_warnings: Mutex<Vec<String>>,
    /// How views of the cameras added from Python are made, where not as a file's camera's
    /// (`View::from_camera`), by camera index.
    lenses: Mutex<HashMap<usize, CameraLens>>,
    /// The last `env` panorama rendered with, turned and scaled, and what it was made from.
    environment: Mutex<Option<(EnvironmentKey, Arc<Environment>)>>,
    /// The decoded textures of another scene of the same file, alive when this one was loaded
    /// (the last pose of a loop over an animation's times), offered to this scene's
    /// preparation ([`live_textures`]).
    inherited: Mutex<Option<TextureSet>>,
}

/// The last scene prepared in this process, with the file it was loaded from; weakly, so that
/// it is freed when the program drops it.
static LAST_PREPARED: Mutex<Option<(PathBuf, Weak<Prepared>)>> = Mutex::new(None);

/// The decoded textures of the last scene prepared from `path`, if the program still holds it:
/// `for t in times: scene = meshtracer.load(path, time=t)` loads each pose while the last one
/// is still bound, and its images do not change with the pose. A preparation keeps them only
/// where decoding again would give the same (`TextureSet::load_reusing`: the files unchanged
/// on disk, the same images drawn), as the CLI's frames do.
fn live_textures(path: &Path) -> Option<TextureSet> {
    let last = LAST_PREPARED.lock().ok()?;
    let (last_path, prepared) = last.as_ref()?;
    (last_path == path)
        .then(|| prepared.upgrade())
        .flatten()
        .map(|p| p.textures.clone())
}

/// How the views of a camera added from Python are made.
#[derive(Clone, Copy, Debug)]
enum CameraLens {
    /// Pinhole intrinsics (fx, fy, cx, cy in pixels): kept in the scene as a perspective
    /// camera, given its intrinsics when a view is made of it.
    Intrinsics([f32; 4]),
    /// `stretch=True`: its aspectRatio or xmag kept whatever the image's aspect
    /// (`View::stretched_to`).
    Stretched,
}

/// What an `env` panorama was made from: the file (as it was on disk) and the transform.
#[derive(Clone, Debug, PartialEq)]
struct EnvironmentKey {
    path: PathBuf,
    /// The file as it was on disk (`None`: it could not be read).
    file: Option<FileStamp>,
    rotation_degrees: f32,
    intensity: f32,
}

/// A scene before, during and after its first render.
enum State {
    Loaded(Box<meshtracer::Scene>),
    /// A render is preparing the scene (moved into the preparation), the state's lock and
    /// the GIL released; every other call waits for it on `PyScene::ready`, the GIL released.
    Preparing,
    Prepared(Arc<Prepared>),
    /// The preparation failed with this message; the scene must be loaded again.
    Failed(String),
}

/// The error of a call that finds the scene still `Preparing` after waiting for it: cannot
/// happen ([`PyScene::settled`] waits), reported rather than panicking.
fn still_preparing() -> PyErr {
    Error::new_err("internal error: the scene is being prepared")
}

/// How often a call waiting for another thread's preparation checks for Ctrl-C.
const WAIT_POLL: std::time::Duration = std::time::Duration::from_millis(100);

impl PyScene {
    /// The prepared scene, preparing it now for about `rays` rays if no render has yet (the BVH
    /// preset `auto` picks for that work, as `render --bvh-preset auto` does). The lock on the
    /// state is held only to read and write it, never while preparing: the preparation runs
    /// with the GIL released, and a call from another thread meanwhile (a render, `info()`,
    /// `add_light`, ...) waits for it with the GIL released too and then uses it, so the scene
    /// is prepared once however many threads render it.
    fn prepared(&self, py: Python<'_>, rays: f64) -> PyResult<Arc<Prepared>> {
        let scene = {
            let mut state = self.settled(py)?;
            match std::mem::replace(&mut *state, State::Preparing) {
                State::Loaded(scene) => scene,
                State::Prepared(p) => {
                    *state = State::Prepared(Arc::clone(&p));
                    return Ok(p);
                }
                other => {
                    let error = match &other {
                        State::Failed(message) => self.failed_earlier(message),
                        _ => still_preparing(),
                    };
                    *state = other;
                    return Err(error);
                }
            }
        };
        let options = PrepareOptions {
            accel: AccelKind::Bvh,
            bvh_preset: BvhPreset::Auto.for_work(scene.soup.len(), rays),
            max_texture_bytes: MAX_TEXTURE_MIB.saturating_mul(1 << 20),
            strict: self.strict,
        };
        let mut warnings = Vec::new();
        let inherited = self.inherited.lock().ok().and_then(|mut i| i.take());
        let kept = inherited.or_else(|| live_textures(&self.path));
        // A panic must not leave the state `Preparing`: the waiting calls would wait forever.
        let outcome = py.detach(|| {
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                Prepared::build_reusing(*scene, &options, &mut warnings, &mut |_, _| {}, kept)
            }))
        });
        let result = match outcome {
            Ok(prepared) => prepared
                .map(Arc::new)
                .map_err(|e| format!("{:#}", anyhow::Error::from(e))),
            Err(panic) => Err(format!(
                "{}: internal error while preparing the scene (please report it): {}",
                self.path.display(),
                meshtracer::scene::panic_message(panic.as_ref())
            )),
        };
        if let Ok(mut kept) = self.prepare_warnings.lock() {
            kept.extend(warnings);
        }
        if let (Ok(p), Ok(mut last)) = (&result, LAST_PREPARED.lock()) {
            *last = Some((self.path.clone(), Arc::downgrade(p)));
        }
        let mut state = self.state.lock().unwrap_or_else(|p| p.into_inner());
        *state = match &result {
            Ok(p) => State::Prepared(Arc::clone(p)),
            Err(message) => State::Failed(message.clone()),
        };
        drop(state);
        self.ready.notify_all();
        result.map_err(Error::new_err)
    }

    fn lock(&self) -> PyResult<MutexGuard<'_, State>> {
        self.state
            .lock()
            .map_err(|_| Error::new_err("the scene was poisoned by a panic in an earlier call"))
    }

    /// The state once no preparation is under way, waiting for one (on another thread) to
    /// end with the GIL released: the preparing thread needs the GIL back to finish its call.
    /// The lock is taken with the GIL held only where no holder waits for the GIL: nothing
    /// done under it calls Python.
    fn settled(&self, py: Python<'_>) -> PyResult<MutexGuard<'_, State>> {
        loop {
            let state = self.lock()?;
            if !matches!(*state, State::Preparing) {
                return Ok(state);
            }
            drop(state);
            py.detach(|| {
                if let Ok(state) = self.state.lock() {
                    let preparing = |s: &mut State| matches!(s, State::Preparing);
                    drop(self.ready.wait_timeout_while(state, WAIT_POLL, preparing));
                }
            });
            py.check_signals()?;
        }
    }

    /// Runs `f` on the scene as loaded (or as prepared).
    fn with_scene<T>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&meshtracer::Scene) -> T,
    ) -> PyResult<T> {
        match &*self.settled(py)? {
            State::Loaded(scene) => Ok(f(scene)),
            State::Prepared(p) => Ok(f(&p.scene)),
            State::Failed(message) => Err(self.failed_earlier(message)),
            State::Preparing => Err(still_preparing()),
        }
    }

    /// Runs `f` on the scene to change it: a prepared scene goes back to its loaded form (the
    /// next render prepares it again, BVH and all).
    fn with_scene_mut<T>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut meshtracer::Scene) -> T,
    ) -> PyResult<T> {
        let mut state = self.settled(py)?;
        if let State::Prepared(p) = &*state {
            let scene = p.scene.clone();
            *state = State::Loaded(Box::new(scene));
        }
        match &mut *state {
            State::Loaded(scene) => Ok(f(scene)),
            State::Failed(message) => Err(self.failed_earlier(message)),
            _ => Err(still_preparing()),
        }
    }

    /// Runs `f` on the scene to change only its cameras or lights, which its preparation does
    /// not depend on: a prepared scene stays prepared unless a render still holds it.
    fn with_views_mut<T>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut meshtracer::Scene) -> T,
    ) -> PyResult<T> {
        {
            let mut state = self.settled(py)?;
            if let State::Prepared(p) = &mut *state {
                if let Some(p) = Arc::get_mut(p) {
                    return Ok(f(&mut p.scene));
                }
            }
        }
        self.with_scene_mut(py, f)
    }

    /// The error of every call after a preparation that failed with `message`.
    fn failed_earlier(&self, message: &str) -> PyErr {
        Error::new_err(format!(
            "{}: an earlier preparation of this scene failed: load it again ({message})",
            self.path.display()
        ))
    }

    fn new(path: PathBuf, strict: bool, scene: meshtracer::Scene) -> PyScene {
        PyScene {
            path,
            strict,
            state: Mutex::new(State::Loaded(Box::new(scene))),
            ready: Condvar::new(),
            prepare_warnings: Mutex::new(Vec::new()),
            lenses: Mutex::new(HashMap::new()),
            environment: Mutex::new(None),
            inherited: Mutex::new(None),
        }
    }

    /// The `env` panorama of `o`, turned by `env_rotation` and scaled by `env_intensity` as the
    /// CLI's `--env` is; `None` without one. Loaded once and kept while the file (its length
    /// and modification time) and the transform stay the same: rendering many frames lit by
    /// one large EXR reads it once.
    fn environment(&self, py: Python<'_>, o: &RenderOptions) -> PyResult<Option<Arc<Environment>>> {
        let Some(path) = &o.env else {
            return Ok(None);
        };
        let stamp = FileStamp::of(path);
        let missing = matches!(&stamp, Err(e) if e.kind() == std::io::ErrorKind::NotFound);
        let key = EnvironmentKey {
            path: path.clone(),
            file: stamp.ok(),
            rotation_degrees: o.env_rotation,
            intensity: o.env_intensity,
        };
        let mut kept = self
            .environment
            .lock()
            .map_err(|_| Error::new_err("the scene was poisoned by a panic in an earlier call"))?;
        if let Some((k, env)) = &*kept {
            if *k == key {
                return Ok(Some(Arc::clone(env)));
            }
        }
        let env = Environment::load(path)
            .map_err(|e| file_error(py, e.to_string(), missing))?
            .with_transform(o.env_rotation, o.env_intensity);
        let env = Arc::new(env);
        *kept = Some((key, Arc::clone(&env)));
        Ok(Some(env))
    }

    /// The view of camera `camera` (default the first; else the automatic camera framing the
    /// bounds) for a `width` x `height` image, with its intrinsics or stretch if it was added with them.
    fn view(
        &self,
        py: Python<'_>,
        camera: Option<usize>,
        width: u32,
        height: u32,
    ) -> PyResult<View> {
        let chosen = self.with_scene(py, |scene| -> PyResult<Camera> {
            let file_camera = match camera {
                Some(i) => Some(scene.cameras.get(i).ok_or_else(|| {
                    Error::new_err(format!(
                        "{}: camera {i}: the file has {} camera(s)",
                        self.path.display(),
                        scene.cameras.len()
                    ))
                })?),
                None => scene.cameras.first(),
            };
            Ok(match file_camera {
                Some(c) => c.clone(),
                None => auto_camera(
                    &scene.bounds,
                    &scene.soup.positions,
                    width as f32 / height as f32,
                ),
            })
        })??;
        let view = View::from_camera(&chosen, width, height);
        self.with_lens(camera.unwrap_or(0), &chosen, view)
    }

    /// `view` with the depth of field of `aperture_radius`, focused at `focus_distance`, else
    /// at the view-axis depth of `look_at`, else of the scene's centre (`render
    /// --aperture-radius`); `which` names the view in an error ("the camera", "view 2").
    fn with_thin_lens(
        &self,
        py: Python<'_>,
        view: View,
        o: &RenderOptions,
        look_at: Option<Vec3>,
        which: &str,
    ) -> PyResult<View> {
        let Some(aperture_radius) = o.aperture_radius else {
            return Ok(view);
        };
        let focus_distance = match o.focus_distance {
            Some(f) => f,
            None => {
                let target = match look_at {
                    Some(at) => at,
                    None => self.with_scene(py, |scene| scene.bounds.center())?,
                };
                view.depth_of(target).ok_or_else(|| {
                    Error::new_err(format!(
                        "aperture_radius: the point to focus on (the view's look_at, else the \
                         scene's centre) is not in front of {which}: give focus_distance"
                    ))
                })?
            }
        };
        Ok(view.with_thin_lens(meshtracer::camera::ThinLens {
            aperture_radius,
            focus_distance,
        }))
    }

    /// `view`, made by `View::from_camera` of `camera` (the scene's camera `index`), with the
    /// intrinsics or stretch that camera was added with, if any.
    fn with_lens(&self, index: usize, camera: &Camera, view: View) -> PyResult<View> {
        let lens = self
            .lenses
            .lock()
            .map_err(|_| Error::new_err("the scene was poisoned by a panic in an earlier call"))?
            .get(&index)
            .copied();
        Ok(match lens {
            Some(CameraLens::Intrinsics([fx, fy, cx, cy])) => view.with_intrinsics(fx, fy, cx, cy),
            Some(CameraLens::Stretched) => view.stretched_to(camera),
            None => view,
        })
    }

    /// The settings of one view: `view` lit as [`setup::lighting`] decides, the rig (when the
    /// scene has no lights) placed for `rig_view`.
    fn settings(
        &self,
        py: Python<'_>,
        view: View,
        rig_view: &View,
        o: &RenderOptions,
    ) -> PyResult<RenderSettings> {
        let denoised = o.denoises();
        let (spp, noise) = setup::sampling(o.integrator, o.spp, o.noise, false, denoised);
        // As the CLI: the count checked is the one the render takes, the adaptive default's
        // most included.
        if spp == 0 || spp > o.max_spp {
            return Err(Error::new_err(format!(
                "spp {spp}: must be between 1 and {} (raise the limit with max_spp)",
                o.max_spp
            )));
        }
        let mut lighting_options = LightingOptions::new(o.integrator);
        lighting_options.no_default_lights = !o.default_lights;
        lighting_options.environment = self.environment(py, o)?;
        lighting_options.studio_rotation_degrees = o.env_rotation;
        lighting_options.studio_intensity = o.env_intensity;
        let lit = self.with_scene(py, |scene| {
            setup::lighting(&scene.lights, None, rig_view, lighting_options)
        })?;
        Ok(RenderSettings {
            view,
            spp,
            seed: o.seed,
            lights: lit.lights,
            ambient: o.ambient.unwrap_or(lit.ambient),
            exposure: o.exposure,
            shading: ShadingModel::Pbr,
            aovs: o.wants("depth") || o.wants("normal") || o.wants("segmentation"),
            integrator: o.integrator,
            bounces: o.bounces,
            environment: lit.environment,
            environment_visible: o.env_visible,
            noise,
            clamp_indirect: o.clamp_indirect,
            // The path tracer averages the denoiser's guides from its own samples.
            guides: denoised,
        })
    }

    /// Renders every view of `views` with one preparation of the scene (the BVH preset chosen
    /// for the rays of all of them), reporting tiles over all views to `progress`.
    fn render_settings<'py>(
        &self,
        py: Python<'py>,
        views: &[RenderSettings],
        o: &RenderOptions,
        progress: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let rays: f64 = views
            .iter()
            .map(|s| {
                setup::expected_rays(
                    u64::from(s.view.width) * u64::from(s.view.height),
                    s.spp,
                    s.noise.map(|_| s.first_batch()),
                    s.lights.len(),
                    s.integrator,
                    s.bounces,
                )
            })
            .sum();
        check_memory(views, o)?;
        let prepared = self.prepared(py, rays)?;
        let rendered = progress::run_cancellable(py, progress, |cancel, report| {
            let count = views.len() as u64;
            let mut out = Vec::with_capacity(views.len());
            for (k, settings) in views.iter().enumerate() {
                let k = k as u64;
                // Tiles of view k count after those of the views before it.
                let per_view = |done: u64, total: u64| report(k * total + done, count * total);
                let (mut image, stats, aovs) = render(&prepared, settings, cancel, &per_view)?;
                let denoise_seconds = if o.denoises() {
                    Some(denoise(&prepared, settings, &mut image)?)
                } else {
                    None
                };
                out.push((image, stats, aovs, denoise_seconds));
            }
            Ok(out)
        })?
        .map_err(|e: Failed| match e {
            Failed::Cancelled => Error::new_err("the render was cancelled"),
            Failed::Denoise(message) => Error::new_err(message),
        })?;
        rendered
            .into_iter()
            .zip(views)
            .map(|((image, stats, aovs, denoise_seconds), settings)| {
                let out = arrays(py, &settings.view, &image, aovs, o)?;
                let numbers = PyDict::new(py);
                numbers.set_item("render_seconds", stats.time.as_secs_f64())?;
                numbers.set_item("primary_rays", stats.primary_rays)?;
                numbers.set_item("shadow_rays", stats.shadow_rays)?;
                numbers.set_item("indirect_rays", stats.indirect_rays)?;
                numbers.set_item("denoise_seconds", denoise_seconds)?;
                numbers.set_item("textures_kept", prepared.textures.reused())?;
                out.set_item("stats", numbers)?;
                Ok(out)
            })
            .collect()
    }
}

/// Why a render ended without its images.
enum Failed {
    /// Ctrl-C or the progress callback.
    Cancelled,
    /// The denoiser refused (its message).
    Denoise(String),
}

impl From<meshtracer::render::Cancelled> for Failed {
    fn from(_: meshtracer::render::Cancelled) -> Failed {
        Failed::Cancelled
    }
}

/// Denoises `image` with the built-in filter, as `meshtracer render` does: the guides the path
/// tracer averaged from its samples, else (the direct integrator) traced ones. Returns the
/// seconds it took.
fn denoise(
    prepared: &Prepared,
    settings: &RenderSettings,
    image: &mut meshtracer::render::Image,
) -> Result<f64, Failed> {
    let start = std::time::Instant::now();
    let guides = match image.guides.take() {
        Some(guides) => guides,
        None => meshtracer::render::denoise::guides(
            prepared,
            settings,
            Region::full(settings.view.width, settings.view.height),
        ),
    };
    meshtracer::render::denoise::denoise(image, guides)
        .map_err(|e| Failed::Denoise(e.to_string()))?;
    Ok(start.elapsed().as_secs_f64())
}

/// The options every render takes, checked.
struct RenderOptions {
    /// Exactly this many samples per pixel; `None` for the CLI's default
    /// ([`setup::sampling`]).
    spp: Option<u32>,
    integrator: IntegratorKind,
    seed: u64,
    bounces: u32,
    exposure: f32,
    aovs: Vec<String>,
    srgb8: bool,
    tonemap: ViewTransform,
    noise: Option<f32>,
    clamp_indirect: Option<f32>,
    ambient: Option<Vec3>,
    default_lights: bool,
    /// `--env`, `--env-rotation` (degrees), `--env-intensity`, `--env-visible`.
    env: Option<PathBuf>,
    env_rotation: f32,
    env_intensity: f32,
    env_visible: bool,
    /// `--max-pixels`, `--max-spp`: the largest image and sample count accepted.
    max_pixels: u64,
    max_spp: u32,
    /// Denoise each view with the built-in filter; `None` until [`RenderOptions::for_views`]
    /// decides as the CLI does ([`setup::denoises_by_default`]).
    denoise: Option<bool>,
    /// `--aperture-radius`, `--focus-distance`: depth of field (`render` only).
    aperture_radius: Option<f32>,
    focus_distance: Option<f32>,
}

impl RenderOptions {
    /// These options for a `single_image` render (`Scene.render`) or views (`render_views`):
    /// unless `denoise` was given, a single image with the path tracer's default sampling is
    /// denoised (the CLI's default render), views are not (as `meshtracer render --views`).
    fn resolved(mut self, single_image: bool) -> RenderOptions {
        self.denoise = Some(self.denoise.unwrap_or_else(|| {
            setup::denoises_by_default(self.integrator, self.spp, self.noise, false, single_image)
        }));
        self
    }

    fn denoises(&self) -> bool {
        self.denoise == Some(true)
    }

    fn wants(&self, name: &str) -> bool {
        self.aovs.iter().any(|a| a == name)
    }
}

/// Refuses the view options `render --views` refuses (its `check_image_options` and
/// `check_orbit_options`), with the CLI's messages naming the Python arguments.
fn check_plan_options(spec: &ViewSpec, options: &PlanOptions) -> PyResult<()> {
    let refuse = |message: String| Err(Error::new_err(message));
    if let Some(yfov) = options.yfov_degrees.filter(|y| !(*y > 0.0 && *y < 180.0)) {
        return refuse(format!("yfov {yfov}: must be between 0 and 180 degrees"));
    }
    if let Some(at) = options.look_at.filter(|v| !v.is_finite()) {
        return refuse(format!(
            "look_at [{}, {}, {}]: must be three finite numbers",
            at.x, at.y, at.z
        ));
    }
    if let Some(e) = options
        .orbit_elevation
        .filter(|e| !(-90.0..=90.0).contains(e))
    {
        return refuse(format!(
            "orbit_elevation {e}: must be between -90 and 90 degrees"
        ));
    }
    if let Some(r) = options
        .orbit_radius
        .filter(|r| !(*r > 0.0 && r.is_finite()))
    {
        return refuse(format!("orbit_radius {r}: must be a positive distance"));
    }
    if let Some(a) = options.orbit_azimuth {
        if !a.is_finite() {
            return refuse(format!(
                "orbit_azimuth {a}: must be a finite number of degrees"
            ));
        }
        if !matches!(spec, ViewSpec::Orbit(_)) {
            return refuse(
                "orbit_azimuth: only orbits (render_views(\"orbit:N\", ...)) have a starting azimuth"
                    .to_string(),
            );
        }
    }
    Ok(())
}

/// Refuses a size the CLI refuses.
fn check_size(width: i128, height: i128, max_pixels: u64) -> PyResult<(u32, u32)> {
    if width < 1 || height < 1 {
        return Err(Error::new_err(format!(
            "image size {width}x{height}: width and height must be at least 1"
        )));
    }
    let pixels = (width as u128).saturating_mul(height as u128);
    match (u32::try_from(width), u32::try_from(height)) {
        (Ok(w), Ok(h)) if pixels <= u128::from(max_pixels) => Ok((w, h)),
        _ => Err(Error::new_err(format!(
            "image size {width}x{height} is {pixels} pixels, over the limit of {max_pixels} \
             (raise it with max_pixels)"
        ))),
    }
}

/// A camera index given from Python: an error naming it when it is negative or beyond any
/// file's cameras.
fn camera_index(camera: Option<i128>) -> PyResult<Option<usize>> {
    camera
        .map(|i| {
            usize::try_from(i).map_err(|_| {
                Error::new_err(if i < 0 {
                    format!("camera {i}: indices count from 0")
                } else {
                    format!("camera {i}: no file has that many cameras")
                })
            })
        })
        .transpose()
}

/// The unsigned integer types of whole-number keyword options, with their largest value.
trait WholeNumber: TryFrom<i128> {
    const LARGEST: u128;
}

impl WholeNumber for u32 {
    const LARGEST: u128 = u32::MAX as u128;
}

impl WholeNumber for u64 {
    const LARGEST: u128 = u64::MAX as u128;
}

/// A whole-number keyword option (`spp`, `seed`...): a negative or too large number is an
/// error naming the option and the number, not Python's bare `OverflowError`.
fn whole<T: WholeNumber>(key: &str, value: &Bound<'_, PyAny>) -> PyResult<T> {
    let number: i128 = value
        .extract()
        .map_err(|e| Error::new_err(format!("{key}: {e}")))?;
    T::try_from(number).map_err(|_| {
        Error::new_err(format!(
            "{key} {number}: must be a whole number from 0 to {}",
            T::LARGEST
        ))
    })
}

/// [`whole`], or `None` for Python's `None`.
fn whole_or_none<T: WholeNumber>(key: &str, value: &Bound<'_, PyAny>) -> PyResult<Option<T>> {
    if value.is_none() {
        return Ok(None);
    }
    whole(key, value).map(Some)
}

/// Bytes a pixel of each view holds until the call returns: the film (RGBA and variance, 20),
/// the AOVs (depth, normal, instance: 20) and the arrays handed to Python (colour 16, mask,
/// srgb8, normal).
fn bytes_kept_per_pixel(settings: &RenderSettings, o: &RenderOptions) -> u64 {
    let aovs = if settings.aovs { 20 } else { 0 };
    let mask = if o.wants("mask") { 4 } else { 0 };
    let srgb8 = if o.srgb8 { 8 } else { 0 };
    let normal = if o.wants("normal") { 12 } else { 0 };
    20 + aovs + 16 + mask + srgb8 + normal
}

/// Bytes a pixel of one view needs while it is rendered and denoised, besides what it keeps:
/// the denoiser's guides (albedo, normal, depth, visibility, emission: 44) and its planes.
const DENOISE_BYTES_PER_PIXEL: u64 = 44 + 96;

/// Refuses, with a `MemoryError` naming the image size and the bytes, renders whose film,
/// AOVs and arrays could not be allocated (the library allocates them infallibly: a failed
/// allocation would abort the Python process). The estimate is reserved and freed at once
/// (`Vec::try_reserve_exact`: the pages are never touched), so the system's own refusal
/// decides, as it would for the render's allocations.
fn check_memory(views: &[RenderSettings], o: &RenderOptions) -> PyResult<()> {
    let mut bytes = 0u64;
    let mut transient = 0u64;
    for settings in views {
        let pixels = u64::from(settings.view.width) * u64::from(settings.view.height);
        let kept = pixels.saturating_mul(bytes_kept_per_pixel(settings, o));
        bytes = bytes.saturating_add(kept);
        if o.denoises() {
            transient = transient.max(pixels.saturating_mul(DENOISE_BYTES_PER_PIXEL));
        }
    }
    let bytes = bytes.saturating_add(transient);
    let reserved = usize::try_from(bytes)
        .ok()
        .is_some_and(|n| Vec::<u8>::new().try_reserve_exact(n).is_ok());
    if reserved {
        return Ok(());
    }
    let size = match views {
        [one] => format!("image size {}x{}", one.view.width, one.view.height),
        [first, ..] => format!(
            "{} views of {}x{}",
            views.len(),
            first.view.width,
            first.view.height
        ),
        [] => "no view".to_string(),
    };
    Err(PyMemoryError::new_err(format!(
        "{size}: the film, AOVs and arrays need about {:.1} GiB ({bytes} bytes), which cannot \
         be allocated",
        bytes as f64 / f64::from(1u32 << 30)
    )))
}

/// The arrays of one rendered view (docs/python.md has the table).
fn arrays<'py>(
    py: Python<'py>,
    view: &View,
    image: &meshtracer::render::Image,
    rendered_aovs: Option<meshtracer::render::Aovs>,
    o: &RenderOptions,
) -> PyResult<Bound<'py, PyDict>> {
    let (h, w) = (view.height as usize, view.width as usize);
    let out = PyDict::new(py);
    let color: Vec<f32> = image.pixels.iter().flat_map(|p| p.to_array()).collect();
    out.set_item("color", PyArray1::from_vec(py, color).reshape([h, w, 4])?)?;
    if o.srgb8 {
        let bytes = image.to_srgb8(None, o.tonemap);
        out.set_item("srgb8", PyArray1::from_vec(py, bytes).reshape([h, w, 4])?)?;
    }
    if o.wants("mask") {
        let mask: Vec<f32> = image.pixels.iter().map(|p| p.w).collect();
        out.set_item("mask", PyArray1::from_vec(py, mask).reshape([h, w])?)?;
    }
    if let Some(a) = rendered_aovs {
        if o.wants("depth") {
            out.set_item("depth", PyArray1::from_vec(py, a.depth).reshape([h, w])?)?;
        }
        if o.wants("normal") {
            let normal: Vec<f32> = a.normal.iter().flat_map(|n| n.to_array()).collect();
            out.set_item("normal", PyArray1::from_vec(py, normal).reshape([h, w, 3])?)?;
        }
        if o.wants("segmentation") {
            out.set_item(
                "segmentation",
                PyArray1::from_vec(py, a.instance).reshape([h, w])?,
            )?;
        }
    }
    Ok(out)
}

#[pymethods]
impl PyScene {
    /// What `meshtracer info --json` prints about the model, as a dict.
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let text = self.with_scene(py, |s| s.info_json().to_string())?;
        py.import("json")?.call_method1("loads", (text,))
    }

    /// The file the scene was loaded from (for a scene built from arrays, its name).
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// The warnings of the load and, once rendered, of the texture decoding: what the CLI
    /// prints as `warning: FILE: ...`.
    #[getter]
    fn warnings(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        let mut all = self.with_scene(py, |s| s.warnings.clone())?;
        if let Ok(kept) = self.prepare_warnings.lock() {
            all.extend(kept.iter().cloned());
        }
        Ok(all)
    }

    /// An empty scene named `name`; see `meshtracer.Scene.from_arrays` in `__init__.py`.
    #[staticmethod]
    fn empty(name: PathBuf) -> PyScene {
        let scene = meshtracer::Scene::empty(name.clone());
        PyScene::new(name, false, scene)
    }

    /// Adds a mesh from float32/uint32 arrays the Python side converted and shaped; see
    /// `meshtracer.Scene.add_mesh` in `__init__.py`.
    #[pyo3(signature = (positions, indices, normals=None, uvs=None, colors=None, material=None, pose=None, name=None, uvs1=None))]
    #[allow(clippy::too_many_arguments)]
    fn _add_mesh(
        &self,
        py: Python<'_>,
        positions: PyReadonlyArray2<'_, f32>,
        indices: PyReadonlyArray2<'_, u32>,
        normals: Option<PyReadonlyArray2<'_, f32>>,
        uvs: Option<PyReadonlyArray2<'_, f32>>,
        colors: Option<PyReadonlyArray2<'_, f32>>,
        material: Option<Bound<'_, PyDict>>,
        pose: Option<[f32; 16]>,
        name: Option<String>,
        uvs1: Option<PyReadonlyArray2<'_, f32>>,
    ) -> PyResult<usize> {
        let mesh = MeshArrays {
            positions: build::rows::<Vec3, 3>("positions", &positions)?,
            indices: build::triangles(&indices)?,
            normals: normals
                .as_ref()
                .map(|a| build::rows::<Vec3, 3>("normals", a))
                .transpose()?,
            uv0: uvs
                .as_ref()
                .map(|a| build::rows::<Vec2, 2>("uvs", a))
                .transpose()?,
            uv1: uvs1
                .as_ref()
                .map(|a| build::rows::<Vec2, 2>("uvs1", a))
                .transpose()?,
            colors: colors
                .as_ref()
                .map(|a| build::rows::<Vec4, 4>("colors", a))
                .transpose()?,
        };
        let material = build::material(material.as_ref())?;
        let pose = build::pose(pose);
        self.with_scene_mut(py, |scene| scene.add_mesh(&mesh, material, pose, name))?
            .map_err(|e| Error::new_err(format!("{}: {e}", self.path.display())))
    }

    /// Adds a texture from a C-contiguous uint8 H x W x 4 array (RGBA, rows from the top) that
    /// the Python side converted; see `meshtracer.Scene.add_texture` in `__init__.py`.
    #[pyo3(signature = (pixels, wrap_s, wrap_t, mag_filter, min_filter, name=None))]
    #[allow(clippy::too_many_arguments)]
    fn _add_texture(
        &self,
        py: Python<'_>,
        pixels: PyReadonlyArray3<'_, u8>,
        wrap_s: &str,
        wrap_t: &str,
        mag_filter: &str,
        min_filter: &str,
        name: Option<String>,
    ) -> PyResult<usize> {
        let shape = pixels.shape();
        let (height, width) = (shape[0], shape[1]);
        if shape[2] != 4 {
            return Err(Error::new_err(format!(
                "texture: shape {shape:?}, expected (H, W, 4)"
            )));
        }
        let fits = |n: usize| u32::try_from(n).ok();
        let (Some(width), Some(height)) = (fits(width), fits(height)) else {
            return Err(Error::new_err(format!(
                "texture: {width}x{height} pixels is too large"
            )));
        };
        let rgba = pixels
            .as_slice()
            .map_err(|_| Error::new_err("texture: not a contiguous array"))?
            .to_vec();
        let sampler = build::sampler(wrap_s, wrap_t, mag_filter, min_filter)?;
        self.with_scene_mut(py, |scene| {
            scene.add_texture(width, height, rgba, sampler, name)
        })?
        .map_err(|e| Error::new_err(format!("{}: {e}", self.path.display())))
    }

    /// Adds a camera; see `meshtracer.Scene.add_camera` in `__init__.py`.
    #[pyo3(signature = (pose, *, yfov=None, aspect_ratio=None, xmag=None, ymag=None, fx=None,
        fy=None, cx=None, cy=None, znear=0.05, zfar=None, stretch=false, name=None))]
    #[allow(clippy::too_many_arguments)]
    fn add_camera(
        &self,
        py: Python<'_>,
        pose: [f32; 16],
        yfov: Option<f32>,
        aspect_ratio: Option<f32>,
        xmag: Option<f32>,
        ymag: Option<f32>,
        fx: Option<f32>,
        fy: Option<f32>,
        cx: Option<f32>,
        cy: Option<f32>,
        znear: f32,
        zfar: Option<f32>,
        stretch: bool,
        name: Option<String>,
    ) -> PyResult<usize> {
        let positive = |what: &str, v: f32| {
            if v.is_finite() && v > 0.0 {
                Ok(v)
            } else {
                Err(Error::new_err(format!(
                    "camera {what} {v}: must be a number above 0"
                )))
            }
        };
        positive("znear", znear)?;
        if let Some(far) = zfar {
            if positive("zfar", far)? <= znear {
                return Err(Error::new_err(format!(
                    "camera zfar {far}: must be beyond znear {znear}"
                )));
            }
        }
        let mut lens = stretch.then_some(CameraLens::Stretched);
        let projection = match (yfov, xmag.zip(ymag), fx.zip(fy).zip(cx.zip(cy))) {
            (Some(yfov), None, None) if yfov < std::f32::consts::PI => Projection::Perspective {
                yfov: positive("yfov", yfov)?,
                aspect_ratio: aspect_ratio
                    .map(|a| positive("aspect_ratio", a))
                    .transpose()?,
                znear,
                zfar,
            },
            (None, Some((xmag, ymag)), None) => Projection::Orthographic {
                xmag: positive("xmag", xmag)?,
                ymag: positive("ymag", ymag)?,
                znear,
                zfar: zfar.unwrap_or(f32::INFINITY),
            },
            (None, None, Some(((fx, fy), (cx, cy)))) => {
                let (fx, fy) = (positive("fx", fx)?, positive("fy", fy)?);
                if !(cx.is_finite() && cy.is_finite()) {
                    return Err(Error::new_err("camera cx, cy: must be finite numbers"));
                }
                if stretch {
                    return Err(Error::new_err(
                        "camera stretch: intrinsics say the picture exactly; stretch is for \
                         yfov with aspect_ratio, or xmag and ymag",
                    ));
                }
                lens = Some(CameraLens::Intrinsics([fx, fy, cx, cy]));
                // Kept as the perspective camera an image of 2·cy rows would have (what
                // info() shows); every view of it is made from the intrinsics.
                Projection::Perspective {
                    yfov: 2.0 * (cy.abs().max(0.5) / fy).atan(),
                    aspect_ratio: None,
                    znear,
                    zfar,
                }
            }
            _ => {
                return Err(Error::new_err(
                    "a camera is given by yfov (perspective, below pi), by xmag and ymag \
                     (orthographic), or by fx, fy, cx and cy (intrinsics): exactly one of them",
                ))
            }
        };
        let camera = Camera::from_pose(build::pose(Some(pose)), projection, name)
            .ok_or_else(|| Error::new_err("camera pose: not finite, or it collapses -Z or +Y"))?;
        let index = self.with_views_mut(py, |scene| {
            scene.cameras.push(camera);
            scene.cameras.len() - 1
        })?;
        if let Some(lens) = lens {
            if let Ok(mut map) = self.lenses.lock() {
                map.insert(index, lens);
            }
        }
        Ok(index)
    }

    /// Adds a punctual light; see `meshtracer.Scene.add_light` in `__init__.py`.
    #[pyo3(signature = (kind, pose, *, color=[1.0, 1.0, 1.0], intensity=1.0, range=None,
        inner_cone_angle=0.0, outer_cone_angle=std::f32::consts::FRAC_PI_4, name=None))]
    #[allow(clippy::too_many_arguments)]
    fn add_light(
        &self,
        py: Python<'_>,
        kind: &str,
        pose: [f32; 16],
        color: [f32; 3],
        intensity: f32,
        range: Option<f32>,
        inner_cone_angle: f32,
        outer_cone_angle: f32,
        name: Option<String>,
    ) -> PyResult<usize> {
        let kind = build::light_kind(kind, inner_cone_angle, outer_cone_angle)?;
        if color.iter().any(|c| !(c.is_finite() && *c >= 0.0)) {
            return Err(Error::new_err(format!(
                "light color {color:?}: must be finite numbers of at least 0"
            )));
        }
        // KHR_lights_punctual: a range, when given, is above 0 (None is no range window).
        if let Some(r) = range.filter(|r| r.is_nan() || *r <= 0.0) {
            return Err(Error::new_err(format!(
                "light range {r}: must be above 0 (or None for no range)"
            )));
        }
        let light = Light::from_pose(
            kind,
            Vec3::from(color),
            intensity,
            range,
            build::pose(Some(pose)),
            name,
        )
        .ok_or_else(|| {
            Error::new_err(format!(
                "light: intensity {intensity} must be a finite number of at least 0, and the pose finite"
            ))
        })?;
        self.with_views_mut(py, |scene| {
            scene.lights.push(light);
            scene.lights.len() - 1
        })
    }

    /// Removes every camera (the file's too); the scene stays prepared.
    fn clear_cameras(&self, py: Python<'_>) -> PyResult<()> {
        self.with_views_mut(py, |scene| scene.cameras.clear())?;
        if let Ok(mut map) = self.lenses.lock() {
            map.clear();
        }
        Ok(())
    }

    /// Removes every light (the file's too); the scene stays prepared. Without lights it is
    /// lit as a file without lights is (the default rig, unless `default_lights=False`).
    fn clear_lights(&self, py: Python<'_>) -> PyResult<()> {
        self.with_views_mut(py, |scene| scene.lights.clear())
    }

    /// Renders one view; see `meshtracer.Scene.render` in `__init__.py` for the arguments.
    #[pyo3(signature = (width, height, *, camera=None, progress=None, **options))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        width: i128,
        height: i128,
        camera: Option<i128>,
        progress: Option<Bound<'py, PyAny>>,
        options: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let o = RenderOptions::from_kwargs(options)?.resolved(true);
        let (width, height) = check_size(width, height, o.max_pixels)?;
        let view = self.view(py, camera_index(camera)?, width, height)?;
        let view = self.with_thin_lens(py, view, &o, None, "the camera")?;
        let settings = self.settings(py, view.clone(), &view, &o)?;
        let mut out = self.render_settings(py, &[settings], &o, progress.as_ref())?;
        out.pop()
            .ok_or_else(|| Error::new_err("internal error: no view was rendered"))
    }

    /// Renders many views after one preparation; see `meshtracer.Scene.render_views` in
    /// `__init__.py` for the arguments.
    #[pyo3(signature = (spec, width, height, *, views_json=None, yfov=None, look_at=None,
        orbit_radius=None, orbit_azimuth=None, orbit_elevation=None, progress=None, **options))]
    #[allow(clippy::too_many_arguments)]
    fn render_views<'py>(
        &self,
        py: Python<'py>,
        spec: &str,
        width: i128,
        height: i128,
        views_json: Option<&str>,
        yfov: Option<f32>,
        look_at: Option<[f32; 3]>,
        orbit_radius: Option<f32>,
        orbit_azimuth: Option<f32>,
        orbit_elevation: Option<f32>,
        progress: Option<Bound<'py, PyAny>>,
        options: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let o = RenderOptions::from_kwargs(options)?.resolved(false);
        let (width, height) = check_size(width, height, o.max_pixels)?;
        let views_error = |e: ViewsError| Error::new_err(e.to_string());
        let (parsed, explicit) = match views_json {
            Some(text) => (
                ViewSpec::File(PathBuf::from("<views>")),
                parse_views(text).map_err(views_error)?,
            ),
            None => match ViewSpec::parse(spec).map_err(views_error)? {
                ViewSpec::File(path) => {
                    let explicit = read_views_file(&path).map_err(views_error)?;
                    (ViewSpec::File(path), explicit)
                }
                other => (other, Vec::new()),
            },
        };
        let options = PlanOptions {
            yfov_degrees: yfov,
            look_at: look_at.map(Vec3::from),
            orbit_radius,
            orbit_azimuth,
            orbit_elevation,
            seed: o.seed,
        };
        check_plan_options(&parsed, &options)?;
        let aspect = width as f32 / height as f32;
        let (cameras, front) = self
            .with_scene(py, |scene| {
                plan_cameras(&parsed, &explicit, scene, aspect, &options)
                    .map(|c| (c, auto_camera(&scene.bounds, &scene.soup.positions, aspect)))
            })?
            .map_err(views_error)?;
        // As `render --views`: the lights stay put from view to view, the default rig placed
        // for the automatic camera.
        let front = View::from_camera(&front, width, height);
        // The file's cameras (`cameras`: camera i is the scene's camera i) keep the
        // intrinsics or stretch they were added with, as `render(camera=i)` does.
        let scene_cameras = matches!(parsed, ViewSpec::Cameras);
        let views: Vec<RenderSettings> = cameras
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let view = View::from_camera(c, width, height);
                let view = match scene_cameras {
                    true => self.with_lens(i, c, view)?,
                    false => view,
                };
                // Focused at the view's own look_at, where a views file gives one.
                let target = explicit.get(i).and_then(ExplicitView::focus_target);
                let which = format!("view {i}");
                let view = self.with_thin_lens(py, view, &o, target.or(options.look_at), &which)?;
                self.settings(py, view, &front, &o)
            })
            .collect::<PyResult<_>>()?;
        let out = self.render_settings(py, &views, &o, progress.as_ref())?;
        for (dict, settings) in out.iter().zip(&views) {
            let pose: Vec<f32> = camera_to_world(&settings.view)
                .into_iter()
                .flatten()
                .collect();
            dict.set_item(
                "camera_to_world",
                PyArray1::from_vec(py, pose).reshape([4, 4])?,
            )?;
            if let Some(k) = Intrinsics::of(&settings.view) {
                dict.set_item("intrinsics", [k.fl_x, k.fl_y, k.cx, k.cy])?;
            }
        }
        Ok(out)
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let triangles = self.with_scene(py, |s| s.soup.len())?;
        Ok(format!(
            "meshtracer.Scene('{}', {triangles} triangles)",
            self.path.display()
        ))
    }
}

impl RenderOptions {
    /// The options of a render given as keyword arguments (docs/python.md lists them), each
    /// checked as the CLI checks it; missing ones take the CLI's defaults.
    fn from_kwargs(kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<RenderOptions> {
        let mut o = RenderOptions {
            spp: None,
            integrator: IntegratorKind::Path,
            seed: 0,
            bounces: DEFAULT_BOUNCES,
            exposure: 0.0,
            aovs: vec!["depth".to_string(), "mask".to_string()],
            srgb8: false,
            tonemap: setup::DEFAULT_VIEW_TRANSFORM,
            noise: None,
            clamp_indirect: None,
            ambient: None,
            default_lights: true,
            env: None,
            env_rotation: 0.0,
            env_intensity: 1.0,
            env_visible: false,
            max_pixels: MAX_RENDER_PIXELS,
            max_spp: MAX_SPP,
            denoise: None,
            aperture_radius: None,
            focus_distance: None,
        };
        for (key, value) in kwargs.into_iter().flat_map(|d| d.iter()) {
            let key: String = key.extract()?;
            let bad = |e: PyErr| Error::new_err(format!("{key}: {e}"));
            match key.as_str() {
                // None: the CLI's default sampling, as when `spp` is not given.
                "spp" => o.spp = whole_or_none("spp", &value)?,
                "integrator" => {
                    o.integrator = match value.extract::<String>().map_err(bad)?.as_str() {
                        "direct" => IntegratorKind::Direct,
                        "path" => IntegratorKind::Path,
                        other => {
                            return Err(Error::new_err(format!(
                                "integrator '{other}': use 'direct' or 'path'"
                            )))
                        }
                    }
                }
                "seed" => o.seed = whole("seed", &value)?,
                "bounces" => o.bounces = whole("bounces", &value)?,
                "exposure" => o.exposure = value.extract().map_err(bad)?,
                "aovs" => o.aovs = value.extract().map_err(bad)?,
                "srgb8" => o.srgb8 = value.extract().map_err(bad)?,
                "tonemap" => {
                    let name: String = value.extract().map_err(bad)?;
                    o.tonemap = ViewTransform::from_name(&name).ok_or_else(|| {
                        let names: Vec<&str> =
                            ViewTransform::ALL.iter().map(|v| v.name()).collect();
                        Error::new_err(format!("tonemap '{name}': use {}", names.join(", ")))
                    })?;
                }
                "noise" => o.noise = value.extract().map_err(bad)?,
                "clamp_indirect" => o.clamp_indirect = value.extract().map_err(bad)?,
                "ambient" => {
                    o.ambient = value
                        .extract::<Option<[f32; 3]>>()
                        .map_err(bad)?
                        .map(Vec3::from)
                }
                "default_lights" => o.default_lights = value.extract().map_err(bad)?,
                "env" if value.is_none() => o.env = None,
                // str, os.PathLike or bytes, as `open` takes them.
                "env" => o.env = Some(fs_path(&value).map_err(bad)?),
                "env_rotation" => o.env_rotation = value.extract().map_err(bad)?,
                "env_intensity" => o.env_intensity = value.extract().map_err(bad)?,
                "env_visible" => o.env_visible = value.extract().map_err(bad)?,
                "max_pixels" => o.max_pixels = whole("max_pixels", &value)?,
                "max_spp" => o.max_spp = whole("max_spp", &value)?,
                "denoise" => o.denoise = value.extract().map_err(bad)?,
                "aperture_radius" => o.aperture_radius = value.extract().map_err(bad)?,
                "focus_distance" => o.focus_distance = value.extract().map_err(bad)?,
                _ => {
                    return Err(Error::new_err(format!(
                        "unknown render option '{key}': use spp, integrator, seed, bounces, \
                         exposure, aovs, srgb8, tonemap, noise, clamp_indirect, ambient, \
                         default_lights, env, env_rotation, env_intensity, env_visible, max_pixels, \
                         max_spp, denoise, aperture_radius, focus_distance"
                    )))
                }
            }
        }
        if let Some(r) = o.aperture_radius.filter(|r| !(r.is_finite() && *r >= 0.0)) {
            return Err(Error::new_err(format!(
                "aperture_radius {r}: must be a finite number, 0 or more (scene units)"
            )));
        }
        if let Some(f) = o.focus_distance {
            if !(f.is_finite() && f > 0.0) {
                return Err(Error::new_err(format!(
                    "focus_distance {f}: must be a finite number above 0 (scene units)"
                )));
            }
            if o.aperture_radius.is_none() {
                return Err(Error::new_err(
                    "focus_distance focuses a thin lens: give aperture_radius too",
                ));
            }
        }
        for (name, value) in [("noise", o.noise), ("clamp_indirect", o.clamp_indirect)] {
            if value.is_some_and(|v| !(v.is_finite() && v > 0.0)) {
                return Err(Error::new_err(format!("{name} must be a number above 0")));
            }
        }
        // The CLI's checks and messages, with the options' Python names.
        if o.integrator != IntegratorKind::Path && (o.env.is_some() || o.env_visible) {
            return Err(Error::new_err(
                "env and env_visible light the path tracer: use integrator='path'",
            ));
        }
        if !(o.env_intensity >= 0.0 && o.env_intensity.is_finite()) {
            return Err(Error::new_err(
                "env_intensity must be a finite number, 0 or more",
            ));
        }
        if !o.env_rotation.is_finite() {
            return Err(Error::new_err(
                "env_rotation must be a finite number of degrees",
            ));
        }
        if o.bounces > MAX_VIEW_BOUNCES {
            return Err(Error::new_err(format!(
                "bounces {}: at most {MAX_VIEW_BOUNCES}",
                o.bounces
            )));
        }
        if !o.exposure.is_finite() {
            return Err(Error::new_err("exposure must be a finite number"));
        }
        if let Some(a) = o
            .ambient
            .filter(|a| !(a.is_finite() && a.min_element() >= 0.0))
        {
            return Err(Error::new_err(format!(
                "ambient {a}: must be finite numbers of at least 0"
            )));
        }
        if let Some(unknown) = o.aovs.iter().find(|a| !AOV_NAMES.contains(&a.as_str())) {
            return Err(Error::new_err(format!(
                "aov '{unknown}': use {}",
                AOV_NAMES.join(", ")
            )));
        }
        Ok(o)
    }
}

/// A file name as Python's own file functions take one: str, bytes (decoded as `os.fsdecode`
/// decodes them) or an `os.PathLike` object.
fn fs_path(value: &Bound<'_, PyAny>) -> PyResult<PathBuf> {
    let os = value.py().import("os")?;
    os.call_method1("fsdecode", (value,))?.extract()
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
    // A panic inside an importer is a bug (ours or a dependency's); as the CLI does, it is
    // reported as an error naming the file rather than as pyo3's PanicException.
    let loaded = py.detach(|| {
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            meshtracer::Scene::load_with(&path, &options)
        }))
    });
    let scene = match loaded {
        Ok(result) => result.map_err(|e| load_error(py, e))?,
        Err(panic) => {
            let what = meshtracer::scene::panic_message(panic.as_ref());
            return Err(Error::new_err(format!(
                "{}: internal error while loading (please report this file): {what}",
                path.display()
            )));
        }
    };
    // Taken while the last pose, if it is this file's, is still bound.
    let inherited = live_textures(&path);
    let loaded = PyScene::new(path, strict, scene);
    if let Ok(mut slot) = loaded.inherited.lock() {
        *slot = inherited;
    }
    Ok(loaded)
}

#[pymodule]
fn _meshtracer(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Error", m.py().get_type::<Error>())?;
    m.add("MissingFileError", missing_file_error_type(m.py())?)?;
    m.add_class::<PyScene>()?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    Ok(())
}
