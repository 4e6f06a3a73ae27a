"""Every candidate encoder for each output kind of a dataset.

Renders real frames (Spot, as bench_dataset.py, and a row of three textured Fuze bottles with
instance ids 1-3, each on an orbit of cameras, 640x480) and, for each output kind

  * color        (h, w, 3) uint8
  * instance_id  (h, w) int32; the PNG rows store id + 1 as uint16 (softrast's "png16")
  * depth        (h, w) float32
  * normal       (h, w, 3) float32

times every candidate encoder to bytes in memory (ms per frame: the median over frames x rounds,
and the minimum; one thread, candidates interleaved frame by frame), and reports bytes per frame,
whether the bytes decode bit-exactly with the same library, whether two threads encode ~2x as
fast as one for the main candidates (``main=True``, softrast's defaults, and CPython's
zlib as the control, which shows what the machine's load leaves of a second core), whether the
codec holds the GIL (how late a sleeping thread wakes while one thread encodes: independent of
the load; every candidate), and which readers open the file bit-exactly (same dtype and values;
BGR order undone for cv2; a trailing channel of 1 allowed):
cv2.imread(IMREAD_UNCHANGED), skimage.io.imread, imageio.v3.imread, Pillow (np.asarray of
Image.open), tifffile.imread, OpenEXR (the official bindings) and OpenImageIO
(read_image(format="unknown")). Readers that return a *different* array without raising are
listed as silent mis-reads.

    python3 benchmarks/bench_encoders.py [--quick] [--views 6] [--rounds 3] [--thread-rounds 3]

Adding a candidate is one ``candidate(kind, name, encode, decode, ext)`` line in
``register_candidates``. Libraries that are not installed give "not installed" rows: the script
needs only softrast's base dependencies (numpy, trimesh, OpenImageIO, Pillow).
"""
from __future__ import annotations

import argparse
import concurrent.futures
import dataclasses
import gc
import importlib
import importlib.util
import io
import logging
import os
import statistics
import sys
import tempfile
import threading
import time
import warnings
import zlib
from typing import Any, Callable

os.environ.setdefault("IMAGEIO_NO_INTERNET", "1")  # no plugin downloads while probing readers
import numpy as np  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "python"))
import softrast as sr  # noqa: E402
import softrast.io as sio  # noqa: E402

W, H = 640, 480
KINDS = ("color", "instance_id", "depth", "normal")
GIL_HELD = 2.5e-4  # a wake delay this much over the idle one: the encoder holds the GIL
OUTPUTS = ("color", "depth", "instance_id", "normal")
# Scratch files (the OpenImageIO and OpenEXR-file rows, the reader checks): tmpfs when there is one.
TMP = tempfile.mkdtemp(prefix="sr_enc_", dir="/dev/shm" if os.path.isdir("/dev/shm") else None)


# ---------------------------------------------------------------------------------------------
# Candidates

@dataclasses.dataclass(eq=False)
class Candidate:
    kind: str
    name: str
    encode: Callable[[np.ndarray], Any]  # stored array -> bytes-like (or _File: a path it wrote)
    decode: Callable[[Any], Any]  # bytes -> array, with the same library (floors: -> raw bytes)
    ext: str | None  # the file's extension for the reader checks; None: not a file (floors)
    needs: tuple[str, ...] = ()  # modules ("imagecodecs") or codecs ("imagecodecs.JPEGXL")
    stored: str = "native"  # "native" or "id+1 uint16": what the file holds (converted in the clock)
    floor: bool = False  # a bandwidth floor, not a file format
    default: bool = False  # what softrast's Frame.save writes by default
    main: bool = False  # timed on 1 thread against 2 (with the default, softrast's own, the control)
    note: str = ""
    convert: bool = True  # False: the encoder takes the output itself and stores it as `stored`

    def input(self, a: np.ndarray) -> np.ndarray:
        """What the encoder is given for output array ``a`` (converted in the clock)."""
        return STORED[self.stored](a) if self.convert else a


CANDIDATES: list[Candidate] = []


def candidate(kind: str, name: str, encode: Callable[[np.ndarray], Any],
              decode: Callable[[Any], Any], ext: str | None, **kw: Any) -> None:
    CANDIDATES.append(Candidate(kind, name, encode, decode, ext, **kw))


STORED: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "native": lambda a: a,
    "id+1 uint16": lambda a: (a + 1).astype(np.uint16),
}


