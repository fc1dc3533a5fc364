//! `meshtracer bench`: build time and ray throughput of the BVH (and of the linear scan) on
//! generated meshes and models, and with `--path-spp` the path tracer against the BVH alone;
//! the measurements are in [`meshtracer::tools::bench`]. Prints a Markdown table and the
//! settings (or with `--json` one JSON object), and writes them to `--report` and a scaling
//! plot to `--plot`; `--export-rays` writes the traced triangles, rays and hits as NumPy arrays.

use super::{interrupt_flag, load, load_options, worker_pool, Interrupted, QUIT_ON_SECOND_PRESS};
use crate::cli::BenchArgs;
use anyhow::{bail, Context, Result};
use meshtracer::render::RenderSettings;
use meshtracer::scene::Scene;
use meshtracer::tools::bench::{
    generated_mesh, markdown_table, measure, median_f64, scene_from_soup, BenchOptions, PathRow,
    Row,
};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

/// `meshtracer bench`.
pub(super) fn bench_command(args: &BenchArgs) -> Result<()> {
    check_bench_options(args)?;
    let (threads, pool) = worker_pool(args.threads)?;
    let options = BenchOptions {
        kind: args.rays[0],
        side: args.side,
        runs: args.runs,
        linear_budget: args.linear_budget,
        preset: args.bvh_preset,
        packets: args.packets,
    };
    // Ctrl-C once: finish the measurement under way, then report what is done (exit 130).
    // Twice: quit at once, writing nothing (a 1M-triangle linear scan can take a minute).
    let _ = QUIT_ON_SECOND_PRESS
        .set("stopping after the current measurement (Ctrl-C again to quit now)");
    let stop = interrupt_flag();
    let jobs = bench_jobs(args);
    let mut measured = Measured::default();
    for (i, job) in jobs.iter().enumerate() {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        if !args.quiet {
            note!(
                "[{}/{}] {}: building and tracing...",
                i + 1,
                jobs.len(),
                job.name
            );
        }
        measure_job(args, &options, &pool, job, &stop, &mut measured)?;
    }
    let table = measured.table();
    let wanted = jobs.len() * args.rays.len();
    let partial = (measured.rows.len() < wanted).then(|| {
        format!(
            "stopped early: {} of {wanted} measurements",
            measured.rows.len(),
        )
    });
    let settings = settings_line(args, &options, threads, partial.as_deref());
    if args.json {
        let json = bench_json(args, &options, threads, partial.as_deref(), &measured);
        out!("{}", serde_json::to_string_pretty(&json)?);
    } else {
        out!("{table}");
        out!("{settings}");
    }
    write_report_and_plot(args, &settings, &table, &measured)?;
    match partial {
        Some(p) => Err(Interrupted(format!("{p} reported")).into()),
        None => Ok(()),
    }
}

/// Refuses, in this order and before any measurement: a `--report` or `--plot` that is a
/// folder, a `--plot` not named `.svg` or of several ray kinds, `--side` outside 1..=8192,
/// `--path-spp` over 4096, nothing to measure, an `--export-rays` with other than one model
/// and no generated sizes, and a `--sizes` entry outside 8..=`--max-triangles`.
fn check_bench_options(args: &BenchArgs) -> Result<()> {
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
        if args.rays.len() != 1 {
            bail!("--plot draws one ray kind: give --rays one kind");
        }
    }
    if args.runs == 0 {
        bail!("--runs 0: at least one timed run is needed (the median of the runs is reported)");
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
    if args.export_rays.is_some() && (args.models.len() != 1 || !args.sizes.is_empty()) {
        bail!("--export-rays writes one scene's rays: name one model, with --sizes=");
    }
    if let Some(&n) = args
        .sizes
        .iter()
        .find(|&&n| n < 8 || n as u64 > args.load.max_triangles)
    {
        bail!("--sizes: {n} is outside 8..={}", args.load.max_triangles);
    }
    Ok(())
}

/// One measurement: a generated mesh or a model file, and its name in the table.
struct BenchJob<'a> {
    name: String,
    source: BenchSource<'a>,
}

/// What a [`BenchJob`] measures.
enum BenchSource<'a> {
    /// A generated mesh of this many triangles.
    Generated(usize),
    /// A model file.
    Model(&'a Path),
}

/// The measurements in the order made: the generated sizes, then the models (named by their
/// file name).
fn bench_jobs(args: &BenchArgs) -> Vec<BenchJob<'_>> {
    args.sizes
        .iter()
        .map(|&n| BenchJob {
            name: format!("generated {n}"),
            source: BenchSource::Generated(n),
        })
        .chain(args.models.iter().map(|p| {
            let name = p.file_name().map_or_else(
                || p.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            );
            BenchJob {
                name,
                source: BenchSource::Model(p),
            }
        }))
        .collect()
}

