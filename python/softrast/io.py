"""Image files: lossless round trips, atomic writes, no silent quantization.

PNG and TIFF are written by softrast's own encoder (``_core.encode_png``, ``_core.encode_tiff``:
cpp/encode.hpp) unless a ``compression`` is asked for: 5-10x faster than libpng or zlib at
level 1 on rendered frames, with the GIL released, and the same bytes on every machine. Every
other format, and every read, goes through OpenImageIO.

Arrays are (h, w) or (h, w, c), row 0 at the top of the image (the layout of every render output).
"""
from __future__ import annotations

import contextlib
import errno
import os
import uuid
from typing import Any, Iterator

import numpy as np
import numpy.typing as npt

from . import _core
from .limits import check_budget

__all__ = ["imread", "imwrite"]

_U8, _U16, _F32 = np.dtype(np.uint8), np.dtype(np.uint16), np.dtype(np.float32)
_I32, _U32 = np.dtype(np.int32), np.dtype(np.uint32)

# Pixel types each format stores exactly. Anything else would be converted silently by
# OpenImageIO (float -> 8 bit in PNG, uint8 -> half in EXR), so we refuse it instead.
# Extensions not listed are passed to OpenImageIO unchecked.
_FORMAT_DTYPES: dict[str, frozenset[np.dtype]] = {
    ".png": frozenset({_U8, _U16}),
    ".jpg": frozenset({_U8}),
    ".jpeg": frozenset({_U8}),
    ".bmp": frozenset({_U8}),
    ".tga": frozenset({_U8}),
    ".webp": frozenset({_U8}),
    ".gif": frozenset({_U8}),
    ".ppm": frozenset({_U8, _U16}),
    ".pgm": frozenset({_U8, _U16}),
    ".pnm": frozenset({_U8, _U16}),
    ".exr": frozenset({_F32}),
    ".hdr": frozenset({_F32}),
    ".tif": frozenset({_U8, _U16, _F32, _I32, _U32}),
    ".tiff": frozenset({_U8, _U16, _F32, _I32, _U32}),
}
# JPEG has no alpha (OpenImageIO drops it silently); Radiance HDR is RGB only.
_FORMAT_CHANNELS: dict[str, frozenset[int]] = {
    ".jpg": frozenset({1, 3}),
    ".jpeg": frozenset({1, 3}),
    ".hdr": frozenset({3}),
}
_OIIO_TYPE = {_U8: "uint8", _U16: "uint16", _F32: "float", _I32: "int", _U32: "uint"}
# Channel counts beyond gray / RGB / RGBA: two (uvs) in the formats that store any count.
_ANY_CHANNELS = frozenset({".exr", ".tif", ".tiff"})
# imwrite(compression=): the codecs each format offers (OpenImageIO's names); PNG takes a zlib
# level 0-9 instead.
_COMPRESSIONS: dict[str, tuple[str, ...]] = {
    ".exr": ("none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"),
    ".tif": ("none", "lzw", "zip", "packbits"),
    ".tiff": ("none", "lzw", "zip", "packbits"),
}


def _compression_attribute(ext: str, compression: Any) -> tuple[str, str | int] | None:
    """The OpenImageIO attribute (name, value) for imwrite's ``compression`` argument."""
    if compression is None:
        # OpenImageIO's default (EXR: zip, lossless); PNG and TIFF are not written by it.
        return None
    if ext == ".png":
        if isinstance(compression, bool) or not isinstance(compression, (int, np.integer)) \
                or not 0 <= compression <= 9:
            raise ValueError(f"compression for .png must be a zlib level 0-9, got {compression!r:.80}")
        return ("png:compressionLevel", int(compression))
    codecs = _COMPRESSIONS.get(ext)
    if codecs is None:
        raise ValueError(f"compression is not supported for {ext} files (only .png levels 0-9, "
                         f"and codecs for .exr and .tif)")
    if compression not in codecs:
        raise ValueError(f"compression for {ext} must be one of {codecs}, got {compression!r:.80}")
    return ("compression", str(compression))
# Deflate expands at most 1032:1, so a PNG of n bytes decodes to at most ~1032 n bytes (plus one
# filter byte per row). A header claiming more is corrupt => refuse before allocating pixels.
_PNG_MAX_RATIO = 1032


