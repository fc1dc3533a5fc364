//! Accumulates world-space triangles from any importer into a [`TriangleSoup`], dropping the
//! ones a ray tracer must never see.

use super::{Bounds, LoadErrorKind, TriangleSoup};
use glam::{Vec2, Vec3, Vec4};

/// One triangle as an importer hands it over, already in world space and front-face
/// counter-clockwise. Missing attributes are `None`.
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

/// Builds a [`TriangleSoup`], counting what it drops.
#[derive(Debug)]
pub struct SoupBuilder {
    soup: TriangleSoup,
    bounds: Bounds,
    max_triangles: u64,
    /// Triangles dropped for zero area.
    pub degenerate: usize,
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
        self.soup.positions.reserve(additional);
        self.soup.normals.reserve(additional);
        self.soup.material.reserve(additional);
        self.soup.instance.reserve(additional);
        Ok(())
    }

    /// Adds a triangle unless it is degenerate or not finite (then it is counted and dropped).
    pub fn push(&mut self, tri: &TriangleIn, material: u32, instance: u32) {
        let [a, b, c] = tri.positions;
        if !(a.is_finite() && b.is_finite() && c.is_finite()) {
            self.non_finite += 1;
            return;
        }
        let cross = (b - a).cross(c - a);
        let area2 = cross.length_squared();
        // Below f32::MIN_POSITIVE the squared normal is denormal and 1/|n|² overflows in the
        // intersection precompute; such a triangle has no visible area anyway.
        if !(area2 >= f32::MIN_POSITIVE && area2.is_finite()) {
            self.degenerate += 1;
            return;
        }
        let flat = cross / area2.sqrt();
        let normals = tri
            .normals
            .map(|ns| ns.map(|n| n.normalize_or_zero()))
            .filter(|ns| ns.iter().all(|n| n.is_finite() && *n != Vec3::ZERO))
            .unwrap_or([flat; 3]);
        let index = self.soup.len();
        push_optional(&mut self.soup.uv0, index, tri.uv0, [Vec2::ZERO; 3]);
        push_optional(&mut self.soup.uv1, index, tri.uv1, [Vec2::ZERO; 3]);
        push_optional(&mut self.soup.colors, index, tri.colors, [Vec4::ONE; 3]);
        push_optional(
            &mut self.soup.tangents,
            index,
            tri.tangents,
            [Vec4::ZERO; 3],
        );
        self.soup.positions.push(tri.positions);
        self.soup.normals.push(normals);
        self.soup.material.push(material);
        self.soup.instance.push(instance);
        for p in tri.positions {
            self.bounds.grow(p);
        }
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
        self.soup.len() + self.degenerate + self.non_finite
    }

    /// A warning line for what was dropped, if anything was.
    pub fn dropped_warning(&self) -> Option<String> {
        match (self.degenerate, self.non_finite) {
            (0, 0) => None,
            (d, 0) => Some(format!("dropped {d} degenerate (zero-area) triangles")),
            (0, n) => Some(format!("dropped {n} triangles with NaN or infinite coordinates")),
            (d, n) => Some(format!(
                "dropped {d} degenerate (zero-area) triangles and {n} with NaN or infinite coordinates"
            )),
        }
    }

    /// The soup and its bounds.
    pub fn finish(self) -> (TriangleSoup, Bounds) {
        (self.soup, self.bounds)
    }
}

/// Keeps an optional per-triangle array either empty (no triangle had the attribute) or exactly
/// as long as the soup, padding earlier triangles with `default` when the attribute first shows up.
fn push_optional<T: Copy>(vec: &mut Vec<T>, index: usize, value: Option<T>, default: T) {
    match value {
        Some(v) => {
            if vec.len() < index {
                vec.resize(index, default);
            }
            vec.push(v);
        }
        None if !vec.is_empty() => vec.push(default),
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
        let (soup, bounds) = b.finish();
        assert_eq!(
            soup.normals[0],
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
        assert_eq!(soup.uv0.len(), 3);
        assert_eq!(soup.uv0[0], [Vec2::ZERO; 3]);
        assert_eq!(soup.uv0[1], [Vec2::ONE; 3]);
        assert!(soup.colors.is_empty());
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
