"""Runs pyrender 0.1.45 under OSMesa for test_to_pyrender.py: renders scenes built directly in
pyrender from plain arrays, and softrast scenes converted by softrast.to_pyrender.

    PYOPENGL_PLATFORM=osmesa python3 tests/support/pyrender_to_child.py SOFTRAST_PARENT_DIR JOBS.pkl OUT_DIR

JOBS.pkl (written by the test) is a list of jobs, each a dict with "name", "width", "height" and
either
* "direct": {"meshes": [{positions, faces, colors (None or (n, 4) float), base (RGBA), pose}],
  "camera": {"kind": "opencv", K, R, t (an OpenCV calibration: x_cam = R X + t)} or {"kind":
  "perspective", yfov (radians), pose (OpenGL axes)} or {"kind": "orthographic", xmag, ymag,
  pose}, "znear", "zfar"}: a pyrender scene built here from those arrays alone (this script's
  own reading of pyrender's conventions: K's principal point + 0.5 and the OpenCV pose's y and z
  flipped for pyrender's IntrinsicsCamera), rendered with RenderFlags.FLAT; or
* "scene" (a pickled softrast.Scene) and "camera" (a softrast camera or None): converted with
  softrast.to_pyrender (its warnings recorded), summarized (plain arrays and strings: the parent
  never imports pyrender), rendered with each flag set in "render" ("flat": RenderFlags.FLAT,
  "lit": the default shading), and converted back with softrast.from_pyrender.
Writes OUT_DIR/<name>.pkl: {"warnings", "renders": {mode: (color (H, W, 3) uint8, depth (H, W)
float32)}, "summary", "back": (softrast.Scene, camera) or None, "error": None or a traceback}.
Exit status 3 if pyrender cannot be imported.
"""
import os
import pickle
import sys
import traceback
import warnings

from pyrender_env import import_pyrender  # noqa: E402

import numpy as np  # noqa: E402

pyrender, trimesh = import_pyrender("pyrender_to_child")

GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])


def direct_scene(spec):
    scene = pyrender.Scene(ambient_light=np.zeros(3), bg_color=[0.0, 0.0, 0.0, 1.0])
    for m in spec["meshes"]:
        material = pyrender.MetallicRoughnessMaterial(baseColorFactor=list(m["base"]), metallicFactor=0.0,
                                                      roughnessFactor=1.0)
        prim = pyrender.Primitive(positions=m["positions"], indices=m["faces"], color_0=m["colors"],
                                  material=material)
        scene.add(pyrender.Mesh(primitives=[prim]), pose=np.asarray(m["pose"], float))
    cam = spec["camera"]
    znear, zfar = spec["znear"], spec["zfar"]
    if cam["kind"] == "opencv":
        k = np.asarray(cam["K"], float)
        # OpenCV puts pixel centres at integers, pyrender (OpenGL) at + 0.5; OpenCV's camera looks
        # down +z with y down, pyrender's down -z with y up.
        camera = pyrender.IntrinsicsCamera(fx=k[0, 0], fy=k[1, 1], cx=k[0, 2] + 0.5, cy=k[1, 2] + 0.5,
                                           znear=znear, zfar=zfar)
        world_to_cv = np.eye(4)
        world_to_cv[:3, :3], world_to_cv[:3, 3] = cam["R"], cam["t"]
        pose = np.linalg.inv(world_to_cv) @ GL_FROM_CV
    elif cam["kind"] == "perspective":
        camera = pyrender.PerspectiveCamera(yfov=cam["yfov"], znear=znear, zfar=zfar)
        pose = np.asarray(cam["pose"], float)
    else:
        camera = pyrender.OrthographicCamera(xmag=cam["xmag"], ymag=cam["ymag"], znear=znear, zfar=zfar)
        pose = np.asarray(cam["pose"], float)
    scene.add(camera, pose=pose)
    return scene


def texture_summary(tex):
    if tex is None:
        return None
    s = tex.sampler
    return {"source": np.array(tex.source), "channels": tex.source_channels, "name": tex.name,
            "sampler": (s.magFilter, s.minFilter, s.wrapS, s.wrapT)}


