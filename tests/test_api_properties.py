"""Property test of the public API's promise: every call either renders a correct frame
or raises ValueError / TypeError naming the argument that is wrong; never another exception
type, a crash or a hang.

Each example builds a Renderer, meshes, a Scene, a camera and a render call from strategies
that draw, for every argument, a valid value (over wide ranges: singular and mirroring poses,
extreme fields of view, near/far ratios of 1e9, tiny and huge scenes, a vertex at 1e19-1e30
among unit ones; materials with textures in every slot, of every dtype and 1 to 4 channels,
float ones up to 1e30; lights of intensity up to 3.4e38, placed up to 1e30 away; lines and
points up to 1e30; msaa and ssaa; both normal kinds) or, for at most one
argument, a bad one whose expected argument name is known. A returned frame must satisfy the
invariants the fuzzer checks on the C++ core (mask == depth > 0, ids -1 exactly on background,
finite normals of length 1 on covered pixels and 0 elsewhere, finite radiance >= 0, background
colour where nothing is hit, the requested outputs with their shapes and dtypes).

The examples run in a child process under a timeout, so a crash fails the test with its signal
and a hang fails it at the timeout instead of stalling CI. derandomize=True: the same examples
every run. SOFTRAST_HYPOTHESIS_EXAMPLES sets their number (default 200, about 15 s with the
textures, anti-aliasing and primitives; 1,500 pass in about 2 min).
"""
from __future__ import annotations

import math
import os
import re
import subprocess
import sys
import warnings

import numpy as np

EXAMPLES = int(os.environ.get("SOFTRAST_HYPOTHESIS_EXAMPLES", "200"))
TIMEOUT_S = 120 + EXAMPLES * 0.5  # a hang guard only (200 examples take ~15 s, 1,500 ~2 min)


def test_public_api_renders_correctly_or_names_the_bad_argument():
    env = dict(os.environ, SOFTRAST_HYPOTHESIS_EXAMPLES=str(EXAMPLES))
    try:
        proc = subprocess.run([sys.executable, __file__], capture_output=True, text=True,
                              timeout=TIMEOUT_S, env=env)
    except subprocess.TimeoutExpired as exc:
        raise AssertionError(f"the property run hung (no result in {TIMEOUT_S:.0f} s):\n"
                             f"{exc.stdout}\n{exc.stderr}") from None
    assert proc.returncode == 0, (f"property run failed, exit code {proc.returncode} "
                                  f"(negative: killed by that signal):\n{proc.stdout}\n{proc.stderr}")
    counts = re.search(r"examples: (\d+) rendered: (\d+) refused: (\d+) \(renders with pixels hit: (\d+)", proc.stdout)
    assert counts, proc.stdout
    examples, rendered, refused, hit = map(int, counts.groups())
    # Both outcomes exercised, and renders that cover pixels (300 examples: ~200 / 100 / 90).
    assert examples >= EXAMPLES and rendered > EXAMPLES // 2 and refused > EXAMPLES // 10, proc.stdout
    assert hit > EXAMPLES // 10, proc.stdout


# ---------------------------------------------------------------------------------------------
# Everything below runs in the child process.
# ---------------------------------------------------------------------------------------------

OUTPUTS = ("color", "depth", "mask", "normal", "triangle_id", "instance_id", "coverage", "radiance")
SHADINGS = ("auto", "unlit", "lambert", "phong", "blinn_phong", "pbr", "normal", "uv")
DTYPES = {"radiance": (np.float32, 3), "color": (np.uint8, 3), "depth": (np.float32, 0), "mask": (np.bool_, 0),
          "normal": (np.float32, 3), "triangle_id": (np.int32, 0), "instance_id": (np.int32, 0),
          "coverage": (np.uint32, 0)}


