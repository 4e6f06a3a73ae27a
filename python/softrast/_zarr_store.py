"""``write_dataset(store="zarr")``: each output as one chunked, compressed array of a zarr group.

The layout (zarr format 2, a view a chunk, Blosc), fill values, why format 2, how chunks are
written atomically by softrast itself (not through zarr-python) and how resume checks them are
in docs/file_formats.md, "zarr (``write_dataset(store="zarr")``)".
"""
from __future__ import annotations

import concurrent.futures
import importlib.util
import json
import os
import struct
import time
from typing import Any, Iterable, NamedTuple, Sequence

import numpy as np

from . import _core
from ._dataset_writing import (WrittenViews, _interrupt_between_views, _progress_bar,
                               _remove_stale_temporaries, _write_frames)
from .cameras_json import _write_cameras_json
from .frame import _check_output_names
from .io import _write_bytes

GROUP = "views.zarr"
_GROUP_ATTRS = {"softrast": "dataset views: <output>[k] is the view of cameras.json's frames[k]"}
_CNAME, _CLEVEL = "lz4", 5
_BLOSC_HEADER = 16
_BLOSC_MAX_BYTES = 2**31 - 1 - _BLOSC_HEADER  # Blosc 1 compresses at most this much a chunk
_ROWS = {row["name"]: row for row in _core.OUTPUT_TABLE}


def _blosc() -> Any:
    """numcodecs' Blosc codec class; ImportError naming the extra when zarr is not installed."""
    hint = "store='zarr' needs zarr: pip install softrast[zarr]"
    if importlib.util.find_spec("zarr") is None:
        raise ImportError(f"{hint} (zarr is not installed)")
    try:
        from numcodecs import Blosc
    except ImportError as e:
        raise ImportError(f"{hint} ({e})") from e
    return Blosc


def _fill_value(dtype: np.dtype) -> Any:
    """A value no render gives, where the dtype has one (JSON, as .zarray holds it); else
    null: no fill value."""
    if dtype.kind == "f":
        return "NaN"
    if dtype == np.int32:  # ids are >= -1
        return int(np.iinfo(np.int32).min)
    if dtype == np.uint32:  # coverage: a count of triangles
        return int(np.iinfo(np.uint32).max)
    return None  # colour, mask: every value is a pixel's, so none (xarray then masks nothing)


class _Array(NamedTuple):
    """One output's array: where its chunks go and what a view of it is."""

    name: str
    folder: str
    shape: tuple[int, ...]  # of a view
    dtype: np.dtype
    codec: Any  # numcodecs.Blosc

    def chunk(self, k: int) -> str:
        return os.path.join(self.folder, ".".join([str(k)] + ["0"] * len(self.shape)))

    @property
    def nbytes(self) -> int:
        return int(np.prod(self.shape)) * self.dtype.itemsize


def _view_shape(name: str, h: int, w: int) -> tuple[int, ...]:
    c = _ROWS[name]["channels"]
    return (h, w) if c == 1 else (h, w, c)


def _array_metadata(name: str, n: int, h: int, w: int) -> tuple[dict, dict]:
    """(.zarray, .zattrs) of output ``name`` with ``n`` views of h x w."""
    dtype = np.dtype(_ROWS[name]["dtype"])
    view = _view_shape(name, h, w)
    dims = ["view", "y", "x"] + ([f"{name}_channel"] if len(view) == 3 else [])
    zarray = {"zarr_format": 2, "shape": [n, *view], "chunks": [1, *view], "dtype": dtype.str,
              "compressor": {"id": "blosc", "cname": _CNAME, "clevel": _CLEVEL,
                             "shuffle": 1 if dtype.kind == "f" else 0, "blocksize": 0},
              "fill_value": _fill_value(dtype), "order": "C", "filters": None,
              "dimension_separator": "."}
    zattrs = {"_ARRAY_DIMENSIONS": dims, "description": _ROWS[name]["doc"]}
    return zarray, zattrs


def _dumps(doc: Any) -> bytes:
    return (json.dumps(doc, indent=2) + "\n").encode("utf-8")


def _read_json(path: str) -> Any:
    try:
        with open(path, "rb") as f:
            return json.loads(f.read().decode("utf-8"))
    except (OSError, ValueError, RecursionError):
        return None


def _atomic_write(path: str, data: bytes) -> None:
    """``data`` to ``path`` through a hidden temporary in the same folder
    (``.{name}.{pid}-{id}.tmp``), then renamed."""
    _write_bytes(path, data, suffix="")


def _describe(zarray: dict) -> str:
    return (f"{tuple(zarray.get('shape', ())[1:])} {zarray.get('dtype')} views, compressor "
            f"{zarray.get('compressor')}, fill {zarray.get('fill_value')!r}")


