"""softrast vs pyrender (OSMesa) vs a bare moderngl pipeline (EGL), all on the CPU: the headline table.

Run ``bash benchmarks/setup_baselines.sh`` once first, then::

    python3 benchmarks/bench_vs_pyrender.py [--quick] [--rows 0,1,4] [--json out.json]
    python3 benchmarks/bench_vs_pyrender.py --lit [--lit-only] [--png DIR]    # the lit rows
    python3 benchmarks/bench_vs_pyrender.py --textured [--png DIR]            # the textured rows
    python3 benchmarks/bench_vs_pyrender.py --aa [--png DIR]                  # the msaa rows
    python3 benchmarks/bench_vs_pyrender.py --points [--png DIR]              # the point cloud
    python3 benchmarks/bench_vs_pyrender.py --ab-python OLD_PY [--new-python NEW_PY]   # A/B, all rows
        [--groups plain,lit,textured,aa,points] [--quick] [--json out.json]
    python3 benchmarks/bench_vs_pyrender.py --ab OLD_PYTHONPATH [--rows 1,2,3,4] [--lit-only]

Scenes: trimesh icospheres (radius 1, smooth normals) seen by a 45-degree perspective camera at a
distance that makes the sphere's silhouette 0.8 of the image height (about half of a square
image), one directional light along the viewing axis, no anti-aliasing, black background.

Every cell is steady state: the scene is uploaded once and the renderer reused; each renderer is
warmed up, then timed for N frames (N chosen so each cell takes ~1.5 s, 0.3 s with --quick), and
the cells of a row are interleaved in rounds so that they share the machine's noise. Times are
medians in ms per frame and include reading the frame back into NumPy arrays.

Columns:
  pyrender   OffscreenRenderer.render(scene, flags): NONE (colour+depth), DEPTH_ONLY, FLAT
  moderngl   a bare pipeline: one lit shader, RGBA8 + depth renderbuffers, fbo.read_into NumPy
             (colour+depth only; the raw [0, 1] depth buffer, not linearised as the others are)
  softrast   Renderer(w, h, threads).render(scene, cam, outputs=...), "out" = into the frame of
             an earlier render (out=frame, as a batch user would), "new" = fresh arrays per frame
Lit rows (--lit; RESULTS.md, "Lit shading"): "blinn_phong" with 4 point lights and "pbr" with one
directional and two point lights, on ico6 at 640x480 and 1024x1024 and on Spot
(assets/meshes/spot.obj, vertices merged, no texture) at 640x480; the same lights, poses, ambient
light and base colour in both renderers. pyrender has no Blinn-Phong: both rows run its standard
metallic-roughness shader (MetallicRoughnessMaterial), which is what a pyrender user would run.
softrast cells: t2 and t1 colour+depth into out=, with the default sRGB-encoded colour, and t2 with
srgb=False (linear).
--png DIR writes each lit row's colour image from each renderer.

A/B, old build vs new build (--ab-python OLD_PY: the rule for kernel changes is no cell more than
3% slower and the same bits in every cell). OLD_PY and NEW_PY (default: the running interpreter)
are Python interpreters, each with its own softrast installed; the old side runs without
PYTHONPATH, so OLD_PY imports only its own build, and NEW_PY given explicitly does too (the
default new side keeps this process's environment). Each side is a worker process running this
file, holding the scenes and renderers of every cell of the chosen groups, built by the same code
as the non-A/B rows (the same scenes, sizes, thread counts and options; with --quick, the rows
their --quick keeps: no 2048x2048 plain row, no lit, textured or aa row above 640x480):
  plain     ROWS, t2 and t1 colour+depth out=          lit       LIT_ROWS, t2, t2 linear, t1
  textured  TEXTURED_ROWS, every softrast column       aa        AA_ROWS, t2, every AA_MODES level
  points    POINT_ROWS, t2 and t1
(--all-cells adds the plain rows' depth, flat and t2 "new" cells and the lit rows' depth and unlit
cells.) The parent alternates blocks of frames between the workers (only one renders at a time;
old first in even rounds, new first in odd ones), cell by cell, --ab-rounds times (16, --quick 8),
~--ab-seconds per cell and build in all (3 s, --quick 0.6 s; at least 3 frames a block), and
prints per cell the old and new median ms over all frames, new/old, the lowest and highest
new/old of one round (the noise), and whether one frame of each build had the same bits (a hash
of every output array, taken after warm-up and again at the end), then the worst new/old.
--ab-cells SUBSTR reruns a few cells. Exit status 1 when a cell's bits differ or a cell exists on
one side only. pyrender is not needed. The noise floor depends on what else the machine runs (the
load average is printed before and after): with the same build on both sides, cells read
0.78-1.22 with --quick at a load of 3-5 on 2 cores, and 0.92-1.06 in a full run at a load of 1.4-2.6.
Rerun a cell above 1.03 (--ab-cells) before believing it.
--ab OLD_PYTHONPATH: the same A/B on this interpreter, softrast from OLD_PYTHONPATH against this
checkout's ../python; default group plain with rows 1-4 (--lit-only: the lit group, --rows then
indexing LIT_ROWS). Both builds run the same calls (colour is sRGB-encoded by default on both
sides: an old build from before srgb= existed (feca5f9) is not comparable).

The "first" column is context + first frame: creating the renderer (and its GL context), uploading
the scene and rendering and reading back one colour+depth frame; scene build (mesh conversion and
Scene construction from a trimesh) is reported apart.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass, field
from typing import Callable

# pyrender reads PYOPENGL_PLATFORM when it is imported: OSMesa is its no-AA CPU path (its EGL
# path forces 4x MSAA; OSMesaPlatform.supports_framebuffers() is False, so OffscreenRenderer draws
# into OSMesa's single-sample buffer: tests/test_pyrender_aliasing.py). moderngl's EGL context
# needs no display with the surfaceless platform.
os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")
os.environ.setdefault("EGL_PLATFORM", "surfaceless")

import numpy as np  # noqa: E402
import trimesh  # noqa: E402

import softrast as sr  # noqa: E402

# (subdivisions, width, height), the plain rows (RESULTS.md, "Against pyrender").
ROWS = [(3, 256, 256), (6, 640, 480), (6, 1024, 1024), (7, 2048, 2048), (8, 1024, 1024)]
FOV_Y_DEG = 45.0
NEAR, FAR = 0.05, 100.0
SILHOUETTE_FRACTION = 0.8  # sphere diameter / image height => ~50% of a square image covered
AMBIENT = 0.25
GOALS = {"color+depth": 30.0, "depth": 10.0, "moderngl": 5.0, "first_over_steady": 3.0}


def camera_distance() -> float:
    """Distance at which a unit sphere's silhouette spans SILHOUETTE_FRACTION of the height."""
    tan_half = math.tan(math.radians(FOV_Y_DEG) / 2)
    alpha = math.atan(SILHOUETTE_FRACTION * tan_half)  # silhouette half-angle: sin(alpha) = 1/d
    return 1.0 / math.sin(alpha)


def camera_pose() -> np.ndarray:
    pose = np.eye(4)
    pose[2, 3] = camera_distance()  # camera-to-world: at +z looking down -z (OpenGL)
    return pose


def fresh_trimesh(base: trimesh.Trimesh) -> trimesh.Trimesh:
    """A copy without trimesh's caches, so each renderer's scene build pays for its own normals."""
    return trimesh.Trimesh(vertices=base.vertices.copy(), faces=base.faces.copy(), process=False)


# ----------------------------------------------------------------------------------- timing


@dataclass
class Cell:
    """One renderer x mode: a callable that renders and reads back one frame."""
    name: str
    frame: Callable[[], object]
    times: list[float] = field(default_factory=list)  # seconds
    n: int = 0

    @property
    def median_ms(self) -> float:
        return 1e3 * statistics.median(self.times) if self.times else float("nan")


def run_interleaved(cells: list[Cell], target_s: float, n_min: int, n_max: int, rounds: int) -> None:
    """Warm up every cell, size N from its warm-up time, then time all cells in rounds."""
    for cell in cells:
        for _ in range(2):
            cell.frame()
        t0 = time.perf_counter()
        cell.frame()
        est = time.perf_counter() - t0
        cell.n = max(n_min, min(n_max, int(target_s / max(est, 1e-6))))
    for r in range(rounds):
        order = cells[r % len(cells):] + cells[:r % len(cells)]  # rotate who goes first
        for cell in order:
            k = math.ceil(cell.n / rounds)
            for _ in range(k):
                t0 = time.perf_counter()
                cell.frame()
                cell.times.append(time.perf_counter() - t0)


def time_row(cells: list[Cell], what: str, label: str, target_s: float, n_min: int, n_max: int,
             rounds: int, **extra: object) -> dict:
    """Times one row's cells (run_interleaved), prints them, and returns {"row", "ms", **extra}."""
    run_interleaved(cells, target_s, n_min, n_max, rounds)
    row = {"row": label, **extra, "ms": {c.name: c.median_ms for c in cells}}
    print(f"  done {what} {label}: " + ", ".join(f"{k} {v:.2f}" for k, v in row["ms"].items()), flush=True)
    return row


def timed_once(fn: Callable[[], object]) -> tuple[float, object]:
    t0 = time.perf_counter()
    result = fn()
    return 1e3 * (time.perf_counter() - t0), result


# ----------------------------------------------------------------------------- baselines


def import_pyrender():
    """pyrender or the reason it cannot run here."""
    try:
        import pyrender  # noqa: F401
        return pyrender, None
    except Exception as exc:  # noqa: BLE001 - report whatever broke
        return None, f"import pyrender failed: {type(exc).__name__}: {exc}"


