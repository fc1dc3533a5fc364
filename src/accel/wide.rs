//! Binary BVH -> compressed wide BVH (CWBVH, eight children a node), in parallel.
//!
//! Adapted from obvhs 0.4's `cwbvh::bvh2_to_cwbvh` (MIT OR Apache-2.0), which follows Ylitie,
//! Karras and Laine, "Efficient Incoherent Ray Traversal on GPUs Through Compressed Wide BVHs"
//! (HPG 2017) and Jan van Bergen's GPU-Raytracer. obvhs converts on one thread: 0.6-0.8 s of a
//! 1.1-1.5 s build for a million triangles on this project's 2-core machine, and the larger
//! share on a machine with more cores. This version makes the same decisions and writes the
//! same nodes in the same order (the tests compare it with obvhs node for node), with both of
//! its passes spread over threads:
//!
//! 1. **Costs.** The paper's dynamic program runs bottom-up; the two subtrees of a node are
//!    independent, so near the root they are costed in parallel (`rayon::join`). A subtree's
//!    seven costs and wide node counts go up the recursion as its return value; each node's
//!    seven choices are packed a byte each into one word, written with a relaxed atomic (a
//!    plain move on x86-64 and AArch64) for the encoding.
//! 2. **Layout.** obvhs writes depth first: a node's internal children side by side, then each
//!    child's subtree in turn, and likewise for primitive indices. So every subtree owns one
//!    contiguous range of nodes and one of primitives. The cost pass has counted the nodes
//!    under each wide node and the primitives under each node; the encoding hands each subtree
//!    its own slices (`split_at_mut`) and fills them in parallel, without locks or unsafe code.
//!
//! Measured on 1M random boxes (PLOC, medium preset), 2 threads: obvhs 820 ms, this 465 ms
//! (before the branch-free child ordering, below). The decision table takes 8 bytes a binary
//! node instead of obvhs's 56.

use glam::{Vec3A, Vec4};
use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::CwBvh;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering::Relaxed};

/// Children of a wide node.
const BRANCHING: usize = 8;
/// Child boxes are quantised to 8 bits a side (obvhs `cwbvh::DENOM`).
const DENOM: f32 = 1.0 / 255.0;
/// Cost of testing one primitive relative to one node (obvhs `PRIM_COST`).
const PRIM_COST: f32 = 0.3;
/// Empty child slot.
const INVALID: u32 = u32::MAX;
/// Subtrees with fewer primitives than this are converted on the calling thread: below it,
/// spawning costs more than it saves.
const PARALLEL_GRAIN: u32 = 2048;
/// The cost pass forks the two halves of every node this many levels below the root and
/// above (2^12 tasks: enough to keep any core count busy, few enough to cost nothing).
const FORK_DEPTH: u32 = 12;

/// What a binary node becomes in the wide tree, for a given number of wide slots.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Kind {
    Leaf,
    Internal,
    Distribute,
}

/// One entry of the dynamic program: the best cost of the subtree using `i + 1` wide slots.
#[derive(Clone, Copy, Debug)]
struct Decision {
    cost: f32,
    kind: Kind,
    left: u8,
    right: u8,
}

impl Decision {
    /// The kind and the two shares in one byte: 2 bits of kind, 3 bits a share (0..=6, and 7
    /// for "none", obvhs's `INVALID`, which only a NaN cost can leave in place).
    fn choice(self) -> u8 {
        let kind = match self.kind {
            Kind::Leaf => 0,
            Kind::Internal => 1,
            Kind::Distribute => 2,
        };
        kind | self.left.min(7) << 2 | self.right.min(7) << 5
    }

    #[cfg(test)]
    fn from_parts(cost: f32, choice: u8) -> Self {
        let (kind, left, right) = unpack_choice(choice);
        Self {
            cost,
            kind,
            left,
            right,
        }
    }
}

/// The kind and shares of a packed choice byte.
fn unpack_choice(choice: u8) -> (Kind, u8, u8) {
    let kind = match choice & 3 {
        0 => Kind::Leaf,
        1 => Kind::Internal,
        _ => Kind::Distribute,
    };
    (kind, (choice >> 2) & 7, choice >> 5)
}

