//! The renderer: eye rays per pixel, closest hit, one shadow ray per light, glTF
//! metallic-roughness (or Blinn-Phong) shading with textures, normal maps and alpha.
//!
//! Alpha (glTF 2.0 §3.9.4): OPAQUE ignores alpha; MASK surfaces below `alphaCutoff` are absent
//! for camera and shadow rays alike (tested inside traversal); BLEND surfaces are composited
//! front to back along the eye ray (up to [`MAX_BLEND_LAYERS`]) and attenuate shadow rays by
//! (1 - alpha) each: an approximation that ignores their colour and the order of layers.
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
use crate::scene::{AlphaMode, Material, TextureRef};
use crate::scene::{Light, LightKind, Scene};
use crate::shading::{shade, ShadingModel, SurfaceMaterial};
use crate::texture::{transform_uv, TextureSet};
use glam::Vec2;
use glam::{Vec3, Vec4};
use rayon::prelude::*;
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Tile edge in pixels: small enough to balance load over cores, large enough that per-tile
/// overhead vanishes.
pub const TILE_SIZE: u32 = 32;

/// Most BLEND surfaces an eye ray composites before it stops.
pub const MAX_BLEND_LAYERS: usize = 16;

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
    /// Shading model.
    pub shading: ShadingModel,
    /// Also compute the per-pixel AOVs (depth, normal, instance id) from pixel-centre rays.
    pub aovs: bool,
}

/// Arbitrary output variables, from one ray through each pixel's centre (no anti-aliasing,
/// so ids never blend across boundaries), row-major from the top-left pixel.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Aovs {
    /// Camera-space depth: distance along the view axis (as pyrender's), 0 where nothing is hit.
    pub depth: Vec<f32>,
    /// World-space unit shading normal facing the camera (interpolated, before normal maps);
    /// zero where nothing is hit.
    pub normal: Vec<Vec3>,
    /// Mesh instance id + 1 (index into `Scene::instances`), 0 where nothing is hit.
    pub instance: Vec<u32>,
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
    textures: &TextureSet,
    settings: &RenderSettings,
    cancel: &AtomicBool,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<(Image, RenderStats, Option<Aovs>), Cancelled> {
    let start = Instant::now();
    let (width, height) = (settings.view.width, settings.view.height);
    let tiles_x = width.div_ceil(TILE_SIZE);
    let tiles_y = height.div_ceil(TILE_SIZE);
    let total = u64::from(tiles_x) * u64::from(tiles_y);
    let done = std::sync::atomic::AtomicU64::new(0);
    let tracer = Tracer::new(scene, accel, textures, settings);
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
    let pixel_count = width as usize * height as usize;
    let mut aovs = settings.aovs.then(|| Aovs {
        depth: vec![0.0; pixel_count],
        normal: vec![Vec3::ZERO; pixel_count],
        instance: vec![0; pixel_count],
    });
    let mut stats = RenderStats::default();
    for tile in results {
        let tile = tile.ok_or(Cancelled)?;
        stats.primary_rays += tile.primary_rays;
        stats.shadow_rays += tile.shadow_rays;
        for (row, chunk) in tile.pixels.chunks(tile.width as usize).enumerate() {
            let y = tile.y + row as u32;
            let begin = (y * width + tile.x) as usize;
            image.pixels[begin..begin + chunk.len()].copy_from_slice(chunk);
            if let Some(a) = aovs.as_mut() {
                let at = row * tile.width as usize;
                let n = chunk.len();
                a.depth[begin..begin + n].copy_from_slice(&tile.aovs.depth[at..at + n]);
                a.normal[begin..begin + n].copy_from_slice(&tile.aovs.normal[at..at + n]);
                a.instance[begin..begin + n].copy_from_slice(&tile.aovs.instance[at..at + n]);
            }
        }
    }
    stats.time = start.elapsed();
    Ok((image, stats, aovs))
}

/// One finished tile.
struct Tile {
    x: u32,
    y: u32,
    width: u32,
    pixels: Vec<Vec4>,
    aovs: Aovs,
    primary_rays: u64,
    shadow_rays: u64,
}