class _File(str):
    """A path an encoder wrote (libraries without a memory output); read after the clock stops."""


def _bytes(out: Any) -> Any:
    if isinstance(out, _File):
        with open(out, "rb") as f:
            return f.read()
    return out


def _nbytes(out: Any) -> int:
    return memoryview(out).nbytes


def _missing(needs: tuple[str, ...]) -> str | None:
    for need in needs:
        mod, _, codec = need.partition(".")
        if importlib.util.find_spec(mod) is None:
            return mod
        if codec:
            try:
                if not getattr(importlib.import_module(mod), codec).available:
                    return need
            except Exception:
                return need
    return None


def _scratch(ext: str, tag: str = "") -> str:
    return os.path.join(TMP, f"{tag}{threading.get_ident()}.{ext}")


def _via_file(reader: Callable[[str], np.ndarray], ext: str) -> Callable[[Any], np.ndarray]:
    """A decoder from bytes for a library that reads files only."""
    def dec(b: Any) -> np.ndarray:
        p = _scratch(ext, "dec")
        with open(p, "wb") as f:
            f.write(b)
        return reader(p)
    return dec


def _rgb_to_bgr(a: np.ndarray) -> np.ndarray:
    if a.ndim == 3 and a.shape[2] == 3:
        return a[:, :, ::-1]
    if a.ndim == 3 and a.shape[2] == 4:
        return a[:, :, [2, 1, 0, 3]]
    return a


# --- encoders -----------------------------------------------------------------------------------

def oiio(ext: str, compression: Any = None) -> Callable[[np.ndarray], Any]:
    """softrast.io.imwrite (OpenImageIO; its Python API has no memory output: a file on tmpfs)."""
    def enc(a: np.ndarray) -> _File:
        p = _scratch(ext, "oiio")
        sio.imwrite(p, a, compression=compression)
        return _File(p)
    return enc


def cv2_enc(ext: str, params: Callable[[Any], list[int]] = lambda cv2: []) -> Callable[[np.ndarray], Any]:
    def enc(a: np.ndarray) -> Any:
        import cv2
        ok, buf = cv2.imencode(ext, _rgb_to_bgr(a), params(cv2))  # the BGR flip is in the clock
        if not ok:
            raise RuntimeError(f"cv2.imencode({ext}) failed")
        return buf
    return enc


def _cv2_deflate(cv2: Any) -> list[int]:
    return [cv2.IMWRITE_TIFF_COMPRESSION, cv2.IMWRITE_TIFF_COMPRESSION_ADOBE_DEFLATE]  # its predictor: auto


def cv2_dec(b: Any) -> np.ndarray:
    import cv2
    a = cv2.imdecode(np.frombuffer(b, np.uint8), cv2.IMREAD_UNCHANGED)
    if a is None:
        raise ValueError("cv2.imdecode failed")
    return _rgb_to_bgr(a)


def codec(name: str, **kw: Any) -> Callable[[np.ndarray], Any]:
    def enc(a: np.ndarray) -> Any:
        import imagecodecs
        return getattr(imagecodecs, f"{name}_encode")(a, **kw)
    return enc


def codec_dec(name: str) -> Callable[[Any], np.ndarray]:
    def dec(b: Any) -> np.ndarray:
        import imagecodecs
        return getattr(imagecodecs, f"{name}_decode")(b)
    return dec


def fpng_enc(a: np.ndarray) -> bytes:
    from fpng import fpng_ext
    h, w, c = a.shape
    return fpng_ext.encode_image_to_memory(a.tobytes(), w, h, c)


def pillow_png(a: np.ndarray) -> Any:
    from PIL import Image
    bio = io.BytesIO()
    Image.fromarray(a).save(bio, format="PNG", compress_level=1)
    return bio.getbuffer()


def pillow_dec(b: Any) -> np.ndarray:
    from PIL import Image
    with Image.open(io.BytesIO(b)) as im:
        return np.asarray(im)


def tiff(compression: str | None = None, level: int | None = None,
         predictor: int | None = None) -> Callable[[np.ndarray], Any]:
    def enc(a: np.ndarray) -> Any:
        import tifffile
        bio = io.BytesIO()
        tifffile.imwrite(bio, a, photometric="rgb" if a.ndim == 3 else "minisblack",
                         compression=compression, predictor=predictor, metadata=None, maxworkers=1,
                         compressionargs=None if level is None else {"level": level})
        return bio.getbuffer()
    return enc


