//! `EXT_meshopt_compression` and `KHR_meshopt_compression`: buffer views whose bytes are stored
//! compressed elsewhere, decoded (by the `meshoptimizer-rs` crate, safe Rust) into their place
//! before anything reads them, so that the decoded data passes the same buffer view and
//! accessor checks as plain data.
//!
//! Rules followed (the extensions' README, "bufferView" and "Fallback buffers"):
//! - the view's extension names `buffer`, `byteOffset` (default 0) and `byteLength` of the
//!   compressed stream, the element `byteStride` and `count`, the `mode` (`ATTRIBUTES`,
//!   `TRIANGLES`, `INDICES`) and the `filter` (`NONE` by default, `OCTAHEDRAL`, `QUATERNION`,
//!   `EXPONENTIAL`; `COLOR` in KHR only);
//! - the decoded data is `count` × `byteStride` bytes and fills the view exactly; an
//!   ATTRIBUTES view that declares its own `byteStride` must declare the same one;
//! - a buffer whose extension says `fallback: true` holds nothing but decoded views: it need
//!   not have data (and is never read from disk here), so it starts zeroed.
//!
//! Both extensions share one bitstream; version 1 of the vertex codec is KHR's, but a stream
//! that says it is version 1 is decoded under either name (the decoder checks the stream).

use super::buffer::Buffer;
use crate::scene::error::LoadErrorKind;
use meshoptimizer_rs::codec::{self, Mode};
use meshoptimizer_rs::{Limits, Workspace};
use serde_json::Value;

/// The two extension names, KHR first (the ratified one).
pub(crate) const EXTENSIONS: [&str; 2] = ["KHR_meshopt_compression", "EXT_meshopt_compression"];

/// The extension object and its name, if `get` finds one of [`EXTENSIONS`].
fn find<'a>(get: impl Fn(&str) -> Option<&'a Value>) -> Option<(&'static str, &'a Value)> {
    EXTENSIONS
        .iter()
        .find_map(|&name| get(name).map(|value| (name, value)))
}

/// Whether a buffer is a meshopt fallback buffer (`fallback: true`): its bytes are all
/// produced by decoding, so its `uri` (if any) need not be read.
pub(crate) fn is_fallback(buffer: &gltf::Buffer) -> bool {
    find(|name| buffer.extension_value(name)).is_some_and(|(_, ext)| {
        ext.get("fallback")
            .and_then(Value::as_bool)
            .unwrap_or(false)
    })
}

/// The post-decode filter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Filter {
    None,
    Octahedral,
    Quaternion,
    Exponential,
    Color,
}

/// One compressed view, as its extension describes it.
struct Compressed {
    buffer: usize,
    offset: usize,
    length: usize,
    stride: usize,
    count: usize,
    mode: Mode,
    filter: Filter,
}

fn parse(name: &str, ext: &Value) -> Result<Compressed, String> {
    let number = |key: &str, default: Option<usize>| -> Result<usize, String> {
        match ext.get(key) {
            None => default.ok_or_else(|| format!("has no {key}")),
            Some(v) => v
                .as_u64()
                .and_then(|n| usize::try_from(n).ok())
                .ok_or_else(|| format!("{key} {v} is not a non-negative integer")),
        }
    };
    let mode = match ext.get("mode").and_then(Value::as_str) {
        Some("ATTRIBUTES") => Mode::Attributes,
        Some("TRIANGLES") => Mode::Triangles,
        Some("INDICES") => Mode::Indices,
        other => {
            return Err(format!(
                "mode {} is not ATTRIBUTES, TRIANGLES or INDICES",
                other.map_or("(missing)".to_string(), |m| format!("'{m}'"))
            ))
        }
    };
    let filter = match ext.get("filter").map(|f| f.as_str()) {
        None | Some(Some("NONE")) => Filter::None,
        Some(Some("OCTAHEDRAL")) => Filter::Octahedral,
        Some(Some("QUATERNION")) => Filter::Quaternion,
        Some(Some("EXPONENTIAL")) => Filter::Exponential,
        Some(Some("COLOR")) if name.starts_with("KHR") => Filter::Color,
        Some(other) => return Err(format!("filter {other:?} is not defined by {name}")),
    };
    if mode != Mode::Attributes && filter != Filter::None {
        return Err(format!(
            "filter {filter:?} is only allowed with mode ATTRIBUTES"
        ));
    }
    Ok(Compressed {
        buffer: number("buffer", None)?,
        offset: number("byteOffset", Some(0))?,
        length: number("byteLength", None)?,
        stride: number("byteStride", None)?,
        count: number("count", None)?,
        mode,
        filter,
    })
}

