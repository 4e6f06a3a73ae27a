"""What mesh files carry besides geometry: colours, colour spaces, OBJ/MTL and glTF
materials, parts and node transforms, and a warning for everything dropped."""
from __future__ import annotations

import json
import os
import shutil
import struct
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh

import softrast as sr
from softrast.files.context import srgb_to_linear
from softrast.reference import encoding

ROOT = Path(__file__).resolve().parents[1]
ASSETS = ROOT / "assets" / "meshes"
BOX_TEXTURED = ASSETS / "BoxTextured.gltf"
SPOT = ASSETS / "spot.obj"
SPOT_TEXTURE = ASSETS / "spot_texture.png"


def decode(byte):
    """The exact IEC 61966-2-1 curve, from the NumPy reference (independent of softrast.files)."""
    return float(encoding.srgb_to_linear(byte / 255.0))


def encode(c):
    return float(encoding.srgb_curve(c))


@pytest.fixture
def no_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        yield


# -- colour spaces ---------------------------------------------------------------------------------
def test_srgb_decoding_is_exact_and_round_trips_every_byte():
    got = srgb_to_linear(np.arange(256) / 255.0)
    # NumPy's and Python's pow may differ in the last bit of a float64; never in a stored float32.
    np.testing.assert_allclose(got, [decode(b) for b in range(256)], rtol=1e-15, atol=0)
    np.testing.assert_array_equal(got.astype(np.float32), np.float32([decode(b) for b in range(256)]))
    # Stored as float32 in a Mesh, encoding back to sRGB and rounding gives the byte again.
    stored = got.astype(np.float32).astype(np.float64)
    assert [round(255 * encode(c)) for c in stored] == list(range(256))


# -- PLY: per-face and per-vertex colours -----------------------------------------------------------
QUAD_PLY = """ply
format ascii 1.0
element vertex 4
property float x
property float y
property float z
element face 2
property list uchar int vertex_indices
property uchar red
property uchar green
property uchar blue
end_header
-1 -1 0
1 -1 0
1 1 0
-1 1 0
3 0 1 2 200 10 0
3 0 2 3 30 128 255
"""


def test_ply_face_colors_give_each_face_its_own_vertices(tmp_path, no_warnings):
    path = tmp_path / "quad.ply"
    path.write_text(QUAD_PLY)
    mesh = sr.load_mesh(path)
    assert mesh.num_faces == 2 and mesh.num_vertices == 6
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [3, 4, 5]])
    corners = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, -1, 0], [1, 1, 0], [-1, 1, 0]])
    np.testing.assert_array_equal(mesh.positions, corners)  # face order kept: triangle_id = file face
    expected = [[decode(200), decode(10), decode(0), 1.0]] * 3 + [[decode(30), decode(128), decode(255), 1.0]] * 3
    np.testing.assert_array_equal(mesh.colors, np.float32(expected))
    # smooth normals: the original vertex's
    tm = trimesh.load(path, process=False)
    np.testing.assert_array_equal(mesh.normals, np.float32(tm.vertex_normals[[0, 1, 2, 0, 2, 3]]))
    assert sr.load_mesh(path, smooth=False).normals is None
    assert mesh.material is None


def test_ply_face_colors_reach_the_image(tmp_path, no_warnings):
    path = tmp_path / "quad.ply"
    path.write_text(QUAD_PLY)
    scene = sr.Scene()
    scene.add(sr.load_mesh(path))
    cam = sr.OrthographicCamera(xmag=1.0, ymag=1.0)
    cam.pose = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 5], [0, 0, 0, 1]], dtype=float)
    frame = sr.Renderer(32, 32).render(scene, cam, outputs=("color", "triangle_id"), shading="unlit")
    # face 0 covers the lower right (x > y), face 1 the upper left; image row 0 is the top
    lower_right, upper_left = frame.color[28, 28], frame.color[3, 3]
    assert frame.triangle_id[28, 28] == 0 and frame.triangle_id[3, 3] == 1
    # Decoded to linear at load, sRGB-encoded on output: the file's bytes come back exactly.
    for pixel, rgb in ((lower_right, (200, 10, 0)), (upper_left, (30, 128, 255))):
        np.testing.assert_array_equal(pixel[:3], rgb)
    linear = sr.Renderer(32, 32).render(scene, cam, outputs=("color",), shading="unlit", srgb=False)
    for pixel, rgb in ((linear.color[28, 28], (200, 10, 0)), (linear.color[3, 3], (30, 128, 255))):
        np.testing.assert_allclose(pixel[:3], [round(255 * decode(b)) for b in rgb], atol=1)


