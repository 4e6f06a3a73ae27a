"""Textures from mesh files: glTF / GLB (baseColorTexture, emissiveTexture, normalTexture,
metallicRoughnessTexture, occlusionTexture and its strength, samplers) and OBJ + MTL (map_Kd,
map_Ke, norm, map_Bump / bump as height or normal maps), their uv convention checked on rendered
pixels, metallic-roughness, occlusion and bump maps checked on rendered radiance, sharing within
a load, and a warning for every map that is not drawn.

uv convention: trimesh flips glTF's v on load (v = 1 - v), so every loaded mesh's uvs are
OpenGL-style (v up, image row 0 at v = 1), as OBJ's vt are; the loaders make every texture with
uv_origin="bottom_left". The pixel tests below find the expected texel on their own (ray /
triangle intersection from the camera's matrices, barycentric uvs, then row = (1 - v) * h), so a
flipped texture fails them.
"""
from __future__ import annotations

import json
import struct
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh

import softrast as sr
from softrast.reference.encoding import srgb_curve, srgb_to_linear

ROOT = Path(__file__).resolve().parents[1]
ASSETS = ROOT / "assets" / "meshes"
BOX_TEXTURED = ASSETS / "BoxTextured.gltf"
SPOT = ASSETS / "spot.obj"
SPOT_TEXTURE = ASSETS / "spot_texture.png"


@pytest.fixture
def no_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        yield


def decode(byte):
    return srgb_to_linear(np.asarray(byte, dtype=np.float64) / 255.0)


def encode(c):  # c in [0, 1]
    return np.rint(255 * srgb_curve(c))


# -- helpers: the texel under a pixel, found independently of the renderer ----------------------
def pixel_uvs(scene, camera, width, height, tri_ids, pixels):
    """uv of the visible surface at each pixel centre (row, col): the camera ray through it
    (unprojected with the camera's matrices) intersected with the triangle ``tri_ids`` names;
    NaN where the ray misses that triangle (pixels at its edges)."""
    (inst,) = scene.instances
    mesh = inst.mesh
    world = (np.c_[mesh.positions, np.ones(len(mesh.positions))] @ inst.pose.T)[:, :3]
    inverse = np.linalg.inv(camera.projection_matrix(width, height) @ camera.view_matrix())
    out = np.full((len(pixels), 2), np.nan)
    for k, (row, col) in enumerate(pixels):
        x = (col + 0.5) / width * 2 - 1
        y = 1 - (row + 0.5) / height * 2
        ends = [inverse @ [x, y, z, 1.0] for z in (0.0, 0.5)]
        a, b = (e[:3] / e[3] for e in ends)
        d = b - a
        face = mesh.faces[tri_ids[row, col]]
        p0, p1, p2 = world[face]
        # Moller-Trumbore
        e1, e2 = p1 - p0, p2 - p0
        h = np.cross(d, e2)
        det = e1 @ h
        s = a - p0
        b1 = (s @ h) / det
        q = np.cross(s, e1)
        b2 = (d @ q) / det
        b0 = 1 - b1 - b2
        if min(b0, b1, b2) < -1e-9:
            continue
        out[k] = b0 * mesh.uvs[face[0]] + b1 * mesh.uvs[face[1]] + b2 * mesh.uvs[face[2]]
    return out


def texel_at(image, uv, flip=False):
    """The texel nearest filtering picks at ``uv`` (repeat wrap, image row 0 at v = 1, or at v = 0
    with ``flip``); None near a texel boundary."""
    h, w = image.shape[:2]
    u, v = uv - np.floor(uv)
    x, y = u * w, (v if flip else 1 - v) * h
    if min(abs(x - round(x)), abs(y - round(y))) < 0.05:
        return None
    return image[min(int(y), h - 1), min(int(x), w - 1)]


# -- glTF ---------------------------------------------------------------------------------------
def test_box_textured_gltf_texture_lands_right_side_up(no_warnings):
    scene = sr.load_scene(BOX_TEXTURED)
    (inst,) = scene.instances
    material = inst.material
    texture = material.base_color_texture
    assert isinstance(texture, sr.Texture)
    # a palette PNG (mode P, no transparency) -> RGB uint8; its sampler: minFilter 9986
    # (NEAREST_MIPMAP_LINEAR) -> trilinear; wrapS / wrapT 10497 -> repeat
    assert texture.image.shape == (211, 211, 3) and texture.image.dtype == np.uint8
    assert texture.uv_origin == "bottom_left" and texture.srgb is None
    assert texture.filter == "trilinear" and texture.wrap == ("repeat", "repeat")
    assert material.emissive_texture is None and material.normal_texture is None
    # the texels are the PNG's (decoded here with Pillow from the file's data URI)
    from PIL import Image
    import base64
    import io

    doc = json.loads(BOX_TEXTURED.read_text())
    png = base64.b64decode(doc["images"][0]["uri"].split(",", 1)[1])
    np.testing.assert_array_equal(texture.image, np.asarray(Image.open(io.BytesIO(png)).convert("RGB")))

    width = height = 160
    camera = sr.PerspectiveCamera(fov_y=40.0, near=0.1, far=20.0)
    camera.look_at(eye=(1.6, 1.2, 2.2), target=(0.0, 0.0, 0.0), up=(0, 1, 0))
    frame = sr.Renderer(width, height).render(scene, camera, outputs=("color", "triangle_id"), shading="unlit",
                                              srgb=True, texture_filter="nearest")
    rows, cols = np.nonzero(frame.triangle_id >= 0)
    pick = np.arange(0, len(rows), 7)
    pixels = list(zip(rows[pick], cols[pick]))
    uvs = pixel_uvs(scene, camera, width, height, frame.triangle_id, pixels)
    assert np.isfinite(uvs[:, 0]).mean() > 0.9  # the unprojection agrees with the renderer
    checked = wrong_if_flipped = 0
    for (row, col), uv in zip(pixels, uvs):
        if not np.isfinite(uv[0]):
            continue
        expected = texel_at(texture.image, uv)
        if expected is None:
            continue
        got = frame.color[row, col].astype(int)
        assert np.abs(got - expected.astype(int)).max() <= 2, (row, col, uv, got, expected)
        checked += 1
        flipped = texel_at(texture.image, uv, flip=True)
        wrong_if_flipped += flipped is not None and np.abs(got - flipped.astype(int)).max() > 2
    assert checked > 300
    assert wrong_if_flipped > checked // 3  # the check can tell a flipped texture


