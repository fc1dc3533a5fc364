//! `meshtracer batch MANIFEST -o DIR` and `meshtracer batch-merge DIR`: many models, each
//! rendered by the same code as `render` (one view, or `--views` after one load and one BVH
//! build), a failure recorded without stopping the others; `--resume` and `--shard I/N` make
//! each task of a scheduler a clean, resumable, deterministic slice of the work.
//!
//! How records survive a kill: each job, once its outputs are written, writes
//! `DIR/<id>/job.json` atomically (temporary file, fsync, rename), and a job about to be
//! (re)done first deletes its job.json, so a job killed halfway never passes for finished.
//! The results file (`results.jsonl`, or `results.I-of-N.jsonl` for a shard) is rebuilt from
//! this run's records, sorted by id, and written the same way once every job has run. A
//! killed run therefore leaves whole files only, never a torn line: the job.json of every
//! job it finished, which `--resume` reads, and the results file of an earlier run if any.
//!
//! `--contact-sheet FILE` lays this run's jobs out in a grid, in manifest order: each cell the
//! first image a job wrote (read back from its file, a skipped job's too), a failed job a
//! crossed-out cell, labelled with the job id.

use super::views::{has_extension, sheet_layout, write_sheet};
use super::{
    image_size, interrupt_flag, remove_leftovers, render_model, Interrupted, RenderReport,
};
use crate::cli::{BatchArgs, BatchMergeArgs, LoadArgs, RenderArgs};
use anyhow::{anyhow, bail, Context, Result};
use meshtracer::jobs::batch::{
    check_output_name, input_records, output_key, read_manifest, read_results, results_jsonl,
    sha256_file, verify_inputs, Entry, FingerprintRecord, Job, JobRecord, OutputRecord, Shard,
    Status, Timings, JOB_FILE, RESULTS_FILE,
};
use meshtracer::jobs::lock::{self, Acquired, Holder};
use meshtracer::output::sheet::ContactSheet;
use meshtracer::output::PendingFile;
use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant, SystemTime};

/// The image of a job without views, unless `--image-name` or the manifest says otherwise.
const DEFAULT_IMAGE: &str = "image.png";

/// How many failed jobs the final error lists by name (the results file has them all).
const FAILURES_LISTED: usize = 3;

