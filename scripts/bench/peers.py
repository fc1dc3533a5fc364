#!/usr/bin/env python3
"""meshtracer against Intel Embree 4 (ray queries) and Mitsuba 3 (path tracing), on one thread.

Set up once (the peers are not in CI: too heavy), from the repository's root:

    cargo build --release
    python3 -m venv .venv-peers
    .venv-peers/bin/pip install -r scripts/bench/requirements-peers.txt
    apt-get install libllvm19        # optional: Mitsuba's llvm_ad_rgb variant needs libLLVM

then run

    MESHTRACER_SAMPLES=/path/to/assets .venv-peers/bin/python scripts/bench/peers.py \\
        [MODEL ...] [--rounds 5] [--side 512] [--cli target/release/meshtracer]

Models default to the bundled Cornell box and, under $MESHTRACER_SAMPLES, the Stanford bunny,
DamagedHelmet and MetalRoughSpheresNoTextures (those missing are skipped with a message).

**Embree.** For each model `meshtracer bench MODEL --export-rays DIR --double-sided` writes the
triangles it traces, its primary, shadow and diffuse rays and its BVH's answers as .npy files.
Embree (the `embreex` wheel: one `rtcIntersect1`/`rtcOccluded1` per ray from its Cython loop)
builds a scene of the same triangles (build timed apart) and traces the same rays: closest hit
for primary and diffuse rays, occlusion for shadow rays. Its answers are checked ray for ray
against meshtracer's; disagreements are counted, with ties (another triangle at the same t) and
grazing hits (within EDGE of a triangle's edge) counted apart. Then `--rounds` interleaved
rounds: one `meshtracer bench MODEL --threads 1 --runs 1 --json` process, one more with
`--packets` (eight consecutive rays at a time through meshtracer's packet queries), then Embree
on each ray kind; the table gives the medians and meshtracer/Embree rays per second for both.

**Mitsuba 3.** The bundled Cornell box made diffuse (every material Lambertian: metallic 0,
`KHR_materials_specular` factor 0; the punctual lights removed, the emissive lamp panel kept
and made single-sided, as a Mitsuba area light emits from its front alone) is written as a glTF
for meshtracer (rendered with --no-default-lights: no studio environment) and, through
meshtracer's own export of its triangles and per-triangle materials, as a Mitsuba scene dict
(the same albedos, the lamp an area emitter of the same radiance, the same camera). Both render
it at 512x512, 16 spp, the same path depth, in interleaved rounds: `meshtracer render
--integrator path --threads 1 --stats` (its render phase) against `mi.render` after one warm-up
render (which compiles the llvm variant's kernels). The table gives samples per second and the
mean luminance of each image. Then the same at equal time: Mitsuba renders a converged
reference (`llvm_ad_rgb`, --reference-spp, every CPU), each variant renders again per round
with the spp that fits meshtracer's median render time at its own measured speed, and the
second table gives each side's RMSE against the reference (meshtracer's from its images of the
rounds; lower is better). Last, where a sample's time goes: the box's primary, shadow and
diffuse rays (`bench --export-rays`) traced alone by meshtracer (`bench`, one at a time) and by
Mitsuba's `llvm_ad_rgb` (`ray_intersect_preliminary` and `ray_test` on the whole wavefront,
which Mitsuba 3 hands to Embree's 16-ray packet queries, `rtcIntersect16`/`rtcOccluded16`),
interleaved;
times meshtracer's rays per sample (`--stats`: camera, shadow and bounce rays), that gives the
traversal's share of a sample, for Mitsuba on the assumption that its path tracer traces as
many rays a sample (the same algorithm: a light sample and a BSDF sample at each vertex).

Everything runs pinned to one CPU (os.sched_setaffinity): Embree's build (TBB), Mitsuba's
threads and meshtracer's all get one core; the timings of a shared machine are as noisy as its
load, which interleaving spreads over both sides alike. A peer that cannot be imported is
skipped with a message. Prints Markdown (docs/benchmarks.md records a run).
"""

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

try:
    import numpy as np
