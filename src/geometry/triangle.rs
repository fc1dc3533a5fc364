//! The classic plane-plus-three-edge-tests ray/triangle intersection, precomputed.
//!
//! For triangle (a, b, c) with normal n = (b - a) × (c - a):
//! 1. the ray p + t·d meets the plane at `t = (a - p)·n / (d·n)`;
//! 2. the hit point x is inside when the three edge tests hold:
//!    `((b - a) × (x - a))·n ≥ 0`, `((c - b) × (x - b))·n ≥ 0`, `((a - c) × (x - c))·n ≥ 0`.
//!
//! By the scalar triple product `((b - a) × (x - a))·n = (x - a)·(n × (b - a))`, so each edge test
//! is a plane equation in x. Dividing by |n|² makes each one the barycentric coordinate of the
//! opposite vertex, which shading needs anyway. All four are homogeneous planes `(m, -m·q)`.
//!
//! The four planes are stored transposed (one `Vec4` per coordinate, a lane per plane: 64 bytes,
//! one cache line), so one ray evaluates all four at once with multiply-adds and no horizontal
//! sums: `P·(o, 1)` and `P·(d, 0)` give every plane's value at the origin and its rate along the
//! ray. The plane lane gives `t`, and because every plane is affine, its value at the hit point
//! `x = o + t·d` is `P·(o, 1) + t·P·(d, 0)`: the three edge tests in one compare.

use super::Ray;
use glam::{Vec3, Vec3A, Vec4};

/// How far outside an edge (in barycentric units) a hit still counts. Two triangles sharing an
/// edge compute their edge functions from different planes and hit points, so rounding can put
/// a ray through the shared edge just outside both. Measured on random triangles 10 units from
/// the origin with rays down to grazing angles: misses reach 5e-5 (x has error ~ulp(|x|)/cosθ),
/// so 1e-4 closes every gap. The overlap is 0.01% of the triangle's size: invisible.
pub const EDGE_EPSILON: f32 = 1e-4;

/// Per-lane lower bounds of the four plane values at the hit point: the supporting plane (lane
/// 0) is zero there by construction, so it only has to be a number; each edge lane is a
/// barycentric coordinate and may dip [`EDGE_EPSILON`] below zero.
const LOWER_BOUNDS: Vec4 = Vec4::new(f32::MIN, -EDGE_EPSILON, -EDGE_EPSILON, -EDGE_EPSILON);

/// A triangle prepared for the plane-plus-three-edge test.
///
/// Lane order in every field: the supporting plane `(n, -n·a)` with n = (b - a) × (c - a), not
/// normalised; then edge a->b scaled to give the barycentric coordinate of c; edge b->c, giving
/// that of a; edge c->a, giving that of b.
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C, align(16))]
pub struct PreparedTriangle {
    /// The x coefficients of the four planes.
    x: Vec4,
    /// The y coefficients.
    y: Vec4,
    /// The z coefficients.
    z: Vec4,
    /// The constant terms.
    w: Vec4,
}

/// Where a ray met a triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Barycentric weights of vertices (a, b, c), summing to 1 (up to [`EDGE_EPSILON`]).
    pub barycentric: Vec3,
    /// True when the ray arrives against the normal (b - a) × (c - a): the front face for a
    /// counter-clockwise triangle (glTF 2.0 §3.7.2.1).
    pub front: bool,
}

impl PreparedTriangle {
    /// A triangle no ray hits (its plane is zero, so `t` is NaN): a placeholder that keeps
    /// indices aligned should a triangle fail to prepare.
    pub const NEVER: PreparedTriangle = PreparedTriangle {
        x: Vec4::ZERO,
        y: Vec4::ZERO,
        z: Vec4::ZERO,
        w: Vec4::ZERO,
    };

