//! The obvhs compressed wide BVH (CWBVH): built with PLOC and reinsertion, traversed eight
//! children at a time by `super::traverse` with our own node and triangle tests.

use crate::geometry::EDGE_EPSILON;
use crate::measure::Steps;
use crate::scene::TriangleSoup;
use glam::Vec3A;
use obvhs::aabb::Aabb;
use rayon::prelude::*;
use std::time::Duration;

/// Builds the CWBVH over `soup`, marking each step in `steps`. The steps are those of obvhs's
/// `build_cwbvh_from_tris` (PLOC, reinsertion, conversion to the wide BVH), written out here
/// so that each temporary is dropped as soon as the next step no longer needs it and each step
/// is measured: PLOC reads bounding boxes only (32 bytes a triangle instead of the 48 of
/// obvhs's `Triangle`), and the binary BVH is freed once converted. The presets with spatial
/// pre-splits need whole triangles and go through obvhs's helper.
///
/// Also returns the binary tree's node buffer (its pages are already mapped): at 32
/// bytes a node and 2n - 1 nodes (capacity 2n) it is exactly the 64 bytes a triangle the
/// caller's triangle test data needs, which then costs no fresh page faults (16 thousand for
/// a million triangles, a third of that step's time). Empty for the presets with spatial
/// pre-splits.
///
/// With `pair`, neighbouring triangles are paired first ([`pair_neighbours`]) and the tree is
/// built over the pairs.
pub(super) fn build(
    soup: &TriangleSoup,
    params: obvhs::BvhBuildParams,
    pair: bool,
    steps: &mut Steps,
) -> (obvhs::cwbvh::CwBvh, Vec<obvhs::bvh2::node::Bvh2Node>) {
    use obvhs::{bvh2::reinsertion::ReinsertionOptimizer, ploc::PlocBuilder};
    // The triangle test accepts hits up to EDGE_EPSILON outside each edge (in barycentric
    // units): that region is the triangle scaled by 1 + 3·EDGE_EPSILON about its centroid. The
    // BVH is built over triangles scaled a little more, so its boxes contain every hit the test
    // can report and the BVH finds exactly what the linear scan finds.
    let grow = 1.0 + 4.0 * EDGE_EPSILON;
    let grown = |i: usize| -> [Vec3A; 3] {
        let [a, b, c] = soup.triangle(i);
        let centroid = (a + b + c) / 3.0;
        [a, b, c].map(|p| Vec3A::from(centroid + (p - centroid) * grow))
    };
    let n = soup.len();
    if params.pre_split {
        let tris: Vec<obvhs::triangle::Triangle> = (0..n)
            .into_par_iter()
            .map(|i| {
                let [v0, v1, v2] = grown(i);
                obvhs::triangle::Triangle { v0, v1, v2 }
            })
            .collect();
        steps.mark("triangles");
        let bvh =
            obvhs::cwbvh::builder::build_cwbvh_from_tris(&tris, params, &mut Duration::default());
        steps.mark("split, ploc, reinsertion, conversion");
        return (bvh, Vec::new());
    }
    let boxes: Vec<Aabb> = (0..n)
        .into_par_iter()
        .map(|i| {
            let [a, b, c] = grown(i);
            Aabb::new(a.min(b).min(c), a.max(b).max(c))
        })
        .collect();
    steps.mark("bounds");
    let max_prims = params.max_prims_per_leaf.clamp(1, 3);
    let (leaf_boxes, pairs) = if pair && max_prims >= 2 {
        let (pair_boxes, starts) = pair_neighbours(&boxes);
        drop(boxes);
        steps.mark("pairs");
        (pair_boxes, Some(starts))
    } else {
        (boxes, None)
    };
    let m: usize = leaf_boxes.len();
    // obvhs's `build` over a tree of our own: the same zeroed 2m - 1 nodes, in a buffer of 2n
    // (see above; with pairs, m is about n / 2 and PLOC maps only the pages it writes).
    let mut nodes = bytemuck::allocation::zeroed_vec(2 * n);
    nodes.truncate((2 * m).saturating_sub(1));
    let mut bvh2 = obvhs::bvh2::Bvh2 {
        nodes,
        ..Default::default()
    };
    PlocBuilder::with_capacity(m).build_with_bvh(
        &mut bvh2,
        params.ploc_search_distance,
        &leaf_boxes,
        (0..m as u32).collect(),
        params.sort_precision,
        params.search_depth_threshold,
    );
    drop(leaf_boxes);
    if let Some(starts) = pairs {
        // PLOC's leaves name their pair; they now hold its triangles (in soup order).
        bvh2.nodes
            .par_iter_mut()
            .filter(|node| node.is_leaf())
            .for_each(|node| {
                let c = node.first_index as usize;
                if let (Some(&start), Some(&end)) = (starts.get(c), starts.get(c + 1)) {
                    node.first_index = start;
                    node.prim_count = end - start;
                }
            });
        bvh2.primitive_indices = (0..n as u32).collect();
    }
    steps.mark("ploc");
    ReinsertionOptimizer::default().run(&mut bvh2, params.reinsertion_batch_ratio, None);
    steps.mark("reinsertion");
    let cwbvh = super::wide::convert(&bvh2, max_prims).unwrap_or_else(|| {
        obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh(&bvh2, max_prims, true, false)
    });
    let spare = std::mem::take(&mut bvh2.nodes);
    drop(bvh2);
    steps.mark("wide bvh conversion");
    (cwbvh, spare)
}

