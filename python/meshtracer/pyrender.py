"""A pyrender-compatible front: render a ``pyrender.Scene`` with meshtracer instead of OpenGL.

    from meshtracer.pyrender import OffscreenRenderer, RenderFlags   # instead of pyrender's
    renderer = OffscreenRenderer(640, 480)
    color, depth = renderer.render(scene)        # scene: a pyrender.Scene

The scene is read through pyrender's own objects (nodes and their world poses, meshes and
primitives with their materials and textures, the main camera, the lights, ``ambient_light``
and ``bg_color``) and handed to ``meshtracer.Scene.add_mesh`` / ``add_texture`` /
``add_camera`` / ``add_light``; the picture comes from the meshtracer library (shadows,
reflections, the glTF BRDF), not from OpenGL. pyrender itself is imported only to tell its objects apart, when ``render`` is called:
this module imports without it. docs/python.md lists every flag and what is done with it.
"""

import enum

import numpy as np

from . import Error, Scene

__all__ = ["OffscreenRenderer", "RenderFlags"]


class RenderFlags(enum.IntFlag):
    """pyrender's ``RenderFlags``, with the same values (pyrender's own flags work as well)."""

    NONE = 0
    DEPTH_ONLY = 1
    OFFSCREEN = 2
    FLIP_WIREFRAME = 4
    ALL_WIREFRAME = 8
    ALL_SOLID = 16
    SHADOWS_DIRECTIONAL = 32
    SHADOWS_POINT = 64
    SHADOWS_SPOT = 128
    SHADOWS_ALL = 32 | 64 | 128
    VERTEX_NORMALS = 256
    FACE_NORMALS = 512
    SKIP_CULL_FACES = 1024
    RGBA = 2048
    FLAT = 4096
    SEG = 8192


# Flags refused rather than ignored: they ask for a different picture than the one returned.
_REFUSED = {
    RenderFlags.FLIP_WIREFRAME: "wireframes are not drawn",
    RenderFlags.ALL_WIREFRAME: "wireframes are not drawn",
    RenderFlags.VERTEX_NORMALS: "normal vectors are not drawn as lines (render(aovs=('normal',)) "
                                "of meshtracer.Scene gives them as an array)",
    RenderFlags.FACE_NORMALS: "normal vectors are not drawn as lines",
}

_TRIANGLES = 4  # GLTF.TRIANGLES, the only primitive mode with faces.

# OpenGL's sampler constants, as pyrender's Sampler holds them, by meshtracer's names.
_WRAPS = {10497: "repeat", 33071: "clamp_to_edge", 33648: "mirrored_repeat"}
_NEAREST = {9728, 9984}  # GL_NEAREST, GL_NEAREST_MIPMAP_NEAREST; the other filters are linear

# pyrender's texture slots (its material attributes) by meshtracer's material keys.
_TEXTURES = {
    "base_color_texture": "baseColorTexture",
    "metallic_roughness_texture": "metallicRoughnessTexture",
    "normal_texture": "normalTexture",
    "occlusion_texture": "occlusionTexture",
    "emissive_texture": "emissiveTexture",
}


def _texture(target, texture, cache):
    """The index in ``target`` of a pyrender ``Texture``, added the first time it is seen
    (``cache``: id of the texture -> index). pyrender keeps of each slot's image only the
    channels its shader reads (``source_channels``): metallic-roughness "GB" (roughness in
    G, metalness in B, as glTF) goes back into those channels of an RGBA image."""
    key = id(texture)
    if key in cache:
        return cache[key]
    source = np.asarray(texture.source)
    if texture.source_channels == "GB":
        if source.ndim == 2:
            source = source[:, :, None]
        g, b = source[..., :1], source[..., -1:]
        source = np.concatenate([np.full_like(g, 255), g, b], axis=2)
    sampler = texture.sampler
    wrap = tuple(_WRAPS.get(w, "repeat") for w in (sampler.wrapS, sampler.wrapT))
    filters = tuple("nearest" if f in _NEAREST else "linear"
                    for f in (sampler.magFilter, sampler.minFilter))
    cache[key] = target.add_texture(source, wrap=wrap, filter=filters, name=texture.name)
    return cache[key]


