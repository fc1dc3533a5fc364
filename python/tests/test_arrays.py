"""Scenes built from Python (from_arrays, add_mesh, cameras, lights), many views after one
preparation, progress and cancelling.

The quad tests know their answer in closed form: a unit quad two metres in front of a camera
whose view rectangle is one metre tall at one metre covers exactly the middle half of the
image in each direction, at depth 2.
"""

import math

import numpy as np
import pytest

import meshtracer
from conftest import ASSETS

CORNELL = ASSETS / "cornell-box.gltf"

QUAD = np.array([[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.5, 0.5, 0.0], [-0.5, 0.5, 0.0]])
QUAD_TRIANGLES = np.array([[0, 1, 2], [0, 2, 3]])
MATTE = {"base_color": [0.8, 0.8, 0.8], "metallic": 0.0, "roughness": 1.0}
# Explicit settings: the defaults of render may change, these tests' answers do not.
SETTINGS = dict(spp=4, integrator="direct", seed=0, tonemap="standard")


def translation(x, y, z):
    pose = np.eye(4)
    pose[:3, 3] = [x, y, z]
    return pose


def quad_scene():
    scene = meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES, material=MATTE)
    scene.add_light("directional", np.eye(4), intensity=3.0)
    return scene


def covered(mask):
    """The rows and columns `mask` reaches, and the number of its pixels."""
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    return (rows[0], rows[-1] + 1, cols[0], cols[-1] + 1), int((mask > 0).sum())


@pytest.mark.parametrize("projection, rect", [
    # yfov with tan(yfov/2) = 1/2: the view rectangle is 1 m tall at 1 m.
    ({"yfov": 2 * math.atan(0.5)}, (16, 48, 16, 48)),
    # Half extents of 1 m: the quad's 1 m is half the image.
    ({"xmag": 1.0, "ymag": 1.0}, (16, 48, 16, 48)),
    # fx = fy = 64 px: 1 m at 2 m is 32 px; the principal point moves the quad with it.
    ({"fx": 64.0, "fy": 64.0, "cx": 24.0, "cy": 40.0}, (24, 56, 8, 40)),
])
def test_a_unit_quad_fills_its_analytic_pixels(projection, rect):
    scene = quad_scene()
    assert scene.add_camera(translation(0, 0, 2), **projection) == 0
    out = scene.render(64, 64, aovs=("depth", "mask", "segmentation"), **SETTINGS)
    top, bottom, left, right = rect
    expected = np.zeros((64, 64), bool)
    expected[top:bottom, left:right] = True
    full = out["mask"] == 1.0
    assert covered(full) == (rect, 32 * 32)
    np.testing.assert_array_equal(full, expected)
    # A sample that lands exactly on the quad's edge (the edges lie on pixel boundaries) may
    # count for the pixel beside it: never more than one of its samples.
    assert out["mask"][~expected].max() <= 1 / SETTINGS["spp"]
    np.testing.assert_allclose(out["depth"][expected], 2.0, rtol=1e-6)
    assert (out["depth"][~expected] == 0).all()
    np.testing.assert_array_equal(out["segmentation"], expected.astype(np.uint32))
    lit = out["color"][expected][:, :3]
    assert (lit > 0.1).all(), "lit head-on by its directional light"


@pytest.mark.parametrize("projection", [
    # 4 m x 2 m at any distance, on a square image: the picture is squeezed sideways.
    {"xmag": 2.0, "ymag": 1.0},
    # tan(yfov/2) = 1/2 and aspect ratio 2: 2 m x 1 m at 1 m, 4 m x 2 m at the quad's 2 m.
    {"yfov": 2 * math.atan(0.5), "aspect_ratio": 2.0},
])
def test_a_stretched_camera_keeps_its_own_horizontal_extent(projection):
    scene = quad_scene()
    scene.add_camera(translation(0, 0, 2), **projection)
    scene.add_camera(translation(0, 0, 2), stretch=True, **projection)
    plain = scene.render(64, 64, camera=0, aovs=("mask",), **SETTINGS)["mask"] == 1.0
    stretched = scene.render(64, 64, camera=1, aovs=("mask",), **SETTINGS)["mask"] == 1.0
    # By default the image's aspect sets the width: 2 m x 2 m (perspective: 1 m x 1 m at 1 m),
    # the unit quad the middle 32 x 32 pixels.
    assert covered(plain) == ((16, 48, 16, 48), 32 * 32)
    # Stretched: the quad's 1 m is a quarter of the width, half of the height.
    assert covered(stretched) == ((16, 48, 24, 40), 16 * 32)


