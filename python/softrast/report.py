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
  models' formulas (``softrast.material``) applied to that normal give the colour. Only the
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
"""
from __future__ import annotations

import csv
import math
import os
import platform
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from ._core import OUTPUTS

__all__ = ["run", "measure", "Settings", "QUICK", "FULL", "Row", "CSV_COLUMNS", "disk_coverage",
           "sphere_radius_px", "sphere_hit", "GrazingPlane", "checker_box_filter", "shade",
           "supersampled_render", "pareto_front"]

# The long-format CSV's columns, in order: the first five are the contract.
CSV_COLUMNS = ("knob", "value", "metric", "error", "time_ms", "time_spread_ms", "scene",
               "reference", "better", "unit", "setting")

_SUPERSAMPLED = "render_16x16_supersampled"  # the label of a reference that is a render


# ----------------------------------------------------------------------------- optional deps

def _require(module: str, package: str) -> Any:
    """Import an optional dependency of the report, or say which package to install."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise ImportError(f"softrast's report needs {package}: pip install softrast[report] "
                          f"(or pip install {package})") from None


# ----------------------------------------------------------------------- reference: the sphere

def sphere_radius_px(fov_y: float, height: int, distance: float, radius: float = 1.0) -> float:
    """Radius in pixels of the silhouette of a sphere centred on a pinhole camera's optical axis.

    The cone of rays tangent to the sphere has half-angle asin(R / d), so its trace on the image
    plane is a circle of radius f tan(asin(R / d)) = f R / sqrt(d^2 - R^2), with f the focal
    length in pixels, (height / 2) / tan(fov_y / 2). fov_y in degrees; d > R.
    """
    f = (height / 2.0) / math.tan(math.radians(fov_y) / 2.0)
    return f * radius / math.sqrt(distance * distance - radius * radius)


def _disk_quadrant_area(x: np.ndarray, y: np.ndarray, r: float) -> np.ndarray:
    """Area of {X <= x, Y <= y} inside the disk X^2 + Y^2 <= r^2, in closed form (float64).

    It is the integral over X in [-r, min(x, r)] of the chord's part below y,
    clamp(y, -s, s) + s with s(X) = sqrt(r^2 - X^2), whose antiderivative is
    S(X) = (X s(X) + r^2 asin(X / r)) / 2. Where |X| < a = sqrt(r^2 - y^2) the clamp is y,
    elsewhere it is sign(y) s(X): every piece is S or a line.
    """
    def S(X: np.ndarray) -> np.ndarray:
        X = np.clip(X, -r, r)
        return 0.5 * (X * np.sqrt(np.maximum(r * r - X * X, 0.0)) + r * r * np.arcsin(X / r))

    x, y = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
    xc = np.clip(x, -r, r)
    full = S(xc) - S(-r)                       # the integral of s: the whole chord's half
    yc = np.clip(y, -r, r)
    a = np.sqrt(np.maximum(r * r - yc * yc, 0.0))
    sign = np.sign(y)
    clamped = (sign * (S(np.minimum(xc, -a)) - S(-r))            # X < -a: sign(y) s
               + yc * (np.clip(xc, -a, a) + a)                     # |X| < a: y
               + sign * (S(np.maximum(xc, a)) - S(a)))            # X > a: sign(y) s
    return full + clamped


def disk_coverage(width: int, height: int, radius_px: float, centre: tuple[float, float] | None = None
                  ) -> np.ndarray:
    """(height, width) float64: the exact area of a disk inside each pixel square, in [0, 1].

    Pixel (row i, col j) is the square [j, j + 1] x [i, i + 1] in window coordinates; the disk
    has ``radius_px`` and ``centre`` (x, y) in window coordinates (default the image centre).
    Each pixel is the inclusion-exclusion of four quadrant areas (``_disk_quadrant_area``),
    computed relative to the disk's centre. The areas sum to pi r^2 (for a disk inside the image)
    to a few ulps of the largest quadrant area per pixel: ~1e-13 relative (tested to 1e-9).
    """
    cx, cy = (width / 2.0, height / 2.0) if centre is None else centre
    xs = np.arange(width + 1, dtype=np.float64) - cx    # pixel edges relative to the centre
    ys = np.arange(height + 1, dtype=np.float64) - cy
    # Window y points down, but the disk is symmetric about its centre, so the quadrant areas
    # are the same with y measured either way.
    Q = _disk_quadrant_area(xs[None, :], ys[:, None], radius_px)      # (h + 1, w + 1)
    area = Q[1:, 1:] - Q[:-1, 1:] - Q[1:, :-1] + Q[:-1, :-1]
    # Squares wholly inside (farthest corner in the disk) or outside (nearest point out of it)
    # are exactly 1 and 0: the differences above leave them a few ulps off.
    near_x = np.maximum(np.maximum(xs[:-1], -xs[1:]), 0.0)
    near_y = np.maximum(np.maximum(ys[:-1], -ys[1:]), 0.0)
    far_x = np.maximum(np.abs(xs[:-1]), np.abs(xs[1:]))
    far_y = np.maximum(np.abs(ys[:-1]), np.abs(ys[1:]))
    r2 = radius_px * radius_px
    area = np.where(near_y[:, None] ** 2 + near_x[None, :] ** 2 >= r2, 0.0, area)
    area = np.where(far_y[:, None] ** 2 + far_x[None, :] ** 2 <= r2, 1.0, area)
    return np.clip(area, 0.0, 1.0)


