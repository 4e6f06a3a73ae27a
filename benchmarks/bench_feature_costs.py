"""What each feature costs against softrast's own frame: "with / without" ratios, A/B in one run.

    python3 benchmarks/bench_feature_costs.py [--sizes 640x480,1024x1024] [--rounds 5] [--quick]
        [--groups textures,aa,lit] [--threads 2[,1]] [--no-pyrender] [--png DIR]

Every row is a pair of renders of one scene that differ in one feature only; both (and the
pyrender pair beside them) are cells of one interleaved run (bench_vs_pyrender.run_interleaved:
warm-up, then --rounds rounds, the cells' order rotated each round), and the row's ratio is the
median ms "with" over the median ms "without". Colour+depth into out= (the frame of an earlier
render), softrast threads=2 (--threads 2,1 adds one-thread rows), sRGB-encoded colour.

Scenes (assets/meshes and our own), framed as bench_vs_pyrender's textured rows (a 45-degree
camera at the distance that makes the bounding sphere span 0.8 of the image height):
  spot   Spot with spot_texture.png (1024x1024)       fuze   fuze.obj with fuze_uv.jpg
  wood   wood.obj, one textured quad seen obliquely   box    BoxTextured.gltf
  ico    a trimesh icosphere (6 subdivisions) with spherical uvs and a procedural 1024x1024
         checker texture
Rows (groups):
  textures  unlit: trilinear and anisotropic (max_anisotropy 16) base colour texture vs the
            same material without it (base colour 0.8 grey); "normal map": blinn_phong, one
            point light, the material with a procedural bump pattern as normal_texture (512x512,
            linear) vs without. pyrender: RenderFlags.FLAT textured vs untextured (its default
            sampler, the same figure beside both texture rows) and its metallic-roughness shader
            with one point light with vs without normalTexture.
  aa        msaa 2, 4, 8 and ssaa 2 vs the same render at 1 (the scene's meshes untextured, 0.8
            grey, lambert with one point light). pyrender under OSMesa has no MSAA: n/a.
  lit       lambert, phong, blinn_phong (ks 0.5, shininess 32) and pbr (metallic 0.2, roughness
            0.4) with the first 1, 3 and 8 of eight point lights vs the same scene unlit (the
            meshes untextured, 0.8 grey, so that the texture's own cost, measured by the textures
            rows, does not dilute the lighting's). pyrender: its metallic-roughness
            shader with the same lights vs RenderFlags.FLAT (the same figure beside every model).
Per lit model the run also prints ns per covered pixel per added light, (t8 - t1) / 7 / covered
pixels, covered = pixels with depth > 0.
--quick: 640x480 only, 3 rounds, scenes spot and ico only, ~0.15 s per cell (~20 s in all; the
default run ~3-4 min on a 2-core machine).
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import numpy as np  # noqa: E402

np.infty = np.inf  # pyrender 0.1.45 uses it (gone in NumPy 2)

import trimesh  # noqa: E402

import softrast as sr  # noqa: E402
from bench_vs_pyrender import (FAR, FOV_Y_DEG, LIT_AMBIENT, NEAR, SPOT_PATH, Cell,  # noqa: E402
                               camera_distance, import_pyrender, look_at, machine_lines,
                               run_interleaved, textured_trimesh_scene)

MESH_DIR = os.path.dirname(SPOT_PATH)
SCENES = ("spot", "fuze", "wood", "box", "ico")
QUICK_SCENES = ("spot", "ico")
GROUP_SCENES = {"textures": SCENES, "aa": ("spot", "box", "ico"), "lit": ("spot", "fuze", "ico")}
VIEW_DIRS = {"wood": (0.35, 0.45, 1.0)}  # the quad faces +z; others: a 3/4 view
DEFAULT_VIEW = (1.0, 0.4, 1.0)
LIT_MODELS = ("lambert", "phong", "blinn_phong", "pbr")
LIGHT_COUNTS = (1, 3, 8)
AA_MODES = (("msaa 2", dict(msaa=2)), ("msaa 4", dict(msaa=4)), ("msaa 8", dict(msaa=8)),
            ("ssaa 2", dict(ssaa=2)))
GOALS = {"trilinear": 1.5, "anisotropic": 2.0, "msaa 4": 2.0, "msaa 8": 3.0,
         "blinn_phong 1 light": 1.5, "pbr 3 lights": 1.6}
# Eight point lights: offsets in the camera's axes in units of the object's radius (towards the
# camera), colours; the first n are used. Intensity 4 * radius^2 / n, so the sum stays the same.
POINT_LIGHTS = [((1.5, 1.5, 1.5), (1.0, 0.9, 0.8)), ((-1.5, 1.0, 1.5), (0.8, 0.9, 1.0)),
                ((0.0, -1.5, 1.5), (0.9, 1.0, 0.9)), ((1.5, -1.0, 1.0), (1.0, 1.0, 1.0)),
                ((-1.5, -1.0, 1.0), (1.0, 0.95, 0.9)), ((0.0, 1.8, 1.0), (0.9, 0.95, 1.0)),
                ((2.0, 0.0, 0.5), (1.0, 1.0, 0.9)), ((-2.0, 0.0, 0.5), (0.9, 1.0, 1.0))]
POINT_INTENSITY = 4.0


# --------------------------------------------------------------------------------- assets


def checker_image(n: int = 1024, squares: int = 16) -> np.ndarray:
    """Our own texture: a coloured checkerboard with a smooth gradient across it."""
    i, j = np.mgrid[0:n, 0:n]
    check = ((i * squares // n + j * squares // n) % 2).astype(np.float64)
    img = np.stack([0.2 + 0.6 * check + 0.2 * j / n, 0.3 + 0.4 * (1 - check), 0.2 + 0.6 * i / n], axis=-1)
    return (np.clip(img, 0, 1) * 255).astype(np.uint8)


def bump_normal_map(n: int = 512, bumps: int = 12, strength: float = 2.5) -> np.ndarray:
    """A tangent-space normal map (OpenGL convention) of the height sin(u) * sin(v) bumps."""
    u, v = np.meshgrid(np.linspace(0, 2 * math.pi * bumps, n, endpoint=False),
                       np.linspace(0, 2 * math.pi * bumps, n, endpoint=False))
    dh_du, dh_dv = np.cos(u) * np.sin(v), np.sin(u) * np.cos(v)
    nrm = np.stack([-strength * dh_du / bumps, -strength * dh_dv / bumps, np.ones_like(u)], axis=-1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    return ((nrm * 0.5 + 0.5) * 255).round().astype(np.uint8)[::-1]  # row 0 = top = v 1


def icosphere_parts() -> list[tuple]:
    tm = trimesh.creation.icosphere(subdivisions=6, radius=1.0)
    x, y, z = tm.vertices.T
    uv = np.stack([np.arctan2(x, z) / (2 * math.pi) + 0.5, np.arcsin(np.clip(y, -1, 1)) / math.pi + 0.5], axis=1)
    return [(np.eye(4), tm.vertices, tm.faces, tm.vertex_normals, uv, checker_image())]


def scene_parts(name: str) -> list[tuple]:
    """[(pose, vertices, faces, normals, uv, image uint8 RGB)] of one scene."""
    if name == "ico":
        return icosphere_parts()
    if name in ("spot", "box"):
        tscene = textured_trimesh_scene(name)
    else:
        tscene = trimesh.load(os.path.join(MESH_DIR, name, f"{name}.obj"), force="scene")
    parts = []
    for node in tscene.graph.nodes_geometry:
        pose, geom_name = tscene.graph[node]
        g = tscene.geometry[geom_name]
        mat = g.visual.material
        image = getattr(mat, "baseColorTexture", None) or getattr(mat, "image", None)
        parts.append((pose, g.vertices, g.faces, g.vertex_normals, g.visual.uv,
                      np.ascontiguousarray(np.asarray(image.convert("RGB")))))
    return parts


class SceneSet:
    """One scene's geometry, camera pose and lights, and the softrast / pyrender variants of it."""

    def __init__(self, name: str, width: int, height: int, pyrender, pr_renderer) -> None:
        self.name, self.width, self.height = name, width, height
        self.parts = scene_parts(name)
        pts = np.concatenate([(p[:3, :3] @ np.asarray(v).T).T + p[:3, 3] for p, v, *_ in self.parts])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        centre = (lo + hi) / 2
        radius = float(np.linalg.norm(pts - centre, axis=1).max())  # the bounding sphere about centre
        view = np.asarray(VIEW_DIRS.get(name, DEFAULT_VIEW), float)
        self.cam_pose = look_at(centre + radius * camera_distance() * view / np.linalg.norm(view), centre)
        rot = self.cam_pose[:3, :3]
        self.lights = []  # (pose, rgb)
        for offset, rgb in POINT_LIGHTS:
            pose = np.eye(4)
            pose[:3, 3] = centre + radius * (rot @ np.asarray(offset))
            self.lights.append((pose, rgb))
        self.radius = radius
        self.cam = sr.PerspectiveCamera(fov_y=FOV_Y_DEG, width=width, height=height, near=NEAR, far=FAR)
        self.cam.pose = self.cam_pose
        self.textures = [sr.Texture(img) for *_, img in self.parts]
        self.normal_map = sr.Texture(bump_normal_map(), srgb=False)
        self.pyrender, self.pr_renderer = pyrender, pr_renderer
        self.pr_textures = {}

    # ---- softrast
    def sr_scene(self, textured: bool = True, model: str = "blinn_phong", n_lights: int = 0,
                 normal_map: bool = False, filt: str = "trilinear", light_scale: float = 1.0) -> sr.Scene:
        scene = sr.Scene(ambient_light=(LIT_AMBIENT,) * 3)
        for (pose, v, f, n, uv, _), tex in zip(self.parts, self.textures):
            kw = dict(model=model, ks=(0.5, 0.5, 0.5), shininess=32.0, metallic=0.2, roughness=0.4)
            if textured:
                kw["base_color_texture"] = tex.replace(filter=filt)
                kw["base_color"] = (1.0, 1.0, 1.0, 1.0)
            else:
                kw["base_color"] = (0.8, 0.8, 0.8, 1.0)
            if normal_map:
                kw["normal_texture"] = self.normal_map
            mesh = sr.Mesh(v, f, normals=n, uvs=uv)
            scene.add(mesh, pose=pose, material=sr.Material(**kw))
        for pose, rgb in self.lights[:n_lights]:
            scene.add(sr.PointLight(color=rgb, intensity=light_scale * POINT_INTENSITY * self.radius ** 2
                                    / n_lights), pose=pose)
        return scene

    def coverage_px(self, renderer, scene) -> int:
        return int((renderer.render(scene, self.cam, outputs=("depth",)).depth > 0).sum())

    # ---- pyrender
    def pr_scene(self, textured: bool, n_lights: int, normal_map: bool = False):
        pr = self.pyrender
        scene = pr.Scene(ambient_light=[LIT_AMBIENT] * 3, bg_color=[0.0, 0.0, 0.0, 0.0])
        for i, (pose, v, f, n, uv, img) in enumerate(self.parts):
            kw = dict(metallicFactor=0.2, roughnessFactor=0.4)
            if textured:
                if i not in self.pr_textures:
                    self.pr_textures[i] = pr.Texture(source=img, source_channels="RGB")
                kw["baseColorTexture"] = self.pr_textures[i]
            else:
                kw["baseColorFactor"] = (0.8, 0.8, 0.8, 1.0)
            if normal_map:
                if "normal" not in self.pr_textures:
                    self.pr_textures["normal"] = pr.Texture(source=bump_normal_map(), source_channels="RGB")
                kw["normalTexture"] = self.pr_textures["normal"]
            prim = pr.Primitive(positions=np.asarray(v, np.float32), normals=np.asarray(n, np.float32),
                                texcoord_0=np.asarray(uv, np.float32), indices=np.asarray(f, np.uint32),
                                material=pr.MetallicRoughnessMaterial(**kw))
            scene.add(pr.Mesh(primitives=[prim]), pose=pose)
        scene.add(pr.PerspectiveCamera(yfov=math.radians(FOV_Y_DEG), aspectRatio=self.width / self.height,
                                       znear=NEAR, zfar=FAR), pose=self.cam_pose)
        for pose, rgb in self.lights[:n_lights]:
            scene.add(pr.PointLight(color=rgb, intensity=POINT_INTENSITY * self.radius ** 2 / n_lights), pose=pose)
        return scene

    def pr_cell(self, name: str, scene, flat: bool = False) -> Cell:
        r, flags = self.pr_renderer, self.pyrender.RenderFlags
        f = flags.FLAT if flat else flags.NONE
        r.render(scene, flags=f)
        return Cell(name, lambda: r.render(scene, flags=f))