def _glb_parts(data: bytes):
    _, _, _, n, _ = struct.unpack("<4sIII4s", data[:20])
    return json.loads(data[20:20 + n]), data[20 + n:]


def _glb(doc, rest: bytes) -> bytes:
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    return struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text) + len(rest)) + \
        struct.pack("<I4s", len(text), b"JSON") + text + rest


RNG_IMAGE = np.random.default_rng(7).integers(0, 256, (8, 8, 3), dtype=np.uint8)


def _textured_glb(tmp_path, edit=None, name="tex.glb", **textures):
    """A box with a PBR material whose textures are PIL images, written by trimesh's exporter
    (then its JSON edited)."""
    from PIL import Image

    box = trimesh.creation.box()
    uv = np.random.default_rng(0).random((len(box.vertices), 2))
    images = {k: Image.fromarray(v) if isinstance(v, np.ndarray) else v for k, v in textures.items()}
    box.visual = trimesh.visual.TextureVisuals(uv=uv, material=trimesh.visual.material.PBRMaterial(
        name="paint", **images))
    doc, rest = _glb_parts(box.export(file_type="glb"))
    if edit:
        edit(doc)
    path = tmp_path / name
    path.write_bytes(_glb(doc, rest))
    return path, uv


def test_glb_textures_samplers_and_normal_scale(tmp_path, no_warnings):
    normal = np.full((4, 4, 3), (128, 128, 255), np.uint8)
    grey_alpha = np.random.default_rng(1).integers(0, 256, (4, 6, 2), dtype=np.uint8)

    def edit(doc):
        mat = doc["materials"][0]
        mat["emissiveFactor"] = [1.0, 0.5, 0.25]
        mat["normalTexture"]["scale"] = 0.5
        doc["samplers"] = [{"wrapS": 33071, "wrapT": 33648, "magFilter": 9728, "minFilter": 9728},
                           {"wrapS": 33648, "minFilter": 9729}]
        doc["textures"][mat["pbrMetallicRoughness"]["baseColorTexture"]["index"]]["sampler"] = 0
        doc["textures"][mat["emissiveTexture"]["index"]]["sampler"] = 1
        doc["images"][mat["normalTexture"]["index"]]["name"] = "bumps"

    path, uv = _textured_glb(tmp_path, edit, baseColorTexture=RNG_IMAGE, emissiveTexture=grey_alpha,
                             normalTexture=normal)
    mesh = sr.load_mesh(path)
    m = mesh.material
    assert m.model == "pbr" and m.emissive == (1.0, 0.5, 0.25)
    np.testing.assert_array_equal(m.base_color_texture.image, RNG_IMAGE)
    assert m.base_color_texture.image.dtype == np.uint8
    assert m.base_color_texture.wrap == ("clamp", "mirror") and m.base_color_texture.filter == "nearest"
    np.testing.assert_array_equal(m.emissive_texture.image, grey_alpha)  # LA: 2 channels kept
    assert m.emissive_texture.wrap == ("mirror", "repeat") and m.emissive_texture.filter == "bilinear"
    np.testing.assert_array_equal(m.normal_texture.image, normal)
    assert m.normal_texture.filter == "trilinear" and m.normal_texture.wrap == ("repeat", "repeat")
    assert m.normal_texture.name == "bumps"
    assert m.normal_scale == 0.5 and m.normal_map_convention == "opengl"
    for tex in (m.base_color_texture, m.emissive_texture, m.normal_texture):
        assert tex.uv_origin == "bottom_left" and tex.srgb is None  # the slot decides
    # trimesh flipped the file's v: the mesh has the uvs trimesh was given (what it exported)
    np.testing.assert_allclose(mesh.uvs, uv, atol=1e-6)


@pytest.mark.parametrize("mode, channels", [("L", 1), ("LA", 2), ("RGB", 3), ("RGBA", 4), ("P", 3),
                                            ("P+transparency", 4), ("I;16", 1)])
def test_pil_modes_become_1_to_4_channels(tmp_path, no_warnings, mode, channels):
    from PIL import Image

    rng = np.random.default_rng(2)
    rgba = rng.integers(0, 256, (5, 7, 4), dtype=np.uint8)
    if mode == "I;16":
        data = rng.integers(0, 65536, (5, 7), dtype=np.uint16)
        image = Image.fromarray(data)
        assert image.mode == "I;16"
        expected = data
    elif mode.startswith("P"):
        image = Image.fromarray(rgba[:, :, :3]).quantize(colors=16)
        if mode == "P+transparency":
            image.info["transparency"] = 0
        expected = np.asarray(image.convert("RGBA" if channels == 4 else "RGB"))
    else:
        image = Image.fromarray(rgba[:, :, :channels] if channels > 1 else rgba[:, :, 0], mode)
        expected = np.asarray(image)
    tm = trimesh.creation.box()
    tm.visual = trimesh.visual.TextureVisuals(uv=np.zeros((8, 2)), material=trimesh.visual.material.PBRMaterial(
        baseColorTexture=image))
    texture = sr.Mesh.from_trimesh(tm).material.base_color_texture
    assert texture.channels == channels
    np.testing.assert_array_equal(texture.image.reshape(expected.shape), expected)
    assert texture.image.dtype == (np.uint16 if mode == "I;16" else np.uint8)


