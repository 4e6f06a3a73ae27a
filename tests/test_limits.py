"""softrast.set_memory_budget: renders, imread, meshes and mesh files are refused before allocating."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import softrast as sr
from softrast import _core

from conftest import ALL_OUTPUTS, icosphere


@pytest.fixture(autouse=True)
def restore_budget():
    before = sr.get_memory_budget()
    yield
    sr.set_memory_budget(before)


def _scene_camera():
    scene = sr.Scene()
    scene.add(icosphere(1))
    cam = sr.PerspectiveCamera(fov_y=50.0)
    cam.look_at(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0))
    return scene, cam


def test_default_matches_core_limit_and_is_exported():
    assert sr.get_memory_budget() == _core.MAX_FRAMEBUFFER_BYTES == 4 * 2**30
    assert "set_memory_budget" in sr.__all__ and "get_memory_budget" in sr.__all__
    sr.set_memory_budget(12345)
    assert sr.get_memory_budget() == 12345


@pytest.mark.parametrize("value, error", [(0, ValueError), (-1, ValueError), (1.5, TypeError),
                                          (True, TypeError), ("1", TypeError)])
def test_bad_budget_refused(value, error):
    with pytest.raises(error, match="nbytes"):
        sr.set_memory_budget(value)


@pytest.mark.parametrize("outputs", [("color",), ("depth", "mask"), ALL_OUTPUTS])
def test_render_budget_is_exact(outputs):
    scene, cam = _scene_camera()
    renderer = sr.Renderer(40, 30)
    needed = sum(a.nbytes for a in renderer.render(scene, cam, outputs=outputs).as_dict().values())
    sr.set_memory_budget(needed)
    assert renderer.render(scene, cam, outputs=outputs).outputs == outputs
    sr.set_memory_budget(needed - 1)
    with pytest.raises(ValueError, match=rf"outputs .* needs {needed} bytes.*budget of {needed - 1} "
                                         r"bytes.*softrast.set_memory_budget"):
        renderer.render(scene, cam, outputs=outputs)


def test_render_budget_ignores_out_arrays():
    scene, cam = _scene_camera()
    renderer = sr.Renderer(40, 30)
    frame = renderer.render(scene, cam, outputs=("color", "depth"))
    expected = {k: v.copy() for k, v in frame.as_dict().items()}
    sr.set_memory_budget(1)  # nothing new may be allocated, and nothing needs to be
    renderer.render(scene, cam, outputs=("color", "depth"), out=frame)
    for name, want in expected.items():
        np.testing.assert_array_equal(getattr(frame, name), want)
    sr.set_memory_budget(40 * 30 - 1)  # the mask (1 B/px) is not in out => must be allocated
    with pytest.raises(ValueError, match=r"outputs \('mask',\) at 40x30 needs 1200 bytes"):
        renderer.render(scene, cam, outputs=("color", "depth", "mask"), out=frame)


def test_default_budget_refuses_before_the_core(monkeypatch):
    scene, cam = _scene_camera()
    renderer = sr.Renderer(16384, 16384)
    calls = []
    monkeypatch.setattr(renderer, "_core", type("Spy", (), {"render": lambda *a: calls.append(a),
                                                             "width": 16384, "height": 16384})())
    with pytest.raises(ValueError, match=r"needs 5100273664 bytes .*budget of 4294967296"):
        renderer.render(scene, cam, outputs=("normal", "color", "depth"))  # 19 B/px * 2**28 px
    assert calls == []


def test_imread_budget(tmp_path):
    image = np.arange(24 * 16 * 3, dtype=np.uint16).reshape(24, 16, 3)
    sr.imwrite(tmp_path / "im.png", image)
    sr.set_memory_budget(image.nbytes)
    np.testing.assert_array_equal(sr.imread(tmp_path / "im.png"), image)
    sr.set_memory_budget(image.nbytes - 1)
    with pytest.raises(ValueError, match=rf"im.png.*16x24x3.*needs {image.nbytes} bytes.*set_memory_budget"):
        sr.imread(tmp_path / "im.png")


def test_mesh_budget():
    m = trimesh.creation.icosphere(subdivisions=2)
    n, f = len(m.vertices), len(m.faces)
    needed = 4 * (3 * n + 3 * f)  # the stored float32 positions + int32 faces (the core views them)
    mesh = sr.Mesh(m.vertices, m.faces)
    assert needed == mesh.positions.nbytes + mesh.faces.nbytes
    sr.set_memory_budget(needed)
    sr.Mesh(m.vertices, m.faces)
    sr.set_memory_budget(needed - 1)
    with pytest.raises(ValueError, match=rf"mesh with {n} vertices and {f} triangles needs {needed}"):
        sr.Mesh(m.vertices, m.faces)
    # Attributes: normals 3, uvs 2 and colours 4 float32 per vertex (RGB is stored as RGBA).
    uvs, rgb = m.vertices[:, :2], np.full((n, 3), 0.5)
    with_all = needed + 4 * (3 + 2 + 4) * n
    sr.set_memory_budget(with_all)
    sr.Mesh(m.vertices, m.faces, normals=m.vertex_normals, uvs=uvs, colors=rgb)
    sr.set_memory_budget(with_all - 1)
    with pytest.raises(ValueError, match=rf"mesh with {n} vertices and {f} triangles needs {with_all}"):
        sr.Mesh(m.vertices, m.faces, normals=m.vertex_normals, uvs=uvs, colors=rgb)


def test_mesh_file_budget_from_header(tmp_path):
    # A consistent binary PLY whose declared counts exceed a small budget: refused from the header.
    m = trimesh.creation.icosphere(subdivisions=3)
    path = tmp_path / "sphere.ply"
    m.export(path, encoding="binary")
    sr.set_memory_budget(path.stat().st_size + 1)  # the file itself fits
    with pytest.raises(ValueError, match=r"sphere.ply.*PLY header counts.*set_memory_budget"):
        sr.load_mesh(path)
    sr.set_memory_budget(path.stat().st_size - 1)
    with pytest.raises(ValueError, match=r"mesh file .*sphere.ply' needs"):
        sr.load_mesh(path)


# -- textures: mip chains and decoded copies -----------------------------------------------------

MIP_SIDE = 512  # a 512 x 512 chain's build peaks near 28 B a texel: 7 MiB, over a 2 MiB budget


def _textured_scene(texture):
    quad = sr.Mesh(np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]]),
                   np.array([[0, 1, 2], [0, 2, 3]]), uvs=np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]),
                   material=sr.Material(base_color_texture=texture, model="unlit"))
    scene = sr.Scene()
    scene.add(quad)
    cam = sr.PerspectiveCamera(fov_y=50.0)
    cam.look_at(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0))
    return scene, cam


def _checker(side=MIP_SIDE, dtype=np.uint8):
    img = np.zeros((side, side, 4), dtype)
    img[::2, ::2] = 1.0 if np.dtype(dtype).kind == "f" else np.iinfo(dtype).max
    return img


@pytest.mark.parametrize("filt", ["trilinear", "anisotropic"])
def test_render_refuses_a_mip_chain_over_the_budget(filt):
    tex = sr.Texture(_checker(), filter=filt, name="checker.png")
    scene, cam = _textured_scene(tex)
    renderer = sr.Renderer(40, 30)
    sr.set_memory_budget(2 * 2**20)
    with pytest.raises(ValueError, match=r"texture 'checker\.png'.*mip chain.*memory budget"):
        renderer.render(scene, cam, outputs=("color",))
    assert not tex._core(True).has_mips  # refused before building
    # filters without a chain need none, and the override decides
    renderer.render(scene, cam, outputs=("color",), texture_filter="bilinear")
    with pytest.raises(ValueError, match="checker.png"):
        sr.Renderer(40, 30).render(_textured_scene(tex.replace(filter="nearest"))[0], cam,
                                   outputs=("color",), texture_filter=filt)
    sr.set_memory_budget(2**30)
    renderer.render(scene, cam, outputs=("color",))
    assert tex._core(True).has_mips
    sr.set_memory_budget(2 * 2**20)  # built once: later renders allocate no chain
    renderer.render(scene, cam, outputs=("color",))


def test_texture_mip_levels_and_sample_check_the_budget():
    tex = sr.Texture(_checker(), srgb=False, name="checker.png")
    sr.set_memory_budget(2 * 2**20)
    assert tex.levels[1] == (MIP_SIDE // 2, MIP_SIDE // 2)  # sizes are known without the chain
    with pytest.raises(ValueError, match=r"texture 'checker\.png'.*mip chain"):
        tex.mip(1)
    with pytest.raises(ValueError, match=r"texture 'checker\.png'.*level 0"):
        tex.mip(0)  # a (512, 512, 4) float32 array: 4 MiB
    uv = np.full((8, 2), 0.25)
    with pytest.raises(ValueError, match=r"texture 'checker\.png'.*mip chain"):
        tex.sample(uv)  # the texture's trilinear filter
    with pytest.raises(ValueError, match=r"texture 'checker\.png'.*mip chain"):
        tex.sample(uv, filter="anisotropic")
    assert tex.sample(uv, filter="bilinear").shape == (8, 4)  # no chain needed
    assert not tex._core().has_mips
    sr.set_memory_budget(2**30)
    assert tex.mip(1).shape == (MIP_SIDE // 2, MIP_SIDE // 2, 4)
    sr.set_memory_budget(2 * 2**20)
    assert tex.mip(5).shape == (MIP_SIDE // 32, MIP_SIDE // 32, 4)  # built: small levels are fine
    tex.sample(uv)


@pytest.mark.parametrize("dtype, srgb", [(np.uint16, False), (np.uint16, True), (np.float32, True),
                                         (np.float64, False)])
def test_a_texture_s_decoded_copy_counts(dtype, srgb):
    """Non-uint8 textures are converted to float32 (sRGB-decoded in float64) for the core: that
    copy, 4 MiB for 512 x 512 x 4, is checked against the budget first, naming the texture."""
    tex = sr.Texture(_checker(dtype=dtype), srgb=srgb, filter="bilinear", name="big.exr")
    sr.set_memory_budget(2 * 2**20)
    with pytest.raises(ValueError, match=r"texture 'big\.exr'.*decoded"):
        tex.levels
    with pytest.raises(ValueError, match=r"texture 'big\.exr'"):
        sr.Material(base_color_texture=tex)
    sr.set_memory_budget(2**30)
    assert tex.levels[0] == (MIP_SIDE, MIP_SIDE)
    assert sr.Texture(_checker(dtype=np.float32), srgb=False).levels  # float32 linear: viewed, no copy


def test_huge_texture_refused_before_copying_or_building():
    """32768 x 32768 (the largest side a texture may have): the contiguous copy of a strided
    uint8 image and a chain of 28 GiB are refused under the budget, never std::bad_alloc."""
    image = np.broadcast_to(np.uint8(200), (32768, 32768, 1))  # no memory behind it
    tex = sr.Texture(image, name="huge")
    sr.set_memory_budget(64 * 2**20)
    with pytest.raises(ValueError, match=r"texture 'huge'"):
        sr.Material(base_color_texture=tex)
    with pytest.raises(ValueError, match=r"texture 'huge'"):
        tex.sample(np.zeros((1, 2)))
