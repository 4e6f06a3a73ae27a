"""nvdiffrast's functional API on NumPy arrays: ``import softrast.nv as dr``.

Code written for nvdiffrast (``import nvdiffrast.torch as dr``, CUDA only) runs on a CPU
after converting its tensors to NumPy arrays (``t.detach().cpu().numpy()``). Only the forward
pass of ``rasterize`` and ``interpolate`` is provided: no gradients, no ``texture`` or
``antialias``. The outputs follow nvdiffrast's sources (``nvdiffrast/common/rasterize.cu``,
``interpolate.cu``, ``rasterize_gl.cpp``; see ``rasterize``) channel for channel:

* ``pos`` is in clip space (after model, view and projection; OpenGL's NDC = xyz / w).
* Image row 0 is the BOTTOM of the image (NDC y = -1), as nvdiffrast returns it; flip with
  ``img[:, ::-1]`` (or ``img[0, ::-1]`` for one image) for a top-down picture file.
* The centre of pixel (row r, column c) is at NDC ``(2 (c + 0.5) / W - 1, 2 (r + 0.5) / H - 1)``.
* ``rast = (u, v, z/w, triangle_id + 1)`` per pixel; ``u`` weighs vertex ``tri[id, 0]`` and ``v``
  weighs ``tri[id, 1]``: an attribute interpolates as ``u a0 + v a1 + (1 - u - v) a2``
  (perspective-correct). All four are 0 where no triangle covers the pixel centre.
* Triangles are clipped to ``-w <= z <= w`` (OpenGL's near and far planes) and depth-tested on
  z/w, nearer (smaller) winning; a tie keeps the earlier triangle, as OpenGL's GL_LESS does (softrast
  counts fragments within 2^-20 of the depth as tied: README, "Ties and coplanar geometry").
  Both windings are drawn (no back-face culling).

How: coverage and visibility come from softrast's exact fixed-point rasterizer (8 sub-pixel
bits, top-left fill rule), fed the clipped triangles in NDC through an orthographic camera
whose view volume is NDC itself; every output value is then computed in float64 from the
source triangle's clip-space vertices at the pixel centre and rounded to float32 once.
"""
from __future__ import annotations

import inspect
import operator
from typing import Any

import numpy as np
import numpy.typing as npt

from . import _core
from .camera import OrthographicCamera
from .limits import check_budget
from .mesh import Mesh
from .render import Renderer
from .scene import Scene

__all__ = ["RasterizeCudaContext", "RasterizeGLContext", "interpolate", "rasterize"]

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
_FLOAT32_MAX = float(np.finfo(np.float32).max)


class _Context:
    """Base of the context stand-ins (isinstance tells ``rasterize``'s two call forms apart)."""

    output_db = True


class RasterizeCudaContext(_Context):
    """Stands in for ``nvdiffrast.torch.RasterizeCudaContext`` so code written for it runs
    unchanged; it holds no state (softrast needs none). ``device`` is accepted and ignored."""

    def __init__(self, device: Any = None) -> None:
        self.device = device

    def __repr__(self) -> str:
        return "RasterizeCudaContext()"


class RasterizeGLContext(_Context):
    """Stands in for ``nvdiffrast.torch.RasterizeGLContext``; it holds no state.

    output_db : False => ``rasterize`` returns an empty (b, h, w, 0) ``rast_db``, as nvdiffrast
        does for such a context. mode : "automatic" or "manual" (``set_context`` and
        ``release_context`` then do nothing). device : ignored.
    """

    def __init__(self, output_db: bool = True, mode: str = "automatic", device: Any = None) -> None:
        if not isinstance(output_db, (bool, np.bool_)):
            raise ValueError(f"output_db must be True or False, got {output_db!r:.80}")
        if mode not in ("automatic", "manual"):
            raise ValueError(f"mode must be 'automatic' or 'manual', got {mode!r:.80}")
        self.output_db = bool(output_db)
        self.mode = mode
        self.device = device

    def set_context(self) -> None:
        """No-op (nvdiffrast makes its OpenGL context current here)."""

    def release_context(self) -> None:
        """No-op."""

    def __repr__(self) -> str:
        return f"RasterizeGLContext(output_db={self.output_db}, mode={self.mode!r})"


