//! Reading a model file with every size checked before it is allocated: the format from the
//! first bytes (a 2 GB file of zeros is refused after 64 bytes, not read whole), a large GLB's
//! declared counts from its JSON before its binary chunk, then only the bytes its header
//! declares, into memory allocated fallibly (too little memory is an error, not an abort).

use super::error::{allocate, LoadError, LoadErrorKind};
use super::gltf_import::{self, DeferredImages};
use super::options::{Format, LoadOptions};
use std::io::{Read, Seek};
use std::path::Path;

/// Bytes read first to tell the format: GLB's magic and header, JSON's `{` after any
/// whitespace or byte-order mark.
const HEAD_BYTES: u64 = 64;

/// GLBs of this many bytes or more have the sizes their JSON declares checked before the rest
/// is read. A smaller file is read whole first: it cannot back a count that costs more than a
/// few times its size, and the importer checks the same counts before it allocates for them.
const EARLY_CHECK_MIN_BYTES: u64 = 16 << 20;

/// The bytes of the model at `path`, `len` bytes long by its metadata (a GLB: the bytes its
/// header declares, trailing bytes left unread), and the images a GLB left on disk.
pub(super) fn read_model(
    path: &Path,
    len: u64,
    options: &LoadOptions,
) -> Result<(Vec<u8>, Option<DeferredImages>), LoadError> {
    let err = |kind| LoadError::new(path, kind);
    let io = |e| err(LoadErrorKind::Io(e));
    let mut file = std::fs::File::open(path).map_err(io)?;
    let mut head = Vec::new();
    Read::by_ref(&mut file)
        .take(HEAD_BYTES)
        .read_to_end(&mut head)
        .map_err(io)?;
    if head.is_empty() {
        return Err(err(LoadErrorKind::EmptyFile));
    }
    let format = Format::sniff(path, &head).ok_or_else(|| err(LoadErrorKind::UnknownFormat))?;
    let len = match format {
        Format::Glb => glb_length(&head, len),
        _ => len,
    };
    if format == Format::Glb && len >= EARLY_CHECK_MIN_BYTES {
        check_glb_json(&mut file, &head, len, options).map_err(err)?;
    }
    file.rewind().map_err(io)?;
    if format == Format::Glb {
        // A GLB's images stay on disk until the texture phase reads them.
        if let Some((bytes, deferred)) =
            gltf_import::read_glb_deferring_images(&mut file, len).map_err(io)?
        {
            return Ok((bytes, Some(deferred)));
        }
        // From the start again, whatever the GLB reader had read.
        file.rewind().map_err(io)?;
    }
    let mut bytes = allocate(len, "the file's bytes").map_err(err)?;
    file.take(len).read_to_end(&mut bytes).map_err(io)?;
    Ok((bytes, None))
}

/// The length a GLB's header declares, when it is a version 2 header declaring a length
/// between the header's and the file's; otherwise `file_len` (the importer then says what is
/// wrong with the header).
fn glb_length(head: &[u8], file_len: u64) -> u64 {
    let word = |i: usize| {
        head.get(i..i + 4)
            .map(|b| u64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])))
    };
    match (word(4), word(8)) {
        (Some(2), Some(declared)) if (12..=file_len).contains(&declared) => declared,
        _ => file_len,
    }
}

/// Reads the JSON chunk of a GLB of `len` bytes whose first bytes are `head` and checks the
/// sizes it declares ([`gltf_import::check_declared_sizes`]). JSON that does not parse here is
/// left to the importer, which reports it.
fn check_glb_json(
    file: &mut std::fs::File,
    head: &[u8],
    len: u64,
    options: &LoadOptions,
) -> Result<(), LoadErrorKind> {
    let Some(chunk) = head.get(12..20) else {
        return Ok(());
    };
    let json_len = u64::from(u32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]));
    if &chunk[4..8] != b"JSON" || 20 + json_len > len {
        return Ok(());
    }
    file.seek(std::io::SeekFrom::Start(20))
        .map_err(LoadErrorKind::Io)?;
    let mut json = allocate(json_len, "the GLB's JSON chunk")?;
    Read::by_ref(file)
        .take(json_len)
        .read_to_end(&mut json)
        .map_err(LoadErrorKind::Io)?;
    match gltf::json::deserialize::from_slice::<gltf::json::Root>(&json) {
        Ok(root) => gltf_import::check_declared_sizes(&root, &options.limits),
        Err(_) => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Only a version 2 header declaring a length inside the file is believed.
    #[test]
    fn a_glb_is_read_to_the_length_its_header_declares() {
        let header = |version: u32, length: u32| {
            let mut h = b"glTF".to_vec();
            h.extend(version.to_le_bytes());
            h.extend(length.to_le_bytes());
            h
        };
        assert_eq!(glb_length(&header(2, 100), 120), 100);
        assert_eq!(glb_length(&header(2, 200), 120), 120, "past the end");
        assert_eq!(glb_length(&header(2, 4), 120), 120, "inside the header");
        assert_eq!(glb_length(&header(1, 100), 120), 120, "glTF 1");
        assert_eq!(glb_length(b"glTF", 120), 120, "no header");
    }

    #[test]
    fn an_allocation_too_large_is_an_error() {
        let err = allocate(u64::MAX, "the file's bytes").unwrap_err();
        assert_eq!(
            err.to_string(),
            format!(
                "not enough memory for the file's bytes ({} bytes)",
                u64::MAX
            )
        );
        assert!(allocate(1 << 60, "x").is_err(), "more than any machine has");
        assert_eq!(
            allocate(10, "x").map(|v| v.capacity() >= 10).ok(),
            Some(true)
        );
    }
}
