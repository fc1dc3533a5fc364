//! Traversal of the obvhs CWBVH with our own loops and node test.
//!
//! The node layout is obvhs 0.4's (MIT OR Apache-2.0, after Ylitie, Karras and Laine,
//! "Efficient Incoherent Ray Traversal on GPUs Through Compressed Wide BVHs", HPG 2017): eight
//! children a node, their boxes quantised to a byte a plane. The node test ([`NodeTest`])
//! gives every child the ray enters and where: [`Avx2`] tests all eight in one register,
//! [`Portable`] four at a time for CPUs without AVX2 (obvhs's own SSE test converts the planes
//! to floats a byte at a time and clamps box entry to a fixed 1e-4 instead of the ray's
//! `tmin`). Closest-hit queries ([`closest`]) visit children nearest entry first, as Embree's
//! single-ray traversal does, with each waiting node's entry distance on the stack; any-hit
//! queries ([`occluded`]) take them in storage order, in bit groups as obvhs's `traverse!`
//! macro does.

use super::{Accel, Accept, Closest};
use crate::geometry::{PreparedTriangle, Ray};
use glam::{UVec2, Vec3A, Vec4};
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::CwBvh;
use std::mem::{offset_of, MaybeUninit};

/// Direction components smaller than this in magnitude are replaced by it (with their sign)
/// before inverting, so inverse directions stay finite and a slab test never multiplies zero by
/// infinity. A ray leaning 1e-18 off an axis stays in a slab for 1e18 units of `t`, far past
/// any scene: the slab bounds computed from the clamped component are still on the same side.
const MIN_DIRECTION: f32 = 1e-18;

/// How far before `ray.tmin` boxes still count as entered. Both the box and the triangle
/// round the point where the ray meets a surface, differently; a ray starting on a surface
/// (`tmin` 0, as the linear scan sees it) must not lose the triangle it starts on because the
/// box's far side rounded to just behind the origin. This is the slack the earlier obvhs-based
/// traversal had (it tested boxes from a point 2e-4 behind the origin, clamped at 1e-4).
const BOX_TMIN_SLACK: f32 = 1e-4;

/// Byte offset of the near-plane bytes of x, y and z in a node (`child_min_x` ...): each axis
/// has eight min bytes followed by eight max bytes.
const PLANES: usize = offset_of!(CwBvhNode, child_min_x);
const _: () = assert!(
    offset_of!(CwBvhNode, child_max_x) == PLANES + 8
        && offset_of!(CwBvhNode, child_min_y) == PLANES + 16
        && offset_of!(CwBvhNode, child_min_z) == PLANES + 32
        && offset_of!(CwBvhNode, child_max_z) == PLANES + 40
        && std::mem::size_of::<CwBvhNode>() == PLANES + 48
);

/// What the node test needs of a ray, computed once per query.
#[derive(Clone, Copy, Debug)]
pub(super) struct NodeRay {
    origin: Vec3A,
    /// 1 / direction, with tiny components clamped ([`MIN_DIRECTION`]).
    inv_direction: Vec3A,
    /// Per axis, the byte offset in a node of the eight child planes the ray enters by (the
    /// min planes for a positive direction component, the max planes for a negative one), and
    /// of those it leaves by. The sign bit decides, so -0.0 goes with its -inverse.
    near: [usize; 3],
    far: [usize; 3],
    /// Box interval: boxes outside (`tmin`, `tmax`) are culled.
    tmin: f32,
    tmax: f32,
}

impl NodeRay {
    /// A ray whose near planes are the min ones and far planes the max ones on every axis
    /// (one going up all three axes), for [`planes_avx2`] to give a node's min and max planes.
    #[cfg(target_arch = "x86_64")]
    const MIN_MAX_PLANES: NodeRay = NodeRay {
        origin: Vec3A::ZERO,
        inv_direction: Vec3A::ONE,
        near: [PLANES, PLANES + 16, PLANES + 32],
        far: [PLANES + 8, PLANES + 24, PLANES + 40],
        tmin: 0.0,
        tmax: 0.0,
    };

    /// The node-test form of `ray`.
    #[inline]
    pub(super) fn new(ray: &Ray) -> NodeRay {
        let d = ray.direction;
        let safe = |x: f32| {
            if x.abs() < MIN_DIRECTION {
                MIN_DIRECTION.copysign(x)
            } else {
                x
            }
        };
        let inv_direction = Vec3A::ONE / Vec3A::new(safe(d.x), safe(d.y), safe(d.z));
        let negative = [
            d.x.is_sign_negative(),
            d.y.is_sign_negative(),
            d.z.is_sign_negative(),
        ];
        let plane = |axis: usize, max: bool| PLANES + 16 * axis + if max { 8 } else { 0 };
        NodeRay {
            origin: ray.origin,
            inv_direction,
            near: [0, 1, 2].map(|a| plane(a, negative[a])),
            far: [0, 1, 2].map(|a| plane(a, !negative[a])),
            tmin: ray.tmin - BOX_TMIN_SLACK,
            tmax: ray.tmax,
        }
    }

    /// Narrows the box interval's far end.
    #[inline(always)]
    pub(super) fn set_tmax(&mut self, tmax: f32) {
        self.tmax = tmax;
    }

    /// The ray in the node's quantised grid: `t = q · scale + offset` per axis, q the 0-255
    /// plane byte (obvhs `intersect_ray_simd`'s `adj_ray_dir_inv` and `adj_ray_origin`).
    #[inline(always)]
    fn in_grid(&self, node: &CwBvhNode) -> (Vec3A, Vec3A) {
        // The grid step per axis is 2^(e - 127): the exponent byte shifted into a float.
        let extent = Vec3A::new(
            f32::from_bits(u32::from(node.e[0]) << 23),
            f32::from_bits(u32::from(node.e[1]) << 23),
            f32::from_bits(u32::from(node.e[2]) << 23),
        );
        (
            extent * self.inv_direction,
            (Vec3A::from(node.p) - self.origin) * self.inv_direction,
        )
    }
}

