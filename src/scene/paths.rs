//! Resolving the URIs and paths a model file references, without escaping its folder.
//!
//! A downloaded model is untrusted: `"uri": "/etc/passwd"` or `"../../.ssh/id_rsa"` must not be
//! read unless the user allows it. Symlinks are resolved before the check, so a link inside the
//! folder that points outside is refused too.

use super::error::{LoadError, LoadErrorKind};
use std::path::{Path, PathBuf};

/// Reads files referenced by a model, confined to the model's folder unless allowed otherwise.
#[derive(Clone, Debug)]
pub struct FileAccess {
    /// The model file (for error messages).
    pub model: PathBuf,
    /// The folder relative URIs resolve against.
    pub base: PathBuf,
    /// When the model path is a symbolic link to a file in another folder: that folder, where
    /// relative URIs resolve when the file is missing beside the link (a model linked into a
    /// folder of links keeps finding its buffers and textures).
    target_base: Option<PathBuf>,
    /// Whether absolute URIs and `..` that escape `base` are allowed.
    pub allow_external: bool,
    /// Largest file read, in bytes.
    pub max_bytes: u64,
    /// Every path [`FileAccess::resolve`] gave, shared by the clones: the files the model
    /// refers to.
    resolved: std::sync::Arc<std::sync::Mutex<Vec<PathBuf>>>,
    /// The references found only with another letter case ([`find_ignoring_case`]) or only
    /// by their file name elsewhere in the folder ([`find_by_name`]): as written, as found,
    /// and whether by name. Shared by the clones.
    recased: std::sync::Arc<std::sync::Mutex<Vec<(String, PathBuf, bool)>>>,
}

impl FileAccess {
    /// Access rooted at the folder of `model`.
    pub fn new(model: &Path, allow_external: bool, max_bytes: u64) -> Self {
        let base = model
            .parent()
            .map(Path::to_path_buf)
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or_else(|| PathBuf::from("."));
        let target_base = std::fs::symlink_metadata(model)
            .ok()
            .filter(|meta| meta.file_type().is_symlink())
            .and_then(|_| model.canonicalize().ok())
            .and_then(|real| real.parent().map(Path::to_path_buf))
            .filter(|target| base.canonicalize().ok().as_ref() != Some(target));
        Self {
            model: model.to_path_buf(),
            base,
            target_base,
            allow_external,
            max_bytes,
            resolved: Default::default(),
            recased: Default::default(),
        }
    }

    /// One warning for each reference found only with another letter case (the model names
    /// its files as a case-insensitive file system, Windows' or macOS', finds them) or only by
    /// its file name (a path on its author's machine).
    pub fn recased_warnings(&self) -> Vec<String> {
        let recased = self.recased.lock().unwrap_or_else(|e| e.into_inner());
        let mut seen = std::collections::HashSet::new();
        recased
            .iter()
            .filter(|(uri, _, _)| seen.insert(uri.clone()))
            .map(|(uri, found, by_name)| {
                let found = found.strip_prefix(&self.base).unwrap_or(found).display();
                if *by_name {
                    format!(
                        "'{uri}' names no file in the model's folder; '{found}', the one file of that name in it, is used"
                    )
                } else {
                    format!(
                        "'{uri}' names no file; '{found}' differs from it only in letter case and is used (Windows and macOS ignore the case of file names, other systems do not)"
                    )
                }
            })
            .collect()
    }

    /// `found` in place of the reference `uri`, noted for [`FileAccess::recased_warnings`].
    fn found_instead(&self, uri: &str, found: PathBuf, by_name: bool) -> PathBuf {
        self.recased
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push((uri.to_string(), found.clone(), by_name));
        found
    }

    /// The files resolved so far (buffers, images, material libraries), each once, in the
    /// order first resolved: what the model refers to besides itself.
    pub fn resolved(&self) -> Vec<PathBuf> {
        let resolved = self.resolved.lock().unwrap_or_else(|e| e.into_inner());
        let mut seen = std::collections::HashSet::new();
        resolved
            .iter()
            .filter(|p| seen.insert(*p))
            .cloned()
            .collect()
    }

