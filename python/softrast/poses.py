"""Camera poses for datasets: turntables (``orbit``) and even coverage of a sphere
(``sphere_poses``). Each returns an (n, 4, 4) float64 array of camera-to-world poses that look at
``target``, in the axes of the camera ``convention`` they are for ("opengl": x right, y up,
looking down -z, as ``PerspectiveCamera`` and pyrender; "opencv": x right, y down, looking down
+z, as ``IntrinsicsCamera``'s default): assign one to ``camera.pose``.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from ._checks import choice, finite_real, positive_real, real_array
from .camera import IntrinsicsCamera, PerspectiveCamera

__all__ = ["orbit", "sphere_poses", "look_at_pose"]

_GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])


def _vec3(value: Any, name: str) -> npt.NDArray[np.float64]:
    v = real_array(value, name).reshape(-1)
    if v.shape != (3,) or not np.isfinite(v).all():
        raise ValueError(f"{name} must be 3 finite numbers, got {np.asarray(value).tolist()!r:.80}")
    return v


def _count(n: Any) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise TypeError(f"n must be an integer, got {type(n).__name__}")
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    return int(n)


def look_at_pose(eye: npt.ArrayLike, target: npt.ArrayLike, up: npt.ArrayLike = (0.0, 1.0, 0.0),
                 convention: str = "opengl") -> npt.NDArray[np.float64]:
    """The camera-to-world pose at ``eye`` looking at ``target`` (as ``Camera.look_at``).

    Parameters
    ----------
    eye, target : array_like, shape (3,)
        World-space points.
    up : array_like, shape (3,), optional
        Up in the image (default +y).
    convention : str, optional
        "opengl" (default: x right, y up, looking down -z, as ``PerspectiveCamera`` and pyrender)
        or "opencv" (x right, y down, looking down +z, as ``IntrinsicsCamera``'s default).

    Returns
    -------
    ndarray, shape (4, 4), float64

    Raises
    ------
    ValueError
        As ``Camera.look_at``.
    """
    choice(convention, "convention", ("opengl", "opencv"))
    cam = PerspectiveCamera() if convention == "opengl" else IntrinsicsCamera(1.0, 1.0, 0.0, 0.0, 1, 1)
    return cam.look_at(eye, target, up).pose.copy()


def _poses(eyes: npt.NDArray[np.float64], target, up, convention) -> npt.NDArray[np.float64]:
    up_v = _vec3(up, "up")
    out = np.empty((len(eyes), 4, 4))
    for k, eye in enumerate(eyes):
        # at a pole (the view along up) the roll is undefined: take the next axis as up
        u = up_v
        if np.linalg.norm(np.cross(u / np.linalg.norm(u), (target - eye) / np.linalg.norm(target - eye))) < 1e-6:
            u = np.roll(up_v, 1)
        out[k] = look_at_pose(eye, target, u, convention)
    return out


def _common(target, radius, n, up, convention):
    """The generators' shared arguments, checked, and an orthonormal frame (a, b, u): u along
    up, a the azimuth-0 direction (toward +z where up allows), b = u x a."""
    t = _vec3(target, "target")
    r = positive_real(radius, "radius")
    count = _count(n)
    up_v = _vec3(up, "up")
    if not np.linalg.norm(up_v) > 0:
        raise ValueError("up must be a non-zero vector")
    choice(convention, "convention", ("opengl", "opencv"))
    u = up_v / np.linalg.norm(up_v)
    a = np.array([0.0, 0.0, 1.0]) - u[2] * u
    if np.linalg.norm(a) < 1e-6:
        a = np.array([1.0, 0.0, 0.0]) - u[0] * u
    a /= np.linalg.norm(a)
    return t, r, count, up_v, (a, np.cross(u, a), u)


def orbit(target: npt.ArrayLike, radius: float, n: int, elevation: float = 20.0,
          up: npt.ArrayLike = (0.0, 1.0, 0.0), start: float = 0.0,
          convention: str = "opengl") -> npt.NDArray[np.float64]:
    """``n`` poses on a turntable around ``target``.

    Parameters
    ----------
    target : array_like, shape (3,)
        What every pose looks at.
    radius : float
        Distance from ``target`` (> 0).
    n : int
        Number of poses (>= 1).
    elevation : float, optional
        Degrees above the plane normal to ``up``, in [-90, 90] (default 20).
    up : array_like, shape (3,), optional
        Non-zero (default +y).
    start : float, optional
        Azimuths are start + 360 k / n degrees (k = 0 .. n-1; azimuth 0 is the +z side of
        ``target`` for up = +y, increasing counter-clockwise seen from above).
    convention : str, optional
        "opengl" (default: x right, y up, looking down -z, as ``PerspectiveCamera`` and pyrender)
        or "opencv" (x right, y down, looking down +z, as ``IntrinsicsCamera``'s default).

    Returns
    -------
    ndarray, shape (n, 4, 4), float64
        Camera-to-world poses looking at ``target``: assign one to ``camera.pose``.

    Raises
    ------
    TypeError, ValueError
        For a bad argument, naming it.
    """
    t, r, count, up_v, (a, b, u) = _common(target, radius, n, up, convention)
    el = finite_real(elevation, "elevation")
    if not -90.0 <= el <= 90.0:
        raise ValueError(f"elevation must be in [-90, 90] degrees, got {elevation!r}")
    az0 = finite_real(start, "start")
    az = np.radians(az0 + 360.0 * np.arange(count) / count)
    e = math.radians(el)
    dirs = (np.cos(e) * (np.cos(az)[:, None] * a + np.sin(az)[:, None] * b) + math.sin(e) * u)
    return _poses(t + r * dirs, t, up_v, convention)


def sphere_poses(target: npt.ArrayLike, radius: float, n: int, up: npt.ArrayLike = (0.0, 1.0, 0.0),
                 convention: str = "opengl") -> npt.NDArray[np.float64]:
    """``n`` poses spread evenly over the sphere of ``radius`` around ``target``.

    A Fibonacci lattice: equal-area bands, golden-angle azimuths, from the top (along ``up``)
    down; ``up`` stays up in each image (at the poles the roll follows the next axis).

    Parameters
    ----------
    target : array_like, shape (3,)
        What every pose looks at.
    radius : float
        Distance from ``target`` (> 0).
    n : int
        Number of poses (>= 1).
    up : array_like, shape (3,), optional
        Non-zero (default +y).
    convention : str, optional
        "opengl" (default: x right, y up, looking down -z, as ``PerspectiveCamera`` and pyrender)
        or "opencv" (x right, y down, looking down +z, as ``IntrinsicsCamera``'s default).

    Returns
    -------
    ndarray, shape (n, 4, 4), float64
        Camera-to-world poses looking at ``target``: assign one to ``camera.pose``.

    Raises
    ------
    TypeError, ValueError
        For a bad argument, naming it.
    """
    t, r, count, up_v, (a, b, u) = _common(target, radius, n, up, convention)
    k = np.arange(count) + 0.5
    height = 1.0 - 2.0 * k / count  # equal-area bands
    ring = np.sqrt(np.maximum(0.0, 1.0 - height ** 2))
    az = k * math.pi * (3.0 - math.sqrt(5.0))  # the golden angle
    dirs = height[:, None] * u + ring[:, None] * (np.cos(az)[:, None] * a + np.sin(az)[:, None] * b)
    return _poses(t + r * dirs, t, up_v, convention)
