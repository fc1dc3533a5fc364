"""The pyrender front against pyrender itself (OSMesa, no GPU): one scene built with pyrender's
own classes, rendered by both; depth must agree within 0.5% where both hit, and what each
covers must overlap with an IoU of at least 0.99.

It needs pyrender (installed from PyPI by scripts/reference/install_pyrender.sh, whose venv
scripts/test-python.sh installs the meshtracer wheel into and runs this file with); without it
the test skips saying why.
"""

import os

import numpy as np
import pytest

os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")
try:
    import pyrender
    import trimesh
except Exception as e:  # ImportError, or OpenGL failing to find OSMesa
    pytest.skip(f"SKIPPED: pyrender cannot be imported here ({type(e).__name__}: {e}); "
                "scripts/test-python.sh runs this file in MESHTRACER_PYRENDER_PYTHON's "
                "environment", allow_module_level=True)

import meshtracer
import meshtracer.pyrender as front

WIDTH, HEIGHT = 320, 240


def look_at(eye, target, up=(0.0, 1.0, 0.0)):
    """The world-from-camera pose of a camera at `eye` looking at `target` (local -Z)."""
    eye, target, up = (np.asarray(v, float) for v in (eye, target, up))
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross(up, back)
    right /= np.linalg.norm(right)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = right, np.cross(back, right), back, eye
    return pose


def orthographic_z(returned, znear, zfar):
    """pyrender 0.1.45 linearises every depth buffer with the perspective formula
    d = 2·n·f / (f + n - z_ndc·(f - n)), also for an orthographic camera, whose buffer is
    linear in z: undone here, z = f + n - n·f/d is the camera-space depth it stands for."""
    hit = returned > 0
    out = np.zeros_like(returned)
    out[hit] = zfar + znear - znear * zfar / returned[hit].astype(np.float64)
    return out


def render_both(scene, width, height, flags):
    """`scene` rendered by pyrender and by the front (4 spp) with `flags` (the same names in
    both): ((colour, depth) of pyrender, (colour, depth) of the front)."""
    reference = pyrender.OffscreenRenderer(width, height)
    try:
        theirs = reference.render(scene, flags=getattr(pyrender.RenderFlags, flags))
    finally:
        reference.delete()
    ours = front.OffscreenRenderer(width, height, spp=4).render(
        scene, flags=getattr(front.RenderFlags, flags))
    return theirs, ours


def build_scene(camera):
    scene = pyrender.Scene(bg_color=[0.0, 0.0, 0.0, 0.0], ambient_light=[0.1, 0.1, 0.1])
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    box = trimesh.creation.box(extents=[0.7, 0.5, 0.9])
    red = pyrender.MetallicRoughnessMaterial(baseColorFactor=[0.8, 0.2, 0.2, 1.0],
                                             metallicFactor=0.0, roughnessFactor=0.7)
    scene.add(pyrender.Mesh.from_trimesh(sphere, material=red),
              pose=np.array([[1, 0, 0, -0.55], [0, 1, 0, 0.1], [0, 0, 1, 0], [0, 0, 0, 1.0]]))
    turned = trimesh.transformations.rotation_matrix(0.6, [0, 1, 0])
    turned[:3, 3] = [0.5, -0.1, -0.2]
    scene.add(pyrender.Mesh.from_trimesh(box, smooth=False), pose=turned)
    scene.add(camera, pose=look_at([0.4, 0.9, 2.6], [0.0, 0.0, 0.0]))
    scene.add(pyrender.DirectionalLight(color=[1.0, 1.0, 1.0], intensity=3.0),
              pose=look_at([1.0, 2.0, 1.5], [0.0, 0.0, 0.0]))
    return scene


@pytest.mark.parametrize("camera", [
    pyrender.PerspectiveCamera(yfov=np.pi / 3.0),
    pyrender.PerspectiveCamera(yfov=np.pi / 4.0, znear=0.1, zfar=20.0),
    pyrender.PerspectiveCamera(yfov=np.pi / 3.0, aspectRatio=1.0),
    pyrender.IntrinsicsCamera(fx=300.0, fy=300.0, cx=150.0, cy=130.0),
    pyrender.OrthographicCamera(xmag=1.2 * WIDTH / HEIGHT, ymag=1.2),
    pyrender.OrthographicCamera(xmag=1.2, ymag=1.2),  # pyrender sets xmag from the viewport
], ids=["perspective", "perspective-zfar", "perspective-stretched", "intrinsics", "orthographic",
        "orthographic-square-xmag"])
