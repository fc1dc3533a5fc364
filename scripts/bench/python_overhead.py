#!/usr/bin/env python3
"""What rendering from Python costs over the CLI's render phase, for the same work.

    python scripts/bench/python_overhead.py [MODEL] [--cli target/release/meshtracer]
        [--size 640x480] [--spp 16] [--runs 5]

Run it with the Python that has the meshtracer package (pip install ./python: the release
build, as the CLI it is compared with should be). For each of `--runs` interleaved rounds it
times one `meshtracer render MODEL ... --stats FILE` (the "render" phase of the JSON: the
pixel loop alone) and one `Scene.render(...)` call of an already prepared scene (the pixel loop,
the thread hand-over, the progress polling and the copy into NumPy arrays), with the same size,
spp, integrator, seed and AOVs (depth and mask in both). It prints the medians and the overhead
(Python / CLI - 1), and the overhead of the Python call over the library's own pixel loop in
the same call (`stats["render_seconds"]`), which needs no CLI of the same build (`--cli none`).
docs/python.md records a run.
"""

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import meshtracer

REPO = Path(__file__).resolve().parents[2]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", nargs="?", default=REPO / "assets" / "cornell-box.gltf")
    parser.add_argument("--cli", default=REPO / "target" / "release" / "meshtracer")
    parser.add_argument("--size", default="640x480")
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--integrator", default="direct")
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.lower().split("x"))

    scene = meshtracer.load(args.model)
    options = dict(spp=args.spp, integrator=args.integrator, seed=0, aovs=("depth", "mask"))
    scene.render(width, height, **options)  # prepares the scene (the CLI's other phases)
    cli_times, py_times, loop_times = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for _ in range(args.runs):
            start = time.perf_counter()
            out = scene.render(width, height, **options)
            py_times.append(time.perf_counter() - start)
            loop_times.append(out["stats"]["render_seconds"])
            if str(args.cli) == "none":
                continue
            stats = tmp / "stats.json"
            subprocess.run(
                [str(args.cli), "render", str(args.model), "-o", str(tmp / "out.png"),
                 "--width", str(width), "--height", str(height), "--spp", str(args.spp),
                 "--integrator", args.integrator, "--seed", "0", "--quiet",
                 "--depth-out", str(tmp / "depth.npy"), "--mask-out", str(tmp / "mask.npy"),
                 "--stats", str(stats)],
                check=True, capture_output=True)
            phases = json.loads(stats.read_text())["phases"]
            cli_times.append(next(p["seconds"] for p in phases if p["phase"] == "render"))

    def row(name, times):
        print(f"  {name:<28} {statistics.median(times) * 1000:9.1f} ms   (runs: "
              + ", ".join(f"{t * 1000:.0f}" for t in times) + ")")

    py = statistics.median(py_times)
    print(f"{args.model}: {width}x{height}, {args.spp} spp, {args.integrator}, "
          f"median of {args.runs}")
    row("Python render() call", py_times)
    row("its pixel loop", loop_times)
    print(f"  overhead over the pixel loop {(py / statistics.median(loop_times) - 1) * 100:+8.1f} %")
    if cli_times:
        row("CLI render phase", cli_times)
        print(f"  overhead over the CLI        {(py / statistics.median(cli_times) - 1) * 100:+8.1f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
