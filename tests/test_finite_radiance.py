"""Extreme but valid lighting stays finite:

* a point or spot light exactly on the surface lights nothing at that point, in every model:
  pbr gave inf (point) or NaN (spot) over whole triangles at the vertex and face frequencies;
* the msaa / ssaa resolve of finite per-sample radiance near the float32 maximum is finite
  (the sum of the samples overflowed before the division).
"""
from __future__ import annotations

import numpy as np
import pytest

import softrast as sr

N = 32
MODELS = ["lambert", "phong", "blinn_phong", "pbr"]


def _quad_scene(light: sr.Light, light_pos, material: sr.Material) -> sr.Scene:
    # Two triangles over [-1, 1]^2 at z = 0, facing +z; a vertex at (1, 1, 0).
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
    scene = sr.Scene()
    scene.add(sr.Mesh(v, [[0, 1, 2], [0, 2, 3]]), material=material)
    pose = np.eye(4)
    pose[:3, 3] = light_pos  # (in the quad's plane: n.l = 0 elsewhere; r = 0 at light_pos)
    scene.add(light, pose=pose)
    return scene


def _camera() -> sr.OrthographicCamera:
    cam = sr.OrthographicCamera(xmag=1.2, ymag=1.2, near=0.5, far=3.0)
    cam.pose = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1], [0, 0, 0, 1]]
    return cam


def _lights():
    return [sr.PointLight(intensity=2.0), sr.SpotLight(intensity=2.0, outer_cone=1.2)]


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("frequency, where", [("vertex", (1.0, 1.0, 0.0)),
                                              ("face", (1.0 / 3.0, -1.0 / 3.0, 0.0)),
                                              ("pixel", (1.0, 1.0, 0.0))])
def test_light_on_the_surface_gives_finite_radiance(model, frequency, where):
    mat = sr.Material(base_color=(0.7, 0.6, 0.5, 1.0), ks=(0.5, 0.5, 0.5), roughness=0.4, model=model)
    for light in _lights():
        scene = _quad_scene(light, where, mat)
        frame = sr.Renderer(N, N).render(scene, _camera(), outputs=("radiance", "mask"),
                                         frequency=frequency)
        rad = frame.radiance[frame.mask]
        assert np.isfinite(rad).all() and (rad >= 0).all(), (type(light).__name__, frequency)


def test_face_centroid_light_matches_the_limit_of_no_light():
    # At the face frequency the face is lit once, at its centroid: a light there adds nothing,
    # the same colour as the scene's ambient term alone.
    mat = sr.Material(base_color=(0.7, 0.6, 0.5, 1.0), model="pbr")
    centroid = (1.0 / 3.0, -1.0 / 3.0, 0.0)  # of triangle 0: (-1,-1), (1,-1), (1,1)
    scene = _quad_scene(sr.PointLight(intensity=3.0), centroid, mat)
    scene.ambient_light = (0.2, 0.2, 0.2)
    frame = sr.Renderer(N, N).render(scene, _camera(), outputs=("radiance", "triangle_id"),
                                     frequency="face")
    tri0 = frame.radiance[frame.triangle_id == 0]
    np.testing.assert_allclose(tri0, np.broadcast_to(np.float32(0.2) * np.float32([0.7, 0.6, 0.5]),
                                                     tri0.shape), rtol=1e-6)


@pytest.mark.parametrize("aa", [{"msaa": 4}, {"msaa": 16}, {"ssaa": 8}])
def test_resolve_of_huge_finite_radiance_is_finite(aa):
    big = 1.5e38
    scene = sr.Scene()
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
    scene.add(sr.Mesh(v, [[0, 1, 2], [0, 2, 3]]), material=sr.Material(base_color=(1, 1, 1, 1),
                                                                       model="lambert"))
    scene.add(sr.DirectionalLight(intensity=big), pose=np.eye(4))  # shines down -z: n.l = 1
    frame = sr.Renderer(N, N).render(scene, _camera(), outputs=("radiance", "color"), **aa)
    rad = frame.radiance
    assert np.isfinite(rad).all()
    inner = rad[N // 2 - 4:N // 2 + 4, N // 2 - 4:N // 2 + 4]
    np.testing.assert_allclose(inner, np.float32(big), rtol=1e-6)
    assert (frame.color[N // 2, N // 2] == 255).all()
