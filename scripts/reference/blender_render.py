"""Render MODEL with Blender Cycles (CPU) from a meshtracer view file.

    python blender_render.py -- VIEW.json MODEL OUT.png [options]      (PyPI bpy 5.x)
    blender -b --factory-startup -P blender_render.py -- VIEW.json MODEL OUT.png [options]

Options: [--mode direct|gi] [--samples 32] [--units compat|spec] [--threads N]

The camera, lights and ambient come from VIEW.json (`meshtracer render --view-out`); the
model's own cameras and lights are removed. `--mode direct` (default) renders direct light only
(max bounces 0), like meshtracer; `--mode gi` renders full global illumination. A view written
by `meshtracer render --integrator path` selects `gi` with the same bounces, and its environment
lights the world: the `--env-out` panorama when the view names one (rotation and intensity
already applied), else the source panorama with the same rotation and intensity (the built-in
studio needs `--env-out`). The view transform and exposure are the view's `display` record
(`--tonemap`, `--exposure`; 'Standard' and 0 for views written before it): Standard, Khronos PBR
Neutral and AgX are Blender's own view transforms; `aces` needs an ACES view (Blender 5's
"ACES 1.3" or "ACES 2.0"). Transparent film, hard shadows (light radius and sun angle 0), and
meshtracer's pixel filter (a box one pixel wide).

Light units: Blender's glTF importer ("SPEC" mode) converts W = cd·4π/683 for point and spot
lights and W/m² = lux/683 for suns, which makes 1 lux read 1/683 as bright as in meshtracer and
pyrender. `--units compat` (default) uses W = 4π·I and sun strength = E instead, so a white
Lambertian surface under 1 lux reads about 1/π in all three renderers; `--units spec` gives the
importer's numbers.

Importer corrections, so that Cycles renders the file as glTF and MTL define it (Blender 5.2;
each is skipped where the Blender at hand does not need it):
- a primitive without a material gets glTF's default material (white, metallic 1, roughness 1),
  not Cycles' grey; an OBJ face without one gets meshtracer's grey (0.8, metallic 0,
  roughness 1);
- `KHR_materials_iridescence`: the importer reads the maximum thickness from a key the
  extension does not define (`iridescenceThickness`), so the film is always 400 nm thick; the
  script sets the file's `iridescenceThicknessMaximum` (without a thickness texture), and no
  film where `iridescenceFactor` is 0 (Cycles has no film factor: 0 < factor < 1 renders as 1);
- OBJ: the importer turns an MTL `Tf` into transmission on every material, so `Tf 1 1 1` on an
  opaque `illum 2` material becomes clear glass: transmission is reset unless `illum` is 4, 6,
  7 or 9;
- OBJ: a `usemtl` naming no material of the MTL becomes an empty material of that name;
  where the MTL defines just one material, those faces get it, as meshtracer reads them;
- OBJ: vertex colours (`v x y z r g b`) are imported as a colour attribute no material reads;
  they multiply each material's base colour (a white default's where a face has none), as in
  meshtracer.
"""
import argparse
import json
import math
import os
import struct
import sys

import bpy
import numpy

# Blender 3.4's glTF importer uses np.bool, which numpy 1.24 removed.
if not hasattr(numpy, "bool"):
    numpy.bool = bool

from mathutils import Matrix, Vector  # noqa: E402


def pose(position, forward, up_hint):
    w = -Vector(forward).normalized()
    up = Vector(up_hint)
    if abs(up.normalized().dot(w)) > 0.99:
        up = Vector((1.0, 0.0, 0.0)) if abs(w.x) < 0.9 else Vector((0.0, 1.0, 0.0))
    u = up.cross(w).normalized()
    v = w.cross(u)
    m = Matrix.Identity(4)
    for row in range(3):
        m[row][0], m[row][1], m[row][2], m[row][3] = u[row], v[row], w[row], position[row]
    return m


# glTF is +Y up; Blender is +Z up. The importer rotates the model by this matrix, so the view's
# glTF-space camera and lights get the same rotation.
GLTF_TO_BLENDER = Matrix(((1, 0, 0, 0), (0, 0, -1, 0), (0, 1, 0, 0), (0, 0, 0, 1)))


# meshtracer's --tonemap names and the Blender view transforms that match them.
VIEW_TRANSFORMS = {
    "standard": ["Standard"],
    "khronos-pbr-neutral": ["Khronos PBR Neutral"],
    "agx": ["AgX"],
    "aces": ["ACES 1.3", "ACES 2.0"],
}


