"""Independent NumPy reference of softrast's texture sampler, written from the texture spec
(decoding, coordinates, wrapping, box-filtered mip chain, nearest / bilinear / trilinear /
anisotropic), not from the C++ core. Vectorised over n points.

    decode(image, srgb) -> (h, w, 4) float64 linear RGBA (srgb_to_linear from .encoding)
    mip_chain(level0) -> [level 0, level 1, ..., 1x1], float64 (h_l, w_l, 4)
    sample(image, uv, duv=None, filter="bilinear", wrap=("repeat", "repeat"), srgb=False,
           max_anisotropy=16, uv_origin="bottom_left") -> (n, 4) float64
    sample_chain(chain, uv, ...)  the same on an already decoded mip chain (or on any list of
                                  levels, e.g. the core's own tex.mip(l))

Precision. The core computes texel coordinates in float32, so this reference does the same for
the coordinate arithmetic the spec writes down, operation by operation (wrap reduction of u and
v, x = u * w, y = (1 - v) * h, x - 0.5, floor, the fraction, the anisotropic sample positions
uv + d * ((i + 0.5) / N - 0.5)); the texel values, the blends, the mip chain and the level of
detail are float64. Fed the same float32 uv, floor() then sees exactly the values the core sees,
so texel-boundary points need not be avoided. (The only discontinuities left that float32 vs
float64 can move are the integer steps of N = ceil(Pmax / Pmin - 1/64) in the anisotropic
filter; the tests keep away from those.)
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .encoding import srgb_to_linear

__all__ = ["FILTERS", "WRAPS", "srgb_to_linear", "decode", "box_weights", "mip_chain", "level_sizes",
           "reduce_coord", "wrap_index", "texel_xy", "nearest", "bilinear", "axes", "clamp_lambda",
           "trilinear", "aniso_count", "anisotropic", "sample_chain", "sample"]

F32 = np.float32
FILTERS = ("nearest", "bilinear", "trilinear", "anisotropic")
WRAPS = ("repeat", "clamp", "mirror")


# ------------------------------------------------------------------------------------- decoding

def decode(image: Any, srgb: bool) -> np.ndarray:
    """A texture image as linear RGBA (texture.py's channel rules).

    Parameters
    ----------
    image : array_like, shape (h, w) or (h, w, c)
        uint8 (/ 255), uint16 (/ 65535) or float (as float32) values; c = 1 grey, 2 grey + alpha,
        3 RGB, 4 RGBA.
    srgb : bool
        Decode the colour channels (never the alpha) with ``srgb_to_linear``.

    Returns
    -------
    numpy.ndarray
        (h, w, 4) float64 linear RGBA (alpha 1 without an alpha channel).
    """
    a = np.asarray(image)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.dtype == np.uint8:
        v = a / 255.0
    elif a.dtype == np.uint16:
        v = a / 65535.0
    else:  # float32 as is (float64 input is converted to float32 by the API)
        v = a.astype(np.float32).astype(np.float64)
    c = v.shape[2]
    colour = v[..., :1] if c <= 2 else v[..., :3]
    if srgb:
        colour = srgb_to_linear(colour)  # never the alpha
    out = np.ones(v.shape[:2] + (4,))
    out[..., :3] = colour  # broadcasts L to (L, L, L)
    if c in (2, 4):
        out[..., 3] = v[..., c - 1]
    return out


# ------------------------------------------------------------------------------------ mip chain

def box_weights(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Exact area weights of one mip step along one axis, n texels -> m = max(1, n // 2).

    New texel i covers source [i n/m, (i+1) n/m); the weight of source texel j is its overlap
    length / (n / m). Computed in integers scaled by m (texel j = [j m, (j+1) m), new texel
    i = [i n, (i+1) n)).

    Parameters
    ----------
    n : int
        The source level's size along the axis.

    Returns
    -------
    index : numpy.ndarray, shape (m, 4)
        The source texels of each new texel (repeated where it spans fewer than 4).
    weight : numpy.ndarray, shape (m, 4)
        Their weights (0 for the repeats), summing to 1 per new texel.
    """
    m = max(1, n // 2)
    i = np.arange(m)[:, None]
    j = (i * n) // m + np.arange(4)[None, :]  # the new texel spans < 4 source texels... at most 4
    overlap = np.minimum((i + 1) * n, (j + 1) * m) - np.maximum(i * n, j * m)
    weight = np.clip(overlap, 0, None) / n
    return np.minimum(j, n - 1), weight


def _down(level: np.ndarray, axis: int) -> np.ndarray:
    idx, wt = box_weights(level.shape[axis])
    taken = np.take(level, idx, axis=axis)  # axis becomes (m, 4)
    shape = [1] * taken.ndim
    shape[axis], shape[axis + 1] = wt.shape
    return (taken * wt.reshape(shape)).sum(axis=axis + 1)


def mip_chain(level0: np.ndarray) -> list[np.ndarray]:
    """The box-filtered mip chain of a level 0.

    Parameters
    ----------
    level0 : numpy.ndarray, shape (h, w, 4)
        Linear RGBA.

    Returns
    -------
    list of numpy.ndarray
        Every level down to 1x1, float64 (each step filters columns, then rows).
    """
    chain = [np.asarray(level0, dtype=np.float64)]
    while chain[-1].shape[:2] != (1, 1):
        chain.append(_down(_down(chain[-1], axis=1), axis=0))
    return chain


def level_sizes(h: int, w: int) -> list[tuple[int, int]]:
    """The (height, width) of every mip level of an h x w texture.

    Parameters
    ----------
    h, w : int
        Level 0's size.

    Returns
    -------
    list of tuple of int
        Halved (floor, at least 1) step by step down to (1, 1).
    """
    sizes = [(h, w)]
    while sizes[-1] != (1, 1):
        sizes.append((max(1, sizes[-1][0] // 2), max(1, sizes[-1][1] // 2)))
    return sizes


# ---------------------------------------------------------------------------- coordinates, wrap

def _pair(wrap) -> tuple[str, str]:
    return (wrap, wrap) if isinstance(wrap, str) else tuple(wrap)


def reduce_coord(u: np.ndarray, mode: str) -> np.ndarray:
    """The float32 reduction of u (or v) before it is scaled to texels.

    Parameters
    ----------
    u : numpy.ndarray
        Coordinates (converted to float32).
    mode : {"repeat", "clamp", "mirror"}
        The wrap mode: u - floor(u), clamp to [-1, 2], or u - 2 floor(u / 2).

    Returns
    -------
    numpy.ndarray
        float32, the same shape.
    """
    u = u.astype(F32)
    if mode == "repeat":
        return u - np.floor(u)
    if mode == "mirror":
        return u - F32(2) * np.floor(u / F32(2))
    return np.clip(u, F32(-1), F32(2))


def wrap_index(i: np.ndarray, n: int, mode: str) -> np.ndarray:
    """Texel indices wrapped into [0, n).

    Parameters
    ----------
    i : numpy.ndarray
        Integer texel indices (any).
    n : int
        The level's size along the axis.
    mode : {"repeat", "clamp", "mirror"}
        The wrap mode.

    Returns
    -------
    numpy.ndarray
        Indices in [0, n), the same shape.
    """
    if mode == "repeat":
        return np.mod(i, n)
    if mode == "clamp":
        return np.clip(i, 0, n - 1)
    m = np.mod(i, 2 * n)
    return np.where(m < n, m, 2 * n - 1 - m)


def texel_xy(u: np.ndarray, v: np.ndarray, h: int, w: int, wrap: Any,
             uv_origin: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Texture coordinates in texel units of one level, in float32 as the spec writes them.

    Parameters
    ----------
    u, v : numpy.ndarray, shape (n,)
        Texture coordinates.
    h, w : int
        The level's size.
    wrap : str or pair of str
        The wrap mode of u and v.
    uv_origin : {"bottom_left", "top_left"}
        Where v = 0 is: y = (1 - v) h or y = v h.

    Returns
    -------
    x, y : numpy.ndarray, shape (n,)
        float32 texel coordinates (0 at the NaN points).
    bad : numpy.ndarray, shape (n,)
        bool, where u or v is NaN (those points' colour is (0, 0, 0, 0)).
    """
    wu, wv = _pair(wrap)
    with np.errstate(invalid="ignore"):
        ru, rv = reduce_coord(u, wu), reduce_coord(v, wv)
    bad = ~(np.isfinite(ru) & np.isfinite(rv))  # NaN u or v (inf reduces to NaN except in clamp)
    ru, rv = np.where(bad, F32(0), ru), np.where(bad, F32(0), rv)
    x = ru * F32(w)
    y = (F32(1) - rv) * F32(h) if uv_origin == "bottom_left" else rv * F32(h)
    return x, y, bad


def nearest(level: np.ndarray, u: np.ndarray, v: np.ndarray, wrap: Any,
            uv_origin: str = "bottom_left") -> np.ndarray:
    """The nearest filter: the texel containing each point.

    Parameters
    ----------
    level : numpy.ndarray, shape (h, w, 4)
        One linear RGBA level.
    u, v, wrap, uv_origin
        As for ``texel_xy``.

    Returns
    -------
    numpy.ndarray
        (n, 4) float64 RGBA.
    """
    h, w = level.shape[:2]
    wu, wv = _pair(wrap)
    x, y, bad = texel_xy(u, v, h, w, wrap, uv_origin)
    j = wrap_index(np.floor(x).astype(np.int64), w, wu)
    r = wrap_index(np.floor(y).astype(np.int64), h, wv)
    return np.where(bad[:, None], 0.0, level[r, j])


def bilinear(level: np.ndarray, u: np.ndarray, v: np.ndarray, wrap: Any,
             uv_origin: str = "bottom_left") -> np.ndarray:
    """The bilinear filter.

    Parameters
    ----------
    level, u, v, wrap, uv_origin
        As for ``nearest``.

    Returns
    -------
    numpy.ndarray
        (n, 4) float64 RGBA: the four texels around (x - 1/2, y - 1/2), blended in float64 by
        the float32 fractions.
    """
    h, w = level.shape[:2]
    wu, wv = _pair(wrap)
    x, y, bad = texel_xy(u, v, h, w, wrap, uv_origin)
    xs, ys = x - F32(0.5), y - F32(0.5)
    j0, r0 = np.floor(xs), np.floor(ys)
    fx, fy = (xs - j0).astype(np.float64)[:, None], (ys - r0).astype(np.float64)[:, None]
    j0, r0 = j0.astype(np.int64), r0.astype(np.int64)
    ja, jb = wrap_index(j0, w, wu), wrap_index(j0 + 1, w, wu)
    ra, rb = wrap_index(r0, h, wv), wrap_index(r0 + 1, h, wv)
    top = level[ra, ja] + (level[ra, jb] - level[ra, ja]) * fx
    bottom = level[rb, ja] + (level[rb, jb] - level[rb, ja]) * fx
    return np.where(bad[:, None], 0.0, top + (bottom - top) * fy)


def _bilinear_at(chain, lvl, u, v, wrap, uv_origin) -> np.ndarray:
    """Bilinear at a per-point level index."""
    out = np.zeros((len(u), 4))
    for l in np.unique(lvl):
        m = lvl == l
        out[m] = bilinear(chain[l], u[m], v[m], wrap, uv_origin)
    return out


# ------------------------------------------------------------------------------ level of detail

def axes(duv: np.ndarray, h0: int, w0: int) -> tuple[np.ndarray, np.ndarray]:
    """The lengths of the screen-x and screen-y footprints in level-0 texels.

    Parameters
    ----------
    duv : numpy.ndarray, shape (n, 4)
        (du/dx, dv/dx, du/dy, dv/dy) per point.
    h0, w0 : int
        Level 0's size.

    Returns
    -------
    ax, ay : numpy.ndarray, shape (n,)
        |(du/dx w0, dv/dx h0)| and |(du/dy w0, dv/dy h0)|, float64.
    """
    d = np.asarray(duv, dtype=np.float64)
    return np.hypot(d[:, 0] * w0, d[:, 1] * h0), np.hypot(d[:, 2] * w0, d[:, 3] * h0)


def clamp_lambda(rho: np.ndarray, n_levels: int) -> np.ndarray:
    """The level of detail of a footprint.

    Parameters
    ----------
    rho : numpy.ndarray
        Footprint lengths in level-0 texels.
    n_levels : int
        L, the chain's number of levels.

    Returns
    -------
    numpy.ndarray
        log2(rho) clamped to [0, L - 1] (rho = 0 or NaN -> 0, inf -> L - 1), float64.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.log2(rho)
    return np.clip(np.where(np.isnan(lam), 0.0, lam), 0.0, n_levels - 1)


def trilinear(chain: Sequence[np.ndarray], u: np.ndarray, v: np.ndarray, lam: np.ndarray,
              wrap: Any, uv_origin: str = "bottom_left") -> np.ndarray:
    """Bilinear on levels floor(lambda) and floor(lambda) + 1, blended by the fraction.

    Parameters
    ----------
    chain : sequence of numpy.ndarray
        The levels (``mip_chain``).
    u, v, wrap, uv_origin
        As for ``texel_xy``.
    lam : numpy.ndarray, shape (n,)
        The level of detail per point (``clamp_lambda``).

    Returns
    -------
    numpy.ndarray
        (n, 4) float64 RGBA.
    """
    l0 = np.floor(lam).astype(np.int64)
    t = (lam - l0)[:, None]
    l1 = np.minimum(l0 + 1, len(chain) - 1)
    a = _bilinear_at(chain, l0, u, v, wrap, uv_origin)
    b = _bilinear_at(chain, l1, u, v, wrap, uv_origin)
    return a + (b - a) * t


ANISO_SLACK = 1 / 64  # ceil(Pmax / Pmin - 1/64): rounding-level anisotropy stays one probe


def aniso_count(la: np.ndarray, lb: np.ndarray, max_anisotropy: int) -> np.ndarray:
    """The anisotropic filter's number of probes.

    Parameters
    ----------
    la, lb : numpy.ndarray, shape (n,)
        The footprint's axis lengths (``axes``).
    max_anisotropy : int
        The most probes.

    Returns
    -------
    numpy.ndarray
        int64 N = min(ceil(Pmax / Pmin - 1/64), max_anisotropy), Pmin = 0 -> max_anisotropy,
        N >= 1 (float64 here; the core's float32 ratio can only differ right at the steps
        Pmax / Pmin = k + 1/64, which the tests avoid).
    """
    pmax, pmin = np.maximum(la, lb), np.minimum(la, lb)
    with np.errstate(divide="ignore", invalid="ignore"):
        n = np.minimum(np.ceil(pmax / pmin - ANISO_SLACK), max_anisotropy)
    n = np.where(pmin == 0, max_anisotropy, n)
    return np.maximum(np.where(np.isnan(n), 1, n), 1).astype(np.int64)


def anisotropic(chain: Sequence[np.ndarray], u: np.ndarray, v: np.ndarray, duv: np.ndarray,
                wrap: Any, max_anisotropy: int = 16, uv_origin: str = "bottom_left") -> np.ndarray:
    """The anisotropic filter: the mean of N trilinear probes along the footprint's major axis,
    at uv + d ((i + 0.5) / N - 0.5), each at lambda = log2(Pmax / N).

    Parameters
    ----------
    chain, u, v, wrap, uv_origin
        As for ``trilinear``.
    duv : numpy.ndarray, shape (n, 4)
        (du/dx, dv/dx, du/dy, dv/dy) per point.
    max_anisotropy : int
        The most probes.

    Returns
    -------
    numpy.ndarray
        (n, 4) float64 RGBA.
    """
    h0, w0 = chain[0].shape[:2]
    d32 = np.asarray(duv, dtype=F32)
    la, lb = axes(d32, h0, w0)
    n = aniso_count(la, lb, max_anisotropy)
    with np.errstate(invalid="ignore"):
        lam = clamp_lambda(np.maximum(la, lb) / n, len(chain))
    major_x = la >= lb
    du = np.where(major_x, d32[:, 0], d32[:, 2])
    dv = np.where(major_x, d32[:, 1], d32[:, 3])
    # All N samples of all points at once: point p[k], sample index i[k] in 0..N-1.
    p = np.repeat(np.arange(len(u)), n)
    i = np.arange(len(p)) - np.repeat(np.cumsum(n) - n, n)
    off = (i.astype(F32) + F32(0.5)) / n[p].astype(F32) - F32(0.5)  # float32, as written
    with np.errstate(invalid="ignore", over="ignore"):
        pu = u[p] + du[p] * off
        pv = v[p] + dv[p] * off
    values = trilinear(chain, pu, pv, lam[p], wrap, uv_origin)
    total = np.stack([np.bincount(p, values[:, c], minlength=len(u)) for c in range(4)], axis=1)
    return total / n[:, None]


# ---------------------------------------------------------------------------------- entry points

def sample_chain(chain: Sequence[np.ndarray], uv: Any, duv: Any = None, filter: str = "bilinear",
                 wrap: Any = ("repeat", "repeat"), max_anisotropy: int = 16,
                 uv_origin: str = "bottom_left") -> np.ndarray:
    """Sample a list of linear RGBA levels.

    Parameters
    ----------
    chain : sequence of numpy.ndarray
        (h_l, w_l, 4) levels, level 0 first (``mip_chain``, or e.g. the core's own tex.mip(l)).
    uv : array_like, shape (n, 2)
        Texture coordinates (converted to float32).
    duv : array_like, shape (n, 4), optional
        (du/dx, dv/dx, du/dy, dv/dy); zero when None.
    filter : {"nearest", "bilinear", "trilinear", "anisotropic"}
        The filter.
    wrap : str or pair of str
        The wrap mode of u and v ("repeat", "clamp" or "mirror").
    max_anisotropy : int
        The anisotropic filter's most probes.
    uv_origin : {"bottom_left", "top_left"}
        Where v = 0 is.

    Returns
    -------
    numpy.ndarray
        (n, 4) float64 linear RGBA.
    """
    uv = np.asarray(uv, dtype=F32).reshape(-1, 2)
    u, v = uv[:, 0], uv[:, 1]
    duv = np.zeros((len(uv), 4), F32) if duv is None else np.asarray(duv, dtype=F32).reshape(-1, 4)
    if filter == "nearest":
        return nearest(chain[0], u, v, wrap, uv_origin)
    if filter == "bilinear":
        return bilinear(chain[0], u, v, wrap, uv_origin)
    h0, w0 = chain[0].shape[:2]
    if filter == "trilinear":
        la, lb = axes(duv, h0, w0)
        return trilinear(chain, u, v, clamp_lambda(np.maximum(la, lb), len(chain)), wrap, uv_origin)
    if filter == "anisotropic":
        return anisotropic(chain, u, v, duv, wrap, max_anisotropy, uv_origin)
    raise ValueError(f"unknown filter {filter!r}")


def sample(image: Any, uv: Any, duv: Any = None, filter: str = "bilinear",
           wrap: Any = ("repeat", "repeat"), srgb: bool = False, max_anisotropy: int = 16,
           uv_origin: str = "bottom_left") -> np.ndarray:
    """The reference of softrast.Texture(image, srgb, wrap=..., ...).sample(uv, duv, filter).

    Parameters
    ----------
    image, srgb
        The texture image, decoded by ``decode(image, srgb)``.
    uv, duv, filter, wrap, max_anisotropy, uv_origin
        As for ``sample_chain``.

    Returns
    -------
    numpy.ndarray
        (n, 4) float64 linear RGBA.
    """
    return sample_chain(mip_chain(decode(image, srgb)), uv, duv, filter, wrap, max_anisotropy,
                        uv_origin)
