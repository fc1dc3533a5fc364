//! Accumulates world-space triangles from any importer into a [`TriangleSoup`], dropping the
//! ones a ray tracer must never see.

use super::error::LoadErrorKind;
use super::soup::{Bounds, TriangleSoup};
use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
use rayon::prelude::*;

/// Triangles of a primitive one thread classifies at least (see
/// [`SoupBuilder::push_primitive`]): below a few thousand, handing work to the other thread
/// costs more than it saves.
const PARALLEL_TRIANGLES: usize = 4096;

/// What becomes of one triangle of a primitive: one byte a triangle; its indices and flat
/// normal are computed again when it is appended (a 40-byte record holding them, grown one
/// push at a time, was most of the classification's time).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Outcome {
    /// NaN or infinite coordinates: dropped.
    NonFinite,
    /// Zero area: dropped.
    Degenerate,
    /// An area single precision cannot hold: dropped.
    OutOfScale,
    /// Kept on the primitive's shared vertices.
    Shared,
    /// Kept on three vertices of its own with its flat normal (a shared normal is unusable).
    Own,
}

/// Why [`classify`] refuses a triangle.
enum Refusal {
    NonFinite,
    Degenerate,
    /// Not degenerate, but its squared normal (edges shorter than about 3e-10 or longer than
    /// about 4e9 units) is outside f32's normal range, where the intersection precompute's
    /// 1/|n|² is not finite.
    OutOfScale,
}

/// A triangle's unnormalised geometric normal `(b - a) × (c - a)` and its squared length, or
/// why a ray tracer must not see it.
fn classify(positions: &[Vec3; 3]) -> Result<(Vec3, f32), Refusal> {
    let [a, b, c] = *positions;
    if !(a.is_finite() && b.is_finite() && c.is_finite()) {
        return Err(Refusal::NonFinite);
    }
    let cross = (b - a).cross(c - a);
    let area2 = cross.length_squared();
    // Below f32::MIN_POSITIVE the squared normal is denormal and 1/|n|² overflows in the
    // intersection precompute; above f32::MAX it is infinite. Either is a zero-area triangle,
    // or one whose size single precision cannot handle: the same area in f64 tells which, so
    // that a model drawn in units far too small or large is not reported as degenerate.
    if !(area2 >= f32::MIN_POSITIVE && area2.is_finite()) {
        let [a, b, c] = positions.map(|p| p.as_dvec3());
        let area2_f64 = (b - a).cross(c - a).length_squared();
        return Err(if area2_f64 > 0.0 {
            Refusal::OutOfScale
        } else {
            Refusal::Degenerate
        });
    }
    Ok((cross, area2))
}

/// One triangle as an importer hands it over, already in world space and front-face
/// counter-clockwise. Missing attributes are `None`. It gets three vertices of its own; a
/// primitive whose triangles share vertices goes through [`SoupBuilder::push_primitive`].
#[derive(Clone, Copy, Debug, Default)]
pub struct TriangleIn {
    /// Vertex positions.
    pub positions: [Vec3; 3],
    /// Shading normals (need not be unit length).
    pub normals: Option<[Vec3; 3]>,
    /// Texture coordinates, set 0.
    pub uv0: Option<[Vec2; 3]>,
    /// Texture coordinates, set 1.
    pub uv1: Option<[Vec2; 3]>,
    /// Vertex colours, linear RGBA.
    pub colors: Option<[Vec4; 3]>,
    /// Tangents (xyz) with handedness (w).
    pub tangents: Option<[Vec4; 3]>,
}

/// A primitive's vertices as an importer hands them over, world space; every present
/// attribute is as long as `positions`.
#[derive(Clone, Copy, Debug, Default)]
pub struct VerticesIn<'a> {
    /// Vertex positions.
    pub positions: &'a [Vec3],
    /// Shading normals (need not be unit length).
    pub normals: Option<&'a [Vec3]>,
    /// Texture coordinates, set 0.
    pub uv0: Option<&'a [Vec2]>,
    /// Texture coordinates, set 1.
    pub uv1: Option<&'a [Vec2]>,
    /// Vertex colours, linear RGBA.
    pub colors: Option<&'a [Vec4]>,
    /// Tangents (xyz) with handedness (w).
    pub tangents: Option<&'a [Vec4]>,
}

