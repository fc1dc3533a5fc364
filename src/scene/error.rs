//! Load errors: every one names the file, and says where in it and what is wrong.

use std::fmt;
use std::path::{Path, PathBuf};

/// A failure to load a scene. Displays as `FILE: problem`.
#[derive(Debug, thiserror::Error)]
#[error("{}: {kind}", path.display())]
pub struct LoadError {
    /// The file the problem is in (the model, or the buffer/image/MTL it references).
    pub path: PathBuf,
    /// What went wrong.
    pub kind: LoadErrorKind,
}

impl LoadError {
    /// An error about `path`.
    pub fn new(path: &Path, kind: LoadErrorKind) -> Self {
        Self {
            path: path.to_path_buf(),
            kind,
        }
    }

    /// The file whose absence is the error, if that is what it is: the model itself, or a
    /// buffer or texture it refers to ([`LoadErrorKind::MissingFile`]). A caller can then
    /// tell a missing file from a broken one (the Python package raises `MissingFileError`,
    /// also a `FileNotFoundError`).
    pub fn missing_file(&self) -> Option<&Path> {
        match &self.kind {
            LoadErrorKind::Io(e) if e.kind() == std::io::ErrorKind::NotFound => Some(&self.path),
            LoadErrorKind::MissingFile { file, .. } => Some(file),
            _ => None,
        }
    }
}

/// Where in a glTF mesh a problem is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PrimitiveAt {
    /// Mesh index.
    pub mesh: usize,
    /// Primitive index within the mesh.
    pub primitive: usize,
}

impl fmt::Display for PrimitiveAt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "mesh {} primitive {}", self.mesh, self.primitive)
    }
}

