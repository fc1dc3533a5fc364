#!/usr/bin/env bash
# Seeds fuzz/corpus/{gltf_json,glb,obj} from the shared sample models (small files only) and
# from the broken-file corpus that tests/broken_files.rs generates.
set -euo pipefail
cd "$(dirname "$0")/.."
samples="${MESHTRACER_SAMPLES:-../shared/assets}"
mkdir -p fuzz/corpus/gltf_json fuzz/corpus/glb fuzz/corpus/obj
if [ -d "$samples" ]; then
  find "$samples" -name '*.gltf' -size -200k -exec cp {} fuzz/corpus/gltf_json/ \;
  find "$samples" -name '*.glb' -size -200k -exec cp {} fuzz/corpus/glb/ \;
  find "$samples" -name '*.obj' -size -200k -exec cp {} fuzz/corpus/obj/ \;
fi
cp assets/*.gltf fuzz/corpus/gltf_json/
cp assets/*.obj fuzz/corpus/obj/
broken=$(mktemp -d)
MESHTRACER_WRITE_CORPUS="$broken" cargo test -q --test broken_files every_broken_file >/dev/null
find "$broken" -name 'model.gltf' -type f | while read -r f; do cp "$f" "fuzz/corpus/gltf_json/$(basename "$(dirname "$f")").gltf"; done
find "$broken" -name 'model.glb' | while read -r f; do cp "$f" "fuzz/corpus/glb/$(basename "$(dirname "$f")").glb"; done
find "$broken" -name 'model.obj' | while read -r f; do cp "$f" "fuzz/corpus/obj/$(basename "$(dirname "$f")").obj"; done
rm -rf "$broken"
for t in gltf_json glb obj; do echo "$t: $(ls fuzz/corpus/$t | wc -l) seeds"; done