def import_moderngl():
    try:
        import moderngl  # noqa: F401
        return moderngl, None
    except Exception as exc:  # noqa: BLE001
        return None, f"import moderngl failed: {type(exc).__name__}: {exc}"


class PyrenderRow:
    """pyrender scene (mesh, camera, one directional light) and an OffscreenRenderer for a row."""

    def __init__(self, pyrender, tm: trimesh.Trimesh, width: int, height: int) -> None:
        self.pyrender = pyrender
        self.build_ms, self.scene = timed_once(lambda: self._scene(fresh_trimesh(tm), width, height))
        self.first_ms, self.renderer = timed_once(lambda: self._first(width, height))

    def _scene(self, tm, width, height):
        pr = self.pyrender
        scene = pr.Scene(ambient_light=[AMBIENT] * 3, bg_color=[0.0, 0.0, 0.0, 0.0])
        scene.add(pr.Mesh.from_trimesh(tm, smooth=True))
        pose = camera_pose()
        scene.add(pr.PerspectiveCamera(yfov=math.radians(FOV_Y_DEG), aspectRatio=width / height,
                                       znear=NEAR, zfar=FAR), pose=pose)
        scene.add(pr.DirectionalLight(color=[1.0, 1.0, 1.0], intensity=3.0), pose=pose)
        return scene

    def _first(self, width, height):
        renderer = self.pyrender.OffscreenRenderer(width, height)
        renderer.render(self.scene)  # context + upload + first frame + readback
        return renderer

    def cells(self) -> list[Cell]:
        flags = self.pyrender.RenderFlags
        r, s = self.renderer, self.scene
        return [Cell("pyrender color+depth", lambda: r.render(s)),
                Cell("pyrender depth", lambda: r.render(s, flags=flags.DEPTH_ONLY)),
                Cell("pyrender flat", lambda: r.render(s, flags=flags.FLAT))]

    def close(self) -> None:
        self.renderer.delete()


VERTEX_SHADER = """
#version 330
uniform mat4 mvp;
uniform mat3 normal_view;
in vec3 in_position;
in vec3 in_normal;
out vec3 v_normal_view;
void main() {
    gl_Position = mvp * vec4(in_position, 1.0);
    v_normal_view = normal_view * in_normal;
}
"""
FRAGMENT_SHADER = """
#version 330
uniform vec3 base_color;
uniform float ambient;
in vec3 v_normal_view;
out vec4 f_color;
void main() {
    float lambert = abs(normalize(v_normal_view).z);  // headlight along the view axis, two-sided
    f_color = vec4(base_color * (ambient + (1.0 - ambient) * lambert), 1.0);
}
"""


def perspective(fov_y_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    f = 1.0 / math.tan(math.radians(fov_y_deg) / 2)
    return np.array([[f / aspect, 0, 0, 0], [0, f, 0, 0],
                     [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)],
                     [0, 0, -1, 0]])


class ModernglRow:
    """A bare moderngl pipeline: one VAO, one lit program, colour + depth renderbuffers."""

    def __init__(self, moderngl, tm: trimesh.Trimesh, width: int, height: int) -> None:
        self.moderngl = moderngl
        self.width, self.height = width, height
        self.build_ms, arrays = timed_once(lambda: self._arrays(fresh_trimesh(tm)))
        self.first_ms, _ = timed_once(lambda: self._first(arrays))

    @staticmethod
    def _arrays(tm):
        vertices = np.hstack([tm.vertices, tm.vertex_normals]).astype(np.float32)
        return np.ascontiguousarray(vertices), np.ascontiguousarray(tm.faces, dtype=np.int32)

    def _first(self, arrays):
        mgl = self.moderngl
        w, h = self.width, self.height
        self.ctx = ctx = mgl.create_standalone_context(backend="egl")
        with ctx:
            prog = ctx.program(vertex_shader=VERTEX_SHADER, fragment_shader=FRAGMENT_SHADER)
            view = np.linalg.inv(camera_pose())
            mvp = perspective(FOV_Y_DEG, w / h, NEAR, FAR) @ view
            prog["mvp"].write(mvp.T.astype(np.float32).tobytes())  # GL is column-major
            prog["normal_view"].write(np.linalg.inv(view[:3, :3]).astype(np.float32).tobytes())
            prog["base_color"].value = (1.0, 1.0, 1.0)
            prog["ambient"].value = AMBIENT
            vertices, faces = arrays
            vbo, ibo = ctx.buffer(vertices.tobytes()), ctx.buffer(faces.tobytes())
            self.vao = ctx.vertex_array(prog, [(vbo, "3f 3f", "in_position", "in_normal")],
                                        index_buffer=ibo, index_element_size=4)
            self.fbo = ctx.framebuffer(color_attachments=[ctx.renderbuffer((w, h), 4)],
                                       depth_attachment=ctx.depth_renderbuffer((w, h)))
            ctx.enable(mgl.DEPTH_TEST | mgl.CULL_FACE)
            self.color = np.empty((h, w, 3), np.uint8)
            self.depth = np.empty((h, w), np.float32)
            self.frame()

    def frame(self):
        with self.ctx:  # pyrender's OSMesa context may be current in between
            self.fbo.use()
            self.fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            self.vao.render(self.moderngl.TRIANGLES)
            self.fbo.read_into(self.color, components=3)
            self.fbo.read_into(self.depth, attachment=-1, dtype="f4")
        return self.color, self.depth

    def cells(self) -> list[Cell]:
        return [Cell("moderngl color+depth", self.frame)]

    def close(self) -> None:
        self.ctx.release()


class SoftrastRow:
    """softrast scene and one Renderer per thread count."""

    def __init__(self, tm: trimesh.Trimesh, width: int, height: int, threads: tuple[int, ...]) -> None:
        self.build_ms, self.scene = timed_once(lambda: self._scene(fresh_trimesh(tm)))
        self.cam = sr.PerspectiveCamera(fov_y=FOV_Y_DEG, width=width, height=height, near=NEAR, far=FAR)
        self.cam.pose = camera_pose()
        self.renderers, self.first_ms = {}, {}
        for t in threads:
            self.first_ms[t], self.renderers[t] = timed_once(lambda t=t: self._first(width, height, t))
        self.coverage = float((self.renderers[threads[0]].render(self.scene, self.cam).depth > 0).mean())

    @staticmethod
    def _scene(tm):
        scene = sr.Scene()
        scene.add(sr.Mesh.from_trimesh(tm), color=(1.0, 1.0, 1.0))
        return scene

    def _first(self, width, height, threads):
        renderer = sr.Renderer(width, height, threads=threads)
        renderer.render(self.scene, self.cam, outputs=("color", "depth"))
        return renderer

    def cells(self) -> list[Cell]:
        cells = []
        s, cam = self.scene, self.cam
        for t, r in self.renderers.items():
            cd, d = r.render(s, cam), r.render(s, cam, outputs=("depth",))
            flat = r.render(s, cam, shading="unlit")
            cells += [
                Cell(f"softrast t{t} color+depth out",
                     lambda r=r, f=cd: r.render(s, cam, outputs=("color", "depth"), out=f)),
                Cell(f"softrast t{t} depth out",
                     lambda r=r, f=d: r.render(s, cam, outputs=("depth",), out=f)),
                Cell(f"softrast t{t} flat out",
                     lambda r=r, f=flat: r.render(s, cam, outputs=("color", "depth"), shading="unlit", out=f)),
            ]
            if t == max(self.renderers):
                cells.append(Cell(f"softrast t{t} color+depth new",
                                  lambda r=r: r.render(s, cam, outputs=("color", "depth"))))
        return cells


# -------------------------------------------------------- lit rows (RESULTS.md, "Lit shading")

# (model, scene, width, height): scene is "ico6" or "spot".
LIT_ROWS = [("blinn_phong", "ico6", 640, 480), ("blinn_phong", "ico6", 1024, 1024),
            ("blinn_phong", "spot", 640, 480), ("pbr", "ico6", 640, 480),
            ("pbr", "ico6", 1024, 1024), ("pbr", "spot", 640, 480)]
LIT_GOAL = 20.0  # lit rows >= 20x pyrender (RESULTS.md, "Lit shading")
LIT_BASE = (0.8, 0.5, 0.3)  # linear base colour of every lit row
LIT_AMBIENT = 0.05
SPOT_PATH = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "assets", "meshes",
                         "spot.obj")
# Point lights: (offset in the camera's axes, in units of the object's radius, RGB); intensity
# scaled by radius**2 so every scene gets the same irradiance. Offsets are towards the camera.
LIT_POINTS = {"blinn_phong": [((1.5, 1.5, 1.5), (1.0, 0.9, 0.8)), ((-1.5, 1.5, 1.5), (0.8, 0.9, 1.0)),
                              ((1.5, -1.5, 1.5), (0.9, 1.0, 0.9)), ((-1.5, -1.5, 1.5), (1.0, 1.0, 1.0))],
              "pbr": [((1.5, 1.5, 1.5), (1.0, 0.9, 0.8)), ((-1.5, -1.0, 1.5), (0.8, 0.9, 1.0))]}
LIT_POINT_INTENSITY = {"blinn_phong": 3.0, "pbr": 6.0}
LIT_DIRECTIONAL = {"pbr": [((-0.4, 0.6, 1.0), (1.0, 1.0, 1.0), 2.0)]}  # from the light, camera axes


