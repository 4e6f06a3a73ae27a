"""OpenCV interop: IntrinsicsCamera.from_opencv / to_opencv against cv2.projectPoints,
and the softrast.opencv helpers against OpenCV's own functions."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

import softrast as sr

W, H = 640, 480


def random_calibration(rng: np.random.Generator):
    f = rng.uniform(350.0, 700.0)
    K = np.array([[f, 0.0, rng.uniform(0.4, 0.6) * W], [0.0, f * rng.uniform(0.9, 1.1), rng.uniform(0.4, 0.6) * H],
                  [0.0, 0.0, 1.0]])
    rvec = rng.normal(size=3) * 1.2
    tvec = rng.normal(size=3) * np.array([0.3, 0.3, 0.5]) + np.array([0.0, 0.0, 5.0])
    return K, rvec, tvec


@pytest.mark.parametrize("seed", range(20))
def test_from_opencv_to_opencv_round_trip(seed: int) -> None:
    rng = np.random.default_rng(seed)
    K, rvec, tvec = random_calibration(rng)
    R = cv2.Rodrigues(rvec)[0]
    for rot in (rvec, rvec.reshape(3, 1), R):
        cam = sr.IntrinsicsCamera.from_opencv(K, rot, tvec.reshape(3, 1), W, H, near=0.1, far=50.0)
        K2, R2, t2, dist = cam.to_opencv()
        np.testing.assert_allclose(K2, K, rtol=0, atol=1e-12)
        np.testing.assert_allclose(R2, R, rtol=0, atol=1e-12)
        np.testing.assert_allclose(t2, tvec, rtol=0, atol=1e-12)
        assert dist.shape == (5,) and not dist.any()
        assert cam.convention == "opencv" and (cam.width, cam.height) == (W, H)
    # rvec back through cv2.Rodrigues, and a second round trip
    rvec2 = cv2.Rodrigues(R2)[0].ravel()
    cam2 = sr.IntrinsicsCamera.from_opencv(K2, rvec2, t2, W, H, dist=np.zeros(5), near=0.1, far=50.0)
    for a, b in zip(cam2.to_opencv(), cam.to_opencv()):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


def test_to_opencv_of_an_opengl_camera_projects_the_same() -> None:
    """An "opengl" (pyrender) IntrinsicsCamera's to_opencv: cv2.projectPoints lands where the
    camera's own projection matrix puts the point (window coordinates - 0.5)."""
    rng = np.random.default_rng(7)
    cam = sr.IntrinsicsCamera(500.0, 480.0, 330.0, 250.0, W, H, near=0.1, far=50.0, convention="opengl")
    cam.look_at((1.0, 2.0, 5.0), (0.1, -0.2, 0.0))
    K, R, t, dist = cam.to_opencv()
    pts = rng.uniform(-1.0, 1.0, size=(50, 3))
    uv, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), cv2.Rodrigues(R)[0], t, K, dist)
    clip = np.c_[pts, np.ones(50)] @ (cam.projection_matrix(W, H) @ cam.view_matrix()).T
    ndc = clip[:, :3] / clip[:, 3:]
    win = np.c_[(ndc[:, 0] + 1) / 2 * W, (1 - ndc[:, 1]) / 2 * H]
    np.testing.assert_allclose(uv.reshape(-1, 2), win - 0.5, rtol=0, atol=1e-9)


def inside_distance(tri2d: np.ndarray, w: int, h: int) -> np.ndarray:
    """Signed distance (px) of each pixel centre (u, v) = (j, i) to the 2D triangle's edges: the
    minimum over edges, > 0 inside (either winding)."""
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    e1, e2 = tri2d[1] - tri2d[0], tri2d[2] - tri2d[0]
    area = e1[0] * e2[1] - e1[1] * e2[0]
    dist = np.full(u.shape, np.inf)
    for k in range(3):
        a, b = tri2d[k], tri2d[(k + 1) % 3]
        e = b - a
        side = (e[0] * (v - a[1]) - e[1] * (u - a[0])) / np.hypot(*e)
        dist = np.minimum(dist, side * np.sign(area))
    return dist


