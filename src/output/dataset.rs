//! `transforms.json`: the camera file that NeRF and Gaussian-splatting tools read, as
//! nerfstudio's data conventions describe it (and instant-ngp and the original NeRF Blender
//! loader read it).
//!
//! - Intrinsics in pixels: `fl_x`, `fl_y` (focal lengths), `cx`, `cy` (principal point), `w`,
//!   `h`, plus `camera_angle_x` (horizontal field of view in radians, what instant-ngp and
//!   the NeRF Blender loader take). nerfstudio's pixel (i, j) is sampled at its centre
//!   (i + 0.5, j + 0.5), as meshtracer's is, so the principal point of a centred lens is
//!   (w/2, h/2). When every frame shares them they are written once at the top, else per
//!   frame (nerfstudio reads either; `w` and `h` are always shared).
//! - Per frame: `file_path` (relative to the folder of `transforms.json`), the 4x4
//!   `transform_matrix` camera-to-world, row-major, in OpenGL axes (columns: camera +X right,
//!   +Y up, +Z backwards, the eye; the camera looks down -Z), which is glTF's camera
//!   convention too, and when written `depth_file_path` and `mask_path`.
//! - `depth_unit_scale_factor`: metres per stored depth unit (nerfstudio's dataparser option of
//!   that name, default 0.001, must match it). Depth is the distance along the view axis
//!   (z-depth), which is what nerfstudio's depth losses expect by default
//!   (`is_euclidean_depth = False`).
//!
//! Only perspective (pinhole) cameras can be described; [`Intrinsics::of`] gives `None` for an
//! orthographic one.

use crate::camera::{Lens, View};
use crate::output::SaveError;
use serde::Serialize;
use std::path::Path;

/// Pinhole intrinsics of one view, in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Intrinsics {
    /// Horizontal field of view, radians.
    pub camera_angle_x: f64,
    /// Focal length along x, pixels.
    pub fl_x: f64,
    /// Focal length along y, pixels.
    pub fl_y: f64,
    /// Principal point x, pixels from the left edge.
    pub cx: f64,
    /// Principal point y, pixels from the top edge.
    pub cy: f64,
}

impl Intrinsics {
    /// The intrinsics of a perspective view: its view rectangle at distance 1 is
    /// `lens.width` x `lens.height`, so `fl_x = w / lens.width` and `fl_y = h / lens.height`; the principal point is the image
    /// centre moved by the lens offset.
    /// `None` for an orthographic view.
    pub fn of(view: &View) -> Option<Intrinsics> {
        let Lens::Perspective {
            width,
            height,
            offset,
        } = view.lens
        else {
            return None;
        };
        let (w, h) = (f64::from(view.width), f64::from(view.height));
        let fl_x = w / f64::from(width);
        let fl_y = h / f64::from(height);
        Some(Intrinsics {
            camera_angle_x: 2.0 * (w / (2.0 * fl_x)).atan(),
            fl_x,
            fl_y,
            cx: w / 2.0 - f64::from(offset.x) * fl_x,
            cy: h / 2.0 + f64::from(offset.y) * fl_y,
        })
    }
}

/// The camera-to-world matrix of a view, row-major: columns right (u), up (v), backwards (w)
/// and the eye, in OpenGL camera axes (looking down -Z, +Y up), last row (0, 0, 0, 1).
pub fn camera_to_world(view: &View) -> [[f32; 4]; 4] {
    let (u, v, w, eye) = (view.u, view.v, view.w, view.eye);
    [
        [u.x, v.x, w.x, eye.x],
        [u.y, v.y, w.y, eye.y],
        [u.z, v.z, w.z, eye.z],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// One frame of the dataset.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// The image, relative to the folder of `transforms.json` (or absolute).
    pub file_path: String,
    /// Camera-to-world, row-major ([`camera_to_world`]).
    pub transform_matrix: [[f32; 4]; 4],
    /// The view's intrinsics.
    pub intrinsics: Intrinsics,
    /// The depth map, if written.
    pub depth_file_path: Option<String>,
    /// The coverage mask, if written.
    pub mask_path: Option<String>,
    /// The view's thin lens, if it has one (`render --aperture-radius`): written as the frame's
    /// `aperture_radius` and `focus_distance`, which the pinhole model above does not describe
    /// (nerfstudio and instant-ngp ignore keys they do not know).
    pub thin_lens: Option<crate::camera::ThinLens>,
}

/// The frames of one multi-view render, all of `width` x `height` pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct Dataset {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Metres per unit of the depth files, when depth is written.
    pub depth_unit_scale_factor: Option<f32>,
    /// The frames in view order.
    pub frames: Vec<Frame>,
}

