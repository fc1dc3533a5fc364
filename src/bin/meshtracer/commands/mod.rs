//! The commands: glue between the CLI and the library phases.

use crate::cli::{Command, InfoArgs, LoadArgs, RenderArgs};
use anyhow::{bail, Context, Result};
use meshtracer::accel::AccelKind;
use meshtracer::camera::{auto_camera, look_at, View};
use meshtracer::defaults::{DEFAULT_HEIGHT, DEFAULT_WIDTH, DEFAULT_YFOV_DEGREES};
use meshtracer::integrator::IntegratorKind;
use meshtracer::light::environment::Environment;
use meshtracer::output::PendingOutput;
use meshtracer::prepare::Prepared;
use meshtracer::render::{render, render_region, RenderSettings};
use meshtracer::scene::{Camera, LightKind, LoadOptions, Projection, Scene};
use meshtracer::setup::{lighting, Lighting, LightingOptions, RecordedLighting};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// `println!` for the commands' results on standard output. A reader that stops early
/// (`meshtracer compare A B | head -3`) closes the pipe: the command then ends quietly with
/// success, as other command-line tools do, instead of panicking on the failed write.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = writeln!(std::io::stdout(), $($arg)*) {
            if e.kind() == std::io::ErrorKind::BrokenPipe {
                std::process::exit(0);
            }
            return Err(anyhow::Error::from(e).context("cannot write to standard output"));
        }
    }};
}