/// Per-render constants shared by all tiles.
struct Tracer<'a> {
    scene: &'a Scene,
    accel: &'a Accel,
    textures: &'a TextureSet,
    settings: &'a RenderSettings,
    /// How far shadow rays start off the surface, along the geometric normal, to escape the
    /// surface they leave despite rounding in the hit point: 1e-5 of the scene's extent
    /// (coordinates carry ~1e-7 relative error in f32, so this is a 100x margin).
    ray_offset: f32,
    /// 2^exposure.
    scale: f32,
    /// Strata per axis for jittered sampling.
    strata: (u32, u32),
    /// Ray-cone footprint of a pixel: width at distance t is `spread.0 + spread.1 · t`
    /// (perspective: angle per pixel; orthographic: pixel size).
    spread: (f32, f32),
    /// Whether any material is not OPAQUE (else the alpha machinery is skipped).
    any_alpha: bool,
}

/// Everything shading needs about a hit point.
struct Surface<'m> {
    point: Vec3,
    /// From `point` onto the curved surface a smooth-shaded triangle's vertex normals describe
    /// (see [`terminator_lift`]); zero for flat triangles.
    lift: Vec3,
    /// Geometric normal facing the incoming ray.
    geometric: Vec3,
    /// Interpolated vertex normal on the geometric normal's side: the smooth surface the
    /// mesh approximates.
    smooth: Vec3,
    /// Shading normal (interpolated, normal-mapped) on the geometric normal's side.
    normal: Vec3,
    material: SurfaceMaterial,
    emissive: Vec3,
    occlusion: f32,
    alpha: f32,
    source: &'m Material,
}

