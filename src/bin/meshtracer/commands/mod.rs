//! The commands: glue between the CLI and the library phases.

use crate::cli::{Command, InfoArgs, LoadArgs, RenderArgs};
use anyhow::{bail, Context, Result};
use meshtracer::defaults::{DEFAULT_HEIGHT, DEFAULT_WIDTH};
use meshtracer::light::environment::Environment;
use meshtracer::output::view_file::{SegmentId, ViewEnvironment};
use meshtracer::prepare::textures::TextureSet;
use meshtracer::prepare::Prepared;
use meshtracer::scene::{Camera, LightKind, LoadOptions, Projection, Scene};
use meshtracer::setup::LightingOptions;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

/// `println!` for the commands' results on standard output. A reader that stops early
/// (`meshtracer compare A B | head -3`) closes the pipe: the lines after it are dropped
/// quietly and the command goes on as if they had been read, so that the files it writes
/// after its lines (`bench --report`) are still written and its verdict (`compare
/// --fail-above`) still sets the exit status, instead of a panic or an error about a reader
/// who has gone. Any other failure to write is an error.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = writeln!(std::io::stdout(), $($arg)*) {
            if e.kind() != std::io::ErrorKind::BrokenPipe {
                return Err(anyhow::Error::from(e).context("cannot write to standard output"));
            }
        }
    }};
}

mod batch;
mod bench;
mod frames;
mod render;
mod tiles;
mod views;

// batch renders each job as `render` does.
use render::render_model;

/// Wall time and peak memory after each phase of a render, for `--stats`.
#[derive(Default)]
pub(crate) struct Phases {
    /// (phase, seconds, peak resident memory in bytes after it, its own steps).
    list: Vec<(
        &'static str,
        f64,
        Option<u64>,
        Vec<meshtracer::measure::Step>,
    )>,
}

impl Phases {
    fn mark(&mut self, phase: &'static str, start: Instant) {
        self.list.push((
            phase,
            start.elapsed().as_secs_f64(),
            peak_memory_bytes(),
            Vec::new(),
        ));
    }

    /// Records the steps the phase named `phase` was made of.
    fn sub_steps_of(&mut self, phase: &str, steps: &[meshtracer::measure::Step]) {
        if let Some(entry) = self.list.iter_mut().find(|e| e.0 == phase) {
            entry.3 = steps.to_vec();
        }
    }

    /// Records the steps the last phase was made of.
    fn sub_steps(&mut self, steps: &[meshtracer::measure::Step]) {
        if let Some(last) = self.list.last_mut() {
            last.3 = steps.to_vec();
        }
    }

    /// The phases as JSON: name, seconds, peak memory and, where measured, their steps.
    fn to_json(&self) -> serde_json::Value {
        let step = |s: &meshtracer::measure::Step| {
            serde_json::json!({
                "step": s.name, "seconds": s.time.as_secs_f64(), "peak_memory_bytes": s.peak_memory,
            })
        };
        self.list
            .iter()
            .map(|(name, seconds, peak, steps)| {
                let mut phase = serde_json::json!({
                    "phase": name, "seconds": seconds, "peak_memory_bytes": peak,
                });
                if !steps.is_empty() {
                    phase["steps"] = steps.iter().map(step).collect();
                }
                phase
            })
            .collect()
    }
}

pub use meshtracer::measure::peak_memory_bytes;

/// The decoded textures of the last model this process prepared, with the path it was given
/// by. The frames of `render --frames` and a batch's jobs load a model again for each pose,
/// and its images do not change with the pose: [`prepare_scene`] offers this set to the next
/// preparation of the same path, which keeps it only where it is what decoding again would
/// give ([`TextureSet::load_reusing`]: the files unchanged on disk, the same images drawn, the
/// same budget) and otherwise drops it before decoding. Its images are shared with the
/// prepared scene's (no copy); a batch forgets them before a job of another model
/// ([`forget_kept_textures_unless`]).
static KEPT_TEXTURES: Mutex<Option<(PathBuf, TextureSet)>> = Mutex::new(None);

/// [`KEPT_TEXTURES`], locked (nothing panics while holding it, and a kept set is valid
/// whatever happened elsewhere: a poisoned lock is taken as it is).
fn kept_textures() -> MutexGuard<'static, Option<(PathBuf, TextureSet)>> {
    KEPT_TEXTURES.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The textures kept for `model`, taken out; a set kept for another model is dropped.
