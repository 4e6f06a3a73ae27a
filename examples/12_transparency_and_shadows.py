"""Transparency and shadows: Spot standing on a floor behind a pane of tinted glass
(``alpha_mode="blend"``), lit by a sun and a spot lamp. Four renders of the same view:
no shadows (12_shadows_off.png), exact shadows (12_shadows_exact.png: a ray per pixel to each
light, hard and without acne or a bias to tune), shadow maps as pyrender and game engines draw
them (12_shadows_map.png: soft-edged by the filter, a 1024-texel map per light), and the exact
render's difference to the maps (12_exact_vs_map.png, amplified 8x). The glass composites over
whatever is behind it in depth order, and casts no shadow. Last, msaa=4 with
``alpha_threshold=0.3``: the depth output then describes the glass (alpha 0.35) where it lies
in front, instead of what is seen through it (12_depth_through_glass.png vs
12_depth_of_glass.png)."""
import sys
from pathlib import Path

import numpy as np
import trimesh

import softrast as sr

root = Path(__file__).resolve().parent.parent
out = Path(sys.argv[1] if len(sys.argv) > 1 else "out")
out.mkdir(parents=True, exist_ok=True)

tm = trimesh.load(root / "assets/meshes/spot.obj", process=False)
texture = sr.load_texture(root / "assets/meshes/spot_texture.png")
cow = sr.Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals, uvs=tm.visual.uv,
              material=sr.Material(base_color_texture=texture, model="blinn_phong",
                                   ks=(0.2, 0.2, 0.2), shininess=30.0))
y0 = float(tm.vertices[:, 1].min())
floor = sr.Mesh(np.array([[-3.0, y0, -3.0], [3.0, y0, -3.0], [3.0, y0, 3.0], [-3.0, y0, 3.0]]),
                np.array([[0, 2, 1], [0, 3, 2]]),
                material=sr.Material(base_color=(0.75, 0.72, 0.68), model="lambert"))
glass = sr.Mesh(np.array([[-0.9, y0, -0.9], [0.2, y0, -1.3], [0.2, y0 + 1.0, -1.3], [-0.9, y0 + 1.0, -0.9]]),
                np.array([[0, 1, 2], [0, 2, 3]]),
                material=sr.Material(base_color=(0.3, 0.6, 0.9, 0.35), model="blinn_phong",
                                     alpha_mode="blend", double_sided=True))

scene = sr.Scene(ambient_light=(0.12, 0.12, 0.14))
for mesh in (cow, floor, glass):
    scene.add(mesh)
# Lights shine along their pose's -z: look_at_pose from the light toward the cow. Each light
# says how it casts shadows; render(shadows=...) below overrides them all for one render.
scene.add(sr.DirectionalLight(color=(1.0, 0.95, 0.85), intensity=1.2, shadows="exact",
                              shadow_resolution=1024),
          pose=sr.look_at_pose(eye=(-2.0, 3.0, 1.0), target=(0.0, 0.0, 0.0)))
scene.add(sr.SpotLight(color=(0.6, 0.7, 1.0), intensity=4.0, inner_cone=0.3, outer_cone=0.6,
                       shadows="exact", shadow_resolution=1024),
          pose=sr.look_at_pose(eye=(1.8, 2.2, 0.5), target=(0.0, 0.0, 0.0)))

w, h = 480, 360
camera = sr.PerspectiveCamera(fov_y=45.0, width=w, height=h, near=0.05, far=20.0)
camera.look_at(eye=(0.9, 1.2, -3.0), target=(0.0, 0.05, 0.0))
renderer = sr.Renderer(w, h)

frames = {name: renderer.render(scene, camera, outputs=("color", "radiance"), shadows=shadows)
          for name, shadows in (("off", False), ("exact", "exact"), ("map", "map"))}
for name, frame in frames.items():
    sr.imwrite(out / f"12_shadows_{name}.png", frame.color)
difference = np.abs(frames["exact"].radiance - frames["map"].radiance).max(-1)
sr.imwrite(out / "12_exact_vs_map.png", (np.clip(difference * 8.0, 0.0, 1.0) * 255).astype(np.uint8))
shadowed = (frames["exact"].radiance < frames["off"].radiance).any(-1)
print(f"{shadowed.mean():.1%} of the pixels lose some light to a shadow; exact and map differ by "
      f"more than 1/255 on {(difference > 1 / 255).mean():.2%} of them (mostly the maps' soft edges)")

# Depth (and ids, mask, normal, the surface outputs) follow the nearest opaque surface by
# default; alpha_threshold makes a blended fragment with an alpha at least that stand for it.
for name, threshold in (("through_glass", None), ("of_glass", 0.3)):
    f = renderer.render(scene, camera, outputs=("depth", "alpha"), msaa=4, alpha_threshold=threshold)
    grey = np.where(f.depth > 0, 1.0 - (f.depth - 2.0) / 3.0, 0.0)
    sr.imwrite(out / f"12_depth_{name}.png", (np.clip(grey, 0.0, 1.0) * 255).astype(np.uint8)[..., None])
    print(f"alpha_threshold={threshold}: mean depth {f.depth[f.depth > 0].mean():.3f}")
