"""glTF materials, read exactly from the file's JSON: factors, alpha modes, textures with their
samplers. The rules are in docs/file_formats.md, "glTF and GLB"."""
from __future__ import annotations

import math
import os
from typing import Any

import numpy as np

from .._checks import FLOAT32_MAX
from ..material import Material
from .context import FileInfo
from .images import _have_pillow, _pil_texture


# glTF texture slots: (where, key, Material field)
_GLTF_SLOTS = (("pbr", "baseColorTexture", "base_color_texture"),
               ("pbr", "metallicRoughnessTexture", "metallic_roughness_texture"),
               ("material", "normalTexture", "normal_texture"),
               ("material", "occlusionTexture", "occlusion_texture"),
               ("material", "emissiveTexture", "emissive_texture"))


# what a glTF material renders instead of a texture that is not drawn
_GLTF_FALLBACK = {"baseColorTexture": "; rendering its base colour factor",
                  "metallicRoughnessTexture": "; rendering its metallic and roughness factors",
                  "normalTexture": "", "occlusionTexture": "",
                  "emissiveTexture": "; rendering its emissive factor"}


_GLTF_WRAPS = {10497: "repeat", 33071: "clamp", 33648: "mirror"}


_GL_NEAREST, _GL_LINEAR, _GL_NEAREST_MIPMAP_NEAREST = 9728, 9729, 9984


def _gltf_material(index: int, entry: Any, info: FileInfo, mat: Any = None) -> tuple[Material, list[str]]:
    """The exact Material of glTF material ``index`` and the list of what is dropped; its
    textures are the images trimesh decoded into its PBRMaterial ``mat``."""
    entry = entry if isinstance(entry, dict) else {}
    name = entry.get("name") if isinstance(entry.get("name"), str) else None
    where = f"material {name!r}" if name is not None else f"material {index}"
    pbr = entry.get("pbrMetallicRoughness", {})
    pbr = pbr if isinstance(pbr, dict) else {}
    dropped: list[str] = []

    def factor(obj: dict[str, Any], key: str, default: Any, n: int) -> Any:
        value = obj.get(key, default)
        try:
            arr = np.asarray(value, dtype=np.float64).reshape(n) if n else float(value)
        except (TypeError, ValueError):
            dropped.append(f"{key} {value!r} is not valid (using {default})")
            return default
        arr_np = np.asarray(arr, dtype=np.float64)
        if not np.isfinite(arr_np).all():
            dropped.append(f"{key} {value!r} is not finite (using {default})")
            return default
        clipped = np.clip(arr_np, 0.0, 1.0)
        if (clipped != arr_np).any():
            dropped.append(f"{key} {value!r} clipped to [0, 1]")
        return tuple(clipped.tolist()) if n else float(clipped)

    base = factor(pbr, "baseColorFactor", (1.0, 1.0, 1.0, 1.0), 4)
    metallic = factor(pbr, "metallicFactor", 1.0, 0)
    roughness = factor(pbr, "roughnessFactor", 1.0, 0)
    emissive = factor(entry, "emissiveFactor", (0.0, 0.0, 0.0), 3)
    textures = _gltf_textures(entry, pbr, info, mat, dropped)
    alpha = _gltf_alpha(entry.get("alphaMode", "OPAQUE"), entry.get("alphaCutoff", 0.5), dropped)
    model = "pbr"
    extensions = entry.get("extensions", {})
    for ext in (extensions if isinstance(extensions, dict) else {}):
        if ext == "KHR_materials_unlit":
            model = "unlit"
        else:
            dropped.append(f"extension {ext} is ignored")
    double = entry.get("doubleSided", False)
    return Material(base_color=base, metallic=metallic, roughness=roughness, emissive=emissive,
                    double_sided=bool(double) if isinstance(double, bool) else False,
                    model=model, name=name, **alpha, **textures), dropped


def _gltf_alpha(mode: Any, cutoff: Any, dropped: list[str]) -> dict[str, Any]:
    """A glTF material's alphaMode and alphaCutoff as Material arguments: MASK (cutoff 0.5
    unless given) -> "mask", BLEND -> "blend", OPAQUE or None -> opaque; any other value is
    rendered opaque with a note in `dropped`."""
    if mode == "MASK":
        if cutoff is None:
            cutoff = 0.5
        if (isinstance(cutoff, bool) or not isinstance(cutoff, (int, float))
                or not 0 <= cutoff <= FLOAT32_MAX):  # NaN fails too; Material's float32 range
            dropped.append(f"alphaCutoff {cutoff!r} is not a number >= 0 within float32's range "
                           "(using 0.5)")
            cutoff = 0.5
        return {"alpha_mode": "mask", "alpha_cutoff": float(cutoff)}
    if mode == "BLEND":
        return {"alpha_mode": "blend"}
    if mode not in (None, "OPAQUE"):
        dropped.append(f"alphaMode {mode!r:.40} is not a glTF alpha mode: rendered opaque")
    return {}


