//! Reads glTF vertex attribute accessors of every component type that core glTF 2.0 or
//! `KHR_mesh_quantization` allows, to `f32`, dequantized as the specification says.
//!
//! glTF 2.0 §3.11 ("Animations", table of normalized integers) and `KHR_mesh_quantization`:
//! a normalized component c becomes
//! - signed byte: max(c / 127, -1), signed short: max(c / 32767, -1);
//! - unsigned byte: c / 255, unsigned short: c / 65535;
//!
//! and a non-normalized integer is taken as it is (the node transform or `KHR_texture_transform`
//! carries the scale). The `gltf` crate's reader accepts neither normalized integer POSITION nor
//! NORMAL, and reads TEXCOORD integers as normalized whatever the `normalized` flag says, so
//! attributes are read here, from bytes that `check_accessor` has already bounded.

use super::buffer::Buffer;
use gltf::accessor::{DataType, Dimensions};

/// Why an accessor could not be read (a hostile file that passed the range checks cannot
/// reach these, but nothing here indexes without checking).
pub(crate) type ReadResult<T> = Result<T, String>;

/// One component of type `data_type` starting at `bytes[0]`, as f32.
pub(crate) fn component(bytes: &[u8], data_type: DataType, normalized: bool) -> Option<f32> {
    let b = |n: usize| bytes.get(..n);
    Some(match data_type {
        DataType::F32 => f32::from_le_bytes(b(4)?.try_into().ok()?),
        DataType::I8 => dequantize_i8(i8::from_le_bytes(b(1)?.try_into().ok()?), normalized),
        DataType::U8 => dequantize_u8(b(1)?[0], normalized),
        DataType::I16 => dequantize_i16(i16::from_le_bytes(b(2)?.try_into().ok()?), normalized),
        DataType::U16 => dequantize_u16(u16::from_le_bytes(b(2)?.try_into().ok()?), normalized),
        // Not allowed for vertex attributes (glTF 2.0 §3.7.2.1); indices are read elsewhere.
        DataType::U32 => u32::from_le_bytes(b(4)?.try_into().ok()?) as f32,
    })
}

/// Signed byte: max(c / 127, -1) when normalized (so -128 and -127 both give -1).
pub(crate) fn dequantize_i8(c: i8, normalized: bool) -> f32 {
    if normalized {
        (f32::from(c) / 127.0).max(-1.0)
    } else {
        f32::from(c)
    }
}

/// Unsigned byte: c / 255 when normalized.
pub(crate) fn dequantize_u8(c: u8, normalized: bool) -> f32 {
    if normalized {
        f32::from(c) / 255.0
    } else {
        f32::from(c)
    }
}

/// Signed short: max(c / 32767, -1) when normalized.
pub(crate) fn dequantize_i16(c: i16, normalized: bool) -> f32 {
    if normalized {
        (f32::from(c) / 32767.0).max(-1.0)
    } else {
        f32::from(c)
    }
}

/// Unsigned short: c / 65535 when normalized.
pub(crate) fn dequantize_u16(c: u16, normalized: bool) -> f32 {
    if normalized {
        f32::from(c) / 65535.0
    } else {
        f32::from(c)
    }
}

/// Number of components of an accessor type.
fn components(dims: Dimensions) -> usize {
    match dims {
        Dimensions::Scalar => 1,
        Dimensions::Vec2 => 2,
        Dimensions::Vec3 => 3,
        Dimensions::Vec4 => 4,
        Dimensions::Mat2 => 4,
        Dimensions::Mat3 => 9,
        Dimensions::Mat4 => 16,
    }
}

