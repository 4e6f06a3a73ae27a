"""Golden renders: SHA-256 of every output of a fixed set of scenes, recorded from a known commit.

The seams refactor (the core split into stages) had to leave every output bit-identical. This module
defines the scenes (every path of the core: both shading models, smooth/flat normals, vertex
colours, the three cull modes, near-plane and guard-band clipping, perspective/orthographic/OpenCV
cameras, mirroring poses, a scene far from the origin, forward/deferred/auto shading paths,
overdraw, many chunks, odd and tiny image sizes, a frame big enough to be written with streaming
stores) and hashes their outputs. Meshes come from tests/data/golden_meshes.npz, not from trimesh,
so a trimesh upgrade cannot change them.

    python3 tests/support/golden.py --write   # record tests/data/golden_hashes.json from the installed build
    python3 tests/support/golden.py           # compare (what tests/test_golden.py does, per scene)
"""
from __future__ import annotations

import hashlib
import json
import os
import pathlib
import sys
from typing import Callable

import numpy as np

import softrast as sr

DATA = pathlib.Path(__file__).resolve().parents[1] / "data"
MESHES = DATA / "golden_meshes.npz"
HASHES = DATA / "golden_hashes.json"
# The outputs recorded at the commit (not sr.OUTPUTS: an output added later is not in the record).
ALL = ("color", "depth", "mask", "normal", "triangle_id", "instance_id", "coverage")


def _meshes() -> dict[str, sr.Mesh]:
    d = np.load(MESHES)
    spot_p, spot_f, spot_n = d["spot_positions"], d["spot_faces"], d["spot_normals"]
    sph_p, sph_f = d["sphere_positions"], d["sphere_faces"]
    lo, hi = spot_p.min(0), spot_p.max(0)
    rgb = (spot_p - lo) / (hi - lo)
    colors = np.concatenate([rgb, np.ones((len(rgb), 1), np.float32)], 1)
    return {
        "spot": sr.Mesh(spot_p, spot_f, normals=spot_n, uvs=d["spot_uvs"]),
        "spot_flat": sr.Mesh(spot_p, spot_f, color=(0.8, 0.6, 0.3, 1.0)),
        "spot_colors": sr.Mesh(spot_p, spot_f, normals=spot_n, colors=colors),
        "sphere": sr.Mesh(sph_p, sph_f, normals=sph_p / np.linalg.norm(sph_p, axis=1, keepdims=True)),
        "sphere_flat": sr.Mesh(sph_p, sph_f),
        # A floor plane 2000 units across, seen at a grazing angle; a huge triangle for the guard band.
        "floor": sr.Mesh(np.array([[-1e3, 0, -1e3], [1e3, 0, -1e3], [1e3, 0, 1e3], [-1e3, 0, 1e3]]),
                         np.array([[0, 2, 1], [0, 3, 2]]), color=(0.4, 0.7, 0.9, 1.0)),
    }


def _translate(x: float, y: float, z: float, s: float = 1.0) -> np.ndarray:
    m = np.diag([s, s, s, 1.0])
    m[:3, 3] = (x, y, z)
    return m


def _rot_y(deg: float) -> np.ndarray:
    a = np.radians(deg)
    m = np.eye(4)
    m[0, 0], m[0, 2], m[2, 0], m[2, 2] = np.cos(a), np.sin(a), -np.sin(a), np.cos(a)
    return m


def _persp(eye, target, fov=45.0, near=0.05, far=100.0) -> sr.Camera:
    cam = sr.PerspectiveCamera(fov_y=fov, near=near, far=far)
    cam.look_at(eye, target)
    return cam


# name -> (width, height, build(meshes) -> (scene, camera), render keyword options)
Scene = Callable[[dict], tuple]


