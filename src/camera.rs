//! Eye rays from a camera basis (u, v, w).
//!
//! The camera sits at `eye` and looks down -w, with u to the right and v up (glTF 2.0 §3.10.1:
//! a camera looks down its local -Z with +Y up, so u, v, w are the node's local X, Y, Z).
//! For a perspective camera the view rectangle lies one unit in front of the eye, with height
//! `H = 2·tan(yfov/2)` and width `W = aspect·H`; the ray through image coordinates
//! (s, t) ∈ [0, 1]² (s to the right, t up) passes through
//! `eye - w + (s - 1/2)·W·u + (t - 1/2)·H·v`. An orthographic camera shoots parallel rays along
//! -w from the points `eye + (s - 1/2)·2·xmag·u + (t - 1/2)·2·ymag·v`.
//!
//! A [`ThinLens`] (depth of field; glTF cameras have none, so only when asked for) replaces the
//! pinhole by a disk of radius `aperture_radius` around each pinhole ray's origin, across u and
//! v: the ray through pixel (s, t) and lens point L goes from L through the point where the
//! pinhole ray meets the plane of focus, `focus_distance` in front of the eye along -w. Points
//! on that plane stay sharp; a point at view-axis depth z spreads over a circle of diameter
//! `2·aperture_radius·|z - focus_distance| / z` measured on the plane of focus (pbrt's and
//! Mitsuba's `thinlens` model).

use crate::geometry::Ray;
use crate::scene::{Bounds, Camera, Projection};
use glam::{Vec2, Vec3};

/// A camera ready to generate rays for an image of a given size.
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    /// Eye position.
    pub eye: Vec3,
    /// Right.
    pub u: Vec3,
    /// Up.
    pub v: Vec3,
    /// Backwards: the camera looks down -w.
    pub w: Vec3,
    /// Projection, with the image aspect resolved.
    pub lens: Lens,
    /// Near clip distance along the view axis.
    pub znear: f32,
    /// Far clip distance along the view axis (infinite when the file sets none).
    pub zfar: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Depth of field, when asked for: `None` is a pinhole.
    pub thin_lens: Option<ThinLens>,
}

/// A thin lens: depth of field (see the module's notes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinLens {
    /// Radius of the lens disk, in scene units (metres for glTF).
    pub aperture_radius: f32,
    /// Distance of the plane in focus in front of the eye, along the view axis.
    pub focus_distance: f32,
}

/// The projection with sizes resolved for the image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lens {
    /// View rectangle of `width` x `height` at distance 1.
    Perspective {
        /// Rectangle width, `aspect · height`.
        width: f32,
        /// Rectangle height, `2·tan(yfov/2)`.
        height: f32,
        /// The rectangle's centre off the view axis, at distance 1 (x along u, y along v):
        /// zero for glTF cameras, set by [`View::with_intrinsics`] for a principal point off
        /// the image centre.
        offset: Vec2,
    },
    /// View rectangle of `width` x `height` at the eye.
    Orthographic {
        /// Full width.
        width: f32,
        /// Full height.
        height: f32,
    },
}

impl View {
    /// A view from a scene camera for an image of `width` x `height` pixels.
    ///
    /// The image aspect wins over the camera's `aspectRatio` (the caller sizes the image from it
    /// when the user gives only a width): like glTF viewers, `yfov` (or `ymag`) is kept and the
    /// horizontal extent follows the image.
    pub fn from_camera(camera: &Camera, width: u32, height: u32) -> View {
        let aspect = width as f32 / height as f32;
        let w = -camera.forward;
        let v = camera.up;
        let u = v.cross(w);
        let (lens, znear, zfar) = match camera.projection {
            Projection::Perspective {
                yfov, znear, zfar, ..
            } => {
                let h = 2.0 * (yfov * 0.5).tan();
                (
                    Lens::Perspective {
                        width: aspect * h,
                        height: h,
                        offset: Vec2::ZERO,
                    },
                    znear,
                    zfar.unwrap_or(f32::INFINITY),
                )
            }
            Projection::Orthographic {
                ymag, znear, zfar, ..
            } => (
                Lens::Orthographic {
                    width: 2.0 * ymag * aspect,
                    height: 2.0 * ymag,
                },
                znear,
                zfar,
            ),
        };
        View {
            eye: camera.position,
            u,
            v,
            w,
            lens,
            znear,
            zfar,
            width,
            height,
            thin_lens: None,
        }
    }

