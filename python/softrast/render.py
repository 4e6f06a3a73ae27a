"""Renderer and Frame: the public face of the C++ pipeline (``softrast._core``)."""
from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Any, Sequence

import numpy as np
import numpy.typing as npt

from . import _core
from ._checks import flag, image_side, integer
from .camera import Camera
from .distortion import render_distorted
from .draws import _check_mip_budgets, _draws, _lights, _primitive_draws, _wireframe_draws
from .frame import _OUTPUT_BYTES, Frame, _out_arrays, _output_names
from .limits import check_budget
from .options import SHADING, RenderOptions, _antialiasing, resolve
from .scene import Scene

__all__ = ["Frame", "RenderOptions", "Renderer"]

# The option names and kinds the CLI and report read (RenderOptions checks them).
_SHADING = SHADING


def sample_positions(msaa: int = 1, ssaa: int = 1) -> npt.NDArray[np.float64]:
    """Where an anti-aliasing mode samples each pixel.

    msaa: the Direct3D / Vulkan standard positions (multiples of 1/16 px); ssaa=k: a k x k grid
    at ((i + 1/2) / k, (j + 1/2) / k), row by row, rounded to the rasterizer's 1/256 px. The
    representative sample of a pixel (``Renderer.render``) is its covered sample nearest the
    centre (0.5, 0.5), ties to the lower index.

    Parameters
    ----------
    msaa : int, optional
        1 (default), 2, 4, 8 or 16.
    ssaa : int, optional
        In [1, 8] (default 1); not with msaa > 1.

    Returns
    -------
    ndarray, shape (n, 2), float64
        (x, y) offsets from the pixel's top-left corner in pixels (x right, y down), in sample
        order.

    Raises
    ------
    TypeError, ValueError
        For counts outside those, or both msaa and ssaa.
    """
    msaa, ssaa = _antialiasing(msaa, ssaa)
    return np.array(_core._sample_pattern(msaa, ssaa), dtype=np.float64) / (1 << _core.SUBPIXEL_BITS)


_END = object()  # render_many's end of the cameras (None is a camera to refuse, not the end)


