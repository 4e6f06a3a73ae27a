"""Datasets: many views of a scene rendered and written to a directory, with the cameras in
``cameras.json`` (``write_dataset``, ``load_cameras``, ``DatasetJob``, ``render_dataset``).

``write_dataset`` renders with ``Renderer.render_many`` while writer threads encode; files are
written atomically and ``resume`` skips the views already written. The stores (files, zarr),
``cameras.json``'s fields and the sharded runs are in docs/file_formats.md, "Datasets".
"""
from __future__ import annotations

import concurrent.futures
import os
import time
from dataclasses import dataclass, field
from typing import Any, Iterable, Sequence

from ._dataset_writing import (WrittenViews, _interrupt_between_views, _intact, _progress_bar,
                               _remove_stale_temporaries, _write_frames)
from ._zarr_store import prepare_job, write_views
from .camera import Camera
from .cameras_json import _in_output_order, _write_cameras_json, camera_record, load_cameras
from .files.load import load_mesh
from .frame import Frame, _default_format
from .render import Renderer
from .scene import Scene

__all__ = ["write_dataset", "load_cameras", "camera_record", "DatasetJob", "render_dataset",
           "WrittenViews"]


def write_dataset(scene: Scene, cameras: Sequence[Camera], directory: str | os.PathLike[str],
                  outputs: Sequence[str] = ("color", "depth", "instance_id"),
                  formats: dict[str, str] | None = None, renderer: Renderer | None = None,
                  writers: int | None = None, progress: bool = False, resume: bool = True,
                  first: int = 0, cameras_json: bool = True, store: str = "files",
                  **options: Any) -> WrittenViews:
    """Render ``scene`` from every camera and write each frame as ``Frame.save`` does, plus ``cameras.json``.

    Files are ``{stem}_{output}.{ext}``, stems 000000, 000001, ...; docs/file_formats.md,
    "Datasets", has the layouts.

    Parameters
    ----------
    scene : Scene
        What is drawn.
    cameras : sequence of Camera
        Posed cameras, each with its image size (all the same size: one renderer).
    directory : str or os.PathLike
        An existing directory.
    outputs : sequence of str, optional
        Default ("color", "depth", "instance_id").
    formats : dict of str to str, optional
        {output: format} as ``Frame.save`` takes (store "files" only).
    renderer : Renderer, optional
        The renderer to use (default: a new one, all cores, for the cameras' size).
    writers : int, optional
        Encoding threads (default: the renderer's thread count); encoding overlaps rendering, at
        most 2 frames per writer wait to be written.
    progress : bool, optional
        A tqdm bar over all the views, starting at the skipped ones (named in it); its rate
        counts only the views rendered.
    resume : bool, optional
        Skip the views whose files all exist and are intact (default True: a rerun after an
        interruption renders only what is missing; files are written atomically, so none is
        partial; the hidden temporary files a killed run can leave are removed). Each file found
        is decoded (by the writer threads) and must hold the output save writes, at the cameras'
        size; a view with a truncated, empty or corrupt file (as far as its decoder or the .npy
        header reveals it: PNG chunks carry checksums, compressed data mostly fails to inflate, but
        flipped bits in raw .npy data or uncompressed pixels go unseen) is rendered again.
    first : int, optional
        The index of the first camera's view (its stem); for a shard of a larger job.
    cameras_json : bool, optional
        Write cameras.json (False for a shard: ``render_dataset`` writes it whole).
    store : str, optional
        "files" (default: each output of each view a file, as above) or "zarr": each output one
        chunked, Blosc-compressed array, a view a chunk, in ``directory/views.zarr`` (zarr format
        2; needs ``pip install softrast[zarr]``; ``formats`` does not apply); each view's
        {output: path} is then ``directory/views.zarr/{output}[{view}]`` (docs/file_formats.md,
        "zarr", has the layout). Atomic chunks and resume as for files.
    **options
        Passed to ``render`` (shading=, cull=, background=, ...).

    Returns
    -------
    WrittenViews
        Each frame's {output: path}, in ``softrast.OUTPUTS`` order (as ``files`` in cameras.json:
        a resumed run writes the same cameras.json, byte for byte, as an uninterrupted one), a
        list whose ``rendered``, ``skipped`` and ``seconds`` say how many views this call
        rendered, how many ``resume`` skipped, and the time the rendered ones took.

    Raises
    ------
    TypeError, ValueError
        For a bad argument: no cameras, a camera without an image size, cameras of different
        sizes, an unknown store, ...
    FileNotFoundError
        If ``directory`` does not exist.
    """
    _check_store(store)
    cams = list(cameras)
    if not cams:
        raise ValueError("cameras: at least one camera is needed")
    for k, cam in enumerate(cams):
        if not isinstance(cam, Camera):
            raise TypeError(f"cameras[{k}] must be a softrast.Camera, got {type(cam).__name__}")
        if cam.width is None or cam.height is None:
            raise ValueError(f"cameras[{k}] has no image size: give each camera width and height")
    sizes = {(c.width, c.height) for c in cams}
    if len(sizes) != 1:
        raise ValueError(f"cameras: all must have one image size (one renderer), got {sorted(sizes)}")
    (w, h), = sizes
    directory = os.fspath(directory)
    if not os.path.isdir(directory):
        raise FileNotFoundError(f"directory does not exist: {directory}")
    names = (outputs,) if isinstance(outputs, str) else tuple(outputs)
    r = renderer if renderer is not None else Renderer(w, h)
    if (r.width, r.height) != (w, h):
        raise ValueError(f"renderer is {r.width}x{r.height}, the cameras {w}x{h}")
    n_writers = r.threads if writers is None else int(writers)
    if n_writers < 1:
        raise ValueError(f"writers must be >= 1, got {writers!r}")
    formats = dict(formats or {})
    if store == "zarr":  # one array per output in directory/views.zarr (_zarr_store.py)
        return write_views(scene, cams, directory, names, r, n_writers, progress, resume, first,
                           cameras_json, formats, options)
    stems = [f"{first + k:06d}" for k in range(len(cams))]

    def expected(stem: str) -> dict[str, str]:
        # the files a view's save writes (ids fall back to .tif only when they do not fit in png16)
        out = {}
        for name in names:
            fmt = formats.get(name) or _default_format(name)
            ext = "png" if fmt in ("png16", "png16mm") else fmt
            out[name] = os.path.join(directory, f"{stem}_{name}.{ext}")
        return out

    def complete(stem: str) -> dict[str, str] | None:
        # the view's files, if each one is there and decodes to the output save wrote (not
        # truncated, empty or corrupt, of the cameras' size): else None, to render it again
        paths = expected(stem)
        for name, path in list(paths.items()):
            if not os.path.exists(path):
                alt = os.path.splitext(path)[0] + ".tif"  # large ids
                if name in ("triangle_id", "instance_id") and os.path.exists(alt):
                    paths[name] = path = alt
                else:
                    return None
            if not _intact(path, name, h, w):
                return None
        return paths

    _remove_stale_temporaries(directory, stems)
    done: dict[int, dict[str, str]] = {}
    todo = []
    bar = None
    skipped = 0
    try:
        with _interrupt_between_views() as check, \
                concurrent.futures.ThreadPoolExecutor(n_writers, "softrast-writer") as pool:
            # resume: the writers decode the files already there (OpenImageIO releases the GIL)
            found = pool.map(complete, stems) if resume else [None] * len(stems)
            for k, paths in enumerate(found):
                check()
                if paths is not None:
                    done[k] = paths
                else:
                    todo.append(k)
            skipped = len(done)
            start = time.perf_counter()
            bar = _progress_bar(len(cams), skipped) if progress else None
            views: Iterable[Frame] = r.render_many(scene, [cams[k] for k in todo], outputs=names,
                                                   **options)
            _write_frames(pool, views, todo, lambda frame, k: frame.save(directory, stems[k], formats),
                          done, bar, n_writers, check)
    finally:
        if bar is not None:
            bar.close()
    seconds = time.perf_counter() - start if todo else 0.0
    paths = WrittenViews((_in_output_order(done[k]) for k in range(len(cams))), rendered=len(todo),
                         skipped=skipped, seconds=seconds)
    if cameras_json:
        _write_cameras_json(directory, cams, stems, paths)
    return paths


