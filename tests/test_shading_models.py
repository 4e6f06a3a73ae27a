"""Shading models added through the policy seam (cpp/shade_models.hpp): "normal" shows the
world-space unit normal as a colour, (n + 1) / 2, and must agree with the normal output to the bit."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import softrast as sr

SPHERE = trimesh.creation.icosphere(subdivisions=4)


def _unorm8(v: np.ndarray) -> np.ndarray:
    """The core's float -> 8-bit rule: clamp to [0, 1], * 255 + 0.5, truncate (float32 throughout)."""
    v = np.clip(v.astype(np.float32), np.float32(0), np.float32(1))
    return (v * np.float32(255) + np.float32(0.5)).astype(np.uint8)


def _render(mesh: sr.Mesh, simd: bool = True, path: str = "auto", **kw) -> sr.Frame:
    # srgb=False: the colour is (n + 1) / 2 itself, linearly encoded (the default sRGB encoding
    # would apply its curve to it), as _unorm8 computes.
    kw.setdefault("srgb", False)
    # The normal the shading read (the default normal output is the exact surface normal).
    kw.setdefault("normal_kind", "shading")
    scene = sr.Scene()
    scene.add(mesh, pose=np.diag([1.0, 1.0, 1.0, 1.0]))
    cam = sr.PerspectiveCamera(fov_y=40.0, near=0.1, far=10.0)
    cam.look_at((0.6, 0.8, 3.2), (0.0, 0.0, 0.0))
    return sr.Renderer(160, 120, simd=simd).render(
        scene, cam, outputs=("color", "normal", "mask"), shading="normal", shading_path=path,
        background=(0.1, 0.2, 0.3), **kw)


@pytest.mark.parametrize("smooth", [True, False])
@pytest.mark.parametrize("simd", [True, False])
@pytest.mark.parametrize("path", ["forward", "deferred"])
def test_normal_model_is_the_normal_output_as_colour(smooth, simd, path):
    normals = SPHERE.vertex_normals if smooth else None
    frame = _render(sr.Mesh(SPHERE.vertices, SPHERE.faces, normals=normals), simd, path)
    m = frame.mask
    assert m.sum() > 3000
    want = _unorm8(frame.normal[m] * np.float32(0.5) + np.float32(0.5))
    np.testing.assert_array_equal(frame.color[m], want)
    np.testing.assert_array_equal(frame.color[~m], np.broadcast_to(_unorm8(np.array([0.1, 0.2, 0.3])), (int((~m).sum()), 3)))


def test_normal_model_matches_the_analytic_sphere():
    # Smooth normals of a unit sphere centred at the origin: the normal at a visible point is the
    # point itself. Colour (n + 1) / 2 within two 8-bit steps of the exact sphere's.
    frame = _render(sr.Mesh(SPHERE.vertices, SPHERE.faces, normals=SPHERE.vertex_normals))
    cam_pos = np.array([0.6, 0.8, 3.2])
    h, w = frame.mask.shape
    cam = sr.PerspectiveCamera(fov_y=40.0, near=0.1, far=10.0)
    cam.look_at(cam_pos, (0.0, 0.0, 0.0))
    # Ray through each pixel centre, intersected with the unit sphere.
    f = 1.0 / np.tan(np.radians(40.0) / 2)
    j, i = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    d_view = np.stack([(2 * j / w - 1) * w / h / f, (1 - 2 * i / h) / f, -np.ones_like(j)], -1)
    d = d_view @ cam.pose[:3, :3].T
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    b = (d * cam_pos).sum(-1)
    disc = b * b - (cam_pos @ cam_pos - 1.0)
    inside = disc > 0.05  # away from the silhouette, where the tessellation differs most
    t = -b - np.sqrt(np.where(inside, disc, 0))
    n = cam_pos + t[..., None] * d
    sel = inside & frame.mask
    assert sel.sum() > 3000
    err = np.abs(frame.color[sel].astype(int) - np.round((n[sel] + 1) / 2 * 255)).max()
    assert err <= 2, err


def test_normal_model_ignores_the_base_colour():
    a = _render(sr.Mesh(SPHERE.vertices, SPHERE.faces, normals=SPHERE.vertex_normals, color=(1, 0, 0, 1)))
    colors = np.random.default_rng(3).uniform(0, 1, (len(SPHERE.vertices), 4))
    b = _render(sr.Mesh(SPHERE.vertices, SPHERE.faces, normals=SPHERE.vertex_normals, colors=colors))
    np.testing.assert_array_equal(a.color, b.color)


def test_unknown_shading_names_the_argument():
    # "phong" is a shading model now: an unknown name is needed. _checks.choice's message.
    with pytest.raises(ValueError, match=r"^shading must be one of \(.*'normal'.*\), got 'toon'$"):
        sr.Renderer(8, 8).render(sr.Scene(), sr.PerspectiveCamera(), shading="toon")


