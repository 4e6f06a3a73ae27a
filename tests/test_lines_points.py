"""Lines and points (softrast.Lines, softrast.Points) against NumPy references written here,
independent of the C++: Bresenham and DDA (all octants, both endpoints), viewport and near-plane
clipping, thick-line footprints, depth tests against triangles and each other, perspective-correct
depth and colour, point clouds, every output's value on primitive pixels, determinism across
threads and instruction sets, msaa and scanline renders, and argument checks."""
from __future__ import annotations

import pickle

import numpy as np
import pytest

import softrast as sr
from softrast.reference.encoding import srgb_curve
from conftest import pixel_mesh, pixel_ortho, window_to_world

W, H = 150, 130  # 3 x 3 tiles: lines cross tile borders
DEPTH = 10.0     # pixel_ortho's geometry plane (conftest.Z_PLANE) as a depth


# -- references ----------------------------------------------------------------------------------

def bresenham(x0: int, y0: int, x1: int, y1: int) -> list[tuple[int, int]]:
    """The integer all-octant Bresenham loop (one error term), both endpoints included."""
    out = []
    dx, sx = abs(x1 - x0), (1 if x0 < x1 else -1)
    dy, sy = -abs(y1 - y0), (1 if y0 < y1 else -1)
    err = dx + dy
    while True:
        out.append((x0, y0))
        if x0 == x1 and y0 == y1:
            return out
        e2 = 2 * err
        if e2 >= dy:
            err += dy
            x0 += sx
        if e2 <= dx:
            err += dx
            y0 += sy


def dda(x0: int, y0: int, x1: int, y1: int) -> list[tuple[int, int]]:
    """DDA over the major axis: the minor coordinate m0 + k dm / M, rounded half up."""
    steps = max(abs(x1 - x0), abs(y1 - y0))
    if steps == 0:
        return [(x0, y0)]
    out = []
    for k in range(steps + 1):
        x = x0 + (k * (x1 - x0)) / steps
        y = y0 + (k * (y1 - y0)) / steps
        out.append((int(np.floor(x + 0.5)), int(np.floor(y + 0.5))))
    return out


def capsule(a, b, width: float, w: int, h: int) -> np.ndarray:
    """Pixels whose centre lies within width / 2 of the segment a-b (window coordinates), in the
    form the rule is stated: 4 cross^2 <= width^2 |d|^2 inside the segment, else the nearer end."""
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    ux, uy = xx + 0.5 - a[0], yy + 0.5 - a[1]
    dx, dy = b[0] - a[0], b[1] - a[1]
    len2 = dx * dx + dy * dy
    w2 = float(np.float32(width)) ** 2
    dot = ux * dx + uy * dy
    near_a = 4.0 * (ux * ux + uy * uy) <= w2
    vx, vy = ux - dx, uy - dy
    near_b = 4.0 * (vx * vx + vy * vy) <= w2
    cross = ux * dy - uy * dx
    near_line = 4.0 * cross * cross <= w2 * len2
    return np.where((dot <= 0) | (len2 == 0), near_a, np.where(dot >= len2, near_b, near_line))


def to_mask(pixels, w: int = W, h: int = H) -> np.ndarray:
    m = np.zeros((h, w), bool)
    for x, y in pixels:
        if 0 <= x < w and 0 <= y < h:
            m[y, x] = True
    return m


def window_points(xy) -> np.ndarray:
    """World points that pixel_ortho puts at window positions `xy` (avoid integer coordinates:
    the pixel of a point is floor(window))."""
    return window_to_world(np.asarray(xy, dtype=np.float64), W, H)


def render(scene, cam=None, outputs=sr.OUTPUTS, threads=2, simd=True, w=W, h=H, **kw):
    cam = pixel_ortho(w, h) if cam is None else cam
    return sr.Renderer(w, h, threads=threads, simd=simd).render(scene, cam, outputs=outputs, **kw)


def line_scene(xy, width=1.0, colors=None, instance_id=3) -> sr.Scene:
    scene = sr.Scene()
    scene.add(sr.Lines(window_points(xy), [[0, 1]], colors=colors, width=width),
              instance_id=instance_id)
    return scene


# Endpoints around a centre, in every octant, on the axes and diagonals, and zero length.
CENTRE = (70, 60)
OFFSETS = [(0, 0), (1, 0), (0, 1), (-1, 0), (0, -1), (1, 1), (-1, -1), (1, -1), (-1, 1),
           (40, 0), (-40, 0), (0, 45), (0, -45), (30, 30), (-30, 30), (30, -30), (-30, -30),
           (37, 11), (11, 37), (-11, 37), (-37, 11), (-37, -11), (-11, -37), (11, -37), (37, -11),
           (2, 1), (2, -1), (-2, 1), (-2, -1), (1, 2), (-1, 2), (1, -2), (-1, -2), (64, 3),
           (5, 58), (-60, -21)]


def frac(rng) -> tuple[float, float]:
    return tuple(rng.uniform(0.1, 0.9, 2))


@pytest.mark.parametrize("algorithm,reference", [("bresenham", bresenham), ("dda", dda)])
def test_lines_match_reference_in_every_octant(algorithm, reference, rng):
    for ox, oy in OFFSETS:
        x0, y0 = CENTRE
        x1, y1 = x0 + ox, y0 + oy
        (fx0, fy0), (fx1, fy1) = frac(rng), frac(rng)
        frame = render(line_scene([(x0 + fx0, y0 + fy0), (x1 + fx1, y1 + fy1)]),
                       outputs=("mask",), line_algorithm=algorithm)
        expected = to_mask(reference(x0, y0, x1, y1))
        assert expected[y0, x0] and expected[y1, x1]  # both endpoints
        np.testing.assert_array_equal(frame.mask, expected, err_msg=f"{algorithm} {(ox, oy)}")


def test_bresenham_and_dda_differ_where_their_rounding_differs():
    # A tie leaving toward -y: Bresenham rounds away from the start (y - 1), DDA half up (y).
    xy = [(10.5, 20.5), (12.5, 19.5)]
    b = render(line_scene(xy), outputs=("mask",), line_algorithm="bresenham").mask
    d = render(line_scene(xy), outputs=("mask",), line_algorithm="dda").mask
    assert b[19, 11] and not b[20, 11]
    assert d[20, 11] and not d[19, 11]


