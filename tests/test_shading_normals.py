"""``render(normal_kind=)``: the ``normal`` output is the interpolated vertex normal by default
(a G-buffer's normal: no normal or bump map), or with ``"shading"`` the normal the lighting
uses, perturbed by the material's normal or bump map.

Checked against the tangent-space formula in NumPy on a screen-aligned quad (tangent +x,
bitangent +y, normal +z, nearest texels: each pixel's texel is known), and against the shading
itself: ``shading="normal"`` draws the same normal as (n + 1) / 2.
"""
from __future__ import annotations

import numpy as np
import pytest

import softrast as sr

N = 32  # pixels; the quad fills the image and its uvs span [0, 1]


def _normal_map() -> np.ndarray:
    rng = np.random.default_rng(7)
    v = rng.normal(size=(4, 4, 3)) * (0.45, 0.45, 0.2) + (0.0, 0.0, 1.0)
    v /= np.linalg.norm(v, axis=2, keepdims=True)
    return np.round((v * 0.5 + 0.5) * 255.0).astype(np.uint8)


def _scene(material: sr.Material) -> tuple[sr.Scene, sr.OrthographicCamera]:
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float64)
    scene = sr.Scene()
    scene.add(sr.Mesh(v, [[0, 1, 2], [0, 2, 3]], uvs=uv), material=material)
    cam = sr.OrthographicCamera(xmag=1.0, ymag=1.0, near=0.5, far=3.0)
    cam.pose = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1], [0, 0, 0, 1]]
    return scene, cam


def _expected(img: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """(N, N, 3): the perturbed normal per pixel: t (2r - 1) s + b (2g - 1) s + n (2b - 1),
    normalised, with t = +x, b = +y, n = +z; image row 0 is v = 1, the top of the frame."""
    c = img.astype(np.float64) / 255.0 * 2.0 - 1.0
    m = np.stack([c[..., 0] * scale, c[..., 1] * scale, c[..., 2]], -1)
    m /= np.linalg.norm(m, axis=2, keepdims=True)
    k = N // img.shape[0]
    return np.repeat(np.repeat(m, k, axis=0), k, axis=1)


def _render(material, **options):
    scene, cam = _scene(material)
    return sr.Renderer(N, N).render(scene, cam, **options)


@pytest.mark.parametrize("outputs", [("normal",), ("color", "normal"), ("normal", "radiance", "depth")])
@pytest.mark.parametrize("model", ["blinn_phong", "pbr", "unlit", "lambert"])
def test_shading_normal_is_the_normal_map_formula(outputs, model):
    img = _normal_map()
    mat = sr.Material(normal_texture=sr.Texture(img, filter="nearest"), normal_scale=0.8, model=model)
    got = _render(mat, outputs=outputs, normal_kind="shading").normal
    np.testing.assert_allclose(got, _expected(img, 0.8), atol=2e-6)
    flat = _render(mat, outputs=outputs).normal  # the default: the interpolated normal
    assert np.array_equal(flat, np.broadcast_to(np.float32([0, 0, 1]), flat.shape))


def test_shading_normal_matches_what_the_normal_view_draws():
    img = _normal_map()
    mat = sr.Material(normal_texture=sr.Texture(img, filter="bilinear"))
    frame = _render(mat, outputs=("normal", "radiance"), shading="normal", normal_kind="shading")
    np.testing.assert_allclose(frame.normal * 0.5 + 0.5, frame.radiance, atol=1e-6)
    alone = _render(mat, outputs=("normal",), normal_kind="shading").normal
    assert np.array_equal(alone, frame.normal)  # an output's bits do not depend on the others


def test_bump_map_and_msaa():
    h = np.zeros((8, 8), np.float32)
    h[2:6, 2:6] = 1.0
    mat = sr.Material(bump_texture=sr.Texture(h, filter="nearest"), bump_scale=0.5)
    frame = _render(mat, outputs=("normal", "radiance"), shading="normal", normal_kind="shading")
    n = frame.normal
    assert np.allclose(np.linalg.norm(n, axis=2), 1.0, atol=1e-6)
    assert (n[..., 2] < 0.99).sum() > 0 and (n[..., 2] > 0.999).sum() > 0  # edges tilt, flats not
    np.testing.assert_allclose(n * 0.5 + 0.5, frame.radiance, atol=1e-6)
    ms = _render(mat, outputs=("normal",), normal_kind="shading", msaa=4).normal
    assert not np.array_equal(ms, _render(mat, outputs=("normal",), msaa=4).normal)
    inner = np.abs(n - ms).max(axis=2) < 1e-6  # pixels whose samples share one texel
    assert inner.mean() > 0.5


def test_without_maps_or_at_other_frequencies_both_kinds_agree():
    img = _normal_map()
    for mat, options in ((sr.Material(), {}),
                         (sr.Material(normal_texture=sr.Texture(img)), {"frequency": "vertex"}),
                         (sr.Material(normal_texture=sr.Texture(img)), {"shading": "uv"})):
        a = _render(mat, outputs=("color", "normal"), **options).normal
        b = _render(mat, outputs=("color", "normal"), normal_kind="shading", **options).normal
        assert np.array_equal(a, b), options


def test_normal_kind_is_checked():
    with pytest.raises(ValueError, match="normal_kind"):
        _render(sr.Material(), outputs=("normal",), normal_kind="geometric")
