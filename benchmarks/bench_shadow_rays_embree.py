"""Shadow rays: softrast's exact method against Intel Embree on the same rays, one thread.

    pip install embreex   # Embree 4 for Python (trimesh's optional ray backend), not a dependency
    python3 benchmarks/bench_shadow_rays_embree.py

The scenes of bench_shadows.py under its directional light (Spot on a floor, 5,858 triangles,
and Spot subdivided twice, 93,698), 1024x1024. The rays: one from every covered pixel's
``position`` toward the light. Embree (embreex's ``EmbreeScene.run(query="OCCLUDED")``, one call,
single rays, float32, each origin pushed 1e-4 along the ray: Embree has no on-surface rule)
against softrast's frame with exact shadows minus its frame without, on one thread, as rays per
second (softrast's an upper bound: it casts rays only from pixels facing the light). The shadow
goals name Embree the reference for CPU ray queries; this is that comparison (RESULTS.md,
"Shadows").
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

import softrast as sr

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_shadows import SUN, floor_arrays, scene_of, spot_arrays  # noqa: E402


def main() -> None:
    try:
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh
    except ImportError:
        sys.exit("needs embreex (pip install embreex)")
    w = h = 1024
    print(f"{'triangles':>9} {'rays':>8} {'embree ms':>10} {'Mrays/s':>8} {'softrast ms':>12} {'Mrays/s':>8} "
          f"{'blocked':>8}")
    for sub in (0, 2):
        scene, cam = scene_of("directional", sub)
        r = sr.Renderer(w, h, threads=1)
        f = r.render(scene, cam, outputs=("position", "mask"), shadows=False)
        p = f.position[f.mask].astype(np.float64)
        v, fa = spot_arrays(sub)
        fv, ff = floor_arrays(float(v[:, 1].min()))
        verts, faces = np.concatenate([v, fv]), np.concatenate([fa, ff + len(v)])
        es = rtcs.EmbreeScene()
        TriangleMesh(es, verts[faces].astype(np.float32))
        d = sr.look_at_pose(*SUN)[:3, 2]  # toward the light (a light shines along its -z)
        origins = (p + 1e-4 * d).astype(np.float32)
        dirs = np.tile(d.astype(np.float32), (len(p), 1))
        es.run(origins[:1000], dirs[:1000], query="OCCLUDED")  # (warm up)
        embree = []
        for _ in range(3):
            t = time.perf_counter()
            occluded = es.run(origins, dirs, query="OCCLUDED")
            embree.append(time.perf_counter() - t)
        blocked = float(np.mean(np.asarray(occluded) != -1))
        times = {}
        for method in (False, "exact"):
            rr = sr.Renderer(w, h, threads=1)
            rr.render(scene, cam, outputs=("color", "depth"), shadows=method)
            runs = []
            for _ in range(3):
                t = time.perf_counter()
                rr.render(scene, cam, outputs=("color", "depth"), shadows=method)
                runs.append(time.perf_counter() - t)
            times[method] = min(runs)
        te, ts = min(embree), times["exact"] - times[False]
        print(f"{len(faces):9d} {len(p):8d} {te * 1e3:10.1f} {len(p) / te / 1e6:8.1f} {ts * 1e3:12.1f} "
              f"{len(p) / ts / 1e6:8.1f} {blocked:8.1%}")


if __name__ == "__main__":
    main()
