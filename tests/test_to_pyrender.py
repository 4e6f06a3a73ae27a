"""softrast.to_pyrender, and softrast's unlit colour, masks and depth against pyrender 0.1.45.

pyrender runs in a child process (tests/support/pyrender_to_child.py, PYOPENGL_PLATFORM=osmesa,
Mesa's llvmpipe), so this process never loads OpenGL; softrast scenes and cameras travel there
pickled.
Checked here:

* the unlit cross-check: scenes built in pyrender directly from plain arrays (several meshes,
  per-vertex colours and per-instance base colours; an OpenCV calibration K, R, t turned into
  pyrender's IntrinsicsCamera by the child's own reading of the conventions, a perspective and an
  orthographic camera; the same poses and near / far) rendered with RenderFlags.FLAT, against
  softrast's ``shading="unlit", srgb=False`` (FLAT writes the linear base colour times the
  vertex colour with no gamma, docs/pbr_notes.md). On interior pixels (covered in both, the same
  instance in the whole 3x3 neighbourhood) the colour is within 2/255; the masks differ only
  within 1 px of softrast's silhouette (each rasterizer's own rule for pixels a silhouette
  crosses); depth within 1e-5 relative (pyrender's 24-bit depth buffer is the limit;
  pyrender's orthographic depth is wrong, test_from_pyrender.py, so it is not compared);
* the round trip: a softrast scene (vertex colours, flat meshes without normals, shared meshes,
  Scene.add colour overrides, scaled, mirrored and sheared poses, a texture, four kinds of
  lights) -> to_pyrender -> pyrender renders, FLAT, as softrast renders it (same bounds), and
  lit, as softrast's ``pbr`` (in pyrender's gamma encoding, within 2/255, and 0.5/255 on average
  per instance);
* to_pyrender -> from_pyrender gives back the same world geometry, colours, uvs, normals,
  materials, textures, lights and camera (a pure conversion check);
* what to_pyrender builds (pyrender's attributes) and each warning for what does not convert.
The test FAILS (never skips) without pyrender and OSMesa: see test_pbr_vs_pyrender.py.
"""
from __future__ import annotations

import math
import os
import pathlib
import pickle
import subprocess
import sys

import numpy as np
import pytest
import trimesh
from scipy import ndimage

import softrast as sr
from softrast.reference.encoding import pyrender_encode
from support.pyrender_runner import INSTALL_HINT, run_pyrender_child

CHILD = pathlib.Path(__file__).resolve().parent / "support" / "pyrender_to_child.py"
W, H = 320, 240
NEAR, FAR = 0.5, 20.0
EYE, TARGET = (0.4, 0.9, 4.2), (0.0, 0.0, -0.2)
COLOR_TOL = 2  # bytes, unlit / FLAT
DEPTH_REL_TOL = 1e-5
# Lit, in pyrender's encoding (measured here: max 1/255, means per instance <= 0.13/255). Tighter
# than test_pbr_vs_pyrender.py's bounds (mean 3/255, p99 8/255) on purpose: a light left out
# (the camera-space one) moves the means per instance by 1.2-3.4/255.
LIT_MAX, LIT_INSTANCE_MEAN = 2, 0.5
GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])


def rigid(angle, axis, offset) -> np.ndarray:
    m = trimesh.transformations.rotation_matrix(angle, axis)
    m[:3, 3] = offset
    return m


def pose_towards(direction, position) -> np.ndarray:
    """A rigid pose at ``position`` whose -z axis points along ``direction``."""
    z = -np.asarray(direction, float)
    z /= np.linalg.norm(z)
    x = np.cross([0.3, 1.0, 0.1], z)
    x /= np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, np.cross(z, x), z, position
    return pose


def position_colors(positions: np.ndarray) -> np.ndarray:
    """Smoothly varying RGBA per vertex: red along x, green along y, blue along z."""
    p = np.asarray(positions, float)
    unit = (p - p.min(0)) / np.ptp(p, axis=0)
    return np.c_[0.1 + 0.85 * unit, np.ones(len(p))]


def sphere(radius=0.55):
    ico = trimesh.creation.icosphere(subdivisions=3, radius=radius)
    return np.asarray(ico.vertices), np.asarray(ico.faces), np.asarray(ico.vertex_normals)


def box(extents=(0.7, 0.6, 0.8)):
    b = trimesh.creation.box(extents=extents)
    return np.asarray(b.vertices), np.asarray(b.faces)


def cylinder():
    c = trimesh.creation.cylinder(radius=0.35, height=0.9, sections=48)
    return np.asarray(c.vertices), np.asarray(c.faces)


def textured_box(size=0.8):
    """A cube with its own uvs on each face (24 vertices): (0, 0) to (1, 1) across every face."""
    positions, uvs, faces = [], [], []
    h = size / 2
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u = np.zeros(3)
            u[(axis + 1) % 3] = 1.0
            v = np.cross(n, u)
            base = len(positions)
            for du, dv in ((0, 0), (1, 0), (1, 1), (0, 1)):
                positions.append(h * n + (2 * du - 1) * h * u + (2 * dv - 1) * h * v)
                uvs.append((du, dv))
            faces += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return np.array(positions), np.array(faces), np.array(uvs, float)


def gradient_texture() -> np.ndarray:
    """16 x 16 RGB uint8: red grows to the right, green downwards (rows), blue constant. Smooth,
    so filtering in sRGB (pyrender's FLAT) or linear space (softrast) differs by < 1/255."""
    j, i = np.meshgrid(np.arange(16), np.arange(16))
    return np.stack([40 + 12 * j, 30 + 13 * i, np.full_like(i, 120)], axis=-1).astype(np.uint8)


# -- the scenes ----------------------------------------------------------------------------------

