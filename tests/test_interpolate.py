"""Perspective-correct attribute interpolation, checked against the world point each ray hits."""
from __future__ import annotations

import numpy as np

import softrast as sr


def test_vertex_colours_are_perspective_correct():
    # A quad receding steeply from the camera; red = world x in [0, 1], green = world z in [0, 1].
    # Screen-affine interpolation would be off by up to ~0.3 here; perspective-correct is exact.
    W, H = 120, 90
    z0, z1 = -1.2, -12.0
    positions = np.array([[-1, -1, z0], [1, -1, z0], [1, -1, z1], [-1, -1, z1]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    colors = np.stack([(positions[:, 0] + 1) / 2, (positions[:, 2] - z0) / (z1 - z0),
                       np.zeros(4)], axis=1)
    scene = sr.Scene()
    scene.add(sr.Mesh(positions, faces, colors=colors))
    cam = sr.PerspectiveCamera(fov_y=60.0, near=0.1, far=50.0)
    cam.pose = np.eye(4)
    # srgb=False: the colours are checked against the linear values (x * 255, rounded).
    frame = sr.Renderer(W, H).render(scene, cam, outputs=("color", "mask", "depth"), shading="unlit",
                                     srgb=False)

    i, j = np.nonzero(frame.mask)
    t = np.tan(np.radians(30.0))
    ray_x = ((j + 0.5) / W * 2 - 1) * t * W / H  # view-space direction with z = -1
    ray_y = (1 - (i + 0.5) / H * 2) * t
    depth = -1.0 / ray_y  # the floor y = -1
    np.testing.assert_allclose(frame.depth[i, j], depth, rtol=1e-5)
    x, z = ray_x * depth, -depth
    want = np.stack([(x + 1) / 2, (z - z0) / (z1 - z0)], axis=1) * 255
    got = frame.color[i, j, :2].astype(float)
    assert np.abs(got - want).max() <= 0.51 + 1e-3  # rounding to 8 bits only
    assert len(i) > 1500
