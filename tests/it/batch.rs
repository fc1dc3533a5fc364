//! `meshtracer batch` and `batch-merge` through the real binary: a folder manifest with a
//! broken model, a JSONL manifest with a malformed line and ids or names that try to leave the
//! output folder, shards (by --shard and by the Slurm variables) whose union is the whole run
//! byte for byte and whose assignment survives a shuffled manifest, --resume after damage and
//! after a real kill, the example Slurm and Kubernetes scripts run locally for every index,
//! and (with MESHTRACER_SAMPLES) a batch over every shared sample model plus a broken file.

use crate::common::{root, s};
use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Every job renders this small: the tests check bookkeeping, not pictures.
const SMALL: [&str; 7] = ["--width", "32", "--height", "24", "--spp", "1", "-q"];

/// Scheduler variables a developer's or CI's shell might carry, which would shard a run.
const SCHEDULER_VARS: [&str; 8] = [
    "SLURM_ARRAY_TASK_ID",
    "SLURM_ARRAY_TASK_COUNT",
    "SLURM_ARRAY_TASK_MIN",
    "SLURM_ARRAY_TASK_MAX",
    "SLURM_ARRAY_TASK_STEP",
    "JOB_COMPLETION_INDEX",
    "MESHTRACER_SHARD_COUNT",
    "MESHTRACER_OPTIONS",
];

/// The binary with no scheduler variables but `env`.
fn command(program: &str, args: &[&str], env: &[(&str, &str)]) -> Command {
    let mut cmd = crate::common::program(program);
    cmd.args(args);
    for var in SCHEDULER_VARS {
        cmd.env_remove(var);
    }
    cmd.envs(env.iter().copied());
    cmd
}

