"""softrast.nv: nvdiffrast's rasterize / interpolate on NumPy arrays, checked against closed-form
math and an independent NumPy rasterizer (per-pixel 3x3 solves), not against earlier output.

nvdiffrast's conventions (nvdiffrast/common/rasterize.cu, interpolate.cu): row 0 at the bottom;
pixel (r, c) centre at NDC (2 (c + 0.5) / W - 1, 2 (r + 0.5) / H - 1); rast = (u, v, z/w, id + 1)
with u, v the weights of vertices tri[id, 0] and tri[id, 1]; rast_db = (du/dX, du/dY, dv/dX, dv/dY).
"""
from __future__ import annotations

import numpy as np
import pytest

import softrast as sr
import softrast.nv as dr
from softrast import _core, nv


def centres(height: int, width: int, dx: float = 0.0, dy: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """NDC (X, Y) of every pixel centre, each (h, w), row 0 at the bottom; (dx, dy) in pixels."""
    x = (2.0 * (np.arange(width) + 0.5 + dx)) / width - 1.0
    y = (2.0 * (np.arange(height) + 0.5 + dy)) / height - 1.0
    return np.meshgrid(x, y)


def solve_weights(clip: np.ndarray, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """q = M^-1 (X, Y, 1) per pixel for one triangle: M's columns are the vertices' (x, y, w).

    The clip-space point sum(q_i p_i) projects to (X, Y) with w = 1, so the perspective-correct
    barycentrics are q / sum(q), and the point lies on the triangle in front of the eye iff q >= 0.
    """
    m = clip[:, [0, 1, 3]].T  # rows x, y, w; columns the vertices
    rhs = np.stack([X, Y, np.ones_like(X)], axis=-1)
    return rhs @ np.linalg.inv(m).T  # (h, w, 3)


def reference(clip_tris: np.ndarray, height: int, width: int, dx: float = 0.0, dy: float = 0.0,
              depth_clip: bool = True):
    """An independent rasterizer: (ids, bary (h, w, 3), z/w) with the nearest z/w winning (the
    earlier triangle on a tie), -1 / 0 where nothing is visible. Clipping to -w <= z <= w is the
    condition |z/w| <= 1 on the visible point (depth_clip=False drops it)."""
    X, Y = centres(height, width, dx, dy)
    ids = np.full((height, width), -1)
    best = np.full((height, width), np.inf)
    bary = np.zeros((height, width, 3))
    for k, clip in enumerate(clip_tris):
        if abs(np.linalg.det(clip[:, [0, 1, 3]])) < 1e-12:
            continue  # degenerate: seen edge-on, covers nothing
        q = solve_weights(clip, X, Y)
        zw = q @ clip[:, 2]
        hit = (q >= 0).all(axis=-1) & (q.sum(axis=-1) > 0) & (zw < best)
        if depth_clip:
            hit &= np.abs(zw) <= 1.0
        ids[hit], best[hit] = k, zw[hit]
        bary[hit] = (q / q.sum(axis=-1, keepdims=True))[hit]
    return ids, bary, np.where(ids >= 0, best, 0.0)


def unambiguous(clip_tris: np.ndarray, height: int, width: int, eps: float = 0.01,
                union: bool = False) -> np.ndarray:
    """Pixels whose reference result is the same with the centre moved by eps px in any direction:
    away from edges, where vertex snapping (1/256 px) and the fill rule cannot matter. union:
    only coverage by any triangle counts (edges shared inside the union are not ambiguous)."""
    def result(dx, dy):
        ids = reference(clip_tris, height, width, dx, dy)[0]
        return ids >= 0 if union else ids

    centre = result(0.0, 0.0)
    same = np.ones(centre.shape, dtype=bool)
    for dx, dy in ((eps, 0), (-eps, 0), (0, eps), (0, -eps)):
        same &= result(dx, dy) == centre
    return same


def perspective(fov_y: float = 60.0, aspect: float = 1.0, near: float = 0.1, far: float = 10.0) -> np.ndarray:
    t = 1.0 / np.tan(np.radians(fov_y) / 2.0)
    return np.array([[t / aspect, 0, 0, 0], [0, t, 0, 0],
                     [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)], [0, 0, -1, 0]])


def to_clip(points: np.ndarray, mvp: np.ndarray) -> np.ndarray:
    return (np.c_[points, np.ones(len(points))] @ mvp.T).astype(np.float32)


# nvdiffrast's samples/torch/triangle.py
TRI_POS = np.array([[[-0.8, -0.8, 0, 1], [0.8, -0.8, 0, 1], [-0.8, 0.8, 0, 1]]], dtype=np.float32)
TRI_COL = np.array([[[1, 0, 0], [0, 1, 0], [0, 0, 1]]], dtype=np.float32)
TRI = np.array([[0, 1, 2]], dtype=np.int32)

# A perspective triangle: vertices at different depths, so the barycentrics are not affine.
PERSP_TRI = to_clip(np.array([[-1.0, -0.8, -1.5], [1.2, -0.5, -4.0], [-0.2, 1.0, -2.5]]),
                    perspective(aspect=4 / 3))[None]


def test_triangle_sample():
    """nvdiffrast's first sample, 256x256: coverage, (u, v, z/w, id) and the colours in closed form."""
    glctx = dr.RasterizeCudaContext()
    rast, rast_db = dr.rasterize(glctx, TRI_POS, TRI, resolution=[256, 256])
    out, out_da = dr.interpolate(TRI_COL, rast, TRI)
    assert rast.shape == rast_db.shape == (1, 256, 256, 4) and rast.dtype == rast_db.dtype == np.float32
    assert out.shape == (1, 256, 256, 3) and out.dtype == np.float32 and out_da.shape == (1, 256, 256, 0)

    X, Y = centres(256, 256)
    s, t = (X + 0.8) / 1.6, (Y + 0.8) / 1.6  # along the edges from vertex 0 to 1 and 0 to 2
    inside = (s > 0) & (t > 0) & (s + t < 1)
    tie = np.isclose(s + t, 1.0, rtol=0, atol=1e-12)  # pixel centres exactly on the hypotenuse
    covered = rast[0, ..., 3] > 0
    np.testing.assert_array_equal(covered[~tie], inside[~tie])
    u, v = 1 - s - t, s  # u weighs vertex 0, v vertex 1
    np.testing.assert_allclose(rast[0, covered, 0], u[covered], atol=1e-6)
    np.testing.assert_allclose(rast[0, covered, 1], v[covered], atol=1e-6)
    assert (rast[0, covered, 2] == 0).all() and (rast[0, covered, 3] == 1).all()
    assert (rast[0, ~covered] == 0).all() and (out[0, ~covered] == 0).all()
    # Screen-space derivatives of an affine triangle: du/dX = -(2 / 256) / 1.6, dv/dX = +(2 / 256) / 1.6.
    step = 2 / 256 / 1.6
    np.testing.assert_allclose(rast_db[0, covered], np.broadcast_to([-step, -step, step, 0], (covered.sum(), 4)),
                               atol=1e-7)
    np.testing.assert_allclose(out[0, covered], np.stack([u, v, 1 - u - v], -1)[covered], atol=1e-6)
    # Flipped to top-down as the sample saves it: the blue vertex (-0.8, 0.8) is at the top left.
    img = out[0, ::-1]
    assert img[40, 27].argmax() == 2 and img[225, 30].argmax() == 0 and img[225, 220].argmax() == 1


def test_perspective_triangle_closed_form():
    """u, v, z/w against per-pixel 3x3 solves; the id; zeros elsewhere."""
    h, w = 48, 64
    rast, _ = dr.rasterize(PERSP_TRI, TRI, (h, w))
    ids, bary, zw = reference(PERSP_TRI[0][None].astype(np.float64), h, w)
    sure = unambiguous(PERSP_TRI[0][None].astype(np.float64), h, w)
    covered = rast[0, ..., 3] > 0
    np.testing.assert_array_equal(covered[sure], (ids >= 0)[sure])
    assert covered.sum() > 300
    both = covered & (ids >= 0)
    np.testing.assert_allclose(rast[0, both, 0], bary[both, 0], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(rast[0, both, 1], bary[both, 1], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(rast[0, both, 2], zw[both], rtol=1e-5, atol=1e-6)
    assert not np.allclose(np.diff(rast[0, both, 0]), np.diff(rast[0, both, 0]).mean())  # not affine


def test_rast_db_matches_finite_differences():
    """rast_db is d(u, v) per pixel step right (X) and up (Y), channel order (du/dX, du/dY, dv/dX,
    dv/dY): central differences of the closed form at +-0.001 px, and of rast between neighbours."""
    h, w = 48, 64
    clip = PERSP_TRI[0].astype(np.float64)
    rast, rast_db = dr.rasterize(PERSP_TRI, TRI, (h, w))
    eps = 1e-3

    def bary(dx, dy):
        q = solve_weights(clip, *centres(h, w, dx, dy))
        return q / q.sum(axis=-1, keepdims=True)

    d_dx = (bary(eps, 0) - bary(-eps, 0)) / (2 * eps)
    d_dy = (bary(0, eps) - bary(0, -eps)) / (2 * eps)
    expect = np.stack([d_dx[..., 0], d_dy[..., 0], d_dx[..., 1], d_dy[..., 1]], axis=-1)
    covered = rast[0, ..., 3] > 0
    np.testing.assert_allclose(rast_db[0, covered], expect[covered], rtol=1e-4, atol=1e-8)
    assert (rast_db[0, ~covered] == 0).all()
    # The same from the image itself: rows increase upwards, columns to the right.
    inner = covered[1:-1, 1:-1] & covered[1:-1, 2:] & covered[1:-1, :-2] & covered[2:, 1:-1] & covered[:-2, 1:-1]
    du_dx = (rast[0, 1:-1, 2:, 0] - rast[0, 1:-1, :-2, 0]) / 2
    dv_dy = (rast[0, 2:, 1:-1, 1] - rast[0, :-2, 1:-1, 1]) / 2
    np.testing.assert_allclose(du_dx[inner], rast_db[0, 1:-1, 1:-1, 0][inner], rtol=0.02, atol=1e-4)
    np.testing.assert_allclose(dv_dy[inner], rast_db[0, 1:-1, 1:-1, 3][inner], rtol=0.02, atol=1e-4)


def test_interpolated_clip_position_is_the_pixel_centre():
    """Interpolating the clip-space positions themselves gives back each pixel centre's NDC."""
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    model_view = np.eye(4)
    model_view[2, 3] = -3.0
    pos = to_clip(np.asarray(sphere.vertices), perspective() @ model_view)
    tri = np.asarray(sphere.faces, dtype=np.int32)
    h, w = 40, 56
    rast, _ = dr.rasterize(pos[None], tri, (h, w))
    out, _ = dr.interpolate(pos, rast, tri)
    covered = rast[0, ..., 3] > 0
    assert covered.mean() > 0.2
    X, Y = centres(h, w)
    x, y, z, w_clip = out[0, covered].T.astype(np.float64)
    np.testing.assert_allclose(x / w_clip, X[covered], atol=1e-5)
    np.testing.assert_allclose(y / w_clip, Y[covered], atol=1e-5)
    np.testing.assert_allclose(z / w_clip, rast[0, covered, 2], atol=1e-5)
    assert not out[0, ~covered].any()


def test_out_da_matches_finite_differences():
    """out_da = (dA/dX, dA/dY) per selected attribute, in diff_attrs' order (negative indices too)."""
    h, w = 48, 64
    clip = PERSP_TRI[0].astype(np.float64)
    attr = np.array([[0.3, -2.0, 5.0], [1.5, 0.25, -1.0], [-0.7, 3.0, 2.0]], dtype=np.float32)
    rast, rast_db = dr.rasterize(PERSP_TRI, TRI, (h, w))
    out, out_da = dr.interpolate(attr, rast, TRI, rast_db, diff_attrs=[2, -3])
    assert out_da.shape == (1, h, w, 4) and out_da.dtype == np.float32
    eps = 1e-3

    def value(dx, dy):
        q = solve_weights(clip, *centres(h, w, dx, dy))
        return (q / q.sum(axis=-1, keepdims=True)) @ attr.astype(np.float64)

    dx = (value(eps, 0) - value(-eps, 0)) / (2 * eps)
    dy = (value(0, eps) - value(0, -eps)) / (2 * eps)
    covered = rast[0, ..., 3] > 0
    np.testing.assert_allclose(out[0, covered], value(0, 0)[covered], rtol=1e-5, atol=1e-5)
    expect = np.stack([dx[..., 2], dy[..., 2], dx[..., 0], dy[..., 0]], axis=-1)
    np.testing.assert_allclose(out_da[0, covered], expect[covered], rtol=1e-4, atol=1e-6)
    assert (out_da[0, ~covered] == 0).all()
    _, all_da = dr.interpolate(attr, rast, TRI, rast_db, diff_attrs="all")
    np.testing.assert_array_equal(all_da[..., 4:6], out_da[..., 0:2])
    np.testing.assert_array_equal(all_da[..., 0:2], out_da[..., 2:4])


def random_triangles(rng: np.random.Generator, count: int) -> np.ndarray:
    """(count, 3, 4) clip-space triangles, all in front of the eye (w > 0), some partly outside."""
    ndc = rng.uniform(-1.3, 1.3, size=(count, 3, 3))
    ndc[:, :, 2] = rng.uniform(-0.9, 0.9, size=(count, 3))
    w = rng.uniform(0.5, 3.0, size=(count, 3, 1))
    return np.concatenate([ndc * w, w], axis=-1)


def crossing_triangles(rng: np.random.Generator, count: int) -> np.ndarray:
    """(count, 3, 4) clip-space triangles with vertices behind the eye (w < 0) and beyond the near
    and far planes (|z| > w): every one is clipped."""
    clip = rng.uniform(-1.5, 1.5, size=(count, 3, 4))
    clip[:, :, 3] = rng.uniform(-1.0, 2.0, size=(count, 3))
    clip[:, 0, 3] = rng.uniform(0.5, 2.0, size=count)  # one vertex in front, so most are seen
    clip[:, :, 2] = rng.uniform(-1.6, 1.6, size=(count, 3)) * np.abs(clip[:, :, 3])
    return clip


@pytest.mark.parametrize("make", [random_triangles, crossing_triangles])
def test_coverage_and_depth_match_a_point_in_triangle_reference(rng, make):
    """Random overlapping triangles of both windings (in front of the eye, or crossing the near
    and far planes and w = 0): the visible triangle at every pixel centre equals the reference's
    (nearest z/w, clipped to -w <= z <= w), except within 0.01 px of an edge."""
    clip_tris = make(rng, 24)
    pos = clip_tris.reshape(-1, 4).astype(np.float32)
    tri = np.arange(len(pos), dtype=np.int32).reshape(-1, 3)
    h, w = 72, 96
    rast, _ = dr.rasterize(pos[None], tri, (h, w))
    clip64 = pos.reshape(-1, 3, 4).astype(np.float64)
    ids, bary, zw = reference(clip64, h, w)
    sure = unambiguous(clip64, h, w)
    assert sure.mean() > 0.9 and (ids >= 0).mean() > 0.3
    got = rast[0, ..., 3].astype(np.int64) - 1
    np.testing.assert_array_equal(got[sure], ids[sure])
    agree = sure & (ids >= 0)
    np.testing.assert_allclose(rast[0, agree, :2], bary[agree, :2], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(rast[0, agree, 2], zw[agree], rtol=1e-5, atol=1e-6)


def test_nearer_wins_and_both_windings_are_drawn():
    """Two overlapping triangles of opposite winding: the one with the smaller z/w is seen in
    either order (GL_LESS on z/w, no culling); an exact tie keeps the earlier one."""
    near_ccw = [[-0.9, -0.9, -0.5, 1], [0.9, -0.9, -0.5, 1], [0.0, 0.9, -0.5, 1]]
    far_cw = [[-0.9, 0.9, 0.5, 1], [0.9, 0.9, 0.5, 1], [0.0, -0.9, 0.5, 1]]
    tri = np.array([[0, 1, 2], [3, 4, 5]], dtype=np.int32)
    for first, second, nearer_id in ((near_ccw, far_cw, 1), (far_cw, near_ccw, 2)):
        rast, _ = dr.rasterize(np.array([first + second], np.float32), tri, (32, 32))
        assert rast[0, 16, 16, 3] == nearer_id and rast[0, 16, 16, 2] == -0.5
        assert set(np.unique(rast[0, ..., 3])) == {0, 1, 2}  # both windings drawn
    tied = np.array([near_ccw + near_ccw], np.float32)
    rast, _ = dr.rasterize(tied, tri, (32, 32))
    assert set(np.unique(rast[0, ..., 3])) == {0, 1}


def test_near_plane_crossing():
    """A triangle reaching behind the eye (a vertex with w < 0) is clipped at the near plane
    inside the view: its coverage is the clipped polygon's (not the unclipped triangle's), with
    the barycentrics of the whole triangle."""
    view = np.array([[-1.5, -0.3, -4.0], [1.5, -0.3, -4.0], [0.0, 0.3, 1.0]])  # the last one behind
    pos = to_clip(view, perspective(near=1.0, far=20.0))
    assert pos[2, 3] < 0
    h, w = 60, 80
    rast, _ = dr.rasterize(pos[None], TRI, (h, w))
    clip64 = pos.astype(np.float64)[None]
    ids, bary, zw = reference(clip64, h, w)
    sure = unambiguous(clip64, h, w)
    covered = rast[0, ..., 3] > 0
    np.testing.assert_array_equal(covered[sure], (ids >= 0)[sure])
    both = covered & (ids >= 0)
    np.testing.assert_allclose(rast[0, both, :2], bary[both, :2], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(rast[0, both, 2], zw[both], rtol=1e-5, atol=1e-6)
    assert covered.sum() > 300 and (rast[0, covered, 2] >= -1).all()
    # The near plane's cut runs through the view: the unclipped triangle covers more.
    unclipped = reference(clip64, h, w, depth_clip=False)[0] >= 0
    assert (unclipped & ~covered & sure).sum() > 50


def test_floor_through_the_near_plane_has_no_cracks():
    """A jittered grid floor (y = -1) reaching behind the eye, clipped by the near plane (its cut
    visible at NDC y = -0.87) and the guard band: every pixel centre between the cut and the
    horizon is covered (clipped shared edges stay watertight), none below the cut."""
    rng = np.random.default_rng(3)
    n = 16
    gx, gz = np.meshgrid(np.linspace(-20, 20, n + 1), np.linspace(-30, 10, n + 1))
    gx[1:-1, 1:-1] += rng.uniform(-0.8, 0.8, size=(n - 1, n - 1))
    gz[1:-1, 1:-1] += rng.uniform(-0.8, 0.8, size=(n - 1, n - 1))
    points = np.stack([gx.ravel(), np.full(gx.size, -1.0), gz.ravel()], axis=1)
    k = np.arange(n * (n + 1)).reshape(n, n + 1)[:, :n].ravel()  # lower-left corner of each cell
    tri = np.concatenate([np.stack([k, k + 1, k + n + 2], 1), np.stack([k, k + n + 2, k + n + 1], 1)])
    pos = to_clip(points, perspective(near=2.0, far=50.0))
    h, w = 96, 96
    rast, _ = dr.rasterize(pos[None], tri.astype(np.int32), (h, w))
    covered = rast[0, ..., 3] > 0
    _, Y = centres(h, w)
    cut = -1.0 / (2.0 * np.tan(np.radians(30)))  # the floor at the near plane, z_view = -2
    assert covered[(Y > cut + 0.03) & (Y < -0.1)].all()
    assert not covered[(Y < cut - 0.03) | (Y > 0.0)].any()


def test_far_plane_clips():
    """z/w > 1 is clipped away: a triangle crossing the far plane keeps only its near part."""
    pos = np.array([[[-0.9, -0.9, 0.0, 1.0], [0.9, -0.9, 0.0, 1.0], [0.0, 0.9, 3.0, 1.0]]], np.float32)
    rast, _ = dr.rasterize(pos, TRI, (64, 64))
    covered = rast[0, ..., 3] > 0
    X, Y = centres(64, 64)
    z = 3.0 * (Y + 0.9) / 1.8  # z/w along the triangle (w = 1: affine)
    inside = reference(pos.astype(np.float64), 64, 64)[0] >= 0
    np.testing.assert_array_equal(covered, inside)
    assert covered.any() and (z[covered] <= 1.0 + 1e-9).all() and not covered[z > 1.05].any()


def test_cube_sample():
    """nvdiffrast's cube sample's geometry and projection (samples/torch/cube.py, util.py:
    projection(x=0.4) flips y), a closed cube with per-face colours through a separate index
    buffer: the visible face at every pixel matches the reference's."""
    corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    tri = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                    [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], dtype=np.int32)
    x, n, f = 0.4, 1.0, 50.0
    proj = np.array([[n / x, 0, 0, 0], [0, n / -x, 0, 0], [0, 0, -(f + n) / (f - n), -(2 * f * n) / (f - n)],
                     [0, 0, -1, 0]])
    s, c = np.sin(0.7), np.cos(0.7)
    rot = np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1]])
    rot = np.array([[1, 0, 0, 0], [0, np.cos(-0.4), np.sin(-0.4), 0], [0, -np.sin(-0.4), np.cos(-0.4), 0],
                    [0, 0, 0, 1]]) @ rot
    mv = np.eye(4)
    mv[2, 3] = -3.5
    pos = to_clip(corners, proj @ mv @ rot)
    h = w = 64
    rast, rast_db = dr.rasterize(dr.RasterizeGLContext(), pos[None], tri, resolution=[h, w])
    clip64 = pos.astype(np.float64)[tri]
    ids = reference(clip64, h, w)[0]
    sure = unambiguous(clip64, h, w)
    got = rast[0, ..., 3].astype(np.int64) - 1
    np.testing.assert_array_equal(got[sure], ids[sure])
    faces, pixels = np.unique(got[sure & (got >= 0)] // 2, return_counts=True)
    assert len(faces) == 3 and pixels.min() > 100  # a cube seen from a corner direction shows three faces
    # Per-face colours through their own index buffer (cube_d.npz style): face k has colour k.
    col_idx = np.arange(36, dtype=np.int32).reshape(12, 3)
    vtx_col = np.repeat(np.arange(6, dtype=np.float32), 6)[:, None]
    color, _ = dr.interpolate(vtx_col[None], rast, col_idx)
    np.testing.assert_allclose(color[0, got >= 0, 0], got[got >= 0] // 2, atol=1e-5)


def test_row_zero_is_the_bottom():
    """A triangle in the upper half of NDC (y > 0) lands in the upper half of the rows."""
    pos = np.array([[[-0.5, 0.2, 0, 1], [0.5, 0.2, 0, 1], [0.0, 0.9, 0, 1]]], np.float32)
    rast, _ = dr.rasterize(pos, TRI, (40, 30))
    rows = np.nonzero(rast[0, ..., 3])[0]
    assert rows.min() >= 24 and rows.max() <= 38  # Y = 2 (r + 0.5) / 40 - 1 in [0.2, 0.9]


def test_range_mode_equals_instanced_mode():
    """Range mode draws tri[start:start + count] for each image; ids index the whole tri."""
    rng = np.random.default_rng(7)
    clip_tris = random_triangles(rng, 10)
    pos = clip_tris.reshape(-1, 4).astype(np.float32)
    tri = np.arange(len(pos), dtype=np.int32).reshape(-1, 3)[::-1].copy()
    ranges = np.array([[0, 4], [4, 6], [3, 0], [2, 5]], dtype=np.int32)
    rast, rast_db = dr.rasterize(pos, tri, (40, 50), ranges=ranges)
    assert rast.shape == (4, 40, 50, 4)
    for k, (start, count) in enumerate(ranges):
        if count == 0:
            assert (rast[k] == 0).all() and (rast_db[k] == 0).all()
            continue
        one, one_db = dr.rasterize(pos[None], tri[start:start + count], (40, 50))
        covered = one[0, ..., 3] > 0
        np.testing.assert_array_equal(rast[k, ..., :3], one[0, ..., :3])
        np.testing.assert_array_equal(rast[k, ..., 3], np.where(covered, one[0, ..., 3] + start, 0))
        np.testing.assert_array_equal(rast_db[k], one_db[0])
    # interpolate in range mode: 2-D attr, the whole tri.
    attr = np.arange(len(pos), dtype=np.float32)[:, None]
    out, _ = dr.interpolate(attr, rast, tri)
    covered = rast[..., 3] > 0
    ids = rast[covered, 3].astype(int) - 1
    u, v = rast[covered, 0], rast[covered, 1]
    expect = u * attr[tri[ids, 0], 0] + v * attr[tri[ids, 1], 0] + (1 - u - v) * attr[tri[ids, 2], 0]
    np.testing.assert_allclose(out[covered, 0], expect, rtol=1e-5, atol=1e-5)


def test_instanced_minibatch_and_attr_broadcast():
    """Each image of a minibatch has its own positions; attr of minibatch 1 is broadcast."""
    shifted = TRI_POS.copy()
    shifted[0, :, 0] += 0.5
    pos = np.concatenate([TRI_POS, shifted])
    rast, _ = dr.rasterize(pos, TRI, (32, 32))
    alone, _ = dr.rasterize(shifted, TRI, (32, 32))
    np.testing.assert_array_equal(rast[1], alone[0])
    out_b, _ = dr.interpolate(TRI_COL, rast, TRI)  # (1, 3, 3): broadcast
    out_2d, _ = dr.interpolate(TRI_COL[0], rast, TRI)  # (3, 3): range-mode attr
    out_full, _ = dr.interpolate(np.concatenate([TRI_COL, TRI_COL]), rast, TRI)
    np.testing.assert_array_equal(out_b, out_2d)
    np.testing.assert_array_equal(out_b, out_full)
    different, _ = dr.interpolate(np.concatenate([TRI_COL, 2 * TRI_COL]), rast, TRI)
    np.testing.assert_allclose(different[1], 2 * out_b[1], rtol=1e-6)


def test_call_forms_and_contexts():
    """With and without a context (positional or glctx=), keyword arguments, and a GL context
    without derivatives; all the same numbers."""
    plain = dr.rasterize(PERSP_TRI, TRI, [24, 32])
    for result in (dr.rasterize(dr.RasterizeCudaContext(), PERSP_TRI, TRI, resolution=(24, 32)),
                   dr.rasterize(dr.RasterizeGLContext(), PERSP_TRI, TRI, [24, 32], None, False),
                   dr.rasterize(glctx=dr.RasterizeCudaContext(device="cuda:0"), pos=PERSP_TRI, tri=TRI,
                                resolution=(np.int64(24), 32)),
                   dr.rasterize(PERSP_TRI, tri=TRI, resolution=(24, 32), grad_db=False)):
        np.testing.assert_array_equal(result[0], plain[0])
        np.testing.assert_array_equal(result[1], plain[1])
    ctx = dr.RasterizeGLContext(output_db=False, mode="manual")
    ctx.set_context()
    rast, rast_db = dr.rasterize(ctx, PERSP_TRI, TRI, (24, 32))
    ctx.release_context()
    np.testing.assert_array_equal(rast, plain[0])
    assert rast_db.shape == (1, 24, 32, 0)
    with pytest.raises(ValueError, match="rast_db"):
        dr.interpolate(TRI_COL, rast, TRI, rast_db, diff_attrs="all")
    _, out_da = dr.interpolate(TRI_COL, rast, TRI, rast_db)  # no diff_attrs: fine
    assert out_da.shape == (1, 24, 32, 0)
    with pytest.raises(TypeError, match="rasterize"):
        dr.rasterize(PERSP_TRI, TRI)
    assert sr.nv is nv


def test_triangle_id_float_encoding():
    """Ids past 2**24 use nvdiffrast's biased float bits (common.h) and decode back exactly."""
    ids = np.array([0, 1, 2**24 - 1, 2**24, 2**24 + 1, 123456789, 889192447])
    enc = nv._ids_to_float(ids)
    assert enc.dtype == np.float32 and (enc[:4] == ids[:4]).all() and enc[4] != ids[4]
    np.testing.assert_array_equal(nv._float_to_ids(enc), ids)
    assert np.isfinite(enc).all() and len(np.unique(enc)) == len(ids)


def test_empty_and_offscreen():
    """Triangles wholly outside the view, degenerate or behind the eye give zeros."""
    pos = np.array([[[2, 2, 0, 1], [3, 2, 0, 1], [2, 3, 0, 1],             # off to the right
                     [0, 0, 0, 1], [0.5, 0.5, 0, 1], [1, 1, 0, 1],         # zero area
                     [-0.5, -0.5, 0, -1], [0.5, -0.5, 0, -1], [0, 0.5, 0, -1]]], np.float32)  # w < 0
    tri = np.arange(9, dtype=np.int32).reshape(3, 3)
    rast, rast_db = dr.rasterize(pos, tri, (16, 16))
    assert not rast.any() and not rast_db.any()
    out, _ = dr.interpolate(np.ones((9, 2), np.float32), rast, tri)
    assert not out.any()


def test_large_triangles_through_the_guard_band():
    """A triangle reaching far outside the view (clipped to the +-4 w guard band in float64)
    and one with a vertex at w near 0 cover exactly what the reference covers."""
    pos = np.array([[-50.0, -40.0, 0.2, 1.0], [60.0, -35.0, 0.2, 1.0], [0.3, 80.0, 0.2, 1.0],
                    [-0.5, -0.6, -0.5, 1.0], [0.7, -0.2, 0.5, 1.0], [1e-3, 2e-3, 1e-7, 1e-6]], np.float32)
    tri = np.array([[0, 1, 2], [3, 4, 5]], dtype=np.int32)
    h, w = 50, 70
    rast, _ = dr.rasterize(pos[None], tri, (h, w))
    clip64 = pos.astype(np.float64)[tri]
    ids, bary, _ = reference(clip64, h, w)
    sure = unambiguous(clip64, h, w)
    got = rast[0, ..., 3].astype(np.int64) - 1
    np.testing.assert_array_equal(got[sure], ids[sure])
    assert set(np.unique(got)) == {0, 1}  # the large one covers the whole view
    agree = sure & (ids >= 0)
    np.testing.assert_allclose(rast[0, agree, :2], bary[agree, :2], rtol=1e-5, atol=1e-6)


def test_clipping_keeps_shared_edges_watertight():
    """Two triangles sharing an edge that crosses the near plane: every pixel of their union is
    covered exactly once (no crack, no double cover) after clipping."""
    view = np.array([[-2.0, -1.0, -8.0], [2.0, -1.0, -8.0], [2.0, -1.0, 3.0], [-2.0, -1.0, 3.0]])
    pos = to_clip(view, perspective(near=0.5))
    tri = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32)
    h, w = 64, 64
    rast, _ = dr.rasterize(pos[None], tri, (h, w))
    covered = rast[0, ..., 3] > 0
    quad = reference(pos.astype(np.float64)[tri], h, w)[0] >= 0
    sure = unambiguous(pos.astype(np.float64)[tri], h, w, union=True)  # the diagonal is not an edge
    # Every pixel of the quad's interior, along the shared diagonal too, is covered: no crack.
    np.testing.assert_array_equal(covered[sure], quad[sure])
    assert covered.sum() > 500


BAD_CALLS = [
    (lambda: dr.rasterize(TRI_POS[0, :, :3][None], TRI, (8, 8)), "pos must have shape"),
    (lambda: dr.rasterize(TRI_POS[0, 0], TRI, (8, 8)), "pos must have shape"),
    (lambda: dr.rasterize(TRI_POS.astype(bool), TRI, (8, 8)), "pos must hold"),
    (lambda: dr.rasterize(TRI_POS.astype(complex), TRI, (8, 8)), "pos must hold"),
    (lambda: dr.rasterize(np.where(np.arange(4) == 1, np.nan, TRI_POS), TRI, (8, 8)),
     r"pos contains NaN or inf, at pos\[0, 0, 1\]"),
    (lambda: dr.rasterize(TRI_POS * np.array([1, 1, 1, np.inf], np.float32), TRI, (8, 8)), "pos contains NaN or inf"),
    (lambda: dr.rasterize(TRI_POS.astype(np.float64) * np.array([1, 1, 1, 1e39]), TRI, (8, 8)),
     r"pos contains 1e\+39, beyond float32's range, at pos\[0, 0, 3\]"),
    (lambda: dr.rasterize(TRI_POS, TRI.astype(np.float32), (8, 8)), "tri must hold integers"),
    (lambda: dr.rasterize(TRI_POS, TRI[0], (8, 8)), "tri must have shape"),
    (lambda: dr.rasterize(TRI_POS, TRI + 1, (8, 8)), r"tri\[0\] = \[1, 2, 3\]"),
    (lambda: dr.rasterize(TRI_POS, -TRI, (8, 8)), r"tri\[0\]"),
    (lambda: dr.rasterize(TRI_POS, TRI, (0, 8)), "resolution height"),
    (lambda: dr.rasterize(TRI_POS, TRI, (8, -1)), "resolution width"),
    (lambda: dr.rasterize(TRI_POS, TRI, (8, 8.0)), "resolution width must be an int"),
    (lambda: dr.rasterize(TRI_POS, TRI, (8, True)), "resolution width must be an int"),
    (lambda: dr.rasterize(TRI_POS, TRI, 8), "resolution must be"),
    (lambda: dr.rasterize(TRI_POS, TRI, (8, sr.MAX_IMAGE_SIDE + 1)), "resolution width"),
    (lambda: dr.rasterize(TRI_POS[0], TRI, (8, 8)), "ranges is required"),
    (lambda: dr.rasterize(TRI_POS[0], TRI, (8, 8), ranges=[[0, 2]]), r"ranges\[0\]"),
    (lambda: dr.rasterize(TRI_POS[0], TRI, (8, 8), ranges=[[-1, 1]]), r"ranges\[0\]"),
    (lambda: dr.rasterize(TRI_POS[0], TRI, (8, 8), ranges=[0, 1]), "ranges must have shape"),
    (lambda: dr.rasterize(TRI_POS[0], TRI, (8, 8), ranges=[[0.0, 1.0]]), "ranges must hold"),
    (lambda: dr.rasterize(TRI_POS, TRI, (8, 8), grad_db=1), "grad_db"),
    (lambda: dr.rasterize(None, TRI, (8, 8)), "pos must be"),
    (lambda: dr.rasterize(glctx="gl", pos=TRI_POS, tri=TRI, resolution=(8, 8)), "glctx"),
    # a wrong context given positionally is the context's fault, not pos's
    (lambda: dr.rasterize(object(), TRI_POS, TRI, (8, 8)), r"^glctx must be"),
    (lambda: dr.rasterize(object(), TRI_POS, TRI, resolution=(8, 8)), r"^glctx must be"),
    (lambda: dr.rasterize(object(), TRI, (8, 8)), r"^pos must"),  # 3 arguments: pos, tri, resolution
    (lambda: dr.RasterizeGLContext(mode="auto"), "mode"),
    (lambda: dr.RasterizeGLContext(output_db=1), "output_db"),
]


@pytest.mark.parametrize("call, match", BAD_CALLS, ids=[m for _, m in BAD_CALLS])
def test_bad_rasterize_input_raises_value_error(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_bad_interpolate_input_raises_value_error():
    rast, rast_db = dr.rasterize(TRI_POS, TRI, (16, 16))
    cases = [
        (lambda: dr.interpolate(TRI_COL[0, :, 0], rast, TRI), "attr must have shape"),
        (lambda: dr.interpolate(TRI_COL.astype(bool), rast, TRI), "attr must hold"),
        (lambda: dr.interpolate(np.where(TRI_COL == 1, np.nan, TRI_COL), rast, TRI),
         r"attr contains NaN.*attr\[0, 0, 0\]"),
        (lambda: dr.interpolate(np.concatenate([TRI_COL] * 2), rast, TRI), "minibatch"),
        (lambda: dr.interpolate(TRI_COL, rast[..., :3], TRI), "rast must have shape"),
        (lambda: dr.interpolate(TRI_COL, rast * np.nan, TRI), "rast contains NaN"),
        (lambda: dr.interpolate(TRI_COL, rast, TRI + 1), r"tri\[0\]"),
        (lambda: dr.interpolate(TRI_COL, rast, TRI[:0]), "beyond tri's 0 triangles"),
        (lambda: dr.interpolate(TRI_COL, rast, TRI, diff_attrs="all"), "rast_db is required"),
        (lambda: dr.interpolate(TRI_COL, rast, TRI, rast_db[..., :2], diff_attrs="all"), "rast_db must have"),
        (lambda: dr.interpolate(TRI_COL, rast, TRI, np.where(rast_db == 0, np.inf, rast_db), diff_attrs=[0]),
         "rast_db contains"),
        (lambda: dr.interpolate(TRI_COL, rast, TRI, rast_db, diff_attrs=[3]), "diff_attrs: index 3"),
        (lambda: dr.interpolate(TRI_COL, rast, TRI, rast_db, diff_attrs=[-4]), "diff_attrs: index -4"),
        (lambda: dr.interpolate(TRI_COL, rast, TRI, rast_db, diff_attrs="some"), "diff_attrs must be"),
        (lambda: dr.interpolate(TRI_COL, rast, TRI, rast_db, diff_attrs=[[0]]), "diff_attrs must be a flat"),
        (lambda: dr.interpolate(TRI_COL, rast, TRI, rast_db, diff_attrs=[0.5]), "diff_attrs must hold"),
    ]
    for call, match in cases:
        with pytest.raises(ValueError, match=match):
            call()


# -- the memory budget ---------------------------------------------------------------------------

QUAD_POS = np.array([[[-1, -1, 0, 1], [1, -1, 0, 1], [1, 1, 0, 1], [-1, 1, 0, 1]]], np.float32)
QUAD_TRI = np.array([[0, 1, 2], [0, 2, 3]], np.int32)


@pytest.fixture
def budget():
    before = sr.get_memory_budget()
    yield sr.set_memory_budget
    sr.set_memory_budget(before)


def test_rasterize_refuses_outputs_over_the_budget_before_allocating(budget):
    """8 images of 2048 x 2048 need 1 GiB of rast and rast_db: refused under 64 MiB, naming the
    arguments that set the size (once allocated regardless: 512 MiB under 64 MiB)."""
    budget(64 * 2**20)
    pos = np.broadcast_to(QUAD_POS, (8, 4, 4))
    with pytest.raises(ValueError, match=r"rasterize.*8 images \(pos\).*resolution \(2048, 2048\).*memory budget"):
        dr.rasterize(pos, QUAD_TRI, (2048, 2048))
    with pytest.raises(ValueError, match=r"ranges.*resolution \(2048, 2048\)"):
        dr.rasterize(QUAD_POS[0], QUAD_TRI, (2048, 2048), ranges=np.array([[0, 2]] * 8, np.int32))
    rast, _ = dr.rasterize(QUAD_POS, QUAD_TRI, (64, 64))  # small calls still run
    assert (rast[..., 3] > 0).all()


def test_rasterize_refuses_triangle_work_over_the_budget(budget):
    """The clipping and culling work grows with the triangles of an image: named by tri."""
    n = 20000
    pos = np.zeros((1, 3 * n, 4), np.float32)
    pos[..., 3] = 1.0
    tri = np.arange(3 * n, dtype=np.int32).reshape(-1, 3)
    budget(4 * 2**20)
    with pytest.raises(ValueError, match=rf"rasterize.*{n} triangles \(tri\)"):
        dr.rasterize(pos, tri, (8, 8))


@pytest.mark.parametrize("case", ["cover", "triangles", "minibatch"])
def test_rasterize_budget_bounds_what_it_allocates(budget, case):
    """The check counts at least what rasterize allocates (NumPy's allocations, traced): a budget
    one byte under the traced peak is refused."""
    import tracemalloc

    if case == "cover":
        args = (QUAD_POS, QUAD_TRI, (300, 200))
    elif case == "minibatch":
        args = (np.repeat(QUAD_POS * np.float32([0.5, 0.5, 1, 1]), 5, axis=0), QUAD_TRI, (64, 96))
    else:
        rng = np.random.default_rng(1)
        pos = rng.uniform(-1.5, 1.5, (1, 3000, 4)).astype(np.float32)
        pos[..., 3] = rng.uniform(0.5, 2.0, (1, 3000))
        args = (pos, np.arange(3000, dtype=np.int32).reshape(-1, 3), (32, 32))
    tracemalloc.start()
    try:
        dr.rasterize(*args)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    budget(peak - 1)
    with pytest.raises(ValueError, match="memory budget"):
        dr.rasterize(*args)


def test_core_entry_point_checks_its_arrays():
    """_core._rasterize_clip (nv's raster) refuses what it could not read or write safely, even
    though nv's checks come first: wrong dtypes, an index outside pos, ranges outside tri, an
    output of the wrong shape or read-only, rast and rast_db sharing memory."""
    pos = np.ascontiguousarray(TRI_POS)
    ranges = np.array([[0, 1]], np.int64)
    rast = np.zeros((1, 8, 8, 4), np.float32)
    read_only = rast.copy()
    read_only.flags.writeable = False
    cases = [((pos.astype(np.float64), TRI, ranges, 8, 8, rast, None), "pos"),
             ((pos, TRI + 1, ranges, 8, 8, rast, None), "tri"),
             ((pos, TRI.astype(np.int64), ranges, 8, 8, rast, None), "tri"),
             ((pos, TRI, np.array([[0, 2]], np.int64), 8, 8, rast, None), "ranges"),
             ((pos, TRI, ranges, 8, 9, rast, None), "rast"),
             ((pos, TRI, ranges, 8, 8, read_only, None), "rast"),
             ((pos, TRI, ranges, 8, 8, rast, rast), "share memory"),
             ((pos, TRI, ranges, 0, 8, np.zeros((1, 8, 0, 4), np.float32), None), "width")]
    for args, match in cases:
        with pytest.raises(ValueError, match=match):
            _core._rasterize_clip(*args)
    _core._rasterize_clip(pos, TRI, ranges, 8, 8, rast, None)
    np.testing.assert_array_equal(rast, dr.rasterize(TRI_POS, TRI, (8, 8))[0])
