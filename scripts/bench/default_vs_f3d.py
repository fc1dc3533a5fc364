"""The default render against F3D 4.0, model by model (issue 39's last check).

For every shared glTF and OBJ model (the plain variant of each folder of MESHTRACER_SAMPLES) at
640x480 it prints two tables:

1. Wall time of `meshtracer render MODEL -o out.png --width 640 --height 480` (the default
   render: nothing else on the command line) against F3D 4.0 rendering the same file headless
   to a PNG of the same size, each in a fresh process, in interleaved rounds (median).
2. How far the default render is from its own converged image: mean FLIP against
   `--spp REFERENCE_SPP` of the same view (`--seed 1`), both through the default view
   transform.

F3D comes from PyPI (`pip install f3d==4.0.0`): run this script with that Python. F3D
rasterises with its default light kit (no environment, no shadows); it is the nearest CLI
peer, and the time a user waits for a picture is what is compared, not the pictures.

    python scripts/bench/default_vs_f3d.py --meshtracer target/release/meshtracer \
        --samples ../shared/assets [--rounds 3] [--reference-spp 256] [--out DIR] [--only Duck,Box]

docs/path-tracer.md ("The default render against F3D") has the figures and the conditions.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

MODELS = [
    "AnimatedMorphCube/glTF/AnimatedMorphCube.gltf",
    "Avocado/glTF/Avocado.gltf",
    "Box/glTF/Box.gltf",
    "BoxInterleaved/glTF/BoxInterleaved.gltf",
    "BoxTextured/glTF/BoxTextured.gltf",
    "Cameras/glTF/Cameras.gltf",
    "CesiumMan/glTF/CesiumMan.gltf",
    "CesiumMilkTruck/glTF/CesiumMilkTruck.gltf",
    "CornellBox-OBJ/CornellBox-Original.obj",
    "CornellBox-OBJ/CornellBox-Sphere.obj",
    "DamagedHelmet/glTF/DamagedHelmet.gltf",
    "Duck/glTF/Duck.gltf",
    "Fox/glTF/Fox.gltf",
    "Lantern/glTF/Lantern.gltf",
    "LightsPunctualLamp/glTF/LightsPunctualLamp.gltf",
    "MeshPrimitiveModes/glTF/MeshPrimitiveModes.gltf",
    "MetalRoughSpheresNoTextures/glTF/MetalRoughSpheresNoTextures.gltf",
    "MultipleScenes/glTF/MultipleScenes.gltf",
    "OrientationTest/glTF/OrientationTest.gltf",
    "RiggedSimple/glTF/RiggedSimple.gltf",
    "SimpleSparseAccessor/glTF/SimpleSparseAccessor.gltf",
    "StainedGlassLamp/glTF-JPG-PNG/StainedGlassLamp.gltf",
    "StanfordBunny-OBJ/stanford-bunny.obj",
    "Suzanne/glTF/Suzanne.gltf",
    "TextureCoordinateTest/glTF/TextureCoordinateTest.gltf",
    "Triangle/glTF/Triangle.gltf",
    "TriangleWithoutIndices/glTF/TriangleWithoutIndices.gltf",
    "VikingRoom-OBJ/viking_room.obj",
]

# F3D in a fresh interpreter, as a user's one-off command would run it: create the headless
# engine, load, render one frame, write the PNG.
F3D_RENDER = """
import sys, f3d
f3d.Log.set_verbose_level(f3d.Log.VerboseLevel.QUIET)
engine = f3d.Engine.create(True)
engine.window.size = 640, 480
engine.scene.add(sys.argv[1])
engine.window.render_to_image().save(sys.argv[2])
"""

WIDTH, HEIGHT = 640, 480


def timed(command):
    """Wall time of one run of `command` in seconds; raises when it fails."""
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        raise RuntimeError(f"{command[0]} failed: {done.stderr.strip()[-400:]}")
    return elapsed


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--meshtracer", required=True)
    parser.add_argument("--samples", default=os.environ.get("MESHTRACER_SAMPLES"))
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--reference-spp", type=int, default=256)
    parser.add_argument("--no-reference", action="store_true", help="times only")
    parser.add_argument("--only", help="comma-separated folder names")
    parser.add_argument("--out", help="folder for the images (default: a temporary one); "
                        "references already in it are reused")
    parser.add_argument("--extra", default="",
                        help="options added to the default command, to try a candidate default "
                        "(e.g. \"--noise 0.2\")")
    parser.add_argument("--no-f3d", action="store_true", help="meshtracer only (no timing ratio)")
    args = parser.parse_args()
    if not args.samples:
        sys.exit("--samples DIR or MESHTRACER_SAMPLES is needed")
    if not args.no_f3d:
        try:
            import f3d  # noqa: F401  (checked here so a missing F3D fails before any render)
        except ImportError:
            sys.exit("F3D is not installed in this Python: pip install f3d==4.0.0")
    out = args.out or tempfile.mkdtemp(prefix="default-vs-f3d-")
    os.makedirs(out, exist_ok=True)
    models = [m for m in MODELS if not args.only or m.split("/")[0] in args.only.split(",")]

    times = []
    flips = []
    for model in models:
        path = os.path.join(args.samples, model)
        name = os.path.splitext(os.path.basename(model))[0]
        if not os.path.exists(path):
            print(f"{name}: missing, skipped", file=sys.stderr)
            continue
        ours_png = os.path.join(out, f"{name}-default.png")
        ours, theirs = [], []
        for _ in range(args.rounds):
            # Interleaved: F3D, then meshtracer, each round, so a busy moment hits both.
            if not args.no_f3d:
                theirs.append(timed([sys.executable, "-c", F3D_RENDER, path,
                                     os.path.join(out, f"{name}-f3d.png")]))
            ours.append(
                timed([args.meshtracer, "render", path, "-o", ours_png, "--width", str(WIDTH),
                       "--height", str(HEIGHT), "--quiet", "--no-warnings", *args.extra.split()])
            )
        t_ours = statistics.median(ours)
        t_f3d = statistics.median(theirs) if theirs else float("nan")
        times.append((name, t_ours, t_f3d))
        print(f"{name}: meshtracer {t_ours:.2f} s, F3D {t_f3d:.2f} s", file=sys.stderr, flush=True)
        if args.no_reference:
            continue
        reference = os.path.join(out, f"{name}-reference-{args.reference_spp}.png")
        if not os.path.exists(reference):
            subprocess.run(
                [args.meshtracer, "render", path, "-o", reference, "--width", str(WIDTH),
                 "--height", str(HEIGHT), "--spp", str(args.reference_spp), "--seed", "1",
                 "--quiet", "--no-warnings"],
                check=True,
            )
        compared = subprocess.run(
            [args.meshtracer, "compare", reference, ours_png, "--json"],
            check=True, capture_output=True, text=True,
        )
        flips.append((name, json.loads(compared.stdout)["flip"]))

    print("| model | meshtracer default (s) | F3D 4.0 (s) | ratio |")
    print("|---|---:|---:|---:|")
    for name, t_ours, t_f3d in times:
        print(f"| {name} | {t_ours:.2f} | {t_f3d:.2f} | {t_ours / t_f3d:.2f} |")
    if times and not args.no_f3d:
        ratios = [t / f for _, t, f in times]
        print(f"\nmedian ratio {statistics.median(ratios):.2f}, "
              f"{sum(r <= 1.0 for r in ratios)} of {len(ratios)} models at most F3D's time")
    if flips:
        print(f"\n| model | FLIP against {args.reference_spp} spp |")
        print("|---|---:|")
        for name, flip in flips:
            print(f"| {name} | {flip:.4f} |")
        values = [f for _, f in flips]
        print(f"\nmedian {statistics.median(values):.4f}, worst {max(values):.4f}, "
              f"{sum(f <= 0.06 for f in values)} of {len(values)} within 0.06")
    print(f"\nimages in {out}", file=sys.stderr)


if __name__ == "__main__":
    main()
