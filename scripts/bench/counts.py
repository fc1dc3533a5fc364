#!/usr/bin/env python3
"""Instructions, cache misses and branches a ray: meshtracer's BVH queries against Embree's, under valgrind.

Where `peers.py` times the two tracers, this counts what each does for a ray, on the same
triangles and rays, so that a change to the traversal can be judged by more than its time on a
noisy host. Set up as for `peers.py` (its venv, for `embreex` and NumPy), plus valgrind
(`apt-get install valgrind`); then, from the repository's root:

    MESHTRACER_SAMPLES=/path/to/assets .venv-peers/bin/python scripts/bench/counts.py \\
        [MODEL ...] [--kinds primary,shadow,diffuse] [--side 256] [--passes 10] [--branches]

Models default to those of `peers.py`. For each model, `meshtracer bench MODEL --export-rays
DIR --double-sided --side SIDE` writes the triangles and rays (camera rays, and a shadow and a
diffuse ray from each camera hit). Then, one process at a time, single-threaded:

- **meshtracer**: `callgrind` runs `meshtracer bench MODEL --rays KIND --threads 1 --runs
  PASSES-1` (a warm-up and PASSES-1 timed runs: PASSES walks over the rays), collecting only
  inside the query (`Accel::intersect_filtered` for closest hits, `Accel::occluded_filtered`
  for shadow rays). A run of two passes is taken off, so the figures are those of the passes
  beyond two (a warm cache), and a diffuse run's camera rays (traced once, for the diffuse
  rays to start from) cancel.
- **Embree** (`embreex`, one `rtcIntersect1`/`rtcOccluded1` a ray, as `peers.py` calls it):
  `callgrind` runs a small driver that builds the scene (inside embreex's first `run`) and
  traces the rays PASSES times, dumping its counts after each `run`; the dumps of the passes
  beyond two are summed over Embree's library (`libembree4`: its stripped internals, the
  traversal among them, and its entry points `rtcIntersect1`, `rtcOccluded1`).

Both simulate the same caches: a first-level data cache of `--l1` and a last level of `--ll`
(valgrind's two levels; the defaults are Zen 4's L1 and L3, and `--ll 1048576,8,64` models
its L2 instead). `--branches` adds valgrind's branch model (a simple predictor without global
history, which mispredicts more than a modern CPU's). Valgrind's CPU has no AVX-512, so Embree
runs its AVX2 kernels, as meshtracer does everywhere.

The two are counted at slightly different edges: meshtracer's query reads its ray from the
bench's array of 48-byte rays (about 0.75 first-level misses a ray, streaming), where embreex
copies each ray into Embree's struct in its own code, which is not counted. On a model whose
data fits the first level (the bundled Cornell box) that is most of meshtracer's misses.

Prints a Markdown table. A model takes a few minutes, the 1.04M-triangle one about fifteen
(valgrind runs the programs 20-50 times slower). docs/performance-log.md records a run
("Instructions and cache misses a ray, against Embree").
"""

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import peers  # noqa: E402  (the shared helpers: models, the bench command's conventions)

np = peers.np

# The Embree side: build a scene of the exported triangles, then trace each kind PASSES times.
EMBREE_DRIVER = """
import sys, numpy as np
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh
folder, kinds, passes = sys.argv[1], [k for k in sys.argv[2].split(",") if k], int(sys.argv[3])
scene = rtcore_scene.EmbreeScene()
TriangleMesh(scene, np.load(folder + "/triangles.npy"))
def rays(kind):
    r = np.load(f"{folder}/{kind}.npy")
    # embreex starts every ray at t = 0: move the origin to tmin (as peers.py does).
    o = np.ascontiguousarray(r[:, 0:3] + r[:, 3:6] * r[:, 6:7], dtype=np.float32)
    return o, np.ascontiguousarray(r[:, 3:6]), np.ascontiguousarray(r[:, 7] - r[:, 6])
o, d, _ = rays("primary")
scene.run(o[:1], d[:1])  # embreex builds the scene on its first query
for kind in kinds:
    o, d, t = rays(kind)
    for _ in range(passes):
        scene.run(o, d, dists=t.copy(), query="OCCLUDED" if kind == "shadow" else "INTERSECT")
"""