def tiff_dec(b: Any) -> np.ndarray:
    import tifffile
    return tifffile.imread(io.BytesIO(b))


def openexr(compression: str) -> Callable[[np.ndarray], Any]:
    def enc(a: np.ndarray) -> Any:
        import OpenEXR
        channels = {"Y": a} if a.ndim == 2 else {"RGB": a}
        header = {"compression": getattr(OpenEXR, compression), "type": OpenEXR.scanlineimage}
        bio = io.BytesIO()
        with OpenEXR.File(header, channels, num_threads=1) as f:
            f.write(bio)
        return bio.getbuffer()
    return enc


def openexr_dec(b: Any) -> np.ndarray:
    import OpenEXR
    with OpenEXR.File(io.BytesIO(b), num_threads=1) as f:
        return _exr_pixels(f)


def npy_enc(a: np.ndarray) -> Any:
    bio = io.BytesIO()
    np.save(bio, a)
    return bio.getbuffer()


def npy_dec(b: Any) -> np.ndarray:
    return np.load(io.BytesIO(b))


# ---------------------------------------------------------------------------------------------
# Readers: path -> array (raise when they cannot open it)

def read_cv2(p: str) -> np.ndarray:
    import cv2
    a = cv2.imread(p, cv2.IMREAD_UNCHANGED)
    if a is None:
        raise ValueError("cv2.imread returned None")
    return _rgb_to_bgr(a)  # cv2 is BGR(A): back to the file's RGB(A)


def read_skimage(p: str) -> np.ndarray:
    import skimage.io
    return skimage.io.imread(p)


def read_imageio(p: str) -> np.ndarray:
    import imageio.v3 as iio
    return iio.imread(p)


def read_pillow(p: str) -> np.ndarray:
    from PIL import Image
    with Image.open(p) as im:
        return np.asarray(im)


def read_tifffile(p: str) -> np.ndarray:
    import tifffile
    return tifffile.imread(p)


def _exr_pixels(f: Any) -> np.ndarray:
    ch = f.channels()
    if len(ch) == 1:
        return next(iter(ch.values())).pixels
    for key in ("RGBA", "RGB"):
        if key in ch:
            return ch[key].pixels
    raise ValueError(f"channels {sorted(ch)}")


def read_openexr(p: str) -> np.ndarray:
    import OpenEXR
    with OpenEXR.File(p) as f:
        return _exr_pixels(f)


def read_oiio(p: str) -> np.ndarray:
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(p)
    if inp is None:
        raise ValueError(oiio.geterror())
    try:
        a = inp.read_image(format="unknown")
        err = inp.geterror()
    finally:
        inp.close()
    if a is None or err:
        raise ValueError(err or "no pixels")
    return a


READERS: list[tuple[str, str, Callable[[str], np.ndarray]]] = [
    ("cv2", "cv2", read_cv2), ("skimage", "skimage", read_skimage), ("imageio", "imageio", read_imageio),
    ("Pillow", "PIL", read_pillow), ("tifffile", "tifffile", read_tifffile),
    ("OpenEXR", "OpenEXR", read_openexr), ("OIIO", "OpenImageIO", read_oiio),
]


def compare(got: Any, want: np.ndarray) -> str | None:
    """None when ``got`` is ``want`` bit for bit (a trailing channel of 1 allowed), else why not."""
    if not isinstance(got, np.ndarray):
        return f"a {type(got).__name__}"
    g = got
    if g.shape != want.shape and g.ndim == want.ndim + 1 and g.shape[-1] == 1:
        g = g[..., 0]
    if g.shape != want.shape:
        if g.size == want.size and g.ndim == 1:  # the raw floors decode flat
            g = g.reshape(want.shape)
        else:
            return f"shape {got.shape} {got.dtype}"
    if g.dtype != want.dtype and g.dtype.newbyteorder("=") == want.dtype.newbyteorder("="):
        g = g.astype(want.dtype)  # the same values in the other byte order
    if g.dtype != want.dtype:
        return f"{g.dtype} for {want.dtype}"
    if np.ascontiguousarray(g).tobytes() == want.tobytes():
        return None
    if g.ndim == 3 and g.shape[2] == 3 and np.array_equal(g[:, :, ::-1], want):
        return "channels reversed"
    diff = (g.view(np.uint8).reshape(*g.shape, -1) != want.view(np.uint8).reshape(*want.shape, -1)).any(-1)
    return f"{diff.mean():.1%} of values differ"