/// The rows measured so far.
#[derive(Default)]
struct Measured {
    /// Every BVH row, in the order measured.
    rows: Vec<Row>,
    /// The path tracer's rows (`--path-spp`).
    path_rows: Vec<PathRow>,
    /// The generated meshes' rows (the plot's lines).
    generated: Vec<Row>,
    /// The models' rows (the plot's markers).
    models: Vec<Row>,
}

impl Measured {
    /// The Markdown table of the rows, followed by the path tracer's table when measured.
    fn table(&self) -> String {
        let mut table = markdown_table(&self.rows);
        if !self.path_rows.is_empty() {
            table.push('\n');
            table.push_str(&meshtracer::tools::bench::path_table(&self.path_rows));
        }
        table
    }
}

/// Measures `job` on `pool`: builds or loads its scene, measures the BVH (and the linear scan)
/// and prints the row unless `--quiet`, then with `--path-spp`, unless Ctrl-C (`stop`) came
/// meanwhile, the path tracer against the BVH. The rows go into `measured`.
fn measure_job(
    args: &BenchArgs,
    options: &BenchOptions,
    pool: &rayon::ThreadPool,
    job: &BenchJob,
    stop: &AtomicBool,
    measured: &mut Measured,
) -> Result<()> {
    let name = &job.name;
    let mut scene = match job.source {
        BenchSource::Generated(n) => scene_from_soup(generated_mesh(n, 1), name),
        BenchSource::Model(p) => load(p, &load_options(&args.load))?,
    };
    if args.double_sided {
        for material in &mut scene.materials {
            material.double_sided = true;
        }
    }
    if let Some(dir) = &args.export_rays {
        let files = pool.install(|| {
            meshtracer::tools::bench::export_rays(
                &scene,
                &args.rays,
                args.side,
                args.bvh_preset,
                dir,
            )
        })?;
        if !args.quiet {
            note!("      wrote {} arrays to {}", files.len(), dir.display());
        }
    }
    for (i, &kind) in args.rays.iter().enumerate() {
        if i > 0 && stop.load(Ordering::SeqCst) {
            return Ok(());
        }
        let options = BenchOptions { kind, ..*options };
        let row = pool.install(|| measure(&scene, name, &options))?;
        if !args.quiet {
            note!(
                "      {} triangles, {} rays: build {:.1} ms, BVH {:.2} Mrays/s{}",
                row.triangles,
                kind.name(),
                row.build.as_secs_f64() * 1e3,
                row.bvh_mrays,
                row.linear_mrays
                    .map_or(String::new(), |l| format!(", linear {l:.4} Mrays/s"))
            );
        }
        match job.source {
            BenchSource::Generated(_) => measured.generated.push(row.clone()),
            BenchSource::Model(_) => measured.models.push(row.clone()),
        }
        measured.rows.push(row);
    }
    if args.path_spp > 0 && !stop.load(Ordering::SeqCst) {
        if !args.quiet {
            note!(
                "      path tracer against the BVH, {} alternating rounds...",
                options.runs
            );
        }
        let settings = bench_path_settings(&scene, args.path_size, args.path_spp);
        let row = pool.install(|| measure_path(args, options, scene, &settings, name))?;
        measured.path_rows.push(row);
    }
    Ok(())
}

/// Runs on the worker pool: prepares `scene` (its textures decoded, their warnings printed
/// unless `--quiet`) and measures the path tracer rendering `settings` against the BVH alone.
fn measure_path(
    args: &BenchArgs,
    options: &BenchOptions,
    scene: Scene,
    settings: &RenderSettings,
    name: &str,
) -> Result<PathRow> {
    let prepare = meshtracer::prepare::PrepareOptions {
        bvh_preset: args.bvh_preset,
        ..Default::default()
    };
    let mut warnings = Vec::new();
    let prepared = meshtracer::prepare::Prepared::new(scene, &prepare, &mut warnings)
        .with_context(|| format!("{name}: textures"))?;
    if !args.quiet {
        for w in &warnings {
            note!("warning: {name}: {w}");
        }
    }
    Ok(meshtracer::tools::bench::path_versus_bvh(
        &prepared,
        settings,
        name,
        args.side,
        options.runs,
    )?)
}

