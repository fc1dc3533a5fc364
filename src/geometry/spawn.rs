//! Where secondary rays start: hit points with a floating-point error bound, and origins pushed
//! just far enough off the surface that no ray re-hits the triangle it leaves.
//!
//! A secondary ray (shadow, reflection, refraction, a path bounce) that starts exactly at a
//! computed hit point may find the very surface it leaves, because the point carries rounding
//! error and may lie on the wrong side of the triangle's plane: "shadow acne". Any fixed offset
//! fails somewhere: a scene-size constant is too small where the model lies far from the origin
//! compared with its triangles, and too large for contact shadows of small parts. Following
//! pbrt-v4 (Pharr, Jakob and Humphreys, "Physically Based Rendering", 4th ed., §6.8.6), the
//! offset is computed per hit from a bound on the error of that hit point and of the triangle
//! test that will judge the new ray, and is therefore independent of the scene's scale.
//!
//! ## The bound
//! With unit roundoff u = 2⁻²⁴ and Higham's γₙ = n·u / (1 - n·u) (the relative error bound of
//! n chained f32 operations), for a hit on triangle (p₀, p₁, p₂) with barycentrics bᵢ:
//!
//! 1. The hit point `p = Σ bᵢ·pᵢ`, with the bᵢ first rescaled to sum to 1, is off the exact
//!    point of the triangle by at most `γ₇ · Σ |bᵢ·pᵢ|` per coordinate (pbrt-v4, §6.8.5). The
//!    barycentrics themselves may be off by far more (the edge planes are evaluated with
//!    cancellation), but rescaled ones only slide the point *within* the plane.
//! 2. The plane-plus-three-edge test ([`super::triangle`]) decides on which side of its plane a
//!    ray origin `o` lies from `n·o + w`, where `n` is the rounded normal (b - a) × (c - a) and
//!    `w = -n·a` is rounded too. That value is wrong by at most `γ₄·(|n|·|o| + |w|) + γ₃·|n|·|a|`
//!    in plane units, that is, about `γ₈·(|o| + |a|)` along the unit normal. The rounded
//!    normal is also tilted from the exact one, by at most γ₃·‖e₁‖·‖e₂‖ / ‖n‖ radians; across a
//!    triangle of longest edge ℓ that moves its plane by `γ₃·ℓ·‖e₁‖·‖e₂‖ / ‖n‖`, which only
//!    matters for slivers.
//!
//! Both are covered by [`SpawnPoint::error`]: per coordinate `γ₁₆ · max |pᵢ|` (twice the sum of
//! the two coordinate terms above, so the margin is a factor of two) plus the tilt term, and the
//! origin moves along the unit geometric normal by `|n̂|·error` (the largest error projected on
//! the normal), then every coordinate is rounded one more ulp away from the surface. For a model
//! whose coordinates are around 1 that is about 1e-6 (a micrometre at metre scale); it scales
//! with the coordinates, not with the scene's extent, so it is the same in relative terms at
//! 1e-4x and 1e4x. A property test fires rays from random points of random triangles at
//! magnitudes 1e-6 to 1e6 and checks that none re-hits its own triangle (or a coplanar
//! neighbour) and none starts outside a slab 1e-5 of the coordinates' magnitude thick.
//!
//! The offset goes to the side of the surface the new ray travels into: out of the surface
//! for shadow and reflected rays, through it for transmitted ones.

use super::Ray;
use glam::{Vec3, Vec3A};

/// f32's unit roundoff: half the distance from 1 to the next float.
const UNIT_ROUNDOFF: f32 = f32::EPSILON * 0.5;

/// Higham's γₙ = n·u / (1 - n·u): bounds the relative error of n chained f32 operations.
const fn gamma(n: u8) -> f32 {
    let nu = n as f32 * UNIT_ROUNDOFF;
    nu / (1.0 - nu)
}

/// How far short of its end a ray toward a point (a light, another surface) stops, relative to
/// its length: the end point carries rounding error too, and a surface right at a point light
/// (a bulb modelled around its light) must not shadow it. pbrt-v4 uses the same 1e-4
/// (`ShadowEpsilon`).
pub const SHADOW_EPSILON: f32 = 1e-4;

/// How far a ray toward something `distance` away goes: [`SHADOW_EPSILON`] of it short of the
/// end, and without end toward a direction (`distance` infinite).
pub fn ray_extent(distance: f32) -> f32 {
    if distance.is_finite() {
        distance * (1.0 - SHADOW_EPSILON)
    } else {
        f32::INFINITY
    }
}

