"""Cameras, checked against cv2.projectPoints, the gluPerspective / pyrender formulas and geometry."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from softrast.camera import IntrinsicsCamera, OrthographicCamera, PerspectiveCamera


def to_window(camera, points_world, width, height):
    """The core's pipeline in float64: clip = P @ view @ [X, 1], NDC, window (row 0 at top)."""
    p_h = np.c_[points_world, np.ones(len(points_world))]
    p_clip = p_h @ (camera.projection_matrix(width, height) @ camera.view_matrix()).T
    p_ndc = p_clip[:, :3] / p_clip[:, 3:]
    x_win = (p_ndc[:, 0] + 1.0) / 2.0 * width
    y_win = (1.0 - p_ndc[:, 1]) / 2.0 * height
    return np.c_[x_win, y_win], p_ndc[:, 2], p_clip[:, 3]


def random_pose(rng):
    """A random rigid camera-to-world transform (rotation from a Rodrigues vector)."""
    rot, _ = cv2.Rodrigues(rng.normal(size=3) * 2.0)
    pose = np.eye(4)
    pose[:3, :3] = rot
    pose[:3, 3] = rng.normal(size=3) * 3.0
    return pose


def points_in_front(rng, n, pose, opencv):
    """World points that lie 0.5..20 units in front of a camera with ``pose``."""
    depth = rng.uniform(0.5, 20.0, n)
    xy = rng.uniform(-0.6, 0.6, (n, 2)) * depth[:, None]
    z_cam = depth if opencv else -depth  # OpenCV looks down +z, OpenGL down -z
    p_cam = np.c_[xy, z_cam, np.ones(n)]
    return (p_cam @ pose.T)[:, :3], depth


# -- IntrinsicsCamera, OpenCV convention --------------------------------------------------------

@pytest.mark.parametrize("size", [(640, 480), (123, 457), (1000, 37)])
def test_opencv_intrinsics_match_cv2_project_points(rng, size):
    width, height = size
    for _ in range(5):
        fx, fy = rng.uniform(50.0, 900.0, 2)
        cx = rng.uniform(0.2, 0.8) * width  # off-centre principal point
        cy = rng.uniform(0.2, 0.8) * height
        cam = IntrinsicsCamera(fx, fy, cx, cy, width, height, near=0.1, far=50.0)
        pose = random_pose(rng)
        cam.pose = pose
        points, _ = points_in_front(rng, 50, pose, opencv=True)

        world_to_cam = np.linalg.inv(pose)  # cv2 wants world-to-camera, i.e. inverse of the pose
        rvec, _ = cv2.Rodrigues(world_to_cam[:3, :3])
        object_points = np.ascontiguousarray(points).reshape(-1, 1, 3)
        uv, _ = cv2.projectPoints(object_points, rvec, world_to_cam[:3, 3], cam.K, None)
        uv = uv.reshape(-1, 2)

        p_win, _, _ = to_window(cam, points, width, height)
        np.testing.assert_allclose(p_win - 0.5, uv, rtol=0, atol=1e-6)
        # Which pixel a point falls in: (row, col) = (round(v), round(u)) both ways.
        np.testing.assert_array_equal(np.floor(p_win), np.round(uv))


def test_opencv_intrinsics_depth_is_distance_along_axis(rng):
    cam = IntrinsicsCamera(500, 520, 300, 200, 640, 400, near=0.1, far=50.0)
    pose = random_pose(rng)
    cam.pose = pose
    points, depth = points_in_front(rng, 20, pose, opencv=True)
    _, z_ndc, w_clip = to_window(cam, points, 640, 400)
    np.testing.assert_allclose(w_clip, depth, rtol=1e-12)
    assert np.all(np.abs(z_ndc) < 1.0)  # inside [near, far]


def test_opencv_view_matrix_flips_y_and_z(rng):
    cam = IntrinsicsCamera(500, 500, 320, 240, 640, 480)
    pose = random_pose(rng)
    cam.pose = pose
    np.testing.assert_allclose(cam.view_matrix(), np.diag([1.0, -1.0, -1.0, 1.0]) @ np.linalg.inv(pose), atol=1e-12)