/// Reads every element of `accessor` as `N` f32 components (the accessor must have exactly
/// `N` components), applying its stride, sparse substitution and, where `normalized`, integer
/// normalization (the caller decides, see `Expect::reads_normalized`). Elements without a
/// buffer view start at zero (glTF 2.0 §3.6.2.3).
pub(crate) fn read<const N: usize>(
    accessor: &gltf::Accessor,
    buffers: &[Buffer],
    normalized: bool,
) -> ReadResult<Vec<[f32; N]>> {
    let n = components(accessor.dimensions());
    if n != N {
        return Err(format!("has {n} components, expected {N}"));
    }
    let data_type = accessor.data_type();
    let size = data_type.size();
    let count = accessor.count();
    let element = accessor.size();
    let view_bytes = |view: &gltf::buffer::View| -> ReadResult<&[u8]> {
        let buffer = buffers
            .get(view.buffer().index())
            .ok_or_else(|| format!("bufferView {}: buffer missing", view.index()))?;
        buffer
            .get(view.offset()..view.offset().saturating_add(view.length()))
            .ok_or_else(|| format!("bufferView {} is past its buffer's end", view.index()))
    };
    let element_at = |bytes: &[u8], start: usize| -> ReadResult<[f32; N]> {
        let mut out = [0.0; N];
        for (k, value) in out.iter_mut().enumerate() {
            // Matrices pad columns to 4 bytes; attributes never are matrices.
            let at = start + k * size;
            *value = bytes
                .get(at..)
                .and_then(|b| component(b, data_type, normalized))
                .ok_or_else(|| format!("element at byte {start} is past the view's end"))?;
        }
        Ok(out)
    };
    if let Some(view) = accessor.view() {
        // Refused before allocating: a hostile count must not reserve memory its view cannot
        // fill (callers that ran `check_accessor` never get here with such a count).
        let stride = view.stride().unwrap_or(element).max(1);
        let room = view.length().saturating_sub(accessor.offset());
        if count > 0 && (count - 1).saturating_mul(stride).saturating_add(element) > room {
            return Err(format!(
                "{count} elements of {element} bytes (stride {stride}) from offset {} do not fit bufferView {} ({} bytes)",
                accessor.offset(),
                view.index(),
                view.length()
            ));
        }
    }
    let mut out = Vec::new();
    out.try_reserve_exact(count)
        .map_err(|_| format!("cannot allocate {count} elements"))?;
    match accessor.view() {
        Some(view) => {
            let bytes = view_bytes(&view)?;
            let stride = view.stride().unwrap_or(element);
            let data = bytes
                .get(accessor.offset()..)
                .ok_or_else(|| "the accessor starts past its view's end".to_string())?;
            // One loop per component type, so that the type is matched once per accessor
            // rather than once per component (this was most of a plain load's flatten).
            match data_type {
                DataType::F32 => elements(data, count, stride, &mut out, f32::from_le_bytes)?,
                DataType::I8 => elements(data, count, stride, &mut out, |b: [u8; 1]| {
                    dequantize_i8(i8::from_le_bytes(b), normalized)
                })?,
                DataType::U8 => elements(data, count, stride, &mut out, |b: [u8; 1]| {
                    dequantize_u8(b[0], normalized)
                })?,
                DataType::I16 => elements(data, count, stride, &mut out, |b| {
                    dequantize_i16(i16::from_le_bytes(b), normalized)
                })?,
                DataType::U16 => elements(data, count, stride, &mut out, |b| {
                    dequantize_u16(u16::from_le_bytes(b), normalized)
                })?,
                DataType::U32 => elements(data, count, stride, &mut out, |b| {
                    u32::from_le_bytes(b) as f32
                })?,
            }
        }
        None => out.resize(count, [0.0; N]),
    }
    if let Some(sparse) = accessor.sparse() {
        let indices = sparse.indices();
        let index_bytes = view_bytes(&indices.view())?;
        let index_size = indices.index_type().size();
        let values = sparse.values();
        let value_bytes = view_bytes(&values.view())?;
        for k in 0..sparse.count() {
            let at = indices.offset() + k * index_size;
            let raw = index_bytes
                .get(at..at + index_size)
                .ok_or_else(|| format!("sparse index {k} is past its view's end"))?;
            let index = match raw {
                [a] => usize::from(*a),
                [a, b] => usize::from(u16::from_le_bytes([*a, *b])),
                [a, b, c, d] => u32::from_le_bytes([*a, *b, *c, *d]) as usize,
                _ => return Err("sparse index type is not 1, 2 or 4 bytes".to_string()),
            };
            let slot = out
                .get_mut(index)
                .ok_or_else(|| format!("sparse index {index} is out of range for {count}"))?;
            *slot = element_at(value_bytes, values.offset() + k * element)?;
        }
    }
    Ok(out)
}

