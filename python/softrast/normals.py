"""Face and vertex normals of triangle meshes, exact at any scale: each cross product is taken of
edges scaled by powers of two, so coordinates anywhere from 1e-30 to 3e38 give the same unit
normals (``Mesh.from_trimesh(smooth=...)``, ``softrast.displace``)."""
from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["SMOOTH", "face_normals", "merge_exact", "unit_rows", "vertex_normals"]


SMOOTH = (True, False, "area", "angle")


def _power_of_two_scaled(v: np.ndarray, largest: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rows of ``v`` times 2**-e, e) with e per row such that ``largest`` (per row, > 0) times 2**-e
    lies in [1, 2): exact, so a quantity homogeneous in the row keeps its bits while its squares
    neither overflow nor underflow float64. Rows whose ``largest`` is 0 or not finite: unscaled."""
    ok = (largest > 0.0) & np.isfinite(largest)
    _, e = np.frexp(np.where(ok, largest, 1.0))  # largest = m 2**e, m in [0.5, 1)
    e = np.where(ok, e - 1, 0)
    return np.ldexp(v, -e.reshape((-1,) + (1,) * (v.ndim - 1))), e


def unit_rows(v: Any) -> np.ndarray:
    """Each row of the (n, 3) array ``v`` divided by its length, in float64; zero for a zero row
    or one with NaN or inf. Each row is scaled by a power of two to a largest |component| in
    [1, 2) first (exact): unit for any finite nonzero row, 1e-300 or 1e300 alike, and for rows
    whose squared length is a normal float64 the same bits as ``v / np.linalg.norm(v)``."""
    v = np.asarray(v, dtype=np.float64)
    finite = np.isfinite(v).all(axis=1)
    largest = np.where(finite, np.abs(np.where(finite[:, None], v, 0.0)).max(axis=1, initial=0.0), 0.0)
    scaled, _ = _power_of_two_scaled(np.where(finite[:, None], v, 0.0), largest)
    length = np.linalg.norm(scaled, axis=1, keepdims=True)
    return np.divide(scaled, length, out=np.zeros_like(scaled), where=(length > 0.0) & finite[:, None])


def _face_cross(e01: np.ndarray, e02: np.ndarray, e12: np.ndarray) -> np.ndarray:
    """(m, 3) counter-clockwise face normals e01 x e02 (unnormalised) from each face's edges
    (corner 0 -> 1, 0 -> 2, 1 -> 2). Where corner 0's angle is below ~2^-30 rad the cross
    product has cancelled (a corner 0 1e19 away from the other two: both its edges round to the
    same float64, and their cross product is 0): those faces' are taken at the corner opposite
    the longest edge (the largest angle), the cyclic order kept. Every other face keeps corner
    0's, the bits of a plain ``np.cross(e01, e02)``; the core's flat normals do the same."""
    cross = np.cross(e01, e02)
    dot = lambda a, b: np.einsum("ij,ij->i", a, b)  # noqa: E731
    with np.errstate(over="ignore", invalid="ignore"):
        # |cross|^2 < 2^-60 (e01.e02)^2 (|e01|^2 |e02|^2 = |cross|^2 + (e01.e02)^2): the core's test
        bad = ~(dot(cross, cross) >= 2.0**-60 * dot(e01, e02) ** 2)
    if bad.any():
        e01, e02, e12 = e01[bad], e02[bad], e12[bad]
        longest = np.argmax(np.stack([dot(e12, e12), dot(e02, e02), dot(e01, e01)]), axis=0)
        at1 = np.cross(e12, -e01)  # corner 1: (2 - 1) x (0 - 1)
        at2 = np.cross(-e02, -e12)  # corner 2: (0 - 2) x (1 - 2)
        cross[bad] = np.where((longest == 1)[:, None], at1, np.where((longest == 2)[:, None], at2, cross[bad]))
    return cross


def face_normals(positions: Any, faces: Any) -> tuple[np.ndarray, np.ndarray]:
    """(unit normals, corner angles) of the counter-clockwise faces, in float64, from each face's
    corners relative to its first corner scaled by a power of two to a largest |coordinate| in
    [1, 2) (exact) before the cross product: neither the cross product nor its squared length
    over- or underflows for corners anywhere in float32's range (a face with one corner at 3e38
    or all within 1e-45), so every face that is not degenerate in float64 has a unit normal.
    The angles (radians, (m, 3), at corners 0, 1, 2) are atan2(|cross|, dot) of the scaled
    edges: accurate for slivers too (a corner of 1e-39 rad, where an arccos of the dot gives 0).
    A degenerate face (collinear corners): normal 0, its angles 0 at coincident corners."""
    v = np.asarray(positions, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    c = v[f]  # (m, 3, 3)
    edges = np.stack([c[:, 1] - c[:, 0], c[:, 2] - c[:, 0], c[:, 2] - c[:, 1]], axis=1)
    largest = np.abs(edges).max(axis=(1, 2), initial=0.0)
    e01, e02, e12 = np.moveaxis(_power_of_two_scaled(edges, largest)[0], 1, 0)
    cross = _face_cross(e01, e02, e12)
    normals = unit_rows(cross)
    twice_area = np.linalg.norm(cross, axis=1)  # |cross| is the same for any two of the edges
    angles = np.stack([np.arctan2(twice_area, np.einsum("ij,ij->i", e01, e02)),
                       np.arctan2(twice_area, -np.einsum("ij,ij->i", e01, e12)),
                       np.arctan2(twice_area, np.einsum("ij,ij->i", e02, e12))], axis=1)
    return normals, angles


def _angle_weighted_normals(tm: Any) -> np.ndarray:
    """trimesh's angle-weighted vertex normals (Thuerrner & Wuethrich), kept as trimesh gives them
    wherever its rule holds, so the same bits; recomputed by the same rule from ``face_normals``
    (float64, corners scaled to unit magnitude, angles by atan2) at every vertex of a face that
    trimesh drops but is not degenerate: trimesh zeroes a face normal below its tolerance (each
    face of a mesh smaller than about 1e-5) and all angles of a face with a corner below 1e-8 rad
    (a vertex 1e19 from unit ones), which left such vertices a zero normal."""
    v = np.asarray(tm.vertices, dtype=np.float64)
    f = np.asarray(tm.faces, dtype=np.int64)
    out = np.array(tm.vertex_normals, dtype=np.float64)
    if len(f) == 0:
        return out
    normals, angles = face_normals(v, f)
    with np.errstate(invalid="ignore"):
        theirs_ok = ((np.abs(np.linalg.norm(np.asarray(tm.face_normals, np.float64), axis=1) - 1.0) < 1e-6)
                     & (np.asarray(tm.face_angles, np.float64) > 0.0).all(axis=1))
    redo = np.zeros(len(v), dtype=bool)
    redo[f[(normals != 0.0).any(axis=1) & ~theirs_ok].ravel()] = True
    redo |= np.abs(np.linalg.norm(out, axis=1) - 1.0) > 1e-6  # (a zero one: also recomputed)
    if not redo.any():
        return out
    acc = np.zeros_like(v)
    for k in range(3):
        np.add.at(acc, f[:, k], angles[:, k, None] * normals)
    out[redo] = unit_rows(acc[redo])
    return out


def vertex_normals(tm: Any, smooth: bool | str) -> np.ndarray | None:
    """Per-vertex normals for ``smooth`` (see load_mesh): the file's own where it has them, else
    the sum of the adjacent faces' normals weighted by their areas (True or "area", as the
    course notes prescribe) or by their corner angles ("angle", trimesh's rule); False: None
    (flat face normals). Computed in float64 (area: the cross products of float32 corners are
    at most ~1e78 and at least ~1e-90, squared inside float64's range; each sum is normalised by
    ``unit_rows``), so every vertex of a face that is not degenerate gets a unit normal for
    coordinates anywhere in float32's range, from 1e-45 to 3.4e38 (a vertex in no face, or
    whose faces cancel, keeps a zero normal: the renderer then uses the face normal)."""
    if not (isinstance(smooth, bool) or (isinstance(smooth, str) and smooth in ("area", "angle"))):
        raise ValueError(f"smooth must be True, False, 'area' or 'angle', got {smooth!r:.80}")
    if smooth is False:
        return None
    cached = tm._cache.cache.get("vertex_normals") if hasattr(tm, "_cache") else None
    if cached is not None and len(cached) == len(tm.vertices):  # the file's own normals
        return np.asarray(cached)
    if smooth == "angle":
        return _angle_weighted_normals(tm)
    v = np.asarray(tm.vertices, dtype=np.float64)
    f = np.asarray(tm.faces, dtype=np.int64)
    # The cross product's length is twice the face's area: summing it weights by area.
    cross = _face_cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 1]])
    acc = np.zeros_like(v)
    for k in range(3):
        np.add.at(acc, f[:, k], cross)
    # A vertex in no face (or whose faces cancel) keeps a zero normal: shaded with its face normal.
    return unit_rows(acc)


def merge_exact(positions: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Merge vertices with exactly equal positions (as trimesh's ``merge_vertices`` does for a
    file that stores none, but bit-exact, without its rounding): (positions, faces, first), the
    merged vertices in order of first use, faces in their order, ``first[k]`` the index of merged
    vertex k's first occurrence. -0.0 and 0.0 are one position."""
    pos = np.ascontiguousarray(np.asarray(positions, dtype=np.float64) + 0.0)  # -0.0 -> 0.0
    _, index, inverse = np.unique(pos, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    order = np.argsort(index, kind="stable")  # unique rows sorted by first occurrence
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    first = index[order]
    return np.asarray(positions)[first], rank[inverse][np.asarray(faces)], first
