"""What mesh files carry besides geometry: colours, materials, parts and node transforms.

``softrast.load_mesh`` (one Mesh) and ``softrast.load_scene`` (a Scene, one instance per part)
read files with trimesh and keep, with these conventions:

* Per-vertex and per-face colours. A Mesh has only per-vertex colours, so a file with per-face
  colours (PLY ``face`` red/green/blue, trimesh ``visual.kind == "face"``) gets three vertices of
  its own per face, carrying the face's colour (faces keep their order, so ``triangle_id`` still
  indexes the file's faces; smooth normals are the original vertex's).
* Colour spaces. Colours stored in PLY, OBJ, OFF (and STL) files are 8-bit sRGB by convention:
  they are decoded to linear with the exact IEC 61966-2-1 curve (c <= 0.04045 ? c / 12.92 :
  ((c + 0.055) / 1.055) ** 2.4), so an ``unlit`` render with the default sRGB output gives back
  the file's bytes. Alpha is linear and only scaled (/ 255). glTF ``COLOR_0`` is linear (glTF
  spec) and kept as is, multiplied by the material's ``baseColorFactor`` as glTF prescribes.
  MTL colours (Ka, Kd, Ks) and glTF factors are linear.
* OBJ + MTL: ``Ka Kd Ks Ns d`` (and ``Ke``) -> ``Material(ka=Ka, kd=Kd, base_color=(Kd, d),
  ks=Ks, shininess=Ns, emissive=Ke, metallic=0, roughness=R, model="pbr", name=newmtl)``, read
  from the MTL file itself (trimesh keeps them only as 8-bit values). Absent: Kd -> base colour
  0.8 grey, Ka -> kd, Ks -> no specular (0), Ns -> 32, d -> 1. A negative Ns is read as 0,
  with a warning naming the file and material.
* MTL transparency: ``d`` (dissolve, clipped to [0, 1]) < 1 -> ``alpha_mode="blend"`` with
  base colour alpha d (``softrast.Material`` says how blending is drawn; a ``map_Kd`` image's
  alpha multiplies d); ``d 1`` (or no ``d``) stays opaque. ``Tr`` (not in Wavefront's spec)
  is read only where the material has no ``d`` (where it has both, ``d`` is read and ``Tr``
  ignored, as tinyobjloader does). Exporters disagree on what it means: transparency, d = 1 -
  Tr (tinyobjloader's and three.js's reading, so ``Tr 0`` is opaque), or opacity, d = Tr
  (Meshlab and 3ds Max, so ``Tr 1`` is opaque: assets/meshes/fuze's MTL, a Meshlab export,
  says ``Tr 1.000000``). softrast reads ``Tr`` t in (0, 1) as transparency (d = 1 - t,
  blended) and both ends, ``Tr 0`` and ``Tr 1``, as opaque, the only readings that do not make
  one convention's opaque material invisible; a Meshlab ``Tr 0.3`` (meaning d 0.3) is drawn
  with alpha 0.7. trimesh (5.2) reads neither ``d`` nor ``Tr``: it keeps them as unparsed
  strings in ``SimpleMaterial.kwargs`` and its diffuse alpha stays 255, so
  ``pyrender.Mesh.from_trimesh`` draws such a material opaque (alphaMode BLEND at alpha 1),
  where softrast blends it. ``Mesh.from_trimesh`` blends a ``SimpleMaterial`` whose diffuse
  alpha is below 255 (what pyrender's BLEND does with it).
* How MTL materials are lit (``render(shading="auto")``): as the rough dielectric that
  pyrender (through ``pyrender.Mesh.from_trimesh``) and Blender's OBJ importer draw, not as
  Blinn-Phong: model "pbr", base colour Kd (times ``map_Kd``), metallic 0, and
  ``R = (2 / (Ns + 2)) ** 0.25``, the specular exponent's mapping of trimesh's
  ``SimpleMaterial.to_pbr`` and pyrender's ``Mesh.from_trimesh`` (Ns 0 -> 1, 1 -> 0.90, 10 ->
  0.64, 200 -> 0.32, 1000 -> 0.21); a material without a highlight (Ks absent or black) gets
  R = 1, the roughest. So ``Ns 0`` (what Meshlab writes, e.g. with ``Ks 1 1 1``) is a matte
  surface, where Blinn-Phong's (n.h)^0 = 1 added Ks everywhere and washed the surface out to
  white. The dielectric's specular reflectance is glTF's 4% whatever Ks (pbr has no specular
  level), and Ka is not used (the ambient light times the base colour, as glTF). Differences
  from the tools: pyrender 0.1.45 leaves metallicFactor at 1 (every MTL material a metal: no
  diffuse term, Kd as the specular colour), ignores Ns (it looks up ``"Ns"`` where trimesh
  stores ``"ns"``: roughness 0.90 always) and uses 0.4 grey for an absent Kd; Blender's
  importer (obj_import_mtl.cc) maps roughness = 1 - sqrt(min(Ns, 1000) / 1000) (also 1 for Ns
  0), metallic 0 but for the ray-traced reflection ``illum`` modes (3 and others: the mean of
  Ka), the specular level from the mean of Ks, and reads the PBR extension's ``Pr`` / ``Pm``;
  softrast reads neither ``illum`` nor ``Pr`` / ``Pm``. Like every ``pbr`` material, the
  diffuse term is base / pi per unit of light intensity (glTF's and pyrender's units), where
  ``lambert`` and Blinn-Phong give kd: under the same lights an MTL surface is about a third
  as bright as it was drawn before this rule (issue 33). An explicit
  ``shading="blinn_phong"`` (or "phong", "lambert") still uses ka, kd, ks and shininess = Ns
  as written. ``Mesh.from_trimesh`` applies the same rule to a trimesh ``SimpleMaterial`` (its
  8-bit Ks and its glossiness as Ns).
* glTF / GLB: ``pbrMetallicRoughness.baseColorFactor`` (default 1), ``metallicFactor`` (default 1),
  ``roughnessFactor`` (default 1), ``emissiveFactor`` (default 0), ``doubleSided`` (default
  false) -> ``Material(base_color=, metallic=, roughness=, emissive=, double_sided=,
  model="pbr", name=)``, read exactly from the file's JSON; ``KHR_materials_unlit`` -> model
  "unlit". A primitive without a material gets none (softrast's default look).

Textures (``softrast.Texture``, see ``softrast.texture``):

* uvs. trimesh flips glTF's v on load (``v = 1 - v``: glTF puts image row 0 at v = 0), so the
  uvs of every loaded mesh are OpenGL-style, as OBJ ``vt`` are: v up, image row 0 at v = 1.
  Every texture is therefore made with ``uv_origin="bottom_left"``, and normal maps are
  OpenGL-style (green = +v = towards the image's top, which is glTF's convention too).
* glTF: ``baseColorTexture`` -> ``base_color_texture`` (multiplying ``baseColorFactor`` and
  ``COLOR_0``), ``emissiveTexture`` -> ``emissive_texture`` (multiplying ``emissiveFactor``,
  default 0 as glTF says), ``normalTexture`` -> ``normal_texture`` with its ``scale`` ->
  ``normal_scale``, ``metallicRoughnessTexture`` -> ``metallic_roughness_texture`` (green x
  ``roughnessFactor``, blue x ``metallicFactor``), ``occlusionTexture`` -> ``occlusion_texture``
  (red) with its ``strength`` (default 1, clipped to [0, 1] with a warning) ->
  ``occlusion_strength``. An image used by several slots (an occlusion-roughness-metallic image
  named by both ``occlusionTexture`` and ``metallicRoughnessTexture``) is one Texture. Every
  Texture is made with ``srgb=None``, so the material slot decides: base colour and emissive
  are decoded from sRGB, normal, metallic-roughness and occlusion read linear, as glTF says.
  The images are the ones trimesh decodes with Pillow (a dependency: without it trimesh drops
  every image, with a warning naming the file), 1 to 4 channels of uint8 as stored (L, LA,
  RGB, RGBA; palette images become RGB, or RGBA if they have transparency; 16-bit grey stays
  uint16). The texture's sampler: ``wrapS`` / ``wrapT`` 10497 -> "repeat"
  (the default), 33071 -> "clamp", 33648 -> "mirror"; the filter from ``minFilter`` (NEAREST ->
  "nearest", LINEAR -> "bilinear", the mipmapped ones and none -> "trilinear", except
  NEAREST_MIPMAP_NEAREST, or no minFilter, with magFilter NEAREST -> "nearest"). A texture read
  through ``texCoord`` other than 0 is not drawn (trimesh reads only TEXCOORD_0);
  ``KHR_texture_transform`` is ignored (with a warning).
* MTL: ``map_Kd`` -> ``base_color_texture`` (the material then has ``kd=None``, so the texture
  multiplies Kd, as MTL prescribes; without Kd, white), ``map_Ke`` -> ``emissive_texture``
  (multiplying Ke; without Ke, white), ``norm`` -> ``normal_texture`` (a tangent-space normal
  map; ``-bm`` -> ``normal_scale``), ``map_Ks`` -> ``specular_texture`` (read linear; it
  multiplies Ks, white without Ks; drawn by ``shading="phong"`` / ``"blinn_phong"``, since
  ``pbr``, the MTL materials' own model, has no specular level), ``map_Bump`` / ``bump`` (a height map) -> ``bump_texture``
  with ``-bm`` (MTL's bump multiplier, default 1) -> ``bump_scale``; its first (red) channel is
  the height, so a colour (not grey) height map gets a warning unless it says ``-imfchan r``
  (MTL's default is luminance). An RGB ``map_Bump`` / ``bump`` image that is plainly a
  tangent-space normal map (mean colour near (0.5, 0.5, 1): what Blender writes there) is drawn
  as the normal map instead (``-bm`` -> ``normal_scale``), with a warning saying so; if the
  material's ``norm`` map is drawn, such an image is ignored, with a warning. A height map
  with a ``norm`` map is kept too (the material has both), but the renderer draws the normal
  map where a material has both, so a warning notes that the bump map is not drawn. A second
  ``map_Bump`` / ``bump`` statement in one material is ignored, with a warning. File names are
  relative to the MTL file (backslashes are read as separators); images are read with
  ``softrast.load_texture``; ``-clamp on`` -> wrap "clamp", other options are ignored with a
  warning. ``Mesh.from_trimesh``: a SimpleMaterial's image -> ``base_color_texture``; a
  PBRMaterial's five images -> the five glTF slots above (trimesh keeps no sampler, normal scale
  or occlusion strength: trilinear, repeat, 1 and 1).
* Within one load, an image is one Texture however many materials and instances use it.
* A textured material on a mesh without uvs loses its textures, with a warning.

* glTF ``alphaMode`` MASK and ``alphaCutoff`` -> ``alpha_mode="mask"``, ``alpha_cutoff``;
  BLEND -> ``alpha_mode="blend"`` (the alpha: ``baseColorFactor``'s times ``COLOR_0``'s times
  the ``baseColorTexture``'s, as glTF says); OPAQUE (or none) -> "opaque".

Whatever a file carries that softrast cannot draw yet (textures read through ``texCoord``
other than 0, ``KHR_texture_transform`` and other texture or material extensions; MTL
``map_Ka``, ``map_Ns``, ``map_d``, ``disp``, ``decal``, ``refl`` and the PBR maps ``map_Pr``,
``map_Pm``, ``map_Ps``, ``map_RMA``, ``map_ORM``, map options other than ``-clamp``, ``-bm``
(on ``norm`` and bump maps) and ``-imfchan r`` (on bump maps)) is dropped with a
``UserWarning`` naming the file, the material and what was dropped: never silently; so is a
texture that cannot be read.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import struct
import sys
import warnings
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ._checks import FLOAT32_MAX
from .material import Material
from .texture import Texture

__all__ = ["load_scene", "srgb_to_linear"]

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
# MTL statements naming texture maps (lower case). map_Kd, map_Ke, norm and map_Bump / bump
# (a height map, or a normal map) are drawn; the others are dropped with a warning.
_MTL_MAPS = ("map_ka", "map_kd", "map_ks", "map_ns", "map_d", "map_ke", "map_bump", "bump",
             "disp", "decal", "refl", "norm", "map_pr", "map_pm", "map_ps", "map_rma", "map_orm")
_MTL_SLOTS = {"map_kd": "base_color_texture", "map_ke": "emissive_texture", "norm": "normal_texture",
              "map_ks": "specular_texture"}
# MTL map options and how many arguments each takes ((1, 3): one to three numbers)
_MTL_OPTIONS = {"-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1,
                "-imfchan": 1, "-mm": 2, "-o": (1, 3), "-s": (1, 3), "-t": (1, 3), "-texres": 1,
                "-type": 1}


def srgb_to_linear(c: Any) -> np.ndarray:
    """Exact IEC 61966-2-1 sRGB decoding of values in [0, 1] (float64)."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


