"""Cameras for datasets: K in OpenCV's convention for every pinhole camera,
project / unproject consistent with the renderer, the degrees-or-radians warning, and the pose
generators orbit / sphere_poses."""
from __future__ import annotations

import warnings

import cv2
import numpy as np
import pytest
import trimesh

import softrast as sr

W, H = 96, 72


def _cameras():
    persp = sr.PerspectiveCamera(fov_y=50.0, width=W, height=H, near=0.1, far=30.0)
    intr_cv = sr.IntrinsicsCamera(80.0, 85.0, 47.3, 35.1, W, H, near=0.1, far=30.0)
    intr_gl = sr.IntrinsicsCamera(80.0, 85.0, 47.3, 35.1, W, H, near=0.1, far=30.0, convention="opengl")
    for cam in (persp, intr_cv, intr_gl):
        cam.look_at((1.2, 1.0, 3.0), (0.1, -0.2, 0.0))
    return {"perspective": persp, "intrinsics_opencv": intr_cv, "intrinsics_opengl": intr_gl}


def _scene():
    tm = trimesh.creation.icosphere(subdivisions=4)
    scene = sr.Scene()
    scene.add(sr.Mesh(tm.vertices * 0.8, tm.faces), pose=np.array(
        [[1, 0, 0, 0.1], [0, 1, 0, -0.2], [0, 0, 1, 0], [0, 0, 0, 1.0]]))
    return scene


@pytest.mark.parametrize("name", ["perspective", "intrinsics_opencv", "intrinsics_opengl"])
def test_K_and_project_agree_with_opencv_and_the_renderer(name: str) -> None:
    cam = _cameras()[name]
    K = cam.K
    assert K.shape == (3, 3) and K[0, 1] == K[1, 0] == 0 and K[2].tolist() == [0, 0, 1]
    if name == "intrinsics_opencv":
        np.testing.assert_array_equal(K, [[80.0, 0, 47.3], [0, 85.0, 35.1], [0, 0, 1]])
    if name == "intrinsics_opengl":  # pyrender's (cx, cy) are from the corner: half a pixel off
        np.testing.assert_allclose(K, cam.to_opencv()[0], atol=1e-12)
        np.testing.assert_allclose(K[:2, 2], [46.8, 34.6], atol=1e-12)
    # cv2.projectPoints with K and the pose's OpenCV extrinsics gives project()'s pixels
    pts = np.random.default_rng(0).normal(size=(50, 3)) * 0.5
    view_cv = np.diag([1.0, -1, -1, 1]) @ cam.view_matrix()
    rvec, _ = cv2.Rodrigues(view_cv[:3, :3])
    uv_cv, _ = cv2.projectPoints(pts, rvec, view_cv[:3, 3], K, None)
    np.testing.assert_allclose(cam.project(pts), uv_cv.reshape(-1, 2), atol=1e-9)
    # and the renderer: every visible point projects back onto its own pixel centre
    frame = sr.Renderer(W, H).render(_scene(), cam, outputs=("position", "mask"))
    rows, cols = np.nonzero(frame.mask)
    assert rows.size > 500
    uv = cam.project(frame.position[rows, cols].astype(np.float64))
    assert np.abs(uv - np.c_[cols, rows]).max() < 0.01


def test_project_behind_the_camera_is_nan_and_orthographic_has_no_K() -> None:
    cam = _cameras()["perspective"]
    uv = cam.project([[1.2, 1.0, 5.0], [0.1, -0.2, 0.0]])  # behind the eye, then the target
    assert np.isnan(uv[0]).all() and np.isfinite(uv[1]).all()
    np.testing.assert_allclose(uv[1], [(W - 1) / 2, (H - 1) / 2], atol=1e-9)  # target at the centre
    ortho = sr.OrthographicCamera(xmag=2.0, ymag=1.5, width=W, height=H)
    with pytest.raises(ValueError, match="orthographic"):
        ortho.K
    np.testing.assert_allclose(ortho.project([[0.0, 0.0, -5.0], [2.0, 1.5, -1.0]]),
                               [[(W - 1) / 2, (H - 1) / 2], [W - 0.5, -0.5]], atol=1e-9)
    with pytest.raises(ValueError, match="width and height"):
        sr.PerspectiveCamera().K
    np.testing.assert_allclose(sr.PerspectiveCamera(fov_y=90.0).intrinsics(200, 100),
                               [[50, 0, 99.5], [0, 50, 49.5], [0, 0, 1]], atol=1e-12)


