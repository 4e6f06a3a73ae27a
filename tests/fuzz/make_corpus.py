"""Writes the seed corpus of tests/fuzz/fuzz_render.cpp into tests/fuzz/corpus/ (replacing it).

Each seed is one scene in the byte format documented at the top of fuzz_render.cpp: ordinary
scenes that reach every stage (clipping, guard band, mirroring, all outputs, thread counts) and
the edge cases the core must refuse or survive (NaN, inf, huge, tiny, bad indices and cameras).
Run: python3 tests/fuzz/make_corpus.py
"""
from __future__ import annotations

import math
import pathlib
import struct

import numpy as np

CORPUS = pathlib.Path(__file__).resolve().parent / "corpus"

NAN, INF = float("nan"), float("inf")
ALL_OUTPUTS = 0x7F
CULL = {"none": 0, "back": 1, "front": 2}


# --- encoders mirroring Reader in fuzz_render.cpp -------------------------------------------

def u8(v: int) -> bytes:
    return struct.pack("<B", v & 0xFF)


def value(x: float) -> bytes:
    """A double through the selector byte: specials by selector, the rest as a raw double."""
    specials = {0.0: 0, INF: 2, -INF: 3}
    if isinstance(x, float) and math.isnan(x):
        return u8(1)
    if x == 0.0 and math.copysign(1.0, x) < 0:
        return u8(8)
    if x in specials:
        return u8(specials[x])
    return u8(10) + struct.pack("<d", x)


def index(i: int, n: int) -> bytes:
    if 0 <= i < min(n, 0xF0):
        return u8(i)
    return u8(0xF4) + struct.pack("<i", i)  # a raw int32


def matrix(m=None) -> bytes:
    """None => identity; a (4, 4) array (row-major maths layout) => 16 raw values."""
    if m is None:
        return u8(0)
    m = np.asarray(m, dtype=np.float64)
    return u8(3) + b"".join(value(float(m[r, c])) for c in range(4) for r in range(4))


def translation(t) -> bytes:
    return u8(1) + b"".join(value(float(v)) for v in t)


def scale_translation(s, t) -> bytes:
    return u8(2) + b"".join(value(float(v)) for v in (*s, *t))


def rotation(angle, axis, t=(0, 0, 0)) -> bytes:
    return u8(4) + value(angle) + b"".join(value(float(v)) for v in (*axis, *t))


def mirror(t) -> bytes:
    return u8(5) + b"".join(value(float(v)) for v in t)


def perspective(fovy_deg: float = 45.0) -> bytes:
    return u8(0) + value(math.radians(fovy_deg))


def ortho(x: float, y: float) -> bytes:
    return u8(1) + value(x) + value(y)


def attribute(rows, mode: int | None = None) -> bytes:
    """mode: 0 absent, 1 one per vertex, 2 one too many, 3 one too few (rows as given)."""
    if rows is None:
        return u8(0)
    rows = np.asarray(rows, dtype=np.float64)
    return u8(1 if mode is None else mode) + b"".join(value(float(v)) for v in rows.ravel())


def scene(*, size=(64, 48), threads=1, outputs=ALL_OUTPUTS, cull="back", shading=1, ortho_cam=False,
          compare_threads=False, background=(0.1, 0.2, 0.3), ambient=0.25, view=None,
          near=0.1, far=100.0, proj=None, positions=(), faces=(), normals=None, colors=None,
          uvs=None, attr_modes=(None, None, None), draws=((None, 0, (0.8, 0.6, 0.4, 1.0)),),
          lit: bytes = b"") -> bytes:
    w, h = size
    b = u8(w - 1) + u8(h - 1) + u8(threads - 1) + u8(outputs) + u8(CULL[cull]) + u8(shading)
    b += u8(int(ortho_cam) | (2 if compare_threads else 0))
    b += b"".join(value(c) for c in background) + value(ambient)
    b += view if isinstance(view, bytes) else matrix(view)
    b += value(near) + value(far)
    b += proj if proj is not None else (ortho(2.0, 1.5) if ortho_cam else perspective())
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    n = len(positions)
    b += u8(n) + b"".join(value(float(v)) for v in positions.ravel())
    b += u8(len(faces)) + b"".join(index(int(i), n) for i in faces.ravel())
    for rows, mode in zip((normals, colors, uvs), attr_modes):
        b += attribute(rows, mode)
    b += u8(len(draws))
    for model, instance_id, rgba in draws:
        b += model if isinstance(model, bytes) else matrix(model)
        b += struct.pack("<i", instance_id) + b"".join(value(c) for c in rgba)
    return b + lit