    /// The distance along the view axis at which `target` lies, for a thin lens to focus on
    /// it: `None` where it is not in front of the eye.
    pub fn depth_of(&self, target: Vec3) -> Option<f32> {
        let depth = (target - self.eye).dot(-self.w);
        (depth.is_finite() && depth > 0.0).then_some(depth)
    }

    /// This view with depth of field through `lens` (a radius of 0 keeps the pinhole).
    pub fn with_thin_lens(mut self, lens: ThinLens) -> View {
        self.thin_lens = (lens.aperture_radius > 0.0).then_some(lens);
        self
    }

    /// The eye ray through continuous pixel coordinates (`px`, `py`), as [`View::ray`], and
    /// through the lens point that `lens` (two numbers in [0, 1)) picks on the thin lens's
    /// disk; without a thin lens, the pinhole ray itself. Every lens point's ray through a
    /// pixel position meets the pinhole ray on the plane of focus; its interval is the clip
    /// range along the view axis, as the pinhole ray's.
    #[inline(always)]
    pub fn lens_ray(&self, px: f32, py: f32, lens: (f32, f32)) -> Ray {
        let pinhole = self.ray(px, py);
        let Some(thin) = self.thin_lens else {
            return pinhole;
        };
        let disk = crate::sampling::concentric_disk(lens.0, lens.1) * thin.aperture_radius;
        if disk == glam::Vec2::ZERO {
            // The lens centre: the pinhole ray, bit for bit.
            return pinhole;
        }
        let (origin, direction) = (Vec3::from(pinhole.origin), Vec3::from(pinhole.direction));
        let forward = -self.w;
        // The pinhole ray reaches view-axis depth z at distance z / cos along it.
        let focus = origin + direction * (thin.focus_distance / direction.dot(forward));
        let start = origin + disk.x * self.u + disk.y * self.v;
        let direction = (focus - start).normalize();
        let cos = direction.dot(forward);
        Ray::new(start, direction, self.znear / cos, self.zfar / cos)
    }

    /// This view with `camera`'s own horizontal extent where it has one: a perspective
    /// camera's `aspectRatio` and an orthographic camera's `xmag`, kept whatever the image's
    /// aspect, as glTF's projection matrices write them (§3.10.3) and pyrender renders them.
    /// The picture stretches where they differ from the image's aspect ([`View::from_camera`]
    /// keeps it instead, as glTF viewers do). `camera` is the one this view was made from.
    pub fn stretched_to(mut self, camera: &Camera) -> View {
        match (&mut self.lens, camera.projection) {
            (
                Lens::Perspective { width, height, .. },
                Projection::Perspective {
                    aspect_ratio: Some(aspect),
                    ..
                },
            ) => *width = aspect * *height,
            (Lens::Orthographic { width, .. }, Projection::Orthographic { xmag, .. }) => {
                *width = 2.0 * xmag
            }
            _ => {}
        }
        self
    }

    /// This view with the pinhole intrinsics of a calibrated camera (OpenCV's and pyrender's
    /// `IntrinsicsCamera`), in pixels of this view's image: focal lengths `fx`, `fy` and the
    /// principal point (`cx`, `cy`) measured from the image's top-left corner, y down. A point
    /// at camera-space (x, y, -z) lands at image position (cx + fx·x/z, cy - fy·y/z). The
    /// view's position, orientation and clip range are kept; an orthographic view becomes a
    /// perspective one.
    pub fn with_intrinsics(mut self, fx: f32, fy: f32, cx: f32, cy: f32) -> View {
        let (width, height) = (self.width as f32, self.height as f32);
        self.lens = Lens::Perspective {
            width: width / fx,
            height: height / fy,
            offset: Vec2::new((0.5 * width - cx) / fx, (cy - 0.5 * height) / fy),
        };
        self
    }

