"""A NumPy (float64) reference for softrast's exact shadows (``shadows="exact"``).

The rule, for a shaded point p and a light:

* the shadow ray leaves p toward the light: for a directional light along
  ``-light_direction`` (``light_direction`` = the pose's -z axis, normalised), every t > 0;
  for a point or spot light at L along d = L - p, blockers only for 0 < t < 1;
* a triangle blocks when the ray meets it (Moller-Trumbore in double: barycentrics u, v,
  1 - u - v all >= 0), **except** a triangle whose plane passes within
  eps = 2**-19 * max(|a|_inf, |b|_inf, |c|_inf, |p|_inf) of p (a, b, c its world corners): the
  surface through the shaded point (and any surface coplanar with it) never shadows it;
* every triangle of every draw casts, both faces, in view or not, except the draws whose
  material has ``alpha_mode="blend"``.

``shadow_rays`` returns, per point, whether it is blocked and a *margin*: how far the decision is
from flipping, as a relative number (barycentric units for a triangle's edges, the ray's length
over the scene's scale for the ends of its range). For a blocked point it is the largest margin
among the blocking triangles (all of them would have to stop blocking); for an unblocked point the
smallest distance of any triangle from blocking. Points whose plane distance to a triangle is
within a factor 4 of eps (either side), where that triangle would otherwise block, get margin 0.
Comparisons with the renderer, which decides at its own float32 point, leave out points whose
margin is below a small threshold (1e-5).
"""
from __future__ import annotations

from typing import Any, Iterable, NamedTuple

import numpy as np

from .shading import pose_at

__all__ = ["EPS_SCALE", "EXCLUDE_BAND", "RefLight", "light_pose", "light_from_pose", "scene_lights",
           "mesh_triangles", "scene_triangles", "shadow_rays", "shadowed", "face_centroids",
           "lights_blocked"]

EPS_SCALE = 2.0 ** -19          # the rule's relative plane distance
EXCLUDE_BAND = 4.0              # plane distances in [eps / 4, 4 eps] are ambiguous
PAIRS_PER_CHUNK = 400_000       # points x triangles evaluated at once (bounds memory to ~100 MB)


class RefLight(NamedTuple):
    """A light as the rule reads it: kind ("directional", "point" or "spot"), world position
    (point / spot) and unit direction of travel (the pose's -z axis)."""

    kind: str
    position: np.ndarray
    direction: np.ndarray


def light_pose(position: Any = (0.0, 0.0, 0.0), travel: Any = (0.0, -1.0, 0.0)) -> np.ndarray:
    """``softrast.reference.shading.pose_at`` with a light travelling down by default.

    Parameters
    ----------
    position : array_like, shape (3,)
        The light's position.
    travel : array_like, shape (3,)
        The way the light travels (the pose's -z axis).

    Returns
    -------
    numpy.ndarray
        (4, 4) float64 light-to-world pose.
    """
    return pose_at(position, travel)


def light_from_pose(kind: str, pose: np.ndarray) -> RefLight:
    """The RefLight of a light placed at a pose.

    Parameters
    ----------
    kind : {"directional", "point", "spot"}
        The light's kind.
    pose : numpy.ndarray, shape (4, 4)
        Light to world.

    Returns
    -------
    RefLight
    """
    pose = np.asarray(pose, np.float64)
    d = -pose[:3, 2]
    return RefLight(kind, pose[:3, 3].copy(), d / np.linalg.norm(d))


def scene_lights(scene: Any) -> list[RefLight]:
    """The world-space lights of a scene.

    Parameters
    ----------
    scene : softrast.Scene
        Its ``lights`` (camera-space lights are not supported here: ValueError).

    Returns
    -------
    list of RefLight
    """
    out = []
    for li in scene.lights:
        if li.camera_space:
            raise ValueError("softrast.reference.shadow: camera-space lights are not supported")
        out.append(light_from_pose(li.light._kind, li.pose))
    return out


def mesh_triangles(positions: Any, faces: Any, pose: Any = None) -> np.ndarray:
    """The world triangles of a mesh.

    Parameters
    ----------
    positions : array_like, shape (n, 3)
        Its (float32-stored) positions, taken in float64.
    faces : array_like, shape (F, 3)
        Vertex indices.
    pose : array_like, shape (4, 4), optional
        Model to world.

    Returns
    -------
    numpy.ndarray
        (F, 3, 3) float64.
    """
    pos = np.asarray(positions, np.float64)
    if pose is not None:
        pose = np.asarray(pose, np.float64)
        pos = pos @ pose[:3, :3].T + pose[:3, 3]
    return pos[np.asarray(faces, np.int64)]


def scene_triangles(scene: Any, include_blend: bool = False, return_owner: bool = False) -> Any:
    """The world triangles that cast shadows in a scene.

    Parameters
    ----------
    scene : softrast.Scene
        Every mesh instance's triangles, in the order added, except those whose material has
        ``alpha_mode="blend"``.
    include_blend : bool
        Keep the blended instances too.
    return_owner : bool
        Also return who owns each triangle.

    Returns
    -------
    triangles : numpy.ndarray, shape (N, 3, 3)
        float64 world triangles.
    owner : numpy.ndarray, shape (N, 2)
        With ``return_owner``: (index of the instance in ``scene.instances``, face index).
    """
    tris, owner = [], []
    for k, inst in enumerate(scene.instances):
        mat = inst.material
        if not include_blend and mat is not None and getattr(mat, "alpha_mode", "opaque") == "blend":
            continue
        t = mesh_triangles(inst.mesh.positions, inst.mesh.faces, inst.pose)
        tris.append(t)
        owner.append(np.stack([np.full(len(t), k), np.arange(len(t))], axis=1))
    tris_a = np.concatenate(tris) if tris else np.zeros((0, 3, 3))
    if return_owner:
        return tris_a, (np.concatenate(owner) if owner else np.zeros((0, 2), np.int64))
    return tris_a


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...k,...k->...", a, b)


