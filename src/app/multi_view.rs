//! `render MODEL --views SPEC -o DIR`: many views of one model after one load and one BVH
//! build. The spec becomes cameras ([`crate::views`]); every view is rendered from the
//! prepared scene with the same settings and writes its image, the AOVs asked for and its view
//! file; the folder gets one `transforms.json` ([`crate::dataset`]).
//!
//! Kept apart from the single-view flow in `app.rs`, which hands over after checking the
//! options they share.

use super::{check_size, image_size, interrupt_flag, load, worker_pool, Interrupted, RenderReport};
use crate::accel::{Accel, AccelKind};
use crate::camera::{auto_camera, framing_distance, framing_radius, View};
use crate::cli::RenderArgs;
use crate::dataset::{camera_to_world, Dataset, Frame, Intrinsics};
use crate::environment::Environment;
use crate::integrator::IntegratorKind;
use crate::output::{OutputFormat, PendingOutput};
use crate::prepare::Prepared;
use crate::render::{render, RenderSettings, RenderStats};
use crate::scene::{Camera, Light, Projection, Scene};
use crate::setup::{default_rig, AMBIENT_WITH_FILE_LIGHTS, DEFAULT_YFOV_DEGREES};
use crate::view::{SegmentId, ViewEnvironment, ViewFile};
use crate::views::{
    fibonacci_directions, orbit_directions, random_directions, read_views_file, ExplicitView,
    Framing, NamePattern, ViewSpec,
};
use anyhow::{bail, Context, Result};
use glam::Vec3;
use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The camera file of the folder, for NeRF and Gaussian-splatting tools.
const TRANSFORMS_FILE: &str = "transforms.json";

/// The names of one view's files, relative to the output folder (absolute when the pattern
/// was): what `transforms.json` records.
struct ViewNames {
    image: String,
    depth: Option<String>,
    normal: Option<String>,
    mask: Option<String>,
    segmentation: Option<String>,
    view: String,
}

/// The file-name patterns of the outputs asked for; `None` for the image and the view file
/// means the default numbered name.
struct Layout {
    image: Option<NamePattern>,
    depth: Option<NamePattern>,
    normal: Option<NamePattern>,
    mask: Option<NamePattern>,
    segmentation: Option<NamePattern>,
    view: Option<NamePattern>,
}

impl Layout {
    fn from_args(args: &RenderArgs) -> Result<Layout> {
        let pattern = |path: Option<&Path>, option: &str| -> Result<Option<NamePattern>> {
            let Some(path) = path else {
                return Ok(None);
            };
            let text = path
                .to_str()
                .with_context(|| format!("{option} {}: not valid UTF-8", path.display()))?;
            Ok(Some(NamePattern::parse(text, option)?))
        };
        let image = match &args.view_name {
            Some(text) => Some(NamePattern::parse(text, "--view-name")?),
            None => None,
        };
        if let Some(image) = &image {
            OutputFormat::from_path(Path::new(image.as_str()))?;
        }
        Ok(Layout {
            image,
            depth: pattern(args.depth_out.as_deref(), "--depth-out")?,
            normal: pattern(args.normal_out.as_deref(), "--normal-out")?,
            mask: pattern(args.mask_out.as_deref(), "--mask-out")?,
            segmentation: pattern(args.segmentation_out.as_deref(), "--segmentation-out")?,
            view: pattern(args.view_out.as_deref(), "--view-out")?,
        })
    }

