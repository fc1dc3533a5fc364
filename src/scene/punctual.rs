//! The punctual lights (`KHR_lights_punctual`) a file places in the world, as plain data;
//! [`crate::light`] computes what they deliver.

use glam::{Mat4, Vec3};
use serde::Serialize;

/// Type of a punctual light (`KHR_lights_punctual`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum LightKind {
    /// Omnidirectional point light; intensity in candela.
    Point,
    /// Spot light; intensity in candela; cone angles in radians from the axis.
    Spot {
        /// Angle where falloff starts.
        inner_cone_angle: f32,
        /// Angle where the light reaches zero.
        outer_cone_angle: f32,
    },
    /// Directional light; intensity in lux.
    Directional,
}

/// A punctual light in world space (`KHR_lights_punctual`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Light {
    /// Name from the file, if any.
    pub name: Option<String>,
    /// Type and cone.
    pub kind: LightKind,
    /// Linear RGB colour.
    pub color: Vec3,
    /// Candela for point and spot lights, lux for directional lights.
    pub intensity: f32,
    /// Distance beyond which the light has no effect (point and spot only).
    pub range: Option<f32>,
    /// World position (unused for directional lights).
    pub position: Vec3,
    /// Unit direction the light travels, world space (local -Z of its node).
    pub direction: Vec3,
}

impl Light {
    /// A light placed by `pose`, its world-from-light matrix (a glTF node's world transform,
    /// pyrender's light pose): at the pose's origin, shining down its local -Z. `None` when the
    /// pose is not finite or collapses -Z, or `intensity` is negative or not finite (what the
    /// glTF importer skips too). `range` is kept only when positive and finite.
    pub fn from_pose(
        kind: LightKind,
        color: Vec3,
        intensity: f32,
        range: Option<f32>,
        pose: Mat4,
        name: Option<String>,
    ) -> Option<Light> {
        let position = pose.transform_point3(Vec3::ZERO);
        let direction = pose.transform_vector3(Vec3::NEG_Z).try_normalize()?;
        if !position.is_finite() || !intensity.is_finite() || intensity < 0.0 {
            return None;
        }
        Some(Light {
            name,
            kind,
            color,
            intensity,
            range: range.filter(|r| *r > 0.0 && r.is_finite()),
            position,
            direction,
        })
    }
}