mod batch;
mod tiles;
mod views;

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
/// `--max-texture-memory`, each step timed into `phases`, the decoder's warnings printed unless
/// `--quiet`.
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
    let prepared = Prepared::build(scene, &options, &mut warnings, &mut |step, start| {
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
    })?;
    phases.sub_steps_of("bvh build", prepared.accel.build_steps());
    if !args.quiet {
        for w in &warnings {
            eprintln!("warning: {}: {w}", args.model.display());
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
        environment: env_file,
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

/// Prints the loaded model's warnings and the pose it is drawn in, unless `--quiet` (shared by
/// single- and multi-view renders).
pub(crate) fn report_load(args: &RenderArgs, scene: &Scene) {
    if args.quiet {
        return;
    }
    for w in &scene.warnings {
        eprintln!("warning: {}: {w}", args.model.display());
    }
    if let Some(pose) = &scene.pose {
        eprintln!("{}: posed by {pose}", args.model.display());
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
    if lights.is_empty() && environment.is_none() && !args.quiet {
        eprintln!(
            "warning: no lights (--no-default-lights): only ambient and emissive light the scene"
        );
    }
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

/// The spp that fits `limit` seconds: one sample per pixel is rendered and timed, and the
/// rest of the budget buys as many more passes of that cost as fit (at least 1, at most
/// `max_spp`).
fn spp_for_time_limit(
    prepared: &Prepared,
    settings: &RenderSettings,
    cancel: &AtomicBool,
    limit: f64,
    max_spp: u32,
) -> Result<u32> {
    let calibration = RenderSettings {
        spp: 1,
        aovs: false,
        ..settings.clone()
    };
    let (_, stats, _) = render(prepared, &calibration, cancel, &|_, _| {})?;
    let per_sample = stats.time.as_secs_f64().max(1e-6);
    let fit = ((limit - per_sample) / per_sample).floor();
    Ok((fit.max(1.0) as u32).min(max_spp.max(1)))
}

/// Most path bounces `--bounces` accepts: far beyond any visible difference.
const MAX_BOUNCES: u32 = meshtracer::output::view_file::MAX_VIEW_BOUNCES;

/// Runs one command.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Info(args) => info(&args),
        Command::Render(args) => render_command(&args),
        Command::Batch(args) => batch::batch_command(&args),
        Command::BatchMerge(args) => batch::merge_command(&args),
        Command::Bench(args) => bench_command(&args),
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
            let what = panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("unknown panic");
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
    let scene = load(&args.model, &load_options(&args.load))?;
    let load_time = start.elapsed();
    let json = info_json(&scene);
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
        "meshes      {} ({} instances, {} triangle primitives flattened)",
        scene.mesh_count,
        scene.instances.len(),
        scene.primitive_count
    );
    out!("materials   {}", scene.materials.len());
    out!(
        "textures    {} ({} images)",
        scene.textures.len(),
        scene.images.len()
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
    out!(
        "bounds      min {:.4?} max {:.4?}",
        b.min.to_array(),
        b.max.to_array()
    );
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

/// The `info --json` object.
pub fn info_json(scene: &Scene) -> serde_json::Value {
    serde_json::json!({
        "file": scene.source,
        "format": scene.format,
        "triangles": scene.file_triangles,
        "traced_triangles": scene.soup.len(),
        "dropped_triangles": scene.file_triangles - scene.soup.len(),
        "meshes": scene.mesh_count,
        "primitives": scene.primitive_count,
        "instances": scene.instances.len(),
        "materials": scene.materials.len(),
        "textures": scene.textures.len(),
        "images": scene.images.len(),
        "cameras": scene.cameras,
        "lights": scene.lights,
        "bounds": scene.bounds,
        "warnings": scene.warnings,
        "variants": scene.variants,
        "animations": scene.animations,
        "pose": scene.pose,
        "extensions": scene.extensions,
        "material_list": scene.materials,
    })
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
        let _ = ctrlc::set_handler(move || {
            if handler_flag.swap(true, Ordering::SeqCst) && QUIT_ON_SECOND_PRESS.get().is_some() {
                eprintln!("meshtracer: interrupted; no output written");
                std::process::exit(130);
            }
            if let Some(notice) = QUIT_ON_SECOND_PRESS.get() {
                eprintln!("{notice}");
            }
        });
        flag
    }))
}

/// Set by a command whose first Ctrl-C lets it finish what is under way and report (bench):
/// the notice the first press prints; a second press then quits at once, writing nothing.
static QUIT_ON_SECOND_PRESS: std::sync::OnceLock<&'static str> = std::sync::OnceLock::new();

fn render_command(args: &RenderArgs) -> Result<()> {
    render_model(args, &|_, _| {}).map(|_| ())
}

/// Renders one model as `render` does, calling `on_view(done, total)` as views finish.
fn render_model(
    args: &RenderArgs,
    on_view: &(dyn Fn(usize, usize) + Sync),
) -> Result<RenderReport> {
    let run_start = Instant::now();
    start_load_threads(args.threads);
    // Everything that can be refused is refused before any work: options, output, then model.
    if args.spp == 0 || args.spp > args.max_spp {
        bail!(
            "--spp {}: must be between 1 and {} (raise the limit with --max-spp)",
            args.spp,
            args.max_spp
        );
    }
    if let Some(limit) = args.time_limit {
        if !(limit > 0.0 && limit.is_finite()) {
            bail!("--time-limit {limit}: must be a positive number of seconds");
        }
    }
    if !args.exposure.is_finite() {
        bail!("--exposure must be a finite number");
    }
    if args.denoise {
        if !meshtracer::render::denoise::AVAILABLE {
            bail!(meshtracer::render::denoise::NOT_BUILT);
        }
        // The command line refuses these combinations; a batch job's manifest can still ask.
        if args.views.is_some() || args.turntable.is_some() {
            bail!("--denoise denoises a single image: not with --views or --turntable (yet)");
        }
    }
    if let Some(yfov) = args.yfov {
        if !(yfov > 0.0 && yfov < 180.0) {
            bail!("--yfov {yfov}: must be between 0 and 180 degrees");
        }
    }
    if let (Some(w), Some(h)) = (args.width, args.height) {
        check_size(args, w, h)?;
    } else if args.width == Some(0) || args.height == Some(0) {
        bail!("image width and height must be at least 1");
    }
    let view_file = match &args.view {
        Some(path) => Some(meshtracer::output::view_file::ViewFile::read(path)?),
        None => None,
    };
    if let Some(v) = &view_file {
        check_size(args, v.image.width, v.image.height)?;
    }
    for (path, allowed) in [
        (&args.depth_out, &["exr", "npy", "png"][..]),
        (&args.normal_out, &["exr", "npy", "png"][..]),
        (&args.mask_out, &["npy", "png"][..]),
        (&args.segmentation_out, &["npy", "png"][..]),
    ] {
        if let Some(p) = path {
            meshtracer::output::aov::check(p, allowed)?;
        }
    }
    if !(args.depth_scale > 0.0 && args.depth_scale.is_finite()) {
        bail!("--depth-scale must be a positive number");
    }
    let path_tracing = args.integrator == IntegratorKind::Path;
    if !path_tracing && (args.env.is_some() || args.env_visible || args.env_out.is_some()) {
        bail!("--env, --env-visible and --env-out light the path tracer: add --integrator path");
    }
    if !(args.env_intensity >= 0.0 && args.env_intensity.is_finite()) {
        bail!("--env-intensity must be a finite number, 0 or more");
    }
    if !args.env_rotation.is_finite() {
        bail!("--env-rotation must be a finite number of degrees");
    }
    if args.bounces > MAX_BOUNCES {
        bail!("--bounces {}: at most {MAX_BOUNCES}", args.bounces);
    }
    if let Some(p) = &args.env_out {
        meshtracer::output::aov::check(p, &["hdr"])?;
    }
    if let Some(p) = &args.stats {
        meshtracer::output::aov::check(p, &["json"])?;
    }
    tiles::check_render(args)?;
    let env_file = match &args.env {
        Some(path) => {
            Some(Environment::load(path)?.with_transform(args.env_rotation, args.env_intensity))
        }
        None => None,
    };
    if let Some(spec) = &args.views {
        // Many views after one load and one BVH build: its own flow, in commands/views.rs.
        return views::render_views(args, spec, env_file, on_view);
    }
    if let Some(frames) = args.turntable {
        // A turntable is an orbit (starting where the plain render stands).
        return views::render_views(args, &format!("orbit:{frames}"), env_file, on_view);
    }
    if args.contact_sheet.is_some() {
        bail!("--contact-sheet lays out many views: add --views SPEC or --turntable N (or give it to batch, for a cell per job)");
    }
    let output = PendingOutput::reserve(&args.output, args.no_clobber)?;
    let (threads, pool) = worker_pool(args.threads)?;

    let load_start = Instant::now();
    let load_options = render_load_options(args);
    let mut phases = Phases::default();
    let scene = load(&args.model, &load_options)?;
    phases.mark("parse and flatten", load_start);
    phases.sub_steps(&scene.load_steps);
    let mut load_time = load_start.elapsed();
    report_load(args, &scene);

    let file_camera = match args.camera {
        Some(i) => Some(scene.cameras.get(i).with_context(|| {
            format!(
                "{}: --camera {i}: the file has {} camera(s)",
                args.model.display(),
                scene.cameras.len()
            )
        })?),
        None => scene.cameras.first(),
    };
    let (width, height) = match &view_file {
        Some(v) => (v.image.width, v.image.height),
        None => image_size(
            args,
            if args.look_from.is_some() {
                None
            } else {
                file_camera
            },
        ),
    };
    check_size(args, width, height)?;
    let aspect = width as f32 / height as f32;
    let camera = match &view_file {
        Some(v) => v.camera()?,
        None => choose_camera(args, &scene, file_camera, aspect),
    };
    let view = View::from_camera(&camera, width, height);
    let region = tiles::region(args, width, height)?;

    // A view file's environment lights the path tracer again unless --env says otherwise.
    let recorded = match &view_file {
        Some(v) => Some(RecordedLighting {
            lights: v.lights(),
            ambient: glam::Vec3::from(v.ambient),
            environment: match &v.environment {
                Some(recorded) if path_tracing && env_file.is_none() => Some(recorded.load()?),
                _ => None,
            },
        }),
        None => None,
    };
    let Lighting {
        lights,
        ambient: default_ambient,
        environment,
        default_rig: using_rig,
    } = lighting(
        &scene.lights,
        recorded,
        &view,
        lighting_options(args, env_file),
    );
    check_lighting(args, &lights, environment.as_deref())?;
    let mut settings = RenderSettings {
        view,
        spp: args.spp,
        seed: args.seed,
        lights,
        ambient: args.ambient.unwrap_or(default_ambient),
        exposure: args.exposure,
        shading: args.shading,
        aovs: args.depth_out.is_some()
            || args.normal_out.is_some()
            || args.segmentation_out.is_some(),
        integrator: args.integrator,
        bounces: args.bounces,
        environment,
        environment_visible: args.env_visible,
    };

    let cancel = interrupt_flag();
    let (prepared, warnings, texture_time, (image, stats, aovs), denoised) =
        pool.install(|| -> Result<_> {
            let rays = meshtracer::setup::expected_rays(
                u64::from(width) * u64::from(height),
                settings.spp,
                settings.lights.len(),
                settings.integrator,
                settings.bounces,
            );
            let PreparedModel {
                prepared,
                warnings,
                tangents,
                textures: texture_time,
            } = prepare_scene(args, scene, rays, &mut phases)?;
            load_time += tangents;
            let render_start = Instant::now();
            if let Some(limit) = args.time_limit {
                settings.spp =
                    spp_for_time_limit(&prepared, &settings, &cancel, limit, args.max_spp)?;
            }
            let bar = progress_bar(args.quiet);
            let result = render_region(&prepared, &settings, region, &cancel, &|done, total| {
                bar.set_length(total);
                bar.set_position(done);
            });
            bar.finish_and_clear();
            phases.mark("render", render_start);
            let (mut image, stats, aovs) = result?;
            let denoised = if args.denoise {
                // On the linear HDR film, before the output encodes it (sRGB PNG, EXR, HDR).
                let guide_start = Instant::now();
                let guides = meshtracer::render::denoise::guides(&prepared, &settings, region);
                phases.mark("denoise guides", guide_start);
                let denoise_start = Instant::now();
                let report = meshtracer::render::denoise::denoise(&mut image, &guides)?;
                phases.mark("denoise", denoise_start);
                if cancel.load(Ordering::SeqCst) {
                    return Err(meshtracer::render::Cancelled.into());
                }
                Some((report, guides.samples_per_pixel, guide_start.elapsed()))
            } else {
                None
            };
            Ok((
                prepared,
                warnings,
                texture_time,
                (image, stats, aovs),
                denoised,
            ))
        })?;
    let write_start = Instant::now();
    let (scene, accel, textures) = (&prepared.scene, &prepared.accel, &prepared.textures);
    let background = args.background;
    output.commit(&image, background)?;
    if let Some(mode) = args.preview {
        meshtracer::output::preview::show(&image, background, mode).context("--preview")?;
    }
    if let Some(a) = &aovs {
        if let Some(p) = &args.depth_out {
            meshtracer::output::aov::write_depth(
                p,
                image.width,
                image.height,
                &a.depth,
                args.depth_scale,
            )?;
        }
        if let Some(p) = &args.normal_out {
            meshtracer::output::aov::write_normals(p, image.width, image.height, &a.normal)?;
        }
        if let Some(p) = &args.segmentation_out {
            meshtracer::output::aov::write_segmentation(p, image.width, image.height, &a.instance)?;
        }
    }
    if let Some(p) = &args.mask_out {
        let coverage: Vec<f32> = image.pixels.iter().map(|p| p.w).collect();
        meshtracer::output::aov::write_mask(p, image.width, image.height, &coverage)?;
    }
    if let (Some(path), Some(env)) = (&args.env_out, &settings.environment) {
        let panorama = env.to_rgb32f();
        let mut bytes = Vec::new();
        image::codecs::hdr::HdrEncoder::new(&mut bytes)
            .encode(
                panorama
                    .pixels()
                    .map(|p| image::Rgb(p.0))
                    .collect::<Vec<_>>()
                    .as_slice(),
                panorama.width() as usize,
                panorama.height() as usize,
            )
            .with_context(|| format!("{}: cannot encode the panorama", path.display()))?;
        meshtracer::output::write_atomic(path, &bytes)?;
    }
    if let Some(path) = &args.view_out {
        let mut view = meshtracer::output::view_file::ViewFile::new(
            &camera,
            width,
            height,
            &settings.lights,
            settings.ambient,
            using_rig,
        );
        view.segmentation = scene
            .instances
            .iter()
            .enumerate()
            .map(|(i, inst)| meshtracer::output::view_file::SegmentId {
                id: i as u32 + 1,
                node: inst.node,
                mesh: inst.mesh,
                name: inst.name.clone(),
            })
            .collect();
        view.depth_png_scale = args.depth_scale;
        view.integrator = settings.integrator;
        if settings.integrator == IntegratorKind::Path {
            view.bounces = Some(settings.bounces);
            view.environment = settings.environment.as_ref().map(|env| {
                meshtracer::output::view_file::ViewEnvironment {
                    source: env.source.clone(),
                    rotation_degrees: env.rotation_degrees(),
                    intensity: env.intensity(),
                    visible: settings.environment_visible,
                    panorama: args
                        .env_out
                        .as_ref()
                        .map(|p| p.canonicalize().unwrap_or_else(|_| p.clone())),
                }
            });
        }
        view.denoise = denoised.as_ref().map(|(report, guide_samples, _)| {
            meshtracer::output::view_file::ViewDenoise {
                denoiser: "Intel Open Image Denoise".into(),
                version: report.library_version.clone(),
                filter: "RT".into(),
                hdr: true,
                guides: vec!["albedo".into(), "normal".into()],
                guide_samples_per_pixel: *guide_samples,
                clean_aux: true,
            }
        });
        view.write(path)?;
    }
    tiles::write_sidecar(args, region, &settings, scene)?;
    phases.mark("write", write_start);
    if let Some(path) = &args.stats {
        let json = serde_json::json!({
            "model": args.model,
            "triangles": scene.soup.len(),
            "width": width,
            "height": height,
            "spp": settings.spp,
            "threads": threads,
            "phases": phases.to_json(),
            "total_seconds": run_start.elapsed().as_secs_f64(),
            "peak_memory_bytes": peak_memory_bytes(),
            "rays": stats.rays(),
            "mrays_per_second": stats.mrays_per_second(),
            "denoised": denoised.is_some(),
        });
        meshtracer::output::write_atomic(path, serde_json::to_string_pretty(&json)?.as_bytes())?;
    }
    if !args.quiet {
        let structure = match accel.kind() {
            AccelKind::Bvh => format!(
                "BVH ({}) built in {:.1} ms",
                preset_label(args.bvh_preset, accel.preset()),
                accel.build_time().as_secs_f64() * 1e3
            ),
            AccelKind::Linear => "linear scan (no BVH)".to_string(),
        };
        let denoise_note = match &denoised {
            Some((report, _, total)) => format!(
                ", denoised by Open Image Denoise {} in {:.3} s (guides and filter)",
                report.library_version,
                total.as_secs_f64()
            ),
            None => String::new(),
        };
        eprintln!(
            "{}: {} triangles, loaded in {:.1} ms, {} MB of textures in {:.1} ms, {structure}, {width}x{height} at {} spp rendered in {:.3} s ({:.0} samples/s{}){denoise_note}, peak memory {}: {} rays ({} primary, {} shadow{}), {:.2} Mrays/s on {threads} threads -> {}",
            args.model.display(),
            scene.soup.len(),
            load_time.as_secs_f64() * 1e3,
            textures.bytes >> 20,
            texture_time.as_secs_f64() * 1e3,
            settings.spp,
            stats.time.as_secs_f64(),
            stats.samples_per_second(),
            stats
                .noise
                .map_or(String::new(), |n| format!(", noise ±{n:.4}")),
            peak_memory_bytes().map_or("unknown".to_string(), |b| format!("{} MB", b >> 20)),
            stats.rays(),
            stats.primary_rays,
            stats.shadow_rays,
            if stats.indirect_rays > 0 {
                format!(", {} indirect", stats.indirect_rays)
            } else {
                String::new()
            },
            stats.mrays_per_second(),
            args.output.display()
        );
    }
    on_view(1, 1);
    // Every path given was written above (AOVs whenever one is asked for).
    let outputs = std::iter::once(Some(&args.output))
        .chain(args.side_outputs().into_iter().map(|(_, path)| path));
    Ok(RenderReport {
        triangles: scene.soup.len(),
        load: load_time,
        bvh: accel.build_time(),
        render: stats.time,
        outputs: outputs.flatten().cloned().collect(),
        warnings,
    })
}

fn choose_camera(
    args: &RenderArgs,
    scene: &Scene,
    file_camera: Option<&Camera>,
    aspect: f32,
) -> Camera {
    let bounds = &scene.bounds;
    if let Some(from) = args.look_from {
        let at = args.look_at.unwrap_or(bounds.center());
        let distance = (at - from).length();
        let yfov = args.yfov.unwrap_or(DEFAULT_YFOV_DEGREES).to_radians();
        let mut camera = look_at(
            from,
            at,
            args.up.unwrap_or(glam::Vec3::Y),
            yfov,
            distance,
            bounds.radius(),
        );
        // The near plane follows the scene, not the look-at point (which may lie far beyond
        // the model, or the scene may surround the eye).
        if let Projection::Perspective { znear, .. } = &mut camera.projection {
            *znear = meshtracer::camera::near_plane(from, bounds.center(), bounds.radius());
        }
        return camera;
    }
    let mut camera = match file_camera {
        Some(c) => c.clone(),
        None => auto_camera(bounds, aspect),
    };
    if let (Some(deg), Projection::Perspective { yfov, .. }) = (args.yfov, &mut camera.projection) {
        *yfov = deg.to_radians();
    }
    camera
}

fn progress_bar(quiet: bool) -> indicatif::ProgressBar {
    if quiet {
        return indicatif::ProgressBar::hidden();
    }
    // indicatif draws only when stderr is a terminal.
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} rendering [{bar:40}] {percent}% tiles {pos}/{len} eta {eta}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    bar
}