    /// The file names of `count` views in `dir`, checked before any rendering: every pattern
    /// numbers the views (when there are several), no two outputs share a name, nothing is
    /// overwritten under `--no-clobber`; the folders are created.
    fn plan(&self, count: usize, dir: &Path, no_clobber: bool) -> Result<Vec<ViewNames>> {
        let image = self
            .image
            .clone()
            .unwrap_or_else(|| NamePattern::numbered(count, ".png"));
        let view = self
            .view
            .clone()
            .unwrap_or_else(|| NamePattern::numbered(count, ".view.json"));
        let optional = [
            ("--depth-out", &self.depth),
            ("--normal-out", &self.normal),
            ("--mask-out", &self.mask),
            ("--segmentation-out", &self.segmentation),
        ];
        let patterns = [("--view-name", &image), ("--view-out", &view)]
            .into_iter()
            .chain(
                optional
                    .iter()
                    .filter_map(|(option, p)| p.as_ref().map(|p| (*option, p))),
            );
        if count > 1 {
            for (option, p) in patterns {
                if !p.has_view() {
                    bail!(
                        "{option} {}: with --views, a name needs {{view}} or {{view:03}} (e.g. depth/{{view:03}}.png), else every view writes the same file",
                        p.as_str()
                    );
                }
            }
        }
        let mut taken: HashMap<PathBuf, &str> = HashMap::new();
        claim(
            &mut taken,
            dir,
            TRANSFORMS_FILE,
            "transforms.json",
            no_clobber,
        )?;
        let mut names = Vec::with_capacity(count);
        for k in 0..count {
            let mut optional = |p: &Option<NamePattern>, option: &'static str| {
                p.as_ref()
                    .map(|p| name_of(&mut taken, dir, p, k, option, no_clobber))
                    .transpose()
            };
            let depth = optional(&self.depth, "--depth-out")?;
            let normal = optional(&self.normal, "--normal-out")?;
            let mask = optional(&self.mask, "--mask-out")?;
            let segmentation = optional(&self.segmentation, "--segmentation-out")?;
            names.push(ViewNames {
                image: name_of(&mut taken, dir, &image, k, "--view-name", no_clobber)?,
                depth,
                normal,
                mask,
                segmentation,
                view: name_of(&mut taken, dir, &view, k, "--view-out", no_clobber)?,
            });
        }
        let folders: BTreeSet<PathBuf> = std::iter::once(dir.to_path_buf())
            .chain(
                taken
                    .keys()
                    .filter_map(|p| p.parent().map(Path::to_path_buf)),
            )
            .collect();
        for folder in folders.iter().filter(|f| !f.as_os_str().is_empty()) {
            std::fs::create_dir_all(folder)
                .with_context(|| format!("cannot create the folder {}", folder.display()))?;
        }
        Ok(names)
    }
}

/// Reserves `name` (relative to `dir`, or absolute) for `option`.
fn claim<'a>(
    taken: &mut HashMap<PathBuf, &'a str>,
    dir: &Path,
    name: &str,
    option: &'a str,
    no_clobber: bool,
) -> Result<String> {
    let path = dir.join(name);
    if let Some(other) = taken.insert(path.clone(), option) {
        bail!(
            "{} would be written twice ({other} and {option}): give the outputs different names",
            path.display()
        );
    }
    if no_clobber && path.exists() {
        bail!("{}: already exists (--no-clobber)", path.display());
    }
    Ok(name.to_string())
}

fn name_of<'a>(
    taken: &mut HashMap<PathBuf, &'a str>,
    dir: &Path,
    pattern: &NamePattern,
    view: usize,
    option: &'a str,
    no_clobber: bool,
) -> Result<String> {
    claim(taken, dir, &pattern.expand(view), option, no_clobber)
}

