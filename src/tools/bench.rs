//! Benchmark workloads shared by `meshtracer bench` and the criterion benches: seeded generated
//! meshes, ray sets of three coherences, and timed query loops that check their own results.
//!
//! - **Generated meshes**: a unit sphere of `rings × 2·rings` quads split into triangles, its
//!   radius modulated by `1 + 0.05·sin(7θ + a)·sin(9φ + b)` (a, b from the seed) so that no two
//!   triangles are coplanar. `rings` is chosen so the count is within 1% of the request.
//! - **Primary rays**: one per pixel of a square image from the automatic camera, in scanline
//!   order (coherent). **Shadow rays**: from each primary hit toward a point light above and in
//!   front of the scene (any-hit queries, coherent-ish). **Diffuse rays**: from each primary hit
//!   in a cosine-distributed random direction about the normal (closest-hit, incoherent).
//! - **Export** ([`export_rays`]): the triangles, the rays of each kind and the BVH's answers as
//!   `.npy` arrays, so that another ray tracer (`scripts/bench/peers.py` runs Intel Embree) can
//!   trace exactly the same work and be checked ray for ray.

use crate::accel::{Accel, AccelKind, BvhPreset};
use crate::camera::{auto_camera, View};
use crate::geometry::Ray;
use crate::sampling::Rng;
use crate::scene::{Material, Scene, SoupBuilder, TriangleIn, TriangleSoup};
use glam::Vec3;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Ray coherence of a workload.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RayKind {
    /// Camera rays in scanline order; closest hit.
    Primary,
    /// From primary hits toward a light; any hit.
    Shadow,
    /// From primary hits in random cosine-weighted directions; closest hit.
    Diffuse,
}

impl RayKind {
    /// Every kind, in the order the tables list them.
    pub const ALL: [RayKind; 3] = [RayKind::Primary, RayKind::Shadow, RayKind::Diffuse];

    /// The kind's name on the command line, in JSON and in exported file names.
    pub fn name(self) -> &'static str {
        match self {
            RayKind::Primary => "primary",
            RayKind::Shadow => "shadow",
            RayKind::Diffuse => "diffuse",
        }
    }
}

/// A seeded bumpy sphere with about `triangles` triangles (see the module docs).
pub fn generated_mesh(triangles: usize, seed: u64) -> TriangleSoup {
    let rings = ((triangles as f64 / 4.0).sqrt().round() as u32).max(2);
    let segments = 2 * rings;
    let mut rng = Rng::new(seed);
    let (a, b) = (
        rng.next_f32() * std::f32::consts::TAU,
        rng.next_f32() * std::f32::consts::TAU,
    );
    let point = |i: u32, j: u32| {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        let phi = std::f32::consts::TAU * j as f32 / segments as f32;
        let r = 1.0 + 0.05 * (7.0 * theta + a).sin() * (9.0 * phi + b).sin();
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            theta.sin() * phi.sin(),
        ) * r
    };
    let mut builder = SoupBuilder::new(u64::MAX);
    for i in 0..rings {
        for j in 0..segments {
            let (p00, p10, p11, p01) = (
                point(i, j),
                point(i + 1, j),
                point(i + 1, j + 1),
                point(i, j + 1),
            );
            for positions in [[p00, p01, p11], [p00, p11, p10]] {
                builder.push(
                    &TriangleIn {
                        positions,
                        ..Default::default()
                    },
                    0,
                    0,
                );
            }
        }
    }
    builder.finish().0
}

/// A scene around a soup, with one double-sided grey material (so nothing is culled and the
/// BVH and linear scan do the same work).
pub fn scene_from_soup(soup: TriangleSoup, name: &str) -> Scene {
    let mut bounds = crate::scene::Bounds::EMPTY;
    for p in &soup.positions {
        bounds.grow(*p);
    }
    Scene {
        source: name.into(),
        format: crate::scene::Format::Gltf,
        file_triangles: soup.len(),
        soup,
        materials: vec![Material {
            double_sided: true,
            metallic: 0.0,
            ..Material::default()
        }],
        textures: Vec::new(),
        images: Vec::new(),
        cameras: Vec::new(),
        lights: Vec::new(),
        instances: Vec::new(),
        mesh_count: 1,
        primitive_count: 1,
        variants: Vec::new(),
        variant: None,
        extensions: Vec::new(),
        animations: Vec::new(),
        pose: None,
        bounds,
        warnings: Vec::new(),
        load_steps: Vec::new(),
        archive: None,
        inputs: Vec::new(),
    }
}

