"""Lights, placed like pyrender's: ``scene.add(light, pose=)`` with a 4x4 light-to-world pose
(``DirectionalLight``, ``PointLight``, ``SpotLight``).

How a light is placed and attenuated (falloff, the spot cone), the headlight, and both shadow
methods (``shadows="exact"``: a ray per shaded point; ``"map"``: pyrender's shadow maps) are
in docs/conventions.md, "Lights and shadows".
"""
from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from . import _core
from ._checks import choice, float32_real, real, unit_rgb, unit_vector

__all__ = ["DirectionalLight", "Light", "PointLight", "SpotLight"]

FALLOFFS = ("inverse_square", "none")
# A light's `shadows`: False, or the method (True means "exact"). The core's names: "none",
# "exact", "map".
SHADOW_METHODS = ("exact", "map")
_NO_SHADOW, _EXACT, _MAP = _core.SHADOW_METHODS
# Kinds as the core names them (cpp/bind/module.cpp, Light.kind).
_DIRECTIONAL, _POINT, _SPOT = _core.LIGHT_KINDS  # "directional", "point", "spot"


def shadow_method(value: Any, name: str = "shadows") -> str | bool:
    """False, or the shadow method ``value`` names (True means "exact").

    Parameters
    ----------
    value : bool or str
        False, True, "exact" or "map".
    name : str, optional
        The argument's name, for the error.

    Returns
    -------
    False or str
        False, "exact" or "map".

    Raises
    ------
    ValueError
        Naming ``name``, for any other value.
    """
    if value is False:
        return False
    if isinstance(value, (bool, np.bool_)):
        return "exact" if value else False
    if not isinstance(value, str) or value not in SHADOW_METHODS:
        raise ValueError(f"{name} must be False, True, 'exact' or 'map', got {value!r:.80}")
    return value


def _shadow_resolution(value: Any) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"shadow_resolution must be an int, got {value!r:.80}")
    if not 1 <= int(value) <= 16384:
        raise ValueError(f"shadow_resolution must be in [1, 16384], got {value!r}")
    return int(value)


def _shadow_bias(value: Any) -> float:
    bias = real(value, "shadow_bias")
    if not (math.isfinite(bias) and bias >= 0.0):
        raise ValueError(f"shadow_bias must be finite and >= 0, got {value!r}")
    return bias


def _rebuild(cls: type, fields: dict[str, Any]) -> "Light":
    return cls(**fields)


def _intensity(value: Any) -> float:
    # The core holds color * intensity in float32: with color in [0, 1] and intensity at most
    # FLOAT32_MAX, the product stays finite there.
    return float32_real(value, "intensity", nonnegative=True)


