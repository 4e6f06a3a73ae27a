"""Double-sided materials are never culled (glTF 2.0, "doubleSided": back-face culling is
disabled), per material, under every cull mode, unless ``render(cull_double_sided=True)``.

Checked against pyrender 0.1.45 (OSMesa, in a child process: tests/support/pyrender_child.py), which
turns culling off for a double-sided material, on a GLB with two quads seen from behind: one
double-sided, one not. Meshes without a material stay culled (softrast's default look).
"""
from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest
import trimesh

import softrast as sr
from support.pyrender_runner import run_pyrender_child

CHILD = pathlib.Path(__file__).resolve().parent / "support" / "pyrender_child.py"
W, H = 96, 64
YFOV = 0.8


def _quad(x0: float, material: trimesh.visual.material.PBRMaterial | None) -> trimesh.Trimesh:
    v = np.array([[x0, -0.5, 0.0], [x0 + 0.8, -0.5, 0.0], [x0 + 0.8, 0.5, 0.0], [x0, 0.5, 0.0]])
    f = np.array([[0, 2, 1], [0, 3, 2]])  # clockwise seen from +z: the camera sees the back
    mesh = trimesh.Trimesh(v, f, process=False)
    if material is not None:
        mesh.visual = trimesh.visual.TextureVisuals(material=material)
    return mesh


@pytest.fixture(scope="module")
def quads_glb(tmp_path_factory: pytest.TempPathFactory) -> pathlib.Path:
    pbr = trimesh.visual.material.PBRMaterial
    scene = trimesh.Scene()
    scene.add_geometry(_quad(-0.9, pbr(name="two", baseColorFactor=[200, 100, 50, 255],
                                       doubleSided=True, metallicFactor=0.0, roughnessFactor=0.5)),
                       geom_name="two")
    scene.add_geometry(_quad(0.1, pbr(name="one", baseColorFactor=[50, 100, 200, 255],
                                      doubleSided=False, metallicFactor=0.0, roughnessFactor=0.5)),
                       geom_name="one")
    path = tmp_path_factory.mktemp("double_sided") / "quads.glb"
    path.write_bytes(scene.export(file_type="glb"))
    return path


def _camera() -> sr.PerspectiveCamera:
    cam = sr.PerspectiveCamera(fov_y=np.degrees(YFOV), near=0.5, far=10.0)
    cam.pose = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 2], [0, 0, 0, 1]]  # at +z, looking down -z:
    return cam                                                       # both quads show their backs


def _left_right(mask: np.ndarray) -> tuple[int, int]:
    return int(mask[:, : W // 2].sum()), int(mask[:, W // 2:].sum())


def test_gltf_double_sided_is_drawn_from_behind_like_pyrender(quads_glb, tmp_path):
    scene = sr.load_scene(str(quads_glb))
    r = sr.Renderer(W, H)
    mask = r.render(scene, _camera(), outputs=("mask",)).mask
    left, right = _left_right(mask)
    assert left > 0.25 * (H * W // 2), "the double-sided quad is culled from behind"
    assert right == 0, "the single-sided quad is drawn from behind under cull='back'"

    spec = {"width": W, "height": H, "yfov": YFOV, "znear": 0.5, "zfar": 10.0,
            "camera_pose": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 2], [0, 0, 0, 1]],
            "ambient": [1.0, 1.0, 1.0], "lights": [], "gltf": str(quads_glb)}
    spec_path = tmp_path / "spec.json"
    spec_path.write_text(json.dumps(spec))
    run_pyrender_child(CHILD, [spec_path, tmp_path], timeout=120)
    theirs = np.load(tmp_path / "depth.npy") > 0
    assert _left_right(theirs)[0] > 0 and _left_right(theirs)[1] == 0  # pyrender: the same rule
    # The same pixels, but for pyrender's own silhouette rule (a pixel's width at the edges).
    assert (mask != theirs).sum() <= 2 * (H + W), (mask != theirs).sum()


@pytest.mark.parametrize("cull", ["back", "front", "none"])
def test_double_sided_material_never_culled_under_any_mode(cull):
    r = sr.Renderer(W, H)
    cam = _camera()
    for facing_camera in (False, True):
        mesh = _quad(-0.4, None)
        faces = mesh.faces if not facing_camera else mesh.faces[:, ::-1]
        m = sr.Mesh(mesh.vertices, faces)
        scene = sr.Scene()
        scene.add(m, material=sr.Material(double_sided=True))
        assert r.render(scene, cam, outputs=("mask",), cull=cull).mask.sum() > 0
        # The explicit override culls them as any other.
        culled = r.render(scene, cam, outputs=("mask",), cull=cull, cull_double_sided=True).mask
        front_culled = cull == "front" and facing_camera
        back_culled = cull == "back" and not facing_camera
        assert (culled.sum() == 0) == (front_culled or back_culled)


def test_single_sided_and_plain_meshes_stay_culled():
    r = sr.Renderer(W, H)
    mesh = _quad(-0.4, None)
    for material in (None, sr.Material(), sr.Material(double_sided=False, model="pbr")):
        scene = sr.Scene()
        scene.add(sr.Mesh(mesh.vertices, mesh.faces), material=material)
        assert r.render(scene, _camera(), outputs=("mask",)).mask.sum() == 0, material
        assert r.render(scene, _camera(), outputs=("mask",), cull="none").mask.sum() > 0


def test_cull_double_sided_is_checked():
    r = sr.Renderer(W, H)
    with pytest.raises(TypeError, match="cull_double_sided"):
        r.render(sr.Scene(), _camera(), cull_double_sided="yes")