def _strategies():
    from hypothesis import strategies as st

    def floats(lo, hi):
        return st.floats(lo, hi, allow_nan=False, allow_infinity=False)

    def log_floats(lo_exp, hi_exp):  # positive floats spread over decades
        return st.tuples(floats(lo_exp, hi_exp), floats(1.0, 9.99)).map(lambda t: t[1] * 10.0 ** t[0])

    not_numbers = st.sampled_from([True, False, "1", "abc", b"1", 1j, [1.0], np.array([1.0]), np.bool_(True)])
    not_numbers_or_none = st.one_of(st.none(), not_numbers)  # for arguments where None is no default
    unit = st.one_of(floats(0.0, 1.0), st.sampled_from([0, 1, np.float32(0.5), np.float64(0.25)]))
    rgb = st.one_of(st.tuples(unit, unit, unit), st.tuples(unit, unit, unit).map(np.array))

    # ---- good values --------------------------------------------------------------------------
    def rotation(draw):
        q = np.array(draw(st.tuples(*[floats(-1.0, 1.0)] * 4)))
        q = q / np.linalg.norm(q) if np.linalg.norm(q) > 1e-3 else np.array([1.0, 0.0, 0.0, 0.0])
        w, x, y, z = q
        return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])

    @st.composite
    def model_pose(draw):
        scale = draw(st.sampled_from(["one", "one", "one", "uniform", "axes", "singular"]))
        if scale == "one":
            s = np.ones(3)
        elif scale == "uniform":
            s = np.full(3, draw(st.sampled_from([1e-30, 1e-3, 0.5, 2.0, 1e3, -1.0, 1e-6])))
        elif scale == "axes":
            s = np.array(draw(st.tuples(*[st.sampled_from([1.0, -1.0, 0.3, 4.0, 1e-30, -2.0])] * 3)))
        else:  # zero scale on one, two or three axes
            s = np.array(draw(st.tuples(*[st.sampled_from([0.0, 1.0, -1.5])] * 3)))
        pose = np.eye(4)
        pose[:3, :3] = rotation(draw) @ np.diag(s)
        pose[:3, 3] = draw(st.tuples(*[floats(-1.0, 1.0)] * 3))
        if draw(st.integers(0, 19)) == 0:
            pose[:3, 3] *= draw(st.sampled_from([1e6, 1e20, -1e30]))  # far away
        return pose if draw(st.booleans()) else pose.tolist()

    @st.composite
    def mesh_args(draw):
        # Fixed, well-spread points plus drawn offsets (hypothesis favours zeros: drawn points
        # alone would mostly coincide), a fan of faces over them, and maybe drawn extra faces.
        n = draw(st.integers(3, 9))
        scale = draw(st.sampled_from([1.0] * 16 + [1e-20, 1e-3, 1e3, 1e20, 1e30]))
        offsets = np.array(draw(st.lists(st.tuples(*[floats(-1.0, 1.0)] * 3), min_size=n, max_size=n)))
        positions = (np.random.default_rng(n).uniform(-1.5, 1.5, (n, 3)) + offsets) * scale
        faces = [[0, k, k + 1] for k in range(1, n - 1)]
        faces += draw(st.lists(st.tuples(*[st.integers(0, n - 1)] * 3), max_size=6))
        kw = {"positions": positions, "faces": np.array(faces)}
        if draw(st.booleans()):
            kw["normals"] = np.array(draw(st.lists(st.tuples(*[floats(-1.0, 1.0)] * 3),
                                                   min_size=n, max_size=n)))
        if draw(st.integers(0, 3)) == 0:
            kw["colors"] = np.array(draw(st.lists(st.tuples(unit, unit, unit), min_size=n, max_size=n)),
                                    dtype=np.float64)
        if draw(st.booleans()):
            kw["color"] = draw(rgb)
        if draw(st.booleans()):  # uvs over a few periods, for the textures
            kw["uvs"] = np.random.default_rng(n + 1).uniform(-2.0, 3.0, (n, 2)) * draw(
                st.sampled_from([1.0, 1.0, 1e-3, 1e6]))
        if scale == 1.0 and draw(st.integers(0, 9)) == 0:  # one vertex very far among unit ones
            kw["positions"] = kw["positions"].copy()
            kw["positions"][0] *= draw(st.sampled_from([1e19, 1e30, -1e25]))
        return kw

    @st.composite
    def camera_args(draw, w=16, h=16):
        kind = draw(st.sampled_from(["perspective", "orthographic", "intrinsics"]))
        near = draw(st.sampled_from([0.05, 0.05, 0.05, 1e-3, 0.5, 1e-6, 2.0]))
        ratio = draw(st.sampled_from([1e3, 1e4, 1e4, 1e4, 1e4, 1e9, 2.0]))
        far = near * ratio if ratio < 1e3 else max(near * ratio, 20.0)  # near/far up to 1e9
        kw = {"near": near, "far": far}
        if kind == "perspective":
            extreme = draw(st.integers(0, 4)) == 0
            kw["fov_y"] = draw(st.sampled_from([1e-3, 179.99, 1e-20]) if extreme else floats(10.0, 150.0))
            if draw(st.booleans()):
                kw["aspect"] = draw(st.sampled_from([0.5, 1.0, 2.0, 0.7, 1.5, 1e-3, 1e3]))
        elif kind == "orthographic":
            extreme = draw(st.integers(0, 4)) == 0
            kw["xmag"] = draw(log_floats(-6, 3) if extreme else floats(0.5, 5.0))
            kw["ymag"] = draw(log_floats(-6, 3) if extreme else floats(0.5, 5.0))
        else:
            extreme = draw(st.integers(0, 4)) == 0
            kw["fx"] = draw(log_floats(-2, 4) if extreme else floats(0.3 * w, 2.0 * w))
            kw["fy"] = draw(log_floats(-2, 4) if extreme else floats(0.3 * h, 2.0 * h))
            kw["cx"] = draw(floats(-50.0, 100.0) if extreme else floats(0.0, w))
            kw["cy"] = draw(floats(-50.0, 100.0) if extreme else floats(0.0, h))
            kw["convention"] = draw(st.sampled_from(["opencv", "opengl"]))
        return kind, kw

    @st.composite
    def placement(draw):
        # Mostly a camera 2-8 units from the origin looking near it, where the meshes are.
        direction = np.array(draw(st.tuples(*[floats(-1.0, 1.0)] * 3)))
        if np.linalg.norm(direction) < 1e-3:
            direction = np.array([0.0, 0.0, 1.0])
        eye = direction / np.linalg.norm(direction) * draw(floats(2.0, 8.0))
        target = np.array(draw(st.tuples(*[floats(-0.5, 0.5)] * 3)))
        if draw(st.booleans()):
            up = np.array(draw(st.sampled_from([(0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, 1.0, 0.3)])))
            d = target - eye
            # Valid by construction: eye != target, up not parallel to the view direction.
            if np.linalg.norm(d) < 1e-3 or np.linalg.norm(np.cross(d / np.linalg.norm(d), up)) < 0.05 * np.linalg.norm(up):
                eye = target + np.array([0.1, 0.2, 3.0])
            return {"look_at": (eye, target, up)}
        pose = np.eye(4)
        if draw(st.integers(0, 4)) == 0:
            pose[:3, :3] = rotation(draw)  # anywhere
        else:  # looking at the origin along its -z, rolled at random (OpenGL axes)
            z = eye / np.linalg.norm(eye)
            x = np.cross(rotation(draw)[:, 0], z)
            x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-6 else np.cross(z, [0.6, 0.0, 0.8]) / np.linalg.norm(np.cross(z, [0.6, 0.0, 0.8]))
            pose[:3, 0], pose[:3, 1], pose[:3, 2] = x, np.cross(z, x), z
        pose[:3, 3] = eye
        return {"pose": pose}

    @st.composite
    def render_args(draw):
        outputs = draw(st.one_of(st.sampled_from(OUTPUTS),
                                 st.lists(st.sampled_from(OUTPUTS), min_size=1, max_size=8).map(tuple)))
        aa = draw(st.sampled_from([{}, {}, {}, {"msaa": 4}, {"msaa": 2}, {"ssaa": 2}, {"ssaa": 3}]))
        return {**aa, "outputs": outputs,
                "cull": draw(st.sampled_from(["back", "front", "none", "none"])),
                "cull_double_sided": draw(st.booleans()),
                "normal_kind": draw(st.sampled_from(["interpolated", "shading"])),
                "shading": draw(st.sampled_from(SHADINGS)),
                "frequency": draw(st.sampled_from(["pixel", "pixel", "vertex", "face"])),
                "srgb": draw(st.booleans()),
                "shading_path": draw(st.sampled_from(["auto", "forward", "deferred"])),
                "background": draw(rgb),
                "ambient": draw(unit)}

    @st.composite
    def texture_args(draw):
        # 1 to 4 channels of every dtype, float ones up to HDR values of 1e30.
        dtype = draw(st.sampled_from([np.uint8, np.uint16, np.float32, np.float64]))
        c = draw(st.integers(1, 4))
        h, w = draw(st.integers(1, 9)), draw(st.integers(1, 9))
        rng = np.random.default_rng(h * 31 + w * 7 + c)
        if np.dtype(dtype).kind == "u":
            image = rng.integers(0, np.iinfo(dtype).max, (h, w, c), endpoint=True).astype(dtype)
        else:
            top = draw(st.sampled_from([1.0, 1.0, 4.0, 1e6, 1e30]))
            image = (rng.uniform(0.0, 1.0, (h, w, c)) * top).astype(dtype)
        return {"image": image, "filter": draw(st.sampled_from(["nearest", "bilinear", "trilinear", "anisotropic"])),
                "wrap": draw(st.sampled_from(["repeat", "clamp", "mirror"])),
                "srgb": draw(st.sampled_from([None, None, False]))}

    @st.composite
    def material_args(draw):
        kw = {"base_color": draw(rgb), "ks": draw(rgb), "shininess": draw(st.sampled_from([0.0, 1.0, 32.0, 1e4, 3.4e38])),
              "metallic": draw(unit), "roughness": draw(unit), "emissive": draw(rgb),
              "double_sided": draw(st.booleans()),
              "model": draw(st.sampled_from([None, "lambert", "phong", "blinn_phong", "pbr", "unlit", "normal"]))}
        for slot in ("base_color_texture", "emissive_texture", "normal_texture", "bump_texture",
                     "metallic_roughness_texture", "occlusion_texture", "specular_texture"):
            if draw(st.integers(0, 5)) == 0:
                kw[slot] = draw(texture_args())
        if draw(st.integers(0, 4)) == 0:
            kw["alpha_mode"] = "mask"
        return kw

    @st.composite
    def light_args(draw):
        kind = draw(st.sampled_from(["directional", "point", "spot"]))
        kw = {"color": draw(rgb), "intensity": draw(st.sampled_from([0.0, 1.0, 3.0, 1e3, 1e30, 3.4e38]))}
        if kind != "directional":
            kw["falloff"] = draw(st.sampled_from(["inverse_square", "none"]))
        if kind == "spot":
            outer = draw(floats(0.01, math.pi / 2))
            kw["outer_cone"] = outer
            kw["inner_cone"] = draw(floats(0.0, outer * 0.99))
        pose = np.eye(4)
        pose[:3, :3] = rotation(draw)
        pose[:3, 3] = draw(st.tuples(*[floats(-5.0, 5.0)] * 3))
        if draw(st.integers(0, 9)) == 0:
            pose[:3, 3] *= draw(st.sampled_from([1e-30, 1e20, 1e30]))
        return kind, kw, pose, draw(st.booleans())

    @st.composite
    def primitive_args(draw):
        n = draw(st.integers(1, 6))
        scale = draw(st.sampled_from([1.0, 1.0, 1.0, 1e-3, 1e19, 1e30]))
        positions = np.random.default_rng(n + 5).uniform(-1.5, 1.5, (n, 3)) * scale
        if draw(st.booleans()):
            segments = np.array([[k, (k + 1) % n] for k in range(n)], np.int64)
            return "lines", {"positions": positions, "segments": segments,
                             "width": draw(st.sampled_from([1.0, 1.0, 2.5, 0.5]))}
        return "points", {"positions": positions, "size": draw(st.sampled_from([1.0, 3.0, 0.5]))}

    # ---- bad values: (where, argument, value, expected name in the message) ----------------
    nan3 = (0.1, math.nan, 0.2)
    bad = {
        ("renderer", "width"): st.one_of(not_numbers_or_none, st.sampled_from([0, -1, 10**6, 2.5])),
        ("renderer", "height"): st.one_of(not_numbers_or_none, st.sampled_from([0, -3, 16385, 4.0])),
        ("renderer", "simd"): st.sampled_from(["yes", 1, None, 0.0]),
        ("renderer", "threads"): st.one_of(not_numbers_or_none, st.sampled_from([-1, 1.5])),
        ("mesh", "positions"): st.sampled_from([None, "abc", [[0, 0, 0], [1, 0]], np.full((3, 3), np.nan),
                                                np.zeros((3, 2)), np.eye(3, dtype=bool), np.eye(3) * 1j]),
        ("mesh", "faces"): st.sampled_from([None, [[0, 1, 99]], [[0, -1, 2]], [[0.0, 1.0, 2.0]], [[0, 1]],
                                            np.zeros((0, 3), int), "012"]),
        ("mesh", "normals"): st.sampled_from(["abc", np.zeros((2, 3)), np.full((9, 3), np.inf), np.zeros((9, 2))]),
        ("mesh", "colors"): st.sampled_from(["abc", np.full((9, 3), 2.0), np.zeros((9, 5)), np.zeros((2, 3))]),
        ("mesh", "color"): st.one_of(not_numbers, st.sampled_from([(2.0, 0.0, 0.0), (0.1, 0.2), nan3])),  # None: the default
        ("add", "pose"): st.one_of(not_numbers, st.sampled_from([np.eye(3), np.full((4, 4), np.nan), np.ones((4, 4)),
                                                                 np.eye(4, dtype=bool), [["1"] * 4] * 4])),
        ("add", "instance_id"): st.one_of(not_numbers, st.sampled_from([-1, 2**31, 1.5, np.float64(2.0)])),
        ("add", "color"): st.one_of(not_numbers, st.sampled_from([(2.0, 0.0, 0.0), (0.1, 0.2), nan3])),
        ("camera", "near"): st.one_of(not_numbers_or_none, st.sampled_from([0.0, -1.0, math.nan, math.inf])),
        ("camera", "far"): st.one_of(not_numbers_or_none, st.sampled_from([-1.0, math.nan, math.inf, 1e-9])),
        ("perspective", "fov_y"): st.one_of(not_numbers_or_none, st.sampled_from([0.0, 180.0, -5.0, math.nan, 5e-324, 1e-40])),
        ("perspective", "aspect"): st.one_of(not_numbers, st.sampled_from([0.0, -1.0, math.inf, 1e-300])),
        ("orthographic", "xmag"): st.one_of(not_numbers_or_none, st.sampled_from([0.0, -1.0, math.inf, 5e-324, 1e-39])),
        ("orthographic", "ymag"): st.one_of(not_numbers_or_none, st.sampled_from([0.0, math.nan, 5e-324])),
        ("intrinsics", "fx"): st.one_of(not_numbers_or_none, st.sampled_from([0.0, -1.0, math.nan, 1e308, 1e40])),
        ("intrinsics", "fy"): st.one_of(not_numbers_or_none, st.sampled_from([0.0, math.inf, 1e308])),
        ("intrinsics", "cx"): st.one_of(not_numbers_or_none, st.sampled_from([math.nan, 1e308, -1e40])),
        ("intrinsics", "cy"): st.one_of(not_numbers_or_none, st.sampled_from([math.inf, 1e308])),
        ("intrinsics", "convention"): st.sampled_from([None, "OpenCV", 1, ["opencv"]]),
        ("place", "eye"): st.one_of(not_numbers_or_none, st.sampled_from([(0, 0), (math.nan, 0, 0), (True, 0, 0)])),
        ("place", "target"): st.one_of(not_numbers_or_none, st.sampled_from([(0, 0, 0, 0), (0, math.inf, 0)])),
        ("place", "up"): st.one_of(not_numbers_or_none, st.sampled_from([(0, 0, 0), (0, 0)])),
        ("place", "pose"): st.one_of(not_numbers_or_none, st.sampled_from([np.diag([2.0, 2.0, 2.0, 1.0]),
                                                                   np.diag([-1.0, 1.0, 1.0, 1.0]), np.eye(3)])),
        ("render", "outputs"): st.sampled_from([None, 5, (), ("albedo",), ("color", 5), b"color", [None]]),
        ("render", "cull"): st.sampled_from([None, "BACK", 1, ["back"], "sideways"]),
        ("render", "shading"): st.sampled_from([None, "toon", 0, ("lambert",), "lit"]),
        ("render", "frequency"): st.sampled_from([None, "fragment", 1, ("pixel",)]),
        ("render", "srgb"): st.sampled_from([None, "yes", 1, 0.0]),
        ("material", "base_color"): st.one_of(not_numbers, st.sampled_from([(2.0, 0.0, 0.0), nan3, (0.1,)])),  # None: the default
        ("material", "shininess"): st.one_of(not_numbers_or_none, st.sampled_from([-1.0, math.nan, math.inf])),
        ("material", "metallic"): st.one_of(not_numbers_or_none, st.sampled_from([-0.1, 1.5, math.nan])),
        ("material", "roughness"): st.one_of(not_numbers_or_none, st.sampled_from([-0.1, 2.0, math.nan])),
        ("material", "model"): st.sampled_from(["toon", 1, "uv", "auto"]),
        ("light", "intensity"): st.one_of(not_numbers_or_none, st.sampled_from([-1.0, math.nan, math.inf])),
        ("light", "color"): st.one_of(not_numbers_or_none, st.sampled_from([(2.0, 0.0, 0.0), nan3, (0.5, 0.5)])),
        ("spot", "outer_cone"): st.one_of(not_numbers_or_none, st.sampled_from([0.0, 2.0, -1.0, math.nan])),
        ("spot", "inner_cone"): st.one_of(not_numbers_or_none, st.sampled_from([-0.1, 1.0, math.nan])),
        ("render", "shading_path"): st.sampled_from([None, "fast", 2]),
        ("render", "msaa"): st.sampled_from([3, 0, 32, -4, 4.0, "4", True, None]),
        ("render", "ssaa"): st.sampled_from([0, 9, -1, 2.5, "2", None]),
        ("render", "background"): st.one_of(not_numbers_or_none, st.sampled_from([(0.1, 0.2), (2.0, 0.0, 0.0), nan3,
                                                                          (True, 0, 0), ("0", "0", "0")])),
        ("render", "out"): st.sampled_from([5, "abc", [np.zeros((4, 4))], {n: np.zeros((41, 41, 3)) for n in OUTPUTS},
                                            {n: np.zeros((41, 41), np.int32) for n in OUTPUTS}]),
        ("render", "ambient"): st.one_of(not_numbers_or_none, st.sampled_from([-0.1, 1.5, math.nan, 10**400])),
    }
    # The name a message must contain for each bad argument (an empty mesh names itself).
    expected = {key: key[1] for key in bad}
    expected[("mesh", "faces")] = "faces|empty"
    expected[("camera", "near")] = "near"
    expected[("camera", "far")] = "far"

    @st.composite
    def call(draw):
        which = draw(st.one_of(st.none(), st.none(), st.sampled_from(sorted(bad))))
        w, h = draw(st.integers(1, 40)), draw(st.integers(1, 40))
        spec = {
            "renderer": {"width": w, "height": h, "threads": draw(st.integers(0, 2)), "simd": draw(st.booleans())},
            "meshes": [draw(mesh_args()) for _ in range(draw(st.sampled_from([0, 1, 1, 1, 2, 3])))],
            "camera": draw(camera_args(w, h)),
            "place": draw(placement()),
            "render": draw(render_args()),
        }
        spec["reuse_out"] = draw(st.integers(0, 3)) == 0  # render again into the frame's arrays
        spec["adds"] = [{"pose": draw(st.one_of(st.none(), model_pose())),
                         "instance_id": draw(st.one_of(st.none(), st.integers(0, 2**31 - 1))),
                         "color": draw(st.one_of(st.none(), rgb))} for _ in spec["meshes"]]
        spec["materials"] = [draw(st.one_of(st.none(), st.none(), material_args())) for _ in spec["meshes"]]
        spec["lights"] = [draw(light_args()) for _ in range(draw(st.sampled_from([0, 0, 1, 2, 4])))]
        spec["primitives"] = [draw(primitive_args()) for _ in range(draw(st.sampled_from([0, 0, 0, 1, 2])))]
        spec["ambient_light"] = draw(st.one_of(st.none(), rgb))
        if which is not None:
            where, arg = which
            value = draw(bad[which])
            kind, cam_kw = spec["camera"]
            if where == "renderer":
                spec["renderer"][arg] = value
            elif where in ("mesh", "add"):
                if not spec["meshes"]:
                    spec["meshes"].append(draw(mesh_args()))
                    spec["adds"].append({"pose": None, "instance_id": None, "color": None})
                    spec["materials"].append(None)
                spec["meshes" if where == "mesh" else "adds"][0][arg] = value
            elif where == "camera":
                cam_kw[arg] = value
            elif where == "material":
                if not spec["meshes"]:
                    spec["meshes"].append(draw(mesh_args()))
                    spec["adds"].append({"pose": None, "instance_id": None, "color": None})
                    spec["materials"].append(None)
                spec["materials"][0] = dict(spec["materials"][0] or {}, **{arg: value})
            elif where in ("light", "spot"):
                kind = "spot" if where == "spot" else draw(st.sampled_from(["directional", "point", "spot"]))
                kw = {"outer_cone": 0.5, "inner_cone": 0.2} if kind == "spot" else {}
                kw[arg] = value
                spec["lights"].insert(0, (kind, kw, np.eye(4), False))
            elif where in ("perspective", "orthographic", "intrinsics"):
                if kind != where:
                    spec["camera"] = kind, cam_kw = draw(camera_args(w, h).filter(lambda c: c[0] == where))
                cam_kw[arg] = value
            elif where == "place":
                if arg == "pose":
                    spec["place"] = {"pose": value}
                else:
                    args = {"eye": (0, 0, 3), "target": (0, 0, 0), "up": (0, 1, 0), arg: value}
                    spec["place"] = {"look_at": (args["eye"], args["target"], args["up"])}
            else:
                spec["render"][arg] = value
        return spec, which, None if which is None else expected[which]

    return call()


