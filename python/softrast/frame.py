"""Frame: a render's outputs as NumPy arrays (views of the renderer's memory, no copy), and the
output table's names, formats and files."""
from __future__ import annotations

import os
from collections.abc import Iterable
from typing import Any, Sequence

import numpy as np

from . import _core
from .limits import check_budget
from .io import _write_bytes, imread, imwrite
from .opencv import depth_to_mm_uint16

__all__ = ["Frame"]


# Bytes per pixel of each output (see Frame): what a render allocates for it. From the core's
# output table, as every list of outputs here is.
_OUTPUT_BYTES = {row["name"]: row["bytes_per_pixel"] for row in _core.OUTPUT_TABLE}


class Frame:
    """The buffers of one render, as NumPy arrays. Outputs that were not requested are ``None``.

    Every array views memory the C++ renderer allocated for this frame alone (``arr.base`` owns
    it; nothing is copied). Later renders never write into it.

    Parameters
    ----------
    buffers : dict of str to ndarray
        The outputs by name (``Renderer.render`` makes Frames; ``Frame.load`` reads them back).

    Attributes
    ----------
{outputs}
    """

    __slots__ = _core.OUTPUTS

    def __init__(self, buffers: dict[str, np.ndarray]) -> None:
        _init_frame(self, buffers.get)

    @property
    def outputs(self) -> tuple[str, ...]:
        """Names of the outputs this frame holds."""
        return tuple(n for n in self.__slots__ if getattr(self, n) is not None)

    def as_dict(self) -> dict[str, np.ndarray]:
        """The outputs this frame holds, by name.

        Returns
        -------
        dict of str to ndarray
        """
        return {n: getattr(self, n) for n in self.outputs}

    def save(self, directory: str | os.PathLike[str], stem: str,
             formats: dict[str, str] | None = None) -> dict[str, str]:
        """Write each output to ``directory/{stem}_{name}.{ext}``.

        PNG and TIFF are written by softrast's own encoder (``softrast.imwrite``), fast and with the
        GIL released. Every format but jpg and png16mm gives the output back exactly (``Frame.load``),
        and the same frame gives the same bytes (files are reproducible). Each file is written
        atomically. docs/file_formats.md, "Frames on disk", has the table.

        Parameters
        ----------
        directory : str or os.PathLike
            Where to write.
        stem : str
            A non-empty file name part (no path separator).
        formats : dict of str to str, optional
            {output name: format} overriding the defaults, formats being:

            - "png": 8-bit PNG: color, mask (0 / 255)
            - "jpg": JPEG (lossy): color
            - "png16": 16-bit PNG: triangle_id, instance_id storing id + 1 (0 = background; ids must
              fit: at most 65534), coverage
            - "png16mm": 16-bit PNG of depth or ray_depth in millimetres (round half up, clipped to
              [1, 65535] where hit, 0 = background: lossy, for tools that want it)
            - "tif": TIFF in the output's own dtype (deflated): every output
            - "exr": float32 OpenEXR (zip, through OpenImageIO, 5-10x slower): every float output
            - "npy": NumPy's .npy: every output, raw

            Defaults: color and mask "png"; the float outputs "tif" (float32, which OpenCV,
            scikit-image, imageio, tifffile and OpenImageIO open; Pillow the one-channel ones);
            triangle_id and instance_id "png16" when every id fits, else "tif" (int32, the id itself);
            coverage "tif".

        Returns
        -------
        dict of str to str
            {name: path} of the files written.

        Raises
        ------
        ValueError
            For a bad stem, a format an output cannot be saved in, or values a format cannot store.
        """
        if not isinstance(stem, str) or not stem or os.sep in stem:
            raise ValueError(f"stem must be a non-empty file name part, got {stem!r:.80}")
        formats = dict(formats or {})
        for name, fmt in formats.items():
            if name not in self.outputs:
                raise ValueError(f"formats: {name!r} is not an output of this frame {self.outputs}")
            if fmt not in _SAVE_FORMATS.get(name, ()):
                raise ValueError(f"formats: {name!r} cannot be saved as {fmt!r}; choose from "
                                 f"{_SAVE_FORMATS[name]}")
        directory = os.fspath(directory)
        written = {}
        for name in self.outputs:
            arr = getattr(self, name)
            fmt = formats.get(name) or _default_format(name)
            path = os.path.join(directory, f"{stem}_{name}.{fmt if fmt not in ('png16', 'png16mm') else 'png'}")
            if fmt == "npy":
                _save_npy(path, arr)
            elif fmt == "png16" and name in ("triangle_id", "instance_id"):
                try:
                    data = _core.encode_png_ids(arr)  # id + 1, checked to fit, in one pass
                except ValueError:
                    if name in formats:
                        raise ValueError(f"formats: {name} has ids outside -1..65534, which png16 "
                                         "cannot store (id + 1): use 'tif' or 'npy'") from None
                    path = os.path.splitext(path)[0] + ".tif"  # the default's fallback: the ids
                    imwrite(path, arr)
                else:
                    _write_bytes(path, data)
            elif fmt == "png16":  # coverage
                if arr.size and int(arr.max()) > 65535:
                    raise ValueError(f"formats: {name} has values over 65535: use 'tif' or 'npy'")
                imwrite(path, arr.astype(np.uint16))
            elif fmt == "png16mm":
                imwrite(path, depth_to_mm_uint16(arr, scale=1000.0))
            else:
                imwrite(path, arr)
            written[name] = path
        return written

    @classmethod
    def load(cls, directory: str | os.PathLike[str], stem: str) -> "Frame":
        """The frame ``save`` wrote as ``directory/{stem}_*``.

        Parameters
        ----------
        directory : str or os.PathLike
            Where ``save`` wrote.
        stem : str
            ``save``'s stem.

        Returns
        -------
        Frame
            Each output as it was (png16 ids less 1, masks as bool; png16mm depths in scene units,
            from millimetres).

        Raises
        ------
        ValueError
            Naming the file, unless each file holds what ``save`` writes for its output (the dtype
            and channels of ``softrast.OUTPUT_TABLE``, in a format ``save`` offers for it) and all of
            them one (h, w). Two files of one output (say a .png and the .tif of a later save in
            another format) are ambiguous: ValueError naming both.
        FileNotFoundError
            If no output was saved under that stem.
        """
        directory = os.fspath(directory)
        buffers = {}
        first: tuple[str, tuple[int, ...]] | None = None
        for name in _core.OUTPUTS:
            found = [path for ext in ("npy", "png", "exr", "tif", "jpg")
                     if os.path.exists(path := os.path.join(directory, f"{stem}_{name}.{ext}"))]
            if not found:
                continue
            if len(found) > 1:  # saved again in another format: which one is this frame's?
                raise ValueError(f"{' and '.join(found)}: two files of output {name}; remove "
                                 "the stale one")
            path = found[0]
            arr = _read_output(path, name)
            if first is None:
                first = (path, arr.shape[:2])
            elif arr.shape[:2] != first[1]:
                raise ValueError(f"{path}: {name} is {arr.shape[:2]} (h, w), but {first[0]} "
                                 f"is {first[1]}: the outputs of one frame have one size")
            buffers[name] = arr
        if not buffers:
            raise FileNotFoundError(f"no outputs saved as {os.path.join(directory, stem)}_*")
        return cls(buffers)

    def __repr__(self) -> str:
        shapes = ", ".join(f"{n}={getattr(self, n).shape}" for n in self.outputs)
        return f"Frame({shapes})"