def test_glb_texcoord_and_transform_warn_but_blend_mr_and_occlusion_load(tmp_path):
    mr = np.full((2, 2, 3), (0, 128, 255), np.uint8)

    def edit(doc):
        mat = doc["materials"][0]
        mat["occlusionTexture"] = {"index": mat["pbrMetallicRoughness"]["metallicRoughnessTexture"]["index"]}
        mat["alphaMode"] = "BLEND"
        mat["emissiveTexture"] = {"index": 0, "texCoord": 1}
        mat["pbrMetallicRoughness"]["baseColorTexture"]["extensions"] = {"KHR_texture_transform": {"scale": [2, 2]}}

    path, _ = _textured_glb(tmp_path, edit, baseColorTexture=RNG_IMAGE, metallicRoughnessTexture=mr)
    with pytest.warns(UserWarning) as record:
        scene = sr.load_scene(path)
    (text,) = [str(w.message) for w in record]
    assert text.startswith(f"{path}: material 'paint': ")
    for part in ("emissiveTexture uses texCoord 1 and only TEXCOORD_0 is read: not drawn",
                 "baseColorTexture: extension KHR_texture_transform is ignored"):
        assert part in text
    assert "metallicRoughnessTexture" not in text and "occlusionTexture" not in text
    assert "alphaMode" not in text  # BLEND is drawn
    (inst,) = scene.instances
    m = inst.material
    assert m.alpha_mode == "blend"
    assert m.base_color_texture is not None and m.emissive_texture is None
    # one image named by both slots (an occlusion-roughness-metallic image): one Texture
    assert m.metallic_roughness_texture is m.occlusion_texture
    np.testing.assert_array_equal(m.metallic_roughness_texture.image, mr)
    assert m.occlusion_strength == 1.0  # glTF's default


@pytest.mark.parametrize("cutoff", [None, 0.25])
def test_glb_alpha_mask_loads_and_cuts(tmp_path, no_warnings, cutoff):
    """alphaMode MASK with the file's alphaCutoff (glTF's default 0.5 when absent): the mesh is
    drawn exactly where the texture's alpha reaches it, from load_mesh and from trimesh."""
    rgba = np.random.default_rng(3).integers(0, 256, (8, 8, 4), dtype=np.uint8)

    def edit(doc):
        mat = doc["materials"][0]
        mat["alphaMode"] = "MASK"
        if cutoff is not None:
            mat["alphaCutoff"] = cutoff

    path, _ = _textured_glb(tmp_path, edit, baseColorTexture=rgba)
    expected_cutoff = 0.5 if cutoff is None else cutoff
    for mesh in (sr.load_mesh(path), sr.Mesh.from_trimesh(trimesh.load(path, force="mesh"))):
        m = mesh.material
        assert (m.alpha_mode, m.alpha_cutoff) == ("mask", expected_cutoff)
        np.testing.assert_array_equal(m.base_color_texture.image, rgba)
    # a quad with the file's material and one texel per pixel
    n = 8
    quad = sr.Mesh(np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32),
                   np.array([[0, 1, 2], [0, 2, 3]]), uvs=np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]),
                   material=m.replace(base_color_texture=sr.Texture(rgba, filter="nearest")))
    scene = sr.Scene()
    scene.add(quad)
    cam = sr.OrthographicCamera(xmag=1.0, ymag=1.0, width=n, height=n)
    cam.pose = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 2.0], [0, 0, 0, 1]])
    frame = sr.Renderer(n, n).render(scene, cam, outputs=("mask",))
    np.testing.assert_array_equal(frame.mask, rgba[..., 3] / 255 >= expected_cutoff)


def test_glb_bad_alpha_cutoff_warns(tmp_path):
    def edit(doc):
        doc["materials"][0].update(alphaMode="MASK", alphaCutoff=-1)

    path, _ = _textured_glb(tmp_path, edit, baseColorTexture=RNG_IMAGE)
    with pytest.warns(UserWarning, match="alphaCutoff -1 is not a number >= 0"):
        m = sr.load_mesh(path).material
    assert (m.alpha_mode, m.alpha_cutoff) == ("mask", 0.5)


def _lit_scene(mesh, ambient=(0.2, 0.2, 0.2)):
    scene = sr.Scene(ambient_light=ambient)
    scene.add(mesh)
    scene.add(sr.PointLight(intensity=6.0), pose=trimesh.transformations.translation_matrix([1.5, 2.0, 2.5]))
    return scene


def _radiance(mesh, ambient=(0.2, 0.2, 0.2)):
    """The box seen from a corner (three faces), lit by a point light and an ambient light."""
    camera = sr.PerspectiveCamera(fov_y=40.0, near=0.1, far=20.0)
    camera.look_at(eye=(1.6, 1.2, 2.2), target=(0.0, 0.0, 0.0), up=(0, 1, 0))
    frame = sr.Renderer(48, 48).render(_lit_scene(mesh, ambient), camera, outputs=("radiance", "triangle_id"))
    assert (frame.triangle_id >= 0).mean() > 0.3
    return frame.radiance


PAINT_FACTORS = {"baseColorFactor": [0.8, 0.5, 0.3, 1.0], "metallicFactor": 0.8, "roughnessFactor": 0.6}


def _factors_only(g: int, b: int):
    """A glTF edit: PAINT_FACTORS with roughness x g/255 and metallic x b/255, and no
    metallicRoughnessTexture (what a constant (_, g, b) texture should render as)."""
    def scaled(doc):
        pbr = doc["materials"][0]["pbrMetallicRoughness"]
        pbr.update(PAINT_FACTORS)
        del pbr["metallicRoughnessTexture"]
        pbr["roughnessFactor"] = 0.6 * g / 255
        pbr["metallicFactor"] = 0.8 * b / 255
    return scaled


def test_glb_metallic_roughness_and_occlusion_textures_load(tmp_path, no_warnings):
    mr = np.full((4, 4, 3), (0, 64, 128), np.uint8)
    ao = np.random.default_rng(3).integers(0, 256, (4, 4), dtype=np.uint8)  # L: 1 channel

    def edit(doc):
        mat = doc["materials"][0]
        mat["pbrMetallicRoughness"].update(PAINT_FACTORS)
        mat["occlusionTexture"]["strength"] = 0.5
        doc["samplers"] = [{"wrapS": 33071, "wrapT": 33648, "magFilter": 9728, "minFilter": 9728}]
        doc["textures"][mat["occlusionTexture"]["index"]]["sampler"] = 0

    path, uv = _textured_glb(tmp_path, edit, metallicRoughnessTexture=mr, occlusionTexture=ao)
    mesh = sr.load_mesh(path)  # no warning: both are drawn
    m = mesh.material
    assert m.model == "pbr" and m.metallic == 0.8 and m.roughness == 0.6
    np.testing.assert_array_equal(m.metallic_roughness_texture.image, mr)
    np.testing.assert_array_equal(m.occlusion_texture.image.reshape(4, 4), ao)
    assert m.occlusion_strength == 0.5
    assert m.metallic_roughness_texture.filter == "trilinear"
    assert m.metallic_roughness_texture.wrap == ("repeat", "repeat")
    assert m.occlusion_texture.filter == "nearest" and m.occlusion_texture.wrap == ("clamp", "mirror")
    for tex in (m.metallic_roughness_texture, m.occlusion_texture):
        # linear data: the slot decides (srgb None reads linear in these slots)
        assert tex.uv_origin == "bottom_left" and tex.srgb is None
    assert m.base_color_texture is None and m.normal_texture is None and m.bump_texture is None
    np.testing.assert_allclose(mesh.uvs, uv, atol=1e-6)


