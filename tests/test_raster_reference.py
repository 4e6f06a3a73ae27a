"""Unit tests of the NumPy reference rasterizer (softrast.reference.raster) against hand-derived cases."""
from __future__ import annotations

import numpy as np
import pytest

from softrast.reference import raster as ref


def _cov(xy, faces, w, h, cull="none"):
    return ref.rasterize(np.asarray(xy, float), np.asarray(faces), w, h, cull=cull)[0]


def test_right_triangle_through_pixel_centres_hand_derived():
    # (0.5,0.5) (2.5,0.5) (0.5,2.5): top edge row 0, left edge col 0, hypotenuse is a right edge.
    cov = _cov([[0.5, 0.5], [2.5, 0.5], [0.5, 2.5]], [[0, 1, 2]], 4, 4)
    expected = np.zeros((4, 4), int)
    expected[0, 0] = expected[0, 1] = expected[1, 0] = 1
    np.testing.assert_array_equal(cov, expected)


def test_bottom_and_right_edges_excluded_hand_derived():
    # Mirror image: (3.5,3.5) (1.5,3.5) (3.5,1.5): bottom edge row 3 and right edge col 3 are out.
    cov = _cov([[3.5, 3.5], [1.5, 3.5], [3.5, 1.5]], [[0, 1, 2]], 5, 5)
    # No centre is strictly inside; (2.5, 2.5) lies on the hypotenuse, which is a left edge
    # (it rises from bottom-left to top-right, interior to its right) => the only covered sample.
    expected = np.zeros((5, 5), int)
    expected[2, 2] = 1
    np.testing.assert_array_equal(cov, expected)


@pytest.mark.parametrize("x0,y0,x1,y1", [(0, 0, 5, 3), (2, 1, 7, 6), (1, 3, 2, 4)])
def test_rectangle_corners_on_centres_covers_half_open_range(x0, y0, x1, y1):
    xy = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float) + 0.5
    w, h = 9, 8
    expected = np.zeros((h, w), int)
    expected[y0:y1, x0:x1] = 1
    for faces in ([[0, 1, 2], [0, 2, 3]], [[0, 1, 3], [1, 2, 3]], [[0, 2, 1], [0, 3, 2]]):
        np.testing.assert_array_equal(_cov(xy, faces, w, h), expected)


def test_winding_and_cull():
    xy = np.array([[1.3, 1.1], [7.7, 2.2], [3.1, 6.9]])
    cw_screen = [[0, 1, 2]]  # clockwise in y-down window space => counter-clockwise in NDC => front
    ccw_screen = [[0, 2, 1]]
    assert ref.signed_area2_fixed(ref.snap(xy), np.array(cw_screen))[0] > 0
    a = _cov(xy, cw_screen, 10, 10)
    assert a.sum() > 0
    np.testing.assert_array_equal(_cov(xy, ccw_screen, 10, 10), a)
    # area > 0 in y-down space is counter-clockwise in NDC? No: y flips => it is clockwise => back.
    np.testing.assert_array_equal(_cov(xy, cw_screen, 10, 10, cull="back"), 0)
    np.testing.assert_array_equal(_cov(xy, cw_screen, 10, 10, cull="front"), a)
    np.testing.assert_array_equal(_cov(xy, ccw_screen, 10, 10, cull="back"), a)
    np.testing.assert_array_equal(_cov(xy, ccw_screen, 10, 10, cull="front"), 0)


def test_degenerate_covers_nothing():
    xy = np.array([[0.5, 0.5], [2.5, 2.5], [4.5, 4.5], [1.5, 0.5]])
    assert _cov(xy, [[0, 1, 2]], 6, 6).sum() == 0
    assert _cov(xy, [[0, 0, 3]], 6, 6).sum() == 0


def test_matches_brute_force_nudge_formulation():
    rng = np.random.default_rng(1)
    w = h = 9
    for trial in range(150):
        if trial % 2:  # vertices on pixel centres / half-pixel lines => many exact ties
            xy = (rng.integers(-2, 2 * w + 2, size=(3, 2)) / 2.0) + 0.5
        else:
            xy = rng.integers(-200, (w + 1) * 256, size=(3, 2)) / 256.0
        fx = ref.snap(xy)
        expected = ref.covered_brute_force(fx, np.array([0, 1, 2]), w, h)
        np.testing.assert_array_equal(_cov(xy, [[0, 1, 2]], w, h), expected.astype(int))


def test_random_triangulated_grid_tiles_exactly():
    rng = np.random.default_rng(2)
    nx, ny, w, h = 7, 6, 24, 20
    gx, gy = np.meshgrid(np.linspace(2.5, 21.5, nx), np.linspace(1.5, 17.5, ny))
    xy = np.stack([gx, gy], -1).reshape(-1, 2)
    interior = (gx > 2.5) & (gx < 21.5) & (gy > 1.5) & (gy < 17.5)
    xy[interior.ravel()] += rng.uniform(-0.8, 0.8, size=(interior.sum(), 2))
    faces = []
    for r in range(ny - 1):
        for c in range(nx - 1):
            a, b, cc, d = r * nx + c, r * nx + c + 1, (r + 1) * nx + c + 1, (r + 1) * nx + c
            faces += [[a, b, cc], [a, cc, d]] if rng.random() < 0.5 else [[a, b, d], [b, cc, d]]
    cov = _cov(xy, faces, w, h)
    expected = np.zeros((h, w), int)
    expected[1:17, 2:21] = 1  # centres in [2.5, 21.5) x [1.5, 17.5)
    np.testing.assert_array_equal(cov, expected)


def test_count_matches_area_for_large_triangle():
    # Pick's-theorem-like bound: |#samples - area| <= perimeter (in px) for a convex region.
    xy = np.array([[3.3, 2.1], [90.7, 11.9], [40.2, 77.6]])
    cov = _cov(xy, [[0, 1, 2]], 100, 100)
    p = ref.snap(xy) / 256.0
    (ux, uy), (vx, vy) = p[1] - p[0], p[2] - p[0]
    area = abs(ux * vy - uy * vx) / 2
    perim = sum(np.linalg.norm(p[k] - p[(k + 1) % 3]) for k in range(3))
    assert abs(cov.sum() - area) <= perim


def test_near_edges():
    m = ref.near_edges(np.array([[0.5, 0.5], [4.5, 0.5], [0.5, 4.5]]), np.array([[0, 1, 2]]), 6, 6, 0.01)
    assert m[0, :5].all() and m[:5, 0].all() and m[2, 2] and m[1, 3] and not m[1, 1] and not m[5, 5]