impl<'a> Tracer<'a> {
    fn new(
        scene: &'a Scene,
        accel: &'a Accel,
        textures: &'a TextureSet,
        settings: &'a RenderSettings,
    ) -> Self {
        let b = &scene.bounds;
        let extent = b.min.abs().max(b.max.abs()).max_element() + b.radius();
        let sx = (settings.spp as f32).sqrt().floor().max(1.0) as u32;
        let sy = settings.spp.div_ceil(sx);
        let view = &settings.view;
        let spread = match view.lens {
            crate::camera::Lens::Perspective { height, .. } => (0.0, height / view.height as f32),
            crate::camera::Lens::Orthographic { height, .. } => (height / view.height as f32, 0.0),
        };
        Self {
            scene,
            accel,
            textures,
            settings,
            ray_offset: (extent * 1e-5).max(f32::MIN_POSITIVE),
            scale: settings.exposure.exp2(),
            strata: (sx, sy),
            spread,
            any_alpha: scene
                .materials
                .iter()
                .any(|m| m.alpha_mode != AlphaMode::Opaque),
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
            aovs: Aovs::default(),
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
                    let (color, coverage) = self.radiance(&ray, &mut tile);
                    sum += (color * self.scale).extend(coverage);
                }
                tile.pixels.push(sum / spp as f32);
                if self.settings.aovs {
                    self.aov(&view.ray(x as f32 + 0.5, y as f32 + 0.5), &mut tile.aovs);
                }
            }
        }
        tile
    }

    /// Depth, normal and instance id of the first surface along a pixel-centre ray.
    fn aov(&self, ray: &Ray, out: &mut Aovs) {
        let accept = |tri: u32, b: Vec3| self.accept_for_camera(tri, b);
        let hit = self.accel.intersect_filtered(ray, Some(&accept));
        match hit {
            Some(hit) => {
                let soup = &self.scene.soup;
                let tri = hit.triangle as usize;
                let b = hit.barycentric;
                let [na, nb, nc] = soup.normals[tri];
                let [pa, pb, pc] = soup.positions[tri];
                let direction = Vec3::from(ray.direction);
                let mut n = (na * b.x + nb * b.y + nc * b.z)
                    .try_normalize()
                    .unwrap_or((pb - pa).cross(pc - pa).normalize_or_zero());
                if n.dot(direction) > 0.0 {
                    n = -n;
                }
                out.depth.push(hit.t * direction.dot(-self.settings.view.w));
                out.normal.push(n);
                out.instance
                    .push(soup.instance.get(tri).map_or(0, |i| i + 1));
            }
            None => {
                out.depth.push(0.0);
                out.normal.push(Vec3::ZERO);
                out.instance.push(0);
            }
        }
    }

    /// Alpha of a MASK or BLEND surface at a candidate hit: base colour factor × texture ×
    /// vertex colour (the texture at full resolution: this runs inside traversal).
    fn alpha_at(&self, triangle: u32, barycentric: Vec3) -> f32 {
        let soup = &self.scene.soup;
        let tri = triangle as usize;
        let Some(material) = self.scene.materials.get(soup.material[tri] as usize) else {
            return 1.0;
        };
        let mut alpha = material.base_color.w;
        if let Some([a, b, c]) = soup.colors.get(tri) {
            alpha *= a.w * barycentric.x + b.w * barycentric.y + c.w * barycentric.z;
        }
        if let Some(r) = &material.base_color_texture {
            if let Some((image, sampler)) = self.textures.lookup(self.scene, r) {
                let uv = transform_uv(r, self.uv(tri, r.tex_coord, barycentric));
                alpha *= image.sample(uv, 0.0, sampler, false).w;
            }
        }
        alpha
    }

    /// MASK surfaces exist where alpha reaches the cutoff; BLEND surfaces are always hit by
    /// eye rays (and composited).
    fn accept_for_camera(&self, triangle: u32, barycentric: Vec3) -> bool {
        let material = &self.scene.materials[self.scene.soup.material[triangle as usize] as usize];
        material.alpha_mode != AlphaMode::Mask
            || self.alpha_at(triangle, barycentric) >= material.alpha_cutoff
    }

    fn uv(&self, tri: usize, set: u32, b: Vec3) -> Vec2 {
        let uvs = if set == 1 {
            &self.scene.soup.uv1
        } else {
            &self.scene.soup.uv0
        };
        match uvs.get(tri) {
            Some([ua, ub, uc]) => *ua * b.x + *ub * b.y + *uc * b.z,
            None => Vec2::ZERO,
        }
    }

    /// Samples a texture at a hit with a mip level from the ray cone (Akenine-Möller et al.,
    /// "Texture Level of Detail Strategies for Real-Time Ray Tracing", 2019):
    /// lod = ½·log2(texels · uv area / world area) + log2(cone width / |n·d|).
    fn sample(
        &self,
        r: &TextureRef,
        tri: usize,
        b: Vec3,
        cone: f32,
        cos: f32,
        srgb: bool,
    ) -> Option<Vec4> {
        let (image, sampler) = self.textures.lookup(self.scene, r)?;
        let uvs = if r.tex_coord == 1 {
            &self.scene.soup.uv1
        } else {
            &self.scene.soup.uv0
        };
        let [pa, pb, pc] = self.scene.soup.positions[tri];
        let lod = match uvs.get(tri) {
            Some(corners) => {
                // The footprint is measured in the coordinates that address the texture, after
                // KHR_texture_transform (quantized files scale integer UVs by 1/4096 or so).
                let [ua, ub, uc] = corners.map(|uv| transform_uv(r, uv));
                let world = (pb - pa).cross(pc - pa).length();
                let uv_area = (ub - ua).perp_dot(uc - ua).abs();
                let (w, h) = image.size();
                let density = (w as f32 * h as f32 * uv_area / world.max(f32::MIN_POSITIVE)).sqrt();
                (density * cone / cos.abs().max(1e-3)).log2()
            }
            None => 0.0,
        };
        let uv = transform_uv(r, self.uv(tri, r.tex_coord, b));
        Some(image.sample(uv, lod, sampler, srgb))
    }

    fn surface(&self, ray: &Ray, hit: &crate::accel::Hit, cone: f32) -> Surface<'a> {
        let soup = &self.scene.soup;
        let tri = hit.triangle as usize;
        let b = hit.barycentric;
        let [pa, pb, pc] = soup.positions[tri];
        let point = pa * b.x + pb * b.y + pc * b.z;
        let direction = Vec3::from(ray.direction);
        let mut geometric = (pb - pa).cross(pc - pa).normalize_or_zero();
        if geometric.dot(direction) > 0.0 {
            geometric = -geometric;
        }
        let cos = geometric.dot(direction);
        let [na, nb, nc] = soup.normals[tri];
        let mut normal = (na * b.x + nb * b.y + nc * b.z)
            .try_normalize()
            .unwrap_or(geometric);
        if normal.dot(geometric) < 0.0 {
            normal = -normal;
        }
        let smooth = normal;
        let facing = |n: Vec3| if n.dot(geometric) < 0.0 { -n } else { n };
        let lift = terminator_lift(point, [pa, pb, pc], [facing(na), facing(nb), facing(nc)], b);
        static DEFAULT: std::sync::OnceLock<Material> = std::sync::OnceLock::new();
        let material = self
            .scene
            .materials
            .get(soup.material[tri] as usize)
            .unwrap_or_else(|| DEFAULT.get_or_init(Material::default));
        let mut base = material.base_color;
        if let Some([ca, cb, cc]) = soup.colors.get(tri) {
            base *= *ca * b.x + *cb * b.y + *cc * b.z;
        }
        let sample = |r: &Option<TextureRef>, srgb: bool| {
            r.as_ref()
                .and_then(|r| self.sample(r, tri, b, cone, cos, srgb))
        };
        if let Some(t) = sample(&material.base_color_texture, true) {
            base *= t;
        }
        let (mut metallic, mut roughness) = (material.metallic, material.roughness);
        if let Some(t) = sample(&material.metallic_roughness_texture, false) {
            // glTF 2.0 §3.9.2: roughness in G, metalness in B.
            roughness *= t.y;
            metallic *= t.z;
        }
        let mut emissive = material.emissive * material.emissive_strength;
        if let Some(t) = sample(&material.emissive_texture, true) {
            emissive *= t.truncate();
        }
        let occlusion = match sample(&material.occlusion_texture, false) {
            // glTF 2.0 §3.9.3: occluded = 1 + strength · (sample - 1), from the R channel.
            Some(t) => 1.0 + material.occlusion_strength * (t.x - 1.0),
            None => 1.0,
        };
        if let (Some(r), Some(t)) = (
            &material.normal_texture,
            sample(&material.normal_texture, false),
        ) {
            normal = self.normal_mapped(tri, b, r, normal, geometric, t, material.normal_scale);
        }
        Surface {
            point,
            lift,
            geometric,
            smooth,
            normal,
            material: SurfaceMaterial {
                base_color: base.truncate(),
                metallic: metallic.clamp(0.0, 1.0),
                roughness: roughness.clamp(0.0, 1.0),
                specular: material.specular,
            },
            emissive,
            occlusion,
            alpha: if material.alpha_mode == AlphaMode::Opaque {
                1.0
            } else {
                base.w.clamp(0.0, 1.0)
            },
            source: material,
        }
    }

    /// Perturbs the shading normal by a tangent-space normal map (glTF 2.0 §3.9.3): n =
    /// normalize(T·x + B·y + N·z) with (x, y, z) = (2·rgb - 1)·(scale, scale, 1), B = (N × T)·w.
    /// Tangents come from the file's TANGENT, else from MikkTSpace at load
    /// ([`crate::scene::tangents`]), else (degenerate UVs) from the triangle's UV gradient.
    #[allow(clippy::too_many_arguments)]
    fn normal_mapped(
        &self,
        tri: usize,
        b: Vec3,
        r: &TextureRef,
        n: Vec3,
        geometric: Vec3,
        texel: Vec4,
        scale: f32,
    ) -> Vec3 {
        let soup = &self.scene.soup;
        let from_file = soup.tangents.get(tri).and_then(|[ta, tb, tc]| {
            let t = *ta * b.x + *tb * b.y + *tc * b.z;
            (ta.w != 0.0).then(|| (t.truncate(), if ta.w < 0.0 { -1.0 } else { 1.0 }))
        });
        let frame = from_file.or_else(|| {
            let uvs = if r.tex_coord == 1 {
                &soup.uv1
            } else {
                &soup.uv0
            };
            let [ua, ub, uc] = *uvs.get(tri)?;
            let [pa, pb, pc] = soup.positions[tri];
            let (e1, e2) = (pb - pa, pc - pa);
            let (d1, d2) = (ub - ua, uc - ua);
            let det = d1.x * d2.y - d2.x * d1.y;
            if det.abs() < 1e-20 {
                return None;
            }
            let tangent = (e1 * d2.y - e2 * d1.y) / det;
            let bitangent = (e2 * d1.x - e1 * d2.x) / det;
            // glTF UVs have v down, so the bitangent points along -v in texture terms.
            let w = if n.cross(tangent).dot(bitangent) < 0.0 {
                1.0
            } else {
                -1.0
            };
            Some((tangent, w))
        });
        let Some((tangent, w)) = frame else {
            return n;
        };
        let t = (tangent - n * n.dot(tangent)).try_normalize();
        let Some(t) = t else {
            return n;
        };
        let bt = n.cross(t) * w;
        let m = Vec3::new(
            (2.0 * texel.x - 1.0) * scale,
            (2.0 * texel.y - 1.0) * scale,
            2.0 * texel.z - 1.0,
        );
        let mapped = (t * m.x + bt * m.y + n * m.z).try_normalize().unwrap_or(n);
        if mapped.dot(geometric) <= 0.0 {
            n
        } else {
            mapped
        }
    }

    /// Radiance and coverage along an eye ray: (premultiplied colour, alpha).
    fn radiance(&self, ray: &Ray, tile: &mut Tile) -> (Vec3, f32) {
        let accept = |tri: u32, b: Vec3| self.accept_for_camera(tri, b);
        let mut color = Vec3::ZERO;
        let mut transmittance = 1.0f32;
        let mut ray = *ray;
        for _ in 0..MAX_BLEND_LAYERS {
            tile.primary_rays += 1;
            let hit = if self.any_alpha {
                self.accel.intersect_filtered(&ray, Some(&accept))
            } else {
                self.accel.intersect(&ray)
            };
            let Some(hit) = hit else {
                break;
            };
            let cone = self.spread.0 + self.spread.1 * hit.t;
            let surface = self.surface(&ray, &hit, cone);
            let shaded = self.shade(&ray, &surface, &mut tile.shadow_rays);
            let alpha = if surface.source.alpha_mode == AlphaMode::Blend {
                surface.alpha
            } else {
                1.0
            };
            color += shaded * alpha * transmittance;
            transmittance *= 1.0 - alpha;
            if transmittance < 1e-3 {
                transmittance = 0.0;
                break;
            }
            ray.tmin = hit.t;
        }
        (color, 1.0 - transmittance)
    }

    /// Direct lighting of a surface point: ambient (with occlusion), emission, and each light
    /// through a shadow ray.
    fn shade(&self, ray: &Ray, s: &Surface, shadow_rays: &mut u64) -> Vec3 {
        let to_eye = -Vec3::from(ray.direction);
        let mut color = self.settings.ambient * s.material.base_color * s.occlusion + s.emissive;
        for light in &self.settings.lights {
            let Some(incoming) = incident(light, s.point) else {
                continue;
            };
            // The light must be above the smooth surface (not the flat facet: near the
            // terminator of a smooth-shaded mesh the facet test cuts light off facet by facet,
            // a staircase) and above the shading normal. Flat triangles have smooth = facet.
            if incoming.to_light.dot(s.smooth) <= 0.0 || incoming.to_light.dot(s.normal) <= 0.0 {
                continue;
            }
            *shadow_rays += 1;
            // Shadow rays leave from the lifted point only where the light grazes or sits below
            // the facet (cosine under TERMINATOR_BAND, fading in): only there can the facet's
            // own neighbours block a ray the smooth surface would let through. Elsewhere the
            // lift would only move the origin off the real geometry and thin contact shadows
            // (it cost the Avocado's seed its shadow). The same idea as Cycles' "shadow
            // terminator geometry offset".
            let toward = incoming.to_light.dot(s.geometric);
            let amount = (1.0 - toward / TERMINATOR_BAND).clamp(0.0, 1.0);
            let origin = s.point + s.lift * amount + s.geometric * self.ray_offset;
            let tmax = if incoming.distance.is_finite() {
                incoming.distance - self.ray_offset
            } else {
                f32::INFINITY
            };
            let shadow = Ray::new(origin, incoming.to_light, 0.0, tmax);
            let transmittance = self.shadow_transmittance(&shadow);
            if transmittance <= 0.0 {
                continue;
            }
            color += transmittance
                * shade(
                    self.settings.shading,
                    &s.material,
                    s.normal,
                    incoming.to_light,
                    to_eye,
                    incoming.irradiance,
                );
        }
        color
    }

    /// 1 for an unblocked shadow ray, 0 for a blocked one, the product of (1 - alpha) over
    /// BLEND surfaces in between otherwise.
    fn shadow_transmittance(&self, shadow: &Ray) -> f32 {
        if !self.any_alpha {
            return if self.accel.occluded(shadow) {
                0.0
            } else {
                1.0
            };
        }
        let transmittance = Cell::new(1.0f32);
        let accept = |tri: u32, b: Vec3| {
            let material = &self.scene.materials[self.scene.soup.material[tri as usize] as usize];
            match material.alpha_mode {
                AlphaMode::Mask => self.alpha_at(tri, b) >= material.alpha_cutoff,
                AlphaMode::Blend => {
                    let alpha = self.alpha_at(tri, b).clamp(0.0, 1.0);
                    transmittance.set(transmittance.get() * (1.0 - alpha));
                    transmittance.get() < 1e-3
                }
                AlphaMode::Opaque => true,
            }
        };
        if self.accel.occluded_filtered(shadow, Some(&accept)) {
            0.0
        } else {
            transmittance.get()
        }
    }
}

