//! The glTF container: a GLB's header and chunks or a .gltf's JSON, parsed without copying the
//! binary chunk; a large GLB read with its image-only buffer views left on disk; and the
//! buffers, from the binary chunk, `data:` URIs or files next to the model.

use super::buffer::Buffer;
use super::lenient::{self, Rewritten};
use super::meshopt;
use crate::scene::error::{LoadError, LoadErrorKind};
use crate::scene::options::Format;
use crate::scene::paths::FileAccess;
use base64::Engine;
use std::borrow::Cow;

/// GLB header: magic, version, length (glTF 2.0 §4.4.2).
const GLB_HEADER_BYTES: usize = 12;

/// The unvalidated document as [`lenient::deserialize`] rewrites it and, for a GLB, its binary
/// chunk, borrowed from `bytes` (`gltf::Gltf::from_slice_without_validation` copies the chunk
/// into a `Vec`: for DamagedHelmet's GLB, 3.3 MB copied and page-faulted in on every load, a
/// fifth of its time). The header must have passed [`check_glb_header`].
pub(super) fn parse(
    bytes: &[u8],
    format: Format,
) -> Result<(Rewritten, Option<Buffer<'_>>), LoadErrorKind> {
    let (json, blob) = match format {
        Format::Glb => glb_chunks(bytes)?,
        _ => (bytes, None),
    };
    let rewritten = lenient::deserialize(json).map_err(|e| match e {
        gltf::Error::Deserialize(d) => LoadErrorKind::Gltf(format!("JSON: {d}")),
        other => LoadErrorKind::Gltf(other.to_string()),
    })?;
    Ok((rewritten, blob.map(Cow::Borrowed)))
}

/// GLB chunk header: length, type (glTF 2.0 §4.4.3).
const CHUNK_HEADER_BYTES: usize = 8;

/// A GLB's JSON chunk and its first binary chunk (glTF 2.0 §4.4.3), within the length its
/// header declares. Chunks of other types are skipped ("client implementations must ignore
/// chunks with unknown types"); fewer bytes than a chunk header after the last chunk (padding)
/// and anything past the declared length are not read. A chunk longer than what follows it is
/// an error (truncated), except an unknown one at the end, which is skipped like padding.
fn glb_chunks(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), LoadErrorKind> {
    let word = |b: &[u8]| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize;
    let length = bytes.get(8..12).map_or(0, word);
    let mut rest = bytes.get(GLB_HEADER_BYTES..length).unwrap_or_default();
    let mut json = None;
    let mut bin = None;
    while rest.len() >= CHUNK_HEADER_BYTES {
        let (size, kind) = (word(&rest[..4]), &rest[4..8]);
        let body = &rest[CHUNK_HEADER_BYTES..];
        let name = match kind {
            b"JSON" => "JSON",
            b"BIN\0" => "BIN",
            _ => "unknown",
        };
        if size > body.len() {
            if name == "unknown" {
                break;
            }
            return Err(LoadErrorKind::Glb(format!(
                "{name} chunk declares {size} bytes but only {} follow (truncated)",
                body.len()
            )));
        }
        match name {
            "JSON" if json.is_none() && bin.is_none() => json = Some(&body[..size]),
            "JSON" => return Err(LoadErrorKind::Glb("a second JSON chunk".to_string())),
            _ if json.is_none() => {
                return Err(LoadErrorKind::Glb(format!(
                    "the first chunk is {} ({kind:?}), not JSON",
                    if name == "BIN" {
                        "BIN"
                    } else {
                        "of an unknown type"
                    }
                )))
            }
            "BIN" if bin.is_none() => bin = Some(&body[..size]),
            _ => {}
        }
        rest = &body[size..];
    }
    let json = json.ok_or_else(|| {
        LoadErrorKind::Glb(format!(
            "no JSON chunk in the {} bytes after the header (truncated)",
            length.saturating_sub(GLB_HEADER_BYTES)
        ))
    })?;
    Ok((json, bin))
}

