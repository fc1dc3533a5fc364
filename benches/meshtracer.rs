//! Criterion benchmarks: BVH build, traversal (the BVH one and eight rays at a time vs. the
//! linear scan, three ray coherences), the triangle tests alone, bare obvhs traversal against
//! our query path, an end-to-end render, and
//! the path tracer's rays per second beside the BVH's own on diffuse rays.
//!
//! Every benchmark builds outside the timed region, warms up (criterion's warm-up), and checks
//! its answer while timing: the hit count or checksum of each timed run must equal the one
//! computed beforehand. Traversal runs on a one-thread pool, so the figures are per thread.
//! Real models from `MESHTRACER_SAMPLES` are added when it is set.
//!
//! `cargo bench` runs everything; `cargo bench -- traverse` a group.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::{Vec3, Vec3A};
use meshtracer::accel::{Accel, AccelKind, BvhPreset};
use meshtracer::geometry::{PreparedTriangle, Ray};
use meshtracer::sampling::Rng;
use meshtracer::tools::bench::{
    generated_mesh, make_rays, scene_from_soup, trace, trace_packets, RayKind,
};
use meshtracer::Scene;
use std::hint::black_box;
use std::time::Duration;

fn one_thread() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread pool")
}

/// Generated scenes by size, plus real models when the samples are available.
fn scenes(sizes: &[usize]) -> Vec<(String, Scene)> {
    let mut out: Vec<(String, Scene)> = sizes
        .iter()
        .map(|&n| {
            (
                format!("gen{n}"),
                scene_from_soup(generated_mesh(n, 1), "generated"),
            )
        })
        .collect();
    if let Some(dir) = std::env::var_os("MESHTRACER_SAMPLES") {
        for (name, path) in [
            ("DamagedHelmet", "DamagedHelmet/glTF/DamagedHelmet.gltf"),
            ("StanfordBunny", "StanfordBunny-OBJ/stanford-bunny.obj"),
            (
                "MetalRoughSpheres",
                "MetalRoughSpheresNoTextures/glTF-Binary/MetalRoughSpheresNoTextures.glb",
            ),
        ] {
            if let Ok(scene) = Scene::load(std::path::Path::new(&dir).join(path)) {
                out.push((name.to_string(), scene));
            }
        }
    }
    out
}

fn build(c: &mut Criterion) {
    let mut group = c.benchmark_group("build");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(5));
    /// Scene, preset, triangles, soup bytes, acceleration structure bytes.
    type Memory = (String, BvhPreset, usize, usize, usize);
    let mut memory: Vec<Memory> = Vec::new();
    for (name, scene) in scenes(&[1_000, 10_000, 100_000, 1_000_000]) {
        group.throughput(Throughput::Elements(scene.soup.len() as u64));
        for preset in [
            BvhPreset::Fastest,
            BvhPreset::VeryFast,
            BvhPreset::Medium,
            BvhPreset::Slow,
        ] {
            if preset == BvhPreset::Slow && scene.soup.len() > 200_000 {
                continue;
            }
            group.bench_with_input(
                BenchmarkId::new(format!("{preset:?}"), &name),
                &scene,
                |b, scene| {
                    // Criterion calls this for warm-up and for every sample: record the
                    // memory once, from a build outside the timed loop.
                    if !memory.iter().any(|m: &Memory| m.0 == name && m.1 == preset) {
                        let accel =
                            Accel::build(&scene.soup, &scene.materials, AccelKind::Bvh, preset);
                        let (soup, bvh) = (scene.soup.heap_bytes(), accel.heap_bytes());
                        memory.push((name.clone(), preset, scene.soup.len(), soup, bvh));
                    }
                    b.iter(|| {
                        let accel =
                            Accel::build(&scene.soup, &scene.materials, AccelKind::Bvh, preset);
                        assert!(accel.len() >= scene.soup.len());
                        accel
                    })
                },
            );
        }
    }
    group.finish();
    // The memory report: what a render keeps besides the images (empty when filtered out).
    if memory.is_empty() {
        return;
    }
    println!("\nmemory: scene, preset, soup MB, BVH and triangle test data MB, bytes a triangle");
    for (name, preset, triangles, soup, accel) in memory {
        println!(
            "  {name:<20} {:<9} {:>8.1} {:>8.1} {:>6.0}",
            format!("{preset:?}"),
            soup as f64 / 1e6,
            accel as f64 / 1e6,
            (soup + accel) as f64 / triangles.max(1) as f64
        );
    }
}

