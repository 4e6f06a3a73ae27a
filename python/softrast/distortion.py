"""Lens distortion: OpenCV's camera model (k1..k6 radial, p1 p2 tangential, s1..s4 thin prism)
for ``IntrinsicsCamera(..., dist=)``, rendered by ``render_distorted``.

Geometry outputs come from each pixel's own ray, cast exactly against the triangles
(``cpp/distortion.cpp``); colour from an ideal pinhole view remapped bilinearly. The model,
each step and its cost are in docs/conventions.md, "Lens distortion" and "How a distorted
camera is rendered".
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from . import _core
from .camera import IntrinsicsCamera
from .draws import _draws
from .frame import _OUTPUT_BYTES, Frame, _out_arrays
from .lens import undistort
from .limits import check_budget
from .options import RenderOptions
from .scene import Scene

__all__ = ["render_distorted"]


class _Rays:
    """Per camera and size: each output pixel's ray and where it falls in the ideal view."""

    def __init__(self, camera: Any, width: int, height: int, oversample: int) -> None:
        k = camera.intrinsics(width, height)  # OpenCV's K: pixel centres at integer (u, v)
        fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2], k[1, 2]
        jj, ii = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
        x, y, valid = undistort((jj - cx) / fx, (ii - cy) / fy, camera.dist_coefficients)
        self.valid = valid
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
        half = 0.0 if camera.convention == "opencv" else 0.5  # an "opengl" K is measured from the corner
        self.camera = IntrinsicsCamera(fx * s, fy * s, cxs + half, cys + half, self.width, self.height,
                                       near=camera.near, far=camera.far, convention=camera.convention)
        us, vs = s * (u - u0 + 0.5) - 0.5, s * (v - v0 + 0.5) - 0.5  # ray positions in the view
        us, vs = np.where(valid, us, 0.0), np.where(valid, vs, 0.0)
        # Flat per-pixel arrays for the core's passes (_core._distortion_cast / _bilinear).
        self.valid_flat = np.ascontiguousarray(valid.reshape(-1))
        self.nearest = (np.clip(np.floor(vs + 0.5), 0, self.height - 1).astype(np.int64) * self.width
                        + np.clip(np.floor(us + 0.5), 0, self.width - 1).astype(np.int64)).reshape(-1)
        j0, i0 = np.floor(us), np.floor(vs)
        fu, fv = (us - j0).astype(np.float32).reshape(-1), (vs - i0).astype(np.float32).reshape(-1)
        one = np.float32(1.0)
        self.weights = np.stack([(one - fu) * (one - fv), fu * (one - fv), (one - fu) * fv, fu * fv])
        j0 = np.clip(j0, 0, self.width - 2).astype(np.int64)
        i0 = np.clip(i0, 0, self.height - 2).astype(np.int64)
        self.corner = (i0 * self.width + j0).reshape(-1)  # top-left of the bilinear 2x2
        self.view_size = self.width * self.height
        # The rays (x', y', 1) in OpenCV camera axes, bucketed in a grid of the plane z = 1 with
        # cells one ideal pixel wide, stored cell by cell (row-major): the exact cast scatters
        # each triangle's box over it.
        pixel = np.flatnonzero(self.valid_flat)
        xs, ys = x.reshape(-1)[pixel], y.reshape(-1)[pixel]
        x0, y0 = float(xs.min()), float(ys.min())
        cx = np.floor((xs - x0) * fx).astype(np.int64)
        cy = np.floor((ys - y0) * fy).astype(np.int64)
        nx, ny = int(cx.max()) + 1, int(cy.max()) + 1
        cell = cy * nx + cx
        order = np.argsort(cell, kind="stable")
        self.grid_pixel = np.ascontiguousarray(pixel[order])
        self.grid_xy = np.ascontiguousarray(np.stack([xs[order], ys[order]], axis=-1))
        self.grid_cell_start = np.zeros(nx * ny + 1, np.int64)
        np.cumsum(np.bincount(cell, minlength=nx * ny), out=self.grid_cell_start[1:])
        self.grid_slot = np.full(width * height, -1, np.int64)
        self.grid_slot[self.grid_pixel] = np.arange(pixel.size, dtype=np.int64)
        self.grid_shape = (nx, ny)
        self.grid_frame = (x0, y0, float(fx), float(fy))
        arrays = (self.valid_flat, self.nearest, self.corner, self.grid_pixel, self.grid_xy, self.grid_slot,
                  self.grid_cell_start)
        for a in arrays:
            a.setflags(write=False)
        # The core's copy of these, checked once.
        self.core = _core._LensRays(self.valid_flat, self.nearest, self.corner, self.width, self.view_size,
                                    self.grid_pixel, self.grid_xy, self.grid_slot, self.grid_cell_start, nx, ny,
                                    self.grid_frame)


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
    def build() -> Any:
        instances = scene.instances  # one snapshot: the shadow's instances and ids agree
        shadow = Scene(ambient_light=scene.ambient_light)
        shadow._lights = list(scene._lights)
        shadow._instances = [dataclasses.replace(inst, instance_id=k)
                             for k, inst in enumerate(instances)]
        shadow._source_ids = np.array([inst.instance_id for inst in instances] or [0],
                                      dtype=np.int32)
        return shadow

    return scene._cached("distortion_shadow", build)


_BILINEAR = ("color", "radiance")
_GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])


def _maps_normal(inst: Any) -> bool:
    m = inst.material
    return m is not None and (m.normal_texture is not None or m.bump_texture is not None)


