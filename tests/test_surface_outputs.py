"""Surface outputs: barycentric, uv, position and ray_depth, read from the visible
triangle at each pixel, and normals in camera space. Checked against the mesh (the weights
rebuild the position from the face's corners), against the camera (positions project back to
their pixel centres; ray depth is the distance to the camera centre) and against closed forms
(uvs of a quad, a sphere's positions)."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import softrast as sr
from test_texture_render import _opencv_plane_camera, _plane_uv, ortho_camera, quad

SURFACE = ("barycentric", "uv", "position", "ray_depth")


def _sphere_scene(centre=(0.2, -0.1, 0.0)):
    tm = trimesh.creation.icosphere(subdivisions=5)
    mesh = sr.Mesh(tm.vertices, tm.faces, uvs=np.asarray(tm.vertices)[:, :2] * 0.5 + 0.5)
    pose = np.eye(4)
    pose[:3, 3] = centre
    scene = sr.Scene()
    scene.add(mesh, pose=pose)
    return scene, mesh, pose


def _pixel_of(camera, w, h, points):
    """OpenCV pixel coordinates (centre of pixel (row i, col j) at (j, i)) of world points."""
    clip = np.c_[points, np.ones(len(points))] @ (camera.projection_matrix(w, h) @ camera.view_matrix()).T
    ndc = clip[:, :3] / clip[:, 3:]
    return np.c_[(ndc[:, 0] + 1) * w / 2 - 0.5, (1 - ndc[:, 1]) * h / 2 - 0.5]


def _check_against_mesh(frame, mesh, pose, camera, w, h, eye):
    vis = frame.triangle_id >= 0
    bary = frame.barycentric[vis].astype(np.float64)
    assert (bary >= -1e-3).all() and (bary <= 1 + 1e-3).all()  # the exact hit's: outside by the snap
    np.testing.assert_allclose(bary.sum(1), 1.0, atol=3e-7)
    corners = mesh.positions[mesh.faces[frame.triangle_id[vis]]].astype(np.float64)  # (n, 3, 3)
    world = (np.einsum("nc,ncd->nd", bary, corners)) @ pose[:3, :3].T + pose[:3, 3]
    np.testing.assert_allclose(frame.position[vis], world, rtol=0, atol=2e-6)
    uv = np.einsum("nc,ncd->nd", bary, mesh.uvs[mesh.faces[frame.triangle_id[vis]]].astype(np.float64))
    np.testing.assert_allclose(frame.uv[vis], uv, rtol=0, atol=1e-6)
    # each point lies on its pixel's ray: it projects back to the pixel centre (the exact step:
    # to float32's rounding of the position)
    rows, cols = np.nonzero(vis)
    px = _pixel_of(camera, w, h, frame.position[vis].astype(np.float64))
    assert np.abs(px - np.c_[cols, rows]).max() < 1e-4
    if eye is not None:
        dist = np.linalg.norm(frame.position[vis].astype(np.float64) - eye, axis=1)
        np.testing.assert_allclose(frame.ray_depth[vis], dist, rtol=1e-6)
    for name in SURFACE:  # background
        assert (getattr(frame, name)[~vis] == 0).all(), name


def test_sphere_surface_outputs_against_the_mesh_and_camera() -> None:
    w, h = 96, 72
    scene, mesh, pose = _sphere_scene()
    cam = sr.PerspectiveCamera(fov_y=45.0, width=w, height=h, near=0.1, far=20.0)
    cam.look_at((1.0, 1.5, 3.5), (0.2, -0.1, 0.0))
    frame = sr.Renderer(w, h).render(scene, cam, outputs=SURFACE + ("triangle_id", "depth"))
    vis = frame.triangle_id >= 0
    assert vis.mean() > 0.2
    _check_against_mesh(frame, mesh, pose, cam, w, h, eye=np.array([1.0, 1.5, 3.5]))
    # on the sphere (up to its facets: icosphere 5's sag is under 5e-4)
    r = np.linalg.norm(frame.position[vis] - [0.2, -0.1, 0.0], axis=1)
    assert np.abs(r - 1).max() < 5e-4
    # ray depth over depth is the length of the pixel's ray at unit depth
    view = np.c_[frame.position[vis], np.ones(vis.sum())] @ cam.view_matrix().T
    np.testing.assert_allclose(frame.ray_depth[vis] / np.linalg.norm(view[:, :3], axis=1), 1, rtol=1e-6)


def test_uv_of_a_quad_one_pixel_per_uv_step() -> None:
    """An orthographic quad filling the image: the uv at pixel (i, j) is ((j + 1/2) / w,
    1 - (i + 1/2) / h)."""
    w, h = 40, 24
    scene = sr.Scene()
    scene.add(quad(sr.Material()))
    frame = sr.Renderer(w, h).render(scene, ortho_camera(w, h), outputs=("uv", "ray_depth", "depth"))
    j, i = np.meshgrid(np.arange(w), np.arange(h))
    np.testing.assert_allclose(frame.uv[..., 0], (j + 0.5) / w, atol=2e-7)
    np.testing.assert_allclose(frame.uv[..., 1], 1 - (i + 0.5) / h, atol=2e-7)
    np.testing.assert_array_equal(frame.ray_depth, frame.depth)  # orthographic: along the rays


def test_uv_and_position_of_a_tilted_plane_against_the_analytic_ray() -> None:
    """A perspective plane at about 60 degrees: uvs at pixel centres against the float64 ray
    intersection (the rasterizer's vertex snapping, 1/256 pixel, bounds the difference)."""
    w, h, size = 96, 72, 1.5
    cam, K, R, t = _opencv_plane_camera(w, h)
    scene = sr.Scene()
    scene.add(quad(sr.Material(), size=size))
    frame = sr.Renderer(w, h).render(scene, cam, outputs=("uv", "position", "triangle_id"))
    rows, cols = np.nonzero(frame.triangle_id >= 0)
    assert rows.size > 0.4 * w * h
    uv = _plane_uv(K, R, t, cols.astype(np.float64), rows.astype(np.float64), size)
    err = np.abs(frame.uv[rows, cols] - uv)
    assert err.max() < 2e-4 and np.median(err) < 2e-5, (err.max(), np.median(err))
    np.testing.assert_allclose(frame.position[rows, cols][:, :2], uv * 2 * size - size, atol=6e-4)
    assert np.abs(frame.position[rows, cols][:, 2]).max() < 1e-6  # on the plane z = 0


def test_clipped_faces_report_weights_of_the_whole_face() -> None:
    """A ground plane crossing the near plane: its clipped pieces still give weights of the
    mesh face, which rebuild the position from the face's corners."""
    w, h = 80, 60
    cam = sr.PerspectiveCamera(fov_y=70.0, near=0.05, far=50.0, width=w, height=h)
    cam.look_at((0.0, 0.4, 0.0), (0.0, 0.0, -2.0))
    ground = np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1.0]])
    mesh = quad(sr.Material(), size=10.0)
    scene = sr.Scene()
    scene.add(mesh, pose=ground)
    frame = sr.Renderer(w, h).render(scene, cam, outputs=SURFACE + ("triangle_id",), cull="none")
    assert frame.triangle_id[-1].min() >= 0  # the plane under the camera fills the bottom row
    _check_against_mesh(frame, mesh, ground, cam, w, h, eye=np.array([0.0, 0.4, 0.0]))