fn traverse(c: &mut Criterion) {
    let pool = one_thread();
    let mut group = c.benchmark_group("traverse");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(4));
    for (name, scene) in scenes(&[1_000, 10_000, 100_000, 1_000_000]) {
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
        for kind in [RayKind::Primary, RayKind::Shadow, RayKind::Diffuse] {
            let rays = make_rays(&scene, &bvh, kind, 256, 7);
            let expected = pool.install(|| trace(&bvh, &rays, kind));
            group.throughput(Throughput::Elements(rays.len() as u64));
            group.bench_function(BenchmarkId::new(format!("bvh-{kind:?}"), &name), |b| {
                b.iter(|| {
                    let got = pool.install(|| trace(&bvh, black_box(&rays), kind));
                    assert_eq!(got, expected);
                })
            });
            // Eight rays at a time through the packet queries: the same answers.
            group.bench_function(BenchmarkId::new(format!("packets-{kind:?}"), &name), |b| {
                b.iter(|| {
                    let got = pool.install(|| trace_packets(&bvh, black_box(&rays), kind));
                    assert_eq!(got, expected);
                })
            });
            // The linear scan only where it finishes: a few hundred rays below 100k triangles.
            if scene.soup.len() <= 100_000 {
                let subset = &rays[..rays.len().min(20_000_000 / scene.soup.len())];
                let want = pool.install(|| trace(&bvh, subset, kind));
                group.throughput(Throughput::Elements(subset.len() as u64));
                group.bench_function(BenchmarkId::new(format!("linear-{kind:?}"), &name), |b| {
                    b.iter(|| {
                        let got = pool.install(|| trace(&linear, black_box(subset), kind));
                        assert_eq!(got, want);
                    })
                });
            }
        }
    }
    group.finish();
}

/// Möller–Trumbore (1997), the reference the other two tests are compared with.
#[derive(Clone, Copy)]
struct MollerTrumbore {
    v0: Vec3A,
    e1: Vec3A,
    e2: Vec3A,
}

impl MollerTrumbore {
    #[inline(always)]
    fn intersect(&self, ray: &Ray) -> f32 {
        let p = ray.direction.cross(self.e2);
        let det = self.e1.dot(p);
        if det.abs() < 1e-12 {
            return f32::INFINITY;
        }
        let inv = 1.0 / det;
        let s = ray.origin - self.v0;
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return f32::INFINITY;
        }
        let q = s.cross(self.e1);
        let v = ray.direction.dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            return f32::INFINITY;
        }
        let t = self.e2.dot(q) * inv;
        if t > ray.tmin && t < ray.tmax {
            t
        } else {
            f32::INFINITY
        }
    }
}

