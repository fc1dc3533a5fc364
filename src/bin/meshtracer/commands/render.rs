//! `render MODEL -o IMAGE`: one view of one model. Every option that can be refused is refused
//! before any work; then the image file is reserved, the model loaded, the view framed and lit,
//! the scene prepared and rendered (and denoised with `--denoise`), and the image and its side
//! outputs written. `--views` and `--turntable` hand over to commands/views.rs once the options
//! both flows share are checked.

use super::{
    check_lighting, check_size, frames, image_size, interrupt_flag, lighting_options, load,
    peak_memory_bytes, prepare_scene, preset_label, record_render, render_load_options,
    report_load, start_load_threads, tiles, views, worker_pool, write_panorama, Phases,
    PreparedModel, RenderReport,
};
use crate::cli::RenderArgs;
use anyhow::{bail, Context, Result};
use meshtracer::accel::AccelKind;
use meshtracer::camera::{auto_camera, look_at, ThinLens, View};
use meshtracer::defaults::DEFAULT_YFOV_DEGREES;
use meshtracer::integrator::IntegratorKind;
use meshtracer::light::environment::Environment;
use meshtracer::output::view_file::ViewFile;
use meshtracer::output::PendingOutput;
use meshtracer::prepare::Prepared;
use meshtracer::render::denoise::{Denoised, Denoiser, Guides};
use meshtracer::render::{render, render_region, Aovs, Image, Region, RenderSettings, RenderStats};
use meshtracer::scene::{Camera, Light, Projection, Scene};
use meshtracer::setup::{lighting, Lighting, RecordedLighting};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Most path bounces `--bounces` accepts: far beyond any visible difference.
const MAX_BOUNCES: u32 = meshtracer::output::view_file::MAX_VIEW_BOUNCES;

/// `meshtracer render`.
pub(super) fn render_command(args: &RenderArgs) -> Result<()> {
    // A batch passes its --resume to every job; only a run of many views resumes within it.
    if args.resume && args.views.is_none() && args.turntable.is_none() {
        bail!("--resume keeps the finished views of an interrupted --views or --turntable run (a single render has nothing to keep; batch --resume skips finished jobs)");
    }
    if args.shard.is_some() && args.views.is_none() && args.turntable.is_none() {
        bail!("--shard I/N splits the views of --views or --turntable (a single image splits into tiles with --tile; batch --shard splits jobs)");
    }
    render_model(args, &|_, _| {}).map(|_| ())
}

/// Renders one model as `render` does, calling `on_view(done, total)` as views finish.
pub(super) fn render_model(
    args: &RenderArgs,
    on_view: &(dyn Fn(usize, usize) + Sync),
) -> Result<RenderReport> {
    let run_start = Instant::now();
    // Before any output is reserved: a Ctrl-C or a scheduler's SIGTERM during the load or the
    // BVH build would otherwise kill the process, leaving the reserved temporary file behind.
    interrupt_flag();
    start_load_threads(args.threads);
    // Everything that can be refused is refused before any work: options, output, then model.
    check_image_options(args)?;
    let view_file = read_view_file(args)?;
    check_output_and_lighting_options(args)?;
    let env_file = load_environment(args)?;
    if let Some(spec) = &args.views {
        // Many views after one load and one BVH build: its own flow, in commands/views.rs.
        return views::render_views(args, spec, env_file, on_view);
    }
    if let Some(frames) = args.turntable {
        // A turntable is an orbit (starting where the plain render stands).
        return views::render_views(args, &format!("orbit:{frames}"), env_file, on_view);
    }
    if let Some(frames) = args.frames {
        // An animation's frames, each loaded in its own pose: commands/frames.rs.
        return frames::render_frames(args, frames, env_file, on_view);
    }
    if args.contact_sheet.is_some() {
        bail!("--contact-sheet lays out many views: add --views SPEC or --turntable N (or give it to batch, for a cell per job)");
    }
    let report = render_one(args, view_file.as_ref(), env_file, run_start, None)?;
    on_view(1, 1);
    Ok(report)
}