/// A CWBVH node test.
pub(super) trait NodeTest: Copy {
    /// Every child `ray` enters (bit `i` for child `i`, leaf or internal, in storage order),
    /// with the distance at which it enters each in lane `i` of `enter` (the box's near side,
    /// clamped to the ray's box interval; the other lanes hold anything).
    fn entries(self, node: &CwBvhNode, ray: &NodeRay, enter: &mut [f32; 8]) -> u32;

    /// [`PreparedTriangle::intersect_t`] of two triangles of a leaf.
    #[inline(always)]
    fn pair(self, a: &PreparedTriangle, b: &PreparedTriangle, ray: &Ray) -> (f32, f32) {
        (a.intersect_t(ray), b.intersect_t(ray))
    }

    /// [`NodeTest::entries`] of `node` for each ray of `waiting` (bit r for `node_rays[r]`),
    /// each ray's entry distances into `enter[r]`: row r of an 8x8 bit matrix (byte r) holds
    /// the children ray r enters; and the children any of them enters. `one_octant`: every
    /// ray's direction has the same signs.
    #[inline(always)]
    fn packet_rows(
        self,
        node: &CwBvhNode,
        node_rays: &[NodeRay; PACKET],
        waiting: u32,
        enter: &mut [[f32; 8]; PACKET],
        _one_octant: bool,
    ) -> (u64, u32) {
        rows_ray_by_ray(self, node, node_rays, waiting, enter)
    }
}

/// [`NodeTest::packet_rows`] as [`NodeTest::entries`] of each ray in turn.
#[inline(always)]
fn rows_ray_by_ray<K: NodeTest>(
    k: K,
    node: &CwBvhNode,
    node_rays: &[NodeRay; PACKET],
    waiting: u32,
    enter: &mut [[f32; 8]; PACKET],
) -> (u64, u32) {
    let (mut rows, mut any) = (0u64, 0u32);
    let mut bits = waiting;
    while bits != 0 {
        let r = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        let entered = k.entries(node, &node_rays[r], &mut enter[r]);
        rows |= u64::from(entered) << (8 * r);
        any |= entered;
    }
    (rows, any)
}

/// Four children at a time with glam's `Vec4` (SSE2 on x86-64, scalar elsewhere): the test for
/// CPUs without AVX2, and the reference [`Avx2`] is tested against.
#[derive(Clone, Copy, Debug)]
pub(super) struct Portable;

impl NodeTest for Portable {
    #[inline(always)]
    fn entries(self, node: &CwBvhNode, ray: &NodeRay, enter: &mut [f32; 8]) -> u32 {
        portable_entries(node, ray, false, enter)
    }
}

/// [`Portable`]'s slab test of all eight children, four at a time: the children entered and
/// where (see [`NodeTest::entries`]). With `fused`, each `q · scale + offset` is rounded once
/// (as [`Avx2`]'s fused multiply-add does) instead of twice: the reference the AVX2 test is
/// held to. Without FMA hardware `mul_add` is a library call, too slow for the fallback.
#[inline(always)]
fn portable_entries(node: &CwBvhNode, ray: &NodeRay, fused: bool, out: &mut [f32; 8]) -> u32 {
    let (scale, offset) = ray.in_grid(node);
    let bytes = bytemuck::bytes_of(node);
    let mut mask = 0;
    for half in [0, 4] {
        let q = |at: usize| four_bytes(&bytes[at + half..at + half + 4]);
        let slab = |axis: usize| {
            let (s, o) = (Vec4::splat(scale[axis]), Vec4::splat(offset[axis]));
            let t = |q: Vec4| if fused { q.mul_add(s, o) } else { q * s + o };
            (t(q(ray.near[axis])), t(q(ray.far[axis])))
        };
        let (nx, fx) = slab(0);
        let (ny, fy) = slab(1);
        let (nz, fz) = slab(2);
        let enter = nx.max(ny).max(nz.max(Vec4::splat(ray.tmin)));
        let leave = fx.min(fy).min(fz.min(Vec4::splat(ray.tmax)));
        mask |= enter.cmple(leave).bitmask() << half;
        out[half..half + 4].copy_from_slice(&enter.to_array());
    }
    mask
}

/// Four bytes as four floats: SSE2's integer unpacks and one conversion on x86-64 (converting
/// one byte at a time was most of the portable test's time), one at a time elsewhere.
#[inline(always)]
fn four_bytes(b: &[u8]) -> Vec4 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        let word = i32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        // SAFETY: SSE2 is part of x86-64; these only move and convert register contents.
        unsafe {
            let zero = _mm_setzero_si128();
            let wide = _mm_unpacklo_epi16(_mm_unpacklo_epi8(_mm_cvtsi32_si128(word), zero), zero);
            Vec4::from(_mm_cvtepi32_ps(wide))
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    Vec4::new(b[0] as f32, b[1] as f32, b[2] as f32, b[3] as f32)
}

/// [`portable_entries`] with fused multiply-adds, for tests.
#[cfg(test)]
pub(super) fn fused_entries(node: &CwBvhNode, ray: &NodeRay, enter: &mut [f32; 8]) -> u32 {
    portable_entries(node, ray, true, enter)
}

/// All eight children in one AVX2 register. Only made where the CPU has AVX2 and FMA
/// ([`Avx2::new`]), so its test may use them.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
pub(super) struct Avx2(());

#[cfg(target_arch = "x86_64")]
impl Avx2 {
    /// The test, when this CPU runs x86-64-v3 code.
    pub(super) fn new() -> Option<Avx2> {
        crate::cpu::has_v3().then_some(Avx2(()))
    }
}

#[cfg(target_arch = "x86_64")]
impl NodeTest for Avx2 {
    #[inline(always)]
    fn entries(self, node: &CwBvhNode, ray: &NodeRay, enter: &mut [f32; 8]) -> u32 {
        // SAFETY: an `Avx2` exists only where the CPU has AVX2 (`Avx2::new`).
        unsafe { entries_avx2(node, ray, enter) }
    }