def direct_meshes() -> list[dict]:
    """Four meshes as plain arrays: two with per-vertex colours, two with a base colour only."""
    sp, sf, _ = sphere()
    bp, bf = box()
    cp, cf = cylinder()
    return [
        {"positions": sp, "faces": sf, "colors": position_colors(sp), "base": (1.0, 1.0, 1.0, 1.0),
         "pose": rigid(0.4, (0, 1, 0), (-0.9, 0.25, 0.0))},
        {"positions": bp, "faces": bf, "colors": position_colors(bp)[:, [2, 0, 1, 3]],
         "base": (1.0, 1.0, 1.0, 1.0), "pose": rigid(0.6, (1, 1, 0), (0.8, 0.3, -0.4))},
        {"positions": cp, "faces": cf, "colors": None, "base": (0.85, 0.3, 0.2, 1.0),
         "pose": rigid(0.3, (1, 0, 0), (0.1, -0.6, 0.3))},
        {"positions": sp, "faces": sf, "colors": None, "base": (0.2, 0.5, 0.9, 1.0),
         "pose": rigid(0.0, (0, 1, 0), (0.25, 0.55, -1.3))},
    ]


def direct_softrast_scene(meshes: list[dict]) -> sr.Scene:
    scene = sr.Scene()
    for m in meshes:
        if m["colors"] is not None:
            scene.add(sr.Mesh(m["positions"], m["faces"], colors=m["colors"]), pose=m["pose"])
        else:
            scene.add(sr.Mesh(m["positions"], m["faces"]), pose=m["pose"], color=m["base"])
    return scene


def direct_cameras() -> dict[str, tuple[sr.Camera, dict]]:
    """softrast's camera and the child's description of the same camera, per kind."""
    calibrated = sr.IntrinsicsCamera(300.0, 295.0, 158.7, 121.3, W, H, near=NEAR, far=FAR).look_at(EYE, TARGET)
    k, r, t, _ = calibrated.to_opencv()
    opencv = sr.IntrinsicsCamera.from_opencv(k, r, t, W, H, near=NEAR, far=FAR)
    persp = sr.PerspectiveCamera(fov_y=42.0, near=NEAR, far=FAR).look_at(EYE, TARGET)
    ortho = sr.OrthographicCamera(xmag=2.0, ymag=1.5, near=NEAR, far=FAR).look_at(EYE, TARGET)
    return {
        "opencv": (opencv, {"kind": "opencv", "K": k, "R": r, "t": t}),
        "perspective": (persp, {"kind": "perspective", "yfov": math.radians(42.0), "pose": persp.pose}),
        "orthographic": (ortho, {"kind": "orthographic", "xmag": 2.0, "ymag": 1.5, "pose": ortho.pose}),
    }