/// Reads an index accessor (unsigned byte, short or int scalars, glTF 2.0 §3.7.2.1) as u32,
/// one loop per component type. `None` where the `gltf` crate's general reader should take it
/// instead: a sparse accessor, one without a view or with a byte stride (index views have none,
/// glTF 2.0 §3.6.2.4), another type, or a range past the view or the buffer. That reader went
/// element by element through a generic iterator: about 7% of a million-triangle load.
pub(crate) fn read_indices(accessor: &gltf::Accessor, buffers: &[Buffer]) -> Option<Vec<u32>> {
    if accessor.sparse().is_some() || accessor.dimensions() != Dimensions::Scalar {
        return None;
    }
    let view = accessor.view()?;
    let data_type = accessor.data_type();
    let size = data_type.size();
    if view.stride().is_some_and(|stride| stride != size) {
        return None;
    }
    let start = view.offset().checked_add(accessor.offset())?;
    let end = start.checked_add(accessor.count().checked_mul(size)?)?;
    if end > view.offset().checked_add(view.length())? {
        return None;
    }
    let bytes = buffers.get(view.buffer().index())?.get(start..end)?;
    let mut out = Vec::new();
    out.try_reserve_exact(accessor.count()).ok()?;
    match data_type {
        DataType::U8 => out.extend(bytes.iter().map(|&b| u32::from(b))),
        DataType::U16 => out.extend(
            bytes
                .chunks_exact(2)
                .map(|c| u32::from(u16::from_le_bytes([c[0], c[1]]))),
        ),
        DataType::U32 => out.extend(
            bytes
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])),
        ),
        _ => return None,
    }
    Some(out)
}

