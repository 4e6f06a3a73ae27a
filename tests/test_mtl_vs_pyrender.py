"""OBJ + MTL materials against pyrender 0.1.45 (``Ns 0`` once rendered as white blobs).

softrast renders an MTL material as ``pbr`` (the rule is stated in ``softrast.loaders``): base
colour Kd (times ``map_Kd``), metallic 0, roughness (2 / (Ns + 2)) ** 0.25 (trimesh's
``SimpleMaterial.to_pbr`` and pyrender's ``Mesh.from_trimesh`` mapping), 1 without a highlight (Ks
absent or black). pyrender renders the same file (trimesh.load, its own uvs, normals and texture:
tests/support/pyrender_child.py) with a MetallicRoughnessMaterial of the factors the rule gives,
written out here as numbers, and the two are compared as in test_pbr_vs_pyrender.py: interior pixels
(both masks, eroded by 2 px), mean |diff| <= 3/255, p99 <= 8/255, under ``shading="auto"``.

pyrender's own conversion of these files is not the rule, and is not matched: pyrender 0.1.45
leaves metallicFactor at its default 1 (every MTL material becomes a metal: no diffuse term, Kd
becomes the specular colour) and reads ``mat.kwargs["Ns"]`` where trimesh stores ``"ns"``, so
Ns is ignored and the roughness is always (2 / 3) ** 0.25 = 0.904 (Ns 1); without Kd the base
colour is trimesh's default 0.4 grey. test_pyrender_own_conversion_is_a_rough_metal checks that
this, and nothing else, is the difference: softrast given pyrender's factors matches pyrender's
own render within the same bounds.

Assets: assets/meshes/fuze (a Meshlab export: Ks 1 1 1, Ns 0, illum 2, map_Kd) and
assets/meshes/wood (map_Kd only), from pyrender's tests/data (assets/LICENSES.md), and an OBJ
written here with Ns 0, 10 and 200 and a material without Ks. Needs pyrender 0.1.45 with OSMesa:
without it the test FAILS (see test_pbr_vs_pyrender.py).
"""
from __future__ import annotations

import pathlib

import numpy as np
import pytest
import trimesh

import softrast as sr
from test_pbr_vs_pyrender import AMBIENT, FOV_Y_DEG, add_lights, compare, render_pyrender

ASSETS = pathlib.Path(__file__).resolve().parents[1] / "assets" / "meshes"
FUZE = ASSETS / "fuze" / "fuze.obj"
WOOD = ASSETS / "wood" / "wood.obj"
OWN_EYE = (0.5, -2.9, 0.8)
FUZE_EYE = (0.3, 0.2, 0.19)  # the bottle fills most of the image height
# fuze's JPEG texture: the largest differences (p99 7 to 8/255 here) lie on its sharp edges, where
# softrast's trilinear filtering of decoded texels and llvmpipe's differ; the mean is ~0.7/255.
FUZE_P99 = 12.0
ROUGH_NS1 = (2.0 / 3.0) ** 0.25  # pyrender's roughness for every MTL material (Ns ignored)


def rule_roughness(ns: float) -> float:
    return (2.0 / (ns + 2.0)) ** 0.25


# Ns 0 (the fuze case, without a texture), 10, 200, and a material without Ks (no highlight).
OWN_MATERIALS = {  # name: (MTL lines, base colour, roughness the rule gives)
    "white_ns0": ("Kd 0.8 0.8 0.8\nKs 1 1 1\nNs 0\nillum 2", (0.8, 0.8, 0.8, 1.0), 1.0),
    "red_ns10": ("Kd 0.7 0.15 0.1\nKs 0.5 0.5 0.5\nNs 10", (0.7, 0.15, 0.1, 1.0), rule_roughness(10.0)),
    "blue_ns200": ("Kd 0.1 0.2 0.7\nKs 1 1 1\nNs 200", (0.1, 0.2, 0.7, 1.0), rule_roughness(200.0)),
    "green_no_ks": ("Kd 0.2 0.6 0.2\nNs 200", (0.2, 0.6, 0.2, 1.0), 1.0),
}


