"""Renderer outputs checked against analytic geometry: depth, ids, shading, buffers, determinism
and argument validation."""
from __future__ import annotations

import gc
import inspect
import math
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import trimesh

import softrast as sr
from conftest import (
    ALL_OUTPUTS,
    icosphere,
    look_at_gl,
    pixel_rays_view,
    render,
    scene_of,
    view_to_window_persp,
    window_to_view_persp,
)

_DTYPES = {"color": (np.uint8, 3), "depth": (np.float32, 0), "mask": (np.bool_, 0),
           "normal": (np.float32, 3), "triangle_id": (np.int32, 0), "instance_id": (np.int32, 0),
           "coverage": (np.uint32, 0), "radiance": (np.float32, 3), "barycentric": (np.float32, 3),
           "uv": (np.float32, 2), "position": (np.float32, 3), "ray_depth": (np.float32, 0),
           "alpha": (np.float32, 0)}


def _plane_through_window_points(xy_window, plane_n, plane_d, w, h, fov):
    """View-space points on the plane n . p = d whose projections are exactly ``xy_window``."""
    rays = window_to_view_persp(xy_window, 1.0, w, h, fov)  # depth-1 points = rays with z = -1
    t = plane_d / (rays @ plane_n)
    assert (t > 0).all()
    return rays * t[:, None]


# --------------------------------------------------------------------------------------------
# 3. Analytic depth
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("normal", [(0.0, 0.0, 1.0), (0.2, -0.3, 0.9), (-0.35, 0.15, 0.9)])
def test_perspective_plane_depth_is_exact(normal):
    w, h, fov, d = 64, 48, 55.0, 3.7
    n = np.asarray(normal) / np.linalg.norm(normal)
    plane_d = n @ np.array([0.0, 0.0, -d])  # plane through (0, 0, -d)
    # Corners at window positions that are multiples of 1/256 px => snapping moves nothing.
    corners = np.array([[-8.0, -6.0], [w + 8.0, -6.0], [w + 8.0, h + 6.0], [-8.0, h + 6.0]])
    pos = _plane_through_window_points(corners, n, plane_d, w, h, fov)
    cam = sr.PerspectiveCamera(fov_y=fov, near=0.05, far=100.0)
    cam.pose = np.eye(4)
    faces = np.array([[0, 3, 2], [0, 2, 1]])  # counter-clockwise on screen (y up)
    frame = render(scene_of(sr.Mesh(pos, faces)), cam, w, h, cull="back")
    assert frame.mask.all()
    rays = pixel_rays_view(w, h, fov)
    expected = plane_d / (rays @ n)  # ray p = t * dir with dir_z = -1 => depth = t
    rtol = 1e-6 if normal[:2] == (0.0, 0.0) else 1e-5
    np.testing.assert_allclose(frame.depth, expected, rtol=rtol)
    if normal[:2] == (0.0, 0.0):
        np.testing.assert_allclose(frame.depth, d, rtol=1e-6)


def test_perspective_plane_depth_exact_with_unsnapped_vertices():
    # Vertices at arbitrary (not 1/256 px) positions: the contract still promises the exact ray
    # depth of the surface, not of a plane through the snapped vertices.
    w, h, fov, d = 64, 48, 60.0, 3.7
    n = np.array([0.2, -0.3, 0.9]) / np.linalg.norm([0.2, -0.3, 0.9])
    plane_d = n @ np.array([0.0, 0.0, -d])
    xy = np.array([[-3.1234, -2.3456], [3.3456, -2.1111], [3.2222, 2.4567], [-3.0101, 2.3333]])
    z = (plane_d - xy @ n[:2]) / n[2]
    mesh = sr.Mesh(np.c_[xy, z], [[0, 1, 2], [0, 2, 3]])
    mesh_pos = mesh.positions.astype(np.float64)  # the float32 vertices define the true plane
    n32 = np.cross(mesh_pos[1] - mesh_pos[0], mesh_pos[2] - mesh_pos[0])
    n32 /= np.linalg.norm(n32)
    cam = sr.PerspectiveCamera(fov_y=fov, near=0.05, far=100.0)
    cam.pose = np.eye(4)
    frame = render(scene_of(mesh), cam, w, h, cull="back")
    m = frame.mask
    assert m.sum() > 0.5 * w * h
    rays = pixel_rays_view(w, h, fov)
    expected = (n32 @ mesh_pos[0]) / (rays @ n32)
    np.testing.assert_allclose(frame.depth[m], expected[m], rtol=1e-5)


def _ray_sphere_depth(rays, centre, radius):
    """Depth (-z_view) of the first hit of rays p = t * dir (dir_z = -1) with a sphere, or nan."""
    b = rays @ centre
    a = np.einsum("...k,...k", rays, rays)
    disc = b * b - a * (centre @ centre - radius * radius)
    with np.errstate(invalid="ignore"):
        t = (b - np.sqrt(disc)) / a
    return np.where(disc >= 0, t, np.nan)


