"""Material and texture defaults a newcomer relies on:

* ``Material(base_color_texture=t)`` shows the texture as it is: the default base colour is
  white where a base-colour texture is given, as glTF's ``baseColorFactor`` and pyrender's
  ``MetallicRoughnessMaterial`` default to (0.8 grey without a texture, as before);
* ``ka`` / ``kd`` / ``ks`` / ``emissive`` accept one number as grey (course code writes them so);
* a float texture in a colour slot with values above 1 warns (naming the slot and, for 0..255
  values, the likely cause); negative ones are refused;
* float textures are linear by default in every slot, as ``Texture.sample`` reads them, and an
  sRGB decode that overflows float32 is refused.
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import softrast as sr
from conftest import ROOT


def _checker(n: int = 8) -> np.ndarray:
    img = np.zeros((n, n, 3), np.uint8)
    img[::2, ::2] = (200, 40, 90)
    img[1::2, 1::2] = (20, 180, 250)
    img[::2, 1::2] = (255, 255, 255)
    img[1::2, ::2] = (5, 60, 120)
    return img


def _unlit_quad(material: sr.Material, size: int = 32, **options) -> np.ndarray:
    """An unlit screen-filling quad with uvs over [0, 1]^2, drawn with nearest texels."""
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float64)
    mesh = sr.Mesh(v, [[0, 1, 2], [0, 2, 3]], uvs=uv)
    scene = sr.Scene()
    scene.add(mesh, material=material)
    cam = sr.OrthographicCamera(xmag=1.0, ymag=1.0, near=0.5, far=3.0)
    cam.pose = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1], [0, 0, 0, 1]]
    return sr.Renderer(size, size).render(scene, cam, outputs=("color", "radiance"),
                                          shading="unlit", **options)


def test_texture_only_material_shows_the_texture_at_full_strength():
    img = _checker()
    mat = sr.Material(base_color_texture=sr.Texture(img, filter="nearest"))
    assert mat.base_color == (1.0, 1.0, 1.0, 1.0)  # glTF baseColorFactor's default
    color = _unlit_quad(mat).color
    # 32 px over 8 texels: every pixel shows one texel; unlit sRGB output gives its bytes back.
    expected = np.repeat(np.repeat(img, 4, axis=0), 4, axis=1)
    assert np.array_equal(color, expected)


def test_untextured_default_and_explicit_factor_unchanged():
    assert sr.Material().base_color == (0.8, 0.8, 0.8, 1.0)
    mat = sr.Material(base_color=(0.5, 0.5, 0.5), base_color_texture=sr.Texture(_checker()))
    assert mat.base_color == (0.5, 0.5, 0.5, 1.0)


def test_gltf_texture_without_factor_matches_the_constructor_default():
    scene = sr.load_scene(str(ROOT / "assets" / "meshes" / "BoxTextured.gltf"))
    mats = [i.material for i in scene.instances if i.material is not None]
    assert mats and all(m.base_color_texture is not None for m in mats)
    for m in mats:  # BoxTextured gives no baseColorFactor: glTF's default, 1
        assert m.base_color == sr.Material(base_color_texture=m.base_color_texture).base_color


@pytest.mark.parametrize("name", ["ka", "kd", "ks", "emissive"])
def test_scalar_coefficients_are_grey(name):
    mat = sr.Material(**{name: 0.25})
    assert getattr(mat, name) == (0.25, 0.25, 0.25)
    assert mat == sr.Material(**{name: (0.25, 0.25, 0.25)})
    with pytest.raises(ValueError, match=name):
        sr.Material(**{name: 1.5})
    with pytest.raises(ValueError, match=name):
        sr.Material(**{name: float("nan")})


def test_scalar_base_color_is_still_refused():
    with pytest.raises(ValueError, match="base_color"):
        sr.Material(base_color=0.5)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_float_texture_in_0_255_warns_naming_slot_and_cause(dtype):
    img = _checker().astype(dtype)
    with pytest.warns(UserWarning, match=r"base_color_texture.*up to 255.*8-bit values"):
        sr.Material(base_color_texture=sr.Texture(img))
    with pytest.warns(UserWarning, match=r"emissive_texture"):
        sr.Material(emissive_texture=sr.Texture(img))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sr.Material(base_color_texture=sr.Texture(img / 255.0))  # in range: silent
        sr.Material(bump_texture=sr.Texture(img))  # a height map may exceed 1


def test_negative_float_texels_refused_in_colour_slots_kept_in_data_slots():
    img = np.full((4, 4, 3), 0.5, np.float32)
    img[1, 2, 0] = -0.25
    with pytest.raises(ValueError, match=r"base_color_texture.*negative"):
        sr.Material(base_color_texture=sr.Texture(img))
    sr.Material(normal_texture=sr.Texture(img))  # signed data stays


def test_float_textures_are_linear_in_colour_slots_as_sample_reads_them():
    img = np.zeros((4, 4, 3), np.float32)
    img[...] = (0.2, 0.5, 0.05)
    tex = sr.Texture(img, filter="nearest")
    radiance = _unlit_quad(sr.Material(base_color_texture=tex)).radiance
    sampled = tex.sample(np.array([[0.5, 0.5]], np.float32))[0, :3]
    assert np.allclose(sampled, (0.2, 0.5, 0.05))
    assert np.allclose(radiance[16, 16], sampled, rtol=0, atol=1e-7)
    # srgb=True still decodes (an 8-bit-era image stored as floats in 0..1)
    dec = _unlit_quad(sr.Material(base_color_texture=tex.replace(srgb=True))).radiance[16, 16]
    assert np.allclose(dec, sr.texture.srgb_decode(np.array([0.2, 0.5, 0.05])), atol=1e-6)


def test_srgb_decode_overflow_is_refused():
    img = np.full((2, 2, 3), 1e20, np.float32)
    with pytest.warns(UserWarning), pytest.raises(ValueError, match=r"huge\.exr.*overflows"):
        sr.Material(base_color_texture=sr.Texture(img, srgb=True, name="huge.exr"))
    with pytest.warns(UserWarning):  # linear (the default): finite, saturated white
        linear = sr.Material(base_color_texture=sr.Texture(img))
    out = _unlit_quad(linear)
    assert np.isfinite(out.radiance).all() and (out.color == 255).all()
