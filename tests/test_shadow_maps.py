"""Shadow maps (a light's ``shadows="map"``): against the exact method and against pyrender.

A shadow map approximates the exact shadow: it sees the occluders from the light at a finite
resolution, filters its comparisons (pyrender's 3 x 3 bilinear percentage-closer filter) and
needs a bias. So the checks are agreements of shadow masks away from shadow edges (pixels
within 2 px of either mask's edge are left out, where filtering and resolution legitimately
differ), on a floor with a sphere and a box above it:

* softrast's map agrees with softrast's exact shadows on >= 99% of the compared pixels, for a
  directional light, a spot light and a point light (a cube map; pyrender has no point light
  shadows);
* softrast's map agrees with pyrender 0.1.45's ``RenderFlags.SHADOWS_DIRECTIONAL`` and
  ``SHADOWS_SPOT`` (its shadow maps, on Mesa's llvmpipe) on >= 98%;
* maps follow ``shadow_resolution`` (coarser maps still agree, a 1-texel map sees nothing to
  shadow); bad ``shadow_resolution`` / ``shadow_bias`` raise;
* the same bits across thread counts and instruction sets.

A pixel is "in shadow" when the light's contribution drops below half: its radiance (or
pyrender's byte) is below the mean of the render without shadows and the render with the light
at intensity 0. Only pixels the light reaches by at least 10% of its full contribution without
shadows are compared (the light's own terminator is no shadow).

The pyrender part FAILS (never skips) without pyrender and OSMesa: see test_pbr_vs_pyrender.py.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from scipy import ndimage

import softrast as sr
from support.pyrender_runner import run_pyrender_script

W, H = 200, 150
NEAR, FAR = 0.1, 50.0
EYE, TARGET = (3.0, 3.5, 4.0), (0.0, 0.3, 0.0)
AMBIENT = (0.1, 0.1, 0.1)


LIGHTS = {
    "directional": dict(pose=sr.look_at_pose((-2.5, 3.0, -1.5), (0.0, 0.0, 0.0)), intensity=3.0),
    "spot": dict(pose=sr.look_at_pose((-1.5, 3.5, 1.5), (0.2, 0.0, 0.0)), intensity=40.0,
                 inner=0.3, outer=0.7),
    "point": dict(pose=sr.look_at_pose((-1.0, 2.5, 1.2), (0.0, 0.0, 0.0)), intensity=25.0),
}


def meshes() -> list[dict]:
    """Plain arrays for both renderers: a floor, a sphere and a box (world space, pose I)."""
    floor = {"positions": np.array([[-4.0, 0.0, -4.0], [4.0, 0.0, -4.0], [4.0, 0.0, 4.0],
                                    [-4.0, 0.0, 4.0]]),
             "faces": np.array([[0, 2, 1], [0, 3, 2]]), "color": (0.8, 0.8, 0.8)}
    floor["normals"] = np.tile([0.0, 1.0, 0.0], (4, 1))
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    ball.apply_translation((0.0, 0.9, 0.0))
    box = trimesh.creation.box(extents=(0.6, 0.6, 0.6))
    box.apply_translation((1.2, 0.3, 0.4))
    box = box.subdivide()  # (vertex normals of a box are averaged; faces stay flat enough)
    out = [floor]
    for tm, color in ((ball, (0.9, 0.5, 0.4)), (box, (0.4, 0.6, 0.9))):
        out.append({"positions": np.asarray(tm.vertices, float), "faces": np.asarray(tm.faces),
                    "normals": np.asarray(tm.vertex_normals, float), "color": color})
    return out


def camera() -> sr.PerspectiveCamera:
    return sr.PerspectiveCamera(fov_y=45.0, width=W, height=H, near=NEAR, far=FAR).look_at(EYE, TARGET)


def softrast_scene(kind: str, intensity_scale: float = 1.0, **light_kw) -> sr.Scene:
    scene = sr.Scene(ambient_light=AMBIENT)
    for m in meshes():
        mat = sr.Material(base_color=m["color"], metallic=0.0, roughness=1.0, model="pbr")
        scene.add(sr.Mesh(m["positions"], m["faces"], normals=m["normals"], material=mat))
    spec = LIGHTS[kind]
    intensity = spec["intensity"] * intensity_scale
    if kind == "directional":
        light = sr.DirectionalLight(intensity=intensity, **light_kw)
    elif kind == "spot":
        light = sr.SpotLight(intensity=intensity, inner_cone=spec["inner"], outer_cone=spec["outer"],
                             **light_kw)
    else:
        light = sr.PointLight(intensity=intensity, **light_kw)
    scene.add(light, pose=spec["pose"])
    return scene


def radiance(kind: str, shadows, intensity_scale: float = 1.0, threads: int = 2, simd: bool = True,
             **light_kw) -> np.ndarray:
    scene = softrast_scene(kind, intensity_scale, **light_kw)
    frame = sr.Renderer(W, H, threads=threads, simd=simd).render(
        scene, camera(), outputs=("radiance",), shadows=shadows)
    return frame.radiance.astype(np.float64).sum(-1)


def shadow_mask(lit: np.ndarray, shadowed: np.ndarray, dark: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(in shadow, compared): the light's contribution below half; compared where it reaches by
    at least 10% of the brightest contribution without shadows."""
    direct = lit - dark
    compared = direct > 0.1 * direct.max()
    return shadowed < 0.5 * (lit + dark), compared


