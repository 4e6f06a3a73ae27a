"""Triangle meshes: validated, read-only geometry that is uploaded to the C++ core once.

A ``Mesh`` owns immutable copies of its arrays; the cached ``softrast._core.MeshData`` views them
in place (no second copy), and they can never change under it. Vertex order is kept exactly as
given (or as the file lists it), so ``triangle_id`` outputs index ``Mesh.faces`` directly.
"""
from __future__ import annotations

import contextvars
import ctypes
import math
import warnings
from typing import Any, Callable, Iterator, Sequence

import numpy as np
import numpy.typing as npt

from . import _core
from .files.context import FileInfo
from .files.convert import Part, mesh_part
from .limits import check_budget
from .material import Material

__all__ = ["Mesh", "PrecisionWarning"]

# The core indexes vertices and faces with int32.
_MAX_COUNT = 2**31 - 1
DEFAULT_COLOR = (0.8, 0.8, 0.8, 1.0)

# Rows validated and converted at a time. Every temporary is per chunk (at most a float64 copy of
# 2**16 x 3 values, 1.5 MiB), so building a mesh needs its final arrays plus about 2 MiB whatever
# the input's size or dtype (measured: +72.4 MB for 72.0 MB stored; a 10**8-vertex float64 input
# used to take +382 MB in validation alone).
_CHUNK_ROWS = 2**16
_FLOAT32_MAX = float(np.finfo(np.float32).max)  # 3.4028235e38
# PrecisionWarning threshold: a vertex moved by float32 rounding by more than this fraction of the
# mesh's bounding-box diagonal (see Mesh).
PRECISION_WARNING_FRACTION = 1e-4


# The file load_mesh is reading, for its warnings (a context variable: threads load their own).
_LOADING_FILE: contextvars.ContextVar[str | None] = contextvars.ContextVar("_LOADING_FILE", default=None)


class PrecisionWarning(UserWarning):
    """Storing a mesh's positions as float32 moved its vertices noticeably (see ``Mesh``).

    Raised when positions lie far from the mesh's own origin compared with its size (e.g. geographic
    or world coordinates): centre the mesh and put the offset in the pose, which stays float64.
    """


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


def _check_rows(arr: np.ndarray, name: str, n: int) -> None:
    if arr.shape[0] != n:
        raise ValueError(f"{name} must have one row per vertex ({n}), got {arr.shape[0]}")


# The stored arrays live in bytes objects: NumPy refuses to make an array over a bytes object
# writeable again, whereas an array owning its memory can be, even once marked read-only. The core
# relies on this to view them without a copy (mutation after validation could send face indices
# out of range). ndarray.tobytes() copies the whole array once more, a temporary as large as the
# result: past one chunk, the bytes object is instead created empty and filled in place while
# nothing else can see it, which is what the C API's PyBytes_FromStringAndSize(NULL, size) is for.
_new_bytes = ctypes.PYFUNCTYPE(ctypes.py_object, ctypes.c_void_p, ctypes.c_ssize_t)(
    ("PyBytes_FromStringAndSize", ctypes.pythonapi))
_bytes_address = ctypes.PYFUNCTYPE(ctypes.c_void_p, ctypes.py_object)(
    ("PyBytes_AsString", ctypes.pythonapi))


def _frozen_buffer(shape: tuple[int, int], dtype: npt.DTypeLike) -> tuple[np.ndarray, Callable[[], np.ndarray]]:
    """(fill, freeze): a writeable C-contiguous array to fill, and a function returning the filled
    result as a read-only array over a bytes object. ``fill`` must not be used after ``freeze``."""
    dtype = np.dtype(dtype)
    if shape[0] <= _CHUNK_ROWS:  # small: the copy made by tobytes() is itself at most a chunk
        small = np.empty(shape, dtype)
        return small, lambda: np.frombuffer(small.tobytes(), dtype=dtype).reshape(shape)
    nbytes = shape[0] * shape[1] * dtype.itemsize
    data = _new_bytes(None, nbytes)  # uninitialised; raises MemoryError if it cannot be allocated
    raw = (ctypes.c_char * nbytes).from_address(_bytes_address(data))
    return np.frombuffer(raw, dtype=dtype).reshape(shape), lambda: np.frombuffer(data, dtype=dtype).reshape(shape)


def _chunks(n: int) -> Iterator[slice]:
    for start in range(0, n, _CHUNK_ROWS):
        yield slice(start, min(start + _CHUNK_ROWS, n))


