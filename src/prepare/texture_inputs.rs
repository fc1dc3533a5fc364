//! What a scene's decoded textures depend on, so that a later load of the same model (the next
//! frame of `render --frames`, which loads the model again in its next pose) can keep the
//! images already decoded: the same files, unchanged on disk, the same images named the same
//! way, the same images drawn and the same budget give the same [`TextureSet`], bit for bit.
//!
//! [`TextureSet`]: super::textures::TextureSet

use crate::scene::{FileStamp, Scene};
use std::path::PathBuf;

/// An image as the model names it: where it comes from, not the bytes (those are covered by
/// the files' stamps: an external image's file is one of the model's inputs, and embedded
/// bytes are part of the model's file or of a buffer's).
#[derive(Clone, Debug, PartialEq)]
struct ImageName {
    origin: String,
    mime_type: Option<String>,
    /// For an image left in the model's file: its byte range.
    range: Option<std::ops::Range<u64>>,
    /// Embedded bytes (a buffer view or `data:` URI): their length.
    embedded: Option<usize>,
}

/// Everything [`TextureSet::load`] reads to decide what it decodes and how.
///
/// [`TextureSet::load`]: super::textures::TextureSet::load
#[derive(Clone, Debug, PartialEq)]
pub(super) struct TextureInputs {
    /// The model's file and every file it refers to (buffers, images, material libraries).
    files: Vec<FileStamp>,
    images: Vec<ImageName>,
    used: Vec<bool>,
    budget: usize,
    strict: bool,
}

impl TextureInputs {
    /// The inputs of decoding `scene`'s `used` images within `budget` bytes; `None` when they
    /// cannot be told apart from another scene's: an image handed over as pixels (not a file),
    /// or a file missing or unreadable now.
    pub(super) fn of(
        scene: &Scene,
        used: &[bool],
        budget: usize,
        strict: bool,
    ) -> Option<TextureInputs> {
        let files = std::iter::once(scene.source.as_path())
            .chain(scene.inputs.iter().map(PathBuf::as_path))
            .map(|path| FileStamp::of(path).ok())
            .collect::<Option<Vec<_>>>()?;
        let images = scene
            .images
            .iter()
            .map(|source| {
                if source.pixels.is_some() {
                    return None;
                }
                Some(ImageName {
                    origin: source.origin.clone(),
                    mime_type: source.mime_type.clone(),
                    range: source.in_file.as_ref().map(|f| f.range.clone()),
                    embedded: source.bytes.as_ref().map(|b| b.len()),
                })
            })
            .collect::<Option<Vec<_>>>()?;
        Some(TextureInputs {
            files,
            images,
            used: used.to_vec(),
            budget,
            strict,
        })
    }
}
