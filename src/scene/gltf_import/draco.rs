//! `KHR_draco_mesh_compression`: a primitive whose geometry is a Draco stream in a buffer view,
//! decoded by the pure-Rust `draco-core` crate.
//!
//! Rules followed (the extension's README, "Conformance" and "Implementation note"):
//! - the extension names the `bufferView` holding the stream and maps each compressed glTF
//!   attribute semantic to the Draco attribute's unique id (`attributes`);
//! - the primitive's accessors for those semantics (and its `indices`) have no buffer view but
//!   keep their `count`, `type` and `componentType`, which must match the decoded data;
//! - the decoded faces are the primitive's triangles; attributes not in the extension's map
//!   are read from their own accessors, as usual;
//! - Draco dequantizes positions, normals and texture coordinates itself: decoded values are
//!   floats (or integers, e.g. JOINTS_n), converted here exactly as the accessor says.
//!
//! A stream is decoded once per primitive, however many nodes instance its mesh, under
//! ceilings taken from the load limits (`DecodeLimits`), so a header that claims billions of
//! points is refused before anything is allocated for them.

use super::attributes;
use super::buffer::Buffer;
use crate::scene::options::LoadLimits;
use draco_core::{DataType as DracoType, DecodeLimits, DecoderBuffer, Mesh, MeshDecoder};
use gltf::accessor::{DataType, Dimensions};
use serde_json::Value;

/// The extension's name.
pub(crate) const EXTENSION: &str = "KHR_draco_mesh_compression";

/// The extension object of a primitive that has one.
pub(crate) fn extension<'a>(primitive: &'a gltf::Primitive) -> Option<&'a Value> {
    primitive.extension_value(EXTENSION)
}

/// A decoded primitive: its triangles (point indices, checked against the point count) and
/// the decoded attributes, found by glTF semantic.
pub(crate) struct Decoded {
    mesh: Mesh,
    /// Three point indices per triangle, each below `point_count`.
    pub indices: Vec<u32>,
    /// Points (vertices) the stream decodes to.
    pub point_count: usize,
    /// glTF semantic -> Draco unique id, from the extension.
    attributes: Vec<(String, u32)>,
}

/// The extension's `bufferView` and `attributes` map.
fn parse(ext: &Value) -> Result<(usize, Vec<(String, u32)>), String> {
    let view = ext
        .get("bufferView")
        .and_then(Value::as_u64)
        .and_then(|v| usize::try_from(v).ok())
        .ok_or("has no bufferView (a non-negative integer)")?;
    let map = ext
        .get("attributes")
        .and_then(Value::as_object)
        .ok_or("has no attributes object")?;
    let mut attributes = Vec::with_capacity(map.len());
    for (semantic, id) in map {
        let id = id
            .as_u64()
            .and_then(|i| u32::try_from(i).ok())
            .ok_or_else(|| format!("attribute {semantic}: id {id} is not a Draco unique id"))?;
        attributes.push((semantic.clone(), id));
    }
    Ok((view, attributes))
}

/// Ceilings for one stream: no more triangles than the scene may hold, no more points than
/// those triangles have corners, and no more decoded bytes than the largest file we read.
fn limits(limits: &LoadLimits) -> DecodeLimits {
    DecodeLimits::default()
        .with_max_faces(limits.max_triangles)
        .with_max_points(limits.max_triangles.saturating_mul(3))
        .with_max_decoded_bytes(limits.max_file_bytes)
}