_FLOAT_OUTPUTS = tuple(r["name"] for r in _core.OUTPUT_TABLE if r["dtype"] == "float32")


_SAVE_FORMATS: dict[str, tuple[str, ...]] = {
    **{name: ("exr", "tif", "npy") for name in _FLOAT_OUTPUTS},
    "depth": ("exr", "tif", "npy", "png16mm"), "ray_depth": ("exr", "tif", "npy", "png16mm"),
    "color": ("png", "jpg", "tif", "npy"), "mask": ("png", "tif", "npy"),
    "triangle_id": ("png16", "tif", "npy"), "instance_id": ("png16", "tif", "npy"),
    "coverage": ("png16", "tif", "npy"),
}


_OUTPUT_ROWS = {row["name"]: row for row in _core.OUTPUT_TABLE}


# The file extensions save writes for each output (png16 and png16mm are .png files).
_SAVE_EXTENSIONS = {name: frozenset("png" if f in ("png16", "png16mm") else f for f in fmts)
                    for name, fmts in _SAVE_FORMATS.items()}


def _stored_dtype(name: str, ext: str) -> np.dtype:
    """The dtype in which ``save`` stores output ``name`` in a ``.ext`` file."""
    if ext in ("png", "jpg"):  # 8-bit colour and masks, 16-bit ids, coverage and millimetres
        return np.dtype(np.uint8) if name in ("color", "mask") else np.dtype(np.uint16)
    if name == "mask" and ext != "npy":  # tif: 0 / 255
        return np.dtype(np.uint8)
    return np.dtype(_OUTPUT_ROWS[name]["dtype"])