fn triangle_tests(c: &mut Criterion) {
    // 1024 random triangles and 1024 rays aimed near random triangles: about half the tests hit.
    let mut rng = Rng::new(3);
    let mut p = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
    let tris: Vec<[Vec3; 3]> = (0..1024).map(|_| [p(), p(), p()]).collect();
    let rays: Vec<Ray> = (0..1024)
        .map(|i| {
            let [a, b, c] = tris[(i * 7) % tris.len()];
            let target = (a + b + c) / 3.0 + (p() * 0.3);
            let origin = p() * 4.0;
            Ray::new(origin, (target - origin).normalize(), 0.0, f32::INFINITY)
        })
        .collect();
    let ours: Vec<PreparedTriangle> = tris
        .iter()
        .filter_map(|[a, b, c]| PreparedTriangle::new(*a, *b, *c))
        .collect();
    let obvhs_tris: Vec<obvhs::rt_triangle::RtTriangle> = tris
        .iter()
        .map(|[a, b, c]| obvhs::rt_triangle::RtTriangle::new((*a).into(), (*b).into(), (*c).into()))
        .collect();
    let obvhs_rays: Vec<obvhs::ray::Ray> = rays
        .iter()
        .map(|r| obvhs::ray::Ray::new(r.origin, r.direction, r.tmin, r.tmax))
        .collect();
    let mt: Vec<MollerTrumbore> = tris
        .iter()
        .map(|[a, b, c]| MollerTrumbore {
            v0: (*a).into(),
            e1: (*b - *a).into(),
            e2: (*c - *a).into(),
        })
        .collect();
    let count = |f: &dyn Fn(usize, usize) -> f32| {
        let mut hits = 0u32;
        for r in 0..rays.len() {
            for t in 0..tris.len() {
                hits += u32::from(f(r, t) < f32::INFINITY);
            }
        }
        hits
    };
    let ours_hits = count(&|r, t| ours[t].intersect_t(&rays[r]));
    let obvhs_hits = count(&|r, t| obvhs_tris[t].intersect(&obvhs_rays[r]));
    let mt_hits = count(&|r, t| mt[t].intersect(&rays[r]));
    // The three tests agree up to edge handling (ours accepts a 1e-4 barycentric overlap).
    let spread = ours_hits.max(obvhs_hits).max(mt_hits) - ours_hits.min(obvhs_hits).min(mt_hits);
    assert!(
        spread * 200 < ours_hits,
        "hit counts {ours_hits} {obvhs_hits} {mt_hits}"
    );

    let mut group = c.benchmark_group("triangle");
    group.throughput(Throughput::Elements((rays.len() * tris.len()) as u64));
    group.bench_function("plane+3 edges (ours)", |b| {
        b.iter(|| {
            assert_eq!(
                count(&|r, t| black_box(&ours[t]).intersect_t(&rays[r])),
                ours_hits
            )
        })
    });
    group.bench_function("obvhs RtTriangle", |b| {
        b.iter(|| {
            assert_eq!(
                count(&|r, t| black_box(&obvhs_tris[t]).intersect(&obvhs_rays[r])),
                obvhs_hits
            )
        })
    });
    group.bench_function("Moller-Trumbore", |b| {
        b.iter(|| {
            assert_eq!(
                count(&|r, t| black_box(&mt[t]).intersect(&rays[r])),
                mt_hits
            )
        })
    });
    group.finish();
}

/// Our closest-hit query against obvhs's own `ray_traverse` with its RtTriangle, on the same
/// scene, rays and preset (each with its own build): the overhead of our triangle test, tie
/// rule, culling and hit record over bare traversal.
fn bare_obvhs(c: &mut Criterion) {
    let scene = scene_from_soup(generated_mesh(100_000, 1), "generated");
    let bvh = Accel::build(
        &scene.soup,
        &scene.materials,
        AccelKind::Bvh,
        BvhPreset::Medium,
    );
    let rays = make_rays(&scene, &bvh, RayKind::Primary, 256, 7);
    let tris: Vec<obvhs::triangle::Triangle> = (0..scene.soup.len())
        .map(|t| {
            let [a, b, c] = scene.soup.triangle(t);
            obvhs::triangle::Triangle {
                v0: a.into(),
                v1: b.into(),
                v2: c.into(),
            }
        })
        .collect();
    let cw = obvhs::cwbvh::builder::build_cwbvh_from_tris(
        &tris,
        BvhPreset::Medium.params(),
        &mut Duration::default(),
    );
    let rt: Vec<obvhs::rt_triangle::RtTriangle> = cw
        .primitive_indices
        .iter()
        .map(|&i| (&tris[i as usize]).into())
        .collect();
    let obvhs_rays: Vec<obvhs::ray::Ray> = rays
        .iter()
        .map(|r| obvhs::ray::Ray::new(r.origin, r.direction, r.tmin, r.tmax))
        .collect();
    let bare = || {
        let mut hits = 0u32;
        for ray in &obvhs_rays {
            let mut hit = obvhs::ray::RayHit::none();
            hits += u32::from(cw.ray_traverse(*ray, &mut hit, |r, id| rt[id].intersect(r)));
        }
        hits
    };
    let ours = || rays.iter().filter(|r| bvh.intersect(r).is_some()).count() as u32;
    let (bare_hits, our_hits) = (bare(), ours());
    assert!(
        bare_hits.abs_diff(our_hits) * 1000 < our_hits,
        "{bare_hits} vs {our_hits}"
    );
    let mut group = c.benchmark_group("query");
    group.throughput(Throughput::Elements(rays.len() as u64));
    group.bench_function("bare obvhs ray_traverse + RtTriangle", |b| {
        b.iter(|| assert_eq!(bare(), bare_hits))
    });
    group.bench_function("meshtracer Accel::intersect", |b| {
        b.iter(|| assert_eq!(ours(), our_hits))
    });
    group.finish();
}