/// Builds rays of `kind` for `scene`: `side × side` primary rays, and for shadow and diffuse
/// rays one per primary hit. `reference` answers the primary queries.
pub fn make_rays(
    scene: &Scene,
    reference: &Accel,
    kind: RayKind,
    side: u32,
    seed: u64,
) -> Vec<Ray> {
    let camera = auto_camera(&scene.bounds, &scene.soup.positions, 1.0);
    let view = View::from_camera(&camera, side, side);
    let primary: Vec<Ray> = (0..side)
        .flat_map(|y| (0..side).map(move |x| (x, y)))
        .map(|(x, y)| view.ray(x as f32 + 0.5, y as f32 + 0.5))
        .collect();
    if kind == RayKind::Primary {
        return primary;
    }
    let offset = scene.bounds.radius() * 1e-4;
    let light = scene.bounds.center() + Vec3::new(0.3, 1.0, 0.8) * scene.bounds.radius() * 3.0;
    let mut rng = Rng::new(seed);
    primary
        .iter()
        .filter_map(|ray| reference.intersect(ray).map(|hit| (ray, hit)))
        .map(|(ray, hit)| {
            let [a, b, c] = scene.soup.triangle(hit.triangle as usize);
            let mut n = (b - a).cross(c - a).normalize();
            if n.dot(Vec3::from(ray.direction)) > 0.0 {
                n = -n;
            }
            let origin = ray.at(hit.t) + n * offset;
            match kind {
                RayKind::Shadow => {
                    let to_light = light - origin;
                    let distance = to_light.length();
                    Ray::new(origin, to_light / distance, 0.0, distance)
                }
                _ => {
                    // Cosine-weighted hemisphere about n (Malley's method).
                    let (u1, u2) = (rng.next_f32(), rng.next_f32());
                    let r = u1.sqrt();
                    let phi = std::f32::consts::TAU * u2;
                    let (t, bt) = n.any_orthonormal_pair();
                    let dir =
                        t * (r * phi.cos()) + bt * (r * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt();
                    Ray::new(origin, dir.normalize(), 0.0, f32::INFINITY)
                }
            }
        })
        .collect()
}

/// The answer a ray set must give, to check a timed run against: hits and the sum of hit
/// triangle indices (closest-hit kinds), or the number of blocked rays (shadow).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Checksum {
    /// Rays that hit (or are blocked).
    pub hits: u64,
    /// Sum of the indices of the triangles hit (0 for shadow rays).
    pub triangle_sum: u64,
}

/// Runs every ray of `rays` through `accel` once on the current rayon pool.
pub fn trace(accel: &Accel, rays: &[Ray], kind: RayKind) -> Checksum {
    in_chunks(rays, |rays| {
        if kind == RayKind::Shadow {
            Checksum::of_blocked(rays.iter().map(|ray| accel.occluded(ray)))
        } else {
            Checksum::of_hits(rays.iter().filter_map(|ray| accel.intersect(ray)))
        }
    })
}

/// [`trace`] with the BVH's packet queries: the rays eight consecutive ones at a time through
/// [`Accel::intersect_many`] or [`Accel::occluded_many`]. The same answers.
pub fn trace_packets(accel: &Accel, rays: &[Ray], kind: RayKind) -> Checksum {
    in_chunks(rays, |rays| {
        if kind == RayKind::Shadow {
            let mut blocked = vec![false; rays.len()];
            accel.occluded_many(rays, None, &mut blocked);
            Checksum::of_blocked(blocked.into_iter())
        } else {
            let mut hits = vec![None; rays.len()];
            accel.intersect_many(rays, None, &mut hits);
            Checksum::of_hits(hits.into_iter().flatten())
        }
    })
}

/// `chunk` over chunks of `rays` on the current rayon pool, the checksums added.
fn in_chunks(rays: &[Ray], chunk: impl Fn(&[Ray]) -> Checksum + Sync + Send) -> Checksum {
    rays.par_chunks(4096)
        .map(chunk)
        .reduce(Checksum::default, |a, b| Checksum {
            hits: a.hits + b.hits,
            triangle_sum: a.triangle_sum + b.triangle_sum,
        })
}

impl Checksum {
    /// The checksum of closest hits.
    fn of_hits(hits: impl Iterator<Item = crate::accel::Hit>) -> Checksum {
        hits.fold(Checksum::default(), |c, hit| Checksum {
            hits: c.hits + 1,
            triangle_sum: c.triangle_sum + u64::from(hit.triangle),
        })
    }