@pytest.mark.parametrize("seed", range(4))
def test_rendered_triangles_land_where_projectpoints_says(seed: int) -> None:
    """Triangles at random 3D points: the pixels the render covers are exactly the pixel centres
    inside the 2D triangle of the three cv2.projectPoints vertices, except centres closer than
    0.01 px to an edge (vertices snap to 1/256 px); so the centroid of the covered pixels is the
    sampled centroid of OpenCV's triangle (and both are within a lattice effect of the vertices'
    mean: printed, not asserted, as it depends on the edges' slopes, not on the projection)."""
    rng = np.random.default_rng(100 + seed)
    K, rvec, tvec = random_calibration(rng)
    R = cv2.Rodrigues(rvec)[0]
    cam = sr.IntrinsicsCamera.from_opencv(K, rvec, tvec, W, H, near=0.1, far=50.0)
    renderer = sr.Renderer(W, H)
    worst_centroid = worst_lattice = 0.0
    for _ in range(10):
        uv = np.array([rng.uniform(120, W - 120), rng.uniform(120, H - 120)])
        z = rng.uniform(3.0, 7.0)
        centre = np.linalg.solve(K, np.r_[uv, 1.0]) * z  # camera coordinates
        angles = rng.uniform(0.0, 2.0 * np.pi) + np.radians([0.0, 120.0, 240.0]) + rng.uniform(-0.3, 0.3, 3)
        corners_cam = centre + np.c_[np.cos(angles), np.sin(angles), rng.uniform(-0.1, 0.1, 3)] * (60.0 / K[0, 0] * z)
        world = (corners_cam - tvec) @ R  # R^T (x - t)
        proj, _ = cv2.projectPoints(world.reshape(-1, 1, 3), rvec, tvec, K, None)
        proj = proj.reshape(3, 2)
        scene = sr.Scene()
        scene.add(sr.Mesh(world, np.array([[0, 1, 2]])))
        mask = renderer.render(scene, cam, outputs="mask", cull="none").mask
        dist = inside_distance(proj, W, H)
        wrong = mask != (dist > 0)
        assert (np.abs(dist[wrong]) < 0.01).all(), (
            f"{int(wrong.sum())} pixels differ from OpenCV's triangle, up to {np.abs(dist[wrong]).max():.4f} px inside")
        rows, cols = np.nonzero(mask)
        ref_rows, ref_cols = np.nonzero(dist > 0)
        if len(rows) == 0:
            continue
        centroid = np.array([cols.mean(), rows.mean()])
        worst_centroid = max(worst_centroid, float(np.abs(centroid - [ref_cols.mean(), ref_rows.mean()]).max()))
        worst_lattice = max(worst_lattice, float(np.abs(centroid - proj.mean(axis=0)).max()))
    print(f"seed {seed}: covered-pixel centroid vs OpenCV triangle's sampled centroid: max {worst_centroid:.2e} px; "
          f"vs the mean of the projected vertices (lattice effect, ~100 px triangles): max {worst_lattice:.3f} px")
    assert worst_centroid < 0.05


