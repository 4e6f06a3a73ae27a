"""The report's measurements: each knob swept on its scene (rows of error and time, the
configurations of a knob timed together) and what a scene pays for each feature."""
from __future__ import annotations

import math
import os
import time
from typing import Any, Callable, Sequence

import numpy as np

from .._core import OUTPUTS
from ..light import PointLight
from ..material import Material
from ..render import Renderer
from ..scene import Scene
from ..texture import FILTERS, Texture
from ._common import _SUPERSAMPLED, Row, Settings
from ._references import GrazingPlane, supersampled_render
from ._scenes import (_MODELS, _Checker, _colour_metrics, _icosphere, _shadow_scene, _Sphere,
                      _sphere_camera)


def _time_all(renders: Sequence[Callable[[], Any]], repeats: int) -> list[tuple[float, float]]:
    """(median ms, interquartile range ms) of each callable: one warm-up call each, then
    ``repeats`` rounds calling each once in turn. Interleaved, so that a burst of load elsewhere
    on the machine spreads over every configuration of a knob instead of landing on one."""
    for render in renders:
        render()
    times = np.zeros((repeats, len(renders)))
    for i in range(repeats):
        for j, render in enumerate(renders):
            start = time.perf_counter()
            render()
            times[i, j] = (time.perf_counter() - start) * 1e3
    q1, median, q3 = np.percentile(times, [25, 50, 75], axis=0)
    return [(float(m), float(b - a)) for a, m, b in zip(q1, median, q3)]


# Every configuration's time is that of a render of its linear colour alone, so that the knobs
# of one scene compare; the metrics read their outputs from one more render (_frame_and_timer).
_TIMED_OUTPUTS = ("radiance",)


def _frame_and_timer(renderer: Any, scene: Any, camera: Any, outputs: Sequence[str],
                     **options: Any) -> tuple[Any, Callable[[], Any]]:
    """(a frame with ``outputs``, a callable rendering _TIMED_OUTPUTS with the same options on
    the same Renderer, for _time_all)."""
    frame = renderer.render(scene, camera, outputs=outputs, **options)
    return frame, lambda: renderer.render(scene, camera, outputs=_TIMED_OUTPUTS, **options)


# One configuration of a knob: (value, setting, metrics, the callable to time).
_Case = tuple[Any, str, list[tuple[str, float, str, str, str]], Callable[[], Any]]


def _knob_rows(knob: str, scene: str, cases: Sequence[_Case], repeats: int) -> list[Row]:
    """Time a knob's configurations together (_time_all) and make a Row per value and metric."""
    times = _time_all([case[3] for case in cases], repeats)
    return [Row(knob, value, metric, error, t, spread, scene, reference, better, unit, setting)
            for (value, setting, metrics, _), (t, spread) in zip(cases, times)
            for metric, error, unit, reference, better in metrics]


_SPHERE_OUTPUTS = ("radiance", "depth", "mask", "normal")


def _sweep_tessellation(s: Settings, sphere: _Sphere, renderer: Any) -> list[Row]:
    """Icosphere subdivisions: every geometric metric, and colour (lambert, per pixel) against
    the closed form at pixel centres and against the 16x16-supersampled render (box filter)."""
    size = f"{sphere.width}x{sphere.height}"
    box = _supersampled_box(s, sphere, renderer)
    box_label = f"{_SUPERSAMPLED} (ico{s.supersampled_subdivision}, lambert)"
    cases = []
    for k in s.subdivisions:
        frame, timer = _frame_and_timer(renderer, sphere.scene(k), sphere.camera, _SPHERE_OUTPUTS)
        metrics = sphere.geometry_metrics(frame)
        metrics += _colour_metrics(frame.radiance, sphere.colour("lambert"), "analytic lambert, pixel centres")
        rmse_box = float(np.sqrt(np.mean((frame.radiance[..., 0] - box[..., 0]) ** 2)))
        metrics.append(("rmse_box", rmse_box, "linear radiance", box_label, "lower"))
        cases.append((k, f"{len(sphere.mesh(k).faces)} faces, lambert, pixel, {size}", metrics, timer))
    return _knob_rows("tessellation", "sphere", cases, s.repeats)


