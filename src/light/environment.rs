//! Environment lighting: an equirectangular (latitude-longitude) panorama of radiance that
//! surrounds the scene, importance-sampled for next-event estimation.
//!
//! **Orientation** (the convention Blender Cycles uses for the same files, so a Cycles
//! reference lights the model identically): in glTF's frame (+Y up), direction d maps to
//! `u = 0.5 + atan2(d.z, d.x) / 2π`, `v = acos(d.y) / π`, with v = 0 the top row. The centre
//! column looks along +X, the top row straight up. `rotation` turns the panorama about +Y
//! (positive = counter-clockwise seen from above, as Blender's Z rotation of the mapping).
//!
//! **Sampling**: texel (i, j) is drawn with probability ∝ luminance × sin θ (its solid angle),
//! through a marginal distribution over rows and a conditional one per row (pbrt-v4 §12.5); the
//! pdf per steradian is `p_uv / (2π² sin θ)`.
//!
//! **Filtering**: radiance is interpolated bilinearly between texel centres (wrapping around in
//! u, clamped at the poles), for lighting and for the visible background alike, so mirrors and
//! a visible panorama show no blocky texels. The sampling weight of a texel is the average of
//! that filtered function over the texel (the luminance of the 3 x 3 neighbourhood weighted
//! (1/8, 3/4, 1/8) along each axis), so the pdf is positive wherever the filtered radiance is:
//! the estimator stays unbiased and MIS stays consistent, and a tiny sun still converges.

use crate::color::luminance;
use crate::sampling::{sin_cos_turns, Distribution1D};
use glam::Vec3;
use std::f32::consts::{PI, TAU};
use std::path::{Path, PathBuf};

/// Largest panorama accepted: 16384 x 8192 texels (a 2 GB float image is not a light).
pub const MAX_ENVIRONMENT_TEXELS: u64 = 16384 * 8192;

/// Where an environment came from, as `VIEW.json` records it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum EnvironmentSource {
    /// The built-in neutral studio ([`Environment::studio`]), with its parameters.
    Studio {
        /// Radiance below the horizon.
        floor: f32,
        /// Radiance at the horizon, above it.
        horizon: f32,
        /// Radiance added straight up, falling off as cos⁴ of the angle from +Y.
        top: f32,
    },
    /// A panorama file.
    File {
        /// The file as given.
        path: PathBuf,
    },
    /// One radiance in every direction (the white furnace).
    Uniform {
        /// The radiance.
        radiance: [f32; 3],
    },
}

/// A failure to read a panorama.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {problem}")]
pub struct EnvironmentError {
    /// The file.
    pub path: PathBuf,
    /// What went wrong.
    pub problem: String,
}

/// A point of the panorama in map coordinates (u, v) in [0, 1)² (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapPoint {
    u: f32,
    v: f32,
}

/// An environment light.
#[derive(Clone, Debug)]
pub struct Environment {
    width: usize,
    height: usize,
    /// Linear radiance, row-major from the top row.
    texels: Vec<Vec3>,
    /// Rotation about +Y, radians.
    rotation: f32,
    /// sin and cos of `rotation` (world from map) and of `-rotation` (map from world), worked
    /// out once: every lookup turns its direction, and `sin_cos` was 4% of a path-traced Box.
    world_from_map: (f32, f32),
    map_from_world: (f32, f32),
    /// Multiplier on every texel.
    intensity: f32,
    rows: Distribution1D,
    columns: Vec<Distribution1D>,
    /// Per texel (row-major), the probability of drawing it times the texel count: the
    /// density over map coordinates that [`Environment::sample`] and [`Environment::pdf`]
    /// divide by 2π²·sin θ. Tabulated once by the same expression (two divisions and two
    /// scattered reads a lookup before).
    p_uv: Vec<f32>,
    /// Whether every row holds one value (the built-in studio, a uniform environment): the
    /// radiance and the density then depend on the elevation alone, so lookups skip the
    /// azimuth (an `atan2`) and the rotation, and sampling draws the column uniformly instead
    /// of searching its table (the same density, to the table's rounding).
    azimuth_uniform: bool,
    /// What it is, for `VIEW.json`.
    pub source: EnvironmentSource,
}