fn take_kept_textures(model: &Path) -> Option<TextureSet> {
    let (path, textures) = kept_textures().take()?;
    (path == model).then_some(textures)
}

/// Keeps `textures` (sharing their images) for the next preparation of `model`.
fn keep_textures(model: &Path, textures: &TextureSet) {
    *kept_textures() = Some((model.to_path_buf(), textures.clone()));
}

/// Drops the kept textures unless they are `model`'s: a batch, before a job's load, so that
/// another model's images are not held while it loads and renders.
pub(crate) fn forget_kept_textures_unless(model: &Path) {
    let mut kept = kept_textures();
    if kept.as_ref().is_some_and(|(path, _)| path != model) {
        *kept = None;
    }
}

/// What [`prepare_scene`] hands back.
pub(crate) struct PreparedModel {
    /// The scene ready to render.
    pub prepared: Prepared,
    /// Every warning of the load and the texture decoding, for a caller that records them
    /// (batch).
    pub warnings: Vec<String>,
    /// Wall time of the tangent generation (part of the load, as `render` reports it).
    pub tangents: Duration,
    /// Wall time of the texture decoding.
    pub textures: Duration,
}

/// Prepares `scene` for `render` (one view or many) through the library's one build sequence
/// ([`Prepared::build`]): the BVH preset chosen for `rays` rays, textures within
/// `--max-texture-memory` (the last preparation's, of the same model, kept where decoding
/// again would give the same: [`KEPT_TEXTURES`]), each step timed into `phases`, the decoder's
/// warnings printed unless `--no-warnings`.
pub(crate) fn prepare_scene(
    args: &RenderArgs,
    scene: Scene,
    rays: f64,
    phases: &mut Phases,
) -> Result<PreparedModel> {
    let options = meshtracer::prepare::PrepareOptions {
        accel: args.accel,
        bvh_preset: args.bvh_preset.for_work(scene.soup.len(), rays),
        max_texture_bytes: args.max_texture_memory.saturating_mul(1 << 20),
        strict: args.strict,
    };
    let mut all = scene.warnings.clone();
    let mut warnings = Vec::new();
    let (mut tangents, mut textures) = (Duration::ZERO, Duration::ZERO);
    let mut on_step = |step, start: std::time::Instant| {
        use meshtracer::prepare::PrepareStep;
        match step {
            PrepareStep::Tangents => tangents = start.elapsed(),
            PrepareStep::Textures => textures = start.elapsed(),
            PrepareStep::Bvh | PrepareStep::AreaLights => {}
        }
        phases.mark(
            match step {
                PrepareStep::Tangents => "tangents",
                PrepareStep::Textures => "textures",
                PrepareStep::Bvh => "bvh build",
                PrepareStep::AreaLights => "prepare (area lights)",
            },
            start,
        );
    };
    let kept = take_kept_textures(&args.model);
    let prepared = Prepared::build_reusing(scene, &options, &mut warnings, &mut on_step, kept)?;
    keep_textures(&args.model, &prepared.textures);
    phases.sub_steps_of("bvh build", prepared.accel.build_steps());
    if !args.no_warnings {
        for w in &warnings {
            note!("warning: {}: {w}", args.model.display());
        }
    }
    all.extend(warnings);
    Ok(PreparedModel {
        prepared,
        warnings: all,
        tangents,
        textures,
    })
}

/// The lighting options of `render` (one view or many): the integrator, `--no-default-lights`,
/// the `--env` panorama and the studio environment's `--env-rotation` and `--env-intensity`.
pub(crate) fn lighting_options(
    args: &RenderArgs,
    env_file: Option<Environment>,
) -> LightingOptions {
    LightingOptions {
        integrator: args.integrator,
        no_default_lights: args.no_default_lights,
        environment: env_file.map(Arc::new),
        studio_rotation_degrees: args.env_rotation,
        studio_intensity: args.env_intensity,
    }
}

/// How `render` (one view or many) loads its model: the shared load options, `--strict` and
/// `--variant`.
pub(crate) fn render_load_options(args: &RenderArgs) -> LoadOptions {
    LoadOptions {
        strict: args.strict,
        variant: args.variant.clone(),
        ..load_options(&args.load)
    }
}