/// What went wrong while loading.
#[derive(Debug, thiserror::Error)]
pub enum LoadErrorKind {
    /// Reading a file failed (missing, unreadable).
    #[error("{0}")]
    Io(#[source] std::io::Error),
    /// A file the model refers to (a buffer; a texture under `--strict`) does not exist:
    /// `problem` is the error about it, displayed as it is, and `file` the path looked for.
    #[error("{problem}")]
    MissingFile {
        /// The file looked for, resolved against the model's folder.
        file: PathBuf,
        /// The error, which names the file as the model gives it.
        problem: Box<LoadErrorKind>,
    },
    /// A directory was given where a file was expected.
    #[error("is a folder, not a file")]
    IsDirectory,
    /// Something other than a regular file (a FIFO, a device, a socket) where a file was
    /// expected: refused before it is opened, since reading one may never end (a FIFO) or
    /// never stop (`/dev/zero`).
    #[error("is {kind}, not a regular file")]
    NotARegularFile {
        /// What it is: "a FIFO", "a character device"...
        kind: &'static str,
    },
    /// The file is empty.
    #[error("file is empty (0 bytes)")]
    EmptyFile,
    /// A zip archive that cannot be unpacked, or does not hold exactly one model.
    #[error("zip archive: {0}")]
    Archive(String),
    /// A folder given as the model that does not hold exactly one model file.
    #[error("folder: {0}")]
    Folder(String),
    /// A file is larger than the configured limit.
    #[error("file is {bytes} bytes, over the limit of {limit} bytes")]
    FileTooLarge {
        /// Actual size.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// Neither GLB, glTF JSON nor OBJ.
    #[error("unknown format: not a GLB (no 'glTF' magic), not glTF JSON and not a .obj file")]
    UnknownFormat,
    /// The GLB container is malformed (bad header, truncated chunk...).
    #[error("malformed GLB container: {0}")]
    Glb(String),
    /// The JSON does not parse as glTF, or fails the glTF schema.
    #[error("invalid glTF: {0}")]
    Gltf(String),
    /// The file requires an extension meshtracer does not implement.
    #[error("requires extension {name}{what}, which meshtracer does not support")]
    UnsupportedExtension {
        /// Extension name.
        name: String,
        /// A short explanation of what it is, with a leading space and parentheses, or empty.
        what: String,
    },
    /// A buffer's data could not be found.
    #[error("buffer {buffer}: {problem}")]
    Buffer {
        /// Buffer index.
        buffer: usize,
        /// What is wrong.
        problem: String,
    },
    /// A buffer holds fewer bytes than the file declares.
    #[error("buffer {buffer}: expected {expected} bytes but found {actual}")]
    BufferTooShort {
        /// Buffer index.
        buffer: usize,
        /// Declared length.
        expected: usize,
        /// Available length.
        actual: usize,
    },
    /// A buffer view reaches past its buffer.
    #[error(
        "bufferView {view}: bytes {start}..{end} are past the end of buffer {buffer} ({len} bytes)"
    )]
    ViewOutOfRange {
        /// View index.
        view: usize,
        /// Buffer index.
        buffer: usize,
        /// First byte.
        start: usize,
        /// One past the last byte.
        end: usize,
        /// Buffer length.
        len: usize,
    },
    /// A meshopt-compressed buffer view cannot be decoded.
    #[error("bufferView {view} ({extension}): {problem}")]
    Meshopt {
        /// View index.
        view: usize,
        /// `EXT_meshopt_compression` or `KHR_meshopt_compression`.
        extension: String,
        /// What is wrong.
        problem: String,
    },
    /// A `KHR_draco_mesh_compression` primitive cannot be decoded, or its decoded data does not
    /// match its accessors.
    #[error("{at} (KHR_draco_mesh_compression): {problem}")]
    Draco {
        /// Where.
        at: PrimitiveAt,
        /// What is wrong.
        problem: String,
    },
    /// An accessor is inconsistent with its buffer view or its use.
    #[error("{at}: accessor {accessor} ({semantic}): {problem}")]
    Accessor {
        /// Where it is used.
        at: PrimitiveAt,
        /// Accessor index.
        accessor: usize,
        /// Attribute name, or `indices`.
        semantic: String,
        /// What is wrong.
        problem: String,
    },
    /// An index points past the vertex count.
    #[error("{at}: index {index} is out of range for {vertex_count} vertices")]
    IndexOutOfRange {
        /// Where.
        at: PrimitiveAt,
        /// The bad index value.
        index: u32,
        /// Number of vertices.
        vertex_count: usize,
    },
    /// A primitive has no POSITION attribute.
    #[error("{at}: has no POSITION attribute")]
    MissingPositions {
        /// Where.
        at: PrimitiveAt,
    },
    /// `--variant` names no variant of the file, or a variant mapping is broken.
    #[error("KHR_materials_variants: {0}")]
    Variant(String),
    /// `--animation`/`--time` cannot be honoured, or the chosen animation is broken.
    #[error("animation: {0}")]
    Animation(String),
    /// A skin cannot be applied (bad inverse bind matrices, joints, or skinning attributes).
    #[error("skin {skin}: {problem}")]
    Skin {
        /// Skin index.
        skin: usize,
        /// What is wrong.
        problem: String,
    },
    /// An image reference is broken.
    #[error("image {image}: {problem}")]
    Image {
        /// Image index.
        image: usize,
        /// What is wrong.
        problem: String,
    },
    /// A URI that names no file: an empty one, or one naming a FIFO or a device (refused
    /// before it is opened, as [`LoadErrorKind::NotARegularFile`] is).
    #[error("{what} URI '{uri}' {problem}")]
    BadUri {
        /// The referencing object (`buffer 0`, `image 2`).
        what: String,
        /// The URI as the file gives it.
        uri: String,
        /// What is wrong with it.
        problem: String,
    },
    /// A URI points outside the model's folder.
    #[error("{what} URI '{uri}' points outside the model's folder; pass --allow-external-files to read it")]
    ExternalFile {
        /// What references it (`buffer 0`, `image 2`, `mtllib`).
        what: String,
        /// The URI as written.
        uri: String,
    },
    /// A `data:` URI is malformed.
    #[error("{what}: bad data URI: {problem}")]
    DataUri {
        /// What references it.
        what: String,
        /// What is wrong.
        problem: String,
    },
    /// A node's `EXT_mesh_gpu_instancing` cannot be read.
    #[error("node {node}: EXT_mesh_gpu_instancing: {problem}")]
    Instancing {
        /// The node.
        node: usize,
        /// What is wrong.
        problem: String,
    },
    /// The node hierarchy has a cycle.
    #[error("node {node} is its own ancestor (the node hierarchy has a cycle)")]
    NodeCycle {
        /// A node on the cycle.
        node: usize,
    },
    /// The scene to render does not exist or holds no triangle.
    #[error("the scene has no triangles to render{0}")]
    NoTriangles(String),
    /// A reference between parts of the loaded scene points past the end of its list (an
    /// importer bug or a file that slipped past its checks): refused once at load, so the
    /// renderer can index without checking.
    #[error("{what} {index} is out of range for {count} entries")]
    BadReference {
        /// What refers to what (`triangle material`, `material texture`, `texture image`).
        what: &'static str,
        /// The bad index.
        index: usize,
        /// The length of the list it indexes.
        count: usize,
    },
    /// The glTF file is valid but places nothing in the world: it has no scene, or its scene
    /// has no nodes.
    #[error("nothing to draw: {0}")]
    NothingToDraw(String),
    /// More triangles than the limit allows.
    #[error("the scene has {count} triangles, over the limit of {limit} (raise it with --max-triangles)")]
    TooManyTriangles {
        /// Triangles counted so far.
        count: u64,
        /// The limit.
        limit: u64,
    },
    /// A count the file declares is over a limit: refused before anything of that size is
    /// allocated or read.
    #[error(
        "{what} declares {count} {unit}, over the limit of {limit} (raise it with --max-triangles)"
    )]
    DeclaredTooMany {
        /// Where: `mesh 0 primitive 1`.
        what: String,
        /// The declared count.
        count: u64,
        /// `vertices` or `triangles`.
        unit: &'static str,
        /// The limit.
        limit: u64,
    },
    /// Memory for something the file needs could not be allocated: reported instead of
    /// aborting the process.
    #[error("not enough memory for {what} ({bytes} bytes)")]
    OutOfMemory {
        /// What the memory was for: `the file's bytes`, `the triangle soup`.
        what: String,
        /// Bytes asked for.
        bytes: u64,
    },
    /// OBJ parse failure.
    #[error("OBJ: {0}")]
    Obj(String),
    /// OBJ face index past the vertex list.
    #[error(
        "OBJ: model {model} ('{name}'): {what} index {index} is out of range for {count} entries"
    )]
    ObjIndexOutOfRange {
        /// Model index.
        model: usize,
        /// Model name.
        name: String,
        /// `position`, `normal` or `texcoord`.
        what: &'static str,
        /// The bad index (0-based).
        index: u32,
        /// Number of entries.
        count: usize,
    },
    /// A material library cannot be read.
    #[error("MTL '{mtl}': {problem}")]
    Mtl {
        /// The MTL path as written.
        mtl: String,
        /// What is wrong.
        problem: String,
    },
}

