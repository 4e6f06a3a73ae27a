"""Rendering into caller-supplied arrays (out=)."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import softrast as sr


@pytest.fixture
def setup():
    scene = sr.Scene()
    scene.add(sr.Mesh.from_trimesh(trimesh.creation.icosphere(subdivisions=3)))
    cam = sr.PerspectiveCamera(fov_y=45.0)
    cam.look_at(eye=(0.3, 0.2, 3.0), target=(0.0, 0.0, 0.0))
    return sr.Renderer(80, 60), scene, cam


def test_out_frame_is_written_in_place_and_equals_a_fresh_render(setup):
    renderer, scene, cam = setup
    first = renderer.render(scene, cam, outputs=sr.OUTPUTS)
    arrays = {name: getattr(first, name) for name in sr.OUTPUTS}
    cam.look_at(eye=(-1.0, 0.5, 2.5), target=(0.0, 0.0, 0.0))
    fresh = renderer.render(scene, cam, outputs=sr.OUTPUTS)
    again = renderer.render(scene, cam, outputs=sr.OUTPUTS, out=first)
    for name in sr.OUTPUTS:
        assert getattr(again, name) is arrays[name]  # the very same arrays, rewritten
        np.testing.assert_array_equal(getattr(again, name), getattr(fresh, name))


def test_out_dict_partial_allocates_the_rest(setup):
    renderer, scene, cam = setup
    depth = np.full((60, 80), -7.0, np.float32)
    frame = renderer.render(scene, cam, outputs=("depth", "mask"), out={"depth": depth})
    assert frame.depth is depth and (depth != -7.0).all()
    assert frame.mask is not None and frame.mask.base is not None
    np.testing.assert_array_equal(frame.mask, depth > 0)


def _read_only(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@pytest.mark.parametrize("array, message", [
    (np.zeros((60, 80), np.float64), "out\\['depth'\\]"),
    (np.zeros((61, 80), np.float32), "out\\['depth'\\]"),
    (np.zeros((80, 60), np.float32).T, "C-contiguous"),
    (np.broadcast_to(np.float32(0), (60, 80)), "C-contiguous"),
    (_read_only(np.zeros((60, 80), np.float32)), "writeable"),
])
def test_bad_out_arrays_are_refused(setup, array, message):
    renderer, scene, cam = setup
    with pytest.raises(ValueError, match=message):
        renderer.render(scene, cam, outputs=("depth",), out={"depth": array})


def test_aliased_out_arrays_are_refused(setup):
    renderer, scene, cam = setup
    ids = np.zeros((60, 80), np.int32)
    with pytest.raises(ValueError, match="share memory"):
        renderer.render(scene, cam, outputs=("triangle_id", "instance_id"),
                        out={"triangle_id": ids, "instance_id": ids})
    with pytest.raises(TypeError, match="out"):
        renderer.render(scene, cam, outputs=("depth",), out=[ids])


def test_partly_overlapping_out_arrays_are_refused_and_neighbours_are_not(setup):
    """Views of one buffer: refused if their bytes overlap at all, accepted if they only touch."""
    renderer, scene, cam = setup
    n = 60 * 80 * 4
    raw = np.zeros(2 * n, np.uint8)
    as_depth = lambda offset: raw[offset:offset + n].view(np.float32).reshape(60, 80)  # noqa: E731
    as_ids = lambda offset: raw[offset:offset + n].view(np.int32).reshape(60, 80)  # noqa: E731
    for offset in (4, n // 2, n - 4):  # the depth array's last bytes are the ids' first
        with pytest.raises(ValueError, match="out\\['depth'\\] and out\\['triangle_id'\\] share memory"):
            renderer.render(scene, cam, outputs=("depth", "triangle_id"),
                            out={"depth": as_depth(0), "triangle_id": as_ids(offset)})
    fresh = renderer.render(scene, cam, outputs=("depth", "triangle_id"))
    frame = renderer.render(scene, cam, outputs=("depth", "triangle_id"),
                            out={"depth": as_depth(0), "triangle_id": as_ids(n)})
    np.testing.assert_array_equal(frame.depth, fresh.depth)
    np.testing.assert_array_equal(frame.triangle_id, fresh.triangle_id)
