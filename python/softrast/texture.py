"""Textures: images a material samples per pixel (``Material(base_color_texture=...)`` and the
other texture slots), filtered in the C++ core: ``Texture``, ``load_texture``.

The rules (uv origin, decoding and sRGB, channels, wrap modes, filters and the level of detail,
mip chains and their memory, NaN uvs, when the image is viewed rather than copied) are in
docs/file_formats.md, "Textures"; ``softrast.reference.texture`` implements every one
of them independently.
"""
from __future__ import annotations

import os
import warnings
from typing import Any, Sequence

import numpy as np
import numpy.typing as npt

from . import _core
from ._checks import integer
from .io import imread
from .limits import check_budget

__all__ = ["Texture", "load_texture", "FILTERS", "WRAPS"]

FILTERS: tuple[str, ...] = tuple(_core.TEXTURE_FILTERS)  # nearest, bilinear, trilinear, anisotropic
WRAPS: tuple[str, ...] = tuple(_core.TEXTURE_WRAPS)      # repeat, clamp, mirror
UV_ORIGINS = ("bottom_left", "top_left")


def _choice(value: Any, name: str, choices: Sequence[str]) -> str:
    if not isinstance(value, str):
        raise TypeError(f"{name} must be one of {', '.join(map(repr, choices))}, "
                        f"got {type(value).__name__} {value!r:.80}")
    if value not in choices:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, choices))}, got {value!r:.80}")
    return value


def check_filter(value: Any, name: str = "filter") -> str:
    return _choice(value, name, FILTERS)