@pytest.mark.parametrize("strength, expected, warning", [
    (None, 1.0, None), (0.0, 0.0, None), (1, 1.0, None),
    (1.5, 1.0, "occlusionTexture strength 1.5 clipped to [0, 1]"),
    (-0.25, 0.0, "occlusionTexture strength -0.25 clipped to [0, 1]"),
    ("half", 1.0, "occlusionTexture strength 'half' is not a number (using 1)")])
def test_glb_occlusion_strength_from_the_json(tmp_path, strength, expected, warning):
    def edit(doc):
        if strength is not None:
            doc["materials"][0]["occlusionTexture"]["strength"] = strength

    path, _ = _textured_glb(tmp_path, edit, occlusionTexture=np.full((2, 2), 200, np.uint8))
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        m = sr.load_mesh(path).material
    texts = [str(w.message) for w in record]
    if warning is None:
        assert texts == []
    else:
        (text,) = texts
        assert text.startswith(f"{path}: material 'paint': ") and warning in text
    assert m.occlusion_texture is not None and m.occlusion_strength == expected


def test_glb_metallic_roughness_texture_renders_as_scaled_factors(tmp_path, no_warnings):
    """A constant metallic-roughness texel (0, g, b) renders as the same file without the texture
    and with roughnessFactor x g, metallicFactor x b (the red channel is not read)."""
    g, b = 64, 128
    mr = np.full((4, 4, 3), (0, g, b), np.uint8)

    def textured(doc):
        doc["materials"][0]["pbrMetallicRoughness"].update(PAINT_FACTORS)

    scaled = _factors_only(g, b)

    path, _ = _textured_glb(tmp_path, textured, metallicRoughnessTexture=mr)
    plain_path, _ = _textured_glb(tmp_path, scaled, name="scaled.glb", metallicRoughnessTexture=mr)
    mesh, plain = sr.load_mesh(path), sr.load_mesh(plain_path)
    assert mesh.material.metallic_roughness_texture is not None
    assert plain.material.metallic_roughness_texture is None and not plain.material.textured
    assert plain.material.roughness == pytest.approx(0.6 * g / 255, rel=1e-15)
    got, expected = _radiance(mesh), _radiance(plain)
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-7)
    # the texture matters: without it (the factors alone) the box renders differently
    unscaled = _radiance(sr.Mesh(mesh.positions, mesh.faces, normals=mesh.normals, uvs=mesh.uvs,
                                 material=mesh.material.replace(metallic_roughness_texture=None)))
    assert np.abs(unscaled - expected).max() > 0.05


def test_glb_occlusion_roughness_metallic_image_renders(tmp_path, no_warnings):
    """One image (a, g, b) named by occlusionTexture (strength 0.5) and metallicRoughnessTexture:
    the ambient term times 1 + 0.5 (a - 1), on top of the factors render; the ambient term is
    what the ambient light adds (the render with it less the one without)."""
    a, g, b = 51, 191, 204
    orm = np.full((4, 4, 3), (a, g, b), np.uint8)

    def textured(doc):
        mat = doc["materials"][0]
        mat["pbrMetallicRoughness"].update(PAINT_FACTORS)
        mat["occlusionTexture"] = {"index": mat["pbrMetallicRoughness"]["metallicRoughnessTexture"]["index"],
                                   "strength": 0.5}

    scaled = _factors_only(g, b)

    path, _ = _textured_glb(tmp_path, textured, metallicRoughnessTexture=orm)
    plain_path, _ = _textured_glb(tmp_path, scaled, name="scaled.glb", metallicRoughnessTexture=orm)
    mesh, plain = sr.load_mesh(path), sr.load_mesh(plain_path)
    m = mesh.material
    assert m.occlusion_texture is m.metallic_roughness_texture and m.occlusion_strength == 0.5
    lit, dark = _radiance(plain), _radiance(plain, ambient=(0.0, 0.0, 0.0))
    ambient = lit - dark
    assert ambient.max() > 0.01
    expected = lit + ambient * (0.5 * (a / 255 - 1.0))
    np.testing.assert_allclose(_radiance(mesh), expected, rtol=1e-5, atol=1e-6)
    # without an ambient light the occlusion texture changes nothing
    np.testing.assert_allclose(_radiance(mesh, ambient=(0.0, 0.0, 0.0)), dark, rtol=1e-5, atol=1e-7)


def test_from_trimesh_pbr_material_metallic_roughness_and_occlusion(no_warnings):
    from PIL import Image

    mr = Image.fromarray(np.full((2, 2, 3), (0, 100, 200), np.uint8))
    ao = Image.fromarray(np.full((2, 2), 150, np.uint8))
    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(uv=np.zeros((8, 2)), material=trimesh.visual.material.PBRMaterial(
        metallicRoughnessTexture=mr, occlusionTexture=ao, metallicFactor=0.5))
    m = sr.Mesh.from_trimesh(box).material
    np.testing.assert_array_equal(m.metallic_roughness_texture.image, np.asarray(mr))
    np.testing.assert_array_equal(m.occlusion_texture.image.reshape(2, 2), np.asarray(ao))
    assert m.occlusion_strength == 1.0 and m.metallic == 0.5 and m.roughness == 1.0
    assert m.metallic_roughness_texture.srgb is None and m.occlusion_texture.srgb is None


def test_from_trimesh_textures_without_uvs_are_dropped_naming_every_slot():
    from PIL import Image

    img = Image.fromarray(np.full((2, 2, 3), 100, np.uint8))
    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(
        name="paint", metallicRoughnessTexture=img, occlusionTexture=img))
    with pytest.warns(UserWarning, match=r"material 'paint': the mesh has no uvs, so its "
                                         r"metallic_roughness_texture, occlusion_texture cannot be drawn"):
        m = sr.Mesh.from_trimesh(box).material
    assert not m.textured


