//! Batches (`meshtracer batch`): what a manifest says, which jobs a shard takes, and the record
//! each job leaves. Plain data and checks; the command that renders the jobs is in
//! `src/bin/meshtracer/commands/batch.rs`.
//!
//! - A **manifest** is a folder of models (every `.gltf`, `.glb` and `.obj` below it, hidden
//!   entries skipped, sorted by path) or a JSONL file, one job a line (see [`ManifestLine`]).
//!   A line that is not a job becomes an [`Entry`] that fails alone.
//! - A **job id** names the job's folder inside the output folder: the model's path relative
//!   to the manifest's folder without its extension, or the line's `id`. Ids and output names
//!   are input like any model file: absolute ones and ones with `..` are refused
//!   ([`check_job_id`], [`check_output_name`]).
//! - A **shard** `I/N` holds the jobs whose key (the id, or the text of a line that has none)
//!   hashes to I modulo N with FNV-1a 64 ([`fnv1a64`]): fixed across runs, machines and Rust
//!   versions, and independent of the order of the manifest.
//! - A **record** ([`JobRecord`]) is one line of `results.jsonl` and the job's `job.json`.

use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::io::Read;
use std::path::{Component, Path, PathBuf};

/// The file in each job's folder that records the finished job; `--resume` reads it.
pub const JOB_FILE: &str = "job.json";

/// The results file of an unsharded batch, and of the merged shards.
pub const RESULTS_FILE: &str = "results.jsonl";

/// Model file extensions a folder manifest picks up (compared without case).
pub use crate::scene::MODEL_EXTENSIONS;

/// A manifest that cannot be read at all (a bad line only fails its job).
#[derive(Debug, thiserror::Error)]
#[error("{path}: {problem}")]
pub struct ManifestError {
    /// The manifest, or the entry of it that could not be read.
    pub path: PathBuf,
    /// What went wrong.
    pub problem: String,
}

fn manifest_error(path: &Path, problem: impl Into<String>) -> ManifestError {
    ManifestError {
        path: path.to_path_buf(),
        problem: problem.into(),
    }
}

