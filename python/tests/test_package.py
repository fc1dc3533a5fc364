"""The Python package against the CLI it wraps: load errors, info, colour, depth and mask.

Each comparison renders the same model, size and settings through `meshtracer.load(...).render`
and through the `meshtracer render` binary, and wants the same bytes: both run the library's
one pipeline (load, lighting, prepare, render), so any difference is a bug in the binding.
"""

import faulthandler
import functools
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import meshtracer
from conftest import ASSETS, cli_error_message

CORNELL = ASSETS / "cornell-box.gltf"


def read_png_rgba(path):
    from PIL import Image

    with Image.open(path) as image:
        return np.asarray(image.convert("RGBA"))


def srgb8_from_linear(color):
    """8-bit sRGB of a premultiplied linear RGBA film, as docs/outputs.md describes the PNG:
    colour un-premultiplied, clamped to [0, 1], the sRGB curve, rounded; alpha * 255 rounded."""
    rgb = np.divide(color[..., :3], color[..., 3:4], out=np.zeros_like(color[..., :3]),
                    where=color[..., 3:4] > 0)
    rgb = np.clip(rgb, 0.0, 1.0).astype(np.float64)
    srgb = np.where(rgb <= 0.0031308, rgb * 12.92, 1.055 * np.power(rgb, 1 / 2.4) - 0.055)
    alpha = np.clip(color[..., 3:4], 0.0, 1.0).astype(np.float64)
    return np.round(np.concatenate([srgb, alpha], axis=-1) * 255.0).astype(np.uint8)


# Load errors -------------------------------------------------------------------------------

def test_missing_file_raises_error_naming_the_file(cli, tmp_path):
    missing = tmp_path / "no-such-model.gltf"
    with pytest.raises(meshtracer.Error) as caught:
        meshtracer.load(missing)
    assert str(missing) in str(caught.value)
    assert str(caught.value) == cli_error_message(cli("info", missing, check=False))


def test_a_missing_file_is_also_a_file_not_found_error(tmp_path):
    """A missing model, or panorama, is caught by `except FileNotFoundError` (and `OSError`) as
    well as by `except meshtracer.Error`, with the same message; a file that exists but is
    broken is not a FileNotFoundError."""
    missing = tmp_path / "no-such-model.gltf"
    with pytest.raises(FileNotFoundError) as caught:
        meshtracer.load(missing)
    error = caught.value
    assert isinstance(error, meshtracer.Error) and isinstance(error, OSError)
    assert type(error) is meshtracer.MissingFileError
    assert str(error).startswith(f"{missing}: "), str(error)
    scene = meshtracer.load(CORNELL)
    panorama = tmp_path / "no-such-sky.hdr"
    with pytest.raises(FileNotFoundError, match="no-such-sky.hdr") as caught:
        scene.render(8, 8, spp=1, env=panorama)
    assert isinstance(caught.value, meshtracer.Error)
    broken = tmp_path / "broken.gltf"
    broken.write_text("{")
    with pytest.raises(meshtracer.Error) as caught:
        meshtracer.load(broken)
    assert not isinstance(caught.value, OSError)


def textured_triangle_gltf(folder, buffer_uri, image_uri):
    """A glTF of one textured triangle with its buffer in `buffer_uri` (written when it is
    `tri.bin`) and its texture in `image_uri` (written when it is `tex.png`), and its path."""
    import struct

    from PIL import Image

    data = struct.pack("<9f6f", 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 1)
    (folder / "tri.bin").write_bytes(data)
    Image.new("RGB", (2, 2), (200, 30, 30)).save(folder / "tex.png")
    gltf = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1},
                                    "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0}], "images": [{"uri": image_uri}],
        "buffers": [{"byteLength": len(data), "uri": buffer_uri}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                        {"buffer": 0, "byteOffset": 36, "byteLength": 24}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]},
                      {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}],
    }
    path = folder / f"{Path(buffer_uri).stem}-{Path(image_uri).stem}.gltf"
    path.write_text(json.dumps(gltf))
    return path


