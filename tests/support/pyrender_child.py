"""Renders a scene with pyrender 0.1.45 under OSMesa (Mesa's llvmpipe) for test_pbr_vs_pyrender.

Run as a separate process so the test process never loads OpenGL:
    PYOPENGL_PLATFORM=osmesa python3 tests/support/pyrender_child.py SPEC.json OUT_DIR
SPEC.json (written by the test):
    width, height, yfov (radians), znear, zfar, camera_pose (4x4), ambient (RGB),
    lights: [{kind: "directional" | "point", color, intensity, pose}],
    meshes: [{arrays: NPZ path with positions / faces / normals, base (RGBA), metallic,
              roughness, pose}]     (explicit primitives: exactly these normals), and/or
    gltf: a mesh file (.glb, or .obj with its MTL) loaded with trimesh (process=False, as
          softrast.load_scene does) and turned into nodes by pyrender.Scene.from_trimesh_scene
          (a file trimesh loads as one Trimesh is wrapped in a trimesh.Scene first);
    materials (with gltf, optional): {material name: {base (RGBA), metallic, roughness}}: each
          part gets a MetallicRoughnessMaterial with these factors and its trimesh material's
          image as the base colour texture (pyrender.Mesh.from_trimesh(material=...), so uvs,
          normals and texture are pyrender's own), instead of pyrender's own conversion.
Writes OUT_DIR/color.npy ((H, W, 3) uint8, pyrender's bytes) and OUT_DIR/depth.npy ((H, W)
float32, 0 where nothing was drawn). Exit status 3 with a message if pyrender cannot be imported.
Imports neither softrast nor the test suite (but its pyrender_env, the OSMesa set-up).
"""
import json
import os
import sys

from pyrender_env import import_pyrender  # noqa: E402

import numpy as np  # noqa: E402

pyrender, trimesh = import_pyrender("pyrender_child")


def main(spec_path: str, out_dir: str) -> None:
    with open(spec_path) as f:
        spec = json.load(f)
    scene = pyrender.Scene(ambient_light=np.asarray(spec["ambient"], float), bg_color=[0.0, 0.0, 0.0, 1.0])
    if spec.get("gltf"):
        loaded = trimesh.load(spec["gltf"], process=False)
        if isinstance(loaded, trimesh.Trimesh):  # an OBJ with one part
            loaded = trimesh.Scene(loaded)
        if spec.get("materials") is None:
            scene = pyrender.Scene.from_trimesh_scene(loaded, bg_color=[0.0, 0.0, 0.0, 1.0],
                                                      ambient_light=np.asarray(spec["ambient"], float))
        else:
            for node in loaded.graph.nodes_geometry:
                transform, name = loaded.graph[node]
                geom = loaded.geometry[name]
                own = geom.visual.material
                factors = spec["materials"][own.name]
                material = pyrender.MetallicRoughnessMaterial(
                    baseColorFactor=list(factors["base"]), metallicFactor=float(factors["metallic"]),
                    roughnessFactor=float(factors["roughness"]),
                    baseColorTexture=getattr(own, "image", None))
                scene.add(pyrender.Mesh.from_trimesh(geom, material=material),
                          pose=np.asarray(transform, float))
    for m in spec.get("meshes", []):
        arrays = np.load(m["arrays"])
        material = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=list(m["base"]), metallicFactor=float(m["metallic"]),
            roughnessFactor=float(m["roughness"]))
        prim = pyrender.Primitive(positions=arrays["positions"], normals=arrays["normals"],
                                  indices=arrays["faces"], material=material)
        scene.add(pyrender.Mesh(primitives=[prim]), pose=np.asarray(m["pose"], float))
    for li in spec["lights"]:
        if li["kind"] == "directional":
            light = pyrender.DirectionalLight(color=li["color"], intensity=li["intensity"])
        elif li["kind"] == "point":
            light = pyrender.PointLight(color=li["color"], intensity=li["intensity"])
        else:
            raise ValueError(f"unknown light kind {li['kind']!r}")
        scene.add(light, pose=np.asarray(li["pose"], float))
    w, h = int(spec["width"]), int(spec["height"])
    cam = pyrender.PerspectiveCamera(yfov=float(spec["yfov"]), znear=float(spec["znear"]),
                                     zfar=float(spec["zfar"]), aspectRatio=w / h)
    scene.add(cam, pose=np.asarray(spec["camera_pose"], float))
    renderer = pyrender.OffscreenRenderer(w, h)
    try:
        color, depth = renderer.render(scene)
    finally:
        renderer.delete()
    np.save(os.path.join(out_dir, "color.npy"), np.ascontiguousarray(color[..., :3]))
    np.save(os.path.join(out_dir, "depth.npy"), np.ascontiguousarray(depth, dtype=np.float32))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