def _quad_frame(near: float, eye=(0.3, -1.6, 0.9), target=(0.0, 0.2, 0.0), simd=True, path="auto"):
    """The square [-1, 1]^2 on z = 0 with uv = ((x + 1) / 2, (y + 1) / 2), seen at a grazing angle."""
    positions = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    uvs = (positions[:, :2] + 1) / 2
    mesh = sr.Mesh(positions, [[0, 1, 2], [0, 2, 3]], uvs=uvs)
    scene = sr.Scene()
    scene.add(mesh)
    cam = sr.PerspectiveCamera(fov_y=60.0, near=near, far=10.0)
    cam.look_at(eye, target, up=(0, 0, 1))
    w, h = 160, 120
    # srgb=False: the colour is the uv itself, linearly encoded (x * 255, rounded).
    frame = sr.Renderer(w, h, simd=simd).render(scene, cam, outputs=("color", "mask"), shading="uv",
                                                cull="none", shading_path=path, srgb=False)
    # Exact uv at each pixel centre: the ray through it meets z = 0 at (x, y).
    f = 1.0 / np.tan(np.radians(60.0) / 2)
    j, i = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    d = np.stack([(2 * j / w - 1) * w / h / f, (1 - 2 * i / h) / f, -np.ones_like(j)], -1) @ cam.pose[:3, :3].T
    e = np.asarray(eye, float)
    t = -e[2] / d[..., 2]
    hit = e + t[..., None] * d
    want = (hit[..., :2] + 1) / 2
    return frame, want


@pytest.mark.parametrize("simd", [True, False])
@pytest.mark.parametrize("path", ["forward", "deferred"])
def test_uv_model_is_perspective_correct(simd, path):
    frame, want = _quad_frame(near=0.05, simd=simd, path=path)
    m = frame.mask
    assert m.sum() > 5000
    got = frame.color[m][:, :2].astype(float) / 255
    assert np.abs(got - want[m]).max() <= 1.01 / 255  # the 8-bit rounding of the exact uv
    assert (frame.color[m][:, 2] == 0).all()
    # Affine (screen-space) interpolation would be far off at this angle: the test can tell.
    assert np.abs(want[m] - want[m].mean(0)).max() > 0.3


def test_uv_model_through_near_plane_clipping():
    # The near plane cuts the quad (clipped triangles carry their source corners' weights).
    frame, want = _quad_frame(near=0.9, eye=(0.0, -0.5, 0.6), target=(0.0, 0.5, 0.0))
    m = frame.mask
    assert 1000 < m.sum() < m.size
    got = frame.color[m][:, :2].astype(float) / 255
    assert np.abs(got - want[m]).max() <= 1.01 / 255


def test_uv_model_without_uvs_is_black():
    scene = sr.Scene()
    scene.add(sr.Mesh(SPHERE.vertices, SPHERE.faces))
    cam = sr.PerspectiveCamera(fov_y=40.0, near=0.1, far=10.0)
    cam.look_at((0, 0, 3), (0, 0, 0))
    frame = sr.Renderer(64, 48).render(scene, cam, outputs=("color", "mask"), shading="uv",
                                       background=(1, 1, 1))
    assert frame.mask.sum() > 500
    assert (frame.color[frame.mask] == 0).all() and (frame.color[~frame.mask] == 255).all()


# --------------------------------------------------------------------------------- depth view

@pytest.mark.parametrize("simd", [True, False])
@pytest.mark.parametrize("path", ["forward", "deferred"])
def test_depth_view_is_the_depth_output_as_grey(simd, path):
    # shading="depth": (far - depth) / (far - near) clamped to [0, 1], linearly encoded with
    # srgb=False, from the interpolated world position: the exact plane's depth at each pixel.
    positions = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    scene = sr.Scene()
    scene.add(sr.Mesh(positions, [[0, 1, 2], [0, 2, 3]]))
    near, far = 0.05, 4.0
    cam = sr.PerspectiveCamera(fov_y=60.0, near=near, far=far)
    cam.look_at((0.3, -1.6, 0.9), (0.0, 0.2, 0.0), up=(0, 0, 1))
    got = sr.Renderer(160, 120, simd=simd).render(
        scene, cam, outputs=("color", "depth", "mask"), shading="depth", cull="none",
        shading_path=path, srgb=False)
    m = got.mask
    assert m.sum() > 5000
    want = np.clip((far - got.depth.astype(np.float64)) / (far - near), 0, 1)
    grey = got.color[m].astype(np.float64) / 255
    assert (got.color[m][:, 0] == got.color[m][:, 1]).all() and (got.color[m][:, 0] == got.color[m][:, 2]).all()
    assert np.abs(grey[:, 0] - want[m]).max() <= 0.51 / 255 + 1e-5  # 8-bit rounding, float32
    # The plane recedes: the view spans many grey levels (the test can tell a constant).
    assert np.ptp(grey[:, 0]) > 0.3
    assert (got.color[~m] == 0).all()  # the background


