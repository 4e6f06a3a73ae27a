"""`softrast batch`: datasets from mesh files, with progress and a summary, every bad
argument a one-line error before anything is written, resume after an interruption, --version."""
from __future__ import annotations

import json
import os
import pathlib
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import softrast as sr
from softrast.cli import main

SPOT = pathlib.Path(__file__).resolve().parents[1] / "assets" / "meshes" / "spot.obj"


def _files(d: pathlib.Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir()) if p.is_file()}


def test_batch_writes_a_dataset(tmp_path, capsys):
    assert main(["batch", str(SPOT), "--out", str(tmp_path), "--views", "5", "--size", "64x48",
                 "--outputs", "color,depth,instance_id,uv", "--formats", "depth=npy"]) == 0
    out = capsys.readouterr()
    assert "softrast batch: rendered 5 views of 1 mesh(es) in " in out.out and "5/5" in out.err
    assert "skipped" not in out.out
    d = tmp_path / "spot"
    names = sorted(os.listdir(d))
    assert "cameras.json" in names and "000004_depth.npy" in names and "000004_uv.tif" in names
    cams = sr.load_cameras(d)
    assert len(cams) == 5 and (cams[0].width, cams[0].height) == (64, 48)
    # each view is what render gives for its camera
    scene = sr.Scene()
    scene.add(sr.load_mesh(SPOT), instance_id=0)
    doc = json.loads((d / "cameras.json").read_text())
    for k in (0, 3):
        cam = sr.PerspectiveCamera(fov_y=45.0, width=64, height=48, near=doc["frames"][k]["near"],
                                   far=doc["frames"][k]["far"])
        cam.pose = np.asarray(doc["frames"][k]["pose_opengl"])
        ref = sr.Renderer(64, 48).render(scene, cam, outputs=("color", "depth", "instance_id"))
        back = sr.Frame.load(d, f"{k:06d}")
        np.testing.assert_array_equal(back.color, ref.color)
        np.testing.assert_array_equal(back.depth, ref.depth)
        np.testing.assert_array_equal(back.instance_id, ref.instance_id)


def test_batch_poses_intrinsics_and_sphere(tmp_path):
    poses = sr.sphere_poses((0.0, 0.3, 0.0), 3.0, 4)
    np.save(tmp_path / "poses.npy", poses)
    np.save(tmp_path / "K.npy", np.array([[60.0, 0, 31.5], [0, 60.0, 23.5], [0, 0, 1]]))
    assert main(["batch", str(SPOT), "--out", str(tmp_path / "a"), "--poses", str(tmp_path / "poses.npy"),
                 "--intrinsics", str(tmp_path / "K.npy"), "--size", "64x48", "--outputs", "mask"]) == 0
    cams = sr.load_cameras(tmp_path / "a" / "spot")
    assert len(cams) == 4
    np.testing.assert_allclose(cams[2].K, np.load(tmp_path / "K.npy"), atol=1e-12)
    np.testing.assert_allclose(np.linalg.inv(cams[2].view_matrix()), poses[2], atol=1e-12)
    assert main(["batch", str(SPOT), "--out", str(tmp_path / "b"), "--sphere", "--views", "3",
                 "--size", "32x24", "--outputs", "mask"]) == 0
    assert len(sr.load_cameras(tmp_path / "b" / "spot")) == 3


@pytest.mark.parametrize("extra, match", [
    (["--views", "0"], "--views"),
    (["--outputs", "colour"], "unknown output 'colour'"),
    (["--formats", "depth=png"], "depth=png"),
    (["--formats", "normal=exr"], "normal is not in --outputs"),
    (["--orbit", "95"], "--orbit"),
    (["--orbit", "10", "--sphere"], "not allowed with"),
    (["--size", "0x10"], "--size"),
    (["--fov", "0"], "--fov"),
    (["--poses", "missing.npy"], "--poses"),
    (["--intrinsics", "K_missing.npy"], "--intrinsics"),
])
def test_bad_arguments_are_one_line_and_write_nothing(tmp_path, capsys, extra, match):
    out = tmp_path / "ds"
    assert main(["batch", str(SPOT), "--out", str(out)] + extra) == 2
    err = capsys.readouterr().err
    assert err.startswith("softrast: error:") and err.count("\n") == 1 and match in err, err
    assert not out.exists()


def test_missing_mesh_and_version(tmp_path, capsys):
    assert main(["batch", str(tmp_path / "nope.obj"), "--out", str(tmp_path / "ds")]) == 2
    assert "mesh file not found" in capsys.readouterr().err and not (tmp_path / "ds").exists()
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"softrast {sr.__version__}"
    assert main(["batch", "--help"]) == 0
    help_text = capsys.readouterr().out
    for option in ("--views", "--orbit", "--sphere", "--poses", "--intrinsics", "--outputs", "--formats",
                   "--workers", "--no-resume", "--store"):
        assert option in help_text


class _FakeClock:
    """A perf_counter that advances one second a call: the summary's arithmetic is checked
    against it, so no test depends on how long anything takes."""

    def __init__(self) -> None:
        self.t = 0.0

    def perf_counter(self) -> float:
        self.t += 1.0
        return self.t


