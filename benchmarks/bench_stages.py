"""Where softrast's time goes, measured through the public API (the core exposes no stage timers).

    python3 benchmarks/bench_stages.py [--quick] [--sections faces,pixels,outputs,threads,overhead,memory,callgrind]

Sections (all steady state: renderer reused, frames rendered into with out=, warm-up first, the
cells of a table interleaved in rounds, medians in ms; the machine is shared, so compare within a
table, not across runs):
  faces     icosphere sub 3..8 at 1024x1024: cost per input face (geometry + setup + binning)
  pixels    icosphere sub 6 at 256..4096 square: cost per covered pixel (raster + shade + clear)
  outputs   depth only vs colour+depth vs unlit vs every output: differences estimate shading and
            output-writing cost
  paths     forward vs deferred shading as overdraw grows (layers of spheres drawn back to front,
            the worst order for forward shading): the crossover behind shading_path="auto"
  order     the same sphere with its vertices in trimesh's order, in order of first use by the
            faces, and shuffled (faces unchanged): what the mesh's vertex order costs
  threads   1 vs 2 threads
  lit       cost of each shading model per covered pixel and per light (RESULTS.md, "Lit
            shading"). ico6 (81,920
            faces) at 1024x1024, colour+depth, frequency="pixel", srgb=False (the encoding is
            timed apart), a white-ish Material with every model's parameters and 1, 2, 4 or 8
            point lights in front of the sphere. ns per covered px = (time - depth-only time) /
            covered pixels (so it holds the interpolation, the lighting and the colour write);
            per light = the least-squares slope over 1..8 lights, fixed = the intercept (0
            lights). The plain Lambert headlight (no lights, no material: today's fast path) and
            sRGB encoding (srgb=True - srgb=False) are timed alongside.
  litcg     the lit table in instructions (valgrind callgrind, 1 thread, counted only inside the
            core's sr::Renderer::render, so Python is left out): repeatable under any load. With
            --ab-old PATH also the Lambert rows' instructions, old build (softrast importable
            from PATH) vs this checkout's python/
  distortion a camera with lens distortion (RESULTS.md, "Lens distortion"; a strong barrel,
            oversample 1, 2, 4)
            against the same camera without it, ico6 at 640x480: colour only (bilinear gathers),
            colour+depth and every geometric output (each pixel's ray cast in float64). With
            --ab-old PATH: the same cells, old build (softrast importable from PATH) against this
            one, a fresh process per build and round, the order alternating
  overhead  Python cost per call: a 1x1 render of a 1-triangle scene
  memory    peak RSS of rendering the 1.3M-face sphere at 1024x1024 (a fresh subprocess) against
            the mesh's own arrays plus the framebuffers
  callgrind builds benchmarks/core_bench.cpp (C++ only, no Python) and counts instructions per
            stage source file with valgrind's callgrind: repeatable, independent of machine noise
"""
from __future__ import annotations

import argparse
import json
import math
import re
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict

import numpy as np
import trimesh

import softrast as sr

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FOV_Y_DEG, NEAR, FAR = 45.0, 0.05, 100.0
SILHOUETTE_FRACTION = 0.8  # as bench_vs_pyrender.py: the sphere spans 0.8 of the image height
ALL_OUTPUTS = sr.OUTPUTS
SECTIONS = ("faces", "pixels", "outputs", "paths", "order", "threads", "lit", "litcg", "textures", "distortion",
            "antialiasing", "overhead", "memory", "callgrind")


def camera_distance() -> float:
    return 1.0 / math.sin(math.atan(SILHOUETTE_FRACTION * math.tan(math.radians(FOV_Y_DEG) / 2)))


_MESHES: dict[int, sr.Mesh] = {}


def sphere_scene(sub: int) -> tuple[sr.Scene, int]:
    if sub not in _MESHES:
        _MESHES[sub] = sr.Mesh.from_trimesh(trimesh.creation.icosphere(subdivisions=sub))
    scene = sr.Scene()
    scene.add(_MESHES[sub], color=(1.0, 1.0, 1.0))
    return scene, len(_MESHES[sub].faces)


def camera(width: int, height: int) -> sr.PerspectiveCamera:
    cam = sr.PerspectiveCamera(fov_y=FOV_Y_DEG, width=width, height=height, near=NEAR, far=FAR)
    return cam.look_at(eye=(0.0, 0.0, camera_distance()), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))


class Job:
    """One steady-state render configuration, rendering into its own frame (out=)."""

    def __init__(self, key, sub, width, height, outputs=("color", "depth"), shading="lambert", threads=2):
        self.key = key
        self.scene, self.faces = sphere_scene(sub)
        self.cam = camera(width, height)
        self.renderer = sr.Renderer(width, height, threads=threads)
        self.kwargs = dict(outputs=outputs, shading=shading)
        self.frame = self.renderer.render(self.scene, self.cam, **self.kwargs)
        self.pixels = width * height
        self.covered = int((self.frame.depth > 0).sum()) if self.frame.depth is not None else \
            int((self.renderer.render(self.scene, self.cam, outputs=("depth",)).depth > 0).sum())
        self.times: list[float] = []

    def __call__(self):
        return self.renderer.render(self.scene, self.cam, out=self.frame, **self.kwargs)

    @property
    def ms(self) -> float:
        return 1e3 * statistics.median(self.times)


def run_interleaved(jobs, target_s: float, rounds: int, n_min: int = 5, n_max: int = 2000) -> None:
    counts = []
    for job in jobs:
        job()
        t0 = time.perf_counter()
        job()
        counts.append(max(n_min, min(n_max, int(target_s / max(time.perf_counter() - t0, 1e-7)))))
    for r in range(rounds):
        for i in [(i + r) % len(jobs) for i in range(len(jobs))]:
            job = jobs[i]
            for _ in range(math.ceil(counts[i] / rounds)):
                t0 = time.perf_counter()
                job()
                job.times.append(time.perf_counter() - t0)


def linear_fit(x, y):
    """Least-squares y = a + b x; returns a, b and the largest relative residual."""
    a_mat = np.stack([np.ones(len(x)), np.asarray(x, float)], axis=1)
    (a, b), *_ = np.linalg.lstsq(a_mat, np.asarray(y, float), rcond=None)
    resid = max(abs(a + b * xi - yi) / yi for xi, yi in zip(x, y))
    return a, b, resid


