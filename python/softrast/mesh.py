"""Triangle meshes: validated, read-only geometry that is uploaded to the C++ core once.

A ``Mesh`` owns copies of its arrays (marked read-only) so the cached ``softrast._core.MeshData``
can never go stale. Vertex order is kept exactly as given (or as the file lists it), so
``triangle_id`` outputs index ``Mesh.faces`` directly.
"""
from __future__ import annotations

import contextlib
import errno
import json
import os
import signal
import struct
import threading
import urllib.parse
from typing import Any, Iterator, Sequence

import numpy as np
import numpy.typing as npt

from .limits import check_budget

__all__ = ["Mesh", "load_mesh"]

# The core indexes vertices and faces with int32.
_MAX_COUNT = 2**31 - 1
DEFAULT_COLOR = (0.8, 0.8, 0.8, 1.0)


def _as_array(value: Any, name: str) -> np.ndarray:
    """np.asarray that reports ragged / non-array-like input by argument name."""
    if value is None or isinstance(value, (str, bytes, dict, set)):
        raise TypeError(f"{name} must be an array-like of numbers, got {type(value).__name__}")
    try:
        return np.asarray(value)
    except (ValueError, TypeError) as exc:  # ragged nested lists
        raise ValueError(f"{name} could not be converted to an array: {exc}") from exc


def _check_shape(arr: np.ndarray, name: str, shape_text: str, cols: Sequence[int]) -> None:
    if arr.ndim != 2 or arr.shape[1] not in cols:
        raise ValueError(f"{name} must have shape {shape_text}, got {arr.shape}")
    if arr.shape[0] > _MAX_COUNT:
        raise ValueError(f"{name} has {arr.shape[0]} rows; at most 2**31 - 1 are supported")


def _check_real(arr: np.ndarray, name: str) -> None:
    # bool is numeric to numpy but never a meaningful coordinate => reject with the dtype named.
    if arr.dtype == np.bool_ or not (
        np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)
    ):
        raise TypeError(f"{name} must have a real numeric dtype, got {arr.dtype}")


def _check_finite(arr: np.ndarray, name: str) -> None:
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name} contains NaN or inf at vertex {k}")


def _frozen(arr: np.ndarray, dtype: npt.DTypeLike) -> np.ndarray:
    """A private C-contiguous copy that nobody (including the caller) can modify."""
    out = np.array(arr, dtype=dtype, order="C", copy=True)
    out.setflags(write=False)
    return out


def _vertex_attribute(value: Any, name: str, cols: int, n: int) -> np.ndarray:
    arr = _as_array(value, name)
    _check_real(arr, name)
    _check_shape(arr, name, f"(n, {cols})", (cols,))
    if arr.shape[0] != n:
        raise ValueError(f"{name} must have one row per vertex ({n}), got {arr.shape[0]}")
    _check_finite(arr, name)
    return _frozen(arr, np.float32)


def _vertex_colors(value: Any, n: int) -> np.ndarray:
    arr = _as_array(value, "colors")
    _check_shape(arr, "colors", "(n, 3) or (n, 4)", (3, 4))
    if arr.shape[0] != n:
        raise ValueError(f"colors must have one row per vertex ({n}), got {arr.shape[0]}")
    if arr.dtype == np.uint8:
        rgba = arr.astype(np.float32) / np.float32(255.0)
    elif np.issubdtype(arr.dtype, np.floating):
        _check_finite(arr, "colors")
        if arr.size and (arr.min() < 0.0 or arr.max() > 1.0):
            raise ValueError("colors must be uint8 or float in [0, 1]; float values lie outside [0, 1]")
        rgba = arr.astype(np.float32)
    else:  # an int array is ambiguous (is 1 one 255th or full intensity?) => refuse
        raise TypeError(f"colors must be uint8 (0-255) or float in [0, 1], got {arr.dtype}")
    if rgba.shape[1] == 3:
        rgba = np.concatenate([rgba, np.ones((n, 1), np.float32)], axis=1)
    return _frozen(rgba, np.float32)


def _rgba(value: Any, name: str = "color") -> tuple[float, float, float, float]:
    """3 or 4 numbers in [0, 1] -> a 4-tuple of Python floats (alpha 1 if absent)."""
    arr = _as_array(value, name)
    _check_real(arr, name)
    if arr.shape not in ((3,), (4,)):
        raise ValueError(f"{name} must be 3 or 4 numbers (RGB or RGBA), got shape {arr.shape}")
    arr = arr.astype(np.float64)
    if not np.isfinite(arr).all() or arr.min() < 0.0 or arr.max() > 1.0:
        raise ValueError(f"{name} components must be finite and in [0, 1], got {arr.tolist()}")
    if arr.shape[0] == 3:
        arr = np.append(arr, 1.0)
    return tuple(float(c) for c in arr)  # type: ignore[return-value]