/// The single view of `render_model` once its options are checked: reserves the output,
/// loads the model, frames and lights the view, renders it and writes its files. `camera`,
/// when given, replaces the camera the options choose (the frames of `--frames` share one).
pub(super) fn render_one(
    args: &RenderArgs,
    view_file: Option<&ViewFile>,
    env_file: Option<Environment>,
    run_start: Instant,
    camera: Option<&Camera>,
) -> Result<RenderReport> {
    let cancel = interrupt_flag();
    let outputs = single_view_outputs(args);
    let outputs: Vec<_> = outputs.iter().map(|(o, p)| (*o, p.as_path())).collect();
    meshtracer::output::check_destinations(&outputs, &run_inputs(args), args.no_clobber)?;
    let output = PendingOutput::reserve(&args.output, args.no_clobber)?;
    let (threads, pool) = worker_pool(args.threads)?;

    let mut phases = Phases::default();
    let (scene, load_time) = load_model(args, &mut phases)?;
    let referred: Vec<_> = scene
        .inputs
        .iter()
        .map(|p| ("a file the model refers to", p.as_path()))
        .collect();
    meshtracer::output::check_not_inputs(&outputs, &referred)?;
    stop_if_cancelled(&cancel)?;
    let mut shot = choose_view(args, &scene, view_file)?;
    if let Some(camera) = camera {
        shot.camera = camera.clone();
    }
    let view = View::from_camera(&shot.camera, shot.width, shot.height);
    let view = with_thin_lens(args, view, &scene, view_file)?;
    let lit = light_view(args, &scene.lights, view_file, &view, env_file)?;
    let using_rig = lit.default_rig;
    let mut settings = render_settings(args, view, lit);
    let rendered = pool
        .install(|| prepare_and_render(args, scene, &mut settings, &shot, &cancel, &mut phases))?;
    let done = Finished {
        load_time: load_time + rendered.tangents,
        shot,
        settings,
        using_rig,
        rendered,
        threads,
    };

    let write_start = Instant::now();
    write_outputs(args, output, &done)?;
    phases.mark("write", write_start);
    if let Some(path) = &args.stats {
        write_stats(path, args, &done, &phases, run_start)?;
    }
    if !args.quiet {
        print_summary(args, &done);
    }
    Ok(done.report(args))
}

/// Every file a single-view render writes, with the option that names it: the image, then
/// [`RenderArgs::side_outputs`], then a denoised render's tile's denoise input
/// ([`tiles::denoise_input`]).
fn single_view_outputs(args: &RenderArgs) -> Vec<(&'static str, std::path::PathBuf)> {
    std::iter::once(("-o", args.output.clone()))
        .chain(
            args.side_outputs()
                .into_iter()
                .filter_map(|(option, path)| path.map(|p| (option, p.clone()))),
        )
        .chain(tiles::denoise_input(args))
        .collect()
}

/// The files a render reads that its command line names: the model, the `--env` panorama
/// and the `--view` file (an output must not be one of them).
pub(super) fn run_inputs(args: &RenderArgs) -> Vec<(&'static str, &Path)> {
    let mut inputs = vec![("the model this run renders", args.model.as_path())];
    if let Some(env) = &args.env {
        inputs.push(("the --env panorama", env.as_path()));
    }
    if let Some(view) = &args.view {
        inputs.push(("the --view file", view.as_path()));
    }
    inputs
}

/// Stops a run whose Ctrl-C (or SIGTERM, SIGHUP) came during the load, before the BVH build
/// and the render: exit 130, as a cancelled render ends.
pub(super) fn stop_if_cancelled(cancel: &AtomicBool) -> Result<()> {
    if cancel.load(Ordering::SeqCst) {
        return Err(meshtracer::render::Cancelled.into());
    }
    Ok(())
}