def _check_frame(frame, spec, renderer, scene, cam):
    w, h = renderer.width, renderer.height
    outputs = spec["render"]["outputs"]
    wanted = {outputs} if isinstance(outputs, str) else set(outputs)
    assert set(frame.outputs) == wanted, (frame.outputs, wanted)
    for name in frame.outputs:
        arr = getattr(frame, name)
        dtype, channels = DTYPES[name]
        assert arr.dtype == dtype and arr.shape == ((h, w, channels) if channels else (h, w)), (name, arr.shape)
    hit = None
    for name, covered in (("mask", lambda a: a), ("depth", lambda a: a > 0), ("triangle_id", lambda a: a >= 0),
                          ("instance_id", lambda a: a >= 0)):
        arr = getattr(frame, name)
        if name == "triangle_id" and scene.primitives:
            continue  # lines and points have triangle_id -1 (checked below)
        if arr is not None:
            if hit is None:
                hit = covered(arr)
            assert np.array_equal(covered(arr), hit), f"{name} disagrees with the other outputs on coverage"
    if frame.depth is not None:
        assert np.isfinite(frame.depth).all() and (frame.depth >= 0).all()
    if hit is None:  # no output shows coverage: the mask of the same render (it does not
        # depend on the outputs requested)
        options = {k: v for k, v in spec["render"].items() if k != "outputs"}
        hit = renderer.render(scene, cam, outputs="mask", **options).mask
    instances = scene.instances
    if frame.triangle_id is not None:
        assert (frame.triangle_id[~hit] == -1).all()
        if not scene.primitives:
            assert (frame.triangle_id[hit] >= 0).all()
        most = max((len(i.mesh.faces) for i in instances), default=0)
        assert (frame.triangle_id[hit] < most).all()
    if frame.instance_id is not None:
        assert (frame.instance_id[~hit] == -1).all()
        ids = [i.instance_id for i in instances] + [p.instance_id for p in scene.primitives]
        assert np.isin(frame.instance_id[hit], ids).all()
    if frame.normal is not None:
        n = frame.normal
        assert np.isfinite(n).all(), "normal not finite"
        assert (n[~hit] == 0).all(), "background normal is not 0"
        length = np.linalg.norm(n[hit].astype(np.float64), axis=-1)
        # Unit, or 0 where no normal exists: a zero vertex normal, a face the pose collapses to a
        # segment (rank <= 1 poses: every face) or a float32-collinear face.
        assert ((np.abs(length - 1.0) < 1e-5) | (length == 0.0)).all(), "normal neither unit nor 0"
    if frame.coverage is not None and not scene.primitives:  # (lines and points count no coverage)
        assert (frame.coverage[hit] >= 1).all(), "visible pixel with coverage 0"
    if frame.radiance is not None:
        assert (frame.radiance[~hit] == 0).all(), "background radiance is not 0"
        assert np.isfinite(frame.radiance).all(), "radiance not finite"
        assert (frame.radiance >= 0).all(), "negative radiance"
    if frame.color is not None:
        bg = np.asarray(spec["render"]["background"], dtype=np.float32)
        bg8 = (np.clip(bg, 0, 1) * np.float32(255.0) + np.float32(0.5)).astype(np.uint8)
        assert (frame.color[~hit] == bg8).all(), "background colour"
    return int(hit.any())


