"""Alpha masks (glTF alphaMode MASK): a fragment is kept iff its alpha reaches the
cutoff, before the depth test, in every output. The alpha is checked against what shading itself
samples: a texture whose colour channels equal its alpha channel, rendered opaque and unlit,
gives each pixel's alpha as its radiance (the same uv, derivatives, filter and bits), so the
masked render's coverage must equal radiance >= cutoff exactly."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import softrast as sr
from test_texture_render import _opencv_plane_camera, ortho_camera, quad

FILTERS = ("nearest", "bilinear", "trilinear", "anisotropic")
BACK_ID, FRONT_ID = 7, 3


def alpha_texture(alpha: np.ndarray, filt: str) -> sr.Texture:
    """RGBA float texture whose r = g = b = a = `alpha` (linear)."""
    return sr.Texture(np.repeat(alpha[..., None], 4, axis=-1).astype(np.float32), srgb=False,
                      filter=filt)


def masked(tex: sr.Texture, cutoff: float = 0.5, **kw) -> sr.Material:
    return sr.Material(base_color=(1, 1, 1, 1), base_color_texture=tex, model="unlit",
                       alpha_mode="mask", alpha_cutoff=cutoff, **kw)


def two_layer_scene(front: sr.Mesh, size: float = 1.0) -> sr.Scene:
    """`front` at z = 0 (instance FRONT_ID) over an opaque grey quad at z = -0.5 (BACK_ID)."""
    scene = sr.Scene()
    back = quad(sr.Material(base_color=(0.2, 0.4, 0.6, 1.0), model="unlit"), size=2 * size)
    scene.add(back, pose=np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, -0.5], [0, 0, 0, 1.0]]),
              instance_id=BACK_ID)
    scene.add(front, instance_id=FRONT_ID)
    return scene


def test_one_texel_per_pixel_cuts_exactly_where_alpha_crosses_the_cutoff() -> None:
    """Texel centres on pixel centres: the front quad is kept exactly where the texel's alpha
    >= cutoff, and the quad behind shows through everywhere else, in every output, for both
    instruction sets, 1 and 2 threads, forward and deferred shading."""
    h, w = 40, 56
    rng = np.random.default_rng(5)
    img = rng.integers(0, 256, (h, w, 4)).astype(np.uint8)
    img[:, :, 3] = np.where(img[:, :, 3] == 128, 127, img[:, :, 3])  # no texel at the cutoff
    cutoff = 128 / 255
    kept = img[:, :, 3] / 255 >= cutoff
    assert 0.3 < kept.mean() < 0.7
    for filt in ("nearest", "bilinear"):
        tex = sr.Texture(img, srgb=False, filter=filt)
        scene = two_layer_scene(quad(masked(tex, cutoff)))
        cam = ortho_camera(w, h)
        ref = None
        for threads in (1, 2):
            for simd in (True, False):
                for path in ("forward", "deferred"):
                    f = sr.Renderer(w, h, threads=threads, simd=simd).render(
                        scene, cam, outputs=("color", "depth", "instance_id", "triangle_id", "mask"),
                        srgb=False, shading_path=path)
                    np.testing.assert_array_equal(f.instance_id, np.where(kept, FRONT_ID, BACK_ID))
                    assert f.mask.all()
                    np.testing.assert_array_equal(f.color[kept], img[:, :, :3][kept])
                    back = np.round(np.array([0.2, 0.4, 0.6]) * 255).astype(np.uint8)
                    assert (f.color[~kept] == back).all()
                    np.testing.assert_allclose(f.depth, np.where(kept, 2.0, 2.5), rtol=1e-6)
                    if ref is None:
                        ref = f
                    for name in ("color", "depth", "triangle_id"):
                        np.testing.assert_array_equal(getattr(f, name), getattr(ref, name))
        # Without colour or normals (nothing is shaded) the cut is the same.
        f = sr.Renderer(w, h).render(scene, cam, outputs=("depth", "instance_id"))
        np.testing.assert_array_equal(f.instance_id, np.where(kept, FRONT_ID, BACK_ID))


def _alpha_and_masked(scene_of, cam, w, h, filt, cutoff, **render):
    """The opaque render's per-pixel alpha (radiance) and the masked render's frame."""
    yy, xx = np.mgrid[0:64, 0:64] / 64.0
    alpha = (0.5 + 0.45 * np.sin(2 * np.pi * (3 * xx + yy)) * np.cos(2 * np.pi * 2 * yy))
    tex = alpha_texture(alpha, filt)
    opaque = sr.Renderer(w, h).render(
        scene_of(sr.Material(base_color=(1, 1, 1, 1), base_color_texture=tex, model="unlit")),
        cam, outputs=("radiance", "instance_id"), **render)
    cut = sr.Renderer(w, h).render(scene_of(masked(tex, cutoff)), cam,
                                   outputs=("radiance", "instance_id", "coverage"), **render)
    return opaque, cut


def _plane_scene(material: sr.Material) -> sr.Scene:
    """A 3 x 3 quad with 4 x 4 uv repeats (the plane of _opencv_plane_camera)."""
    scene = sr.Scene()
    scene.add(quad(material, size=1.5, uv_scale=4.0), instance_id=FRONT_ID)
    return scene


@pytest.mark.parametrize("filt", FILTERS)
def test_perspective_plane_cuts_where_the_shaded_alpha_crosses(filt: str) -> None:
    """A tilted, minified plane (uv x4, mip levels and anisotropy in play): the mask keeps
    exactly the pixels whose shaded alpha (the same sample) reaches the cutoff."""
    w, h = 96, 72
    cam, _, _, _ = _opencv_plane_camera(w, h)
    scene_of = _plane_scene
    # (not 0.5: texels of exactly 0.5 would tie, and the opaque radiance is the alpha times an
    # interpolated white that may be 1 - 2^-24)
    opaque, cut = _alpha_and_masked(scene_of, cam, w, h, filt, 0.47)
    drawn = opaque.instance_id == FRONT_ID
    alpha = opaque.radiance[..., 0]
    expected = drawn & (alpha >= 0.47)
    assert 0.2 * drawn.sum() < expected.sum() < 0.8 * drawn.sum()
    np.testing.assert_array_equal(cut.instance_id == FRONT_ID, expected)
    np.testing.assert_array_equal(cut.radiance[expected], opaque.radiance[expected])
    np.testing.assert_array_equal(cut.coverage, expected.astype(cut.coverage.dtype))
    # the cut follows this filter's sample, not another's: nearest would keep other pixels
    if filt != "nearest":
        other, _ = _alpha_and_masked(scene_of, cam, w, h, "nearest", 0.47)
        assert ((other.radiance[..., 0] >= 0.47) & drawn != expected).sum() > 10


def test_texture_filter_option_applies_to_the_alpha_test() -> None:
    w, h = 96, 72
    cam, _, _, _ = _opencv_plane_camera(w, h)
    scene_of = _plane_scene
    opaque, cut = _alpha_and_masked(scene_of, cam, w, h, "trilinear", 0.47, texture_filter="nearest")
    expected = (opaque.instance_id == FRONT_ID) & (opaque.radiance[..., 0] >= 0.47)
    np.testing.assert_array_equal(cut.instance_id == FRONT_ID, expected)


def test_clipped_plane_through_the_near_plane() -> None:
    """A ground plane running from behind the camera to the horizon (its triangles are clipped
    at the near plane): the cut still matches the shaded alpha exactly."""
    w, h = 80, 60
    cam = sr.PerspectiveCamera(fov_y=70.0, near=0.05, far=50.0, width=w, height=h)
    pose = np.eye(4)
    pose[:3, 3] = (0.0, 0.4, 0.0)  # 0.4 above the plane y = 0, looking down -z, tilted down
    c, s = np.cos(-0.5), np.sin(-0.5)
    pose[:3, :3] = [[1, 0, 0], [0, c, -s], [0, s, c]]
    cam.pose = pose
    ground = np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1.0]])  # z=0 -> y=0

    def scene_of(material):
        scene = sr.Scene()
        scene.add(quad(material, size=10.0, uv_scale=8.0), pose=ground, instance_id=FRONT_ID)
        return scene

    opaque, cut = _alpha_and_masked(scene_of, cam, w, h, "trilinear", 0.4, cull="none")
    drawn = opaque.instance_id == FRONT_ID
    assert drawn[-1].all() and drawn.mean() > 0.5  # the plane fills the bottom rows
    expected = drawn & (opaque.radiance[..., 0] >= 0.4)
    assert 0.2 * drawn.sum() < expected.sum() < 0.9 * drawn.sum()
    np.testing.assert_array_equal(cut.instance_id == FRONT_ID, expected)
    assert np.isfinite(cut.radiance).all()


def _vertex_alpha_quad(alphas, material: sr.Material) -> sr.Mesh:
    m = quad(material)
    colors = np.ones((4, 4), np.float32)
    colors[:, 3] = alphas
    return sr.Mesh(m.positions, m.faces, uvs=m.uvs, colors=colors, material=material)


def test_vertex_alpha_is_interpolated_and_multiplies_the_texture() -> None:
    """Per-vertex alpha (no texture, then with one): kept iff the interpolated alpha (times the
    texture's) >= cutoff; the opaque render of colours equal to the alphas gives the reference."""
    w, h = 64, 48
    cam = ortho_camera(w, h)
    alphas = np.array([0.0, 1.0, 0.8, 0.2], np.float32)
    plain = sr.Material(base_color=(1, 1, 1, 1), model="unlit")
    grey = np.repeat(alphas[:, None], 4, axis=1)  # rgb = alpha: the radiance is the alpha
    ref_mesh = sr.Mesh(quad(plain).positions, quad(plain).faces, uvs=quad(plain).uvs,
                       colors=grey, material=plain)
    ref = sr.Scene()
    ref.add(ref_mesh)
    interpolated = sr.Renderer(w, h).render(ref, cam, outputs=("radiance",)).radiance[..., 0]
    cut = sr.Scene()
    cut.add(_vertex_alpha_quad(alphas, sr.Material(model="unlit", alpha_mode="mask", alpha_cutoff=0.45)))
    f = sr.Renderer(w, h).render(cut, cam, outputs=("mask",))
    expected = interpolated >= 0.45
    assert 0.2 < expected.mean() < 0.8
    np.testing.assert_array_equal(f.mask, expected)
    # times a texture's alpha: a left half of alpha 1 and a right half of alpha 0.5
    tex_alpha = np.ones((4, 4), np.float32)
    tex_alpha[:, 2:] = 0.5
    tex = alpha_texture(tex_alpha, "nearest")
    cut = sr.Scene()
    cut.add(_vertex_alpha_quad(alphas, masked(tex, 0.45)))
    f = sr.Renderer(w, h).render(cut, cam, outputs=("mask",))
    right = np.arange(w)[None, :] >= w // 2
    expected = interpolated * np.where(right, np.float32(0.5), np.float32(1.0)) >= np.float32(0.45)
    np.testing.assert_array_equal(f.mask, expected)


@pytest.mark.parametrize("alpha, drawn", [(0.3, False), (0.5, True), (0.7, True)])
def test_one_alpha_for_the_whole_draw(alpha: float, drawn: bool) -> None:
    """No texture alpha and no vertex colours: all or nothing (alpha == cutoff is kept)."""
    scene = two_layer_scene(quad(sr.Material(base_color=(1, 0, 0, alpha), alpha_mode="mask")))
    for outputs in (("instance_id", "color"), ("instance_id",)):
        f = sr.Renderer(32, 32).render(scene, ortho_camera(32, 32), outputs=outputs)
        assert (f.instance_id == (FRONT_ID if drawn else BACK_ID)).all()


def test_texture_without_alpha_and_opaque_mode_ignore_alpha() -> None:
    img = np.zeros((8, 8, 4), np.uint8)  # alpha 0 everywhere
    for material in (sr.Material(base_color_texture=sr.Texture(img[..., :3]), alpha_mode="mask"),
                     sr.Material(base_color=(1, 1, 1, 0), base_color_texture=sr.Texture(img)),
                     sr.Material(base_color=(1, 1, 1, 0.1))):
        f = sr.Renderer(16, 16).render(two_layer_scene(quad(material)), ortho_camera(16, 16),
                                       outputs=("instance_id",))
        assert (f.instance_id == FRONT_ID).all()


def test_coverage_counts_only_kept_fragments() -> None:
    """Two masked quads over each other: coverage = the number of them kept at each pixel."""
    h, w = 24, 32
    rng = np.random.default_rng(1)
    a = rng.integers(0, 256, (h, w, 4)).astype(np.uint8)
    b = rng.integers(0, 256, (h, w, 4)).astype(np.uint8)
    scene = sr.Scene()
    scene.add(quad(masked(sr.Texture(a, srgb=False, filter="nearest"), 0.5)))
    scene.add(quad(masked(sr.Texture(b, srgb=False, filter="nearest"), 0.5)),
              pose=np.diag([1.0, 1.0, 1.0, 1.0]) + np.array([[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0.1], [0, 0, 0, 0]]))
    f = sr.Renderer(w, h).render(scene, ortho_camera(w, h), outputs=("coverage", "instance_id"))
    expected = (a[..., 3] / 255 >= 0.5).astype(int) + (b[..., 3] / 255 >= 0.5)
    np.testing.assert_array_equal(f.coverage, expected)


def test_mask_with_lit_shading_and_normals_output() -> None:
    """Whatever the model: a pbr-lit masked quad under a light cuts the same pixels, and its
    normal output is the quad's normal where kept, the back quad's elsewhere (both +z)."""
    h, w = 32, 32
    img = np.random.default_rng(2).integers(0, 256, (h, w, 4)).astype(np.uint8)
    kept = img[..., 3] / 255 >= 0.5
    mat = sr.Material(base_color_texture=sr.Texture(img, filter="nearest"), model="pbr",
                      alpha_mode="mask")
    scene = two_layer_scene(quad(mat))
    scene.add(sr.DirectionalLight(intensity=2.0), pose=np.eye(4))
    for shading in ("auto", "lambert", "normal"):
        f = sr.Renderer(w, h).render(scene, ortho_camera(w, h), outputs=("color", "normal", "instance_id"),
                                     shading=shading)
        np.testing.assert_array_equal(f.instance_id, np.where(kept, FRONT_ID, BACK_ID))
        np.testing.assert_allclose(f.normal, np.broadcast_to([0, 0, 1.0], f.normal.shape), atol=1e-6)


def test_material_alpha_options_checked() -> None:
    m = sr.Material(alpha_mode="mask", alpha_cutoff=0.25)
    assert (m.alpha_mode, m.alpha_cutoff) == ("mask", 0.25)
    assert not m.plain and sr.Material().alpha_mode == "opaque"
    assert m.replace(alpha_cutoff=0.75).alpha_cutoff == 0.75
    import pickle
    assert pickle.loads(pickle.dumps(m)) == m
    with pytest.raises(ValueError, match="alpha_mode"):
        sr.Material(alpha_mode="clip")
    assert sr.Material(alpha_mode="blend").alpha_mode == "blend"  # "blend" is drawn
    assert m.replace(alpha_mode="blend").alpha_mode == "blend"
    for bad in (float("nan"), float("inf")):
        with pytest.raises(ValueError, match="alpha_cutoff"):
            sr.Material(alpha_cutoff=bad)
    with pytest.raises(TypeError, match="alpha_cutoff"):
        sr.Material(alpha_cutoff="half")


def test_from_pyrender_material_alpha_mode() -> None:
    """pyrender's alphaMode / alphaCutoff (read by attribute: a stand-in class from a module
    named like pyrender's) convert as a glTF file's do."""
    from softrast.interop import _material

    class MetallicRoughnessMaterial:  # noqa: D101 (pyrender's class name and attributes)
        def __init__(self, mode, cutoff):
            self.alphaMode, self.alphaCutoff = mode, cutoff
            self.name, self.baseColorFactor, self.doubleSided = "leaf", (1, 1, 1, 1), False

    MetallicRoughnessMaterial.__module__ = "pyrender.material"
    m = _material(MetallicRoughnessMaterial("MASK", 0.3))
    assert (m.alpha_mode, m.alpha_cutoff) == ("mask", 0.3)
    assert _material(MetallicRoughnessMaterial("OPAQUE", 0.5)).alpha_mode == "opaque"
    # BLEND alone converts opaque: from_pyrender makes a primitive "blend" where an alpha it
    # reads (this factor, its texture, its color_0) is below 1 (test_from_pyrender.py).
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _material(MetallicRoughnessMaterial("BLEND", None)).alpha_mode == "opaque"