/// Runs every job of the manifest that belongs to this shard.
pub(super) fn batch_command(args: &BatchArgs) -> Result<()> {
    let start = Instant::now();
    let defaults = &args.render;
    let dir = defaults.output.as_path();
    // Refused before any work: names on the command line apply to every job.
    for (option, name) in default_output_names(args)? {
        check_output_name(&name, option).map_err(anyhow::Error::msg)?;
    }
    if let Some(n) = defaults.turntable {
        bail!(
            "--turntable {n}: a turntable is made by render; in a batch give the jobs \"views\": \"orbit:{n}\" (or --views orbit:{n})"
        );
    }
    if let Some(n) = defaults.frames {
        bail!(
            "--frames {n}: an animation's frames are made by render (a batch job renders one pose: give it \"animation\" and \"time\")"
        );
    }
    if let Some(path) = &defaults.contact_sheet {
        if !has_extension(path, "png") {
            bail!(
                "--contact-sheet {}: the file name must end in .png",
                path.display()
            );
        }
    }
    let shard = match args.render.shard {
        Some(shard) => shard,
        None => Shard::from_env(|name| std::env::var(name).ok(), args.shard_count)
            .map_err(anyhow::Error::msg)?
            .unwrap_or(Shard::ALL),
    };
    let entries = read_manifest(&defaults.model)?;
    if entries.is_empty() {
        bail!(
            "{}: no jobs (no .gltf, .glb or .obj file below the folder, or no line in the file)",
            defaults.model.display()
        );
    }
    if dir.is_file() {
        bail!(
            "-o {}: is a file; a batch writes into a folder",
            dir.display()
        );
    }
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create the output folder {}", dir.display()))?;
    let mine: Vec<&Entry> = entries.iter().filter(|e| shard.holds(&e.key)).collect();
    // Installed before the sheet's temporary file is reserved, so that a signal never kills
    // the batch beside it.
    let cancel = interrupt_flag();
    // The sheet of jobs goes to --contact-sheet, and to the terminal for --preview (a batch
    // shows its jobs together once, not each job as it finishes).
    let wants_sheet = defaults.contact_sheet.is_some() || defaults.preview.is_some();
    let mut sheet = match &defaults.contact_sheet {
        _ if mine.is_empty() || !wants_sheet => None,
        Some(path) => Some(JobSheet::new(defaults, Some(path), mine.len())?),
        // A sheet only for the terminal is not worth failing the batch for.
        None => JobSheet::new(defaults, None, mine.len())
            .map_err(|e| note!("warning: --preview: no preview of the jobs ({e:#})"))
            .ok(),
    };

    let progress = Progress::new(defaults.quiet, mine.len());
    let started = SystemTime::now();
    let mut records = Vec::with_capacity(mine.len());
    let interrupted = |done: usize| -> anyhow::Error {
        progress.finish();
        Interrupted(format!(
            "{done} of {} jobs done; each finished job is recorded in {}/<id>/{JOB_FILE}: run the same command with --resume to finish",
            mine.len(),
            dir.display()
        ))
        .into()
    };
    // Jobs another batch was rendering into this folder: taken up again once the rest are done.
    let mut busy = Vec::new();
    for (k, entry) in mine.iter().enumerate() {
        let outcome = if cancel.load(Ordering::SeqCst) {
            Outcome::Interrupted
        } else {
            run_job(args, dir, entry, &progress, started, None)
        };
        match outcome {
            Outcome::Done(record, note) => {
                progress.job_done(records.len(), &record, note.as_deref());
                if let Some(sheet) = &mut sheet {
                    sheet.add(k, &record, dir, defaults);
                }
                records.push(*record);
            }
            Outcome::Busy(holder) => busy.push((k, entry, holder)),
            Outcome::Interrupted => return Err(interrupted(records.len())),
        }
    }
    for (k, entry, holder) in busy {
        progress.waiting(entry, &holder, dir);
        let mut watch = lock::Watch::new();
        let record = loop {
            if cancel.load(Ordering::SeqCst) {
                return Err(interrupted(records.len()));
            }
            match run_job(
                args,
                dir,
                entry,
                &progress,
                started,
                Some((&holder, &mut watch)),
            ) {
                Outcome::Done(record, note) => {
                    progress.job_done(records.len(), &record, note.as_deref());
                    break record;
                }
                Outcome::Busy(_) => std::thread::sleep(LOCK_POLL),
                Outcome::Interrupted => return Err(interrupted(records.len())),
            }
        };
        if let Some(sheet) = &mut sheet {
            sheet.add(k, &record, dir, defaults);
        }
        records.push(*record);
    }
    progress.finish();
    let results = dir.join(shard.results_file());
    meshtracer::output::write_atomic(&results, results_jsonl(&records).as_bytes())?;
    if let Some(JobSheet { file, sheet }) = sheet {
        if let Some(file) = file {
            write_sheet(file, &sheet, "jobs", defaults.quiet)?;
        }
        if let Some(mode) = defaults.preview {
            meshtracer::output::preview::show_rgb(sheet.image(), mode).context("--preview")?;
        }
    }
    let count = |status| records.iter().filter(|r| r.status == status).count();
    let failed = count(Status::Failed);
    if !defaults.quiet {
        let of = if shard == Shard::ALL {
            String::new()
        } else {
            format!(" of shard {shard} ({} in the manifest)", entries.len())
        };
        note!(
            "batch: {}{of}: {} ok, {} skipped, {failed} failed in {:.1} s -> {}",
            super::counted(records.len(), "job"),
            count(Status::Ok),
            count(Status::Skipped),
            start.elapsed().as_secs_f64(),
            results.display()
        );
    }
    failures(&records, &results)
}

/// `Err` listing the failed jobs, if any.
fn failures(records: &[JobRecord], results: &Path) -> Result<()> {
    let failed: Vec<&JobRecord> = records
        .iter()
        .filter(|r| r.status == Status::Failed)
        .collect();
    if failed.is_empty() {
        return Ok(());
    }
    let mut list: Vec<String> = failed
        .iter()
        .take(FAILURES_LISTED)
        .map(|r| {
            format!(
                "{}: {}",
                r.id.as_deref().unwrap_or("(no id)"),
                r.error.as_deref().unwrap_or("failed")
            )
        })
        .collect();
    if failed.len() > FAILURES_LISTED {
        list.push(format!("and {} more", failed.len() - FAILURES_LISTED));
    }
    bail!(
        "{} of {} jobs failed (all recorded in {}): {}",
        failed.len(),
        records.len(),
        results.display(),
        list.join("; ")
    )
}

/// The output names the command line gives every job, with their options.
fn default_output_names(args: &BatchArgs) -> Result<Vec<(&'static str, String)>> {
    let r = &args.render;
    let mut names = Vec::new();
    for (option, path) in r.side_outputs() {
        if let Some(path) = path {
            names.push((option, utf8(path, option)?));
        }
    }
    names.extend(args.image_name.iter().map(|n| ("--image-name", n.clone())));
    names.extend(r.view_name.iter().map(|n| ("--view-name", n.clone())));
    Ok(names)
}

fn utf8(path: &Path, option: &str) -> Result<String> {
    path.to_str()
        .map(str::to_string)
        .with_context(|| format!("{option} {}: not valid UTF-8", path.display()))
}