def _run(spec):
    """Performs the call; returns (frame, renderer, scene, camera)."""
    import softrast as sr

    r = spec["renderer"]
    renderer = sr.Renderer(r["width"], r["height"], threads=r["threads"], simd=r["simd"])
    w, h = renderer.width, renderer.height
    scene = sr.Scene(ambient_light=spec["ambient_light"])
    for mesh_kw, add_kw, mat_kw in zip(spec["meshes"], spec["adds"], spec["materials"]):
        mesh = sr.Mesh(**mesh_kw)
        material = None
        if mat_kw is not None:
            mat_kw = {k: sr.Texture(**v) if k.endswith("_texture") and isinstance(v, dict) else v
                      for k, v in mat_kw.items()}
            with warnings.catch_warnings():  # a colour slot's float image above 1 warns: meant
                warnings.filterwarnings("ignore", message=r".*_texture: its float image")
                material = sr.Material(**mat_kw)
        scene.add(mesh, material=material, **add_kw)
    for kind, kw in spec.get("primitives", []):
        scene.add(sr.Lines(**kw) if kind == "lines" else sr.Points(**kw))
    kinds = {"directional": sr.DirectionalLight, "point": sr.PointLight, "spot": sr.SpotLight}
    for kind, kw, pose, camera_space in spec["lights"]:
        scene.add(kinds[kind](**kw), pose=pose, camera_space=camera_space)
    kind, cam_kw = spec["camera"]
    if kind == "perspective":
        cam = sr.PerspectiveCamera(**cam_kw)
    elif kind == "orthographic":
        cam = sr.OrthographicCamera(**cam_kw)
    else:
        cam = sr.IntrinsicsCamera(width=w, height=h, **cam_kw)
    if "pose" in spec["place"]:
        cam.pose = spec["place"]["pose"]
    else:
        eye, target, up = spec["place"]["look_at"]
        cam.look_at(eye, target, up=up)
    frame = renderer.render(scene, cam, **spec["render"])
    return frame, renderer, scene, cam


