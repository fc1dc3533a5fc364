//! Ray queries over the triangle soup: [`Accel::intersect`] (closest hit) and
//! [`Accel::occluded`] (any hit), answered by an obvhs CWBVH or by a linear scan of every
//! triangle. The linear scan is the slow, obviously correct reference the BVH is tested against,
//! and the baseline of the benchmarks.
//!
//! Both use the same triangle test and the same tie rule (equal `t` goes to the lower triangle
//! index), so they return the same closest triangle for every ray and render identical images.

mod bvh;
mod linear;
mod traverse;
mod wide;

use crate::geometry::{PreparedTriangle, Ray};
use crate::measure::{Step, Steps};
use crate::scene::{Material, TriangleSoup};
use glam::Vec3;
use rayon::prelude::*;
use std::time::Duration;

/// Which acceleration structure answers ray queries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum AccelKind {
    /// obvhs compressed wide BVH (CWBVH, eight-way).
    #[default]
    Bvh,
    /// Test every triangle (the reference and benchmark baseline).
    Linear,
}

/// obvhs build presets, from fastest build to fastest traversal, or chosen by the work.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BvhPreset {
    /// Chosen by the work at hand ([`BvhPreset::for_work`]): `very-fast` for few rays per
    /// triangle, `medium` otherwise.
    #[default]
    Auto,
    /// `BvhBuildParams::fastest_build`.
    Fastest,
    /// `BvhBuildParams::very_fast_build`.
    VeryFast,
    /// `BvhBuildParams::fast_build`.
    Fast,
    /// `BvhBuildParams::medium_build`.
    Medium,
    /// `BvhBuildParams::slow_build` (spatial pre-splits).
    Slow,
    /// `BvhBuildParams::very_slow_build`.
    VerySlow,
}

impl BvhPreset {
    /// The preset to build over `triangles` triangles for about `rays` rays: `Auto` resolves
    /// to `VeryFast` below [`crate::defaults::AUTO_PRESET_RAYS_PER_TRIANGLE`] rays a triangle
    /// and to `Medium` above; any other preset is kept.
    pub fn for_work(self, triangles: usize, rays: f64) -> BvhPreset {
        match self {
            BvhPreset::Auto
                if rays < crate::defaults::AUTO_PRESET_RAYS_PER_TRIANGLE * triangles as f64 =>
            {
                BvhPreset::VeryFast
            }
            BvhPreset::Auto => BvhPreset::Medium,
            other => other,
        }
    }

    /// Whether the build pairs neighbouring triangles into leaves before PLOC: for the preset
    /// `auto` chooses when few rays are traced a triangle, from [`bvh::PAIR_FROM`] triangles
    /// (`fastest` keeps obvhs's one triangle a leaf). See `bvh::pair_neighbours`.
    fn pairs(self, triangles: usize) -> bool {
        self == BvhPreset::VeryFast && triangles >= bvh::PAIR_FROM
    }

    /// The obvhs parameters for this preset (`Auto`, unresolved, builds as `Medium`).
    pub fn params(self) -> obvhs::BvhBuildParams {
        use obvhs::BvhBuildParams as P;
        match self {
            BvhPreset::Auto => P::medium_build(),
            BvhPreset::Fastest => P::fastest_build(),
            BvhPreset::VeryFast => P::very_fast_build(),
            BvhPreset::Fast => P::fast_build(),
            BvhPreset::Medium => P::medium_build(),
            BvhPreset::Slow => P::slow_build(),
            BvhPreset::VerySlow => P::very_slow_build(),
        }
    }
}

/// The closest hit of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Index of the triangle in the soup.
    pub triangle: u32,
    /// Ray parameter of the hit.
    pub t: f32,
    /// Barycentric weights of the triangle's three vertices.
    pub barycentric: Vec3,
    /// True when the ray met the counter-clockwise (front) face.
    pub front: bool,
}

/// [`Accel`] flag: the triangle is single-sided (invisible from behind).
const SINGLE_SIDED: u8 = 1;
/// [`Accel`] flag: the triangle needs the caller's alpha test (MASK and BLEND materials, and
/// see-through sheets, which shadow rays cross attenuated).
const ALPHA_TESTED: u8 = 2;