_SRGB8 = srgb_to_linear(np.arange(256) / 255.0)  # 8-bit code -> linear


def _colors8(u8: Any, srgb: bool) -> np.ndarray:
    """(n, 3|4) 8-bit colours -> (n, 4) float64 linear RGBA (alpha only scaled)."""
    arr = np.asarray(u8)
    if arr.dtype != np.uint8:  # trimesh's colours are uint8; anything else as 0..255 numbers
        arr = np.clip(np.rint(np.asarray(arr, dtype=np.float64)), 0, 255).astype(np.uint8)
    out = np.ones((arr.shape[0], 4), dtype=np.float64)
    out[:, :3] = _SRGB8[arr[:, :3]] if srgb else arr[:, :3] / 255.0
    if arr.shape[1] == 4:
        out[:, 3] = arr[:, 3] / 255.0
    return out


def _normalized(values: Any) -> np.ndarray:
    """glTF COLOR_0 accessor data (float, or normalized unsigned byte / short) -> (n, 4) float64."""
    arr = np.asarray(values)
    if arr.ndim != 2 or arr.shape[1] not in (3, 4):
        raise ValueError(f"COLOR_0 must have 3 or 4 components, got shape {arr.shape}")
    if np.issubdtype(arr.dtype, np.integer):
        arr = arr / float(np.iinfo(arr.dtype).max)
    arr = np.clip(np.asarray(arr, dtype=np.float64), 0.0, 1.0)
    if arr.shape[1] == 3:
        arr = np.hstack([arr, np.ones((arr.shape[0], 1))])
    return arr