class Light:
    """Base class of the light types (not made directly); immutable, hashable, picklable.

    Lights are placed by ``Scene.add(light, pose=)``: they shine along the pose's -z axis. The
    rules (falloff, the spot cone, the headlight, both shadow methods) are in
    docs/conventions.md, "Lights and shadows".

    Parameters
    ----------
    color : sequence of 3 floats, optional
        Linear RGB in [0, 1] (default white).
    intensity : float, optional
        >= 0, at most float32's 3.4e38 (default 1). The light sends ``color * intensity``.
    shadows : bool or str, optional
        False (default), True or "exact" (the same: a ray per shaded point) or "map" (shadow maps);
        ``render(shadows=)`` overrides it for one render.
    shadow_resolution : int, optional
        A shadow map's side in texels, in [1, 16384] (default 2048).
    shadow_bias : float, optional
        A shadow map's bias in scene units, finite and >= 0 (default 0.005), plus a slope term.

    Raises
    ------
    TypeError, ValueError
        For a bad argument, naming it.
    """

    __slots__ = ("color", "intensity", "shadows", "shadow_resolution", "shadow_bias")
    _kind = ""

    def __init__(self, color: Sequence[float] = (1.0, 1.0, 1.0), intensity: float = 1.0, *,
                 shadows: bool | str = False, shadow_resolution: int = 2048,
                 shadow_bias: float = 0.005) -> None:
        object.__setattr__(self, "color", unit_rgb(color, "color"))
        object.__setattr__(self, "intensity", _intensity(intensity))
        object.__setattr__(self, "shadows", shadow_method(shadows))
        object.__setattr__(self, "shadow_resolution", _shadow_resolution(shadow_resolution))
        object.__setattr__(self, "shadow_bias", _shadow_bias(shadow_bias))

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError(f"{type(self).__name__} is immutable: make a new one")

    def __reduce__(self) -> tuple[Any, ...]:
        return (_rebuild, (type(self), {k: getattr(self, k) for k in self._fields()}))

    @classmethod
    def _fields(cls) -> tuple[str, ...]:
        return tuple(s for c in reversed(cls.__mro__) for s in getattr(c, "__slots__", ()))

    def __eq__(self, other: object) -> bool:
        return type(self) is type(other) and all(
            getattr(self, k) == getattr(other, k) for k in self._fields())

    def __hash__(self) -> int:
        return hash((type(self),) + tuple(getattr(self, k) for k in self._fields()))

    def __repr__(self) -> str:
        fields = ", ".join(f"{k}={getattr(self, k)!r}" for k in self._fields())
        return f"{type(self).__name__}({fields})"

    def _core(self, pose_world: np.ndarray, shadows: str | bool | None = None,
              maps: list[tuple[Any, ...]] | None = None) -> Any:
        """The core's light record (``softrast._core.Light``), in world space; ``shadows``
        (render's override, checked) replaces the light's own setting unless None; a "map"
        light's ``maps`` are its faces, (view, proj, orthographic, depth) each."""
        fields = self._record_fields(pose_world)
        method = self.shadows if shadows is None else shadows
        fields["shadow"] = {False: _NO_SHADOW, "exact": _EXACT, "map": _MAP}[method]
        record = _core.Light(**fields)
        if method == "map":
            _core._attach_shadow_map(record, list(maps or []), self.shadow_bias)
        return record

    def _record_fields(self, pose_world: np.ndarray) -> dict[str, Any]:
        """The fields of the core's light record, by name, in float64 (the record holds float32;
        softrast.reference.shading reads these)."""
        pos = pose_world[:3, 3]
        d = unit_vector(-pose_world[:3, 2])  # scaled: a 1e-200 or 1e300 long z axis has one too
        if d is None:
            raise ValueError(f"{type(self).__name__} pose: its z axis has zero length, so it has "
                             "no direction")
        scale, offset = self._cone()
        return dict(kind=self._kind, radiance=tuple(c * self.intensity for c in self.color),
                    position=tuple(float(x) for x in pos), direction=tuple(float(x) for x in d),
                    inverse_square=getattr(self, "falloff", "none") == "inverse_square",
                    cone_scale=scale, cone_offset=offset)

    def _cone(self) -> tuple[float, float]:
        return 0.0, 1.0  # factor = clamp(cd * 0 + 1) ** 2 = 1: no cone


class DirectionalLight(Light):
    """Light from infinitely far away along the pose's -z axis (the sun). pyrender's name.

    Parameters
    ----------
    color : sequence of 3 floats, optional
        Linear RGB in [0, 1] (default white).
    intensity : float, optional
        >= 0, at most float32's 3.4e38 (default 1). The light sends ``color * intensity``.
    shadows : bool or str, optional
        False (default), True or "exact" (the same: a ray per shaded point) or "map" (shadow maps);
        ``render(shadows=)`` overrides it for one render.
    shadow_resolution : int, optional
        A shadow map's side in texels, in [1, 16384] (default 2048).
    shadow_bias : float, optional
        A shadow map's bias in scene units, finite and >= 0 (default 0.005), plus a slope term.

    Raises
    ------
    TypeError, ValueError
        For a bad argument, naming it.
    """

    __slots__ = ()
    _kind = _DIRECTIONAL