except ImportError:
    sys.exit("peers.py needs numpy: run it with the venv its docstring sets up")

REPO = Path(__file__).resolve().parents[2]
KINDS = ("primary", "shadow", "diffuse")
# A hit parameter within this fraction (of max(1, t)) of the other's is the same distance:
# two triangles that share the edge or vertex the ray passes through (a tie).
T_TOLERANCE = 1e-4
# A hit this close to an edge, in barycentric terms, is grazing: the two tracers' triangle
# tests (meshtracer's plane and three edge tests, Embree's) may round it either way.
EDGE = 1e-4
MISS = np.uint32(0xFFFFFFFF)
DEFAULT_MODELS = (
    "StanfordBunny-OBJ/stanford-bunny.obj",
    "DamagedHelmet/glTF/DamagedHelmet.gltf",
    "MetalRoughSpheresNoTextures/glTF/MetalRoughSpheresNoTextures.gltf",
)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="*", type=Path)
    parser.add_argument("--cli", type=Path, default=REPO / "target" / "release" / "meshtracer")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--side", type=int, default=512, help="primary rays per image side")
    parser.add_argument("--size", type=int, default=512, help="Mitsuba comparison: image side")
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--bounces", type=int, default=8, help="meshtracer --bounces (Mitsuba max_depth = bounces + 2)")
    parser.add_argument("--reference-spp", type=int, default=1024,
                        help="Mitsuba comparison: spp of the converged reference for the equal-time RMSE (0 skips it)")
    parser.add_argument("--skip-embree", action="store_true")
    parser.add_argument("--skip-mitsuba", action="store_true")
    args = parser.parse_args()
    if not args.cli.is_file():
        sys.exit(f"{args.cli}: no meshtracer binary (cargo build --release, or --cli PATH)")
    cpu = max(os.sched_getaffinity(0))
    os.sched_setaffinity(0, {cpu})
    print(f"Pinned to CPU {cpu}; {date()}; {cpu_name()}\n")
    models = args.models or default_models()
    with tempfile.TemporaryDirectory(prefix="meshtracer-peers-") as tmp:
        if not args.skip_embree:
            embree_comparison(args, models, Path(tmp))
        if not args.skip_mitsuba:
            mitsuba_comparison(args, Path(tmp))


def default_models():
    models = [REPO / "assets" / "cornell-box.gltf"]
    samples = os.environ.get("MESHTRACER_SAMPLES")
    if not samples:
        print("MESHTRACER_SAMPLES is not set: the Cornell box alone\n")
        return models
    for name in DEFAULT_MODELS:
        path = Path(samples) / name
        if path.is_file():
            models.append(path)
        else:
            print(f"{path}: missing, skipped")
    return models


def date():
    return time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())


def cpu_name():
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return "unknown CPU"


def run(command):
    result = subprocess.run([str(c) for c in command], capture_output=True, text=True)
    if result.returncode != 0:
        sys.exit(f"failed: {' '.join(map(str, command))}\n{result.stderr}")
    return result.stdout


def bench_command(args, model, *extra):
    return [args.cli, "bench", model, "--sizes=", "--rays", ",".join(KINDS), "--double-sided",
            "--side", args.side, "--threads", 1, "--runs", 1, "--linear-budget", 0, "--json", "-q",
            *extra]


# --- Embree -------------------------------------------------------------------------------