/// Below this cosine between the light and the facet normal, shadow rays start from the
/// terminator-lifted point (fading in from here to 0).
const TERMINATOR_BAND: f32 = 0.1;

/// The shadow-terminator offset of Hanika, "Hacking the shadow terminator" (Ray Tracing Gems
/// II, ch. 4, 2021). A smooth-shaded mesh is flat between its vertices, so near the terminator
/// a shadow ray leaving the flat facet is blocked by the neighbouring facets (or the facet
/// itself) although the shading normal says the point is lit: the terminator turns into a
/// staircase along the tessellation. Project `point` onto the tangent plane of each vertex
/// (the plane through the vertex, normal to its shading normal) when it lies below it, and
/// blend the three projections with the barycentric weights: the result lies on a smooth
/// surface through the vertices, above the facets that caused the staircase. Flat triangles
/// (vertex normals equal to the face normal) are not moved. Returns the offset from `point`.
/// `normals` must face the side the ray arrived from.
fn terminator_lift(point: Vec3, vertices: [Vec3; 3], normals: [Vec3; 3], b: Vec3) -> Vec3 {
    let below = |i: usize| (point - vertices[i]).dot(normals[i]).min(0.0) * normals[i];
    -(below(0) * b.x + below(1) * b.y + below(2) * b.z)
}