def look_at(eye, target, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """A 4x4 pose (OpenGL: -z towards target) at eye."""
    eye, target, up = (np.asarray(v, float) for v in (eye, target, up))
    z = eye - target
    z /= np.linalg.norm(z)
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, np.cross(z, x), z, eye
    return pose


class LitScene:
    """The geometry, camera pose and lights (world poses) of one lit row, for both renderers."""

    def __init__(self, model: str, scene: str, width: int, height: int) -> None:
        self.model, self.name, self.width, self.height = model, scene, width, height
        if scene == "spot":
            raw = trimesh.load(SPOT_PATH, force="mesh", process=False)
            # Only the geometry: vertices merged across the texture seams, no texture.
            self.tm = trimesh.Trimesh(vertices=raw.vertices, faces=raw.faces, process=True)
            centre = self.tm.bounds.mean(axis=0)
            radius = float(np.linalg.norm(self.tm.vertices - centre, axis=1).max())
            view_dir = np.array([1.0, 0.4, 1.0]) / np.linalg.norm([1.0, 0.4, 1.0])  # 3/4 view
        else:
            self.tm = trimesh.creation.icosphere(subdivisions=int(scene[3:]), radius=1.0)
            centre, radius, view_dir = np.zeros(3), 1.0, np.array([0.0, 0.0, 1.0])
        self.cam_pose = look_at(centre + radius * camera_distance() * view_dir, centre)
        rot = self.cam_pose[:3, :3]
        self.points = []  # (pose, rgb, intensity)
        for offset, rgb in LIT_POINTS[model]:
            pose = np.eye(4)
            pose[:3, 3] = centre + radius * (rot @ np.asarray(offset))
            self.points.append((pose, rgb, LIT_POINT_INTENSITY[model] * radius ** 2))
        self.directionals = []
        for from_dir, rgb, intensity in LIT_DIRECTIONAL.get(model, []):
            d = rot @ np.asarray(from_dir, float)
            self.directionals.append((look_at(centre + d, centre), rgb, intensity))

    @property
    def label(self) -> str:
        return f"{self.model} {self.name} {self.width}x{self.height}"


class PyrenderLitRow(PyrenderRow):
    """pyrender with the lit row's lights and a MetallicRoughnessMaterial (its standard shader)."""

    def __init__(self, pyrender, lit: LitScene) -> None:
        self.lit = lit
        super().__init__(pyrender, lit.tm, lit.width, lit.height)

    def _scene(self, tm, width, height):
        pr, lit = self.pyrender, self.lit
        scene = pr.Scene(ambient_light=[LIT_AMBIENT] * 3, bg_color=[0.0, 0.0, 0.0, 0.0])
        metallic, roughness = (0.2, 0.4) if lit.model == "pbr" else (0.0, 0.5)
        material = pr.MetallicRoughnessMaterial(baseColorFactor=(*LIT_BASE, 1.0), metallicFactor=metallic,
                                                roughnessFactor=roughness)
        scene.add(pr.Mesh.from_trimesh(tm, material=material, smooth=True))
        scene.add(pr.PerspectiveCamera(yfov=math.radians(FOV_Y_DEG), aspectRatio=width / height,
                                       znear=NEAR, zfar=FAR), pose=lit.cam_pose)
        for pose, rgb, intensity in lit.points:
            scene.add(pr.PointLight(color=rgb, intensity=intensity), pose=pose)
        for pose, rgb, intensity in lit.directionals:
            scene.add(pr.DirectionalLight(color=rgb, intensity=intensity), pose=pose)
        return scene

    def cells(self) -> list[Cell]:
        r, s = self.renderer, self.scene
        return [Cell("pyrender color+depth", lambda: r.render(s))]


class SoftrastLitRow:
    """softrast with the lit row's lights and material; t2 and t1 renderers."""

    def __init__(self, lit: LitScene, threads: tuple[int, ...] = (2, 1)) -> None:
        self.lit = lit
        self.build_ms, self.scene = timed_once(lambda: self._scene(fresh_trimesh(lit.tm)))
        self.cam = sr.PerspectiveCamera(fov_y=FOV_Y_DEG, width=lit.width, height=lit.height, near=NEAR, far=FAR)
        self.cam.pose = lit.cam_pose
        self.kwargs = dict(outputs=("color", "depth"), shading=lit.model, frequency="pixel")
        self.renderers, self.first_ms = {}, {}
        for t in threads:
            self.first_ms[t], self.renderers[t] = timed_once(
                lambda t=t: self._first(lit.width, lit.height, t))
        self.coverage = float((self.renderers[threads[0]].render(self.scene, self.cam, **self.kwargs)
                               .depth > 0).mean())

    def _scene(self, tm):
        lit = self.lit
        scene = sr.Scene(ambient_light=(LIT_AMBIENT,) * 3)
        if lit.model == "pbr":
            material = sr.Material(base_color=LIT_BASE, metallic=0.2, roughness=0.4, model="pbr")
        else:
            material = sr.Material(base_color=LIT_BASE, ks=(0.5, 0.5, 0.5), shininess=32.0, model="blinn_phong")
        scene.add(sr.Mesh.from_trimesh(tm), material=material)
        for pose, rgb, intensity in lit.points:
            scene.add(sr.PointLight(color=rgb, intensity=intensity), pose=pose)
        for pose, rgb, intensity in lit.directionals:
            scene.add(sr.DirectionalLight(color=rgb, intensity=intensity), pose=pose)
        return scene

    def _first(self, width, height, threads):
        renderer = sr.Renderer(width, height, threads=threads)
        renderer.render(self.scene, self.cam, **self.kwargs)
        return renderer

    def cells(self) -> list[Cell]:
        s, cam, kw = self.scene, self.cam, self.kwargs
        cells = []
        for t, r in self.renderers.items():
            f = r.render(s, cam, **kw)
            cells.append(Cell(f"softrast t{t} color+depth out",
                              lambda r=r, f=f: r.render(s, cam, out=f, **kw)))
            if t == max(self.renderers):
                lin = r.render(s, cam, srgb=False, **kw)
                cells.append(Cell(f"softrast t{t} color+depth out linear",
                                  lambda r=r, f=lin: r.render(s, cam, out=f, srgb=False, **kw)))
                # The floor under the lit frame: the same geometry with no lighting at all.
                for label, extra in (("depth", dict(outputs=("depth",))),
                                     ("unlit color+depth", dict(shading="unlit"))):
                    kw2 = dict(kw, **extra)
                    f2 = r.render(s, cam, **kw2)
                    cells.append(Cell(f"softrast t{t} {label} out",
                                      lambda r=r, f=f2, kw2=kw2: r.render(s, cam, out=f, **kw2)))
        return cells


def run_lit(rows, pyrender, pyrender_error, target_s, n_min, n_max, rounds, png_dir) -> list[dict]:
    results = []
    for model, scene_name, w, h in rows:
        lit = LitScene(model, scene_name, w, h)
        res = {"row": lit.label, "model": model, "scene": scene_name, "faces": len(lit.tm.faces),
               "width": w, "height": h, "errors": {}}
        cells: list[Cell] = []
        pr = None
        if pyrender is not None:
            try:
                pr = PyrenderLitRow(pyrender, lit)
                cells += pr.cells()
            except Exception as exc:  # noqa: BLE001
                res["errors"]["pyrender"] = f"{type(exc).__name__}: {exc}"
        srow = SoftrastLitRow(lit)
        cells += srow.cells()
        if png_dir:
            os.makedirs(png_dir, exist_ok=True)
            stem = os.path.join(png_dir, f"{model}_{scene_name}_{w}x{h}")
            sr.imwrite(stem + "_softrast.png", srow.renderers[2].render(srow.scene, srow.cam, **srow.kwargs).color)
            if pr is not None:
                sr.imwrite(stem + "_pyrender.png", pr.renderer.render(pr.scene)[0])
        run_interleaved(cells, target_s, n_min, n_max, rounds)
        res["ms"] = {c.name: c.median_ms for c in cells}
        res["n"] = {c.name: len(c.times) for c in cells}
        res["coverage"] = srow.coverage
        res["first_ms"] = {"pyrender": pr.first_ms if pr else float("nan"),
                           **{f"softrast t{t}": v for t, v in srow.first_ms.items()}}
        if pr is not None:
            pr.close()
        results.append(res)
        print(f"  done {lit.label}: " + ", ".join(f"{k} {v:.2f}" for k, v in res["ms"].items()), flush=True)
    return results


def report_lit(results: list[dict]) -> None:
    get = lambda r, k: r["ms"].get(k, float("nan"))  # noqa: E731
    print("\nLit rows: median ms per colour+depth frame (steady state, out=, readback included);"
          "\npyrender runs its standard metallic-roughness shader for both models (it has no Blinn-Phong);"
          "\nsr = softrast (sRGB-encoded colour unless 'lin'), t2/t1 = threads")
    head = (f"{'model':<12}{'scene':<7}{'faces':>8}{'size':>10}{'cover':>6}{'pyrender':>9}{'sr t2':>8}"
            f"{'sr t2 lin':>10}{'sr t1':>8}{'xpyr t2':>9}{'xpyr t1':>9}  goal >= {LIT_GOAL:.0f}x (t2)")
    print(head)
    print("-" * len(head))
    for r in results:
        pyr, t2, lin, t1 = (get(r, k) for k in ("pyrender color+depth", "softrast t2 color+depth out",
                                                "softrast t2 color+depth out linear",
                                                "softrast t1 color+depth out"))
        x = ratio(pyr, t2)
        status = verdict(x, LIT_GOAL)
        print(f"{r['model']:<12}{r['scene']:<7}{r['faces']:>8,}{str(r['width']) + 'x' + str(r['height']):>10}"
              f"{100 * r['coverage']:>5.0f}%{fmt(pyr, 9)}{fmt(t2, 8, 2)}{fmt(lin, 10, 2)}{fmt(t1, 8, 2)}"
              f"{fmt(ratio(pyr, t2), 9)}{fmt(ratio(pyr, t1), 9)}  {status}")
    errors = {k: v for r in results for k, v in r["errors"].items()}
    for name, err in errors.items():
        print(f"  {name}: {err}")
    report_lit_floor(results)


def report_lit_floor(results: list[dict]) -> None:
    """The goal's frame time (pyrender / 20) next to the row's frames without lighting."""
    print(f"\nThe goal's frame time (pyrender / {LIT_GOAL:.0f}) against the same row's softrast frames"
          "\nwithout lighting (t2): depth only, and unlit colour+depth (interpolated base colour, sRGB)")
    names = ("pyrender color+depth", "softrast t2 depth out", "softrast t2 unlit color+depth out",
             "softrast t2 color+depth out")
    cols = ("goal ms", "depth", "unlit", "lit", "goal/depth", "goal/unlit")
    print(f"{'row':<32}" + "".join(f"{c:>11}" for c in cols))
    for r in results:
        pyr, depth, unlit, lit = (r["ms"].get(k, float("nan")) for k in names)
        goal = pyr / LIT_GOAL
        values = (goal, depth, unlit, lit, ratio(goal, depth), ratio(goal, unlit))
        print(f"{r['row']:<32}" + "".join(fmt(v, 11, 2) for v in values))


# ---------------------------------------------------- textured rows (RESULTS.md, "Textures")

TEXTURED_ROWS = [("spot", 640, 480), ("spot", 1024, 1024), ("box", 640, 480)]
TEXTURED_GOAL = 20.0  # textured rows >= 20x pyrender (RESULTS.md, "Textures")


def textured_trimesh_scene(name: str) -> "trimesh.Scene":
    """Spot with its 1024x1024 texture, or BoxTextured (both in assets/meshes)."""
    from PIL import Image

    if name == "spot":
        tm = trimesh.load(SPOT_PATH, force="mesh", process=False)
        image = Image.open(os.path.join(os.path.dirname(SPOT_PATH), "spot_texture.png"))
        tm.visual = trimesh.visual.TextureVisuals(uv=tm.visual.uv, image=image)
        return trimesh.Scene(tm)
    return trimesh.load(os.path.join(os.path.dirname(SPOT_PATH), "BoxTextured.gltf"))


class TexturedRow:
    """One textured row for both renderers: pyrender's standard shader with the file's base
    colour texture, softrast's "pbr" with the same texture (trilinear), one directional light
    along the view and an ambient light, colour+depth."""

    def __init__(self, pyrender, name: str, width: int, height: int) -> None:
        self.name, self.width, self.height = name, width, height
        tscene = textured_trimesh_scene(name)
        lo, hi = tscene.bounds
        centre, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo) / 2)
        view_dir = np.array([1.0, 0.4, 1.0]) / np.linalg.norm([1.0, 0.4, 1.0])
        self.cam_pose = look_at(centre + radius * camera_distance() * view_dir, centre)
        self.pr = None
        if pyrender is not None:
            pr = pyrender
            scene = pr.Scene.from_trimesh_scene(tscene, ambient_light=[LIT_AMBIENT] * 3,
                                                bg_color=[0.0, 0.0, 0.0, 0.0])
            scene.add(pr.PerspectiveCamera(yfov=math.radians(FOV_Y_DEG), aspectRatio=width / height,
                                           znear=NEAR, zfar=FAR), pose=self.cam_pose)
            scene.add(pr.DirectionalLight(color=[1.0, 1.0, 1.0], intensity=3.0), pose=self.cam_pose)
            self.pr_scene = scene
            self.pr = pr.OffscreenRenderer(width, height)
            self.pr.render(scene)
        self.scene = sr.Scene(ambient_light=(LIT_AMBIENT,) * 3)
        # The same meshes without their texture: the floor any texture sampler sits on.
        self.plain = sr.Scene(ambient_light=(LIT_AMBIENT,) * 3)
        textures: dict[int, sr.Texture] = {}
        for node in tscene.graph.nodes_geometry:
            pose, geom_name = tscene.graph[node]
            g = tscene.geometry[geom_name]
            mat = g.visual.material
            image = getattr(mat, "baseColorTexture", None) or getattr(mat, "image", None)
            tex = textures.setdefault(id(image), sr.Texture(np.asarray(image.convert("RGB"))))
            material = sr.Material(base_color=(1, 1, 1, 1), metallic=0.0, roughness=1.0,
                                   base_color_texture=tex, model="pbr")
            mesh = sr.Mesh(g.vertices, g.faces, normals=g.vertex_normals, uvs=g.visual.uv,
                           material=material)
            self.scene.add(mesh, pose=pose)
            self.plain.add(mesh, pose=pose, material=material.replace(base_color_texture=None,
                                                                      base_color=(0.8, 0.8, 0.8, 1)))
        self.scene.add(sr.DirectionalLight(intensity=3.0), pose=self.cam_pose)
        self.plain.add(sr.DirectionalLight(intensity=3.0), pose=self.cam_pose)
        self.cam = sr.PerspectiveCamera(fov_y=FOV_Y_DEG, width=width, height=height, near=NEAR, far=FAR)
        self.cam.pose = self.cam_pose
        self.renderers = {t: sr.Renderer(width, height, threads=t) for t in (2, 1)}
        self.kwargs = dict(outputs=("color", "depth"))
        self.coverage = float((self.renderers[2].render(self.scene, self.cam, **self.kwargs).depth > 0).mean())

    @property
    def label(self) -> str:
        return f"{self.name} {self.width}x{self.height}"

    def cells(self) -> list[Cell]:
        s, cam, kw = self.scene, self.cam, self.kwargs
        cells = []
        if self.pr is not None:
            r, ps = self.pr, self.pr_scene
            cells.append(Cell("pyrender color+depth", lambda r=r, ps=ps: r.render(ps)))
        for t, r in self.renderers.items():
            f = r.render(s, cam, **kw)
            cells.append(Cell(f"softrast t{t} color+depth out", lambda r=r, f=f: r.render(s, cam, out=f, **kw)))
            if t == 2:
                for filt in ("nearest", "bilinear", "anisotropic"):
                    cells.append(Cell(f"softrast t2 {filt}", lambda r=r, f=f, filt=filt: r.render(
                        s, cam, out=f, texture_filter=filt, **kw)))
                cells.append(Cell("softrast t2 untextured", lambda r=r, f=f: r.render(
                    self.plain, cam, out=f, **kw)))
        return cells