def test_tessellated_sphere_depth_within_chord_error():
    w, h, fov = 96, 80, 45.0
    radius, centre = 1.0, np.array([0.2, -0.1, -4.0])
    mesh = icosphere(5, radius)
    p = mesh.positions.astype(np.float64)
    f = mesh.faces
    # Largest radial gap of the inscribed polyhedron: r - min distance from centre to a face plane.
    nrm = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    inner = np.min(np.einsum("ij,ij->i", nrm, p[f[:, 0]]))
    delta = radius - inner
    assert 0 < delta < 1e-3  # subdivision 5: sagitta ~ r (1 - cos(edge/sqrt 3)) ~ 2e-4 r
    cam = sr.PerspectiveCamera(fov_y=fov, near=0.05, far=100.0)
    cam.pose = np.eye(4)
    pose = np.eye(4)
    pose[:3, 3] = centre
    scene = sr.Scene()
    scene.add(mesh, pose=pose)
    frame = render(scene, cam, w, h, cull="back")

    rays = pixel_rays_view(w, h, fov)
    d_outer = _ray_sphere_depth(rays, centre, radius)
    d_inner = _ray_sphere_depth(rays, centre, inner)
    # Convex hull containing ball(inner) and inside ball(r) => entry depth in [d_outer, d_inner].
    # Snapping (<= 1/512 px per axis) adds |grad_px depth| * sqrt(2)/512; restrict to hits with
    # incidence cos >= 0.3 so that gradient stays moderate, and compute it from the sphere.
    hit_point = rays * d_outer[..., None]
    normal = (hit_point - centre) / radius
    cos_inc = -np.einsum("...k,...k", normal, rays / np.linalg.norm(rays, axis=-1, keepdims=True))
    grad = np.hypot(*np.gradient(d_outer))  # depth change per pixel
    ok = (cos_inc >= 0.3) & np.isfinite(d_inner) & np.isfinite(grad)
    assert ok.sum() > 1500
    tol = 2 * grad * math.sqrt(2) / 512 + 2e-6 * d_outer
    got = frame.depth.astype(np.float64)
    assert (got[ok] >= d_outer[ok] - tol[ok]).all(), np.max(d_outer[ok] - got[ok])
    assert (got[ok] <= d_inner[ok] + tol[ok]).all(), np.max(got[ok] - d_inner[ok])

    # Mask: True wherever the ray hits ball(inner), False wherever it misses ball(r), up to the
    # snapping margin (0.01 px measured as ray distance to the centre, in scene units).
    dist_ray = np.linalg.norm(np.cross(rays, centre), axis=-1) / np.linalg.norm(rays, axis=-1)
    px_size = 2 * np.linalg.norm(centre) * math.tan(math.radians(fov) / 2) / h
    assert frame.mask[dist_ray < inner - 0.01 * px_size].all()
    assert not frame.mask[dist_ray > radius + 0.01 * px_size].any()


def test_orthographic_depth_is_linear_view_z():
    w, h = 64, 48
    xmag, ymag = 2.0, 1.5
    cam = sr.OrthographicCamera(xmag=xmag, ymag=ymag, near=0.5, far=20.0)
    cam.pose = look_at_gl([0.4, 0.3, 5.0], [0.4, 0.3, 0.0])  # pure translation (0.4, 0.3, 5)
    # Tilted plane z_world = 0.3 x - 0.5 y - 1 over a quad larger than the view.
    xy = np.array([[-4.0, -4.0], [4.0, -4.0], [4.0, 4.0], [-4.0, 4.0]]) + [0.4, 0.3]
    z = 0.3 * xy[:, 0] - 0.5 * xy[:, 1] - 1.0
    mesh = sr.Mesh(np.c_[xy, z], [[0, 1, 2], [0, 2, 3]])
    frame = render(scene_of(mesh), cam, w, h, cull="back")
    assert frame.mask.all()
    jj, ii = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    x_view = (2 * jj / w - 1) * xmag
    y_view = (1 - 2 * ii / h) * ymag
    x_world, y_world = x_view + 0.4, y_view + 0.3
    depth = 5.0 - (0.3 * x_world - 0.5 * y_world - 1.0)
    np.testing.assert_allclose(frame.depth, depth, rtol=2e-6)


def _facing_quad(size):
    return sr.Mesh(np.array([[-size, -size, 0], [size, -size, 0], [size, size, 0], [-size, size, 0.0]]),
                   [[0, 1, 2], [0, 2, 3]])


@pytest.mark.parametrize("dist", [(1000.0, 1000.5), (1e5, 1.0001e5)])
@pytest.mark.parametrize("near_first", [True, False])
def test_extreme_near_far_ratio_keeps_depth_order(dist, near_first):
    w, h = 48, 40
    cam = sr.PerspectiveCamera(fov_y=45.0, near=1e-3, far=1e6)
    cam.pose = np.eye(4)
    quad = _facing_quad(2.0 * dist[1])
    scene = sr.Scene()
    order = [(dist[0], 11), (dist[1], 22)] if near_first else [(dist[1], 22), (dist[0], 11)]
    for d, iid in order:
        pose = np.eye(4)
        pose[2, 3] = -d
        scene.add(quad, pose=pose, instance_id=iid)
    frame = render(scene, cam, w, h, outputs=("depth", "instance_id", "coverage"))
    assert (frame.coverage == 2).all()
    assert (frame.instance_id == 11).all()
    np.testing.assert_allclose(frame.depth, dist[0], rtol=1e-6)


def test_far_from_origin_renders_like_origin():
    w, h = 64, 48
    mesh = icosphere(3, 0.8)
    results = []
    for offset in (np.zeros(3), np.array([1e6, -1e6, 1e6])):
        pose = np.eye(4)
        pose[:3, 3] = offset
        scene = sr.Scene()
        scene.add(mesh, pose=pose)
        cam = sr.PerspectiveCamera(fov_y=50.0, near=0.05, far=100.0)
        cam.look_at(offset + [0.7, 0.5, 2.5], offset + [0.05, -0.02, 0.0])
        results.append(render(scene, cam, w, h, outputs=("depth", "mask", "coverage")))
    a, b = results
    assert a.mask.sum() > 300
    np.testing.assert_array_equal(a.coverage, b.coverage)
    np.testing.assert_array_equal(a.mask, b.mask)
    np.testing.assert_allclose(b.depth, a.depth, rtol=1e-5)


# --------------------------------------------------------------------------------------------
# 6. Buffers: zero-copy, ownership, independence
# --------------------------------------------------------------------------------------------

def _sphere_scene():
    scene = sr.Scene()
    pose = np.eye(4)
    pose[:3, 3] = [0.1, 0.0, -3.0]
    scene.add(icosphere(2), pose=pose, instance_id=5)
    return scene


def _origin_cam(fov=50.0):
    cam = sr.PerspectiveCamera(fov_y=fov, near=0.05, far=100.0)
    cam.pose = np.eye(4)
    return cam