/// A hit point with its error bound: where secondary rays leave a surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpawnPoint {
    /// The hit point, world space.
    pub point: Vec3,
    /// Per-coordinate bound on how far `point` and the triangle tests around it may be off
    /// (see the module notes).
    pub error: Vec3,
    /// Unit geometric normal of the triangle hit (either orientation).
    pub normal: Vec3,
}

/// What a [`SpawnPoint`] takes from its triangle alone: the error bound and the unit normal,
/// the same at every point of the triangle (the bound depends on the vertices, not on where
/// between them the point lies). An emissive triangle keeps its frame, so that each point drawn
/// on it costs the point's interpolation only.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpawnFrame {
    /// See [`SpawnPoint::error`].
    pub error: Vec3,
    /// See [`SpawnPoint::normal`].
    pub normal: Vec3,
}

impl SpawnFrame {
    /// The frame of triangle `vertices`; `None` for a degenerate or non-finite triangle.
    #[inline(always)]
    pub fn of(vertices: [Vec3; 3]) -> Option<SpawnFrame> {
        // In SIMD lanes (Vec3A): the same operations, lane by lane, as with Vec3, so the same
        // bits, in about half the instructions (this runs at every path vertex).
        let [p0, p1, p2] = vertices.map(Vec3A::from);
        let (e1, e2) = (p1 - p0, p2 - p0);
        let n = e1.cross(e2);
        let n_len2 = n.length_squared();
        let n_len = n_len2.sqrt();
        if !(n_len > 0.0 && n_len.is_finite()) {
            return None;
        }
        let largest = p0.abs().max(p1.abs()).max(p2.abs());
        // Three square roots, not five: squared lengths compared, and ‖e₁‖·‖e₂‖/‖n‖ as one
        // root of a ratio (1/sin of the angle at p₀, so it cannot overflow).
        let (l1, l2) = (e1.length_squared(), e2.length_squared());
        let longest = l1.max(l2).max((p2 - p1).length_squared()).sqrt();
        let tilt = gamma(3) * longest * ((l1 / n_len2) * l2).sqrt();
        let error = gamma(16) * largest + Vec3A::splat(tilt);
        Some(SpawnFrame {
            error: error.into(),
            normal: (n / n_len).into(),
        })
    }

    /// The point at barycentrics `b` of `vertices` (this frame's triangle), rescaled to sum
    /// to 1 first; `None` for non-finite input.
    #[inline(always)]
    pub fn at(self, vertices: [Vec3; 3], b: Vec3) -> Option<SpawnPoint> {
        let sum = b.x + b.y + b.z;
        if !(sum.is_finite() && sum != 0.0) {
            return None;
        }
        let [p0, p1, p2] = vertices.map(Vec3A::from);
        let b = b / sum;
        let point = p0 * b.x + p1 * b.y + p2 * b.z;
        point.is_finite().then_some(SpawnPoint {
            point: point.into(),
            error: self.error,
            normal: self.normal,
        })
    }
}

impl SpawnPoint {
    /// The point at barycentrics `b` of triangle `vertices`, with its error bound. `b` need not
    /// sum to 1 exactly (the triangle test's barycentrics do not): it is rescaled first.
    /// Returns `None` for a degenerate triangle or non-finite input.
    // Inlined into the surface evaluation of the pixel loop: as a call it passed its vectors
    // through memory (callgrind: +3.5% instructions for a path-traced render).
    #[inline(always)]
    pub fn on_triangle(vertices: [Vec3; 3], b: Vec3) -> Option<SpawnPoint> {
        SpawnFrame::of(vertices)?.at(vertices, b)
    }

    /// The same point moved by `offset` (the terminator lift, say), with the error of that
    /// addition added to the bound.
    pub fn moved(self, offset: Vec3) -> SpawnPoint {
        let point = self.point + offset;
        SpawnPoint {
            point,
            error: self.error + gamma(1) * point.abs(),
            normal: self.normal,
        }
    }