def run_textured(pyrender, target_s, n_min, n_max, rounds, png_dir, quick) -> list[dict]:
    results = []
    for name, w, h in TEXTURED_ROWS:
        if quick and w * h > 640 * 480:
            continue
        row = TexturedRow(pyrender, name, w, h)
        if png_dir:
            os.makedirs(png_dir, exist_ok=True)
            sr.imwrite(os.path.join(png_dir, f"textured_{name}_{w}x{h}_softrast.png"),
                       row.renderers[2].render(row.scene, row.cam, **row.kwargs).color)
            if row.pr is not None:
                sr.imwrite(os.path.join(png_dir, f"textured_{name}_{w}x{h}_pyrender.png"),
                           row.pr.render(row.pr_scene)[0])
        cells = row.cells()
        results.append(time_row(cells, "textured", row.label, target_s, n_min, n_max, rounds,
                                coverage=row.coverage))
        if row.pr is not None:
            row.pr.delete()
    return results


def report_textured(results: list[dict]) -> None:
    get = lambda r, k: r["ms"].get(k, float("nan"))  # noqa: E731
    print("\nTextured rows: median ms per colour+depth frame; pyrender's standard shader with"
          "\nthe base colour texture vs softrast pbr + texture (trilinear unless named), t2/t1 = threads")
    head = (f"{'row':<18}{'cover':>6}{'pyrender':>9}{'sr t2':>8}{'sr t1':>8}{'nearest':>8}{'bilin':>8}"
            f"{'aniso':>8}{'untex':>8}{'xpyr t2':>9}{'untex x':>9}  goal >= {TEXTURED_GOAL:.0f}x")
    print(head)
    print("-" * len(head))
    for r in results:
        pyr, t2, t1 = pyrender_t2_t1(r)
        x = ratio(pyr, t2)
        status = verdict(x, TEXTURED_GOAL)
        print(f"{r['row']:<18}{100 * r['coverage']:>5.0f}%{fmt(pyr, 9)}{fmt(t2, 8, 2)}{fmt(t1, 8, 2)}"
              f"{fmt(get(r, 'softrast t2 nearest'), 8, 2)}{fmt(get(r, 'softrast t2 bilinear'), 8, 2)}"
              f"{fmt(get(r, 'softrast t2 anisotropic'), 8, 2)}{fmt(get(r, 'softrast t2 untextured'), 8, 2)}"
              f"{fmt(x, 9)}{fmt(ratio(pyr, get(r, 'softrast t2 untextured')), 9)}  {status}")
    print("(untex: the same meshes and light without the texture, softrast t2: the floor of the"
          "\n textured time; untex x: pyrender's textured time over it)")


# ---------------------------------------------- anti-aliasing (RESULTS.md, "Anti-aliasing")

AA_ROWS = [(6, 640, 480), (6, 1024, 1024)]
AA_GOAL = 20.0  # msaa=4 colour+depth >= 20x pyrender (aliased here: OSMesa, 1 sample; RESULTS.md,
#                 "Anti-aliasing")
AA_MODES = [("msaa1", {}), ("msaa4", dict(msaa=4)), ("msaa8", dict(msaa=8)),
            ("msaa16", dict(msaa=16)), ("ssaa2", dict(ssaa=2)), ("ssaa4", dict(ssaa=4))]


