#!/usr/bin/env bash
# Seeds fuzz/corpus/{gltf_json,glb,obj} from the shared sample models (small files only) and
# from the files tests/it/broken_files.rs, valid_forms.rs, invalid_forms.rs, instancing.rs and
# materials.rs (anisotropy, specular-glossiness, diffuse transmission, dispersion) and
# poses.rs (KHR_animation_pointer, KHR_node_visibility) generate.
set -euo pipefail
cd "$(dirname "$0")/.."
samples="${MESHTRACER_SAMPLES:-../shared/assets}"
mkdir -p fuzz/corpus/gltf_json fuzz/corpus/glb fuzz/corpus/obj fuzz/corpus/image fuzz/corpus/panorama fuzz/corpus/zip
if [ -d "$samples" ]; then
  find "$samples" -name '*.gltf' -size -200k -exec cp {} fuzz/corpus/gltf_json/ \;
  find "$samples" -name '*.glb' -size -200k -exec cp {} fuzz/corpus/glb/ \;
  # The encoded variants (Draco, meshopt, quantized, WebP, KTX2) under their own names, so
  # that each decoder has seeds that reach it.
  # A .gltf's buffers and images are inlined as data: URIs (the fuzzers load from a folder
  # that does not exist, so external files would stop them before any decoder).
  find "$samples" -path '*glTF-*' \( -name '*.gltf' -o -name '*.glb' \) -size -200k | while read -r f; do
    variant=$(basename "$(dirname "$f")"); model=$(basename "$(dirname "$(dirname "$f")")")
    case "$f" in
      *.glb) cp "$f" "fuzz/corpus/glb/$model-$variant.glb" ;;
      *) python3 - "$f" "fuzz/corpus/gltf_json/$model-$variant.gltf" <<'PY' ;;
import base64, json, os, sys
src, dst = sys.argv[1], sys.argv[2]
doc = json.load(open(src))
total = 0
for item in doc.get("buffers", []) + doc.get("images", []):
    uri = item.get("uri")
    if uri and not uri.startswith("data:"):
        path = os.path.join(os.path.dirname(src), uri)
        data = open(path, "rb").read()
        total += len(data)
        mime = item.get("mimeType", "application/octet-stream")
        item["uri"] = f"data:{mime};base64," + base64.b64encode(data).decode()
if total <= 1 << 20:
    json.dump(doc, open(dst, "w"))
PY
    esac
  done
  find "$samples" -name '*.obj' -size -200k -exec cp {} fuzz/corpus/obj/ \;
  # The image target's seeds: the samples' texture files (the screenshots are PNG and JPEG
  # too), KTX2 with both Basis Universal payloads among them.
  find "$samples" \( -iname '*.png' -o -iname '*.jpg' -o -iname '*.jpeg' -o -iname '*.webp' \
    -o -iname '*.ktx2' \) -size -300k | while read -r f; do
    cp "$f" "fuzz/corpus/image/$(basename "$(dirname "$f")")-$(basename "$f")"
  done
fi
# Small images of every kind the image crate decodes here, if Pillow is at hand: WebP lossy,
# lossless and with alpha, progressive JPEG, PNG with a palette and 16 bits.
python3 - fuzz/corpus/image <<'PY' || echo "no Pillow: the image target is seeded from the samples only"
import io, os, sys
from PIL import Image
out = sys.argv[1]
img = Image.new("RGBA", (13, 7))
img.putdata([(x * 19 % 256, y * 37 % 256, (x * y) % 256, 255 - x) for y in range(7) for x in range(13)])
forms = {
    "lossy.webp": lambda f: img.save(f, "WEBP", quality=50),
    "lossless.webp": lambda f: img.save(f, "WEBP", lossless=True),
    "opaque.webp": lambda f: img.convert("RGB").save(f, "WEBP"),
    "progressive.jpg": lambda f: img.convert("RGB").save(f, "JPEG", progressive=True),
    "grey.jpg": lambda f: img.convert("L").save(f, "JPEG"),
    "palette.png": lambda f: img.convert("P").save(f, "PNG"),
    "grey16.png": lambda f: img.convert("I;16").save(f, "PNG"),
    "interlaced.png": lambda f: img.save(f, "PNG", interlace=1),
}
for name, save in forms.items():
    with open(os.path.join(out, name), "wb") as f:
        save(f)
