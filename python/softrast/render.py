"""Renderer and Frame: the public face of the C++ pipeline (``softrast._core``)."""
from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Any, Sequence

import numpy as np
import numpy.typing as npt

from . import _core
from ._checks import choice, image_side, integer, real, unit_rgb
from .camera import Camera
from .distortion import render_distorted
from .draws import _check_mip_budgets, _draws, _lights, _primitive_draws, _wireframe_draws
from .frame import _OUTPUT_BYTES, Frame, _out_arrays, _output_names
from .light import shadow_method
from .limits import check_budget
from .scene import Scene
from .texture import check_filter

__all__ = ["Frame", "Renderer"]

_CULL = _core.CULL_MODES
_NORMAL_KINDS = _core.NORMAL_KINDS  # interpolated, shading
_SHADING_PATHS = _core.SHADING_PATHS
_RASTER = _core.RASTER_ALGORITHMS
_LINE_ALGORITHMS = _core.LINE_ALGORITHMS
_FREQUENCIES = _core.FREQUENCIES
# render(shading=): "auto" (each material's own model), every reflectance model of a material
# (python/softrast/material.py, MODELS) and the debug views ("uv"). The core picks its kernels
# from them and the scene (cpp/renderer.cpp, the plan).
_SHADING = _core.SHADING_MODELS
_NORMAL_SPACES = ("world", "camera")


MSAA_COUNTS = (1, 2, 4, 8, 16)


def _antialiasing(msaa: Any, ssaa: Any) -> tuple[int, int]:
    """Checked msaa and ssaa counts (render's docstring)."""
    for name, value in (("msaa", msaa), ("ssaa", ssaa)):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
            raise TypeError(f"{name} must be an int, got {value!r:.80}")
    if int(msaa) not in MSAA_COUNTS:
        raise ValueError(f"msaa must be one of {MSAA_COUNTS}, got {msaa!r}")
    if not 1 <= int(ssaa) <= 8:
        raise ValueError(f"ssaa must be in [1, 8], got {ssaa!r}")
    if msaa > 1 and ssaa > 1:
        raise ValueError(f"msaa and ssaa: use one of them, got msaa={msaa}, ssaa={ssaa}")
    return int(msaa), int(ssaa)


def sample_positions(msaa: int = 1, ssaa: int = 1) -> npt.NDArray[np.float64]:
    """Where an anti-aliasing mode samples each pixel: an (n, 2) float64 array of (x, y) offsets
    from the pixel's top-left corner in pixels (x right, y down), in sample order. msaa: the
    Direct3D / Vulkan standard positions (multiples of 1/16 px); ssaa=k: a k x k grid at
    ((i + 1/2) / k, (j + 1/2) / k), row by row, rounded to the rasterizer's 1/256 px. The
    representative sample of a pixel (``Renderer.render``) is its covered sample nearest the
    centre (0.5, 0.5), ties to the lower index."""
    msaa, ssaa = _antialiasing(msaa, ssaa)
    return np.array(_core._sample_pattern(msaa, ssaa), dtype=np.float64) / (1 << _core.SUBPIXEL_BITS)


_END = object()  # render_many's end of the cameras (None is a camera to refuse, not the end)


