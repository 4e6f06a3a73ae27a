"""softrast's own PNG and TIFF encoder (cpp/encode.cpp) against independent decoders.

- The deflate stream (``_core.zlib_compress``) against Python's zlib: every edge of the run
  coding (runs of 1..600 bytes, the 258-byte match limit and its neighbours, 1 MB of zeros),
  incompressible data (stored blocks, within n + 5 per 65535 + 6 bytes), code lengths that the
  15-bit limit must cut (Fibonacci frequencies), a property test over runs and literals; the
  zlib header, the adler32 trailer (zlib.adler32) and no trailing bytes.
- PNG and TIFF files read back exactly, bit for bit (floats by their bits: NaN payloads, +-inf,
  -0.0), by every reader that supports the layout: OpenImageIO (softrast.imread), OpenCV,
  scikit-image, imageio, Pillow and tifffile (SUPPORT, measured: the readers each layout is
  asserted for, so a regression in our files shows); their structure (chunk CRCs, filter
  types, TIFF tags) checked directly.
- Frame.save / Frame.load of a real render with the default formats: bit-exact, read by OpenCV
  and scikit-image too, the same bytes twice; ids outside -1..65534 fall back to TIFF, or are
  refused by name when png16 is forced.
- Layouts (flipped, strided, Fortran-order, (h, w, 1), 1x1, a large image) give the same pixels
  and the same bytes; bad input raises ValueError / TypeError, never crashes.
- The same bytes everywhere: sha256 of fixed images (no zlib involved, so no zlib version in it),
  and from 4 threads at once; the GIL is released while encoding.
"""
from __future__ import annotations

import hashlib
import heapq
import io as pyio
import struct
import threading
import zlib

import cv2
import imageio.v3 as iio
import numpy as np
import pytest
import skimage.io
import tifffile
import trimesh
from hypothesis import given, settings, strategies as st
from PIL import Image

import softrast as sr
from softrast import _core
from softrast.io import encode_png, encode_tiff
from support.gil_probe import calls_that_let_python_run

# --- helpers --------------------------------------------------------------------------------


def inflate(stream: bytes) -> bytes:
    """The data of a zlib stream, checked: a valid header (deflate, 32 KiB window, check bits),
    the adler32 trailer (zlib verifies it), the stream complete and nothing after it."""
    assert len(stream) >= 6
    cmf, flg = stream[0], stream[1]
    assert cmf & 0x0F == 8 and cmf >> 4 <= 7, stream[:2]  # deflate, window <= 32 KiB
    assert (cmf << 8 | flg) % 31 == 0 and not flg & 0x20, stream[:2]  # check bits, no dictionary
    d = zlib.decompressobj()
    data = d.decompress(stream) + d.flush()
    assert d.eof and d.unused_data == b"" and d.unconsumed_tail == b""
    assert stream[-4:] == zlib.adler32(data).to_bytes(4, "big")
    return data


class _Bits:
    """Deflate's bit order: least significant bit of each byte first."""

    def __init__(self, data: bytes) -> None:
        self.data, self.pos = data, 0

    def get(self, n: int) -> int:
        v = 0
        for k in range(n):
            v |= (self.data[self.pos >> 3] >> (self.pos & 7) & 1) << k
            self.pos += 1
        return v

    def symbol(self, table: dict[tuple[int, int], int]) -> int:
        code = 0
        for length in range(1, 16):
            code = code << 1 | self.get(1)  # Huffman codes are packed from their first bit
            if (length, code) in table:
                return table[(length, code)]
        raise AssertionError("no Huffman code matches")


def _canonical(lengths: list[int]) -> dict[tuple[int, int], int]:
    """RFC 1951 3.2.2: {(length, code): symbol}."""
    table, code = {}, 0
    for length in range(1, 16):
        for s, n in enumerate(lengths):
            if n == length:
                table[(length, code)] = s
                code += 1
        code <<= 1
    return table


_CL_ORDER = (16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15)


def first_block(stream: bytes) -> tuple[int, int, list[int], list[int]]:
    """(BFINAL, BTYPE, literal/length code lengths, distance code lengths) of the first deflate
    block of a zlib stream (the code lengths of a dynamic block only; else empty)."""
    b = _Bits(stream[2:])
    final, btype = b.get(1), b.get(2)
    if btype != 2:
        return final, btype, [], []
    hlit, hdist, hclen = b.get(5) + 257, b.get(5) + 1, b.get(4) + 4
    cl = [0] * 19
    for k in range(hclen):
        cl[_CL_ORDER[k]] = b.get(3)
    table = _canonical(cl)
    lengths: list[int] = []
    while len(lengths) < hlit + hdist:
        s = b.symbol(table)
        if s < 16:
            lengths.append(s)
        elif s == 16:
            lengths += [lengths[-1]] * (3 + b.get(2))
        elif s == 17:
            lengths += [0] * (3 + b.get(3))
        else:
            lengths += [0] * (11 + b.get(7))
    assert len(lengths) == hlit + hdist
    return final, btype, lengths[:hlit], lengths[hlit:]


def kraft(lengths: list[int]) -> float:
    return sum(2.0 ** -n for n in lengths if n)


