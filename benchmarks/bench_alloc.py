"""A default render (new arrays each time, released by the caller) against a render into
out= arrays, on bench_vs_pyrender.py's Lambert rows (colour + depth, threads 2): the goal is the
default within 10% of out= on every row (RESULTS.md, "Python overhead and memory"). Interleaved
rounds, medians in ms.

    python3 benchmarks/bench_alloc.py [--rounds 7] [--frames 30]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import trimesh

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "python"))
import softrast as sr  # noqa: E402

ROWS = [(3, 256, 256), (6, 640, 480), (6, 1024, 1024), (7, 2048, 2048), (8, 1024, 1024)]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--frames", type=int, default=30)
    args = ap.parse_args()
    print(f"softrast {sr.__version__}; colour+depth, threads 2, median of {args.rounds} rounds x "
          f"{args.frames} frames")
    print(f"{'row':<18}{'out= ms':>9}{'default ms':>12}{'default/out':>13}")
    for sub, w, h in ROWS:
        tm = trimesh.creation.icosphere(subdivisions=sub)
        scene = sr.Scene()
        scene.add(sr.Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals))
        cam = sr.PerspectiveCamera(fov_y=45.0, width=w, height=h)
        cam.look_at((0.0, 0.0, 3.2), (0.0, 0.0, 0.0))
        r = sr.Renderer(w, h, threads=2)
        kw = dict(outputs=("color", "depth"))
        frame = r.render(scene, cam, **kw)
        times = {"out": [], "default": []}
        for _ in range(args.rounds):
            t = time.perf_counter()
            for _ in range(args.frames):
                r.render(scene, cam, out=frame, **kw)
            times["out"].append((time.perf_counter() - t) / args.frames)
            t = time.perf_counter()
            for _ in range(args.frames):
                r.render(scene, cam, **kw)  # the frame is released at once
            times["default"].append((time.perf_counter() - t) / args.frames)
        o, d = (statistics.median(times[k]) * 1e3 for k in ("out", "default"))
        print(f"ico{sub} {w}x{h}".ljust(18) + f"{o:>9.3f}{d:>12.3f}{d / o:>13.3f}", flush=True)


if __name__ == "__main__":
    main()