SHEAR = np.array([[1.0, 0.35, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.2, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
TEXTURED = 8  # the textured instance of roundtrip_scene
VERTEX_COLORED = (0, 6)  # its instances with per-vertex colours


def roundtrip_scene() -> sr.Scene:
    sp, sf, sn = sphere(0.5)
    painted = sr.Mesh(sp, sf, normals=sn, colors=position_colors(sp),
                      material=sr.Material(model="pbr", metallic=0.2, roughness=0.5, name="painted"))
    bp, bf = box()
    flat_box = sr.Mesh(bp, bf)  # no normals: flat faces
    cp, cf = cylinder()
    brass = sr.Material(base_color=(0.8, 0.7, 0.2, 1.0), metallic=0.0, roughness=0.35, model="pbr", name="brass")
    cyl = sr.Mesh(cp, cf, material=brass)
    plain = sr.Mesh(sp, sf, normals=sn, color=(0.9, 0.5, 0.4))
    tp, tf, tuv = textured_box()
    tex = sr.Texture(gradient_texture(), filter="bilinear", wrap="clamp", uv_origin="top_left", name="gradient")
    card = sr.Mesh(tp, tf, uvs=tuv, material=sr.Material(base_color_texture=tex, base_color=(1.0, 1.0, 1.0, 1.0),
                                                           roughness=0.6, model="pbr", name="card"))
    scene = sr.Scene(ambient_light=(0.05, 0.05, 0.06))
    scene.add(painted, pose=rigid(0.4, (0, 1, 0), (-1.6, 1.1, 0.0)))                      # 0
    scene.add(flat_box, pose=rigid(0.6, (1, 1, 0), (0.0, 1.1, 0.0)), color=(0.25, 0.6, 0.9))  # 1
    scene.add(cyl, pose=rigid(0.3, (1, 0, 0), (1.6, 1.1, 0.0)))                             # 2
    scene.add(cyl, pose=rigid(-0.3, (1, 0, 1), (-1.6, 0.0, 0.0)), color=(0.6, 0.2, 0.7))    # 3
    scaled = rigid(0.5, (0, 0, 1), (0.0, 0.0, 0.0)) @ np.diag([1.4, 0.8, 1.0, 1.0])
    scene.add(plain, pose=scaled)                                                          # 4
    scene.add(plain, pose=rigid(0.0, (0, 1, 0), (1.6, 0.0, -0.3)))                         # 5
    mirrored = rigid(0.3, (0, 1, 0), (-1.6, -1.1, 0.0)) @ np.diag([-1.0, 1.0, 1.0, 1.0])
    scene.add(painted, pose=mirrored)                                                      # 6
    sheared = rigid(0.2, (0, 1, 0), (0.0, -1.1, 0.0)) @ SHEAR
    scene.add(flat_box, pose=sheared, color=(0.9, 0.8, 0.3))                               # 7
    scene.add(card, pose=rigid(0.7, (1, 1.5, 0.2), (1.6, -1.1, 0.0)))                      # 8
    scene.add(sr.DirectionalLight((1.0, 0.95, 0.9), 2.5), pose=pose_towards((-0.4, -0.6, -1.0), (0, 0, 0)))
    scene.add(sr.PointLight((1.0, 0.8, 0.6), 14.0), pose=pose_towards((0, 0, -1), (2.6, 2.0, 3.0)))
    scene.add(sr.SpotLight((0.5, 0.7, 1.0), 20.0, inner_cone=0.3, outer_cone=0.7),
              pose=pose_towards((0.0, -0.8, -1.0), (0.0, 2.4, 3.0)))
    scene.add(sr.PointLight((0.6, 0.6, 0.6), 3.0), pose=pose_towards((0, 0, -1), (0.5, 0.5, 0.0)),
              camera_space=True)
    return scene


def roundtrip_cameras() -> dict[str, sr.Camera]:
    eye, target = (0.3, 0.6, 5.5), (0.0, 0.0, 0.0)
    return {
        "perspective": sr.PerspectiveCamera(fov_y=45.0, near=NEAR, far=FAR).look_at(eye, target),
        "opencv": sr.IntrinsicsCamera(255.0, 262.0, 163.2, 117.9, W, H, near=NEAR, far=FAR).look_at(eye, target),
        "orthographic": sr.OrthographicCamera(xmag=3.2, ymag=2.4, width=W, height=H, near=NEAR,
                                              far=FAR).look_at(eye, target),
    }


def warning_scenes() -> dict[str, tuple[sr.Scene, sr.Camera | None]]:
    bp, bf = box()
    mesh = sr.Mesh(bp, bf)
    lights = sr.Scene()
    lights.add(mesh)
    lights.add(sr.PointLight((1, 1, 1), 2.0, falloff="none"), pose=rigid(0, (0, 1, 0), (0, 0, 3)))
    lights.add(sr.SpotLight((1, 1, 1), 2.0, outer_cone=0.5, falloff="none", shadows=True),
               pose=rigid(0, (0, 1, 0), (0, 0, 3)))
    lights.add(sr.DirectionalLight(), pose=np.eye(4), camera_space=True)
    many = sr.Scene()
    many.add(mesh)
    for k in range(5):
        many.add(sr.DirectionalLight(intensity=0.2), pose=rigid(0.1 * k, (1, 0, 0), (0, 0, 0)))
    dark = sr.Scene(ambient_light=(0.1, 0.1, 0.1))
    dark.add(mesh)
    rng = np.random.default_rng(7)
    tp, tf, tuv = textured_box()
    texture_material = sr.Material(
        model="blinn_phong", kd=(0.5, 0.4, 0.3), ks=(0.2, 0.2, 0.2), shininess=10.0, name="legacy",
        base_color_texture=sr.Texture((rng.random((8, 8, 4)) * 65535).astype(np.uint16), filter="anisotropic"),
        emissive_texture=sr.Texture(np.full((4, 4, 3), 0.5, np.float32), srgb=False, filter="nearest"),
        normal_texture=sr.Texture(rng.integers(0, 256, (4, 4, 3), dtype=np.uint8), filter="nearest"),
        normal_scale=2.0, normal_map_convention="directx",
        metallic_roughness_texture=sr.Texture(rng.integers(0, 256, (4, 4, 3), dtype=np.uint8), wrap=("repeat", "mirror")),
        occlusion_texture=sr.Texture(rng.integers(0, 256, (4, 4), dtype=np.uint8)), occlusion_strength=0.5,
        bump_texture=sr.Texture(rng.integers(0, 256, (4, 4), dtype=np.uint8)), alpha_mode="mask", alpha_cutoff=0.3)
    materials = sr.Scene()
    materials.add(sr.Mesh(tp, tf, uvs=tuv, material=texture_material))
    materials.add(sr.DirectionalLight())
    ortho = sr.OrthographicCamera(xmag=1.0, ymag=1.0, width=W, height=H).look_at((0, 0, 3), (0, 0, 0))
    prims = sr.Scene(ambient_light=(1.0, 1.0, 1.0))
    prims.add(mesh, instance_id=1)
    cloud = rng.uniform(-0.5, 0.5, (50, 3))
    prims.add(sr.Points(cloud, colors=rng.uniform(0, 1, (50, 3)), size=3.0), instance_id=4,
              pose=rigid(0.3, (0, 1, 0), (0.1, 0.2, 0.0)))
    prims.add(sr.Lines([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1], [1, 2]], color=(1.0, 0.0, 0.0),
                       width=2.0), instance_id=7, pose=np.diag([1.0, 1.0, -1.0, 1.0]))  # a mirror
    # alpha_mode "blend": a base colour alpha 0.5, vertex colours with alpha below 1, and alpha 1
    blend = sr.Scene()
    blend.add(sr.Mesh(bp, bf, material=sr.Material(base_color=(0.2, 0.4, 0.8, 0.5), metallic=0.0,
                                                   alpha_mode="blend", name="glass")))
    tints = np.c_[np.full((len(bp), 3), 0.5), np.linspace(0.25, 1.0, len(bp))]
    blend.add(sr.Mesh(bp, bf, colors=tints, material=sr.Material(alpha_mode="blend", name="tinted")),
              pose=rigid(0.0, (0, 1, 0), (1.0, 0.0, 0.0)))
    blend.add(sr.Mesh(bp, bf, material=sr.Material(alpha_mode="blend", name="clear")),
              pose=rigid(0.0, (0, 1, 0), (-1.0, 0.0, 0.0)))
    blend.add(sr.DirectionalLight())
    blend_cam = sr.PerspectiveCamera(fov_y=45.0, near=NEAR, far=FAR).look_at((0, 0, 5), (0, 0, 0))
    return {"warn_lights": (lights, None), "warn_many_lights": (many, None), "warn_no_lights": (dark, None),
            "warn_materials": (materials, ortho), "primitives": (prims, None), "blend": (blend, blend_cam)}


# -- running pyrender ----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def results(tmp_path_factory) -> dict[str, dict]:
    jobs = []
    meshes = direct_meshes()
    for kind, (_, desc) in direct_cameras().items():
        jobs.append({"name": f"direct_{kind}", "width": W, "height": H,
                     "direct": {"meshes": meshes, "camera": desc, "znear": NEAR, "zfar": FAR}})
    scene = roundtrip_scene()
    for kind, cam in roundtrip_cameras().items():
        jobs.append({"name": f"roundtrip_{kind}", "width": W, "height": H, "scene": scene, "camera": cam,
                     "render": ("flat", "lit"), "back": True})
    for name, (s, cam) in warning_scenes().items():
        jobs.append({"name": name, "width": W, "height": H, "scene": s, "camera": cam, "back": True})
    out = tmp_path_factory.mktemp("to_pyrender")
    jobs_path = out / "jobs.pkl"
    jobs_path.write_bytes(pickle.dumps(jobs))
    # The child imports softrast too: it keeps the environment (see test_from_pyrender.py).
    parent = str(pathlib.Path(sr.__file__).resolve().parent.parent)
    run_pyrender_child(CHILD, [parent, jobs_path, out], timeout=600)
    loaded = {}
    for job in jobs:
        result = pickle.loads((out / f"{job['name']}.pkl").read_bytes())
        assert result["error"] is None, f"{job['name']}: {result['error']}"
        loaded[job["name"]] = result
    return loaded


# -- comparing images ----------------------------------------------------------------------------

def silhouette_band(mask: np.ndarray) -> np.ndarray:
    """Pixels within 1 px (8-neighbourhood) of the mask's boundary."""
    full = np.ones((3, 3), bool)
    return ndimage.binary_dilation(mask, full) & ~ndimage.binary_erosion(mask, full, border_value=1)


def interior(frame: sr.Frame, pr_depth: np.ndarray) -> np.ndarray:
    """Covered in both renders, and the same instance in softrast's whole 3x3 neighbourhood."""
    ids = frame.instance_id
    same = (ndimage.maximum_filter(ids, size=3) == ndimage.minimum_filter(ids, size=3)) & (ids >= 0)
    both = frame.mask & (pr_depth > 0)
    return ndimage.binary_erosion(both, np.ones((3, 3), bool)) & same


def check_masks(name: str, sr_mask: np.ndarray, pr_depth: np.ndarray) -> int:
    pr_mask = pr_depth > 0
    differ = sr_mask != pr_mask
    outside = differ & ~silhouette_band(sr_mask)
    assert sr_mask.sum() > 8000, f"{name}: too little covered ({sr_mask.sum()} px)"
    assert not outside.any(), f"{name}: masks differ away from silhouettes at {np.argwhere(outside)[:5].tolist()}"
    return int(differ.sum())


def check_depth(name: str, frame: sr.Frame, pr_depth: np.ndarray, inner: np.ndarray) -> float:
    sr_d = frame.depth.astype(np.float64)[inner]
    rel = np.abs(sr_d - pr_depth.astype(np.float64)[inner]) / sr_d
    assert rel.max() <= DEPTH_REL_TOL, f"{name}: depth max rel {rel.max():.2e}"
    return float(rel.max())


def save_pair(folder: pathlib.Path, name: str, pr: np.ndarray, ours: np.ndarray) -> None:
    """pyrender | softrast side by side, for looking at (pytest's temporary directory)."""
    gap = np.full((pr.shape[0], 6, 3), 255, np.uint8)
    sr.imwrite(folder / f"{name}.png", np.concatenate([pr, gap, ours], axis=1))


# -- the unlit cross-check: pyrender scenes built directly ----------------------------------------

@pytest.mark.parametrize("kind", ["opencv", "perspective", "orthographic"])
def test_unlit_matches_pyrender_flat(results, kind: str, tmp_path: pathlib.Path) -> None:
    cam = direct_cameras()[kind][0]
    scene = direct_softrast_scene(direct_meshes())
    frame = sr.Renderer(W, H).render(scene, cam, outputs=("color", "depth", "mask", "instance_id"),
                                     shading="unlit", srgb=False)
    pr_color, pr_depth = results[f"direct_{kind}"]["renders"]["flat"]
    save_pair(tmp_path, f"direct_{kind}", pr_color, frame.color)
    name = f"direct {kind}"
    n_differ = check_masks(name, frame.mask, pr_depth)
    inner = interior(frame, pr_depth)
    assert inner.sum() > 0.7 * frame.mask.sum()
    assert set(np.unique(frame.instance_id[inner])) == {0, 1, 2, 3}  # every mesh is compared
    diff = np.abs(frame.color.astype(np.int64) - pr_color.astype(np.int64))[inner]
    msg = (f"{name}: {int(inner.sum())} interior pixels, colour max |diff| {diff.max()}/255 "
           f"({(diff > 0).any(-1).mean():.2%} differ), masks differ on {n_differ} silhouette pixels")
    if kind != "orthographic":  # pyrender's orthographic depth is wrong (test_from_pyrender.py)
        msg += f", depth max rel {check_depth(name, frame, pr_depth, inner):.2e}"
    print(msg)
    assert diff.max() <= COLOR_TOL, msg


# -- the round trip: softrast -> to_pyrender -> pyrender renders ----------------------------------

def softrast_renders(cam: sr.Camera) -> tuple[sr.Frame, sr.Frame, sr.Frame]:
    scene = roundtrip_scene()
    r = sr.Renderer(W, H)
    unlit = r.render(scene, cam, outputs=("color", "depth", "mask", "instance_id"), shading="unlit", srgb=False)
    # pyrender's FLAT samples the base colour texture without decoding sRGB; softrast's unlit
    # decodes it: with a white base colour, softrast's sRGB-encoded colour is the texel again.
    unlit_srgb = r.render(scene, cam, outputs=("color",), shading="unlit", srgb=True)
    lit = r.render(scene, cam, outputs=("radiance", "mask", "instance_id"), shading="pbr")
    return unlit, unlit_srgb, lit


@pytest.mark.parametrize("kind", ["perspective", "opencv", "orthographic"])
def test_roundtrip_flat_matches_softrast_unlit(results, kind: str, tmp_path: pathlib.Path) -> None:
    cam = roundtrip_cameras()[kind]
    result = results[f"roundtrip_{kind}"]
    assert result["warnings"] == []  # everything in this scene converts exactly
    unlit, unlit_srgb, _ = softrast_renders(cam)
    pr_color, pr_depth = result["renders"]["flat"]
    ours = np.where((unlit.instance_id == TEXTURED)[..., None], unlit_srgb.color, unlit.color)
    save_pair(tmp_path, f"roundtrip_{kind}_flat", pr_color, ours)
    name = f"round trip {kind} (FLAT)"
    n_differ = check_masks(name, unlit.mask, pr_depth)
    inner = interior(unlit, pr_depth)
    assert set(np.unique(unlit.instance_id[inner])) == set(range(9))
    diff = np.abs(ours.astype(np.int64) - pr_color.astype(np.int64))[inner]
    msg = (f"{name}: {int(inner.sum())} interior pixels, colour max |diff| {diff.max()}/255, "
           f"masks differ on {n_differ} silhouette pixels")
    if kind != "orthographic":
        msg += f", depth max rel {check_depth(name, unlit, pr_depth, inner):.2e}"
    print(msg)
    assert diff.max() <= COLOR_TOL, msg


@pytest.mark.parametrize("kind", ["perspective", "opencv"])
def test_roundtrip_lit_matches_softrast_pbr(results, kind: str, tmp_path: pathlib.Path) -> None:
    """Lights (directional, point, spot, camera-space), ambient light and materials convert:
    pyrender's lit render against softrast's pbr in pyrender's encoding, on the instances
    without vertex colours (pyrender multiplies its shaded colour by them: docs/pbr_notes.md)."""
    cam = roundtrip_cameras()[kind]
    _, _, lit = softrast_renders(cam)
    pr_color, pr_depth = results[f"roundtrip_{kind}"]["renders"]["lit"]
    ours = pyrender_encode(lit.radiance)
    save_pair(tmp_path, f"roundtrip_{kind}_lit", pr_color, ours)
    inner = interior(lit, pr_depth) & ~np.isin(lit.instance_id, VERTEX_COLORED)
    inner = ndimage.binary_erosion(inner, np.ones((3, 3), bool))  # test_pbr_vs_pyrender's 2 px
    diff = np.abs(ours.astype(np.int64) - pr_color.astype(np.int64))[inner]
    per = {int(i): float(np.abs(ours.astype(np.int64) - pr_color.astype(np.int64))[inner & (lit.instance_id == i)].mean())
           for i in np.unique(lit.instance_id[inner])}
    msg = (f"round trip {kind} (lit): {int(inner.sum())} pixels, mean |diff| {diff.mean():.3f}/255, "
           f"p99 {np.percentile(diff, 99):.1f}/255, max {diff.max()}/255; mean per instance "
           + ", ".join(f"{i}: {m:.2f}" for i, m in per.items()))
    print(msg)
    assert len(per) == 7
    assert diff.max() <= LIT_MAX and max(per.values()) <= LIT_INSTANCE_MEAN, msg


# -- what to_pyrender builds ---------------------------------------------------------------------

def test_what_to_pyrender_builds(results) -> None:
    scene = roundtrip_scene()
    cams = roundtrip_cameras()
    summary = results["roundtrip_opencv"]["summary"]
    nodes = summary["nodes"]
    assert [n["name"] for n in nodes] == [f"softrast instance {k} (id {k})" for k in range(9)]
    assert np.array_equal(summary["bg_color"], [0, 0, 0, 1])
    np.testing.assert_allclose(summary["ambient"], (0.05, 0.05, 0.06))
    insts = scene.instances
    for k, (node, inst) in enumerate(zip(nodes, insts)):
        baked = k in (6, 7)  # mirror, shear: baked into the vertices
        np.testing.assert_allclose(node["pose"], np.eye(4) if baked else inst.pose, atol=1e-12, err_msg=str(k))
        (prim,) = node["primitives"]
        assert prim["mode"] == 4 and prim["material"]["type"] == "MetallicRoughnessMaterial"
        indices = prim["indices"].astype(np.int64)  # pyrender keeps them as float32
        assert np.array_equal(indices, prim["indices"])
        corners = prim["positions"].astype(np.float64)[indices]
        want = inst.mesh.positions.astype(np.float64)[inst.mesh.faces]
        if baked:
            want = want @ inst.pose[:3, :3].T + inst.pose[:3, 3]
            if k == 6:
                want = want[:, ::-1]  # a mirror: the winding reversed
        np.testing.assert_allclose(corners, want, atol=1e-6, err_msg=str(k))
        if inst.mesh.colors is not None:
            np.testing.assert_array_equal(prim["color_0"][indices],
                                          inst.mesh.colors[inst.mesh.faces][:, ::-1 if k == 6 else 1])
            np.testing.assert_array_equal(prim["material"]["baseColorFactor"], (1, 1, 1, 1))
        else:
            assert prim["color_0"] is None
            np.testing.assert_allclose(prim["material"]["baseColorFactor"], inst.color, atol=1e-7)
        if inst.mesh.normals is None:  # unshared, one unit face normal per corner
            assert len(prim["positions"]) == 3 * inst.mesh.num_faces
            n = prim["normals"].reshape(-1, 3, 3)
            np.testing.assert_allclose(n[:, 0], n[:, 2])
            e = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
            face = np.cross(*e)
            np.testing.assert_allclose(n[:, 0], face / np.linalg.norm(face, axis=1, keepdims=True), atol=1e-6)
        mat = prim["material"]
        if inst.material is None:
            assert (mat["metallicFactor"], mat["roughnessFactor"], mat["doubleSided"]) == (0.0, 0.5, True)
        else:
            assert mat["name"] == inst.material.name and mat["doubleSided"] == inst.material.double_sided
            assert (mat["metallicFactor"], mat["roughnessFactor"]) == (inst.material.metallic, inst.material.roughness)
        assert mat["alphaMode"] == "OPAQUE"
    # a Mesh shared with the same material is one pyrender mesh; a colour override is not
    assert nodes[4]["mesh_id"] == nodes[5]["mesh_id"] and nodes[2]["mesh_id"] != nodes[3]["mesh_id"]
    np.testing.assert_allclose(nodes[3]["primitives"][0]["material"]["baseColorFactor"], (0.6, 0.2, 0.7, 1.0))
    tex = nodes[TEXTURED]["primitives"][0]["material"]["textures"]["baseColorTexture"]
    expected = np.concatenate([gradient_texture(), np.full((16, 16, 1), 255, np.uint8)], axis=2)[::-1]
    np.testing.assert_array_equal(tex["source"], expected)  # top_left: flipped for pyrender's uvs
    assert tex["channels"] == "RGBA" and tex["sampler"] == (9729, 9729, 33071, 33071) and tex["name"] == "gradient"
    card = nodes[TEXTURED]["primitives"][0]  # no normals: unshared, so uvs per corner
    np.testing.assert_array_equal(card["texcoord_0"][card["indices"].astype(np.int64)],
                                  insts[TEXTURED].mesh.uvs[insts[TEXTURED].mesh.faces])

    lights = summary["lights"]
    assert [li["type"] for li in lights] == ["DirectionalLight", "PointLight", "SpotLight", "PointLight"]
    for li, src in zip(lights, scene.lights):
        assert li["intensity"] == src.light.intensity
        np.testing.assert_allclose(li["color"], src.light.color, atol=1e-7)
        world = (np.linalg.inv(cams["opencv"].view_matrix()) @ src.pose) if src.camera_space else src.pose
        np.testing.assert_allclose(li["pose"], world, atol=1e-12)
        assert li["parent"] == ("camera" if src.camera_space else None)
    assert lights[2]["cones"] == (0.3, 0.7)

    for kind, cam in cams.items():
        c = results[f"roundtrip_{kind}"]["summary"]["camera"]
        assert (c["znear"], c["zfar"]) == (NEAR, FAR)
        gl_pose = cam.pose @ GL_FROM_CV if cam.convention == "opencv" else cam.pose
        np.testing.assert_allclose(c["pose"], gl_pose, atol=1e-12)  # pyrender: via a quaternion
        if kind == "perspective":
            assert c["type"] == "PerspectiveCamera" and c["yfov"] == math.radians(45.0) and c["aspectRatio"] is None
        elif kind == "opencv":  # pyrender's principal point is OpenCV's + 0.5
            assert c["type"] == "IntrinsicsCamera"
            assert (c["fx"], c["fy"]) == (255.0, 262.0)
            assert (c["cx"], c["cy"]) == (pytest.approx(163.7, rel=1e-15), pytest.approx(118.4, rel=1e-15))
        else:
            assert c["type"] == "OrthographicCamera" and (c["xmag"], c["ymag"]) == (3.2, 2.4)


def world_corners(inst) -> np.ndarray:
    p = inst.mesh.positions.astype(np.float64)[inst.mesh.faces]
    return p @ inst.pose[:3, :3].T + inst.pose[:3, 3]


def world_normals(inst) -> np.ndarray:
    """Unit world normals per corner (flat meshes: the face normal)."""
    m3 = inst.pose[:3, :3]
    if inst.mesh.normals is None:
        c = world_corners(inst)
        n = np.repeat(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])[:, None], 3, axis=1)
        if np.linalg.det(m3) < 0:  # softrast flips the facing of a mirrored pose
            n = -n
    else:
        n = inst.mesh.normals.astype(np.float64)[inst.mesh.faces] @ np.linalg.inv(m3)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