    /// Resolves `uri` (percent-decoded, relative to the model's folder) to a path, refusing one
    /// that leaves the folder. `what` names the referencing object in errors (`buffer 0`).
    pub fn resolve(&self, what: &str, uri: &str) -> Result<PathBuf, LoadError> {
        let decoded = percent_decode(uri);
        let bad = |problem: String| {
            LoadError::new(
                &self.model,
                LoadErrorKind::BadUri {
                    what: what.to_string(),
                    uri: uri.to_string(),
                    problem,
                },
            )
        };
        if decoded.is_empty() {
            return Err(bad("is empty: it names no file".to_string()));
        }
        let external = || {
            LoadError::new(
                &self.model,
                LoadErrorKind::ExternalFile {
                    what: what.to_string(),
                    uri: uri.to_string(),
                },
            )
        };
        let relative = resolve_relative(&decoded);
        // The folder the URI resolves in: the model's, or, for a linked model whose file is
        // not beside the link, the linked file's.
        let mut base = &self.base;
        let path = match relative {
            Some(rel) => match &self.target_base {
                Some(target) if !self.base.join(&rel).exists() && target.join(&rel).exists() => {
                    base = target;
                    target.join(rel)
                }
                _ => {
                    let path = self.base.join(&rel);
                    if path.exists() {
                        path
                    } else if let Some(found) = find_ignoring_case(&self.base, &rel) {
                        self.found_instead(&decoded, found, false)
                    } else if let Some(found) = find_by_name(&self.base, &decoded) {
                        self.found_instead(&decoded, found, true)
                    } else {
                        path
                    }
                }
            },
            None if self.allow_external => {
                let p = decoded.strip_prefix("file://").unwrap_or(&decoded);
                let p = Path::new(p);
                let p = if p.is_absolute() {
                    p.to_path_buf()
                } else {
                    self.base.join(p)
                };
                match p.exists() {
                    true => p,
                    false => match find_by_name(&self.base, &decoded) {
                        Some(found) => self.found_instead(&decoded, found, true),
                        None => p,
                    },
                }
            }
            // A path on the author's machine (`C:\Users\...\wood.png`): the file of that name
            // in the model's folder, if there is one, else refused.
            None => match find_by_name(&self.base, &decoded) {
                Some(found) => self.found_instead(&decoded, found, true),
                None => return Err(external()),
            },
        };
        if !self.allow_external {
            // Symlinks: compare canonical forms when the file exists. A missing file is reported
            // by the read that follows.
            if let (Ok(real), Ok(base)) = (path.canonicalize(), base.canonicalize()) {
                if !real.starts_with(&base) {
                    return Err(external());
                }
            }
        }
        // A FIFO or a device is refused here, before anything opens it (the image header check
        // and the decoders open image files by path). A missing file is reported by the read.
        if let Ok(meta) = std::fs::metadata(&path) {
            if let Some(kind) = irregular_kind(&meta) {
                return Err(bad(format!(
                    "names {kind} ('{}'), not a regular file",
                    path.display()
                )));
            }
        }
        self.resolved
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(path.clone());
        Ok(path)
    }

    /// Reads a resolved file, with the size limit applied before reading.
    pub fn read(&self, path: &Path) -> Result<Vec<u8>, LoadError> {
        let err = |kind| LoadError::new(path, kind);
        let meta = regular_file(path).map_err(err)?;
        if meta.len() > self.max_bytes {
            return Err(err(LoadErrorKind::FileTooLarge {
                bytes: meta.len(),
                limit: self.max_bytes,
            }));
        }
        std::fs::read(path).map_err(|e| err(LoadErrorKind::Io(e)))
    }

    /// Reads the first `len` bytes of a resolved file (fewer if it is shorter), never the rest:
    /// a buffer is read to its `byteLength`, not to the end of whatever file it names. The limit
    /// applies to `len`, and too little memory for it is an error.
    pub fn read_prefix(&self, path: &Path, len: u64) -> Result<Vec<u8>, LoadError> {
        use std::io::Read;
        let err = |kind| LoadError::new(path, kind);
        regular_file(path).map_err(err)?;
        if len > self.max_bytes {
            return Err(err(LoadErrorKind::FileTooLarge {
                bytes: len,
                limit: self.max_bytes,
            }));
        }
        let file = std::fs::File::open(path).map_err(|e| err(LoadErrorKind::Io(e)))?;
        let mut bytes = super::error::allocate(len, "a buffer").map_err(err)?;
        file.take(len)
            .read_to_end(&mut bytes)
            .map_err(|e| err(LoadErrorKind::Io(e)))?;
        Ok(bytes)
    }
}

/// `relative` under `base`, each of its parts matched to the folder's entries without regard
/// to letter case, where the path as written names nothing (`Textures/Wood.PNG` for
/// `textures/wood.png`: models made on Windows or macOS, whose file systems ignore case, often
/// name their files so). A part that matches exactly is taken as it is; `None` when a part
/// matches no entry, or more than one.
fn find_ignoring_case(base: &Path, relative: &Path) -> Option<PathBuf> {
    let mut found = base.to_path_buf();
    for part in relative.components() {
        let name = part.as_os_str();
        let exact = found.join(name);
        if exact.exists() {
            found = exact;
            continue;
        }
        let wanted = name.to_str()?.to_lowercase();
        let mut matches = std::fs::read_dir(&found).ok()?.filter_map(|entry| {
            let entry = entry.ok()?;
            let same = entry.file_name().to_str()?.to_lowercase() == wanted;
            same.then(|| entry.path())
        });
        let first = matches.next()?;
        if matches.next().is_some() {
            return None;
        }
        found = first;
    }
    Some(found)
}

