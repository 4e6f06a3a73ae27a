"""Lens distortion: OpenCV's camera model (k1..k6 radial, p1 p2 tangential, s1..s4 thin prism)
for ``IntrinsicsCamera(..., dist=)``.

A rasterizer draws straight edges; a distorted lens bends them. So a distorted camera is rendered
in two steps, each exact where it can be:

1. Every output pixel's own ray. The centre of pixel (row i, col j) is the distorted point
   (u, v) = (j, i); its ray is the undistorted normalized point (x', y') that OpenCV's model
   maps there, found by Newton's method in float64 (to 1e-12, checked). Pixels the model
   cannot reach (beyond the fold of a strong barrel distortion) see nothing: background.
2. An ideal pinhole view with the same K, covering every such ray with a margin and
   ``oversample`` times finer (so ``oversample`` squared times as many pixels), rendered by the
   ordinary pipeline. Each output pixel then takes, at its ray's exact point in that view:
   - ``color`` and ``radiance``: the bilinear interpolation of the four nearest samples (what
     ``cv2.remap`` with INTER_LINEAR does);
   - ``depth``, ``ray_depth``, ``position`` and ``barycentric``: the nearest sample's triangle
     intersected with the pixel's own ray in float64, so a visible point reprojects through
     ``cv2.projectPoints`` to its pixel centre (to float32 rounding: tests/test_distortion.py).
     Near a triangle's edge the ray may pass just outside it (by less than the silhouette bound
     below): the point is then on the triangle's plane, and the barycentrics are clamped to
     [0, 1] and renormalized;
   - every other output (ids, mask, normal, uv, coverage): the nearest sample.
   Which surface a pixel sees is the nearest sample's: a silhouette or an id boundary is off
   by at most half a sample diagonal, 0.71 / oversample ideal pixels (tests/test_distortion.py).

Cost: the render of the larger, finer view (``oversample=2``, the default, renders about four to
five times the output's pixels) plus the per-pixel gathers in NumPy; the rays are computed once
per camera and cached. ``benchmarks/bench_stages.py`` measures it.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from ._checks import real_array

__all__ = ["check_dist", "distort", "undistort", "render_distorted"]

# OpenCV's coefficient order: (k1, k2, p1, p2[, k3[, k4, k5, k6[, s1, s2, s3, s4[, tauX, tauY]]]]).
_SIZES = (4, 5, 8, 12, 14)
_NEWTON_STEPS = 60
_TOLERANCE = 1e-12  # normalized units: 1e-9 px at a focal length of 1000 px


def check_dist(dist: Any) -> npt.NDArray[np.float64] | None:
    """The 12 coefficients (k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4) of ``dist``, or None
    for no distortion (None or all zeros). A tilted sensor (tauX, tauY non-zero) is refused."""
    if dist is None:
        return None
    d = real_array(dist, "dist").reshape(-1)
    if d.size not in _SIZES:
        raise ValueError(f"dist must hold 4, 5, 8, 12 or 14 OpenCV coefficients (k1, k2, p1, p2[, k3"
                         f"[, k4, k5, k6[, s1..s4[, tauX, tauY]]]]), got {d.size}")
    if not np.isfinite(d).all():
        raise ValueError(f"dist must be finite, got {d.tolist()}")
    if d.size == 14 and np.any(d[12:] != 0.0):
        raise ValueError(f"dist: a tilted sensor (tauX, tauY = {d[12]}, {d[13]}) is not supported; "
                         "only the radial, tangential and thin-prism terms are")
    full = np.zeros(12)
    full[:min(d.size, 12)] = d[:12]
    if not full.any():
        return None
    full.setflags(write=False)
    return full


def distort(x: npt.NDArray[np.float64], y: npt.NDArray[np.float64],
            d: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """OpenCV's distortion of normalized points (x, y) = (X / Z, Y / Z): ``cv2.projectPoints``
    before K."""
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = d
    r2 = x * x + y * y
    radial = (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1.0 + r2 * (k4 + r2 * (k5 + r2 * k6)))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) + r2 * (s1 + s2 * r2)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y + r2 * (s3 + s4 * r2)
    return xd, yd


def _jacobian(x: npt.NDArray[np.float64], y: npt.NDArray[np.float64], d: npt.NDArray[np.float64]) -> tuple[Any, ...]:
    """d(xd, yd) / d(x, y), and the radial denominator (the model is valid where it is > 0)."""
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = d
    r2 = x * x + y * y
    num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
    radial = num / den
    dnum = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)
    dden = k4 + r2 * (2.0 * k5 + 3.0 * k6 * r2)
    dradial = (dnum * den - num * dden) / (den * den)  # d radial / d r2
    sx = s1 + 2.0 * s2 * r2  # d (s1 r2 + s2 r2^2) / d r2
    sy = s3 + 2.0 * s4 * r2
    a = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x + 2.0 * x * sx
    b = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y + 2.0 * y * sx
    c = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y + 2.0 * x * sy
    e = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x + 2.0 * y * sy
    return a, b, c, e, den


def undistort(xd: npt.ArrayLike, yd: npt.ArrayLike, d: npt.NDArray[np.float64]) -> tuple[Any, Any, Any]:
    """(x, y, valid): the normalized points OpenCV's model distorts to (xd, yd), by Newton's
    method from (xd, yd) in float64. ``valid`` is False where no such point was found to 1e-12
    or where the model folds (its Jacobian is not positive there: a second, outer solution of a
    strong barrel distortion, which a lens does not see); x and y are NaN there."""
    xd = np.asarray(xd, dtype=np.float64)
    yd = np.asarray(yd, dtype=np.float64)
    x, y = xd.copy(), yd.copy()
    with np.errstate(all="ignore"):  # diverging points become NaN and are marked invalid
        fx, fy = distort(x, y, d)
        fx, fy = fx - xd, fy - yd
        res = np.hypot(fx, fy)
        for _ in range(_NEWTON_STEPS):
            live = ~(res <= _TOLERANCE * (1.0 + np.hypot(xd, yd)))
            if not live.any():
                break
            a, b, c, e, _den = _jacobian(x, y, d)
            det = a * e - b * c
            dx = (e * fx - b * fy) / det
            dy = (a * fy - c * fx) / det
            step = np.where(live, 1.0, 0.0)
            nx, ny = x - step * dx, y - step * dy
            gx, gy = distort(nx, ny, d)
            gx, gy = gx - xd, gy - yd
            new = np.hypot(gx, gy)
            for _half in range(8):  # damped: halve a step that does not reduce the residual
                worse = live & ~(new < res)
                if not worse.any():
                    break
                step = np.where(worse, step * 0.5, step)
                nx, ny = x - step * dx, y - step * dy
                gx, gy = distort(nx, ny, d)
                gx, gy = gx - xd, gy - yd
                new = np.hypot(gx, gy)
            ok = live & (new < res)
            x, y = np.where(ok, nx, x), np.where(ok, ny, y)
            fx, fy, res = np.where(ok, gx, fx), np.where(ok, gy, fy), np.where(ok, new, res)
        valid = (res <= _TOLERANCE * (1.0 + np.hypot(xd, yd))) & np.isfinite(x) & np.isfinite(y)
        # The lens sees the sheet of the model around the axis: the Jacobian stays positive all
        # the way from the centre to the point (beyond a fold, or where the radial factor turns
        # negative and mirrors points through the axis, the model describes no real ray).
        for f in (1.0, 0.875, 0.75, 0.625, 0.5, 0.375, 0.25, 0.125):
            a, b, c, e, den = _jacobian(f * x, f * y, d)
            valid &= (a * e - b * c > 0.0) & (den > 0.0)
        r2 = x * x + y * y
        k1, k2, _, _, k3 = d[:5]
        valid &= (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))) > 0.0
    x = np.where(valid, x, np.nan)
    y = np.where(valid, y, np.nan)
    return x, y, valid


class _Rays:
    """Per camera and size: each output pixel's ray and where it falls in the ideal view."""

    def __init__(self, camera: Any, width: int, height: int, oversample: int) -> None:
        from . import _core
        from .camera import IntrinsicsCamera

        k = camera.intrinsics(width, height)  # OpenCV's K: pixel centres at integer (u, v)
        fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2], k[1, 2]
        jj, ii = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
        x, y, valid = undistort((jj - cx) / fx, (ii - cy) / fy, camera.dist_coefficients)
        self.valid = valid
        self.x, self.y = x, y
        if not valid.any():
            raise ValueError("dist: no pixel of this camera sees anything (the distortion model "
                             "has no undistorted point for any pixel centre)")
        u, v = fx * x + cx, fy * y + cy  # ideal pinhole pixel coordinates of each ray
        s = oversample
        # The ideal view covers every ray, one ideal pixel of margin (bilinear's neighbours).
        u0, v0 = math.floor(np.nanmin(u)) - 1, math.floor(np.nanmin(v)) - 1
        nu, nv = math.ceil(np.nanmax(u)) + 2 - u0, math.ceil(np.nanmax(v)) + 2 - v0
        self.width, self.height = nu * s, nv * s
        for name, side in (("width", self.width), ("height", self.height)):
            if side > _core.MAX_IMAGE_SIDE:
                raise ValueError(
                    f"dist: the undistorted view this calibration needs is {self.width}x{self.height} "
                    f"pixels at oversample={s} (its {name} is over softrast.MAX_IMAGE_SIDE = "
                    f"{_core.MAX_IMAGE_SIDE}): lower the camera's oversample, or the distortion reaches "
                    "rays too far from the axis for a pinhole view")
        # Pixel jj of the ideal view has its centre at u = u0 - 1/2 + (jj + 1/2) / s, so its
        # OpenCV K has fx * s and cx' = s (cx - u0 + 1/2) - 1/2.
        cxs, cys = s * (cx - u0 + 0.5) - 0.5, s * (cy - v0 + 0.5) - 0.5
        self._sample_to_normalized = (1.0 / (s * fx), -cxs / (s * fx), 1.0 / (s * fy), -cys / (s * fy))
        half = 0.0 if camera.convention == "opencv" else 0.5  # an "opengl" K is measured from the corner
        self.camera = IntrinsicsCamera(fx * s, fy * s, cxs + half, cys + half, self.width, self.height,
                                       near=camera.near, far=camera.far, convention=camera.convention)
        us, vs = s * (u - u0 + 0.5) - 0.5, s * (v - v0 + 0.5) - 0.5  # ray positions in the view
        us, vs = np.where(valid, us, 0.0), np.where(valid, vs, 0.0)
        self.nearest = (np.clip(np.floor(vs + 0.5), 0, self.height - 1).astype(np.intp) * self.width
                        + np.clip(np.floor(us + 0.5), 0, self.width - 1).astype(np.intp))
        j0, i0 = np.floor(us), np.floor(vs)
        fu, fv = (us - j0).astype(np.float32)[..., None], (vs - i0).astype(np.float32)[..., None]
        one = np.float32(1.0)
        self.weights = ((one - fu) * (one - fv), fu * (one - fv), (one - fu) * fv, fu * fv)
        j0 = np.clip(j0, 0, self.width - 2).astype(np.intp)
        i0 = np.clip(i0, 0, self.height - 2).astype(np.intp)
        self.corner = i0 * self.width + j0  # top-left of the bilinear 2x2
        # The rays in world space (through OpenCV camera axes), from the camera centre.
        self.directions_cv = np.stack([np.where(valid, x, 0.0), np.where(valid, y, 0.0),
                                       np.ones_like(x)], axis=-1)


    def sample_directions(self, samples: npt.NDArray[Any]) -> npt.NDArray[np.float64]:
        """(n, 3) rays (OpenCV camera axes, z = 1) through the centres of ideal-view samples."""
        i, j = np.divmod(samples, self.width)
        ax, bx, ay, by = self._sample_to_normalized
        return np.stack([j * ax + bx, i * ay + by, np.ones(samples.size)], axis=-1)


