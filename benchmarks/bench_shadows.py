"""What shadows cost: a frame with one shadowed light over the same frame without, one run.

    python3 benchmarks/bench_shadows.py [--quick] [--png DIR] [--no-pyrender]

Scenes: Spot (assets/meshes/spot.obj, 5,856 triangles, Blinn-Phong) standing on a floor of two
triangles, lit by one light (directional, then point), filling most of the image; and the same
Spot subdivided twice (93,696 triangles: the issue's ~100k-triangle scene) under the
directional light. Rows: 640x480 and 1024x1024, two threads, colour + depth. Columns: "off"
(render(shadows=False)), "exact" (render(shadows=True)), "map" (render(shadows="map"): 2048x2048
maps, a cube of six for the point light, made in the first render and kept with the scene),
their ratios to "off", the shadow rays per second over the exact frame's added time (counting
one per covered pixel, an upper bound: only pixels facing the light cast one), the share of
covered pixels in shadow, and pyrender 0.1.45 (OSMesa's llvmpipe, in a child process) with
``RenderFlags.SHADOWS_DIRECTIONAL`` on the same scene, over its own unshadowed frame (it has no
point-light shadows).

Each method renders with its own Renderer, as a loop over views of one scene would: the exact
method keeps its occluders' hierarchy between frames (a shadow-map render drops it). Cells
alternate in rounds so that they share the machine's noise; times are medians in ms per frame,
steady state (scene uploaded once, renderers reused).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import softrast as sr

ROOT = Path(__file__).resolve().parents[1]
EYE, TARGET = (0.3, 1.2, 2.6), (0.0, 0.0, 0.0)
SUN = ((2.0, 3.0, 1.0), (0.0, 0.0, 0.0))
LAMP = ((1.5, 2.5, 1.5), (0.0, 0.0, 0.0))


def spot_arrays(subdivisions: int = 0) -> tuple[np.ndarray, np.ndarray]:
    import trimesh
    tm = trimesh.load(ROOT / "assets" / "meshes" / "spot.obj", process=False, force="mesh")
    v, f = np.asarray(tm.vertices), np.asarray(tm.faces)
    for _ in range(subdivisions):
        v, f = trimesh.remesh.subdivide(v, f)
    return v, f


def floor_arrays(y0: float) -> tuple[np.ndarray, np.ndarray]:
    return (np.array([[-3.0, y0, -3.0], [3.0, y0, -3.0], [3.0, y0, 3.0], [-3.0, y0, 3.0]]),
            np.array([[0, 2, 1], [0, 3, 2]]))


def scene_of(kind: str, subdivisions: int = 0) -> tuple[sr.Scene, sr.PerspectiveCamera]:
    v, f = spot_arrays(subdivisions)
    spot = sr.Mesh(v, f)
    scene = sr.Scene(ambient_light=(0.1, 0.1, 0.1))
    scene.add(spot, material=sr.Material(base_color=(0.8, 0.7, 0.6), model="blinn_phong"))
    fv, ff = floor_arrays(float(v[:, 1].min()))
    scene.add(sr.Mesh(fv, ff), material=sr.Material(base_color=(0.7, 0.7, 0.7), model="lambert"))
    if kind == "directional":
        scene.add(sr.DirectionalLight(intensity=1.2, shadows=True), pose=sr.look_at_pose(*SUN))
    else:
        scene.add(sr.PointLight(intensity=10.0, shadows=True), pose=sr.look_at_pose(*LAMP))
    cam = sr.PerspectiveCamera(fov_y=45.0, near=0.1, far=20.0)
    cam.look_at(eye=EYE, target=TARGET)
    return scene, cam


METHODS = (False, "exact", "map")

# pyrender's side, run in a child process (its OpenGL platform never touches this one): the same
# meshes, camera and directional light; prints {"off": ms, "shadows": ms} medians.
PYRENDER_CHILD = r'''
import json, sys, time
import numpy as np
np.infty = np.inf  # pyrender 0.1.45's shadow pass uses it (gone in NumPy 2)
import pyrender, trimesh
sys.path.insert(0, sys.argv[1])
import bench_shadows as b
w, h, sub, rounds = (int(a) for a in sys.argv[2:6])
v, f = b.spot_arrays(sub)
fv, ff = b.floor_arrays(float(v[:, 1].min()))
scene = pyrender.Scene(ambient_light=[0.1, 0.1, 0.1], bg_color=[0, 0, 0, 0])
mat = lambda c: pyrender.MetallicRoughnessMaterial(baseColorFactor=c + [1.0], metallicFactor=0.0, roughnessFactor=0.8)
scene.add(pyrender.Mesh.from_trimesh(trimesh.Trimesh(v, f, process=False), material=mat([0.8, 0.7, 0.6]), smooth=True))
scene.add(pyrender.Mesh.from_trimesh(trimesh.Trimesh(fv, ff, process=False), material=mat([0.7, 0.7, 0.7])))
import softrast as sr
cam = sr.PerspectiveCamera(fov_y=45.0, near=0.1, far=20.0)
cam.look_at(eye=b.EYE, target=b.TARGET)
scene.add(pyrender.PerspectiveCamera(yfov=np.radians(45.0), aspectRatio=w / h, znear=0.1, zfar=20.0), pose=cam.pose)
scene.add(pyrender.DirectionalLight(intensity=1.2), pose=sr.look_at_pose(*b.SUN))
r = pyrender.OffscreenRenderer(w, h)
flags = {"off": pyrender.RenderFlags.NONE, "shadows": pyrender.RenderFlags.SHADOWS_DIRECTIONAL}
for fl in flags.values():
    r.render(scene, flags=fl)
times = {k: [] for k in flags}
for k in range(rounds):
    for name, fl in (flags.items() if k % 2 == 0 else list(flags.items())[::-1]):
        t = time.perf_counter()
        for _ in range(3):
            r.render(scene, flags=fl)
        times[name].append((time.perf_counter() - t) / 3)
print(json.dumps({k: float(np.median(v)) * 1e3 for k, v in times.items()}))
'''


def pyrender_ms(w: int, h: int, subdivisions: int, rounds: int) -> dict | None:
    env = dict(os.environ, PYOPENGL_PLATFORM="osmesa")
    proc = subprocess.run([sys.executable, "-c", PYRENDER_CHILD, str(Path(__file__).parent),
                           str(w), str(h), str(subdivisions), str(rounds)],
                          env=env, capture_output=True, text=True, timeout=900)
    if proc.returncode != 0:
        print(f"(pyrender failed: {proc.stderr.strip().splitlines()[-1:]})")
        return None
    # (PyOpenGL may print at interpreter shutdown: the result is the line that is a JSON object)
    return json.loads(next(line for line in proc.stdout.splitlines() if line.startswith("{")))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--png", type=Path)
    ap.add_argument("--no-pyrender", action="store_true")
    args = ap.parse_args()
    rounds = 5 if args.quick else 9
    rows = [("directional", 0, (640, 480)), ("point", 0, (640, 480))]
    if not args.quick:
        rows = [("directional", 0, (640, 480)), ("directional", 0, (1024, 1024)),
                ("point", 0, (640, 480)), ("point", 0, (1024, 1024)), ("directional", 2, (1024, 1024))]
    print(f"{'light':>12} {'triangles':>9} {'size':>10} {'off ms':>8} {'exact ms':>9} {'map ms':>8} "
          f"{'exact/off':>10} {'map/off':>8} {'Mrays/s':>8} {'in shadow':>10} {'pyrender off/shadows ms':>24}")
    for kind, sub, (w, h) in rows:
        scene, cam = scene_of(kind, sub)
        tris = sum(len(i.mesh.faces) for i in scene.instances)
        renderers = {s: sr.Renderer(w, h, threads=2) for s in METHODS}
        frames = {s: renderers[s].render(scene, cam, outputs=("color", "depth"), shadows=s) for s in METHODS}
        rad = {s: sr.Renderer(w, h).render(scene, cam, outputs=("radiance", "mask"), shadows=s)
               for s in (False, "exact")}
        covered = rad[False].mask
        dark = (rad["exact"].radiance < rad[False].radiance).any(-1)
        rays = int(covered.sum())  # at most one per covered pixel (those facing the light)
        if args.png:
            args.png.mkdir(parents=True, exist_ok=True)
            for s, f in frames.items():
                sr.imwrite(args.png / f"shadows_{kind}_{tris}_{s or 'off'}_{w}x{h}.png", f.color)
        n = max(2, int(0.3 / max(1e-4, _time(renderers["exact"], scene, cam, frames["exact"], "exact", 1))))
        times: dict = {s: [] for s in METHODS}
        ratios: dict = {s: [] for s in METHODS[1:]}
        for k in range(rounds):
            order = METHODS if k % 2 == 0 else METHODS[::-1]
            t = {s: _time(renderers[s], scene, cam, frames[s], s, n) for s in order}
            for s in order:
                times[s].append(t[s])
            for s in METHODS[1:]:
                ratios[s].append(t[s] / t[False])
        med = {s: float(np.median(v)) for s, v in times.items()}
        mrays = rays / max(1e-9, med["exact"] - med[False]) / 1e6
        pyr = "n/a (no point shadows)" if kind != "directional" or args.no_pyrender else "failed"
        if kind == "directional" and not args.no_pyrender:
            got = pyrender_ms(w, h, sub, rounds)
            if got:
                pyr = f"{got['off']:.1f} / {got['shadows']:.1f}"
        print(f"{kind:>12} {tris:>9} {w}x{h:<5} {med[False] * 1e3:8.2f} {med['exact'] * 1e3:9.2f} "
              f"{med['map'] * 1e3:8.2f} {float(np.median(ratios['exact'])):10.2f} "
              f"{float(np.median(ratios['map'])):8.2f} {mrays:8.2f} {dark[covered].mean():10.1%} {pyr:>24}",
              flush=True)


def _time(r, scene, cam, frame, shadows, n: int) -> float:
    t0 = time.perf_counter()
    for _ in range(n):
        r.render(scene, cam, outputs=("color", "depth"), shadows=shadows, out=frame)
    return (time.perf_counter() - t0) / n


if __name__ == "__main__":
    main()
