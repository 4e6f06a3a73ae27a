"""Frames' memory is recycled: a render reuses the buffers of frames the user has
released (already paged in), never those of frames still held, and a buffer may outlive its
renderer."""
from __future__ import annotations

import gc

import numpy as np
import trimesh

import softrast as sr

OUTPUTS = ("color", "depth", "instance_id")


def _setup():
    tm = trimesh.creation.icosphere(subdivisions=3)
    scene = sr.Scene()
    scene.add(sr.Mesh(tm.vertices, tm.faces), instance_id=1)
    cams = []
    for pose in sr.orbit((0.0, 0.0, 0.0), 3.0, 3, elevation=10.0):
        cam = sr.PerspectiveCamera(fov_y=45.0, width=64, height=48)
        cam.pose = pose
        cams.append(cam)
    return scene, cams


def _addresses(frame):
    return {n: getattr(frame, n).__array_interface__["data"][0] for n in OUTPUTS}


def test_released_frames_are_reused_and_held_ones_never_written():
    scene, cams = _setup()
    r = sr.Renderer(64, 48)
    first = r.render(scene, cams[0], outputs=OUTPUTS)
    a = _addresses(first)
    del first
    gc.collect()
    second = r.render(scene, cams[1], outputs=OUTPUTS)
    # the released buffers, reused (depth and instance_id have one size: either may get either)
    assert set(_addresses(second).values()) == set(a.values())
    kept = {n: getattr(second, n).copy() for n in OUTPUTS}
    third = r.render(scene, cams[2], outputs=OUTPUTS)  # `second` is held: new memory
    assert not set(_addresses(third).values()) & set(a.values())
    for n in OUTPUTS:
        np.testing.assert_array_equal(getattr(second, n), kept[n])
    # a view keeps its buffer too
    view = third.depth[10:20]
    t_addr = _addresses(third)
    del third
    gc.collect()
    fourth = r.render(scene, cams[0], outputs=OUTPUTS)
    assert fourth.depth.__array_interface__["data"][0] != t_addr["depth"]
    assert fourth.color.__array_interface__["data"][0] == t_addr["color"]
    expected = sr.Renderer(64, 48).render(scene, cams[2], outputs=("depth",)).depth[10:20]
    np.testing.assert_array_equal(view, expected)
    # recycled frames are the same bits as fresh ones
    fresh = sr.Renderer(64, 48).render(scene, cams[0], outputs=OUTPUTS)
    for n in OUTPUTS:
        np.testing.assert_array_equal(getattr(fourth, n), getattr(fresh, n))


def test_buffers_outlive_their_renderer_and_the_pool_is_bounded():
    scene, cams = _setup()
    r = sr.Renderer(64, 48)
    frame = r.render(scene, cams[0], outputs=OUTPUTS)
    ref = frame.color.copy()
    del r
    gc.collect()
    np.testing.assert_array_equal(frame.color, ref)  # still valid
    del frame  # given back to a pool that only the buffer kept alive: freed with it
    gc.collect()
    r = sr.Renderer(64, 48)
    seen = set()
    for k in range(50):  # released at once: at most two frames' buffers in circulation
        seen.add(r.render(scene, cams[k % 3], outputs=OUTPUTS).color.__array_interface__["data"][0])
    assert len(seen) <= 2