def prepare(root: str, n: int, h: int, w: int, names: Sequence[str]) -> dict[str, _Array]:
    """Make (or check, or grow to ``n`` views) the group ``root`` and one array per output.

    Only what differs from what is on disk is written (the metadata of a resumed run, or of a
    shard after ``render_dataset`` made the arrays, is left untouched), each file atomically,
    .zmetadata last.

    Parameters
    ----------
    root : str
        The group's directory.
    n : int
        Views.
    h, w : int
        Image size.
    names : sequence of str
        The outputs.

    Returns
    -------
    dict of str to _Array
        The arrays by output.

    Raises
    ------
    ValueError
        Naming the array, for one of another image size, dtype or codec.
    """
    Blosc = _blosc()
    os.makedirs(root, exist_ok=True)
    if os.path.exists(os.path.join(root, "zarr.json")):
        raise ValueError(f"{root}: a zarr format 3 node; softrast writes format 2 here: use "
                         "another directory or remove it")
    _remove_stale_metadata(root)
    arrays, docs = {}, {}
    for name in names:
        zarray, zattrs = _array_metadata(name, n, h, w)
        folder = os.path.join(root, name)
        old = _read_json(os.path.join(folder, ".zarray"))
        if isinstance(old, dict) and isinstance(old.get("shape"), list) and old["shape"]:
            same = {**old, "shape": old["shape"][1:]} == {**zarray, "shape": zarray["shape"][1:]}
            if not same:
                raise ValueError(
                    f"{folder} holds {_describe(old)}; these views are {_describe(zarray)}: "
                    f"write to another directory, or remove {folder}")
            if isinstance(old["shape"][0], int) and old["shape"][0] > n:
                zarray["shape"][0] = old["shape"][0]  # never shrunk: later views stay readable
        view = _view_shape(name, h, w)
        dtype = np.dtype(_ROWS[name]["dtype"])
        arrays[name] = a = _Array(name, folder, view, dtype,
                                  Blosc(_CNAME, _CLEVEL, zarray["compressor"]["shuffle"], 0))
        if a.nbytes > _BLOSC_MAX_BYTES:
            raise ValueError(f"store='zarr': a view of {name} is {a.nbytes} bytes, over Blosc's "
                             f"{_BLOSC_MAX_BYTES} a chunk: use store='files' (or a smaller size)")
        docs[f"{name}/.zarray"], docs[f"{name}/.zattrs"] = zarray, zattrs
    # arrays of other outputs (an earlier run's) stay listed in the consolidated metadata
    for entry in sorted(os.listdir(root)):
        if entry not in arrays and os.path.isdir(os.path.join(root, entry)):
            for meta in (".zarray", ".zattrs"):
                doc = _read_json(os.path.join(root, entry, meta))
                if isinstance(doc, dict):
                    docs[f"{entry}/{meta}"] = doc
    group = {".zgroup": {"zarr_format": 2}, ".zattrs": _GROUP_ATTRS}
    consolidated = {".zmetadata": {"metadata": {**group, **docs}, "zarr_consolidated_format": 1}}
    for name in names:
        os.makedirs(arrays[name].folder, exist_ok=True)
    for key, doc in {**{k: docs[k] for k in docs if k.split("/")[0] in arrays}, **group,
                     **consolidated}.items():
        path = os.path.join(root, *key.split("/"))
        data = _dumps(doc)
        try:
            with open(path, "rb") as f:
                if f.read() == data:
                    continue
        except OSError:
            pass
        _atomic_write(path, data)
    return arrays


def _remove_stale_metadata(root: str) -> None:
    """The group's metadata temporaries a killed run left (``..zgroup.{pid}-{id}.tmp``, ...)."""
    for name in os.listdir(root):
        if name.startswith("..z") and name.endswith(".tmp"):
            try:
                os.remove(os.path.join(root, name))
            except FileNotFoundError:
                pass


def _remove_stale_chunks(arrays: Iterable[_Array], views: range) -> None:
    """The temporaries a killed run left in these arrays' folders: their metadata's
    (``..zarray.{pid}-{id}.tmp``) and these views' chunks' (``.12.0.0.{pid}-{id}.tmp``); other
    views' are not touched (another shard of the job may be writing them)."""
    for a in arrays:
        try:
            names = os.listdir(a.folder)
        except FileNotFoundError:
            continue
        for name in names:
            if name.startswith(".") and name.endswith(".tmp"):
                head = name[1:].split(".", 1)[0]
                if name.startswith("..z") or (head.isdigit() and int(head) in views):
                    try:
                        os.remove(os.path.join(a.folder, name))
                    except FileNotFoundError:
                        pass