    /// Precomputes the planes. Returns `None` for a degenerate triangle (zero or non-finite
    /// area), which the importer never produces.
    pub fn new(a: Vec3, b: Vec3, c: Vec3) -> Option<Self> {
        let n = (b - a).cross(c - a);
        let inv_len2 = 1.0 / n.length_squared();
        if !inv_len2.is_finite() || inv_len2 <= 0.0 {
            return None;
        }
        let edge = |from: Vec3, to: Vec3| {
            let m = n.cross(to - from) * inv_len2;
            m.extend(-m.dot(from))
        };
        let planes = [n.extend(-n.dot(a)), edge(a, b), edge(b, c), edge(c, a)];
        if !planes.iter().all(|p| p.is_finite()) {
            return None;
        }
        let lane = |i: usize| Vec4::from_array(planes.map(|p| p[i]));
        Some(Self {
            x: lane(0),
            y: lane(1),
            z: lane(2),
            w: lane(3),
        })
    }

    /// The geometric normal (b - a) × (c - a), not normalised.
    pub fn normal(&self) -> Vec3 {
        Vec3::new(self.x.x, self.y.x, self.z.x)
    }

    /// The four plane values at the hit point `origin + t·direction`, with `t` splatted, for
    /// the ray's supporting-plane intersection (see the module notes).
    #[inline(always)]
    fn planes_at_hit(&self, ray: &Ray) -> (Vec4, Vec4) {
        let (o, d) = (ray.origin, ray.direction);
        let at_origin = self.x * o.x + self.y * o.y + self.z * o.z + self.w;
        let along = self.x * d.x + self.y * d.y + self.z * d.z;
        // Plane: n·(o + t d) - n·a = 0.
        let t = -Vec4::splat(at_origin.x) / Vec4::splat(along.x);
        (at_origin + along * t, t)
    }

    /// Ray parameter of the hit in the open interval (`ray.tmin`, `ray.tmax`), or `f32::INFINITY`
    /// for a miss (parallel ray, plane behind or beyond, or outside an edge). The hot path;
    /// [`PreparedTriangle::intersect`] gives the full hit record.
    #[inline(always)]
    pub fn intersect_t(&self, ray: &Ray) -> f32 {
        let (at_hit, t) = self.planes_at_hit(ray);
        let t = t.x;
        // All five tests are evaluated and combined without branches (`&` on bools): with rays
        // that hit about half the triangles they test, branches mispredict and cost more than
        // the work they would skip. NaN (a ray parallel to and inside the plane) fails the
        // interval test and every lane compare.
        let inside =
            (t > ray.tmin) & (t < ray.tmax) & (at_hit.cmpge(LOWER_BOUNDS).bitmask() == 0b1111);
        if inside {
            t
        } else {
            f32::INFINITY
        }
    }

