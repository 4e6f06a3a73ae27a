"""Normals at any scale: face and vertex normals are unit for meshes with
coordinates from 1e-30 to 3e38, under poses that scale an axis by anything from 1e-300 to 1e30,
seen by perspective and orthographic cameras. The README's "Normals" bullet under "Numerical
behaviour at the limits" cites this file.

What broke before: trimesh's angle-weighted vertex normals (``load_mesh(smooth="angle")``) were
zero at a vertex 1e19 from unit ones and everywhere on a mesh smaller than ~1e-5; the core's flat
normals and world vertex normals were zero under a pose scaling one axis by 1e-160 (the normal
matrix's 1e160 squared overflows double). References here are float64 NumPy, computed on each
face's corners scaled to unit magnitude (an ordinary division, not the code's power of two), with
Kahan's formula for the corner angles (not the code's atan2).
"""
from __future__ import annotations

import math
import warnings
from fractions import Fraction

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import softrast as sr
from softrast.normals import face_normals, unit_rows, vertex_normals

FAN = np.array([[0, 1, 2], [1, 3, 2]])
# The far vertex (3) at each corner of the second face: as corner 0 both its edges round to the
# same float64 (1 - 1e19 == -1e19), and a cross product taken there is 0.
FANS = [FAN, np.array([[0, 1, 2], [3, 2, 1]]), np.array([[0, 1, 2], [2, 1, 3]])]


def _far_vertex_mesh(big: float) -> np.ndarray:
    return np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [big, big, 0.5]])


def _reference_vertex_normals(v: np.ndarray, f: np.ndarray, weighting: str) -> np.ndarray:
    """Exact rational arithmetic on the float64 corners (Fractions), rounded once: each face's
    cross product and its corners' dot products; its unit normal; its area (|cross| / 2) or
    corner angles atan2(|cross|, dot) (|cross| is twice the area whichever two edges span it)."""
    acc = np.zeros_like(np.asarray(v, dtype=np.float64))
    for face in f:
        c = [[Fraction(float(x)) for x in v[i]] for i in face]
        e = [[c[j][k] - c[i][k] for k in range(3)] for i, j in ((0, 1), (0, 2), (1, 2))]
        cross = [e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
                 e[0][0] * e[1][1] - e[0][1] * e[1][0]]
        if not any(cross):
            continue
        twice_area = math.sqrt(sum(x * x for x in cross))  # (a Fraction up to ~1e156: a float)
        n = np.array([float(x / Fraction(twice_area)) for x in cross])
        if weighting == "area":
            weights = [twice_area] * 3
        else:
            def dot(a, b, sa=1, sb=1):
                return float(sum(sa * x * sb * y for x, y in zip(a, b)))
            weights = [math.atan2(twice_area, dot(e[0], e[1])), math.atan2(twice_area, dot(e[0], e[2], -1)),
                       math.atan2(twice_area, dot(e[1], e[2]))]
        for k in range(3):
            acc[face[k]] += weights[k] * n
    scale = np.abs(acc).max(axis=1, keepdims=True)
    acc = acc / np.where(scale > 0, scale, 1.0)
    return acc / np.linalg.norm(acc, axis=1, keepdims=True)


# ------------------------------------------------------------------- vertex normals (Python)

@pytest.mark.parametrize("smooth", [True, "angle"])
@pytest.mark.parametrize("big", [1e19, 1e20, 1e30, 3e38, -1e25])
def test_vertex_normals_with_one_far_vertex_are_unit_and_right(big: float, smooth) -> None:
    v = _far_vertex_mesh(big)
    for fan in FANS:
        got = vertex_normals(trimesh.Trimesh(v, fan, process=False), smooth)
        want = _reference_vertex_normals(v, fan, "area" if smooth is True else "angle")
        np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-12)
        np.testing.assert_allclose(got, want, atol=1e-12)
        assert (np.sum(got * want, axis=1) > 1.0 - 1e-12).all()


@pytest.mark.parametrize("smooth", [True, "angle"])
@pytest.mark.parametrize("scale", [1e-30, 1e-20, 1e-10, 1e-6, 1e10, 1e30, 2e38])
def test_vertex_normals_of_a_whole_mesh_at_any_scale(scale: float, smooth) -> None:
    """A sphere and a slanted fan scaled from 1e-30 to 2e38: the unit-scale mesh's normals
    (trimesh's angle rule gave zeros below ~1e-5)."""
    for tm in (trimesh.creation.icosphere(subdivisions=1), trimesh.Trimesh(_far_vertex_mesh(1.0), FAN, process=False)):
        unit = vertex_normals(tm, smooth)
        got = vertex_normals(trimesh.Trimesh(tm.vertices * scale, tm.faces, process=False), smooth)
        np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-12)
        np.testing.assert_allclose(got, unit, atol=1e-12)
        want = _reference_vertex_normals(tm.vertices * scale, np.asarray(tm.faces),
                                         "area" if smooth is True else "angle")
        np.testing.assert_allclose(got, want, atol=1e-12)


