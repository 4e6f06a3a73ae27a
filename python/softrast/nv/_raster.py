"""softrast.nv's raster: the core's own clipping and rasterization of triangles given in clip
space (``_core._rasterize_clip``, cpp/clip_raster.hpp), and nvdiffrast's triangle ids in a float32
channel both ways.

How: the core culls and clips each triangle against -w <= z <= w and its guard band (clip.cpp),
snaps it to 1/256 px and rasterizes it with its exact fixed-point edge functions (top-left fill
rule), the nearest z/w winning the depth test; at each covered pixel centre it computes nvdiffrast's
(u, v, z/w, id + 1) and (du/dX, du/dY, dv/dX, dv/dY) in float64 from the source triangle's
clip-space corners and rounds them to float32 once, writing into rast and rast_db in place, the
GIL released. The same bits for any thread count and instruction set (tests/test_threads.py,
tests/test_simd.py).
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .. import _core

# nvdiffrast's triangle id in a float32 channel (common.h, triidx_to_float): exact up to 2**24,
# then the bits of the int 0x4a800000 + id read as a float32 (the core writes them so too).
_EXACT_ID_MAX = 0x01000000
_ID_BIAS = 0x4A800000


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


def _rasterize_clip(pos: npt.NDArray[np.floating], tri: npt.NDArray[np.integer],
                    ranges: npt.NDArray[np.integer], height: int, width: int, output_db: bool,
                    threads: int = 0, simd: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(rast, rast_db) for checked arguments: pos (1 or images, num_vertices, 4) in clip space
    (rounded to float32), tri (num_triangles, 3), ranges (images, 2) of (first, count): image k
    draws tri[first:first + count] with pos[k] (pos[0] for every image if pos holds one set).
    rast_db is (images, height, width, 0) without output_db. threads: 0 = one per core; simd=False:
    the generic kernels (the same bits)."""
    images = len(ranges)
    rast = np.empty((images, height, width, 4), dtype=np.float32)
    rast_db = np.empty((images, height, width, 4 if output_db else 0), dtype=np.float32)
    _core._rasterize_clip(np.ascontiguousarray(pos, dtype=np.float32), np.ascontiguousarray(tri, dtype=np.int32),
                          np.ascontiguousarray(ranges, dtype=np.int64), width, height, rast,
                          rast_db if output_db else None, threads, simd)
    return rast, rast_db