/// FNV-1a, 64 bits (offset basis 0xcbf29ce484222325, prime 0x100000001b3), over `bytes`:
/// the shard hash. Chosen for being fixed and documented (Rust's `DefaultHasher` is seeded
/// per process), tiny and well spread over short strings.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |hash, &b| {
        (hash ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Shard `index` of `count` (0-based: `index < count`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// Which shard, from 0.
    pub index: usize,
    /// How many shards.
    pub count: usize,
}

impl Shard {
    /// Every job: one shard.
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// Parses `I/N` (`--shard`).
    pub fn parse(text: &str) -> Result<Shard, String> {
        let (i, n) = text
            .split_once('/')
            .ok_or_else(|| format!("expected I/N (shard I of N, from 0), got '{text}'"))?;
        let number = |x: &str| {
            x.trim()
                .parse::<usize>()
                .map_err(|_| format!("'{x}' is not a whole number"))
        };
        Shard::new(number(i)?, number(n)?)
    }

    /// Shard `index` of `count`, checked.
    pub fn new(index: usize, count: usize) -> Result<Shard, String> {
        if count == 0 {
            return Err(format!(
                "shard {index}/{count}: there must be at least 1 shard"
            ));
        }
        if index >= count {
            return Err(format!(
                "shard {index}/{count}: the index counts from 0 and must be below the count (0/{count} .. {}/{count})",
                count - 1
            ));
        }
        Ok(Shard { index, count })
    }

    /// The shard a scheduler's environment names, when no `--shard` was given: a Slurm array
    /// task (`SLURM_ARRAY_TASK_ID`, counted from `SLURM_ARRAY_TASK_MIN` in steps of
    /// `SLURM_ARRAY_TASK_STEP`, out of `SLURM_ARRAY_TASK_COUNT`, else the count from MIN and
    /// MAX), else a Kubernetes Indexed Job (`JOB_COMPLETION_INDEX` out of `shard_count`, else
    /// `MESHTRACER_SHARD_COUNT`). `None` when neither is set. `var` reads a variable.
    pub fn from_env(
        var: impl Fn(&str) -> Option<String>,
        shard_count: Option<usize>,
    ) -> Result<Option<Shard>, String> {
        let number = |name: &str| -> Result<Option<usize>, String> {
            match var(name) {
                None => Ok(None),
                Some(text) => text
                    .trim()
                    .parse::<usize>()
                    .map(Some)
                    .map_err(|_| format!("{name}={text}: not a whole number")),
            }
        };
        if let Some(id) = number("SLURM_ARRAY_TASK_ID")? {
            let min = number("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
            let step = number("SLURM_ARRAY_TASK_STEP")?.unwrap_or(1).max(1);
            let count = match (number("SLURM_ARRAY_TASK_COUNT")?, number("SLURM_ARRAY_TASK_MAX")?) {
                (Some(count), _) => count,
                (None, Some(max)) if max >= min => (max - min) / step + 1,
                _ => {
                    return Err(
                        "SLURM_ARRAY_TASK_ID is set without SLURM_ARRAY_TASK_COUNT or SLURM_ARRAY_TASK_MAX: give --shard I/N"
                            .into(),
                    )
                }
            };
            if id < min || (id - min) % step != 0 {
                return Err(format!(
                    "SLURM_ARRAY_TASK_ID={id} is not in the array {min}-..:{step}: use a range such as --array=0-{} or give --shard I/N",
                    count.max(1) - 1
                ));
            }
            let shard = Shard::new((id - min) / step, count)
                .map_err(|e| format!("from the Slurm array variables: {e} (use a range such as --array=0-{}, or give --shard I/N)", count.max(1) - 1))?;
            return Ok(Some(shard));
        }
        if let Some(index) = number("JOB_COMPLETION_INDEX")? {
            let count = match shard_count {
                Some(n) => n,
                None => number("MESHTRACER_SHARD_COUNT")?.ok_or(
                    "JOB_COMPLETION_INDEX is set: give the number of shards (the Job's completions) with --shard-count N or MESHTRACER_SHARD_COUNT",
                )?,
            };
            return Shard::new(index, count)
                .map(Some)
                .map_err(|e| format!("from JOB_COMPLETION_INDEX: {e}"));
        }
        if shard_count.is_some() {
            return Err("--shard-count goes with JOB_COMPLETION_INDEX (a Kubernetes Indexed Job), which is not set: give --shard I/N".into());
        }
        Ok(None)
    }

    /// Whether the job (or bad line) with this key belongs to this shard.
    pub fn holds(&self, key: &str) -> bool {
        fnv1a64(key.as_bytes()) % self.count as u64 == self.index as u64
    }

    /// The results file this shard writes: [`RESULTS_FILE`] for the whole batch,
    /// `results.I-of-N.jsonl` for a shard, so that shards never write the same file.
    pub fn results_file(&self) -> String {
        self.jsonl_file("results")
    }

    /// Reads `results.I-of-N.jsonl` back into the shard it names.
    pub fn of_results_file(name: &str) -> Option<Shard> {
        Shard::of_jsonl_file("results", name)
    }

    /// This shard's JSONL file named `stem`: `STEM.jsonl` for the whole, `STEM.I-of-N.jsonl`
    /// for a shard.
    pub fn jsonl_file(&self, stem: &str) -> String {
        if self.count == 1 {
            format!("{stem}.jsonl")
        } else {
            format!("{stem}.{}-of-{}.jsonl", self.index, self.count)
        }
    }

    /// Reads `STEM.I-of-N.jsonl` back into the shard it names.
    pub fn of_jsonl_file(stem: &str, name: &str) -> Option<Shard> {
        let middle = name
            .strip_prefix(stem)?
            .strip_prefix('.')?
            .strip_suffix(".jsonl")?;
        let (i, n) = middle.split_once("-of-")?;
        let all_digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
        if !all_digits(i) || !all_digits(n) {
            return None;
        }
        Shard::new(i.parse().ok()?, n.parse().ok()?).ok()
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Output file names a job may set, each relative to its folder; unset ones take the
/// command line's (`--image-name`, `--depth-out`...). With views, each is a `{view}` pattern.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Outputs {
    /// The image (with views: `--view-name`).
    pub image: Option<String>,
    /// `--depth-out`.
    pub depth: Option<String>,
    /// `--normal-out`.
    pub normal: Option<String>,
    /// `--mask-out`.
    pub mask: Option<String>,
    /// `--segmentation-out`.
    pub segmentation: Option<String>,
    /// `--view-out`.
    pub view: Option<String>,
}

impl Outputs {
    /// The names given, with the option each stands for.
    pub fn named(&self) -> impl Iterator<Item = (&'static str, &str)> {
        [
            ("image", &self.image),
            ("depth", &self.depth),
            ("normal", &self.normal),
            ("mask", &self.mask),
            ("segmentation", &self.segmentation),
            ("view", &self.view),
        ]
        .into_iter()
        .filter_map(|(what, name)| name.as_deref().map(|n| (what, n)))
    }
}

/// One line of a JSONL manifest. Unknown fields are refused, so that a misspelt option fails
/// its job instead of being ignored.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManifestLine {
    /// The job id [default: the model path without its extension].
    pub id: Option<String>,
    /// The model, relative to the manifest's folder or absolute.
    pub model: String,
    /// `--views` spec (a views file is relative to the manifest's folder).
    pub views: Option<String>,
    /// `--width`.
    pub width: Option<u32>,
    /// `--height`.
    pub height: Option<u32>,
    /// `--spp`.
    pub spp: Option<u32>,
    /// `--seed`.
    pub seed: Option<u64>,
    /// `--animation`: a name, or an index as a number or a string.
    #[serde(default, deserialize_with = "animation_ref")]
    pub animation: Option<String>,
    /// `--time`, in seconds (0 or more).
    pub time: Option<f32>,
    /// Output file names.
    #[serde(default)]
    pub outputs: Outputs,
}

/// A manifest's `"animation"`: `"Walk"`, `"1"` or `1`, kept as the text `--animation` takes.
fn animation_ref<'de, D: serde::Deserializer<'de>>(
    deserializer: D,
) -> Result<Option<String>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum NameOrIndex {
        Name(String),
        Index(u64),
    }
    Ok(
        Option::<NameOrIndex>::deserialize(deserializer)?.map(|a| match a {
            NameOrIndex::Name(name) => name,
            NameOrIndex::Index(index) => index.to_string(),
        }),
    )
}

/// A job: what to render and what to call it. Unset options take the command line's.
#[derive(Clone, Debug, PartialEq)]
pub struct Job {
    /// The id: the job's folder inside the output folder.
    pub id: String,
    /// The model path as the manifest gives it (recorded; relative to the manifest's folder).
    pub model_text: String,
    /// The model path to load.
    pub model: PathBuf,
    /// `--views`, a views file already resolved against the manifest's folder.
    pub views: Option<String>,
    /// `--width`.
    pub width: Option<u32>,
    /// `--height`.
    pub height: Option<u32>,
    /// `--spp`.
    pub spp: Option<u32>,
    /// `--seed`.
    pub seed: Option<u64>,
    /// `--animation`.
    pub animation: Option<String>,
    /// `--time`, checked finite and not negative.
    pub time: Option<f32>,
    /// Output file names.
    pub outputs: Outputs,
}

/// One entry of a manifest: a job, or something that could not be one, which fails alone.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    /// What the shard hash reads: the id when there is one (even a refused one), else the
    /// line's text.
    pub key: String,
    /// The id as given or derived (recorded even when refused).
    pub id: Option<String>,
    /// The model path as given.
    pub model: Option<String>,
    /// Where the manifest gives the job, for its errors (`jobs.jsonl line 3`); `None` for a
    /// model found in a folder, whose own path says where.
    pub origin: Option<String>,
    /// The line of a JSONL manifest that gives the job, counted from 1; `None` in a folder.
    pub line: Option<usize>,
    /// The job, or why there is none (without the [`origin`](Entry::origin), which
    /// [`JobRecord::failed`] puts in front).
    pub job: Result<Job, String>,
}