def test_a_missing_buffer_or_texture_is_a_missing_file_error(cli, tmp_path):
    """A buffer file that is missing, and under strict=True a texture or MTL file, raise
    MissingFileError (so FileNotFoundError too) naming the file, with the CLI's message; a
    missing texture without strict is a warning, as in the CLI."""
    no_buffer = textured_triangle_gltf(tmp_path, "no-such.bin", "tex.png")
    with pytest.raises(meshtracer.MissingFileError) as caught:
        meshtracer.load(no_buffer)
    assert isinstance(caught.value, FileNotFoundError)
    assert "no-such.bin" in str(caught.value), str(caught.value)
    assert str(caught.value) == cli_error_message(cli("info", no_buffer, check=False))

    no_texture = textured_triangle_gltf(tmp_path, "tri.bin", "no-such.png")
    with pytest.raises(meshtracer.MissingFileError) as caught:
        meshtracer.load(no_texture, strict=True)
    assert "no-such.png" in str(caught.value), str(caught.value)
    out = tmp_path / "out.png"
    refused = cli("render", no_texture, "-o", out, "--strict", "-q", check=False)
    assert str(caught.value) == cli_error_message(refused)
    meshtracer.load(no_texture)

    # An OBJ's material library too, under strict=True (else its faces are grey).
    no_mtl = tmp_path / "no-mtl.obj"
    no_mtl.write_text("mtllib no-such.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(meshtracer.MissingFileError) as caught:
        meshtracer.load(no_mtl, strict=True)
    assert "no-such.mtl" in str(caught.value), str(caught.value)
    meshtracer.load(no_mtl)

    # A file that is there but broken stays a plain Error.
    whole = textured_triangle_gltf(tmp_path, "tri.bin", "tex.png")
    (tmp_path / "tri.bin").write_bytes(b"\0" * 8)
    with pytest.raises(meshtracer.Error) as caught:
        meshtracer.load(whole)
    assert not isinstance(caught.value, OSError)


def test_broken_gltf_raises_the_clis_message(cli, tmp_path):
    broken = tmp_path / "broken.gltf"
    broken.write_text('{"asset": {"version": "2.0"}, "meshes": [')
    with pytest.raises(meshtracer.Error) as caught:
        meshtracer.load(broken)
    assert str(broken) in str(caught.value)
    assert str(caught.value) == cli_error_message(cli("info", broken, check=False))


def test_error_is_an_exception_subclass():
    assert issubclass(meshtracer.Error, Exception)


def test_bad_render_arguments_raise_errors():
    scene = meshtracer.load(CORNELL)
    with pytest.raises(meshtracer.Error, match="integrator 'photon'"):
        scene.render(8, 8, integrator="photon")
    with pytest.raises(meshtracer.Error, match="width and height must be at least 1"):
        scene.render(0, 8)
    with pytest.raises(meshtracer.Error, match="camera 5: the file has 1 camera"):
        scene.render(8, 8, camera=5)
    # Negative and too large numbers name the argument and the number, not a bare
    # OverflowError.
    with pytest.raises(meshtracer.Error, match=r"image size -1x8: width and height must be at least 1"):
        scene.render(-1, 8)
    with pytest.raises(meshtracer.Error, match=r"image size 8x4294967296 is 34359738368 pixels, over the limit"):
        scene.render(8, 2**32)
    with pytest.raises(meshtracer.Error, match=r"image size 18446744073709551616x8 is .* pixels, over the limit"):
        scene.render(2**64, 8)
    with pytest.raises(meshtracer.Error, match=r"camera 18446744073709551616: no file has that many cameras"):
        scene.render(8, 8, camera=2**64)
    with pytest.raises(meshtracer.Error, match=r"camera -1: indices count from 0"):
        scene.render(8, 8, camera=-1)
    with pytest.raises(meshtracer.Error, match=r"spp -3: must be a whole number from 0 to 4294967295"):
        scene.render(8, 8, spp=-3)
    with pytest.raises(meshtracer.Error, match=r"seed -1: must be a whole number from 0 to 18446744073709551615"):
        scene.render(8, 8, seed=-1)
    with pytest.raises(meshtracer.Error, match=r"bounces 4294967296: must be a whole number"):
        scene.render(8, 8, bounces=2**32)
    with pytest.raises(meshtracer.Error, match=r"seed:"):
        scene.render(8, 8, seed=1.5)
    with pytest.raises(meshtracer.Error, match="aov 'albedo'"):
        scene.render(8, 8, aovs=("albedo",))
    with pytest.raises(meshtracer.Error, match="--time"):
        meshtracer.load(CORNELL, time=-1)


@pytest.mark.parametrize("call, message", [
    # 200000 x 100000 pixels would be a 320 GB film, which used to end the Python process.
    (lambda s: s.render(200000, 100000, spp=1), "image size 200000x100000 is 20000000000 "
     "pixels, over the limit of 67108864 (raise it with max_pixels)"),
    (lambda s: s.render(4, 2, spp=1, max_pixels=4),
     "image size 4x2 is 8 pixels, over the limit of 4"),
    (lambda s: s.render_views("orbit:2", 10000, 10000, spp=1), "over the limit of 67108864"),
    (lambda s: s.render(8, 8, spp=5000),
     "spp 5000: must be between 1 and 4096 (raise the limit with max_spp)"),
    (lambda s: s.render(8, 8, spp=3, max_spp=2), "spp 3: must be between 1 and 2"),
    # The default render samples adaptively up to 32 a pixel: that is the count checked.
    (lambda s: s.render(8, 8, max_spp=8), "spp 32: must be between 1 and 8"),
    (lambda s: s.render(8, 8, spp=0), "spp 0: must be between 1 and 4096"),
    (lambda s: s.render(8, 8, bounces=1000000), "bounces 1000000: at most"),
])
def test_absurd_sizes_and_counts_are_refused_before_anything_is_allocated(call, message):
    # The CLI's limits (--max-pixels, --max-spp), raised the same way.
    scene = meshtracer.load(CORNELL)
    with pytest.raises(meshtracer.Error) as caught:
        call(scene)
    assert message in str(caught.value)
    assert scene.render(4, 2, spp=1, max_pixels=8)["color"].shape == (2, 4, 4)


# info --------------------------------------------------------------------------------------

def test_info_is_what_info_json_prints(cli):
    scene = meshtracer.load(CORNELL)
    assert scene.info() == json.loads(cli("info", "--json", CORNELL).stdout)


def test_a_file_name_may_be_str_bytes_or_path_like():
    """As Python's own file functions take a name (`open`, `os.stat`): a `str`, `bytes` or an
    `os.PathLike`, all the same file; anything else is a TypeError, as `open` raises."""
    info = meshtracer.load(CORNELL).info()
    assert meshtracer.load(str(CORNELL)).info() == info
    assert meshtracer.load(os.fsencode(CORNELL)).info() == info
    with pytest.raises(TypeError):
        meshtracer.load(3)


def test_a_zip_download_loads_as_its_files_and_is_named_inside(tmp_path):
    import zipfile

    archive = tmp_path / "shapes.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as z:
        for name in ("shapes.obj", "shapes.mtl"):
            z.write(ASSETS / name, f"shapes/{name}")
    zipped, plain = meshtracer.load(archive), meshtracer.load(ASSETS / "shapes.obj")
    info = zipped.info()
    assert info["file"] == str(archive / "shapes" / "shapes.obj")
    assert info["material_list"] == plain.info()["material_list"]
    a, b = zipped.render(32, 24, spp=2), plain.render(32, 24, spp=2)
    np.testing.assert_array_equal(a["color"], b["color"])


# Colour, depth and mask against the CLI's files --------------------------------------------

def render_both(cli, tmp_path, model, width, height, extra_cli=(), **render_options):
    """Renders `model` through the package and the CLI; returns (arrays, the CLI's files)."""
    png, depth, mask = tmp_path / "cli.png", tmp_path / "depth.npy", tmp_path / "mask.npy"
    options = []
    for key, value in render_options.items():
        options += [f"--{key}", value]
    cli("render", model, "-o", png, "--width", width, "--height", height, "--quiet",
        "--depth-out", depth, "--mask-out", mask, *options, *extra_cli)
    arrays = meshtracer.load(model).render(width, height, srgb8=True, **render_options)
    return arrays, {"png": read_png_rgba(png), "depth": np.load(depth), "mask": np.load(mask)}


def test_cornell_box_colour_equals_the_clis_png(cli, tmp_path):
    # The standard (clipping) encoding, so the linear film can be encoded here as the PNG is.
    arrays, files = render_both(cli, tmp_path, CORNELL, 96, 72, spp=4, tonemap="standard")
    color = arrays["color"]
    assert color.dtype == np.float32 and color.shape == (72, 96, 4)
    np.testing.assert_array_equal(arrays["srgb8"], files["png"])
    # The linear film, encoded here as the PNG encoder does: the same bytes but for rounding
    # ties of float32 powers in another library (at most 1 of 255).
    encoded = srgb8_from_linear(color)
    diff = np.abs(encoded.astype(int) - files["png"].astype(int))
    assert diff.max() <= 1, diff.max()
    assert (diff == 0).mean() > 0.999


def test_cornell_box_depth_and_mask_equal_the_clis_npy(cli, tmp_path):
    arrays, files = render_both(cli, tmp_path, CORNELL, 64, 48, spp=1)
    depth = arrays["depth"]
    assert depth.dtype == np.float32 and depth.shape == (48, 64)
    np.testing.assert_array_equal(depth, files["depth"])
    np.testing.assert_array_equal(arrays["mask"], files["mask"])
    assert (depth > 0).any() and (depth >= 0).all()


def test_path_tracer_colour_equals_the_clis_png(cli, tmp_path):
    arrays, files = render_both(cli, tmp_path, CORNELL, 48, 36, spp=2, integrator="path",
                                seed=7)
    np.testing.assert_array_equal(arrays["srgb8"], files["png"])


def test_depth_of_field_equals_the_clis(cli, tmp_path):
    # The thin lens focused at the CLI's default (the scene centre's depth) and at a given
    # distance: the same bytes as --aperture-radius / --focus-distance.
    scene = meshtracer.load(CORNELL)
    for focus in (None, 2.5):
        png = tmp_path / f"dof-{focus}.png"
        extra = () if focus is None else ("--focus-distance", focus)
        cli("render", CORNELL, "-o", png, "--width", 48, "--height", 36, "--quiet", "--spp", 8,
            "--aperture-radius", 0.1, *extra)
        options = {} if focus is None else {"focus_distance": focus}
        arrays = scene.render(48, 36, spp=8, srgb8=True, aperture_radius=0.1, **options)
        np.testing.assert_array_equal(arrays["srgb8"], read_png_rgba(png))
    pinhole = scene.render(48, 36, spp=8, srgb8=True)["srgb8"]
    assert (pinhole != arrays["srgb8"]).any()
    with pytest.raises(meshtracer.Error, match="aperture_radius -1: must be a finite number"):
        scene.render(8, 8, aperture_radius=-1.0)
    with pytest.raises(meshtracer.Error, match="give aperture_radius too"):
        scene.render(8, 8, focus_distance=2.0)
    with pytest.raises(meshtracer.Error, match="not in front of view 0: give focus_distance"):
        # A view file's camera looking away from the scene: no look_at of its own to focus on.
        away = ('[{"camera": {"type": "perspective", "position": [0, 1, 6], "look_at": [0, 1, 7],'
                ' "up": [0, 1, 0], "yfov": 0.8, "aspect": 1.0, "znear": 0.05, "zfar": null}}]')
        scene.render_views("", 8, 8, aperture_radius=0.1, views_json=away)
    # A views file's look_at is where its view focuses: 4 in front of the eye here, where
    # the scene's centre (0, 1, 0) is 6.
    ahead = '[{"look_from": [0, 1, 6], "look_at": [0, 1, 2]}]'
    own = scene.render_views("", 16, 12, spp=8, aperture_radius=0.2, views_json=ahead)
    at = {f: scene.render_views("", 16, 12, spp=8, aperture_radius=0.2, focus_distance=f,
                                views_json=ahead)[0]["color"] for f in (4.0, 6.0)}
    np.testing.assert_array_equal(own[0]["color"], at[4.0])
    assert (own[0]["color"] != at[6.0]).any()


def write_hdr(path, pixels):
    """A Radiance .hdr of float32 H x W x 3 `pixels`, flat RGBE scanlines (W < 8: never
    run-length encoded)."""
    h, w = pixels.shape[:2]
    peak = pixels.max(axis=2)
    mantissa, exponent = np.frexp(peak)
    scale = np.where(peak > 1e-32, mantissa * 256.0 / np.maximum(peak, 1e-32), 0.0)
    rgbe = np.zeros((h, w, 4), np.uint8)
    rgbe[..., :3] = np.clip(pixels * scale[..., None], 0, 255).astype(np.uint8)
    rgbe[..., 3] = np.where(peak > 1e-32, exponent + 128, 0)
    header = f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n".encode()
    path.write_bytes(header + rgbe.tobytes())


def test_env_options_equal_the_clis(cli, tmp_path):
    # A 4 x 2 panorama: a warm bright upper half, a blue dim lower one, one hot spot.
    sky = np.array([[[4.0, 3.0, 2.0]] * 4, [[0.1, 0.2, 0.5]] * 4], np.float32)
    sky[0, 1] = [40.0, 40.0, 40.0]
    hdr = tmp_path / "sky.hdr"
    write_hdr(hdr, sky)
    png = tmp_path / "cli.png"
    model = ASSETS / "shapes.obj"
    cli("render", model, "-o", png, "--width", 48, "--height", 36, "--quiet", "--spp", 2,
        "--integrator", "path", "--env", hdr, "--env-rotation", 90, "--env-intensity", 0.5,
        "--env-visible")
    scene = meshtracer.load(model)
    options = dict(spp=2, integrator="path", srgb8=True, env_rotation=90, env_intensity=0.5,
                   env_visible=True)
    arrays = scene.render(48, 36, env=hdr, **options)
    np.testing.assert_array_equal(arrays["srgb8"], read_png_rgba(png))
    assert (arrays["color"][..., 3] == 1.0).all(), "the visible panorama covers the background"
    # Read once: a second render with the same file and transform uses what was read.
    again = scene.render(48, 36, env=str(hdr), **options)
    np.testing.assert_array_equal(again["srgb8"], arrays["srgb8"])
    # A file name as bytes, as Python's own file functions take one.
    named_in_bytes = scene.render(48, 36, env=os.fsencode(hdr), **options)
    np.testing.assert_array_equal(named_in_bytes["srgb8"], arrays["srgb8"])
    turned = scene.render(48, 36, env=hdr, **{**options, "env_rotation": 180})
    assert not np.array_equal(turned["srgb8"], arrays["srgb8"])
    with pytest.raises(meshtracer.Error, match="env and env_visible light the path tracer"):
        scene.render(8, 8, env=hdr, integrator="direct")
    with pytest.raises(meshtracer.Error, match="env_intensity must be a finite number"):
        scene.render(8, 8, env=hdr, env_intensity=-1.0)
    with pytest.raises(meshtracer.Error, match="missing.hdr"):
        scene.render(8, 8, env=tmp_path / "missing.hdr")


def test_default_render_is_the_clis_denoised_default(cli, tmp_path):
    # No spp, noise or denoise: the CLI's default render, adaptive and denoised, byte for byte.
    arrays, files = render_both(cli, tmp_path, CORNELL, 64, 48)
    np.testing.assert_array_equal(arrays["srgb8"], files["png"])
    assert arrays["stats"]["denoise_seconds"] is not None
    # denoise=False is the CLI's --no-denoise; an explicit spp is not denoised unless asked.
    _, raw_files = render_both(cli, tmp_path, CORNELL, 64, 48, extra_cli=("--no-denoise",))
    raw = meshtracer.load(CORNELL).render(64, 48, srgb8=True, denoise=False)
    np.testing.assert_array_equal(raw["srgb8"], raw_files["png"])
    assert raw["stats"]["denoise_seconds"] is None
    assert not np.array_equal(raw["srgb8"], arrays["srgb8"])
    scene = meshtracer.load(CORNELL)
    assert scene.render(16, 12, spp=2)["stats"]["denoise_seconds"] is None
    assert scene.render(16, 12, spp=2, denoise=True)["stats"]["denoise_seconds"] is not None


@pytest.mark.parametrize("model", ["Box/glTF/Box.gltf", "Avocado/glTF/Avocado.gltf",
                                   "CornellBox-OBJ/CornellBox-Original.obj"])
def test_sample_model_equals_the_cli(cli, samples, tmp_path, model):
    path = samples / model
    if not path.exists():
        pytest.fail(f"{path}: the sample model is missing from MESHTRACER_SAMPLES")
    arrays, files = render_both(cli, tmp_path, path, 80, 60, spp=2)
    np.testing.assert_array_equal(arrays["srgb8"], files["png"])
    np.testing.assert_array_equal(arrays["depth"], files["depth"])
    np.testing.assert_array_equal(arrays["mask"], files["mask"])
    assert (arrays["depth"] > 0).any()


def test_poses_of_one_model_share_its_decoded_textures(samples):
    """A loop over an animation's times loads each pose while the last is still bound: the new
    pose keeps the last one's decoded textures (so does a pose loaded ahead and rendered while
    another pose of the file is alive), and renders exactly as a fresh load does."""
    import gc

    fox = samples / "Fox/glTF/Fox.gltf"
    if not fox.exists():
        pytest.fail(f"{fox}: the sample model is missing from MESHTRACER_SAMPLES")
    kept = []
    scene = None
    for time in (0.5, 1.0, 1.5):
        scene = meshtracer.load(fox, time=time)
        out = scene.render(32, 24, spp=1, aovs=())
        kept.append(out["stats"]["textures_kept"])
    assert kept == [False, True, True]
    del scene, out
    gc.collect()
    # Nothing of the file is alive now: a fresh load decodes, and draws the same pixels.
    fresh = meshtracer.load(fox, time=1.5).render(32, 24, spp=1, aovs=())
    assert fresh["stats"]["textures_kept"] is False
    # Poses loaded ahead: the first rendered decodes, a later one takes its textures then.
    first = meshtracer.load(fox, time=1.0)
    second = meshtracer.load(fox, time=1.5)
    assert first.render(32, 24, spp=1, aovs=())["stats"]["textures_kept"] is False
    again = second.render(32, 24, spp=1, aovs=())
    assert again["stats"]["textures_kept"] is True
    np.testing.assert_array_equal(fresh["color"], again["color"])


# The binding itself ------------------------------------------------------------------------

def test_renders_are_deterministic_and_the_scene_is_reused():
    scene = meshtracer.load(CORNELL)
    first = scene.render(32, 24, spp=2, aovs=("depth", "mask", "normal", "segmentation"))
    second = scene.render(32, 24, spp=2, aovs=("depth", "mask", "normal", "segmentation"))
    for key in ("color", "depth", "mask", "normal", "segmentation"):
        np.testing.assert_array_equal(first[key], second[key])
    assert first["normal"].shape == (24, 32, 3)
    assert first["segmentation"].dtype == np.uint32
    small = scene.render(8, 8, aovs=(), spp=4)
    assert set(small.keys()) == {"color", "stats"}
    assert small["stats"]["primary_rays"] == 8 * 8 * 4
    assert small["stats"]["render_seconds"] > 0


def test_render_releases_the_gil():
    """While one thread renders, another runs Python: its longest wait is a small part of the
    render (holding the GIL, the render would stall it throughout)."""
    scene = meshtracer.load(CORNELL)
    scene.render(8, 8)  # prepared here, so that the timed call only renders
    done = threading.Event()
    timing = {}

    def work():
        start = time.perf_counter()
        scene.render(160, 120, spp=16)
        timing["render"] = time.perf_counter() - start
        done.set()

    thread = threading.Thread(target=work)
    last, longest = time.perf_counter(), 0.0
    thread.start()
    while not done.is_set():
        now = time.perf_counter()
        longest, last = max(longest, now - last), now
        sum(range(100))
    thread.join()
    assert timing["render"] > 0.05, "the render is too short to tell"
    assert longest < 0.5 * timing["render"], (longest, timing["render"])


# Threads ------------------------------------------------------------------------------------

# Set in the interpreter that `in_own_interpreter` starts: the test runs there, not again.
CHILD_VARIABLE = "MESHTRACER_TEST_IN_CHILD"


def in_own_interpreter(timeout):
    """Runs the decorated test (it takes no fixtures) in a Python of its own, which fails it
    after `timeout` seconds: a thread that waits while it holds the GIL (the deadlock these
    tests guard against) freezes every thread of its interpreter, the one that would time it
    out included (`Thread.join(timeout)` needs the GIL to return), so only another process can.
    In the child, faulthandler's watchdog (a C thread, without the GIL) prints every thread's
    stack and exits; the parent's own limit is for a child that does not even get that far."""
    def decorate(test):
        @functools.wraps(test)
        def run():
            if os.environ.get(CHILD_VARIABLE):
                faulthandler.dump_traceback_later(timeout, exit=True)
                try:
                    return test()
                finally:
                    faulthandler.cancel_dump_traceback_later()
            code = f"import test_package; test_package.{test.__name__}()"
            env = dict(os.environ, **{CHILD_VARIABLE: "1"})
            try:
                child = subprocess.run([sys.executable, "-c", code], cwd=Path(__file__).parent,
                                       env=env, capture_output=True, text=True,
                                       timeout=timeout + 30)
            except subprocess.TimeoutExpired as e:
                pytest.fail(f"{test.__name__}: still running after {timeout + 30} s and killed "
                            f"(a deadlock?)\n{e.stderr or ''}")
            if child.returncode != 0:
                frozen = "Timeout (" in child.stderr
                why = f"still running after {timeout} s: a deadlock" if frozen else "failed"
                pytest.fail(f"{test.__name__} {why}\n{child.stdout}{child.stderr}")
        return run
    return decorate


def run_in_threads(calls, timeout=60.0):
    """Runs each of `calls` on a daemon thread of its own, all at once; returns their results
    (an exception raised is returned as it is). Fails if any is still running after `timeout`
    seconds, a thread that waits with the GIL released; one that waits holding the GIL freezes
    this one too, which `in_own_interpreter` is for."""
    results = [None] * len(calls)

    def run(i, call):
        try:
            results[i] = call()
        except Exception as e:  # returned, for the test to look at
            results[i] = e

    threads = [threading.Thread(target=run, args=(i, c), daemon=True) for i, c in enumerate(calls)]
    for t in threads:
        t.start()
    deadline = time.monotonic() + timeout
    for t in threads:
        t.join(max(0.0, deadline - time.monotonic()))
    assert not any(t.is_alive() for t in threads), f"still running after {timeout} s: a deadlock"
    return results


def grid_scene(n):
    """A wavy grid of 2·n² triangles from arrays: its preparation takes long enough (a BVH of
    320000 triangles at n = 400) for other threads to call while it runs."""
    u, v = np.meshgrid(np.linspace(-1, 1, n + 1), np.linspace(-1, 1, n + 1))
    positions = np.stack([u, v, 0.1 * np.sin(7 * u) * np.cos(5 * v)], axis=-1).reshape(-1, 3)
    corner = (np.arange(n)[None, :] + (n + 1) * np.arange(n)[:, None]).ravel()
    indices = np.concatenate([np.stack([corner, corner + 1, corner + n + 2], 1),
                              np.stack([corner, corner + n + 2, corner + n + 1], 1)])
    scene = meshtracer.Scene.from_arrays(positions, indices)
    scene.add_camera(np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 3], [0, 0, 0, 1]]), yfov=0.8)
    return scene


