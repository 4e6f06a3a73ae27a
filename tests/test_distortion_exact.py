"""Lens distortion, exactly: every output pixel's own float64 ray is tested
against every triangle whose footprint can reach it, so geometry thinner than a sample of the
ideal view is still seen where a pixel's ray meets it.

Checked against an exact float64 ray caster written here in NumPy (OpenCV's own inverse of the
lens model, cv2.undistortPoints run to convergence, then ray/triangle tests): needles a hundredth
of a pixel wide land on their pixels, masks agree pixel for pixel (excusing only rays within 1e-6
ideal px of an edge), ids, depth, barycentrics, uv and normals are the hit's, culling is the
pinhole render's, and the result is the same bits for any thread count and instruction set.
"""
from __future__ import annotations

import cv2
import numpy as np
import pytest
import trimesh

import softrast as sr
from softrast import _core

W, H = 320, 240
K = np.array([[220.0, 0.0, 161.3], [0.0, 215.0, 118.6], [0.0, 0.0, 1.0]])
NEAR, FAR = 0.1, 50.0
LENSES = {
    "barrel": np.array([-0.35, 0.15, 0.001, -0.0015, -0.03]),
    "pincushion": np.array([0.22, 0.05, -0.002, 0.001, 0.0]),
    "rational": np.array([0.1, -0.05, 0.001, 0.001, 0.01, 0.3, -0.02, 0.005]),
    "thin_prism": np.array([-0.2, 0.04, 0.001, 0.0005, 0.0, 0.0, 0.0, 0.0, 0.002, -0.001, 0.0015, 0.0005]),
}
OVERSAMPLES = (1, 2, 4)
EDGE_EXCUSE = 1e-6  # ideal pixels: a ray this close to an edge may go either way


def camera(dist, oversample=2):
    """Camera at the origin looking down +z in OpenCV axes: world = camera coordinates."""
    return sr.IntrinsicsCamera.from_opencv(K, np.zeros(3), np.zeros(3), W, H, dist=dist, near=NEAR, far=FAR,
                                           oversample=oversample)


_RAYS: dict[str, np.ndarray] = {}


def exact_rays(name):
    """(H, W, 2) normalized (x', y') of every pixel centre's ray, NaN where the lens model has none,
    by OpenCV's iterative inverse run to convergence (independent of softrast's Newton)."""
    if name not in _RAYS:
        d = LENSES[name]
        jj, ii = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
        pts = np.c_[jj.ravel(), ii.ravel()].reshape(-1, 1, 2)
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 300, 1e-15)
        if hasattr(cv2, "undistortPointsIter"):
            und = cv2.undistortPointsIter(pts, K, d, None, None, crit)
        else:
            und = cv2.undistortPoints(pts, K, d, None, None, None, crit)
        und = und.reshape(H, W, 2)
        # keep only rays that map back onto their pixel (beyond a barrel's fold there is none)
        x, y = und[..., 0], und[..., 1]
        back, _ = cv2.projectPoints(np.dstack([x, y, np.ones_like(x)]).reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, d)
        err = np.hypot(*(back.reshape(H, W, 2) - np.dstack([jj, ii])).transpose(2, 0, 1))
        und[err > 1e-6] = np.nan
        _RAYS[name] = und
    return _RAYS[name]