    /// The checksum of shadow rays' answers.
    fn of_blocked(blocked: impl Iterator<Item = bool>) -> Checksum {
        Checksum {
            hits: blocked.filter(|&b| b).count() as u64,
            triangle_sum: 0,
        }
    }
}

/// One row of the benchmark table.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Model name or `generated N`.
    pub name: String,
    /// The rays traced.
    pub kind: RayKind,
    /// Triangles traced.
    pub triangles: usize,
    /// BVH build time (median of the runs).
    pub build: Duration,
    /// BVH throughput, million rays per second over all threads (median of the runs).
    pub bvh_mrays: f64,
    /// BVH throughput of each timed run, in the order run.
    pub bvh_run_mrays: Vec<f64>,
    /// Linear-scan throughput, if measured.
    pub linear_mrays: Option<f64>,
    /// Rays traced per BVH run.
    pub rays: usize,
    /// Threads used.
    pub threads: usize,
    /// The steps of the median build, with their times.
    pub build_steps: Vec<(&'static str, Duration)>,
    /// Heap bytes of the triangle soup (vertices, indices, materials).
    pub soup_bytes: usize,
    /// Heap bytes of the acceleration structure (nodes and the triangles' test data).
    pub accel_bytes: usize,
}

impl Row {
    /// BVH nanoseconds per ray per thread.
    pub fn bvh_ns_per_ray(&self) -> f64 {
        1e3 / self.bvh_mrays * self.threads as f64
    }

    /// Linear nanoseconds per ray per thread.
    pub fn linear_ns_per_ray(&self) -> Option<f64> {
        self.linear_mrays.map(|m| 1e3 / m * self.threads as f64)
    }

    /// BVH speed-up over the linear scan.
    pub fn speedup(&self) -> Option<f64> {
        self.linear_mrays.map(|l| self.bvh_mrays / l)
    }
}

/// Options of one measurement.
#[derive(Clone, Copy, Debug)]
pub struct BenchOptions {
    /// Ray coherence.
    pub kind: RayKind,
    /// Primary rays per axis (side² rays).
    pub side: u32,
    /// Timed repetitions; the median is reported.
    pub runs: usize,
    /// Triangle tests the linear scan may spend per measurement; it traces a subset of the rays
    /// so that O(n) per ray still finishes (0 disables the linear scan).
    pub linear_budget: u64,
    /// BVH build preset.
    pub preset: BvhPreset,
    /// Trace eight rays at a time ([`trace_packets`]) instead of one at a time.
    pub packets: bool,
}

