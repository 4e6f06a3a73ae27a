"""Error against run time: each quality knob swept on reference scenes whose references are exact.

    softrast.report.run(out_dir, quick=False) -> {"csv": path, "markdown": path, "plot": path}
    softrast report --out DIR [--quick]

Writes DIR/report.csv (long format: one row per knob, value and metric), DIR/report.md (a table
per knob, the Pareto fronts, what a scene pays for each feature) and DIR/error_vs_time.png
(log-log, one curve per knob, the Pareto front marked). Needs matplotlib and scikit-image
(``pip install softrast[report]``); softrast itself imports without them.

Scenes and their exact references (NumPy float64):

* **sphere**: a unit sphere (trimesh icospheres, vertices on the sphere, exact radial vertex
  normals) centred on the optical axis of a PerspectiveCamera, lit by one DirectionalLight and
  an ambient light. Its silhouette is then a disk of radius ``f R / sqrt(d^2 - R^2)`` pixels
  about the image centre, and ``disk_coverage`` integrates it over every pixel square in closed
  form (the areas sum to pi r^2 to ~1e-13 relative). ``sphere_hit`` intersects each pixel
  centre's ray with the sphere (depth along the viewing axis, point, normal), and the shading
  models' formulas (``softrast.reference.shading``) applied to that normal give the colour. Only the
  box-filtered shaded sphere (metric ``rmse_box``, what msaa / ssaa are measured against) has
  no closed form: its reference is a 16 x 16-supersampled render, labelled so.
  The same sphere casting a shadow onto a backdrop plane measures shadow maps' resolution
  (``shadow_resolution``) against the exact method, a ray per pixel (errors in radiance and in
  pixels lit or shadowed differently).
* **checker**: a plane at a grazing angle carrying a 64 x 64 checkerboard texture (8 x 8 texels
  a check, so the texture is exactly the checker function), unlit. ``checker_box_filter``
  integrates the checker function over each pixel square exactly: the camera's x axis is
  parallel to the checks' rows, so lines of constant v are image rows and lines of constant u
  are straight image lines whose x is linear in y; between the rows where v crosses a check,
  the integral of a clamped linear function is closed form.

Metrics per image: colour RMSE, max error, PSNR and SSIM (scikit-image) on linear ``radiance``;
depth error in scene units and relative, where render and reference both hit; coverage error
(the 0/1 mask, or with msaa / ssaa the ``alpha`` output, against the exact area fraction) and
pixels whose mask differs from the exact point-sampled disk; normal error in degrees. Time is that of a render of the configuration's linear colour alone (``radiance``),
the median of repeated renders (the same Renderer, warmed up once) with the interquartile range;
the metrics read their outputs from one more render. No time is asserted anywhere: the numbers
describe the machine (and its load) they ran on.

The parts: ``_references`` (the exact references), ``_scenes`` (the sphere and checkerboard
scenes and their metrics), ``_sweeps`` (the knobs' sweeps and the feature costs), ``_writers``
(report.csv, report.md, error_vs_time.png), ``_common`` (``Row``, ``Settings``); ``measure``
and ``run`` are here.
"""
from __future__ import annotations

import os
import platform
import time
from typing import Any, Callable, Iterable

from .._version import __version__
from ..render import Renderer
from ._common import CSV_COLUMNS, FULL, QUICK, Row, Settings, _require
from ._references import (GrazingPlane, checker_box_filter, disk_coverage, shade, sphere_hit,
                          sphere_radius_px, supersampled_render)
from ._references import _clamped_line_mean  # noqa: F401 (tests check it)
from ._scenes import _Checker, _Sphere
from ._sweeps import _CHECKER_SWEEPS, _SPHERE_SWEEPS, _feature_costs
from ._writers import _plot, _write_csv, _write_markdown, pareto_front

__all__ = ["run", "measure", "Settings", "QUICK", "FULL", "Row", "CSV_COLUMNS", "disk_coverage",
           "sphere_radius_px", "sphere_hit", "GrazingPlane", "checker_box_filter", "shade",
           "supersampled_render", "pareto_front"]

