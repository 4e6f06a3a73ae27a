"""The camera base class: a pose (camera-to-world) plus a projection to OpenGL clip space. The
cameras themselves are in ``softrast.camera``.

The conventions shared with the C++ core (``_core.pyi``): view, clip, NDC and window spaces,
row 0 at the top, pixel centres at (j + 0.5, i + 0.5), the pose's axes for ``convention``
"opengl" and "opencv", are in docs/conventions.md, "Spaces" and "Pixels and images".
"""
from __future__ import annotations

import abc
import math
from typing import Any

import numpy as np
import numpy.typing as npt

from ._checks import FLOAT32_MAX, affine_pose, choice, finite_real, image_side, positive_real, real_array

__all__ = ["Camera"]


_ORTHONORMAL_TOL = 1e-4  # float32-sourced rotations are orthonormal to ~1e-7; 1e-4 catches scale/shear


_GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])  # flips y and z: OpenCV camera axes <-> OpenGL view axes


def _image_side(value: Any, name: str, optional: bool) -> int | None:
    if value is None:
        if optional:
            return None
        raise ValueError(f"{name} is required")
    return image_side(value, name)


def _vec3(value: Any, name: str) -> npt.NDArray[np.float64]:
    v = real_array(value, name)
    if v.shape != (3,):
        raise ValueError(f"{name} must be 3 numbers, got shape {v.shape}")
    if not np.isfinite(v).all():
        raise ValueError(f"{name} must be finite, got {v.tolist()}")
    return v


def _float32_finite(x: float) -> bool:
    """``x`` stays finite in the core, which rounds projection matrices to float32."""
    return abs(x) <= FLOAT32_MAX  # False for NaN too


def _check_pose(pose: Any) -> npt.NDArray[np.float64]:
    m = affine_pose(pose)
    r = m[:3, :3]
    # Entries of a rotation are in [-1, 1]: testing that first keeps r.T @ r from overflowing
    # (a 1e200 scale raised NumPy's overflow RuntimeWarning, an error under warnings-as-errors).
    if np.abs(r).max() > 1.0 + _ORTHONORMAL_TOL or np.abs(r.T @ r - np.eye(3)).max() > _ORTHONORMAL_TOL:
        raise ValueError("pose rotation part (pose[:3, :3]) must be orthonormal (no scale or shear)")
    if np.linalg.det(r) < 0.0:  # a mirror would silently swap front and back faces
        raise ValueError("pose rotation part must be a proper rotation (determinant +1), not a reflection")
    return m


