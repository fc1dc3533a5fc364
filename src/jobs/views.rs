//! Many views of one model (`render --views SPEC`): what a spec means, the cameras it stands
//! for, and the `{view}` patterns that name each view's files.
//!
//! Specs:
//! - `orbit:N`: N cameras on a horizontal circle around the target at a given elevation,
//!   view 0 in front (+Z, the glTF front of an asset), turning counter-clockwise seen from
//!   above (about +Y, glTF's up);
//! - `sphere:N`: N cameras spread evenly over a sphere (a Fibonacci lattice);
//! - `random:N`: N cameras in uniformly random directions from a seeded generator;
//! - `cameras`: every camera of the file;
//! - anything else: a JSON file of explicit views (see [`read_views_file`]).
//!
//! Generated cameras look at the target with +Y up and stand at one distance from it (by
//! default the automatic camera's, which frames the model).
//!
//! A run records each view it finishes in the folder's [`RENDERED_FILE`] ([`RenderedView`]),
//! so that `--resume` keeps what an interrupted run finished.

use crate::camera::{look_at, near_plane};
use crate::defaults::MAX_VIEWS;
use crate::jobs::batch::{verify_outputs, OutputRecord, Shard};
use crate::output::view_file::ViewCamera;
use crate::sampling::Rng;
use crate::scene::Camera;
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// What `--views` asks for.
#[derive(Clone, Debug, PartialEq)]
pub enum ViewSpec {
    /// N views on a circle around the target.
    Orbit(usize),
    /// N views spread evenly over a sphere around the target.
    Sphere(usize),
    /// N views from seeded random directions.
    Random(usize),
    /// Every camera of the file.
    Cameras,
    /// A JSON file of explicit views.
    File(PathBuf),
}

/// A refused spec, views file or name pattern: what was given, and what is wrong with it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{what}: {problem}")]
pub struct ViewsError {
    /// The option and value, or the file (and view) at fault.
    pub what: String,
    /// What is wrong.
    pub problem: String,
}

fn views_error(what: impl Into<String>, problem: impl Into<String>) -> ViewsError {
    ViewsError {
        what: what.into(),
        problem: problem.into(),
    }
}

impl ViewSpec {
    /// Parses a `--views` value. Whatever is not `orbit:N`, `sphere:N`, `random:N` or
    /// `cameras` is taken for the path of a views file (read by [`read_views_file`]).
    pub fn parse(spec: &str) -> Result<ViewSpec, ViewsError> {
        let what = format!("--views {spec}");
        let text = spec.trim();
        if text.is_empty() {
            return Err(views_error(
                what,
                "empty: give orbit:N, sphere:N, random:N, cameras or a JSON file of views",
            ));
        }
        if text == "cameras" {
            return Ok(ViewSpec::Cameras);
        }
        type Make = fn(usize) -> ViewSpec;
        let kinds: [(&str, Make); 3] = [
            ("orbit", ViewSpec::Orbit),
            ("sphere", ViewSpec::Sphere),
            ("random", ViewSpec::Random),
        ];
        for (kind, make) in kinds {
            if text == kind {
                return Err(views_error(
                    what,
                    format!("give the number of views: {kind}:N"),
                ));
            }
            if let Some(count) = text.strip_prefix(kind).and_then(|r| r.strip_prefix(':')) {
                return parse_count(count)
                    .map(make)
                    .map_err(|p| views_error(what, p));
            }
        }
        Ok(ViewSpec::File(PathBuf::from(spec)))
    }

    /// The number of views, when the spec alone says it (not for `cameras` or a file).
    pub fn count(&self) -> Option<usize> {
        match self {
            ViewSpec::Orbit(n) | ViewSpec::Sphere(n) | ViewSpec::Random(n) => Some(*n),
            ViewSpec::Cameras | ViewSpec::File(_) => None,
        }
    }
}

/// A view count: a whole number from 1 to [`MAX_VIEWS`].
fn parse_count(text: &str) -> Result<usize, String> {
    let n: usize = text
        .trim()
        .parse()
        .map_err(|_| format!("'{text}' is not a whole number of views"))?;
    if n == 0 {
        return Err("the number of views must be at least 1".into());
    }
    if n > MAX_VIEWS {
        return Err(format!("{n} views: at most {MAX_VIEWS}"));
    }
    Ok(n)
}

/// Where generated views stand and what they look at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Framing {
    /// The point every view looks at (the model's centre unless told otherwise).
    pub target: Vec3,
    /// Distance of every view from the target.
    pub distance: f32,
    /// Vertical field of view, radians.
    pub yfov: f32,
    /// Radius of the model's bounding sphere, which sets the near clip plane.
    pub scene_radius: f32,
}

impl Framing {
    /// A camera in unit direction `direction` from the target, looking at it with +Y up.
    pub fn camera_from(&self, direction: Vec3) -> Camera {
        let mut camera = look_at(
            self.target + direction * self.distance,
            self.target,
            Vec3::Y,
            self.yfov,
            self.distance,
            self.scene_radius,
        );
        camera.name = None;
        camera
    }

    /// One camera per direction.
    pub fn cameras(&self, directions: &[Vec3]) -> Vec<Camera> {
        directions.iter().map(|&d| self.camera_from(d)).collect()
    }
}

