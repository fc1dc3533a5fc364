//! MikkTSpace tangents for triangle lists, bit-identical to `bevy_mikktspace` 1.0.0 (itself
//! byte-identical to Morten S. Mikkelsen's C reference on x86) and faster: DamagedHelmet's
//! tangent phase in a real render (cold caches, fresh pages) went from 17.6-18.8 ms to about
//! 7.6 ms (median, 2 threads), and with the weld by value to about 5 ms; the algorithm alone,
//! warm in a loop, from 16.9 to 6.1 and then about 4 ms.
//!
//! # Why our own
//! `bevy_mikktspace` took 17-25 ms of DamagedHelmet's load (15,452 triangles, about 1.2 µs
//! per triangle, where the whole load should take 0.5). `perf` put a third of it in the
//! grouping and output loops (a degenerate triangle searched every good corner, O(N^2); every
//! pair of triangles around a vertex re-projected both tangents), 11% in the welding, 7% in the
//! C-compatible quick sort of all edges, and the rest in trait callbacks, iterator adapters
//! and ~50,000 small allocations. This version keeps every floating-point operation of the
//! reference in the same order, and changes only how the work is found and scheduled:
//!
//! * an indexed triangle list instead of `Geometry` callbacks (the soup's own vertex arrays,
//!   not a per-corner copy); triangles only (our soup has nothing else), so the quad paths
//!   fall away;
//! * where no edge has a choice of partner (a manifold mesh; see `unique_neighbors`), which
//!   corner represents a weld class changes nothing, so the classes come from a hash table of
//!   the distinct vertices' values instead of the reference's recursive spatial split, and the
//!   edges pair without reproducing the reference's edge order; elsewhere (and for NaN or
//!   infinite values, where the reference's weld is not plain equality) the reference's weld
//!   and order are reproduced as below;
//! * the per-triangle first-order tangents, the per-bucket welding and the per-group
//!   tangent evaluation run in parallel with rayon; each is a pure function of its input
//!   collected in order, so the result does not depend on the thread count;
//! * the edges are ordered with a counting sort on their first vertex (keys are unique, so any
//!   correct sort gives the reference's order), except the one run the C quick sort leaves
//!   unsorted (see [`sort_edges`]): for that run the quick sort is replayed only on the
//!   sub-ranges that hold it (O(n) expected instead of O(n log n));
//! * a degenerate triangle's corner finds its donor through a first-occurrence table (O(1))
//!   instead of a scan of all good corners;
//! * within a vertex group each member's projected tangent is computed once, not once per pair
//!   (the values are the same: the same operations on the same inputs).
//!
//! Only what the caller uses comes out: the unit tangent and its handedness. The bitangent and
//! the magnitudes influence neither, so they are not computed.
//!
//! # Derivation and licence
//! Derived from `bevy_mikktspace` 1.0.0 (<https://github.com/bevyengine/bevy_mikktspace>,
//! licence Zlib AND (MIT OR Apache-2.0)), a Rust port of MikkTSpace
//! (<https://github.com/mmikk/MikkTSpace>, zlib licence), whose notice follows as that licence
//! requires. This is an altered version: restructured for speed, same results.
//!
//! > Copyright (C) 2011 by Morten S. Mikkelsen
//! >
//! > This software is provided 'as-is', without any express or implied
//! > warranty.  In no event will the authors be held liable for any damages
//! > arising from the use of this software.
//! >
//! > Permission is granted to anyone to use this software for any purpose,
//! > including commercial applications, and to alter it and redistribute it
//! > freely, subject to the following restrictions:
//! >
//! > 1. The origin of this software must not be misrepresented; you must not
//! >    claim that you wrote the original software. If you use this software
//! >    in a product, an acknowledgment in the product documentation would be
//! >    appreciated but is not required.
//! > 2. Altered source versions must be plainly marked as such, and must not be
//! >    misrepresented as being the original software.
//! > 3. This notice may not be removed or altered from any source distribution.

use rayon::prelude::*;

/// The linear grouping threshold of `bevy_mikktspace::generate_tangents` (-1: no angular
/// split of a vertex's tangent space).
const THRESHOLD: f32 = -1.0;

/// The input of [`generate`]: an indexed triangle list. Corner `3 * f + v` is vertex `v` of
/// triangle `f`, and its attributes are entry `indices[3 * f + v]` of the three slices (a mesh
/// given per corner has the indices 0, 1, 2, ...).
pub struct Corners<'a> {
    /// Positions.
    pub positions: &'a [[f32; 3]],
    /// Unit normals.
    pub normals: &'a [[f32; 3]],
    /// Texture coordinates with v pointing up (MikkTSpace's convention).
    pub uvs: &'a [[f32; 2]],
    /// Three a triangle, each below the length of all three slices.
    pub indices: &'a [u32],
}

/// [`Corners`] once its indices are checked: the attributes of a corner by its id.
#[derive(Clone, Copy)]
struct Mesh<'a> {
    positions: &'a [V3],
    normals: &'a [V3],
    uvs: &'a [[f32; 2]],
    indices: &'a [u32],
}

impl<'a> Corners<'a> {
    /// The attributes of a corner by its id (indices unchecked: [`generate`] checks them).
    fn mesh(&self) -> Mesh<'a> {
        Mesh {
            positions: self.positions,
            normals: self.normals,
            uvs: self.uvs,
            indices: self.indices,
        }
    }
}

impl Mesh<'_> {
    #[inline]
    fn position(&self, corner: usize) -> V3 {
        self.positions[self.indices[corner] as usize]
    }

    #[inline]
    fn normal(&self, corner: usize) -> V3 {
        self.normals[self.indices[corner] as usize]
    }

    #[inline]
    fn uv(&self, corner: usize) -> [f32; 2] {
        self.uvs[self.indices[corner] as usize]
    }
}

type V3 = [f32; 3];

#[inline]
fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `s * v` as the reference computes it (`rhs * self.x` per component).
#[inline]
fn scale(v: V3, s: f32) -> V3 {
    [s * v[0], s * v[1], s * v[2]]
}

#[inline]
fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The reference's `not_zero`: larger in magnitude than the smallest normal f32 (NaN is not).
#[inline]
fn not_zero(x: f32) -> bool {
    x.abs() > f32::MIN_POSITIVE
}

#[inline]
fn length(v: V3) -> f32 {
    dot(v, v).sqrt()
}

/// The reference's `normalized_or_zero`: unchanged when every component is (nearly) zero.
#[inline]
fn normalized_or_zero(v: V3) -> V3 {
    if not_zero(v[0]) || not_zero(v[1]) || not_zero(v[2]) {
        scale(v, length(v).recip())
    } else {
        v
    }
}

/// `v` minus its component along the unit normal `n`, normalized.
#[inline]
fn project(v: V3, n: V3) -> V3 {
    normalized_or_zero(sub(v, scale(n, dot(n, v))))
}

/// What MikkTSpace knows of one triangle before grouping.
#[derive(Clone, Copy)]
struct Triangle {
    /// The group of each corner, `u32::MAX` for none yet.
    group: [u32; 3],
    /// Normalized first-order tangent and bitangent, signed by the orientation.
    s: V3,
    t: V3,
    /// Too degenerate in UV for a tangent of its own: takes any group it touches.
    group_with_any: bool,
    orientation_preserving: bool,
}

const NONE: u32 = u32::MAX;