/// Decodes the primitive's Draco stream and checks that its faces and every attribute the
/// extension maps exist and agree with the primitive's accessors. `buffers` are the file's
/// buffers after `check_views`.
pub(crate) fn decode(
    primitive: &gltf::Primitive,
    ext: &Value,
    document: &gltf::Document,
    buffers: &[Buffer],
    load_limits: &LoadLimits,
) -> Result<Decoded, String> {
    let (view_index, attributes) = parse(ext)?;
    let view = document
        .views()
        .nth(view_index)
        .ok_or_else(|| format!("bufferView {view_index} does not exist"))?;
    let start = view.offset();
    let stream = buffers
        .get(view.buffer().index())
        .and_then(|b| b.get(start..start.checked_add(view.length())?))
        .ok_or_else(|| format!("bufferView {view_index} is past its buffer's end"))?;
    let mut buffer = DecoderBuffer::new(stream).with_limits(limits(load_limits));
    let mut mesh = Mesh::new();
    MeshDecoder::new()
        .decode(&mut buffer, &mut mesh)
        .map_err(|e| {
            format!(
                "Draco stream in bufferView {view_index} ({} bytes): {e}",
                stream.len()
            )
        })?;
    let point_count = mesh.num_points();
    let mut indices = Vec::new();
    indices
        .try_reserve_exact(mesh.num_faces().saturating_mul(3))
        .map_err(|_| format!("cannot allocate {} faces", mesh.num_faces()))?;
    for (f, face) in mesh.faces().iter().enumerate() {
        for corner in face {
            if corner.0 as usize >= point_count {
                return Err(format!(
                    "decoded face {f} refers to point {}, but the stream has {point_count} points",
                    corner.0
                ));
            }
            indices.push(corner.0);
        }
    }
    if indices.is_empty() {
        return Err("the Draco stream decodes to no triangles".to_string());
    }
    let decoded = Decoded {
        mesh,
        indices,
        point_count,
        attributes,
    };
    // Every mapped attribute, used by the importer or not, must exist and match its accessor.
    for (semantic, id) in &decoded.attributes {
        let accessor = primitive
            .attributes()
            .find(|(s, _)| s.to_string() == *semantic)
            .map(|(_, a)| a)
            .ok_or_else(|| {
                format!("attributes maps {semantic}, which the primitive does not have")
            })?;
        decoded.check(semantic, *id, &accessor)?;
    }
    if let Some(accessor) = primitive.indices() {
        if primitive.mode() == gltf::mesh::Mode::Triangles
            && accessor.count() != decoded.indices.len()
        {
            return Err(format!(
                "indices accessor {} has count {}, but the stream decodes to {} indices",
                accessor.index(),
                accessor.count(),
                decoded.indices.len()
            ));
        }
    }
    Ok(decoded)
}

/// The glTF component type a Draco data type corresponds to, if any.
fn gltf_type(t: DracoType) -> Option<DataType> {
    Some(match t {
        DracoType::Int8 => DataType::I8,
        DracoType::Uint8 => DataType::U8,
        DracoType::Int16 => DataType::I16,
        DracoType::Uint16 => DataType::U16,
        DracoType::Uint32 => DataType::U32,
        DracoType::Float32 => DataType::F32,
        _ => return None,
    })
}

fn components(dims: Dimensions) -> Option<usize> {
    match dims {
        Dimensions::Scalar => Some(1),
        Dimensions::Vec2 => Some(2),
        Dimensions::Vec3 => Some(3),
        Dimensions::Vec4 => Some(4),
        _ => None,
    }
}

impl Decoded {
    /// Whether the extension maps `semantic` (e.g. `TEXCOORD_0`) to a decoded attribute.
    pub(crate) fn has(&self, semantic: &str) -> bool {
        self.attributes.iter().any(|(s, _)| s == semantic)
    }

    fn attribute(&self, semantic: &str) -> Result<&draco_core::PointAttribute, String> {
        let (_, id) = self
            .attributes
            .iter()
            .find(|(s, _)| s == semantic)
            .ok_or_else(|| format!("{semantic} is not in the extension's attributes"))?;
        self.mesh.attribute_by_unique_id(*id).ok_or_else(|| {
            format!(
                "attribute {semantic}: Draco attribute id {id} does not exist in the stream (it has {})",
                self.mesh.num_attributes()
            )
        })
    }