/// Warns (unless `--no-warnings`) of what the 16-bit PNG files of `aovs` at `depth` and
/// `segmentation` lose: depths beyond the PNG's range, instance ids above 65535.
pub(crate) fn warn_png_losses(
    args: &RenderArgs,
    depth: Option<&Path>,
    segmentation: Option<&Path>,
    aovs: &meshtracer::render::Aovs,
) {
    use meshtracer::output::aov::{depth_png_loss, segmentation_png_loss};
    let losses = [
        depth.and_then(|p| depth_png_loss(p, &aovs.depth, args.depth_scale)),
        segmentation.and_then(|p| segmentation_png_loss(p, &aovs.instance)),
    ];
    for loss in losses.into_iter().flatten() {
        if !args.no_warnings {
            note!("warning: {loss}");
        }
    }
}

/// Prints the loaded model's warnings unless `--no-warnings` (`--quiet` does not hide a
/// warning about the picture), and the pose it is drawn in unless `--quiet` (shared by single-
/// and multi-view renders).
pub(crate) fn report_load(args: &RenderArgs, scene: &Scene) {
    if !args.no_warnings {
        for w in &scene.warnings {
            note!("warning: {}: {w}", args.model.display());
        }
    }
    if let (Some(pose), false) = (&scene.pose, args.quiet) {
        note!("{}: posed by {pose}", args.model.display());
    }
}

/// Refuses `--env-out` when no environment lights the render, and warns when nothing but
/// ambient and emission lights it (shared by single- and multi-view renders).
pub(crate) fn check_lighting(
    args: &RenderArgs,
    lights: &[meshtracer::scene::Light],
    environment: Option<&Environment>,
) -> Result<()> {
    if let (Some(path), None) = (&args.env_out, environment) {
        bail!(
            "{}: --env-out: no environment lights this render (the file has lights; give --env)",
            path.display()
        );
    }
    if lights.is_empty() && environment.is_none() && !args.no_warnings {
        note!(
            "warning: no lights (--no-default-lights): only ambient and emissive light the scene"
        );
    }
    Ok(())
}

/// The segmentation ids of a scene's mesh instances, as view files list them: id `i + 1` for
/// instance `i` (0 is the background of the segmentation image); shared by single- and
/// multi-view renders.
pub(crate) fn segmentation_ids(scene: &Scene) -> Vec<SegmentId> {
    scene
        .instances
        .iter()
        .enumerate()
        .map(|(i, inst)| SegmentId {
            id: i as u32 + 1,
            node: inst.node,
            mesh: inst.mesh,
            name: inst.name.clone(),
        })
        .collect()
}

/// Records in `view` how a view of `scene` was rendered, as `args` asked: the segmentation ids,
/// the depth PNG's scale, the integrator, the display encoding (exposure, view transform) and,
/// for the path tracer, its bounces, indirect clamp and the `environment` that lit it; shared
/// by single- and multi-view renders.
pub(crate) fn record_render(
    view: &mut meshtracer::output::view_file::ViewFile,
    args: &RenderArgs,
    scene: &Scene,
    environment: Option<&Arc<Environment>>,
) {
    view.segmentation = segmentation_ids(scene);
    view.depth_png_scale = args.depth_scale;
    view.integrator = args.integrator;
    view.display = Some(meshtracer::output::view_file::ViewDisplay::new(
        args.exposure,
        args.tonemap,
    ));
    if args.integrator == meshtracer::integrator::IntegratorKind::Path {
        view.bounces = Some(args.bounces);
        view.clamp_indirect = args.clamp_indirect;
        view.environment = environment.map(|env| view_environment(args, env));
    }
}

/// How a view file records the environment `env` that lit a path-traced render: its source,
/// turn and scale, whether the camera sees it (`--env-visible`), and the `--env-out` panorama,
/// made absolute when the path resolves; shared by single- and multi-view renders.
pub(crate) fn view_environment(args: &RenderArgs, env: &Environment) -> ViewEnvironment {
    ViewEnvironment {
        source: env.source.clone(),
        rotation_degrees: env.rotation_degrees(),
        intensity: env.intensity(),
        visible: args.env_visible,
        panorama: args
            .env_out
            .as_ref()
            .map(|p| p.canonicalize().unwrap_or_else(|_| p.clone())),
    }
}