def test_angle_weighted_normals_keep_trimesh_bits_on_ordinary_meshes() -> None:
    for tm in (trimesh.creation.icosphere(subdivisions=3), trimesh.creation.cone(0.5, 2.0, sections=24),
               trimesh.creation.box(extents=(1.0, 2.0, 3.0))):
        tm = trimesh.Trimesh(tm.vertices, tm.faces, process=False)
        np.testing.assert_array_equal(vertex_normals(tm, "angle"), tm.vertex_normals)


@pytest.mark.parametrize("smooth", [True, "angle"])
@pytest.mark.parametrize("big", [1e19, 3e38])
def test_load_mesh_far_vertex_gets_unit_normals(tmp_path, big: float, smooth) -> None:
    path = tmp_path / "far.obj"
    v = _far_vertex_mesh(big)
    path.write_text("".join(f"v {float(x)!r} {float(y)!r} {float(z)!r}\n" for x, y, z in v) + "f 1 2 3\nf 2 4 3\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sr.PrecisionWarning)
        mesh = sr.load_mesh(path, smooth=smooth)
    want = _reference_vertex_normals(mesh.positions.astype(np.float64), mesh.faces,
                                     "area" if smooth is True else "angle")
    np.testing.assert_allclose(np.linalg.norm(mesh.normals.astype(np.float64), axis=1), 1.0, atol=1e-6)
    np.testing.assert_allclose(mesh.normals, want, atol=1e-6)


def test_unit_rows_and_face_normals_at_any_magnitude() -> None:
    rng = np.random.default_rng(7)
    rows = rng.uniform(-1.0, 1.0, (200, 3))
    # Same bits as v / |v| where |v|^2 is a normal double (the power of two is exact).
    np.testing.assert_array_equal(unit_rows(rows), rows / np.linalg.norm(rows, axis=1, keepdims=True))
    for m in (1e-320, 1e-300, 1e-160, 1e-45, 1e45, 1e160, 1e300, 1e308):
        x = rows * m  # (1e-320: subnormal, a few bits of the rows left)
        got = unit_rows(x)
        ref = x / np.abs(x).max(axis=1, keepdims=True)
        np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-15)
        np.testing.assert_allclose(got, ref / np.linalg.norm(ref, axis=1, keepdims=True), atol=1e-15)
    np.testing.assert_array_equal(unit_rows([[0.0, 0.0, 0.0], [np.nan, 0.0, 1.0], [np.inf, 0.0, 0.0]]), 0.0)
    # Faces with corners from 1e-45 to 3.4e38: unit normals, angles summing to pi.
    for s in (1.4e-45, 1e-30, 1.0, 1e30, 3.4e38 / 1.5):
        n, a = face_normals(_far_vertex_mesh(1.0) * s, FAN)
        np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-15)
        np.testing.assert_allclose(a.sum(axis=1), math.pi, atol=1e-12)
    for fan, far_corner in zip(FANS, (1, 0, 2)):  # a corner of ~1e-39 rad, wherever it is
        n, a = face_normals(_far_vertex_mesh(3e38), fan)
        assert 0.0 < a[1, far_corner] < 1e-38 and np.linalg.norm(n[1]) == pytest.approx(1.0, abs=1e-15)
        assert n[1, 2] == pytest.approx(1.0, abs=1e-15)
    n, _ = face_normals([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]], [[0, 1, 2]])
    np.testing.assert_array_equal(n, 0.0)  # collinear: no normal


# ------------------------------------------------------------------- the core (renders)

def _render(positions, pose, eye, target, normals=None, ortho=False, size=1.0, **kw):
    scene = sr.Scene()
    scene.add(sr.Mesh(positions, [[0, 1, 2]], normals=normals), pose=pose)
    if ortho:
        cam = sr.OrthographicCamera(xmag=2.0 * size, ymag=2.0 * size, near=0.1 * size, far=10.0 * size)
    else:
        cam = sr.PerspectiveCamera(fov_y=60.0, near=0.1 * size, far=10.0 * size)
    cam.look_at(eye, target, up=(0.0, 1.0, 0.0) if abs(np.subtract(eye, target)[1]) < 1e-3 else (1.0, 0.0, 0.0))
    return sr.Renderer(32, 32).render(scene, cam, ("normal", "mask", "triangle_id"), cull="none", **kw)


