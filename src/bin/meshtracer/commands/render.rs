//! `render MODEL -o IMAGE`: one view of one model. Every option that can be refused is refused
//! before any work; then the image file is reserved, the model loaded, the view framed and lit,
//! the scene prepared and rendered (and denoised with `--denoise`), and the image and its side
//! outputs written. `--views` and `--turntable` hand over to commands/views.rs once the options
//! both flows share are checked.

use super::{
    check_lighting, check_size, image_size, interrupt_flag, lighting_options, load,
    peak_memory_bytes, prepare_scene, preset_label, render_load_options, report_load,
    start_load_threads, tiles, views, worker_pool, Phases, PreparedModel, RenderReport,
};
use crate::cli::RenderArgs;
use anyhow::{bail, Context, Result};
use meshtracer::accel::AccelKind;
use meshtracer::camera::{auto_camera, look_at, View};
use meshtracer::defaults::DEFAULT_YFOV_DEGREES;
use meshtracer::integrator::IntegratorKind;
use meshtracer::light::environment::Environment;
use meshtracer::output::PendingOutput;
use meshtracer::prepare::Prepared;
use meshtracer::render::{render, render_region, RenderSettings};
use meshtracer::scene::{Camera, Projection, Scene};
use meshtracer::setup::{lighting, Lighting, RecordedLighting};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

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

pub(super) fn render_command(args: &RenderArgs) -> Result<()> {
    render_model(args, &|_, _| {}).map(|_| ())
}

/// Renders one model as `render` does, calling `on_view(done, total)` as views finish.
pub(super) fn render_model(
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
        // The scene may surround the eye: clip only very close to it.
        if let Projection::Perspective { znear, .. } = &mut camera.projection {
            let to_centre = (bounds.center() - from).length();
            if to_centre <= bounds.radius() {
                *znear = bounds.radius() * 1e-5;
            }
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
