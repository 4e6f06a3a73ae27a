"""Mesh construction within the memory budget.

The budget is checked from the inputs' shapes before anything is converted, and validation runs
in chunks: a 10**8-vertex broadcast array or a 4.8 GB memory map is refused without being read,
and an accepted mesh needs its stored arrays plus a few MiB, whatever the input. Each case runs in
a child process (a hang fails on the timeout instead of stalling the suite) that resets its peak
RSS (VmHWM, via /proc/self/clear_refs) just before building the mesh and reports the growth.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

TIMEOUT_S = 60  # hang guard; each case takes well under a second
BUDGET = 100 * 2**20

CHILD = r"""
import json, sys
import numpy as np
import softrast as sr

def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) * 1024

case, arg, budget = sys.argv[1], sys.argv[2], int(sys.argv[3])
sr.set_memory_budget(budget)
tri = np.array([[0, 1, 2]])
if case == "broadcast_positions":
    args = (np.broadcast_to(np.arange(3.0), (10**8, 3)), tri)
elif case == "broadcast_faces":
    args = (np.eye(3), np.broadcast_to(np.array([0, 1, 2]), (10**8, 3)))
elif case == "broadcast_normals":
    args = (np.eye(3), tri)
elif case == "memmap":
    rows = int(arg.split(":")[1])
    args = (np.memmap(arg.split(":")[0], dtype=np.float64, mode="r", shape=(rows, 3)), tri)
elif case == "accepted":  # 4e6 float64 vertices (a view: the input costs nothing) -> 48 MB stored
    rows = int(arg)
    args = (np.broadcast_to(np.array([0.25, 0.5, 0.75]), (rows, 3)),
            np.broadcast_to(np.array([0, 1, 2]), (rows // 2, 3)))
# normals with 10**8 rows for 3 vertices: refused by their row count, before any conversion
kwargs = {"normals": np.broadcast_to(np.ones(3), (10**8, 3))} if case == "broadcast_normals" else {}
open("/proc/self/clear_refs", "w").write("5")  # reset the peak RSS (VmHWM) to the current RSS
before = status("VmRSS:")
result = {"error": None}
try:
    mesh = sr.Mesh(*args, **kwargs)
except Exception as exc:
    result["error"] = f"{type(exc).__name__}: {exc}"
result["growth"] = status("VmHWM:") - before
if result["error"] is None:  # checked after measuring: these comparisons allocate
    result["stored"] = mesh.positions.nbytes + mesh.faces.nbytes
    result["checks"] = bool((mesh.positions == np.float32([0.25, 0.5, 0.75])).all()
                            and (mesh.faces == [0, 1, 2]).all())
print(json.dumps(result))
"""


def _run(case: str, arg: str = "", budget: int = BUDGET) -> dict:
    env = dict(os.environ)
    # Under AddressSanitizer (.ci/sanitize sets SOFTRAST_ASAN) freed memory is held in a 256 MB
    # quarantine, which would show up as peak growth: the child turns it off.
    if env.get("SOFTRAST_ASAN"):
        env["ASAN_OPTIONS"] = env.get("ASAN_OPTIONS", "") + ":quarantine_size_mb=0"
    try:
        proc = subprocess.run([sys.executable, "-c", CHILD, case, arg, str(budget)], capture_output=True,
                              text=True, timeout=TIMEOUT_S, env=env)
    except subprocess.TimeoutExpired:
        pytest.fail(f"Mesh construction ({case}) did not finish in {TIMEOUT_S} s")
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.splitlines()[-1])


@pytest.mark.parametrize("case", ["broadcast_positions", "broadcast_faces"])
def test_huge_broadcast_input_refused_from_its_shape(case):
    # 10**8 rows stored as float32 / int32 need 1.2 GB: refused before a single row is read. The
    # positions case used to peak at +382 MB in validation (isfinite over the whole input) first.
    result = _run(case)
    assert result["error"] is not None and result["error"].startswith("ValueError: mesh with "), result
    assert "needs 1200000" in result["error"] and "memory budget of 104857600" in result["error"], result
    assert result["growth"] < 10 * 2**20, result


def test_attribute_with_wrong_row_count_refused_before_conversion():
    result = _run("broadcast_normals")
    assert result["error"] == "ValueError: normals must have one row per vertex (3), got 100000000", result
    assert result["growth"] < 10 * 2**20, result


def test_huge_memory_map_refused_without_reading_it(tmp_path):
    # A 4.8 GB sparse file (no disk space used) mapped as 2e8 float64 vertices: refused from the
    # shape. It used to be scanned for NaN (reading all 4.8 GB) before the budget was checked.
    rows = 200_000_000
    path = tmp_path / "vertices.f64"
    with open(path, "wb") as f:
        f.truncate(rows * 3 * 8)
    result = _run("memmap", f"{path}:{rows}")
    assert result["error"] is not None and result["error"].startswith("ValueError: mesh with 200000000 vertices"), result
    assert "needs 2400000012 bytes" in result["error"], result
    assert result["growth"] < 10 * 2**20, result


def test_accepted_mesh_needs_its_arrays_plus_a_few_mib():
    # 4e6 float64 vertices and 2e6 faces: 72 MB stored. Validating them whole used to add a bool
    # mask and a second copy for the bytes object (+60 MB); in chunks of 65,536 rows the
    # temporaries stay near 2 MiB.
    rows = 4_000_000
    result = _run("accepted", str(rows), budget=4 * 2**30)
    assert result["error"] is None and result["checks"], result
    assert result["stored"] == rows * 12 + rows // 2 * 12
    assert result["growth"] < result["stored"] + 8 * 2**20, result
