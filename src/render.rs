//! The renderer: eye rays per pixel, closest hit, one shadow ray per light, Blinn-Phong shading.
//!
//! Work is split into square tiles rendered in parallel with rayon. Every pixel's samples come
//! from a generator keyed by (seed, x, y), so the image is the same, byte for byte, whatever the
//! number of threads or the order tiles finish in.

use crate::accel::Accel;
use crate::camera::View;
use crate::geometry::Ray;
use crate::image::Image;
use crate::light::incident;
use crate::sampling::Rng;
use crate::scene::{Light, LightKind, Scene};
use crate::shading::{blinn_phong, SurfaceMaterial};
use glam::{Vec3, Vec4};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Tile edge in pixels: small enough to balance load over cores, large enough that per-tile
/// overhead vanishes.
pub const TILE_SIZE: u32 = 32;

/// Everything the renderer needs besides the scene and the acceleration structure.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    /// The camera, sized for the image.
    pub view: View,
    /// Samples per pixel: 1 is the pixel centre; more are stratified jittered samples.
    pub spp: u32,
    /// Seed of the sample pattern.
    pub seed: u64,
    /// Lights in use (the file's, or the default rig).
    pub lights: Vec<Light>,
    /// Ambient radiance multiplier for base colour (unshadowed).
    pub ambient: Vec3,
    /// Exposure in stops: radiance is scaled by 2^exposure before output.
    pub exposure: f32,
}

/// What a render did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderStats {
    /// Camera rays traced.
    pub primary_rays: u64,
    /// Shadow rays traced.
    pub shadow_rays: u64,
    /// Wall time of the render (not the BVH build).
    pub time: Duration,
}

impl RenderStats {
    /// All rays traced.
    pub fn rays(&self) -> u64 {
        self.primary_rays + self.shadow_rays
    }

    /// Millions of rays per second over the render's wall time.
    pub fn mrays_per_second(&self) -> f64 {
        self.rays() as f64 / self.time.as_secs_f64().max(1e-9) / 1e6
    }
}

/// The render was stopped through its cancel flag.
#[derive(Debug, thiserror::Error)]
#[error("render interrupted")]
pub struct Cancelled;

/// The default light rig for scenes without lights, in the camera's frame: a key light from
/// above-left behind the camera (2.5 lux, so a white diffuse surface facing it reads about 0.8),
/// a fill from the right at a third of that, and ambient 0.08. Both are directional, so the rig
/// does not depend on the scene's scale.
pub fn default_rig(view: &View) -> (Vec<Light>, Vec3) {
    let directional = |name: &str, to_light: Vec3, lux: f32| Light {
        name: Some(name.to_string()),
        kind: LightKind::Directional,
        color: Vec3::ONE,
        intensity: lux,
        range: None,
        position: Vec3::ZERO,
        direction: -to_light.normalize(),
    };
    let key = directional("default key", view.w + 0.8 * view.v - 0.6 * view.u, 2.5);
    let fill = directional(
        "default fill",
        0.6 * view.w + 0.2 * view.v + 1.0 * view.u,
        0.8,
    );
    (vec![key, fill], Vec3::splat(0.08))
}

/// Renders `scene` through `accel`. `progress` is called with the number of finished tiles and
/// the total; setting `cancel` stops the render at the next tile.
pub fn render(
    scene: &Scene,
    accel: &Accel,
    settings: &RenderSettings,
    cancel: &AtomicBool,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<(Image, RenderStats), Cancelled> {
    let start = Instant::now();
    let (width, height) = (settings.view.width, settings.view.height);
    let tiles_x = width.div_ceil(TILE_SIZE);
    let tiles_y = height.div_ceil(TILE_SIZE);
    let total = u64::from(tiles_x) * u64::from(tiles_y);
    let done = std::sync::atomic::AtomicU64::new(0);
    let tracer = Tracer::new(scene, accel, settings);
    let tiles: Vec<(u32, u32)> = (0..tiles_y)
        .flat_map(|ty| (0..tiles_x).map(move |tx| (tx, ty)))
        .collect();
    let results: Vec<Option<Tile>> = tiles
        .par_iter()
        .map(|&(tx, ty)| {
            if cancel.load(Ordering::Relaxed) {
                return None;
            }
            let tile = tracer.tile(tx * TILE_SIZE, ty * TILE_SIZE);
            progress(done.fetch_add(1, Ordering::Relaxed) + 1, total);
            Some(tile)
        })
        .collect();
    let mut image = Image::new(width, height);
    let mut stats = RenderStats::default();
    for tile in results {
        let tile = tile.ok_or(Cancelled)?;
        stats.primary_rays += tile.primary_rays;
        stats.shadow_rays += tile.shadow_rays;
        for (row, chunk) in tile.pixels.chunks(tile.width as usize).enumerate() {
            let y = tile.y + row as u32;
            let begin = (y * width + tile.x) as usize;
            image.pixels[begin..begin + chunk.len()].copy_from_slice(chunk);
        }
    }
    stats.time = start.elapsed();
    Ok((image, stats))
}

/// One finished tile.
struct Tile {
    x: u32,
    y: u32,
    width: u32,
    pixels: Vec<Vec4>,
    primary_rays: u64,
    shadow_rays: u64,
}

/// Per-render constants shared by all tiles.
struct Tracer<'a> {
    scene: &'a Scene,
    accel: &'a Accel,
    settings: &'a RenderSettings,
    /// How far shadow rays start off the surface, along the geometric normal, to escape the
    /// surface they leave despite rounding in the hit point: 1e-5 of the scene's extent
    /// (coordinates carry ~1e-7 relative error in f32, so this is a 100x margin).
    ray_offset: f32,
    /// 2^exposure.
    scale: f32,
    /// Strata per axis for jittered sampling.
    strata: (u32, u32),
}