# -- argument checks (ValueError naming the argument, for any bad input) ---------------------

def _array(value: Any, name: str, kinds: str, what: str) -> np.ndarray:
    if value is None or isinstance(value, (str, bytes, dict, set)):
        raise ValueError(f"{name} must be an array of {what}, got {type(value).__name__}")
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError, RuntimeError) as exc:  # ragged lists, CUDA tensors, ...
        raise ValueError(f"{name} must be a NumPy array of {what} (a torch tensor: "
                         f"t.detach().cpu().numpy()): {exc}") from None
    if arr.dtype.kind not in kinds:
        raise ValueError(f"{name} must hold {what}, got dtype {arr.dtype}")
    return arr


def _real_array(value: Any, name: str) -> npt.NDArray[np.float64]:
    return _array(value, name, "iuf", "real numbers").astype(np.float64, copy=False)


def _float32_values(arr: npt.NDArray[np.float64], name: str) -> None:
    """Finite and within float32's range, as nvdiffrast's float32 tensors are: the float64
    arithmetic here (products of three values at most) can then neither overflow nor make NaN."""
    ok = np.abs(arr) <= _FLOAT32_MAX  # False for NaN
    if not ok.all():
        k = tuple(int(i) for i in np.argwhere(~ok)[0])
        value = float(arr[k])
        what = "NaN or inf" if not np.isfinite(value) else f"{value!r}, beyond float32's range"
        raise ValueError(f"{name} contains {what}, at {name}[{', '.join(map(str, k))}]")


def _index_array(value: Any, name: str) -> npt.NDArray[np.int64]:
    return _array(value, name, "iu", "integers (int32)").astype(np.int64, copy=False)


def _shape_text(arr: np.ndarray) -> str:
    return str(tuple(int(s) for s in arr.shape))


def _check_tri(tri: Any, num_vertices: int, vertices_of: str) -> npt.NDArray[np.int64]:
    t = _index_array(tri, "tri")
    if t.ndim != 2 or t.shape[1] != 3:
        raise ValueError(f"tri must have shape (num_triangles, 3), got {_shape_text(t)}")
    bad = (t < 0) | (t >= num_vertices)
    if bad.any():
        k = int(np.flatnonzero(bad.any(axis=1))[0])
        raise ValueError(f"tri[{k}] = {t[k].tolist()} indexes a vertex outside [0, {num_vertices}) "
                         f"({vertices_of} has {num_vertices} vertices)")
    return t


def _check_resolution(resolution: Any) -> tuple[int, int]:
    try:
        h, w = resolution
    except (TypeError, ValueError):
        raise ValueError(f"resolution must be (height, width), got {resolution!r:.80}") from None
    sides = []
    for name, side in (("height", h), ("width", w)):
        if isinstance(side, (bool, np.bool_)):
            raise ValueError(f"resolution {name} must be an int, got {side!r}")
        try:
            side = operator.index(side)
        except TypeError:
            raise ValueError(f"resolution {name} must be an int, got {side!r:.80}") from None
        if not 1 <= side <= _core.MAX_IMAGE_SIDE:
            raise ValueError(f"resolution {name} must be in [1, {_core.MAX_IMAGE_SIDE}], got {side}")
        sides.append(side)
    return sides[0], sides[1]