def test_ply_vertex_colors_are_decoded_from_srgb(tmp_path, no_warnings):
    path = tmp_path / "tri.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
                    "property uchar alpha\nelement face 1\nproperty list uchar int vertex_indices\n"
                    "end_header\n0 0 0 255 0 10 128\n1 0 0 0 64 0 255\n0 1 0 11 12 13 0\n3 0 1 2\n")
    mesh = sr.load_mesh(path)
    assert mesh.num_vertices == 3
    expected = [[decode(255), decode(0), decode(10), 128 / 255], [decode(0), decode(64), decode(0), 1.0],
                [decode(11), decode(12), decode(13), 0.0]]
    np.testing.assert_array_equal(mesh.colors, np.float32(expected))


# -- OBJ + MTL -----------------------------------------------------------------------------------
OBJ_TWO = """mtllib two.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 2 0 0
v 2 1 0
usemtl red_plastic
f 1 2 3
f 1 3 4
usemtl blue_glass
f 2 5 6
"""
MTL_TWO = """# two materials
newmtl red_plastic
Ka 0.1 0.05 0.025
Kd 0.7 0.2 0.1
Ks 0.3 0.35 0.4
Ns 96.078431
d 1.0
illum 2

newmtl blue_glass
Kd 0.15 0.25 0.9
Ks 1 1 1
Ns 250
d 0.375
"""
def mtl_roughness(ns):  # the MTL rule (softrast.loaders): trimesh's and pyrender's mapping
    return (2.0 / (ns + 2.0)) ** 0.25


RED = sr.Material(base_color=(0.7, 0.2, 0.1, 1.0), ka=(0.1, 0.05, 0.025), kd=(0.7, 0.2, 0.1),
                  ks=(0.3, 0.35, 0.4), shininess=96.078431, metallic=0.0,
                  roughness=mtl_roughness(96.078431), model="pbr", name="red_plastic")
# d 0.375 < 1: blended, with base colour alpha d
BLUE = sr.Material(base_color=(0.15, 0.25, 0.9, 0.375), kd=(0.15, 0.25, 0.9), ks=(1.0, 1.0, 1.0),
                   shininess=250.0, metallic=0.0, roughness=mtl_roughness(250.0), model="pbr",
                   name="blue_glass", alpha_mode="blend")


def _write_obj(tmp_path, obj=OBJ_TWO, mtl=MTL_TWO):
    (tmp_path / "two.mtl").write_text(mtl)
    path = tmp_path / "two.obj"
    path.write_text(obj)
    return path


def test_obj_mtl_materials_are_exact_in_load_scene(tmp_path, no_warnings):
    path = _write_obj(tmp_path)
    scene = sr.load_scene(path)  # d 0.375 is drawn (blended): nothing to warn about
    assert len(scene) == 2
    by_name = {inst.material.name: inst for inst in scene}
    assert by_name["red_plastic"].material == RED  # exact: not trimesh's 8-bit copies
    assert by_name["blue_glass"].material == BLUE
    assert by_name["red_plastic"].mesh.num_faces == 2 and by_name["blue_glass"].mesh.num_faces == 1
    assert by_name["red_plastic"].mesh.material == RED
    for inst in scene:
        np.testing.assert_array_equal(inst.pose, np.eye(4))
        assert inst.color == inst.material.base_color


def test_obj_parts_with_different_materials_are_merged_with_a_warning(tmp_path):
    path = _write_obj(tmp_path)
    with pytest.warns(UserWarning) as record:
        mesh = sr.load_mesh(path)
    texts = [str(w.message) for w in record]
    assert any("two.obj: 2 parts with 2 different materials were merged into one mesh with the first "
               "part's material; use softrast.load_scene to keep each part's material" in t for t in texts)
    assert mesh.num_faces == 3 and mesh.material in (RED, BLUE)