# What the table shows, by valgrind's event names: (column, events summed).
COLUMNS = (
    ("instructions", ("Ir",)),
    ("L1 data misses", ("D1mr", "D1mw")),
    ("last-level misses", ("DLmr", "DLmw")),
)
BRANCH_COLUMNS = (
    ("conditional branches", ("Bc",)),
    ("mispredicted", ("Bcm",)),
)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="*", type=Path)
    parser.add_argument("--cli", type=Path, default=peers.REPO / "target" / "release" / "meshtracer")
    parser.add_argument("--kinds", default=",".join(peers.KINDS))
    parser.add_argument("--side", type=int, default=256, help="camera rays per image side")
    parser.add_argument("--passes", type=int, default=10, help="walks over the rays (at least 3)")
    parser.add_argument("--l1", default="32768,8,64", help="first-level data cache: size,ways,line")
    parser.add_argument("--ll", default="33554432,16,64", help="last-level cache: size,ways,line")
    parser.add_argument("--branches", action="store_true", help="add valgrind's branch model")
    args = parser.parse_args()
    kinds = [k for k in args.kinds.split(",") if k]
    if unknown := set(kinds) - set(peers.KINDS):
        sys.exit(f"--kinds: unknown {', '.join(sorted(unknown))} (primary, shadow, diffuse)")
    if args.passes < 3:
        sys.exit("--passes: at least 3 (the counts are those of the passes beyond two)")
    if not args.cli.is_file():
        sys.exit(f"{args.cli}: no meshtracer binary (cargo build --release, or --cli PATH)")
    if not shutil.which("valgrind"):
        sys.exit("valgrind is not installed (apt-get install valgrind)")
    try:
        import embreex  # noqa: F401
    except ImportError as error:
        sys.exit(f"embreex cannot be imported ({error}): run this with peers.py's venv")
    columns = COLUMNS + (BRANCH_COLUMNS if args.branches else ())
    print(f"{peers.date()}; {peers.cpu_name()}; caches: L1 data {args.l1}, last level {args.ll}; "
          f"{args.side}² camera rays, {args.passes} passes\n")
    headers = [f"{name} a ray, meshtracer / Embree" for name, _ in columns]
    print("| model | rays | " + " | ".join(headers) + " |")
    print("|---|---|" + "---:|" * len(columns))
    with tempfile.TemporaryDirectory(prefix="meshtracer-counts-") as tmp:
        for model in args.models or peers.default_models():
            for kind, ours, theirs in model_counts(args, model, kinds, Path(tmp)):
                cells = [f"{ratio_cell(ours, theirs, events)}" for _, events in columns]
                print(f"| {model.name} | {kind} | " + " | ".join(cells) + " |", flush=True)


def model_counts(args, model, kinds, tmp):
    """(kind, meshtracer's counts a ray, Embree's counts a ray) for each kind."""
    folder = Path(tempfile.mkdtemp(prefix=f"{model.stem}-", dir=tmp))
    peers.run([args.cli, "bench", model, "--sizes=", "--rays", ",".join(peers.KINDS),
               "--double-sided", "--side", args.side, "--threads", 1, "--runs", 1,
               "--linear-budget", 0, "-q", "--json", "--export-rays", folder])
    rays = {kind: len(np.load(folder / f"{kind}.npy")) for kind in peers.KINDS}
    driver = tmp / "embree_driver.py"
    driver.write_text(EMBREE_DRIVER)
    for kind in kinds:
        if rays[kind] == 0:
            print(f"{model}: no {kind} rays (the camera rays hit nothing), skipped", file=sys.stderr)
            continue
        # The passes beyond two, on each side: a warm cache, and for meshtracer's diffuse rays
        # without the camera rays they start from (traced once, after the build, in both runs).
        total = ours_events(args, model, kind, args.passes, tmp)
        two = ours_events(args, model, kind, 2, tmp)
        per_ray = rays[kind] * (args.passes - 2)
        ours = {e: (v - two.get(e, 0)) / per_ray for e, v in total.items()}
        theirs = {e: v / per_ray for e, v in embree_events(args, driver, folder, kind, tmp).items()}
        yield kind, ours, theirs