@pytest.mark.parametrize("ortho", [False, True])
@pytest.mark.parametrize("scale", [1e-100, 1e-160, 1e-200, 1e-300])
@pytest.mark.parametrize("normals", ["flat", "unit", "1e-30", "3e38"])
def test_pose_flattening_an_axis_keeps_unit_normals(scale: float, normals: str, ortho: bool) -> None:
    """A triangle in the z = 0 plane (normal +z) under diag(1, 1, scale): the normal matrix is
    diag(1, 1, 1/scale); its 1e160 times a face normal or a 3e38 vertex normal squared overflowed
    double (zero normals). Now the normal is +-z, unit. And a triangle in x = 0 (normal +x) under
    diag(scale, 1, 1), seen along x: +-x."""
    tri = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    vn = None if normals == "flat" else np.tile([0.0, 0.0, {"unit": 1.0, "1e-30": 1e-30, "3e38": 3e38}[normals]], (3, 1))
    for axis in (2, 0):
        pose = np.eye(4)
        pose[axis, axis] = scale
        p = np.roll(tri, axis + 1, axis=1) if axis == 0 else tri  # x = 0 plane: (0, x, y)
        n = None if vn is None else np.roll(vn, axis + 1, axis=1) if axis == 0 else vn
        eye = np.full(3, 0.3)
        eye[axis] = 3.0
        target = np.full(3, 0.3)
        target[axis] = 0.0
        f = _render(p, pose, eye, target, normals=n, ortho=ortho)
        assert f.mask.sum() > 20
        got = f.normal[f.mask].astype(np.float64)
        assert np.isfinite(f.normal).all()
        np.testing.assert_allclose(np.abs(got[:, axis]), 1.0, atol=1e-6)
        np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-6)