_STORES = ("files", "zarr")


def _check_store(store: Any) -> None:
    if not isinstance(store, str) or store not in _STORES:
        raise ValueError(f"store must be one of {_STORES}, got {store!r:.80}")


@dataclass(frozen=True)
class DatasetJob:
    """A dataset to render: every mesh file from every camera, into ``out_dir/<mesh file stem>/``.

    Each mesh's directory is written as ``write_dataset`` writes one. Picklable: shards of it run
    anywhere.

    Parameters
    ----------
    meshes : sequence of str or os.PathLike
        Mesh file paths (readable where the shards run), with distinct file names.
    cameras : sequence of Camera
        Posed cameras, each with its image size (one size for all).
    outputs : sequence of str, optional
        Output names.
    out_dir : str or os.PathLike, optional
        Where the meshes' directories go (default ".").
    formats : dict of str to str, optional
        {output: format} as ``Frame.save`` takes (store "files" only).
    shard_size : int, optional
        Views per shard (>= 1, default 16; a shard is one mesh x a run of cameras).
    store : str, optional
        "files" or "zarr" (``write_dataset``'s): with "zarr", ``render_dataset`` makes each mesh's
        arrays, for all the cameras, before the shards write their views into them.
    **options
        ``render`` options (shading=, cull=, ...).

    Raises
    ------
    ValueError
        For no mesh or camera, a bad shard size or store, formats with "zarr", or two meshes of
        one file name (their directories would clash).
    """

    meshes: tuple
    cameras: tuple
    outputs: tuple = ("color", "depth", "instance_id")
    out_dir: str = "."
    formats: dict = field(default_factory=dict)
    shard_size: int = 16
    options: dict = field(default_factory=dict)
    store: str = "files"

    def __init__(self, meshes: Sequence[str | os.PathLike[str]], cameras: Sequence[Camera],
                 outputs: Sequence[str] = ("color", "depth", "instance_id"),
                 out_dir: str | os.PathLike[str] = ".", formats: dict[str, str] | None = None,
                 shard_size: int = 16, store: str = "files", **options: Any) -> None:
        s = object.__setattr__
        s(self, "meshes", tuple(os.fspath(m) for m in meshes))
        s(self, "cameras", tuple(cameras))
        s(self, "outputs", (outputs,) if isinstance(outputs, str) else tuple(outputs))
        s(self, "out_dir", os.fspath(out_dir))
        s(self, "formats", dict(formats or {}))
        s(self, "shard_size", int(shard_size))
        s(self, "options", dict(options))
        _check_store(store)
        s(self, "store", store)
        if store == "zarr" and self.formats:
            raise ValueError("formats: for store='files' only (store='zarr' keeps each output in "
                             "its own dtype, Blosc-compressed)")
        if not self.meshes or not self.cameras:
            raise ValueError("DatasetJob needs at least one mesh and one camera")
        if self.shard_size < 1:
            raise ValueError(f"shard_size must be >= 1, got {shard_size!r}")
        stems = [os.path.splitext(os.path.basename(m))[0] for m in self.meshes]
        if len(set(stems)) != len(stems):
            raise ValueError("meshes: two files have the same name (their directories would clash)")

    def shards(self) -> list[tuple[int, int, int]]:
        """The shards: (mesh index, first camera, end camera) of each.

        Returns
        -------
        list of tuple of int
        """
        return [(m, a, min(a + self.shard_size, len(self.cameras)))
                for m in range(len(self.meshes)) for a in range(0, len(self.cameras), self.shard_size)]

    def directory(self, m: int) -> str:
        """The directory mesh ``m``'s views are written to: ``out_dir/<its file stem>``.

        Parameters
        ----------
        m : int
            The mesh's index.

        Returns
        -------
        str
        """
        return os.path.join(self.out_dir, os.path.splitext(os.path.basename(self.meshes[m]))[0])