@pytest.mark.parametrize("algorithm,reference", [("bresenham", bresenham), ("dda", dda)])
def test_lines_leaving_the_canvas_are_the_reference_restricted_to_the_image(algorithm, reference,
                                                                            rng):
    ends = [((-50, 10), (200, 100)), ((75, -80), (60, 300)), ((-30, -40), (-5, 500)),
            ((149, 129), (400, 200)), ((-1000, 65), (1200, 64)), ((20, 20), (-300, 129))]
    for (x0, y0), (x1, y1) in ends:
        (fx0, fy0), (fx1, fy1) = frac(rng), frac(rng)
        frame = render(line_scene([(x0 + fx0, y0 + fy0), (x1 + fx1, y1 + fy1)]),
                       outputs=("mask",), line_algorithm=algorithm)
        np.testing.assert_array_equal(frame.mask, to_mask(reference(x0, y0, x1, y1)),
                                      err_msg=str(((x0, y0), (x1, y1))))


def perspective_camera(w=W, h=H):
    cam = sr.PerspectiveCamera(fov_y=60.0, near=0.5, far=100.0)
    cam.pose = np.eye(4)  # at the origin, looking down -z
    return cam


def project(cam, points, w=W, h=H):
    """Window x, y and clip w of world points (camera pose identity: world = view)."""
    proj = cam.projection_matrix(w, h)
    p = np.c_[np.asarray(points, np.float64), np.ones(len(points))] @ proj.T
    x = (p[:, 0] / p[:, 3] + 1.0) * 0.5 * w
    y = (1.0 - p[:, 1] / p[:, 3]) * 0.5 * h
    return x, y, p[:, 3]


def test_line_crossing_the_near_plane_draws_only_its_front_part():
    cam = perspective_camera()
    a = np.array([0.3, 0.2, -5.0])
    b = np.array([-0.9, 0.4, 5.0])  # behind the camera
    scene = sr.Scene()
    scene.add(sr.Lines(np.stack([a, b]), [[0, 1]]), instance_id=1)
    frame = render(scene, cam)
    # The reference clips at depth = near, in double, then projects.
    pa, pb = scene.primitives[0].item.positions.astype(np.float64)
    t = (-pa[2] - cam.near) / ((-pa[2] - cam.near) - (-pb[2] - cam.near))
    clipped = pa + t * (pb - pa)
    x, y, _ = project(cam, np.stack([pa, clipped]))
    expected = to_mask(bresenham(*map(int, np.floor([x[0], y[0], x[1], y[1]]))))
    assert expected.any()
    np.testing.assert_array_equal(frame.mask, expected)
    assert np.isfinite(frame.depth).all() and np.isfinite(frame.radiance).all()
    assert (frame.depth[frame.mask] >= cam.near * (1 - 1e-6)).all()
    assert (frame.depth[frame.mask] <= 5.0 * (1 + 1e-6)).all()
    # Wholly behind the camera: nothing.
    behind = sr.Scene()
    behind.add(sr.Lines([[0, 0, 1.0], [1, 1, 3.0]], [[0, 1]]))
    assert not render(behind, cam, outputs=("mask",)).mask.any()


@pytest.mark.parametrize("width", [1.0, 2.0, 3.0, 5.0, 2.5])
def test_thick_line_footprint(width, rng):
    for ox, oy in [(50, 0), (0, 40), (37, 11), (-25, 30), (30, 30), (-44, -7), (0, 0), (3, -1)]:
        x0, y0 = CENTRE
        x1, y1 = x0 + ox, y0 + oy
        (fx0, fy0), (fx1, fy1) = frac(rng), frac(rng)
        scene = line_scene([(x0 + fx0, y0 + fy0), (x1 + fx1, y1 + fy1)], width=width)
        mask = render(scene, outputs=("mask",)).mask
        if width <= 1.0:
            expected = to_mask(bresenham(x0, y0, x1, y1))
        else:
            stored = scene.primitives[0].item.positions.astype(np.float64)
            a, b = stored[:, :2] * [1, -1] + [W / 2.0, H / 2.0]  # pixel_ortho's window
            expected = capsule(a, b, width, W, H)
            # About a rectangle of the width plus two half-disc caps (an axis-aligned line may
            # gain or lose a row of pixels to the lattice).
            length = np.hypot(*(b - a))
            area = length * width + np.pi * width ** 2 / 4
            assert abs(int(mask.sum()) - area) <= length + 2 * width + 4
        np.testing.assert_array_equal(mask, expected, err_msg=f"width {width} {(ox, oy)}")


def test_line_depth_against_a_triangle_pixel_exact():
    # A triangle at depth 10 over the whole image; a line from depth 5 to 15 through it.
    tri = pixel_mesh(np.array([[-10.0, -10.0], [-10.0, 400.0], [400.0, -10.0]]),
                     np.array([[0, 1, 2]]), W, H)
    scene = sr.Scene()
    scene.add(tri, instance_id=0)
    xy = np.array([(5.3, 7.7), (141.6, 101.2)])
    pts = window_points(xy)
    pts[:, 2] = [-5.0, -15.0]
    scene.add(sr.Lines(pts, [[0, 1]], colors=[[1, 0, 0], [0, 0, 1]]), instance_id=9)
    frame = render(scene, shading="unlit")
    line = to_mask(bresenham(5, 7, 141, 101))
    # Analytic depth at each line pixel: the segment's point nearest the pixel centre.
    ys, xs = np.nonzero(line)
    e = xy[1] - xy[0]
    s = np.clip(((xs + 0.5 - xy[0, 0]) * e[0] + (ys + 0.5 - xy[0, 1]) * e[1]) / (e @ e), 0, 1)
    depth = 5.0 + 10.0 * s
    assert np.abs(depth - DEPTH).min() > 1e-3  # no pixel near a tie
    front = depth < DEPTH
    assert front.any() and (~front).any()
    np.testing.assert_array_equal(frame.instance_id[ys, xs], np.where(front, 9, 0))
    np.testing.assert_array_equal(frame.triangle_id[ys, xs], np.where(front, -1, 0))
    np.testing.assert_allclose(frame.depth[ys, xs], np.where(front, depth, DEPTH), rtol=1e-6)
    # Off the line: the triangle alone.
    assert (frame.instance_id[~line] == 0).all()