    /// Checks the decoded attribute against the accessor (count, type, componentType).
    fn check(&self, semantic: &str, id: u32, accessor: &gltf::Accessor) -> Result<(), String> {
        let attribute = self.attribute(semantic)?;
        let what = || {
            format!(
                "attribute {semantic} (Draco id {id}, accessor {})",
                accessor.index()
            )
        };
        if accessor.count() != self.point_count {
            return Err(format!(
                "{}: accessor count {} differs from the {} decoded points",
                what(),
                accessor.count(),
                self.point_count
            ));
        }
        let n = usize::from(attribute.num_components());
        if components(accessor.dimensions()) != Some(n) {
            return Err(format!(
                "{}: accessor type {:?} differs from the decoded {n} components",
                what(),
                accessor.dimensions()
            ));
        }
        let decoded_type = attribute.data_type();
        if gltf_type(decoded_type) != Some(accessor.data_type()) {
            return Err(format!(
                "{}: accessor componentType {:?} differs from the decoded {decoded_type:?}",
                what(),
                accessor.data_type()
            ));
        }
        Ok(())
    }

    /// Every point's value of `semantic` as `N` f32 components, normalized as the accessor's
    /// component type says when `normalized` (the decoded type equals it: see `check`).
    pub(crate) fn read<const N: usize>(
        &self,
        semantic: &str,
        normalized: bool,
    ) -> Result<Vec<[f32; N]>, String> {
        let attribute = self.attribute(semantic)?;
        let n = usize::from(attribute.num_components());
        if n != N {
            return Err(format!("has {n} components, expected {N}"));
        }
        let data_type = gltf_type(attribute.data_type()).ok_or_else(|| {
            format!(
                "decoded type {:?} is not a glTF type",
                attribute.data_type()
            )
        })?;
        let size = data_type.size();
        let stride = usize::try_from(attribute.byte_stride())
            .ok()
            .filter(|&s| s >= n * size)
            .ok_or_else(|| format!("decoded stride {} is too small", attribute.byte_stride()))?;
        let data = attribute.buffer().data();
        let mut out = Vec::new();
        out.try_reserve_exact(self.point_count)
            .map_err(|_| format!("cannot allocate {} points", self.point_count))?;
        for point in 0..self.point_count {
            let index = u32::try_from(point)
                .map_err(|_| format!("point {point} is past Draco's 32-bit point ids"))?;
            let value = attribute.mapped_index(draco_core::PointIndex(index)).0 as usize;
            let bytes = value
                .checked_mul(stride)
                .filter(|_| value < attribute.size())
                .and_then(|start| data.get(start..start.checked_add(n * size)?))
                .ok_or_else(|| {
                    format!("point {point} maps to value {value}, past the decoded values")
                })?;
            let mut element = [0.0; N];
            for (k, slot) in element.iter_mut().enumerate() {
                *slot = bytes
                    .get(k * size..)
                    .and_then(|b| attributes::component(b, data_type, normalized))
                    .ok_or_else(|| format!("point {point}: component {k} is missing"))?;
            }
            out.push(element);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn the_extension_object_is_parsed_and_checked() {
        let (view, attributes) =
            parse(&json!({"bufferView": 2, "attributes": {"POSITION": 0, "NORMAL": 1}})).unwrap();
        assert_eq!(view, 2);
        assert_eq!(attributes.len(), 2);
        assert!(parse(&json!({"attributes": {}})).is_err());
        assert!(parse(&json!({"bufferView": 0})).is_err());
        assert!(parse(&json!({"bufferView": 0, "attributes": {"POSITION": -1}})).is_err());
    }

    #[test]
    fn limits_follow_the_load_limits() {
        let l = limits(&LoadLimits {
            max_file_bytes: 1000,
            max_triangles: 10,
            max_image_pixels: 1,
        });
        assert_eq!(
            (l.max_faces, l.max_points, l.max_decoded_bytes),
            (10, 30, 1000)
        );
    }
}