def _check_ranges(ranges: Any, num_triangles: int) -> npt.NDArray[np.int64]:
    if ranges is None:
        raise ValueError("ranges is required in range mode (pos of shape (num_vertices, 4)): "
                         "(minibatch_size, 2) int32 rows [first triangle, triangle count]; "
                         "or give pos as (minibatch_size, num_vertices, 4) for instanced mode")
    r = _index_array(ranges, "ranges")
    if r.ndim != 2 or r.shape[0] < 1 or r.shape[1] != 2:
        raise ValueError(f"ranges must have shape (minibatch_size >= 1, 2), got {_shape_text(r)}")
    bad = (r[:, 0] < 0) | (r[:, 1] < 0) | (r[:, 0] + r[:, 1] > num_triangles)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"ranges[{k}] = {r[k].tolist()} (first triangle, count) reaches outside "
                         f"tri's {num_triangles} triangles")
    return r


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


# -- rasterize ---------------------------------------------------------------------------------

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


def _rasterize(glctx: _Context | None, pos: Any, tri: Any, resolution: Any, ranges: Any = None,
               grad_db: bool = True) -> tuple[np.ndarray, np.ndarray]:
    p = _real_array(pos, "pos")
    if p.ndim == 3:
        if p.shape[0] < 1 or p.shape[1] < 1 or p.shape[2] != 4:
            raise ValueError(f"pos must have shape (minibatch_size, num_vertices, 4) in instanced mode "
                             f"(both >= 1), got {_shape_text(p)}")
        num_vertices = p.shape[1]
    elif p.ndim == 2:
        if p.shape[0] < 1 or p.shape[1] != 4:
            raise ValueError(f"pos must have shape (num_vertices >= 1, 4) in range mode, got {_shape_text(p)}")
        num_vertices = p.shape[0]
    else:
        raise ValueError("pos must have shape (minibatch_size, num_vertices, 4) (instanced mode) or "
                         f"(num_vertices, 4) with ranges (range mode), got {_shape_text(p)}")
    _float32_values(p, "pos")
    t = _check_tri(tri, num_vertices, "pos")
    height, width = _check_resolution(resolution)
    if not isinstance(grad_db, (bool, np.bool_)):
        raise ValueError(f"grad_db must be True or False, got {grad_db!r:.80}")
    # (clip-space vertices, first triangle) per image; ranges are ignored in instanced mode.
    if p.ndim == 3:
        jobs = [(p[k], 0, len(t)) for k in range(p.shape[0])]
    else:
        jobs = [(p, int(first), int(n)) for first, n in _check_ranges(ranges, len(t))]
    output_db = glctx is None or glctx.output_db
    _check_rasterize_budget(len(jobs), height, width, output_db, max((n for _, _, n in jobs), default=0),
                            "pos" if p.ndim == 3 else "ranges")
    rast = np.zeros((len(jobs), height, width, 4), dtype=np.float32)
    rast_db = np.zeros((len(jobs), height, width, 4 if output_db else 0), dtype=np.float32)
    for k, (vertices, first, n) in enumerate(jobs):
        if n == 0:
            continue
        clip = vertices[t[first:first + n]]  # (n, 3, 4)
        _shade(clip, _visible_triangles(clip, height, width), first, rast[k], rast_db[k])
    return rast, rast_db


# rasterize's working memory besides its outputs, bytes (NumPy's allocations as tracemalloc traces
# them, with margin; tests/test_nv.py checks that these bound them): per pixel of an image (the
# visibility map, the covered pixels' indices), per pixel shaded at once (_SHADE_BLOCK of them at
# most: the float64 barycentrics and derivatives), per triangle of an image (culling, clipping).
_PIXEL_WORK, _SHADED_PIXEL_WORK, _TRIANGLE_WORK = 40, 450, 1700


def _check_rasterize_budget(images: int, height: int, width: int, output_db: bool, triangles: int,
                            minibatch_from: str) -> None:
    """rast and rast_db, and the work of one image, against the memory budget before any of it
    is allocated, naming the arguments that set the size."""
    pixels = height * width
    outputs = images * pixels * (32 if output_db else 16)  # (h, w, 4) float32 each
    work = (pixels * _PIXEL_WORK + min(pixels, _SHADE_BLOCK) * _SHADED_PIXEL_WORK
            + triangles * _TRIANGLE_WORK)
    check_budget(outputs + work,
                 f"rasterize(): rast{' and rast_db' if output_db else ''} for {images} images "
                 f"({minibatch_from}) at resolution ({height}, {width}), with the work of up to "
                 f"{triangles} triangles (tri) an image,")