/// MikkTSpace tangents for the whole triangles of `corners`: for each corner the unit
/// tangent and, in `w`, +1 or -1 for the bitangent's handedness, or `None` where the algorithm
/// gives none (a degenerate triangle with no good neighbour; every corner when an index is
/// out of range). Equal, bit for bit, to `bevy_mikktspace::generate_tangents` over the same
/// triangles given corner by corner.
pub fn generate(corners: &Corners) -> Tangents {
    let n_faces = corners.indices.len() / 3;
    let n_vertices = corners
        .positions
        .len()
        .min(corners.normals.len())
        .min(corners.uvs.len());
    let indices = &corners.indices[..n_faces * 3];
    // Corner ids are u32; the soup's 50-million-triangle limit keeps them below 2^28.
    if n_faces == 0
        || n_faces * 3 >= NONE as usize
        || indices.iter().any(|&v| v as usize >= n_vertices)
    {
        return Tangents::none(n_faces * 3);
    }
    let mesh = Mesh {
        indices,
        ..corners.mesh()
    };

    // The good triangles before the degenerate ones, each in file order (the reference's
    // stable sort by (degenerate, index)).
    let degenerate: Vec<bool> = (0..n_faces)
        .into_par_iter()
        .with_min_len(4096)
        .map(|f| is_degenerate(&mesh, f))
        .collect();
    let mut order: Vec<u32> = Vec::with_capacity(n_faces);
    order.extend((0..n_faces as u32).filter(|&f| !degenerate[f as usize]));
    let n_good = order.len();
    order.extend((0..n_faces as u32).filter(|&f| degenerate[f as usize]));
    drop(degenerate);

    // The good triangles' first-order tangents, beside the welding and pairing, which do not
    // need them.
    let (mut triangles, (vertices, neighbors)) = rayon::join(
        || -> Vec<Triangle> {
            order[..n_good]
                .par_iter()
                .with_min_len(1024)
                .map(|&f| triangle_info(&mesh, f as usize))
                .collect()
        },
        || weld_and_pair(&mesh, &order, n_good),
    );
    let good_vertices = &vertices[..n_good * 3];
    let groups = build_groups(&mut triangles, &neighbors, good_vertices);
    drop(neighbors);

    // Evaluate every group in parallel. A group's members nearly always get one tangent (with
    // the threshold of -1 they part only where projected tangents are exactly opposite, or
    // NaN): it is kept once a group, and a member whose tangent differs is listed apart. The
    // corners then read their group's tangent in order, where a list of (corner, tangent)
    // scattered into the output was 0.5 ms of random writes and 0.9 MB for DamagedHelmet.
    let evaluated: Vec<Evaluated> = groups
        .groups
        .par_chunks(256)
        .map(|chunk| {
            let mut scratch = GroupScratch::default();
            let mut apart = Vec::new();
            let tangents = chunk
                .iter()
                .map(|group| {
                    evaluate_group(
                        group,
                        &groups.faces,
                        &triangles,
                        good_vertices,
                        &order,
                        &mesh,
                        &mut scratch,
                        &mut apart,
                    )
                })
                .collect();
            (tangents, apart)
        })
        .collect();
    // Each corner's entry: its group's tangent, or one of its own if it was listed apart.
    let mut values: Vec<[f32; 4]> = evaluated.iter().flat_map(|e| e.0.iter().copied()).collect();
    // Triangle `f`'s place among the good ones (`NONE` for a degenerate one).
    let good_index: Option<Vec<u32>> = (n_good < n_faces).then(|| {
        let mut index = vec![NONE; n_faces];
        for (k, &f) in order[..n_good].iter().enumerate() {
            index[f as usize] = k as u32;
        }
        index
    });
    let mut corner: Vec<u32> = (0..n_faces * 3)
        .into_par_iter()
        .with_min_len(4096)
        .map(|c| {
            let f = c / 3;
            let k = good_index.as_ref().map_or(f as u32, |index| index[f]);
            triangles.get(k as usize).map_or(NONE, |t| t.group[c % 3])
        })
        .collect();
    for &(c, tangent) in evaluated.iter().flat_map(|e| e.1.iter()) {
        corner[c as usize] = values.len() as u32;
        values.push(tangent);
    }
    drop(evaluated);

    // A degenerate triangle's corner copies the tangent of the first good corner (in the
    // good triangles' order) welded to the same vertex.
    if n_good < n_faces {
        let mut first_good = vec![NONE; n_faces * 3];
        for (k, &v) in good_vertices.iter().enumerate().rev() {
            first_good[v as usize] = k as u32;
        }
        let corner_of = |k: usize| (3 * order[k / 3] + (k % 3) as u32) as usize;
        for k in n_good * 3..n_faces * 3 {
            let src = first_good[vertices[k] as usize];
            corner[corner_of(k)] = if src != NONE {
                corner[corner_of(src as usize)]
            } else {
                NONE
            };
        }
    }
    Tangents { corner, values }
}

/// The tangents of [`generate`], read by corner: each corner's index into a list of distinct
/// tangents (one a vertex group, and the few members that part from their group's), 4 bytes
/// a corner where a list of every corner's tangent took 20 (0.9 MB of fresh pages for
/// DamagedHelmet, about 0.3 ms).
pub struct Tangents {
    /// Each corner's entry in `values`; `NONE` for none.
    corner: Vec<u32>,
    values: Vec<[f32; 4]>,
}

impl Tangents {
    /// No tangent for any of `corners` corners.
    fn none(corners: usize) -> Self {
        Tangents {
            corner: vec![NONE; corners],
            values: Vec::new(),
        }
    }

    /// Corner `corner`'s unit tangent with the bitangent's handedness (+1 or -1) in `w`, or
    /// `None` where MikkTSpace gives none (or past the last corner).
    pub fn get(&self, corner: usize) -> Option<[f32; 4]> {
        let &entry = self.corner.get(corner)?;
        self.values.get(entry as usize).copied()
    }

    /// Every corner's tangent, in order.
    #[cfg(test)]
    fn to_vec(&self) -> Vec<Option<[f32; 4]>> {
        (0..self.corner.len()).map(|c| self.get(c)).collect()
    }
}

/// Corner ids of triangles `order` (the good ones, `n_good`, first), each replaced by its weld
/// representative, and the good triangles' neighbours ([`build_neighbors`]).
///
/// Where no edge has a choice of partners (see [`unique_neighbors`]), the neighbours, and so
/// the tangents, do not depend on which corner of a weld class represents it: any will do, and
/// [`weld_by_value`] finds the classes in a fraction of the reference's time. Otherwise the
/// reference's representatives and edge order decide, and [`weld`] and [`build_neighbors`]
/// reproduce them.
fn weld_and_pair(mesh: &Mesh, order: &[u32], n_good: usize) -> (Vec<u32>, Vec<[u32; 3]>) {
    let corner_ids = || order.iter().flat_map(|&f| [3 * f, 3 * f + 1, 3 * f + 2]);
    let mut vertices: Vec<u32> = corner_ids().collect();
    if weld_by_value(mesh, &mut vertices) {
        if let Some(neighbors) = unique_neighbors(&vertices[..n_good * 3]) {
            return (vertices, neighbors);
        }
    }
    for (slot, corner) in vertices.iter_mut().zip(corner_ids()) {
        *slot = corner;
    }
    weld(mesh, &mut vertices);
    let neighbors = build_neighbors(&vertices[..n_good * 3]);
    (vertices, neighbors)
}

/// Whether triangle `f` is degenerate: two of its positions are equal.
fn is_degenerate(mesh: &Mesh, f: usize) -> bool {
    let v = [0, 1, 2].map(|k| mesh.position(3 * f + k));
    v[0] == v[1] || v[1] == v[2] || v[2] == v[0]
}

