//! The prepare phase: a loaded [`Scene`] plus what rendering it needs (tangents, the decoded
//! textures, the acceleration structure and the area lights), built once and shared read-only
//! by every render of it. [`Prepared::build`] is the one build sequence: the CLI's commands,
//! the benchmarks, the denoiser and library users all go through it, so the same scene and
//! settings give the same image whoever renders it.

pub mod lights;
pub(crate) mod queries;
mod texture_inputs;
pub mod textures;

use crate::accel::{Accel, AccelKind, BvhPreset};
use crate::light::AreaLights;
use crate::prepare::textures::{TextureError, TextureSet};
use crate::scene::{AlphaMode, Scene};
use std::time::Instant;

/// A scene ready to render.
pub struct Prepared {
    /// The triangle soup, materials, cameras and lights.
    pub scene: Scene,
    /// Ray queries over `scene.soup`.
    pub accel: Accel,
    /// Decoded images of `scene.textures`.
    pub textures: TextureSet,
    /// The emissive triangles, for next-event estimation.
    pub area_lights: AreaLights,
    /// Whether any material is not OPAQUE (else the alpha machinery is skipped).
    any_alpha: bool,
}

/// How to prepare a scene.
#[derive(Clone, Copy, Debug)]
pub struct PrepareOptions {
    /// BVH or linear scan.
    pub accel: AccelKind,
    /// obvhs build preset.
    pub bvh_preset: BvhPreset,
    /// Budget for decoded textures, in bytes: larger images are halved (with a warning).
    pub max_texture_bytes: usize,
    /// Refuse an image that cannot be decoded instead of drawing without it (`--strict`).
    pub strict: bool,
}

impl Default for PrepareOptions {
    fn default() -> Self {
        Self {
            accel: AccelKind::Bvh,
            bvh_preset: BvhPreset::Medium,
            max_texture_bytes: crate::defaults::MAX_TEXTURE_MIB << 20,
            strict: false,
        }
    }
}

/// A step of [`Prepared::build`], in the order they run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PrepareStep {
    /// MikkTSpace tangents for the normal-mapped primitives that lack them.
    Tangents,
    /// The textures decoded, within the memory budget.
    Textures,
    /// The acceleration structure built (`accel.build_steps()` has its parts).
    Bvh,
    /// The emissive triangles gathered as area lights.
    AreaLights,
}

impl Prepared {
    /// [`Prepared::build`] without step reports.
    pub fn new(
        scene: Scene,
        options: &PrepareOptions,
        warnings: &mut Vec<String>,
    ) -> Result<Prepared, TextureError> {
        Prepared::build(scene, options, warnings, &mut |_, _| {})
    }

    /// The one build sequence (on the current rayon pool): MikkTSpace tangents where a normal
    /// map needs them and the file has none, the textures, the acceleration structure, the area
    /// lights. Texture warnings (images halved to fit the budget, images drawn without) are
    /// appended to `warnings`. `on_step` is told each step as it ends, with the instant it
    /// started (`render --stats` times them).
    pub fn build(
        scene: Scene,
        options: &PrepareOptions,
        warnings: &mut Vec<String>,
        on_step: &mut dyn FnMut(PrepareStep, Instant),
    ) -> Result<Prepared, TextureError> {
        Prepared::build_reusing(scene, options, warnings, on_step, None)
    }

    /// [`Prepared::build`], keeping `textures` (an earlier build's, of the same model in
    /// another pose) where [`TextureSet::load_reusing`] finds them decoded from the same
    /// inputs.
    pub fn build_reusing(
        mut scene: Scene,
        options: &PrepareOptions,
        warnings: &mut Vec<String>,
        on_step: &mut dyn FnMut(PrepareStep, Instant),
        textures: Option<TextureSet>,
    ) -> Result<Prepared, TextureError> {
        let start = Instant::now();
        crate::scene::tangents::generate_missing(&mut scene);
        warnings.extend(crate::scene::tangents::anisotropy_without_tangents(&scene));
        on_step(PrepareStep::Tangents, start);
        let start = Instant::now();
        let textures = TextureSet::load_reusing(
            &scene,
            options.max_texture_bytes,
            options.strict,
            warnings,
            textures,
        )?;
        on_step(PrepareStep::Textures, start);
        let start = Instant::now();
        let accel = Accel::build(
            &scene.soup,
            &scene.materials,
            options.accel,
            options.bvh_preset,
        );
        on_step(PrepareStep::Bvh, start);
        let start = Instant::now();
        let prepared = Prepared::from_parts(scene, accel, textures);
        on_step(PrepareStep::AreaLights, start);
        Ok(prepared)
    }

    /// Assembles a prepared scene from parts built separately (the CLI times each phase).
    pub fn from_parts(scene: Scene, accel: Accel, textures: TextureSet) -> Prepared {
        let any_alpha = scene
            .materials
            .iter()
            .any(|m| m.alpha_mode != AlphaMode::Opaque || m.see_through());
        let mut prepared = Prepared {
            scene,
            accel,
            textures,
            area_lights: AreaLights::default(),
            any_alpha,
        };
        // The emission averaged over each emissive triangle's corners and centroid.
        let points = [
            glam::Vec3::X,
            glam::Vec3::Y,
            glam::Vec3::Z,
            glam::Vec3::splat(1.0 / 3.0),
        ];
        let area_lights = AreaLights::new(&prepared.scene, |tri| {
            points
                .iter()
                .map(|&b| crate::color::luminance(prepared.emission_at(tri, b)))
                .sum::<f32>()
                / points.len() as f32
        });
        prepared.area_lights = area_lights;
        prepared
    }

    /// Whether any material is MASK or BLEND.
    pub fn any_alpha(&self) -> bool {
        self.any_alpha
    }
}
