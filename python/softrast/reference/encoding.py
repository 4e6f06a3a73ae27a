"""The 8-bit encodings and the sRGB transfer curve, in float64, written from IEC 61966-2-1 and
pyrender's shader (docs/pbr_notes.md), not from the C++ core.

    srgb_curve(linear) -> float64    IEC 61966-2-1 encoding of clamp(x, 0, 1), in [0, 1]
    srgb_encode(linear) -> uint8     floor(srgb_curve(x) * 255 + 0.5)
    linear_encode(linear) -> uint8   floor(clamp(x, 0, 1) * 255 + 0.5)
    pyrender_encode(linear) -> uint8 pyrender's pow(c, 1/2.2)
    srgb_to_linear(encoded) -> float64  the decoding curve (textures, colours read from files)
"""
from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["srgb_curve", "srgb_encode", "linear_encode", "pyrender_encode", "srgb_to_linear"]


def srgb_curve(linear: Any) -> np.ndarray:
    """The IEC 61966-2-1 encoding of clamp(x, 0, 1), as floats.

    Parameters
    ----------
    linear : array_like
        Linear values (any shape); clamped to [0, 1] first.

    Returns
    -------
    numpy.ndarray
        float64, the same shape, in [0, 1]: 12.92 x up to x = 0.0031308, else
        1.055 x^(1/2.4) - 0.055.
    """
    x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def srgb_encode(linear: Any) -> np.ndarray:
    """uint8 sRGB bytes: floor(srgb_curve(x) * 255 + 0.5).

    Parameters
    ----------
    linear : array_like
        Linear values (any shape).

    Returns
    -------
    numpy.ndarray
        uint8, the same shape.
    """
    return np.floor(srgb_curve(linear) * 255.0 + 0.5).astype(np.uint8)


def linear_encode(linear: Any) -> np.ndarray:
    """Bytes without a transfer curve.

    Parameters
    ----------
    linear : array_like
        Values of any shape, clamped to [0, 1].

    Returns
    -------
    numpy.ndarray
        uint8 floor(x * 255 + 0.5), the shape of ``linear``.
    """
    x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    return np.floor(x * 255.0 + 0.5).astype(np.uint8)


def pyrender_encode(linear: Any) -> np.ndarray:
    """pyrender's output bytes: clamp(pow(c, 1/2.2), 0, 1), stored to RGBA8 (round to nearest).

    Parameters
    ----------
    linear : array_like
        Linear radiance (any shape); negative values count as 0.

    Returns
    -------
    numpy.ndarray
        uint8, the same shape.
    """
    x = np.maximum(np.asarray(linear, dtype=np.float64), 0.0)
    return np.floor(np.clip(np.power(x, 1.0 / 2.2), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def srgb_to_linear(c: Any) -> np.ndarray:
    """The IEC 61966-2-1 decoding curve: c <= 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055)^2.4.

    Parameters
    ----------
    c : array_like
        Encoded values in [0, 1] (any shape); values below 0.04045, negative ones too, take the
        linear segment.

    Returns
    -------
    numpy.ndarray
        float64 linear values, the same shape.
    """
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((np.maximum(c, 0.04045) + 0.055) / 1.055) ** 2.4)
