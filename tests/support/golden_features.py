"""Golden renders of every feature: SHA-256 of every output (its dtype, shape and bytes) of a
second set of scenes.

tests/support/golden.py's 18 scenes predate most of the core's features (lights and materials, every
shading model and frequency, textures, the surface outputs, anti-aliasing, lines and points, lens
distortion). The scenes here exercise each of those paths, so that a restructuring of the C++
kernels that must not change any output can be checked bit for bit:

* shading: ``shading="auto"`` mixing materials of every model in one frame; every name forced
  ("unlit", "lambert", "phong", "blinn_phong", "pbr", "normal", "uv") at the "pixel", "vertex"
  and "face" frequencies; the headlight (no lights) and point, spot (cones, camera-space,
  ``falloff="none"``) and directional lights with an ambient light; single- and double-sided
  materials seen from behind; vertex colours; flat (no normals) and smooth meshes; sRGB on and
  off; a whole and a fractional specular exponent; emissive colours;
* textures: the base colour under each filter (nearest, bilinear, trilinear, anisotropic) and a
  render-wide ``texture_filter``; every wrap mode (and a pair), both uv origins, uint8, uint16
  and float32 texels of 1 to 4 channels; emissive, normal (OpenGL and DirectX conventions,
  mirrored uvs and a mirroring pose), bump, metallic-roughness and occlusion maps; alpha masks
  (texture alpha and vertex alpha; colour, depth-only and anti-aliased renders); textures at the
  vertex and face frequencies (modulated);
* outputs: every output of ``softrast.OUTPUTS`` (as of the recorded commit, ``OUTPUTS`` below),
  ``normal_space="camera"``, the surface outputs without shading, depth-only renders;
* the shading paths "forward", "deferred" and "auto" (a frame whose left tile has heavy overdraw
  and whose right tile has little), ``raster="scanline"``, and ``coverage`` (which makes a
  render deferred);
* anti-aliasing: ``msaa`` 2, 4, 8, 16 and ``ssaa`` 2, 3, with the headlight kernel, the lit
  model, textures, alpha masks, coverage, alpha and backgrounds;
* lines and points (widths and sizes 1 and above, per-vertex colours, both line algorithms, a
  line through the near plane), ``wireframe=True``, and both with msaa / ssaa;
* lens distortion (a strong barrel lens past its fold, and a thin-prism one with ``oversample=1``
  and OpenGL conventions) with colour, depth and the surface outputs;
* orthographic cameras, OpenCV intrinsics, near-plane clipping of lit, textured, normal-mapped
  geometry.

Every mesh, texture, light and camera pose is made here with NumPy from correctly rounded operations
only (+, -, *, /, sqrt, in a fixed order: no transcendental functions, BLAS or reductions, whose
last bits may differ between NumPy builds), or read from tests/data/golden_meshes.npz (Spot and an
icosphere), so neither a trimesh, Pillow nor NumPy upgrade can change the inputs. Meshes are built
once and shared by every render (as in tests/support/golden.py); textures are made per render, so
each render builds its own mip chains. Images are small (at most 128 x 80) so the whole record
renders in a few seconds; tests/test_golden.py renders each scene once per instruction set (simd
True and False) and thread count (1, 2, 3) and compares every output's hash with the record, made
with simd=True and 2 threads.

The record, tests/data/golden_features.json, was made from commit 9c24f39 (the build before the
shading kernels were restructured for build time). A change that means to alter any of these
outputs must re-record them and say so, scene by scene, in its commit message:

    python3 tests/support/golden_features.py --write 9c24f39   # record from the installed build
    python3 tests/support/golden_features.py                   # compare every scene and configuration
    python3 tests/support/golden_features.py --png DIR         # write each scene's colour image to DIR

(``--write`` refuses to record a scene whose colour image is blank or flat.)
"""
from __future__ import annotations

import hashlib
import json
import math
import pathlib
import sys
from typing import Callable

import numpy as np

import softrast as sr

if not __package__:  # run as a script, by path: tests/ on sys.path, for "from support import"
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
from support import golden  # noqa: E402  the Spot and sphere meshes, and the configurations

DATA = pathlib.Path(__file__).resolve().parents[1] / "data"
HASHES = DATA / "golden_features.json"
# The outputs at the recorded commit (not sr.OUTPUTS: an output added later is not recorded).
OUTPUTS = ("color", "depth", "mask", "normal", "triangle_id", "instance_id", "coverage",
           "radiance", "barycentric", "uv", "position", "ray_depth", "alpha")
# Asking for coverage makes a render deferred: most scenes leave it out, so "auto" can go forward.
NO_COVERAGE = tuple(o for o in OUTPUTS if o != "coverage")
SURFACE = ("barycentric", "uv", "position", "ray_depth")
CONFIGS = golden.CONFIGS


# ---------------------------------------------------------------------------------------------
# Geometry (float64 +, -, *, / and sqrt only, each correctly rounded, in a fixed order; then float32)

def _length(v: np.ndarray) -> np.ndarray:
    """|v| over the last axis (of 3), summed in a fixed order (no BLAS, no reduction)."""
    return np.sqrt(v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1] + v[..., 2] * v[..., 2])[..., None]


def _quad_grid(n: int) -> tuple[np.ndarray, np.ndarray]:
    """(n + 1)^2 points of [-1, 1]^2 (row-major, x fastest) and the 2 n^2 counter-clockwise
    (seen from +z) triangles between them."""
    t = np.arange(n + 1, dtype=np.float64) * (2.0 / n) - 1.0
    x, y = np.meshgrid(t, t)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return np.stack([x.ravel(), y.ravel()], 1), faces


def plane(n: int = 4, uv_scale=(1.0, 1.0), uv_offset=(0.0, 0.0), mirror_u: bool = False,
          colors: bool = False) -> sr.Mesh:
    """The square [-1, 1]^2 at z = 0 facing +z, with normals, uvs (``uv_offset`` + ``uv_scale``
    times [0, 1]^2; u decreasing along +x with ``mirror_u``) and optionally vertex colours."""
    xy, faces = _quad_grid(n)
    pos = np.concatenate([xy, np.zeros((len(xy), 1))], 1)
    s = (xy + 1.0) * 0.5
    if mirror_u:
        s[:, 0] = 1.0 - s[:, 0]
    uvs = np.asarray(uv_offset) + s * np.asarray(uv_scale)
    normals = np.tile([0.0, 0.0, 1.0], (len(xy), 1))
    cols = None
    if colors:  # RGBA: alpha 1 at the left edge falling to 0 at the right (for alpha masks)
        cols = np.stack([s[:, 0], s[:, 1], 1.0 - s[:, 0] * s[:, 1], 1.0 - s[:, 0]], 1)
    return sr.Mesh(pos, faces, normals=normals, uvs=uvs, colors=cols)


