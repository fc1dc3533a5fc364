#!/usr/bin/env bash
# The SHA-256 of a fixed set of outputs, one line each: for changes meant to keep behaviour
# byte for byte (a restructuring, a refactor). Run it before and after and diff the two lists.
#
#   scripts/dev/output-hashes.sh [BINARY] > hashes.txt
#
# BINARY defaults to target/release/meshtracer. Models from $MESHTRACER_SAMPLES are used when it
# is set (else ../shared/assets if present); without them only the bundled scenes are hashed.
set -euo pipefail
repo="$(cd "$(dirname "$0")/../.." && pwd)"
bin="${1:-$repo/target/release/meshtracer}"
bin="$(cd "$(dirname "$bin")" && pwd)/$(basename "$bin")"
samples="${MESHTRACER_SAMPLES:-$repo/../shared/assets}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
box="$repo/assets/cornell-box.gltf"
q=(--quiet)

# The bundled scene with both integrators (small sizes: the hashes are the point, not the time).
"$bin" render "$box" -o direct.png --width 256 --height 192 "${q[@]}"
"$bin" render "$box" -o path.png --width 160 --height 120 --spp 16 --integrator path "${q[@]}"
"$bin" render "$box" -o aovs.png --width 128 --height 96 --depth-out depth.npy \
  --normal-out normal.exr --mask-out mask.png --segmentation-out seg.png --view-out view.json "${q[@]}"
# Many views with transforms.json.
"$bin" render "$box" --views orbit:4 -o views/ --width 96 --height 72 "${q[@]}"
# A tiled render merged.
for i in 0 1 2; do
  "$bin" render "$box" -o "tile-$i.png" --width 128 --height 96 --spp 4 --integrator path \
    --tile "$i/3" --depth-out "tile-$i.depth.png" "${q[@]}"
done
"$bin" merge -o merged.png --depth-out merged.depth.png tile-0.png tile-1.png tile-2.png "${q[@]}"
# info --json of three models (two bundled, one sample when present).
for m in "$repo"/assets/*.gltf "$repo"/assets/*.obj; do
  [ -f "$m" ] && "$bin" info "$m" --json > "info-$(basename "$m").json"
done
if [ -f "$samples/DamagedHelmet/glTF/DamagedHelmet.gltf" ]; then
  "$bin" info "$samples/DamagedHelmet/glTF/DamagedHelmet.gltf" --json > info-helmet.json
  "$bin" info "$samples/Duck/glTF-Draco/Duck.gltf" --json > info-duck-draco.json
  "$bin" render "$samples/DamagedHelmet/glTF/DamagedHelmet.gltf" -o helmet-path.png --width 96 --height 96 --spp 4 --integrator path "${q[@]}"
  "$bin" render "$samples/DamagedHelmet/glTF/DamagedHelmet.gltf" -o helmet.png --width 96 --height 96 "${q[@]}"
fi
# One batch's results.jsonl without timings (the "seconds" of each record).
mkdir batch-in
cp "$box" batch-in/
printf '{"id":"box","model":"cornell-box.gltf"}\n{"id":"orbit","model":"cornell-box.gltf","views":"orbit:2","width":64,"height":48}\n{"id":"bad","model":"missing.gltf"}\n' > batch-in/jobs.jsonl
"$bin" batch batch-in/jobs.jsonl -o batch-out/ --width 80 --height 60 "${q[@]}" || true
for f in batch-out/results.jsonl batch-out/*/job.json; do
  python3 -c 'import json, sys
text = open(sys.argv[1]).read()
docs = [json.loads(l) for l in text.splitlines() if l.strip()] if sys.argv[1].endswith("l") else [json.loads(text)]
for d in docs:
    d.pop("seconds", None)
    print(json.dumps(d))' "$f" > "$f.no-timings"
  rm "$f"
done
find . -type f ! -path './batch-in/*' | LC_ALL=C sort | xargs sha256sum