class Mesh:
    """An indexed triangle mesh with optional per-vertex attributes.

    Parameters
    ----------
    positions : (n, 3) real array, object-space coordinates (finite); stored as float32.
    faces : (m, 3) integer array of vertex indices in [0, n); stored as int32.
        Counter-clockwise faces (seen from outside) are front faces, as in OpenGL.
    normals : (n, 3) real array or None, per-vertex normals; None => flat face normals.
    uvs : (n, 2) real array or None, texture coordinates (u right, v up).
    colors : (n, 3) or (n, 4) uint8 (0-255) or float in [0, 1], or None;
        stored as (n, 4) float32 RGBA in [0, 1] (alpha 1 when absent).
    color : 3 or 4 floats in [0, 1], the base colour used when ``colors`` is None.

    All stored arrays are read-only copies, so later edits to the inputs never reach the mesh.
    """

    __slots__ = ("_positions", "_faces", "_normals", "_uvs", "_colors", "_color", "_core")

    def __init__(
        self,
        positions: npt.ArrayLike,
        faces: npt.ArrayLike,
        normals: npt.ArrayLike | None = None,
        uvs: npt.ArrayLike | None = None,
        colors: npt.ArrayLike | None = None,
        color: Sequence[float] = DEFAULT_COLOR,
    ) -> None:
        pos = _as_array(positions, "positions")
        _check_real(pos, "positions")
        _check_shape(pos, "positions", "(n, 3)", (3,))
        fac = _as_array(faces, "faces")
        if fac.dtype == np.bool_ or not np.issubdtype(fac.dtype, np.integer):
            raise TypeError(f"faces must have an integer dtype, got {fac.dtype}")
        _check_shape(fac, "faces", "(m, 3)", (3,))
        n, m = pos.shape[0], fac.shape[0]
        if n == 0 or m == 0:
            raise ValueError(f"mesh is empty: positions has {n} vertices and faces has {m} triangles")
        _check_finite(pos, "positions")
        lo, hi = fac.min(), fac.max()
        if lo < 0:
            raise ValueError(f"faces contains a negative index {int(lo)}; indices must be in [0, {n})")
        if hi >= n:
            raise ValueError(f"faces contains index {int(hi)}, but there are only {n} vertices")

        # Bytes of the float32 / int32 copies below; the core holds one more copy of each.
        check_budget(2 * 4 * (3 * n + 3 * m + sum(
            k * n for k, v in ((3, normals), (2, uvs), (4, colors)) if v is not None)),
            f"mesh with {n} vertices and {m} triangles")
        self._positions = _frozen(pos, np.float32)
        self._faces = _frozen(fac, np.int32)
        self._normals = None if normals is None else _vertex_attribute(normals, "normals", 3, n)
        self._uvs = None if uvs is None else _vertex_attribute(uvs, "uvs", 2, n)
        self._colors = None if colors is None else _vertex_colors(colors, n)
        self._color = _rgba(color, "color")
        self._core: Any = None

    # -- read-only views --------------------------------------------------------------------
    @property
    def positions(self) -> npt.NDArray[np.float32]:
        """(n, 3) float32, read-only."""
        return self._positions

    @property
    def faces(self) -> npt.NDArray[np.int32]:
        """(m, 3) int32, read-only."""
        return self._faces

    @property
    def normals(self) -> npt.NDArray[np.float32] | None:
        """(n, 3) float32 per-vertex normals, read-only, or None."""
        return self._normals

    @property
    def uvs(self) -> npt.NDArray[np.float32] | None:
        """(n, 2) float32 texture coordinates, read-only, or None."""
        return self._uvs

    @property
    def colors(self) -> npt.NDArray[np.float32] | None:
        """(n, 4) float32 RGBA in [0, 1], read-only, or None."""
        return self._colors

    @property
    def color(self) -> tuple[float, float, float, float]:
        """Base RGBA colour in [0, 1]."""
        return self._color

    @property
    def num_vertices(self) -> int:
        return int(self._positions.shape[0])

    @property
    def num_faces(self) -> int:
        return int(self._faces.shape[0])

    @property
    def bounds(self) -> npt.NDArray[np.float64]:
        """(2, 3) float64: row 0 = per-axis minimum, row 1 = maximum, object space."""
        return np.stack([self._positions.min(axis=0), self._positions.max(axis=0)]).astype(np.float64)

    def __repr__(self) -> str:
        attrs = [a for a in ("normals", "uvs", "colors") if getattr(self, "_" + a) is not None]
        return f"Mesh(num_vertices={self.num_vertices}, num_faces={self.num_faces}, attributes={attrs})"

    def _core_data(self) -> Any:
        """The ``softrast._core.MeshData`` for this mesh, built on first use and cached."""
        if self._core is None:
            from softrast import _core  # lazy: geometry can be built without the compiled core

            self._core = _core.MeshData(self._positions, self._faces, self._normals, self._colors, self._uvs)
        return self._core

    # -- constructors -----------------------------------------------------------------------
    @classmethod
    def from_trimesh(cls, tm: Any, smooth: bool = True, color: Sequence[float] | None = None) -> "Mesh":
        """Build a Mesh from a ``trimesh.Trimesh`` (or a ``trimesh.Scene``, concatenated).

        smooth : True => per-vertex normals from ``tm.vertex_normals``; False => flat shading.
        color : base RGBA; None => the default grey.
        uvs are taken from a ``TextureVisuals`` with uv; colors from per-vertex ``ColorVisuals``
        (per-face colours are not carried over).
        """
        import trimesh

        if isinstance(tm, trimesh.Scene):
            parts = [g for g in tm.dump() if isinstance(g, trimesh.Trimesh) and len(g.faces)]
            if not parts:
                raise ValueError("tm is a trimesh.Scene without any triangle geometry")
            # One part keeps its visuals untouched; several are merged with their scene transforms.
            tm = parts[0] if len(parts) == 1 else trimesh.util.concatenate(parts)
        if not isinstance(tm, trimesh.Trimesh):
            raise TypeError(f"tm must be a trimesh.Trimesh or trimesh.Scene, got {type(tm).__name__}")

        normals = np.asarray(tm.vertex_normals) if smooth else None
        uvs = colors = None
        visual = getattr(tm, "visual", None)
        if isinstance(visual, trimesh.visual.texture.TextureVisuals) and visual.uv is not None:
            uvs = np.asarray(visual.uv)[:, :2]
        elif visual is not None and visual.kind == "vertex":
            colors = np.asarray(visual.vertex_colors)
        return cls(
            tm.vertices, tm.faces, normals=normals, uvs=uvs, colors=colors,
            color=DEFAULT_COLOR if color is None else color,
        )