#[derive(Serialize)]
struct TransformsFile<'a> {
    camera_model: &'static str,
    #[serde(flatten)]
    shared: Option<Intrinsics>,
    w: u32,
    h: u32,
    #[serde(skip_serializing_if = "Option::is_none")]
    depth_unit_scale_factor: Option<f32>,
    frames: Vec<FrameEntry<'a>>,
}

#[derive(Serialize)]
struct FrameEntry<'a> {
    file_path: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    depth_file_path: Option<&'a str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    mask_path: Option<&'a str>,
    #[serde(flatten)]
    intrinsics: Option<Intrinsics>,
    #[serde(skip_serializing_if = "Option::is_none")]
    aperture_radius: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    focus_distance: Option<f32>,
    transform_matrix: [[f32; 4]; 4],
}

impl Dataset {
    /// Whether every frame has the same intrinsics (then they are written once, at the top).
    fn shared_intrinsics(&self) -> Option<Intrinsics> {
        let first = self.frames.first()?.intrinsics;
        self.frames
            .iter()
            .all(|f| f.intrinsics == first)
            .then_some(first)
    }

    /// The `transforms.json` text: pretty JSON, keys in a fixed order, so the same frames give
    /// the same bytes.
    pub fn to_json(&self) -> String {
        let shared = self.shared_intrinsics();
        let file = TransformsFile {
            // OPENCV with no distortion terms is the pinhole model; it is what nerfstudio's
            // own conversions write, and instant-ngp ignores the key.
            camera_model: "OPENCV",
            shared,
            w: self.width,
            h: self.height,
            depth_unit_scale_factor: self.depth_unit_scale_factor,
            frames: self
                .frames
                .iter()
                .map(|f| FrameEntry {
                    file_path: &f.file_path,
                    depth_file_path: f.depth_file_path.as_deref(),
                    mask_path: f.mask_path.as_deref(),
                    intrinsics: shared.is_none().then_some(f.intrinsics),
                    aperture_radius: f.thin_lens.map(|l| l.aperture_radius),
                    focus_distance: f.thin_lens.map(|l| l.focus_distance),
                    transform_matrix: f.transform_matrix,
                })
                .collect(),
        };
        let mut text = serde_json::to_string_pretty(&file).unwrap_or_default();
        text.push('\n');
        text
    }

