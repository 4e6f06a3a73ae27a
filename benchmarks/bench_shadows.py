"""What shadows cost: a frame with one shadowed light over the same frame without, one run.

    python3 benchmarks/bench_shadows.py [--quick] [--png DIR]

Scene: Spot (assets/meshes/spot.obj, 5,856 triangles, Blinn-Phong) standing on a floor of two
triangles, lit by one light (directional, then point), filling most of the image. Rows: 640x480
and 1024x1024, two threads, colour + depth. Columns: "off" (render(shadows=False)), "exact"
(render(shadows=True)), "map" (render(shadows="map"): 2048x2048 maps, a cube of six for the
point light, made in the first render and kept with the scene), their ratios to "off", the
shadow rays per second over the exact frame's added time (counting one per covered pixel, an
upper bound: only pixels facing the light cast one), and the share of covered pixels in shadow.
Cells alternate in rounds so that they share the machine's noise; times are medians in ms per
frame, steady state (scene uploaded once, renderer reused; the exact method's occluder hierarchy
is built in every frame, and is part of its time).
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import softrast as sr

ROOT = Path(__file__).resolve().parents[1]


def scene_of(kind: str) -> tuple[sr.Scene, sr.PerspectiveCamera]:
    spot = sr.load_mesh(ROOT / "assets" / "meshes" / "spot.obj")
    scene = sr.Scene(ambient_light=(0.1, 0.1, 0.1))
    scene.add(spot, material=sr.Material(base_color=(0.8, 0.7, 0.6), model="blinn_phong"))
    y0 = float(spot.positions[:, 1].min())
    floor = sr.Mesh(np.array([[-3.0, y0, -3.0], [3.0, y0, -3.0], [3.0, y0, 3.0], [-3.0, y0, 3.0]]),
                    np.array([[0, 2, 1], [0, 3, 2]]))
    scene.add(floor, material=sr.Material(base_color=(0.7, 0.7, 0.7), model="lambert"))
    if kind == "directional":
        scene.add(sr.DirectionalLight(intensity=1.2, shadows=True), pose=sr.look_at_pose((2.0, 3.0, 1.0), (0, 0, 0)))
    else:
        scene.add(sr.PointLight(intensity=10.0, shadows=True), pose=sr.look_at_pose((1.5, 2.5, 1.5), (0, 0, 0)))
    cam = sr.PerspectiveCamera(fov_y=45.0, near=0.1, far=20.0)
    cam.look_at(eye=(0.3, 1.2, 2.6), target=(0.0, 0.0, 0.0))
    return scene, cam


METHODS = (False, "exact", "map")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--png", type=Path)
    args = ap.parse_args()
    sizes = [(640, 480)] + ([] if args.quick else [(1024, 1024)])
    rounds = 5 if args.quick else 9
    print(f"{'light':>12} {'size':>10} {'off ms':>8} {'exact ms':>9} {'map ms':>8} {'exact/off':>10} "
          f"{'map/off':>8} {'Mrays/s':>8} {'in shadow':>10}")
    for kind in ("directional", "point"):
        scene, cam = scene_of(kind)
        for w, h in sizes:
            r = sr.Renderer(w, h, threads=2)
            frames = {s: r.render(scene, cam, outputs=("color", "depth"), shadows=s) for s in METHODS}
            rad = {s: sr.Renderer(w, h).render(scene, cam, outputs=("radiance", "mask"), shadows=s)
                   for s in (False, "exact")}
            covered = rad[False].mask
            dark = (rad["exact"].radiance < rad[False].radiance).any(-1)
            rays = int(covered.sum())  # at most one per covered pixel (those facing the light)
            if args.png:
                args.png.mkdir(parents=True, exist_ok=True)
                for s, f in frames.items():
                    sr.imwrite(args.png / f"shadows_{kind}_{s or 'off'}_{w}x{h}.png", f.color)
            n = max(2, int(0.3 / max(1e-4, _time(r, scene, cam, frames["exact"], "exact", 1))))
            times: dict = {s: [] for s in METHODS}
            ratios: dict = {s: [] for s in METHODS[1:]}
            for k in range(rounds):
                order = METHODS if k % 2 == 0 else METHODS[::-1]
                t = {s: _time(r, scene, cam, frames[s], s, n) for s in order}
                for s in order:
                    times[s].append(t[s])
                for s in METHODS[1:]:
                    ratios[s].append(t[s] / t[False])
            med = {s: float(np.median(v)) for s, v in times.items()}
            mrays = rays / max(1e-9, med["exact"] - med[False]) / 1e6
            print(f"{kind:>12} {w}x{h:<5} {med[False] * 1e3:8.2f} {med['exact'] * 1e3:9.2f} "
                  f"{med['map'] * 1e3:8.2f} {float(np.median(ratios['exact'])):10.2f} "
                  f"{float(np.median(ratios['map'])):8.2f} {mrays:8.2f} {dark[covered].mean():10.1%}")


def _time(r, scene, cam, frame, shadows, n: int) -> float:
    t0 = time.perf_counter()
    for _ in range(n):
        r.render(scene, cam, outputs=("color", "depth"), shadows=shadows, out=frame)
    return (time.perf_counter() - t0) / n


if __name__ == "__main__":
    main()