def embree_comparison(args, models, tmp):
    try:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh
    except ImportError as error:
        print(f"Embree skipped: embreex cannot be imported ({error}); see the docstring\n")
        return
    scenes = []
    for model in models:
        folder = tmp / f"rays-{len(scenes)}"
        run(bench_command(args, model, "--export-rays", folder))
        scene = EmbreeModel(model, folder, rtcore_scene, TriangleMesh)
        print(f"{model.name}: {scene.count} triangles, Embree build {scene.build_ms[0]:.1f} ms; "
              + "; ".join(scene.check(kind) for kind in KINDS))
        scenes.append(scene)
    print()
    ours = {(s.name, k): [] for s in scenes for k in KINDS}
    packets = {(s.name, k): [] for s in scenes for k in KINDS}
    our_build = {s.name: [] for s in scenes}
    theirs = {(s.name, k): [] for s in scenes for k in KINDS}
    for round_ in range(args.rounds):
        print(f"round {round_ + 1}/{args.rounds}", file=sys.stderr)
        for scene in scenes:
            report = json.loads(run(bench_command(args, scene.model)))
            for row in report["rows"]:
                ours[(scene.name, row["rays"])].append(row["mrays_per_second_per_thread"])
                our_build[scene.name].append(row["build_ms"])
            report = json.loads(run(bench_command(args, scene.model, "--packets")))
            for row in report["rows"]:
                packets[(scene.name, row["rays"])].append(row["mrays_per_second_per_thread"])
            scene.build_ms.append(scene.build())
            for kind in KINDS:
                theirs[(scene.name, kind)].append(scene.time(kind))
    print(f"Ray queries, one thread, median of {args.rounds} interleaved rounds, "
          f"{args.side}x{args.side} primary rays and a shadow and a diffuse ray from each hit:\n")
    print("meshtracer traces the rays one at a time, then eight consecutive ones at a time "
          "(`--packets`); Embree (embreex) one at a time.\n")
    print("| model | triangles | ray kind | rays | meshtracer Mrays/s | eight at a time | Embree Mrays/s | meshtracer / Embree | eight at a time / Embree | disagreements |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---|")
    for scene in scenes:
        for kind in KINDS:
            m = statistics.median(ours[(scene.name, kind)])
            p = statistics.median(packets[(scene.name, kind)])
            e = statistics.median(theirs[(scene.name, kind)])
            print(f"| {scene.name} | {scene.count} | {kind} | {len(scene.rays[kind][0])} | {m:.2f} | "
                  f"{p:.2f} | {e:.2f} | {m / e:.2f} | **{p / e:.2f}** | {scene.checks[kind]} |")
    print("\n| model | meshtracer BVH build ms (1 thread, medium preset) | Embree build ms (1 thread, median of the rounds) |")
    print("|---|---:|---:|")
    for scene in scenes:
        print(f"| {scene.name} | {statistics.median(our_build[scene.name]):.1f} | "
              f"{statistics.median(scene.build_ms[1:]):.1f} |")
    print()


