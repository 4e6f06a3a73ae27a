"""softrast.Scene.from_trimesh: parts, node transforms and materials kept; the same
instances as load_scene of the file trimesh writes; the same pixels as the merged Mesh."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh
from trimesh.visual import TextureVisuals
from trimesh.visual.material import PBRMaterial

import softrast as sr


def make_scene() -> trimesh.Scene:
    tscene = trimesh.Scene()
    box = trimesh.creation.box(extents=(0.8, 0.8, 0.8))
    box.visual = TextureVisuals(material=PBRMaterial(name="red", baseColorFactor=(204, 51, 25, 255),
                                                     metallicFactor=0.0, roughnessFactor=0.5))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.4)
    ball.visual = TextureVisuals(material=PBRMaterial(name="gold", baseColorFactor=(240, 200, 90, 255),
                                                      metallicFactor=1.0, roughnessFactor=0.3))
    for name, geom, node, axis, offset in (("box", box, "box", (0, 1, 0), (-1.0, 0.0, 0.0)),
                                           ("ball", ball, "ball_a", (1, 0, 0), (0.5, 0.3, 0.0)),
                                           ("ball", ball, "ball_b", (0, 0, 1), (1.2, -0.4, -0.5))):
        m = trimesh.transformations.rotation_matrix(0.4, axis)
        m[:3, 3] = offset
        if name in tscene.geometry:  # a second placement of the same geometry
            tscene.graph.update(frame_to=node, frame_from=tscene.graph.base_frame, matrix=m, geometry=name)
        else:
            tscene.add_geometry(geom, geom_name=name, node_name=node, transform=m)
    return tscene


def test_parts_transforms_and_materials_are_kept(tmp_path) -> None:
    tscene = make_scene()
    scene = sr.Scene.from_trimesh(tscene)
    insts = scene.instances
    assert len(insts) == 3 and [i.instance_id for i in insts] == [0, 1, 2]
    expected = {node: tscene.graph[node] for node in tscene.graph.nodes_geometry}
    for inst, node in zip(insts, tscene.graph.nodes_geometry):
        transform, name = expected[node]
        np.testing.assert_array_equal(inst.pose, transform)
        assert inst.mesh.num_faces == len(tscene.geometry[name].faces)
        assert inst.material.model == "pbr"
    by_name = {inst.material.name: inst for inst in insts}
    assert set(by_name) == {"red", "gold"}
    np.testing.assert_allclose(by_name["red"].material.base_color, np.array([204, 51, 25, 255]) / 255.0)
    assert by_name["gold"].material.metallic == 1.0 and by_name["gold"].material.roughness == 0.3
    balls = [i for i in insts if i.material.name == "gold"]
    assert balls[0].mesh is balls[1].mesh  # one geometry, two nodes: one shared Mesh
    # load_scene of the same scene written as a GLB: the same parts in the same places
    glb = tmp_path / "parts.glb"
    tscene.export(str(glb))
    loaded = sr.load_scene(glb)
    assert len(loaded) == 3
    assert sorted(i.mesh.num_faces for i in loaded) == sorted(i.mesh.num_faces for i in insts)
    poses_a = sorted(tuple(np.round(i.pose, 6).ravel()) for i in insts)
    poses_b = sorted(tuple(np.round(i.pose, 6).ravel()) for i in loaded)
    np.testing.assert_allclose(poses_a, poses_b, atol=1e-6)


def test_renders_like_the_merged_mesh() -> None:
    tscene = make_scene()
    scene = sr.Scene.from_trimesh(tscene, smooth=False)
    merged = sr.Scene()
    with pytest.warns(UserWarning, match="different materials"):
        merged.add(sr.Mesh.from_trimesh(tscene, smooth=False))
    cam = sr.PerspectiveCamera(fov_y=45.0, near=0.1, far=20.0).look_at((0.3, 1.0, 4.0), (0.0, 0.0, 0.0))
    renderer = sr.Renderer(200, 150)
    a = renderer.render(scene, cam, outputs=("depth", "instance_id"))
    b = renderer.render(merged, cam, outputs=("depth",))
    np.testing.assert_array_equal(a.depth > 0, b.depth > 0)
    # the merged mesh's vertices are moved in float64 before float32; the instances' in the core
    np.testing.assert_allclose(a.depth, b.depth, rtol=1e-5, atol=0)
    assert set(np.unique(a.instance_id)) == {-1, 0, 1, 2}


def test_from_trimesh_inputs() -> None:
    single = sr.Scene.from_trimesh(trimesh.creation.box())
    assert len(single) == 1 and np.array_equal(single.instances[0].pose, np.eye(4))
    with pytest.raises(ValueError, match="no triangle geometry"):
        sr.Scene.from_trimesh(trimesh.Scene())
    with pytest.raises(TypeError, match="trimesh.Scene"):
        sr.Scene.from_trimesh("box.glb")
    with pytest.raises(ValueError, match="smooth"):
        sr.Scene.from_trimesh(trimesh.creation.box(), smooth="yes")
