//! Zip archives: what Sketchfab's and many asset stores' "glTF" downloads are (`scene.gltf`,
//! `scene.bin` and a `textures/` folder in one `.zip`). The one model inside (`.gltf`, `.glb`
//! or `.obj`) is loaded with the files beside it, from a private temporary folder the archive
//! is unpacked into, which lives as long as the scene (textures are decoded after the load).
//!
//! A hostile archive gets one error, nothing written outside that folder: entries whose path
//! leaves it (`../`, absolute paths) are refused, symbolic links are skipped, and the bytes
//! unpacked (counted as they are inflated, not as the archive declares them) may not exceed
//! the model file limit (`LoadLimits::max_file_bytes`), so a zip bomb stops at the limit.

use super::error::LoadErrorKind;
use std::io::Read;
use std::path::{Component, Path, PathBuf};
use std::sync::{Arc, Mutex};

/// A zip's local file header signature, its first bytes.
const MAGIC: &[u8; 4] = b"PK\x03\x04";

/// The first bytes of an empty zip archive: its end-of-central-directory record alone.
const EMPTY_MAGIC: &[u8; 4] = b"PK\x05\x06";

/// Most entries an archive may hold: a model's download has a few dozen.
const MAX_ENTRIES: usize = 100_000;

/// The extensions of the model files meshtracer reads (compared without case): what an
/// archive's model and a folder manifest's jobs are found by.
pub const MODEL_EXTENSIONS: [&str; 3] = ["gltf", "glb", "obj"];

/// Keeps an archive's unpacked files while the scene made from them lives.
#[derive(Clone, Debug)]
pub struct Archive {
    /// The temporary folder, removed when the last clone is dropped.
    folder: Arc<Unpacked>,
}

impl Archive {
    /// The folder the archive was unpacked into.
    pub(super) fn folder(&self) -> &Path {
        self.folder.0.path()
    }
}

/// The folders of the archives being unpacked or held by a scene: what [`remove_unpacked`]
/// removes for a process about to exit without dropping its scenes.
static UNPACKED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// An archive's temporary folder, listed in [`UNPACKED`] from its creation until it is
/// dropped (and removed, by `TempDir`).
#[derive(Debug)]
struct Unpacked(tempfile::TempDir);

impl Unpacked {
    fn new(folder: tempfile::TempDir) -> Unpacked {
        let mut listed = UNPACKED.lock().unwrap_or_else(|e| e.into_inner());
        listed.push(folder.path().to_path_buf());
        Unpacked(folder)
    }
}

impl Drop for Unpacked {
    fn drop(&mut self) {
        let mut listed = UNPACKED.lock().unwrap_or_else(|e| e.into_inner());
        listed.retain(|p| p != self.0.path());
    }
}

/// Removes the temporary folder of every archive unpacked and not yet dropped: for a process
/// that is about to exit at once (`std::process::exit` runs no destructors), such as the
/// command line's second Ctrl-C or a closed standard output. A scene still using one then
/// finds its files gone, so call it only on the way out.
pub fn remove_unpacked() {
    let mut listed = UNPACKED.lock().unwrap_or_else(|e| e.into_inner());
    for folder in listed.drain(..) {
        let _ = std::fs::remove_dir_all(folder);
    }
}

/// Whether the file at `path` starts as a zip archive does.
pub(super) fn is_zip(path: &Path) -> bool {
    let mut head = [0u8; 4];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok_and(|()| &head == MAGIC || &head == EMPTY_MAGIC)
}

/// Why a file that starts as a zip could not be opened as one, in a user's words: a file
/// without the directory a zip ends with was most likely cut short.
fn unreadable(e: &zip::result::ZipError) -> String {
    match e {
        zip::result::ZipError::InvalidArchive(why) if why.contains("Could not find EOCD") => {
            "not a readable zip archive: the directory a zip ends with is missing (is the file \
             complete, or was the download cut short?)"
                .to_string()
        }
        e => format!("not a readable zip archive ({e})"),
    }
}