def test_glb_texture_that_cannot_be_read_warns(tmp_path):
    def edit(doc):
        doc["materials"][0]["normalTexture"] = {"index": 9}

    path, _ = _textured_glb(tmp_path, edit, baseColorTexture=RNG_IMAGE)
    with pytest.warns(UserWarning, match=r"tex\.glb: material 'paint': normalTexture refers to texture 9, "
                                         r"which the file does not have: not drawn"):
        mesh = sr.load_mesh(path)
    assert mesh.material.normal_texture is None and mesh.material.base_color_texture is not None


def test_one_texture_per_image_within_a_load(tmp_path, no_warnings):
    # two materials, on two meshes, both naming image 0; the box placed twice
    from PIL import Image

    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(uv=np.random.default_rng(0).random((8, 2)),
                                               material=trimesh.visual.material.PBRMaterial(
                                                   name="a", baseColorTexture=Image.fromarray(RNG_IMAGE)))
    ball = trimesh.creation.icosphere(subdivisions=1)
    ball.visual = trimesh.visual.TextureVisuals(uv=np.zeros((len(ball.vertices), 2)),
                                                material=trimesh.visual.material.PBRMaterial(
                                                    name="b", baseColorTexture=Image.fromarray(RNG_IMAGE),
                                                    emissiveTexture=Image.fromarray(RNG_IMAGE)))
    tscene = trimesh.Scene()
    tscene.add_geometry(box, node_name="one", geom_name="box")
    tscene.add_geometry(box, node_name="two", geom_name="box",
                        transform=trimesh.transformations.translation_matrix([3.0, 0.0, 0.0]))
    tscene.add_geometry(ball, node_name="ball", geom_name="ball")
    doc, rest = _glb_parts(tscene.export(file_type="glb"))
    assert len(doc["images"]) >= 2  # trimesh writes the image once per use
    path = tmp_path / "shared.glb"
    path.write_bytes(_glb(doc, rest))
    scene = sr.load_scene(path)
    textures = {id(inst.material.base_color_texture) for inst in scene}
    textures |= {id(inst.material.emissive_texture) for inst in scene if inst.material.emissive_texture}
    assert len(scene) == 3 and len(textures) == 1
    # another load makes its own
    again = sr.load_scene(path)
    assert again.instances[0].material.base_color_texture is not scene.instances[0].material.base_color_texture


def test_missing_pillow_warns_naming_the_file(tmp_path, monkeypatch):
    path, _ = _textured_glb(tmp_path, baseColorTexture=RNG_IMAGE)
    for name in [k for k in sys.modules if k == "PIL" or k.startswith("PIL.")]:
        monkeypatch.setitem(sys.modules, name, None)
    monkeypatch.setitem(sys.modules, "PIL", None)
    with pytest.warns(UserWarning) as record:
        mesh = sr.load_mesh(path)
    (text,) = [str(w.message) for w in record]
    assert text.startswith(f"{path}: Pillow is not installed") and "pip install pillow" in text
    assert mesh.material is not None and mesh.material.base_color_texture is None


def test_pillow_is_importable():
    import PIL.Image  # a dependency (pyproject.toml): trimesh needs it for the images of GLB and MTL

    assert PIL.Image.open is not None
    text = (ROOT / "pyproject.toml").read_text()
    deps = text.split("dependencies = [", 1)[1].split("]", 1)[0].lower()
    assert "pillow" in deps


# -- OBJ + MTL ----------------------------------------------------------------------------------
QUAD_OBJ = """mtllib quad.mtl
v -1 -1 0
v 1 -1 0
v 1 1 0
v -1 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
usemtl {material}
f 1/1/1 2/2/1 3/3/1
f 1/1/1 3/3/1 4/4/1
"""

IMAGE = np.array([[[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 0]],
                  [[0, 255, 255], [255, 0, 255], [255, 255, 255], [0, 0, 0]],
                  [[128, 0, 0], [0, 128, 0], [0, 0, 128], [128, 128, 0]],
                  [[0, 128, 128], [128, 0, 128], [64, 64, 64], [200, 100, 50]]], np.uint8)


def _quad(tmp_path, mtl, material="tex"):
    (tmp_path / "quad.obj").write_text(QUAD_OBJ.format(material=material))
    (tmp_path / "quad.mtl").write_text(mtl)
    return tmp_path / "quad.obj"


def _render_quad(mesh, texture_filter="nearest", shading="unlit"):
    """The quad filling a 64 x 64 image exactly: pixel (r, c) sees uv ((c + 0.5) / 64,
    1 - (r + 0.5) / 64)."""
    scene = sr.Scene()
    scene.add(mesh)
    camera = sr.OrthographicCamera(xmag=1.0, ymag=1.0, near=0.1, far=10.0)
    camera.look_at(eye=(0, 0, 3), target=(0, 0, 0), up=(0, 1, 0))
    return sr.Renderer(64, 64).render(scene, camera, outputs=("color",), shading=shading, srgb=True,
                                      texture_filter=texture_filter).color


