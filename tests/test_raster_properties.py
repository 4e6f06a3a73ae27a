"""Property-based tests of the raster over random closed meshes, poses and cameras:
watertight coverage, depth within each visible triangle's depth range, barycentrics in [0, 1]
summing to 1, no NaN anywhere, and the same bits for any thread count and instruction set.

The meshes are convex hulls of random points (closed, consistently wound outward), so a camera
outside one sees each pixel centre of its silhouette on exactly one front face: with back-face
culling, `coverage` is 0 or 1 everywhere and 2 without culling (front and back). derandomize=True:
the same examples every run.
"""
from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import softrast as sr

W, H = 96, 72
OUTPUTS = ("depth", "coverage", "triangle_id", "barycentric", "position", "normal", "color", "radiance")


def hull(seed: int, n: int, squash: float) -> trimesh.Trimesh:
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(n, 3)) * [1.0, squash, 1.0]
    return trimesh.convex.convex_hull(pts)


@st.composite
def scenes(draw):
    seed = draw(st.integers(0, 2**31 - 1))
    n = draw(st.integers(5, 60))
    squash = draw(st.sampled_from([1.0, 0.3, 1e-3]))  # 1e-3: a hull of slivers
    scale = draw(st.sampled_from([1e-3, 1.0, 1e3]))
    mesh = hull(seed, n, squash)
    rng = np.random.default_rng(seed + 1)
    axis = rng.normal(size=3)
    pose = trimesh.transformations.rotation_matrix(rng.uniform(0, 2 * np.pi), axis)
    pose[:3, :3] *= scale
    radius = scale * float(np.linalg.norm(mesh.vertices, axis=1).max())
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    distance = radius * draw(st.sampled_from([1.5, 3.0, 20.0]))
    kind = draw(st.sampled_from(["perspective", "orthographic"]))
    if kind == "perspective":
        cam = sr.PerspectiveCamera(fov_y=draw(st.sampled_from([10.0, 45.0, 120.0])),
                                   near=1e-3 * distance, far=10 * distance)
    else:
        cam = sr.OrthographicCamera(xmag=1.2 * radius, ymag=0.9 * radius, near=1e-3 * distance, far=10 * distance)
    up = np.array([0.0, 1.0, 0.0]) if abs(direction[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    cam.look_at(distance * direction + rng.normal(size=3) * 0.2 * radius, (0.0, 0.0, 0.0), up=up)
    return mesh, pose, cam


@settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(scenes())
def test_random_closed_meshes(case) -> None:
    mesh, pose, cam = case
    scene = sr.Scene()
    m = sr.Mesh.from_trimesh(mesh)
    scene.add(m, pose=pose)
    ref = sr.Renderer(W, H, threads=1, simd=False).render(scene, cam, OUTPUTS, cull="back")
    # no NaN anywhere
    for name in ("depth", "barycentric", "position", "normal", "radiance"):
        assert np.isfinite(getattr(ref, name)).all(), name
    # watertight: every pixel covered at most once by the front faces of a closed convex mesh...
    assert set(np.unique(ref.coverage)) <= {0, 1}
    seen = ref.coverage == 1
    assert ((ref.triangle_id >= 0) == seen).all()
    # ...and exactly twice by front and back faces without culling
    both = sr.Renderer(W, H).render(scene, cam, ("coverage",), cull="none").coverage
    assert set(np.unique(both)) <= {0, 2} and ((both == 2) == seen).all()
    if not seen.any():
        return
    # depth within the visible triangle's corners' depth range (float32 rounding aside)
    world = mesh.vertices @ pose[:3, :3].T + pose[:3, 3]
    view = world @ cam.view_matrix()[:3, :3].T + cam.view_matrix()[:3, 3]
    corner_depth = -view[mesh.faces[ref.triangle_id[seen]]][..., 2]
    d = ref.depth[seen].astype(np.float64)
    slack = 1e-5 * np.abs(corner_depth).max(axis=1)
    assert (d >= corner_depth.min(axis=1) - slack).all() and (d <= corner_depth.max(axis=1) + slack).all()
    # barycentrics summing to 1 and rebuilding the position from the posed corners; in [0, 1]
    # but for the snap: the exact hit of a pixel centre the snapped triangle covers lies within
    # sqrt(2) / 512 px of the true triangle, so a weight leaves [0, 1] by at most that over the
    # triangle's height there (perspective: times the corners' spread of w)
    b = ref.barycentric[seen].astype(np.float64)
    clip = np.c_[world, np.ones(len(world))] @ (cam.projection_matrix(W, H) @ cam.view_matrix()).T
    win = np.c_[(clip[:, 0] / clip[:, 3] + 1) * W / 2, (1 - clip[:, 1] / clip[:, 3]) * H / 2]
    tri = win[mesh.faces[ref.triangle_id[seen]]]  # (n, 3, 2)
    area2 = np.abs((tri[:, 1, 0] - tri[:, 0, 0]) * (tri[:, 2, 1] - tri[:, 0, 1])
                   - (tri[:, 1, 1] - tri[:, 0, 1]) * (tri[:, 2, 0] - tri[:, 0, 0]))
    opposite = np.stack([np.linalg.norm(tri[:, (k + 2) % 3] - tri[:, (k + 1) % 3], axis=1) for k in range(3)], 1)
    w = np.abs(clip[:, 3])[mesh.faces[ref.triangle_id[seen]]]
    spread = (w.max(1) / w.min(1))[:, None] ** 2
    bound = 2 ** 0.5 / 512 * opposite / area2[:, None] * spread * 1.01 + 1e-6
    assert (b >= -bound).all() and (b <= 1 + bound).all()
    np.testing.assert_allclose(b.sum(axis=1), 1.0, atol=1e-6)
    rebuilt = np.einsum("ij,ijk->ik", b, world[mesh.faces[ref.triangle_id[seen]]])
    extent = np.abs(world).max()
    np.testing.assert_allclose(rebuilt, ref.position[seen], atol=1e-5 * extent)
    # the same bits for any thread count and instruction set
    for threads, simd in ((3, True), (2, False), (1, True)):
        got = sr.Renderer(W, H, threads=threads, simd=simd).render(scene, cam, OUTPUTS, cull="back")
        for name in OUTPUTS:
            assert np.array_equal(getattr(got, name), getattr(ref, name)), (name, threads, simd)