impl VerticesIn<'_> {
    /// Triangle `corners` of these vertices as a [`TriangleIn`].
    fn triangle(&self, corners: [usize; 3]) -> TriangleIn {
        TriangleIn {
            positions: corners.map(|i| self.positions[i]),
            normals: self.normals.map(|a| corners.map(|i| a[i])),
            uv0: self.uv0.map(|a| corners.map(|i| a[i])),
            uv1: self.uv1.map(|a| corners.map(|i| a[i])),
            colors: self.colors.map(|a| corners.map(|i| a[i])),
            tangents: self.tangents.map(|a| corners.map(|i| a[i])),
        }
    }

    /// These vertices without any attribute that is not as long as `positions` (importers
    /// check their accessors; this keeps a slip from indexing out of range).
    fn sanitized(&self) -> Self {
        let n = self.positions.len();
        fn keep<T>(a: Option<&[T]>, n: usize) -> Option<&[T]> {
            a.filter(|a| a.len() == n)
        }
        Self {
            positions: self.positions,
            normals: keep(self.normals, n),
            uv0: keep(self.uv0, n),
            uv1: keep(self.uv1, n),
            colors: keep(self.colors, n),
            tangents: keep(self.tangents, n),
        }
    }
}

/// Builds a [`TriangleSoup`], counting what it drops.
#[derive(Debug)]
pub struct SoupBuilder {
    soup: TriangleSoup,
    bounds: Bounds,
    max_triangles: u64,
    /// Triangles dropped for zero area.
    pub degenerate: usize,
    /// Triangles dropped for a size f32 cannot handle: not degenerate, but with edges under
    /// about 3e-10 or over about 4e9 units.
    pub out_of_scale: usize,
    /// Triangles dropped for NaN or infinite coordinates.
    pub non_finite: usize,
}

impl SoupBuilder {
    /// A builder that refuses to grow past `max_triangles`.
    pub fn new(max_triangles: u64) -> Self {
        Self {
            soup: TriangleSoup::default(),
            bounds: Bounds::EMPTY,
            max_triangles,
            degenerate: 0,
            out_of_scale: 0,
            non_finite: 0,
        }
    }

    /// Checks that `additional` more triangles fit the limit, and reserves room for them.
    /// Call it before expanding a primitive so a hostile file cannot allocate without bound.
    pub fn reserve(&mut self, additional: usize) -> Result<(), LoadErrorKind> {
        let count = self.soup.len() as u64 + additional as u64;
        if count > self.max_triangles {
            return Err(LoadErrorKind::TooManyTriangles {
                count,
                limit: self.max_triangles,
            });
        }
        let out_of_memory = |_| LoadErrorKind::OutOfMemory {
            what: format!("{count} triangles"),
            bytes: additional as u64 * (std::mem::size_of::<[u32; 3]>() as u64 + 8),
        };
        self.soup
            .indices
            .try_reserve(additional)
            .map_err(out_of_memory)?;
        self.soup
            .material
            .try_reserve(additional)
            .map_err(out_of_memory)?;
        self.soup
            .instance
            .try_reserve(additional)
            .map_err(out_of_memory)?;
        Ok(())
    }

    /// Adds a triangle with three vertices of its own, unless it is degenerate or not finite
    /// (then it is counted and dropped).
    pub fn push(&mut self, tri: &TriangleIn, material: u32, instance: u32) {
        if let Some(flat) = self.check(&tri.positions) {
            let normals = tri
                .normals
                .map(|ns| ns.map(|n| n.normalize_or_zero()))
                .filter(|ns| ns.iter().all(|n| usable_normal(*n)))
                .unwrap_or([flat; 3]);
            self.push_own_vertices(tri, normals, material, instance);
        }
    }

