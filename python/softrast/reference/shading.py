"""Independent NumPy float64 reference of softrast's shading models, lights and 8-bit encodings.

Written from the formulas (python/softrast/material.py, light.py, docs/pbr_notes.md), not from the C++
core, so the renderer can be tested against it. Everything is vectorised over N pixels.

    radiance(model, n, p, base_rgb, material, lights, ambient_light, eye, orthographic_dir=None)
        -> (N, 3) float64 linear radiance, unclamped
    srgb_encode(linear) -> uint8     IEC 61966-2-1 curve on clamp(x, 0, 1), floor(v * 255 + 0.5)
    linear_encode(linear) -> uint8   floor(clamp(x, 0, 1) * 255 + 0.5)
    pyrender_encode(linear) -> uint8 pyrender's pow(c, 1/2.2)   (the three from .encoding)
    headlight(view_matrix, ambient) -> (lights, ambient_light) of a scene without lights
    light_records(scene, view_matrix) -> the core records of a scene's lights (camera_space too)
    unproject(depth, view, proj) -> world positions of pixel centres from a depth output

A light record here is a tuple of what ``Light._record_fields(pose_world)`` holds by name: (kind 0
directional / 1 point / 2 spot, radiance rgb = colour * intensity, position, direction of travel
(unit), inverse_square, cone scale, cone offset).
"""
from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any, Sequence

import numpy as np

from .encoding import linear_encode, pyrender_encode, srgb_curve, srgb_encode

__all__ = ["DIRECTIONAL", "POINT", "SPOT", "MODELS", "pose_at", "light_dir_and_radiance",
           "view_vectors", "pbr_brdf", "radiance", "srgb_curve", "srgb_encode", "linear_encode",
           "pyrender_encode", "camera_to_world", "headlight", "as_tuple", "light_records",
           "scene_lighting", "unproject"]

DIRECTIONAL, POINT, SPOT = 0, 1, 2
MODELS = ("unlit", "lambert", "phong", "blinn_phong", "pbr", "normal")

# pyrender's mesh.frag constants (docs/pbr_notes.md).
MIN_ROUGHNESS = 0.04  # the dielectric F0 and the lower clamp of the roughness factor
NL_MIN = 0.001        # NdotL and NdotV are clamped to [0.001, 1]
SPEC_EPS = 0.001      # the specular denominator is 4 * nl * nv + 0.001
# A mesh without a material rendered with "pbr" uses softrast.Material()'s defaults.
DEFAULT_METALLIC, DEFAULT_ROUGHNESS = 0.0, 0.5

Lighting = tuple[list[tuple[Any, ...]], tuple[float, float, float]]


def pose_at(position: Any = (0.0, 0.0, 0.0), travel: Any = (0.0, 0.0, -1.0)) -> np.ndarray:
    """A rigid light pose at ``position`` whose -z axis (the direction of travel) is ``travel``.

    Parameters
    ----------
    position : array_like, shape (3,)
        The pose's origin (world).
    travel : array_like, shape (3,)
        The direction the light travels (any length > 0).

    Returns
    -------
    numpy.ndarray
        (4, 4) float64 light-to-world pose; its x axis is chosen from the world x (or y, when
        ``travel`` is nearly along x) axis.
    """
    z = -np.asarray(travel, float) / np.linalg.norm(travel)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, np.cross(z, x), z, position
    return pose


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)[:, None]


def _normalize(a: np.ndarray) -> np.ndarray:
    """Unit rows; a zero row stays zero (h = l + v = 0 when the light is exactly behind the
    surface opposite the viewer: the renderer must not produce NaN there either)."""
    norm = np.linalg.norm(a, axis=1, keepdims=True)
    return np.divide(a, norm, out=np.zeros_like(a), where=norm > 0)


def _rows(x: Any, n: int) -> np.ndarray:
    arr = np.asarray(x, dtype=np.float64)
    return np.broadcast_to(arr.reshape(-1, 3) if arr.ndim == 1 else arr, (n, 3)).astype(np.float64)