/// The first-order tangents of the good (not degenerate) triangle `f`.
fn triangle_info(mesh: &Mesh, f: usize) -> Triangle {
    let mut info = Triangle {
        group: [NONE; 3],
        s: [0.0; 3],
        t: [0.0; 3],
        group_with_any: false,
        orientation_preserving: false,
    };
    let v = [0, 1, 2].map(|k| mesh.position(3 * f + k));
    let tx = [0, 1, 2].map(|k| mesh.uv(3 * f + k));
    let d_tx = [1, 2].map(|k| [tx[k][0] - tx[0][0], tx[k][1] - tx[0][1]]);
    let d_v = [sub(v[1], v[0]), sub(v[2], v[0])];
    let signed_area_double = d_tx[0][0] * d_tx[1][1] - d_tx[0][1] * d_tx[1][0];
    let area_double = signed_area_double.abs();
    let s = sub(scale(d_v[0], d_tx[1][1]), scale(d_v[1], d_tx[0][1]));
    let t = add(scale(d_v[0], -d_tx[1][0]), scale(d_v[1], d_tx[0][0]));
    info.group_with_any = true;
    info.orientation_preserving = signed_area_double > 0.0;
    if not_zero(area_double) {
        let sign = if info.orientation_preserving {
            1.0
        } else {
            -1.0
        };
        info.s = scale(normalized_or_zero(s), sign);
        info.t = scale(normalized_or_zero(t), sign);
        let s_magnitude = length(s) / area_double;
        let t_magnitude = length(t) / area_double;
        if not_zero(s_magnitude) && not_zero(t_magnitude) {
            info.group_with_any = false;
        }
    }
    info
}

/// One corner in the welding buffer: its attributes (copied in: looking them up by id in the
/// leaves' pairwise comparisons was a quarter of the welding's time, in cache misses) and its
/// index in the vertex list.
#[derive(Clone, Copy)]
struct WeldVertex {
    position: V3,
    normal: V3,
    uv: [f32; 2],
    index: u32,
    /// Filled in by the leaf: the corner id it welds to.
    rep: u32,
}

/// Replaces each corner id in `vertices` by the id of the corner it welds to (equal position,
/// normal and texture coordinate, compared with `==`), choosing the same representative as the
/// reference (`weld_vertices_legacy.rs`): 2048 buckets along the longest axis of the bounds,
/// each split recursively at its midpoint with the same swaps, the first equal corner of each
/// leaf winning. Buckets are independent, so they run in parallel.
fn weld(mesh: &Mesh, vertices: &mut [u32]) {
    const GROUPS: usize = 2048;
    let Some(&first) = vertices.first() else {
        return;
    };
    let first = mesh.position(first as usize);
    let (mut min, mut max) = (first, first);
    for &v in vertices.iter() {
        let p = mesh.position(v as usize);
        for c in 0..3 {
            min[c] = min[c].min(p[c]);
            max[c] = max[c].max(p[c]);
        }
    }
    let d = sub(max, min);
    let c_max = longest_axis(d);
    let bucket = |p: V3| -> usize {
        let t = (p[c_max] - min[c_max]) / d[c_max];
        let group = (GROUPS as f32 * t.clamp(0., 1.)) as u16;
        (group as usize).min(GROUPS - 1)
    };
    // A counting sort: stable, like the reference's `sort_by_key`.
    let buckets: Vec<u16> = vertices
        .par_iter()
        .with_min_len(4096)
        .map(|&v| bucket(mesh.position(v as usize)) as u16)
        .collect();
    let mut starts = vec![0usize; GROUPS + 1];
    for &b in &buckets {
        starts[b as usize + 1] += 1;
    }
    for g in 0..GROUPS {
        starts[g + 1] += starts[g];
    }
    // The sort scatters 4-byte indices; the 40-byte records are then written once, in
    // order and in parallel (filling a zeroed 1.9 MB buffer and then scattering into it
    // touched every page twice, sequentially).
    let mut next = starts.clone();
    let mut sorted = vec![0u32; vertices.len()];
    for (k, &b) in buckets.iter().enumerate() {
        let slot = &mut next[b as usize];
        sorted[*slot] = k as u32;
        *slot += 1;
    }
    drop(buckets);
    let mut buffer: Vec<WeldVertex> = sorted
        .par_iter()
        .with_min_len(4096)
        .map(|&k| {
            let v = vertices[k as usize] as usize;
            WeldVertex {
                position: mesh.position(v),
                normal: mesh.normal(v),
                uv: mesh.uv(v),
                index: k,
                rep: v as u32,
            }
        })
        .collect();
    drop(sorted);
    let mut chunks: Vec<&mut [WeldVertex]> = Vec::with_capacity(GROUPS);
    let mut rest = buffer.as_mut_slice();
    for g in 0..GROUPS {
        let (chunk, tail) = rest.split_at_mut(starts[g + 1] - starts[g]);
        if !chunk.is_empty() {
            chunks.push(chunk);
        }
        rest = tail;
    }
    chunks.par_iter_mut().for_each(|chunk| merge_verts(chunk));
    for w in &buffer {
        vertices[w.index as usize] = w.rep;
    }
}

/// The largest magnitude [`weld_by_value`] takes: the reference splits a bucket at
/// 0.5 * (max + min), which overflows to infinity past f32::MAX / 2, and a bucket whose split
/// is not finite welds nothing.
const WELD_BY_VALUE_LIMIT: f32 = 1e37;

/// Replaces each corner id in `vertices` by the first corner in `vertices` with the same
/// position, normal and texture coordinate (compared with `==`): the reference's weld classes,
/// with other representatives. Corners of one vertex index are equal without a look; the
/// distinct vertices are matched through a hash table of their values (open addressing, at
/// most half full, 4 bytes a slot). Returns false (with `vertices` partly rewritten) where the
/// classes or the result may differ from the reference's: a NaN (equal to nothing), an
/// infinity or a value past [`WELD_BY_VALUE_LIMIT`] (the reference's splits stop there), or a
/// class whose members differ in the sign of a zero (`==` welds -0 to +0, and then which one
/// represents the class can change the sign of a zero in the tangent).
fn weld_by_value(mesh: &Mesh, vertices: &mut [u32]) -> bool {
    // A vertex's eight values as bits.
    let key = |v: usize| -> Option<[u32; 8]> {
        let (p, n, t) = (mesh.positions[v], mesh.normals[v], mesh.uvs[v]);
        let values = [p[0], p[1], p[2], n[0], n[1], n[2], t[0], t[1]];
        // (NaN fails the comparison too.)
        values
            .iter()
            .all(|x| x.abs() < WELD_BY_VALUE_LIMIT)
            .then(|| values.map(f32::to_bits))
    };
    // Equal under `==`: -0 and +0 alike. Adding +0 turns every zero into +0 (IEEE 754, round
    // to nearest), so values equal under `==` have equal canonical bits.
    let canonical = |bits: [u32; 8]| bits.map(|b| (f32::from_bits(b) + 0.0).to_bits());
    let mut class = vec![NONE; mesh.positions.len()];
    let bits = (2 * class.len().min(vertices.len()))
        .max(2)
        .next_power_of_two()
        .trailing_zeros();
    let mut table = vec![NONE; 1 << bits];
    let mask = table.len() - 1;
    for slot in vertices.iter_mut() {
        let corner = *slot;
        let v = mesh.indices[corner as usize] as usize;
        if class[v] == NONE {
            let Some(values) = key(v) else {
                return false;
            };
            let equal = canonical(values);
            // FxHash's word step (rustc's hasher: rotate, xor, multiply by an odd constant);
            // the slot from the product's well-mixed high bits.
            let hash = equal.iter().fold(0u64, |h, &w| {
                (h.rotate_left(5) ^ w as u64).wrapping_mul(0xf135_7aea_2e62_a9c5)
            });
            let mut at = (hash >> (64 - bits)) as usize;
            class[v] = loop {
                let held = table[at];
                if held == NONE {
                    table[at] = corner;
                    break corner;
                }
                // (Every vertex in the table passed `key`.)
                let other = key(mesh.indices[held as usize] as usize).unwrap_or_default();
                if canonical(other) == equal {
                    if other != values {
                        return false;
                    }
                    break held;
                }
                at = (at + 1) & mask;
            };
        }
        *slot = class[v];
    }
    true
}

