"""Renderer and Frame: the public face of the C++ pipeline (``softrast._core``)."""
from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from typing import Any, Sequence

import numpy as np
import numpy.typing as npt

from . import _core
from ._checks import choice, image_side, integer, real, unit_rgb
from .camera import Camera
from .light import shadow_method
from .shadow_maps import map_cameras, occluder_bounds
from .limits import check_budget
from .scene import Scene
from .texture import FILTERS_WITH_MIPS, check_filter

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
# Bytes per pixel of each output (see Frame): what a render allocates for it. From the core's
# output table, as every list of outputs here is.
_OUTPUT_BYTES = {row["name"]: row["bytes_per_pixel"] for row in _core.OUTPUT_TABLE}


class Frame:
    """The buffers of one render. Outputs that were not requested are ``None``.

{outputs}

    Every array views memory the C++ renderer allocated for this frame alone (``arr.base`` owns
    it; nothing is copied). Later renders never write into it.
    """

    __slots__ = _core.OUTPUTS

    def __init__(self, buffers: dict[str, np.ndarray]) -> None:
        _init_frame(self, buffers.get)

    @property
    def outputs(self) -> tuple[str, ...]:
        """Names of the outputs this frame holds."""
        return tuple(n for n in self.__slots__ if getattr(self, n) is not None)

    def as_dict(self) -> dict[str, np.ndarray]:
        return {n: getattr(self, n) for n in self.outputs}

    def save(self, directory: str | os.PathLike[str], stem: str,
             formats: dict[str, str] | None = None) -> dict[str, str]:
        """Write each output to ``directory/{stem}_{name}.{ext}``; returns {name: path}.

        formats : {output name: format} overriding the defaults, formats being
            "png"   8-bit PNG: color, mask (0 / 255)
            "jpg"   JPEG (lossy): color
            "png16" 16-bit PNG: triangle_id, instance_id storing id + 1 (0 = background; ids
                    must fit: at most 65534), coverage
            "png16mm" 16-bit PNG of depth or ray_depth in millimetres (round half up, clipped to
                    [1, 65535] where hit, 0 = background: lossy, for tools that want it)
            "tif"   TIFF in the output's own dtype (deflated): every output
            "exr"   float32 OpenEXR (zip, through OpenImageIO, 5-10x slower): every float output
            "npy"   NumPy's .npy: every output, raw
        Defaults: color and mask "png"; the float outputs "tif" (float32, which OpenCV,
        scikit-image, imageio, tifffile and OpenImageIO open; Pillow the one-channel ones);
        triangle_id and instance_id "png16" when every id fits, else "tif" (int32, the id
        itself); coverage "tif". PNG and TIFF are written by softrast's own encoder
        (``softrast.imwrite``), fast and with the GIL released. Every format but jpg and
        png16mm gives the output back exactly (``Frame.load``), and the same frame gives the
        same bytes (files are reproducible). Each file is written atomically.
        """
        from .io import _write_bytes, imwrite

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
                from .opencv import depth_to_mm_uint16
                imwrite(path, depth_to_mm_uint16(arr, scale=1000.0))
            else:
                imwrite(path, arr)
            written[name] = path
        return written

    @classmethod
    def load(cls, directory: str | os.PathLike[str], stem: str) -> "Frame":
        """The frame ``save`` wrote as ``directory/{stem}_*``: each output as it was (png16 ids
        less 1, masks as bool; png16mm depths in scene units, from millimetres).

        Each file must hold what ``save`` writes for its output (the dtype and channels of
        ``softrast.OUTPUT_TABLE``, in a format ``save`` offers for it) and all of them one
        (h, w); else ValueError naming the file. Two files of one output (say a .png and the
        .tif of a later save in another format) are ambiguous: ValueError naming both."""
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
    from .io import imread

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
    """Save's format for output ``name`` (benchmarks/RESULTS.md, "Issue 37", has the table of
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


def _caster_scene(scene: Scene) -> Scene:
    """The scene's mesh instances that cast shadows (not blended), without lights, lines or
    points: what a shadow map sees."""
    casters = Scene()
    for inst in scene.instances:
        if inst.material is None or inst.material.alpha_mode != "blend":
            casters.add(inst.mesh, pose=inst.pose, instance_id=inst.instance_id, color=inst.color,
                        material=inst.material)
    return casters


def _light_maps(scene: Scene, li: Any, pose: np.ndarray, threads: int, simd: bool) -> list[Any]:
    """A shadow-mapped light's faces (view, proj, orthographic, depth), rendered by softrast from
    the cameras shadow_maps.map_cameras fits to the occluders."""
    light = li.light
    corners = occluder_bounds(scene.instances)
    if corners is None:
        return []
    n = light.shadow_resolution
    fields = light._record_fields(pose)
    cams = map_cameras(light._kind, np.asarray(fields["position"]),
                       np.asarray(fields["direction"]), getattr(light, "outer_cone", 0.0),
                       corners, n)
    casters = scene._cached("shadow_casters", lambda: _caster_scene(scene))
    r = Renderer(n, n, threads=threads, simd=simd)
    faces = []
    for cam in cams:
        depth = r.render(casters, cam, outputs=("depth",), cull="none").depth
        view, proj = cam._render_matrices(n, n)
        faces.append((view, proj, cam.orthographic, np.ascontiguousarray(depth)))
    return faces


def _lights(scene: Scene, view: Any, shadows: str | bool | None = None,
            renderer: tuple[int, bool] = (0, True)) -> list[Any]:
    """The core's light records (world space) of the scene's lights for one render, cached in the
    scene for the last view matrix (cameras keep one array per pose) and shadow override:
    camera-space lights move with it. A scene without lights gets the headlight from the core."""
    cached = scene._render_cache.get("lights")
    version = scene.__dict__.get("_version", 0)
    if cached is not None and cached[0] == version and cached[1] is view and cached[3] == shadows:
        return cached[2]
    records = []
    cam_to_world = None
    for li in list(scene._lights):
        pose = li.pose
        if li.camera_space:
            if cam_to_world is None:
                cam_to_world = np.linalg.inv(np.asarray(view, dtype=np.float64))
            pose = cam_to_world @ pose
        method = li.light.shadows if shadows is None else shadows
        if method != "map":
            records.append(li.light._core(pose, shadows))
            continue
        # A shadow-mapped light's record holds its maps: kept in the scene until it changes
        # (not for a camera-space light, whose pose follows every view).
        def make(li=li, pose=pose) -> Any:
            return li.light._core(pose, shadows, _light_maps(scene, li, pose, *renderer))
        records.append(make() if li.camera_space else
                       scene._cached(("shadow_map", li.light, pose.tobytes(), shadows), make))
    # Stored with the version read before the lights were: used only while it is current.
    scene._render_cache["lights"] = (version, view, records, shadows)
    return records


def _primitive_draws(scene: Scene) -> list[Any]:
    """The core's records of the scene's lines and points (cached in the scene until it
    changes); each holds its object's read-only arrays, which the core views during a render."""
    return scene._cached("primitives", lambda: [
        p.item._core_record(p.pose, p.instance_id) for p in scene.primitives])