def valgrind_options(args):
    options = ["--tool=callgrind", "--cache-sim=yes", f"--D1={args.l1}", f"--LL={args.ll}"]
    return options + (["--branch-sim=yes"] if args.branches else [])


def ours_events(args, model, kind, passes, tmp):
    """meshtracer's events inside its query function over a whole `bench` run of `passes`."""
    query = "occluded_filtered" if kind == "shadow" else "intersect_filtered"
    out = tmp / f"callgrind.{kind}.{passes}.out"
    peers.run(["valgrind", *valgrind_options(args), "--collect-atstart=no",
               f"--toggle-collect=*Accel::{query}*", "--compress-strings=no", "--compress-pos=no",
               f"--callgrind-out-file={out}",
               args.cli, "bench", model, "--sizes=", "--rays", kind, "--double-sided",
               "--side", args.side, "--threads", 1, "--runs", passes - 1,
               "--linear-budget", 0, "-q", "--json"])
    counted = totals(out)
    if not counted.get("Ir"):
        sys.exit(f"{args.cli}: nothing counted inside Accel::{query} (inlined in this build?)")
    return counted


def embree_events(args, driver, folder, kind, tmp):
    """Embree's events in the driver's queries: callgrind dumps its counts after each call of
    embreex's `run` (the first call builds the scene), and the dumps after the first are
    summed over Embree's code."""
    out = tmp / f"callgrind.embree.{kind}.out"
    peers.run(["valgrind", *valgrind_options(args), "--dump-after=*EmbreeScene_2run*",
               "--compress-strings=no", "--compress-pos=no", f"--callgrind-out-file={out}",
               sys.executable, driver, folder, kind, args.passes])
    parts = sorted(out.parent.glob(out.name + ".*"), key=lambda p: int(p.suffix[1:]))
    if len(parts) != args.passes + 1:
        sys.exit(f"{out}: {len(parts)} dumps where {args.passes + 1} calls of embreex's run "
                 "were expected")
    sums = {}
    for part in parts[3:]:  # after the build's dump and the first two passes' (as ours)
        for event, value in totals(part, embree=True).items():
            sums[event] = sums.get(event, 0) + value
    return sums


def totals(path, embree=False):
    """Event totals of a callgrind output file (written without position or name compression):
    its `totals:` line, or, if `embree`, the sum of the self costs of Embree's library (`ob=`
    naming libembree: its stripped internals, the traversal among them, and its entry points
    `rtcIntersect1`, `rtcOccluded1`); not NumPy's and embreex's code, which copy each ray in
    and its answer out, nor TBB's threads."""
    events, sums, library, call = [], [], False, False
    for line in path.read_text(errors="replace").splitlines():
        if line.startswith("events:"):
            events = line.split()[1:]
            sums = [0] * len(events)
        elif line.startswith("totals:") and not embree:
            return dict(zip(events, map(int, line.split()[1:])))
        elif line.startswith("ob="):
            library = "libembree" in Path(line[3:]).name
        elif line.startswith("calls="):
            call = True  # the next cost line is the call's inclusive cost: not self cost
        elif line[:1].isdigit() or line.startswith("0x"):
            if embree and library and not call:
                for i, value in enumerate(line.split()[1:len(events) + 1]):
                    sums[i] += int(value)
            call = False
    return dict(zip(events, sums))


def ratio_cell(ours, theirs, events):
    a = sum(ours.get(e, 0) for e in events)
    b = sum(theirs.get(e, 0) for e in events)
    # No ratio of counts that are noise (the warm last level: a hundredth of a miss a ray).
    ratio = f" ({a / b:.2f}x)" if min(a, b) >= 0.01 else ""
    digits = 0 if max(a, b) >= 100 else 2
    return f"{a:,.{digits}f} / {b:,.{digits}f}{ratio}"


if __name__ == "__main__":
    main()