fn render(c: &mut Criterion) {
    use meshtracer::camera::View;
    use meshtracer::render::{render, RenderSettings};
    let scene = Scene::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/cornell-box.gltf"
    ))
    .expect("bundled scene");
    let accel = Accel::build(
        &scene.soup,
        &scene.materials,
        AccelKind::Bvh,
        BvhPreset::Medium,
    );
    let settings = RenderSettings {
        view: View::from_camera(&scene.cameras[0], 256, 192),
        spp: 1,
        seed: 0,
        lights: scene.lights.clone(),
        ambient: Vec3::splat(0.03),
        exposure: 0.0,
        shading: meshtracer::shading::ShadingModel::Pbr,
        aovs: false,
        integrator: meshtracer::integrator::IntegratorKind::Direct,
        bounces: 0,
        environment: None,
        environment_visible: false,
        noise: None,
        clamp_indirect: None,
        guides: false,
    };
    let scene = meshtracer::prepare::Prepared::from_parts(
        scene,
        accel,
        meshtracer::prepare::textures::TextureSet::default(),
    );
    let cancel = std::sync::atomic::AtomicBool::new(false);
    let pool = one_thread();
    let reference = pool
        .install(|| render(&scene, &settings, &cancel, &|_, _| {}))
        .expect("renders")
        .0;
    let mut group = c.benchmark_group("render");
    group
        .sample_size(10)
        .throughput(Throughput::Elements(256 * 192));
    time_render(
        &mut group,
        "cornell-box 256x192 1spp, 1 thread",
        &pool,
        &scene,
        &settings,
        &reference,
    );
    group.finish();
}

/// Times renders of `settings` on `pool`, each checked to equal `reference`.
fn time_render(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    name: &str,
    pool: &rayon::ThreadPool,
    scene: &meshtracer::prepare::Prepared,
    settings: &meshtracer::render::RenderSettings,
    reference: &meshtracer::output::Image,
) {
    let cancel = std::sync::atomic::AtomicBool::new(false);
    group.bench_function(name, |b| {
        b.iter(|| {
            let (image, _, _) = pool
                .install(|| meshtracer::render::render(scene, settings, &cancel, &|_, _| {}))
                .expect("renders");
            assert!(&image == reference);
        })
    });
}