# --------------------------------------------------------------------------------- sections


def _sweep(jobs, keys, key_label, key_text, amount, unit, digits, opts):
    """Times depth-only and colour+depth for each key, prints per-unit costs and a linear fit.

    amount(job) is the unit the cost grows with (faces, covered pixels)."""
    outs = (("depth",), ("color", "depth"))
    run_interleaved(jobs, opts.target, opts.rounds)
    by = {j.key: j for j in jobs}
    print(f"{key_label:>10}{unit:>12}{'depth ms':>10}{'c+d ms':>9}{'ns/' + unit + ' d':>14}"
          f"{'ns/' + unit + ' c+d':>16}{'marginal d':>12}{'c+d':>8}")
    prev = None
    for k in keys:
        d, cd = by[(k, outs[0])], by[(k, outs[1])]
        marg = ("", "")
        if prev is not None:
            du = amount(d) - amount(prev[0])
            marg = (f"{1e6 * (d.ms - prev[0].ms) / du:.{digits}f}",
                    f"{1e6 * (cd.ms - prev[1].ms) / du:.{digits}f}")
        print(f"{key_text(k):>10}{amount(d):>12,}{d.ms:>10.2f}{cd.ms:>9.2f}"
              f"{1e6 * d.ms / amount(d):>14.{digits}f}{1e6 * cd.ms / amount(cd):>16.{digits}f}"
              f"{marg[0]:>12}{marg[1]:>8}")
        prev = (d, cd)
    for name, o in (("depth", outs[0]), ("c+d", outs[1])):
        a, b, r = linear_fit([amount(by[(k, o)]) for k in keys], [by[(k, o)].ms for k in keys])
        print(f"fit {name}: {a:.2f} ms + {1e6 * b:.{digits}f} ns/{unit} (wall, 2 threads); "
              f"worst residual {100 * r:.0f}%")


def section_faces(opts):
    subs = [3, 4, 5, 6, 7] + ([] if opts.quick else [8])
    print("\n## Scaling with faces: icosphere sub 3..8 at 1024x1024, threads 2, out=")
    jobs = [Job((s, o), s, 1024, 1024, outputs=o) for s in subs for o in (("depth",), ("color", "depth"))]
    _sweep(jobs, subs, "sub", str, lambda j: j.faces, "face", 1, opts)


def section_pixels(opts):
    sides = [256, 512, 1024, 2048] + ([] if opts.quick else [4096])
    print("\n## Scaling with pixels: icosphere sub 6 (81,920 faces), square images, threads 2, out=")
    jobs = [Job((n, o), 6, n, n, outputs=o) for n in sides for o in (("depth",), ("color", "depth"))]
    _sweep(jobs, sides, "size", lambda n: f"{n}x{n}", lambda j: j.covered, "covpx", 2, opts)


def section_outputs(opts):
    print("\n## Outputs and shading (threads 2, out=): differences estimate shading / output cost")
    configs = [("depth", ("depth",), "lambert"), ("color+depth unlit", ("color", "depth"), "unlit"),
               ("color+depth lambert", ("color", "depth"), "lambert"),
               ("color only lambert", ("color",), "lambert"), ("all 7 outputs", ALL_OUTPUTS, "lambert")]
    scenes = [(6, 1024, 1024), (8, 1024, 1024)] if not opts.quick else [(6, 1024, 1024)]
    jobs = [Job((sc, name), *sc, outputs=o, shading=sh) for sc in scenes for name, o, sh in configs]
    run_interleaved(jobs, opts.target, opts.rounds)
    by = {j.key: j for j in jobs}
    for sc in scenes:
        base = by[(sc, "depth")]
        print(f"ico{sc[0]} {sc[1]}x{sc[2]} ({base.faces:,} faces, {base.covered:,} covered px)")
        print(f"  {'outputs':<22}{'ms':>8}{'- depth ms':>12}{'ns/covered px over depth':>27}")
        for name, _, _ in configs:
            j = by[(sc, name)]
            extra = j.ms - base.ms
            print(f"  {name:<22}{j.ms:>8.2f}{extra:>12.2f}{1e6 * extra / base.covered:>27.2f}")


class PathJob(Job):
    """`layers` icospheres one behind another (same silhouette), drawn back to front."""

    def __init__(self, key, sub, layers, size, path):
        super().__init__(key, sub, size, size)
        self.scene = sr.Scene()
        d = camera_distance()
        for k in reversed(range(layers)):  # farthest first: every layer wins its pixels in turn
            z = -0.6 * k
            scale = (d - z) / d  # keeps the silhouette the same size
            self.scene.add(_MESHES[sub], pose=np.diag([scale, scale, scale, 1.0]) @ _translate(0, 0, z / scale),
                           color=(1.0, 1.0, 1.0))
        self.kwargs = dict(outputs=("color", "depth"), shading_path=path)
        self.frame = self.renderer.render(self.scene, self.cam, **self.kwargs)