impl<'a> Tracer<'a> {
    fn new(scene: &'a Scene, accel: &'a Accel, settings: &'a RenderSettings) -> Self {
        let b = &scene.bounds;
        let extent = b.min.abs().max(b.max.abs()).max_element() + b.radius();
        let sx = (settings.spp as f32).sqrt().floor().max(1.0) as u32;
        let sy = settings.spp.div_ceil(sx);
        Self {
            scene,
            accel,
            settings,
            ray_offset: (extent * 1e-5).max(f32::MIN_POSITIVE),
            scale: settings.exposure.exp2(),
            strata: (sx, sy),
        }
    }

    fn tile(&self, x0: u32, y0: u32) -> Tile {
        let view = &self.settings.view;
        let x1 = (x0 + TILE_SIZE).min(view.width);
        let y1 = (y0 + TILE_SIZE).min(view.height);
        let mut tile = Tile {
            x: x0,
            y: y0,
            width: x1 - x0,
            pixels: Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize),
            primary_rays: 0,
            shadow_rays: 0,
        };
        let spp = self.settings.spp.max(1);
        for y in y0..y1 {
            for x in x0..x1 {
                let mut rng = Rng::for_pixel(self.settings.seed, x, y);
                let mut sum = Vec4::ZERO;
                for s in 0..spp {
                    let (dx, dy) = if spp == 1 {
                        (0.5, 0.5)
                    } else {
                        let (sx, sy) = self.strata;
                        let (cx, cy) = (s % sx, (s / sx) % sy);
                        (
                            (cx as f32 + rng.next_f32()) / sx as f32,
                            (cy as f32 + rng.next_f32()) / sy as f32,
                        )
                    };
                    let ray = view.ray(x as f32 + dx, y as f32 + dy);
                    tile.primary_rays += 1;
                    if let Some(color) = self.radiance(&ray, &mut tile.shadow_rays) {
                        sum += (color * self.scale).extend(1.0);
                    }
                }
                tile.pixels.push(sum / spp as f32);
            }
        }
        tile
    }

    /// Radiance along an eye ray, or `None` when it hits nothing.
    fn radiance(&self, ray: &Ray, shadow_rays: &mut u64) -> Option<Vec3> {
        let hit = self.accel.intersect(ray)?;
        let soup = &self.scene.soup;
        let tri = hit.triangle as usize;
        let b = hit.barycentric;
        let [pa, pb, pc] = soup.positions[tri];
        let point = pa * b.x + pb * b.y + pc * b.z;
        let direction = Vec3::from(ray.direction);
        let to_eye = -direction;
        // Geometric normal, turned to face the incoming ray.
        let mut geometric = (pb - pa).cross(pc - pa).normalize_or_zero();
        if geometric.dot(direction) > 0.0 {
            geometric = -geometric;
        }
        // Shading normal on the same side as the geometric one: handles back faces of
        // double-sided surfaces and files whose normals disagree with their winding.
        let [na, nb, nc] = soup.normals[tri];
        let mut normal = (na * b.x + nb * b.y + nc * b.z)
            .try_normalize()
            .unwrap_or(geometric);
        if normal.dot(geometric) < 0.0 {
            normal = -normal;
        }
        let material = self
            .scene
            .materials
            .get(soup.material[tri] as usize)
            .cloned()
            .unwrap_or_default();
        let mut base = material.base_color;
        if let Some([ca, cb, cc]) = soup.colors.get(tri) {
            base *= *ca * b.x + *cb * b.y + *cc * b.z;
        }
        let surface = SurfaceMaterial {
            base_color: base.truncate(),
            metallic: material.metallic.clamp(0.0, 1.0),
            roughness: material.roughness.clamp(0.0, 1.0),
            specular: material.specular,
        };
        let mut color = self.settings.ambient * surface.base_color
            + material.emissive * material.emissive_strength;
        let origin = point + geometric * self.ray_offset;
        for light in &self.settings.lights {
            let Some(incoming) = incident(light, point) else {
                continue;
            };
            if incoming.to_light.dot(geometric) <= 0.0 || incoming.to_light.dot(normal) <= 0.0 {
                continue;
            }
            *shadow_rays += 1;
            let tmax = if incoming.distance.is_finite() {
                incoming.distance - self.ray_offset
            } else {
                f32::INFINITY
            };
            let shadow = Ray::new(origin, incoming.to_light, 0.0, tmax);
            if self.accel.occluded(&shadow) {
                continue;
            }
            color += blinn_phong(
                &surface,
                normal,
                incoming.to_light,
                to_eye,
                incoming.irradiance,
            );
        }
        Some(color)
    }
}
