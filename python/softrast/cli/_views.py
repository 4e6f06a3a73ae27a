"""What the ``render`` and ``batch`` subcommands set up besides the renderer: the default camera
framing a mesh (``frame_camera``), ``--poses`` and ``--intrinsics`` read and checked, the
memory a view holds, and ``batch``'s summary line."""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..camera import IntrinsicsCamera
from ..camera_base import _check_pose
from ..dataset import load_cameras
from ..limits import _human, get_memory_budget
from ._args import CliError

_FRAME_MARGIN = 1.1  # the bounding sphere fills ~90% of the narrower field of view
_VIEW_DIRECTION = np.array([0.0, 0.25, 1.0])  # default eye: in front of the mesh, a little above


def frame_camera(bounds: np.ndarray, fov_y: float, width: int, height: int,
                 eye: Sequence[float] | None = None, target: Sequence[float] | None = None
                 ) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Choose (eye, target, near, far) so the bounding sphere of ``bounds`` is in view.

    bounds : (2, 3) world-space AABB. fov_y : vertical field of view in degrees.
    Missing ``target`` => the bounds centre; missing ``eye`` => target + (0, 0.25, 1) * distance
    with the distance that fits the sphere in the narrower of the vertical / horizontal fov.
    near / far bracket the sphere as seen from the eye.
    """
    centre = bounds.mean(axis=0)
    radius = 0.5 * float(np.linalg.norm(bounds[1] - bounds[0]))
    if radius == 0.0:  # a single point => any scale works; pick one unit
        radius = 1.0
    target_w = centre if target is None else np.asarray(target, dtype=np.float64)
    if eye is None:
        half_fov_y = math.radians(fov_y) / 2.0
        half_fov_x = math.atan(math.tan(half_fov_y) * width / height)
        distance = _FRAME_MARGIN * radius / math.sin(min(half_fov_y, half_fov_x))
        eye_w = target_w + _VIEW_DIRECTION / np.linalg.norm(_VIEW_DIRECTION) * distance
    else:
        eye_w = np.asarray(eye, dtype=np.float64)
    to_centre = float(np.linalg.norm(centre - eye_w))
    # Outside the sphere => near just in front of it; inside => a small fraction of its size.
    near = max(0.9 * (to_centre - radius), 1e-3 * (to_centre + radius))
    far = 1.1 * (to_centre + radius)
    return eye_w, target_w, near, far


def batch_summary(rendered: int, skipped: int, meshes: int, render_seconds: float,
                  total_seconds: float, out: str) -> str:
    """``batch``'s last line: the views rendered, in the time rendering and writing them took
    (``write_dataset``'s ``seconds``) with the rate over them alone; the views a resumed run
    skipped as already on disk; the run's whole wall time (loading meshes, checking files)."""
    line = (f"softrast batch: rendered {rendered} view{'s' if rendered != 1 else ''} of {meshes} "
            f"mesh(es)")
    if rendered:
        line += f" in {render_seconds:.1f} s ({rendered / max(render_seconds, 1e-9):.1f} frames/s)"
    if skipped:
        line += f", skipped {skipped} already on disk"
    return f"{line}; {total_seconds:.1f} s in all -> {out}"


# What one view of a batch holds in memory until its mesh is done, an upper estimate: its camera
# (~0.7 KB), its file paths (~0.5 KB), its cameras.json record (~3 KB while the file is written),
# and write_dataset's lists. ``--views`` is checked against the memory budget with it before any
# camera is made (a billion views once grew to 24 GB before the kernel killed the process).
_VIEW_BYTES = 8 * 1024


def _mesh_bytes(mesh) -> int:
    """The bytes of a mesh's arrays (what keeping it loaded costs, textures aside)."""
    arrays = (mesh.positions, mesh.faces, mesh.normals, mesh.uvs, mesh.colors)
    return sum(int(a.nbytes) for a in arrays if a is not None)


def _load_poses(path: str) -> np.ndarray:
    """``--poses``: (n, 4, 4) camera-to-world poses (OpenGL axes), each checked as a camera pose,
    their number checked against the memory budget before they are read."""
    try:
        if path.endswith(".json"):
            poses = np.stack([c.view_matrix() for c in load_cameras(path)])
            poses = np.linalg.inv(poses)  # camera-to-world, OpenGL axes
        else:
            poses = np.load(path, mmap_mode="r", allow_pickle=False)  # the header only, so far
    except (OSError, ValueError) as e:
        raise CliError(f"--poses: {e}") from None
    if not isinstance(poses, np.ndarray) or poses.dtype.kind not in "iuf":
        raise CliError(f"--poses: expected an array of numbers, got {getattr(poses, 'dtype', type(poses))}")
    if poses.ndim != 3 or poses.shape[1:] != (4, 4) or poses.shape[0] == 0:
        raise CliError(f"--poses: expected (n, 4, 4) camera-to-world poses with n >= 1, got shape "
                       f"{poses.shape}")
    if poses.shape[0] * _VIEW_BYTES > get_memory_budget():  # before they are read
        raise CliError(f"--poses: {poses.shape[0]} views need about "
                       f"{_human(poses.shape[0] * _VIEW_BYTES)} for their cameras and file records, "
                       f"more than the memory budget of {_human(get_memory_budget())}: at most "
                       f"{get_memory_budget() // _VIEW_BYTES} views a run (split the poses)")
    poses = np.array(poses, dtype=np.float64)
    for k, pose in enumerate(poses):
        try:
            _check_pose(pose)
        except ValueError as e:
            raise CliError(f"--poses: pose {k}: {e}") from None
    return poses


def _load_intrinsics(path: str, width: int, height: int) -> np.ndarray:
    """``--intrinsics``: a (3, 3) OpenCV K, [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], fx, fy > 0."""
    try:
        K = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as e:
        raise CliError(f"--intrinsics: {e}") from None
    if not isinstance(K, np.ndarray) or K.dtype.kind not in "iuf" or K.shape != (3, 3) \
            or not np.isfinite(K).all():
        raise CliError(f"--intrinsics: expected a finite (3, 3) K of numbers, got "
                       f"{getattr(K, 'shape', type(K).__name__)}")
    K = K.astype(np.float64)
    if K[0, 1] != 0.0 or K[1, 0] != 0.0 or K[2, 0] != 0.0 or K[2, 1] != 0.0 or K[2, 2] != 1.0:
        raise CliError(f"--intrinsics: K must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew), "
                       f"got {K.tolist()}")
    try:
        IntrinsicsCamera(K[0, 0], K[1, 1], K[0, 2], K[1, 2], width, height, convention="opencv")
    except ValueError as e:
        raise CliError(f"--intrinsics: {e}") from None
    return K