/// The `gltf` crate subtracts the header size from the declared length without checking it.
pub(super) fn check_glb_header(bytes: &[u8]) -> Result<(), LoadErrorKind> {
    if !bytes.starts_with(b"glTF") {
        return Ok(());
    }
    if bytes.len() < GLB_HEADER_BYTES {
        return Err(LoadErrorKind::Glb(format!(
            "file is {} bytes, shorter than the 12-byte GLB header",
            bytes.len()
        )));
    }
    let word = |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    let (version, length) = (word(4), word(8) as usize);
    if version != 2 {
        return Err(LoadErrorKind::Glb(format!(
            "version {version}, only glTF 2 is supported"
        )));
    }
    if length < GLB_HEADER_BYTES || length > bytes.len() {
        return Err(LoadErrorKind::Glb(format!(
            "header declares {length} bytes but the file has {} (truncated or corrupt)",
            bytes.len()
        )));
    }
    Ok(())
}

/// Images of a GLB this many bytes together or more are left on disk by the load
/// ([`read_glb_deferring_images`]); smaller ones are read with the rest of the file.
const MIN_DEFERRED_IMAGE_BYTES: u64 = 256 << 10;

/// A GLB read without its images: the byte ranges of the file that were left unread (zero in
/// the bytes read), each exactly the buffer view of one or more images and nothing else.
#[derive(Debug, Default)]
pub(crate) struct DeferredImages {
    /// File offset of the binary chunk's data (buffer 0).
    pub bin_start: u64,
    /// Sorted, disjoint file ranges.
    pub ranges: Vec<std::ops::Range<u64>>,
}

impl DeferredImages {
    /// Whether bytes `offset..offset + length` of buffer 0 are one of the ranges left unread.
    pub(super) fn holds(&self, offset: usize, length: usize) -> bool {
        let start = self.bin_start + offset as u64;
        self.ranges
            .binary_search_by_key(&start, |r| r.start)
            .is_ok_and(|i| self.ranges[i].end - start == length as u64)
    }
}

/// The file [`Scene::load_with`] read: its bytes, and the images it left on disk.
///
/// [`Scene::load_with`]: crate::scene::model::Scene::load_with
#[derive(Clone, Copy)]
pub(crate) struct LoadedFile<'a> {
    pub bytes: &'a std::sync::Arc<Vec<u8>>,
    pub deferred: Option<&'a DeferredImages>,
}

/// Reads a GLB of `len` bytes from `file` except the buffer views that only images use, when
/// those are at least [`MIN_DEFERRED_IMAGE_BYTES`]: a textured GLB is mostly its JPEGs and PNGs
/// (DamagedHelmet's meshopt GLB: 3.1 of 3.35 MB), and the load needs none of their bytes but
/// the header, which [`check_image_header`](crate::scene::image_header::check_image_header)
/// reads from the file. The texture phase reads them then, on the decoding threads, as it
/// reads a .gltf's image files. The unread ranges are left zero in the returned bytes (memory
/// the kernel maps only if it is touched).
///
/// A view stays in the read part when anything else may read it: a `bufferView` named anywhere
/// in the JSON outside `images` (accessors, sparse accessors, Draco), a range that an extension
/// of a buffer view names (meshopt's compressed bytes), or another view overlapping it. `None`
/// (read the whole file as before) for anything that is not a plain GLB with a JSON chunk and a
/// binary chunk inside the file, or JSON that does not parse: the full parse then says why (the
/// caller reads the file again from its start).
pub(crate) fn read_glb_deferring_images(
    file: &mut std::fs::File,
    len: u64,
) -> std::io::Result<Option<(Vec<u8>, DeferredImages)>> {
    use std::io::{Read, Seek, SeekFrom};
    if len < MIN_DEFERRED_IMAGE_BYTES {
        return Ok(None);
    }
    let mut head = [0u8; 20];
    file.read_exact(&mut head)?;
    let word =
        |b: &[u8], i: usize| u64::from(u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]));
    let bin_header = 20 + word(&head, 12);
    if !head.starts_with(b"glTF") || &head[16..20] != b"JSON" || bin_header + 8 > len {
        return Ok(None);
    }
    let mut json = zeroed_bytes(bin_header + 8 - 20)?;
    file.read_exact(&mut json)?;
    let bin_head = json.split_off(json.len() - 8);
    let bin_start = bin_header + 8;
    let bin_len = word(&bin_head, 0);
    if &bin_head[4..8] != b"BIN\0" || bin_start + bin_len > len {
        return Ok(None);
    }
    let Ok(mut root) = serde_json::from_slice::<serde_json::Value>(&json) else {
        return Ok(None);
    };
    // As the load will read it: an index written `2.0` names view 2 here too.
    lenient::integers_and_extras(&mut root);
    let ranges = image_only_ranges(&root, bin_len)
        .into_iter()
        .map(|r| bin_start + r.start..bin_start + r.end)
        .collect::<Vec<_>>();
    if ranges.iter().map(|r| r.end - r.start).sum::<u64>() < MIN_DEFERRED_IMAGE_BYTES {
        return Ok(None);
    }
    // Zeroed: the kernel maps a page of it when it is first written, so the ranges left unread
    // cost nothing.
    let mut bytes = zeroed_bytes(len)?;
    bytes[..20].copy_from_slice(&head);
    bytes[20..20 + json.len()].copy_from_slice(&json);
    bytes[20 + json.len()..bin_start as usize].copy_from_slice(&bin_head);
    // Everything but the ranges, in order.
    let mut at = bin_start;
    for (start, end) in ranges.iter().map(|r| (r.start, r.end)).chain([(len, len)]) {
        if start > at {
            file.seek(SeekFrom::Start(at))?;
            file.read_exact(&mut bytes[at as usize..start as usize])?;
        }
        at = end;
    }
    Ok(Some((bytes, DeferredImages { bin_start, ranges })))
}