@pytest.mark.parametrize("kind", ["perspective", "opencv", "orthographic"])
def test_to_pyrender_then_from_pyrender_gives_the_scene_back(results, kind: str) -> None:
    scene, cam = roundtrip_scene(), roundtrip_cameras()[kind]
    back, back_cam = results[f"roundtrip_{kind}"]["back"]
    assert results[f"roundtrip_{kind}"]["back_warnings"] == []
    assert len(back) == len(scene)
    for k, (a, b) in enumerate(zip(scene, back)):
        mirrored = np.linalg.det(a.pose[:3, :3]) < 0
        order = slice(None, None, -1) if mirrored else slice(None)
        np.testing.assert_allclose(world_corners(b), world_corners(a)[:, order], atol=2e-6, err_msg=str(k))
        np.testing.assert_allclose(world_normals(b), world_normals(a)[:, order], atol=2e-6, err_msg=str(k))
        for attr in ("colors", "uvs"):
            va, vb = getattr(a.mesh, attr), getattr(b.mesh, attr)
            assert (va is None) == (vb is None), (k, attr)
            if va is not None:
                np.testing.assert_array_equal(vb[b.mesh.faces], va[a.mesh.faces][:, order], err_msg=f"{k} {attr}")
        ma, mb = a.material, b.material
        assert mb.model == "pbr"
        if a.mesh.colors is None:
            np.testing.assert_allclose(mb.base_color, a.color, atol=1e-7)
        assert (mb.metallic, mb.roughness) == pytest.approx((0.0, 0.5) if ma is None else (ma.metallic, ma.roughness))
        assert mb.double_sided == (True if ma is None else ma.double_sided)
        assert (mb.alpha_mode, mb.emissive, mb.name) == ("opaque", (0.0, 0.0, 0.0), None if ma is None else ma.name)
        if ma is not None and ma.base_color_texture is not None:
            ta, tb = ma.base_color_texture, mb.base_color_texture
            assert (tb.filter, tb.wrap, tb.uv_origin) == (ta.filter, ta.wrap, "bottom_left")
            np.testing.assert_array_equal(tb.image[::-1, :, :3], ta.image)  # sampled alike at every uv
    assert len(back.lights) == len(scene.lights)
    for a, b in zip(scene.lights, back.lights):
        assert type(b.light) is type(a.light) and not b.camera_space
        assert (b.light.color, b.light.intensity) == (pytest.approx(a.light.color), a.light.intensity)
        assert getattr(b.light, "falloff", None) == getattr(a.light, "falloff", None)
        assert getattr(b.light, "outer_cone", None) == getattr(a.light, "outer_cone", None)
        world = np.linalg.inv(cam.view_matrix()) @ a.pose if a.camera_space else a.pose
        np.testing.assert_allclose(b.pose, world, atol=1e-12)
    assert back.ambient_light == pytest.approx(scene.ambient_light)
    assert type(back_cam) is type(cam) and (back_cam.near, back_cam.far) == (NEAR, FAR)
    if kind == "opencv":  # back as convention "opengl": the same calibration
        assert back_cam.convention == "opengl"
        for x, y in zip(back_cam.to_opencv(), cam.to_opencv()):
            np.testing.assert_allclose(x, y, atol=1e-12)
    else:
        np.testing.assert_allclose(back_cam.pose, cam.pose, atol=1e-12)
        if kind == "perspective":
            assert back_cam.fov_y == pytest.approx(45.0, rel=1e-15) and back_cam.aspect is None
        else:
            assert (back_cam.xmag, back_cam.ymag) == (3.2, 2.4)
    # and softrast renders the converted-back scene as the original
    r = sr.Renderer(W, H)
    one = r.render(scene, cam, outputs=("color", "depth"), shading="unlit", srgb=False)
    two = r.render(back, back_cam, outputs=("color", "depth"), shading="unlit", srgb=False)
    both = (one.depth > 0) & (two.depth > 0)
    color_diff = np.abs(one.color.astype(int) - two.color.astype(int)).max(-1)[both]
    print(f"{kind}: softrast, original vs converted back: masks differ on "
          f"{int(((one.depth > 0) != (two.depth > 0)).sum())} px, colour differs on {int((color_diff > 0).sum())} "
          f"of {int(both.sum())} px (max {color_diff.max()}/255)")
    # measured: masks equal, colour off by 1/255 on at most 1 pixel (baked poses: float32 vertices)
    assert ((one.depth > 0) != (two.depth > 0)).sum() <= 5 and color_diff.max() <= 1


