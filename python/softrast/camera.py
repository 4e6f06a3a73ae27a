"""Cameras: a pose (camera-to-world) plus a projection to OpenGL clip space.

Conventions (shared with the C++ core, see ``_core.pyi``):

* ``view_matrix()`` is world-to-view in OpenGL's view space: x right, y up, the camera looks
  down -z. ``projection_matrix(w, h)`` maps view space to clip space; NDC = clip.xyz / clip.w.
* Window space: x_win = (ndc_x + 1) / 2 * W, y_win = (1 - ndc_y) / 2 * H; row 0 is the top of
  the image and the centre of pixel (row i, col j) is at (j + 0.5, i + 0.5).
* For a world point X: clip = P @ view @ [X, 1].
* ``pose`` is a (4, 4) float64 rigid camera-to-world transform whose axes follow
  ``convention``: "opengl" (x right, y up, looking down -z) or "opencv" (x right, y down,
  looking down +z; only ``IntrinsicsCamera`` offers it).
"""
from __future__ import annotations

import abc
import math
import operator
from typing import Any

import numpy as np
import numpy.typing as npt

from ._checks import affine_pose

__all__ = ["Camera", "PerspectiveCamera", "OrthographicCamera", "IntrinsicsCamera"]

_ORTHONORMAL_TOL = 1e-4  # float32-sourced rotations are orthonormal to ~1e-7; 1e-4 catches scale/shear
_GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])  # flips y and z: OpenCV camera axes <-> OpenGL view axes