/// What a run of many views may set about where generated views stand (the `--views`
/// options of `render`); `None` everywhere gives the defaults.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlanOptions {
    /// Vertical field of view of generated views, and of the file's perspective cameras when
    /// set (`--yfov`), degrees [default: 45].
    pub yfov_degrees: Option<f32>,
    /// The point generated views look at (`--look-at`) [default: the model's centre].
    pub look_at: Option<Vec3>,
    /// Their distance from it (`--orbit-radius`) [default: the distance that frames the model].
    pub orbit_radius: Option<f32>,
    /// Azimuth of the first orbit view (`--orbit-azimuth`), degrees [default: 0, in front].
    pub orbit_azimuth: Option<f32>,
    /// Elevation of the orbit (`--orbit-elevation`), degrees [default: 20].
    pub orbit_elevation: Option<f32>,
    /// Seed of `random:N` directions.
    pub seed: u64,
}

/// The cameras of `spec` for `scene` at an image aspect of `aspect`: generated views around
/// the target ([`Framing`]), the file's cameras (`cameras`; their yfov replaced when
/// `options` sets one), or the views of a file (`explicit`, as [`read_views_file`] read
/// them). Refuses `cameras` for a file without any.
pub fn plan_cameras(
    spec: &ViewSpec,
    explicit: &[ExplicitView],
    scene: &crate::scene::Scene,
    aspect: f32,
    options: &PlanOptions,
) -> Result<Vec<Camera>, ViewsError> {
    use crate::camera::{fit_distance, framing_distance, framing_radius};
    use crate::defaults::{DEFAULT_ORBIT_ELEVATION_DEGREES, DEFAULT_YFOV_DEGREES};
    let yfov = options
        .yfov_degrees
        .unwrap_or(DEFAULT_YFOV_DEGREES)
        .to_radians();
    let scene_radius = framing_radius(&scene.bounds);
    // Generated views share one distance: the closest at which every vertex is inside the frame
    // from every one of their directions (as the automatic camera fits its own); a look-at
    // target away from the centre frames the bounding sphere instead.
    let distance = |directions: &[Vec3]| match (options.orbit_radius, options.look_at) {
        (Some(radius), _) => radius,
        (None, None) => {
            let points = &scene.soup.positions;
            fit_distance(
                &scene.bounds,
                points,
                directions.iter().copied(),
                yfov,
                aspect,
            )
            .unwrap_or_else(|| framing_distance(scene_radius, yfov, aspect))
        }
        (None, Some(_)) => framing_distance(scene_radius, yfov, aspect),
    };
    let generated = |directions: Vec<Vec3>| {
        let framing = Framing {
            target: options.look_at.unwrap_or(scene.bounds.center()),
            distance: distance(&directions),
            yfov,
            scene_radius,
        };
        framing.cameras(&directions)
    };
    Ok(match spec {
        ViewSpec::Orbit(n) => generated(orbit_directions(
            *n,
            options
                .orbit_elevation
                .unwrap_or(DEFAULT_ORBIT_ELEVATION_DEGREES),
            options.orbit_azimuth.unwrap_or(0.0),
        )),
        ViewSpec::Sphere(n) => generated(fibonacci_directions(*n)),
        ViewSpec::Random(n) => generated(random_directions(*n, options.seed)),
        ViewSpec::Cameras => {
            if scene.cameras.is_empty() {
                return Err(views_error(
                    format!("{}: --views cameras", scene.source.display()),
                    "the file has no cameras",
                ));
            }
            let mut cameras = scene.cameras.clone();
            if let Some(deg) = options.yfov_degrees {
                for c in &mut cameras {
                    if let crate::scene::Projection::Perspective { yfov, .. } = &mut c.projection {
                        *yfov = deg.to_radians();
                    }
                }
            }
            cameras
        }
        ViewSpec::File(_) => explicit
            .iter()
            .map(|v| v.camera(yfov, scene.bounds.center(), scene_radius))
            .collect(),
    })
}

/// `n` unit directions on the circle at `elevation_degrees` above the horizontal plane: the
/// first at `azimuth_degrees` (0 toward +Z, 90 toward +X), then counter-clockwise seen from
/// above (about +Y) in equal steps.
pub fn orbit_directions(n: usize, elevation_degrees: f32, azimuth_degrees: f32) -> Vec<Vec3> {
    let elevation = elevation_degrees.to_radians();
    let start = azimuth_degrees.to_radians();
    (0..n)
        .map(|k| {
            let azimuth = start + std::f32::consts::TAU * k as f32 / n as f32;
            Vec3::new(
                elevation.cos() * azimuth.sin(),
                elevation.sin(),
                elevation.cos() * azimuth.cos(),
            )
        })
        .collect()
}

/// The azimuth of `from` seen from `target`, in degrees as [`orbit_directions`] counts them:
/// 0 toward +Z, 90 toward +X, in (-180, 180]. A point straight above or below the target
/// (no horizontal offset) has azimuth 0.
pub fn azimuth_degrees(from: Vec3, target: Vec3) -> f32 {
    let offset = from - target;
    let horizontal = offset.x.hypot(offset.z);
    // NaN (a non-finite position) counts as no offset too.
    if horizontal.is_nan() || horizontal <= offset.length() * 1e-6 {
        return 0.0;
    }
    offset.x.atan2(offset.z).to_degrees()
}

