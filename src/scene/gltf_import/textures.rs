//! glTF textures (§3.8): the image each one uses (`EXT_texture_webp`, `KHR_texture_basisu`
//! and `MSFT_texture_dds` sources, with their fallbacks), its sampler, and every image's source with its header
//! checked.

use super::buffer::Buffer;
use super::container::{decode_data_uri, LoadedFile};
use crate::scene::error::{LoadError, LoadErrorKind};
use crate::scene::image_header::check_image_header;
use crate::scene::image_source::{FileRange, ImageSource, SharedBytes};
use crate::scene::material::UnusableImage;
use crate::scene::options::LoadOptions;
use crate::scene::paths::FileAccess;
use crate::scene::texture::{Filter, Sampler, Texture, Wrap};

/// EXT_texture_webp, KHR_texture_basisu and MSFT_texture_dds: a texture whose extension names
/// a WebP, KTX2 or DDS image uses it, and keeps its core `source` (if any) as the fallback for when that image
/// cannot be decoded (the extensions' fallback rule). Rewritten in the JSON before the `gltf`
/// crate validates it, since gltf-json 1.4 requires `source` (WebP-only and KTX2-only files
/// have none). Returns each texture's fallback.
pub(super) fn choose_texture_sources(root: &mut gltf::json::Root) -> Vec<Option<usize>> {
    let image_count = root.images.len();
    root.textures
        .iter_mut()
        .map(|texture| {
            let source_of = |name: &str| {
                texture
                    .extensions
                    .as_ref()
                    .and_then(|e| e.others.get(name))
                    .and_then(|w| w.get("source"))
                    .and_then(serde_json::Value::as_u64)
                    .and_then(|i| usize::try_from(i).ok())
                    .filter(|&i| i < image_count)
            };
            let core = texture.source.value();
            let chosen = source_of("EXT_texture_webp")
                .or_else(|| source_of("KHR_texture_basisu"))
                .or_else(|| source_of("MSFT_texture_dds"))?;
            texture.source = gltf::json::Index::new(chosen as u32);
            (core < image_count && core != chosen).then_some(core)
        })
        .collect()
}

pub(super) fn textures(
    document: &gltf::Document,
    webp_fallbacks: &[Option<usize>],
) -> Vec<Texture> {
    use gltf::texture::{MagFilter, MinFilter, WrappingMode};
    let wrap = |w: WrappingMode| match w {
        WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        WrappingMode::Repeat => Wrap::Repeat,
    };
    document
        .textures()
        .map(|t| {
            let s = t.sampler();
            Texture {
                name: t.name().map(str::to_string),
                image: t.source().index(),
                fallback_image: webp_fallbacks.get(t.index()).copied().flatten(),
                sampler: Sampler {
                    mag_filter: match s.mag_filter() {
                        Some(MagFilter::Nearest) => Filter::Nearest,
                        _ => Filter::Linear,
                    },
                    min_filter: match s.min_filter() {
                        Some(MinFilter::Nearest | MinFilter::NearestMipmapNearest) => {
                            Filter::Nearest
                        }
                        _ => Filter::Linear,
                    },
                    wrap_s: wrap(s.wrap_s()),
                    wrap_t: wrap(s.wrap_t()),
                },
            }
        })
        .collect()
}