/// What the cost pass passes up from a subtree, for one to seven wide slots given to it.
struct Subtree {
    /// The best cost.
    costs: [f32; 7],
    /// The wide nodes it then makes.
    wide: [u32; 7],
    /// Its primitives.
    prims: u32,
}

/// The converter's shared state: the binary tree and the tables both passes fill.
struct Converter<'a> {
    bvh2: &'a Bvh2,
    max_prims_per_leaf: u32,
    /// Seven packed [`Decision::choice`]s per binary node (slot count i in byte i): all the
    /// encoding reads, at a byte a decision, so that it stays in cache.
    choices: Vec<AtomicU64>,
    /// Primitives under each binary node.
    prims: Vec<AtomicU32>,
    /// Wide nodes under each binary node that becomes a wide node (its subtree, without it).
    nodes_below: Vec<AtomicU32>,
}

/// Converts `bvh2` to a CWBVH with at most `max_prims_per_leaf` (1..=3) primitives per leaf,
/// children ordered for octant traversal. A binary leaf holds one primitive (as PLOC builds
/// it; the tree is then node for node obvhs's) or up to `max_prims_per_leaf` (the pairs of
/// `bvh::pair_neighbours`). Returns `None` when a leaf holds none or more (the caller then
/// uses obvhs's own converter).
pub(super) fn convert(bvh2: &Bvh2, max_prims_per_leaf: u32) -> Option<CwBvh> {
    if bvh2.nodes.is_empty() {
        return Some(CwBvh::default());
    }
    let max_prims_per_leaf = max_prims_per_leaf.clamp(1, 3);
    if bvh2
        .nodes
        .par_iter()
        .any(|n| n.is_leaf() && (n.prim_count == 0 || n.prim_count > max_prims_per_leaf))
    {
        return None;
    }
    let n = bvh2.nodes.len();
    let converter = Converter {
        bvh2,
        max_prims_per_leaf,
        choices: (0..n).map(|_| AtomicU64::new(0)).collect(),
        prims: (0..n).map(|_| AtomicU32::new(0)).collect(),
        nodes_below: (0..n).map(|_| AtomicU32::new(0)).collect(),
    };
    converter.cost(0, 0);
    let below = converter.nodes_below[0].load(Relaxed);
    let prim_total = converter.prims[0].load(Relaxed) as usize;
    let mut nodes = vec![CwBvhNode::default(); 1 + below as usize];
    let mut primitive_indices = vec![0u32; prim_total];
    let (root, rest) = nodes.split_at_mut(1);
    converter.encode(0, &mut root[0], rest, 1, &mut primitive_indices, 0);
    Some(CwBvh {
        nodes,
        primitive_indices,
        total_aabb: *bvh2.nodes[0].aabb(),
        exact_node_aabbs: None,
        uses_spatial_splits: bvh2.uses_spatial_splits,
    })
}