def sr_cell(name: str, renderer, scene, cam, **kw) -> Cell:
    kw.setdefault("outputs", ("color", "depth"))
    frame = renderer.render(scene, cam, **kw)
    return Cell(name, lambda: renderer.render(scene, cam, out=frame, **kw))


# ----------------------------------------------------------------------------------- rows


def rows_textures(ss: SceneSet, renderers, use_pr: bool, png: str | None):
    """[(feature, without cell, with cell, pyrender without, pyrender with)], cells."""
    cells, rows = [], []
    untex = ss.sr_scene(textured=False, model="unlit")
    lit_plain = ss.sr_scene(textured=False, model="blinn_phong", n_lights=1)
    lit_nmap = ss.sr_scene(textured=False, model="blinn_phong", n_lights=1, normal_map=True)
    pr_pairs = {}
    if use_pr:
        flat_untex = ss.pr_cell(f"{ss.name} pyr flat untextured", ss.pr_scene(False, 0), flat=True)
        flat_tex = ss.pr_cell(f"{ss.name} pyr flat textured", ss.pr_scene(True, 0), flat=True)
        pr_plain = ss.pr_cell(f"{ss.name} pyr lit", ss.pr_scene(False, 1))
        pr_nmap = ss.pr_cell(f"{ss.name} pyr lit normal map", ss.pr_scene(False, 1, normal_map=True))
        cells += [flat_untex, flat_tex, pr_plain, pr_nmap]
        pr_pairs = {"tex": (flat_untex, flat_tex), "nmap": (pr_plain, pr_nmap)}
    for t, r in renderers.items():
        base = sr_cell(f"{ss.name} t{t} unlit untextured", r, untex, ss.cam)
        cells.append(base)
        for filt in ("trilinear", "anisotropic"):
            scene = ss.sr_scene(textured=True, model="unlit", filt=filt)
            c = sr_cell(f"{ss.name} t{t} unlit {filt}", r, scene, ss.cam)
            cells.append(c)
            rows.append((f"{filt}", t, base, c, *pr_pairs.get("tex", (None, None))))
            if png and t == max(renderers) and filt == "trilinear":
                sr.imwrite(os.path.join(png, f"{ss.name}_{ss.width}x{ss.height}_trilinear.png"),
                           r.render(scene, ss.cam).color)
        a = sr_cell(f"{ss.name} t{t} blinn_phong", r, lit_plain, ss.cam)
        b = sr_cell(f"{ss.name} t{t} blinn_phong normal map", r, lit_nmap, ss.cam)
        cells += [a, b]
        rows.append(("normal map (blinn_phong, 1 light)", t, a, b, *pr_pairs.get("nmap", (None, None))))
        if png and t == max(renderers):
            sr.imwrite(os.path.join(png, f"{ss.name}_{ss.width}x{ss.height}_normalmap.png"),
                       r.render(lit_nmap, ss.cam).color)
    return rows, cells