def _suggest(dtype: np.dtype) -> str:
    if dtype == _F32:
        return "use .exr or .tif for float data"
    return "use .png or .tif for uint8/uint16 data (or convert to float32 for .exr)"


def imwrite(path: str | os.PathLike[str], array: npt.ArrayLike, compression: str | int | None = None) -> None:
    """Write ``array`` to ``path`` atomically; the format follows the file extension.

    Files are reproducible: the same array gives the same bytes (no write time in EXR or TIFF
    headers; softrast's encoder gives the same bytes on every machine). The file is written under
    a temporary name in the same directory and renamed into place, so an interrupted write never
    leaves a partial file. docs/file_formats.md, "Image files", has the details.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write; its extension picks the format.
    array : array_like
        (h, w), (h, w, 1), (h, w, 3) or (h, w, 4) (.exr and .tif: (h, w, 2) too); row 0 is the top
        of the image. dtype uint8, uint16, float32, float64 (stored as float32) or bool (stored as
        uint8 0/255); .tif also stores int32 and uint32. Channels are stored as given (gray, RGB,
        RGBA); RGBA is not premultiplied on the way.
    compression : str or int, optional
        None (the default: .png and .tif by softrast's own encoder, deflated, the fastest;
        OpenImageIO's default otherwise, zip for .exr) or, through OpenImageIO, for .png a zlib
        level 0-9 (0 = stored; 9 = smallest and slowest); for .exr one of "none", "rle", "zips",
        "zip", "piz", "pxr24" (lossy for float32: 24 bits), "b44", "b44a", "dwaa", "dwab" (lossy);
        for .tif "none", "lzw", "zip", "packbits". Lossless ones round-trip exactly.

    Raises
    ------
    TypeError
        For a dtype not listed above.
    ValueError
        For a shape or compression the format does not take. Formats are never asked to
        quantize: float data to an 8-bit format such as PNG raises ValueError (use .exr or .tif).
    """
    import OpenImageIO as oiio

    path_str = os.fspath(path)
    arr = np.asarray(array)
    if arr.dtype == np.bool_:
        arr = arr.view(np.uint8) * np.uint8(255)
    elif arr.dtype == np.float64:
        arr = arr.astype(np.float32)
    if arr.dtype not in _OIIO_TYPE:
        raise TypeError(f"array dtype must be uint8, uint16, float32, float64 or bool (or int32 / "
                        f"uint32 for .tif), got {arr.dtype}")
    if arr.ndim == 2:
        arr = arr[:, :, np.newaxis]  # OpenImageIO mis-writes 2-D arrays => always pass (h, w, c)
    any_channels = os.path.splitext(os.fspath(path_str))[1].lower() in _ANY_CHANNELS
    if arr.ndim != 3 or arr.shape[2] not in ((1, 2, 3, 4) if any_channels else (1, 3, 4)):
        raise ValueError(
            f"array must have shape (h, w), (h, w, 1), (h, w, 3) or (h, w, 4) (or (h, w, 2) for "
            f".exr and .tif), got {np.shape(array)}")
    h, w, c = arr.shape
    if h == 0 or w == 0:
        raise ValueError(f"array is empty: shape {np.shape(array)}")

    directory, name = os.path.split(os.path.abspath(path_str))
    ext = os.path.splitext(name)[1].lower()
    if not ext:
        raise ValueError(f"path {path_str!r} has no file extension to choose an image format")
    allowed = _FORMAT_DTYPES.get(ext)
    if allowed is not None and arr.dtype not in allowed:
        raise ValueError(
            f"cannot store {arr.dtype} data in a {ext} file without converting it; {_suggest(arr.dtype)}")
    compression_attr = _compression_attribute(ext, compression)
    channels = _FORMAT_CHANNELS.get(ext)
    if channels is not None and c not in channels:
        raise ValueError(f"a {ext} file cannot store {c} channels (allowed: {sorted(channels)}); "
                         "use .png, .tif or .exr")
    if compression is None and ext in _OWN_ENCODER:
        _write_bytes(path_str, _OWN_ENCODER[ext](arr))
        return
    out = oiio.ImageOutput.create(path_str)
    if out is None:
        msg = oiio.geterror()  # always retrieve, or OpenImageIO prints it at exit
        raise ValueError(f"path {path_str!r}: unknown image format {ext!r} ({msg})")
    if not os.path.isdir(directory):
        raise FileNotFoundError(errno.ENOENT, "directory does not exist", directory)

    arr = np.ascontiguousarray(arr)
    with _replacing(path_str, ext) as tmp_path:
        spec = oiio.ImageSpec(w, h, c, _OIIO_TYPE[arr.dtype])
        # Store pixels as given: without this, PNG writers divide colour by alpha (unpremultiply).
        spec.attribute("oiio:UnassociatedAlpha", 1)
        spec.attribute("DateTime", "")  # else EXR and TIFF headers carry the time: not reproducible
        if compression_attr is not None:
            spec.attribute(*compression_attr)
        if not out.open(tmp_path, spec):
            raise OSError(f"could not open {path_str!r} for writing: {out.geterror()}")
        ok = out.write_image(arr)
        err = out.geterror()
        closed = out.close()
        if not ok or not closed:
            raise OSError(f"could not write {path_str!r}: {err or out.geterror()}")


