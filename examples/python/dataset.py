#!/usr/bin/env python3
"""A small multi-view dataset of one model: colour, mask, depth and segmentation of many views
into NumPy files, with each view's camera.

    pip install ./python                      # once, from the repository
    python examples/python/dataset.py [MODEL] [OUT_DIR] [--views SPEC] [--size WxH] [--spp N]

MODEL defaults to the bundled Cornell box (assets/cornell-box.gltf), OUT_DIR to
`dataset-out`, SPEC to `sphere:24` (any `render --views` spec: orbit:N, sphere:N, random:N,
cameras, or a views file). The model is loaded and prepared (BVH and all) once; every view is
then rendered from it. OUT_DIR gets:

- `color.npy`: uint8 N x H x W x 4, the 8-bit sRGB pictures (the CLI's PNG bytes);
- `mask.npy`: float32 N x H x W coverage;
- `depth.npy`: float32 N x H x W, metres along each view axis, 0 where nothing was hit;
- `segmentation.npy`: uint32 N x H x W, mesh instance + 1 (0: background);
- `camera_to_world.npy`: float32 N x 4 x 4 (OpenGL camera axes, as transforms.json);
- `intrinsics.npy`: float64 N x 4 (fx, fy, cx, cy in pixels).
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import meshtracer

REPO = Path(__file__).resolve().parents[2]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", nargs="?", default=REPO / "assets" / "cornell-box.gltf")
    parser.add_argument("out", nargs="?", default="dataset-out")
    parser.add_argument("--views", default="sphere:24")
    parser.add_argument("--size", default="256x192")
    parser.add_argument("--spp", type=int, default=16)
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.lower().split("x"))

    scene = meshtracer.load(args.model)
    start = time.perf_counter()

    def progress(done, total):
        print(f"\r{done}/{total} tiles", end="", file=sys.stderr, flush=True)

    views = scene.render_views(args.views, width, height, spp=args.spp, integrator="direct",
                               srgb8=True, aovs=("mask", "depth", "segmentation"),
                               progress=progress)
    print(file=sys.stderr)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for key in ("srgb8", "mask", "depth", "segmentation", "camera_to_world"):
        name = "color" if key == "srgb8" else key
        np.save(out / f"{name}.npy", np.stack([v[key] for v in views]))
    np.save(out / "intrinsics.npy", np.array([v["intrinsics"] for v in views]))
    for warning in scene.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    print(f"{len(views)} views of {args.model} at {width}x{height} in "
          f"{time.perf_counter() - start:.1f} s -> {out}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
