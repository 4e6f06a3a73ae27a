"""Builds a pyrender scene, renders it with pyrender 0.1.45 under OSMesa AND converts it with
softrast.from_pyrender and renders that with softrast, for test_from_pyrender.py.

    PYOPENGL_PLATFORM=osmesa python3 tests/support/pyrender_interop_child.py SOFTRAST_PARENT_DIR OUT_DIR

The scene: two meshes (a smooth icosphere given as an explicit Primitive with normals and a
MetallicRoughnessMaterial; a box from pyrender.Mesh.from_trimesh with per-vertex colours, under
a parent node so its world pose is composed), a directional and a spot light, ambient light, and
one camera per run: "perspective" (PerspectiveCamera, yfov in radians), "intrinsics"
(IntrinsicsCamera) and "orthographic" (OrthographicCamera). For each camera writes
OUT_DIR/<camera>_{pr_depth,pr_color,sr_depth,sr_mask,sr_color}.npy and OUT_DIR/info.json (what
from_pyrender returned), and OUT_DIR/world_triangles.npy ((n, 3, 3) float64, the converted scene). Exit status 3 if pyrender cannot be imported.
"""
import json
import os
import sys

from pyrender_env import import_pyrender  # noqa: E402

import numpy as np  # noqa: E402

pyrender, trimesh = import_pyrender("pyrender_interop_child")

W, H = 320, 240


def rigid(angle, axis, offset):
    m = trimesh.transformations.rotation_matrix(angle, axis)
    m[:3, 3] = offset
    return m


def build(camera_kind):
    scene = pyrender.Scene(ambient_light=np.array([0.05, 0.05, 0.06]), bg_color=[0.0, 0.0, 0.0, 1.0])
    ico = trimesh.creation.icosphere(subdivisions=3, radius=0.6)
    prim = pyrender.Primitive(
        positions=np.asarray(ico.vertices, np.float32), normals=np.asarray(ico.vertex_normals, np.float32),
        indices=np.asarray(ico.faces, np.int32),
        material=pyrender.MetallicRoughnessMaterial(baseColorFactor=[0.9, 0.6, 0.3, 1.0], metallicFactor=0.2,
                                                    roughnessFactor=0.6, name="ball"))
    scene.add(pyrender.Mesh(primitives=[prim], name="ball"), pose=rigid(0.3, (0, 1, 0), (-0.5, 0.1, 0.0)),
              name="ball")
    box = trimesh.creation.box(extents=(0.8, 0.7, 0.9))
    box.visual.vertex_colors = np.array([[200, 80, 40, 255]] * len(box.vertices), np.uint8)
    parent = pyrender.Node(name="holder", matrix=rigid(0.4, (1, 0, 0), (0.6, 0.0, -0.3)))
    scene.add_node(parent)
    scene.add_node(pyrender.Node(name="box", mesh=pyrender.Mesh.from_trimesh(box, smooth=False),
                                 matrix=rigid(0.7, (0.2, 1.0, 0.1), (0.1, -0.1, 0.0))), parent_node=parent)
    scene.add(pyrender.DirectionalLight(color=[1.0, 0.95, 0.9], intensity=2.5),
              pose=rigid(-0.6, (1, 0.2, 0), (0, 0, 0)), name="sun")
    scene.add(pyrender.SpotLight(color=[0.5, 0.7, 1.0], intensity=9.0, innerConeAngle=0.2, outerConeAngle=0.6),
              pose=rigid(0.2, (0, 1, 0), (0.5, 0.5, 3.0)), name="spot")
    if camera_kind == "perspective":
        cam = pyrender.PerspectiveCamera(yfov=np.radians(40.0), znear=0.5, zfar=20.0, aspectRatio=W / H)
    elif camera_kind == "intrinsics":
        cam = pyrender.IntrinsicsCamera(fx=300.0, fy=290.0, cx=170.3, cy=112.6, znear=0.5, zfar=20.0)
    else:
        cam = pyrender.OrthographicCamera(xmag=1.6, ymag=1.2, znear=0.5, zfar=20.0)
    cam_pose = rigid(0.15, (-1.0, 0.4, 0.0), (0.2, 0.6, 3.6))
    scene.add(cam, pose=cam_pose, name="camera")
    return scene


def main(parent_dir, out_dir):
    sys.path.insert(0, parent_dir)
    import softrast as sr

    info = {}
    renderer = pyrender.OffscreenRenderer(W, H)
    try:
        for kind in ("perspective", "intrinsics", "orthographic"):
            scene = build(kind)
            color, depth = renderer.render(scene)
            sr_scene, sr_cam = sr.from_pyrender(scene, W, H)
            frame = sr.Renderer(W, H).render(sr_scene, sr_cam, outputs=("color", "depth", "mask"))
            if kind == "orthographic":  # world-space triangles, for the parent's ray casting
                tris = [inst.mesh.positions.astype(np.float64)[inst.mesh.faces] @ inst.pose[:3, :3].T
                        + inst.pose[:3, 3] for inst in sr_scene]
                np.save(os.path.join(out_dir, "world_triangles.npy"), np.concatenate(tris))
            for name, arr in (("pr_depth", depth), ("pr_color", color[..., :3]), ("sr_depth", frame.depth),
                              ("sr_mask", frame.mask), ("sr_color", frame.color)):
                np.save(os.path.join(out_dir, f"{kind}_{name}.npy"), np.ascontiguousarray(arr))
            info[kind] = {
                "camera": type(sr_cam).__name__,
                "fov_y": getattr(sr_cam, "fov_y", None), "aspect": getattr(sr_cam, "aspect", None),
                "near": sr_cam.near, "far": sr_cam.far, "convention": sr_cam.convention,
                "pose": sr_cam.pose.tolist(),
                "instances": [{"faces": inst.mesh.num_faces, "pose": inst.pose.tolist(),
                               "material": None if inst.material is None else
                               [list(inst.material.base_color), inst.material.metallic, inst.material.roughness,
                                inst.material.model],
                               "colors": inst.mesh.colors is not None} for inst in sr_scene],
                "lights": [{"type": type(li.light).__name__, "color": list(li.light.color),
                            "intensity": li.light.intensity, "pose": li.pose.tolist(),
                            "cones": [getattr(li.light, "inner_cone", None), getattr(li.light, "outer_cone", None)]}
                           for li in sr_scene.lights],
                "ambient": list(sr_scene.ambient_light),
            }
    finally:
        renderer.delete()
    with open(os.path.join(out_dir, "info.json"), "w") as f:
        json.dump(info, f)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