def run_aa(pyrender, target_s, n_min, n_max, rounds, png_dir, quick) -> list[dict]:
    """The Lambert rows' scene, colour+depth: pyrender's OffscreenRenderer against softrast at
    each anti-aliasing level, 2 threads, out=. Under OSMesa pyrender renders aliased (one sample
    per pixel: its 4-sample framebuffer, renderer.py's _configure_main_framebuffer, is made only
    on platforms that support framebuffers, EGL and pyglet; tests/test_pyrender_aliasing.py)."""
    results = []
    for sub, w, h in AA_ROWS:
        if quick and w * h > 640 * 480:
            continue
        base = trimesh.creation.icosphere(subdivisions=sub, radius=1.0)
        cells: list[Cell] = []
        pr = None
        if pyrender is not None:
            pr = PyrenderRow(pyrender, base, w, h)
            cells.append(pr.cells()[0])
        srow = SoftrastRow(base, w, h, threads=(2,))
        r, s, cam = srow.renderers[2], srow.scene, srow.cam
        for label, mode in AA_MODES:
            f = r.render(s, cam, outputs=("color", "depth"), **mode)
            cells.append(Cell(f"softrast t2 {label}", lambda f=f, mode=mode: r.render(
                s, cam, outputs=("color", "depth"), out=f, **mode)))
            if png_dir:
                os.makedirs(png_dir, exist_ok=True)
                sr.imwrite(os.path.join(png_dir, f"aa_ico{sub}_{w}x{h}_{label}.png"), f.color)
        if png_dir and pr is not None:
            sr.imwrite(os.path.join(png_dir, f"aa_ico{sub}_{w}x{h}_pyrender.png"),
                       pr.renderer.render(pr.scene)[0])
        results.append(time_row(cells, "aa", f"ico{sub} {w}x{h}", target_s, n_min, n_max, rounds,
                                coverage=srow.coverage))
        if pr is not None:
            pr.close()
    return results


def report_aa(results: list[dict]) -> None:
    get = lambda r, k: r["ms"].get(k, float("nan"))  # noqa: E731
    print("\nAnti-aliasing rows: median ms per colour+depth frame, softrast t2 out=;"
          "\npyrender under OSMesa is aliased (1 sample per pixel; its 4x MSAA is EGL / on-screen only)")
    head = (f"{'row':<16}{'pyrender':>9}" + "".join(f"{label:>8}" for label, _ in AA_MODES)
            + f"{'x pyr m4':>9}{'m4/m1':>7}  goal >= {AA_GOAL:.0f}x")
    print(head)
    print("-" * len(head))
    for r in results:
        pyr, m1, m4 = get(r, "pyrender color+depth"), get(r, "softrast t2 msaa1"), get(r, "softrast t2 msaa4")
        x = ratio(pyr, m4)
        status = verdict(x, AA_GOAL)
        print(f"{r['row']:<16}{fmt(pyr, 9)}" + "".join(fmt(get(r, f"softrast t2 {label}"), 8, 2)
                                                    for label, _ in AA_MODES)
              + f"{fmt(x, 9)}{fmt(ratio(m4, m1), 7, 2)}  {status}")
    print(f"The goal's frame time (pyrender / {AA_GOAL:.0f}) against softrast's frame without anti-aliasing:")
    for r in results:
        pyr, m1 = get(r, "pyrender color+depth"), get(r, "softrast t2 msaa1")
        goal = pyr / AA_GOAL
        print(f"  {r['row']:<16} goal {fmt(goal, 0, 2)} ms, msaa1 {fmt(m1, 0, 2)} ms: msaa=4 would have to cost "
              f"{fmt(ratio(goal, m1), 0, 2)}x a render without it")


# -------------------------------------------- point clouds (RESULTS.md, "Lines and points")

POINT_ROWS = [(1_000_000, 1024, 1024)]
POINTS_GOAL = 20.0  # a 1M-point cloud at 1024x1024 >= 20x pyrender's points (RESULTS.md,
#                     "Lines and points")


def run_points(pyrender, target_s, n_min, n_max, rounds, png_dir) -> list[dict]:
    """n random points in a unit ball, per-point colours, one pixel each, colour+depth:
    pyrender's Mesh.from_points (GL_POINTS, point_size 1, aliased under OSMesa) against
    softrast.Points (1 and 2 threads, out=)."""
    results = []
    for n, w, h in POINT_ROWS:
        rng = np.random.default_rng(0)
        xyz = rng.normal(size=(n, 3))
        xyz *= (rng.uniform(size=(n, 1)) ** (1 / 3)) / np.linalg.norm(xyz, axis=1, keepdims=True)
        rgb = rng.uniform(size=(n, 3))
        cells: list[Cell] = []
        pose = camera_pose()
        pr_renderer = None
        if pyrender is not None:
            pr = pyrender
            scene = pr.Scene(bg_color=[0.0, 0.0, 0.0, 0.0], ambient_light=[1.0, 1.0, 1.0])  # (unlit points)
            scene.add(pr.Mesh.from_points(xyz, colors=rgb))
            scene.add(pr.PerspectiveCamera(yfov=math.radians(FOV_Y_DEG), aspectRatio=w / h, znear=NEAR,
                                           zfar=FAR), pose=pose)
            pr_renderer = pr.OffscreenRenderer(w, h, point_size=1.0)
            pr_renderer.render(scene)
            cells.append(Cell("pyrender color+depth", lambda: pr_renderer.render(scene)))
            if png_dir:
                os.makedirs(png_dir, exist_ok=True)
                sr.imwrite(os.path.join(png_dir, f"points_{n}_{w}x{h}_pyrender.png"), pr_renderer.render(scene)[0])
        s = sr.Scene()
        s.add(sr.Points(xyz, colors=rgb))
        cam = sr.PerspectiveCamera(fov_y=FOV_Y_DEG, width=w, height=h, near=NEAR, far=FAR)
        cam.pose = pose
        for t in (2, 1):
            r = sr.Renderer(w, h, threads=t)
            f = r.render(s, cam, outputs=("color", "depth"))
            cells.append(Cell(f"softrast t{t} color+depth out", lambda r=r, f=f: r.render(
                s, cam, outputs=("color", "depth"), out=f)))
            if png_dir and t == 2:
                sr.imwrite(os.path.join(png_dir, f"points_{n}_{w}x{h}_softrast.png"), f.color)
        results.append(time_row(cells, "points", f"{n // 1000}k points {w}x{h}", target_s, n_min,
                                n_max, rounds))
        if pr_renderer is not None:
            pr_renderer.delete()
    return results


def report_points(results: list[dict]) -> None:
    print("\nPoint cloud rows: median ms per colour+depth frame, out=")
    head = f"{'row':<26}{'pyrender':>9}{'sr t2':>8}{'sr t1':>8}{'x pyr t2':>9}  goal >= {POINTS_GOAL:.0f}x"
    print(head)
    print("-" * len(head))
    for r in results:
        pyr, t2, t1 = pyrender_t2_t1(r)
        x = ratio(pyr, t2)
        print(f"{r['row']:<26}{fmt(pyr, 9)}{fmt(t2, 8, 2)}{fmt(t1, 8, 2)}{fmt(x, 9)}  {verdict(x, POINTS_GOAL)}")


# ------------------------------------------------------------------- A/B: old build vs new build

AB_GROUPS = ("plain", "lit", "textured", "aa", "points")
AB_LIMIT = 1.03  # the rule for kernel changes: no cell slower than this (new / old)


def ab_rows(groups: list[str], quick: bool, rows_arg: str | None, legacy: bool, lit_only: bool) -> dict:
    """The rows each group's cells use: those of the group's non-A/B run (with --quick, the same rows
    --quick keeps). --rows indexes ROWS (the plain group); with --ab and --lit-only, LIT_ROWS."""
    small = lambda w, h: not quick or w * h <= 640 * 480  # noqa: E731 (what --quick keeps elsewhere)
    rows = {"plain": [r for r in ROWS if not (quick and r[1] >= 2048)],
            "lit": [r for r in LIT_ROWS if small(r[2], r[3])],
            "textured": [r for r in TEXTURED_ROWS if small(r[1], r[2])],
            "aa": [r for r in AA_ROWS if small(r[1], r[2])],
            "points": list(POINT_ROWS)}
    if legacy:  # --ab's defaults: Lambert rows 1-4, every lit row
        rows["plain"], rows["lit"] = ROWS[1:], list(LIT_ROWS)
    if rows_arg:
        index = [int(i) for i in rows_arg.split(",")]
        if legacy and lit_only:
            rows["lit"] = [LIT_ROWS[i] for i in index]
        else:
            rows["plain"] = [ROWS[i] for i in index]
    return {g: [list(r) for r in rows[g]] for g in groups}


def ab_aa_cells(sub: int, w: int, h: int) -> list[Cell]:
    """run_aa's softrast cells for one row (the same scene, renderer and calls)."""
    srow = SoftrastRow(trimesh.creation.icosphere(subdivisions=sub, radius=1.0), w, h, threads=(2,))
    r, s, cam = srow.renderers[2], srow.scene, srow.cam
    cells = []
    for label, mode in AA_MODES:
        f = r.render(s, cam, outputs=("color", "depth"), **mode)
        cells.append(Cell(f"softrast t2 {label}", lambda f=f, mode=mode: r.render(
            s, cam, outputs=("color", "depth"), out=f, **mode)))
    return cells


