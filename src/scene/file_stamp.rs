//! A file as it was on disk, to tell later whether it changed: what a cache of something made
//! from a file (decoded textures, a loaded panorama) compares before it reuses it.

use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// A file's path, length and modification time.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FileStamp {
    /// The path, as given.
    pub path: PathBuf,
    /// Length in bytes.
    pub len: u64,
    /// Modification time, where the filesystem keeps one.
    pub modified: Option<SystemTime>,
}

impl FileStamp {
    /// The stamp of the file at `path` now; the error of reading its metadata (a missing or
    /// unreadable file) otherwise.
    pub fn of(path: &Path) -> std::io::Result<FileStamp> {
        let meta = std::fs::metadata(path)?;
        Ok(FileStamp {
            path: path.to_path_buf(),
            len: meta.len(),
            modified: meta.modified().ok(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rewritten file of another length stamps differently; a missing file is an error.
    #[test]
    fn stamps_follow_the_file() {
        let dir = tempfile::tempdir().expect("a temporary folder");
        let path = dir.path().join("a.bin");
        std::fs::write(&path, [1, 2, 3]).expect("writes");
        let first = FileStamp::of(&path).expect("stamps");
        assert_eq!(first.len, 3);
        assert_eq!(FileStamp::of(&path).expect("stamps"), first);
        std::fs::write(&path, [1, 2, 3, 4]).expect("writes");
        assert_ne!(FileStamp::of(&path).expect("stamps"), first);
        let missing = FileStamp::of(&dir.path().join("none")).expect_err("no file");
        assert_eq!(missing.kind(), std::io::ErrorKind::NotFound);
    }
}
