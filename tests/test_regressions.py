"""Regressions found by the sanitizer build (.ci/sanitize) and the fuzzer (.ci/fuzz).

Each test reproduces one finding through the Python API where it is reachable there, else
through the private _core module (the C++ API's contract).
"""
from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

import softrast as sr
from softrast import _core

TRI = np.array([[-1.0, -1.0, -3.0], [1.0, -1.0, -3.0], [0.0, 1.0, -3.0]])
FACE = np.array([[0, 1, 2]])


def _camera(**kw) -> sr.PerspectiveCamera:
    cam = sr.PerspectiveCamera(width=32, height=32, **kw)
    cam.pose = np.eye(4)
    return cam


def _check_normals(frame) -> None:
    hit = frame.mask
    assert hit.any()
    assert np.isfinite(frame.normal).all()
    np.testing.assert_allclose(np.linalg.norm(frame.normal[hit], axis=-1), 1.0, atol=1e-5)


def test_normal_overflowing_float_stays_finite_and_unit():
    # fuzz: finite normals (3e38) under a pose that scales by 0.1: the inverse-transpose scales
    # normals by 10, they overflow to inf in float, and the normalised output was NaN.
    scene = sr.Scene()
    scene.add(sr.Mesh(TRI, FACE, normals=np.full((3, 3), 3e38)), pose=np.diag([0.1, 0.1, 0.1, 1.0]))
    frame = sr.Renderer(32, 32).render(scene, _camera(near=0.01), outputs=("normal", "mask"))
    _check_normals(frame)


def test_flat_normal_of_a_huge_triangle_is_unit():
    # fuzz: a triangle 1e20 units wide: its face normal (a cross product, ~1e40) overflows float
    # and the normal output was the zero vector on covered pixels instead of a unit normal.
    scene = sr.Scene()
    scene.add(sr.Mesh(TRI * 1e20, FACE))
    frame = sr.Renderer(32, 32).render(scene, _camera(near=1e19, far=1e22), outputs=("normal", "mask"))
    _check_normals(frame)


def test_core_mesh_refuses_non_finite_colors_and_normals():
    # fuzz: MeshData::validate checked only positions; NaN colours reached shading, where
    # float -> uint8 of NaN is undefined behaviour (UBSan: shade.cpp to_unorm8).
    positions = TRI.astype(np.float32)
    faces = FACE.astype(np.int32)
    with pytest.raises(ValueError, match="colors"):
        _core.MeshData(positions, faces, None, np.full((3, 4), np.nan, np.float32))
    with pytest.raises(ValueError, match="normals"):
        _core.MeshData(positions, faces, np.full((3, 3), np.inf, np.float32))


def test_core_render_refuses_a_nan_material_colour():
    # fuzz: Renderer::render did not check a draw's colour; NaN reached float -> uint8 in
    # shading (undefined behaviour; aborts under UBSan). In a subprocess: under .ci/sanitize the
    # report aborts the process, which must not take the test run with it.
    code = textwrap.dedent("""
        import numpy as np
        from softrast import _core
        tri = np.array([[-1, -1, -3], [1, -1, -3], [0, 1, -3]], np.float32)
        mesh = _core.MeshData(tri, np.array([[0, 1, 2]], np.int32))
        proj = np.array([[2.4, 0, 0, 0], [0, 2.4, 0, 0], [0, 0, -1, -0.2], [0, 0, -1, 0]])
        r = _core.Renderer(32, 32, 1)
        try:
            draw = _core.Draw(mesh=mesh, color=(float("nan"), 0.5, 0.5, 1.0))
            r.render([draw], dict(view=np.eye(4), proj=proj, orthographic=False, near=0.1,
                                  far=100.0, outputs=["color"], cull="none"))
            print("rendered")
        except ValueError:
            print("ValueError")
    """)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "ValueError"