# -- warnings ----------------------------------------------------------------------------------

def test_lights_that_do_not_convert_warn(results) -> None:
    w = results["warn_lights"]["warnings"]
    assert len(w) == 4, w
    assert "light 0 (PointLight): falloff='none' is not converted" in w[0]
    assert "light 1 (SpotLight): falloff='none' is not converted" in w[1]
    assert "light 1 (SpotLight) casts shadows ('exact')" in w[2] and "SHADOWS_SPOT" in w[2]
    assert "light 2 (DirectionalLight) is in camera space" in w[3] and "not converted" in w[3]
    assert all(x.startswith("UserWarning: to_pyrender: ") for x in w)
    lights = results["warn_lights"]["summary"]["lights"]
    assert [li["type"] for li in lights] == ["PointLight", "SpotLight"]  # converted, 1/r^2 anyway
    (many,) = results["warn_many_lights"]["warnings"]
    assert "5 DirectionalLights" in many and "at most 4" in many
    (dark,) = results["warn_no_lights"]["warnings"]
    assert "no lights" in dark and "headlight" in dark
    np.testing.assert_allclose(results["warn_no_lights"]["summary"]["ambient"], (0.1, 0.1, 0.1))


def test_lines_and_points_convert_both_ways(results) -> None:
    # Points -> GL_POINTS and lines -> GL_LINES primitives with their colours and poses (a
    # mirror baked into the positions); size and width, which pyrender cannot hold, warn; and
    # from_pyrender gives them back as Points and Lines at the same world positions.
    result = results["primitives"]
    w = "\n".join(result["warnings"])
    assert "points 0 (id 4): size 3 is not converted" in w
    assert "lines 1 (id 7): width 2 is not converted" in w
    assert "lines and points are unlit in softrast" in w
    nodes = {n["name"]: n for n in result["summary"]["nodes"]}
    (points,) = nodes["softrast points 0 (id 4)"]["primitives"]
    (lines,) = nodes["softrast lines 1 (id 7)"]["primitives"]
    assert points["mode"] == 0 and lines["mode"] == 1
    scene = warning_scenes()["primitives"][0]
    src_points, src_lines = (p.item for p in scene.primitives)
    np.testing.assert_allclose(points["positions"], src_points.positions, atol=1e-6)
    np.testing.assert_allclose(points["color_0"][:, :3], src_points.colors, atol=1e-6)
    pose = np.asarray(nodes["softrast points 0 (id 4)"]["pose"])
    np.testing.assert_allclose(pose, scene.primitives[0].pose, atol=1e-12)
    mirrored = src_lines.positions[src_lines.segments.reshape(-1)] * [1.0, 1.0, -1.0]
    np.testing.assert_allclose(lines["positions"], mirrored, atol=1e-6)
    np.testing.assert_allclose(lines["color_0"][:, :3], np.tile([1.0, 0.0, 0.0], (4, 1)))
    back = result["back"][0]
    kinds = {type(p.item).__name__: p for p in back.primitives}
    assert set(kinds) == {"Points", "Lines"} and len(back.instances) == 1
    world = kinds["Points"].item.positions @ kinds["Points"].pose[:3, :3].T + kinds["Points"].pose[:3, 3]
    expect = src_points.positions @ scene.primitives[0].pose[:3, :3].T + scene.primitives[0].pose[:3, 3]
    np.testing.assert_allclose(world, expect, atol=1e-5)
    np.testing.assert_allclose(kinds["Lines"].item.positions[kinds["Lines"].item.segments.reshape(-1)],
                               mirrored, atol=1e-6)


