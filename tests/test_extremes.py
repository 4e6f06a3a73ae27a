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