impl Default for BenchOptions {
    fn default() -> Self {
        Self {
            kind: RayKind::Primary,
            side: 512,
            runs: 3,
            linear_budget: 2_000_000_000,
            preset: BvhPreset::Medium,
            packets: false,
        }
    }
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

/// Why a measurement could not be trusted: on scene `.0`, the two answers named by `.1`
/// differ (`.2` against `.3`).
#[derive(Debug, thiserror::Error)]
#[error("{0}: {1} disagree ({2:?} vs {3:?}): a bug")]
pub struct Mismatch(String, &'static str, Checksum, Checksum);

/// What a timed run is checked against, for [`Mismatch`].
fn timed_against(packets: bool) -> &'static str {
    if packets {
        "eight rays at a time and one at a time"
    } else {
        "a timed run and the first"
    }
}

/// Measures build time and BVH (and linear) throughput on `scene`. The BVH is built outside
/// the timed traversal, every run is checked against the first, and the linear scan's answers
/// on its subset of rays must equal the BVH's.
pub fn measure(scene: &Scene, name: &str, options: &BenchOptions) -> Result<Row, Mismatch> {
    let threads = rayon::current_num_threads();
    let mut builds = Vec::new();
    let mut accel = None;
    for _ in 0..options.runs.max(1) {
        let start = Instant::now();
        let built = Accel::build(
            &scene.soup,
            &scene.materials,
            AccelKind::Bvh,
            options.preset,
        );
        let time = start.elapsed();
        let steps: Vec<(&'static str, Duration)> = built
            .build_steps()
            .iter()
            .map(|s| (s.name, s.time))
            .collect();
        builds.push((time, steps));
        accel = Some(built);
    }
    let Some(bvh) = accel else {
        unreachable!("runs >= 1")
    };
    builds.sort_by_key(|(time, _)| *time);
    let (build, build_steps) = builds.swap_remove(builds.len() / 2);
    let rays = make_rays(scene, &bvh, options.kind, options.side, 7);
    let timed = |accel: &Accel, rays: &[Ray]| {
        if options.packets {
            trace_packets(accel, rays, options.kind)
        } else {
            trace(accel, rays, options.kind)
        }
    };
    // Warm-up run, which is also the reference answer (one ray at a time, which packets must
    // match).
    let expected = trace(&bvh, &rays, options.kind);
    let mut times = Vec::new();
    for _ in 0..options.runs.max(1) {
        let start = Instant::now();
        let got = timed(&bvh, &rays);
        times.push(start.elapsed());
        if got != expected {
            let what = timed_against(options.packets);
            return Err(Mismatch(name.into(), what, got, expected));
        }
    }
    let bvh_run_mrays = times
        .iter()
        .map(|t| rays.len() as f64 / t.as_secs_f64().max(1e-9) / 1e6)
        .collect();
    let bvh_time = median(times);
    let linear_rays = (options.linear_budget / scene.soup.len().max(1) as u64) as usize;
    let linear_mrays = (linear_rays >= 64).then(|| {
        let subset = &rays[..linear_rays.min(rays.len())];
        let linear = Accel::build(
            &scene.soup,
            &scene.materials,
            AccelKind::Linear,
            options.preset,
        );
        let start = Instant::now();
        let got = trace(&linear, subset, options.kind);
        let time = start.elapsed();
        let want = timed(&bvh, subset);
        (got, want, subset.len() as f64 / time.as_secs_f64() / 1e6)
    });
    if let Some((got, want, _)) = linear_mrays {
        if got != want {
            return Err(Mismatch(
                name.into(),
                "the BVH and the linear scan",
                got,
                want,
            ));
        }
    }
    Ok(Row {
        name: name.into(),
        kind: options.kind,
        triangles: scene.soup.len(),
        build,
        build_steps,
        soup_bytes: scene.soup.heap_bytes(),
        accel_bytes: bvh.heap_bytes(),
        bvh_mrays: rays.len() as f64 / bvh_time.as_secs_f64().max(1e-9) / 1e6,
        bvh_run_mrays,
        linear_mrays: linear_mrays.map(|(_, _, m)| m),
        rays: rays.len(),
        threads,
    })
}

/// The build steps of all rows, in the order they ran, as table columns (presets with spatial
/// splits have steps of their own, and big models pair triangles first): a step first seen in
/// a later row goes in after the step it followed there.
fn step_columns<'a>(
    rows: impl Iterator<Item = &'a [(&'static str, Duration)]>,
) -> Vec<&'static str> {
    let mut steps: Vec<&'static str> = Vec::new();
    for row in rows {
        let mut after = None;
        for &(name, _) in row {
            let at = match steps.iter().position(|&s| s == name) {
                Some(at) => at,
                None => {
                    let at = after.map_or(0, |i: usize| i + 1);
                    steps.insert(at, name);
                    at
                }
            };
            after = Some(at);
        }
    }
    steps
}

/// The tables as Markdown: throughput and memory, then the build's steps.
pub fn markdown_table(rows: &[Row]) -> String {
    let mut out = String::from(
        "| scene | rays | triangles | build ms | BVH Mrays/s | BVH Mrays/s/thread | linear Mrays/s | speedup | BVH ns/ray/thread | linear ns/ray/thread | soup MB | BVH MB |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        let opt =
            |v: Option<f64>, digits: usize| v.map_or("-".to_string(), |v| format!("{v:.digits$}"));
        out.push_str(&format!(
            "| {} | {} | {} | {:.1} | {:.2} | {:.2} | {} | {} | {:.0} | {} | {:.1} | {:.1} |\n",
            r.name,
            r.kind.name(),
            r.triangles,
            r.build.as_secs_f64() * 1e3,
            r.bvh_mrays,
            r.bvh_mrays / r.threads.max(1) as f64,
            opt(r.linear_mrays, 4),
            opt(r.speedup(), 0),
            r.bvh_ns_per_ray(),
            opt(r.linear_ns_per_ray(), 0),
            r.soup_bytes as f64 / 1e6,
            r.accel_bytes as f64 / 1e6,
        ));
    }
    let steps = step_columns(rows.iter().map(|r| r.build_steps.as_slice()));
    if !steps.is_empty() {
        out.push_str(&format!(
            "\n| build steps, ms | {} |\n|---|{}\n",
            steps.join(" | "),
            "---:|".repeat(steps.len())
        ));
        for r in rows {
            let cells: Vec<String> = steps
                .iter()
                .map(|step| {
                    r.build_steps
                        .iter()
                        .find(|(name, _)| name == step)
                        .map_or("-".into(), |(_, t)| format!("{:.1}", t.as_secs_f64() * 1e3))
                })
                .collect();
            // Each ray kind built its own BVH: a row each, named by the kind too.
            out.push_str(&format!(
                "| {}, {} | {} |\n",
                r.name,
                r.kind.name(),
                cells.join(" | ")
            ));
        }
    }
    out
}