class Renderer:
    """An offscreen renderer of a fixed image size (like pyrender's OffscreenRenderer).

    Parameters
    ----------
    width, height : image size in pixels, each in [1, softrast.MAX_IMAGE_SIDE].
    threads : worker threads, the calling thread included, in [0, softrast.MAX_THREADS] (0 = one
        per core, at most MAX_THREADS). The images are bit-identical for any count. Raises
        ``ValueError`` for a count outside that range and ``RuntimeError`` (naming ``threads``)
        when the system refuses to start a worker thread (``ulimit -u``, ``ulimit -v``, memory);
        the workers already started are stopped first, so none is left behind.
    simd : use the widest instruction set the CPU has for the per-pixel kernels (AVX2 where
        available; see ``isa``). False forces the generic x86-64 kernels. The images are
        bit-identical either way.

    The GIL is released while rendering, so Python threads may render concurrently (calls on one
    Renderer are serialised; use one Renderer per thread for parallelism).

    Picklable (as its arguments: a new Renderer is built where it is unpickled), like Scene,
    Mesh, cameras, lights and materials, before or after any render.

    Fork-safe: ``os.fork()`` (and so ``multiprocessing``'s "fork" start method) waits for renders
    in progress on other threads to end; in the child an inherited Renderer starts its own worker
    threads at its first render, renders the same bits and can be destroyed. A daemon thread
    still rendering when the interpreter exits is left asleep (the process exits normally).
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
        return self._core.width

    @property
    def height(self) -> int:
        return self._core.height

    @property
    def threads(self) -> int:
        return self._core.threads

    @property
    def isa(self) -> str:
        """Instruction set of the per-pixel kernels in use: "avx2" or "generic"."""
        return self._core.isa

    def render(
        self,
        scene: Scene,
        camera: Camera,
        outputs: str | Sequence[str] = ("color", "depth"),
        cull: str = "back",
        shading: str = "auto",
        background: Sequence[float] = (0.0, 0.0, 0.0),
        ambient: float = 0.25,
        out: Frame | dict[str, np.ndarray] | None = None,
        shading_path: str = "auto",
        frequency: str = "pixel",
        srgb: bool = True,
        texture_filter: str | None = None,
        normal_space: str = "world",
        raster: str = "edge",
        msaa: int = 1,
        ssaa: int = 1,
        line_algorithm: str = "bresenham",
        wireframe: bool = False,
        line_color: Sequence[float] = (0.0, 0.0, 0.0),
        line_width: float = 1.0,
        cull_double_sided: bool = False,
        normal_kind: str = "interpolated",
        shadows: bool | str | None = None,
        alpha_threshold: float | None = None,
    ) -> Frame:
        """Render ``scene`` seen by ``camera``; only ``outputs`` are allocated and written.

        outputs : any of softrast.OUTPUTS (see Frame, or softrast.OUTPUT_TABLE, for shapes,
                  dtypes, units and background values).
        cull : "back" (default), "front" or "none". Front faces are counter-clockwise in the
               image as OpenGL defines it; a mirroring pose flips the winding, and the test.
               Instances whose material is double-sided (``Material(double_sided=True)``,
               glTF's ``doubleSided``) are never culled, as glTF and pyrender say, unless
               ``cull_double_sided=True``; meshes without a material are culled.
        cull_double_sided : apply ``cull`` to double-sided materials too (default False).
        shading : "auto" (default) — each instance's material's own model (its ``model``;
                  "blinn_phong" for a material without one, "lambert" for a mesh without a
                  material); or one model for everything: "unlit" (the base colour), "lambert",
                  "phong", "blinn_phong", "pbr" (glTF metallic-roughness as pyrender computes
                  it), "normal" (the world-space unit normal of the visible side as a colour,
                  (n + 1) / 2), "uv" (the mesh's texture coordinates as a colour, (u, v, 0)
                  clamped to [0, 1], perspective-correct; black without uvs) or "depth" (the
                  depth output as a grey, (far - depth) / (far - near) clamped to [0, 1]: white
                  at the near plane, black at the far plane). The formulas are in
                  ``softrast.material``; the lights are the scene's (``softrast.light``), or the
                  headlight in a scene without lights: a directional light along the camera's
                  viewing axis of intensity 1 - ambient plus an ambient light of ``ambient``, so
                  lambert gives base colour * (ambient + (1 - ambient) * max(0, n . l)). The base
                  colour is the mesh's per-vertex colours if it has them, else the instance's
                  colour (its material's base colour).
        frequency : where lighting is evaluated: "pixel" (default; normals interpolated per pixel,
                  Phong shading), "vertex" (Gouraud: at the vertices, colour interpolated) or
                  "face" (flat: once per face, with its face normal, at its centroid).
        srgb : True (default): the ``color`` output is the radiance sRGB-encoded (the exact IEC
               61966-2-1 curve, as pyrender's and glTF viewers' output and cameras' images are);
               False: linear. Either way clamped to [0, 1] and rounded to 8 bits; ``radiance``
               holds the linear, unclamped values.
        texture_filter : None (default: each texture's own filter) or one filter for every
               texture of this render: "nearest", "bilinear", "trilinear" or "anisotropic"
               (``softrast.texture``).
        background : RGB in [0, 1] for pixels nothing covers, written to ``color`` as given
               (times 255, not encoded).
        out : a Frame from an earlier render, or a dict of arrays, to render into in place
              (no allocation). Each array must have exactly its output's dtype and shape, be
              C-contiguous and writeable. Requested outputs missing from ``out`` are allocated.
              Without ``out`` every render returns new arrays and never touches earlier ones.
              A render's own arrays start on a 64-byte cache line; arrays of your own render
              fastest if they do too (NumPy aligns only to 16 bytes: reusing a Frame is best).
        shading_path : when fragments are shaded: "forward" (as they pass the depth test),
              "deferred" (once per visible pixel, after the depth test) or "auto" (default:
              per 64x64 tile, forward unless the tile's triangles cover it over 1.5 times).
              The same bits either way; only speed differs (forward wins without overdraw).
              A render that asks for ``coverage`` (a diagnostic) is always deferred.
        normal_space : the ``normal`` output's axes: "world" (default) or "camera": the axes of
              ``camera.pose`` (OpenGL's x right, y up, z toward the viewer; OpenCV's x right,
              y down, z forward for an ``IntrinsicsCamera(convention="opencv")``), as
              ``camera.unproject(..., space="camera")`` gives points.
        normal_kind : what the ``normal`` output holds: "interpolated" (default) — the
              interpolated vertex normal (the face normal of a mesh without normals), unit,
              of the visible side, as a G-buffer stores it: no normal or bump map, and
              interpolated at the pixel's own point of the surface (the exact weights, as
              ``barycentric``); or
              "shading" — the normal the lighting uses: that normal perturbed by the
              material's ``normal_texture`` (or ``bump_texture``) at the pixel frequency,
              exactly as the shading perturbs it (``shading="normal"`` shows it as a
              colour), with the weights shading interpolated with: the exact ones where the
              draw's model reads positions or uvs (lights, textures), else the snapped
              triangle's, whose point lies within 1/724 px of the pixel's. Meshes without such maps, the vertex and face frequencies, and the
              "uv" and "depth" views give the interpolated normal either way.
        shadows : None (default: each light's own ``shadows``), False (no light casts shadows),
              True / "exact" (every light casts exact shadows) or "map" (shadow maps):
              softrast.light states the rules. Shadows darken only the colour and radiance
              outputs.
        alpha_threshold : None (default) or a number in [0, 1]. Where blended materials
              (``alpha_mode="blend"``) lie in front of the nearest opaque surface, ``color``,
              ``radiance`` and ``alpha`` are always composited; ``depth``, ``mask``, the ids,
              ``normal`` and the surface outputs (``barycentric``, ``uv``, ``position``,
              ``ray_depth``) describe by default the nearest opaque surface (seen through the
              glass). With a threshold they describe the nearest fragment, blended or opaque,
              whose alpha (clamped to [0, 1]) is at least ``alpha_threshold``, as Blender's
              "pass alpha threshold" does (0.5 there); 0 takes the nearest blended fragment of
              any alpha. With msaa / ssaa the representative sample is then the sample nearest
              the centre that sees such a fragment or an opaque surface. ``coverage`` still
              counts opaque fragments. Not with a lens-distorted camera.
        raster : how triangles are filled: "edge" (default; edge functions tested at every
              pixel of a triangle's box) or "scanline" (each row's span found by edge walking,
              the classical algorithm). Both use the same snapped vertices and top-left rule, so
              they cover exactly the same pixels and every output is the same bits; "scanline"
              cross-checks the default and is slower (always deferred shading).
        msaa : multisample anti-aliasing: 1 (default, off: every output exact and unblended), 2,
              4, 8 or 16 samples per pixel at the Direct3D / Vulkan standard positions. Coverage
              and depth are tested per sample; each triangle is shaded once per pixel (at its
              sample nearest the centre among those it covers); colour and radiance are the box
              filter (mean) of the samples in linear light, the colour output then encoded.
        ssaa : supersampling: k (1 to 8) shades a k x k grid of samples per pixel and averages
              them: the reference-quality mode, k^2 times the shading. Not with msaa > 1.
              With either, ``alpha`` is the fraction of samples covered and ``radiance`` is
              premultiplied by it (0 where uncovered; ``color`` mixes in the background by
              1 - alpha). Ids, mask, depth, normal and the surface outputs are never averaged:
              they come from one representative sample per pixel, the covered sample nearest
              the pixel centre (ties: the lower sample index), so they describe one surface
              point. ``coverage`` sums the fragments of all samples.
        line_algorithm : how lines (``softrast.Lines``) of width <= 1 are stepped, one pixel per
              step along the major axis (x when |dx| >= |dy|) from the first endpoint's pixel to
              the second's, both drawn (an endpoint's pixel is (floor(x), floor(y)) of its
              window position): "bresenham" (default; integer, the minor offset at step k is
              k |dm| / M rounded, halves away from the first endpoint) or "dda" (the minor
              coordinate m0 + k dm / M in double, rounded half up: floor(v + 0.5)). Wider lines
              cover every pixel whose centre lies within width / 2 of the segment between the
              endpoints' pixel centres. Lines are clipped to the near and far planes in
              homogeneous space; depth, colour and position along them are perspective-correct
              (at the segment's point nearest the pixel centre). Lines and points are drawn
              after the triangles, nearer-wins (ties keep what was drawn first), as whole pixels:
              with msaa / ssaa over the resolved pixels, alpha 1.
        wireframe : True draws every mesh instance's edges over the image as lines of
              ``line_color`` (RGB in [0, 1], linear; default black) and ``line_width`` pixels
              (default 1), with the instance's id and triangle_id -1. In the depth test an edge
              counts as nearer by 1/256 of its depth (``WIREFRAME_DEPTH_BIAS``), so over its own
              solid it shows the front edges and hides the back ones (a surface in front by
              less than that, or a face seen at a grazing angle, may let an edge through).
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
        choice(cull, "cull", _CULL)
        choice(normal_kind, "normal_kind", _NORMAL_KINDS)
        if not isinstance(cull_double_sided, (bool, np.bool_)):
            raise TypeError(f"cull_double_sided must be True or False, got {cull_double_sided!r:.80}")
        choice(shading, "shading", _SHADING)
        choice(shading_path, "shading_path", _SHADING_PATHS)
        choice(raster, "raster", _RASTER)
        choice(line_algorithm, "line_algorithm", _LINE_ALGORITHMS)
        if not isinstance(wireframe, (bool, np.bool_)):
            raise TypeError(f"wireframe must be True or False, got {wireframe!r:.80}")
        if wireframe:
            wire_color = unit_rgb(line_color, "line_color")
            wire_width = real(line_width, "line_width")
            if not (np.isfinite(wire_width) and 0.0 < wire_width <= 1e6):
                raise ValueError(f"line_width must be finite, > 0 and at most 1e6, got {line_width!r}")
        choice(frequency, "frequency", _FREQUENCIES)
        choice(normal_space, "normal_space", _NORMAL_SPACES)
        if not isinstance(srgb, (bool, np.bool_)):
            raise TypeError(f"srgb must be True or False, got {srgb!r:.80}")
        if texture_filter is not None:
            check_filter(texture_filter, "texture_filter")
        bg = unit_rgb(background, "background")
        ambient_f = real(ambient, "ambient")
        if not 0.0 <= ambient_f <= 1.0:  # NaN fails too
            raise ValueError(f"ambient must be in [0, 1], got {ambient!r}")
        msaa, ssaa = _antialiasing(msaa, ssaa)
        shadow_override = None if shadows is None else shadow_method(shadows)
        if alpha_threshold is not None:
            threshold = real(alpha_threshold, "alpha_threshold")
            if not 0.0 <= threshold <= 1.0:  # NaN fails too
                raise ValueError(f"alpha_threshold must be None or in [0, 1], got {alpha_threshold!r}")
            alpha_threshold = threshold

        if getattr(camera, "_dist", None) is not None:  # an IntrinsicsCamera with lens distortion
            if msaa > 1 or ssaa > 1:
                raise ValueError("msaa / ssaa: anti-aliasing a camera with lens distortion is not "
                                 "supported (its oversample= already averages colour bilinearly)")
            if scene.primitives or wireframe:
                raise ValueError("scene: lines and points (and wireframe) are not supported with "
                                 "a camera with lens distortion")
            if alpha_threshold is not None:
                raise ValueError("alpha_threshold: not supported with a camera with lens distortion "
                                 "(its depth and ids are ray cast against opaque surfaces only)")
            return render_distorted(self, scene, camera, names, {
                "cull": cull, "cull_double_sided": bool(cull_double_sided),
                "normal_kind": normal_kind, "shading": shading,
                "background": background, "ambient": ambient,
                "shading_path": shading_path, "frequency": frequency, "srgb": srgb,
                "texture_filter": texture_filter, "normal_space": normal_space, "raster": raster,
                "shadows": shadows},
                out)
        out_arrays = _out_arrays(out, names)
        new = names if not out_arrays else [n for n in names if n not in out_arrays]  # out= reused
        if new:
            check_budget(w * h * sum(_OUTPUT_BYTES[n] for n in new), f"outputs {tuple(new)} at {w}x{h}")
        _check_mip_budgets(scene, texture_filter)

        draws = _draws(scene)
        primitives = _primitive_draws(scene)
        if wireframe:
            primitives = primitives + _wireframe_draws(scene, wire_color, float(np.float32(wire_width)))
        view, proj = camera._render_matrices(w, h)
        # Every option is checked above, once; the core reads them by name (_core.RENDER_OPTIONS).
        buffers = self._core.render(draws, {
            "view": view, "proj": proj, "orthographic": camera.orthographic, "near": camera.near,
            "far": camera.far, "outputs": names, "cull": cull,
            "cull_double_sided": bool(cull_double_sided), "normal_kind": normal_kind,
            "shading": shading,
            "shading_path": shading_path, "background": bg, "ambient": ambient_f, "out": out_arrays,
            "lights": _lights(scene, view, shadow_override, self._map_renderer),
            "ambient_light": scene.ambient_light,
            "frequency": frequency, "srgb": bool(srgb), "texture_filter": texture_filter,
            "normal_rotation": None if normal_space == "world" else
            tuple(map(tuple, camera.pose[:3, :3].T.tolist())),
            "raster": raster, "msaa": msaa, "ssaa": ssaa, "primitives": primitives,
            "line_algorithm": line_algorithm, "alpha_threshold": alpha_threshold})
        return Frame(buffers)

    def render_many(self, scene: Scene, cameras: Iterable[Camera], outputs: str | Sequence[str] = ("color", "depth"),
                    progress: bool = False, callback: Callable[[int, Frame], Any] | None = None,
                    workers: int | None = None, **options: Any) -> Iterator[Frame]:
        """Render ``scene`` from each of ``cameras`` in turn: a generator of Frames, in the
        cameras' order, equal byte for byte to ``render(scene, camera, outputs, **options)`` in a
        loop (any option of ``render`` but ``out``).

        Views render concurrently, each on its own single-threaded renderer (``workers`` of them,
        default: this renderer's thread count), with the GIL released, while the caller consumes
        earlier frames: small frames, whose own passes cannot keep every core busy, then use
        them all. At most 2 x workers frames are in flight, so 10,000 views never sit in memory.
        The scene is uploaded once (its meshes' arrays are shared, its draw records cached);
        ``cameras`` may be any iterable (a generator of posed cameras, say), read as needed.

        progress : show a tqdm progress bar (total = len(cameras) when it has one).
        callback : called as callback(i, frame) for each frame, before it is yielded.
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
        if not isinstance(progress, (bool, np.bool_)):
            raise TypeError(f"progress must be True or False, got {progress!r:.80}")
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