def test_obj_map_kd_renders_right_side_up_and_multiplies_kd(tmp_path, no_warnings):
    sr.imwrite(tmp_path / "tex.png", IMAGE)
    path = _quad(tmp_path, "newmtl tex\nmap_Kd tex.png\n")
    mesh = sr.load_mesh(path)
    m = mesh.material
    assert m.kd is None and m.base_color == (1.0, 1.0, 1.0, 1.0)  # no Kd: the texture as is
    assert m.base_color_texture.uv_origin == "bottom_left" and m.base_color_texture.name == "tex.png"
    np.testing.assert_array_equal(m.base_color_texture.image, IMAGE)
    color = _render_quad(mesh)
    # uv (0, 1) is the quad's top-left corner: the image's top-left texel is drawn there
    np.testing.assert_array_equal(color[:16, :16], np.broadcast_to(IMAGE[0, 0], (16, 16, 3)))
    np.testing.assert_array_equal(color, np.repeat(np.repeat(IMAGE, 16, axis=0), 16, axis=1))
    # the default (trilinear) filter: near the centre of each texel's 16 x 16 block, that texel
    # (pixel centres are 1/32 of a texel from texel centres, so a little of the neighbours)
    smooth = _render_quad(mesh, texture_filter=None)
    assert m.base_color_texture.filter == "trilinear"
    assert np.abs(decode(smooth[8::16, 8::16]) - decode(IMAGE)).max() < 0.1

    # Kd multiplies the texture (kd is the base colour, which the texture multiplies)
    path = _quad(tmp_path, "newmtl tex\nKa 0.1 0.1 0.1\nKd 0.5 0.25 1.0\nd 1\nmap_Kd tex.png\n")
    m = sr.load_mesh(path).material
    assert m.kd is None and m.ka == (0.1, 0.1, 0.1) and m.base_color == (0.5, 0.25, 1.0, 1.0)
    color = _render_quad(sr.load_mesh(path)).astype(int)
    expected = encode(decode(IMAGE) * [0.5, 0.25, 1.0])
    assert np.abs(color[8::16, 8::16] - expected).max() <= 1
    # lit: the diffuse term carries the texture
    lit = _render_quad(sr.load_mesh(path), shading="lambert").astype(int)
    assert lit[:16, :16].sum(axis=(0, 1)).argmax() == 0 and lit[:16, 16:32].sum(axis=(0, 1)).argmax() == 1


def test_spot_obj_map_kd_matches_the_uvs(tmp_path, no_warnings):
    import shutil

    shutil.copy(SPOT_TEXTURE, tmp_path / "spot_texture.png")
    (tmp_path / "spot.mtl").write_text("newmtl cow\nmap_Kd spot_texture.png\n")
    (tmp_path / "spot.obj").write_text("mtllib spot.mtl\nusemtl cow\n" + SPOT.read_text())
    scene = sr.load_scene(tmp_path / "spot.obj")
    texture = scene.instances[0].material.base_color_texture
    assert texture.image.shape == (1024, 1024, 3)
    width, height = 160, 120
    camera = sr.PerspectiveCamera(fov_y=45.0, near=0.05, far=100.0)
    camera.look_at(eye=(1.7, 0.9, -2.3), target=(0.0, 0.05, 0.15), up=(0, 1, 0))
    frame = sr.Renderer(width, height).render(scene, camera, outputs=("color", "triangle_id"), shading="unlit",
                                              texture_filter="nearest")
    rows, cols = np.nonzero(frame.triangle_id >= 0)
    pick = np.arange(0, len(rows), 5)
    pixels = list(zip(rows[pick], cols[pick]))
    uvs = pixel_uvs(scene, camera, width, height, frame.triangle_id, pixels)
    good = bad = 0
    for (row, col), uv in zip(pixels, uvs):
        expected = texel_at(texture.image, uv) if np.isfinite(uv[0]) else None
        if expected is not None:
            ok = np.abs(frame.color[row, col].astype(int) - expected.astype(int)).max() <= 2
            good += ok
            bad += not ok
    assert good > 500 and bad <= good // 100  # float rounding at a rare texel boundary


def test_obj_norm_map_ke_and_bump(tmp_path):
    normal = np.zeros((4, 4, 3), np.uint8)
    normal[:] = (120, 135, 250)
    sr.imwrite(tmp_path / "n.png", normal)
    sr.imwrite(tmp_path / "glow.png", IMAGE)
    sr.imwrite(tmp_path / "height.png", np.full((4, 4), 90, np.uint8))
    sr.imwrite(tmp_path / "tex.png", IMAGE)
    mtl = ("newmtl tex\nKd 1 1 1\nmap_Kd -clamp on tex.png\nmap_Ke glow.png\nnorm -bm 0.75 n.png\n"
           "newmtl blender\nmap_Kd tex.png\nmap_Bump -bm 1.000000 n.png\n"
           "newmtl height\nmap_Kd tex.png\nKe 0.5 0.5 0.5\nmap_Ke glow.png\nbump -bm 0.2 height.png\n")
    path = _quad(tmp_path, mtl)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = sr.load_mesh(path).material
    assert m.normal_texture is not None and m.normal_scale == 0.75 and m.normal_map_convention == "opengl"
    np.testing.assert_array_equal(m.normal_texture.image, normal)
    assert m.normal_texture.srgb is None  # the normal slot reads it linear
    assert m.base_color_texture.wrap == ("clamp", "clamp")
    assert m.emissive_texture is not None and m.emissive == (1.0, 1.0, 1.0)  # no Ke: white x map_Ke
    np.testing.assert_array_equal(m.emissive_texture.image, IMAGE)

    # Blender writes normal maps as map_Bump: drawn as one, with a warning saying so
    path = _quad(tmp_path, mtl, material="blender")
    with pytest.warns(UserWarning, match=r"quad\.obj: material 'blender': map_Bump 'n\.png' looks like a "
                                         r"tangent-space normal map"):
        m = sr.load_mesh(path).material
    assert m.normal_texture is not None and m.normal_scale == 1.0

    # a height map is a bump map: -bm is its bump_scale
    path = _quad(tmp_path, mtl, material="height")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = sr.load_mesh(path).material
    assert m.normal_texture is None and m.emissive == (0.5, 0.5, 0.5) and m.emissive_texture is not None
    assert m.bump_texture is not None and m.bump_scale == 0.2 and m.bump_texture.srgb is None
    # one Texture per file within a load: glow.png and tex.png hold the same texels but are two files
    assert m.base_color_texture is not m.emissive_texture


HEIGHT = np.random.default_rng(4).integers(0, 256, (16, 16), dtype=np.uint8)


def _lit_quad_radiance(mesh):
    """The quad filling a 64 x 64 image, lambert, lit by a slanted directional light."""
    scene = sr.Scene(ambient_light=(0.1, 0.1, 0.1))
    scene.add(mesh)
    light = trimesh.transformations.rotation_matrix(0.6, [1.0, 0.5, 0.0])  # its -z: the direction
    scene.add(sr.DirectionalLight(intensity=1.0), pose=light)
    camera = sr.OrthographicCamera(xmag=1.0, ymag=1.0, near=0.1, far=10.0)
    camera.look_at(eye=(0, 0, 3), target=(0, 0, 0), up=(0, 1, 0))
    return sr.Renderer(64, 64).render(scene, camera, outputs=("radiance",), shading="lambert").radiance


