"""softrast.Texture's sampler (the C++ core) against the NumPy reference
softrast.reference.texture, which is written from the texture spec (decoding, coordinates,
wrap, box-filtered mips, nearest / bilinear / trilinear / anisotropic), plus closed-form checks of
the reference itself.

Texel boundaries: every uv and duv is generated as float32 and the same float32 values go to the
core and to the reference, and the reference performs the spec's coordinate arithmetic in float32
operation by operation (wrap reduction, x = u * w, y = (1 - v) * h, x - 0.5, floor, fraction,
anisotropic positions), blending in float64. So floor() sees what the core sees and points at or
near texel boundaries are kept (exact boundaries are even added on purpose). The one discontinuity
that float32-vs-float64 *level-of-detail* arithmetic can move, the steps of the anisotropic
N = ceil(Pmax / Pmin - 1/64), is avoided: points whose ratio is within 1e-4 (relative) of a step
k + 1/64 (k < max_anisotropy) are dropped.
"""
from __future__ import annotations

import functools
import math

import numpy as np
import pytest

import softrast as sr
from softrast.reference import texture as ref

F32 = np.float32
DTYPES = (np.uint8, np.uint16, np.float32)
ATOL = 1e-5  # core (float32) vs reference (float64 blends)


# -------------------------------------------------------------------------------------- helpers

def make_image(h: int, w: int, channels: int, dtype, seed: int = 0) -> np.ndarray:
    """Deterministic random texels; float32 includes HDR and negative values (sampled 'as is')."""
    rng = np.random.default_rng([h, w, channels, np.dtype(dtype).num, seed])
    shape = (h, w, channels)
    if dtype == np.uint8:
        return rng.integers(0, 256, shape, dtype=np.uint8)
    if dtype == np.uint16:
        return rng.integers(0, 65536, shape, dtype=np.uint16)
    return rng.uniform(-0.25, 2.0, shape).astype(np.float32)


@functools.lru_cache(maxsize=None)
def image_and_chain(h, w, channels, dtype_name, srgb):
    image = make_image(h, w, channels, np.dtype(dtype_name).type)
    return image, ref.mip_chain(ref.decode(image, srgb))


def n_levels(h: int, w: int) -> int:
    return len(ref.level_sizes(h, w))


def near_aniso_step(duv: np.ndarray, h: int, w: int, max_anisotropy: int) -> np.ndarray:
    """Points where N = ceil(Pmax / Pmin - 1/64) could differ between float32 and float64:
    Pmax / Pmin within 1e-4 (relative) of a step k + 1/64, k < max_anisotropy."""
    la, lb = ref.axes(duv, h, w)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.maximum(la, lb) / np.minimum(la, lb)
    r = np.where(np.isfinite(r), r, 0.0)  # Pmin = 0: N = max_anisotropy, no step
    s = r - ref.ANISO_SLACK
    k = np.round(s)
    return (k >= 1) & (k < max_anisotropy) & (np.abs(s - k) < 1e-4 * r)


@functools.lru_cache(maxsize=None)
def random_queries(h: int, w: int, n: int = 256, seed: int = 0, max_anisotropy: int = 16):
    """float32 uv in [-3, 3] (plus exact texel edges / centres / integers) and float32 duv:
    footprint lengths log-uniform from 1/16 texel (magnification) to 4x the whole texture, random
    directions; a quarter isotropic (ay = -ax exactly), a quarter ay = 0 (Pmin = 0), a quarter
    ay shorter by a ratio in [1, 64] and a quarter ay longer by such a ratio (anisotropic, up to
    beyond max_anisotropy)."""
    rng = np.random.default_rng([h, w, n, seed])
    uv = rng.uniform(-3.0, 3.0, (n, 2))
    # exact boundaries and centres of level-0 texels, and the integers, in both u and v
    j = rng.integers(-w, 2 * w + 1, 24)
    r = rng.integers(-h, 2 * h + 1, 24)
    edges_u = np.concatenate([j / w, (j + 0.5) / w, [-3, -2, -1, 0, 0.5, 1, 2, 3]])
    edges_v = np.concatenate([r / h, (r + 0.5) / h, [-3, -2, -1, 0, 0.5, 1, 2, 3]])
    uv[: len(edges_u), 0] = edges_u
    uv[-len(edges_v):, 1] = edges_v
    uv = uv.astype(F32)

    length = 2.0 ** rng.uniform(-4.0, math.log2(max(h, w)) + 2.0, n)
    th = rng.uniform(0, 2 * np.pi, n)
    ph = th + rng.uniform(0.3, np.pi - 0.3, n)
    ratio = 2.0 ** rng.uniform(0.0, 6.0, n)
    ax = length[:, None] * np.stack([np.cos(th), np.sin(th)], 1)
    other = np.stack([np.cos(ph), np.sin(ph)], 1)
    kind = np.arange(n) % 4
    ay = np.where((kind == 2)[:, None], (length / ratio)[:, None] * other,
                  (length * ratio)[:, None] * other)
    ay[kind == 1] = 0.0
    scale = np.array([w, h], float)
    dx = (ax / scale).astype(F32)
    dy = (ay / scale).astype(F32)
    dy[kind == 0] = -dx[kind == 0]  # exactly isotropic: |ay| == |ax| in any precision
    duv = np.concatenate([dx, dy], axis=1)
    keep = ~near_aniso_step(duv, h, w, max_anisotropy)
    return uv[keep], duv[keep]