@contextlib.contextmanager
def _replacing(path: str, suffix: str) -> Iterator[str]:
    """A temporary name beside ``path`` (``.{name}.{pid}-{id}.tmp{suffix}``) to write to; renamed
    onto ``path`` when the block ends, removed if it raises, so an interrupted write never leaves
    a partial file. The same directory: os.replace is then an atomic rename. A fresh name rather
    than mkstemp: the file gets the usual permissions, not 0600."""
    directory, name = os.path.split(os.path.abspath(path))
    tmp_path = os.path.join(directory, f".{name}.{os.getpid()}-{uuid.uuid4().hex[:12]}.tmp{suffix}")
    try:
        yield tmp_path
        os.replace(tmp_path, path)
    except BaseException:
        try:
            os.remove(tmp_path)
        except FileNotFoundError:
            pass
        raise


# TIFF SampleFormat of each dtype the TIFF encoder takes: unsigned, signed, float.
_TIFF_SAMPLE = {_U8: 1, _U16: 1, _U32: 1, _I32: 2, _F32: 3}


def encode_png(array: np.ndarray) -> bytes:
    """PNG file bytes of a uint8 or uint16 (h, w) or (h, w, 1-4) array.

    softrast's encoder: a filter per row and one deflate block of literals and runs; the GIL
    released.

    Parameters
    ----------
    array : ndarray

    Returns
    -------
    bytes
    """
    return _core.encode_png(_rows_contiguous(array))


def encode_tiff(array: np.ndarray, compress: bool = True) -> bytes:
    """TIFF file bytes of an (h, w) or (h, w, 1-4) array of uint8, uint16, uint32, int32 or float32.

    One strip; deflated (Adobe deflate) when ``compress``, integer samples after the horizontal
    predictor (which every TIFF reader undoes), float samples without a predictor (tifffile needs
    imagecodecs for the floating-point one, so scikit-image may not read it).

    Parameters
    ----------
    array : ndarray
    compress : bool, optional
        Deflate (default True).

    Returns
    -------
    bytes

    Raises
    ------
    TypeError
        For another dtype.
    """
    arr = _rows_contiguous(array)
    if arr.dtype not in _TIFF_SAMPLE:
        raise TypeError(f"array dtype must be uint8, uint16, uint32, int32 or float32, got {arr.dtype}")
    predictor = 2 if compress and arr.dtype != _F32 else 1
    return _core.encode_tiff(arr, _TIFF_SAMPLE[arr.dtype], bool(compress), predictor)


def _rows_contiguous(array: np.ndarray) -> np.ndarray:
    # the encoders take any row stride but need each row's pixels packed
    a = np.asarray(array)
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[:, :, 0]
    if a.strides[-1] != a.itemsize or a.strides[0] < 0 or \
            (a.ndim == 3 and a.strides[1] != a.itemsize * a.shape[2]):
        a = np.ascontiguousarray(a)
    return a


_OWN_ENCODER = {".png": encode_png, ".tif": encode_tiff, ".tiff": encode_tiff}


