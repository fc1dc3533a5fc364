//! Rays and the ray/triangle test.

pub mod spawn;
pub mod triangle;

pub use spawn::{SpawnFrame, SpawnPoint, SHADOW_EPSILON};
pub use triangle::{PreparedTriangle, TriangleHit, EDGE_EPSILON};

use glam::{Vec3, Vec3A};

/// A ray `origin + t · direction` for t in the open interval (`tmin`, `tmax`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point, world space.
    pub origin: Vec3A,
    /// Direction (unit length for camera and shadow rays; any non-zero length works).
    pub direction: Vec3A,
    /// Hits at or below this parameter are ignored.
    pub tmin: f32,
    /// Hits at or beyond this parameter are ignored.
    pub tmax: f32,
}

impl Ray {
    /// A ray from `origin` along `direction`, limited to (`tmin`, `tmax`).
    pub fn new(origin: Vec3, direction: Vec3, tmin: f32, tmax: f32) -> Self {
        Self {
            origin: origin.into(),
            direction: direction.into(),
            tmin,
            tmax,
        }
    }

    /// The point at parameter `t`.
    pub fn at(&self, t: f32) -> Vec3 {
        (self.origin + self.direction * t).into()
    }
}