def test_obj_with_one_material_keeps_it(tmp_path, no_warnings):
    obj = "mtllib two.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nusemtl red_plastic\nf 1 2 3\nf 2 4 3\n"
    mesh = sr.load_mesh(_write_obj(tmp_path, obj=obj))
    assert mesh.material == RED and mesh.color == RED.base_color
    assert mesh.num_faces == 2 and mesh.num_vertices == 4
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [1, 3, 2]])  # order kept
    # color= replaces the material's base colour
    assert sr.load_mesh(tmp_path / "two.obj", color=(0, 1, 0)).material == RED.replace(base_color=(0, 1, 0, 1))


def test_obj_without_mtllib_has_no_material_and_no_warning(no_warnings):
    mesh = sr.load_mesh(SPOT)
    assert mesh.material is None and mesh.uvs is not None


def test_obj_mtl_texture_is_drawn_multiplying_kd(tmp_path, no_warnings):
    # spot.obj with an MTL that maps its texture: the texture multiplies Kd (kd is the base colour;
    # tests/test_file_textures.py checks the pixels).
    shutil.copy(SPOT_TEXTURE, tmp_path / "spot_texture.png")
    (tmp_path / "spot.mtl").write_text("newmtl cow\nKd 0.9 0.5 0.25\nmap_Kd spot_texture.png\n")
    text = SPOT.read_text()
    (tmp_path / "spot.obj").write_text("mtllib spot.mtl\nusemtl cow\n" + text)
    mesh = sr.load_mesh(tmp_path / "spot.obj")
    texture = mesh.material.base_color_texture
    assert texture is not None and texture.image.shape == (1024, 1024, 3) and texture.name == "spot_texture.png"
    assert mesh.material == sr.Material(base_color=(0.9, 0.5, 0.25, 1.0), kd=None, ks=None, metallic=0.0,
                                        roughness=1.0, model="pbr", name="cow", base_color_texture=texture)
    plain = sr.load_mesh(SPOT)
    assert mesh.num_faces == plain.num_faces and mesh.num_vertices == plain.num_vertices
    np.testing.assert_array_equal(mesh.faces, plain.faces)


def test_obj_missing_mtllib_and_bad_mtl_lines_warn(tmp_path):
    path = tmp_path / "lost.obj"
    path.write_text("mtllib nowhere.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n")
    with pytest.warns(UserWarning, match=r"lost\.obj: mtllib 'nowhere.mtl' not found"):
        mesh = sr.load_mesh(path)
    assert mesh.material is None and mesh.num_faces == 1
    obj = "mtllib two.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n"
    _write_obj(tmp_path, obj=obj, mtl="newmtl m\nKd red green blue\nKs 2 0.5 0.5\nNs 10\n")
    with pytest.warns(UserWarning) as record:
        mesh = sr.load_mesh(tmp_path / "two.obj")
    texts = " | ".join(str(w.message) for w in record)
    assert "Kd 'red green blue' is not a colour" in texts and "Ks [2.0, 0.5, 0.5] clipped" in texts
    assert mesh.material == sr.Material(ks=(1.0, 0.5, 0.5), shininess=10.0, metallic=0.0,
                                        roughness=mtl_roughness(10.0), model="pbr", name="m")


def test_mtl_roughness_rule_and_negative_ns(tmp_path):
    # MTL -> pbr, metallic 0, roughness (2 / (Ns + 2)) ** 0.25, 1 without Ks; a negative
    # Ns is read as 0 with a warning naming the file and the material
    obj = "mtllib two.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n"
    expected = {"Ks 1 1 1\nNs 0": (1.0, 0.0), "Ks 0.2 0.2 0.2\nNs 10": (mtl_roughness(10.0), 10.0),
                "Ks 1 1 1\nNs 200": (mtl_roughness(200.0), 200.0), "Ks 1 1 1": (mtl_roughness(32.0), 32.0),
                "Ks 0 0 0\nNs 200": (1.0, 200.0), "Ns 200": (1.0, 200.0)}
    for lines, (roughness, ns) in expected.items():
        _write_obj(tmp_path, obj=obj, mtl=f"newmtl m\nKd 0.5 0.5 0.5\n{lines}\n")
        m = sr.load_mesh(tmp_path / "two.obj").material
        assert (m.model, m.metallic, m.shininess) == ("pbr", 0.0, ns), lines
        assert m.roughness == pytest.approx(roughness, rel=1e-15), lines
    assert mtl_roughness(10.0) == pytest.approx(0.6389, abs=1e-4)
    _write_obj(tmp_path, obj=obj, mtl="newmtl m\nKs 1 1 1\nNs -5\n")
    with pytest.warns(UserWarning, match=r"two\.obj: material 'm': Ns -5 is negative: read as 0"):
        m = sr.load_mesh(tmp_path / "two.obj").material
    assert (m.shininess, m.roughness) == (0.0, 1.0)



