"""What one load of a mesh file knows: the file (for warnings), its colour convention, its
materials as written, and the textures already made; sRGB decoding of 8-bit colours."""
from __future__ import annotations

import os
import sys
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..material import Material
from ..texture import Texture, srgb_decode

__all__ = ["FileInfo", "srgb_to_linear"]


srgb_to_linear = srgb_decode  # exact IEC 61966-2-1 sRGB decoding (float64), the texture's


_SRGB8 = srgb_to_linear(np.arange(256) / 255.0)  # 8-bit code -> linear


def _colors8(u8: Any, srgb: bool) -> np.ndarray:
    """(n, 3|4) 8-bit colours -> (n, 4) float64 linear RGBA (alpha only scaled)."""
    arr = np.asarray(u8)
    if arr.dtype != np.uint8:  # trimesh's colours are uint8; anything else as 0..255 numbers
        arr = np.clip(np.rint(np.asarray(arr, dtype=np.float64)), 0, 255).astype(np.uint8)
    out = np.ones((arr.shape[0], 4), dtype=np.float64)
    out[:, :3] = _SRGB8[arr[:, :3]] if srgb else arr[:, :3] / 255.0
    if arr.shape[1] == 4:
        out[:, 3] = arr[:, 3] / 255.0
    return out


def _normalized(values: Any) -> np.ndarray:
    """glTF COLOR_0 accessor data (float, or normalized unsigned byte / short) -> (n, 4) float64."""
    arr = np.asarray(values)
    if arr.ndim != 2 or arr.shape[1] not in (3, 4):
        raise ValueError(f"COLOR_0 must have 3 or 4 components, got shape {arr.shape}")
    if np.issubdtype(arr.dtype, np.integer):
        arr = arr / float(np.iinfo(arr.dtype).max)
    arr = np.clip(np.asarray(arr, dtype=np.float64), 0.0, 1.0)
    if arr.shape[1] == 3:
        arr = np.hstack([arr, np.ones((arr.shape[0], 1))])
    return arr


# -- what a file says about its materials --------------------------------------------------------
@dataclass
class FileInfo:
    """Per-load context: the file (for warnings), its colour convention and exact materials."""

    source: str | None  # the path as given; None for Mesh.from_trimesh
    srgb: bool  # 8-bit colours are sRGB-encoded (PLY / OBJ / OFF / STL); False for glTF
    gltf: list[Any] | None = None  # the glTF JSON "materials" list
    mtl: dict[str, Any] | None = None  # newmtl name -> its mtl._MtlEntry, read from the MTL
    soup: bool = False  # the format stores no shared vertices (STL): smooth=True merges them
    warned: set[Any] = field(default_factory=set)
    gltf_doc: dict[str, Any] | None = None  # the whole glTF JSON (textures, samplers, images)
    # One Texture per image (and sampler) within one load: key -> (what keeps the key's id
    # alive, Texture or None, why not)
    textures: dict[Any, tuple[Any, Texture | None, str | None]] = field(default_factory=dict)
    materials: dict[Any, tuple[Material | None, list[str]]] = field(default_factory=dict)

    def warn(self, key: Any, text: str) -> None:
        if key in self.warned:
            return
        self.warned.add(key)
        warnings.warn((f"{self.source}: " if self.source else "") + text, UserWarning,
                      stacklevel=_caller_level())


_PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))


def _caller_level() -> int:
    """The stacklevel of the first frame outside softrast (the user's load_mesh call)."""
    frame, level = sys._getframe(1), 1
    while frame is not None and os.path.dirname(os.path.abspath(frame.f_code.co_filename)) == _PACKAGE_DIR:
        frame, level = frame.f_back, level + 1
    return level