def test_opencv_principal_pixel_centre():
    # A point on the optical axis projects to (u, v) = (cx, cy): the centre of pixel (cy, cx).
    cam = IntrinsicsCamera(400, 400, 10, 20, 64, 48, convention="opencv")
    p_win, _, _ = to_window(cam, np.array([[0.0, 0.0, 5.0]]), 64, 48)  # +z is forward for opencv
    np.testing.assert_allclose(p_win[0], [10.5, 20.5], atol=1e-12)


# -- IntrinsicsCamera, OpenGL convention (pyrender) ----------------------------------------------

def test_opengl_intrinsics_equals_pyrender_formula():
    fx, fy, cx, cy, w, h, n, f = 410.0, 395.0, 300.5, 170.25, 640, 360, 0.2, 30.0
    cam = IntrinsicsCamera(fx, fy, cx, cy, w, h, near=n, far=f, convention="opengl")
    expected = np.array([
        [2 * fx / w, 0, 1 - 2 * cx / w, 0],  # pyrender IntrinsicsCamera.get_projection_matrix
        [0, 2 * fy / h, 2 * cy / h - 1, 0],
        [0, 0, (f + n) / (n - f), 2 * f * n / (n - f)],
        [0, 0, -1, 0],
    ])
    np.testing.assert_allclose(cam.projection_matrix(w, h), expected, rtol=1e-15, atol=0)
    assert cam.convention == "opengl"


def test_opengl_intrinsics_projects_from_top_left_corner(rng):
    fx, fy, cx, cy, w, h = 300.0, 310.0, 50.0, 30.0, 100, 80
    cam = IntrinsicsCamera(fx, fy, cx, cy, w, h, convention="opengl")
    pose = random_pose(rng)
    cam.pose = pose
    points, depth = points_in_front(rng, 30, pose, opencv=False)
    p_cam = (np.c_[points, np.ones(30)] @ np.linalg.inv(pose).T)[:, :3]  # OpenGL camera axes
    p_win, _, w_clip = to_window(cam, points, w, h)
    np.testing.assert_allclose(p_win[:, 0], fx * p_cam[:, 0] / depth + cx, atol=1e-9)
    np.testing.assert_allclose(p_win[:, 1], cy - fy * p_cam[:, 1] / depth, atol=1e-9)  # y up => rows down
    np.testing.assert_allclose(w_clip, depth, rtol=1e-12)


def test_intrinsics_K():
    cam = IntrinsicsCamera(1, 2, 3, 4, 10, 10)
    np.testing.assert_array_equal(cam.K, [[1, 0, 3], [0, 2, 4], [0, 0, 1]])


# -- PerspectiveCamera --------------------------------------------------------------------------

def test_perspective_matches_glu_perspective():
    fov, n, f, w, h = 60.0, 0.1, 25.0, 320, 200
    cam = PerspectiveCamera(fov_y=fov, near=n, far=f)
    t = 1.0 / math.tan(math.radians(fov) / 2)
    expected = np.array([
        [t / (w / h), 0, 0, 0],
        [0, t, 0, 0],
        [0, 0, (f + n) / (n - f), 2 * f * n / (n - f)],
        [0, 0, -1, 0],
    ])
    np.testing.assert_allclose(cam.projection_matrix(w, h), expected, rtol=1e-15)
    assert cam.projection_matrix(w, h).dtype == np.float64


def test_perspective_aspect_override():
    cam = PerspectiveCamera(fov_y=90.0, aspect=2.0)
    proj = cam.projection_matrix(100, 100)
    assert proj[0, 0] == pytest.approx(0.5)
    assert proj[1, 1] == pytest.approx(1.0)


def test_perspective_fov_reaches_image_edges():
    # A point at half the vertical fov above the axis lands on the top edge of the image.
    cam = PerspectiveCamera(fov_y=50.0)
    half = math.radians(25.0)
    pts = np.array([[0.0, math.tan(half) * 4.0, -4.0], [0.0, -math.tan(half) * 4.0, -4.0]])
    p_win, _, _ = to_window(cam, pts, 80, 60)
    np.testing.assert_allclose(p_win[:, 1], [0.0, 60.0], atol=1e-12)
    np.testing.assert_allclose(p_win[:, 0], [40.0, 40.0], atol=1e-12)