/// What became of one job.
enum Outcome {
    /// Recorded (ok, failed or skipped), with a note for the progress line.
    Done(Box<JobRecord>, Option<String>),
    /// Ctrl-C: the job was not finished and is not recorded.
    Interrupted,
    /// Another batch holds the job's lock (it is rendering the job into the same folder).
    Busy(Holder),
}

/// How often a batch looks again at a job another batch holds.
const LOCK_POLL: Duration = Duration::from_millis(200);

/// Runs one job: refused, skipped (`--resume`, verified), or rendered and recorded.
/// The job's lock is taken first: a job another batch holds is left alone (`Busy`), and a job
/// another batch recorded since this one `started` (also one taken up again `after` its holder
/// let it go, its lock watched meanwhile) adopts that batch's record instead of rendering again.
fn run_job(
    args: &BatchArgs,
    dir: &Path,
    entry: &Entry,
    progress: &Progress,
    started: SystemTime,
    after: Option<(&Holder, &mut lock::Watch)>,
) -> Outcome {
    let start = Instant::now();
    let fail = |error: String| {
        Outcome::Done(
            Box::new(JobRecord::failed(
                entry,
                error,
                start.elapsed().as_secs_f64(),
            )),
            None,
        )
    };
    let job = match &entry.job {
        Ok(job) => job,
        Err(e) => return fail(e.clone()),
    };
    let job_dir = dir.join(&job.id);
    let (render_args, fingerprint) = match job_args(args, job, &job_dir) {
        Ok(prepared) => prepared,
        Err(e) => return fail(format!("job '{}': {e:#}", job.id)),
    };
    let record_path = job_dir.join(JOB_FILE);
    if let Err(e) = std::fs::create_dir_all(&job_dir) {
        return fail(format!("cannot create {}: {e}", job_dir.display()));
    }
    // Held until this function returns, whatever it returns.
    let (after, watch) = after.unzip();
    let _lock = match lock::acquire(&job_dir, watch, progress.renewal_failed()) {
        Ok(Acquired::Held(lock)) => lock,
        Ok(Acquired::Busy(holder)) => return Outcome::Busy(holder),
        Err(e) => return fail(format!("job '{}': cannot lock its folder: {e}", job.id)),
    };
    // A record written since this batch started is another batch's, running beside it.
    if let Some(record) = record_of_other_batch(&record_path, &fingerprint, dir, started) {
        let by = after.map_or("another batch".to_string(), |h| format!("the batch of {h}"));
        return Outcome::Done(
            Box::new(record),
            Some(format!("rendered meanwhile by {by}")),
        );
    }
    // Let go without a record this batch can adopt: that batch stopped (interrupted, killed,
    // its host lost) or renders with other options.
    let mut note =
        after.map(|h| format!("taken over from the batch of {h}, which left no record of it"));
    if args.render.resume {
        match finished_record(&record_path, &fingerprint, &job.model, dir) {
            Ok(Some(mut record)) => {
                record.status = Status::Skipped;
                return Outcome::Done(
                    Box::new(record),
                    Some("done before, outputs verified".into()),
                );
            }
            Ok(None) => {}
            Err(why) => note = Some(format!("redone: {why}")),
        }
    }
    // From here until the new record is written, the job must not pass for finished.
    match std::fs::remove_file(&record_path) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => return fail(format!("{}: {e}", record_path.display())),
    }
    for folder in output_folders(&render_args, &job_dir) {
        if let Err(e) = std::fs::create_dir_all(&folder) {
            return fail(format!("cannot create {}: {e}", folder.display()));
        }
        remove_leftovers(&folder);
    }
    progress.start_job(&job.id);
    // Consecutive jobs of one model (an animation's frames as jobs) keep its decoded textures;
    // another model's are not held while this one loads and renders.
    super::forget_kept_textures_unless(&render_args.model);
    let rendered = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        render_model(&render_args, &|done, total| progress.view(done, total))
    }))
    .unwrap_or_else(|panic| {
        let what = panic
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| panic.downcast_ref::<&str>().copied())
            .unwrap_or("unknown panic");
        Err(anyhow!(
            "{}: internal error (please report this model): {what}",
            job.model.display()
        ))
    });
    let mut record = match rendered.and_then(|report| finished(entry, &job.model, dir, &report)) {
        Ok(record) => record,
        Err(e) => {
            if interrupt_flag().load(Ordering::SeqCst) {
                return Outcome::Interrupted;
            }
            remove_single_view_outputs(&render_args);
            JobRecord::failed(entry, format!("{e:#}"), 0.0)
        }
    };
    record.seconds.total = start.elapsed().as_secs_f64();
    record.fingerprint = Some(fingerprint);
    let text = serde_json::to_string_pretty(&record).expect("a record serialises") + "\n";
    if let Err(e) = meshtracer::output::write_atomic(&record_path, text.as_bytes()) {
        return fail(format!("job '{}': {e}", job.id));
    }
    Outcome::Done(Box::new(record), note)
}

