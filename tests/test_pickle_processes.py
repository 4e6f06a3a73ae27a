"""Pickling and processes: Mesh, Scene, cameras, lights, materials, textures and a
Renderer pickle before and after a render and render the same bytes in another process, under
the fork, spawn and forkserver start methods, with the parent's renderer busy beforehand."""
from __future__ import annotations

import multiprocessing
import pickle

import numpy as np
import pytest
import trimesh

import softrast as sr
from support.mp_worker import render_bytes

OUTPUTS = ("color", "depth", "instance_id", "barycentric")


def _scene():
    tm = trimesh.creation.icosphere(subdivisions=3)
    uv = np.asarray(tm.vertices)[:, :2] * 0.5 + 0.5
    tex = sr.Texture(np.random.default_rng(0).integers(0, 256, (16, 16, 4)).astype(np.uint8))
    material = sr.Material(base_color_texture=tex, model="pbr", alpha_mode="mask", alpha_cutoff=0.3)
    scene = sr.Scene(ambient_light=(0.1, 0.1, 0.1))
    scene.add(sr.Mesh(tm.vertices, tm.faces, uvs=uv, material=material), instance_id=4)
    scene.add(sr.Mesh(tm.vertices, tm.faces), pose=np.diag([3.0, 3.0, 3.0, 1.0]) @ np.eye(4) +
              np.array([[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, -6.0], [0, 0, 0, 0]]), instance_id=9)
    scene.add(sr.PointLight(intensity=8.0), pose=np.array(
        [[1, 0, 0, 1.0], [0, 1, 0, 2.0], [0, 0, 1, 3.0], [0, 0, 0, 1.0]]))
    cam = sr.PerspectiveCamera(fov_y=45.0, width=48, height=40)
    cam.look_at((0.5, 0.8, 3.2), (0.0, 0.0, 0.0))
    return scene, cam


def test_everything_pickles_before_and_after_a_render() -> None:
    scene, cam = _scene()
    renderer = sr.Renderer(48, 40, threads=2)
    before = pickle.dumps((renderer, scene, cam, OUTPUTS))
    frame = renderer.render(scene, cam, outputs=OUTPUTS)
    after = pickle.dumps((renderer, scene, cam, OUTPUTS))
    assert (frame.instance_id == 4).any() and (frame.instance_id == 9).any()
    for payload in (before, after):
        r2, s2, c2, _ = pickle.loads(payload)
        assert (r2.width, r2.height, r2.threads) == (48, 40, 2) and r2 is not renderer
        f2 = r2.render(s2, c2, outputs=OUTPUTS)
        for name in OUTPUTS:
            np.testing.assert_array_equal(getattr(f2, name), getattr(frame, name))
    assert render_bytes(after) == {n: getattr(frame, n).tobytes() for n in OUTPUTS}


@pytest.mark.parametrize("method", ["fork", "spawn", "forkserver"])
def test_render_in_other_processes(method: str) -> None:
    """A pool of two processes renders pickled jobs to the parent's bytes; the parent rendered
    (its worker threads running) before the pool started, and renders again after."""
    scene, cam = _scene()
    renderer = sr.Renderer(48, 40, threads=2)
    expected = {n: getattr(f, n).tobytes() for f in [renderer.render(scene, cam, outputs=OUTPUTS)]
                for n in OUTPUTS}
    poses = sr.orbit((0.0, 0.0, 0.0), 3.2, 4, elevation=15.0)
    jobs = []
    for pose in poses:
        c = pickle.loads(pickle.dumps(cam))
        c.pose = pose
        jobs.append(pickle.dumps((renderer, scene, c, OUTPUTS)))
    ctx = multiprocessing.get_context(method)
    with ctx.Pool(2) as pool:
        results = pool.map(render_bytes, [pickle.dumps((renderer, scene, cam, OUTPUTS))] + jobs,
                           chunksize=1)
    assert results[0] == expected
    for pose, got in zip(poses, results[1:]):
        c = pickle.loads(pickle.dumps(cam))
        c.pose = pose
        local = renderer.render(scene, c, outputs=OUTPUTS)
        assert got == {n: getattr(local, n).tobytes() for n in OUTPUTS}