def _chunk_intact(a: _Array, k: int) -> bool:
    """Whether view ``k``'s chunk of ``a`` is there, of the size its Blosc header gives, for a
    view's bytes, and decompresses (in a writer thread: the GIL released)."""
    try:
        with open(a.chunk(k), "rb") as f:
            data = f.read()
    except OSError:
        return False
    if len(data) < _BLOSC_HEADER:
        return False
    nbytes, _, cbytes = struct.unpack_from("<III", data, 4)
    if cbytes != len(data) or nbytes != a.nbytes:
        return False
    try:
        a.codec.decode(data, out=np.empty(a.shape, a.dtype))
    except (RuntimeError, ValueError, MemoryError):
        return False
    return True


def _write_view(arrays: dict[str, _Array], frame: Any, k: int) -> None:
    """Encodes (GIL released) and writes, atomically, each output's chunk of view ``k``."""
    for a in arrays.values():
        arr = np.ascontiguousarray(getattr(frame, a.name))
        if arr.shape != a.shape or arr.dtype != a.dtype:  # the table and the render disagree
            raise ValueError(f"{a.name}: the frame's {arr.shape} {arr.dtype}, not {a.shape} {a.dtype}")
        _atomic_write(a.chunk(k), a.codec.encode(arr))


def entry(name: str, k: int) -> str:
    """Where view ``k`` of output ``name`` is, relative to the dataset directory.

    Returns
    -------
    str
        ``views.zarr/{name}[{k}]``.
    """
    return f"{GROUP}/{name}[{k}]"


def write_views(scene: Any, cams: Sequence[Any], directory: str, outputs: Sequence[str],
                renderer: Any, n_writers: int, progress: bool, resume: bool, first: int,
                cameras_json: bool, formats: dict[str, str], options: dict[str, Any]) -> Any:
    """``write_dataset`` for store="zarr" (its arguments checked there).

    Returns
    -------
    WrittenViews
        As ``write_dataset``'s.
    """
    _blosc()
    if formats:
        raise ValueError("formats: for store='files' only (store='zarr' keeps each output in its "
                         "own dtype, Blosc-compressed)")
    wanted = set(_check_output_names(outputs))
    names = tuple(n for n in _core.OUTPUTS if n in wanted)
    root = os.path.join(directory, GROUP)
    arrays = prepare(root, first + len(cams), renderer.height, renderer.width, names)
    views = range(first, first + len(cams))
    stems = [f"{k:06d}" for k in views]
    _remove_stale_temporaries(directory, stems)  # cameras.json's
    _remove_stale_chunks(arrays.values(), views)

    def files(k: int) -> dict[str, str]:
        return {n: os.path.join(directory, entry(n, k)) for n in names}

    def complete(k: int) -> bool:
        return all(_chunk_intact(a, k) for a in arrays.values())

    def write(frame: Any, k: int) -> dict[str, str]:
        _write_view(arrays, frame, k)
        return files(k)

    done: dict[int, dict[str, str]] = {}
    todo: list[int] = []
    bar = None
    try:
        with _interrupt_between_views() as check, \
                concurrent.futures.ThreadPoolExecutor(n_writers, "softrast-writer") as pool:
            found = pool.map(complete, views) if resume else [False] * len(views)
            for k, ok in zip(views, found):
                check()
                if ok:
                    done[k] = files(k)
                else:
                    todo.append(k)
            skipped = len(done)
            start = time.perf_counter()
            bar = _progress_bar(len(cams), skipped) if progress else None
            frames = renderer.render_many(scene, [cams[k - first] for k in todo], outputs=names,
                                          **options)
            _write_frames(pool, frames, todo, write, done, bar, n_writers, check)
    finally:
        if bar is not None:
            bar.close()
    seconds = time.perf_counter() - start if todo else 0.0
    paths = WrittenViews((done[k] for k in views), rendered=len(todo), skipped=skipped,
                         seconds=seconds)
    if cameras_json:
        _write_cameras_json(directory, cams, stems, paths)
    return paths


def prepare_job(job: Any) -> None:
    """``render_dataset``: each mesh's arrays made once, for all the job's views.

    Made before the shards write their (disjoint) views into them.

    Parameters
    ----------
    job : DatasetJob

    Raises
    ------
    ValueError
        Unless every camera has one image size.
    """
    sizes = {(c.width, c.height) for c in job.cameras}
    if len(sizes) != 1 or None in next(iter(sizes)):
        raise ValueError(f"cameras: all must have one image size, got {sorted(sizes, key=str)}")
    (w, h), = sizes
    wanted = set(_check_output_names(job.outputs))
    names = tuple(n for n in _core.OUTPUTS if n in wanted)
    for m in range(len(job.meshes)):
        os.makedirs(job.directory(m), exist_ok=True)
        prepare(os.path.join(job.directory(m), GROUP), len(job.cameras), h, w, names)