def _float32_rows(arr: np.ndarray, name: str) -> np.ndarray:
    """A frozen float32 copy of the real (n, k) ``arr``, refusing NaN, inf and values that are finite
    but beyond float32's range (1e39 would be stored as inf), by argument name and vertex."""
    fill, freeze = _frozen_buffer(arr.shape, np.float32)
    with np.errstate(over="ignore", invalid="ignore"):  # overflow is reported below, by vertex
        for rows in _chunks(arr.shape[0]):
            out = fill[rows]
            np.copyto(out, arr[rows], casting="unsafe")
            if not np.isfinite(out).all():
                k = rows.start + int(np.flatnonzero(~np.isfinite(out).all(axis=1))[0])
                if np.isfinite(arr[k]).all():
                    raise ValueError(
                        f"{name} has a value beyond float32's range (+-{_FLOAT32_MAX:.8g}) at vertex "
                        f"{k}: {arr[k].tolist()} (float32 would store it as inf)")
                raise ValueError(f"{name} contains NaN or inf at vertex {k}")
    return freeze()


def _int32_faces(arr: np.ndarray, n: int) -> np.ndarray:
    """A frozen int32 copy of the integer (m, 3) ``arr``, every index in [0, n)."""
    fill, freeze = _frozen_buffer(arr.shape, np.int32)
    # Viewed as unsigned, a negative index is huge: one max() checks both ends of [0, n).
    unsigned = np.dtype(f"{arr.dtype.str[0]}u{arr.dtype.itemsize}")  # same byte order ('>i4' -> '>u4')
    for rows in _chunks(arr.shape[0]):
        chunk = arr[rows]
        if chunk.view(unsigned).max() >= n:
            bad = np.flatnonzero(((chunk < 0) | (chunk >= n)).any(axis=1))[0]
            index = next(int(i) for i in chunk[bad] if not 0 <= i < n)
            raise ValueError(f"faces: index {index} in face {rows.start + int(bad)} is outside [0, {n})")
        np.copyto(fill[rows], chunk, casting="unsafe")  # in [0, n) with n < 2**31: exact
    return freeze()


def _colors_kind(arr: np.ndarray) -> str:
    if arr.dtype == np.uint8:
        return "uint8"
    if np.issubdtype(arr.dtype, np.floating):
        return "float"
    # an int array is ambiguous (is 1 one 255th or full intensity?) => refuse
    raise TypeError(f"colors must be uint8 (0-255) or float in [0, 1], got {arr.dtype}")


def _rgba_rows(arr: np.ndarray) -> np.ndarray:
    """Frozen (n, 4) float32 RGBA in [0, 1] from (n, 3) or (n, 4) uint8 or float ``colors``."""
    n, cols = arr.shape
    fill, freeze = _frozen_buffer((n, 4), np.float32)
    if cols == 3:
        fill[:, 3] = 1.0  # opaque when alpha is absent
    kind = _colors_kind(arr)
    for rows in _chunks(n):
        chunk, out = arr[rows], fill[rows, :cols]
        if kind == "uint8":
            np.copyto(out, chunk, casting="unsafe")
            out /= np.float32(255.0)
            continue
        finite = np.isfinite(chunk).all(axis=1)
        if not finite.all():
            raise ValueError(f"colors contains NaN or inf at vertex {rows.start + int(np.flatnonzero(~finite)[0])}")
        if chunk.min() < 0.0 or chunk.max() > 1.0:
            raise ValueError("colors must be uint8 or float in [0, 1]; float values lie outside [0, 1]")
        np.copyto(out, chunk, casting="unsafe")
    return freeze()


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


def _column_bounds(arr: np.ndarray) -> tuple[list[float], list[float]]:
    """Per-column minima and maxima as Python numbers.

    NumPy reduces a (n, 3) array along axis 0 with an inner loop of 3 (62 us for 642 rows, 7 ms
    for 65,536); a transposed copy of each chunk reduces along contiguous rows instead (5 us,
    0.13 ms), 12x to 55x faster, for a chunk-sized temporary.
    """
    lo: list[float] = []
    hi: list[float] = []
    for rows in _chunks(arr.shape[0]):
        t = np.ascontiguousarray(arr[rows].T)
        lo = [min(a, b) for a, b in zip(lo, t.min(axis=1).tolist())] if lo else t.min(axis=1).tolist()
        hi = [max(a, b) for a, b in zip(hi, t.max(axis=1).tolist())] if hi else t.max(axis=1).tolist()
    return lo, hi