/// Reads a manifest: a folder of models or a JSONL file. Fails only when the manifest itself
/// cannot be read; each bad entry fails alone. Ids given to more than one entry fail all of
/// them (whichever came first would depend on the order of the manifest).
pub fn read_manifest(path: &Path) -> Result<Vec<Entry>, ManifestError> {
    let mut entries = if path.is_dir() {
        read_folder(path)?
    } else {
        let is_model = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| MODEL_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()));
        if is_model {
            return Err(manifest_error(
                path,
                "is a model: a batch takes a folder of models or a JSONL file of jobs (render one model with `meshtracer render`)",
            ));
        }
        let meta = std::fs::metadata(path).map_err(|e| manifest_error(path, e.to_string()))?;
        if let Some(kind) = crate::scene::irregular_kind(&meta) {
            return Err(manifest_error(
                path,
                format!("is {kind}, not a regular file"),
            ));
        }
        let bytes = std::fs::read(path).map_err(|e| manifest_error(path, e.to_string()))?;
        let folder = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        read_jsonl(&bytes, path, folder)
    };
    refuse_shared_ids(&mut entries);
    Ok(entries)
}

/// Fails every job whose id another job of the manifest has too, naming all of them (their
/// lines, or for a folder their model files), so that each can be fixed from its own record.
fn refuse_shared_ids(entries: &mut [Entry]) {
    let mut uses: HashMap<String, Vec<usize>> = HashMap::new();
    for (i, entry) in entries.iter().enumerate() {
        if let (Some(id), Ok(_)) = (&entry.id, &entry.job) {
            uses.entry(id.clone()).or_default().push(i);
        }
    }
    for (id, sharing) in uses {
        if sharing.len() < 2 {
            continue;
        }
        let lines: Option<Vec<String>> = sharing
            .iter()
            .map(|&i| entries[i].line.map(|n| n.to_string()))
            .collect();
        let places = match lines {
            Some(lines) => format!("lines {}", lines.join(", ")),
            None => sharing
                .iter()
                .map(|&i| entries[i].model.clone().unwrap_or_default())
                .collect::<Vec<_>>()
                .join(", "),
        };
        for &i in &sharing {
            entries[i].job = Err(format!(
                "job id '{id}' is given to {} jobs of the manifest ({places}): ids name output folders and must be unique",
                sharing.len()
            ));
        }
    }
}

/// Every model file below `root`, and every zip holding one (a zipped download), sorted by
/// path; hidden files and folders (`.git`...) are skipped and symbolic links to folders not
/// followed (no cycles). A zip is left out when its unzipped copy is beside it (a folder of its
/// name, whose model is found as a file) or a model file has its job id (`duck.glb` beside
/// `duck.zip`), so that no model renders twice and no id is claimed twice.
fn read_folder(root: &Path) -> Result<Vec<Entry>, ManifestError> {
    let mut found: Vec<PathBuf> = Vec::new();
    let mut zips: Vec<PathBuf> = Vec::new();
    let mut pending = vec![root.to_path_buf()];
    while let Some(folder) = pending.pop() {
        let listing =
            std::fs::read_dir(&folder).map_err(|e| manifest_error(&folder, e.to_string()))?;
        for item in listing {
            let item = item.map_err(|e| manifest_error(&folder, e.to_string()))?;
            let name = item.file_name();
            if name.to_string_lossy().starts_with('.') {
                continue;
            }
            let path = item.path();
            let kind = item
                .file_type()
                .map_err(|e| manifest_error(&path, e.to_string()))?;
            if kind.is_dir() {
                pending.push(path);
            } else if path
                .extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| MODEL_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
                && path.is_file()
            {
                found.push(path);
            } else if path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("zip"))
                && path.is_file()
            {
                zips.push(path);
            }
        }
    }
    let ids: std::collections::HashSet<PathBuf> =
        found.iter().map(|p| p.with_extension("")).collect();
    found.extend(zips.into_iter().filter(|zip| {
        let id = zip.with_extension("");
        !id.is_dir() && !ids.contains(&id) && crate::scene::zip_holds_a_model(zip)
    }));
    let mut entries: Vec<(String, Entry)> = found
        .into_iter()
        .map(|path| {
            let relative = path.strip_prefix(root).unwrap_or(&path).to_path_buf();
            let text = slash_path(&relative);
            let id = slash_path(&relative.with_extension(""));
            let job = match (relative.to_str(), check_job_id(&id)) {
                (None, _) => Err(format!(
                    "{}: the file name is not valid UTF-8, so it cannot name a job",
                    path.display()
                )),
                (_, Err(e)) => Err(e),
                (Some(_), Ok(())) => Ok(Job {
                    id: id.clone(),
                    model_text: text.clone(),
                    model: path.clone(),
                    views: None,
                    width: None,
                    height: None,
                    spp: None,
                    seed: None,
                    animation: None,
                    time: None,
                    outputs: Outputs::default(),
                }),
            };
            (
                text.clone(),
                Entry {
                    key: id.clone(),
                    id: Some(id),
                    model: Some(text),
                    origin: None,
                    line: None,
                    job,
                },
            )
        })
        .collect();
    entries.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(entries.into_iter().map(|(_, e)| e).collect())
}

/// A relative path with `/` between its parts, whatever the platform.
fn slash_path(path: &Path) -> String {
    path.components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join("/")
}

/// The entries of a JSONL manifest; blank lines are skipped.
fn read_jsonl(bytes: &[u8], path: &Path, folder: &Path) -> Vec<Entry> {
    let bytes = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes);
    let mut entries = Vec::new();
    for (n, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let text = String::from_utf8_lossy(raw);
        let text = text.trim();
        if text.is_empty() {
            continue;
        }
        let value: Result<serde_json::Value, String> = std::str::from_utf8(raw)
            .map_err(|_| "not valid UTF-8".to_string())
            .and_then(|s| serde_json::from_str(s).map_err(|e| format!("not JSON: {e}")));
        // An id (and model) that can be read is kept even when the rest of the line is wrong,
        // so that the failure is recorded under it and in its shard.
        let field = |name: &str| {
            value
                .as_ref()
                .ok()
                .and_then(|v| v.get(name))
                .and_then(|v| v.as_str())
                .map(str::to_string)
        };
        let (given_id, model) = (field("id"), field("model"));
        let line = value.and_then(|v| {
            if !v.is_object() {
                return Err("a job is a JSON object: {\"model\": ...}".to_string());
            }
            serde_json::from_value::<ManifestLine>(v).map_err(|e| e.to_string())
        });
        let (id, job) = match line {
            Err(e) => (given_id, Err(e)),
            Ok(line) => {
                let id = match &line.id {
                    Some(id) => check_job_id(id).map(|()| id.clone()),
                    None => id_from_model(&line.model),
                };
                let job = id.clone().and_then(|id| job_of_line(line, id, folder));
                (given_id.or(id.ok()), job)
            }
        };
        entries.push(Entry {
            key: id.clone().unwrap_or_else(|| text.to_string()),
            id,
            model,
            origin: Some(format!("{} line {}", path.display(), n + 1)),
            line: Some(n + 1),
            job,
        });
    }
    entries
}