impl Converter<'_> {
    /// Records a node's seven decisions, packed a byte each (slot count i in byte i).
    fn set_choices(&self, node: usize, packed: u64) {
        self.choices[node].store(packed, Relaxed);
    }

    /// The kind and shares of a decision.
    fn choice(&self, node: usize, slots: usize) -> (Kind, u8, u8) {
        unpack_choice((self.choices[node].load(Relaxed) >> (8 * slots)) as u8)
    }

    /// Fills the choice table for the subtree at `index`, `depth` levels below the root, and
    /// returns its seven costs and wide node counts (for one to seven wide slots) and its
    /// primitive count. These go up the recursion instead of into a table: a parent reads each
    /// child's once. Records the primitives under `index` and the wide nodes below it should
    /// it become a wide node.
    fn cost(&self, index: usize, depth: u32) -> Subtree {
        let node = &self.bvh2.nodes[index];
        let half_area = node.aabb().half_area();
        if node.is_leaf() {
            let leaf = Decision {
                cost: half_area * node.prim_count as f32 * PRIM_COST,
                kind: Kind::Leaf,
                left: 0,
                right: 0,
            };
            self.set_choices(index, u64::from(leaf.choice()) * 0x0001_0101_0101_0101);
            self.prims[index].store(node.prim_count, Relaxed);
            return Subtree {
                costs: [leaf.cost; 7],
                wide: [0; 7],
                prims: node.prim_count,
            };
        }
        let (a, b) = (node.first_index as usize, node.first_index as usize + 1);
        // The subtree sizes are not known yet (this pass counts them), so the halves are
        // forked at the top levels only, where they are big.
        let (sa, sb) = if depth < FORK_DEPTH {
            rayon::join(|| self.cost(a, depth + 1), || self.cost(b, depth + 1))
        } else {
            (self.cost(a, depth + 1), self.cost(b, depth + 1))
        };
        let (ca, cb) = (&sa.costs, &sb.costs);
        // Wide nodes the children contribute with `l + 1` and `r + 1` slots (none for the
        // "no share" of a NaN cost, which makes no decision either).
        let wide = |l: u8, r: u8| {
            sa.wide.get(l as usize).copied().unwrap_or(0)
                + sb.wide.get(r as usize).copied().unwrap_or(0)
        };
        let count = sa.prims + sb.prims;
        self.prims[index].store(count, Relaxed);

        // One slot (i = 1 in the paper): a leaf, or an internal node whose eight slots are
        // shared between the two children.
        let leaf_cost = if count <= self.max_prims_per_leaf {
            count as f32 * half_area * PRIM_COST
        } else {
            f32::INFINITY
        };
        let mut distribute = f32::INFINITY;
        let (mut left, mut right) = (u8::MAX, u8::MAX);
        for k in 0..7 {
            let c = ca[k] + cb[6 - k];
            if c < distribute {
                distribute = c;
                left = k as u8;
                right = 6 - k as u8;
            }
        }
        let internal_cost = distribute + half_area;
        let (cost, kind) = if leaf_cost < internal_cost {
            (leaf_cost, Kind::Leaf)
        } else {
            (internal_cost, Kind::Internal)
        };
        let mut previous = Decision {
            cost,
            kind,
            left,
            right,
        };
        let mut costs = [0.0; 7];
        costs[0] = cost;
        let mut packed = u64::from(previous.choice());
        // As a wide node, its eight slots go to the children as `left` and `right` say: the
        // wide nodes below it are theirs (obvhs's layout pass counts the same).
        let below = wide(left, right);
        self.nodes_below[index].store(below, Relaxed);
        let mut nodes = [0; 7];
        nodes[0] = if kind == Kind::Internal { 1 + below } else { 0 };

        // i + 1 slots (i = 2..7 in the paper): as with i slots, or distributed over both.
        for i in 1..7 {
            let mut best = previous.cost;
            let (mut left, mut right) = (u8::MAX, u8::MAX);
            for k in 0..i {
                let c = ca[k] + cb[i - k - 1];
                if c < best {
                    best = c;
                    left = k as u8;
                    right = (i - k - 1) as u8;
                }
            }
            let d = if left != u8::MAX {
                nodes[i] = wide(left, right);
                Decision {
                    cost: best,
                    kind: Kind::Distribute,
                    left,
                    right,
                }
            } else {
                nodes[i] = nodes[i - 1];
                previous
            };
            packed |= u64::from(d.choice()) << (8 * i);
            costs[i] = d.cost;
            previous = d;
        }
        self.set_choices(index, packed);
        Subtree {
            costs,
            wide: nodes,
            prims: count,
        }
    }

    /// The wide children of binary node `index` taking `slots + 1` wide slots (obvhs
    /// `get_children`), appended to `children`.
    fn children(
        &self,
        index: usize,
        slots: usize,
        children: &mut [u32; BRANCHING],
        count: &mut usize,
    ) {
        let node = &self.bvh2.nodes[index];
        if node.is_leaf() {
            children[*count] = index as u32;
            *count += 1;
            return;
        }
        let (_, left, right) = self.choice(index, slots);
        for (child, share) in [
            (node.first_index as usize, left),
            (node.first_index as usize + 1, right),
        ] {
            if self.choice(child, share as usize).0 == Kind::Distribute {
                self.children(child, share as usize, children, count);
            } else {
                children[*count] = child as u32;
                *count += 1;
            }
        }
    }

    /// The wide children of `index` as a wide node, each in its octant-order slot; empty
    /// slots hold [`INVALID`].
    fn wide_children(&self, index: usize) -> [u32; BRANCHING] {
        let mut children = [INVALID; BRANCHING];
        let mut count = 0;
        self.children(index, 0, &mut children, &mut count);
        self.order_children(index, &mut children, count);
        children
    }

    fn is_internal(&self, child: u32) -> bool {
        self.choice(child as usize, 0).0 == Kind::Internal
    }

    /// Orders children so that traversal by ray octant visits them front to back (obvhs
    /// `order_children`: greedy assignment of children to the eight direction slots).
    ///
    /// obvhs repeatedly takes the cheapest (child, slot) pair left, cost below `f32::MAX`, the
    /// first in (child, slot) order among equals, from a full scan with a branch per pair. The
    /// outcome of those branches is data-dependent (about 75 mispredictions a wide node, a
    /// quarter of the encoding's time), so this does the same scan without branches:
    /// taken pairs' costs become infinite, each round takes the minimum over the 8x8 table
    /// four lanes at a time, and the first pair equal to it (a bit mask's lowest set bit, in
    /// row-major (child, slot) order) is the one obvhs takes.
    fn order_children(&self, index: usize, children: &mut [u32; BRANCHING], count: usize) {
        let p = self.bvh2.nodes[index].aabb().center();
        // Lane s of the slot directions (obvhs `direction_lut`): -1 in x for s & 4, in y for
        // s & 2, in z for s & 1. The cost is d·v = (dx·vx + dy·vy) + dz·vz, summed in glam's
        // `dot` order, so each cost has the same bits as obvhs's.
        const SY: Vec4 = Vec4::new(1.0, 1.0, -1.0, -1.0);
        const SZ: Vec4 = Vec4::new(1.0, -1.0, 1.0, -1.0);
        let mut cost = [[Vec4::INFINITY; 2]; BRANCHING];
        for (c, row) in cost.iter_mut().enumerate().take(count) {
            let v = self.bvh2.nodes[children[c] as usize].aabb().center() - p;
            for (half, sx) in row.iter_mut().zip([1.0, -1.0]) {
                let d = (Vec4::splat(sx * v.x) + SY * v.y) + SZ * v.z;
                // obvhs only takes costs below f32::MAX (NaN never): the rest are never taken.
                *half = Vec4::select(d.cmplt(Vec4::splat(f32::MAX)), d, Vec4::INFINITY);
            }
        }
        let mut assignment = [usize::MAX; BRANCHING];
        for _ in 0..count {
            let min = cost
                .iter()
                .fold(Vec4::INFINITY, |m, row| m.min(row[0]).min(row[1]))
                .min_element();
            if min == f32::INFINITY {
                break;
            }
            let mut equal = 0u64;
            for (c, row) in cost.iter().enumerate() {
                let lanes = row[0].cmpeq(Vec4::splat(min)).bitmask()
                    | row[1].cmpeq(Vec4::splat(min)).bitmask() << 4;
                equal |= u64::from(lanes) << (8 * c);
            }
            let first = equal.trailing_zeros() as usize;
            let (child, slot) = (first / BRANCHING, first % BRANCHING);
            assignment[child] = slot;
            // The child is placed and the slot taken: neither is offered again.
            cost[child] = [Vec4::INFINITY; 2];
            for row in &mut cost {
                row[slot / 4][slot % 4] = f32::INFINITY;
            }
        }
        let original = std::mem::replace(children, [INVALID; BRANCHING]);
        for c in 0..count {
            // Every child gets a slot: there are as many slots as children at most.
            if let Some(slot) = children.get_mut(assignment[c]) {
                *slot = original[c];
            }
        }
    }

    /// Appends the primitives of the subtree at `index` to `out` from `at`, depth first.
    fn collect_primitives(&self, index: usize, out: &mut [u32], at: &mut usize) {
        let node = &self.bvh2.nodes[index];
        if node.is_leaf() {
            let first = node.first_index as usize;
            let prims = &self.bvh2.primitive_indices[first..first + node.prim_count as usize];
            out[*at..*at + prims.len()].copy_from_slice(prims);
            *at += prims.len();
        } else {
            self.collect_primitives(node.first_index as usize, out, at);
            self.collect_primitives(node.first_index as usize + 1, out, at);
        }
    }

    /// Encodes binary node `index` as the wide node `node`, whose subtree's other nodes go to
    /// `below` (global index `below_base` onwards) and whose primitives go to `prims` (global
    /// index `prims_base` onwards).
    fn encode(
        &self,
        index: usize,
        node: &mut CwBvhNode,
        below: &mut [CwBvhNode],
        below_base: u32,
        prims: &mut [u32],
        prims_base: u32,
    ) {
        let aabb = self.bvh2.nodes[index].aabb();
        // obvhs: e = 2^ceil(log2(extent / 255)), per axis. log2 stays the library's (its
        // rounding decides the exponent next to powers of two); the ceiling and the power of two
        // are exact integer steps, which the baseline x86-64 target would otherwise make libm
        // calls (no `roundss` before SSE4.1).
        let exponent = |extent: f32| ceil_i32((extent.max(1e-20) * DENOM).log2());
        let size = aabb.max - aabb.min;
        let k = [exponent(size.x), exponent(size.y), exponent(size.z)];
        // Biased exponents: 2^k is normal for every k this can give (-74..=121).
        let biased = k.map(|k| (k + 127) as u32);
        let rcp_e = Vec3A::from(biased.map(|b| 1.0 / f32::from_bits(b << 23)));
        node.p = aabb.min.into();
        // e is a power of two: only its exponent bits are stored.
        node.e = biased.map(|b| b as u8);
        node.imask = 0;
        node.child_base_idx = below_base;
        node.primitive_base_idx = prims_base;

        let children = self.wide_children(index);
        let mut internal_count = 0;
        let mut prim_count = 0usize;
        let mut internal = [INVALID; BRANCHING];
        for (i, &child) in children.iter().enumerate() {
            if child == INVALID {
                continue;
            }
            let child_aabb = self.bvh2.nodes[child as usize].aabb();
            let lo = (child_aabb.min - aabb.min) * rcp_e;
            let hi = (child_aabb.max - aabb.min) * rcp_e;
            node.child_min_x[i] = floor_u8(lo.x);
            node.child_min_y[i] = floor_u8(lo.y);
            node.child_min_z[i] = floor_u8(lo.z);
            node.child_max_x[i] = ceil_u8(hi.x);
            node.child_max_y[i] = ceil_u8(hi.y);
            node.child_max_z[i] = ceil_u8(hi.z);
            if self.is_internal(child) {
                node.imask |= 1 << i;
                node.child_meta[i] = (24 + i as u8) | 0b0010_0000;
                internal[internal_count] = child;
                internal_count += 1;
            } else {
                let first = prim_count;
                self.collect_primitives(child as usize, prims, &mut prim_count);
                // The three high bits hold the leaf's primitive count in unary.
                let unary = match prim_count - first {
                    1 => 0b0010_0000,
                    2 => 0b0110_0000,
                    _ => 0b1110_0000,
                };
                node.child_meta[i] = first as u8 | unary;
            }
        }

        // Hand each internal child its slot, its subtree's node range and its primitives.
        let (slots, mut rest_nodes) = below.split_at_mut(internal_count);
        let (_, mut rest_prims) = prims.split_at_mut(prim_count);
        let mut node_at = below_base + internal_count as u32;
        let mut prim_at = prims_base + prim_count as u32;
        let mut internal = slots.iter_mut().zip(&internal[..internal_count]);
        let jobs = std::iter::from_fn(move || {
            let (slot, &child) = internal.next()?;
            let nodes = self.nodes_below[child as usize].load(Relaxed) as usize;
            let count = self.prims[child as usize].load(Relaxed) as usize;
            let (mine, more) = std::mem::take(&mut rest_nodes).split_at_mut(nodes);
            let (my_prims, more_prims) = std::mem::take(&mut rest_prims).split_at_mut(count);
            let job = (child as usize, slot, mine, node_at, my_prims, prim_at);
            node_at += nodes as u32;
            prim_at += count as u32;
            rest_nodes = more;
            rest_prims = more_prims;
            Some(job)
        });
        if self.prims[index].load(Relaxed) >= PARALLEL_GRAIN {
            rayon::scope(|scope| {
                for (child, slot, mine, base, my_prims, pbase) in jobs {
                    scope.spawn(move |_| self.encode(child, slot, mine, base, my_prims, pbase));
                }
            });
        } else {
            for (child, slot, mine, base, my_prims, pbase) in jobs {
                self.encode(child, slot, mine, base, my_prims, pbase);
            }
        }
    }
}

