"""Mesh-file checks made from headers alone, before trimesh allocates anything.

trimesh trusts headers: a 200-byte PLY that declares 2**31 vertices, or a glTF accessor longer
than its buffer, must be refused from the header, with the file named, before any parsing.
"""
from __future__ import annotations

import errno
import json
import os
import struct
import urllib.parse
from typing import Any

from .limits import check_budget

__all__ = ["check_mesh_file"]

_PLY_SIZES = {"char": 1, "int8": 1, "uchar": 1, "uint8": 1, "short": 2, "int16": 2, "ushort": 2,
              "uint16": 2, "int": 4, "int32": 4, "uint": 4, "uint32": 4, "float": 4, "float32": 4,
              "double": 8, "float64": 8}
_PLY_MAX_HEADER = 1 << 20
_VALUE_BYTES = 8  # trimesh converts every parsed value to float64 / int64
_GLTF_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_GLTF_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


def _corrupt(path_str: str, what: str) -> ValueError:
    return ValueError(f"could not load mesh {path_str!r}: {what}")


def _check_ply(path_str: str, size: int) -> None:
    with open(path_str, "rb") as f:
        head = f.read(_PLY_MAX_HEADER)
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        raise _corrupt(path_str, "not a PLY file or no end_header in its first 1 MiB")
    body = size - (head.index(b"\n", end) + 1 if b"\n" in head[end:] else size)
    binary, elements = False, []  # (name, count, fixed bytes, number of values, list count bytes)
    for line in head[:end].decode("latin-1").splitlines():
        words = line.split()
        try:
            if words[:1] == ["format"]:
                binary = words[1] != "ascii"
            elif words[:1] == ["element"]:
                elements.append([words[1], int(words[2]), 0, 0, []])
            elif words[:1] == ["property"] and elements:
                el = elements[-1]
                if words[1] == "list":
                    el[4].append(_PLY_SIZES[words[2]])
                else:
                    el[2] += _PLY_SIZES[words[1]]
                    el[3] += 1
        except (IndexError, KeyError, ValueError):
            raise _corrupt(path_str, f"malformed PLY header line {line!r}") from None
    needed = estimate = 0
    for name, count, fixed, values, lists in elements:
        if count < 0:
            raise _corrupt(path_str, f"PLY element {name!r} has a negative count {count}")
        # Smallest possible row: binary => the fixed properties and empty lists; ascii => one
        # digit and one separator per value.
        row = fixed + sum(lists) if binary else 2 * (values + len(lists))
        needed += count * row
        estimate += count * _VALUE_BYTES * (values + 4 * len(lists))  # lists: mostly triangles
        if needed > body:
            raise _corrupt(path_str, f"the PLY header declares {count} {name!r} elements, which need "
                                     f"at least {needed} bytes, but only {body} follow the header: "
                                     "truncated or corrupt")
    check_budget(estimate, f"mesh file {path_str!r} (PLY header counts)")


def _check_stl(path_str: str, size: int) -> None:
    with open(path_str, "rb") as f:
        head = f.read(84)
        if size >= 84:
            f.seek(max(84, size - 1024))
            tail = f.read()
    if size < 84 and not head.lstrip().startswith(b"solid"):
        raise _corrupt(path_str, f"{size} bytes is too short for a binary STL (84-byte header)")
    if size >= 84:
        (count,) = struct.unpack("<I", head[80:84])
        if size == 84 + 50 * count:  # binary: 50 bytes per triangle
            check_budget(count * 3 * 3 * _VALUE_BYTES * 2, f"mesh file {path_str!r} (STL triangle count)")
            return
        if not head.lstrip().startswith(b"solid"):
            raise _corrupt(path_str, f"the binary STL header declares {count} triangles "
                                     f"({84 + 50 * count} bytes) but the file has {size} bytes: "
                                     "truncated or corrupt")
        if b"endsolid" not in tail:
            raise _corrupt(path_str, "the ASCII STL has no 'endsolid': truncated")


