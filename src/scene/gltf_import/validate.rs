//! What the `gltf` crate would index blindly, checked first: accessor and image references
//! in the JSON before its validation runs, buffer views against their buffers, and each
//! accessor's type and byte range against what its use allows (glTF 2.0 §3.6, §3.7.2.1,
//! `KHR_mesh_quantization`), so that a hostile file gets an error instead of a panic.

use super::buffer::Buffer;
use crate::scene::error::{LoadErrorKind, PrimitiveAt};
use gltf::accessor::{DataType, Dimensions};

/// What the `gltf` crate assumes but does not validate (both found by fuzzing): gltf-json 1.4's
/// validation indexes `accessors[POSITION]` before checking that the index exists, and
/// `Image::source` unwraps `mimeType` (required with `bufferView`) and `uri` (required without).
pub(super) fn check_attribute_indices(root: &gltf::json::Root) -> Result<(), LoadErrorKind> {
    for (index, image) in root.images.iter().enumerate() {
        let problem = match (&image.buffer_view, &image.mime_type, &image.uri) {
            (Some(_), None, _) => "has a bufferView but no mimeType",
            (None, _, None) => "has neither a uri nor a bufferView",
            _ => continue,
        };
        return Err(LoadErrorKind::Image {
            image: index,
            problem: problem.to_string(),
        });
    }
    let count = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let referenced = primitive
                .attributes
                .values()
                .chain(primitive.indices.iter())
                .map(|i| i.value());
            for index in referenced {
                if index >= count {
                    return Err(LoadErrorKind::Gltf(format!(
                        "meshes[{m}].primitives[{p}] refers to accessor {index}, but the file has {count}"
                    )));
                }
            }
        }
    }
    Ok(())
}

/// The `gltf` crate's validation, except for what glTF 2.0 allows and gltf-json 1.4 refuses:
/// an accessor without a `bufferView` (§3.6.2.3: its elements are zeros, replaced by its sparse
/// values if it has any; also the accessors of `KHR_draco_mesh_compression` primitives, whose
/// data is the decoded stream) and a primitive without POSITION (§3.7.2.1 only says that
/// without it the primitive is not drawn: the node walk skips it with a warning).
pub(super) fn validate(root: gltf::json::Root) -> Result<gltf::Document, gltf::Error> {
    use gltf::json::validation::{Error, Validate};
    let allowed_missing = |path: &str| {
        let accessor_view = path
            .strip_prefix("accessors[")
            .and_then(|rest| rest.split_once(']'))
            .is_some_and(|(index, field)| {
                field == ".bufferView" && index.bytes().all(|b| b.is_ascii_digit())
            });
        accessor_view
            || (path.starts_with("meshes[") && path.ends_with(".attributes[\"POSITION\"]"))
    };
    let mut errors = Vec::new();
    root.validate(&root, gltf::json::Path::new, &mut |path, error| {
        let path = path();
        if !(matches!(error, Error::Missing) && allowed_missing(path.as_str())) {
            errors.push((path, error));
        }
    });
    if errors.is_empty() {
        Ok(gltf::Document::from_json_without_validation(root))
    } else {
        Err(gltf::Error::Validation(errors))
    }
}

pub(super) fn check_views(
    document: &gltf::Document,
    buffers: &[Buffer],
) -> Result<(), LoadErrorKind> {
    for view in document.views() {
        let buffer = view.buffer().index();
        let len = buffers.get(buffer).map_or(0, |b| b.len());
        let start = view.offset();
        let end = start.saturating_add(view.length());
        if end > len {
            return Err(LoadErrorKind::ViewOutOfRange {
                view: view.index(),
                buffer,
                start,
                end,
                len,
            });
        }
    }
    Ok(())
}

/// Whether an integer accessor must, may or must not be `normalized`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Normalized {
    Yes,
    No,
    Either,
}

/// What an attribute accessor may be: glTF 2.0 §3.7.2.1 (table "Attributes"), plus what
/// `KHR_mesh_quantization` allows when the file declares it.
pub(super) struct Expect {
    pub(super) semantic: &'static str,
    dims: &'static [Dimensions],
    types: &'static [(DataType, Normalized)],
    quantized: &'static [(DataType, Normalized)],
}

const FLOAT: &[(DataType, Normalized)] = &[(DataType::F32, Normalized::No)];

/// KHR_mesh_quantization: unit vectors as normalized signed bytes or shorts.
const UNIT_VECTORS: &[(DataType, Normalized)] = &[
    (DataType::I8, Normalized::Yes),
    (DataType::I16, Normalized::Yes),
];

/// Core TEXCOORD_n and COLOR_n: float, or normalized unsigned bytes or shorts.
const FLOAT_OR_UNORM: &[(DataType, Normalized)] = &[
    (DataType::F32, Normalized::No),
    (DataType::U8, Normalized::Yes),
    (DataType::U16, Normalized::Yes),
];