def set_display(scene, display):
    """Sets the view transform and exposure recorded in the view file."""
    name = display.get("view_transform", "standard")
    # The list of view transforms is dynamic (the colour management configuration's), so try
    # each name rather than reading the enum's static items.
    for choice in VIEW_TRANSFORMS.get(name, []):
        try:
            scene.view_settings.view_transform = choice
            break
        except TypeError:
            continue
    else:
        sys.exit(f"view transform {name!r}: this Blender has none of {VIEW_TRANSFORMS.get(name)}")
    scene.view_settings.look = "None"
    scene.view_settings.exposure = display.get("exposure", 0.0)
    scene.view_settings.gamma = 1.0


def gltf_json(path):
    """The JSON of a .gltf or .glb file (None when unreadable)."""
    try:
        with open(path, "rb") as f:
            data = f.read()
        if data[:4] == b"glTF":
            length, kind = struct.unpack_from("<II", data, 12)
            if kind != 0x4E4F534A:
                return None
            return json.loads(data[20:20 + length])
        return json.loads(data)
    except (OSError, ValueError, struct.error):
        return None


def principled(material):
    if material is None or material.node_tree is None:
        return None
    for node in material.node_tree.nodes:
        if node.type == "BSDF_PRINCIPLED":
            return node
    return None


def fix_iridescence(model):
    """Sets each film's maximum thickness from the file, and no film where the factor is 0."""
    doc = gltf_json(model)
    if not doc:
        return
    for m in doc.get("materials", []):
        ext = m.get("extensions", {}).get("KHR_materials_iridescence")
        material = bpy.data.materials.get(m.get("name", ""))
        node = principled(material)
        if ext is None or node is None or "Thin Film Thickness" not in node.inputs:
            continue
        socket = node.inputs["Thin Film Thickness"]
        if ext.get("iridescenceFactor", 0.0) <= 0.0 and "iridescenceTexture" not in ext:
            if socket.is_linked:
                material.node_tree.links.remove(socket.links[0])
            socket.default_value = 0.0
        elif "iridescenceThicknessTexture" not in ext and not socket.is_linked:
            socket.default_value = ext.get("iridescenceThicknessMaximum", 400.0)


def default_material(obj_file, coloured=False):
    """glTF's default material (white, metallic 1, roughness 1), or for an OBJ face without a
    material meshtracer's grey (0.8, metallic 0, roughness 1), white under vertex colours."""
    material = bpy.data.materials.new("default")
    if hasattr(material, "use_nodes"):
        material.use_nodes = True
    node = principled(material)
    grey = 0.8 if obj_file and not coloured else 1.0
    node.inputs["Base Color"].default_value = (grey, grey, grey, 1.0)
    node.inputs["Metallic"].default_value = 0.0 if obj_file else 1.0
    node.inputs["Roughness"].default_value = 1.0
    return material


def fix_missing_materials(obj_file):
    """Gives meshes without a material the default one meshtracer uses, not Cycles' grey."""
    defaults = {}
    for obj in bpy.data.objects:
        if obj.type != "MESH":
            continue
        slots = obj.data.materials
        if len(slots) == 0 or any(m is None for m in slots):
            coloured = obj_file and len(obj.data.color_attributes) > 0
            if coloured not in defaults:
                defaults[coloured] = default_material(obj_file, coloured)
            material = defaults[coloured]
            if len(slots) == 0:
                slots.append(material)
            else:
                for i, m in enumerate(slots):
                    if m is None:
                        slots[i] = material


def mtl_illum(model):
    """MTL material name -> illum (2 where the MTL gives none), for every material the
    libraries the OBJ names define."""
    illum, libraries = {}, []
    try:
        with open(model, errors="replace") as f:
            for line in f:
                if line.startswith("mtllib"):
                    libraries += line.split()[1:]
    except OSError:
        return illum
    for library in libraries:
        name = None
        try:
            with open(os.path.join(os.path.dirname(model), library), errors="replace") as f:
                for line in f:
                    words = line.split()
                    if len(words) >= 2 and words[0] == "newmtl":
                        name = line.split(None, 1)[1].strip()
                        illum.setdefault(name, 2)
                    elif len(words) >= 2 and words[0] == "illum" and name is not None:
                        illum[name] = int(float(words[1]))
        except (OSError, ValueError):
            continue
    return illum


def fix_obj_transmission(model):
    """Keeps transmission only on MTL materials whose illum model refracts (4, 6, 7, 9)."""
    illum = mtl_illum(model)
    for material in bpy.data.materials:
        node = principled(material)
        if node is None or "Transmission Weight" not in node.inputs:
            continue
        if illum.get(material.name, 2) not in (4, 6, 7, 9):
            node.inputs["Transmission Weight"].default_value = 0.0