def render_distorted(renderer: Any, scene: Any, camera: Any, names: Any, options: RenderOptions,
                     out: Any) -> Any:
    """``Renderer.render`` for a camera with lens distortion.

    docs/conventions.md, "How a distorted camera is rendered", states each step.

    Parameters
    ----------
    renderer : Renderer
        Its size is the output's.
    scene : Scene
    camera : IntrinsicsCamera
        With ``dist``.
    names : sequence of str
        The outputs, checked.
    options : RenderOptions
        Resolved (no anti-aliasing, wireframe or ``alpha_threshold``: ``Renderer.render`` refuses
        them first).
    out : Frame or dict of str to ndarray or None
        As ``Renderer.render``'s.

    Returns
    -------
    Frame
    """
    w, h = renderer.width, renderer.height
    rays = _rays(camera, w, h)
    wanted = list(names)
    shadow = _shadow_scene(scene)  # instance_id = the instance's index, one snapshot of the scene
    instances = shadow._instances
    cast = list(dict.fromkeys(n for n in wanted if n not in _BILINEAR))
    # The ideal view: colour and radiance; the ids where the cast needs the view's samples (alpha
    # masked materials: their alpha test; normal_kind="shading" with normal or bump maps: the
    # shaded normal of the sample showing the hit triangle).
    mapped = np.array([_maps_normal(i) for i in instances] or [False])
    shading_normals = "normal" in cast and options.normal_kind == "shading" and bool(mapped.any())
    masked = any(i.material is not None and i.material.alpha_mode == "mask" for i in instances)
    need_ids = bool(cast) and (masked or shading_normals)
    # Blended materials are composited in the ideal view; the cast sees only opaque surfaces, so
    # where a ray hits none, alpha (their coverage) is gathered from the view like colour.
    blended = "alpha" in cast and any(i.material is not None and i.material.alpha_mode == "blend"
                                      for i in instances)
    inner = [n for n in wanted if n in _BILINEAR] + (["triangle_id", "instance_id"] if need_ids else []) \
        + (["normal"] if shading_normals else []) + (["alpha"] if blended else [])
    frame = None
    if inner:
        view_renderers = renderer.__dict__.setdefault("_distortion_renderers", {})
        key = (rays.width, rays.height)
        # The ideal view's outputs, checked before its renderer is made or anything is drawn.
        check_budget(rays.view_size * sum(_OUTPUT_BYTES[n] for n in inner),
                     f"oversample={camera.oversample}: the undistorted view's outputs {tuple(inner)} at "
                     f"{rays.width}x{rays.height}")
        big = view_renderers.get(key)
        if big is None:
            view_renderers.clear()  # one at a time: a renderer holds its scratch memory
            big = view_renderers[key] = type(renderer)(rays.width, rays.height, renderer.threads,
                                                       renderer.isa != "generic")
        rays.camera.pose = camera.pose  # the ideal view shares the camera's pose (set per render)
        frame = big.render(shadow if need_ids else scene, rays.camera, inner, options)

    valid = rays.valid
    hits: dict[str, np.ndarray] = {}
    if cast:
        pose_cv = camera.pose if camera.convention == "opencv" else camera.pose @ _GL_FROM_CV
        view = None
        if need_ids:
            view = (frame.triangle_id, frame.instance_id)
        hits = _core._distortion_cast(
            rays.core, _draws(shadow), tuple(pose_cv[:3, :3].reshape(-1)), tuple(pose_cv[:3, 3]),
            float(camera.near), float(camera.far), options.cull, options.cull_double_sided,
            cast + (["instance_id", "sample"] if shading_normals else []), view, renderer.threads)
    hit_index = hits["instance_id"].copy() if shading_normals else None  # before ids are mapped
    table = {row["name"]: row for row in _core.OUTPUT_TABLE}
    result: dict[str, np.ndarray] = {}
    for name in wanted:
        row = table[name]
        shape = (h, w) + ((row["channels"],) if row["channels"] > 1 else ())
        if name in _BILINEAR:
            value = np.empty(shape, row["dtype"])
            _core._distortion_bilinear(rays.core, rays.weights, getattr(frame, name), value)
        else:
            value = hits[name].reshape(shape)
        if name == "color":
            bg = np.floor(np.clip(np.asarray(options.background, np.float32), 0, 1) * np.float32(255.0)
                          + np.float32(0.5)).astype(np.uint8)
            value[~valid] = bg
        elif name == "radiance":
            value[~valid] = 0.0
        elif name == "alpha" and blended:  # no opaque hit: the blended coverage, gathered
            gathered = np.empty(shape, np.float32)
            _core._distortion_bilinear(rays.core, rays.weights, frame.alpha[..., None], gathered)
            gathered[~valid] = 0.0
            value = np.where(value == 1.0, value, gathered)
        elif name == "instance_id":
            seen = value >= 0
            value[seen] = shadow._source_ids[value[seen]]
        elif name == "normal":
            if options.normal_space != "world":  # the camera's axes, as the pipeline's rotation
                seen = value.any(axis=-1)
                value[seen] = (value[seen].astype(np.float64) @ camera.pose[:3, :3]).astype(np.float32)
            if shading_normals:  # the shaded normal of the view sample showing the hit triangle
                take = (hit_index >= 0) & mapped[np.maximum(hit_index, 0)]
                value.reshape(-1, 3)[take] = frame.normal.reshape(-1, 3)[hits["sample"][take]]
        result[name] = value
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
