"""An independent NumPy reference for order-independent alpha blending (glTF alphaMode BLEND),
no softrast code: every fragment of every triangle at every pixel centre, sorted, composited.

The rules it implements (the ones ``Material(alpha_mode="blend")`` promises):

* coverage: softrast.reference.raster's (vertices snapped to 1/256 px, exact integer edge
  functions, the top-left rule); pixel (row i, col j) has its centre at window (j + 0.5, i + 0.5);
* a fragment's depth is the view depth of the unsnapped triangle at the pixel centre
  (perspective-correct, float64); its colour and alpha are the per-vertex RGBA (the material's
  base colour repeated when the mesh has no vertex colours) interpolated perspective-correctly,
  with the snapped triangle's weights (``weights="snapped"``: what the raster's unlit shading
  reads) or the unsnapped one's (``"exact"``; ``"screen"``: the snapped screen-space weights,
  not perspective-correct, only to show that a test can tell), times a base colour texture's
  texel (nearest filter, repeat, uv origin bottom-left, uvs always interpolated with the exact
  weights) where the draw has one; alpha clamped to [0, 1];
* at each pixel the fragments are sorted nearest first (equal depths: draw order, then face
  order, i.e. the order of ``tris``); blended fragments in front of the nearest opaque one are
  composited front to back in linear light: C = sum_i T_i a_i c_i + T_n B, T_0 = 1,
  T_{i+1} = T_i (1 - a_i), B the opaque fragment's colour (0 where there is none);
* ``alpha`` = 1 where an opaque fragment is seen, else 1 - T_n.

A pixel is flagged ``ambiguous`` where the comparison cannot be exact by construction: its centre
lies within ``margin`` px of an edge of any triangle (coverage there depends on float32 rounding
and on the snap; except an edge inside a draw of one colour, where one of its two faces covers
the pixel either way), two of its fragments up to the nearest opaque one have depths within
``depth_tol`` (relative) of each other (their order is then the core's tie rule), or a textured
fragment's uv lies within ``uv_margin`` texels of a texel boundary.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .encoding import linear_encode, srgb_encode, srgb_to_linear
from .raster import SUBPIXEL_HALF, SUBPIXEL_ONE, near_segment, rasterize, signed_area2_fixed, snap
from .triangles import RefCamera, Tri, f32, mesh_tris, texture_linear

__all__ = ["RefCamera", "Tri", "f32", "texture_linear", "mesh_tris",
           "Fragments", "fragments", "Composite", "composite", "render", "threshold_surface"]

# ----------------------------------------------------------------------------- fragments


def _interior_edges(tris: list[Tri]) -> set:
    """Edges (draw, vertex pair) where exactly two faces of one draw meet with the same winding
    on screen, so the two lie on opposite sides of it and exactly one covers each pixel centre
    near it (watertight), and whose fragment there is the same either way: the draw's colour is
    one RGBA over all its corners, without a texture (depths agree on the edge, and a pixel centre
    within ``margin`` of it is far from any depth tie that matters). Pixels near such edges need
    not be excluded."""
    by_edge: dict = {}
    constant: dict = {}
    for t in tris:
        area = signed_area2_fixed(snap(t.xy), np.array([[0, 1, 2]]))[0]
        c = constant.setdefault(t.draw, t.rgba[0].copy())
        if t.texture is not None or not (t.rgba == c).all():
            constant[t.draw] = None
        for k in range(3):
            key = (t.draw, frozenset((t.verts[k], t.verts[(k + 1) % 3])))
            by_edge.setdefault(key, []).append(np.sign(area))
    return {key for key, signs in by_edge.items()
            if len(signs) == 2 and signs[0] == signs[1] != 0 and constant.get(key[0]) is not None}


def _screen_weights(xy: np.ndarray, px: np.ndarray, py: np.ndarray) -> np.ndarray:
    """(3, ...) screen-space barycentric weights of the triangle ``xy`` at points (px, py)."""
    a, b, c = xy
    area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])

    def edge(p, q):  # twice the signed area of (p, q, point)
        return (q[0] - p[0]) * (py - p[1]) - (q[1] - p[1]) * (px - p[0])

    return np.stack([edge(b, c), edge(c, a), edge(a, b)]) / area


def _perspective(lam: np.ndarray, depth: np.ndarray, perspective: bool) -> tuple[np.ndarray, np.ndarray]:
    """Screen weights -> (perspective-correct weights, depth at the point)."""
    if not perspective:
        return lam, np.tensordot(depth, lam, axes=1)
    q = lam / depth.reshape((3,) + (1,) * (lam.ndim - 1))
    s = q.sum(axis=0)
    return q / s, 1.0 / s


def _nearest_texel(tex: np.ndarray, uv: np.ndarray, uv_margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Nearest, repeat, bottom-left origin: (..., 4) texels at (2, ...) uvs, and where a uv is
    within ``uv_margin`` texels of a texel boundary."""
    th, tw = tex.shape[:2]
    x = (uv[0] - np.floor(uv[0])) * tw
    y = (1.0 - (uv[1] - np.floor(uv[1]))) * th
    near = (np.abs(x - np.rint(x)) < uv_margin) | (np.abs(y - np.rint(y)) < uv_margin)
    col = np.floor(x).astype(np.int64) % tw
    row = np.floor(y).astype(np.int64) % th
    return tex[row, col], near


