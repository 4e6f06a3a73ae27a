"""Cameras: a pose (camera-to-world) plus a projection to OpenGL clip space
(``PerspectiveCamera``, ``OrthographicCamera``, ``IntrinsicsCamera``; the base class is in
``softrast.camera_base``).

The conventions shared with the C++ core (``_core.pyi``: view, clip, NDC and window spaces, row
0 at the top, pixel centres, the pose's axes for each ``convention``) and each camera's rules
are in docs/conventions.md, "Spaces", "Pixels and images" and "Cameras".
"""
from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
import numpy.typing as npt

from . import _core
from ._checks import FLOAT32_MAX, choice, finite_real, integer, positive_real, real_array
from .camera_base import _GL_FROM_CV, Camera, _depth_image, _float32_finite, _image_side, _rotation
from .lens import check_dist, distort, undistort

__all__ = ["Camera", "PerspectiveCamera", "OrthographicCamera", "IntrinsicsCamera"]


class PerspectiveCamera(Camera):
    """A pinhole camera with a vertical field of view.

    gluPerspective's projection, as pyrender's ``PerspectiveCamera``, but pyrender's ``yfov`` is
    in RADIANS: ``fov_y=math.degrees(yfov)``.

    Parameters
    ----------
    fov_y : float, optional
        Vertical field of view in DEGREES, in (0, 180) (default 45), and large enough that the
        projection is finite in float32 (at least 5.5e-33 degrees without a fixed aspect or image
        size).
    width, height : int, optional
        Image size in pixels (informational; None if not fixed).
    near, far : float, optional
        Clipping distances along the viewing axis in scene units, 0 < near < far (defaults 0.05 and
        100).
    aspect : float, optional
        Width / height of the view volume; None => the aspect of the rendered image.

    Raises
    ------
    ValueError
        For a value outside those ranges, naming it.

    Warns
    -----
    UserWarning
        For a ``fov_y`` in [0.1, 3.2): it looks like radians.
    """

    def __init__(self, fov_y: float = 45.0, width: int | None = None, height: int | None = None,
                 near: float = 0.05, far: float = 100.0, aspect: float | None = None) -> None:
        super().__init__(near, far, width, height)
        fov = finite_real(fov_y, "fov_y")
        if not 0.0 < fov < 180.0:
            raise ValueError(f"fov_y must be in (0, 180) degrees, got {fov_y!r}")
        aspect_f = None if aspect is None else positive_real(aspect, "aspect")
        # projection_matrix's x and y scales, f / aspect and f with f = 1 / tan(fov_y / 2), must
        # be finite in float32: fov_y = 5e-324 made tan 0 (ZeroDivisionError at render time).
        # Without a fixed aspect the image's is used, w / h >= 1 / MAX_IMAGE_SIDE: fov_y must
        # then be at least 5.5e-33 degrees.
        half = math.radians(fov) / 2.0
        f = 1.0 / math.tan(half) if half > 0.0 else math.inf
        if aspect_f is not None:
            widest, by = 1.0 / aspect_f, f"aspect {aspect_f!r}"
        elif self._width is not None and self._height is not None:
            widest, by = self._height / self._width, f"the aspect of width x height {self._width}x{self._height}"
        else:
            widest, by = float(_core.MAX_IMAGE_SIDE), f"any image aspect down to 1/{_core.MAX_IMAGE_SIDE}"
        if not (_float32_finite(f) and _float32_finite(f * max(widest, 1.0))):
            if _float32_finite(f) and aspect_f is not None:
                raise ValueError(f"aspect {aspect!r} is too small for fov_y {fov_y!r}: the projection's "
                                 f"x scale (f / aspect = {f / aspect_f:.3g}) is not finite in float32")
            least = math.degrees(2.0 * math.atan(max(widest, 1.0) / FLOAT32_MAX))
            raise ValueError(f"fov_y must be large enough for a finite projection with {by} "
                             f"(at least {least:.3g} degrees), got {fov_y!r}")
        if 0.1 <= fov < 3.2:  # (below 0.1 degrees: a deliberate telephoto, not radians)
            warnings.warn(f"fov_y is in degrees, got {fov_y!r}: did you pass radians (as pyrender's "
                          f"yfov)? Then use fov_y=math.degrees(yfov) = {math.degrees(fov):.4g}",
                          UserWarning, stacklevel=2)
        self._fov_y = fov
        self._aspect = aspect_f

    @property
    def fov_y(self) -> float:
        """Vertical field of view in degrees."""
        return self._fov_y

    @property
    def aspect(self) -> float | None:
        """Fixed width / height ratio, or None to follow the rendered image."""
        return self._aspect

    def projection_matrix(self, width: int | None = None, height: int | None = None) -> npt.NDArray[np.float64]:
        """The (4, 4) float64 view-to-clip matrix (OpenGL) for a ``width`` x ``height`` image.

        Parameters
        ----------
        width, height : int, optional
            The image size; None: the camera's own (needed unless ``aspect`` is fixed).

        Returns
        -------
        ndarray, shape (4, 4), float64
        """
        w, h = self._render_size(width, height)
        aspect = self._aspect if self._aspect is not None else w / h
        f = 1.0 / math.tan(math.radians(self._fov_y) / 2.0)
        proj = np.zeros((4, 4))
        proj[0, 0] = f / aspect
        proj[1, 1] = f
        self._depth_rows(proj)
        return proj

    # the projection depends only on construction-time parameters: cached per image size
    _fixed_projection = projection_matrix