class EmbreeModel:
    """One model's exported triangles and rays, and an Embree scene of the triangles."""

    def __init__(self, model, folder, rtcore_scene, TriangleMesh):
        self.model, self.name = model, model.name
        self.triangles = np.load(folder / "triangles.npy")
        self.count = len(self.triangles)
        self.rays, self.expected, self.checks = {}, {}, {}
        for kind in KINDS:
            rays = np.load(folder / f"{kind}.npy")
            # embreex starts every ray at t = 0: move the origin to tmin (primary rays start
            # at the camera's near plane) and measure t from there.
            origins = rays[:, 0:3] + rays[:, 3:6] * rays[:, 6:7]
            self.rays[kind] = (np.ascontiguousarray(origins, dtype=np.float32),
                               np.ascontiguousarray(rays[:, 3:6]),
                               np.ascontiguousarray(rays[:, 7] - rays[:, 6]),
                               rays[:, 6])
            if kind == "shadow":
                self.expected[kind] = np.load(folder / "shadow_occluded.npy") == 1
            else:
                self.expected[kind] = (np.load(folder / f"{kind}_triangle.npy"),
                                       np.load(folder / f"{kind}_t.npy"))
        self.embree = (rtcore_scene, TriangleMesh)
        self.build_ms = [self.build()]

    def build(self):
        """Builds the Embree scene anew; returns the milliseconds it took."""
        rtcore_scene, TriangleMesh = self.embree
        self.scene = None  # the old scene's memory goes first
        start = time.perf_counter()
        self.scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self.scene, self.triangles)
        # embreex commits (builds) the scene on its first query.
        one = self.rays["primary"]
        self.scene.run(one[0][:1], one[1][:1])
        return (time.perf_counter() - start) * 1e3

    def query(self, kind, output=None):
        origins, directions, tmax, _ = self.rays[kind]
        query = "OCCLUDED" if kind == "shadow" else "INTERSECT"
        return self.scene.run(origins, directions, dists=tmax.copy(), query=query, output=output)

    def time(self, kind):
        """Embree's million rays per second on `kind`, one pass."""
        start = time.perf_counter()
        self.query(kind)
        return len(self.rays[kind][0]) / (time.perf_counter() - start) / 1e6

    def check(self, kind):
        """Embree's answers against meshtracer's, ray for ray: a short report, kept."""
        if kind == "shadow":
            blocked = self.query(kind) != -1
            differ = int(np.count_nonzero(blocked != self.expected[kind]))
            self.checks[kind] = f"{differ} ({100 * differ / max(1, len(blocked)):.3f}%)"
            return f"shadow: {differ} of {len(blocked)} differ"
        hits = self.query(kind, output=1)
        theirs = hits["primID"].astype(np.int64)
        their_t = np.where(theirs >= 0, hits["tfar"] + self.rays[kind][3], np.inf)
        ours_raw, our_t = self.expected[kind]
        ours = np.where(ours_raw == MISS, -1, ours_raw.astype(np.int64))
        differ = np.flatnonzero(ours != theirs)
        both = (ours[differ] >= 0) & (theirs[differ] >= 0)
        scale = np.maximum(1.0, np.abs(our_t[differ]))
        tie = both & (np.abs(our_t[differ] - their_t[differ]) <= T_TOLERANCE * scale)
        graze = ~tie & self.grazing(kind, differ, ours, theirs)
        other = len(differ) - int(tie.sum()) - int(graze.sum())
        # Where both hit the same triangle, how far apart their distances are.
        same = (ours == theirs) & (ours >= 0)
        t_error = np.abs(our_t[same] - their_t[same]) / np.maximum(1.0, np.abs(our_t[same]))
        self.checks[kind] = (f"{len(differ)} ({100 * len(differ) / max(1, len(ours)):.3f}%): "
                             f"{int(tie.sum())} ties, {int(graze.sum())} grazing, {other} other; "
                             f"same triangle: t within {t_error.max(initial=0):.1e}")
        return f"{kind}: {self.checks[kind]}"

    def grazing(self, kind, rays, ours, theirs):
        """For each ray index in `rays`: whether the hit either side found lies within EDGE
        (barycentric) of an edge of its triangle."""
        origins, directions, _, _ = self.rays[kind]
        near_edge = np.zeros(len(rays), dtype=bool)
        for found in (ours, theirs):
            tri = found[rays]
            hit = tri >= 0
            a, b, c = (self.triangles[tri[hit], i].astype(np.float64) for i in range(3))
            o, d = origins[rays[hit]].astype(np.float64), directions[rays[hit]].astype(np.float64)
            # Möller-Trumbore barycentrics of the ray's crossing of the triangle's plane.
            e1, e2 = b - a, c - a
            p = np.cross(d, e2)
            det = np.einsum("ij,ij->i", e1, p)
            det = np.where(np.abs(det) < 1e-30, 1e-30, det)
            s = o - a
            u = np.einsum("ij,ij->i", s, p) / det
            v = np.einsum("ij,ij->i", d, np.cross(s, e1)) / det
            smallest = np.minimum(np.minimum(u, v), 1 - u - v)
            near_edge[hit] |= np.abs(smallest) <= EDGE
        return near_edge


# --- Mitsuba 3 ----------------------------------------------------------------------------