/// Every image's source, its header checked. An image that fails the check (absent, not an
/// image, too large) switches the textures that have a fallback image (EXT_texture_webp) to it,
/// with a warning; any other texture using it is reported in the returned list, for
/// [`draw_without`](crate::scene::material::draw_without). A malformed `data:` URI or a URI
/// leaving the folder stays an error.
pub(super) fn images(
    document: &gltf::Document,
    buffers: &[Buffer],
    file: Option<LoadedFile>,
    access: &FileAccess,
    options: &LoadOptions,
    textures: &mut [Texture],
    warnings: &mut Vec<String>,
) -> Result<(Vec<ImageSource>, Vec<UnusableImage>), LoadError> {
    let mut out = Vec::with_capacity(document.images().len());
    let mut unusable = Vec::new();
    // An image's view that the read left on disk (buffer 0 is then the GLB's binary chunk).
    let deferred = |view: &gltf::buffer::View| {
        let d = file.and_then(|f| f.deferred)?;
        (view.buffer().index() == 0 && d.holds(view.offset(), view.length())).then(|| {
            let start = d.bin_start + view.offset() as u64;
            FileRange {
                path: access.model.clone(),
                range: start..start + view.length() as u64,
            }
        })
    };
    // Sharing keeps the whole file alive as long as the scene: worth it only when the images
    // are most of it. A big GLB with a small texture copies the texture, so that its geometry
    // bytes are freed after the load as before; then at most the images' size is ever held
    // beyond them, as with copies.
    let embedded: usize = document
        .images()
        .filter_map(|image| match image.source() {
            gltf::image::Source::View { view, .. } if deferred(&view).is_none() => {
                Some(view.length())
            }
            _ => None,
        })
        .sum();
    let file = file
        .map(|f| f.bytes)
        .filter(|f| embedded.saturating_mul(2) >= f.len());
    for image in document.images() {
        let index = image.index();
        let what = format!("image {index}");
        let image_err = |problem: String| {
            LoadError::new(
                &access.model,
                LoadErrorKind::Image {
                    image: index,
                    problem,
                },
            )
        };
        let source = match image.source() {
            gltf::image::Source::View { view, mime_type } if deferred(&view).is_some() => {
                ImageSource {
                    origin: format!("bufferView {}", view.index()),
                    mime_type: Some(mime_type.to_string()),
                    path: None,
                    bytes: None,
                    in_file: deferred(&view),
                    pixels: None,
                }
            }
            gltf::image::Source::View { view, mime_type } => {
                let start = view.offset();
                // check_views made sure this range exists.
                let bytes = buffers
                    .get(view.buffer().index())
                    .and_then(|b| b.get(start..start + view.length()))
                    .ok_or_else(|| {
                        image_err(format!("bufferView {} is out of range", view.index()))
                    })?;
                ImageSource {
                    origin: format!("bufferView {}", view.index()),
                    mime_type: Some(mime_type.to_string()),
                    path: None,
                    // A GLB's own chunk is borrowed from the file: shared, not copied.
                    bytes: Some(SharedBytes::within(file, bytes)),
                    in_file: None,
                    pixels: None,
                }
            }
            gltf::image::Source::Uri { uri, mime_type } if uri.starts_with("data:") => {
                let (mime, bytes) = decode_data_uri(&what, uri, access.max_bytes)
                    .map_err(|k| LoadError::new(&access.model, k))?;
                ImageSource {
                    origin: format!("{}...", &uri[..uri.len().min(32)]),
                    mime_type: mime.or(mime_type.map(str::to_string)),
                    path: None,
                    bytes: Some(SharedBytes::whole(bytes)),
                    in_file: None,
                    pixels: None,
                }
            }
            gltf::image::Source::Uri { uri, mime_type } => ImageSource {
                origin: uri.to_string(),
                mime_type: mime_type.map(str::to_string),
                path: Some(access.resolve(&what, uri)?),
                bytes: None,
                in_file: None,
                pixels: None,
            },
        };
        let checked = match &source.path {
            Some(path) if path.is_dir() => {
                Err(format!("'{}' is a folder, not a file", path.display()))
            }
            Some(path) if !path.is_file() => Err(format!("file '{}' not found", path.display())),
            _ => check_image_header(&source, options.limits.max_image_pixels),
        };
        if let Err(problem) = checked {
            let mut switched = 0;
            for texture in textures.iter_mut().filter(|t| t.image == index) {
                if let Some(fallback) = texture.fallback_image.take() {
                    texture.image = fallback;
                    switched += 1;
                }
            }
            if switched > 0 {
                warnings.push(format!(
                    "image {index} ({}): {problem}; {switched} texture(s) use their fallback image instead",
                    source.origin
                ));
            }
            if switched == 0 || textures.iter().any(|t| t.image == index) {
                unusable.push(UnusableImage::new(
                    index,
                    source.origin.clone(),
                    problem,
                    source.path.as_deref(),
                ));
            }
        }
        out.push(source);
    }
    Ok((out, unusable))
}