impl Environment {
    /// The built-in neutral studio: a grey floor of radiance 0.12 below the horizon, a sky of
    /// 0.35 at the horizon brightening to 1.55 straight up (a soft top light, cos⁴ falloff), no
    /// colour cast, smooth across the horizon over ±3°. A white diffuse surface facing up then
    /// reads about 0.6, as under the direct renderer's default rig. 256 x 128 texels.
    pub fn studio() -> Environment {
        let (floor, horizon, top) = (0.12, 0.35, 1.2);
        let source = EnvironmentSource::Studio {
            floor,
            horizon,
            top,
        };
        Environment::from_fn(256, 128, source, move |d| {
            let up = d.y.max(0.0);
            let sky = horizon + top * up.powi(4);
            let t = ((d.y + 0.05) / 0.1).clamp(0.0, 1.0);
            let blend = t * t * (3.0 - 2.0 * t);
            Vec3::splat(floor + (sky - floor) * blend)
        })
    }

    /// The same radiance from every direction.
    pub fn uniform(radiance: Vec3) -> Environment {
        Environment::from_fn(
            8,
            4,
            EnvironmentSource::Uniform {
                radiance: radiance.to_array(),
            },
            move |_| radiance,
        )
    }

    /// A panorama tabulated from a function of direction at texel centres.
    fn from_fn(
        width: usize,
        height: usize,
        source: EnvironmentSource,
        f: impl Fn(Vec3) -> Vec3,
    ) -> Environment {
        let mut texels = Vec::with_capacity(width * height);
        for j in 0..height {
            for i in 0..width {
                let u = (i as f32 + 0.5) / width as f32;
                let v = (j as f32 + 0.5) / height as f32;
                texels.push(f(direction_of(u, v)));
            }
        }
        Environment::from_texels(width, height, texels, source)
    }