    /// The eye ray through continuous pixel coordinates (`px`, `py`), with (0, 0) the top-left
    /// corner of the image and (width, height) the bottom-right; pixel (i, j)'s centre is at
    /// (i + 0.5, j + 0.5). Its direction is unit length and its interval is the near/far clip
    /// range measured along the view axis.
    #[inline(always)]
    pub fn ray(&self, px: f32, py: f32) -> Ray {
        let s = px / self.width as f32 - 0.5;
        let t = 0.5 - py / self.height as f32;
        match self.lens {
            Lens::Perspective {
                width,
                height,
                offset,
            } => {
                // With a zero offset (every glTF camera) the sums are exact: the rays are
                // those of the plain rectangle, bit for bit.
                let through =
                    -self.w + (s * width + offset.x) * self.u + (t * height + offset.y) * self.v;
                let direction = through.normalize();
                // Along the ray, view-axis distance z is reached at t = z / cos(angle to -w).
                let cos = direction.dot(-self.w);
                Ray::new(self.eye, direction, self.znear / cos, self.zfar / cos)
            }
            Lens::Orthographic { width, height } => {
                let origin = self.eye + s * width * self.u + t * height * self.v;
                Ray::new(origin, -self.w, self.znear, self.zfar)
            }
        }
    }
}

/// The direction from the model's centre toward the automatic camera: in front (+Z, the glTF
/// "forward" of an asset), above and to the right.
pub const AUTO_CAMERA_DIRECTION: Vec3 = Vec3::new(0.55, 0.45, 1.0);

/// A camera that frames a model as glTF viewers do: yfov 45°, looking at the centre of its
/// `bounds` from [`AUTO_CAMERA_DIRECTION`], as close as it can stand with every one of its
/// `points` (the vertices; with none, the box's corners) inside the frame with an 8% margin
/// ([`fit_distance`]). The box's bounding sphere, which this once framed, left a compact model
/// a third of the frame wide. Generated views (orbits, turntables) stand at the distance that
/// fits every one of their directions, so they are at least this far away.
pub fn auto_camera(bounds: &Bounds, points: &[Vec3], aspect: f32) -> Camera {
    let yfov = crate::defaults::DEFAULT_YFOV_DEGREES.to_radians();
    let center = bounds.center();
    let radius = framing_radius(bounds);
    let direction = AUTO_CAMERA_DIRECTION.normalize();
    let distance = fit_distance(bounds, points, [direction], yfov, aspect)
        .unwrap_or_else(|| framing_distance(radius, yfov, aspect));
    look_at(
        center + direction * distance,
        center,
        Vec3::Y,
        yfov,
        distance,
        radius,
    )
}

/// Most point-direction pairs [`fit_distance`] projects (a few hundred views of a model with a
/// million vertices, well under a second); beyond that it fits the box's corners, which
/// enclose the points, so the fit is looser but still holds.
const MAX_FIT_PROJECTIONS: usize = 1 << 28;

/// The margin the fit keeps: the outermost point reaches 1/1.08 of the half-frame.
const FIT_MARGIN: f32 = 1.08;

/// The one distance from the centre of `bounds` at which a camera looking at the centre (up
/// +Y, vertical field of view `yfov`, image aspect `aspect`) from each of the unit
/// `directions` (toward the eye) sees every one of `points` (the model's vertices, inside
/// `bounds`; with none, or too many to project, the box's eight corners) inside the frame with
/// an 8% margin: for a point at p from the centre, p·direction + max(|p·right| / tan_x,
/// |p·up| / tan_y), the largest over the points and directions. Directions straight above or
/// below the centre, which have no "up", are skipped. `None` for an empty or unbounded box or
/// when no direction fits.
pub fn fit_distance(
    bounds: &Bounds,
    points: &[Vec3],
    directions: impl IntoIterator<Item = Vec3>,
    yfov: f32,
    aspect: f32,
) -> Option<f32> {
    let centre = bounds.center();
    let half = (bounds.max - bounds.min) * 0.5;
    if !(half.is_finite() && half.max_element() > 0.0) {
        return None;
    }
    let corners: Vec<Vec3> = (0..8)
        .map(|k| {
            let sign = |bit: u32| if k & bit == 0 { -1.0 } else { 1.0 };
            centre + half * Vec3::new(sign(1), sign(2), sign(4))
        })
        .collect();
    let directions: Vec<Vec3> = directions.into_iter().collect();
    let use_points =
        !points.is_empty() && points.len().saturating_mul(directions.len()) <= MAX_FIT_PROJECTIONS;
    let points = if use_points { points } else { &corners[..] };
    let tan_y = (yfov * 0.5).tan() / FIT_MARGIN;
    let tan_x = tan_y * aspect;
    let fits = directions.iter().filter_map(|&direction| {
        let right = (-direction).cross(Vec3::Y).try_normalize()?;
        let up = right.cross(-direction);
        let reach = |p: Vec3| {
            let p = p - centre;
            p.dot(direction) + (p.dot(right).abs() / tan_x).max(p.dot(up).abs() / tan_y)
        };
        Some(points.iter().map(|&p| reach(p)).fold(0.0f32, f32::max))
    });
    let distance = fits.reduce(f32::max)?;
    (distance > 0.0 && distance.is_finite()).then_some(distance)
}