def test_mtl_ns_beyond_float32_is_clipped(tmp_path):
    """Material refuses a shininess beyond float32's range; an MTL file's Ns 1e39
    is clipped to the largest float32 (as a negative Ns is clipped to 0), not a dropped material."""
    obj = "mtllib two.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n"
    _write_obj(tmp_path, obj=obj, mtl="newmtl m\nKd 0.5 0.5 0.5\nNs 1e39\n")
    mesh = sr.load_mesh(tmp_path / "two.obj")
    assert mesh.material is not None and mesh.material.shininess == float(np.finfo(np.float32).max)


# -- glTF ---------------------------------------------------------------------------------------
def _glb_parts(data: bytes):
    _, _, _, n, _ = struct.unpack("<4sIII4s", data[:20])
    return json.loads(data[20:20 + n]), data[20 + n:]


def _glb(doc, rest: bytes) -> bytes:
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    return struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text) + len(rest)) + \
        struct.pack("<I4s", len(text), b"JSON") + text + rest


def _two_material_glb(tmp_path, edit=None):
    """A GLB with a box and a sphere, each with its own material, under two nodes."""
    box = trimesh.creation.box()
    box.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(
        name="paint", baseColorFactor=[0.3, 0.6, 0.9, 1.0], metallicFactor=0.25, roughnessFactor=0.75,
        emissiveFactor=[0.1, 0.0, 0.0], doubleSided=True))
    ball = trimesh.creation.icosphere(subdivisions=1)
    ball.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(
        name="chrome", baseColorFactor=[1.0, 1.0, 1.0, 1.0], metallicFactor=1.0, roughnessFactor=0.125))
    tscene = trimesh.Scene()
    move = trimesh.transformations.translation_matrix([1.0, 2.0, 3.0])
    turn = trimesh.transformations.rotation_matrix(np.pi / 2, [0, 0, 1]) @ np.diag([2.0, 2.0, 2.0, 1.0])
    tscene.add_geometry(box, node_name="box_node", geom_name="box", transform=move)
    tscene.add_geometry(ball, node_name="ball_node", geom_name="ball", transform=turn)
    doc, rest = _glb_parts(tscene.export(file_type="glb"))
    # trimesh writes metallic / roughness / emissive as given, but the base colour only as 8 bits
    # (0.3 -> 76 / 255): write exact factors, which the loader must read from the file itself.
    paint = next(m for m in doc["materials"] if m["name"] == "paint")
    assert paint["pbrMetallicRoughness"]["metallicFactor"] == 0.25
    assert paint["pbrMetallicRoughness"]["roughnessFactor"] == 0.75
    assert paint["emissiveFactor"] == [0.1, 0.0, 0.0] and paint["doubleSided"] is True
    assert paint["pbrMetallicRoughness"]["baseColorFactor"] != [0.3, 0.6, 0.9, 1.0]
    paint["pbrMetallicRoughness"]["baseColorFactor"] = [0.3, 0.6, 0.9, 0.5]
    chrome = next(m for m in doc["materials"] if m["name"] == "chrome")
    chrome["pbrMetallicRoughness"] = {"roughnessFactor": 0.125}  # glTF defaults: base 1, metallic 1
    if edit:
        edit(doc)
    path = tmp_path / "two.glb"
    path.write_bytes(_glb(doc, rest))
    return path, move, turn


PAINT = sr.Material(base_color=(0.3, 0.6, 0.9, 0.5), metallic=0.25, roughness=0.75, emissive=(0.1, 0.0, 0.0),
                    double_sided=True, model="pbr", name="paint")
CHROME = sr.Material(base_color=(1.0, 1.0, 1.0, 1.0), metallic=1.0, roughness=0.125, model="pbr",
                     name="chrome")


