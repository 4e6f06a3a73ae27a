"""imread / imwrite: exact round trips for every lossless format, refusals, atomic writes."""
from __future__ import annotations

import os

import numpy as np
import pytest

from softrast.io import imread, imwrite

H, W = 7, 11  # non-square, odd sizes catch transposed / 2-D mis-writes


def random_image(rng, dtype, channels):
    shape = (H, W) if channels is None else (H, W, channels)
    if dtype == np.float32:
        return (rng.normal(size=shape) * 100.0).astype(np.float32)  # negative and > 1 too
    info = np.iinfo(dtype)
    return rng.integers(info.min, info.max, size=shape, endpoint=True).astype(dtype)


@pytest.mark.parametrize("ext, dtype, channels", [
    (".png", np.uint8, 1), (".png", np.uint8, 3), (".png", np.uint8, 4), (".png", np.uint8, None),
    (".png", np.uint16, 1), (".png", np.uint16, 3), (".png", np.uint16, 4),
    (".exr", np.float32, 1), (".exr", np.float32, 3), (".exr", np.float32, 4), (".exr", np.float32, None),
    (".tif", np.float32, 1), (".tif", np.float32, 3), (".tif", np.float32, None),
    (".tif", np.uint8, 3), (".tif", np.uint16, 4),
])
def test_lossless_round_trip(tmp_path, rng, ext, dtype, channels):
    image = random_image(rng, dtype, channels)
    path = tmp_path / f"image{ext}"
    imwrite(path, image)
    back = imread(path)
    assert back.dtype == dtype
    expected = image if channels != 1 else image[:, :, 0]  # one channel comes back as (h, w)
    assert back.shape == expected.shape
    np.testing.assert_array_equal(back, expected)


def test_two_dimensional_image_keeps_orientation(tmp_path):
    # Distinct values per pixel: a transposed or strided mis-write cannot pass.
    image = np.arange(H * W, dtype=np.uint16).reshape(H, W) * 300
    imwrite(tmp_path / "ramp.png", image)
    np.testing.assert_array_equal(imread(tmp_path / "ramp.png"), image)


def test_jpeg_is_close(tmp_path):
    yy, xx = np.mgrid[0:64, 0:96]
    smooth = np.stack([xx * 2, yy * 3, (xx + yy)], axis=-1).astype(np.uint8)  # JPEG-friendly ramp
    imwrite(tmp_path / "ramp.jpg", smooth)
    back = imread(tmp_path / "ramp.jpg")
    assert back.shape == smooth.shape and back.dtype == np.uint8
    assert np.abs(back.astype(int) - smooth).mean() < 3.0
    imwrite(tmp_path / "gray.jpg", smooth[:, :, 0])
    assert imread(tmp_path / "gray.jpg").shape == (64, 96)


def test_bool_and_float64_are_converted(tmp_path, rng):
    mask = rng.random((H, W)) > 0.5
    imwrite(tmp_path / "mask.png", mask)
    back = imread(tmp_path / "mask.png")
    assert back.dtype == np.uint8
    np.testing.assert_array_equal(back, mask.astype(np.uint8) * 255)

    depth = rng.random((H, W)) * 10.0
    imwrite(tmp_path / "depth.exr", depth)
    back = imread(tmp_path / "depth.exr")
    assert back.dtype == np.float32
    np.testing.assert_array_equal(back, depth.astype(np.float32))


def test_overwrite_and_no_temporary_files_left(tmp_path, rng):
    for k in range(3):
        imwrite(tmp_path / "a.png", random_image(rng, np.uint8, 3))
        imwrite(tmp_path / "b.exr", random_image(rng, np.float32, 3))
    assert sorted(os.listdir(tmp_path)) == ["a.png", "b.exr"]


def test_interrupted_write_keeps_old_file_and_leaves_no_temporary(tmp_path, monkeypatch):
    old = np.zeros((H, W, 3), np.uint8)
    imwrite(tmp_path / "a.png", old)

    def fail(src, dst):
        raise KeyboardInterrupt  # interrupted between writing the data and renaming it

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(KeyboardInterrupt):
        imwrite(tmp_path / "a.png", np.full((H, W, 3), 200, np.uint8))
    monkeypatch.undo()
    assert os.listdir(tmp_path) == ["a.png"]
    np.testing.assert_array_equal(imread(tmp_path / "a.png"), old)


@pytest.mark.parametrize("name, array, error, match", [
    ("f.png", np.zeros((H, W, 3), np.float32), ValueError, r"\.exr or \.tif"),
    ("f.jpg", np.zeros((H, W, 3), np.float32), ValueError, r"\.exr"),
    ("f.png", np.zeros((H, W, 3), np.float64), ValueError, r"\.exr"),
    ("f.jpg", np.zeros((H, W, 3), np.uint16), ValueError, "uint16"),
    ("f.exr", np.zeros((H, W, 3), np.uint8), ValueError, "uint8"),
    ("f.jpg", np.zeros((H, W, 4), np.uint8), ValueError, "4 channels"),
    ("f.png", np.zeros((H, W, 2), np.uint8), ValueError, "array"),
    ("f.png", np.zeros((H, W, 3, 1), np.uint8), ValueError, "array"),
    ("f.png", np.zeros(W, np.uint8), ValueError, "array"),
    ("f.png", np.zeros((0, W, 3), np.uint8), ValueError, "array is empty"),
    ("f.png", np.zeros((H, W, 3), np.int64), TypeError, "array dtype"),
    ("f.tif", np.zeros((H, W, 3), np.complex64), TypeError, "array dtype"),
    ("f.qqq", np.zeros((H, W, 3), np.uint8), ValueError, "path"),
    ("noext", np.zeros((H, W, 3), np.uint8), ValueError, "extension"),
])
def test_imwrite_refuses(tmp_path, name, array, error, match):
    with pytest.raises(error, match=match):
        imwrite(tmp_path / name, array)
    assert os.listdir(tmp_path) == []  # nothing written, no temporary left


