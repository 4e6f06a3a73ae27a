"""Soak: thousands of renders and renderers in one process leak neither memory nor threads.

SOFTRAST_SOAK_RENDERS sets the number of renders (default 1000, ~3 s); benchmarks/soak.py runs
the same loop 10,000 times and prints RSS as it goes.
"""
from __future__ import annotations

import importlib.util
import os
import time

import numpy as np

import softrast as sr

from conftest import ROOT, icosphere

MAX_RSS_GROWTH_MB = 20.0
# Under AddressSanitizer (.ci/sanitize sets SOFTRAST_ASAN) freed memory is held in a 256 MB
# quarantine (to catch use-after-free) before it is reused, so RSS grows by up to that much
# without a leak: the budget includes it there.
if os.environ.get("SOFTRAST_ASAN"):
    MAX_RSS_GROWTH_MB += 256.0


def _soak_module():
    spec = importlib.util.spec_from_file_location("soak", ROOT / "benchmarks" / "soak.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _threads() -> int:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("Threads:"))


def test_many_renders_of_changing_scenes_do_not_grow_rss():
    renders = int(os.environ.get("SOFTRAST_SOAK_RENDERS", "1000"))
    result = _soak_module().run(renders)
    growth = result["rss_peak_mb"] - result["rss_warm_mb"]
    assert growth < MAX_RSS_GROWTH_MB, result


def test_thousand_renderers_join_their_threads_and_free_memory():
    scene = sr.Scene()
    scene.add(icosphere(2))
    cam = sr.PerspectiveCamera(fov_y=50.0)
    cam.look_at(eye=(0.0, 0.0, 3.0), target=(0.0, 0.0, 0.0))
    expected = sr.Renderer(48, 32, threads=1).render(scene, cam, outputs=("color", "depth"))
    baseline_threads = _threads()
    rss = _soak_module().rss_bytes
    most_threads = 0
    for k in range(1000):
        renderer = sr.Renderer(48, 32, threads=2)
        if k % 10 == 0:  # a render makes sure the workers actually started
            frame = renderer.render(scene, cam, outputs=("color", "depth"))
            np.testing.assert_array_equal(frame.color, expected.color)
        if k == 100:
            rss_warm = rss()
        most_threads = max(most_threads, _threads())
        del renderer
    # Destroying a Renderer joins its workers: the count is back to the baseline, at once.
    deadline = time.monotonic() + 2.0
    while _threads() != baseline_threads and time.monotonic() < deadline:
        time.sleep(0.01)
    assert _threads() == baseline_threads
    assert most_threads <= baseline_threads + 2  # never more than one renderer's two workers
    assert (rss() - rss_warm) / 2**20 < MAX_RSS_GROWTH_MB
