#!/usr/bin/env python3
"""Render MODEL with pyrender from a meshtracer view file, for comparison with meshtracer.

    PYOPENGL_PLATFORM=osmesa python pyrender_render.py VIEW.json MODEL OUT.png [--depth-out D.npy]

The camera, lights and ambient term come from VIEW.json (written by `meshtracer render
--view-out`), so both renderers see the same view. Units: pyrender uses light intensities as
given (point/spot: I/d^2, directional: irradiance), which is exactly glTF's candela and lux, so
no conversion is needed. Differences that remain are listed in this folder's README.
"""
import argparse
import json
import os
import sys

os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")

import numpy as np  # noqa: E402
import pyrender  # noqa: E402
import trimesh  # noqa: E402
from PIL import Image  # noqa: E402


def camera_pose(cam):
    """4x4 world-from-camera matrix: the camera looks down its local -Z with +Y up."""
    eye = np.array(cam["position"], dtype=np.float64)
    forward = np.array(cam["look_at"], dtype=np.float64) - eye
    forward /= np.linalg.norm(forward)
    up = np.array(cam["up"], dtype=np.float64)
    w = -forward
    u = np.cross(up, w)
    u /= np.linalg.norm(u)
    v = np.cross(w, u)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = u, v, w, eye
    return pose


def light_pose(light):
    """Pose whose local -Z is the light's travel direction, at its position."""
    d = np.array(light["direction"], dtype=np.float64)
    d /= np.linalg.norm(d)
    w = -d
    helper = np.array([0.0, 1.0, 0.0]) if abs(w[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(helper, w)
    u /= np.linalg.norm(u)
    v = np.cross(w, u)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = u, v, w, light["position"]
    return pose


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("view")
    parser.add_argument("model")
    parser.add_argument("out")
    parser.add_argument("--depth-out", help="camera-space depth as float32 .npy (0 = no hit)")
    args = parser.parse_args()

    with open(args.view) as f:
        view = json.load(f)
    width, height = view["image"]["width"], view["image"]["height"]
    loaded = trimesh.load(args.model, force="scene")
    scene = pyrender.Scene.from_trimesh_scene(
        loaded, bg_color=[0, 0, 0, 0], ambient_light=view.get("ambient", [0, 0, 0])
    )

    cam = view["camera"]
    if cam.get("aperture_radius"):
        print("warning: pyrender has no depth of field: the view's thin lens is rendered as "
              "a pinhole", file=sys.stderr)
    zfar = cam.get("zfar")
    if cam["type"] == "perspective":
        camera = pyrender.PerspectiveCamera(
            yfov=cam["yfov"], aspectRatio=cam["aspect"], znear=cam["znear"], zfar=zfar
        )
    else:
        camera = pyrender.OrthographicCamera(
            xmag=cam["xmag"], ymag=cam["ymag"], znear=cam["znear"], zfar=zfar or 1e6
        )
    scene.add(camera, pose=camera_pose(cam))

    for light in view["lights"]:
        color = light["color"]
        intensity = light["intensity"]
        if light["type"] == "point":
            node = pyrender.PointLight(color=color, intensity=intensity)
        elif light["type"] == "spot":
            node = pyrender.SpotLight(
                color=color,
                intensity=intensity,
                innerConeAngle=light.get("inner_cone_angle", 0.0),
                outerConeAngle=light.get("outer_cone_angle", np.pi / 4),
            )
        else:
            node = pyrender.DirectionalLight(color=color, intensity=intensity)
        scene.add(node, pose=light_pose(light))

    renderer = pyrender.OffscreenRenderer(width, height)
    # SHADOWS_ALL fails on Mesa and pyrender has no point-light shadows (REFERENCES.md).
    flags = pyrender.RenderFlags.RGBA | pyrender.RenderFlags.SHADOWS_DIRECTIONAL | pyrender.RenderFlags.SHADOWS_SPOT
    color, depth = renderer.render(scene, flags=flags)
    renderer.delete()
    # Depending on the platform pyrender returns RGB even with the RGBA flag: take coverage
    # from depth (0 where nothing was hit), as meshtracer's alpha.
    rgba = np.zeros((height, width, 4), dtype=np.uint8)
    rgba[..., :3] = color[..., :3]
    rgba[..., 3] = np.where(depth > 0, 255, 0)
    Image.fromarray(rgba).save(args.out)
    if args.depth_out:
        np.save(args.depth_out, depth.astype(np.float32))
    return 0


if __name__ == "__main__":
    sys.exit(main())