/// Unpacks the zip archive at `path` into a new temporary folder, at most `max_bytes` of it,
/// and names the one model in it (relative to the folder).
pub(super) fn unpack(path: &Path, max_bytes: u64) -> Result<(Archive, PathBuf), LoadErrorKind> {
    let bad = |problem: String| LoadErrorKind::Archive(problem);
    let file = std::fs::File::open(path).map_err(LoadErrorKind::Io)?;
    let mut zip = zip::ZipArchive::new(file).map_err(|e| bad(unreadable(&e)))?;
    if zip.len() > MAX_ENTRIES {
        return Err(bad(format!(
            "{} entries, over the limit of {MAX_ENTRIES}",
            zip.len()
        )));
    }
    let model = the_model(&mut zip, max_bytes)?;
    let folder = tempfile::Builder::new()
        .prefix("meshtracer-zip-")
        .tempdir()
        .map(Unpacked::new)
        .map_err(|e| bad(format!("no temporary folder to unpack it into ({e})")))?;
    let mut left = max_bytes;
    for i in 0..zip.len() {
        let mut entry = zip
            .by_index(i)
            .map_err(|e| bad(format!("entry {i}: {e}")))?;
        if entry.is_dir() || entry.is_symlink() {
            continue;
        }
        let name = entry.name().to_string();
        let relative = inside(&name).ok_or_else(|| {
            bad(format!(
                "entry '{name}' would be written outside the archive's folder"
            ))
        })?;
        if skipped(&relative) {
            continue;
        }
        let target = folder.0.path().join(&relative);
        if let Some(parent) = target.parent() {
            std::fs::create_dir_all(parent).map_err(|e| bad(format!("entry '{name}': {e}")))?;
        }
        let mut out =
            std::fs::File::create_new(&target).map_err(|e| bad(format!("entry '{name}': {e}")))?;
        let copied = std::io::copy(&mut (&mut entry).take(left.saturating_add(1)), &mut out)
            .map_err(|e| bad(format!("entry '{name}': {e}")))?;
        if copied > left {
            return Err(bad(format!(
                "unpacks to more than the limit of {max_bytes} bytes (at entry '{name}')"
            )));
        }
        left -= copied;
    }
    let archive = Archive {
        folder: Arc::new(folder),
    };
    Ok((archive, model))
}

/// The one model file the archive holds, or an error naming what it holds instead; an
/// archive whose entries declare more than `max_bytes` between them is refused before
/// anything is unpacked (what they really inflate to is counted again as they are).
fn the_model<R: std::io::Read + std::io::Seek>(
    zip: &mut zip::ZipArchive<R>,
    max_bytes: u64,
) -> Result<PathBuf, LoadErrorKind> {
    let found = models_in(zip, max_bytes)?;
    if let ([], [name, rest @ ..]) = (found.models.as_slice(), found.refused.as_slice()) {
        let more = match rest.len() {
            0 => String::new(),
            n => format!(" (and {n} more model entries like it)"),
        };
        return Err(LoadErrorKind::Archive(format!(
            "its model entry '{name}' is refused: its path leaves the archive (absolute, or through '..'){more}"
        )));
    }
    one_model(found.models, "unzip it and render one").map_err(LoadErrorKind::Archive)
}

/// Whether the file at `path` is a zip archive whose entries name at least one model file
/// (`.gltf`, `.glb`, `.obj`; macOS's resource forks aside): what a batch's folder manifest
/// takes for a zipped download. A model entry whose path leaves the archive (`../m.gltf`,
/// `/m.glb`) counts: the job is then refused when it loads, naming the zip and the entry,
/// rather than the zip left out of the batch without a word. So does a file that starts as a
/// zip but whose directory cannot be read (a download cut short) or lists more than
/// `MAX_ENTRIES` entries: what it holds is unknown, and its job fails naming the problem. Only
/// the archive's directory is read; nothing is unpacked. A file that only ends in `.zip` is
/// not one.
pub fn holds_a_model(path: &Path) -> bool {
    let Ok(mut file) = std::fs::File::open(path) else {
        return false;
    };
    // The magic first (a cheap refusal of what only ends in `.zip`), then the directory,
    // read through the same file.
    let mut head = [0u8; 4];
    if file.read_exact(&mut head).is_err() || &head != MAGIC {
        return false;
    }
    let Ok(mut zip) = zip::ZipArchive::new(file) else {
        return true;
    };
    if zip.len() > MAX_ENTRIES {
        return true;
    }
    models_in(&mut zip, u64::MAX).map_or(true, |found| {
        !found.models.is_empty() || !found.refused.is_empty()
    })
}