def light_dir_and_radiance(light: Sequence[Any], p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The direction towards a light and the radiance arriving from it, at N points.

    Parameters
    ----------
    light : tuple or light record
        A light record (see the module docstring, or anything ``as_tuple`` reads).
    p : numpy.ndarray, shape (N, 3)
        World positions.

    Returns
    -------
    l : numpy.ndarray, shape (N, 3)
        Unit vectors from each point towards the light.
    I : numpy.ndarray, shape (N, 3)
        Arriving radiance: colour * intensity, times 1/r^2 if inverse_square, times the spot cone
        factor clamp(cos * scale + offset, 0, 1)^2.
    """
    kind, rgb, pos, d, inverse_square, scale, offset = as_tuple(light)
    n = p.shape[0]
    rgb = np.broadcast_to(np.asarray(rgb, dtype=np.float64), (n, 3)).copy()
    d = np.asarray(d, dtype=np.float64)
    if kind == DIRECTIONAL:
        return np.broadcast_to(-d, (n, 3)).copy(), rgb
    to_light = np.asarray(pos, dtype=np.float64) - p
    r2 = _dot(to_light, to_light)
    l = to_light / np.sqrt(r2)
    if inverse_square:
        rgb = rgb / r2
    if kind == SPOT:
        cd = np.clip(-l @ d, 0.0, 1.0)  # pyrender clamps cos to [0, 1] first: the same factor
        t = np.clip(cd * scale + offset, 0.0, 1.0)
        rgb = rgb * (t * t)[:, None]
    elif kind != POINT:
        raise ValueError(f"unknown light kind {kind!r}")
    return l, rgb


def view_vectors(p: np.ndarray, eye: Any, orthographic_dir: Any = None) -> np.ndarray:
    """v: the unit vectors towards the viewer.

    Parameters
    ----------
    p : numpy.ndarray, shape (N, 3)
        World positions.
    eye : array_like, shape (3,)
        The camera centre (perspective cameras).
    orthographic_dir : array_like, shape (3,), optional
        The viewing direction of an orthographic camera; v is then -direction everywhere.

    Returns
    -------
    numpy.ndarray
        (N, 3) float64 unit vectors (a point at the eye gets 0).
    """
    if orthographic_dir is not None:
        d = np.asarray(orthographic_dir, dtype=np.float64)
        return np.broadcast_to(-d / np.linalg.norm(d), p.shape).copy()
    return _normalize(np.asarray(eye, dtype=np.float64) - p)


def pbr_brdf(n: np.ndarray, v: np.ndarray, l: np.ndarray, base: np.ndarray, metallic: float,
             roughness: float, radiance: np.ndarray) -> np.ndarray:
    """One light's contribution to "pbr", exactly pyrender 0.1.45's compute_brdf.

    Parameters
    ----------
    n, v, l : numpy.ndarray, shape (N, 3)
        Unit normal, direction to the viewer and direction to the light.
    base : numpy.ndarray, shape (N, 3)
        Base colour (linear).
    metallic, roughness : float
        The material's factors (clamped to [0, 1] and [0.04, 1]).
    radiance : numpy.ndarray, shape (N, 3)
        The light's arriving radiance (``light_dir_and_radiance``).

    Returns
    -------
    numpy.ndarray
        (N, 3) float64: NdotL * radiance * (diffuse + specular), docs/pbr_notes.md.
    """
    roughness = min(max(roughness, MIN_ROUGHNESS), 1.0)
    metallic = min(max(metallic, 0.0), 1.0)
    c_diff = base * (1.0 - MIN_ROUGHNESS) * (1.0 - metallic)
    f0 = MIN_ROUGHNESS * (1.0 - metallic) + base * metallic
    h = _normalize(l + v)
    nl = np.clip(_dot(n, l), NL_MIN, 1.0)
    nv = np.clip(np.abs(_dot(n, v)), NL_MIN, 1.0)
    nh = np.clip(_dot(n, h), 0.0, 1.0)
    vh = np.clip(_dot(v, h), 0.0, 1.0)
    F = f0 + (1.0 - f0) * (1.0 - vh) ** 5
    r = roughness + 1.0
    k = r * r / 8.0
    G = (nv / (nv * (1.0 - k) + k)) * (nl / (nl * (1.0 - k) + k))
    a2 = (roughness * roughness) ** 2
    denom = nh * nh * (a2 - 1.0) + 1.0
    D = a2 / (math.pi * denom * denom)
    diffuse = (1.0 - F) * c_diff / math.pi
    spec = F * G * D / (4.0 * nl * nv + SPEC_EPS)
    return nl * radiance * (diffuse + spec)


def radiance(model: str, n: Any, p: Any, base_rgb: Any, material: Any, lights: Sequence[Any],
             ambient_light: Any, eye: Any, orthographic_dir: Any = None) -> np.ndarray:
    """The linear radiance of a shading model at N points.

    Parameters
    ----------
    model : str
        One of ``MODELS``.
    n : array_like, shape (N, 3)
        Unit normals of the visible side.
    p : array_like, shape (N, 3) or (3,)
        World positions.
    base_rgb : array_like, shape (N, 3) or (3,)
        Base colour (linear).
    material : softrast.Material or None
        Its kd, ka, ks, shininess, emissive, metallic and roughness are read; None: kd = ka =
        base, ks = 0, emissive 0, and for "pbr" metallic 0, roughness 0.5.
    lights : sequence of light records
        See the module docstring (or anything ``as_tuple`` reads).
    ambient_light : array_like, shape (3,)
        The ambient light's RGB.
    eye : array_like, shape (3,)
        The camera centre.
    orthographic_dir : array_like, shape (3,), optional
        The viewing direction of an orthographic camera.

    Returns
    -------
    numpy.ndarray
        (N, 3) float64 linear radiance, unclamped.
    """
    if model not in MODELS:
        raise ValueError(f"unknown model {model!r}")
    n = np.atleast_2d(np.asarray(n, dtype=np.float64))
    N = n.shape[0]
    p = _rows(p, N)
    base = _rows(base_rgb, N)
    if model == "unlit":
        return base.copy()
    if model == "normal":
        return (n + 1.0) / 2.0
    ia = np.asarray(ambient_light, dtype=np.float64).reshape(1, 3)
    v = view_vectors(p, eye, orthographic_dir)
    emissive = np.zeros((1, 3)) if material is None else np.asarray(material.emissive).reshape(1, 3)

    if model == "pbr":
        metallic = DEFAULT_METALLIC if material is None else material.metallic
        roughness = DEFAULT_ROUGHNESS if material is None else material.roughness
        out = np.zeros((N, 3))
        for light in lights:
            l, I = light_dir_and_radiance(light, p)
            out += pbr_brdf(n, v, l, base, metallic, roughness, I)
        return out + base * ia + emissive  # pyrender's ambient: base * ambient_light

    kd = base if material is None or material.kd is None else _rows(material.kd, N)
    ka = kd if material is None or material.ka is None else _rows(material.ka, N)
    ks = np.zeros((1, 3)) if material is None else np.asarray(material.ks).reshape(1, 3)
    shininess = 0.0 if material is None else material.shininess
    out = ka * ia + emissive
    for light in lights:
        l, I = light_dir_and_radiance(light, p)
        nl = _dot(n, l)
        out = out + kd * I * np.maximum(0.0, nl)
        if model == "lambert":
            continue
        if model == "phong":
            r = 2.0 * nl * n - l
            s = np.maximum(0.0, _dot(r, v))
        else:  # blinn_phong
            s = np.maximum(0.0, _dot(n, _normalize(l + v)))
        out = out + np.where(nl > 0.0, ks * I * s ** shininess, 0.0)
    return out


def camera_to_world(view_matrix: Any) -> np.ndarray:
    """The inverse of a (rigid) world-to-view matrix.

    Parameters
    ----------
    view_matrix : array_like, shape (4, 4)
        World to view (OpenGL axes).

    Returns
    -------
    numpy.ndarray
        (4, 4) float64 camera-to-world pose.
    """
    return np.linalg.inv(np.asarray(view_matrix, dtype=np.float64))


def headlight(view_matrix: Any, ambient: float) -> Lighting:
    """The lights of a scene without lights.

    Parameters
    ----------
    view_matrix : array_like, shape (4, 4)
        The camera's world-to-view matrix.
    ambient : float
        The renderer's ``ambient`` option.

    Returns
    -------
    lights : list of tuple
        One record: a white directional light of intensity (1 - ambient) travelling along the
        camera's viewing axis (its -z in world space).
    ambient_light : tuple of float
        (ambient, ambient, ambient).
    """
    pose = camera_to_world(view_matrix)
    d = -pose[:3, 2] / np.linalg.norm(pose[:3, 2])
    a = float(ambient)
    record = (DIRECTIONAL, (1.0 - a,) * 3, tuple(float(x) for x in pose[:3, 3]),
              tuple(float(x) for x in d), False, 0.0, 1.0)
    return [record], (a, a, a)


def as_tuple(light: Any) -> tuple[Any, ...]:
    """A light record as this module's tuple.

    Parameters
    ----------
    light : tuple, list, dict or object
        A tuple or list (returned as a tuple), the dict of ``Light._record_fields(pose)``
        (float64), or an object with the same attributes (e.g. a ``softrast._core.Light``,
        float32).

    Returns
    -------
    tuple
        (kind, radiance, position, direction, inverse_square, cone_scale, cone_offset), kind 0
        directional, 1 point, 2 spot.
    """
    if isinstance(light, (tuple, list)):
        return tuple(light)
    if isinstance(light, dict):
        light = SimpleNamespace(**light)
    kind = ("directional", "point", "spot").index(light.kind)
    return (kind, light.radiance, light.position, light.direction, light.inverse_square,
            light.cone_scale, light.cone_offset)


def light_records(scene: Any, view_matrix: Any) -> list[tuple[Any, ...]]:
    """The world-space records of a scene's lights.

    Parameters
    ----------
    scene : softrast.Scene
        Its ``lights`` are read (camera_space poses are light-to-camera).
    view_matrix : array_like, shape (4, 4)
        The camera's world-to-view matrix.

    Returns
    -------
    list of tuple
        One record per light, in the scene's order.
    """
    cam = camera_to_world(view_matrix)
    return [as_tuple(li.light._record_fields(cam @ li.pose if li.camera_space else li.pose))
            for li in scene.lights]


def scene_lighting(scene: Any, view_matrix: Any, ambient: float) -> Lighting:
    """The lights and ambient light a render of a scene uses.

    Parameters
    ----------
    scene : softrast.Scene
        Its ``lights`` and ``ambient_light`` are read.
    view_matrix : array_like, shape (4, 4)
        The camera's world-to-view matrix.
    ambient : float
        The renderer's ``ambient`` option (used when the scene has no lights).

    Returns
    -------
    lights : list of tuple
        ``light_records``, or the ``headlight`` of a scene without lights.
    ambient_light : tuple of float
        scene.ambient_light; when None, 0 with lights and ``ambient`` without.
    """
    if not scene.lights:
        lights, amb = headlight(view_matrix, ambient)
        if scene.ambient_light is not None:
            amb = scene.ambient_light
        return lights, amb
    amb = (0.0, 0.0, 0.0) if scene.ambient_light is None else scene.ambient_light
    return light_records(scene, view_matrix), amb


def unproject(depth: np.ndarray, view: Any, proj: Any, rows: np.ndarray | None = None,
              cols: np.ndarray | None = None) -> np.ndarray:
    """World positions of pixel centres (row i, column j) from the depth output (-z_view).

    Solves the projection for x_view, y_view given z_view = -depth at the pixel centre's NDC
    (ndc_x = 2 (j + 0.5) / W - 1, ndc_y = 1 - 2 (i + 0.5) / H); works for perspective,
    orthographic and intrinsics (off-centre, skewed) projections.

    Parameters
    ----------
    depth : numpy.ndarray, shape (H, W)
        The depth output.
    view, proj : array_like, shape (4, 4)
        The camera's view and projection matrices.
    rows, cols : numpy.ndarray, optional
        The pixels (integer indices); all pixels, row-major, when None.

    Returns
    -------
    numpy.ndarray
        (N, 3) float64 world positions.
    """
    h, w = depth.shape
    if rows is None:
        rows, cols = np.divmod(np.arange(h * w), w)
    P = np.asarray(proj, dtype=np.float64)
    z = -depth[rows, cols].astype(np.float64)
    ndc_x = 2.0 * (cols + 0.5) / w - 1.0
    ndc_y = 1.0 - 2.0 * (rows + 0.5) / h
    wc = P[3, 2] * z + P[3, 3]  # P[3, 0] = P[3, 1] = 0 for every camera of softrast
    bx = ndc_x * wc - P[0, 2] * z - P[0, 3]
    by = ndc_y * wc - P[1, 2] * z - P[1, 3]
    det = P[0, 0] * P[1, 1] - P[0, 1] * P[1, 0]
    x = (bx * P[1, 1] - P[0, 1] * by) / det
    y = (P[0, 0] * by - P[1, 0] * bx) / det
    p_view = np.stack([x, y, z, np.ones_like(z)], axis=1)
    return (p_view @ camera_to_world(view).T)[:, :3]
