"""softrast's ``pbr`` against pyrender 0.1.45 on Mesa's llvmpipe (OSMesa).

pyrender renders in a child process (tests/support/pyrender_child.py, PYOPENGL_PLATFORM=osmesa), so this
process never loads OpenGL; the same scene (camera, poses, lights, materials, normals, ambient
light, black background) is rendered by softrast here. softrast's linear ``radiance`` is encoded
as pyrender encodes it (``softrast.reference.encoding.pyrender_encode``: pow(c, 1/2.2), not sRGB) and
compared with pyrender's 8-bit colour on interior pixels: both masks set, eroded by 2 px
(pyrender rasterizes silhouettes by its own rule). Bounds (the promised ones): mean |diff| <= 3/255
and 99th percentile <= 8/255; the masks must agree on >= 99% of the pixels.

Scenes: a 4x4 grid of spheres over metallic x roughness under a directional and two point
lights with some ambient light; a GLB made with trimesh with three parts and three materials
(box, sphere, cylinder), loaded by softrast.load_scene and by pyrender.Scene.from_trimesh_scene.

Also printed, not asserted: softrast's own default ``color`` (exact sRGB curve) against
pyrender's bytes (gamma 2.2): how much the two encodings differ (run with -s to see it).

Needs pyrender 0.1.45, PyOpenGL >= 3.1.10 and Mesa's OSMesa: ``bash .ci/install --test``
installs them (or ``bash benchmarks/setup_baselines.sh``). Without them the test FAILS.
"""
from __future__ import annotations

import json
import math
import os
import pathlib

import numpy as np
import trimesh
from scipy import ndimage

import softrast as sr
from softrast.reference.encoding import pyrender_encode
from support.pyrender_runner import run_pyrender_child

CHILD = pathlib.Path(__file__).resolve().parent / "support" / "pyrender_child.py"
W, H = 320, 240
FOV_Y_DEG = 40.0
NEAR, FAR = 0.5, 30.0
ERODE_PX = 2
MEAN_MAX, P99_MAX, MASK_AGREE_MIN = 3.0, 8.0, 0.99  # bytes, bytes, fraction of pixels
# The child's environment: the sanitizer run (.ci/sanitize) preloads libasan / libstdc++ and
# sets ASan's options for its pytest; the pyrender child is plain Python + Mesa and loads no
# sanitized code, so it runs without them (llvmpipe under a preloaded ASan is neither needed nor
# supported).
_DROP_ENV = ("LD_PRELOAD", "ASAN_OPTIONS", "UBSAN_OPTIONS", "LSAN_OPTIONS", "SOFTRAST_ASAN")