impl LoadErrorKind {
    /// `NoTriangles` with no detail.
    pub fn no_triangles() -> Self {
        LoadErrorKind::NoTriangles(String::new())
    }
}

/// An empty vector with room for `bytes` bytes, or [`LoadErrorKind::OutOfMemory`] naming
/// `what` when the allocator refuses (under `ulimit -v`, or a container's memory limit).
pub(super) fn allocate(bytes: u64, what: &str) -> Result<Vec<u8>, LoadErrorKind> {
    let out_of_memory = || LoadErrorKind::OutOfMemory {
        what: what.to_string(),
        bytes,
    };
    let size = usize::try_from(bytes).map_err(|_| out_of_memory())?;
    let mut out = Vec::new();
    out.try_reserve_exact(size).map_err(|_| out_of_memory())?;
    Ok(out)
}

/// The message a caught panic carries (`panic!("...")` with or without formatting), or
/// "unknown panic". A panic inside an importer is a bug; the CLI and the Python package catch
/// it around the load and report it as an error naming the file with this message.
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> &str {
    payload
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| payload.downcast_ref::<&str>().copied())
        .unwrap_or("unknown panic")
}

thread_local! {
    /// Whether a panic on this thread is being caught by [`catch_quietly`], which reports it
    /// itself.
    static CATCHING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// An `image` crate error in words for the user: a format it does not read and a file that
/// ends early said plainly (the crate's own texts are "The file extension `.\"gltf\"` was
/// not recognized as an image format" and "failed to fill whole buffer"), anything else as
/// the crate says it.
pub fn image_error_text(error: &image::ImageError) -> String {
    use image::error::{ImageError, UnsupportedErrorKind};
    match error {
        ImageError::Unsupported(u) if matches!(u.kind(), UnsupportedErrorKind::Format(_)) => {
            "not an image in a format meshtracer reads".to_string()
        }
        ImageError::IoError(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
            "the file ends early (empty or cut short)".to_string()
        }
        other => other.to_string(),
    }
}

/// Runs `f` on this thread and returns what it returns, or the message of a panic inside it.
/// The panic hook stays silent for that panic (the caller makes it one error or warning among
/// its own); panics elsewhere, and on other threads, still reach the hook there was. For
/// third-party code reading hostile bytes (the image decoders), where a panic is a bug to
/// report but must not end the process.
///
/// The first call wraps the process's panic hook in one that asks this thread's flag first;
/// a hook set later replaces the wrapper, and then such panics are caught but not silenced.
pub fn catch_quietly<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    static WRAPPED: std::sync::Once = std::sync::Once::new();
    WRAPPED.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !CATCHING.with(std::cell::Cell::get) {
                previous(info);
            }
        }));
    });
    let outer = CATCHING.with(|c| c.replace(true));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    CATCHING.with(|c| c.set(outer));
    result.map_err(|panic| panic_message(panic.as_ref()).to_string())
}

