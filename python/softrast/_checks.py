"""Argument checks shared by the Python modules (errors name the argument)."""
from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt


def affine_pose(pose: Any, name: str = "pose") -> npt.NDArray[np.float64]:
    """A finite (4, 4) float64 affine transform (last row [0, 0, 0, 1]), returned read-only."""
    try:
        m = np.array(pose, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a (4, 4) array of numbers: {exc}") from exc
    if m.shape != (4, 4):
        raise ValueError(f"{name} must have shape (4, 4), got {m.shape}")
    if not np.isfinite(m).all():
        raise ValueError(f"{name} contains NaN or inf")
    if not np.allclose(m[3], [0.0, 0.0, 0.0, 1.0], rtol=0.0, atol=1e-12):  # no projective poses
        raise ValueError(f"{name} last row must be [0, 0, 0, 1], got {m[3].tolist()}")
    m[3] = (0.0, 0.0, 0.0, 1.0)
    m.setflags(write=False)
    return m