/// The path tracer's rays per second (camera, shadow and bounce rays, shading included) on
/// DamagedHelmet (five 2048² textures) under the built-in studio, one thread: compare it with
/// `traverse/bvh-Diffuse/DamagedHelmet`, the BVH alone on incoherent rays. The README's light
/// transport table states the ratio (at least 60%). Needs `MESHTRACER_SAMPLES`.
fn path_tracer(c: &mut Criterion) {
    use meshtracer::camera::{auto_camera, View};
    use meshtracer::render::{render, RenderSettings};
    let Some(dir) = std::env::var_os("MESHTRACER_SAMPLES") else {
        eprintln!("path tracer benchmark skipped: set MESHTRACER_SAMPLES");
        return;
    };
    let path = std::path::Path::new(&dir).join("DamagedHelmet/glTF/DamagedHelmet.gltf");
    let Ok(scene) = Scene::load(&path) else {
        eprintln!(
            "path tracer benchmark skipped: {} does not load",
            path.display()
        );
        return;
    };
    let pool = one_thread();
    let scene = pool.install(|| {
        meshtracer::prepare::Prepared::new(scene, &Default::default(), &mut Vec::new())
            .expect("textures decode")
    });
    let camera = auto_camera(&scene.scene.bounds, &scene.scene.soup.positions, 4.0 / 3.0);
    let settings = RenderSettings {
        view: View::from_camera(&camera, 160, 120),
        spp: 4,
        seed: 0,
        lights: Vec::new(),
        ambient: Vec3::ZERO,
        exposure: 0.0,
        shading: meshtracer::shading::ShadingModel::Pbr,
        aovs: false,
        integrator: meshtracer::integrator::IntegratorKind::Path,
        bounces: 8,
        environment: Some(std::sync::Arc::new(
            meshtracer::light::environment::Environment::studio(),
        )),
        environment_visible: false,
        noise: None,
        clamp_indirect: None,
        guides: false,
    };
    let cancel = std::sync::atomic::AtomicBool::new(false);
    let (reference, stats, _) = pool
        .install(|| render(&scene, &settings, &cancel, &|_, _| {}))
        .expect("renders");
    let mut group = c.benchmark_group("path");
    group
        .sample_size(10)
        .throughput(Throughput::Elements(stats.rays()));
    time_render(
        &mut group,
        "DamagedHelmet 160x120 4spp studio, rays, 1 thread",
        &pool,
        &scene,
        &settings,
        &reference,
    );
    group.finish();
}

/// Loading (parse, decode, flatten, tangents; textures are decoded later) of each encoded sample
/// beside its plain sibling: Draco and meshopt should stay within 1.5x of plain.
/// Needs `MESHTRACER_SAMPLES`; skipped without it.
fn load(c: &mut Criterion) {
    let Some(dir) = std::env::var_os("MESHTRACER_SAMPLES") else {
        eprintln!("load benchmark skipped: set MESHTRACER_SAMPLES");
        return;
    };
    let dir = std::path::Path::new(&dir);
    let mut group = c.benchmark_group("load");
    group.sample_size(20);
    for (model, variants) in [
        (
            "Duck",
            &[
                "glTF/Duck.gltf",
                "glTF-Draco/Duck.gltf",
                "glTF-Meshopt/Duck.glb",
            ][..],
        ),
        (
            "CesiumMilkTruck",
            &[
                "glTF/CesiumMilkTruck.gltf",
                "glTF-Draco/CesiumMilkTruck.gltf",
            ][..],
        ),
        (
            "CesiumMan",
            &["glTF/CesiumMan.gltf", "glTF-Draco/CesiumMan.gltf"][..],
        ),
        (
            "DamagedHelmet",
            &["glTF/DamagedHelmet.gltf", "glTF-Meshopt/DamagedHelmet.glb"][..],
        ),
    ] {
        for variant in variants {
            let path = dir.join(model).join(variant);
            if Scene::load(&path).is_err() {
                continue;
            }
            let folder = variant.split('/').next().unwrap_or(variant);
            group.bench_function(BenchmarkId::new(model, folder), |b| {
                b.iter(|| Scene::load(&path).expect("loads"))
            });
        }
    }
    group.finish();
}

criterion_group!(
    benches,
    triangle_tests,
    bare_obvhs,
    traverse,
    build,
    render,
    path_tracer,
    load
);
criterion_main!(benches);