def _translate(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def section_paths(opts):
    print("\n## Shading path: forward vs deferred as overdraw grows (colour+depth, threads 2, out=)")
    print("layers of ico5 spheres with the same silhouette, drawn back to front (forward shading's"
          " worst order); auto = per tile, forward while the tile's triangle area <= 1.5x its pixels")
    cases = [(5, layers, 1024) for layers in (1, 2, 3, 4)] + [(3, 1, 256), (6, 1, 640)]
    if opts.quick:
        cases = cases[:3]
    paths = ("forward", "deferred", "auto")
    jobs = [PathJob((c, p), c[0], c[1], c[2], p) for c in cases for p in paths]
    run_interleaved(jobs, opts.target, opts.rounds)
    by = {j.key: j for j in jobs}
    print(f"{'scene':<26}{'forward':>9}{'deferred':>10}{'auto':>8}{'fwd/def':>9}")
    for c in cases:
        f, d, a = (by[(c, p)].ms for p in paths)
        name = f"ico{c[0]} x{c[1]} layer{'s' if c[1] > 1 else ''} {c[2]}px"
        print(f"{name:<26}{f:>9.2f}{d:>10.2f}{a:>8.2f}{f / d:>9.2f}")


def reorder_vertices(mesh: sr.Mesh, order: np.ndarray) -> sr.Mesh:
    """The same triangles, faces in the same order, with vertex i of the result = mesh's order[i]."""
    remap = np.empty(len(order), np.int64)
    remap[order] = np.arange(len(order))
    return sr.Mesh(mesh.positions[order], remap[mesh.faces],
                   normals=None if mesh.normals is None else mesh.normals[order])


class OrderJob(Job):
    def __init__(self, key, sub, width, height, order, outputs):
        super().__init__(key, sub, width, height, outputs=outputs)
        base = _MESHES[sub]
        n = len(base.positions)
        if order == "first use":
            _, first = np.unique(base.faces.ravel(), return_index=True)
            base = reorder_vertices(base, np.argsort(first, kind="stable"))
        elif order == "shuffled":
            base = reorder_vertices(base, np.random.default_rng(0).permutation(n))
        self.scene = sr.Scene()
        self.scene.add(base, color=(1.0, 1.0, 1.0))
        self.frame = self.renderer.render(self.scene, self.cam, **self.kwargs)


def section_order(opts):
    print("\n## Vertex order: the same sphere, vertices reordered (threads 2, out=)")
    print("faces and their order unchanged (the same image); setup gathers projected vertices and"
          " shading vertex normals by index, so the order decides how often those miss the caches")
    cases = [(6, 640, 480), (8, 1024, 1024)] if not opts.quick else [(6, 640, 480), (7, 1024, 1024)]
    orders = ("trimesh", "first use", "shuffled")
    outs = (("depth",), ("color", "depth"))
    jobs = [OrderJob((c, o, out), *c, o, out) for c in cases for o in orders for out in outs]
    ref = {}
    for j in jobs:  # the order must not change a single bit
        key = (j.key[0], j.key[2])
        frame = j()
        arrays = [a.copy() for a in (frame.depth, frame.color) if a is not None]
        if key in ref and not all(np.array_equal(a, b) for a, b in zip(ref[key], arrays)):
            raise AssertionError(f"vertex order changed the image: {j.key}")
        ref.setdefault(key, arrays)
    run_interleaved(jobs, opts.target, opts.rounds)
    by = {j.key: j for j in jobs}
    print(f"{'scene':<18}{'mode':<13}" + "".join(f"{o:>11}" for o in orders) + f"{'shuf/first':>12}")
    for c in cases:
        for out in outs:
            ms = [by[(c, o, out)].ms for o in orders]
            mode = "depth" if out == ("depth",) else "color+depth"
            print(f"{'ico%d %dx%d' % c:<18}{mode:<13}" + "".join(f"{m:>11.2f}" for m in ms)
                  + f"{ms[2] / ms[1]:>12.2f}")


def section_threads(opts):
    print("\n## Threads: 1 vs 2 (colour+depth and depth, out=)")
    scenes = [(3, 256, 256), (6, 640, 480), (6, 1024, 1024), (8, 1024, 1024)]
    if not opts.quick:
        scenes.append((7, 2048, 2048))
    jobs = [Job((sc, o, t), *sc, outputs=o, threads=t) for sc in scenes
            for o in (("depth",), ("color", "depth")) for t in (1, 2)]
    run_interleaved(jobs, opts.target, opts.rounds)
    by = {j.key: j for j in jobs}
    print(f"{'scene':<18}{'d t1':>8}{'d t2':>8}{'speedup':>9}{'c+d t1':>9}{'c+d t2':>9}{'speedup':>9}")
    for sc in scenes:
        d1, d2 = by[(sc, ("depth",), 1)].ms, by[(sc, ("depth",), 2)].ms
        c1, c2 = by[(sc, ("color", "depth"), 1)].ms, by[(sc, ("color", "depth"), 2)].ms
        print(f"{'ico%d %dx%d' % sc:<18}{d1:>8.2f}{d2:>8.2f}{d1 / d2:>9.2f}{c1:>9.2f}{c2:>9.2f}{c1 / c2:>9.2f}")


LIT_MODELS = ("unlit", "lambert", "phong", "blinn_phong", "pbr")
LIT_COUNTS = (1, 2, 4, 8)


class LitJob(Job):
    """The sphere with a Material and `lights` point lights, rendered with one shading model."""

    def __init__(self, key, sub, width, height, model, lights, srgb=False):
        super().__init__(key, sub, width, height)
        self.scene = sr.Scene(ambient_light=(0.05, 0.05, 0.05))
        material = sr.Material(base_color=(0.8, 0.5, 0.3), ks=(0.5, 0.5, 0.5), shininess=32.0,
                               metallic=0.2, roughness=0.4)
        self.scene.add(_MESHES[sub], material=material)
        d = camera_distance()
        for k in range(lights):  # on a ring in front of the sphere, all lighting its visible side
            a = 2 * math.pi * k / max(lights, 1)
            pose = _translate(1.5 * math.cos(a), 1.5 * math.sin(a), 0.5 * d)
            self.scene.add(sr.PointLight(color=(1.0, 1.0, 1.0), intensity=4.0 / max(lights, 1)), pose=pose)
        self.kwargs = dict(outputs=("color", "depth"), shading=model, frequency="pixel", srgb=srgb)
        self.frame = self.renderer.render(self.scene, self.cam, **self.kwargs)


def section_lit(opts):
    sub, size = 6, 1024
    print(f"\n## Lit shading: ns per covered pixel by model and point lights; ico{sub} "
          f"{size}x{size}, colour+depth, frequency=pixel, srgb=False, threads 2, out=")
    counts = LIT_COUNTS if not opts.quick else (1, 4)
    jobs = [Job("depth", sub, size, size, outputs=("depth",)),
            Job("headlight", sub, size, size),  # no lights, no material: the plain Lambert path
            LitJob(("lambert", 1, "srgb"), sub, size, size, "lambert", 1, srgb=True)]
    jobs += [LitJob((m, n), sub, size, size, m, n) for m in LIT_MODELS for n in counts]
    run_interleaved(jobs, opts.target, opts.rounds)
    by = {j.key: j for j in jobs}
    depth = by["depth"]
    cov = depth.covered
    ns = lambda j: 1e6 * (j.ms - depth.ms) / cov  # noqa: E731
    print(f"depth only {depth.ms:.2f} ms; {cov:,} covered px; plain Lambert headlight (no lights, no "
          f"material) {by['headlight'].ms:.2f} ms = {ns(by['headlight']):.2f} ns/covered px over depth")
    print(f"{'model':<13}" + "".join(f"{str(n) + ' light' + ('s' if n > 1 else '') + ' ms':>13}" for n in counts)
          + "".join(f"{'ns/px ' + str(n):>10}" for n in counts) + f"{'fixed ns/px':>13}{'ns/px/light':>13}")
    rows = {}
    for m in LIT_MODELS:
        ms = [by[(m, n)].ms for n in counts]
        per = [ns(by[(m, n)]) for n in counts]
        a, b, _ = linear_fit(list(counts), per) if len(counts) > 1 else (per[0], float("nan"), 0)
        rows[m] = (ms, per, a, b)
        print(f"{m:<13}" + "".join(f"{x:>13.2f}" for x in ms) + "".join(f"{x:>10.2f}" for x in per)
              + f"{a:>13.2f}{b:>13.2f}")
    srgb, lin = by[("lambert", 1, "srgb")], by[("lambert", 1)]
    print(f"sRGB encoding (lambert, 1 light, srgb=True - srgb=False): {srgb.ms - lin.ms:+.2f} ms = "
          f"{1e6 * (srgb.ms - lin.ms) / cov:+.2f} ns/covered px")
    print("(2 threads: ns are wall time over both cores; per core, double them)")


class TexturedJob(Job):
    """The sphere with spherical uvs, unlit, its base colour from the 1024x1024 Spot texture
    (None: no texture), one texture filter."""

    def __init__(self, key, sub, width, height, filt, texture, alpha_mode="opaque"):
        super().__init__(key, sub, width, height)
        mesh = _MESHES[sub]
        p = mesh.positions.astype(np.float64)
        uv = np.c_[np.arctan2(p[:, 2], p[:, 0]) / (2 * math.pi) + 0.5,
                   np.arcsin(np.clip(p[:, 1], -1, 1)) / math.pi + 0.5] * (4.0, 2.0)  # 4x2 repeats
        material = sr.Material(base_color=(1.0, 1.0, 1.0), base_color_texture=texture, model="unlit",
                               alpha_mode=alpha_mode)
        self.scene = sr.Scene()
        self.scene.add(sr.Mesh(mesh.positions, mesh.faces, normals=mesh.normals, uvs=uv), material=material)
        self.kwargs = dict(outputs=("color", "depth"), texture_filter=filt if texture is not None else None)
        self.frame = self.renderer.render(self.scene, self.cam, **self.kwargs)


def section_textures(opts):
    sub, size = 6, 1024
    print(f"\n## Textures: ns per covered pixel by filter over the same untextured unlit "
          f"render; ico{sub} {size}x{size} with spherical uvs (4x2 repeats of the 1024x1024 Spot "
          f"texture: ~1-2 texels per pixel), colour+depth, threads 2, out=")
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    texture = sr.load_texture(os.path.join(root, "assets", "meshes", "spot_texture.png"))
    filters = ("nearest", "bilinear", "trilinear", "anisotropic")
    jobs = [Job("depth", sub, size, size, outputs=("depth",)),
            TexturedJob("untextured", sub, size, size, None, None)]
    jobs += [TexturedJob(f, sub, size, size, f, texture) for f in filters]
    # Alpha masks: the same texels with an alpha channel of 255 (every fragment kept), so the
    # extra time is the masked raster path and its alpha sample alone.
    opaque_alpha = sr.Texture(np.dstack([texture.image, np.full(texture.image.shape[:2], 255, np.uint8)]))
    masked = ("bilinear", "trilinear")
    jobs += [TexturedJob(f"{f} masked", sub, size, size, f, opaque_alpha, alpha_mode="mask") for f in masked]
    run_interleaved(jobs, opts.target, opts.rounds)
    by = {j.key: j for j in jobs}
    cov = by["depth"].covered
    base = by["untextured"]
    print(f"untextured unlit {base.ms:.2f} ms; {cov:,} covered px")
    print(f"{'filter':<13}{'ms':>9}{'ns/px extra':>13}")
    for f in filters:
        print(f"{f:<13}{by[f].ms:>9.2f}{1e6 * (by[f].ms - base.ms) / cov:>13.2f}")
    print("(2 threads: ns are wall time over both cores; per core, double them)")
    print(f"\nalpha_mode='mask' (alpha 1 everywhere: nothing cut) over the same filter, opaque:")
    print(f"{'filter':<13}{'ms':>9}{'ns/px extra':>13}")
    for f in masked:
        print(f"{f:<13}{by[f + ' masked'].ms:>9.2f}{1e6 * (by[f + ' masked'].ms - by[f].ms) / cov:>13.2f}")


# Runs under valgrind in a fresh interpreter (no trimesh import: the mesh comes from an .npz):
# renders one configuration `renders` times (the first into new arrays, then out=); callgrind
# counts only inside sr::Renderer::render.
LITCG_CHILD = r"""
import json, math, sys
import numpy as np, softrast as sr
spec = json.loads(sys.argv[1])
arrays = np.load(spec["mesh"])  # the icosphere's float32 positions and normals, int32 faces
mesh = sr.Mesh(arrays["p"], arrays["f"], normals=arrays["n"])
w, h = spec["size"]
d = 1.0 / math.sin(math.atan(0.8 * math.tan(math.radians(45.0) / 2)))
cam = sr.PerspectiveCamera(fov_y=45.0, width=w, height=h, near=0.05, far=100.0)
cam.look_at(eye=(0.0, 0.0, d), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))
kw = dict(outputs=tuple(spec["outputs"]))
if spec.get("model") is None:
    scene = sr.Scene(); scene.add(mesh, color=(1.0, 1.0, 1.0))
    if "srgb" in spec:
        kw["srgb"] = spec["srgb"]
else:
    scene = sr.Scene(ambient_light=(0.05, 0.05, 0.05))
    scene.add(mesh, material=sr.Material(base_color=(0.8, 0.5, 0.3), ks=(0.5, 0.5, 0.5), shininess=32.0,
                                         metallic=0.2, roughness=0.4))
    n = spec["lights"]
    for k in range(n):
        a = 2 * math.pi * k / n
        pose = np.eye(4); pose[:3, 3] = (1.5 * math.cos(a), 1.5 * math.sin(a), 0.5 * d)
        scene.add(sr.PointLight(color=(1.0, 1.0, 1.0), intensity=4.0 / n), pose=pose)
    kw.update(shading=spec["model"], frequency="pixel", srgb=spec.get("srgb", False))
r = sr.Renderer(w, h, threads=1)
frame = r.render(scene, cam, **kw)
for _ in range(spec["renders"] - 1):
    r.render(scene, cam, out=frame, **kw)
print(json.dumps({"covered": int((r.render(scene, cam, outputs=("depth",)).depth > 0).sum())
                  if spec["count_cover"] else None}))
"""


def _callgrind_renders(specs, pythonpath, parallel=2):
    """Instructions per render inside sr::Renderer::render for each spec (dict), run `parallel`
    valgrind processes at a time. Returns [(instructions per render, covered px or None)]."""
    import concurrent.futures
    # The interpreter itself (a pyenv shim would hide it from valgrind).
    exe = os.path.realpath(sys.executable)
    meshes = tempfile.TemporaryDirectory()
    for sub in sorted({spec["sub"] for spec in specs}):
        tm = trimesh.creation.icosphere(subdivisions=sub)
        np.savez(os.path.join(meshes.name, f"ico{sub}.npz"), p=np.asarray(tm.vertices, np.float32),
                 f=np.asarray(tm.faces, np.int32), n=np.asarray(tm.vertex_normals, np.float32))
    specs = [dict(spec, mesh=os.path.join(meshes.name, f"ico{spec['sub']}.npz")) for spec in specs]

    def one(spec):
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "cg.out")
            env = dict(os.environ, PYTHONPATH=pythonpath)
            run = subprocess.run(["valgrind", "--tool=callgrind", "--collect-atstart=no",
                                  "--toggle-collect=sr::Renderer::render*", f"--callgrind-out-file={out}",
                                  exe, "-c", LITCG_CHILD, json.dumps(spec)],
                                 capture_output=True, text=True, env=env)
            if run.returncode != 0:
                raise RuntimeError(f"callgrind failed for {spec}: {run.stderr[-1500:]}")
            with open(out) as fh:
                total = next(int(line.split()[1]) for line in fh if line.startswith("totals:"))
            renders = spec["renders"] + (1 if spec["count_cover"] else 0)
            return total / renders if not spec["count_cover"] else None, json.loads(run.stdout.strip().splitlines()[-1])
    with meshes, concurrent.futures.ThreadPoolExecutor(parallel) as pool:
        return list(pool.map(one, specs))