def _cube_sphere_parts(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A cube's six faces, each an n x n grid with its own uv square, as (cube points, uvs,
    faces), counter-clockwise seen from outside."""
    xy, faces = _quad_grid(n)
    uv = (xy + 1.0) * 0.5
    one = np.ones(len(xy))
    # (u axis, v axis, outward normal) of each face: u x v = normal keeps the winding outward.
    axes = [((0, 0, -1), (0, 1, 0), (1, 0, 0)), ((0, 0, 1), (0, 1, 0), (-1, 0, 0)),
            ((1, 0, 0), (0, 0, -1), (0, 1, 0)), ((1, 0, 0), (0, 0, 1), (0, -1, 0)),
            ((1, 0, 0), (0, 1, 0), (0, 0, 1)), ((-1, 0, 0), (0, 1, 0), (0, 0, -1))]
    pts, uvs, tris = [], [], []
    for k, (u, v, w) in enumerate(axes):
        p = (xy[:, :1] * np.asarray(u, np.float64) + xy[:, 1:] * np.asarray(v, np.float64)
             + one[:, None] * np.asarray(w, np.float64))
        pts.append(p)
        uvs.append(uv)
        tris.append(faces + k * len(xy))
    return np.concatenate(pts), np.concatenate(uvs), np.concatenate(tris)


def cube_sphere(n: int = 8, colors: bool = False) -> sr.Mesh:
    """A unit sphere made of a cube's six gridded faces projected onto it (each face's own uv
    square, so every face has its own tangent frame), with normals and uvs."""
    p, uv, f = _cube_sphere_parts(n)
    unit = p / _length(p)
    cols = None
    if colors:
        c = (unit + 1.0) * 0.5
        cols = np.concatenate([c, np.ones((len(c), 1))], 1)
    return sr.Mesh(unit, f, normals=unit, uvs=uv, colors=cols)


def bowl(n: int = 8) -> sr.Mesh:
    """The half of ``cube_sphere(n)`` (n even) with z <= 0: an open bowl whose inside (back
    faces) shows to a camera on the +z side."""
    p, uv, f = _cube_sphere_parts(n)
    keep = (p[f][:, :, 2] <= 0.0).all(1)
    f = f[keep]
    used = np.unique(f)
    remap = np.full(len(p), -1)
    remap[used] = np.arange(len(used))
    q = p[used]
    unit = q / _length(q)
    return sr.Mesh(unit, remap[f], normals=unit, uvs=uv[used])


# ---------------------------------------------------------------------------------------------
# Textures (small NumPy images)

def checker(n: int = 32, cell: int = 4, a=(235, 200, 40), b=(30, 60, 170)) -> np.ndarray:
    """uint8 RGB checkerboard with a one-texel grid of a third colour every 4 cells (so the
    filters differ)."""
    i, j = np.mgrid[0:n, 0:n]
    on = ((i // cell + j // cell) % 2).astype(bool)
    img = np.where(on[..., None], np.array(a, np.uint8), np.array(b, np.uint8))
    img[(i % (4 * cell) == 0) | (j % (4 * cell) == 0)] = (250, 250, 250)
    return np.ascontiguousarray(img.astype(np.uint8))


def gradient_rgba_u16(h: int = 12, w: int = 20) -> np.ndarray:
    i, j = np.mgrid[0:h, 0:w].astype(np.float64)
    img = np.stack([j / (w - 1), i / (h - 1), 1.0 - j / (w - 1), 0.5 + 0.5 * (i % 2)], -1)
    return np.round(img * 65535.0).astype(np.uint16)


def stripes_f32(h: int = 16, w: int = 16) -> np.ndarray:
    i, j = np.mgrid[0:h, 0:w]
    img = np.stack([(j % 4) / 3.0, (i % 5) / 4.0, ((i + j) % 3) / 2.0], -1)
    return img.astype(np.float32)


def grey_u8(h: int = 9, w: int = 7) -> np.ndarray:
    i, j = np.mgrid[0:h, 0:w]
    return ((i * 29 + j * 37) % 256).astype(np.uint8)


def heights(n: int = 32, bumps: int = 4) -> np.ndarray:
    """float32 (n, n) height map in [0, 1]: a grid of bumps^2 round caps (1 - r^2)^2."""
    t = (np.arange(n, dtype=np.float64) + 0.5) * (bumps / n)
    f = t - np.floor(t) - 0.5  # -0.5..0.5 within each cell
    x, y = np.meshgrid(f, f)
    r2 = (x * x + y * y) * 4.0
    return np.where(r2 < 1.0, (1.0 - r2) ** 2, 0.0).astype(np.float32)


def normal_map(n: int = 32, bumps: int = 4, strength: float = 3.0) -> np.ndarray:
    """uint8 RGB tangent-space normal map (OpenGL: green = +v, v up the image) of heights()."""
    h = heights(n, bumps).astype(np.float64)
    dx = (np.roll(h, -1, 1) - np.roll(h, 1, 1)) * strength
    dy = (np.roll(h, 1, 0) - np.roll(h, -1, 0)) * strength  # row 0 is the top: v grows upwards
    nrm = np.stack([-dx, -dy, np.ones_like(h)], -1)
    nrm /= _length(nrm)
    return np.round((nrm * 0.5 + 0.5) * 255.0).astype(np.uint8)


def lattice_rgba(n: int = 24, period: int = 6, bar: int = 2) -> np.ndarray:
    """uint8 RGBA: opaque bars (a grid), transparent holes, a soft alpha edge."""
    i, j = np.mgrid[0:n, 0:n]
    on = (i % period < bar) | (j % period < bar)
    edge = (i % period == bar) | (j % period == bar)
    alpha = np.where(on, 255, np.where(edge, 140, 0))
    rgb = np.stack([40 + 8 * i, 200 - 6 * j, 90 + 3 * (i + j)], -1)
    return np.concatenate([rgb, alpha[..., None]], -1).astype(np.uint8)


def metal_rough_u16(n: int = 16) -> np.ndarray:
    """uint16 RGB: green = roughness (a ramp along u), blue = metallic (stripes along v)."""
    i, j = np.mgrid[0:n, 0:n].astype(np.float64)
    rough = 0.05 + 0.95 * j / (n - 1)
    metal = ((i // 4) % 2).astype(np.float64)
    return np.round(np.stack([np.zeros_like(i), rough, metal], -1) * 65535.0).astype(np.uint16)


def occlusion_u8(n: int = 16) -> np.ndarray:
    """uint8 single channel: dark rings (ambient occlusion in the red channel)."""
    i, j = np.mgrid[0:n, 0:n].astype(np.float64)
    r2 = ((i - 7.5) ** 2 + (j - 7.5) ** 2) / 64.0
    return np.round(255.0 * np.clip(0.15 + r2, 0.0, 1.0)).astype(np.uint8)


def dots_u8(n: int = 16) -> np.ndarray:
    """uint8 RGB emissive pattern: bright dots on black."""
    i, j = np.mgrid[0:n, 0:n]
    on = ((i % 4) < 2) & ((j % 4) < 2)
    img = np.zeros((n, n, 3), np.uint8)
    img[on] = (255, 180, 60)
    img[on & (i >= n // 2)] = (60, 255, 200)
    return img


def grey_alpha_f32(n: int = 8) -> np.ndarray:
    """float32 two channels (grey, alpha): alpha a diagonal ramp."""
    i, j = np.mgrid[0:n, 0:n].astype(np.float64)
    return np.stack([0.3 + 0.7 * (i % 2), (i + j) / (2 * n - 2)], -1).astype(np.float32)


# ---------------------------------------------------------------------------------------------
# Poses, lights, cameras

def _translate(x, y, z, s=1.0) -> np.ndarray:
    return golden._translate(x, y, z, s)


def _scale(sx, sy, sz) -> np.ndarray:
    return np.diag([sx, sy, sz, 1.0])


def _rot(axis: str, c: float, s: float) -> np.ndarray:
    """A rotation about ``axis`` given its cosine and sine (no trigonometry: exact inputs)."""
    n = math.sqrt(c * c + s * s)
    c, s = c / n, s / n
    m = np.eye(4)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def _aim(pos, target, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """A light pose at ``pos`` shining (along its -z) at ``target``."""
    pos, target = np.asarray(pos, np.float64), np.asarray(target, np.float64)
    z = pos - target
    z = z / _length(z)
    x = np.cross(np.asarray(up, np.float64), z)
    x = x / _length(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, y, z, pos
    return m


def _lights(sc: sr.Scene, target=(0.0, 0.1, 0.1), kinds: str = "psd",
            ambient=(0.05, 0.045, 0.07)) -> sr.Scene:
    """Adds a warm point light, a cool spot light and a white directional light (any of "psd")
    around ``target``, and an ambient light (None: none set)."""
    t = np.asarray(target, np.float64)
    if "p" in kinds:
        sc.add(sr.PointLight(color=(1.0, 0.85, 0.6), intensity=7.0), pose=_translate(*(t + (1.6, 1.4, -1.2))))
    if "s" in kinds:
        sc.add(sr.SpotLight(color=(0.5, 0.75, 1.0), intensity=12.0, inner_cone=0.12, outer_cone=0.4),
               pose=_aim(t + (-1.4, 1.9, 1.6), t))
    if "d" in kinds:
        sc.add(sr.DirectionalLight(color=(1.0, 1.0, 0.95), intensity=0.55),
               pose=_aim(t + (0.4, 1.0, 0.7), t))
    if ambient is not None:
        sc.ambient_light = ambient
    return sc


def _look(cam: sr.Camera, eye, target) -> sr.Camera:
    """What ``cam.look_at(eye, target)`` does (up +y), computed here in a fixed order of exact
    operations."""
    pose = _aim(eye, target)  # OpenGL axes: x right, y up, looking down -z
    if getattr(cam, "convention", "opengl") == "opencv":  # x right, y down, looking down +z
        pose = pose @ np.diag([1.0, -1.0, -1.0, 1.0])
    cam.pose = pose
    return cam


def _persp(eye, target, fov=45.0, near=0.05, far=100.0) -> sr.Camera:
    return _look(sr.PerspectiveCamera(fov_y=fov, near=near, far=far), eye, target)


SPOT_EYE, SPOT_TARGET = (1.7, 0.9, -2.3), (0.0, 0.05, 0.15)


def _spot_cam() -> sr.Camera:
    return _persp(SPOT_EYE, SPOT_TARGET)


# Materials used by several scenes (immutable: sharing one between renders is fine; textures are
# made per build so that every render builds its own mip chains).
# The default base colour before a texture made it white: the golden scenes keep 0.8.
GREY = (0.8, 0.8, 0.8, 1.0)

SHINY = sr.Material(base_color=(0.85, 0.55, 0.3, 1.0), ks=(0.6, 0.6, 0.55), shininess=16.0,
                    metallic=0.35, roughness=0.4)


# ---------------------------------------------------------------------------------------------
# Meshes shared by every render (built once per process, like golden._meshes())

def meshes() -> dict[str, sr.Mesh]:
    m = golden._meshes()
    d = np.load(golden.MESHES)
    sph_p, sph_f = d["sphere_positions"], d["sphere_faces"]
    unit = sph_p.astype(np.float64)
    c = (unit + 1.0) * 0.5
    m.update({
        # As golden's, with the normals computed here (in a fixed order).
        "sphere": sr.Mesh(sph_p, sph_f, normals=unit / _length(unit)),
        # The icosphere without normals (flat) but with vertex colours.
        "sphere_flat_colors": sr.Mesh(sph_p, sph_f, colors=np.concatenate([c, np.ones((len(c), 1))], 1)),
        "ball": cube_sphere(8),
        "ball_colors": cube_sphere(8, colors=True),
        "coarse_ball": cube_sphere(3),
        "bowl": bowl(8),
        "plane": plane(4),
        "plane_colors": plane(4, colors=True),
        "checker_floor": plane(6, uv_scale=(12.0, 12.0)),
        "wrap_quad": plane(2, uv_scale=(3.5, 3.5), uv_offset=(-1.25, -1.25)),
        "mirrored_quad": plane(2, mirror_u=True),
    })
    return m


# ---------------------------------------------------------------------------------------------
# The scenes: name -> (width, height, build(meshes) -> (scene, camera), render options)

Build = Callable[[dict], tuple]


def _scenes() -> dict[str, tuple[int, int, Build, dict]]:
    s: dict[str, tuple[int, int, Build, dict]] = {}

    def add(name, w, h, **options):
        def deco(fn):
            assert name not in s, name
            s[name] = (w, h, fn, options)
            return fn
        return deco

    # -- shading="auto": every model of a material in one frame ---------------------------------
    def mixed(m, lights=True):
        sc = sr.Scene()
        mats = [None,                                                     # lambert, plain
                sr.Material(base_color=(0.3, 0.7, 0.35, 1.0)),            # blinn_phong (default)
                sr.Material(base_color=(0.7, 0.3, 0.6, 1.0), ks=(0.9, 0.9, 0.9), shininess=20.5,
                            model="phong"),                               # fractional exponent
                sr.Material(base_color=(0.9, 0.75, 0.3, 1.0), metallic=0.8, roughness=0.3,
                            model="pbr"),
                sr.Material(base_color=(0.2, 0.5, 0.9, 1.0), model="unlit"),
                sr.Material(model="normal"),
                sr.Material(base_color=(0.6, 0.6, 0.6, 1.0), ka=(0.1, 0.0, 0.3), kd=(0.9, 0.4, 0.2),
                            emissive=(0.15, 0.05, 0.0), model="lambert", double_sided=True),
                sr.Material(base_color=(0.8, 0.8, 0.85, 1.0), metallic=0.0, roughness=0.9,
                            emissive=(0.0, 0.1, 0.2), model="pbr")]
        for k, mat in enumerate(mats):
            mesh = m["sphere"] if k % 3 else m["ball"]
            if k == 5:
                mesh = m["sphere_flat"]
            sc.add(mesh, pose=_translate(0.95 * (k % 4) - 1.425, 0.5 - 1.0 * (k // 4), 0.0, 0.45),
                   material=mat, instance_id=10 + k,
                   color=(0.95, 0.95, 0.5, 1.0) if k == 7 else None)  # replaces the base colour
        if lights:
            _lights(sc, target=(0.0, 0.0, 0.0))
        return sc, _persp((0.3, 0.6, 4.2), (0.0, 0.0, 0.0), fov=40)

    # 97 x 70: four tiles (64 x 64), two of them narrow
    add("auto_mixed_materials_lights", 97, 70)(mixed)
    # (coverage counts the back faces a double-sided material no longer culls)
    add("auto_mixed_materials_coverage_linear", 97, 70, outputs=OUTPUTS, srgb=False,
        cull_double_sided=True)(mixed)
    add("auto_mixed_materials_headlight", 97, 70, ambient=0.3)(lambda m: mixed(m, lights=False))
    # Shadows: every model under exact shadows from all three lights (the spheres shadow each
    # other and themselves), and shadow maps of 96 texels (cheap under the sanitizers).
    add("auto_mixed_materials_shadows_exact", 97, 70, shadows=True)(mixed)

    def mapped(m):
        sc, cam = mixed(m, lights=False)
        t = np.zeros(3)
        sc.add(sr.PointLight(color=(1.0, 0.85, 0.6), intensity=7.0, shadows="map",
                             shadow_resolution=96), pose=_translate(*(t + (1.6, 1.4, -1.2))))
        sc.add(sr.SpotLight(color=(0.5, 0.75, 1.0), intensity=12.0, inner_cone=0.12, outer_cone=0.4,
                            shadows="map", shadow_resolution=64, shadow_bias=0.01),
               pose=_aim(t + (-1.4, 1.9, 1.6), t))
        sc.add(sr.DirectionalLight(intensity=0.55, shadows="map", shadow_resolution=80),
               pose=_aim(t + (0.4, 1.0, 0.7), t))
        sc.ambient_light = (0.05, 0.045, 0.07)
        return sc, cam

    add("auto_mixed_materials_shadow_maps", 97, 70)(mapped)

    # -- every lit model forced, at every frequency, under every kind of light ------------------
    def lit_spot(m):
        sc = sr.Scene()
        sc.add(m["spot"], material=SHINY, instance_id=3)
        sc.add(m["sphere_flat_colors"], pose=_translate(0.55, 0.55, 0.9, 0.3), instance_id=4)
        sc.add(m["spot_flat"], pose=_translate(-1.0, -0.4, -0.6, 0.35) @ _rot("y", 0.5, 0.85),
               material=SHINY.replace(base_color=(0.4, 0.8, 0.5, 1.0), double_sided=True),
               instance_id=5)
        return _lights(sc), _spot_cam()

    for k, model in enumerate(("lambert", "phong", "blinn_phong", "pbr")):
        for f, freq in enumerate(("pixel", "vertex", "face")):
            add(f"{model}_{freq}_lights", 64 + 2 * k + f, 48 + f, shading=model, frequency=freq,
                srgb=(k + f) % 2 == 0)(lit_spot)

    # -- lambert under the headlight: the plain kernel (pixel) and the lit one (vertex, face) ----
    def plain(m):
        sc = sr.Scene()
        sc.add(m["spot"]); sc.add(m["spot_colors"], pose=_translate(0.9, 0.1, 0.6, 0.6))
        sc.add(m["sphere_flat"], pose=_translate(-0.9, 0.6, -0.4, 0.25))
        return sc, _spot_cam()

    for freq in ("pixel", "vertex", "face"):
        add(f"lambert_headlight_{freq}", 65, 49, shading="lambert", frequency=freq, ambient=0.4)(plain)

    # -- the debug and unlit models --------------------------------------------------------------
    add("unlit_vertex_colors_background", 71, 45, shading="unlit", background=(0.15, 0.3, 0.2))(plain)
    for freq in ("pixel", "vertex", "face"):
        add(f"normal_{freq}", 60, 46, shading="normal", frequency=freq)(lit_spot)

    @add("uv_model", 72, 50, shading="uv", srgb=False)
    def _(m):  # Spot's uvs, a mesh without uvs (black) and a textured plane beyond [0, 1]
        sc = sr.Scene()
        sc.add(m["spot"])
        sc.add(m["sphere"], pose=_translate(-0.9, 0.6, -0.4, 0.25))
        sc.add(m["wrap_quad"], pose=_translate(-0.3, 0.0, 1.4, 0.8) @ _rot("y", -0.94, -0.34),
               material=sr.Material(base_color=GREY, base_color_texture=sr.Texture(checker(16))))
        return sc, _spot_cam()

    # -- sidedness: back faces of single- and double-sided materials ---------------------------
    @add("back_faces_single_double_sided", 90, 40, cull="none")
    def _(m):  # three bowls open towards the camera: their insides are back faces
        sc = sr.Scene()
        mats = [sr.Material(base_color=(0.9, 0.5, 0.2, 1.0), emissive=(0.05, 0.0, 0.1)),
                sr.Material(base_color=(0.9, 0.5, 0.2, 1.0), double_sided=True),
                None]
        for k, mat in enumerate(mats):
            sc.add(m["bowl"], pose=_translate(2.2 * k - 2.2, 0.0, 0.0) @ _rot("y", 0.95, 0.3),
                   material=mat)
        sc.add(sr.PointLight(intensity=14.0), pose=_translate(0.5, 1.5, 3.0))
        sc.ambient_light = (0.1, 0.1, 0.1)
        return sc, _persp((0.0, 0.8, 5.0), (0.0, 0.0, 0.0), fov=45)

    @add("back_faces_pbr_cull_front", 61, 47, cull="front", shading="pbr")
    def _(m):  # the camera inside a sphere: culling front faces leaves the far inside
        sc = sr.Scene()
        sc.add(m["ball"], pose=_scale(2.0, 2.0, 2.0),
               material=sr.Material(base_color=(0.7, 0.7, 0.9, 1.0), roughness=0.6, double_sided=True,
                                    base_color_texture=sr.Texture(checker(16, 2))))
        sc.add(m["ball"], pose=_translate(0.3, -0.2, -0.9, 0.35),  # single-sided: its far inside
               material=sr.Material(base_color=(0.9, 0.4, 0.4, 1.0), roughness=0.3, emissive=(0.2, 0.0, 0.0)))
        sc.add(sr.PointLight(intensity=3.0), pose=_translate(0.0, 0.5, 0.5))
        sc.ambient_light = (0.1, 0.1, 0.1)
        return sc, _persp((0.0, 0.0, 1.2), (0.0, 0.0, -1.0), fov=80)

    # -- light kinds: a spot light's cone on a floor, camera-space lights, no falloff ----------
    @add("spot_cone_camera_space_falloff_none", 80, 60)
    def _(m):
        sc = sr.Scene()
        sc.add(m["plane"], pose=_rot("x", 0.0, -1.0) @ _scale(3.0, 3.0, 1.0),
               material=sr.Material(base_color=(0.8, 0.8, 0.8, 1.0), ks=(0.2, 0.2, 0.2),
                                    shininess=64.0))
        sc.add(m["sphere"], pose=_translate(0.6, 0.45, 0.0, 0.45),
               material=sr.Material(base_color=(0.9, 0.3, 0.3, 1.0), shininess=100.0))
        sc.add(sr.SpotLight(color=(1.0, 0.9, 0.6), intensity=9.0, inner_cone=0.25, outer_cone=0.55),
               pose=_aim((-0.4, 2.5, 0.3), (-0.4, 0.0, 0.0)))
        sc.add(sr.SpotLight(color=(0.3, 0.5, 1.0), intensity=0.8, inner_cone=0.0, outer_cone=0.3,
                            falloff="none"), pose=_aim((1.5, 2.0, 1.5), (0.6, 0.0, 0.0)))
        sc.add(sr.PointLight(color=(0.4, 1.0, 0.4), intensity=0.35, falloff="none"),
               pose=_translate(0.8, 0.5, -0.5), camera_space=True)
        sc.add(sr.DirectionalLight(color=(0.3, 0.3, 0.3), intensity=0.5),
               pose=np.eye(4), camera_space=True)
        return sc, _persp((0.0, 2.4, 3.2), (0.0, 0.0, 0.0), fov=50)

    # -- textures: the base colour under every filter, and a render-wide override --------------
    def floor(m, filt="trilinear", aniso=16):
        sc = sr.Scene()
        tex = sr.Texture(checker(32, 4), filter=filt, max_anisotropy=aniso)
        sc.add(m["checker_floor"], pose=_rot("x", 0.0, -1.0) @ _scale(6.0, 6.0, 1.0),
               material=sr.Material(base_color=GREY, base_color_texture=tex, ks=(0.0, 0.0, 0.0), model="lambert"))
        sc.add(sr.DirectionalLight(intensity=0.5), pose=_aim((0.5, 2.0, 1.0), (0.0, 0.0, 0.0)))
        sc.add(sr.PointLight(intensity=0.6, color=(1.0, 0.8, 0.6)), pose=_translate(0.8, 0.5, 1.5))
        sc.ambient_light = (0.2, 0.2, 0.2)
        return sc, _persp((0.0, 0.35, 3.5), (0.0, 0.0, -2.0), fov=50)

    for filt in ("nearest", "bilinear", "trilinear", "anisotropic"):
        add(f"texture_filter_{filt}", 80, 48)(lambda m, filt=filt: floor(m, filt))
    add("texture_filter_override_anisotropic", 80, 48, texture_filter="anisotropic")(
        lambda m: floor(m, "nearest", aniso=5))
    add("texture_filter_override_nearest_vertex", 80, 48, texture_filter="nearest",
        frequency="vertex")(lambda m: floor(m, "anisotropic"))

    @add("texture_wrap_modes_dtypes", 96, 40, shading="unlit", srgb=False)
    def _(m):  # uvs in [-1.25, 2.25]: repeat, clamp, mirror, (mirror, clamp); 1 to 4 channels
        sc = sr.Scene()
        texs = [sr.Texture(checker(8, 2), wrap="repeat", filter="nearest"),
                sr.Texture(gradient_rgba_u16(), wrap="clamp", filter="bilinear"),
                sr.Texture(stripes_f32(), wrap="mirror", filter="nearest", uv_origin="top_left",
                           srgb=True),  # (float images are linear by default now)
                sr.Texture(grey_u8(), wrap=("mirror", "clamp"), filter="bilinear", srgb=False),
                sr.Texture(grey_alpha_f32(), wrap=("clamp", "repeat"), filter="trilinear", srgb=True)]
        for k, tex in enumerate(texs):
            sc.add(m["wrap_quad"], pose=_translate(2.1 * k - 4.2, 0.0, 0.0),
                   material=sr.Material(base_color=(1.0, 1.0, 1.0, 1.0), base_color_texture=tex))
        cam = sr.OrthographicCamera(xmag=5.3, ymag=2.2)
        _look(cam, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0))
        return sc, cam

    def textured_spot(m, model=None, colors=False):
        sc = sr.Scene()
        tex = sr.Texture(checker(32, 4, a=(250, 245, 230), b=(140, 40, 40)))
        mat = SHINY.replace(base_color=(1.0, 1.0, 1.0, 1.0), base_color_texture=tex, model=model)
        sc.add(m["spot_colors"] if colors else m["spot"], material=mat)
        sc.add(m["ball_colors"], pose=_translate(0.75, 0.6, 0.8, 0.3),
               material=mat.replace(model="lambert"))
        return _lights(sc), _spot_cam()

    add("textured_pbr_pixel", 70, 52)(lambda m: textured_spot(m, "pbr"))
    add("textured_vertex_colors_vertex", 70, 52, frequency="vertex")(
        lambda m: textured_spot(m, "phong", colors=True))
    add("textured_vertex_colors_face_linear", 70, 52, frequency="face", srgb=False)(
        lambda m: textured_spot(m, "blinn_phong", colors=True))
    add("textured_unlit", 70, 52, shading="unlit")(lambda m: textured_spot(m, colors=True))

    @add("emissive_texture", 64, 48)
    def _(m):
        sc = sr.Scene()
        sc.add(m["ball"], pose=_rot("y", 0.8, 0.6),
               material=sr.Material(base_color=(0.3, 0.3, 0.35, 1.0), emissive=(1.0, 0.9, 0.8),
                                    emissive_texture=sr.Texture(dots_u8(), filter="bilinear")))
        sc.add(m["ball"], pose=_translate(1.9, 0.0, -0.5) @ _rot("x", 0.8, 0.6),
               material=sr.Material(base_color=(0.3, 0.3, 0.35, 1.0), emissive=(0.6, 0.6, 1.0),
                                    emissive_texture=sr.Texture(dots_u8(), filter="nearest"),
                                    model="pbr"))
        return _lights(sc, kinds="d", ambient=(0.03, 0.03, 0.03)), _persp((0.9, 0.5, 4.5), (0.9, 0.0, 0.0))

    def normal_mapped(m, convention="opengl", bump=False):
        sc = sr.Scene()
        if bump:
            kw = dict(bump_texture=sr.Texture(heights(), filter="bilinear"), bump_scale=6.0)
        else:
            kw = dict(normal_texture=sr.Texture(normal_map(), filter="trilinear"),
                      normal_scale=1.5 if convention == "opengl" else 0.7,
                      normal_map_convention=convention)
        mat = sr.Material(base_color=(0.75, 0.75, 0.8, 1.0), ks=(0.5, 0.5, 0.5), shininess=24.0, **kw)
        sc.add(m["ball"], pose=_rot("y", 0.9, 0.4), material=mat)
        sc.add(m["mirrored_quad"], pose=_translate(1.9, 0.0, 0.0, 0.9), material=mat)
        # A mirroring pose (negative determinant) flips the winding and the tangent frame.
        sc.add(m["plane"], pose=_translate(-1.9, 0.0, 0.0) @ _scale(-0.9, 0.9, 0.9),
               material=mat.replace(model="pbr", double_sided=True))
        sc.add(sr.PointLight(intensity=9.0), pose=_translate(-1.0, 2.0, 2.0))
        sc.add(sr.DirectionalLight(color=(0.6, 0.7, 1.0), intensity=0.4), pose=_aim((2, 0.5, 1), (0, 0, 0)))
        sc.ambient_light = (0.05, 0.05, 0.05)
        return sc, _persp((0.0, 0.4, 5.5), (0.0, 0.0, 0.0), fov=40)

    add("normal_map_opengl", 96, 40)(normal_mapped)
    add("normal_map_directx", 96, 40)(lambda m: normal_mapped(m, "directx"))
    add("bump_map", 96, 40)(lambda m: normal_mapped(m, bump=True))
    add("normal_model_normal_map", 96, 40, shading="normal")(normal_mapped)

    @add("metallic_roughness_occlusion_pbr", 80, 40)
    def _(m):
        sc = sr.Scene()
        mat = sr.Material(base_color=(0.95, 0.7, 0.4, 1.0), metallic=1.0, roughness=1.0, model="pbr",
                          metallic_roughness_texture=sr.Texture(metal_rough_u16(), filter="bilinear"),
                          occlusion_texture=sr.Texture(occlusion_u8(), filter="nearest"),
                          occlusion_strength=0.8)
        sc.add(m["ball"], pose=_rot("y", 0.9, 0.4), material=mat)
        sc.add(m["plane"], pose=_translate(2.2, 0.0, 0.0), material=mat.replace(
            base_color_texture=sr.Texture(checker(16, 4)), model="blinn_phong"))
        _lights(sc, target=(1.0, 0.0, 0.0), ambient=(0.5, 0.5, 0.5))
        return sc, _persp((1.1, 0.5, 4.6), (1.1, 0.0, 0.0), fov=42)

    # -- alpha masks -------------------------------------------------------------------------------
    def masked(m):
        sc = sr.Scene()
        cam = _spot_cam()
        sc.add(m["spot"], material=SHINY, instance_id=1)
        lattice = sr.Material(base_color=(1.0, 1.0, 1.0, 1.0), alpha_mode="mask", alpha_cutoff=0.4,
                              base_color_texture=sr.Texture(lattice_rgba(), filter="bilinear"),
                              double_sided=True)
        # Quads placed in the camera's frame (x right, y up, -z ahead).
        sc.add(m["plane"], pose=cam.pose @ _translate(0.3, 0.0, -1.8, 0.35), material=lattice,
               instance_id=2)
        sc.add(m["plane_colors"], pose=cam.pose @ _translate(-0.55, 0.3, -2.4, 0.3),  # vertex alpha
               material=sr.Material(alpha_mode="mask", model="unlit", double_sided=True), instance_id=3)
        sc.add(m["plane"], pose=cam.pose @ _translate(-0.4, -0.4, -2.0, 0.3) @ _rot("y", 0.8, 0.6),
               material=sr.Material(alpha_mode="mask", alpha_cutoff=0.55, double_sided=True,
                                    base_color=GREY, base_color_texture=sr.Texture(
                                        grey_alpha_f32(), filter="nearest", srgb=True)),
               instance_id=4)  # a two-channel (grey, alpha) float texture
        return _lights(sc), cam

    # -- alpha blending: textured, vertex and material alpha over a lit mesh; msaa and ssaa with
    # an alpha threshold (depth and ids from a blended fragment); a depth-only render with one
    def blended(m):
        sc = sr.Scene()
        cam = _spot_cam()
        sc.add(m["spot"], material=SHINY, instance_id=1)
        glass = sr.Material(base_color=(1.0, 1.0, 1.0, 1.0), alpha_mode="blend", double_sided=True,
                            base_color_texture=sr.Texture(lattice_rgba(), filter="bilinear"))
        sc.add(m["plane"], pose=cam.pose @ _translate(0.3, 0.0, -1.8, 0.35), material=glass,
               instance_id=2)
        sc.add(m["plane_colors"], pose=cam.pose @ _translate(-0.55, 0.3, -2.4, 0.3),  # vertex alpha
               material=sr.Material(alpha_mode="blend", model="unlit", double_sided=True), instance_id=3)
        sc.add(m["ball"], pose=cam.pose @ _translate(-0.25, -0.3, -2.1, 0.3),  # front and back faces
               material=sr.Material(base_color=(0.3, 0.6, 0.9, 0.45), alpha_mode="blend", model="pbr",
                                    roughness=0.4, double_sided=True), instance_id=4)
        return _lights(sc), cam

    add("blend_lit", 75, 55, cull="none", outputs=OUTPUTS)(blended)
    add("blend_msaa4_alpha_threshold", 75, 55, cull="none", outputs=OUTPUTS, msaa=4,
        alpha_threshold=0.4)(blended)
    add("blend_ssaa2_alpha_threshold_depth_ids", 75, 55, cull="none", ssaa=2, alpha_threshold=0.4,
        outputs=("depth", "instance_id", "normal"))(blended)

    add("alpha_mask_coverage", 75, 55, cull="none", outputs=OUTPUTS)(masked)
    add("alpha_mask_depth_only", 75, 55, cull="none", outputs=("depth",))(masked)
    add("alpha_mask_ids_no_shading", 75, 55, cull="none",
        outputs=("mask", "triangle_id", "instance_id", "coverage", "alpha"))(masked)
    add("alpha_mask_msaa4", 75, 55, cull="none", msaa=4, outputs=OUTPUTS)(masked)

    # -- outputs: camera-space normals (OpenCV axes), the surface outputs without shading ------
    @add("opencv_normal_space_camera", 69, 53, normal_space="camera")
    def _(m):
        sc, _ = textured_spot(m, "blinn_phong")
        cam = sr.IntrinsicsCamera(fx=70.0, fy=72.0, cx=33.7, cy=27.2, width=69, height=53,
                                  convention="opencv")
        _look(cam, SPOT_EYE, SPOT_TARGET)
        return sc, cam

    @add("surface_outputs_only_clipped", 67, 51, cull="none",
         outputs=("depth", "mask", "triangle_id", "instance_id", "alpha") + SURFACE)
    def _(m):  # the near plane cuts the spheres: the surface outputs of clipped triangles
        sc = sr.Scene()
        sc.add(m["spot"], instance_id=7)
        cam = _persp((1.4, 0.8, -2.6), SPOT_TARGET, fov=60, near=0.3)
        sc.add(m["ball"], pose=cam.pose @ _translate(0.25, 0.12, -0.45, 0.22), instance_id=8)
        return sc, cam

    # -- shading paths: heavy overdraw in the left tile, little in the right -------------------
    def overdraw(m):
        sc = sr.Scene()
        tex = sr.Texture(checker(16, 2))
        for k in range(8):
            mat = sr.Material(base_color=(1.0, 0.9 - 0.1 * k, 0.5 + 0.05 * k, 1.0), base_color_texture=tex,
                              model=("blinn_phong", "pbr", "lambert", "phong")[k % 4])
            sc.add(m["ball"], pose=_translate(-1.0 + 0.03 * k, 0.02 * k, -0.15 * k, 0.85),
                   material=mat, instance_id=k)
        sc.add(m["sphere"], pose=_translate(1.2, 0.0, 0.0, 0.5), material=SHINY, instance_id=9)
        sc.add(m["spot"], pose=_translate(1.2, -0.6, -0.8, 0.4), instance_id=10)
        _lights(sc, target=(0.0, 0.0, 0.0))
        cam = sr.OrthographicCamera(xmag=2.0, ymag=1.0)
        _look(cam, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0))
        return sc, cam

    for path in ("auto", "forward", "deferred"):
        add(f"overdraw_lit_textured_{path}", 128, 64, shading_path=path)(overdraw)
    add("overdraw_lit_textured_scanline", 128, 64, raster="scanline")(overdraw)
    add("scanline_textured_near_clip_coverage", 64, 48, raster="scanline", cull="none",
        outputs=OUTPUTS)(lambda m: near_clip(m))

    # -- anti-aliasing -------------------------------------------------------------------------------
    add("msaa2_lambert_headlight_coverage", 65, 49, msaa=2, shading="lambert", outputs=OUTPUTS,
        background=(0.9, 0.85, 0.2))(plain)
    add("msaa4_textured_lit", 70, 52, msaa=4, outputs=OUTPUTS)(lambda m: textured_spot(m))
    add("msaa8_mixed_materials_background", 97, 70, msaa=8, background=(0.2, 0.2, 0.5))(mixed)
    add("msaa16_unlit_vertex_colors_linear", 65, 49, msaa=16, shading="unlit", srgb=False,
        outputs=OUTPUTS)(plain)
    add("msaa4_vertex_frequency_phong", 64, 48, msaa=4, shading="phong", frequency="vertex")(lit_spot)
    add("msaa2_normal_model_face", 64, 48, msaa=2, shading="normal", frequency="face")(lit_spot)
    add("ssaa2_normal_map", 96, 40, ssaa=2, outputs=OUTPUTS)(normal_mapped)
    add("ssaa3_lambert_headlight_background", 65, 49, ssaa=3, background=(0.1, 0.5, 0.3),
        outputs=OUTPUTS)(plain)
    add("ssaa3_textured_pbr_face", 70, 52, ssaa=3, frequency="face")(lambda m: textured_spot(m, "pbr"))
    add("ssaa2_uv_model", 72, 50, ssaa=2, shading="uv")(s["uv_model"][2])

    # -- lines and points ----------------------------------------------------------------------------
    def lines_points(m):
        sc = sr.Scene()
        sc.add(m["sphere"], pose=_translate(0.0, 0.0, 0.0, 0.6), instance_id=1)
        # A star of 16 segments (every octant) through the sphere, per-vertex colours.
        k = np.arange(16, dtype=np.float64)
        dirs = np.array([[4, 0], [4, 1], [4, 2], [4, 3], [4, 4], [3, 4], [2, 4], [1, 4]], np.float64)
        dirs = np.concatenate([dirs, -dirs])
        ends = np.concatenate([np.zeros((16, 3)), np.concatenate([dirs * 0.32, np.zeros((16, 1))], 1)])
        ends[:16, 2] = 0.7   # the centre in front of the sphere, the ends behind its rim
        ends[16:, 2] = -0.3 + 0.04 * k
        cols = np.concatenate([np.tile([[1.0, 1.0, 0.2]], (16, 1)),
                               np.stack([k / 15, 1.0 - k / 15, np.full(16, 0.8)], 1)])
        seg = np.stack([np.arange(16), np.arange(16) + 16], 1)
        sc.add(sr.Lines(ends, seg, colors=cols), instance_id=2)
        # Wide lines (round caps) and a line from in front of the camera to behind it.
        sc.add(sr.Lines([[-1.6, -1.0, 0.3], [1.6, -0.8, -0.5], [-1.5, 1.1, 0.0], [0.5, 0.9, 9.0]],
                        [[0, 1], [2, 3]], width=3.5, color=(0.9, 0.2, 0.9)), instance_id=3)
        # Points: size 1 (the compact record), 3 and 2.5, uint8 colours.
        g = np.stack(np.meshgrid(np.arange(9.0), np.arange(5.0)), -1).reshape(-1, 2)
        pts = np.concatenate([g * (0.35, 0.3) - (1.4, 1.25), np.full((len(g), 1), 0.2)], 1)
        rgb = np.stack([g[:, 0] * 28, g[:, 1] * 60, 255 - g[:, 0] * 28], 1).astype(np.uint8)
        sc.add(sr.Points(pts, colors=rgb), instance_id=4)
        sc.add(sr.Points(pts[::3] + (0.17, 0.15, 0.0), size=3.0, color=(0.1, 0.9, 0.9)), instance_id=5)
        sc.add(sr.Points(pts[1::4] + (0.1, 0.05, -0.9), size=2.5, color=(1.0, 0.5, 0.0)), instance_id=6)
        cam = _persp((0.0, 0.0, 4.0), (0.0, 0.0, 0.0), fov=45, near=0.5)
        return _lights(sc, target=(0.0, 0.0, 0.0), kinds="d"), cam

    add("lines_points_bresenham", 81, 67, outputs=OUTPUTS)(lines_points)
    add("lines_points_dda_linear", 81, 67, line_algorithm="dda", srgb=False)(lines_points)
    add("lines_points_msaa4", 81, 67, msaa=4, outputs=OUTPUTS)(lines_points)
    add("lines_points_ssaa2_dda", 81, 67, ssaa=2, line_algorithm="dda")(lines_points)

    def wire(m):  # coarse meshes, so that the faces show between the edges
        sc = sr.Scene()
        sc.add(m["coarse_ball"], pose=_rot("y", 0.9, 0.4), material=SHINY, instance_id=1)
        sc.add(m["coarse_ball"], pose=_translate(1.2, 0.5, -1.0, 0.6), instance_id=2)
        sc.add(m["plane"], pose=_translate(-1.3, -0.2, -0.5) @ _rot("y", 0.8, 0.6),
               material=sr.Material(base_color=GREY, base_color_texture=sr.Texture(checker(16, 4)), double_sided=True),
               instance_id=3)
        return _lights(sc, target=(0.0, 0.0, 0.0)), _persp((0.2, 0.8, 3.6), (0.0, 0.0, -0.3), fov=50)

    add("wireframe_lit", 90, 68, wireframe=True, line_color=(0.0, 0.3, 0.0))(wire)
    add("wireframe_wide_msaa4_textured", 90, 68, wireframe=True, line_width=2.0, msaa=4,
        line_color=(1.0, 1.0, 1.0), outputs=OUTPUTS)(wire)

    # -- lens distortion -----------------------------------------------------------------------------
    @add("distortion_barrel_lit_textured", 72, 54, outputs=OUTPUTS)
    def _(m):  # strong barrel: the corners lie beyond the fold (background)
        sc, _ = textured_spot(m, "pbr")
        floor_pose = _translate(0.0, -0.74, 0.0) @ _rot("x", 0.0, -1.0) @ _scale(2.0, 2.0, 1.0)
        sc.add(m["checker_floor"], pose=floor_pose,
               material=sr.Material(base_color=GREY, base_color_texture=sr.Texture(checker(32, 4)), model="lambert"),
               instance_id=9)
        cam = sr.IntrinsicsCamera(fx=38.0, fy=38.0, cx=35.5, cy=26.5, width=72, height=54,
                                  convention="opencv", dist=(-0.42, 0.08, 0.002, -0.003, 0.0))
        _look(cam, SPOT_EYE, SPOT_TARGET)
        return sc, cam

    @add("distortion_thin_prism_oversample1", 61, 47, shading="unlit", srgb=False,
         normal_space="camera", outputs=OUTPUTS)
    def _(m):
        sc = sr.Scene()
        sc.add(m["spot_colors"]); sc.add(m["ball_colors"], pose=_translate(0.8, 0.6, 0.7, 0.3))
        cam = sr.IntrinsicsCamera(fx=60.0, fy=58.0, cx=30.0, cy=24.0, width=61, height=47,
                                  convention="opengl", oversample=1,
                                  dist=(0.12, -0.05, 0.001, 0.002, 0.01, 0.02, -0.01, 0.005,
                                        0.003, -0.001, 0.002, 0.001))
        _look(cam, SPOT_EYE, SPOT_TARGET)
        return sc, cam

    @add("distortion_pincushion_lambert_headlight", 57, 43, outputs=("color", "depth", "normal"))
    def _(m):
        cam = sr.IntrinsicsCamera(fx=55.0, fy=55.0, cx=28.0, cy=21.0, width=57, height=43,
                                  dist=(0.25, 0.05, 0.0, 0.0))
        _look(cam, SPOT_EYE, SPOT_TARGET)
        return plain(m)[0], cam

    # -- cameras and clipping ------------------------------------------------------------------------
    @add("ortho_lit_textured", 76, 58)
    def _(m):
        sc, _ = textured_spot(m, "pbr")
        cam = sr.OrthographicCamera(xmag=1.2, ymag=0.9)
        _look(cam, SPOT_EYE, SPOT_TARGET)
        return sc, cam

    def near_clip(m):  # the near plane cuts a textured, normal-mapped floor and a textured ball
        sc = sr.Scene()
        tex = sr.Texture(checker(32, 4), filter="anisotropic", max_anisotropy=8)
        sc.add(m["checker_floor"], pose=_rot("x", 0.0, -1.0) @ _scale(3.0, 3.0, 1.0),
               material=sr.Material(base_color=GREY, base_color_texture=tex, normal_texture=sr.Texture(normal_map()),
                                    shininess=12.0))
        sc.add(m["ball"], pose=_translate(0.45, 0.3, 0.35, 0.35),
               material=sr.Material(base_color=GREY, base_color_texture=tex, model="pbr", roughness=0.35))
        sc.add(sr.PointLight(intensity=3.0, color=(1.0, 0.95, 0.85)), pose=_translate(0.5, 1.2, 1.0))
        sc.add(sr.SpotLight(intensity=4.0, outer_cone=0.7), pose=_aim((-1.0, 1.5, 0.5), (0.0, 0.0, 0.0)))
        sc.ambient_light = (0.1, 0.1, 0.1)
        return sc, _persp((0.0, 0.3, 0.9), (0.1, 0.15, 0.0), fov=75, near=0.55)

    add("near_clip_lit_textured", 64, 48, cull="none")(near_clip)
    add("near_clip_lit_textured_face", 64, 48, cull="none", frequency="face")(near_clip)

    return s


SCENES = _scenes()


class _LitKernel:
    """A core renderer whose renders all take the lit kernel (the core's lit_kernel option)."""

    def __init__(self, core) -> None:
        self._core = core

    def render(self, draws, options):
        return self._core.render(draws, dict(options, lit_kernel=True))

    def __getattr__(self, name):
        return getattr(self._core, name)


def render(name: str, simd: bool = True, threads: int = 2, meshes_: dict | None = None,
           lit_kernel: bool = False) -> sr.Frame:
    """A scene's frame; lit_kernel: shaded by the lit kernel where a plain one would serve."""
    w, h, build, options = SCENES[name]
    options = dict(options)
    outputs = options.pop("outputs", NO_COVERAGE)
    options.setdefault("srgb", True)  # pinned: the recorded default
    scene, camera = build(meshes_ or meshes())
    renderer = sr.Renderer(w, h, threads=threads, simd=simd)
    if lit_kernel:
        renderer._core = _LitKernel(renderer._core)
    return renderer.render(scene, camera, outputs=outputs, **options)


def digest(arr: np.ndarray) -> str:
    """SHA-256 of an output's dtype, shape and bytes."""
    arr = np.ascontiguousarray(arr)
    h = hashlib.sha256(f"{arr.dtype.str}{arr.shape}".encode())
    h.update(arr.tobytes())
    return h.hexdigest()


def render_hashes(name: str, simd: bool, threads: int, meshes_: dict | None = None,
                  lit_kernel: bool = False) -> dict[str, str]:
    return {k: digest(v)
            for k, v in render(name, simd, threads, meshes_, lit_kernel).as_dict().items()}


def _nontrivial(name: str, frame: sr.Frame) -> str | None:
    """Why a scene's frame is not worth recording (None if it is)."""
    if frame.color is not None:
        colors = np.unique(frame.color.reshape(-1, 3), axis=0)
        if len(colors) < 8:
            return f"{name}: only {len(colors)} distinct colours"
    cover = frame.mask if frame.mask is not None else (frame.depth > 0 if frame.depth is not None else None)
    if cover is not None and not cover.mean() > 0.05:
        return f"{name}: covers {cover.mean():.0%} of the image"
    return None


def main() -> int:
    meshes_ = meshes()
    if "--png" in sys.argv:
        out = pathlib.Path(sys.argv[sys.argv.index("--png") + 1])
        out.mkdir(parents=True, exist_ok=True)
        for name in SCENES:
            frame = render(name, True, 2, meshes_)
            if frame.color is not None:
                sr.imwrite(str(out / f"{name}.png"), frame.color)
        print(f"wrote {out}")
        return 0
    if "--write" in sys.argv:
        scenes, problems = {}, []
        for name in SCENES:
            frame = render(name, True, 2, meshes_)
            why = _nontrivial(name, frame)
            if why:
                problems.append(why)
            scenes[name] = {k: digest(v) for k, v in frame.as_dict().items()}
        if problems:
            print("refusing to record:\n" + "\n".join(problems))
            return 1
        commit = sys.argv[-1] if len(sys.argv) > 2 and not sys.argv[-1].startswith("-") else ""
        HASHES.write_text(json.dumps({"commit": commit, "scenes": scenes}, indent=1, sort_keys=True) + "\n")
        print(f"wrote {HASHES} ({len(scenes)} scenes)")
        return 0
    want = json.loads(HASHES.read_text())["scenes"]
    bad = [(n, c) for n in SCENES for c in CONFIGS if render_hashes(n, *c, meshes_) != want.get(n)]
    print("\n".join(f"DIFFERS: {n} simd={c[0]} threads={c[1]}" for n, c in bad) or "all identical")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
