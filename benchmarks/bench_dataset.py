"""Dataset rendering rates: N views of Spot (assets/meshes/spot.obj, 640x480, colour
+ depth + instance_id, an orbit of cameras) as

  * a Python loop over Renderer.render (threads 2),
  * Renderer.render_many (the same renderer's two cores as two single-threaded views at a time),
  * pyrender's OffscreenRenderer in a loop (OSMesa / llvmpipe, as bench_vs_pyrender.py), with
    its depth and a segmentation pass for the instance ids, if pyrender is installed,

in interleaved rounds; frames per second, and ratios measured in the same run. Rendering only
(no files written).

    python3 benchmarks/bench_dataset.py [--views 200] [--rounds 3] [--no-pyrender] [--write | --codecs]

``--write`` times written datasets instead: render_many alone (nothing written), the file
encoders alone, ``write_dataset`` with the file store and with ``store="zarr"``, and a loop of
render + save, each cell's frames/s and its ratio to render_many. ``--codecs`` measures the
Blosc choices for the zarr store on real frames (20 views): encode and decode time, one thread,
and size per output, for LZ4 and Zstd at a few levels with no, byte and bit shuffle.
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
                    help="instead: written datasets (files, zarr) against render_many and the encoders")
    ap.add_argument("--codecs", action="store_true", help="instead: the zarr store's Blosc choices")
    ap.add_argument("--mesh", choices=("spot", "fuze"), default="spot",
                    help="Spot (untextured, the default) or pyrender's Fuze bottle (textured, MTL)")
    ap.add_argument("--dir", default=None,
                    help="--write: where the datasets go (default: a new folder in the system's "
                         "temporary directory)")
    args = ap.parse_args()

    if args.mesh == "spot":
        tm = trimesh.load(os.path.join(ROOT, "assets", "meshes", "spot.obj"), force="mesh", process=False)
        mesh = sr.Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals)
        scene = sr.Scene()
        scene.add(mesh, instance_id=1)
        radius = float(np.linalg.norm(tm.extents)) * 1.3
    else:
        path = os.path.join(ROOT, "assets", "meshes", "fuze", "fuze.obj")
        tm = trimesh.load(path, force="mesh")
        scene = sr.load_scene(path)
        radius = float(np.linalg.norm(tm.extents)) * 0.9
    centre = tm.bounds.mean(axis=0)
    poses = sr.orbit(centre, radius, args.views, elevation=20.0)
    cams = []
    for pose in poses:
        cam = sr.PerspectiveCamera(fov_y=45.0, width=W, height=H, near=0.05, far=100.0)
        cam.pose = pose
        cams.append(cam)
    r = sr.Renderer(W, H, threads=2)
    if args.write:
        return bench_write(scene, cams, r, args)
    if args.codecs:
        return bench_codecs(scene, cams, r)
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
    formats: colour PNG, depth float32 TIFF, ids PNG16 of id + 1, all by softrast's encoder; and
    store="zarr": Blosc LZ4 chunks) against render_many writing nothing, the file encoders alone
    (the same frames, pre-rendered, saved by one and by two threads) and a one-thread loop of
    render + save."""
    import concurrent.futures
    import shutil
    import tempfile

    pre = [r.render(scene, c, outputs=OUTPUTS) for c in cams[:20]]
    root = tempfile.mkdtemp(prefix="sr_bench_", dir=args.dir)

    def fresh(name):
        d = os.path.join(root, name)
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(d)
        return d

    def encoders(threads):
        def run():
            d = fresh(f"enc{threads}")
            with concurrent.futures.ThreadPoolExecutor(threads) as pool:
                list(pool.map(lambda k: pre[k % len(pre)].save(d, f"{k:06d}"), range(len(cams))))
        return run

    def dataset():
        sr.write_dataset(scene, cams, fresh("ds"), outputs=OUTPUTS, renderer=r, resume=False)

    def zarr_dataset():
        sr.write_dataset(scene, cams, fresh("zarr"), outputs=OUTPUTS, renderer=r, resume=False,
                         store="zarr")

    def many():
        for _ in r.render_many(scene, cams, outputs=OUTPUTS):
            pass

    def loop():
        d = fresh("loop")
        for k, c in enumerate(cams):
            r.render(scene, c, outputs=OUTPUTS).save(d, f"{k:06d}")

    cells = {"render_many (nothing written)": many,
             "encoders alone (1 thread, pre-rendered)": encoders(1),
             "encoders alone (2 threads, pre-rendered)": encoders(2), "write_dataset": dataset,
             "write_dataset(store='zarr')": zarr_dataset, "loop: render + save (1 thread)": loop}
    times = {k: [] for k in cells}
    sizes = {}
    try:
        for _ in range(args.rounds):
            for name, fn in cells.items():
                t = time.perf_counter()
                fn()
                times[name].append(time.perf_counter() - t)
        for name in ("ds", "zarr"):
            sizes[name] = sum(os.path.getsize(os.path.join(dp, f)) for dp, _, fs in
                              os.walk(os.path.join(root, name)) for f in fs)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    rate = {k: args.views / statistics.median(v) for k, v in times.items()}
    print(f"{args.views} views of {args.mesh} at {W}x{H}, {', '.join(OUTPUTS)}, default formats, "
          f"written to {os.path.dirname(root)}; median of {args.rounds} interleaved rounds; "
          f"{os.cpu_count()} cores")
    base = rate["render_many (nothing written)"]
    for name, fps in rate.items():
        print(f"{name:<44}{fps:>9.1f} frames/s{fps / base:>7.2f}x render_many")
    enc1, enc2 = rate["encoders alone (1 thread, pre-rendered)"], rate["encoders alone (2 threads, pre-rendered)"]
    print(f"encoders: 2 threads / 1 thread: {enc2 / enc1:.2f}; write_dataset / encoders alone "
          f"(2 threads): {rate['write_dataset'] / enc2:.2f}")
    print(f"bytes a view: files {sizes['ds'] / args.views / 1e3:.1f} kB, zarr "
          f"{sizes['zarr'] / args.views / 1e3:.1f} kB (raw {OUTPUT_BYTES * W * H / 1e3:.1f} kB)")