def test_depth_and_coverage_match_pyrender(camera):
    scene = build_scene(camera)
    (ref_color, ref_depth), (color, depth) = render_both(scene, WIDTH, HEIGHT, "RGBA")
    if isinstance(camera, pyrender.OrthographicCamera):
        ref_depth = orthographic_z(ref_depth, camera.znear, camera.zfar)

    assert color.dtype == np.uint8 and color.shape == (HEIGHT, WIDTH, 4)
    assert depth.dtype == np.float32 and depth.shape == (HEIGHT, WIDTH)
    hit, ref_hit = depth > 0, ref_depth > 0
    iou = (hit & ref_hit).sum() / (hit | ref_hit).sum()
    print(f"{camera}: IoU {iou:.4f}, {ref_hit.sum()} pixels covered by pyrender")
    assert ref_hit.sum() > 0.1 * WIDTH * HEIGHT, "the objects are in view"
    assert iou >= 0.99, iou
    both = hit & ref_hit
    relative = np.abs(depth[both] - ref_depth[both]) / ref_depth[both]
    print(f"relative depth difference: max {relative.max():.2e}, "
          f"99.9th percentile {np.quantile(relative, 0.999):.2e}")
    assert relative.max() <= 0.005, relative.max()
    # The colour is a picture of the same scene: where pyrender sees the red sphere lit, so
    # does the front (red above green), and the background is bg_color's transparent black.
    # (Edge pixels whose centre misses may still be partly covered: anti-aliased colour.)
    assert (color[~hit] == 0).all(axis=-1).mean() > 0.97
    lit = both & (ref_color[..., 0] > ref_color[..., 1] + 40)
    assert lit.sum() > 1000
    assert (color[lit][:, 0] > color[lit][:, 1]).mean() > 0.99


def test_depth_only_and_flags():
    scene = build_scene(pyrender.PerspectiveCamera(yfov=np.pi / 3.0))
    renderer = front.OffscreenRenderer(64, 48)
    depth = renderer.render(scene, flags=front.RenderFlags.DEPTH_ONLY)
    assert depth.shape == (48, 64) and depth.dtype == np.float32 and (depth > 0).any()
    color, _ = renderer.render(scene, flags=pyrender.RenderFlags.SHADOWS_DIRECTIONAL)
    assert color.shape == (48, 64, 3)
    with pytest.raises(meshtracer.Error, match="ALL_WIREFRAME: wireframes are not drawn"):
        renderer.render(scene, flags=front.RenderFlags.ALL_WIREFRAME)
    nodes = list(scene.mesh_nodes)
    seg, _ = renderer.render(scene, flags=front.RenderFlags.SEG,
                             seg_node_map={nodes[0]: (255, 0, 0), nodes[1]: (0, 0, 255)})
    colours = {tuple(c) for c in seg.reshape(-1, 3)}
    assert colours == {(0, 0, 0), (255, 0, 0), (0, 0, 255)}