def test_a_resumed_run_counts_skipped_views_apart(tmp_path, capsys, monkeypatch):
    """A rerun that finds 3 of 5 views on disk says it rendered 2 and skipped 3,
    and its rate is over the 2 rendered views only (it used to claim 5 views at 5 / time)."""
    import softrast.cli as cli
    import softrast.dataset as dataset

    args = ["batch", str(SPOT), "--out", str(tmp_path), "--views", "5", "--size", "32x24",
            "--outputs", "color,depth"]
    assert main(args) == 0
    capsys.readouterr()
    d = tmp_path / "spot"
    for k in (1, 3):
        os.remove(d / f"{k:06d}_depth.tif")  # as if interrupted: views 1 and 3 are incomplete
    clock = _FakeClock()  # calls: the run's start, write_dataset's start and end, the run's end
    monkeypatch.setattr(cli, "time", clock, raising=False)
    monkeypatch.setattr(dataset, "time", clock, raising=False)
    assert main(args) == 0
    out = capsys.readouterr()
    # rendering the 2 views took 1 (fake) second, the run 3: 2.0 frames/s, not 5 / 3 = 1.7
    assert out.out.strip() == (f"softrast batch: rendered 2 views of 1 mesh(es) in 1.0 s (2.0 frames/s), "
                               f"skipped 3 already on disk; 3.0 s in all -> {tmp_path}")
    assert "5/5" in out.err and "skipped 3" in out.err  # the bar starts at the skipped views
    assert (d / "000001_depth.tif").exists() and (d / "000003_depth.tif").exists()
    # nothing left to do: nothing rendered, no rate
    assert main(args) == 0
    out = capsys.readouterr().out.strip()
    assert out.startswith("softrast batch: rendered 0 views of 1 mesh(es), skipped 5 already on disk; ")
    assert "frames/s" not in out


def test_batch_summary_wording():
    from softrast.cli import batch_summary

    assert batch_summary(3, 7, 1, 1.2, 1.5, "ds") == (
        "softrast batch: rendered 3 views of 1 mesh(es) in 1.2 s (2.5 frames/s), skipped 7 already "
        "on disk; 1.5 s in all -> ds")
    assert batch_summary(1, 0, 2, 0.5, 0.6, "ds") == (
        "softrast batch: rendered 1 view of 2 mesh(es) in 0.5 s (2.0 frames/s); 0.6 s in all -> ds")


