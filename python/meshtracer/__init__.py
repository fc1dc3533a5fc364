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

``Scene.render(width, height, *, spp=None, integrator="path", seed=0, bounces=8, exposure=0.0,
camera=None, aovs=("depth", "mask"), srgb8=False, tonemap="khronos-pbr-neutral", noise=None,
clamp_indirect=None, denoise=None) -> dict``
    One view from the file's camera ``camera`` (default its first, else a camera framing the
    model), lit as the CLI lights it. The dict holds "color" (linear RGBA float32, H x W x 4,
    premultiplied by coverage, as the film is before it is written) and the AOVs asked for:
    "depth" (float32 H x W, metres along the view axis, 0 where nothing was hit, as pyrender
    returns it), "mask" (float32 H x W coverage), "normal" (float32 H x W x 3, world space),
    "segmentation" (uint32 H x W, mesh instance + 1, 0 for the background). ``srgb8=True``
    adds "srgb8": uint8 H x W x 4, the bytes of the CLI's PNG through the view transform
    ``tonemap`` (the CLI's ``--tonemap``; "color" stays linear). ``noise`` and
    ``clamp_indirect`` are the CLI's ``--noise`` and ``--clamp-indirect``. Without ``spp`` or
    ``noise`` the render is the CLI's default one, adaptive and denoised by the built-in
    filter; ``denoise=False`` or ``True`` is the CLI's ``--no-denoise`` or ``--denoise``. The
    GIL is released while the scene is prepared (first render) and rendered.

``Scene.render(..., ambient=None, default_lights=True, env=None, env_rotation=0.0,
env_intensity=1.0, env_visible=False, progress=None)``
    ``ambient`` and ``default_lights=False`` are the CLI's ``--ambient`` and
    ``--no-default-lights``; ``env`` (the path of an .exr or .hdr panorama), ``env_rotation``
    (degrees), ``env_intensity`` and ``env_visible`` the path tracer's ``--env`` options (read
    once and kept while the file and transform stay the same); ``aperture_radius`` and
    ``focus_distance`` are ``--aperture-radius`` and ``--focus-distance`` (depth of field
    through a thin lens, in scene units); ``progress(done, total)`` is called on this thread as tiles finish,
    and an exception it raises, or Ctrl-C, cancels the render and propagates. Any other keyword
    raises Error.

``Scene.from_arrays(positions, indices, ...)``, ``Scene.add_mesh``, ``Scene.add_texture``,
``Scene.add_camera``, ``Scene.add_light``, ``Scene.render_views(spec, width, height, ...)``
    Scenes built from NumPy arrays and many views after one preparation: see each method's
    docstring and docs/python.md. ``meshtracer.pyrender`` renders a ``pyrender.Scene``.

``Error``
    Raised when a model cannot be loaded or rendered; its message is exactly what the CLI
    prints after ``meshtracer: error:``, naming the file and the part.

``MissingFileError``
    The ``Error`` raised when a file does not exist: the model, a buffer or (with
    ``strict=True``) a texture it refers to, or the ``env`` panorama. It is
    also a ``FileNotFoundError``, so ``except FileNotFoundError`` and ``except OSError`` catch
    it as well as ``except meshtracer.Error``.