def summarize(scene):
    nodes = []
    for node in sorted(scene.mesh_nodes, key=lambda n: str(n.name)):
        prims = []
        for p in node.mesh.primitives:
            mat = p.material
            prims.append({
                "positions": np.array(p.positions), "normals": None if p.normals is None else np.array(p.normals),
                "indices": None if p.indices is None else np.array(p.indices),
                "color_0": None if p.color_0 is None else np.array(p.color_0),
                "texcoord_0": None if p.texcoord_0 is None else np.array(p.texcoord_0), "mode": p.mode,
                "material": {
                    "type": type(mat).__name__, "name": mat.name,
                    "baseColorFactor": np.array(mat.baseColorFactor), "metallicFactor": mat.metallicFactor,
                    "roughnessFactor": mat.roughnessFactor, "emissiveFactor": np.array(mat.emissiveFactor),
                    "doubleSided": mat.doubleSided, "alphaMode": mat.alphaMode, "alphaCutoff": mat.alphaCutoff,
                    "textures": {k: texture_summary(getattr(mat, k)) for k in (
                        "baseColorTexture", "emissiveTexture", "normalTexture", "metallicRoughnessTexture",
                        "occlusionTexture")}},
                "material_id": id(mat)})
        nodes.append({"name": node.name, "pose": scene.get_pose(node), "mesh_id": id(node.mesh),
                      "primitives": prims})
    lights = []
    for node in sorted(scene.light_nodes, key=lambda n: str(n.name)):
        li = node.light
        lights.append({"name": node.name, "type": type(li).__name__, "color": np.array(li.color),
                       "intensity": li.intensity, "pose": scene.get_pose(node),
                       "local": np.array(node.matrix),
                       "cones": (getattr(li, "innerConeAngle", None), getattr(li, "outerConeAngle", None)),
                       "parent": parent_name(scene, node)})
    cam = None
    if scene.main_camera_node is not None:
        c = scene.main_camera_node.camera
        cam = {"type": type(c).__name__, "pose": scene.get_pose(scene.main_camera_node),
               "name": scene.main_camera_node.name,
               **{k: getattr(c, k, None) for k in ("yfov", "aspectRatio", "xmag", "ymag", "fx", "fy", "cx",
                                                    "cy", "znear", "zfar")}}
    return {"nodes": nodes, "lights": lights, "camera": cam, "ambient": np.array(scene.ambient_light),
            "bg_color": np.array(scene.bg_color)}


def parent_name(scene, node):
    """The name of ``node``'s parent node, or None at the root (pyrender keeps the tree in a
    networkx graph whose edges point from child to parent, the root being "world")."""
    parent = next(iter(scene._digraph.successors(node)))
    return None if isinstance(parent, str) else parent.name


def run(job, renderers):
    result = {"warnings": [], "renders": {}, "summary": None, "back": None, "error": None}
    w, h = job["width"], job["height"]
    if (w, h) not in renderers:
        renderers[(w, h)] = pyrender.OffscreenRenderer(w, h)
    renderer = renderers[(w, h)]
    if "direct" in job:
        scene = direct_scene(job["direct"])
        color, depth = renderer.render(scene, flags=pyrender.RenderFlags.FLAT)
        result["renders"]["flat"] = (np.ascontiguousarray(color[..., :3]), np.ascontiguousarray(depth))
        return result
    import softrast as sr

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = sr.to_pyrender(job["scene"], job["camera"])
    result["warnings"] = [f"{type(c.message).__name__}: {c.message}" for c in caught]
    result["summary"] = summarize(scene)
    for mode in job.get("render", ()):
        flags = pyrender.RenderFlags.FLAT if mode == "flat" else pyrender.RenderFlags.NONE
        color, depth = renderer.render(scene, flags=flags)
        result["renders"][mode] = (np.ascontiguousarray(color[..., :3]), np.ascontiguousarray(depth))
    if job.get("back"):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result["back"] = sr.from_pyrender(scene, w, h)
        result["back_warnings"] = [str(c.message) for c in caught]
    return result


def main(parent_dir, jobs_path, out_dir):
    sys.path.insert(0, parent_dir)
    with open(jobs_path, "rb") as f:
        jobs = pickle.load(f)
    renderers = {}
    try:
        for job in jobs:
            try:
                result = run(job, renderers)
            except Exception:
                result = {"error": traceback.format_exc()}
            with open(os.path.join(out_dir, f"{job['name']}.pkl"), "wb") as f:
                pickle.dump(result, f)
    finally:
        for r in renderers.values():
            r.delete()


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3])
