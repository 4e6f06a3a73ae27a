"""render(raster="scanline"): triangles filled by edge walking cover exactly the samples the edge
functions cover, so every output is the same bits as raster="edge" (the default).

Checked on 100 random scenes (triangle soups with slivers, horizontal and vertical edges, huge and
tiny triangles, edges through pixel centres, coplanar ties; posed closed meshes under a
perspective camera), against a NumPy scanline fill written in exact rationals, across thread
counts and instruction sets.
"""
from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
import trimesh

import softrast as sr
from softrast.reference import raster as ref
from conftest import ALL_OUTPUTS, look_at_gl, random_rotation, window_to_world

SIZES = [(64, 64), (97, 61), (130, 70), (33, 129), (200, 67), (1, 1), (5, 150), (150, 3)]
SHADINGS = ["auto", "normal", "blinn_phong", "pbr", "unlit"]


def _pixel_camera(w: int, h: int) -> sr.OrthographicCamera:
    """conftest.pixel_ortho with a deeper range: world (X, Y, Z) -> window (X + W/2, H/2 - Y)."""
    cam = sr.OrthographicCamera(xmag=w / 2.0, ymag=h / 2.0, near=1.0, far=1000.0)
    cam.pose = np.eye(4)
    return cam


def _soup_triangles(rng: np.random.Generator, w: int, h: int, n: int) -> np.ndarray:
    """(n, 3, 2) window coordinates of triangles of every kind the kernels treat differently."""
    span = np.array([w, h], np.float64)
    tris = np.empty((n, 3, 2))
    for t in range(n):
        kind = rng.integers(0, 8)
        if kind == 0:  # anywhere, partly off the image
            p = rng.uniform(-0.3, 1.3, (3, 2)) * span
        elif kind == 1:  # sliver: the third vertex within a hair (down to 1/256 px, or 0) of an edge
            a, b = rng.uniform(-0.2, 1.2, (2, 2)) * span
            d = b - a
            perp = np.array([-d[1], d[0]]) / max(np.linalg.norm(d), 1e-9)
            eps = rng.choice([0.0, 1e-6, 1e-3, 1 / 256, 3 / 256])
            p = np.array([a, b, a + rng.uniform(0.1, 0.9) * d + eps * rng.choice([-1, 1]) * perp])
        elif kind == 2:  # a horizontal edge (top or bottom), often on a pixel-centre row
            p = rng.uniform(-0.2, 1.2, (3, 2)) * span
            p[1, 1] = p[0, 1] = np.floor(p[0, 1]) + rng.choice([0.5, 0.0, 0.25])
        elif kind == 3:  # a vertical edge
            p = rng.uniform(-0.2, 1.2, (3, 2)) * span
            p[1, 0] = p[0, 0] = np.floor(p[0, 0]) + rng.choice([0.5, 0.0, 0.75])
        elif kind == 4:  # huge: corners far off screen (int64 path; beyond the guard band: clipped)
            p = rng.uniform(-1.0, 1.0, (3, 2)) * rng.choice([2e3, 2e4, 3e5])
        elif kind == 5:  # tiny: sub-pixel to a few pixels (eight-lane and pair kernels by default)
            size = rng.choice([0.3, 1.5, 5.0])
            p = rng.uniform(-0.1, 1.1, (1, 2)) * span + rng.uniform(0, size, (3, 2))
        elif kind == 6:  # vertices on pixel centres and half-pixel lines: edges through samples
            p = np.round(rng.uniform(-0.1, 1.1, (3, 2)) * span * 2) / 2 + rng.choice([0.0, 0.5])
        else:  # a long thin strip across tiles, nearly horizontal or vertical
            a = rng.uniform(0, 1, 2) * span
            d = rng.uniform(-2, 2, 2) * span
            d[rng.integers(0, 2)] *= rng.choice([1e-3, 1e-2])
            p = np.array([a, a + d, a + d * 0.5 + rng.uniform(-1, 1, 2)])
        tris[t] = p
    return tris


def _soup_scene(rng: np.random.Generator, w: int, h: int) -> tuple[sr.Scene, sr.Camera]:
    """Two or three instances of random triangle soups at random depths (some coplanar: ties)."""
    scene = sr.Scene()
    for k in range(rng.integers(2, 4)):
        n = int(rng.integers(20, 120))
        xy = _soup_triangles(rng, w, h, n).reshape(-1, 2)
        z = rng.uniform(-900.0, -2.0, len(xy))
        flat = rng.random(n) < 0.3  # coplanar triangles at one depth: ties in the depth test
        z.reshape(n, 3)[flat] = -50.0
        points = window_to_world(xy, w, h)
        points[:, 2] = z
        faces = np.arange(3 * n).reshape(n, 3)
        colors = rng.uniform(0, 1, (3 * n, 4)).astype(np.float32)
        colors[:, 3] = 1.0
        scene.add(sr.Mesh(points, faces, colors=colors if rng.random() < 0.5 else None),
                  instance_id=int(rng.integers(0, 1000)), color=tuple(rng.uniform(0, 1, 3)))
    return scene, _pixel_camera(w, h)