def _expected_shape(name: str) -> str:
    return "(h, w)" if _OUTPUT_ROWS[name]["channels"] == 1 else f"(h, w, {_OUTPUT_ROWS[name]['channels']})"


def _check_stored(path: str, name: str, ext: str, dtype: np.dtype, shape: tuple[int, ...]) -> None:
    channels = _OUTPUT_ROWS[name]["channels"]
    want = _stored_dtype(name, ext)
    ok_shape = len(shape) == 2 if channels == 1 else (len(shape) == 3 and shape[2] == channels)
    if dtype != want or not ok_shape or 0 in shape:
        raise ValueError(f"{path}: holds a {tuple(shape)} {dtype} array, but {name} is stored "
                         f"in a .{ext} file as {_expected_shape(name)} {want} (softrast.OUTPUT_TABLE)")


def _read_npy(path: str, name: str) -> np.ndarray:
    """A .npy file of output ``name``, its header checked before any data is read."""
    from numpy.lib import format as npy_format

    try:
        with open(path, "rb") as f:
            version = npy_format.read_magic(f)
            if version == (1, 0):
                shape, fortran, dtype = npy_format.read_array_header_1_0(f)
            elif version == (2, 0):
                shape, fortran, dtype = npy_format.read_array_header_2_0(f)
            else:
                raise ValueError(f"unsupported .npy version {version}")
            _check_stored(path, name, "npy", dtype, shape)
            need = f.tell() + int(np.prod(shape)) * dtype.itemsize
            size = os.fstat(f.fileno()).st_size
            if size != need:
                raise ValueError(f"{path}: {size} bytes, but its header ({shape} {dtype}) needs "
                                 f"{need}: truncated or corrupt")
            check_budget(need, f"{path} ({shape} {dtype})")
            f.seek(0)
            arr = npy_format.read_array(f, allow_pickle=False)
    except ValueError as e:
        if path in str(e):
            raise
        raise ValueError(f"{path}: not a valid .npy file of {name}: {e}") from None
    except (EOFError, OSError, UnicodeDecodeError, SyntaxError) as e:
        raise ValueError(f"{path}: not a valid .npy file of {name}: {e}") from None
    return np.ascontiguousarray(arr)


def _read_output(path: str, name: str) -> np.ndarray:
    """Output ``name`` from a file ``save`` wrote (``path``, its format from the extension),
    converted back to the output's dtype; ValueError naming the file when it holds anything
    else (a format save never uses for it, another dtype or channel count, a damaged file)."""
    ext = os.path.splitext(path)[1][1:].lower()
    if ext not in _SAVE_EXTENSIONS[name]:
        raise ValueError(f"{path}: save never writes {name} as .{ext} (it writes "
                         f"{', '.join('.' + e for e in sorted(_SAVE_EXTENSIONS[name]))})")
    if ext == "npy":
        return _read_npy(path, name)
    arr = imread(path)
    _check_stored(path, name, ext, arr.dtype, arr.shape)
    if ext == "png" and name in ("triangle_id", "instance_id"):
        arr = arr.astype(np.int32) - 1
    elif ext == "png" and name == "coverage":
        arr = arr.astype(np.uint32)
    elif name == "mask":  # png / tif store 0 / 255
        arr = arr > 0
    elif ext == "png" and name in ("depth", "ray_depth"):
        arr = arr.astype(np.float32) / np.float32(1000.0)
    return arr