def agreement(a: np.ndarray, b: np.ndarray, compared: np.ndarray) -> tuple[float, int]:
    """The share of compared pixels where masks a and b agree, away from both masks' edges
    (2 px), and how many pixels were compared."""
    edges = np.zeros_like(a)
    for m in (a, b):
        edges |= ndimage.binary_dilation(m, iterations=2) & ndimage.binary_dilation(~m, iterations=2)
    sel = compared & ~edges
    return float((a[sel] == b[sel]).mean()), int(sel.sum())


@pytest.mark.parametrize("kind", ["directional", "spot", "point"])
def test_map_agrees_with_exact(kind):
    lit = radiance(kind, False)
    dark = radiance(kind, False, intensity_scale=0.0)
    exact, compared = shadow_mask(lit, radiance(kind, "exact"), dark)
    mapped, _ = shadow_mask(lit, radiance(kind, "map"), dark)
    assert exact[compared].mean() > 0.03, "the scene casts too little shadow to compare"
    share, n = agreement(exact, mapped, compared)
    print(f"{kind}: map vs exact agree on {share:.4%} of {n} px")
    assert n > 0.3 * compared.sum() and share >= 0.99, (share, n)


def test_resolution_and_bad_values():
    lit = radiance("directional", False)
    dark = radiance("directional", False, intensity_scale=0.0)
    exact, compared = shadow_mask(lit, radiance("directional", "exact"), dark)
    coarse, _ = shadow_mask(lit, radiance("directional", "map", shadow_resolution=256), dark)
    share, _ = agreement(exact, coarse, compared)
    assert share >= 0.97, share
    # One texel sees the occluders' nearest depth over the whole map: it cannot tell the floor
    # from what is above it, so with the bias the floor is lit (no shadow anywhere on it).
    one = radiance("directional", "map", shadow_resolution=1)
    assert (np.abs(one - lit) <= 1e-6 * np.maximum(lit, 1e-6)).mean() > 0.5
    for bad in (0, -1, 16385):
        with pytest.raises(ValueError, match="shadow_resolution"):
            sr.SpotLight(shadows="map", shadow_resolution=bad)
    for bad in (-0.1, math.inf, math.nan):
        with pytest.raises(ValueError, match="shadow_bias"):
            sr.PointLight(shadows="map", shadow_bias=bad)
    with pytest.raises(ValueError, match="shadows"):
        sr.DirectionalLight(shadows="maps")


