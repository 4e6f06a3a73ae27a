"""Renderer.render_many: many views of one scene, equal byte for byte to a loop of
render, in order, lazily (a generator over any iterable of cameras), with a callback and a
progress bar."""
from __future__ import annotations

import itertools

import numpy as np
import pytest
import trimesh

import softrast as sr

OUTPUTS = ("color", "depth", "instance_id", "normal")


def _scene():
    tm = trimesh.creation.icosphere(subdivisions=3)
    scene = sr.Scene()
    scene.add(sr.Mesh(tm.vertices, tm.faces, material=sr.Material(base_color=(0.8, 0.3, 0.2), model="pbr")),
              instance_id=3)
    scene.add(sr.Mesh(tm.vertices, tm.faces), pose=np.array(
        [[0.5, 0, 0, 1.2], [0, 0.5, 0, 0], [0, 0, 0.5, 0], [0, 0, 0, 1.0]]), instance_id=8)
    scene.add(sr.PointLight(intensity=6.0), pose=np.array(
        [[1, 0, 0, 2.0], [0, 1, 0, 2.0], [0, 0, 1, 2.0], [0, 0, 0, 1.0]]))
    return scene


def _cameras(n, w=64, h=48):
    for pose in sr.orbit((0.3, 0.0, 0.0), 4.0, n, elevation=25.0):
        cam = sr.PerspectiveCamera(fov_y=40.0, width=w, height=h)
        cam.pose = pose
        yield cam


@pytest.mark.parametrize("workers", [None, 1, 3])
def test_render_many_equals_a_loop(workers) -> None:
    scene = _scene()
    r = sr.Renderer(64, 48, threads=2)
    cams = list(_cameras(9))
    seen = []
    frames = list(r.render_many(scene, cams, outputs=OUTPUTS, workers=workers,
                                callback=lambda i, f: seen.append((i, f)), shading="auto", srgb=False))
    assert len(frames) == 9 and [i for i, _ in seen] == list(range(9))
    assert all(f is g for f, (_, g) in zip(frames, seen))
    for cam, frame in zip(cams, frames):
        ref = r.render(scene, cam, outputs=OUTPUTS, shading="auto", srgb=False)
        for name in OUTPUTS:
            np.testing.assert_array_equal(getattr(frame, name), getattr(ref, name))
    # the views differ (the test has power)
    assert not np.array_equal(frames[0].color, frames[4].color)


def test_render_many_is_lazy_and_bounded() -> None:
    """Cameras are read as needed: with 2 workers at most 4 views are ahead of the consumer."""
    scene = _scene()
    r = sr.Renderer(64, 48, threads=2)
    taken = []

    def cameras():
        for k, cam in enumerate(_cameras(1000)):
            taken.append(k)
            yield cam

    gen = r.render_many(scene, cameras(), outputs=("depth",), workers=2)
    first = list(itertools.islice(gen, 3))
    assert len(first) == 3 and len(taken) <= 3 + 4
    gen.close()


def test_render_many_progress_bar(capsys) -> None:
    frames = list(sr.Renderer(32, 24).render_many(_scene(), list(_cameras(5, 32, 24)), outputs=("mask",),
                                                   progress=True))
    assert len(frames) == 5
    err = capsys.readouterr().err
    assert "5/5" in err and "render_many" in err


def test_render_many_checks_its_arguments() -> None:
    r = sr.Renderer(32, 24)
    scene = _scene()
    with pytest.raises(ValueError, match="out="):
        r.render_many(scene, [], out={})
    with pytest.raises(ValueError, match="workers"):
        r.render_many(scene, [], workers=0)
    with pytest.raises(TypeError, match="callback"):
        r.render_many(scene, [], callback=3)
    with pytest.raises(TypeError, match="scene"):
        r.render_many([], [])
    with pytest.raises(TypeError, match=r"cameras\[1\]"):
        list(r.render_many(scene, [next(_cameras(1, 32, 24)), "camera"], outputs=("mask",)))
    with pytest.raises(ValueError, match="outputs"):
        list(r.render_many(scene, list(_cameras(2, 32, 24)), outputs=("colour",)))
    assert list(r.render_many(scene, [])) == []


@pytest.mark.parametrize("workers", [1, 2])
def test_render_many_refuses_a_none_camera(workers) -> None:
    """A None among the cameras is an error naming it, not the end of the views
    (it once ended the iteration: 2 frames from 5 cameras)."""
    r = sr.Renderer(32, 24, threads=2)
    scene = _scene()
    cams = list(_cameras(4, 32, 24))
    frames = []
    with pytest.raises(TypeError, match=r"cameras\[2\].*NoneType"):
        for frame in r.render_many(scene, cams[:2] + [None] + cams[2:], outputs=("mask",), workers=workers):
            frames.append(frame)
    assert len(frames) <= 2