/// The model files among an archive's entries.
struct FoundModels {
    /// Those inside the archive's folder, relative to it.
    models: Vec<PathBuf>,
    /// The names of those whose path leaves it (`../m.gltf`, `/m.glb`), which are never
    /// unpacked: without them, an archive holding only such a model would seem to hold none.
    refused: Vec<String>,
}

/// The model files among the archive's entries; an error if they declare more than
/// `max_bytes` between them.
fn models_in<R: std::io::Read + std::io::Seek>(
    zip: &mut zip::ZipArchive<R>,
    max_bytes: u64,
) -> Result<FoundModels, LoadErrorKind> {
    let mut found = FoundModels {
        models: Vec::new(),
        refused: Vec::new(),
    };
    let mut declared = 0u64;
    for i in 0..zip.len() {
        let entry = zip
            .by_index_raw(i)
            .map_err(|e| LoadErrorKind::Archive(format!("entry {i}: {e}")))?;
        declared = declared.saturating_add(entry.size());
        if declared > max_bytes {
            return Err(LoadErrorKind::Archive(format!(
                "its entries declare more than the limit of {max_bytes} bytes unpacked"
            )));
        }
        if entry.is_dir() || entry.is_symlink() {
            continue;
        }
        let name = Path::new(entry.name());
        if !is_model(name) || skipped(name) {
            continue;
        }
        match inside(entry.name()) {
            Some(relative) => found.models.push(relative),
            None => found.refused.push(entry.name().to_string()),
        }
    }
    Ok(found)
}

/// Whether `path` names a model file by its extension ([`MODEL_EXTENSIONS`]).
fn is_model(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| MODEL_EXTENSIONS.iter().any(|m| e.eq_ignore_ascii_case(m)))
}

/// The one model among `models`, or what there is instead: none, or several (the first five
/// named), with `advice`.
fn one_model(mut models: Vec<PathBuf>, advice: &str) -> Result<PathBuf, String> {
    models.sort();
    match models.as_slice() {
        [one] => Ok(one.clone()),
        [] => Err("holds no .gltf, .glb or .obj file".to_string()),
        many => {
            let names: Vec<String> = many
                .iter()
                .take(5)
                .map(|p| format!("'{}'", p.display()))
                .collect();
            let more = if many.len() > 5 { ", ..." } else { "" };
            Err(format!(
                "holds {} models ({}{more}): {advice}",
                many.len(),
                names.join(", ")
            ))
        }
    }
}

/// Most entries [`folder_model`] looks at, and how deep.
const FOLDER_ENTRIES: usize = 10_000;
const FOLDER_DEPTH: usize = 6;

/// The one model file in the folder `dir` or below it (an unzipped download), relative to
/// it: symbolic links are not followed, hidden entries and macOS's resource forks are passed
/// over, and at most [`FOLDER_ENTRIES`] entries [`FOLDER_DEPTH`] levels deep are looked at.
pub(super) fn folder_model(dir: &Path) -> Result<PathBuf, LoadErrorKind> {
    let mut models = Vec::new();
    let mut seen = 0usize;
    let mut stack = vec![(PathBuf::new(), 0usize)];
    while let Some((relative, depth)) = stack.pop() {
        let entries = std::fs::read_dir(dir.join(&relative)).map_err(LoadErrorKind::Io)?;
        for entry in entries {
            let entry = entry.map_err(LoadErrorKind::Io)?;
            seen += 1;
            if seen > FOLDER_ENTRIES {
                return Err(LoadErrorKind::Folder(format!(
                    "more than {FOLDER_ENTRIES} entries to look through: name the model file"
                )));
            }
            let name = relative.join(entry.file_name());
            let hidden = entry
                .file_name()
                .to_str()
                .is_some_and(|s| s.starts_with('.'));
            if hidden || skipped(&name) {
                continue;
            }
            let kind = entry.file_type().map_err(LoadErrorKind::Io)?;
            if kind.is_dir() && depth + 1 < FOLDER_DEPTH {
                stack.push((name, depth + 1));
            } else if kind.is_file() && is_model(&name) {
                models.push(name);
            }
        }
    }
    one_model(models, "name the one to render").map_err(LoadErrorKind::Folder)
}

