//! The cameras a file places in the world, as plain data; [`crate::camera`] makes rays from them.

use glam::Vec3;
use serde::Serialize;

/// Camera projection (glTF 2.0 §3.10).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum Projection {
    /// Perspective: `yfov` is the vertical field of view in radians (glTF 2.0 §5.14).
    Perspective {
        /// Vertical field of view, radians.
        yfov: f32,
        /// Width / height, if the file sets it.
        aspect_ratio: Option<f32>,
        /// Near clip distance.
        znear: f32,
        /// Far clip distance; infinite when absent.
        zfar: Option<f32>,
    },
    /// Orthographic: `xmag`/`ymag` are half the width/height of the view volume.
    Orthographic {
        /// Half width of the view, metres.
        xmag: f32,
        /// Half height of the view, metres.
        ymag: f32,
        /// Near clip distance.
        znear: f32,
        /// Far clip distance.
        zfar: f32,
    },
}

/// A camera placed in the world. glTF 2.0 §3.10.1: a camera looks down its node's local -Z with
/// +Y up; node scale is removed.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Camera {
    /// Name of the camera or its node.
    pub name: Option<String>,
    /// Eye position, world space.
    pub position: Vec3,
    /// Unit view direction (world-space image of local -Z).
    pub forward: Vec3,
    /// Unit up vector, orthogonal to `forward` (world-space image of local +Y).
    pub up: Vec3,
    /// Projection.
    pub projection: Projection,
}