/// The elevation of `from` above the horizontal plane through `target`, in degrees as
/// [`orbit_directions`] counts them: from -90 (straight below) to 90 (straight above); 0 when
/// the two points coincide.
pub fn elevation_degrees(from: Vec3, target: Vec3) -> f32 {
    match (from - target).try_normalize() {
        Some(direction) => direction.y.clamp(-1.0, 1.0).asin().to_degrees(),
        None => 0.0,
    }
}

/// `n` unit directions spread evenly over the sphere: the Fibonacci lattice, equal-area bands
/// in y (from top to bottom) turned by the golden angle from one point to the next, so that
/// every point covers about 4π/n of the sphere.
pub fn fibonacci_directions(n: usize) -> Vec<Vec3> {
    let golden_angle = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let ring = (1.0 - y * y).max(0.0).sqrt();
            let phi = golden_angle * i as f64;
            Vec3::new(
                (ring * phi.sin()) as f32,
                y as f32,
                (ring * phi.cos()) as f32,
            )
        })
        .collect()
}

/// `n` unit directions drawn uniformly over the sphere from a generator seeded with `seed`:
/// the same seed gives the same directions.
pub fn random_directions(n: usize, seed: u64) -> Vec<Vec3> {
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| {
            // Archimedes: y uniform in [-1, 1] and the azimuth uniform is uniform on the sphere.
            let y = 1.0 - 2.0 * rng.next_f32();
            let phi = std::f32::consts::TAU * rng.next_f32();
            let ring = (1.0 - y * y).max(0.0).sqrt();
            Vec3::new(ring * phi.sin(), y, ring * phi.cos())
        })
        .collect()
}

/// One view of a views file.
#[derive(Clone, Debug, PartialEq)]
pub enum ExplicitView {
    /// A camera at `from` looking at `at`.
    LookAt {
        /// Eye position.
        from: Vec3,
        /// Point looked at.
        at: Vec3,
        /// Up direction [default: +Y].
        up: Option<Vec3>,
        /// Vertical field of view in degrees [default: `--yfov`, else 45].
        yfov_degrees: Option<f32>,
    },
    /// A camera as a view file (`--view-out`) records it.
    Camera(Camera),
}

impl ExplicitView {
    /// The point a thin lens focuses on by default: the view's `look_at`, where it has one
    /// (a view file's camera records only a direction).
    pub fn focus_target(&self) -> Option<Vec3> {
        match self {
            ExplicitView::LookAt { at, .. } => Some(*at),
            ExplicitView::Camera(_) => None,
        }
    }

    /// The camera of this view: `yfov` (radians) where the view gives none, and the near clip
    /// plane from the scene's bounding sphere (`scene_centre`, `scene_radius`).
    pub fn camera(&self, yfov: f32, scene_centre: Vec3, scene_radius: f32) -> Camera {
        match self {
            ExplicitView::LookAt {
                from,
                at,
                up,
                yfov_degrees,
            } => {
                let yfov = yfov_degrees.map_or(yfov, f32::to_radians);
                let distance = (*at - *from).length();
                let mut camera = look_at(
                    *from,
                    *at,
                    up.unwrap_or(Vec3::Y),
                    yfov,
                    distance,
                    scene_radius,
                );
                camera.name = None;
                // As `--look-from` does: the near plane follows the scene, not the look-at point.
                if let crate::scene::Projection::Perspective { znear, .. } = &mut camera.projection
                {
                    *znear = near_plane(*from, scene_centre, scene_radius);
                }
                camera
            }
            ExplicitView::Camera(camera) => camera.clone(),
        }
    }
}

/// A views file larger than this is refused before it is read: [`MAX_VIEWS`] views of a few
/// hundred bytes each fit many times over.
pub const MAX_VIEWS_FILE_BYTES: u64 = 256 << 20;

/// Reads a views file: a JSON list (or an object whose `views` member is the list) of
/// - `{"look_from": [x, y, z], "look_at": [x, y, z], "up": [x, y, z], "yfov_degrees": deg}`
///   (`up` and `yfov_degrees` optional), or
/// - objects with a `camera` member as a view file records it (`--view-out`): a whole view file
///   is accepted, and only its camera is used.
///
/// Every view is checked here, before any model is loaded: errors name the file and the view.
pub fn read_views_file(path: &Path) -> Result<Vec<ExplicitView>, ViewsError> {
    let file = path.display().to_string();
    let size = std::fs::metadata(path)
        .map_err(|e| {
            views_error(
                format!("--views {file}"),
                format!(
                    "not orbit:N, sphere:N, random:N or cameras, and not a readable file ({e})"
                ),
            )
        })?
        .len();
    if size > MAX_VIEWS_FILE_BYTES {
        return Err(views_error(
            &file,
            format!("{size} bytes: a views file may have at most {MAX_VIEWS_FILE_BYTES}"),
        ));
    }
    let text = std::fs::read_to_string(path).map_err(|e| views_error(&file, e.to_string()))?;
    parse_views(&text).map_err(|mut e| {
        e.what = if e.what.is_empty() {
            file.clone()
        } else {
            format!("{file}: {}", e.what)
        };
        e
    })
}