#[cfg(test)]
mod panic_tests {
    use super::{catch_quietly, image_error_text, panic_message};

    #[test]
    fn a_panic_caught_quietly_is_its_message() {
        assert_eq!(catch_quietly(|| 7), Ok(7));
        assert_eq!(
            catch_quietly(|| -> u8 { panic!("decoder {}", 3) }),
            Err("decoder 3".to_string())
        );
        // Nested: the inner catch restores the outer one's flag.
        let nested = catch_quietly(|| {
            let inner = catch_quietly(|| -> u8 { panic!("inner") });
            assert_eq!(inner, Err("inner".to_string()));
            panic!("outer")
        });
        assert_eq!(nested, Err::<(), _>("outer".to_string()));
    }

    #[test]
    fn a_panics_message_is_read_from_either_payload() {
        let formatted = std::panic::catch_unwind(|| panic!("bad {}", 7)).unwrap_err();
        let plain = std::panic::catch_unwind(|| panic!("plain")).unwrap_err();
        let other = std::panic::catch_unwind(|| std::panic::panic_any(7u8)).unwrap_err();
        assert_eq!(panic_message(formatted.as_ref()), "bad 7");
        assert_eq!(panic_message(plain.as_ref()), "plain");
        assert_eq!(panic_message(other.as_ref()), "unknown panic");
    }

    /// The image crate's texts for an unknown format and a short file are said plainly.
    #[test]
    fn image_errors_are_said_plainly() {
        let unknown = image::load_from_memory(b"{\"asset\": {}}").unwrap_err();
        assert_eq!(
            image_error_text(&unknown),
            "not an image in a format meshtracer reads"
        );
        let short = image::ImageError::IoError(std::io::ErrorKind::UnexpectedEof.into());
        assert_eq!(
            image_error_text(&short),
            "the file ends early (empty or cut short)"
        );
    }
}