class Renderer:
    """An offscreen renderer of a fixed image size (like pyrender's OffscreenRenderer).

    The GIL is released while rendering, so Python threads may render concurrently (calls on one
    Renderer are serialised; use one Renderer per thread for parallelism).

    Picklable (as its arguments: a new Renderer is built where it is unpickled), like Scene,
    Mesh, cameras, lights and materials, before or after any render.

    Fork-safe: ``os.fork()`` (and so ``multiprocessing``'s "fork" start method) waits for renders
    in progress on other threads to end; in the child an inherited Renderer starts its own worker
    threads at its first render, renders the same bits and can be destroyed. A daemon thread
    still rendering when the interpreter exits is left asleep (the process exits normally).

    Parameters
    ----------
    width, height : int
        Image size in pixels, each in [1, softrast.MAX_IMAGE_SIDE].
    threads : int, optional
        Worker threads, the calling thread included, in [0, softrast.MAX_THREADS] (0, the
        default = one per core, at most MAX_THREADS). The images are bit-identical for any count.
    simd : bool, optional
        Use the widest instruction set the CPU has for the per-pixel kernels (AVX2 where
        available; see ``isa``). False forces the generic x86-64 kernels. The images are
        bit-identical either way.

    Raises
    ------
    ValueError
        For a size or thread count outside those ranges, or a non-bool ``simd``.
    RuntimeError
        Naming ``threads``, when the system refuses to start a worker thread (``ulimit -u``,
        ``ulimit -v``, memory); the workers already started are stopped first, so none is left
        behind.
    """

    def __init__(self, width: int, height: int, threads: int = 0, simd: bool = True) -> None:
        w = image_side(width, "width")
        h = image_side(height, "height")
        threads = integer(threads, "threads")  # bool and float are TypeErrors
        if threads < 0:
            raise ValueError(f"threads must be an int >= 0, got {threads!r}")
        if threads > _core.MAX_THREADS:
            raise ValueError(f"threads must be in [0, {_core.MAX_THREADS}] (0 = one per core), got {threads}")
        if not isinstance(simd, (bool, np.bool_)):
            raise ValueError(f"simd must be True or False, got {simd!r}")
        self._core = _core.Renderer(w, h, int(threads), bool(simd))
        self._size = (w, h)
        self._args = (w, h, int(threads), bool(simd))

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        """Pickles as its arguments: unpickling (in another process) builds a new Renderer, with
        its own threads and scratch memory (threads=0 is again one per core there)."""
        return (Renderer, self._args)

    def _map_renderer(self, n: int) -> Renderer:
        """An n x n Renderer with this one's threads and instruction sets (for shadow maps)."""
        return Renderer(n, n, threads=self._args[2], simd=self._args[3])

    @property
    def width(self) -> int:
        """Image width in pixels."""
        return self._core.width

    @property
    def height(self) -> int:
        """Image height in pixels."""
        return self._core.height

    @property
    def threads(self) -> int:
        """Worker threads in use, the calling thread included."""
        return self._core.threads

    @property
    def isa(self) -> str:
        """Instruction set of the per-pixel kernels in use: "avx2" or "generic"."""
        return self._core.isa

    def render(self, scene: Scene, camera: Camera, outputs: str | Sequence[str] = ("color", "depth"),
               options: RenderOptions | None = None, *, out: Frame | dict[str, np.ndarray] | None = None,
               **overrides: Any) -> Frame:
        """Render ``scene`` seen by ``camera``; only ``outputs`` are allocated and written.

        Parameters
        ----------
        scene : Scene
            What is drawn: meshes, lines and points, lights.
        camera : Camera
            Its pose and projection; a camera with a fixed width and height must match the
            renderer's.
        outputs : str or sequence of str
            Any of ``softrast.OUTPUTS`` (see Frame, or ``softrast.OUTPUT_TABLE``, for shapes,
            dtypes, units and background values). Default ("color", "depth").
        options : RenderOptions, optional
            How to draw (shading, anti-aliasing, culling, shadows, ...): ``RenderOptions``
            documents every field. None: the defaults.
        out : Frame or dict of str to ndarray, optional
            A Frame from an earlier render, or a dict of arrays, to render into in place (no
            allocation). Each array must have exactly its output's dtype and shape, be
            C-contiguous and writeable. Requested outputs missing from ``out`` are allocated.
            Without ``out`` every render returns new arrays and never touches earlier ones. A
            render's own arrays start on a 64-byte cache line; arrays of your own render
            fastest if they do too (NumPy aligns only to 16 bytes: reusing a Frame is best).
        **overrides
            Any field of ``RenderOptions`` by name, replacing ``options``' value:
            ``render(scene, cam, msaa=4)``.

        Returns
        -------
        Frame
            The outputs as NumPy arrays, views of memory the Frame owns.

        Raises
        ------
        TypeError, ValueError
            For a bad argument or option, naming it.
        """
        if not isinstance(scene, Scene):
            raise TypeError(f"scene must be a softrast.Scene, got {type(scene).__name__}")
        if not isinstance(camera, Camera):
            raise TypeError(f"camera must be a softrast camera, got {type(camera).__name__}")
        w, h = self._size
        for name, size, ours in (("width", camera.width, w), ("height", camera.height, h)):
            if size is not None and size != ours:
                raise ValueError(f"camera {name} {size} differs from the renderer's {ours}")
        names = _output_names(outputs)
        o = resolve(options, overrides)
        if getattr(camera, "_dist", None) is not None:  # an IntrinsicsCamera with lens distortion
            if o.msaa > 1 or o.ssaa > 1:
                raise ValueError("msaa / ssaa: anti-aliasing a camera with lens distortion is not "
                                 "supported (its oversample= already averages colour bilinearly)")
            if scene.primitives or o.wireframe:
                raise ValueError("scene: lines and points (and wireframe) are not supported with "
                                 "a camera with lens distortion")
            if o.alpha_threshold is not None:
                raise ValueError("alpha_threshold: not supported with a camera with lens distortion "
                                 "(its depth and ids are ray cast against opaque surfaces only)")
            return render_distorted(self, scene, camera, names, o, out)
        out_arrays = _out_arrays(out, names)
        new = names if not out_arrays else [n for n in names if n not in out_arrays]  # out= reused
        if new:
            check_budget(w * h * sum(_OUTPUT_BYTES[n] for n in new), f"outputs {tuple(new)} at {w}x{h}")
        _check_mip_budgets(scene, o.texture_filter)

        draws = _draws(scene)
        primitives = _primitive_draws(scene)
        if o.wireframe:
            primitives = primitives + _wireframe_draws(scene, o.line_color, float(np.float32(o.line_width)))
        view, proj = camera._render_matrices(w, h)
        # Every option is checked once (RenderOptions); the core reads them by name
        # (_core.RENDER_OPTIONS).
        buffers = self._core.render(draws, {
            "view": view, "proj": proj, "orthographic": camera.orthographic, "near": camera.near,
            "far": camera.far, "outputs": names, "cull": o.cull,
            "cull_double_sided": o.cull_double_sided, "normal_kind": o.normal_kind,
            "shading": o.shading,
            "shading_path": o.shading_path, "background": o.background, "ambient": o.ambient,
            "out": out_arrays,
            "lights": _lights(scene, view, o.shadows, self._map_renderer),
            "ambient_light": scene.ambient_light,
            "frequency": o.frequency, "srgb": o.srgb, "texture_filter": o.texture_filter,
            "normal_rotation": None if o.normal_space == "world" else
            tuple(map(tuple, camera.pose[:3, :3].T.tolist())),
            "raster": o.raster, "msaa": o.msaa, "ssaa": o.ssaa, "primitives": primitives,
            "line_algorithm": o.line_algorithm, "alpha_threshold": o.alpha_threshold})
        return Frame(buffers)

    def render_many(self, scene: Scene, cameras: Iterable[Camera], outputs: str | Sequence[str] = ("color", "depth"),
                    progress: bool = False, callback: Callable[[int, Frame], Any] | None = None,
                    workers: int | None = None, **options: Any) -> Iterator[Frame]:
        """Render ``scene`` from each of ``cameras`` in turn: a generator of Frames, in the cameras' order.

        Each Frame equals, byte for byte, ``render(scene, camera, outputs, **options)`` in a loop.
        Views render concurrently, each on its own single-threaded renderer (``workers`` of them),
        with the GIL released, while the caller consumes earlier frames: small frames, whose own
        passes cannot keep every core busy, then use them all. At most 2 x workers frames are in
        flight, so 10,000 views never sit in memory. The scene is uploaded once (its meshes' arrays
        are shared, its draw records cached).

        Parameters
        ----------
        scene : Scene
            What is drawn, uploaded once.
        cameras : iterable of Camera
            Any iterable (a generator of posed cameras, say), read as needed.
        outputs : str or sequence of str, optional
            As for ``render``.
        progress : bool, optional
            Show a tqdm progress bar (total = len(cameras) when it has one).
        callback : callable, optional
            Called as callback(i, frame) for each frame, before it is yielded.
        workers : int, optional
            In [1, softrast.MAX_THREADS]; default: this renderer's thread count.
        **options
            Any option of ``render`` but ``out``.

        Yields
        ------
        Frame

        Raises
        ------
        TypeError, ValueError
            For ``out=``, a bad scene, callback, ``workers`` or ``progress``; TypeError for a
            camera that is not a softrast Camera (raised when it is reached).
        """
        if "out" in options:
            raise ValueError("render_many: out= is not supported (each view gets new arrays)")
        if not isinstance(scene, Scene):
            raise TypeError(f"scene must be a softrast.Scene, got {type(scene).__name__}")
        if callback is not None and not callable(callback):
            raise TypeError(f"callback must be callable or None, got {type(callback).__name__}")
        n_workers = self.threads if workers is None else integer(workers, "workers")
        if not 1 <= n_workers <= _core.MAX_THREADS:
            raise ValueError(f"workers must be in [1, {_core.MAX_THREADS}], got {n_workers}")
        flag(progress, "progress")
        return self._render_many(scene, cameras, outputs, bool(progress), callback, n_workers,
                                 self._args[3], options)

    def _render_many(self, scene, cameras, outputs, progress, callback, n_workers, simd, options):
        import concurrent.futures
        import queue

        if n_workers == 1:
            render = lambda cam: self.render(scene, cam, outputs, **options)  # noqa: E731
        else:
            # Single-threaded renderers kept on this one for later calls (their threads and
            # scratch memory are made once); each view borrows one.
            spares = self.__dict__.setdefault("_view_renderers", [])
            while len(spares) < n_workers:
                spares.append(Renderer(*self._size, threads=1, simd=simd))
            idle: queue.SimpleQueue = queue.SimpleQueue()
            for r in spares[:n_workers]:
                idle.put(r)

            def render(cam):
                r = idle.get()
                try:
                    return r.render(scene, cam, outputs, **options)
                finally:
                    idle.put(r)
        total = len(cameras) if hasattr(cameras, "__len__") else None
        bar = None
        if progress:
            from tqdm.auto import tqdm
            bar = tqdm(total=total, unit="view", desc="render_many")
        try:
            with concurrent.futures.ThreadPoolExecutor(n_workers, "softrast-view") as pool:
                pending: list = []
                views = iter(cameras)
                i = 0
                exhausted = False
                while True:
                    while not exhausted and len(pending) < 2 * n_workers:
                        cam = next(views, _END)  # not None: a None camera is an error below
                        if cam is _END:
                            exhausted = True
                            break
                        if not isinstance(cam, Camera):
                            raise TypeError(f"cameras[{i + len(pending)}] must be a softrast.Camera, "
                                            f"got {type(cam).__name__}")
                        pending.append(pool.submit(render, cam))
                    if not pending:
                        break
                    frame = pending.pop(0).result()
                    if callback is not None:
                        callback(i, frame)
                    if bar is not None:
                        bar.update(1)
                    yield frame
                    i += 1
        finally:
            if bar is not None:
                bar.close()

    def __repr__(self) -> str:
        return f"Renderer({self.width}x{self.height}, threads={self.threads}, isa={self.isa!r})"