def _default_format(name: str) -> str:
    """Save's format for output ``name`` (benchmarks/RESULTS.md, "Datasets and encoders", has the table of
    encoders this was chosen from): the fastest exact file that the common readers open. (Ids
    over 65534 fall back to "tif" when saved.)"""
    if name in ("color", "mask"):
        return "png"
    if name in ("triangle_id", "instance_id"):
        return "png16"
    return "tif"  # coverage and the float outputs


def _save_npy(path: str, arr: np.ndarray) -> None:
    """np.save, atomically (a temporary name in the same directory, then renamed)."""
    import uuid

    directory, base = os.path.split(os.path.abspath(path))
    if not os.path.isdir(directory):
        raise FileNotFoundError(f"directory does not exist: {directory}")
    tmp = os.path.join(directory, f".{base}.{os.getpid()}-{uuid.uuid4().hex[:12]}.tmp")
    try:
        with open(tmp, "wb") as f:
            np.save(f, np.ascontiguousarray(arr), allow_pickle=False)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def _make_frame_init() -> Any:
    """Frame's attribute assignments, one per output of the table, as straight-line code (a loop
    of setattr cost 2 us of a 6 us render call)."""
    body = "".join(f"    frame.{n} = get({n!r})\n" for n in _core.OUTPUTS)
    namespace: dict[str, Any] = {}
    exec(f"def _init_frame(frame, get):\n{body}", namespace)
    return namespace["_init_frame"]


_init_frame = _make_frame_init()


Frame.__doc__ = (Frame.__doc__ or "").replace("{outputs}", "\n".join(
    f"    {row['name']:<11} : {row['doc']}" for row in _core.OUTPUT_TABLE))


# Checked output tuples (and single names): a batch asks for the same outputs every render.
_CHECKED_OUTPUTS: dict[Any, Sequence[str]] = {}


def _output_names(outputs: str | Iterable[str]) -> Sequence[str]:
    """The distinct output names of ``outputs`` (one name or an iterable of names), in order."""
    if type(outputs) is tuple or type(outputs) is str:
        cached = _CHECKED_OUTPUTS.get(outputs)
        if cached is not None:
            return cached
        names = _check_output_names(outputs)
        if len(_CHECKED_OUTPUTS) < 256:
            _CHECKED_OUTPUTS[outputs] = names = tuple(names)  # shared: immutable
        return names
    return _check_output_names(outputs)


def _check_output_names(outputs: str | Iterable[str]) -> list[str]:
    if isinstance(outputs, str):
        names = [outputs]
    elif isinstance(outputs, bytes) or not isinstance(outputs, Iterable):
        raise TypeError(f"outputs must be an output name or a sequence of them, got {type(outputs).__name__}")
    else:
        names = list(outputs)
    if not names:
        raise ValueError("outputs must name at least one output")
    for name in names:
        if not isinstance(name, str):
            raise TypeError(f"outputs must hold output names (str), got {type(name).__name__} {name!r:.80}")
        if name not in _core.OUTPUTS:
            raise ValueError(f"outputs: unknown output {name!r}; choose from {', '.join(_core.OUTPUTS)}")
    return list(dict.fromkeys(names))  # a name given twice is one output (and counted once)


def _out_arrays(out: Frame | dict[str, np.ndarray] | None, names: list[str]) -> dict[str, np.ndarray] | None:
    """The arrays of ``out`` that ``names`` asks for (the core checks each one, and overlaps)."""
    if out is None:
        return None
    if isinstance(out, Frame):
        arrays = {n: a for n in names if (a := getattr(out, n)) is not None}
    elif isinstance(out, dict):
        arrays = {n: a for n in names if (a := out.get(n)) is not None}
    else:
        raise TypeError(f"out must be a Frame or a dict of arrays, got {type(out).__name__}")
    return arrays
