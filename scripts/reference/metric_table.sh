#!/usr/bin/env bash
# Renders each model with meshtracer, pyrender and Blender (direct light) from the same view and
# prints the metric table (meshtracer vs each reference), meshtracer with the direct integrator
# and the standard encoding as both references light and encode.
#   scripts/reference/metric_table.sh MESHTRACER PYTHON_WITH_PYRENDER SAMPLES_DIR [WIDTH HEIGHT] [-- extra meshtracer render options]
set -euo pipefail
mt="$1"; py="$2"; samples="$3"; width="${4:-320}"; height="${5:-240}"
shift $(( $# < 5 ? $# : 5 )); [ "${1:-}" = "--" ] && shift
here="$(cd "$(dirname "$0")" && pwd)"
work="$(mktemp -d)"
models=(
  Duck/glTF/Duck.gltf
  DamagedHelmet/glTF/DamagedHelmet.gltf
  Suzanne/glTF/Suzanne.gltf
  Avocado/glTF/Avocado.gltf
  BoxTextured/glTF/BoxTextured.gltf
  CesiumMilkTruck/glTF/CesiumMilkTruck.gltf
  VikingRoom-OBJ/viking_room.obj
  LightsPunctualLamp/glTF/LightsPunctualLamp.gltf
  StanfordBunny-OBJ/stanford-bunny.obj
)
echo "| model | vs | PSNR dB | SSIM | FLIP | coverage IoU |"
echo "|---|---|---:|---:|---:|---:|"
for m in "${models[@]}"; do
  name="$(basename "${m%.*}")"
  "$mt" render "$samples/$m" -o "$work/$name-mt.png" --width "$width" --height "$height" --spp 16 --quiet \
    --integrator direct --tonemap standard \
    --view-out "$work/$name.json" "$@"
  PYOPENGL_PLATFORM=osmesa "$py" "$here/pyrender_render.py" "$work/$name.json" "$samples/$m" "$work/$name-pr.png" >/dev/null 2>&1 || true
  if command -v blender >/dev/null; then
    blender -b --factory-startup -P "$here/blender_render.py" -- "$work/$name.json" "$samples/$m" "$work/$name-bl.png" >/dev/null 2>&1 || true
  fi
  for ref in pr bl; do
    [ -f "$work/$name-$ref.png" ] || continue
    label=$([ $ref = pr ] && echo pyrender || echo "Blender direct")
    "$mt" compare "$work/$name-$ref.png" "$work/$name-mt.png" --json | python3 -c "
import json, sys
m = json.load(sys.stdin)
psnr = 'inf' if m['psnr'] is None else f\"{m['psnr']:.2f}\"
print(f\"| $name | $label | {psnr} | {m['ssim']:.4f} | {m['flip']:.4f} | {m['coverage_iou']:.4f} |\")"
  done
done
echo
echo "images in $work"