def _sweep_frequency(s: Settings, sphere: _Sphere, renderer: Any) -> list[Row]:
    """Shading frequency face / vertex / pixel, lambert, at a fixed tessellation."""
    k = s.fixed_subdivision
    scene = sphere.scene(k)
    cases = []
    for frequency in ("face", "vertex", "pixel"):
        frame, timer = _frame_and_timer(renderer, scene, sphere.camera, ("radiance",), frequency=frequency)
        metrics = _colour_metrics(frame.radiance, sphere.colour("lambert"), "analytic lambert, pixel centres")
        cases.append((frequency, f"ico{k}, lambert, {sphere.width}x{sphere.height}", metrics, timer))
    return _knob_rows("frequency", "sphere", cases, s.repeats)


def _sweep_shading(s: Settings, sphere: _Sphere, renderer: Any) -> list[Row]:
    """Shading models with a closed form, each against its own, at a fixed tessellation."""
    k = s.fixed_subdivision
    cases = []
    for model in _MODELS:
        frame, timer = _frame_and_timer(renderer, sphere.scene(k, model), sphere.camera, ("radiance",))
        metrics = _colour_metrics(frame.radiance, sphere.colour(model), f"analytic {model}, pixel centres")
        cases.append((model, f"ico{k}, pixel, {sphere.width}x{sphere.height}", metrics, timer))
    return _knob_rows("shading_model", "sphere", cases, s.repeats)


def _sweep_threads(s: Settings, sphere: _Sphere, renderer: Any) -> list[Row]:
    """Worker threads (time only: images are bit-identical for any thread count)."""
    k = s.threads_subdivision
    scene = sphere.scene(k)
    cases, first = [], None
    for n in [n for n in (1, 2, 4, 8, 16) if n <= max(os.cpu_count() or 1, 2)]:
        frame, timer = _frame_and_timer(Renderer(sphere.width, sphere.height, threads=n), scene,
                                        sphere.camera, ("radiance",))
        first = frame.radiance if first is None else first
        same = "identical" if np.array_equal(first, frame.radiance) else "DIFFERENT"
        metrics = _colour_metrics(frame.radiance, sphere.colour("lambert"), "analytic lambert, pixel centres")[:1]
        cases.append((n, f"ico{k}, lambert, pixel, {sphere.width}x{sphere.height}, image {same} to threads=1",
                      metrics, timer))
    return _knob_rows("threads", "sphere", cases, s.repeats)


def _supersampled_box(s: Settings, sphere: _Sphere, renderer: Any) -> np.ndarray:
    """The 16x16-supersampled lambert render of the sphere at s.supersampled_subdivision, once
    per sphere (the tessellation and anti-aliasing sweeps share it)."""
    cached = getattr(sphere, "_box", None)
    if cached is None:
        cached = supersampled_render(renderer, sphere.scene(s.supersampled_subdivision),
                                     sphere.camera_args())
        sphere._box = cached
    return cached