def section_litcg(opts):
    if not shutil.which("valgrind"):
        print("\n## litcg skipped: valgrind is needed (bash benchmarks/setup_baselines.sh installs it)")
        return
    new_path = os.path.join(REPO, "python")
    sub, size, renders = 6, (1024, 1024), 2
    counts = LIT_COUNTS if not opts.quick else (1, 4)
    print(f"\n## Lit shading in instructions (callgrind, 1 thread, inside sr::Renderer::render only): "
          f"ico{sub} {size[0]}x{size[1]}, colour+depth, frequency=pixel, srgb=False; mean of {renders} renders")
    base = dict(sub=sub, size=size, renders=renders, count_cover=False)
    specs = [dict(base, outputs=["depth"], count_cover=True), dict(base, outputs=["depth"]),
             dict(base, outputs=["color", "depth"]), dict(base, outputs=["color", "depth"], model="lambert",
                                                           lights=1, srgb=True)]
    specs += [dict(base, outputs=["color", "depth"], model=m, lights=n) for m in LIT_MODELS for n in counts]
    res = _callgrind_renders(specs, new_path)
    cov = res[0][1]["covered"]
    depth = res[1][0]
    ipx = lambda i: (i - depth) / cov  # noqa: E731
    print(f"depth only {depth / 1e6:.1f} M instructions per render; {cov:,} covered px; plain Lambert "
          f"headlight {res[2][0] / 1e6:.1f} M = {ipx(res[2][0]):.1f} instr/covered px over depth")
    print(f"{'model':<13}" + "".join(f"{'M instr ' + str(n) + 'L':>13}" for n in counts)
          + "".join(f"{'i/px ' + str(n) + 'L':>9}" for n in counts) + f"{'fixed i/px':>12}{'i/px/light':>12}")
    by = {(s.get("model"), s.get("lights")): r[0] for s, r in zip(specs[4:], res[4:])}
    for m in LIT_MODELS:
        per = [ipx(by[(m, n)]) for n in counts]
        a, b, _ = linear_fit(list(counts), per)
        print(f"{m:<13}" + "".join(f"{by[(m, n)] / 1e6:>13.1f}" for n in counts)
              + "".join(f"{x:>9.1f}" for x in per) + f"{a:>12.1f}{b:>12.1f}")
    print(f"sRGB encoding (lambert, 1 light): {(res[3][0] - by[('lambert', 1)]) / cov:+.1f} instr/covered px")

    if not opts.ab_old:
        return
    print(f"\n## Lambert rows in instructions, old build ({opts.ab_old}) vs new (callgrind, 1 thread, "
          f"inside sr::Renderer::render only; mean of {renders} renders, out= after the first)")
    cases = [(6, (640, 480)), (6, (1024, 1024))]  # larger meshes take minutes under valgrind
    variants = [("color+depth", ["color", "depth"], {}), ("depth", ["depth"], {})]
    old_specs = [dict(sub=c[0], size=c[1], renders=renders, count_cover=False, outputs=o) for c in cases
                 for _, o, _ in variants]
    new_specs = [dict(s, srgb=False) if s["outputs"] != ["depth"] else dict(s) for s in old_specs]
    new_srgb = [dict(s, srgb=True) for s in old_specs if s["outputs"] != ["depth"]]
    old_res = _callgrind_renders(old_specs, opts.ab_old)
    new_res = _callgrind_renders(new_specs + new_srgb, new_path)
    print(f"{'case':<30}{'old':>14}{'new':>14}{'new/old':>9}")
    k_srgb = len(new_specs)
    for i, s in enumerate(old_specs):
        label = f"ico{s['sub']} {s['size'][0]}x{s['size'][1]} {'+'.join(s['outputs'])}"
        o, n = old_res[i][0], new_res[i][0]
        print(f"{label + (' linear' if len(s['outputs']) > 1 else ''):<30}{o:>14,.0f}{n:>14,.0f}{n / o:>9.4f}")
        if len(s["outputs"]) > 1:
            n2 = new_res[k_srgb][0]
            k_srgb += 1
            print(f"{label + ' sRGB':<30}{o:>14,.0f}{n2:>14,.0f}{n2 / o:>9.4f}")