/// Writes the environment that lit a render as a Radiance .hdr panorama (`--env-out`); shared
/// by single- and multi-view renders.
pub(crate) fn write_panorama(path: &Path, env: &Environment) -> Result<()> {
    let panorama = env.to_rgb32f();
    let pixels: Vec<image::Rgb<f32>> = panorama.pixels().map(|p| image::Rgb(p.0)).collect();
    let mut bytes = Vec::new();
    image::codecs::hdr::HdrEncoder::new(&mut bytes)
        .encode(
            &pixels,
            panorama.width() as usize,
            panorama.height() as usize,
        )
        .with_context(|| format!("{}: cannot encode the panorama", path.display()))?;
    meshtracer::output::write_atomic(path, &bytes)?;
    Ok(())
}

/// The preset a BVH was built with, for the summary line: "VeryFast, auto" when `--bvh-preset
/// auto` chose it.
pub(crate) fn preset_label(
    asked: meshtracer::accel::BvhPreset,
    built: meshtracer::accel::BvhPreset,
) -> String {
    if asked == meshtracer::accel::BvhPreset::Auto {
        format!("{built:?}, auto")
    } else {
        format!("{built:?}")
    }
}

/// `1 thread`, `2 threads`: a report's thread count with its noun.
pub(crate) fn threads_label(threads: usize) -> String {
    counted(threads, "thread")
}

/// A count with its noun, singular for one: `1 job`, `0 jobs`, `2 jobs` (nouns whose plural
/// adds an `s`).
pub(crate) fn counted(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

/// A length for a summary line: as given where it reads plainly (`0.08`, `3`), in scientific
/// notation where its digits would run on (`3e38`, `1e-30`).
pub(crate) fn length_label(x: f32) -> String {
    if x == 0.0 || (1e-3..1e6).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// The samples a pixel, for a summary line: "12.3 spp (adaptive to noise 0.1, at most 32)" when
/// the adaptive sampler chose how many (`samples` over `pixels` is their mean), else "16 spp".
pub(crate) fn spp_label(spp: u32, noise: Option<f32>, samples: u64, pixels: u64) -> String {
    match noise {
        Some(target) => format!(
            "{:.1} spp (adaptive to noise {target}, at most {spp})",
            samples as f64 / pixels.max(1) as f64
        ),
        None => format!("{spp} spp"),
    }
}

/// Runs one command.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Info(args) => info(&args),
        Command::Render(args) => render::render_command(&args),
        Command::Batch(args) => batch::batch_command(&args),
        Command::BatchMerge(args) => batch::merge_command(&args),
        Command::Bench(args) => bench::bench_command(&args),
        Command::Compare(args) => compare_command(&args),
        Command::Merge(args) => tiles::merge_command(&args),
    }
}

/// Loads a model. A panic inside the importer is a bug (ours or a dependency's: fuzzing found
/// one in gltf-json's validation); it is reported as an error naming the file instead of
/// aborting, while the fuzz targets, which call the library directly, still see it.
fn load(path: &std::path::Path, options: &LoadOptions) -> Result<Scene> {
    // Loading runs on this thread alone, before any worker starts: silencing the panic hook
    // for its duration keeps the report to one message.
    let previous_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let result = std::panic::catch_unwind(|| Scene::load_with(path, options));
    std::panic::set_hook(previous_hook);
    match result {
        Ok(loaded) => Ok(loaded?),
        Err(panic) => {
            let what = meshtracer::scene::panic_message(panic.as_ref());
            bail!(
                "{}: internal error while loading (please report this file): {what}",
                path.display()
            )
        }
    }
}

/// Starts the threads the load runs on (rayon's global pool; the render has a pool of its
/// own), sized by `--threads`, now rather than at the load's first parallel step: they come
/// up while the options are checked and the file is read and parsed, instead of inside the
/// flatten (DamagedHelmet, 25 interleaved cold runs: parse and flatten 2.59 -> 2.46 ms, median).
/// The load's sequential parts stay on the calling thread, whose malloc arena is warm (on
/// the render's pool they ran slower). A second call, or a pool some caller already made
/// global, keeps the pool there is.
fn start_load_threads(requested: usize) {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if requested > 0 {
        builder = builder.num_threads(requested);
    }
    // Err only when a global pool exists already: then that one is used, as before.
    let _ = builder.build_global();
}