/// The few of `points` that decide [`auto_camera`]'s distance (for an image of `aspect`,
/// whatever the bounds' centre): the distance [`fit_distance`] reaches from one direction is
/// the largest of four linear functions of a point (`p·direction ± p·right / tan_x`, `±
/// p·up / tan_y`), so the point that maximises each decides it. Fitting these four (from each
/// of many point sets, such as an animation's poses) gives the distance that fitting every
/// point gives, without keeping them all.
pub fn auto_camera_extremes(points: &[Vec3], aspect: f32) -> Vec<Vec3> {
    let yfov = crate::defaults::DEFAULT_YFOV_DEGREES.to_radians();
    let direction = AUTO_CAMERA_DIRECTION.normalize();
    // The basis and the margin of `fit_distance`.
    let tan_y = (yfov * 0.5).tan() / FIT_MARGIN;
    let tan_x = tan_y * aspect;
    let Some(right) = (-direction).cross(Vec3::Y).try_normalize() else {
        return points.to_vec();
    };
    let up = right.cross(-direction);
    [right / tan_x, -right / tan_x, up / tan_y, -up / tan_y]
        .into_iter()
        .filter_map(|side| {
            let part = direction + side;
            points
                .iter()
                .copied()
                .max_by(|a, b| a.dot(part).total_cmp(&b.dot(part)))
        })
        .collect()
}

/// The radius of the sphere the automatic camera frames: the bounding sphere's. Any positive
/// radius is framed as it is (a model in micrometres is still a model); only an empty or
/// single-point scene gets a unit sphere.
pub fn framing_radius(bounds: &Bounds) -> f32 {
    match bounds.radius() {
        r if r > 0.0 && r.is_finite() => r,
        _ => 1.0,
    }
}

/// How far from the centre of a sphere of `radius` a perspective camera with vertical field of
/// view `yfov` (radians) and image aspect `aspect` (width / height) stands to see all of it,
/// with a 5% margin: the sphere fits the narrower of the two fields of view.
pub fn framing_distance(radius: f32, yfov: f32, aspect: f32) -> f32 {
    let half_h = (yfov * 0.5).tan();
    let half_fov = half_h.min(half_h * aspect).atan();
    radius / half_fov.sin() * 1.05
}

/// The near clip distance for an eye at `eye` and a scene inside the sphere of `radius` about
/// `centre`: half the way to the sphere (never below 1e-4 of the distance to its centre, which
/// keeps depth precision), or, for an eye inside the sphere, a hundred-thousandth of its
/// radius. It follows the scene, not the point looked at: a camera close to a model and
/// looking at a point far beyond it still sees the model.
pub fn near_plane(eye: Vec3, centre: Vec3, radius: f32) -> f32 {
    let to_centre = (centre - eye).length();
    if to_centre <= radius {
        radius * 1e-5
    } else {
        ((to_centre - radius) * 0.5).max(to_centre * 1e-4)
    }
}

/// How far from the view a camera's up vector must be (the sine of the angle between them)
/// to be used: nearer, its part across the view is mostly rounding (an orbit's pole, where
/// `cos 90°` is 4e-8 in f32), and normalised it is not at right angles to the view.
pub const MIN_UP_SINE: f32 = 1e-3;

