"""What blending costs: a frame with blended layers over the same frame drawn opaque, one run.

    python3 benchmarks/bench_blend.py [--quick] [--png DIR] [--msaa N | --ssaa K]

Scene: Spot (assets/meshes/spot.obj, no texture, Blinn-Phong, one point light) filling about half
of the image, and four translucent quads (alpha 0.5, Blinn-Phong, different colours) stacked in
front of it, each slightly offset, so that about a fifth of the covered pixels see up to four
blended layers. Rows: 640x480 and 1024x1024, two threads, colour + depth. Columns: "opaque" (the
same draws, alpha_mode "opaque"), "blend" (alpha_mode "blend") and their ratio; cells alternate
in rounds so that they share the machine's noise; times are medians in ms per frame, steady
state (scene uploaded once, renderer reused). The goal: blend / opaque <= 1.5 (RESULTS.md, "Blending").
``--msaa N`` / ``--ssaa K`` render both columns anti-aliased (each sample composites its layers).
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import softrast as sr

ROOT = Path(__file__).resolve().parents[1]
AA: dict = {"msaa": 1, "ssaa": 1}  # (main sets it from --msaa / --ssaa)


def scene_of(mode: str) -> tuple[sr.Scene, sr.PerspectiveCamera]:
    spot = sr.load_mesh(ROOT / "assets" / "meshes" / "spot.obj")
    scene = sr.Scene()
    scene.add(spot, material=sr.Material(base_color=(0.8, 0.7, 0.6), model="blinn_phong"))
    colours = [(1.0, 0.2, 0.2, 0.5), (0.2, 1.0, 0.2, 0.5), (0.2, 0.2, 1.0, 0.5), (1.0, 1.0, 0.2, 0.5)]
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    for k, c in enumerate(colours):
        x, y, z = -0.25 + 0.05 * k, -0.15 + 0.04 * k, 0.9 + 0.1 * k
        s = 0.15
        quad = sr.Mesh(np.array([[x - s, y - s, z], [x + s, y - s, z], [x + s, y + s, z], [x - s, y + s, z]]),
                       faces)
        scene.add(quad, material=sr.Material(base_color=c if mode == "blend" else c[:3],
                                             model="blinn_phong", alpha_mode=mode))
    light_pose = np.eye(4)
    light_pose[:3, 3] = (2.0, 2.0, 3.0)
    scene.add(sr.PointLight(intensity=12.0), pose=light_pose)
    cam = sr.PerspectiveCamera(fov_y=45.0, near=0.1, far=20.0)
    cam.look_at(eye=(0.0, 0.2, 3.2), target=(0.0, 0.0, 0.0))
    return scene, cam


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--png", type=Path)
    ap.add_argument("--msaa", type=int, default=1)
    ap.add_argument("--ssaa", type=int, default=1)
    args = ap.parse_args()
    global AA
    AA = {"msaa": args.msaa, "ssaa": args.ssaa}
    sizes = [(640, 480)] + ([] if args.quick else [(1024, 1024)])
    rounds = 5 if args.quick else 11
    print(f"{'size':>10} {'opaque ms':>10} {'blend ms':>10} {'ratio':>7} {'layered px':>11}")
    for w, h in sizes:
        cells = {}
        for mode in ("opaque", "blend"):
            scene, cam = scene_of(mode)
            r = sr.Renderer(w, h, threads=2)
            frame = r.render(scene, cam, outputs=("color", "depth"), **AA)
            cells[mode] = (r, scene, cam, frame)
        # The share of covered pixels with a blended layer (the quads' own coverage).
        _, scene_o, cam_o, _ = cells["opaque"]
        ids = sr.Renderer(w, h).render(scene_o, cam_o, outputs=("instance_id",)).instance_id
        layered = float(np.mean(ids[ids >= 0] >= 1))
        if args.png:
            args.png.mkdir(parents=True, exist_ok=True)
            for mode, (_, _, _, frame) in cells.items():
                sr.imwrite(args.png / f"blend_{mode}_{w}x{h}.png", frame.color)
        n = max(3, int(0.3 / max(1e-4, _time(cells["blend"], 3))))
        times: dict[str, list[float]] = {"opaque": [], "blend": []}
        ratios = []
        for k in range(rounds):
            order = ("opaque", "blend") if k % 2 == 0 else ("blend", "opaque")
            t = {m: _time(cells[m], n) for m in order}
            for m in order:
                times[m].append(t[m])
            ratios.append(t["blend"] / t["opaque"])
        to = float(np.median(times["opaque"])) * 1e3
        tb = float(np.median(times["blend"])) * 1e3
        print(f"{w}x{h:<5} {to:10.3f} {tb:10.3f} {float(np.median(ratios)):7.3f} {layered:11.1%}")


def _time(cell, n: int) -> float:
    r, scene, cam, frame = cell
    t0 = time.perf_counter()
    for _ in range(n):
        r.render(scene, cam, outputs=("color", "depth"), out=frame, **AA)
    return (time.perf_counter() - t0) / n


if __name__ == "__main__":
    main()
