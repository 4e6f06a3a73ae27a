"""nvdiffrast's functional API on NumPy arrays: ``import softrast.nv as dr``.

Code written for nvdiffrast (``import nvdiffrast.torch as dr``, CUDA only) runs on a CPU after
converting its tensors to NumPy arrays (``t.detach().cpu().numpy()``): the forward pass of
``rasterize`` and ``interpolate`` only (no gradients, no ``texture`` or ``antialias``), their
outputs channel for channel as nvdiffrast's, ``pos`` in clip space and image row 0 at the
BOTTOM (see ``rasterize`` and ``interpolate``). The triangles are clipped and drawn by the
core's own clipping and exact fixed-point rasterizer (``_raster``: ``_core._rasterize_clip``);
the arguments are checked by ``_arguments``. See docs/interop.md.
"""
from __future__ import annotations

import inspect
import os
from typing import Any

import numpy as np

from ..limits import check_budget
from ._arguments import (_check_ranges, _check_resolution, _check_tri, _float32_values, _index_array,
                         _real_array, _shape_text)
from ._raster import _float_to_ids, _rasterize_clip
from ._raster import _ids_to_float  # noqa: F401 (tests check the id encoding both ways)

__all__ = ["RasterizeCudaContext", "RasterizeGLContext", "interpolate", "rasterize"]


# -- contexts ----------------------------------------------------------------------------------

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


# -- rasterize ---------------------------------------------------------------------------------

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
    # Per image (first triangle, count); ranges are ignored in instanced mode, where image k
    # draws every triangle with pos[k]. Range mode: every image draws with the one pos.
    if p.ndim == 3:
        ranges = np.tile(np.array([0, len(t)], dtype=np.int64), (p.shape[0], 1))
    else:
        ranges = _check_ranges(ranges, len(t))
    output_db = glctx is None or glctx.output_db
    _check_rasterize_budget(len(ranges), height, width, output_db, p.size // 4,
                            int(ranges[:, 1].max(initial=0)), "pos" if p.ndim == 3 else "ranges")
    return _rasterize_clip(p if p.ndim == 3 else p[None], t, ranges, height, width, output_db)


# rasterize's working memory besides its outputs, bytes (tests/test_nv.py checks that these bound
# NumPy's allocations as tracemalloc traces them; the core's are counted from its records): per
# vertex of pos (the checked float64 copy and its check, the float32 copy, the core's snapped
# vertex), per triangle of an image (tri's checked copies, the core's setup record and its tile
# lists, the pieces clipping makes), per thread (the core's tile scratch, one per core).
_VERTEX_WORK, _TRIANGLE_WORK, _THREAD_WORK = 128, 400, 64 << 10


def _check_rasterize_budget(images: int, height: int, width: int, output_db: bool, vertices: int,
                            triangles: int, minibatch_from: str) -> None:
    """rast and rast_db, and the work of one image, against the memory budget before any of it
    is allocated, naming the arguments that set the size."""
    outputs = images * height * width * (32 if output_db else 16)  # (h, w, 4) float32 each
    work = vertices * _VERTEX_WORK + triangles * _TRIANGLE_WORK + (os.cpu_count() or 1) * _THREAD_WORK
    check_budget(outputs + work,
                 f"rasterize(): rast{' and rast_db' if output_db else ''} for {images} images "
                 f"({minibatch_from}) at resolution ({height}, {width}), with the work of "
                 f"{vertices} vertices (pos) and up to {triangles} triangles (tri) an image,")


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

    pos : clip-space vertex positions (x, y, z, w), float32 (any real dtype is accepted and
        rounded to float32, as nvdiffrast's tensors are). Instanced mode: (minibatch_size, num_vertices, 4), every image
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

    Triangles are clipped against -w <= z <= w; the nearest z/w wins the depth test (a tie, or
    a fragment nearer by less than (z/w + 2) 2**-20, keeps the earlier triangle); both windings are drawn. Coverage is
    softrast's exact fixed-point test (top-left fill rule, 1/256 px vertex precision); the
    outputs are computed in float64 from the triangle's clip-space corners at the pixel centre
    and rounded to float32 once (cpp/clip_raster.hpp), the same bits on any machine.

    Raises ValueError naming the argument for a wrong shape or dtype, NaN, inf or a value beyond
    float32's range in ``pos``, an index in ``tri`` outside [0, num_vertices), ``ranges``
    reaching outside ``tri``, a resolution outside [1, MAX_IMAGE_SIDE], a ``glctx`` that is
    not a context of this module (positional or by keyword), or outputs and working memory
    (about 130 bytes a vertex of ``pos`` and 400 bytes a triangle of an image besides rast and
    rast_db) beyond
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