/// The path tracer against the BVH alone on one prepared scene: [`path_versus_bvh`]'s result.
#[derive(Clone, Debug, PartialEq)]
pub struct PathRow {
    /// Model name.
    pub name: String,
    /// The render measured: width, height, samples per pixel.
    pub render: (u32, u32, u32),
    /// The path tracer's rays (camera, shadow and bounce) per second, in millions, each round.
    pub path_mrays: Vec<f64>,
    /// The BVH's closest hits of diffuse rays per second, in millions, each round.
    pub bvh_mrays: Vec<f64>,
    /// The path tracer's samples (camera paths) per second, each round.
    pub samples_per_second: Vec<f64>,
    /// Threads used.
    pub threads: usize,
}

impl PathRow {
    /// The path tracer's throughput over the BVH's, each round (none for rounds where the
    /// BVH traced nothing: a scene no camera ray hits has no diffuse rays).
    pub fn ratios(&self) -> Vec<f64> {
        self.path_mrays
            .iter()
            .zip(&self.bvh_mrays)
            .filter(|(_, b)| **b > 0.0)
            .map(|(p, b)| p / b)
            .collect()
    }
}

/// The median of `v` (the upper one of an even count); 0 for none.
pub fn median_f64(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// Measures the path tracer's rays per second (`settings`, which should name the path
/// integrator) and the BVH's own throughput on diffuse rays (`side`² camera rays, a
/// cosine-distributed bounce from each hit, as [`RayKind::Diffuse`]) in the same structure,
/// alternating the two `runs` times: a host whose speed drifts (other work, clock changes)
/// then slows both alike, so the ratio of each round is steadier than that of two separate
/// measurements. Every BVH run is checked against the first.
pub fn path_versus_bvh(
    scene: &crate::prepare::Prepared,
    settings: &crate::render::RenderSettings,
    name: &str,
    side: u32,
    runs: usize,
) -> Result<PathRow, Mismatch> {
    let rays = make_rays(&scene.scene, &scene.accel, RayKind::Diffuse, side, 7);
    let expected = trace(&scene.accel, &rays, RayKind::Diffuse);
    let cancel = std::sync::atomic::AtomicBool::new(false);
    let (mut path_mrays, mut bvh_mrays, mut samples_per_second) =
        (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..runs.max(1) {
        let start = Instant::now();
        let got = trace(&scene.accel, &rays, RayKind::Diffuse);
        let time = start.elapsed().as_secs_f64();
        if got != expected {
            let what = timed_against(false);
            return Err(Mismatch(name.into(), what, got, expected));
        }
        bvh_mrays.push(rays.len() as f64 / time.max(1e-9) / 1e6);
        // Never cancelled: the flag is only read.
        let stats = match crate::render::render(scene, settings, &cancel, &|_, _| {}) {
            Ok((_, stats, _)) => stats,
            Err(_) => unreachable!("the flag is never set"),
        };
        path_mrays.push(stats.rays() as f64 / stats.time.as_secs_f64().max(1e-9) / 1e6);
        samples_per_second.push(stats.samples_per_second());
    }
    Ok(PathRow {
        name: name.into(),
        render: (
            settings.view.width,
            settings.view.height,
            settings.spp.max(1),
        ),
        path_mrays,
        bvh_mrays,
        samples_per_second,
        threads: rayon::current_num_threads(),
    })
}

/// [`PathRow`]s as a Markdown table: medians, and the range of the rounds' ratios.
pub fn path_table(rows: &[PathRow]) -> String {
    let mut out = String::from(
        "| scene | render | path tracer Mrays/s | samples/s/thread | BVH alone, diffuse, Mrays/s | ratio (median of rounds) | ratio range |\n|---|---|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        let ratios = r.ratios();
        let (lo, hi) = ratios.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        });
        let (w, h, spp) = r.render;
        let (ratio, range) = if ratios.is_empty() {
            ("-".to_string(), "-".to_string())
        } else {
            (
                format!("{:.0}%", 100.0 * median_f64(&ratios)),
                format!("{:.0}-{:.0}%", 100.0 * lo, 100.0 * hi),
            )
        };
        out.push_str(&format!(
            "| {} | {w}x{h}, {spp} spp | {:.2} | {:.0} | {:.2} | {ratio} | {range} |\n",
            r.name,
            median_f64(&r.path_mrays),
            median_f64(&r.samples_per_second) / r.threads.max(1) as f64,
            median_f64(&r.bvh_mrays),
        ));
    }
    out
}