# -- what a file says about its materials --------------------------------------------------------
@dataclass
class _FileInfo:
    """Per-load context: the file (for warnings), its colour convention and exact materials."""

    source: str | None  # the path as given; None for Mesh.from_trimesh
    srgb: bool  # 8-bit colours are sRGB-encoded (PLY / OBJ / OFF / STL); False for glTF
    gltf: list[Any] | None = None  # the glTF JSON "materials" list
    mtl: dict[str, _MtlEntry] | None = None  # newmtl name -> its material, read from the MTL
    soup: bool = False  # the format stores no shared vertices (STL): smooth=True merges them
    warned: set[Any] = field(default_factory=set)
    gltf_doc: dict[str, Any] | None = None  # the whole glTF JSON (textures, samplers, images)
    # One Texture per image (and sampler) within one load: key -> (what keeps the key's id
    # alive, Texture or None, why not)
    textures: dict[Any, tuple[Any, Texture | None, str | None]] = field(default_factory=dict)
    materials: dict[Any, tuple[Material | None, list[str]]] = field(default_factory=dict)

    def warn(self, key: Any, text: str) -> None:
        if key in self.warned:
            return
        self.warned.add(key)
        warnings.warn((f"{self.source}: " if self.source else "") + text, UserWarning,
                      stacklevel=_caller_level())


@dataclass
class _MtlMap:
    statement: str  # as written (map_Kd, norm, ...)
    file: str  # the file name as written
    options: dict[str, list[str]]  # option -> its arguments


@dataclass
class _MtlEntry:
    material: Material  # without textures
    dropped: list[str]
    maps: list[_MtlMap]
    folder: str  # the MTL file's folder: map file names are relative to it
    ke_given: bool  # the material states Ke (else map_Ke multiplies white)
    ks_given: bool = False  # the material states Ks (else map_Ks multiplies white)
    resolved: tuple[Material, list[str]] | None = None


_PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))


def _caller_level() -> int:
    """The stacklevel of the first frame outside softrast (the user's load_mesh call)."""
    frame, level = sys._getframe(1), 1
    while frame is not None and os.path.dirname(os.path.abspath(frame.f_code.co_filename)) == _PACKAGE_DIR:
        frame, level = frame.f_back, level + 1
    return level


def _file_info(path_str: str) -> _FileInfo:
    ext = os.path.splitext(path_str)[1].lower()
    if ext in (".gltf", ".glb"):
        info = _FileInfo(path_str, srgb=False)
        try:
            doc = _gltf_doc(path_str)
            mats = doc.get("materials", [])
            info.gltf = mats if isinstance(mats, list) else []
            info.gltf_doc = doc
        except (OSError, ValueError, UnicodeDecodeError, struct.error):
            info.gltf = []  # check_mesh_file has refused broken JSON already
        images = (info.gltf_doc or {}).get("images")
        if isinstance(images, list) and images and not _have_pillow():
            info.warn("pillow", f"Pillow is not installed, so trimesh drops this file's {len(images)} "
                                "image(s): its textures are not drawn (Pillow is a softrast "
                                "dependency: pip install pillow)")
        return info
    info = _FileInfo(path_str, srgb=True, soup=ext == ".stl")
    if ext == ".obj":
        info.mtl = _obj_materials(path_str, info)
    return info


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
    from .limits import check_budget

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