/// The neighbours [`build_neighbors`] finds, where no edge has a choice of partner: for every
/// pair of welded end points either at most one edge runs each way, or all run the same way.
/// Then the reference's pairing joins exactly the opposite pairs, whatever order it visits the
/// edges in, and whichever corner represents each weld class. `None` where some edge has a
/// choice (a non-manifold edge with edges both ways): the reference's order decides there.
fn unique_neighbors(vertices: &[u32]) -> Option<Vec<[u32; 3]>> {
    let n = vertices.len();
    let max_i0 = (0..n).map(|k| edge_key(vertices, k).0).max()?;
    let (sorted, starts) = counting_sort_edges(vertices, max_i0, false);
    let id = |x: u64| x as u32 as usize;
    let mut neighbors = vec![[NONE; 3]; n / 3];
    for (i0, run) in starts.windows(2).enumerate() {
        let run = &sorted[run[0] as usize..run[1] as usize];
        for same in run.chunk_by(|a, b| a >> 32 == b >> 32) {
            let forward = |&e: &u64| edge_ends(vertices, id(e)).0 as usize == i0;
            match same {
                [_] => {}
                [a, b] => {
                    if forward(a) != forward(b) {
                        let (ka, kb) = (id(*a), id(*b));
                        neighbors[ka / 3][ka % 3] = (kb / 3) as u32;
                        neighbors[kb / 3][kb % 3] = (ka / 3) as u32;
                    }
                }
                _ => {
                    let ahead = same.iter().filter(|e| forward(e)).count();
                    if ahead != 0 && ahead != same.len() {
                        return None;
                    }
                }
            }
        }
    }
    Some(neighbors)
}

/// The reference's choice of axis: y if strictly longest, else z if longer than x, else x.
#[inline]
fn longest_axis(d: V3) -> usize {
    if d[1] > d[0] && d[1] > d[2] {
        1
    } else if d[2] > d[0] {
        2
    } else {
        0
    }
}

/// The reference's `merge_verts_fast`, same splits and swaps; in a leaf each corner takes the
/// id of the first earlier corner equal to it (equality is transitive, so that is the first
/// of its class, whose id the reference's chain of copies also ends at).
fn merge_verts(buffer: &mut [WeldVertex]) {
    if buffer.len() < 2 {
        return;
    }
    let (mut min, mut max) = (buffer[0].position, buffer[0].position);
    for w in buffer.iter() {
        for c in 0..3 {
            min[c] = min[c].min(w.position[c]);
            max[c] = max[c].max(w.position[c]);
        }
    }
    let c = longest_axis(sub(max, min));
    let sep = 0.5f32 * (max[c] + min[c]);
    if !sep.is_finite() {
        return;
    }
    if !(min[c] < sep && sep < max[c]) {
        for l in 1..buffer.len() {
            let a = buffer[l];
            if let Some(b) = buffer[..l]
                .iter()
                .find(|b| b.position == a.position && b.normal == a.normal && b.uv == a.uv)
            {
                buffer[l].rep = b.rep;
            }
        }
        return;
    }
    let mut unsorted = 0..buffer.len();
    while unsorted.len() >= 2 {
        let a = unsorted.find(|&i| buffer[i].position[c] >= sep);
        let b = (&mut unsorted).rev().find(|&i| buffer[i].position[c] < sep);
        unsorted = match (a, b) {
            (Some(a), Some(b)) => {
                buffer.swap(a, b);
                (a + 1)..b
            }
            (None, Some(b)) => unsorted.start..(b + 1),
            (Some(a), None) => a..(a + 1),
            (None, None) => unsorted,
        };
    }
    let partition = if !unsorted.is_empty() && buffer[unsorted.start].position[c] < sep {
        unsorted.start + 1
    } else {
        unsorted.start
    };
    let (lesser, greater) = buffer.split_at_mut(partition);
    merge_verts(lesser);
    merge_verts(greater);
}

/// Edge `k` of the good triangles is edge `k % 3` (corner `k % 3` to the next) of triangle
/// `k / 3`; its welded end points.
#[inline]
fn edge_ends(vertices: &[u32], k: usize) -> (u32, u32) {
    let f = k - k % 3;
    (vertices[k], vertices[f + (k + 1) % 3])
}

/// An edge's end points in ascending order, `(i0, i1)`.
#[inline]
fn edge_key(vertices: &[u32], k: usize) -> (u32, u32) {
    let (a, b) = edge_ends(vertices, k);
    (a.min(b), a.max(b))
}

/// Pairs the edges of the good triangles as the reference does: in the order of
/// [`sort_edges`], each edge takes the first later edge with the same end points, the opposite
/// direction and no neighbour yet, looking only while the end points stay the same.
///
/// Returns, for each good triangle, the neighbouring triangle across edge `i` (corner `i` to
/// corner `i + 1`), `u32::MAX` for none. A 12-byte record of its own, not a field of
/// [`Triangle`]: the pairing reads it in edge order, all over the triangles, and a 52-byte
/// stride put nearly every read on a cache line of its own.
fn build_neighbors(vertices: &[u32]) -> Vec<[u32; 3]> {
    let mut neighbors = vec![[NONE; 3]; vertices.len() / 3];
    let (sorted, starts) = sort_edges(vertices);
    let i1 = |x: u64| (x >> 32) as u32;
    let id = |x: u64| x as u32 as usize;
    let taken = |neighbors: &[[u32; 3]], k: usize| neighbors[k / 3][k % 3] != NONE;
    // Runs of one i0 are contiguous; the pairing never looks past the end of its run.
    for run in starts.windows(2) {
        let run = &sorted[run[0] as usize..run[1] as usize];
        for (index, &a) in run.iter().enumerate() {
            let ka = id(a);
            if taken(&neighbors, ka) {
                continue;
            }
            let (a0, a1) = edge_ends(vertices, ka);
            let found = run[index + 1..]
                .iter()
                .take_while(|&&b| i1(b) == i1(a))
                .find(|&&b| {
                    let (b1, b0) = edge_ends(vertices, id(b));
                    (a0, a1) == (b0, b1) && !taken(&neighbors, id(b))
                })
                .copied();
            if let Some(b) = found {
                let kb = id(b);
                neighbors[ka / 3][ka % 3] = (kb / 3) as u32;
                neighbors[kb / 3][kb % 3] = (ka / 3) as u32;
            }
        }
    }
    neighbors
}

/// Puts the edges in the order the reference's `quick_sort_edges` (`quick_sort_legacy.rs`,
/// which replicates an off-by-one of the C code) leaves them: sorted by `(i0, i1, f)`, except
/// the run with the largest `i0`, which is in the order a seeded quick sort on `i0` alone
/// leaves it, then sorted by `f` within each run of equal `i1` except the last run.
///
/// Returns each edge as `i1 << 32 | k` (edge id `k = 3 f + e`, so ordering by `k` orders by
/// `f`: keys are unique) in that order, and where each `i0`'s run starts (its last entry is
/// the number of edges): `i0` is implicit, so an entry is 8 bytes, not a 16-byte struct, and
/// no list of edges is built before sorting (the struct version built, sorted and copied
/// three 740 KB buffers for DamagedHelmet's 46,356 edges, 1.0-1.3 ms cold, mostly page faults).
///
/// The keys are unique, so the sorted part may come from any sort: a counting sort on `i0`
/// (ids are below the number of corners) and a small sort per bucket. The last run's order
/// depends on every swap the quick sort makes on the ranges that hold it, so those are
/// replayed: ranges without a largest-`i0` edge cannot move one and are skipped.
fn sort_edges(vertices: &[u32]) -> (Vec<u64>, Vec<u32>) {
    let n = vertices.len();
    let Some(max_i0) = (0..n).map(|k| edge_key(vertices, k).0).max() else {
        return (Vec::new(), vec![0]);
    };
    // The replay of the quick sort needs only the keys, so it runs beside the counting sort.
    let (replay, (mut sorted, starts)) = rayon::join(
        || {
            let mut replay: Vec<(u32, u32)> = (0..n)
                .map(|k| (edge_key(vertices, k).0, k as u32))
                .collect();
            replay_quick_sort(&mut replay, max_i0, INTERNAL_RND_SORT_SEED);
            replay
        },
        || counting_sort_edges(vertices, max_i0, true),
    );
    let good_len = starts[max_i0 as usize] as usize;
    let tail = &mut sorted[good_len..];
    for (slot, &(_, k)) in tail.iter_mut().zip(replay.iter().filter(|e| e.0 == max_i0)) {
        *slot = (edge_key(vertices, k as usize).1 as u64) << 32 | k as u64;
    }
    drop(replay);
    // The reference's off-by-one: every run of equal i1 but the last is sorted by f.
    let mut runs: Vec<&mut [u64]> = tail.chunk_by_mut(|a, b| a >> 32 == b >> 32).collect();
    runs.pop();
    for run in runs {
        run.sort_unstable();
    }
    (sorted, starts)
}