class DistortionJob(Job):
    """ico6 at 640x480 through an IntrinsicsCamera with (or without) a strong barrel distortion."""

    def __init__(self, key, dist, oversample, outputs):
        super().__init__(key, 6, 640, 480, outputs=outputs)
        K = np.array([[420.0, 0.0, 319.5], [0.0, 420.0, 239.5], [0.0, 0.0, 1.0]])
        self.cam = sr.IntrinsicsCamera.from_opencv(K, np.zeros(3), np.zeros(3), 640, 480, dist=dist, near=NEAR,
                                                   far=FAR, oversample=oversample)
        self.cam.look_at(eye=(0.0, 0.0, 0.8 * camera_distance()), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))
        self.kwargs = dict(outputs=outputs)
        self.frame = self.renderer.render(self.scene, self.cam, **self.kwargs)


DISTORTION_BARREL = np.array([-0.3, 0.1, 0.0005, -0.0005, -0.02])
DISTORTION_OUTPUTS = {"color": ("color",), "c+d": ("color", "depth"),
                      "geometry": ("depth", "normal", "triangle_id", "instance_id", "position", "barycentric")}
DISTORTION_CAMERAS = [("pinhole", None, 1), ("dist s=1", DISTORTION_BARREL, 1), ("dist s=2", DISTORTION_BARREL, 2),
                      ("dist s=4", DISTORTION_BARREL, 4)]