def _pil_texture(image: Any, info: _FileInfo, filter: str = "trilinear",
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


def _file_texture(path: str, info: _FileInfo, wrap: str) -> tuple[Texture | None, str | None]:
    """(Texture, None) for an image file (softrast.load_texture), or (None, why not); one Texture
    per file and wrap within a load."""
    from .texture import load_texture

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


def _gltf_doc(path_str: str) -> dict[str, Any]:
    """The JSON of a .gltf or .glb (only its JSON chunk is read)."""
    with open(path_str, "rb") as f:
        head = f.read(20)
        if head[:4] == b"glTF":
            _, _, _, length, _ = struct.unpack("<4sIII4s", head)
            text = f.read(length)
        else:
            text = head + f.read()
    doc = json.loads(text)
    return doc if isinstance(doc, dict) else {}


def _first_mtllib(path_str: str) -> str | None:
    """The ``mtllib`` file name as trimesh reads it: the rest of the line after the file's first
    "mtllib" (trimesh loads only that one)."""
    tail = b""
    with open(path_str, "rb") as f:
        while True:
            block = f.read(1 << 20)
            if not block:
                break
            text = tail + block
            at = text.find(b"mtllib")
            if at >= 0:
                line = text[at + 6:]
                while b"\n" not in line and b"\r" not in line:
                    more = f.read(1 << 16)
                    if not more:
                        break
                    line += more
                return line.splitlines()[0].decode("utf-8", "replace").strip() if line else ""
            tail = text[-5:]
    return None


def _obj_materials(path_str: str, info: _FileInfo) -> dict[str, _MtlEntry]:
    name = _first_mtllib(path_str)
    if name is None:
        return {}
    folder = os.path.dirname(os.path.abspath(path_str))
    for candidate in (os.path.join(folder, name), os.path.join(folder, os.path.basename(name))):
        if name and os.path.isfile(candidate):
            try:
                with open(candidate, "rb") as f:
                    text = f.read().decode("utf-8", "replace")
            except OSError as exc:
                info.warn("mtllib", f"mtllib {name!r} could not be read ({exc}): its materials are "
                                    "dropped, faces render in the default grey")
                return {}
            return _parse_mtl(text, name, info, os.path.dirname(candidate))
    info.warn("mtllib", f"mtllib {name!r} not found next to the OBJ: its materials are dropped, "
                        "faces render in the default grey")
    return {}


def _mtl_color(words: list[str], key: str, where: str, info: _FileInfo) -> tuple[float, ...] | None:
    if words and words[0].lower() in ("spectral", "xyz"):
        info.warn((where, key), f"{where}: {key} {' '.join(words)}: only RGB colours are read; "
                                f"{key} is dropped")
        return None
    try:
        values = [float(w) for w in words[:3]]
    except ValueError:
        info.warn((where, key), f"{where}: {key} {' '.join(words)!r} is not a colour; dropped")
        return None
    if not values or not all(math.isfinite(v) for v in values):
        info.warn((where, key), f"{where}: {key} {' '.join(words)!r} is not a colour; dropped")
        return None
    if len(values) < 3:  # "Kd 0.5": g and b default to r
        values = [values[0]] * 3
    clipped = tuple(min(max(v, 0.0), 1.0) for v in values)
    if clipped != tuple(values):
        info.warn((where, key, "clip"), f"{where}: {key} {values} clipped to [0, 1]: {list(clipped)}")
    return clipped


def _mtl_map(words: list[str], where: str, info: _FileInfo) -> _MtlMap | None:
    """A map statement's options and file name (the words after the options, joined)."""
    options: dict[str, list[str]] = {}
    i = 1
    while i < len(words) - 1 and words[i].lower() in _MTL_OPTIONS:
        option, count = words[i].lower(), _MTL_OPTIONS[words[i].lower()]
        i += 1
        if isinstance(count, tuple):  # -o / -s / -t: one to three numbers
            args = []
            while len(args) < count[1] and i < len(words) - 1:
                try:
                    float(words[i])
                except ValueError:
                    break
                args.append(words[i])
                i += 1
        else:
            args = words[i:i + count]
            i += count
        options[option] = args
    if i >= len(words):
        info.warn((where, words[0], "file"), f"{where}: {' '.join(words)!r} names no file; dropped")
        return None
    return _MtlMap(words[0], " ".join(words[i:]), options)


_MTL_NS_DEFAULT = 32.0  # Ns when an MTL material gives none (softrast.Material's shininess default)


def _mtl_roughness(ks: Sequence[float] | None, ns: float) -> float:
    """The ``pbr`` roughness of an MTL material (or a trimesh SimpleMaterial): trimesh's and
    pyrender's mapping of the specular exponent, ``(2 / (Ns + 2)) ** 0.25`` (Ns 0 -> 1, 10 ->
    0.64, 200 -> 0.32), or 1, the roughest, for a material without a highlight (``Ks`` absent or
    black)."""
    if ks is None or max(ks) <= 0.0:
        return 1.0
    return (2.0 / (max(ns, 0.0) + 2.0)) ** 0.25


def _parse_mtl(text: str, mtl_name: str, info: _FileInfo, folder: str = "") -> dict[str, _MtlEntry]:
    """newmtl name -> its entry (Material without textures, what is dropped, its maps) from MTL
    text; ``folder`` is where the MTL's map file names are relative to."""
    found: dict[str, _MtlEntry] = {}
    current: dict[str, Any] | None = None

    def finish() -> None:
        if current is None:
            return
        name = current["name"]
        where = f"material {name!r}"
        kd = current.get("kd")
        dropped = list(current["dropped"])
        # d wins over Tr (tinyobjloader's rule); Tr t in (0, 1) alone is d = 1 - t, Tr 1 is
        # opaque (Meshlab and 3ds Max write Tr meaning d: "Tr 1" is their opaque material)
        tr = current.get("tr", 0.0)
        d = current.get("d", 1.0 - tr if tr < 1.0 else 1.0)
        maps = current["maps"]
        ks, ns = current.get("ks"), current.get("ns", _MTL_NS_DEFAULT)
        kwargs: dict[str, Any] = {
            "base_color": (*kd, d) if kd is not None else (0.8, 0.8, 0.8, d),
            "ka": current.get("ka"), "kd": kd, "ks": ks, "shininess": ns,
            "metallic": 0.0, "roughness": _mtl_roughness(ks, ns), "model": "pbr", "name": name,
        }
        if d < 1.0:  # MTL transparency: blended with base colour alpha d
            kwargs["alpha_mode"] = "blend"
        if "ke" in current:
            kwargs["emissive"] = current["ke"]
        try:
            found[name] = _MtlEntry(Material(**kwargs), dropped, maps, folder, "ke" in current,
                                    "ks" in current)
        except (TypeError, ValueError) as exc:  # cannot happen after the clipping above
            info.warn((where, "bad"), f"{where} in {mtl_name!r} is invalid ({exc}); dropped")

    for raw in text.splitlines():
        words = raw.split("#", 1)[0].split()
        if len(words) < 2:
            continue
        key = words[0].lower()
        if key == "newmtl":
            finish()
            current = {"name": " ".join(words[1:]), "dropped": [], "maps": []}
            continue
        if current is None:
            continue
        where = f"material {current['name']!r}"
        if key in ("ka", "kd", "ks", "ke"):
            value = _mtl_color(words[1:], words[0], where, info)
            if value is not None:
                current[key] = value
        elif key in ("ns", "d", "tr"):
            try:
                v = float(words[1])
                if not math.isfinite(v):
                    raise ValueError
            except ValueError:
                info.warn((where, key), f"{where}: {words[0]} {words[1]!r} is not a number; dropped")
                continue
            if key == "ns":
                if v < 0.0:
                    info.warn((where, "ns<0"), f"{where}: {words[0]} {words[1]} is negative: read as 0 "
                                               "(no highlight)")
                current["ns"] = min(max(v, 0.0), FLOAT32_MAX)  # Material's (float32) range
            else:  # d, or Tr (1 - d): clipped to [0, 1]
                current[key] = min(max(v, 0.0), 1.0)
        elif key in _MTL_MAPS:
            if key in _MTL_SLOTS or key in ("map_bump", "bump"):
                entry = _mtl_map(words, where, info)
                if entry is not None:
                    current["maps"].append(entry)
            else:
                current["dropped"].append(f"{words[0]} {words[-1]!r} is not drawn yet")
        # other statements (illum, Ni, Tf, ...) are not read
    finish()
    return found


def _mtl_path(folder: str, name: str) -> str | None:
    """The file a map names: relative to the MTL's folder, backslashes read as separators, else
    the bare file name in that folder."""
    slashed = name.replace("\\", "/")
    for candidate in (name, slashed, os.path.basename(slashed)):
        path = os.path.join(folder, candidate)
        if candidate and os.path.isfile(path):
            return path
    return None


def _mtl_resolve(entry: _MtlEntry, info: _FileInfo) -> tuple[Material, list[str]]:
    """The MTL material with its textures (read on first use, shared within the load).

    ``map_Bump`` / ``bump`` (the first that can be read; a second is ignored): a height map ->
    ``bump_texture``, ``-bm`` -> ``bump_scale``; an RGB image that looks like a tangent-space
    normal map -> ``normal_texture``, ``-bm`` -> ``normal_scale`` (with a warning), unless the
    material's ``norm`` map is drawn (then it is ignored, with a warning). A height map next to a
    drawn ``norm`` map is kept as ``bump_texture`` but not drawn (a material draws its bump map
    only without a normal map), with a note.
    """
    if entry.resolved is not None:
        return entry.resolved
    dropped = list(entry.dropped)
    textures: dict[str, Any] = {}
    bump_seen = False
    normal_like: tuple[str, Texture, float | None] | None = None  # a bump map holding a normal map
    bump_what = ""
    for m in entry.maps:
        statement = m.statement.lower()
        bump = statement in ("map_bump", "bump")
        what = f"{m.statement} {m.file!r}"
        if bump and bump_seen:
            dropped.append(f"{what}: a second bump map is ignored")
            continue
        scaled = statement not in ("map_kd", "map_ke", "map_ks")  # -bm: normal_scale, bump_scale
        red = bump and [a.lower() for a in m.options.get("-imfchan", [])] == ["r"]
        ignored = []
        for option, args in m.options.items():
            identity = ((option == "-o" and all(float(a) == 0.0 for a in args))
                        or (option == "-s" and all(float(a) == 1.0 for a in args)))
            if (option == "-clamp" or identity or (option == "-bm" and scaled)
                    or (option == "-imfchan" and red)):
                continue
            ignored.append(" ".join([option] + args))
        if ignored:
            dropped.append(f"{what}: option(s) {', '.join(ignored)} ignored")
        path = _mtl_path(entry.folder, m.file)
        if path is None:
            dropped.append(f"{what} not found next to the MTL file: not drawn")
            continue
        clamp = [a.lower() for a in m.options.get("-clamp", ["off"])[:1]] == ["on"]
        tex, why = _file_texture(path, info, "clamp" if clamp else "repeat")
        if tex is None:
            dropped.append(f"{what} {why}: not drawn")
            continue
        bump_seen = bump_seen or bump
        scale = None
        if scaled and "-bm" in m.options:
            try:
                scale = float(m.options["-bm"][0])
                if not abs(scale) <= FLOAT32_MAX:  # inf and NaN too: Material's (float32) range
                    raise ValueError
            except (ValueError, IndexError):
                scale = None
                dropped.append(f"{what}: -bm {' '.join(m.options['-bm'])!r} is not a number; ignored")
        if bump and _looks_like_normal_map(tex):
            normal_like = (what, tex, scale)  # drawn as the normal map if there is no norm
            continue
        slot = "bump_texture" if bump else _MTL_SLOTS[statement]
        if slot in textures:
            dropped.append(f"{what}: a second {slot} is ignored")
            continue
        textures[slot] = tex
        if scale is not None:
            textures["bump_scale" if bump else "normal_scale"] = scale
        if bump:
            bump_what = what
            if not red and not _is_grey(tex):
                dropped.append(f"{what} is a colour image: its red channel is read as the height")
    if normal_like is not None:
        what, tex, scale = normal_like
        if "normal_texture" in textures:
            dropped.append(f"{what} looks like a tangent-space normal map, and the material's norm "
                           "map is drawn: ignored")
        else:
            dropped.append(f"{what} looks like a tangent-space normal map (RGB, mean colour near "
                           "(0.5, 0.5, 1)): drawn as one (name it with 'norm' to say so)")
            textures["normal_texture"] = tex
            if scale is not None:
                textures["normal_scale"] = scale
    elif "normal_texture" in textures and "bump_texture" in textures:
        dropped.append(f"{bump_what} (a height map) is kept as bump_texture but not drawn: the "
                       "norm map is drawn in its place")
    material = entry.material
    if "base_color_texture" in textures:
        # map_Kd multiplies Kd (white without Kd): kd is the base colour, which the texture
        # multiplies; Ka, if given, stays
        rgb = material.kd if material.kd is not None else (1.0, 1.0, 1.0)
        textures.update(kd=None, base_color=(*rgb, material.base_color[3]))
    if "emissive_texture" in textures and not entry.ke_given:
        textures["emissive"] = (1.0, 1.0, 1.0)  # map_Ke multiplies Ke, white without it
    if "specular_texture" in textures and not entry.ks_given:
        textures["ks"] = (1.0, 1.0, 1.0)  # map_Ks multiplies Ks, white without it
    if textures:
        material = material.replace(**textures)
    entry.resolved = (material, dropped)
    return entry.resolved


def _gltf_material(index: int, entry: Any, info: _FileInfo, mat: Any = None) -> tuple[Material, list[str]]:
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


def _gltf_textures(entry: dict[str, Any], pbr: dict[str, Any], info: _FileInfo, mat: Any,
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


def _u8(value: Any) -> tuple[int, ...] | None:
    if value is None:
        return None
    return tuple(int(v) for v in np.asarray(value).reshape(-1))


def _gltf_index(mat: Any, info: _FileInfo) -> int | None:
    """Which of the file's glTF materials trimesh's PBRMaterial ``mat`` was built from.

    trimesh keeps the factors (baseColorFactor only as 8 bits) and the name but not the index, so
    the candidates are the file's materials whose values agree with ``mat``; among equals, the
    first (their exact values can then differ only below 8 bits, in base colour).
    """
    from trimesh.visual.color import to_rgba

    entries = info.gltf or []

    def agrees(entry: Any, strict: bool) -> bool:
        if not isinstance(entry, dict):
            return False
        name = entry.get("name") if isinstance(entry.get("name"), str) else None
        if name != getattr(mat, "name", None):
            return False
        if not strict:
            return True
        pbr = entry.get("pbrMetallicRoughness", {})
        pbr = pbr if isinstance(pbr, dict) else {}
        try:
            if "baseColorFactor" in pbr and _u8(to_rgba(pbr["baseColorFactor"])) != _u8(mat.baseColorFactor):
                return False
            for key in ("metallicFactor", "roughnessFactor"):
                if key in pbr and getattr(mat, key) is not None and float(pbr[key]) != getattr(mat, key):
                    return False
        except (TypeError, ValueError):
            return False
        for where, key, _ in _GLTF_SLOTS:  # a texture trimesh read is one the entry names
            if getattr(mat, key, None) is not None and key not in (pbr if where == "pbr" else entry):
                return False
        return bool(entry.get("doubleSided", False)) == bool(mat.doubleSided)

    for strict in (True, False):
        for i, entry in enumerate(entries):
            if agrees(entry, strict):
                return i
    return None


def _trimesh_material(mat: Any, info: _FileInfo) -> tuple[Material | None, list[str], Any]:
    """(Material or None, dropped, key for warning once) for a trimesh material object."""
    from trimesh.visual import material as tmat

    if mat is None:
        return None, [], None
    if isinstance(mat, tmat.PBRMaterial):
        if info.gltf is not None:
            index = _gltf_index(mat, info)
            if index is not None:
                key = ("gltf", index)
                cached = info.materials.get((key, id(mat)))
                if cached is None:
                    cached = info.materials[(key, id(mat))] = _gltf_material(
                        index, info.gltf[index], info, mat)
                return cached[0], cached[1], key
        # from trimesh's values (8-bit base colour): Mesh.from_trimesh, or no match in the file.
        # trimesh keeps no sampler, normal scale or occlusion strength: the defaults (trilinear,
        # repeat, 1, 1).
        dropped: list[str] = []
        textures: dict[str, Any] = {}
        for _, k, slot in _GLTF_SLOTS:
            image = getattr(mat, k, None)
            if image is not None:
                texture, why = _pil_texture(image, info)
                if texture is None:
                    dropped.append(f"{k} {why}: not drawn{_GLTF_FALLBACK[k]}")
                else:
                    textures[slot] = texture
        alpha = _gltf_alpha(mat.alphaMode, mat.alphaCutoff, dropped)
        base = (1.0, 1.0, 1.0, 1.0) if mat.baseColorFactor is None else tuple(
            (np.asarray(mat.baseColorFactor, dtype=np.float64) / 255.0).tolist())
        emissive = (0.0, 0.0, 0.0) if mat.emissiveFactor is None else tuple(
            np.clip(np.asarray(mat.emissiveFactor, dtype=np.float64), 0.0, 1.0).tolist())
        m = Material(base_color=base,
                     metallic=1.0 if mat.metallicFactor is None else min(max(mat.metallicFactor, 0.0), 1.0),
                     roughness=1.0 if mat.roughnessFactor is None else min(max(mat.roughnessFactor, 0.0), 1.0),
                     emissive=emissive, double_sided=bool(mat.doubleSided), model="pbr",
                     name=mat.name if isinstance(mat.name, str) else None, **alpha, **textures)
        return m, dropped, ("pbr", id(mat))
    if isinstance(mat, tmat.SimpleMaterial):
        name = getattr(mat, "_name", None)
        if info.mtl is not None:  # an OBJ: the MTL file's own values, or none
            if name in info.mtl:
                m, dropped = _mtl_resolve(info.mtl[name], info)
                return m, dropped, ("mtl", name)
            return None, [], None
        if name is None and _is_empty(mat):
            return None, [], None  # trimesh's placeholder for UVs without a material
        rgb = [tuple((np.asarray(c, dtype=np.float64)[:3] / 255.0).tolist())
               for c in (mat.ambient, mat.diffuse, mat.specular)]
        alpha = float(np.asarray(mat.diffuse)[3]) / 255.0
        dropped = []
        texture = None
        if mat.image is not None and not _is_empty(mat):
            texture, why = _pil_texture(mat.image, info)
            if texture is None:
                dropped.append(f"its texture image {why}: not drawn")
        # a texture multiplies the diffuse colour: kd is the base colour then
        # the MTL rule (see the module docstring): pbr, metallic 0, roughness from Ks and Ns
        ns = min(max(float(mat.glossiness), 0.0), FLOAT32_MAX)  # Material's (float32) range
        # a diffuse alpha below 1 blends, as MTL's d < 1 (pyrender's from_trimesh: BLEND)
        m = Material(base_color=(*rgb[1], alpha), ka=rgb[0], kd=None if texture is not None else rgb[1],
                     ks=rgb[2], shininess=ns, metallic=0.0, roughness=_mtl_roughness(rgb[2], ns),
                     model="pbr", name=name if isinstance(name, str) else None,
                     base_color_texture=texture, alpha_mode="blend" if alpha < 1.0 else "opaque")
        return m, dropped, ("simple", id(mat))
    return None, [f"a {type(mat).__name__} is not supported"], ("other", id(mat))


def _without_textures(material: Material | None, uvs: Any, where: str, key: Any, info: _FileInfo,
                      plain: Material | None = None) -> Material | None:
    """``material`` without its textures (or ``plain``, the file's material without them) if the
    mesh has no uvs to sample them at, with a warning."""
    if material is None or uvs is not None or not material.textured:
        return material
    slots = [k for k in Material._TEXTURE_SLOTS if getattr(material, k) is not None]
    info.warn(("no uvs", key), f"{where}: the mesh has no uvs, so its {', '.join(slots)} "
                               "cannot be drawn: dropped")
    return plain if plain is not None else material.replace(**{k: None for k in slots})


def _is_empty(mat: Any) -> bool:
    """trimesh's empty_material(): unnamed, default colours, a 2x2 placeholder image."""
    from trimesh.visual.color import DEFAULT_COLOR

    image = getattr(mat, "image", None)
    return (getattr(mat, "_name", None) is None
            and all(_u8(getattr(mat, k)) == _u8(DEFAULT_COLOR) for k in ("ambient", "diffuse", "specular"))
            and (image is None or getattr(image, "size", None) == (2, 2)))


# -- trimesh geometry -> arrays -------------------------------------------------------------------
@dataclass
class _Part:
    positions: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None
    uvs: np.ndarray | None
    colors: np.ndarray | None  # (n, 4) float64 linear RGBA
    material: Material | None


SMOOTH = (True, False, "area", "angle")


def _power_of_two_scaled(v: np.ndarray, largest: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rows of ``v`` times 2**-e, e) with e per row such that ``largest`` (per row, > 0) times 2**-e
    lies in [1, 2): exact, so a quantity homogeneous in the row keeps its bits while its squares
    neither overflow nor underflow float64. Rows whose ``largest`` is 0 or not finite: unscaled."""
    ok = (largest > 0.0) & np.isfinite(largest)
    _, e = np.frexp(np.where(ok, largest, 1.0))  # largest = m 2**e, m in [0.5, 1)
    e = np.where(ok, e - 1, 0)
    return np.ldexp(v, -e.reshape((-1,) + (1,) * (v.ndim - 1))), e


def unit_rows(v: Any) -> np.ndarray:
    """Each row of the (n, 3) array ``v`` divided by its length, in float64; zero for a zero row
    or one with NaN or inf. Each row is scaled by a power of two to a largest |component| in
    [1, 2) first (exact): unit for any finite nonzero row, 1e-300 or 1e300 alike, and for rows
    whose squared length is a normal float64 the same bits as ``v / np.linalg.norm(v)``."""
    v = np.asarray(v, dtype=np.float64)
    finite = np.isfinite(v).all(axis=1)
    largest = np.where(finite, np.abs(np.where(finite[:, None], v, 0.0)).max(axis=1, initial=0.0), 0.0)
    scaled, _ = _power_of_two_scaled(np.where(finite[:, None], v, 0.0), largest)
    length = np.linalg.norm(scaled, axis=1, keepdims=True)
    return np.divide(scaled, length, out=np.zeros_like(scaled), where=(length > 0.0) & finite[:, None])


def _face_cross(e01: np.ndarray, e02: np.ndarray, e12: np.ndarray) -> np.ndarray:
    """(m, 3) counter-clockwise face normals e01 x e02 (unnormalised) from each face's edges
    (corner 0 -> 1, 0 -> 2, 1 -> 2). Where corner 0's angle is below ~2^-30 rad the cross
    product has cancelled (a corner 0 1e19 away from the other two: both its edges round to the
    same float64, and their cross product is 0): those faces' are taken at the corner opposite
    the longest edge (the largest angle), the cyclic order kept. Every other face keeps corner
    0's, the bits of a plain ``np.cross(e01, e02)``; the core's flat normals do the same."""
    cross = np.cross(e01, e02)
    dot = lambda a, b: np.einsum("ij,ij->i", a, b)  # noqa: E731
    with np.errstate(over="ignore", invalid="ignore"):
        # |cross|^2 < 2^-60 (e01.e02)^2 (|e01|^2 |e02|^2 = |cross|^2 + (e01.e02)^2): the core's test
        bad = ~(dot(cross, cross) >= 2.0**-60 * dot(e01, e02) ** 2)
    if bad.any():
        e01, e02, e12 = e01[bad], e02[bad], e12[bad]
        longest = np.argmax(np.stack([dot(e12, e12), dot(e02, e02), dot(e01, e01)]), axis=0)
        at1 = np.cross(e12, -e01)  # corner 1: (2 - 1) x (0 - 1)
        at2 = np.cross(-e02, -e12)  # corner 2: (0 - 2) x (1 - 2)
        cross[bad] = np.where((longest == 1)[:, None], at1, np.where((longest == 2)[:, None], at2, cross[bad]))
    return cross


def face_normals(positions: Any, faces: Any) -> tuple[np.ndarray, np.ndarray]:
    """(unit normals, corner angles) of the counter-clockwise faces, in float64, from each face's
    corners relative to its first corner scaled by a power of two to a largest |coordinate| in
    [1, 2) (exact) before the cross product: neither the cross product nor its squared length
    over- or underflows for corners anywhere in float32's range (a face with one corner at 3e38
    or all within 1e-45), so every face that is not degenerate in float64 has a unit normal.
    The angles (radians, (m, 3), at corners 0, 1, 2) are atan2(|cross|, dot) of the scaled
    edges: accurate for slivers too (a corner of 1e-39 rad, where an arccos of the dot gives 0).
    A degenerate face (collinear corners): normal 0, its angles 0 at coincident corners."""
    v = np.asarray(positions, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    c = v[f]  # (m, 3, 3)
    edges = np.stack([c[:, 1] - c[:, 0], c[:, 2] - c[:, 0], c[:, 2] - c[:, 1]], axis=1)
    largest = np.abs(edges).max(axis=(1, 2), initial=0.0)
    e01, e02, e12 = np.moveaxis(_power_of_two_scaled(edges, largest)[0], 1, 0)
    cross = _face_cross(e01, e02, e12)
    normals = unit_rows(cross)
    twice_area = np.linalg.norm(cross, axis=1)  # |cross| is the same for any two of the edges
    angles = np.stack([np.arctan2(twice_area, np.einsum("ij,ij->i", e01, e02)),
                       np.arctan2(twice_area, -np.einsum("ij,ij->i", e01, e12)),
                       np.arctan2(twice_area, np.einsum("ij,ij->i", e02, e12))], axis=1)
    return normals, angles


def _angle_weighted_normals(tm: Any) -> np.ndarray:
    """trimesh's angle-weighted vertex normals (Thuerrner & Wuethrich), kept as trimesh gives them
    wherever its rule holds, so the same bits; recomputed by the same rule from ``face_normals``
    (float64, corners scaled to unit magnitude, angles by atan2) at every vertex of a face that
    trimesh drops but is not degenerate: trimesh zeroes a face normal below its tolerance (each
    face of a mesh smaller than about 1e-5) and all angles of a face with a corner below 1e-8 rad
    (a vertex 1e19 from unit ones), which left such vertices a zero normal."""
    v = np.asarray(tm.vertices, dtype=np.float64)
    f = np.asarray(tm.faces, dtype=np.int64)
    out = np.array(tm.vertex_normals, dtype=np.float64)
    if len(f) == 0:
        return out
    normals, angles = face_normals(v, f)
    with np.errstate(invalid="ignore"):
        theirs_ok = ((np.abs(np.linalg.norm(np.asarray(tm.face_normals, np.float64), axis=1) - 1.0) < 1e-6)
                     & (np.asarray(tm.face_angles, np.float64) > 0.0).all(axis=1))
    redo = np.zeros(len(v), dtype=bool)
    redo[f[(normals != 0.0).any(axis=1) & ~theirs_ok].ravel()] = True
    redo |= np.abs(np.linalg.norm(out, axis=1) - 1.0) > 1e-6  # (a zero one: also recomputed)
    if not redo.any():
        return out
    acc = np.zeros_like(v)
    for k in range(3):
        np.add.at(acc, f[:, k], angles[:, k, None] * normals)
    out[redo] = unit_rows(acc[redo])
    return out


def vertex_normals(tm: Any, smooth: bool | str) -> np.ndarray | None:
    """Per-vertex normals for ``smooth`` (see load_mesh): the file's own where it has them, else
    the sum of the adjacent faces' normals weighted by their areas (True or "area", as the
    course notes prescribe) or by their corner angles ("angle", trimesh's rule); False: None
    (flat face normals). Computed in float64 (area: the cross products of float32 corners are
    at most ~1e78 and at least ~1e-90, squared inside float64's range; each sum is normalised by
    ``unit_rows``), so every vertex of a face that is not degenerate gets a unit normal for
    coordinates anywhere in float32's range, from 1e-45 to 3.4e38 (a vertex in no face, or
    whose faces cancel, keeps a zero normal: the renderer then uses the face normal)."""
    if not (isinstance(smooth, bool) or (isinstance(smooth, str) and smooth in ("area", "angle"))):
        raise ValueError(f"smooth must be True, False, 'area' or 'angle', got {smooth!r:.80}")
    if smooth is False:
        return None
    cached = tm._cache.cache.get("vertex_normals") if hasattr(tm, "_cache") else None
    if cached is not None and len(cached) == len(tm.vertices):  # the file's own normals
        return np.asarray(cached)
    if smooth == "angle":
        return _angle_weighted_normals(tm)
    v = np.asarray(tm.vertices, dtype=np.float64)
    f = np.asarray(tm.faces, dtype=np.int64)
    # The cross product's length is twice the face's area: summing it weights by area.
    cross = _face_cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 1]])
    acc = np.zeros_like(v)
    for k in range(3):
        np.add.at(acc, f[:, k], cross)
    # A vertex in no face (or whose faces cancel) keeps a zero normal: shaded with its face normal.
    return unit_rows(acc)


def merge_exact(positions: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Merge vertices with exactly equal positions (as trimesh's ``merge_vertices`` does for a
    file that stores none, but bit-exact, without its rounding): (positions, faces, first), the
    merged vertices in order of first use, faces in their order, ``first[k]`` the index of merged
    vertex k's first occurrence. -0.0 and 0.0 are one position."""
    pos = np.ascontiguousarray(np.asarray(positions, dtype=np.float64) + 0.0)  # -0.0 -> 0.0
    _, index, inverse = np.unique(pos, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    order = np.argsort(index, kind="stable")  # unique rows sorted by first occurrence
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    first = index[order]
    return np.asarray(positions)[first], rank[inverse][np.asarray(faces)], first


def _part(tm: Any, smooth: bool | str, info: _FileInfo) -> _Part:
    """One trimesh.Trimesh as arrays, its colours linear, its material resolved (warning about
    what is dropped, once per material)."""
    import trimesh

    faces = np.asarray(tm.faces)
    positions = np.asarray(tm.vertices)
    first = None  # merged vertex -> the file's vertex it came from (STL with smooth normals)
    if info.soup and smooth is not False:
        positions, faces, first = merge_exact(positions, faces)
        normals = vertex_normals(trimesh.Trimesh(positions, faces, process=False), smooth)
    else:
        normals = vertex_normals(tm, smooth)
    uvs = colors = face_colors = None
    material = None
    visual = getattr(tm, "visual", None)
    if isinstance(visual, trimesh.visual.texture.TextureVisuals):
        if visual.uv is not None and len(visual.uv) == len(positions):
            uvs = np.asarray(visual.uv)[:, :2]
        material, dropped, key = _trimesh_material(visual.material, info)
        if material is not None and material.name:
            where = f"material {material.name!r}"
        else:
            where = f"material {key[1]}" if key is not None and key[0] == "gltf" else "material"
        if dropped and key is not None:
            info.warn(key, f"{where}: " + "; ".join(dropped))
        if key is not None and key[0] == "mtl" and uvs is None and material is not None and material.textured:
            material = _without_textures(material, uvs, where, key, info, info.mtl[key[1]].material)
        material = _without_textures(material, uvs, where, key, info)
        raw = getattr(visual, "vertex_attributes", {}).get("color")  # glTF COLOR_0 with a material
        if raw is not None and len(raw) == len(positions):
            colors = _normalized(raw)
            if info.srgb and np.issubdtype(np.asarray(raw).dtype, np.integer):
                colors[:, :3] = srgb_to_linear(colors[:, :3])
    elif visual is not None:
        kind = visual.kind
        if kind == "vertex":
            colors = _colors8(visual.vertex_colors, info.srgb)
        elif kind == "face":
            face_colors = _colors8(visual.face_colors, info.srgb)
    if first is not None:  # per-vertex data of the file's vertices, to the merged ones
        uvs = None if uvs is None or len(uvs) != len(tm.vertices) else uvs[first]
        colors = None if colors is None or len(colors) != len(tm.vertices) else colors[first]
    if colors is not None and material is not None and info.gltf is not None:
        colors = colors * np.asarray(material.base_color)  # glTF: COLOR_0 x baseColorFactor
    if face_colors is not None:
        # A Mesh colours vertices: each face gets three vertices of its own, in face order.
        corners = faces.reshape(-1)
        positions = positions[corners]
        normals = None if normals is None else normals[corners]
        uvs = None if uvs is None else uvs[corners]
        colors = np.repeat(face_colors, 3, axis=0)
        faces = np.arange(3 * len(faces), dtype=np.int64).reshape(-1, 3)
    return _Part(positions, faces, normals, uvs, colors, material)


def _merge(parts: list[_Part], info: _FileInfo) -> _Part:
    """Concatenate parts into one; different materials => the first part's, with a warning."""
    if len(parts) == 1:
        return parts[0]
    materials: list[Material | None] = []
    for p in parts:
        if p.material not in materials:
            materials.append(p.material)
    material = parts[0].material
    if len(materials) > 1:
        info.warn("merged", f"{len(parts)} parts with {len(materials)} different materials were merged "
                            "into one mesh with the first part's material; use softrast.load_scene "
                            "to keep each part's material")
    if not all(p.uvs is not None for p in parts):
        material = _without_textures(material, None, "the merged mesh", "merged uvs", info)
    offsets = np.cumsum([0] + [len(p.positions) for p in parts[:-1]])
    faces = np.concatenate([p.faces + o for p, o in zip(parts, offsets)])
    positions = np.concatenate([p.positions for p in parts])
    normals = (np.concatenate([p.normals for p in parts])
               if all(p.normals is not None for p in parts) else None)
    uvs = np.concatenate([p.uvs for p in parts]) if all(p.uvs is not None for p in parts) else None
    colors = None
    if any(p.colors is not None for p in parts):
        fill = material.base_color if material is not None else (0.8, 0.8, 0.8, 1.0)
        colors = np.concatenate([
            p.colors if p.colors is not None else np.tile(np.asarray(fill, dtype=np.float64), (len(p.positions), 1))
            for p in parts])
    return _Part(positions, faces, normals, uvs, colors, material)


def _to_mesh(part: _Part, color: Sequence[float] | None) -> Any:
    from .mesh import DEFAULT_COLOR, Mesh

    material = part.material
    if material is not None and color is not None:
        material = material.replace(base_color=color)  # checked like the constructor's
    colors = None
    if part.colors is not None:
        colors = np.clip(part.colors, 0.0, 1.0)
    if material is not None:
        return Mesh(part.positions, part.faces, normals=part.normals, uvs=part.uvs, colors=colors,
                    material=material)
    return Mesh(part.positions, part.faces, normals=part.normals, uvs=part.uvs, colors=colors,
                color=DEFAULT_COLOR if color is None else color)


def _transformed(part: _Part, matrix: Any) -> _Part:
    """``part`` moved by the (4, 4) ``matrix`` as trimesh's apply_transform moves a mesh: normals
    by the adjugate, and a mirroring matrix reverses each face's corners (keeping faces in order)
    so front faces stay counter-clockwise."""
    m = np.asarray(matrix, dtype=np.float64)
    if np.array_equal(m, np.eye(4)):
        return part
    linear = m[:3, :3]
    positions = part.positions @ linear.T + m[:3, 3]
    faces, normals = part.faces, part.normals
    # The matrix scaled by a power of two to a largest |entry| in [1, 2) for the determinant's
    # sign and the adjugate: exact, the same directions, no overflow for a node scaled by 1e200.
    unit_linear = _power_of_two_scaled(linear[None], np.abs(linear).max(keepdims=True).ravel())[0][0]
    flip = np.linalg.det(unit_linear) < 0
    if normals is not None:
        adjugate = np.cross(unit_linear.T[[1, 2, 0]], unit_linear.T[[2, 0, 1]])
        normals = unit_rows(normals @ (-adjugate if flip else adjugate))
    if flip:
        faces = np.ascontiguousarray(faces[:, ::-1])
    return _Part(positions, faces, normals, part.uvs, part.colors, part.material)


# load_mesh / load_scene(up_axis="z"): (x, y, z) -> (x, z, -y), a proper rotation about x
UP_Z_TO_Y = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])