@dataclass
class Fragments:
    """Every fragment of every triangle (flat arrays, one entry per covered pixel centre)."""
    width: int
    height: int
    pixel: np.ndarray          # (m,) row * width + col
    tri: np.ndarray            # (m,) index into ``tris`` (draw order, then face order)
    depth: np.ndarray          # (m,) view depth (tests may overwrite it to force exact ties)
    rgba: np.ndarray           # (m, 4) linear colour, alpha clamped to [0, 1]
    blend: np.ndarray          # (n,) per triangle
    near_edge: np.ndarray      # (h, w) bool
    near_texel: np.ndarray     # (h, w) bool
    tris: list = field(default_factory=list)

    def nearest_depth(self) -> np.ndarray:
        """The nearest fragment's depth per pixel.

        Returns
        -------
        numpy.ndarray
            (h, w) float64, inf where there is none.
        """
        out = np.full(self.width * self.height, np.inf)
        np.minimum.at(out, self.pixel, self.depth)
        return out.reshape(self.height, self.width)


def fragments(tris: list[Tri], cam: RefCamera, weights: str = "snapped", margin: float = 0.01,
              uv_margin: float = 1e-3) -> Fragments:
    """Every fragment of every triangle (see the module docstring).

    Parameters
    ----------
    tris : list of Tri
        In draw order, then face order (``mesh_tris``).
    cam : RefCamera
        The camera.
    weights : {"snapped", "exact", "screen"}
        The colour's interpolation weights.
    margin : float
        Pixel centres within this many px of an edge are flagged (``near_edge``).
    uv_margin : float
        Textured fragments within this many texels of a texel boundary are flagged.

    Returns
    -------
    Fragments
    """
    w, h = cam.width, cam.height
    near_edge = np.zeros((h, w), bool)
    near_texel = np.zeros((h, w), bool)
    interior = _interior_edges(tris)
    pixels, tri_idx, depths, colours = [], [], [], []
    pad = int(np.ceil(margin)) + 1
    for k, t in enumerate(tris):
        # pixel centres near an edge that is not inside a one-colour draw
        j0 = max(0, int(np.floor(t.xy[:, 0].min())) - pad)
        j1 = min(w - 1, int(np.ceil(t.xy[:, 0].max())) + pad)
        i0 = max(0, int(np.floor(t.xy[:, 1].min())) - pad)
        i1 = min(h - 1, int(np.ceil(t.xy[:, 1].max())) + pad)
        if j0 <= j1 and i0 <= i1:
            bx, by = np.meshgrid(np.arange(j0, j1 + 1) + 0.5, np.arange(i0, i1 + 1) + 0.5)
            for e in range(3):
                if (t.draw, frozenset((t.verts[e], t.verts[(e + 1) % 3]))) not in interior:
                    near_edge[i0:i1 + 1, j0:j1 + 1] |= near_segment(t.xy[e], t.xy[(e + 1) % 3],
                                                                     bx, by, margin)
        fixed = snap(t.xy)
        cov, _ = rasterize(fixed, np.array([[0, 1, 2]]), w, h, cull=t.cull, fixed=True)
        rows, cols = np.nonzero(cov)
        if len(rows) == 0:
            continue
        px, py = cols + 0.5, rows + 0.5
        b_exact, d = _perspective(_screen_weights(t.xy, px, py), t.depth, cam.perspective)
        # the fixed-point sample positions, for the snapped weights
        spx = (cols * SUBPIXEL_ONE + SUBPIXEL_HALF).astype(np.float64)
        spy = (rows * SUBPIXEL_ONE + SUBPIXEL_HALF).astype(np.float64)
        if weights == "snapped":
            b, _ = _perspective(_screen_weights(fixed.astype(np.float64), spx, spy), t.depth,
                                cam.perspective)
        elif weights == "exact":
            b = b_exact
        elif weights == "screen":  # not perspective-correct (for showing that it matters)
            b = _screen_weights(fixed.astype(np.float64), spx, spy)
        else:
            raise ValueError(weights)
        col = t.rgba.T @ b  # (4, m)
        if t.texture is not None:
            uv = t.uv.T @ b_exact
            texel, near = _nearest_texel(t.texture, uv, uv_margin)
            col = col * texel.T
            near_texel[rows[near], cols[near]] = True
        col[3] = np.clip(col[3], 0.0, 1.0)
        pixels.append(rows * w + cols)
        tri_idx.append(np.full(len(rows), k))
        depths.append(d)
        colours.append(col.T)
    cat = (lambda parts, shape: np.concatenate(parts) if parts else np.zeros(shape))
    return Fragments(w, h, cat(pixels, 0).astype(np.int64), cat(tri_idx, 0).astype(np.int64),
                     cat(depths, 0), cat(colours, (0, 4)), np.array([t.blend for t in tris], bool),
                     near_edge, near_texel, tris)