def test_textures_land_where_pyrender_puts_them():
    """A trimesh quad with a texture (trimesh's and pyrender's uvs have v up, glTF's down),
    shown flat by both renderers: each quadrant is its texel's colour in both, and the front
    uses the texture's own sampler (nearest here: the texel edges stay sharp)."""
    from PIL import Image

    # Rows from the top: red, green / blue, white, each quadrant 2x2 texels.
    checker = np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]], np.uint8)
    checker = checker.repeat(2, axis=0).repeat(2, axis=1)
    vertices = [[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.5, 0.5, 0.0], [-0.5, 0.5, 0.0]]
    uv = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
    visual = trimesh.visual.TextureVisuals(uv=uv, image=Image.fromarray(checker))
    quad = trimesh.Trimesh(vertices, [[0, 1, 2], [0, 2, 3]], visual=visual, process=False)
    mesh = pyrender.Mesh.from_trimesh(quad)
    material = mesh.primitives[0].material
    texture = material.baseColorTexture
    assert texture is not None, "pyrender took the trimesh texture"
    # trimesh's material has a grey diffuse factor (0.4), which the renderers would carry
    # through different transfer functions (pyrender's flat shader writes linear values).
    material.baseColorFactor = [1.0, 1.0, 1.0, 1.0]
    texture.sampler = pyrender.Sampler(magFilter=9728, minFilter=9728)  # GL_NEAREST
    scene = pyrender.Scene(bg_color=[0.0, 0.0, 0.0, 0.0])
    scene.add(mesh)
    scene.add(pyrender.OrthographicCamera(xmag=0.5, ymag=0.5), pose=look_at([0, 0, 1], [0, 0, 0]))
    size = 64
    (ref_color, _), (color, _) = render_both(scene, size, size, "FLAT")
    quadrants = [(size // 4, size // 4), (size // 4, 3 * size // 4),
                 (3 * size // 4, size // 4), (3 * size // 4, 3 * size // 4)]
    expected = [[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255]]
    assert [ref_color[p].tolist() for p in quadrants] == expected, "pyrender's own picture"
    assert [color[p].tolist() for p in quadrants] == expected
    # Nearest filtering: the pixels either side of the quad's middle are already the next
    # quadrant's colour.
    middle = size // 2
    assert color[size // 4, middle - 1].tolist() == [255, 0, 0]
    assert color[size // 4, middle].tolist() == [0, 255, 0]


def test_seg_draws_the_mapped_nodes_alone_as_pyrender():
    """With ``SEG``, pyrender draws only the nodes in ``seg_node_map`` (an unmapped node in
    front hides nothing, and the depth leaves it out), a number standing for its grey: the
    front's masks and depth agree with pyrender's, and with an empty map both are empty."""
    scene = build_scene(pyrender.PerspectiveCamera(yfov=np.pi / 3.0))
    sphere, box = sorted(scene.mesh_nodes, key=lambda n: len(n.mesh.primitives[0].positions),
                         reverse=True)
    # The box in front of the sphere, half hiding it.
    scene.set_pose(box, np.array([[1, 0, 0, -0.3], [0, 1, 0, 0.1], [0, 0, 1, 0.6],
                                  [0, 0, 0, 1.0]]))
    reference = pyrender.OffscreenRenderer(WIDTH, HEIGHT)
    try:
        theirs = reference.render(scene, flags=pyrender.RenderFlags.SEG,
                                  seg_node_map={sphere: 200})
        all_in = reference.render(scene, flags=pyrender.RenderFlags.SEG,
                                  seg_node_map={sphere: 200, box: (0, 0, 255)})
    finally:
        reference.delete()
    renderer = front.OffscreenRenderer(WIDTH, HEIGHT)
    ours = renderer.render(scene, flags=front.RenderFlags.SEG, seg_node_map={sphere: 200})
    (ref_color, ref_depth), (color, depth) = theirs, ours
    assert {tuple(c) for c in color.reshape(-1, 3)} == {(0, 0, 0), (200, 200, 200)}
    mask, ref_mask = color[..., 0] == 200, ref_color[..., 0] == 200
    iou = (mask & ref_mask).sum() / (mask | ref_mask).sum()
    assert iou >= 0.99, iou
    # The depth is the mapped node's alone, in both.
    assert ((depth > 0) == mask).all()
    assert ((ref_depth > 0) == ref_mask).mean() > 0.99
    # The sphere drawn whole: more of it than when the box, mapped too, hides part.
    hidden = (all_in[0][..., 0] == 200).sum()
    assert (ours[0][..., 0] == 200).sum() > 1.1 * hidden > 0
    color, depth = renderer.render(scene, flags=front.RenderFlags.SEG, seg_node_map={})
    assert not color.any() and not depth.any()


def test_hidden_meshes_are_not_drawn():
    """`Mesh.is_visible = False` draws nothing, as pyrender: the depth sees only the other
    mesh, and with every mesh hidden the picture is the background."""
    scene = build_scene(pyrender.PerspectiveCamera(yfov=np.pi / 3.0))
    renderer = front.OffscreenRenderer(64, 48, spp=1)
    both = renderer.render(scene, flags=front.RenderFlags.DEPTH_ONLY)
    sphere, box = sorted(scene.mesh_nodes, key=lambda n: len(n.mesh.primitives[0].positions),
                         reverse=True)
    sphere.mesh.is_visible = False
    box_only = renderer.render(scene, flags=front.RenderFlags.DEPTH_ONLY)
    assert 0 < (box_only > 0).sum() < (both > 0).sum()
    box.mesh.is_visible = False
    color, depth = renderer.render(scene)
    assert not (depth > 0).any() and not color.any()


def test_a_material_or_vertex_edit_between_renders_is_drawn():
    """The scene kept between renders is built again when a material factor or a vertex
    array changed in place (its key once held only ids and poses), and reused otherwise. Reuse
    is checked as the same built scene object, not by timing the renders (a busy machine made
    the timed form fail)."""
    scene = build_scene(pyrender.PerspectiveCamera(yfov=np.pi / 3.0))
    renderer = front.OffscreenRenderer(64, 48, spp=1)
    flat = front.RenderFlags.FLAT
    sphere = max(scene.mesh_nodes, key=lambda n: len(n.mesh.primitives[0].positions))
    red, _ = renderer.render(scene, flags=flat)
    first = renderer._built
    renderer.render(scene, flags=flat)
    assert renderer._built is first
    sphere.mesh.primitives[0].material.baseColorFactor = np.array([0.2, 0.2, 0.9, 1.0])
    blue, _ = renderer.render(scene, flags=flat)
    assert renderer._built is not first
    changed = np.any(red != blue, axis=-1)
    assert changed.sum() > 100
    assert (blue[changed][:, 2] > blue[changed][:, 0]).all()
    before = renderer.render(scene, flags=front.RenderFlags.DEPTH_ONLY)
    recoloured = renderer._built
    sphere.mesh.primitives[0].positions[:] *= 0.5  # in place: the same array object
    after = renderer.render(scene, flags=front.RenderFlags.DEPTH_ONLY)
    assert renderer._built is not recoloured
    assert (after > 0).sum() < (before > 0).sum()
    kept = renderer._built
    renderer.render(scene, flags=front.RenderFlags.DEPTH_ONLY)
    assert renderer._built is kept