def up_axis_matrix(up_axis: Any) -> np.ndarray | None:
    """None for "y" (as stored), the rotation for "z"; ValueError naming up_axis otherwise."""
    if isinstance(up_axis, str) and up_axis == "y":
        return None
    if isinstance(up_axis, str) and up_axis == "z":
        return UP_Z_TO_Y
    raise ValueError(f"up_axis must be 'y' or 'z', got {up_axis!r:.80}")


def mesh_from_trimesh(tm: Any, smooth: bool, color: Sequence[float] | None, info: _FileInfo,
                      root: Any = None) -> Any:
    """Mesh.from_trimesh's work (a Trimesh, or a Scene merged with its transforms)."""
    import trimesh

    if isinstance(tm, trimesh.Scene):
        # Each placement of each geometry, in trimesh's graph order (as Scene.dump() lists them);
        # not dump() itself: its copies lose vertex attributes such as glTF COLOR_0.
        parts, converted = [], {}
        for node in tm.graph.nodes_geometry:
            transform, name = tm.graph[node]
            geom = tm.geometry.get(name)
            if isinstance(geom, trimesh.Trimesh) and len(geom.faces):
                if name not in converted:  # geometry placed by several nodes: converted once
                    converted[name] = _part(geom, smooth, info)
                parts.append(_transformed(converted[name], transform))
        if not parts:
            raise ValueError("tm is a trimesh.Scene without any triangle geometry")
    elif isinstance(tm, trimesh.Trimesh):
        parts = [_part(tm, smooth, info)]
    else:
        raise TypeError(f"tm must be a trimesh.Trimesh or trimesh.Scene, got {type(tm).__name__}")
    merged = _merge(parts, info)
    return _to_mesh(merged if root is None else _transformed(merged, root), color)