@dataclass
class Composite:
    """The composited image (``composite``)."""
    radiance: np.ndarray        # (h, w, 3) premultiplied linear (0 behind nothing)
    alpha: np.ndarray           # (h, w)
    transmittance: np.ndarray   # (h, w) T_n
    opaque: np.ndarray          # (h, w) index into tris of the visible opaque fragment, -1 none
    layers: np.ndarray          # (h, w) blended fragments composited
    ambiguous: np.ndarray       # (h, w) bool

    def color(self, background: Any = (0.0, 0.0, 0.0), srgb: bool = True) -> np.ndarray:
        """The ``color`` output: the composite over the background.

        Parameters
        ----------
        background : array_like, shape (3,)
            The background colour (its byte's linear value shows where no opaque surface is).
        srgb : bool
            Encode with the sRGB curve (else linearly).

        Returns
        -------
        numpy.ndarray
            (h, w, 3) int64 bytes.
        """
        bg_byte = np.floor(np.asarray(background, np.float64) * 255.0 + 0.5) / 255.0
        bg = srgb_to_linear(bg_byte) if srgb else bg_byte
        c = self.radiance + np.where(self.opaque[..., None] < 0, self.transmittance[..., None] * bg, 0.0)
        return (srgb_encode(c) if srgb else linear_encode(c)).astype(np.int64)