def srgb_decode(c: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB decode (float64); values below 0.04045 (negative ones too) take the
    linear segment, values above 1 the power segment."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((np.maximum(c, 0.04045) + 0.055) / 1.055) ** 2.4)


def mip_chain_bytes(width: int, height: int) -> int:
    """The peak bytes of building a width x height texture's mip chain (cpp/texture.cpp,
    Texture::build_mips): its float32 RGBA copy of level 0, the row pass to half width and level 1
    at once (later levels are smaller: their peak with the kept levels is lower)."""
    if width == 1 and height == 1:
        return 0
    half_w, half_h = max(1, width // 2), max(1, height // 2)
    return 16 * (width * height + half_w * height + half_w * half_h)


FILTERS_WITH_MIPS = ("trilinear", "anisotropic")


def _check_image(image: Any) -> np.ndarray:
    if isinstance(image, Texture):
        raise TypeError("image must be an array; this is already a Texture")
    arr = np.asarray(image)
    if arr.dtype == np.bool_ or arr.dtype.kind not in "uf" or arr.dtype not in (
            np.uint8, np.uint16, np.float32, np.float64):
        raise TypeError(f"image must be a uint8, uint16 or float32 array, got dtype {arr.dtype}")
    if arr.ndim == 2:
        arr = arr[:, :, None]
    if arr.ndim != 3:
        raise ValueError(f"image must have shape (h, w, c) or (h, w), got {arr.shape}")
    h, w, c = arr.shape
    if not 1 <= c <= 4:
        raise ValueError(f"image must have 1 to 4 channels, got {c} (shape {arr.shape})")
    if h == 0 or w == 0:
        raise ValueError(f"image is empty: shape {arr.shape}")
    if max(h, w) > _core.MAX_IMAGE_SIDE * 2:
        raise ValueError(f"image is too large: {w} x {h} (at most {_core.MAX_IMAGE_SIDE * 2} a side)")
    if arr.dtype.kind == "f" and not np.isfinite(arr).all():
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(f"image has a non-finite texel value at (row, col, channel) {tuple(bad)}")
    return arr


class Texture:
    """An image that a material samples, with its sampling options; immutable.

    The sampling rules are in docs/file_formats.md, "Textures".

    Parameters
    ----------
    image : array_like, shape (h, w, c) or (h, w)
        uint8, uint16 or float32 (float64 is converted), c in 1..4. Viewed, not copied, where its
        layout allows: do not modify it after the first render.
    srgb : bool or None, optional
        True (sRGB-encoded colour), False (linear data) or None (8- and 16-bit images: the
        material slot decides; float images: linear. See docs/file_formats.md, "Textures").
    filter : str, optional
        "nearest", "bilinear", "trilinear" (default) or "anisotropic";
        ``render(texture_filter=)`` overrides it for one render.
    wrap : str or pair of str, optional
        "repeat" (default), "clamp" or "mirror", or a pair (wrap_u, wrap_v).
    max_anisotropy : int, optional
        Probes of the anisotropic filter at most, in [1, 64] (default 16).
    uv_origin : str, optional
        "bottom_left" (OpenGL, default) or "top_left" (DirectX, raw glTF).
    name : str or None, optional
        A label (the file's name for ``load_texture``), used in error messages.

    Raises
    ------
    TypeError, ValueError
        For a bad argument, naming it: a dtype other than those above, a shape other than (h, w)
        or (h, w, 1..4), an empty image, a side over 2 x ``MAX_IMAGE_SIDE``, a non-finite texel.
    """

    __slots__ = ("image", "srgb", "filter", "wrap", "max_anisotropy", "uv_origin", "name",
                 "_cores", "_warned", "__weakref__")

    def __init__(self, image: npt.ArrayLike, srgb: bool | None = None, filter: str = "trilinear",
                 wrap: str | Sequence[str] = "repeat", max_anisotropy: int = 16,
                 uv_origin: str = "bottom_left", name: str | None = None) -> None:
        s = object.__setattr__
        arr = _check_image(image)
        if srgb is not None and not isinstance(srgb, (bool, np.bool_)):
            raise TypeError(f"srgb must be True, False or None, got {srgb!r:.80}")
        check_filter(filter)
        if isinstance(wrap, str):
            wraps = (_choice(wrap, "wrap", WRAPS),) * 2
        else:
            try:
                wraps = tuple(wrap)
            except TypeError:
                raise TypeError(f"wrap must be one of {WRAPS} or a pair of them, got {wrap!r:.80}") from None
            if len(wraps) != 2:
                raise ValueError(f"wrap must be one of {WRAPS} or a pair (wrap_u, wrap_v), got {wrap!r:.80}")
            wraps = tuple(_choice(w, "wrap", WRAPS) for w in wraps)
        n = integer(max_anisotropy, "max_anisotropy")
        if not 1 <= n <= 64:
            raise ValueError(f"max_anisotropy must be in [1, 64], got {max_anisotropy!r}")
        _choice(uv_origin, "uv_origin", UV_ORIGINS)
        if name is not None and not isinstance(name, str):
            raise TypeError(f"name must be a str or None, got {type(name).__name__}")
        s(self, "image", arr)
        s(self, "srgb", None if srgb is None else bool(srgb))
        s(self, "filter", filter)
        s(self, "wrap", wraps)
        s(self, "max_anisotropy", n)
        s(self, "uv_origin", uv_origin)
        s(self, "name", name)
        s(self, "_cores", {})
        s(self, "_warned", set())  # the colour slots already checked (_check_color_range)

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError("Texture is immutable: make a new one (softrast.Texture(...) or "
                             "texture.replace(...))")

    def replace(self, **changes: Any) -> "Texture":
        """A copy with some options changed (the image is shared, not copied).

        Parameters
        ----------
        **changes
            Any of the constructor's arguments by name.

        Returns
        -------
        Texture
            The new texture, checked like the constructor's.
        """
        args = {k: getattr(self, k) for k in ("image", "srgb", "filter", "wrap", "max_anisotropy",
                                               "uv_origin", "name")}
        args.update(changes)
        return Texture(**args)

    @property
    def height(self) -> int:
        """Image height in texels."""
        return int(self.image.shape[0])

    @property
    def width(self) -> int:
        """Image width in texels."""
        return int(self.image.shape[1])

    @property
    def channels(self) -> int:
        """Channels of the image, 1 to 4."""
        return int(self.image.shape[2])

    def _decodes_srgb(self, slot_srgb: bool | None = None) -> bool:
        if self.srgb is not None:
            return self.srgb
        if self.image.dtype.kind == "f":
            return False  # float images are linear (EXR, HDR), in every slot
        return True if slot_srgb is None else slot_srgb

    def _label(self) -> str:
        """How budget errors name this texture."""
        size = f"{self.width}x{self.height}x{self.channels} {self.image.dtype}"
        return f"texture {self.name!r} ({size})" if self.name else f"texture ({size})"

    def _core(self, slot_srgb: bool | None = None) -> Any:
        """The core's texture, decoding sRGB or not (made once for each)."""
        srgb = self._decodes_srgb(slot_srgb)
        core = self._cores.get(srgb)
        if core is None:
            arr = self.image
            contiguous = arr.flags.c_contiguous
            if arr.dtype == np.uint8:
                if not contiguous:
                    check_budget(arr.size, f"{self._label()}: its contiguous copy")
                core = _core.Texture(np.ascontiguousarray(arr), srgb)
            else:
                if srgb or arr.dtype != np.float32 or not contiguous:
                    check_budget(4 * arr.size, f"{self._label()}: its decoded float32 copy")
                if srgb or arr.dtype == np.uint16:
                    # Converted a block of rows at a time (each value in float64 as ever): the
                    # float64 temporaries stay small whatever the texture's size.
                    values = np.empty(arr.shape, np.float32)
                    rows = max(1, (1 << 18) // (arr.shape[1] * arr.shape[2]))
                    with np.errstate(over="ignore"):
                        for r in range(0, arr.shape[0], rows):
                            values[r:r + rows] = self._decoded(arr[r:r + rows], srgb)
                    if srgb and arr.dtype.kind == "f" and not np.isfinite(values).all():
                        raise ValueError(
                            f"Texture{' ' + repr(self.name) if self.name else ''}: sRGB-decoding "
                            f"its float image (values up to {float(arr.max()):g}) overflows "
                            f"float32; float images are linear unless srgb=True")
                else:
                    values = np.ascontiguousarray(arr, dtype=np.float32)  # a view if it can be
                core = _core.Texture(values)
            core.configure(FILTERS.index(self.filter), WRAPS.index(self.wrap[0]),
                           WRAPS.index(self.wrap[1]), self.uv_origin == "top_left",
                           self.max_anisotropy)
            self._cores[srgb] = core
        return core

    def _check_color_range(self, slot: str) -> None:
        """Refuses negative values in a colour slot's float image, and warns of values above 1
        (often 0..255 as floats)."""
        arr = self.image
        if arr.dtype.kind != "f" or slot in self._warned:
            return  # (each slot checked once per texture: materials are remade by replace())
        color = arr[:, :, :arr.shape[2] if arr.shape[2] in (1, 3) else arr.shape[2] - 1]
        low = float(arr.min())
        if low < 0.0:  # radiance would go negative; data slots (normal maps) keep signed values
            raise ValueError(f"{slot}: its float image has a negative value ({low:g}); colour "
                             f"and alpha texels must be >= 0")
        self._warned.add(slot)
        top = float(color.max())
        if top > 1.0:
            hint = (" It looks like 8-bit values stored as floats: pass a uint8 array, or "
                    "divide by 255." if top <= 255.0 and float(color.min()) >= 0.0
                    and np.array_equal(color, np.round(color)) else "")
            warnings.warn(f"{slot}: its float image ({arr.dtype}) has values up to {top:g}; float "
                          f"texels are used as they are, 1 being full intensity, so colours above "
                          f"1 saturate.{hint}", UserWarning, stacklevel=3)

    @staticmethod
    def _decoded(block: np.ndarray, srgb: bool) -> np.ndarray:
        """Texels as linear values in float64: uint16 scaled to [0, 1], colour channels
        sRGB-decoded if ``srgb`` (alpha never)."""
        values = block.astype(np.float64) / 65535.0 if block.dtype == np.uint16 else block.astype(np.float64)
        if srgb:
            color = values.shape[2] if values.shape[2] in (1, 3) else values.shape[2] - 1
            values[:, :, :color] = srgb_decode(values[:, :, :color])
        return values

    def _check_mips(self, core: Any) -> None:
        """Before the core builds ``core``'s mip chain (a render or sample with a trilinear or
        anisotropic filter, or ``mip``): its peak against the memory budget."""
        if not core.has_mips:
            check_budget(mip_chain_bytes(self.width, self.height),
                         f"{self._label()}: its mip chain (float32 RGBA)")

    @property
    def levels(self) -> list[tuple[int, int]]:
        """The (height, width) of each mip level, level 0 first, the last 1 x 1.

        Returns
        -------
        list of tuple of int
        """
        core = self._core()
        return [tuple(core.level_size(level)) for level in range(core.num_levels)]

    def mip(self, level: int) -> np.ndarray:
        """One mip level as linear RGBA.

        The chain is built on first use; it and the array are checked against the memory budget
        first.

        Parameters
        ----------
        level : int
            In [0, len(levels)).

        Returns
        -------
        ndarray, shape (h, w, 4), float32
            Linear RGBA.

        Raises
        ------
        ValueError
            For a level outside that range, or beyond ``softrast.get_memory_budget()``.
        """
        core = self._core()
        level = integer(level, "level")
        if not 0 <= level < core.num_levels:
            raise ValueError(f"level must be in [0, {core.num_levels - 1}], got {level}")
        if level > 0:
            self._check_mips(core)
        h, w = core.level_size(level)
        check_budget(16 * h * w, f"{self._label()}: level {level} as a ({h}, {w}, 4) float32 array")
        return core.mip(level)

    def sample(self, uv: npt.ArrayLike, duv: npt.ArrayLike | None = None,
               filter: str | None = None) -> np.ndarray:
        """Sample at n points exactly as a render does.

        Parameters
        ----------
        uv : array_like, shape (n, 2)
            Texture coordinates.
        duv : array_like, shape (n, 4), optional
            The screen derivatives (du/dx, dv/dx, du/dy, dv/dy) in uv units per pixel; None: zeros
            (level 0).
        filter : str, optional
            None: the texture's own filter.

        Returns
        -------
        ndarray, shape (n, 4), float32
            Linear RGBA.

        Raises
        ------
        ValueError
            For a uv or duv of the wrong shape or dtype, or a mip chain beyond the memory budget.
        """
        uv_arr = np.asarray(uv)
        if uv_arr.dtype.kind not in "fiu" or uv_arr.ndim != 2 or uv_arr.shape[1] != 2:
            raise ValueError(f"uv must be a real (n, 2) array, got shape {uv_arr.shape} dtype {uv_arr.dtype}")
        if duv is None:
            duv_arr = np.zeros((uv_arr.shape[0], 4), np.float32)
        else:
            duv_arr = np.asarray(duv)
            if duv_arr.dtype.kind not in "fiu" or duv_arr.shape != (uv_arr.shape[0], 4):
                raise ValueError(f"duv must be a real (n, 4) array matching uv, got shape "
                                 f"{duv_arr.shape} dtype {duv_arr.dtype}")
        f = self.filter if filter is None else check_filter(filter)
        core = self._core()
        if f in FILTERS_WITH_MIPS:
            self._check_mips(core)
        return core.sample(np.ascontiguousarray(uv_arr, np.float32),
                                   np.ascontiguousarray(duv_arr, np.float32), FILTERS.index(f))

    def __reduce__(self) -> tuple[Any, ...]:
        return (Texture, (self.image, self.srgb, self.filter, self.wrap, self.max_anisotropy,
                          self.uv_origin, self.name))

    def __repr__(self) -> str:
        return (f"Texture({self.width}x{self.height}x{self.channels} {self.image.dtype}, "
                f"srgb={self.srgb}, filter={self.filter!r}, wrap={self.wrap!r}"
                + (f", name={self.name!r}" if self.name else "") + ")")


def load_texture(path: str | os.PathLike[str], srgb: bool | None = None, **options: Any) -> Texture:
    """Read an image file as a Texture.

    PNG, JPEG, TGA, EXR, TIFF, ... through OpenImageIO: 8-bit files stay uint8 (viewed), 16-bit
    ones uint16, floating-point ones float32.

    Parameters
    ----------
    path : str or os.PathLike
        The image file.
    srgb : bool or None, optional
        As for ``Texture``.
    **options
        Texture's other arguments (filter, wrap, max_anisotropy, uv_origin; ``name`` defaults to
        the file's name).

    Returns
    -------
    Texture

    Raises
    ------
    FileNotFoundError, ValueError
        As ``softrast.imread``; ValueError naming the file for an image Texture refuses.
    """
    image = imread(path)
    if image.dtype == np.float16 or image.dtype == np.float64:
        image = image.astype(np.float32)
    options.setdefault("name", os.path.basename(os.fspath(path)))
    try:
        return Texture(image, srgb=srgb, **options)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{os.fspath(path)}: {e}") from None
