"""Materials: how a surface reflects light, for every shading model (``Material``, ``MODELS``,
``ALPHA_MODES``).

One ``Material`` carries the parameters of every model, in linear colours. The models'
formulas and what each texture slot does are in docs/conventions.md, "Materials and shading
models"; the ``pbr`` model, term by term, in docs/pbr_notes.md.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from . import _core
from ._checks import flag, float32_real, real, real_array
from .texture import Texture

__all__ = ["Material", "MODELS", "ALPHA_MODES"]

# Shading models a material may ask for (render(shading="auto") uses each material's own).
MODELS: tuple[str, ...] = tuple(_core.REFLECTANCE_MODELS)  # unlit, lambert, phong, blinn_phong, pbr, normal
# How a material's alpha is used (glTF's alphaMode, lower case).
ALPHA_MODES = ("opaque", "mask", "blend")


def _color(value: Any, name: str, n: int) -> tuple[float, ...]:
    """``n`` finite numbers in [0, 1] (RGB; RGBA when n == 4, where 3 get alpha 1). For RGB, one
    number is grey: ``ka=0.1`` is (0.1, 0.1, 0.1), as course code writes it."""
    arr = real_array(value, name)
    if arr.shape == () and n == 3:
        arr = np.repeat(arr.reshape(1), 3)
    if arr.shape not in ((n,),) + (((3,),) if n == 4 else ()):
        what = "3 or 4 numbers (RGB or RGBA)" if n == 4 else f"{n} numbers (RGB)"
        raise ValueError(f"{name} must be {what} in [0, 1], got shape {arr.shape}")
    if not (np.isfinite(arr).all() and (arr >= 0.0).all() and (arr <= 1.0).all()):
        raise ValueError(f"{name} must be finite and in [0, 1], got {arr.tolist()}")
    if arr.shape[0] == 3 and n == 4:
        arr = np.append(arr, 1.0)
    return tuple(float(c) for c in arr)


def _unit_real(value: Any, name: str) -> float:
    v = real(value, name)
    if not 0.0 <= v <= 1.0:  # NaN fails too
        raise ValueError(f"{name} must be in [0, 1], got {value!r}")
    return v


class Material:
    """A surface's reflectance for every shading model; immutable (make a new one to change it).

    Colours are linear RGB(A) in [0, 1]. The models' formulas and the texture slots' rules are in
    docs/conventions.md, "Materials and shading models".

    Parameters
    ----------
    base_color : sequence of 3 or 4 floats, optional
        RGBA (or RGB) in [0, 1], linear, or None (default): 0.8 grey, or white (1, 1, 1, 1) where a
        ``base_color_texture`` is given, as glTF's ``baseColorFactor`` and pyrender default to, so
        the texture shows as it is. The colour of ``unlit``, the albedo of ``pbr`` and the default
        ``kd``; it multiplies the ``base_color_texture``. A mesh's per-vertex colours replace it
        where present.
    ka, kd, ks : sequence of 3 floats, float or None, optional
        RGB in [0, 1] (one number is grey: ``ks=0.5``): ambient, diffuse and specular reflectance
        of the lambert / phong / blinn_phong models. ``kd=None`` => the base colour; ``ka=None`` =>
        ``kd``; ``ks`` defaults to 0.5 grey (a mesh without any material has ks = 0).
    shininess : float, optional
        The specular exponent p >= 0 (``Ns`` in MTL files). Default 32. It and the other numbers
        below are held in float32 by the core: beyond its range (3.4e38) is refused.
    metallic, roughness : float, optional
        glTF metallic-roughness factors in [0, 1] (``pbr``). Defaults 0 and 0.5 (glTF files default
        to 1 and 1 when they give none; the file readers apply that).
    emissive : sequence of 3 floats or float, optional
        RGB in [0, 1] (or one number, grey), added to the radiance of every lit model.
    double_sided : bool, optional
        As glTF's doubleSided: never culled (whatever ``render(cull=)`` says, unless
        ``render(cull_double_sided=True)``), and back faces are lit with the flipped normal. False
        (default): a back face (visible only with ``cull="none"`` or ``"front"``) is lit with its
        own normal, which faces away from the camera, so it gets only the ambient and emissive
        terms, as OpenGL renders a single-sided material. Meshes without a material are lit
        two-sided but culled by ``render(cull=)``.
    model : str or None, optional
        The shading model ``render(shading="auto")`` uses for this material, one of
        ``softrast.material.MODELS``, or None: "blinn_phong" (the file readers set "pbr" for glTF
        and MTL materials: docs/file_formats.md states how MTL's Ks and Ns become roughness).
    name : str or None, optional
        A label (the file's material name), not used for rendering.
    base_color_texture, emissive_texture : Texture or None, optional
        sRGB-decoded unless the texture says ``srgb=False``.
    normal_texture : Texture or None, optional
        A tangent-space normal map (linear unless the texture says ``srgb=True``).
    normal_scale : float, optional
        Finite; scales the normal map's x and y (default 1).
    normal_map_convention : str, optional
        "opengl" (default, green = +v) or "directx" (green = -v).
    metallic_roughness_texture, occlusion_texture : Texture or None, optional
        See docs/conventions.md, "Materials and shading models".
    occlusion_strength : float, optional
        In [0, 1] (default 1).
    bump_texture : Texture or None, optional
        A height map (docs/conventions.md).
    bump_scale : float, optional
        Finite (default 1).
    alpha_mode : str, optional
        "opaque" (default: alpha is ignored) or "mask" (glTF's alphaMode MASK): a fragment is drawn
        only where its alpha >= ``alpha_cutoff``, else it is discarded before the depth test, so
        what lies behind shows through, in every output (depth, ids, mask, colour) and whatever the
        shading model. The alpha is ``base_color``'s (or the mesh's interpolated per-vertex alpha
        where it has vertex colours) times the ``base_color_texture``'s alpha at the pixel, sampled
        with the same uv, filter and level of detail as its colour. ``coverage`` counts only the
        fragments kept. "blend" (glTF's alphaMode BLEND): the material is translucent with that
        same alpha. At every pixel its fragments in front of the nearest opaque surface are
        composited in exact depth order (whatever the draw order; fragments at equal depth in draw
        order), in linear light, over that surface or the background. ``color`` and ``radiance``
        are composited, ``alpha`` is the total coverage; ``depth``, ids, ``mask``, ``normal`` and
        the surface outputs follow the nearest opaque surface, and ``coverage`` counts opaque
        fragments only. A blended draw whose one alpha is 1 (no vertex colours, no texture alpha)
        is drawn opaque, the same colours.
    alpha_cutoff : float, optional
        Finite; default 0.5, as glTF's.
    specular_texture : Texture or None, optional
        Its rgb scales ``ks`` per pixel in the phong and blinn_phong models (MTL's ``map_Ks``);
        linear unless the texture says ``srgb=True``. Read at the pixel frequency; ``pbr`` does not
        read it.

    Attributes
    ----------
    base_color : tuple of 4 floats
        As given or defaulted; every other argument is an attribute too, as checked (``ka`` and
        ``kd`` None when not given, ``ks`` a 3-tuple).

    Raises
    ------
    TypeError, ValueError
        For a bad argument, naming it (a colour outside [0, 1], a model not in ``MODELS``, a
        texture slot holding something other than a Texture, ...). A colour slot's float texture
        with a negative value raises ValueError; one with values above 1 warns (UserWarning).
    """

    __slots__ = ("base_color", "ka", "kd", "ks", "shininess", "metallic", "roughness", "emissive",
                 "double_sided", "model", "name", "base_color_texture", "emissive_texture",
                 "normal_texture", "normal_scale", "normal_map_convention",
                 "metallic_roughness_texture", "occlusion_texture", "occlusion_strength",
                 "bump_texture", "bump_scale", "alpha_mode", "alpha_cutoff", "specular_texture",
                 "_core")
    _FIELDS = ("base_color", "ka", "kd", "ks", "shininess", "metallic", "roughness", "emissive",
               "double_sided", "model", "name", "base_color_texture", "emissive_texture",
               "normal_texture", "normal_scale", "normal_map_convention",
               "metallic_roughness_texture", "occlusion_texture", "occlusion_strength",
               "bump_texture", "bump_scale", "alpha_mode", "alpha_cutoff", "specular_texture")
    _TEXTURE_SLOTS = ("base_color_texture", "emissive_texture", "normal_texture",
                      "metallic_roughness_texture", "occlusion_texture", "bump_texture",
                      "specular_texture")

    def __init__(self, base_color: Sequence[float] | None = None,
                 ka: Sequence[float] | float | None = None, kd: Sequence[float] | float | None = None,
                 ks: Sequence[float] | float | None = (0.5, 0.5, 0.5), shininess: float = 32.0,
                 metallic: float = 0.0, roughness: float = 0.5,
                 emissive: Sequence[float] | float = (0.0, 0.0, 0.0), double_sided: bool = False,
                 model: str | None = None, name: str | None = None,
                 base_color_texture: Texture | None = None,
                 emissive_texture: Texture | None = None, normal_texture: Texture | None = None,
                 normal_scale: float = 1.0, normal_map_convention: str = "opengl",
                 metallic_roughness_texture: Texture | None = None,
                 occlusion_texture: Texture | None = None, occlusion_strength: float = 1.0,
                 bump_texture: Texture | None = None, bump_scale: float = 1.0,
                 alpha_mode: str = "opaque", alpha_cutoff: float = 0.5,
                 specular_texture: Texture | None = None) -> None:
        s = object.__setattr__
        if base_color is None:
            base_color = (0.8, 0.8, 0.8, 1.0) if base_color_texture is None else (1.0, 1.0, 1.0, 1.0)
        s(self, "base_color", _color(base_color, "base_color", 4))
        s(self, "ka", None if ka is None else _color(ka, "ka", 3))
        s(self, "kd", None if kd is None else _color(kd, "kd", 3))
        s(self, "ks", (0.0, 0.0, 0.0) if ks is None else _color(ks, "ks", 3))
        p = float32_real(shininess, "shininess", nonnegative=True)  # the core's float32 range
        s(self, "shininess", p)
        s(self, "metallic", _unit_real(metallic, "metallic"))
        s(self, "roughness", _unit_real(roughness, "roughness"))
        s(self, "emissive", _color(emissive, "emissive", 3))
        s(self, "double_sided", flag(double_sided, "double_sided"))
        if model is not None:
            if not isinstance(model, str):
                raise TypeError(f"model must be one of {MODELS} or None, got {type(model).__name__}")
            if model not in MODELS:
                raise ValueError(f"model must be one of {MODELS} or None, got {model!r:.80}")
        s(self, "model", model)
        if name is not None and not isinstance(name, str):
            raise TypeError(f"name must be a str or None, got {type(name).__name__}")
        s(self, "name", name)
        for slot, tex in (("base_color_texture", base_color_texture),
                          ("emissive_texture", emissive_texture), ("normal_texture", normal_texture),
                          ("metallic_roughness_texture", metallic_roughness_texture),
                          ("occlusion_texture", occlusion_texture), ("bump_texture", bump_texture),
                          ("specular_texture", specular_texture)):
            if tex is not None and not isinstance(tex, Texture):
                raise TypeError(f"{slot} must be a softrast.Texture or None, got {type(tex).__name__}")
            if tex is not None and slot in ("base_color_texture", "emissive_texture"):
                tex._check_color_range(slot)
            s(self, slot, tex)
        scale = float32_real(normal_scale, "normal_scale")
        s(self, "normal_scale", scale)
        if normal_map_convention not in ("opengl", "directx"):
            raise ValueError(f"normal_map_convention must be 'opengl' or 'directx', got "
                             f"{normal_map_convention!r:.80}")
        s(self, "normal_map_convention", normal_map_convention)
        s(self, "occlusion_strength", _unit_real(occlusion_strength, "occlusion_strength"))
        bump = float32_real(bump_scale, "bump_scale")
        s(self, "bump_scale", bump)
        if not isinstance(alpha_mode, str) or alpha_mode not in ALPHA_MODES:
            raise ValueError(f"alpha_mode must be one of {ALPHA_MODES}, got {alpha_mode!r:.80}")
        s(self, "alpha_mode", alpha_mode)
        cutoff = float32_real(alpha_cutoff, "alpha_cutoff")
        s(self, "alpha_cutoff", cutoff)
        core = lambda tex, srgb: tex._core(srgb) if tex is not None else None  # noqa: E731
        # The core's record (cpp/bind/records.cpp, every field by name): colour slots decode
        # sRGB unless the texture says otherwise. A material without a model is Blinn-Phong.
        s(self, "_core", _core.Material(
            model=model or "blinn_phong", kd_is_base=self.kd is None, ka_is_kd=self.ka is None,
            double_sided=self.double_sided,
            ka=self.ka if self.ka is not None else (0.0, 0.0, 0.0),
            kd=self.kd if self.kd is not None else (0.0, 0.0, 0.0), ks=self.ks, shininess=p,
            metallic=self.metallic, roughness=self.roughness, emissive=self.emissive,
            base_color_texture=core(base_color_texture, True),
            emissive_texture=core(emissive_texture, True),
            normal_texture=core(normal_texture, False), normal_scale=scale,
            normal_y_down=normal_map_convention == "directx",
            metallic_roughness_texture=core(metallic_roughness_texture, False),
            occlusion_texture=core(occlusion_texture, False),
            occlusion_strength=self.occlusion_strength, bump_texture=core(bump_texture, False),
            bump_scale=bump, alpha_mask=alpha_mode == "mask", alpha_cutoff=cutoff,
            alpha_blend=alpha_mode == "blend",
            specular_texture=core(specular_texture, False)))

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError("Material is immutable: make a new one (softrast.Material(...) or "
                             "material.replace(...))")

    @property
    def plain(self) -> bool:
        """True if the material is lambert shading of its base colour, two-sided.

        What a mesh without a material gets (render's fast headlight path takes it too).
        """
        return (self.ka is None and self.kd is None and self.emissive == (0.0, 0.0, 0.0)
                and self.double_sided and not self.textured and self.alpha_mode == "opaque")

    @property
    def textured(self) -> bool:
        """True if the material samples a texture."""
        return any(getattr(self, slot) is not None for slot in self._TEXTURE_SLOTS)

    def replace(self, **changes: Any) -> "Material":
        """A copy with some parameters changed.

        Parameters
        ----------
        **changes
            Any of the constructor's arguments by name.

        Returns
        -------
        Material
            The new material, checked like the constructor's.
        """
        args = {k: getattr(self, k) for k in self._FIELDS}
        args.update(changes)
        return Material(**args)

    def __reduce__(self) -> tuple[Any, ...]:
        return (_rebuild, ({k: getattr(self, k) for k in self._FIELDS},))

    def __eq__(self, other: object) -> bool:  # textures compare by identity
        return isinstance(other, Material) and all(
            getattr(self, k) is getattr(other, k) if k.endswith("_texture")
            else getattr(self, k) == getattr(other, k) for k in self._FIELDS)

    def __hash__(self) -> int:
        return hash(tuple(id(getattr(self, k)) if k.endswith("_texture") else getattr(self, k)
                          for k in self._FIELDS))

    def __repr__(self) -> str:
        fields = ", ".join(f"{k}={getattr(self, k)!r}" for k in self._FIELDS
                           if getattr(self, k) is not None)
        return f"Material({fields})"


def _rebuild(args: dict[str, Any]) -> Material:
    return Material(**args)