    /// Adds the `triangle_count` triangles of one primitive: `corners(t)` are triangle t's
    /// indices into `vertices` (in range: the importer checked them), counter-clockwise from
    /// the front. The vertices are stored once and shared by the triangles that use them. A
    /// triangle whose normals are missing or unusable (zero, NaN) gets three vertices of its
    /// own with its flat normal; degenerate and non-finite triangles are counted and dropped.
    ///
    /// Big primitives are classified on every thread (each triangle's outcome depends on it
    /// alone, and bounds are a min and a max, so the soup is the same at any thread count),
    /// then appended in order. Measured on MetalRoughSpheresNoTextures (1.04M triangles in
    /// 123 primitives): this loop was a quarter of the load, one thread.
    pub fn push_primitive(
        &mut self,
        vertices: &VerticesIn,
        triangle_count: usize,
        corners: impl Fn(usize) -> [usize; 3] + Sync,
        material: u32,
        instance: u32,
    ) {
        let vertices = &vertices.sanitized();
        let Some(normals) = vertices.normals else {
            for t in 0..triangle_count {
                self.push(&vertices.triangle(corners(t)), material, instance);
            }
            return;
        };
        let base = self.soup.positions.len();
        let count = vertices.positions.len();
        // Positions no kept triangle uses (a NaN vertex) are stored as the origin, so that
        // nothing reading the vertex arrays meets a non-finite value.
        let soup = &mut self.soup;
        soup.positions.extend(vertices.positions.iter().map(|p| {
            if p.is_finite() {
                *p
            } else {
                Vec3::ZERO
            }
        }));
        soup.normals
            .extend(normals.iter().map(|n| n.normalize_or_zero()));
        append(&mut soup.uv0, base, count, vertices.uv0, Vec2::ZERO);
        append(&mut soup.uv1, base, count, vertices.uv1, Vec2::ZERO);
        append(&mut soup.colors, base, count, vertices.colors, Vec4::ONE);
        append(
            &mut soup.tangents,
            base,
            count,
            vertices.tangents,
            Vec4::ZERO,
        );
        let shared_normals = &soup.normals[base..];
        let classified: Vec<(Vec<Outcome>, Bounds)> = (0..triangle_count)
            .into_par_iter()
            .with_min_len(PARALLEL_TRIANGLES)
            .fold(
                || (Vec::new(), Bounds::EMPTY),
                |(mut outcomes, mut bounds), t| {
                    let c = corners(t);
                    let positions = c.map(|i| vertices.positions[i]);
                    outcomes.push(match classify(&positions) {
                        Err(Refusal::NonFinite) => Outcome::NonFinite,
                        Err(Refusal::Degenerate) => Outcome::Degenerate,
                        Err(Refusal::OutOfScale) => Outcome::OutOfScale,
                        Ok(_) => {
                            for p in positions {
                                bounds.grow(p);
                            }
                            if c.iter().all(|&i| usable_normal(shared_normals[i])) {
                                Outcome::Shared
                            } else {
                                Outcome::Own
                            }
                        }
                    });
                    (outcomes, bounds)
                },
            )
            .collect();
        let mut t = 0;
        for (outcomes, bounds) in classified {
            if bounds.min.cmple(bounds.max).all() {
                self.bounds.grow(bounds.min);
                self.bounds.grow(bounds.max);
            }
            for outcome in outcomes {
                let c = corners(t);
                t += 1;
                match outcome {
                    Outcome::NonFinite => self.non_finite += 1,
                    Outcome::Degenerate => self.degenerate += 1,
                    Outcome::OutOfScale => self.out_of_scale += 1,
                    Outcome::Shared => {
                        self.soup.indices.push(c.map(|i| (base + i) as u32));
                        self.soup.material.push(material);
                        self.soup.instance.push(instance);
                    }
                    Outcome::Own => {
                        let tri = vertices.triangle(c);
                        // Classified as kept above: the same positions give the same answer.
                        if let Ok((cross, area2)) = classify(&tri.positions) {
                            let flat = cross / area2.sqrt();
                            self.push_own_vertices(&tri, [flat; 3], material, instance);
                        }
                    }
                }
            }
        }
    }