def _sweep_antialiasing(s: Settings, sphere: _Sphere, renderer: Any) -> list[Row]:
    """msaa 1, 2, 4, 8, 16 and ssaa 1..4 (8 in the full report) on the finest sphere: coverage
    (the frame's alpha against the exact disk area per pixel) and colour (radiance, which is
    premultiplied by alpha, against the 16x16-supersampled box filter, whose background is 0
    too). Point sampling's floor is the knobs' value 1."""
    k = s.supersampled_subdivision
    scene = sphere.scene(k)
    box = _supersampled_box(s, sphere, renderer)
    box_label = f"{_SUPERSAMPLED} (ico{k}, lambert)"
    cov_label = sphere.reference_coverage
    area = math.pi * sphere.radius_px ** 2
    edge = (sphere.coverage > 0.0) & (sphere.coverage < 1.0)
    rows = []
    for knob, values in (("msaa", (1, 2, 4, 8, 16)), ("ssaa", (1, 2, 3, 4) if s.size < 256 else (1, 2, 3, 4, 6, 8))):
        cases = []
        for n in values:
            frame, timer = _frame_and_timer(renderer, scene, sphere.camera, ("radiance", "alpha"),
                                            **{knob: n})
            err = np.abs(frame.alpha - sphere.coverage)
            rmse_box = float(np.sqrt(np.mean((frame.radiance[..., 0] - box[..., 0]) ** 2)))
            metrics = [
                ("coverage_mean", float(err[edge].mean()), "pixel fraction", cov_label, "lower"),
                ("coverage_max", float(err.max()), "pixel fraction", cov_label, "lower"),
                ("area_rel", abs(float(frame.alpha.sum()) - area) / area, "relative", cov_label, "lower"),
                ("rmse_box", rmse_box, "linear radiance", box_label, "lower"),
            ]
            samples = n if knob == "msaa" else n * n
            cases.append((n, f"{samples} samples, ico{k}, lambert, {sphere.width}x{sphere.height}",
                          metrics, timer))
        rows += _knob_rows(knob, "sphere", cases, s.repeats)
    return rows


def _sweep_filter(s: Settings, checker: _Checker, renderer: Any) -> list[Row]:
    scene = checker.scene(16)
    cases = []
    for name in FILTERS:
        frame, timer = _frame_and_timer(renderer, scene, checker.camera, ("radiance",), texture_filter=name)
        cases.append((name, f"max_anisotropy 16, {checker.width}x{checker.height}", checker.metrics(frame), timer))
    return _knob_rows("texture_filter", "checker", cases, s.repeats)


def _sweep_anisotropy(s: Settings, checker: _Checker, renderer: Any) -> list[Row]:
    cases = []
    for n in s.anisotropy:
        frame, timer = _frame_and_timer(renderer, checker.scene(n), checker.camera, ("radiance",),
                                        texture_filter="anisotropic")
        cases.append((n, f"anisotropic, {checker.width}x{checker.height}", checker.metrics(frame), timer))
    return _knob_rows("max_anisotropy", "checker", cases, s.repeats)


def _sweep_shadow_resolution(s: Settings, sphere: _Sphere, renderer: Any) -> list[Row]:
    """Shadow maps of growing resolution against the exact method (a ray per pixel), on the
    sphere casting onto a backdrop: radiance RMSE, and the share of pixels whose radiance
    differs by over 0.05 (lit against shadowed: the maps' filtered edges and their texels).
    The value "exact" is the reference itself (error 0), for its time."""
    k = s.fixed_subdivision
    size = f"ico{k} over a plane, lambert, {sphere.width}x{sphere.height}"
    # (its own renderer: it keeps the occluders' hierarchy between renders, as a loop over views
    # of one scene does, which renders of the map scenes in between would drop)
    exact, exact_timer = _frame_and_timer(Renderer(sphere.width, sphere.height),
                                          _shadow_scene(sphere, k, "exact"), sphere.camera, ("radiance",))
    reference = exact.radiance[..., 0].astype(np.float64)
    label = "exact shadows (a ray per pixel), the same renderer"
    cases = []
    for resolution in s.shadow_resolutions:
        frame, timer = _frame_and_timer(renderer, _shadow_scene(sphere, k, "map", resolution),
                                        sphere.camera, ("radiance",))
        diff = np.abs(frame.radiance[..., 0].astype(np.float64) - reference)
        cases.append((resolution, f"{resolution}x{resolution} map, {size}", [
            ("rmse", float(np.sqrt(np.mean(diff ** 2))), "linear radiance", label, "lower"),
            ("shadow_mismatch", float(np.mean(diff > 0.05)), "pixel fraction", label, "lower")], timer))
    cases.append(("exact", f"exact, {size}", [
        ("rmse", 0.0, "linear radiance", label, "lower"),
        ("shadow_mismatch", 0.0, "pixel fraction", label, "lower")], exact_timer))
    return _knob_rows("shadow_resolution", "sphere", cases, s.repeats)