def _material(material, flags):
    """The factors of a pyrender material as ``meshtracer.Scene.add_mesh`` takes them."""
    out = {}
    base = getattr(material, "baseColorFactor", None)
    if base is None:  # SpecularGlossinessMaterial: its diffuse factor as the base colour
        base = getattr(material, "diffuseFactor", None)
        out["metallic"] = 0.0
        gloss = getattr(material, "glossinessFactor", None)
        out["roughness"] = 1.0 - float(gloss) if gloss is not None else 1.0
    else:
        out["metallic"] = float(material.metallicFactor)
        out["roughness"] = float(material.roughnessFactor)
    if base is not None:
        out["base_color"] = [float(np.clip(c, 0.0, 1.0)) for c in np.asarray(base).ravel()[:4]]
    emissive = getattr(material, "emissiveFactor", None)
    if emissive is not None:
        out["emissive"] = [float(c) for c in np.asarray(emissive).ravel()[:3]]
    mode = (getattr(material, "alphaMode", None) or "OPAQUE").upper()
    out["alpha_mode"] = mode
    if mode == "MASK":
        out["alpha_cutoff"] = float(material.alphaCutoff)
    out["double_sided"] = bool(material.doubleSided) or bool(flags & RenderFlags.SKIP_CULL_FACES)
    if flags & RenderFlags.FLAT:
        out["unlit"] = True
    return out