def lighting(lights=(), ambient_light=(0.05, 0.05, 0.05), frequency=0, srgb=True, materials=()) -> bytes:
    """The lit model's tail: lights [(kind, radiance, position, direction, inverse_square, scale,
    offset)], ambient light, frequency, srgb, then per draw (brdf, flags, ka, kd, ks, emissive,
    shininess, metallic, roughness)."""
    b = u8(len(lights))
    for kind, rad, pos, dirn, inv_sq, scale, offset in lights:
        b += u8(kind) + b"".join(value(float(v)) for v in (*rad, *pos, *dirn))
        b += u8(int(inv_sq)) + value(scale) + value(offset)
    b += b"".join(value(v) for v in ambient_light) + u8(frequency) + u8(int(srgb))
    for brdf, flags, ka, kd, ks, em, shininess, metallic, roughness in materials:
        b += u8(brdf) + u8(flags) + b"".join(value(float(v)) for v in (*ka, *kd, *ks, *em))
        b += value(shininess) + value(metallic) + value(roughness)
    return b


def texturing(texels, channels=3, floats=False, srgb=True, top_left=False, mips=True, filt=2,
              wrap=(0, 0), max_aniso=16, override=0xFF, slots=((1, 1.0, 0),)) -> bytes:
    """The textures' tail: the render's filter override, one texture (texels (h, w, c) as
    uint8, or floats), then per draw (slots bits, normal_scale, normal_y_down)."""
    texels = np.asarray(texels)
    h, w = texels.shape[:2]
    b = u8(override) + u8(w - 1) + u8(h - 1) + u8(channels - 1)
    b += u8(int(floats) | (2 if srgb else 0) | (4 if top_left else 0) | (8 if mips else 0))
    b += u8(filt) + u8(wrap[0]) + u8(wrap[1]) + u8(max_aniso - 1)
    if floats:
        b += b"".join(value(float(v)) for v in texels.ravel())
    else:
        b += bytes(texels.astype(np.uint8).ravel())
    for bits, scale, y_down, *more in slots:
        b += u8(bits) + value(scale) + u8(y_down)
        if bits & 56:
            b += value(more[0] if more else 1.0) + value(more[1] if len(more) > 1 else 1.0)
        if bits & 64:
            b += value(more[2] if len(more) > 2 else 0.5)
    return b


# --- geometry -------------------------------------------------------------------------------

def primitive(points: bool, positions, segments=(), *, colors=None, width=1.0, size=None,
              pose=None, instance_id=7, depth_bias=0.0) -> bytes:
    """One line or point set after the extras byte: flags, positions, segments, colours, width
    (or size), pose, id, depth bias."""
    out = u8((1 if points else 0) | (2 if colors is not None else 0)) + u8(len(positions) - 1)
    out += b"".join(value(float(c)) for p in positions for c in p)
    if not points:
        out += u8(len(segments)) + b"".join(u8(a) + u8(b) for a, b in segments)
    if colors is not None:
        out += b"".join(value(float(c)) for rgb in colors for c in rgb)
    out += value(float(size if points and size is not None else width)) + matrix(pose)
    return out + struct.pack("<i", instance_id) + value(float(depth_bias))