# ---------------------------------------------------------------------------------------------

def register_candidates() -> None:
    """Every candidate, one line each. ADD NEW ENCODERS HERE: candidate(kind, name, encode,
    decode, ext); softrast's own encoders join automatically once softrast.io has them."""
    png_any = _via_file(read_oiio, "png")
    # softrast's own encoders: what Frame.save writes by default (RESULTS.md, "Datasets and encoders")
    if hasattr(sio, "encode_png"):
        candidate("color", "softrast.io.encode_png", sio.encode_png, png_any, "png", default=True,
                  main=True)
    if hasattr(sio, "encode_tiff"):
        for kind in KINDS:
            candidate(kind, "softrast.io.encode_tiff (deflate; integers: predictor 2)", sio.encode_tiff,
                      _via_file(read_oiio, "tif"), "tif", default=kind in ("depth", "normal"), main=True)
    if hasattr(sio._core, "encode_png_ids"):
        candidate("instance_id", "softrast _core.encode_png_ids (PNG16 of id + 1, in C++)",
                  sio._core.encode_png_ids, png_any, "png", stored="id+1 uint16", default=True,
                  convert=False)

    # colour: (h, w, 3) uint8
    c = "color"
    candidate(c, "OIIO PNG zlib 1 (softrast's former default)", oiio("png", 1), png_any, "png")
    candidate(c, "cv2 PNG level 1", cv2_enc(".png", lambda cv2: [cv2.IMWRITE_PNG_COMPRESSION, 1]), cv2_dec,
              "png", needs=("cv2",))
    candidate(c, "imagecodecs png (libpng) level 1", codec("png", level=1), codec_dec("png"), "png",
              needs=("imagecodecs.PNG",))
    candidate(c, "imagecodecs spng level 1", codec("spng", level=1), codec_dec("spng"), "png",
              needs=("imagecodecs.SPNG",))
    candidate(c, "Pillow PNG compress_level 1", pillow_png, pillow_dec, "png")
    candidate(c, "fpng", fpng_enc, pillow_dec, "png", needs=("fpng",), main=True,
              note="fpng has no Python decoder: round trip decoded by Pillow")
    candidate(c, "QOI (imagecodecs)", codec("qoi"), codec_dec("qoi"), "qoi", needs=("imagecodecs.QOI",), main=True)
    candidate(c, "WebP lossless level 0 method 0 (imagecodecs)",
              codec("webp", level=0, lossless=True, method=0, numthreads=1), codec_dec("webp"), "webp",
              needs=("imagecodecs.WEBP",))
    candidate(c, "JPEG-XL lossless effort 1 (imagecodecs)",
              codec("jpegxl", lossless=True, effort=1, numthreads=1), codec_dec("jpegxl"), "jxl",
              needs=("imagecodecs.JPEGXL",))

    # ids: PNG16 of id + 1, or int32 TIFF of the id itself
    c, u16 = "instance_id", "id+1 uint16"
    candidate(c, "OIIO PNG16 zlib 1 (softrast's former default)", oiio("png", 1), png_any, "png",
              stored=u16)
    candidate(c, "cv2 PNG16 level 1", cv2_enc(".png", lambda cv2: [cv2.IMWRITE_PNG_COMPRESSION, 1]), cv2_dec,
              "png", needs=("cv2",), stored=u16)
    candidate(c, "imagecodecs png16 (libpng) level 1", codec("png", level=1), codec_dec("png"), "png",
              needs=("imagecodecs.PNG",), stored=u16)
    candidate(c, "imagecodecs spng16 level 1", codec("spng", level=1), codec_dec("spng"), "png",
              needs=("imagecodecs.SPNG",), stored=u16)
    candidate(c, "Pillow PNG16 compress_level 1", pillow_png, pillow_dec, "png", stored=u16, main=True)

    # int32 ids and float32 depth / normal: TIFF, EXR (floats)
    for c in ("instance_id", "depth", "normal"):
        tif_any = _via_file(read_oiio, "tif")
        candidate(c, "OIIO TIFF zip", oiio("tif", "zip"), tif_any, "tif")
        candidate(c, "OIIO TIFF none", oiio("tif", "none"), tif_any, "tif")
        candidate(c, "tifffile none", tiff(), tiff_dec, "tif", needs=("tifffile",))
        candidate(c, "tifffile zlib 1", tiff("zlib", 1), tiff_dec, "tif", needs=("tifffile",),
                  main=c == "instance_id")
        if c == "instance_id":
            candidate(c, "tifffile zstd 1", tiff("zstd", 1), tiff_dec, "tif",
                      needs=("tifffile", "imagecodecs.ZSTD"))
            candidate(c, "tifffile lzw", tiff("lzw"), tiff_dec, "tif", needs=("tifffile", "imagecodecs.LZW"))
            candidate(c, "cv2 TIFF (its default for int32: LZW + predictor 2)", cv2_enc(".tif"), cv2_dec, "tif",
                      needs=("cv2",))
            candidate(c, "cv2 TIFF deflate (+ predictor 2)", cv2_enc(".tif", _cv2_deflate), cv2_dec, "tif",
                      needs=("cv2",))
            continue
        candidate(c, "tifffile zlib 1 + predictor 3 (float)", tiff("zlib", 1, 3), tiff_dec, "tif",
                  needs=("tifffile", "imagecodecs"))
        candidate(c, "tifffile zstd 1 + predictor 3 (float)", tiff("zstd", 1, 3), tiff_dec, "tif",
                  needs=("tifffile", "imagecodecs.ZSTD"), main=True)
        candidate(c, "cv2 TIFF float (its default for float: uncompressed)", cv2_enc(".tif"), cv2_dec, "tif",
                  needs=("cv2",))
        candidate(c, "cv2 TIFF float deflate (+ predictor 3)", cv2_enc(".tif", _cv2_deflate), cv2_dec, "tif",
                  needs=("cv2",))
        exr_any = _via_file(read_oiio, "exr")
        for comp in ("none", "zip", "zips", "piz", "rle"):
            candidate(c, f"OIIO EXR {comp}" + (" (softrast's former default)" if comp == "zip" else ""),
                      oiio("exr", comp), exr_any, "exr")
        for comp in ("NO", "ZIP"):
            candidate(c, f"OpenEXR bindings {comp.lower() if comp == 'ZIP' else 'none'}",
                      openexr(f"{comp}_COMPRESSION"), openexr_dec, "exr", needs=("OpenEXR",), main=comp == "ZIP")

    # every kind: raw .npy, and the floors (structure only: the raw bytes, no format)
    for c in KINDS:
        candidate(c, ".npy (np.save to BytesIO)", npy_enc, npy_dec, "npy")
        candidate(c, "floor: zlib.compress level 1", lambda a: zlib.compress(a, 1), zlib.decompress, None,
                  floor=True, main=True)  # main: the control (CPython's zlib releases the GIL)
        candidate(c, "floor: imagecodecs zlibng level 1", codec("zlibng", level=1), codec_dec("zlibng"), None,
                  floor=True, needs=("imagecodecs.ZLIBNG",))
        candidate(c, "floor: memcpy (tobytes)", lambda a: a.tobytes(), bytes, None, floor=True)
    candidate("instance_id", "floor: zlib.compress level 1 of id+1 uint16", lambda a: zlib.compress(a, 1),
              zlib.decompress, None, floor=True, stored=u16)


