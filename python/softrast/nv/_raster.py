"""softrast.nv's NumPy clip and raster helpers: triangles culled and clipped in clip space
(float64), drawn in NDC, and the outputs computed at each covered pixel centre.

How: coverage and visibility come from softrast's exact fixed-point rasterizer (8 sub-pixel
bits, top-left fill rule), fed the clipped triangles in NDC through an orthographic camera
whose view volume is NDC itself; every output value is then computed in float64 from the
source triangle's clip-space vertices at the pixel centre and rounded to float32 once.
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..camera import OrthographicCamera
from ..mesh import Mesh
from ..render import Renderer
from ..scene import Scene


# Clip-space half-spaces as 4-vectors c: a point p is inside when c . p >= 0.
_NEAR_FAR = np.array([[0.0, 0.0, 1.0, 1.0],    # z >= -w (near)
                      [0.0, 0.0, -1.0, 1.0]])  # z <= w (far)
# Guard band, |x|, |y| <= 4 w: the rasterizer gets NDC in float32, whose spacing at 4 (4.8e-7)
# is at most its 1/256 px vertex precision in the largest image (16384 px); triangles reaching
# beyond the band are clipped in float64 first.
_GUARD_NDC = 4.0
_CLIP_PLANES = np.concatenate([_NEAR_FAR, [[-1.0, 0.0, 0.0, _GUARD_NDC], [1.0, 0.0, 0.0, _GUARD_NDC],
                                           [0.0, -1.0, 0.0, _GUARD_NDC], [0.0, 1.0, 0.0, _GUARD_NDC]]])
# The view frustum, |x|, |y|, |z| <= w: a triangle wholly outside one of these planes is culled.
_FRUSTUM = np.concatenate([_NEAR_FAR, [[-1.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 1.0],
                                       [0.0, -1.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0]]])
# The NDC cube drawn by an orthographic camera at the origin looking down -z: z_view =
# -(z_ndc + 2) puts z_ndc in [-1, 1] at depth [1, 3], inside near/far with room for rounding.
# Depth is then linear in z_ndc, so the depth test orders fragments by z/w as OpenGL does.
_Z_VIEW_OFFSET = 2.0
_NDC_NEAR, _NDC_FAR = 0.5, 3.5
# nvdiffrast's triangle id in a float32 channel (common.h, triidx_to_float): exact up to 2**24,
# then the bits of the int 0x4a800000 + id read as a float32.
_EXACT_ID_MAX = 0x01000000
_ID_BIAS = 0x4A800000


# -- triangle ids in a float32 channel ---------------------------------------------------------

def _ids_to_float(ids: npt.NDArray[np.int64]) -> npt.NDArray[np.float32]:
    """triangle_id + 1 as nvdiffrast stores it (float(id) up to 2**24, biased bits beyond)."""
    out = ids.astype(np.float32)
    big = ids > _EXACT_ID_MAX
    if big.any():
        out[big] = (ids[big] + _ID_BIAS).astype(np.int32).view(np.float32)
    return out


def _float_to_ids(f: npt.NDArray[np.float32]) -> npt.NDArray[np.int64]:
    """The inverse of _ids_to_float (nvdiffrast's float_to_triidx): triangle_id + 1, 0 = none."""
    f = np.ascontiguousarray(f, dtype=np.float32)
    ids = np.trunc(np.minimum(f, np.float32(_EXACT_ID_MAX))).astype(np.int64)
    big = f > np.float32(_EXACT_ID_MAX)
    if big.any():
        ids[big] = f[big].view(np.int32).astype(np.int64) - _ID_BIAS
    return ids


# -- clip, rasterize, shade --------------------------------------------------------------------

def _clip_polygons(tris: npt.NDArray[np.float64], planes: npt.NDArray[np.float64]
                   ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """Sutherland-Hodgman in clip space: (k, 3, 4) triangles clipped to every half-space of
    ``planes`` -> (k, v, 4) convex polygons (in the input's winding) and their vertex counts.

    A crossing point is interpolated from an edge's inside end to its outside end, so two
    triangles sharing the edge get bit-identical points and stay watertight after clipping.
    """
    poly = tris.copy()
    count = np.full(len(tris), 3, dtype=np.int64)
    for plane in planes:
        v = poly.shape[1]
        j = np.arange(v)
        dist = poly @ plane
        valid = j < count[:, None]
        nxt = np.where(j + 1 < count[:, None], j + 1, 0)
        dist_next = np.take_along_axis(dist, nxt, axis=1)
        poly_next = np.take_along_axis(poly, nxt[:, :, None], axis=1)
        inside, inside_next = dist >= 0.0, dist_next >= 0.0
        keep = valid & inside
        cross = valid & (inside != inside_next)
        a = np.where(inside[:, :, None], poly, poly_next)  # the inside end
        b = np.where(inside[:, :, None], poly_next, poly)
        da = np.where(inside, dist, dist_next)
        db = np.where(inside, dist_next, dist)
        t = np.divide(da, da - db, out=np.zeros_like(da), where=cross)  # da >= 0 > db there
        crossing = a + t[:, :, None] * (b - a)
        # Each edge j emits its start vertex (if inside), then its crossing point (if any).
        candidates = np.stack([poly, crossing], axis=2).reshape(len(poly), 2 * v, 4)
        emit = np.stack([keep, cross], axis=2).reshape(len(poly), 2 * v)
        count = emit.sum(axis=1)
        rows, cols = np.nonzero(emit)
        slot = np.cumsum(emit, axis=1)[rows, cols] - 1
        poly = np.zeros((len(poly), max(int(count.max(initial=0)), 3), 4))
        poly[rows, slot] = candidates[rows, cols]
    return poly, count


def _ndc_triangles(clip: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """The triangles (m, 3, 4) in clip space, culled and clipped, in NDC: ((s, 3, 3) float64
    vertices with |x|, |y| <= 4 and |z| <= 1, (s,) index of each one's source triangle), in
    source order (the depth test keeps the earlier of two equal depths)."""
    # Wholly outside one frustum plane => cull (the half-space is convex in clip space).
    culled = ((clip @ _FRUSTUM.T) < 0.0).all(axis=1).any(axis=1)
    keep = np.flatnonzero(~culled)
    clip = clip[keep]
    # A vertex outside the near, far or guard planes, or at w <= 0, => clip in float64.
    d = clip @ _CLIP_PLANES.T
    needs_clip = (d < 0.0).any(axis=(1, 2)) | (clip[:, :, 3] <= 0.0).any(axis=1)
    whole = clip[~needs_clip]
    pieces, sources = [whole], [keep[~needs_clip]]
    if needs_clip.any():
        poly, count = _clip_polygons(clip[needs_clip], _CLIP_PLANES)
        src = keep[needs_clip]
        for i in range(1, poly.shape[1] - 1):  # fan (0, i, i + 1)
            has = count > i + 1
            pieces.append(np.stack([poly[has, 0], poly[has, i], poly[has, i + 1]], axis=1))
            sources.append(src[has])
    tris = np.concatenate(pieces)
    source = np.concatenate(sources)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # w <= 0: dropped below
        ndc = tris[:, :, :3] / tris[:, :, 3:]
    # Inside the guard band and depth range but for rounding, except where cancellation made a
    # crossing point's w tiny (near the eye, in a triangle seen almost edge-on): clamp those.
    ndc[:, :, :2] = np.clip(ndc[:, :, :2], -_GUARD_NDC, _GUARD_NDC)
    ndc[:, :, 2] = np.clip(ndc[:, :, 2], -1.0, 1.0)
    # A clipped vertex at w <= 0 can only be the clip-space origin (it passed z >= -w, z <= w
    # and the guard band): the triangle's plane then contains the eye => zero area, drop it.
    ok = (tris[:, :, 3] > 0.0).all(axis=1) & ~np.isnan(ndc).any(axis=(1, 2))
    ndc, source = ndc[ok], source[ok]
    order = np.argsort(source, kind="stable")
    return ndc[order], source[order]


def _visible_triangles(clip: npt.NDArray[np.float64], height: int, width: int) -> npt.NDArray[np.int64]:
    """(h, w) index into ``clip`` (m, 3, 4) of the triangle seen at each pixel centre, -1 for
    none; row 0 at the bottom."""
    ndc, source = _ndc_triangles(clip)
    if len(source) == 0:
        return np.full((height, width), -1, dtype=np.int64)
    positions = ndc.reshape(-1, 3).copy()
    positions[:, 2] = -(positions[:, 2] + _Z_VIEW_OFFSET)  # z_view: depth = z_ndc + 2
    faces = np.arange(len(positions), dtype=np.int32).reshape(-1, 3)
    scene = Scene()
    scene.add(Mesh(positions.astype(np.float32), faces))  # float32 in: stored exactly, no warning
    camera = OrthographicCamera(xmag=1.0, ymag=1.0, near=_NDC_NEAR, far=_NDC_FAR)  # NDC x, y in [-1, 1]
    # A new renderer per call (0.2 ms): calls from several Python threads run in parallel.
    frame = Renderer(width, height).render(scene, camera, outputs=("triangle_id",), cull="none",
                                           shading="unlit")
    sub = frame.triangle_id[::-1]  # softrast's row 0 is the top, nvdiffrast's the bottom
    return np.where(sub >= 0, source[np.maximum(sub, 0)], -1)


def _shade(clip: npt.NDArray[np.float64], visible: npt.NDArray[np.int64], first_id: int,
           rast: npt.NDArray[np.float32], rast_db: npt.NDArray[np.float32]) -> None:
    """Write (u, v, z/w, id + 1) and (du/dX, du/dY, dv/dX, dv/dY) at the covered pixels.

    With p_i = (x_i, y_i, z_i, w_i) the source triangle's clip-space vertices and (X, Y) the
    pixel centre in NDC, the edge functions a_i (nvdiffrast's, rasterize.cu) of x_i - X w_i and
    y_i - Y w_i give the perspective-correct barycentrics b_i = a_i / (a_0 + a_1 + a_2). Each
    a_i is affine in (X, Y), so the image-space derivatives are exact: d b_i / dX =
    (a_i' - b_i sum(a')) / sum(a) times dX/dcolumn = 2 / W (and 2 / H for rows).
    """
    all_rows, all_cols = np.nonzero(visible >= 0)
    # A block of pixels at a time: each pixel's values depend on it alone, and the float64 work
    # (about 400 bytes a pixel) stays a few MB whatever the resolution.
    for start in range(0, len(all_rows), _SHADE_BLOCK):
        _shade_pixels(clip, visible, first_id, rast, rast_db, all_rows[start:start + _SHADE_BLOCK],
                      all_cols[start:start + _SHADE_BLOCK])


_SHADE_BLOCK = 1 << 14  # pixels shaded at once


def _shade_pixels(clip: npt.NDArray[np.float64], visible: npt.NDArray[np.int64], first_id: int,
                  rast: npt.NDArray[np.float32], rast_db: npt.NDArray[np.float32],
                  rows: npt.NDArray[np.int64], cols: npt.NDArray[np.int64]) -> None:
    height, width = visible.shape
    tri = visible[rows, cols]
    rast[rows, cols, 3] = _ids_to_float(tri + first_id + 1)
    p = clip[tri]  # (N, 3, 4)
    x, y, z, w = p[:, :, 0], p[:, :, 1], p[:, :, 2], p[:, :, 3]
    ndc_x = (2.0 * cols + 1.0) / width - 1.0
    ndc_y = (2.0 * rows + 1.0) / height - 1.0
    # A sliver seen edge-on can give values beyond float32's range: inf, as nvdiffrast's would be.
    with np.errstate(over="ignore", invalid="ignore"):
        px = x - ndc_x[:, None] * w
        py = y - ndc_y[:, None] * w
        a = np.stack([px[:, 1] * py[:, 2] - py[:, 1] * px[:, 2],
                      px[:, 2] * py[:, 0] - py[:, 2] * px[:, 0],
                      px[:, 0] * py[:, 1] - py[:, 0] * px[:, 1]], axis=1)
        a_sum = a.sum(axis=1)
        a_sum = np.where(a_sum == 0.0, 1.0, a_sum)  # only a degenerate triangle; it covers nothing
        bary = a / a_sum[:, None]
        wa = (w * a).sum(axis=1)
        zw = (z * a).sum(axis=1) / np.where(wa == 0.0, 1.0, wa)
        rast[rows, cols, 0] = np.clip(bary[:, 0], 0.0, 1.0)  # clamped as nvdiffrast does
        rast[rows, cols, 1] = np.clip(bary[:, 1], 0.0, 1.0)
        rast[rows, cols, 2] = np.clip(zw, -1.0, 1.0)
        if rast_db.shape[-1] == 0:
            return
        # d a_i / dX and d a_i / dY (constant over the triangle: the X Y terms cancel).
        da_dx = np.stack([y[:, 1] * w[:, 2] - y[:, 2] * w[:, 1],
                          y[:, 2] * w[:, 0] - y[:, 0] * w[:, 2],
                          y[:, 0] * w[:, 1] - y[:, 1] * w[:, 0]], axis=1)
        da_dy = np.stack([x[:, 2] * w[:, 1] - x[:, 1] * w[:, 2],
                          x[:, 0] * w[:, 2] - x[:, 2] * w[:, 0],
                          x[:, 1] * w[:, 0] - x[:, 0] * w[:, 1]], axis=1)
        db_dx = (da_dx - bary * da_dx.sum(axis=1, keepdims=True)) * (2.0 / width / a_sum)[:, None]
        db_dy = (da_dy - bary * da_dy.sum(axis=1, keepdims=True)) * (2.0 / height / a_sum)[:, None]
        rast_db[rows, cols] = np.stack([db_dx[:, 0], db_dy[:, 0], db_dx[:, 1], db_dy[:, 1]], axis=1)
