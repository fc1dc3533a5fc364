//! `meshtracer bench --plot`: the log-log plot is an SVG with both series; any other name is
//! refused before a measurement starts, leaving no file.

use crate::common::{run, s, samples, stderr};

#[test]
fn bench_plots_an_svg_and_refuses_other_plot_names_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let plot = dir.path().join("scaling.svg");
    let report = dir.path().join("report.md");
    let base = [
        "bench",
        "--sizes",
        "1000,10000",
        "--side",
        "32",
        "--runs",
        "1",
        "-q",
    ];
    run(
        &[&base[..], &["--plot", s(&plot), "--report", s(&report)]].concat(),
        true,
    );
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    for text in [
        "time per primary ray vs triangles",
        "BVH, O(log n)",
        "linear scan, O(n)",
    ] {
        assert!(
            svg.contains(&format!(">\n{text}\n</text>")),
            "{text}: {svg:.400}"
        );
    }
    // Two generated sizes: two filled points on each of the two lines.
    assert_eq!(svg.matches("<circle").count(), 4);

    let png = dir.path().join("scaling.png");
    // Not quiet: the refusal comes before the first progress line would.
    let refused = run(&[&base[..7], &["--plot", s(&png)]].concat(), false);
    let err = stderr(&refused);
    assert!(err.contains("scaling.png") && err.contains("SVG"), "{err}");
    assert!(
        !err.contains("building and tracing"),
        "refused before measuring: {err}"
    );
    assert!(!png.exists());
}

/// `--sizes=` measures the models alone (the help's "empty for none"); with no model either
/// there is nothing to measure, which is an error; a size that is not a count names itself.
#[test]
fn empty_sizes_measure_only_the_models() {
    let quick = ["--side", "8", "--runs", "1", "--linear-budget", "0", "-q"];
    let out = run(
        &[
            &["bench", "assets/cornell-box.gltf", "--sizes="][..],
            &quick,
        ]
        .concat(),
        true,
    );
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(table.contains("| cornell-box.gltf |"), "{table}");
    assert!(!table.contains("generated"), "{table}");
    let nothing = run(&[&["bench", "--sizes="][..], &quick].concat(), false);
    assert!(
        stderr(&nothing).contains("nothing to measure"),
        "{}",
        stderr(&nothing)
    );
    let bad = run(&[&["bench", "--sizes=1000,x"][..], &quick].concat(), false);
    assert!(
        stderr(&bad).contains("'x' is not a count"),
        "{}",
        stderr(&bad)
    );
}

/// `--path-spp` renders each model with the path tracer in alternation with the BVH's diffuse
/// rays and reports both and their ratio, with the render it measured; the figures are
/// throughputs of real work (positive, finite), not timings to compare with a bound. A bad
/// `--path-size` or too many samples are refused, naming the flag.
#[test]
fn bench_sets_the_path_tracer_against_the_bvh() {
    let quick = ["--side", "16", "--runs", "2", "--linear-budget", "0", "-q"];
    let path = ["--path-spp", "1", "--path-size", "40x30"];
    let out = run(
        &[
            &[
                "bench",
                "assets/cornell-box.gltf",
                "--sizes=",
                "--rays",
                "diffuse",
            ][..],
            &quick,
            &path,
        ]
        .concat(),
        true,
    );
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(
        table.contains(
            "| scene | render | path tracer Mrays/s | samples/s/thread | BVH alone, diffuse, Mrays/s |"
        ),
        "{table}"
    );
    let row = table
        .lines()
        .find(|l| l.starts_with("| cornell-box.gltf | 40x30, 1 spp |"))
        .unwrap_or_else(|| panic!("no path row: {table}"));
    let cells: Vec<&str> = row.split('|').map(str::trim).collect();
    let figure = |i: usize| -> f64 { cells[i].trim_end_matches('%').parse().unwrap() };
    // Path tracer Mrays/s, its samples/s per thread, the BVH's Mrays/s, their ratio.
    for i in [3, 4, 5, 6] {
        assert!(figure(i).is_finite() && figure(i) > 0.0, "{row}");
    }

    let bad = run(
        &[
            &["bench", "assets/cornell-box.gltf", "--sizes="][..],
            &quick,
            &["--path-spp", "1", "--path-size", "0x30"],
        ]
        .concat(),
        false,
    );
    assert!(
        stderr(&bad).contains("--path-size") && stderr(&bad).contains("WIDTHxHEIGHT"),
        "{}",
        stderr(&bad)
    );
    // More samples than render accepts is refused before anything is measured.
    let greedy = run(
        &[
            &["bench", "assets/cornell-box.gltf", "--sizes="][..],
            &quick[..6],
            &["--path-spp", "5000"],
        ]
        .concat(),
        false,
    );
    let err = stderr(&greedy);
    assert!(
        err.contains("--path-spp 5000") && err.contains("4096"),
        "{err}"
    );
    assert!(!err.contains("building and tracing"), "{err}");
}