class OrthographicCamera(Camera):
    """A parallel projection (pyrender's meaning of xmag / ymag).

    The depth output is still the distance along the viewing axis (-z_view).

    Parameters
    ----------
    xmag, ymag : float, optional
        Half-width and half-height of the view volume in scene units (> 0, and 1 / xmag finite in
        float32; default 1).
    width, height : int, optional
        Image size in pixels (informational; None if not fixed).
    near, far : float, optional
        Clipping distances along the viewing axis in scene units, 0 < near < far (defaults 0.05 and
        100).

    Raises
    ------
    ValueError
        For a value outside those ranges, naming it.
    """

    orthographic = True

    def __init__(self, xmag: float = 1.0, ymag: float = 1.0, width: int | None = None,
                 height: int | None = None, near: float = 0.05, far: float = 100.0) -> None:
        super().__init__(near, far, width, height)
        self._xmag = positive_real(xmag, "xmag")
        self._ymag = positive_real(ymag, "ymag")
        # The projection scales by 1 / xmag and 1 / ymag, in float32 in the core: a denormal
        # xmag (5e-324) was refused only at render time, as "projection matrix is not finite".
        for name, mag in (("xmag", self._xmag), ("ymag", self._ymag)):
            if not _float32_finite(1.0 / mag):
                raise ValueError(f"{name} must be at least {1.0 / FLOAT32_MAX:.3g} (1 / {name} finite "
                                 f"in float32), got {mag!r}")

    @property
    def xmag(self) -> float:
        """Half-width of the view volume in scene units."""
        return self._xmag

    @property
    def ymag(self) -> float:
        """Half-height of the view volume in scene units."""
        return self._ymag

    def projection_matrix(self, width: int | None = None, height: int | None = None) -> npt.NDArray[np.float64]:
        """The (4, 4) float64 view-to-clip matrix (OpenGL); the image size does not enter it.

        Parameters
        ----------
        width, height : int, optional
            Checked, not used (xmag and ymag fix the extent).

        Returns
        -------
        ndarray, shape (4, 4), float64
        """
        # The image size does not enter the matrix (xmag / ymag fix the extent); still validate it.
        if width is not None:
            _image_side(width, "width", optional=False)
        if height is not None:
            _image_side(height, "height", optional=False)
        n, f = self._near, self._far
        proj = np.zeros((4, 4))
        proj[0, 0] = 1.0 / self._xmag
        proj[1, 1] = 1.0 / self._ymag
        proj[2, 2] = -2.0 / (f - n)
        proj[2, 3] = -(f + n) / (f - n)
        proj[3, 3] = 1.0
        return proj

    # the projection depends only on construction-time parameters: cached per image size
    _fixed_projection = projection_matrix