/// Folders below the model's that [`find_by_name`] looks in: two levels (`textures/`,
/// `model/textures/`).
const FIND_DEPTH: usize = 2;

/// Folder entries [`find_by_name`] reads at most, so that a model in a large folder (a
/// download folder, a home) costs little.
const FIND_ENTRIES: usize = 4096;

/// The file named as the last part of `uri` (after its last `/` or `\`), found without regard
/// to letter case in `base` or the folders below it down to [`FIND_DEPTH`], at the shallowest
/// level that has it, when exactly one file there has that name (as Blender's importers
/// search for a texture whose path is another machine's). Folder links are not followed.
fn find_by_name(base: &Path, uri: &str) -> Option<PathBuf> {
    let name = uri.rsplit(['/', '\\']).next()?.to_lowercase();
    if name.is_empty() || name == "." || name == ".." {
        return None;
    }
    let mut folders = vec![base.to_path_buf()];
    let mut read = 0usize;
    for _ in 0..=FIND_DEPTH {
        let (mut matches, mut below) = (Vec::new(), Vec::new());
        for folder in &folders {
            let Ok(entries) = std::fs::read_dir(folder) else {
                continue;
            };
            for entry in entries.flatten() {
                read += 1;
                if read > FIND_ENTRIES {
                    return None;
                }
                let Ok(kind) = entry.file_type() else {
                    continue;
                };
                if kind.is_dir() {
                    below.push(entry.path());
                } else if entry.file_name().to_str().map(str::to_lowercase) == Some(name.clone()) {
                    matches.push(entry.path());
                }
            }
        }
        match matches.len() {
            0 => folders = below,
            1 => return matches.pop(),
            _ => return None,
        }
    }
    None
}

/// What kind of file `meta` describes, when it is not a regular file or a directory: "a FIFO",
/// "a character device", "a block device", "a socket". `None` for regular files and
/// directories.
pub fn irregular_kind(meta: &std::fs::Metadata) -> Option<&'static str> {
    let file_type = meta.file_type();
    if file_type.is_file() || file_type.is_dir() {
        return None;
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if file_type.is_fifo() {
            return Some("a FIFO");
        }
        if file_type.is_char_device() {
            return Some("a character device");
        }
        if file_type.is_block_device() {
            return Some("a block device");
        }
        if file_type.is_socket() {
            return Some("a socket");
        }
    }
    Some("not a file")
}

/// The metadata of `path` if it is a regular file (following symbolic links): a directory or
/// anything that is not a file (a FIFO would block the read forever, `/dev/zero` never ends)
/// is refused before it is opened.
pub fn regular_file(path: &Path) -> Result<std::fs::Metadata, LoadErrorKind> {
    let meta = std::fs::metadata(path).map_err(LoadErrorKind::Io)?;
    if meta.is_dir() {
        return Err(LoadErrorKind::IsDirectory);
    }
    match irregular_kind(&meta) {
        Some(kind) => Err(LoadErrorKind::NotARegularFile { kind }),
        None => Ok(meta),
    }
}

/// Interprets `uri` as a relative path that stays inside its base folder: returns the cleaned
/// relative path, or `None` when it is absolute, has a scheme or a drive, or climbs out with `..`.
pub fn resolve_relative(uri: &str) -> Option<PathBuf> {
    if uri.contains("://") || uri.starts_with('/') || uri.starts_with('\\') {
        return None;
    }
    // A Windows drive letter ("C:") is absolute too, whatever platform reads the file.
    let bytes = uri.as_bytes();
    if bytes.len() >= 2 && bytes[1] == b':' && bytes[0].is_ascii_alphabetic() {
        return None;
    }
    let mut out = PathBuf::new();
    let mut depth = 0usize;
    for part in uri.split(['/', '\\']) {
        if part.is_empty() || part == "." {
            continue;
        }
        if part == ".." {
            if depth == 0 {
                return None;
            }
            depth -= 1;
            out.pop();
        } else {
            depth += 1;
            out.push(part);
        }
    }
    if depth == 0 {
        return None;
    }
    Some(out)
}