def load_scene(path: str | os.PathLike[str], smooth: bool | str = True, up_axis: str = "y") -> Any:
    """Load a mesh file as a ``softrast.Scene``: one instance per part, each with its own Mesh
    and Material, placed by the file's node transforms (glTF nodes; identity for formats without
    a scene graph). Geometry that several nodes instance is one shared Mesh. Instance ids are
    0, 1, 2, ... in the order of trimesh's scene graph (``graph.nodes_geometry``).

    Colours, materials and what is dropped (with a warning) are as described in
    ``softrast.loaders``; ``smooth`` and ``up_axis`` as for ``load_mesh`` (``up_axis="z"``
    rotates every instance's pose, the meshes stay as stored). Raises like ``load_mesh``:
    FileNotFoundError for a missing file (or a buffer or texture a glTF references), ValueError
    naming the file for every other failure.
    """
    from .mesh import _FileProblem, _LOADING_FILE, _check_smooth, _load_trimesh

    path_str = os.fspath(path)
    _check_smooth(smooth)
    root = up_axis_matrix(up_axis)
    loaded, info = _load_trimesh(path_str)
    token = _LOADING_FILE.set(path_str)
    try:
        scene = scene_from_trimesh(loaded, smooth, info, root)
        if not len(scene):
            raise _FileProblem("the file contains no triangles")
        return scene
    except UserWarning:
        raise  # a warning made an error (-W error): it names the file already
    except Exception as exc:
        what = str(exc) if type(exc) in (ValueError, _FileProblem) else f"{type(exc).__name__}: {exc}"
        raise ValueError(f"could not load mesh {path_str!r}: {what}") from exc
    finally:
        _LOADING_FILE.reset(token)