/// Removes the files a failed single-view job may have written before it failed (the image
/// when its depth or normals could not be written, say): a failed job leaves none of its
/// files, never an image without the outputs that go with it. A job with views is left to
/// `render --views`, which keeps its finished views whole.
fn remove_single_view_outputs(args: &RenderArgs) {
    if args.views.is_some() {
        return;
    }
    let side = args.side_outputs().into_iter().filter_map(|(_, path)| path);
    for path in std::iter::once(&args.output).chain(side) {
        let _ = std::fs::remove_file(path);
    }
}

/// The folders a job writes into (those a `{view}` pattern names excepted: render --views
/// makes them).
fn output_folders(args: &RenderArgs, job_dir: &Path) -> Vec<PathBuf> {
    let names = args.side_outputs().map(|(_, path)| path);
    let image = match &args.views {
        // With views the names are relative to the job's folder, the image a --view-name.
        Some(_) => args.view_name.as_ref().map(PathBuf::from),
        None => Some(args.output.clone()),
    };
    let mut folders = vec![job_dir.to_path_buf()];
    for file in names.into_iter().flatten().cloned().chain(image) {
        // A single view's paths already start with the job's folder; --views names are
        // relative to it.
        let file = if args.views.is_some() {
            job_dir.join(file)
        } else {
            file
        };
        if let Some(folder) = file.parent() {
            if !folder.to_string_lossy().contains('{') && !folders.iter().any(|f| f == folder) {
                folders.push(folder.to_path_buf());
            }
        }
    }
    folders
}

/// The record of a finished render of the model at `model`: its timings, every output with
/// its hash and the model's inputs with theirs.
fn finished(entry: &Entry, model: &Path, dir: &Path, report: &RenderReport) -> Result<JobRecord> {
    let mut outputs = Vec::with_capacity(report.outputs.len());
    for path in &report.outputs {
        let relative = path.strip_prefix(dir).unwrap_or(path);
        let sha256 =
            sha256_file(path).with_context(|| format!("{}: cannot hash", path.display()))?;
        outputs.push(OutputRecord {
            path: slash_path(relative),
            sha256,
        });
    }
    let seconds = |d: Duration| Some(d.as_secs_f64());
    Ok(JobRecord {
        id: entry.id.clone(),
        model: entry.model.clone(),
        status: Status::Ok,
        error: None,
        triangles: Some(report.triangles),
        seconds: Timings {
            load: seconds(report.load),
            bvh: seconds(report.bvh),
            render: seconds(report.render),
            total: 0.0,
        },
        outputs,
        warnings: report.warnings.clone(),
        inputs: input_records(model, &report.inputs),
        fingerprint: None,
    })
}

fn slash_path(path: &Path) -> String {
    path.components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join("/")
}

/// The record another batch wrote for this job since `started` (this batch's start), when it
/// is for the same options and model: failed, or ok with its outputs as recorded.
fn record_of_other_batch(
    record_path: &Path,
    fingerprint: &str,
    dir: &Path,
    started: SystemTime,
) -> Option<JobRecord> {
    let written = std::fs::metadata(record_path).ok()?.modified().ok()?;
    if written < started {
        return None;
    }
    let text = std::fs::read_to_string(record_path).ok()?;
    let record: JobRecord = serde_json::from_str(&text).ok()?;
    let usable = record.fingerprint.as_deref() == Some(fingerprint)
        && (record.status == Status::Failed || record.verify(dir).is_ok());
    usable.then_some(record)
}

/// The record of an earlier run of this job when it may be skipped: it finished (ok) with the
/// same fingerprint, the files the model refers to are as they were, and every output still
/// has its recorded hash. `Ok(None)` when there is no record; `Err` says why an existing
/// record does not count.
fn finished_record(
    record_path: &Path,
    fingerprint: &str,
    model: &Path,
    dir: &Path,
) -> Result<Option<JobRecord>, String> {
    let text = match std::fs::read_to_string(record_path) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("{JOB_FILE}: {e}")),
    };
    let record: JobRecord =
        serde_json::from_str(&text).map_err(|e| format!("{JOB_FILE} unreadable: {e}"))?;
    if record.status != Status::Ok {
        return Err("it failed last time".into());
    }
    if record.fingerprint.as_deref() != Some(fingerprint) {
        return Err("the options or the model changed".into());
    }
    verify_inputs(model, &record.inputs)?;
    record.verify(dir)?;
    Ok(Some(record))
}

