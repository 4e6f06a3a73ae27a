"""Dataset rendering rates (issue 22): N views of Spot (assets/meshes/spot.obj, 640x480, colour
+ depth + instance_id, an orbit of cameras) as

  * a Python loop over Renderer.render (threads 2),
  * Renderer.render_many (the same renderer's two cores as two single-threaded views at a time),
  * pyrender's OffscreenRenderer in a loop (OSMesa / llvmpipe, as bench_vs_pyrender.py), with
    its depth and a segmentation pass for the instance ids, if pyrender is installed,

in interleaved rounds; frames per second, and ratios measured in the same run. Rendering only
(no files written).

    python3 benchmarks/bench_dataset.py [--views 200] [--rounds 3] [--no-pyrender] [--write]

``--write`` times written datasets instead: ``write_dataset`` against the encoders alone.
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time

os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")
import numpy as np  # noqa: E402
import trimesh  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "python"))
import softrast as sr  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
W, H = 640, 480
OUTPUTS = ("color", "depth", "instance_id")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--views", type=int, default=200)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--no-pyrender", action="store_true")
    ap.add_argument("--write", action="store_true",
                    help="instead: written datasets (default formats) against the encoders alone")
    args = ap.parse_args()

    tm = trimesh.load(os.path.join(ROOT, "assets", "meshes", "spot.obj"), force="mesh", process=False)
    mesh = sr.Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals)
    scene = sr.Scene()
    scene.add(mesh, instance_id=1)
    centre = tm.bounds.mean(axis=0)
    radius = float(np.linalg.norm(tm.extents)) * 1.3
    poses = sr.orbit(centre, radius, args.views, elevation=20.0)
    cams = []
    for pose in poses:
        cam = sr.PerspectiveCamera(fov_y=45.0, width=W, height=H, near=0.05, far=100.0)
        cam.pose = pose
        cams.append(cam)
    r = sr.Renderer(W, H, threads=2)
    if args.write:
        return bench_write(scene, cams, r, args)
    for cam in cams[:5]:
        r.render(scene, cam, outputs=OUTPUTS)
    list(r.render_many(scene, cams[:5], outputs=OUTPUTS))

    def loop():
        for cam in cams:
            r.render(scene, cam, outputs=OUTPUTS)

    def many():
        for _ in r.render_many(scene, cams, outputs=OUTPUTS):
            pass

    cells = {"softrast loop (t2)": loop, "softrast render_many": many}
    if not args.no_pyrender:
        try:
            import pyrender
        except ImportError:
            pyrender = None
        if pyrender is not None:
            pm = pyrender.Mesh.from_trimesh(tm)
            pscene = pyrender.Scene()
            node = pscene.add(pm)
            cam_node = pscene.add(pyrender.PerspectiveCamera(yfov=math.radians(45.0), aspectRatio=W / H,
                                                             znear=0.05, zfar=100.0), pose=poses[0])
            pscene.add(pyrender.DirectionalLight(intensity=3.0), parent_node=cam_node)
            pr = pyrender.OffscreenRenderer(W, H)
            seg = {node: (1, 1, 1)}

            def pyrender_loop():
                for pose in poses:
                    pscene.set_pose(cam_node, pose)
                    pr.render(pscene)  # colour + depth
                    pr.render(pscene, flags=pyrender.RenderFlags.SEG, seg_node_map=seg)  # ids
            pyrender_loop()
            cells["pyrender loop (colour+depth, + SEG pass)"] = pyrender_loop
    times = {k: [] for k in cells}
    for _ in range(args.rounds):
        for name, fn in cells.items():
            t = time.perf_counter()
            fn()
            times[name].append(time.perf_counter() - t)
    print(f"softrast {sr.__version__}, {os.cpu_count()} cores; {args.views} views of Spot at {W}x{H}, "
          f"{', '.join(OUTPUTS)}; median of {args.rounds} interleaved rounds")
    rate = {k: args.views / statistics.median(v) for k, v in times.items()}
    base = rate["softrast loop (t2)"]
    for name, fps in rate.items():
        print(f"{name:<44}{fps:>9.1f} frames/s{fps / base:>8.2f}x the loop")
    if len(rate) > 2:
        print(f"render_many / pyrender loop: {rate['softrast render_many'] / list(rate.values())[2]:.1f}x")


def bench_write(scene, cams, r, args) -> None:
    """Frames/s of a written dataset (write_dataset: render_many + two writer threads, default
    formats: colour PNG level 1, depth EXR zip, ids PNG16) against the same encoders alone (the
    same frames, pre-rendered, saved by two threads) and a one-thread loop of render + save."""
    import concurrent.futures
    import shutil
    import tempfile

    pre = [r.render(scene, c, outputs=OUTPUTS) for c in cams[:20]]
    root = tempfile.mkdtemp(prefix="sr_bench_")

    def fresh(name):
        d = os.path.join(root, name)
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(d)
        return d

    def encoders():
        d = fresh("enc")
        with concurrent.futures.ThreadPoolExecutor(2) as pool:
            list(pool.map(lambda k: pre[k % len(pre)].save(d, f"{k:06d}"), range(len(cams))))

    def dataset():
        sr.write_dataset(scene, cams, fresh("ds"), outputs=OUTPUTS, renderer=r, resume=False)

    def loop():
        d = fresh("loop")
        for k, c in enumerate(cams):
            r.render(scene, c, outputs=OUTPUTS).save(d, f"{k:06d}")

    cells = {"encoders alone (2 threads, pre-rendered)": encoders, "write_dataset": dataset,
             "loop: render + save (1 thread)": loop}
    times = {k: [] for k in cells}
    try:
        for _ in range(args.rounds):
            for name, fn in cells.items():
                t = time.perf_counter()
                fn()
                times[name].append(time.perf_counter() - t)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    rate = {k: args.views / statistics.median(v) for k, v in times.items()}
    print(f"{args.views} views of Spot at {W}x{H}, {', '.join(OUTPUTS)}, default formats, written to "
          f"/tmp; median of {args.rounds} interleaved rounds")
    for name, fps in rate.items():
        print(f"{name:<44}{fps:>9.1f} frames/s")
    print(f"write_dataset / encoders alone: {rate['write_dataset'] / rate['encoders alone (2 threads, pre-rendered)']:.2f}")


if __name__ == "__main__":
    main()