pub(super) const POSITION: Expect = Expect {
    semantic: "POSITION",
    dims: &[Dimensions::Vec3],
    types: FLOAT,
    quantized: &[
        (DataType::I8, Normalized::Either),
        (DataType::U8, Normalized::Either),
        (DataType::I16, Normalized::Either),
        (DataType::U16, Normalized::Either),
    ],
};

pub(super) const NORMAL: Expect = Expect {
    semantic: "NORMAL",
    dims: &[Dimensions::Vec3],
    types: FLOAT,
    quantized: UNIT_VECTORS,
};

pub(super) const TANGENT: Expect = Expect {
    semantic: "TANGENT",
    dims: &[Dimensions::Vec4],
    types: FLOAT,
    quantized: UNIT_VECTORS,
};

pub(super) const TEXCOORD: Expect = Expect {
    semantic: "TEXCOORD",
    dims: &[Dimensions::Vec2],
    types: FLOAT_OR_UNORM,
    quantized: &[
        (DataType::I8, Normalized::Either),
        (DataType::U8, Normalized::No),
        (DataType::I16, Normalized::Either),
        (DataType::U16, Normalized::No),
    ],
};

pub(super) const COLOR: Expect = Expect {
    semantic: "COLOR_0",
    dims: &[Dimensions::Vec3, Dimensions::Vec4],
    types: FLOAT_OR_UNORM,
    quantized: &[],
};

/// glTF 2.0 §3.7.3: JOINTS_n are unsigned byte or short joint indices, WEIGHTS_n float or
/// normalized unsigned byte or short.
pub(super) const JOINTS: Expect = Expect {
    semantic: "JOINTS_n",
    dims: &[Dimensions::Vec4],
    types: &[
        (DataType::U8, Normalized::No),
        (DataType::U16, Normalized::No),
    ],
    quantized: &[],
};

pub(super) const WEIGHTS: Expect = Expect {
    semantic: "WEIGHTS_n",
    dims: &[Dimensions::Vec4],
    types: FLOAT_OR_UNORM,
    quantized: &[],
};

/// §3.7.2.2: morph target deltas are float; `KHR_mesh_quantization` adds (normalized) signed
/// bytes and shorts for POSITION, normalized ones for NORMAL and TANGENT.
pub(super) const MORPH_POSITION: Expect = Expect {
    semantic: "POSITION",
    dims: &[Dimensions::Vec3],
    types: FLOAT,
    quantized: &[
        (DataType::I8, Normalized::Either),
        (DataType::I16, Normalized::Either),
    ],
};

pub(super) const MORPH_NORMAL: Expect = Expect {
    semantic: "NORMAL",
    dims: &[Dimensions::Vec3],
    types: FLOAT,
    quantized: UNIT_VECTORS,
};

pub(super) const MORPH_TANGENT: Expect = Expect {
    semantic: "TANGENT",
    dims: &[Dimensions::Vec3],
    types: FLOAT,
    quantized: UNIT_VECTORS,
};

pub(super) const INDICES: Expect = Expect {
    semantic: "indices",
    dims: &[Dimensions::Scalar],
    types: &[
        (DataType::U8, Normalized::Either),
        (DataType::U16, Normalized::Either),
        (DataType::U32, Normalized::Either),
    ],
    quantized: &[],
};

impl Expect {
    /// Whether integer components are read as normalized: as the file says, except that
    /// COLOR_n is always normalized and, without `KHR_mesh_quantization`, so is TEXCOORD_n
    /// (core glTF allows nothing else, and files that forgot the flag meant it; the `gltf`
    /// crate read them so before us).
    pub(super) fn reads_normalized(&self, normalized: bool, quantization: bool) -> bool {
        normalized || self.semantic == "COLOR_0" || (self.semantic == "TEXCOORD" && !quantization)
    }

    /// Whether `data_type` read with that normalization is allowed (a float's flag is ignored).
    fn allows(&self, data_type: DataType, normalized: bool, quantization: bool) -> bool {
        let fits = |&(t, n): &(DataType, Normalized)| {
            t == data_type
                && (t == DataType::F32
                    || match n {
                        Normalized::Yes => normalized,
                        Normalized::No => !normalized,
                        Normalized::Either => true,
                    })
        };
        self.types.iter().any(fits) || (quantization && self.quantized.iter().any(fits))
    }
}