class PointLight(Light):
    """Light from the pose's translation in every direction.

    Parameters
    ----------
    color : sequence of 3 floats, optional
        Linear RGB in [0, 1] (default white).
    intensity : float, optional
        >= 0, at most float32's 3.4e38 (default 1). The light sends ``color * intensity``.
    falloff : str, optional
        "inverse_square" (default: radiance / r**2, physical and pyrender's) or "none".
    shadows : bool or str, optional
        False (default), True or "exact" (the same: a ray per shaded point) or "map" (shadow maps);
        ``render(shadows=)`` overrides it for one render.
    shadow_resolution : int, optional
        A shadow map's side in texels, in [1, 16384] (default 2048).
    shadow_bias : float, optional
        A shadow map's bias in scene units, finite and >= 0 (default 0.005), plus a slope term.

    Raises
    ------
    TypeError, ValueError
        For a bad argument, naming it.
    """

    __slots__ = ("falloff",)
    _kind = _POINT

    def __init__(self, color: Sequence[float] = (1.0, 1.0, 1.0), intensity: float = 1.0,
                 falloff: str = "inverse_square", *, shadows: bool | str = False,
                 shadow_resolution: int = 2048, shadow_bias: float = 0.005) -> None:
        super().__init__(color, intensity, shadows=shadows, shadow_resolution=shadow_resolution,
                         shadow_bias=shadow_bias)
        object.__setattr__(self, "falloff", choice(falloff, "falloff", FALLOFFS))


class SpotLight(Light):
    """A point light restricted to a cone around the pose's -z axis.

    Full intensity inside the inner cone, none outside the outer one, glTF's smooth falloff
    between.

    Parameters
    ----------
    color : sequence of 3 floats, optional
        Linear RGB in [0, 1] (default white).
    intensity : float, optional
        >= 0, at most float32's 3.4e38 (default 1). The light sends ``color * intensity``.
    inner_cone, outer_cone : float, optional
        Half-angles in radians, 0 <= inner_cone < outer_cone <= pi / 2 (as glTF's
        KHR_lights_punctual and pyrender; defaults 0 and pi / 4).
    falloff : str, optional
        "inverse_square" (default: radiance / r**2) or "none".
    shadows : bool or str, optional
        False (default), True or "exact" (the same: a ray per shaded point) or "map" (shadow maps);
        ``render(shadows=)`` overrides it for one render.
    shadow_resolution : int, optional
        A shadow map's side in texels, in [1, 16384] (default 2048).
    shadow_bias : float, optional
        A shadow map's bias in scene units, finite and >= 0 (default 0.005), plus a slope term.

    Raises
    ------
    TypeError, ValueError
        For a bad argument, naming it.
    """

    __slots__ = ("inner_cone", "outer_cone", "falloff")
    _kind = _SPOT

    def __init__(self, color: Sequence[float] = (1.0, 1.0, 1.0), intensity: float = 1.0,
                 inner_cone: float = 0.0, outer_cone: float = math.pi / 4,
                 falloff: str = "inverse_square", *, shadows: bool | str = False,
                 shadow_resolution: int = 2048, shadow_bias: float = 0.005) -> None:
        super().__init__(color, intensity, shadows=shadows, shadow_resolution=shadow_resolution,
                         shadow_bias=shadow_bias)
        inner = real(inner_cone, "inner_cone")
        outer = real(outer_cone, "outer_cone")
        if not 0.0 < outer <= math.pi / 2:
            raise ValueError(f"outer_cone must be in (0, pi/2] radians, got {outer_cone!r}")
        if not 0.0 <= inner < outer:
            raise ValueError(f"inner_cone must be in [0, outer_cone) radians, got {inner_cone!r} "
                             f"with outer_cone {outer!r}")
        object.__setattr__(self, "inner_cone", inner)
        object.__setattr__(self, "outer_cone", outer)
        object.__setattr__(self, "falloff", choice(falloff, "falloff", FALLOFFS))

    def _cone(self) -> tuple[float, float]:
        # glTF: scale = 1 / max(0.001, cos(inner) - cos(outer)), offset = -cos(outer) * scale.
        scale = 1.0 / max(0.001, math.cos(self.inner_cone) - math.cos(self.outer_cone))
        return scale, -math.cos(self.outer_cone) * scale
