"""OpenCV's lens model (k1..k6 radial, p1 p2 tangential, s1..s4 thin prism): the coefficients
checked, points distorted, and distorted points undistorted by Newton's method in float64. How a
distorted camera is rendered is in docs/conventions.md, "How a distorted camera is rendered"
(code: ``softrast.distortion``).
"""
from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ._checks import real_array

__all__ = ["check_dist", "distort", "undistort"]


# OpenCV's coefficient order: (k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3, s4[, tauX, tauY]]]]).
_SIZES = (4, 5, 8, 12, 14)


_NEWTON_STEPS = 60


_TOLERANCE = 1e-12  # normalized units: 1e-9 px at a focal length of 1000 px


def check_dist(dist: Any) -> npt.NDArray[np.float64] | None:
    """The 12 coefficients of ``dist``, checked, or None for no distortion.

    Parameters
    ----------
    dist : array_like or None
        4, 5, 8, 12 or 14 finite OpenCV coefficients (k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2,
        s3, s4[, tauX, tauY]]]]).

    Returns
    -------
    ndarray, shape (12,), float64, or None
        (k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4), read-only; None for None or all zeros.

    Raises
    ------
    ValueError
        For another count, a non-finite value, or a tilted sensor (tauX, tauY non-zero).
    """
    if dist is None:
        return None
    d = real_array(dist, "dist").reshape(-1)
    if d.size not in _SIZES:
        raise ValueError(f"dist must hold 4, 5, 8, 12 or 14 OpenCV coefficients (k1, k2, p1, p2[, k3"
                         f"[, k4, k5, k6[, s1..s4[, tauX, tauY]]]]), got {d.size}")
    if not np.isfinite(d).all():
        raise ValueError(f"dist must be finite, got {d.tolist()}")
    if d.size == 14 and np.any(d[12:] != 0.0):
        raise ValueError(f"dist: a tilted sensor (tauX, tauY = {d[12]}, {d[13]}) is not supported; "
                         "only the radial, tangential and thin-prism terms are")
    full = np.zeros(12)
    full[:min(d.size, 12)] = d[:12]
    if not full.any():
        return None
    full.setflags(write=False)
    return full


def distort(x: npt.NDArray[np.float64], y: npt.NDArray[np.float64],
            d: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """OpenCV's distortion of normalized points (x, y) = (X / Z, Y / Z): ``cv2.projectPoints`` before K.

    Parameters
    ----------
    x, y : ndarray
        Normalized coordinates, float64.
    d : ndarray, shape (12,)
        ``check_dist``'s coefficients.

    Returns
    -------
    xd, yd : ndarray
        The distorted normalized coordinates.
    """
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = d
    r2 = x * x + y * y
    radial = (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1.0 + r2 * (k4 + r2 * (k5 + r2 * k6)))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) + r2 * (s1 + s2 * r2)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y + r2 * (s3 + s4 * r2)
    return xd, yd


def _jacobian(x: npt.NDArray[np.float64], y: npt.NDArray[np.float64], d: npt.NDArray[np.float64]) -> tuple[Any, ...]:
    """d(xd, yd) / d(x, y), and the radial denominator (the model is valid where it is > 0)."""
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = d
    r2 = x * x + y * y
    num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
    radial = num / den
    dnum = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)
    dden = k4 + r2 * (2.0 * k5 + 3.0 * k6 * r2)
    dradial = (dnum * den - num * dden) / (den * den)  # d radial / d r2
    sx = s1 + 2.0 * s2 * r2  # d (s1 r2 + s2 r2^2) / d r2
    sy = s3 + 2.0 * s4 * r2
    a = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x + 2.0 * x * sx
    b = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y + 2.0 * y * sx
    c = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y + 2.0 * x * sy
    e = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x + 2.0 * y * sy
    return a, b, c, e, den


def undistort(xd: npt.ArrayLike, yd: npt.ArrayLike, d: npt.NDArray[np.float64]) -> tuple[Any, Any, Any]:
    """The normalized points OpenCV's model distorts to (xd, yd), by Newton's method in float64.

    Parameters
    ----------
    xd, yd : array_like
        Distorted normalized coordinates (broadcast together).
    d : ndarray, shape (12,)
        ``check_dist``'s coefficients.

    Returns
    -------
    x, y : ndarray
        The undistorted points, NaN where not ``valid``.
    valid : ndarray of bool
        False where no such point was found to 1e-12 or where the model folds (its Jacobian is not
        positive there: a second, outer solution of a strong barrel distortion, which a lens does
        not see).
    """
    xd = np.asarray(xd, dtype=np.float64)
    yd = np.asarray(yd, dtype=np.float64)
    shape = np.broadcast(xd, yd).shape
    xd, yd = np.broadcast_to(xd, shape).reshape(-1), np.broadcast_to(yd, shape).reshape(-1)
    x, y = xd.copy(), yd.copy()
    tolerance = _TOLERANCE * (1.0 + np.hypot(xd, yd))
    with np.errstate(all="ignore"):  # diverging points become NaN and are marked invalid
        fx, fy = distort(x, y, d)
        fx, fy = fx - xd, fy - yd
        res = np.hypot(fx, fy)
        # Newton's steps on the points not converged yet, damped (a step that does not reduce
        # the residual is halved, up to 8 times); a point whose step cannot be made to reduce
        # it is dropped (it stays invalid): beyond a fold no solution exists.
        live = np.nonzero(~(res <= tolerance))[0]
        for _ in range(_NEWTON_STEPS):
            if not live.size:
                break
            lx, ly, lfx, lfy, lres = x[live], y[live], fx[live], fy[live], res[live]
            a, b, c, e, _den = _jacobian(lx, ly, d)
            det = a * e - b * c
            dx = (e * lfx - b * lfy) / det
            dy = (a * lfy - c * lfx) / det
            step = np.ones(live.size)
            nx, ny = lx - dx, ly - dy
            gx, gy = distort(nx, ny, d)
            gx, gy = gx - xd[live], gy - yd[live]
            new = np.hypot(gx, gy)
            for _half in range(8):
                worse = ~(new < lres)
                if not worse.any():
                    break
                step = np.where(worse, step * 0.5, step)
                nx, ny = lx - step * dx, ly - step * dy
                gx, gy = distort(nx, ny, d)
                gx, gy = gx - xd[live], gy - yd[live]
                new = np.hypot(gx, gy)
            ok = new < lres
            idx = live[ok]
            x[idx], y[idx], fx[idx], fy[idx], res[idx] = nx[ok], ny[ok], gx[ok], gy[ok], new[ok]
            live = idx[~(res[idx] <= tolerance[idx])]
        valid = (res <= tolerance) & np.isfinite(x) & np.isfinite(y)
        # The lens sees the sheet of the model around the axis: the Jacobian stays positive all
        # the way from the centre to the point (beyond a fold, or where the radial factor turns
        # negative and mirrors points through the axis, the model describes no real ray).
        for f in (1.0, 0.875, 0.75, 0.625, 0.5, 0.375, 0.25, 0.125):
            a, b, c, e, den = _jacobian(f * x, f * y, d)
            valid &= (a * e - b * c > 0.0) & (den > 0.0)
        r2 = x * x + y * y
        k1, k2, _, _, k3 = d[:5]
        valid &= (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))) > 0.0
    x = np.where(valid, x, np.nan).reshape(shape)
    y = np.where(valid, y, np.nan).reshape(shape)
    valid = valid.reshape(shape)
    return x, y, valid