def icosphere(subdivisions: int = 1):
    t = (1.0 + 5 ** 0.5) / 2.0
    p = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t],
         [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    for _ in range(subdivisions):
        mid = {}

        def midpoint(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                p.append([(x + y) / 2 for x, y in zip(p[a], p[b])])
                mid[key] = len(p) - 1
            return mid[key]

        nf = []
        for a, b, c in f:
            ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
            nf += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = nf
    p = np.array(p, dtype=np.float64)
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    return p, np.array(f)


def grid(nx: int, ny: int, size: float = 2.0, z: float = 0.0):
    xs, ys = np.meshgrid(np.linspace(-size / 2, size / 2, nx + 1), np.linspace(-size / 2, size / 2, ny + 1))
    p = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, z)], axis=1)
    f = []
    for j in range(ny):
        for i in range(nx):
            a = j * (nx + 1) + i
            f += [[a, a + 1, a + nx + 2], [a, a + nx + 2, a + nx + 1]]
    return p, np.array(f)


TRI = np.array([[-1.0, -1.0, -3.0], [1.0, -1.0, -3.0], [0.0, 1.0, -3.0]])


def seeds() -> dict[str, bytes]:
    sphere_p, sphere_f = icosphere(1)
    grid_p, grid_f = grid(6, 4)
    rng = np.random.default_rng(7)
    out = {}
    out["triangle"] = scene(positions=TRI, faces=[[0, 1, 2]], cull="none")
    out["triangle_ortho"] = scene(positions=TRI, faces=[[0, 1, 2]], ortho_cam=True)
    out["triangle_back_culled"] = scene(positions=TRI, faces=[[0, 2, 1]], cull="back")
    out["triangle_front_cull"] = scene(positions=TRI, faces=[[0, 2, 1]], cull="front", shading=0)
    out["sphere_all_attributes"] = scene(
        positions=sphere_p, faces=sphere_f, normals=sphere_p, colors=np.c_[(sphere_p + 1) / 2, np.ones(len(sphere_p))],
        uvs=sphere_p[:, :2], draws=((translation((0, 0, -4)), 3, (1, 1, 1, 1)),))
    out["sphere_two_instances_threads"] = scene(
        size=(200, 130), threads=3, compare_threads=True, positions=sphere_p, faces=sphere_f,
        draws=((translation((-0.7, 0, -4)), 1, (1, 0, 0, 1)), (translation((0.7, 0.2, -4.5)), 2, (0, 1, 0, 1))))
    out["sphere_ortho_three_draws"] = scene(
        ortho_cam=True, threads=2, compare_threads=True, positions=sphere_p, faces=sphere_f, normals=sphere_p,
        draws=tuple((translation((x, 0, -5)), i, (0.5, 0.5, 0.5, 1)) for i, x in enumerate((-1.2, 0, 1.2))))
    out["sphere_mirrored"] = scene(positions=sphere_p, faces=sphere_f, draws=((mirror((0, 0, -4)), 0, (1, 1, 1, 1)),))
    out["sphere_crossing_near"] = scene(positions=sphere_p, faces=sphere_f, near=0.5, cull="none",
                                        draws=((translation((0, 0, -0.7)), 0, (1, 1, 1, 1)),))
    out["sphere_camera_inside"] = scene(positions=sphere_p, faces=sphere_f, cull="none", normals=sphere_p,
                                        draws=((scale_translation((3, 3, 3), (0, 0, 0)), 0, (1, 1, 1, 1)),))
    out["sphere_crossing_far"] = scene(positions=sphere_p, faces=sphere_f, far=4.2,
                                       draws=((translation((0, 0, -4)), 0, (1, 1, 1, 1)),))
    out["guard_band_huge_triangle"] = scene(positions=TRI * [1e5, 1e5, 1], faces=[[0, 1, 2]], cull="none")
    out["guard_band_far_sideways"] = scene(positions=TRI + [3000, 0, 0], faces=[[0, 1, 2]], cull="none")
    out["grid_floor_grazing"] = scene(
        size=(256, 96), positions=grid_p, faces=grid_f, cull="none",
        draws=((rotation(-math.pi / 2 + 0.02, (1, 0, 0), (0, -0.3, -2)), 0, (1, 1, 1, 1)),))
    out["grid_rotated_threads"] = scene(
        size=(130, 129), threads=2, compare_threads=True, positions=grid_p, faces=grid_f,
        draws=((rotation(0.7, (0.3, 1, 0.2), (0, 0, -3)), 5, (1, 1, 1, 1)),))
    out["far_from_origin"] = scene(
        positions=TRI, faces=[[0, 1, 2]], view=translation((-1e6, 0, 0)),
        draws=((translation((1e6, 0, 0)), 0, (1, 1, 1, 1)),))
    out["tiny_scale"] = scene(positions=TRI * 1e-30, faces=[[0, 1, 2]], near=1e-35, far=1e-20, cull="none")
    out["huge_scale"] = scene(positions=TRI * 1e30, faces=[[0, 1, 2]], near=1e20, far=1e35, cull="none")
    out["denormal_vertices"] = scene(positions=[[1e-45, 0, -1], [0, 1e-45, -1], [1e-45, 1e-45, -1]],
                                     faces=[[0, 1, 2]], cull="none")
    out["singular_model"] = scene(positions=sphere_p, faces=sphere_f,
                                  draws=((scale_translation((1, 0, 1), (0, 0, -4)), 0, (1, 1, 1, 1)),))
    out["degenerate_triangles"] = scene(positions=[[0, 0, -2], [1, 1, -2], [2, 2, -2], [0, 0, -2]],
                                        faces=[[0, 1, 2], [0, 3, 1], [0, 0, 0]], cull="none")
    sliver = np.array([[0, 0, -2]] + [[math.cos(a), math.sin(a), -2] for a in np.linspace(0, 1e-3, 40)])
    out["sliver_fan"] = scene(positions=sliver, faces=[[0, i, i + 1] for i in range(1, 40)], cull="none")
    out["pixel_sizes_1x1"] = scene(size=(1, 1), positions=TRI, faces=[[0, 1, 2]], cull="none")
    out["pixel_sizes_256x1"] = scene(size=(256, 1), threads=3, compare_threads=True, positions=TRI, faces=[[0, 1, 2]])
    out["pixel_sizes_1x256"] = scene(size=(1, 256), threads=2, positions=TRI, faces=[[0, 1, 2]])
    out["pixel_sizes_256x256"] = scene(size=(256, 256), threads=3, compare_threads=True, positions=sphere_p,
                                       faces=sphere_f, draws=((translation((0, 0, -2.5)), 0, (1, 1, 1, 1)),))
    out["no_draws"] = scene(positions=TRI, faces=[[0, 1, 2]], draws=())
    for bit in range(7):
        out[f"output_bit{bit}"] = scene(positions=TRI, faces=[[0, 1, 2]], outputs=1 << bit, cull="none")
    # Refused inputs: the core must throw std::invalid_argument, not crash.
    out["bad_outputs_zero"] = scene(positions=TRI, faces=[[0, 1, 2]], outputs=0)
    out["bad_outputs_unknown_bit"] = scene(positions=TRI, faces=[[0, 1, 2]], outputs=0xFF)
    out["bad_ambient_nan"] = scene(positions=TRI, faces=[[0, 1, 2]], ambient=NAN)
    out["bad_near_zero"] = scene(positions=TRI, faces=[[0, 1, 2]], near=0.0)
    out["bad_far_below_near"] = scene(positions=TRI, faces=[[0, 1, 2]], near=2.0, far=1.0)
    out["bad_proj_nan"] = scene(positions=TRI, faces=[[0, 1, 2]], proj=u8(2) + value(NAN) * 16)
    out["bad_proj_zero"] = scene(positions=TRI, faces=[[0, 1, 2]], proj=u8(2) + value(0.0) * 16)
    out["bad_view_inf"] = scene(positions=TRI, faces=[[0, 1, 2]], view=translation((INF, 0, 0)))
    out["bad_model_nan"] = scene(positions=TRI, faces=[[0, 1, 2]], draws=((translation((NAN, 0, 0)), 0, (1, 1, 1, 1)),))
    out["bad_vertex_nan"] = scene(positions=[[NAN, 0, -1], [1, 0, -1], [0, 1, -1]], faces=[[0, 1, 2]])
    out["bad_vertex_inf"] = scene(positions=[[INF, 0, -1], [1, 0, -1], [0, 1, -1]], faces=[[0, 1, 2]])
    out["bad_index_negative"] = scene(positions=TRI, faces=[[0, 1, -1]])
    out["bad_index_out_of_range"] = scene(positions=TRI, faces=[[0, 1, 3]])
    out["bad_index_int_min"] = scene(positions=TRI, faces=[[-2 ** 31, 1, 2]])
    out["bad_normals_too_many"] = scene(positions=TRI, faces=[[0, 1, 2]], normals=np.ones((4, 3)), attr_modes=(2, None, None))
    out["bad_colors_too_few"] = scene(positions=TRI, faces=[[0, 1, 2]], colors=np.ones((2, 4)), attr_modes=(None, 3, None))
    out["bad_empty_mesh"] = scene(positions=np.zeros((0, 3)), faces=np.zeros((0, 3)))
    out["nan_normals_and_colors"] = scene(positions=TRI, faces=[[0, 1, 2]], normals=np.full((3, 3), NAN),
                                          colors=np.full((3, 4), NAN), cull="none")
    # Random soup: arbitrary triangles around the camera, some behind it.
    p = rng.normal(size=(60, 3)) * [2, 2, 3] + [0, 0, -2]
    out["random_soup"] = scene(size=(97, 71), threads=2, compare_threads=True, positions=p,
                               faces=rng.integers(0, 60, size=(80, 3)), cull="none")
    out["random_soup_raw_matrices"] = scene(
        positions=p, faces=rng.integers(0, 60, size=(40, 3)), cull="none", view=matrix(np.eye(4) + rng.normal(size=(4, 4)) * 0.1),
        proj=u8(2) + b"".join(value(float(v)) for v in rng.normal(size=16)),
        draws=((matrix(rng.normal(size=(4, 4))), 0, (1, 1, 1, 1)),))
    # The lit model (shading 4): every light kind, material model and frequency, and extremes.
    lights = [(0, (1, 0.9, 0.8), (0, 0, 0), (0, -0.6, -0.8), 0, 0.0, 1.0),
              (1, (3, 3, 3), (1, 1, -2), (0, 0, -1), 1, 0.0, 1.0),
              (2, (5, 2, 2), (0, 2, -3), (0, -1, 0), 1, 3.4, -2.4)]
    mats = [(b, b % 8, (0.1, 0.1, 0.1), (0.5, 0.4, 0.3), (0.6, 0.6, 0.6), (0.0, 0.01, 0.0), 40.0,
             0.5, 0.3) for b in range(6)]
    for freq in range(3):
        out[f"lit_sphere_models_frequency{freq}"] = scene(
            size=(120, 90), threads=2, compare_threads=True, outputs=0xFF, shading=4, cull="none",
            positions=sphere_p, faces=sphere_f, normals=sphere_p,
            colors=np.c_[(sphere_p + 1) / 2, np.ones(len(sphere_p))] if freq == 1 else None,
            draws=tuple((translation((x, 0, -4)), i, (0.7, 0.7, 0.7, 1)) for i, x in enumerate((-1.5, -0.5, 0.5, 1.5))),
            lit=lighting(lights, frequency=freq, srgb=freq != 2, materials=mats[freq:freq + 4]))
    out["lit_extreme_values"] = scene(
        outputs=0xFF, shading=4, positions=sphere_p, faces=sphere_f, normals=np.zeros_like(sphere_p),
        draws=((translation((0, 0, -3)), 0, (1, 1, 1, 1)),),
        lit=lighting([(1, (1e30, 1e30, 1e30), (0, 0, -3), (0, 0, 1), 1, 0.0, 1.0),
                      (2, (1, 1, 1), (0, 0, 0), (0, 0, 0), 0, 1e30, -1e30)],
                     materials=[(4, 0, (0, 0, 0), (0, 0, 0), (1, 1, 1), (0, 0, 0), 1e30, 1.0, 0.0)]))
    # Textures: every filter and wrap, uint8 and float texels, uvs far out, NaN and inf.
    checker = ((np.indices((16, 16)).sum(0) % 2) * 255)[:, :, None].repeat(3, 2)
    gp, gf = grid(6, 6)
    guv = np.c_[gp[:, 0], gp[:, 1]] * 3.0
    for filt in range(4):
        for wrap in range(3):
            out[f"tex_grid_filter{filt}_wrap{wrap}"] = scene(
                size=(80, 60), threads=2, compare_threads=True, outputs=0xFF, shading=4, cull="none",
                positions=gp, faces=gf, normals=np.tile([0, 0, 1.0], (len(gp), 1)), uvs=guv,
                view=rotation(1.2, (1, 0, 0), (0, 0, -2)),
                draws=((None, 0, (1, 1, 1, 1)),),
                lit=lighting(lights[:2], frequency=filt % 3, materials=[mats[filt + 1]])
                + texturing(checker, filt=filt, wrap=(wrap, (wrap + 1) % 3),
                            slots=((1 | (4 if filt % 2 else 0) | (2 if wrap == 2 else 0), 1.0, wrap % 2),)))
    odd = rng.random((7, 13, 4)) * 3 - 1
    odd[0, 0, 0], odd[1, 1, 1], odd[2, 2, 2] = NAN, INF, -INF
    out["tex_float_nan_inf_texels_far_uvs"] = scene(
        outputs=0xFF, shading=4, cull="none", positions=sphere_p, faces=sphere_f, normals=sphere_p,
        uvs=np.c_[sphere_p[:, 0] * 1e6, sphere_p[:, 1] * 1e30], draws=((translation((0, 0, -3)), 0, (1, 1, 1, 1)),),
        lit=lighting(lights, materials=[mats[4]])
        + texturing(odd, channels=4, floats=True, filt=3, max_aniso=32, override=3, slots=((7, 1e30, 1),)))
    out["tex_nan_uvs_one_texel"] = scene(
        outputs=0xFF, shading=4, positions=TRI, faces=[[0, 1, 2]], uvs=np.array([[NAN, 0], [INF, 1], [0, -INF]]),
        lit=lighting(lights[:1], materials=[mats[0]])
        + texturing(np.full((1, 1, 1), 200), channels=1, mips=False, filt=2, slots=((7, NAN, 0),)))
    # Alpha masks: an RGBA texture cut at its alpha, vertex alpha, clipped at the near plane,
    # depth only (nothing shaded), a NaN cutoff refused.
    rgba = rng.integers(0, 256, (16, 16, 4))
    valpha = np.c_[np.ones((len(gp), 3)), rng.random(len(gp))]
    for name, outputs, view, cutoff in (("mask_all_outputs", 0xFF, rotation(1.2, (1, 0, 0), (0, 0, -2)), 0.5),
                                        ("mask_depth_only", 2 | 16, rotation(1.2, (1, 0, 0), (0, 0, -2)), 0.3),
                                        ("mask_near_plane", 0xFF, rotation(1.5, (1, 0, 0), (0, 0.2, 0)), 0.5),
                                        ("mask_nan_cutoff", 0xFF, rotation(1.2, (1, 0, 0), (0, 0, -2)), NAN)):
        out[f"tex_alpha_{name}"] = scene(
            size=(80, 60), threads=2, compare_threads=True, outputs=outputs, shading=4, cull="none",
            positions=gp, faces=gf, normals=np.tile([0, 0, 1.0], (len(gp), 1)), uvs=guv, colors=valpha,
            view=view, draws=((None, 0, (1, 1, 1, 1)), (translation((0, 0, -0.3)), 1, (1, 1, 1, 0.2))),
            lit=lighting(lights[:1], materials=[mats[1], mats[2]])
            + texturing(rgba, channels=4, filt=3, slots=((1 | 64, 1.0, 0, 1.0, 1.0, cutoff),
                                                          (64, 1.0, 0, 1.0, 1.0, 0.5))))
    # Surface outputs (barycentric, uv, position, ray_depth) and camera-space normals: a sphere
    # compared across thread counts, a grid crossing the near plane (clipped faces), orthographic.
    surface = texturing(checker, slots=((0, 1.0, 0),)) + u8(0x1F)
    out["surface_sphere_threads"] = scene(
        threads=2, compare_threads=True, outputs=0xFF, shading=4, positions=sphere_p, faces=sphere_f,
        normals=sphere_p, uvs=sphere_p[:, :2], draws=((translation((0, 0, -3)), 0, (1, 1, 1, 1)),),
        lit=lighting(lights[:1], materials=[mats[0]]) + surface)
    out["surface_grid_near_plane"] = scene(
        size=(80, 60), threads=2, compare_threads=True, outputs=2 | 16, cull="none", positions=gp,
        faces=gf, uvs=guv, view=rotation(1.5, (1, 0, 0), (0, 0.2, 0)),
        lit=lighting(materials=[mats[0]]) + surface)
    out["surface_ortho"] = scene(
        ortho_cam=True, outputs=4, positions=sphere_p, faces=sphere_f,
        draws=((translation((0, 0, -3)), 5, (1, 1, 1, 1)),),
        lit=lighting(materials=[mats[0]]) + texturing(checker, slots=((0, 1.0, 0),)) + u8(0x0C))
    # The extras byte after the surface byte: double-sided draws never culled (and the override),
    # shading normals with a normal map, a specular map, and lines and points (far ones too).
    normal_map = np.zeros((8, 8, 3), np.uint8)
    normal_map[:] = (150, 110, 230)
    normal_map[::2, 1::2] = (100, 160, 220)
    for name, extras, prims in (
            ("never_culled_shading_normals", 1 << 3 | 2 | 4, b""),
            ("cull_double_sided_override", 1 | 1 << 3, b""),
            ("lines_and_points", 2 << 4,
             primitive(False, [(-1, -1, -3), (1, 1, -3), (1e20, 0.2, -4), (-1e30, 0.1, -4)],
                       [(0, 1), (2, 3)], width=2.5)
             + primitive(True, [(0, 0, -3), (0.5, -0.5, -2), (1e30, 0, -3)], size=3.0,
                         colors=[(1, 0, 0), (0, 1, 0), (NAN, 0, 1)])),
            ("lines_dda_depth_bias", 1 << 4 | 64,
             primitive(False, [(-1, 0, -2.9), (1, 0.3, -3.1), (0, 1, -3)], [(0, 1), (1, 2), (2, 0)],
                       width=1.0, depth_bias=0.01))):
        out[f"extras_{name}"] = scene(
            threads=2, compare_threads=True, outputs=0xFF, shading=4, cull="back", positions=sphere_p,
            faces=sphere_f, normals=sphere_p, uvs=sphere_p[:, :2],
            draws=((translation((0, 0, -3)), 0, (1, 1, 1, 1)),),
            lit=lighting(lights[:2], materials=[mats[0]])
            + texturing(normal_map, slots=((4, 1.0, 0),)) + u8(0x1F) + u8(extras) + prims)
    out["lit_nan_light_refused"] = scene(
        outputs=0xFF, shading=4, positions=TRI, faces=[[0, 1, 2]],
        lit=lighting([(0, (NAN, 1, 1), (0, 0, 0), (0, 0, -1), 0, 0.0, 1.0)], materials=[mats[3]]))
    return out


def main() -> None:
    CORPUS.mkdir(exist_ok=True)
    for old in CORPUS.glob("*.bin"):
        old.unlink()
    total = 0
    for name, data in seeds().items():
        (CORPUS / f"{name}.bin").write_bytes(data)
        total += len(data)
    print(f"wrote {len(seeds())} seeds, {total} bytes, to {CORPUS}")


if __name__ == "__main__":
    main()