fn job_of_line(line: ManifestLine, id: String, folder: &Path) -> Result<Job, String> {
    for (what, name) in line.outputs.named() {
        check_output_name(name, &format!("outputs.{what}"))?;
    }
    let views = match &line.views {
        Some(spec) => {
            let parsed = crate::jobs::views::ViewSpec::parse(spec).map_err(|e| e.to_string())?;
            Some(match parsed {
                crate::jobs::views::ViewSpec::File(p) if p.is_relative() => {
                    folder.join(p).to_string_lossy().into_owned()
                }
                _ => spec.clone(),
            })
        }
        None => None,
    };
    if line.model.trim().is_empty() {
        return Err("\"model\" is empty".into());
    }
    crate::scene::PoseOptions {
        animation: None,
        time: line.time,
    }
    .check()
    .map_err(|e| format!("\"time\": {e}"))?;
    Ok(Job {
        id,
        model: folder.join(&line.model),
        model_text: line.model,
        views,
        width: line.width,
        height: line.height,
        spp: line.spp,
        seed: line.seed,
        animation: line.animation,
        time: line.time,
        outputs: line.outputs,
    })
}

/// The id of a job without one: its model path without the extension, `/` between folders.
/// A path that leaves the manifest's folder (absolute, or with `..`) cannot name a folder
/// inside the output folder.
fn id_from_model(model: &str) -> Result<String, String> {
    let path = Path::new(model);
    let mut parts = Vec::new();
    for component in path.with_extension("").components() {
        match component {
            Component::Normal(part) => parts.push(part.to_string_lossy().into_owned()),
            Component::CurDir => {}
            _ => {
                return Err(format!(
                    "model '{model}' is outside the manifest's folder, so its path cannot be the job id: give the job an \"id\""
                ))
            }
        }
    }
    let id = parts.join("/");
    check_job_id(&id)?;
    Ok(id)
}

/// Checks that a job id names a folder inside the output folder: not empty, relative, parts
/// separated by `/` that are neither empty nor `.` nor `..`, no backslash or NUL, and not the
/// name of a results file.
pub fn check_job_id(id: &str) -> Result<(), String> {
    let refuse = |why: &str| Err(format!("job id '{id}' refused: {why}"));
    if id.is_empty() {
        return refuse("it is empty");
    }
    if id.starts_with('/') || Path::new(id).is_absolute() {
        return refuse("it is absolute; ids name folders inside the output folder");
    }
    if id.contains('\\') || id.contains('\0') {
        return refuse("it contains a backslash or NUL; separate folders with /");
    }
    for part in id.split('/') {
        match part {
            "" => return refuse("it has an empty part (// or a trailing /)"),
            "." | ".." => {
                return refuse(
                    "it contains '.' or '..'; ids may not climb out of the output folder",
                )
            }
            _ => {}
        }
    }
    let first = id.split('/').next().unwrap_or(id);
    if first == RESULTS_FILE || Shard::of_results_file(first).is_some() {
        return refuse("it is the name of a results file");
    }
    Ok(())
}

/// Checks an output file name (or `{view}` pattern) of a batch job: relative, inside the
/// job's folder (no `..`), and not the job's own record.
pub fn check_output_name(name: &str, what: &str) -> Result<(), String> {
    let refuse = |why: &str| Err(format!("{what} '{name}' refused: {why}"));
    if name.trim().is_empty() {
        return refuse("it is empty");
    }
    let path = Path::new(name);
    if name.starts_with('/') || path.is_absolute() {
        return refuse("it is absolute; in a batch, output names are relative to the job's folder");
    }
    if name.contains('\\') || name.contains('\0') {
        return refuse("it contains a backslash or NUL; separate folders with /");
    }
    if path
        .components()
        .any(|c| !matches!(c, Component::Normal(_) | Component::CurDir))
    {
        return refuse("it contains '..'; outputs may not climb out of the job's folder");
    }
    if output_key(name) == Path::new(JOB_FILE) {
        return refuse("job.json is the job's record");
    }
    Ok(())
}

/// An output name without its `.` parts: two names with the same key are the same file.
pub fn output_key(name: &str) -> PathBuf {
    Path::new(name)
        .components()
        .filter(|c| !matches!(c, Component::CurDir))
        .collect()
}

/// How a job ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Rendered, every output written and hashed.
    Ok,
    /// Not rendered; `error` says why.
    Failed,
    /// Done by an earlier run and verified (`--resume`): its outputs and timings are that
    /// run's.
    Skipped,
}

/// Wall times of a job, in seconds; `None` for phases a failed job did not finish.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Timings {
    /// Load: parse, flatten, tangents.
    pub load: Option<f64>,
    /// BVH build.
    pub bvh: Option<f64>,
    /// Rendering, every view.
    pub render: Option<f64>,
    /// The whole job, writing and hashing included.
    pub total: f64,
}

/// One output file of a job.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct OutputRecord {
    /// Path relative to the batch's output folder, `/` between folders.
    pub path: String,
    /// SHA-256 of the file's bytes, lower-case hex (what `sha256sum` prints).
    pub sha256: String,
}

/// A file a job's model refers to (a buffer, a texture, a material library), as it was when
/// the job was rendered: `--resume` redoes a job one of whose inputs changed, which the
/// fingerprint (the model file's own bytes) does not see.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct InputRecord {
    /// Path relative to the model's folder (to the model itself when it is a folder), `/`
    /// between folders; absolute for a file outside it (`--allow-external-files`).
    pub path: String,
    /// SHA-256 of the file's bytes, lower-case hex; `missing` for a file that was not there
    /// (a texture drawn without), `unreadable (why)` for one that could not be read.
    pub sha256: String,
}

