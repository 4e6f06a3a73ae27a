"""DatasetJob / render_dataset: a job's shards (mesh x camera runs) on any
concurrent.futures executor give the same files, byte for byte, as the local run: a process
pool and a two-worker dask.distributed LocalCluster; with store="zarr" too, every
chunk file of the arrays the job makes before its shards run."""
from __future__ import annotations

import concurrent.futures
import multiprocessing
import pathlib
import pickle

import distributed
import pytest
import trimesh
import zarr

import softrast as sr

ASSETS = pathlib.Path(__file__).resolve().parents[1] / "assets" / "meshes"


def _job(out_dir, store="files", **kw):
    cams = []
    for pose in sr.orbit((0.0, 0.2, 0.0), 3.0, 7, elevation=15.0):
        cam = sr.PerspectiveCamera(fov_y=45.0, width=48, height=36, near=0.05, far=20.0)
        cam.pose = pose
        cams.append(cam)
    ball = pathlib.Path(out_dir).parent / "ball.ply"
    if not ball.exists():
        trimesh.creation.icosphere(subdivisions=3).export(ball)
    meshes = [ASSETS / "spot.obj", ball]
    return sr.DatasetJob(meshes, cams, outputs=("color", "depth", "instance_id", "uv"), out_dir=out_dir,
                         formats={"depth": "npy"} if store == "files" else None, shard_size=3,
                         store=store, **kw)


def _tree(d: pathlib.Path) -> dict[str, bytes]:
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def test_process_pool_equals_local_run(tmp_path):
    local = sr.render_dataset(_job(tmp_path / "local"))
    assert [len(v) for v in local] == [7, 7]
    job = _job(tmp_path / "pool")
    assert pickle.loads(pickle.dumps(job)).shards() == job.shards()
    with concurrent.futures.ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as ex:
        sr.render_dataset(job, ex)
    a, b = _tree(tmp_path / "local"), _tree(tmp_path / "pool")
    assert a == b and len(a) > 7 * 4
    assert len(sr.load_cameras(tmp_path / "pool" / "spot")) == 7


def test_dask_local_cluster_equals_local_run(tmp_path):
    sr.render_dataset(_job(tmp_path / "local"))
    sr.render_dataset(_job(tmp_path / "local_zarr", store="zarr"))
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address="127.0.0.1:0") as cluster, distributed.Client(cluster) as client:
        paths = sr.render_dataset(_job(tmp_path / "dask"), client.get_executor())
        zarr_paths = sr.render_dataset(_job(tmp_path / "dask_zarr", store="zarr"), client.get_executor())
    assert _tree(tmp_path / "local") == _tree(tmp_path / "dask")
    assert all(p.startswith(str(tmp_path / "dask")) for per in paths for view in per for p in view.values())
    local, dask = _tree(tmp_path / "local_zarr"), _tree(tmp_path / "dask_zarr")
    chunks = [n for n in local if n.split("/")[-1][0].isdigit()]
    assert len(chunks) == 2 * 7 * 4 and local == dask  # every chunk file, metadata, cameras.json
    assert zarr_paths[1][5]["uv"] == str(tmp_path / "dask_zarr" / "ball" / "views.zarr/uv[5]")
    views = zarr.open_group(str(tmp_path / "dask_zarr" / "spot" / "views.zarr"), mode="r")
    assert views["depth"].shape == (7, 36, 48) and (views["depth"][:] > 0).any()


def test_job_checks_its_arguments(tmp_path):
    with pytest.raises(ValueError, match="at least one mesh"):
        sr.DatasetJob([], [sr.PerspectiveCamera(width=8, height=8)])
    with pytest.raises(ValueError, match="shard_size"):
        sr.DatasetJob([ASSETS / "spot.obj"], [sr.PerspectiveCamera(width=8, height=8)], shard_size=0)
    with pytest.raises(ValueError, match="same name"):
        sr.DatasetJob([ASSETS / "spot.obj", tmp_path / "spot.obj"], [sr.PerspectiveCamera(width=8, height=8)])