/// `x.floor().clamp(0.0, 255.0) as u8`, without a libm call: for x in [0, 255] truncation is
/// the floor, and clamping first changes nothing outside (NaN gives 0 either way).
#[inline]
fn floor_u8(x: f32) -> u8 {
    x.clamp(0.0, 255.0) as u8
}

/// `x.ceil().clamp(0.0, 255.0) as u8`, without a libm call.
#[inline]
fn ceil_u8(x: f32) -> u8 {
    let x = x.clamp(0.0, 255.0);
    let t = x as u8;
    t + u8::from((t as f32) < x)
}

/// `x.ceil() as i32` for |x| < 2^31, without a libm call: truncation rounds toward zero, which
/// is the ceiling for negative x and one short of it for positive x with a fraction.
#[inline]
fn ceil_i32(x: f32) -> i32 {
    let t = x as i32;
    t + i32::from((t as f32) < x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use obvhs::aabb::Aabb;
    use obvhs::ploc::PlocBuilder;

    /// Boxes of a jittered grid of small triangles, with some large and overlapping ones.
    fn boxes(n: usize) -> Vec<Aabb> {
        let mut rng = crate::sampling::Rng::new(7);
        (0..n)
            .map(|_| {
                let c = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
                let size = if rng.next_f32() < 0.05 { 2.0 } else { 0.05 };
                let d = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * size;
                Aabb::new(c - d, c + d)
            })
            .collect()
    }

    /// Equal cubes on a regular grid: child centres sit at equal distances in several
    /// directions, so slot costs tie exactly and the tie rule decides.
    fn grid(side: usize) -> Vec<Aabb> {
        let mut out = Vec::new();
        for x in 0..side {
            for y in 0..side {
                for z in 0..side {
                    let c = Vec3A::new(x as f32, y as f32, z as f32);
                    out.push(Aabb::new(c - 0.25, c + 0.25));
                }
            }
        }
        out
    }

    fn bvh2(n: usize, reinsertion: f32) -> Bvh2 {
        bvh2_over(boxes(n), reinsertion)
    }

    fn bvh2_over(boxes: Vec<Aabb>, reinsertion: f32) -> Bvh2 {
        let params = obvhs::BvhBuildParams::medium_build();
        let n = boxes.len();
        let mut bvh2 = PlocBuilder::with_capacity(n).build(
            params.ploc_search_distance,
            &boxes,
            (0..n as u32).collect(),
            params.sort_precision,
            params.search_depth_threshold,
        );
        obvhs::bvh2::reinsertion::ReinsertionOptimizer::default().run(&mut bvh2, reinsertion, None);
        bvh2
    }

    #[test]
    fn same_nodes_and_primitives_as_obvhs() {
        let random = [
            (1, 0.0),
            (2, 0.0),
            (3, 0.0),
            (5, 0.05),
            (100, 0.05),
            (20_000, 0.2),
        ]
        .map(|(n, reinsertion)| (n, bvh2(n, reinsertion)));
        let grids = [(4, 0.0), (22, 0.1)].map(|(side, reinsertion)| {
            let boxes = grid(side);
            (boxes.len(), bvh2_over(boxes, reinsertion))
        });
        for (n, bvh2) in random.into_iter().chain(grids) {
            for max_prims in 1..=3 {
                let expected =
                    obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh(&bvh2, max_prims, true, false);
                let got = convert(&bvh2, max_prims).expect("PLOC leaves hold one primitive");
                assert_eq!(
                    got.primitive_indices, expected.primitive_indices,
                    "{n} {max_prims}"
                );
                assert!(
                    got.nodes == expected.nodes,
                    "{n} triangles, {max_prims} a leaf"
                );
                assert_eq!(got.total_aabb, expected.total_aabb);
            }
        }
    }

    #[test]
    fn decisions_survive_packing() {
        for (kind, left, right) in [
            (Kind::Distribute, 6, 0),
            (Kind::Leaf, 0, 6),
            (Kind::Internal, 3, 3),
        ] {
            let d = Decision {
                cost: -1.5e-7,
                kind,
                left,
                right,
            };
            let u = Decision::from_parts(d.cost, d.choice());
            assert_eq!(
                (u.cost, u.kind, u.left, u.right),
                (d.cost, d.kind, d.left, d.right)
            );
        }
    }
}