def _mesh_scene(rng: np.random.Generator, w: int, h: int) -> tuple[sr.Scene, sr.Camera]:
    """Closed meshes (icospheres, boxes) with random poses, and a ground plane crossing the near
    plane, seen by a perspective camera looking at the first one's centre (so that even a 1 x 1
    or 150 x 3 image sees something)."""
    scene = sr.Scene()
    centres = []
    for k in range(rng.integers(1, 4)):
        if rng.random() < 0.7:
            m = trimesh.creation.icosphere(subdivisions=int(rng.integers(1, 4)),
                                           radius=rng.uniform(0.2, 1.0))
        else:
            m = trimesh.creation.box(extents=rng.uniform(0.2, 1.5, 3))
        pose = np.eye(4)
        pose[:3, :3] = random_rotation(rng)
        pose[:3, 3] = rng.uniform(-1.0, 1.0, 3)
        centres.append(pose[:3, 3])
        scene.add(sr.Mesh.from_trimesh(m), pose=pose, instance_id=k, color=tuple(rng.uniform(0, 1, 3)))
    if rng.random() < 0.5:
        ground = np.array([[-1e3, -1.2, -1e3], [1e3, -1.2, -1e3], [1e3, -1.2, 1e3], [-1e3, -1.2, 1e3]])
        scene.add(sr.Mesh(ground, [[0, 2, 1], [0, 3, 2]]), instance_id=9)
    fov_y = rng.uniform(30.0, 90.0) if min(w, h) >= 16 else rng.uniform(4.0, 8.0)  # a few px
    cam = sr.PerspectiveCamera(fov_y=fov_y, near=0.05, far=100.0)
    eye = rng.normal(size=3)
    eye = centres[0] + eye / np.linalg.norm(eye) * rng.uniform(2.0, 5.0)
    cam.pose = look_at_gl(eye, centres[0], up=rng.normal(size=3))
    return scene, cam


def _assert_same(a: sr.Frame, b: sr.Frame, what: str) -> None:
    for name in a.outputs:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape
        # Bits, not values: NaN == NaN and -0.0 != 0.0.
        where = np.argwhere(x != y)[:5].tolist()
        assert x.tobytes() == y.tobytes(), f"{what}: {name} differs at {where}"


@pytest.mark.parametrize("seed", range(100))
def test_scanline_gives_the_edge_functions_bits(seed):
    rng = np.random.default_rng(7000 + seed)
    w, h = SIZES[seed % len(SIZES)]
    scene, cam = (_mesh_scene if seed % 3 == 2 else _soup_scene)(rng, w, h)
    cull = ["none", "back", "front"][int(rng.integers(0, 3))]
    kw = dict(cull=cull, shading=SHADINGS[seed % len(SHADINGS)])
    renderer = sr.Renderer(w, h)
    edge = renderer.render(scene, cam, outputs=ALL_OUTPUTS, **kw)
    scan = renderer.render(scene, cam, outputs=ALL_OUTPUTS, raster="scanline", **kw)
    _assert_same(edge, scan, f"seed {seed}")
    if w * h > 1:
        assert edge.mask.any(), "a scene that draws nothing proves nothing"
    # Without coverage counting the default renders take forward shading where it pays (the
    # scanline ones stay deferred): still the same bits.
    outputs = ("color", "depth", "triangle_id", "instance_id", "mask", "normal")
    for path in ("auto", "forward"):
        edge = renderer.render(scene, cam, outputs=outputs, shading_path=path, **kw)
        scan = renderer.render(scene, cam, outputs=outputs, shading_path=path, raster="scanline",
                               **kw)
        _assert_same(edge, scan, f"seed {seed}, shading_path={path}")


# --------------------------------------------------------------------------------------------
# A NumPy scanline fill in exact rationals: each row's span between the edges' crossings.
# --------------------------------------------------------------------------------------------