/// Runs a command; on an unexpected outcome, panics with the command, stdout and stderr.
fn check(mut cmd: Command, expect_success: bool) -> Output {
    let out = cmd.output().expect("the command runs");
    if out.status.success() != expect_success {
        panic!(
            "{cmd:?}\nexpected success = {expect_success}, got {}\n--- stdout\n{}\n--- stderr\n{}",
            out.status,
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    out
}

/// `meshtracer batch MANIFEST -o OUT` at the small size, with `extra` options and `env`.
fn batch(manifest: &Path, out: &Path, extra: &[&str], env: &[(&str, &str)], ok: bool) -> Output {
    let mut args = vec!["batch", s(manifest), "-o", s(out)];
    args.extend_from_slice(&SMALL);
    args.extend_from_slice(extra);
    check(command(env!("CARGO_BIN_EXE_meshtracer"), &args, env), ok)
}

fn merge(out: &Path, ok: bool) -> Output {
    let args = ["batch-merge", s(out), "-q"];
    check(command(env!("CARGO_BIN_EXE_meshtracer"), &args, &[]), ok)
}

/// The records of a results file, in file order.
fn records(path: &Path) -> Vec<Value> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{}: {e}: {l}", path.display())))
        .collect()
}

/// Records keyed by id (failed lines without one under their error).
fn by_id(records: &[Value]) -> BTreeMap<String, Value> {
    records
        .iter()
        .map(|r| {
            let key = r["id"]
                .as_str()
                .map_or_else(|| format!("(no id) {}", r["error"]), str::to_string);
            (key, r.clone())
        })
        .collect()
}

/// A record without its timings, which differ from run to run.
fn timeless(record: &Value) -> Value {
    let mut r = record.clone();
    r.as_object_mut().unwrap().remove("seconds");
    r
}

fn sha256(path: &Path) -> String {
    use sha2::Digest;
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    sha2::Sha256::digest(&bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Every output a record lists exists under `out` with the recorded hash, and lies inside
/// the job's folder.
fn assert_hashes_match(out: &Path, record: &Value) {
    let id = record["id"].as_str().unwrap();
    let outputs = record["outputs"].as_array().unwrap();
    assert!(!outputs.is_empty(), "{id}: no outputs");
    for o in outputs {
        let path = o["path"].as_str().unwrap();
        assert!(
            path.starts_with(&format!("{id}/")),
            "{path} is not in {id}/"
        );
        assert_eq!(
            sha256(&out.join(path)),
            o["sha256"].as_str().unwrap(),
            "{path}"
        );
    }
}

/// Every file below `dir` (relative path -> bytes), without the run records (job.json and
/// results files hold timings).
fn outputs_tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(dir: &Path, base: &Path, files: &mut BTreeMap<String, Vec<u8>>) {
        for item in std::fs::read_dir(dir).unwrap().flatten() {
            let path = item.path();
            if path.is_dir() {
                walk(&path, base, files);
                continue;
            }
            let name = path.file_name().unwrap().to_str().unwrap();
            if name == "job.json" || (name.starts_with("results") && name.ends_with(".jsonl")) {
                continue;
            }
            let relative = path
                .strip_prefix(base)
                .unwrap()
                .to_str()
                .unwrap()
                .to_string();
            files.insert(relative, std::fs::read(&path).unwrap());
        }
    }
    let mut files = BTreeMap::new();
    walk(dir, dir, &mut files);
    files
}

/// Every path below `dir`, folders included.
fn all_paths(dir: &Path) -> BTreeSet<PathBuf> {
    let mut paths = BTreeSet::new();
    let mut pending = vec![dir.to_path_buf()];
    while let Some(d) = pending.pop() {
        for item in std::fs::read_dir(&d).unwrap().flatten() {
            let path = item.path();
            if path.is_dir() {
                pending.push(path.clone());
            }
            paths.insert(path);
        }
    }
    paths
}

/// A folder of models: the Cornell box, the OBJ shapes one folder down (with their MTL), and
/// optionally a broken file.
fn models_folder(dir: &Path, broken: bool) -> PathBuf {
    let models = dir.join("models");
    std::fs::create_dir_all(models.join("sub")).unwrap();
    let assets = root().join("assets");
    std::fs::copy(
        assets.join("cornell-box.gltf"),
        models.join("cornell-box.gltf"),
    )
    .unwrap();
    for name in ["shapes.obj", "shapes.mtl"] {
        std::fs::copy(assets.join(name), models.join("sub").join(name)).unwrap();
    }
    if broken {
        std::fs::write(models.join("broken.glb"), b"glTF this is not").unwrap();
    }
    models
}

/// A JSONL manifest of `lines` beside a copy of the models, and its path.
fn jsonl_manifest(dir: &Path, name: &str, lines: &[String]) -> PathBuf {
    let models = models_folder(dir, false);
    let path = models.join(name);
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    path
}

/// Nine jobs of both models: different seeds, sample counts and sizes, two orbits with depth,
/// one path-traced; enough for every one of 3 shards to get some.
fn nine_jobs() -> Vec<String> {
    (0..9)
        .map(|k| {
            let model = if k % 2 == 0 {
                "cornell-box.gltf"
            } else {
                "sub/shapes.obj"
            };
            let extra = match k {
                2 => r#", "views": "orbit:2", "outputs": {"depth": "depth/{view}.npy"}"#,
                5 => r#", "views": "orbit:2", "width": 20"#,
                7 => r#", "spp": 2, "outputs": {"image": "beauty.exr", "mask": "mask.png"}"#,
                _ => "",
            };
            format!(r#"{{"id": "job-{k}", "model": "{model}", "seed": {k}{extra}}}"#)
        })
        .collect()
}

/// A folder of two good models and a broken file: two jobs ok, one failed naming the file,
/// exit non-zero; results.jsonl has the three, with hashes that match the files.
#[test]
fn a_folder_batch_records_every_model_and_isolates_the_broken_one() {
    let dir = tempfile::tempdir().unwrap();
    let models = models_folder(dir.path(), true);
    let out = dir.path().join("out");
    let run = batch(&models, &out, &["--depth-out", "aov/depth.npy"], &[], false);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("1 of 3 jobs failed"), "{stderr}");
    assert!(stderr.contains("broken.glb"), "{stderr}");

    let results = records(&out.join("results.jsonl"));
    assert_eq!(results.len(), 3);
    let jobs = by_id(&results);
    assert_eq!(
        jobs.keys().collect::<Vec<_>>(),
        ["broken", "cornell-box", "sub/shapes"],
        "ids are the model paths without extension"
    );
    let broken = &jobs["broken"];
    assert_eq!(broken["status"], "failed");
    assert!(
        broken["error"].as_str().unwrap().contains("broken.glb"),
        "{broken}"
    );
    assert!(broken["outputs"].as_array().unwrap().is_empty());
    for id in ["cornell-box", "sub/shapes"] {
        let job = &jobs[id];
        assert_eq!(job["status"], "ok", "{job}");
        assert!(job["triangles"].as_u64().unwrap() > 0);
        for phase in ["load", "bvh", "render", "total"] {
            assert!(
                job["seconds"][phase].as_f64().is_some(),
                "{id}: no {phase} time"
            );
        }
        let paths: Vec<&str> = job["outputs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|o| o["path"].as_str().unwrap())
            .collect();
        assert_eq!(
            paths,
            [format!("{id}/image.png"), format!("{id}/aov/depth.npy")]
        );
        assert_hashes_match(&out, job);
        let image = image::open(out.join(id).join("image.png")).unwrap();
        assert_eq!((image.width(), image.height()), (32, 24));
    }
    // The hash is the one coreutils prints, so anyone can check a file.
    if let Ok(sum) = Command::new("sha256sum")
        .arg(out.join("cornell-box/image.png"))
        .output()
    {
        let printed = String::from_utf8_lossy(&sum.stdout);
        let recorded = jobs["cornell-box"]["outputs"][0]["sha256"]
            .as_str()
            .unwrap();
        assert!(printed.starts_with(recorded), "{printed} vs {recorded}");
    }
}

/// A folder of zipped downloads: each zip holding a model is a job (id: its path without
/// `.zip`) that renders as the model's files do, one holding two fails naming them, so does
/// one whose only model leaves the archive (`../evil.gltf`, `/abs.glb`) and so does one cut
/// short (a download that did not finish: its directory is lost), and a zip without a model, a file that only ends in `.zip`, a zip beside its unzipped copy and one
/// beside a model of its id are not jobs.
#[test]
fn a_folder_batch_renders_zipped_downloads_once() {
    let dir = tempfile::tempdir().unwrap();
    let models = dir.path().join("models");
    std::fs::create_dir_all(models.join("plain")).unwrap();
    std::fs::create_dir_all(models.join("duck")).unwrap();
    let assets = root().join("assets");
    let read = |name: &str| std::fs::read(assets.join(name)).unwrap();
    let shapes = || {
        vec![
            ("shapes/shapes.obj", read("shapes.obj")),
            ("shapes/shapes.mtl", read("shapes.mtl")),
        ]
    };
    for name in ["shapes.obj", "shapes.mtl"] {
        std::fs::write(models.join("plain").join(name), read(name)).unwrap();
        std::fs::write(models.join("duck").join(name), read(name)).unwrap();
    }
    std::fs::rename(models.join("duck/shapes.obj"), models.join("duck/duck.obj")).unwrap();
    let zip = |name: &str, entries: &[(&str, Vec<u8>)]| {
        crate::archives::write_zip(&models.join(name), entries);
    };
    zip("shapes.zip", &shapes());
    zip("duck.zip", &shapes());
    zip("box.zip", &shapes());
    std::fs::write(models.join("box.gltf"), read("cornell-box.gltf")).unwrap();
    zip("textures.zip", &[("textures/a.png", b"png".to_vec())]);
    std::fs::write(models.join("junk.zip"), b"not a zip").unwrap();
    let mut two = shapes();
    two.push(("shapes/other.obj", read("shapes.obj")));
    zip("two.zip", &two);
    zip("evil.zip", &[("../evil.gltf", b"{}".to_vec())]);
    zip("absolute.zip", &[("/abs.glb", b"glTF".to_vec())]);
    let whole = std::fs::read(models.join("shapes.zip")).unwrap();
    std::fs::write(models.join("cut.zip"), &whole[..whole.len() / 2]).unwrap();

    let out = dir.path().join("out");
    let run = batch(&models, &out, &[], &[], false);
    let stderr = String::from_utf8_lossy(&run.stderr);
    let jobs = by_id(&records(&out.join("results.jsonl")));
    assert_eq!(
        jobs.keys().collect::<Vec<_>>(),
        [
            "absolute",
            "box",
            "cut",
            "duck/duck",
            "evil",
            "plain/shapes",
            "shapes",
            "two"
        ],
        "{stderr}"
    );
    for (id, entry) in [("evil", "../evil.gltf"), ("absolute", "/abs.glb")] {
        assert_eq!(jobs[id]["status"], "failed");
        let error = jobs[id]["error"].as_str().unwrap();
        assert!(
            error.contains(&format!("{id}.zip"))
                && error.contains(&format!("'{entry}' is refused")),
            "{error}"
        );
    }
    let cut = &jobs["cut"];
    assert_eq!(cut["status"], "failed");
    let error = cut["error"].as_str().unwrap();
    assert!(
        error.contains("cut.zip") && error.contains("not a readable zip archive"),
        "{error}"
    );
    let two = &jobs["two"];
    assert_eq!(two["status"], "failed");
    let error = two["error"].as_str().unwrap();
    assert!(
        error.contains("two.zip") && error.contains("2 models"),
        "{error}"
    );
    for id in ["box", "duck/duck", "plain/shapes", "shapes"] {
        assert_eq!(jobs[id]["status"], "ok", "{id}: {}", jobs[id]);
    }
    let image = |id: &str| std::fs::read(out.join(id).join("image.png")).unwrap();
    assert!(
        image("shapes") == image("plain/shapes"),
        "the zip renders as its files"
    );
}

/// A model whose texture file is missing renders without it (a job that succeeds), and its
/// record says why the picture lacks the texture: the warnings `render` prints, naming the
/// image and its file, are in results.jsonl. A model without problems records none.
#[test]
fn a_job_records_the_warnings_of_its_model() {
    let dir = tempfile::tempdir().unwrap();
    let models = dir.path().join("models");
    std::fs::create_dir_all(&models).unwrap();
    let (json, bin) = crate::common::quads_gltf(
        &[(crate::common::square(1.0, 0.0), 0)],
        serde_json::json!({
            "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
            "textures": [{"source": 0}],
            "images": [{"uri": "missing.png"}]
        }),
    );
    crate::common::write_gltf(&models, "untextured.gltf", json, &bin);
    std::fs::copy(
        root().join("assets/cornell-box.gltf"),
        models.join("cornell-box.gltf"),
    )
    .unwrap();
    let out = dir.path().join("out");
    batch(&models, &out, &[], &[], true);
    let jobs = by_id(&records(&out.join("results.jsonl")));
    let untextured = &jobs["untextured"];
    assert_eq!(untextured["status"], "ok", "{untextured}");
    let warnings = untextured["warnings"].as_array().unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w.as_str().unwrap().contains("missing.png")),
        "{untextured}"
    );
    assert_eq!(jobs["cornell-box"]["warnings"], serde_json::json!([]));
}

/// A JSONL manifest with a malformed line, ids and output names that leave the output folder
/// (`../escape`, absolute) and a misspelt option: those jobs fail with a message, the others
/// render (one with views), and nothing is written outside the output folder.
#[test]
fn a_jsonl_batch_refuses_bad_lines_and_escaping_names_and_writes_only_inside_dir() {
    let dir = tempfile::tempdir().unwrap();
    let lines = [
        r#"{"model": "cornell-box.gltf"}"#,
        r#"{"id": "shapes", "model": "sub/shapes.obj", "views": "orbit:2", "outputs": {"normal": "n/{view:03}.png"}}"#,
        r#"{"model": "cornell-box.gltf", "spp": 2,"#,
        r#"{"id": "../escape", "model": "cornell-box.gltf"}"#,
        r#"{"id": "/tmp/absolute", "model": "cornell-box.gltf"}"#,
        r#"{"id": "climber", "model": "cornell-box.gltf", "outputs": {"image": "../../climbed.png"}}"#,
        r#"{"id": "typo", "model": "cornell-box.gltf", "sp": 2}"#,
    ]
    .map(String::from);
    let manifest = jsonl_manifest(dir.path(), "jobs.jsonl", &lines);
    let out = dir.path().join("out");
    let before: BTreeSet<PathBuf> = all_paths(dir.path());
    batch(&manifest, &out, &[], &[], false);

    let results = records(&out.join("results.jsonl"));
    assert_eq!(results.len(), 7, "one record per line");
    let jobs = by_id(&results);
    for id in ["cornell-box", "shapes"] {
        assert_eq!(jobs[id]["status"], "ok", "{}", jobs[id]);
        assert_hashes_match(&out, &jobs[id]);
    }
    assert!(out.join("shapes/n/001.png").is_file());
    assert!(out.join("shapes/transforms.json").is_file());
    let error = |key: &str| {
        let job = &jobs[key];
        assert_eq!(job["status"], "failed", "{job}");
        job["error"].as_str().unwrap().to_string()
    };
    let malformed = jobs
        .keys()
        .find(|k| k.starts_with("(no id)"))
        .expect("the malformed line is recorded without an id")
        .clone();
    assert!(
        error(&malformed).contains("jobs.jsonl line 3"),
        "{}",
        error(&malformed)
    );
    assert!(error("../escape").contains("'../escape' refused"));
    assert!(error("/tmp/absolute").contains("absolute"));
    assert!(error("climber").contains("'../../climbed.png' refused"));
    assert!(error("typo").contains("unknown field `sp`"));

    // Nothing new outside the output folder: the manifest's folder is as it was.
    let created: Vec<PathBuf> = all_paths(dir.path())
        .difference(&before)
        .filter(|p| !p.starts_with(&out))
        .cloned()
        .collect();
    assert_eq!(created, Vec::<PathBuf>::new());
    assert!(!dir.path().join("escape").exists() && !Path::new("/tmp/absolute").exists());
    let folders: BTreeSet<String> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        folders,
        ["cornell-box", "results.jsonl", "shapes"]
            .map(String::from)
            .into(),
        "only the good jobs have folders"
    );
}