/// A rayon pool of `requested` threads, or one per core for 0.
fn worker_pool(requested: usize) -> Result<(usize, rayon::ThreadPool)> {
    let threads = if requested == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        requested
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("cannot start worker threads")?;
    Ok((threads, pool))
}

fn load_options(args: &LoadArgs) -> LoadOptions {
    let mut options = LoadOptions {
        allow_external_files: args.allow_external_files,
        pose: meshtracer::scene::PoseOptions {
            animation: args.animation.clone(),
            time: args.time,
        },
        ..Default::default()
    };
    options.limits.max_triangles = args.max_triangles;
    options
}

fn info(args: &InfoArgs) -> Result<()> {
    let start = Instant::now();
    let options = LoadOptions {
        allow_nothing_to_draw: true,
        ..load_options(&args.load)
    };
    let scene = load(&args.model, &options)?;
    let load_time = start.elapsed();
    let json = scene.info_json();
    if args.json {
        out!("{}", serde_json::to_string_pretty(&json)?);
        return Ok(());
    }
    let b = &scene.bounds;
    out!("file        {}", scene.source.display());
    out!("format      {}", json["format"].as_str().unwrap_or("?"));
    if scene.file_triangles == scene.soup.len() {
        out!("triangles   {}", scene.soup.len());
    } else {
        out!(
            "triangles   {} ({} traced, {} degenerate or non-finite dropped)",
            scene.file_triangles,
            scene.soup.len(),
            scene.file_triangles - scene.soup.len()
        );
    }
    out!(
        "meshes      {} ({}, {} flattened)",
        scene.mesh_count,
        counted(scene.instances.len(), "instance"),
        counted(scene.primitive_count, "triangle primitive")
    );
    let attributes = scene.soup.attributes();
    out!(
        "attributes  {}",
        if attributes.is_empty() {
            "positions and normals only".to_string()
        } else {
            format!("{} (beside positions and normals)", attributes.join(", "))
        }
    );
    out!("materials   {}", scene.materials.len());
    out!(
        "textures    {} ({})",
        scene.textures.len(),
        counted(scene.images.len(), "image")
    );
    if !scene.variants.is_empty() {
        let names: Vec<String> = scene.variants.iter().map(|v| format!("'{v}'")).collect();
        out!(
            "variants    {} (--variant NAME): {}",
            scene.variants.len(),
            names.join(", ")
        );
    }
    if !scene.animations.is_empty() {
        out!(
            "animations  {} (--animation NAME|INDEX, --time SECONDS)",
            scene.animations.len()
        );
        for a in &scene.animations {
            out!(
                "  [{}] {:.3} s, {} channels{}",
                a.index,
                a.duration,
                a.channels,
                a.name
                    .as_deref()
                    .map_or(String::new(), |n| format!(" '{n}'"))
            );
        }
    }
    if let Some(pose) = &scene.pose {
        out!("pose        {pose}");
    }
    out!("cameras     {}", scene.cameras.len());
    for (i, c) in scene.cameras.iter().enumerate() {
        let projection = match c.projection {
            Projection::Perspective {
                yfov, aspect_ratio, ..
            } => format!(
                "perspective yfov {:.4} rad ({:.1}°){}",
                yfov,
                yfov.to_degrees(),
                aspect_ratio.map_or(String::new(), |a| format!(", aspect {a:.4}"))
            ),
            Projection::Orthographic { xmag, ymag, .. } => {
                format!("orthographic xmag {xmag} ymag {ymag}")
            }
        };
        out!(
            "  [{i}] {projection} at {:.3?} looking {:.3?}{}",
            c.position.to_array(),
            c.forward.to_array(),
            c.name
                .as_deref()
                .map_or(String::new(), |n| format!(" '{n}'"))
        );
    }
    out!("lights      {}", scene.lights.len());
    for (i, l) in scene.lights.iter().enumerate() {
        let (kind, unit) = match l.kind {
            LightKind::Point => ("point".to_string(), "cd"),
            LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => (
                format!("spot (cone {inner_cone_angle:.3}..{outer_cone_angle:.3} rad)"),
                "cd",
            ),
            LightKind::Directional => ("directional".to_string(), "lux"),
        };
        let place = match l.kind {
            LightKind::Directional => format!("direction {:.3?}", l.direction.to_array()),
            _ => format!("at {:.3?}", l.position.to_array()),
        };
        out!(
            "  [{i}] {kind} colour {:.3?} intensity {} {unit} {place}",
            l.color.to_array(),
            l.intensity
        );
    }
    if b.is_empty() {
        out!("bounds      none (no triangles)");
    } else {
        out!(
            "bounds      min {:.4?} max {:.4?}",
            b.min.to_array(),
            b.max.to_array()
        );
    }
    for w in &scene.warnings {
        out!("warning     {w}");
    }
    out!(
        "loaded in   {:.1} ms ({:.1} MB of triangle data)",
        load_time.as_secs_f64() * 1e3,
        scene.soup.heap_bytes() as f64 / 1e6
    );
    Ok(())
}