def test_glb_load_scene_keeps_materials_exactly_and_node_transforms(tmp_path, no_warnings):
    path, move, turn = _two_material_glb(tmp_path)
    scene = sr.load_scene(path)
    assert len(scene) == 2
    by_name = {inst.material.name: inst for inst in scene}
    assert by_name["paint"].material == PAINT
    assert by_name["chrome"].material == CHROME
    np.testing.assert_allclose(by_name["paint"].pose, move, atol=1e-12)
    np.testing.assert_allclose(by_name["chrome"].pose, turn, atol=1e-12)
    assert by_name["paint"].mesh.num_faces == 12 and by_name["chrome"].mesh.num_faces == 80
    # the meshes are in object space: the pose places them
    np.testing.assert_allclose(by_name["paint"].mesh.bounds, [[-0.5] * 3, [0.5] * 3])
    assert sorted(inst.instance_id for inst in scene) == [0, 1]


def test_glb_materials_with_equal_names_and_factors_are_told_apart(tmp_path, no_warnings):
    # Two materials called "paint" with the same base colour (to 8 bits), metallic, roughness and
    # doubleSided: trimesh keeps no index, so only the primitive's own "material" index tells
    # which is which. The second differs in what trimesh does not compare (its exact base colour,
    # its emissive factor, its alpha mode).
    def edit(doc):
        chrome = next(i for i, m in enumerate(doc["materials"]) if m["name"] == "chrome")
        twin = json.loads(json.dumps(next(m for m in doc["materials"] if m["name"] == "paint")))
        twin["pbrMetallicRoughness"]["baseColorFactor"] = [0.3, 0.6001, 0.9, 0.5]
        twin["emissiveFactor"] = [0.0, 0.0, 0.5]
        twin["alphaMode"] = "MASK"
        doc["materials"][chrome] = twin

    path, move, turn = _two_material_glb(tmp_path, edit)
    twin = PAINT.replace(base_color=(0.3, 0.6001, 0.9, 0.5), emissive=(0.0, 0.0, 0.5), alpha_mode="mask")
    for _ in range(2):  # the file's material order must not matter either
        scene = sr.load_scene(path)
        by_faces = {inst.mesh.num_faces: inst.material for inst in scene}
        assert by_faces == {12: PAINT, 80: twin}
        doc, rest = _glb_parts(path.read_bytes())
        doc["materials"].reverse()
        for m in doc["meshes"]:
            for p in m["primitives"]:
                p["material"] = len(doc["materials"]) - 1 - p["material"]
        path.write_bytes(_glb(doc, rest))


def test_gltf_files_are_read_once(tmp_path, monkeypatch, no_warnings):
    import builtins

    path, _, _ = _two_material_glb(tmp_path)
    gltf = tmp_path / "box.gltf"
    gltf.write_bytes(BOX_TEXTURED.read_bytes())
    opened = []
    real_open = builtins.open

    def counting_open(file, *args, **kwargs):
        opened.append(os.path.abspath(os.fspath(file)) if isinstance(file, (str, os.PathLike)) else file)
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", counting_open)
    for f in (path, gltf):
        opened.clear()
        sr.load_scene(f)
        assert opened.count(os.path.abspath(f)) == 1


def test_glb_load_mesh_merges_with_a_warning(tmp_path):
    path, move, turn = _two_material_glb(tmp_path)
    with pytest.warns(UserWarning, match="2 parts with 2 different materials were merged into one mesh"):
        mesh = sr.load_mesh(path)
    assert mesh.num_faces == 92 and mesh.material in (PAINT, CHROME)
    lo, hi = mesh.bounds  # merged in world space: the box moved to (1, 2, 3), the sphere scaled by 2
    assert hi[2] == pytest.approx(3.5) and lo[0] == pytest.approx(-2.0, abs=1e-6)


def test_glb_alpha_mode_textures_and_extensions_warn(tmp_path):
    def edit(doc):
        paint = next(m for m in doc["materials"] if m["name"] == "paint")
        paint["alphaMode"] = "BLEND"
        paint["occlusionTexture"] = {"index": 0}
        chrome = next(m for m in doc["materials"] if m["name"] == "chrome")
        chrome["extensions"] = {"KHR_materials_unlit": {}, "KHR_materials_sheen": {}}

    path, _, _ = _two_material_glb(tmp_path, edit)
    with pytest.warns(UserWarning) as record:
        scene = sr.load_scene(path)
    texts = sorted(str(w.message) for w in record)
    assert len(texts) == 2
    assert texts[0].startswith(f"{path}: material 'chrome': extension KHR_materials_sheen is ignored")
    # the file has no textures: the occlusionTexture names one it does not have
    assert texts[1].startswith(f"{path}: material 'paint': occlusionTexture refers to texture 0, which the "
                               "file does not have: not drawn")
    assert "alphaMode" not in texts[1]  # BLEND is drawn
    by_name = {inst.material.name: inst.material for inst in scene}
    assert by_name["chrome"] == CHROME.replace(model="unlit")
    assert by_name["paint"] == PAINT.replace(alpha_mode="blend")