def mitsuba_comparison(args, tmp):
    try:
        import mitsuba as mi
    except ImportError as error:
        print(f"Mitsuba skipped: mitsuba cannot be imported ({error}); see the docstring\n")
        return
    import drjit as dr

    variants = []
    for variant in ("scalar_rgb", "llvm_ad_rgb"):
        try:
            mi.set_variant(variant)
            variants.append(variant)
        except Exception as error:  # the llvm variant raises without libLLVM
            print(f"Mitsuba {variant} skipped: {error}")
    if not variants:
        return
    gltf_path, camera = diffuse_cornell_box(tmp)
    folder = tmp / "cornell"
    run([args.cli, "bench", gltf_path, "--sizes=", "--rays", "primary", "--side", 8, "--runs", 1,
         "--linear-budget", 0, "--json", "-q", "--export-rays", folder])
    triangles = np.load(folder / "triangles.npy")
    materials = np.load(folder / "triangle_materials.npy")
    gltf = json.loads(gltf_path.read_text())
    depth = args.bounces + 2  # Mitsuba's max_depth counts the camera segment and the emitter hit
    scenes = {}
    for variant in variants:
        mi.set_variant(variant)
        # One thread for Mitsuba's own pool and Dr.Jit's kernels.
        dr.set_thread_count(1)
        scene = mi.load_dict(mitsuba_scene(mi, tmp, triangles, materials, gltf, camera, args, depth))
        render_mitsuba(mi, scene, args.spp, 0)  # warm-up: kernel compilation, caches
        scenes[variant] = scene

    ours, our_seconds, our_images = [], [], []
    theirs = {v: [] for v in variants}
    their_seconds = {v: [] for v in variants}
    their_means = {v: [] for v in variants}
    samples = args.size * args.size * args.spp
    for round_ in range(args.rounds):
        print(f"Mitsuba round {round_ + 1}/{args.rounds}", file=sys.stderr)
        out, stats = tmp / "mt.exr", tmp / "mt.json"
        run([args.cli, "render", gltf_path, "--integrator", "path", "--spp", args.spp,
             "--bounces", args.bounces, "--width", args.size, "--height", args.size,
             "--threads", 1, "--seed", round_ + 1, "-o", out, "--stats", stats, "-q",
             "--no-default-lights", "--no-warnings"])
        report = json.loads(stats.read_text())
        seconds = next(p["seconds"] for p in report["phases"] if p["phase"] == "render")
        ours.append(report["samples"] / seconds)
        rays_per_sample = {k: n / report["samples"] for k, n in report["rays_by_kind"].items()}
        our_seconds.append(seconds)
        # Reading an EXR deadlocks with one Dr.Jit thread (Mitsuba 3.9): two while it reads.
        dr.set_thread_count(2)
        our_images.append(np.array(mi.Bitmap(str(out)), dtype=np.float64)[..., :3])
        dr.set_thread_count(1)
        for variant in variants:
            mi.set_variant(variant)
            image, seconds = render_mitsuba(mi, scenes[variant], args.spp, round_ + 1)
            theirs[variant].append(samples / seconds)
            their_seconds[variant].append(seconds)
            their_means[variant].append(luminance(image).mean())
    our_mean = statistics.mean(luminance(i).mean() for i in our_images)
    print(f"\nPath tracing, the diffuse Cornell box ({len(triangles)} triangles), {args.size}x"
          f"{args.size}, {args.spp} spp, meshtracer --bounces {args.bounces} = Mitsuba max_depth "
          f"{depth}, one thread, median of {args.rounds} interleaved rounds:\n")
    print("| renderer | samples/s | meshtracer / it | mean luminance (mean of rounds) | difference |")
    print("|---|---:|---:|---:|---:|")
    m = statistics.median(ours)
    print(f"| meshtracer | {m:,.0f} | 1 | {our_mean:.5f} | |")
    for variant in variants:
        t = statistics.median(theirs[variant])
        mean = statistics.mean(their_means[variant])
        print(f"| Mitsuba 3 `{variant}` | {t:,.0f} | **{m / t:.2f}** | {mean:.5f} | "
              f"{100 * (our_mean / mean - 1):+.2f}% |")
    print()
    if args.reference_spp > 0:
        def multijitter_scene():
            scene = mitsuba_scene(mi, tmp, triangles, materials, gltf, camera, args, depth)
            scene["sensor"]["sampler"]["type"] = "multijitter"
            return mi.load_dict(scene)

        equal_time_rmse(mi, dr, args, scenes, multijitter_scene, our_images, our_seconds,
                        their_seconds)
    if "llvm_ad_rgb" in scenes:
        time_budget(mi, dr, args, tmp, gltf_path, scenes["llvm_ad_rgb"], rays_per_sample,
                    {"meshtracer": m, "llvm_ad_rgb": statistics.median(theirs["llvm_ad_rgb"])})