/// What `bench --path-spp` renders: `scene`'s default render at `size` (the path tracer, lit
/// by the file's lights, else the built-in studio environment) with exactly `spp` samples per
/// pixel: no adaptive stop, so every run does the same work.
fn bench_path_settings(scene: &Scene, (width, height): (u32, u32), spp: u32) -> RenderSettings {
    let mut settings = meshtracer::setup::default_settings(scene, width, height);
    settings.spp = spp;
    settings.noise = None;
    settings
}

/// The line under the table: what was measured and how (ray kind, rays per run, runs,
/// one or eight at a time, threads, BVH preset, linear budget), the CPU, and `partial` when Ctrl-C stopped it early.
fn settings_line(
    args: &BenchArgs,
    options: &BenchOptions,
    threads: usize,
    partial: Option<&str>,
) -> String {
    format!(
        "{} rays ({} primary rays per run, shadow/diffuse rays from their hits, {}), median of {} runs, {}, obvhs preset {:?}, linear scan budget {} triangle tests{}; CPU: {}{}",
        kind_names(args).join(", "),
        u64::from(args.side) * u64::from(args.side),
        if args.packets {
            "eight at a time"
        } else {
            "one at a time"
        },
        options.runs,
        super::threads_label(threads),
        args.bvh_preset,
        args.linear_budget,
        if args.double_sided {
            ", every triangle double-sided"
        } else {
            ""
        },
        cpu_name(),
        partial.map_or(String::new(), |p| format!("; {p}"))
    )
}

/// Writes `--report` (the settings and the table as Markdown) and `--plot` (time per ray
/// against triangles, as SVG), in this order.
fn write_report_and_plot(
    args: &BenchArgs,
    settings: &str,
    table: &str,
    measured: &Measured,
) -> Result<()> {
    if let Some(path) = &args.report {
        let report = format!("# meshtracer bench\n\n{settings}\n\n{table}");
        meshtracer::output::write_atomic(path, report.as_bytes())?;
    }
    if let Some(path) = &args.plot {
        let title = format!("time per {} ray vs triangles", kind_names(args).join(", "));
        let svg =
            meshtracer::tools::plot::scaling_plot(&measured.generated, &measured.models, &title)?;
        meshtracer::output::write_atomic(path, svg.as_bytes())?;
    }
    Ok(())
}

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

/// The names of the `--rays` kinds, in the order given.
fn kind_names(args: &BenchArgs) -> Vec<&'static str> {
    args.rays.iter().map(|k| k.name()).collect()
}

/// `--json`: the settings, one row per scene and ray kind (throughput over all threads and
/// per thread, each timed run's), and the path tracer's rows (samples per second, all threads
/// and per thread, each round's).
fn bench_json(
    args: &BenchArgs,
    options: &BenchOptions,
    threads: usize,
    partial: Option<&str>,
    measured: &Measured,
) -> serde_json::Value {
    let rows: Vec<serde_json::Value> = measured
        .rows
        .iter()
        .map(|r| {
            serde_json::json!({
                "scene": r.name,
                "rays": r.kind.name(),
                "triangles": r.triangles,
                "traced": r.rays,
                "threads": r.threads,
                "build_ms": r.build.as_secs_f64() * 1e3,
                "mrays_per_second": r.bvh_mrays,
                "mrays_per_second_per_thread": r.bvh_mrays / r.threads.max(1) as f64,
                "run_mrays_per_second": r.bvh_run_mrays,
                "linear_mrays_per_second": r.linear_mrays,
                "soup_bytes": r.soup_bytes,
                "bvh_bytes": r.accel_bytes,
            })
        })
        .collect();
    let path: Vec<serde_json::Value> = measured
        .path_rows
        .iter()
        .map(|r| {
            let samples = median_f64(&r.samples_per_second);
            serde_json::json!({
                "scene": r.name,
                "width": r.render.0,
                "height": r.render.1,
                "spp": r.render.2,
                "threads": r.threads,
                "samples_per_second": samples,
                "samples_per_second_per_thread": samples / r.threads.max(1) as f64,
                "run_samples_per_second": r.samples_per_second,
                "path_mrays_per_second": median_f64(&r.path_mrays),
                "bvh_diffuse_mrays_per_second": median_f64(&r.bvh_mrays),
            })
        })
        .collect();
    serde_json::json!({
        "settings": {
            "rays": kind_names(args),
            "side": args.side,
            "runs": options.runs,
            "threads": threads,
            "bvh_preset": format!("{:?}", args.bvh_preset),
            "packets": args.packets,
            "double_sided": args.double_sided,
            "cpu": cpu_name(),
            "partial": partial,
        },
        "rows": rows,
        "path": path,
    })
}