def _rays(camera: Any, width: int, height: int) -> _Rays:
    key = (width, height)
    cache = camera.__dict__.setdefault("_rays_cache", {})
    rays = cache.get(key)
    if rays is None:
        if len(cache) >= 4:
            cache.clear()
        rays = cache[key] = _Rays(camera, width, height, camera.oversample)
    return rays


def _shadow_scene(scene: Any) -> Any:
    """The scene with each instance's id replaced by its index (ids need not be unique; the
    refinement must find each pixel's triangle), cached in the scene until it changes."""
    import dataclasses

    from .scene import Scene

    shadow = scene._render_cache.get("distortion_shadow")
    if shadow is None:
        shadow = Scene(ambient_light=scene.ambient_light)
        shadow._lights = list(scene._lights)
        shadow._instances = [dataclasses.replace(inst, instance_id=k)
                             for k, inst in enumerate(scene._instances)]
        scene._render_cache["distortion_shadow"] = shadow
    return shadow


_REFINED = ("depth", "ray_depth", "position", "barycentric")
_BILINEAR = ("color", "radiance")
_HIT_TOLERANCE = 1e-9  # barycentric slack of a ray on a shared edge


def render_distorted(renderer: Any, scene: Any, camera: Any, names: Any, options: dict[str, Any],
                     out: Any) -> Any:
    """``Renderer.render`` for a camera with lens distortion (see this module's docstring)."""
    from . import _core
    from .render import Frame, Renderer, _out_arrays

    w, h = renderer.width, renderer.height
    rays = _rays(camera, w, h)
    view_renderers = renderer.__dict__.setdefault("_distortion_renderers", {})
    key = (rays.width, rays.height)
    big = view_renderers.get(key)
    if big is None:
        view_renderers.clear()  # one at a time: a renderer holds its scratch memory
        big = view_renderers[key] = Renderer(rays.width, rays.height, renderer.threads,
                                             renderer.isa != "generic")
    wanted = list(names)
    # Anything but colour and radiance is taken from one sample per pixel, chosen by casting the
    # pixel's ray at its neighbourhood's triangles: that needs every sample's triangle.
    resolve = any(n not in _BILINEAR for n in wanted)
    inner = list(dict.fromkeys(wanted + (["triangle_id", "instance_id"] if resolve else [])))
    view_scene = _shadow_scene(scene) if resolve else scene  # instance_id = the instance's index
    rays.camera.pose = camera.pose  # the ideal view shares the camera's pose (set per render)
    frame = big.render(view_scene, rays.camera, inner, **options)

    valid = rays.valid
    flat = {n: getattr(frame, n).reshape(rays.width * rays.height, -1) for n in inner}
    hits = _resolve(scene, camera, rays, flat) if resolve else None
    table = {row["name"]: row for row in _core.OUTPUT_TABLE}
    result: dict[str, np.ndarray] = {}
    for name in wanted:
        row = table[name]
        shape = (h, w) + ((row["channels"],) if row["channels"] > 1 else ())
        src = flat[name]
        if name in _BILINEAR:
            c, wt = rays.corner, rays.weights
            value = (src[c] * wt[0] + src[c + 1] * wt[1]) + (src[c + rays.width] * wt[2]
                                                             + src[c + rays.width + 1] * wt[3])
            if name == "color":
                value = np.floor(value + np.float32(0.5))
            value = value.astype(row["dtype"]).reshape(shape)
        else:
            value = src[hits.sample].astype(row["dtype"], copy=False).reshape(shape)
        if name == "color":
            bg = np.floor(np.clip(np.asarray(options["background"], np.float32), 0, 1) * np.float32(255.0)
                          + np.float32(0.5)).astype(np.uint8)
            value[~valid] = bg
        elif name == "instance_id":
            ids = np.array([inst.instance_id for inst in scene._instances] or [0], dtype=np.int32)
            seen = value >= 0
            value[seen] = ids[value[seen]]
            value[~valid] = -1
        else:
            value[~valid] = row["background"]
        result[name] = value
    if hits is not None:
        rows, cols = hits.rows, hits.cols
        if "depth" in result:
            result["depth"][rows, cols] = hits.t
        if "ray_depth" in result:
            result["ray_depth"][rows, cols] = hits.ray_depth
        if "position" in result:
            result["position"][rows, cols] = hits.position
        if "barycentric" in result:
            result["barycentric"][rows, cols] = hits.barycentric
    out_arrays = _out_arrays(out, wanted)
    if out_arrays:
        for name, arr in out_arrays.items():
            mine = result[name]
            if not isinstance(arr, np.ndarray) or arr.dtype != mine.dtype or arr.shape != mine.shape \
                    or not arr.flags.writeable:
                raise ValueError(f"out[{name!r}] must be a writeable {mine.dtype} array of shape {mine.shape}")
            arr[...] = mine
            result[name] = arr
    return Frame(result)


