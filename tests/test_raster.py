"""Rasterization rules through the public API: watertightness, the top-left fill rule, projection
against cv2.projectPoints, and clipping. Expected pixel sets come from exact geometry or from the
independent NumPy rasterizer in softrast.reference.raster, never from earlier renders."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
import trimesh

import softrast as sr
from softrast.reference import raster as ref
from conftest import (
    icosphere,
    look_at_gl,
    pixel_mesh,
    pixel_ortho,
    pixel_rays_view,
    random_rotation,
    render,
    scene_of,
)

_GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])


def test_subpixel_bits_is_eight():
    assert sr._core.SUBPIXEL_BITS == ref.SUBPIXEL_BITS == 8


# --------------------------------------------------------------------------------------------
# 1. Watertightness
# --------------------------------------------------------------------------------------------

def _grid(rng, nx, ny, x0, x1, y0, y1, mode):
    """Triangulated grid over the rectangle [x0, x1] x [y0, y1] (window px) with a random diagonal
    per quad. Boundary vertices stay on the outline, so the outline is exactly the rectangle.

    mode "jitter": interior vertices jittered by up to 0.3 cell, quantized to 1/256 px
                   (exactly representable => snapping is exact in the renderer and reference);
    mode "centres": every vertex on a pixel centre (x, y = k + 0.5);
    mode "lines": every vertex on a pixel-centre line in x, free (1/256 px) in y.
    """
    xs, ys = np.linspace(x0, x1, nx), np.linspace(y0, y1, ny)
    gx, gy = np.meshgrid(xs, ys)
    cell = np.array([(x1 - x0) / (nx - 1), (y1 - y0) / (ny - 1)])
    jit = rng.uniform(-0.3, 0.3, size=(ny, nx, 2)) * cell
    jit[:, [0, -1], 0] = 0.0  # left/right columns stay on x = x0 / x1
    jit[[0, -1], :, 1] = 0.0  # top/bottom rows stay on y = y0 / y1
    if mode == "centres":
        jit = np.round(jit)  # integer offsets keep points on centres
    elif mode == "lines":
        jit[..., 0] = np.round(jit[..., 0])
        jit[..., 1] = np.round(jit[..., 1] * 256) / 256
    else:
        jit = np.round(jit * 256) / 256
    xy = (np.stack([gx, gy], -1) + jit).reshape(-1, 2)
    faces = []
    for r in range(ny - 1):
        for c in range(nx - 1):
            a, b, cc, d = r * nx + c, r * nx + c + 1, (r + 1) * nx + c + 1, (r + 1) * nx + c
            faces += [[a, b, cc], [a, cc, d]] if rng.random() < 0.5 else [[a, b, d], [b, cc, d]]
    faces = np.array(faces)
    area = ref.signed_area2_fixed(ref.snap(xy), faces)
    assert (area >= 0).all()  # the construction itself: no folded cells (zero-area ones are fine)
    return xy, faces


@pytest.mark.parametrize("mode,outline", [
    ("jitter", (3.125, 60.6875, 2.75, 45.0390625)),
    ("jitter", (-7.0, 71.0, -5.5, 55.25)),       # outline beyond the image
    ("centres", (2.5, 59.5, 1.5, 43.5)),
    ("lines", (0.5, 63.5, 3.5, 44.5)),
])
@pytest.mark.parametrize("flip", [False, True])
def test_planar_grid_is_watertight(rng, mode, outline, flip):
    w, h = 64, 48
    x0, x1, y0, y1 = outline
    nx, ny = (20, 15) if mode == "jitter" else (20, 14)
    if mode != "jitter":  # integer cell sizes keep centres on centres
        nx = int(round(x1 - x0)) // 3 + 1
        ny = int(round(y1 - y0)) // 3 + 1
        x1, y1 = x0 + 3 * (nx - 1), y0 + 3 * (ny - 1)
    xy, faces = _grid(rng, nx, ny, x0, x1, y0, y1, mode)
    if flip:
        faces = faces[:, ::-1]
    frame = render(scene_of(pixel_mesh(xy, faces, w, h)), pixel_ortho(w, h), w, h, cull="none")

    # Exact expectation from the outline: centre (j+.5, i+.5) covered iff x0 <= x < x1 and
    # y0 <= y < y1 (left and top edges are in, right and bottom edges out).
    cx = np.arange(w) + 0.5
    cy = np.arange(h) + 0.5
    inside = ((cy >= y0) & (cy < y1))[:, None] & ((cx >= x0) & (cx < x1))[None, :]
    np.testing.assert_array_equal(frame.coverage, inside.astype(np.uint32))
    np.testing.assert_array_equal(frame.mask, inside)
    # Each covered centre belongs to exactly one triangle: the one the reference rasterizer picks.
    cov_ref, owner_ref = ref.rasterize(xy, faces, w, h)
    np.testing.assert_array_equal(cov_ref, inside)  # the reference agrees with the outline
    np.testing.assert_array_equal(frame.triangle_id, owner_ref)


def _sphere_cameras():
    persp = lambda: sr.PerspectiveCamera(fov_y=50.0, near=0.1, far=50.0)  # noqa: E731
    ortho = lambda: sr.OrthographicCamera(xmag=1.6, ymag=1.2, near=0.1, far=50.0)  # noqa: E731
    return [("persp", persp), ("ortho", ortho)]


@pytest.mark.parametrize("subdivisions", [2, 3, 4])
@pytest.mark.parametrize("cam_name,make_cam", _sphere_cameras())
def test_closed_icosphere_covers_silhouette_once(rng, subdivisions, cam_name, make_cam):
    w, h = 80, 60
    mesh = icosphere(subdivisions)
    for _ in range(3):
        direction = rng.normal(size=3)
        eye = direction / np.linalg.norm(direction) * rng.uniform(2.6, 4.0)
        target = rng.uniform(-0.3, 0.3, size=3)
        cam = make_cam()
        cam.pose = look_at_gl(eye, target, up=rng.normal(size=3))
        scene = scene_of(mesh)
        back = render(scene, cam, w, h, cull="back")
        # Convex and closed => the front faces tile the silhouette exactly once.
        assert 0.05 * w * h < back.mask.sum() < w * h
        np.testing.assert_array_equal(back.coverage, back.mask.astype(np.uint32))
        # ... and so do the back faces: every covered centre is covered exactly twice.
        both = render(scene, cam, w, h, cull="none")
        np.testing.assert_array_equal(both.coverage, 2 * back.mask.astype(np.uint32))
        front_only = render(scene, cam, w, h, cull="front")
        np.testing.assert_array_equal(front_only.coverage, back.mask.astype(np.uint32))


# --------------------------------------------------------------------------------------------
# 2. Fill rule (window coordinates = world units in pixel_ortho; 32 x 32 => xmag = 16 exact)
# --------------------------------------------------------------------------------------------

_FILL_TRIANGLES = {
    # right isosceles triangles, right angle at each corner: horizontal top/bottom edges,
    # vertical left/right edges and diagonals of slope +-1 facing all four directions
    "corner_tl": [(4.5, 4.5), (12.5, 4.5), (4.5, 12.5)],
    "corner_tr": [(12.5, 4.5), (12.5, 12.5), (4.5, 4.5)],
    "corner_br": [(12.5, 12.5), (4.5, 12.5), (12.5, 4.5)],
    "corner_bl": [(4.5, 12.5), (4.5, 4.5), (12.5, 12.5)],
    "flat_top": [(3.5, 5.5), (15.5, 5.5), (9.5, 11.5)],
    "flat_bottom": [(3.5, 11.5), (9.5, 5.5), (15.5, 11.5)],
    "point_left": [(3.5, 8.5), (13.5, 3.5), (13.5, 13.5)],
    "point_right": [(13.5, 8.5), (3.5, 3.5), (3.5, 13.5)],
    "slope_half": [(2.5, 2.5), (14.5, 8.5), (6.5, 16.5)],  # slopes 1/2, -2, ... through centres
    "sliver": [(1.5, 1.5), (21.5, 11.5), (23.5, 12.5)],
    "one_pixel": [(5.5, 5.5), (6.5, 5.5), (5.5, 6.5)],
    "half_px_vertices": [(2.0, 3.0), (17.0, 9.5), (7.5, 20.0)],
    "degenerate_row": [(2.5, 2.5), (12.5, 2.5), (6.5, 2.5)],  # zero area along pixel centres
    "degenerate_diagonal": [(2.5, 2.5), (9.5, 9.5), (4.5, 4.5)],
}


@pytest.mark.parametrize("name", sorted(_FILL_TRIANGLES))
@pytest.mark.parametrize("cull", ["none", "back", "front"])
def test_fill_rule_matches_reference(name, cull):
    w = h = 32
    xy = np.array(_FILL_TRIANGLES[name], dtype=np.float64)
    for faces in (np.array([[0, 1, 2]]), np.array([[0, 2, 1]])):  # both windings
        frame = render(scene_of(pixel_mesh(xy, faces, w, h)), pixel_ortho(w, h), w, h, cull=cull)
        expected, _ = ref.rasterize(xy, faces, w, h, cull=cull)
        if name.startswith("degenerate"):
            assert expected.sum() == 0
        np.testing.assert_array_equal(frame.coverage, expected, err_msg=f"{name} faces={faces}")
        np.testing.assert_array_equal(frame.mask, expected > 0)


def test_fill_rule_random_triangles_on_centres(rng):
    w = h = 32
    n = 60
    xy = rng.integers(-3, 35, size=(3 * n, 2)) + 0.5  # vertices on pixel centres (some off-image)
    xy[1::6] = rng.integers(-6, 70, size=xy[1::6].shape) / 2.0  # and some on half-pixel lines
    faces = np.arange(3 * n).reshape(n, 3)
    frame = render(scene_of(pixel_mesh(xy, faces, w, h)), pixel_ortho(w, h), w, h, cull="none")
    expected, _ = ref.rasterize(xy, faces, w, h, cull="none")
    np.testing.assert_array_equal(frame.coverage, expected)


def test_tiny_triangles_across_tile_borders_match_reference(rng):
    # Boxes of 1..6 px (the kernels step two rows of four pixels, or rows of eight), vertices on
    # pixel centres and half-pixel lines so edges pass exactly through centres, many straddling
    # the 64 px tile borders and the image's edges; overlapping, both windings.
    w, h = 150, 140
    n = 3000
    corner = rng.integers(-4, 154, size=(n, 1, 2)) + rng.integers(0, 2, size=(n, 1, 2)) / 2.0
    xy = (corner + rng.integers(0, 13, size=(n, 3, 2)) / 2.0).reshape(-1, 2)
    faces = np.arange(3 * n).reshape(n, 3)
    frame = render(scene_of(pixel_mesh(xy, faces, w, h)), pixel_ortho(w, h), w, h, cull="none")
    expected, _ = ref.rasterize(xy, faces, w, h, cull="none")
    assert expected.max() >= 3
    np.testing.assert_array_equal(frame.coverage, expected)


@pytest.mark.parametrize("quad", [
    [(3.5, 3.5), (20.5, 3.5), (20.5, 17.5), (3.5, 17.5)],      # shared diagonal of slope ~0.8
    [(2.5, 2.5), (14.5, 2.5), (14.5, 14.5), (2.5, 14.5)],      # shared diagonal of slope 1
    [(6.5, 1.5), (26.5, 11.5), (16.5, 29.5), (1.5, 13.5)],     # skewed quad, slopes 1/2, -9/5 ...
    [(10.5, 2.5), (20.5, 12.5), (10.5, 22.5), (0.5, 12.5)],    # diamond: vertical / horizontal split
])
@pytest.mark.parametrize("split", [0, 1])
def test_shared_edge_through_centres_covered_once(quad, split):
    w = h = 32
    xy = np.array(quad, dtype=np.float64)
    faces = np.array([[0, 1, 2], [0, 2, 3]] if split == 0 else [[0, 1, 3], [1, 2, 3]])
    assert (ref.signed_area2_fixed(ref.snap(xy), faces) > 0).all()  # a convex quad, one winding
    frame = render(scene_of(pixel_mesh(xy, faces, w, h)), pixel_ortho(w, h), w, h, cull="none")
    expected, _ = ref.rasterize(xy, faces, w, h, cull="none")
    assert expected.max() == 1 and expected.sum() > 50
    np.testing.assert_array_equal(frame.coverage, expected)


# --------------------------------------------------------------------------------------------
# 4. Projection against cv2.projectPoints
# --------------------------------------------------------------------------------------------

def _camera_facing_triangles(rng, p_cam_cv, sizes_px, f_px, ortho):
    """Small triangles (circumradius sizes_px, in px) centred on camera-space (OpenCV) points,
    lying in planes of constant depth. Returns (3n, 3) camera-space vertices."""
    n = len(p_cam_cv)
    ang = rng.uniform(0, 2 * np.pi, n)[:, None] + np.array([0.0, 2.1, 4.2])[None, :]
    ang = ang + rng.uniform(-0.3, 0.3, (n, 3))
    scale = (sizes_px / f_px)[:, None] * (1.0 if ortho else p_cam_cv[:, 2:3])  # px -> scene units
    verts = np.repeat(p_cam_cv[:, None, :], 3, axis=1).copy()
    verts[..., 0] += scale * np.cos(ang)
    verts[..., 1] += scale * np.sin(ang)
    return verts.reshape(-1, 3)


def _check_projection(rng, cam, w, h, project_uv, f_px, n=40):
    """Render small triangles around random points in front of the camera; compare the covered
    samples with the reference rasterizer run on cv2-projected vertices (pixel centres within
    0.01 px of an edge are excluded: float32 vs float64 projection may legitimately differ).
    Tiny (0.3 px) triangles may only light the pixel whose centre is nearest the projection.
    """
    depth = rng.uniform(1.5, 12.0, n)
    uv_target = np.c_[rng.uniform(-0.5, w - 0.5, n), rng.uniform(-0.5, h - 0.5, n)]
    sizes = np.where(np.arange(n) % 2 == 0, 0.3, 1.6)
    # Points in OpenCV camera space, found by a rough inverse of project_uv (the test only needs
    # them to land in the image; the expectation comes from cv2 on the final vertices).
    centre_cv = project_uv.inverse(uv_target, depth)
    verts_cv = _camera_facing_triangles(rng, centre_cv, sizes, f_px, project_uv.ortho)
    cam_to_world = np.linalg.inv(project_uv.world_to_cv)
    verts_world = verts_cv @ cam_to_world[:3, :3].T + cam_to_world[:3, 3]
    faces = np.arange(3 * n).reshape(n, 3)
    mesh = sr.Mesh(verts_world, faces)
    frame = render(scene_of(mesh), cam, w, h, outputs=("coverage", "triangle_id"), cull="none")

    p_world = mesh.positions.astype(np.float64)  # exactly what the renderer got
    uv = project_uv(p_world)
    xy_window = uv + 0.5  # OpenCV pixel centres are integers; window centres are at +0.5
    expected, _ = ref.rasterize(xy_window, faces, w, h, cull="none")
    unsure = ref.near_edges(xy_window, faces, w, h, 0.01)
    assert expected[~unsure].sum() > n // 3  # the test exercises something
    np.testing.assert_array_equal(frame.coverage[~unsure], expected[~unsure])

    centre_uv = project_uv(mesh.positions.astype(np.float64).reshape(n, 3, 3).mean(axis=1))
    for t in np.flatnonzero(sizes == 0.3):
        ii, jj = np.nonzero(frame.triangle_id == t)
        for i, j in zip(ii, jj):
            assert (i, j) == (round(centre_uv[t, 1]), round(centre_uv[t, 0])), f"triangle {t}"


class _Projector:
    """cv2.projectPoints with given K (perspective) or an affine camera (orthographic)."""

    def __init__(self, world_to_cv, K, ortho=False):
        self.world_to_cv, self.K, self.ortho = world_to_cv, K, ortho
        self.rvec, _ = cv2.Rodrigues(world_to_cv[:3, :3])
        self.tvec = world_to_cv[:3, 3].copy()

    def __call__(self, p_world):
        p_world = np.ascontiguousarray(p_world, dtype=np.float64)
        if not self.ortho:
            uv, _ = cv2.projectPoints(p_world, self.rvec, self.tvec, self.K, None)
            return uv.reshape(-1, 2)
        p_cv = p_world @ self.world_to_cv[:3, :3].T + self.world_to_cv[:3, 3]
        flat = np.c_[p_cv[:, :2], np.ones(len(p_cv))]  # parallel projection = pinhole at Z = 1
        uv, _ = cv2.projectPoints(flat, np.zeros(3), np.zeros(3), self.K, None)
        return uv.reshape(-1, 2)

    def inverse(self, uv, depth):
        fx, fy, cx, cy = self.K[0, 0], self.K[1, 1], self.K[0, 2], self.K[1, 2]
        s = 1.0 if self.ortho else depth
        return np.c_[(uv[:, 0] - cx) / fx * s, (uv[:, 1] - cy) / fy * s, depth]


def _random_world_to_cv(rng):
    m = np.eye(4)
    m[:3, :3] = random_rotation(rng)
    m[:3, 3] = rng.normal(size=3) * 2.0
    return m


@pytest.mark.parametrize("w,h", [(97, 61), (64, 64), (40, 90)])
def test_intrinsics_opencv_matches_cv2(rng, w, h):
    world_to_cv = _random_world_to_cv(rng)
    fx, fy = 0.9 * w, 0.8 * w
    cx, cy = 0.37 * w, 0.61 * h  # off-centre principal point
    cam = sr.IntrinsicsCamera(fx, fy, cx, cy, w, h, near=0.5, far=50.0, convention="opencv")
    cam.pose = np.linalg.inv(world_to_cv)  # camera-to-world in OpenCV axes
    K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
    _check_projection(rng, cam, w, h, _Projector(world_to_cv, K), fx)


@pytest.mark.parametrize("w,h", [(97, 61), (61, 97)])
def test_intrinsics_opengl_matches_cv2_with_half_pixel_shift(rng, w, h):
    world_to_cv = _random_world_to_cv(rng)
    fx, fy = 1.1 * w, 1.0 * w
    cx_cv, cy_cv = 0.55 * w, 0.42 * h
    # pyrender's convention: (cx, cy) measured from the top-left corner => +0.5 px; pose in GL axes.
    cam = sr.IntrinsicsCamera(fx, fy, cx_cv + 0.5, cy_cv + 0.5, w, h, near=0.5, far=50.0,
                              convention="opengl")
    cam.pose = np.linalg.inv(world_to_cv) @ _GL_FROM_CV
    K = np.array([[fx, 0, cx_cv], [0, fy, cy_cv], [0, 0, 1.0]])
    _check_projection(rng, cam, w, h, _Projector(world_to_cv, K), fx)


@pytest.mark.parametrize("w,h", [(97, 61), (50, 80)])
def test_perspective_camera_matches_cv2(rng, w, h):
    fov_y = 52.0
    cam = sr.PerspectiveCamera(fov_y=fov_y, near=0.5, far=50.0)
    pose_gl = look_at_gl(rng.normal(size=3) * 3.0, rng.normal(size=3), up=rng.normal(size=3))
    cam.pose = pose_gl
    world_to_cv = np.linalg.inv(pose_gl @ _GL_FROM_CV)
    f = (h / 2.0) / math.tan(math.radians(fov_y) / 2.0)
    K = np.array([[f, 0, (w - 1) / 2.0], [0, f, (h - 1) / 2.0], [0, 0, 1.0]])
    _check_projection(rng, cam, w, h, _Projector(world_to_cv, K), f)


@pytest.mark.parametrize("w,h", [(97, 61), (64, 48)])
def test_orthographic_camera_matches_cv2(rng, w, h):
    xmag, ymag = 2.0, 1.7  # non-square pixels on purpose
    cam = sr.OrthographicCamera(xmag=xmag, ymag=ymag, near=0.5, far=50.0)
    pose_gl = look_at_gl(rng.normal(size=3) * 3.0 + 4.0, rng.normal(size=3), up=rng.normal(size=3))
    cam.pose = pose_gl
    world_to_cv = np.linalg.inv(pose_gl @ _GL_FROM_CV)
    fx, fy = w / (2 * xmag), h / (2 * ymag)
    K = np.array([[fx, 0, (w - 1) / 2.0], [0, fy, (h - 1) / 2.0], [0, 0, 1.0]])
    proj = _Projector(world_to_cv, K, ortho=True)
    _check_projection(rng, cam, w, h, proj, fx / 1.0)


# --------------------------------------------------------------------------------------------
# 5. Clipping (the near plane: tests/test_near_plane.py)
# --------------------------------------------------------------------------------------------

def test_huge_triangles_beyond_guard_band():
    w, h, fov, d = 64, 48, 60.0, 2.0
    cam = sr.PerspectiveCamera(fov_y=fov, near=0.05, far=100.0)
    cam.pose = np.eye(4)
    # A horizontal band y in [y_lo, y_hi] at depth d made of two triangles reaching x = +-1e7,
    # and a wedge with its apex in the image and its other corners at x = +-1e7.
    y_lo, y_hi = -0.31, 0.4
    band = np.array([[-1e7, y_lo, -d], [1e7, y_lo, -d], [1e7, y_hi, -d], [-1e7, y_hi, -d]])
    band_faces = np.array([[0, 1, 2], [0, 2, 3]])
    rays = pixel_rays_view(w, h, fov)
    y_hit = rays[..., 1] * d  # view-space y where the ray crosses z = -d
    x_hit = rays[..., 0] * d
    frame = render(scene_of(sr.Mesh(band, band_faces)), cam, w, h, cull="back")
    inside = (y_hit > y_lo) & (y_hit < y_hi)
    assert 0 < inside.sum() < w * h
    np.testing.assert_array_equal(frame.coverage, inside.astype(np.uint32))  # no crack/overlap
    np.testing.assert_allclose(frame.depth[inside], d, rtol=2e-6)

    apex = np.array([0.13, 0.37, -d])
    wedge = np.array([apex, [-1e7, apex[1] - 1e7, -d], [1e7, apex[1] - 1e7, -d]])
    frame = render(scene_of(sr.Mesh(wedge, [[0, 1, 2]])), cam, w, h, cull="back")
    # Inside: below both slanted edges through the apex with slope +-1 (to 1e-7 relative).
    below_left = y_hit < apex[1] + (x_hit - apex[0])
    below_right = y_hit < apex[1] - (x_hit - apex[0])
    inside = below_left & below_right
    px = 2 * d * math.tan(math.radians(fov) / 2) / h  # view units per pixel at depth d
    dist = np.minimum(np.abs(y_hit - apex[1] - (x_hit - apex[0])),
                      np.abs(y_hit - apex[1] + (x_hit - apex[0]))) / math.sqrt(2) / px
    sure = dist > 0.01
    assert inside.sum() > 100
    np.testing.assert_array_equal(frame.coverage[sure], inside[sure].astype(np.uint32))
    np.testing.assert_allclose(frame.depth[inside & sure], d, rtol=2e-6)


def test_icosphere_trimesh_sanity():
    # The sphere fixture really is closed with outward faces (so coverage tests mean something).
    m = trimesh.creation.icosphere(subdivisions=2)
    assert m.is_watertight and m.is_winding_consistent and m.volume > 0