    /// Counts and refuses a non-finite or degenerate triangle; otherwise grows the bounds and
    /// returns its flat (unit geometric) normal.
    fn check(&mut self, positions: &[Vec3; 3]) -> Option<Vec3> {
        match classify(positions) {
            Err(Refusal::NonFinite) => {
                self.non_finite += 1;
                None
            }
            Err(Refusal::Degenerate) => {
                self.degenerate += 1;
                None
            }
            Err(Refusal::OutOfScale) => {
                self.out_of_scale += 1;
                None
            }
            Ok((cross, area2)) => {
                for p in positions {
                    self.bounds.grow(*p);
                }
                Some(cross / area2.sqrt())
            }
        }
    }

    /// Appends `tri` as three new vertices with `normals` (unit) and one triangle using them.
    fn push_own_vertices(
        &mut self,
        tri: &TriangleIn,
        normals: [Vec3; 3],
        material: u32,
        instance: u32,
    ) {
        let soup = &mut self.soup;
        let base = soup.positions.len();
        soup.positions.extend(tri.positions);
        soup.normals.extend(normals);
        append(
            &mut soup.uv0,
            base,
            3,
            tri.uv0.as_ref().map(|a| a.as_slice()),
            Vec2::ZERO,
        );
        append(
            &mut soup.uv1,
            base,
            3,
            tri.uv1.as_ref().map(|a| a.as_slice()),
            Vec2::ZERO,
        );
        append(
            &mut soup.colors,
            base,
            3,
            tri.colors.as_ref().map(|a| a.as_slice()),
            Vec4::ONE,
        );
        append(
            &mut soup.tangents,
            base,
            3,
            tri.tangents.as_ref().map(|a| a.as_slice()),
            Vec4::ZERO,
        );
        let v = base as u32;
        soup.indices.push([v, v + 1, v + 2]);
        soup.material.push(material);
        soup.instance.push(instance);
    }

    /// Number of triangles kept so far.
    pub fn len(&self) -> usize {
        self.soup.len()
    }

    /// True when no triangle was kept.
    pub fn is_empty(&self) -> bool {
        self.soup.is_empty()
    }

    /// Triangles offered to [`SoupBuilder::push`], kept or dropped.
    pub fn offered(&self) -> usize {
        self.soup.len() + self.degenerate + self.out_of_scale + self.non_finite
    }

    /// A warning line for what was dropped, if anything was.
    pub fn dropped_warning(&self) -> Option<String> {
        let s = |n: usize| if n == 1 { "" } else { "s" };
        let mut parts = Vec::new();
        if self.degenerate > 0 {
            let n = self.degenerate;
            parts.push(format!("{n} degenerate (zero-area) triangle{}", s(n)));
        }
        if self.out_of_scale > 0 {
            let n = self.out_of_scale;
            parts.push(format!(
                "{n} triangle{} too small or too large for single precision (edges under about \
                 1e-9 or over about 1e9 units; scale the model)",
                s(n)
            ));
        }
        if self.non_finite > 0 {
            let n = self.non_finite;
            parts.push(if parts.is_empty() {
                format!("{n} triangle{} with NaN or infinite coordinates", s(n))
            } else {
                format!("{n} with NaN or infinite coordinates")
            });
        }
        (!parts.is_empty()).then(|| format!("dropped {}", parts.join(" and ")))
    }

    /// The soup and its bounds.
    pub fn finish(self) -> (TriangleSoup, Bounds) {
        (self.soup, self.bounds)
    }
}

/// Places vertices given in a node's local space in the world by its transform `world`
/// (glTF 2.0 §3.7.2.1): positions as points, normals by the inverse transpose (left
/// unnormalised: the builder normalises them), tangents by the linear part with their
/// handedness flipped when `world` mirrors. The caller flips the winding of a mirroring
/// transform.
pub(crate) fn place_vertices(
    world: Mat4,
    positions: &mut [Vec3],
    normals: Option<&mut [Vec3]>,
    tangents: Option<&mut [Vec4]>,
) {
    let linear = Mat3::from_mat4(world);
    let normal_matrix = linear.inverse().transpose();
    let mirror = if world.determinant() < 0.0 { -1.0 } else { 1.0 };
    for p in positions.iter_mut() {
        *p = world.transform_point3(*p);
    }
    for n in normals.into_iter().flatten() {
        *n = normal_matrix * *n;
    }
    for t in tangents.into_iter().flatten() {
        let xyz = (linear * t.truncate()).normalize_or_zero();
        *t = xyz.extend(t.w * mirror);
    }
}