def ab_points_cells(n: int, w: int, h: int) -> list[Cell]:
    """run_points' softrast cells for one row (the same random cloud, renderers and calls)."""
    rng = np.random.default_rng(0)
    xyz = rng.normal(size=(n, 3))
    xyz *= (rng.uniform(size=(n, 1)) ** (1 / 3)) / np.linalg.norm(xyz, axis=1, keepdims=True)
    rgb = rng.uniform(size=(n, 3))
    s = sr.Scene()
    s.add(sr.Points(xyz, colors=rgb))
    cam = sr.PerspectiveCamera(fov_y=FOV_Y_DEG, width=w, height=h, near=NEAR, far=FAR)
    cam.pose = camera_pose()
    cells = []
    for t in (2, 1):
        r = sr.Renderer(w, h, threads=t)
        f = r.render(s, cam, outputs=("color", "depth"))
        cells.append(Cell(f"softrast t{t} color+depth out", lambda r=r, f=f: r.render(
            s, cam, outputs=("color", "depth"), out=f)))
    return cells


def ab_row_cells(group: str, row: list, all_cells: bool) -> tuple[str, list[Cell]]:
    """(row label, softrast cells) of one row of a group, built by the classes the non-A/B rows use.
    Without all_cells: the cells of the group's table (plain: colour+depth t2 and t1; lit: t2, t2
    linear, t1); with it also plain depth, flat and t2 "new", and the lit rows' depth and unlit."""
    if group == "plain":
        sub, w, h = row
        srow = SoftrastRow(trimesh.creation.icosphere(subdivisions=sub, radius=1.0), w, h, threads=(2, 1))
        return f"ico{sub} {w}x{h}", [c for c in srow.cells() if all_cells or c.name.endswith("color+depth out")]
    if group == "lit":
        lrow = SoftrastLitRow(LitScene(*row))
        return lrow.lit.label, [c for c in lrow.cells() if all_cells
                                or c.name.endswith(("color+depth out", "color+depth out linear"))
                                and "unlit" not in c.name]
    if group == "textured":
        trow = TexturedRow(None, *row)  # no pyrender: only the softrast cells
        return trow.label, trow.cells()
    if group == "aa":
        sub, w, h = row
        return f"ico{sub} {w}x{h}", ab_aa_cells(sub, w, h)
    if group == "points":
        n, w, h = row
        return f"{n // 1000}k points {w}x{h}", ab_points_cells(n, w, h)
    raise ValueError(f"unknown A/B group {group!r} (groups: {', '.join(AB_GROUPS)})")


def ab_digest(frame) -> dict[str, str]:
    """{output: hash of its dtype, shape and bytes} of one frame (every output array it holds)."""
    import hashlib
    arrays = (frame.as_dict() if hasattr(frame, "as_dict") else
              {n: getattr(frame, n) for n in ("color", "depth") if getattr(frame, n, None) is not None})
    return {name: hashlib.sha1(f"{a.dtype.str}{a.shape}".encode() + np.ascontiguousarray(a).tobytes())
            .hexdigest()[:16] for name, a in sorted(arrays.items())}


def ab_worker(spec: dict) -> int:
    """Worker of the A/B modes: builds the cells of spec's groups for the softrast it imports, then
    answers JSON lines on stdin ({"cell", "n"}: times of n frames; {"digest"}; {"quit"})."""
    proto = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)  # whatever else prints (Python or C++) goes to stderr, not into the protocol

    def send(obj: dict) -> None:
        proto.write(json.dumps(obj) + "\n")
        proto.flush()

    t0 = time.perf_counter()
    cells, errors = {}, {}
    for group in spec["groups"]:
        for row in spec["rows"][group]:
            try:
                label, row_cells = ab_row_cells(group, row, spec.get("all_cells", False))
            except Exception as exc:  # noqa: BLE001 (an old build may lack a feature: reported)
                errors[f"{group}: {row}"] = f"{type(exc).__name__}: {exc}"
                continue
            for c in row_cells:
                name = c.name[len("softrast "):] if c.name.startswith("softrast ") else c.name
                cells[f"{group}: {label} {name}"] = c.frame
    digests = {key: ab_digest(fn()) for key, fn in cells.items()}
    core = getattr(getattr(sr, "_core", None), "__file__", None)
    send({"ready": list(cells), "digest": digests, "errors": errors, "file": os.path.dirname(sr.__file__),
          "version": getattr(sr, "__version__", "?"), "python": sys.executable,
          "core_mtime": os.path.getmtime(core) if core else None, "setup_s": time.perf_counter() - t0})
    for line in sys.stdin:
        cmd = json.loads(line)
        if cmd.get("quit"):
            break
        if cmd.get("digest"):
            send({"digest": {key: ab_digest(fn()) for key, fn in cells.items()}})
            continue
        fn = cells[cmd["cell"]]
        times = []
        for _ in range(cmd["n"]):
            t1 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t1)
        send({"times": times})
    return 0


class AbWorker:
    """One side of the A/B: a worker process (ab_worker) on `python` with environment `env`."""

    def __init__(self, side: str, python: str, env: dict, spec: dict) -> None:
        self.side, self.python = side, python
        self.proc = subprocess.Popen([python, os.path.abspath(__file__), "--ab-worker", json.dumps(spec)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)

    def read(self) -> dict:
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"the {self.side} worker ({self.python}) exited with code {self.proc.wait()};"
                               " its error is above")
        return json.loads(line)

    def ask(self, cmd: dict) -> dict:
        self.proc.stdin.write(json.dumps(cmd) + "\n")
        self.proc.stdin.flush()
        return self.read()

    def close(self) -> None:
        if self.proc.poll() is None:
            try:
                self.proc.stdin.write(json.dumps({"quit": True}) + "\n")
                self.proc.stdin.close()
            except OSError:
                pass
            self.proc.wait()


def run_ab(sides: dict, spec: dict, target_s: float, rounds: int, only: list[str] | None = None) -> dict:
    """Times every cell both workers hold: blocks of frames alternating between the builds (one
    renders at a time; old first in even rounds, new first in odd ones), cell by cell, `rounds`
    times; about target_s per cell and build in all. sides: {"old"/"new": (python, env)}."""
    t_start = time.perf_counter()
    workers = {side: AbWorker(side, python, env, spec) for side, (python, env) in sides.items()}
    try:  # both build their scenes at once; nothing is timed until both are ready
        info = {side: w.read() for side, w in workers.items()}
        for side in ("old", "new"):
            i = info[side]
            built = (time.strftime(", core built %Y-%m-%d %H:%M", time.localtime(i["core_mtime"]))
                     if i.get("core_mtime") else "")
            print(f"{side}: softrast {i['version']} from {i['file']}{built} (python {i['python']}; "
                  f"{len(i['ready'])} cells in {i['setup_s']:.1f} s)", flush=True)
            for row, err in i["errors"].items():
                print(f"  {side} could not build {row}: {err}", flush=True)
        if info["old"]["file"] == info["new"]["file"]:
            print("note: both sides import the same softrast: this run measures the A/B's noise floor",
                  flush=True)
        keys = [k for k in info["new"]["ready"] if k in info["old"]["ready"]
                and (not only or any(s in k for s in only))]
        missing = {side: [k for k in info[side]["ready"] if k not in info[other]["ready"]
                          and (not only or any(s in k for s in only))]
                   for side, other in (("old", "new"), ("new", "old"))}

        def block(side: str, key: str, n: int) -> list[float]:
            return workers[side].ask({"cell": key, "n": n})["times"]

        counts = {}
        for key in keys:  # a warm-up block on each side sizes the cell's blocks (the same n for both)
            est = min(statistics.median(block(side, key, 3)) for side in ("old", "new"))
            counts[key] = max(3, min(400, math.ceil(target_s / max(est, 1e-6) / rounds)))
        times = {(side, key): [] for side in ("old", "new") for key in keys}
        for r in range(rounds):
            for key in keys:
                for side in (("old", "new") if r % 2 == 0 else ("new", "old")):
                    times[(side, key)].append(block(side, key, counts[key]))
            print(f"  A/B round {r + 1}/{rounds} done ({time.perf_counter() - t_start:.0f} s)", flush=True)
        final = {side: w.ask({"digest": True})["digest"] for side, w in workers.items()}
    finally:
        for w in workers.values():
            w.close()

    cells = []
    for key in keys:
        old_t, new_t = times[("old", key)], times[("new", key)]
        old_ms = 1e3 * statistics.median([t for b in old_t for t in b])
        new_ms = 1e3 * statistics.median([t for b in new_t for t in b])
        d_old, d_new = info["old"]["digest"][key], info["new"]["digest"][key]
        group, cell = key.split(": ", 1)
        cells.append({
            "group": group, "cell": cell, "old_ms": old_ms, "new_ms": new_ms, "ratio": new_ms / old_ms,
            "round_ratios": [statistics.median(n) / statistics.median(o) for o, n in zip(old_t, new_t)],
            "same_bits": d_old == d_new,
            "differ": sorted(k for k in set(d_old) | set(d_new) if d_old.get(k) != d_new.get(k)),
            "stable": final["old"][key] == d_old and final["new"][key] == d_new,
            "n": {"old": sum(map(len, old_t)), "new": sum(map(len, new_t))}})
    return {"cells": cells, "rounds": rounds, "target_s": target_s, "missing": missing,
            "load_after": os.getloadavg()[0],
            "errors": {side: info[side]["errors"] for side in info},
            "sides": {side: {k: info[side][k] for k in ("file", "version", "python")} for side in info},
            "seconds": time.perf_counter() - t_start}