# ---------------------------------------------------------------------------------------------
# Frames

def render_frames(views: int) -> list[dict[str, np.ndarray]]:
    import trimesh

    cams = []
    r = sr.Renderer(W, H, threads=2)
    frames = []
    # Spot, as bench_dataset.py
    tm = trimesh.load(os.path.join(ROOT, "assets", "meshes", "spot.obj"), force="mesh", process=False)
    spot = sr.Scene()
    spot.add(sr.Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals), instance_id=1)
    # Fuze (textured OBJ + MTL, z-up): a row of three bottles, instance ids 1-3
    fuze = sr.Scene()
    (inst,) = list(sr.load_scene(os.path.join(ROOT, "assets", "meshes", "fuze", "fuze.obj"), up_axis="z"))
    for k, x in enumerate((-0.09, 0.0, 0.09)):
        t = np.eye(4)
        t[0, 3] = x
        fuze.add(inst.mesh, pose=t @ inst.pose, instance_id=k + 1, material=inst.material)
    for scene, centre, radius in ((spot, tm.bounds.mean(axis=0), float(np.linalg.norm(tm.extents)) * 1.3),
                                  (fuze, np.array([0.0, 0.11, 0.0]), 0.42)):
        for pose in sr.orbit(centre, radius, views, elevation=20.0, start=10.0):
            cam = sr.PerspectiveCamera(fov_y=45.0, width=W, height=H, near=0.01, far=100.0)
            cam.pose = pose
            cams.append(cam)
            f = r.render(scene, cam, outputs=OUTPUTS)
            frames.append({k: np.ascontiguousarray(getattr(f, k)) for k in KINDS})
    return frames