def test_perspective_depth_and_near_far_planes(rng):
    cam = PerspectiveCamera(fov_y=45.0, near=0.5, far=40.0)
    cam.pose = random_pose(rng)
    forward = -cam.pose[:3, 2]  # OpenGL camera looks down its -z axis
    eye = cam.pose[:3, 3]
    points = eye + forward * np.array([[0.5], [3.0], [40.0]])
    _, z_ndc, w_clip = to_window(cam, points, 64, 48)
    np.testing.assert_allclose(w_clip, [0.5, 3.0, 40.0], rtol=1e-12)  # w_clip = -z_view = depth
    np.testing.assert_allclose(z_ndc[[0, 2]], [-1.0, 1.0], atol=1e-12)


def test_perspective_needs_an_image_size():
    with pytest.raises(ValueError, match="width and height"):
        PerspectiveCamera().projection_matrix()
    cam = PerspectiveCamera(width=40, height=20)
    assert cam.projection_matrix()[0, 0] == pytest.approx(cam.projection_matrix(40, 20)[0, 0])


# -- OrthographicCamera -------------------------------------------------------------------------

def test_orthographic_matrix_and_extent():
    n, f = 0.5, 10.0
    cam = OrthographicCamera(xmag=2.0, ymag=1.5, near=n, far=f)
    expected = np.array([
        [0.5, 0, 0, 0], [0, 1 / 1.5, 0, 0],
        [0, 0, -2 / (f - n), -(f + n) / (f - n)], [0, 0, 0, 1],
    ])
    np.testing.assert_allclose(cam.projection_matrix(64, 48), expected, rtol=1e-15)
    assert cam.orthographic
    # xmag / ymag are half-extents: (2, 1.5) in view space is the top-right corner.
    p_win, z_ndc, w_clip = to_window(cam, np.array([[2.0, 1.5, -n], [-2.0, -1.5, -f]]), 64, 48)
    np.testing.assert_allclose(p_win, [[64.0, 0.0], [0.0, 48.0]], atol=1e-12)
    np.testing.assert_allclose(z_ndc, [-1.0, 1.0], atol=1e-12)
    np.testing.assert_array_equal(w_clip, [1.0, 1.0])


# -- look_at and pose ---------------------------------------------------------------------------

CAMERAS = [
    lambda: PerspectiveCamera(fov_y=40.0),
    lambda: OrthographicCamera(xmag=3.0, ymag=2.0),
    lambda: IntrinsicsCamera(300, 300, 31.5, 23.5, 64, 48, convention="opencv"),  # cx = (W-1)/2
    lambda: IntrinsicsCamera(300, 300, 32.0, 24.0, 64, 48, convention="opengl"),  # cx = W/2
]


@pytest.mark.parametrize("make", CAMERAS)
def test_look_at_centres_target_and_keeps_up_up(rng, make):
    for _ in range(5):
        cam = make()
        eye, target = rng.normal(size=3) * 5.0, rng.normal(size=3)
        up = np.array([0.0, 0.0, 1.0])
        assert cam.look_at(eye, target, up) is cam
        p_win, _, w_clip = to_window(cam, np.array([target, target + 0.1 * up]), 64, 48)
        np.testing.assert_allclose(p_win[0], [32.0, 24.0], atol=1e-9)
        assert p_win[1, 1] < p_win[0, 1]  # a point above the target is higher in the image
        if not cam.orthographic:
            np.testing.assert_allclose(w_clip[0], np.linalg.norm(target - eye), rtol=1e-12)


def test_look_at_opencv_axes():
    cam = IntrinsicsCamera(100, 100, 50, 50, 100, 100).look_at((0, 0, 5), (0, 0, 0))
    np.testing.assert_allclose(cam.pose[:3, 2], [0, 0, -1], atol=1e-15)  # z toward the target
    np.testing.assert_allclose(cam.pose[:3, 1], [0, -1, 0], atol=1e-15)  # y down
    np.testing.assert_allclose(cam.pose[:3, 0], [1, 0, 0], atol=1e-15)
    gl = PerspectiveCamera().look_at((0, 0, 5), (0, 0, 0))
    np.testing.assert_allclose(gl.pose[:3, :3], np.eye(3), atol=1e-15)
    np.testing.assert_allclose(gl.view_matrix() @ gl.pose, np.eye(4), atol=1e-15)