/// Triangle count from which [`build`] may pair neighbouring triangles into two-triangle
/// leaves before PLOC (see [`pair_neighbours`]). Below it the build is a few milliseconds
/// and the full-resolution tree is worth its cost.
pub(super) const PAIR_FROM: usize = 100_000;

/// Pairs whose box would be larger than this share of the two boxes' half areas together
/// stay apart: two triangles that share an edge make a box about as large as both of theirs
/// (a long thin strip, less), two far apart one many times larger.
const PAIR_MAX_AREA_RATIO: f32 = 1.0;

/// Triangles the pairing walks as one run: a fixed size, so the pairs do not depend on the
/// thread count (and neither does the tree).
const PAIR_RUN: usize = 1 << 14;

/// Triangles in pairs, for builds that trace few rays a triangle (where the build is most of
/// the time to the first pixel). Each triangle is paired with the next in the soup unless the
/// pair's box would be much larger than both of theirs ([`PAIR_MAX_AREA_RATIO`]): exporters
/// write meshes in strips, grids and vertex-cache order, so the next triangle is nearly
/// always a neighbour (the two halves of a quad, most often), and a soup in random order
/// simply pairs little. PLOC and the wide conversion then work on about half the nodes; the
/// leaves they make hold the pairs (and at most three triangles, as before).
///
/// One pass in soup order, no sort: a Morton-sorted pairing was tried first and its sort and
/// scattered reads took 75 ms of a million triangles, as long as it saved.
///
/// Returns the clusters' boxes and where each cluster starts in soup order (one more entry
/// than clusters, the last the triangle count).
pub(super) fn pair_neighbours(boxes: &[Aabb]) -> (Vec<Aabb>, Vec<u32>) {
    let runs: Vec<Vec<u32>> = boxes
        .par_chunks(PAIR_RUN)
        .enumerate()
        .map(|(run, chunk)| {
            let base = run * PAIR_RUN;
            let mut starts = Vec::with_capacity(chunk.len() / 2 + 1);
            let mut k = 0;
            while k < chunk.len() {
                starts.push((base + k) as u32);
                let joins = chunk.get(k + 1).is_some_and(|next| {
                    let a = &chunk[k];
                    a.union(next).half_area()
                        <= PAIR_MAX_AREA_RATIO * (a.half_area() + next.half_area())
                });
                k += if joins { 2 } else { 1 };
            }
            starts
        })
        .collect();
    let mut starts = Vec::with_capacity(runs.iter().map(Vec::len).sum::<usize>() + 1);
    for run in runs {
        starts.extend(run);
    }
    starts.push(boxes.len() as u32);
    let pair_boxes = starts
        .par_windows(2)
        .map(|w| {
            boxes[w[0] as usize..w[1] as usize]
                .iter()
                .fold(Aabb::empty(), |acc, b| acc.union(b))
        })
        .collect();
    (pair_boxes, starts)
}