PY
cp assets/*.gltf fuzz/corpus/gltf_json/
cp assets/*.obj fuzz/corpus/obj/
broken=$(mktemp -d)
MESHTRACER_WRITE_CORPUS="$broken" cargo test -q --test it -- broken_files::every_broken_file valid_forms:: invalid_forms:: \
  instancing:: materials::anisotropy materials::specular_glossiness materials::diffuse_transmission materials::dispersion poses::animation_pointer poses::node_visibility >/dev/null
find "$broken" -name 'model.gltf' -type f | while read -r f; do cp "$f" "fuzz/corpus/gltf_json/$(basename "$(dirname "$f")").gltf"; done
find "$broken" -name 'model.glb' | while read -r f; do cp "$f" "fuzz/corpus/glb/$(basename "$(dirname "$f")").glb"; done
find "$broken" -name 'model.obj' | while read -r f; do cp "$f" "fuzz/corpus/obj/$(basename "$(dirname "$f")").obj"; done
rm -rf "$broken"
# Normal-mapped copies of the textured .gltf seeds, so that MikkTSpace (which the targets run
# after a load, as a render does) meets their meshes: the small samples have no normal map.
python3 - fuzz/corpus/gltf_json <<'PY'
import glob, json, os, sys
for f in sorted(glob.glob(os.path.join(sys.argv[1], "*.gltf"))):
    if f.endswith("-normalmapped.gltf"):
        continue
    try:
        doc = json.load(open(f))
    except (ValueError, UnicodeDecodeError):
        continue
    if not doc.get("textures") or not doc.get("materials"):
        continue
    for m in doc["materials"]:
        m["normalTexture"] = {"index": 0}
    json.dump(doc, open(f[:-5] + "-normalmapped.gltf", "w"))
PY
# The zip target's seeds: the bundled models zipped as downloads are (in a folder, deflated or
# stored, with a macOS resource fork), the Duck with its texture if the samples are here, and
# an archive of two models.
python3 - fuzz/corpus/zip "$samples" <<'PY'
import os, sys, zipfile
out, samples = sys.argv[1], sys.argv[2]
def write(name, files, method=zipfile.ZIP_DEFLATED):
    with zipfile.ZipFile(os.path.join(out, name), "w", method) as z:
        for arcname, path in files:
            z.write(path, arcname)
write("shapes.zip", [("shapes/shapes.obj", "assets/shapes.obj"), ("shapes/shapes.mtl", "assets/shapes.mtl")])
write("box-stored.zip", [("cornell-box.gltf", "assets/cornell-box.gltf")], zipfile.ZIP_STORED)
write("fork.zip", [("m/shapes.obj", "assets/shapes.obj"), ("__MACOSX/m/._shapes.obj", "assets/shapes.mtl")])
write("two.zip", [("a.obj", "assets/shapes.obj"), ("b.gltf", "assets/cornell-box.gltf")])
duck = os.path.join(samples, "Duck", "glTF")
if os.path.isdir(duck):
    write("duck.zip", [("duck/" + f, os.path.join(duck, f)) for f in sorted(os.listdir(duck))])
PY
# The panorama target's seeds: small .hdr and .exr files written by meshtracer itself (its
# encoders: RGBE run-length scanlines, OpenEXR with alpha), and the shared panoramas' headers
# (the first 32 KB of each: a truncated file is a seed too, and a small one).
envs="${MESHTRACER_ENVIRONMENTS:-../shared/environments}"
cargo run -q --release -- render assets/cornell-box.gltf -o fuzz/corpus/panorama/box.hdr \
  --width 24 --height 12 --spp 1 --no-denoise -q
cargo run -q --release -- render assets/cornell-box.gltf -o fuzz/corpus/panorama/box.exr \
  --width 24 --height 12 --spp 1 --no-denoise -q
if [ -d "$envs" ]; then
  for f in "$envs"/*.hdr "$envs"/*.exr; do
    head -c 32768 "$f" > "fuzz/corpus/panorama/$(basename "$f").head"
  done
fi
# Small EXR panoramas in every compression OpenEXR writes (DWAA/DWAB, Blender's default,
# among them), if its Python bindings (PyPI `OpenEXR`) are at hand.
python3 - fuzz/corpus/panorama <<'PY' || echo "no OpenEXR module: the panorama target has no DWA, PIZ or B44 seeds"
import os, sys
import numpy as np
import OpenEXR
y, x = np.mgrid[0:32, 0:64]
rgb = np.stack([np.sin(x / 7.0) + 1.2, np.cos(y / 5.0) + 1.1, (x + y) / 40.0], axis=-1)
for name in ["DWAA", "DWAB", "PIZ", "B44", "B44A", "PXR24", "RLE", "ZIPS", "ZIP"]:
    header = {"compression": getattr(OpenEXR, name + "_COMPRESSION"),
              "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {"RGB": rgb.astype(np.float16)}).write(
        os.path.join(sys.argv[1], name.lower() + ".exr"))
PY
for t in gltf_json glb obj image panorama; do echo "$t: $(ls fuzz/corpus/$t | wc -l) seeds"; done