    /// Reads an equirectangular `.hdr` (Radiance RGBE) or `.exr` panorama.
    pub fn load(path: &Path) -> Result<Environment, EnvironmentError> {
        let fail = |problem: String| EnvironmentError {
            path: path.to_path_buf(),
            problem,
        };
        let mut magic = [0u8; 4];
        let is_exr = std::fs::File::open(path)
            .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut magic))
            .is_ok()
            && magic == EXR_MAGIC;
        // A panic in a decoder (another crate reading the user's file) is a bug to report,
        // and an error naming the file here, not the end of the process.
        let decoded = crate::scene::catch_quietly(|| {
            if is_exr {
                read_exr(path)
            } else {
                read_with_image(path)
            }
        })
        .map_err(|panic| {
            fail(format!(
                "the decoder failed (an internal error; please report this file): {panic}"
            ))
        })?;
        let (width, height, image) = decoded.map_err(fail)?;
        if width < 2 || height < 1 {
            return Err(fail(format!("a {width}x{height} image is not a panorama")));
        }
        let texels: Vec<Vec3> = image
            .into_iter()
            .map(|c| {
                // Negative or non-finite texels would poison the sampling tables.
                if c.is_finite() {
                    c.max(Vec3::ZERO)
                } else {
                    Vec3::ZERO
                }
            })
            .collect();
        Ok(Environment::from_texels(
            width,
            height,
            texels,
            EnvironmentSource::File {
                // Absolute, so that a VIEW.json recording it works from any folder.
                path: path.canonicalize().unwrap_or_else(|_| path.to_path_buf()),
            },
        ))
    }

    fn from_texels(
        width: usize,
        height: usize,
        texels: Vec<Vec3>,
        source: EnvironmentSource,
    ) -> Environment {
        let filtered = filtered_luminance(width, height, &texels);
        let mut columns = Vec::with_capacity(height);
        let mut row_weights = Vec::with_capacity(height);
        for j in 0..height {
            let sin_theta = (PI * (j as f32 + 0.5) / height as f32).sin();
            let weights: Vec<f32> = filtered[j * width..(j + 1) * width]
                .iter()
                .map(|&l| l * sin_theta)
                .collect();
            let row = Distribution1D::new(weights);
            row_weights.push(row.total());
            columns.push(row);
        }
        let rows = Distribution1D::new(row_weights);
        let mut p_uv = Vec::with_capacity(width * height);
        for (j, row) in columns.iter().enumerate() {
            for i in 0..width {
                p_uv.push(rows.probability(j) * row.probability(i) * (width * height) as f32);
            }
        }
        let azimuth_uniform = texels
            .chunks(width.max(1))
            .all(|row| row.iter().all(|t| *t == row[0]));
        Environment {
            width,
            height,
            texels,
            azimuth_uniform,
            rotation: 0.0,
            world_from_map: 0.0f32.sin_cos(),
            map_from_world: (-0.0f32).sin_cos(),
            intensity: 1.0,
            rows,
            columns,
            p_uv,
            source,
        }
    }

    /// Turns the panorama by `degrees` about +Y and scales its radiance by `intensity`.
    pub fn with_transform(mut self, degrees: f32, intensity: f32) -> Environment {
        self.rotation = degrees.to_radians();
        self.world_from_map = self.rotation.sin_cos();
        self.map_from_world = (-self.rotation).sin_cos();
        self.intensity = intensity;
        self
    }

    /// Rotation about +Y in degrees.
    pub fn rotation_degrees(&self) -> f32 {
        self.rotation.to_degrees()
    }

    /// Radiance multiplier.
    pub fn intensity(&self) -> f32 {
        self.intensity
    }

    /// Panorama size in texels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// World direction -> the panorama's own frame (undo the rotation).
    fn to_map(&self, d: Vec3) -> Vec3 {
        let (s, c) = self.map_from_world;
        Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
    }

    /// The panorama's frame -> world.
    fn to_world(&self, d: Vec3) -> Vec3 {
        let (s, c) = self.world_from_map;
        Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
    }

    /// Map coordinates of world direction `direction` for the lookups: [`uv_of`] in the
    /// panorama's frame, or where every row is one value, the first column's centre (whose
    /// bilinear weight is then exactly 1) and the direction's elevation.
    #[inline]
    fn lookup_uv(&self, direction: Vec3) -> (f32, f32) {
        if self.azimuth_uniform {
            (self.first_column(), elevation_v(direction.y))
        } else {
            uv_of(self.to_map(direction))
        }
    }

    /// u of the first column's centre.
    #[inline]
    fn first_column(&self) -> f32 {
        0.5 / self.width as f32
    }

    fn texel(&self, u: f32, v: f32) -> (usize, usize) {
        let i = ((u * self.width as f32) as usize).min(self.width - 1);
        let j = ((v * self.height as f32) as usize).min(self.height - 1);
        (i, j)
    }

    /// Radiance arriving from world direction `direction` (unit length), bilinearly filtered.
    pub fn radiance(&self, direction: Vec3) -> Vec3 {
        let (u, v) = self.lookup_uv(direction);
        self.filtered(u, v) * self.intensity
    }

    /// [`Environment::radiance`] and [`Environment::pdf`] of one direction, which map it to
    /// the panorama once (a BSDF-sampled ray that escapes needs both).
    pub fn radiance_and_pdf(&self, direction: Vec3) -> (Vec3, f32) {
        let (u, v) = self.lookup_uv(direction);
        (self.filtered(u, v) * self.intensity, self.pdf_at(u, v))
    }

    /// The panorama at map coordinates (u, v), interpolated bilinearly between the centres of
    /// the four nearest texels: wrapping around in u, clamped to the first and last row in v.
    fn filtered(&self, u: f32, v: f32) -> Vec3 {
        let x = u * self.width as f32 - 0.5;
        let y = v * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (width, height) = (self.width as i64, self.height as i64);
        let i0 = (x0 as i64).rem_euclid(width) as usize;
        let i1 = (i0 + 1) % self.width;
        let j0 = (y0 as i64).clamp(0, height - 1) as usize;
        let j1 = (y0 as i64 + 1).clamp(0, height - 1) as usize;
        let texel = |i: usize, j: usize| self.texels[j * self.width + i];
        let top = texel(i0, j0) * (1.0 - fx) + texel(i1, j0) * fx;
        let bottom = texel(i0, j1) * (1.0 - fx) + texel(i1, j1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// A direction toward the environment drawn in proportion to luminance × solid angle:
    /// (unit direction, radiance, pdf per steradian). `None` for a black environment.
    pub fn sample(&self, u1: f32, u2: f32) -> Option<(Vec3, Vec3, f32)> {
        let (direction, pdf, at) = self.sample_direction(u1, u2)?;
        Some((direction, self.radiance_at(at), pdf))
    }

    /// [`Environment::sample`] without the radiance: (unit direction, pdf per steradian, the
    /// map coordinates for [`Environment::radiance_at`]). The path tracer looks the radiance
    /// up only for samples that reach the surface unblocked (inside a Cornell box most do
    /// not).
    #[inline]
    pub fn sample_direction(&self, u1: f32, u2: f32) -> Option<(Vec3, f32, MapPoint)> {
        if self.rows.total() <= 0.0 {
            return None;
        }
        let (j, within_row) = self.rows.sample(u1)?;
        let (i, within_column) = if self.azimuth_uniform {
            // Every column of the row is as likely: no search.
            let x = u2 * self.width as f32;
            let i = (x as usize).min(self.width - 1);
            (i, (x - i as f32).clamp(0.0, 1.0 - f32::EPSILON))
        } else {
            self.columns[j].sample(u2)?
        };
        let u = (i as f32 + within_column) / self.width as f32;
        let v = (j as f32 + within_row) / self.height as f32;
        // direction_of(u, v), keeping sin θ for the pdf.
        let (sin_theta, cos_theta) = sin_cos_turns(0.5 * v);
        let (sin_phi, cos_phi) = sin_cos_turns(u - 0.5);
        let local = Vec3::new(sin_theta * cos_phi, cos_theta, sin_theta * sin_phi);
        if sin_theta <= 0.0 {
            return None;
        }
        let p_uv = self.p_uv[j * self.width + i];
        let pdf = p_uv / (2.0 * PI * PI * sin_theta);
        // Where the rows are uniform, the radiance is looked up where `lookup_uv` would.
        let at = MapPoint {
            u: if self.azimuth_uniform {
                self.first_column()
            } else {
                u
            },
            v,
        };
        (pdf > 0.0 && pdf.is_finite()).then(|| (self.to_world(local), pdf, at))
    }

    /// The radiance at a point of the panorama [`Environment::sample_direction`] drew: the
    /// same as [`Environment::radiance`] of its direction, without mapping it back.
    #[inline]
    pub fn radiance_at(&self, at: MapPoint) -> Vec3 {
        self.filtered(at.u, at.v) * self.intensity
    }

    /// The pdf per steradian with which [`Environment::sample`] draws `direction`.
    pub fn pdf(&self, direction: Vec3) -> f32 {
        let (u, v) = self.lookup_uv(direction);
        self.pdf_at(u, v)
    }

    /// The pdf per steradian of [`Environment::pdf`] at map coordinates (u, v).
    fn pdf_at(&self, u: f32, v: f32) -> f32 {
        if self.rows.total() <= 0.0 {
            return 0.0;
        }
        let sin_theta = (PI * v).sin();
        if sin_theta <= 0.0 {
            return 0.0;
        }
        let (i, j) = self.texel(u, v);
        self.p_uv[j * self.width + i] / (2.0 * PI * PI * sin_theta)
    }

    /// The panorama as used (rotation baked in, intensity applied) as a Radiance `.hdr`, so any
    /// other renderer can be lit the same way.
    pub fn to_rgb32f(&self) -> image::Rgb32FImage {
        image::Rgb32FImage::from_fn(self.width as u32, self.height as u32, |i, j| {
            let u = (i as f32 + 0.5) / self.width as f32;
            let v = (j as f32 + 0.5) / self.height as f32;
            // The texel itself where the panorama is not turned (the file back, bit for bit).
            let (u, v) = uv_of(self.to_map(direction_of(u, v)));
            let (i, j) = self.texel(u, v);
            image::Rgb((self.texels[j * self.width + i] * self.intensity).to_array())
        })
    }
}

/// Each texel's average of the bilinearly filtered luminance over its own area: the luminance
/// of its 3 x 3 neighbourhood weighted (1/8, 3/4, 1/8) along each axis (the integral of the
/// tent between texel centres over one texel), wrapping around in u, clamped in v.
fn filtered_luminance(width: usize, height: usize, texels: &[Vec3]) -> Vec<f32> {
    const SIDE: f32 = 0.125;
    const MIDDLE: f32 = 0.75;
    let lum: Vec<f32> = texels.iter().map(|&c| luminance(c)).collect();
    let mut across = vec![0.0f32; lum.len()];
    for j in 0..height {
        let row = &lum[j * width..(j + 1) * width];
        for i in 0..width {
            let left = row[(i + width - 1) % width];
            let right = row[(i + 1) % width];
            across[j * width + i] = SIDE * left + MIDDLE * row[i] + SIDE * right;
        }
    }
    let mut out = vec![0.0f32; lum.len()];
    for j in 0..height {
        let up = j.saturating_sub(1);
        let down = (j + 1).min(height - 1);
        for i in 0..width {
            out[j * width + i] = SIDE * across[up * width + i]
                + MIDDLE * across[j * width + i]
                + SIDE * across[down * width + i];
        }
    }
    out
}

/// Map coordinates of a unit direction in the panorama's frame (module docs).
fn uv_of(d: Vec3) -> (f32, f32) {
    let u = 0.5 + d.z.atan2(d.x) / TAU;
    (u.rem_euclid(1.0), elevation_v(d.y))
}

/// v of a direction whose y (up) component is `y`: its polar angle over π (a turn about +Y
/// leaves it alone).
#[inline]
fn elevation_v(y: f32) -> f32 {
    y.clamp(-1.0, 1.0).acos() / PI
}

/// The unit direction at map coordinates (u, v), in the panorama's frame.
fn direction_of(u: f32, v: f32) -> Vec3 {
    // φ = (u - 0.5)·2π, θ = v·π.
    let (sin_theta, cos_theta) = sin_cos_turns(0.5 * v);
    let (sin_phi, cos_phi) = sin_cos_turns(u - 0.5);
    Vec3::new(sin_theta * cos_phi, cos_theta, sin_theta * sin_phi)
}

/// The first bytes of every OpenEXR file.
const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// Largest panorama side accepted, in texels (width; the height is at most half of it).
const MAX_PANORAMA_WIDTH: usize = 16384;

/// An RGB float image's size and texels, rows from the top.
fn sized_texels(image: &image::Rgb32FImage) -> (usize, usize, Vec<Vec3>) {
    let (width, height) = (image.width() as usize, image.height() as usize);
    (
        width,
        height,
        image.pixels().map(|p| Vec3::from(p.0)).collect(),
    )
}

/// A panorama's size and linear RGB texels (rows from the top), read by the `image` crate
/// (Radiance `.hdr`, and any other format it knows), within the panorama size limits. An
/// image of integers (an 8- or 16-bit PNG, a JPEG, a WebP) holds sRGB-encoded colours, as
/// every such panorama is authored (Blender and pbrt read them so too), and is decoded to
/// linear radiance; float images (`.hdr`) are linear already.
fn read_with_image(path: &Path) -> Result<(usize, usize, Vec<Vec3>), String> {
    let mut reader = image::ImageReader::open(path)
        .map_err(|e| e.to_string())?
        .with_guessed_format()
        .map_err(|e| e.to_string())?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_PANORAMA_WIDTH as u32);
    limits.max_image_height = Some(MAX_PANORAMA_WIDTH as u32 / 2);
    limits.max_alloc = Some(MAX_ENVIRONMENT_TEXELS * 16);
    reader.limits(limits);
    let image = reader.decode().map_err(|e| {
        format!(
            "cannot decode the panorama: {}",
            crate::scene::image_error_text(&e)
        )
    })?;
    let linear = matches!(
        image.color(),
        image::ColorType::Rgb32F | image::ColorType::Rgba32F
    );
    let (width, height, mut texels) = sized_texels(&image.into_rgb32f());
    if !linear {
        for texel in &mut texels {
            *texel = Vec3::from(texel.to_array().map(crate::color::srgb_to_linear));
        }
    }
    Ok((width, height, texels))
}

