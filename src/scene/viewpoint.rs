//! The cameras a file places in the world, as plain data; [`crate::camera`] makes rays from them.

use glam::{Mat4, Vec3};
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

impl Camera {
    /// A camera placed by `pose`, its world-from-camera matrix (a glTF node's world transform,
    /// pyrender's camera pose): it looks down the pose's local -Z with local +Y up, scale
    /// removed. `None` when the pose is degenerate (not finite, or -Z or +Y collapsed).
    pub fn from_pose(pose: Mat4, projection: Projection, name: Option<String>) -> Option<Camera> {
        let (position, forward, up) = pose_frame(pose)?;
        Some(Camera {
            name,
            position,
            forward,
            up,
            projection,
        })
    }
}

/// Position, forward (local -Z) and up (local +Y) of a node's world transform, with scale
/// removed and up made orthogonal to forward. `None` when the transform is degenerate.
pub(crate) fn pose_frame(world: Mat4) -> Option<(Vec3, Vec3, Vec3)> {
    let position = world.transform_point3(Vec3::ZERO);
    let forward = world.transform_vector3(Vec3::NEG_Z).try_normalize()?;
    let up_raw = world.transform_vector3(Vec3::Y);
    let up = (up_raw - forward * up_raw.dot(forward)).try_normalize()?;
    position.is_finite().then_some((position, forward, up))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_frame_removes_scale_and_keeps_minus_z() {
        let world = Mat4::from_scale_rotation_translation(
            Vec3::splat(3.0),
            glam::Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
            Vec3::new(1.0, 2.0, 3.0),
        );
        let (p, f, u) = pose_frame(world).unwrap();
        assert!((p - Vec3::new(1.0, 2.0, 3.0)).length() < 1e-6);
        // Rotating -Z by +90° about Y gives -X.
        assert!((f - Vec3::NEG_X).length() < 1e-6);
        assert!((u - Vec3::Y).length() < 1e-6);
        assert!(pose_frame(Mat4::ZERO).is_none());
    }
}