def test_render_views_of_the_cameras_keeps_their_intrinsics_and_stretch():
    scene = quad_scene()
    scene.add_camera(translation(0, 0, 2), fx=64.0, fy=64.0, cx=24.0, cy=40.0)
    scene.add_camera(translation(0, 0, 2), xmag=2.0, ymag=1.0, stretch=True)
    scene.add_camera(translation(0, 0, 2), yfov=2 * math.atan(0.5))
    views = scene.render_views("cameras", 64, 64, aovs=("mask",), **SETTINGS)
    for i, view in enumerate(views):
        alone = scene.render(64, 64, camera=i, aovs=("mask",), **SETTINGS)
        np.testing.assert_array_equal(view["mask"], alone["mask"])
    assert covered(views[0]["mask"] == 1.0) == ((24, 56, 8, 40), 32 * 32)
    assert covered(views[1]["mask"] == 1.0) == ((16, 48, 24, 40), 16 * 32)


def test_stretch_is_refused_with_intrinsics():
    with pytest.raises(meshtracer.Error, match="camera stretch: intrinsics say the picture"):
        quad_scene().add_camera(np.eye(4), fx=10.0, fy=10.0, cx=1.0, cy=1.0, stretch=True)


def test_meshes_added_later_get_their_own_pose_material_and_id():
    scene = quad_scene()
    red = {"base_color": [1, 0, 0, 1], "metallic": 0.0, "roughness": 1.0}
    assert scene.add_mesh(QUAD, QUAD_TRIANGLES, material=red, pose=translation(0.5, 0, 0.5),
                          name="front") == 1
    scene.add_camera(translation(0, 0, 2), yfov=2 * math.atan(0.5))
    out = scene.render(64, 64, aovs=("depth", "segmentation"), **SETTINGS)
    seg = out["segmentation"]
    # The second quad, half a metre nearer (depth 1.5) and half a metre to the right: its
    # left edge (x = 0) is on the view axis, the image centre.
    assert set(np.unique(seg).tolist()) == {0, 1, 2}
    front = seg == 2
    np.testing.assert_allclose(out["depth"][front], 1.5, rtol=1e-6)
    color = out["color"]
    # Red: green only from the dielectric's white specular reflection (F0 = 0.04).
    assert (color[front][:, 0] > 0.1).all() and (color[front][:, 0] > 5 * color[front][:, 1]).all()
    _, cols = np.nonzero(front)
    assert cols.min() == 32


def test_the_scene_says_what_it_holds():
    scene = quad_scene()
    info = scene.info()
    assert info["format"] == "memory"
    assert scene.warnings == []
    assert "2 triangles" in repr(scene)


@pytest.mark.parametrize("call, message", [
    (lambda: meshtracer.Scene.from_arrays(QUAD[:, :2], QUAD_TRIANGLES),
     "positions: shape (4, 2), expected (N, 3)"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, [[0, 1, 2], [0, 2, 7]]),
     "<arrays>: mesh 0: indices: triangle 1 uses vertex 7, but there are 4 vertices (0 to 3)"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, [[0, 1, 2], [0, -2, 3]]),
     "indices: triangle 1 has a negative index ([0, -2, 3])"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES.ravel()),
     "indices: shape (6,), expected (M, 3): three vertices a triangle"),
    (lambda: meshtracer.Scene.from_arrays(np.where(QUAD == 0.5, np.nan, QUAD), QUAD_TRIANGLES),
     "<arrays>: mesh 0: positions: row 1 is not finite (NaN or infinite)"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES, normals=np.ones((3, 3))),
     "<arrays>: mesh 0: normals: 3 rows, but there are 4 positions (one row a vertex)"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES, material={"roughness": 2}),
     "<arrays>: mesh 0: material: roughness 2: must be from 0 to 1"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES, material={"shiny": 1}),
     "material: unknown key 'shiny'"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES, material={"transmission": 1.5}),
     "<arrays>: mesh 0: material: transmission 1.5: must be from 0 to 1"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES, material={"ior": 0.5}),
     "material: ior 0.5: must be a finite number of at least 1"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES, material={"dispersion": -1}),
     "material: dispersion -1: must be a finite number of at least 0"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES, material={"thickness": -1}),
     "material: thickness -1: must be a finite number of at least 0"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES,
                                          material={"sheen_color": [2, 0, 0]}),
     "material: sheen_color[0] 2: must be from 0 to 1"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES,
                                          material={"diffuse_transmission_color": [1, 2, 1]}),
     "material: diffuse_transmission_color[1] 2: must be from 0 to 1"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES, material={"anisotropy": 1.5}),
     "material: anisotropy 1.5: must be from 0 to 1"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES,
                                          material={"anisotropy_rotation": float("inf")}),
     "material: anisotropy_rotation inf: must be a finite angle in radians"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES, pose=np.diag([0, 0, 0, 1.0])),
     "<arrays>: mesh 0: pose: singular (determinant 0): it flattens the mesh"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES,
                                          pose=[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0],
                                                [2, 0, 0, 1]]),
     "pose: last row [2, 0, 0, 1], expected [0, 0, 0, 1]"),
    (lambda: quad_scene().add_camera([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 0]],
                                     yfov=1.0),
     "pose: last row [0, 0, 1, 0], expected [0, 0, 0, 1]"),
    (lambda: quad_scene().add_light("point", np.full((4, 4), np.nan)),
     "pose: not finite"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, [[0, 0, 1]]),
     "<arrays>: mesh 0: indices: all 1 triangles have zero area or repeat a vertex: nothing to draw"),
    (lambda: quad_scene().add_camera(np.eye(4), yfov=1.0, fx=10.0, fy=10.0, cx=1.0, cy=1.0),
     "a camera is given by yfov"),
    (lambda: quad_scene().add_light("area", np.eye(4)),
     "light kind 'area': use directional, point or spot"),
    (lambda: quad_scene().add_light("point", np.eye(4), intensity=float("nan")),
     "light: intensity NaN must be a finite number of at least 0"),
    (lambda: quad_scene().add_light("point", np.eye(4), range=0.0),
     "light range 0: must be above 0 (or None for no range)"),
    (lambda: quad_scene().add_light("spot", np.eye(4), range=float("nan")),
     "light range NaN: must be above 0"),
    (lambda: quad_scene().render(8, 8, camera=3), "<arrays>: camera 3: the file has 0 camera(s)"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES, colors=np.full((4, 3), 2.0)),
     "<arrays>: mesh 0: colors: row 0: 2 must be from 0 to 1"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES,
                                          colors=[[1, 1, 1], [1, 1, 1], [0, -0.5, 0], [1, 1, 1]]),
     "<arrays>: mesh 0: colors: row 2: -0.5 must be from 0 to 1"),
    (lambda: meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES, colors=np.full((4, 4), np.inf)),
     "<arrays>: mesh 0: colors: row 0 is not finite (NaN or infinite)"),
])
def test_bad_arrays_and_parts_raise_errors_naming_them(call, message):
    with pytest.raises(meshtracer.Error) as caught:
        call()
    assert message in str(caught.value)


