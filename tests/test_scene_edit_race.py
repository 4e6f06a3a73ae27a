"""A scene edited by one thread while others render it: once the edits stop, every render shows
the scene's current state (a draw, wireframe, primitive or light record list
built from the old state and stored after an edit must not be used again)."""
from __future__ import annotations

import sys
import threading

import numpy as np
import pytest
import trimesh

import softrast as sr

OUTPUTS = ("color", "depth", "instance_id", "triangle_id")
SIZE = 40
WIRE = {"wireframe": True, "line_color": (1.0, 0.0, 0.0), "line_width": 1.0}


def _meshes() -> list[sr.Mesh]:
    return [sr.Mesh.from_trimesh(trimesh.creation.icosphere(subdivisions=1, radius=0.3)),
            sr.Mesh.from_trimesh(trimesh.creation.box(extents=(0.4, 0.4, 0.4)))]


def _pose(x: float, y: float, z: float = 0.0) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = (x, y, z)
    return pose


def _base_scene(meshes: list[sr.Mesh]) -> sr.Scene:
    scene = sr.Scene()
    scene.add(sr.DirectionalLight(intensity=2.0), camera_space=True)
    for k in range(40):  # many instances: building the records takes a while
        scene.add(meshes[k % 2], pose=_pose(-1.5 + 0.08 * k, -1.0 + 0.05 * k, -0.02 * k),
                  instance_id=k)
    scene.add(sr.Lines([[-1.0, 1.2, 0.5], [1.0, 1.2, 0.5]], [[0, 1]], color=(0.0, 1.0, 0.0)),
              instance_id=500)
    return scene


def _edits(scene: sr.Scene, meshes: list[sr.Mesh], trial: int) -> None:
    """A fixed sequence of edits (set_pose, add, remove; lines and lights too)."""
    for step in range(12):
        scene.set_pose(step % 40, _pose(0.1 * step - 0.6, 0.9 - 0.1 * trial % 5, 0.3))
        scene.add(meshes[step % 2], pose=_pose(-0.8 + 0.15 * step, 0.5, 0.4), instance_id=100 + step)
        if step % 3 == 2:
            scene.remove(100 + step - 1)
        if step % 4 == 1:
            scene.remove(20 + step)
        scene.set_pose(500, _pose(0.0, -0.1 * step))
        if step == 7:
            scene.add(sr.PointLight(intensity=3.0), pose=_pose(0.0, 2.0, 2.0))


def _camera() -> sr.PerspectiveCamera:
    cam = sr.PerspectiveCamera(fov_y=60.0, width=SIZE, height=SIZE)
    cam.look_at(eye=(0.0, 0.0, 4.0), target=(0.0, 0.0, 0.0))
    return cam


def _assert_same(got: sr.Frame, want: sr.Frame, what: str) -> None:
    differ = [name for name in OUTPUTS if not np.array_equal(getattr(got, name), getattr(want, name))]
    if differ:
        pytest.fail(f"{what}: {', '.join(differ)} differ from a fresh scene in the final state")


def test_renders_after_concurrent_edits_show_the_final_scene():
    meshes = _meshes()
    cam = _camera()
    old_interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads often: builds and edits interleave
    try:
        for trial in range(20):
            scene = _base_scene(meshes)
            stop = threading.Event()
            errors: list[BaseException] = []

            def renders(k: int) -> None:
                r = sr.Renderer(SIZE, SIZE, threads=1)
                try:
                    while not stop.is_set():
                        r.render(scene, cam, outputs=OUTPUTS, **(WIRE if k % 2 else {}))
                except BaseException as exc:  # noqa: BLE001 - reported below
                    errors.append(exc)

            threads = [threading.Thread(target=renders, args=(k,)) for k in range(3)]
            for t in threads:
                t.start()
            _edits(scene, meshes, trial)
            # The edits have stopped (the renders go on): the scene's state is final.
            fresh = _base_scene(meshes)
            _edits(fresh, meshes, trial)
            renderer = sr.Renderer(SIZE, SIZE, threads=1)
            want = renderer.render(fresh, cam, outputs=OUTPUTS)
            want_wire = renderer.render(fresh, cam, outputs=OUTPUTS, **WIRE)
            stop.set()
            for t in threads:
                t.join()
            assert not errors, errors
            _assert_same(renderer.render(scene, cam, outputs=OUTPUTS), want, f"trial {trial}")
            _assert_same(renderer.render(scene, cam, outputs=OUTPUTS, **WIRE), want_wire,
                         f"trial {trial}, wireframe")
            many = list(sr.Renderer(SIZE, SIZE, threads=2).render_many(
                scene, [cam, cam], outputs=OUTPUTS, workers=2))
            for frame in many:
                _assert_same(frame, want, f"trial {trial}, render_many")
    finally:
        sys.setswitchinterval(old_interval)


class _EditBeforeStore(dict):
    """A scene's render cache that runs ``edit`` (as another thread would) once, just before the
    records built for ``key`` are stored: the build read the scene before the edit."""

    def __init__(self, key, edit):
        super().__init__()
        self.key, self.edit = key, edit

    def __setitem__(self, key, value):
        if key == self.key and self.edit is not None:
            edit, self.edit = self.edit, None
            edit()
        super().__setitem__(key, value)


def _edit_mid_build_then_render(key, camera, outputs, **options) -> None:
    meshes = _meshes()

    def build(scene):
        scene.add(meshes[0], instance_id=3)
        scene.add(meshes[1], pose=_pose(0.5, 0.2, 0.3), instance_id=5)
        return scene

    def edit(scene):
        scene.set_pose(5, _pose(-0.4, -0.3, 0.5))
        scene.remove(3)
        scene.add(meshes[0], pose=_pose(0.3, 0.4, -0.2), instance_id=9)

    scene = build(sr.Scene())
    cache = scene._render_cache = _EditBeforeStore(key, lambda: edit(scene))
    w, h = camera.width, camera.height
    renderer = sr.Renderer(w, h, threads=1)
    renderer.render(scene, camera, outputs, **options)  # the build that the edit overtakes
    assert cache.edit is None and [i.instance_id for i in scene.instances] == [5, 9]
    fresh = build(sr.Scene())
    edit(fresh)
    want = renderer.render(fresh, camera, outputs, **options)
    got = renderer.render(scene, camera, outputs, **options)
    differ = [n for n in outputs if not np.array_equal(getattr(got, n), getattr(want, n))]
    assert not differ, f"{differ} show the scene from before the edit"


def test_an_edit_during_the_draw_build_is_not_undone():
    _edit_mid_build_then_render("draws", _camera(), OUTPUTS)


def test_an_edit_during_the_wireframe_build_is_not_undone():
    _edit_mid_build_then_render(("wireframe", WIRE["line_color"], 1.0), _camera(), OUTPUTS, **WIRE)


def test_an_edit_during_the_distortion_build_is_not_undone():
    cam = sr.IntrinsicsCamera(50.0, 50.0, 20.0, 20.0, SIZE, SIZE, near=0.1, far=20.0,
                              dist=[-0.2, 0.05, 0.0, 0.0, 0.0])
    cam.look_at(eye=(0.0, 0.0, 4.0), target=(0.0, 0.0, 0.0))
    _edit_mid_build_then_render("distortion_shadow", cam, OUTPUTS)
