"""load_mesh / load_scene options: STL vertices merged for smooth normals, and
up_axis="z" (also the CLI's --up-axis)."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import softrast as sr
from softrast.cli import main
from softrast.io import imread

UP_Z = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])  # (x, y, z) -> (x, z, -y)


@pytest.fixture()
def stl_sphere(tmp_path):
    path = tmp_path / "sphere.stl"
    trimesh.creation.icosphere(subdivisions=3, radius=1.0).export(str(path))
    return path


def test_stl_smooth_merges_vertices(stl_sphere) -> None:
    raw = trimesh.load(str(stl_sphere), process=False)  # the file: 3 vertices per face
    soup = np.asarray(raw.vertices)[np.asarray(raw.faces)]
    assert len(raw.vertices) == 3 * len(raw.faces)
    mesh = sr.load_mesh(stl_sphere, smooth=True)
    assert mesh.num_faces == len(raw.faces) and mesh.num_vertices == 642
    # faces keep their order and their corners
    np.testing.assert_array_equal(mesh.positions[mesh.faces], soup.astype(np.float32))
    # as trimesh's merge_vertices: the same vertex count
    merged = trimesh.load(str(stl_sphere), process=False)
    merged.merge_vertices()
    assert len(merged.vertices) == mesh.num_vertices
    # smooth: each normal is close to the sphere's radial direction (faceted: up to ~10 degrees off)
    radial = mesh.positions / np.linalg.norm(mesh.positions, axis=1, keepdims=True)
    cos = np.sum(mesh.normals * radial, axis=1)
    print(f"STL sphere, smooth normals vs radial: max angle {np.degrees(np.arccos(cos.min())):.3f} deg")
    assert cos.min() > np.cos(np.radians(1.0))
    np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-6)
    # shared corners get one normal: the normal varies smoothly across an edge
    flat = sr.load_mesh(stl_sphere, smooth=False)
    assert flat.num_vertices == 3 * flat.num_faces and flat.normals is None
    angle = sr.load_mesh(stl_sphere, smooth="angle")
    assert angle.num_vertices == 642
    scene = sr.load_scene(stl_sphere)
    assert scene.instances[0].mesh.num_vertices == 642


def test_up_axis_z(tmp_path) -> None:
    tm = trimesh.creation.cone(radius=0.5, height=2.0, sections=24)  # tip at +z
    path = tmp_path / "cone.ply"
    tm.export(str(path))
    as_is = sr.load_mesh(path)
    up = sr.load_mesh(path, up_axis="z")
    np.testing.assert_allclose(up.positions, as_is.positions @ UP_Z.T, atol=1e-7)
    np.testing.assert_allclose(up.normals, as_is.normals @ UP_Z.T, atol=1e-6)
    np.testing.assert_array_equal(up.faces, as_is.faces)
    assert up.bounds[1, 1] == pytest.approx(2.0)  # the tip now points up (+y)
    scene = sr.load_scene(path, up_axis="z")
    np.testing.assert_allclose(scene.instances[0].pose[:3, :3], UP_Z)
    with pytest.raises(ValueError, match="up_axis"):
        sr.load_mesh(path, up_axis="x")
    with pytest.raises(ValueError, match="up_axis"):
        sr.load_scene(path, up_axis="Z")
    # the CLI: --up-axis z renders the rotated mesh
    args = ["render", str(path), "--size", "48x48", "--eye", "0,1,6", "--target", "0,1,0",
            "--near", "1", "--far", "20", "--cull", "none"]
    assert main(args + ["-o", str(tmp_path / "z.png"), "--depth", str(tmp_path / "z.exr"), "--up-axis", "z"]) == 0
    scene = sr.Scene()
    scene.add(up)
    cam = sr.PerspectiveCamera(fov_y=45.0, width=48, height=48, near=1.0, far=20.0).look_at((0, 1, 6), (0, 1, 0))
    np.testing.assert_array_equal(imread(tmp_path / "z.exr"), sr.Renderer(48, 48).render(
        scene, cam, outputs="depth", cull="none").depth)
