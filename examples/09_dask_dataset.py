"""A dataset job on a Dask cluster: every mesh from every camera, cut into shards (one mesh x a
run of cameras) that run on any concurrent.futures executor -- here a local two-worker
dask.distributed cluster; point the Client at a real scheduler for many machines. The files are
the same, byte for byte, as a local run (sr.render_dataset(job) without an executor)."""
import sys
from pathlib import Path

import softrast as sr

root = Path(__file__).resolve().parent.parent
out = Path(sys.argv[1] if len(sys.argv) > 1 else "out") / "09_dask_dataset"

if __name__ == "__main__":  # (Dask's worker processes import this file: keep the work here)
    from distributed import Client, LocalCluster

    cameras = []
    for pose in sr.orbit(target=(0.0, 0.1, 0.2), radius=3.0, n=12, elevation=20.0):
        camera = sr.PerspectiveCamera(fov_y=40.0, width=256, height=256, near=0.05, far=20.0)
        camera.pose = pose
        cameras.append(camera)
    job = sr.DatasetJob([root / "assets" / "meshes" / "spot.obj"], cameras,
                        outputs=("color", "depth", "instance_id"), out_dir=out, shard_size=4)
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address="127.0.0.1:0") as cluster, \
            Client(cluster) as client:
        paths = sr.render_dataset(job, client.get_executor())
    print(f"wrote {sum(len(p) for p in paths)} views with cameras.json to {out}")