/// Parses the text of a views file (see [`read_views_file`]); errors name the view, not the
/// file.
pub fn parse_views(text: &str) -> Result<Vec<ExplicitView>, ViewsError> {
    let json: serde_json::Value =
        serde_json::from_str(text).map_err(|e| views_error("", format!("not JSON: {e}")))?;
    let list = match &json {
        serde_json::Value::Array(list) => list,
        serde_json::Value::Object(object) => match object.get("views") {
            Some(serde_json::Value::Array(list)) => list,
            _ => {
                return Err(views_error(
                    "",
                    "expected a list of views, or an object with a \"views\" list",
                ))
            }
        },
        _ => return Err(views_error("", "expected a list of views")),
    };
    if list.is_empty() {
        return Err(views_error("", "the list of views is empty"));
    }
    if list.len() > MAX_VIEWS {
        return Err(views_error(
            "",
            format!("{} views: at most {MAX_VIEWS}", list.len()),
        ));
    }
    list.iter()
        .enumerate()
        .map(|(i, entry)| parse_view(entry).map_err(|p| views_error(format!("view {i}"), p)))
        .collect()
}

/// A look-at entry of a views file.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct LookAtEntry {
    look_from: [f32; 3],
    look_at: [f32; 3],
    #[serde(default)]
    up: Option<[f32; 3]>,
    #[serde(default)]
    yfov_degrees: Option<f32>,
}

fn parse_view(entry: &serde_json::Value) -> Result<ExplicitView, String> {
    let Some(object) = entry.as_object() else {
        return Err("expected an object with look_from and look_at, or with a camera".into());
    };
    if let Some(camera) = object.get("camera") {
        let camera: ViewCamera = serde_json::from_value(camera.clone())
            .map_err(|e| format!("camera: not a view file's camera: {e}"))?;
        return camera
            .to_camera()
            .map(ExplicitView::Camera)
            .map_err(|p| format!("camera: {p}"));
    }
    if !object.contains_key("look_from") {
        return Err("expected look_from and look_at, or a camera as --view-out writes it".into());
    }
    let entry: LookAtEntry = serde_json::from_value(entry.clone()).map_err(|e| e.to_string())?;
    let finite = |v: [f32; 3]| v.iter().all(|x| x.is_finite());
    if !(finite(entry.look_from) && finite(entry.look_at) && entry.up.is_none_or(finite)) {
        return Err("look_from, look_at and up must be finite".into());
    }
    let (from, at) = (Vec3::from(entry.look_from), Vec3::from(entry.look_at));
    let Some(forward) = (at - from).try_normalize() else {
        return Err("look_at equals look_from".into());
    };
    if let Some(up) = entry.up.map(Vec3::from) {
        if (up - forward * up.dot(forward)).try_normalize().is_none() {
            return Err("up is zero or parallel to the view direction".into());
        }
    }
    if let Some(deg) = entry.yfov_degrees {
        if !(deg > 0.0 && deg < 180.0) {
            return Err(format!(
                "yfov_degrees {deg}: must be between 0 and 180 degrees"
            ));
        }
    }
    Ok(ExplicitView::LookAt {
        from,
        at,
        up: entry.up.map(Vec3::from),
        yfov_degrees: entry.yfov_degrees,
    })
}

/// A file-name pattern with the view number in it: `{view}` is the number, `{view:0N}` the
/// number zero-padded to N digits (N from 1 to 9), as in Python's format strings.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NamePattern {
    text: String,
    parts: Vec<NamePart>,
}

#[derive(Clone, Debug, PartialEq, Eq)]
enum NamePart {
    Literal(String),
    View { width: usize },
}

impl NamePattern {
    /// Parses a pattern; `option` names it in errors (e.g. `--depth-out`).
    pub fn parse(pattern: &str, option: &str) -> Result<NamePattern, ViewsError> {
        let err = |problem: String| views_error(format!("{option} {pattern}"), problem);
        let mut parts = Vec::new();
        let mut rest = pattern;
        while let Some(open) = rest.find(['{', '}']) {
            if rest[open..].starts_with('}') {
                return Err(err("a '}' without its '{'".into()));
            }
            if open > 0 {
                parts.push(NamePart::Literal(rest[..open].to_string()));
            }
            let Some(close) = rest[open..].find('}') else {
                return Err(err("a '{' without its '}'".into()));
            };
            let field = &rest[open + 1..open + close];
            let width = match field {
                "view" => 0,
                _ => field
                    .strip_prefix("view:0")
                    .and_then(|w| w.parse::<usize>().ok())
                    .filter(|w| (1..=9).contains(w))
                    .ok_or_else(|| {
                        err(format!(
                            "unknown placeholder {{{field}}} (use {{view}} or {{view:03}})"
                        ))
                    })?,
            };
            parts.push(NamePart::View { width });
            rest = &rest[open + close + 1..];
        }
        if !rest.is_empty() {
            parts.push(NamePart::Literal(rest.to_string()));
        }
        if pattern.is_empty() {
            return Err(err("empty".into()));
        }
        Ok(NamePattern {
            text: pattern.to_string(),
            parts,
        })
    }