def _warn_if_imprecise(given: np.ndarray, stored: np.ndarray) -> None:
    """PrecisionWarning if float32 rounding moved a vertex by more than PRECISION_WARNING_FRACTION
    of the bounding-box diagonal (both measured on ``given``, in float64)."""
    # Quick bound from the stored bounds: rounding moves a value by at most half the float32
    # spacing at the largest magnitude (ulp / 2), and the diagonal by at most sqrt(3) * ulp. Every
    # usual mesh stops here (icosphere, spot.obj: ulp / diagonal ~ 1e-7).
    lo, hi = _column_bounds(stored)
    # float32 spacing in the binade of the largest magnitude; 2**-149 among subnormals
    ulp = max(math.ldexp(1.0, math.frexp(max(map(abs, lo + hi)))[1] - 24), 2.0**-149)
    if ulp / 2 <= PRECISION_WARNING_FRACTION * (math.dist(lo, hi) - 2 * ulp):
        return
    low, high = (np.array(b, np.float64) for b in _column_bounds(given))
    diagonal = math.dist(low.tolist(), high.tolist())  # scaled: np.linalg.norm underflows at 1e-300
    if diagonal == 0.0:  # a single point: nothing to distort
        return
    moved, worst = 0.0, 0
    for rows in _chunks(given.shape[0]):  # the actual error: float32 input, say, loses nothing
        error = stored[rows].astype(np.float64)  # the one chunk-sized temporary (1.5 MiB)
        np.subtract(error, given[rows], out=error, casting="unsafe")  # longdouble input: rounded
        error = np.abs(error, out=error).max(axis=1)
        k = int(error.argmax())
        if error[k] > moved:
            moved, worst = float(error[k]), rows.start + k
    if moved > PRECISION_WARNING_FRACTION * diagonal:
        largest = float(np.abs(np.concatenate([low, high])).max())
        if largest > diagonal:  # far from its origin for its size: the usual case
            advice = (f"its coordinates (up to {largest:.3g}) are far from its origin for its size. "
                      f"Centre the mesh (subtract {((low + high) / 2).tolist()}) and put that "
                      "offset in the pose (Scene.add(mesh, pose=...), float64) instead")
        else:  # tiny: float32 subnormals (below 1.2e-38) or zero
            advice = (f"its coordinates (up to {largest:.3g}) are too small for float32. Scale "
                      "the mesh up and put the inverse scale in the pose instead")
        source = _LOADING_FILE.get()
        warnings.warn(
            (f"{source}: " if source else "") +
            f"positions: storing them as float32 moved vertex {worst} by {moved:.3g}, "
            f"{moved / diagonal:.2g} of the mesh's bounding-box diagonal ({diagonal:.3g}): {advice}",
            PrecisionWarning, stacklevel=3)