def test_output_arrays_shapes_dtypes_and_ownership():
    w, h = 40, 30
    r = sr.Renderer(w, h)
    frame = r.render(_sphere_scene(), _origin_cam(), outputs=ALL_OUTPUTS)
    arrays = {name: getattr(frame, name) for name in ALL_OUTPUTS}
    for name, arr in arrays.items():
        dtype, ch = _DTYPES[name]
        assert arr.dtype == dtype, name
        assert arr.shape == ((h, w, ch) if ch else (h, w)), name
        assert arr.flags.c_contiguous and arr.flags.writeable, name
        assert arr.base is not None, name  # a view of C++ memory, not a copy
        assert arr.ctypes.data % 64 == 0, name  # starts on a cache line (threads share no line)
    names = list(arrays)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            assert not np.shares_memory(arrays[a], arrays[b]), (a, b)
    saved = {k: v.copy() for k, v in arrays.items()}
    del r, frame
    gc.collect()
    for k in arrays:
        np.testing.assert_array_equal(arrays[k], saved[k])
    arrays["depth"][:] = 7.0  # writeable and really ours
    assert (arrays["depth"] == 7.0).all()


def test_second_render_does_not_touch_first():
    w, h = 40, 30
    r = sr.Renderer(w, h)
    first = r.render(_sphere_scene(), _origin_cam(), outputs=ALL_OUTPUTS)
    saved = {k: getattr(first, k).copy() for k in ALL_OUTPUTS}
    second = r.render(scene_of(_facing_quad(50.0)), _origin_cam(70.0), outputs=ALL_OUTPUTS,
                      cull="none", background=(1.0, 1.0, 1.0))
    for k in ALL_OUTPUTS:
        np.testing.assert_array_equal(getattr(first, k), saved[k], err_msg=k)
        assert not np.shares_memory(getattr(first, k), getattr(second, k)), k


@pytest.mark.parametrize("outputs", [("depth",), ("mask", "coverage"), ("color", "triangle_id", "normal")])
def test_only_requested_outputs_exist(outputs):
    frame = render(_sphere_scene(), _origin_cam(), 32, 24, outputs=outputs)
    for name in ALL_OUTPUTS:
        assert (getattr(frame, name) is None) == (name not in outputs), name


# --------------------------------------------------------------------------------------------
# 7. Determinism
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("which", ["spot", "sphere"])
def test_deterministic_across_runs_and_thread_counts(which, spot):
    w, h = 150, 110  # several 64 px tiles, partial tiles at the borders
    scene = sr.Scene()
    if which == "spot":
        scene.add(spot, instance_id=3)
        cam = sr.PerspectiveCamera(fov_y=40.0, near=0.05, far=100.0)
        cam.look_at([1.6, 0.9, 2.2], [0.0, 0.2, 0.0])
    else:
        scene.add(icosphere(4), instance_id=1)
        pose = np.eye(4)
        pose[:3, 3] = [0.8, 0.3, 0.5]
        scene.add(icosphere(3, 0.7), pose=pose, instance_id=2)  # intersects the first sphere
        cam = sr.PerspectiveCamera(fov_y=50.0, near=0.05, far=100.0)
        cam.look_at([0.5, 0.4, 3.0], [0.0, 0.0, 0.0])
    reference = None
    for threads in (1, 2, 3, 8, 1):
        for _ in range(2):
            frame = render(scene, cam, w, h, threads=threads, cull="none")
            got = {k: getattr(frame, k).tobytes() for k in ALL_OUTPUTS}
            if reference is None:
                reference = got
                assert np.frombuffer(got["mask"], bool).any()
            for k in ALL_OUTPUTS:
                assert got[k] == reference[k], f"{k} differs with threads={threads}"


@pytest.mark.parametrize("simd", [True, False])
def test_vertex_order_does_not_change_any_output(simd):
    """Vertices permuted (faces remapped, in the same order): every output bit for bit the same.

    Setup and shading fetch vertices by index ahead of use; this pins that the order they sit in
    decides speed only. Vertex normals and colours (both fetched), and a camera inside the
    sphere's bounding box so that near-plane clipping runs too."""
    m = trimesh.creation.icosphere(subdivisions=4)
    rng = np.random.default_rng(5)
    positions, faces = np.asarray(m.vertices), np.asarray(m.faces)
    normals, colors = np.asarray(m.vertex_normals), rng.random((len(positions), 4))
    order = rng.permutation(len(positions))
    remap = np.empty(len(order), np.int64)
    remap[order] = np.arange(len(order))
    meshes = [sr.Mesh(positions, faces, normals=normals, colors=colors),
              sr.Mesh(positions[order], remap[faces], normals=normals[order], colors=colors[order])]
    cam = sr.PerspectiveCamera(fov_y=70.0, near=0.4, far=100.0)
    cam.look_at([0.2, 0.3, 1.25], [0.0, 0.0, 0.0])  # the near plane cuts the sphere
    frames = []
    for mesh in meshes:
        scene = sr.Scene()
        scene.add(mesh, instance_id=4)
        r = sr.Renderer(160, 120, threads=2, simd=simd)
        frames.append([r.render(scene, cam, outputs=ALL_OUTPUTS, cull=cull, shading_path=path)
                       for cull in ("back", "none") for path in ("forward", "deferred")])
    clipped = frames[0][2]  # cull="none": the inside of the sphere behind the cut
    assert clipped.mask.all() and clipped.depth.min() < 0.41
    for a, b in zip(*frames):
        assert a.mask.any()
        for k in ALL_OUTPUTS:
            assert np.array_equal(getattr(a, k), getattr(b, k)), k


# --------------------------------------------------------------------------------------------
# 8. Bad input
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("w,h,name", [(0, 10, "width"), (10, 0, "height"), (-5, 10, "width"),
                                      (10, -1, "height"), (100000, 100000, "width|height"),
                                      (10, 10**12, "height")])
def test_bad_image_size(w, h, name):
    with pytest.raises(ValueError, match=name):
        sr.Renderer(w, h)