class IntrinsicsCamera(Camera):
    """A pinhole camera from a calibration matrix K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]].

    Parameters
    ----------
    fx, fy : float
        Focal lengths in pixels (> 0).
    cx, cy : float
        Principal point in pixels.
    width, height : int
        The image size K was calibrated for (required, pixels).
    near, far : float, optional
        Clipping distances along the viewing axis in scene units, 0 < near < far (defaults 0.05 and
        100).
    convention : str, optional
        "opencv" (default): ``pose`` axes are x right, y down, z forward, and K follows OpenCV:
        pixel (row i, col j) has its centre at (u, v) = (j, i), so a point that
        ``cv2.projectPoints`` maps to (u, v) lands in pixel (round(v), round(u)). "opengl": exactly
        pyrender's IntrinsicsCamera: ``pose`` in OpenGL axes, and (cx, cy) measured from the
        image's top-left corner (pixel centres at j + 0.5, i + 0.5).
    dist : array_like, optional
        OpenCV distortion coefficients, as for ``from_opencv``; None: an ideal pinhole.
    oversample : int, optional
        In [1, 16] (default 2): with ``dist``, how much finer than the output the ideal view is
        sampled.

    Raises
    ------
    ValueError
        For a value outside those ranges, naming it.
    """

    def __init__(self, fx: float, fy: float, cx: float, cy: float, width: int, height: int,
                 near: float = 0.05, far: float = 100.0, convention: str = "opencv",
                 dist: npt.ArrayLike | None = None, oversample: int = 2) -> None:
        choice(convention, "convention", ("opencv", "opengl"))
        self._dist = check_dist(dist)
        self._oversample = integer(oversample, "oversample")
        if not 1 <= self._oversample <= 16:
            raise ValueError(f"oversample must be an int in [1, 16], got {oversample!r}")
        w = _image_side(width, "width", optional=False)
        h = _image_side(height, "height", optional=False)
        super().__init__(near, far, w, h)
        self._convention = convention
        self._fx = positive_real(fx, "fx")
        self._fy = positive_real(fy, "fy")
        self._cx = finite_real(cx, "cx")
        self._cy = finite_real(cy, "cy")
        # The entries projection_matrix makes of them must be finite in float32 (see there).
        half = 0.5 if convention == "opencv" else 0.0
        for name, term in (("fx", 2.0 * self._fx / w), ("fy", 2.0 * self._fy / h),
                           ("cx", 1.0 - 2.0 * (self._cx + half) / w),
                           ("cy", 2.0 * (self._cy + half) / h - 1.0)):
            if not _float32_finite(term):
                raise ValueError(f"{name} is too large for a {w}x{h} image: its projection term "
                                 f"{term:.3g} is not finite in float32")

    @property
    def fx(self) -> float:
        """Focal length along x, pixels."""
        return self._fx

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without the rays a distorted render cached (rebuilt on use)."""
        state = self.__dict__.copy()
        state.pop("_rays_cache", None)
        return state

    @property
    def dist(self) -> npt.NDArray[np.float64] | None:
        """OpenCV distortion coefficients (k1, k2, p1, p2, k3[, k4, k5, k6[, s1, s2, s3, s4]]), as
        few as hold every non-zero one (at least five), or None: an ideal pinhole."""
        if self._dist is None:
            return None
        n = 5 if not self._dist[5:].any() else 8 if not self._dist[8:].any() else 12
        return self._dist[:n].copy()

    @property
    def dist_coefficients(self) -> npt.NDArray[np.float64] | None:
        """All 12 coefficients (read-only), or None without distortion."""
        return self._dist

    @property
    def oversample(self) -> int:
        """With ``dist``: how many times finer than the output the ideal view a render samples is.

        A silhouette is placed to 0.71 / oversample pixels (docs/conventions.md, "Lens distortion").
        """
        return self._oversample

    def project(self, points: npt.ArrayLike, width: int | None = None,
                height: int | None = None) -> npt.NDArray[np.float64]:
        """OpenCV pixel coordinates (u, v) of world points, lens distortion included.

        Equal to ``cv2.projectPoints`` with ``to_opencv()``'s K, R, t, dist.

        Parameters
        ----------
        points : array_like, shape (n, 3)
            World points.
        width, height : int, optional
            Checked against the calibrated size (K is for one image size).

        Returns
        -------
        ndarray, shape (n, 2), float64
            Points on or behind the camera plane give NaN.

        Raises
        ------
        ValueError
            For points of another shape or another image size.
        """
        if self._dist is None:
            return super().project(points, width, height)
        pts = real_array(points, "points")
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"points must have shape (n, 3), got {pts.shape}")
        self.projection_matrix(width, height)  # checks the size: K is for one image size
        k, rot, t, _ = self.to_opencv()
        cam = pts @ rot.T + t
        with np.errstate(divide="ignore", invalid="ignore"):
            xd, yd = distort(cam[:, 0] / cam[:, 2], cam[:, 1] / cam[:, 2], self._dist)
        uv = np.c_[k[0, 0] * xd + k[0, 2], k[1, 1] * yd + k[1, 2]]
        uv[~(cam[:, 2] > 0)] = np.nan
        return uv

    def unproject(self, depth: npt.ArrayLike, space: str = "world") -> npt.NDArray[np.float64]:
        """As ``Camera.unproject``, each pixel's point on its own (distorted) ray.

        OpenCV's model inverted at the pixel centre (``softrast.lens.undistort``).

        Parameters
        ----------
        depth : array_like, shape (h, w)
            The renderer's depth (0 = background).
        space : str, optional
            "world" (default) or "camera", as for ``Camera.unproject``.

        Returns
        -------
        ndarray, shape (h, w, 3), float64
            Background pixels and pixels no ray reaches give 0.
        """
        if self._dist is None:
            return super().unproject(depth, space)
        choice(space, "space", ("world", "camera"))
        d = _depth_image(depth)
        h, w = d.shape
        self.projection_matrix(w, h)  # checks the size: K is for one image size
        k, rot, t, _ = self.to_opencv()
        j, i = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        x, y, valid = undistort((j - k[0, 2]) / k[0, 0], (i - k[1, 2]) / k[1, 1], self._dist)
        cv = np.stack([np.where(valid, x, 0.0) * d, np.where(valid, y, 0.0) * d, d], axis=-1)
        cv[(d == 0) | ~valid] = 0.0
        if space == "camera":
            return cv if self._convention == "opencv" else cv * np.array([1.0, -1.0, -1.0])
        world = (cv - t) @ rot  # R^T (x - t)
        world[(d == 0) | ~valid] = 0.0
        return world

    @property
    def fy(self) -> float:
        """Focal length along y, pixels."""
        return self._fy

    @property
    def cx(self) -> float:
        """Principal point x, pixels (in this camera's ``convention``)."""
        return self._cx

    @property
    def cy(self) -> float:
        """Principal point y, pixels (in this camera's ``convention``)."""
        return self._cy

    @classmethod
    def from_opencv(cls, K: npt.ArrayLike, rvec_or_R: npt.ArrayLike, tvec: npt.ArrayLike,  # noqa: N803
                    width: int, height: int, dist: npt.ArrayLike | None = None,
                    near: float = 0.05, far: float = 100.0, oversample: int = 2) -> "IntrinsicsCamera":
        """A camera from an OpenCV calibration: ``x_cam = R @ X_world + t``, pixel ``K @ x_cam``.

        Parameters
        ----------
        K : array_like, shape (3, 3)
            [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] in OpenCV's pixel coordinates (pixel (row i, col j)
            has its centre at (u, v) = (j, i)); zero skew.
        rvec_or_R : array_like, shape (3,) or (3, 3)
            A Rodrigues rotation vector (as ``cv2.solvePnP`` / ``cv2.calibrateCamera`` return it) or a
            rotation matrix, world-to-camera.
        tvec : array_like, shape (3,)
            World-to-camera translation (OpenCV's ``tvec``).
        width, height : int
            The image size K was calibrated for, pixels.
        dist : array_like, optional
            OpenCV distortion coefficients (k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3, s4[, tauX,
            tauY]]]]), or None; renders see through the distorted lens (docs/conventions.md, "Lens
            distortion"; a tilted sensor, tauX or tauY non-zero, is refused).
        near, far : float, optional
            Clipping distances along the viewing axis (scene units).
        oversample : int, optional
            With ``dist``, how much finer than the output the ideal view is sampled (default 2).

        Returns
        -------
        IntrinsicsCamera
            ``convention="opencv"``, whose pose is the inverse of [R | t]: a point
            ``cv2.projectPoints(X, rvec, tvec, K, dist)`` maps to (u, v) is drawn in pixel
            (round(v), round(u)).

        Raises
        ------
        ValueError
            For a K with skew or not finite, a rotation that is not proper, a tvec that is not 3 finite
            numbers, or a bad camera argument.
        """
        k = real_array(K, "K")
        if k.shape != (3, 3):
            raise ValueError(f"K must be a (3, 3) matrix, got shape {k.shape}")
        if not np.isfinite(k).all():
            raise ValueError("K must be finite")
        if k[0, 1] != 0.0 or k[1, 0] != 0.0 or k[2, 0] != 0.0 or k[2, 1] != 0.0 or k[2, 2] != 1.0:
            raise ValueError("K must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew), got "
                             f"{k.tolist()}")
        rot = _rotation(rvec_or_R)
        t = real_array(tvec, "tvec").reshape(-1)
        if t.shape != (3,) or not np.isfinite(t).all():
            raise ValueError(f"tvec must be 3 finite numbers, got {np.asarray(tvec).tolist()}")
        cam = cls(k[0, 0], k[1, 1], k[0, 2], k[1, 2], width, height, near=near, far=far,
                  convention="opencv", dist=dist, oversample=oversample)
        pose = np.eye(4)
        pose[:3, :3] = rot.T
        pose[:3, 3] = -rot.T @ t
        cam.pose = pose
        return cam

    def to_opencv(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64],
                                 npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """The camera as OpenCV sees it: ``x_cam = R @ X_world + t``, pixels ``K @ x_cam``.

        Works for either ``convention``: an "opengl" camera's principal point is shifted by half a
        pixel to OpenCV's pixel-centre coordinates and its pose's y and z axes flipped, so the same
        world point lands on the same pixel.

        Returns
        -------
        K : ndarray, shape (3, 3), float64
        R : ndarray, shape (3, 3), float64
            ``cv2.Rodrigues(R)[0]`` gives an ``rvec``.
        t : ndarray, shape (3,), float64
        dist : ndarray, shape (5,) (or (8,), (12,)), float64
            The camera's (``dist``), zeros for an ideal pinhole.
        """
        half = 0.0 if self._convention == "opencv" else 0.5
        k = np.array([[self._fx, 0.0, self._cx - half], [0.0, self._fy, self._cy - half], [0.0, 0.0, 1.0]])
        view_cv = _GL_FROM_CV @ self.view_matrix()  # world -> OpenCV camera axes
        dist = self.dist
        return k, view_cv[:3, :3].copy(), view_cv[:3, 3].copy(), np.zeros(5) if dist is None else dist

    def projection_matrix(self, width: int | None = None, height: int | None = None) -> npt.NDArray[np.float64]:
        """The (4, 4) float64 view-to-clip matrix (OpenGL).

        Parameters
        ----------
        width, height : int, optional
            Must be the calibrated size (None: it).

        Returns
        -------
        ndarray, shape (4, 4), float64

        Raises
        ------
        ValueError
            For another image size: K is in pixels of one specific image size.
        """
        w, h = self._render_size(width, height)
        if (w, h) != (self._width, self._height):  # K is in pixels of one specific image size
            raise ValueError(
                f"width x height {w}x{h} differs from the {self._width}x{self._height} image "
                "this IntrinsicsCamera was calibrated for"
            )
        # OpenCV puts pixel centres at integer (u, v); window space at +0.5 => shift the principal point.
        half = 0.5 if self._convention == "opencv" else 0.0
        proj = np.zeros((4, 4))
        proj[0, 0] = 2.0 * self._fx / w
        proj[1, 1] = 2.0 * self._fy / h
        proj[0, 2] = 1.0 - 2.0 * (self._cx + half) / w
        proj[1, 2] = 2.0 * (self._cy + half) / h - 1.0
        self._depth_rows(proj)
        return proj

    # the projection depends only on construction-time parameters: cached per image size
    _fixed_projection = projection_matrix