def assert_close(got, want, uv, duv=None, atol=ATOL, rtol=0.0, what=""):
    """assert_allclose with the worst point's inputs in the message."""
    got = np.asarray(got)
    assert got.shape == want.shape, f"{what}: shape {got.shape}, expected {want.shape}"
    err = np.abs(got.astype(np.float64) - want) - rtol * np.abs(want)
    bad = ~(err <= atol)
    if bad.any():
        k = int(np.argmax(np.where(bad, np.nan_to_num(err, nan=np.inf), -1).max(axis=1)))
        d = "" if duv is None else f" duv={np.asarray(duv)[k].tolist()}"
        raise AssertionError(
            f"{what}: {int(bad.any(axis=1).sum())}/{len(got)} points differ by > {atol}; worst "
            f"uv={np.asarray(uv)[k].tolist()}{d}: expected {want[k].tolist()}, "
            f"got {got[k].tolist()}")


def size_id(s) -> str:
    return f"{s[1]}x{s[0]}"  # w x h


# ------------------------------------------------------------------------ the reference itself

def test_reference_srgb_decode_closed_form():
    got = ref.srgb_to_linear(np.array([0, 10, 11, 255]) / 255.0)
    want = [0.0, 10 / 255 / 12.92, ((11 / 255 + 0.055) / 1.055) ** 2.4, 1.0]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
    # published 8-bit sRGB table values
    np.testing.assert_allclose(got[1:3], [0.0030352698, 0.0033465358], rtol=0, atol=1e-10)
    # alpha is never decoded; channel layouts
    img = np.array([[[10, 11, 12, 13]]], np.uint8)
    np.testing.assert_allclose(ref.decode(img, True)[0, 0, 3], 13 / 255, rtol=0, atol=0)
    np.testing.assert_allclose(ref.decode(img[..., :1], True)[0, 0], [got[1]] * 3 + [1.0])
    np.testing.assert_allclose(ref.decode(img[..., :2], False)[0, 0], [10 / 255] * 3 + [11 / 255])
    np.testing.assert_allclose(ref.decode(img[..., :3], False)[0, 0],
                               [10 / 255, 11 / 255, 12 / 255, 1.0])
    np.testing.assert_allclose(ref.decode(np.array([[65535]], np.uint16), True)[0, 0], [1, 1, 1, 1])