def test_resume_after_an_interruption_gives_the_clean_result(tmp_path):
    """Interrupted (SIGINT) mid-run, resumed and killed (SIGKILL), then rerun: the same files,
    byte for byte, as one clean run, and no temporary left behind."""
    args = [sys.executable, "-m", "softrast", "batch", str(SPOT), "--views", "400", "--size", "96x72",
            "--workers", "1"]
    clean = subprocess.run(args + ["--out", str(tmp_path / "clean")], capture_output=True, text=True,
                           timeout=300)
    assert clean.returncode == 0, clean.stderr
    d = tmp_path / "cut" / "spot"
    proc = subprocess.Popen(args + ["--out", str(tmp_path / "cut")], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while time.time() < deadline and not (d.exists() and len(os.listdir(d)) > 30):
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and "interrupted" in err, (proc.returncode, err[-500:])
    assert not (d / "cameras.json").exists()
    assert not [n for n in os.listdir(d) if n.startswith(".")]  # no temporaries
    done = len(os.listdir(d))
    assert 30 < done < 3 * 400
    # resumed, then killed outright (SIGKILL: no handler runs; a write may be cut mid-file)
    proc = subprocess.Popen(args + ["--out", str(tmp_path / "cut")], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and len(os.listdir(d)) < done + 30:
        time.sleep(0.01)
    proc.kill()
    proc.wait(timeout=60)
    assert not (d / "cameras.json").exists()
    rerun = subprocess.run(args + ["--out", str(tmp_path / "cut")], capture_output=True, text=True,
                           timeout=300)
    assert rerun.returncode == 0, rerun.stderr
    assert not [n for n in os.listdir(d) if n.startswith(".")]  # the killed run's temporaries went
    assert _files(d) == _files(tmp_path / "clean" / "spot")


@pytest.fixture
def budget():
    """Restores the memory budget that a test lowers."""
    before = sr.get_memory_budget()
    yield sr.set_memory_budget
    sr.set_memory_budget(before)


def _bad_inputs(d: pathlib.Path) -> dict[str, list[str]]:
    scaled = np.diag([2.0, 2.0, 2.0, 1.0])[None]
    last_row = np.eye(4)
    last_row[3] = (0.0, 0.0, 1.0, 1.0)
    files = {"scaled.npy": scaled, "last_row.npy": last_row[None], "no_poses.npy": np.zeros((0, 4, 4)),
             "K_negative.npy": np.array([[-60.0, 0, 31.5], [0, 60.0, 23.5], [0, 0, 1]]),
             "K_zero.npy": np.array([[0.0, 0, 31.5], [0, 60.0, 23.5], [0, 0, 1]]),
             "K_not_K.npy": np.array([[60.0, 0, 31.5], [0, 60.0, 23.5], [0, 0, 2]]),
             "K_skew.npy": np.array([[60.0, 0.5, 31.5], [0, 60.0, 23.5], [0, 0, 1]])}
    for name, arr in files.items():
        np.save(d / name, arr)
    return {name: [("--poses" if name[0] != "K" else "--intrinsics"), str(d / name)] for name in files}


@pytest.mark.parametrize("extra, match", [
    (["--size", "20000x10"], "--size"),
    (["--size", "10x16385"], "--size"),
    (["--workers", "1000"], "--workers"),
    ("scaled.npy", "--poses"),
    ("last_row.npy", "--poses"),
    ("no_poses.npy", "--poses"),
    ("K_negative.npy", "--intrinsics"),
    ("K_zero.npy", "--intrinsics"),
    ("K_not_K.npy", "--intrinsics"),
    ("K_skew.npy", "--intrinsics"),
])
def test_bad_sizes_workers_poses_and_K_write_nothing(tmp_path, capsys, extra, match):
    """These were found after the output folder (and the mesh's) was created."""
    if isinstance(extra, str):
        extra = _bad_inputs(tmp_path)[extra]
    out = tmp_path / "ds"
    assert main(["batch", str(SPOT), "--out", str(out), "--views", "2", "--size", "32x24"] + extra) == 2
    err = capsys.readouterr().err
    assert err.startswith("softrast: error:") and err.count("\n") == 1 and match in err, err
    assert not out.exists()


def test_frames_over_the_memory_budget_write_nothing(tmp_path, capsys, budget):
    budget(2**20)  # 1 MiB: one 640x480 colour + depth + instance_id frame is 3.4 MB
    out = tmp_path / "ds"
    assert main(["batch", str(SPOT), "--out", str(out), "--views", "2", "--size", "640x480"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("softrast: error: --size 640x480") and "memory budget" in err, err
    assert not out.exists()


def test_a_corrupt_second_mesh_is_reported_before_anything_is_written(tmp_path, capsys):
    bad = tmp_path / "broken.ply"
    bad.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1 2\n")
    empty = tmp_path / "empty.obj"
    empty.write_text("# no faces\nv 0 0 0\n")
    for second in (bad, empty):
        out = tmp_path / "ds"
        assert main(["batch", str(SPOT), str(second), "--out", str(out), "--views", "2",
                     "--size", "32x24"]) == 2
        err = capsys.readouterr().err
        assert err.startswith("softrast: error:") and err.count("\n") == 1 and second.name in err, err
        assert not out.exists()  # spot's views were written first, before


@pytest.mark.parametrize("budget_bytes, views, said", [
    (16 * 2**20, 5000, "memory budget"),
    (4 * 2**30, 524289, "524288 views a run"),  # README: 524,288 views at the default 4 GiB
])
def test_more_views_than_memory_allows_fail_before_writing(tmp_path, capsys, budget, budget_bytes,
                                                           views, said):
    budget(budget_bytes)  # about 8 KB a view
    out = tmp_path / "ds"
    assert main(["batch", str(SPOT), "--out", str(out), "--views", str(views), "--size", "8x8",
                 "--outputs", "mask", "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"softrast: error: --views {views}") and said in err, err
    assert not out.exists()


def test_more_poses_than_memory_allows_fail_before_writing(tmp_path, capsys, budget):
    np.save(tmp_path / "poses.npy", np.broadcast_to(np.eye(4), (3000, 4, 4)))
    budget(16 * 2**20)
    out = tmp_path / "ds"
    assert main(["batch", str(SPOT), "--out", str(out), "--poses", str(tmp_path / "poses.npy"),
                 "--size", "8x8", "--outputs", "mask", "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("softrast: error: --poses: 3000 views") and "memory budget" in err, err
    assert not out.exists()


def test_a_billion_views_fail_fast_naming_views(tmp_path):
    """`--views 1000000000` grew to 24 GB before the kernel killed it: now refused before any
    camera is made (the child's address space is capped so the old behaviour fails, not swaps)."""
    import resource

    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (3 * 2**30, 3 * 2**30))

    # Under AddressSanitizer (.ci/sanitize sets SOFTRAST_ASAN) the shadow memory cannot be mapped
    # inside an address-space cap: ASan's own RSS limit caps the child instead.
    env = dict(os.environ)
    asan = bool(env.get("SOFTRAST_ASAN"))
    if asan:
        env["ASAN_OPTIONS"] = env.get("ASAN_OPTIONS", "") + ":hard_rss_limit_mb=3072"
    out = tmp_path / "ds"
    proc = subprocess.run([sys.executable, "-m", "softrast", "batch", str(SPOT), "--out", str(out),
                           "--views", "1000000000", "--workers", "1"], capture_output=True, text=True,
                          timeout=120, preexec_fn=None if asan else cap, env=env)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert proc.stderr.startswith("softrast: error: --views 1000000000"), proc.stderr[-2000:]
    assert proc.stderr.count("\n") == 1 and "memory budget" in proc.stderr
    assert not out.exists()