    /// The default pattern `{view:03}` + `suffix`, padded wider when `count` views need more
    /// than three digits, so that the names sort in view order.
    pub fn numbered(count: usize, suffix: &str) -> NamePattern {
        let digits = count.saturating_sub(1).max(1).to_string().len().max(3);
        let mut parts = vec![NamePart::View { width: digits }];
        if !suffix.is_empty() {
            parts.push(NamePart::Literal(suffix.to_string()));
        }
        NamePattern {
            text: format!("{{view:0{digits}}}{suffix}"),
            parts,
        }
    }

    /// Whether the pattern has the view number in it (else every view gets the same name).
    pub fn has_view(&self) -> bool {
        self.parts
            .iter()
            .any(|p| matches!(p, NamePart::View { .. }))
    }

    /// The pattern as given.
    pub fn as_str(&self) -> &str {
        &self.text
    }

    /// The name of view `view`.
    pub fn expand(&self, view: usize) -> String {
        self.parts
            .iter()
            .map(|p| match p {
                NamePart::Literal(text) => text.clone(),
                NamePart::View { width } => format!("{view:0width$}"),
            })
            .collect()
    }
}

/// The file in a `--views` folder that records every finished view, one [`RenderedView`] a
/// line: appended as each view's files are all written, rewritten in view order at the end (so
/// the same run writes the same bytes). `--resume` reads it.
pub const RENDERED_FILE: &str = "rendered.jsonl";

/// A finished view, a line of [`RENDERED_FILE`]: what it was rendered from and its files.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct RenderedView {
    /// The view number.
    pub view: usize,
    /// SHA-256 (hex) of everything that decides the view's files: meshtracer's version, the
    /// model file's hash, the render settings and the view file's text.
    pub fingerprint: String,
    /// Its files (image, AOVs, mask, view file), paths as named under the folder, with their
    /// SHA-256.
    pub files: Vec<OutputRecord>,
}

impl RenderedView {
    /// The record as one line of [`RENDERED_FILE`], newline included.
    pub fn line(&self) -> String {
        serde_json::to_string(self).expect("a record serialises") + "\n"
    }

    /// Whether this record vouches for view `view` rendered from `fingerprint` into the files
    /// `names` in `dir`: the same view, fingerprint and file names, and every file still with
    /// its recorded hash. The error says what differs.
    pub fn vouches_for(
        &self,
        dir: &Path,
        view: usize,
        fingerprint: &str,
        names: &[&str],
    ) -> Result<(), String> {
        if self.view != view {
            return Err(format!("the record is of view {}", self.view));
        }
        if self.fingerprint != fingerprint {
            return Err(
                "the options, the model (or a file it refers to) or meshtracer changed".into(),
            );
        }
        let recorded: Vec<&str> = self.files.iter().map(|f| f.path.as_str()).collect();
        if recorded != names {
            return Err("its files have other names".into());
        }
        verify_outputs(dir, &self.files)
    }
}

/// The records of finished views by view number, as [`read_rendered_in`] finds them.
pub type ViewRecords = std::collections::HashMap<usize, Vec<RenderedView>>;

/// The record file of `shard`'s views: [`RENDERED_FILE`] for a whole run,
/// `rendered.I-of-N.jsonl` for a shard, so that shards never write the same file.
pub fn rendered_file(shard: Shard) -> String {
    shard.jsonl_file("rendered")
}

/// Whether view `view` is one of `shard`'s: view k belongs to shard k mod N, so that each
/// shard of an orbit gets views from all around it.
pub fn in_shard(view: usize, shard: Shard) -> bool {
    view % shard.count == shard.index
}

/// The shards' record files (`rendered.I-of-N.jsonl`, N > 1) in `dir`, sorted; none when
/// `dir` does not exist.
pub fn shard_record_files(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let listing = match std::fs::read_dir(dir) {
        Ok(listing) => listing,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(e),
    };
    let mut files = Vec::new();
    for item in listing {
        let item = item?;
        let is_shard = item
            .file_name()
            .to_str()
            .and_then(|n| Shard::of_jsonl_file("rendered", n))
            .is_some_and(|s| s.count > 1);
        if is_shard {
            files.push(item.path());
        }
    }
    files.sort();
    Ok(files)
}

/// Every record of finished views in `dir`, from [`RENDERED_FILE`] and every shard's
/// ([`shard_record_files`]): the records of each view, several when the files overlap. An
/// error names the file that could not be read.
pub fn read_rendered_in(dir: &Path) -> std::io::Result<ViewRecords> {
    let mut records = ViewRecords::new();
    for path in std::iter::once(dir.join(RENDERED_FILE)).chain(shard_record_files(dir)?) {
        let read = read_rendered(&path)
            .map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", path.display())))?;
        for (view, record) in read {
            records.entry(view).or_default().push(record);
        }
    }
    Ok(records)
}