def _render_shard(job: DatasetJob, shard: tuple[int, int, int]) -> list[dict[str, str]]:
    """Runs one shard (in whatever process the executor gives it): load, render, write."""
    m, a, b = shard
    scene = Scene()
    scene.add(load_mesh(job.meshes[m]), instance_id=0)
    directory = job.directory(m)
    os.makedirs(directory, exist_ok=True)
    cams = job.cameras[a:b]
    renderer = Renderer(cams[0].width, cams[0].height, threads=1)
    return write_dataset(scene, cams, directory, outputs=job.outputs, formats=job.formats,
                         renderer=renderer, first=a, cameras_json=False, store=job.store,
                         **job.options)


def render_dataset(job: DatasetJob, executor: concurrent.futures.Executor | None = None
                   ) -> list[list[dict[str, str]]]:
    """Run ``job``'s shards on ``executor``, then write each mesh's ``cameras.json``.

    The files are the same, byte for byte, whichever executor runs it (with ``store="zarr"`` too:
    each mesh's arrays are made here, then each shard writes its views' chunks).

    Parameters
    ----------
    job : DatasetJob
        The dataset to render.
    executor : concurrent.futures.Executor, optional
        Any Executor: a ``ProcessPoolExecutor``, or a Dask cluster's ``client.get_executor()``;
        None: one process, here.

    Returns
    -------
    list of list of dict
        Per mesh, each view's {output: path}.
    """
    os.makedirs(job.out_dir, exist_ok=True)
    if job.store == "zarr":
        prepare_job(job)
    shards = job.shards()
    if executor is None:
        results = [_render_shard(job, s) for s in shards]
    else:
        futures = [executor.submit(_render_shard, job, s) for s in shards]
        results = [f.result() for f in futures]
    per_mesh: list[list[dict[str, str]]] = [[] for _ in job.meshes]
    for (m, _, _), paths in zip(shards, results):
        per_mesh[m].extend(paths)
    stems = [f"{k:06d}" for k in range(len(job.cameras))]
    for m in range(len(job.meshes)):
        _write_cameras_json(job.directory(m), job.cameras, stems, per_mesh[m])
    return per_mesh
