"""Extreme but valid input renders correctly: huge and tiny scales, near/far of 1e-6/1e6, slivers."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import softrast as sr

SPHERE = trimesh.creation.icosphere(subdivisions=4)
OUTPUTS = ("depth", "mask", "coverage", "color", "normal")


def _render(scale: float, near: float, far: float) -> sr.Frame:
    scene = sr.Scene()
    scene.add(sr.Mesh(SPHERE.vertices * scale, SPHERE.faces, normals=SPHERE.vertex_normals))
    cam = sr.PerspectiveCamera(fov_y=45.0, near=near, far=far)
    cam.look_at((0.0, 0.0, 3.4 * scale), (0.0, 0.0, 0.0))
    return sr.Renderer(128, 96).render(scene, cam, outputs=OUTPUTS)


@pytest.mark.parametrize("scale, near, far", [
    (1e30, 1e29, 1e31),
    (1e-30, 1e-31, 1e-29),
    (1e-3, 1e-6, 1e6),
    (1e3, 1e-6, 1e6),
    (1.0, 1e-6, 1e6),
])
def test_scaled_scene_renders_like_the_unit_scene(scale, near, far):
    # Scaling the scene, the camera and the planes together changes nothing but depth's unit.
    ref = _render(1.0, 0.05, 100.0)
    frame = _render(scale, near, far)
    np.testing.assert_array_equal(frame.mask, ref.mask)
    np.testing.assert_array_equal(frame.coverage, ref.coverage)
    assert set(np.unique(frame.coverage)) == {0, 1}
    np.testing.assert_allclose(frame.depth[frame.mask] / scale, ref.depth[ref.mask], rtol=2e-6)
    assert np.abs(frame.color.astype(int) - ref.color).max() <= 1
    assert np.isfinite(frame.normal).all()


def test_fan_of_slivers_is_watertight():
    # 2000 triangles a fraction of a pixel wide at the rim, all meeting at the centre pixel.
    n = 2000
    angles = np.linspace(0.0, 2.0 * np.pi, n + 1)[:-1]
    positions = np.vstack([[0.0, 0.0, 0.0], np.stack([np.cos(angles), np.sin(angles), np.zeros(n)], 1)])
    faces = np.array([[0, 1 + i, 1 + (i + 1) % n] for i in range(n)])
    scene = sr.Scene()
    scene.add(sr.Mesh(positions, faces))
    cam = sr.OrthographicCamera(xmag=1.1, ymag=1.1, near=0.1, far=10.0)
    cam.look_at((0.0, 0.0, 3.0), (0.0, 0.0, 0.0))
    frame = sr.Renderer(201, 201).render(scene, cam, outputs=("coverage",), cull="none")
    i, j = np.mgrid[0:201, 0:201]
    r = np.hypot(((j + 0.5) / 201 * 2 - 1) * 1.1, (1 - (i + 0.5) / 201 * 2) * 1.1)
    assert (frame.coverage[r < 0.99] == 1).all()  # the polygon's chords stay within 1e-3 of r = 1
    assert (frame.coverage[r > 1.0] == 0).all()


# A ground quad under a camera 1.7 units up: the common dataset idiom, cut by the near plane
# (and by the guard band when it is wide). The points clipping creates are computed from the
# corners transformed in double, so the cut quad keeps its plane: with float32 corners, a quad
# 1e6 wide read 1e-3 relative off at 50 units, 1e7 wide 1.4e-2, 1e4 wide 3.8e-6. What remains
# for the widest quads is the float32 window position of their far corners, which lie within a
# thousandth of a pixel of the horizon (the README's "Depth" paragraph).
@pytest.mark.parametrize("half, bound", [(1e2, 4e-7), (1e4, 4e-7), (1e6, 2.5e-4), (1e7, 2.5e-4)])
def test_ground_plane_depth_is_exact_to_the_stated_bound(half: float, bound: float) -> None:
    w, h = 640, 480
    quad = np.array([[-half, 0, -half], [half, 0, -half], [half, 0, half], [-half, 0, half]])
    scene = sr.Scene()
    scene.add(sr.Mesh(quad, [[0, 2, 1], [0, 3, 2]]))
    cam = sr.PerspectiveCamera(fov_y=60.0, near=0.05, far=1e8)
    cam.look_at((0.3, 1.7, 0.2), (3.0, 1.2, -10.0), up=(0.0, 1.0, 0.0))
    depth = sr.Renderer(w, h).render(scene, cam, "depth", cull="none").depth
    # the exact ray-plane (y = 0) distance along the viewing axis at each pixel centre
    p = cam.projection_matrix(w, h)
    j, i = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    ray = np.stack([(j * 2 / w - 1 + p[0, 2]) / p[0, 0], (1 - i * 2 / h + p[1, 2]) / p[1, 1], -np.ones((h, w))], -1)
    to_world = np.linalg.inv(cam.view_matrix())
    dy = ray @ to_world[1, :3]
    with np.errstate(divide="ignore"):
        t = -to_world[1, 3] / dy
    seen = (t > 0) & (t < 50.0)
    assert seen.sum() > 0.4 * w * h and (depth[seen] > 0).all()
    rel = np.abs(depth[seen] - t[seen]) / t[seen]
    print(f"half-size {half:g}: depth within 50 units, max relative error {rel.max():.2e}")
    assert rel.max() <= bound