/// A job that fails only when it runs (a missing model, an animation the model lacks) is
/// named by its manifest line, in the batch's error and in its record, as a line that is not
/// a job is: with many jobs of one model, the model alone does not say which line to fix.
#[test]
fn a_jsonl_job_failing_when_it_runs_names_its_manifest_line() {
    let dir = tempfile::tempdir().unwrap();
    let lines = [
        r#"{"model": "cornell-box.gltf"}"#,
        r#"{"id": "missing", "model": "nowhere.gltf"}"#,
        r#"{"id": "unposed", "model": "cornell-box.gltf", "animation": "Walk"}"#,
    ]
    .map(String::from);
    let manifest = jsonl_manifest(dir.path(), "jobs.jsonl", &lines);
    let out = dir.path().join("out");
    let run = batch(&manifest, &out, &[], &[], false);
    let stderr = String::from_utf8_lossy(&run.stderr);
    let error = stderr
        .lines()
        .find(|l| l.contains("2 of 3 jobs failed"))
        .unwrap_or_else(|| panic!("one message for the failures:\n{stderr}"));
    for expected in [
        "jobs.jsonl line 2: ",
        "nowhere.gltf",
        "jobs.jsonl line 3: ",
        "Walk",
    ] {
        assert!(error.contains(expected), "{expected}: {error}");
    }
    let jobs = by_id(&records(&out.join("results.jsonl")));
    assert_eq!(jobs["cornell-box"]["status"], "ok");
    for (id, line) in [("missing", "line 2: "), ("unposed", "line 3: ")] {
        let recorded = jobs[id]["error"].as_str().unwrap();
        assert!(
            recorded.contains(&format!("jobs.jsonl {line}")),
            "{recorded}"
        );
    }
}