    /// Writes `transforms.json` to `path`, atomically.
    pub fn write(&self, path: &Path) -> Result<(), SaveError> {
        crate::output::write_atomic(path, self.to_json().as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::look_at;
    use glam::{Vec3, Vec4};

    fn view(yfov_degrees: f32) -> View {
        let camera = look_at(
            Vec3::new(3.0, 2.0, 4.0),
            Vec3::new(0.5, 0.0, 0.0),
            Vec3::Y,
            yfov_degrees.to_radians(),
            5.0,
            1.0,
        );
        View::from_camera(&camera, 64, 48)
    }

    /// The matrix takes the camera's origin to the eye and its -Z axis to the view direction,
    /// and unprojecting a pixel with fl/cx/cy nerfstudio's way gives the renderer's own ray.
    #[test]
    fn matrix_and_intrinsics_reproduce_the_renderer_rays() {
        let view = view(50.0);
        let m = glam::Mat4::from_cols_array_2d(&camera_to_world(&view)).transpose();
        assert_eq!(m.w_axis, view.eye.extend(1.0));
        let k = Intrinsics::of(&view).unwrap();
        assert!((k.fl_x - k.fl_y).abs() < 1e-3, "square pixels");
        assert!((k.camera_angle_x - 2.0 * (32.0 / k.fl_x).atan()).abs() < 1e-12);
        for (i, j) in [(0u32, 0u32), (63, 47), (10, 30), (32, 24)] {
            let (x, y) = (f64::from(i) + 0.5, f64::from(j) + 0.5);
            // nerfstudio: camera-space direction ((x - cx)/fx, -(y - cy)/fy, -1).
            let d = Vec4::new(
                ((x - k.cx) / k.fl_x) as f32,
                (-(y - k.cy) / k.fl_y) as f32,
                -1.0,
                0.0,
            );
            let world = (m * d).truncate().normalize();
            let ray = Vec3::from(view.ray(x as f32, y as f32).direction);
            assert!(
                (world - ray).length() < 1e-5,
                "pixel ({i}, {j}): {world} vs {ray}"
            );
        }
    }

    #[test]
    fn shared_intrinsics_go_on_top_and_differing_ones_per_frame() {
        let frame = |yfov: f32, name: &str| {
            let v = view(yfov);
            Frame {
                file_path: name.into(),
                transform_matrix: camera_to_world(&v),
                intrinsics: Intrinsics::of(&v).unwrap(),
                depth_file_path: Some(format!("depth/{name}")),
                mask_path: None,
                thin_lens: None,
            }
        };
        let mut set = Dataset {
            width: 64,
            height: 48,
            depth_unit_scale_factor: Some(0.001),
            frames: vec![frame(40.0, "000.png"), frame(40.0, "001.png")],
        };
        let json: serde_json::Value = serde_json::from_str(&set.to_json()).unwrap();
        assert!(json["fl_x"].is_f64() && json["camera_angle_x"].is_f64());
        assert_eq!(
            (json["w"].as_u64(), json["h"].as_u64()),
            (Some(64), Some(48))
        );
        // f32 values are written in their shortest form: 0.001, not 0.0010000000474974513.
        assert_eq!(json["depth_unit_scale_factor"].as_f64(), Some(0.001));
        let frames = json["frames"].as_array().unwrap();
        assert_eq!(frames[1]["file_path"], "001.png");
        assert_eq!(frames[1]["depth_file_path"], "depth/001.png");
        assert!(frames[0].get("mask_path").is_none() && frames[0].get("fl_x").is_none());
        assert_eq!(frames[0]["transform_matrix"].as_array().unwrap().len(), 4);
        set.frames[1] = frame(60.0, "001.png");
        let json: serde_json::Value = serde_json::from_str(&set.to_json()).unwrap();
        assert!(json.get("fl_x").is_none());
        assert!(json["frames"][0]["fl_x"].as_f64() > json["frames"][1]["fl_x"].as_f64());
        assert_eq!(set.to_json(), set.to_json(), "deterministic");
        // A frame through a thin lens says so; the others do not.
        set.frames[0].thin_lens = Some(crate::camera::ThinLens {
            aperture_radius: 0.25,
            focus_distance: 2.0,
        });
        let json: serde_json::Value = serde_json::from_str(&set.to_json()).unwrap();
        assert_eq!(json["frames"][0]["aperture_radius"].as_f64(), Some(0.25));
        assert_eq!(json["frames"][0]["focus_distance"].as_f64(), Some(2.0));
        assert!(json["frames"][1].get("aperture_radius").is_none());
    }

    #[test]
    fn orthographic_views_have_no_pinhole_intrinsics() {
        let camera = crate::scene::Camera {
            name: None,
            position: Vec3::Z,
            forward: Vec3::NEG_Z,
            up: Vec3::Y,
            projection: crate::scene::Projection::Orthographic {
                xmag: 1.0,
                ymag: 1.0,
                znear: 0.0,
                zfar: 10.0,
            },
        };
        assert!(Intrinsics::of(&View::from_camera(&camera, 8, 8)).is_none());
    }
}