/// The render options of one job: the command line's, overridden by the manifest's, with
/// every output inside `job_dir`; and the job's fingerprint.
fn job_args(batch: &BatchArgs, job: &Job, job_dir: &Path) -> Result<(RenderArgs, String)> {
    let args = render_args(batch, job, job_dir)?;
    // The fingerprint sees the options as they are for any output folder and thread count
    // (the output is the same bytes for any), the model path as the manifest gives it, and
    // the model file's bytes (not the files it refers to).
    let mut canonical = render_args(batch, job, Path::new(""))?;
    canonical.model = PathBuf::from(&job.model_text);
    canonical.threads = 0;
    let model_hash = sha256_file(&job.model).unwrap_or_else(|e| format!("unreadable ({e})"));
    let fingerprint =
        fingerprint_record(&canonical).fingerprint(env!("CARGO_PKG_VERSION"), &model_hash);
    Ok((args, fingerprint))
}

/// The fingerprint record (version 1, [`FingerprintRecord`]) of a job's canonical options:
/// every field of [`RenderArgs`] and [`LoadArgs`], in version 1's order. The destructuring
/// names every field, so an option added to the command line does not compile until its place
/// in the record is decided (appending it changes every fingerprint: a new record version;
/// an option whose default draws what version 1 drew is appended only when it is not the
/// default, so version 1's fingerprints stay as they were).
fn fingerprint_record(args: &RenderArgs) -> FingerprintRecord {
    let RenderArgs {
        model,
        output,
        width,
        height,
        spp_given: _,
        noise_given: _,
        time_limit,
        denoise: _,
        no_denoise: _,
        seed,
        camera,
        look_from,
        look_at,
        up,
        yfov,
        aperture_radius,
        focus_distance,
        views,
        turntable,
        frames,
        gif,
        fps,
        orbit_elevation,
        orbit_azimuth,
        orbit_radius,
        contact_sheet,
        sheet_columns,
        sheet_cell_width,
        view_name,
        tile,
        crop,
        preview,
        accel,
        bvh_preset,
        threads,
        exposure,
        tonemap,
        background,
        ambient,
        shading,
        max_texture_memory,
        no_default_lights,
        integrator,
        bounces,
        clamp_indirect,
        env,
        env_rotation,
        env_intensity,
        env_visible,
        env_out,
        depth_out,
        depth_scale,
        normal_out,
        mask_out,
        segmentation_out,
        stats,
        view_out,
        view,
        max_pixels,
        max_spp,
        no_clobber,
        // How the job is done, never what it writes (a job with views keeps its finished
        // views, which are what it would render again): not part of the fingerprint.
        resume: _,
        // Which jobs the batch renders, never what a job writes.
        shard: _,
        quiet,
        // Changes what is printed, never what is written: not part of the fingerprint.
        no_warnings: _,
        strict,
        variant,
        load,
    } = args;
    let load_record = load_fingerprint_record(load);
    FingerprintRecord::render_options()
        .field("model", model)
        .field("output", output)
        .field("width", width)
        .field("height", height)
        .field("spp", &args.spp())
        .field("time_limit", time_limit)
        // Whether it is denoised, asked for or by default (the default render is).
        .field("denoise", &args.denoises())
        .field("seed", seed)
        .field("camera", camera)
        .field("look_from", look_from)
        .field("look_at", look_at)
        .field("up", up)
        .field("yfov", yfov)
        .field("views", views)
        .field("turntable", turntable)
        .field("gif", gif)
        .field("fps", fps)
        .field("orbit_elevation", orbit_elevation)
        .field("orbit_azimuth", orbit_azimuth)
        .field("orbit_radius", orbit_radius)
        .field("contact_sheet", contact_sheet)
        .field("sheet_columns", sheet_columns)
        .field("sheet_cell_width", sheet_cell_width)
        .field("view_name", view_name)
        .field("tile", tile)
        .field("crop", crop)
        .field("preview", preview)
        .field("accel", accel)
        .field("bvh_preset", bvh_preset)
        .field("threads", threads)
        .field("exposure", exposure)
        .field("background", background)
        .field("ambient", ambient)
        .field("shading", shading)
        .field("max_texture_memory", max_texture_memory)
        .field("no_default_lights", no_default_lights)
        .field("integrator", integrator)
        .field("bounces", bounces)
        .field("env", env)
        .field("env_rotation", env_rotation)
        .field("env_intensity", env_intensity)
        .field("env_visible", env_visible)
        .field("env_out", env_out)
        .field("depth_out", depth_out)
        .field("depth_scale", depth_scale)
        .field("normal_out", normal_out)
        .field("mask_out", mask_out)
        .field("segmentation_out", segmentation_out)
        .field("stats", stats)
        .field("view_out", view_out)
        .field("view", view)
        .field("max_pixels", max_pixels)
        .field("max_spp", max_spp)
        .field("no_clobber", no_clobber)
        .field("quiet", quiet)
        .field("strict", strict)
        .field("variant", variant)
        .field_unless_default("tonemap", tonemap)
        .field_unless_default("noise", &args.noise())
        .field_unless_default("clamp_indirect", clamp_indirect)
        .field_unless_default("aperture_radius", aperture_radius)
        .field_unless_default("focus_distance", focus_distance)
        .field_unless_default("frames", frames)
        .group_field("load", &load_record)
}