def test_bad_image_size_types():
    with pytest.raises(TypeError):
        sr.Renderer(10.5, 10)
    with pytest.raises(TypeError):
        sr.Renderer("10", 10)


@pytest.mark.parametrize("kwargs,name", [
    ({"outputs": ("color", "albedo")}, "output"),
    ({"cull": "sideways"}, "cull"),
    ({"cull": "BACK "}, "cull"),
    ({"shading": "toon"}, "shading"),  # "phong" is a shading model now
])
def test_bad_render_options(kwargs, name):
    with pytest.raises(ValueError, match=name):
        render(_sphere_scene(), _origin_cam(), 16, 16, **kwargs)


def test_bad_render_argument_types():
    r = sr.Renderer(16, 16)
    with pytest.raises(TypeError):
        r.render("scene", _origin_cam())
    with pytest.raises(TypeError):
        r.render(_sphere_scene(), np.eye(4))
    with pytest.raises(TypeError):
        r.render(_origin_cam(), _sphere_scene())


def test_nan_and_inf_poses_rejected():
    for bad in (np.nan, np.inf):
        pose = np.eye(4)
        pose[0, 3] = bad
        with pytest.raises(ValueError):
            scene = sr.Scene()
            scene.add(icosphere(1), pose=pose)
            render(scene, _origin_cam(), 16, 16)
        with pytest.raises(ValueError):
            cam = _origin_cam()
            cam.pose = pose
            render(_sphere_scene(), cam, 16, 16)


def test_empty_scene_renders_background():
    frame = render(sr.Scene(), _origin_cam(), 20, 10, background=(0.2, 0.6, 0.8))
    assert not frame.mask.any() and (frame.depth == 0).all() and (frame.coverage == 0).all()
    assert (frame.triangle_id == -1).all() and (frame.instance_id == -1).all()
    assert (frame.color == [51, 153, 204]).all()


_TRI = np.array([[0, 0, -2.0], [1, 0, -2.0], [0, 1, -2.0]])


@pytest.mark.parametrize("positions,faces,error,name", [
    (np.array([[0, 0, np.nan], [1, 0, 0], [0, 1, 0]]), [[0, 1, 2]], ValueError, "positions"),
    (np.array([[0, 0, np.inf], [1, 0, 0], [0, 1, 0]]), [[0, 1, 2]], ValueError, "positions"),
    (_TRI, [[0, 1, 3]], ValueError, "faces|index"),
    (_TRI, [[0, -1, 2]], ValueError, "faces|index"),
    (_TRI, np.array([[0.0, 1.0, 2.0]]), TypeError, "faces"),
    (_TRI[:, :2], [[0, 1, 2]], ValueError, "positions"),
    (_TRI, [[0, 1, 2, 0]], ValueError, "faces"),
    (_TRI, [0, 1, 2], ValueError, "faces"),
    (np.zeros((0, 3)), np.zeros((0, 3), int), ValueError, "empty|positions"),
    (_TRI, np.zeros((0, 3), int), ValueError, "empty|faces"),
    (_TRI, np.array([[0, 1, 2**32 + 2]], np.int64), ValueError, "faces|index"),  # no int32 wrap
    (_TRI, np.array([[0, 1, 2**31]], np.int64), ValueError, "faces|index"),
])
def test_bad_mesh_never_reaches_the_renderer(positions, faces, error, name):
    with pytest.raises(error, match=name):
        mesh = sr.Mesh(positions, faces)
        render(scene_of(mesh), _origin_cam(), 16, 16)


@pytest.mark.parametrize("make", [
    lambda: sr.PerspectiveCamera(near=0.0),
    lambda: sr.PerspectiveCamera(near=-1.0),
    lambda: sr.PerspectiveCamera(near=1.0, far=1.0),
    lambda: sr.PerspectiveCamera(near=2.0, far=1.0),
    lambda: sr.OrthographicCamera(near=0.0),
    lambda: sr.OrthographicCamera(near=1.0, far=0.5),
    lambda: sr.PerspectiveCamera().look_at([1, 2, 3], [1, 2, 3]),
    lambda: sr.OrthographicCamera().look_at([0, 0, 0], [0, 0, 0]),
])
def test_bad_camera(make):
    with pytest.raises(ValueError):
        make()


def test_dangerous_inputs_do_not_crash_the_interpreter():
    # In a subprocess with a 3 GB address-space cap: a crash shows up as a signal, not as a
    # killed test run; a framebuffer over MAX_FRAMEBUFFER_BYTES must be refused before allocation.
    # Under AddressSanitizer (.ci/sanitize sets SOFTRAST_ASAN) an address-space cap cannot work:
    # ASan reserves terabytes of shadow memory at start-up and every later mmap would fail. ASan's
    # own limits give the same cap there: a larger allocation or resident set aborts the child.
    env = dict(os.environ)
    if env.get("SOFTRAST_ASAN"):
        env["ASAN_OPTIONS"] = (env.get("ASAN_OPTIONS", "") +
                               ":max_allocation_size_mb=3072:hard_rss_limit_mb=3072")
    code = textwrap.dedent("""
        import os, resource, numpy as np, softrast as sr
        if not os.environ.get("SOFTRAST_ASAN"):
            resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))
        tri = np.array([[0, 0, -2.0], [1, 0, -2.0], [0, 1, -2.0]])
        cam = sr.PerspectiveCamera(); cam.pose = np.eye(4)
        outcomes = []
        for faces in ([[0, 1, 2**31 - 1]], [[0, 1, 2**40]], [[0, 1, -2**31]], [[2**63 - 1, 0, 1]]):
            try:
                sr.Mesh(tri, np.array(faces, np.int64))
                outcomes.append("accepted")
            except ValueError:
                outcomes.append("ValueError")
        side = sr.MAX_IMAGE_SIDE
        try:
            r = sr.Renderer(side, side)
            r.render(sr.Scene(), cam, outputs=("color", "depth", "mask", "normal", "triangle_id",
                                                "instance_id", "coverage"))
            outcomes.append("allocated")
        except ValueError as exc:
            outcomes.append("ValueError")
        print(outcomes)
    """)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env=env)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(["ValueError"] * 5), proc.stdout + proc.stderr