# ---------------------------------------------------------------------------------------------

@dataclasses.dataclass(eq=False)
class Result:
    status: str = ""  # "" ok, else "not installed (x)" / "failed: ..."
    times: list[float] = dataclasses.field(default_factory=list)
    sizes: list[int] = dataclasses.field(default_factory=list)
    exact: str = ""
    opens: list[str] = dataclasses.field(default_factory=list)
    misreads: dict[str, str] = dataclasses.field(default_factory=dict)
    speedup: float | None = None
    gil_delay: float | None = None  # median wake delay of a sleeping thread while encoding (s)


def wake_delay(run: Callable[[], None], nap: float = 1e-3) -> float:
    """Median lateness (s) of a thread's 1 ms sleeps while ``run`` runs in this one. Waking needs
    the GIL: a codec that holds it through a call of D ms makes each wake wait up to D, one that
    releases it leaves the lateness at the timer's own (~0.1 ms), however busy the cores are."""
    flag: list[bool] = [True]
    late: list[float] = []

    def watch() -> None:
        while flag[0]:
            t = time.perf_counter()
            time.sleep(nap)
            late.append(time.perf_counter() - t - nap)

    th = threading.Thread(target=watch)
    th.start()
    try:
        run()
    finally:
        flag[0] = False
        th.join()
    return statistics.median(late) if late else 0.0


def round_trip(cand: Candidate, out: Any, want: np.ndarray) -> str | None:
    got = cand.decode(out)  # type: ignore[misc]
    if cand.floor:  # raw bytes back: the array's flat bytes
        got = np.frombuffer(got, want.dtype)
    return compare(got, want)


def check_readers(cand: Candidate, out: Any, want: np.ndarray, res: Result, first: bool) -> None:
    p = os.path.join(TMP, f"check.{cand.ext}")
    with open(p, "wb") as f:
        f.write(out)
    ok = []
    for label, module, reader in READERS:
        if importlib.util.find_spec(module) is None:
            continue
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                why = compare(reader(p), want)
        except Exception:
            why = "error"
        if why is None:
            ok.append(label)
        elif why != "error":
            res.misreads.setdefault(label, why)
    res.opens = ok if first else [x for x in res.opens if x in ok]
    try:
        import OpenImageIO
        OpenImageIO.geterror()  # retrieve, or OpenImageIO prints it at exit
    except ImportError:
        pass


def quiet_libraries() -> None:
    """Single-threaded codecs; silence the readers' complaints about files they cannot open."""
    logging.getLogger("tifffile").setLevel(logging.CRITICAL)
    try:
        import OpenImageIO as oiio
        oiio.attribute("threads", 1)
        oiio.attribute("exr_threads", 1)
    except ImportError:
        pass
    try:
        import cv2
        cv2.setNumThreads(1)
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    except (ImportError, AttributeError):
        pass


