"""Rendering into caller-supplied arrays (out=)."""
from __future__ import annotations

import copy
import pickle
import sys

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


# -- dtypes are compared by value, not identity ---------------------------------------------------

def _equal_not_identical(dtype: np.dtype) -> list[np.dtype]:
    """Dtypes equal to ``dtype`` that are other objects than NumPy's cached instance."""
    variants = [pickle.loads(pickle.dumps(dtype)), copy.deepcopy(dtype), dtype.newbyteorder("="),
                np.dtype(dtype, metadata={"from": "test"})]
    assert all(v == dtype and v is not dtype for v in variants)
    return variants


def test_unpickled_out_frame_is_accepted_for_every_output(setup):
    # Arrays that travelled through pickle (a worker pool's results, say) used to be refused with
    # "must be a float32 array" although they were float32: the dtype object is another instance.
    renderer, scene, cam = setup
    fresh = renderer.render(scene, cam, outputs=sr.OUTPUTS).as_dict()
    arrays = pickle.loads(pickle.dumps({name: np.zeros_like(a) for name, a in fresh.items()}))
    assert any(a.dtype is not fresh[name].dtype for name, a in arrays.items())
    frame = renderer.render(scene, cam, outputs=sr.OUTPUTS, out=arrays)
    for name, want in fresh.items():
        assert getattr(frame, name) is arrays[name]
        np.testing.assert_array_equal(arrays[name], want)


@pytest.mark.parametrize("variant", range(5))
def test_equal_dtype_objects_are_accepted(setup, variant):
    renderer, scene, cam = setup
    dtypes = _equal_not_identical(np.dtype(np.float32)) + [np.dtype("<f4" if sys.byteorder == "little" else ">f4")]
    depth = np.zeros((60, 80), dtypes[variant])
    renderer.render(scene, cam, outputs=("depth",), out={"depth": depth})
    np.testing.assert_array_equal(depth, renderer.render(scene, cam, outputs=("depth",)).depth)


@pytest.mark.parametrize("name, dtype", [("depth", ">f4"), ("triangle_id", ">i4"), ("coverage", ">u4"),
                                         ("normal", ">f4")])
def test_byte_swapped_out_arrays_are_refused_with_a_clear_message(setup, name, dtype):
    # The core writes native values in place, so a big-endian array cannot be filled: refused.
    renderer, scene, cam = setup
    shape = (60, 80, 3) if name == "normal" else (60, 80)
    with pytest.raises(ValueError, match=rf"^out\['{name}'\] must be a \w+ array \(native byte order\) "
                                         rf"of shape \({', '.join(map(str, shape))}\), got a {dtype} array"):
        renderer.render(scene, cam, outputs=(name,), out={name: np.zeros(shape, dtype)})


def test_core_mesh_data_compares_dtypes_by_value():
    # The same identity check guarded _core.MeshData (which sr.Mesh feeds): equal dtypes are
    # accepted, a byte-swapped one is refused by argument name. sr.Mesh itself converts any
    # real dtype, '>f4' included, to native float32.
    from softrast import _core

    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    faces = np.array([[0, 1, 2]], np.int32)
    for f32, i32 in zip(_equal_not_identical(positions.dtype), _equal_not_identical(faces.dtype)):
        assert _core.MeshData(positions.astype(f32), faces.astype(i32)).num_faces == 1
    with pytest.raises(TypeError, match=r"^positions must have dtype float32 \(native byte order\), got >f4"):
        _core.MeshData(positions.astype(">f4"), faces)
    with pytest.raises(TypeError, match=r"^faces must have dtype int32 \(native byte order\), got >i4"):
        _core.MeshData(positions, faces.astype(">i4"))
    swapped = sr.Mesh(positions.astype(">f4"), faces.astype(">i4"), normals=positions.astype(">f8"))
    assert swapped.positions.dtype == np.float32 and swapped.positions.dtype.isnative
    np.testing.assert_array_equal(swapped.positions, positions)
    np.testing.assert_array_equal(swapped.faces, faces)