/// Renders every view of `spec_text`, calling `on_view(done, total)` as views finish; the
/// options shared with a single render were checked by the caller.
pub(super) fn render_views(
    args: &RenderArgs,
    spec_text: &str,
    env_file: Option<Environment>,
    on_view: &(dyn Fn(usize, usize) + Sync),
) -> Result<RenderReport> {
    let run_start = Instant::now();
    // Everything that can be refused without the model is refused before loading it.
    let spec = ViewSpec::parse(spec_text)?;
    let explicit = match &spec {
        ViewSpec::File(path) => read_views_file(path)?,
        _ => Vec::new(),
    };
    if !(-90.0..=90.0).contains(&args.orbit_elevation) {
        bail!(
            "--orbit-elevation {}: must be between -90 and 90 degrees",
            args.orbit_elevation
        );
    }
    if let Some(r) = args.orbit_radius {
        if !(r > 0.0 && r.is_finite()) {
            bail!("--orbit-radius {r}: must be a positive distance");
        }
    }
    let dir = args.output.as_path();
    if dir.is_file() || (!dir.exists() && OutputFormat::from_path(dir).is_ok()) {
        bail!(
            "-o {}: with --views, -o names the folder the views are written to, not an image",
            dir.display()
        );
    }
    let layout = Layout::from_args(args)?;
    let known_count = match spec {
        ViewSpec::File(_) => Some(explicit.len()),
        _ => spec.count(),
    };
    let mut planned = match known_count {
        Some(n) => Some(layout.plan(n, dir, args.no_clobber)?),
        None => None,
    };
    let (threads, pool) = worker_pool(args.threads)?;

    let load_start = Instant::now();
    let load_options = super::render_load_options(args);
    let mut scene = load(&args.model, &load_options)?;
    crate::scene::tangents::generate_missing(&mut scene);
    let load_time = load_start.elapsed();
    super::report_load(args, &scene);

    // One image size for all views (transforms.json shares w and h).
    let first_file_camera = match spec {
        ViewSpec::Cameras => scene.cameras.first(),
        _ => None,
    };
    let (width, height) = image_size(args, first_file_camera);
    check_size(args, width, height)?;
    let cameras = view_cameras(args, &spec, &explicit, &scene, width, height)?;
    let names = match planned.take() {
        Some(names) => names,
        None => layout.plan(cameras.len(), dir, args.no_clobber)?,
    };

    // Lights stay put in the world from view to view, as multi-view reconstruction expects of
    // its photographs: the file's, or the default rig placed for the automatic camera.
    let path_tracing = args.integrator == IntegratorKind::Path;
    let using_rig = scene.lights.is_empty() && !args.no_default_lights && !path_tracing;
    let (lights, default_ambient) = if !scene.lights.is_empty() {
        (scene.lights.clone(), Vec3::splat(AMBIENT_WITH_FILE_LIGHTS))
    } else if using_rig {
        let front = auto_camera(&scene.bounds, width as f32 / height as f32);
        default_rig(&View::from_camera(&front, width, height))
    } else {
        (Vec::new(), Vec3::ZERO)
    };
    let environment = match env_file {
        Some(env) => Some(env),
        None if path_tracing && scene.lights.is_empty() && !args.no_default_lights => {
            Some(Environment::studio().with_transform(args.env_rotation, args.env_intensity))
        }
        None => None,
    }
    .map(Arc::new);
    super::check_lighting(args, &lights, environment.as_deref())?;
    let textures = super::load_textures(args, &scene)?;
    if let (Some(path), Some(env)) = (&args.env_out, &environment) {
        write_panorama(path, env)?;
    }
    let cancel = interrupt_flag();

    let (summary, frames) = pool.install(|| -> Result<_> {
        let bvh_start = Instant::now();
        // Every view's rays count toward the choice of preset: the tree is built once.
        let rays = crate::setup::expected_rays(
            u64::from(width) * u64::from(height),
            args.spp,
            lights.len(),
            args.integrator,
            args.bounces,
        ) * cameras.len() as f64;
        let preset = args.bvh_preset.for_work(scene.soup.len(), rays);
        let accel = Accel::build(&scene.soup, &scene.materials, args.accel, preset);
        let bvh_time = bvh_start.elapsed();
        let prepared = Prepared::from_parts(scene, accel, textures);
        let run = ViewRun {
            args,
            dir,
            prepared: &prepared,
            width,
            height,
            lights: &lights,
            ambient: args.ambient.unwrap_or(default_ambient),
            using_rig,
            environment: &environment,
            cancel: &cancel,
            count: cameras.len(),
        };
        let mut frames = Vec::with_capacity(cameras.len());
        let mut totals = RenderStats::default();
        on_view(0, cameras.len());
        for (k, (camera, names)) in cameras.iter().zip(&names).enumerate() {
            let (frame, stats) = run.render(k, camera, names)?;
            on_view(k + 1, cameras.len());
            frames.push(frame);
            totals.primary_rays += stats.primary_rays;
            totals.shadow_rays += stats.shadow_rays;
            totals.indirect_rays += stats.indirect_rays;
            totals.samples += stats.samples;
            totals.time += stats.time;
        }
        let summary = Summary {
            triangles: prepared.scene.soup.len(),
            accel: prepared.accel.kind(),
            preset: prepared.accel.preset(),
            load_time,
            bvh_time,
            views: cameras.len(),
            width,
            height,
            totals,
            threads,
        };
        Ok((summary, frames))
    })?;
    let depth_unit_scale_factor = args.depth_out.as_ref().map(|p| {
        let png = p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png"));
        // A 16-bit PNG stores depth in units of --depth-scale; .npy and .exr in metres.
        if png {
            args.depth_scale
        } else {
            1.0
        }
    });
    let dataset = Dataset {
        width,
        height,
        depth_unit_scale_factor,
        frames,
    };
    dataset.write(&dir.join(TRANSFORMS_FILE))?;
    if !args.quiet {
        summary.print(args, run_start.elapsed());
    }
    // In the order written: the panorama, each view's files as ViewRun::render writes them,
    // transforms.json.
    let mut outputs: Vec<PathBuf> = args.env_out.iter().cloned().collect();
    for view in &names {
        let files = [
            Some(&view.image),
            view.depth.as_ref(),
            view.normal.as_ref(),
            view.segmentation.as_ref(),
            view.mask.as_ref(),
            Some(&view.view),
        ];
        outputs.extend(files.into_iter().flatten().map(|name| dir.join(name)));
    }
    outputs.push(dir.join(TRANSFORMS_FILE));
    Ok(RenderReport {
        triangles: summary.triangles,
        load: summary.load_time,
        bvh: summary.bvh_time,
        render: summary.totals.time,
        outputs,
    })
}