def test_depth_of_every_pixel_matches_the_opencv_ray() -> None:
    """A tilted plane filling the view: at pixel (i, j) the rendered depth is z_cam of the plane
    point that cv2.projectPoints maps to (u, v) = (j, i). The depth error divided by the depth's
    change per pixel bounds the projection's offset: below 0.01 px."""
    rng = np.random.default_rng(3)
    K, rvec, tvec = random_calibration(rng)
    R = cv2.Rodrigues(rvec)[0]
    cam = sr.IntrinsicsCamera.from_opencv(K, rvec, tvec, W, H, near=0.1, far=50.0)
    # plane in camera coordinates: n . x = d, tilted
    n = np.array([0.35, -0.25, -1.0])
    n /= np.linalg.norm(n)
    d = -5.0 * abs(n[2])
    big = 20.0
    quad_cam = []
    for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
        x, y = a * big, b * big
        z = (d - n[0] * x - n[1] * y) / n[2]
        quad_cam.append((x, y, z))
    world = (np.array(quad_cam) - tvec) @ R
    scene = sr.Scene()
    scene.add(sr.Mesh(world, np.array([[0, 1, 2], [0, 2, 3]])))
    depth = sr.Renderer(W, H).render(scene, cam, outputs="depth", cull="none").depth
    jj, ii = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    rays = np.stack([(jj - K[0, 2]) / K[0, 0], (ii - K[1, 2]) / K[1, 1], np.ones_like(jj)], axis=-1)
    z = d / (rays @ n)  # ray-plane intersection; z_cam
    points_cam = rays * z[..., None]
    # the analytic points project back on their own pixel centres through OpenCV
    sample = points_cam[::17, ::19].reshape(-1, 3)
    uv, _ = cv2.projectPoints(((sample - tvec) @ R).reshape(-1, 1, 3), rvec, tvec, K, None)
    np.testing.assert_allclose(uv.reshape(-1, 2), np.c_[jj[::17, ::19].ravel(), ii[::17, ::19].ravel()], atol=1e-6)
    assert (depth > 0).all()
    gy, gx = np.gradient(z)
    per_px = np.hypot(gx, gy)
    offset_px = np.abs(depth - z) / per_px
    rel = np.abs(depth - z) / z
    print(f"depth vs the OpenCV ray: max rel {rel.max():.2e}; as a pixel offset: max {offset_px.max():.5f} px, "
          f"mean {offset_px.mean():.6f} px")
    assert offset_px.max() < 0.01


def test_from_opencv_refuses_bad_input() -> None:
    K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    with pytest.raises(ValueError, match=r"^dist: a tilted sensor"):
        sr.IntrinsicsCamera.from_opencv(K, np.zeros(3), np.zeros(3), W, H, dist=[0.1] + [0] * 12 + [0.01])
    with pytest.raises(ValueError, match="dist must hold"):
        sr.IntrinsicsCamera.from_opencv(K, np.zeros(3), np.zeros(3), W, H, dist=[0.0, 0.0])
    with pytest.raises(ValueError, match="no skew"):
        sr.IntrinsicsCamera.from_opencv(K + np.array([[0, 1.0, 0], [0, 0, 0], [0, 0, 0]]), np.zeros(3),
                                        np.zeros(3), W, H)
    with pytest.raises(ValueError, match="proper rotation"):
        sr.IntrinsicsCamera.from_opencv(K, np.diag([1.0, 1.0, -1.0]), np.zeros(3), W, H)
    with pytest.raises(ValueError, match="tvec"):
        sr.IntrinsicsCamera.from_opencv(K, np.zeros(3), np.zeros(2), W, H)
    cam = sr.IntrinsicsCamera.from_opencv(K, np.zeros(3), np.zeros(3), W, H, dist=np.zeros((1, 5)))
    assert np.array_equal(cam.pose, np.eye(4))
    assert math.isclose(cam.fx, 500.0)


# -- softrast.opencv helpers ------------------------------------------------------------------------
def test_to_bgr_matches_cv2_cvtcolor() -> None:
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (37, 53, 3), dtype=np.uint8)
    bgr = sr.opencv.to_bgr(rgb)
    assert np.array_equal(bgr, cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    assert bgr.flags.c_contiguous and not np.shares_memory(bgr, rgb)
    assert np.array_equal(sr.opencv.to_bgr(bgr), rgb)
    rgba = rng.integers(0, 256, (5, 7, 4), dtype=np.uint8)
    assert np.array_equal(sr.opencv.to_bgr(rgba), cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGRA))
    # a rendered frame, drawn on by OpenCV in place (needs the contiguous copy)
    scene = sr.Scene()
    scene.add(sr.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], color=(1.0, 0.0, 0.0)))
    cam = sr.PerspectiveCamera(fov_y=60.0).look_at((0.3, 0.3, 2.0), (0.3, 0.3, 0.0))
    frame = sr.Renderer(64, 48).render(scene, cam, outputs="color", shading="unlit")
    bgr = sr.opencv.to_bgr(frame.color)
    cv2.circle(bgr, (5, 5), 2, (255, 255, 255), -1)
    hit = frame.color[24, 32]
    assert tuple(hit) == (255, 0, 0) and tuple(bgr[24, 32]) == (0, 0, 255)
    with pytest.raises(ValueError, match="RGB"):
        sr.opencv.to_bgr(np.zeros((4, 4)))