def time_budget(mi, dr, args, tmp, gltf_path, scene, rays_per_sample, samples_per_second):
    """Where a path-traced sample's time goes: the box's exported rays traced alone by each side
    (interleaved rounds, medians), times meshtracer's rays per sample, against the time a sample
    takes. Mitsuba is assumed to trace as many rays a sample."""
    folder = tmp / "cornell-rays"
    run(bench_command(args, gltf_path, "--export-rays", folder))
    mi.set_variant("llvm_ad_rgb")
    dr.set_thread_count(1)
    wavefronts = {}
    for kind in KINDS:
        rays = np.load(folder / f"{kind}.npy").astype(np.float32)
        o = rays[:, 0:3] + rays[:, 3:6] * rays[:, 6:7]
        d, maxt = rays[:, 3:6], rays[:, 7] - rays[:, 6]
        ray = mi.Ray3f(mi.Point3f(o[:, 0], o[:, 1], o[:, 2]),
                       mi.Vector3f(d[:, 0], d[:, 1], d[:, 2]))
        ray.maxt = mi.Float(maxt)
        dr.eval(ray)
        wavefronts[kind] = (ray, len(rays))

    def mitsuba_rate(kind):
        ray, n = wavefronts[kind]
        start = time.perf_counter()
        if kind == "shadow":
            dr.eval(scene.ray_test(ray))
        else:
            dr.eval(scene.ray_intersect_preliminary(ray).t)
        return n / (time.perf_counter() - start) / 1e6

    for kind in KINDS:  # warm-up: kernel compilation
        mitsuba_rate(kind)
    ours = {k: [] for k in KINDS}
    theirs = {k: [] for k in KINDS}
    for _ in range(args.rounds):
        for row in json.loads(run(bench_command(args, gltf_path)))["rows"]:
            ours[row["rays"]].append(row["mrays_per_second_per_thread"])
        for kind in KINDS:
            theirs[kind].append(mitsuba_rate(kind))
    rates = {"meshtracer": {k: statistics.median(v) for k, v in ours.items()},
             "llvm_ad_rgb": {k: statistics.median(v) for k, v in theirs.items()}}
    # The path tracer's rays by kind against the bench's: camera rays are primary rays, bounces
    # diffuse ones.
    per_sample = {"primary": rays_per_sample["primary"], "shadow": rays_per_sample["shadow"],
                  "diffuse": rays_per_sample["indirect"]}
    print("Where a sample's time goes, the same Cornell box, one thread: the box's rays traced "
          f"alone (median of {args.rounds} interleaved rounds, Mrays/s; meshtracer one at a time, "
          "Mitsuba its wavefront through Embree's packet queries), and with meshtracer's "
          f"rays per sample ({per_sample['primary']:.2f} camera, {per_sample['shadow']:.2f} "
          f"shadow, {per_sample['diffuse']:.2f} bounce) the traversal's share of a sample:\n")
    print("| renderer | primary | shadow | diffuse | µs a sample | traversal µs (est.) | the rest µs |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name, rate in rates.items():
        total = 1e6 / samples_per_second[name]
        traversal = sum(per_sample[k] / rate[k] for k in KINDS)
        print(f"| {name} | {rate['primary']:.2f} | {rate['shadow']:.2f} | {rate['diffuse']:.2f} "
              f"| {total:.3f} | {traversal:.3f} | {total - traversal:.3f} |")
    print()


def equal_time_rmse(mi, dr, args, scenes, multijitter_scene, our_images, our_seconds,
                    their_seconds):
    """RMSE against a converged reference at equal render time: meshtracer's images of the
    rounds above (its median time is the budget) against each Mitsuba variant given the spp
    that fits the same budget at its measured speed, rendered and timed again per round
    (seeds 101...), with its default `independent` sampler and, for `llvm_ad_rgb`, with
    `multijitter` too (its best sampler on this scene; the spp the largest square that fits,
    as it asks for a square; each sample costs it about a fifth more than an independent
    one). The reference is Mitsuba `llvm_ad_rgb` (else the first variant) at
    --reference-spp with every CPU, so a bias of meshtracer's against Mitsuba counts against
    meshtracer. Its own noise adds the same to both sides' squared error: at 1024 against 16
    spp about 1.6%, under 1% of the RMSE. A new spp recompiles the llvm kernels: the first
    round of each row pays for it, the median does not."""
    variant = "llvm_ad_rgb" if "llvm_ad_rgb" in scenes else next(iter(scenes))
    mi.set_variant(variant)
    pinned = os.sched_getaffinity(0)
    os.sched_setaffinity(0, range(os.cpu_count() or 1))
    dr.set_thread_count(os.cpu_count() or 1)
    print(f"Reference: Mitsuba {variant} at {args.reference_spp} spp", file=sys.stderr)
    start = time.perf_counter()
    reference, _ = render_mitsuba(mi, scenes[variant], args.reference_spp, 1000)
    reference = reference[..., :3]
    reference_seconds = time.perf_counter() - start
    os.sched_setaffinity(0, pinned)
    dr.set_thread_count(1)
    budget = statistics.median(our_seconds)
    ours = [rmse(image, reference) for image in our_images]
    rows = [("meshtracer (Owen-scrambled Sobol)", args.spp, budget, statistics.median(ours))]
    runs = [(name, "independent", scenes[name], seconds) for name, seconds in their_seconds.items()]
    if "llvm_ad_rgb" in scenes:
        mi.set_variant("llvm_ad_rgb")
        runs.append(("llvm_ad_rgb", "multijitter", multijitter_scene(),
                     their_seconds["llvm_ad_rgb"]))
    for name, sampler, scene, seconds in runs:
        # The spp that fits the budget at the speed measured in the rounds (at least 1).
        spp = max(1, round(args.spp * budget / statistics.median(seconds)))
        if sampler == "multijitter":
            spp = max(1, math.isqrt(spp)) ** 2
        mi.set_variant(name)
        errors, times = [], []
        for round_ in range(len(our_images)):
            print(f"Mitsuba {name} {sampler} at {spp} spp, round {round_ + 1}", file=sys.stderr)
            image, took = render_mitsuba(mi, scene, spp, 101 + round_)
            errors.append(rmse(image[..., :3], reference))
            times.append(took)
        rows.append((f"Mitsuba 3 `{name}` ({sampler})", spp, statistics.median(times),
                     statistics.median(errors)))
    print(f"Equal time, the same Cornell box: RMSE of linear RGB against Mitsuba {variant} at "
          f"{args.reference_spp} spp (rendered in {reference_seconds:.0f} s on every CPU), "
          f"one thread, median of {len(our_images)} rounds (lower is better):\n")
    print("| renderer (sampler) | spp | render time (s) | RMSE | meshtracer / it |")
    print("|---|---:|---:|---:|---:|")
    mine = rows[0][3]
    for index, (name, spp, seconds, error) in enumerate(rows):
        ratio = "1" if index == 0 else f"**{mine / error:.2f}**"
        print(f"| {name} | {spp} | {seconds:.2f} | {error:.5f} | {ratio} |")
    print()


def rmse(image, reference):
    return float(np.sqrt(np.mean((image - reference) ** 2)))


def render_mitsuba(mi, scene, spp, seed):
    start = time.perf_counter()
    image = np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float64)
    return image, time.perf_counter() - start