/// The `load` group of [`fingerprint_record`]: every field of [`LoadArgs`], named by the
/// destructuring as there.
fn load_fingerprint_record(load: &LoadArgs) -> FingerprintRecord {
    let LoadArgs {
        allow_external_files,
        max_triangles,
        animation,
        time,
    } = load;
    FingerprintRecord::load_options()
        .field("allow_external_files", allow_external_files)
        .field("max_triangles", max_triangles)
        .field("animation", animation)
        .field("time", time)
}

fn render_args(batch: &BatchArgs, job: &Job, job_dir: &Path) -> Result<RenderArgs> {
    let mut args = batch.render.clone();
    args.model = job.model.clone();
    // A job with views keeps its finished views on --resume; under --no-clobber, which
    // `render --views --resume` refuses, the job renders as before.
    args.resume = batch.render.resume && !batch.render.no_clobber;
    // The batch's shard picks jobs; a job renders all its views.
    args.shard = None;
    args.quiet = true;
    // A job's warnings go to its record (job.json, results.jsonl), not between the batch's
    // progress lines.
    args.no_warnings = true;
    // The batch's sheet and preview are not the job's (and their options leave the
    // fingerprint alone).
    args.contact_sheet = None;
    args.preview = None;
    args.sheet_columns = None;
    args.sheet_cell_width = meshtracer::output::sheet::DEFAULT_CELL_WIDTH;
    if job.width.is_some() {
        args.width = job.width;
    }
    if job.height.is_some() {
        args.height = job.height;
    }
    if let Some(spp) = job.spp {
        args.spp_given = Some(spp);
    }
    if let Some(seed) = job.seed {
        args.seed = seed;
    }
    if job.animation.is_some() {
        args.load.animation = job.animation.clone();
    }
    if job.time.is_some() {
        args.load.time = job.time;
    }
    if job.views.is_some() {
        args.views = job.views.clone();
    }
    let views = args.views.is_some();
    // The command line's names serve jobs with and without views alike: for a job with views
    // a name without {view} is numbered per view, as the view files are ({view:03}.NAME).
    let numbered = |name: String| {
        if !views || name.contains("{view") {
            return name;
        }
        match name.rsplit_once('/') {
            Some((folder, file)) => format!("{folder}/{{view:03}}.{file}"),
            None => format!("{{view:03}}.{name}"),
        }
    };
    let given = |name: &Option<String>, default: &Option<PathBuf>, option: &str| match name {
        Some(n) => Ok(Some(n.clone())),
        None => default
            .as_deref()
            .map(|p| utf8(p, option).map(numbered))
            .transpose(),
    };
    let o = &job.outputs;
    let image = o
        .image
        .clone()
        .or_else(|| batch.image_name.clone().map(numbered))
        .or_else(|| if views { args.view_name.clone() } else { None });
    let depth = given(&o.depth, &args.depth_out, "--depth-out")?;
    let normal = given(&o.normal, &args.normal_out, "--normal-out")?;
    let mask = given(&o.mask, &args.mask_out, "--mask-out")?;
    let segmentation = given(
        &o.segmentation,
        &args.segmentation_out,
        "--segmentation-out",
    )?;
    let view = given(&o.view, &args.view_out, "--view-out")?;
    let env_out = given(&None, &args.env_out, "--env-out")?;
    let stats = given(&None, &args.stats, "--stats")?;
    // A single view's image has a name even when none is given.
    let image_name = match (&image, views) {
        (None, false) => Some(DEFAULT_IMAGE.to_string()),
        _ => image.clone(),
    };
    let names = [
        ("image", image_name.as_ref()),
        ("depth", depth.as_ref()),
        ("normal", normal.as_ref()),
        ("mask", mask.as_ref()),
        ("segmentation", segmentation.as_ref()),
        ("view", view.as_ref()),
        ("--env-out", env_out.as_ref()),
        ("--stats", stats.as_ref()),
    ];
    let mut taken = HashSet::new();
    for (what, name) in names {
        if let Some(name) = name {
            check_output_name(name, what).map_err(anyhow::Error::msg)?;
            if !taken.insert(output_key(name)) {
                bail!("two outputs are named '{name}': give them different names");
            }
        }
    }
    let inside = |name: Option<String>| name.map(|n| job_dir.join(n));
    // The panorama is written where named, with or without views.
    args.env_out = inside(env_out);
    if views {
        if stats.is_some() {
            bail!("--stats measures a single-view render; this job has views");
        }
        // render --views names every file relative to the folder it writes into.
        args.output = job_dir.to_path_buf();
        args.view_name = image;
        args.depth_out = depth.map(PathBuf::from);
        args.normal_out = normal.map(PathBuf::from);
        args.mask_out = mask.map(PathBuf::from);
        args.segmentation_out = segmentation.map(PathBuf::from);
        args.view_out = view.map(PathBuf::from);
    } else {
        args.output = job_dir.join(image.as_deref().unwrap_or(DEFAULT_IMAGE));
        args.depth_out = inside(depth);
        args.normal_out = inside(normal);
        args.mask_out = inside(mask);
        args.segmentation_out = inside(segmentation);
        args.view_out = inside(view);
        args.stats = inside(stats);
    }
    Ok(args)
}