#[cfg(test)]
mod tests {
    use super::terminator_lift;
    use glam::{vec3, Vec3};

    #[test]
    fn terminator_lift_leaves_flat_triangles_alone() {
        let vertices = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let b = vec3(0.2, 0.3, 0.5);
        let point = vertices[0] * b.x + vertices[1] * b.y + vertices[2] * b.z;
        assert_eq!(
            terminator_lift(point, vertices, [Vec3::Z; 3], b),
            Vec3::ZERO
        );
    }

    /// A facet of a unit sphere with vertex normals pointing out of the sphere: the lifted
    /// centroid lies outside the facet, most of the way to the sphere, and not beyond it.
    #[test]
    fn terminator_lift_moves_toward_the_smooth_surface() {
        let vertices = [
            vec3(1.0, 0.0, 0.0),
            vec3(0.0, 1.0, 0.0),
            vec3(0.0, 0.0, 1.0),
        ];
        let b = Vec3::splat(1.0 / 3.0);
        let point = (vertices[0] + vertices[1] + vertices[2]) / 3.0;
        let lifted = point + terminator_lift(point, vertices, vertices, b);
        let (before, after) = (point.length(), lifted.length());
        assert!((before - 0.577).abs() < 1e-3, "{before}");
        assert!(
            after > before + 0.5 * (1.0 - before) && after <= 1.0 + 1e-6,
            "|lifted| = {after}"
        );
    }
}