class Mesh:
    """An indexed triangle mesh with optional per-vertex attributes; immutable.

    Stored arrays are immutable copies (later edits to the inputs never reach the mesh);
    ``copy.copy`` and ``copy.deepcopy`` return the mesh itself (it cannot change); pickling
    rebuilds it through this constructor, read-only and bit-identical.

    Parameters
    ----------
    positions : array_like, shape (n, 3)
        Real object-space coordinates (finite); stored as float32.
    faces : array_like, shape (m, 3)
        Integer vertex indices in [0, n); stored as int32. Counter-clockwise faces (seen from
        outside) are front faces, as in OpenGL.
    normals : array_like, shape (n, 3), optional
        Real per-vertex normals; None => flat face normals.
    uvs : array_like, shape (n, 2), optional
        Real texture coordinates (u right, v up).
    colors : array_like, shape (n, 3) or (n, 4), optional
        uint8 (0-255) or float in [0, 1]; stored as (n, 4) float32 RGBA (alpha 1 if absent).
    color : sequence of 3 or 4 floats, optional
        In [0, 1], the base colour used when ``colors`` is None.
    material : Material, optional
        With a material, ``color`` is its base colour (a ``color`` given as well must agree).
        None: lambert shading of the base colour, two-sided, no specular term (``Scene.add(...,
        material=)`` overrides it per instance).

    Raises
    ------
    TypeError, ValueError
        Naming the argument (and the vertex or face) for a wrong dtype or shape, NaN or inf, a
        finite value beyond float32's range (|x| > 3.4028235e38, e.g. 1e39, which float32 would
        store as inf), colours outside [0, 1] or an index outside [0, n); ValueError if the
        stored arrays (4 bytes per value) exceed ``softrast.get_memory_budget()``, checked from
        the shapes before anything is converted. Validation works in chunks of 65,536 rows, so
        it needs about 2 MiB beyond the stored arrays whatever the input's size or dtype.

    Warns
    -----
    PrecisionWarning
        When storing positions as float32 moves a vertex by more than
        ``PRECISION_WARNING_FRACTION`` (1e-4) of the mesh's bounding-box diagonal: a tenth of a
        pixel when the mesh spans 1,000 pixels, one pixel at 10,000. float32 keeps 24 bits, so
        this happens once coordinates are about 2**24 * 1e-4 ~ 1,700 times (or more) farther
        from the mesh's origin than its size, e.g. a 1 m object at 10 km, or a 20 m building in
        UTM coordinates (~1e6 m, float32 spacing 0.06 m). Centre the mesh and put the offset in
        the pose (float64: rendered correctly). Only the actual rounding counts: float32 input,
        or integers below 2**24, are stored exactly and never warn.
    """

    __slots__ = ("_positions", "_faces", "_normals", "_uvs", "_colors", "_color", "_material", "_core")

    def __init__(
        self,
        positions: npt.ArrayLike,
        faces: npt.ArrayLike,
        normals: npt.ArrayLike | None = None,
        uvs: npt.ArrayLike | None = None,
        colors: npt.ArrayLike | None = None,
        color: Sequence[float] | None = None,
        material: Any = None,
    ) -> None:
        # 1. Shapes and dtypes only: nothing proportional to the input is allocated before the
        # budget check (np.asarray is no copy for arrays, broadcast views and memory maps).
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
        attributes: dict[str, np.ndarray] = {}
        for name, value, cols in (("normals", normals, 3), ("uvs", uvs, 2)):
            if value is not None:
                arr = attributes[name] = _as_array(value, name)
                _check_real(arr, name)
                _check_shape(arr, name, f"(n, {cols})", (cols,))
                _check_rows(arr, name, n)
        if colors is not None:
            arr = attributes["colors"] = _as_array(colors, "colors")
            _check_shape(arr, "colors", "(n, 3) or (n, 4)", (3, 4))
            _check_rows(arr, "colors", n)
            _colors_kind(arr)
        if material is not None:
            if not isinstance(material, Material):
                raise TypeError(f"material must be a softrast.Material or None, got {type(material).__name__}")
            if color is not None and _rgba(color, "color") != material.base_color:
                raise ValueError(f"color {tuple(color)} differs from material.base_color "
                                 f"{material.base_color}: give one of them")
            rgba = material.base_color
        else:
            rgba = _rgba(DEFAULT_COLOR if color is None else color, "color")

        # 2. The budget: the bytes of the float32 / int32 arrays stored below, which the core views
        # in place. Validation and conversion add only per-chunk temporaries (about 2 MiB).
        check_budget(4 * (3 * n + 3 * m + sum(
            cols * n for name, cols in (("normals", 3), ("uvs", 2), ("colors", 4)) if name in attributes)),
            f"mesh with {n} vertices and {m} triangles")

        # 3. Validate and convert, a chunk of rows at a time.
        self._positions = _float32_rows(pos, "positions")
        self._faces = _int32_faces(fac, n)
        self._normals = _float32_rows(attributes["normals"], "normals") if "normals" in attributes else None
        self._uvs = _float32_rows(attributes["uvs"], "uvs") if "uvs" in attributes else None
        self._colors = _rgba_rows(attributes["colors"]) if "colors" in attributes else None
        self._color = rgba
        self._material = material
        self._core: Any = None
        _warn_if_imprecise(pos, self._positions)

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
    def material(self) -> Any:
        """The mesh's ``softrast.Material``, or None (lambert, two-sided, no specular)."""
        return self._material

    @property
    def num_vertices(self) -> int:
        """Number of vertices, n."""
        return int(self._positions.shape[0])

    @property
    def num_faces(self) -> int:
        """Number of triangles, m."""
        return int(self._faces.shape[0])

    @property
    def bounds(self) -> npt.NDArray[np.float64]:
        """(2, 3) float64: row 0 = per-axis minimum, row 1 = maximum, object space."""
        return np.stack([self._positions.min(axis=0), self._positions.max(axis=0)]).astype(np.float64)

    # -- copy and pickle: immutable, so a copy is the mesh itself (as for tuples), keeping the core
    # upload. Pickles hold the arrays, rebuilt by the validating constructor (float32 round-trips
    # exactly, warning no more than the original); the core upload is rebuilt on first use.
    def __copy__(self) -> "Mesh":
        return self

    def __deepcopy__(self, memo: dict[int, Any]) -> "Mesh":
        return self

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        return (type(self), (self._positions, self._faces, self._normals, self._uvs, self._colors,
                             None if self._material is not None else self._color, self._material))

    def __repr__(self) -> str:
        attrs = [a for a in ("normals", "uvs", "colors") if getattr(self, "_" + a) is not None]
        return f"Mesh(num_vertices={self.num_vertices}, num_faces={self.num_faces}, attributes={attrs})"

    def _core_data(self) -> Any:
        """The ``softrast._core.MeshData`` for this mesh, built on first use and cached."""
        if self._core is None:
            self._core = _core.MeshData(self._positions, self._faces, self._normals, self._colors, self._uvs)
        return self._core

    # -- constructors -----------------------------------------------------------------------
    @classmethod
    def from_trimesh(cls, tm: Any, smooth: bool = True, color: Sequence[float] | None = None,
                     srgb_colors: bool = False) -> "Mesh":
        """Build a Mesh from a ``trimesh.Trimesh`` (or a ``trimesh.Scene``, concatenated).

        Parameters
        ----------
        tm : trimesh.Trimesh or trimesh.Scene
            Its uvs (``TextureVisuals``), per-vertex and per-face colours are kept: a Mesh
            colours vertices, so each face with a colour of its own gets three vertices of its
            own (faces keep their order; smooth normals are the original vertex's). A Scene whose
            parts have different materials gets the first part's, with a UserWarning
            (``softrast.load_scene`` keeps each part's).
        smooth : bool or str, optional
            Per-vertex normals: the file's own where it carries them, else True or "area"
            (default): each vertex's adjacent face normals weighted by face area (the course
            notes' rule), "angle": weighted by the face's corner angle (trimesh's
            ``vertex_normals``, recomputed in float64 where trimesh drops a face: a mesh below
            ~1e-5 units, a corner 1e19 away from unit ones); False: flat face normals (faceted
            shading). Either weighting gives every vertex of a non-degenerate face a unit normal
            for coordinates anywhere from 1e-30 to 3e38 (``softrast.normals.vertex_normals``).
        color : sequence of 3 or 4 floats, optional
            Base RGBA; None => the material's base colour, else the default grey. With a
            material, ``color`` replaces its base colour.
        srgb_colors : bool, optional
            True => trimesh's 8-bit vertex / face colours are sRGB-encoded (as PLY, OBJ and OFF
            files store them) and are decoded to linear with the exact IEC 61966-2-1 curve;
            False (default) => they are taken as linear (value / 255). Alpha is linear.

        Returns
        -------
        Mesh
            A trimesh material becomes a ``softrast.Material``: a ``SimpleMaterial`` (MTL) ->
            ka/kd/ks/shininess and model "pbr", metallic 0, roughness from ks and shininess (the
            MTL rule of docs/file_formats.md); a ``PBRMaterial`` (glTF) -> base colour,
            metallic, roughness (trimesh's None: glTF's defaults 1 and 1), emissive,
            double_sided, model "pbr". trimesh holds their colours as 8 bits;
            ``softrast.load_mesh`` reads the exact values from the file instead. Its images
            become ``softrast.Texture`` objects (a SimpleMaterial's image: the base colour
            texture; a PBRMaterial's base colour, metallic-roughness, normal, occlusion and
            emissive textures, with default samplers: trimesh keeps none), and its alpha mode (a
            PBRMaterial's MASK -> "mask", BLEND -> "blend"; a SimpleMaterial whose diffuse alpha
            is below 255 -> "blend", as MTL's ``d`` < 1).
        """
        return _mesh_of(mesh_part(tm, smooth, FileInfo(None, srgb=bool(srgb_colors))), color)


def _check_smooth(smooth: Any) -> None:
    """True, False, "area" or "angle" (not 1 or 0: bools only)."""
    if not (isinstance(smooth, bool) or (isinstance(smooth, str) and smooth in ("area", "angle"))):
        raise ValueError(f"smooth must be True, False, 'area' or 'angle', got {smooth!r:.80}")


def _mesh_of(part: Part, color: Sequence[float] | None) -> Mesh:
    """The Mesh of a file's (or trimesh object's) part; ``color`` replaces its base colour."""
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