def composite(frags: Fragments, depth_tol: float = 1e-5) -> Composite:
    """Sort each pixel's fragments and composite them (see the module docstring).

    Parameters
    ----------
    frags : Fragments
        From ``fragments``.
    depth_tol : float
        Relative depth difference below which two fragments' order is ambiguous.

    Returns
    -------
    Composite
    """
    h, w = frags.height, frags.width
    npix = h * w
    # sorted per pixel: nearest first, ties in ``tris`` order (draw order, then face order)
    order = np.lexsort((frags.tri, frags.depth, frags.pixel))
    pix = frags.pixel[order]
    counts = np.bincount(pix, minlength=npix)
    n = max(int(counts.max(initial=0)), 1)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    rank = np.arange(len(pix)) - starts[pix]
    # dense (n, h, w) layers: layer k holds each pixel's k-th nearest fragment
    d = np.full((n, npix), np.inf)
    cov = np.zeros((n, npix), bool)
    rgba = np.zeros((n, npix, 4))
    tri = np.full((n, npix), -1)
    d[rank, pix] = frags.depth[order]
    cov[rank, pix] = True
    rgba[rank, pix] = frags.rgba[order]
    tri[rank, pix] = frags.tri[order]
    d, cov, tri = (x.reshape(n, h, w) for x in (d, cov, tri))
    rgba = rgba.reshape(n, h, w, 4)
    blend = cov & frags.blend[np.maximum(tri, 0)]
    opaque_frag = cov & ~blend
    # opaque fragments strictly before position k
    opaque_before = np.cumsum(opaque_frag, axis=0) - opaque_frag
    contrib = blend & (opaque_before == 0)
    a = np.where(contrib, rgba[..., 3], 0.0)
    trans = np.cumprod(1.0 - a, axis=0)
    t_before = np.concatenate([np.ones((1, h, w)), trans[:-1]], axis=0)
    rad = np.einsum("khw,khwc->hwc", t_before * a, rgba[..., :3])
    t_n = trans[-1]
    first_opaque = opaque_frag & (opaque_before == 0)
    has_opaque = first_opaque.any(axis=0)
    opaque_pos = np.argmax(first_opaque, axis=0)
    opaque_rgb = np.take_along_axis(rgba[..., :3], opaque_pos[None, :, :, None], axis=0)[0]
    rad = rad + np.where(has_opaque[..., None], t_n[..., None] * opaque_rgb, 0.0)
    opaque_idx = np.where(has_opaque, np.take_along_axis(tri, opaque_pos[None], axis=0)[0], -1)
    alpha = np.where(has_opaque, 1.0, 1.0 - t_n)
    # ambiguity: consecutive covered fragments up to (and one past) the nearest opaque one whose
    # depths are within depth_tol (relative)
    ambiguous = frags.near_edge | frags.near_texel
    if n > 1:
        both = cov[:-1] & cov[1:] & (opaque_before[:-1] == 0)
        with np.errstate(invalid="ignore"):
            close = np.abs(d[1:] - d[:-1]) < depth_tol * np.abs(d[:-1])
        ambiguous = ambiguous | (both & close).any(axis=0)
    return Composite(rad, alpha, t_n, opaque_idx, contrib.sum(axis=0), ambiguous)


def render(tris: list[Tri], cam: RefCamera, weights: str = "snapped", margin: float = 0.01,
           depth_tol: float = 1e-5) -> Composite:
    """``composite(fragments(tris, cam, weights, margin), depth_tol)``.

    Parameters
    ----------
    tris, cam, weights, margin
        As for ``fragments``.
    depth_tol : float
        As for ``composite``.

    Returns
    -------
    Composite
    """
    return composite(fragments(tris, cam, weights, margin), depth_tol)


def threshold_surface(frags: Fragments, threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """What ``render(alpha_threshold=threshold)`` reports as each pixel's surface: the nearest
    fragment (depth order, ties in ``tris`` order) that is opaque or blended with an alpha of at
    least ``threshold``.

    Parameters
    ----------
    frags : Fragments
        From ``fragments``.
    threshold : float
        The alpha threshold.

    Returns
    -------
    tri : numpy.ndarray, shape (h, w)
        The surface's index into ``tris``, -1 where none.
    depth : numpy.ndarray, shape (h, w)
        Its depth, inf where none.
    """
    h, w = frags.height, frags.width
    qualifies = ~frags.blend[frags.tri] | (frags.rgba[:, 3] >= threshold)
    order = np.lexsort((frags.tri, frags.depth, frags.pixel))
    order = order[qualifies[order]]
    pix = frags.pixel[order]
    first = np.ones(len(pix), bool)
    first[1:] = pix[1:] != pix[:-1]
    tri = np.full(h * w, -1)
    depth = np.full(h * w, np.inf)
    tri[pix[first]] = frags.tri[order[first]]
    depth[pix[first]] = frags.depth[order[first]]
    return tri.reshape(h, w), depth.reshape(h, w)