def section_distortion(opts):
    print("\n## Lens distortion: ico6 640x480, strong barrel (k1 -0.3, k2 0.1), 2 threads, out=")
    outs = DISTORTION_OUTPUTS
    cams = DISTORTION_CAMERAS
    if opts.ab_old:
        return distortion_ab(opts)
    jobs = [DistortionJob((c, o), d, s, outs[o]) for c, d, s in cams for o in outs]
    run_interleaved(jobs, opts.target, opts.rounds)
    by = {j.key: j for j in jobs}
    print(f"{'camera':<12}" + "".join(f"{o + ' ms':>14}{'x pinhole':>11}" for o in outs))
    for c, _, _ in cams:
        print(f"{c:<12}" + "".join(f"{by[(c, o)].ms:>14.2f}{by[(c, o)].ms / by[('pinhole', o)].ms:>11.1f}"
                                   for o in outs))


def distortion_worker(renders: int) -> int:
    """One round of every distortion cell in this process (softrast as imported): its render
    times (s) as JSON on stdout."""
    jobs = [DistortionJob((c, o), d, s, DISTORTION_OUTPUTS[o]) for c, d, s in DISTORTION_CAMERAS
            for o in DISTORTION_OUTPUTS]
    out = {}
    for job in jobs:
        job()
        times = []
        for _ in range(renders):
            t0 = time.perf_counter()
            job()
            times.append(time.perf_counter() - t0)
        out[" / ".join(job.key)] = times
    print(json.dumps(out))
    return 0


def distortion_ab(opts):
    """--ab-old PATH: the distortion cells, old build (softrast importable from PATH) against this one,
    each round a fresh process per build, the builds' order alternating round by round."""
    here = os.path.dirname(os.path.dirname(sr.__file__))
    builds = {"old": opts.ab_old, "new": here}
    times = {"old": defaultdict(list), "new": defaultdict(list)}
    rounds = opts.rounds * 2
    for r in range(rounds):
        for b in (("old", "new") if r % 2 == 0 else ("new", "old")):
            env = dict(os.environ, PYTHONPATH=builds[b])
            res = subprocess.run([sys.executable, os.path.abspath(__file__), "--distortion-worker", "5"],
                                 capture_output=True, text=True, env=env, check=True)
            for k, v in json.loads(res.stdout.strip().splitlines()[-1]).items():
                times[b][k] += v
    print(f"A/B: old = {builds['old']}, new = {builds['new']}; {rounds} rounds x 5 renders, medians (ms)")
    print(f"{'cell':<26}{'old ms':>10}{'new ms':>10}{'new/old':>9}")
    for k in times["new"]:
        o, n = statistics.median(times["old"][k]) * 1e3, statistics.median(times["new"][k]) * 1e3
        print(f"{k:<26}{o:>10.2f}{n:>10.2f}{n / o:>9.3f}")


class AaJob(Job):
    """Job with an anti-aliasing mode (render(msaa=, ssaa=))."""

    def __init__(self, key, sub, width, height, outputs, mode, scene=None, cam=None):
        super().__init__(key, sub, width, height, outputs=outputs)
        if scene is not None:
            self.scene, self.cam = scene, cam
        self.kwargs = dict(outputs=outputs, shading="lambert", **mode)
        self.frame = self.renderer.render(self.scene, self.cam, **self.kwargs)


def _spot_scene(width, height):
    mesh = sr.load_mesh(os.path.join(REPO, "assets", "meshes", "spot.obj"))
    scene = sr.Scene()
    scene.add(mesh)
    cam = sr.PerspectiveCamera(fov_y=45.0, width=width, height=height, near=0.05, far=100.0)
    cam.look_at(eye=(1.7, 0.9, -2.3), target=(0.0, 0.05, 0.15), up=(0, 1, 0))
    return scene, cam


def section_antialiasing(opts):
    print("\n## Anti-aliasing: cost of each msaa / ssaa level, 640x480, 2 threads, out=;"
          "\n   ico6 (81,920 faces of ~4 px: most pixels meet an edge) and Spot (5,856 faces)")
    modes = [("off", {}), ("msaa2", dict(msaa=2)), ("msaa4", dict(msaa=4)), ("msaa8", dict(msaa=8)),
             ("msaa16", dict(msaa=16)), ("ssaa2", dict(ssaa=2)), ("ssaa3", dict(ssaa=3)),
             ("ssaa4", dict(ssaa=4))]
    if not opts.quick:
        modes.append(("ssaa8", dict(ssaa=8)))
    outs = {"depth": ("depth",), "c+d": ("color", "depth")}
    spot = _spot_scene(640, 480)
    jobs = []
    for scene_name in ("ico6", "spot"):
        extra = {} if scene_name == "ico6" else dict(scene=spot[0], cam=spot[1])
        jobs += [AaJob((scene_name, m, o), 6, 640, 480, outs[o], mode, **extra)
                 for m, mode in modes for o in outs]
    run_interleaved(jobs, opts.target, opts.rounds)
    by = {j.key: j for j in jobs}
    for scene_name in ("ico6", "spot"):
        print(f"{scene_name:<8}{'mode':<8}" + "".join(f"{o + ' ms':>10}{'x off':>7}" for o in outs))
        for m, _ in modes:
            print(f"{'':<8}{m:<8}" + "".join(
                f"{by[(scene_name, m, o)].ms:>10.2f}{by[(scene_name, m, o)].ms / by[(scene_name, 'off', o)].ms:>7.2f}"
                for o in outs))