# --------------------------------------------------------------------------------------------
# 9. ids and mask consistency
# --------------------------------------------------------------------------------------------

def _ray_cast(rays, tris):
    """Möller-Trumbore: for rays from the origin (view space), first hit per ray over triangles
    (m, 3, 3). Returns (t (h, w) with inf for misses, face index (h, w) or -1)."""
    d = rays.reshape(-1, 3)
    v0, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    best_t = np.full(len(d), np.inf)
    best_f = np.full(len(d), -1)
    for start in range(0, len(tris), 256):
        sl = slice(start, start + 256)
        pvec = np.cross(d[:, None, :], e2[None, sl])
        det = np.einsum("rfk,fk->rf", pvec, e1[sl])
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            tvec = -v0[None, sl]
            u = np.einsum("fk,rfk->rf", tvec[0], pvec) * inv
            qvec = np.cross(tvec, e1[None, sl])
            v = np.einsum("rk,rfk->rf", d, np.broadcast_to(qvec, pvec.shape)) * inv
            t = np.einsum("fk,fk->f", e2[sl], qvec[0])[None, :] * inv
        hit = (det > 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)  # det = -d . n > 0: front
        t = np.where(hit, t, np.inf)
        k = np.argmin(t, axis=1)
        tk = t[np.arange(len(d)), k]
        better = tk < best_t
        best_t[better] = tk[better]
        best_f[better] = k[better] + start
    return best_t.reshape(rays.shape[:2]), best_f.reshape(rays.shape[:2])


def test_triangle_and_instance_ids_match_ray_cast():
    w, h, fov = 64, 48, 50.0
    meshes = [(icosphere(2, 1.0), [0.5, 0.2, -4.0], 7), (icosphere(2, 1.2), [-0.7, -0.1, -5.0], 3)]
    scene = sr.Scene()
    tris, owner, local, ids = [], [], [], []
    for mesh, centre, iid in meshes:
        pose = np.eye(4)
        pose[:3, 3] = centre
        scene.add(mesh, pose=pose, instance_id=iid)
        p = mesh.positions.astype(np.float64) + centre
        tris.append(p[mesh.faces])
        local.append(np.arange(mesh.num_faces))
        ids.append(np.full(mesh.num_faces, iid))
    tris, local, ids = np.concatenate(tris), np.concatenate(local), np.concatenate(ids)
    frame = render(scene, _origin_cam(fov), w, h, cull="back")
    rays = pixel_rays_view(w, h, fov)
    t, face = _ray_cast(rays, tris)
    hit = face >= 0
    # Ignore centres within 0.01 px of an edge of the hit triangle (snapping may flip those).
    win = view_to_window_persp(tris.reshape(-1, 3), w, h, fov).reshape(-1, 3, 2)
    jj, ii = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    sample = np.stack([jj, ii], -1)
    fw = win[np.where(hit, face, 0)]
    dist = np.full((h, w), np.inf)
    for k in range(3):
        a, b = fw[..., k, :], fw[..., (k + 1) % 3, :]
        e = b - a
        cross = e[..., 0] * (sample[..., 1] - a[..., 1]) - e[..., 1] * (sample[..., 0] - a[..., 0])
        dist = np.minimum(dist, np.abs(cross) / np.linalg.norm(e, axis=-1))
    sure = ~hit | (dist > 0.01)
    assert hit.sum() > 400 and (hit & sure).sum() > 0.9 * hit.sum()
    assert len(np.unique(ids[face[hit & sure]])) == 2  # both instances visible
    np.testing.assert_array_equal(frame.mask[sure], hit[sure])
    np.testing.assert_array_equal(frame.triangle_id[sure & hit], local[face[sure & hit]])
    np.testing.assert_array_equal(frame.instance_id[sure & hit], ids[face[sure & hit]])
    np.testing.assert_allclose(frame.depth[sure & hit], t[sure & hit], rtol=1e-4)
    # Consistency of all the "is something here" signals.
    m = frame.mask
    np.testing.assert_array_equal(m, frame.depth > 0)
    np.testing.assert_array_equal(m, frame.triangle_id >= 0)
    np.testing.assert_array_equal(m, frame.instance_id >= 0)
    np.testing.assert_array_equal(m, frame.coverage > 0)
    np.testing.assert_array_equal(frame.instance_id[~m], -1)
    np.testing.assert_array_equal(frame.normal[~m], 0.0)


def test_mirrored_pose_keeps_outside_as_front_and_normals_follow_the_sphere():
    w, h, fov = 64, 48, 50.0
    centre = np.array([0.0, 0.0, -4.0])
    mesh = icosphere(3)
    for diag in ([1.0, 1.0, 1.0], [-1.0, 1.0, 1.0], [1.0, -1.0, -1.0]):  # the last is a rotation
        pose = np.diag(diag + [1.0])
        pose[:3, 3] = centre
        scene = sr.Scene()
        scene.add(mesh, pose=pose)
        frame = render(scene, _origin_cam(fov), w, h, cull="back")
        m = frame.mask
        assert m.sum() > 300
        np.testing.assert_array_equal(frame.coverage, m.astype(np.uint32))
        # The visible surface is the near half of the sphere (depth < 4), not the far half.
        assert (frame.depth[m] < 4.0).all()
        # Flat face normals are unit and within the face's angular size of the sphere's normal.
        n = frame.normal[m].astype(np.float64)
        np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-5)
        rays = pixel_rays_view(w, h, fov)[m]
        p = rays * frame.depth[m][:, None].astype(np.float64)
        true_n = (p - centre) / np.linalg.norm(p - centre, axis=1, keepdims=True)
        max_edge_angle = 1.2 * 1.1071 / 2**3  # icosahedron edge angle / 2^subdivisions, with margin
        assert (np.einsum("ij,ij->i", n, true_n) > math.cos(max_edge_angle)).all()