/// The folder a model's inputs are recorded relative to: the model's own folder, or the model
/// when it is a folder (an unzipped download, whose model file may sit below it).
fn input_base(model: &Path) -> PathBuf {
    if model.is_dir() {
        return model.to_path_buf();
    }
    match model.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// What a file's bytes are now, for an [`InputRecord`].
fn input_hash(path: &Path) -> String {
    match sha256_file(path) {
        Ok(hash) => hash,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => "missing".to_string(),
        Err(e) => format!("unreadable ({e})"),
    }
}

/// The records of the files `inputs` (a loaded scene's [`inputs`]) of the model at `model`.
///
/// [`inputs`]: crate::scene::Scene::inputs
pub fn input_records(model: &Path, inputs: &[PathBuf]) -> Vec<InputRecord> {
    let base = input_base(model);
    inputs
        .iter()
        .map(|file| {
            let path = match file.strip_prefix(&base) {
                Ok(inside) => inside
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy().into_owned())
                    .collect::<Vec<_>>()
                    .join("/"),
                Err(_) => file.to_string_lossy().into_owned(),
            };
            InputRecord {
                path,
                sha256: input_hash(file),
            }
        })
        .collect()
}

/// The SHA-256 of the model file at `model`, followed by each of its `inputs` (the files it
/// refers to) with theirs: what a view's fingerprint and a tile's hold of the model, so that
/// `--resume` renders again the views of a model whose textures or buffers changed and `merge`
/// refuses tiles rendered before and after such a change. A model that refers to nothing (a
/// GLB, a zip) gives its file's hash alone.
pub fn model_digest(model: &Path, inputs: &[PathBuf]) -> String {
    let mut digest = sha256_file(model).unwrap_or_else(|e| format!("unreadable ({e})"));
    for input in input_records(model, inputs) {
        digest.push_str(&format!("\ninput {} {}", input.path, input.sha256));
    }
    digest
}

/// Checks that each of `inputs` of the model at `model` is as recorded; the error names the
/// first that changed.
pub fn verify_inputs(model: &Path, inputs: &[InputRecord]) -> Result<(), String> {
    let base = input_base(model);
    for input in inputs {
        let now = input_hash(&base.join(&input.path));
        if now != input.sha256 {
            return Err(match (input.sha256.as_str(), now.as_str()) {
                ("missing", _) => format!("{} appeared since the job was rendered", input.path),
                (_, "missing") => format!("{} is gone since the job was rendered", input.path),
                _ => format!("{} changed since the job was rendered", input.path),
            });
        }
    }
    Ok(())
}

/// A job's line in the results file, and its `job.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JobRecord {
    /// The job id; `null` for a manifest line where none could be read.
    pub id: Option<String>,
    /// The model path as the manifest gives it.
    pub model: Option<String>,
    /// How the job ended.
    pub status: Status,
    /// Why it failed (the whole error chain).
    pub error: Option<String>,
    /// Triangles traced.
    pub triangles: Option<usize>,
    /// Wall times.
    pub seconds: Timings,
    /// Every file written, in the order written.
    pub outputs: Vec<OutputRecord>,
    /// What the load and the texture decoding warned about (a texture drawn without, an
    /// extension approximated), as `render` prints them; absent in records of older runs.
    #[serde(default)]
    pub warnings: Vec<String>,
    /// The files the model refers to, as they were when it was rendered; absent in records
    /// of older runs (and empty for a model that holds everything, a GLB or a zip).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub inputs: Vec<InputRecord>,
    /// SHA-256 of what the job was asked to do (meshtracer's version, the options, the model
    /// file's hash); `--resume` redoes a job whose fingerprint changed.
    pub fingerprint: Option<String>,
}

impl JobRecord {
    /// A job that failed before producing anything; the error starts with where the manifest
    /// gives the job, when it is a line of a file.
    pub fn failed(entry: &Entry, error: String, total: f64) -> JobRecord {
        let error = match &entry.origin {
            Some(origin) => format!("{origin}: {error}"),
            None => error,
        };
        JobRecord {
            id: entry.id.clone(),
            model: entry.model.clone(),
            status: Status::Failed,
            error: Some(error),
            triangles: None,
            seconds: Timings {
                total,
                ..Timings::default()
            },
            outputs: Vec::new(),
            warnings: Vec::new(),
            inputs: Vec::new(),
            fingerprint: None,
        }
    }

    /// The order of results files: by id, then the id-less lines by their error, whose
    /// numbers compare as numbers: each starts with its manifest line (`jobs.jsonl line 2: `),
    /// so line 2 comes before line 10. The same for any order of the manifest and any
    /// sharding, and for records read back from a results file (which keep no line number
    /// but in their error).
    pub fn sort(records: &mut [JobRecord]) {
        records.sort_by(|a, b| {
            (a.id.is_none(), &a.id)
                .cmp(&(b.id.is_none(), &b.id))
                .then_with(|| {
                    numbers_as_numbers(
                        a.error.as_deref().unwrap_or_default(),
                        b.error.as_deref().unwrap_or_default(),
                    )
                })
        });
    }

    /// Checks that every output the record lists is in `dir` with its recorded hash.
    pub fn verify(&self, dir: &Path) -> Result<(), String> {
        verify_outputs(dir, &self.outputs)
    }
}

/// Checks that each of `outputs` (none is an error: nothing to vouch for) is in `dir` with its
/// recorded hash; the error names the first that is missing, unreadable or changed.
pub fn verify_outputs(dir: &Path, outputs: &[OutputRecord]) -> Result<(), String> {
    if outputs.is_empty() {
        return Err("no outputs recorded".into());
    }
    for output in outputs {
        let path = dir.join(&output.path);
        match sha256_file(&path) {
            Ok(hash) if hash == output.sha256 => {}
            Ok(_) => return Err(format!("{} changed since it was written", output.path)),
            Err(e) => return Err(format!("{}: {e}", output.path)),
        }
    }
    Ok(())
}