def test_default_pose_is_identity():
    for make in CAMERAS:
        np.testing.assert_array_equal(make().pose, np.eye(4))


def test_pose_is_copied_and_read_only():
    cam = PerspectiveCamera()
    pose = np.eye(4)
    cam.pose = pose
    pose[0, 3] = 5.0
    assert cam.pose[0, 3] == 0.0
    with pytest.raises(ValueError):
        cam.pose[0, 3] = 1.0



@pytest.mark.parametrize("make", CAMERAS)
def test_render_matrices_follow_every_new_pose(rng, make):
    """A render reuses the camera's matrices until its pose changes (the core reads these)."""
    cam = make()
    w, h = (cam.width or 64), (cam.height or 48)
    view, proj = cam._render_matrices(w, h)
    again = cam._render_matrices(w, h)
    assert again[0] is view and again[1] is proj  # cached
    assert not view.flags.writeable and not proj.flags.writeable
    for _ in range(3):
        cam.pose = random_pose(rng)
        view, proj = cam._render_matrices(w, h)
        np.testing.assert_array_equal(view, cam.view_matrix())
        np.testing.assert_array_equal(proj, cam.projection_matrix(w, h))
    cam.look_at(eye=(1.0, 2.0, 3.0), target=(0.0, 0.0, 0.0))
    np.testing.assert_array_equal(cam._render_matrices(w, h)[0], cam.view_matrix())
    if cam.width is None:  # another image size, another projection
        np.testing.assert_array_equal(cam._render_matrices(32, 48)[1], cam.projection_matrix(32, 48))


def test_a_subclass_projection_is_asked_on_every_render():
    """A user camera may change its projection between renders: no stale cached matrix."""
    import softrast as sr
    import trimesh

    class ZoomCamera(PerspectiveCamera):
        zoom = 1.0

        def projection_matrix(self, width=None, height=None):
            proj = super().projection_matrix(width, height)
            proj[:2, :2] *= self.zoom
            return proj

    scene = sr.Scene()
    scene.add(sr.Mesh.from_trimesh(trimesh.creation.icosphere(subdivisions=2)))
    renderer = sr.Renderer(64, 64)
    cam = ZoomCamera(fov_y=60.0)
    cam.look_at(eye=(0.0, 0.0, 4.0), target=(0.0, 0.0, 0.0))
    small = renderer.render(scene, cam, outputs="mask").mask.sum()
    cam.zoom = 2.0
    big = renderer.render(scene, cam, outputs="mask").mask.sum()
    assert 3.5 * small < big < 4.5 * small  # twice the focal length: four times the area


# -- bad inputs ---------------------------------------------------------------------------------

@pytest.mark.parametrize("pose", [
    np.eye(3),
    np.diag([2.0, 1.0, 1.0, 1.0]),  # scale
    np.diag([-1.0, 1.0, 1.0, 1.0]),  # reflection
    np.full((4, 4), np.nan),
    np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1.0]]),  # projective last row
])
def test_bad_pose(pose):
    with pytest.raises(ValueError, match="pose"):
        PerspectiveCamera().pose = pose


def test_bad_look_at():
    cam = PerspectiveCamera()
    with pytest.raises(ValueError, match="eye and target"):
        cam.look_at((1, 2, 3), (1, 2, 3))
    with pytest.raises(ValueError, match="up"):
        cam.look_at((0, 5, 0), (0, 0, 0), up=(0, 1, 0))
    with pytest.raises(ValueError, match="up"):
        cam.look_at((0, 0, 5), (0, 0, 0), up=(0, 0, 0))
    with pytest.raises(ValueError, match="eye"):
        cam.look_at((0, np.nan, 5), (0, 0, 0))
    with pytest.raises(ValueError, match="target"):
        cam.look_at((0, 0, 5), (0, np.inf, 0))
    with pytest.raises(ValueError, match="eye"):
        cam.look_at((0, 5), (0, 0, 0))
    np.testing.assert_array_equal(cam.pose, np.eye(4))  # failed calls left the pose alone