    #[inline(always)]
    fn pair(self, a: &PreparedTriangle, b: &PreparedTriangle, ray: &Ray) -> (f32, f32) {
        // SAFETY: an `Avx2` exists only where the CPU has AVX2, hence AVX (`Avx2::new`).
        unsafe { PreparedTriangle::intersect_t_pair(a, b, ray) }
    }

    #[inline(always)]
    fn packet_rows(
        self,
        node: &CwBvhNode,
        node_rays: &[NodeRay; PACKET],
        waiting: u32,
        enter: &mut [[f32; 8]; PACKET],
        one_octant: bool,
    ) -> (u64, u32) {
        // SAFETY: an `Avx2` exists only where the CPU has AVX2 and FMA (`Avx2::new`); the
        // shared planes of one octant are used only when every ray has them.
        unsafe {
            if one_octant {
                packet_rows_avx2::<false>(node, node_rays, waiting, enter)
            } else {
                packet_rows_avx2::<true>(node, node_rays, waiting, enter)
            }
        }
    }
}

/// [`Avx2`]'s slab test: where the ray enters each child's box and whether it does (all
/// lanes set). The arithmetic is [`Portable`]'s lane for lane, but with fused multiply-adds
/// (3% more rays a second on the bunny; the boxes' margins absorb either rounding), so it
/// gives [`fused_entries`]'s answer.
///
/// # Safety
/// The CPU must have AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn slabs_avx2(
    node: &CwBvhNode,
    ray: &NodeRay,
) -> (std::arch::x86_64::__m256, std::arch::x86_64::__m256) {
    // SAFETY: the caller's CPU has AVX2 and FMA.
    unsafe {
        let head = node_head(node);
        let planes = planes_avx2(node, ray);
        slabs_of_planes_avx2::<false>(head, grid_step(head), planes, ray)
    }
}

/// The first 16 bytes of `node`: its origin `p`, then its three exponent bytes and `imask`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn node_head(node: &CwBvhNode) -> std::arch::x86_64::__m128 {
    // SAFETY: SSE is part of x86-64; the node is 80 bytes; the load is unaligned.
    unsafe { std::arch::x86_64::_mm_loadu_ps((node as *const CwBvhNode).cast::<f32>()) }
}

/// A node's grid step per axis from its head ([`node_head`]): 2^(e - 127), the exponent byte
/// shifted into a float's exponent.
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn grid_step(head: std::arch::x86_64::__m128) -> std::arch::x86_64::__m128 {
    use std::arch::x86_64::*;
    let exponents = _mm_cvtepu8_epi32(_mm_srli_si128::<12>(_mm_castps_si128(head)));
    _mm_castsi128_ps(_mm_slli_epi32::<23>(exponents))
}

/// The eight children's planes `ray` enters and leaves by, as floats: near x, far x, near y,
/// far y, near z, far z.
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn planes_avx2(node: &CwBvhNode, ray: &NodeRay) -> [std::arch::x86_64::__m256; 6] {
    use std::arch::x86_64::*;
    let base = (node as *const CwBvhNode).cast::<u8>();
    // Eight plane bytes at `at` as eight floats.
    let planes = |at: usize| {
        // SAFETY: `at` is one of `NodeRay`'s plane offsets, eight bytes inside the node (the
        // layout is asserted above); the load is unaligned.
        _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(unsafe {
            _mm_loadl_epi64(base.add(at).cast::<__m128i>())
        }))
    };
    [
        planes(ray.near[0]),
        planes(ray.far[0]),
        planes(ray.near[1]),
        planes(ray.far[1]),
        planes(ray.near[2]),
        planes(ray.far[2]),
    ]
}

/// The slab test of `ray` on a node's `planes` ([`planes_avx2`] of the ray, or of another ray
/// of its octant) and `head` ([`node_head`]): where the ray enters each child's box and
/// whether it does (all lanes set). `MIN_MAX`: the planes are the min and max ones
/// ([`NodeRay::MIN_MAX_PLANES`]), whatever the ray's octant; the near and far distances are
/// then the lesser and the greater of each pair's, which are the same values (rounding is
/// monotonic, so with a positive scale the min plane's distance is never above the max
/// plane's, and with a negative one never below).
///
/// # Safety
/// The CPU must have AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn slabs_of_planes_avx2<const MIN_MAX: bool>(
    head: std::arch::x86_64::__m128,
    extent: std::arch::x86_64::__m128,
    planes: [std::arch::x86_64::__m256; 6],
    ray: &NodeRay,
) -> (std::arch::x86_64::__m256, std::arch::x86_64::__m256) {
    use std::arch::x86_64::*;
    // `NodeRay::in_grid` from the node's head and grid step ([`grid_step`]): the same
    // operations on the same values.
    let inv: __m128 = ray.inv_direction.into();
    let origin: __m128 = ray.origin.into();
    let scale = _mm_mul_ps(extent, inv);
    let offset = _mm_mul_ps(_mm_sub_ps(head, origin), inv);
    // Both in both halves, to splat a lane with an in-lane permute.
    let scale = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(scale), scale);
    let offset = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(offset), offset);
    macro_rules! slab {
        ($axis:expr, $lane:expr) => {{
            let s = _mm256_permute_ps::<$lane>(scale);
            let o = _mm256_permute_ps::<$lane>(offset);
            let near = _mm256_fmadd_ps(planes[2 * $axis], s, o);
            let far = _mm256_fmadd_ps(planes[2 * $axis + 1], s, o);
            if MIN_MAX {
                (_mm256_min_ps(near, far), _mm256_max_ps(near, far))
            } else {
                (near, far)
            }
        }};
    }
    let (nx, fx) = slab!(0, 0b00_00_00_00);
    let (ny, fy) = slab!(1, 0b01_01_01_01);
    let (nz, fz) = slab!(2, 0b10_10_10_10);
    let enter = _mm256_max_ps(
        _mm256_max_ps(nx, ny),
        _mm256_max_ps(nz, _mm256_set1_ps(ray.tmin)),
    );
    let leave = _mm256_min_ps(
        _mm256_min_ps(fx, fy),
        _mm256_min_ps(fz, _mm256_set1_ps(ray.tmax)),
    );
    (enter, _mm256_cmp_ps::<_CMP_LE_OQ>(enter, leave))
}