def fix_obj_vertex_colours():
    """OBJ vertex colours multiply the base colour, as glTF's COLOR_0 does and meshtracer draws
    them; Blender's importer keeps them (decoded from sRGB, as meshtracer decodes them) as a
    colour attribute that no material reads. Each coloured mesh gets its own copy of its
    materials, with the attribute multiplied into Base Color."""
    for obj in bpy.data.objects:
        if obj.type != "MESH" or len(obj.data.color_attributes) == 0:
            continue
        layer = obj.data.color_attributes[0].name
        slots = obj.data.materials
        for i, material in enumerate(slots):
            if material is None:
                continue
            material = material.copy()
            slots[i] = material
            node = principled(material)
            if node is None:
                continue
            tree = material.node_tree
            attribute = tree.nodes.new("ShaderNodeVertexColor")
            attribute.layer_name = layer
            mix = tree.nodes.new("ShaderNodeMix")
            mix.data_type = "RGBA"
            mix.blend_type = "MULTIPLY"
            mix.inputs["Factor"].default_value = 1.0
            base, colour_a, colour_b = node.inputs["Base Color"], mix.inputs[6], mix.inputs[7]
            if base.is_linked:
                tree.links.new(base.links[0].from_socket, colour_a)
            else:
                colour_a.default_value = base.default_value
            tree.links.new(attribute.outputs["Color"], colour_b)
            tree.links.new(mix.outputs[2], base)


def fix_obj_undefined_materials(model):
    """Faces whose `usemtl` names no material of the MTL get its only material when it defines
    just one, as meshtracer (and tinyobjloader-based viewers) read them: VikingRoom says
    `usemtl Texture1` and its MTL defines only `room`. Blender's importer makes an empty
    material of that name instead, which renders the room untextured and white."""
    defined = list(mtl_illum(model))
    if len(defined) != 1:
        return
    only = bpy.data.materials.get(defined[0])
    if only is None:
        return
    for obj in bpy.data.objects:
        if obj.type != "MESH":
            continue
        slots = obj.data.materials
        for i, material in enumerate(slots):
            if material is None or material.name.split(".")[0] not in defined:
                slots[i] = only


def import_model(model):
    if model.lower().endswith(".obj"):
        if hasattr(bpy.ops.wm, "obj_import"):
            bpy.ops.wm.obj_import(filepath=model, forward_axis="NEGATIVE_Z", up_axis="Y")
            fix_obj_transmission(model)
            fix_obj_undefined_materials(model)
        else:
            bpy.ops.import_scene.obj(filepath=model, axis_forward="-Z", axis_up="Y")
    else:
        options = {}
        props = bpy.ops.import_scene.gltf.get_rna_type().properties
        if "export_import_convert_lighting_mode" in props:
            options["export_import_convert_lighting_mode"] = "COMPAT"
        bpy.ops.import_scene.gltf(filepath=model, **options)
        fix_iridescence(model)
    fix_missing_materials(model.lower().endswith(".obj"))
    if model.lower().endswith(".obj"):
        fix_obj_vertex_colours()
    for obj in list(bpy.data.objects):
        if obj.type in {"CAMERA", "LIGHT"}:
            bpy.data.objects.remove(obj, do_unlink=True)


