//! The BVH against the linear-scan reference, with seeded rays.

use super::*;
use crate::sampling::Rng;
use crate::scene::SoupBuilder;
use crate::scene::TriangleIn;
use glam::{vec3, Vec3A};

/// A scene with structure and trouble: a tessellated sphere (shared edges everywhere), a
/// ground quad, and random triangles of all sizes, some single-sided.
fn test_soup() -> (TriangleSoup, Vec<Material>) {
    let mut b = SoupBuilder::new(1_000_000);
    let mut push = |p: [Vec3; 3], material: u32| {
        b.push(
            &TriangleIn {
                positions: p,
                ..Default::default()
            },
            material,
            0,
        )
    };
    let (rings, segments) = (24, 48);
    let point = |i: u32, j: u32| {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        let phi = std::f32::consts::TAU * j as f32 / segments as f32;
        vec3(
            theta.sin() * phi.cos(),
            theta.cos(),
            theta.sin() * phi.sin(),
        )
    };
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (
                point(i, j),
                point(i + 1, j),
                point(i + 1, j + 1),
                point(i, j + 1),
            );
            push([a, b, c], 0);
            push([a, c, d], 0);
        }
    }
    push(
        [
            vec3(-5.0, -1.0, -5.0),
            vec3(-5.0, -1.0, 5.0),
            vec3(5.0, -1.0, 5.0),
        ],
        1,
    );
    push(
        [
            vec3(-5.0, -1.0, -5.0),
            vec3(5.0, -1.0, 5.0),
            vec3(5.0, -1.0, -5.0),
        ],
        1,
    );
    let mut rng = Rng::new(42);
    for k in 0..2000 {
        let centre = vec3(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 8.0 - 4.0;
        let size = 0.01 + rng.next_f32() * if k % 10 == 0 { 3.0 } else { 0.3 };
        let mut corner =
            || centre + (vec3(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * size;
        push([corner(), corner(), corner()], k % 2);
    }
    let (soup, _) = b.finish();
    let materials = vec![
        Material {
            double_sided: true,
            ..Material::default()
        },
        Material::default(),
    ];
    (soup, materials)
}

fn random_rays(n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Rng::new(seed);
    let mut rays = Vec::with_capacity(n);
    for i in 0..n {
        let origin = vec3(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 12.0 - 6.0;
        let mut dir = vec3(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        match i % 5 {
            // Axis-parallel: two zero components (inverse direction is infinite).
            0 => dir = [Vec3::X, Vec3::NEG_Y, Vec3::Z][i % 3],
            // One zero component, of either sign: obvhs picks box planes from the sign bit.
            1 => dir.y = if i % 2 == 0 { 0.0 } else { -0.0 },
            // Grazing the ground plane at y = -1.
            2 => {
                dir.y = 1e-4;
                rays.push(Ray::new(
                    vec3(origin.x, -1.0 + 1e-5, origin.z),
                    dir.normalize(),
                    0.0,
                    f32::INFINITY,
                ));
                continue;
            }
            // Starting just above the ground, heading down: hits at t below 1e-4, where obvhs's
            // box test would cull (it clamps box entry to its own EPSILON, not ray.tmin).
            3 => {
                let height = 1e-6 + rng.next_f32() * 5e-5;
                dir.y = -0.2 - dir.y.abs();
                rays.push(Ray::new(
                    vec3(origin.x * 0.8, -1.0 + height, origin.z * 0.8),
                    dir.normalize(),
                    0.0,
                    f32::INFINITY,
                ));
                continue;
            }
            _ => {}
        }
        if dir.length_squared() < 1e-6 {
            dir = Vec3::X;
        }
        rays.push(Ray::new(origin, dir.normalize(), 0.0, f32::INFINITY));
    }
    rays
}

#[test]
fn bvh_matches_linear_scan_for_closest_and_any_hit() {
    let (soup, materials) = test_soup();
    let linear = Accel::build(&soup, &materials, AccelKind::Linear, BvhPreset::Medium);
    for preset in [BvhPreset::Fastest, BvhPreset::Medium, BvhPreset::Slow] {
        let bvh = Accel::build(&soup, &materials, AccelKind::Bvh, preset);
        let mut hits = 0;
        for (i, ray) in random_rays(20_000, 9).iter().enumerate() {
            let a = linear.intersect(ray);
            let b = bvh.intersect(ray);
            assert_eq!(
                a.map(|h| (h.triangle, h.t)),
                b.map(|h| (h.triangle, h.t)),
                "ray {i} {ray:?} preset {preset:?}"
            );
            assert_eq!(linear.occluded(ray), bvh.occluded(ray), "ray {i}");
            if let Some(h) = a {
                hits += 1;
                // Cut at 0.99 t the two agree (a culled back face may still block); reaching
                // past the hit, both are blocked.
                let mut short = *ray;
                short.tmax = h.t * 0.99;
                assert_eq!(linear.occluded(&short), bvh.occluded(&short), "ray {i}");
                let mut long = *ray;
                long.tmax = h.t * 1.01;
                assert!(linear.occluded(&long) && bvh.occluded(&long), "ray {i}");
            }
        }
        assert!(
            hits > 3_000,
            "the test rays must actually hit things ({hits})"
        );
    }
}

#[test]
fn paired_leaves_find_what_the_linear_scan_finds() {
    // Pairing starts at 100k triangles; forced here on the small scene.
    let (soup, materials) = test_soup();
    let linear = Accel::build(&soup, &materials, AccelKind::Linear, BvhPreset::Medium);
    for preset in [BvhPreset::VeryFast, BvhPreset::Medium] {
        let bvh = Accel::build_pairing(&soup, &materials, AccelKind::Bvh, preset, true);
        assert!(
            bvh.steps.list().iter().any(|s| s.name == "pairs"),
            "the build paired"
        );
        let mut ids = bvh.ids.clone();
        ids.sort_unstable();
        assert!(
            ids.iter().copied().eq(0..soup.len() as u32),
            "every triangle once"
        );
        for (i, ray) in random_rays(20_000, 11).iter().enumerate() {
            let a = linear.intersect(ray);
            assert_eq!(
                a.map(|h| (h.triangle, h.t)),
                bvh.intersect(ray).map(|h| (h.triangle, h.t)),
                "ray {i} {ray:?} preset {preset:?}"
            );
            assert_eq!(linear.occluded(ray), bvh.occluded(ray), "ray {i}");
        }
    }
}

#[test]
fn pairs_join_neighbours_only() {
    use obvhs::aabb::Aabb;
    let unit = |x: f32| Aabb::new(Vec3A::new(x, 0.0, 0.0), Vec3A::new(x + 1.0, 1.0, 1.0));
    // Touching unit boxes along x pair up in soup order; the one far away stays alone (a
    // pair with it would be a box ten times their size), and so does the last.
    let boxes = [
        unit(0.0),
        unit(1.0),
        unit(40.0),
        unit(2.0),
        unit(3.0),
        unit(4.0),
    ];
    let (pair_boxes, starts) = bvh::pair_neighbours(&boxes);
    assert_eq!(starts, [0, 2, 3, 5, 6]);
    assert_eq!(pair_boxes.len(), 4);
    assert_eq!((pair_boxes[0].min.x, pair_boxes[0].max.x), (0.0, 2.0));
    assert_eq!((pair_boxes[1].min.x, pair_boxes[1].max.x), (40.0, 41.0));
    assert_eq!((pair_boxes[2].min.x, pair_boxes[2].max.x), (2.0, 4.0));
    assert_eq!((pair_boxes[3].min.x, pair_boxes[3].max.x), (4.0, 5.0));
}

#[test]
fn paired_builds_do_not_depend_on_the_thread_count() {
    // A 150x150 grid of quads (45,000 triangles: three pairing runs), built on one thread
    // and on two: the same leaf order and the same nodes.
    let mut b = SoupBuilder::new(1_000_000);
    for i in 0..150 {
        for j in 0..150 {
            let p = |di: i32, dj: i32| {
                let (x, z) = ((i + di) as f32, (j + dj) as f32);
                vec3(x, (x * 0.3).sin() * (z * 0.2).cos(), z)
            };
            for tri in [[p(0, 0), p(1, 0), p(1, 1)], [p(0, 0), p(1, 1), p(0, 1)]] {
                b.push(
                    &TriangleIn {
                        positions: tri,
                        ..Default::default()
                    },
                    0,
                    0,
                );
            }
        }
    }
    let (soup, _) = b.finish();
    let materials = [Material::default()];
    let build = |threads: usize| {
        crate::on_threads(threads, || {
            let accel =
                Accel::build_pairing(&soup, &materials, AccelKind::Bvh, BvhPreset::VeryFast, true);
            let nodes: Vec<u8> = accel
                .bvh
                .as_ref()
                .map(|b| bytemuck::cast_slice(&b.nodes).to_vec())
                .unwrap_or_default();
            (accel.ids, nodes)
        })
    };
    let one = build(1);
    assert!(!one.1.is_empty());
    assert!(one == build(2), "the same tree on one thread and on two");
}

#[test]
fn single_sided_triangles_are_invisible_from_behind() {
    let mut b = SoupBuilder::new(10);
    b.push(
        &TriangleIn {
            positions: [Vec3::ZERO, Vec3::X, Vec3::Y],
            ..Default::default()
        },
        0,
        0,
    );
    let (soup, _) = b.finish();
    for kind in [AccelKind::Bvh, AccelKind::Linear] {
        let single = Accel::build(&soup, &[Material::default()], kind, BvhPreset::Medium);
        let front = Ray::new(vec3(0.2, 0.2, 1.0), Vec3::NEG_Z, 0.0, f32::INFINITY);
        let back = Ray::new(vec3(0.2, 0.2, -1.0), Vec3::Z, 0.0, f32::INFINITY);
        assert!(single.intersect(&front).is_some_and(|h| h.front));
        assert!(single.intersect(&back).is_none());
        assert!(single.occluded(&back), "it still casts shadows");
        let double = Material {
            double_sided: true,
            ..Material::default()
        };
        let both = Accel::build(&soup, &[double], kind, BvhPreset::Medium);
        assert!(both.intersect(&back).is_some_and(|h| !h.front));
    }
}

#[test]
fn the_auto_preset_follows_the_rays_a_triangle() {
    use crate::accel::BvhPreset;
    // 1M triangles at 640x480, 4 spp, two lights: about 3.7M rays, under 32 a triangle.
    assert_eq!(
        BvhPreset::Auto.for_work(1_000_000, 3.7e6),
        BvhPreset::VeryFast
    );
    assert_eq!(BvhPreset::Auto.for_work(15_000, 3.7e6), BvhPreset::Medium);
    assert_eq!(BvhPreset::Slow.for_work(1_000_000, 1.0), BvhPreset::Slow);
    let (soup, materials) = test_soup();
    let built = Accel::build(&soup, &materials, AccelKind::Bvh, BvhPreset::Auto);
    assert_eq!(
        built.preset(),
        BvhPreset::Medium,
        "unresolved auto builds as medium"
    );
}

#[test]
fn triangle_data_reuses_the_binary_trees_node_buffer() {
    // The shape `bvh::build` hands back: 2n - 1 nodes in a buffer of 2n.
    let n = 5;
    let mut spare: Vec<obvhs::bvh2::node::Bvh2Node> = bytemuck::allocation::zeroed_vec(2 * n);
    spare.truncate(2 * n - 1);
    let at = spare.as_ptr() as usize;
    let mut triangles = triangle_buffer(spare, n);
    assert!(triangles.is_empty());
    assert_eq!(triangles.capacity(), n);
    assert_eq!(triangles.as_ptr() as usize, at, "same allocation");
    // Filled in parallel as `Accel::build` fills it, it stays where it is.
    let mut flags = Vec::new();
    (0..n)
        .into_par_iter()
        .map(|_| (PreparedTriangle::NEVER, 0u8))
        .unzip_into_vecs(&mut triangles, &mut flags);
    assert_eq!((triangles.len(), triangles.as_ptr() as usize), (n, at));
    // Any other size gets room of its own.
    for spare in [bytemuck::allocation::zeroed_vec(7), Vec::new()] {
        let fresh = triangle_buffer(spare, n);
        assert!(fresh.is_empty() && fresh.capacity() >= n);
    }
}

/// Rays from points on the soup's triangles (as shadow and bounce rays start, but with
/// `tmin` 0 so the triangle itself is in reach), in random directions and along the axes.
fn rays_from_surfaces(soup: &TriangleSoup, n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|i| {
            let k = (rng.next_f32() * soup.len() as f32) as usize % soup.len();
            let [a, b, c] = soup.triangle(k);
            let (u, v) = (rng.next_f32(), rng.next_f32());
            let (u, v) = if u + v > 1.0 {
                (1.0 - u, 1.0 - v)
            } else {
                (u, v)
            };
            let origin = a + (b - a) * u + (c - a) * v;
            let dir = match i % 4 {
                0 => [Vec3::X, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_X][i % 16 / 4],
                _ => (vec3(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0)
                    .try_normalize()
                    .unwrap_or(Vec3::Y),
            };
            Ray::new(origin, dir, 0.0, f32::INFINITY)
        })
        .collect()
}

/// Every ray kind the tests use: random, axis-parallel, zero components of either sign,
/// grazing, starting just above or on a surface.
fn all_test_rays(soup: &TriangleSoup) -> Vec<Ray> {
    let mut rays = random_rays(10_000, 21);
    rays.extend(rays_from_surfaces(soup, 10_000, 22));
    rays
}

#[test]
fn rays_starting_on_triangles_find_what_the_linear_scan_finds() {
    let (soup, materials) = test_soup();
    let linear = Accel::build(&soup, &materials, AccelKind::Linear, BvhPreset::Medium);
    let bvh = Accel::build(&soup, &materials, AccelKind::Bvh, BvhPreset::Medium);
    let mut hits = 0;
    for (i, ray) in rays_from_surfaces(&soup, 20_000, 5).iter().enumerate() {
        let a = linear.intersect(ray);
        hits += usize::from(a.is_some());
        assert_eq!(
            a.map(|h| (h.triangle, h.t)),
            bvh.intersect(ray).map(|h| (h.triangle, h.t)),
            "ray {i} {ray:?}"
        );
        assert_eq!(linear.occluded(ray), bvh.occluded(ray), "ray {i} {ray:?}");
    }
    assert!(hits > 5_000, "the rays must hit things ({hits})");
}

/// The portable traversal (CPUs without AVX2) against the linear scan, called directly so it
/// is tested on any CPU.
#[test]
fn the_portable_traversal_finds_what_the_linear_scan_finds() {
    let (soup, materials) = test_soup();
    let linear = Accel::build(&soup, &materials, AccelKind::Linear, BvhPreset::Medium);
    for pair in [false, true] {
        let bvh = Accel::build_pairing(&soup, &materials, AccelKind::Bvh, BvhPreset::Medium, pair);
        for (i, ray) in all_test_rays(&soup).iter().enumerate() {
            assert_eq!(
                linear.intersect(ray).map(|h| (h.triangle, h.t)),
                bvh.closest_hit(traverse::Portable, ray, None)
                    .map(|h| (h.triangle, h.t)),
                "ray {i} {ray:?} pair {pair}"
            );
            assert_eq!(
                linear.occluded(ray),
                bvh.any_hit(traverse::Portable, ray, None),
                "ray {i} {ray:?} pair {pair}"
            );
        }
    }
}

/// The AVX2 node test gives the portable one's answer (with fused multiply-adds, as the AVX2
/// one uses) for every node, on every test ray; the portable one without them differs at most
/// in a few boxes the ray grazes.
#[test]
#[cfg(target_arch = "x86_64")]
fn the_avx2_node_test_agrees_with_the_portable_one() {
    let Some(avx2) = traverse::Avx2::new() else {
        eprintln!("no AVX2 on this CPU: nothing to compare");
        return;
    };
    let (soup, materials) = test_soup();
    let bvh = Accel::build(&soup, &materials, AccelKind::Bvh, BvhPreset::Medium);
    let nodes = &bvh.bvh.as_ref().expect("a BVH").nodes;
    let (mut entered, mut differ) = (0, 0);
    for ray in all_test_rays(&soup).iter().step_by(7) {
        let mut node_ray = traverse::NodeRay::new(ray);
        for tmax in [ray.tmax, 3.0, 0.5] {
            node_ray.set_tmax(tmax);
            for node in nodes {
                use traverse::NodeTest;
                // The same children entered, at the same distances (the closest-hit
                // traversal sorts by them).
                let (mut fused_enter, mut wide_enter) = ([0.0; 8], [0.0; 8]);
                let fused = traverse::fused_entries(node, &node_ray, &mut fused_enter);
                let wide = avx2.entries(node, &node_ray, &mut wide_enter);
                assert_eq!(fused, wide, "{ray:?} tmax {tmax} {node:?}");
                for lane in (0..8).filter(|lane| fused & 1 << lane != 0) {
                    assert_eq!(
                        fused_enter[lane].to_bits(),
                        wide_enter[lane].to_bits(),
                        "{ray:?} tmax {tmax} lane {lane}"
                    );
                }
                let portable = traverse::Portable.entries(node, &node_ray, &mut [0.0; 8]);
                differ += u32::from(portable != fused);
                entered += fused.count_ones();
            }
        }
    }
    assert!(entered > 10_000, "the rays must enter boxes ({entered})");
    assert!(differ * 1000 < entered, "{differ} of {entered}");
}

/// Camera rays through a grid of pixels, in scanline order: the coherent rays packets are
/// for, with neighbours entering the same nodes. Each also comes cut short at half its hit.
fn camera_rays(linear: &Accel) -> Vec<Ray> {
    let eye = vec3(0.3, 2.5, 9.0);
    let side = 48;
    let mut rays = Vec::new();
    for y in 0..side {
        for x in 0..side {
            let target = vec3(x as f32, (side - y) as f32, 0.0) / side as f32 * 10.0 - 5.0;
            let ray = Ray::new(eye, (target - eye).normalize(), 0.0, f32::INFINITY);
            rays.push(ray);
            if let Some(hit) = linear.intersect(&ray) {
                let mut short = ray;
                short.tmax = hit.t * 0.5;
                rays.push(short);
            }
        }
    }
    rays
}

/// Eight rays at a time, AVX2 and portable, over plain and paired leaves: the same hit
/// records as one ray at a time and the linear scan's triangle and distance, hit for hit,
/// and the same occlusion, on random, axis-parallel, grazing, surface-starting and coherent
/// camera rays, with a packet of fewer than eight at the end.
#[test]
fn packets_find_what_the_linear_scan_finds() {
    let (soup, materials) = test_soup();
    let linear = Accel::build(&soup, &materials, AccelKind::Linear, BvhPreset::Medium);
    let mut rays = all_test_rays(&soup);
    rays.extend(camera_rays(&linear));
    rays.truncate(rays.len() / 8 * 8 - 3);
    let want_hits: Vec<_> = rays.iter().map(|r| linear.intersect(r)).collect();
    let want_blocked: Vec<_> = rays.iter().map(|r| linear.occluded(r)).collect();
    assert!(want_hits.iter().flatten().count() > 8_000);
    assert!(want_blocked.iter().any(|&b| !b));
    // Both of the AVX2 packet test's paths are taken: packets of one octant (the node's
    // planes shared) and of mixed directions.
    let octants = |packet: &[Ray]| {
        let node_rays: Vec<_> = packet.iter().map(traverse::NodeRay::new).collect();
        traverse::one_octant(&node_rays)
    };
    let shared = rays.chunks(traverse::PACKET).filter(|p| octants(p)).count();
    assert!(shared > 100, "{shared} packets of one octant");
    assert!(
        shared * 2 < rays.len() / traverse::PACKET,
        "{shared}: mixed ones too"
    );
    for pair in [false, true] {
        let bvh = Accel::build_pairing(&soup, &materials, AccelKind::Bvh, BvhPreset::Medium, pair);
        let mut hits = vec![None; rays.len()];
        let mut blocked = vec![false; rays.len()];
        bvh.intersect_many(&rays, None, &mut hits);
        bvh.occluded_many(&rays, None, &mut blocked);
        for (i, ray) in rays.iter().enumerate() {
            let key = |h: &Option<Hit>| h.map(|h| (h.triangle, h.t));
            assert_eq!(key(&hits[i]), key(&want_hits[i]), "ray {i} {ray:?}");
            assert_eq!(hits[i], bvh.intersect(ray), "ray {i} {ray:?}");
            assert_eq!(blocked[i], want_blocked[i], "ray {i} {ray:?}");
        }
        // The portable node test (CPUs without AVX2), called directly.
        for (at, packet) in rays.chunks(traverse::PACKET).enumerate() {
            let at = at * traverse::PACKET;
            let found = bvh.closest_hit_packet(traverse::Portable, packet, None);
            let bits = bvh.any_hit_packet(traverse::Portable, packet, None);
            for (i, ray) in packet.iter().enumerate() {
                let key = found[i].map(|c| (bvh.ids[c.slot], c.t));
                assert_eq!(key, want_hits[at + i].map(|h| (h.triangle, h.t)), "{ray:?}");
                assert_eq!(bits >> i & 1 != 0, want_blocked[at + i], "{ray:?}");
            }
            assert_eq!(bits >> packet.len(), 0, "no answers past the packet");
        }
    }
}

/// The alpha test's callback is asked of packets as of single rays: with every hit on the
/// even triangles refused, eight at a time finds what one at a time finds.
#[test]
fn packets_ask_the_alpha_test() {
    let (soup, mut materials) = test_soup();
    for m in &mut materials {
        m.alpha_mode = crate::scene::AlphaMode::Mask;
    }
    let bvh = Accel::build(&soup, &materials, AccelKind::Bvh, BvhPreset::Medium);
    let accept = |triangle: u32, _: Vec3| triangle % 2 == 1;
    let rays = all_test_rays(&soup);
    let mut hits = vec![None; rays.len()];
    let mut blocked = vec![false; rays.len()];
    bvh.intersect_many(&rays, Some(&accept), &mut hits);
    bvh.occluded_many(&rays, Some(&accept), &mut blocked);
    let mut refused = 0;
    for (i, ray) in rays.iter().enumerate() {
        let one = bvh.intersect_filtered(ray, Some(&accept));
        refused += usize::from(one != bvh.intersect(ray));
        assert_eq!(hits[i], one, "ray {i} {ray:?}");
        assert_eq!(
            blocked[i],
            bvh.occluded_filtered(ray, Some(&accept)),
            "ray {i}"
        );
    }
    assert!(
        refused > 1_000,
        "the filter must change answers ({refused})"
    );
}
