"""Every shading model at every frequency: Spot the cow under a warm key light, a blue point light
and a spot light, as one labelled grid (rows: pixel / vertex / face frequency; columns: models)."""
import math
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

import softrast as sr

root = Path(__file__).resolve().parent.parent
out = Path(sys.argv[1] if len(sys.argv) > 1 else "out")
out.mkdir(parents=True, exist_ok=True)


def light_pose(position, target=(0.0, 0.0, 0.0)):
    """A pose at `position` whose -z axis (the way lights shine) points at `target`."""
    z = np.asarray(position, float) - np.asarray(target, float)
    z /= np.linalg.norm(z)
    x = np.cross((0.0, 1.0, 0.0), z)
    x /= np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, np.cross(z, x), z, position
    return pose


material = sr.Material(base_color=(0.75, 0.55, 0.35), ks=(0.6, 0.6, 0.6), shininess=60.0,
                       metallic=0.0, roughness=0.35)
mesh = sr.Mesh.from_trimesh(__import__("trimesh").load(root / "assets/meshes/spot.obj", process=False,
                                                       skip_materials=True))
scene = sr.Scene(ambient_light=(0.04, 0.04, 0.05))
scene.add(mesh, material=material)
scene.add(sr.DirectionalLight(color=(1.0, 0.92, 0.8), intensity=0.9), pose=light_pose((2, 3, -2)))
scene.add(sr.PointLight(color=(0.4, 0.6, 1.0), intensity=1.5), pose=light_pose((-1.2, 0.6, 1.0)))
scene.add(sr.SpotLight(intensity=2.0, inner_cone=0.1, outer_cone=0.3), pose=light_pose((0.3, 2.0, -0.8)))

w, h = 256, 192
camera = sr.PerspectiveCamera(fov_y=40.0, width=w, height=h, near=0.05, far=20.0)
camera.look_at(eye=(1.7, 0.9, -2.3), target=(0.0, 0.05, 0.15))
renderer = sr.Renderer(w, h)

models = ("unlit", "lambert", "phong", "blinn_phong", "pbr", "normal")
frequencies = ("pixel", "vertex", "face")
label_h = 18
grid = np.zeros((len(frequencies) * (h + label_h), len(models) * w, 3), np.uint8)
for i, frequency in enumerate(frequencies):
    for j, model in enumerate(models):
        frame = renderer.render(scene, camera, outputs=("color",), shading=model, frequency=frequency,
                                background=(0.12, 0.12, 0.12))
        y = i * (h + label_h) + label_h
        grid[y:y + h, j * w:(j + 1) * w] = frame.color

image = Image.fromarray(grid)
draw = ImageDraw.Draw(image)
for i, frequency in enumerate(frequencies):
    for j, model in enumerate(models):
        draw.text((j * w + 6, i * (h + label_h) + 3), f"{model}, frequency={frequency}", fill=(230, 230, 230))
sr.imwrite(out / "06_shading_models.png", np.asarray(image))
print(f"wrote {out / '06_shading_models.png'}: {len(models)} models x {len(frequencies)} frequencies "
      f"({math.prod(grid.shape[:2]) // 1000} kpixels)")