_SPHERE_SWEEPS = (_sweep_tessellation, _sweep_frequency, _sweep_shading, _sweep_threads,
                  _sweep_antialiasing, _sweep_shadow_resolution)
_CHECKER_SWEEPS = (_sweep_filter, _sweep_anisotropy)


# ------------------------------------------------------------------------ what a scene pays for

def _feature_costs(s: Settings) -> list[dict[str, Any]]:
    """Time of the sphere scene with each feature off, then on, in groups: the outputs asked for,
    a texture, lights, shadows, the normal output, the exact surface step, anti-aliasing. Rows: group, setting, time_ms, time_spread_ms,
    delta_ms (against the group's first row)."""
    width, height = s.cost_size
    camera = _sphere_camera(width, height)
    mesh = _icosphere(s.cost_subdivision, uvs=True)
    renderer = Renderer(width, height)

    def scene_with(material: Any = None, lights: int = 0) -> Any:
        scene = Scene()
        scene.add(mesh, material=material)
        for i in range(lights):  # around the camera, in front of the sphere
            angle = 2.0 * math.pi * i / max(lights, 1)
            pose = np.eye(4)
            pose[:3, 3] = (2.0 * math.cos(angle), 2.0 * math.sin(angle), 3.0)
            scene.add(PointLight(intensity=6.0 / lights), pose=pose)
        return scene

    plain = scene_with()
    white = Material(base_color=(1.0, 1.0, 1.0), model="lambert")
    rgb8 = np.repeat(GrazingPlane().texture_image() * np.uint8(255), 3, axis=2).astype(np.uint8)
    textured = white.replace(base_color_texture=Texture(rgb8))  # 8-bit sRGB, as files are
    colour_depth = ("color", "depth")
    groups = [
        ("outputs", [("depth", plain, ("depth",)), ("color + depth", plain, colour_depth),
                     (f"all {len(OUTPUTS)} outputs", plain, tuple(OUTPUTS))]),
        ("texture", [("none (lambert material)", scene_with(white), colour_depth),
                     ("512x512 RGB base colour texture, trilinear", scene_with(textured), colour_depth)]),
        ("lights", [("0 (the headlight)", plain, colour_depth), ("1 point light", scene_with(lights=1), colour_depth),
                    ("4 point lights", scene_with(lights=4), colour_depth)]),
        ("shadows", [("1 point light", scene_with(lights=1), colour_depth),
                     ("1 point light, exact shadows (a ray per lit pixel)", scene_with(lights=1),
                      colour_depth, {"shadows": True}),
                     ("1 point light, shadow map (a cube of six, made once per scene state)",
                      scene_with(lights=1), colour_depth, {"shadows": "map"})]),
        ("normal output", [("color + depth", plain, colour_depth),
                           ("color + depth + normal", plain, colour_depth + ("normal",))]),
        # the exact surface step (cpp/surface.cpp): each pixel's ray on its face, in double
        ("exact surface step", [("depth + ids", plain, ("depth", "triangle_id", "instance_id")),
                                ("+ barycentric, uv, position, ray_depth (each pixel's exact hit)", plain,
                                 ("depth", "triangle_id", "instance_id", "barycentric", "uv", "position",
                                  "ray_depth"))]),
        ("anti-aliasing", [("off", plain, colour_depth), ("msaa=4", plain, colour_depth, {"msaa": 4}),
                           ("ssaa=2 (4 samples, each shaded)", plain, colour_depth, {"ssaa": 2})]),
    ]
    rows = []
    for group, cases in groups:
        times = _time_all([lambda case=case: renderer.render(case[1], camera, outputs=case[2],
                                                             **(case[3] if len(case) > 3 else {}))
                           for case in cases], s.cost_repeats)
        for (setting, *_), (t, spread) in zip(cases, times):
            rows.append({"group": group, "setting": setting, "time_ms": t, "time_spread_ms": spread,
                         "delta_ms": t - times[0][0]})
    return rows