@in_own_interpreter(timeout=90.0)
def test_threads_rendering_one_scene_share_its_one_preparation():
    """Two renders and the scene's other calls from other threads while the first render
    prepares the scene: all finish (the preparation once held the scene's lock while it
    waited for the GIL, and the interpreter froze), and the renders are one picture."""
    scene = grid_scene(400)
    render = lambda: scene.render(64, 48, spp=1, integrator="direct", seed=3)  # noqa: E731
    results = run_in_threads([render, render, scene.info, lambda: repr(scene),
                              lambda: scene.warnings, render])
    renders = [results[i] for i in (0, 1, 5)]
    for r in results:
        assert not isinstance(r, Exception), r
    for r in renders[1:]:
        assert np.array_equal(r["color"], renders[0]["color"])
    assert results[2] == scene.info()


def broken_texture_gltf(folder):
    """A glTF of one textured triangle whose PNG ends after its header: the load (which reads
    the header) takes it, the preparation cannot decode it."""
    import base64
    import io
    import struct

    from PIL import Image

    data = struct.pack("<9f6f3H", 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 1, 2) + b"\0\0"
    gltf = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1},
                                    "indices": 2, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0}], "images": [{"uri": "broken.png"}],
        "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64,"
                     + base64.b64encode(data).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                        {"buffer": 0, "byteOffset": 36, "byteLength": 24},
                        {"buffer": 0, "byteOffset": 60, "byteLength": 6}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]},
                      {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"},
                      {"bufferView": 2, "componentType": 5123, "count": 3, "type": "SCALAR"}],
    }
    png = io.BytesIO()
    Image.fromarray(np.arange(64 * 64 * 3, dtype=np.uint8).reshape(64, 64, 3)).save(png, "PNG")
    (folder / "broken.png").write_bytes(png.getvalue()[:60])
    path = folder / "broken.gltf"
    path.write_text(json.dumps(gltf))
    return path