/// `len` zero bytes, allocated zeroed (pages the kernel maps only when written), or an
/// `OutOfMemory` error when the allocator refuses: never the process aborted.
fn zeroed_bytes(len: u64) -> std::io::Result<Vec<u8>> {
    let refused = || {
        std::io::Error::new(
            std::io::ErrorKind::OutOfMemory,
            format!("not enough memory to read {len} bytes"),
        )
    };
    let size = usize::try_from(len).map_err(|_| refused())?;
    if size == 0 {
        return Ok(Vec::new());
    }
    let layout = std::alloc::Layout::array::<u8>(size).map_err(|_| refused())?;
    // SAFETY: `layout` has a non-zero size. A non-null pointer is a block of the global
    // allocator of exactly `layout`, every byte initialised (zero), so it is a valid Vec<u8> of
    // length and capacity `size`, which the Vec frees with the same layout.
    unsafe {
        let ptr = std::alloc::alloc_zeroed(layout);
        if ptr.is_null() {
            return Err(refused());
        }
        Ok(Vec::from_raw_parts(ptr, size, size))
    }
}

/// The byte ranges of buffer 0 (a GLB's binary chunk, `bin_len` bytes) that images' buffer
/// views cover and nothing else may read (see [`read_glb_deferring_images`]), sorted and
/// disjoint. Empty where buffer 0 is not the binary chunk (it has a `uri`).
fn image_only_ranges(root: &serde_json::Value, bin_len: u64) -> Vec<std::ops::Range<u64>> {
    use serde_json::Value;
    let list = |key: &str| {
        root.get(key)
            .and_then(Value::as_array)
            .map_or(&[][..], |v| v)
    };
    if list("buffers")
        .first()
        .is_none_or(|b| b.get("uri").is_some())
    {
        return Vec::new();
    }
    let int = |v: &Value, key: &str| v.get(key).and_then(Value::as_u64);
    // A view's range of buffer 0, if that is its buffer and the range lies inside it.
    let range = |v: &Value| -> Option<std::ops::Range<u64>> {
        let start = int(v, "byteOffset").unwrap_or(0);
        let end = start.checked_add(int(v, "byteLength")?)?;
        (int(v, "buffer")? == 0 && end <= bin_len).then_some(start..end)
    };
    let views = list("bufferViews");
    let mut by_images: Vec<usize> = list("images")
        .iter()
        .filter_map(|image| int(image, "bufferView"))
        .filter_map(|v| usize::try_from(v).ok())
        .collect();
    by_images.sort_unstable();
    by_images.dedup();
    // Every `bufferView` named outside `images`, at any depth (accessors, sparse, Draco, ...).
    let mut named = Vec::new();
    fn collect(v: &Value, out: &mut Vec<u64>) {
        match v {
            Value::Object(map) => {
                for (key, value) in map {
                    match (key.as_str(), value.as_u64()) {
                        ("bufferView", Some(index)) => out.push(index),
                        _ => collect(value, out),
                    }
                }
            }
            Value::Array(items) => items.iter().for_each(|item| collect(item, out)),
            _ => {}
        }
    }
    if let Value::Object(map) = root {
        for (key, value) in map {
            if key != "images" {
                collect(value, &mut named);
            }
        }
    }
    named.sort_unstable();
    let only_images =
        |i: usize| by_images.binary_search(&i).is_ok() && named.binary_search(&(i as u64)).is_err();
    // What else may be read: every other view, and every range a view's extension names.
    let mut other: Vec<std::ops::Range<u64>> = Vec::new();
    for (i, view) in views.iter().enumerate() {
        if !only_images(i) {
            // A view of no range (absent, or past the end) is left to the full parse.
            other.extend(range(view));
        }
        if let Some(Value::Object(extensions)) = view.get("extensions") {
            other.extend(extensions.values().filter_map(range));
        }
    }
    other.sort_unstable_by_key(|r| r.start);
    // The furthest end among the first k others, for k = 0..=len.
    let reach: Vec<u64> = std::iter::once(0)
        .chain(other.iter().scan(0, |end, r| {
            *end = r.end.max(*end);
            Some(*end)
        }))
        .collect();
    let mut candidates: Vec<std::ops::Range<u64>> = by_images
        .iter()
        .filter(|&&i| only_images(i))
        .filter_map(|&i| views.get(i).and_then(range))
        .filter(|r| r.end > r.start)
        .collect();
    candidates.sort_unstable_by_key(|r| (r.start, r.end));
    // Two images of one view are one range.
    candidates.dedup();
    let mut out = Vec::with_capacity(candidates.len());
    let mut earlier_end = 0;
    for (i, r) in candidates.iter().enumerate() {
        let overlaps_earlier = r.start < earlier_end;
        let overlaps_later = candidates.get(i + 1).is_some_and(|next| next.start < r.end);
        // Others starting before this range ends; one of them overlaps it if it reaches past
        // its start.
        let starting_before = other.partition_point(|o| o.start < r.end);
        let overlaps_other = reach[starting_before] > r.start;
        if !(overlaps_earlier || overlaps_later || overlaps_other) {
            out.push(r.clone());
        }
        earlier_end = earlier_end.max(r.end);
    }
    out
}