def test_materials_and_textures_that_do_not_convert_warn(results) -> None:
    result = results["warn_materials"]
    w = "\n".join(result["warnings"])
    expected = [
        "material 'legacy' (instance 0): shading model 'blinn_phong' is not converted",
        "material 'legacy' (instance 0): kd, ks, shininess not converted",
        "bump_texture is not converted",
        "normal_scale 2.0 is not converted",
        "occlusion_strength 0.5 is not converted",
        "alpha_mode 'mask' is converted to alphaMode 'MASK' (alphaCutoff 0.3)",
        "base_color_texture (uint16, sRGB) is stored as 8-bit sRGB values",
        "emissive_texture (float32, linear) is stored as 8-bit sRGB values",
        "base_color_texture's filter 'anisotropic' is not converted",
        "camera: xmag / ymag (1.0 / 1.0) differs from the image's aspect (320 x 240)",
    ]
    for text in expected:
        assert text in w, f"{text!r} not in:\n{w}"
    assert len(result["warnings"]) == len(expected), w
    (node,) = result["summary"]["nodes"]
    mat = node["primitives"][0]["material"]
    assert (mat["alphaMode"], mat["alphaCutoff"]) == ("MASK", 0.3)
    src = warning_scenes()["warn_materials"][0].instances[0].material
    tex = mat["textures"]
    # uint16 sRGB -> 8-bit sRGB: rounded
    np.testing.assert_array_equal(tex["baseColorTexture"]["source"],
                                  np.floor(src.base_color_texture.image / 65535.0 * 255.0 + 0.5).astype(np.uint8))
    assert tex["baseColorTexture"]["sampler"][:2] == (9729, 9987)  # anisotropic -> trilinear
    # linear float emissive (srgb=False) -> sRGB bytes, as pyrender decodes its emissive slot
    enc = 1.055 * 0.5 ** (1 / 2.4) - 0.055
    assert np.all(tex["emissiveTexture"]["source"] == math.floor(enc * 255 + 0.5))
    assert tex["emissiveTexture"]["sampler"][:2] == (9728, 9728)
    # a DirectX normal map: green inverted
    n_src = src.normal_texture.image
    np.testing.assert_array_equal(tex["normalTexture"]["source"],
                                  np.stack([n_src[..., 0], 255 - n_src[..., 1], n_src[..., 2]], axis=-1))
    # metallic-roughness: pyrender keeps G and B; wraps per axis
    mr = tex["metallicRoughnessTexture"]
    np.testing.assert_array_equal(mr["source"], src.metallic_roughness_texture.image[..., 1:3])
    assert mr["channels"] == "GB" and mr["sampler"][2:] == (10497, 33648)
    np.testing.assert_array_equal(tex["occlusionTexture"]["source"], src.occlusion_texture.image[..., 0])
    # ...and from_pyrender reads them back in the same slots (metallic-roughness as (0, G, B))
    back, _ = result["back"]
    mb = back.instances[0].material
    np.testing.assert_array_equal(mb.metallic_roughness_texture.image[..., 1:],
                                  src.metallic_roughness_texture.image[..., 1:3])
    assert (mb.metallic_roughness_texture.image[..., 0] == 0).all()
    np.testing.assert_array_equal(mb.occlusion_texture.image[..., 0], src.occlusion_texture.image[..., 0])
    assert mb.bump_texture is None and (mb.alpha_mode, mb.alpha_cutoff) == ("mask", pytest.approx(0.3))