/// Compares two texts with each run of ASCII digits taken as the number it writes
/// (`line 2` < `line 10`; leading zeros aside, `007` = `7`, then the shorter run first so
/// that the order is total) and the rest character by character.
fn numbers_as_numbers(a: &str, b: &str) -> std::cmp::Ordering {
    let (mut a, mut b) = (a, b);
    loop {
        let digits = |s: &str| s.find(|c: char| !c.is_ascii_digit()).unwrap_or(s.len());
        let (da, db) = (digits(a), digits(b));
        if da > 0 && db > 0 {
            let (na, nb) = (
                a[..da].trim_start_matches('0'),
                b[..db].trim_start_matches('0'),
            );
            let order = (na.len(), na, da).cmp(&(nb.len(), nb, db));
            if order.is_ne() {
                return order;
            }
            (a, b) = (&a[da..], &b[db..]);
            continue;
        }
        let (mut ca, mut cb) = (a.chars(), b.chars());
        match (ca.next(), cb.next()) {
            (None, None) => return std::cmp::Ordering::Equal,
            (x, y) if x != y => return x.cmp(&y),
            _ => (a, b) = (ca.as_str(), cb.as_str()),
        }
    }
}

/// Results as JSONL: one record a line, in [`JobRecord::sort`] order.
pub fn results_jsonl(records: &[JobRecord]) -> String {
    let mut sorted = records.to_vec();
    JobRecord::sort(&mut sorted);
    sorted
        .iter()
        .map(|r| serde_json::to_string(r).expect("a record serialises") + "\n")
        .collect()
}

/// Reads a results file written by [`results_jsonl`]; a line that is not a record is an error
/// naming the file and line (results files are written whole, by renaming, so there are no
/// torn lines to forgive).
pub fn read_results(path: &Path) -> Result<Vec<JobRecord>, ManifestError> {
    let text = std::fs::read_to_string(path).map_err(|e| manifest_error(path, e.to_string()))?;
    text.lines()
        .enumerate()
        .filter(|(_, line)| !line.trim().is_empty())
        .map(|(n, line)| {
            serde_json::from_str(line)
                .map_err(|e| manifest_error(path, format!("line {}: {e}", n + 1)))
        })
        .collect()
}

/// SHA-256 of a file, lower-case hex.
pub fn sha256_file(path: &Path) -> std::io::Result<String> {
    use sha2::Digest;
    // A FIFO or a device would block or never end: refused before it is opened.
    if let Some(kind) = crate::scene::irregular_kind(&std::fs::metadata(path)?) {
        return Err(std::io::Error::other(format!(
            "is {kind}, not a regular file"
        )));
    }
    let mut file = std::fs::File::open(path)?;
    let mut hasher = sha2::Sha256::new();
    let mut buffer = vec![0u8; 1 << 16];
    loop {
        let n = file.read(&mut buffer)?;
        if n == 0 {
            break;
        }
        hasher.update(&buffer[..n]);
    }
    Ok(hex(&hasher.finalize()))
}

/// The version of [`FingerprintRecord`]'s layout. A job's fingerprint changes (and `--resume`
/// redoes it) whenever its options, the model file or meshtracer's version change; a change of
/// this layout would change every fingerprint at once, so it is versioned and pinned by a test.
pub const FINGERPRINT_RECORD_VERSION: u32 = 1;

/// What a job's resume fingerprint is computed from: every render option of the job, in a
/// fixed order, with its value written as Rust's `Debug` writes it (`Some(32)`, `"name.png"`,
/// `Vec3(1.0, 2.0, 3.0)`, `false`). The record is explicit rather than the `Debug` text of the
/// command line's option struct, so that renaming a flag or moving code leaves finished
/// batches finished.
///
/// Version 1, the layout meshtracer 0.1.0 wrote: `RenderArgs { name: value, ... }`, the load
/// options nested as the value of `load` in a `LoadArgs { ... }` group. The names `RenderArgs`
/// and `LoadArgs` are part of the layout, not references to any type.
#[derive(Clone, Debug, PartialEq)]
pub struct FingerprintRecord {
    group: &'static str,
    fields: Vec<(&'static str, String)>,
}

impl FingerprintRecord {
    /// The record of a job's render options (version 1's outer group).
    pub fn render_options() -> FingerprintRecord {
        FingerprintRecord::group("RenderArgs")
    }

    /// The record of a job's load options (version 1's group nested under `load`).
    pub fn load_options() -> FingerprintRecord {
        FingerprintRecord::group("LoadArgs")
    }

    fn group(group: &'static str) -> FingerprintRecord {
        FingerprintRecord {
            group,
            fields: Vec::new(),
        }
    }

    /// Appends option `name` with `value` (written as `Debug` writes it).
    pub fn field(mut self, name: &'static str, value: &dyn std::fmt::Debug) -> Self {
        self.fields.push((name, format!("{value:?}")));
        self
    }

    /// Appends option `name` with `value` unless it is the type's default: an option added
    /// after version 1 whose default renders what version 1 rendered leaves the record of a
    /// job that does not use it unchanged.
    pub fn field_unless_default<T: std::fmt::Debug + Default + PartialEq>(
        self,
        name: &'static str,
        value: &T,
    ) -> Self {
        if *value == T::default() {
            self
        } else {
            self.field(name, value)
        }
    }

    /// Appends a nested group under `name`.
    pub fn group_field(mut self, name: &'static str, group: &FingerprintRecord) -> Self {
        self.fields.push((name, group.text()));
        self
    }

    /// The record as hashed: `Group { name: value, ... }`.
    pub fn text(&self) -> String {
        if self.fields.is_empty() {
            return self.group.to_string();
        }
        let fields: Vec<String> = self
            .fields
            .iter()
            .map(|(name, value)| format!("{name}: {value}"))
            .collect();
        format!("{} {{ {} }}", self.group, fields.join(", "))
    }