/// An exported triangle index that means "no hit" (NumPy `<u4`).
pub const NO_TRIANGLE: u32 = u32::MAX;

/// A ray as one exported row: origin x, y, z, direction x, y, z, tmin, tmax.
pub fn ray_row(ray: &Ray) -> [f32; 8] {
    let (o, d) = (ray.origin, ray.direction);
    [o.x, o.y, o.z, d.x, d.y, d.z, ray.tmin, ray.tmax]
}

/// What `accel` answers for each ray of `kind`: closest-hit kinds give the soup triangle and
/// the hit parameter ([`NO_TRIANGLE`] and `f32::INFINITY` for a miss); shadow rays give 1
/// when blocked, else 0, and no parameter (`f32::INFINITY`): an any-hit query names no
/// particular triangle.
pub fn expected_hits(accel: &Accel, rays: &[Ray], kind: RayKind) -> Vec<(u32, f32)> {
    rays.par_iter()
        .map(|ray| match kind {
            RayKind::Shadow => (u32::from(accel.occluded(ray)), f32::INFINITY),
            _ => accel
                .intersect(ray)
                .map_or((NO_TRIANGLE, f32::INFINITY), |hit| (hit.triangle, hit.t)),
        })
        .collect()
}

/// Little-endian bytes of `values`, for a `.npy` file.
fn le_bytes<T: Copy, const N: usize>(
    values: impl Iterator<Item = T>,
    to: fn(T) -> [u8; N],
) -> Vec<u8> {
    values.flat_map(to).collect()
}