def _pixel_rays(width: int, height: int, fov_y: float) -> np.ndarray:
    """(h, w, 3) view-space directions through the pixel centres, scaled so that z = -1 (the
    distance along a ray is then its depth along the viewing axis). Square pixels, the vertical
    field of view fov_y in degrees, window y down (row 0 at the top)."""
    t = math.tan(math.radians(fov_y) / 2.0)
    x_ndc = 2.0 * (np.arange(width) + 0.5) / width - 1.0
    y_ndc = 1.0 - 2.0 * (np.arange(height) + 0.5) / height
    d = np.empty((height, width, 3))
    d[..., 0] = x_ndc[None, :] * t * width / height
    d[..., 1] = y_ndc[:, None] * t
    d[..., 2] = -1.0
    return d


def sphere_hit(width: int, height: int, fov_y: float, distance: float, radius: float = 1.0
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ray-sphere intersection at every pixel centre, for a camera at (0, 0, distance) looking
    down -z at a sphere of ``radius`` at the origin (view axes = world axes).

    Returns (depth (h, w): the nearest hit's distance along the viewing axis, 0 = miss;
    position (h, w, 3) world points, 0 = miss; normal (h, w, 3) unit outward normals, 0 = miss).
    With the ray o + t d, d_z = -1, t is the depth and solves |d|^2 t^2 - 2 D t + D^2 - R^2 = 0
    (o . d = -D): t = (D^2 - R^2) / (D + sqrt(D^2 - |d|^2 (D^2 - R^2))), the form without
    cancellation. At the image centre t = D - R exactly.
    """
    d = _pixel_rays(width, height, fov_y)
    a = np.einsum("ijk,ijk->ij", d, d)
    c = distance * distance - radius * radius
    disc = distance * distance - a * c
    hit = disc >= 0.0
    t = np.where(hit, c / (distance + np.sqrt(np.maximum(disc, 0.0))), 0.0)
    position = d * t[..., None]
    position[..., 2] += distance
    position[~hit] = 0.0
    normal = position / radius
    return t, position, normal


# ------------------------------------------------------------------- reference: the checkerboard

@dataclass(frozen=True)
class GrazingPlane:
    """The checkerboard scene: the plane y = 0, x and z in [-half, half], with
    u = (x + half) / (2 half) and v = (half - z) / (2 half) (v = 1 at the far edge), carrying
    ``checks`` x ``checks`` checks (check (k, l) = floor(checks u), floor(checks v) is white when
    k + l is odd); a camera at (0, eye_height, eye_z) pitched down by ``pitch`` degrees (no yaw,
    no roll: its x axis is the world's, so u-lines and v-lines are straight lines in the image
    and v-lines are rows), vertical field of view ``fov_y`` degrees, square pixels."""

    half: float = 4.0
    checks: int = 64
    texels_per_check: int = 8
    eye_height: float = 0.35
    eye_z: float = 4.3
    pitch: float = math.degrees(math.atan2(0.35, 5.3))  # looks at (0, 0, -1): example 07's view
    fov_y: float = 50.0

    def pose(self) -> np.ndarray:
        """(4, 4) camera-to-world pose (OpenGL axes: x right, y up, looking down -z)."""
        s, c = math.sin(math.radians(self.pitch)), math.cos(math.radians(self.pitch))
        pose = np.eye(4)
        pose[:3, 1] = (0.0, c, -s)
        pose[:3, 2] = (0.0, s, c)
        pose[:3, 3] = (0.0, self.eye_height, self.eye_z)
        return pose

    def texture_image(self) -> np.ndarray:
        """(n, n, 1) float32 in {0, 1}: the checker function texel for texel (row 0 is v = 1)."""
        n = self.checks * self.texels_per_check
        rows, cols = np.mgrid[0:n, 0:n]
        return (((n - 1 - rows) // self.texels_per_check + cols // self.texels_per_check) % 2
                ).astype(np.float32)[:, :, None]

    # The camera's rays: window (x, y) -> view direction (x_ndc a T, y_ndc T, -1), whose world
    # y component is cos(p) q - sin(p) (q = y_ndc T), so the ray meets y = 0 at
    # t = eye_height / (sin(p) - cos(p) q), at X = t x_ndc a T and Z = eye_z - t (sin(p) q + cos(p)).

    def _t(self, y: np.ndarray, height: int) -> np.ndarray:
        q = (1.0 - 2.0 * np.asarray(y, dtype=np.float64) / height) * math.tan(math.radians(self.fov_y) / 2.0)
        s, c = math.sin(math.radians(self.pitch)), math.cos(math.radians(self.pitch))
        with np.errstate(divide="ignore"):
            return np.where(s - c * q > 0.0, self.eye_height / (s - c * q), np.inf)  # inf: horizon and above

    def uv(self, x: np.ndarray, y: np.ndarray, width: int, height: int) -> np.ndarray:
        """(..., 2) float64 uv of the plane point seen at window (x, y); NaN above the horizon."""
        T = math.tan(math.radians(self.fov_y) / 2.0)
        q = (1.0 - 2.0 * np.asarray(y, dtype=np.float64) / height) * T
        s, c = math.sin(math.radians(self.pitch)), math.cos(math.radians(self.pitch))
        t = self._t(y, height)
        t = np.where(np.isfinite(t), t, np.nan)
        X = t * (2.0 * np.asarray(x, dtype=np.float64) / width - 1.0) * T * width / height
        Z = self.eye_z - t * (s * q + c)
        return np.stack(np.broadcast_arrays((X + self.half) / (2.0 * self.half),
                                            (self.half - Z) / (2.0 * self.half)), axis=-1)

    def row_of_v(self, v: np.ndarray, height: int) -> np.ndarray:
        """Window y of the image row where the plane's v takes each value (v-lines are rows)."""
        Z = self.half - 2.0 * self.half * np.asarray(v, dtype=np.float64)
        g = (self.eye_z - Z) / self.eye_height   # Z = eye_z - t (s q + c) with t = h / (s - c q)
        s, c = math.sin(math.radians(self.pitch)), math.cos(math.radians(self.pitch))
        q = (g * s - c) / (s + g * c)
        return (1.0 - q / math.tan(math.radians(self.fov_y) / 2.0)) * height / 2.0

    def x_of_u(self, u: np.ndarray, y: np.ndarray, width: int, height: int) -> np.ndarray:
        """Window x where the line of constant u crosses window row y (linear in y)."""
        X = 2.0 * self.half * np.asarray(u, dtype=np.float64) - self.half
        T = math.tan(math.radians(self.fov_y) / 2.0)
        x_ndc = X / (self._t(y, height) * T * width / height)
        return (1.0 + x_ndc) * width / 2.0


def _clamped_line_mean(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Mean over s in [0, 1] of clamp(p + (q - p) s, 0, 1), in closed form (float64).

    The line is below 0, in [0, 1] and above 1 on three intervals of s (split at the s where it
    crosses 0 and 1): the middle one contributes its length times the line's mean there, the
    upper one its length. p == q is the constant clamp(p)."""
    p, q = np.broadcast_arrays(np.asarray(p, dtype=np.float64), np.asarray(q, dtype=np.float64))
    dz = q - p
    flat = dz == 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        s0 = np.clip(np.where(flat, 0.0, -p / dz), 0.0, 1.0)           # z = 0
        s1 = np.clip(np.where(flat, 0.0, (1.0 - p) / dz), 0.0, 1.0)    # z = 1
    lo, hi = np.minimum(s0, s1), np.maximum(s0, s1)
    middle = (hi - lo) * np.clip(p + dz * 0.5 * (lo + hi), 0.0, 1.0)
    above = np.where(dz > 0.0, 1.0 - s1, s1)                          # where z > 1
    return np.where(flat, np.clip(p, 0.0, 1.0), middle + above)


def checker_box_filter(plane: GrazingPlane, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """The exact box-filtered image of the checkerboard: the mean of the checker function over
    each pixel square (window coordinates, uniform weight), in float64.

    Returns (image (h, w) in [0, 1]; full (h, w) bool: the pixel square lies wholly on the plane,
    so the reference is defined without the background; only those pixels are compared).

    Exact by construction: rows of constant v are image rows (``row_of_v``), so a pixel row is
    cut into bands in which v stays in one check; inside a band each line of constant u = k / N
    is a segment x_k(y) linear in y (``x_of_u``), the length of [j, j + 1] between lines k and
    k + 1 is clamp(x_{k+1}) - clamp(x_k), and the integral over the band of a clamped linear
    function is ``_clamped_line_mean`` times the band's height. Checked in tests against dense
    supersampling of the checker function.
    """
    n = plane.checks
    corner_uv = plane.uv(*np.meshgrid(np.arange(width + 1.0), np.arange(height + 1.0)), width, height)
    inside = np.all((corner_uv >= 0.0) & (corner_uv <= 1.0), axis=-1)  # NaN (above horizon) fails
    full = inside[:-1, :-1] & inside[:-1, 1:] & inside[1:, :-1] & inside[1:, 1:]
    image = np.zeros((height, width))
    v_rows = plane.row_of_v(np.arange(n + 1) / n, height)
    ks = np.arange(n + 1)
    cols = np.arange(width, dtype=np.float64)
    for i in range(height):
        if not full[i].any():
            continue
        cuts = np.concatenate(([i], np.sort(v_rows[(v_rows > i) & (v_rows < i + 1)]), [i + 1.0]))
        for ya, yb in zip(cuts[:-1], cuts[1:]):  # v depends on y alone: read it mid-band
            l = int(np.floor(n * plane.uv(np.array(width / 2.0), np.array(0.5 * (ya + yb)),
                                          width, height)[..., 1]))
            xa = plane.x_of_u(ks / n, np.array(ya), width, height)
            xb = plane.x_of_u(ks / n, np.array(yb), width, height)
            # (n + 1, w): integral over the band of clamp(x_k(y) - j, 0, 1)
            integral = (yb - ya) * _clamped_line_mean(xa[:, None] - cols, xb[:, None] - cols)
            strips = integral[1:] - integral[:-1]              # check column k between k and k + 1
            image[i] += strips[(ks[:-1] + l) % 2 == 1].sum(axis=0)
    return np.where(full, image, 0.0), full


# ------------------------------------------------------------------------- reference: shading

def _unit(a: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(a, axis=-1, keepdims=True)
    return np.divide(a, norm, out=np.zeros_like(a), where=norm > 0.0)


def shade(model: str, normal: np.ndarray, position: np.ndarray, eye: Sequence[float],
          light_dir: Sequence[float], light_rgb: float, ambient: float, material: Any) -> np.ndarray:
    """(..., 3) linear radiance of a grey ``material`` (softrast.Material, no emissive) under one
    directional light (unit ``light_dir`` towards the light, radiance ``light_rgb``) and an
    ambient light, as softrast's models define it (the table in softrast.material; pbr: pyrender
    0.1.45's compute_brdf, PBR_NOTES.md), at unit ``normal`` (..., 3) and world ``position``
    (..., 3) seen from ``eye``. Grey, so one channel is computed and repeated."""
    n = normal
    l = np.asarray(light_dir, dtype=np.float64)
    v = _unit(np.asarray(eye, dtype=np.float64) - position)
    nl = n @ l
    kd = material.base_color[0] if material.kd is None else material.kd[0]
    ka = kd if material.ka is None else material.ka[0]
    ks, p = material.ks[0], material.shininess
    if model == "normal":
        return (n + 1.0) / 2.0
    if model == "lambert":
        out = ka * ambient + kd * light_rgb * np.maximum(nl, 0.0)
    elif model in ("phong", "blinn_phong"):
        if model == "phong":
            s = np.maximum(np.einsum("...k,...k->...", 2.0 * nl[..., None] * n - l, v), 0.0)
        else:
            s = np.maximum(np.einsum("...k,...k->...", n, _unit(l + v)), 0.0)
        out = (ka * ambient + kd * light_rgb * np.maximum(nl, 0.0)
               + np.where(nl > 0.0, ks * light_rgb * s ** p, 0.0))
    elif model == "pbr":
        base = material.base_color[0]
        rough = min(max(material.roughness, 0.04), 1.0)
        metal = min(max(material.metallic, 0.0), 1.0)
        c_diff = base * 0.96 * (1.0 - metal)
        f0 = 0.04 * (1.0 - metal) + base * metal
        h = _unit(l + v)
        nlc = np.clip(nl, 0.001, 1.0)
        nv = np.clip(np.abs(np.einsum("...k,...k->...", n, v)), 0.001, 1.0)
        nh = np.clip(np.einsum("...k,...k->...", n, h), 0.0, 1.0)
        vh = np.clip(np.einsum("...k,...k->...", v, h), 0.0, 1.0)
        F = f0 + (1.0 - f0) * (1.0 - vh) ** 5
        k = (rough + 1.0) ** 2 / 8.0
        G = (nv / (nv * (1.0 - k) + k)) * (nlc / (nlc * (1.0 - k) + k))
        a2 = rough ** 4
        D = a2 / (math.pi * (nh * nh * (a2 - 1.0) + 1.0) ** 2)
        brdf = (1.0 - F) * c_diff / math.pi + F * G * D / (4.0 * nlc * nv + 0.001)
        out = nlc * light_rgb * brdf + base * ambient
    else:
        raise ValueError(f"no closed form for shading model {model!r}")
    return np.repeat(out[..., None], 3, axis=-1)


def supersampled_render(renderer: Any, scene: Any, camera_args: dict[str, Any], n: int = 16,
                        output: str = "radiance", **options: Any) -> np.ndarray:
    """The mean of ``output`` over n x n renders whose pixel centres are shifted to the centres
    of an n x n grid of sub-pixels: a box-filtered image where no closed form exists (its rows
    carry the label ``render_16x16_supersampled``). float64, (h, w, ...).

    camera_args : an IntrinsicsCamera's (fx, fy, cx, cy, width, height, near, far, pose) for the
    unshifted view, OpenGL convention (cx, cy from the image's top-left corner). The grid of
    offsets is symmetric about the pixel centre, so the mean does not depend on the sign with
    which a principal point shift moves the image.
    """
    from .camera import IntrinsicsCamera

    a = dict(camera_args)
    pose = a.pop("pose")
    offsets = (np.arange(n) + 0.5) / n - 0.5
    cameras = []
    for oy in offsets:
        for ox in offsets:
            cam = IntrinsicsCamera(a["fx"], a["fy"], a["cx"] - ox, a["cy"] - oy, a["width"], a["height"],
                                   near=a["near"], far=a["far"], convention="opengl")
            cam.pose = pose
            cameras.append(cam)
    total = None
    for frame in renderer.render_many(scene, cameras, outputs=(output,), **options):
        image = getattr(frame, output).astype(np.float64)
        total = image if total is None else total + image
    return total / len(cameras)


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

# The sphere scene: a unit sphere 5 units in front of the camera (its silhouette fills ~3/4 of
# the image height), one grey directional light from the upper left front and an ambient light,
# so a white lambert sphere's radiance is in [0.2, 1] on its lit side.
_FOV = 30.0
_DISTANCE = 5.0
_LIGHT_DIR = tuple(np.array([-1.0, 1.0, 1.0]) / math.sqrt(3.0))  # towards the light
_LIGHT = 0.8
_AMBIENT = 0.2
_MODELS = ("lambert", "phong", "blinn_phong", "pbr", "normal")  # those with a closed form here


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


def _light_pose(direction: Sequence[float]) -> np.ndarray:
    """A light pose whose +z axis is ``direction`` (unit, towards the light): lights shine
    along their -z."""
    z = np.asarray(direction, dtype=np.float64)
    x = np.cross((0.0, 1.0, 0.0), z)
    x /= np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2] = x, np.cross(z, x), z
    return pose


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles in degrees between rows of unit vectors: 2 atan2(|a - b|, |a + b|), accurate for
    small angles (arccos of the dot product is not, below ~0.03 degrees)."""
    return np.degrees(2.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1)))


def _sphere_camera(width: int, height: int) -> Any:
    """The sphere scene's camera: at (0, 0, _DISTANCE) looking down -z at the origin."""
    from .camera import PerspectiveCamera

    camera = PerspectiveCamera(fov_y=_FOV, width=width, height=height, near=0.1, far=100.0)
    pose = np.eye(4)
    pose[2, 3] = _DISTANCE
    camera.pose = pose
    return camera


def _icosphere(subdivisions: int, uvs: bool = False) -> Any:
    """A trimesh icosphere as a softrast Mesh with its exact normals (its vertices, which lie on
    the unit sphere) and, if asked, longitude-latitude uvs."""
    import trimesh

    from .mesh import Mesh

    tm = trimesh.creation.icosphere(subdivisions=subdivisions)
    v = np.asarray(tm.vertices)
    uv = None
    if uvs:
        uv = np.stack([np.arctan2(v[:, 0], v[:, 2]) / (2.0 * math.pi) + 0.5,
                       np.arcsin(np.clip(v[:, 1], -1.0, 1.0)) / math.pi + 0.5], axis=1)
    return Mesh(v, tm.faces, normals=v, uvs=uv)


class _Sphere:
    """The sphere scene at one image size: its exact references (computed once) and meshes."""

    reference_coverage = "exact disk area per pixel"
    reference_points = "exact disk, pixel centres"
    reference_hit = "exact ray-sphere hit, pixel centres"

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self.radius_px = sphere_radius_px(_FOV, height, _DISTANCE)
        self.coverage = disk_coverage(width, height, self.radius_px)
        self.depth, self.position, self.normal = sphere_hit(width, height, _FOV, _DISTANCE)
        self.inside = self.depth > 0.0
        self.camera = _sphere_camera(width, height)
        self._meshes: dict[int, Any] = {}
        self._colour: dict[str, np.ndarray] = {}

    def mesh(self, subdivisions: int) -> Any:
        """The icosphere (trimesh) as a softrast Mesh with its exact normals (the vertices)."""
        if subdivisions not in self._meshes:
            self._meshes[subdivisions] = _icosphere(subdivisions)
        return self._meshes[subdivisions]

    @staticmethod
    def material(model: str = "lambert") -> Any:
        from .material import Material

        return Material(base_color=(1.0, 1.0, 1.0), ks=(0.5, 0.5, 0.5), shininess=32.0,
                        roughness=0.5, metallic=0.0, model=model)

    def scene(self, subdivisions: int, model: str = "lambert") -> Any:
        from .light import DirectionalLight
        from .scene import Scene

        scene = Scene(ambient_light=(_AMBIENT,) * 3)
        scene.add(self.mesh(subdivisions), material=self.material(model))
        scene.add(DirectionalLight(intensity=_LIGHT), pose=_light_pose(_LIGHT_DIR))
        return scene

    def colour(self, model: str) -> np.ndarray:
        """(h, w, 3) float64: the model's closed form at each pixel centre's hit, 0 = miss."""
        if model not in self._colour:
            c = shade(model, self.normal, self.position, (0.0, 0.0, _DISTANCE), _LIGHT_DIR, _LIGHT,
                      _AMBIENT, self.material(model))
            self._colour[model] = np.where(self.inside[..., None], c, 0.0)
        return self._colour[model]

    def camera_args(self) -> dict[str, Any]:
        f = (self.height / 2.0) / math.tan(math.radians(_FOV) / 2.0)
        return {"fx": f, "fy": f, "cx": self.width / 2.0, "cy": self.height / 2.0,
                "width": self.width, "height": self.height, "near": 0.1, "far": 100.0,
                "pose": np.asarray(self.camera.pose)}

    def geometry_metrics(self, frame: Any) -> list[tuple[str, float, str, str, str]]:
        """(metric, error, unit, reference, better) of coverage, depth and normals."""
        mask = frame.mask
        err = np.abs(mask - self.coverage)
        considered = ((self.coverage > 0.0) & (self.coverage < 1.0)) | (err > 0.0)
        area = math.pi * self.radius_px ** 2
        both = mask & self.inside
        d_err = np.abs(frame.depth[both].astype(np.float64) - self.depth[both])
        n_render = frame.normal[both].astype(np.float64)
        n_render /= np.linalg.norm(n_render, axis=-1, keepdims=True)
        angles = _angle_deg(n_render, self.normal[both])
        cov, pts, hit = self.reference_coverage, self.reference_points, self.reference_hit
        return [
            ("coverage_mean", float(err[considered].mean()), "pixel fraction", cov, "lower"),
            ("coverage_max", float(err.max()), "pixel fraction", cov, "lower"),
            ("area_rel", abs(float(mask.sum()) - area) / area, "relative", cov, "lower"),
            ("mask_mismatch_px", float(np.count_nonzero(mask != self.inside)), "pixels", pts, "lower"),
            ("depth_mean", float(d_err.mean()), "scene units", hit, "lower"),
            ("depth_max", float(d_err.max()), "scene units", hit, "lower"),
            ("depth_rel_max", float((d_err / self.depth[both]).max()), "relative", hit, "lower"),
            ("normal_mean_deg", float(angles.mean()), "degrees", hit, "lower"),
            ("normal_max_deg", float(angles.max()), "degrees", hit, "lower"),
        ]


def _colour_metrics(image: np.ndarray, reference: np.ndarray, label: str,
                    region: np.ndarray | None = None) -> list[tuple[str, float, str, str, str]]:
    """(metric, error, unit, reference, better): RMSE, max error, PSNR and SSIM (scikit-image)
    of a grey linear image against its reference, over ``region`` (default: every pixel).

    The scenes are grey (white light, white or black-and-white materials), so one channel is
    compared. data_range is the reference's range. SSIM is computed on the region's bounding
    box with the pixels outside the region taken from the reference (they add no error)."""
    metrics = _require("skimage.metrics", "scikit-image")
    img = np.asarray(image, dtype=np.float64)
    ref = np.asarray(reference, dtype=np.float64)
    img = img[..., 0] if img.ndim == 3 else img
    ref = ref[..., 0] if ref.ndim == 3 else ref
    if region is None:
        region = np.ones(ref.shape, dtype=bool)
    data_range = float(ref[region].max() - min(ref[region].min(), 0.0))
    diff = img[region] - ref[region]
    psnr = metrics.peak_signal_noise_ratio(ref[region], img[region], data_range=data_range)
    rows, cols = np.nonzero(region)
    box = (slice(rows.min(), rows.max() + 1), slice(cols.min(), cols.max() + 1))
    ssim = metrics.structural_similarity(ref[box], np.where(region, img, ref)[box], data_range=data_range)
    return [("rmse", float(np.sqrt(np.mean(diff ** 2))), "linear radiance", label, "lower"),
            ("max_abs", float(np.abs(diff).max()), "linear radiance", label, "lower"),
            ("psnr_db", float(psnr), "dB", label, "higher"),
            ("ssim", float(ssim), "", label, "higher")]


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
    from .render import Renderer

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


class _Checker:
    """The grazing checkerboard at one image size: the exact box-filtered reference and a scene
    per texture (one per max_anisotropy)."""

    reference = "exact box filter of the checker function"

    def __init__(self, width: int, height: int) -> None:
        from .camera import PerspectiveCamera

        self.plane = GrazingPlane()
        self.width, self.height = width, height
        self.image, self.full = checker_box_filter(self.plane, width, height)
        self.camera = PerspectiveCamera(fov_y=self.plane.fov_y, width=width, height=height, near=0.05, far=50.0)
        self.camera.pose = self.plane.pose()
        self._texels = self.plane.texture_image()

    def scene(self, max_anisotropy: int = 16) -> Any:
        from .material import Material
        from .mesh import Mesh
        from .scene import Scene
        from .texture import Texture

        h = self.plane.half
        texture = Texture(self._texels, srgb=False, max_anisotropy=max_anisotropy)
        plane = Mesh([[-h, 0, -h], [h, 0, -h], [h, 0, h], [-h, 0, h]], [[0, 2, 1], [0, 3, 2]],
                     uvs=[[0, 1], [1, 1], [1, 0], [0, 0]],
                     material=Material(base_color=(1, 1, 1), base_color_texture=texture, model="unlit"))
        scene = Scene()
        scene.add(plane)
        return scene

    def metrics(self, frame: Any) -> list[tuple[str, float, str, str, str]]:
        return _colour_metrics(frame.radiance, self.image, self.reference, region=self.full)


def _sweep_filter(s: Settings, checker: _Checker, renderer: Any) -> list[Row]:
    from .texture import FILTERS

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


def _shadow_scene(sphere: _Sphere, subdivisions: int, shadows: Any, resolution: int = 2048) -> Any:
    """The sphere (lambert) over a backdrop plane at z = -1.2 facing the camera, its light
    casting ``shadows``: the sphere's shadow falls on the backdrop's lower right."""
    from .light import DirectionalLight
    from .material import Material
    from .mesh import Mesh
    from .scene import Scene

    scene = Scene(ambient_light=(_AMBIENT,) * 3)
    scene.add(sphere.mesh(subdivisions), material=sphere.material("lambert"))
    h, z = 3.0, -1.2
    scene.add(Mesh([[-h, -h, z], [h, -h, z], [h, h, z], [-h, h, z]], [[0, 1, 2], [0, 2, 3]]),
              material=Material(base_color=(1.0, 1.0, 1.0), model="lambert"))
    scene.add(DirectionalLight(intensity=_LIGHT, shadows=shadows, shadow_resolution=resolution),
              pose=_light_pose(_LIGHT_DIR))
    return scene


def _sweep_shadow_resolution(s: Settings, sphere: _Sphere, renderer: Any) -> list[Row]:
    """Shadow maps of growing resolution against the exact method (a ray per pixel), on the
    sphere casting onto a backdrop: radiance RMSE, and the share of pixels whose radiance
    differs by over 0.05 (lit against shadowed: the maps' filtered edges and their texels).
    The value "exact" is the reference itself (error 0), for its time."""
    from .render import Renderer

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
    from .light import PointLight
    from .material import Material
    from .render import Renderer
    from .scene import Scene
    from .texture import Texture

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


# ----------------------------------------------------------------------------------- the report

def pareto_front(points: Sequence[tuple[float, float]]) -> list[int]:
    """Indices of the (time, error) points no other point beats on both (lower is better for
    both), in order of time: the fastest way to each error level."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def _front_groups(rows: Sequence[Row]) -> dict[tuple[str, str, str], list[Row]]:
    """Rows by (scene, metric, reference): the points a Pareto front may compare (one reference,
    one metric). "higher is better" metrics are left out (their error is not an error), and so
    is the threads knob (it trades time alone; its rows repeat other knobs' configurations)."""
    groups: dict[tuple[str, str, str], list[Row]] = {}
    for r in rows:
        if r.better == "lower" and math.isfinite(r.error) and r.knob != "threads":
            groups.setdefault((r.scene, r.metric, r.reference), []).append(r)
    return groups


# The plot's panels and the Markdown's Pareto fronts: (scene, metric, title).
_PANELS = (
    ("sphere", "coverage_mean", "sphere: coverage error per edge pixel\n(mean |alpha - exact area|; alpha = mask without AA)"),
    ("sphere", "depth_max", "sphere: max depth error (scene units)\nvs exact ray-sphere hit"),
    ("sphere", "normal_mean_deg", "sphere: mean normal error (degrees)\nvs exact normal"),
    ("sphere", "rmse", "sphere: colour RMSE, lambert (linear)\nvs the closed form at pixel centres"),
    ("sphere", "rmse_box", "sphere: colour RMSE vs box filter\n(16x16-supersampled render)"),
    ("checker", "rmse", "grazing checkerboard: RMSE (linear)\nvs exact box filter"),
)


def _fmt(x: Any) -> str:
    if isinstance(x, float):
        return f"{x:.3g}" if math.isfinite(x) else str(x)
    return str(x)


def _write_csv(path: str, rows: Sequence[Row]) -> None:
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=CSV_COLUMNS)
        writer.writeheader()
        for r in rows:
            d = r.as_dict()
            d["error"] = repr(float(r.error))
            d["time_ms"] = f"{r.time_ms:.4f}"
            d["time_spread_ms"] = f"{r.time_spread_ms:.4f}"
            writer.writerow(d)


def _write_markdown(path: str, rows: Sequence[Row], costs: Sequence[dict[str, Any]], header: Sequence[str],
                    settings: Settings) -> None:
    lines = ["# softrast: error against run time", ""] + list(header) + [""]
    lines += ["References (exact unless labelled): the sphere's silhouette is a disk, integrated over "
              "each pixel square in closed form; depth, point and normal are the exact ray-sphere hit at "
              "each pixel centre, and colour the shading model's formula there; the checkerboard is "
              f"integrated exactly over each pixel square. `{_SUPERSAMPLED}` marks the one reference "
              "that is a render (the box-filtered shaded sphere has no closed form). Errors: lower is "
              "better except psnr_db and ssim. Time: of a render of the linear colour alone, median of the "
              "timed renders (interquartile range); the machine's load shows in it.", ""]
    knobs: dict[str, list[Row]] = {}
    for r in rows:
        knobs.setdefault(r.knob, []).append(r)
    for knob, krows in knobs.items():
        metrics = list(dict.fromkeys(r.metric for r in krows))
        values = list(dict.fromkeys(r.value for r in krows))
        scene = krows[0].scene
        lines += [f"## {knob} ({scene})", ""]
        by_ref: dict[str, list[str]] = {}
        units: dict[str, str] = {}
        for r in krows:
            if r.metric not in by_ref.setdefault(r.reference, []):
                by_ref[r.reference].append(r.metric)
            units[r.metric] = r.unit
        lines += ["References: " + "; ".join(f"{', '.join(m)} against {ref}" for ref, m in by_ref.items())
                  + ". Units: " + "; ".join(f"{m} {u}" for m, u in units.items() if u) + ".", ""]
        lines.append("| value | setting | time ms (IQR) | " + " | ".join(metrics) + " |")
        lines.append("|---" * (3 + len(metrics)) + "|")
        for v in values:
            vrows = {r.metric: r for r in krows if r.value == v}
            first = next(iter(vrows.values()))
            lines.append(f"| {v} | {first.setting} | {first.time_ms:.3f} ({first.time_spread_ms:.3f}) | "
                         + " | ".join(_fmt(vrows[m].error) if m in vrows else "" for m in metrics) + " |")
        lines.append("")
    lines += ["## Pareto fronts", "",
              "The configurations no other beats on both time and error, fastest first, per scene, "
              "metric and reference (every knob's rows together).", ""]
    groups = _front_groups(rows)
    for scene, metric, _ in _PANELS:
        for (g_scene, g_metric, ref), grows in groups.items():
            if (g_scene, g_metric) != (scene, metric) or len(grows) < 2:
                continue
            front = pareto_front([(r.time_ms, r.error) for r in grows])
            items = ", ".join(f"{grows[i].knob}={grows[i].value} ({grows[i].time_ms:.3f} ms, "
                              f"{_fmt(grows[i].error)})" for i in front)
            lines += [f"- {scene} {metric} against {ref}: {items}"]
    width, height = settings.cost_size
    lines += ["", "## What a scene pays for", "",
              f"The sphere scene at {width}x{height} (ico{settings.cost_subdivision}, "
              f"{20 * 4 ** settings.cost_subdivision} faces; a mesh without a material, "
              "lambert under the headlight, unless stated), each feature off, then on; the difference "
              "is against the group's first row.", ""]
    lines += ["| feature | setting | time ms (IQR) | difference ms |", "|---|---|---|---|"]
    for c in costs:
        lines.append(f"| {c['group']} | {c['setting']} | {c['time_ms']:.3f} ({c['time_spread_ms']:.3f}) | "
                     f"{c['delta_ms']:+.3f} |")
    lines += [""]
    with open(path, "w") as f:
        f.write("\n".join(lines))


def _log_ticks(axis: Any) -> None:
    """Plain labels (0.2, 5, 1e-05) on a log axis: every decade, also 2 and 5 when the axis spans
    less than three decades, evenly spaced values when it spans less than one (matplotlib's
    default labels every minor tick of a short axis, overlapping)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, MaxNLocator, NullFormatter

    lo, hi = axis.get_view_interval()
    if hi / lo < 10.0:
        axis.set_major_locator(MaxNLocator(nbins=5))
    else:
        axis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0) if hi / lo < 1e3 else (1.0,)))
    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


_NOT_PLOTTED = ("shading_model",)  # each model against its own closed form: no common curve


def _plot(path: str, rows: Sequence[Row], title: str) -> None:
    """error_vs_time.png: one log-log panel per (scene, metric) of _PANELS, one curve per knob
    (points in the knob's order, labelled with its values, horizontal bars the time's IQR), the
    Pareto front of the panel's main reference as a black dashed staircase through circled points.
    Zero errors (no log) and the knobs of _NOT_PLOTTED are left to the tables."""
    _require("matplotlib", "matplotlib")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(15, 9.5), dpi=110)
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 3).ravel()
    colours = {"tessellation": "tab:blue", "frequency": "tab:orange", "shading_model": "tab:green",
               "threads": "tab:red", "texture_filter": "tab:purple", "max_anisotropy": "tab:brown",
               "msaa": "tab:cyan", "ssaa": "tab:pink", "shadow_resolution": "tab:olive"}
    groups = _front_groups(rows)
    for ax, (scene, metric, panel_title) in zip(axes, _PANELS):
        prows = [r for r in rows if r.scene == scene and r.metric == metric and r.error > 0.0
                 and r.knob not in _NOT_PLOTTED]
        knobs = list(dict.fromkeys(r.knob for r in prows))
        for knob in knobs:
            krows = [r for r in prows if r.knob == knob]
            x = [r.time_ms for r in krows]
            y = [r.error for r in krows]
            spread = [r.time_spread_ms / 2.0 for r in krows]
            ax.errorbar(x, y, xerr=spread, marker="o", ms=4, lw=1.2, capsize=2,
                        color=colours.get(knob), label=knob)
            for r in krows:
                ax.annotate(str(r.value), (r.time_ms, r.error), textcoords="offset points", xytext=(4, 3),
                            fontsize=6.5, color=colours.get(knob))
        # The front over the rows that share the panel's most common reference.
        refs = [r.reference for r in prows]
        if refs:
            main_ref = max(set(refs), key=refs.count)
            grows = [r for r in groups.get((scene, metric, main_ref), []) if r.error > 0.0]
            front = [grows[i] for i in pareto_front([(r.time_ms, r.error) for r in grows])]
            if len(front) >= 1:
                ax.plot([r.time_ms for r in front], [r.error for r in front], "k--", lw=0.9,
                        drawstyle="steps-post", label="Pareto front", zorder=0)
                ax.scatter([r.time_ms for r in front], [r.error for r in front], s=90, facecolors="none",
                           edgecolors="k", linewidths=1.0, zorder=3)
        ax.set_xscale("log")
        ax.set_yscale("log")
        _log_ticks(ax.xaxis)
        _log_ticks(ax.yaxis)
        ax.set_title(panel_title, fontsize=9.5)
        ax.set_xlabel("render time, ms (median; bars: IQR)", fontsize=8)
        ax.tick_params(labelsize=7.5)
        ax.grid(True, which="both", lw=0.3, alpha=0.5)
        if knobs:
            ax.legend(fontsize=7.5, loc="best")
    fig.suptitle(title, fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.96))
    fig.savefig(path)


def measure(settings: Settings = QUICK, log: Callable[[str], Any] | None = None
            ) -> tuple[list[Row], list[dict[str, Any]]]:
    """Run every sweep and the feature costs; returns (rows, costs) without writing anything."""
    from .render import Renderer

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
    from . import __version__

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
    from .render import Renderer

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