def exact_cast(name, tris, cull="back"):
    """The exact caster: for each pixel, the nearest triangle (index into tris, (m, 3, 3) world =
    camera space) its ray hits with depth in [NEAR, FAR], -1 for none; the depth; and whether the
    ray passes within EDGE_EXCUSE ideal px of some triangle's edge (either answer is then right)."""
    und = exact_rays(name)
    ok = np.isfinite(und[..., 0])
    x = np.where(ok, und[..., 0], 0.0).ravel()
    y = np.where(ok, und[..., 1], 0.0).ravel()
    best = np.full(x.size, -1)
    depth = np.full(x.size, np.inf)
    near_edge = np.zeros(x.size, bool)
    for k, (a, b, c) in enumerate(np.asarray(tris, np.float32).astype(np.float64)):  # as rendered
        n = np.cross(b - a, c - a)
        front = np.dot(n, -a) > 0.0  # the camera (origin) sees the counter-clockwise side
        if (cull == "back" and not front) or (cull == "front" and front):
            continue
        d_dot_n = x * n[0] + y * n[1] + n[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.dot(a, n) / d_dot_n
            p = np.stack([x * t, y * t, t], axis=-1)
            # barycentric weights from areas, and each edge's distance in ideal pixels
            inside = np.ones(x.size, bool)
            margin = np.full(x.size, np.inf)
            for u, v in ((a, b), (b, c), (c, a)):
                side = np.einsum("ij,j->i", np.cross(v - u, p - u), n)
                inside &= side >= 0.0
                # the edge's plane through the camera; the ray's angle to it, in ideal pixels
                plane = np.cross(u, v)
                ang = (x * plane[0] + y * plane[1] + plane[2]) / np.linalg.norm(plane)
                margin = np.minimum(margin, np.abs(ang) * K[0, 0] * (1.0 + x * x + y * y))
        valid_t = (t >= NEAR) & (t <= FAR)
        hit = inside & valid_t
        near_edge |= valid_t & (margin < EDGE_EXCUSE)
        closer = hit & (t < depth)
        best[closer] = k
        depth[closer] = t[closer]
    best[~ok.ravel()] = -1
    return best.reshape(H, W), np.where(best >= 0, depth, 0.0).reshape(H, W), near_edge.reshape(H, W)


def render(dist, tris, outputs, oversample=2, cull="back", **kw):
    s = sr.Scene()
    s.add(sr.Mesh(np.asarray(tris, np.float32).reshape(-1, 3), np.arange(3 * len(tris)).reshape(-1, 3)))
    return sr.Renderer(W, H, **kw).render(s, camera(dist, oversample), outputs, cull=cull)


# -- needles ------------------------------------------------------------------------------------
def needles(name, width_px=0.01):
    """Thin triangles, one per chosen pixel, each crossing that pixel's exact ray (width_px ideal
    pixels wide where the ray meets it), at varied depths and angles; and the pixels."""
    und = exact_rays(name)
    rng = np.random.default_rng(34)
    pixels, tris = [], []
    for i in range(14, H - 10, 30):
        for j in range(14, W - 10, 37):
            if not np.isfinite(und[i, j]).all():
                continue
            x, y = und[i, j]
            d = np.array([x, y, 1.0])
            z = rng.uniform(1.5, 6.0)
            p = z * d
            ang = rng.uniform(0.0, np.pi)
            u = np.array([np.cos(ang), np.sin(ang), 0.0])
            u -= d * np.dot(u, d) / np.dot(d, d)
            u /= np.linalg.norm(u)
            v = np.cross(d / np.linalg.norm(d), u)
            length = 3.0 * z / K[0, 0]  # 3 ideal px each way
            w = width_px * z / K[0, 0]
            a, b, c = p + length * u, p - length * u + w * v, p - length * u - w * v
            if np.dot(np.cross(b - a, c - a), -a) < 0.0:  # counter-clockwise as seen: front
                b, c = c, b
            pixels.append((i, j))
            tris.append((a, b, c))
    return np.array(pixels), np.array(tris)


@pytest.mark.parametrize("oversample", OVERSAMPLES)
@pytest.mark.parametrize("name", LENSES)
def test_every_needle_lands_on_its_pixel(name: str, oversample: int) -> None:
    pixels, tris = needles(name)
    assert len(pixels) >= 55
    f = render(LENSES[name], tris, ("triangle_id", "mask", "depth", "barycentric", "coverage"), oversample)
    ids = f.triangle_id[pixels[:, 0], pixels[:, 1]]
    landed = ids == np.arange(len(pixels))
    print(f"{name} oversample {oversample}: {landed.sum()} of {len(pixels)} needles (1/100 px wide) on their pixel")
    assert landed.all(), np.flatnonzero(~landed)
    # each the nearest and only hit there, at the needle's depth (z of its centre point)
    assert (f.coverage[pixels[:, 0], pixels[:, 1]] == 1).all()
    best, depth, near_edge = exact_cast(name, tris)
    np.testing.assert_allclose(f.depth[pixels[:, 0], pixels[:, 1]], depth[pixels[:, 0], pixels[:, 1]], rtol=1e-6)
    # and every other pixel is the exact caster's answer too (a needle spans ~6 px along its length)
    agree = (f.triangle_id == best) | near_edge
    assert agree.all(), np.argwhere(~agree)[:5]


# -- masks against the exact caster -------------------------------------------------------------
SQUARE = np.array([[-0.5, -0.4, 2.0], [0.6, -0.5, 2.3], [0.55, 0.45, 2.1], [-0.45, 0.5, 1.9]])


def square_tris():
    a, b, c, d = SQUARE
    return np.array([(a, c, b), (a, d, c)])  # counter-clockwise seen from the origin


def sphere_tris():
    s = trimesh.creation.icosphere(2, radius=0.8)
    return s.vertices[s.faces] + [0.15, -0.1, 2.4]


def centroid(mask):
    rows, cols = np.nonzero(mask)
    return np.array([cols.mean(), rows.mean()])


# Every lens at every oversampling for the square; the sphere (its caster is the slow part of
# this file) at oversample 2, the default: the cast does not depend on the view's oversampling.
@pytest.mark.parametrize("shape, name, oversample",
                         [("square", n, o) for n in LENSES for o in OVERSAMPLES]
                         + [("sphere", n, 2) for n in LENSES])
def test_masks_match_the_exact_caster_pixel_for_pixel(shape: str, name: str, oversample: int) -> None:
    tris = square_tris() if shape == "square" else sphere_tris()
    f = render(LENSES[name], tris, ("mask", "triangle_id", "depth"), oversample)
    best, depth, near_edge = exact_cast(name, tris)
    exact = best >= 0
    wrong = (f.mask != exact) & ~near_edge
    err = np.hypot(*(centroid(f.mask) - centroid(exact)))
    print(f"{shape} {name} oversample {oversample}: {int(exact.sum())} px, {int(wrong.sum())} differ "
          f"({int(near_edge.sum())} within {EDGE_EXCUSE} px of an edge), centroid off by {err:.2e} px")
    assert exact.sum() > 2000
    assert not wrong.any(), np.argwhere(wrong)[:5]
    assert err <= 0.01
    same = (f.triangle_id == best) | near_edge
    assert same.all()
    both = f.mask & exact
    np.testing.assert_allclose(f.depth[both], depth[both], rtol=1e-6)


def test_culling_is_the_pinhole_renders() -> None:
    """A lens distorting by 1e-9 px: ids, depth, uv and normals those of the pinhole render, for every
    cull mode, a mirrored instance and a double-sided material (never culled)."""
    pin = sr.IntrinsicsCamera.from_opencv(K, np.zeros(3), np.zeros(3), W, H, near=NEAR, far=FAR)
    lens = camera([1e-12, 0.0, 0.0, 0.0])
    for c in (pin, lens):
        c.look_at((0.9, 0.6, 2.6), (0.0, 0.0, 0.1), up=(0.0, 1.0, 0.0))
    s = sr.Scene()
    box = sr.Mesh.from_trimesh(trimesh.creation.box((0.8, 0.8, 0.8)))
    ball = sr.Mesh.from_trimesh(trimesh.creation.icosphere(3, radius=0.4))
    uv = ball.positions[:, :2] * 1.2 + 0.5  # smooth: the point's location decides it
    ball = sr.Mesh(ball.positions, ball.faces, normals=ball.normals, uvs=uv)
    s.add(box, pose=trimesh.transformations.translation_matrix((-0.6, 0.0, 0.0)), instance_id=1)
    s.add(ball, pose=np.diag([1.0, -1.2, 1.0, 1.0]) @ trimesh.transformations.translation_matrix((0.5, 0.1, 0.2)),
          instance_id=2)  # mirrored
    s.add(sr.Mesh.from_trimesh(trimesh.creation.icosphere(2, radius=0.3)),
          pose=trimesh.transformations.translation_matrix((0.0, 0.0, 0.7)),
          material=sr.Material(base_color=(0.3, 0.6, 0.2), double_sided=True), instance_id=3)
    outputs = ("triangle_id", "instance_id", "depth", "normal", "uv", "mask")
    for cull in ("back", "front", "none"):
        a = sr.Renderer(W, H).render(s, pin, outputs, cull=cull)
        b = sr.Renderer(W, H).render(s, lens, outputs, cull=cull)
        differ = (a.triangle_id != b.triangle_id) | (a.instance_id != b.instance_id)
        print(f"cull {cull}: {int(differ.sum())} of {int(a.mask.sum())} pixels differ (edges)")
        assert a.mask.sum() > 3000 and differ.sum() <= 0.01 * a.mask.sum()
        same = ~differ & a.mask
        np.testing.assert_allclose(b.depth[same], a.depth[same], rtol=1e-5)
        # the box's normals (its 8 corners' averages) turn fast across a face of a few pixels: the
        # pinhole's snapped vertices (1/256 px) move its weights by ~1e-3 of that
        np.testing.assert_allclose(b.normal[same], a.normal[same], atol=1e-2)
        assert np.median(np.abs(b.normal[same] - a.normal[same])) < 1e-4
        np.testing.assert_allclose(b.uv[same], a.uv[same], atol=2e-3)


def test_barycentrics_uv_and_position_are_the_hits() -> None:
    pixels, tris = needles("rational")
    tris = np.concatenate([tris, sphere_tris()])
    s = sr.Scene()
    pos = tris.reshape(-1, 3).astype(np.float32)
    uv = np.random.default_rng(2).uniform(0, 1, (len(pos), 2))
    s.add(sr.Mesh(pos, np.arange(len(pos)).reshape(-1, 3), uvs=uv))
    f = sr.Renderer(W, H).render(s, camera(LENSES["rational"]), ("triangle_id", "barycentric", "uv", "position",
                                                                    "mask", "alpha", "ray_depth"))
    rows, cols = np.nonzero(f.mask)
    face = f.triangle_id[rows, cols]
    b = f.barycentric[rows, cols].astype(np.float64)
    assert (b >= 0).all() and np.allclose(b.sum(axis=1), 1.0, atol=1e-6)
    corners = pos.astype(np.float64)[3 * face[:, None] + np.arange(3)]
    rebuilt = np.einsum("ij,ijk->ik", b, corners)
    np.testing.assert_allclose(rebuilt, f.position[rows, cols], atol=2e-5)
    np.testing.assert_allclose(np.einsum("ij,ijk->ik", b, uv[3 * face[:, None] + np.arange(3)]), f.uv[rows, cols],
                               atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(f.position[rows, cols].astype(np.float64), axis=1),
                               f.ray_depth[rows, cols], rtol=1e-6)
    assert (f.alpha == f.mask).all()


def test_coverage_counts_every_hit() -> None:
    """cull="none" on a closed sphere: each ray inside the silhouette meets it twice."""
    tris = sphere_tris()
    f = render(LENSES["barrel"], tris, ("coverage", "mask"), cull="none")
    _, _, near_edge = exact_cast("barrel", tris, cull="none")
    inner = f.mask & ~near_edge & (cv2.erode(f.mask.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0)
    assert inner.sum() > 2000 and (f.coverage[inner] == 2).all()


def test_alpha_masked_and_invisible_materials() -> None:
    """A constant alpha below the cutoff draws nothing; a vertex-alpha masked draw is seen where the
    ideal view's alpha-tested samples around the ray show it (as before the exact rays)."""
    s = sr.Scene()
    a, b, c, d = SQUARE
    quad = sr.Mesh(SQUARE, [[0, 2, 1], [0, 3, 2]])
    s.add(quad, material=sr.Material(base_color=(1, 1, 1, 0.2), alpha_mode="mask", alpha_cutoff=0.5))
    f = sr.Renderer(W, H).render(s, camera(LENSES["barrel"]), ("mask", "depth"))
    assert not f.mask.any()
    s = sr.Scene()
    colors = np.array([[1, 1, 1, 1.0], [1, 1, 1, 0.0], [1, 1, 1, 1.0], [1, 1, 1, 1.0]])
    s.add(sr.Mesh(SQUARE, [[0, 2, 1], [0, 3, 2]], colors=colors), material=sr.Material(alpha_mode="mask"))
    cam = camera(LENSES["barrel"])
    f = sr.Renderer(W, H).render(s, cam, ("mask", "triangle_id", "depth", "color"))
    exact = exact_cast("barrel", square_tris())[0] >= 0
    assert 0.3 * exact.sum() < f.mask.sum() < exact.sum()  # the alpha test removes a corner
    assert not (f.mask & ~exact).any()


def test_same_bits_across_threads_and_isa() -> None:
    pixels, tris = needles("thin_prism")
    s = sr.Scene()
    pos = np.concatenate([tris, sphere_tris()]).reshape(-1, 3).astype(np.float32)
    s.add(sr.Mesh(pos, np.arange(len(pos)).reshape(-1, 3), uvs=np.random.default_rng(3).uniform(0, 1, (len(pos), 2))),
          color=(0.4, 0.7, 0.2))
    outputs = tuple(sr.OUTPUTS)
    cam = camera(LENSES["thin_prism"], oversample=2)
    ref = sr.Renderer(W, H, threads=1, simd=False).render(s, cam, outputs, cull="none")
    for r in (sr.Renderer(W, H, threads=2), sr.Renderer(W, H, threads=3, simd=True),
              sr.Renderer(W, H, threads=2, simd=False)):
        f = r.render(s, cam, outputs, cull="none")
        for n in outputs:
            assert np.array_equal(getattr(f, n), getattr(ref, n)), n


def test_geometry_alone_renders_no_ideal_view() -> None:
    """Outputs that come from the rays alone (no colour) do not render the oversampled view."""
    r = sr.Renderer(W, H)
    cam = camera(LENSES["barrel"], oversample=4)
    r.render(_square_scene(), cam, ("depth", "triangle_id", "normal"))
    assert not r.__dict__.get("_distortion_renderers")
    r.render(_square_scene(), cam, ("color", "depth"))
    assert r.__dict__.get("_distortion_renderers")


def _square_scene():
    s = sr.Scene()
    s.add(sr.Mesh(SQUARE, [[0, 2, 1], [0, 3, 2]]))
    return s


def test_bad_core_input_raises_clear_errors() -> None:
    cam = camera(LENSES["barrel"])
    f = sr.Renderer(W, H).render(_square_scene(), cam, ("color", "depth"))  # builds the rays
    rays = cam._rays_cache[(W, H)]
    from softrast.render import _draws

    args = (rays.core, _draws(_square_scene()), tuple(np.eye(3).reshape(-1)), (0.0, 0.0, 0.0))
    ok = _core._distortion_cast(*args, NEAR, FAR, "back", False, ["depth"], None, 1)
    assert np.array_equal(ok["depth"].reshape(H, W), f.depth)
    with pytest.raises(ValueError, match="cull"):
        _core._distortion_cast(*args, NEAR, FAR, "sideways", False, ["depth"], None, 1)
    with pytest.raises(ValueError, match="near, far"):
        _core._distortion_cast(*args, FAR, NEAR, "back", False, ["depth"], None, 1)
    with pytest.raises(ValueError, match="no cast output"):
        _core._distortion_cast(*args, NEAR, FAR, "back", False, ["colour"], None, 1)
    with pytest.raises(ValueError, match="sample needs the view"):
        _core._distortion_cast(*args, NEAR, FAR, "back", False, ["sample"], None, 1)
    ids = np.zeros((rays.height, rays.width), np.int32)
    with pytest.raises(ValueError, match="triangle_id: wrong shape"):
        _core._distortion_cast(*args, NEAR, FAR, "back", False, ["depth"], (ids[1:], ids), 1)
    # a view id naming no face: refused, not read out of bounds
    with pytest.raises(ValueError, match="names no instance or face"):
        _core._distortion_cast(*args, NEAR, FAR, "back", False, ["depth", "sample"], (ids + 5, ids), 2)
    # the grid is checked once, when made: writeable arrays, inconsistent slots
    grid = (rays.valid_flat, rays.nearest, rays.corner, rays.width, rays.view_size, rays.grid_pixel, rays.grid_xy,
            rays.grid_slot, rays.grid_cell_start, *_grid_shape(rays))
    _core._LensRays(*grid)
    with pytest.raises(ValueError, match="read-only"):
        _core._LensRays(*grid[:5], rays.grid_pixel.copy(), *grid[6:])
    bad = rays.grid_slot.copy()
    bad[np.flatnonzero(bad >= 0)[:2]] = bad[np.flatnonzero(bad >= 0)[:2]][::-1]
    bad.setflags(write=False)
    with pytest.raises(ValueError, match="describe one another"):
        _core._LensRays(*grid[:7], bad, *grid[8:])
    with pytest.raises(ValueError, match="cells a side"):
        _core._LensRays(*grid[:9], 0, grid[10], grid[11])


def _grid_shape(rays):
    return rays.grid_shape + (rays.grid_frame,)