# --------------------------------------------------------------------------------------------
# 10. Shading
# --------------------------------------------------------------------------------------------

def _ambient_default():
    p = inspect.signature(sr.Renderer.render).parameters.get("ambient")
    return 0.25 if p is None else float(p.default)


def test_unlit_flat_colour_and_background():
    color = (0.2, 0.45, 0.93)  # *255 = 51, 114.75, 237.15 (no rounding ties)
    scene = sr.Scene()
    pose = np.eye(4)
    pose[:3, 3] = [0.0, 0.0, -3.0]
    scene.add(icosphere(3), pose=pose, color=color)
    # srgb=False: the expected colour is the linear x * 255, rounded (the background is never encoded).
    frame = render(scene, _origin_cam(), 48, 40, shading="unlit", background=(0.2, 0.6, 0.8),
                   srgb=False)
    assert 0 < frame.mask.sum() < frame.mask.size
    assert (frame.color[frame.mask] == [51, 115, 237]).all()
    assert (frame.color[~frame.mask] == [51, 153, 204]).all()


@pytest.mark.parametrize("tilt_deg", [60.0, 30.0, 85.0])
def test_lambert_headlight_follows_cosine(tilt_deg):
    w, h = 32, 32
    ambient = _ambient_default()
    cam = sr.OrthographicCamera(xmag=1.0, ymag=1.0, near=0.5, far=100.0)
    cam.pose = np.eye(4)
    base = np.array([0.9, 0.6, 0.3])
    results = {}
    for angle in (0.0, tilt_deg):
        a = math.radians(angle)
        rot = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
        pose = np.eye(4)
        pose[:3, :3] = rot
        pose[:3, 3] = [0.0, 0.0, -30.0]  # the 15-unit quad stays within near/far at any tilt
        scene = sr.Scene()
        scene.add(_facing_quad(15.0), pose=pose, color=tuple(base))
        # srgb=False: the cosine law is checked on the linear colour (x * 255, rounded).
        frame = render(scene, cam, w, h, shading="lambert", cull="none", srgb=False)
        assert frame.mask.all()
        np.testing.assert_allclose(frame.normal, np.broadcast_to(rot[:, 2], (h, w, 3)), atol=1e-6)
        results[angle] = frame.color.astype(np.float64)
        expected = 255 * base * (ambient + (1 - ambient) * math.cos(a))
        assert np.abs(frame.color - expected).max() <= 0.5 + 1e-3, (angle, frame.color[0, 0], expected)
    assert (results[0.0] > results[tilt_deg]).all()


@pytest.mark.parametrize("camera", ["perspective", "orthographic"])
def test_smooth_lambert_matches_the_interpolated_normal(camera):
    # Smooth shading with one base colour takes its own kernel (dot(n, L) / |n| of the
    # unnormalised interpolated normal); the normal output is interpolated and normalised by the
    # general one. The colour must be the Lambert term of that normal, to rounding.
    ambient = 0.2
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    mesh = sr.Mesh(np.asarray(m.vertices), np.asarray(m.faces), normals=np.asarray(m.vertices))
    pose = np.eye(4)
    pose[:3, :3] = trimesh.transformations.rotation_matrix(0.4, [1.0, 2.0, 0.5])[:3, :3]
    pose[:3, 3] = [0.3, -0.2, -3.0]
    base = np.array([0.9, 0.6, 0.3])
    scene = sr.Scene()
    scene.add(mesh, pose=pose, color=tuple(base))
    if camera == "perspective":
        cam = _origin_cam()
    else:
        cam = sr.OrthographicCamera(xmag=1.4, ymag=1.2, near=0.5, far=100.0)
        cam.pose = np.eye(4)
    # srgb=False: the Lambert term is checked on the linear colour (x * 255, rounded).
    # (normal_kind="shading": the normal the shading read; the default is the exact one)
    frame = render(scene, cam, 96, 80, outputs=("color", "normal", "mask"), ambient=ambient,
                   srgb=False, normal_kind="shading")
    assert frame.mask.sum() > 1000
    n = frame.normal[frame.mask].astype(np.float64)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-5)
    light = np.array([0.0, 0.0, 1.0])  # the headlight, toward the camera (identity pose)
    expected = 255 * base * (ambient + (1 - ambient) * np.maximum(n @ light, 0.0))[:, None]
    got = frame.color[frame.mask].astype(np.float64)
    assert np.abs(got - expected).max() <= 0.5 + 1e-3
    # The normals do vary across faces (the smooth kernel was taken, not the one-normal one).
    assert len(np.unique(frame.color[frame.mask], axis=0)) > 200


