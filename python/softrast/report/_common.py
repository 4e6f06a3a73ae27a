"""What the report's parts share: the CSV's columns, a measurement (``Row``), what a report
sweeps (``Settings``, ``QUICK``, ``FULL``) and the import of its optional dependencies."""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

# The long-format CSV's columns, in order: the first five are the contract.
CSV_COLUMNS = ("knob", "value", "metric", "error", "time_ms", "time_spread_ms", "scene",
               "reference", "better", "unit", "setting")

_SUPERSAMPLED = "render_16x16_supersampled"  # the label of a reference that is a render


# ----------------------------------------------------------------------------- optional deps

def _require(module: str, package: str) -> Any:
    """Import an optional dependency of the report, or say which package to install."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise ImportError(f"softrast's report needs {package}: pip install softrast[report] "
                          f"(or pip install {package})") from None


# --------------------------------------------------------------------------------- measurement

@dataclass
class Row:
    """One measurement: a knob's value on a scene, one metric against one reference."""

    knob: str
    value: Any
    metric: str
    error: float
    time_ms: float
    time_spread_ms: float
    scene: str
    reference: str
    better: str = "lower"  # "higher" for psnr_db and ssim
    unit: str = ""
    setting: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in CSV_COLUMNS}


@dataclass(frozen=True)
class Settings:
    """What a report sweeps. ``QUICK`` runs in seconds (CI); ``FULL`` makes the README's figure."""

    size: int                          # the sweeps' images are size x size
    repeats: int                       # timed renders per configuration, after one warm-up
    subdivisions: tuple[int, ...]      # icosphere subdivisions of the tessellation knob
    fixed_subdivision: int             # the frequency and shading-model knobs' sphere
    threads_subdivision: int
    supersampled_subdivision: int      # the sphere of the 16x16-supersampled colour reference
    anisotropy: tuple[int, ...]
    cost_size: tuple[int, int] = (640, 480)
    cost_subdivision: int = 6
    cost_repeats: int = 11
    shadow_resolutions: tuple[int, ...] = (64, 128, 256, 512, 1024, 2048)


QUICK = Settings(size=128, repeats=7, subdivisions=(1, 2, 3, 4, 5, 6, 7), fixed_subdivision=4,
                 threads_subdivision=6, supersampled_subdivision=7, anisotropy=(1, 4, 16),
                 cost_subdivision=6, cost_repeats=9)
FULL = Settings(size=512, repeats=25, subdivisions=(1, 2, 3, 4, 5, 6, 7, 8), fixed_subdivision=4,
                threads_subdivision=7, supersampled_subdivision=8, anisotropy=(1, 2, 4, 8, 16),
                cost_subdivision=6, cost_repeats=31,
                shadow_resolutions=(64, 128, 256, 512, 1024, 2048, 4096))
