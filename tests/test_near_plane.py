"""The near plane: triangles that reach behind the camera, touch its plane (w = 0) or its centre,
or surround it, are clipped to what lies in front of the near plane, and cover, interpolate and
report depth as the float64 rays through the pixel centres say.

* triangles with vertices behind the camera, on the camera plane and at its centre, against ray
  casting (coverage for each cull mode, depth, barycentric, position, normal), with the cut
  off-screen and across the image; a camera inside a closed icosphere;
* a floor crossing the camera plane: no crack, no overlap, exact depth; triangles entirely behind
  the camera cover nothing (perspective and orthographic);
* attributes of clipped triangles interpolate the source triangle's, not the clip polygon's.

Other files check the near plane through their own feature (listed in ARCHITECTURE.md, "Where the
tests are"): lines (test_lines_points.py), alpha masks (test_alpha_mask.py), the uv shading model
(test_shading_models.py), surface outputs (test_surface_outputs.py), nvdiffrast's clip space
(test_nv.py), AVX2 against generic code (test_simd.py), extreme scales (test_extreme_scales.py).

Where float32 rounding can legitimately move a sample across an edge, only pixel centres within
0.01 px of an edge are excused (``_stable``).
"""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import softrast as sr
from conftest import pixel_rays_view, render, scene_of
from support.exact_pixels import (
    EVERYTHING,
    _assert_finite,
    _centres,
    _scene,
    _stable,
    _view_rays,
    _window,
)


# ------------------------------------------------------------- against float64 ray casting