def write_own_obj(folder: pathlib.Path) -> pathlib.Path:
    """Four smooth spheres in a 2 x 2 grid (in the x-z plane, z up), one per material, with their
    normals written out."""
    ball = trimesh.creation.icosphere(subdivisions=4, radius=0.42)
    lines = ["mtllib own.mtl"]
    for k, name in enumerate(OWN_MATERIALS):
        base = len(ball.vertices) * k
        lines += [f"o {name}"]
        dx, dz = k % 2 - 0.5, 0.5 - k // 2
        lines += [f"v {x + dx:.6f} {y:.6f} {z + dz:.6f}" for x, y, z in ball.vertices]
        lines += [f"vn {x:.6f} {y:.6f} {z:.6f}" for x, y, z in ball.vertex_normals]
        lines += [f"usemtl {name}"]
        lines += [f"f {a}//{a} {b}//{b} {c}//{c}" for a, b, c in ball.faces + 1 + base]
    (folder / "own.mtl").write_text("".join(f"newmtl {name}\n{text}\n\n"
                                            for name, (text, _, _) in OWN_MATERIALS.items()))
    path = folder / "own.obj"
    path.write_text("\n".join(lines) + "\n")
    return path


def lit(path: pathlib.Path) -> sr.Scene:
    scene = sr.load_scene(path)
    scene.ambient_light = AMBIENT
    return scene


def z_up_camera(eye, target, near: float) -> sr.PerspectiveCamera:
    return sr.PerspectiveCamera(fov_y=FOV_Y_DEG, near=near, far=30.0).look_at(eye, target, up=(0.0, 0.0, 1.0))


def pyrender_render(name: str, cam: sr.PerspectiveCamera, path: pathlib.Path, materials: dict | None,
                    tmp_path: pathlib.Path) -> tuple[np.ndarray, np.ndarray]:
    """pyrender's colour and depth of ``path`` under the lights of ``add_lights``, with
    ``materials``' factors, or with its own conversion if None."""
    spec_lights = add_lights(sr.Scene())  # the lights add_lights gives softrast's scene
    out = tmp_path / name
    out.mkdir()
    spec = {"ambient": list(AMBIENT), "lights": spec_lights, "gltf": str(path),
            "camera_pose": cam.pose.tolist(), "znear": cam.near, "zfar": cam.far}
    if materials is not None:
        spec["materials"] = materials
    return render_pyrender(spec, out)


def against_pyrender(name: str, scene: sr.Scene, cam: sr.PerspectiveCamera, path: pathlib.Path,
                     materials: dict | None, tmp_path: pathlib.Path, **bounds) -> float:
    """softrast's render of ``scene`` under shading="auto" against pyrender's of ``path``, within
    the bounds; returns the mean |diff|."""
    return compare(name, scene, cam, *pyrender_render(name, cam, path, materials, tmp_path),
                   shading="auto", **bounds)


def test_fuze_is_rough_plastic_and_matches_pyrender(tmp_path: pathlib.Path) -> None:
    scene = lit(FUZE)
    (inst,) = list(scene)
    m = inst.material
    assert (m.model, m.metallic, m.roughness) == ("pbr", 0.0, 1.0)
    assert m.ks == (1.0, 1.0, 1.0) and m.shininess == 0.0 and m.base_color_texture is not None
    add_lights(scene)
    cam = z_up_camera(FUZE_EYE, (0.0, 0.0, 0.11), 0.05)
    against_pyrender("fuze", scene, cam, FUZE,
                     {"material_0": {"base": [1.0, 1.0, 1.0, 1.0], "metallic": 0.0, "roughness": 1.0}},
                     tmp_path, p99_max=FUZE_P99)


def test_fuze_is_no_white_blob_under_the_headlight() -> None:
    # The report's case: the default look (no lights: the headlight), shading "auto". With Ns 0
    # read as a Blinn-Phong exponent, ks (n.h)^0 = ks added everywhere washed it out to white.
    scene = sr.load_scene(FUZE)
    cam = z_up_camera(FUZE_EYE, (0.0, 0.0, 0.11), 0.05)
    frame = sr.Renderer(160, 120).render(scene, cam, outputs=("color", "depth"))
    unlit = sr.Renderer(160, 120).render(scene, cam, outputs=("color",), shading="unlit")
    covered = frame.depth > 0
    assert covered.sum() > 1000
    assert (frame.color[covered] >= 250).all(-1).mean() < 0.01
    # no brighter than the texture itself, on average (the washed-out render was ~0.9 of white)
    assert frame.color[covered].mean() <= unlit.color[covered].mean()
    # an explicit Blinn-Phong still uses the file's ks and Ns: the old washed-out look
    phong = sr.Renderer(160, 120).render(scene, cam, outputs=("color",), shading="blinn_phong")
    assert phong.color[covered].mean() > 0.8 * 255


