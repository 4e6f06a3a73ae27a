"""An independent NumPy reference rasterizer (no softrast code): the rules the C++ core promises.

    rasterize(xy_window, faces, width, height, cull) -> (coverage, last face) per pixel centre
    covered_brute_force(xy_fixed, tri, width, height) -> the same rule, formulated a second way
    near_edges(xy_window, faces, width, height, eps_px) -> the pixel centres near an edge

* window space: x right, y down; the centre of pixel (row i, col j) is (j + 0.5, i + 0.5);
* vertices snapped to 1/256 px: x_fixed = round(x_window * 256) (tests avoid rounding ties);
* exact integer edge functions (int64: |coordinate| < 2^23 => |E| < 2^48);
* Direct3D top-left rule: a sample exactly on an edge is covered only if the edge is a top edge
  (horizontal, triangle below it) or a left edge;
* front faces are counter-clockwise in NDC (y up), i.e. clockwise-negative in y-down window space;
  zero-area triangles cover nothing.
"""
from __future__ import annotations

import numpy as np

__all__ = ["SUBPIXEL_BITS", "SUBPIXEL_ONE", "SUBPIXEL_HALF", "snap", "signed_area2_fixed",
           "rasterize", "covered_brute_force", "near_edges", "near_segment"]

SUBPIXEL_BITS = 8
SUBPIXEL_ONE = 1 << SUBPIXEL_BITS
SUBPIXEL_HALF = SUBPIXEL_ONE // 2


def snap(xy_window: np.ndarray) -> np.ndarray:
    """Window coordinates snapped to the 1/256 px grid.

    Parameters
    ----------
    xy_window : numpy.ndarray, shape (n, 2)
        Float window coordinates (finite, below 2^22 px in magnitude).

    Returns
    -------
    numpy.ndarray
        (n, 2) int64 fixed point: round(xy * 256).
    """
    xy = np.asarray(xy_window, dtype=np.float64)
    if not np.isfinite(xy).all() or np.abs(xy).max(initial=0.0) >= 2.0**22:
        raise ValueError("reference rasterizer: window coordinates must be finite and < 2^22 px")
    return np.rint(xy * SUBPIXEL_ONE).astype(np.int64)