def _gltf_json(path_str: str, size: int) -> tuple[dict[str, Any], int | None]:
    """The glTF JSON and, for .glb, the length of the binary chunk (None if there is none)."""
    with open(path_str, "rb") as f:
        data = f.read()
    bin_length = None
    if data[:4] == b"glTF":
        if len(data) < 20:
            raise _corrupt(path_str, "GLB shorter than its 20-byte header")
        _, _, total, json_length, json_type = struct.unpack("<4sIII4s", data[:20])
        if total != size or json_type != b"JSON" or 20 + json_length > size:
            raise _corrupt(path_str, f"GLB header declares {total} bytes (JSON chunk {json_length}) "
                                     f"but the file has {size}: truncated or corrupt")
        text = data[20:20 + json_length]
        rest = 20 + ((json_length + 3) & ~3)
        if rest + 8 <= size:
            bin_length, bin_type = struct.unpack("<I4s", data[rest:rest + 8])
            if bin_type != b"BIN\x00" or rest + 8 + bin_length > size:
                raise _corrupt(path_str, "GLB binary chunk is truncated or corrupt")
    else:
        text = data
    try:
        doc = json.loads(text)
    except (ValueError, UnicodeDecodeError) as exc:
        raise _corrupt(path_str, f"invalid glTF JSON: {exc}") from None
    if not isinstance(doc, dict):
        raise _corrupt(path_str, "glTF JSON is not an object")
    return doc, bin_length


def _external(path_str: str, uri: str, what: str) -> str | None:
    """The local path of a non-data URI, raising FileNotFoundError (naming it) if it is missing."""
    if uri.startswith("data:"):
        return None
    local = os.path.join(os.path.dirname(os.path.abspath(path_str)), urllib.parse.unquote(uri))
    if not os.path.isfile(local):
        raise FileNotFoundError(errno.ENOENT, f"{what} referenced by mesh file {path_str!r} not found",
                                local)
    return local


def _check_gltf(path_str: str, size: int) -> None:
    doc, bin_length = _gltf_json(path_str, size)
    try:
        buffers = []  # actual bytes available in each buffer
        for i, buf in enumerate(doc.get("buffers", [])):
            uri = buf.get("uri")
            if uri is None:
                actual = bin_length or 0
            else:
                local = _external(path_str, uri, f"buffer {i} ({uri!r})")
                actual = os.path.getsize(local) if local else len(uri.partition(",")[2]) * 3 // 4
            if actual < int(buf["byteLength"]):
                raise _corrupt(path_str, f"glTF buffer {i} declares {buf['byteLength']} bytes but "
                                         f"holds {actual}: truncated")
            buffers.append(int(buf["byteLength"]))
        views = []
        for i, view in enumerate(doc.get("bufferViews", [])):
            start, length = int(view.get("byteOffset", 0)), int(view["byteLength"])
            if start < 0 or length < 0 or start + length > buffers[int(view["buffer"])]:
                raise _corrupt(path_str, f"glTF bufferView {i} lies outside its buffer")
            views.append((length, int(view.get("byteStride", 0))))
        estimate = 0
        for i, acc in enumerate(doc.get("accessors", [])):
            count = int(acc["count"])
            element = _GLTF_COMPONENT_BYTES[acc["componentType"]] * _GLTF_COMPONENTS[acc["type"]]
            estimate += count * _GLTF_COMPONENTS[acc["type"]] * _VALUE_BYTES
            if count < 0:
                raise _corrupt(path_str, f"glTF accessor {i} has a negative count")
            if "bufferView" in acc and count > 0:
                length, stride = views[int(acc["bufferView"])]
                end = int(acc.get("byteOffset", 0)) + (stride or element) * (count - 1) + element
                if end > length:
                    raise _corrupt(path_str, f"glTF accessor {i} reads {end} bytes from a "
                                             f"{length}-byte bufferView: truncated or corrupt")
        for i, image in enumerate(doc.get("images", [])):
            if "uri" in image:
                _external(path_str, image["uri"], f"image {i} ({image['uri']!r})")
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:
        if isinstance(exc, ValueError) and str(exc).startswith("could not load mesh"):
            raise
        raise _corrupt(path_str, f"malformed glTF ({type(exc).__name__}: {exc})") from None
    check_budget(estimate, f"mesh file {path_str!r} (glTF accessor counts)")


def check_mesh_file(path_str: str) -> None:
    """Refuse, from headers alone, files that are truncated or would make trimesh allocate more
    than the memory budget (raises ValueError or FileNotFoundError naming the file)."""
    size = os.path.getsize(path_str)
    check_budget(size, f"mesh file {path_str!r}")  # trimesh reads the whole file into memory
    ext = os.path.splitext(path_str)[1].lower()
    if ext == ".ply":
        _check_ply(path_str, size)
    elif ext == ".stl":
        _check_stl(path_str, size)
    elif ext in (".gltf", ".glb"):
        _check_gltf(path_str, size)