    /// The job's fingerprint: SHA-256 (hex) of `meshtracer VERSION`, the model file's SHA-256
    /// (`model_sha256`) and this record, one a line.
    pub fn fingerprint(&self, meshtracer_version: &str, model_sha256: &str) -> String {
        sha256_hex(
            format!(
                "meshtracer {meshtracer_version}\nmodel sha256 {model_sha256}\n{}",
                self.text()
            )
            .as_bytes(),
        )
    }
}

/// SHA-256 of bytes, lower-case hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    hex(&sha2::Sha256::digest(bytes))
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    /// The record writes what `derive(Debug)` of version 1's option structs wrote.
    #[test]
    fn a_fingerprint_record_is_written_as_debug_writes_a_struct() {
        #[derive(Debug)]
        struct LoadArgs {
            strict: bool,
        }
        #[derive(Debug)]
        #[allow(dead_code)]
        struct RenderArgs {
            model: std::path::PathBuf,
            width: Option<u32>,
            up: Option<glam::Vec3>,
            load: LoadArgs,
        }
        let args = RenderArgs {
            model: "a b/\"c\".gltf".into(),
            width: Some(32),
            up: Some(glam::Vec3::new(0.0, 1.0, -0.5)),
            load: LoadArgs { strict: true },
        };
        let load = FingerprintRecord::load_options().field("strict", &args.load.strict);
        let record = FingerprintRecord::render_options()
            .field("model", &args.model)
            .field("width", &args.width)
            .field("up", &args.up)
            .group_field("load", &load);
        assert_eq!(record.text(), format!("{args:?}"));
        assert_eq!(FingerprintRecord::load_options().text(), "LoadArgs");
    }

    use super::*;

    /// Inputs are recorded relative to the model's folder (or the model, when it is a
    /// folder) and verified against the files as they are now, naming the first that differs.
    #[test]
    fn inputs_are_recorded_beside_the_model_and_their_changes_named() {
        let dir = tempfile::tempdir().unwrap();
        let model = dir.path().join("m.gltf");
        std::fs::write(&model, "{}").unwrap();
        std::fs::create_dir(dir.path().join("tex")).unwrap();
        let (bin, png) = (dir.path().join("m.bin"), dir.path().join("tex/a.png"));
        std::fs::write(&bin, b"bytes").unwrap();
        std::fs::write(&png, b"pixels").unwrap();
        let gone = dir.path().join("gone.png");
        let records = input_records(&model, &[bin.clone(), png.clone(), gone.clone()]);
        let paths: Vec<&str> = records.iter().map(|r| r.path.as_str()).collect();
        assert_eq!(paths, ["m.bin", "tex/a.png", "gone.png"]);
        assert_eq!(records[0].sha256, sha256_hex(b"bytes"));
        assert_eq!(records[2].sha256, "missing");
        assert_eq!(verify_inputs(&model, &records), Ok(()));
        // The same files seen through the folder as the model (an unzipped download).
        assert_eq!(
            input_records(dir.path(), std::slice::from_ref(&png))[0].path,
            "tex/a.png"
        );

        std::fs::write(&png, b"other pixels").unwrap();
        assert_eq!(
            verify_inputs(&model, &records),
            Err("tex/a.png changed since the job was rendered".to_string())
        );
        std::fs::write(&png, b"pixels").unwrap();
        std::fs::write(&gone, b"new").unwrap();
        assert_eq!(
            verify_inputs(&model, &records),
            Err("gone.png appeared since the job was rendered".to_string())
        );
        std::fs::remove_file(&gone).unwrap();
        std::fs::remove_file(&bin).unwrap();
        assert_eq!(
            verify_inputs(&model, &records),
            Err("m.bin is gone since the job was rendered".to_string())
        );
    }

    #[test]
    fn fnv1a64_matches_the_reference_vectors() {
        // From the FNV reference test suite (Landon Curt Noll's fnv_test.c).
        assert_eq!(fnv1a64(b""), 0xcbf29ce484222325);
        assert_eq!(fnv1a64(b"a"), 0xaf63dc4c8601ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x85944171f73967e8);
    }

    #[test]
    fn every_key_is_in_exactly_one_shard() {
        for key in ["a", "cornell-box", "sub/shapes", "x/y/z", ""] {
            let holders = (0..5)
                .filter(|&i| Shard::new(i, 5).unwrap().holds(key))
                .count();
            assert_eq!(holders, 1, "{key}");
            assert!(Shard::ALL.holds(key));
        }
    }