@pytest.mark.parametrize("kind", ["spot", "directional"])
def test_map_same_bits_for_threads_and_instruction_sets(kind):
    ref = radiance(kind, "map", threads=1, simd=True)
    for threads, simd in ((2, True), (3, True), (1, False), (3, False)):
        got = radiance(kind, "map", threads=threads, simd=simd)
        assert got.tobytes() == ref.tobytes(), (threads, simd)


# ------------------------------------------------------------------------------------- pyrender

CHILD = r"""
import pickle, sys
sys.path.insert(0, sys.argv[1])  # tests/: support.pyrender_env (PYOPENGL_PLATFORM, np.infty)
from support.pyrender_env import import_pyrender
import numpy as np
pyrender, trimesh = import_pyrender("shadow maps child")

with open(sys.argv[3], "rb") as f:
    job = pickle.load(f)
renderer = pyrender.OffscreenRenderer(job["width"], job["height"])
out = {}
for kind, light in job["lights"].items():
    for name, (intensity, shadows) in {"lit": (1.0, False), "shadowed": (1.0, True),
                                        "dark": (0.0, False)}.items():
        scene = pyrender.Scene(ambient_light=job["ambient"], bg_color=[0.0, 0.0, 0.0, 1.0])
        for m in job["meshes"]:
            material = pyrender.MetallicRoughnessMaterial(
                baseColorFactor=list(m["color"]) + [1.0], metallicFactor=0.0, roughnessFactor=1.0)
            prim = pyrender.Primitive(positions=m["positions"], normals=m["normals"],
                                      indices=m["faces"], material=material)
            scene.add(pyrender.Mesh(primitives=[prim]))
        if kind == "directional":
            pl = pyrender.DirectionalLight(intensity=light["intensity"] * intensity)
            flags = pyrender.RenderFlags.SHADOWS_DIRECTIONAL if shadows else pyrender.RenderFlags.NONE
        else:
            pl = pyrender.SpotLight(intensity=light["intensity"] * intensity,
                                    innerConeAngle=light["inner"], outerConeAngle=light["outer"])
            flags = pyrender.RenderFlags.SHADOWS_SPOT if shadows else pyrender.RenderFlags.NONE
        scene.add(pl, pose=light["pose"])
        cam = job["camera"]
        scene.add(pyrender.PerspectiveCamera(yfov=cam["yfov"], znear=cam["znear"], zfar=cam["zfar"],
                                             aspectRatio=job["width"] / job["height"]),
                  pose=cam["pose"])
        color, _ = renderer.render(scene, flags=flags)
        out[(kind, name)] = np.ascontiguousarray(color[..., :3])
renderer.delete()
with open(sys.argv[4], "wb") as f:
    pickle.dump(out, f)
"""


@pytest.fixture(scope="module")
def pyrender_images(tmp_path_factory) -> dict:
    cam = camera()
    job = {"width": W, "height": H, "ambient": list(AMBIENT), "meshes": meshes(),
           "lights": {k: LIGHTS[k] for k in ("directional", "spot")},
           "camera": {"yfov": math.radians(45.0), "znear": NEAR, "zfar": FAR, "pose": cam.pose}}
    return run_pyrender_script(tmp_path_factory.mktemp("shadow_maps"), "shadow_maps_child",
                               CHILD, job)


@pytest.mark.parametrize("kind", ["directional", "spot"])
def test_map_agrees_with_pyrender(kind, pyrender_images):
    ours_lit = radiance(kind, False)
    ours_dark = radiance(kind, False, intensity_scale=0.0)
    ours, compared = shadow_mask(ours_lit, radiance(kind, "map"), ours_dark)
    img = {name: pyrender_images[(kind, name)].astype(np.float64).sum(-1)
           for name in ("lit", "shadowed", "dark")}
    theirs, theirs_compared = shadow_mask(img["lit"], img["shadowed"], img["dark"])
    both = compared & theirs_compared
    assert ours[both].mean() > 0.03 and theirs[both].mean() > 0.03
    share, n = agreement(ours, theirs, both)
    print(f"{kind}: softrast map vs pyrender agree on {share:.4%} of {n} px")
    assert n > 0.3 * both.sum() and share >= 0.98, (share, n)