def section_overhead(opts):
    print("\n## Python overhead per frame: 1x1 image, one triangle (goal: < 50 us)")
    tri = sr.Mesh(np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]], np.int32))
    scene = sr.Scene()
    scene.add(tri)
    cam = sr.PerspectiveCamera(fov_y=FOV_Y_DEG, width=1, height=1, near=NEAR, far=FAR)
    cam.look_at(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))
    n = 2000 if opts.quick else 10000
    rows = []
    for threads in (1, 2):
        r = sr.Renderer(1, 1, threads=threads)
        f_cd, f_d = r.render(scene, cam), r.render(scene, cam, outputs=("depth",))
        calls = {
            "color+depth, new arrays": lambda: r.render(scene, cam),
            "color+depth, out=": lambda: r.render(scene, cam, out=f_cd),
            "depth, out=": lambda: r.render(scene, cam, outputs=("depth",), out=f_d),
        }
        samples = defaultdict(list)
        for _ in range(200):
            for fn in calls.values():
                fn()
        for _ in range(5):  # interleave in blocks
            for name, fn in calls.items():
                for _ in range(n // 5):
                    t0 = time.perf_counter_ns()
                    fn()
                    samples[name].append(time.perf_counter_ns() - t0)
        for name in calls:
            s = np.array(samples[name]) / 1e3
            rows.append((threads, name, np.median(s), np.percentile(s, 10), np.percentile(s, 90)))
    print(f"{'threads':>8}  {'call':<26}{'median us':>10}{'p10':>8}{'p90':>8}")
    for threads, name, med, p10, p90 in rows:
        print(f"{threads:>8}  {name:<26}{med:>10.1f}{p10:>8.1f}{p90:>8.1f}")
    print("(the whole call: argument checks, scene walk, matrices, the C++ render of 1 pixel and "
          "the arrays' wrapping; with threads 2 it includes waking the pool)")


# Runs in a fresh interpreter. Peak RSS is VmHWM (the high-water mark of this process's own
# memory): ru_maxrss would also do, but a forked child inherits the parent's ru_maxrss.
MEMORY_CHILD = r"""
import json, resource, sys
def status(key):
    with open('/proc/self/status') as f:
        return next(int(l.split()[1]) for l in f if l.startswith(key + ':')) / 1024
import numpy as np, softrast as sr
sys.path.insert(0, sys.argv[2])
from bench_stages import camera
rec = {'imports': status('VmRSS')}
positions, faces, normals = (np.load(sys.argv[1] + n) for n in ('/p.npy', '/f.npy', '/n.npy'))
rec['arrays'] = status('VmRSS')
mesh = sr.Mesh(positions, faces, normals=normals)
scene = sr.Scene(); scene.add(mesh)
rec['mesh'] = status('VmRSS')
cam = camera(1024, 1024)
r = sr.Renderer(1024, 1024, threads=2)
frame = r.render(scene, cam, outputs=('color', 'depth'))
for _ in range(3): r.render(scene, cam, outputs=('color', 'depth'), out=frame)
rec['render'] = status('VmRSS'); rec['peak'] = status('VmHWM')
rec['ru_maxrss'] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps(rec))
"""


def section_memory(opts):
    print("\n## Peak memory: icosphere sub 8 (1,310,720 faces) at 1024x1024, colour+depth, threads 2")
    tm = trimesh.creation.icosphere(subdivisions=8)
    positions = np.ascontiguousarray(tm.vertices, np.float32)
    faces = np.ascontiguousarray(tm.faces, np.int32)
    normals = np.ascontiguousarray(tm.vertex_normals, np.float32)
    mesh_mb = (positions.nbytes + faces.nbytes + normals.nbytes) / 2**20
    fb_mb = 1024 * 1024 * (3 + 4) / 2**20
    with tempfile.TemporaryDirectory() as tmp:
        for name, arr in (("p", positions), ("f", faces), ("n", normals)):
            np.save(f"{tmp}/{name}.npy", arr)
        child = subprocess.run([sys.executable, "-c", MEMORY_CHILD, tmp, os.path.dirname(os.path.abspath(__file__))],
                               capture_output=True, text=True)
    if child.returncode != 0:
        print("memory child failed:", child.stderr[-2000:])
        return
    rec = json.loads(child.stdout.strip().splitlines()[-1])
    used = rec["peak"] - rec["imports"]
    print(f"mesh's own arrays (float32 positions + normals, int32 faces): {mesh_mb:.1f} MiB; "
          f"framebuffers (RGB8 + float32 depth): {fb_mb:.1f} MiB; sum {mesh_mb + fb_mb:.1f} MiB")
    print(f"RSS (MiB) of a fresh process: after imports {rec['imports']:.1f}; + loaded arrays "
          f"{rec['arrays']:.1f}; + sr.Mesh and Scene {rec['mesh']:.1f}; after 4 renders {rec['render']:.1f}; "
          f"peak (VmHWM) {rec['peak']:.1f} (ru_maxrss {rec['ru_maxrss']:.1f})")
    print(f"peak - imports = {used:.1f} MiB = {used / (mesh_mb + fb_mb):.2f}x (mesh arrays + "
          f"framebuffers); goal < 4x. Of it: softrast's mesh copies {rec['mesh'] - rec['arrays']:.1f} MiB, "
          f"renders {rec['peak'] - rec['mesh']:.1f} MiB")


ANNOTATE_LINE = re.compile(r"^\s*([\d,]+)\s+\(\s*[\d.]+%\)\s+(.*?):(.*)$")
# Stage of a function, by the names the core's stage files use (inlined GLM / std lines are
# reported under the function they were inlined into, so classify by function, not file).
STAGES = (("driver (excluded)", ("icosphere", "_Rb_tree", "main", "MeshData::validate", "dl_",
                                 "do_lookup", "_dl", "Renderer::Renderer", "ThreadPool::ThreadPool")),
          ("transform", ("transform_point", "make_draw_transform")),  # inlined: counted in project_vertices
          ("clip", ("clip_triangle", "intersect", "ClipPlanes")),
          ("project+setup+bin", ("project", "setup", "true_plane_keys")),
          ("raster", ("rasterize",)),
          ("shade", ("shade", "prepare")),
          ("framebuffer alloc/clear", ("Framebuffer", "memset")),
          ("copies (memcpy)", ("memcpy", "memmove")),
          ("malloc/free (render and driver)", ("malloc", "free", "operator new", "operator delete",
                                              "unlink_chunk", "consolidate")),
          ("thread pool, renderer", ("ThreadPool", "Renderer", "thread", "_Function_handler")))


def stage_of(fn: str) -> str:
    name = re.sub(r"\((anonymous namespace|glm::qualifier)\)", "", fn).split("(")[0]
    for stage, keys in STAGES:
        if any(k in name for k in keys):
            return stage
    return "other"


def short_name(fn: str) -> str:
    return re.sub(r"\(.*\)", "(...)", fn.replace("sr::(anonymous namespace)::", "sr::"))[:90]


def section_callgrind(opts):
    print("\n## Instructions per stage (valgrind callgrind, C++ core without Python, 1 thread)")
    if not shutil.which("valgrind") or not shutil.which("g++"):
        print("skipped: valgrind and g++ are needed (bash benchmarks/setup_baselines.sh installs them)")
        return
    exe = os.path.join(REPO, "build", "core_bench")
    sources = sorted(os.path.join(REPO, "cpp", f) for f in os.listdir(os.path.join(REPO, "cpp"))
                     if f.endswith(".cpp") and f != "bindings.cpp")
    os.makedirs(os.path.dirname(exe), exist_ok=True)
    # -g adds line/file info for callgrind_annotate and does not change the generated code.
    cmd = ["g++", "-O2", "-g", "-std=c++17", "-I" + os.path.join(REPO, "cpp"),
           os.path.join(REPO, "benchmarks", "core_bench.cpp"), *sources, "-lpthread", "-o", exe]
    build = subprocess.run(cmd, capture_output=True, text=True)
    if build.returncode != 0:
        print("core_bench build failed:\n" + build.stderr[-3000:])
        return
    renders = 3  # every instruction of the process is counted; the driver's own are left out
    cases = [(6, 1024, 1024, 3, "color+depth"), (6, 1024, 1024, 2, "depth")]
    if not opts.quick:
        cases += [(8, 1024, 1024, 3, "color+depth"), (8, 1024, 1024, 2, "depth")]
    for sub, w, h, bits, label in cases:
        with tempfile.TemporaryDirectory() as tmp:
            out = os.path.join(tmp, "cg.out")
            run = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
                                  exe, str(sub), str(w), str(h), str(bits), str(renders), "1"],
                                 capture_output=True, text=True)
            if run.returncode != 0:
                print(f"callgrind failed for ico{sub}:\n{run.stderr[-2000:]}")
                continue
            ann = subprocess.run(["callgrind_annotate", "--inclusive=no", "--auto=no", "--threshold=100", out],
                                 capture_output=True, text=True).stdout
        per_stage, per_fn, total = defaultdict(int), [], 0
        for line in ann.splitlines():
            m = ANNOTATE_LINE.match(line)
            if not m:
                continue
            ir, file, fn = int(m.group(1).replace(",", "")), m.group(2), m.group(3)
            fn = re.sub(r" \[/[^\]]*\]$", "", fn)  # drop the trailing [object file]
            stage = stage_of(fn)
            per_stage[stage] += ir
            if stage != "driver (excluded)":
                per_fn.append((ir, fn, os.path.basename(file)))
                total += ir
        if total == 0:
            print(f"ico{sub}: could not parse callgrind_annotate output:\n{ann[:2000]}")
            continue
        merged = defaultdict(int)  # one function's lines may be spread over inlined headers
        for ir, fn, _ in per_fn:
            merged[fn] += ir
        faces = 20 * 4 ** sub
        print(f"ico{sub} {w}x{h} {label}: {total / renders / 1e6:.1f} M instructions per render "
              f"(mean of {renders} renders, 1 thread), {total / renders / faces:.0f} per face")
        for stage, ir in sorted(per_stage.items(), key=lambda kv: (kv[0].startswith("driver"), -kv[1])):
            share = "  (not in the total)" if stage.startswith("driver") else \
                f"  {100 * ir / total:5.1f}%  {ir / renders / faces:7.1f} /face"
            print(f"  {stage:<32}{ir / renders / 1e6:>9.2f} M{share}")
        print("  top functions (self):")
        for fn, ir in sorted(merged.items(), key=lambda kv: -kv[1])[:8]:
            print(f"    {100 * ir / total:5.1f}%  {short_name(fn)}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer repetitions, no sub 8 / 4096 / 2048 rows")
    ap.add_argument("--sections", default=",".join(SECTIONS), help="comma-separated: " + ",".join(SECTIONS))
    ap.add_argument("--ab-old", default=None, metavar="PATH",
                    help="litcg: also count the Lambert rows' instructions with the old build importable from PATH; "
                         "distortion: time its cells A/B against that build (interleaved processes)")
    ap.add_argument("--distortion-worker", type=int, default=0, help=argparse.SUPPRESS)
    opts = ap.parse_args(argv)
    if opts.distortion_worker:
        return distortion_worker(opts.distortion_worker)
    opts.target, opts.rounds = (0.3, 3) if opts.quick else (1.2, 5)
    sections = opts.sections.split(",")
    for s in sections:
        if s not in SECTIONS:
            ap.error(f"unknown section {s!r}")
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                            cwd=REPO).stdout.strip()
    print(f"softrast {getattr(sr, '__version__', '?')} commit {commit}, {os.cpu_count()} cores; "
          f"sphere silhouette {SILHOUETTE_FRACTION} of the height (camera at {camera_distance():.3f})")
    for s in sections:
        globals()["section_" + s](opts)
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