def test_blend_converts_to_blend_and_back(results) -> None:
    """alpha_mode "blend" -> alphaMode "BLEND" without a warning (the alpha in baseColorFactor,
    or in color_0 for a mesh with vertex colours), and from_pyrender reads "BLEND" with an alpha
    below 1 back as "blend"; at alpha 1 it reads it back opaque (as softrast draws a blended
    draw whose one alpha is 1). How pyrender's blending compares: test_blend_vs_pyrender.py."""
    result = results["blend"]
    assert result["warnings"] == [], result["warnings"]
    prims = {node["primitives"][0]["material"]["name"]: node["primitives"][0]
             for node in result["summary"]["nodes"]}
    assert {name: p["material"]["alphaMode"] for name, p in prims.items()} == {
        "glass": "BLEND", "tinted": "BLEND", "clear": "BLEND"}
    np.testing.assert_allclose(prims["glass"]["material"]["baseColorFactor"], (0.2, 0.4, 0.8, 0.5), atol=1e-7)
    np.testing.assert_array_equal(prims["tinted"]["material"]["baseColorFactor"], (1, 1, 1, 1))
    source = warning_scenes()["blend"][0].instances[1].mesh
    tinted = prims["tinted"]
    np.testing.assert_allclose(tinted["color_0"][tinted["indices"].astype(np.int64)],
                               source.colors[source.faces], atol=1e-7)
    back, _ = result["back"]
    assert result["back_warnings"] == []
    got = {inst.material.name: inst.material.alpha_mode for inst in back.instances}
    assert got == {"glass": "blend", "tinted": "blend", "clear": "opaque"}


# -- importing -----------------------------------------------------------------------------------

BUILD_WITHOUT_DISPLAY = r"""
import sys
sys.path.insert(0, sys.argv[1])
import softrast as sr
assert "pyrender" not in sys.modules and "OpenGL" not in sys.modules
scene = sr.Scene()
scene.add(sr.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]))
scene.add(sr.DirectionalLight())
pr = sr.to_pyrender(scene, sr.PerspectiveCamera(fov_y=50.0))
assert len(pr.mesh_nodes) == 1 and len(pr.light_nodes) == 1 and pr.main_camera_node is not None
print("built", type(pr).__module__)
"""


def test_to_pyrender_needs_no_display() -> None:
    """Building a pyrender scene imports pyrender (lazily: not at import softrast) but opens no
    display and no OpenGL context: it works with DISPLAY unset and no PYOPENGL_PLATFORM."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "PYOPENGL_PLATFORM")}
    parent = str(pathlib.Path(sr.__file__).resolve().parent.parent)
    proc = subprocess.run([sys.executable, "-W", "error", "-c", BUILD_WITHOUT_DISPLAY, parent], env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:] + INSTALL_HINT
    assert proc.stdout.strip() == "built pyrender.scene"