/// Checks that every byte the `gltf` crate's reader will touch for this accessor exists, and
/// that its type is what the semantic allows. After this the reader cannot panic or read junk.
pub(super) fn check_accessor(
    accessor: &gltf::Accessor,
    at: PrimitiveAt,
    expect: &Expect,
    quantization: bool,
) -> Result<(), LoadErrorKind> {
    check_accessor_type(accessor, at, expect, quantization)?;
    let fail = accessor_error(at, accessor, expect);
    let element = accessor.size();
    match accessor.view() {
        Some(view) => check_range(&view, accessor.offset(), accessor.count(), element)
            .map_err(|p| fail(format!("bufferView {}: {p}", view.index())))?,
        // §3.6.2.3: zeros (then the sparse values, if any), which no byte of the file bounds.
        None => {
            let bytes = accessor.count().saturating_mul(element) as u64;
            if bytes > MAX_ZERO_ACCESSOR_BYTES {
                return Err(fail(format!(
                    "has no bufferView and {} elements of {element} bytes: {bytes} bytes of zeros, over the limit of {MAX_ZERO_ACCESSOR_BYTES}",
                    accessor.count()
                )));
            }
        }
    }
    if let Some(sparse) = accessor.sparse() {
        let count = sparse.count();
        if count == 0 || count > accessor.count() {
            return Err(fail(format!(
                "sparse count {count} is not in 1..={}",
                accessor.count()
            )));
        }
        let indices = sparse.indices();
        let index_size = indices.index_type().size();
        check_range(&indices.view(), indices.offset(), count, index_size)
            .map_err(|p| fail(format!("sparse indices: {p}")))?;
        let values = sparse.values();
        check_range(&values.view(), values.offset(), count, element)
            .map_err(|p| fail(format!("sparse values: {p}")))?;
    }
    Ok(())
}

/// The error for a problem with `accessor`, read as `expect.semantic` of the primitive `at`.
pub(super) fn accessor_error<'a>(
    at: PrimitiveAt,
    accessor: &'a gltf::Accessor,
    expect: &'a Expect,
) -> impl Fn(String) -> LoadErrorKind + 'a {
    move |problem| LoadErrorKind::Accessor {
        at,
        accessor: accessor.index(),
        semantic: expect.semantic.to_string(),
        problem,
    }
}

/// Checks that an accessor's type is what the semantic allows and that it is not empty; for
/// accessors whose data is decoded elsewhere (Draco), this is all that is checked of them.
pub(super) fn check_accessor_type(
    accessor: &gltf::Accessor,
    at: PrimitiveAt,
    expect: &Expect,
    quantization: bool,
) -> Result<(), LoadErrorKind> {
    let fail = accessor_error(at, accessor, expect);
    let normalized = expect.reads_normalized(accessor.normalized(), quantization);
    if !expect.dims.contains(&accessor.dimensions())
        || !expect.allows(accessor.data_type(), normalized, quantization)
    {
        let list = |types: &[(DataType, Normalized)]| {
            types
                .iter()
                .map(|(t, n)| match n {
                    _ if *t == DataType::F32 => format!("{t:?}"),
                    Normalized::Yes => format!("normalized {t:?}"),
                    Normalized::No => format!("{t:?}"),
                    Normalized::Either => format!("{t:?} (normalized or not)"),
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        let mut expected = format!("{:?} of {}", expect.dims, list(expect.types));
        if !expect.quantized.is_empty() {
            expected += &format!(
                "; with KHR_mesh_quantization{} also {}",
                if quantization { "" } else { " (not declared)" },
                list(expect.quantized)
            );
        }
        return Err(fail(format!(
            "type {:?} of {}{:?} is not allowed here (expected {expected})",
            accessor.dimensions(),
            if accessor.normalized() {
                "normalized "
            } else {
                ""
            },
            accessor.data_type(),
        )));
    }
    if accessor.count() == 0 {
        return Err(fail("count is 0".to_string()));
    }
    Ok(())
}

/// Most bytes an accessor without a bufferView may stand for: its zeros come from no byte of
/// the file, so a few bytes of JSON could otherwise ask for any amount of memory. As much as
/// a buffer within the default file limit (2 GiB) could hold.
const MAX_ZERO_ACCESSOR_BYTES: u64 = 2 << 30;

/// `count` elements of `element` bytes from `offset` in `view`, at the view's stride.
fn check_range(
    view: &gltf::buffer::View,
    offset: usize,
    count: usize,
    element: usize,
) -> Result<(), String> {
    let stride = view.stride().unwrap_or(element);
    if stride < element {
        return Err(format!(
            "byteStride {stride} is smaller than the element size {element}"
        ));
    }
    let end = stride
        .checked_mul(count - 1)
        .and_then(|v| v.checked_add(element))
        .and_then(|v| v.checked_add(offset));
    match end {
        Some(end) if end <= view.length() => Ok(()),
        _ => Err(format!(
            "{count} elements of {element} bytes (stride {stride}) from offset {offset} do not fit its {} bytes",
            view.length()
        )),
    }
}
