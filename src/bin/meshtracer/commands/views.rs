//! `render MODEL --views SPEC -o DIR`: many views of one model after one load and one BVH
//! build. The spec becomes cameras ([`meshtracer::jobs::views`]); every view is rendered from the
//! prepared scene with the same settings and writes its image, the AOVs asked for and its view
//! file; the folder gets one `transforms.json` ([`meshtracer::output::dataset`]). `--turntable N` is an
//! orbit that starts at the plain render's azimuth; `--gif` streams its frames into an
//! animated GIF ([`meshtracer::output::turntable`]) and `--contact-sheet` lays any views out in a grid
//! ([`meshtracer::output::sheet`]), both from the images in memory as the views finish.
//!
//! Kept apart from the single-view flow in `commands/render.rs`, which hands over after checking
//! the options they share.

use super::{
    check_size, image_size, interrupt_flag, load, record_render, worker_pool, write_panorama,
    Interrupted, RenderReport,
};
use crate::cli::RenderArgs;
use anyhow::{bail, Context, Result};
use glam::Vec3;
use meshtracer::accel::AccelKind;
use meshtracer::camera::{auto_camera, ThinLens, View};
use meshtracer::jobs::batch::{model_digest, sha256_file, sha256_hex, OutputRecord, Shard};
use meshtracer::jobs::views::{
    azimuth_degrees, elevation_degrees, in_shard, plan_cameras, read_rendered_in, read_views_file,
    rendered_file, shard_record_files, ExplicitView, NamePattern, PlanOptions, RenderedView,
    ViewSpec, RENDERED_FILE,
};
use meshtracer::light::environment::Environment;
use meshtracer::output::dataset::{camera_to_world, Dataset, Frame, Intrinsics};
use meshtracer::output::sheet::{ContactSheet, SheetLayout};
use meshtracer::output::turntable::{check_fps, frame_delay_centiseconds, GifWriter};
use meshtracer::output::view_file::ViewFile;
use meshtracer::output::{OutputFormat, PendingFile, PendingOutput, SaveError};
use meshtracer::prepare::Prepared;
use meshtracer::render::{render, RenderSettings, RenderStats};
use meshtracer::scene::{Camera, Light, Projection, Scene};
use meshtracer::setup::{lighting, Lighting};
use std::collections::{BTreeSet, HashMap};
use std::io::Write;
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

impl ViewNames {
    /// The names of the files that go with the image: AOVs, mask and view file.
    fn companions(&self) -> impl Iterator<Item = &String> {
        [&self.depth, &self.normal, &self.mask, &self.segmentation]
            .into_iter()
            .flatten()
            .chain(std::iter::once(&self.view))
    }

