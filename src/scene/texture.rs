//! A texture: which image, and how it is sampled.

use serde::Serialize;

/// A texture: an image plus how it is sampled.
#[derive(Clone, Debug, Serialize)]
pub struct Texture {
    /// Name from the file, if any.
    pub name: Option<String>,
    /// Index into [`Scene::images`](super::model::Scene::images).
    pub image: usize,
    /// The image to use instead when `image` cannot be decoded: the core `source` of a
    /// texture whose `EXT_texture_webp` source was chosen.
    pub fallback_image: Option<usize>,
    /// Sampler state.
    pub sampler: Sampler,
}

/// Texture wrap mode (glTF 2.0 §3.8.4.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Wrap {
    /// Tile.
    Repeat,
    /// Clamp to the edge texel.
    ClampToEdge,
    /// Tile, mirroring every other copy.
    MirroredRepeat,
}

/// Texture filter (glTF 2.0 §3.8.4.2), simplified to what a ray tracer distinguishes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Filter {
    /// Nearest texel.
    Nearest,
    /// Bilinear.
    Linear,
}

/// Sampler state of a texture.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Sampler {
    /// Magnification filter.
    pub mag_filter: Filter,
    /// Minification filter (mipmapped when the file asks for it).
    pub min_filter: Filter,
    /// Wrap along u.
    pub wrap_s: Wrap,
    /// Wrap along v.
    pub wrap_t: Wrap,
}

impl Default for Sampler {
    fn default() -> Self {
        Self {
            mag_filter: Filter::Linear,
            min_filter: Filter::Linear,
            wrap_s: Wrap::Repeat,
            wrap_t: Wrap::Repeat,
        }
    }
}