def report_ab(ab: dict, limit: float = AB_LIMIT) -> bool:
    """Prints run_ab's table and summary; True when every cell's frames were bit-identical (and
    repeatable) and no cell was built by one side only."""
    if "pairs" in ab:  # a --json file of the earlier --ab (old key / new key pairs)
        ab = {"rounds": ab.get("rounds"), "cells": [
            {"group": "plain", "cell": new, "old_ms": ab["ms"][f"old {old}"], "new_ms": ab["ms"][f"new {new}"],
             "ratio": ab["ms"][f"new {new}"] / ab["ms"][f"old {old}"], "round_ratios": [],
             "same_bits": ab["same_bits"].get(old) if old == new else None, "differ": [], "stable": True}
            for old, new in ab["pairs"]]}
    cells = ab["cells"]
    print(f"\nA/B, old build vs new build in one run: median ms per frame (steady state, out=, readback "
          f"included), {ab.get('rounds')} alternations;\n'rounds' = the lowest and highest new/old of one "
          f"alternation's medians (the noise); '!' = new/old above {limit:.2f}")
    head = f"{'group':<9}{'cell':<49}{'old ms':>9}{'new ms':>9}{'new/old':>9}{'rounds':>13}  same bits"
    print(head)
    print("-" * len(head))
    for c in cells:
        rr = c.get("round_ratios") or []
        spread = f"{min(rr):.3f}-{max(rr):.3f}" if rr else ""
        bits = ("n/a" if c["same_bits"] is None else "yes" if c["same_bits"]
                else "NO (" + ", ".join(c.get("differ") or ["?"]) + ")")
        if not c.get("stable", True):
            bits += ", NOT REPEATABLE (a side's last frame differs from its first)"
        flag = "!" if c["ratio"] > limit else " "
        print(f"{c['group']:<9}{c['cell']:<49}{c['old_ms']:>9.3f}{c['new_ms']:>9.3f}{c['ratio']:>8.3f}{flag}"
              f"{spread:>13}  {bits}")
    for side, keys in (ab.get("missing") or {}).items():
        for key in keys:
            print(f"  only the {side} build has {key}")
    for side, errors in (ab.get("errors") or {}).items():
        for row, err in errors.items():
            print(f"  the {side} build could not build {row}: {err}")
    if not cells:
        print("no cell on both sides")
        return False
    worst = max(cells, key=lambda c: c["ratio"])
    same = sum(bool(c["same_bits"]) and c.get("stable", True) for c in cells)
    over = sum(c["ratio"] > limit for c in cells)
    print(f"\nworst new/old {worst['ratio']:.3f} ({worst['group']}: {worst['cell']}); best "
          f"{min(c['ratio'] for c in cells):.3f}, median {statistics.median(c['ratio'] for c in cells):.3f}; "
          f"{over} of {len(cells)} cells above {limit:.2f}; bit-identical frames in {same} of {len(cells)} cells"
          + (f"; {ab['seconds']:.0f} s" if ab.get("seconds") else "")
          + (f"; load average {ab['load_after']:.2f}" if ab.get("load_after") is not None else ""))
    return same == len(cells) and not any((ab.get("missing") or {}).values())


def main_ab(args, target_s: float) -> int:
    """--ab-python / --ab: picks the sides and the cells, runs run_ab, prints, writes --json."""
    import shutil
    legacy = bool(args.ab)
    if args.groups:
        groups = [g.strip() for g in args.groups.split(",") if g.strip()]
        unknown = [g for g in groups if g not in AB_GROUPS]
        if unknown:
            raise SystemExit(f"unknown --groups {', '.join(unknown)} (choose from {', '.join(AB_GROUPS)})")
    else:
        groups = (["lit"] if args.lit_only else ["plain"]) if legacy else list(AB_GROUPS)
    spec = {"groups": groups, "rows": ab_rows(groups, args.quick, args.rows, legacy, args.lit_only),
            "all_cells": args.all_cells}
    if legacy:  # this interpreter on both sides: old softrast from OLD_PYTHONPATH, new from ../python
        new_path = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "python")
        sides = {"old": (sys.executable, dict(os.environ, PYTHONPATH=args.ab)),
                 "new": (sys.executable, dict(os.environ, PYTHONPATH=new_path))}
    else:  # each interpreter imports its own installed build; only the running one keeps PYTHONPATH
        clean = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        sides = {"old": (args.ab_python, clean),
                 "new": (args.new_python, clean) if args.new_python else (sys.executable, dict(os.environ))}
        for python, _ in sides.values():
            if not (os.path.isfile(python) and os.access(python, os.X_OK)) and not shutil.which(python):
                raise SystemExit(f"no Python interpreter {python}")
    rounds = args.ab_rounds or (8 if args.quick else 16)
    seconds = args.ab_seconds or target_s * 2
    for line in machine_lines():
        print(line)
    print(f"A/B groups {', '.join(groups)}: {rounds} alternations, ~{seconds:.1f} s per cell and build in all; "
          f"load average {os.getloadavg()[0]:.2f}", flush=True)
    ab = run_ab(sides, spec, seconds, rounds, [s for s in args.ab_cells.split(",") if s] if args.ab_cells else None)
    ok = report_ab(ab, args.ab_limit)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"ab": ab}, fh, indent=1)
    return 0 if ok else 1


# ------------------------------------------------------------------------------- report


def machine_lines() -> list[str]:
    model = "?"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
        flags = open("/proc/cpuinfo").read()
        avx2 = "avx2" in flags.split()
    except OSError:
        avx2 = False
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=os.path.dirname(os.path.abspath(__file__))).stdout.strip()
    except OSError:
        commit = "?"
    return [f"machine: {model}, {os.cpu_count()} cores, AVX2 {'yes' if avx2 else 'no'}, "
            f"{platform.system()} {platform.release()}, Python {platform.python_version()}, "
            f"NumPy {np.__version__}",
            f"softrast commit {commit or '?'}"]


def verdict(x: float, goal: float) -> str:
    """A goal's verdict for a speed-up ``x`` (NaN: a baseline is missing)."""
    return "n/a" if x != x else ("MET" if x >= goal else f"NOT MET (short by {goal / x:.2f}x)")


def pyrender_t2_t1(r: dict) -> tuple[float, float, float]:
    """A row's pyrender, softrast t2 and t1 colour+depth medians (NaN where missing)."""
    return tuple(r["ms"].get(k, float("nan")) for k in (
        "pyrender color+depth", "softrast t2 color+depth out", "softrast t1 color+depth out"))


def fmt(v: float, width: int = 8, digits: int = 1) -> str:
    return f"{v:{width}.{digits}f}" if v == v else f"{'n/a':>{width}}"