def test_wood_matches_pyrender(tmp_path: pathlib.Path) -> None:
    scene = lit(WOOD)
    (inst,) = list(scene)
    assert (inst.material.model, inst.material.metallic, inst.material.roughness) == ("pbr", 0.0, 1.0)
    add_lights(scene)
    cam = z_up_camera((0.35, -0.55, 0.9), (0.0, 0.0, 0.0), 0.2)
    # no Kd: the texture as it is (trimesh's SimpleMaterial says 0.4 grey; softrast, white)
    against_pyrender("wood", scene, cam, WOOD,
                     {"material_0": {"base": [1.0, 1.0, 1.0, 1.0], "metallic": 0.0, "roughness": 1.0}},
                     tmp_path)


def test_own_mtl_ns_0_10_200_and_no_ks_match_pyrender(tmp_path: pathlib.Path) -> None:
    path = write_own_obj(tmp_path)
    scene = lit(path)
    by_name = {inst.material.name: inst.material for inst in scene}
    assert set(by_name) == set(OWN_MATERIALS)
    for name, (_, base, roughness) in OWN_MATERIALS.items():
        m = by_name[name]
        assert (m.model, m.metallic) == ("pbr", 0.0) and m.base_color == pytest.approx(base)
        assert m.roughness == pytest.approx(roughness, rel=1e-12), name
    assert by_name["red_ns10"].roughness == pytest.approx(0.6389, abs=1e-4)
    assert by_name["blue_ns200"].roughness == pytest.approx(0.3154, abs=1e-4)
    add_lights(scene)
    cam = z_up_camera(OWN_EYE, (0.0, 0.0, 0.0), 0.5)
    against_pyrender("own MTL", scene, cam, path,
                     {name: {"base": list(base), "metallic": 0.0, "roughness": roughness}
                      for name, (_, base, roughness) in OWN_MATERIALS.items()}, tmp_path)


def test_pyrender_own_conversion_is_a_rough_metal(tmp_path: pathlib.Path) -> None:
    """pyrender's Mesh.from_trimesh of an MTL material: metallic 1, roughness 0.904 whatever Ns
    (and 0.4 grey without Kd). softrast given those factors matches it; softrast's rule does not
    (printed: run with -s)."""
    path = write_own_obj(tmp_path)
    cases = [("fuze", FUZE, z_up_camera(FUZE_EYE, (0.0, 0.0, 0.11), 0.05), None),
             ("wood", WOOD, z_up_camera((0.35, -0.55, 0.9), (0.0, 0.0, 0.0), 0.2), (0.4, 0.4, 0.4, 1.0)),
             ("own MTL", path, z_up_camera(OWN_EYE, (0.0, 0.0, 0.0), 0.5), None)]
    for name, file, cam, base in cases:
        rule = lit(file)
        as_pyrender = sr.Scene(ambient_light=AMBIENT)
        for inst in rule:
            m = inst.material.replace(metallic=1.0, roughness=ROUGH_NS1, **({"base_color": base} if base else {}))
            as_pyrender.add(inst.mesh, pose=inst.pose, material=m)
        add_lights(rule)
        add_lights(as_pyrender)
        pr = pyrender_render(name, cam, file, None, tmp_path)
        mean = compare(f"{name}, pyrender's factors vs pyrender's own conversion", as_pyrender, cam, *pr,
                       shading="auto", p99_max=FUZE_P99)
        off = compare(f"{name}, softrast's rule vs pyrender's own conversion", rule, cam, *pr,
                      shading="auto", check=False)
        print(f"{name}: softrast with pyrender's factors {mean:.2f}/255 from pyrender's own conversion; "
              f"softrast's rule {off:.2f}/255 from it")
