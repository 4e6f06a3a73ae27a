"""Runs a pyrender child script (tests/pyrender_*child.py) for a test: pyrender on OSMesa lives in
its own process, so its OpenGL platform never touches the test process."""
from __future__ import annotations

import os
import subprocess
import sys
from typing import Mapping, Sequence

import pytest

INSTALL_HINT = (
    "pyrender 0.1.45 with OSMesa is required by this test (it is never skipped). Install it with "
    "`bash .ci/install --test` (Debian packages libosmesa6 libgl1, then "
    "`pip install pyrender==0.1.45` and `pip install 'PyOpenGL>=3.1.10'` over pyrender's pin), "
    "or `bash benchmarks/setup_baselines.sh`.")


def run_pyrender_child(child: os.PathLike[str] | str, args: Sequence[str], timeout: float,
                       env: Mapping[str, str] | None = None) -> subprocess.CompletedProcess:
    """Runs ``child`` with ``args`` under PYOPENGL_PLATFORM=osmesa (``env``: the environment,
    default this process's: under the sanitizer run the ASan runtime must stay preloaded for a
    child that imports softrast). Fails the test on a hang, on exit status 3 (pyrender cannot be
    imported: the install instructions) and on any other failure (the child's stderr)."""
    env = dict(os.environ if env is None else env, PYOPENGL_PLATFORM="osmesa")
    name = os.path.basename(os.fspath(child))
    try:
        proc = subprocess.run([sys.executable, os.fspath(child), *map(str, args)], env=env,
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as exc:
        pytest.fail(f"the pyrender child ({name}) did not finish in {exc.timeout} s")
    if proc.returncode == 3:
        pytest.fail(f"{INSTALL_HINT}\n{proc.stderr.strip()}")
    assert proc.returncode == 0, (f"the pyrender child ({name}) failed (exit {proc.returncode}); "
                                  f"{INSTALL_HINT}\nstderr:\n{proc.stderr[-4000:]}")
    return proc