_RASTERIZE_SIGNATURE = inspect.signature(_rasterize).replace(
    parameters=list(inspect.signature(_rasterize).parameters.values())[1:])


def _wrong_context(args: tuple[Any, ...], kwargs: dict[str, Any]) -> bool:
    """Whether ``args[0]``, not a context of this module, is meant as one: it is no array and
    the call reads as ``rasterize(glctx, pos, tri, resolution, ...)`` (the rest binds, with a
    resolution where one belongs) rather than ``rasterize(pos, tri, resolution, ...)``."""
    first = args[0]
    if first is None or isinstance(first, (np.ndarray, list, tuple, int, float, complex)) or any(
            hasattr(first, a) for a in ("__array__", "__array_interface__", "__cuda_array_interface__",
                                        "__dlpack__")):
        return False

    def bound(a: tuple[Any, ...]) -> Any:
        try:
            return _RASTERIZE_SIGNATURE.bind(*a, **kwargs).arguments
        except TypeError:
            return None

    def pair_of_ints(value: Any) -> bool:
        try:
            arr = np.asarray(value)
        except Exception:  # noqa: BLE001 - anything that is no array is no resolution
            return False
        return arr.shape == (2,) and arr.dtype.kind in "iu"

    rest, whole = bound(args[1:]), bound(args)
    return rest is not None and (whole is None or (pair_of_ints(rest["resolution"])
                                                   and not pair_of_ints(whole["resolution"])))


def rasterize(*args: Any, **kwargs: Any) -> tuple[np.ndarray, np.ndarray]:
    """Rasterize triangles: ``rasterize([glctx,] pos, tri, resolution, ranges=None, grad_db=True)``.

    Both of nvdiffrast's call forms work: ``rasterize(glctx, pos, ...)`` (nvdiffrast.torch; glctx
    a ``RasterizeCudaContext`` or ``RasterizeGLContext`` from this module) and ``rasterize(pos,
    ...)`` (nvdiffrast.tensorflow, no context).

    pos : clip-space vertex positions (x, y, z, w), float32 (any real dtype is accepted and used
        as given, in float64). Instanced mode: (minibatch_size, num_vertices, 4), every image
        draws all of ``tri`` with its own positions. Range mode: (num_vertices, 4) with ``ranges``.
    tri : (num_triangles, 3) int32 vertex indices.
    resolution : (height, width) in pixels.
    ranges : range mode only: (minibatch_size, 2) int32, image k draws triangles
        ``tri[start:start + count]`` for ``ranges[k] = (start, count)``; ignored in instanced mode.
    grad_db : accepted for compatibility (there is no backward pass here).

    Returns (rast, rast_db), each (minibatch_size, height, width, 4) float32, row 0 at the BOTTOM
    of the image (NDC y = -1) as nvdiffrast returns them; pixel (row r, column c) is sampled at
    its centre, NDC (2 (c + 0.5) / W - 1, 2 (r + 0.5) / H - 1).

    * rast = (u, v, z/w, triangle_id + 1): the perspective-correct barycentric weights of
      vertices ``tri[id, 0]`` and ``tri[id, 1]`` (``tri[id, 2]`` weighs 1 - u - v), each clamped
      to [0, 1]; depth z/w in [-1, 1]; the index into ``tri`` plus one (in range mode too: the
      index in the whole ``tri``), stored as nvdiffrast does (exact up to 2**24). All four are
      0 where no triangle covers the pixel centre.
    * rast_db = (du/dX, du/dY, dv/dX, dv/dY): derivatives per pixel step right (X) and UP (Y),
      computed exactly at the pixel centre; 0 where empty. A ``RasterizeGLContext(output_db=False)``
      gives an empty (minibatch_size, height, width, 0) array instead, as in nvdiffrast.

    Triangles are clipped against -w <= z <= w; the nearest z/w wins the depth test (an exact
    tie keeps the earlier triangle); both windings are drawn. Coverage is softrast's exact
    fixed-point test (top-left fill rule, 1/256 px vertex precision).

    Raises ValueError naming the argument for a wrong shape or dtype, NaN, inf or a value beyond
    float32's range in ``pos``, an index in ``tri`` outside [0, num_vertices), ``ranges``
    reaching outside ``tri``, a resolution outside [1, MAX_IMAGE_SIDE], a ``glctx`` that is
    not a context of this module (positional or by keyword), or outputs and working memory
    (about 40 bytes a pixel and 1.7 kB a triangle of an image besides rast and rast_db) beyond
    the memory budget (``softrast.set_memory_budget``), before allocating them.
    """
    glctx: _Context | None = None
    if args and isinstance(args[0], _Context):
        glctx, args = args[0], args[1:]
    elif "glctx" in kwargs:
        glctx = kwargs.pop("glctx")
        if glctx is not None and not isinstance(glctx, _Context):
            raise ValueError("glctx must be a softrast.nv.RasterizeCudaContext or RasterizeGLContext, "
                             f"got {type(glctx).__name__}")
    elif args and _wrong_context(args, kwargs):
        raise ValueError("glctx must be a softrast.nv.RasterizeCudaContext or RasterizeGLContext, "
                         f"got {type(args[0]).__module__}.{type(args[0]).__name__}")
    try:
        bound = _RASTERIZE_SIGNATURE.bind(*args, **kwargs)
    except TypeError as exc:
        raise TypeError(f"rasterize(): {exc}; call rasterize([glctx,] pos, tri, resolution, "
                        "ranges=None, grad_db=True)") from None
    return _rasterize(glctx, *bound.args, **bound.kwargs)