/// `hint`'s part at right angles to the unit `forward`, normalised; `None` when `hint` is
/// within [`MIN_UP_SINE`] of the view.
pub fn across_view(forward: Vec3, hint: Vec3) -> Option<Vec3> {
    let across = hint - forward * hint.dot(forward);
    (across.length() > MIN_UP_SINE * hint.length()).then(|| across.normalize())
}

/// A perspective camera at `from` looking at `at` with `up`; near and far planes bracket a
/// sphere of `radius` at `distance`.
pub fn look_at(from: Vec3, at: Vec3, up: Vec3, yfov: f32, distance: f32, radius: f32) -> Camera {
    let forward = (at - from).try_normalize().unwrap_or(Vec3::NEG_Z);
    let up = across_view(forward, up)
        .or_else(|| across_view(forward, Vec3::Z))
        .unwrap_or(Vec3::Y);
    Camera {
        name: Some("auto".into()),
        position: from,
        forward,
        up,
        projection: Projection::Perspective {
            yfov,
            aspect_ratio: None,
            znear: ((distance - radius) * 0.5).max(distance * 1e-4),
            zfar: None,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At an orbit's pole the view is along +Y but for rounding (cos 90° is 4e-8 in f32): the
    /// camera's up is still at right angles to it, not the normalised rounding.
    #[test]
    fn a_camera_at_the_pole_has_an_orthonormal_basis() {
        for elevation in [90.0f32, -90.0, 89.99, 0.0] {
            let e = elevation.to_radians();
            for azimuth in [0.0f32, 0.3, 2.0] {
                let direction =
                    Vec3::new(e.cos() * azimuth.sin(), e.sin(), e.cos() * azimuth.cos());
                let camera = look_at(direction * 5.0, Vec3::ZERO, Vec3::Y, 0.8, 5.0, 1.0);
                let (f, u) = (camera.forward, camera.up);
                assert!(f.dot(u).abs() < 1e-6, "{elevation} {azimuth}: {f} {u}");
                assert!((u.length() - 1.0).abs() < 1e-6, "{elevation}: {u}");
            }
        }
        assert!(across_view(Vec3::NEG_Y, Vec3::new(1e-5, 1.0, 0.0)).is_none());
        assert_eq!(across_view(Vec3::NEG_Z, Vec3::Y), Some(Vec3::Y));
    }

    /// A model a micrometre across is framed like a metre-sized one (the fit once clamped the
    /// radius to 1e-6, so a 1e-4-scale model filled a quarter of the frame).
    #[test]
    fn auto_camera_frames_tiny_models_like_large_ones() {
        let framing = |r: f32| {
            let bounds = Bounds {
                min: Vec3::splat(-r),
                max: Vec3::splat(r),
            };
            let cam = auto_camera(&bounds, &[], 4.0 / 3.0);
            (cam.position - bounds.center()).length() / r
        };
        let (tiny, unit) = (framing(1e-7), framing(1.0));
        assert!((tiny / unit - 1.0).abs() < 1e-4, "{tiny} vs {unit}");
    }

    /// Where each of `points` projects in `cam`'s frame: the larger of |x| and |y| in units of
    /// the half-frame (1 = the edge), for a perspective camera with image aspect `aspect`.
    fn reaches(cam: &Camera, points: &[Vec3], aspect: f32) -> Vec<f32> {
        let Projection::Perspective { yfov, .. } = cam.projection else {
            panic!("perspective");
        };
        let right = cam.forward.cross(cam.up).normalize();
        let (tan_y, tan_x) = ((yfov * 0.5).tan(), (yfov * 0.5).tan() * aspect);
        points
            .iter()
            .map(|&point| {
                let p = point - cam.position;
                let depth = p.dot(cam.forward);
                assert!(depth > 0.0, "{point} behind the camera");
                let (x, y) = (
                    p.dot(right) / (depth * tan_x),
                    p.dot(cam.up) / (depth * tan_y),
                );
                x.abs().max(y.abs())
            })
            .collect()
    }

    /// Without points the automatic camera fits the box's corners, not its sphere: for a cube,
    /// a flat plate and a tall pole every corner projects inside the frame within the 8%
    /// margin, and the outermost one touches the margin (the fit is tight).
    #[test]
    fn auto_camera_fits_the_box_corners_to_the_frame() {
        let aspect = 4.0 / 3.0;
        for half in [
            Vec3::ONE,
            Vec3::new(2.0, 0.05, 1.5),
            Vec3::new(0.1, 3.0, 0.1),
        ] {
            let centre = Vec3::new(1.0, -2.0, 0.5);
            let bounds = Bounds {
                min: centre - half,
                max: centre + half,
            };
            let corners: Vec<Vec3> = (0..8)
                .map(|k| {
                    let sign = |bit: u32| if k & bit == 0 { -1.0 } else { 1.0 };
                    centre + half * Vec3::new(sign(1), sign(2), sign(4))
                })
                .collect();
            let reach = reaches(&auto_camera(&bounds, &[], aspect), &corners, aspect);
            let outermost = reach.iter().copied().fold(0.0f32, f32::max);
            assert!(outermost <= 1.0 / 1.08 + 1e-4, "{half}: {outermost}");
            assert!(
                outermost > 1.0 / 1.08 - 1e-3,
                "{half}: loose fit {outermost}"
            );
        }
    }

    /// With the model's points the camera fits them, not their box: 2,000 points on a sphere
    /// all project inside the margin, the outermost touches it, and the camera stands closer
    /// than the corner fit and the bounding-sphere framing would put it.
    #[test]
    fn auto_camera_fits_the_points_closer_than_their_box() {
        let aspect = 4.0 / 3.0;
        let centre = Vec3::new(0.3, 1.0, -2.0);
        let points: Vec<Vec3> = (0..2000)
            .map(|k| {
                let z = 1.0 - 2.0 * (k as f32 + 0.5) / 2000.0;
                let phi = k as f32 * 2.399_963;
                let r = (1.0 - z * z).sqrt();
                centre + Vec3::new(r * phi.cos(), z, r * phi.sin())
            })
            .collect();
        let mut bounds = Bounds::EMPTY;
        points.iter().for_each(|&p| bounds.grow(p));
        let fitted = auto_camera(&bounds, &points, aspect);
        let reach = reaches(&fitted, &points, aspect);
        let outermost = reach.iter().copied().fold(0.0f32, f32::max);
        assert!(outermost <= 1.0 / 1.08 + 1e-4, "{outermost}");
        assert!(outermost > 1.0 / 1.08 - 1e-3, "loose fit {outermost}");
        let distance = |cam: &Camera| (cam.position - bounds.center()).length();
        let boxed = distance(&auto_camera(&bounds, &[], aspect));
        let sphere = framing_distance(framing_radius(&bounds), 45f32.to_radians(), aspect);
        assert!(
            distance(&fitted) < 0.8 * boxed.min(sphere),
            "{} vs {boxed}, {sphere}",
            distance(&fitted)
        );
    }

    /// The four extremes of each of several point sets fit the camera as all their points do:
    /// three sets of 500 scattered points (poses of a model, say), a box around them all and
    /// both aspects; and a set with no points gives none.
    #[test]
    fn the_extremes_of_point_sets_fit_as_all_their_points() {
        let mut state = 12_345u32;
        let mut random = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32 - 0.5
        };
        let sets: Vec<Vec<Vec3>> = (0..3)
            .map(|k| {
                let offset = Vec3::new(k as f32 * 0.7, k as f32 * 0.2, -(k as f32) * 0.4);
                (0..500)
                    .map(|_| offset + Vec3::new(random(), random() * 2.0, random()))
                    .collect()
            })
            .collect();
        let all: Vec<Vec3> = sets.concat();
        let mut bounds = Bounds::EMPTY;
        all.iter().for_each(|&p| bounds.grow(p));
        for aspect in [4.0 / 3.0, 0.5] {
            let extremes: Vec<Vec3> = sets
                .iter()
                .flat_map(|set| auto_camera_extremes(set, aspect))
                .collect();
            assert_eq!(extremes.len(), 12);
            let yfov = 45f32.to_radians();
            let direction = [AUTO_CAMERA_DIRECTION.normalize()];
            let from_all = fit_distance(&bounds, &all, direction, yfov, aspect).unwrap();
            let from_extremes = fit_distance(&bounds, &extremes, direction, yfov, aspect).unwrap();
            assert!(
                (from_all - from_extremes).abs() <= 1e-5 * from_all,
                "{from_all} vs {from_extremes}"
            );
            let boxed = fit_distance(&bounds, &[], direction, yfov, aspect).unwrap();
            assert!(from_all < 0.95 * boxed, "{from_all} vs {boxed}");
        }
        assert!(auto_camera_extremes(&[], 1.0).is_empty());
    }

    fn camera(projection: Projection) -> Camera {
        Camera {
            name: None,
            position: Vec3::new(0.0, 0.0, 5.0),
            forward: Vec3::NEG_Z,
            up: Vec3::Y,
            projection,
        }
    }

    #[test]
    fn perspective_centre_and_corners() {
        let cam = camera(Projection::Perspective {
            yfov: 90f32.to_radians(),
            aspect_ratio: None,
            znear: 0.1,
            zfar: None,
        });
        let view = View::from_camera(&cam, 200, 100);
        let centre = view.ray(100.0, 50.0);
        assert!((Vec3::from(centre.direction) - Vec3::NEG_Z).length() < 1e-6);
        // yfov 90°: the top edge is 45° up; aspect 2 puts the right edge at x = 2 on the unit plane.
        let top_right = Vec3::from(view.ray(200.0, 0.0).direction);
        let expected = Vec3::new(2.0, 1.0, -1.0).normalize();
        assert!((top_right - expected).length() < 1e-6, "{top_right}");
        assert!((centre.tmin - 0.1).abs() < 1e-6);
    }

    #[test]
    fn orthographic_rays_are_parallel() {
        let cam = camera(Projection::Orthographic {
            xmag: 2.0,
            ymag: 1.0,
            znear: 0.0,
            zfar: 100.0,
        });
        let view = View::from_camera(&cam, 200, 100);
        let r = view.ray(0.0, 0.0);
        assert_eq!(Vec3::from(r.direction), Vec3::NEG_Z);
        assert!((Vec3::from(r.origin) - Vec3::new(-2.0, 1.0, 5.0)).length() < 1e-6);
    }

    /// Stretched, the camera's own horizontal extent is kept whatever the image's aspect:
    /// an orthographic camera's xmag, a perspective camera's aspectRatio; a camera without
    /// one keeps the image's.
    #[test]
    fn stretched_views_keep_the_cameras_horizontal_extent() {
        let ortho = camera(Projection::Orthographic {
            xmag: 1.0,
            ymag: 1.0,
            znear: 0.0,
            zfar: 100.0,
        });
        // 200x100 pixels: the image's aspect would make the view 4 m wide; xmag says 2.
        let view = View::from_camera(&ortho, 200, 100).stretched_to(&ortho);
        let left = Vec3::from(view.ray(0.0, 50.0).origin);
        assert!((left - Vec3::new(-1.0, 0.0, 5.0)).length() < 1e-6, "{left}");
        let perspective = |aspect_ratio| {
            camera(Projection::Perspective {
                yfov: std::f32::consts::FRAC_PI_2,
                aspect_ratio,
                znear: 0.1,
                zfar: None,
            })
        };
        let wide = perspective(Some(3.0));
        // yfov 90°, aspectRatio 3: the right edge at x = 3 on the unit plane, not 2.
        let right = Vec3::from(
            View::from_camera(&wide, 200, 100)
                .stretched_to(&wide)
                .ray(200.0, 50.0)
                .direction,
        );
        assert!((right - Vec3::new(3.0, 0.0, -1.0).normalize()).length() < 1e-6);
        let free = perspective(None);
        let plain = View::from_camera(&free, 200, 100);
        let edge = |v: &View| Vec3::from(v.ray(200.0, 50.0).direction);
        assert_eq!(edge(&plain.clone().stretched_to(&free)), edge(&plain));
    }

    /// The automatic camera looks at the centre of the box.
    #[test]
    fn auto_camera_looks_at_the_centre() {
        let bounds = Bounds {
            min: Vec3::splat(-1.0),
            max: Vec3::splat(1.0),
        };
        let cam = auto_camera(&bounds, &[], 4.0 / 3.0);
        let to_centre = (bounds.center() - cam.position).normalize();
        assert!((to_centre - cam.forward).length() < 1e-5);
    }

    /// A pinhole with intrinsics sends the ray through pixel position (px, py) along
    /// ((px - cx)/fx, (cy - py)/fy, -1) in camera space, principal point off centre or not;
    /// with the centre as principal point it is the plain perspective view.
    #[test]
    fn intrinsics_put_the_principal_point_where_they_say() {
        let camera = Camera {
            name: None,
            position: Vec3::new(1.0, 2.0, 3.0),
            forward: Vec3::NEG_Z,
            up: Vec3::Y,
            projection: Projection::Perspective {
                yfov: 1.0,
                aspect_ratio: None,
                znear: 0.1,
                zfar: None,
            },
        };
        let view = View::from_camera(&camera, 64, 48).with_intrinsics(50.0, 40.0, 20.0, 30.0);
        for (px, py) in [(20.0, 30.0), (0.0, 0.0), (63.5, 47.5)] {
            let d = Vec3::from(view.ray(px, py).direction);
            let expected = Vec3::new((px - 20.0) / 50.0, (30.0 - py) / 40.0, -1.0).normalize();
            assert!(
                (d - expected).length() < 1e-6,
                "{px},{py}: {d} vs {expected}"
            );
        }
        let plain = View::from_camera(&camera, 64, 48);
        let Lens::Perspective { width, height, .. } = plain.lens else {
            unreachable!("a perspective camera")
        };
        let (fx, fy) = (64.0 / width, 48.0 / height);
        let centred = plain.clone().with_intrinsics(fx, fy, 32.0, 24.0);
        let (a, b) = (centred.ray(10.5, 7.5), plain.ray(10.5, 7.5));
        assert!((a.direction - b.direction).length() < 1e-6);
    }

    /// A thin lens's rays through one pixel position start on the lens disk (within the
    /// aperture radius of the eye, across the view axis) and all meet the pinhole ray where it
    /// crosses the plane of focus; the lens centre's ray is the pinhole ray, and a radius of 0
    /// is the pinhole. Orthographic views focus the same way.
    #[test]
    fn thin_lens_rays_meet_on_the_plane_of_focus() {
        let lens = ThinLens {
            aperture_radius: 0.05,
            focus_distance: 2.5,
        };
        let ortho = Camera {
            projection: Projection::Orthographic {
                xmag: 1.0,
                ymag: 0.75,
                znear: 0.0,
                zfar: 100.0,
            },
            ..camera(Projection::Perspective {
                yfov: 0.8,
                aspect_ratio: None,
                znear: 0.1,
                zfar: None,
            })
        };
        for base in [
            camera(Projection::Perspective {
                yfov: 0.8,
                aspect_ratio: None,
                znear: 0.1,
                zfar: None,
            }),
            ortho,
        ] {
            let plain = View::from_camera(&base, 64, 48);
            let view = plain.clone().with_thin_lens(lens);
            let forward = -view.w;
            for (px, py) in [(32.0, 24.0), (0.5, 0.5), (63.0, 10.25)] {
                let pinhole = plain.ray(px, py);
                let (o, d) = (Vec3::from(pinhole.origin), Vec3::from(pinhole.direction));
                let focus = o + d * (2.5 / d.dot(forward));
                assert_eq!(view.lens_ray(px, py, (0.5, 0.5)), pinhole);
                for u in [(0.0, 0.0), (0.9, 0.2), (0.3, 0.99), (0.5, 0.01)] {
                    let ray = view.lens_ray(px, py, u);
                    let (start, dir) = (Vec3::from(ray.origin), Vec3::from(ray.direction));
                    let across = start - o;
                    assert!(across.dot(forward).abs() < 1e-6, "{across}");
                    assert!(across.length() <= 0.05 + 1e-6, "{across}");
                    let reached = start + dir * ((focus - start).dot(forward) / dir.dot(forward));
                    assert!((reached - focus).length() < 1e-5, "{reached} vs {focus}");
                    assert!((ray.tmin * dir.dot(forward) - view.znear).abs() < 1e-6);
                }
            }
            let closed = plain.clone().with_thin_lens(ThinLens {
                aperture_radius: 0.0,
                ..lens
            });
            assert_eq!(closed, plain);
            assert_eq!(closed.lens_ray(3.0, 4.0, (0.1, 0.9)), plain.ray(3.0, 4.0));
        }
    }
}
