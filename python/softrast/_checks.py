"""Argument checks shared by the Python modules: one helper per kind of check, and every error
names the argument (TypeError for the wrong kind of value, ValueError for a wrong value).

Numbers: int, float and NumPy integer/floating scalars (or 0-d arrays of them). bool is refused
though Python counts it as an int (``fov_y=True`` is a mistake, not 1 degree), and so are
strings (``float("45")`` would accept ``"45"``), complex numbers, None and arrays.
"""
from __future__ import annotations

import math
import numbers
import operator
from typing import Any, Sequence

import numpy as np
import numpy.typing as npt

from . import _core

# The core rounds its matrices to float32 for the per-vertex work; a matrix entry beyond this
# becomes inf there. Cameras check their projection against it when they are made.
FLOAT32_MAX = float(np.finfo(np.float32).max)  # 3.4028235e38


def _type_name(value: Any) -> str:
    return type(value).__name__


def real(value: Any, name: str) -> float:
    """A real number as a Python float (may be NaN or inf: see finite_real / positive_real)."""
    if type(value) is float:  # the common case first: a render checks several per call
        return value
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be a number, got bool {value!r}")
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        value = value[()]
    if not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {_type_name(value)} {value!r:.80}")
    try:
        return float(value)
    except OverflowError:  # an int beyond float's range (10**400)
        raise ValueError(f"{name} must be finite, got an int of {int(value).bit_length()} bits") from None


def finite_real(value: Any, name: str) -> float:
    v = real(value, name)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return v


def positive_real(value: Any, name: str) -> float:
    v = real(value, name)
    if not (math.isfinite(v) and v > 0.0):
        raise ValueError(f"{name} must be positive and finite, got {value!r}")
    return v


def float32_real(value: Any, name: str, nonnegative: bool = False) -> float:
    """A real number the core holds in float32: finite and at most FLOAT32_MAX in magnitude
    (>= 0 too if ``nonnegative``), so it is refused when given, naming ``name``, not at render."""
    v = real(value, name)
    if not ((0.0 if nonnegative else -FLOAT32_MAX) <= v <= FLOAT32_MAX):  # NaN fails too
        raise ValueError(f"{name} must be finite{', >= 0' if nonnegative else ''} and at most "
                         f"{FLOAT32_MAX:.8g} in magnitude (float32's range), got {value!r}")
    return v


def unit_vector(v: Any) -> npt.NDArray[np.float64] | None:
    """The direction of a finite float vector as a unit vector, or None for the zero vector.
    Scaled first by the largest magnitude, so a 1e-200 or 1e300 long vector (whose squares are 0
    or inf) has its direction too."""
    a = np.asarray(v, dtype=np.float64)
    m = float(np.max(np.abs(a))) if a.size else 0.0
    if not m > 0.0:
        return None
    if not 1e-150 < m < 1e150:  # the squares would under- or overflow
        a = a / m  # the largest component is +-1
    return a / float(np.linalg.norm(a))  # unscaled otherwise: the same bits as ever


def integer(value: Any, name: str) -> int:
    """An int (Python or NumPy integer), not bool, not float."""
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be an int, got bool {value!r}")
    try:
        return operator.index(value)
    except TypeError:
        raise TypeError(f"{name} must be an int, got {_type_name(value)} {value!r:.80}") from None


def image_side(value: Any, name: str) -> int:
    """A width or height in pixels: an int in [1, MAX_IMAGE_SIDE] (what a Renderer can make)."""
    side = integer(value, name)
    if not 1 <= side <= _core.MAX_IMAGE_SIDE:
        raise ValueError(f"{name} must be in [1, {_core.MAX_IMAGE_SIDE}] pixels, got {side}")
    return side


def flag(value: Any, name: str) -> bool:
    """True or False (a NumPy bool too) as a Python bool; not 1 or 0."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False, got {value!r:.80}")
    return bool(value)


def choice(value: Any, name: str, options: Sequence[str]) -> str:
    """One of the strings ``options``."""
    if not isinstance(value, str):
        raise TypeError(f"{name} must be one of {tuple(options)}, got {_type_name(value)} {value!r:.80}")
    if value not in options:
        raise ValueError(f"{name} must be one of {tuple(options)}, got {value!r:.80}")
    return value


def _holds_bool(value: Any, depth: int = 0) -> bool:
    """A bool among nested lists / tuples (the small ones these checks see: poses, RGB, 3-vectors)."""
    if isinstance(value, (bool, np.bool_)):
        return True
    return isinstance(value, (list, tuple)) and depth < 4 and any(_holds_bool(v, depth + 1) for v in value)


def real_array(value: Any, name: str) -> npt.NDArray[np.float64]:
    """An array of real numbers (int or float dtype) as a new float64 array; any shape.

    bool, string, complex and object arrays are refused: NumPy would turn True into 1.0 and
    "1" into 1.0 without a word.
    """
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{name} must be an array of numbers, got {_type_name(value)} {value!r:.80}")
    if _holds_bool(value):  # NumPy makes (True, 0, 0) an int array
        raise TypeError(f"{name} must hold real numbers, not bools: got {value!r:.80}")
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError, OverflowError) as exc:  # ragged nested lists, ...
        raise TypeError(f"{name} must be an array of numbers: {exc}") from None
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"{name} must hold real numbers, got dtype {arr.dtype} from {_type_name(value)}")
    return arr.astype(np.float64)  # always a copy: callers may write into it


def unit_rgb(value: Any, name: str) -> tuple[float, float, float]:
    """3 real numbers in [0, 1] (an RGB colour) as a tuple of Python floats."""
    if type(value) is tuple and len(value) == 3:  # fast path: plain floats and ints, not bools
        t0, t1, t2 = type(value[0]), type(value[1]), type(value[2])
        if (t0 is float or t0 is int) and (t1 is float or t1 is int) and (t2 is float or t2 is int):
            r, g, b = float(value[0]), float(value[1]), float(value[2])
            if 0.0 <= r <= 1.0 and 0.0 <= g <= 1.0 and 0.0 <= b <= 1.0:
                return r, g, b
    arr = real_array(value, name)
    if arr.shape != (3,):
        raise ValueError(f"{name} must be 3 numbers in [0, 1] (RGB), got shape {arr.shape}")
    if not (np.isfinite(arr).all() and (arr >= 0.0).all() and (arr <= 1.0).all()):
        raise ValueError(f"{name} must be 3 numbers in [0, 1] (RGB), got {arr.tolist()}")
    return float(arr[0]), float(arr[1]), float(arr[2])


def affine_pose(pose: Any, name: str = "pose") -> npt.NDArray[np.float64]:
    """A finite (4, 4) float64 affine transform (last row [0, 0, 0, 1]), returned read-only."""
    m = real_array(pose, name)
    if m.shape != (4, 4):
        raise ValueError(f"{name} must have shape (4, 4), got {m.shape}")
    if not np.isfinite(m).all():
        raise ValueError(f"{name} contains NaN or inf")
    if not np.allclose(m[3], [0.0, 0.0, 0.0, 1.0], rtol=0.0, atol=1e-12):  # no projective poses
        raise ValueError(f"{name} last row must be [0, 0, 0, 1], got {m[3].tolist()}")
    m[3] = (0.0, 0.0, 0.0, 1.0)
    m.setflags(write=False)
    return m