def signed_area2_fixed(xy_fixed: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Twice the signed area of each triangle in y-down window space.

    Parameters
    ----------
    xy_fixed : numpy.ndarray, shape (n, 2)
        int64 fixed-point vertices (``snap``).
    faces : numpy.ndarray, shape (m, 3)
        Vertex indices.

    Returns
    -------
    numpy.ndarray
        (m,) int64; > 0: clockwise on screen, a back face.
    """
    a, b, c = (xy_fixed[faces[:, k]] for k in range(3))
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


def _ceil_div(a: int, b: int) -> int:
    return -((-a) // b)


def rasterize(xy_window: np.ndarray, faces: np.ndarray, width: int, height: int,
              cull: str = "none", fixed: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Coverage of pixel centres by the triangles ``faces`` over vertices ``xy_window``.

    Parameters
    ----------
    xy_window : numpy.ndarray, shape (n, 2)
        Window coordinates: float px, or int64 1/256 px if ``fixed``.
    faces : numpy.ndarray, shape (m, 3)
        int vertex indices.
    width, height : int
        The image's size.
    cull : {"none", "back", "front"}
        The faces left out.
    fixed : bool
        ``xy_window`` is already snapped.

    Returns
    -------
    coverage : numpy.ndarray, shape (height, width)
        int64, the number of triangles covering each centre.
    last : numpy.ndarray, shape (height, width)
        int64, the index of the last face covering it, -1 if none.
    """
    xy = np.asarray(xy_window, dtype=np.int64) if fixed else snap(xy_window)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    area2 = signed_area2_fixed(xy, faces)
    coverage = np.zeros((height, width), np.int64)
    last = np.full((height, width), -1, np.int64)
    for f, (tri, area) in enumerate(zip(faces, area2)):
        area = int(area)
        if area == 0:
            continue  # degenerate => covers nothing
        front = area < 0  # counter-clockwise in NDC
        if (cull == "back" and not front) or (cull == "front" and front):
            continue
        p = [xy[int(k)] for k in tri]
        if area < 0:  # order so that area > 0 (clockwise on screen): inside <=> E >= 0
            p[1], p[2] = p[2], p[1]
        xs = [int(q[0]) for q in p]
        ys = [int(q[1]) for q in p]
        # Pixels whose centre j * 256 + 128 lies in [min, max].
        j0 = max(0, _ceil_div(min(xs) - SUBPIXEL_HALF, SUBPIXEL_ONE))
        j1 = min(width - 1, (max(xs) - SUBPIXEL_HALF) // SUBPIXEL_ONE)
        i0 = max(0, _ceil_div(min(ys) - SUBPIXEL_HALF, SUBPIXEL_ONE))
        i1 = min(height - 1, (max(ys) - SUBPIXEL_HALF) // SUBPIXEL_ONE)
        if j0 > j1 or i0 > i1:
            continue
        sx = np.arange(j0, j1 + 1, dtype=np.int64)[None, :] * SUBPIXEL_ONE + SUBPIXEL_HALF
        sy = np.arange(i0, i1 + 1, dtype=np.int64)[:, None] * SUBPIXEL_ONE + SUBPIXEL_HALF
        inside = np.ones((i1 - i0 + 1, j1 - j0 + 1), bool)
        for k in range(3):
            ax, ay = xs[k], ys[k]
            bx, by = xs[(k + 1) % 3], ys[(k + 1) % 3]
            dx, dy = bx - ax, by - ay
            e = dx * (sy - ay) - dy * (sx - ax)
            top_left = (dy == 0 and dx > 0) or dy < 0  # top edge, or left edge (going up)
            inside &= (e >= 0) if top_left else (e > 0)
        coverage[i0:i1 + 1, j0:j1 + 1] += inside
        last[i0:i1 + 1, j0:j1 + 1][inside] = f
    return coverage, last


def covered_brute_force(xy_fixed: np.ndarray, tri: np.ndarray, width: int, height: int) -> np.ndarray:
    """A second, slow formulation of the same rule for checking ``rasterize`` itself.

    The top-left rule is equivalent to testing the sample nudged by (eps, eps^2), eps -> 0+:
    it is covered iff it lies strictly inside on every edge after the nudge, i.e. iff for every
    edge the tuple (E, dE/dx, dE/dy) is lexicographically positive. Winding-independent.

    Parameters
    ----------
    xy_fixed : numpy.ndarray, shape (n, 2)
        int64 fixed-point vertices (``snap``).
    tri : array_like, shape (3,)
        One triangle's vertex indices.
    width, height : int
        The image's size.

    Returns
    -------
    numpy.ndarray
        (height, width) bool coverage of the pixel centres.
    """
    p = [tuple(int(v) for v in xy_fixed[int(k)]) for k in tri]
    area = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[1][1] - p[0][1]) * (p[2][0] - p[0][0])
    out = np.zeros((height, width), bool)
    if area == 0:
        return out
    sign = 1 if area > 0 else -1
    for i in range(height):
        for j in range(width):
            sx, sy = j * SUBPIXEL_ONE + SUBPIXEL_HALF, i * SUBPIXEL_ONE + SUBPIXEL_HALF
            ok = True
            for k in range(3):
                (ax, ay), (bx, by) = p[k], p[(k + 1) % 3]
                e = sign * ((bx - ax) * (sy - ay) - (by - ay) * (sx - ax))
                de_dx, de_dy = sign * -(by - ay), sign * (bx - ax)
                if (e, de_dx, de_dy) <= (0, 0, 0):
                    ok = False
                    break
            out[i, j] = ok
    return out


def near_edges(xy_window: np.ndarray, faces: np.ndarray, width: int, height: int,
               eps_px: float) -> np.ndarray:
    """The pixel centres within ``eps_px`` of any triangle edge segment (float math).

    Used to ignore samples whose coverage legitimately depends on float32 rounding.

    Parameters
    ----------
    xy_window : numpy.ndarray, shape (n, 2)
        Float window coordinates.
    faces : numpy.ndarray, shape (m, 3)
        Vertex indices.
    width, height : int
        The image's size.
    eps_px : float
        The distance, in pixels.

    Returns
    -------
    numpy.ndarray
        (height, width) bool.
    """
    xy = np.asarray(xy_window, dtype=np.float64)
    out = np.zeros((height, width), bool)
    pad = int(np.ceil(eps_px)) + 1
    for tri in np.asarray(faces).reshape(-1, 3):
        p = xy[tri]
        j0 = max(0, int(np.floor(p[:, 0].min())) - pad)
        j1 = min(width - 1, int(np.ceil(p[:, 0].max())) + pad)
        i0 = max(0, int(np.floor(p[:, 1].min())) - pad)
        i1 = min(height - 1, int(np.ceil(p[:, 1].max())) + pad)
        if j0 > j1 or i0 > i1:
            continue
        sx = np.arange(j0, j1 + 1)[None, :] + 0.5
        sy = np.arange(i0, i1 + 1)[:, None] + 0.5
        for k in range(3):
            out[i0:i1 + 1, j0:j1 + 1] |= near_segment(p[k], p[(k + 1) % 3], sx, sy, eps_px)
    return out


def near_segment(a: np.ndarray, b: np.ndarray, px: np.ndarray, py: np.ndarray,
                 eps: float) -> np.ndarray:
    """Which points lie within ``eps`` of the segment from ``a`` to ``b`` (float64).

    Parameters
    ----------
    a, b : numpy.ndarray, shape (2,)
        The segment's ends (window coordinates).
    px, py : numpy.ndarray
        The points' x and y (broadcast against each other).
    eps : float
        The distance.

    Returns
    -------
    numpy.ndarray
        bool, the broadcast shape of ``px`` and ``py``.
    """
    d = b - a
    ll = float(d @ d)
    t = np.zeros_like(px * py) if ll == 0.0 else np.clip(((px - a[0]) * d[0] + (py - a[1]) * d[1]) / ll, 0, 1)
    return np.hypot(px - (a[0] + t * d[0]), py - (a[1] + t * d[1])) <= eps