/// Image size from the options and the camera: `--height` wins, then the camera's
/// `aspectRatio` (glTF 2.0 §5.13), then the default.
fn image_size(args: &RenderArgs, camera: Option<&Camera>) -> (u32, u32) {
    let width = args.width.unwrap_or(DEFAULT_WIDTH);
    let aspect = camera.and_then(|c| match c.projection {
        Projection::Perspective { aspect_ratio, .. } => aspect_ratio,
        Projection::Orthographic { .. } => None,
    });
    let height = match (args.height, aspect) {
        (Some(h), _) => h,
        (None, Some(a)) if a.is_finite() && a > 0.0 => ((width as f32 / a).round() as u32).max(1),
        (None, _) if args.width.is_some() => {
            ((width as u64 * DEFAULT_HEIGHT as u64) / DEFAULT_WIDTH as u64).max(1) as u32
        }
        (None, _) => DEFAULT_HEIGHT,
    };
    (width, height)
}

fn check_size(args: &RenderArgs, width: u32, height: u32) -> Result<()> {
    let pixels = u64::from(width) * u64::from(height);
    if width == 0 || height == 0 {
        bail!("image size {width}x{height}: width and height must be at least 1");
    }
    if pixels > args.max_pixels {
        bail!(
            "image size {width}x{height} is {pixels} pixels, over the limit of {} (raise it with --max-pixels)",
            args.max_pixels
        );
    }
    Ok(())
}

/// What one render (one view, or `--views`) did: for a caller that records it.
#[derive(Default)]
pub(crate) struct RenderReport {
    /// Triangles traced.
    pub triangles: usize,
    /// Wall time of the load (parse, flatten, tangents).
    pub load: Duration,
    /// Wall time of the BVH build (zero for the linear scan).
    pub bvh: Duration,
    /// Render time, of every view together.
    pub render: Duration,
    /// Every file written, in the order written.
    pub outputs: Vec<std::path::PathBuf>,
    /// The warnings of the load and the texture decoding (printed unless `--quiet`).
    pub warnings: Vec<String>,
    /// The files the model refers to ([`meshtracer::scene::Scene::inputs`]).
    pub inputs: Vec<std::path::PathBuf>,
}

/// The process's Ctrl-C flag, shared by every render of the process (a batch runs many) and by
/// bench: ctrlc takes one handler per process, so a flag made per render would go unheard after the
/// first. Without a handler Ctrl-C kills the process; every file is still whole (renamed into
/// place after a complete write).
fn interrupt_flag() -> Arc<AtomicBool> {
    static FLAG: std::sync::OnceLock<Arc<AtomicBool>> = std::sync::OnceLock::new();
    Arc::clone(FLAG.get_or_init(|| {
        let flag = Arc::new(AtomicBool::new(false));
        let handler_flag = Arc::clone(&flag);
        let _ = keeping_ignored_signals(|| {
            ctrlc::set_handler(move || {
                if handler_flag.swap(true, Ordering::SeqCst) && QUIT_ON_SECOND_PRESS.get().is_some()
                {
                    note!("meshtracer: interrupted; no output written");
                    exit_now(130);
                }
                if let Some(notice) = QUIT_ON_SECOND_PRESS.get() {
                    note!("{notice}");
                }
            })
        });
        flag
    }))
}