def test_glb_blend_loads_as_blend_without_a_warning(tmp_path, no_warnings):
    """glTF alphaMode BLEND -> alpha_mode "blend" (its baseColorFactor alpha kept, alphaCutoff
    ignored as glTF says), OPAQUE -> opaque; nothing warns."""
    def edit(doc):
        paint = next(m for m in doc["materials"] if m["name"] == "paint")
        paint["alphaMode"], paint["alphaCutoff"] = "BLEND", 0.9
        chrome = next(m for m in doc["materials"] if m["name"] == "chrome")
        chrome["alphaMode"] = "OPAQUE"

    path, _, _ = _two_material_glb(tmp_path, edit)
    by_name = {inst.material.name: inst.material for inst in sr.load_scene(path)}
    assert by_name["paint"].alpha_mode == "blend" and by_name["paint"].base_color[3] == 0.5
    assert by_name["paint"] == PAINT.replace(alpha_mode="blend")
    assert by_name["chrome"] == CHROME and by_name["chrome"].alpha_mode == "opaque"


MTL_ALPHA = """newmtl half
Kd 1 0 0
d 0.5
newmtl tr
Kd 0 1 0
Tr 0.25
newmtl solid
Kd 0 0 1
d 1.0
newmtl agree
Kd 1 1 0
d 0.5
Tr 0.5
newmtl tr_zero
Kd 0 1 1
Tr 0
newmtl dissolved
Kd 1 0 1
d -0.5
newmtl meshlab
Kd 0.5 0.5 0.5
Tr 1.000000
"""


def _alpha_obj(tmp_path, mtl, names):
    lines = ["mtllib alpha.mtl"]
    for i, name in enumerate(names):
        lines += [f"v {i} 0 0", f"v {i + 1} 0 0", f"v {i} 1 0", f"usemtl {name}",
                  f"f {3 * i + 1} {3 * i + 2} {3 * i + 3}"]
    (tmp_path / "alpha.mtl").write_text(mtl)
    path = tmp_path / "alpha.obj"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_mtl_transparency_loads_as_blend(tmp_path, no_warnings):
    """MTL d < 1 -> alpha_mode "blend" with base colour alpha d (a d below 0 clipped to 0);
    d 1 stays opaque. Tr t in (0, 1) without d -> d = 1 - t; Tr 0 and Tr 1 (Meshlab's opaque:
    vcglib writes Tr meaning d, as assets/meshes/fuze's MTL shows) stay opaque. Nothing warns.
    trimesh 5.2 ignores d and Tr (its diffuse alpha stays 255: pyrender.Mesh.from_trimesh draws
    such a material opaque), so this is read from the MTL file itself."""
    names = ["half", "tr", "solid", "agree", "tr_zero", "dissolved", "meshlab"]
    scene = sr.load_scene(_alpha_obj(tmp_path, MTL_ALPHA, names))
    got = {inst.material.name: (inst.material.alpha_mode, inst.material.base_color) for inst in scene}
    assert got == {"half": ("blend", (1.0, 0.0, 0.0, 0.5)), "tr": ("blend", (0.0, 1.0, 0.0, 0.75)),
                   "solid": ("opaque", (0.0, 0.0, 1.0, 1.0)), "agree": ("blend", (1.0, 1.0, 0.0, 0.5)),
                   "tr_zero": ("opaque", (0.0, 1.0, 1.0, 1.0)),
                   "dissolved": ("blend", (1.0, 0.0, 1.0, 0.0)),
                   "meshlab": ("opaque", (0.5, 0.5, 0.5, 1.0))}
    # load_mesh of a one-material file keeps it too (and the base colour as the mesh's colour)
    mesh = sr.load_mesh(_alpha_obj(tmp_path, MTL_ALPHA, ["half"]))
    assert mesh.material.alpha_mode == "blend" and mesh.material.base_color == (1.0, 0.0, 0.0, 0.5)
    assert mesh.material == sr.Material(base_color=(1.0, 0.0, 0.0, 0.5), kd=(1.0, 0.0, 0.0), ks=None,
                                        metallic=0.0, roughness=1.0, model="pbr", name="half",
                                        alpha_mode="blend")