fn bench_command(args: &crate::cli::BenchArgs) -> Result<()> {
    use meshtracer::tools::bench::{
        generated_mesh, markdown_table, measure, scene_from_soup, BenchOptions,
    };
    for path in [&args.report, &args.plot].into_iter().flatten() {
        if path.is_dir() {
            bail!("{}: is a directory", path.display());
        }
    }
    if let Some(path) = &args.plot {
        let svg = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("svg"));
        if !svg {
            bail!(
                "--plot {}: the plot is written as SVG; name the file .svg",
                path.display()
            );
        }
    }
    if args.side == 0 || args.side > 8192 {
        bail!("--side {}: must be between 1 and 8192", args.side);
    }
    if args.path_spp > 4096 {
        bail!(
            "--path-spp {}: at most 4096 (render's --max-spp default)",
            args.path_spp
        );
    }
    if args.sizes.is_empty() && args.models.is_empty() {
        bail!("nothing to measure: name models, or generated sizes with --sizes");
    }
    if let Some(&n) = args
        .sizes
        .iter()
        .find(|&&n| n < 8 || n as u64 > args.load.max_triangles)
    {
        bail!("--sizes: {n} is outside 8..={}", args.load.max_triangles);
    }
    let (threads, pool) = worker_pool(args.threads)?;
    let options = BenchOptions {
        kind: args.rays,
        side: args.side,
        runs: args.runs.max(1),
        linear_budget: args.linear_budget,
        preset: args.bvh_preset,
    };
    // Ctrl-C once: finish the measurement under way, then report what is done (exit 130).
    // Twice: quit at once, writing nothing (a 1M-triangle linear scan can take a minute).
    let _ = QUIT_ON_SECOND_PRESS
        .set("stopping after the current measurement (Ctrl-C again to quit now)");
    let stop = interrupt_flag();
    let mut rows = Vec::new();
    let mut path_rows = Vec::new();
    let (mut generated_rows, mut model_rows) = (Vec::new(), Vec::new());
    let jobs: Vec<(String, Option<usize>, Option<&std::path::PathBuf>)> = args
        .sizes
        .iter()
        .map(|&n| (format!("generated {n}"), Some(n), None))
        .chain(args.models.iter().map(|p| {
            let name = p.file_name().map_or_else(
                || p.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            );
            (name, None, Some(p))
        }))
        .collect();
    for (i, (name, size, path)) in jobs.iter().enumerate() {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        if !args.quiet {
            eprintln!("[{}/{}] {name}: building and tracing...", i + 1, jobs.len());
        }
        let scene = match (size, path) {
            (Some(n), _) => scene_from_soup(generated_mesh(*n, 1), name),
            (None, Some(p)) => load(p, &load_options(&args.load))?,
            (None, None) => continue,
        };
        let row = pool.install(|| measure(&scene, name, &options))?;
        if !args.quiet {
            eprintln!(
                "      {} triangles: build {:.1} ms, BVH {:.2} Mrays/s{}",
                row.triangles,
                row.build.as_secs_f64() * 1e3,
                row.bvh_mrays,
                row.linear_mrays
                    .map_or(String::new(), |l| format!(", linear {l:.4} Mrays/s"))
            );
        }
        if size.is_some() {
            generated_rows.push(row.clone());
        } else {
            model_rows.push(row.clone());
        }
        rows.push(row);
        if args.path_spp > 0 && !stop.load(Ordering::SeqCst) {
            if !args.quiet {
                eprintln!(
                    "      path tracer against the BVH, {} alternating rounds...",
                    options.runs
                );
            }
            let settings = bench_path_settings(&scene, args.path_size, args.path_spp);
            let prepare = meshtracer::prepare::PrepareOptions {
                bvh_preset: args.bvh_preset,
                ..Default::default()
            };
            let row = pool.install(|| -> Result<meshtracer::tools::bench::PathRow> {
                let mut warnings = Vec::new();
                let prepared = meshtracer::prepare::Prepared::new(scene, &prepare, &mut warnings)
                    .with_context(|| format!("{name}: textures"))?;
                if !args.quiet {
                    for w in &warnings {
                        eprintln!("warning: {name}: {w}");
                    }
                }
                Ok(meshtracer::tools::bench::path_versus_bvh(
                    &prepared,
                    &settings,
                    name,
                    args.side,
                    options.runs,
                )?)
            })?;
            path_rows.push(row);
        }
    }
    let mut table = markdown_table(&rows);
    if !path_rows.is_empty() {
        table.push('\n');
        table.push_str(&meshtracer::tools::bench::path_table(&path_rows));
    }
    out!("{table}");
    let partial = (rows.len() < jobs.len()).then(|| {
        format!(
            "stopped early: {} of {} measurements",
            rows.len(),
            jobs.len()
        )
    });
    let settings = format!(
        "{:?} rays ({} primary rays per run, shadow/diffuse rays from their hits), median of {} runs, {threads} threads, obvhs preset {:?}, linear scan budget {} triangle tests; CPU: {}{}",
        args.rays,
        u64::from(args.side) * u64::from(args.side),
        options.runs,
        args.bvh_preset,
        args.linear_budget,
        cpu_name(),
        partial.as_ref().map_or(String::new(), |p| format!("; {p}"))
    );
    out!("{settings}");
    if let Some(path) = &args.report {
        let report = format!("# meshtracer bench\n\n{settings}\n\n{table}");
        meshtracer::output::write_atomic(path, report.as_bytes())?;
    }
    if let Some(path) = &args.plot {
        let title = format!("time per {:?} ray vs triangles", args.rays).to_lowercase();
        let svg = meshtracer::tools::plot::scaling_plot(&generated_rows, &model_rows, &title)?;
        meshtracer::output::write_atomic(path, svg.as_bytes())?;
    }
    match partial {
        Some(p) => Err(Interrupted(format!("{p} reported")).into()),
        None => Ok(()),
    }
}