/// Runs `install` (ctrlc's, which takes SIGINT, SIGTERM and SIGHUP whatever their
/// disposition), then sets back to ignored each of those signals the process was started
/// ignoring: `nohup` starts it with SIGHUP ignored, so that closing the terminal does not stop
/// the render, and a shell starts a background job with SIGINT ignored.
#[cfg(unix)]
fn keeping_ignored_signals<T>(install: impl FnOnce() -> T) -> T {
    let signals = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];
    let ignored: Vec<libc::c_int> = signals
        .into_iter()
        .filter(|&signal| {
            // SAFETY: with a null new action, sigaction only reads the current one into `old`,
            // a zeroed (valid) sigaction struct.
            unsafe {
                let mut old: libc::sigaction = std::mem::zeroed();
                libc::sigaction(signal, std::ptr::null(), &mut old) == 0
                    && old.sa_sigaction == libc::SIG_IGN
            }
        })
        .collect();
    let installed = install();
    for signal in ignored {
        // SAFETY: setting a signal's disposition to SIG_IGN runs no code of ours.
        unsafe { libc::signal(signal, libc::SIG_IGN) };
    }
    installed
}

#[cfg(not(unix))]
fn keeping_ignored_signals<T>(install: impl FnOnce() -> T) -> T {
    install()
}

/// Removes the temporary files (`.meshtracer-*.partial`) that a killed run left in `folder`
/// (SIGKILL cannot be caught, so nothing cleaned up): for a run that owns the folder and is
/// about to redo that run's work (a batch's job, a resumed `--views` run).
fn remove_leftovers(folder: &std::path::Path) {
    let Ok(listing) = std::fs::read_dir(folder) else {
        return;
    };
    for item in listing.flatten() {
        let name = item.file_name();
        let name = name.to_string_lossy();
        if name.starts_with(".meshtracer-") && name.ends_with(".partial") {
            let _ = std::fs::remove_file(item.path());
        }
    }
}

/// Exits at once with `code`, after removing the folders of the zip archives still unpacked:
/// `std::process::exit` runs no destructors, and the scenes holding them are not dropped.
pub(crate) fn exit_now(code: i32) -> ! {
    meshtracer::scene::remove_unpacked_archives();
    std::process::exit(code)
}

/// Set by a command whose first Ctrl-C lets it finish what is under way and report (bench):
/// the notice the first press prints; a second press then quits at once, writing nothing.
static QUIT_ON_SECOND_PRESS: std::sync::OnceLock<&'static str> = std::sync::OnceLock::new();

/// The user stopped a command with Ctrl-C after it reported what it had finished: exit 130,
/// like a render that was interrupted, so that a script never takes partial results for whole.
#[derive(Debug, thiserror::Error)]
#[error("interrupted; {0}")]
pub struct Interrupted(pub String);