/// An empty vector with room for `len` triangles: `spare`'s allocation when it holds exactly
/// that many bytes (the binary BVH's nodes, whose first half is already paged in), else a new
/// one. Nothing is written: the caller fills it in parallel. (Zeroing the nodes' untouched
/// half first, as `Vec::resize` did, was a 32 MB memset on one thread for a million paired
/// triangles, with its 8,000 page faults: about half of the step.)
fn triangle_buffer(
    mut spare: Vec<obvhs::bvh2::node::Bvh2Node>,
    len: usize,
) -> Vec<PreparedTriangle> {
    let bytes = len * std::mem::size_of::<PreparedTriangle>();
    if spare.capacity() * std::mem::size_of::<obvhs::bvh2::node::Bvh2Node>() == bytes {
        spare.clear();
        if let Ok(recycled) = bytemuck::allocation::try_cast_vec(spare) {
            return recycled;
        }
    }
    Vec::with_capacity(len)
}

/// `$self.$v3(Avx2, args)` where the CPU runs x86-64-v3 code (a `_v3` copy made with
/// [`crate::cpu::v3!`]), else `$self.$portable(Portable, args)`: every query's choice of node
/// test and compiled copy, in one place.
macro_rules! by_cpu {
    ($self:ident . $v3:ident | $portable:ident ($($arg:expr),*)) => {{
        #[cfg(target_arch = "x86_64")]
        if let Some(avx2) = traverse::Avx2::new() {
            // SAFETY: `Avx2::new` checked that the CPU has every feature the `_v3` copies are
            // compiled for.
            return unsafe { $self.$v3(avx2, $($arg),*) };
        }
        $self.$portable(traverse::Portable, $($arg),*)
    }};
}

/// Rays one packet query ([`Accel::intersect_many`], [`Accel::occluded_many`]) takes into the
/// tree together.
pub const PACKET: usize = traverse::PACKET;

/// Ray queries over a triangle soup.
pub struct Accel {
    kind: AccelKind,
    /// Triangles in traversal order (BVH leaf order, or soup order for the linear scan).
    triangles: Vec<PreparedTriangle>,
    /// Soup index of each entry of `triangles`.
    ids: Vec<u32>,
    /// Per entry of `triangles`: [`SINGLE_SIDED`] and [`ALPHA_TESTED`] bits.
    flags: Vec<u8>,
    bvh: Option<obvhs::cwbvh::CwBvh>,
    /// How long each step of the build took.
    steps: Steps,
    /// The preset it was built with (resolved: never `Auto`).
    preset: BvhPreset,
}

impl Accel {
    /// Builds the structure over `soup`. `materials` decides which triangles are single-sided
    /// (glTF 2.0 §3.9.6: `doubleSided: false` surfaces are invisible from behind).
    pub fn build(
        soup: &TriangleSoup,
        materials: &[Material],
        kind: AccelKind,
        preset: BvhPreset,
    ) -> Accel {
        Accel::build_pairing(soup, materials, kind, preset, preset.pairs(soup.len()))
    }

