"""Writes a glTF of three UV spheres with KHR_materials_iridescence (docs/cycles.md).

    python iridescent_spheres.py OUT.gltf [bare]

`bare` writes the same spheres without the films.
"""
import base64
import json
import math
import struct
import sys

def sphere(n_lat=48, n_lon=96):
    pos, nor, idx = [], [], []
    for i in range(n_lat + 1):
        th = math.pi * i / n_lat
        for j in range(n_lon + 1):
            ph = 2 * math.pi * j / n_lon
            v = (math.sin(th) * math.cos(ph), math.cos(th), math.sin(th) * math.sin(ph))
            pos.append(v); nor.append(v)
    for i in range(n_lat):
        for j in range(n_lon):
            a = i * (n_lon + 1) + j; b = a + n_lon + 1
            # At the poles one triangle of each quad has two corners on the pole: leave it out
            # (the renderer would drop it as degenerate, with a warning).
            if i > 0:
                idx += [a, a + 1, b]
            if i < n_lat - 1:
                idx += [a + 1, b + 1, b]
    return pos, nor, idx

pos, nor, idx = sphere()
blob = b"".join(struct.pack("<3f", *p) for p in pos) + b"".join(struct.pack("<3f", *n) for n in nor)
off_idx = len(blob)
blob += b"".join(struct.pack("<I", i) for i in idx)
materials = [
    {"name": "film-dark-dielectric", "pbrMetallicRoughness": {"baseColorFactor": [0.05, 0.05, 0.05, 1], "metallicFactor": 0.0, "roughnessFactor": 0.15},
     "extensions": {"KHR_materials_iridescence": {"iridescenceFactor": 1.0, "iridescenceIor": 1.3, "iridescenceThicknessMaximum": 400}}},
    {"name": "film-white-metal", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.9, 0.9, 1], "metallicFactor": 1.0, "roughnessFactor": 0.3},
     "extensions": {"KHR_materials_iridescence": {"iridescenceFactor": 1.0, "iridescenceIor": 1.3, "iridescenceThicknessMaximum": 400}}},
    {"name": "film-grey-dielectric", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0.0, "roughnessFactor": 0.4},
     "extensions": {"KHR_materials_iridescence": {"iridescenceFactor": 1.0, "iridescenceIor": 1.8, "iridescenceThicknessMaximum": 250}}},
]
if len(sys.argv) > 2 and sys.argv[2] == "bare":
    for m in materials: m.pop("extensions")
gltf = {
    "asset": {"version": "2.0"},
    "extensionsUsed": [] if (len(sys.argv) > 2 and sys.argv[2] == "bare") else ["KHR_materials_iridescence"],
    "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 12 * len(pos)},
                    {"buffer": 0, "byteOffset": 12 * len(pos), "byteLength": 12 * len(pos)},
                    {"buffer": 0, "byteOffset": off_idx, "byteLength": 4 * len(idx)}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(pos), "type": "VEC3", "min": [-1, -1, -1], "max": [1, 1, 1]},
                  {"bufferView": 1, "componentType": 5126, "count": len(pos), "type": "VEC3"},
                  {"bufferView": 2, "componentType": 5125, "count": len(idx), "type": "SCALAR"}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": k}]} for k in range(3)],
    "materials": materials,
    "nodes": [{"mesh": k, "translation": [2.2 * (k - 1), 0, 0]} for k in range(3)],
    "scenes": [{"nodes": [0, 1, 2]}], "scene": 0,
}
json.dump(gltf, open(sys.argv[1], "w"))
