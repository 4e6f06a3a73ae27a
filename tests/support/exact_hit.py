"""The exact surface point of each pixel, in float64: the pixel's own ray (through its centre, or
through a sample) intersected with the plane of the triangle the render says is visible there,
whose corners are the mesh's stored vertices posed in double. The oracle of the README's
"Surface outputs are exact" bounds (tests/test_exact_surface.py).

Written independently of the core: the ray comes from inverting the camera's projection and view
matrices, the hit from Cramer's rule on (e1, e2, -d), in world space."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import softrast as sr


@dataclass
class Hits:
    """Per visible pixel (``rows``, ``cols``): the exact hit and what it gives."""
    rows: np.ndarray
    cols: np.ndarray
    depth: np.ndarray        # along the viewing axis
    ray_depth: np.ndarray    # from the camera centre (orthographic: = depth)
    position: np.ndarray     # world, (n, 3)
    barycentric: np.ndarray  # of the face's corners, (n, 3)
    uv: np.ndarray | None    # (n, 2), or None without uvs


def rays(camera, w: int, h: int, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World-space (origin, direction) of the rays through window points (x, y) (pixel (i, j)'s
    centre is (j + 0.5, i + 0.5)), from the inverse of projection @ view, in float64."""
    inv = np.linalg.inv(camera.projection_matrix(w, h) @ camera.view_matrix())
    ndc = np.stack([x * 2.0 / w - 1.0, 1.0 - y * 2.0 / h], -1)

    def unproject(z: float) -> np.ndarray:
        p = np.concatenate([ndc, np.full(ndc.shape[:-1] + (1,), z), np.ones(ndc.shape[:-1] + (1,))], -1)
        q = p @ inv.T
        return q[..., :3] / q[..., 3:]

    near, far = unproject(-1.0), unproject(1.0)
    if isinstance(camera, sr.OrthographicCamera):
        return near, far - near
    eye = np.linalg.inv(camera.view_matrix())[:3, 3]
    return np.broadcast_to(eye, near.shape).copy(), near - eye


def hits(frame, scene_instances, camera, w: int, h: int, sample=(0.5, 0.5),
         pixels: np.ndarray | None = None) -> Hits:
    """The exact hits of every pixel with ``frame.triangle_id >= 0`` (or of the boolean mask
    ``pixels``). ``scene_instances`` maps instance id -> (Mesh, 4x4 pose)."""
    vis = frame.triangle_id >= 0 if pixels is None else pixels
    rows, cols = np.nonzero(vis)
    tri = frame.triangle_id[rows, cols]
    inst = frame.instance_id[rows, cols]
    n = len(rows)
    corners = np.empty((n, 3, 3))
    uvs = np.zeros((n, 3, 2))
    has_uv = True
    for iid, (mesh, pose) in scene_instances.items():
        sel = inst == iid
        f = mesh.faces[tri[sel]]
        local = mesh.positions[f].astype(np.float64)
        pose = np.asarray(pose, np.float64)
        corners[sel] = local @ pose[:3, :3].T + pose[:3, 3]
        if mesh.uvs is not None:
            uvs[sel] = mesh.uvs[f].astype(np.float64)
        else:
            has_uv = False
    origin, d = rays(camera, w, h, cols + sample[0], rows + sample[1])
    p0 = corners[:, 0]
    e1, e2 = corners[:, 1] - p0, corners[:, 2] - p0
    rhs = origin - p0
    # Cramer's rule on [e1 e2 -d] (u, v, t) = rhs
    det = np.einsum("ni,ni->n", np.cross(e1, e2), -d)
    u = np.einsum("ni,ni->n", np.cross(rhs, e2), -d) / det
    v = np.einsum("ni,ni->n", np.cross(e1, rhs), -d) / det
    t = np.einsum("ni,ni->n", np.cross(e1, e2), rhs) / det
    position = origin + t[:, None] * d
    view = camera.view_matrix()
    depth = -(position @ view[2, :3] + view[2, 3])
    if isinstance(camera, sr.OrthographicCamera):
        ray_depth = depth
    else:
        ray_depth = np.linalg.norm(position - origin, axis=1)
    bary = np.stack([1.0 - u - v, u, v], 1)
    uv = np.einsum("nc,ncd->nd", bary, uvs) if has_uv else None
    return Hits(rows, cols, depth, ray_depth, position, bary, uv)


def ulps(got: np.ndarray, exact: np.ndarray) -> np.ndarray:
    """|got - exact| in units of float32's spacing at the exact value."""
    exact = np.asarray(exact, np.float64)
    return np.abs(np.asarray(got, np.float64) - exact) / np.spacing(np.abs(exact).astype(np.float32)).astype(np.float64)


def reproject_px(positions: np.ndarray, camera, w: int, h: int) -> np.ndarray:
    """Window coordinates (x, y) of world points, float64."""
    clip = np.c_[positions, np.ones(len(positions))] @ (camera.projection_matrix(w, h) @ camera.view_matrix()).T
    ndc = clip[:, :2] / clip[:, 3:]
    return np.c_[(ndc[:, 0] + 1) * w / 2, (1 - ndc[:, 1]) * h / 2]