/// The contact sheet of a batch: a cell per job of this run, in manifest order.
struct JobSheet {
    /// `--contact-sheet`, if given (else the sheet is only for `--preview`).
    file: Option<PendingFile>,
    sheet: ContactSheet,
}

impl JobSheet {
    /// Reserves `path` (if any) and lays out `count` cells, boxes of the command line's image size
    /// (a job of another aspect is fitted inside its box).
    fn new(defaults: &RenderArgs, path: Option<&Path>, count: usize) -> Result<JobSheet> {
        let layout = sheet_layout(defaults, count, image_size(defaults, None))?;
        Ok(JobSheet {
            file: match path {
                Some(path) => Some(PendingFile::reserve(path, defaults.no_clobber)?),
                None => None,
            },
            sheet: ContactSheet::new(layout),
        })
    }

    /// Puts job `k`'s first image in its cell, or crosses the cell out when the job failed
    /// or its image cannot be read back.
    fn add(&mut self, k: usize, record: &JobRecord, dir: &Path, defaults: &RenderArgs) {
        let id = record.id.as_deref().unwrap_or("(no id)");
        if record.status == Status::Failed {
            self.sheet.place_failed(k, id);
            return;
        }
        // Outputs are listed in the order written: the image first, but for the panorama
        // (--env-out) that a job with views writes before its views.
        let panorama = defaults
            .env_out
            .as_ref()
            .map(|name| slash_path(&Path::new(id).join(name)));
        let image = record
            .outputs
            .iter()
            .find(|o| Some(&o.path) != panorama.as_ref())
            .and_then(|o| {
                meshtracer::tools::compare::read(&dir.join(&o.path), defaults.tonemap).ok()
            });
        match image {
            Some(image) => self.sheet.place(k, &image, id),
            None => self.sheet.place_failed(k, id),
        }
    }
}

/// Progress on standard error: a bar of jobs with an ETA and a bar of the current job's
/// views (drawn only on a terminal), and one line per job (also in logs, e.g. Slurm's).
struct Progress {
    quiet: bool,
    multi: indicatif::MultiProgress,
    jobs: indicatif::ProgressBar,
    views: indicatif::ProgressBar,
    total: usize,
    start: Instant,
}

impl Progress {
    fn new(quiet: bool, total: usize) -> Progress {
        let multi = if quiet {
            indicatif::MultiProgress::with_draw_target(indicatif::ProgressDrawTarget::hidden())
        } else {
            indicatif::MultiProgress::new()
        };
        let style = |template: &str| {
            indicatif::ProgressStyle::with_template(template)
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
                .progress_chars("=> ")
        };
        let jobs = multi.add(indicatif::ProgressBar::new(total as u64));
        jobs.set_style(style(
            "{spinner} jobs  [{bar:30}] {pos}/{len} eta {eta} {msg}",
        ));
        let views = multi.add(indicatif::ProgressBar::new(0));
        views.set_style(style("  views [{bar:30}] {pos}/{len}"));
        Progress {
            quiet,
            multi,
            jobs,
            views,
            total,
            start: Instant::now(),
        }
    }

    fn start_job(&self, id: &str) {
        self.jobs.set_message(id.to_string());
        self.views.set_length(1);
        self.views.set_position(0);
    }

    fn view(&self, done: usize, total: usize) {
        self.views.set_length(total as u64);
        self.views.set_position(done as u64);
    }

    /// The job of `entry` is held by another batch, which this one now waits for: one line
    /// naming the holder and the lock file (to delete if that batch is gone, on another host).
    fn waiting(&self, entry: &Entry, holder: &Holder, dir: &Path) {
        if self.quiet {
            return;
        }
        let id = entry.id.as_deref().unwrap_or("(no id)");
        let lock = dir.join(id).join(lock::LOCK_FILE);
        self.multi.suspend(|| {
            note!(
                "{id}: held by the batch of {holder}; waiting for its record ({} is taken over once that batch is gone: at once on this host, after {} s without a heartbeat from another)",
                lock.display(),
                lock::LEASE.as_secs()
            );
        });
    }

    /// What a job's lock says when renewing it fails: a warning, even with `--quiet`, since
    /// a batch on another host may then render the job beside this one.
    fn renewal_failed(&self) -> lock::RenewalFailed {
        let multi = self.multi.clone();
        Box::new(move |path, e| {
            multi.suspend(|| {
                note!(
                    "warning: cannot renew the job lock {} ({e}); until it is renewed, another batch may take the job over and render it beside this one",
                    path.display(),
                );
            });
        })
    }