fn compare_command(args: &crate::cli::CompareArgs) -> Result<()> {
    use meshtracer::tools::compare::{compare_files, side_by_side};
    for (metric, _) in &args.fail_above {
        if !["flip", "rmse", "max_abs"].contains(&metric.as_str()) {
            bail!("--fail-above {metric}: use --fail-below for psnr, ssim and coverage_iou");
        }
    }
    for (metric, _) in &args.fail_below {
        if !["psnr", "ssim", "coverage_iou"].contains(&metric.as_str()) {
            bail!("--fail-below {metric}: use --fail-above for flip, rmse and max_abs");
        }
    }
    // Both are written as PNG: another name would hold a PNG under a wrong extension.
    for (option, path) in [
        ("--diff-out", &args.diff_out),
        ("--side-by-side", &args.side_by_side),
    ] {
        if let Some(path) = path.as_ref().filter(|p| !views::has_extension(p, "png")) {
            bail!(
                "{option} {}: the file name must end in .png",
                path.display()
            );
        }
    }
    let background = args.background.map(|c| {
        // Accept 0-1 or 0-255 components.
        let scale = if c.max_element() <= 1.0 { 255.0 } else { 1.0 };
        (c * scale)
            .clamp(glam::Vec3::ZERO, glam::Vec3::splat(255.0))
            .round()
            .to_array()
            .map(|v| v as u8)
    });
    // A signal before the images are written stops the comparison with no file written;
    // once the writing starts, both are written.
    let cancel = interrupt_flag();
    let outputs: Vec<_> = [
        ("--diff-out", &args.diff_out),
        ("--side-by-side", &args.side_by_side),
    ]
    .into_iter()
    .filter_map(|(option, path)| path.as_deref().map(|p| (option, p)))
    .collect();
    let inputs = [
        ("the first image compared", args.a.as_path()),
        ("the second image compared", args.b.as_path()),
    ];
    meshtracer::output::check_destinations(&outputs, &inputs, false)?;
    let (metrics, a, b, heat) = compare_files(&args.a, &args.b, background, args.tonemap)?;
    let mut encoded = Vec::new();
    if let Some(path) = &args.diff_out {
        let mut png = Vec::new();
        heat.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .context("encoding the heatmap")?;
        encoded.push((path, png));
    }
    if let Some(path) = &args.side_by_side {
        let name = |p: &std::path::Path| {
            p.file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
        };
        let flip_label = format!("FLIP {:.3}", metrics.flip);
        let strip = side_by_side(
            &a,
            &b,
            &heat,
            [&name(&args.a), &name(&args.b), &flip_label],
            background,
        );
        let mut png = Vec::new();
        strip
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .context("encoding the side-by-side image")?;
        encoded.push((path, png));
    }
    render::stop_if_cancelled(&cancel)?;
    for (path, png) in encoded {
        meshtracer::output::write_atomic(path, &png)?;
    }
    if args.json {
        out!("{}", serde_json::to_string_pretty(&metrics)?);
    } else {
        out!(
            "{} vs {} ({}x{})",
            args.a.display(),
            args.b.display(),
            metrics.width,
            metrics.height
        );
        out!("PSNR          {:.2} dB", metrics.psnr);
        out!("SSIM          {:.4}", metrics.ssim);
        out!("FLIP (mean)   {:.4}", metrics.flip);
        out!("RMSE          {:.4}", metrics.rmse);
        out!("max abs error {:.4}", metrics.max_abs);
        out!("coverage IoU  {:.4}", metrics.coverage_iou);
    }
    let value = |m: &str| match m {
        "psnr" => metrics.psnr,
        "ssim" => metrics.ssim,
        "flip" => metrics.flip,
        "rmse" => metrics.rmse,
        "max_abs" => metrics.max_abs,
        _ => metrics.coverage_iou,
    };
    let mut failed = Vec::new();
    for (m, limit) in &args.fail_above {
        if value(m) > *limit {
            failed.push(format!("{m} {:.4} > {limit}", value(m)));
        }
    }
    for (m, limit) in &args.fail_below {
        // NaN (no score) fails too.
        if value(m).partial_cmp(limit) != Some(std::cmp::Ordering::Greater) && value(m) != *limit {
            failed.push(format!("{m} {:.4} < {limit}", value(m)));
        }
    }
    if !failed.is_empty() {
        bail!(
            "{} vs {}: {}",
            args.a.display(),
            args.b.display(),
            failed.join(", ")
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_are_singular_for_one() {
        assert_eq!(counted(0, "job"), "0 jobs");
        assert_eq!(counted(1, "job"), "1 job");
        assert_eq!(counted(2, "triangle"), "2 triangles");
        assert_eq!(threads_label(1), "1 thread");
        assert_eq!(threads_label(8), "8 threads");
    }

    #[test]
    fn lengths_read_plainly_or_in_scientific_notation() {
        assert_eq!(length_label(0.08), "0.08");
        assert_eq!(length_label(3.0), "3");
        assert_eq!(length_label(0.0), "0");
        assert_eq!(length_label(3e38), "3e38");
        assert_eq!(length_label(1e-30), "1e-30");
    }

    #[test]
    fn spp_is_the_mean_over_the_pixels_rendered_when_adaptive() {
        assert_eq!(spp_label(16, None, 999, 10), "16 spp");
        // 2 samples a pixel over a 1024x384 tile: its own pixels, not the whole image's.
        assert_eq!(
            spp_label(32, Some(1.0), 2 * 1024 * 384, 1024 * 384),
            "2.0 spp (adaptive to noise 1, at most 32)"
        );
        // No pixels (an empty region) divides by one, not zero.
        assert_eq!(
            spp_label(4, Some(0.5), 0, 0),
            "0.0 spp (adaptive to noise 0.5, at most 4)"
        );
    }
}
