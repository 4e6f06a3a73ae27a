"""Images that mesh files carry or name, as softrast Textures: decoded by Pillow (glTF, trimesh
materials) or read from disk (MTL maps), one Texture per image within a load."""
from __future__ import annotations

import hashlib
import math
import os
from typing import Any

import numpy as np

from ..limits import check_budget
from ..texture import Texture, load_texture
from .context import FileInfo


def _have_pillow() -> bool:
    try:
        import PIL.Image  # noqa: F401
    except ImportError:
        return False
    return True


# -- textures -------------------------------------------------------------------------------------
def _pil_array(image: Any) -> np.ndarray:
    """A PIL image's texels as an (h, w, c) array, c in 1..4, as stored where a Texture can take
    them: L, LA, RGB, RGBA -> uint8; 16-bit grey -> uint16; F -> float32; palette images -> RGB
    (RGBA with transparency); other modes (1, CMYK, YCbCr, premultiplied, ...) converted."""
    mode = image.mode
    width, height = image.size
    check_budget(width * height * 4 * 4, f"texture image ({width}x{height} {mode})")
    if mode == "P" or mode == "PA":
        palette = getattr(image, "palette", None)
        alpha = (mode == "PA" or "transparency" in image.info
                 or getattr(palette, "mode", "RGB") in ("RGBA", "LA"))
        image = image.convert("RGBA" if alpha else "RGB")
    elif mode == "1":
        image = image.convert("L")
    elif mode == "La":
        image = image.convert("LA")
    elif mode == "RGBa":
        image = image.convert("RGBA")
    elif mode not in ("L", "LA", "RGB", "RGBA", "F", "I") and not mode.startswith("I;16"):
        image = image.convert("RGBA" if "A" in image.getbands() else "RGB")
    arr = np.asarray(image)
    if image.mode == "I":  # 32-bit integers: how some Pillow versions hold 16-bit PNGs
        arr = np.clip(arr, 0, 65535).astype(np.uint16)
    elif image.mode.startswith("I;16"):
        arr = arr.astype(np.uint16)  # native byte order
    elif image.mode == "F":
        arr = arr.astype(np.float32)
    return np.ascontiguousarray(arr)


def _pil_texture(image: Any, info: FileInfo, filter: str = "trilinear",
                 wrap: tuple[str, str] = ("repeat", "repeat"),
                 name: str | None = None) -> tuple[Texture | None, str | None]:
    """(Texture, None) for a PIL image trimesh decoded, or (None, why not); one Texture per image
    and sampler within a load."""
    key = ("pil", id(image), filter, wrap)
    cached = info.textures.get(key)
    if cached is None:
        if name is None:
            path = getattr(image, "info", {}).get("file_path")
            name = os.path.basename(str(path).replace("\\", "/")) if path else None
        try:
            arr = _pil_array(image)
            # the same texels (a file storing one image twice, as trimesh's exporter does) are
            # one Texture too
            digest = ("texels", hashlib.blake2b(arr.tobytes(), digest_size=16).digest(),
                      arr.shape, arr.dtype.str, filter, wrap)
            same = info.textures.get(digest)
            if same is not None and same[1] is not None:
                tex: Texture | None = same[1]
            else:
                tex = Texture(arr, filter=filter, wrap=wrap, name=name)
                info.textures[digest] = (None, tex, None)
            why = None
        except UserWarning:
            raise
        except Exception as exc:  # a truncated image, a mode Pillow cannot convert, too large
            tex, why = None, f"its image could not be read ({type(exc).__name__}: {exc})"
        cached = info.textures[key] = (image, tex, why)  # the image keeps its id unique
    return cached[1], cached[2]


def _file_texture(path: str, info: FileInfo, wrap: str) -> tuple[Texture | None, str | None]:
    """(Texture, None) for an image file (softrast.load_texture), or (None, why not); one Texture
    per file and wrap within a load."""
    key = ("file", os.path.realpath(path), wrap)
    cached = info.textures.get(key)
    if cached is None:
        try:
            tex: Texture | None = load_texture(path, wrap=wrap)
            why = None
        except UserWarning:
            raise
        except Exception as exc:
            tex, why = None, f"could not be read ({exc})"
        cached = info.textures[key] = (None, tex, why)
    return cached[1], cached[2]


def _texel_sample(tex: Texture) -> np.ndarray:
    """About 65536 of a texture's texels (a regular subsample), (n, c) float64 in [0, 1]."""
    img = tex.image
    step = max(1, int(math.sqrt(img.shape[0] * img.shape[1] / 65536.0)))
    sample = np.asarray(img[::step, ::step], dtype=np.float64)
    if img.dtype == np.uint8:
        sample = sample / 255.0
    elif img.dtype == np.uint16:
        sample = sample / 65535.0
    return sample.reshape(-1, img.shape[2])


def _looks_like_normal_map(tex: Texture) -> bool:
    """An RGB(A) image whose mean colour is near (0.5, 0.5, 1): a tangent-space normal map,
    not a (grey) height map."""
    if tex.channels < 3:
        return False
    r, g, b = _texel_sample(tex)[:, :3].mean(axis=0)
    return abs(r - 0.5) < 0.15 and abs(g - 0.5) < 0.15 and b > 0.75


def _is_grey(tex: Texture) -> bool:
    """The texture has one grey channel, or RGB(A) with red = green = blue (checked on a
    subsample)."""
    if tex.channels < 3:
        return True
    rgb = _texel_sample(tex)[:, :3]
    return bool((rgb[:, 0] == rgb[:, 1]).all() and (rgb[:, 1] == rgb[:, 2]).all())