def luminance(rgb):
    return rgb[..., 0] * 0.2126 + rgb[..., 1] * 0.7152 + rgb[..., 2] * 0.0722


def diffuse_cornell_box(tmp):
    """The bundled Cornell box with Lambertian materials and its emissive panel as the only
    light, written to `tmp`; and its first camera (node translation, rotation, yfov)."""
    gltf = json.loads((REPO / "assets" / "cornell-box.gltf").read_text())
    for material in gltf["materials"]:
        pbr = material.setdefault("pbrMetallicRoughness", {})
        pbr["metallicFactor"], pbr["roughnessFactor"] = 0.0, 1.0
        material.setdefault("extensions", {})["KHR_materials_specular"] = {"specularFactor": 0.0}
        if max(material.get("emissiveFactor", [0])) > 0:
            # A double-sided emissive triangle emits from both faces in meshtracer, a Mitsuba
            # area light from its front alone: the lamp's back, 1 mm under the ceiling, added
            # 1.7% to the mean at 8 bounces. Single-sided, the means agree within 0.1%.
            material["doubleSided"] = False
    gltf.get("extensions", {}).pop("KHR_lights_punctual", None)
    for node in gltf["nodes"]:
        node.get("extensions", {}).pop("KHR_lights_punctual", None)
    used = [e for e in gltf.get("extensionsUsed", []) if e != "KHR_lights_punctual"]
    gltf["extensionsUsed"] = used + ["KHR_materials_specular"]
    node = next(n for n in gltf["nodes"] if "camera" in n)
    camera = {
        "translation": node.get("translation", [0, 0, 0]),
        "rotation": node.get("rotation", [0, 0, 0, 1]),
        "yfov": gltf["cameras"][node["camera"]]["perspective"]["yfov"],
    }
    path = tmp / "cornell-box-diffuse.gltf"
    path.write_text(json.dumps(gltf))
    return path, camera