def stored_bound(n: int) -> int:
    """Bytes of a zlib stream of n bytes in stored blocks: header, 5 per block, adler32."""
    return n + 5 * max(1, -(-n // 65535)) + 6


DEFLATE_BLOCK = 2 * 65535  # zlib_compress deflates pieces of this many bytes (encode.hpp)


def check_deflate(data: bytes) -> bytes:
    """zlib_compress(data), checked: it decodes to data, its first block a dynamic Huffman block
    with complete codes (final when data fits one piece), or stored blocks, no longer than the
    stored bound."""
    z = _core.zlib_compress(data)
    assert inflate(z) == data
    final, btype, lit, dist = first_block(z)
    assert btype in (0, 2), btype
    if btype == 2:
        assert final == (len(data) <= DEFLATE_BLOCK)
        assert kraft(lit) == 1.0 and kraft(dist) == 1.0 and max(lit) <= 15
        assert len(z) < stored_bound(len(data))
    else:
        assert len(z) <= stored_bound(len(data))
    return z


def huffman_depth(counts) -> int:
    """The longest code of an optimal (unlimited) Huffman code for these counts."""
    heap = [(int(c), 0) for c in counts if c]
    heapq.heapify(heap)
    while len(heap) > 1:
        w1, d1 = heapq.heappop(heap)
        w2, d2 = heapq.heappop(heap)
        heapq.heappush(heap, (w1 + w2, max(d1, d2) + 1))
    return heap[0][1]


def no_two_alike(counts: dict[int, int]) -> bytes:
    """The bytes with these counts arranged so that no two neighbours are equal (no runs: every
    byte is a literal): the commonest first, on even places, then odd ones."""
    order = [b for b, c in sorted(counts.items(), key=lambda kv: -kv[1]) for _ in range(c)]
    n = len(order)
    out = np.empty(n, np.uint8)
    places = list(range(0, n, 2)) + list(range(1, n, 2))
    out[places] = order
    assert (out[1:] != out[:-1]).all()
    return out.tobytes()


# Readers, each returning the array as the file stores it: OpenCV's channels put back in RGB(A)
# order; one channel as (h, w).
def _read_oiio(path):
    return sr.imread(path)


def _read_cv2(path):
    a = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert a is not None, f"cv2 could not read {path}"
    if a.ndim == 3:
        a = a[:, :, [2, 1, 0, 3][:a.shape[2]]]  # BGR(A) -> RGB(A)
    return a


def _decode_cv2(data: bytes) -> np.ndarray:
    a = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    assert a is not None
    return a[:, :, [2, 1, 0, 3][:a.shape[2]]] if a.ndim == 3 else a


def _read_skimage(path):
    return skimage.io.imread(str(path))


def _read_imageio(path):
    return iio.imread(path)


def _read_pillow(path):
    with Image.open(path) as im:
        return np.asarray(im)


READERS = {"oiio": _read_oiio, "cv2": _read_cv2, "skimage": _read_skimage, "imageio": _read_imageio,
           "pillow": _read_pillow, "tifffile": tifffile.imread}

PNG5 = ("oiio", "cv2", "skimage", "imageio", "pillow")
TIF6 = PNG5 + ("tifffile",)
TIF_NO_PILLOW = ("oiio", "cv2", "skimage", "imageio", "tifffile")
TIF_2CH = ("oiio", "skimage", "imageio", "tifffile")  # OpenCV and Pillow have no grey + extra
# The readers that decode each layout exactly, as measured (OpenCV 5.0, scikit-image 0.26,
# imageio 2.38, Pillow 13, tifffile 2026.3, OpenImageIO 3.2). Not listed, by the readers' own
# limits: 16-bit RGB(A) PNG in Pillow (and so imageio and scikit-image, which read PNG through
# it) comes back 8-bit; Pillow opens no multi-channel TIFF beyond 8 bits, and uint32 as int32;
# OpenCV reads 8-bit RGBA TIFF through libtiff's RGBA interface, which premultiplies the alpha,
# and refuses two channels.
SUPPORT: dict[tuple[str, str, int], tuple[str, ...]] = {
    ("png", "uint8", 1): PNG5, ("png", "uint8", 3): PNG5, ("png", "uint8", 4): PNG5,
    ("png", "uint16", 1): PNG5, ("png", "uint16", 3): ("oiio", "cv2"), ("png", "uint16", 4): ("oiio", "cv2"),
    ("tif", "uint8", 1): TIF6, ("tif", "uint8", 2): TIF_2CH, ("tif", "uint8", 3): TIF6,
    ("tif", "uint8", 4): TIF_2CH + ("pillow",),
    ("tif", "uint16", 1): TIF6, ("tif", "uint16", 2): TIF_2CH, ("tif", "uint16", 3): TIF_NO_PILLOW,
    ("tif", "uint16", 4): TIF_NO_PILLOW,
    ("tif", "int32", 1): TIF6, ("tif", "int32", 2): TIF_2CH, ("tif", "int32", 3): TIF_NO_PILLOW,
    ("tif", "int32", 4): TIF_NO_PILLOW,
    ("tif", "uint32", 1): TIF_NO_PILLOW, ("tif", "uint32", 2): TIF_2CH, ("tif", "uint32", 3): TIF_NO_PILLOW,
    ("tif", "uint32", 4): TIF_NO_PILLOW,
    ("tif", "float32", 1): TIF6, ("tif", "float32", 2): TIF_2CH, ("tif", "float32", 3): TIF_NO_PILLOW,
    ("tif", "float32", 4): TIF_NO_PILLOW,
}
READ_CASES = [(fmt, dtype, ch, reader) for (fmt, dtype, ch), readers in SUPPORT.items() for reader in readers]

SHAPES = ((37, 53), (1, 1), (1, 1000), (1000, 1))  # odd sizes, one pixel, one row, one column
# float32 bit patterns every reader must keep: quiet NaN, a NaN with a payload, a negative NaN, a
# signalling NaN, +-inf, -0.0, 0, the smallest subnormal, +-max
FLOAT_SPECIALS = np.array([0x7FC00000, 0x7FC00001, 0xFFC00000, 0x7F800001, 0x7F800000, 0xFF800000,
                           0x80000000, 0, 1, 0x7F7FFFFF, 0xFF7FFFFF], np.uint32).view(np.float32)


def make_image(shape, dtype, channels, seed=0) -> np.ndarray:
    """Random samples with the extremes (0 and the maximum, the minimum of signed types; the
    float specials), some flat rows, a row repeating the one above and runs within rows."""
    rng = np.random.default_rng(seed)
    h, w = shape
    full = (h, w, channels)
    dtype = np.dtype(dtype)
    if dtype.kind == "f":
        a = (rng.normal(size=full) * 1000.0).astype(dtype)
        flat = a.reshape(-1)
        flat[:len(FLOAT_SPECIALS)] = FLOAT_SPECIALS[:flat.size]
        flat[-len(FLOAT_SPECIALS):] = FLOAT_SPECIALS[-flat.size:]
    else:
        info = np.iinfo(dtype)
        a = rng.integers(info.min, info.max, size=full, endpoint=True, dtype=dtype)
        flat = a.reshape(-1)
        flat[:4] = (info.min, info.max, 0, info.max)[:flat.size]
        flat[-2:] = (info.max, info.min)[-flat.size:]
    if h > 4:
        a[1] = a[1, :1]          # a flat row
        a[3] = a[2]              # a row repeating the one above
    if w > 20:
        a[:, 5:20] = a[:, 4:5]   # runs within each row
    return a


def _same(got: np.ndarray, want: np.ndarray, what: str) -> None:
    """got equals want exactly: dtype, shape and every bit (floats compared as uint32)."""
    if want.ndim == 3 and want.shape[2] == 1:
        want = want[:, :, 0]
    assert got.dtype == want.dtype and got.shape == want.shape, (what, got.dtype, got.shape, want.shape)
    if want.dtype == np.float32:
        got, want = got.view(np.uint32), want.view(np.uint32)
    np.testing.assert_array_equal(got, want, err_msg=what)


def png_chunks(data: bytes) -> list[tuple[bytes, bytes]]:
    """The chunks (type, data) of a PNG file, each one's CRC checked; IEND last and nothing after."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    chunks, at = [], 8
    while at < len(data):
        n, kind = struct.unpack(">I4s", data[at:at + 8])
        body = data[at + 8:at + 8 + n]
        assert len(body) == n
        assert struct.unpack(">I", data[at + 8 + n:at + 12 + n])[0] == zlib.crc32(kind + body), kind
        chunks.append((kind, body))
        at += 12 + n
    assert at == len(data) and chunks[0][0] == b"IHDR" and chunks[-1] == (b"IEND", b"")
    return chunks


def check_png_structure(data: bytes, shape, dtype, channels) -> None:
    chunks = png_chunks(data)
    w, h, depth, colour, method, filt, interlace = struct.unpack(">IIBBBBB", chunks[0][1])
    assert (h, w) == tuple(shape) and depth == 8 * np.dtype(dtype).itemsize
    assert colour == {1: 0, 2: 4, 3: 2, 4: 6}[channels] and (method, filt, interlace) == (0, 0, 0)
    assert [k for k, _ in chunks] == [b"IHDR"] + [b"IDAT"] * (len(chunks) - 2) + [b"IEND"]
    raw = inflate(b"".join(body for k, body in chunks if k == b"IDAT"))
    row = 1 + w * channels * np.dtype(dtype).itemsize
    assert len(raw) == h * row
    filters = raw[::row]
    assert filters[0] == 1 and set(filters[1:]) <= {2, 4}, filters  # Sub, then Up or Paeth


def check_tiff_structure(data: bytes, shape, dtype, channels, compress=True, predictor=None) -> None:
    dtype = np.dtype(dtype)
    if predictor is None:
        predictor = (2 if dtype.kind in "iu" else 1) if compress else 1
    assert data[:4] == b"II*\x00"
    with tifffile.TiffFile(pyio.BytesIO(data)) as tf:
        assert len(tf.pages) == 1
        page = tf.pages[0]
        assert page.shape[:2] == tuple(shape) and page.samplesperpixel == channels
        assert page.dtype == dtype and page.planarconfig == 1 and len(page.dataoffsets) == 1
        assert page.compression == (8 if compress else 1)  # Adobe deflate or none
        assert page.predictor == predictor
        assert page.photometric == (2 if channels >= 3 else 1)  # RGB or min-is-black
        if compress:
            start, size = page.dataoffsets[0], page.databytecounts[0]
            n = inflate(data[start:start + size])
            assert len(n) == shape[0] * shape[1] * channels * dtype.itemsize


def _frame(instance_id=5, width=64, height=48) -> sr.Frame:
    tm = trimesh.creation.icosphere(subdivisions=3)
    scene = sr.Scene()
    scene.add(sr.Mesh(tm.vertices, tm.faces, uvs=np.asarray(tm.vertices)[:, :2] * 0.5 + 0.5),
              instance_id=instance_id)
    cam = sr.PerspectiveCamera(fov_y=45.0, width=width, height=height)
    cam.look_at((0.0, 0.5, 3.0), (0.0, 0.0, 0.0))
    return sr.Renderer(width, height).render(scene, cam, outputs=sr.OUTPUTS)


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a).view(np.uint8)


# --- 1. the deflate stream against zlib --------------------------------------------------------


@pytest.mark.parametrize("data", [b"", b"\x00", b"\xff", b"ab", b"aa", b"aaa", b"aaaa", b"aaaaa",
                                  bytes(range(256)), bytes(range(256)) * 100, bytes(range(255, -1, -1)) * 3,
                                  b"\x00\xff" * 50_000, b"ab" * 7 + b"c" * 300 + b"ab" * 7],
                         ids=lambda d: f"{len(d)}B")
def test_deflate_edge_cases(data):
    check_deflate(data)


def test_deflate_runs_of_every_length():
    # A run after a different byte (a match at distance 1 from the start of the run) and at the
    # start of the stream (the first byte is a literal, the rest a match), followed or not.
    for length in range(1, 601):
        for data in (b"\x07" + b"\x2a" * length, b"\x2a" * length, b"\x07" + b"\x2a" * length + b"\x07",
                     b"\x2a" * length + b"\x07\x08"):
            assert inflate(_core.zlib_compress(data)) == data, length


@pytest.mark.parametrize("length", [257, 258, 259, 260, 261, 262, 515, 516, 517, 518, 519, 774, 775, 776])
def test_deflate_runs_around_the_longest_match(length):
    # 258 is the longest match: longer runs are split, never leaving 1 or 2 bytes for a match
    for data in (b"\x01" + b"\x00" * length, b"\x00" * length, b"xyz" + b"\x00" * length + b"q" * length):
        check_deflate(data)


def test_deflate_long_runs():
    zeros = bytes(1 << 20)
    z = check_deflate(zeros)
    assert len(z) < (1 << 20) // 1000 + 32 * -(-(1 << 20) // DEFLATE_BLOCK), len(z)  # runs cost ~1 bit per 258 bytes
    check_deflate(b"\xff" * 1_000_003 + b"\x00" + b"\xff" * 70_000)
    check_deflate(b"".join(bytes([k]) * (1000 + 37 * k) for k in range(256)))


@pytest.mark.parametrize("n", [1, 100, 65534, 65535, 65536, 131070, 131071, 200_000, 1_000_000])
def test_deflate_incompressible_falls_back_to_stored_blocks(n):
    data = np.random.default_rng(n).integers(0, 256, n, dtype=np.uint8).tobytes()
    z = check_deflate(data)
    assert len(z) <= stored_bound(n), (len(z), stored_bound(n))
    assert first_block(z)[1] == 0  # stored


def test_deflate_random_with_runs_is_dynamic():
    rng = np.random.default_rng(7)
    data = rng.integers(0, 256, 300_000, dtype=np.uint8)
    data[::3] = data[1::3]  # every third byte repeats its neighbour: short runs
    data[100_000:180_000] = 9
    z = check_deflate(data.tobytes())
    assert first_block(z)[1] == 2


def _fibonacci(n: int) -> list[int]:
    """1, 2, 3, 5, 8, ... (n of them): with the end of block's 1, each code a bit longer."""
    f = [1, 2]
    while len(f) < n:
        f.append(f[-1] + f[-2])
    return f[:n]


@pytest.mark.parametrize("name, counts", [
    ("fibonacci", dict(zip(range(0, 256, 11), _fibonacci(20)))),
    ("powers of two", {b: 1 << k for k, b in enumerate(range(3, 3 + 18))}),
    ("fibonacci over every byte", {b: _fibonacci(26)[min(b, 25)] if b < 26 else 1 for b in range(256)}),
])
def test_deflate_code_lengths_over_15_bits_are_limited(name, counts):
    data = no_two_alike(counts)
    # the optimal code (these literals and the end of block) needs codes longer than 15 bits
    assert huffman_depth(list(counts.values()) + [1]) > 15
    z = check_deflate(data)
    final, btype, lit, dist = first_block(z)
    assert btype == 2 and max(lit) <= 15 and kraft(lit) == 1.0, (btype, max(lit))


@pytest.mark.parametrize("n", [0, 1, 15, 16, 17, 31, 5551, 5552, 5553, 5552 * 3 + 7, 5552 * 16 + 15, 100_003])
@pytest.mark.parametrize("fill", ["0xff", "random"])
def test_adler32_at_block_edges(n, fill):
    # adler32 sums 16 bytes at a time in blocks of 5552 (SSE2 on x86-64); all-0xFF bytes make the
    # largest sums, where an overflow would show
    data = b"\xff" * n if fill == "0xff" else np.random.default_rng(n).integers(0, 256, n, dtype=np.uint8).tobytes()
    z = _core.zlib_compress(data)
    assert z[-4:] == zlib.adler32(data).to_bytes(4, "big")
    assert inflate(z) == data


@st.composite
def structured_buffers(draw):
    """Concatenated segments: runs of one byte (1 to 70,000) and random literals (1 to 5,000
    bytes from a drawn seed, over alphabets of 1 to 256 values), up to ~200 kB in all."""
    parts, total = [], 0
    for kind, byte, length, seed in draw(st.lists(st.tuples(
            st.sampled_from(["run", "literals"]), st.integers(0, 255),
            st.one_of(st.integers(1, 600), st.integers(1, 70_000)), st.integers(0, 2**32 - 1)),
            max_size=24)):
        if kind == "literals":
            length = min(length, 5000)
            alphabet = 1 + seed % 256  # small ones make short runs (2-4 bytes, coded as literals)
            parts.append(np.random.default_rng(seed).integers(0, alphabet, length, dtype=np.uint8).tobytes())
        else:
            parts.append(bytes([byte]) * length)
        total += length
        if total >= 200_000:
            break
    return b"".join(parts)[:200_000]


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(structured_buffers())
def test_deflate_property(data):
    check_deflate(data)


def test_deflate_takes_any_contiguous_buffer():
    a = np.arange(1000, dtype=np.int32)
    assert inflate(_core.zlib_compress(a)) == a.tobytes()
    assert inflate(_core.zlib_compress(memoryview(b"abcabc" * 9))) == b"abcabc" * 9
    assert inflate(_core.zlib_compress(bytearray(b"\x00" * 999))) == b"\x00" * 999
    with pytest.raises(TypeError):
        _core.zlib_compress("text")


def test_deflate_of_a_strided_buffer_is_refused_or_exact():
    a = np.arange(10, dtype=np.uint8)[::2]  # in bounds either way: the first 5 bytes of 10
    try:
        z = _core.zlib_compress(a)
    except (ValueError, TypeError, BufferError):
        return
    assert inflate(z) == a.tobytes()


# --- 2. PNG and TIFF files against every reader -------------------------------------------------


@pytest.mark.parametrize("fmt, dtype, channels, reader", READ_CASES,
                         ids=[f"{f}-{d}-{c}ch-{r}" for f, d, c, r in READ_CASES])
def test_files_decode_exactly(tmp_path, fmt, dtype, channels, reader):
    for k, shape in enumerate(SHAPES):
        a = make_image(shape, dtype, channels, seed=k)
        path = tmp_path / f"{k}.{fmt}"
        sr.imwrite(path, a)
        got = READERS[reader](path)
        _same(np.asarray(got), a, f"{fmt} {dtype} {channels}ch {shape} by {reader}")


@pytest.mark.parametrize("fmt, dtype, channels", list(SUPPORT))
def test_file_structure_and_bytes(tmp_path, fmt, dtype, channels):
    """imwrite writes the encoder's bytes; PNG chunks, filters and TIFF tags are as documented."""
    for k, shape in enumerate(SHAPES):
        a = make_image(shape, dtype, channels, seed=k)
        path = tmp_path / f"{k}.{fmt}"
        sr.imwrite(path, a)
        data = path.read_bytes()
        if fmt == "png":
            assert data == encode_png(a) == _core.encode_png(a if channels > 1 else a[:, :, 0])
            check_png_structure(data, shape, dtype, channels)
        else:
            assert data == encode_tiff(a)
            check_tiff_structure(data, shape, dtype, channels)
        if fmt == "tif":
            sr.imwrite(tmp_path / f"{k}.tiff", a)
            assert (tmp_path / f"{k}.tiff").read_bytes() == data


@pytest.mark.parametrize("dtype, channels", [(d, c) for f, d, c in SUPPORT if f == "tif"])
def test_uncompressed_tiff_decodes_exactly(tmp_path, dtype, channels):
    for k, shape in enumerate(SHAPES[:2]):
        a = make_image(shape, dtype, channels, seed=k)
        data = encode_tiff(a, compress=False)
        check_tiff_structure(data, shape, dtype, channels, compress=False)
        # the pixels stored as they are, after the header
        assert data[8:8 + a.nbytes] == a.astype(a.dtype.newbyteorder("<")).tobytes()
        path = tmp_path / f"{k}.tif"
        path.write_bytes(data)
        for reader in SUPPORT[("tif", dtype, channels)]:
            _same(np.asarray(READERS[reader](path)), a, f"uncompressed {dtype} {channels}ch {shape} by {reader}")


@pytest.mark.parametrize("channels", [1, 2, 3, 4])
def test_tiff_floating_point_predictor_decodes_exactly(tmp_path, channels):
    # (tifffile decodes it only through imagecodecs, which is not a test dependency)
    readers = ("oiio",) + (("cv2",) if channels != 2 else ())
    for k, shape in enumerate(SHAPES):
        a = make_image(shape, np.float32, channels, seed=k)
        data = _core.encode_tiff(a if channels > 1 else a[:, :, 0], 3, True, 3)
        check_tiff_structure(data, shape, np.float32, channels, predictor=3)
        path = tmp_path / f"{k}.tif"
        path.write_bytes(data)
        for reader in readers:
            _same(np.asarray(READERS[reader](path)), a, f"predictor 3 {channels}ch {shape} by {reader}")


def test_encoded_bytes_decode_from_memory():
    a = make_image((37, 53), np.uint8, 3)
    png = encode_png(a)
    np.testing.assert_array_equal(_decode_cv2(png), a)
    np.testing.assert_array_equal(iio.imread(png), a)
    with Image.open(pyio.BytesIO(png)) as im:
        np.testing.assert_array_equal(np.asarray(im), a)
    f = make_image((37, 53), np.float32, 1)
    _same(tifffile.imread(pyio.BytesIO(encode_tiff(f))), f, "tiff from memory")


# --- 3. Frame.save / Frame.load ---------------------------------------------------------------


def test_frame_save_defaults_read_back_exactly(tmp_path):
    frame = _frame()
    assert frame.instance_id.min() == -1 and frame.instance_id.max() == 5
    paths = frame.save(tmp_path, "f")
    assert set(paths) == set(sr.OUTPUTS)
    back = sr.Frame.load(tmp_path, "f")
    for name in sr.OUTPUTS:
        got, want = getattr(back, name), getattr(frame, name)
        assert got.dtype == want.dtype and got.shape == want.shape, name
        np.testing.assert_array_equal(_bits(got), _bits(want), err_msg=name)
    # and by other readers: depth (float32 TIFF), color (PNG, BGR in OpenCV), ids + 1 (PNG16)
    assert paths["depth"].endswith(".tif") and paths["color"].endswith(".png")
    assert paths["instance_id"].endswith(".png")
    for read in (_read_cv2, _read_skimage):
        _same(read(paths["depth"]), frame.depth, f"depth by {read.__name__}")
        _same(read(paths["color"]), frame.color, f"color by {read.__name__}")
        _same(read(paths["instance_id"]), (frame.instance_id + 1).astype(np.uint16),
              f"instance_id by {read.__name__}")
    raw = cv2.imread(paths["color"], cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(raw, frame.color[:, :, ::-1])  # OpenCV's own order is BGR


def test_frame_save_twice_gives_the_same_bytes(tmp_path):
    frame = _frame()
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    first, second = frame.save(tmp_path / "a", "f"), frame.save(tmp_path / "b", "f")
    for name in sr.OUTPUTS:
        with open(first[name], "rb") as f1, open(second[name], "rb") as f2:
            assert f1.read() == f2.read(), name


def test_frame_save_large_ids_fall_back_to_tiff(tmp_path):
    frame = _frame(instance_id=70000)
    paths = frame.save(tmp_path, "a")
    assert paths["instance_id"].endswith(".tif") and paths["triangle_id"].endswith(".png")
    _same(tifffile.imread(paths["instance_id"]), frame.instance_id, "ids in TIFF")
    np.testing.assert_array_equal(sr.Frame.load(tmp_path, "a").instance_id, frame.instance_id)
    with pytest.raises(ValueError, match="instance_id"):
        frame.save(tmp_path, "b", formats={"instance_id": "png16"})


@pytest.mark.parametrize("ids, png", [
    ([-1, 0, 65534], True),       # the whole range of id + 1 in 16 bits
    ([-1, 0, 65535], False),
    ([-5, 0, 3], False),          # negative ids other than -1 do not fit either
    ([-1, -2147483648, 1], False),
    ([2147483647], False),
])
def test_frame_save_ids_outside_the_png16_range(tmp_path, ids, png):
    arr = np.resize(np.array(ids, np.int32), (5, 7))
    frame = sr.Frame({"instance_id": arr, "triangle_id": arr.copy()})
    paths = frame.save(tmp_path, "f")
    for name in ("instance_id", "triangle_id"):
        assert paths[name].endswith(".png" if png else ".tif"), (name, paths[name])
        np.testing.assert_array_equal(getattr(sr.Frame.load(tmp_path, "f"), name), arr)
    if png:
        _same(_read_cv2(paths["instance_id"]), (arr + 1).astype(np.uint16), "id + 1")
    else:
        for name in ("instance_id", "triangle_id"):
            with pytest.raises(ValueError, match=name):
                frame.save(tmp_path, "g", formats={name: "png16"})
        with pytest.raises(ValueError, match="65534"):
            _core.encode_png_ids(arr)


# --- 4. layouts and bad input -------------------------------------------------------------------


@pytest.mark.parametrize("dtype, channels", [(np.uint8, 1), (np.uint8, 3), (np.uint8, 4), (np.uint16, 1),
                                             (np.uint16, 3), (np.float32, 2), (np.int32, 1)])
def test_layouts_give_the_same_pixels_and_bytes(tmp_path, dtype, channels):
    big = make_image((74, 106), dtype, channels, seed=3)
    encode = encode_tiff if np.dtype(dtype) in (np.float32, np.int32) else encode_png
    views = {
        "rows flipped": big[::-1], "columns flipped": big[:, ::-1], "both flipped": big[::-1, ::-1],
        "every other row": big[::2], "every other column": big[:, ::2], "a window": big[5:40, 3:60],
        "fortran": np.asfortranarray(big), "channels reversed": big[:, :, ::-1],
    }
    if channels == 1:
        assert encode(big) == encode(big[:, :, 0]) == encode(np.ascontiguousarray(big[:, :, 0]))
        views["(h, w)"] = big[:, :, 0]
        views["(h, w) fortran"] = np.asfortranarray(big[:, :, 0])
    for what, view in views.items():
        data = encode(view)
        assert data == encode(np.ascontiguousarray(view)), what
        path = tmp_path / ("x.png" if encode is encode_png else "x.tif")
        path.write_bytes(data)
        _same(sr.imread(path), np.ascontiguousarray(view), what)
        if view.ndim == 2 or view.shape[2] != 2:
            _same(_read_cv2(path), np.ascontiguousarray(view), what)


def test_core_takes_any_row_stride_and_refuses_unpacked_pixels():
    a = make_image((40, 30), np.uint8, 3)
    core = {"png": _core.encode_png, "tiff": lambda x: _core.encode_tiff(x, 1, True, 2)}
    for name, enc in core.items():
        for what, view in {"every other row": a[::2], "a window": a[7:33, 4:25],
                           "one row repeated (stride 0)": np.broadcast_to(a[5], a.shape)}.items():
            assert view.strides[1] == 3 and view.strides[2] == 1
            assert enc(view) == enc(np.ascontiguousarray(view)), (name, what)
        for what, view in {"rows flipped": a[::-1], "columns flipped": a[:, ::-1],
                           "every other column": a[:, ::2], "fortran": np.asfortranarray(a)}.items():
            with pytest.raises(ValueError, match="contiguous"):
                enc(view)


@pytest.mark.parametrize("dtype, channels", [(np.uint8, 1), (np.uint8, 2), (np.uint8, 3), (np.uint8, 4),
                                             (np.uint16, 1), (np.uint16, 4)])
def test_one_pixel_png(dtype, channels):
    for value in (0, np.iinfo(dtype).max, 77):
        a = np.full((1, 1, channels), value, dtype)
        data = encode_png(a)
        check_png_structure(data, (1, 1), dtype, channels)
        if channels != 2:  # OpenCV drops the alpha of grey + alpha
            _same(_decode_cv2(data), a, f"{value} by OpenCV")
        if dtype == np.uint8 or channels == 1:
            with Image.open(pyio.BytesIO(data)) as im:
                _same(np.asarray(im), a, f"{value} by Pillow")


def test_two_channel_png_reads_back(tmp_path):
    # grey + alpha (colour type 4): the encoder writes it, though imwrite offers (h, w, 2) for TIFF
    a = make_image((37, 53), np.uint8, 2)
    data = encode_png(a)
    check_png_structure(data, (37, 53), np.uint8, 2)
    with Image.open(pyio.BytesIO(data)) as im:
        assert im.mode == "LA"
        _same(np.asarray(im), a, "grey + alpha by Pillow")
    path = tmp_path / "la.png"
    path.write_bytes(data)
    _same(sr.imread(path), a, "grey + alpha by OpenImageIO")


def test_large_image_decodes_exactly(tmp_path):
    y, x = np.mgrid[0:3000, 0:2000]
    a = np.stack([x * 255 // 1999, y * 255 // 2999, (x + y) % 256], axis=-1).astype(np.uint8)
    a[1000:1010] = 255  # a white band
    data = encode_png(a)
    assert len(data) < a.nbytes // 4  # rows of a gradient filter to runs
    np.testing.assert_array_equal(_decode_cv2(data), a)
    t = encode_tiff(a.astype(np.uint16) * 257)
    np.testing.assert_array_equal(tifffile.imread(pyio.BytesIO(t)), a.astype(np.uint16) * 257)


@pytest.mark.parametrize("array, error", [
    (np.zeros((4, 4), np.float32), TypeError),
    (np.zeros((4, 4, 3), np.float64), TypeError),
    (np.zeros((4, 4), np.int64), TypeError),
    (np.zeros((4, 4, 5), np.uint8), ValueError),
    (np.zeros((4, 4, 3, 1), np.uint8), ValueError),
    (np.zeros((4,), np.uint8), ValueError),
    (np.zeros((0, 4), np.uint8), ValueError),
    (np.zeros((4, 0, 3), np.uint8), ValueError),
    (np.zeros((4, 4, 0), np.uint8), ValueError),
    ([[1, 2], [3, 4]], TypeError),
    (None, TypeError),
], ids=["float32", "float64", "int64", "5 channels", "4-D", "1-D", "no rows", "no columns",
        "no channels", "list", "None"])
def test_core_encode_png_refuses_bad_input(array, error):
    with pytest.raises(error):
        _core.encode_png(array)


@pytest.mark.parametrize("args, match", [
    ((np.zeros((4, 4), np.uint16), 1, True, 3), "floating-point predictor"),
    ((np.zeros((4, 4), np.int32), 2, True, 3), "floating-point predictor"),
    ((np.zeros((4, 4), np.float32), 3, True, 2), "horizontal predictor"),
    ((np.zeros((4, 4), np.float16), 3, True, 1), TypeError),
    ((np.zeros((4, 4), np.uint8), 0, True, 1), "sample_format"),
    ((np.zeros((4, 4), np.uint8), 1, True, 4), "predictor"),
    ((np.zeros((4, 4), np.float64), 3, True, 1), TypeError),
    ((np.zeros((4, 4, 5), np.uint8), 1, True, 2), "layout"),
    ((np.zeros((0, 4), np.uint8), 1, True, 2), None),
])
def test_core_encode_tiff_refuses_bad_input(args, match):
    # std::invalid_argument (and py::value_error) reach Python as ValueError; a dtype that does
    # not match sample_format is a TypeError
    if match is TypeError:
        with pytest.raises(TypeError, match="dtype"):
            _core.encode_tiff(*args)
        return
    with pytest.raises(ValueError, match=match):
        _core.encode_tiff(*args)


def test_tiff_predictor_is_ignored_when_stored():
    # compress=False stores the pixels as they are, whatever predictor is asked
    a = make_image((9, 11), np.float32, 1)[:, :, 0]
    assert _core.encode_tiff(a, 3, False, 3) == _core.encode_tiff(a, 3, False, 1) == encode_tiff(a, compress=False)


def test_core_encode_png_ids_refuses_bad_input():
    with pytest.raises(TypeError):
        _core.encode_png_ids(np.zeros((4, 4), np.int64))  # no silent narrowing
    with pytest.raises(ValueError):
        _core.encode_png_ids(np.zeros((4, 4, 2), np.int32))
    with pytest.raises(ValueError, match="contiguous"):
        _core.encode_png_ids(np.zeros((4, 4), np.int32)[::-1])
    with pytest.raises(ValueError):
        _core.encode_png_ids(np.zeros((0, 4), np.int32))


@pytest.mark.parametrize("encode, dtype", [("png", np.int16), ("png", np.float16), ("png", np.int8),
                                           ("tiff", np.int16), ("tiff", np.float64)])
def test_encoders_refuse_other_dtypes(encode, dtype):
    with pytest.raises((TypeError, ValueError)):
        (encode_png if encode == "png" else encode_tiff)(np.zeros((4, 4), dtype))


# --- 5. the same bytes everywhere ---------------------------------------------------------------


def golden_images() -> dict[str, bytes]:
    """Fixed images from integer arithmetic only (no RNG, no libm), encoded."""
    y, x = np.mgrid[0:67, 0:91].astype(np.int64)
    checker = ((x // 8 + y // 8) % 2) * 255
    rgba = np.stack([(x * 7 + y * 3) % 256, checker, (x * y) % 251, 255 - (x ^ y) % 256], axis=-1).astype(np.uint8)
    rgba[20:30] = rgba[20]  # repeated rows (Up)
    rgb16 = (rgba[:, :, :3].astype(np.uint16) * 257) ^ (x[..., None] * 13).astype(np.uint16)
    depth = ((x * 3 - y * 5).astype(np.float32) / np.float32(8.0) + np.float32(2.0))
    depth[:, :10] = 0.0
    ids = ((x // 16) + (y // 16) * 6 - 1).astype(np.int32)
    ramp = (np.arange(100_003, dtype=np.int64) * 2654435761 % 1009 % 7).astype(np.uint8)  # short runs
    return {
        "png rgba8": _core.encode_png(rgba),
        "png grey8": _core.encode_png(np.ascontiguousarray(rgba[:, :, 0])),
        "png rgb16": _core.encode_png(rgb16),
        "png ids": _core.encode_png_ids(ids),
        "tiff rgb16": _core.encode_tiff(rgb16, 1, True, 2),
        "tiff int32": _core.encode_tiff(ids, 2, True, 2),
        "tiff float": _core.encode_tiff(depth, 3, True, 1),
        "tiff float predictor 3": _core.encode_tiff(depth, 3, True, 3),
        "zlib ramp": _core.zlib_compress(ramp),
    }


# Recorded on x86-64 with the generic build (SSE2 adler32, the PNG filters in 16-byte lanes),
# 2026; they hold with the filters' AVX2 clone (chosen at load time where the CPU has AVX2) and
# must hold on aarch64 (the scalar adler32). The sizes for reference.
GOLDEN_SHA256 = {
    "png rgba8": "0d9896ab087b3dd8c62ed634400db17d555a092db3fb51bc25cce18fbf7de894",  # 10314 bytes
    "png grey8": "f3c22f4ccb8bbdd5be002ec4a0b6c5a51d2e3a4e50579dafe8fb49d0879aa104",  # 187 bytes
    "png rgb16": "1fa081e92d70e77961d13f4b36349b43bfe6dae7b288f99be521265a0ccd26e8",  # 20933 bytes
    "png ids": "a7643f67b93f825c94f82e4f240547561c5c471841745cbe3782412ed9ef8cd5",  # 229 bytes
    "tiff rgb16": "668b2075096a99604d58fc080251693767384e0726dc2e69162a5c3c9d046f4a",  # 28716 bytes
    "tiff int32": "1cf99a4dd2ca4a47b08f481402ceb604816588281a3b780a7e9e7bf3ad8f09d7",  # 752 bytes
    "tiff float": "a907783b5970d3818bfc9d0d4c7064d8dbe87cc9c5f96c1992bb8579d026320e",  # 10758 bytes
    "tiff float predictor 3": "e6c284b0ee1fbc1a238240660696232a17be074857ce8830ddc7f174a78a9d70",  # 2632 bytes
    "zlib ramp": "f11c253af9a7f438bb0457518bcd5f5b16dcfa7e2d8854b25470cde29867618b",  # 6094 bytes
}


def test_golden_bytes():
    """The encoder is integer code with no dependence on the machine: the same image gives the
    same bytes on every machine, thread count and instruction set (it does not use zlib, so not
    its version either). In particular adler32 has an SSE2 path (x86-64) and a scalar one
    (elsewhere, or SR_ENCODE_SCALAR) that must give the same sums: these hashes, recorded on
    x86-64, must hold on aarch64 too. A deliberate change of the encoder's output (its tables,
    filters, run coding) changes them: check the files still decode (the rest of this file) and
    record the new hashes."""
    images = golden_images()
    for name, data in images.items():  # what the hashes stand for decodes
        if name.startswith("png"):
            png_chunks(data)
            assert _decode_cv2(data) is not None
        elif name.startswith("tiff"):
            # (libtiff, through OpenCV: tifffile >= 2026 decodes predictor 3 only with
            # imagecodecs, which is not a test dependency)
            assert _decode_cv2(data).shape[:2] == (67, 91)
        else:
            inflate(data)
    got = {name: hashlib.sha256(data).hexdigest() for name, data in images.items()}
    assert got == GOLDEN_SHA256


def test_concurrent_encodes_give_the_same_bytes():
    img = make_image((300, 257), np.uint8, 3, seed=11)
    img16 = make_image((200, 131), np.uint16, 4, seed=12)
    f = make_image((150, 111), np.float32, 1, seed=13)[:, :, 0]
    jobs = [lambda: _core.encode_png(img), lambda: _core.encode_png(img16),
            lambda: _core.encode_tiff(f, 3, True, 3), lambda: encode_tiff(img16),
            lambda: _core.zlib_compress(img16)]
    want = [job() for job in jobs]
    results: list[list[bytes]] = [[] for _ in range(4)]
    barrier = threading.Barrier(4)
    errors = []

    def work(k: int) -> None:
        try:
            for _ in range(5):
                barrier.wait()
                results[k].extend(job() for job in jobs[k:] + jobs[:k])  # different orders
        except BaseException as e:  # noqa: BLE001 - reported below
            errors.append(e)
            barrier.abort()

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    for k in range(4):
        order = want[k:] + want[:k]
        assert results[k] == order * 5, k


# --- 6. the GIL is released -----------------------------------------------------------------


@pytest.mark.parametrize("encode", ["encode_png", "encode_tiff"])
def test_gil_is_released_while_encoding(encode):
    # Observed by a counting thread (tests/support/gil_probe.py), not by a clock.
    y, x = np.mgrid[0:2048, 0:2048]
    img = np.stack([x % 256, y % 256, (x * y) % 256], axis=-1).astype(np.uint8)
    call = (lambda: _core.encode_png(img)) if encode == "encode_png" else \
        (lambda: _core.encode_tiff(img, 1, True, 2))
    progressed = calls_that_let_python_run(call)
    assert progressed >= 3, progressed