/// Writes what [`measure`] traces on `scene` for each of `kinds` (the same BVH preset, `side`
/// and seed) into the folder `dir`, created if missing, as NumPy arrays:
///
/// - `triangles.npy`: `<f4`, (triangles, 3, 3), each triangle's corners in soup order (world
///   space), so row `i` is the triangle the hit files call `i`;
/// - `triangle_materials.npy`: `<u4`, (triangles,), each triangle's material index;
/// - `KIND.npy` (`primary`, `shadow`, `diffuse`): `<f4`, (rays, 8), one [`ray_row`] a ray;
/// - `KIND_triangle.npy` and `KIND_t.npy` for the closest-hit kinds: `<u4` and `<f4`, (rays,),
///   the BVH's closest hit ([`expected_hits`]);
/// - `shadow_occluded.npy`: `<u4`, (rays,), 1 where the BVH finds the shadow ray blocked.
///
/// Returns the files written, in that order.
pub fn export_rays(
    scene: &Scene,
    kinds: &[RayKind],
    side: u32,
    preset: BvhPreset,
    dir: &Path,
) -> Result<Vec<PathBuf>, crate::output::SaveError> {
    use crate::output::npy::encode;
    std::fs::create_dir_all(dir).map_err(|error| crate::output::SaveError::Unwritable {
        path: dir.to_path_buf(),
        error,
    })?;
    let bvh = Accel::build(&scene.soup, &scene.materials, AccelKind::Bvh, preset);
    let n = scene.soup.len();
    let corners = (0..n)
        .flat_map(|t| scene.soup.triangle(t))
        .flat_map(|p| p.to_array());
    let mut files = vec![
        (
            "triangles".to_string(),
            encode("<f4", &[n, 3, 3], &le_bytes(corners, f32::to_le_bytes)),
        ),
        (
            "triangle_materials".to_string(),
            encode(
                "<u4",
                &[n],
                &le_bytes(scene.soup.material.iter().copied(), u32::to_le_bytes),
            ),
        ),
    ];
    for &kind in kinds {
        let rays = make_rays(scene, &bvh, kind, side, 7);
        let rows = rays.iter().flat_map(ray_row);
        let name = kind.name();
        files.push((
            name.to_string(),
            encode("<f4", &[rays.len(), 8], &le_bytes(rows, f32::to_le_bytes)),
        ));
        let hits = expected_hits(&bvh, &rays, kind);
        let triangles = le_bytes(hits.iter().map(|h| h.0), u32::to_le_bytes);
        if kind == RayKind::Shadow {
            files.push((
                format!("{name}_occluded"),
                encode("<u4", &[rays.len()], &triangles),
            ));
        } else {
            files.push((
                format!("{name}_triangle"),
                encode("<u4", &[rays.len()], &triangles),
            ));
            let t = le_bytes(hits.iter().map(|h| h.1), f32::to_le_bytes);
            files.push((format!("{name}_t"), encode("<f4", &[rays.len()], &t)));
        }
    }
    let mut written = Vec::new();
    for (name, bytes) in files {
        let path = dir.join(format!("{name}.npy"));
        crate::output::write_atomic(&path, &bytes)?;
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generated_mesh_has_about_the_requested_size() {
        for n in [1_000, 10_000, 100_000] {
            let soup = generated_mesh(n, 1);
            let err = (soup.len() as f64 - n as f64).abs() / n as f64;
            assert!(err < 0.05, "{n}: {}", soup.len());
        }
        assert_eq!(
            generated_mesh(1000, 3).positions,
            generated_mesh(1000, 3).positions
        );
    }

    #[test]
    fn measurement_checks_bvh_against_linear() {
        let scene = scene_from_soup(generated_mesh(2_000, 1), "test");
        for kind in [RayKind::Primary, RayKind::Shadow, RayKind::Diffuse] {
            for packets in [false, true] {
                let options = BenchOptions {
                    kind,
                    side: 32,
                    runs: 1,
                    packets,
                    ..BenchOptions::default()
                };
                let row = measure(&scene, "test", &options).unwrap();
                assert!(row.rays > 100, "{kind:?}: {}", row.rays);
                assert!(row.linear_mrays.is_some());
            }
        }
    }

    #[test]
    fn the_report_gives_memory_and_build_steps() {
        let scene = scene_from_soup(generated_mesh(2_000, 1), "test");
        let options = BenchOptions {
            side: 16,
            runs: 3,
            linear_budget: 0,
            ..BenchOptions::default()
        };
        let row = measure(&scene, "gen", &options).unwrap();
        let steps: Vec<&str> = row.build_steps.iter().map(|(name, _)| *name).collect();
        assert_eq!(
            steps,
            [
                "bounds",
                "ploc",
                "reinsertion",
                "wide bvh conversion",
                "triangle test data"
            ]
        );
        let sum: Duration = row.build_steps.iter().map(|(_, t)| *t).sum();
        assert!(
            sum <= row.build,
            "the steps are inside the build: {sum:?} vs {:?}",
            row.build
        );
        // 2,000 triangles on 3 own vertices each: 6,000 x (12 + 12) + 2,000 x (12 + 4 + 4).
        assert_eq!(row.soup_bytes, scene.soup.len() * (3 * 24 + 20));
        assert!(
            row.accel_bytes >= scene.soup.len() * 64,
            "{}",
            row.accel_bytes
        );
        let table = markdown_table(&[row]);
        assert!(table.contains("| soup MB | BVH MB |"), "{table}");
        assert!(
            table.contains("| build steps, ms | bounds | ploc |"),
            "{table}"
        );
        assert!(table.contains("\n| gen | "), "{table}");
        assert!(table.contains("\n| gen, primary | "), "{table}");
    }

    #[test]
    fn a_step_of_a_later_row_stands_where_it_ran() {
        let t = Duration::ZERO;
        let small = [("bounds", t), ("ploc", t), ("wide bvh conversion", t)];
        let big = [
            ("bounds", t),
            ("pairs", t),
            ("ploc", t),
            ("wide bvh conversion", t),
        ];
        let split = [("triangles", t), ("split, ploc", t)];
        assert_eq!(
            step_columns([&small[..], &big[..], &split[..]].into_iter()),
            [
                "triangles",
                "split, ploc",
                "bounds",
                "pairs",
                "ploc",
                "wide bvh conversion"
            ]
        );
    }
    /// The path table gives the medians of the rounds and the range of their ratios.
    #[test]
    fn path_table_gives_medians_and_the_ratio_range() {
        let row = PathRow {
            name: "box".into(),
            render: (64, 48, 2),
            path_mrays: vec![4.0, 5.0, 6.0],
            bvh_mrays: vec![10.0, 10.0, 8.0],
            samples_per_second: vec![2000.0, 3000.0, 1000.0],
            threads: 2,
        };
        assert_eq!(row.ratios(), vec![0.4, 0.5, 0.75]);
        let table = path_table(&[row]);
        assert!(
            table.contains("| box | 64x48, 2 spp | 5.00 | 1000 | 10.00 | 50% | 40-75% |"),
            "{table}"
        );
        // Nothing in view: no diffuse rays, so no ratio (not "inf%").
        let empty = PathRow {
            name: "away".into(),
            render: (8, 8, 1),
            path_mrays: vec![1.0],
            bvh_mrays: vec![0.0],
            samples_per_second: vec![64.0],
            threads: 1,
        };
        let table = path_table(&[empty]);
        assert!(
            table.contains("| away | 8x8, 1 spp | 1.00 | 64 | 0.00 | - | - |")
                && !table.contains("inf"),
            "{table}"
        );
    }

    /// The exported arrays read back as the rays that were traced, and the hit files give what
    /// the linear scan (the reference) answers for the rays read back: same triangle, same t.
    #[test]
    fn exported_rays_round_trip_and_their_hits_match_the_reference() {
        use crate::output::npy;
        let scene = scene_from_soup(generated_mesh(2_000, 1), "test");
        let dir = tempfile::tempdir().unwrap();
        let files = export_rays(&scene, &RayKind::ALL, 24, BvhPreset::Medium, dir.path()).unwrap();
        // triangles, materials; primary (rays, triangle, t); shadow (rays, occluded); diffuse.
        assert_eq!(files.len(), 2 + 3 + 2 + 3);
        let bytes = |name: &str| std::fs::read(dir.path().join(format!("{name}.npy"))).unwrap();
        let floats = |data: &[u8]| -> Vec<f32> {
            data.chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect()
        };
        // A 1-D array (which `npy::decode`, made for images, refuses): the header must give
        // its length, and the elements are the file's last 4·len bytes.
        let column = |name: &str, len: usize| -> Vec<u32> {
            let file = bytes(name);
            let header = String::from_utf8_lossy(&file[..64.min(file.len())]).into_owned();
            assert!(file.len() > 4 * len, "{name}");
            let text = String::from_utf8_lossy(&file[..file.len() - 4 * len]).into_owned();
            assert!(
                text.contains(&format!("'shape': ({len},)")),
                "{name}: {header}"
            );
            file[file.len() - 4 * len..]
                .chunks_exact(4)
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect()
        };
        let triangles = npy::decode(&bytes("triangles")).unwrap();
        assert_eq!(triangles.shape, [scene.soup.len(), 3, 3]);
        let corners = floats(&triangles.data);
        for t in [0, 917, scene.soup.len() - 1] {
            let want: Vec<f32> = scene
                .soup
                .triangle(t)
                .iter()
                .flat_map(|p| p.to_array())
                .collect();
            assert_eq!(corners[9 * t..9 * t + 9], want[..], "triangle {t}");
        }
        assert_eq!(
            column("triangle_materials", scene.soup.len()),
            scene.soup.material
        );

        let bvh = Accel::build(
            &scene.soup,
            &scene.materials,
            AccelKind::Bvh,
            BvhPreset::Medium,
        );
        let linear = Accel::build(
            &scene.soup,
            &scene.materials,
            AccelKind::Linear,
            BvhPreset::Medium,
        );
        for kind in RayKind::ALL {
            let array = npy::decode(&bytes(kind.name())).unwrap();
            let rows = floats(&array.data);
            let rays: Vec<Ray> = rows
                .chunks_exact(8)
                .map(|r| {
                    Ray::new(
                        Vec3::new(r[0], r[1], r[2]),
                        Vec3::new(r[3], r[4], r[5]),
                        r[6],
                        r[7],
                    )
                })
                .collect();
            let traced = make_rays(&scene, &bvh, kind, 24, 7);
            assert_eq!(array.shape, [traced.len(), 8], "{kind:?}");
            assert!(traced.len() > 100, "{kind:?}: {}", traced.len());
            assert_eq!(
                rows,
                traced.iter().flat_map(ray_row).collect::<Vec<_>>(),
                "{kind:?}"
            );
            let reference = expected_hits(&linear, &rays, kind);
            let n = rays.len();
            if kind == RayKind::Shadow {
                let occluded = column("shadow_occluded", n);
                assert_eq!(occluded, reference.iter().map(|h| h.0).collect::<Vec<_>>());
                assert!(
                    occluded.contains(&0) && occluded.contains(&1),
                    "{occluded:?}"
                );
            } else {
                let triangle = column(&format!("{}_triangle", kind.name()), n);
                let t: Vec<f32> = column(&format!("{}_t", kind.name()), n)
                    .into_iter()
                    .map(f32::from_bits)
                    .collect();
                let want: (Vec<u32>, Vec<f32>) = reference.into_iter().unzip();
                assert_eq!((triangle, t), want, "{kind:?}");
            }
        }
    }
}