def ratio(a: float, b: float) -> float:
    return a / b if a == a and b == b and b > 0 else float("nan")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="~0.3 s per cell and no 2048x2048 row")
    ap.add_argument("--rows", default=None,
                    help="comma-separated row indices into " + ", ".join(
                        f"{i}=ico{s}@{w}x{h}" for i, (s, w, h) in enumerate(ROWS)))
    ap.add_argument("--no-pyrender", action="store_true")
    ap.add_argument("--no-moderngl", action="store_true")
    ap.add_argument("--json", help="also write every median to this JSON file")
    ap.add_argument("--from-json", help="print the tables of an earlier --json file and exit")
    ap.add_argument("--lit", action="store_true", help="also run the lit rows (blinn_phong, pbr)")
    ap.add_argument("--lit-only", action="store_true", help="run only the lit rows")
    ap.add_argument("--textured", action="store_true",
                    help="only the textured rows (textured Spot, BoxTextured)")
    ap.add_argument("--aa", action="store_true", help="only the anti-aliasing rows")
    ap.add_argument("--points", action="store_true", help="only the point cloud row")
    ap.add_argument("--png", help="write each lit row's colour image from each renderer into this directory")
    ab = ap.add_argument_group("A/B (old build vs new build, one run; no pyrender needed)")
    ab.add_argument("--ab-python", metavar="OLD_PY",
                    help="only the A/B: the softrast installed in the interpreter OLD_PY vs the one in "
                         "--new-python, every cell of --groups")
    ab.add_argument("--new-python", metavar="NEW_PY",
                    help="the new side's interpreter (default: this one, with its environment)")
    ab.add_argument("--groups", help="comma-separated A/B groups of " + ",".join(AB_GROUPS)
                    + " (default: all with --ab-python; plain, or lit with --lit-only, with --ab)")
    ab.add_argument("--ab", metavar="OLD_PYTHONPATH",
                    help="only the A/B on this interpreter: softrast from OLD_PYTHONPATH vs this checkout's "
                         "python/ (default group plain, rows 1,2,3,4; with --lit-only the lit rows, "
                         "--rows then indexing the lit rows)")
    ab.add_argument("--all-cells", action="store_true",
                    help="A/B also the plain rows' depth, flat and t2 new cells and the lit rows' depth and "
                         "unlit cells")
    ab.add_argument("--ab-cells", metavar="SUBSTR[,SUBSTR]",
                    help="A/B only the cells whose 'group: row cell' name contains one of these")
    ab.add_argument("--ab-rounds", type=int, default=None, help="A/B alternations (default 16, --quick 8)")
    ab.add_argument("--ab-seconds", type=float, default=None,
                    help="A/B seconds per cell and build, all rounds (default 3, --quick 0.6)")
    ab.add_argument("--ab-limit", type=float, default=AB_LIMIT,
                    help=f"flag cells whose new/old exceeds this (default {AB_LIMIT})")
    ap.add_argument("--ab-worker", metavar="SPEC", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.from_json:
        with open(args.from_json) as fh:
            data = json.load(fh)
        if isinstance(data, list):
            data = {"lambert": data}
        if data.get("lambert"):
            report(data["lambert"], None, None)
        if data.get("lit"):
            report_lit(data["lit"])
        if data.get("ab"):
            report_ab(data["ab"])
        return 0

    if args.ab_worker:
        return ab_worker(json.loads(args.ab_worker))
    target_s, n_min, n_max, rounds = (0.3, 3, 60, 3) if args.quick else (1.5, 7, 400, 7)
    if args.ab_python or args.ab:
        return main_ab(args, target_s)
    if args.rows:
        rows = [ROWS[int(i)] for i in args.rows.split(",")]
    else:
        rows = [r for r in ROWS if not (args.quick and r[1] >= 2048)]
    if args.lit_only or args.textured or args.aa or args.points:
        rows = []

    pyrender, pyrender_error = (None, "skipped (--no-pyrender)") if args.no_pyrender else import_pyrender()
    moderngl, moderngl_error = (None, "skipped (--no-moderngl)") if args.no_moderngl else import_moderngl()
    for line in machine_lines():
        print(line)
    print(f"softrast {getattr(sr, '__version__', '?')}, trimesh {trimesh.__version__}, "
          f"pyrender {getattr(pyrender, '__version__', None) or pyrender_error} "
          f"(PYOPENGL_PLATFORM={os.environ['PYOPENGL_PLATFORM']}), "
          f"moderngl {getattr(moderngl, '__version__', None) or moderngl_error} (EGL)")
    print(f"camera distance {camera_distance():.3f} (fov {FOV_Y_DEG}), N per cell ~{target_s} s "
          f"(min {n_min}, max {n_max}) in {rounds} interleaved rounds after warm-up; medians in ms")
    sys.stdout.flush()

    results = []
    for sub, w, h in rows:
        base = trimesh.creation.icosphere(subdivisions=sub, radius=1.0)
        res = {"row": f"ico{sub} {w}x{h}", "sub": sub, "faces": len(base.faces), "width": w,
               "height": h, "errors": {}}
        cells: list[Cell] = []
        baselines = {}
        for name, module, row_class in (("pyrender", pyrender, PyrenderRow),
                                        ("moderngl", moderngl, ModernglRow)):
            if module is None:
                continue
            try:
                baselines[name] = row_class(module, base, w, h)
                cells += baselines[name].cells()
            except Exception as exc:  # noqa: BLE001 (a baseline that fails is reported, not fatal)
                res["errors"][name] = f"{type(exc).__name__}: {exc}"
        pr, mg = baselines.get("pyrender"), baselines.get("moderngl")
        srow = SoftrastRow(base, w, h, threads=(2, 1))
        cells += srow.cells()
        run_interleaved(cells, target_s, n_min, n_max, rounds)
        res["ms"] = {c.name: c.median_ms for c in cells}
        res["n"] = {c.name: len(c.times) for c in cells}
        res["first_ms"] = {"pyrender": pr.first_ms if pr else float("nan"),
                           "moderngl": mg.first_ms if mg else float("nan"),
                           **{f"softrast t{t}": v for t, v in srow.first_ms.items()}}
        res["build_ms"] = {"pyrender": pr.build_ms if pr else float("nan"),
                           "moderngl": mg.build_ms if mg else float("nan"),
                           "softrast": srow.build_ms}
        res["coverage"] = srow.coverage
        for obj in (pr, mg):
            if obj is not None:
                obj.close()
        results.append(res)
        print(f"  done ico{sub} {w}x{h}: "
              + ", ".join(f"{k} {v:.2f}" for k, v in res["ms"].items()), flush=True)

    if args.points:
        report_points(run_points(pyrender, target_s, n_min, n_max, rounds, args.png))
        return 0
    if args.aa:
        report_aa(run_aa(pyrender, target_s, n_min, n_max, rounds, args.png, args.quick))
        return 0
    if args.textured:
        report_textured(run_textured(pyrender, target_s, n_min, n_max, rounds, args.png, args.quick))
        return 0
    lit_results = []
    if args.lit or args.lit_only:
        lit_results = run_lit([r for r in LIT_ROWS if not (args.quick and r[2] * r[3] > 640 * 480)]
                              if args.quick else LIT_ROWS, pyrender, pyrender_error, target_s, n_min,
                              n_max, rounds, args.png)

    if results:
        report(results, pyrender_error, moderngl_error)
    if lit_results:
        report_lit(lit_results)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"lambert": results, "lit": lit_results} if lit_results else results, fh, indent=1)
    return 0


def report(results: list[dict], pyrender_error: str | None, moderngl_error: str | None) -> None:
    get = lambda r, k: r["ms"].get(k, float("nan"))  # noqa: E731
    print("\nMedian ms per frame (steady state, readback included); sr = softrast, t2/t1 = threads")
    head = (f"{'scene':<6}{'faces':>10}{'size':>10}{'cover':>6}  {'mode':<12}{'pyrender':>9}{'moderngl':>9}"
            f"{'sr t2':>8}{'sr t2new':>9}{'sr t1':>8}{'xpyr t2':>9}{'xpyr t1':>9}{'xmgl t2':>9}")
    print(head)
    print("-" * len(head))
    for r in results:
        label = (f"ico{r['sub']:<3}{r['faces']:>10,}{str(r['width']) + 'x' + str(r['height']):>10}"
                 f"{100 * r['coverage']:>5.0f}%")
        for mode in ("color+depth", "depth", "flat"):
            pyr, t2, t1 = get(r, f"pyrender {mode}"), get(r, f"softrast t2 {mode} out"), get(r, f"softrast t1 {mode} out")
            mgl = get(r, "moderngl color+depth") if mode == "color+depth" else float("nan")
            new = get(r, "softrast t2 color+depth new") if mode == "color+depth" else float("nan")
            print(f"{label}  {mode:<12}{fmt(pyr, 9)}{fmt(mgl, 9)}{fmt(t2, 8, 2)}{fmt(new, 9, 2)}{fmt(t1, 8, 2)}"
                  f"{fmt(ratio(pyr, t2), 9)}{fmt(ratio(pyr, t1), 9)}{fmt(ratio(mgl, t2), 9)}")
            label = " " * len(label)

    print("\nContext + first colour+depth frame (ms, one sample) and scene build from a trimesh (ms)")
    head = (f"{'scene':<22}{'pyrender':>9}{'moderngl':>9}{'sr t2':>8}{'sr t1':>8}"
            f"{'sr t2 first/steady':>20}   {'build: pyrender':>15}{'moderngl':>9}{'softrast':>9}")
    print(head)
    print("-" * len(head))
    for r in results:
        f, b = r["first_ms"], r["build_ms"]
        steady = get(r, "softrast t2 color+depth new")
        print(f"ico{r['sub']} {r['width']}x{r['height']:<12}{fmt(f['pyrender'], 9)}{fmt(f['moderngl'], 9)}"
              f"{fmt(f['softrast t2'], 8)}{fmt(f['softrast t1'], 8)}{fmt(ratio(f['softrast t2'], steady), 20, 2)}"
              f"   {fmt(b['pyrender'], 15)}{fmt(b['moderngl'], 9)}{fmt(b['softrast'], 9)}")

    print("\nsoftrast throughput per core (t2 figures divided by 2 threads): Mtri/s = input faces / time;"
          "\nMpix/s = image pixels / time (the sphere covers the 'cover' fraction of them)")
    head = f"{'scene':<22}{'mode':<13}{'Mtri/s t1':>10}{'Mtri/s t2':>10}{'Mpix/s t1':>10}{'Mpix/s t2':>10}{'t1/t2':>7}"
    print(head)
    print("-" * len(head))
    for r in results:
        for mode in ("color+depth", "depth", "flat"):
            t1, t2 = get(r, f"softrast t1 {mode} out"), get(r, f"softrast t2 {mode} out")
            pix = r["width"] * r["height"]
            print(f"{'ico' + str(r['sub']) + ' ' + str(r['width']) + 'x' + str(r['height']):<22}{mode:<13}"
                  f"{fmt(r['faces'] / t1 / 1e3, 10, 2)}{fmt(r['faces'] / t2 / 2e3, 10, 2)}"
                  f"{fmt(pix / t1 / 1e3, 10)}{fmt(pix / t2 / 2e3, 10)}{fmt(ratio(t1, t2), 7, 2)}")

    print(f"\nGoals: colour+depth >= {GOALS['color+depth']:.0f}x pyrender, depth-only >= "
          f"{GOALS['depth']:.0f}x pyrender, colour+depth >= {GOALS['moderngl']:.0f}x moderngl, "
          f"first frame <= {GOALS['first_over_steady']:.0f} steady frames (softrast t2; ratios vs t2 out=, "
          f"first frame vs steady frames into new arrays)")
    for r in results:
        checks = []
        for what, num, den, goal in (
                ("c+d vs pyrender", get(r, "pyrender color+depth"), get(r, "softrast t2 color+depth out"), GOALS["color+depth"]),
                ("depth vs pyrender", get(r, "pyrender depth"), get(r, "softrast t2 depth out"), GOALS["depth"]),
                ("c+d vs moderngl", get(r, "moderngl color+depth"), get(r, "softrast t2 color+depth out"), GOALS["moderngl"])):
            x = ratio(num, den)
            checks.append(f"{what} {x:.1f}x {'MET' if x >= goal else 'short by %.2fx' % (goal / x)}"
                          if x == x else f"{what} n/a")
        x = ratio(r["first_ms"]["softrast t2"], get(r, "softrast t2 color+depth new"))
        checks.append(f"first {x:.1f} frames {'MET' if x <= GOALS['first_over_steady'] else 'NOT MET'}")
        print(f"  ico{r['sub']} {r['width']}x{r['height']}: " + "; ".join(checks))
    errors = {k: v for r in results for k, v in r["errors"].items()}
    if pyrender_error or moderngl_error or errors:
        print("\nBaselines that did not run:")
        for name, err in (("pyrender", pyrender_error), ("moderngl", moderngl_error), *errors.items()):
            if err:
                hint = "" if err.startswith("skipped") else "  (run: bash benchmarks/setup_baselines.sh)"
                print(f"  {name}: {err}{hint}")


if __name__ == "__main__":
    sys.exit(main())