@pytest.mark.parametrize("name", ["perspective", "intrinsics_opencv", "intrinsics_opengl", "orthographic"])
def test_unproject_depth_gives_the_rendered_points(name: str) -> None:
    """unproject(frame.depth) puts each pixel's centre at its depth: it projects back onto the
    pixel centre exactly, and lands on the renderer's own positions up to the 1/256-pixel vertex
    snapping (depth comes from the snapped triangle's plane, position from its weights applied
    to the unsnapped corners: ~1e-3 pixel apart laterally, more along grazing rays)."""
    if name == "orthographic":
        cam = sr.OrthographicCamera(xmag=1.2, ymag=0.9, width=W, height=H, near=0.1, far=30.0)
        cam.look_at((1.2, 1.0, 3.0), (0.1, -0.2, 0.0))
    else:
        cam = _cameras()[name]
    frame = sr.Renderer(W, H).render(_scene(), cam, outputs=("depth", "position", "mask"))
    world = cam.unproject(frame.depth)
    assert world.shape == (H, W, 3) and world.dtype == np.float64
    m = frame.mask
    rows, cols = np.nonzero(m)
    np.testing.assert_allclose(cam.project(world[m]), np.c_[cols, rows], atol=1e-9)
    err = np.linalg.norm(world[m] - frame.position[m], axis=1)  # the scene is ~3 units away
    assert np.median(err) < 1e-4 and np.percentile(err, 90) < 5e-4, (np.median(err), err.max())
    assert (world[~m] == 0).all()
    local = cam.unproject(frame.depth, space="camera")
    z = local[..., 2][m]
    np.testing.assert_allclose(z, frame.depth[m] if cam.convention == "opencv" else -frame.depth[m], rtol=1e-12)
    back = local[m] @ cam.pose[:3, :3].T + cam.pose[:3, 3]  # world = pose @ camera point
    np.testing.assert_allclose(back, world[m], atol=1e-9)


def test_unproject_checks_its_arguments() -> None:
    cam = _cameras()["perspective"]
    with pytest.raises(ValueError, match="space"):
        cam.unproject(np.ones((H, W)), space="view")
    with pytest.raises(ValueError, match="depth"):
        cam.unproject(np.ones(5))
    with pytest.raises(ValueError, match="depth"):
        cam.unproject(np.full((H, W), np.nan))
    with pytest.raises(ValueError, match="width x height|differs"):
        _cameras()["intrinsics_opencv"].unproject(np.ones((10, 10)))


def test_fov_in_radians_warns() -> None:
    with pytest.warns(UserWarning, match="did you pass radians"):
        sr.PerspectiveCamera(fov_y=0.8)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sr.PerspectiveCamera(fov_y=45.0)
        sr.PerspectiveCamera(fov_y=0.01)  # a deliberate telephoto, far below any radians fov
        sr.PerspectiveCamera(fov_y=3.2)


@pytest.mark.parametrize("convention", ["opengl", "opencv"])
def test_orbit_poses(convention: str) -> None:
    target = np.array([0.3, -0.2, 1.0])
    poses = sr.orbit(target, 2.5, 12, elevation=30.0, convention=convention)
    assert poses.shape == (12, 4, 4)
    eyes = poses[:, :3, 3]
    np.testing.assert_allclose(np.linalg.norm(eyes - target, axis=1), 2.5, rtol=1e-12)
    np.testing.assert_allclose(np.degrees(np.arcsin((eyes - target)[:, 1] / 2.5)), 30.0, atol=1e-9)
    forward = poses[:, :3, 2] * (1.0 if convention == "opencv" else -1.0)  # the viewing direction
    np.testing.assert_allclose(forward, (target - eyes) / 2.5, atol=1e-12)
    azimuth = np.degrees(np.arctan2((eyes - target)[:, 0], (eyes - target)[:, 2]))
    np.testing.assert_allclose(np.diff(np.unwrap(np.radians(azimuth))), np.radians(30.0), atol=1e-9)
    # each pose sees the target at the image centre, upright (world up is up in the image)
    cam = sr.PerspectiveCamera(fov_y=40, width=64, height=48) if convention == "opengl" else \
        sr.IntrinsicsCamera(60, 60, 31.5, 23.5, 64, 48)
    for pose in poses:
        cam.pose = pose
        np.testing.assert_allclose(cam.project([target]), [[31.5, 23.5]], atol=1e-9)
        above = cam.project([target + [0, 0.1, 0]])[0]
        assert above[1] < 23.5


def test_sphere_poses_cover_the_sphere() -> None:
    target = np.zeros(3)
    poses = sr.sphere_poses(target, 3.0, 200)
    eyes = poses[:, :3, 3]
    np.testing.assert_allclose(np.linalg.norm(eyes, axis=1), 3.0, rtol=1e-12)
    dirs = eyes / 3.0
    assert np.linalg.norm(dirs.mean(axis=0)) < 0.01  # evenly spread
    # every direction of a dense test set has a pose within ~ the lattice spacing
    test = np.random.default_rng(1).normal(size=(2000, 3))
    test /= np.linalg.norm(test, axis=1, keepdims=True)
    nearest = np.degrees(np.arccos(np.clip((test @ dirs.T).max(axis=1), -1, 1)))
    assert nearest.max() < 12.0
    np.testing.assert_allclose(-poses[:, :3, 2], -dirs, atol=1e-12)  # all look at the centre
    assert np.isfinite(sr.sphere_poses(target, 1.0, 1)).all()  # n = 1: the top, roll chosen


def test_pose_generators_check_their_arguments() -> None:
    for call, match in ((lambda: sr.orbit((0, 0, 0), 1.0, 0), "n must be >= 1"),
                        (lambda: sr.orbit((0, 0, 0), -1.0, 4), "radius"),
                        (lambda: sr.orbit((0, 0, 0), 1.0, 4, elevation=100), "elevation"),
                        (lambda: sr.orbit((0, 0), 1.0, 4), "target"),
                        (lambda: sr.sphere_poses((0, 0, 0), 1.0, 4, up=(0, 0, 0)), "up"),
                        (lambda: sr.orbit((0, 0, 0), 1.0, 4, convention="dx"), "convention")):
        with pytest.raises(ValueError, match=match):
            call()
    with pytest.raises(TypeError, match="n must be an integer"):
        sr.orbit((0, 0, 0), 1.0, 2.5)