@pytest.mark.parametrize("ortho", [False, True])
@pytest.mark.parametrize("big", [1e8, 1e14, 1e19, 1e20, 1e30, 1e37])
def test_flat_normal_of_a_face_with_a_far_corner(big: float, ortho: bool) -> None:
    """A face with one corner at (big, big, 0.5) among unit ones, the far corner first, second or
    third: its flat normal is (-0.5, -0.5, 2 big) normalised (a cross product taken at the far
    corner was 0 from 1e19 up: zero normals; at 1e14 off by 5e-3 rad)."""
    p = np.array([[big, big, 0.5], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    want = np.array([-0.5, -0.5, 2.0 * big])
    want /= np.linalg.norm(want)
    for face in ([0, 1, 2], [1, 2, 0], [2, 0, 1]):
        f = _render(p[face], np.eye(4), (0.6, 0.6, 3.0), (0.6, 0.6, 0.0), ortho=ortho, shading="normal")
        assert f.mask.sum() > 20
        np.testing.assert_allclose(f.normal[f.mask], np.tile(want, (int(f.mask.sum()), 1)), atol=1e-6)


# ------------------------------------------------------------------- property test

def _magnitudes(lo: int, hi: float):
    """Positive floats spread over decades 10**lo .. hi."""
    return st.tuples(st.floats(lo, math.log10(hi)), st.floats(1.0, 9.99)).map(
        lambda t: min(t[1] * 10.0 ** t[0], hi))


@st.composite
def _cases(draw):
    n = draw(st.integers(3, 6))
    rng = np.random.default_rng(draw(st.integers(0, 2**31 - 1)))
    positions = rng.uniform(-1.5, 1.5, (n, 3))
    kind = draw(st.sampled_from(["one far", "one tiny", "whole mesh", "mixed"]))
    if kind == "whole mesh":  # the mesh itself at 1e-30 .. 3e38
        positions *= draw(_magnitudes(-30, 3e38)) / np.abs(positions).max()
    else:
        for k in draw(st.lists(st.integers(0, n - 1), min_size=1, max_size=2 if kind == "mixed" else 1)):
            m = draw(_magnitudes(-30, 3e38) if kind != "one tiny" else _magnitudes(-30, 1e-3))
            positions[k] = rng.choice([-1.0, 1.0], 3) * m * rng.uniform(0.5, 1.0, 3)
    positions = positions.astype(np.float32).astype(np.float64)
    faces = np.array([[0, k, k + 1] for k in range(1, n - 1)])
    smooth = draw(st.sampled_from(["flat", "area", "angle", "given"]))
    rotation = trimesh.transformations.random_rotation_matrix(rng.uniform(size=3))[:3, :3]
    scales = draw(st.tuples(*[st.sampled_from([1.0, 1.0, 2.0, -1.0, 1e-30, 1e30, 1e-100, 1e-160, 1e-300, 2.0**-100])] * 3))
    if draw(st.booleans()):
        scales = (scales[0],) * 3  # uniform
    pose = np.eye(4)
    pose[:3, :3] = rotation @ np.diag(scales)
    pose[:3, 3] = rng.uniform(-1.0, 1.0, 3) * draw(st.sampled_from([0.0, 1.0, 1e-30, 1e20, 1e30]))
    camera = draw(st.sampled_from(["perspective", "orthographic"]))
    frequency = draw(st.sampled_from(["pixel", "face", "vertex"]))
    shading = draw(st.sampled_from(["normal", "lambert", "pbr"]))
    # The inverse-transpose R diag(1 / s), scaled by min |s| (entries <= 1, no overflow).
    normal_matrix = rotation @ np.diag(np.abs(scales).min() / np.array(scales))
    return positions, faces, smooth, pose, normal_matrix, camera, frequency, shading, rng


def _exact_cross(corners: np.ndarray) -> np.ndarray:
    """(c1 - c0) x (c2 - c0) in exact rational arithmetic, rounded once to float64."""
    c = [[Fraction(float(x)) for x in row] for row in corners]
    a = [c[1][k] - c[0][k] for k in range(3)]
    b = [c[2][k] - c[0][k] for k in range(3)]
    return np.array([float(a[1] * b[2] - a[2] * b[1]), float(a[2] * b[0] - a[0] * b[2]),
                     float(a[0] * b[1] - a[1] * b[0])])


def _world_face_normal(normal_matrix: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """The world-space unit normal of a face, float64: its exact model-space cross product,
    scaled by its largest |component|, the (scaled) inverse-transpose applied."""
    n = _exact_cross(corners)
    n = normal_matrix @ (n / np.abs(n).max())
    n = n / np.abs(n).max()
    return n / np.linalg.norm(n)


@settings(max_examples=150, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(_cases())
def test_unit_normals_for_any_mesh_pose_and_camera(case) -> None:
    """Every visible pixel's normal is finite and unit (|n| within 1e-5 of 1); for a mesh without
    vertex normals it is its face's world normal (float64 reference), toward either side."""
    positions, faces, smooth, pose, normal_matrix, camera, frequency, shading, rng = case
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sr.PrecisionWarning)
        normals = None
        if smooth in ("area", "angle"):
            tm = trimesh.Trimesh(positions, faces, process=False)
            normals = vertex_normals(tm, True if smooth == "area" else "angle")
        elif smooth == "given":
            normals = rng.normal(size=(len(positions), 3)) * 10.0 ** rng.uniform(-30, 38, (len(positions), 1))
        mesh = sr.Mesh(positions, faces, normals=normals)
    if normals is not None:
        assert np.isfinite(mesh.normals).all()
    # The camera looks along face 0's normal at a point inside it near its shortest edge, from 3x
    # that edge's length (a face with a corner at 1e30 is seen where its other corners are).
    world = positions @ pose[:3, :3].T + pose[:3, 3]
    assume(np.isfinite(world).all() and np.abs(world).max() < 1e37)
    corners = world[faces[0]]
    i, j, k = min(((0, 1, 2), (1, 2, 0), (2, 0, 1)), key=lambda e: np.linalg.norm(corners[e[1]] - corners[e[0]]))
    e1, e2 = corners[j] - corners[i], corners[k] - corners[i]
    size = float(np.linalg.norm(e1))
    assume(1e-30 < size < 1e36)
    n0 = np.cross(e1 / size, e2 / np.linalg.norm(e2))
    assume(np.linalg.norm(n0) > 1e-6)  # face 0 not edge-on in world space
    n0 /= np.linalg.norm(n0)
    mid = 0.5 * (corners[i] + corners[j])
    eps = min(1.0 / 3.0, 0.25 * size / np.linalg.norm(corners[k] - mid))
    target = (1.0 - eps) * mid + eps * corners[k]
    eye = target + 3.0 * size * n0
    try:
        if camera == "perspective":
            cam = sr.PerspectiveCamera(fov_y=60.0, near=0.5 * size, far=20.0 * size)
        else:
            cam = sr.OrthographicCamera(xmag=2.0 * size, ymag=2.0 * size, near=0.5 * size, far=20.0 * size)
        up = (0.0, 1.0, 0.0) if abs(n0[1]) < 0.9 else (1.0, 0.0, 0.0)
        cam.look_at(eye, target, up=up)
        scene = sr.Scene()
        scene.add(mesh, pose=pose)
    except ValueError:
        assume(False)
    f = sr.Renderer(24, 24).render(scene, cam, ("normal", "triangle_id", "mask"), cull="none",
                                   shading=shading, frequency=frequency)
    assert np.isfinite(f.normal).all()
    assume(f.mask.any())
    got = f.normal[f.mask].astype(np.float64)
    lengths = np.linalg.norm(got, axis=1)
    assert np.abs(lengths - 1.0).max() <= 1e-5, (lengths.min(), lengths.max())
    if normals is None:  # flat: each pixel has its face's normal (of the side the camera sees)
        ids = f.triangle_id[f.mask]
        for t in np.unique(ids):
            want = _world_face_normal(normal_matrix, positions[faces[t]])
            np.testing.assert_allclose(np.abs(got[ids == t] @ want), 1.0, atol=1e-5)