/// The cameras of a spec, all perspective (transforms.json describes pinhole cameras only).
/// Generated views frame the model as the automatic camera does, at `--yfov` (default 45°).
fn view_cameras(
    args: &RenderArgs,
    spec: &ViewSpec,
    explicit: &[ExplicitView],
    scene: &Scene,
    width: u32,
    height: u32,
) -> Result<Vec<Camera>> {
    let aspect = width as f32 / height as f32;
    let yfov = args.yfov.unwrap_or(DEFAULT_YFOV_DEGREES).to_radians();
    let scene_radius = framing_radius(&scene.bounds);
    let framing = Framing {
        target: args.look_at.unwrap_or(scene.bounds.center()),
        distance: args
            .orbit_radius
            .unwrap_or_else(|| framing_distance(scene_radius, yfov, aspect)),
        yfov,
        scene_radius,
    };
    let cameras: Vec<Camera> = match spec {
        ViewSpec::Orbit(n) => framing.cameras(&orbit_directions(*n, args.orbit_elevation)),
        ViewSpec::Sphere(n) => framing.cameras(&fibonacci_directions(*n)),
        ViewSpec::Random(n) => framing.cameras(&random_directions(*n, args.seed)),
        ViewSpec::Cameras => {
            if scene.cameras.is_empty() {
                bail!(
                    "{}: --views cameras: the file has no cameras",
                    args.model.display()
                );
            }
            let mut cameras = scene.cameras.clone();
            if let Some(deg) = args.yfov {
                for c in &mut cameras {
                    if let Projection::Perspective { yfov, .. } = &mut c.projection {
                        *yfov = deg.to_radians();
                    }
                }
            }
            cameras
        }
        ViewSpec::File(_) => explicit
            .iter()
            .map(|v| v.camera(yfov, scene.bounds.center(), scene_radius))
            .collect(),
    };
    if let Some(i) = cameras
        .iter()
        .position(|c| matches!(c.projection, Projection::Orthographic { .. }))
    {
        bail!(
            "{}: --views: view {i} is an orthographic camera, and transforms.json describes perspective (pinhole) cameras only",
            args.model.display()
        );
    }
    Ok(cameras)
}

/// What every view of a run shares.
struct ViewRun<'a> {
    args: &'a RenderArgs,
    dir: &'a Path,
    prepared: &'a Prepared,
    width: u32,
    height: u32,
    /// Fixed in the world for every view.
    lights: &'a [Light],
    ambient: Vec3,
    using_rig: bool,
    environment: &'a Option<Arc<Environment>>,
    cancel: &'a AtomicBool,
    count: usize,
}