"""

import numpy as _np

from ._meshtracer import Error, MissingFileError, Scene
from ._meshtracer import load as _load

__all__ = ["Error", "MissingFileError", "Scene", "load"]


def load(path, *, animation=None, time=None, variant=None, strict=False,
         allow_external_files=False):
    """Loads a .gltf, .glb or .obj model as ``meshtracer render`` does (see the module docs)."""
    import os

    if animation is not None and not isinstance(animation, str):
        animation = str(int(animation))
    # os.fsdecode: str, bytes or os.PathLike, as Python's own file functions take a name.
    return _load(os.fsdecode(path), animation=animation,
                 time=None if time is None else float(time), variant=variant,
                 strict=bool(strict), allow_external_files=bool(allow_external_files))


def _rows(name, values, width):
    """``values`` as a C-contiguous float32 N x ``width`` array, or an Error naming ``name``."""
    try:
        array = _np.asarray(values, dtype=_np.float32)
    except (TypeError, ValueError) as e:
        raise Error(f"{name}: not an array of numbers ({e})") from None
    if array.ndim != 2 or array.shape[1] != width:
        raise Error(f"{name}: shape {array.shape}, expected (N, {width})")
    return _np.ascontiguousarray(array)


def _triangles(indices):
    """``indices`` as a C-contiguous uint32 M x 3 array, or an Error."""
    array = _np.asarray(indices)
    if array.dtype.kind not in "iu":
        if array.dtype.kind == "f" and array.size and _np.all(_np.mod(array, 1) == 0):
            array = array.astype(_np.int64)
        else:
            raise Error(f"indices: dtype {array.dtype}, expected integers")
    if array.ndim != 2 or array.shape[1] != 3:
        raise Error(f"indices: shape {array.shape}, expected (M, 3): three vertices a triangle")
    if array.size and array.min() < 0:
        t = int(_np.argwhere(array < 0)[0][0])
        raise Error(f"indices: triangle {t} has a negative index ({array[t].tolist()})")
    if array.size and array.max() > 0xFFFFFFFF:
        raise Error("indices: an index beyond 2**32 - 1")
    return _np.ascontiguousarray(array, dtype=_np.uint32)


def _pose(pose):
    """A 4x4 pose (world from local, rows as NumPy prints it) as 16 floats in rows."""
    if pose is None:
        return None
    array = _np.asarray(pose, dtype=_np.float64)
    if array.shape != (4, 4):
        raise Error(f"pose: shape {array.shape}, expected (4, 4)")
    # An affine transform's last row is exactly [0, 0, 0, 1]; the renderer applies the upper
    # three rows alone, so any other row (a projective matrix, or one transposed) would be
    # dropped without a word. Rounding from float64 products is allowed for.
    bottom = array[3]
    if not _np.isfinite(array).all():
        raise Error("pose: not finite (NaN or infinite entries)")
    if _np.abs(bottom - [0.0, 0.0, 0.0, 1.0]).max() > 1e-6:
        row = ", ".join(f"{v:g}" for v in bottom)
        raise Error(f"pose: last row [{row}], expected [0, 0, 0, 1]: a pose is an affine "
                    "4x4 world-from-local matrix, rows as NumPy prints it (transposed?)")
    return [float(v) for v in array.ravel()]


_TEXTURE_SLOTS = ("base_color_texture", "metallic_roughness_texture", "normal_texture",
                  "occlusion_texture", "emissive_texture",
                  # The material extensions' (glTF's names in snake case).
                  "transmission_texture", "thickness_texture", "specular_texture",
                  "specular_color_texture", "sheen_color_texture", "sheen_roughness_texture",
                  "clearcoat_texture", "clearcoat_roughness_texture",
                  "clearcoat_normal_texture", "iridescence_texture",
                  "iridescence_thickness_texture", "anisotropy_texture",
                  "diffuse_transmission_texture", "diffuse_transmission_color_texture")


def _rgba8(image):
    """``image`` (H x W or H x W x C with C 1 to 4: grey, grey and alpha, RGB, RGBA; uint8
    0-255 or floats 0-1; or a PIL image) as a C-contiguous uint8 H x W x 4 array."""
    if not isinstance(image, _np.ndarray) and hasattr(image, "convert"):  # a PIL image
        image = image.convert("RGBA")
    try:
        a = _np.asarray(image)
    except (TypeError, ValueError) as e:
        raise Error(f"texture: not an image array ({e})") from None
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or not 1 <= a.shape[2] <= 4:
        raise Error(f"texture: shape {a.shape}, expected (H, W) or (H, W, C) with C from 1 to 4")
    if a.dtype.kind == "f":
        if a.size and not (_np.all(_np.isfinite(a)) and a.min() >= 0.0 and a.max() <= 1.0):
            raise Error("texture: float values must be finite and from 0 to 1 "
                        "(or give uint8 values from 0 to 255)")
        a = _np.rint(a * 255.0).astype(_np.uint8)
    elif a.dtype.kind in "iu":
        if a.size and (a.min() < 0 or a.max() > 255):
            raise Error("texture: integer values must be from 0 to 255")
        a = a.astype(_np.uint8)
    elif a.dtype.kind == "b":
        a = a.astype(_np.uint8) * 255
    else:
        raise Error(f"texture: dtype {a.dtype}, expected uint8 or floats")
    opaque = _np.full(a.shape[:2] + (1,), 255, _np.uint8)
    if a.shape[2] == 1:
        a = _np.concatenate([a, a, a, opaque], axis=2)
    elif a.shape[2] == 2:
        a = _np.concatenate([a[..., :1], a[..., :1], a[..., :1], a[..., 1:]], axis=2)
    elif a.shape[2] == 3:
        a = _np.concatenate([a, opaque], axis=2)
    return _np.ascontiguousarray(a)


def _pair(name, value):
    """A setting for both axes (a string) or for each (a pair of strings)."""
    if isinstance(value, str):
        return value, value
    try:
        first, second = value
    except (TypeError, ValueError):
        raise Error(f"{name}: a string or a pair of strings, not {value!r}") from None
    return str(first), str(second)


def _add_texture(self, image, *, wrap="repeat", filter="linear", name=None):
    """Adds a texture image; returns its index for a material's texture slots (several
    materials may share it).

    image: H x W or H x W x C (C 1 to 4: grey, grey and alpha, RGB, RGBA), uint8 0-255 or
    floats 0-1, or a PIL image: the values an image file would hold, so colour textures are
    sRGB-encoded and data textures (metallic-roughness, normal, occlusion) linear, as glTF's.
    Row 0 is the top of the image, where uv (0, 0) is (glTF's convention). wrap: "repeat",
    "clamp_to_edge" or "mirrored_repeat", or a pair (u, v); filter: "linear" or "nearest", or
    a pair (magnification, minification)."""
    wrap_s, wrap_t = _pair("wrap", wrap)
    mag, min_ = _pair("filter", filter)
    return self._add_texture(_rgba8(image), wrap_s, wrap_t, mag, min_, name)


def _add_mesh(self, positions, indices, normals=None, uvs=None, colors=None, material=None,
              pose=None, name=None, uvs1=None):
    """Adds a mesh given as arrays; returns its instance index (segmentation id - 1).

    positions: N x 3 (metres), indices: M x 3 (counter-clockwise from the front), normals:
    N x 3, uvs: N x 2 ((0, 0) at the texture's top-left, as glTF), uvs1: N x 2, a second set
    (glTF's TEXCOORD_1) for textures that name it, colors: N x 3 or N x 4
    (linear, multiplying the base colour; floats from 0 to 1, or uint8 or uint16 arrays read as
    glTF reads normalized integer colours, 255 or 65535 = 1, so trimesh's
    ``visual.vertex_colors`` can be passed as they are); pose: 4x4 world-from-local matrix (default
    identity); material: a dict of glTF metallic-roughness factors (``base_color`` RGB or
    RGBA, ``metallic``, ``roughness``, ``emissive``, ``emissive_strength``, ``alpha_mode``,
    ``alpha_cutoff``, ``double_sided``, ``unlit``, ``normal_scale``, ``occlusion_strength``,
    ``name``), every key optional with glTF's default (white, metallic 1, roughness 1), the
    factors of the material extensions (``transmission``, ``ior``, ``dispersion``, ``thickness`` (0: a thin
    wall, above: a volume), ``attenuation_color``, ``attenuation_distance``, ``specular``,
    ``specular_color``, ``sheen_color``, ``sheen_roughness``, ``clearcoat``,
    ``clearcoat_roughness``, ``iridescence``, ``iridescence_ior``, ``iridescence_thickness``
    (min, max nm)), and textures (``base_color_texture``, ``metallic_roughness_texture``,
    ``normal_texture``, ``occlusion_texture``, ``emissive_texture``, and the extensions':
    ``transmission_texture``, ``clearcoat_texture`` and the others named as glTF names them,
    in snake case): each an index from ``add_texture`` or an image as it takes (added with
    its defaults), or a dict of one (``texture``) with the uv set it reads (``tex_coord``: 0,
    the default, or 1 for ``uvs1``) and a KHR_texture_transform (``offset``, ``scale``:
    (u, v); ``rotation``: radians, counter-clockwise); textures need the uvs they read.
    Raises Error, naming the mesh and the array, for a wrong shape, a NaN, an index out of
    range or a factor out of its range.
    """
    if colors is not None:
        c = _np.asarray(colors)
        if c.dtype in (_np.uint8, _np.uint16):
            # glTF's normalized unsigned integers: 255 (65535) is 1.
            c = c.astype(_np.float32) / _np.float32(_np.iinfo(c.dtype).max)
        colors = _np.asarray(c, dtype=_np.float32)
        if colors.ndim == 2 and colors.shape[1] == 3:
            colors = _np.concatenate([colors, _np.ones((len(colors), 1), _np.float32)], axis=1)
    if material is not None and not isinstance(material, dict):
        raise Error(f"material: a dict of factors, not {type(material).__name__}")
    if material is not None and any(k in material for k in _TEXTURE_SLOTS):
        material = dict(material)
        for key in _TEXTURE_SLOTS:
            value = material.get(key)
            if value is None:
                material.pop(key, None)
                continue
            try:
                if isinstance(value, dict):
                    # An image inside a transform's dict is added the same way.
                    image = value.get("texture")
                    if image is not None and not isinstance(image, (int, _np.integer)):
                        material[key] = {**value, "texture": _add_texture(self, image)}
                elif not isinstance(value, (int, _np.integer)):
                    material[key] = _add_texture(self, value)
            except Error as e:
                raise Error(f"material: {key}: {e}") from None
    return self._add_mesh(
        _rows("positions", positions, 3), _triangles(indices),
        None if normals is None else _rows("normals", normals, 3),
        None if uvs is None else _rows("uvs", uvs, 2),
        None if colors is None else _rows("colors", colors, 4),
        material, _pose(pose), name,
        None if uvs1 is None else _rows("uvs1", uvs1, 2))


def _from_arrays(positions, indices, normals=None, uvs=None, colors=None, material=None,
                 pose=None, name="<arrays>", uvs1=None):
    """A scene of one mesh given as arrays (see ``Scene.add_mesh``); add more meshes,
    cameras and lights to it, then render it as a loaded scene."""
    scene = Scene.empty(str(name))
    scene.add_mesh(positions, indices, normals, uvs, colors, material, pose, uvs1=uvs1)
    return scene


_scene_add_camera = Scene.add_camera
_scene_add_light = Scene.add_light
_scene_render_views = Scene.render_views


def _add_camera(self, pose, **projection):
    """Adds a camera placed by ``pose`` (4x4 world from camera: it looks down its local -Z with
    +Y up, as glTF and pyrender cameras do); returns its index for ``render(camera=...)``.
    The first camera is the default view. The projection is one of: ``yfov`` (radians) with
    optional ``aspect_ratio``; ``xmag`` and ``ymag`` (orthographic half extents, metres);
    ``fx``, ``fy``, ``cx``, ``cy`` (pinhole intrinsics in pixels of the rendered image,
    principal point from the top-left corner, y down). ``znear`` (default 0.05) and
    ``zfar`` (default none) clip along the view axis. The image's aspect sets the horizontal
    extent, as glTF viewers do; ``stretch=True`` keeps ``aspect_ratio`` or ``xmag`` instead,
    stretching the picture as glTF's projection matrices and pyrender do."""
    return _scene_add_camera(self, _pose(pose), **projection)


def _add_light(self, kind, pose=None, **light):
    """Adds a punctual light (``KHR_lights_punctual``): ``kind`` "directional" (intensity in
    lux), "point" or "spot" (candela; ``inner_cone_angle``, ``outer_cone_angle`` in radians),
    placed by ``pose`` (4x4 world from light: it shines down its local -Z), with ``color``
    (linear RGB), ``intensity`` and ``range``. Returns its index. A scene with lights is lit
    by them alone (and the ambient ``render`` is given), not by the default rig."""
    return _scene_add_light(self, kind, _pose(pose if pose is not None else _np.eye(4)), **light)


def _render_views(self, spec, width, height, **options):
    """Renders many views after one preparation of the scene (one BVH build), as
    ``meshtracer render --views SPEC``: ``spec`` is "orbit:N", "sphere:N", "random:N",
    "cameras", the path of a views file, or a list of views as such a file holds them
    (dicts with "look_from", "look_at" and optional "up", "yfov_degrees"). ``yfov``
    (degrees), ``look_at``, ``orbit_radius``, ``orbit_azimuth``, ``orbit_elevation`` are the
    CLI's options of the same names; the rest are ``render``'s. Returns one dict a view:
    ``render``'s arrays plus "camera_to_world" (4x4, OpenGL camera axes, as transforms.json)
    and, for perspective views, "intrinsics" (fl_x, fl_y, cx, cy in pixels)."""
    import json
    import os

    if isinstance(spec, (list, tuple)):
        return _scene_render_views(self, "", width, height, views_json=json.dumps(list(spec)),
                                   **options)
    return _scene_render_views(self, os.fsdecode(spec), width, height, **options)


Scene.add_mesh = _add_mesh
Scene.add_texture = _add_texture
Scene.from_arrays = staticmethod(_from_arrays)
Scene.add_camera = _add_camera
Scene.add_light = _add_light
Scene.render_views = _render_views