def _rigid_inverse(m: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Inverse of a rigid transform: [R t]^-1 = [R^T  -R^T t] (exact, unlike np.linalg.inv)."""
    inv = np.eye(4)
    inv[:3, :3] = m[:3, :3].T
    inv[:3, 3] = -m[:3, :3].T @ m[:3, 3]
    return inv


def _depth_image(depth: Any) -> npt.NDArray[np.float64]:
    """``unproject``'s depth argument, checked: a non-empty (h, w) image, finite and >= 0."""
    d = real_array(depth, "depth")
    if d.ndim != 2 or d.size == 0:
        raise ValueError(f"depth must be a non-empty (h, w) image, got shape {d.shape}")
    if not (np.isfinite(d).all() and (d >= 0).all()):
        raise ValueError("depth must be finite and >= 0 (0 = background)")
    return d


def _rotation(value: Any) -> npt.NDArray[np.float64]:
    """A (3, 3) rotation from a Rodrigues vector (3 numbers) or a rotation matrix (checked)."""
    arr = real_array(value, "rvec_or_R")
    if not np.isfinite(arr).all():
        raise ValueError("rvec_or_R must be finite")
    if arr.size == 3:
        r = arr.reshape(3)
        theta = float(np.linalg.norm(r))
        if theta == 0.0:
            return np.eye(3)
        k = r / theta
        kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        # Rodrigues' formula, as cv2.Rodrigues: R = cos I + (1 - cos) k k^T + sin [k]x
        return math.cos(theta) * np.eye(3) + (1.0 - math.cos(theta)) * np.outer(k, k) + math.sin(theta) * kx
    if arr.shape != (3, 3):
        raise ValueError(f"rvec_or_R must be a rotation vector (3 numbers) or a (3, 3) matrix, got shape {arr.shape}")
    if np.abs(arr.T @ arr - np.eye(3)).max() > _ORTHONORMAL_TOL or np.linalg.det(arr) < 0.0:
        raise ValueError("rvec_or_R: a (3, 3) R must be a proper rotation (orthonormal, determinant +1)")
    return arr


class Camera(abc.ABC):
    """Base class of the cameras: near/far planes, pose, look_at, the view matrix, OpenCV's K.

    Subclasses implement ``projection_matrix(width, height)``.

    Parameters
    ----------
    near, far : float, optional
        Clipping distances along the viewing axis in scene units, 0 < near < far (defaults 0.05
        and 100), giving a projection finite in float32.
    width, height : int, optional
        Image size in pixels fixed by the camera, or None.

    Raises
    ------
    ValueError
        For a bad near / far pair or image size, naming it.
    """

    orthographic: bool = False  # True => parallel projection (clip w = 1)
    _convention: str = "opengl"

    def __init__(self, near: float = 0.05, far: float = 100.0,
                 width: int | None = None, height: int | None = None) -> None:
        near_f = positive_real(near, "near")
        far_f = finite_real(far, "far")
        if far_f <= near_f:
            raise ValueError(f"far must be greater than near ({near_f}), got {far_f}")
        # The projection's depth rows (see _depth_rows and OrthographicCamera) must be finite in
        # float32, as the core uses them: a near/far pair closer than that (1e30 and 1e30 + 1e15:
        # 2 f n / (f - n) = 2e45) or beyond float32 (near 1e39) was refused only at render time,
        # by a "projection matrix is not finite" that named neither.
        n, f = near_f, far_f
        if self.orthographic:
            rows = (2.0 / (f - n), (f + n) / (f - n))
        else:
            rows = ((f + n) / (f - n), 2.0 * f * n / (f - n))
        if not all(_float32_finite(x) for x in rows):
            raise ValueError(f"near and far ({near_f!r}, {far_f!r}) give a projection that is not finite "
                             f"in float32 (depth terms {rows[0]:.3g}, {rows[1]:.3g}): far must differ "
                             "more from near, and both stay below 1.7e38")
        self._near, self._far = near_f, far_f
        self._width = _image_side(width, "width", optional=True)
        self._height = _image_side(height, "height", optional=True)
        self._pose = _check_pose(np.eye(4))
        self._view_of: tuple[Any, Any] = (None, None)  # (pose, its view matrix): see _render_matrices
        self._projections: dict[tuple[int, int], npt.NDArray[np.float64]] = {}

    @property
    def near(self) -> float:
        """Distance to the near clipping plane along the viewing axis, scene units (> 0)."""
        return self._near

    @property
    def far(self) -> float:
        """Distance to the far clipping plane along the viewing axis, scene units (> near)."""
        return self._far

    @property
    def width(self) -> int | None:
        """Image width in pixels fixed by the camera, or None."""
        return self._width

    @property
    def height(self) -> int | None:
        """Image height in pixels fixed by the camera, or None."""
        return self._height

    @property
    def convention(self) -> str:
        """Axes of ``pose``: "opengl" (x right, y up, looks down -z) or "opencv" (y down, looks down +z)."""
        return self._convention

    @property
    def pose(self) -> npt.NDArray[np.float64]:
        """(4, 4) float64 camera-to-world rigid transform (read-only); axes per ``convention``.

        Settable: a new pose must be rigid (orthonormal rotation, determinant +1, last row
        [0, 0, 0, 1]), else ValueError; it is stored as a new read-only array.
        """
        return self._pose

    @pose.setter
    def pose(self, value: npt.ArrayLike) -> None:
        self._pose = _check_pose(value)

    def look_at(self, eye: npt.ArrayLike, target: npt.ArrayLike,
                up: npt.ArrayLike = (0.0, 1.0, 0.0)) -> "Camera":
        """Place the camera at ``eye`` looking at ``target``, ``up`` pointing up in the image.

        Parameters
        ----------
        eye, target, up : array_like, shape (3,)
            World-space points (``up`` a direction, default +y).

        Returns
        -------
        Camera
            ``self``, its ``pose`` set.

        Raises
        ------
        ValueError
            If eye and target coincide, ``up`` is zero or parallel to the view direction, or the
            values overflow float64.
        """
        eye_w, target_w, up_w = _vec3(eye, "eye"), _vec3(target, "target"), _vec3(up, "up")
        with np.errstate(over="ignore", invalid="ignore"):  # checked below, by name
            back = eye_w - target_w  # OpenGL camera +z points away from what it looks at
            dist = np.linalg.norm(back)
            up_norm = np.linalg.norm(up_w)
        if not (np.isfinite(dist) and np.isfinite(up_norm)):
            raise ValueError("eye, target and up must be within float64's range: "
                             "target - eye or the length of up overflows")
        if dist == 0.0 or dist <= 1e-12 * max(np.abs(eye_w).max(), np.abs(target_w).max()):
            raise ValueError("eye and target must be different points")
        z_axis = back / dist
        if up_norm == 0.0:
            raise ValueError("up must be a non-zero vector")
        x_axis = np.cross(up_w / up_norm, z_axis)
        sin_angle = np.linalg.norm(x_axis)
        if sin_angle < 1e-6:  # up (anti)parallel to the view direction => image roll undefined
            raise ValueError("up must not be parallel to the view direction (target - eye)")
        x_axis /= sin_angle
        y_axis = np.cross(z_axis, x_axis)
        pose_gl = np.eye(4)
        pose_gl[:3, 0], pose_gl[:3, 1], pose_gl[:3, 2], pose_gl[:3, 3] = x_axis, y_axis, z_axis, eye_w
        # OpenCV axes are OpenGL's with y and z flipped: z toward the target, y down.
        self.pose = pose_gl @ _GL_FROM_CV if self._convention == "opencv" else pose_gl
        return self

    def view_matrix(self) -> npt.NDArray[np.float64]:
        """The (4, 4) float64 world-to-view matrix.

        View space is OpenGL's (x right, y up, looking down -z), whatever the ``convention``.

        Returns
        -------
        ndarray, shape (4, 4), float64
        """
        view = _rigid_inverse(self._pose)
        return _GL_FROM_CV @ view if self._convention == "opencv" else view

    @abc.abstractmethod
    def projection_matrix(self, width: int | None = None, height: int | None = None) -> npt.NDArray[np.float64]:
        """The (4, 4) float64 view-to-clip matrix (OpenGL) for a ``width`` x ``height`` pixel image.

        Parameters
        ----------
        width, height : int, optional
            The image size; None: the camera's own.

        Returns
        -------
        ndarray, shape (4, 4), float64
        """

    def _render_matrices(self, width: int, height: int) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """(view, projection) for a render, read-only, cached: a render of a batch reuses them.

        The view matrix is cached per pose (poses are read-only: a new pose is a new array); the
        projection per image size, for softrast's cameras, whose parameters are fixed at
        construction (their ``_fixed_projection`` is their own ``projection_matrix``). A
        subclass that defines its own projection_matrix is asked every time.
        """
        pose, view = self._view_of
        if pose is not self._pose:
            pose, view = self._pose, self.view_matrix()
            view.setflags(write=False)
            self._view_of = (pose, view)
        if type(self).projection_matrix is not getattr(type(self), "_fixed_projection", None):
            return view, self.projection_matrix(width, height)
        proj = self._projections.get((width, height))
        if proj is None:
            if len(self._projections) >= 8:  # a camera reused at many sizes: keep the cache small
                self._projections.clear()
            proj = self.projection_matrix(width, height)
            proj.setflags(write=False)
            self._projections[(width, height)] = proj
        return view, proj

    # -- the camera as OpenCV sees it: K, projecting points, unprojecting depth ------------------
    # Pixel coordinates follow OpenCV: the centre of pixel (row i, col j) is at (u, v) = (j, i).

    def intrinsics(self, width: int | None = None, height: int | None = None) -> npt.NDArray[np.float64]:
        """The pinhole matrix K in OpenCV's convention for a ``width`` x ``height`` image.

        K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]: a point at (x, y, z) in OpenCV camera axes (x
        right, y down, z forward) is seen at pixel (u, v) = (fx x / z + cx, fy y / z + cy).

        Parameters
        ----------
        width, height : int, optional
            Default: the camera's own size.

        Returns
        -------
        ndarray, shape (3, 3), float64

        Raises
        ------
        ValueError
            For an orthographic camera (it has none), or without an image size.
        """
        if self.orthographic:
            raise ValueError("an orthographic camera has no pinhole matrix K")
        w, h = self._render_size(width, height)
        p = self.projection_matrix(w, h)
        return np.array([[p[0, 0] * w / 2, 0.0, (1.0 - p[0, 2]) * w / 2 - 0.5],
                         [0.0, p[1, 1] * h / 2, (1.0 + p[1, 2]) * h / 2 - 0.5],
                         [0.0, 0.0, 1.0]])

    @property
    def K(self) -> npt.NDArray[np.float64]:  # noqa: N802 (the standard name)
        """``intrinsics()`` for the camera's own image size (width and height must be fixed)."""
        return self.intrinsics()

    def project(self, points: npt.ArrayLike, width: int | None = None,
                height: int | None = None) -> npt.NDArray[np.float64]:
        """OpenCV pixel coordinates (u, v) of world points, as the renderer projects them.

        The centre of pixel (row i, col j) is (j, i).

        Parameters
        ----------
        points : array_like, shape (n, 3)
            World points.
        width, height : int, optional
            Default: the camera's own size.

        Returns
        -------
        ndarray, shape (n, 2), float64
            Points on or behind the camera plane of a perspective camera give NaN.

        Raises
        ------
        ValueError
            For points of another shape, or without an image size.
        """
        pts = real_array(points, "points")
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"points must have shape (n, 3), got {pts.shape}")
        w, h = self._render_size(width, height)
        clip = np.c_[pts, np.ones(len(pts))] @ (self.projection_matrix(w, h) @ self.view_matrix()).T
        with np.errstate(divide="ignore", invalid="ignore"):
            ndc = clip[:, :2] / clip[:, 3:]
        uv = np.c_[(ndc[:, 0] + 1.0) * w / 2 - 0.5, (1.0 - ndc[:, 1]) * h / 2 - 0.5]
        if not self.orthographic:
            uv[clip[:, 3] <= 0] = np.nan
        return uv

    def unproject(self, depth: npt.ArrayLike, space: str = "world") -> npt.NDArray[np.float64]:
        """Points from a depth image: each pixel's centre pushed to its depth along its ray.

        Parameters
        ----------
        depth : array_like, shape (h, w)
            The renderer's depth: distance along the viewing axis, finite and >= 0; 0 = background,
            which gives 0.
        space : str, optional
            "world" (default), or "camera": the axes of ``pose`` (so that world = pose @ camera point):
            OpenGL's (x right, y up, z backward, so z = -depth) for ``convention="opengl"``, OpenCV's
            (x right, y down, z forward, z = depth) for "opencv".

        Returns
        -------
        ndarray, shape (h, w, 3), float64

        Raises
        ------
        ValueError
            For an empty or non-finite depth, a negative one, or another ``space``.
        """
        choice(space, "space", ("world", "camera"))
        d = _depth_image(depth)
        h, w = d.shape
        p = self.projection_matrix(*self._render_size(w, h))
        j, i = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        x_ndc, y_ndc = (j + 0.5) * 2.0 / w - 1.0, 1.0 - (i + 0.5) * 2.0 / h
        if self.orthographic:  # x_ndc = P00 x + P03, y_ndc = P11 y + P13
            x, y = (x_ndc - p[0, 3]) / p[0, 0], (y_ndc - p[1, 3]) / p[1, 1]
        else:  # x_ndc = -(P00 x + P02 z) / z with z = -depth
            x, y = (x_ndc + p[0, 2]) * d / p[0, 0], (y_ndc + p[1, 2]) * d / p[1, 1]
        gl = np.stack([x, y, -d], axis=-1)  # OpenGL view space
        gl[d == 0] = 0.0
        if space == "camera":
            return gl * np.array([1.0, -1.0, -1.0]) if self._convention == "opencv" else gl
        view_to_world = _rigid_inverse(self.view_matrix())
        world = gl @ view_to_world[:3, :3].T + view_to_world[:3, 3]
        world[d == 0] = 0.0
        return world

    def _render_size(self, width: Any, height: Any) -> tuple[int, int]:
        """The image size to project for: the arguments, else the camera's own width/height."""
        w = self._width if width is None else _image_side(width, "width", optional=False)
        h = self._height if height is None else _image_side(height, "height", optional=False)
        if w is None or h is None:
            raise ValueError("width and height are required: this camera does not fix an image size")
        return int(w), int(h)

    def _depth_rows(self, proj: npt.NDArray[np.float64]) -> None:
        """gluPerspective rows 2, 3: z_ndc = -1 at -near, +1 at -far; w_clip = -z_view."""
        n, f = self._near, self._far
        proj[2, 2] = -(f + n) / (f - n)
        proj[2, 3] = -2.0 * f * n / (f - n)
        proj[3, 2] = -1.0
