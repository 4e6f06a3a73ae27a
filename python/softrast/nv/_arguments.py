"""softrast.nv's argument checks: a ValueError naming the argument for any bad input (shape,
dtype, NaN, inf or values beyond float32's range, indices outside their array, resolution)."""
from __future__ import annotations

import operator
from typing import Any

import numpy as np
import numpy.typing as npt

from .. import _core

_FLOAT32_MAX = float(np.finfo(np.float32).max)


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