def test_obj_bump_height_map_is_drawn_with_its_bm(tmp_path, no_warnings):
    sr.imwrite(tmp_path / "h.png", HEIGHT)
    plain = sr.load_mesh(_quad(tmp_path, "newmtl tex\nKd 0.8 0.7 0.6\n"))
    path = _quad(tmp_path, "newmtl tex\nKd 0.8 0.7 0.6\nbump -bm 2.5 h.png\n")
    mesh = sr.load_mesh(path)
    m = mesh.material
    assert m.bump_scale == 2.5 and m.bump_texture.name == "h.png" and m.bump_texture.srgb is None
    np.testing.assert_array_equal(m.bump_texture.image.reshape(16, 16), HEIGHT)
    assert m.bump_texture.uv_origin == "bottom_left" and m.bump_texture.wrap == ("repeat", "repeat")
    assert m.normal_texture is None
    # the MTL's material otherwise, as without the bump statement
    assert m == plain.material.replace(bump_texture=m.bump_texture, bump_scale=2.5)
    bumped, flat = _lit_quad_radiance(mesh), _lit_quad_radiance(plain)
    assert np.abs(bumped - flat).max() > 0.1
    # the same as the hand-built material, and -bm scales the bump
    by_hand = sr.Mesh(plain.positions, plain.faces, normals=plain.normals, uvs=plain.uvs,
                      material=plain.material.replace(bump_texture=sr.Texture(HEIGHT), bump_scale=2.5))
    np.testing.assert_array_equal(bumped, _lit_quad_radiance(by_hand))
    one = sr.load_mesh(_quad(tmp_path, "newmtl tex\nKd 0.8 0.7 0.6\nmap_Bump h.png\n"))
    assert one.material.bump_scale == 1.0 and one.material.bump_texture is not None
    assert np.abs(_lit_quad_radiance(one) - bumped).max() > 0.01


def test_obj_norm_and_bump_keeps_both_and_notes_the_bump_is_not_drawn(tmp_path):
    sr.imwrite(tmp_path / "h.png", HEIGHT)
    sr.imwrite(tmp_path / "n.png", np.full((4, 4, 3), (120, 135, 250), np.uint8))
    path = _quad(tmp_path, "newmtl tex\nbump -bm 3 h.png\nnorm -bm 0.5 n.png\n")
    with pytest.warns(UserWarning) as record:
        m = sr.load_mesh(path).material
    (text,) = [str(w.message) for w in record]
    assert text == (f"{path}: material 'tex': bump 'h.png' (a height map) is kept as bump_texture but not "
                    "drawn: the norm map is drawn in its place")
    assert m.normal_texture is not None and m.normal_scale == 0.5
    assert m.bump_texture is not None and m.bump_scale == 3.0


def test_obj_bump_normal_maps_colour_heights_and_second_bumps(tmp_path):
    normal = np.full((4, 4, 3), (120, 135, 250), np.uint8)
    sr.imwrite(tmp_path / "n.png", normal)
    sr.imwrite(tmp_path / "n2.png", normal)  # the same texels, another file
    sr.imwrite(tmp_path / "h.png", HEIGHT)
    colour = np.random.default_rng(6).integers(0, 256, (8, 8, 3), dtype=np.uint8)
    sr.imwrite(tmp_path / "c.png", colour)
    sr.imwrite(tmp_path / "grey.png", np.repeat(HEIGHT[:, :, None], 3, axis=2))

    # a normal map in map_Bump next to a norm map: the norm map is drawn, the other ignored
    path = _quad(tmp_path, "newmtl tex\nmap_Bump -bm 2 n.png\nnorm n2.png\n")
    with pytest.warns(UserWarning, match=r"material 'tex': map_Bump 'n\.png' looks like a tangent-space "
                                         r"normal map, and the material's norm map is drawn: ignored"):
        m = sr.load_mesh(path).material
    assert m.normal_texture.name == "n2.png" and m.normal_scale == 1.0 and m.bump_texture is None

    # ... and without a norm map (or with one that cannot be found) drawn as the normal map
    path = _quad(tmp_path, "newmtl tex\nnorm missing.png\nbump -bm 2 n.png\n")
    with pytest.warns(UserWarning) as record:
        m = sr.load_mesh(path).material
    (text,) = [str(w.message) for w in record]
    assert "norm 'missing.png' not found next to the MTL file: not drawn" in text
    assert "bump 'n.png' looks like a tangent-space normal map (RGB, mean colour near (0.5, 0.5, 1)): drawn " \
           "as one" in text
    assert m.normal_texture.name == "n.png" and m.normal_scale == 2.0 and m.bump_texture is None

    # a colour height map: its red channel is the height, said unless -imfchan r says so
    path = _quad(tmp_path, "newmtl tex\nbump c.png\n")
    with pytest.warns(UserWarning, match=r"material 'tex': bump 'c\.png' is a colour image: its red channel "
                                         r"is read as the height"):
        m = sr.load_mesh(path).material
    np.testing.assert_array_equal(m.bump_texture.image, colour)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = sr.load_mesh(_quad(tmp_path, "newmtl tex\nbump -imfchan r c.png\n")).material
        assert m.bump_texture is not None
        m = sr.load_mesh(_quad(tmp_path, "newmtl tex\nbump grey.png\n")).material  # R = G = B
        assert m.bump_texture is not None
    path = _quad(tmp_path, "newmtl tex\nbump -imfchan g c.png\n")
    with pytest.warns(UserWarning) as record:
        sr.load_mesh(path)
    (text,) = [str(w.message) for w in record]
    assert "bump 'c.png': option(s) -imfchan g ignored" in text and "red channel is read" in text

    # a second bump statement is ignored; a first that cannot be found does not count
    path = _quad(tmp_path, "newmtl tex\nbump nowhere.png\nmap_Bump -bm 0.5 h.png\nbump grey.png\n")
    with pytest.warns(UserWarning) as record:
        m = sr.load_mesh(path).material
    (text,) = [str(w.message) for w in record]
    assert "bump 'nowhere.png' not found next to the MTL file: not drawn" in text
    assert "bump 'grey.png': a second bump map is ignored" in text
    assert m.bump_texture.name == "h.png" and m.bump_scale == 0.5

    # a bad -bm: the default scale, with a warning
    path = _quad(tmp_path, "newmtl tex\nbump -bm x h.png\n")
    with pytest.warns(UserWarning, match=r"bump 'h\.png': -bm 'x' is not a number; ignored"):
        m = sr.load_mesh(path).material
    assert m.bump_texture is not None and m.bump_scale == 1.0


