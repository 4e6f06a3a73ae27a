"""Shadow maps (a light's ``shadows="map"``): the cameras its depth maps are rendered from.

cpp/shadow.hpp states how a map is read (pyrender's percentage-closer filter, a slope-scaled
bias). The cameras, fitted to the occluders (every mesh instance whose material does not blend):

* a directional light: one orthographic camera looking along the light, square, covering the
  occluders' world boxes (their corners in the light's axes) with a margin of 8 texels;
* a spot light: one perspective camera at the light along its axis, square, whose field of view
  is the cone (2 outer_cone) plus 8 texels; wider than 150 degrees, a cube as a point light's;
* a point light: a cube, six perspective cameras along +-x, +-y, +-z, each 90 degrees plus 8
  texels, so that the filter's taps near a face's edge stay inside that face.

The far plane reaches the farthest occluder corner; the near plane is 1e-4 of it (the depth map
holds view-axis distances in float32, so the ratio costs no precision).
"""
from __future__ import annotations

import math
from typing import Any, Iterable

import numpy as np

from .camera import Camera, OrthographicCamera, PerspectiveCamera

__all__ = ["map_cameras", "occluder_bounds"]

_CUBE = ((1.0, 0.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, -1.0, 0.0),
         (0.0, 0.0, 1.0), (0.0, 0.0, -1.0))
_MARGIN_TEXELS = 8
_WIDEST_SPOT = math.radians(150.0)


def occluder_bounds(instances: Iterable[Any]) -> np.ndarray | None:
    """The world-space corners of the boxes of the instances that cast shadows (not blended).

    Parameters
    ----------
    instances : iterable of Instance

    Returns
    -------
    ndarray, shape (8 * n, 3), or None
        8 corners per instance; None if there are none.
    """
    corners = []
    for inst in instances:
        material = inst.material
        if material is not None and getattr(material, "alpha_mode", "opaque") == "blend":
            continue
        pos = np.asarray(inst.mesh.positions, dtype=np.float64)
        if len(pos) == 0:
            continue
        lo, hi = pos.min(axis=0), pos.max(axis=0)
        box = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
        pose = np.asarray(inst.pose, dtype=np.float64)
        corners.append(box @ pose[:3, :3].T + pose[:3, 3])
    if not corners:
        return None
    out = np.concatenate(corners)
    return out if np.isfinite(out).all() else None


def _looking(origin: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """A camera pose at ``origin`` looking along the unit ``direction`` (its -z axis): the
    cameras' own look_at, with world y up unless the view runs nearly along it."""
    up = (0.0, 1.0, 0.0) if abs(direction[1]) < 0.9 else (1.0, 0.0, 0.0)
    return PerspectiveCamera().look_at(origin, np.asarray(origin) + direction, up).pose.copy()


def map_cameras(kind: str, position: np.ndarray, direction: np.ndarray, outer_cone: float,
                corners: np.ndarray, resolution: int) -> list[Camera]:
    """The cameras of a light's maps (their fitting is stated in this module's header).

    Parameters
    ----------
    kind : str
        "directional", "spot" or "point".
    position : ndarray, shape (3,)
        The light's world position.
    direction : ndarray, shape (3,)
        Its unit travel direction.
    outer_cone : float
        A spot light's outer half-angle in radians.
    corners : ndarray, shape (k, 3)
        The occluders' corners (``occluder_bounds``).
    resolution : int
        Texels square.

    Returns
    -------
    list of Camera
        One orthographic camera (directional), one perspective camera (spot up to 150 degrees),
        six (a cube), or none when the occluders sit at the light.
    """
    margin = _MARGIN_TEXELS / resolution
    span = float(np.max(np.ptp(corners, axis=0))) if len(corners) else 0.0
    if kind == "directional":
        centre = (corners.min(axis=0) + corners.max(axis=0)) * 0.5
        pose = _looking(centre, direction)
        local = (corners - centre) @ pose[:3, :3]  # (x, y, z) in the light's axes
        half = max(float(np.abs(local[:, :2]).max()), 1e-30) * (1.0 + 2.0 * margin)
        top, bottom = float(local[:, 2].max()), float(local[:, 2].min())
        pad = 0.01 * max(top - bottom, span, 1e-30)
        pose[:3, 3] = centre + pose[:3, 2] * (top + pad)
        cam = OrthographicCamera(xmag=half, ymag=half, width=resolution, height=resolution,
                                 near=0.5 * pad, far=top - bottom + 2.0 * pad)
        cam.pose = pose
        return [cam]
    far = float(np.linalg.norm(corners - position, axis=1).max()) * 1.01
    if not far > 0.0:
        return []
    near = far * 1e-4
    fov = 2.0 * outer_cone * (1.0 + 2.0 * margin)
    if kind == "spot" and fov <= _WIDEST_SPOT:
        cam = PerspectiveCamera(fov_y=math.degrees(fov), width=resolution, height=resolution,
                                near=near, far=far)
        cam.pose = _looking(position, direction)
        return [cam]
    cube = math.degrees(2.0 * math.atan(1.0 + 2.0 * margin))
    cams = []
    for axis in _CUBE:
        cam = PerspectiveCamera(fov_y=cube, width=resolution, height=resolution, near=near, far=far)
        cam.pose = _looking(position, np.array(axis))
        cams.append(cam)
    return cams