def test_perspective_correct_depth_and_colour_along_a_line():
    cam = perspective_camera()
    a = np.array([-1.2, -0.7, -2.0])
    b = np.array([1.5, 0.9, -20.0])
    ca, cb = np.array([1.0, 0.0, 0.25]), np.array([0.0, 1.0, 0.75])
    scene = sr.Scene()
    scene.add(sr.Lines(np.stack([a, b]), [[0, 1]], colors=np.stack([ca, cb])), instance_id=4)
    frame = render(scene, cam)
    lines = scene.primitives[0].item
    pa, pb = lines.positions.astype(np.float64)
    x, y, w = project(cam, np.stack([pa, pb]))
    ys, xs = np.nonzero(frame.mask)
    assert len(xs) > 50
    np.testing.assert_array_equal(
        frame.mask, to_mask(bresenham(*map(int, np.floor([x[0], y[0], x[1], y[1]])))))
    ex, ey = x[1] - x[0], y[1] - y[0]
    s = np.clip(((xs + 0.5 - x[0]) * ex + (ys + 0.5 - y[0]) * ey) / (ex * ex + ey * ey), 0, 1)
    u = (s / w[1]) / ((1 - s) / w[0] + s / w[1])
    p3 = pa + u[:, None] * (pb - pa)
    # u is the perspective-correct parameter: the 3-D point projects to the window point s.
    px, py, _ = project(cam, p3)
    np.testing.assert_allclose(px, x[0] + s * ex, atol=1e-6)
    np.testing.assert_allclose(py, y[0] + s * ey, atol=1e-6)
    np.testing.assert_allclose(frame.depth[ys, xs], -p3[:, 2], rtol=1e-5)
    colour = ca + u[:, None] * (cb - ca)
    np.testing.assert_allclose(frame.radiance[ys, xs], colour, atol=1e-5)
    np.testing.assert_allclose(frame.position[ys, xs], p3, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(frame.ray_depth[ys, xs], np.linalg.norm(p3, axis=1), rtol=1e-5)
    # Screen-space (affine) interpolation would be visibly wrong here.
    assert np.abs(u - s).max() > 0.1


def point_winners(frame, px, py, depth, w, h):
    """The z-buffer of one-pixel points at pixels (px, py): per pixel the nearest, then the first
    drawn. Asserts the frame's mask is exactly the pixels won; returns the winners' indices and
    their pixels' rows and columns."""
    idx = np.flatnonzero((px >= 0) & (px < w) & (py >= 0) & (py < h))
    flat = py[idx] * w + px[idx]
    order = np.lexsort((idx, depth[idx], flat))
    flat_sorted = flat[order]
    first = np.r_[True, flat_sorted[1:] != flat_sorted[:-1]]
    expected_mask = np.zeros(w * h, bool)
    expected_mask[flat_sorted[first]] = True
    np.testing.assert_array_equal(frame.mask.ravel(), expected_mask)
    wy, wx = np.divmod(flat_sorted[first], w)
    return idx[order][first], wy, wx


def test_point_cloud_lands_where_numpy_projects(rng):
    n = 100_000
    w, h = 300, 200
    xy = rng.uniform(-20.0, [w + 20.0, h + 20.0], (n, 2))
    xy += (np.abs(xy - np.round(xy)) < 1e-3) * 0.01  # keep off pixel borders
    pts = window_to_world(xy, w, h)
    pts[:, 2] = -rng.uniform(2.0, 90.0, n)
    colors = rng.uniform(0, 1, (n, 3)).astype(np.float32)
    scene = sr.Scene()
    scene.add(sr.Points(pts, colors=colors), instance_id=5)
    frame = render(scene, outputs=("mask", "depth", "radiance", "instance_id", "triangle_id"),
                   w=w, h=h, threads=3)
    stored = scene.primitives[0].item.positions.astype(np.float64)
    px = np.floor(stored[:, 0] + w / 2.0).astype(np.int64)
    py = np.floor(h / 2.0 - stored[:, 1]).astype(np.int64)
    depth = -stored[:, 2]
    winner, wy, wx = point_winners(frame, px, py, depth, w, h)
    np.testing.assert_allclose(frame.depth[wy, wx], depth[winner], rtol=1e-6)
    np.testing.assert_array_equal(frame.radiance[wy, wx], colors[winner])
    assert (frame.instance_id[frame.mask] == 5).all() and (frame.triangle_id == -1).all()


@pytest.mark.parametrize("size", [1.0, 0.25])
def test_perspective_point_cloud_with_a_pose_against_numpy(size, rng):
    """Points of size <= 1 under a perspective camera and a pose: each lands in the pixel holding
    its pinhole projection, the nearest (then the first) wins, and its colour, depth, position and
    ray depth are the point's own (read back for the winner only)."""
    n, w, h, fy = 60_000, 211, 147, 120.0
    pose = np.eye(4)
    pose[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]  # 90 degrees about z
    pose[:3, 3] = [0.25, -0.5, -1.0]
    # Window positions away from pixel borders (float32 storage moves them by < 1e-4 px) and
    # depths, some off the image, a few pairs sharing a pixel.
    xy = rng.uniform(-30.0, [w + 30.0, h + 30.0], (n, 2))
    xy = np.floor(xy) + rng.uniform(0.01, 0.99, (n, 2))
    xy[1::50] = xy[::50][: len(xy[1::50])]
    depth = rng.uniform(1.0, 50.0, n)
    cam_pts = np.c_[(xy[:, 0] - w / 2) / fy * depth, -(xy[:, 1] - h / 2) / fy * depth, -depth]
    world = cam_pts
    model = np.linalg.solve(pose, np.c_[world, np.ones(n)].T).T[:, :3]
    colors = rng.uniform(0, 1, (n, 3)).astype(np.float32)
    scene = sr.Scene()
    scene.add(sr.Points(model, colors=colors, size=size), pose=pose, instance_id=9)
    cam = sr.PerspectiveCamera(fov_y=np.degrees(2 * np.arctan(h / 2 / fy)), width=w, height=h,
                               near=0.5, far=100.0)
    frame = render(scene, cam, outputs=("mask", "depth", "radiance", "position", "ray_depth",
                                        "instance_id"), w=w, h=h)
    px, py = np.floor(xy).astype(np.int64).T
    winner, wy, wx = point_winners(frame, px, py, depth, w, h)
    np.testing.assert_allclose(frame.depth[wy, wx], depth[winner], rtol=1e-5)
    np.testing.assert_array_equal(frame.radiance[wy, wx], colors[winner])
    np.testing.assert_allclose(frame.position[wy, wx], world[winner], rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(frame.ray_depth[wy, wx], np.linalg.norm(world[winner], axis=1),
                               rtol=1e-5)
    assert (frame.instance_id[frame.mask] == 9).all()


@pytest.mark.parametrize("size", [1.0, 2.0, 3.0, 2.5, 0.4])
def test_point_squares(size, rng):
    xy = rng.uniform(10, [W - 10, H - 10], (12, 2))
    for p in xy:
        scene = sr.Scene()
        scene.add(sr.Points(window_points([p]), size=size))
        mask = render(scene, outputs=("mask",)).mask
        stored = scene.primitives[0].item.positions[0].astype(np.float64)
        x, y = stored[0] + W / 2.0, H / 2.0 - stored[1]
        half = max(size, 1.0) / 2.0
        cx = np.arange(W) + 0.5
        cy = np.arange(H) + 0.5
        expected = ((cy > y - half) & (cy <= y + half))[:, None] & \
                   ((cx > x - half) & (cx <= x + half))[None, :]
        side = round(max(size, 1.0)) if size != 2.5 else None
        if side:
            assert expected.sum() == side * side
        np.testing.assert_array_equal(mask, expected, err_msg=str(p))
        if size == 1.0:
            assert mask[int(np.floor(y)), int(np.floor(x))]


def test_points_depth_test_among_themselves_and_against_triangles():
    tri = pixel_mesh(np.array([[0.0, 0.0], [0.0, 60.0], [60.0, 0.0]]), np.array([[0, 1, 2]]), W, H)
    scene = sr.Scene()
    scene.add(tri, instance_id=0)
    pts = window_points([(10.5, 10.5), (12.5, 10.5), (10.5, 10.5), (100.5, 100.5),
                         (100.5, 100.5)])
    pts[:, 2] = [-5.0, -20.0, -3.0, -30.0, -30.0]  # nearer, farther, nearest; a tie
    scene.add(sr.Points(pts, colors=np.eye(3)[[0, 1, 2, 0, 1]]), instance_id=7)
    frame = render(scene, shading="unlit")
    assert frame.instance_id[10, 10] == 7 and frame.depth[10, 10] == pytest.approx(3.0)
    np.testing.assert_array_equal(frame.radiance[10, 10], [0, 0, 1])
    assert frame.instance_id[10, 12] == 0 and frame.depth[10, 12] == pytest.approx(DEPTH)
    np.testing.assert_array_equal(frame.radiance[100, 100], [1, 0, 0])  # the tie keeps the first


def test_outputs_on_primitive_pixels():
    tri = pixel_mesh(np.array([[0.0, 0.0], [0.0, 120.0], [120.0, 0.0]]), np.array([[0, 1, 2]]), W, H)
    scene = sr.Scene()
    scene.add(tri, instance_id=0)
    pts = window_points([(20.5, 30.5), (130.5, 90.5)])
    pts[:, 2] = -4.0
    scene.add(sr.Lines(pts, [[0, 1]], colors=[[0.5, 0.25, 1.0], [0.5, 0.25, 1.0]]), instance_id=11)
    scene.add(sr.Points(window_points([(140.5, 10.5)]), size=3, color=(0.2, 0.4, 0.6)),
              instance_id=12)
    frame = render(scene)
    alone = sr.Scene()
    alone.add(tri, instance_id=0)
    base = render(alone)
    prim = frame.instance_id >= 11
    assert prim.sum() > 100 and (frame.instance_id == 12).sum() == 9
    assert (frame.triangle_id[prim] == -1).all() and frame.mask[prim].all()
    assert (frame.alpha[prim] == 1.0).all() and (frame.normal[prim] == 0).all()
    assert (frame.barycentric[prim] == 0).all() and (frame.uv[prim] == 0).all()
    np.testing.assert_allclose(frame.depth[frame.instance_id == 11], 4.0, rtol=1e-6)
    np.testing.assert_allclose(frame.ray_depth[frame.instance_id == 11], 4.0, rtol=1e-6)
    np.testing.assert_allclose(frame.position[frame.instance_id == 11][:, 2], -4.0, rtol=1e-6)
    np.testing.assert_array_equal(frame.radiance[frame.instance_id == 11][0],
                                  np.float32([0.5, 0.25, 1.0]))
    # sRGB-encoded like everything else.
    srgb = lambda v: np.round(255 * srgb_curve(v))  # noqa: E731  (v in [0, 1])
    np.testing.assert_array_equal(frame.color[frame.instance_id == 12][0],
                                  srgb(np.float32([0.2, 0.4, 0.6]).astype(np.float64)))
    # Everywhere else the triangles' render, bit for bit.
    for name in sr.OUTPUTS:
        if name in ("coverage",):
            continue
        np.testing.assert_array_equal(getattr(frame, name)[~prim], getattr(base, name)[~prim],
                                      err_msg=name)


def busy_scene(rng) -> sr.Scene:
    scene = sr.Scene()
    tri_xy = rng.uniform(-20, [W + 20, H + 20], (60, 2))
    scene.add(pixel_mesh(tri_xy, np.arange(60).reshape(20, 3), W, H), instance_id=0)
    starts = rng.uniform(-30, [W + 30, H + 30], (200, 2))
    pts = window_points(np.r_[starts, starts + rng.normal(0, 40, (200, 2))])
    pts[:, 2] = -rng.uniform(2, 30, 400)
    seg = np.c_[np.arange(200), np.arange(200, 400)]
    scene.add(sr.Lines(pts, seg, colors=rng.uniform(0, 1, (400, 3))), instance_id=1)
    scene.add(sr.Lines(pts, seg[::7], width=3.5), instance_id=2)
    scene.add(sr.Points(pts, size=2.0, colors=rng.uniform(0, 1, (400, 4))), instance_id=3)
    # One pixel each (their own setup and records), over everything and among each other.
    cloud = window_points(rng.uniform(-5, [W + 5, H + 5], (3000, 2)))
    cloud[:, 2] = -rng.uniform(1, 30, 3000)
    scene.add(sr.Points(cloud, colors=rng.uniform(0, 1, (3000, 3))), instance_id=4)
    scene.add(sr.Points(cloud[::3] * [1, 1, 0.9], size=0.5), instance_id=5)
    return scene


@pytest.mark.parametrize("kw", [{}, {"msaa": 4}, {"raster": "scanline"}, {"ssaa": 2},
                                {"line_algorithm": "dda"}])
def test_same_bits_for_any_thread_count_and_isa(kw, rng):
    scene = busy_scene(rng)
    ref = render(scene, threads=1, **kw)
    assert (ref.instance_id >= 1).sum() > 500
    for threads, simd in ((2, True), (3, True), (1, False), (3, False)):
        frame = render(scene, threads=threads, simd=simd, **kw)
        for name in sr.OUTPUTS:
            np.testing.assert_array_equal(getattr(frame, name), getattr(ref, name),
                                          err_msg=f"{name} threads={threads} simd={simd} {kw}")


@pytest.mark.parametrize("kw", [{"msaa": 4}, {"raster": "scanline"}, {"ssaa": 3}])
def test_antialiased_and_scanline_renders_draw_the_same_primitive_pixels(kw, rng):
    scene = busy_scene(rng)
    plain = render(scene)
    frame = render(scene, **kw)
    # Lines and points are drawn over the resolved pixels: where one wins in both renders, the
    # two agree on everything but what the triangles' samples changed.
    prim = (plain.instance_id >= 1) & (frame.instance_id >= 1)
    assert prim.sum() > 0.8 * (plain.instance_id >= 1).sum()
    for name in ("alpha", "mask", "triangle_id", "instance_id", "radiance", "color", "normal",
                 "depth", "position"):
        np.testing.assert_array_equal(getattr(frame, name)[prim], getattr(plain, name)[prim],
                                      err_msg=f"{name} {kw}")
    assert (frame.alpha[prim] == 1.0).all()
    if "raster" in kw:  # scanline: the same bits everywhere
        for name in sr.OUTPUTS:
            np.testing.assert_array_equal(getattr(frame, name), getattr(plain, name), err_msg=name)


def test_primitives_alone_and_a_scene_without_them():
    # Only points: no triangles at all.
    scene = sr.Scene()
    scene.add(sr.Points(window_points([(3.5, 4.5)])))
    frame = render(scene)
    assert frame.mask.sum() == 1 and frame.mask[4, 3]
    np.testing.assert_array_equal(frame.color[4, 3], [255, 255, 255])
    # Empty Lines / Points objects draw nothing.
    empty = sr.Scene()
    empty.add(sr.Lines(np.zeros((0, 3)), np.zeros((0, 2), np.int32)))
    empty.add(sr.Points(np.zeros((0, 3))))
    assert not render(empty, outputs=("mask",)).mask.any()


def test_pose_moves_primitives_and_instance_ids_default_to_the_count():
    scene = sr.Scene()
    pose = np.eye(4)
    pose[:3, 3] = [10.0, -5.0, 0.0]  # pixel_ortho: +10 px right, +5 px down
    assert scene.add(sr.Points(window_points([(20.5, 20.5)])), pose=pose) == 0
    assert scene.add(sr.Points(window_points([(40.5, 20.5)]))) == 1
    frame = render(scene)
    assert frame.mask[25, 30] and frame.instance_id[25, 30] == 0
    assert frame.instance_id[20, 40] == 1 and frame.mask.sum() == 2


def test_pickle_round_trip(rng):
    lines = sr.Lines(rng.normal(size=(5, 3)), [[0, 1], [3, 4]], colors=rng.uniform(0, 1, (5, 3)),
                     width=2.0)
    points = sr.Points(rng.normal(size=(4, 3)), size=3.0, color=(0.1, 0.2, 0.3))
    for obj in (lines, points):
        back = pickle.loads(pickle.dumps(obj))
        assert type(back) is type(obj)
        for attr in ("positions", "colors"):
            a, b = getattr(obj, attr), getattr(back, attr)
            assert (a is None and b is None) or np.array_equal(a, b)
    assert np.array_equal(pickle.loads(pickle.dumps(lines)).segments, lines.segments)
    assert pickle.loads(pickle.dumps(points)).size == 3.0
    assert not lines.positions.flags.writeable
    scene = sr.Scene()
    scene.add(lines, instance_id=3)
    back = pickle.loads(pickle.dumps(scene))
    assert back.primitives[0].instance_id == 3


def test_bad_inputs_raise_value_errors_naming_the_argument():
    p = np.zeros((3, 3))
    cases = [
        (lambda: sr.Lines(p, [[0, 1]], width=0.0), "width"),
        (lambda: sr.Lines(p, [[0, 1]], width=-1.0), "width"),
        (lambda: sr.Lines(p, [[0, 1]], width=float("nan")), "width"),
        (lambda: sr.Points(p, size=0.0), "size"),
        (lambda: sr.Points(p, size=-2), "size"),
        (lambda: sr.Lines(p, [[0, 3]]), "segments"),
        (lambda: sr.Lines(p, [[-1, 0]]), "segments"),
        (lambda: sr.Lines(p, [[0, 1, 2]]), "segments"),
        (lambda: sr.Lines(p, [[0.0, 1.0]]), "segments"),
        (lambda: sr.Lines([[0, 0, float("nan")], [1, 1, 1]], [[0, 1]]), "positions"),
        (lambda: sr.Points([[0, 0, np.inf]]), "positions"),
        (lambda: sr.Points(np.zeros((3, 2))), "positions"),
        (lambda: sr.Points(np.zeros(3)), "positions"),
        (lambda: sr.Points(np.array([["a", "b", "c"]])), "positions"),
        (lambda: sr.Points(np.zeros((3, 3), bool)), "positions"),
        (lambda: sr.Points(p, colors=np.zeros((2, 3))), "colors"),
        (lambda: sr.Points(p, colors=np.full((3, 3), 2.0)), "colors"),
        (lambda: sr.Points(p, colors=np.zeros((3, 5))), "colors"),
        (lambda: sr.Points(p, size="big"), "size"),
        (lambda: sr.Lines(p, "segments"), "segments"),
    ]
    for make, name in cases:
        with pytest.raises(ValueError, match=name):
            make()
    scene = sr.Scene()
    with pytest.raises(ValueError, match="instance_id"):
        scene.add(sr.Points(p), instance_id=-1)
    with pytest.raises(ValueError, match="color"):
        scene.add(sr.Points(p), color=(1, 0, 0))
    scene.add(sr.Points(p))
    with pytest.raises(ValueError, match="line_algorithm"):
        render(scene, line_algorithm="wu")
    cam = sr.IntrinsicsCamera(100.0, 100.0, W / 2, H / 2, W, H, dist=[0.1, 0, 0, 0, 0])
    with pytest.raises(ValueError, match="lines and points"):
        sr.Renderer(W, H).render(scene, cam)


def test_the_core_rechecks_what_it_views():
    # render.py's records go straight to the core, which views the arrays: it must refuse bad ones.
    from conftest import core_options
    from softrast import _core

    cam = pixel_ortho(W, H)
    view, proj = cam._render_matrices(W, H)
    good = np.zeros((2, 3), np.float32)
    seg = np.array([[0, 5]], np.int32)
    pair = np.zeros((1, 2), np.int32)
    for fields, name in [
        (dict(positions=good, segments=seg), "segments"),
        (dict(points=True, positions=good, width=0.0), "size"),
        (dict(positions=good, segments=pair, width=1e30), "width"),
        (dict(positions=good, segments=pair, depth_bias=1.5), "depth_bias"),
        (dict(points=True, positions=good.astype(np.float64)), "positions"),
        (dict(points=True, positions=np.full((2, 3), np.nan, np.float32)), "positions"),
    ]:
        core = _core.Renderer(W, H, 1, True)
        with pytest.raises(ValueError, match=name):  # when the record is made, or rendered
            record = _core.Primitive(**fields)
            core.render([], core_options(view, proj, True, cam.near, cam.far, ["mask"],
                                         primitives=[record]))


# -- render(wireframe=True) ----------------------------------------------------------------------

def test_wireframe_of_a_flat_triangle_is_its_three_bresenham_edges(rng):
    xy = np.array([[20.3, 15.6], [130.7, 40.2], [55.4, 118.8]])
    scene = sr.Scene()
    scene.add(pixel_mesh(xy, np.array([[0, 2, 1]]), W, H), instance_id=6)
    solid = render(scene, shading="unlit")
    frame = render(scene, shading="unlit", wireframe=True, line_color=(1.0, 0.0, 0.0))
    edges = np.zeros((H, W), bool)
    corners = np.floor(xy).astype(int)
    for a, b in ((0, 1), (1, 2), (2, 0)):
        edges |= to_mask(bresenham(*corners[a], *corners[b]))
    wire = frame.mask & (frame.triangle_id == -1)
    np.testing.assert_array_equal(wire, edges)
    assert (frame.instance_id[wire] == 6).all()
    np.testing.assert_array_equal(frame.radiance[wire], np.tile([1.0, 0.0, 0.0], (wire.sum(), 1)))
    np.testing.assert_allclose(frame.depth[wire], DEPTH, rtol=1e-6)  # the bias is not written
    for name in sr.OUTPUTS:  # elsewhere the solid render, bit for bit
        np.testing.assert_array_equal(getattr(frame, name)[~edges], getattr(solid, name)[~edges],
                                      err_msg=name)


def test_wireframe_over_its_own_solid_shows_front_edges_and_hides_back_ones():
    from conftest import icosphere

    mesh = icosphere(2)
    scene = sr.Scene()
    scene.add(mesh, instance_id=4)
    cam = sr.PerspectiveCamera(fov_y=45.0)
    pose = np.eye(4)
    pose[2, 3] = 5.0
    cam.pose = pose
    w = h = 256
    frame = render(scene, cam, w=w, h=h, wireframe=True, msaa=4)
    wire = frame.mask & (frame.triangle_id == -1)
    v = mesh.positions.astype(np.float64)
    f = mesh.faces
    normals = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    centres = v[f].mean(axis=1)
    facing = ((pose[:3, 3] - centres) * normals).sum(1) / np.linalg.norm(normals, axis=1) \
        / np.linalg.norm(pose[:3, 3] - centres, axis=1)
    # Each edge with the faces on either side.
    edge_faces: dict[tuple, list] = {}
    for k, face in enumerate(f):
        for a, b in ((0, 1), (1, 2), (2, 0)):
            edge_faces.setdefault(tuple(sorted((face[a], face[b]))), []).append(k)
    seen = [e for e, fs in edge_faces.items() if max(facing[fs]) > 0.0]
    front = [e for e, fs in edge_faces.items() if min(facing[fs]) > 0.3]
    # Every edge pixel is the point of an edge with a face toward the camera.
    p = frame.position[wire]
    a, b = v[[e[0] for e in seen]], v[[e[1] for e in seen]]
    d = b - a
    t = np.clip(((p[:, None, :] - a) * d).sum(-1) / (d * d).sum(-1), 0, 1)
    dist = np.linalg.norm(p[:, None, :] - (a + t[..., None] * d), axis=-1).min(axis=1)
    assert dist.max() < 1e-4
    # And the edges whose faces both face the camera are drawn (nearly) whole.
    proj = cam.projection_matrix(w, h)
    view = np.linalg.inv(pose)
    clip = np.c_[v, np.ones(len(v))] @ (proj @ view).T
    win = np.c_[(clip[:, 0] / clip[:, 3] + 1) * 0.5 * w, (1 - clip[:, 1] / clip[:, 3]) * 0.5 * h]
    pix = np.floor(win).astype(int)
    drawn = total = 0
    for i, j in front:
        m = to_mask(bresenham(*pix[i], *pix[j]), w, h)
        drawn += (m & wire).sum()
        total += m.sum()
    assert drawn >= 0.95 * total
    # The same edges as plain Lines (no bias) tie with their faces and often lose to them.
    plain = sr.Scene()
    plain.add(mesh, instance_id=4)
    plain.add(sr.Lines(mesh.positions, np.array(front)), instance_id=5)
    unbiased = render(plain, cam, w=w, h=h, msaa=4).instance_id == 5
    assert unbiased.sum() < 0.75 * drawn, (unbiased.sum(), drawn)


def test_wireframe_arguments():
    scene = sr.Scene()
    scene.add(pixel_mesh(np.array([[0.5, 0.5], [50.5, 0.5], [0.5, 50.5]]), np.array([[0, 2, 1]]),
                         W, H))
    with pytest.raises(ValueError, match="line_width"):
        render(scene, wireframe=True, line_width=0.0)
    with pytest.raises(ValueError, match="line_color"):
        render(scene, wireframe=True, line_color=(2.0, 0.0, 0.0))
    with pytest.raises(TypeError, match="wireframe"):
        render(scene, wireframe="yes")
    thick = render(scene, wireframe=True, line_width=3.0)
    thin = render(scene, wireframe=True)
    assert (thick.triangle_id == -1).sum() > 2 * ((thin.triangle_id == -1) & thin.mask).sum()


def test_scene_edits_lines_and_points_like_meshes():
    # set_pose moves a point cloud, remove drops it, ids reach primitives, bounds include them.
    scene = sr.Scene()
    mesh = pixel_mesh(np.array([[2.0, 2.0], [10.0, 2.0], [2.0, 10.0]]), np.array([[0, 1, 2]]), W, H)
    scene.add(mesh, instance_id=1)
    points = sr.Points(window_to_world(np.array([[20.5, 20.5]]), W, H), size=1.0)
    scene.add(points, instance_id=5)
    first = render(scene, outputs=("instance_id",)).instance_id
    assert first[20, 20] == 5
    moved = scene.set_pose(5, np.array([[1, 0, 0, 3.0], [0, 1, 0, -2.0], [0, 0, 1, 0], [0, 0, 0, 1]]))
    assert isinstance(moved, sr.scene.PrimitiveInstance) and scene.primitives[0] is moved
    after = render(scene, outputs=("instance_id",)).instance_id
    assert after[20, 20] == -1 and after[22, 23] == 5  # 3 px right, 2 px down (world y is up)
    lo, hi = scene.bounds
    assert hi[0] == pytest.approx(20.5 - W / 2 + 3.0) and lo[0] == pytest.approx(2.0 - W / 2)
    assert "1 lines/points" in repr(scene)
    with pytest.raises(ValueError, match="lines or points"):
        scene._index(5)
    removed = scene.remove(moved)
    assert removed is moved and not scene.primitives
    assert (render(scene, outputs=("instance_id",)).instance_id != 5).all()
    scene.add(points, instance_id=1)
    with pytest.raises(ValueError, match="names 2 instances"):
        scene.remove(1)


@pytest.mark.parametrize("mode", [0, 1])  # pyrender's GL_POINTS, GL_LINES
def test_from_pyrender_infinite_far_covers_lines_and_points(mode):
    """A pyrender scene of only points or lines with zfar=None (infinite) gets a far
    plane beyond them; the bounds once counted mesh instances only, so far = 2 * znear and nothing
    was drawn. Stand-in classes named as pyrender's (read by attribute; pyrender itself runs in
    a child process elsewhere)."""
    class Primitive:
        def __init__(self):
            self.mode = mode
            self.positions = np.array([[-1.0, 0.0, -10.0], [1.0, 0.0, -10.0],
                                       [0.0, -1.0, -10.0], [0.0, 1.0, -10.0]])

    class Mesh:
        is_visible = True
        primitives = [Primitive()]

    class Node:
        def __init__(self, name, **kw):
            self.name = name
            self.__dict__.update(kw)

    class PerspectiveCamera:
        yfov, znear, zfar, aspectRatio = 1.0, 0.05, None, None

    class PyrenderScene:
        ambient_light = None
        mesh_nodes = [Node("lines", mesh=Mesh())]
        light_nodes = []
        main_camera_node = Node("camera", camera=PerspectiveCamera())

        def get_pose(self, node):
            return np.eye(4)

    for cls in (Primitive, Mesh, Node, PyrenderScene):
        cls.__module__ = "pyrender.fake"
    PerspectiveCamera.__module__ = "pyrender.camera"
    scene, cam = sr.from_pyrender(PyrenderScene(), 32, 32)
    assert len(scene.primitives) == 1 and len(scene) == 0
    assert cam.far >= 10.0
    frame = sr.Renderer(32, 32).render(scene, cam, outputs=("mask",))
    assert frame.mask.sum() >= (4 if mode == 0 else 8)  # 2 lines about 6 px long cross


# -- far endpoints ---------------------------------------------------------------------------------
# A segment whose endpoints are huge next to its visible part, e.g. from x = -1e20 to 1e20 across
# the view at depth 5: clipping it in clip space lerps a + (b - a) t with t a double near 0.5,
# where one ulp of t is 2^-53 |b - a| (16384 units at 1e20), so both clipped ends collapsed to one
# point and the line drew one pixel. Each case below is drawn next to its visible part, clipped by
# hand, as an ordinary short segment: the same pixels, depths and colours.

FAR_W, FAR_H = 64, 48


def far_camera(pose=None):
    cam = sr.PerspectiveCamera(fov_y=60.0, near=0.5, far=100.0)
    cam.pose = np.eye(4) if pose is None else pose
    return cam


def far_render(positions, colors, cam, outputs=("mask", "depth", "radiance"), **kw):
    scene = sr.Scene()
    scene.add(sr.Lines(np.asarray(positions, np.float64), [[0, 1]], colors=colors), instance_id=2)
    return render(scene, cam, outputs=outputs, w=FAR_W, h=FAR_H, **kw)


def assert_same_line(frame, ref, what):
    np.testing.assert_array_equal(frame.mask, ref.mask, err_msg=what)
    m = ref.mask
    np.testing.assert_allclose(frame.depth[m], ref.depth[m], rtol=1e-6, err_msg=what)
    np.testing.assert_allclose(frame.radiance[m], ref.radiance[m], atol=1e-5, err_msg=what)


def colours_at(colors, k):
    """The colours at parameters k along a segment (k = 0 at its first end), as float32 rows."""
    c = np.asarray(colors, np.float64)
    return (c[0] + np.asarray(k, np.float64)[:, None] * (c[1] - c[0])).astype(np.float32)


# (x of A, x of B, y of A, y of B): at depth 5 (world = view), a row of the 64 px image.
FAR_ROWS = [(-1e19, 1e19, 0.1, 0.1), (-1e20, 1e20, 0.1, 0.1), (-1e30, 1e30, 0.1, 0.1),
            (1e20, -1e20, 0.1, 0.1), (-1e30, 1e19, 0.1, 0.1), (-1e19, 1e30, -0.4, -0.4),
            (-1e20, 1e20, 0.1, 0.3), (-3e38, 3e38, 0.7, 0.7), (0.3, 1e30, 0.1, 0.1),
            (-1e20, -0.25, 0.1, 0.1)]


@pytest.mark.parametrize("algorithm", ["bresenham", "dda"])
def test_far_horizontal_lines_are_their_visible_part(algorithm):
    cam = far_camera()
    colors = [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    # The image spans |x| < 5 tan(30 deg) * 4 / 3 = 3.85 at depth 5: the visible part, clipped by
    # hand, is the part with |x| <= 8 (or up to an end inside that), a segment of ordinary size.
    for xa, xb, ya, yb in FAR_ROWS:
        frame = far_render([[xa, ya, -5.0], [xb, yb, -5.0]], colors, cam,
                           line_algorithm=algorithm)
        lo, hi = max(min(xa, xb), -8.0), min(max(xa, xb), 8.0)
        x = np.array([lo, hi] if xa < xb else [hi, lo])
        k = (x - xa) / (xb - xa)
        y = ya + k * (yb - ya)
        ref = far_render(np.c_[x, y, [-5.0, -5.0]], colours_at(colors, k), cam,
                         line_algorithm=algorithm)
        what = f"{(xa, xb, ya, yb)} {algorithm}"
        assert_same_line(frame, ref, what)
        rows = np.nonzero(frame.mask.any(axis=1))[0]
        assert len(rows) == 1, what
        if min(xa, xb) < -8.0 and max(xa, xb) > 8.0:
            assert frame.mask.sum() == FAR_W, what  # the whole row


def test_far_lines_along_the_view_axis_are_clipped_at_near_and_far():
    # From behind the camera to far beyond the far plane: a diagonal from the near plane's
    # point to the far plane's, both inside the image (window positions away from integers).
    cam = far_camera()
    colors = [[0.0, 1.0, 0.0], [1.0, 0.0, 1.0]]
    x, y = 0.3, 0.1
    for za, zb in [(1e19, -1e19), (1e20, -1e20), (1e30, -1e30), (1e30, -1e19), (2.0, -1e30),
                   (1e20, -20.0), (-1e20, 1e30)]:
        frame = far_render([[x, y, za], [x, y, zb]], colors, cam)
        z = np.array([-0.5, -100.0] if za > zb else [-100.0, -0.5])
        z = np.clip(z, min(za, zb), max(za, zb))
        k = (z - za) / (zb - za)
        ref = far_render(np.c_[[x, x], [y, y], z], colours_at(colors, k), cam)
        assert_same_line(frame, ref, str((za, zb)))
        assert frame.mask.sum() >= 9
        wx, wy, _ = project(cam, np.c_[[x, x], [y, y], z], FAR_W, FAR_H)
        assert np.abs(np.r_[wx, wy] - np.round(np.r_[wx, wy])).min() > 1e-3


def test_far_lines_in_any_direction_under_a_rotated_camera():
    # Lines through the world origin (A = -B 2^k exactly, so the float32 ends define a line that
    # does pass through it) in a direction near the view axis of a camera looking at the origin
    # from 5 units away: visible from the near plane to the far plane. The reference is clipped
    # in exact rational arithmetic.
    from fractions import Fraction

    yaw, pitch = np.radians(25.0), np.radians(-15.0)
    fwd = np.array([np.sin(yaw) * np.cos(pitch), np.sin(pitch), -np.cos(yaw) * np.cos(pitch)])
    right = np.cross(fwd, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = right, up, -fwd, -5.0 * fwd
    cam = far_camera(pose)
    view = cam.view_matrix()
    colors = [[1.0, 1.0, 0.0], [0.0, 0.5, 1.0]]
    direction = fwd + 0.23 * right + 0.17 * up
    for scale, k2 in [(1e19, 1), (1e20, 1), (1e30, 1), (1e20, 2.0**33), (1e30, 2.0**-36)]:
        b = (direction / np.linalg.norm(direction) * scale).astype(np.float32)
        a = (-b.astype(np.float64) * k2).astype(np.float32)
        assert (a.astype(np.float64) == -b.astype(np.float64) * k2).all()
        frame = far_render(np.stack([a, b]), colors, cam)
        # depth(s) of a + s (b - a), exactly; the s where it is near and far.
        fa = [Fraction(float(v)) for v in a]
        fd = [Fraction(float(vb)) - Fraction(float(va)) for va, vb in zip(a, b)]
        row = [Fraction(float(v)) for v in view[2]]
        depth0 = -(sum(r * v for r, v in zip(row, fa)) + row[3])
        slope = -sum(r * v for r, v in zip(row[:3], fd))
        s = [(Fraction(d) - depth0) / slope for d in (0.5, 100.0)]
        s.sort()
        ends = np.array([[float(fa[i] + si * fd[i]) for i in range(3)] for si in s])
        ref = far_render(ends, colours_at(colors, [float(si) for si in s]), cam)
        what = f"{scale} {k2}"
        assert_same_line(frame, ref, what)
        assert frame.mask.sum() >= 10, what
        clip = np.c_[ends, np.ones(2)] @ (cam.projection_matrix(FAR_W, FAR_H) @ view).T
        win = np.r_[(clip[:, 0] / clip[:, 3] + 1) * 0.5 * FAR_W,
                    (1 - clip[:, 1] / clip[:, 3]) * 0.5 * FAR_H]
        assert np.abs(win - np.round(win)).min() > 1e-3, what


def test_far_points_are_culled_and_near_ones_land_where_numpy_projects():
    cam = far_camera()
    far = [[1e20, 0.1, -5.0], [-1e20, 0.1, -5.0], [0.1, 1e30, -5.0], [0.1, 0.1, -1e20],
           [0.1, 0.1, 1e20], [3e38, -3e38, -3e38], [1e19, 1e19, 1e19], [-1e30, 0.0, -1e20]]
    for size in (1.0, 3.0):
        scene = sr.Scene()
        scene.add(sr.Points(far, size=size), instance_id=1)
        assert not render(scene, cam, outputs=("mask",), w=FAR_W, h=FAR_H).mask.any(), size
    # Far along the view axis inside a far plane of 1e25: drawn where NumPy projects them.
    deep = sr.PerspectiveCamera(fov_y=60.0, near=0.5, far=1e25)
    deep.pose = np.eye(4)
    pts = np.array([[1e19, 2e18, -1e20], [-3e23, -1e23, -1e24], [0.1, 0.1, -5.0]])
    scene = sr.Scene()
    scene.add(sr.Points(pts, size=1.0), instance_id=1)
    frame = render(scene, deep, outputs=("mask", "depth"), w=FAR_W, h=FAR_H)
    x, y, _ = project(deep, pts.astype(np.float32).astype(np.float64), FAR_W, FAR_H)
    np.testing.assert_array_equal(frame.mask, to_mask(zip(np.floor(x).astype(int),
                                                          np.floor(y).astype(int)), FAR_W, FAR_H))
    assert frame.mask.sum() == 3


def test_wireframe_of_a_mesh_with_far_vertices():
    # render(wireframe=True) draws mesh edges as lines: a far vertex's edges are clipped the same.
    cam = far_camera()
    v = np.array([[-1e20, 0.1, -5.0], [1e20, 0.1, -5.0], [0.0, 1e20, -5.0]])
    scene = sr.Scene()
    scene.add(sr.Mesh(v, np.array([[0, 1, 2]])), instance_id=3)
    frame = render(scene, cam, outputs=("mask", "triangle_id", "depth"), w=FAR_W, h=FAR_H,
                   shading="unlit", wireframe=True)
    edge = far_render([[-8.0, 0.1, -5.0], [8.0, 0.1, -5.0]], None, cam)
    wire = frame.mask & (frame.triangle_id == -1)
    np.testing.assert_array_equal(wire, edge.mask)
    assert wire.sum() == FAR_W
    np.testing.assert_allclose(frame.depth[wire], 5.0, rtol=1e-6)