/// An OpenEXR panorama's size and R, G, B texels over its display window (black where the data
/// window does not cover it), decoded on this thread ([`crate::scene::decode_exr`]: a panic
/// in the `exr` crate then reaches [`crate::scene::catch_quietly`]). Compressions it cannot
/// decode are refused by name first ([`check_exr_compression`]), and sizes over the panorama
/// limits before any pixel is read.
fn read_exr(path: &Path) -> Result<(usize, usize, Vec<Vec3>), String> {
    check_exr_compression(path)?;
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let image = crate::scene::decode_exr(file, MAX_ENVIRONMENT_TEXELS as usize)
        .map_err(|e| format!("cannot decode the panorama: {e}"))?
        .into_rgb32f();
    Ok(sized_texels(&image))
}

/// What an OpenEXR panorama's header must allow before its pixels are read: a compression
/// the `exr` crate decodes (it cannot decode OpenEXR 3.4's HTJ2K, refused by name with what to
/// do; DWAA and DWAB, Blender's default and how Blender ships its own studio panoramas, it
/// decodes to the values of their ZIP conversions, as a test checks), and display and data
/// windows within the panorama size limits.
fn check_exr_compression(path: &Path) -> Result<(), String> {
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .map_err(|e| format!("not a readable OpenEXR file: {e}"))?;
    for header in meta.headers.iter() {
        let name = format!("{:?}", header.compression);
        if name.starts_with("HTJ2K") {
            return Err(format!(
                "OpenEXR {name} compression cannot be decoded by the EXR reader meshtracer \
                 uses; convert the panorama to ZIP, PIZ or DWAB compression (e.g. `oiiotool \
                 IN.exr --compression zip -o OUT.exr`) or to .hdr"
            ));
        }
        for (what, size) in [
            (
                "display window",
                header.shared_attributes.display_window.size,
            ),
            ("data window", header.layer_size),
        ] {
            let (w, h) = (size.width(), size.height());
            if w > MAX_PANORAMA_WIDTH || h > MAX_PANORAMA_WIDTH / 2 {
                return Err(format!(
                    "its {what} is {w}x{h} texels: a panorama may be at most {MAX_PANORAMA_WIDTH}x{}",
                    MAX_PANORAMA_WIDTH / 2
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    #[test]
    fn directions_and_map_coordinates_round_trip() {
        for d in [
            Vec3::X,
            Vec3::Z,
            Vec3::NEG_X,
            Vec3::new(0.3, 0.5, -0.81).normalize(),
        ] {
            let (u, v) = uv_of(d);
            assert!((direction_of(u, v) - d).length() < 1e-5, "{d}");
        }
        // The centre column looks along +X; the top row is +Y.
        assert!((direction_of(0.5, 0.5) - Vec3::X).length() < 1e-6);
        assert!((direction_of(0.3, 0.0) - Vec3::Y).length() < 1e-6);
    }

    /// Importance sampling agrees with uniform sphere sampling on the irradiance of a
    /// panorama with a small, very bright spot (the hard case): E(n) = ∫ L cos⁺ dω.
    #[test]
    fn importance_sampling_agrees_with_uniform_sampling() {
        let sun = Vec3::new(0.4, 0.8, 0.2).normalize();
        let env = Environment::from_fn(
            128,
            64,
            EnvironmentSource::Uniform { radiance: [0.0; 3] },
            |d| Vec3::splat(if d.dot(sun) > 0.995 { 500.0 } else { 0.5 }),
        )
        .with_transform(30.0, 1.0);
        let n = Vec3::new(0.0, 1.0, 0.3).normalize();
        let mut rng = Rng::new(4);
        let count = 400_000;
        let (mut uniform, mut importance) = (0.0f64, 0.0f64);
        let mut mismatched = 0usize;
        for _ in 0..count {
            let z = 1.0 - 2.0 * rng.next_f32();
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = TAU * rng.next_f32();
            let d = Vec3::new(r * phi.cos(), z, r * phi.sin());
            uniform += f64::from(env.radiance(d).x * n.dot(d).max(0.0) * 4.0 * PI);
            if let Some((d, l, pdf)) = env.sample(rng.next_f32(), rng.next_f32()) {
                // The round trip direction -> texel may cross a texel edge (rounding) or lose
                // digits near the poles (acos): rare, and harmless to the estimate.
                mismatched += usize::from((env.pdf(d) - pdf).abs() > 1e-2 * pdf);
                importance += f64::from(l.x * n.dot(d).max(0.0) / pdf);
            }
        }
        assert!(
            mismatched < 400,
            "pdf() disagrees with sample() {mismatched} times"
        );
        let (uniform, importance) = (uniform / f64::from(count), importance / f64::from(count));
        assert!(
            (uniform - importance).abs() < 0.03 * importance,
            "uniform {uniform} vs importance {importance}"
        );
    }

    /// The built-in studio's rows are uniform, and its shortcuts (no azimuth, no column search)
    /// give what the general lookups give: the radiance and the pdf of any direction to 1e-5
    /// relative, turned or not; a sampled direction's pdf and radiance are `pdf()` and
    /// `radiance()` of it (to 1e-3, but for a rare round trip across a row); and importance
    /// sampling agrees with uniform sampling on the irradiance of a tilted plane.
    #[test]
    fn azimuth_uniform_panoramas_take_the_shortcuts_unchanged() {
        let studio = Environment::studio().with_transform(40.0, 1.0);
        assert!(studio.azimuth_uniform);
        let mut general = studio.clone();
        general.azimuth_uniform = false;
        let mut rng = Rng::new(9);
        let close = |a: f32, b: f32| (a - b).abs() <= 1e-5 * b.abs().max(1e-3);
        let normal = Vec3::new(0.3, 0.2, 0.9).normalize();
        let (mut uniform, mut importance) = (0.0f64, 0.0f64);
        let mut mismatched = 0u32;
        let count = 200_000u32;
        for _ in 0..count {
            let z = 1.0 - 2.0 * rng.next_f32();
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = TAU * rng.next_f32();
            let d = Vec3::new(r * phi.cos(), z, r * phi.sin());
            let (l, pdf) = studio.radiance_and_pdf(d);
            let (l_general, pdf_general) = general.radiance_and_pdf(d);
            assert!(close(l.x, l_general.x) && close(pdf, pdf_general), "{d}");
            uniform += f64::from(l.x * normal.dot(d).max(0.0) * 4.0 * PI);
            if let Some((d, l, pdf)) = studio.sample(rng.next_f32(), rng.next_f32()) {
                // As in the general case, the round trip direction -> row may lose digits
                // near the poles (acos) or cross a row's edge: rare, and harmless.
                mismatched += u32::from((studio.pdf(d) - pdf).abs() > 1e-3 * pdf);
                mismatched += u32::from((general.radiance(d).x - l.x).abs() > 1e-3 * l.x);
                importance += f64::from(l.x * normal.dot(d).max(0.0) / pdf);
            }
        }
        assert!(mismatched < count / 1000, "{mismatched} samples disagree");
        let (uniform, importance) = (uniform / f64::from(count), importance / f64::from(count));
        assert!(
            (uniform - importance).abs() < 0.01 * importance,
            "uniform {uniform} vs importance {importance}"
        );
        // A panorama with any column different takes the general path.
        let mut texels = vec![Vec3::ONE; 8 * 4];
        texels[9] = Vec3::splat(2.0);
        let env = Environment::from_texels(
            8,
            4,
            texels,
            EnvironmentSource::Uniform { radiance: [0.0; 3] },
        );
        assert!(!env.azimuth_uniform);
    }

    /// Bilinear lookups: a texel's centre gives the texel, half way between two centres their
    /// mean, and the seam at u = 0 / 1 blends the last column with the first.
    #[test]
    fn lookups_interpolate_between_texel_centres() {
        let (width, height) = (8, 4);
        let texels: Vec<Vec3> = (0..width * height)
            .map(|k| Vec3::new(k as f32, (k % width) as f32, 1.0))
            .collect();
        let env = Environment::from_texels(
            width,
            height,
            texels.clone(),
            EnvironmentSource::Uniform { radiance: [0.0; 3] },
        );
        let at = |x: f32, y: f32| env.filtered(x / width as f32, y / height as f32);
        assert!((at(2.5, 1.5) - texels[width + 2]).abs().max_element() < 1e-4);
        let mean = (texels[width + 2] + texels[width + 3]) * 0.5;
        assert!((at(3.0, 1.5) - mean).abs().max_element() < 1e-4);
        let seam = (texels[width + width - 1] + texels[width]) * 0.5;
        assert!((at(0.0, 1.5) - seam).abs().max_element() < 1e-4);
        assert!((at(8.0, 1.5) - seam).abs().max_element() < 1e-4);
    }

    /// The sampling weights follow the filtered panorama, not its texels: with one bright texel
    /// on black, the light spread into its neighbours by the filter is still sampled, so
    /// importance sampling integrates the filtered panorama (within 1% of quadrature; texel
    /// weights would give the neighbours no chance and lose the light they carry).
    #[test]
    fn importance_sampling_covers_what_the_filter_spreads() {
        let (width, height) = (64, 32);
        let mut texels = vec![Vec3::ZERO; width * height];
        texels[10 * width + 20] = Vec3::splat(1000.0);
        let env = Environment::from_texels(
            width,
            height,
            texels,
            EnvironmentSource::Uniform { radiance: [0.0; 3] },
        );
        // The integral of the filtered radiance over the sphere, by midpoint quadrature in map
        // coordinates at 16 x 16 points a texel: dω = 2π² sin(πv) du dv.
        let (nu, nv) = (width * 16, height * 16);
        let mut exact = 0.0f64;
        for b in 0..nv {
            let v = (b as f32 + 0.5) / nv as f32;
            for a in 0..nu {
                let u = (a as f32 + 0.5) / nu as f32;
                exact += f64::from(env.filtered(u, v).x * (PI * v).sin());
            }
        }
        exact *= 2.0 * std::f64::consts::PI.powi(2) / (nu * nv) as f64;
        let mut rng = Rng::new(9);
        let count = 200_000;
        let mut importance = 0.0f64;
        for _ in 0..count {
            if let Some((_, l, pdf)) = env.sample(rng.next_f32(), rng.next_f32()) {
                importance += f64::from(l.x / pdf);
            }
        }
        let importance = importance / f64::from(count);
        assert!(
            (exact - importance).abs() < 0.01 * exact,
            "quadrature {exact} vs importance sampling {importance}"
        );
    }

    /// A DWAB panorama (written by the exr crate) loads; the same file with one block's DC
    /// count raised to 2^54 (what a fuzzed file claimed, and exr allocated) is refused naming
    /// the claim, before any section is inflated.
    #[test]
    fn a_dwa_block_claiming_more_than_its_pixels_is_refused() {
        use exr::prelude::*;
        let dir = tempfile::tempdir().expect("a temporary folder");
        let path = dir.path().join("smooth.exr");
        let channels = SpecificChannels::rgb(|at: Vec2<usize>| {
            let (x, y) = (at.x() as f32, at.y() as f32);
            (
                f16::from_f32((x / 7.0).sin() + 1.2),
                f16::from_f32((y / 5.0).cos() + 1.1),
                f16::from_f32((x + y) / 40.0),
            )
        });
        let encoding = Encoding {
            compression: Compression::DWAB(None),
            blocks: Blocks::ScanLines,
            line_order: LineOrder::Increasing,
        };
        Image::from_encoded_channels((64, 32), encoding, channels)
            .write()
            .to_file(&path)
            .expect("writes");
        assert_eq!(Environment::load(&path).expect("loads").size(), (64, 32));
        // The first block's counters: find them in the file, then raise the DC count (the
        // tenth u64).
        let chunk = exr::block::read(
            std::io::BufReader::new(std::fs::File::open(&path).unwrap()),
            false,
        )
        .unwrap()
        .all_chunks(false)
        .unwrap()
        .next()
        .unwrap()
        .unwrap();
        let exr::block::chunk::CompressedBlock::ScanLine(block) = chunk.compressed_block else {
            panic!("scan lines were written");
        };
        let mut bytes = std::fs::read(&path).unwrap();
        let at = bytes
            .windows(88)
            .position(|w| w == &block.compressed_pixels_le[..88])
            .expect("the block is in the file");
        bytes[at + 72..at + 80].copy_from_slice(&(1u64 << 54).to_le_bytes());
        std::fs::write(&path, bytes).unwrap();
        let Err(refused) = Environment::load(&path) else {
            panic!("a block claiming 2^54 coefficients loaded");
        };
        let refused = refused.to_string();
        assert!(
            refused.contains("claims a section of 18014398509481984"),
            "{refused}"
        );
    }

    /// An 8-bit panorama (PNG, JPEG) is sRGB-encoded and lights the scene with its linear
    /// values; a Radiance .hdr is linear already and keeps its values.
    #[test]
    fn eight_bit_panoramas_are_decoded_from_srgb() {
        let dir = tempfile::tempdir().expect("a temporary folder");
        let png = dir.path().join("sky.png");
        image::RgbImage::from_pixel(8, 4, image::Rgb([128, 64, 255]))
            .save(&png)
            .expect("writes the PNG");
        let texel = Environment::load(&png).expect("loads").to_rgb32f()[(3, 2)].0;
        let expected = [128.0f32, 64.0, 255.0].map(|c| crate::color::srgb_to_linear(c / 255.0));
        for (got, want) in texel.iter().zip(expected) {
            assert!((got - want).abs() < 1e-5, "{texel:?} against {expected:?}");
        }
        let hdr = dir.path().join("sky.hdr");
        image::Rgb32FImage::from_pixel(8, 4, image::Rgb([0.5, 0.25, 2.0]))
            .save(&hdr)
            .expect("writes the .hdr");
        let texel = Environment::load(&hdr).expect("loads").to_rgb32f()[(3, 2)].0;
        assert_eq!(texel, [0.5, 0.25, 2.0]);
    }

    /// Blender's studio panoramas as it ships them (DWAB-compressed EXR) decode to the values
    /// of their lossless ZIP conversions, texel for texel (the `exr` crate's DWA decoder gives
    /// a few texels of -0.003 to 0 where OpenEXR's gave 0; the loader takes negatives as 0),
    /// the single-threaded EXR reader gives what the image crate's gives, and the Radiance
    /// .hdr conversions decode at the same size.
    #[test]
    fn dwab_panoramas_decode_as_their_zip_conversions() {
        let Some(dir) = std::env::var_os("MESHTRACER_ENVIRONMENTS").map(PathBuf::from) else {
            println!("SKIPPED: MESHTRACER_ENVIRONMENTS is not set (the shared panoramas)");
            return;
        };
        for name in ["studio", "courtyard", "forest", "city", "interior", "night"] {
            let load = |file: String| {
                Environment::load(&dir.join(&file)).unwrap_or_else(|e| panic!("{file}: {e}"))
            };
            // The single-threaded reader gives what the image crate's reader gave.
            for file in [format!("{name}.exr"), format!("{name}.zip.exr")] {
                let ours = read_exr(&dir.join(&file)).expect("decodes");
                let image_crate = read_with_image(&dir.join(&file)).expect("decodes");
                assert!(ours == image_crate, "{file}: the two readers differ");
            }
            let dwab = load(format!("{name}.exr"));
            let zip = load(format!("{name}.zip.exr"));
            assert_eq!(dwab.size(), (1024, 512));
            assert!(
                dwab.to_rgb32f().as_raw() == zip.to_rgb32f().as_raw(),
                "{name}.exr and {name}.zip.exr differ"
            );
            assert_eq!(load(format!("{name}.hdr")).size(), (1024, 512));
        }
    }
}