/// [`Avx2`]'s [`NodeTest::packet_rows`]: the node's planes converted to floats once for the
/// packet, not once for each ray. For rays of one octant (not `MIXED`) they are the planes its
/// first ray enters and leaves by ([`planes_avx2`]); for rays of several (`MIXED`) the min and
/// max planes, each ray's slab the lesser and the greater of their distances (choosing planes
/// ray by ray would mispredict). Either way each ray's slabs are [`slabs_avx2`]'s, bit for
/// bit ([`slabs_of_planes_avx2`]).
///
/// # Safety
/// The CPU must have AVX2 and FMA; unless `MIXED`, every ray of `waiting` must enter by the
/// planes of the first.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn packet_rows_avx2<const MIXED: bool>(
    node: &CwBvhNode,
    node_rays: &[NodeRay; PACKET],
    waiting: u32,
    enter: &mut [[f32; 8]; PACKET],
) -> (u64, u32) {
    use std::arch::x86_64::*;
    let head = node_head(node);
    // SAFETY: the caller's CPU has AVX2.
    let extent = unsafe { grid_step(head) };
    let first = &node_rays[waiting.trailing_zeros() as usize];
    // SAFETY: the caller's CPU has AVX2.
    let planes = unsafe {
        if MIXED {
            planes_avx2(node, &NodeRay::MIN_MAX_PLANES)
        } else {
            planes_avx2(node, first)
        }
    };
    let (mut rows, mut any) = (0u64, 0u32);
    let mut bits = waiting;
    while bits != 0 {
        let r = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        // SAFETY: the caller's CPU has AVX2 and FMA.
        let (near, hit) =
            unsafe { slabs_of_planes_avx2::<MIXED>(head, extent, planes, &node_rays[r]) };
        // SAFETY: `enter[r]` is eight floats; the store is unaligned.
        unsafe { _mm256_storeu_ps(enter[r].as_mut_ptr(), near) };
        let entered = _mm256_movemask_ps(hit) as u32;
        rows |= u64::from(entered) << (8 * r);
        any |= entered;
    }
    (rows, any)
}

/// [`Avx2`]'s [`NodeTest::entries`].
///
/// # Safety
/// The CPU must have AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn entries_avx2(node: &CwBvhNode, ray: &NodeRay, out: &mut [f32; 8]) -> u32 {
    use std::arch::x86_64::*;
    // SAFETY: the caller's CPU has AVX2 and FMA.
    let (enter, hit) = unsafe { slabs_avx2(node, ray) };
    // SAFETY: `out` is eight floats; the store is unaligned.
    unsafe { _mm256_storeu_ps(out.as_mut_ptr(), enter) };
    _mm256_movemask_ps(hit) as u32
}

/// The traversal stack: groups of children still to visit. A wide BVH is shallow (obvhs keeps
/// 32 entries and overwrites the last when full); this holds 64 and spills beyond that to the
/// heap rather than lose a group, so a pathologically deep tree is slow, never wrong.
///
/// The entries start uninitialised and live in the caller's frame ([`Entries`]), apart from
/// `len`: with the array beside the zeroed `len` in one struct, LLVM merged the two into a
/// 520-byte `memset` call per ray (the Cornell box's rays are short enough for that to show).
struct Stack<'a, T> {
    entries: &'a mut Entries<T>,
    len: usize,
    spill: Vec<T>,
}

/// [`Stack`]'s fixed entries.
type Entries<T> = [MaybeUninit<T>; 64];

