#!/usr/bin/env bash
# Renders each shared model with meshtracer's path tracer and with Blender Cycles from the same
# view file and panorama, and prints the per-model table: covered FLIP, coverage IoU and the
# mean luminance ratio (meshtracer / Cycles). docs/cycles.md has the table and how to read it.
#
#   scripts/reference/cycles_table.sh MESHTRACER BPY_PYTHON SAMPLES_DIR ENV.hdr [WIDTH HEIGHT SPP] [OUT_DIR]
#
# BPY_PYTHON is a Python with `bpy` (Blender 5.2 as a module), numpy and Pillow
# (scripts/reference/README.md). Renders run one at a time; Cycles' denoiser is off.
# MODELS="Duck/glTF/Duck.gltf ..." renders only those (paths under SAMPLES_DIR).
set -euo pipefail
mt="$1"; py="$2"; samples="$3"; env="$4"
width="${5:-320}"; height="${6:-240}"; spp="${7:-256}"
work="${8:-$(mktemp -d)}"
mkdir -p "$work"
here="$(cd "$(dirname "$0")" && pwd)"
models=(
  Avocado/glTF/Avocado.gltf
  BoxTextured/glTF/BoxTextured.gltf
  Box/glTF/Box.gltf
  BoxInterleaved/glTF/BoxInterleaved.gltf
  CesiumMilkTruck/glTF/CesiumMilkTruck.gltf
  CornellBox-OBJ/CornellBox-Original.obj
  CornellBox-OBJ/CornellBox-Sphere.obj
  DamagedHelmet/glTF/DamagedHelmet.gltf
  Duck/glTF/Duck.gltf
  Lantern/glTF/Lantern.gltf
  LightsPunctualLamp/glTF/LightsPunctualLamp.gltf
  MetalRoughSpheresNoTextures/glTF/MetalRoughSpheresNoTextures.gltf
  OrientationTest/glTF/OrientationTest.gltf
  StanfordBunny-OBJ/stanford-bunny.obj
  Suzanne/glTF/Suzanne.gltf
  TextureCoordinateTest/glTF/TextureCoordinateTest.gltf
  VikingRoom-OBJ/viking_room.obj
)
[ -n "${MODELS:-}" ] && read -r -a models <<<"$MODELS"
echo "| model | covered FLIP | coverage IoU | mean luminance ours/Cycles |"
echo "|---|---:|---:|---:|"
for m in "${models[@]}"; do
  [ -f "$samples/$m" ] || { echo "| $(basename "${m%.*}") | missing | | |"; continue; }
  name="$(basename "${m%.*}")"
  # The camera is meshtracer's framing of the model, written to the view file that Cycles reads.
  "$mt" render "$samples/$m" -o "$work/$name-mt.png" --width "$width" --height "$height" \
    --spp "$spp" --integrator path --bounces 8 --tonemap standard --seed 1 \
    --env "$env" --view-out "$work/$name.json" --quiet 2>"$work/$name-mt.log"
  "$py" "$here/blender_render.py" -- "$work/$name.json" "$samples/$m" "$work/$name-bl.png" \
    --samples "$spp" >"$work/$name-bl.log" 2>&1
  "$mt" compare "$work/$name-bl.png" "$work/$name-mt.png" --json \
    --side-by-side "$work/$name-strip.png" >"$work/$name-compare.json"
  "$py" "$here/covered_metrics.py" "$work/$name-bl.png" "$work/$name-mt.png" \
    "$work/$name-compare.json" "$name"
done
echo
echo "images in $work"