def scene_from_trimesh(loaded: Any, smooth: bool | str, info: _FileInfo, root: Any = None) -> Any:
    """load_scene's and Scene.from_trimesh's work: a softrast.Scene with one instance per
    placement of each triangle geometry of a trimesh.Scene (trimesh's graph order,
    ``graph.nodes_geometry``), placed by its node's world transform; geometry placed by several
    nodes is one shared Mesh. A trimesh.Trimesh is one instance at the identity. May be empty."""
    import trimesh

    from .scene import Scene

    scene = Scene()
    if isinstance(loaded, trimesh.Trimesh):
        if len(loaded.faces):
            scene.add(_to_mesh(_part(loaded, smooth, info), None), pose=root)
        return scene
    if not isinstance(loaded, trimesh.Scene):
        raise TypeError(f"expected a trimesh.Scene or trimesh.Trimesh, got {type(loaded).__name__}")
    meshes: dict[str, Any] = {}
    for node in loaded.graph.nodes_geometry:
        transform, name = loaded.graph[node]
        geom = loaded.geometry.get(name)
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        if name not in meshes:
            meshes[name] = _to_mesh(_part(geom, smooth, info), None)
        pose = np.asarray(transform, dtype=np.float64)
        scene.add(meshes[name], pose=pose if root is None else root @ pose)
    return scene
