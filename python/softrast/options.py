"""RenderOptions: every option of a render but its outputs, checked once, frozen and hashable.

``Renderer.render(scene, camera, outputs, options=None, **overrides)`` takes one (or the
defaults), with any field overridden by keyword: today's keywords (``render(..., msaa=4)``)
keep working.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import _core
from ._checks import choice, flag, real, unit_rgb
from .light import shadow_method
from .texture import check_filter

__all__ = ["MSAA_COUNTS", "RenderOptions"]

MSAA_COUNTS = (1, 2, 4, 8, 16)
# render(shading=): "auto" (each material's own model), every reflectance model of a material
# (python/softrast/material.py, MODELS) and the debug views ("uv"). The core picks its kernels
# from them and the scene (cpp/renderer.cpp, the plan).
SHADING = _core.SHADING_MODELS
NORMAL_SPACES = ("world", "camera")


def _antialiasing(msaa: Any, ssaa: Any) -> tuple[int, int]:
    """Checked msaa and ssaa counts."""
    for name, value in (("msaa", msaa), ("ssaa", ssaa)):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
            raise TypeError(f"{name} must be an int, got {value!r:.80}")
    if int(msaa) not in MSAA_COUNTS:
        raise ValueError(f"msaa must be one of {MSAA_COUNTS}, got {msaa!r}")
    if not 1 <= int(ssaa) <= 8:
        raise ValueError(f"ssaa must be in [1, 8], got {ssaa!r}")
    if msaa > 1 and ssaa > 1:
        raise ValueError(f"msaa and ssaa: use one of them, got msaa={msaa}, ssaa={ssaa}")
    return int(msaa), int(ssaa)


@dataclass(frozen=True)
class RenderOptions:
    """How a render draws, checked at construction (a bad value raises ValueError or TypeError
    naming it). Frozen and hashable: build one and reuse it for many renders.

    Parameters
    ----------
    shading : str
        "auto" (default): each instance's material's own model (its ``model``; "blinn_phong"
        for a material without one, "lambert" for a mesh without a material); or one model for
        everything: "unlit" (the base colour), "lambert", "phong", "blinn_phong", "pbr" (glTF
        metallic-roughness as pyrender computes it), "normal" (the world-space unit normal of
        the visible side as a colour, (n + 1) / 2), "uv" (the mesh's texture coordinates as a
        colour, (u, v, 0) clamped to [0, 1], perspective-correct; black without uvs) or
        "depth" (the depth output as a grey, (far - depth) / (far - near) clamped to [0, 1]).
        The formulas are in ``softrast.material``; the lights are the scene's, or the headlight
        in a scene without lights: a directional light along the camera's viewing axis of
        intensity 1 - ambient plus an ambient light of ``ambient``. The base colour is the
        mesh's per-vertex colours if it has them, else the instance's colour.
    frequency : str
        Where lighting is evaluated: "pixel" (default; Phong shading), "vertex" (Gouraud) or
        "face" (flat: once per face, with its face normal, at its centroid).
    srgb : bool
        True (default): ``color`` is the radiance sRGB-encoded (the exact IEC 61966-2-1 curve);
        False: linear. Either way clamped to [0, 1] and rounded to 8 bits; ``radiance`` holds
        the linear, unclamped values.
    background : tuple of 3 floats
        RGB in [0, 1] for pixels nothing covers, written to ``color`` as given (times 255).
    ambient : float
        In [0, 1]: the headlight's ambient part (default 0.25).
    texture_filter : str or None
        None (default: each texture's own filter) or one filter for every texture: "nearest",
        "bilinear", "trilinear" or "anisotropic" (``softrast.texture``).
    normal_space : str
        The ``normal`` output's axes: "world" (default) or "camera" (the axes of
        ``camera.pose``, as ``camera.unproject(..., space="camera")`` gives points).
    normal_kind : str
        "interpolated" (default): the ``normal`` output holds the interpolated vertex normal
        (the face normal of a mesh without normals), unit, of the visible side, at the pixel's
        own point of the surface; "shading": the normal the lighting uses, perturbed by the
        material's ``normal_texture`` or ``bump_texture`` exactly as the shading perturbs it.
    shadows : None, bool or str
        None (default: each light's own ``shadows``), False (no light casts shadows), True /
        "exact" (every light casts exact shadows) or "map" (shadow maps): ``softrast.light``
        states the rules. Shadows darken only ``color`` and ``radiance``. Stored as False,
        "exact" or "map" (or None).
    alpha_threshold : float or None
        None (default): ``depth``, ``mask``, the ids, ``normal`` and the surface outputs
        describe the nearest opaque surface, seen through blended materials; a number in [0, 1]:
        the nearest fragment, blended or opaque, whose alpha is at least it (Blender's "pass
        alpha threshold"). ``color``, ``radiance`` and ``alpha`` are composited either way. Not
        with a lens-distorted camera.
    cull : str
        "back" (default), "front" or "none". Front faces are counter-clockwise in the image as
        OpenGL defines it; a mirroring pose flips the winding, and the test. Double-sided
        materials are never culled unless ``cull_double_sided``.
    cull_double_sided : bool
        Apply ``cull`` to double-sided materials too (default False).
    wireframe : bool
        True draws every mesh instance's edges over the image as lines of ``line_color`` and
        ``line_width`` pixels, with the instance's id and triangle_id -1; in the depth test an
        edge counts as nearer by 1/256 of its depth (``WIREFRAME_DEPTH_BIAS``).
    line_color : tuple of 3 floats
        The wireframe's RGB in [0, 1], linear (default black).
    line_width : float
        The wireframe's width in pixels, finite, > 0 and at most 1e6 (default 1).
    msaa : int
        Multisample anti-aliasing: 1 (default, off), 2, 4, 8 or 16 samples per pixel at the
        Direct3D / Vulkan standard positions; each triangle shaded once per pixel; colour and
        radiance the mean of the samples in linear light.
    ssaa : int
        Supersampling: k (1 to 8) shades a k x k grid of samples per pixel and averages them.
        Not with msaa > 1. With either, ``alpha`` is the fraction of samples covered and
        ``radiance`` is premultiplied by it; ids, mask, depth, normal and the surface outputs
        come from one representative sample, the covered one nearest the pixel centre.

    The cross-checks below change how the same image is computed, never its bits (lines aside,
    whose two steppings differ by design); they exist to check one algorithm against another.

    shading_path : str
        "forward" (shade fragments as they pass the depth test), "deferred" (once per visible
        pixel) or "auto" (default: per 64x64 tile, forward unless its triangles cover it over
        1.5 times). A render asking for ``coverage`` is always deferred.
    raster : str
        "edge" (default: edge functions at every pixel of a triangle's box) or "scanline"
        (each row's span by edge walking): the same pixels and bits.
    line_algorithm : str
        How lines of width <= 1 are stepped: "bresenham" (default; integer) or "dda" (the minor
        coordinate in double, rounded half up).
    """

    shading: str = "auto"
    frequency: str = "pixel"
    srgb: bool = True
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)
    ambient: float = 0.25
    texture_filter: str | None = None
    normal_space: str = "world"
    normal_kind: str = "interpolated"
    shadows: bool | str | None = None
    alpha_threshold: float | None = None
    cull: str = "back"
    cull_double_sided: bool = False
    wireframe: bool = False
    line_color: tuple[float, float, float] = (0.0, 0.0, 0.0)
    line_width: float = 1.0
    msaa: int = 1
    ssaa: int = 1
    # cross-checks: the same image by another algorithm
    shading_path: str = "auto"
    raster: str = "edge"
    line_algorithm: str = "bresenham"

    def __post_init__(self) -> None:
        # The order of today's checks in render(), so the first bad value named is the same.
        set_ = object.__setattr__
        choice(self.cull, "cull", _core.CULL_MODES)
        choice(self.normal_kind, "normal_kind", _core.NORMAL_KINDS)
        set_(self, "cull_double_sided", flag(self.cull_double_sided, "cull_double_sided"))
        choice(self.shading, "shading", SHADING)
        choice(self.shading_path, "shading_path", _core.SHADING_PATHS)
        choice(self.raster, "raster", _core.RASTER_ALGORITHMS)
        choice(self.line_algorithm, "line_algorithm", _core.LINE_ALGORITHMS)
        set_(self, "wireframe", flag(self.wireframe, "wireframe"))
        set_(self, "line_color", unit_rgb(self.line_color, "line_color"))
        width = real(self.line_width, "line_width")
        if not (np.isfinite(width) and 0.0 < width <= 1e6):
            raise ValueError(f"line_width must be finite, > 0 and at most 1e6, got {self.line_width!r}")
        set_(self, "line_width", width)
        choice(self.frequency, "frequency", _core.FREQUENCIES)
        choice(self.normal_space, "normal_space", NORMAL_SPACES)
        set_(self, "srgb", flag(self.srgb, "srgb"))
        if self.texture_filter is not None:
            check_filter(self.texture_filter, "texture_filter")
        set_(self, "background", unit_rgb(self.background, "background"))
        ambient = real(self.ambient, "ambient")
        if not 0.0 <= ambient <= 1.0:  # NaN fails too
            raise ValueError(f"ambient must be in [0, 1], got {self.ambient!r}")
        set_(self, "ambient", ambient)
        msaa, ssaa = _antialiasing(self.msaa, self.ssaa)
        set_(self, "msaa", msaa)
        set_(self, "ssaa", ssaa)
        if self.shadows is not None:
            set_(self, "shadows", shadow_method(self.shadows))
        if self.alpha_threshold is not None:
            threshold = real(self.alpha_threshold, "alpha_threshold")
            if not 0.0 <= threshold <= 1.0:  # NaN fails too
                raise ValueError(f"alpha_threshold must be None or in [0, 1], got {self.alpha_threshold!r}")
            set_(self, "alpha_threshold", threshold)

    def replace(self, **changes: Any) -> RenderOptions:
        """A copy with ``changes`` (field names, as keywords), checked; TypeError naming an
        unknown one."""
        unknown = [k for k in changes if k not in _FIELDS]
        if unknown:
            raise TypeError(f"render() got an unexpected keyword argument {unknown[0]!r} (the "
                            f"options are RenderOptions' fields: {', '.join(_FIELDS)})")
        return dataclasses.replace(self, **changes)


_FIELDS = tuple(f.name for f in dataclasses.fields(RenderOptions))
DEFAULT = RenderOptions()
_RESOLVED: dict[Any, RenderOptions] = {}  # (options, overrides) -> checked options


def _typed(value: Any) -> Any:
    if type(value) is tuple:
        return (tuple, tuple(_typed(v) for v in value))
    return (type(value), value)


def resolve(options: RenderOptions | None, overrides: dict[str, Any]) -> RenderOptions:
    """``options`` (or the defaults) with ``overrides``, checked once per distinct combination
    of hashable values (a render called in a loop with the same keywords checks them once)."""
    if options is None:
        options = DEFAULT
    elif not isinstance(options, RenderOptions):
        raise TypeError(f"options must be a softrast.RenderOptions or None, got {type(options).__name__}")
    if not overrides:
        return options
    try:  # each value with its type (and a tuple's items with theirs): True must not pass as 1
        key = (options, tuple((k, _typed(v)) for k, v in sorted(overrides.items())))
        hash(key)
    except TypeError:  # a list for background, say: checked every time
        return options.replace(**overrides)
    resolved = _RESOLVED.get(key)
    if resolved is None:
        resolved = options.replace(**overrides)
        if len(_RESOLVED) >= 64:
            _RESOLVED.clear()
        _RESOLVED[key] = resolved
    return resolved