/// What `bench --path-spp` renders: `scene`'s default view at `size` with the path tracer
/// and `spp` samples, lit as `render --integrator path` lights it (the file's lights, else the
/// built-in studio environment and no light rig).
fn bench_path_settings(
    scene: &meshtracer::scene::Scene,
    (width, height): (u32, u32),
    spp: u32,
) -> RenderSettings {
    let mut settings = meshtracer::setup::default_settings(scene, width, height);
    settings.integrator = meshtracer::integrator::IntegratorKind::Path;
    settings.spp = spp;
    let lit = lighting(
        &scene.lights,
        None,
        &settings.view,
        LightingOptions::new(settings.integrator),
    );
    settings.lights = lit.lights;
    settings.ambient = lit.ambient;
    settings.environment = lit.environment;
    settings
}

/// The user stopped a command with Ctrl-C after it reported what it had finished: exit 130,
/// like a render that was interrupted, so that a script never takes partial results for whole.
#[derive(Debug, thiserror::Error)]
#[error("interrupted; {0}")]
pub struct Interrupted(pub String);

/// The CPU model, for reports.
fn cpu_name() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|info| {
            info.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into())
}

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
    let background = args.background.map(|c| {
        // Accept 0-1 or 0-255 components.
        let scale = if c.max_element() <= 1.0 { 255.0 } else { 1.0 };
        (c * scale)
            .clamp(glam::Vec3::ZERO, glam::Vec3::splat(255.0))
            .round()
            .to_array()
            .map(|v| v as u8)
    });
    let (metrics, a, b, heat) = compare_files(&args.a, &args.b, background)?;
    if let Some(path) = &args.diff_out {
        let mut png = Vec::new();
        heat.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .context("encoding the heatmap")?;
        meshtracer::output::write_atomic(path, &png)?;
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