@pytest.mark.parametrize("kwargs, name", [
    ({"near": 0.0}, "near"),
    ({"near": -1.0}, "near"),
    ({"near": np.nan}, "near"),
    ({"far": 0.01}, "far"),
    ({"near": 1.0, "far": 1.0}, "far"),
    ({"far": np.inf}, "far"),
    ({"fov_y": 0.0}, "fov_y"),
    ({"fov_y": 180.0}, "fov_y"),
    ({"fov_y": np.nan}, "fov_y"),
    ({"aspect": 0.0}, "aspect"),
    ({"width": 0}, "width"),
    ({"height": -3}, "height"),
])
def test_bad_perspective(kwargs, name):
    with pytest.raises(ValueError, match=name):
        PerspectiveCamera(**kwargs)


@pytest.mark.parametrize("kwargs, name", [
    ({"xmag": 0.0}, "xmag"), ({"ymag": -1.0}, "ymag"), ({"xmag": np.inf}, "xmag"),
    ({"near": 0.0}, "near"), ({"near": 2.0, "far": 1.0}, "far"),
])
def test_bad_orthographic(kwargs, name):
    with pytest.raises(ValueError, match=name):
        OrthographicCamera(**kwargs)


@pytest.mark.parametrize("kwargs, name, error", [
    ({"fx": 0.0}, "fx", ValueError),
    ({"fy": -5.0}, "fy", ValueError),
    ({"fx": np.nan}, "fx", ValueError),
    ({"cx": np.inf}, "cx", ValueError),
    ({"width": 0}, "width", ValueError),
    ({"height": None}, "height", ValueError),
    ({"width": 64.5}, "width", TypeError),
    ({"convention": "directx"}, "convention", ValueError),
    ({"near": -0.1}, "near", ValueError),
])
def test_bad_intrinsics(kwargs, name, error):
    args = {"fx": 100.0, "fy": 100.0, "cx": 32.0, "cy": 24.0, "width": 64, "height": 48, **kwargs}
    with pytest.raises(error, match=name):
        IntrinsicsCamera(**args)


def test_intrinsics_refuses_other_image_size():
    cam = IntrinsicsCamera(100, 100, 32, 24, 64, 48)
    with pytest.raises(ValueError, match="64x48"):
        cam.projection_matrix(128, 96)
    np.testing.assert_array_equal(cam.projection_matrix(), cam.projection_matrix(64, 48))


# Every camera argument checked by name at construction; nothing that passes
# can fail at render time ("projection matrix is not finite", ZeroDivisionError).