def _write_bytes(path: str | os.PathLike[str], data: bytes, suffix: str | None = None) -> None:
    """An encoded file's bytes to ``path``, atomically (as imwrite writes); its temporary ends
    with ``suffix`` (default: the file's extension)."""
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        raise FileNotFoundError(errno.ENOENT, "directory does not exist", directory)
    ext = os.path.splitext(path)[1].lower() if suffix is None else suffix
    with _replacing(path, ext) as tmp_path:
        # os.open and os.write: no buffered file object, whose set-up costs syscalls per file
        fd = os.open(tmp_path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
        finally:
            os.close(fd)


def _check_png_size(path_str: str) -> None:
    """Refuse a PNG whose IHDR claims more pixel data than its compressed size can hold."""
    with open(path_str, "rb") as f:
        head = f.read(29)  # signature (8), IHDR length + type (8), width, height, depth, colour
        file_size = os.fstat(f.fileno()).st_size
    if len(head) < 29 or head[12:16] != b"IHDR":
        return  # OpenImageIO parsed it, so let it decode (and report) whatever this is
    width, height = int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
    samples = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}.get(head[25], 4)  # per pixel, by colour type
    # Pixel data alone (no filter bytes) is a lower bound on the inflated stream, interlaced or not.
    data = height * ((width * samples * head[24] + 7) // 8)
    if data > _PNG_MAX_RATIO * file_size:
        raise ValueError(
            f"image {path_str!r}: the header claims {width}x{height} pixels ({data} bytes of "
            f"pixel data), more than a {file_size}-byte PNG can hold: corrupt or truncated")


def _decoded_bytes(spec: Any) -> int:
    """Bytes ``read_image(format="unknown")`` allocates for the first subimage of ``spec``."""
    if spec.width <= 0 or spec.height <= 0 or spec.depth <= 0 or spec.nchannels <= 0:
        raise ValueError(f"image size {spec.width}x{spec.height}x{spec.nchannels} is not positive")
    sizes = [f.size() for f in spec.channelformats] or [spec.format.size()] * spec.nchannels
    return spec.width * spec.height * spec.depth * max(sizes) * spec.nchannels


def imread(path: str | os.PathLike[str]) -> np.ndarray:
    """Read an image file in its stored pixel type.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    ndarray
        (h, w, c) with the file's own dtype (uint8, uint16, float32, ...), or (h, w) when the file
        has one channel; row 0 is the top of the image. Values are as stored (colour is not
        premultiplied by alpha). Multi-part files: the first part.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        Naming the file and giving the decoder's message, if it cannot be decoded, or the decoder
        reports an error while decoding it (a truncated or damaged file), or if its header declares
        more pixel bytes than ``softrast.get_memory_budget()`` (checked before any pixel is read).
    """
    import OpenImageIO as oiio

    path_str = os.fspath(path)
    if not os.path.isfile(path_str):
        raise FileNotFoundError(errno.ENOENT, "image file not found", path_str)
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)  # return stored values, not premultiplied by alpha
    inp = oiio.ImageInput.open(path_str, config)
    if inp is None:
        raise ValueError(f"could not read image {path_str!r}: {oiio.geterror()}")
    try:
        spec = inp.spec()  # the header only: nothing is decoded yet
        nbytes = _decoded_bytes(spec)
        check_budget(nbytes, f"image {path_str!r} ({spec.width}x{spec.height}x{spec.nchannels} "
                             f"{spec.format})")
        if inp.format_name() == "png":
            _check_png_size(path_str)
        pixels: Any = inp.read_image(format="unknown")  # "unknown" => keep the native pixel type
        # A damaged file (a truncated JPEG, flipped bytes) can still return pixels, mostly grey:
        # the decoder reports it as an error beside them, so any reported error refuses the image.
        failed = inp.has_error
        err = inp.geterror()  # always retrieve, or OpenImageIO prints it at exit
    finally:
        inp.close()
    if failed or err or pixels is None or not isinstance(pixels, np.ndarray):
        raise ValueError(f"could not read image {path_str!r}: {err.strip() or 'no pixel data'}")
    if pixels.ndim == 2:  # defensive: OpenImageIO returns (h, w, c), but be explicit
        return pixels
    return pixels[:, :, 0] if pixels.shape[2] == 1 else pixels