    /// The origin for a ray leaving along `direction`: off the surface on the side `direction`
    /// points to, by the error bound projected on the normal, every coordinate rounded one
    /// more float away from the surface.
    #[inline(always)]
    pub fn origin(&self, direction: Vec3) -> Vec3 {
        // Never zero: a coordinate that is exact (all three vertices at z = 0, say) still
        // moves one float off the plane.
        let distance = self.normal.abs().dot(self.error).max(f32::MIN_POSITIVE);
        let mut offset = self.normal * distance;
        if direction.dot(self.normal) < 0.0 {
            offset = -offset;
        }
        let moved = self.point + offset;
        let away = |p: f32, o: f32| {
            if o > 0.0 {
                p.next_up()
            } else if o < 0.0 {
                p.next_down()
            } else {
                p
            }
        };
        Vec3::new(
            away(moved.x, offset.x),
            away(moved.y, offset.y),
            away(moved.z, offset.z),
        )
    }

    /// A ray leaving the surface along `direction` (unit length), as far as `distance` (the
    /// distance from the hit point to a light or another point; infinite for a direction),
    /// stopping [`SHADOW_EPSILON`] of it short of the end.
    #[inline(always)]
    pub fn ray(&self, direction: Vec3, distance: f32) -> Ray {
        Ray::new(self.origin(direction), direction, 0.0, ray_extent(distance))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::PreparedTriangle;
    use crate::sampling::Rng;
    use glam::vec3;

    fn unit(rng: &mut Rng) -> Vec3 {
        loop {
            let v = vec3(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            if let Some(v) = v.try_normalize() {
                return v;
            }
        }
    }

    /// The thinnest slab, relative to the largest coordinate of the triangle, that a spawned
    /// origin must stay within: √3·γ₁₆ ≈ 1.7e-6, plus the tilt term, which for a triangle no
    /// thinner than the test's sliver cut adds up to about 3e-6 (10 µm one metre from the
    /// origin; 0.1 µm for a part one centimetre from it).
    const THIN_SLAB: f32 = 1e-5;

    fn n_len(a: Vec3, b: Vec3, c: Vec3) -> f32 {
        (b - a).cross(c - a).length()
    }

    fn longest(a: Vec3, b: Vec3, c: Vec3) -> f32 {
        (b - a).length().max((c - b).length()).max((a - c).length())
    }

    fn largest_coordinate(vertices: [Vec3; 3]) -> f32 {
        vertices
            .iter()
            .map(|v| v.abs().max_element())
            .fold(0.0, f32::max)
    }

    /// A random direction in the hemisphere around `n`.
    fn toward(rng: &mut Rng, n: Vec3) -> Vec3 {
        let d = unit(rng);
        if d.dot(n) < 0.0 {
            -d
        } else {
            d
        }
    }

    /// The property the module promises, on random triangles whose size ranges from a
    /// thousandth of their distance to the origin up to their distance, at magnitudes from
    /// 1e-6 to 1e6: the triangle test finds a hit, the ray spawned from it (into a random
    /// direction on either side, as shadow and reflected or transmitted rays go) never hits
    /// the same triangle again, nor the coplanar neighbour sharing its edge, and its origin
    /// lies within [`THIN_SLAB`] of the plane: a surface that thin is not tunnelled through.
    /// (With γ₁ instead of γ₁₆ in the bound, 49 of the 160,000 rays re-hit; with γ₄, none:
    /// the documented bound has a margin of four.)
    #[test]
    fn spawned_rays_never_rehit_their_triangle_at_any_scale() {
        let mut rng = Rng::new(12);
        let (mut cases, mut rehits, mut outside_slab) = (0, 0, 0);
        let mut worst = 0.0f32;
        for exponent in -6..=6 {
            let magnitude = 10f32.powi(exponent);
            for _ in 0..4000 {
                let size = magnitude * 10f32.powf(-3.0 * rng.next_f32());
                let centre = unit(&mut rng) * magnitude;
                let (a, b, c) = (
                    centre + unit(&mut rng) * size,
                    centre + unit(&mut rng) * size,
                    centre + unit(&mut rng) * size,
                );
                // The neighbour across edge b-c, in the same plane, wound the same way.
                let d = b + c - a;
                let (Some(triangle), Some(neighbour)) = (
                    PreparedTriangle::new(a, b, c),
                    PreparedTriangle::new(d, c, b),
                ) else {
                    continue;
                };
                let n = (b - a).cross(c - a).normalize();
                // A camera-like ray at a random angle toward a random interior point.
                let (u, v) = (rng.next_f32(), rng.next_f32());
                let (u, v) = if u + v > 1.0 {
                    (1.0 - u, 1.0 - v)
                } else {
                    (u, v)
                };
                let target = a + (b - a) * u + (c - a) * v;
                let side = if rng.next_f32() < 0.5 { n } else { -n };
                let from = target + toward(&mut rng, side) * size * 4.0;
                let ray = Ray::new(from, (target - from).normalize(), 0.0, f32::INFINITY);
                let Some(hit) = triangle.intersect(&ray) else {
                    continue;
                };
                let Some(spawn) = SpawnPoint::on_triangle([a, b, c], hit.barycentric) else {
                    continue;
                };
                cases += 1;
                for _ in 0..4 {
                    let side = if rng.next_f32() < 0.5 { n } else { -n };
                    let direction = toward(&mut rng, side);
                    let secondary = spawn.ray(direction, f32::INFINITY);
                    let origin = Vec3::from(secondary.origin);
                    if triangle.intersect(&secondary).is_some()
                        || neighbour.intersect(&secondary).is_some()
                    {
                        rehits += 1;
                    }
                    let height = (origin - a).dot(n).abs();
                    if n_len(a, b, c) >= 0.1 * longest(a, b, c).powi(2) {
                        worst = worst.max(height / largest_coordinate([a, b, c]));
                    }
                    // Slivers excepted: their rounded plane is itself uncertain by more (the
                    // tilt term of the bound).
                    let sliver = n_len(a, b, c) < 0.1 * longest(a, b, c).powi(2);
                    if !sliver && height > THIN_SLAB * largest_coordinate([a, b, c]) {
                        outside_slab += 1;
                    }
                }
            }
        }
        assert!(cases > 40_000, "only {cases} cases");
        assert_eq!(rehits, 0, "{rehits} secondary rays re-hit their surface");
        assert_eq!(
            outside_slab, 0,
            "{outside_slab} origins beyond the slab (worst {worst} of the coordinates)"
        );
    }

    /// `SpawnPoint::origin` depends only on the side a direction points to, and the side test
    /// of a normal and of its negation agree exactly: what lets a surface compute the origin
    /// once for every ray leaving on its geometric side (`Surface::exit`).
    #[test]
    fn one_origin_serves_every_direction_on_a_side() {
        let mut rng = Rng::new(31);
        for _ in 0..2000 {
            let magnitude = 10f32.powf(6.0 * rng.next_f32() - 3.0);
            let [a, b, c] = [0; 3].map(|_| unit(&mut rng) * magnitude);
            let bary = crate::sampling::uniform_triangle(rng.next_f32(), rng.next_f32());
            let Some(p) = SpawnPoint::on_triangle([a, b, c], bary) else {
                continue;
            };
            for facing in [p.normal, -p.normal] {
                let once = p.origin(facing);
                for _ in 0..8 {
                    let d = toward(&mut rng, facing);
                    if d.dot(facing) > 0.0 {
                        assert_eq!(p.origin(d).to_array(), once.to_array());
                        assert_eq!(p.ray(d, 2.0).origin, Ray::new(once, d, 0.0, 1.0).origin);
                    }
                }
            }
        }
    }

    /// A ray toward a point stops short of it by [`SHADOW_EPSILON`] of the distance, and a
    /// direction has no end.
    #[test]
    fn rays_toward_points_stop_short() {
        let spawn = SpawnPoint::on_triangle([Vec3::ZERO, Vec3::X, Vec3::Y], Vec3::splat(1.0 / 3.0))
            .expect("a proper triangle");
        let ray = spawn.ray(Vec3::Z, 10.0);
        assert!((ray.tmax - 10.0 * (1.0 - SHADOW_EPSILON)).abs() < 1e-6);
        assert_eq!(spawn.ray(Vec3::Z, f32::INFINITY).tmax, f32::INFINITY);
        // The origin is above the plane for an outgoing ray, below it for a transmitted one.
        assert!(spawn.origin(Vec3::Z).z > 0.0);
        assert!(spawn.origin(Vec3::NEG_Z).z < 0.0);
    }

    #[test]
    fn degenerate_triangles_give_no_point() {
        let line = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        assert!(SpawnPoint::on_triangle(line, Vec3::splat(1.0 / 3.0)).is_none());
        let proper = [Vec3::ZERO, Vec3::X, Vec3::Y];
        assert!(SpawnPoint::on_triangle(proper, Vec3::ZERO).is_none());
        assert!(SpawnPoint::on_triangle(proper, Vec3::splat(f32::NAN)).is_none());
    }
}
