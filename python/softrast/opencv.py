"""Small helpers for OpenCV users: channel order, depth in millimetres, mask outlines.

OpenCV itself (``cv2``) is needed only by ``draw_outline`` and is imported when it is called;
``softrast`` does not depend on it.

* ``to_bgr(color)``: softrast's colour is RGB (RGBA stays 4-channel: BGRA); OpenCV's is BGR.
* ``depth_to_mm_uint16(depth)``: the 16-bit millimetre depth images depth cameras and datasets
  (Kinect, RealSense, BOP, LINEMOD) store.
* ``draw_outline(image, mask)``: the silhouette of a render drawn on a photo.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np
import numpy.typing as npt

from ._checks import positive_real

__all__ = ["to_bgr", "depth_to_mm_uint16", "draw_outline"]


def to_bgr(color: npt.ArrayLike) -> np.ndarray:
    """RGB (h, w, 3) -> BGR, or RGBA (h, w, 4) -> BGRA, any dtype (``frame.color`` is uint8).

    Applying it twice gives the RGB back.

    Parameters
    ----------
    color : array_like, shape (h, w, 3) or (h, w, 4)

    Returns
    -------
    ndarray
        A new C-contiguous COPY (never a view of ``color``): OpenCV's drawing functions write in
        place and refuse the negative-stride view ``color[..., ::-1]`` would be, and a copy cannot
        change the frame.

    Raises
    ------
    ValueError
        For another shape.
    """
    arr = np.asarray(color)
    if arr.ndim != 3 or arr.shape[2] not in (3, 4):
        raise ValueError(f"color must be an (h, w, 3) RGB or (h, w, 4) RGBA image, got shape {arr.shape}")
    order = [2, 1, 0] if arr.shape[2] == 3 else [2, 1, 0, 3]
    return np.ascontiguousarray(arr[..., order])


def depth_to_mm_uint16(depth: npt.ArrayLike, scale: float = 1000.0) -> np.ndarray:
    """Depth in scene units (0 = nothing hit, as softrast's ``depth``) -> uint16 millimetres.

    Parameters
    ----------
    depth : array_like
        Real depths, finite and >= 0.
    scale : float, optional
        Millimetres per scene unit (1000.0: the scene is in metres; 1.0: already in mm).

    Returns
    -------
    ndarray, uint16
        Each value ``d > 0`` becomes ``floor(d * scale + 0.5)`` (round to nearest, halves up),
        clamped to [1, 65535]: a hit never reads as 0 (OpenCV's and depth cameras' "no reading"),
        and a depth beyond 65.535 m (at scale 1000) saturates at 65535. 0 stays 0.

    Raises
    ------
    TypeError
        For a depth that is not real numbers.
    ValueError
        For negative, NaN or infinite depths.
    """
    s = positive_real(scale, "scale")
    d = np.asarray(depth)
    if not (np.issubdtype(d.dtype, np.floating) or np.issubdtype(d.dtype, np.integer)) or d.dtype == np.bool_:
        raise TypeError(f"depth must be an array of real numbers, got dtype {d.dtype}")
    d = d.astype(np.float64)
    if not np.isfinite(d).all() or (d < 0).any():
        raise ValueError("depth must be finite and >= 0 (0 = nothing hit)")
    with np.errstate(over="ignore"):  # beyond float64: inf, saturated below
        mm = np.floor(d * s + 0.5)
    out = np.clip(mm, 1.0, 65535.0).astype(np.uint16)
    out[d == 0] = 0
    return out


def draw_outline(image: np.ndarray, mask: npt.ArrayLike, color: Sequence[int] = (0, 255, 0),
                 thickness: int = 1) -> np.ndarray:
    """Draw the outline of ``mask`` on ``image`` IN PLACE.

    The contours are ``cv2.findContours(mask, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)`` (every
    boundary, holes included, pixel by pixel) drawn with ``cv2.drawContours``: with
    ``thickness=1`` exactly the mask's boundary pixels (mask pixels with a 4-neighbour outside the
    mask) are set to ``color``.

    Parameters
    ----------
    image : ndarray, shape (h, w, 3), uint8
        C-contiguous and writeable.
    mask : array_like, shape (h, w)
    color : sequence of 3 int, optional
        In [0, 255], in the image's own channel order (BGR for an image from ``cv2.imread`` or
        ``to_bgr``); default green.
    thickness : int, optional
        >= 1 (default 1).

    Returns
    -------
    ndarray
        ``image``.

    Raises
    ------
    ValueError
        For a bad argument, naming it.
    """
    import cv2

    m = np.asarray(mask)
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        raise ValueError("image must be an (h, w, 3) uint8 NumPy array")
    if m.shape != image.shape[:2]:
        raise ValueError(f"mask shape {m.shape} differs from the image's {image.shape[:2]}")
    if not image.flags.c_contiguous or not image.flags.writeable:
        raise ValueError("image must be C-contiguous and writeable (drawn in place): use np.ascontiguousarray")
    if isinstance(thickness, bool) or not isinstance(thickness, (int, np.integer)) or thickness < 1:
        raise ValueError(f"thickness must be an int >= 1, got {thickness!r}")
    rgb = tuple(int(c) for c in color)
    if len(rgb) != 3 or not all(0 <= c <= 255 for c in rgb):
        raise ValueError(f"color must be 3 ints in [0, 255], got {color!r}")
    contours, _ = cv2.findContours((m != 0).astype(np.uint8), cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    cv2.drawContours(image, contours, -1, rgb, int(thickness))
    return image