# Many views ---------------------------------------------------------------------------------

# uv (0, 0) at the image's top-left (glTF's convention): the quad's top-left corner.
QUAD_UVS = np.array([[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]])
# Rows from the top: red, green / blue, white; each quadrant 2x2 texels, so that bilinear
# filtering near a quadrant's centre blends only texels of its colour.
CHECKER = np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]], np.uint8)
CHECKER = CHECKER.repeat(2, axis=0).repeat(2, axis=1)
UNLIT = {"unlit": True}


def textured_quad(material):
    """The unit quad with `material` and uvs ((0, 0) at its top-left corner), seen head-on by
    an orthographic camera whose view it fills exactly."""
    scene = meshtracer.Scene.empty("<textured>")
    scene.add_mesh(QUAD, QUAD_TRIANGLES, uvs=QUAD_UVS, material=material)
    scene.add_camera(translation(0, 0, 1), xmag=0.5, ymag=0.5)
    return scene


def quadrant_centres(image):
    """The pixels at the centres of the four quadrants: top-left, top-right, bottom-left,
    bottom-right."""
    h, w = image.shape[:2]
    return [image[h // 4, w // 4], image[h // 4, 3 * w // 4],
            image[3 * h // 4, w // 4], image[3 * h // 4, 3 * w // 4]]


@pytest.mark.parametrize("how", ["array", "index", "float", "pil"])
def test_a_texture_lands_where_its_uvs_put_it(how):
    if how == "index":
        scene = meshtracer.Scene.empty("<textured>")
        texture = scene.add_texture(CHECKER, filter="nearest")
        # Two meshes share it: the second, behind the first, is hidden.
        for z in (0.0, -0.5):
            scene.add_mesh(QUAD, QUAD_TRIANGLES, uvs=QUAD_UVS, pose=translation(0, 0, z),
                           material={**UNLIT, "base_color_texture": texture})
        scene.add_camera(translation(0, 0, 1), xmag=0.5, ymag=0.5)
    else:
        image = {"array": CHECKER, "float": CHECKER / 255.0}.get(how)
        if how == "pil":
            Image = pytest.importorskip("PIL.Image")
            image = Image.fromarray(CHECKER)
        scene = textured_quad({**UNLIT, "base_color_texture": image})
    out = scene.render(32, 32, spp=1, integrator="direct", seed=0, tonemap="standard",
                       srgb8=True)
    # 8-bit sRGB in, linear 0 or 1 out: each quadrant is its texel exactly.
    expected = [[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255], [255, 255, 255, 255]]
    assert [q.tolist() for q in quadrant_centres(out["srgb8"])] == expected
    np.testing.assert_array_equal(quadrant_centres(out["color"]),
                                  np.array(expected, np.float32) / 255.0)


# A black emitter's face: radiance (1, 1, 1) from both sides, nothing reflected.
WHITE_LIGHT = {"base_color": [0, 0, 0], "metallic": 0.0, "emissive": [1, 1, 1],
               "double_sided": True}


def seen_head_on(material, behind=None):
    """The mean linear colour of a 1 m quad of `material` seen head-on (orthographic, the
    middle 0.5 m), path traced with no light but a 4 m white emitter 1 m behind the camera,
    facing the quad (so the quad's reflectance at normal incidence is what comes back), and
    `behind`, a material for a second 4 m quad 1 m behind the first."""
    scene = meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES, uvs=QUAD_UVS, material=material)
    scene.add_mesh(QUAD * 4, QUAD_TRIANGLES, pose=translation(0, 0, 3), material=WHITE_LIGHT)
    if behind is not None:
        scene.add_mesh(QUAD * 4, QUAD_TRIANGLES, pose=translation(0, 0, -1), material=behind)
    scene.add_camera(translation(0, 0, 2), xmag=0.25, ymag=0.25)
    out = scene.render(8, 8, spp=16, integrator="path", seed=0, tonemap="standard",
                       default_lights=False, ambient=[0.0, 0.0, 0.0])
    return out["color"][..., :3].mean(axis=(0, 1))


@pytest.mark.parametrize("extensions, reflectance", [
    # A smooth black dielectric reflects Fresnel's F0 = ((ior - 1) / (ior + 1))^2 at normal
    # incidence: 0.04 at glTF's default ior 1.5, 1/9 at 2 (KHR_materials_ior).
    ({}, [0.04] * 3),
    ({"ior": 2.0}, [1 / 9] * 3),
    # KHR_materials_specular: its factor scales the dielectric's reflection (0: none), its
    # colour tints F0.
    ({"specular": 0.0}, [0.0] * 3),
    ({"specular_color": [1.0, 0.0, 0.5]}, [0.04, 0.0, 0.02]),
    # KHR_materials_clearcoat: a smooth coat (its ior fixed at 1.5) over a base that reflects
    # nothing.
    ({"specular": 0.0, "clearcoat": 1.0}, [0.04] * 3),
])
def test_extension_factors_set_the_reflectance_at_normal_incidence(extensions, reflectance):
    black = {"base_color": [0, 0, 0], "metallic": 0.0, "roughness": 0.0, **extensions}
    # Within 3% of F0 (a mirror sampled per pixel: no noise to speak of), 1e-4 absolute for 0.
    np.testing.assert_allclose(seen_head_on(black), reflectance, rtol=0.03, atol=1e-4)


@pytest.mark.parametrize("texel, reflectance", [(0, 0.0), (255, 0.04)])
def test_an_extension_texture_scales_its_factor(texel, reflectance):
    """KHR_materials_clearcoat: the coat's weight is its factor times the texture's red
    channel, here 0 or 1 all over."""
    black = {"base_color": [0, 0, 0], "metallic": 0.0, "roughness": 0.0, "specular": 0.0,
             "clearcoat": 1.0, "clearcoat_texture": np.full((2, 2), texel, np.uint8)}
    np.testing.assert_allclose(seen_head_on(black), [reflectance] * 3, rtol=0.03, atol=1e-4)


def test_anisotropy_stretches_the_lobe_only_where_its_strength_is_above_0():
    """KHR_materials_anisotropy from the material dict: strength 0 is the isotropic lobe,
    pixel for pixel; strength 0.9 (along the tangent, which MikkTSpace gives from the uvs)
    widens a rough metal's lobe along it, so less of the emitter behind the camera comes back
    head-on; the same strength turned by 90 degrees or by a texture comes back alike."""
    metal = {"base_color": [1, 1, 1], "metallic": 1.0, "roughness": 0.3}
    plain = seen_head_on(metal)
    np.testing.assert_array_equal(seen_head_on({**metal, "anisotropy": 0.0}), plain)
    stretched = seen_head_on({**metal, "anisotropy": 0.9})
    assert stretched[0] < 0.95 * plain[0], (stretched, plain)
    turned = seen_head_on({**metal, "anisotropy": 0.9, "anisotropy_rotation": np.pi / 2})
    np.testing.assert_allclose(turned, stretched, rtol=0.02)
    # Red-green (0.5, 1) is +bitangent: the same turn as the rotation.
    texel = np.array([[[128, 255, 255]]], np.uint8)
    textured = seen_head_on({**metal, "anisotropy": 0.9, "anisotropy_texture": texel})
    np.testing.assert_allclose(textured, turned, rtol=0.02)


@pytest.mark.parametrize("texel", [None, 255, 0])
def test_diffuse_transmission_lets_the_light_behind_a_wall_through(texel):
    """KHR_materials_diffuse_transmission from the material dict: a wall that reflects
    nothing (black base, specular 0) in front of a red emitter lets through weight x colour
    of its light diffusely: seen head-on, the red emitter (a 4 m quad 1 m behind) fills most
    of the wall's far hemisphere, so the wall shows about 0.5 x 0.9 of its red, and nothing
    where the texture's alpha makes the weight 0."""
    wall = {"base_color": [0, 0, 0], "metallic": 0.0, "specular": 0.0,
            "diffuse_transmission": 0.5, "diffuse_transmission_color": [1.0, 0.5, 0.5],
            "double_sided": True}
    if texel is not None:
        wall["diffuse_transmission_texture"] = np.full((2, 2, 4), texel, np.uint8)
    red = {"base_color": [0, 0, 0], "metallic": 0.0, "emissive": [1, 0, 0],
           "double_sided": True}
    seen = seen_head_on(wall, behind=red)
    if texel == 0:
        np.testing.assert_allclose(seen[0], 0.0, atol=1e-4)
    else:
        # The emitter covers cos-weighted 1 - 1/(1 + 4) = 0.8 of the far hemisphere (a disc
        # of radius 2 at 1 m); the square, a little more: between 0.8 and 0.9 of 0.5.
        assert 0.38 < seen[0] < 0.46, seen
    assert seen[1] < 1e-3 and seen[2] < 1e-3, seen


@pytest.mark.parametrize("transmission", [1.0, 0.5, 0.0])
def test_a_clear_sheet_shows_what_is_behind_it_by_its_transmission(transmission):
    """KHR_materials_transmission on a thin wall (thickness 0, the default): a smooth white
    sheet in front of a red emitter lets through transmission x (1 - F0) of its light
    straight, and hides it without. The white emitter behind the camera lights the sheet's
    front (its diffuse part, 1 - transmission, and its reflection) in every channel alike, so
    what the red emitter adds is red minus green."""
    sheet = {"base_color": [1, 1, 1], "metallic": 0.0, "roughness": 0.0,
             "transmission": transmission, "double_sided": True}
    red = {"base_color": [0, 0, 0], "metallic": 0.0, "emissive": [1, 0, 0],
           "double_sided": True}
    seen = seen_head_on(sheet, behind=red)
    assert seen[1] == seen[2]
    # Measured 0.960, 0.483 and 0.001 of the red emitter's 1 for 0.96, 0.48 and 0.
    assert seen[0] - seen[1] == pytest.approx(0.96 * transmission, abs=0.015)


@pytest.mark.parametrize("transform, top_row", [
    # KHR_texture_transform, uv' = offset + rotation(scale * uv), the sampler repeating: the
    # checker (red, green / blue, white) twice across the quad, or shifted by half its width.
    ({"scale": (2, 2)}, ["red", "green", "red", "green"]),
    ({"offset": (0.5, 0.0)}, ["green", "green", "red", "red"]),
    ({}, ["red", "red", "green", "green"]),
])
def test_a_texture_transform_moves_the_texture(transform, top_row):
    colours = {"red": [255, 0, 0, 255], "green": [0, 255, 0, 255]}
    scene = meshtracer.Scene.empty("<transformed>")
    # Nearest texels: the columns below fall near texel edges once scaled.
    texture = scene.add_texture(CHECKER, filter="nearest")
    scene.add_mesh(QUAD, QUAD_TRIANGLES, uvs=QUAD_UVS,
                   material={**UNLIT, "base_color_texture": {"texture": texture, **transform}})
    scene.add_camera(translation(0, 0, 1), xmag=0.5, ymag=0.5)
    out = scene.render(32, 32, spp=1, integrator="direct", seed=0, tonemap="standard",
                       srgb8=True)
    # Pixel columns 4, 12, 20, 28 of row 4: u = 0.14, 0.39, 0.64, 0.89 and v = 0.14.
    assert [out["srgb8"][4, x].tolist() for x in (4, 12, 20, 28)] == [colours[c] for c in top_row]


@pytest.mark.parametrize("tex_coord, top_row", [
    # The checker read through uvs (as it is) or through uvs1 (u mirrored): red, green on
    # its top row, or green, red.
    (0, ["red", "red", "green", "green"]),
    (1, ["green", "green", "red", "red"]),
])
def test_a_texture_reads_the_uv_set_it_names(tex_coord, top_row):
    colours = {"red": [255, 0, 0, 255], "green": [0, 255, 0, 255]}
    scene = meshtracer.Scene.empty("<two sets>")
    texture = scene.add_texture(CHECKER, filter="nearest")
    mirrored = np.array(QUAD_UVS, np.float32) * [-1, 1] + [1, 0]
    scene.add_mesh(QUAD, QUAD_TRIANGLES, uvs=QUAD_UVS, uvs1=mirrored,
                   material={**UNLIT, "base_color_texture": {"texture": texture,
                                                             "tex_coord": tex_coord}})
    scene.add_camera(translation(0, 0, 1), xmag=0.5, ymag=0.5)
    out = scene.render(32, 32, spp=1, integrator="direct", seed=0, tonemap="standard",
                       srgb8=True)
    assert [out["srgb8"][4, x].tolist() for x in (4, 12, 20, 28)] == [colours[c] for c in top_row]


def test_a_texture_on_the_second_uv_set_needs_it():
    scene = meshtracer.Scene.empty("<one set>")
    texture = scene.add_texture(CHECKER)
    with pytest.raises(meshtracer.Error, match="uvs1: missing"):
        scene.add_mesh(QUAD, QUAD_TRIANGLES, uvs=QUAD_UVS,
                       material={"base_color_texture": {"texture": texture, "tex_coord": 1}})
    with pytest.raises(meshtracer.Error, match="reads texture coordinate set 2"):
        scene.add_mesh(QUAD, QUAD_TRIANGLES, uvs=QUAD_UVS, uvs1=QUAD_UVS,
                       material={"base_color_texture": {"texture": texture, "tex_coord": 2}})


def test_grey_textures_are_srgb_for_colour_and_linear_for_data():
    grey = np.full((1, 1), 128, np.uint8)
    colour = textured_quad({**UNLIT, "base_color_texture": grey})
    out = colour.render(8, 8, spp=1, integrator="direct", tonemap="standard")
    # glTF: a base colour texture holds sRGB-encoded values; 128/255 is 0.2158605 linear.
    srgb = 128 / 255
    linear = ((srgb + 0.055) / 1.055) ** 2.4
    np.testing.assert_allclose(out["color"][4, 4, :3], linear, rtol=1e-5)
    # Grey and alpha: the alpha channel is the texture's second.
    blend = textured_quad({**UNLIT, "alpha_mode": "BLEND",
                           "base_color_texture": np.dstack([grey, np.zeros_like(grey)])})
    out = blend.render(8, 8, spp=4, integrator="direct", tonemap="standard", aovs=("mask",))
    assert out["mask"].max() == 0.0, "alpha 0 everywhere: nothing is seen"


def test_a_normal_map_turns_the_surface_toward_its_light():
    """A constant tangent-space normal map on a quad facing +Z whose uvs run with x and -y:
    tangents (generated, MikkTSpace) point along +x, so a map of (±0.71, 0, 0.71) turns the
    normal toward or away from a directional light shining from 45 degrees on the +x side."""
    c = np.cos(np.pi / 4)
    light = np.array([[c, 0, c, 0], [0, 1, 0, 0], [-c, 0, c, 0], [0, 0, 0, 1.0]])  # from +x+z

    def lit(normal_map):
        material = {**MATTE}
        if normal_map is not None:
            material["normal_texture"] = np.full((2, 2, 3), normal_map, np.uint8)
        scene = textured_quad(material)
        scene.add_light("directional", light, intensity=3.0)
        out = scene.render(8, 8, spp=1, integrator="direct", tonemap="standard",
                           ambient=[0.0, 0.0, 0.0])
        return float(out["color"][4, 4, 0])

    flat, up = lit(None), lit([128, 128, 255])
    toward, away = lit([218, 128, 218]), lit([38, 128, 218])
    assert up == pytest.approx(flat, rel=0.02), "an untilted map changes nothing"
    # Lambert: cos 45° flat, cos 0° turned toward the light, 90° turned away.
    assert toward == pytest.approx(flat / c, rel=0.05)
    assert away < 0.02 * flat


@pytest.mark.parametrize("call, message", [
    (lambda s: s.add_texture(np.zeros((2, 2, 5), np.uint8)),
     "texture: shape (2, 2, 5), expected (H, W) or (H, W, C) with C from 1 to 4"),
    (lambda s: s.add_texture(np.full((2, 2), 1.5)),
     "texture: float values must be finite and from 0 to 1"),
    (lambda s: s.add_texture(np.full((2, 2), 300)),
     "texture: integer values must be from 0 to 255"),
    (lambda s: s.add_texture(np.zeros((0, 4), np.uint8)),
     "<t>: texture 0: 4x0 pixels: an image needs at least one"),
    (lambda s: s.add_texture(CHECKER, wrap="tile"),
     "wrap_s 'tile': use repeat, clamp_to_edge or mirrored_repeat"),
    (lambda s: s.add_texture(CHECKER, filter=("linear", "cubic")),
     "min_filter 'cubic': use linear or nearest"),
    (lambda s: s.add_mesh(QUAD, QUAD_TRIANGLES, material={"emissive_texture": CHECKER}),
     "<t>: mesh 0: uvs: missing: the material has textures, which are placed by the uvs"),
    (lambda s: s.add_mesh(QUAD, QUAD_TRIANGLES, uvs=QUAD_UVS, material={"normal_texture": 4}),
     "<t>: mesh 0: material: texture 4 does not exist (the scene has 0"),
    (lambda s: s.add_mesh(QUAD, QUAD_TRIANGLES, uvs=QUAD_UVS, material={"normal_texture": "x"}),
     "material: normal_texture: texture: shape (), expected (H, W)"),
    (lambda s: s.add_mesh(QUAD, QUAD_TRIANGLES, material={"normal_scale": float("nan")}),
     "<t>: mesh 0: material: normal_scale NaN: must be a finite number"),
    (lambda s: s.add_mesh(QUAD, QUAD_TRIANGLES, material={"occlusion_strength": 5}),
     "<t>: mesh 0: material: occlusion_strength 5: must be from 0 to 1"),
    (lambda s: s.add_mesh(QUAD, QUAD_TRIANGLES, uvs=QUAD_UVS,
                          material={"base_color_texture": {"texture": CHECKER, "tilt": 1}}),
     "material: base_color_texture: unknown key 'tilt': use texture, tex_coord, offset, scale, rotation"),
    (lambda s: s.add_mesh(QUAD, QUAD_TRIANGLES, uvs=QUAD_UVS,
                          material={"base_color_texture": {"scale": (2, 2)}}),
     "material: base_color_texture: a dict needs 'texture'"),
    (lambda s: s.add_mesh(QUAD, QUAD_TRIANGLES, uvs=QUAD_UVS,
                          material={"base_color_texture": {"texture": CHECKER,
                                                           "rotation": float("inf")}}),
     "<t>: mesh 0: material: texture 0: transform offset [0.0, 0.0], rotation inf, "
     "scale [1.0, 1.0]: must be finite numbers"),
])
def test_bad_textures_raise_errors_naming_them(call, message):
    with pytest.raises(meshtracer.Error) as e:
        call(meshtracer.Scene.empty("<t>"))
    assert message in str(e.value)


def test_render_views_equals_one_render_per_view():
    """Views rendered together (one preparation) are the views rendered one by one."""
    scene = meshtracer.load(CORNELL)
    views = [{"look_from": [0, 1, 3.5], "look_at": [0, 1, 0]},
             {"look_from": [1.5, 1.2, 3], "look_at": [0, 1, 0], "yfov_degrees": 50}]
    together = scene.render_views(views, 40, 30, aovs=("depth", "mask"), **SETTINGS)
    assert len(together) == 2
    for view, out in zip(views, together):
        single = meshtracer.load(CORNELL)
        pose = out["camera_to_world"]
        np.testing.assert_allclose(pose[:3, 3], view["look_from"], atol=1e-6)
        single.clear_cameras()
        single.add_camera(pose, yfov=math.radians(view.get("yfov_degrees", 45)), znear=0.05)
        alone = single.render(40, 30, aovs=("depth", "mask"), **SETTINGS)
        assert out["intrinsics"][2:] == [20.0, 15.0]
        np.testing.assert_array_equal(out["mask"], alone["mask"])
        np.testing.assert_allclose(out["depth"], alone["depth"], rtol=1e-5)


def test_render_views_orbit_gives_n_views_around_the_model(cli, tmp_path):
    scene = meshtracer.load(CORNELL)
    out = scene.render_views("orbit:3", 48, 36, srgb8=True, **SETTINGS)
    cli("render", CORNELL, "--views", "orbit:3", "-o", tmp_path, "--width", 48, "--height", 36,
        "--spp", 4, "--integrator", "direct", "--seed", 0, "--tonemap", "standard", "--quiet")
    from PIL import Image
    pngs = sorted(tmp_path.glob("*.png"))
    assert len(pngs) == 3, pngs
    for view, png in zip(out, pngs):
        with Image.open(png) as image:
            np.testing.assert_array_equal(view["srgb8"], np.asarray(image.convert("RGBA")))


def test_views_through_a_thin_lens_are_the_clis(cli, tmp_path):
    # Each view focused at its distance to the scene's centre, as `--views --aperture-radius`.
    out = meshtracer.load(CORNELL).render_views("orbit:2", 48, 36, srgb8=True,
                                                aperture_radius=0.2, **SETTINGS)
    cli("render", CORNELL, "--views", "orbit:2", "-o", tmp_path, "--width", 48, "--height", 36,
        "--spp", 4, "--integrator", "direct", "--seed", 0, "--tonemap", "standard", "--quiet",
        "--aperture-radius", 0.2)
    from PIL import Image
    pngs = sorted(tmp_path.glob("*.png"))
    assert len(pngs) == 2, pngs
    for view, png in zip(out, pngs):
        with Image.open(png) as image:
            np.testing.assert_array_equal(view["srgb8"], np.asarray(image.convert("RGBA")))


def test_denoised_views_are_the_clis(cli, tmp_path):
    # The default sampling with denoise=True: each view adaptive and denoised, as
    # `render --views --denoise` makes it.
    out = meshtracer.load(CORNELL).render_views("orbit:2", 48, 36, srgb8=True, denoise=True)
    cli("render", CORNELL, "--views", "orbit:2", "-o", tmp_path, "--width", 48, "--height", 36,
        "--denoise", "--quiet")
    from PIL import Image
    pngs = sorted(tmp_path.glob("*.png"))
    assert len(pngs) == 2, pngs
    for view, png in zip(out, pngs):
        assert view["stats"]["denoise_seconds"] is not None
        with Image.open(png) as image:
            np.testing.assert_array_equal(view["srgb8"], np.asarray(image.convert("RGBA")))


@pytest.mark.parametrize("spec, options, message", [
    ("orbit:2", {"yfov": float("nan")}, "yfov NaN: must be between 0 and 180 degrees"),
    ("orbit:2", {"yfov": 0}, "yfov 0: must be between 0 and 180 degrees"),
    ("orbit:2", {"yfov": -10}, "yfov -10: must be between 0 and 180 degrees"),
    ("orbit:2", {"orbit_radius": -1}, "orbit_radius -1: must be a positive distance"),
    ("orbit:2", {"orbit_radius": float("nan")}, "orbit_radius NaN: must be a positive distance"),
    ("orbit:2", {"look_at": [float("nan"), 0, 0]}, "look_at [NaN, 0, 0]: must be three finite numbers"),
    ("orbit:2", {"orbit_elevation": 1000}, "orbit_elevation 1000: must be between -90 and 90 degrees"),
    ("orbit:2", {"orbit_azimuth": float("inf")}, "orbit_azimuth inf: must be a finite number of degrees"),
    ("sphere:2", {"orbit_azimuth": 10}, "orbit_azimuth: only orbits"),
])
def test_bad_orbit_options_are_refused_as_the_cli_refuses_them(spec, options, message):
    with pytest.raises(meshtracer.Error) as caught:
        quad_scene().render_views(spec, 8, 8, spp=1, **options)
    assert message in str(caught.value)


def test_bad_view_specs_raise_the_clis_message():
    scene = meshtracer.load(CORNELL)
    with pytest.raises(meshtracer.Error, match="--views orbit:0: the number of views must be at least 1"):
        scene.render_views("orbit:0", 8, 8)
    with pytest.raises(meshtracer.Error, match="--views cameras: the file has no cameras"):
        quad_scene().render_views("cameras", 8, 8)


# Progress and cancelling --------------------------------------------------------------------

def test_progress_counts_rise_to_the_total():
    scene = meshtracer.load(CORNELL)
    calls = []
    scene.render(256, 192, progress=lambda done, total: calls.append((done, total)), **SETTINGS)
    assert calls, "the callable was called"
    done = [d for d, _ in calls]
    totals = {t for _, t in calls}
    assert done == sorted(set(done)), "strictly increasing"
    assert len(totals) == 1 and done[-1] == totals.pop()


def test_progress_of_many_views_counts_over_all_of_them():
    calls = []
    meshtracer.load(CORNELL).render_views(
        "orbit:3", 64, 48, progress=lambda d, t: calls.append((d, t)), **SETTINGS)
    total = calls[-1][1]
    assert calls[-1][0] == total and total % 3 == 0


@pytest.mark.parametrize("exception", [ValueError, KeyboardInterrupt])
def test_an_exception_in_the_callback_cancels_and_propagates(exception):
    scene = meshtracer.load(CORNELL)
    calls = []

    def stop(done, total):
        calls.append(done)
        raise exception("stop here")

    with pytest.raises(exception, match="stop here"):
        scene.render(320, 240, spp=64, integrator="direct", progress=stop)
    assert len(calls) == 1, "no call after the exception"
    # The scene is intact: it renders again.
    again = scene.render(16, 12, **SETTINGS)
    assert again["color"].shape == (12, 16, 4)


def test_integer_colours_are_normalized_as_gltf_reads_them():
    """uint8 and uint16 colours (trimesh's ``visual.vertex_colors`` are uint8 RGBA) are read as
    glTF reads normalized integers, 255 or 65535 = 1: the same picture as the floats."""
    floats = np.array([[1.0, 0.5, 0.2], [1.0, 0.5, 0.2], [0.2, 0.5, 1.0], [0.2, 0.5, 1.0]])

    def render(colors):
        scene = meshtracer.Scene.from_arrays(QUAD, QUAD_TRIANGLES, colors=colors, material=MATTE)
        scene.add_light("directional", np.eye(4), intensity=3.0)
        return scene.render(16, 16, spp=1, integrator="direct", default_lights=False)["color"]

    reference = render(np.round(floats * 255) / 255)
    rgba8 = np.concatenate([np.round(floats * 255), np.full((4, 1), 255)], axis=1).astype(np.uint8)
    assert np.allclose(render(rgba8), reference, atol=1e-6)
    rgb16 = np.round(np.round(floats * 255) / 255 * 65535).astype(np.uint16)
    assert np.allclose(render(rgb16), reference, atol=1e-5)
    # A quad whose colours were ignored would be grey: it shades from orange to blue.
    seen = reference[reference[:, :, 3] > 0]
    assert (seen[:, 0] > 2 * seen[:, 2]).any() and (seen[:, 2] > 2 * seen[:, 0]).any()