impl ViewRun<'_> {
    /// Renders view `k` and writes its files: image, AOVs, view file. Returns its frame of
    /// transforms.json and what the render did.
    fn render(&self, k: usize, camera: &Camera, names: &ViewNames) -> Result<(Frame, RenderStats)> {
        let (args, dir, (width, height)) = (self.args, self.dir, (self.width, self.height));
        let path_tracing = args.integrator == IntegratorKind::Path;
        let mut record = ViewFile::new(
            camera,
            width,
            height,
            self.lights,
            self.ambient,
            self.using_rig,
        );
        record.segmentation = segmentation_ids(&self.prepared.scene);
        record.depth_png_scale = args.depth_scale;
        record.integrator = args.integrator;
        if path_tracing {
            record.bounces = Some(args.bounces);
            record.environment = self.environment.as_ref().map(|env| ViewEnvironment {
                source: env.source.clone(),
                rotation_degrees: env.rotation_degrees(),
                intensity: env.intensity(),
                visible: args.env_visible,
                panorama: args
                    .env_out
                    .as_ref()
                    .map(|p| p.canonicalize().unwrap_or_else(|_| p.clone())),
            });
        }
        // Render what `render --view` reads back from the view file, number for number, so
        // that the view rendered alone from its file gives the same bytes.
        let text = record.to_json();
        let view_path = dir.join(&names.view);
        let record = ViewFile::from_json(&text, &view_path)?;
        let view = View::from_camera(&record.camera()?, width, height);
        let intrinsics =
            Intrinsics::of(&view).with_context(|| format!("view {k}: not a perspective camera"))?;
        let settings = RenderSettings {
            view,
            spp: args.spp,
            seed: args.seed,
            lights: record.lights(),
            ambient: Vec3::from(record.ambient),
            exposure: args.exposure,
            shading: args.shading,
            aovs: names.depth.is_some() || names.normal.is_some() || names.segmentation.is_some(),
            integrator: args.integrator,
            bounces: args.bounces,
            environment: self.environment.clone(),
            environment_visible: args.env_visible,
        };
        let image_path = dir.join(&names.image);
        let output = PendingOutput::reserve(&image_path, args.no_clobber)?;
        let (image, stats, aovs) = render(self.prepared, &settings, self.cancel, &|_, _| {})
            .map_err(|_| {
                Interrupted(format!(
                    "{k} of {} views written to {} ({TRANSFORMS_FILE} not written)",
                    self.count,
                    dir.display()
                ))
            })?;
        output.commit(&image, args.background)?;
        if let Some(a) = &aovs {
            if let Some(name) = &names.depth {
                let path = dir.join(name);
                crate::aov::write_depth(&path, width, height, &a.depth, args.depth_scale)?;
            }
            if let Some(name) = &names.normal {
                crate::aov::write_normals(&dir.join(name), width, height, &a.normal)?;
            }
            if let Some(name) = &names.segmentation {
                crate::aov::write_segmentation(&dir.join(name), width, height, &a.instance)?;
            }
        }
        if let Some(name) = &names.mask {
            let coverage: Vec<f32> = image.pixels.iter().map(|p| p.w).collect();
            crate::aov::write_mask(&dir.join(name), width, height, &coverage)?;
        }
        crate::output::write_atomic(&view_path, text.as_bytes())?;
        if !args.quiet {
            eprintln!(
                "[{}/{}] {} rendered in {:.3} s",
                k + 1,
                self.count,
                image_path.display(),
                stats.time.as_secs_f64()
            );
        }
        let frame = Frame {
            file_path: names.image.clone(),
            transform_matrix: camera_to_world(&settings.view),
            intrinsics,
            depth_file_path: names.depth.clone(),
            mask_path: names.mask.clone(),
        };
        Ok((frame, stats))
    }
}

/// The segmentation ids of a scene's mesh instances, as view files list them.
fn segmentation_ids(scene: &Scene) -> Vec<SegmentId> {
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

/// What the summary line reports.
struct Summary {
    triangles: usize,
    accel: AccelKind,
    preset: crate::accel::BvhPreset,
    load_time: Duration,
    bvh_time: Duration,
    views: usize,
    width: u32,
    height: u32,
    totals: RenderStats,
    threads: usize,
}

impl Summary {
    /// Prints the one summary line of a multi-view render: the load and the BVH build once,
    /// the render time of all views.
    fn print(&self, args: &RenderArgs, wall: Duration) {
        let structure = match self.accel {
            AccelKind::Bvh => format!(
                "BVH ({}) built once in {:.1} ms",
                super::preset_label(args.bvh_preset, self.preset),
                self.bvh_time.as_secs_f64() * 1e3
            ),
            AccelKind::Linear => "linear scan (no BVH)".to_string(),
        };
        let render_seconds = self.totals.time.as_secs_f64();
        eprintln!(
            "{}: {} triangles, loaded once in {:.1} ms, {structure}; {} views of {}x{} at {} spp rendered in {:.3} s ({:.3} s a view): {} rays, {:.2} Mrays/s on {} threads; {:.3} s in all -> {}",
            args.model.display(),
            self.triangles,
            self.load_time.as_secs_f64() * 1e3,
            self.views,
            self.width,
            self.height,
            args.spp,
            render_seconds,
            render_seconds / self.views.max(1) as f64,
            self.totals.rays(),
            self.totals.mrays_per_second(),
            self.threads,
            wall.as_secs_f64(),
            args.output.join(TRANSFORMS_FILE).display()
        );
    }
}

/// Writes the environment that lit the views as a Radiance .hdr panorama (`--env-out`).
fn write_panorama(path: &Path, env: &Environment) -> Result<()> {
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
    crate::output::write_atomic(path, &bytes)?;
    Ok(())
}