/// Refuses, in this order, the sampling and image options that are wrong on their own:
/// `--spp` (1 to `--max-spp`), `--time-limit`, `--exposure`, `--yfov`, and
/// `--width`/`--height` (at least 1, and within `--max-pixels` when both are given); then the
/// camera options ([`check_camera_options`]).
fn check_image_options(args: &RenderArgs) -> Result<()> {
    if args.spp() == 0 || args.spp() > args.max_spp {
        bail!(
            "--spp {}: must be between 1 and {} (raise the limit with --max-spp)",
            args.spp(),
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
    if let Some(yfov) = args.yfov {
        if !(yfov > 0.0 && yfov < 180.0) {
            bail!("--yfov {yfov}: must be between 0 and 180 degrees");
        }
    }
    if let Some(r) = args.aperture_radius {
        if !(r.is_finite() && r >= 0.0) {
            bail!("--aperture-radius {r}: must be a finite number, 0 or more (scene units)");
        }
    }
    if let Some(f) = args.focus_distance {
        if !(f.is_finite() && f > 0.0) {
            bail!("--focus-distance {f}: must be a finite number above 0 (scene units)");
        }
    }
    if let (Some(w), Some(h)) = (args.width, args.height) {
        check_size(args, w, h)?;
    } else if args.width == Some(0) || args.height == Some(0) {
        bail!("image width and height must be at least 1");
    }
    check_camera_options(args)
}

/// Refuses a camera the options cannot make, as a views file's entry is refused: a zero
/// `--up`, a `--look-from` at its `--look-at`, an `--up` along the view between them. (With
/// the default up, a view straight down or up takes +Z as up instead.)
fn check_camera_options(args: &RenderArgs) -> Result<()> {
    let text = |v: glam::Vec3| format!("{},{},{}", v.x, v.y, v.z);
    if let Some(up) = args.up.filter(|u| *u == glam::Vec3::ZERO) {
        bail!("--up {}: the up vector must not be zero", text(up));
    }
    if let (Some(from), Some(at)) = (args.look_from, args.look_at) {
        let Some(view) = (at - from).try_normalize() else {
            bail!(
                "--look-from and --look-at are the same point ({}): the camera needs a direction",
                text(from)
            );
        };
        if let Some(up) = args.up {
            if meshtracer::camera::across_view(view, up).is_none() {
                bail!(
                    "--up {}: along the view from --look-from to --look-at; give an up vector across it",
                    text(up)
                );
            }
        }
    }
    Ok(())
}

/// The `--view` file, read and its image size refused over the limits as `--width` and
/// `--height` are (which it overrides, with a warning when they are given); `None` without
/// `--view`. Keys no view file has (a typo: `yfvo`) are named in a warning, and refused
/// under `--strict`.
fn read_view_file(args: &RenderArgs) -> Result<Option<ViewFile>> {
    let Some(path) = &args.view else {
        return Ok(None);
    };
    let (view_file, unknown) = ViewFile::read(path)?;
    if !unknown.is_empty() {
        let keys: Vec<String> = unknown.iter().map(|k| format!("'{k}'")).collect();
        let what = format!(
            "{}: unknown key{} {} (misspelt?)",
            path.display(),
            if keys.len() == 1 { "" } else { "s" },
            keys.join(", ")
        );
        if args.strict {
            bail!("{what}: --strict refuses the file");
        }
        if !args.no_warnings {
            note!("warning: {what}: ignored");
        }
    }
    check_size(args, view_file.image.width, view_file.image.height)?;
    if (args.width.is_some() || args.height.is_some()) && !args.no_warnings {
        note!(
            "warning: --width and --height are ignored: {} sets the image size ({}x{})",
            path.display(),
            view_file.image.width,
            view_file.image.height
        );
    }
    Ok(Some(view_file))
}

/// Refuses, in this order: an AOV file whose format cannot hold it, `--depth-scale`, the
/// environment options without the path tracer, `--env-intensity`, `--env-rotation`, a
/// negative `--ambient`, `--bounces`, an `--env-out` that is not `.hdr`, a `--stats` that is
/// not `.json`, and a tile the merge could not join exactly ([`tiles::check_render`]).
fn check_output_and_lighting_options(args: &RenderArgs) -> Result<()> {
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
    if let Some(a) = args.ambient.filter(|a| a.min_element() < 0.0) {
        bail!(
            "--ambient {},{},{}: must be 0 or more (a negative radiance would take light away)",
            a.x,
            a.y,
            a.z
        );
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
    tiles::check_render(args)
}

/// The `--env` panorama, loaded, turned by `--env-rotation` and scaled by `--env-intensity`;
/// `None` without `--env`. The last refusal before the flows part: a file that cannot be read
/// fails one view and many alike.
fn load_environment(args: &RenderArgs) -> Result<Option<Environment>> {
    match &args.env {
        Some(path) => Ok(Some(
            Environment::load(path)?.with_transform(args.env_rotation, args.env_intensity),
        )),
        None => Ok(None),
    }
}

/// Loads the model as `render` loads it ([`render_load_options`]), timing the parse and flatten
/// (and its steps) into `phases`, and prints its warnings (unless `--no-warnings`) and pose (unless `--quiet`). Returns
/// the scene and the wall time of the load so far (the tangents come later, in the prepare).
fn load_model(args: &RenderArgs, phases: &mut Phases) -> Result<(Scene, Duration)> {
    let load_start = Instant::now();
    let load_options = render_load_options(args);
    let scene = load(&args.model, &load_options)?;
    phases.mark("parse and flatten", load_start);
    phases.sub_steps(&scene.load_steps);
    let load_time = load_start.elapsed();
    report_load(args, &scene);
    Ok((scene, load_time))
}

/// The single view: its camera, its image size and the part of the image rendered.
struct Shot {
    camera: Camera,
    width: u32,
    height: u32,
    /// The whole image, or the tile of `--tile` or `--crop`.
    region: Region,
}

/// `view` with the depth of field asked for: `--aperture-radius` (focused at
/// `--focus-distance`, else at the view-axis depth of `--look-at` or of the scene's centre),
/// else the `--view` file's thin lens, else the pinhole. Refuses a default focus behind the
/// camera.
fn with_thin_lens(
    args: &RenderArgs,
    view: View,
    scene: &Scene,
    view_file: Option<&ViewFile>,
) -> Result<View> {
    let Some(aperture_radius) = args.aperture_radius else {
        let lens = match view_file {
            Some(file) => file.camera.thin_lens().map_err(|problem| {
                anyhow::anyhow!(
                    "{}: {problem}",
                    args.view
                        .as_deref()
                        .unwrap_or(Path::new("--view"))
                        .display()
                )
            })?,
            None => None,
        };
        return Ok(match lens {
            Some(lens) => view.with_thin_lens(lens),
            None => view,
        });
    };
    let focus_distance = match args.focus_distance {
        Some(f) => f,
        None => {
            let (target, what) = match args.look_at {
                Some(at) => (at, "--look-at"),
                None => (scene.bounds.center(), "the scene's centre"),
            };
            view.depth_of(target).with_context(|| {
                format!("--aperture-radius: {what} is not in front of the camera, so it cannot be the plane in focus: give --focus-distance")
            })?
        }
    };
    Ok(view.with_thin_lens(ThinLens {
        aperture_radius,
        focus_distance,
    }))
}

/// Frames the single view. The `--view` file gives the camera and size; else the size comes
/// from the options and the camera that frames the view ([`image_size`]: not the file's camera
/// under `--look-from`), and the camera from [`choose_camera`]. Refuses, in this order, a
/// `--camera` the file lacks, a size over the limits, a view file's camera it cannot use and a
/// tile that does not fit the image.
fn choose_view(args: &RenderArgs, scene: &Scene, view_file: Option<&ViewFile>) -> Result<Shot> {
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
    let (width, height) = match view_file {
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
    let camera = match view_file {
        Some(v) => v.camera()?,
        None => choose_camera(args, scene, file_camera, aspect),
    };
    let region = tiles::region(args, width, height)?;
    Ok(Shot {
        camera,
        width,
        height,
        region,
    })
}

/// The camera of a single view without a view file: `--look-from` (towards `--look-at`, else
/// the model's centre), else the file's camera, else the automatic one for `aspect`; `--yfov`
/// overrides the field of view of a perspective camera.
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
        None => auto_camera(bounds, &scene.soup.positions, aspect),
    };
    if let (Some(deg), Projection::Perspective { yfov, .. }) = (args.yfov, &mut camera.projection) {
        *yfov = deg.to_radians();
    }
    camera
}

/// The lighting of the single view ([`lighting`]): the lights, ambient and environment the
/// `--view` file recorded, else the file's `scene_lights` or the default rig placed for `view`.
/// A view file's environment lights the path tracer again unless `--env` replaces it. Refuses
/// what [`check_lighting`] refuses.
fn light_view(
    args: &RenderArgs,
    scene_lights: &[Light],
    view_file: Option<&ViewFile>,
    view: &View,
    env_file: Option<Environment>,
) -> Result<Lighting> {
    let path_tracing = args.integrator == IntegratorKind::Path;
    let recorded = match view_file {
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
    let lit = lighting(
        scene_lights,
        recorded,
        view,
        lighting_options(args, env_file),
    );
    check_lighting(args, &lit.lights, lit.environment.as_deref())?;
    Ok(lit)
}

/// The settings of the single view's render: `view` lit by `lit` (`--ambient` overrides its
/// ambient), the sampling and shading options, and AOVs when a depth, normal or segmentation
/// file is asked for.
fn render_settings(args: &RenderArgs, view: View, lit: Lighting) -> RenderSettings {
    let Lighting {
        lights,
        ambient: default_ambient,
        environment,
        default_rig: _,
    } = lit;
    RenderSettings {
        view,
        spp: args.spp(),
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
        noise: args.noise(),
        clamp_indirect: args.clamp_indirect,
        guides: args.denoises(),
    }
}

/// What [`prepare_and_render`] hands back.
struct Rendered {
    /// The scene as rendered.
    prepared: Prepared,
    /// The warnings of the load and the texture decoding.
    warnings: Vec<String>,
    /// Wall time of the tangent generation (part of the load, as the summary reports it).
    tangents: Duration,
    /// Wall time of the texture decoding.
    textures: Duration,
    image: Image,
    stats: RenderStats,
    /// The AOVs, when [`RenderSettings::aovs`] asked for them.
    aovs: Option<Aovs>,
    /// What `--denoise` did, when asked (for a whole image).
    denoised: Option<Denoising>,
    /// A denoised render's tile: the guides of its pixels, kept with its film for `merge`,
    /// which denoises the whole image.
    denoise_guides: Option<Guides>,
}

/// What `--denoise` did.
pub(super) struct Denoising {
    /// The denoiser's own report (which filter, its version).
    pub(super) report: Denoised,
    /// Guide rays per pixel.
    pub(super) guide_samples: u32,
    /// Wall time of the guides and the filter together.
    pub(super) time: Duration,
}

/// Runs on the worker pool: prepares `scene` ([`prepare_scene`], the BVH preset chosen for the
/// rays this render will trace), fits `settings.spp` to `--time-limit`, renders the shot's
/// region with a progress bar (hidden under `--quiet`) and denoises it with `--denoise`; each
/// phase is timed into `phases`. A Ctrl-C (`cancel`) ends it with
/// [`meshtracer::render::Cancelled`].
fn prepare_and_render(
    args: &RenderArgs,
    scene: Scene,
    settings: &mut RenderSettings,
    shot: &Shot,
    cancel: &AtomicBool,
    phases: &mut Phases,
) -> Result<Rendered> {
    let rays = meshtracer::setup::expected_rays(
        u64::from(shot.width) * u64::from(shot.height),
        settings.spp,
        settings.noise.map(|_| settings.first_batch()),
        settings.lights.len(),
        settings.integrator,
        settings.bounces,
    );
    let PreparedModel {
        prepared,
        warnings,
        tangents,
        textures,
    } = prepare_scene(args, scene, rays, phases)?;
    let render_start = Instant::now();
    if let Some(limit) = args.time_limit {
        settings.spp = spp_for_time_limit(&prepared, settings, cancel, limit, args.max_spp)?;
    }
    let bar = progress_bar(args.quiet);
    let result = render_region(&prepared, settings, shot.region, cancel, &|done, total| {
        bar.set_length(total);
        bar.set_position(done);
    });
    bar.finish_and_clear();
    phases.mark("render", render_start);
    let (mut image, stats, aovs) = result?;
    let (mut denoised, mut denoise_guides) = (None, None);
    if args.denoises() && tiles::tiled(args) {
        // A tile is not denoised alone: the filter reaches across its edges.
        let guide_start = Instant::now();
        denoise_guides = Some(denoise_guides_of(
            &prepared,
            settings,
            shot.region,
            &mut image,
        ));
        phases.mark("denoise guides", guide_start);
    } else if args.denoises() {
        denoised = Some(denoise_image(
            &prepared,
            settings,
            shot.region,
            &mut image,
            cancel,
            phases,
        )?);
    }
    Ok(Rendered {
        prepared,
        warnings,
        tangents,
        textures,
        image,
        stats,
        aovs,
        denoised,
        denoise_guides,
    })
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
        noise: None,
        guides: false,
        ..settings.clone()
    };
    let (_, stats, _) = render(prepared, &calibration, cancel, &|_, _| {})?;
    let per_sample = stats.time.as_secs_f64().max(1e-6);
    let fit = ((limit - per_sample) / per_sample).floor();
    Ok((fit.max(1.0) as u32).min(max_spp.max(1)))
}

/// The progress bar of a render: hidden under `--quiet`, else drawn while standard error is a
/// terminal.
fn progress_bar(quiet: bool) -> indicatif::ProgressBar {
    bar_with_template(
        quiet,
        "{spinner} rendering [{bar:40}] {percent}% tiles {pos}/{len} eta {eta}",
    )
}

/// A progress bar drawn with indicatif's `template` (hidden under `--quiet`; indicatif draws
/// only when stderr is a terminal).
pub(super) fn bar_with_template(quiet: bool, template: &str) -> indicatif::ProgressBar {
    if quiet {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template(template)
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar
}

/// Denoises `image` in place (`--denoise`) on the linear HDR film, before the output encodes
/// it (sRGB PNG, EXR, HDR): the guides of `region` first, then the filter, each timed into
/// `phases`. A Ctrl-C during either ends it with [`meshtracer::render::Cancelled`].
pub(super) fn denoise_image(
    prepared: &Prepared,
    settings: &RenderSettings,
    region: Region,
    image: &mut Image,
    cancel: &AtomicBool,
    phases: &mut Phases,
) -> Result<Denoising> {
    let guide_start = Instant::now();
    let guides = denoise_guides_of(prepared, settings, region, image);
    phases.mark("denoise guides", guide_start);
    let denoise_start = Instant::now();
    let guide_samples = guides.samples_per_pixel;
    let report = meshtracer::render::denoise::denoise(image, guides)?;
    phases.mark("denoise", denoise_start);
    if cancel.load(Ordering::SeqCst) {
        return Err(meshtracer::render::Cancelled.into());
    }
    Ok(Denoising {
        report,
        guide_samples,
        time: guide_start.elapsed(),
    })
}

/// The denoiser's guides of `image`, the rendered `region`: the path tracer averaged them over
/// each pixel's own samples (taken out of `image`); the direct integrator's are traced here.
fn denoise_guides_of(
    prepared: &Prepared,
    settings: &RenderSettings,
    region: Region,
    image: &mut Image,
) -> Guides {
    match image.guides.take() {
        Some(guides) => guides,
        None => meshtracer::render::denoise::guides(prepared, settings, region),
    }
}

/// A rendered single view, for the steps that write and report it.
struct Finished {
    shot: Shot,
    /// As rendered (`--time-limit` may have changed the spp).
    settings: RenderSettings,
    /// Whether the default light rig lit the view (the view file records it).
    using_rig: bool,
    rendered: Rendered,
    /// Wall time of the load, tangents included.
    load_time: Duration,
    /// Worker threads of the render.
    threads: usize,
}

impl Finished {
    /// What the render did, for a caller that records it (batch). Every path given was
    /// written (AOVs whenever one is asked for).
    fn report(self, args: &RenderArgs) -> RenderReport {
        let outputs = std::iter::once(Some(&args.output))
            .chain(args.side_outputs().into_iter().map(|(_, path)| path));
        RenderReport {
            triangles: self.rendered.prepared.scene.soup.len(),
            load: self.load_time,
            bvh: self.rendered.prepared.accel.build_time(),
            render: self.rendered.stats.time,
            outputs: outputs.flatten().cloned().collect(),
            warnings: self.rendered.warnings,
            inputs: self.rendered.prepared.scene.inputs.clone(),
        }
    }
}

/// Writes the single view's files, in this order: the image (into the file reserved before the
/// load), the terminal preview (`--preview`), the AOVs, the mask, the `--env-out` panorama, the
/// `--view-out` view file and the tile's sidecar.
fn write_outputs(args: &RenderArgs, output: PendingOutput, done: &Finished) -> Result<()> {
    let image = &done.rendered.image;
    let background = args.background;
    output.commit(image, background, args.tonemap)?;
    if let Some(mode) = args.preview {
        meshtracer::output::preview::show(image, background, args.tonemap, mode)
            .context("--preview")?;
    }
    write_aovs(args, image, done.rendered.aovs.as_ref())?;
    if let (Some(path), Some(env)) = (&args.env_out, &done.settings.environment) {
        write_panorama(path, env)?;
    }
    if let Some(path) = &args.view_out {
        view_record(args, done).write(path)?;
    }
    let denoise_input = done.rendered.denoise_guides.as_ref().map(|g| (image, g));
    tiles::write_sidecar(
        args,
        done.shot.region,
        &done.settings,
        &done.rendered.prepared.scene,
        denoise_input,
    )
}

/// Writes the AOV files asked for, in this order: depth, normals, segmentation (from `aovs`,
/// rendered when any of them is asked for), then the mask (from `image`'s coverage).
fn write_aovs(args: &RenderArgs, image: &Image, aovs: Option<&Aovs>) -> Result<()> {
    if let Some(a) = aovs {
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
        super::warn_png_losses(
            args,
            args.depth_out.as_deref(),
            args.segmentation_out.as_deref(),
            a,
        );
    }
    if let Some(p) = &args.mask_out {
        let coverage: Vec<f32> = image.pixels.iter().map(|p| p.w).collect();
        meshtracer::output::aov::write_mask(p, image.width, image.height, &coverage)?;
    }
    Ok(())
}

/// The `--view-out` record of the single view: what `render --view` reads back to render it
/// again (camera, size, lights, integrator and environment, depth scale), the segmentation ids
/// of the mesh instances, and the denoiser's settings when `--denoise` ran.
fn view_record(args: &RenderArgs, done: &Finished) -> ViewFile {
    let settings = &done.settings;
    let mut view = ViewFile::new(
        &done.shot.camera,
        done.shot.width,
        done.shot.height,
        &settings.lights,
        settings.ambient,
        done.using_rig,
    );
    record_render(
        &mut view,
        args,
        &done.rendered.prepared.scene,
        settings.environment.as_ref(),
    );
    view.denoise = done.rendered.denoised.as_ref().map(view_denoise);
    view.camera.set_thin_lens(settings.view.thin_lens);
    view
}

/// The view file's record of how an image was denoised.
pub(super) fn view_denoise(d: &Denoising) -> meshtracer::output::view_file::ViewDenoise {
    meshtracer::output::view_file::ViewDenoise {
        denoiser: d.report.denoiser.name().into(),
        version: d.report.version.clone(),
        filter: d.report.denoiser.filter().into(),
        hdr: true,
        guides: d.report.guides().iter().map(|g| g.to_string()).collect(),
        guide_samples_per_pixel: d.guide_samples,
        clean_aux: true,
    }
}

/// Writes `--stats`: the image, the threads, each phase's time and peak memory (`phases`), the
/// whole run's since `run_start`, and the ray counts.
fn write_stats(
    path: &Path,
    args: &RenderArgs,
    done: &Finished,
    phases: &Phases,
    run_start: Instant,
) -> Result<()> {
    let stats = &done.rendered.stats;
    let json = serde_json::json!({
        "model": args.model,
        "triangles": done.rendered.prepared.scene.soup.len(),
        "width": done.shot.width,
        "height": done.shot.height,
        "spp": done.settings.spp,
        "threads": done.threads,
        "phases": phases.to_json(),
        "total_seconds": run_start.elapsed().as_secs_f64(),
        "peak_memory_bytes": peak_memory_bytes(),
        "samples": stats.samples,
        "noise": stats.noise,
        "rays": stats.rays(),
        "rays_by_kind": {
            "primary": stats.primary_rays,
            "shadow": stats.shadow_rays,
            "indirect": stats.indirect_rays,
        },
        "mrays_per_second": stats.mrays_per_second(),
        "denoised": done.rendered.denoised.is_some(),
        "denoiser": done.rendered.denoised.as_ref().map(|d| d.report.denoiser.id()),
    });
    meshtracer::output::write_atomic(path, serde_json::to_string_pretty(&json)?.as_bytes())?;
    Ok(())
}

/// The filter that ran, as the summary names it: "Open Image Denoise 2.5.1" or "the built-in
/// à-trous filter".
pub(super) fn denoiser_label(report: &Denoised) -> String {
    match report.denoiser {
        Denoiser::Oidn => format!("Open Image Denoise {}", report.version),
        Denoiser::Atrous => "the built-in à-trous filter".to_string(),
    }
}

/// The summary's textures: "no textures", or their decoded size (MB, or KB under one MB) and
/// decoding time.
fn textures_label(bytes: usize, time: Duration, reused: bool) -> String {
    let ms = time.as_secs_f64() * 1e3;
    let how = match reused {
        true => "kept from the last frame".to_string(),
        false => format!("in {ms:.1} ms"),
    };
    match bytes {
        0 => "no textures".to_string(),
        b if b < 1 << 20 => format!("{} KB of textures {how}", b.div_ceil(1 << 10)),
        b => format!("{} MB of textures {how}", b >> 20),
    }
}

/// Prints the one summary line of a single-view render on standard error: the load, the
/// textures, the acceleration structure, the render and its rays, the denoiser, peak memory.
fn print_summary(args: &RenderArgs, done: &Finished) {
    let Rendered {
        prepared,
        textures: texture_time,
        stats,
        denoised,
        ..
    } = &done.rendered;
    let (scene, accel) = (&prepared.scene, &prepared.accel);
    let (width, height, threads) = (done.shot.width, done.shot.height, done.threads);
    let structure = match accel.kind() {
        AccelKind::Bvh => format!(
            "BVH ({}) built in {:.1} ms",
            preset_label(args.bvh_preset, accel.preset()),
            accel.build_time().as_secs_f64() * 1e3
        ),
        AccelKind::Linear => "linear scan (no BVH)".to_string(),
    };
    let denoise_note = match denoised {
        Some(d) => format!(
            ", denoised by {} in {:.3} s (guides and filter)",
            denoiser_label(&d.report),
            d.time.as_secs_f64()
        ),
        None if done.rendered.denoise_guides.is_some() => {
            ", film and guides kept for merge to denoise".to_string()
        }
        None => String::new(),
    };
    let region = done.shot.region;
    let size = if region == meshtracer::render::Region::full(width, height) {
        format!("{width}x{height}")
    } else {
        format!(
            "{}x{} of {width}x{height} from ({}, {})",
            region.width, region.height, region.x, region.y
        )
    };
    // Depth of field, when asked for: said beside the size, since it changes the picture.
    let size = match done.settings.view.thin_lens {
        Some(lens) => format!(
            "{size} through a lens of radius {} focused at {}",
            super::length_label(lens.aperture_radius),
            super::length_label(lens.focus_distance)
        ),
        None => size,
    };
    let spp = super::spp_label(
        done.settings.spp,
        done.settings.noise,
        stats.samples,
        // The pixels rendered: a tile's own, not the whole image's.
        u64::from(region.width) * u64::from(region.height),
    );
    note!(
        "{}: {}, loaded in {:.1} ms, {}, {structure}, {size} at {spp} rendered in {:.3} s ({:.0} samples/s{}){denoise_note}, peak memory {}: {} rays ({} primary, {} shadow{}), {:.2} Mrays/s on {} -> {}",
        // The file drawn: the model given, or the one inside the archive or folder given.
        scene.source.display(),
        super::counted(scene.soup.len(), "triangle"),
        done.load_time.as_secs_f64() * 1e3,
        textures_label(
            prepared.textures.bytes,
            *texture_time,
            prepared.textures.reused(),
        ),
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
        super::threads_label(threads),
        args.output.display()
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn textures_are_counted_in_kilobytes_under_a_megabyte() {
        let ms = Duration::from_micros(2500);
        assert_eq!(textures_label(0, ms, false), "no textures");
        assert_eq!(textures_label(1, ms, false), "1 KB of textures in 2.5 ms");
        assert_eq!(
            textures_label(1025, ms, false),
            "2 KB of textures in 2.5 ms"
        );
        assert_eq!(
            textures_label(3 << 20, ms, false),
            "3 MB of textures in 2.5 ms"
        );
        assert_eq!(
            textures_label(3 << 20, ms, true),
            "3 MB of textures kept from the last frame"
        );
    }
}
