//! `meshtracer bench`: build time and ray throughput of the BVH (and of the linear scan) on
//! generated meshes and models, and with `--path-spp` the path tracer against the BVH alone;
//! the measurements are in [`meshtracer::tools::bench`]. Prints a Markdown table and the
//! settings, and writes them to `--report` and a scaling plot to `--plot`.

use super::{interrupt_flag, load, load_options, worker_pool, Interrupted, QUIT_ON_SECOND_PRESS};
use anyhow::{bail, Context, Result};
use meshtracer::render::RenderSettings;
use meshtracer::setup::{lighting, LightingOptions};
use std::sync::atomic::Ordering;

pub(super) fn bench_command(args: &crate::cli::BenchArgs) -> Result<()> {
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