/// The edges sorted by `(i0, i1, k)` (a counting sort on `i0`, then each run by
/// `i1 << 32 | k`), and where each `i0`'s run starts. With `leave_last`, the largest `i0`'s
/// run is left out, its room left at the end.
fn counting_sort_edges(vertices: &[u32], max_i0: u32, leave_last: bool) -> (Vec<u64>, Vec<u32>) {
    let n = vertices.len();
    let n_keys = max_i0 as usize + 1;
    let mut starts = vec![0u32; n_keys + 1];
    for k in 0..n {
        starts[edge_key(vertices, k).0 as usize + 1] += 1;
    }
    for k in 0..n_keys {
        starts[k + 1] += starts[k];
    }
    let mut sorted = vec![0u64; n];
    let mut next = starts.clone();
    for k in 0..n {
        let (i0, i1) = edge_key(vertices, k);
        if !(leave_last && i0 == max_i0) {
            let slot = &mut next[i0 as usize];
            sorted[*slot as usize] = (i1 as u64) << 32 | k as u64;
            *slot += 1;
        }
    }
    drop(next);
    let sorted_keys = if leave_last { n_keys } else { n_keys + 1 };
    for run in starts[..sorted_keys].windows(2) {
        let run = &mut sorted[run[0] as usize..run[1] as usize];
        if run.len() > 1 {
            run.sort_unstable();
        }
    }
    (sorted, starts)
}

/// The reference's `quick_sort_by_key_with_seed` on `i0` (the first of each pair; the second
/// is the edge's id), recursing only into ranges that hold an edge with `i0 == max_i0`.
fn replay_quick_sort(buffer: &mut [(u32, u32)], max_i0: u32, seed: u32) {
    if !buffer.iter().any(|e| e.0 == max_i0) {
        return;
    }
    if buffer.len() <= 2 {
        buffer.sort_unstable_by_key(|e| e.0);
        return;
    }
    let seed = {
        let t = seed & 31;
        let t = seed.wrapping_shl(t) | seed.wrapping_shr(32_u32.wrapping_sub(t));
        seed.wrapping_add(t).wrapping_add(3)
    };
    let pivot = buffer[seed.wrapping_rem(buffer.len() as u32) as usize].0;
    let (mut a, mut b) = (0usize, buffer.len() - 1);
    while a <= b {
        // Both scans stop at the pivot's value at the latest (it stays in the range).
        while buffer[a].0 < pivot {
            a += 1;
        }
        while buffer[b].0 > pivot {
            b -= 1;
        }
        if a <= b {
            buffer.swap(a, b);
            a += 1;
            if b == 0 {
                // The reference's saturating_sub: b stays 0 and the loop ends with a > b.
                break;
            }
            b -= 1;
        }
    }
    let (lesser, rest) = buffer.split_at_mut(b + 1);
    let (_, greater) = rest.split_at_mut(a - lesser.len());
    replay_quick_sort(lesser, max_i0, seed);
    replay_quick_sort(greater, max_i0, seed);
}

const INTERNAL_RND_SORT_SEED: u32 = 39871946;

/// A vertex group: the good triangles around one welded vertex reachable from each other
/// across shared edges, with one orientation.
struct Group {
    /// Its index in the list of groups, the id its corners carry.
    id: u32,
    /// The welded corner id of the vertex.
    vertex: u32,
    orientation_preserving: bool,
    /// Its member triangles (indices among the good ones), in discovery order, are
    /// `GroupList::faces[start..end]` (one flat list: ~15,000 small vectors cost ~1 ms).
    start: u32,
    end: u32,
}

/// The groups, and their members in one list.
struct GroupList {
    groups: Vec<Group>,
    faces: Vec<u32>,
}

/// The reference's `build_4_rule_groups`: corners in order start a group unless taken or their
/// triangle groups with anything; a depth-first walk (same order as the reference's
/// recursion) across the two edges at the vertex adds the triangles of the same orientation.
fn build_groups(triangles: &mut [Triangle], neighbors: &[[u32; 3]], vertices: &[u32]) -> GroupList {
    // At most one group a corner: reserved, not grown (growing copied it ~14 times), and
    // pages of the reservation that are never written are never faulted in.
    let mut groups = Vec::with_capacity(vertices.len());
    let mut faces: Vec<u32> = Vec::with_capacity(vertices.len());
    let mut stack: Vec<u32> = Vec::new();
    for f in 0..triangles.len() {
        for i in 0..3 {
            let info = &mut triangles[f];
            if info.group_with_any || info.group[i] != NONE {
                continue;
            }
            let id = groups.len() as u32;
            let vertex = vertices[3 * f + i];
            let orientation = info.orientation_preserving;
            let start = faces.len() as u32;
            faces.push(f as u32);
            info.group[i] = id;
            // Pushed in reverse so that the first neighbour is walked first.
            stack.clear();
            for k in [i, (i + 2) % 3] {
                if neighbors[f][k] != NONE {
                    stack.push(neighbors[f][k]);
                }
            }
            while let Some(t) = stack.pop() {
                let t = t as usize;
                let Some(j) = vertices[3 * t..3 * t + 3].iter().position(|&v| v == vertex) else {
                    continue;
                };
                let info = &mut triangles[t];
                if info.group[j] != NONE {
                    continue;
                }
                if info.group_with_any && info.group == [NONE; 3] {
                    // The first group to reach a group-with-anything triangle sets its
                    // orientation (the reference's one order dependency).
                    info.orientation_preserving = orientation;
                }
                if info.orientation_preserving != orientation {
                    continue;
                }
                faces.push(t as u32);
                info.group[j] = id;
                for k in [j, (j + 2) % 3] {
                    if neighbors[t][k] != NONE {
                        stack.push(neighbors[t][k]);
                    }
                }
            }
            groups.push(Group {
                id,
                vertex,
                orientation_preserving: orientation,
                start,
                end: faces.len() as u32,
            });
        }
    }
    GroupList { groups, faces }
}

/// A chunk of groups evaluated: each group's tangent, and `(corner, tangent)` for the members
/// whose tangent differs from their group's.
type Evaluated = (Vec<[f32; 4]>, Vec<(u32, [f32; 4])>);

/// Reused buffers of [`evaluate_group`].
#[derive(Default)]
struct GroupScratch {
    /// Members sorted, with their projected s and t.
    members: Vec<(u32, V3, V3)>,
    /// Distinct sub-groups found so far: their members are `sub_group_faces[start..end]`.
    sub_groups: Vec<(usize, usize, V3)>,
    sub_group_faces: Vec<u32>,
    current: Vec<u32>,
}