/// `--runs 0` would time nothing (it used to run once without a word): refused with one line
/// naming the option, before anything is measured.
#[test]
fn bench_refuses_zero_runs() {
    let out = run(
        &["bench", "--sizes=1000", "--side", "8", "--runs", "0", "-q"],
        false,
    );
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("--runs 0"), "{err}");
    assert!(out.stdout.is_empty(), "nothing measured: {err}");
}

/// The comparison `scripts/bench/peers.py` makes: three ray kinds in one run as JSON, one
/// thread, per-thread throughput, and the exported arrays: the triangles and, per kind, as
/// many rays as the row says were traced, with a hit file of one entry a ray. An export with
/// generated meshes is refused up front; one into a folder that cannot be made fails with an
/// error naming it.
#[test]
fn bench_reports_every_ray_kind_as_json_and_exports_what_it_traces() {
    let dir = tempfile::tempdir().unwrap();
    let export = dir.path().join("rays");
    let out = run(
        &[
            "bench",
            "assets/cornell-box.gltf",
            "--sizes=",
            "--rays",
            "primary,shadow,diffuse",
            "--double-sided",
            "--side",
            "16",
            "--runs",
            "2",
            "--threads",
            "1",
            "--linear-budget",
            "0",
            "--json",
            "-q",
            "--export-rays",
            s(&export),
        ],
        true,
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["settings"]["threads"], 1, "{report}");
    assert_eq!(report["settings"]["double_sided"], true, "{report}");
    let rows = report["rows"].as_array().unwrap();
    let kinds: Vec<&str> = rows.iter().map(|r| r["rays"].as_str().unwrap()).collect();
    assert_eq!(kinds, ["primary", "shadow", "diffuse"]);
    let triangles = rows[0]["triangles"].as_u64().unwrap() as usize;
    // A .npy's data is its last bytes: the header comes first, padded to 64 bytes.
    let data_len = |name: &str| {
        let bytes = std::fs::read(export.join(format!("{name}.npy"))).unwrap();
        assert!(bytes.starts_with(b"\x93NUMPY"), "{name}");
        let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        bytes.len() - 10 - header_len
    };
    assert_eq!(data_len("triangles"), triangles * 9 * 4);
    assert_eq!(data_len("triangle_materials"), triangles * 4);
    for row in rows {
        let kind = row["rays"].as_str().unwrap();
        let traced = row["traced"].as_u64().unwrap() as usize;
        assert_eq!(row["run_mrays_per_second"].as_array().unwrap().len(), 2);
        assert!(
            row["mrays_per_second_per_thread"].as_f64().unwrap() > 0.0,
            "{row}"
        );
        assert_eq!(data_len(kind), traced * 8 * 4, "{kind}");
        let hits = if kind == "shadow" {
            "shadow_occluded".to_string()
        } else {
            format!("{kind}_triangle")
        };
        assert_eq!(data_len(&hits), traced * 4, "{kind}");
    }
    assert_eq!(rows[0]["traced"], 256, "16x16 primary rays");

    let refused = run(
        &["bench", "--sizes", "1000", "--export-rays", s(&export)],
        false,
    );
    assert!(
        stderr(&refused).contains("--export-rays writes one scene's rays"),
        "{}",
        stderr(&refused)
    );
    // A folder that cannot be made (a file is in the way): one error naming it, no arrays.
    let blocked = dir.path().join("blocked");
    std::fs::write(&blocked, b"a file").unwrap();
    let refused = run(
        &[
            "bench",
            "assets/cornell-box.gltf",
            "--sizes=",
            "--side",
            "8",
            "--runs",
            "1",
            "-q",
            "--export-rays",
            s(&blocked),
        ],
        false,
    );
    assert!(
        stderr(&refused).contains(s(&blocked)),
        "{}",
        stderr(&refused)
    );
    assert_eq!(std::fs::read(&blocked).unwrap(), b"a file");
    // The plot draws one kind's time per ray.
    let plot = dir.path().join("two.svg");
    let refused = run(
        &[
            "bench",
            "--sizes",
            "1000",
            "--rays",
            "primary,shadow",
            "--plot",
            s(&plot),
        ],
        false,
    );
    assert!(
        stderr(&refused).contains("--plot draws one ray kind"),
        "{}",
        stderr(&refused)
    );
    assert!(!plot.exists());
}