    /// [`Accel::build`], told whether to pair triangles into leaves first.
    fn build_pairing(
        soup: &TriangleSoup,
        materials: &[Material],
        kind: AccelKind,
        preset: BvhPreset,
        pair: bool,
    ) -> Accel {
        let mut steps = Steps::new();
        let (mut bvh, spare) = match kind {
            AccelKind::Linear => (None, Vec::new()),
            AccelKind::Bvh => {
                let (bvh, spare) = bvh::build(soup, preset.params(), pair, &mut steps);
                (Some(bvh), spare)
            }
        };
        // Triangles are stored in traversal order (BVH leaf order: with spatial splits a
        // triangle may appear in several leaves), so traversal reads them sequentially without
        // an indirection, and they are prepared straight into that order. Traversal reports
        // leaf slots, so the BVH's own copy of the soup indices moves here.
        let ids: Vec<u32> = match &mut bvh {
            Some(bvh) => std::mem::take(&mut bvh.primitive_indices),
            None => (0..soup.len() as u32).collect(),
        };
        // Each material's flags once; then one parallel pass over the triangles.
        let material_flags: Vec<u8> = materials
            .iter()
            .map(|m| {
                // glTF 2.0 §3.9.6: `doubleSided: false` surfaces are invisible from behind
                // (volume boundaries excepted).
                let mut f = if m.culls_back_faces() {
                    SINGLE_SIDED
                } else {
                    0
                };
                if m.alpha_mode != crate::scene::AlphaMode::Opaque || m.see_through() {
                    f |= ALPHA_TESTED;
                }
                f
            })
            .collect();
        let mut triangles = triangle_buffer(spare, ids.len());
        let mut flags = Vec::with_capacity(ids.len());
        ids.par_iter()
            .map(|&i| {
                let [a, b, c] = soup.triangle(i as usize);
                let prepared = PreparedTriangle::new(a, b, c).unwrap_or(PreparedTriangle::NEVER);
                let flags = soup
                    .material
                    .get(i as usize)
                    .and_then(|&m| material_flags.get(m as usize))
                    .copied()
                    .unwrap_or(0);
                (prepared, flags)
            })
            .unzip_into_vecs(&mut triangles, &mut flags);
        steps.mark("triangle test data");
        Accel {
            kind,
            triangles,
            ids,
            flags,
            bvh,
            steps,
            preset: if preset == BvhPreset::Auto {
                BvhPreset::Medium
            } else {
                preset
            },
        }
    }

    /// The preset the BVH was built with (`Medium` for an unresolved `Auto`).
    pub fn preset(&self) -> BvhPreset {
        self.preset
    }

    /// The structure's kind.
    pub fn kind(&self) -> AccelKind {
        self.kind
    }

    /// Wall time of [`Accel::build`], including triangle preparation.
    pub fn build_time(&self) -> Duration {
        self.steps.total()
    }

    /// The steps of [`Accel::build`] with their times and the peak memory after each.
    pub fn build_steps(&self) -> &[Step] {
        self.steps.list()
    }