@in_own_interpreter(timeout=90.0)
def test_threads_waiting_for_a_failed_preparation_get_its_error():
    """A strict load of a file whose texture cannot be decoded: its preparation fails. Every
    thread that rendered meanwhile gets an error with the preparation's message, none hangs,
    and later calls say the scene must be loaded again."""
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        scene = meshtracer.load(broken_texture_gltf(Path(folder)), strict=True)
        render = lambda: scene.render(16, 16, spp=1, integrator="direct")  # noqa: E731
        results = run_in_threads([render, render, render])
    assert all(isinstance(r, meshtracer.Error) for r in results), results
    first = min((str(r) for r in results), key=len)
    assert "broken.png" in first
    for r in results:
        assert first in str(r)
    with pytest.raises(meshtracer.Error, match="an earlier preparation of this scene failed: load it again"):
        scene.render(16, 16, spp=1)


@in_own_interpreter(timeout=90.0)
def test_threads_prepare_a_scene_once():
    """The texture's warning of the non-strict load appears once however many threads
    rendered the scene at the same time: it was prepared once."""
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        scene = meshtracer.load(broken_texture_gltf(Path(folder)))
        render = lambda: scene.render(16, 16, spp=1, integrator="direct")  # noqa: E731
        results = run_in_threads([render] * 4)
    assert not any(isinstance(r, Exception) for r in results), results
    assert len([w for w in scene.warnings if "broken.png" in w]) == 1, scene.warnings


def test_a_render_too_large_for_memory_raises_memory_error_naming_its_size():
    """Over a raised max_pixels, a film that cannot be allocated is a MemoryError naming the
    size (it was an abort of the Python process: "memory allocation of ... bytes failed")."""
    scene = meshtracer.load(CORNELL)
    with pytest.raises(MemoryError, match=r"image size 200000x200000: .* GiB"):
        scene.render(200000, 200000, spp=1, max_pixels=2**62)
    with pytest.raises(MemoryError, match=r"3 views of 200000x100000"):
        scene.render_views("orbit:3", 200000, 100000, spp=1, max_pixels=2**62)
    assert scene.render(8, 8, spp=1)["color"].shape == (8, 8, 4)


def test_spp_none_is_the_default_sampling():
    scene = meshtracer.load(CORNELL)
    given = scene.render(32, 24, spp=None)
    default = scene.render(32, 24)
    assert np.array_equal(given["color"], default["color"])
    assert given["stats"]["denoise_seconds"] is not None, "the default render is denoised"
