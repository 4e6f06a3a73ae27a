"""Triangle meshes: validated, read-only geometry that is uploaded to the C++ core once.

A ``Mesh`` owns immutable copies of its arrays; the cached ``softrast._core.MeshData`` views them
in place (no second copy), and they can never change under it. Vertex order is kept exactly as
given (or as the file lists it), so ``triangle_id`` outputs index ``Mesh.faces`` directly.
"""
from __future__ import annotations

import contextlib
import errno
import os
import signal
import threading
from typing import Any, Iterator, Sequence

import numpy as np
import numpy.typing as npt

from ._mesh_files import check_mesh_file
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
    """A private C-contiguous copy that nobody (including the caller) can modify.

    Its memory is a bytes object: NumPy refuses to make such an array writeable again, whereas
    an array owning its memory can be, even once marked read-only. The core relies on this to
    view it without a copy (mutation after validation could send face indices out of range).
    """
    contiguous = np.ascontiguousarray(arr, dtype=dtype)  # no copy if already so
    return np.frombuffer(contiguous.tobytes(), dtype=dtype).reshape(contiguous.shape)


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

    All stored arrays are immutable copies, so later edits to the inputs never reach the mesh.
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

        # Bytes of the float32 / int32 copies below, twice: a copy may be converted in a temporary
        # first. The core views the copies in place.
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


class _FileProblem(ValueError):
    """What load_mesh itself finds wrong with a loaded file (reported without a type name)."""


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
    exist, ValueError (naming the file) for every other failure: it cannot be parsed, holds no
    triangles, is truncated or disagrees with its own counts (PLY, OFF, STL, glTF; an OBJ or
    ASCII STL cut mid-line), has a face index out of range, or its header declares more data
    than ``softrast.get_memory_budget()`` (checked before parsing).
    """
    path_str = os.fspath(path)
    if not os.path.isfile(path_str):
        raise FileNotFoundError(errno.ENOENT, "mesh file not found", path_str)
    stated_faces = check_mesh_file(path_str)
    # trimesh raises anything from KeyError to struct.error while parsing, and more later, from
    # its lazily computed properties (an IndexError for a face index past the vertices, a
    # ModuleNotFoundError when merging textured parts needs Pillow): all of it is this file's
    # failure to load, so it becomes a ValueError naming the file.
    try:
        with _keep_ctrl_c():
            import trimesh

            loaded = trimesh.load(path_str, process=False)  # process=False keeps the vertex order
            if isinstance(loaded, trimesh.Scene):
                parts = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh) and len(g.faces)]
                if not parts:
                    raise _FileProblem("the file contains no triangles")
                loaded = parts[0] if len(parts) == 1 else trimesh.util.concatenate(parts)
            if (not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0
                    or len(loaded.vertices) == 0):
                raise _FileProblem("the file contains no triangles")
            if len(loaded.faces) < stated_faces:
                raise _FileProblem(f"it has {stated_faces} faces but only {len(loaded.faces)} "
                                   "could be read: corrupt face rows were skipped")
            faces, count = np.asarray(loaded.faces), len(loaded.vertices)
            bad = (faces < 0) | (faces >= count)
            if bad.any():
                raise _FileProblem(f"face {int(np.flatnonzero(bad.any(axis=1))[0])} has a vertex "
                                   f"index {int(faces[bad][0])} out of bounds for {count} vertices")
    except ImportError as exc:  # trimesh imports optional modules lazily (and hides .name)
        hint = " (Pillow, a softrast dependency: pip install pillow)" if "PIL" in str(exc) else ""
        raise ValueError(f"could not load mesh {path_str!r}: trimesh needs a module that is not "
                         f"installed to read it: {exc}{hint}") from exc
    except Exception as exc:
        what = str(exc) if isinstance(exc, _FileProblem) else f"{type(exc).__name__}: {exc}"
        raise ValueError(f"could not load mesh {path_str!r}: {what}") from exc
    try:
        return Mesh.from_trimesh(loaded, smooth=smooth, color=color)
    except TypeError:
        raise  # an argument (color) of the wrong type: it names the argument, not the file
    except Exception as exc:  # NaN vertices and the like: say which file they came from
        what = str(exc) if type(exc) is ValueError else f"{type(exc).__name__}: {exc}"
        raise ValueError(f"could not load mesh {path_str!r}: {what}") from exc
