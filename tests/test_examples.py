"""Every example script runs and writes the images it promises."""
from __future__ import annotations

import pathlib
import subprocess
import sys

import numpy as np
import pytest

import softrast as sr

EXAMPLES = sorted((pathlib.Path(__file__).resolve().parents[1] / "examples").glob("[0-9]*.py"))


def test_examples_exist():
    assert len(EXAMPLES) >= 5


@pytest.mark.parametrize("script", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_runs(script, tmp_path):
    result = subprocess.run([sys.executable, str(script), str(tmp_path)], capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    images = sorted(tmp_path.rglob("*.png"))
    assert images, "the example wrote no image"
    for path in images:
        image = sr.imread(path)
        assert image.size > 0 and np.ptp(image) > 0, f"{path.name} is blank"