    /// `k` jobs were recorded before this one: one line, with the ETA of the rest at the
    /// mean pace.
    fn job_done(&self, k: usize, record: &JobRecord, note: Option<&str>) {
        self.jobs.inc(1);
        if self.quiet {
            return;
        }
        let done = k + 1;
        let remaining = self.total - done;
        let eta = if remaining > 0 {
            let each = self.start.elapsed() / done as u32;
            format!(
                "; eta {}",
                indicatif::HumanDuration(each * remaining as u32)
            )
        } else {
            String::new()
        };
        let id = record.id.as_deref().unwrap_or("(no id)");
        let what = match record.status {
            Status::Ok => format!(
                "ok, {} triangles, {} file{}, load {:.0} ms, BVH {:.0} ms, render {:.3} s",
                record.triangles.unwrap_or(0),
                record.outputs.len(),
                if record.outputs.len() == 1 { "" } else { "s" },
                record.seconds.load.unwrap_or(0.0) * 1e3,
                record.seconds.bvh.unwrap_or(0.0) * 1e3,
                record.seconds.render.unwrap_or(0.0),
            ),
            Status::Skipped => "skipped".to_string(),
            Status::Failed => format!(
                "FAILED: {}",
                record.error.as_deref().unwrap_or("unknown error")
            ),
        };
        let note = note.map_or(String::new(), |n| format!(" ({n})"));
        self.multi.suspend(|| {
            note!("[{done}/{}] {id}: {what}{note}{eta}", self.total);
        });
    }

    fn finish(&self) {
        self.views.finish_and_clear();
        self.jobs.finish_and_clear();
    }
}

/// Joins the results of every shard of a batch into `DIR/results.jsonl`.
pub(super) fn merge_command(args: &BatchMergeArgs) -> Result<()> {
    // A signal before results.jsonl is written stops with none written (the shards' files
    // are only read); once the writing starts, it is finished.
    let cancel = super::interrupt_flag();
    let dir = args.dir.as_path();
    let mut by_count: BTreeMap<usize, BTreeMap<usize, PathBuf>> = BTreeMap::new();
    let listing =
        std::fs::read_dir(dir).with_context(|| format!("cannot read {}", dir.display()))?;
    for item in listing {
        let item = item.with_context(|| format!("cannot read {}", dir.display()))?;
        if let Some(shard) = item.file_name().to_str().and_then(Shard::of_results_file) {
            by_count
                .entry(shard.count)
                .or_default()
                .insert(shard.index, item.path());
        }
    }
    let (count, files) = match by_count.len() {
        0 => bail!(
            "{}: no results.I-of-N.jsonl: no shard of a batch has finished here",
            dir.display()
        ),
        1 => by_count.into_iter().next().expect("one shard count"),
        _ => {
            let counts: Vec<String> = by_count.keys().map(|n| format!("{n} shards")).collect();
            bail!(
                "{}: results of batches split differently ({}): remove the files of the old split",
                dir.display(),
                counts.join(" and ")
            );
        }
    };
    let missing: Vec<String> = (0..count)
        .filter(|i| !files.contains_key(i))
        .map(|i| format!("{i}/{count}"))
        .collect();
    match missing.as_slice() {
        [] => {}
        [one] => bail!(
            "{}: shard {one} has no results file yet (still running, killed or failed to start): run it with --shard {one} --resume, then merge again",
            dir.display()
        ),
        several => bail!(
            "{}: shards {} have no results files yet (still running, killed or failed to start): run each with --shard I/{count} --resume, then merge again",
            dir.display(),
            several.join(", ")
        ),
    }
    let mut records = Vec::new();
    let mut seen = HashSet::new();
    for path in files.values() {
        for record in read_results(path)? {
            if let Some(id) = &record.id {
                if !seen.insert(id.clone()) {
                    bail!(
                        "{}: job '{id}' is recorded by two shards: were the shards run with different manifests?",
                        path.display()
                    );
                }
            }
            records.push(record);
        }
    }
    let results = dir.join(RESULTS_FILE);
    let text = results_jsonl(&records);
    super::render::stop_if_cancelled(&cancel)?;
    meshtracer::output::write_atomic(&results, text.as_bytes())?;
    if !args.quiet {
        let count_of = |status| records.iter().filter(|r| r.status == status).count();
        note!(
            "batch-merge: {}, {}: {} ok, {} skipped, {} failed -> {}",
            super::counted(count, "shard"),
            super::counted(records.len(), "job"),
            count_of(Status::Ok),
            count_of(Status::Skipped),
            count_of(Status::Failed),
            results.display()
        );
    }
    failures(&records, &results)
}
