"""Soak: many renders of changing scenes in one process; prints RSS as it goes.

    python benchmarks/soak.py [RENDERS]     (default 10000)

Each render builds a fresh mesh of random size (uploaded to the core, then dropped), moves the
camera, picks a random set of outputs and, one time in four, renders in place with out=. RSS is
read from /proc/self/statm; growth is measured from the end of the warm-up (the first 10%).
tests/test_soak.py runs the same loop with fewer renders.
"""
from __future__ import annotations

import math
import os
import sys
import time

import numpy as np

import softrast as sr

PAGE = os.sysconf("SC_PAGE_SIZE")


def rss_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * PAGE


def random_mesh(rng: np.random.Generator) -> sr.Mesh:
    """A height-field grid of random resolution (8 .. 20000 triangles), sometimes with colours."""
    nx, ny = (int(v) for v in rng.integers(2, 100, size=2))
    xs, ys = np.meshgrid(np.linspace(-1, 1, nx + 1), np.linspace(-1, 1, ny + 1))
    zs = 0.2 * np.sin(3 * xs + rng.random()) * np.cos(2 * ys)
    positions = np.stack([xs, ys, zs], axis=-1).reshape(-1, 3)
    i = np.arange(nx * ny) % nx + np.arange(nx * ny) // nx * (nx + 1)
    faces = np.concatenate([np.stack([i, i + 1, i + nx + 2], 1), np.stack([i, i + nx + 2, i + nx + 1], 1)])
    colors = rng.random((len(positions), 3)) if rng.random() < 0.5 else None
    return sr.Mesh(positions, faces, colors=colors)


def run(renders: int, report_every: int = 0, out=sys.stdout) -> dict[str, float]:
    """Render ``renders`` changing scenes; returns RSS (MB) after warm-up and at the end."""
    rng = np.random.default_rng(2026)
    renderers = [sr.Renderer(64, 48, threads=2), sr.Renderer(96, 96, threads=1)]
    warmup = max(50, renders // 10)
    frames: list[sr.Frame | None] = [None, None]
    rss_warm = rss_peak = 0.0
    start = time.perf_counter()
    for k in range(renders):
        which = k % 2
        renderer = renderers[which]
        scene = sr.Scene()
        for j in range(int(rng.integers(1, 4))):
            pose = np.eye(4)
            pose[:3, 3] = rng.normal(scale=0.5, size=3)
            scene.add(random_mesh(rng), pose=pose, instance_id=j)
        angle = 0.01 * k
        cam = sr.PerspectiveCamera(fov_y=float(rng.uniform(30, 70)), near=0.1, far=50.0)
        cam.look_at(eye=(3 * math.sin(angle), 0.5 * math.cos(3 * angle), 3 * math.cos(angle)),
                    target=(0.0, 0.0, 0.0))
        picked = rng.random(len(sr.OUTPUTS)) < 0.5
        outputs = tuple(n for n, p in zip(sr.OUTPUTS, picked) if p) or ("color",)
        prev = frames[which]
        if prev is not None and k % 4 == 0:  # in place: only the outputs prev holds are reused
            frames[which] = renderer.render(scene, cam, outputs=outputs, out=prev)
        else:
            frames[which] = renderer.render(scene, cam, outputs=outputs)
        if k + 1 == warmup:
            rss_warm = rss_bytes() / 2**20
        if k + 1 > warmup:
            rss_peak = max(rss_peak, rss_bytes() / 2**20)
        if report_every and (k + 1) % report_every == 0:
            print(f"render {k + 1:6d}  rss {rss_bytes() / 2**20:8.1f} MB  "
                  f"{time.perf_counter() - start:6.1f} s", file=out, flush=True)
    rss_end = rss_bytes() / 2**20
    return {"rss_warm_mb": rss_warm, "rss_end_mb": rss_end, "rss_peak_mb": max(rss_peak, rss_end),
            "seconds": time.perf_counter() - start}


def main() -> None:
    renders = int(sys.argv[1]) if len(sys.argv) > 1 else 10000
    r = run(renders, report_every=max(1, renders // 20))
    print(f"{renders} renders in {r['seconds']:.1f} s: RSS after warm-up {r['rss_warm_mb']:.1f} MB, "
          f"peak {r['rss_peak_mb']:.1f} MB, end {r['rss_end_mb']:.1f} MB, "
          f"growth {r['rss_end_mb'] - r['rss_warm_mb']:+.1f} MB")


if __name__ == "__main__":
    main()