/// The reference's per-group loop of `generate_tangent_spaces`: for each member triangle the
/// members whose projected tangents agree (with the threshold of -1 nearly all) form a
/// sub-group, whose angle-weighted mean tangent the member's corner gets. Returns the first
/// member's tangent, and pushes `(corner, tangent)` for every member whose tangent differs
/// from it (in any bit).
#[allow(clippy::too_many_arguments)]
fn evaluate_group(
    group: &Group,
    group_faces: &[u32],
    triangles: &[Triangle],
    vertices: &[u32],
    order: &[u32],
    mesh: &Mesh,
    scratch: &mut GroupScratch,
    apart: &mut Vec<(u32, [f32; 4])>,
) -> [f32; 4] {
    let n = mesh.normal(group.vertex as usize);
    let faces = &group_faces[group.start as usize..group.end as usize];
    scratch.members.clear();
    scratch.members.extend(faces.iter().map(|&f| {
        let info = &triangles[f as usize];
        (f, project(info.s, n), project(info.t, n))
    }));
    // The reference sorts each sub-group; filtering sorted members gives the same lists.
    scratch.members.sort_unstable_by_key(|m| m.0);
    scratch.sub_groups.clear();
    scratch.sub_group_faces.clear();
    let sign = if group.orientation_preserving {
        1.0
    } else {
        -1.0
    };
    let mut first: Option<[f32; 4]> = None;
    for &f in faces {
        let a = &triangles[f as usize];
        let Some(&(_, s_a, t_a)) = scratch.members.iter().find(|m| m.0 == f) else {
            continue;
        };
        scratch.current.clear();
        for &(g, s_b, t_b) in &scratch.members {
            let b = &triangles[g as usize];
            let meets = dot(s_a, s_b) > THRESHOLD && dot(t_a, t_b) > THRESHOLD;
            if a.group_with_any || b.group_with_any || g == f || meets {
                scratch.current.push(g);
            }
        }
        let s = match scratch
            .sub_groups
            .iter()
            .find(|&&(start, end, _)| scratch.sub_group_faces[start..end] == scratch.current)
        {
            Some(&(_, _, s)) => s,
            None => {
                let s = sub_group_tangent(
                    &scratch.current,
                    &scratch.members,
                    triangles,
                    vertices,
                    group.vertex,
                    mesh,
                    n,
                );
                let start = scratch.sub_group_faces.len();
                scratch.sub_group_faces.extend_from_slice(&scratch.current);
                scratch
                    .sub_groups
                    .push((start, scratch.sub_group_faces.len(), s));
                s
            }
        };
        let Some(i) = a.group.iter().position(|&g| g == group.id) else {
            continue;
        };
        let tangent = [s[0], s[1], s[2], sign];
        match first {
            None => first = Some(tangent),
            Some(t) if t.map(f32::to_bits) == tangent.map(f32::to_bits) => {}
            Some(_) => apart.push((3 * order[f as usize] + i as u32, tangent)),
        }
    }
    // (A group's first member always gets a tangent: it started the group at this corner.)
    first.unwrap_or([f32::NAN; 4])
}

/// The reference's `evaluate_tangent_space`, s only: the angle-weighted sum of the members'
/// projected tangents (sorted member order, the reference's), normalized.
fn sub_group_tangent(
    members: &[u32],
    projected: &[(u32, V3, V3)],
    triangles: &[Triangle],
    vertices: &[u32],
    vertex: u32,
    mesh: &Mesh,
    n: V3,
) -> V3 {
    let mut res = [0.0f32; 3];
    for &f in members {
        let info = &triangles[f as usize];
        if info.group_with_any {
            continue;
        }
        let tri = &vertices[3 * f as usize..][..3];
        let Some(i) = tri.iter().position(|&v| v == vertex) else {
            continue;
        };
        let p1 = mesh.position(tri[i] as usize);
        let p0 = mesh.position(tri[(i + 1) % 3] as usize);
        let p2 = mesh.position(tri[(i + 2) % 3] as usize);
        let v0 = project(sub(p0, p1), n);
        let v1 = project(sub(p2, p1), n);
        let cos = dot(v0, v1).clamp(-1.0, 1.0);
        let angle = (cos as f64).acos() as f32;
        let Some(&(_, s, _)) = projected.iter().find(|m| m.0 == f) else {
            continue;
        };
        res = add(res, scale(s, angle));
    }
    normalized_or_zero(res)
}