for _cls in (Row, Settings, GrazingPlane):  # pickles and reprs name the public path, as before
    _cls.__module__ = __name__
del _cls


def measure(settings: Settings = QUICK, log: Callable[[str], Any] | None = None
            ) -> tuple[list[Row], list[dict[str, Any]]]:
    """Run every sweep and the feature costs; returns (rows, costs) without writing anything."""
    say = log or (lambda message: None)
    size = settings.size
    renderer = Renderer(size, size)
    rows: list[Row] = []
    sphere = _Sphere(size, size)
    for sweep in _SPHERE_SWEEPS:
        start = time.perf_counter()
        rows += sweep(settings, sphere, renderer)
        say(f"{sweep.__name__[len('_sweep_'):]}: {time.perf_counter() - start:.1f} s")
    checker = _Checker(size, size)
    for sweep in _CHECKER_SWEEPS:
        start = time.perf_counter()
        rows += sweep(settings, checker, renderer)
        say(f"{sweep.__name__[len('_sweep_'):]}: {time.perf_counter() - start:.1f} s")
    start = time.perf_counter()
    costs = _feature_costs(settings)
    say(f"feature costs: {time.perf_counter() - start:.1f} s")
    return rows, costs


def _check_writable(out: str, files: Iterable[str]) -> None:
    """Creates the report folder ``out`` and a file in it (removed), so that a folder the
    report cannot be written to is an error before minutes of measuring, naming it."""
    try:
        os.makedirs(out, exist_ok=True)
    except OSError as e:
        raise type(e)(f"report folder {out!r} cannot be created: {e.strerror or e}") from None
    probe = os.path.join(out, f".softrast-report-{os.getpid()}.probe")
    try:
        with open(probe, "xb"):
            pass
        os.remove(probe)
    except OSError as e:
        raise type(e)(f"report folder {out!r} is not writable: {e.strerror or e}") from None
    for path in files:
        if os.path.isdir(path):
            raise IsADirectoryError(f"report folder {out!r}: {os.path.basename(path)} is a "
                                    "folder, where the report writes a file")


def run(out_dir: str | os.PathLike[str], quick: bool = False, settings: Settings | None = None,
        log: Callable[[str], Any] | None = None) -> dict[str, str]:
    """Measure (``QUICK`` or ``FULL`` settings, or your own) and write DIR/report.csv,
    DIR/report.md and DIR/error_vs_time.png; returns {"csv", "markdown", "plot"} paths.

    Raises ImportError naming the package (and ``pip install softrast[report]``) when matplotlib
    or scikit-image is missing, and OSError naming ``out_dir`` when it cannot be created or
    written to, before measuring anything."""
    _require("matplotlib", "matplotlib")
    _require("skimage.metrics", "scikit-image")
    settings = settings or (QUICK if quick else FULL)
    out = os.fspath(out_dir)
    paths = {"csv": os.path.join(out, "report.csv"), "markdown": os.path.join(out, "report.md"),
             "plot": os.path.join(out, "error_vs_time.png")}
    _check_writable(out, paths.values())
    start = time.perf_counter()
    rows, costs = measure(settings, log)
    seconds = time.perf_counter() - start
    mode = "quick" if settings == QUICK else "full" if settings == FULL else "custom"
    header = [f"softrast {__version__}, {mode} mode: {settings.size}x{settings.size} images, "
              f"{settings.repeats} timed renders per configuration after a warm-up (feature costs: "
              f"{settings.cost_size[0]}x{settings.cost_size[1]}, ico{settings.cost_subdivision}, "
              f"{settings.cost_repeats} renders); measured in {seconds:.1f} s on {os.cpu_count()} "
              f"cores ({Renderer(1, 1).isa} kernels, {platform.machine()}, Python {platform.python_version()})."]
    _write_csv(paths["csv"], rows)
    _write_markdown(paths["markdown"], rows, costs, header, settings)
    _plot(paths["plot"], rows, f"softrast: error against render time ({mode} mode, "
          f"{settings.size}x{settings.size}, {os.cpu_count()} cores)")
    return paths
