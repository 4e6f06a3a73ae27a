"""Python threads: the GIL is released while rendering, concurrent renders give the same bytes."""
from __future__ import annotations

import threading
import time
import weakref

import numpy as np
import pytest
import trimesh

import softrast as sr
from support.gil_probe import calls_that_let_python_run
from softrast import _core
from conftest import core_options, nv_clip_scene
from softrast.nv._raster import _rasterize_clip

OUTPUTS = ("color", "depth", "normal", "triangle_id", "coverage")


def _scene(k: int) -> tuple[sr.Scene, sr.PerspectiveCamera]:
    scene = sr.Scene()
    scene.add(sr.Mesh.from_trimesh(trimesh.creation.icosphere(subdivisions=2 + k % 3)),
              color=(0.2 + 0.1 * k, 0.5, 0.7))
    cam = sr.PerspectiveCamera(fov_y=40.0 + 3 * k)
    cam.look_at(eye=(0.5 * np.sin(k), 0.3 * k - 1.0, 3.0), target=(0.0, 0.0, 0.0))
    return scene, cam


def _run_in_threads(work, count: int) -> None:
    """Runs work(0) .. work(count - 1) in as many threads at once and waits for them all."""
    threads = [threading.Thread(target=work, args=(i,)) for i in range(count)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()


def test_concurrent_renders_match_sequential():
    jobs = [_scene(k) for k in range(8)]
    expected = [sr.Renderer(96, 80, threads=1).render(s, c, outputs=OUTPUTS).as_dict() for s, c in jobs]
    results: list[dict | None] = [None] * len(jobs)

    def work(i: int) -> None:
        s, c = jobs[i]
        renderer = sr.Renderer(96, 80, threads=2)
        for _ in range(5):
            results[i] = renderer.render(s, c, outputs=OUTPUTS).as_dict()

    _run_in_threads(work, len(jobs))
    for want, got in zip(expected, results):
        assert got is not None
        for name in OUTPUTS:
            np.testing.assert_array_equal(got[name], want[name])


def test_one_renderer_shared_by_threads_serialises_calls():
    jobs = [_scene(k) for k in range(4)]
    renderer = sr.Renderer(64, 64)
    expected = [renderer.render(s, c, outputs=("depth",)).depth for s, c in jobs]
    errors: list[str] = []

    def work(i: int) -> None:
        s, c = jobs[i]
        for _ in range(10):
            if not np.array_equal(renderer.render(s, c, outputs=("depth",)).depth, expected[i]):
                errors.append(f"job {i} differs")

    _run_in_threads(work, len(jobs))
    assert errors == []


def test_gil_is_released_while_rendering():
    # Another Python thread counts while this one is inside the C++ render. With a switch interval
    # far longer than the call, the interpreter never takes the GIL from this thread between
    # reading the count and the end of the call: the count can move only if the render itself
    # released the GIL. Repeated because on a loaded machine the counting thread may not be
    # scheduled during a given render; observed by the count, not by a clock.
    scene = sr.Scene()
    scene.add(sr.Mesh.from_trimesh(trimesh.creation.icosphere(subdivisions=5)))
    cam = sr.PerspectiveCamera(fov_y=30.0)
    cam.look_at(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0))
    renderer = sr.Renderer(512, 512, threads=1)
    # The core's call directly: the Python wrapper around it could release the GIL itself.
    draws = [_core.Draw(mesh=inst.mesh._core_data(), pose=inst.pose, color=inst.color)
             for inst in scene]
    spec = core_options(cam.view_matrix(), cam.projection_matrix(512, 512), False, cam.near,
                        cam.far, ["color", "depth", "normal"])  # no lights: the headlight
    progressed = calls_that_let_python_run(lambda: renderer._core.render(draws, spec))
    assert progressed >= 3, progressed


