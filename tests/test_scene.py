"""Scene: instance records, ids, colour overrides, validation and world-space bounds."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from softrast.mesh import Mesh
from softrast.scene import Scene


@pytest.fixture
def cube() -> Mesh:
    """Axis-aligned cube [-0.5, 0.5]^3 (8 vertices)."""
    tm = trimesh.creation.box()
    return Mesh(tm.vertices, tm.faces, color=(0.2, 0.4, 0.6))


def test_add_assigns_sequential_ids_and_records(cube):
    scene = Scene()
    assert len(scene) == 0
    assert scene.add(cube) == 0
    assert scene.add(cube, instance_id=7, color=(1, 0, 0)) == 7
    assert scene.add(cube) == 2  # default = number of instances added before
    assert len(scene) == 3
    first, second, third = scene.instances
    assert first.mesh is cube and first.instance_id == 0
    np.testing.assert_array_equal(first.pose, np.eye(4))
    assert first.pose.dtype == np.float64
    assert first.color == cube.color == (0.2, 0.4, 0.6, 1.0)
    assert second.color == (1.0, 0.0, 0.0, 1.0)  # override, alpha filled in
    assert third.instance_id == 2


def test_instances_list_is_a_copy_and_pose_is_frozen(cube):
    scene = Scene()
    pose = np.eye(4)
    scene.add(cube, pose=pose)
    pose[0, 3] = 3.0
    assert scene.instances[0].pose[0, 3] == 0.0  # the scene kept its own copy
    scene.instances.clear()
    assert len(scene) == 1
    with pytest.raises(ValueError):
        scene.instances[0].pose[0, 0] = 2.0


def test_clear(cube):
    scene = Scene()
    scene.add(cube)
    scene.add(cube)
    scene.clear()
    assert len(scene) == 0 and scene.instances == []
    assert scene.add(cube) == 0


def test_bounds_of_transformed_vertices(cube):
    scene = Scene()
    # 90 degrees about z, scale 2, translate (10, 0, 0): x' = -2y + 10, y' = 2x, z' = 2z.
    pose = np.array([[0, -2, 0, 10], [2, 0, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]], dtype=np.float64)
    scene.add(cube, pose=pose)
    np.testing.assert_allclose(scene.bounds, [[9, -1, -1], [11, 1, 1]], atol=1e-12)
    scene.add(cube, pose=np.diag([1.0, 1.0, 1.0, 1.0]))
    np.testing.assert_allclose(scene.bounds, [[-0.5, -1, -1], [11, 1, 1]], atol=1e-12)
    assert scene.bounds.shape == (2, 3) and scene.bounds.dtype == np.float64


def test_bounds_rotated_is_exact_not_corner_box(rng):
    # A rotated icosphere's vertex AABB is tighter than the rotated corners of its object AABB.
    tm = trimesh.creation.icosphere(subdivisions=3)
    mesh = Mesh(tm.vertices, tm.faces)
    rot = trimesh.transformations.rotation_matrix(0.7, [1, 2, 3])
    scene = Scene()
    scene.add(mesh, pose=rot)
    world = tm.vertices @ rot[:3, :3].T
    np.testing.assert_allclose(scene.bounds, [world.min(0), world.max(0)], atol=1e-6)


def test_empty_bounds():
    with pytest.raises(ValueError, match="empty"):
        Scene().bounds


@pytest.mark.parametrize("kwargs, error, match", [
    ({"pose": np.eye(3)}, ValueError, "pose"),
    ({"pose": np.full((4, 4), np.nan)}, ValueError, "pose"),
    ({"pose": np.ones((4, 4))}, ValueError, "pose"),  # last row not [0, 0, 0, 1]
    ({"pose": "identity"}, TypeError, "pose"),
    ({"instance_id": -1}, ValueError, "instance_id"),
    ({"instance_id": 2**31}, ValueError, "instance_id"),  # beyond int32
    ({"instance_id": 1.5}, TypeError, "instance_id"),
    ({"instance_id": True}, TypeError, "instance_id"),
    ({"color": (2, 0, 0)}, ValueError, "color"),
    ({"color": (1, 0)}, ValueError, "color"),
])
def test_bad_add(cube, kwargs, error, match):
    scene = Scene()
    with pytest.raises(error, match=match):
        scene.add(cube, **kwargs)
    assert len(scene) == 0


def test_largest_instance_id_and_numpy_ints(cube):
    scene = Scene()
    assert scene.add(cube, instance_id=np.int64(2**31 - 1)) == 2**31 - 1  # int32 max
    assert type(scene.instances[0].instance_id) is int


def test_add_rejects_non_mesh():
    with pytest.raises(TypeError, match="mesh"):
        Scene().add(trimesh.creation.box())


@pytest.mark.parametrize("kwargs, error", [
    ({"pose": [["1", "0", "0", "0"], ["0", "1", "0", "0"], ["0", "0", "1", "0"], ["0", "0", "0", "1"]]},
     TypeError),  # numeric strings were converted by NumPy and accepted
    ({"pose": np.eye(4, dtype=bool)}, TypeError),  # bools are not numbers (was: accepted)
    ({"pose": np.eye(4) * (1 + 0j)}, TypeError),
    ({"pose": [[1, 0, 0], [0, 1]]}, TypeError),  # ragged
    ({"pose": None}, None),  # None => identity
    ({"instance_id": np.bool_(True)}, TypeError),
    ({"instance_id": "3"}, TypeError),
    ({"instance_id": np.float64(3.0)}, TypeError),
    ({"color": "red"}, TypeError),
    ({"color": (True, False, False)}, TypeError),
])
def test_add_arguments_of_the_wrong_kind_raise_naming_them(cube, kwargs, error):
    scene = Scene()
    if error is None:
        scene.add(cube, **kwargs)
        return
    name = next(iter(kwargs))
    with pytest.raises(error, match=f"^{name}"):
        scene.add(cube, **kwargs)
    assert len(scene) == 0


def test_renders_follow_every_change_to_the_scene():
    """render.py caches what it derives from a scene (draw and light records) until the scene
    changes: adding a mesh or a light, clearing it, or setting ambient_light must show."""
    import trimesh

    import softrast as sr

    tm = trimesh.creation.icosphere(subdivisions=2)
    mesh = sr.Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals)
    cam = sr.PerspectiveCamera(fov_y=45.0)
    cam.look_at((0, 0, 4), (0, 0, 0))
    r = sr.Renderer(48, 32)
    scene = sr.Scene()
    scene.add(mesh)

    def radiance():
        return r.render(scene, cam, outputs=("radiance",)).radiance.copy()

    headlit = radiance()
    pose = np.eye(4)
    pose[:3, 3] = (0, 3, 1)
    scene.add(sr.PointLight(intensity=5.0), pose=pose)
    lit = radiance()
    assert not np.array_equal(headlit, lit)
    scene.ambient_light = (0.5, 0.5, 0.5)
    brighter = radiance()
    assert (brighter >= lit).all() and (brighter > lit).any()
    scene.add(mesh, pose=np.diag([0.5, 0.5, 0.5, 1.0]) @ np.array(
        [[1, 0, 0, 1.5], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], float))
    assert not np.array_equal(radiance(), brighter)
    scene.clear()  # instances and lights; the ambient light stays
    assert not radiance().any()
    scene.add(mesh)
    assert not np.array_equal(radiance(), headlit)
    scene.ambient_light = None
    np.testing.assert_array_equal(radiance(), headlit)
    # A camera moved between renders moves the headlight with it.
    cam.look_at((4, 0, 0), (0, 0, 0))
    side = radiance()
    cam.look_at((0, 0, 4), (0, 0, 0))
    np.testing.assert_array_equal(radiance(), headlit)
    assert side.any()


def test_set_pose_and_remove_edit_the_scene_between_views():
    """Moving or removing an instance renders as a scene built that way from scratch."""
    import softrast as sr

    tm_mesh = sr.Mesh(np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]]))
    cam = sr.OrthographicCamera(xmag=3.0, ymag=3.0, width=32, height=32)
    cam.pose = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 5.0], [0, 0, 0, 1]])
    r = sr.Renderer(32, 32)
    shift = lambda x: np.array([[1, 0, 0, x], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])  # noqa: E731
    scene = sr.Scene()
    a = scene.add(tm_mesh, pose=shift(-1.5), instance_id=1)
    scene.add(tm_mesh, pose=shift(1.5), instance_id=2)
    r.render(scene, cam, outputs=("instance_id",))  # (fills the scene's render cache)
    moved = scene.set_pose(a, shift(0.5))
    assert moved.instance_id == 1 and moved is scene.instances[0]
    fresh = sr.Scene()
    fresh.add(tm_mesh, pose=shift(0.5), instance_id=1)
    fresh.add(tm_mesh, pose=shift(1.5), instance_id=2)
    np.testing.assert_array_equal(r.render(scene, cam, outputs=("instance_id",)).instance_id,
                                  r.render(fresh, cam, outputs=("instance_id",)).instance_id)
    scene.set_pose(scene.instances[1], shift(-2.0))  # by Instance
    removed = scene.remove(1)
    assert removed.instance_id == 1 and len(scene) == 1
    alone = sr.Scene()
    alone.add(tm_mesh, pose=shift(-2.0), instance_id=2)
    np.testing.assert_array_equal(r.render(scene, cam, outputs=("instance_id",)).instance_id,
                                  r.render(alone, cam, outputs=("instance_id",)).instance_id)
    scene.add(tm_mesh, instance_id=2)
    with pytest.raises(ValueError, match="names 2 instances"):
        scene.set_pose(2, np.eye(4))
    with pytest.raises(ValueError, match="no instance has id 7"):
        scene.remove(7)
    with pytest.raises(ValueError, match="not in this scene"):
        scene.remove(removed)
    with pytest.raises(ValueError, match="pose"):
        scene.set_pose(scene.instances[0], np.full((4, 4), np.nan))