def test_obj_bump_without_uvs_is_dropped(tmp_path):
    sr.imwrite(tmp_path / "h.png", HEIGHT)
    (tmp_path / "quad.obj").write_text("mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl tex\nf 1 2 3\n")
    (tmp_path / "quad.mtl").write_text("newmtl tex\nKd 0.5 0.5 0.5\nbump -bm 2 h.png\n")
    with pytest.warns(UserWarning, match=r"quad\.obj: material 'tex': the mesh has no uvs, so its "
                                         r"bump_texture cannot be drawn"):
        m = sr.load_mesh(tmp_path / "quad.obj").material
    assert not m.textured and m.kd == (0.5, 0.5, 0.5)


def test_obj_maps_not_drawn_or_missing_warn_naming_file_and_material(tmp_path):
    sr.imwrite(tmp_path / "tex.png", IMAGE)
    mtl = ("newmtl tex\nmap_Kd -s 2 2 1 tex.png\nmap_Ns spec.png\nmap_d alpha.png\nmap_Ke nowhere.png\n")
    path = _quad(tmp_path, mtl)
    with pytest.warns(UserWarning) as record:
        m = sr.load_mesh(path).material
    (text,) = [str(w.message) for w in record]
    assert text.startswith(f"{path}: material 'tex': ")
    for part in ("map_Ns 'spec.png' is not drawn yet", "map_d 'alpha.png' is not drawn yet",
                 "map_Ke 'nowhere.png' not found next to the MTL file: not drawn",
                 "map_Kd 'tex.png': option(s) -s 2 2 1 ignored"):
        assert part in text
    assert m.base_color_texture is not None and m.emissive_texture is None and m.emissive == (0.0, 0.0, 0.0)


def test_obj_map_ks_is_the_specular_texture_multiplying_ks(tmp_path, no_warnings):
    sr.imwrite(tmp_path / "spec.png", IMAGE)
    m = sr.load_mesh(_quad(tmp_path, "newmtl tex\nKs 0.5 0.25 1\nNs 20\nmap_Ks spec.png\n")).material
    assert m.specular_texture is not None and m.specular_texture.name == "spec.png"
    assert m.ks == (0.5, 0.25, 1.0)
    # read linear (a data slot): the texture leaves it to the slot, which reads linear
    assert np.array_equal(m.specular_texture.image, IMAGE) and m.specular_texture.srgb is None
    white = sr.load_mesh(_quad(tmp_path, "newmtl tex\nmap_Ks spec.png\n")).material
    assert white.ks == (1.0, 1.0, 1.0)  # without Ks the map multiplies white, as map_Ke


def test_obj_textures_shared_between_materials_and_relative_to_the_mtl(tmp_path, no_warnings):
    (tmp_path / "maps").mkdir()
    sr.imwrite(tmp_path / "maps" / "tex.png", IMAGE)
    obj = QUAD_OBJ.format(material="a").replace("f 1/1/1 3/3/1 4/4/1", "usemtl b\nf 1/1/1 3/3/1 4/4/1")
    (tmp_path / "quad.obj").write_text(obj)
    (tmp_path / "quad.mtl").write_text("newmtl a\nmap_Kd maps/tex.png\nnewmtl b\nKd 0.5 0.5 0.5\n"
                                       "map_Kd maps\\tex.png\n")
    scene = sr.load_scene(tmp_path / "quad.obj")
    by_name = {inst.material.name: inst.material for inst in scene}
    assert by_name["a"].base_color_texture is by_name["b"].base_color_texture
    assert by_name["b"].base_color == (0.5, 0.5, 0.5, 1.0) and by_name["b"].kd is None


def test_textured_material_without_uvs_drops_its_textures_with_a_warning(tmp_path):
    sr.imwrite(tmp_path / "tex.png", IMAGE)
    (tmp_path / "quad.obj").write_text("mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl tex\nf 1 2 3\n")
    (tmp_path / "quad.mtl").write_text("newmtl tex\nKd 0.5 0.5 0.5\nmap_Kd tex.png\n")
    with pytest.warns(UserWarning, match=r"quad\.obj: material 'tex': the mesh has no uvs, so its "
                                         r"base_color_texture cannot be drawn"):
        m = sr.load_mesh(tmp_path / "quad.obj").material
    assert not m.textured and m.kd == (0.5, 0.5, 0.5)  # the MTL's material as without map_Kd


# -- Mesh.from_trimesh --------------------------------------------------------------------------
def test_from_trimesh_simple_material_image(no_warnings):
    from PIL import Image

    quad = trimesh.Trimesh([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [[0, 1, 2], [0, 2, 3]], process=False)
    uv = [[0, 0], [1, 0], [1, 1], [0, 1]]
    material = trimesh.visual.material.SimpleMaterial(image=Image.fromarray(IMAGE), diffuse=[255, 255, 255, 255])
    quad.visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    mesh = sr.Mesh.from_trimesh(quad)
    m = mesh.material
    assert m.kd is None and m.base_color_texture is not None
    np.testing.assert_array_equal(_render_quad(mesh), np.repeat(np.repeat(IMAGE, 16, axis=0), 16, axis=1))
    # the image multiplies the diffuse colour, as trimesh's own SimpleMaterial.to_pbr() says
    # (baseColorFactor = diffuse): trimesh's default diffuse is 102 / 255 grey
    quad.visual = trimesh.visual.TextureVisuals(uv=uv, image=Image.fromarray(IMAGE))
    mesh = sr.Mesh.from_trimesh(quad)
    assert mesh.material.base_color == (0.4, 0.4, 0.4, 1.0)
    color = _render_quad(mesh).astype(int)
    assert np.abs(color[8::16, 8::16] - encode(decode(IMAGE) * 0.4)).max() <= 1