def test_mtl_d_wins_over_tr(tmp_path, no_warnings):
    """A material with both d and Tr reads d, whichever comes first (tinyobjloader's rule),
    without a warning: d is the standard statement, Tr an exporter's duplicate of it."""
    mtl = ("newmtl max\nKd 0.5 0.5 0.5\nd 1\nTr 1\nnewmtl glass\nKd 0.5 0.5 0.5\nTr 0.9\nd 0.25\n"
           "newmtl clear\nKd 0.5 0.5 0.5\nd 1\nTr 0.5\n")
    scene = sr.load_scene(_alpha_obj(tmp_path, mtl, ["max", "glass", "clear"]))
    got = {inst.material.name: (inst.material.alpha_mode, inst.material.base_color[3]) for inst in scene}
    assert got == {"max": ("opaque", 1.0), "glass": ("blend", 0.25), "clear": ("opaque", 1.0)}


def test_fuze_meshlab_tr_1_stays_opaque(no_warnings):
    """assets/meshes/fuze is a Meshlab export whose MTL says "Tr 1.000000" (vcglib writes Tr as
    the opacity): read as opaque, not as an invisible material."""
    mesh = sr.load_mesh(ASSETS / "fuze" / "fuze.obj")
    assert mesh.material.alpha_mode == "opaque" and mesh.material.base_color[3] == 1.0


def test_from_trimesh_simple_material_alpha_blends(no_warnings):
    """Mesh.from_trimesh: a SimpleMaterial whose diffuse alpha is below 255 blends (as MTL's
    d < 1, and as pyrender.Mesh.from_trimesh's BLEND draws it); 255 stays opaque."""
    for alpha, mode in ((128, "blend"), (255, "opaque")):
        tm = trimesh.creation.box()
        tm.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.SimpleMaterial(
            name="m", diffuse=[200, 100, 50, alpha]))
        m = sr.Mesh.from_trimesh(tm).material
        assert m.alpha_mode == mode and m.base_color[3] == alpha / 255.0


def test_box_textured_draws_its_texture(no_warnings):
    mesh = sr.load_mesh(BOX_TEXTURED)
    # no factors in the file: glTF's defaults; the base colour texture (tests/test_file_textures.py
    # checks its pixels)
    texture = mesh.material.base_color_texture
    assert texture is not None and texture.image.shape == (211, 211, 3)
    assert mesh.material == sr.Material(base_color=(1.0, 1.0, 1.0, 1.0), metallic=1.0, roughness=1.0,
                                        model="pbr", base_color_texture=texture)
    assert mesh.num_faces == 12 and mesh.num_vertices == 24 and mesh.uvs is not None
    scene = sr.load_scene(BOX_TEXTURED)
    (inst,) = scene.instances
    # the root node's column-major matrix: z up -> y up
    np.testing.assert_array_equal(inst.pose, [[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]])


# -- Mesh.from_trimesh ----------------------------------------------------------------------------
def test_from_trimesh_face_colors_and_srgb_option(no_warnings):
    tm = trimesh.creation.box()
    rgba = np.random.default_rng(3).integers(0, 256, (12, 4), dtype=np.uint8)
    tm.visual.face_colors = rgba
    linear = sr.Mesh.from_trimesh(tm)
    assert linear.num_vertices == 36
    np.testing.assert_array_equal(linear.faces, np.arange(36).reshape(12, 3))
    np.testing.assert_array_equal(linear.positions, np.float32(tm.vertices[tm.faces.reshape(-1)]))
    np.testing.assert_allclose(linear.colors, np.repeat(rgba / 255.0, 3, axis=0), rtol=1e-6)
    srgb = sr.Mesh.from_trimesh(tm, srgb_colors=True)
    expected = np.repeat([[decode(r), decode(g), decode(b), a / 255] for r, g, b, a in rgba], 3, axis=0)
    np.testing.assert_array_equal(srgb.colors, np.float32(expected))