    #[test]
    fn shards_parse_and_name_their_files() {
        assert_eq!(Shard::parse("1/3"), Ok(Shard { index: 1, count: 3 }));
        assert!(Shard::parse("3/3").is_err());
        assert!(Shard::parse("0/0").is_err());
        assert!(Shard::parse("1").is_err());
        assert!(Shard::parse("-1/3").is_err());
        assert_eq!(Shard::ALL.results_file(), "results.jsonl");
        let shard = Shard::new(2, 7).unwrap();
        assert_eq!(shard.results_file(), "results.2-of-7.jsonl");
        assert_eq!(Shard::of_results_file("results.2-of-7.jsonl"), Some(shard));
        assert_eq!(Shard::of_results_file("results.7-of-7.jsonl"), None);
        assert_eq!(Shard::of_results_file("results.jsonl"), None);
        assert_eq!(Shard::of_results_file("results.a-of-7.jsonl"), None);
    }

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |name| {
            vars.iter()
                .find(|(k, _)| *k == name)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn shards_come_from_slurm_and_kubernetes_variables() {
        let shard = |vars: &[(&str, &str)], count| Shard::from_env(env(vars), count);
        assert_eq!(shard(&[], None), Ok(None));
        let slurm = [
            ("SLURM_ARRAY_TASK_ID", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
        ];
        assert_eq!(shard(&slurm, None), Ok(Some(Shard { index: 2, count: 3 })));
        // --array=1-3: ids 1..3 are shards 0..2.
        let from_one = [
            ("SLURM_ARRAY_TASK_ID", "1"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_MAX", "3"),
        ];
        assert_eq!(
            shard(&from_one, None),
            Ok(Some(Shard { index: 0, count: 3 }))
        );
        // --array=0-8:4 (0, 4, 8).
        let stepped = [
            ("SLURM_ARRAY_TASK_ID", "4"),
            ("SLURM_ARRAY_TASK_STEP", "4"),
            ("SLURM_ARRAY_TASK_MAX", "8"),
        ];
        assert_eq!(
            shard(&stepped, None),
            Ok(Some(Shard { index: 1, count: 3 }))
        );
        assert!(shard(&[("SLURM_ARRAY_TASK_ID", "5")], None).is_err());
        let out_of_range = [
            ("SLURM_ARRAY_TASK_ID", "3"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
        ];
        assert!(shard(&out_of_range, None).is_err());
        let k8s = [("JOB_COMPLETION_INDEX", "1")];
        assert_eq!(shard(&k8s, Some(4)), Ok(Some(Shard { index: 1, count: 4 })));
        assert!(shard(&k8s, None).is_err());
        let k8s_env = [
            ("JOB_COMPLETION_INDEX", "1"),
            ("MESHTRACER_SHARD_COUNT", "2"),
        ];
        assert_eq!(
            shard(&k8s_env, None),
            Ok(Some(Shard { index: 1, count: 2 }))
        );
        assert!(shard(&[("JOB_COMPLETION_INDEX", "x")], Some(2)).is_err());
        assert!(shard(&[], Some(2)).is_err());
    }

    #[test]
    fn ids_and_output_names_stay_inside_the_output_folder() {
        for good in ["a", "sub/shapes", "Duck/glTF-Binary/Duck", "a.b", "..a"] {
            assert_eq!(check_job_id(good), Ok(()), "{good}");
        }
        for bad in [
            "",
            "/etc",
            "../escape",
            "a/../../b",
            "a/./b",
            "a//b",
            "a/",
            "a\\b",
            ".",
            "results.jsonl",
            "results.0-of-2.jsonl/x",
        ] {
            assert!(check_job_id(bad).is_err(), "{bad}");
        }
        for good in ["image.png", "depth/{view:03}.png", "./a.png", "v.json"] {
            assert_eq!(check_output_name(good, "x"), Ok(()), "{good}");
        }
        for bad in [
            "",
            "/tmp/a.png",
            "../a.png",
            "a/../../b.png",
            "job.json",
            "./job.json",
        ] {
            assert!(check_output_name(bad, "x").is_err(), "{bad}");
        }
    }

    #[test]
    fn a_bad_line_fails_alone_and_keeps_what_can_be_read() {
        let text = br#"{"model": "a.glb"}
not json

{"id": "../escape", "model": "b.glb"}
{"id": "typo", "model": "c.glb", "sp": 4}
{"model": "/abs/d.glb"}
{"id": "e", "model": "sub/e.obj", "views": "views.json", "outputs": {"image": "x.exr"}}
[1, 2]
{"id": "f", "model": "f.glb", "outputs": {"depth": "../d.png"}}
"#;
        let entries = read_jsonl(text, Path::new("m/jobs.jsonl"), Path::new("m"));
        assert_eq!(entries.len(), 8, "the blank line is no job");
        let a = entries[0].job.as_ref().unwrap();
        assert_eq!(
            (a.id.as_str(), a.model.as_path()),
            ("a", Path::new("m/a.glb"))
        );
        assert_eq!(entries[1].origin.as_deref(), Some("m/jobs.jsonl line 2"));
        assert_eq!(entries[1].id, None);
        assert_eq!(entries[1].key, "not json");
        assert!(entries[2]
            .job
            .as_ref()
            .unwrap_err()
            .contains("'../escape' refused"));
        assert_eq!(entries[2].key, "../escape");
        assert!(entries[3]
            .job
            .as_ref()
            .unwrap_err()
            .contains("unknown field `sp`"));
        assert_eq!(entries[3].id.as_deref(), Some("typo"));
        assert!(entries[4]
            .job
            .as_ref()
            .unwrap_err()
            .contains("give the job an \"id\""));
        let e = entries[5].job.as_ref().unwrap();
        assert_eq!(e.views.as_deref(), Some("m/views.json"));
        assert_eq!(e.outputs.image.as_deref(), Some("x.exr"));
        assert!(entries[6].job.is_err());
        assert!(entries[7]
            .job
            .as_ref()
            .unwrap_err()
            .contains("outputs.depth"));
    }

    #[test]
    fn a_line_may_pose_its_model() {
        let text = br#"{"id": "a", "model": "a.glb", "animation": "Run", "time": 0.3}
{"id": "b", "model": "b.glb", "animation": 2}
{"id": "c", "model": "c.glb", "time": -1}
{"id": "d", "model": "d.glb", "animation": [1]}
"#;
        let entries = read_jsonl(text, Path::new("m/jobs.jsonl"), Path::new("m"));
        let a = entries[0].job.as_ref().unwrap();
        assert_eq!((a.animation.as_deref(), a.time), (Some("Run"), Some(0.3)));
        let b = entries[1].job.as_ref().unwrap();
        assert_eq!((b.animation.as_deref(), b.time), (Some("2"), None));
        let c = entries[2].job.as_ref().unwrap_err();
        assert!(c.contains("\"time\"") && c.contains("-1"), "{c}");
        assert!(
            entries[3].job.is_err(),
            "an animation is a name or an index"
        );
    }

    #[test]
    fn records_sort_by_id_whatever_the_order() {
        let record = |id: Option<&str>, error: Option<&str>| JobRecord {
            id: id.map(str::to_string),
            model: None,
            status: Status::Failed,
            error: error.map(str::to_string),
            triangles: None,
            seconds: Timings::default(),
            outputs: Vec::new(),
            warnings: Vec::new(),
            inputs: Vec::new(),
            fingerprint: None,
        };
        let a = vec![
            record(None, Some("z")),
            record(Some("b"), None),
            record(Some("a/c"), None),
            record(None, Some("y")),
        ];
        let mut b = a.clone();
        b.reverse();
        assert_eq!(results_jsonl(&a), results_jsonl(&b));
        let first = results_jsonl(&a).lines().next().unwrap().to_string();
        assert!(first.starts_with(r#"{"id":"a/c""#), "{first}");
    }

    #[test]
    fn id_less_records_sort_by_their_line_as_a_number() {
        use std::cmp::Ordering::{Equal, Greater, Less};
        assert_eq!(numbers_as_numbers("j line 2: x", "j line 10: a"), Less);
        assert_eq!(numbers_as_numbers("j line 10: a", "j line 9: z"), Greater);
        assert_eq!(numbers_as_numbers("line 7", "line 007"), Less);
        assert_eq!(numbers_as_numbers("line 7: b", "line 7: a"), Greater);
        assert_eq!(numbers_as_numbers("a1b", "a1b"), Equal);
        assert_eq!(numbers_as_numbers("", "0"), Less);
    }

    #[test]
    fn sha256_is_what_sha256sum_prints() {
        assert_eq!(
            sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}