/// A normal a triangle can shade with: unit length after normalising (not zero, not NaN).
fn usable_normal(n: Vec3) -> bool {
    n.is_finite() && n != Vec3::ZERO
}

/// Appends `count` values of an optional per-vertex attribute for the vertices from `base` on:
/// the array stays empty while no vertex has the attribute, and once one has, it is exactly as
/// long as the positions, earlier vertices padded with `default`.
fn append<T: Copy>(vec: &mut Vec<T>, base: usize, count: usize, values: Option<&[T]>, default: T) {
    match values {
        Some(v) => {
            if vec.len() < base {
                vec.resize(base, default);
            }
            vec.extend_from_slice(v);
        }
        None if !vec.is_empty() => vec.resize(base + count, default),
        None => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(a: Vec3, b: Vec3, c: Vec3) -> TriangleIn {
        TriangleIn {
            positions: [a, b, c],
            ..Default::default()
        }
    }

    #[test]
    fn drops_degenerate_and_non_finite_triangles() {
        let mut b = SoupBuilder::new(100);
        b.push(&tri(Vec3::ZERO, Vec3::X, Vec3::Y), 0, 0);
        b.push(&tri(Vec3::ZERO, Vec3::X, Vec3::X * 2.0), 0, 0);
        b.push(&tri(Vec3::ZERO, Vec3::X, Vec3::splat(f32::NAN)), 0, 0);
        b.push(
            &tri(Vec3::ZERO, Vec3::X, Vec3::new(0.0, f32::INFINITY, 0.0)),
            0,
            0,
        );
        assert_eq!((b.len(), b.degenerate, b.non_finite), (1, 1, 2));
        // Not degenerate, but too small or too large for the intersection precompute in f32:
        // counted apart, with a warning that says so.
        b.push(&tri(Vec3::ZERO, Vec3::X * 1e-10, Vec3::Y * 1e-10), 0, 0);
        b.push(&tri(Vec3::ZERO, Vec3::X * 1e10, Vec3::Y * 1e10), 0, 0);
        b.push(&tri(Vec3::ZERO, Vec3::X * 1e-8, Vec3::Y * 1e-8), 0, 0);
        assert_eq!((b.len(), b.degenerate, b.out_of_scale), (2, 1, 2));
        assert_eq!(
            b.dropped_warning().as_deref(),
            Some(
                "dropped 1 degenerate (zero-area) triangle and 2 triangles too small or too \
                 large for single precision (edges under about 1e-9 or over about 1e9 units; \
                 scale the model) and 2 with NaN or infinite coordinates"
            )
        );
        let (soup, bounds) = b.finish();
        assert_eq!(
            soup.corner_normals(0),
            [Vec3::Z; 3],
            "flat normal of a CCW triangle in XY"
        );
        assert_eq!(bounds.max, Vec3::new(1.0, 1.0, 0.0));
    }

    #[test]
    fn optional_attributes_are_padded() {
        let mut b = SoupBuilder::new(100);
        b.push(&tri(Vec3::ZERO, Vec3::X, Vec3::Y), 0, 0);
        let mut t = tri(Vec3::ZERO, Vec3::X, Vec3::Y);
        t.uv0 = Some([Vec2::ONE; 3]);
        b.push(&t, 0, 0);
        b.push(&tri(Vec3::ZERO, Vec3::X, Vec3::Y), 0, 0);
        let (soup, _) = b.finish();
        assert_eq!(soup.uv0.len(), 9, "three vertices a triangle");
        assert_eq!(soup.corner_uvs(0, 0), Some([Vec2::ZERO; 3]));
        assert_eq!(soup.corner_uvs(0, 1), Some([Vec2::ONE; 3]));
        assert_eq!(soup.corner_uvs(0, 2), Some([Vec2::ZERO; 3]));
        assert!(soup.colors.is_empty());
    }

    #[test]
    fn a_primitive_shares_its_vertices() {
        // A quad of two triangles over four vertices, then a triangle whose normal is zero at
        // one corner (it gets its own vertices and its flat normal) and a degenerate one.
        let positions = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::Y,
            Vec3::X * 2.0,
        ];
        let normals = [Vec3::Z * 2.0, Vec3::Z, Vec3::Z, Vec3::ZERO, Vec3::Z];
        let uv0 = [Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y, Vec2::X];
        let vertices = VerticesIn {
            positions: &positions,
            normals: Some(&normals),
            uv0: Some(&uv0),
            ..Default::default()
        };
        let mut b = SoupBuilder::new(100);
        let triangles = [[0, 1, 2], [0, 2, 3], [0, 1, 4]];
        b.push_primitive(&vertices, 3, |t| triangles[t], 3, 1);
        assert_eq!((b.len(), b.degenerate), (2, 1));
        let (soup, _) = b.finish();
        assert_eq!(soup.indices[0], [0, 1, 2]);
        assert_eq!(
            soup.vertex_count(),
            5 + 3,
            "the shared block, then the fallback's own"
        );
        assert_eq!(soup.corner_normals(0), [Vec3::Z; 3], "normalised");
        assert_eq!(
            soup.triangle(1),
            [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y]
        );
        assert_eq!(
            soup.corner_normals(1),
            [Vec3::Z; 3],
            "flat normal where one was zero"
        );
        assert_eq!(
            soup.corner_uvs(0, 1),
            Some([Vec2::ZERO, Vec2::ONE, Vec2::Y])
        );
        assert_eq!(soup.material, [3, 3]);
        assert_eq!(soup.instance, [1, 1]);
    }

    #[test]
    fn a_big_primitive_gives_the_same_soup_on_any_thread_count() {
        // 300x100 grid quads (60,000 triangles, several parallel pieces) with a NaN vertex,
        // a collapsed row (degenerate triangles) and a zero normal (own vertices).
        let (w, h) = (301, 101);
        let mut positions: Vec<Vec3> = (0..w * h)
            .map(|k| Vec3::new((k % w) as f32, ((k / w) as f32 * 0.7).sin(), (k / w) as f32))
            .collect();
        positions[5 * w + 7] = Vec3::splat(f32::NAN);
        for x in 0..w {
            positions[50 * w + x] = positions[49 * w + x];
        }
        let mut normals = vec![Vec3::Y; w * h];
        normals[80 * w + 80] = Vec3::ZERO;
        let mut triangles = Vec::new();
        for j in 0..h - 1 {
            for i in 0..w - 1 {
                let v = j * w + i;
                triangles.push([v, v + w, v + w + 1]);
                triangles.push([v, v + w + 1, v + 1]);
            }
        }
        let vertices = VerticesIn {
            positions: &positions,
            normals: Some(&normals),
            ..Default::default()
        };
        let build = |threads: usize| {
            crate::on_threads(threads, || {
                let mut b = SoupBuilder::new(1_000_000);
                b.push_primitive(&vertices, triangles.len(), |t| triangles[t], 2, 0);
                let counts = (b.degenerate, b.non_finite);
                let (soup, bounds) = b.finish();
                (
                    soup.indices,
                    soup.positions,
                    soup.normals,
                    counts,
                    bounds.min,
                    bounds.max,
                )
            })
        };
        let one = build(1);
        assert_eq!(
            one.3,
            (2 * (w - 1), 6),
            "a collapsed row, six triangles on the NaN"
        );
        assert_eq!(one.0.len(), triangles.len() - 2 * (w - 1) - 6);
        assert_eq!(
            one.1.len(),
            w * h + 6 * 3,
            "six triangles around the zero normal"
        );
        assert!(one == build(2), "the same soup on one thread and on two");
    }

    #[test]
    fn triangle_limit_is_enforced_before_allocating() {
        let mut b = SoupBuilder::new(10);
        assert!(b.reserve(10).is_ok());
        assert!(matches!(
            b.reserve(11),
            Err(LoadErrorKind::TooManyTriangles {
                count: 11,
                limit: 10
            })
        ));
    }
}