/// The records of [`RENDERED_FILE`] at `path`, by view number (the last line of a view wins);
/// none when the file is missing. A line that is not a record (torn by a kill as it was
/// appended) is passed over: its view is rendered again.
pub fn read_rendered(
    path: &Path,
) -> std::io::Result<std::collections::HashMap<usize, RenderedView>> {
    let text = match std::fs::read(path) {
        Ok(bytes) => bytes,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Default::default()),
        Err(e) => return Err(e),
    };
    Ok(text
        .split(|&b| b == b'\n')
        .filter_map(|line| serde_json::from_slice::<RenderedView>(line).ok())
        .map(|record| (record.view, record))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn framing() -> Framing {
        Framing {
            target: Vec3::new(1.0, 2.0, -3.0),
            distance: 4.0,
            yfov: 45f32.to_radians(),
            scene_radius: 1.5,
        }
    }

    /// The record reads back what it wrote, passes over a torn line, and vouches for a view
    /// only with the same view, fingerprint, names and bytes.
    #[test]
    fn a_rendered_view_vouches_only_for_what_it_recorded() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("000.png"), b"image").unwrap();
        std::fs::write(dir.path().join("000.view.json"), b"{}").unwrap();
        let file = |path: &str| OutputRecord {
            path: path.into(),
            sha256: crate::jobs::batch::sha256_file(&dir.path().join(path)).unwrap(),
        };
        let record = RenderedView {
            view: 0,
            fingerprint: "f".into(),
            files: vec![file("000.png"), file("000.view.json")],
        };
        let names = ["000.png", "000.view.json"];
        assert_eq!(record.vouches_for(dir.path(), 0, "f", &names), Ok(()));
        let refusals = [
            (record.vouches_for(dir.path(), 1, "f", &names), "of view 0"),
            (record.vouches_for(dir.path(), 0, "g", &names), "options"),
            (
                record.vouches_for(dir.path(), 0, "f", &["000.exr", "000.view.json"]),
                "other names",
            ),
        ];
        for (result, words) in refusals {
            assert!(result.unwrap_err().contains(words), "{words}");
        }
        std::fs::write(dir.path().join("000.png"), b"other").unwrap();
        let changed = record.vouches_for(dir.path(), 0, "f", &names).unwrap_err();
        assert_eq!(changed, "000.png changed since it was written");

        let path = dir.path().join(RENDERED_FILE);
        assert!(
            read_rendered(&path).unwrap().is_empty(),
            "no file, no views"
        );
        let second = RenderedView {
            view: 1,
            ..record.clone()
        };
        let torn = &second.line()[..20];
        std::fs::write(&path, record.line() + torn).unwrap();
        let read = read_rendered(&path).unwrap();
        assert_eq!(read.len(), 1);
        assert_eq!(read[&0], record);
    }

    /// Every view belongs to exactly one shard, round the views; each shard records apart, and
    /// the records of a folder are read from the whole run's file and every shard's.
    #[test]
    fn shards_split_the_views_and_their_records_are_found() {
        let shards: Vec<Shard> = (0..3).map(|i| Shard::new(i, 3).unwrap()).collect();
        for view in 0..10 {
            let holders = shards.iter().filter(|&&s| in_shard(view, s)).count();
            assert_eq!(holders, 1, "view {view}");
        }
        assert!(in_shard(7, shards[1]) && in_shard(7, Shard::ALL));
        assert_eq!(rendered_file(Shard::ALL), RENDERED_FILE);
        assert_eq!(rendered_file(shards[2]), "rendered.2-of-3.jsonl");

        let dir = tempfile::tempdir().unwrap();
        assert!(read_rendered_in(&dir.path().join("missing"))
            .unwrap()
            .is_empty());
        let record = |view| RenderedView {
            view,
            fingerprint: "f".into(),
            files: Vec::new(),
        };
        let write = |name: &str, views: &[usize]| {
            let text: String = views.iter().map(|&v| record(v).line()).collect();
            std::fs::write(dir.path().join(name), text).unwrap();
        };
        write(RENDERED_FILE, &[0, 1]);
        write("rendered.1-of-3.jsonl", &[1, 4]);
        write("rendered.0-of-1.jsonl", &[9]);
        write("rendered.x-of-3.jsonl", &[8]);
        let files = shard_record_files(dir.path()).unwrap();
        assert_eq!(files, [dir.path().join("rendered.1-of-3.jsonl")]);
        let found = read_rendered_in(dir.path()).unwrap();
        let mut views: Vec<(usize, usize)> = found.iter().map(|(&v, r)| (v, r.len())).collect();
        views.sort();
        assert_eq!(views, [(0, 1), (1, 2), (4, 1)]);
    }

    #[test]
    fn specs_parse_and_bad_ones_say_why() {
        assert_eq!(ViewSpec::parse("orbit:8"), Ok(ViewSpec::Orbit(8)));
        assert_eq!(ViewSpec::parse("sphere:1"), Ok(ViewSpec::Sphere(1)));
        assert_eq!(
            ViewSpec::parse("random:100000"),
            Ok(ViewSpec::Random(100_000))
        );
        assert_eq!(ViewSpec::parse("cameras"), Ok(ViewSpec::Cameras));
        assert_eq!(
            ViewSpec::parse("my views.json"),
            Ok(ViewSpec::File("my views.json".into()))
        );
        for (spec, words) in [
            ("orbit:0", "at least 1"),
            ("orbit:abc", "'abc' is not a whole number"),
            ("sphere:-3", "'-3' is not a whole number"),
            ("random:100001", "at most 100000"),
            ("orbit:99999999999999999999999", "not a whole number"),
            ("orbit", "orbit:N"),
            ("", "empty"),
        ] {
            let e = ViewSpec::parse(spec).unwrap_err().to_string();
            assert!(e.starts_with(&format!("--views {spec}: ")), "{e}");
            assert!(e.contains(words), "{spec}: {e}");
        }
    }

    /// Orbit cameras stand on the circle at the given elevation and distance, equally spaced,
    /// and look at the target with +Y up.
    #[test]
    fn orbit_points_lie_on_the_circle_and_look_at_the_centre() {
        let f = framing();
        let n = 12;
        let cameras = f.cameras(&orbit_directions(n, 30.0, 0.0));
        assert_eq!(cameras.len(), n);
        let height = f.distance * 30f32.to_radians().sin();
        for (k, c) in cameras.iter().enumerate() {
            let offset = c.position - f.target;
            assert!((offset.length() - f.distance).abs() < 1e-5, "{k}: {offset}");
            assert!((offset.y - height).abs() < 1e-5, "{k}: elevation");
            let to_target = (f.target - c.position).normalize();
            assert!(
                (c.forward - to_target).length() < 1e-6,
                "{k}: looks at the target"
            );
            assert!(c.up.dot(c.forward).abs() < 1e-6 && c.up.y > 0.0, "{k}: up");
            let azimuth = offset.x.atan2(offset.z);
            let expected = std::f32::consts::TAU * k as f32 / n as f32;
            // The difference, wrapped into [-π, π).
            let diff = (azimuth - expected + std::f32::consts::PI)
                .rem_euclid(std::f32::consts::TAU)
                - std::f32::consts::PI;
            assert!(diff.abs() < 1e-5, "{k}: azimuth {azimuth} vs {expected}");
        }
        // View 0 in front (+Z); view 1 turned counter-clockwise seen from above, toward +X.
        assert!(
            cameras[0].position.z > f.target.z && (cameras[0].position.x - f.target.x).abs() < 1e-5
        );
        assert!(cameras[1].position.x > f.target.x);
    }

    /// An orbit may start at any azimuth; the azimuth and elevation of a point are what the
    /// orbit that starts there was given.
    #[test]
    fn orbits_start_at_the_given_azimuth() {
        let f = framing();
        for (start, elevation) in [(0.0f32, 20.0), (28.8, 21.5), (90.0, -45.0), (-135.0, 89.0)] {
            let directions = orbit_directions(4, elevation, start);
            let first = f.camera_from(directions[0]).position;
            let measured = azimuth_degrees(first, f.target);
            let diff = (measured - start + 180.0).rem_euclid(360.0) - 180.0;
            assert!(diff.abs() < 1e-3, "start {start}: {measured}");
            let up = elevation_degrees(first, f.target);
            assert!((up - elevation).abs() < 1e-3, "elevation {elevation}: {up}");
            // Still counter-clockwise seen from above: a quarter turn on.
            let second = azimuth_degrees(f.camera_from(directions[1]).position, f.target);
            let step = (second - measured).rem_euclid(360.0);
            assert!((step - 90.0).abs() < 1e-3, "start {start}: step {step}");
        }
        // The automatic camera's direction (0.55, 0.45, 1): atan(0.55) = 28.81 degrees.
        let auto = azimuth_degrees(Vec3::new(0.55, 0.45, 1.0), Vec3::ZERO);
        assert!((auto - 28.810794).abs() < 1e-4, "{auto}");
        assert_eq!(
            azimuth_degrees(Vec3::new(0.0, 5.0, 0.0), Vec3::ZERO),
            0.0,
            "above"
        );
        // Its elevation: asin(0.45 / |(0.55, 0.45, 1)|) = 21.52 degrees.
        let auto = elevation_degrees(Vec3::new(0.55, 0.45, 1.0), Vec3::ZERO);
        assert!((auto - 21.519177).abs() < 1e-3, "{auto}");
        let above = elevation_degrees(Vec3::new(0.0, 5.0, 0.0), Vec3::new(0.0, 1.0, 0.0));
        assert_eq!(above, 90.0);
        assert_eq!(elevation_degrees(Vec3::ONE, Vec3::ONE), 0.0, "same point");
    }

    /// Fibonacci points are unit vectors, cover the sphere without clumping (every point's
    /// nearest neighbour is at least 0.7 of the spacing sqrt(4π/n) of an ideal lattice; the
    /// lattice reaches 0.87 from 7 points on, 0.76 for 2) and balance out (their mean is near
    /// the centre).
    #[test]
    fn fibonacci_points_are_unit_and_well_spread() {
        for n in [1usize, 2, 7, 50, 400] {
            let points = fibonacci_directions(n);
            assert_eq!(points.len(), n);
            for p in &points {
                assert!((p.length() - 1.0).abs() < 1e-6);
            }
            if n < 2 {
                continue;
            }
            // n points each covering 4π/n: neighbours about sqrt(4π/n) apart.
            let spacing = (4.0 * std::f32::consts::PI / n as f32).sqrt();
            for (i, p) in points.iter().enumerate() {
                let nearest = points
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| *j != i)
                    .map(|(_, q)| (*p - *q).length())
                    .fold(f32::INFINITY, f32::min);
                assert!(
                    nearest > 0.7 * spacing,
                    "n {n}, point {i}: {nearest} vs {spacing}"
                );
            }
            let mean = points.iter().copied().sum::<Vec3>() / n as f32;
            assert!(mean.length() < 1.0 / n as f32 + 1e-3, "n {n}: mean {mean}");
            let upper = points.iter().filter(|p| p.y > 0.0).count();
            assert!(
                upper.abs_diff(n - upper) <= 1,
                "n {n}: {upper} above the equator"
            );
        }
    }

    #[test]
    fn random_directions_are_seeded_unit_and_cover_the_sphere() {
        let a = random_directions(2000, 7);
        assert_eq!(a, random_directions(2000, 7), "same seed, same directions");
        assert_ne!(
            a,
            random_directions(2000, 8),
            "another seed, other directions"
        );
        assert!(a.iter().all(|p| (p.length() - 1.0).abs() < 1e-5));
        // Uniform: each octant holds about an eighth (250 ± 5 sigma, sigma ≈ 14.8).
        for octant in 0..8 {
            let sign = |bit: i32| if octant & bit == 0 { 1.0 } else { -1.0 };
            let count = a
                .iter()
                .filter(|p| p.x * sign(1) > 0.0 && p.y * sign(2) > 0.0 && p.z * sign(4) > 0.0)
                .count();
            assert!((176..=324).contains(&count), "octant {octant}: {count}");
        }
    }

    #[test]
    fn views_files_parse_both_forms_and_name_the_bad_view() {
        let views = parse_views(
            r#"{"views": [
                {"look_from": [0, 1, 5], "look_at": [0, 1, 0]},
                {"look_from": [5, 1, 0], "look_at": [0, 1, 0], "up": [0, 0, 1], "yfov_degrees": 30},
                {"camera": {"type": "perspective", "position": [0, 0, 3], "look_at": [0, 0, 2],
                            "up": [0, 1, 0], "yfov": 0.5, "aspect": 1.5, "znear": 0.1, "zfar": null},
                 "lights": []}
            ]}"#,
        )
        .unwrap();
        assert_eq!(views.len(), 3);
        let c = views[1].camera(1.0, Vec3::ZERO, 1.0);
        assert!((c.forward - Vec3::NEG_X).length() < 1e-6 && (c.up - Vec3::Z).length() < 1e-6);
        match c.projection {
            crate::scene::Projection::Perspective { yfov, .. } => {
                assert!((yfov - 30f32.to_radians()).abs() < 1e-6)
            }
            _ => panic!("perspective"),
        }
        let c = views[2].camera(1.0, Vec3::ZERO, 1.0);
        assert_eq!(c.position, Vec3::new(0.0, 0.0, 3.0));
        for (text, words) in [
            ("[", "not JSON"),
            ("{}", "a list of views"),
            ("[]", "empty"),
            ("[3]", "view 0: expected an object"),
            (
                r#"[{"look_from": [0, 0, 1]}]"#,
                "view 0: missing field `look_at`",
            ),
            (
                r#"[{"look_from": [0,0,1], "look_at": [0,0,0]}, {"look_from": [0,0,1], "look_at": [0,0,1]}]"#,
                "view 1: look_at equals look_from",
            ),
            (
                r#"[{"look_from": [0,0,1], "look_at": [0,0,0], "lookat": 1}]"#,
                "unknown field `lookat`",
            ),
            (
                r#"[{"look_from": [0,0,1], "look_at": [0,0,0], "up": [0,0,2]}]"#,
                "parallel",
            ),
            (
                r#"[{"look_from": [0,0,1], "look_at": [0,0,0], "yfov_degrees": 180}]"#,
                "between 0 and 180",
            ),
            (r#"[{"camera": {"type": "fisheye"}}]"#, "view 0: camera"),
            (r#"[{"up": [0, 1, 0]}]"#, "view 0: expected look_from"),
        ] {
            let e = parse_views(text).unwrap_err().to_string();
            assert!(e.contains(words), "{text}: {e}");
        }
    }

    #[test]
    fn name_patterns_expand_and_refuse_unknown_placeholders() {
        let p = NamePattern::parse("depth/{view:03}.png", "--depth-out").unwrap();
        assert!(p.has_view());
        assert_eq!(p.expand(7), "depth/007.png");
        assert_eq!(p.expand(1234), "depth/1234.png");
        let p = NamePattern::parse("v{view}-{view:02}.npy", "--depth-out").unwrap();
        assert_eq!(p.expand(3), "v3-03.npy");
        assert!(!NamePattern::parse("depth.png", "--depth-out")
            .unwrap()
            .has_view());
        for (pattern, words) in [
            ("{frame}.png", "unknown placeholder {frame}"),
            ("{view:3}.png", "unknown placeholder"),
            ("{view:010}.png", "unknown placeholder"),
            ("{view.png", "without its '}'"),
            ("view}.png", "without its '{'"),
        ] {
            let e = NamePattern::parse(pattern, "--view-name")
                .unwrap_err()
                .to_string();
            assert!(e.starts_with(&format!("--view-name {pattern}: ")), "{e}");
            assert!(e.contains(words), "{pattern}: {e}");
        }
        assert_eq!(NamePattern::numbered(8, ".png").expand(7), "007.png");
        assert_eq!(NamePattern::numbered(1000, ".png").expand(7), "007.png");
        assert_eq!(NamePattern::numbered(1001, ".png").expand(7), "0007.png");
        assert_eq!(NamePattern::numbered(8, ".png").as_str(), "{view:03}.png");
    }
}