def write_ply(path, triangles):
    """Triangles (n, 3, 3) as a binary PLY of unshared vertices (flat shading)."""
    n = len(triangles)
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {3 * n}\n"
              "property float x\nproperty float y\nproperty float z\n"
              f"element face {n}\nproperty list uchar int vertex_indices\nend_header\n")
    faces = np.zeros(n, dtype=[("count", "u1"), ("index", "<i4", 3)])
    faces["count"] = 3
    faces["index"] = np.arange(3 * n, dtype="<i4").reshape(n, 3)
    with open(path, "wb") as file:
        file.write(header.encode())
        file.write(triangles.astype("<f4").tobytes())
        file.write(faces.tobytes())


def mitsuba_scene(mi, tmp, triangles, materials, gltf, camera, args, depth):
    """A Mitsuba scene dict of the exported triangles: one PLY shape per material, diffuse
    with the glTF base colour, the emissive material an area light of its radiance."""
    x, y, z, w = camera["rotation"]
    rotation = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
    world_from_camera = np.eye(4)
    world_from_camera[:3, :3] = rotation
    world_from_camera[:3, 3] = camera["translation"]
    # glTF cameras look down -Z with +X to the right; Mitsuba's down +Z with +X to the left.
    world_from_camera = world_from_camera @ np.diag([-1.0, 1.0, -1.0, 1.0])
    scene = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": depth, "rr_depth": 3},
        "sensor": {
            "type": "perspective",
            "fov": math.degrees(camera["yfov"]),
            "fov_axis": "y",
            "near_clip": 0.05,
            "to_world": mi.ScalarTransform4f(world_from_camera.tolist()),
            "sampler": {"type": "independent", "sample_count": args.spp},
            "film": {"type": "hdrfilm", "width": args.size, "height": args.size,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        },
    }
    for index in np.unique(materials):
        material = gltf["materials"][index]
        albedo = material.get("pbrMetallicRoughness", {}).get("baseColorFactor", [1, 1, 1, 1])[:3]
        path = tmp / f"material-{index}.ply"
        write_ply(path, triangles[materials == index])
        shape = {"type": "ply", "filename": str(path), "face_normals": True,
                 # Two-sided, as the box's doubleSided glTF materials (Mitsuba's diffuse is
                 # black from behind).
                 "bsdf": {"type": "twosided", "bsdf": {
                     "type": "diffuse", "reflectance": {"type": "rgb", "value": albedo}}}}
        emission = material.get("emissiveFactor", [0, 0, 0])
        if max(emission) > 0:
            shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": emission}}
        scene[f"material-{index}"] = shape
    return scene


if __name__ == "__main__":
    main()
