"""An independent NumPy reference for order-independent alpha blending (glTF alphaMode BLEND),
no softrast code: every fragment of every triangle at every pixel centre, sorted, composited.

The rules it implements (the ones ``Material(alpha_mode="blend")`` promises):

* coverage: tests/support/raster_reference.py's (vertices snapped to 1/256 px, exact integer edge
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

import math
from dataclasses import dataclass, field

import numpy as np

from . import raster_reference as raster_ref

# ----------------------------------------------------------------------------- cameras


@dataclass
class RefCamera:
    """A camera at the origin looking down -z (softrast's identity pose, OpenGL view axes).

    Perspective: gluPerspective's projection with vertical field of view ``fov_y`` degrees and the
    image's aspect; orthographic: half extents ``xmag``, ``ymag``. Window space: x right, y down,
    (0, 0) the image's top-left corner.
    """
    width: int
    height: int
    fov_y: float | None = None
    xmag: float | None = None
    ymag: float | None = None

    @property
    def perspective(self) -> bool:
        return self.fov_y is not None

    def _scales(self) -> tuple[float, float]:
        if self.perspective:
            f = 1.0 / math.tan(math.radians(self.fov_y) / 2.0)
            return f / (self.width / self.height), f
        return 1.0 / self.xmag, 1.0 / self.ymag

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n, 3) world points -> ((n, 2) window xy, (n,) view depth = -z), float64."""
        p = np.asarray(points, np.float64)
        sx, sy = self._scales()
        depth = -p[:, 2]
        div = depth if self.perspective else np.ones_like(depth)
        ndc_x, ndc_y = sx * p[:, 0] / div, sy * p[:, 1] / div
        xy = np.stack([(ndc_x + 1.0) * self.width / 2.0, (1.0 - ndc_y) * self.height / 2.0], axis=1)
        return xy, depth

    def unproject(self, xy: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """Inverse of ``project``: window xy at view depth -> (n, 3) world points (float64)."""
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        depth = np.broadcast_to(np.asarray(depth, np.float64), (len(xy),))
        sx, sy = self._scales()
        ndc_x = xy[:, 0] * 2.0 / self.width - 1.0
        ndc_y = 1.0 - xy[:, 1] * 2.0 / self.height
        mul = depth if self.perspective else np.ones_like(depth)
        return np.stack([ndc_x / sx * mul, ndc_y / sy * mul, -depth], axis=1)


# ----------------------------------------------------------------------------- triangles


@dataclass
class Tri:
    """One triangle of one draw, as the reference sees it (listed in draw order, then face order)."""
    xy: np.ndarray            # (3, 2) window coordinates, float64
    depth: np.ndarray         # (3,) view depths (> 0)
    rgba: np.ndarray          # (3, 4) linear RGBA per corner
    blend: bool               # alphaMode BLEND (else opaque)
    cull: str = "none"        # "none" | "back" | "front"
    uv: np.ndarray | None = None       # (3, 2)
    texture: np.ndarray | None = None  # (th, tw, 4) linear RGBA texels, float64
    draw: int = 0
    face: int = 0
    verts: tuple = (0, 1, 2)  # the corners' vertex indices within the draw


def f32(a) -> np.ndarray:
    """Values as the core stores them (float32), back in float64."""
    return np.asarray(a, np.float32).astype(np.float64)


def srgb_decode(v: np.ndarray) -> np.ndarray:
    """The exact IEC 61966-2-1 curve, encoded [0, 1] -> linear."""
    v = np.asarray(v, np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def srgb_encode_u8(v: np.ndarray) -> np.ndarray:
    """Linear -> sRGB-encoded bytes (clamped to [0, 1], rounded to nearest)."""
    v = np.clip(np.asarray(v, np.float64), 0.0, 1.0)
    e = np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)
    return np.floor(e * 255.0 + 0.5).astype(np.int64)


def texture_linear(image: np.ndarray, srgb: bool) -> np.ndarray:
    """(h, w, c) uint8 image -> (h, w, 4) linear RGBA float64 (texture.py's channel rules: 1 grey,
    2 grey + alpha, 3 RGB, 4 RGBA; colour channels sRGB-decoded if ``srgb``; alpha never)."""
    img = np.asarray(image)
    if img.ndim == 2:
        img = img[:, :, None]
    assert img.dtype == np.uint8
    v = img.astype(np.float64) / 255.0
    c = v.shape[2]
    rgb = {1: v[:, :, [0, 0, 0]], 2: v[:, :, [0, 0, 0]], 3: v[:, :, :3], 4: v[:, :, :3]}[c]
    a = v[:, :, 1] if c == 2 else v[:, :, 3] if c == 4 else np.ones(v.shape[:2])
    if srgb:
        rgb = srgb_decode(rgb)
    return np.concatenate([rgb, a[:, :, None]], axis=2)


def mesh_tris(cam: RefCamera, positions, faces, *, rgba=None, base_color=(0.8, 0.8, 0.8, 1.0),
              blend: bool, cull: str = "none", uvs=None, texture=None, draw: int = 0,
              pose: np.ndarray | None = None) -> list[Tri]:
    """The triangles of one draw: ``positions`` (object space, stored as float32 as softrast
    stores them) under ``pose``, per-vertex ``rgba`` (replacing ``base_color``, whose alpha too) or
    the base colour, optional ``uvs`` and a linear RGBA ``texture`` (see ``texture_linear``)."""
    pos = f32(positions)
    if pose is not None:
        pose = np.asarray(pose, np.float64)
        pos = pos @ pose[:3, :3].T + pose[:3, 3]
    xy, depth = cam.project(pos)
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    if rgba is not None:
        col = f32(rgba)
        if col.shape[1] == 3:
            col = np.c_[col, np.ones(len(col))]
    else:
        col = np.tile(f32(base_color), (len(pos), 1))
    uv = None if uvs is None else f32(uvs)
    return [Tri(xy[f], depth[f], col[f], blend, cull, None if uv is None else uv[f], texture,
                draw, k, tuple(int(v) for v in f)) for k, f in enumerate(faces)]


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
        area = raster_ref.signed_area2_fixed(raster_ref.snap(t.xy), np.array([[0, 1, 2]]))[0]
        c = constant.setdefault(t.draw, t.rgba[0].copy())
        if t.texture is not None or not (t.rgba == c).all():
            constant[t.draw] = None
        for k in range(3):
            key = (t.draw, frozenset((t.verts[k], t.verts[(k + 1) % 3])))
            by_edge.setdefault(key, []).append(np.sign(area))
    return {key for key, signs in by_edge.items()
            if len(signs) == 2 and signs[0] == signs[1] != 0 and constant.get(key[0]) is not None}


def _near_segment(a: np.ndarray, b: np.ndarray, px: np.ndarray, py: np.ndarray, eps: float) -> np.ndarray:
    d = b - a
    ll = float(d @ d)
    t = np.zeros_like(px) if ll == 0.0 else np.clip(((px - a[0]) * d[0] + (py - a[1]) * d[1]) / ll, 0, 1)
    return np.hypot(px - (a[0] + t * d[0]), py - (a[1] + t * d[1])) <= eps


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
        """(h, w) the nearest fragment's depth, inf where none."""
        out = np.full(self.width * self.height, np.inf)
        np.minimum.at(out, self.pixel, self.depth)
        return out.reshape(self.height, self.width)


def fragments(tris: list[Tri], cam: RefCamera, weights: str = "snapped", margin: float = 0.01,
              uv_margin: float = 1e-3) -> Fragments:
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
                    near_edge[i0:i1 + 1, j0:j1 + 1] |= _near_segment(t.xy[e], t.xy[(e + 1) % 3],
                                                                     bx, by, margin)
        fixed = raster_ref.snap(t.xy)
        cov, _ = raster_ref.rasterize(fixed, np.array([[0, 1, 2]]), w, h, cull=t.cull, fixed=True)
        rows, cols = np.nonzero(cov)
        if len(rows) == 0:
            continue
        px, py = cols + 0.5, rows + 0.5
        b_exact, d = _perspective(_screen_weights(t.xy, px, py), t.depth, cam.perspective)
        # the fixed-point sample positions, for the snapped weights
        spx = (cols * raster_ref.SUBPIXEL_ONE + raster_ref.SUBPIXEL_HALF).astype(np.float64)
        spy = (rows * raster_ref.SUBPIXEL_ONE + raster_ref.SUBPIXEL_HALF).astype(np.float64)
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
    radiance: np.ndarray        # (h, w, 3) premultiplied linear (0 behind nothing)
    alpha: np.ndarray           # (h, w)
    transmittance: np.ndarray   # (h, w) T_n
    opaque: np.ndarray          # (h, w) index into tris of the visible opaque fragment, -1 none
    layers: np.ndarray          # (h, w) blended fragments composited
    ambiguous: np.ndarray       # (h, w) bool

    def color(self, background=(0.0, 0.0, 0.0), srgb: bool = True) -> np.ndarray:
        """The ``color`` output: the composite over the background (its byte's linear value where
        no opaque surface is seen), clamped and encoded to bytes."""
        bg_byte = np.floor(np.asarray(background, np.float64) * 255.0 + 0.5) / 255.0
        bg = srgb_decode(bg_byte) if srgb else bg_byte
        c = self.radiance + np.where(self.opaque[..., None] < 0, self.transmittance[..., None] * bg, 0.0)
        if srgb:
            return srgb_encode_u8(c)
        return np.floor(np.clip(c, 0.0, 1.0) * 255.0 + 0.5).astype(np.int64)


def composite(frags: Fragments, depth_tol: float = 1e-5) -> Composite:
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
    return composite(fragments(tris, cam, weights, margin), depth_tol)


def threshold_surface(frags: Fragments, threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """What ``render(alpha_threshold=threshold)`` reports as each pixel's surface: the nearest
    fragment (depth order, ties in ``tris`` order) that is opaque or blended with an alpha of at
    least ``threshold``. Returns (h, w) arrays: its index into ``tris`` (-1: none) and its depth
    (inf: none)."""
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