def _scanline_reference(xy_fixed: np.ndarray, w: int, h: int) -> np.ndarray:
    """(h, w) bool: the pixel centres one triangle covers, by the classical scanline fill.

    xy_fixed : (3, 2) int vertices in 1/256 px (window space, y down). Along the row through the
    sample y, each slanted edge crosses at x = xa + (y - ya) dx / dy (a Fraction); an edge with the
    triangle to its right (its third vertex right of the crossing) starts the span, one with the
    triangle to its left ends it. Top-left rule: a sample on a left edge is in, on a right edge
    out; on a horizontal edge in iff the triangle lies below it (a top edge).
    """
    p = [tuple(int(v) for v in q) for q in xy_fixed]
    covered = np.zeros((h, w), bool)
    area2 = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[1][1] - p[0][1]) * (p[2][0] - p[0][0])
    if area2 == 0:
        return covered
    one, half = ref.SUBPIXEL_ONE, ref.SUBPIXEL_HALF
    for i in range(h):
        sy = i * one + half
        lo, hi = Fraction(-10**12), Fraction(10**12)  # the span: samples with lo <= x < hi
        inside_rows = True
        for k in range(3):
            (ax, ay), (bx, by), (cx, cy) = p[k], p[(k + 1) % 3], p[(k + 2) % 3]
            if ay == by:  # horizontal: the triangle is below it (top edge, y >= ay) or above
                inside_rows &= (sy >= ay) if cy > ay else (sy < ay)
                continue
            x_at = lambda y: Fraction(ax) + Fraction((y - ay) * (bx - ax), by - ay)  # noqa: E731
            if cx > x_at(cy):  # the triangle is right of this edge: a left edge, inclusive
                lo = max(lo, x_at(sy))
            else:  # a right edge, exclusive
                hi = min(hi, x_at(sy))
        if inside_rows and lo < hi:  # pixels j with lo <= j * 256 + 128 < hi
            j0, j1 = math.ceil((lo - half) / one), math.ceil((hi - half) / one)
            covered[i, max(j0, 0):max(min(j1, w), 0)] = True
    return covered