def test_nv_rasterize_clip_same_bits_for_any_thread_count_and_releases_the_gil(rng):
    # softrast.nv's entry point: the same bytes on 1, 2 and 3 threads, from several Python threads
    # at once (each call its own pool while another holds the kept one), and without the GIL.
    pos, tri = nv_clip_scene(rng)
    ranges = np.array([[0, len(tri)]] * 2)
    expected = _rasterize_clip(pos, tri, ranges, 200, 170, True, threads=1)
    for threads in (2, 3, 0):
        got = _rasterize_clip(pos, tri, ranges, 200, 170, True, threads=threads)
        assert all(g.tobytes() == e.tobytes() for g, e in zip(got, expected)), threads
    mismatches: list[int] = []

    def work(i: int) -> None:
        for _ in range(5):
            got = _rasterize_clip(pos, tri, ranges, 200, 170, True, threads=1 + i % 3)
            if not all(g.tobytes() == e.tobytes() for g, e in zip(got, expected)):
                mismatches.append(i)

    _run_in_threads(work, 4)
    assert mismatches == []
    rast = np.empty((2, 512, 512, 4), np.float32)
    args = (pos, tri, ranges.astype(np.int64), 512, 512, rast, None, 1, True)
    assert calls_that_let_python_run(lambda: _core._rasterize_clip(*args)) >= 3


def test_eight_threads_eight_scenes_mixed_outputs_match_one_by_one():
    # Different scenes, sizes, outputs and thread counts at once, 20 rounds: every buffer must
    # equal the one-by-one render byte for byte (no shared state between renderers).
    rng = np.random.default_rng(8)
    jobs = []
    for k in range(8):
        scene, cam = _scene(k)
        outputs = tuple(n for n in sr.OUTPUTS if rng.random() < 0.5) or ("instance_id",)
        size = (64 + 16 * k, 48 + 8 * k)
        jobs.append((scene, cam, outputs, size, k % 3))
    expected = [sr.Renderer(*size, threads=1).render(s, c, outputs=o).as_dict()
                for s, c, o, size, _ in jobs]
    barrier = threading.Barrier(len(jobs))
    mismatches: list[str] = []

    def work(i: int) -> None:
        scene, cam, outputs, size, threads = jobs[i]
        renderer = sr.Renderer(*size, threads=threads)
        for rnd in range(20):
            barrier.wait()  # all eight renders start together
            got = renderer.render(scene, cam, outputs=outputs).as_dict()
            for name, want in expected[i].items():
                if got[name].tobytes() != want.tobytes():
                    mismatches.append(f"scene {i} round {rnd} {name}")

    _run_in_threads(work, len(jobs))
    assert mismatches == []
    assert len({name for job in jobs for name in job[2]}) >= 5  # the outputs really are mixed


def test_core_mesh_dropped_by_python_while_a_render_reads_it():
    # The core views a mesh's arrays without copying them. Here Python drops every reference to
    # a core mesh (and so to its arrays) while a render in another thread, GIL released, still
    # reads it: the render's own reference must keep the arrays alive (ASan checks the reads).
    tm = trimesh.creation.icosphere(subdivisions=7)  # ~50 ms per render

    def immutable(values, dtype):
        a = np.ascontiguousarray(values, dtype)
        return np.frombuffer(a.tobytes(), dtype).reshape(a.shape)

    def draws():
        data = _core.MeshData(immutable(tm.vertices, np.float32), immutable(tm.faces, np.int32),
                              immutable(tm.vertex_normals, np.float32))
        return [_core.Draw(mesh=data, color=(1.0, 1.0, 1.0, 1.0))]

    cam = sr.PerspectiveCamera(fov_y=45.0).look_at(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0))
    renderer = _core.Renderer(512, 512, 1)
    spec = core_options(cam.view_matrix(), cam.projection_matrix(512, 512), False, cam.near,
                        cam.far, ["color", "depth"])  # no lights: the headlight
    expected = renderer.render(draws(), spec)
    for attempt in range(20):
        pending = draws()
        probe = weakref.ref(pending[0])  # the draw record, and through it the mesh
        out: dict = {}
        started = threading.Event()

        def work() -> None:
            started.set()
            out.update(renderer.render(pending, spec))
            out["end"] = time.perf_counter()

        thread = threading.Thread(target=work)
        thread.start()
        started.wait()
        time.sleep(0.002 * attempt)
        pending.clear()  # frees the Python object at once (refcount), no gc pass needed
        dropped = time.perf_counter()
        assert probe() is None
        thread.join()
        # Retry if the render began after the drop (nothing drawn) or ended before it.
        if out["depth"].any() and dropped < out["end"]:
            break
    else:
        pytest.fail("never dropped the mesh during a render")
    for name in ("color", "depth"):
        np.testing.assert_array_equal(out[name], expected[name])