def shadow_rays(triangles: np.ndarray, points: np.ndarray, light: RefLight,
                unlimited: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The rule's decision and its margin for each point under ``light``.

    Parameters
    ----------
    triangles : numpy.ndarray, shape (N, 3, 3)
        World triangles (float64; the casters).
    points : numpy.ndarray, shape (M, 3)
        World points (the shaded points).
    light : RefLight
        The light.
    unlimited : bool
        For point / spot lights, accept blockers at any t > 0 (beyond the light too); not the
        rule: tests use it to show that a blocker beyond the light would shadow.

    Returns
    -------
    blocked : numpy.ndarray, shape (M,)
        bool.
    margin : numpy.ndarray, shape (M,)
        float64, how far the decision is from flipping (the module docstring).
    """
    tris = np.asarray(triangles, np.float64).reshape(-1, 3, 3)
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    m, n = len(pts), len(tris)
    blocked = np.zeros(m, bool)
    margin = np.full(m, np.inf)
    if n == 0 or m == 0:
        return blocked, margin
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    e1, e2 = b - a, c - a
    normal = _cross(e1, e2)
    normal_len = np.linalg.norm(normal, axis=1)
    tri_scale = np.abs(tris).max(axis=(1, 2))           # max(|a|, |b|, |c|)_inf
    directional = light.kind == "directional"
    toward = -np.asarray(light.direction, np.float64)
    toward = toward / np.linalg.norm(toward)
    chunk = max(1, PAIRS_PER_CHUNK // n)
    for s in range(0, m, chunk):
        p = pts[s:s + chunk]                            # (k, 3)
        if directional:
            d = np.broadcast_to(toward, p.shape)
            t_max = np.inf
        else:
            d = np.asarray(light.position, np.float64)[None, :] - p
            t_max = np.inf if unlimited else 1.0
        dlen = np.linalg.norm(d, axis=1)                # (k,)
        D = d[:, None, :]                               # (k, 1, 3)
        pvec = _cross(D, e2[None])                      # (k, n, 3)
        det = _dot(e1[None], pvec)                      # (k, n)
        tvec = p[:, None, :] - a[None]                  # (k, n, 3)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            inv = 1.0 / det
            u = _dot(tvec, pvec) * inv
            qvec = _cross(tvec, e1[None])
            v = _dot(D, qvec) * inv
            t = _dot(e2[None], qvec) * inv
            w = 1.0 - u - v
            bary = np.minimum(np.minimum(u, v), w)      # >= 0 inside (edges included)
            dist = np.abs(_dot(tvec, normal[None])) / normal_len[None]
            scale = np.maximum(tri_scale[None], np.abs(p).max(axis=1)[:, None])
            eps = EPS_SCALE * scale
            # The ray's range, as a relative length: > 0 inside (0, t_max).
            lo = t * dlen[:, None]
            hi = (t_max - t) * dlen[:, None] if np.isfinite(t_max) else np.full_like(t, np.inf)
            rng = np.minimum(lo, hi) / scale
            inside_range = (t > 0.0) & (t < t_max)
            valid = (det != 0.0) & np.isfinite(det) & (normal_len[None] > 0.0) & np.isfinite(bary) & np.isfinite(t)
            excluded = dist <= eps
            hit = valid & ~excluded & (bary >= 0.0) & inside_range
            blocked[s:s + chunk] = hit.any(axis=1)
            # Margins: a pair's score is >= 0 when it blocks, its |score| how far from flipping.
            score = np.minimum(bary, rng)
            ambiguous = (dist >= eps / EXCLUDE_BAND) & (dist <= eps * EXCLUDE_BAND)
            score = np.where(ambiguous, np.minimum(score, 0.0), score)
            score = np.where(valid & (dist >= eps / EXCLUDE_BAND), score, -np.inf)
            # A pair that blocks under the rule scores >= 0 even if the relative range rounds to 0.
            score = np.where(hit, np.maximum(score, 0.0), np.minimum(score, -0.0))
            best = score.max(axis=1)
            margin[s:s + chunk] = np.abs(best)
    return blocked, margin


def shadowed(triangles: np.ndarray, points: np.ndarray, light: RefLight) -> np.ndarray:
    """The rule's decision only.

    Parameters
    ----------
    triangles, points, light
        As for ``shadow_rays``.

    Returns
    -------
    numpy.ndarray
        (M,) bool, ``shadow_rays(...)[0]``.
    """
    return shadow_rays(triangles, points, light)[0]


def face_centroids(triangles: np.ndarray) -> np.ndarray:
    """The centroids of triangles.

    Parameters
    ----------
    triangles : array_like, shape (N, 3, 3)
        The triangles.

    Returns
    -------
    numpy.ndarray
        (N, 3) float64.
    """
    return np.asarray(triangles, np.float64).mean(axis=1)


def lights_blocked(triangles: np.ndarray, points: np.ndarray,
                   lights: Iterable[RefLight]) -> list[tuple[np.ndarray, np.ndarray]]:
    """``shadow_rays`` for each light in turn.

    Parameters
    ----------
    triangles, points
        As for ``shadow_rays``.
    lights : iterable of RefLight
        The lights.

    Returns
    -------
    list of tuple
        (blocked, margin) per light.
    """
    return [shadow_rays(triangles, points, li) for li in lights]