def _ray_triangle(eye: np.ndarray, dirs: np.ndarray, tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Moller-Trumbore in float64: the ray parameter t and the barycentrics (..., 3) of corners
    (a, b, c) where eye + t d meets the triangle's plane (NaN / inf where parallel)."""
    a, b, c = (np.asarray(v, np.float64) for v in tri)
    e1, e2 = b - a, c - a
    pv = np.cross(dirs, e2)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / (pv @ e1)
        s = eye - a
        u = (pv @ s) * inv
        q = np.cross(s, e1)
        v = (dirs @ q) * inv
        t = (q @ e2) * inv
    return t, np.stack([1.0 - u - v, u, v], -1)


_NEAR_CASES = {
    "vertex_behind_camera": [[-1.0, -0.8, -2.0], [1.2, -0.5, -3.0], [0.3, 0.6, 1.0]],
    "two_vertices_behind": [[-0.4, -0.3, -2.0], [1.2, -0.5, 2.0], [-0.9, 0.6, 1.5]],
    "vertex_on_camera_plane": [[-1.0, -0.8, -2.0], [1.2, -0.5, -3.0], [0.5, 0.3, 0.0]],
    "edge_on_camera_plane": [[-1.0, -0.8, -2.0], [1.2, -0.5, 0.0], [-0.5, 0.9, 0.0]],
    "vertex_at_camera_centre": [[-1.0, -0.8, -2.0], [1.2, -0.5, -3.0], [0.0, 0.0, 0.0]],
}


def _near_cameras(near: float):
    persp = sr.PerspectiveCamera(fov_y=70.0, near=near, far=100.0)
    intr = sr.IntrinsicsCamera(38.0, 41.0, 29.3, 26.1, 64, 48, near=near, far=100.0, convention="opengl")
    for cam in (persp, intr):
        cam.pose = np.eye(4)  # view = world: a vertex with z = 0 has clip w = 0 exactly
    return {"perspective": persp, "intrinsics": intr}


@pytest.mark.parametrize("near", [0.05, 0.3])
@pytest.mark.parametrize("camera", ["perspective", "intrinsics"])
@pytest.mark.parametrize("case", sorted(_NEAR_CASES))
def test_near_plane_clipping_matches_ray_casting(case: str, camera: str, near: float) -> None:
    """Coverage equals ray casting against the triangle (depth >= near) at every pixel centre
    farther than 0.01 px from an edge, for each cull mode (the facing of the 3D triangle);
    depth, barycentric, position and normal agree with the same rays; no NaN anywhere. With
    near = 0.05 the cut lies off-screen (only the w <= 0 handling shows); with near = 0.3 the
    near plane's cut line crosses the image (hundreds of centres lie between 0 and 0.3)."""
    w, h = 64, 48
    cam = _near_cameras(near)[camera]
    mesh = sr.Mesh(np.array(_NEAR_CASES[case]), [[0, 1, 2]])
    tri = mesh.positions.astype(np.float64)
    normal = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    facing = float(normal @ (np.zeros(3) - tri[0]))  # > 0: counter-clockwise as the camera sees it
    unit = normal / np.linalg.norm(normal)
    renderer = sr.Renderer(w, h)
    x, y = _centres(w, h)
    eye, dirs = _view_rays(cam, w, h, x, y)
    t, bary = _ray_triangle(eye, dirs, tri)
    for cull in ("none", "back", "front"):
        keep = cull == "none" or (cull == "back") == (facing > 0)

        def label_at(xx, yy, keep=keep):
            e, d = _view_rays(cam, w, h, xx, yy)
            tt, bb = _ray_triangle(e, d, tri)
            with np.errstate(invalid="ignore"):
                return keep & (bb >= 0).all(-1) & (tt >= cam.near) & (tt <= cam.far)

        expected, sure = _stable(label_at, w, h)
        with np.errstate(invalid="ignore"):
            cut = int((keep & (bary >= 0).all(-1) & (t > 0) & (t < cam.near)).sum())  # clipped away
        f = renderer.render(_scene(mesh), cam, EVERYTHING, cull=cull)
        _assert_finite(f)
        if case == "vertex_at_camera_centre":  # the plane through the eye: seen edge-on, at depth 0
            assert expected.sum() == 0
        elif keep:
            assert expected.sum() > 50
        np.testing.assert_array_equal(f.coverage[sure], expected[sure].astype(np.uint32), err_msg=cull)
        assert f.coverage.max() <= 1 and np.array_equal(f.mask, f.coverage > 0)
        assert (f.depth[~f.mask] == 0).all() and (f.normal[~f.mask] == 0).all()
        hit = f.mask & sure
        if not hit.any():
            continue
        rel = np.abs(f.depth[hit] - t[hit]) / t[hit]
        b = f.barycentric[hit].astype(np.float64)
        assert rel.max() <= 1e-6, rel.max()
        # the exact hit's weights: outside [0, 1] only by the snap (README, "Surface outputs")
        assert b.min() >= -1e-3 and b.max() <= 1.0 + 1e-3 and np.abs(b.sum(-1) - 1.0).max() <= 1e-6
        # position: the frame's weights applied to the corners, lying on the pixel's own ray
        pos = f.position[hit].astype(np.float64)
        np.testing.assert_allclose(pos, b @ tri, atol=2e-6 * np.abs(tri).max())
        reproj = np.hypot(*(_window(cam, w, h, pos) - np.c_[x[hit], y[hit]]).T)
        assert reproj.max() <= 0.01, reproj.max()
        visible = unit if facing > 0 else -unit  # a mesh without material is lit from either side
        np.testing.assert_allclose(f.normal[hit], np.broadcast_to(visible, (int(hit.sum()), 3)), atol=1e-6)
        assert (f.radiance[f.mask] >= 0).all()
        print(f"{case} {camera} near={near} cull={cull}: {int(expected.sum())} covered, {cut} cut by the near plane, {int((~sure).sum())} px "
              f"within 0.01 px of an edge, depth rel {rel.max():.1e}, position {reproj.max():.4f} px off its ray")


@pytest.mark.parametrize("cull, expected", [("none", 1), ("front", 1), ("back", 0)])
def test_camera_inside_closed_icosphere(cull: str, expected: int) -> None:
    """From the centre of a closed mesh every ray leaves it through exactly one face: with
    cull="none" or "front" (the faces are seen from behind) every pixel is covered once, with
    cull="back" none. Depth, triangle id and normal are the polytope's exit face's: t = c_i /
    (n_i . d), minimal over the faces ahead (pixels within 0.01 px of a face edge excused)."""
    w, h = 64, 48
    tm = trimesh.creation.icosphere(subdivisions=3)
    mesh = sr.Mesh(tm.vertices, tm.faces)
    p = mesh.positions.astype(np.float64)
    fv = p[mesh.faces]
    n = np.cross(fv[:, 1] - fv[:, 0], fv[:, 2] - fv[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    c = (n * fv[:, 0]).sum(1)
    assert c.min() > 0.99  # outward faces around the origin: the camera is inside
    cam = sr.PerspectiveCamera(fov_y=120.0, near=0.05, far=10.0)
    cam.look_at((0.0, 0.0, 0.0), (0.3, 0.5, -1.0), up=(0.2, 1.0, 0.0))

    def exit_face(x, y, with_t=False):
        _, d = _view_rays(cam, w, h, x, y)
        nd = d @ n.T
        with np.errstate(divide="ignore"):
            t = np.where(nd > 0, c / np.where(nd > 0, nd, 1.0), np.inf)
        k = t.argmin(-1)
        return (k, np.take_along_axis(t, k[..., None], -1)[..., 0]) if with_t else k

    f = sr.Renderer(w, h).render(_scene(mesh), cam, EVERYTHING, cull=cull)
    _assert_finite(f)
    assert (f.coverage == expected).all(), np.unique(f.coverage)
    if not expected:
        assert (f.depth == 0).all() and (f.triangle_id == -1).all()
        return
    face, sure = _stable(exit_face, w, h)
    _, t = exit_face(*_centres(w, h), with_t=True)
    np.testing.assert_array_equal(f.triangle_id[sure], face[sure])
    rel = np.abs(f.depth - t)[sure] / t[sure]
    assert rel.max() <= 1e-6, rel.max()
    np.testing.assert_allclose(f.normal[sure], -n[face[sure]], atol=1e-6)  # the inside is seen
    b = f.barycentric.astype(np.float64)
    assert b.min() >= -1e-3 and np.abs(b.sum(-1) - 1.0).max() <= 1e-6  # (outside [0, 1]: the snap)
    print(f"inside icosphere, cull={cull}: {w * h} px covered once, {int((~sure).sum())} near an "
          f"edge, depth rel {rel.max():.1e}")


# ------------------------------------------------------------------- crossing the camera plane

def test_floor_crossing_camera_plane():
    w, h, fov = 64, 48, 60.0
    # Floor y = -1, x and z in [-1000, 1000]: it extends behind the camera at the origin.
    pos = np.array([[-1000, -1, 1000], [1000, -1, 1000], [1000, -1, -1000], [-1000, -1, -1000.0]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])  # counter-clockwise seen from above
    cam = sr.PerspectiveCamera(fov_y=fov, near=0.05, far=1e4)
    cam.pose = np.eye(4)
    frame = render(scene_of(sr.Mesh(pos, faces)), cam, w, h, cull="back")
    rays = pixel_rays_view(w, h, fov)
    below = rays[..., 1] < 0  # rows below the horizon (y = 24 lies between rows 23 and 24)
    t = np.where(below, -1.0 / np.where(below, rays[..., 1], -1.0), 0.0)  # ray hits y = -1 at t
    assert (t[below] < 1000).all() and (np.abs(t * rays[..., 0]) < 1000).all()
    np.testing.assert_array_equal(frame.mask, below)
    np.testing.assert_array_equal(frame.coverage, below.astype(np.uint32))  # no crack, no overlap
    # The contract: depth is the exact -z_view of the surface on the ray through the pixel centre
    # (the clipped, snapped vertices must not perturb it beyond float32 rounding).
    np.testing.assert_allclose(frame.depth[below], t[below], rtol=1e-5)
    assert (frame.depth[~below] == 0).all()


def test_triangles_behind_camera_cover_nothing():
    w, h = 48, 40
    # Would project into the image (inverted) if divided by a negative w without clipping.
    pos = np.array([[-1, -1, 5.0], [1, -1, 5.0], [0, 1, 5.0], [-3, -3, 0.01], [3, -3, 0.01],
                    [0, 3, 0.01], [-50, -50, 3.0], [50, -50, 3.0], [0, 50, 3.0]])
    faces = np.array([[0, 1, 2], [0, 2, 1], [3, 4, 5], [3, 5, 4], [6, 7, 8], [6, 8, 7]])
    for cam in (sr.PerspectiveCamera(fov_y=60.0, near=0.05, far=100.0),
                sr.OrthographicCamera(xmag=2.0, ymag=2.0, near=0.05, far=100.0)):
        cam.pose = np.eye(4)
        frame = render(scene_of(sr.Mesh(pos, faces)), cam, w, h, cull="none")
        assert frame.coverage.sum() == 0 and not frame.mask.any()
        assert (frame.triangle_id == -1).all() and (frame.depth == 0).all()


# ----------------------------------------------------------------------------- interpolation

def test_interpolation_through_clipped_triangles():
    # The same floor, but one triangle pair reaching behind the camera: the clipped pieces must
    # interpolate the source triangle's attributes, not the clip polygon's.
    W, H = 100, 80
    positions = np.array([[-3, -1, 2.0], [3, -1, 2.0], [3, -1, -20.0], [-3, -1, -20.0]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    colors = np.stack([(positions[:, 0] + 3) / 6, (positions[:, 2] - 2.0) / -22.0, np.zeros(4)], axis=1)
    scene = sr.Scene()
    scene.add(sr.Mesh(positions, faces, colors=colors))
    cam = sr.PerspectiveCamera(fov_y=60.0, near=0.1, far=50.0)
    cam.pose = np.eye(4)
    # srgb=False: the colours are checked against the linear values (x * 255, rounded).
    frame = sr.Renderer(W, H).render(scene, cam, outputs=("color", "mask"), shading="unlit",
                                     srgb=False)
    i, j = np.nonzero(frame.mask)
    t = np.tan(np.radians(30.0))
    ray_x = ((j + 0.5) / W * 2 - 1) * t * W / H
    ray_y = (1 - (i + 0.5) / H * 2) * t
    depth = -1.0 / ray_y
    x, z = ray_x * depth, -depth
    want = np.stack([(x + 3) / 6, (z - 2.0) / -22.0], axis=1) * 255
    inside = (np.abs(x) < 2.99) & (z > -19.9)
    assert np.abs(frame.color[i, j, :2].astype(float) - want)[inside].max() <= 0.51 + 1e-3
    assert inside.sum() > 1000