def test_from_trimesh_materials_use_trimesh_values(no_warnings):
    tm = trimesh.creation.box()
    tm.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.SimpleMaterial(
        name="m", ambient=[51, 51, 51, 255], diffuse=[255, 0, 102, 255], specular=[0, 0, 255, 255],
        glossiness=12.0))
    mesh = sr.Mesh.from_trimesh(tm)
    assert mesh.material == sr.Material(base_color=(1.0, 0.0, 0.4, 1.0), ka=(0.2, 0.2, 0.2), kd=(1.0, 0.0, 0.4),
                                        ks=(0.0, 0.0, 1.0), shininess=12.0, metallic=0.0,
                                        roughness=mtl_roughness(12.0), model="pbr", name="m")
    tm.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(
        name="p", baseColorFactor=[255, 255, 0, 255]))
    assert sr.Mesh.from_trimesh(tm).material == sr.Material(base_color=(1, 1, 0, 1), metallic=1.0,
                                                           roughness=1.0, model="pbr", name="p")
    # UVs without a material: trimesh's placeholder material is no material
    tm.visual = trimesh.visual.TextureVisuals(uv=np.zeros((len(tm.vertices), 2)))
    assert sr.Mesh.from_trimesh(tm).material is None


def test_load_scene_of_a_single_mesh_file_and_errors(tmp_path, no_warnings):
    path = tmp_path / "quad.ply"
    path.write_text(QUAD_PLY)
    scene = sr.load_scene(path)
    (inst,) = scene.instances
    assert inst.mesh.num_vertices == 6 and inst.material is None
    np.testing.assert_array_equal(inst.pose, np.eye(4))
    with pytest.raises(FileNotFoundError):
        sr.load_scene(tmp_path / "missing.glb")
    bad = tmp_path / "bad.glb"
    bad.write_bytes(b"glTF" + b"\x00" * 10)
    with pytest.raises(ValueError, match="bad.glb"):
        sr.load_scene(bad)


def test_gltf_color_0_is_linear_and_multiplied_by_the_base_color_factor(tmp_path, no_warnings):
    box = trimesh.creation.box()
    rgba = np.random.default_rng(4).integers(0, 256, (8, 4), dtype=np.uint8)
    box.visual.vertex_colors = rgba
    doc, rest = _glb_parts(box.export(file_type="glb"))
    (prim,) = doc["meshes"][0]["primitives"]
    assert "COLOR_0" in prim["attributes"] and doc["accessors"][prim["attributes"]["COLOR_0"]]["componentType"] == 5121
    plain = tmp_path / "plain.glb"
    plain.write_bytes(_glb(doc, rest))
    mesh = sr.load_mesh(plain)  # no material: COLOR_0 as is (normalized bytes, linear: no decoding)
    assert mesh.material is None
    np.testing.assert_allclose(mesh.colors, rgba / 255.0, rtol=1e-6)
    prim["material"] = 0
    doc["materials"] = [{"name": "tint", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 1.0, 0.25, 1.0]}}]
    tinted = tmp_path / "tinted.glb"
    tinted.write_bytes(_glb(doc, rest))
    mesh = sr.load_mesh(tinted)
    assert mesh.material == sr.Material(base_color=(0.5, 1.0, 0.25, 1.0), metallic=1.0, roughness=1.0,
                                        model="pbr", name="tint")
    np.testing.assert_allclose(mesh.colors, rgba / 255.0 * [0.5, 1.0, 0.25, 1.0], rtol=1e-6)


def test_glb_alpha_cutoff_and_normal_scale_beyond_float32(tmp_path):
    """An alphaCutoff beyond float32's range falls back to 0.5 with a note, like any
    bad cutoff (Material refuses it now), and the material is kept."""
    def edit(doc):
        paint = next(m for m in doc["materials"] if m["name"] == "paint")
        paint["alphaMode"] = "MASK"
        paint["alphaCutoff"] = 1e39

    path, _, _ = _two_material_glb(tmp_path, edit)
    with pytest.warns(UserWarning, match="alphaCutoff"):
        scene = sr.load_scene(path)
    by_name = {inst.material.name: inst.material for inst in scene}
    assert by_name["paint"] == PAINT.replace(alpha_mode="mask", alpha_cutoff=0.5)