def _scenes() -> dict[str, tuple[int, int, Scene, dict]]:
    s: dict[str, tuple[int, int, Scene, dict]] = {}

    def add(name, w, h, options=None):
        def deco(fn):
            s[name] = (w, h, fn, options or {})
            return fn
        return deco

    @add("spot_lambert", 200, 150)
    def _(m):
        sc = sr.Scene(); sc.add(m["spot"])
        return sc, _persp((1.7, 0.9, -2.3), (0, 0.05, 0.15))

    @add("spot_unlit_colors_cull_none_bg", 161, 97, dict(shading="unlit", cull="none",
                                                           background=(0.2, 0.4, 0.6)))
    def _(m):
        sc = sr.Scene(); sc.add(m["spot_colors"], pose=_rot_y(40))
        return sc, _persp((0, 0.4, 2.4), (0, 0.1, 0))

    @add("spot_flat_cull_front_ambient0", 128, 128, dict(cull="front", ambient=0.0))
    def _(m):
        sc = sr.Scene(); sc.add(m["spot_flat"])
        return sc, _persp((0.3, 0.5, 2.0), (0, 0.1, 0))

    @add("spot_colors_lambert_ambient1", 96, 80, dict(ambient=1.0))
    def _(m):
        sc = sr.Scene(); sc.add(m["spot_colors"])
        return sc, _persp((-1.5, 0.5, 1.5), (0, 0.1, 0))

    @add("sphere_near_clip", 150, 110, dict(cull="none"))
    def _(m):  # the near plane cuts the sphere's cap off: its inside shows through the hole
        sc = sr.Scene(); sc.add(m["sphere"])
        return sc, _persp((0, 0.3, 1.3), (0, 0, 0), fov=70, near=0.6)

    @add("sphere_camera_inside_cull_none", 120, 90, dict(cull="none"))
    def _(m):
        sc = sr.Scene(); sc.add(m["sphere_flat"])
        return sc, _persp((0.1, 0.2, 0.3), (0, 0, -1), fov=90, near=0.01)

    @add("ortho_instances_overdraw_auto", 256, 192)
    def _(m):  # 12 overlapping spheres: overdraw above the forward/deferred crossover
        sc = sr.Scene()
        for k in range(12):
            sc.add(m["sphere"], pose=_translate(0.1 * (k % 4) - 0.15, 0.08 * (k // 4) - 0.08, -0.05 * k, 0.9),
                   instance_id=100 + 7 * k, color=(k / 12, 1 - k / 12, 0.5, 1.0))
        cam = sr.OrthographicCamera(xmag=1.4, ymag=1.05, near=0.1, far=20)
        cam.look_at((0.2, 0.3, 5), (0, 0, 0))
        return sc, cam

    for path in ("forward", "deferred"):
        @add(f"ortho_instances_{path}", 256, 192, dict(shading_path=path))
        def _(m):
            return s["ortho_instances_overdraw_auto"][2](m)

    @add("opencv_intrinsics_far_from_origin", 173, 131)
    def _(m):
        off = np.array([1e6, -2e6, 3e5])
        sc = sr.Scene(); sc.add(m["spot"], pose=_translate(*off) @ _rot_y(-30))
        cam = sr.IntrinsicsCamera(fx=190.0, fy=185.0, cx=86.3, cy=61.7, width=173, height=131,
                                  near=0.05, far=100.0, convention="opencv")
        pose = np.eye(4)
        pose[:3, 3] = off + (0.1, 0.05, -2.4)  # OpenCV axes: looking along +z, y down
        cam.pose = pose
        return sc, cam

    @add("mirror_pose", 140, 100)
    def _(m):
        sc = sr.Scene(); sc.add(m["spot"], pose=np.diag([-1.0, 1.0, 1.0, 1.0]))
        sc.add(m["spot_flat"], pose=_translate(0.9, 0, -0.5) @ np.diag([1.0, -1.0, 1.0, 1.0]))
        return sc, _persp((0.4, 0.3, 3.0), (0.4, 0, 0))

    @add("grazing_floor_wide_depth_range", 190, 140)
    def _(m):
        sc = sr.Scene(); sc.add(m["floor"]); sc.add(m["sphere"], pose=_translate(0, 1, -3))
        return sc, _persp((0, 1.5, 6), (0, 1.2, 0), fov=60, near=1e-3, far=1e6)

    @add("guard_band_huge_triangle", 131, 77, dict(cull="none"))
    def _(m):
        sc = sr.Scene(); sc.add(m["floor"], pose=_translate(0, 0, 0, 1e3))
        return sc, _persp((0.5, 0.02, 0.3), (3, 0.0, -2), fov=30, near=0.001, far=1e7)

    @add("tiny_scale", 100, 75)
    def _(m):
        sc = sr.Scene(); sc.add(m["spot"], pose=_translate(0, 0, 0, 2.0**-70))
        return sc, _persp(np.array((1.7, 0.9, -2.3)) * 2.0**-70, (0, 0, 0), near=2.0**-75, far=2.0**-60)

    @add("many_instances", 300, 200)
    def _(m):
        sc = sr.Scene()
        for k in range(24):
            sc.add(m["sphere_flat"] if k % 2 else m["sphere"],
                   pose=_translate(1.1 * (k % 6) - 2.75, 1.1 * (k // 6) - 1.65, -0.3 * (k % 3), 0.5))
        return sc, _persp((0, 0, 7), (0, 0, 0))

    @add("one_pixel", 1, 1)
    def _(m):
        sc = sr.Scene(); sc.add(m["sphere"])
        return sc, _persp((0, 0, 3), (0, 0, 0))

    @add("odd_size", 67, 5)
    def _(m):
        sc = sr.Scene(); sc.add(m["spot"])
        return sc, _persp((1.7, 0.9, -2.3), (0, 0.05, 0.15))

    # 2048 x 1024 colour + depth = 14.7 MB: over the core's streaming-store threshold (12 MB).
    @add("big_streamed", 2048, 1024, dict(outputs=("color", "depth")))
    def _(m):
        sc = sr.Scene(); sc.add(m["sphere"]); sc.add(m["spot"], pose=_translate(1.2, 0, 0.5))
        return sc, _persp((0.5, 0.3, 3.5), (0.5, 0, 0))

    return s


SCENES = _scenes()
# Under the sanitizers (.ci/sanitize sets SOFTRAST_ASAN) one and three threads: one worker, and
# more workers than CI's two cores; the normal suite checks all three counts give the same bits.
CONFIGS = [(simd, threads) for simd in (True, False)
           for threads in ((1, 3) if os.environ.get("SOFTRAST_ASAN") else (1, 2, 3))]


def render_hashes(name: str, simd: bool, threads: int, meshes: dict | None = None) -> dict[str, str]:
    w, h, build, options = SCENES[name]
    options = dict(options)
    outputs = options.pop("outputs", ALL)
    scene, camera = build(meshes or _meshes())
    # Colour linear, as recorded (sRGB became the default later; the recorded commit had none).
    options.setdefault("srgb", False)
    frame = sr.Renderer(w, h, threads=threads, simd=simd).render(scene, camera, outputs=outputs, **options)
    return {k: hashlib.sha256(np.ascontiguousarray(v).tobytes()).hexdigest()
            for k, v in frame.as_dict().items()}


def _make_meshes() -> None:
    import trimesh
    spot = trimesh.load(pathlib.Path(__file__).resolve().parents[2] / "assets/meshes/spot.obj", process=False)
    sph = trimesh.creation.icosphere(subdivisions=4)
    np.savez_compressed(
        MESHES, spot_positions=np.asarray(spot.vertices, np.float32), spot_faces=np.asarray(spot.faces, np.int32),
        spot_normals=np.asarray(spot.vertex_normals, np.float32),
        spot_uvs=np.asarray(spot.visual.uv, np.float32),
        sphere_positions=np.asarray(sph.vertices, np.float32), sphere_faces=np.asarray(sph.faces, np.int32))


def main() -> int:
    if "--meshes" in sys.argv:
        _make_meshes()
    meshes = _meshes()
    if "--write" in sys.argv:
        out = {name: render_hashes(name, True, 2, meshes) for name in SCENES}
        HASHES.write_text(json.dumps({"commit": sys.argv[-1] if len(sys.argv) > 2 else "",
                                      "scenes": out}, indent=1, sort_keys=True) + "\n")
        print(f"wrote {HASHES} ({len(out)} scenes)")
        return 0
    want = json.loads(HASHES.read_text())["scenes"]
    bad = [(n, c) for n in SCENES for c in CONFIGS if render_hashes(n, *c, meshes) != want[n]]
    print("\n".join(f"DIFFERS: {n} simd={c[0]} threads={c[1]}" for n, c in bad) or "all identical")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
