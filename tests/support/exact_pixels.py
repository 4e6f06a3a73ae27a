"""Helpers for tests that check renders against exact per-pixel answers (test_extreme_inputs.py,
test_near_plane.py): pixel centres, the pixels no edge passes near (``_stable``), float64 pinhole
rays and projection, a scene of meshes, and a check that the float outputs are finite."""
from __future__ import annotations

import numpy as np

import softrast as sr

SURFACE_FLOATS = ("depth", "normal", "barycentric", "position", "radiance")
EVERYTHING = ("depth", "mask", "coverage", "triangle_id", "normal", "barycentric", "position",
              "radiance", "color")


def _centres(w: int, h: int) -> tuple[np.ndarray, np.ndarray]:
    """Window coordinates (x, y), each (h, w) float64, of every pixel centre."""
    return np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)


_CIRCLE = np.stack([np.cos(np.arange(16) * np.pi / 8), np.sin(np.arange(16) * np.pi / 8)], 1)


def _stable(label_at, w: int, h: int, eps: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """(labels at the pixel centres, sure): ``label_at(x, y)`` maps (h, w) window coordinates to
    labels; a pixel is sure where the label is the same at 16 points on a circle of ``eps`` px
    around its centre, i.e. where no label boundary (an edge) passes within ~eps px of it."""
    x, y = _centres(w, h)
    labels = label_at(x, y)
    sure = np.ones(labels.shape, bool)
    for dx, dy in eps * _CIRCLE:
        sure &= label_at(x + dx, y + dy) == labels
    return labels, sure


def _view_rays(cam, w: int, h: int, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(eye, directions) in world space of a pinhole camera's rays through window points (x, y);
    each direction has view-space z = -1, so a hit at parameter t has depth (-z_view) t."""
    p = cam.projection_matrix(w, h)
    d = np.stack([(2.0 * x / w - 1.0 + p[0, 2]) / p[0, 0], (1.0 - 2.0 * y / h + p[1, 2]) / p[1, 1],
                  -np.ones_like(x)], -1)
    view_to_world = np.linalg.inv(cam.view_matrix())
    return view_to_world[:3, 3], d @ view_to_world[:3, :3].T


def _window(cam, w: int, h: int, points: np.ndarray) -> np.ndarray:
    """(n, 2) float64 window coordinates of world points (in front of the camera)."""
    pts = np.asarray(points, np.float64)
    clip = np.c_[pts, np.ones(len(pts))] @ (cam.projection_matrix(w, h) @ cam.view_matrix()).T
    ndc = clip[:, :2] / clip[:, 3:]
    return np.c_[(ndc[:, 0] + 1.0) * w / 2.0, (1.0 - ndc[:, 1]) * h / 2.0]


def _scene(*meshes: sr.Mesh) -> sr.Scene:
    scene = sr.Scene()
    for k, m in enumerate(meshes):
        scene.add(m, instance_id=k)
    return scene


def _assert_finite(frame) -> None:
    for name in SURFACE_FLOATS:
        if name in frame.outputs:
            arr = getattr(frame, name)
            assert np.isfinite(arr).all(), f"{name} has {int((~np.isfinite(arr)).sum())} non-finite values"