/// Lines without a readable id are recorded after the jobs, in the order of their lines as
/// numbers: line 2 before line 10 (not before it as text, where "10" < "2").
#[test]
fn id_less_lines_are_recorded_in_line_order() {
    let dir = tempfile::tempdir().unwrap();
    let mut lines = vec![String::new(); 12];
    lines[0] = r#"{"model": "sub/shapes.obj"}"#.into();
    lines[1] = "not json".into();
    lines[9] = "[1, 2]".into();
    lines[10] = "{".into();
    let manifest = jsonl_manifest(dir.path(), "jobs.jsonl", &lines);
    let out = dir.path().join("out");
    batch(&manifest, &out, &[], &[], false);
    let errors: Vec<String> = records(&out.join("results.jsonl"))
        .iter()
        .map(|r| r["error"].as_str().unwrap_or("ok").to_string())
        .collect();
    assert_eq!(errors.len(), 4, "{errors:?}");
    assert_eq!(errors[0], "ok");
    for (error, line) in errors[1..]
        .iter()
        .zip(["line 2: ", "line 10: ", "line 11: "])
    {
        assert!(error.contains(&format!("jobs.jsonl {line}")), "{errors:?}");
    }
}

/// An id given to several jobs fails each of them, and each record names every line (in a
/// folder: every model file) that shares it, so that all can be found from any one.
#[test]
fn a_shared_id_names_every_line_that_shares_it() {
    let dir = tempfile::tempdir().unwrap();
    let lines = [
        r#"{"id": "twin", "model": "cornell-box.gltf"}"#,
        r#"{"model": "sub/shapes.obj"}"#,
        r#"{"id": "twin", "model": "sub/shapes.obj"}"#,
        r#"{"id": "twin", "model": "cornell-box.gltf", "spp": 2}"#,
    ]
    .map(String::from);
    let manifest = jsonl_manifest(dir.path(), "jobs.jsonl", &lines);
    let out = dir.path().join("out");
    batch(&manifest, &out, &[], &[], false);
    let twins: Vec<Value> = records(&out.join("results.jsonl"))
        .into_iter()
        .filter(|r| r["id"] == "twin")
        .collect();
    assert_eq!(twins.len(), 3);
    for (twin, line) in twins.iter().zip([1, 3, 4]) {
        let error = twin["error"].as_str().unwrap();
        assert!(
            error.starts_with(&format!("{} line {line}: ", s(&manifest)))
                && error
                    .contains("job id 'twin' is given to 3 jobs of the manifest (lines 1, 3, 4)"),
            "{error}"
        );
    }
    // A folder: `twin.gltf` and `twin.obj` both have the id `twin`.
    let folder = dir.path().join("folder");
    std::fs::create_dir_all(&folder).unwrap();
    let assets = root().join("assets");
    std::fs::copy(assets.join("cornell-box.gltf"), folder.join("twin.gltf")).unwrap();
    std::fs::copy(assets.join("shapes.obj"), folder.join("twin.obj")).unwrap();
    let out = dir.path().join("folder-out");
    batch(&folder, &out, &[], &[], false);
    for twin in records(&out.join("results.jsonl")) {
        let error = twin["error"].as_str().unwrap();
        assert!(
            error.contains("is given to 2 jobs of the manifest (twin.gltf, twin.obj)"),
            "{error}"
        );
    }
}

/// Issue 15's whole-collection run: a JSONL batch over every model file in the shared samples
/// (MESHTRACER_SAMPLES: glTF, GLB and OBJ, the encoded, animated and variant ones included)
/// plus a broken file records exactly one failed job, naming the file, and renders every
/// other; three shards of it write the same files, and merged the same results.jsonl
/// (timings aside).
#[test]
fn a_batch_over_every_sample_model_fails_only_the_broken_file_and_shards_equal_it() {
    let Some(samples) = crate::common::samples(
        "a_batch_over_every_sample_model_fails_only_the_broken_file_and_shards_equal_it",
    ) else {
        return;
    };
    fn walk(dir: &Path, found: &mut Vec<PathBuf>) {
        let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        entries.sort();
        for path in entries {
            if path.is_dir() {
                walk(&path, found);
            } else if path
                .extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| ["gltf", "glb", "obj"].contains(&e))
            {
                found.push(path);
            }
        }
    }
    let mut models = Vec::new();
    walk(&samples, &mut models);
    assert!(models.len() >= 50, "{} model files", models.len());
    let dir = tempfile::tempdir().unwrap();
    let broken = dir.path().join("broken.glb");
    std::fs::write(&broken, b"glTF this is not").unwrap();
    let line =
        |id: &str, model: &Path| serde_json::json!({"id": id, "model": s(model)}).to_string();
    let mut lines: Vec<String> = models
        .iter()
        .map(|m| {
            let id = m.strip_prefix(&samples).unwrap().with_extension("");
            line(&id.to_string_lossy().replace('\\', "/"), m)
        })
        .collect();
    lines.push(line("broken", &broken));
    let manifest = dir.path().join("all.jsonl");
    std::fs::write(&manifest, lines.join("\n") + "\n").unwrap();

    let whole = dir.path().join("whole");
    let run = batch(&manifest, &whole, &[], &[], false);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains(&format!("1 of {} jobs failed", lines.len())),
        "{stderr}"
    );
    let results = records(&whole.join("results.jsonl"));
    assert_eq!(results.len(), lines.len());
    for record in &results {
        if record["id"] == "broken" {
            assert_eq!(record["status"], "failed");
            assert!(
                record["error"].as_str().unwrap().contains("broken.glb"),
                "{record}"
            );
        } else {
            assert_eq!(record["status"], "ok", "{record}");
            assert!(record["triangles"].as_u64().unwrap() > 0, "{record}");
        }
    }

    let sharded = dir.path().join("sharded");
    for i in 0..3 {
        // The shard that holds the broken job exits non-zero; the others succeed.
        let mut args = vec!["batch", s(&manifest), "-o", s(&sharded)];
        args.extend_from_slice(&SMALL);
        let shard = format!("{i}/3");
        args.extend_from_slice(&["--shard", &shard]);
        command(env!("CARGO_BIN_EXE_meshtracer"), &args, &[])
            .output()
            .expect("the shard runs");
    }
    merge(&sharded, false);
    assert!(
        outputs_tree(&sharded) == outputs_tree(&whole),
        "three shards wrote other files than one run"
    );
    assert_eq!(
        records(&sharded.join("results.jsonl"))
            .iter()
            .map(timeless)
            .collect::<Vec<_>>(),
        results.iter().map(timeless).collect::<Vec<_>>()
    );
}