@pytest.mark.parametrize("make, error, name", [
    (lambda: PerspectiveCamera(fov_y=True), TypeError, "fov_y"),  # was: accepted as 1 degree
    (lambda: PerspectiveCamera(fov_y="45"), TypeError, "fov_y"),  # was: accepted as 45
    (lambda: PerspectiveCamera(fov_y=45 + 0j), TypeError, "fov_y"),
    (lambda: PerspectiveCamera(fov_y=None), TypeError, "fov_y"),
    (lambda: PerspectiveCamera(fov_y=np.array([45.0])), TypeError, "fov_y"),
    (lambda: PerspectiveCamera(fov_y=5e-324), ValueError, "fov_y"),  # was: ZeroDivisionError at render
    (lambda: PerspectiveCamera(fov_y=1e-35), ValueError, "fov_y"),  # f * 16384 > float32 max
    (lambda: PerspectiveCamera(fov_y=1e-34, width=1, height=16384), ValueError, "fov_y"),
    (lambda: PerspectiveCamera(aspect=1e-300), ValueError, "aspect"),
    (lambda: PerspectiveCamera(aspect="1.5"), TypeError, "aspect"),
    (lambda: PerspectiveCamera(near=True), TypeError, "near"),
    (lambda: PerspectiveCamera(far="100"), TypeError, "far"),
    (lambda: PerspectiveCamera(near=None), TypeError, "near"),
    (lambda: PerspectiveCamera(near=1e30, far=1e30 + 1e15), ValueError, "near and far"),
    (lambda: PerspectiveCamera(near=1e39, far=1e40), ValueError, "near and far"),
    (lambda: OrthographicCamera(near=1e-39, far=2e-39), ValueError, "near and far"),  # 2 / (f - n) = 2e39
    (lambda: PerspectiveCamera(width=True), TypeError, "width"),
    (lambda: PerspectiveCamera(height=10**6), ValueError, "height"),
    (lambda: OrthographicCamera(xmag=5e-324), ValueError, "xmag"),  # was: "projection matrix is not finite"
    (lambda: OrthographicCamera(ymag=1e-39), ValueError, "ymag"),
    (lambda: OrthographicCamera(xmag=True), TypeError, "xmag"),
    (lambda: OrthographicCamera(ymag="1"), TypeError, "ymag"),
    (lambda: IntrinsicsCamera(True, 100, 32, 24, 64, 48), TypeError, "fx"),
    (lambda: IntrinsicsCamera(100, "100", 32, 24, 64, 48), TypeError, "fy"),
    (lambda: IntrinsicsCamera(1e308, 100, 32, 24, 64, 48), ValueError, "fx"),  # 2 fx / w = inf
    (lambda: IntrinsicsCamera(100, 1e40, 32, 24, 64, 48), ValueError, "fy"),
    (lambda: IntrinsicsCamera(100, 100, 1e308, 24, 64, 48), ValueError, "cx"),
    (lambda: IntrinsicsCamera(100, 100, 32, -1e40, 64, 48), ValueError, "cy"),
    (lambda: IntrinsicsCamera(100, 100, 32, 24, 64, 48, convention=None), TypeError, "convention"),
    (lambda: IntrinsicsCamera(100, 100, 32, 24, 64.0, 48), TypeError, "width"),
    (lambda: PerspectiveCamera().look_at((True, 0, 0), (0, 0, -1)), TypeError, "eye"),
    (lambda: PerspectiveCamera().look_at((0, 0, 1), "abc"), TypeError, "target"),
    (lambda: PerspectiveCamera().look_at((0, 0, 1), (0, 0, 0), up=None), TypeError, "up"),
    (lambda: PerspectiveCamera().look_at((1e308, 0, 0), (-1e308, 0, 0)), ValueError, "eye"),  # overflow
])
def test_bad_camera_argument_raises_at_construction_naming_it(make, error, name):
    with pytest.raises(error, match=f"^{name}"):
        make()


@pytest.mark.parametrize("pose, error", [
    ([["1", "0", "0", "0"], ["0", "1", "0", "0"], ["0", "0", "1", "0"], ["0", "0", "0", "1"]], TypeError),
    (np.eye(4, dtype=bool), TypeError),
    (np.diag([1e200, 1e200, 1e200, 1.0]), ValueError),  # was: a RuntimeWarning (overflow)
])
def test_bad_camera_pose_raises_naming_it(pose, error):
    cam = PerspectiveCamera()
    with pytest.raises(error, match="^pose"):
        cam.pose = pose


@pytest.mark.parametrize("make", [
    lambda: PerspectiveCamera(fov_y=1e-34, width=16, height=16),  # f = 1.1e36: finite at 1:1
    lambda: PerspectiveCamera(fov_y=179.9999, near=1e-30, far=1e30),
    lambda: PerspectiveCamera(fov_y=1e-30, aspect=1e-3),
    lambda: OrthographicCamera(xmag=1e-38, ymag=1e38, near=1e-30, far=1e30),
    lambda: IntrinsicsCamera(1e38, 1e-300, 1e38, -1e38, 64, 48),
])
def test_extreme_but_valid_cameras_render(make):
    # What construction accepts, the core renders (finite projection in float32).
    import softrast as sr

    scene = sr.Scene()
    scene.add(sr.Mesh([[0, 0, -1.0], [1, 0, -1.0], [0, 1, -1.0]], [[0, 1, 2]]))
    cam = make()
    w, h = cam.width or 64, cam.height or 48
    proj = cam.projection_matrix(w, h)
    assert (np.abs(proj) <= np.finfo(np.float32).max).all()
    frame = sr.Renderer(w, h).render(scene, cam, outputs=("depth", "mask", "normal"))
    assert np.isfinite(frame.depth).all() and np.array_equal(frame.mask, frame.depth > 0)