def _gltf_list(doc: dict[str, Any], key: str, index: Any) -> dict[str, Any] | None:
    """doc[key][index] if it is there (and a dict), else None."""
    items = doc.get(key)
    if (isinstance(index, int) and not isinstance(index, bool) and isinstance(items, list)
            and 0 <= index < len(items) and isinstance(items[index], dict)):
        return items[index]
    return None


def _gltf_sampler(sampler: dict[str, Any] | None) -> tuple[str, tuple[str, str]]:
    """(filter, (wrap_u, wrap_v)) of a glTF sampler (None: the defaults, trilinear and repeat)."""
    sampler = sampler or {}
    wrap = tuple(_GLTF_WRAPS.get(sampler.get(k, 10497), "repeat") for k in ("wrapS", "wrapT"))
    mag, minify = sampler.get("magFilter"), sampler.get("minFilter")
    if minify == _GL_NEAREST or (mag == _GL_NEAREST and minify in (None, _GL_NEAREST_MIPMAP_NEAREST)):
        filt = "nearest"
    elif minify == _GL_LINEAR:
        filt = "bilinear"
    else:
        filt = "trilinear"
    return filt, wrap  # type: ignore[return-value]


def _gltf_textures(entry: dict[str, Any], pbr: dict[str, Any], info: FileInfo, mat: Any,
                   dropped: list[str]) -> dict[str, Any]:
    """The Material texture arguments of a glTF material (entry, its pbrMetallicRoughness):
    the images trimesh decoded into ``mat``, each with its texture's sampler; what is not drawn
    goes to ``dropped``."""
    doc = info.gltf_doc or {}
    out: dict[str, Any] = {}
    for where, key, slot in _GLTF_SLOTS:
        ref = (pbr if where == "pbr" else entry).get(key)
        if ref is None:
            continue
        fallback = _GLTF_FALLBACK[key]
        if not isinstance(ref, dict) or "index" not in ref:
            dropped.append(f"{key} {ref!r:.60} is not a texture reference: not drawn{fallback}")
            continue
        index = ref["index"]
        tex_entry = _gltf_list(doc, "textures", index)
        coord = ref.get("texCoord", 0)
        if coord != 0:
            dropped.append(f"{key} uses texCoord {coord!r:.20} and only TEXCOORD_0 is read: not "
                           f"drawn{fallback}")
            continue
        for ext in (ref.get("extensions") or {}) if isinstance(ref.get("extensions"), dict) else ():
            dropped.append(f"{key}: extension {ext} is ignored")
        image = getattr(mat, key, None) if mat is not None else None
        if image is None:
            if not _have_pillow():
                continue  # said once for the file
            if tex_entry is None:
                why = f"refers to texture {index!r:.20}, which the file does not have"
            else:
                source = _gltf_list(doc, "images", tex_entry.get("source"))
                if source is not None and source.get("mimeType") == "image/ktx2":
                    why = "is a KTX2 image, which trimesh does not read"
                else:
                    why = f"(texture {index}): its image could not be read"
            dropped.append(f"{key} {why}: not drawn{fallback}")
            continue
        tex_entry = tex_entry or {}
        filt, wrap = _gltf_sampler(_gltf_list(doc, "samplers", tex_entry.get("sampler")))
        source = _gltf_list(doc, "images", tex_entry.get("source")) or {}
        name = source.get("name") if isinstance(source.get("name"), str) else None
        uri = source.get("uri")
        if name is None and isinstance(uri, str) and not uri.startswith("data:"):
            name = os.path.basename(uri)
        texture, why = _pil_texture(image, info, filt, wrap, name)
        if texture is None:
            dropped.append(f"{key} (texture {index}) {why}: not drawn{fallback}")
            continue
        out[slot] = texture
        if key == "normalTexture" and "scale" in ref:
            scale = ref["scale"]
            if (isinstance(scale, (int, float)) and not isinstance(scale, bool)
                    and abs(scale) <= FLOAT32_MAX):  # NaN fails too; Material's float32 range
                out["normal_scale"] = float(scale)
            else:
                dropped.append(f"normalTexture scale {scale!r:.40} is not a number (using 1)")
        if key == "occlusionTexture" and "strength" in ref:
            strength = ref["strength"]  # glTF: in [0, 1], default 1
            if (isinstance(strength, (int, float)) and not isinstance(strength, bool)
                    and math.isfinite(strength)):
                clipped = min(max(float(strength), 0.0), 1.0)
                if clipped != strength:
                    dropped.append(f"occlusionTexture strength {strength!r:.40} clipped to [0, 1]")
                out["occlusion_strength"] = clipped
            else:
                dropped.append(f"occlusionTexture strength {strength!r:.40} is not a number "
                               "(using 1)")
    return out