/// The reference comparison, shared with the test of a real model's corners in `tangents`
/// (which gathers them from a loaded scene).
#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// The same corners as `bevy_mikktspace` geometry: the reference.
    struct Reference<'a> {
        corners: &'a Corners<'a>,
        out: Vec<Option<[f32; 4]>>,
    }

    impl bevy_mikktspace::Geometry for Reference<'_> {
        fn num_faces(&self) -> usize {
            self.corners.indices.len() / 3
        }
        fn num_vertices_of_face(&self, _face: usize) -> usize {
            3
        }
        fn position(&self, face: usize, vert: usize) -> [f32; 3] {
            self.corners.positions[self.corners.indices[3 * face + vert] as usize]
        }
        fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
            self.corners.normals[self.corners.indices[3 * face + vert] as usize]
        }
        fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
            self.corners.uvs[self.corners.indices[3 * face + vert] as usize]
        }
        fn set_tangent(
            &mut self,
            tangent_space: Option<bevy_mikktspace::TangentSpace>,
            face: usize,
            vert: usize,
        ) {
            self.out[3 * face + vert] = tangent_space.map(|ts| ts.tangent_encoded());
        }
    }

    fn reference(corners: &Corners) -> Vec<Option<[f32; 4]>> {
        let mut geometry = Reference {
            corners,
            out: vec![None; corners.indices.len() / 3 * 3],
        };
        assert!(bevy_mikktspace::generate_tangents(&mut geometry).is_ok());
        geometry.out
    }

    fn bits(t: &[Option<[f32; 4]>]) -> Vec<Option<[u32; 4]>> {
        t.iter().map(|t| t.map(|t| t.map(f32::to_bits))).collect()
    }

    /// Ours against the reference, bit for bit (tangent xyz, sign, and which corners get
    /// none), at 1 and 2 threads. Returns how many corners got a tangent.
    pub(crate) fn assert_matches(name: &str, corners: &Corners) -> usize {
        let expected = bits(&reference(corners));
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool");
            let ours = bits(&pool.install(|| generate(corners)).to_vec());
            assert_eq!(ours.len(), expected.len(), "{name}");
            if let Some(c) = (0..ours.len()).find(|&c| ours[c] != expected[c]) {
                panic!(
                    "{name}, {threads} thread(s): corner {c} (triangle {}) is {:?}, the reference {:?}",
                    c / 3,
                    ours[c].map(|b| b.map(f32::from_bits)),
                    expected[c].map(|b| b.map(f32::from_bits)),
                );
            }
        }
        expected.iter().filter(|t| t.is_some()).count()
    }

    /// Attribute arrays and their indices (per corner, 0, 1, 2, ... unless built indexed).
    #[derive(Default)]
    struct TestMesh {
        positions: Vec<V3>,
        normals: Vec<V3>,
        uvs: Vec<[f32; 2]>,
        indices: Vec<u32>,
    }

    impl TestMesh {
        fn corners(&self) -> Corners<'_> {
            Corners {
                positions: &self.positions,
                normals: &self.normals,
                uvs: &self.uvs,
                indices: &self.indices,
            }
        }

        /// A corner of its own.
        fn push(&mut self, p: V3, n: V3, uv: [f32; 2]) {
            self.indices.push(self.positions.len() as u32);
            self.positions.push(p);
            self.normals.push(n);
            self.uvs.push(uv);
        }

        /// An indexed mesh, flattened.
        fn from_indexed(p: &[V3], n: &[V3], uv: &[[f32; 2]], tris: &[[usize; 3]]) -> TestMesh {
            let mut mesh = TestMesh::default();
            for tri in tris {
                for &v in tri {
                    mesh.push(p[v], n[v], uv[v]);
                }
            }
            mesh
        }

        /// Every corner its own vertex.
        fn flattened(&self) -> TestMesh {
            let mut mesh = TestMesh::default();
            for &v in &self.indices {
                let v = v as usize;
                mesh.push(self.positions[v], self.normals[v], self.uvs[v]);
            }
            mesh
        }

        /// An indexed mesh, as it is.
        fn indexed(p: &[V3], n: &[V3], uv: &[[f32; 2]], tris: &[[usize; 3]]) -> TestMesh {
            TestMesh {
                positions: p.to_vec(),
                normals: n.to_vec(),
                uvs: uv.to_vec(),
                indices: tris.iter().flatten().map(|&v| v as u32).collect(),
            }
        }
    }

    fn normalize(v: V3) -> V3 {
        let l = length(v);
        if l > 0.0 {
            scale(v, 1.0 / l)
        } else {
            [0.0, 0.0, 1.0]
        }
    }

    /// A UV sphere: `rings` x `segments` quads as triangles, a seam column of duplicated
    /// vertices at u = 0 and u = 1, and fans at the poles. With `mirror`, the right half
    /// of the texture mirrors the left (u -> 1 - u), which flips the tangent frame there.
    fn uv_sphere(rings: usize, segments: usize, mirror: bool) -> TestMesh {
        uv_sphere_indexed(rings, segments, mirror).flattened()
    }

    /// [`uv_sphere`] with each vertex once, indexed.
    fn uv_sphere_indexed(rings: usize, segments: usize, mirror: bool) -> TestMesh {
        let (mut p, mut n, mut uv) = (Vec::new(), Vec::new(), Vec::new());
        for r in 0..=rings {
            let theta = std::f32::consts::PI * r as f32 / rings as f32;
            for s in 0..=segments {
                let phi = std::f32::consts::TAU * s as f32 / segments as f32;
                let q = [
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                ];
                p.push(scale(q, 2.0));
                n.push(q);
                let u = s as f32 / segments as f32;
                let u = if mirror && u > 0.5 { 1.0 - u } else { u };
                uv.push([2.0 * u, r as f32 / rings as f32]);
            }
        }
        let id = |r: usize, s: usize| r * (segments + 1) + s;
        let mut tris = Vec::new();
        for r in 0..rings {
            for s in 0..segments {
                let (a, b, c, d) = (id(r, s), id(r, s + 1), id(r + 1, s), id(r + 1, s + 1));
                tris.push([a, c, b]);
                tris.push([b, c, d]);
            }
        }
        TestMesh::indexed(&p, &n, &uv, &tris)
    }

    #[test]
    fn uv_sphere_with_a_seam_matches_the_reference() {
        let got = assert_matches("sphere", &uv_sphere(24, 48, false).corners());
        assert!(got > 0);
        // Large enough that every parallel step splits (2 * 120 * 240 = 57,600 triangles).
        assert_matches("big sphere", &uv_sphere(120, 240, false).corners());
    }

    /// The sphere as an indexed mesh (each vertex once, shared by its triangles) gives what the
    /// reference gives for it, and, corner for corner, what the same sphere given per corner
    /// gives; and unmirrored it takes the fast weld (manifold: no edge has a choice of
    /// partner), which finds the reference's classes and neighbours.
    #[test]
    fn indexed_input_matches_the_reference_and_welds_by_value() {
        for mirror in [false, true] {
            let indexed = uv_sphere_indexed(24, 48, mirror);
            assert!(indexed.positions.len() < indexed.indices.len() / 2);
            let got = assert_matches("indexed sphere", &indexed.corners());
            assert!(got > 0);
            let flat = indexed.flattened();
            assert_eq!(
                bits(&generate(&indexed.corners()).to_vec()),
                bits(&generate(&flat.corners()).to_vec())
            );
            // (Mirrored, the poles' vertices of one texture coordinate weld, and their
            // positions differ in the sign of zeros: the reference's weld decides there.)
            let fast: &[&TestMesh] = if mirror { &[] } else { &[&indexed, &flat] };
            for mesh in fast {
                let corners = mesh.corners();
                let mesh = corners.mesh();
                let order: Vec<u32> = (0..corners.indices.len() as u32 / 3).collect();
                let mut vertices: Vec<u32> = (0..corners.indices.len() as u32).collect();
                assert!(weld_by_value(&mesh, &mut vertices));
                assert!(unique_neighbors(&vertices).is_some());
                // The same classes as the reference's weld, and the same neighbours.
                let mut exact: Vec<u32> = (0..corners.indices.len() as u32).collect();
                weld(&mesh, &mut exact);
                let (fast, _) = weld_and_pair(&mesh, &order, order.len());
                assert_eq!(fast, vertices);
                for k in 0..exact.len() {
                    for j in [k / 3 * 3, exact.len() - 1 - k] {
                        assert_eq!(exact[k] == exact[j], vertices[k] == vertices[j], "{k} {j}");
                    }
                }
                assert_eq!(unique_neighbors(&vertices), Some(build_neighbors(&exact)));
            }
        }
    }

    /// Where an edge has a choice of partner (three triangles on one edge, two of them running
    /// it the same way), or a value could weld differently in the reference (NaN, infinity), the
    /// fast weld steps aside; the result still matches the reference.
    #[test]
    fn ambiguous_edges_and_odd_values_take_the_reference_weld() {
        let up = [0.0, 0.0, 1.0];
        let p = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.5, 1.0, 0.0],
            [0.5, -1.0, 0.0],
            [0.5, 0.0, 1.0],
        ];
        let uv = [[0.0, 0.0], [1.0, 0.0], [0.5, 1.0], [0.5, -1.0], [0.5, 0.5]];
        // Edge 0-1: triangles 0 and 2 run it 0 -> 1, triangle 1 runs it 1 -> 0.
        let tris = [[0, 1, 2], [1, 0, 3], [0, 1, 4]];
        let mesh = TestMesh::indexed(&p, &[up; 5], &uv, &tris);
        let corners = mesh.corners();
        let view = corners.mesh();
        let mut vertices: Vec<u32> = (0..9).collect();
        assert!(weld_by_value(&view, &mut vertices));
        assert_eq!(unique_neighbors(&vertices), None);
        assert_matches("three triangles on an edge", &corners);

        // Two vertices equal under `==` but for the sign of a zero (normals (0, 0, 1) and
        // (-0, 0, 1) at one position): one weld class, whose representative's bits matter.
        let mut split = TestMesh::indexed(&p, &[up; 5], &uv, &tris[..2]);
        split.positions.push(split.positions[0]);
        split.normals.push([-0.0, 0.0, 1.0]);
        split.uvs.push(split.uvs[0]);
        split.indices[3] = 5;
        let corners = split.corners();
        let mut vertices: Vec<u32> = (0..6).collect();
        assert!(!weld_by_value(&corners.mesh(), &mut vertices));
        assert_matches("-0 and +0 welded", &corners);

        for odd in [f32::NAN, f32::INFINITY, 2e38] {
            let mut mesh = TestMesh::indexed(&p, &[up; 5], &uv, &tris[..2]);
            mesh.uvs[4][0] = odd;
            mesh.normals[2][1] = odd;
            let corners = mesh.corners();
            let view = corners.mesh();
            let mut vertices: Vec<u32> = (0..6).collect();
            assert!(!weld_by_value(&view, &mut vertices), "{odd}");
            assert_matches(&format!("{odd} in the input"), &corners);
        }
    }

    /// A fan around one vertex whose texture turns half a turn more than the fan: its first
    /// and last triangles have exactly opposite tangents, so (threshold -1) they fall into
    /// different sub-groups and the vertex's corners get different tangents.
    #[test]
    fn a_vertex_whose_tangents_part_matches_the_reference() {
        // Position angle and texture angle of the fan's rim, in degrees.
        let rim = [
            (0, 0),
            (90, 90),
            (120, 180),
            (150, 270),
            (180, 360),
            (270, 450),
        ];
        let at = |deg: i32| {
            let r = (deg as f32).to_radians();
            // Exact at the quarter turns, so that the end triangles' tangents are exactly
            // opposite.
            match deg.rem_euclid(360) {
                0 => [1.0, 0.0],
                90 => [0.0, 1.0],
                180 => [-1.0, 0.0],
                270 => [0.0, -1.0],
                _ => [r.cos(), r.sin()],
            }
        };
        let mut p = vec![[0.0; 3]];
        let mut uv = vec![[0.0; 2]];
        for &(position, texture) in &rim {
            let [x, y] = at(position);
            p.push([x, y, 0.0]);
            uv.push(at(texture));
        }
        let tris: Vec<[usize; 3]> = (1..rim.len()).map(|k| [0, k, k + 1]).collect();
        let mesh = TestMesh::indexed(&p, &vec![[0.0, 0.0, 1.0]; p.len()], &uv, &tris);
        assert_matches("a parting fan", &mesh.corners());
        let out = bits(&generate(&mesh.corners()).to_vec());
        let at_centre: Vec<_> = (0..tris.len()).map(|f| out[3 * f]).collect();
        assert!(at_centre.iter().all(Option::is_some));
        assert_ne!(at_centre[0], at_centre[tris.len() - 1]);
    }

    #[test]
    fn mirrored_uvs_match_the_reference() {
        assert_matches("mirrored sphere", &uv_sphere(16, 32, true).corners());
    }

    #[test]
    fn degenerate_triangles_match_the_reference() {
        let mut mesh = uv_sphere(8, 16, false);
        let up = [0.0, 0.0, 1.0];
        // Zero area in space (two equal positions), next to the sphere's first vertices.
        let (p0, p1) = (mesh.positions[0], mesh.positions[1]);
        let (uv0, uv1) = (mesh.uvs[0], mesh.uvs[1]);
        let (n0, n1) = (mesh.normals[0], mesh.normals[1]);
        mesh.push(p0, n0, uv0);
        mesh.push(p1, n1, uv1);
        mesh.push(p1, n1, uv1);
        // Collinear but distinct positions.
        mesh.push([5.0, 0.0, 0.0], up, [0.0, 0.0]);
        mesh.push([6.0, 0.0, 0.0], up, [1.0, 0.0]);
        mesh.push([7.0, 0.0, 0.0], up, [0.0, 1.0]);
        // A zero-length UV edge, and all three UVs equal.
        mesh.push([5.0, 1.0, 0.0], up, [0.5, 0.5]);
        mesh.push([6.0, 1.0, 0.0], up, [0.5, 0.5]);
        mesh.push([5.0, 2.0, 0.0], up, [0.0, 1.0]);
        mesh.push([5.0, 3.0, 0.0], up, [0.2, 0.2]);
        mesh.push([6.0, 3.0, 0.0], up, [0.2, 0.2]);
        mesh.push([5.0, 4.0, 0.0], up, [0.2, 0.2]);
        // A point, and a degenerate triangle with no good neighbour.
        mesh.push(p0, n0, uv0);
        mesh.push(p0, n0, uv0);
        mesh.push(p0, n0, uv0);
        mesh.push([9.0, 9.0, 9.0], up, [0.0, 0.0]);
        mesh.push([9.0, 9.0, 9.0], up, [1.0, 0.0]);
        mesh.push([9.0, 8.0, 9.0], up, [0.0, 1.0]);
        let corners = mesh.corners();
        assert_matches("degenerate", &corners);
        assert!(generate(&corners)
            .to_vec()
            .last()
            .is_some_and(|t| t.is_none()));
    }

    /// Random soups on a small lattice, so that positions repeat (welding, shared and
    /// non-manifold edges, the quick sort's unsorted run), with normals and UVs from small
    /// sets so that a shared position may or may not weld.
    fn random_soup(rng: &mut Rng, triangles: usize, lattice: u32) -> TestMesh {
        let mut mesh = TestMesh::default();
        let pick = |rng: &mut Rng, n: u32| (rng.next_u64() % n as u64) as f32;
        let normals = [
            [0.0, 0.0, 1.0],
            normalize([1.0, 1.0, 1.0]),
            [0.0, -1.0, 0.0],
        ];
        for _ in 0..triangles * 3 {
            let p = [pick(rng, lattice), pick(rng, lattice), pick(rng, lattice)];
            let n = normals[(rng.next_u64() % 3) as usize];
            let uv = [pick(rng, 4) * 0.25, pick(rng, 4) * 0.25];
            mesh.push(p, n, uv);
        }
        mesh
    }

    #[test]
    fn random_soups_match_the_reference() {
        let mut rng = Rng::new(0x5eed);
        for round in 0..300 {
            let triangles = 1 + (rng.next_u64() % 80) as usize;
            let lattice = 2 + (rng.next_u64() % 4) as u32;
            let mesh = random_soup(&mut rng, triangles, lattice);
            assert_matches(&format!("soup {round}"), &mesh.corners());
        }
    }

    /// An indexed random mesh whose triangles share vertices (and so edges, often by more
    /// than two triangles), flattened; some corners of a shared vertex get a different normal.
    #[test]
    fn shared_vertices_with_different_normals_match_the_reference() {
        let mut rng = Rng::new(7);
        for round in 0..100 {
            let verts = 4 + (rng.next_u64() % 12) as usize;
            let p: Vec<V3> = (0..verts)
                .map(|_| [rng.next_f32(), rng.next_f32(), rng.next_f32()])
                .collect();
            let uv: Vec<[f32; 2]> = (0..verts)
                .map(|_| [rng.next_f32(), rng.next_f32()])
                .collect();
            let n: Vec<V3> = p.iter().map(|&q| normalize(sub(q, [0.5; 3]))).collect();
            let tris: Vec<[usize; 3]> = (0..(2 + rng.next_u64() % 40))
                .map(|_| {
                    let a = (rng.next_u64() % verts as u64) as usize;
                    let b = (a + 1 + (rng.next_u64() % (verts as u64 - 1)) as usize) % verts;
                    let mut c = (rng.next_u64() % verts as u64) as usize;
                    while c == a || c == b {
                        c = (c + 1) % verts;
                    }
                    [a, b, c]
                })
                .collect();
            let mut mesh = TestMesh::from_indexed(&p, &n, &uv, &tris);
            for k in 0..mesh.normals.len() {
                if rng.next_u64().is_multiple_of(4) {
                    mesh.normals[k] = normalize(add(mesh.normals[k], [0.0, 1.0, 0.0]));
                }
            }
            assert_matches(&format!("shared {round}"), &mesh.corners());
        }
    }

    #[test]
    fn nan_and_infinite_input_does_not_panic() {
        let mut rng = Rng::new(3);
        for round in 0..50 {
            let mut mesh = random_soup(&mut rng, 30, 3);
            let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -0.0];
            for k in 0..mesh.positions.len() {
                let value = bad[(rng.next_u64() % 4) as usize];
                match rng.next_u64() % 6 {
                    0 => mesh.positions[k][(round % 3) as usize] = value,
                    1 => mesh.normals[k][1] = value,
                    2 => mesh.uvs[k][0] = value,
                    _ => {}
                }
            }
            let out = generate(&mesh.corners()).to_vec();
            assert_eq!(out.len(), mesh.positions.len());
        }
        assert!(generate(&TestMesh::default().corners()).to_vec().is_empty());
        // Whole triangles only: an index list cut inside a triangle ends before it.
        let mut mesh = random_soup(&mut rng, 2, 3);
        mesh.indices.truncate(5);
        assert_eq!(generate(&mesh.corners()).to_vec().len(), 3);
        // An index past the end of a slice: no tangents, and no panic.
        let mut mesh = random_soup(&mut rng, 2, 3);
        mesh.uvs.truncate(4);
        let out = generate(&mesh.corners()).to_vec();
        assert_eq!(out.len(), 6);
        assert!(out.iter().all(Option::is_none));
    }

    /// Asserts that `corners` take the fast weld: the weld by value, and a unique partner for
    /// every edge (for the test of a real model's corners, in `tangents`).
    pub(crate) fn assert_fast_weld(corners: &Corners) {
        let mut vertices: Vec<u32> = (0..corners.indices.len() as u32).collect();
        assert!(weld_by_value(&corners.mesh(), &mut vertices));
        assert!(unique_neighbors(&vertices).is_some());
    }
}