@pytest.mark.parametrize("scale", [2.0**-70, 2.0**70])
def test_power_of_two_scaled_scene_renders_the_same_bits(scale):
    # Scaling the mesh's pose and the camera's near/far by a power of two scales every
    # intermediate value exactly: coverage, normals and colour must not change and depth must scale,
    # to the bit. The normal matrix then scales by 1/scale (2^70 or 2^-70), which float world
    # normals only survive because they are computed from the matrix scaled to a largest entry of 1.
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    mesh = sr.Mesh(np.asarray(m.vertices), np.asarray(m.faces), normals=np.asarray(m.vertices))
    frames = []
    for s in (1.0, scale):
        pose = np.diag([s, s, s, 1.0])
        pose[:3, 3] = [0.3 * s, -0.2 * s, -3.0 * s]
        scene = sr.Scene()
        scene.add(mesh, pose=pose, color=(0.9, 0.6, 0.3))
        cam = sr.PerspectiveCamera(fov_y=50.0, near=0.05 * s, far=100.0 * s)
        cam.pose = np.eye(4)
        frames.append(render(scene, cam, 96, 80, outputs=("color", "normal", "depth", "mask")))
    a, b = frames
    assert a.mask.sum() > 1000
    for name in ("mask", "color", "normal"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert np.array_equal(a.depth, (b.depth.astype(np.float64) / scale).astype(np.float32))


def test_flat_lambert_is_constant_per_face():
    # Without vertex normals every pixel of a face has the face's colour, exactly.
    scene = sr.Scene()
    pose = np.eye(4)
    pose[:3, 3] = [0.0, 0.0, -3.0]
    scene.add(icosphere(2), pose=pose, color=(0.8, 0.7, 0.2))
    frame = render(scene, _origin_cam(), 128, 128, outputs=("color", "triangle_id"))
    ids = frame.triangle_id
    for face in np.unique(ids[ids >= 0]):
        assert len(np.unique(frame.color[ids == face], axis=0)) == 1, face


# --------------------------------------------------------------------------------------------
# 11. Singular poses
# --------------------------------------------------------------------------------------------

def _flattening_pose(rot_axis, angle, diag):
    """rotation(angle about rot_axis) @ diag(diag), translated to (0.2, -0.1, -4): world pose."""
    pose = np.eye(4)
    rot = trimesh.transformations.rotation_matrix(angle, rot_axis)[:3, :3]
    pose[:3, :3] = rot @ np.diag(diag)
    pose[:3, 3] = [0.2, -0.1, -4.0]
    return pose, rot


def _sphere_mesh(smooth):
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    return sr.Mesh(np.asarray(m.vertices), np.asarray(m.faces),
                   normals=np.asarray(m.vertices) if smooth else None)


@pytest.mark.parametrize("diag", [[1.0, 1.0, 0.0], [-1.0, 0.7, 0.0], [0.0, 1.3, 0.8]])
@pytest.mark.parametrize("smooth", [False, True])
def test_pose_flattening_a_sphere_gives_the_discs_normal(diag, smooth):
    # A pose with zero scale on one axis flattens the sphere into an ellipse in the plane its
    # rotation gives (normal: the rotated zero axis). Its normal matrix, the inverse-transpose,
    # does not exist (det 0), and every normal came out zero: ambient-only shading. The normals
    # of the flattened surface are defined (the cofactor matrix maps a face's normal to the
    # transformed face's): the disc's normal, on the side the camera sees.
    pose, rot = _flattening_pose([1.0, 2.0, 0.5], 0.5, diag)
    disc_n = rot[:, int(np.flatnonzero(np.asarray(diag) == 0.0)[0])]
    eye = pose[:3, 3] + 3.0 * disc_n  # looking at the disc along its normal: the headlight is n
    cam = sr.PerspectiveCamera(fov_y=50.0, near=0.05, far=100.0).look_at(eye, pose[:3, 3], up=rot[:, 1])
    base = np.array([0.8, 0.6, 0.4])
    scene = sr.Scene()
    scene.add(_sphere_mesh(smooth), pose=pose, color=tuple(base))
    # srgb=False: the full base colour is checked linearly (x * 255, rounded).
    frame = render(scene, cam, 64, 48, cull="none", srgb=False)
    m = frame.mask
    assert m.sum() > 500
    n = frame.normal[m].astype(np.float64)
    assert np.isfinite(frame.normal).all()
    if not smooth:  # flat: every face of the disc has the disc's normal, toward the camera
        np.testing.assert_allclose(n, np.broadcast_to(disc_n, n.shape), atol=1e-6)
        # n . l = 1: the full base colour (ambient + (1 - ambient) * 1), to rounding.
        assert np.abs(frame.color[m] - 255 * base).max() <= 0.5 + 1e-3
    else:
        # Vertex normals become +-n (or 0 where the sphere's normal lies in the disc's plane,
        # on its rim); interpolated, every pixel's normal is +-n except on such a vertex's edge.
        nonzero = np.linalg.norm(n, axis=1) > 0.0
        assert nonzero.mean() > 0.99
        np.testing.assert_allclose(np.abs(n[nonzero] @ disc_n), 1.0, atol=1e-6)


def test_singular_pose_renders_as_its_near_singular_limit():
    # Scale 1e-30 on an axis worked (the inverse-transpose is finite); scale 0 must give what
    # the limit does: the same pixels, colour and depth, and the same normals to rounding.
    frames = []
    for z in (1e-30, 0.0):
        pose, rot = _flattening_pose([0.3, -1.0, 0.2], 0.7, [1.0, 1.0, z])
        cam = sr.PerspectiveCamera(fov_y=50.0).look_at(pose[:3, 3] + 3.0 * rot[:, 2] + rot[:, 0],
                                                       pose[:3, 3])
        scene = sr.Scene()
        scene.add(_sphere_mesh(False), pose=pose, color=(0.8, 0.6, 0.4))
        frames.append(render(scene, cam, 64, 48, cull="none"))
    a, b = frames
    assert a.mask.sum() > 300 and (a.color[a.mask] > 0.5 * 255 * 0.4).all()  # lit, not ambient-only
    for name in ("mask", "color", "depth", "triangle_id", "coverage"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    np.testing.assert_allclose(a.normal, b.normal, atol=1e-6)


@pytest.mark.parametrize("diag", [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
@pytest.mark.parametrize("smooth", [False, True])
def test_pose_of_rank_one_or_zero_is_well_defined(diag, smooth):
    # Rank <= 1: the mesh collapses to a segment or a point; no face has a normal (the cofactor
    # matrix is 0) and none has an area, in the world or on screen. Whatever the snapped screen
    # positions cover, outputs are finite, normals are 0 or unit, colour is the ambient term.
    for rot_axis in ([0.0, 0.0, 1.0], [1.0, 2.0, 0.5]):
        pose, _ = _flattening_pose(rot_axis, 0.6, diag)
        scene = sr.Scene()
        scene.add(_sphere_mesh(smooth), pose=pose, color=(0.8, 0.6, 0.4))
        frame = render(scene, _origin_cam(), 64, 48, cull="none", ambient=0.5)
        m = frame.mask
        assert np.isfinite(frame.normal).all() and np.isfinite(frame.depth).all()
        np.testing.assert_array_equal(frame.normal[~m], 0.0)
        np.testing.assert_array_equal(frame.normal[m], 0.0)
        assert (frame.color[m] == [102, 77, 51]).all()  # 0.5 * (0.8, 0.6, 0.4) * 255, rounded
        assert (frame.color[~m] == 0).all()


# --------------------------------------------------------------------------------------------
# 12. Every argument checked by name
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, error, name", [
    ({"background": None}, TypeError, "background"),  # was: 'NoneType' object is not iterable
    ({"background": "abc"}, TypeError, "background"),  # was: could not convert string to float
    ({"background": ("0.1", "0.2", "0.3")}, TypeError, "background"),  # numeric strings
    ({"background": (True, False, False)}, TypeError, "background"),  # bools are not numbers
    ({"background": (0.1, 0.2, 0.3j)}, TypeError, "background"),
    ({"background": (0.1, 0.2)}, ValueError, "background"),
    ({"background": (0.1, 0.2, 1.5)}, ValueError, "background"),
    ({"background": (0.1, 0.2, np.nan)}, ValueError, "background"),
    ({"outputs": None}, TypeError, "outputs"),  # was: 'NoneType' object is not iterable
    ({"outputs": 5}, TypeError, "outputs"),  # was: 'int' object is not iterable
    ({"outputs": b"color"}, TypeError, "outputs"),
    ({"outputs": ("color", 5)}, TypeError, "outputs"),
    ({"outputs": ()}, ValueError, "outputs"),
    ({"ambient": None}, TypeError, "ambient"),  # was: float() argument must be ...
    ({"ambient": np.array([0.5])}, TypeError, "ambient"),  # was: a NumPy DeprecationWarning
    ({"ambient": 0.5 + 0j}, TypeError, "ambient"),  # was: float() argument must be ...
    ({"ambient": True}, TypeError, "ambient"),  # was: accepted as 1.0
    ({"ambient": "0.5"}, TypeError, "ambient"),  # was: accepted as 0.5
    ({"ambient": np.nan}, ValueError, "ambient"),
    ({"ambient": 10**400}, ValueError, "ambient"),  # was: OverflowError
    ({"cull": None}, TypeError, "cull"),
    ({"cull": ["back"]}, TypeError, "cull"),
    ({"shading": np.array(["lambert"])}, TypeError, "shading"),  # was: ambiguous truth value
    ({"shading_path": 1}, TypeError, "shading_path"),
])
def test_bad_render_option_raises_naming_it(kwargs, error, name):
    with pytest.raises(error, match=f"^{name}"):
        render(_sphere_scene(), _origin_cam(), 16, 16, **kwargs)


def test_render_options_accept_numpy_and_plain_numbers():
    reference = render(_sphere_scene(), _origin_cam(), 16, 16, background=(0.2, 0.4, 0.6), ambient=0.5)
    for background, ambient in [(np.array([0.2, 0.4, 0.6]), np.float32(0.5)),
                                ([np.float64(0.2), 0.4, 0.6], np.array(0.5)),
                                ((0.2, 0.4, 0.6), 0.5)]:
        frame = render(_sphere_scene(), _origin_cam(), 16, 16, background=background, ambient=ambient)
        for name in ALL_OUTPUTS:
            assert np.array_equal(getattr(frame, name), getattr(reference, name)), name
    # One name, a list or an array of names; a name given twice is one output.
    for outputs in ("depth", ["depth"], np.array(["depth"]), ("depth", "depth")):
        frame = sr.Renderer(16, 16).render(_sphere_scene(), _origin_cam(), outputs=outputs)
        assert frame.outputs == ("depth",) and np.array_equal(frame.depth, reference.depth)


@pytest.mark.parametrize("kwargs, error, name", [
    ({"threads": True}, TypeError, "threads"),  # was: ValueError
    ({"threads": 1.0}, TypeError, "threads"),
    ({"threads": "2"}, TypeError, "threads"),
    ({"threads": -1}, ValueError, "threads"),
    ({"width": True}, TypeError, "width"),
    ({"height": np.float64(16)}, TypeError, "height"),
    ({"width": None}, TypeError, "width"),
])
def test_bad_renderer_argument_raises_naming_it(kwargs, error, name):
    args = {"width": 16, "height": 16, **kwargs}
    with pytest.raises(error, match=f"^{name}"):
        sr.Renderer(**args)
    assert sr.Renderer(np.int64(16), np.int32(8), threads=np.int64(1)).threads == 1


def test_zero_vertex_normals_fall_back_to_the_face_normal():
    """A pose can collapse a vertex normal to zero (diag(1, 1, 0) maps normals through its
    cofactor diag(0, 0, 1), so (1, 0, 0) becomes 0) while the face keeps a normal: shading and
    the normal output then use the face normal instead of losing the orientation."""
    mesh = sr.Mesh(np.array([[-1.0, -1, 0], [1, -1, 0], [0, 1, 0]]), np.array([[0, 1, 2]]),
                   normals=np.tile([1.0, 0.0, 0.0], (3, 1)))
    scene = sr.Scene()
    scene.add(mesh, pose=np.diag([1.0, 1.0, 0.0, 1.0]))
    cam = sr.PerspectiveCamera(fov_y=60.0)
    cam.look_at((0, 0, 3), (0, 0, 0))
    frame = sr.Renderer(32, 32).render(scene, cam, outputs=("normal", "radiance", "mask"),
                                       shading="lambert", ambient=0.25)
    assert frame.mask.sum() > 50
    np.testing.assert_array_equal(frame.normal[frame.mask], np.tile([0.0, 0.0, 1.0], (frame.mask.sum(), 1)))
    # Lambert under the headlight, facing the camera: base * (0.25 + 0.75 * n.l) with n.l ~ 1.
    np.testing.assert_allclose(frame.radiance[frame.mask], 0.8, atol=1e-6)