def rows_aa(ss: SceneSet, renderers, use_pr: bool, png: str | None):
    cells, rows = [], []
    scene = ss.sr_scene(textured=False, model="lambert", n_lights=1)
    for t, r in renderers.items():
        base = sr_cell(f"{ss.name} t{t} aa 1", r, scene, ss.cam)
        cells.append(base)
        for label, mode in AA_MODES:
            c = sr_cell(f"{ss.name} t{t} {label}", r, scene, ss.cam, **mode)
            cells.append(c)
            rows.append((label, t, base, c, "n/a", "n/a"))
        if png and t == max(renderers):
            sr.imwrite(os.path.join(png, f"{ss.name}_{ss.width}x{ss.height}_msaa4.png"),
                       r.render(scene, ss.cam, msaa=4).color)
    return rows, cells


def rows_lit(ss: SceneSet, renderers, use_pr: bool, png: str | None):
    cells, rows = [], []
    pr_flat, pr_lit = None, {}
    if use_pr:
        pr_flat = ss.pr_cell(f"{ss.name} pyr flat", ss.pr_scene(False, 0), flat=True)
        cells.append(pr_flat)
        for n in LIGHT_COUNTS:
            pr_lit[n] = ss.pr_cell(f"{ss.name} pyr lit {n}", ss.pr_scene(False, n))
            cells.append(pr_lit[n])
    unlit_scene = ss.sr_scene(textured=False, model="unlit")
    for t, r in renderers.items():
        base = sr_cell(f"{ss.name} t{t} unlit", r, unlit_scene, ss.cam)
        cells.append(base)
        for model in LIT_MODELS:
            for n in LIGHT_COUNTS:
                scene = ss.sr_scene(textured=False, model=model, n_lights=n)
                c = sr_cell(f"{ss.name} t{t} {model} {n}", r, scene, ss.cam)
                cells.append(c)
                rows.append((f"{model} {n} light{'s' if n > 1 else ''}", t, base, c, pr_flat, pr_lit.get(n)))
                if png and t == max(renderers) and n == 3 and model in ("blinn_phong", "pbr"):
                    sr.imwrite(os.path.join(png, f"{ss.name}_{ss.width}x{ss.height}_{model}3.png"),
                               r.render(scene, ss.cam).color)
    return rows, cells


