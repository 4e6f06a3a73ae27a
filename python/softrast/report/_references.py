"""The report's exact references (NumPy float64): the sphere's silhouette, integrated over each
pixel square in closed form (``disk_coverage``), and its ray-sphere hit at each pixel centre
(``sphere_hit``); the grazing checkerboard's exact box filter (``checker_box_filter``); the
shading models' formulas at those hits (``shade``, softrast.reference.shading under the report's
one light); and, where no closed form exists, a 16 x 16-supersampled render
(``supersampled_render``)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..camera import IntrinsicsCamera
from ..reference import shading


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

def shade(model: str, normal: np.ndarray, position: np.ndarray, eye: Sequence[float],
          light_dir: Sequence[float], light_rgb: float, ambient: float, material: Any) -> np.ndarray:
    """(..., 3) linear radiance of ``material`` (softrast.Material) under one directional light
    (unit ``light_dir`` towards the light, radiance ``light_rgb``) and an ambient light, at unit
    ``normal`` (..., 3) and world ``position`` (..., 3) seen from ``eye``: softrast's models as
    softrast.reference.shading.radiance computes them (pbr: pyrender 0.1.45's compute_brdf,
    docs/pbr_notes.md)."""
    if model not in ("normal", "lambert", "phong", "blinn_phong", "pbr"):
        raise ValueError(f"no closed form for shading model {model!r}")
    n = np.asarray(normal, dtype=np.float64)
    light = (shading.DIRECTIONAL, (float(light_rgb),) * 3, (0.0, 0.0, 0.0),
             tuple(-np.asarray(light_dir, dtype=np.float64)), False, 0.0, 1.0)
    out = shading.radiance(model, n.reshape(-1, 3), np.asarray(position, dtype=np.float64).reshape(-1, 3),
                           material.base_color[:3], material, [light], (ambient,) * 3, eye)
    return out.reshape(n.shape)


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
