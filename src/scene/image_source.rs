//! Where an image's encoded bytes are: a file, a range of the model's file, or memory shared
//! with it; or, for an image handed over as pixels ([`Scene::add_texture`]), the pixels.
//!
//! [`Scene::add_texture`]: super::model::Scene::add_texture

use serde::Serialize;
use std::path::{Path, PathBuf};

/// Where an image's encoded bytes come from. Images are decoded by the renderer when it needs
/// them, not at load time, so `info` stays fast.
#[derive(Clone, Debug, Serialize)]
pub struct ImageSource {
    /// What the file says: a URI, `data:` URI (abbreviated) or `bufferView N`.
    pub origin: String,
    /// MIME type, if the file states it.
    pub mime_type: Option<String>,
    /// The resolved file, for external images.
    pub path: Option<PathBuf>,
    /// The encoded bytes, for embedded images (GLB buffer views and `data:` URIs).
    #[serde(skip)]
    pub bytes: Option<SharedBytes>,
    /// For an image embedded in a GLB that the load did not read ([`Scene::load_with`] leaves
    /// a GLB's image-only buffer views on disk): the file and the byte range that hold it,
    /// read when the image is decoded.
    ///
    /// [`Scene::load_with`]: super::model::Scene::load_with
    #[serde(skip)]
    pub in_file: Option<FileRange>,
    /// For an image given as pixels rather than a file ([`Scene::add_texture`]): them, RGBA8,
    /// rows from the top.
    ///
    /// [`Scene::add_texture`]: super::model::Scene::add_texture
    #[serde(skip)]
    pub pixels: Option<std::sync::Arc<image::RgbaImage>>,
}

/// A byte range of a file.
#[derive(Clone, Debug)]
pub struct FileRange {
    /// The file.
    pub path: PathBuf,
    /// The bytes, as offsets from its start.
    pub range: std::ops::Range<u64>,
}

impl FileRange {
    /// Reads at most `limit` bytes from the start of the range (all of it for `u64::MAX`);
    /// a file that no longer holds the range is an error naming it.
    pub fn read(&self, limit: u64) -> Result<Vec<u8>, String> {
        use std::io::{Read, Seek, SeekFrom};
        let len = (self.range.end - self.range.start).min(limit);
        let fail = |e: std::io::Error| format!("'{}': {e}", self.path.display());
        let mut file = std::fs::File::open(&self.path).map_err(fail)?;
        file.seek(SeekFrom::Start(self.range.start)).map_err(fail)?;
        let mut out = Vec::with_capacity(len as usize);
        file.take(len).read_to_end(&mut out).map_err(fail)?;
        if (out.len() as u64) < len {
            return Err(format!(
                "'{}' ends inside bytes {}..{} (changed since it was loaded?)",
                self.path.display(),
                self.range.start,
                self.range.end
            ));
        }
        Ok(out)
    }
}

/// Where an image's encoded bytes are, as [`ImageSource::encoded`] tells.
pub enum Encoded<'a> {
    /// Not encoded: the pixels themselves (shared: decoding hands over the same buffer).
    Pixels(&'a std::sync::Arc<image::RgbaImage>),
    /// In memory.
    Bytes(&'a [u8]),
    /// A whole image file.
    File(&'a Path),
    /// A range of the model's file (a GLB), not read yet.
    InFile(&'a FileRange),
    /// Nowhere (a source the importer could not resolve).
    Missing,
}

impl ImageSource {
    /// Where the encoded bytes are.
    pub fn encoded(&self) -> Encoded<'_> {
        if let Some(pixels) = &self.pixels {
            return Encoded::Pixels(pixels);
        }
        match (&self.bytes, &self.in_file, &self.path) {
            (Some(bytes), _, _) => Encoded::Bytes(bytes),
            (None, Some(range), _) => Encoded::InFile(range),
            (None, None, Some(path)) => Encoded::File(path),
            (None, None, None) => Encoded::Missing,
        }
    }
}

/// Bytes shared without copying: a range of a buffer that others hold too. An image embedded
/// in a GLB is a range of the file as read, so its JPEG or PNG is not copied out of it
/// (DamagedHelmet's GLB: 3.2 MB copied, and page-faulted in, on every load).
#[derive(Clone)]
pub struct SharedBytes {
    data: std::sync::Arc<Vec<u8>>,
    range: std::ops::Range<usize>,
}

impl SharedBytes {
    /// All of `data`.
    pub fn whole(data: Vec<u8>) -> SharedBytes {
        let range = 0..data.len();
        SharedBytes {
            data: std::sync::Arc::new(data),
            range,
        }
    }

    /// `part` without copying it where it is a sub-slice of `file`; else a copy of it.
    pub fn within(file: Option<&std::sync::Arc<Vec<u8>>>, part: &[u8]) -> SharedBytes {
        if let Some(file) = file {
            // Addresses compared, not dereferenced: `part` lies inside `file` or it does not.
            let base = file.as_ptr() as usize;
            let start = (part.as_ptr() as usize).wrapping_sub(base);
            if start <= file.len() && part.len() <= file.len() - start {
                return SharedBytes {
                    data: std::sync::Arc::clone(file),
                    range: start..start + part.len(),
                };
            }
        }
        SharedBytes::whole(part.to_vec())
    }

    /// How many bytes this keeps alive: its own length for a copy, the whole buffer's for a
    /// range of a shared one (a GLB's file).
    pub fn held(&self) -> usize {
        self.data.len()
    }
}

impl std::ops::Deref for SharedBytes {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        // The range was checked against this very buffer when it was made.
        self.data.get(self.range.clone()).unwrap_or_default()
    }
}

impl std::fmt::Debug for SharedBytes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SharedBytes({} bytes)", self.range.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A part of the file is shared, not copied; anything else is copied; either way the bytes
    /// are the same.
    #[test]
    fn shared_bytes_share_a_part_of_the_file_and_copy_the_rest() {
        let file = std::sync::Arc::new((0u8..=255).collect::<Vec<u8>>());
        let part = &file[10..20];
        let shared = SharedBytes::within(Some(&file), part);
        assert_eq!(&shared[..], part);
        assert_eq!(
            shared.as_ptr(),
            part.as_ptr(),
            "a range of the file, not a copy"
        );
        assert_eq!(std::sync::Arc::strong_count(&file), 2);
        assert_eq!(shared.held(), 256, "the file is what it keeps alive");
        // Empty parts, and the file's last byte.
        assert_eq!(&SharedBytes::within(Some(&file), &file[256..])[..], b"");
        assert_eq!(&SharedBytes::within(Some(&file), &file[255..])[..], [255]);
        // Bytes from elsewhere (a decoded buffer, a data: URI) are copied.
        let other = vec![7u8; 5];
        let copied = SharedBytes::within(Some(&file), &other);
        assert_eq!(&copied[..], &other[..]);
        assert_ne!(copied.as_ptr(), other.as_ptr());
        assert_eq!(copied.held(), 5);
        assert_eq!(&SharedBytes::within(None, part)[..], part);
        assert_eq!(format!("{copied:?}"), "SharedBytes(5 bytes)");
    }
}
