"""``Material(specular_texture=)``: its rgb scales ``ks`` per pixel in the phong and blinn_phong
models (MTL's ``map_Ks``), read linear by default; pbr does not read it.

Checked against the same material without the texture and with ``ks`` scaled by the texel: a
specular map of one value s gives the radiance of ks * s, a map that is 0 on one half gives
no highlight there (the Lambert radiance), and 1 gives the untextured radiance.
"""
from __future__ import annotations

import numpy as np
import pytest

import softrast as sr

W = H = 48


def _render(material: sr.Material, **options) -> np.ndarray:
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float64)
    scene = sr.Scene()
    scene.add(sr.Mesh(v, [[0, 1, 2], [0, 2, 3]], uvs=uv), material=material)
    scene.add(sr.PointLight(color=(1.0, 1.0, 1.0), intensity=6.0),
              pose=[[1, 0, 0, 0.2], [0, 1, 0, -0.1], [0, 0, 1, 1.2], [0, 0, 0, 1]])
    cam = sr.PerspectiveCamera(fov_y=70.0, near=0.1, far=10.0)
    cam.pose = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1.5], [0, 0, 0, 1]]
    return sr.Renderer(W, H).render(scene, cam, outputs=("radiance",), **options).radiance


def _spec_texture(values: np.ndarray) -> sr.Texture:
    return sr.Texture(values.astype(np.float32), filter="nearest")


BASE = dict(base_color=(0.4, 0.3, 0.2, 1.0), ks=(0.8, 0.6, 0.4), shininess=24.0)


@pytest.mark.parametrize("model", ["phong", "blinn_phong"])
def test_uniform_specular_map_scales_ks(model):
    s = np.array([0.5, 0.25, 1.0])
    tex = _spec_texture(np.broadcast_to(s, (4, 4, 3)).copy())
    got = _render(sr.Material(**BASE, model=model, specular_texture=tex))
    want = _render(sr.Material(**{**BASE, "ks": tuple(np.array(BASE["ks"]) * s)}, model=model))
    plain = _render(sr.Material(**BASE, model=model))
    assert not np.allclose(want, plain, atol=1e-3)  # the highlight is there and differs
    np.testing.assert_allclose(got, want, rtol=2e-6, atol=2e-7)


def test_zero_half_has_no_highlight_one_half_full():
    img = np.ones((4, 4, 3))
    img[:, :2] = 0.0  # u < 0.5: no specular (image columns are u)
    got = _render(sr.Material(**BASE, specular_texture=_spec_texture(img)))
    lambert_like = _render(sr.Material(**{**BASE, "ks": (0.0, 0.0, 0.0)}))
    full = _render(sr.Material(**BASE))
    left, right = slice(2, W // 2 - 2), slice(W // 2 + 2, W - 2)
    np.testing.assert_allclose(got[2:-2, left], lambert_like[2:-2, left], rtol=2e-6, atol=2e-7)
    np.testing.assert_allclose(got[2:-2, right], full[2:-2, right], rtol=2e-6, atol=2e-7)
    assert (full[2:-2, left] - lambert_like[2:-2, left]).max() > 0.05  # a highlight was removed


def test_pbr_does_not_read_it_and_it_is_linear_by_default():
    tex = _spec_texture(np.zeros((2, 2, 3)))
    pbr = dict(base_color=(0.4, 0.3, 0.2, 1.0), model="pbr", roughness=0.3)
    np.testing.assert_allclose(_render(sr.Material(**pbr, specular_texture=tex)),
                               _render(sr.Material(**pbr)), rtol=2e-6, atol=2e-7)
    grey = np.full((2, 2, 3), 128, np.uint8)  # 8-bit, linear: 128/255
    got = _render(sr.Material(**BASE, specular_texture=sr.Texture(grey, filter="nearest")))
    want = _render(sr.Material(**{**BASE, "ks": tuple(np.float32(128 / 255) * np.array(BASE["ks"]))}))
    np.testing.assert_allclose(got, want, rtol=5e-6, atol=5e-7)


def test_slot_is_checked_and_kept():
    with pytest.raises(TypeError, match="specular_texture"):
        sr.Material(specular_texture=np.zeros((2, 2, 3)))
    tex = _spec_texture(np.ones((2, 2, 3)))
    mat = sr.Material(specular_texture=tex)
    assert mat.textured and mat.replace(ks=0.2).specular_texture is tex