def _near_miss_triangles(rng: np.random.Generator, w: int, h: int, n: int) -> np.ndarray:
    """(n, 3, 2) window coordinates on the 1/256 px grid: each triangle has an edge whose exact
    edge function is -1, 0 or +1 (in fixed-point units^2) at a pixel centre in the middle of its
    rows. There the span's end lands exactly on the fill rule's tie or one unit beside it: the
    walked quotient's remainder reaches the divisor exactly (a carry), on a row reached by
    stepping rather than by the first division."""
    tris = np.empty((n, 3, 2))
    one = ref.SUBPIXEL_ONE
    for t in range(n):
        target = int(rng.integers(-1, 2))
        sx = int(rng.integers(0, w)) * one + ref.SUBPIXEL_HALF
        sy = int(rng.integers(0, h)) * one + ref.SUBPIXEL_HALF
        while True:  # an edge (dx, dy), 3 to 15 rows tall, the sample mid-way along it
            dx, dy = int(rng.integers(-4000, 4000)), int(rng.integers(3 * one, 15 * one))
            g = math.gcd(dx, dy)
            if target == 0:  # on the edge: the sample is k / g of the way along it
                k = int(rng.integers(0, g))
                p, q = k * (dy // g), k * (dx // g)
            elif g == 1:  # beside it: E = dx * (sy - ay) - dy * (sx - ax) = +-1 where
                # (sy - ay, sx - ax) = (target * u + k * dy, -target * v + k * dx), any integer k
                u = pow(dx, -1, dy)  # dx * u + dy * v = 1
                v = (1 - dx * u) // dy
                k = -((target * u) // dy)
                p, q = target * u + k * dy, -target * v + k * dx
            else:
                continue
            if 0.15 * dy < p < 0.85 * dy:
                break
        a = np.array([sx - q, sy - p])
        b = a + np.array([dx, dy])
        assert dx * (sy - a[1]) - dy * (sx - a[0]) == target
        side = rng.choice([-1, 1]) * rng.uniform(2, 12) * one  # the third vertex on either side
        normal = np.array([dy, -dx]) / math.hypot(dx, dy)
        c = np.round(a + rng.uniform(0.2, 0.8) * (b - a) + side * normal)
        tri = np.array([a, b, c], np.float64) / one
        tris[t] = tri[::-1] if rng.random() < 0.5 else tri  # both windings
    return tris


def test_scanline_matches_a_numpy_scanline_fill(rng):
    w, h = 70, 66
    # Vertices on the 1/256 px grid (snapping is exact), half of them on pixel centres and
    # half-pixel lines so that edges and vertices pass through samples; some horizontal edges.
    n = 60
    xy = rng.uniform(-5, 75, (n, 3, 2))
    on_grid = rng.random(n) < 0.5
    xy[on_grid] = np.round(xy[on_grid] * 2) / 2 + 0.5
    xy[~on_grid] = np.round(xy[~on_grid] * 256) / 256
    flat = rng.random(n) < 0.3
    xy[flat, 1, 1] = xy[flat, 0, 1]
    tiny = rng.random(n) < 0.2
    xy[tiny] = xy[tiny, :1] + np.round(rng.uniform(0, 2, (tiny.sum(), 3, 2)) * 256) / 256
    xy = np.concatenate([xy, _near_miss_triangles(rng, w, h, 300)])
    n = len(xy)
    expected = np.zeros((h, w), np.uint32)
    for tri in xy:
        expected += _scanline_reference(ref.snap(tri), w, h)
    assert expected.max() >= 2 and (expected > 0).sum() > 500

    scene = sr.Scene()
    points = window_to_world(xy.reshape(-1, 2), w, h)
    scene.add(sr.Mesh(points, np.arange(3 * n).reshape(n, 3)))
    for raster in ("scanline", "edge"):
        frame = sr.Renderer(w, h).render(scene, _pixel_camera(w, h), outputs=("coverage",),
                                         cull="none", raster=raster)
        np.testing.assert_array_equal(frame.coverage, expected, err_msg=raster)
    # And the independent edge-function reference (softrast.reference.raster) agrees.
    cov_ref, _ = ref.rasterize(xy.reshape(-1, 2), np.arange(3 * n).reshape(n, 3), w, h)
    np.testing.assert_array_equal(cov_ref, expected)


def test_scanline_reference_fill_rule_by_hand():
    # A right triangle with a top edge and a left edge on pixel-centre lines: the top row and
    # left column are in, the samples on the hypotenuse (x + y = 8) are out.
    xy = ref.snap(np.array([[1.5, 1.5], [6.5, 1.5], [1.5, 6.5]]))
    got = _scanline_reference(xy, 8, 8)
    want = np.zeros((8, 8), bool)
    for i in range(8):
        for j in range(8):
            want[i, j] = j >= 1 and i >= 1 and (j + 0.5) + (i + 0.5) < 8.0
    np.testing.assert_array_equal(got, want)


# --------------------------------------------------------------------------------------------
# Options, threads, instruction sets
# --------------------------------------------------------------------------------------------

def test_raster_is_checked():
    scene = sr.Scene()
    scene.add(sr.Mesh.from_trimesh(trimesh.creation.icosphere(1)))
    cam = sr.PerspectiveCamera(fov_y=50.0)
    cam.look_at(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0))
    renderer = sr.Renderer(16, 16)
    with pytest.raises(ValueError, match="raster"):
        renderer.render(scene, cam, raster="bresenham")
    with pytest.raises(TypeError, match="raster"):
        renderer.render(scene, cam, raster=1)
    assert sr._core.RASTER_ALGORITHMS == ("edge", "scanline")


@pytest.mark.parametrize("seed", range(4))
def test_scanline_same_bits_across_threads_and_isa(seed):
    rng = np.random.default_rng(9100 + seed)
    w, h = (150, 130) if seed % 2 else (97, 200)
    scene, cam = (_mesh_scene if seed % 2 else _soup_scene)(rng, w, h)
    frames = [sr.Renderer(w, h, threads=threads, simd=simd).render(
                  scene, cam, outputs=ALL_OUTPUTS, cull="none", raster=raster)
              for threads, simd, raster in [(1, True, "edge"), (1, True, "scanline"),
                                            (2, True, "scanline"), (1, False, "scanline"),
                                            (2, False, "scanline")]]
    assert frames[0].mask.any()
    for f in frames[1:]:
        _assert_same(frames[0], f, f"seed {seed}")


def test_scanline_with_lens_distortion():
    w, h = 120, 90
    K = np.array([[90.0, 0.0, 60.3], [0.0, 88.0, 44.6], [0.0, 0.0, 1.0]])
    dist = np.array([-0.3, 0.1, 0.001, -0.001, 0.0])
    cam = sr.IntrinsicsCamera.from_opencv(K, np.zeros(3), np.zeros(3), w, h, dist=dist, near=0.1,
                                          far=50.0)
    cam.look_at((0.3, 1.1, 2.1), (0.0, -0.1, 0.0), up=(0.0, 1.0, 0.0))
    scene = sr.Scene()
    scene.add(sr.Mesh.from_trimesh(trimesh.creation.icosphere(3, radius=0.6)), color=(0.9, 0.4, 0.2))
    outputs = ("color", "depth", "triangle_id", "mask")
    edge = sr.Renderer(w, h).render(scene, cam, outputs)
    scan = sr.Renderer(w, h).render(scene, cam, outputs, raster="scanline")
    assert edge.mask.any()
    _assert_same(edge, scan, "distorted")