    /// [`PreparedTriangle::intersect_t`] of two triangles at once, `a` in the low and `b` in
    /// the high half of 256-bit AVX registers. Every lane sees the operations of
    /// `intersect_t`'s lane in the same order (separate multiplies and adds, the same sign
    /// flip and division), so each result is `intersect_t`'s, bit for bit (tested); two
    /// triangles of a leaf then cost one pass instead of two.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    #[inline]
    pub unsafe fn intersect_t_pair(a: &Self, b: &Self, ray: &Ray) -> (f32, f32) {
        use std::arch::x86_64::*;
        let pair = |lo: Vec4, hi: Vec4| _mm256_set_m128(hi.into(), lo.into());
        let (x, y, z, w) = (
            pair(a.x, b.x),
            pair(a.y, b.y),
            pair(a.z, b.z),
            pair(a.w, b.w),
        );
        let (o, d) = (ray.origin, ray.direction);
        let splat = _mm256_set1_ps;
        let at_origin = _mm256_add_ps(
            _mm256_add_ps(
                _mm256_add_ps(_mm256_mul_ps(x, splat(o.x)), _mm256_mul_ps(y, splat(o.y))),
                _mm256_mul_ps(z, splat(o.z)),
            ),
            w,
        );
        let along = _mm256_add_ps(
            _mm256_add_ps(_mm256_mul_ps(x, splat(d.x)), _mm256_mul_ps(y, splat(d.y))),
            _mm256_mul_ps(z, splat(d.z)),
        );
        // Lane 0 of each half (the supporting plane) to all four of its half.
        let plane = |v: __m256| _mm256_permute_ps::<0>(v);
        let t = _mm256_div_ps(_mm256_xor_ps(splat(-0.0), plane(at_origin)), plane(along));
        let at_hit = _mm256_add_ps(at_origin, _mm256_mul_ps(along, t));
        let bounds = _mm256_set_m128(LOWER_BOUNDS.into(), LOWER_BOUNDS.into());
        let edges = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_GE_OS>(at_hit, bounds));
        let (ta, tb) = (
            _mm256_cvtss_f32(t),
            _mm_cvtss_f32(_mm256_extractf128_ps::<1>(t)),
        );
        let hit = |t: f32, inside: bool| {
            if (t > ray.tmin) & (t < ray.tmax) & inside {
                t
            } else {
                f32::INFINITY
            }
        };
        (
            hit(ta, edges & 0b1111 == 0b1111),
            hit(tb, edges >> 4 == 0b1111),
        )
    }

    /// Full hit record for a ray already known to hit at `t` (from [`Self::intersect_t`]).
    pub fn hit_at(&self, ray: &Ray, t: f32) -> TriangleHit {
        let x = ray.origin + ray.direction * t;
        let at_x = self.x * x.x + self.y * x.y + self.z * x.z + self.w;
        TriangleHit {
            t,
            barycentric: Vec3::new(at_x.z, at_x.w, at_x.y),
            front: Vec3A::from(self.normal()).dot(ray.direction) < 0.0,
        }
    }

    /// The intersection, if any.
    pub fn intersect(&self, ray: &Ray) -> Option<TriangleHit> {
        let t = self.intersect_t(ray);
        (t < f32::INFINITY).then(|| self.hit_at(ray, t))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::vec3;

    fn ray(o: Vec3, d: Vec3) -> Ray {
        Ray::new(o, d, 0.0, f32::INFINITY)
    }

    /// The AVX pair gives each triangle `intersect_t`'s bits: random triangles against rays
    /// through them, near their edges, grazing their planes, parallel to them (NaN `t`), with
    /// zero direction components and with a `tmax` at the hit.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_pair_test_is_the_single_test_bit_for_bit() {
        if !std::arch::is_x86_feature_detected!("avx") {
            eprintln!("skipped: this CPU has no AVX");
            return;
        }
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        };
        let mut point = |scale: f32| vec3(next(), next(), next()) * scale;
        let mut triangles = Vec::new();
        while triangles.len() < 64 {
            let (a, b, c) = (point(10.0), point(10.0), point(10.0));
            triangles.extend(PreparedTriangle::new(a, b, c));
        }
        // Axis-aligned triangles, for rays parallel to their planes.
        triangles.extend(PreparedTriangle::new(Vec3::ZERO, Vec3::X, Vec3::Y));
        triangles.extend(PreparedTriangle::new(Vec3::ZERO, Vec3::Z, Vec3::X));
        let mut rays = Vec::new();
        for _ in 0..4000 {
            let origin = point(20.0);
            let target = point(10.0);
            let mut direction = target - origin;
            match rays.len() % 5 {
                0 => direction.x = 0.0,
                1 => direction = vec3(direction.x, 0.0, 0.0),
                2 => direction.z = 0.0,
                _ => {}
            }
            if direction == Vec3::ZERO {
                continue;
            }
            let tmax = if rays.len() % 7 == 0 {
                1.0
            } else {
                f32::INFINITY
            };
            rays.push(Ray::new(origin, direction, 1e-4, tmax));
        }
        let mut hits = 0;
        for (i, ray) in rays.iter().enumerate() {
            let a = &triangles[i % triangles.len()];
            let b = &triangles[(i * 7 + 3) % triangles.len()];
            // SAFETY: AVX was detected above.
            let (ta, tb) = unsafe { PreparedTriangle::intersect_t_pair(a, b, ray) };
            assert_eq!(ta.to_bits(), a.intersect_t(ray).to_bits(), "ray {i}, a");
            assert_eq!(tb.to_bits(), b.intersect_t(ray).to_bits(), "ray {i}, b");
            hits += usize::from(ta.is_finite()) + usize::from(tb.is_finite());
        }
        assert!(hits > 100, "too few hits to test anything: {hits}");
    }

    #[test]
    fn hits_inside_and_reports_barycentrics() {
        let tri = PreparedTriangle::new(Vec3::ZERO, Vec3::X, Vec3::Y).unwrap();
        let hit = tri
            .intersect(&ray(vec3(0.25, 0.25, 2.0), Vec3::NEG_Z))
            .expect("hit");
        assert!((hit.t - 2.0).abs() < 1e-6);
        assert!((hit.barycentric - vec3(0.5, 0.25, 0.25)).length() < 1e-6);
        assert!(hit.front, "ray from +Z meets the CCW front face");
        let back = tri
            .intersect(&ray(vec3(0.25, 0.25, -2.0), Vec3::Z))
            .unwrap();
        assert!(!back.front);
    }

    #[test]
    fn misses_outside_each_edge_and_behind() {
        let tri = PreparedTriangle::new(Vec3::ZERO, Vec3::X, Vec3::Y).unwrap();
        for o in [
            vec3(-0.1, 0.5, 1.0),
            vec3(0.5, -0.1, 1.0),
            vec3(0.6, 0.6, 1.0),
        ] {
            assert!(tri.intersect(&ray(o, Vec3::NEG_Z)).is_none(), "{o}");
        }
        assert!(tri.intersect(&ray(vec3(0.2, 0.2, 1.0), Vec3::Z)).is_none());
        // Parallel to the plane, inside it: no hit, no NaN leaking out.
        assert!(tri.intersect(&ray(vec3(-1.0, 0.2, 0.0), Vec3::X)).is_none());
    }

    #[test]
    fn respects_the_ray_interval() {
        let tri = PreparedTriangle::new(Vec3::ZERO, Vec3::X, Vec3::Y).unwrap();
        let mut r = ray(vec3(0.2, 0.2, 1.0), Vec3::NEG_Z);
        r.tmax = 0.5;
        assert!(tri.intersect(&r).is_none());
        r.tmax = 2.0;
        r.tmin = 1.5;
        assert!(tri.intersect(&r).is_none());
    }

    #[test]
    fn degenerate_triangles_are_refused() {
        assert!(PreparedTriangle::new(Vec3::ZERO, Vec3::X, Vec3::X * 2.0).is_none());
        assert!(PreparedTriangle::new(Vec3::ZERO, Vec3::X, Vec3::splat(f32::NAN)).is_none());
    }

    /// A ray through an edge shared by two triangles hits at least one of them, for many random
    /// points along random shared edges (seeded: the same cases every run).
    #[test]
    fn shared_edges_are_watertight() {
        let mut rng = crate::sampling::Rng::new(7);
        let mut gaps = 0;
        for _ in 0..100_000 {
            let p = |rng: &mut crate::sampling::Rng| {
                vec3(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 20.0 - 10.0
            };
            let (a, b, c, d) = (p(&mut rng), p(&mut rng), p(&mut rng), p(&mut rng));
            // (a, b, c) and (b, a, d) share edge a-b with opposite orientation, as in a mesh.
            let (Some(t1), Some(t2)) = (
                PreparedTriangle::new(a, b, c),
                PreparedTriangle::new(b, a, d),
            ) else {
                continue;
            };
            let s = rng.next_f32();
            let on_edge = a + (b - a) * s;
            let origin = p(&mut rng);
            let dir = (on_edge - origin).normalize();
            let r = ray(origin, dir);
            if t1.intersect(&r).is_none() && t2.intersect(&r).is_none() {
                gaps += 1;
            }
        }
        assert_eq!(gaps, 0, "rays slipped through shared edges");
    }
}