/// `name` as a relative path that stays inside the folder (no `..`, no root, no prefix), or
/// `None`.
fn inside(name: &str) -> Option<PathBuf> {
    let path = Path::new(name);
    let mut out = PathBuf::new();
    for component in path.components() {
        match component {
            Component::Normal(part) => out.push(part),
            Component::CurDir => {}
            Component::ParentDir | Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    (!out.as_os_str().is_empty()).then_some(out)
}

/// Entries left packed: macOS's resource forks (`__MACOSX/`, `._name`), which hold no model.
fn skipped(relative: &Path) -> bool {
    relative.components().any(|c| {
        c.as_os_str()
            .to_str()
            .is_some_and(|s| s == "__MACOSX" || s.starts_with("._"))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    /// An archive's entries: (name, bytes).
    type Entries<'a> = &'a [(&'a str, &'a [u8])];

    fn zip_of(entries: Entries) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("model.zip");
        let mut w = zip::ZipWriter::new(std::fs::File::create(&path).unwrap());
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated);
        for (name, bytes) in entries {
            w.start_file(*name, options).unwrap();
            w.write_all(bytes).unwrap();
        }
        w.finish().unwrap();
        (dir, path)
    }

    #[test]
    fn the_one_model_is_found_and_its_files_unpacked_beside_it() {
        let (_dir, path) = zip_of(&[
            ("duck/scene.gltf", b"{}"),
            ("duck/textures/a.png", b"png"),
            ("__MACOSX/duck/._scene.gltf", b"fork"),
        ]);
        assert!(is_zip(&path));
        let (archive, model) = unpack(&path, 1 << 20).unwrap();
        assert_eq!(model, Path::new("duck/scene.gltf"));
        let folder = archive.folder().to_path_buf();
        assert_eq!(
            std::fs::read(folder.join("duck/textures/a.png")).unwrap(),
            b"png"
        );
        assert!(!folder.join("__MACOSX").exists());
        let listed = || UNPACKED.lock().unwrap().contains(&folder);
        assert!(listed(), "listed for a process exiting at once");
        drop(archive);
        assert!(!folder.exists(), "the folder goes with the last clone");
        assert!(!listed(), "and leaves the list");
    }

    #[test]
    fn hostile_and_ambiguous_archives_are_refused() {
        let cases: [(Entries, &str); 5] = [
            (
                &[("a.glb", b"x"), ("b.obj", b"x")],
                "holds 2 models ('a.glb', 'b.obj')",
            ),
            (&[("readme.txt", b"x")], "holds no .gltf, .glb or .obj file"),
            (
                &[("m.gltf", b"{}"), ("../escape.bin", b"x")],
                "entry '../escape.bin' would be written outside",
            ),
            (
                &[("../evil.gltf", b"{}"), ("readme.txt", b"x")],
                "its model entry '../evil.gltf' is refused: its path leaves the archive",
            ),
            (
                &[("m.gltf", &[b'{'; 4096])],
                "its entries declare more than the limit of 1000 bytes unpacked",
            ),
        ];
        for (entries, problem) in cases {
            let (_dir, path) = zip_of(entries);
            let err = unpack(&path, 1000).unwrap_err().to_string();
            assert!(err.contains(problem), "{err}");
        }
        // An entry that declares 10 bytes and inflates to 4,096 (its sizes patched in the
        // local and central headers): the declared sum passes, the bytes counted as they are
        // inflated stop it.
        let (_dir, path) = zip_of(&[("m.gltf", &[b' '; 4096])]);
        let mut bytes = std::fs::read(&path).unwrap();
        let find = |bytes: &[u8], magic: &[u8]| bytes.windows(4).position(|w| w == magic).unwrap();
        let local = find(&bytes, b"PK\x03\x04");
        let central = find(&bytes, b"PK\x01\x02");
        for at in [local + 22, central + 24] {
            assert_eq!(bytes[at..at + 4], 4096u32.to_le_bytes(), "the size field");
            bytes[at..at + 4].copy_from_slice(&10u32.to_le_bytes());
        }
        std::fs::write(&path, bytes).unwrap();
        let err = unpack(&path, 1000).unwrap_err().to_string();
        assert!(
            err.contains("unpacks to more than the limit of 1000 bytes (at entry 'm.gltf')"),
            "{err}"
        );
        let dir = tempfile::tempdir().unwrap();
        let truncated = dir.path().join("t.zip");
        std::fs::write(&truncated, b"PK\x03\x04 and then nothing").unwrap();
        assert!(is_zip(&truncated));
        let err = unpack(&truncated, 1000).unwrap_err().to_string();
        assert!(err.contains("not a readable zip archive"), "{err}");
    }
}