OUTPUT_BYTES = sum(row["bytes_per_pixel"] for row in sr.OUTPUT_TABLE if row["name"] in OUTPUTS)


def bench_codecs(scene, cams, r) -> None:
    """The zarr store's codec, measured: each Blosc setting on 20 real frames, encode and
    decode ms a frame in one (non-main) thread, as a writer thread runs them (blosc's context
    API, one internal thread), and compressed kB a frame, per output and in all."""
    import concurrent.futures

    from numcodecs import blosc

    frames = [r.render(scene, c, outputs=OUTPUTS) for c in cams[:20]]
    settings = [(c, lv, sh) for c, levels in (("lz4", (1, 5, 9)), ("zstd", (1, 3, 5)))
                for lv in levels for sh in (0, 1, 2)]

    def measure():
        rows = []
        for cname, level, shuffle in settings:
            row = {}
            for name in OUTPUTS:
                arrs = [np.ascontiguousarray(getattr(f, name)) for f in frames]
                enc, dec = [], []
                for _ in range(3):
                    t = time.perf_counter()
                    data = [blosc.compress(a, cname.encode(), level, shuffle, 0) for a in arrs]
                    enc.append((time.perf_counter() - t) / len(arrs))
                    t = time.perf_counter()
                    for d in data:
                        blosc.decompress(d)
                    dec.append((time.perf_counter() - t) / len(arrs))
                row[name] = (min(enc) * 1e3, min(dec) * 1e3, sum(map(len, data)) / len(data) / 1e3)
            rows.append(((cname, level, shuffle), row))
        return rows

    with concurrent.futures.ThreadPoolExecutor(1) as pool:  # not the main thread: as the writers
        rows = pool.submit(measure).result()
    raw = OUTPUT_BYTES * W * H / 1e3
    print(f"Blosc on 20 views of Spot at {W}x{H} ({raw:.0f} kB raw a frame); ms and kB a frame, "
          "best of 3, one thread")
    print(f"{'cname level shuffle':<22}{'enc ms':>8}{'dec ms':>8}{'kB':>8}{'ratio':>7}   " +
          "".join(f"{n + ' enc ms/kB':>22}" for n in OUTPUTS))
    for (cname, level, shuffle), row in rows:
        e, d, kb = (sum(v[i] for v in row.values()) for i in range(3))
        print(f"{cname} {level} {('none', 'byte', 'bit')[shuffle]:<13}{e:8.2f}{d:8.2f}{kb:8.1f}"
              f"{raw / kb:7.1f}   " + "".join(f"{row[n][0]:>13.2f} /{row[n][2]:>6.1f}" for n in OUTPUTS))


if __name__ == "__main__":
    main()