/// Appends `count` elements of `N` components of `S` bytes each, element `i` starting at byte
/// `i * stride` of `data`, each component converted by `value`.
fn elements<const N: usize, const S: usize>(
    data: &[u8],
    count: usize,
    stride: usize,
    out: &mut Vec<[f32; N]>,
    value: impl Fn([u8; S]) -> f32,
) -> ReadResult<()> {
    for i in 0..count {
        let start = i
            .checked_mul(stride)
            .ok_or_else(|| format!("element {i}'s offset overflows"))?;
        let bytes = data
            .get(start..)
            .and_then(|b| b.get(..N * S))
            .ok_or_else(|| format!("element {i} at byte {start} is past the view's end"))?;
        let mut element = [0.0; N];
        for (slot, component) in element.iter_mut().zip(bytes.chunks_exact(S)) {
            let Ok(component) = <[u8; S]>::try_from(component) else {
                return Err(format!("element {i} is cut short"));
            };
            *slot = value(component);
        }
        out.push(element);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Index accessors of each type, at offsets, read as the values written; a strided view, a
    /// float accessor and a range past its view are left to the general reader (`None`).
    #[test]
    fn indices_of_each_type_and_what_is_left_to_the_general_reader() {
        // Bytes 0..3: u8 [7, 0, 255]; 4..10: u16 [1, 65535, 300]; 12..24: u32 [5, 70000, 0].
        let mut bytes = vec![7u8, 0, 255, 0xEE];
        for v in [1u16, 65535, 300] {
            bytes.extend(v.to_le_bytes());
        }
        bytes.extend([0xEE; 2]);
        for v in [5u32, 70000, 0] {
            bytes.extend(v.to_le_bytes());
        }
        let json = serde_json::json!({
            "asset": {"version": "2.0"},
            "buffers": [{"byteLength": bytes.len()}],
            "bufferViews": [
                {"buffer": 0, "byteOffset": 0, "byteLength": 4},
                {"buffer": 0, "byteOffset": 4, "byteLength": 8},
                {"buffer": 0, "byteOffset": 12, "byteLength": 12},
                {"buffer": 0, "byteOffset": 4, "byteLength": 8, "byteStride": 4}
            ],
            "accessors": [
                {"bufferView": 0, "componentType": 5121, "count": 3, "type": "SCALAR"},
                {"bufferView": 1, "byteOffset": 2, "componentType": 5123, "count": 2, "type": "SCALAR"},
                {"bufferView": 2, "componentType": 5125, "count": 3, "type": "SCALAR"},
                {"bufferView": 3, "componentType": 5123, "count": 2, "type": "SCALAR"},
                {"bufferView": 2, "componentType": 5126, "count": 3, "type": "SCALAR"},
                {"bufferView": 1, "byteOffset": 4, "componentType": 5123, "count": 3, "type": "SCALAR"}
            ]
        });
        let document = gltf::Gltf::from_slice(json.to_string().as_bytes()).expect("valid glTF");
        let buffers = [Buffer::Borrowed(&bytes)];
        let read = |i: usize| {
            let accessor = document.accessors().nth(i).expect("accessor");
            read_indices(&accessor, &buffers)
        };
        assert_eq!(read(0), Some(vec![7, 0, 255]));
        assert_eq!(read(1), Some(vec![65535, 300]));
        assert_eq!(read(2), Some(vec![5, 70000, 0]));
        assert_eq!(read(3), None, "strided view");
        assert_eq!(read(4), None, "float indices");
        assert_eq!(read(5), None, "past the view's end");
    }

    #[test]
    fn normalized_integers_follow_the_specification() {
        // Signed: c / (2^(b-1) - 1), with the most negative value clamped to -1.
        assert_eq!(dequantize_i8(127, true), 1.0);
        assert_eq!(dequantize_i8(-127, true), -1.0);
        assert_eq!(dequantize_i8(-128, true), -1.0);
        assert_eq!(dequantize_i8(0, true), 0.0);
        assert_eq!(dequantize_i8(64, true), 64.0 / 127.0);
        assert_eq!(dequantize_i16(32767, true), 1.0);
        assert_eq!(dequantize_i16(-32768, true), -1.0);
        assert_eq!(dequantize_i16(-16384, true), -16384.0 / 32767.0);
        // Unsigned: c / (2^b - 1).
        assert_eq!(dequantize_u8(255, true), 1.0);
        assert_eq!(dequantize_u8(51, true), 0.2);
        assert_eq!(dequantize_u16(65535, true), 1.0);
        assert_eq!(dequantize_u16(0, true), 0.0);
        assert_eq!(dequantize_u16(13107, true), 0.2);
    }

    #[test]
    fn integers_that_are_not_normalized_are_taken_as_they_are() {
        assert_eq!(dequantize_i8(-128, false), -128.0);
        assert_eq!(dequantize_u8(200, false), 200.0);
        assert_eq!(dequantize_i16(-32768, false), -32768.0);
        assert_eq!(dequantize_u16(16383, false), 16383.0);
    }

    /// Elements at a stride larger than they are, each component type's conversion, and a view
    /// that ends inside an element.
    #[test]
    fn elements_follow_the_stride_and_refuse_a_short_view() {
        // Two elements of two f32 each, 12 bytes apart (4 bytes of padding after each).
        let mut bytes = Vec::new();
        for v in [[1.5f32, -2.0], [3.0, 0.25]] {
            bytes.extend(v[0].to_le_bytes());
            bytes.extend(v[1].to_le_bytes());
            bytes.extend([0xAA; 4]);
        }
        let mut out: Vec<[f32; 2]> = Vec::new();
        elements(&bytes, 2, 12, &mut out, f32::from_le_bytes).expect("fits");
        assert_eq!(out, [[1.5, -2.0], [3.0, 0.25]]);
        // Normalized unsigned shorts, three a 6-byte element.
        let shorts: Vec<u8> = [0u16, 65535, 13107]
            .iter()
            .flat_map(|c| c.to_le_bytes())
            .collect();
        let mut out: Vec<[f32; 3]> = Vec::new();
        elements(&shorts, 1, 6, &mut out, |b| {
            dequantize_u16(u16::from_le_bytes(b), true)
        })
        .expect("fits");
        assert_eq!(out, [[0.0, 1.0, 0.2]]);
        // The second element would end past the data: an error, and nothing half-read.
        let mut out: Vec<[f32; 2]> = Vec::new();
        let err = elements(&bytes[..19], 2, 12, &mut out, f32::from_le_bytes)
            .expect_err("the view ends inside element 1");
        assert!(err.contains("element 1"), "{err}");
        assert_eq!(out.len(), 1);
    }

    #[test]
    fn components_decode_little_endian_and_refuse_short_input() {
        assert_eq!(
            component(&1.5f32.to_le_bytes(), DataType::F32, false),
            Some(1.5)
        );
        assert_eq!(
            component(&(-2i16).to_le_bytes(), DataType::I16, false),
            Some(-2.0)
        );
        assert_eq!(component(&[0xff, 0xff], DataType::U16, true), Some(1.0));
        assert_eq!(component(&[0xff], DataType::U16, true), None);
        assert_eq!(component(&[], DataType::I8, true), None);
    }
}