# -- interpolate -------------------------------------------------------------------------------

def _diff_attr_list(diff_attrs: Any, num_attributes: int) -> list[int]:
    if diff_attrs is None:
        return []
    if isinstance(diff_attrs, str):
        if diff_attrs != "all":
            raise ValueError(f"diff_attrs must be 'all' or a list of attribute indices, got {diff_attrs!r:.80}")
        return list(range(num_attributes))
    d = _index_array(diff_attrs, "diff_attrs")
    if d.ndim != 1:
        raise ValueError(f"diff_attrs must be a flat list of attribute indices, got shape {_shape_text(d)}")
    bad = (d < -num_attributes) | (d >= num_attributes)
    if bad.any():
        raise ValueError(f"diff_attrs: index {int(d[bad][0])} is outside attr's {num_attributes} attributes")
    return [int(i) % num_attributes for i in d]  # negative indices count from the end, as in nvdiffrast


def interpolate(attr: Any, rast: Any, tri: Any, rast_db: Any = None,
                diff_attrs: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """Interpolate vertex attributes at each pixel of a ``rasterize`` output, as nvdiffrast.

    attr : (num_vertices, num_attributes), or (minibatch_size, num_vertices, num_attributes) with
        one set per image (a minibatch of 1 is broadcast to every image); float32 (any real dtype).
    rast : rasterize's first output, (minibatch_size, height, width, 4).
    tri : (num_triangles, 3) int32: the triangles rast's ids index (their vertices index ``attr``;
        they may differ from rasterize's ``tri``, e.g. a separate colour index buffer).
    rast_db : rasterize's second output; needed for ``diff_attrs``.
    diff_attrs : None, "all", or a list of attribute indices (negative ones count from the end)
        whose image-space derivatives to return.

    Returns (out, out_da), float32, row 0 at the bottom like ``rast``:

    * out : (minibatch_size, height, width, num_attributes), ``u a0 + v a1 + (1 - u - v) a2``
      with a_k the attributes of vertex ``tri[id, k]``; 0 where no triangle covers the pixel.
    * out_da : (minibatch_size, height, width, 2 len(diff_attrs)), (dA/dX, dA/dY) for each
      selected attribute A in order (per pixel step right and up); 0 where empty. Without
      ``diff_attrs`` an empty (minibatch_size, height, width, 0) array, as nvdiffrast returns.

    Raises ValueError naming the argument for a wrong shape or dtype, NaN, inf or a value beyond
    float32's range in ``attr``, ``rast`` or ``rast_db``, a triangle id beyond ``tri``, an index
    in ``tri`` outside ``attr``'s vertices, an attribute index outside ``attr``, or
    ``diff_attrs`` without ``rast_db``.
    """
    a = _real_array(attr, "attr")
    if a.ndim not in (2, 3) or 0 in a.shape:
        raise ValueError("attr must have shape (num_vertices, num_attributes) or (minibatch_size, "
                         f"num_vertices, num_attributes), none of them 0, got {_shape_text(a)}")
    _float32_values(a, "attr")
    r = _real_array(rast, "rast")
    if r.ndim != 4 or r.shape[3] != 4 or 0 in r.shape:
        raise ValueError(f"rast must have shape (minibatch_size, height, width, 4), got {_shape_text(r)}")
    _float32_values(r, "rast")
    batch = r.shape[0]
    if a.ndim == 3 and a.shape[0] not in (1, batch):
        raise ValueError(f"attr has a minibatch of {a.shape[0]}, rast of {batch} (attr's must equal it or be 1)")
    t = _check_tri(tri, a.shape[-2], "attr")
    num_attributes = a.shape[-1]
    diff = _diff_attr_list(diff_attrs, num_attributes)
    if diff:
        if rast_db is None:
            raise ValueError("rast_db is required with diff_attrs: pass rasterize's second output")
        db = _real_array(rast_db, "rast_db")
        if db.shape != r.shape:
            raise ValueError(f"rast_db must have rast's shape {_shape_text(r)}, got {_shape_text(db)} "
                             "(a RasterizeGLContext(output_db=False) gives no derivatives)")
        _float32_values(db, "rast_db")

    ids = _float_to_ids(r[..., 3].astype(np.float32))  # triangle_id + 1
    if (ids > len(t)).any():
        raise ValueError(f"rast holds triangle id {int(ids.max()) - 1}, beyond tri's {len(t)} triangles "
                         "(was rast made with another tri?)")
    out = np.zeros(r.shape[:3] + (num_attributes,), dtype=np.float32)
    out_da = np.zeros(r.shape[:3] + (2 * len(diff),), dtype=np.float32)
    image, rows, cols = np.nonzero(ids > 0)  # nvdiffrast: id - 1 < 0 => empty
    if len(image) == 0:
        return out, out_da
    vertex = t[ids[image, rows, cols] - 1]  # (N, 3)
    if a.ndim == 2:
        corners = a[vertex]  # (N, 3, num_attributes)
    else:
        corners = a[(image if a.shape[0] > 1 else np.zeros_like(image))[:, None], vertex]
    u = r[image, rows, cols, 0][:, None]
    v = r[image, rows, cols, 1][:, None]
    a0, a1, a2 = corners[:, 0], corners[:, 1], corners[:, 2]
    with np.errstate(over="ignore"):  # a result beyond float32's range => inf, as in float32
        out[image, rows, cols] = u * a0 + v * a1 + (1.0 - u - v) * a2
        if diff:
            du_dx, du_dy, dv_dx, dv_dy = (db[image, rows, cols, k][:, None] for k in range(4))
            da_du = a0[:, diff] - a2[:, diff]
            da_dv = a1[:, diff] - a2[:, diff]
            da = np.stack([du_dx * da_du + dv_dx * da_dv, du_dy * da_du + dv_dy * da_dv], axis=2)
            out_da[image, rows, cols] = da.reshape(len(image), 2 * len(diff))
    return out, out_da