# -- file checks before trimesh allocates anything ----------------------------------------------
# trimesh trusts headers: a 200-byte PLY that declares 2**31 vertices, or a glTF accessor longer
# than its buffer, must be refused from the header, with the file named, before any parsing.
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


def _check_mesh_file(path_str: str) -> None:
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


@contextlib.contextmanager
def _keep_ctrl_c() -> Iterator[None]:
    """Make Ctrl-C inside trimesh reach the caller.

    trimesh catches BaseException in many places (optional imports, loaders), which swallows a
    KeyboardInterrupt. While it runs, SIGINT is recorded as well as raised; if trimesh swallowed
    or converted it, KeyboardInterrupt is raised again on the way out.
    """
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield  # someone else owns SIGINT => leave it alone
        return
    hit: list[int] = []

    def handler(signum: int, frame: Any) -> None:
        hit.append(signum)
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, handler)
    try:
        yield
    except KeyboardInterrupt:
        raise
    except BaseException as exc:
        if hit:
            raise KeyboardInterrupt from exc
        raise
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if hit:
        raise KeyboardInterrupt


def load_mesh(path: str | os.PathLike[str], smooth: bool = True, color: Sequence[float] | None = None) -> Mesh:
    """Load a triangle mesh file (OBJ, PLY, STL, GLB, OFF, ...) with trimesh, keeping vertex order.

    A multi-object file is concatenated into one Mesh. See ``Mesh.from_trimesh`` for
    ``smooth`` and ``color``.

    Raises FileNotFoundError if ``path`` (or a buffer or texture file a glTF references) does not
    exist, ValueError if it cannot be parsed, holds no triangles, is truncated, or its header
    declares more data than ``softrast.get_memory_budget()`` (checked before parsing).
    """
    path_str = os.fspath(path)
    if not os.path.isfile(path_str):
        raise FileNotFoundError(errno.ENOENT, "mesh file not found", path_str)
    _check_mesh_file(path_str)
    try:
        with _keep_ctrl_c():
            import trimesh

            loaded = trimesh.load(path_str, process=False)  # process=False keeps the vertex order
    except Exception as exc:  # trimesh raises anything from KeyError to struct.error
        raise ValueError(f"could not load mesh {path_str!r}: {type(exc).__name__}: {exc}") from exc
    if isinstance(loaded, trimesh.Scene):
        parts = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh) and len(g.faces)]
        if not parts:
            raise ValueError(f"mesh file {path_str!r} contains no triangles")
        loaded = parts[0] if len(parts) == 1 else trimesh.util.concatenate(parts)
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0 or len(loaded.vertices) == 0:
        raise ValueError(f"mesh file {path_str!r} contains no triangles")
    try:
        return Mesh.from_trimesh(loaded, smooth=smooth, color=color)
    except ValueError as exc:  # NaN vertices and the like: say which file they came from
        raise ValueError(f"could not load mesh {path_str!r}: {exc}") from exc