/// Decodes a `data:` URI's payload, base64 (`;base64`) or percent-encoded (RFC 2397: any
/// other octet as itself), refusing one larger than `max_bytes` before decoding. Returns its
/// media type, if it names one, and its bytes.
pub(crate) fn decode_data_uri(
    what: &str,
    uri: &str,
    max_bytes: u64,
) -> Result<(Option<String>, Vec<u8>), LoadErrorKind> {
    let bad = |problem: &str| LoadErrorKind::DataUri {
        what: what.to_string(),
        problem: problem.to_string(),
    };
    let rest = uri
        .strip_prefix("data:")
        .ok_or_else(|| bad("not a data URI"))?;
    let (header, payload) = rest
        .split_once(',')
        .ok_or_else(|| bad("no ',' before the payload"))?;
    let (mime, base64) = match header.strip_suffix(";base64") {
        Some(mime) => (mime, true),
        None => (header, false),
    };
    let decoded_len = if base64 {
        (payload.len() as u64 / 4) * 3
    } else {
        payload.len() as u64
    };
    if decoded_len > max_bytes {
        return Err(bad(&format!(
            "decodes to about {decoded_len} bytes, over the limit of {max_bytes}"
        )));
    }
    let bytes = if base64 {
        let engine = base64::engine::GeneralPurpose::new(
            &base64::alphabet::STANDARD,
            base64::engine::GeneralPurposeConfig::new()
                .with_decode_padding_mode(base64::engine::DecodePaddingMode::Indifferent),
        );
        engine
            .decode(payload.trim())
            .map_err(|e| bad(&format!("base64: {e}")))?
    } else {
        percent_decode(payload).map_err(|at| {
            bad(&format!(
                "'%' at byte {at} of the payload is not followed by two hexadecimal digits"
            ))
        })?
    };
    // Parameters such as `;charset=...` are not part of the media type.
    let mime = mime.split(';').next().unwrap_or_default();
    let mime = (!mime.is_empty()).then(|| mime.to_string());
    Ok((mime, bytes))
}

