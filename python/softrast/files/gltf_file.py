"""A .gltf or .glb file, read once: its JSON checked against its buffers before trimesh parses
anything, and handed to trimesh with each material named by its index, so that the material a
primitive uses is known exactly (the JSON's ``meshes[i].primitives[j].material``), not guessed.
"""
from __future__ import annotations

import errno
import json
import os
import struct
import urllib.parse
from dataclasses import dataclass
from typing import Any

from ..limits import check_budget
from .checks import _VALUE_BYTES, _corrupt

__all__ = ["GltfFile", "material_index", "read_gltf"]

_GLTF_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_GLTF_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


# What trimesh is told each material is called: its index (every material is renamed, so no
# name in the file can collide); the real names stay in GltfFile.doc.
_TAG = "\x00softrast material "


def material_index(name: Any) -> int | None:
    """The index of the glTF material that trimesh built from GltfFile.for_trimesh()'s bytes,
    read from its name; None for a material that did not come from such bytes."""
    if isinstance(name, str) and name.startswith(_TAG) and name[len(_TAG):].isdigit():
        return int(name[len(_TAG):])
    return None


@dataclass
class GltfFile:
    """A .gltf or .glb as read once: its JSON, and the bytes trimesh parses."""

    path: str
    doc: dict[str, Any]
    data: bytes  # the whole file
    json_end: int | None  # GLB: where the JSON chunk ends and the next chunk starts; .gltf: None

    def for_trimesh(self) -> tuple[bytes, str]:
        """(the file with each material named by its index, trimesh's file type "glb" or
        "gltf"). Everything else is as read; a file without materials is handed over as is."""
        kind = "gltf" if self.json_end is None else "glb"
        materials = self.doc.get("materials")
        if not isinstance(materials, list) or not materials:
            return self.data, kind
        doc = dict(self.doc)
        doc["materials"] = [dict(m, name=f"{_TAG}{i}") if isinstance(m, dict) else m
                            for i, m in enumerate(materials)]
        text = json.dumps(doc, separators=(",", ":")).encode("utf-8")
        if self.json_end is None:
            return text, kind
        text += b" " * (-len(text) % 4)  # the spec pads the JSON chunk with spaces
        rest = memoryview(self.data)[self.json_end:]
        version = struct.unpack("<I", self.data[4:8])[0]
        head = struct.pack("<4sIII4s", b"glTF", version, 20 + len(text) + len(rest), len(text), b"JSON")
        return b"".join((head, text, rest)), kind


def read_gltf(path_str: str) -> GltfFile:
    """Read a .gltf or .glb once and check it against its buffers and the memory budget (raises
    ValueError or FileNotFoundError naming the file)."""
    size = os.path.getsize(path_str)
    check_budget(size, f"mesh file {path_str!r}")  # trimesh reads the whole file into memory
    file, bin_length = _gltf_json(path_str, size)
    _check_gltf(file, bin_length)
    return file


def _gltf_json(path_str: str, size: int) -> tuple[GltfFile, int | None]:
    """The file with its glTF JSON and, for .glb, the length of the binary chunk (None if there
    is none)."""
    with open(path_str, "rb") as f:
        data = f.read()
    bin_length = None
    json_end = None
    if data[:4] == b"glTF":
        if len(data) < 20:
            raise _corrupt(path_str, "GLB shorter than its 20-byte header")
        _, _, total, json_length, json_type = struct.unpack("<4sIII4s", data[:20])
        if total != size or json_type != b"JSON" or 20 + json_length > size:
            raise _corrupt(path_str, f"GLB header declares {total} bytes (JSON chunk {json_length}) "
                                     f"but the file has {size}: truncated or corrupt")
        text = data[20:20 + json_length]
        # The next chunk starts right after the JSON, as trimesh reads it: the spec pads the JSON
        # to 4 bytes, but trimesh writes and reads GLBs whose JSON chunk is not padded, and a
        # padded length lands at the same place. Chunks of unknown types are skipped (the spec
        # says so); the first BIN chunk is buffer 0.
        at = json_end = 20 + json_length
        while at + 8 <= size:
            length, kind = struct.unpack("<I4s", data[at:at + 8])
            if at + 8 + length > size:
                raise _corrupt(path_str, f"GLB chunk {kind!r} at byte {at} declares {length} bytes, "
                                         f"past the end of the file: truncated or corrupt")
            if kind == b"BIN\x00" and bin_length is None:
                bin_length = length
            at += 8 + length
    else:
        text = data
    try:
        doc = json.loads(text)
    except (ValueError, UnicodeDecodeError) as exc:
        raise _corrupt(path_str, f"invalid glTF JSON: {exc}") from None
    if not isinstance(doc, dict):
        raise _corrupt(path_str, "glTF JSON is not an object")
    return GltfFile(path_str, doc, data, json_end), bin_length


def _external(path_str: str, uri: str, what: str) -> str | None:
    """The local path of a non-data URI, raising FileNotFoundError (naming it) if it is missing."""
    if uri.startswith("data:"):
        return None
    local = os.path.join(os.path.dirname(os.path.abspath(path_str)), urllib.parse.unquote(uri))
    if not os.path.isfile(local):
        raise FileNotFoundError(errno.ENOENT, f"{what} referenced by mesh file {path_str!r} not found",
                                local)
    return local


def _check_gltf(file: GltfFile, bin_length: int | None) -> None:
    path_str, doc = file.path, file.doc
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
        for m, mesh in enumerate(doc.get("meshes", [])):
            for p, prim in enumerate(mesh.get("primitives", [])):
                # Triangles (mode 4, the default) take indices 3 at a time: a count that is not a
                # multiple of 3 is a cut or a wrong count (trimesh would drop or misread the rest).
                source = prim["indices"] if "indices" in prim else prim["attributes"].get("POSITION")
                if prim.get("mode", 4) == 4 and source is not None:
                    n = int(doc["accessors"][int(source)]["count"])
                    if n % 3:
                        raise _corrupt(path_str, f"glTF mesh {m} primitive {p} has {n} triangle "
                                                 "indices, not a multiple of 3")
        for i, image in enumerate(doc.get("images", [])):
            if "uri" in image:
                _external(path_str, image["uri"], f"image {i} ({image['uri']!r})")
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:
        if isinstance(exc, ValueError) and str(exc).startswith("could not load mesh"):
            raise
        raise _corrupt(path_str, f"malformed glTF ({type(exc).__name__}: {exc})") from None
    check_budget(estimate, f"mesh file {path_str!r} (glTF accessor counts)")
