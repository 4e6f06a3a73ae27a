"""Runs a pyrender child script (tests/support/pyrender_*child.py) for a test: pyrender on OSMesa
lives in its own process, so its OpenGL platform never touches the test process."""
from __future__ import annotations

import os
import pathlib
import pickle
import subprocess
import sys
from typing import Any, Mapping, Sequence

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


def run_pyrender_script(folder: pathlib.Path, name: str, code: str, job: Any,
                        timeout: float = 600) -> Any:
    """Runs the child script ``code`` (written to ``folder``/``name``.py) with run_pyrender_child:
    its arguments are the tests folder (the child imports support.pyrender_env), softrast's parent
    folder (the child may import softrast), the pickled ``job`` and the file it pickles its result
    into, which is returned."""
    child = folder / f"{name}.py"
    child.write_text(code)
    job_path, out_path = folder / f"{name}_job.pkl", folder / f"{name}_out.pkl"
    job_path.write_bytes(pickle.dumps(job))
    import softrast  # (the parent folder of the softrast this process imports)
    tests = str(pathlib.Path(__file__).resolve().parents[1])
    parent = str(pathlib.Path(softrast.__file__).resolve().parent.parent)
    run_pyrender_child(child, [tests, parent, job_path, out_path], timeout=timeout)
    return pickle.loads(out_path.read_bytes())