GROUP_ROWS = {"textures": rows_textures, "aa": rows_aa, "lit": rows_lit}


# --------------------------------------------------------------------------------- report


def med(cell) -> float:
    return cell.median_ms if isinstance(cell, Cell) else float("nan")


def fmt(v: float, digits: int = 2) -> str:
    return f"{v:.{digits}f}" if v == v else "n/a"


def goal_text(feature: str, ratio: float) -> str:
    key = feature.split(" (")[0].replace("1 lights", "1 light")
    goal = GOALS.get(key)
    if goal is None:
        return ""
    return f"<= {goal:g}x " + ("met" if ratio <= goal else "**not met**")


def report(size: str, table: list, coverage: dict, threads) -> None:
    print(f"\n#### {size}\n")
    print("| scene | feature | threads | without (ms) | with (ms) | ratio | goal | pyrender ratio |")
    print("|---|---|---|---|---|---|---|---|")
    for scene, feature, t, without, with_, pr_without, pr_with in table:
        x = med(with_) / med(without)
        if isinstance(pr_without, str):
            pr_text = pr_without
        else:
            pr_text = fmt(med(pr_with) / med(pr_without)) if pr_without is not None else "n/a"
        print(f"| {scene} | {feature} | {t} | {fmt(med(without))} | {fmt(med(with_))} | {fmt(x)} | "
              f"{goal_text(feature, x)} | {pr_text} |")
    lit = [r for r in table if r[1].split()[0] in LIT_MODELS and "light" in r[1]]
    if not lit:
        return
    print(f"\nns per covered pixel per added light, (t8 - t1) / 7 / covered px ({size}):\n")
    scenes = sorted({r[0] for r in lit}, key=lambda s: SCENES.index(s))
    print("| model | threads | " + " | ".join(f"{s} ({coverage[s]:,} px)" for s in scenes) + " |")
    print("|---|---|" + "---|" * len(scenes))
    for model in LIT_MODELS:
        for t in threads:
            vals = []
            for s in scenes:
                t1 = next((med(r[4]) for r in lit if r[0] == s and r[2] == t and r[1] == f"{model} 1 light"), None)
                t8 = next((med(r[4]) for r in lit if r[0] == s and r[2] == t and r[1] == f"{model} 8 lights"), None)
                vals.append(fmt((t8 - t1) * 1e6 / 7 / coverage[s]) if t1 and t8 else "n/a")
            print(f"| {model} | {t} | " + " | ".join(vals) + " |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="640x480,1024x1024")
    ap.add_argument("--rounds", type=int, default=None, help="interleaved rounds (default 5, --quick 3)")
    ap.add_argument("--quick", action="store_true", help="one size (the first), 3 rounds, scenes spot and ico")
    ap.add_argument("--groups", default="textures,aa,lit")
    ap.add_argument("--threads", default="2", help="comma-separated thread counts (default 2)")
    ap.add_argument("--no-pyrender", action="store_true")
    ap.add_argument("--png", help="write one image per scene and group into this directory")
    ap.add_argument("--seconds", type=float, default=None,
                    help="time per cell over all rounds (default 0.7, --quick 0.15)")
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    sizes = [tuple(int(x) for x in s.split("x")) for s in args.sizes.split(",")]
    if args.quick:
        sizes = sizes[:1]
    rounds = args.rounds or (3 if args.quick else 5)
    target_s = args.seconds or (0.15 if args.quick else 0.7)
    groups = [g for g in args.groups.split(",") if g]
    for g in groups:
        if g not in GROUP_ROWS:
            raise SystemExit(f"unknown group {g!r}: use {','.join(GROUP_ROWS)}")
    threads = tuple(int(t) for t in args.threads.split(","))
    pyrender, pyrender_error = (None, "skipped (--no-pyrender)") if args.no_pyrender else import_pyrender()
    if args.png:
        os.makedirs(args.png, exist_ok=True)
    for line in machine_lines():
        print(line)
    print(f"pyrender: {getattr(pyrender, '__version__', None) or pyrender_error} "
          f"(PYOPENGL_PLATFORM={os.environ.get('PYOPENGL_PLATFORM')}); rounds {rounds}, "
          f"~{target_s} s per cell, medians; ratio = with / without (softrast), pyrender's pair beside it",
          flush=True)
    for w, h in sizes:
        size = f"{w}x{h}"
        pr_renderer = None
        if pyrender is not None:
            try:
                pr_renderer = pyrender.OffscreenRenderer(w, h)
            except Exception as exc:  # noqa: BLE001
                print(f"pyrender OffscreenRenderer failed: {type(exc).__name__}: {exc}; n/a", flush=True)
        renderers = {t: sr.Renderer(w, h, threads=t) for t in threads}
        table, coverage = [], {}
        for scene_name in SCENES:
            wanted = [g for g in groups if scene_name in GROUP_SCENES[g]
                      and (not args.quick or scene_name in QUICK_SCENES)]
            if not wanted:
                continue
            ss = SceneSet(scene_name, w, h, pyrender, pr_renderer)
            coverage[scene_name] = ss.coverage_px(renderers[threads[0]], ss.sr_scene(textured=False, model="unlit"))
            for g in wanted:
                use_pr = pr_renderer is not None
                try:
                    rows, cells = GROUP_ROWS[g](ss, renderers, use_pr, args.png)
                except Exception as exc:  # noqa: BLE001 - pyrender trouble: carry on without it
                    if not use_pr:
                        raise
                    print(f"  pyrender failed on {scene_name} {g} ({type(exc).__name__}: {exc}); n/a", flush=True)
                    rows, cells = GROUP_ROWS[g](ss, renderers, False, args.png)
                t0 = time.perf_counter()
                run_interleaved(cells, target_s, rounds, 10_000, rounds)
                print(f"  {size} {scene_name} {g}: {len(cells)} cells, {time.perf_counter() - t0:.1f} s",
                      flush=True)
                table += [(scene_name, *row) for row in rows]
        if pr_renderer is not None:
            pr_renderer.delete()
        features = list(dict.fromkeys(r[1] for r in table))
        table.sort(key=lambda r: (list(GROUP_ROWS).index(group_of(r[1])), features.index(r[1]),
                                  SCENES.index(r[0]), r[2]))
        report(size, table, coverage, threads)
    print(f"\ntotal {time.perf_counter() - t_start:.0f} s", flush=True)
    return 0


def group_of(feature: str) -> str:
    if feature.startswith(("trilinear", "anisotropic", "normal")):
        return "textures"
    return "aa" if feature.startswith(("msaa", "ssaa")) else "lit"


if __name__ == "__main__":
    sys.exit(main())