def _positive_finite(value: Any, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a number, got {type(value).__name__}") from exc
    if not math.isfinite(v) or v <= 0.0:
        raise ValueError(f"{name} must be positive and finite, got {value!r}")
    return v


def _finite(value: Any, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a number, got {type(value).__name__}") from exc
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return v


def _image_side(value: Any, name: str, optional: bool) -> int | None:
    if value is None:
        if optional:
            return None
        raise ValueError(f"{name} is required")
    if isinstance(value, bool):
        raise TypeError(f"{name} must be an int, got bool")
    try:
        v = operator.index(value)
    except TypeError as exc:
        raise TypeError(f"{name} must be an int, got {type(value).__name__}") from exc
    if v <= 0:
        raise ValueError(f"{name} must be a positive number of pixels, got {v}")
    return v


def _vec3(value: Any, name: str) -> npt.NDArray[np.float64]:
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be 3 numbers, got {value!r}") from exc
    if v.shape != (3,):
        raise ValueError(f"{name} must be 3 numbers, got shape {v.shape}")
    if not np.isfinite(v).all():
        raise ValueError(f"{name} must be finite, got {v.tolist()}")
    return v


def _check_pose(pose: Any) -> npt.NDArray[np.float64]:
    m = affine_pose(pose)
    r = m[:3, :3]
    if np.abs(r.T @ r - np.eye(3)).max() > _ORTHONORMAL_TOL:
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


class Camera(abc.ABC):
    """Base class: near/far planes, pose, look_at and the view matrix.

    Subclasses implement ``projection_matrix(width, height)``.
    """

    orthographic: bool = False  # True => parallel projection (clip w = 1)
    _convention: str = "opengl"

    def __init__(self, near: float = 0.05, far: float = 100.0,
                 width: int | None = None, height: int | None = None) -> None:
        near_f = _positive_finite(near, "near")
        far_f = _finite(far, "far")
        if far_f <= near_f:
            raise ValueError(f"far must be greater than near ({near_f}), got {far_f}")
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
        """(4, 4) float64 camera-to-world rigid transform (read-only copy); axes per ``convention``."""
        return self._pose

    @pose.setter
    def pose(self, value: npt.ArrayLike) -> None:
        self._pose = _check_pose(value)

    def look_at(self, eye: npt.ArrayLike, target: npt.ArrayLike,
                up: npt.ArrayLike = (0.0, 1.0, 0.0)) -> "Camera":
        """Place the camera at ``eye`` looking at ``target``, ``up`` pointing up in the image.

        eye, target, up : 3 world-space numbers. Sets ``pose`` and returns ``self``.
        """
        eye_w, target_w, up_w = _vec3(eye, "eye"), _vec3(target, "target"), _vec3(up, "up")
        back = eye_w - target_w  # OpenGL camera +z points away from what it looks at
        dist = np.linalg.norm(back)
        if dist == 0.0 or dist <= 1e-12 * max(np.abs(eye_w).max(), np.abs(target_w).max()):
            raise ValueError("eye and target must be different points")
        z_axis = back / dist
        up_norm = np.linalg.norm(up_w)
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
        """(4, 4) float64 world-to-view; view space is OpenGL's (x right, y up, looking down -z)."""
        view = _rigid_inverse(self._pose)
        return _GL_FROM_CV @ view if self._convention == "opencv" else view

    @abc.abstractmethod
    def projection_matrix(self, width: int | None = None, height: int | None = None) -> npt.NDArray[np.float64]:
        """(4, 4) float64 view-to-clip (OpenGL) for a ``width`` x ``height`` pixel image."""

    def _render_matrices(self, width: int, height: int) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """(view, projection) for a render, read-only, cached: a render of a batch reuses them.

        The view matrix is cached per pose (poses are read-only: a new pose is a new array); the
        projection per image size, for the cameras of this module, whose parameters are fixed
        at construction. A subclass that defines its own projection_matrix is asked every time.
        """
        pose, view = self._view_of
        if pose is not self._pose:
            pose, view = self._pose, self.view_matrix()
            view.setflags(write=False)
            self._view_of = (pose, view)
        if type(self).projection_matrix not in _FIXED_PROJECTIONS:
            return view, self.projection_matrix(width, height)
        proj = self._projections.get((width, height))
        if proj is None:
            if len(self._projections) >= 8:  # a camera reused at many sizes: keep the cache small
                self._projections.clear()
            proj = self.projection_matrix(width, height)
            proj.setflags(write=False)
            self._projections[(width, height)] = proj
        return view, proj

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


class PerspectiveCamera(Camera):
    """A pinhole camera with a vertical field of view (pyrender / gluPerspective).

    fov_y : vertical field of view in degrees, in (0, 180).
    aspect : width / height of the view volume; None => the aspect of the rendered image.
    width, height : optional image size in pixels (informational; None if not fixed).
    near, far : clipping distances in scene units, 0 < near < far.
    """

    def __init__(self, fov_y: float = 45.0, width: int | None = None, height: int | None = None,
                 near: float = 0.05, far: float = 100.0, aspect: float | None = None) -> None:
        super().__init__(near, far, width, height)
        fov = _finite(fov_y, "fov_y")
        if not 0.0 < fov < 180.0:
            raise ValueError(f"fov_y must be in (0, 180) degrees, got {fov_y!r}")
        self._fov_y = fov
        self._aspect = None if aspect is None else _positive_finite(aspect, "aspect")

    @property
    def fov_y(self) -> float:
        """Vertical field of view in degrees."""
        return self._fov_y

    @property
    def aspect(self) -> float | None:
        """Fixed width / height ratio, or None to follow the rendered image."""
        return self._aspect

    def projection_matrix(self, width: int | None = None, height: int | None = None) -> npt.NDArray[np.float64]:
        w, h = self._render_size(width, height)
        aspect = self._aspect if self._aspect is not None else w / h
        f = 1.0 / math.tan(math.radians(self._fov_y) / 2.0)
        proj = np.zeros((4, 4))
        proj[0, 0] = f / aspect
        proj[1, 1] = f
        self._depth_rows(proj)
        return proj


class OrthographicCamera(Camera):
    """A parallel projection (pyrender's meaning of xmag / ymag).

    xmag, ymag : half-width and half-height of the view volume in scene units (> 0).
    near, far : clipping distances along the viewing axis, 0 < near < far.
    Depth output is still the distance along the viewing axis (-z_view).
    """

    orthographic = True

    def __init__(self, xmag: float = 1.0, ymag: float = 1.0, width: int | None = None,
                 height: int | None = None, near: float = 0.05, far: float = 100.0) -> None:
        super().__init__(near, far, width, height)
        self._xmag = _positive_finite(xmag, "xmag")
        self._ymag = _positive_finite(ymag, "ymag")

    @property
    def xmag(self) -> float:
        return self._xmag

    @property
    def ymag(self) -> float:
        return self._ymag

    def projection_matrix(self, width: int | None = None, height: int | None = None) -> npt.NDArray[np.float64]:
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


class IntrinsicsCamera(Camera):
    """A pinhole camera from a calibration matrix K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]].

    fx, fy : focal lengths in pixels (> 0). cx, cy : principal point in pixels.
    width, height : the image size K was calibrated for (required, pixels).
    convention :
      "opencv" (default) -- ``pose`` axes are x right, y down, z forward, and K follows OpenCV:
          pixel (row i, col j) has its centre at (u, v) = (j, i), so a point that
          ``cv2.projectPoints`` maps to (u, v) lands in pixel (round(v), round(u)).
      "opengl" -- exactly pyrender's IntrinsicsCamera: ``pose`` in OpenGL axes, and (cx, cy)
          measured from the image's top-left corner (pixel centres at j + 0.5, i + 0.5).
    """

    def __init__(self, fx: float, fy: float, cx: float, cy: float, width: int, height: int,
                 near: float = 0.05, far: float = 100.0, convention: str = "opencv") -> None:
        if convention not in ("opencv", "opengl"):
            raise ValueError(f"convention must be 'opencv' or 'opengl', got {convention!r}")
        w = _image_side(width, "width", optional=False)
        h = _image_side(height, "height", optional=False)
        super().__init__(near, far, w, h)
        self._convention = convention
        self._fx = _positive_finite(fx, "fx")
        self._fy = _positive_finite(fy, "fy")
        self._cx = _finite(cx, "cx")
        self._cy = _finite(cy, "cy")

    @property
    def fx(self) -> float:
        return self._fx

    @property
    def fy(self) -> float:
        return self._fy

    @property
    def cx(self) -> float:
        return self._cx

    @property
    def cy(self) -> float:
        return self._cy

    @property
    def K(self) -> npt.NDArray[np.float64]:  # noqa: N802 (the standard name)
        """(3, 3) float64 calibration matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]."""
        return np.array([[self._fx, 0.0, self._cx], [0.0, self._fy, self._cy], [0.0, 0.0, 1.0]])

    def projection_matrix(self, width: int | None = None, height: int | None = None) -> npt.NDArray[np.float64]:
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


# Cameras whose projection depends only on construction-time parameters (cacheable per size).
_FIXED_PROJECTIONS = frozenset({PerspectiveCamera.projection_matrix, OrthographicCamera.projection_matrix,
                                IntrinsicsCamera.projection_matrix})