def versions() -> str:
    out = [f"softrast {sr.__version__}", f"numpy {np.__version__}"]
    for label, mod, attr in (("OpenImageIO", "OpenImageIO", "__version__"), ("cv2", "cv2", "__version__"),
                             ("imagecodecs", "imagecodecs", "__version__"), ("tifffile", "tifffile", "__version__"),
                             ("OpenEXR", "OpenEXR", "__version__"), ("Pillow", "PIL", "__version__"),
                             ("fpng", "fpng", "__version__"), ("imageio", "imageio", "__version__"),
                             ("skimage", "skimage", "__version__")):
        if importlib.util.find_spec(mod) is None:
            out.append(f"{label} not installed")
        else:
            try:
                out.append(f"{label} {getattr(importlib.import_module(mod), attr)}")
            except Exception as e:  # noqa: BLE001
                out.append(f"{label} ({type(e).__name__})")
    return ", ".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="3 views per scene, 2 rounds, 1 thread round")
    ap.add_argument("--views", type=int, default=None, help="views per scene (default 6; --quick 3)")
    ap.add_argument("--rounds", type=int, default=None, help="timing rounds (default 3; --quick 2)")
    ap.add_argument("--thread-frames", type=int, default=40, help="frames per 1- vs 2-thread run")
    ap.add_argument("--thread-rounds", type=int, default=None, help="default 3; --quick 1")
    args = ap.parse_args()
    views = args.views or (3 if args.quick else 6)
    rounds = args.rounds or (2 if args.quick else 3)
    thread_rounds = args.thread_rounds or (1 if args.quick else 3)
    gil_seconds = 0.1 if args.quick else 0.25
    t_start = time.perf_counter()
    quiet_libraries()
    register_candidates()
    frames = render_frames(views)
    n = len(frames)

    results: dict[Candidate, Result] = {c: Result() for c in CANDIDATES}
    live: list[Candidate] = []
    stored: dict[Candidate, list[np.ndarray]] = {}
    for c in CANDIDATES:
        miss = _missing(c.needs)
        if miss:
            results[c].status = f"not installed ({miss})"
            continue
        arrays = [f[c.kind] for f in frames]
        try:  # warm up (and find what is missing or fails)
            out = _bytes(c.encode(c.input(arrays[0])))
        except ImportError as e:
            results[c].status = f"not installed ({e.name})"
            continue
        except Exception as e:  # noqa: BLE001
            results[c].status = f"failed: {type(e).__name__}: {str(e).splitlines()[0][:80]}"
            continue
        stored[c] = arrays
        live.append(c)

    # Timing: rounds x frames, every live candidate on each frame in turn (order rotated per round)
    gc.collect()
    gc.disable()
    try:
        for rnd in range(rounds):
            order = live[rnd % len(live):] + live[:rnd % len(live)]
            for fi in range(n):
                for c in order:
                    res = results[c]
                    a = stored[c][fi]
                    t0 = time.perf_counter()
                    out = c.encode(c.input(a))
                    dt = time.perf_counter() - t0
                    res.times.append(dt)
                    if rnd == 0:
                        out = _bytes(out)
                        res.sizes.append(_nbytes(out))
                        want = STORED[c.stored](a)
                        try:
                            why = round_trip(c, out, want)
                        except Exception as e:  # noqa: BLE001
                            why = f"its decoder fails: {type(e).__name__}: {str(e).splitlines()[0][:70]}"
                        if why is not None and not res.exact:
                            res.exact = f"NO ({why})"
                        if c.ext is not None and fi in (0, n // 2):  # one frame of each scene
                            check_readers(c, out, want, res, fi == 0)
                    del out
            gc.collect()
    finally:
        gc.enable()
    for c in live:
        res = results[c]
        if not res.exact:
            res.exact = "yes" + (" (Pillow)" if "fpng" in c.name else "")

    # Two threads against one: the main candidates (softrast's defaults, the ones chosen in
    # register_candidates, softrast's own) and the control, CPython's zlib, which releases the GIL
    chosen = [c for c in live if c.main or c.default or c.name.startswith("softrast.io.encode")]
    ex1 = concurrent.futures.ThreadPoolExecutor(1)
    ex2 = concurrent.futures.ThreadPoolExecutor(2)
    t1s: dict[Candidate, list[float]] = {c: [] for c in chosen}
    t2s: dict[Candidate, list[float]] = {c: [] for c in chosen}
    try:
        for _ in range(thread_rounds):
            for c in chosen:
                batch = [stored[c][k % n] for k in range(args.thread_frames)]
                job = lambda a, c=c: c.encode(c.input(a))  # noqa: E731
                for ex, dest in ((ex1, t1s), (ex2, t2s)):
                    t0 = time.perf_counter()
                    for _out in ex.map(job, batch):
                        pass
                    dest[c].append(time.perf_counter() - t0)
    finally:
        ex1.shutdown()
        ex2.shutdown()
    for c in chosen:
        results[c].speedup = min(t1s[c]) / min(t2s[c])

    # The GIL, for every candidate: how late a sleeping thread wakes while this one encodes
    switch = sys.getswitchinterval()
    sys.setswitchinterval(1e-4)  # the encoding thread's own Python code hands the GIL over quickly
    try:
        idle = []
        for c in live:
            idle.append(wake_delay(lambda: time.sleep(0.05)))
            arrays = stored[c]

            def run(c: Candidate = c, arrays: list = arrays) -> None:
                end, k = time.perf_counter() + gil_seconds, 0
                while time.perf_counter() < end:
                    c.encode(c.input(arrays[k % n]))
                    k += 1
            results[c].gil_delay = wake_delay(run)
    finally:
        sys.setswitchinterval(switch)
    idle_delay = statistics.median(idle)

    report(frames, results, views, rounds, thread_rounds, args.thread_frames, idle_delay)
    print(f"\n(total {time.perf_counter() - t_start:.0f} s)")


def report(frames: list[dict[str, np.ndarray]], results: dict[Candidate, Result], views: int, rounds: int,
           thread_rounds: int, thread_frames: int, idle_delay: float) -> None:
    n = len(frames)
    print(f"{versions()}; {os.cpu_count()} cores")
    missing = [label for label, module, _ in READERS if importlib.util.find_spec(module) is None]
    if missing:
        print(f"readers not installed (so never listed): {', '.join(missing)}")
    print(f"{n} frames at {W}x{H} ({views} views each of Spot and of three textured Fuze bottles, ids 1-3), "
          f"{rounds} rounds; ms/frame = median of {n * rounds} single-thread encodes to bytes (OIIO threads and "
          f"exr_threads 1, cv2.setNumThreads(1), codecs' own thread options 1) "
          f"(OIIO rows: softrast.io.imwrite to a file on {os.path.dirname(TMP)}, its Python API has no "
          f"memory output); 2-thread speedup = time of {thread_frames} encodes on 1 thread / on 2 "
          f"(ThreadPoolExecutor, best of {thread_rounds}); GIL: the median lateness of a second thread's 1 ms "
          f"sleeps while one thread encodes (switch interval 0.1 ms; {idle_delay * 1e3:.2f} ms beside a "
          f"sleep), 'held' when over that + {GIL_HELD * 1e3:.2f} ms, 'released' under + {GIL_HELD / 2.5 * 1e3:.2f} ms; readers checked on one frame of each "
          f"scene")
    for kind in KINDS:
        a = frames[0][kind]
        raw = a.nbytes
        print(f"\n### {kind}: {a.shape} {a.dtype}, {raw:,} raw bytes\n")
        print("| encoder | ms/frame (min) | bytes/frame | exact round trip | 2-thread speedup | GIL (wake delay) "
              "| opened exactly by | silently mis-read by |")
        print("|---|---:|---:|---|---:|---|---|---|")
        for c in (c for c in CANDIDATES if c.kind == kind):
            res = results[c]
            name = c.name + (" *" if c.default else "")
            if res.status:
                print(f"| {name} | {res.status} | | | | | | |")
                continue
            ms = f"{statistics.median(res.times) * 1e3:.2f} ({min(res.times) * 1e3:.2f})"
            size = sum(res.sizes) / len(res.sizes)
            sp = "" if res.speedup is None else f"{res.speedup:.2f}x"
            gil = ""
            if res.gil_delay is not None:
                extra = res.gil_delay - idle_delay
                gil = "held" if extra > GIL_HELD else "released" if extra < GIL_HELD / 2.5 else "short holds"
                gil += f" ({res.gil_delay * 1e3:.2f} ms)"
                if statistics.median(res.times) < 1e-3:
                    gil += "; calls < 1 ms: a hold shows as at most their length"
            opened = "(not a file)" if c.ext is None else (", ".join(res.opens) or "none")
            if c.ext == "npy":
                opened += " (np.load reads it)"
            mis = "; ".join(f"{k}: {v}" for k, v in res.misreads.items())
            print(f"| {name} | {ms} | {size:,.0f} ({size / raw:.0%}) | {res.exact} | {sp} | {gil} | {opened} "
                  f"| {mis} |")
        notes = [f"{c.name}: {c.note}" for c in CANDIDATES if c.kind == kind and c.note]
        if kind == "instance_id":
            notes.append("the PNG16 rows include the id+1 -> uint16 conversion in their time")
        if kind in ("color", "normal"):
            notes.append("the cv2 rows include the RGB -> BGR flip in their time")
        print("\n" + "; ".join(["* = what softrast writes by default"] + notes) + ".")


if __name__ == "__main__":
    try:
        main()
    finally:
        import shutil
        shutil.rmtree(TMP, ignore_errors=True)