def test_depth_to_mm_uint16() -> None:
    depth = np.array([[0.0, 0.0004, 0.0005, 0.0015, 1.2344999], [1.2345001, 65.535, 65.5355, 1e6, 1e308]],
                     dtype=np.float64)
    mm = sr.opencv.depth_to_mm_uint16(depth)
    assert mm.dtype == np.uint16
    assert mm.tolist() == [[0, 1, 1, 2, 1234], [1235, 65535, 65535, 65535, 65535]]
    assert sr.opencv.depth_to_mm_uint16(np.array([2.5, 3.5], np.float32), scale=1.0).tolist() == [3, 4]
    # a float32 render's depth: background 0, hits to the nearest millimetre
    rng = np.random.default_rng(1)
    d = (rng.uniform(0.2, 9.0, (40, 50)) * (rng.uniform(size=(40, 50)) > 0.3)).astype(np.float32)
    mm = sr.opencv.depth_to_mm_uint16(d)
    assert np.array_equal(mm == 0, d == 0)
    assert np.abs(mm[d > 0] - d[d > 0].astype(np.float64) * 1000).max() <= 0.5 + 1e-6
    # what OpenCV writes and reads back as a 16-bit PNG is the same
    ok, png = cv2.imencode(".png", mm)
    assert ok and np.array_equal(cv2.imdecode(png, cv2.IMREAD_UNCHANGED), mm)
    for bad in (np.array([-1.0]), np.array([np.nan]), np.array([np.inf])):
        with pytest.raises(ValueError, match="depth"):
            sr.opencv.depth_to_mm_uint16(bad)
    with pytest.raises(ValueError, match="scale"):
        sr.opencv.depth_to_mm_uint16(d, scale=0.0)


def test_draw_outline_marks_the_boundary_pixels() -> None:
    from scipy import ndimage

    scene = sr.Scene()
    import trimesh

    scene.add(sr.Mesh.from_trimesh(trimesh.creation.icosphere(subdivisions=3, radius=0.5)))
    ring = trimesh.creation.annulus(r_min=0.25, r_max=0.45, height=0.1, sections=48)
    pose = np.eye(4)
    pose[:3, 3] = (1.2, 0.0, 0.0)
    scene.add(sr.Mesh.from_trimesh(ring), pose=pose)  # a silhouette with a hole
    cam = sr.PerspectiveCamera(fov_y=50.0).look_at((0.6, 0.2, 3.0), (0.6, 0.0, 0.0))
    frame = sr.Renderer(160, 120).render(scene, cam, outputs=("color", "mask"))
    photo = np.full((120, 160, 3), 40, np.uint8)
    out = sr.opencv.draw_outline(photo, frame.mask, color=(0, 255, 0))
    assert out is photo
    drawn = (photo == (0, 255, 0)).all(axis=2)
    four = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], bool)
    boundary = frame.mask & ~ndimage.binary_erosion(frame.mask, four, border_value=0)
    assert boundary.sum() > 100
    assert np.array_equal(drawn, boundary), f"{int((drawn != boundary).sum())} pixels differ"
    thick = sr.opencv.draw_outline(np.zeros_like(photo), frame.mask, color=(255, 255, 255), thickness=3)
    assert ((thick[..., 0] > 0) & boundary).sum() == boundary.sum()
    with pytest.raises(ValueError, match="shape"):
        sr.opencv.draw_outline(photo, frame.mask[:-1])
    with pytest.raises(ValueError, match="contiguous"):
        sr.opencv.draw_outline(photo[:, ::-1], frame.mask)
