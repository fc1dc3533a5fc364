"""Render MODEL with Blender Cycles (CPU) from a meshtracer view file.

    blender -b --factory-startup -P blender_render.py -- VIEW.json MODEL OUT.png
            [--mode direct|gi] [--samples 32] [--units compat|spec]

The camera, lights and ambient come from VIEW.json (`meshtracer render --view-out`); the
model's own cameras and lights are removed. `--mode direct` (default) renders direct light only
(max bounces 0), like meshtracer; `--mode gi` renders full global illumination. A view written
by `meshtracer render --integrator path` selects `gi` with the same bounces, and its environment
lights the world: the `--env-out` panorama when the view names one (rotation and intensity
already applied), else the source panorama with the same rotation and intensity (the built-in
studio needs `--env-out`). The view transform and exposure are the view's `display` record
(`--tonemap`, `--exposure`; 'Standard' and 0 for views written before it): Standard, Khronos PBR
Neutral and AgX are Blender's own view transforms; `aces` needs an ACES view (Blender 5's
"ACES 1.3" or "ACES 2.0"). Transparent film, hard shadows (light radius and sun angle 0).

Light units: Blender's glTF importer ("SPEC" mode) converts W = cd·4π/683 for point and spot
lights and W/m² = lux/683 for suns, which makes 1 lux read 1/683 as bright as in meshtracer and
pyrender. `--units compat` (default) uses W = 4π·I and sun strength = E instead, so a white
Lambertian surface under 1 lux reads about 1/π in all three renderers; `--units spec` gives the
importer's numbers.
"""
import argparse
import json
import math
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
    available = {
        item.identifier
        for item in scene.view_settings.bl_rna.properties["view_transform"].enum_items
    }
    choices = [c for c in VIEW_TRANSFORMS.get(name, []) if c in available]
    if not choices:
        sys.exit(f"view transform {name!r}: this Blender has none of {VIEW_TRANSFORMS.get(name)}"
                 f" (it has {sorted(available)})")
    scene.view_settings.view_transform = choices[0]
    scene.view_settings.look = "None"
    scene.view_settings.exposure = display.get("exposure", 0.0)
    scene.view_settings.gamma = 1.0


def main(argv):
    parser = argparse.ArgumentParser()
    parser.add_argument("view")
    parser.add_argument("model")
    parser.add_argument("out")
    parser.add_argument("--mode", choices=["direct", "gi"], default="direct")
    parser.add_argument("--samples", type=int, default=32)
    parser.add_argument("--units", choices=["compat", "spec"], default="compat")
    args = parser.parse_args(argv)
    with open(args.view) as f:
        view = json.load(f)

    bpy.ops.wm.read_factory_settings(use_empty=True)
    if args.model.lower().endswith(".obj"):
        if hasattr(bpy.ops.wm, "obj_import"):
            bpy.ops.wm.obj_import(filepath=args.model, forward_axis="NEGATIVE_Z", up_axis="Y")
        else:
            bpy.ops.import_scene.obj(filepath=args.model, axis_forward="-Z", axis_up="Y")
    else:
        bpy.ops.import_scene.gltf(filepath=args.model)
    for obj in list(bpy.data.objects):
        if obj.type in {"CAMERA", "LIGHT"}:
            bpy.data.objects.remove(obj, do_unlink=True)

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
    camera_data.clip_start = max(cam["znear"], 1e-4)
    camera_data.clip_end = cam["zfar"] or 1e5
    camera = bpy.data.objects.new("view", camera_data)
    forward = [b - a for a, b in zip(cam["position"], cam["look_at"])]
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
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs[0].default_value = (*view.get("ambient", [0, 0, 0]), 1.0)
    scene.world = world
    environment = view.get("environment")
    if view.get("integrator") == "path":
        args.mode = "gi"
    if environment:
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
    if args.mode == "direct":
        scene.cycles.max_bounces = 0
    elif view.get("bounces") is not None:
        bounces = view["bounces"]
        scene.cycles.max_bounces = bounces
        for kind in ("diffuse", "glossy", "transmission", "volume", "transparent"):
            setattr(scene.cycles, f"{kind}_bounces", bounces)
    # --clamp-indirect: Cycles' own indirect clamp (0 = none).
    scene.cycles.sample_clamp_indirect = view.get("clamp_indirect") or 0.0
    scene.render.film_transparent = not (environment and environment.get("visible"))
    set_display(scene, view.get("display") or {})
    scene.render.resolution_x = view["image"]["width"]
    scene.render.resolution_y = view["image"]["height"]
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = args.out
    bpy.ops.render.render(write_still=True)


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    main(argv)