/// Three shards, chosen by --shard and by the Slurm array variables, together do every job
/// exactly once and write the same files, byte for byte, as one unsharded run; batch-merge
/// gives the same results.jsonl (timings aside); a shuffled manifest puts every job in the
/// same shard.
#[test]
fn shards_together_equal_the_whole_run_and_survive_a_shuffled_manifest() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = jsonl_manifest(dir.path(), "jobs.jsonl", &nine_jobs());
    let whole = dir.path().join("whole");
    batch(&manifest, &whole, &[], &[], true);
    let whole_results = records(&whole.join("results.jsonl"));
    assert_eq!(whole_results.len(), 9);
    let whole_files = outputs_tree(&whole);

    let shard_ids = |out: &Path| -> Vec<BTreeSet<String>> {
        (0..3)
            .map(|i| {
                let file = out.join(format!("results.{i}-of-3.jsonl"));
                records(&file)
                    .iter()
                    .map(|r| {
                        assert_eq!(r["status"], "ok", "{r}");
                        r["id"].as_str().unwrap().to_string()
                    })
                    .collect()
            })
            .collect()
    };
    let by_flag = dir.path().join("by-flag");
    for i in 0..3 {
        batch(
            &manifest,
            &by_flag,
            &["--shard", &format!("{i}/3")],
            &[],
            true,
        );
    }
    let by_slurm = dir.path().join("by-slurm");
    for i in 0..3 {
        let id = i.to_string();
        let env = [
            ("SLURM_ARRAY_TASK_ID", id.as_str()),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
        ];
        batch(&manifest, &by_slurm, &[], &env, true);
    }
    let shards = shard_ids(&by_flag);
    assert!(
        shards.iter().filter(|ids| !ids.is_empty()).count() >= 2,
        "the nine jobs spread over the shards: {shards:?}"
    );
    let mut union = BTreeSet::new();
    for ids in &shards {
        for id in ids {
            assert!(union.insert(id.clone()), "{id} done by two shards");
        }
    }
    assert_eq!(union, by_id(&whole_results).keys().cloned().collect());
    assert_eq!(
        shard_ids(&by_slurm),
        shards,
        "Slurm's variables pick the same shards"
    );
    // The documented rule, computed here on its own: FNV-1a 64 of the id's bytes, modulo N.
    let fnv1a64 = |text: &str| {
        text.bytes().fold(0xcbf29ce484222325u64, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x100000001b3)
        })
    };
    for (i, ids) in shards.iter().enumerate() {
        for id in ids {
            assert_eq!(fnv1a64(id) % 3, i as u64, "{id} in shard {i}");
        }
    }

    for out in [&by_flag, &by_slurm] {
        assert!(
            outputs_tree(out) == whole_files,
            "{}: not the same files",
            out.display()
        );
        merge(out, true);
        let merged: Vec<Value> = records(&out.join("results.jsonl"));
        assert_eq!(
            merged.iter().map(timeless).collect::<Vec<_>>(),
            whole_results.iter().map(timeless).collect::<Vec<_>>()
        );
    }

    // The same jobs in another order land in the same shards.
    let mut shuffled = nine_jobs();
    shuffled.reverse();
    shuffled.swap(1, 6);
    let shuffled_manifest = manifest.with_file_name("shuffled.jsonl");
    std::fs::write(&shuffled_manifest, shuffled.join("\n")).unwrap();
    let reordered = dir.path().join("reordered");
    for i in 0..3 {
        batch(
            &shuffled_manifest,
            &reordered,
            &["--shard", &format!("{i}/3")],
            &[],
            true,
        );
    }
    assert_eq!(shard_ids(&reordered), shards);
}

/// A shard whose run was damaged (one job's output corrupted, another's record lost and a
/// temporary file left, as if the run had been killed in the middle of it) resumes: --resume
/// redoes those two jobs only, reports the others skipped, and the files are again the
/// undamaged run's.
#[test]
fn resume_redoes_only_unfinished_or_damaged_jobs() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = jsonl_manifest(dir.path(), "jobs.jsonl", &nine_jobs());
    let out = dir.path().join("out");
    for i in 0..2 {
        batch(&manifest, &out, &["--shard", &format!("{i}/2")], &[], true);
    }
    let pristine = outputs_tree(&out);
    let shard = out.join("results.1-of-2.jsonl");
    let ids: Vec<String> = records(&shard)
        .iter()
        .map(|r| r["id"].as_str().unwrap().to_string())
        .collect();
    assert!(ids.len() >= 3, "shard 1 has enough jobs: {ids:?}");
    let other_shard = std::fs::read(out.join("results.0-of-2.jsonl")).unwrap();

    // Damage: truncate one output; lose one job's record (killed after writing its images).
    let damaged = &ids[0];
    let first_output = records(&shard)[0]["outputs"][0]["path"]
        .as_str()
        .unwrap()
        .to_string();
    let bytes = std::fs::read(out.join(&first_output)).unwrap();
    std::fs::write(out.join(&first_output), &bytes[..bytes.len() / 2]).unwrap();
    let unrecorded = &ids[1];
    std::fs::remove_file(out.join(unrecorded).join("job.json")).unwrap();
    // What a kill leaves of a file being written (it cannot clean up): gone once the job is redone.
    std::fs::write(
        out.join(unrecorded).join(".meshtracer-AbC123.partial"),
        b"half",
    )
    .unwrap();

    batch(&manifest, &out, &["--shard", "1/2", "--resume"], &[], true);
    let resumed = by_id(&records(&shard));
    for id in &ids {
        let expected = if id == damaged || id == unrecorded {
            "ok"
        } else {
            "skipped"
        };
        assert_eq!(resumed[id]["status"], expected, "{id}");
        assert_hashes_match(&out, &resumed[id]);
    }
    assert_eq!(
        outputs_tree(&out),
        pristine,
        "the redone jobs wrote the same bytes and left no temporary file"
    );
    assert_eq!(
        std::fs::read(out.join("results.0-of-2.jsonl")).unwrap(),
        other_shard
    );
    merge(&out, true);
    assert_eq!(records(&out.join("results.jsonl")).len(), 9);
}