def _main():
    from hypothesis import HealthCheck, given, settings

    warnings.simplefilter("error")  # as pytest's filterwarnings = error: a warning is a failure
    counts = {"examples": 0, "rendered": 0, "refused": 0, "with pixels hit": 0}

    @settings(max_examples=EXAMPLES, derandomize=True, deadline=None, database=None,
              suppress_health_check=list(HealthCheck), print_blob=False)
    @given(_strategies())
    def property_(case):
        spec, which, name = case
        counts["examples"] += 1
        try:
            frame, renderer, scene, cam = _run(spec)
        except (ValueError, TypeError) as exc:
            assert which is not None, f"a valid call raised {type(exc).__name__}: {exc}"
            assert re.search(name, str(exc)), (f"bad {which[1]} ({spec!r:.300}) raised "
                                               f"{type(exc).__name__} not naming it: {exc}")
            counts["refused"] += 1
            return
        assert which is None, f"bad {which[1]} was accepted"
        counts["with pixels hit"] += _check_frame(frame, spec, renderer, scene, cam)
        counts["rendered"] += 1
        if spec["reuse_out"]:  # out=: the same arrays, written with the same bits
            before = {name: arr.copy() for name, arr in frame.as_dict().items()}
            again = renderer.render(scene, cam, out=frame, **spec["render"])
            for name, arr in before.items():
                assert getattr(again, name) is getattr(frame, name), f"out= {name} not reused"
                assert np.array_equal(getattr(again, name), arr), f"out= {name} differs"

    property_()
    print(f"examples: {counts['examples']} rendered: {counts['rendered']} refused: {counts['refused']} "
          f"(renders with pixels hit: {counts['with pixels hit']})")


if __name__ == "__main__":
    _main()