def test_same_bits_across_instruction_sets_threads_and_with_other_outputs() -> None:
    w, h = 64, 48
    scene, _, _ = _sphere_scene()
    cam = sr.PerspectiveCamera(fov_y=45.0, width=w, height=h)
    cam.look_at((0.0, 0.0, 3.0), (0.0, 0.0, 0.0))
    ref = sr.Renderer(w, h, threads=1, simd=False).render(scene, cam, outputs=SURFACE)
    for threads, simd, extra in ((2, True, ()), (3, False, ("color", "normal")), (1, True, ("coverage",))):
        f = sr.Renderer(w, h, threads=threads, simd=simd).render(scene, cam, outputs=SURFACE + extra)
        for name in SURFACE:
            np.testing.assert_array_equal(getattr(f, name), getattr(ref, name))


def test_normals_in_camera_space() -> None:
    w, h = 64, 48
    scene, _, _ = _sphere_scene(centre=(0.0, 0.0, 0.0))
    cam = sr.PerspectiveCamera(fov_y=45.0, width=w, height=h)
    cam.look_at((1.5, 2.0, 2.0), (0.0, 0.0, 0.0))
    r = sr.Renderer(w, h)
    world = r.render(scene, cam, outputs=("normal", "mask"))
    camera = r.render(scene, cam, outputs=("normal", "position"), normal_space="camera")
    rot = cam.pose[:3, :3]  # camera -> world
    vis = world.mask
    np.testing.assert_allclose(camera.normal[vis], world.normal[vis] @ rot, atol=2e-6)
    assert (camera.normal[~vis] == 0).all()
    # a sphere seen from outside: every visible normal faces the camera (+z in OpenGL's camera
    # axes points back toward the eye)
    to_eye = (np.array([1.5, 2.0, 2.0]) - camera.position[vis]) @ rot
    assert (np.einsum("nd,nd->n", camera.normal[vis], to_eye) > 0).all()
    assert np.median(camera.normal[vis][:, 2]) > 0.5
    # an OpenCV-convention camera: its own axes (z forward), so visible normals point to -z
    K = cam.intrinsics(w, h)
    cv = sr.IntrinsicsCamera(K[0, 0], K[1, 1], K[0, 2], K[1, 2], w, h)
    cv.look_at((1.5, 2.0, 2.0), (0.0, 0.0, 0.0))
    f = r.render(scene, cv, outputs=("normal",), normal_space="camera")
    np.testing.assert_allclose(f.normal[vis], camera.normal[vis] * [1, -1, -1], atol=2e-6)
    with pytest.raises(ValueError, match="normal_space"):
        r.render(scene, cam, outputs=("normal",), normal_space="eye")