/// `--packets` traces eight rays at a time through the packet queries, checked against the
/// one-at-a-time answers and, within the budget, the linear scan (a mismatch fails the run);
/// the settings say so in the JSON and under the table.
#[test]
fn bench_traces_packets_and_says_so() {
    let args = |json: bool| {
        let mut a = vec![
            "bench",
            "assets/cornell-box.gltf",
            "--sizes=",
            "--rays",
            "primary,shadow,diffuse",
            "--side",
            "24",
            "--runs",
            "2",
            "--threads",
            "1",
            "--packets",
        ];
        if json {
            a.extend(["--json", "-q"]);
        }
        a
    };
    let out = run(&args(true), true);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["settings"]["packets"], true, "{report}");
    let rows = report["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 3);
    for row in rows {
        assert!(row["traced"].as_u64().unwrap() > 100, "{row}");
        // The linear scan ran (and agreed, or the run would have failed).
        assert!(
            row["linear_mrays_per_second"].as_f64().unwrap() > 0.0,
            "{row}"
        );
    }
    let table = run(&args(false), true);
    assert!(
        String::from_utf8_lossy(&table.stdout).contains("eight at a time"),
        "{}",
        String::from_utf8_lossy(&table.stdout)
    );
}

/// On real models the packets find what one ray at a time finds on every ray of every kind,
/// and what the linear scan finds on a budgeted subset: a disagreement fails the run.
#[test]
fn packets_agree_on_the_shared_models() {
    let Some(samples) = samples("packets_agree_on_the_shared_models") else {
        return;
    };
    let models = [
        samples.join("StanfordBunny-OBJ/stanford-bunny.obj"),
        samples.join("DamagedHelmet/glTF/DamagedHelmet.gltf"),
        samples.join("Lantern/glTF/Lantern.gltf"),
    ];
    let mut args = vec!["bench", "--sizes=", "--rays", "primary,shadow,diffuse"];
    args.extend(["--side", "96", "--runs", "1", "--threads", "2"]);
    args.extend(["--linear-budget", "100000000", "--packets", "--json", "-q"]);
    args.extend(models.iter().map(|m| s(m)));
    let out = run(&args, true);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let rows = report["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 9, "{report}");
    for row in rows {
        assert!(row["linear_mrays_per_second"].as_f64().is_some(), "{row}");
    }
}