/// `--resume` redoes a job whose model refers to a file that changed since (an OBJ's material
/// library here), which the fingerprint, made from the model file's own bytes, does not see;
/// a model that refers to nothing records no inputs and stays skipped.
#[test]
fn resume_redoes_a_job_whose_material_library_changed() {
    let dir = tempfile::tempdir().unwrap();
    let models = dir.path().join("models");
    std::fs::create_dir(&models).unwrap();
    for name in ["shapes.obj", "shapes.mtl", "cornell-box.gltf"] {
        std::fs::copy(root().join("assets").join(name), models.join(name)).unwrap();
    }
    let out = dir.path().join("out");
    batch(&models, &out, &[], &[], true);
    let first = by_id(&records(&out.join("results.jsonl")));
    let mtl = models.join("shapes.mtl");
    let inputs = &first["shapes"]["inputs"];
    assert_eq!(inputs[0]["path"], "shapes.mtl", "{inputs}");
    assert_eq!(inputs.as_array().unwrap().len(), 1, "{inputs}");
    let hash = meshtracer::jobs::batch::sha256_file(&mtl).unwrap();
    assert_eq!(inputs[0]["sha256"], hash.as_str());
    assert!(
        first["cornell-box"].get("inputs").is_none(),
        "an embedded buffer is no input"
    );

    batch(&models, &out, &["--resume"], &[], true);
    let resumed = by_id(&records(&out.join("results.jsonl")));
    assert_eq!(resumed["shapes"]["status"], "skipped");
    assert_eq!(resumed["cornell-box"]["status"], "skipped");

    crate::common::recolour_mtl(&mtl);
    let image = out.join("shapes/image.png");
    let before = std::fs::read(&image).unwrap();
    batch(&models, &out, &["--resume"], &[], true);
    let redone = by_id(&records(&out.join("results.jsonl")));
    assert_eq!(redone["shapes"]["status"], "ok");
    assert_eq!(redone["cornell-box"]["status"], "skipped");
    assert_ne!(
        std::fs::read(&image).unwrap(),
        before,
        "drawn with the new colour"
    );
    assert_ne!(redone["shapes"]["inputs"][0]["sha256"], hash.as_str());
}

/// Reads `key: value` from a YAML or sbatch text (first match).
fn setting<'a>(text: &'a str, key: &str) -> &'a str {
    text.lines()
        .find_map(|l| l.trim().strip_prefix(key))
        .unwrap_or_else(|| panic!("no '{key}' in the example"))
        .trim()
}

/// The example scripts run the real command for every index of their array with the
/// variables the scheduler sets: the shards together cover every job once, and merged they
/// equal the unsharded run. The Slurm script is run by bash; the Kubernetes Job's command is
/// read from the YAML and run with JOB_COMPLETION_INDEX (its size options made small, /data
/// mapped to a temporary folder).
#[test]
fn the_slurm_and_kubernetes_examples_cover_every_job() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = jsonl_manifest(dir.path(), "manifest.jsonl", &nine_jobs());
    let whole = dir.path().join("whole");
    batch(&manifest, &whole, &[], &[], true);
    let whole_results: Vec<Value> = records(&whole.join("results.jsonl"))
        .iter()
        .map(timeless)
        .collect();
    let exe = env!("CARGO_BIN_EXE_meshtracer");
    let small = SMALL.join(" ");

    let script = root().join("examples/slurm/render_array.sbatch");
    let text = std::fs::read_to_string(&script).unwrap();
    let array = setting(&text, "#SBATCH --array=");
    let (min, max) = array.split_once('-').expect("--array=MIN-MAX");
    let (min, max): (usize, usize) = (min.parse().unwrap(), max.parse().unwrap());
    let slurm_out = dir.path().join("slurm");
    for task in min..=max {
        let (id, count) = (task.to_string(), (max - min + 1).to_string());
        let (min_s, max_s) = (min.to_string(), max.to_string());
        let env = [
            ("SLURM_ARRAY_TASK_ID", id.as_str()),
            ("SLURM_ARRAY_TASK_COUNT", count.as_str()),
            ("SLURM_ARRAY_TASK_MIN", min_s.as_str()),
            ("SLURM_ARRAY_TASK_MAX", max_s.as_str()),
            ("SLURM_CPUS_PER_TASK", "1"),
            ("MESHTRACER", exe),
            ("MESHTRACER_OPTIONS", small.as_str()),
        ];
        let args = [s(&script), s(&manifest), s(&slurm_out)];
        check(command("bash", &args, &env), true);
    }

    let yaml = std::fs::read_to_string(root().join("examples/k8s/indexed-job.yaml")).unwrap();
    let completions: usize = setting(&yaml, "completions:").parse().unwrap();
    let command_line: Vec<String> = serde_json::from_str(setting(&yaml, "command:")).unwrap();
    let data = dir.path().join("data");
    std::fs::create_dir_all(&data).unwrap();
    std::fs::copy(&manifest, data.join("manifest.jsonl")).unwrap();
    let models = manifest.parent().unwrap();
    std::fs::copy(
        models.join("cornell-box.gltf"),
        data.join("cornell-box.gltf"),
    )
    .unwrap();
    std::fs::create_dir_all(data.join("sub")).unwrap();
    for name in ["shapes.obj", "shapes.mtl"] {
        std::fs::copy(models.join("sub").join(name), data.join("sub").join(name)).unwrap();
    }
    let mut args: Vec<String> = Vec::new();
    let mut words = command_line.iter().skip(1).peekable();
    assert_eq!(command_line[0], "meshtracer");
    while let Some(word) = words.next() {
        match word.as_str() {
            // Size and sample options: the test's small ones below.
            "--width" | "--height" | "--spp" => {
                words.next();
            }
            "--shard-count" => {
                let count = words.next().unwrap();
                assert_eq!(
                    count.parse::<usize>().unwrap(),
                    completions,
                    "--shard-count is the Job's completions"
                );
                args.extend([word.clone(), count.clone()]);
            }
            w => args.push(w.replace("/data", s(&data))),
        }
    }
    args.extend(SMALL.iter().map(|w| w.to_string()));
    for index in 0..completions {
        let index = index.to_string();
        let argv: Vec<&str> = args.iter().map(String::as_str).collect();
        check(
            command(exe, &argv, &[("JOB_COMPLETION_INDEX", &index)]),
            true,
        );
    }

    for out in [slurm_out, data.join("out")] {
        let mut seen = BTreeSet::new();
        for entry in std::fs::read_dir(&out).unwrap().flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            if name.starts_with("results.") {
                for r in records(&entry.path()) {
                    assert!(
                        seen.insert(r["id"].to_string()),
                        "{}: {} twice",
                        out.display(),
                        r["id"]
                    );
                }
            }
        }
        assert_eq!(seen.len(), 9, "{}: every job once", out.display());
        merge(&out, true);
        let merged: Vec<Value> = records(&out.join("results.jsonl"))
            .iter()
            .map(timeless)
            .collect();
        let strip = |rs: &[Value]| -> Vec<Value> {
            // The example's outputs (depth.exr, mask.png) differ from the unsharded run's:
            // compare what every run shares.
            rs.iter()
                .map(|r| serde_json::json!({"id": r["id"], "status": r["status"], "triangles": r["triangles"], "image": r["outputs"][0]}))
                .collect()
        };
        assert_eq!(strip(&merged), strip(&whole_results), "{}", out.display());
    }
}

