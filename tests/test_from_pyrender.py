"""softrast.from_pyrender against pyrender 0.1.45 itself.

The child process (tests/support/pyrender_interop_child.py, PYOPENGL_PLATFORM=osmesa) builds a
pyrender scene with two meshes (one under a parent node), a directional and a spot light, ambient
light and a camera (perspective with yfov in radians, intrinsics, orthographic), renders it with
pyrender on Mesa's llvmpipe, converts it with softrast.from_pyrender and renders the conversion with
softrast, and writes both. Checked here:

* what was converted: fov_y in degrees from yfov in radians, aspect, near / far, the camera's and
  the nested node's world poses, light types / colours / intensities / cone angles, ambient
  light, the MetallicRoughnessMaterial's factors, per-vertex colours;
* masks: every pixel where the two differ is within 1 px of softrast's silhouette (pyrender
  rasterizes with its own rule on silhouette pixels);
* depth, perspective and intrinsics cameras: on interior pixels (the same instance in the whole
  3x3 neighbourhood in both), |softrast - pyrender| <= 1e-5 relative. pyrender's depth comes
  from a 24-bit depth buffer (resolution 2^-24 in NDC, ~1e-7 relative here): that is the limit
  of the comparison, not softrast's float32 depth;
* orthographic: pyrender's depth is wrong for orthographic cameras (its linearization assumes a
  perspective projection), so softrast's depth is checked against rays cast through each pixel
  centre (trimesh's ray-triangle intersection, float64) instead; masks against pyrender.
* alphaMode "BLEND" (every material of pyrender.Mesh.from_trimesh) converts opaque
  where every alpha is 1 (pyrender draws it opaque too), and to ``alpha_mode="blend"`` where one
  is below 1 (pyrender blends), without a warning either way; bg_color comes back as the
  result's ``background``, and softrast renders it as pyrender's bytes (white 255; others
  within 1). How the blends compare: tests/test_blend_vs_pyrender.py.
The test FAILS (never skips) without pyrender and OSMesa: see test_pbr_vs_pyrender.py.
"""
from __future__ import annotations

import json
import math
import os
import pathlib
import pickle
import subprocess
import sys
import warnings

import numpy as np
import pytest
import trimesh
from scipy import ndimage

import softrast as sr

from support.pyrender_runner import INSTALL_HINT, run_pyrender_child

CHILD = pathlib.Path(__file__).resolve().parent / "support" / "pyrender_interop_child.py"
W, H = 320, 240


def rigid(angle, axis, offset):  # as in the child
    m = trimesh.transformations.rotation_matrix(angle, axis)
    m[:3, 3] = offset
    return m


@pytest.fixture(scope="module")
def rendered(tmp_path_factory) -> pathlib.Path:
    out = tmp_path_factory.mktemp("pyrender_interop")
    # The child imports softrast too, so it keeps the environment as it is: under the sanitizer
    # run (.ci/sanitize) the ASan runtime must stay preloaded for softrast's sanitized core.
    parent = str(pathlib.Path(sr.__file__).resolve().parent.parent)
    run_pyrender_child(CHILD, [parent, out], timeout=300)
    return out


def load(out: pathlib.Path, kind: str, name: str) -> np.ndarray:
    return np.load(out / f"{kind}_{name}.npy")


