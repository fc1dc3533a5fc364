//! The sizes a glTF file declares, checked against the load limits before anything of that
//! size is read or allocated: a GLB of 2 GB declaring 170 million vertices is refused from its
//! JSON, in milliseconds, instead of after reading the file and its accessors.

use crate::scene::error::LoadErrorKind;
use crate::scene::options::LoadLimits;
use gltf::json::mesh::Mode;
use gltf::json::validation::Checked;

/// Refuses a primitive declaring more vertices than [`LoadLimits::max_vertices`] or more
/// triangles than [`LoadLimits::max_triangles`] (counted from its indices, else its positions,
/// by its mode), and a buffer declaring more bytes than [`LoadLimits::max_file_bytes`].
/// References out of range and POINTS/LINES primitives are left to the checks that follow
/// (they are reported, or skipped, there). Each primitive is counted once: the soup builder
/// counts instances as it grows.
pub(crate) fn check_declared_sizes(
    root: &gltf::json::Root,
    limits: &LoadLimits,
) -> Result<(), LoadErrorKind> {
    for (index, buffer) in root.buffers.iter().enumerate() {
        let bytes = buffer.byte_length.0;
        if bytes > limits.max_file_bytes {
            return Err(LoadErrorKind::Buffer {
                buffer: index,
                problem: format!(
                    "declares {bytes} bytes, over the limit of {} bytes",
                    limits.max_file_bytes
                ),
            });
        }
    }
    let count = |index: usize| root.accessors.get(index).map(|a| a.count.0);
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let too_many = |count, unit, limit| LoadErrorKind::DeclaredTooMany {
                what: format!("mesh {m} primitive {p}"),
                count,
                unit,
                limit,
            };
            let positions = primitive
                .attributes
                .get(&Checked::Valid(gltf::Semantic::Positions))
                .and_then(|i| count(i.value()));
            if let Some(vertices) = positions.filter(|&n| n > limits.max_vertices()) {
                return Err(too_many(vertices, "vertices", limits.max_vertices()));
            }
            let corners = match &primitive.indices {
                Some(i) => count(i.value()),
                None => positions,
            };
            let triangles = match (&primitive.mode, corners) {
                (Checked::Valid(Mode::Triangles), Some(n)) => n / 3,
                (Checked::Valid(Mode::TriangleStrip | Mode::TriangleFan), Some(n)) => {
                    n.saturating_sub(2)
                }
                _ => 0,
            };
            if triangles > limits.max_triangles {
                return Err(too_many(triangles, "triangles", limits.max_triangles));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn root(json: serde_json::Value) -> gltf::json::Root {
        serde_json::from_value(json).expect("a glTF root")
    }

    fn file(count: u64, indices: Option<u64>, mode: u32) -> gltf::json::Root {
        let mut primitive = serde_json::json!({"attributes": {"POSITION": 0}, "mode": mode});
        let mut accessors = vec![serde_json::json!(
            {"componentType": 5126, "count": count, "type": "VEC3"})];
        if let Some(n) = indices {
            primitive["indices"] = serde_json::json!(1);
            accessors
                .push(serde_json::json!({"componentType": 5125, "count": n, "type": "SCALAR"}));
        }
        root(serde_json::json!({
            "asset": {"version": "2.0"},
            "meshes": [{"primitives": [primitive]}],
            "accessors": accessors,
            "buffers": [{"byteLength": 100}]
        }))
    }

    /// The limits are 10 triangles and so 30 vertices: each count is refused one past its
    /// limit, naming the primitive, and accepted at it; POINTS are not counted.
    #[test]
    fn declared_counts_are_held_to_the_limits() {
        let limits = LoadLimits {
            max_triangles: 10,
            max_file_bytes: 1000,
            ..LoadLimits::default()
        };
        let check = |root: gltf::json::Root| check_declared_sizes(&root, &limits);
        assert!(check(file(30, None, 4)).is_ok());
        let err = check(file(31, Some(3), 4)).unwrap_err().to_string();
        assert_eq!(
            err,
            "mesh 0 primitive 0 declares 31 vertices, over the limit of 30 (raise it with --max-triangles)"
        );
        assert!(check(file(12, Some(30), 4)).is_ok());
        let err = check(file(12, Some(33), 4)).unwrap_err().to_string();
        assert!(err.contains("declares 11 triangles"), "{err}");
        let err = check(file(12, Some(13), 5)).unwrap_err().to_string();
        assert!(err.contains("declares 11 triangles"), "strip: {err}");
        assert!(check(file(30, Some(u64::MAX), 0)).is_ok(), "points");
        let mut big = file(3, None, 4);
        big.buffers[0].byte_length = 1001u64.into();
        let err = check(big).unwrap_err().to_string();
        assert!(
            err.contains("buffer 0") && err.contains("1001 bytes"),
            "{err}"
        );
    }
}