    /// Number of triangles the structure holds (leaf references, for a BVH with splits).
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Heap bytes: the triangles' test data in traversal order, their soup indices and flags,
    /// and the BVH's nodes.
    pub fn heap_bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(self.triangles.as_slice())
            + size_of_val(self.ids.as_slice())
            + size_of_val(self.flags.as_slice())
            + self
                .bvh
                .as_ref()
                .map_or(0, |b| size_of_val(b.nodes.as_slice()))
    }

    /// True when it holds nothing.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// The closest hit in (`ray.tmin`, `ray.tmax`), or `None`. Single-sided triangles seen from
    /// behind are not hit (glTF 2.0 §3.9.6: back-face culling).
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.intersect_filtered(ray, None)
    }

    /// [`Accel::intersect`] where a candidate hit on a MASK or BLEND triangle counts only if
    /// `accept(triangle, barycentric)` says so (alpha testing). Opaque triangles never call it.
    pub fn intersect_filtered(&self, ray: &Ray, accept: Option<&Accept>) -> Option<Hit> {
        by_cpu!(self.closest_hit_v3 | closest_hit(ray, accept))
    }

    #[cfg(target_arch = "x86_64")]
    crate::cpu::v3! {
        /// [`Accel::closest_hit`] for x86-64-v3 CPUs ([`crate::cpu`]).
        fn closest_hit_v3(&self, k: traverse::Avx2, ray: &Ray, accept: Option<&Accept>) -> Option<Hit> = closest_hit
    }

    /// The body of [`Accel::intersect_filtered`], compiled for each CPU level with its node
    /// test `k`.
    #[inline(always)]
    fn closest_hit<K: traverse::NodeTest>(
        &self,
        k: K,
        ray: &Ray,
        accept: Option<&Accept>,
    ) -> Option<Hit> {
        let closest = match &self.bvh {
            Some(bvh) => traverse::closest(k, self, bvh, ray, accept),
            None => linear::closest(self, ray, accept),
        }?;
        Some(self.hit_record(closest, ray))
    }

    /// What a closest-hit query returns for the best hit it found.
    #[inline(always)]
    fn hit_record(&self, closest: Closest, ray: &Ray) -> Hit {
        let hit = self.triangles[closest.slot].hit_at(ray, closest.t);
        Hit {
            triangle: self.ids[closest.slot],
            t: closest.t,
            barycentric: hit.barycentric,
            front: hit.front,
        }
    }

    /// True when anything blocks the ray within (`ray.tmin`, `ray.tmax`): the shadow-ray query,
    /// which stops at the first blocker it finds. Every triangle blocks light from both sides:
    /// `doubleSided` is about what the camera sees (as in rasterisers and Cycles), and a
    /// single-sided ground plane or leaf must still cast a shadow.
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.occluded_filtered(ray, None)
    }

    /// [`Accel::occluded`] where a MASK or BLEND triangle blocks only if `accept` says so.
    /// `accept` may be called for several candidates, in any order, before one blocks.
    pub fn occluded_filtered(&self, ray: &Ray, accept: Option<&Accept>) -> bool {
        by_cpu!(self.any_hit_v3 | any_hit(ray, accept))
    }

    #[cfg(target_arch = "x86_64")]
    crate::cpu::v3! {
        /// [`Accel::any_hit`] for x86-64-v3 CPUs ([`crate::cpu`]).
        fn any_hit_v3(&self, k: traverse::Avx2, ray: &Ray, accept: Option<&Accept>) -> bool = any_hit
    }

    /// The body of [`Accel::occluded_filtered`], compiled for each CPU level with its node
    /// test `k`.
    #[inline(always)]
    fn any_hit<K: traverse::NodeTest>(&self, k: K, ray: &Ray, accept: Option<&Accept>) -> bool {
        match &self.bvh {
            Some(bvh) => traverse::occluded(k, self, bvh, ray, accept),
            None => linear::occluded(self, ray, accept),
        }
    }

    /// The closest hit of each ray of `rays`, into `hits` (one answer a ray, as many as both
    /// hold): the answers of [`Accel::intersect_filtered`] ray by ray, found for eight
    /// consecutive rays at a time in one walk of the BVH (see [`Accel::occluded_many`]).
    pub fn intersect_many(&self, rays: &[Ray], accept: Option<&Accept>, hits: &mut [Option<Hit>]) {
        for (rays, hits) in rays
            .chunks(traverse::PACKET)
            .zip(hits.chunks_mut(traverse::PACKET))
        {
            let found = self.closest_packet(rays, accept);
            for ((hit, closest), ray) in hits.iter_mut().zip(found).zip(rays) {
                *hit = closest.map(|c| self.hit_record(c, ray));
            }
        }
    }

    /// [`Accel::intersect_many`] for at most [`traverse::PACKET`] rays.
    fn closest_packet(
        &self,
        rays: &[Ray],
        accept: Option<&Accept>,
    ) -> [Option<Closest>; traverse::PACKET] {
        by_cpu!(self.closest_hit_packet_v3 | closest_hit_packet(rays, accept))
    }

    #[cfg(target_arch = "x86_64")]
    crate::cpu::v3! {
        /// [`Accel::closest_hit_packet`] compiled for x86-64-v3.
        fn closest_hit_packet_v3(&self, k: traverse::Avx2, rays: &[Ray], accept: Option<&Accept>) -> [Option<Closest>; traverse::PACKET] = closest_hit_packet
    }

    #[inline(always)]
    fn closest_hit_packet<K: traverse::NodeTest>(
        &self,
        k: K,
        rays: &[Ray],
        accept: Option<&Accept>,
    ) -> [Option<Closest>; traverse::PACKET] {
        match &self.bvh {
            Some(bvh) => traverse::closest_packet(k, self, bvh, rays, accept),
            None => {
                let mut found = [None; traverse::PACKET];
                for (f, ray) in found.iter_mut().zip(rays) {
                    *f = linear::closest(self, ray, accept);
                }
                found
            }
        }
    }

    /// Whether anything blocks each ray of `rays`, into `blocked` (one answer a ray, as many
    /// as both hold): the answers of [`Accel::occluded_filtered`] ray by ray, found for eight
    /// consecutive rays at a time in one walk of the BVH. Faster than one ray at a time where
    /// neighbouring rays enter the same nodes (shadow rays from neighbouring pixels toward one
    /// light), since the rays' node tests then overlap instead of each waiting on the last.
    pub fn occluded_many(&self, rays: &[Ray], accept: Option<&Accept>, blocked: &mut [bool]) {
        for (rays, blocked) in rays
            .chunks(traverse::PACKET)
            .zip(blocked.chunks_mut(traverse::PACKET))
        {
            let bits = self.occluded_packet(rays, accept);
            for (i, b) in blocked.iter_mut().enumerate() {
                *b = bits >> i & 1 != 0;
            }
        }
    }

    /// [`Accel::occluded_many`] for at most [`traverse::PACKET`] rays: bit `i` for `rays[i]`.
    fn occluded_packet(&self, rays: &[Ray], accept: Option<&Accept>) -> u32 {
        by_cpu!(self.any_hit_packet_v3 | any_hit_packet(rays, accept))
    }

    #[cfg(target_arch = "x86_64")]
    crate::cpu::v3! {
        /// [`Accel::any_hit_packet`] compiled for x86-64-v3.
        fn any_hit_packet_v3(&self, k: traverse::Avx2, rays: &[Ray], accept: Option<&Accept>) -> u32 = any_hit_packet
    }

    #[inline(always)]
    fn any_hit_packet<K: traverse::NodeTest>(
        &self,
        k: K,
        rays: &[Ray],
        accept: Option<&Accept>,
    ) -> u32 {
        match &self.bvh {
            Some(bvh) => traverse::occluded_packet(k, self, bvh, rays, accept),
            None => rays
                .iter()
                .take(traverse::PACKET)
                .enumerate()
                .filter(|(_, ray)| linear::occluded(self, ray, accept))
                .fold(0, |bits, (i, _)| bits | 1 << i),
        }
    }

    /// The hit parameter of the triangle in `slot`, `f32::INFINITY` for a miss; with `cull`,
    /// the back faces of single-sided triangles are misses. The one place both structures
    /// test a triangle.
    #[inline(always)]
    fn test(&self, slot: usize, ray: &Ray, cull: bool, accept: Option<&Accept>) -> f32 {
        let t = self.triangles[slot].intersect_t(ray);
        self.confirm(slot, t, ray, cull, accept)
    }

    /// [`Accel::test`] of the triangle in `slot` whose plane-and-edges test gave `t`.
    #[inline(always)]
    fn confirm(&self, slot: usize, t: f32, ray: &Ray, cull: bool, accept: Option<&Accept>) -> f32 {
        if t == f32::INFINITY {
            return t;
        }
        let tri = &self.triangles[slot];
        if cull
            && self.flags[slot] & SINGLE_SIDED != 0
            && glam::Vec3A::from(tri.normal()).dot(ray.direction) > 0.0
        {
            return f32::INFINITY;
        }
        if let Some(accept) = accept {
            if self.flags[slot] & ALPHA_TESTED != 0
                && !accept(self.ids[slot], tri.hit_at(ray, t).barycentric)
            {
                return f32::INFINITY;
            }
        }
        t
    }
}

/// An alpha test: given a soup triangle index and the barycentric coordinates of a candidate
/// hit, whether the surface is there.
pub type Accept<'a> = dyn Fn(u32, Vec3) -> bool + 'a;

/// The best candidate found so far by a closest-hit query.
#[derive(Clone, Copy, Debug)]
struct Closest {
    t: f32,
    slot: usize,
}

impl Closest {
    /// Keeps the nearer of the current best and a new hit in `slot`; equal `t` goes to the
    /// lower soup index (`ids`), so the answer does not depend on traversal order. The soup
    /// indices are read only for a tie: a nearer hit needs no look-up (a cache miss on large
    /// models).
    #[inline(always)]
    fn offer(best: &mut Option<Closest>, t: f32, slot: usize, ids: &[u32]) {
        let better = match best {
            None => true,
            Some(b) => t < b.t || (t == b.t && ids[slot] < ids[b.slot]),
        };
        if better {
            *best = Some(Closest { t, slot });
        }
    }
}

#[cfg(test)]
mod tests;