def test_what_from_pyrender_converts(rendered: pathlib.Path) -> None:
    info = json.loads((rendered / "info.json").read_text())
    cam_pose = rigid(0.15, (-1.0, 0.4, 0.0), (0.2, 0.6, 3.6))
    persp = info["perspective"]
    assert persp["camera"] == "PerspectiveCamera"
    assert math.isclose(persp["fov_y"], 40.0, rel_tol=1e-12)  # yfov radians(40) -> 40 degrees
    assert math.isclose(persp["aspect"], W / H, rel_tol=1e-12)
    assert info["intrinsics"]["camera"] == "IntrinsicsCamera" and info["intrinsics"]["convention"] == "opengl"
    assert info["orthographic"]["camera"] == "OrthographicCamera"
    for kind in info.values():
        assert (kind["near"], kind["far"]) == (0.5, 20.0)
        np.testing.assert_allclose(kind["pose"], cam_pose, atol=1e-6)  # pyrender stores poses as float32
    ball, box = persp["instances"]
    assert ball["faces"] == 1280 and box["faces"] == 12
    np.testing.assert_allclose(ball["material"][0], (0.9, 0.6, 0.3, 1.0), atol=1e-6)
    assert ball["material"][1:] == [pytest.approx(0.2), pytest.approx(0.6), "pbr"] and not ball["colors"]
    assert box["colors"]
    np.testing.assert_allclose(ball["pose"], rigid(0.3, (0, 1, 0), (-0.5, 0.1, 0.0)), atol=1e-6)
    nested = rigid(0.4, (1, 0, 0), (0.6, 0.0, -0.3)) @ rigid(0.7, (0.2, 1.0, 0.1), (0.1, -0.1, 0.0))
    np.testing.assert_allclose(box["pose"], nested, atol=1e-6)
    lights = {li["type"]: li for li in persp["lights"]}
    assert set(lights) == {"DirectionalLight", "SpotLight"}
    assert lights["SpotLight"]["cones"] == [pytest.approx(0.2), pytest.approx(0.6)]
    assert lights["SpotLight"]["intensity"] == 9.0 and lights["DirectionalLight"]["intensity"] == 2.5
    np.testing.assert_allclose(lights["SpotLight"]["color"], (0.5, 0.7, 1.0))
    np.testing.assert_allclose(lights["SpotLight"]["pose"], rigid(0.2, (0, 1, 0), (0.5, 0.5, 3.0)), atol=1e-6)
    np.testing.assert_allclose(persp["ambient"], (0.05, 0.05, 0.06), atol=1e-7)


def silhouette_band(mask: np.ndarray) -> np.ndarray:
    """Pixels within 1 px (8-neighbourhood) of the mask's boundary."""
    full = np.ones((3, 3), bool)
    return ndimage.binary_dilation(mask, full) & ~ndimage.binary_erosion(mask, full, border_value=1)


@pytest.mark.parametrize("kind", ["perspective", "intrinsics", "orthographic"])
def test_masks_agree_but_on_silhouettes(rendered: pathlib.Path, kind: str) -> None:
    sr_mask = load(rendered, kind, "sr_mask")
    pr_mask = load(rendered, kind, "pr_depth") > 0
    assert sr_mask.sum() > 5000
    differ = sr_mask != pr_mask
    print(f"{kind}: masks differ on {int(differ.sum())} of {int(sr_mask.sum())} covered pixels")
    assert not (differ & ~silhouette_band(sr_mask)).any()


@pytest.mark.parametrize("kind", ["perspective", "intrinsics"])
def test_depth_agrees_on_interior_pixels(rendered: pathlib.Path, kind: str) -> None:
    sr_depth = load(rendered, kind, "sr_depth").astype(np.float64)
    pr_depth = load(rendered, kind, "pr_depth").astype(np.float64)
    both = (sr_depth > 0) & (pr_depth > 0)
    # interior: inside both masks and no depth discontinuity (a silhouette over the other mesh)
    # in the 3x3 neighbourhood: the depth's local range stays below 5% of the depth
    hi = ndimage.maximum_filter(np.where(both, sr_depth, np.inf), size=3)
    lo = ndimage.minimum_filter(np.where(both, sr_depth, 0.0), size=3)
    interior = ndimage.binary_erosion(both, np.ones((3, 3), bool)) & (hi - lo < 0.05 * sr_depth)
    assert interior.sum() > 0.8 * both.sum() * 0.8
    rel = np.abs(sr_depth - pr_depth)[interior] / sr_depth[interior]
    print(f"{kind}: depth on {int(interior.sum())} interior pixels: max rel {rel.max():.2e}, mean {rel.mean():.2e}")
    assert rel.max() <= 1e-5