def test_reference_box_weights_closed_form():
    for n, m, rows in [(2, 1, [[0.5, 0.5]]), (3, 1, [[1 / 3] * 3]), (1, 1, [[1.0]]),
                       (5, 2, [[0.4, 0.4, 0.2, 0, 0], [0, 0, 0.2, 0.4, 0.4]]),
                       (4, 2, [[0.5, 0.5, 0, 0], [0, 0, 0.5, 0.5]])]:
        idx, wt = ref.box_weights(n)
        dense = np.zeros((m, n))
        np.add.at(dense, (np.arange(m)[:, None].repeat(4, 1), idx), wt)
        np.testing.assert_allclose(dense, rows, rtol=0, atol=1e-15)
    for n in [1, 2, 3, 5, 7, 37, 16383]:
        idx, wt = ref.box_weights(n)
        m = max(1, n // 2)
        assert (wt >= 0).all()
        np.testing.assert_allclose(wt.sum(1), 1.0, atol=1e-12)  # normalised
        np.testing.assert_allclose(np.bincount(idx.ravel(), wt.ravel(), n), m / n,
                                   atol=1e-12)  # every source texel counted by its area


def test_reference_mip_chain_closed_form():
    const = np.broadcast_to([0.2, 0.4, 0.6, 0.8], (23, 37, 4))
    chain = ref.mip_chain(const)
    assert [c.shape[:2] for c in chain] == [(23, 37), (11, 18), (5, 9), (2, 4), (1, 2), (1, 1)]
    for c in chain:
        np.testing.assert_allclose(c, np.broadcast_to([0.2, 0.4, 0.6, 0.8], c.shape), atol=1e-15)
    two = np.random.default_rng(1).random((2, 2, 4))
    np.testing.assert_allclose(ref.mip_chain(two)[1][0, 0], two.mean(axis=(0, 1)), atol=1e-15)
    # 3x1: the last level is the plain mean; 5 wide: (0.4, 0.4, 0.2) and (0.2, 0.4, 0.4)
    row = np.random.default_rng(2).random((1, 5, 4))
    lv1 = ref.mip_chain(row)[1]
    np.testing.assert_allclose(lv1[0, 0], 0.4 * row[0, 0] + 0.4 * row[0, 1] + 0.2 * row[0, 2])
    np.testing.assert_allclose(lv1[0, 1], 0.2 * row[0, 2] + 0.4 * row[0, 3] + 0.4 * row[0, 4])
    np.testing.assert_allclose(ref.mip_chain(row[:, :3])[1][0, 0], row[0, :3].mean(0))


def test_reference_bilinear_closed_form():
    img = np.random.default_rng(3).random((8, 16, 4))
    r, j = np.meshgrid(np.arange(8), np.arange(16), indexing="ij")
    uv = np.stack([(j.ravel() + 0.5) / 16, 1 - (r.ravel() + 0.5) / 8], 1).astype(F32)
    for wrap in ref.WRAPS:
        for f in ("nearest", "bilinear"):
            got = ref.sample_chain([img], uv, filter=f, wrap=wrap)
            np.testing.assert_array_equal(got, img.reshape(-1, 4))
    # halfway between texel centres (0,0) and (0,1): the mean; at u = 0 (repeat) the mean of
    # columns 0 and 15; at u = 0 clamp: column 0; top_left flips rows
    uv = np.array([[1 / 16, 1 - 0.5 / 8], [0.0, 1 - 0.5 / 8]], F32)
    got = ref.sample_chain([img], uv, wrap="repeat")
    np.testing.assert_allclose(got[0], (img[0, 0] + img[0, 1]) / 2, atol=1e-15)
    np.testing.assert_allclose(got[1], (img[0, 0] + img[0, 15]) / 2, atol=1e-15)
    np.testing.assert_allclose(ref.sample_chain([img], uv[1:], wrap="clamp")[0], img[0, 0])
    np.testing.assert_allclose(ref.sample_chain([img], uv[1:], wrap="mirror")[0], img[0, 0])
    top = ref.sample_chain([img], [[0.5 / 16, 0.5 / 8]], filter="nearest", uv_origin="top_left")
    np.testing.assert_array_equal(top[0], img[0, 0])


def test_reference_trilinear_and_anisotropic_closed_form():
    img = np.random.default_rng(4).random((16, 16, 4))
    chain = ref.mip_chain(img)
    uv = np.random.default_rng(5).uniform(-1, 2, (50, 2)).astype(F32)
    b = [ref.sample_chain([c], uv) for c in chain]
    for lam_texels, lo, hi, t in [(2.0, 1, 2, 0.0), (2 ** 1.5, 1, 2, 0.5), (0.25, 0, 1, 0.0),
                                  (1e9, 4, 4, 0.0)]:
        duv = np.tile([lam_texels / 16, 0, 0, 0], (50, 1)).astype(F32)
        got = ref.sample_chain(chain, uv, duv, filter="trilinear")
        np.testing.assert_allclose(got, (1 - t) * b[lo] + t * b[hi], atol=1e-12)
        if lam_texels < 1e9:  # isotropic (ay = -ax): N = 1, the same as trilinear
            iso = duv.copy()
            iso[:, 2:] = -iso[:, :2]
            np.testing.assert_allclose(ref.sample_chain(chain, uv, iso, filter="anisotropic"),
                                       got, atol=1e-12)
    # ax = 8 texels along u, ay = 2 along v: N = 4, lambda = 1, 4 bilinear taps at level 1
    duv = np.tile([8 / 16, 0, 0, 2 / 16], (50, 1)).astype(F32)
    taps = [ref.sample_chain([chain[1]], uv + [[8 / 16 * ((i + 0.5) / 4 - 0.5), 0]])
            for i in range(4)]
    np.testing.assert_allclose(ref.sample_chain(chain, uv, duv, filter="anisotropic"),
                               np.mean(taps, axis=0), atol=1e-12)
    # the 1/64 slack: ratios up to 1 + 1/64 are one probe, just above it two
    one = np.array([1.0])
    for ratio, n in [(1.0, 1), (1.01, 1), (1.015, 1), (1.016, 2), (1.5, 2), (4.0, 4), (4.02, 5),
                     (15.9, 16), (40.0, 16)]:
        assert ref.aniso_count(one * ratio, one, 16)[0] == n, ratio
    assert ref.aniso_count(one * 40.0, one, 7)[0] == 7
    assert ref.aniso_count(one, one * 0, 16)[0] == 16  # Pmin = 0
    # max_anisotropy 2: N = 2, lambda = log2(8 / 2) = 2
    taps = [ref.sample_chain([chain[2]], uv + [[8 / 16 * ((i + 0.5) / 2 - 0.5), 0]])
            for i in range(2)]
    np.testing.assert_allclose(ref.sample_chain(chain, uv, duv, "anisotropic", max_anisotropy=2),
                               np.mean(taps, axis=0), atol=1e-12)


# ------------------------------------------------------------------ exact values at texel centres

def centre_uvs(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """(uv, found): float32 uv of every texel centre (row-major), each chosen among the float32
    neighbours of ((j + 0.5) / w, 1 - (r + 0.5) / h) so that float32 u * w == j + 0.5 and
    (1 - v) * h == r + 0.5 exactly. For non-power-of-two sizes a few centres have no such
    float32 (the products step by more than an ulp); found is False there."""
    steps = np.arange(-8, 9)

    def pick(target: np.ndarray, n: int, to_texel) -> np.ndarray:
        base = target.astype(F32)
        cands = [base]
        for s in steps[steps != 0]:
            c = base
            for _ in range(abs(s)):
                c = np.nextafter(c, F32(np.inf if s > 0 else -np.inf))
            cands.append(c)
        cands = np.stack(cands)  # (17, n)
        ok = to_texel(cands) == (np.arange(n) + 0.5).astype(F32)
        return cands[ok.argmax(axis=0), np.arange(n)], ok.any(axis=0)

    u, fu = pick((np.arange(w) + 0.5) / w, w, lambda c: c * F32(w))
    v, fv = pick(1 - (np.arange(h) + 0.5) / h, h, lambda c: (F32(1) - c) * F32(h))
    uv = np.stack(np.broadcast_arrays(u[None, :], v[:, None]), axis=-1).reshape(-1, 2)
    found = (fu[None, :] & fv[:, None]).ravel()
    assert found.mean() > 0.5
    return uv, found


@pytest.mark.parametrize("size", [(8, 16), (23, 37), (1, 1), (64, 1), (1, 16384)], ids=size_id)
@pytest.mark.parametrize("filter", ["nearest", "bilinear"])
def test_texel_centres_exact(size, filter):
    h, w = size
    uv, found = centre_uvs(h, w)
    if filter == "nearest":  # any point inside the texel: all of them
        found[:] = True
    for channels in (1, 2, 3, 4):
        img = make_image(h, w, channels, np.uint8, seed=7)
        got = sr.Texture(img, srgb=False).sample(uv[found], filter=filter)
        assert got.dtype == np.float32 and got.shape == (found.sum(), 4)
        want = ref.decode(img, False).astype(F32).reshape(-1, 4)[found]  # image/255 in float32
        np.testing.assert_array_equal(got, want, err_msg=f"{channels} channels")


@pytest.mark.parametrize("channels", [1, 2, 3, 4])
@pytest.mark.parametrize("filter", ["nearest", "bilinear"])
def test_srgb_decode_every_8bit_value(channels, filter):
    """A 256x1 ramp: every 8-bit value decoded exactly like np.float32(IEC formula in float64)
    (tolerance 0); the alpha (a reversed ramp) is np.float32(v / 255), never decoded."""
    ramp = np.arange(256, dtype=np.uint8)
    layout = {1: [ramp], 2: [ramp, 255 - ramp], 3: [ramp] * 3, 4: [ramp] * 3 + [255 - ramp]}
    img = np.stack(layout[channels], axis=-1)[None]  # (1, 256, channels)
    uv = np.stack([(np.arange(256) + 0.5) / 256, np.full(256, 0.5)], 1).astype(F32)
    got = sr.Texture(img, srgb=True).sample(uv, filter=filter)
    c = ramp / 255.0
    lin = ref.srgb_to_linear(c).astype(F32)
    alpha = ((255 - ramp) / 255.0).astype(F32) if channels in (2, 4) else np.ones(256, F32)
    want = np.stack([lin, lin, lin, alpha], 1)
    bad = np.flatnonzero((got != want).any(axis=1))
    if bad.size:
        k = bad[0]
        raise AssertionError(f"{bad.size} values differ, first v={k}: expected "
                             f"{want[k].tolist()}, got {got[k].tolist()}")


def test_srgb_default_by_dtype():
    h, w = 4, 8
    uv, _ = centre_uvs(h, w)
    for dtype, default in [(np.uint8, True), (np.uint16, True), (np.float32, False)]:
        img = make_image(h, w, 4, dtype, seed=11)
        if dtype == np.float32:
            img = np.abs(img)
        got = sr.Texture(img).sample(uv, filter="nearest")
        want = sr.Texture(img, srgb=default).sample(uv, filter="nearest")
        np.testing.assert_array_equal(got, want, err_msg=str(np.dtype(dtype)))
        other = sr.Texture(img, srgb=not default).sample(uv, filter="nearest")
        assert not np.array_equal(got, other)


def test_two_dimensional_image_is_one_channel_and_float64_is_float32():
    img = make_image(5, 7, 1, np.float32, seed=3)
    uv, duv = random_queries(5, 7)
    a = sr.Texture(img[..., 0], srgb=False).sample(uv, duv, filter="trilinear")
    b = sr.Texture(img, srgb=False).sample(uv, duv, filter="trilinear")
    c = sr.Texture(img.astype(np.float64), srgb=False).sample(uv, duv, filter="trilinear")
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(c, b)
    # uv and duv as float64 arrays holding the same float32 values: the same result
    d = sr.Texture(img, srgb=False).sample(uv.astype(np.float64), duv.astype(np.float64),
                                           filter="trilinear")
    np.testing.assert_array_equal(d, b)


# --------------------------------------------------------------------- random points vs reference

SIZES = [(23, 37), (1, 1), (1, 64), (64, 1), (1, 16384), (16384, 1), (16, 16)]
WRAP_CASES = ["repeat", "clamp", "mirror", ("clamp", "mirror"), ("mirror", "repeat")]


def wrap_id(w) -> str:
    return w if isinstance(w, str) else "-".join(w)


@pytest.mark.parametrize("filter", ["bilinear", "trilinear", "anisotropic"])
@pytest.mark.parametrize("wrap", WRAP_CASES, ids=wrap_id)
@pytest.mark.parametrize("size", SIZES, ids=size_id)
def test_random_against_reference(size, wrap, filter):
    """Every dtype x channel count x sRGB flag, at random float32 uv in [-3, 3] with random
    derivatives, to 1e-5."""
    h, w = size
    uv, duv = random_queries(h, w)
    errors = []
    for dtype in DTYPES:
        for channels in (1, 2, 3, 4):
            for srgb in (False, True):
                image, chain = image_and_chain(h, w, channels, np.dtype(dtype).name, srgb)
                got = sr.Texture(image, srgb=srgb, wrap=wrap).sample(uv, duv, filter=filter)
                want = ref.sample_chain(chain, uv, duv, filter, wrap)
                try:
                    assert_close(got, want, uv, duv,
                                 what=f"{np.dtype(dtype).name} c={channels} srgb={srgb}")
                except AssertionError as e:
                    errors.append(str(e))
    assert not errors, "\n".join(errors)


@pytest.mark.parametrize("wrap", ["repeat", "mirror", "clamp"])
@pytest.mark.parametrize("size", [(23, 37), (1, 16384)], ids=size_id)
def test_nearest_random_against_reference(size, wrap):
    """nearest at random float32 uv (and exact texel edges), bit-exact texel choice."""
    h, w = size
    uv, _ = random_queries(h, w)
    for dtype in DTYPES:
        image, chain = image_and_chain(h, w, 4, np.dtype(dtype).name, True)
        got = sr.Texture(image, srgb=True, wrap=wrap).sample(uv, filter="nearest")
        assert_close(got, ref.sample_chain(chain, uv, None, "nearest", wrap), uv,
                     what=np.dtype(dtype).name)


@pytest.mark.parametrize("filter", ["nearest", "bilinear", "trilinear", "anisotropic"])
def test_top_left_origin(filter):
    h, w = 23, 37
    uv, duv = random_queries(h, w)
    image, chain = image_and_chain(h, w, 3, "uint8", True)
    tex = sr.Texture(image, srgb=True, wrap=("repeat", "clamp"), uv_origin="top_left")
    want = ref.sample_chain(chain, uv, duv, filter, ("repeat", "clamp"), uv_origin="top_left")
    assert_close(tex.sample(uv, duv, filter=filter), want, uv, duv)


@pytest.mark.parametrize("max_anisotropy", [1, 2, 4, 7])
@pytest.mark.parametrize("size", [(23, 37), (32, 32)], ids=size_id)
def test_max_anisotropy_against_reference(size, max_anisotropy):
    h, w = size
    uv, duv = random_queries(h, w, seed=1, max_anisotropy=max_anisotropy)
    image, chain = image_and_chain(h, w, 4, "uint16", False)
    tex = sr.Texture(image, srgb=False, max_anisotropy=max_anisotropy)
    want = ref.sample_chain(chain, uv, duv, "anisotropic", "repeat", max_anisotropy)
    assert_close(tex.sample(uv, duv, filter="anisotropic"), want, uv, duv)


def test_anisotropic_closed_form_taps():
    """ax = 8 texels along u, ay = 2 along v: N = 4 taps at lambda = 1 spread along u; with
    max_anisotropy = 2: N = 2 taps at lambda = 2. Checked against the core's own mips."""
    h = w = 64
    image = make_image(h, w, 4, np.uint8, seed=5)
    uv = np.random.default_rng(6).uniform(-1, 2, (200, 2)).astype(F32)
    duv = np.tile([8 / w, 0, 0, 2 / h], (200, 1)).astype(F32)
    for max_aniso, n, level in [(16, 4, 1), (2, 2, 2)]:
        tex = sr.Texture(image, srgb=False, max_anisotropy=max_aniso)
        lvl = tex.mip(level).astype(np.float64)
        taps = [ref.bilinear(lvl, uv[:, 0] + F32(8 / w) * F32((i + 0.5) / n - 0.5), uv[:, 1],
                             "repeat") for i in range(n)]
        assert_close(tex.sample(uv, duv, filter="anisotropic"), np.mean(taps, axis=0), uv, duv,
                     atol=1e-6, what=f"max_anisotropy={max_aniso}")


@pytest.mark.parametrize("ratio, n", [(1.01, 1), (1.03, 2), (2.5, 3), (3.0, 3), (3.05, 4)])
def test_anisotropic_probe_count(ratio, n):
    """ax = 16 texels along u, ay = 16 / ratio along v: N = ceil(ratio - 1/64) probes at
    lambda = log2(16 / N), spread along u (the 1/64 keeps a nearly isotropic footprint at one)."""
    h = w = 64
    image = make_image(h, w, 4, np.uint8, seed=8)
    uv = np.random.default_rng(9).uniform(-1, 2, (200, 2)).astype(F32)
    duv = np.tile([16 / w, 0, 0, 16 / ratio / h], (200, 1)).astype(F32)
    tex = sr.Texture(image, srgb=False)
    lam = math.log2(16 / n)
    chain = [tex.mip(l).astype(np.float64) for l in range(len(tex.levels))]
    taps = [ref.trilinear(chain, uv[:, 0] + F32(16 / w) * F32((i + 0.5) / n - 0.5), uv[:, 1],
                          np.full(200, lam), "repeat") for i in range(n)]
    assert_close(tex.sample(uv, duv, filter="anisotropic"), np.mean(taps, axis=0), uv, duv,
                 atol=1e-6, what=f"ratio {ratio}: N = {n}")


# --------------------------------------------------------------------------- mip levels and LOD

@pytest.mark.parametrize("size, sizes", [
    ((23, 37), [(23, 37), (11, 18), (5, 9), (2, 4), (1, 2), (1, 1)]),
    ((1, 1), [(1, 1)]),
    ((1, 64), [(1, 64), (1, 32), (1, 16), (1, 8), (1, 4), (1, 2), (1, 1)]),
    ((3, 2), [(3, 2), (1, 1)]),
    ((1, 16384), [(1, 16384 >> k) for k in range(15)]),
    ((16384, 1), [(16384 >> k, 1) for k in range(15)]),
    ((5, 1000), ref.level_sizes(5, 1000)),
], ids=lambda x: size_id(x) if isinstance(x[0], int) else None)
def test_levels(size, sizes):
    tex = sr.Texture(np.zeros(size + (3,), np.uint8))
    assert [tuple(int(a) for a in s) for s in tex.levels] == sizes


@pytest.mark.parametrize("size", [(23, 37), (1, 64), (64, 1), (7, 5), (1, 16384), (32, 32)],
                         ids=size_id)
def test_mips_against_reference(size):
    h, w = size
    for dtype in DTYPES:
        for channels, srgb in [(1, True), (2, False), (3, True), (4, True), (4, False)]:
            image, chain = image_and_chain(h, w, channels, np.dtype(dtype).name, srgb)
            tex = sr.Texture(image, srgb=srgb)
            assert len(tex.levels) == len(chain)
            for l, want in enumerate(chain):
                got = tex.mip(l)
                what = f"{np.dtype(dtype).name} c={channels} srgb={srgb} level {l}"
                assert got.dtype == np.float32 and got.shape == want.shape, what
                # 1e-6, relative to the value for the HDR float32 texels (sRGB-decoded up to ~5)
                np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6, err_msg=what)


@pytest.mark.parametrize("k, level", [(2, 1), (4, 2), (8, 3)])
@pytest.mark.parametrize("axis", ["du/dx", "dv/dx", "du/dy", "dv/dy"])
@pytest.mark.parametrize("size", [(64, 64), (32, 128)], ids=size_id)
def test_level_selection(size, axis, k, level):
    """A footprint of exactly k = 2^level level-0 texels selects exactly that level (t = 0):
    trilinear equals bilinear on tex.mip(level); so does anisotropic with an isotropic footprint
    (the other axis the exact negation: N = 1)."""
    h, w = size
    image = make_image(h, w, 4, np.uint8, seed=9)
    tex = sr.Texture(image, srgb=False, wrap="mirror")
    uv = np.random.default_rng(10).uniform(-3, 3, (300, 2)).astype(F32)
    col = ["du/dx", "dv/dx", "du/dy", "dv/dy"].index(axis)
    duv = np.zeros((300, 4), F32)
    duv[:, col] = k / (w if col % 2 == 0 else h)
    got = tex.sample(uv, duv, filter="trilinear")
    per_level = [ref.bilinear(tex.mip(l).astype(np.float64), uv[:, 0], uv[:, 1], "mirror")
                 for l in range(len(tex.levels))]
    assert_close(got, per_level[level], uv, duv, atol=1e-6, what=f"level {level}")
    for other in (level - 1, level + 1):  # the levels are distinguishable at these points
        assert np.abs(per_level[other] - per_level[level]).max() > 0.02
    # and the same through the reference's own mips
    chain = ref.mip_chain(ref.decode(image, False))
    assert_close(got, ref.bilinear(chain[level], uv[:, 0], uv[:, 1], "mirror"), uv, duv)
    iso = duv.copy()
    iso[:, (col + 2) % 4] = -duv[:, col]  # |ax| == |ay| == k
    assert_close(tex.sample(uv, iso, filter="anisotropic"), per_level[level], uv, iso, atol=1e-6,
                 what=f"anisotropic, level {level}")


def test_no_derivatives_is_level_zero():
    h, w = 23, 37
    image, chain = image_and_chain(h, w, 4, "uint8", True)
    uv, _ = random_queries(h, w)
    tex = sr.Texture(image, srgb=True)
    want = ref.sample_chain(chain, uv, None, "bilinear")
    for f in ("trilinear", "anisotropic"):
        assert_close(tex.sample(uv, filter=f), want, uv, what=f)
        assert_close(tex.sample(uv, np.zeros((len(uv), 4), F32), filter=f), want, uv, what=f)


def test_constructor_filter_is_the_default():
    h, w = 23, 37
    image, _ = image_and_chain(h, w, 4, "uint8", True)
    uv, duv = random_queries(h, w)
    for f in ref.FILTERS:
        a = sr.Texture(image, filter=f).sample(uv, duv)
        b = sr.Texture(image).sample(uv, duv, filter=f)
        np.testing.assert_array_equal(a, b, err_msg=f)


# ------------------------------------------------------------------------------------- wrapping

def grid_uv(step: float) -> np.ndarray:
    t = np.arange(0.0, 1.0, step)
    return np.stack(np.meshgrid(t, t), -1).reshape(-1, 2).astype(F32)


@pytest.mark.parametrize("filter", ["nearest", "bilinear", "trilinear"])
@pytest.mark.parametrize("size", [(23, 37), (8, 16)], ids=size_id)
def test_wrap_periodicity(size, filter):
    h, w = size
    image, chain = image_and_chain(h, w, 4, "uint8", False)
    base = np.random.default_rng(12).integers(0, 2 ** 16, (200, 2)) / 2 ** 16  # 16-bit fractions
    base = base.astype(F32)
    # nearest is not mirror-symmetric exactly on a texel edge (floor picks the right-hand texel)
    base = base[((base[:, 0] * w) % 1 != 0) & ((base[:, 1] * h) % 1 != 0)]
    duv = np.tile([1.7 / w, 0.4 / h, -0.3 / w, 1.2 / h], (len(base), 1)).astype(F32)
    shifts = [(k, m) for k in (-3, -2, -1, 1, 2, 3) for m in (-3, 0, 2)]
    rep = sr.Texture(image, srgb=False, wrap="repeat")
    mir = sr.Texture(image, srgb=False, wrap="mirror")
    at_base_r = rep.sample(base, duv, filter=filter)
    at_base_m = mir.sample(base, duv, filter=filter)
    assert_close(at_base_r, ref.sample_chain(chain, base, duv, filter, "repeat"), base)
    assert_close(at_base_m, ref.sample_chain(chain, base, duv, filter, "mirror"), base)
    for k, m in shifts:
        uv = base + F32([k, m])
        np.testing.assert_array_equal(rep.sample(uv, duv, filter=filter), at_base_r,
                                      err_msg=f"repeat shift {(k, m)}")
        if k % 2 == 0 and m % 2 == 0:
            np.testing.assert_array_equal(mir.sample(uv, duv, filter=filter), at_base_m,
                                          err_msg=f"mirror shift {(k, m)}")
    # mirror reflects about 0 and about 1 (the same texture read backwards)
    for uv in (np.stack([-base[:, 0], base[:, 1]], 1), np.stack([base[:, 0], 2 - base[:, 1]], 1)):
        uv = uv.astype(F32)
        assert_close(mir.sample(uv, duv, filter=filter), at_base_m, uv, atol=1e-6, what="mirror")
    # clamp: everything beyond an edge is that edge's value
    cl = sr.Texture(image, srgb=False, wrap="clamp")
    for far, edge in [(-3.0, 0.0), (-1e6, 0.0), (3.0, 1.0), (1e6, 1.0), (2.0, 1.0), (-1.0, 0.0)]:
        uv_far = np.stack([np.full(len(base), far), base[:, 1]], 1).astype(F32)
        uv_edge = np.stack([np.full(len(base), edge), base[:, 1]], 1).astype(F32)
        np.testing.assert_array_equal(cl.sample(uv_far, duv, filter=filter),
                                      cl.sample(uv_edge, duv, filter=filter), err_msg=f"u={far}")
        uv_far, uv_edge = uv_far[:, ::-1].copy(), uv_edge[:, ::-1].copy()
        np.testing.assert_array_equal(cl.sample(uv_far, duv, filter=filter),
                                      cl.sample(uv_edge, duv, filter=filter), err_msg=f"v={far}")


@pytest.mark.parametrize("filter", ["nearest", "bilinear", "trilinear"])
def test_wrap_huge_uv(filter):
    """1e6 + offsets (offsets on the float32 grid of 1e6, multiples of 1/16): repeat and mirror
    (1e6 is even) give exactly the value at the offset; odd 1e6 + 1 mirrors."""
    h, w = 23, 37
    image, chain = image_and_chain(h, w, 3, "float32", False)
    off = grid_uv(1 / 16)
    duv = np.tile([2.5 / w, 0, 0, 0.5 / h], (len(off), 1)).astype(F32)
    for wrap in ("repeat", "mirror"):
        tex = sr.Texture(image, srgb=False, wrap=wrap)
        at_off = tex.sample(off, duv, filter=filter)
        assert_close(at_off, ref.sample_chain(chain, off, duv, filter, wrap), off, what=wrap)
        for big in ([1e6, 1e6], [-1e6, 1e6], [1e6, 0], [0, -1e6]):
            uv = off + F32(big)
            assert np.array_equal(uv - np.floor(uv), off)  # exactly representable
            np.testing.assert_array_equal(tex.sample(uv, duv, filter=filter), at_off,
                                          err_msg=f"{wrap} {big}")
    mir = sr.Texture(image, srgb=False, wrap="mirror")
    uv = (F32(1e6 + 1) + off).astype(F32)  # = 1 + off mod 2: the reflection of 1 - off
    refl = (F32(1) - off).astype(F32)
    assert_close(mir.sample(uv, duv, filter=filter),
                 mir.sample(refl, duv, filter=filter).astype(np.float64), uv, atol=1e-6,
                 what="mirror 1e6 + 1")


# ------------------------------------------------------------------------ NaN / inf robustness

@pytest.mark.parametrize("filter", ["nearest", "bilinear", "trilinear", "anisotropic"])
@pytest.mark.parametrize("wrap", ["repeat", "clamp", "mirror"])
def test_nan_uv_is_transparent_black(filter, wrap):
    h, w = 23, 37
    image, chain = image_and_chain(h, w, 4, "uint8", True)
    nan = np.nan
    uv = np.array([[nan, 0.3], [0.3, nan], [nan, nan], [0.3, 0.7], [-nan, 2.5]], F32)
    duv = np.tile([3.0 / w, 0.5 / h, 0.2 / w, 1.0 / h], (len(uv), 1)).astype(F32)
    got = sr.Texture(image, wrap=wrap).sample(uv, duv, filter=filter)
    np.testing.assert_array_equal(got[[0, 1, 2, 4]], np.zeros((4, 4), F32))
    assert_close(got[3:4], ref.sample_chain(chain, uv[3:4], duv[3:4], filter, wrap), uv[3:4])


@pytest.mark.parametrize("wrap", ["repeat", "clamp", "mirror"])
def test_inf_and_nan_derivatives(wrap):
    h, w = 23, 37
    image, chain = image_and_chain(h, w, 4, "uint16", False)
    tex = sr.Texture(image, srgb=False, wrap=wrap)
    inf, nan = np.inf, np.nan
    uv = np.random.default_rng(13).uniform(-3, 3, (6, 2)).astype(F32)
    inf_rows = np.array([[inf, 0, 0, 0], [0, 0, 0, inf], [-inf, 0, 0, 0], [inf] * 4,
                         [0, -inf, 0, 0], [1.0, 1.0, inf, -inf]], F32)
    last = ref.bilinear(chain[-1], uv[:, 0], uv[:, 1], wrap)  # the 1x1 level: the mean
    assert_close(tex.sample(uv, inf_rows, filter="trilinear"), last, uv, inf_rows, what="inf")
    assert_close(tex.sample(uv, inf_rows, filter="trilinear"),
                 np.broadcast_to(tex.mip(len(tex.levels) - 1)[0, 0], (6, 4)).astype(float), uv,
                 inf_rows, atol=1e-6, what="inf vs tex.mip(last)")
    nan_rows = np.array([[nan, 0, 0, 0], [0, nan, 0, 0], [0, 0, nan, 0], [0, 0, 0, nan],
                         [nan] * 4, [nan, nan, 0, 0]], F32)
    first = ref.bilinear(chain[0], uv[:, 0], uv[:, 1], wrap)
    assert_close(tex.sample(uv, nan_rows, filter="trilinear"), first, uv, nan_rows, what="NaN")
    # bilinear / nearest ignore the derivatives; anisotropic: defined only as 'no crash', finite
    for rows in (inf_rows, nan_rows):
        assert_close(tex.sample(uv, rows, filter="bilinear"), first, uv, rows, what="bilinear")
        got = tex.sample(uv, rows, filter="anisotropic")
        assert got.shape == (6, 4) and np.isfinite(got).all(), got


@pytest.mark.parametrize("filter", ["nearest", "bilinear", "trilinear", "anisotropic"])
@pytest.mark.parametrize("wrap", ["repeat", "clamp", "mirror"])
def test_inf_and_extreme_uv(filter, wrap):
    """Beyond the spec's letter (which names NaN): under repeat and mirror an infinite u or v
    reduces to NaN (inf - floor(inf)), so by the NaN rule it samples (0, 0, 0, 0); under clamp it
    clamps to the edge. Never a NaN colour, never a crash. The anisotropic filter is compared
    only where its footprint is finite in float32 (rows 0, 2, 4, 5, 7)."""
    h, w = 1, 16384
    image, chain = image_and_chain(h, w, 2, "uint8", False)
    big = np.finfo(F32).max
    uv = np.array([[np.inf, 0.5], [0.5, -np.inf], [big, -big], [-big, 0.5], [1e30, 1e-30],
                   [np.inf, np.nan], [3e38, 3e38], [-np.inf, 0.25]], F32)
    duv = np.array([[1, 0, 0, 1], [big, big, big, big], [0, 0, 0, 0], [np.inf, 0, 0, 0],
                    [1e-30, 0, 0, 1e-30], [0, 0, 0, 0], [np.nan] * 4, [0, 0, 0, 0]], F32)
    got = sr.Texture(image, srgb=False, wrap=wrap).sample(uv, duv, filter=filter)
    assert got.shape == (8, 4) and got.dtype == np.float32
    rows = [0, 2, 4, 5, 7] if filter == "anisotropic" else list(range(8))
    assert_close(got[rows], ref.sample_chain(chain, uv[rows], duv[rows], filter, wrap), uv[rows],
                 duv[rows])
    assert np.isfinite(got).all() and (got >= 0).all() and (got <= 1).all(), got


def test_empty_query():
    tex = sr.Texture(np.zeros((4, 4, 4), np.uint8))
    got = tex.sample(np.zeros((0, 2), F32), np.zeros((0, 4), F32))
    assert got.shape == (0, 4) and got.dtype == np.float32


# ---------------------------------------------------------------------------------- bad input

@pytest.mark.parametrize("dtype", [bool, np.int64, np.int32, np.complex64, np.int8, object])
def test_bad_image_dtype(dtype):
    with pytest.raises(TypeError, match="image"):
        sr.Texture(np.zeros((4, 4, 3), dtype=dtype))


@pytest.mark.parametrize("shape", [(4, 4, 0), (4, 4, 5), (0, 5), (5, 0), (0, 0, 3), (3, 0, 4),
                                   (4,), (2, 2, 2, 2), ()])
def test_bad_image_shape(shape):
    with pytest.raises(ValueError, match="image"):
        sr.Texture(np.zeros(shape, np.uint8))


@pytest.mark.parametrize("bad", [np.nan, -np.nan])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_nan_in_float_image(bad, dtype):
    img = np.ones((3, 4, 4), dtype)
    img[1, 2, 3] = bad
    with pytest.raises(ValueError, match="image"):
        sr.Texture(img)


def test_bad_filter_wrap_origin_anisotropy():
    img = np.zeros((4, 4, 3), np.uint8)
    with pytest.raises(ValueError, match="filter"):
        sr.Texture(img, filter="cubic")
    with pytest.raises(ValueError, match="filter"):
        sr.Texture(img).sample(np.zeros((1, 2), F32), filter="box")
    for wrap in ("border", ("repeat",), ("repeat", "clamp", "mirror"), ("repeat", "bogus"), ""):
        with pytest.raises(ValueError, match="wrap"):
            sr.Texture(img, wrap=wrap)
    with pytest.raises(ValueError, match="uv_origin"):
        sr.Texture(img, uv_origin="centre")
    for m in (0, -1):
        with pytest.raises(ValueError, match="max_anisotropy"):
            sr.Texture(img, max_anisotropy=m)
    with pytest.raises(TypeError, match="max_anisotropy"):  # a count: an int
        sr.Texture(img, max_anisotropy=0.5)


def test_bad_uv_and_duv_shapes():
    tex = sr.Texture(np.zeros((4, 4, 3), np.uint8))
    for uv in (np.zeros((3, 3)), np.zeros((3,)), np.zeros((2, 2, 2)), np.zeros((3, 1))):
        with pytest.raises(ValueError, match="uv"):
            tex.sample(uv)
    uv = np.zeros((3, 2))
    for duv in (np.zeros((3, 2)), np.zeros((2, 4)), np.zeros((4, 4)), np.zeros((3, 4, 1))):
        with pytest.raises(ValueError, match="duv"):
            tex.sample(uv, duv)