def _cross(a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Row-wise cross products of (n, 3) arrays (np.cross is several times slower on these)."""
    out = np.empty_like(a)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def _dot(a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    return np.einsum("ij,ij->i", a, b)


def _intersect(scene: Any, index: npt.NDArray[Any], face: npt.NDArray[Any], dirs: npt.NDArray[np.float64],
               centre: npt.NDArray[np.float64]) -> tuple[Any, Any, Any]:
    """Rays from ``centre`` along ``dirs`` against instance ``index``'s face ``face`` (float64,
    Moeller-Trumbore, relative to the camera centre so that far scenes keep their digits):
    (t, the face's barycentric weights of the ray's point on its plane, its posed corners)."""
    n = index.size
    t = np.full(n, np.nan)
    bary = np.zeros((n, 3))
    corners = np.zeros((n, 3, 3))
    for k in np.unique(index):
        sel = np.nonzero(index == k)[0]
        inst = scene._instances[int(k)]
        local = inst.mesh.positions[inst.mesh.faces[face[sel]]].astype(np.float64)  # (m, 3, 3)
        world = local @ inst.pose[:3, :3].T + (inst.pose[:3, 3] - centre)
        e1, e2 = world[:, 1] - world[:, 0], world[:, 2] - world[:, 0]
        d = dirs[sel]
        pvec = _cross(d, e2)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / _dot(e1, pvec)
            tvec = -world[:, 0]
            b1 = _dot(tvec, pvec) * inv
            qvec = _cross(tvec, e1)
            b2 = _dot(d, qvec) * inv
            t[sel] = _dot(e2, qvec) * inv
        bary[sel] = np.stack([1.0 - b1 - b2, b1, b2], axis=-1)
        corners[sel] = world
    return t, bary, corners


class _Hits:
    """Per covered output pixel (rows, cols): the sample whose outputs it takes (``sample``, for
    every pixel) and its surface point on the pixel's own ray."""

    sample: npt.NDArray[Any]
    rows: npt.NDArray[Any]
    cols: npt.NDArray[Any]
    t: npt.NDArray[np.float64]
    ray_depth: npt.NDArray[np.float64]
    position: npt.NDArray[np.float64]
    barycentric: npt.NDArray[np.float64]


