"""OBJ + MTL materials, read from the MTL file itself (trimesh keeps only 8-bit values and
drops d, Tr and most maps). The rules are in docs/file_formats.md, "OBJ and MTL"."""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any, Sequence

from .._checks import FLOAT32_MAX
from ..material import Material
from ..texture import Texture
from .context import FileInfo
from .images import _file_texture, _is_grey, _looks_like_normal_map


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


def _obj_materials(path_str: str, info: FileInfo) -> dict[str, _MtlEntry]:
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


def _mtl_color(words: list[str], key: str, where: str, info: FileInfo) -> tuple[float, ...] | None:
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


def _mtl_map(words: list[str], where: str, info: FileInfo) -> _MtlMap | None:
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


def _parse_mtl(text: str, mtl_name: str, info: FileInfo, folder: str = "") -> dict[str, _MtlEntry]:
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


def _mtl_resolve(entry: _MtlEntry, info: FileInfo) -> tuple[Material, list[str]]:
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