/// RFC 3986 percent-decoding: `%XY` is the octet 0xXY, anything else stands for itself.
/// `Err` holds the offset of a `%` without two hexadecimal digits.
fn percent_decode(payload: &str) -> Result<Vec<u8>, usize> {
    let bytes = payload.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while let Some(&b) = bytes.get(i) {
        if b == b'%' {
            let hex = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or(i)?;
            out.push(hex);
            i += 3;
        } else {
            out.push(b);
            i += 1;
        }
    }
    Ok(out)
}

pub(super) fn load_buffers<'a>(
    document: &gltf::Document,
    mut blob: Option<Buffer<'a>>,
    access: &FileAccess,
) -> Result<Vec<Buffer<'a>>, LoadError> {
    let model_err = |kind| LoadError::new(&access.model, kind);
    let mut buffers = Vec::with_capacity(document.buffers().len());
    for buffer in document.buffers() {
        let index = buffer.index();
        let what = format!("buffer {index}");
        if meshopt::is_fallback(&buffer) {
            // Filled by meshopt::decode_views; whatever its uri holds is not needed.
            let length = buffer.length();
            if length as u64 > access.max_bytes {
                return Err(model_err(LoadErrorKind::Buffer {
                    buffer: index,
                    problem: format!(
                        "meshopt fallback buffer of {length} bytes is over the limit of {} bytes",
                        access.max_bytes
                    ),
                }));
            }
            buffers.push(Cow::Owned(vec![0; length]));
            continue;
        }
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                model_err(LoadErrorKind::Buffer {
                    buffer: index,
                    problem: "refers to the GLB binary chunk, which is missing".to_string(),
                })
            })?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => Cow::Owned(
                decode_data_uri(&what, uri, access.max_bytes)
                    .map_err(model_err)?
                    .1,
            ),
            gltf::buffer::Source::Uri(uri) => {
                let file = access.resolve(&what, uri)?;
                Cow::Owned(
                    access
                        .read_prefix(&file, buffer.length() as u64)
                        .map_err(|e| {
                            let problem = LoadErrorKind::Buffer {
                                buffer: index,
                                // The URI as the file gives it, beside the model the error
                                // names: a zip's model is read from a temporary folder whose
                                // path means nothing to the user (and is gone by then).
                                problem: format!("cannot read '{uri}': {}", e.kind),
                            };
                            model_err(match e.missing_file() {
                                Some(missing) => LoadErrorKind::MissingFile {
                                    file: missing.to_path_buf(),
                                    problem: Box::new(problem),
                                },
                                None => problem,
                            })
                        })?,
                )
            }
        };
        if data.len() < buffer.length() {
            return Err(model_err(LoadErrorKind::BufferTooShort {
                buffer: index,
                expected: buffer.length(),
                actual: data.len(),
            }));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The views `image_only_ranges` leaves unread: only an image's, and not one that any
    /// `bufferView` key elsewhere names, however deep (a Draco primitive's here), nor one
    /// that overlaps another view or an extension's range.
    #[test]
    fn only_views_nothing_else_reads_are_deferred() {
        let r = |start: u64, end: u64| start..end;
        let root = |extra: serde_json::Value| {
            let mut json = serde_json::json!({
                "buffers": [{"byteLength": 400}],
                "bufferViews": [
                    {"buffer": 0, "byteOffset": 0, "byteLength": 100},
                    {"buffer": 0, "byteOffset": 100, "byteLength": 100},
                    {"buffer": 0, "byteOffset": 200, "byteLength": 100},
                    {"buffer": 0, "byteOffset": 300, "byteLength": 100}
                ],
                "images": [{"bufferView": 1}, {"bufferView": 2}, {"bufferView": 2}],
                "accessors": [{"bufferView": 0}]
            });
            if let (Some(a), serde_json::Value::Object(b)) = (json.as_object_mut(), extra) {
                a.extend(b);
            }
            json
        };
        assert_eq!(
            image_only_ranges(&root(serde_json::json!({})), 400),
            [r(100, 200), r(200, 300)]
        );
        let draco = serde_json::json!({"meshes": [{"primitives": [{"extensions":
            {"KHR_draco_mesh_compression": {"bufferView": 2}}}]}]});
        assert_eq!(image_only_ranges(&root(draco), 400), [r(100, 200)]);
        // An index written 2.0 names view 2 once the JSON is read as the load reads it.
        let mut float_index = root(serde_json::json!({"accessors": [{"bufferView": 2.0}]}));
        lenient::integers_and_extras(&mut float_index);
        assert_eq!(image_only_ranges(&float_index, 400), [r(100, 200)]);
        let mut overlapping = root(serde_json::json!({}));
        overlapping["bufferViews"][3]["byteOffset"] = serde_json::json!(150);
        overlapping["bufferViews"][3]["byteLength"] = serde_json::json!(10);
        assert_eq!(image_only_ranges(&overlapping, 400), [r(200, 300)]);
        let mut extension = root(serde_json::json!({}));
        extension["bufferViews"][3]["extensions"] = serde_json::json!({"EXT_meshopt_compression": {"buffer": 0, "byteOffset": 250, "byteLength": 4}});
        assert_eq!(image_only_ranges(&extension, 400), [r(100, 200)]);
        let mut external = root(serde_json::json!({}));
        external["buffers"][0]["uri"] = serde_json::json!("data.bin");
        assert!(image_only_ranges(&external, 400).is_empty());
        // A view past the binary chunk is left to the full parse.
        assert_eq!(
            image_only_ranges(&root(serde_json::json!({})), 250),
            [r(100, 200)]
        );
    }

    #[test]
    fn data_uris_decode_and_are_size_checked() {
        let (mime, bytes) =
            decode_data_uri("buffer 0", "data:application/octet-stream;base64,AAEC", 100).unwrap();
        assert_eq!(mime.as_deref(), Some("application/octet-stream"));
        assert_eq!(bytes, vec![0, 1, 2]);
        assert!(decode_data_uri("buffer 0", "data:;base64,AAECAAEC", 3).is_err());
        let (mime, bytes) = decode_data_uri(
            "buffer 0",
            "data:text/plain;charset=US-ASCII,h%C3%A9%00!",
            100,
        )
        .unwrap();
        assert_eq!(mime.as_deref(), Some("text/plain"));
        assert_eq!(bytes, b"h\xc3\xa9\x00!");
        assert!(decode_data_uri("buffer 0", "data:,100%", 100).is_err());
        assert!(decode_data_uri("buffer 0", "data:,%zz", 100).is_err());
        assert!(decode_data_uri("buffer 0", "data:;base64,!!!!", 100).is_err());
    }

    #[test]
    fn glb_header_is_checked_before_the_gltf_crate_sees_it() {
        assert!(check_glb_header(b"glTF").is_err());
        let mut h = b"glTF".to_vec();
        h.extend(2u32.to_le_bytes());
        h.extend(4u32.to_le_bytes());
        assert!(
            check_glb_header(&h).is_err(),
            "length below the header size"
        );
        let mut v1 = b"glTF".to_vec();
        v1.extend(1u32.to_le_bytes());
        v1.extend(12u32.to_le_bytes());
        assert!(check_glb_header(&v1).is_err(), "glTF 1 binary");
    }
}
