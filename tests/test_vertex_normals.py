"""Vertex normals of files without their own: area-weighted by default (the course notes' rule),
angle-weighted on request, the file's own where it has them, flat with smooth=False."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import softrast as sr
from softrast.normals import vertex_normals


def _wedge() -> trimesh.Trimesh:
    # Vertex 0 is shared by a big triangle in the z = 0 plane and a small one in the x = 0 plane,
    # with corner angles at vertex 0 of 90 degrees each: angle weights are equal, area weights not.
    v = np.array([[0, 0, 0], [4, 0, 0], [0, 4, 0], [0, 0, 1], [0, 1, 0]], float)
    f = np.array([[0, 1, 2], [0, 4, 3]])
    return trimesh.Trimesh(v, f, process=False)


def test_area_weighted_by_default_and_angle_weighted_on_request():
    tm = _wedge()
    n_big, n_small = np.array([0, 0, 1.0]), np.array([1.0, 0, 0])  # face normals (ccw)
    area_big, area_small = 8.0, 0.5
    want = area_big * n_big + area_small * n_small
    np.testing.assert_allclose(vertex_normals(tm, True)[0], want / np.linalg.norm(want), atol=1e-12)
    np.testing.assert_allclose(vertex_normals(tm, "area")[0], want / np.linalg.norm(want), atol=1e-12)
    equal = (n_big + n_small) / np.linalg.norm(n_big + n_small)  # both corners are right angles
    np.testing.assert_allclose(vertex_normals(tm, "angle")[0], equal, atol=1e-7)
    assert vertex_normals(tm, False) is None


def test_load_mesh_weights_and_file_normals(tmp_path):
    tm = _wedge()
    path = tmp_path / "wedge.ply"
    tm.export(path)
    area = sr.load_mesh(path).normals[0]
    angle = sr.load_mesh(path, smooth="angle").normals[0]
    assert sr.load_mesh(path, smooth=False).normals is None
    assert area[2] > 0.99 and abs(angle[2] - angle[0]) < 1e-6 and angle[0] > 0.7
    # An OBJ with its own vn lines keeps them, whatever the weighting.
    obj = tmp_path / "own.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0.6 0 0.8\nvn 0.6 0 0.8\nvn 0.6 0 0.8\n"
                   "f 1//1 2//2 3//3\n")
    for smooth in (True, "angle"):
        np.testing.assert_allclose(sr.load_mesh(obj, smooth=smooth).normals, [[0.6, 0, 0.8]] * 3, atol=1e-6)


@pytest.mark.parametrize("bad", ["smooth", 2, None])
def test_bad_smooth_names_the_argument(tmp_path, bad):
    path = tmp_path / "wedge.ply"
    _wedge().export(path)
    with pytest.raises(ValueError, match="smooth"):
        sr.load_mesh(path, smooth=bad)