    /// Every file of the view in the order [`ViewRun::render`] writes them: image, depth,
    /// normals, segmentation, mask, view file.
    fn in_order(&self) -> Vec<&str> {
        [
            Some(&self.image),
            self.depth.as_ref(),
            self.normal.as_ref(),
            self.segmentation.as_ref(),
            self.mask.as_ref(),
            Some(&self.view),
        ]
        .into_iter()
        .flatten()
        .map(String::as_str)
        .collect()
    }
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
    ///
    /// `others` are the outputs named on their own (`--gif`, `--contact-sheet`), which no view
    /// file may overwrite.
    fn plan(
        &self,
        count: usize,
        dir: &Path,
        no_clobber: bool,
        others: &[(&'static str, PathBuf)],
    ) -> Result<Vec<ViewNames>> {
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
        let mut taken: HashMap<PathBuf, &str> = others
            .iter()
            .map(|(option, path)| (path.clone(), *option))
            .collect();
        claim(
            &mut taken,
            dir,
            TRANSFORMS_FILE,
            "transforms.json",
            no_clobber,
        )?;
        claim(&mut taken, dir, RENDERED_FILE, RENDERED_FILE, no_clobber)?;
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
                    // The others are written where named, into folders that exist, as a
                    // single render's -o is.
                    .filter(|p| !others.iter().any(|(_, other)| other == *p))
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
    let (spec, explicit) = read_spec(spec_text)?;
    check_orbit_options(args, &spec)?;
    let dir = args.output.as_path();
    check_output_folder(dir)?;
    check_resume_and_shard(args)?;
    let known_count = match spec {
        ViewSpec::File(_) => Some(explicit.len()),
        _ => spec.count(),
    };
    remove_leftovers_of_a_killed_run(args, dir)?;
    // A run that fails leaves no empty folder it made for -o (from the outermost one that
    // did not exist); a folder holding a finished view is kept.
    let made = dir
        .ancestors()
        .take_while(|a| !a.as_os_str().is_empty() && !a.exists())
        .last()
        .map(Path::to_path_buf);
    let run = (spec, explicit.as_slice(), known_count, run_start);
    render_views_into(args, run, env_file, on_view).inspect_err(|_| {
        if let Some(made) = &made {
            remove_empty_folders(made);
        }
    })
}

/// [`render_views`] once the options are checked: reserves the outputs, loads the model and
/// renders the views of `spec` (`explicit`: a views file's), `known_count` of them when the
/// spec alone tells, for a run that started at `run_start`.
fn render_views_into(
    args: &RenderArgs,
    (spec, explicit, known_count, run_start): (ViewSpec, &[ExplicitView], Option<usize>, Instant),
    env_file: Option<Environment>,
    on_view: &(dyn Fn(usize, usize) + Sync),
) -> Result<RenderReport> {
    // Installed by `render_model` before anything was reserved (the process has one flag).
    let cancel = interrupt_flag();
    let dir = args.output.as_path();
    let mut outputs = Outputs::reserve(args, dir, known_count)?;
    let (threads, pool) = worker_pool(args.threads)?;

    let load_start = Instant::now();
    let scene = load(&args.model, &super::render_load_options(args))?;
    super::render::stop_if_cancelled(&cancel)?;
    let load_time = load_start.elapsed();
    super::report_load(args, &scene);

    let (width, height) = views_size(args, &spec, &scene)?;
    let (cameras, lenses) = view_cameras(args, &spec, explicit, &scene, width, height)?;
    let names = outputs.names(args, dir, cameras.len(), (width, height))?;
    let plan = Plan {
        width,
        height,
        cameras,
        lenses,
        names,
        load_time,
        threads,
    };
    let lit = fixed_lighting(args, &scene, width, height, env_file)?;
    let (summary, frames, warnings) = pool.install(|| {
        render_all(
            args,
            scene,
            &plan,
            &lit,
            &mut outputs.extras,
            &cancel,
            on_view,
        )
    })?;
    // A shard's views join the others' in the run that writes transforms.json (--resume).
    if shard(args) == Shard::ALL {
        write_transforms(args, dir, width, height, frames)?;
    }
    let extra_outputs = outputs.extras.finish(args.quiet, args.preview)?;
    if !args.quiet {
        summary.print(args, run_start.elapsed());
    }
    Ok(RenderReport {
        triangles: summary.triangles,
        load: summary.load_time,
        bvh: summary.bvh_time,
        render: summary.totals.time,
        outputs: written(args, dir, &plan.names, extra_outputs),
        warnings,
        inputs: summary.inputs,
    })
}

/// Parses `--views` and reads a views file; a spec that is neither a kind of views nor a
/// readable file of them is refused here, before the model loads. The views of a file come
/// with it (none for the other kinds).
fn read_spec(spec_text: &str) -> Result<(ViewSpec, Vec<ExplicitView>)> {
    let spec = ViewSpec::parse(spec_text)?;
    let explicit = match &spec {
        ViewSpec::File(path) => read_views_file(path)?,
        _ => Vec::new(),
    };
    Ok((spec, explicit))
}

/// Refuses, in this order, `--orbit-elevation` outside -90..=90, a `--orbit-radius` that is not
/// a positive distance, and an `--orbit-azimuth` that is not finite or not for an orbit.
fn check_orbit_options(args: &RenderArgs, spec: &ViewSpec) -> Result<()> {
    if let Some(e) = args.orbit_elevation {
        if !(-90.0..=90.0).contains(&e) {
            bail!("--orbit-elevation {e}: must be between -90 and 90 degrees");
        }
    }
    if let Some(r) = args.orbit_radius {
        if !(r > 0.0 && r.is_finite()) {
            bail!("--orbit-radius {r}: must be a positive distance");
        }
    }
    if let Some(a) = args.orbit_azimuth {
        if !a.is_finite() {
            bail!("--orbit-azimuth {a}: must be a finite number of degrees");
        }
        if !matches!(spec, ViewSpec::Orbit(_)) {
            bail!("--orbit-azimuth: only orbits (--views orbit:N, --turntable N) have a starting azimuth");
        }
    }
    Ok(())
}

/// With `--resume`, removes the temporary files a killed run left in the folders of the views
/// (SIGKILL, a lost node: nothing cleaned up), before this run reserves any of its own, so
/// that the folder ends as an uninterrupted run leaves it. Not for a shard: shards share the
/// folders, and another's temporary file may be in use; the join cleans up.
fn remove_leftovers_of_a_killed_run(args: &RenderArgs, dir: &Path) -> Result<()> {
    if !args.resume || shard(args) != Shard::ALL {
        return Ok(());
    }
    let layout = Layout::from_args(args)?;
    let patterns = [
        &layout.image,
        &layout.depth,
        &layout.normal,
        &layout.mask,
        &layout.segmentation,
        &layout.view,
    ];
    // A pattern's folder, when it is one for every view (no `{view}` in it).
    let folders: BTreeSet<PathBuf> = std::iter::once(dir.to_path_buf())
        .chain(patterns.into_iter().flatten().filter_map(|p| {
            let folder = dir.join(p.as_str()).parent()?.to_path_buf();
            (!folder.to_string_lossy().contains('{')).then_some(folder)
        }))
        .collect();
    for folder in &folders {
        super::remove_leftovers(folder);
    }
    Ok(())
}

/// Refuses `--resume` with `--no-clobber` (a resumed run rewrites transforms.json and the
/// views it renders again), and with a GIF or a sheet of views that are not PNG: those are
/// made from the images, and only a PNG gives back the bytes they were made from. Refuses a
/// shard of several with a GIF, a sheet or a preview (they need every view: the run that
/// joins the shards makes them) and with `--no-clobber` (the shards share the folder).
fn check_resume_and_shard(args: &RenderArgs) -> Result<()> {
    let shard = shard(args);
    if shard != Shard::ALL {
        let extras = [
            ("--gif", args.gif.is_some()),
            ("--contact-sheet", args.contact_sheet.is_some()),
            ("--preview", args.preview.is_some()),
        ];
        if let Some((option, _)) = extras.iter().find(|(_, given)| *given) {
            bail!("--shard {shard}: {option} needs every view; give it to the run that joins the shards (the same command without --shard, with --resume)");
        }
        if args.no_clobber {
            bail!("--shard {shard}: not with --no-clobber (the shards write into one folder)");
        }
    }
    if !args.resume {
        return Ok(());
    }
    if args.no_clobber {
        bail!("--resume rewrites transforms.json and the views it renders again: not with --no-clobber");
    }
    let extras = args.gif.is_some() || args.contact_sheet.is_some() || args.preview.is_some();
    let png = args
        .view_name
        .as_deref()
        .is_none_or(|name| has_extension(Path::new(name), "png"));
    if extras && !png {
        bail!(
            "--resume with --gif, --contact-sheet or --preview needs the views as PNG (the GIF and the sheet are made again from the kept views' images, and only a PNG gives them back as they were): not --view-name {}",
            args.view_name.as_deref().unwrap_or_default()
        );
    }
    Ok(())
}

/// Refuses an `-o` that names a GIF, an existing file or (not existing yet) an image: with
/// `--views`, `-o` is the folder the views are written to.
fn check_output_folder(dir: &Path) -> Result<()> {
    if has_extension(dir, "gif") {
        bail!(
            "-o {}: with --views or --turntable, -o names the folder of the frames; write the GIF with --turntable N --gif {}",
            dir.display(),
            dir.display()
        );
    }
    if dir.is_file() || (!dir.exists() && OutputFormat::from_path(dir).is_ok()) {
        bail!(
            "-o {}: with --views, -o names the folder the views are written to, not an image",
            dir.display()
        );
    }
    Ok(())
}

/// Removes `dir` and the folders below it if they hold no file.
fn remove_empty_folders(dir: &Path) {
    if let Ok(entries) = std::fs::read_dir(dir) {
        for entry in entries.flatten() {
            if entry.file_type().is_ok_and(|t| t.is_dir()) {
                remove_empty_folders(&entry.path());
            }
        }
    }
    // Fails, and keeps the folder, when anything is left in it.
    let _ = std::fs::remove_dir(dir);
}

/// The files of a run, planned and reserved before the model loads, so that a clashing or
/// unwritable name fails before any work.
struct Outputs {
    layout: Layout,
    /// The outputs named on their own (`--gif`, `--contact-sheet`), which no view's file may
    /// overwrite.
    others: Vec<(&'static str, PathBuf)>,
    /// Every view's file names, when the spec alone gives the number of views (all but
    /// `cameras`).
    names: Option<Vec<ViewNames>>,
    /// The GIF and the sheet, reserved.
    extras: Extras,
}

impl Outputs {
    /// Checks the name patterns and the options of the GIF and the sheet, plans every view's
    /// file names when `known_count` gives their number ([`Layout::plan`]: folders created,
    /// clashes and `--no-clobber` refused), and reserves the GIF and the sheet.
    fn reserve(args: &RenderArgs, dir: &Path, known_count: Option<usize>) -> Result<Outputs> {
        let layout = Layout::from_args(args)?;
        Extras::check(args, known_count)?;
        let others = Extras::paths(args);
        let names = match known_count {
            Some(n) => Some(layout.plan(n, dir, args.no_clobber, &others)?),
            None => None,
        };
        // The GIF or the sheet may go into the -o folder, which the plan creates (not yet for
        // `cameras`, whose count needs the model): made now for them, else left for the plan.
        let into_dir = others
            .iter()
            .any(|(_, p)| p.parent().is_some_and(|f| f.starts_with(dir)));
        if into_dir {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create the folder {}", dir.display()))?;
        }
        let extras = Extras::reserve(args, known_count)?;
        Ok(Outputs {
            layout,
            others,
            names,
            extras,
        })
    }

    /// The file names of the `count` views, planned now when their number needed the model,
    /// and the sheet laid out for views of `size` (refused over `--max-pixels`).
    fn names(
        &mut self,
        args: &RenderArgs,
        dir: &Path,
        count: usize,
        size: (u32, u32),
    ) -> Result<Vec<ViewNames>> {
        let names = match self.names.take() {
            Some(names) => names,
            None => self
                .layout
                .plan(count, dir, args.no_clobber, &self.others)?,
        };
        self.extras.lay_out(args, count, size)?;
        Ok(names)
    }
}

/// The one image size of every view (transforms.json shares `w` and `h`): from the options
/// and, for `--views cameras`, the file's first camera ([`image_size`]); refused over the
/// limits.
fn views_size(args: &RenderArgs, spec: &ViewSpec, scene: &Scene) -> Result<(u32, u32)> {
    let first_file_camera = match spec {
        ViewSpec::Cameras => scene.cameras.first(),
        _ => None,
    };
    let (width, height) = image_size(args, first_file_camera);
    check_size(args, width, height)?;
    Ok((width, height))
}

/// The lighting of every view. Lights stay put in the world from view to view, as multi-view
/// reconstruction expects of its photographs: the file's, or the default rig placed for the
/// automatic camera. Refuses what [`super::check_lighting`] refuses.
fn fixed_lighting(
    args: &RenderArgs,
    scene: &Scene,
    width: u32,
    height: u32,
    env_file: Option<Environment>,
) -> Result<Lighting> {
    let front = auto_camera(
        &scene.bounds,
        &scene.soup.positions,
        width as f32 / height as f32,
    );
    let lit = lighting(
        &scene.lights,
        None,
        &View::from_camera(&front, width, height),
        super::lighting_options(args, env_file),
    );
    super::check_lighting(args, &lit.lights, lit.environment.as_deref())?;
    Ok(lit)
}

/// What a run settled before the scene is prepared: the views, their one size and their file
/// names, and what the summary line reports of the load and the pool.
struct Plan {
    width: u32,
    height: u32,
    cameras: Vec<Camera>,
    /// Each view's thin lens, if `--aperture-radius` asks for one.
    lenses: Vec<Option<ThinLens>>,
    names: Vec<ViewNames>,
    /// Wall time of the parse and flatten (the tangents come with the prepare).
    load_time: Duration,
    threads: usize,
}

/// Runs on the worker pool: prepares `scene` once (the BVH preset chosen for the rays of every
/// view), writes the `--env-out` panorama, then renders and writes the views in order
/// ([`ViewRun::render`]), adding each to the GIF and the sheet and calling
/// `on_view(done, total)`. Returns the summary, each view's frame of transforms.json and the
/// warnings of the load and the texture decoding.
fn render_all(
    args: &RenderArgs,
    scene: Scene,
    plan: &Plan,
    lit: &Lighting,
    extras: &mut Extras,
    cancel: &AtomicBool,
    on_view: &(dyn Fn(usize, usize) + Sync),
) -> Result<(Summary, Vec<Frame>, Vec<String>)> {
    let (width, height, cameras) = (plan.width, plan.height, &plan.cameras);
    // Every view's rays count toward the choice of preset: the tree is built once.
    let rays = meshtracer::setup::expected_rays(
        u64::from(width) * u64::from(height),
        args.spp(),
        args.noise()
            .map(|_| meshtracer::render::first_batch(width, height, args.denoises())),
        lit.lights.len(),
        args.integrator,
        args.bounces,
    ) * cameras.len() as f64;
    let super::PreparedModel {
        prepared,
        warnings,
        tangents,
        ..
    } = super::prepare_scene(args, scene, rays, &mut super::Phases::default())?;
    let load_time = plan.load_time + tangents;
    let bvh_time = prepared.accel.build_time();
    if let (Some(path), Some(env)) = (&args.env_out, &lit.environment) {
        write_panorama(path, env)?;
    }
    let run = ViewRun {
        args,
        dir: args.output.as_path(),
        prepared: &prepared,
        width,
        height,
        lights: &lit.lights,
        ambient: args.ambient.unwrap_or(lit.ambient),
        using_rig: lit.default_rig,
        environment: &lit.environment,
        cancel,
        count: cameras.len(),
        model_sha256: model_digest(&args.model, &prepared.scene.inputs),
        shard: shard(args),
    };
    let (frames, totals, kept) = render_each(&run, plan, extras, on_view)?;
    let summary = Summary {
        triangles: prepared.scene.soup.len(),
        accel: prepared.accel.kind(),
        preset: prepared.accel.preset(),
        load_time,
        bvh_time,
        views: run.views().len(),
        kept,
        width,
        height,
        totals,
        threads: plan.threads,
        inputs: prepared.scene.inputs.clone(),
    };
    Ok((summary, frames, warnings))
}

/// Renders and writes the views of `plan` in order, keeping those an earlier run finished
/// (`--resume`, [`RecordLog`]) and recording each view as it finishes; adds each to the GIF
/// and the sheet and calls `on_view(done, total)`. Returns the frames of transforms.json, what
/// the renders did and how many views were kept.
fn render_each(
    run: &ViewRun,
    plan: &Plan,
    extras: &mut Extras,
    on_view: &(dyn Fn(usize, usize) + Sync),
) -> Result<(Vec<Frame>, RenderStats, usize)> {
    let (args, cameras) = (run.args, &plan.cameras);
    let mut log = RecordLog::start(run, plan)?;
    let mine = run.views();
    let mut frames = Vec::with_capacity(mine.len());
    let mut totals = RenderStats::default();
    on_view(0, mine.len());
    for (done, &k) in mine.iter().enumerate() {
        let (camera, names) = (&cameras[k], &plan.names[k]);
        let work = match run.prepare(k, camera, plan.lenses[k], names) {
            Ok(work) => work,
            Err(e) => return Err(failed_part_way(args, plan, frames, k, e)),
        };
        match log.kept_image(run, k, names, extras.needs_images()) {
            Some(rgba) => {
                if let Some(rgba) = rgba {
                    extras.add_rgba(k, camera, rgba)?;
                }
                if !args.quiet {
                    note!(
                        "[{}/{}] {} kept: finished by an earlier run, its files verified",
                        k + 1,
                        cameras.len(),
                        run.dir.join(&names.image).display()
                    );
                }
            }
            None => {
                let (stats, image, record) = match run.render(k, &work, names) {
                    Ok(done) => done,
                    Err(e) => return Err(failed_part_way(args, plan, frames, k, e)),
                };
                log.append(record)?;
                extras.add(k, camera, &image, (args.background, args.tonemap))?;
                totals.primary_rays += stats.primary_rays;
                totals.shadow_rays += stats.shadow_rays;
                totals.indirect_rays += stats.indirect_rays;
                totals.samples += stats.samples;
                totals.time += stats.time;
            }
        }
        on_view(done + 1, mine.len());
        frames.push(work.frame);
    }
    let kept = log.finish(run.shard)?;
    Ok((frames, totals, kept))
}

/// The run's record of finished views ([`RENDERED_FILE`] in the -o folder): the views kept from
/// an earlier run, then each view rendered, appended as its files are all written, so that a
/// run stopped at any point (a scheduler's time limit, a preemption, SIGKILL) leaves a record
/// of every view it finished. Rewritten in view order at the end.
struct RecordLog {
    path: PathBuf,
    file: std::fs::File,
    records: std::collections::BTreeMap<usize, RenderedView>,
    /// The views kept from the earlier run.
    kept: BTreeSet<usize>,
}

impl RecordLog {
    /// Starts the record. With `--resume`, an earlier run's record of a view is kept when it
    /// vouches for the view this run would render ([`RenderedView::vouches_for`]: the same
    /// fingerprint, file names and file hashes), and the file is rewritten with those alone;
    /// otherwise it starts empty.
    fn start(run: &ViewRun, plan: &Plan) -> Result<RecordLog> {
        let path = run.dir.join(rendered_file(run.shard));
        let mut records = std::collections::BTreeMap::new();
        if run.args.resume {
            let earlier = read_rendered_in(run.dir)
                .context("--resume: cannot read the record of the finished views")?;
            let mine = run.views();
            for &k in &mine {
                let Some(candidates) = earlier.get(&k) else {
                    continue;
                };
                let names = &plan.names[k];
                let fingerprint = run
                    .prepare(k, &plan.cameras[k], plan.lenses[k], names)?
                    .fingerprint;
                // The whole run's record, then each shard's: the first that still holds.
                let mut why = String::new();
                for record in candidates {
                    match record.vouches_for(run.dir, k, &fingerprint, &names.in_order()) {
                        Ok(()) => {
                            records.insert(k, record.clone());
                            break;
                        }
                        Err(reason) => why = reason,
                    }
                }
                if !records.contains_key(&k) && !run.args.quiet {
                    note!("view {k}: rendered again: {why}");
                }
            }
            if !run.args.quiet {
                note!(
                    "--resume: {} of {} views finished before, their files verified; rendering the other {}",
                    records.len(),
                    mine.len(),
                    mine.len() - records.len()
                );
            }
        }
        let text: String = records.values().map(RenderedView::line).collect();
        meshtracer::output::write_atomic(&path, text.as_bytes())?;
        let file = std::fs::OpenOptions::new()
            .append(true)
            .open(&path)
            .with_context(|| format!("cannot open {} to record the views", path.display()))?;
        let kept = records.keys().copied().collect();
        Ok(RecordLog {
            path,
            file,
            records,
            kept,
        })
    }

    /// Whether view `k` is kept from the earlier run: `Some` with its image read back as the
    /// GIF and the sheet take it (`want_image`; the PNG holds the bytes they would be given),
    /// `None` when it must be rendered (not kept, or its image cannot be read back).
    fn kept_image(
        &mut self,
        run: &ViewRun,
        k: usize,
        names: &ViewNames,
        want_image: bool,
    ) -> Option<Option<image::RgbaImage>> {
        if !self.kept.contains(&k) {
            return None;
        }
        if !want_image {
            return Some(None);
        }
        let path = run.dir.join(&names.image);
        let read = std::fs::read(&path)
            .map_err(|e| e.to_string())
            .and_then(|bytes| {
                image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
                    .map_err(|e| e.to_string())
            })
            .map(|image| image.to_rgba8());
        match read {
            Ok(rgba) if rgba.dimensions() == (run.width, run.height) => Some(Some(rgba)),
            Ok(_) | Err(_) => {
                if !run.args.quiet {
                    note!(
                        "view {k}: rendered again: {} cannot be read back for the GIF or the sheet",
                        path.display()
                    );
                }
                self.kept.remove(&k);
                None
            }
        }
    }

    /// Records a view just rendered.
    fn append(&mut self, record: RenderedView) -> Result<()> {
        self.file
            .write_all(record.line().as_bytes())
            .with_context(|| {
                format!(
                    "cannot record view {} in {}",
                    record.view,
                    self.path.display()
                )
            })?;
        self.records.insert(record.view, record);
        Ok(())
    }

    /// Rewrites the record in view order (the same bytes as an uninterrupted run's); returns
    /// how many views were kept. A whole run's record then vouches for every view, and the
    /// shards' records (joined by this run, or stale) are removed, so that the folder is an
    /// unsharded run's.
    fn finish(self, shard: Shard) -> Result<usize> {
        drop(self.file);
        let text: String = self.records.values().map(RenderedView::line).collect();
        meshtracer::output::write_atomic(&self.path, text.as_bytes())?;
        if shard == Shard::ALL {
            let folder = self.path.parent().unwrap_or(Path::new("."));
            for file in shard_record_files(folder).unwrap_or_default() {
                std::fs::remove_file(&file)
                    .with_context(|| format!("cannot remove {}", file.display()))?;
            }
        }
        Ok(self.kept.len())
    }
}

/// The error of a run whose view `k` failed (not interrupted) after views `0..k` were written
/// whole: their `transforms.json` is written, so the views that exist are recorded and a
/// rerun or a tool reading the folder knows which; the error says so.
fn failed_part_way(
    args: &RenderArgs,
    plan: &Plan,
    frames: Vec<Frame>,
    k: usize,
    error: anyhow::Error,
) -> anyhow::Error {
    if k == 0 || error.is::<Interrupted>() {
        return error;
    }
    if shard(args) != Shard::ALL {
        return error.context(format!(
            "view {k} failed; the views of shard {} before it are written whole",
            shard(args)
        ));
    }
    let total = plan.cameras.len();
    let dir = args.output.as_path();
    match write_transforms(args, dir, plan.width, plan.height, frames) {
        Ok(()) => error.context(format!(
            "view {k} failed; views 0 to {} of {total} are written whole and listed in {}",
            k - 1,
            dir.join(TRANSFORMS_FILE).display()
        )),
        Err(_) => error.context(format!(
            "view {k} failed; views 0 to {} of {total} are written whole",
            k - 1
        )),
    }
}

/// Writes the folder's `transforms.json`: the views' `frames`, their one size and, with
/// `--depth-out`, the unit of the depth files.
fn write_transforms(
    args: &RenderArgs,
    dir: &Path,
    width: u32,
    height: u32,
    frames: Vec<Frame>,
) -> Result<()> {
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
    Ok(())
}

/// Every file a run wrote, in the order written: the panorama, each view's files as
/// [`ViewRun::render`] writes them, transforms.json, then `extras` (the GIF and the sheet).
fn written(
    args: &RenderArgs,
    dir: &Path,
    names: &[ViewNames],
    extras: Vec<PathBuf>,
) -> Vec<PathBuf> {
    let shard = shard(args);
    let mut outputs: Vec<PathBuf> = args.env_out.iter().cloned().collect();
    for (k, view) in names.iter().enumerate() {
        if in_shard(k, shard) {
            outputs.extend(view.in_order().into_iter().map(|name| dir.join(name)));
        }
    }
    if shard == Shard::ALL {
        outputs.push(dir.join(TRANSFORMS_FILE));
    }
    outputs.push(dir.join(rendered_file(shard)));
    outputs.extend(extras);
    outputs
}

/// The shard of the views this run renders (`--shard`; all of them without).
fn shard(args: &RenderArgs) -> Shard {
    args.shard.unwrap_or(Shard::ALL)
}

/// View `k`'s thin lens (`--aperture-radius`): focused at `--focus-distance`, else at the
/// depth of `target`, the point it looks at (a views file's `look_at`, else `--look-at`, else
/// the scene's centre); `None` without the option. Refuses a view that does not face its
/// target.
fn view_thin_lens(
    args: &RenderArgs,
    k: usize,
    camera: &Camera,
    target: Vec3,
) -> Result<Option<ThinLens>> {
    let Some(aperture_radius) = args.aperture_radius.filter(|r| *r > 0.0) else {
        return Ok(None);
    };
    let focus_distance = match args.focus_distance {
        Some(f) => f,
        None => View::from_camera(camera, 1, 1)
            .depth_of(target)
            .with_context(|| format!("--aperture-radius: view {k} does not face the point it would focus on (its look_at, else --look-at, else the scene's centre): give --focus-distance"))?,
    };
    Ok(Some(ThinLens {
        aperture_radius,
        focus_distance,
    }))
}

/// The cameras of a spec, all perspective (transforms.json describes pinhole cameras only),
/// and their thin lenses ([`view_thin_lens`]). Generated views frame the model as the
/// automatic camera does, at `--yfov` (default 45°).
fn view_cameras(
    args: &RenderArgs,
    spec: &ViewSpec,
    explicit: &[ExplicitView],
    scene: &Scene,
    width: u32,
    height: u32,
) -> Result<(Vec<Camera>, Vec<Option<ThinLens>>)> {
    let aspect = width as f32 / height as f32;
    let mut options = PlanOptions {
        yfov_degrees: args.yfov,
        look_at: args.look_at,
        orbit_radius: args.orbit_radius,
        orbit_azimuth: args.orbit_azimuth,
        orbit_elevation: args.orbit_elevation,
        seed: args.seed,
    };
    if let (ViewSpec::Orbit(_), Some(_)) = (spec, args.turntable) {
        // A turntable starts where the plain render stands (the file's first camera, else
        // the automatic camera): its direction from the target; a plain orbit in front.
        let plain = match scene.cameras.first() {
            Some(camera) => camera.clone(),
            None => auto_camera(&scene.bounds, &scene.soup.positions, aspect),
        };
        let target = args.look_at.unwrap_or(scene.bounds.center());
        options.orbit_azimuth = options
            .orbit_azimuth
            .or(Some(azimuth_degrees(plain.position, target)));
        options.orbit_elevation = options
            .orbit_elevation
            .or(Some(elevation_degrees(plain.position, target)));
    }
    // The scene's source is the model as given, so a refusal names it as the CLI does.
    let cameras = plan_cameras(spec, explicit, scene, aspect, &options)?;
    if let Some(i) = cameras
        .iter()
        .position(|c| matches!(c.projection, Projection::Orthographic { .. }))
    {
        bail!(
            "{}: --views: view {i} is an orthographic camera, and transforms.json describes perspective (pinhole) cameras only",
            args.model.display()
        );
    }
    // Every view's lens, made before the first view is rendered.
    let lenses = cameras
        .iter()
        .enumerate()
        .map(|(k, camera)| {
            let target = explicit.get(k).and_then(ExplicitView::focus_target);
            let target = target.or(args.look_at).unwrap_or(scene.bounds.center());
            view_thin_lens(args, k, camera, target)
        })
        .collect::<Result<_>>()?;
    Ok((cameras, lenses))
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
    /// The model file's SHA-256 and its inputs' ([`model_digest`]), part of every view's
    /// fingerprint.
    model_sha256: String,
    /// The views to render (`--shard`).
    shard: Shard,
}

/// One view as it will be rendered: the text of its view file, its render settings, its frame
/// of transforms.json and the fingerprint its record carries.
struct ViewWork {
    /// The view file, before the render adds how it was denoised.
    record: ViewFile,
    view_path: PathBuf,
    settings: RenderSettings,
    frame: Frame,
    fingerprint: String,
}

impl ViewRun<'_> {
    /// The numbers of the views this run renders: all, or its shard's.
    fn views(&self) -> Vec<usize> {
        (0..self.count)
            .filter(|&k| in_shard(k, self.shard))
            .collect()
    }

    /// What view `k` is rendered from: the view file's text, the settings read back from it,
    /// its frame and its fingerprint. No work beyond that.
    fn prepare(
        &self,
        k: usize,
        camera: &Camera,
        lens: Option<ThinLens>,
        names: &ViewNames,
    ) -> Result<ViewWork> {
        let (args, dir, (width, height)) = (self.args, self.dir, (self.width, self.height));
        let mut record = ViewFile::new(
            camera,
            width,
            height,
            self.lights,
            self.ambient,
            self.using_rig,
        );
        record_render(
            &mut record,
            args,
            &self.prepared.scene,
            self.environment.as_ref(),
        );
        record.camera.set_thin_lens(lens);
        // Render what `render --view` reads back from the view file, number for number, so
        // that the view rendered alone from its file gives the same bytes.
        let text = record.to_json();
        let view_path = dir.join(&names.view);
        let read_back = ViewFile::from_json(&text, &view_path)?;
        let view = View::from_camera(&read_back.camera()?, width, height);
        let view = match read_back.camera.thin_lens() {
            Ok(Some(lens)) => view.with_thin_lens(lens),
            Ok(None) => view,
            Err(problem) => bail!("view {k}: {problem}"),
        };
        let intrinsics =
            Intrinsics::of(&view).with_context(|| format!("view {k}: not a perspective camera"))?;
        let settings = RenderSettings {
            view,
            spp: args.spp(),
            seed: args.seed,
            lights: read_back.lights(),
            ambient: Vec3::from(read_back.ambient),
            exposure: args.exposure,
            shading: args.shading,
            aovs: names.depth.is_some() || names.normal.is_some() || names.segmentation.is_some(),
            integrator: args.integrator,
            bounces: args.bounces,
            environment: self.environment.clone(),
            environment_visible: args.env_visible,
            noise: args.noise(),
            clamp_indirect: args.clamp_indirect,
            // The denoiser's guides, gathered from the path tracer's own samples.
            guides: args.denoises(),
        };
        let frame = Frame {
            file_path: names.image.clone(),
            transform_matrix: camera_to_world(&settings.view),
            intrinsics,
            depth_file_path: names.depth.clone(),
            mask_path: names.mask.clone(),
            thin_lens: settings.view.thin_lens,
        };
        // Everything that decides the view's bytes: the pixels' inputs (as tiles join on
        // them), the model file and meshtracer's version, and the view file's text.
        let fingerprint = sha256_hex(
            format!(
                "meshtracer {}\nmodel sha256 {}\nrender {}\ndenoised {}\nview file {text}",
                env!("CARGO_PKG_VERSION"),
                self.model_sha256,
                super::tiles::render_fingerprint(args, &settings, &self.prepared.scene),
                args.denoises(),
            )
            .as_bytes(),
        );
        Ok(ViewWork {
            record,
            view_path,
            settings,
            frame,
            fingerprint,
        })
    }

    /// Renders view `k` and writes its files: image, AOVs, view file. Returns what the
    /// render did, the image and the view's record (its files hashed).
    fn render(
        &self,
        k: usize,
        work: &ViewWork,
        names: &ViewNames,
    ) -> Result<(RenderStats, meshtracer::output::Image, RenderedView)> {
        let (args, dir) = (self.args, self.dir);
        let image_path = dir.join(&names.image);
        let output = PendingOutput::reserve(&image_path, args.no_clobber)?;
        let interrupted = || {
            let done = (0..k).filter(|&v| in_shard(v, self.shard)).count();
            Interrupted(format!(
                "{done} of {} views written to {} ({TRANSFORMS_FILE} not written; each finished view is recorded in {}: run the same command with --resume to finish)",
                self.views().len(),
                dir.display(),
                rendered_file(self.shard)
            ))
        };
        let (mut image, stats, aovs) =
            render(self.prepared, &work.settings, self.cancel, &|_, _| {})
                .map_err(|_| interrupted())?;
        // Each view is a whole image: denoised as a single render is, and recorded so.
        let mut record = work.record.clone();
        if args.denoises() {
            let region = meshtracer::render::Region::full(self.width, self.height);
            let denoised = super::render::denoise_image(
                self.prepared,
                &work.settings,
                region,
                &mut image,
                self.cancel,
                &mut super::Phases::default(),
            )
            .map_err(|e| {
                if e.is::<meshtracer::render::Cancelled>() {
                    interrupted().into()
                } else {
                    e
                }
            })?;
            record.denoise = Some(super::render::view_denoise(&denoised));
        }
        output.commit(&image, args.background, args.tonemap)?;
        let text = record.to_json();
        let written = self
            .write_companions(names, &image, aovs.as_ref(), &work.view_path, &text)
            .and_then(|()| self.record(k, work, names));
        let record = match written {
            Ok(record) => record,
            Err(e) => {
                // None of this view's files without the others: the image goes with its AOVs.
                for name in std::iter::once(&names.image).chain(names.companions()) {
                    let _ = std::fs::remove_file(dir.join(name));
                }
                return Err(e);
            }
        };
        if !args.quiet {
            note!(
                "[{}/{}] {} rendered in {:.3} s",
                k + 1,
                self.count,
                image_path.display(),
                stats.time.as_secs_f64()
            );
        }
        Ok((stats, image, record))
    }

    /// The record of view `k`, its files just written: their names and hashes.
    fn record(&self, k: usize, work: &ViewWork, names: &ViewNames) -> Result<RenderedView> {
        let files = names
            .in_order()
            .into_iter()
            .map(|name| {
                let path = self.dir.join(name);
                let sha256 = sha256_file(&path)
                    .with_context(|| format!("{}: cannot read it back", path.display()))?;
                Ok(OutputRecord {
                    path: name.to_string(),
                    sha256,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(RenderedView {
            view: k,
            fingerprint: work.fingerprint.clone(),
            files,
        })
    }

    /// Writes view `k`'s files after its image: the AOVs, the mask, the view file (`text`).
    fn write_companions(
        &self,
        names: &ViewNames,
        image: &meshtracer::output::Image,
        aovs: Option<&meshtracer::render::Aovs>,
        view_path: &Path,
        text: &str,
    ) -> Result<()> {
        let (args, dir, (width, height)) = (self.args, self.dir, (self.width, self.height));
        if let Some(a) = aovs {
            if let Some(name) = &names.depth {
                let path = dir.join(name);
                meshtracer::output::aov::write_depth(
                    &path,
                    width,
                    height,
                    &a.depth,
                    args.depth_scale,
                )?;
            }
            if let Some(name) = &names.normal {
                meshtracer::output::aov::write_normals(&dir.join(name), width, height, &a.normal)?;
            }
            if let Some(name) = &names.segmentation {
                meshtracer::output::aov::write_segmentation(
                    &dir.join(name),
                    width,
                    height,
                    &a.instance,
                )?;
            }
            let depth = names.depth.as_ref().map(|n| dir.join(n));
            let segmentation = names.segmentation.as_ref().map(|n| dir.join(n));
            super::warn_png_losses(args, depth.as_deref(), segmentation.as_deref(), a);
        }
        if let Some(name) = &names.mask {
            let coverage: Vec<f32> = image.pixels.iter().map(|p| p.w).collect();
            meshtracer::output::aov::write_mask(&dir.join(name), width, height, &coverage)?;
        }
        meshtracer::output::write_atomic(view_path, text.as_bytes())?;
        Ok(())
    }
}

/// What the summary line reports.
struct Summary {
    triangles: usize,
    accel: AccelKind,
    preset: meshtracer::accel::BvhPreset,
    load_time: Duration,
    bvh_time: Duration,
    views: usize,
    /// Views kept from an earlier run (`--resume`), not rendered.
    kept: usize,
    width: u32,
    height: u32,
    totals: RenderStats,
    threads: usize,
    /// The files the model refers to.
    inputs: Vec<PathBuf>,
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
        let rendered = self.views - self.kept;
        let kept = match self.kept {
            0 => String::new(),
            n => format!(", {n} kept from an earlier run"),
        };
        let pixels = u64::from(self.width) * u64::from(self.height);
        let work = match rendered {
            // Everything was kept (`--resume`): no rays, no rate to report.
            0 => format!("no view rendered ({} kept from an earlier run)", self.kept),
            n => format!(
                "{n} view{} of {}x{}{} at {} rendered in {render_seconds:.3} s ({:.3} s a view{kept}): {} rays, {:.2} Mrays/s on {}",
                if n == 1 { "" } else { "s" },
                self.width,
                self.height,
                match args.aperture_radius.filter(|r| *r > 0.0) {
                    Some(r) => format!(" through a lens of radius {}", super::length_label(r)),
                    None => String::new(),
                },
                super::spp_label(
                    args.spp(),
                    args.noise(),
                    self.totals.samples,
                    pixels * n as u64
                ),
                render_seconds / n as f64,
                self.totals.rays(),
                self.totals.mrays_per_second(),
                super::threads_label(self.threads),
            ),
        };
        note!(
            "{}: {} triangles, loaded once in {:.1} ms, {structure}; {work}; {:.3} s in all -> {}",
            args.model.display(),
            self.triangles,
            self.load_time.as_secs_f64() * 1e3,
            wall.as_secs_f64(),
            args.output
                .join(match shard(args) {
                    Shard::ALL => TRANSFORMS_FILE.to_string(),
                    // A shard writes no transforms.json: its record is what it adds.
                    part => rendered_file(part),
                })
                .display()
        );
    }
}

/// The outputs of a run beyond each view's files: the turntable's GIF and the contact sheet,
/// both reserved before any work (an unwritable path fails first) and filled view by view.
struct Extras {
    gif: Option<GifWriter>,
    sheet: Option<SheetOutput>,
}

/// A contact sheet being filled, and where it goes: a file (`--contact-sheet`), the terminal
/// (`--preview`: the views of a run are shown together, as one sheet), or both.
struct SheetOutput {
    file: Option<PendingFile>,
    /// Known once the number of views and their size are.
    sheet: Option<ContactSheet>,
}

impl Extras {
    /// Checks the options of the GIF and the sheet; `count` is the number of views when known
    /// before loading (all but `cameras`).
    fn check(args: &RenderArgs, count: Option<usize>) -> Result<()> {
        if let Some(path) = &args.gif {
            if !has_extension(path, "gif") {
                bail!("--gif {}: the file name must end in .gif", path.display());
            }
            if let Some(fps) = args.fps {
                check_fps(fps).map_err(anyhow::Error::msg)?;
            }
        }
        if let Some(path) = &args.contact_sheet {
            if !has_extension(path, "png") {
                bail!(
                    "--contact-sheet {}: the file name must end in .png",
                    path.display()
                );
            }
            // The layout's own checks (columns, cell width) come before the model loads.
            if let Some(n) = count {
                SheetLayout::new(n, args.sheet_columns, args.sheet_cell_width, (1, 1))
                    .map_err(|e| anyhow::anyhow!("--contact-sheet: {e}"))?;
            }
        }
        Ok(())
    }

    /// The paths of the GIF and the sheet, with their options.
    fn paths(args: &RenderArgs) -> Vec<(&'static str, PathBuf)> {
        let gif = args.gif.iter().map(|p| ("--gif", p.clone()));
        let sheet = args
            .contact_sheet
            .iter()
            .map(|p| ("--contact-sheet", p.clone()));
        gif.chain(sheet).collect()
    }

    /// Reserves the files (checked by [`Extras::check`]).
    fn reserve(args: &RenderArgs, count: Option<usize>) -> Result<Extras> {
        let gif = match &args.gif {
            Some(path) => {
                let delay = frame_delay_centiseconds(count.unwrap_or(1), args.fps);
                Some(GifWriter::create(path, args.no_clobber, delay)?)
            }
            None => None,
        };
        let file = match &args.contact_sheet {
            Some(path) => Some(PendingFile::reserve(path, args.no_clobber)?),
            None => None,
        };
        let sheet =
            (file.is_some() || args.preview.is_some()).then_some(SheetOutput { file, sheet: None });
        Ok(Extras { gif, sheet })
    }

    /// Lays the sheet out for `count` views of `size` (width, height), refusing a sheet over
    /// `--max-pixels` before any view is rendered.
    fn lay_out(&mut self, args: &RenderArgs, count: usize, size: (u32, u32)) -> Result<()> {
        if let Some(out) = &mut self.sheet {
            out.sheet = match sheet_layout(args, count, size) {
                Ok(layout) => Some(ContactSheet::new(layout)),
                // A sheet only for the terminal is not worth failing the run for.
                Err(e) if out.file.is_none() => {
                    note!("warning: --preview: no preview of the views ({e:#})");
                    None
                }
                Err(e) => return Err(e),
            };
        }
        Ok(())
    }

    /// Whether the GIF or the sheet (file or terminal) takes the views' images.
    fn needs_images(&self) -> bool {
        self.gif.is_some() || self.sheet.is_some()
    }

    /// Adds view `k` to the GIF and the sheet, over `background` through the view transform.
    fn add(
        &mut self,
        k: usize,
        camera: &Camera,
        image: &meshtracer::output::Image,
        (background, view): (Option<Vec3>, meshtracer::color::ViewTransform),
    ) -> Result<()> {
        if !self.needs_images() {
            return Ok(());
        }
        // The bytes a PNG view holds (`PendingOutput::commit`), which a resumed run reads back.
        let rgba =
            image::RgbaImage::from_raw(image.width, image.height, image.to_srgb8(background, view))
                .context("an image of the wrong size (a bug)")?;
        self.add_rgba(k, camera, rgba)
    }

    /// Adds view `k`, as 8-bit sRGB RGBA, to the GIF and the sheet.
    fn add_rgba(&mut self, k: usize, camera: &Camera, rgba: image::RgbaImage) -> Result<()> {
        if let Some(sheet) = self.sheet.as_mut().and_then(|s| s.sheet.as_mut()) {
            let label = match &camera.name {
                Some(name) => format!("{k} {name}"),
                None => k.to_string(),
            };
            sheet.place(k, &rgba, &label);
        }
        if let Some(gif) = &mut self.gif {
            gif.add(rgba)?;
        }
        Ok(())
    }

    /// Writes the GIF and the sheet, and shows the sheet for `--preview`; returns the paths
    /// in the order written.
    fn finish(self, quiet: bool, preview: Option<crate::cli::PreviewMode>) -> Result<Vec<PathBuf>> {
        let mut written = Vec::new();
        if let Some(gif) = self.gif {
            let (path, frames, time) = (gif.path().to_path_buf(), gif.frames(), gif.encode_time());
            gif.finish()?;
            if !quiet {
                note!(
                    "{}: {frames} frames, encoded in {:.2} s ({:.1} ms a frame)",
                    path.display(),
                    time.as_secs_f64(),
                    time.as_secs_f64() * 1e3 / frames.max(1) as f64
                );
            }
            written.push(path);
        }
        if let Some(SheetOutput { file, sheet }) = self.sheet {
            if let Some(file) = file {
                let sheet = sheet
                    .as_ref()
                    .context("the contact sheet was never laid out (a bug)")?;
                written.push(write_sheet(file, sheet, "views", quiet)?);
            }
            if let (Some(mode), Some(sheet)) = (preview, &sheet) {
                meshtracer::output::preview::show_rgb(sheet.image(), mode).context("--preview")?;
            }
        }
        Ok(written)
    }
}

/// Writes a finished contact sheet (`what` its cells are, for the summary line) and returns
/// its path.
pub(super) fn write_sheet(
    file: PendingFile,
    sheet: &ContactSheet,
    what: &str,
    quiet: bool,
) -> Result<PathBuf> {
    let bytes = sheet.to_png().map_err(|source| SaveError::Encode {
        path: file.path().to_path_buf(),
        error: source,
    })?;
    file.file()
        .write_all(&bytes)
        .map_err(|e| file.unwritable(e))?;
    let path = file.path().to_path_buf();
    file.commit()?;
    if !quiet {
        let l = sheet.layout();
        note!(
            "{}: {} {what} in {}, {}x{} pixels",
            path.display(),
            l.count,
            super::counted(l.columns as usize, "column"),
            l.width(),
            l.height()
        );
    }
    Ok(path)
}

/// The contact-sheet layout the options ask for, refused over `--max-pixels`.
pub(super) fn sheet_layout(
    args: &RenderArgs,
    count: usize,
    image_size: (u32, u32),
) -> Result<SheetLayout> {
    let layout = SheetLayout::new(count, args.sheet_columns, args.sheet_cell_width, image_size)
        .map_err(|e| anyhow::anyhow!("--contact-sheet: {e}"))?;
    if layout.pixels() > args.max_pixels {
        bail!(
            "--contact-sheet: {count} cells of {}x{} in {} columns make a {}x{} sheet, over the limit of {} pixels (choose a smaller --sheet-cell-width, or raise --max-pixels)",
            layout.cell_width,
            layout.thumb_height,
            layout.columns,
            layout.width(),
            layout.height(),
            args.max_pixels
        );
    }
    Ok(layout)
}

/// Whether `path` ends in `.ext` (any case).
pub(super) fn has_extension(path: &Path, ext: &str) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case(ext))
}