def test_depth_view_ignores_materials_and_lights():
    # A textured pbr material under a point light shows only its depth: a plane facing the camera
    # at depth 2 with near 1, far 3 is one grey, (3 - 2) / (3 - 1) = 0.5 -> 128.
    tex = sr.Texture(np.full((4, 4, 3), 200, np.uint8))
    mat = sr.Material(model="pbr", base_color_texture=tex, metallic=1.0)
    scene = sr.Scene()
    quad = sr.Mesh(np.array([[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0]], float),
                   [[0, 1, 2], [0, 2, 3]], uvs=np.zeros((4, 2)), material=mat)
    pose = np.eye(4)
    pose[2, 3] = -2.0
    scene.add(quad, pose=pose)
    scene.add(sr.PointLight(intensity=50.0), pose=np.eye(4))
    cam = sr.PerspectiveCamera(fov_y=60.0, near=1.0, far=3.0)
    cam.look_at((0.0, 0.0, 0.0), (0.0, 0.0, -1.0))
    f = sr.Renderer(32, 32).render(scene, cam, outputs=("color", "mask"), shading="depth", srgb=False)
    assert f.mask.all()
    assert (f.color == 128).all()
    lit = sr.Renderer(32, 32).render(scene, cam, outputs=("color",), srgb=False)
    assert (lit.color != 128).any()  # (the material itself would not give that grey)


# ---------------------------------------------------------------- a pixel's shade is its triangle's
# The lit kernel reuses the previous triangle's classification and constants when their key
# matches (shade_models.hpp, LitClassCache and LitConstantsCache). A key missing a field would
# make a pixel's colour depend on which triangle was shaded before its own: reordering the faces
# would change it. Random triangle soups mix what the keys hold: draws and materials, front and
# back faces (single- and double-sided), uniform and varying vertex colours, one normal and three.

def _soup(rng: np.random.Generator, n: int) -> sr.Mesh:
    centres = rng.uniform(-0.8, 0.8, (n, 1, 3))
    positions = (centres + rng.normal(0.0, 0.25, (n, 3, 3))).reshape(-1, 3)
    normals = rng.normal(0.0, 1.0, (n, 3, 3))
    one = rng.random(n) < 0.4  # faces whose three normals are the same
    normals[one] = normals[one][:, :1]
    colors = rng.uniform(0.2, 1.0, (n, 3, 3))
    uniform = rng.random(n) < 0.5  # faces whose three colours are the same
    colors[uniform] = colors[uniform][:, :1]
    return sr.Mesh(positions, np.arange(3 * n).reshape(n, 3), normals=normals.reshape(-1, 3),
                   colors=colors.reshape(-1, 3))


def _permuted(mesh: sr.Mesh, order: np.ndarray) -> sr.Mesh:
    return sr.Mesh(mesh.positions, mesh.faces[order], normals=mesh.normals, colors=mesh.colors)


@pytest.mark.parametrize("lights", ["point", "directional"])
@pytest.mark.parametrize("path,msaa", [("forward", 1), ("deferred", 1), ("auto", 4)])
def test_a_pixels_shade_does_not_depend_on_face_order(lights, path, msaa):
    rng = np.random.default_rng(7)
    materials = [sr.Material(model="blinn_phong", ks=(0.5, 0.5, 0.5), shininess=20.0),
                 sr.Material(model="blinn_phong", ks=(0.0, 0.0, 0.0), double_sided=True),
                 sr.Material(model="lambert"),
                 sr.Material(model="pbr", metallic=0.3, roughness=0.5, double_sided=True)]
    meshes = [_soup(rng, 150) for _ in materials]
    orders = [rng.permutation(len(m.faces)) for m in meshes]
    cam = sr.PerspectiveCamera(fov_y=50.0, near=0.1, far=20.0)
    cam.look_at((0.3, 0.4, 3.0), (0.0, 0.0, 0.0))
    frames = []
    for shuffle in (False, True):
        scene = sr.Scene(ambient_light=(0.05, 0.05, 0.05))
        for mesh, order, material in zip(meshes, orders, materials):
            scene.add(_permuted(mesh, order) if shuffle else mesh, material=material)
        pose = np.eye(4)
        pose[:3, 3] = (1.0, 1.5, 2.0)
        if lights == "point":
            scene.add(sr.PointLight(color=(1.0, 0.9, 0.8), intensity=8.0), pose=pose)
        scene.add(sr.DirectionalLight(color=(0.8, 0.9, 1.0), intensity=2.0), pose=pose)
        frames.append(sr.Renderer(200, 160, threads=2).render(
            scene, cam, outputs=("color", "instance_id"), cull="none", shading_path=path,
            msaa=msaa, srgb=False))
    a, b = frames
    assert np.array_equal(a.instance_id, b.instance_id)  # the same draw wins every pixel
    covered = a.instance_id >= 0
    assert covered.mean() > 0.3 and len(np.unique(a.instance_id[covered])) == len(materials)
    assert len(np.unique(a.color[covered].reshape(-1, 3), axis=0)) > 1000  # lit, not flat
    assert np.array_equal(a.color, b.color)
