"""meshtracer: a CPU ray tracer for glTF 2.0 and Wavefront OBJ assets, from Python.

    import meshtracer
    scene = meshtracer.load("model.glb")
    out = scene.render(640, 480, spp=16)   # {"color": HxWx4 float32, "depth": HxW, "mask": HxW}

The renderer is the meshtracer library itself (the one the `meshtracer` command runs): the
same model, size and settings give the CLI's picture, bit for bit. docs/python.md has the
details.

``load(path, *, animation=None, time=None, variant=None, strict=False,
allow_external_files=False) -> Scene``
    Loads a .gltf, .glb or .obj file as ``meshtracer render`` does: ``animation`` (name or
    index, as a string or int) and ``time`` (seconds) pose it, ``variant`` picks a
    KHR_materials_variants variant, ``strict`` refuses what the CLI's ``--strict`` refuses.

``Scene.info() -> dict``
    What ``meshtracer info --json`` prints.

``Scene.render(width, height, *, spp=4, integrator="direct", seed=0, bounces=8, exposure=0.0,
camera=None, aovs=("depth", "mask"), srgb8=False, tonemap="standard", noise=None,
clamp_indirect=None) -> dict``
    One view from the file's camera ``camera`` (default its first, else a camera framing the
    model), lit as the CLI lights it. The dict holds "color" (linear RGBA float32, H x W x 4,
    premultiplied by coverage, as the film is before it is written) and the AOVs asked for:
    "depth" (float32 H x W, metres along the view axis, 0 where nothing was hit, as pyrender
    returns it), "mask" (float32 H x W coverage), "normal" (float32 H x W x 3, world space),
    "segmentation" (uint32 H x W, mesh instance + 1, 0 for the background). ``srgb8=True``
    adds "srgb8": uint8 H x W x 4, the bytes of the CLI's PNG through the view transform
    ``tonemap`` (the CLI's ``--tonemap``; "color" stays linear). ``noise`` and
    ``clamp_indirect`` are the CLI's ``--noise`` and ``--clamp-indirect``. The GIL is released while the
    scene is prepared (first render) and rendered.

``Error``
    Raised when a model cannot be loaded or rendered; its message is exactly what the CLI
    prints after ``meshtracer: error:``, naming the file and the part.
"""

from ._meshtracer import Error, Scene
from ._meshtracer import load as _load

__all__ = ["Error", "Scene", "load"]


def load(path, *, animation=None, time=None, variant=None, strict=False,
         allow_external_files=False):
    """Loads a .gltf, .glb or .obj model as ``meshtracer render`` does (see the module docs)."""
    import os

    if animation is not None and not isinstance(animation, str):
        animation = str(int(animation))
    return _load(os.fspath(path), animation=animation,
                 time=None if time is None else float(time), variant=variant,
                 strict=bool(strict), allow_external_files=bool(allow_external_files))