def test_imwrite_missing_directory(tmp_path):
    with pytest.raises(FileNotFoundError, match="nowhere"):
        imwrite(tmp_path / "nowhere" / "a.png", np.zeros((H, W), np.uint8))


def test_imread_missing(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.png"):
        imread(tmp_path / "missing.png")


@pytest.mark.parametrize("name", ["corrupt.png", "corrupt.exr", "corrupt.unknownext"])
def test_imread_corrupt(tmp_path, name):
    path = tmp_path / name
    path.write_bytes(b"this is not an image\x00\x01\x02")
    with pytest.raises(ValueError, match=name):
        imread(path)


def test_imread_truncated_png(tmp_path, rng):
    imwrite(tmp_path / "full.png", random_image(rng, np.uint8, 3))
    data = (tmp_path / "full.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match="cut.png"):
        imread(tmp_path / "cut.png")


@pytest.mark.parametrize("ext, compression, exact", [
    (".png", 0, True), (".png", 1, True), (".png", 9, True),
    (".exr", "none", True), (".exr", "zip", True), (".exr", "zips", True), (".exr", "piz", True),
    (".exr", "rle", True), (".exr", "pxr24", False), (".exr", "dwaa", False),
    (".tif", "none", True), (".tif", "lzw", True), (".tif", "zip", True)])
def test_compression_round_trips(tmp_path, rng, ext, compression, exact):
    """Every lossless codec gives the array back exactly; lossy ones (pxr24: 24-bit floats,
    dwaa) stay close; a higher PNG level never makes a larger file of a smooth image."""
    if ext == ".png":
        yy, xx = np.mgrid[0:60, 0:80]
        arr = np.dstack([xx * 3, yy * 4, (xx + yy) % 256]).astype(np.uint8)
    else:
        arr = (rng.random((60, 80, 1)) * 10).astype(np.float32)
    path = tmp_path / f"c{ext}"
    imwrite(path, arr, compression=compression)
    back = imread(path).reshape(arr.shape)
    if exact:
        np.testing.assert_array_equal(back, arr)
    else:
        np.testing.assert_allclose(back, arr, rtol=2e-2, atol=2e-2)
    if ext == ".png" and compression > 0:
        stored = tmp_path / "stored.png"
        imwrite(stored, arr, compression=0)
        assert os.path.getsize(path) < os.path.getsize(stored)


def test_files_are_reproducible(tmp_path, rng):
    """The same array written twice, a second apart, gives the same bytes in every format
    (OpenImageIO otherwise writes the time into EXR and TIFF headers)."""
    import time

    f32 = rng.random((20, 30, 1)).astype(np.float32)
    u8 = (rng.random((20, 30, 3)) * 255).astype(np.uint8)
    cases = [(".exr", f32), (".tif", f32), (".png", u8), (".tif", u8)]
    first = []
    for k, (ext, arr) in enumerate(cases):
        imwrite(tmp_path / f"a{k}{ext}", arr)
        first.append((tmp_path / f"a{k}{ext}").read_bytes())
    time.sleep(1.1)
    for k, (ext, arr) in enumerate(cases):
        imwrite(tmp_path / f"b{k}{ext}", arr)
        assert (tmp_path / f"b{k}{ext}").read_bytes() == first[k], ext


@pytest.mark.parametrize("name, compression, match", [
    ("a.png", 10, "zlib level 0-9"), ("a.png", "zip", "zlib level 0-9"), ("a.png", True, "zlib level"),
    ("a.exr", "lzw", "compression for .exr must be one of"), ("a.tif", 3, "compression for .tif"),
    ("a.jpg", 90, "not supported for .jpg")])
def test_bad_compression_is_refused(tmp_path, name, compression, match):
    arr = np.zeros((4, 4, 3), np.float32 if name.endswith(".exr") else np.uint8)
    with pytest.raises(ValueError, match=match):
        imwrite(tmp_path / name, arr, compression=compression)
    assert not list(tmp_path.iterdir())


def _damaged(kind, data):
    if kind == "truncated":
        return data[: len(data) // 10]
    flipped = bytearray(data)  # a run of flipped bits in the entropy-coded data, after the headers
    for k in range(len(data) // 2, len(data) // 2 + 400):
        flipped[k] ^= 0x5A
    return bytes(flipped)


@pytest.mark.parametrize("kind", ["truncated", "flipped"])
def test_imread_and_load_texture_report_decoder_errors(tmp_path, rng, kind):
    """OpenImageIO decodes a damaged JPEG to mostly grey and reports it: that is an error, naming
    the file and the decoder's message, not an image."""
    import softrast as sr

    image = (rng.random((64, 80, 3)) * 255).astype(np.uint8)
    imwrite(tmp_path / "full.jpg", image)
    path = tmp_path / f"{kind}.jpg"
    path.write_bytes(_damaged(kind, (tmp_path / "full.jpg").read_bytes()))
    with pytest.raises(ValueError, match=rf"{kind}\.jpg.*(JPEG|jpeg)"):
        imread(path)
    with pytest.raises(ValueError, match=rf"{kind}\.jpg"):
        sr.load_texture(path)
    assert imread(tmp_path / "full.jpg").shape == (64, 80, 3)  # the intact file still loads