/// Decodes one compressed stream to `count` × `stride` bytes, under `limits`.
#[cfg(test)]
fn decode(c: &Compressed, source: &[u8], limits: Limits) -> Result<Vec<u8>, String> {
    let mut data = vec![0; c.count.checked_mul(c.stride).ok_or("size overflows")?];
    decode_into(c, source, &mut data, limits)?;
    Ok(data)
}

/// Decodes one compressed stream into `target` (`count` × `stride` bytes), under `limits`:
/// straight into the buffer it belongs in, with no buffer of its own to fill and copy.
fn decode_into(
    c: &Compressed,
    source: &[u8],
    target: &mut [u8],
    limits: Limits,
) -> Result<(), String> {
    let mut workspace = Workspace::new(limits);
    let ws = &mut workspace;
    let (count, stride) = (c.count, c.stride);
    let (result, what) = match c.mode {
        Mode::Attributes => (
            codec::decode_vertex_buffer_into(target, count, stride, source, ws),
            "vertex stream",
        ),
        Mode::Triangles => (
            codec::decode_index_buffer_into(target, count, stride, source, ws),
            "triangle stream",
        ),
        Mode::Indices => (
            codec::decode_index_sequence_into(target, count, stride, source, ws),
            "index sequence",
        ),
    };
    result.map_err(|e| {
        format!(
            "{what} of {count} elements of {stride} bytes from {} compressed bytes: {e}",
            source.len()
        )
    })?;
    match c.filter {
        Filter::None => Ok(()),
        Filter::Octahedral => codec::decode_filter_oct(target, count, stride, ws),
        Filter::Quaternion => codec::decode_filter_quat(target, count, stride, ws),
        Filter::Exponential => codec::decode_filter_exp(target, count, stride, ws),
        Filter::Color => codec::decode_filter_color(target, count, stride, ws),
    }
    .map_err(|e| format!("{:?} filter: {e}", c.filter))
}