def _add_primitive(target, primitive, world, flags, name, textures):
    """Adds one pyrender primitive (and each of its instance poses) to ``target``; returns the
    instance indices it got. ``textures`` maps the pyrender textures already added to their
    indices."""
    mode = _TRIANGLES if primitive.mode is None else int(primitive.mode)
    if mode != _TRIANGLES:
        return []  # points and lines have no surface to hit
    positions = np.asarray(primitive.positions, dtype=np.float32)
    if primitive.indices is None:
        indices = np.arange(len(positions) // 3 * 3, dtype=np.uint32).reshape(-1, 3)
    else:
        indices = np.asarray(primitive.indices).reshape(-1, 3)
    material = _material(primitive.material, flags)
    smooth = getattr(primitive.material, "smooth", True)
    normals = primitive.normals if smooth else None
    uvs = primitive.texcoord_0
    if uvs is not None:
        # pyrender's textures are OpenGL's: uv (0, 0) at the image's bottom-left (it flips the
        # rows when it uploads them); glTF's and meshtracer's at the top-left.
        uvs = np.asarray(uvs, np.float32)[:, :2] * [1.0, -1.0] + [0.0, 1.0]
        for key, slot in _TEXTURES.items():
            texture = getattr(primitive.material, slot, None)
            if texture is not None and getattr(texture, "source", None) is not None:
                material[key] = _texture(target, texture, textures)
    colors = primitive.color_0
    if colors is not None:
        colors = np.asarray(colors)
        if colors.dtype.kind in "ui":  # 8-bit colours, as trimesh gives them
            colors = colors.astype(np.float32) / 255.0
        colors = colors[:, :4]
    poses = primitive.poses if primitive.poses is not None else [np.eye(4)]
    added = []
    for pose in poses:
        added.append(target.add_mesh(positions, indices, normals=normals, uvs=uvs,
                                     colors=colors, material=material,
                                     pose=np.asarray(world) @ np.asarray(pose), name=name))
    return added


def _digest(hasher, value):
    """Feeds ``value`` (an array, a number, a string, None, or a sequence of them) to
    ``hasher``: arrays by their bytes, dtype and shape."""
    if value is None:
        hasher.update(b"\0")
    elif isinstance(value, np.ndarray):
        hasher.update(f"{value.dtype}{value.shape}".encode())
        hasher.update(np.ascontiguousarray(value).data)
    elif isinstance(value, (list, tuple)):
        for item in value:
            _digest(hasher, item)
    else:
        hasher.update(repr(value).encode())


# What of a pyrender material the picture depends on, besides its textures.
_MATERIAL_FACTORS = ("baseColorFactor", "metallicFactor", "roughnessFactor", "emissiveFactor",
                     "alphaMode", "alphaCutoff", "doubleSided", "smooth", "diffuseFactor",
                     "glossinessFactor")


def _fingerprint(mesh):
    """A digest of what ``_add_primitive`` reads of ``mesh``: every primitive's arrays, its
    material's factors and its textures' images and samplers (BLAKE2 at about 1 GB/s: a
    fraction of what building the scene again costs)."""
    import hashlib

    hasher = hashlib.blake2b(digest_size=16)
    for p in mesh.primitives:
        _digest(hasher, [p.mode, p.positions, p.indices, p.normals, p.texcoord_0, p.color_0,
                         p.poses])
        material = p.material
        _digest(hasher, [type(material).__name__]
                + [getattr(material, f, None) for f in _MATERIAL_FACTORS])
        for slot in _TEXTURES.values():
            texture = getattr(material, slot, None)
            if texture is None:
                _digest(hasher, None)
                continue
            sampler = texture.sampler
            _digest(hasher, [np.asarray(texture.source), texture.source_channels, sampler.wrapS,
                             sampler.wrapT, sampler.magFilter, sampler.minFilter])
    return hasher.digest()


def _camera_options(camera, width, height):
    """``meshtracer.Scene.add_camera``'s projection arguments for a pyrender camera."""
    import pyrender

    options = {"znear": float(camera.znear)}
    zfar = getattr(camera, "zfar", None)
    if zfar is not None and np.isfinite(zfar):
        options["zfar"] = float(zfar)
    if isinstance(camera, pyrender.IntrinsicsCamera):
        options.update(fx=float(camera.fx), fy=float(camera.fy), cx=float(camera.cx),
                       cy=float(camera.cy))
    elif isinstance(camera, pyrender.OrthographicCamera):
        # pyrender 0.1.45 replaces xmag by ymag times the viewport's aspect, as meshtracer does.
        options.update(xmag=float(camera.xmag), ymag=float(camera.ymag))
    elif isinstance(camera, pyrender.PerspectiveCamera):
        # pyrender takes the x scale from aspectRatio whatever the viewport, so the picture
        # stretches where it disagrees with it: stretch=True.
        options.update(yfov=float(camera.yfov), stretch=True)
        if getattr(camera, "aspectRatio", None) is not None:
            options["aspect_ratio"] = float(camera.aspectRatio)
    else:
        raise Error(f"camera of type {type(camera).__name__}: use PerspectiveCamera, "
                    "IntrinsicsCamera or OrthographicCamera")
    return options


def _light_options(light):
    """``meshtracer.Scene.add_light``'s arguments for a pyrender light (pyrender's units are
    glTF's: lux for directional lights, candela for point and spot lights)."""
    import pyrender

    common = {"color": [float(c) for c in np.asarray(light.color).ravel()[:3]],
              "intensity": float(light.intensity)}
    if isinstance(light, pyrender.DirectionalLight):
        return "directional", common
    if isinstance(light, pyrender.SpotLight):
        return "spot", dict(common, inner_cone_angle=float(light.innerConeAngle),
                            outer_cone_angle=float(light.outerConeAngle))
    if isinstance(light, pyrender.PointLight):
        return "point", common
    raise Error(f"light of type {type(light).__name__}: use DirectionalLight, PointLight or "
                "SpotLight")


def _seg_colour(value):
    """A ``seg_node_map`` value as pyrender draws it: an RGB triple (a fourth value ignored) or
    one number repeated, 0-255, rounded to 8 bits as its framebuffer does."""
    colour = np.asarray(value, np.float64).ravel()
    if colour.size == 1:
        colour = np.repeat(colour, 3)
    if colour.size < 3:
        raise Error(f"seg_node_map colour {value!r}: give an RGB triple or one number")
    return np.clip(np.round(colour[:3]), 0, 255).astype(np.uint8)


class OffscreenRenderer:
    """pyrender's ``OffscreenRenderer`` with meshtracer behind it.

    ``spp`` (samples per pixel), ``integrator`` ("direct": punctual lights with shadows and
    ambient, as pyrender lights a scene; "path": global illumination), ``seed`` and
    ``tonemap`` are meshtracer's render options; the rest is pyrender's interface.
    """

    def __init__(self, viewport_width, viewport_height, point_size=1.0, *, spp=16,
                 integrator="direct", seed=0, tonemap="standard"):
        self.viewport_width = int(viewport_width)
        self.viewport_height = int(viewport_height)
        self.point_size = point_size
        self.spp = spp
        self.integrator = integrator
        self.seed = seed
        self.tonemap = tonemap
        # The meshes of the last scene rendered, kept while its meshes and poses stay the same
        # (so that views of one scene share one BVH), with what identifies them.
        self._built = None
        self._built_key = None

    def _scene_for(self, scene, flags, only=None):
        """The meshtracer scene of ``scene``'s visible meshes (of those in ``only`` alone, if
        given), built again only when they changed: the key holds the nodes, their poses and a
        fingerprint of each primitive's arrays and material, so that editing a material or
        vertex data in place is seen."""
        nodes = [n for n in sorted(scene.mesh_nodes, key=id)
                 if getattr(n.mesh, "is_visible", True) and (only is None or n in only)]
        key = (int(flags & (RenderFlags.SKIP_CULL_FACES | RenderFlags.FLAT)),
               tuple((id(n), id(n.mesh), scene.get_pose(n).tobytes(), _fingerprint(n.mesh))
                     for n in nodes))
        if self._built is not None and key == self._built_key:
            return self._built, self._instances
        built = Scene.empty("<pyrender scene>")
        instances = {}
        textures = {}
        for node in nodes:
            world = scene.get_pose(node)
            for primitive in node.mesh.primitives:
                name = node.name or node.mesh.name
                for index in _add_primitive(built, primitive, world, flags, name, textures):
                    instances[index] = node
        if not instances and nodes:
            # Meshes of points and lines alone (hidden meshes draw nothing, as in pyrender: the
            # picture is the background).
            raise Error("the pyrender scene has no mesh with triangles: nothing to draw")
        self._built, self._built_key, self._instances = built, key, instances
        return built, instances

    def render(self, scene, flags=RenderFlags.NONE, seg_node_map=None):
        """Renders ``scene`` (a ``pyrender.Scene``) from its main camera, as pyrender does.

        Returns ``(color, depth)``: color uint8 H x W x 3 (x 4 with ``RGBA``), the
        8-bit sRGB picture over ``scene.bg_color``; depth float32 H x W, camera-space z (distance
        along the view axis) in metres, 0 where nothing was hit. With ``DEPTH_ONLY`` only the
        depth. With ``SEG`` the colour is each mesh node's colour from ``seg_node_map`` (an RGB
        triple, or one number for a grey) over black, and, as in pyrender, nodes missing from
        the map are not drawn at all: they neither show nor hide what is behind them, and the
        depth leaves them out too.
        """
        flags = RenderFlags(int(flags))
        for flag, why in _REFUSED.items():
            if flags & flag:
                raise Error(f"RenderFlags.{flag.name}: {why}")
        if scene.main_camera_node is None:
            raise Error("the pyrender scene has no camera (pyrender needs one too)")
        width, height = self.viewport_width, self.viewport_height
        seg = bool(flags & RenderFlags.SEG)
        if seg:
            # pyrender draws the mapped nodes alone (`_forward_pass` skips the others).
            only = {n for n in scene.mesh_nodes if seg_node_map and n in seg_node_map}
            if not only:
                return (np.zeros((height, width, 3), np.uint8),
                        np.zeros((height, width), np.float32))
        built, instances = self._scene_for(scene, flags, only if seg else None)
        camera_node = scene.main_camera_node
        built.clear_cameras()
        built.add_camera(scene.get_pose(camera_node),
                         **_camera_options(camera_node.camera, width, height))
        built.clear_lights()
        for node in scene.light_nodes:
            kind, options = _light_options(node.light)
            built.add_light(kind, scene.get_pose(node), **options)

        depth_only = bool(flags & RenderFlags.DEPTH_ONLY)
        aovs = ("depth", "segmentation") if seg else ("depth",)
        out = built.render(width, height, camera=0, spp=1 if depth_only or seg else self.spp,
                           integrator=self.integrator, seed=self.seed, aovs=aovs,
                           srgb8=not (depth_only or seg), tonemap=self.tonemap,
                           ambient=[float(a) for a in np.asarray(scene.ambient_light)[:3]],
                           default_lights=False)
        depth = out["depth"]
        if depth_only:
            return depth
        if seg:
            color = np.zeros((height, width, 3), np.uint8)
            ids = out["segmentation"]
            for index, node in instances.items():
                color[ids == index + 1] = _seg_colour(seg_node_map[node])
            return color, depth
        rgba = out["srgb8"].astype(np.float32)
        alpha = rgba[..., 3:4] / 255.0
        background = np.asarray(scene.bg_color, np.float32).ravel()[:4] * 255.0
        rgb = rgba[..., :3] * alpha + background[:3] * (1.0 - alpha)
        channels = [rgb]
        if flags & RenderFlags.RGBA:
            channels.append(rgba[..., 3:4] + background[3] * (1.0 - alpha))
        color = np.concatenate(channels, axis=-1)
        return np.clip(np.round(color), 0, 255).astype(np.uint8), depth

    def delete(self):
        """Frees the scene kept between renders (pyrender frees its GL context here)."""
        self._built = None
        self._built_key = None