def pose_towards(direction, position=(0.0, 0.0, 0.0)) -> np.ndarray:
    """A rigid pose whose -z axis points along ``direction``, placed at ``position``."""
    z = -np.asarray(direction, float)
    z /= np.linalg.norm(z)
    x = np.cross([0.3, 1.0, 0.1], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, y, z, position
    return pose


# One directional light and two point lights (pyrender's and softrast's fields are the same:
# colour and intensity; the point lights fall off as 1/r^2 in both).
LIGHTS = [
    ("directional", (1.0, 0.95, 0.9), 2.5, pose_towards((-0.4, -0.6, -1.0))),
    ("point", (1.0, 0.8, 0.6), 14.0, pose_towards((0, 0, -1), (2.6, 2.0, 3.0))),
    ("point", (0.5, 0.7, 1.0), 9.0, pose_towards((0, 0, -1), (-2.4, -1.6, 2.6))),
]
AMBIENT = (0.05, 0.05, 0.06)


def add_lights(scene: sr.Scene) -> list[dict]:
    spec = []
    for kind, color, intensity, pose in LIGHTS:
        light = (sr.DirectionalLight(color, intensity) if kind == "directional"
                 else sr.PointLight(color, intensity, falloff="inverse_square"))
        scene.add(light, pose=pose)
        spec.append({"kind": kind, "color": list(color), "intensity": intensity, "pose": pose.tolist()})
    return spec


def camera(eye, target=(0.0, 0.0, 0.0)) -> sr.PerspectiveCamera:
    return sr.PerspectiveCamera(fov_y=FOV_Y_DEG, near=NEAR, far=FAR).look_at(eye, target)


def render_pyrender(spec: dict, tmp_path: pathlib.Path) -> tuple[np.ndarray, np.ndarray]:
    spec = {"width": W, "height": H, "yfov": math.radians(FOV_Y_DEG), "znear": NEAR, "zfar": FAR, **spec}
    spec_path = tmp_path / "spec.json"
    spec_path.write_text(json.dumps(spec))
    out = tmp_path / "pyrender_out"
    out.mkdir()
    run_pyrender_child(CHILD, [spec_path, out], timeout=180,
                       env={k: v for k, v in os.environ.items() if k not in _DROP_ENV})
    return np.load(out / "color.npy"), np.load(out / "depth.npy")


def compare(name: str, scene: sr.Scene, cam: sr.PerspectiveCamera, pr_color: np.ndarray,
            pr_depth: np.ndarray, shading: str = "pbr", check: bool = True,
            p99_max: float = P99_MAX) -> float:
    """Asserts the bounds (unless ``check`` is False) and returns the mean |diff| in bytes."""
    frame = sr.Renderer(W, H).render(scene, cam, outputs=("radiance", "color", "depth"),
                                     shading=shading, background=(0.0, 0.0, 0.0))
    sr_mask = frame.depth > 0
    pr_mask = pr_depth > 0
    agree = float((sr_mask == pr_mask).mean())
    both = sr_mask & pr_mask
    inner = ndimage.binary_erosion(both, structure=np.ones((2 * ERODE_PX + 1,) * 2, bool))
    assert inner.sum() > 0.1 * both.sum(), f"{name}: too few interior pixels ({inner.sum()})"

    got = pr_color[inner].astype(np.int64)  # pyrender's bytes
    ours = pyrender_encode(frame.radiance[inner]).astype(np.int64)  # softrast, pyrender's gamma
    d = np.abs(ours - got)
    mean, p99, dmax = float(d.mean()), float(np.percentile(d, 99)), int(d.max())
    d_srgb = np.abs(frame.color[inner].astype(np.int64) - got)  # softrast's own sRGB bytes
    summary = (f"{name}: {int(inner.sum())} interior pixels; {shading} radiance in pyrender's encoding vs "
               f"pyrender: mean |diff| {mean:.3f}/255, p99 {p99:.1f}/255, max {dmax}/255, "
               f"{(d > 1).mean():.4%} of values off by > 1; masks agree on {agree:.4%} of pixels "
               f"(softrast {int(sr_mask.sum())}, pyrender {int(pr_mask.sum())} covered); "
               f"softrast's default sRGB colour vs pyrender's gamma 2.2 (not asserted): mean "
               f"{d_srgb.mean():.3f}/255, p99 {np.percentile(d_srgb, 99):.1f}/255, max {d_srgb.max()}/255")
    print(summary)
    if check:
        assert agree >= MASK_AGREE_MIN, f"masks disagree: {summary}"
        assert mean <= MEAN_MAX, f"mean |diff| above {MEAN_MAX}/255: {summary}"
        assert p99 <= p99_max, f"p99 |diff| above {p99_max}/255: {summary}"
    return mean


def test_sphere_grid_metallic_roughness(tmp_path: pathlib.Path) -> None:
    ico = trimesh.creation.icosphere(subdivisions=4, radius=0.42)
    positions = np.asarray(ico.vertices, np.float32)
    faces = np.asarray(ico.faces, np.int32)
    normals = np.asarray(ico.vertex_normals, np.float32)  # what pyrender's from_trimesh(smooth=True) uses
    arrays = tmp_path / "sphere.npz"
    np.savez(arrays, positions=positions, faces=faces, normals=normals)
    mesh = sr.Mesh(positions, faces, normals=normals)

    scene = sr.Scene(ambient_light=AMBIENT)
    spec_meshes = []
    base = (0.85, 0.55, 0.35, 1.0)
    for i, metallic in enumerate((0.0, 0.33, 0.67, 1.0)):
        for j, roughness in enumerate((0.1, 0.4, 0.7, 1.0)):
            pose = np.eye(4)
            pose[:3, 3] = (-1.5 + j, 1.5 - i, 0.0)
            scene.add(mesh, pose=pose, material=sr.Material(
                base_color=base, metallic=metallic, roughness=roughness, model="pbr"))
            spec_meshes.append({"arrays": str(arrays), "base": list(base), "metallic": metallic,
                                "roughness": roughness, "pose": pose.tolist()})
    spec_lights = add_lights(scene)
    cam = camera((0.3, 0.4, 6.5))
    pr_color, pr_depth = render_pyrender(
        {"ambient": list(AMBIENT), "lights": spec_lights, "meshes": spec_meshes,
         "camera_pose": cam.pose.tolist()}, tmp_path)
    compare("sphere grid", scene, cam, pr_color, pr_depth)


def make_glb(path: pathlib.Path) -> None:
    """Box, sphere and cylinder with three PBR materials (trimesh stores baseColorFactor as 8
    bits: both renderers read the same file). Normals are written to the file, so both use
    exactly those; the box is unmerged (flat faces)."""
    from trimesh.visual import TextureVisuals
    from trimesh.visual.material import PBRMaterial

    tscene = trimesh.Scene()

    def part(tm, name, base, metallic, roughness, offset):
        tm.visual = TextureVisuals(material=PBRMaterial(
            name=name, baseColorFactor=base, metallicFactor=metallic, roughnessFactor=roughness))
        transform = trimesh.transformations.rotation_matrix(0.5, (0.3, 1.0, 0.2))
        transform[:3, 3] = offset
        tscene.add_geometry(tm, geom_name=name, node_name=name, transform=transform)

    box = trimesh.creation.box(extents=(0.9, 0.9, 0.9))
    box.unmerge_vertices()
    part(box, "box", (0.8, 0.3, 0.2, 1.0), 0.0, 0.5, (-1.3, 0.0, 0.0))
    part(trimesh.creation.icosphere(subdivisions=4, radius=0.55), "ball", (0.95, 0.8, 0.35, 1.0),
         1.0, 0.3, (0.0, 0.1, 0.0))
    part(trimesh.creation.cylinder(radius=0.4, height=1.0, sections=64), "cylinder",
         (0.2, 0.5, 0.9, 1.0), 0.4, 0.75, (1.3, 0.0, 0.0))
    tscene.export(str(path), include_normals=True)


def test_gltf_several_materials(tmp_path: pathlib.Path) -> None:
    glb = tmp_path / "parts.glb"
    make_glb(glb)
    scene = sr.load_scene(glb)
    models = {inst.material.model for inst in scene}
    assert len(scene) == 3 and models == {"pbr"}, f"load_scene gave {len(scene)} parts, models {models}"
    scene.ambient_light = AMBIENT
    spec_lights = add_lights(scene)
    cam = camera((0.2, 1.2, 4.2))
    pr_color, pr_depth = render_pyrender(
        {"ambient": list(AMBIENT), "lights": spec_lights, "gltf": str(glb),
         "camera_pose": cam.pose.tolist()}, tmp_path)
    compare("glTF parts", scene, cam, pr_color, pr_depth)