/// Decodes every compressed buffer view into its range of its (usually fallback) buffer.
/// `max_bytes` bounds the decoder's allocations (the importer's file size limit).
pub(crate) fn decode_views(
    document: &gltf::Document,
    buffers: &mut [Buffer],
    max_bytes: u64,
) -> Result<(), LoadErrorKind> {
    let limits = Limits {
        max_bytes: usize::try_from(max_bytes).unwrap_or(usize::MAX),
        ..Limits::default()
    };
    for view in document.views() {
        let Some((name, ext)) = find(|name| view.extension_value(name)) else {
            continue;
        };
        let fail = |problem: String| LoadErrorKind::Meshopt {
            view: view.index(),
            extension: name.to_string(),
            problem,
        };
        let c = parse(name, ext).map_err(fail)?;
        let decoded_len = c.count.checked_mul(c.stride).ok_or_else(|| {
            fail(format!(
                "count {} × byteStride {} overflows",
                c.count, c.stride
            ))
        })?;
        if decoded_len != view.length() {
            return Err(fail(format!(
                "count {} × byteStride {} = {decoded_len} bytes, but the bufferView's byteLength is {}",
                c.count,
                c.stride,
                view.length()
            )));
        }
        if c.mode == Mode::Attributes && view.stride().is_some_and(|s| s != c.stride) {
            return Err(fail(format!(
                "byteStride {} differs from the bufferView's {}",
                c.stride,
                view.stride().unwrap_or(0)
            )));
        }
        let target_buffer = view.buffer().index();
        let start = view.offset();
        let past_end = || {
            fail(format!(
                "its bytes {start}..{} are past the end of buffer {target_buffer}",
                start.saturating_add(decoded_len)
            ))
        };
        if target_buffer >= buffers.len() {
            return Err(past_end());
        }
        // The target's buffer is taken out while the decoder writes into it (the compressed
        // bytes are usually in another one); put back whatever happens.
        let mut target = std::mem::take(&mut buffers[target_buffer]);
        let source = if c.buffer == target_buffer {
            // Both in one buffer: the compressed bytes are copied first.
            target
                .get(c.offset..c.offset.saturating_add(c.length))
                .map(|s| std::borrow::Cow::Owned(s.to_vec()))
        } else {
            buffers
                .get(c.buffer)
                .and_then(|b| b.get(c.offset..c.offset.checked_add(c.length)?))
                .map(std::borrow::Cow::Borrowed)
        };
        let result = match source {
            None => Err(fail(format!(
                "compressed bytes {}..{} are not inside buffer {} ({} bytes)",
                c.offset,
                c.offset.saturating_add(c.length),
                c.buffer,
                if c.buffer == target_buffer {
                    target.len()
                } else {
                    buffers.get(c.buffer).map_or(0, |b| b.len())
                }
            ))),
            // Usually the fallback buffer; a view of a GLB's own chunk copies that chunk once.
            Some(source) => match target
                .to_mut()
                .get_mut(start..start.saturating_add(decoded_len))
            {
                None => Err(past_end()),
                Some(into) => decode_into(&c, &source, into, limits).map_err(fail),
            },
        };
        buffers[target_buffer] = target;
        result?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn extension_fields_are_parsed_with_their_defaults() {
        let c = parse(
            "EXT_meshopt_compression",
            &json!({"buffer": 0, "byteLength": 10, "byteStride": 8, "count": 3, "mode": "ATTRIBUTES"}),
        )
        .unwrap();
        assert_eq!((c.offset, c.filter), (0, Filter::None));
        let color = json!({"buffer": 0, "byteLength": 10, "byteStride": 4, "count": 3,
                           "mode": "ATTRIBUTES", "filter": "COLOR"});
        assert!(parse("KHR_meshopt_compression", &color).is_ok());
        assert!(
            parse("EXT_meshopt_compression", &color).is_err(),
            "COLOR is KHR's"
        );
        let filtered_indices = json!({"buffer": 0, "byteLength": 10, "byteStride": 2, "count": 3,
                                      "mode": "TRIANGLES", "filter": "OCTAHEDRAL"});
        assert!(parse("KHR_meshopt_compression", &filtered_indices).is_err());
        assert!(parse("KHR_meshopt_compression", &json!({"mode": "ATTRIBUTES"})).is_err());
    }

    #[test]
    fn streams_round_trip_through_the_encoder_and_bad_streams_are_errors() {
        let mut ws = Workspace::new(Limits::default());
        // Eight 4-byte vertices, encoded by the same crate's reference encoder.
        let vertices: Vec<u8> = (0u8..32).collect();
        let encoded =
            codec::encode_vertex_buffer(&vertices, 8, 4, codec::VertexEncoding::DEFAULT, &mut ws)
                .unwrap();
        let c = Compressed {
            buffer: 0,
            offset: 0,
            length: encoded.len(),
            stride: 4,
            count: 8,
            mode: Mode::Attributes,
            filter: Filter::None,
        };
        assert_eq!(decode(&c, &encoded, Limits::default()).unwrap(), vertices);
        // Truncated, or a count that does not match the stream: errors, not panics.
        assert!(decode(&c, &encoded[..encoded.len() - 5], Limits::default()).is_err());
        let more = Compressed { count: 4000, ..c };
        assert!(decode(&more, &encoded, Limits::default()).is_err());
        let garbage = vec![0xa0; 40];
        assert!(decode(&c, &garbage, Limits::default()).is_err());
    }
}