/// Decodes `%XX` escapes (glTF URIs are RFC 3986 references). Invalid escapes stay as written.
fn percent_decode(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            let hex = std::str::from_utf8(&bytes[i + 1..i + 3]).ok();
            if let Some(v) = hex.and_then(|h| u8::from_str_radix(h, 16).ok()) {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths_stay_inside() {
        assert_eq!(resolve_relative("a.bin"), Some(PathBuf::from("a.bin")));
        assert_eq!(
            resolve_relative("./tex/a.png"),
            Some(PathBuf::from("tex/a.png"))
        );
        assert_eq!(
            resolve_relative("tex/../a.png"),
            Some(PathBuf::from("a.png"))
        );
        assert_eq!(resolve_relative("../a.bin"), None);
        assert_eq!(resolve_relative("tex/../../a.bin"), None);
        assert_eq!(resolve_relative("/etc/passwd"), None);
        assert_eq!(resolve_relative("C:\\x.bin"), None);
        assert_eq!(resolve_relative("file:///etc/passwd"), None);
        assert_eq!(resolve_relative(""), None);
    }

    #[test]
    fn percent_escapes_decode() {
        assert_eq!(percent_decode("my%20file.bin"), "my file.bin");
        assert_eq!(percent_decode("100%"), "100%");
        assert_eq!(percent_decode("%2e%2e/x"), "../x");
    }

    #[test]
    fn escaped_dot_dot_is_refused() {
        let access = FileAccess::new(Path::new("/tmp/m/model.gltf"), false, 1 << 20);
        assert!(access.resolve("buffer 0", "%2e%2e/secret.bin").is_err());
    }

    /// A reference that names no file is found part by part without regard to letter case,
    /// and said so once; one that matches two entries, or none, stays as written (the read
    /// that follows reports it missing); an exact name is taken as it is.
    #[test]
    fn references_in_another_letter_case_are_found_and_reported() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("Textures")).unwrap();
        for name in [
            "Textures/Wood.PNG",
            "Textures/twin.png",
            "Textures/TWIN.png",
        ] {
            std::fs::write(dir.path().join(name), b"x").unwrap();
        }
        let access = FileAccess::new(&dir.path().join("model.gltf"), false, 1 << 20);
        let wood = dir.path().join("Textures/Wood.PNG");
        assert_eq!(
            access.resolve("image 0", "textures/wood.png").unwrap(),
            wood
        );
        assert_eq!(
            access.resolve("image 1", "textures\\WOOD.png").unwrap(),
            wood
        );
        assert_eq!(
            access.resolve("image 2", "Textures/Wood.PNG").unwrap(),
            wood
        );
        let twin = access.resolve("image 3", "Textures/Twin.png").unwrap();
        assert_eq!(twin, dir.path().join("Textures/Twin.png"));
        let gone = access.resolve("image 4", "textures/gone.png").unwrap();
        assert_eq!(gone, dir.path().join("textures/gone.png"));
        let warnings = access.recased_warnings();
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(
            warnings[0].starts_with(
                "'textures/wood.png' names no file; 'Textures/Wood.PNG' differs from it only in letter case"
            ),
            "{warnings:?}"
        );
        assert!(
            warnings[1].starts_with("'textures\\WOOD.png'"),
            "{warnings:?}"
        );
    }

    /// A path on the author's machine, or one whose folders are wrong, finds the one file of
    /// its name in the model's folder or two levels below it (the shallowest level that has
    /// it), said in a warning; two of that name at that level, or none, and it stays refused
    /// (outside) or missing (inside).
    #[test]
    fn references_to_another_machine_find_the_file_by_name() {
        let dir = tempfile::tempdir().unwrap();
        for folder in ["maps/wood", "a", "b"] {
            std::fs::create_dir_all(dir.path().join(folder)).unwrap();
        }
        for name in [
            "maps/wood/Oak.png",
            "a/twin.png",
            "b/twin.png",
            "c.png",
            "a/c.png",
        ] {
            std::fs::write(dir.path().join(name), b"x").unwrap();
        }
        let access = FileAccess::new(&dir.path().join("m.obj"), false, 1 << 20);
        let oak = dir.path().join("maps/wood/Oak.png");
        let windows = "C:\\Users\\bob\\Desktop\\oak.png";
        assert_eq!(access.resolve("map_Kd", windows).unwrap(), oak);
        assert_eq!(
            access.resolve("map_Kd", "/home/alice/Oak.png").unwrap(),
            oak
        );
        assert_eq!(access.resolve("map_Kd", "textures/oak.png").unwrap(), oak);
        // The shallowest wins; two at one level are no answer.
        assert_eq!(
            access.resolve("map_Kd", "/x/c.png").unwrap(),
            dir.path().join("c.png")
        );
        assert!(access.resolve("map_Kd", "/x/twin.png").is_err());
        assert_eq!(
            access.resolve("map_Kd", "textures/twin.png").unwrap(),
            dir.path().join("textures/twin.png")
        );
        assert!(access.resolve("map_Kd", "/etc/passwd").is_err());
        let warnings = access.recased_warnings();
        assert_eq!(warnings.len(), 4, "{warnings:?}");
        assert_eq!(
            warnings[0],
            format!("'{windows}' names no file in the model's folder; 'maps/wood/Oak.png', the one file of that name in it, is used")
        );
    }
}