/// A batch killed (SIGKILL: no chance to clean up) after a few jobs resumes with `--resume`:
/// the jobs finished before the kill are skipped, every other one is rendered, and the
/// outputs are byte for byte those of a run that was never interrupted.
#[test]
fn a_killed_batch_resumes_redoing_only_the_unfinished_jobs() {
    stop_and_resume("KILL");
}

/// SIGTERM, what a Slurm time limit or `scancel` and a Kubernetes pod's deletion or eviction
/// send, stops a batch as Ctrl-C does: the job under way is cancelled, exit 130 with a
/// message naming `--resume`, and nothing of meshtracer's own is left in the folder: no
/// temporary file and, above all, no job lock, which a retry on another host (a new pod, a
/// requeued task) would take for a live batch's and wait on. Then `--resume` finishes as
/// after a kill.
#[test]
fn a_batch_stopped_by_sigterm_leaves_no_lock_and_resumes() {
    stop_and_resume("TERM");
}

/// Runs `batch MANIFEST -o DIR/whole` to its end, then starts the same batch into
/// `DIR/killed` (standard error piped) for a test to stop: returns both folders, the second
/// run's arguments and its process. The renders are [`STOPPABLE`]'s, heavier than SMALL, so
/// that a stop lands with most of the work still to do (about 60 ms a box in a debug build on
/// 2 cores).
fn whole_then_started(
    dir: &Path,
    manifest: &Path,
) -> (PathBuf, PathBuf, Vec<String>, std::process::Child) {
    let args = |out: &Path| {
        let mut args = vec!["batch", s(manifest), "-o", s(out)];
        args.extend_from_slice(&crate::common::STOPPABLE);
        args.push("-q");
        args.into_iter().map(String::from).collect::<Vec<_>>()
    };
    let whole = dir.join("whole");
    let run_args = args(&whole);
    let run_args: Vec<&str> = run_args.iter().map(String::as_str).collect();
    check(
        command(env!("CARGO_BIN_EXE_meshtracer"), &run_args, &[]),
        true,
    );
    let out = dir.join("killed");
    let kill_args = args(&out);
    let child = command(env!("CARGO_BIN_EXE_meshtracer"), &[], &[])
        .args(&kill_args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    (whole, out, kill_args, child)
}

/// Runs 32 jobs whole, then again until three are done, sends `SIG<signal>`, checks what the
/// stop left, and resumes: the outputs must be the whole run's, byte for byte.
fn stop_and_resume(signal: &str) {
    let dir = tempfile::tempdir().unwrap();
    let lines: Vec<String> = (0..32)
        .map(|k| format!(r#"{{"id": "job-{k:02}", "model": "cornell-box.gltf", "seed": {k}}}"#))
        .collect();
    let manifest = jsonl_manifest(dir.path(), "jobs.jsonl", &lines);
    let (whole, out, kill_args, mut child) = whole_then_started(dir.path(), &manifest);
    let kill_args: Vec<&str> = kill_args.iter().map(String::as_str).collect();
    let finished = |out: &Path| -> BTreeSet<String> {
        (0..32)
            .map(|k| format!("job-{k:02}"))
            .filter(|id| out.join(id).join("job.json").is_file())
            .collect()
    };
    crate::common::wait_until(&mut child, "3 finished jobs", || finished(&out).len() >= 3);
    crate::hostile::send(&child, signal);
    let stopped = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&stopped.stderr);
    if signal != "KILL" {
        assert_eq!(stopped.status.code(), Some(130), "{err}");
        assert!(err.contains("--resume to finish"), "{err}");
        let own: Vec<String> = outputs_tree(&out)
            .into_keys()
            .filter(|name| name.rsplit('/').next().unwrap().starts_with(".meshtracer-"))
            .collect();
        assert!(own.is_empty(), "left behind: {own:?}");
    }
    let done = finished(&out);
    assert!(done.len() < 32, "the kill came before the end");
    assert!(
        !out.join("results.jsonl").exists(),
        "no results file from a killed run"
    );

    let mut resume_args = kill_args.clone();
    resume_args.push("--resume");
    check(
        command(env!("CARGO_BIN_EXE_meshtracer"), &resume_args, &[]),
        true,
    );
    let resumed = by_id(&records(&out.join("results.jsonl")));
    assert_eq!(resumed.len(), 32);
    for (id, record) in &resumed {
        let expected = if done.contains(id) { "skipped" } else { "ok" };
        assert_eq!(record["status"], expected, "{id}");
        assert_hashes_match(&out, record);
    }
    assert_eq!(
        outputs_tree(&out),
        outputs_tree(&whole),
        "the resumed run's files are the uninterrupted run's, with no temporary file left"
    );
}

/// A batch killed in the middle of a job with views keeps that job's finished views on
/// `--resume`: they are not written again (the same files, not copies), and the job ends with
/// the files of an uninterrupted batch.
#[test]
fn a_job_with_views_resumes_within_the_job() {
    let dir = tempfile::tempdir().unwrap();
    let line = r#"{"id": "turn", "model": "cornell-box.gltf", "views": "orbit:12"}"#;
    let manifest = jsonl_manifest(dir.path(), "jobs.jsonl", &[line.to_string()]);
    let (whole, out, kill_args, mut child) = whole_then_started(dir.path(), &manifest);
    let kill_args: Vec<&str> = kill_args.iter().map(String::as_str).collect();
    let view = |k: usize| out.join("turn").join(format!("{k:03}.view.json"));
    crate::common::wait_until(&mut child, "view 2", || view(2).is_file());
    crate::hostile::send(&child, "KILL");
    child.wait().unwrap();
    let finished: Vec<usize> = (0..12).filter(|&k| view(k).is_file()).collect();
    assert!(finished.len() < 12, "the kill came before the end");
    let identity = |k: usize| {
        use std::os::unix::fs::MetadataExt;
        let meta = std::fs::metadata(out.join("turn").join(format!("{k:03}.png"))).unwrap();
        (meta.ino(), meta.mtime_nsec())
    };
    let before: Vec<_> = finished.iter().map(|&k| identity(k)).collect();

    let mut resume_args = kill_args.clone();
    resume_args.push("--resume");
    check(
        command(env!("CARGO_BIN_EXE_meshtracer"), &resume_args, &[]),
        true,
    );
    let after: Vec<_> = finished.iter().map(|&k| identity(k)).collect();
    assert_eq!(before, after, "the finished views were written again");
    let resumed = by_id(&records(&out.join("results.jsonl")));
    assert_eq!(resumed["turn"]["status"], "ok");
    assert_hashes_match(&out, &resumed["turn"]);
    assert_eq!(outputs_tree(&out), outputs_tree(&whole));
}

/// The resume fingerprint of fixed jobs is pinned, so a batch finished by one build stays
/// finished for the next (`--resume` skips it) as long as the fingerprint's record is the
/// same: a change that moves code or renames a command-line flag must not change it. It depends
/// on the bundled models' bytes (copied here), the version and every render option of the job;
/// a deliberate change of any of those, or of the record's layout, changes these values and
/// means every earlier batch is redone on `--resume`: say so in the change.
#[test]
fn the_resume_fingerprint_of_fixed_jobs_is_pinned() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = jsonl_manifest(dir.path(), "jobs.jsonl", &nine_jobs());
    let out = dir.path().join("out");
    batch(&manifest, &out, &["--depth-out", "depth.png"], &[], true);
    let records = by_id(&records(&out.join("results.jsonl")));
    let pinned = [
        (
            "job-0",
            "6f8b72b7c4d2541c56cc7cdc67f9017398cc234871ca9ed3adff05a2da6fc464",
        ),
        (
            "job-2",
            "0e40786dc86927e8db8806052572d579228ae3af5954445266c5831afe228124",
        ),
        (
            "job-5",
            "3d35ef7238e333931d18ef257187f0c76a3118c1885032ec8160d384a4e6c177",
        ),
        (
            "job-7",
            "499ff18a2f210c0c8af5b7c0da71bee1d32fee60529636269017c5bf08589de9",
        ),
    ];
    for (id, fingerprint) in pinned {
        assert_eq!(records[id]["fingerprint"], fingerprint, "{id}");
    }
}

/// Two batches started together into one folder (a duplicate retried while the first still
/// runs): each job rendered by one of them at a time (a lock file a job), the other adopting
/// its record; both exit 0, every job has exactly one `ok` record in each results file (no
/// false failure), the files equal those of a single run byte for byte and no lock is left.
#[test]
fn two_batches_sharing_a_folder_record_every_job_once_ok() {
    let dir = tempfile::tempdir().unwrap();
    let manifest = jsonl_manifest(dir.path(), "jobs.jsonl", &nine_jobs());
    let single = dir.path().join("single");
    batch(&manifest, &single, &[], &[], true);
    let shared = dir.path().join("shared");
    let start = || {
        let mut args = vec!["batch", s(&manifest), "-o", s(&shared)];
        args.extend_from_slice(&SMALL);
        let mut cmd = command(env!("CARGO_BIN_EXE_meshtracer"), &args, &[]);
        cmd.stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped());
        cmd.spawn().unwrap()
    };
    let (first, second) = (start(), start());
    for child in [first, second] {
        let out = child.wait_with_output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let results = records(&shared.join("results.jsonl"));
    let ids: Vec<&str> = results.iter().map(|r| r["id"].as_str().unwrap()).collect();
    let expected: Vec<String> = (0..9).map(|k| format!("job-{k}")).collect();
    assert_eq!(ids, expected, "each job once");
    for record in &results {
        assert_eq!(record["status"], "ok", "{record}");
        assert_hashes_match(&shared, record);
    }
    assert_eq!(outputs_tree(&shared), outputs_tree(&single));
}

/// A job whose depth file cannot be written (the name is taken by a folder) fails alone and
/// leaves none of its files: not its image without the depth; the other job renders.
#[test]
fn a_failed_auxiliary_output_leaves_none_of_the_jobs_files() {
    let dir = tempfile::tempdir().unwrap();
    let lines = [
        r#"{"id": "blocked", "model": "cornell-box.gltf"}"#.to_string(),
        r#"{"id": "fine", "model": "sub/shapes.obj"}"#.to_string(),
    ];
    let manifest = jsonl_manifest(dir.path(), "jobs.jsonl", &lines);
    let out = dir.path().join("out");
    std::fs::create_dir_all(out.join("blocked/depth.npy")).unwrap();
    batch(&manifest, &out, &["--depth-out", "depth.npy"], &[], false);
    let results = by_id(&records(&out.join("results.jsonl")));
    assert_eq!(results["blocked"]["status"], "failed");
    assert_eq!(results["fine"]["status"], "ok");
    assert!(!out.join("blocked/image.png").exists());
    assert!(out.join("fine/image.png").is_file() && out.join("fine/depth.npy").is_file());
}

/// batch-merge with shards missing names each, and the command line that runs the one missing
/// (the shard itself, not a placeholder), or the form for several.
#[test]
fn merge_names_missing_shards() {
    let dir = tempfile::tempdir().unwrap();
    let models = models_folder(dir.path(), false);
    let out = dir.path().join("out");
    batch(&models, &out, &["--shard", "0/2"], &[], true);
    let stderr = String::from_utf8_lossy(&merge(&out, false).stderr).into_owned();
    assert!(
        stderr.contains("shard 1/2 has no results file yet")
            && stderr.contains("run it with --shard 1/2 --resume"),
        "{stderr}"
    );

    let out = dir.path().join("out3");
    batch(&models, &out, &["--shard", "1/3"], &[], true);
    let stderr = String::from_utf8_lossy(&merge(&out, false).stderr).into_owned();
    assert!(
        stderr.contains("shards 0/3, 2/3 have no results files yet")
            && stderr.contains("run each with --shard I/3 --resume"),
        "{stderr}"
    );
}