def main(argv):
    parser = argparse.ArgumentParser()
    parser.add_argument("view")
    parser.add_argument("model")
    parser.add_argument("out")
    parser.add_argument("--mode", choices=["direct", "gi"], default="direct")
    parser.add_argument("--samples", type=int, default=32)
    parser.add_argument("--units", choices=["compat", "spec"], default="compat")
    parser.add_argument("--threads", type=int, default=0, help="render threads (0: all cores)")
    args = parser.parse_args(argv)
    with open(args.view) as f:
        view = json.load(f)

    bpy.ops.wm.read_factory_settings(use_empty=True)
    import_model(os.path.abspath(args.model))

    scene = bpy.context.scene
    cam = view["camera"]
    camera_data = bpy.data.cameras.new("view")
    camera_data.sensor_fit = "VERTICAL"
    if cam["type"] == "perspective":
        camera_data.type = "PERSP"
        camera_data.angle_y = cam["yfov"]
    else:
        camera_data.type = "ORTHO"
        camera_data.ortho_scale = 2.0 * cam["ymag"]
    if cam.get("aperture_radius"):
        # meshtracer's thin lens (--aperture-radius, --focus-distance): Cycles' aperture radius
        # is the focal length / (2·f-stop) (1 / (2·f-stop) for an orthographic camera), the
        # focal length in metres from the sensor height that the vertical fov implies.
        camera_data.dof.use_dof = True
        camera_data.dof.focus_distance = cam["focus_distance"]
        if cam["type"] == "perspective":
            focal = camera_data.lens * 1e-3
        else:
            focal = 1.0
        camera_data.dof.aperture_fstop = focal / (2.0 * cam["aperture_radius"])
        camera_data.dof.aperture_blades = 0
    camera_data.clip_start = max(cam["znear"], 1e-4)
    camera_data.clip_end = cam["zfar"] or 1e5
    camera = bpy.data.objects.new("view", camera_data)
    forward = cam.get("forward") or [b - a for a, b in zip(cam["position"], cam["look_at"])]
    camera.matrix_world = GLTF_TO_BLENDER @ pose(cam["position"], forward, cam["up"])
    scene.collection.objects.link(camera)
    scene.camera = camera

    to_watts = 4.0 * math.pi / (683.0 if args.units == "spec" else 1.0)
    to_sun = 1.0 / (683.0 if args.units == "spec" else 1.0)
    for i, light in enumerate(view["lights"]):
        kind = {"point": "POINT", "spot": "SPOT", "directional": "SUN"}[light["type"]]
        data = bpy.data.lights.new(f"light{i}", kind)
        data.color = light["color"]
        if kind == "SUN":
            data.energy = light["intensity"] * to_sun
            data.angle = 0.0
        else:
            data.energy = light["intensity"] * to_watts
            data.shadow_soft_size = 0.0
        if kind == "SPOT":
            outer = light.get("outer_cone_angle", math.pi / 4)
            inner = light.get("inner_cone_angle", 0.0)
            data.spot_size = 2.0 * outer
            data.spot_blend = (outer - inner) / outer if outer > 0 else 0.0
        obj = bpy.data.objects.new(f"light{i}", data)
        obj.matrix_world = GLTF_TO_BLENDER @ pose(light["position"], light["direction"], [0.0, 1.0, 0.0])
        scene.collection.objects.link(obj)

    world = bpy.data.worlds.new("ambient")
    if hasattr(world, "use_nodes") and not world.use_nodes:
        world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs[0].default_value = (*view.get("ambient", [0, 0, 0]), 1.0)
    scene.world = world
    environment = view.get("environment")
    if view.get("integrator") == "path":
        args.mode = "gi"
    if environment and environment["source"].get("type") == "uniform":
        # The white furnace: one radiance everywhere.
        background.inputs[0].default_value = (*environment["source"]["radiance"], 1.0)
        background.inputs["Strength"].default_value = environment["intensity"]
    elif environment:
        panorama = environment.get("panorama")
        source = environment["source"]
        if panorama is None and source.get("type") != "file":
            sys.exit("the view's environment is the built-in one: render it with --env-out FILE.hdr")
        nodes, links = world.node_tree.nodes, world.node_tree.links
        texture = nodes.new("ShaderNodeTexEnvironment")
        texture.image = bpy.data.images.load(panorama or source["path"])
        background.inputs[0].default_value = (1.0, 1.0, 1.0, 1.0)
        links.new(texture.outputs["Color"], background.inputs["Color"])
        if panorama is None:
            # meshtracer turns the panorama counter-clockwise about +Y (Blender +Z); the mapping
            # node turns the lookup direction, hence the minus sign.
            coords = nodes.new("ShaderNodeTexCoord")
            mapping = nodes.new("ShaderNodeMapping")
            mapping.inputs["Rotation"].default_value[2] = -math.radians(environment["rotation_degrees"])
            links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
            links.new(mapping.outputs["Vector"], texture.inputs["Vector"])
            background.inputs["Strength"].default_value = environment["intensity"]
        else:
            background.inputs["Strength"].default_value = 1.0

    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = args.samples
    scene.cycles.use_denoising = False
    # meshtracer averages a pixel's samples with equal weight over the pixel's square (a box
    # filter 1 pixel wide); Cycles' default is a Blackman-Harris filter 1.5 pixels wide, which
    # blurs edges and textures and makes every silhouette differ. Compare shading, not
    # reconstruction filters.
    scene.cycles.pixel_filter_type = "BOX"
    scene.cycles.filter_width = 1.0
    if args.threads > 0:
        scene.render.threads_mode = "FIXED"
        scene.render.threads = args.threads
    if args.mode == "direct":
        scene.cycles.max_bounces = 0
    elif view.get("bounces") is not None:
        bounces = view["bounces"]
        scene.cycles.max_bounces = bounces
        for kind in ("diffuse", "glossy", "transmission", "volume", "transparent"):
            # Blender 5 renamed some of them ("transparent_max_bounces").
            for name in (f"{kind}_bounces", f"{kind}_max_bounces"):
                if hasattr(scene.cycles, name):
                    setattr(scene.cycles, name, bounces)
    # --clamp-indirect: Cycles' own indirect clamp (0 = none).
    scene.cycles.sample_clamp_indirect = view.get("clamp_indirect") or 0.0
    scene.render.film_transparent = not (environment and environment.get("visible"))
    set_display(scene, view.get("display") or {})
    scene.render.resolution_x = view["image"]["width"]
    scene.render.resolution_y = view["image"]["height"]
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = os.path.abspath(args.out)
    bpy.ops.render.render(write_still=True)


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    main(argv)
