"""The triangles a draw sends to the blending reference (softrast.reference.blend), no softrast
code: a camera at the origin (``RefCamera``: perspective or orthographic, window space x right,
y down), and each triangle's window coordinates, view depths and per-corner colour, alpha and uvs
(``Tri``, ``mesh_tris``), with the values rounded to float32 as the core stores them (``f32``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .texture import decode

__all__ = ["RefCamera", "Tri", "f32", "texture_linear", "mesh_tris"]

# ----------------------------------------------------------------------------- cameras


@dataclass
class RefCamera:
    """A camera at the origin looking down -z (softrast's identity pose, OpenGL view axes).

    Perspective: gluPerspective's projection with vertical field of view ``fov_y`` degrees and the
    image's aspect; orthographic: half extents ``xmag``, ``ymag``. Window space: x right, y down,
    (0, 0) the image's top-left corner.
    """
    width: int
    height: int
    fov_y: float | None = None
    xmag: float | None = None
    ymag: float | None = None

    @property
    def perspective(self) -> bool:
        return self.fov_y is not None

    def _scales(self) -> tuple[float, float]:
        if self.perspective:
            f = 1.0 / math.tan(math.radians(self.fov_y) / 2.0)
            return f / (self.width / self.height), f
        return 1.0 / self.xmag, 1.0 / self.ymag

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points to window coordinates.

        Parameters
        ----------
        points : numpy.ndarray, shape (n, 3)
            World (= view) points.

        Returns
        -------
        xy : numpy.ndarray, shape (n, 2)
            Window coordinates, float64.
        depth : numpy.ndarray, shape (n,)
            View depth, -z.
        """
        p = np.asarray(points, np.float64)
        sx, sy = self._scales()
        depth = -p[:, 2]
        div = depth if self.perspective else np.ones_like(depth)
        ndc_x, ndc_y = sx * p[:, 0] / div, sy * p[:, 1] / div
        xy = np.stack([(ndc_x + 1.0) * self.width / 2.0, (1.0 - ndc_y) * self.height / 2.0], axis=1)
        return xy, depth

    def unproject(self, xy: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """The inverse of ``project``.

        Parameters
        ----------
        xy : numpy.ndarray, shape (n, 2)
            Window coordinates.
        depth : numpy.ndarray, shape (n,) or scalar
            View depths.

        Returns
        -------
        numpy.ndarray
            (n, 3) float64 world points.
        """
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        depth = np.broadcast_to(np.asarray(depth, np.float64), (len(xy),))
        sx, sy = self._scales()
        ndc_x = xy[:, 0] * 2.0 / self.width - 1.0
        ndc_y = 1.0 - xy[:, 1] * 2.0 / self.height
        mul = depth if self.perspective else np.ones_like(depth)
        return np.stack([ndc_x / sx * mul, ndc_y / sy * mul, -depth], axis=1)


# ----------------------------------------------------------------------------- triangles


@dataclass
class Tri:
    """One triangle of one draw, as the reference sees it (listed in draw order, then face order)."""
    xy: np.ndarray            # (3, 2) window coordinates, float64
    depth: np.ndarray         # (3,) view depths (> 0)
    rgba: np.ndarray          # (3, 4) linear RGBA per corner
    blend: bool               # alphaMode BLEND (else opaque)
    cull: str = "none"        # "none" | "back" | "front"
    uv: np.ndarray | None = None       # (3, 2)
    texture: np.ndarray | None = None  # (th, tw, 4) linear RGBA texels, float64
    draw: int = 0
    face: int = 0
    verts: tuple = (0, 1, 2)  # the corners' vertex indices within the draw


def f32(a: Any) -> np.ndarray:
    """Values as the core stores them.

    Parameters
    ----------
    a : array_like
        Any values.

    Returns
    -------
    numpy.ndarray
        ``a`` rounded to float32, back in float64.
    """
    return np.asarray(a, np.float32).astype(np.float64)


def texture_linear(image: np.ndarray, srgb: bool) -> np.ndarray:
    """A uint8 texture image as linear RGBA (``softrast.reference.texture.decode``).

    Parameters
    ----------
    image : numpy.ndarray, shape (h, w) or (h, w, c)
        uint8: 1 grey, 2 grey + alpha, 3 RGB, 4 RGBA.
    srgb : bool
        Decode the colour channels (never the alpha) from sRGB.

    Returns
    -------
    numpy.ndarray
        (h, w, 4) float64 linear RGBA.
    """
    assert np.asarray(image).dtype == np.uint8
    return decode(image, srgb)


def mesh_tris(cam: RefCamera, positions, faces, *, rgba=None, base_color=(0.8, 0.8, 0.8, 1.0),
              blend: bool, cull: str = "none", uvs=None, texture=None, draw: int = 0,
              pose: np.ndarray | None = None) -> list[Tri]:
    """The triangles of one draw, as the reference sees them.

    Parameters
    ----------
    cam : RefCamera
        The camera.
    positions : array_like, shape (n, 3)
        Object-space vertices (stored as float32, as softrast stores them).
    faces : array_like, shape (m, 3)
        Vertex indices.
    rgba : array_like, shape (n, 3) or (n, 4), optional
        Per-vertex colours, replacing ``base_color`` (its alpha too).
    base_color : array_like, shape (4,)
        The material's RGBA.
    blend : bool
        alphaMode BLEND (else opaque).
    cull : {"none", "back", "front"}
        The draw's culling.
    uvs : array_like, shape (n, 2), optional
        Texture coordinates.
    texture : numpy.ndarray, shape (th, tw, 4), optional
        Linear RGBA texels (``texture_linear``).
    draw : int
        The draw's index (its place in the order).
    pose : numpy.ndarray, shape (4, 4), optional
        Model to world.

    Returns
    -------
    list of Tri
        In face order.
    """
    pos = f32(positions)
    if pose is not None:
        pose = np.asarray(pose, np.float64)
        pos = pos @ pose[:3, :3].T + pose[:3, 3]
    xy, depth = cam.project(pos)
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    if rgba is not None:
        col = f32(rgba)
        if col.shape[1] == 3:
            col = np.c_[col, np.ones(len(col))]
    else:
        col = np.tile(f32(base_color), (len(pos), 1))
    uv = None if uvs is None else f32(uvs)
    return [Tri(xy[f], depth[f], col[f], blend, cull, None if uv is None else uv[f], texture,
                draw, k, tuple(int(v) for v in f)) for k, f in enumerate(faces)]