impl<'a, T: Copy> Stack<'a, T> {
    #[inline(always)]
    fn new(entries: &'a mut Entries<T>) -> Stack<'a, T> {
        Stack {
            entries,
            len: 0,
            spill: Vec::new(),
        }
    }

    #[inline(always)]
    fn push(&mut self, group: T) {
        if let Some(entry) = self.entries.get_mut(self.len) {
            entry.write(group);
            self.len += 1;
        } else {
            self.spill.push(group);
        }
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<T> {
        // The spill holds groups only while the array is full (it takes pushes only then, and
        // the array shrinks only once it is empty).
        if self.len == self.entries.len() {
            if let Some(group) = self.spill.pop() {
                return Some(group);
            }
        }
        self.len = self.len.checked_sub(1)?;
        // SAFETY: entries below `len` were written by `push` (`len` only grows there, by one,
        // after the write).
        Some(unsafe { self.entries[self.len].assume_init() })
    }
}

/// Triangles (64 bytes each) from which [`prefetch_leaves`] asks for them early: 8 MB, more
/// than a core's L2 and a fair share of a shared L3. Below it they mostly come from cache, and
/// the loop over the leaves' counts costs more than it hides (its branches mispredict).
const PREFETCH_FROM: usize = 1 << 17;

/// Asks for the triangles of every leaf the ray enters before testing the first: on large
/// models they come from memory, and asked for together their fetches overlap.
#[inline(always)]
fn prefetch_leaves(node: &CwBvhNode, mut leaves: u32, triangles: &[PreparedTriangle]) {
    if triangles.len() < PREFETCH_FROM {
        return;
    }
    #[cfg(target_arch = "x86_64")]
    while leaves != 0 {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let meta = node.child_meta[leaves.trailing_zeros() as usize];
        leaves &= leaves - 1;
        let first = (node.primitive_base_idx + u32::from(meta & 0x1f)) as usize;
        let at = triangles.as_ptr().wrapping_add(first).cast::<i8>();
        for k in 0..u32::from(meta >> 5).count_ones() as usize {
            // SAFETY: a prefetch never faults and changes nothing the program can observe, so
            // any address is sound.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(at.wrapping_add(64 * k)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (node, leaves, triangles);
}

/// A float's bits as an unsigned integer of the same order (negative floats below positive
/// ones, -0.0 just below +0.0), so that a node and its entry distance sort as one `u64`.
#[inline(always)]
fn ordered_bits(x: f32) -> u32 {
    let bits = x.to_bits();
    if bits & 0x8000_0000 == 0 {
        bits | 0x8000_0000
    } else {
        !bits
    }
}

/// The closest hit: every leaf the ray enters before its current best.
///
/// Children are visited nearest first by where the ray enters their boxes (as Embree's
/// single-ray traversal sorts them), not by the ray's octant as [`walk`] does: a stack entry
/// is a node with its entry distance, so once a hit is found, nodes waiting beyond it are
/// dropped when popped without loading them, and leaves beyond it are not tested.
#[inline(always)]
pub(super) fn closest<K: NodeTest>(
    k: K,
    accel: &Accel,
    bvh: &CwBvh,
    ray: &Ray,
    accept: Option<&Accept>,
) -> Option<Closest> {
    if bvh.nodes.is_empty() {
        return None;
    }
    let mut best: Option<Closest> = None;
    let mut local = *ray;
    let mut node_ray = NodeRay::new(ray);
    // Entries: the entry distance's `ordered_bits` above, the node's index below.
    let mut entries: Entries<u64> = [MaybeUninit::uninit(); 64];
    let mut stack = Stack::new(&mut entries);
    // Nodes entered beyond this (`ordered_bits` of `local.tmax`; + 0.0 makes -0.0 +0.0,
    // which keeps a box entered at -0.0 and at +0.0 alike) hold nothing nearer.
    let mut cull = ordered_bits(local.tmax + 0.0);
    let mut current = 0u32;
    let mut enter = [0.0f32; 8];
    loop {
        let node = &bvh.nodes[current as usize];
        let entered = k.entries(node, &node_ray, &mut enter);
        let imask = u32::from(node.imask);
        let leaves = entered & !imask;
        prefetch_leaves(node, leaves, &accel.triangles);
        let mut hit_here = false;
        let mut leaves = leaves;
        while leaves != 0 {
            let child = leaves.trailing_zeros() as usize;
            leaves &= leaves - 1;
            // A hit in an earlier leaf of this node may already be nearer than this box.
            // (Gathering the node's leaves and testing them two at a time across leaves, as
            // `occluded` does, loses this: 4% fewer camera rays a second.)
            if ordered_bits(enter[child]) > cull {
                continue;
            }
            // The leaf's first primitive's offset in the low five bits, its count in unary in
            // the top three.
            let meta = node.child_meta[child];
            let first = (node.primitive_base_idx + u32::from(meta & 0x1f)) as usize;
            // The leaf's triangles, the first two as a pair. The second of a pair is tested
            // against the `tmax` from before the first's hit, not after it; when it hits
            // between the two it is farther than the best, which `offer` keeps: the answer
            // is the same.
            let found = leaf_hits(k, accel, first, meta, &local);
            for (slot, t) in (first..).zip(found) {
                let t = accel.confirm(slot, t, &local, true, accept);
                if t < f32::INFINITY {
                    Closest::offer(&mut best, t, slot, &accel.ids);
                    if let Some(b) = best {
                        // Keep hits at exactly the best t (for the tie rule) but cull
                        // everything farther: the next float up is the tightest such bound.
                        local.tmax = b.t.next_up();
                        node_ray.set_tmax(local.tmax);
                        cull = ordered_bits(local.tmax + 0.0);
                        hit_here = true;
                    }
                }
            }
        }
        let mut inner = entered & imask;
        if hit_here {
            // A leaf of this node hit: children entered beyond that hit hold nothing nearer.
            let mut far = inner;
            while far != 0 {
                let child = far.trailing_zeros();
                far &= far - 1;
                if ordered_bits(enter[child as usize]) > cull {
                    inner &= !(1 << child);
                }
            }
        }
        // Internal children are stored in slot order from `child_base_idx`.
        let index = |child: u32| node.child_base_idx + (imask & !(u32::MAX << child)).count_ones();
        let key = |child: u32| {
            u64::from(ordered_bits(enter[child as usize])) << 32 | u64::from(index(child))
        };
        match inner.count_ones() {
            0 => loop {
                let Some(key) = stack.pop() else {
                    return best;
                };
                if (key >> 32) as u32 <= cull {
                    current = key as u32;
                    break;
                }
            },
            1 => current = index(inner.trailing_zeros()),
            2 => {
                let (a, b) = (inner.trailing_zeros(), 31 - inner.leading_zeros());
                let (near, far) = if enter[b as usize] < enter[a as usize] {
                    (b, a)
                } else {
                    (a, b)
                };
                stack.push(key(far));
                current = index(near);
            }
            count => {
                // Insertion sort, nearest first; the rest wait farthest deepest.
                let count = count as usize;
                let mut keys = [0u64; 8];
                for slot in keys.iter_mut().take(count) {
                    *slot = key(inner.trailing_zeros());
                    inner &= inner - 1;
                }
                for i in 1..count {
                    let key = keys[i];
                    let mut j = i;
                    while j > 0 && keys[j - 1] > key {
                        keys[j] = keys[j - 1];
                        j -= 1;
                    }
                    keys[j] = key;
                }
                for &key in keys[1..count].iter().rev() {
                    stack.push(key);
                }
                current = keys[0] as u32;
            }
        }
    }
}

/// The hit parameters (`f32::INFINITY` for a miss) of a leaf's triangles from slot `first`
/// on, as many as `meta` counts (one to three, in unary in its top three bits), the first two
/// as a pair; the rest of the three stay infinite.
#[inline(always)]
fn leaf_hits<K: NodeTest>(k: K, accel: &Accel, first: usize, meta: u8, ray: &Ray) -> [f32; 3] {
    let mut found = [f32::INFINITY; 3];
    match &accel.triangles[first..first + (meta >> 5).count_ones() as usize] {
        [a] => found[0] = a.intersect_t(ray),
        [a, b, rest @ ..] => {
            (found[0], found[1]) = k.pair(a, b, ray);
            if let [c] = rest {
                found[2] = c.intersect_t(ray);
            }
        }
        [] => {}
    }
    found
}

/// Whether anything blocks the ray: stops at the first blocker.
///
/// Any blocker will do, so children are taken in storage order, without sorting: a group of
/// internal children still to visit is a `UVec2`, their first node's index and the children
/// entered (bits 0-7, the highest visited first) with their parent's `imask` (bits 8-15),
/// which counts the internal children stored before a given one. A node's leaves are tested
/// before its children are visited.
#[inline(always)]
pub(super) fn occluded<K: NodeTest>(
    k: K,
    accel: &Accel,
    bvh: &CwBvh,
    ray: &Ray,
    accept: Option<&Accept>,
) -> bool {
    if bvh.nodes.is_empty() {
        return false;
    }
    let node_ray = NodeRay::new(ray);
    let mut entries: Entries<UVec2> = [MaybeUninit::uninit(); 64];
    let mut stack = Stack::new(&mut entries);
    let mut enter = [0.0f32; 8];
    // The root: a group of one child at index 0.
    let mut group = UVec2::new(0, 1);
    let mut found = Found::new();
    loop {
        if group.y & 0xff == 0 {
            match stack.pop() {
                Some(g) => group = g,
                None => return false,
            }
        }
        let slot = 31 - (group.y & 0xff).leading_zeros();
        let mut rest = group;
        rest.y &= !(1 << slot);
        if rest.y & 0xff != 0 {
            stack.push(rest);
        }
        let relative = ((group.y >> 8) & !(u32::MAX << slot)).count_ones();
        let node = &bvh.nodes[(group.x + relative) as usize];
        let entered = k.entries(node, &node_ray, &mut enter);
        let imask = u32::from(node.imask);
        group = UVec2::new(node.child_base_idx, entered & imask | imask << 8);
        let leaves = entered & !imask;
        prefetch_leaves(node, leaves, &accel.triangles);
        // Every triangle of the leaves entered, two at a time across leaves (4-7% more shadow
        // rays a second on the bunny and DamagedHelmet than leaf by leaf).
        found.clear();
        found.gather(node, leaves);
        found.test(k, accel, ray);
        if found
            .slots()
            .iter()
            .zip(found.hits())
            .any(|(&slot, &t)| accel.confirm(slot as usize, t, ray, false, accept) < f32::INFINITY)
        {
            return true;
        }
    }
}

/// Rays in one [`occluded_packet`] query: one bit each in a byte.
pub(super) const PACKET: usize = 8;

/// Whether anything blocks each of up to [`PACKET`] rays (bit `i` for `rays[i]`): the
/// answers [`occluded`] gives ray by ray, found by walking the tree once for all of them.
///
/// A stack entry is a node with the rays that enter it (a byte of ray bits beside the node's
/// index). At a node each of those rays gets its own node test, and a child is visited by the
/// rays that enter it, so every ray tests exactly the nodes and leaves it would alone, in the
/// same order, until it is found blocked (then it leaves every waiting entry). What the rays
/// share is the walk: a node's tests for several rays do not wait on one another, so they
/// overlap where a lone ray waits on each node's load and test before the next, and the
/// node and its leaves' triangles come into cache once for the packet. Coherent rays (shadow
/// rays from neighbouring pixels toward one light) mostly enter the same nodes.
#[inline(always)]
pub(super) fn occluded_packet<K: NodeTest>(
    k: K,
    accel: &Accel,
    bvh: &CwBvh,
    rays: &[Ray],
    accept: Option<&Accept>,
) -> u32 {
    let rays = &rays[..rays.len().min(PACKET)];
    if bvh.nodes.is_empty() || rays.is_empty() {
        return 0;
    }
    let mut node_rays = [NodeRay::new(&rays[0]); PACKET];
    for (node_ray, ray) in node_rays.iter_mut().zip(rays) {
        *node_ray = NodeRay::new(ray);
    }
    // Rays not yet found blocked.
    let one_octant = one_octant(&node_rays[..rays.len()]);
    let mut open = !(u32::MAX << rays.len());
    let mut entries: Entries<u64> = [MaybeUninit::uninit(); 64];
    let mut stack = Stack::new(&mut entries);
    let mut enter = [[0.0f32; 8]; PACKET];
    // Entries: the node's index above, its rays below.
    let mut next = u64::from(open);
    loop {
        let waiting = next as u32 & open;
        if waiting == 0 {
            match stack.pop() {
                Some(entry) => next = entry,
                None => break,
            }
            continue;
        }
        let node = &bvh.nodes[(next >> 8) as usize];
        let (columns, any) = packet_entries(k, node, &node_rays, waiting, &mut enter, one_octant);
        let imask = u32::from(node.imask);
        let leaves = any & !imask;
        prefetch_leaves(node, leaves, &accel.triangles);
        for (_, first, meta, rays_in) in packet_leaves(node, leaves, columns) {
            let mut bits = rays_in & open;
            while bits != 0 {
                let r = bits.trailing_zeros();
                bits &= bits - 1;
                let ray = &rays[r as usize];
                let found = leaf_hits(k, accel, first, meta, ray);
                if (first..)
                    .zip(found)
                    .any(|(slot, t)| accel.confirm(slot, t, ray, false, accept) < f32::INFINITY)
                {
                    open &= !(1 << r);
                }
            }
        }
        if open == 0 {
            break;
        }
        let mut inner = any & imask;
        next = 0;
        while inner != 0 {
            let child = inner.trailing_zeros();
            inner &= inner - 1;
            // Internal children are stored in slot order from `child_base_idx`.
            let index = node.child_base_idx + (imask & !(u32::MAX << child)).count_ones();
            let entry = u64::from(index) << 8 | (columns >> (8 * child)) & 0xff;
            if next != 0 {
                stack.push(next);
            }
            next = entry;
        }
    }
    !open & !(u32::MAX << rays.len())
}

/// A stack entry of [`closest_packet`]: a node, the rays that enter it, and the nearest of
/// their entry distances.
#[derive(Clone, Copy)]
struct Waiting {
    /// `ordered_bits` of the nearest entry distance above, the node's index below.
    key: u64,
    /// The rays that enter the node (one bit each).
    rays: u32,
}

/// The closest hit of each of up to [`PACKET`] rays (the answers [`closest`] gives ray by
/// ray), found by walking the tree once for all of them, as [`occluded_packet`] does.
///
/// A ray goes on to a child only where it enters the child's box before its own best hit, so
/// it tests no triangle [`closest`] would skip for it. Children are visited nearest first by
/// the nearest entry among the rays that go on to them, and a waiting node is dropped, when
/// popped, for the rays whose best hit is nearer than that entry: for every ray the leaves
/// tested are a superset of those [`closest`] tests, all of them before the ray's best hit, so
/// with the tie rule of [`Closest::offer`] the answers are the same.
#[inline(always)]
pub(super) fn closest_packet<K: NodeTest>(
    k: K,
    accel: &Accel,
    bvh: &CwBvh,
    rays: &[Ray],
    accept: Option<&Accept>,
) -> [Option<Closest>; PACKET] {
    let mut best: [Option<Closest>; PACKET] = [None; PACKET];
    let n = rays.len().min(PACKET);
    if bvh.nodes.is_empty() || n == 0 {
        return best;
    }
    let mut local = [rays[0]; PACKET];
    local[..n].copy_from_slice(&rays[..n]);
    let mut node_rays = local.map(|ray| NodeRay::new(&ray));
    let one_octant = one_octant(&node_rays[..n]);
    // Per ray: nodes entered beyond this hold nothing nearer (see `closest`).
    let mut cull = local.map(|ray| ordered_bits(ray.tmax + 0.0));
    let mut entries: Entries<Waiting> = [MaybeUninit::uninit(); 64];
    let mut stack = Stack::new(&mut entries);
    let mut enter = [[0.0f32; 8]; PACKET];
    let mut current = 0u32;
    let mut waiting = !(u32::MAX << n);
    loop {
        let node = &bvh.nodes[current as usize];
        let (columns, any) = packet_entries(k, node, &node_rays, waiting, &mut enter, one_octant);
        let imask = u32::from(node.imask);
        let leaves = any & !imask;
        prefetch_leaves(node, leaves, &accel.triangles);
        for (child, first, meta, rays_in) in packet_leaves(node, leaves, columns) {
            let mut bits = rays_in;
            while bits != 0 {
                let r = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                // A hit of this ray in an earlier leaf may already be nearer than this box.
                if ordered_bits(enter[r][child]) > cull[r] {
                    continue;
                }
                let found = leaf_hits(k, accel, first, meta, &local[r]);
                for (slot, t) in (first..).zip(found) {
                    let t = accel.confirm(slot, t, &local[r], true, accept);
                    if t < f32::INFINITY {
                        Closest::offer(&mut best[r], t, slot, &accel.ids);
                        if let Some(b) = best[r] {
                            local[r].tmax = b.t.next_up();
                            node_rays[r].set_tmax(local[r].tmax);
                            cull[r] = ordered_bits(local[r].tmax + 0.0);
                        }
                    }
                }
            }
        }
        // The internal children with the rays that go on to each (those entering it before
        // their best hit) and the nearest of their entries.
        let mut keys = [0u64; 8];
        let mut masks = [0u32; 8];
        let mut count = 0;
        let mut inner = any & imask;
        while inner != 0 {
            let child = inner.trailing_zeros();
            inner &= inner - 1;
            let mut bits = (columns >> (8 * child)) as u32 & 0xff;
            let (mut rays_in, mut nearest) = (0u32, u32::MAX);
            while bits != 0 {
                let r = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let at = ordered_bits(enter[r][child as usize]);
                if at <= cull[r] {
                    rays_in |= 1 << r;
                    nearest = nearest.min(at);
                }
            }
            if rays_in != 0 {
                // Internal children are stored in slot order from `child_base_idx`.
                let index = node.child_base_idx + (imask & !(u32::MAX << child)).count_ones();
                keys[count] = u64::from(nearest) << 32 | u64::from(index);
                masks[count] = rays_in;
                count += 1;
            }
        }
        if count == 0 {
            loop {
                let Some(w) = stack.pop() else {
                    return best;
                };
                let at = (w.key >> 32) as u32;
                let mut bits = w.rays;
                waiting = 0;
                while bits != 0 {
                    let r = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    if at <= cull[r] {
                        waiting |= 1 << r;
                    }
                }
                if waiting != 0 {
                    current = w.key as u32;
                    break;
                }
            }
            continue;
        }
        // Insertion sort, nearest first; the rest wait farthest deepest.
        for i in 1..count {
            let (key, mask) = (keys[i], masks[i]);
            let mut j = i;
            while j > 0 && keys[j - 1] > key {
                keys[j] = keys[j - 1];
                masks[j] = masks[j - 1];
                j -= 1;
            }
            keys[j] = key;
            masks[j] = mask;
        }
        for i in (1..count).rev() {
            stack.push(Waiting {
                key: keys[i],
                rays: masks[i],
            });
        }
        current = keys[0] as u32;
        waiting = masks[0];
    }
}

/// Whether every ray enters a node's boxes by the same planes (their directions have the same
/// signs), as the camera rays of neighbouring pixels and the shadow rays toward one light
/// mostly do.
pub(super) fn one_octant(node_rays: &[NodeRay]) -> bool {
    node_rays.iter().all(|r| r.near == node_rays[0].near)
}

/// The node test of `node` for each ray of `waiting` (bit r for `node_rays[r]`), each ray's
/// entry distances into `enter[r]`: the rays that enter each child (byte c for child c) and
/// the children any of them enters. The rays' tests do not depend on one another, so they
/// overlap in the CPU.
#[inline(always)]
fn packet_entries<K: NodeTest>(
    k: K,
    node: &CwBvhNode,
    node_rays: &[NodeRay; PACKET],
    waiting: u32,
    enter: &mut [[f32; 8]; PACKET],
    one_octant: bool,
) -> (u64, u32) {
    let (rows, any) = k.packet_rows(node, node_rays, waiting, enter, one_octant);
    (transpose_bits(rows), any)
}

/// Each leaf child of `node` in `leaves`, in storage order: the child's slot, its first
/// triangle's slot, its meta byte (the count in unary in the top three bits) and the rays
/// that enter it (byte `child` of `columns`).
#[inline(always)]
fn packet_leaves(
    node: &CwBvhNode,
    mut leaves: u32,
    columns: u64,
) -> impl Iterator<Item = (usize, usize, u8, u32)> + '_ {
    std::iter::from_fn(move || {
        if leaves == 0 {
            return None;
        }
        let child = leaves.trailing_zeros() as usize;
        leaves &= leaves - 1;
        let meta = node.child_meta[child];
        let first = (node.primitive_base_idx + u32::from(meta & 0x1f)) as usize;
        Some((child, first, meta, (columns >> (8 * child)) as u32 & 0xff))
    })
}

/// The transpose of an 8x8 bit matrix held row by row in the bytes of `x` (bit `8 r + c` is
/// row r, column c): three exchanges of blocks along the diagonal (Warren, "Hacker's
/// Delight", 7-3).
#[inline(always)]
fn transpose_bits(mut x: u64) -> u64 {
    let t = (x ^ (x >> 7)) & 0x00AA_00AA_00AA_00AA;
    x ^= t ^ (t << 7);
    let t = (x ^ (x >> 14)) & 0x0000_CCCC_0000_CCCC;
    x ^= t ^ (t << 14);
    let t = (x ^ (x >> 28)) & 0x0000_0000_F0F0_F0F0;
    x ^= t ^ (t << 28);
    x
}

/// The triangles of a node's entered leaves (at most eight leaves of three) and their hit
/// parameters ([`PreparedTriangle::intersect_t`], `f32::INFINITY` for a miss), in leaf
/// order. One per query, cleared for each node: filling its arrays anew each time cost 4%
/// of the camera rays.
struct Found {
    slots: [u32; 24],
    hits: [f32; 24],
    len: usize,
}

impl Found {
    #[inline(always)]
    fn new() -> Found {
        Found {
            slots: [0; 24],
            hits: [f32::INFINITY; 24],
            len: 0,
        }
    }

    #[inline(always)]
    fn clear(&mut self) {
        self.len = 0;
    }

    /// Adds the triangles of the leaves in `leaves` (bits of `node`'s children).
    #[inline(always)]
    fn gather(&mut self, node: &CwBvhNode, mut leaves: u32) {
        while leaves != 0 {
            let child = leaves.trailing_zeros() as usize;
            leaves &= leaves - 1;
            // The leaf's first primitive's offset in the low five bits, its count in unary in
            // the top three.
            let meta = node.child_meta[child];
            let first = node.primitive_base_idx + u32::from(meta & 0x1f);
            for slot in first..first + (meta >> 5).count_ones() {
                self.slots[self.len] = slot;
                self.len += 1;
            }
        }
    }

    /// Tests every triangle gathered, two at a time.
    #[inline(always)]
    fn test<K: NodeTest>(&mut self, k: K, accel: &Accel, ray: &Ray) {
        let triangle = |i: usize| &accel.triangles[self.slots[i] as usize];
        let mut i = 0;
        while i + 1 < self.len {
            (self.hits[i], self.hits[i + 1]) = k.pair(triangle(i), triangle(i + 1), ray);
            i += 2;
        }
        if i < self.len {
            self.hits[i] = triangle(i).intersect_t(ray);
        }
    }

    fn slots(&self) -> &[u32] {
        &self.slots[..self.len]
    }

    fn hits(&self) -> &[f32] {
        &self.hits[..self.len]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Past its 64 entries the stack spills to the heap and still pops last in, first out,
    /// through the spill and back into the array, twice over.
    #[test]
    fn the_stack_spills_in_order() {
        let mut entries: Entries<UVec2> = [MaybeUninit::uninit(); 64];
        let mut stack = Stack::new(&mut entries);
        for round in 0..2 {
            for i in 0..150 {
                stack.push(UVec2::new(i, round));
            }
            for i in (0..150).rev() {
                assert_eq!(stack.pop(), Some(UVec2::new(i, round)));
            }
            assert_eq!(stack.pop(), None);
        }
    }

    /// The min and max planes' pseudo-ray enters by the planes a ray going up every axis
    /// enters by, and leaves by those it leaves by.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_min_max_planes_are_those_of_a_ray_going_up() {
        let ray = Ray::new(Vec3A::ZERO.into(), glam::Vec3::ONE.normalize(), 0.0, 1.0);
        let up = NodeRay::new(&ray);
        assert_eq!(up.near, NodeRay::MIN_MAX_PLANES.near);
        assert_eq!(up.far, NodeRay::MIN_MAX_PLANES.far);
    }

    /// Bit (r, c) of the transpose is bit (c, r) of the matrix, for every bit alone and for
    /// dense patterns.
    #[test]
    fn bit_matrices_transpose() {
        let slow = |x: u64| {
            let mut t = 0u64;
            for r in 0..8 {
                for c in 0..8 {
                    t |= (x >> (8 * r + c) & 1) << (8 * c + r);
                }
            }
            t
        };
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for bit in 0..64 {
            assert_eq!(transpose_bits(1 << bit), slow(1 << bit));
            x = x.rotate_left(5).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            assert_eq!(transpose_bits(x), slow(x));
        }
    }
}