# render(wireframe=True): in the depth test an edge counts as nearer by this fraction of its depth,
# so it wins over its own faces (whose depth at a pixel centre differs from the edge's nearest
# point by up to half a pixel's depth slope) and loses to surfaces in front by more than that.
WIREFRAME_DEPTH_BIAS = 2.0**-8


def _wireframe_draws(scene: Scene, line_color: tuple, line_width: float) -> list[Any]:
    """Line records of every mesh instance's unique edges (cached in the scene until it changes;
    one Lines per mesh, shared by its instances)."""
    from .primitives import Lines

    def build() -> list[Any]:
        per_mesh: dict[int, Lines] = {}
        records = []
        for inst in scene.instances:
            mesh = inst.mesh
            lines = per_mesh.get(id(mesh))
            if lines is None:
                faces = np.asarray(mesh.faces)
                edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
                edges = np.unique(edges, axis=0) if len(edges) else edges.reshape(0, 2)
                lines = per_mesh[id(mesh)] = Lines(mesh.positions, edges, width=line_width,
                                                   color=line_color)
            records.append(lines._core_record(inst.pose, inst.instance_id,
                                              depth_bias=WIREFRAME_DEPTH_BIAS))
        return records

    return scene._cached(("wireframe", line_color, line_width), build)


def _draws(scene: Scene) -> list[Any]:
    """The core's draw records (``softrast._core.Draw``), cached in the scene until it changes.
    The core decides how each is shaded (its material's model, or the render's shading=).
    A scene edited by another thread meanwhile: see Scene._cached."""
    return scene._cached("draws", lambda: [
        _core.Draw(mesh=i.mesh._core_data(), pose=i.pose, instance_id=i.instance_id,
                   color=i.color, material=i.material._core if i.material is not None else None)
        for i in scene.instances])


def _textures(scene: Scene) -> list[tuple[Any, Any]]:
    """(Texture, its core texture) of every texture slot of the scene's materials, as the draws
    use them (cached in the scene until it changes)."""
    cached = scene._render_cache.get("textures")
    if cached is None:
        cached, seen = [], set()
        for inst in scene._instances:
            mat = inst.material
            if mat is None:
                continue
            for slot in mat._TEXTURE_SLOTS:
                tex = getattr(mat, slot)
                if tex is not None:
                    core = tex._core(slot in ("base_color_texture", "emissive_texture"))  # as Material
                    if id(core) not in seen:
                        seen.add(id(core))
                        cached.append((tex, core))
        scene._render_cache["textures"] = cached
    return cached


def _check_mip_budgets(scene: Scene, texture_filter: str | None) -> None:
    """The mip chains this render builds (the core builds those its filters need, once per
    texture: cpp/bind/render.cpp), each checked against the memory budget first."""
    for tex, core in _textures(scene):
        if (texture_filter or tex.filter) in FILTERS_WITH_MIPS and not core.has_mips:
            tex._check_mips(core)


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


_END = object()  # render_many's end of the cameras (None is a camera to refuse, not the end)


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
            from .distortion import render_distorted

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
            "lights": _lights(scene, view, shadow_override, self._args[2:]),
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
