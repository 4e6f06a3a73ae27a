"""Lines and points: primitives drawn with a scene's triangles and depth-tested against them
(``Scene.add(Lines(...), pose=, instance_id=)``, like meshes).

Both are drawn unlit in their own linear colour, as whole pixels (aliased; alpha 1 even under
msaa/ssaa, drawn over the resolved pixels). Their pixels get ``triangle_id`` -1, the instance id
given to ``Scene.add``, ``mask`` True, ``normal`` 0, ``barycentric`` and ``uv`` 0, and
``position`` / ``ray_depth`` of the point drawn. The pixel rules (Bresenham, DDA, thick lines,
point squares) are in ``RenderOptions``' docstring (``line_algorithm``) and the README.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from . import _core
from ._checks import real
from .mesh import _as_array, _rgba

__all__ = ["Lines", "Points"]

_MAX_ROWS = 2**31 - 1


def _frozen(arr: np.ndarray, dtype: npt.DTypeLike) -> np.ndarray:
    """A read-only C-contiguous copy over a bytes object (nothing can make it writeable again)."""
    arr = np.ascontiguousarray(arr, dtype=dtype)
    return np.frombuffer(arr.tobytes(), dtype=dtype).reshape(arr.shape)


def _real_rows(value: Any, name: str, cols: tuple[int, ...]) -> np.ndarray:
    try:
        arr = _as_array(value, name)
    except TypeError as exc:
        raise ValueError(str(exc)) from None
    if arr.dtype == np.bool_ or arr.dtype.kind not in "iuf":
        raise ValueError(f"{name} must have a real numeric dtype, got {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] not in cols:
        want = " or ".join(f"(n, {c})" for c in cols)
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")
    if arr.shape[0] > _MAX_ROWS:
        raise ValueError(f"{name} has too many rows ({arr.shape[0]})")
    return arr


def _positions(value: Any) -> np.ndarray:
    arr = _real_rows(value, "positions", (3,))
    with np.errstate(over="ignore"):
        out = _frozen(arr, np.float32)
    bad = ~np.isfinite(out).all(axis=1)
    if bad.any():
        raise ValueError(f"positions contains NaN or inf (or a value beyond float32) at row "
                         f"{int(np.flatnonzero(bad)[0])}")
    return out


def _colors(value: Any, n: int) -> np.ndarray | None:
    """(n, 3) float32 linear RGB from (n, 3) or (n, 4) uint8 (0-255) or float in [0, 1] (alpha
    dropped: lines and points are opaque)."""
    if value is None:
        return None
    arr = _real_rows(value, "colors", (3, 4))
    if arr.shape[0] != n:
        raise ValueError(f"colors must have one row per position ({n}), got {arr.shape[0]}")
    if arr.dtype == np.uint8:
        rgb = arr[:, :3].astype(np.float32) / np.float32(255.0)
    else:
        rgb = arr[:, :3].astype(np.float64)
        if not np.isfinite(rgb).all() or (rgb.size and (rgb.min() < 0.0 or rgb.max() > 1.0)):
            raise ValueError("colors must be uint8 or finite floats in [0, 1]")
    return _frozen(rgb, np.float32)


def _extent(value: Any, name: str) -> float:
    try:
        v = real(value, name)
    except TypeError as exc:
        raise ValueError(str(exc)) from None
    if not (np.isfinite(v) and v > 0.0 and v <= 1e6):
        raise ValueError(f"{name} must be finite, > 0 and at most 1e6 pixels, got {value!r}")
    return float(np.float32(v))


class _Primitive:
    """What Lines and Points share: checked positions, per-position colours or one colour."""

    __slots__ = ("_positions", "_colors", "_color")

    def _set_common(self, positions: npt.ArrayLike, colors: npt.ArrayLike | None, color: Any) -> None:
        self._positions = _positions(positions)
        self._colors = _colors(colors, self._positions.shape[0])
        try:
            self._color = _rgba(color, "color")[:3]
        except TypeError as exc:
            raise ValueError(str(exc)) from None

    @property
    def positions(self) -> npt.NDArray[np.float32]:
        """(n, 3) float32, read-only."""
        return self._positions

    @property
    def colors(self) -> npt.NDArray[np.float32] | None:
        """(n, 3) float32 linear RGB, read-only, or None."""
        return self._colors

    @property
    def color(self) -> tuple[float, float, float]:
        """The RGB colour used without ``colors`` (linear, in [0, 1])."""
        return self._color


class Lines(_Primitive):
    """Line segments between points, drawn ``width`` pixels wide.

    Immutable: the arrays are read-only copies. Picklable.

    Parameters
    ----------
    positions : array_like, shape (n, 3)
        Real, model space (stored as float32).
    segments : array_like, shape (m, 2)
        Integer indices into positions: segment k joins positions[segments[k, 0]] and
        positions[segments[k, 1]] (both endpoints are drawn).
    colors : array_like, shape (n, 3) or (n, 4), optional
        uint8 (0-255) or float in [0, 1], linear, per position;
        interpolated perspective-correctly along each segment. None => ``color``.
    width : float, optional
        > 0 pixels (default 1); <= 1 draws one pixel per step (``render(line_algorithm=)``), above
        1 every pixel whose centre lies within width / 2 of the segment (round caps).
    color : sequence of 3 or 4 floats, optional
        In [0, 1] (alpha ignored), the colour without ``colors``; default white.

    Raises
    ------
    TypeError, ValueError
        For a bad argument, naming it (and the row).
    """

    __slots__ = ("_segments", "_width")

    def __init__(self, positions: npt.ArrayLike, segments: npt.ArrayLike,
                 colors: npt.ArrayLike | None = None, width: float = 1.0,
                 color: Any = (1.0, 1.0, 1.0)) -> None:
        self._set_common(positions, colors, color)
        n = self._positions.shape[0]
        seg = _real_rows(segments, "segments", (2,))
        if seg.dtype.kind not in "iu":
            raise ValueError(f"segments must have an integer dtype, got {seg.dtype}")
        if seg.size and (seg.min() < 0 or seg.max() >= n):
            bad = int(np.flatnonzero(((seg < 0) | (seg >= n)).any(axis=1))[0])
            raise ValueError(f"segments: segment {bad} {seg[bad].tolist()} has an index outside "
                             f"[0, {n})")
        self._segments = _frozen(seg, np.int32)
        self._width = _extent(width, "width")

    @property
    def segments(self) -> npt.NDArray[np.int32]:
        """(m, 2) int32, read-only."""
        return self._segments

    @property
    def width(self) -> float:
        """Line width in pixels."""
        return self._width

    def _core_record(self, pose: np.ndarray, instance_id: int, depth_bias: float = 0.0) -> Any:
        return _core.Primitive(points=False, positions=self._positions, segments=self._segments,
                               colors=self._colors, color=self._color, width=self._width,
                               pose=pose, instance_id=instance_id, depth_bias=depth_bias)

    def __reduce__(self) -> tuple:
        return (Lines, (self._positions, self._segments, self._colors, self._width, self._color))

    def __repr__(self) -> str:
        return f"Lines({self._segments.shape[0]} segments, {self._positions.shape[0]} positions, width={self._width:g})"


class Points(_Primitive):
    """Points drawn as squares of ``size`` x ``size`` pixels.

    Immutable: the arrays are read-only copies. Picklable.

    Parameters
    ----------
    positions : array_like, shape (n, 3)
        Real, model space (stored as float32).
    colors : array_like, shape (n, 3) or (n, 4), optional
        uint8 (0-255) or float in [0, 1], linear, per position, per point. None => ``color``.
    size : float, optional
        > 0 pixels (default 1): a point at window position (x, y) covers the pixels whose centre
        (cx, cy) has x - size/2 < cx <= x + size/2 and the same in y; sizes below 1 draw as 1 (the
        pixel holding the point).
    color : sequence of 3 or 4 floats, optional
        In [0, 1] (alpha ignored), the colour without ``colors``; default white.

    Raises
    ------
    TypeError, ValueError
        For a bad argument, naming it (and the row).
    """

    __slots__ = ("_size",)

    def __init__(self, positions: npt.ArrayLike, colors: npt.ArrayLike | None = None,
                 size: float = 1.0, color: Any = (1.0, 1.0, 1.0)) -> None:
        self._set_common(positions, colors, color)
        self._size = _extent(size, "size")

    @property
    def size(self) -> float:
        """Point size in pixels."""
        return self._size

    def _core_record(self, pose: np.ndarray, instance_id: int) -> Any:
        return _core.Primitive(points=True, positions=self._positions, colors=self._colors,
                               color=self._color, width=self._size, pose=pose,
                               instance_id=instance_id)

    def __reduce__(self) -> tuple:
        return (Points, (self._positions, self._colors, self._size, self._color))

    def __repr__(self) -> str:
        return f"Points({self._positions.shape[0]} points, size={self._size:g})"