def nearest_hit(origins: np.ndarray, direction: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Distance along ``direction`` (unit) from each origin to the nearest triangle it hits, inf
    if none: Moller-Trumbore in float64, every ray against every triangle."""
    t_best = np.full(len(origins), np.inf)
    v0, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    p = np.cross(direction, e2)  # (m, 3)
    det = np.einsum("ij,ij->i", e1, p)
    keep = np.abs(det) > 1e-12
    v0, e1, e2, p, det = v0[keep], e1[keep], e2[keep], p[keep], det[keep]
    for start in range(0, len(origins), 512):
        o = origins[start:start + 512, None, :]  # (r, 1, 3)
        s = o - v0  # (r, m, 3)
        u = np.einsum("rmk,mk->rm", s, p) / det
        q = np.cross(s, e1)
        v = (q @ direction) / det
        t = np.einsum("rmk,mk->rm", q, e2) / det
        t = np.where((u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0), t, np.inf)
        t_best[start:start + 512] = t.min(axis=1)
    return t_best


def test_orthographic_depth_is_the_ray_distance(rendered: pathlib.Path) -> None:
    tris = np.load(rendered / "world_triangles.npy")
    depth = load(rendered, "orthographic", "sr_depth").astype(np.float64)
    pose = rigid(0.15, (-1.0, 0.4, 0.0), (0.2, 0.6, 3.6))
    rows, cols = np.mgrid[0:H:3, 0:W:3]
    x = ((cols + 0.5) / W * 2.0 - 1.0) * 1.6
    y = (1.0 - (rows + 0.5) / H * 2.0) * 1.2
    origins = pose[:3, 3] + np.c_[x.ravel(), y.ravel()] @ pose[:3, :2].T
    t = nearest_hit(origins, -pose[:3, 2], tris)
    got = depth[rows.ravel(), cols.ravel()]
    hit = np.isfinite(t) & (got > 0)
    sr_mask = load(rendered, "orthographic", "sr_mask")
    interior = ~silhouette_band(sr_mask)[rows.ravel(), cols.ravel()]
    pr = load(rendered, "orthographic", "pr_depth").astype(np.float64)[rows.ravel(), cols.ravel()]
    ok = hit & interior
    assert ok.sum() > 500
    err = np.abs(got[ok] - t[ok]) / t[ok]
    pr_err = np.abs(pr[ok] - t[ok]) / t[ok]
    print(f"orthographic: softrast depth vs ray casting on {int(ok.sum())} pixels: max rel {err.max():.2e}; "
          f"pyrender's (not asserted): max rel {pr_err.max():.2f}")
    assert err.max() <= 1e-5


def test_softrast_never_imports_pyrender() -> None:
    code = ("import sys, softrast; softrast.from_pyrender; "
            "assert 'pyrender' not in sys.modules and 'OpenGL' not in sys.modules and 'cv2' not in sys.modules")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONPATH=str(pathlib.Path(sr.__file__).resolve().parent.parent)))
    assert proc.returncode == 0, proc.stderr


TEXTURE_CHILD = r"""
import json, os, sys
sys.path.insert(0, sys.argv[1])
import numpy as np, trimesh, pyrender, softrast as sr
tscene = trimesh.load(sys.argv[2])
prs = pyrender.Scene.from_trimesh_scene(tscene)
cam = pyrender.PerspectiveCamera(yfov=0.8)
pose = np.eye(4); pose[:3, 3] = (1.2, 1.0, 2.5)
z = pose[:3, 3] / np.linalg.norm(pose[:3, 3]); x = np.cross([0, 1, 0], z); x /= np.linalg.norm(x)
pose[:3, 0], pose[:3, 1], pose[:3, 2] = x, np.cross(z, x), z
prs.add(cam, pose=pose)
scene, camera = sr.from_pyrender(prs, 96, 72)
mats = [i.mesh.material for i in scene._instances]
tex = mats[0].base_color_texture
frame = sr.Renderer(96, 72).render(scene, camera, outputs=("radiance",), shading="unlit")
np.save(sys.argv[3], frame.radiance)
np.save(sys.argv[3] + ".pose.npy", camera.pose)
print(json.dumps({"shape": list(tex.image.shape), "dtype": str(tex.image.dtype), "wrap": tex.wrap,
                  "filter": tex.filter, "same": all(m.base_color_texture is tex for m in mats),
                  "n": len(mats)}))
"""


def test_from_pyrender_keeps_textures(tmp_path) -> None:
    """BoxTextured through pyrender.Scene.from_trimesh_scene and sr.from_pyrender renders (unlit)
    exactly as sr.load_scene of the file: the same texture, slot, sampler and uv convention."""
    box = pathlib.Path(__file__).resolve().parents[1] / "assets" / "meshes" / "BoxTextured.gltf"
    env = dict(os.environ, PYOPENGL_PLATFORM="osmesa")
    parent = str(pathlib.Path(sr.__file__).resolve().parent.parent)
    out = tmp_path / "radiance.npy"
    proc = subprocess.run([sys.executable, "-c", TEXTURE_CHILD, parent, str(box), str(out)], env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:] + INSTALL_HINT
    info = json.loads(proc.stdout.strip().splitlines()[-1])
    assert info["shape"][:2] == [211, 211] and info["dtype"] == "uint8" and info["same"]
    got = np.load(out)
    scene = sr.load_scene(box)
    cam = sr.PerspectiveCamera(fov_y=math.degrees(0.8), width=96, height=72)
    cam.pose = np.load(str(out) + ".pose.npy")
    ref = sr.Renderer(96, 72).render(scene, cam, outputs=("radiance",), shading="unlit").radiance
    assert (ref > 0).any(-1).sum() > 1000
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-6)


# -- alphaMode "BLEND" at alpha 1, and bg_color ----------------------------------------------

BLEND_CHILD = r"""
import json, sys, warnings
sys.path.insert(0, sys.argv[1])
sys.path.insert(0, sys.argv[2])
from support.pyrender_env import import_pyrender
import numpy as np
from PIL import Image
pyrender, trimesh = import_pyrender("blend child")
import softrast as sr

W, H = 96, 72
rng = np.random.default_rng(7)


def textured(alpha=None):
    m = trimesh.creation.box(extents=(1.0, 0.8, 0.9))
    image = rng.integers(40, 250, (8, 8, 3 if alpha is None else 4)).astype(np.uint8)
    if alpha is not None:
        image[:, :, 3] = 255
        image[:4, :, 3] = alpha
    m.visual = trimesh.visual.TextureVisuals(uv=rng.random((len(m.vertices), 2)), image=Image.fromarray(image))
    return m


def colored(alpha):
    m = trimesh.creation.box(extents=(1.0, 0.8, 0.9))
    m.visual.vertex_colors = np.array([[200, 90, 40, alpha]] * len(m.vertices), np.uint8)
    return m


def factor(alpha):
    m = trimesh.creation.icosphere(subdivisions=2, radius=0.6)
    mat = pyrender.MetallicRoughnessMaterial(alphaMode="BLEND", baseColorFactor=[0.8, 0.5, 0.3, alpha],
                                             metallicFactor=0.1, roughnessFactor=0.7)
    return pyrender.Mesh.from_trimesh(m, material=mat)


# name: (pyrender mesh, mesh name, node name, material name); from_trimesh marks them all BLEND
cases = {
    "texture_rgb": (pyrender.Mesh.from_trimesh(textured()), None, None, None),
    "texture_rgba_opaque": (pyrender.Mesh.from_trimesh(textured(255)), "crate", None, None),
    "vertex_colors_opaque": (pyrender.Mesh.from_trimesh(colored(255)), None, "brick", None),
    "plain": (pyrender.Mesh.from_trimesh(trimesh.creation.box()), None, None, None),
    "factor_opaque": (factor(1.0), "ball", "ball node", "clay"),
    "factor_translucent": (factor(0.5), "glass", "glass node", "frosted"),
    "texture_translucent": (pyrender.Mesh.from_trimesh(textured(100)), "leaf", "leaf node", "leaf material"),
    "vertex_colors_translucent": (pyrender.Mesh.from_trimesh(colored(128)), "tinted", "tint node", "tint"),
}
renderer = pyrender.OffscreenRenderer(W, H)
out = {}
for name, (mesh, mesh_name, node_name, mat_name) in cases.items():
    mesh.name = mesh_name
    for prim in mesh.primitives:
        prim.material.name = mat_name
    scene = pyrender.Scene(ambient_light=[0.1, 0.1, 0.1], bg_color=[0.2, 0.3, 0.4, 1.0])
    scene.add(mesh, pose=trimesh.transformations.rotation_matrix(0.5, (0.3, 1.0, 0.2)), name=node_name)
    pose = np.eye(4)
    pose[:3, 3] = (0.0, 0.0, 3.0)
    scene.add(pyrender.PerspectiveCamera(yfov=0.7), pose=pose)
    scene.add(pyrender.DirectionalLight(intensity=3.0), pose=pose)
    modes = {prim.material.alphaMode for prim in mesh.primitives}
    blended = renderer.render(scene)[0]
    for prim in mesh.primitives:
        prim.material.alphaMode = "OPAQUE"
    opaque = renderer.render(scene)[0]
    for prim in mesh.primitives:
        prim.material.alphaMode = "BLEND"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        conv = sr.from_pyrender(scene, W, H)
    out[name] = {"modes": sorted(modes), "pyrender_opaque": bool(np.array_equal(blended, opaque)),
                 "differ": int((blended != opaque).any(-1).sum()),
                 "warnings": [str(c.message) for c in caught],
                 "converted": sorted({inst.material.alpha_mode for inst in conv.scene})}
renderer.delete()
print(json.dumps(out))
"""


def run_child(tmp_path: pathlib.Path, code: str, *args: str) -> str:
    child = tmp_path / "child.py"
    child.write_text(code)
    parent = str(pathlib.Path(sr.__file__).resolve().parent.parent)
    tests = str(pathlib.Path(__file__).resolve().parent)
    return run_pyrender_child(child, [parent, tests, *args], timeout=300).stdout


def test_blend_is_blend_below_alpha_one_and_opaque_at_one(tmp_path) -> None:
    """pyrender.Mesh.from_trimesh marks every material it makes alphaMode "BLEND" (textured,
    vertex-coloured, plain). Where every alpha is 1 pyrender draws it opaque (its BLEND render
    equals the same scene's OPAQUE render byte for byte) and from_pyrender converts it opaque;
    where an alpha is below 1 (baseColorFactor, the base colour texture, the vertex colours)
    pyrender blends, and from_pyrender converts it to alpha_mode "blend". Neither warns (blending
    is drawn now)."""
    info = json.loads(run_child(tmp_path, BLEND_CHILD).strip().splitlines()[-1])
    for name, case in info.items():
        assert case["modes"] == ["BLEND"], name
        assert case["warnings"] == [], (name, case["warnings"])
        if name.endswith("translucent"):
            assert not case["pyrender_opaque"] and case["differ"] > 50, name  # pyrender blends
            assert case["converted"] == ["blend"], (name, case)
        else:
            assert case["pyrender_opaque"], name
            assert case["converted"] == ["opaque"], (name, case)
    assert {name for name, case in info.items() if case["converted"] == ["blend"]} == {
        "factor_translucent", "texture_translucent", "vertex_colors_translucent"}


def test_blend_converts_per_primitive_without_a_warning() -> None:
    """Without pyrender (duck-typed stand-ins): a "BLEND" primitive at alpha 1 converts opaque,
    one with baseColorFactor alpha 0.5 (two instancing poses: both instances), one whose
    color_0 alpha is below 1 and one whose base colour texture's alpha is below 1 convert to
    alpha_mode "blend", keeping the alpha; nothing warns (the test suite turns warnings into
    errors)."""

    def pyrender_class(name):
        cls = type(name, (), {})
        cls.__module__ = "pyrender"
        return cls

    def material(alpha, texture=None):
        mat = pyrender_class("MetallicRoughnessMaterial")()
        mat.alphaMode, mat.alphaCutoff, mat.name = "BLEND", 0.5, None
        mat.baseColorFactor, mat.doubleSided = (1.0, 1.0, 1.0, alpha), False
        mat.baseColorTexture = texture
        return mat

    def primitive(alpha, poses=None, color_0=None, texture=None):
        prim = pyrender_class("Primitive")()
        prim.positions, prim.indices, prim.mode = np.eye(3), None, 4
        prim.material, prim.poses, prim.color_0 = material(alpha, texture), poses, color_0
        prim.texcoord_0 = None if texture is None else np.zeros((3, 2))
        return prim

    texture = pyrender_class("Texture")()
    texture.source, texture.sampler = np.full((2, 2, 4), 255, np.uint8), None
    texture.source[0, 0, 3] = 100
    opaque_texture = pyrender_class("Texture")()
    opaque_texture.source, opaque_texture.sampler = np.full((2, 2, 4), 255, np.uint8), None
    tinted = np.array([[1.0, 0.5, 0.25, 1.0], [1.0, 0.5, 0.25, 0.5], [1.0, 0.5, 0.25, 1.0]])
    mesh = pyrender_class("Mesh")()
    mesh.name, mesh.primitives = None, [
        primitive(1.0), primitive(0.5, np.stack([np.eye(4)] * 2)), primitive(1.0, color_0=tinted),
        primitive(1.0, color_0=np.ones((3, 4))), primitive(1.0, texture=texture),
        primitive(1.0, texture=opaque_texture)]
    node = pyrender_class("Node")()
    node.name, node.mesh = None, mesh
    scene = pyrender_class("Scene")()
    scene.mesh_nodes, scene.light_nodes, scene.main_camera_node = [node], [], None
    scene.get_pose = lambda n: np.eye(4)
    scene.ambient_light, scene.bg_color = None, np.array([0.5, 0.25, 1.5, 0.5])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        conv = sr.from_pyrender(scene, 8, 8)
    assert len(conv.scene) == 7 and conv.camera is None
    modes = [inst.material.alpha_mode for inst in conv.scene]
    assert modes == ["opaque", "blend", "blend", "blend", "opaque", "blend", "opaque"]
    assert [inst.material.base_color[3] for inst in conv.scene][:3] == [1.0, 0.5, 0.5]
    np.testing.assert_array_equal(conv.scene.instances[3].mesh.colors[:, 3], [1.0, 0.5, 1.0])
    assert conv.background == (0.5, 0.25, 1.0) and conv.background_alpha == 0.5  # clipped as GL does


def test_conversion_is_still_the_pair() -> None:
    """from_pyrender's result unpacks, compares and pickles as the (scene, camera) tuple it always
    was, and carries the background (a scene without bg_color: pyrender's default, white)."""
    scene = type("Scene", (), {})()
    scene.mesh_nodes, scene.light_nodes, scene.main_camera_node = [], [], None
    conv = sr.from_pyrender(scene, 8, 8)
    sr_scene, camera = conv
    assert isinstance(conv, tuple) and len(conv) == 2 and conv == (sr_scene, None)
    assert conv.scene is sr_scene and conv.camera is None and conv[0] is sr_scene
    assert conv.background == (1.0, 1.0, 1.0) and conv.background_alpha == 1.0
    back = pickle.loads(pickle.dumps(conv))
    assert isinstance(back, sr.interop.PyrenderConversion) and len(back) == 2
    assert (back.background, back.background_alpha, back.camera) == ((1.0, 1.0, 1.0), 1.0, None)
    scene.bg_color = [0.1, 0.2, 0.3]  # RGB: alpha 1
    assert sr.from_pyrender(scene, 8, 8).background_alpha == 1.0


BACKGROUND_CHILD = r"""
import sys
sys.path.insert(0, sys.argv[1])
sys.path.insert(0, sys.argv[2])
from support.pyrender_env import import_pyrender
import numpy as np
pyrender, trimesh = import_pyrender("background child")
from OpenGL import GL
import softrast as sr

W, H = 96, 72
out = {}
backgrounds = {"default": None, "grey": [0.5, 0.5, 0.5], "rgba": [0.3, 0.55, 0.8, 0.4], "dark": [0.02, 0.1, 0.2, 1.0]}
renderer = pyrender.OffscreenRenderer(W, H)
for name, bg in backgrounds.items():
    scene = pyrender.Scene(ambient_light=[0.1, 0.1, 0.1]) if bg is None else pyrender.Scene(
        ambient_light=[0.1, 0.1, 0.1], bg_color=bg)
    scene.add(pyrender.Mesh.from_trimesh(trimesh.creation.box(extents=(1.0, 0.8, 0.9))),
              pose=trimesh.transformations.rotation_matrix(0.5, (0.3, 1.0, 0.2)))
    pose = np.eye(4)
    pose[:3, 3] = (0.0, 0.0, 3.0)
    scene.add(pyrender.PerspectiveCamera(yfov=0.7), pose=pose)
    scene.add(pyrender.DirectionalLight(intensity=3.0), pose=pose)
    color, depth = renderer.render(scene)
    # OSMesa has no framebuffer objects, so pyrender reads its colour as RGB even with
    # RenderFlags.RGBA: read the RGBA pixels it cleared and drew from its context directly.
    renderer._platform.make_current()
    GL.glReadBuffer(GL.GL_FRONT)
    rgba = np.frombuffer(GL.glReadPixels(0, 0, W, H, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE), np.uint8)
    renderer._platform.make_uncurrent()
    rgba = rgba.reshape(H, W, 4)[::-1]
    assert (rgba[:, :, :3] == color).all()
    color = rgba
    conv = sr.from_pyrender(scene, W, H)
    sr_scene, sr_camera = conv  # still the pair it always was
    frame = sr.Renderer(W, H).render(sr_scene, sr_camera, background=conv.background,
                                     outputs=("color", "mask", "alpha"))
    np.savez(sys.argv[3] + f"/{name}.npz", pr_color=color, pr_depth=depth, sr_color=frame.color,
             sr_mask=frame.mask, sr_alpha=frame.alpha, background=conv.background,
             background_alpha=conv.background_alpha)
renderer.delete()
"""


def test_background_is_pyrender_bg_color(tmp_path) -> None:
    """from_pyrender carries bg_color: rendered with ``background=conversion.background`` the
    background pixels are pyrender's bytes (its default white 255, a grey within 1), its alpha is
    ``background_alpha`` where pyrender's RGBA render has it."""
    run_child(tmp_path, BACKGROUND_CHILD, str(tmp_path))
    for name in ("default", "grey", "rgba", "dark"):
        data = np.load(tmp_path / f"{name}.npz")
        pr_color, sr_color = data["pr_color"].astype(int), data["sr_color"].astype(int)
        covered = (data["pr_depth"] > 0) | data["sr_mask"]
        background = ~ndimage.binary_dilation(covered, np.ones((3, 3), bool))
        assert background.sum() > 0.5 * background.size and covered.sum() > 500, name
        diff = np.abs(sr_color[background] - pr_color[background][:, :3])
        print(f"{name}: background {tuple(data['background'])}: pyrender "
              f"{pr_color[background][0].tolist()}, softrast {sr_color[background][0].tolist()}")
        assert diff.max() <= 1, name
        alpha = data["sr_alpha"] + (1.0 - data["sr_alpha"]) * float(data["background_alpha"])
        assert np.abs(alpha[background] * 255.0 - pr_color[background][:, 3]).max() <= 1.0, name
        assert (np.abs(alpha[~covered] * 255.0 - pr_color[~covered][:, 3]) <= 1.0).all(), name
    default = np.load(tmp_path / "default.npz")
    assert (default["sr_color"][~(default["sr_mask"] | (default["pr_depth"] > 0))] == 255).all()
    assert tuple(default["background"]) == (1.0, 1.0, 1.0) and float(default["background_alpha"]) == 1.0