def _resolve(scene: Any, camera: Any, rays: _Rays, flat: dict[str, np.ndarray]) -> _Hits:
    """Which surface each output pixel sees, on its own ray.

    The candidates are the triangles of the sample nearest the ray's point in the ideal view
    and of the four around it (bilinear's). The pixel sees the nearest one its ray hits
    (float64); when the ray hits none of them (it passes beside a silhouette, or through a
    triangle smaller than a sample), it keeps the nearest sample's triangle at that sample's
    point: off the pixel's ray by at most half a sample diagonal, the silhouette bound."""
    tri = flat["triangle_id"].reshape(-1)
    idx = flat["instance_id"].reshape(-1)
    pose_cv = camera.pose if camera.convention == "opencv" else camera.pose @ np.diag([1.0, -1.0, -1.0, 1.0])
    centre, rot = pose_cv[:3, 3], pose_cv[:3, :3]
    valid = rays.valid.reshape(-1)
    nearest = rays.nearest.reshape(-1)
    corner = rays.corner.reshape(-1)
    rw = rays.width
    sample = nearest.copy()
    candidates = valid & ((tri[nearest] >= 0) | (tri[corner] >= 0) | (tri[corner + 1] >= 0)
                          | (tri[corner + rw] >= 0) | (tri[corner + rw + 1] >= 0))
    pix = np.nonzero(candidates)[0]
    dirs = rays.directions_cv.reshape(-1, 3)[pix] @ rot.T  # world space, unit camera-z component
    best_t = np.full(pix.size, np.inf)
    best_b = np.zeros((pix.size, 3))
    found = np.zeros(pix.size, bool)
    for k, cand in enumerate((nearest, corner, corner + 1, corner + rw, corner + rw + 1)):
        c = cand[pix]
        # the nearest sample for all; its neighbours only where the nearest one's triangle missed
        todo = np.nonzero((tri[c] >= 0) & (~found if k else True))[0]
        if not todo.size:
            continue
        t, b, _ = _intersect(scene, idx[c[todo]], tri[c[todo]], dirs[todo], centre)
        hit = (b >= -_HIT_TOLERANCE).all(axis=1) & (t > 0.0) & (t < best_t[todo])
        sel = todo[hit]
        best_t[sel], best_b[sel], sample[pix[sel]] = t[hit], b[hit], c[sel]
        found[sel] = True
    # Missed every candidate: the nearest sample's triangle (if any), at the sample's own point
    # (its centre's ray meets the triangle: it covered it), at most half a sample diagonal away.
    miss = np.nonzero(~found & (tri[nearest[pix]] >= 0))[0]
    chosen = nearest[pix[miss]]
    ray = rays.sample_directions(chosen) @ rot.T
    t, b, corners = _intersect(scene, idx[chosen], tri[chosen], ray, centre)
    grazing = ~np.isfinite(t)  # a ray in the triangle's plane: its centroid
    b[grazing] = 1.0 / 3.0
    b = np.clip(b, 0.0, 1.0)  # the vertex snap can leave a sample's ray just outside its triangle
    b /= b.sum(axis=1, keepdims=True)
    point = np.einsum("ij,ijk->ik", b, corners)  # relative to the camera centre
    exact = ~grazing & (t > 0.0)
    point[exact] = t[exact, None] * ray[exact]

    found_at = np.nonzero(found)[0]
    keep = np.concatenate([found_at, miss])
    hits = _Hits()
    hits.sample = sample.reshape(rays.valid.shape)
    hits.rows, hits.cols = np.divmod(pix[keep], rays.valid.shape[1])
    hits.barycentric = np.concatenate([best_b[found_at], b])
    points = np.concatenate([best_t[found_at, None] * dirs[found_at], point])  # camera-centred
    hits.position = points + centre
    hits.t = points @ rot[:, 2]  # along the viewing axis (OpenCV's +z)
    hits.ray_depth = np.sqrt(np.einsum("ij,ij->i", points, points))
    return hits
