"""Textures: Spot the cow with its texture under a key light (07_textured_spot.png), a
checkerboard plane at a grazing angle under the four filters side by side (07_filters.png):
nearest aliases, bilinear too, trilinear blurs into grey far away, anisotropic stays sharp; and
the cow behind a lattice cut out of a quad by its texture's alpha (07_alpha_mask.png)."""
import sys
from pathlib import Path

import numpy as np
import trimesh
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


# 1. The textured cow: the OBJ's uvs, its 1024x1024 sRGB texture (trilinear by default).
tm = trimesh.load(root / "assets/meshes/spot.obj", process=False)
texture = sr.load_texture(root / "assets/meshes/spot_texture.png")
material = sr.Material(base_color=(1.0, 1.0, 1.0), base_color_texture=texture, ks=(0.25, 0.25, 0.25),
                       shininess=40.0, model="blinn_phong")
cow = sr.Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals, uvs=tm.visual.uv, material=material)
scene = sr.Scene(ambient_light=(0.15, 0.15, 0.17))
scene.add(cow)
scene.add(sr.DirectionalLight(color=(1.0, 0.95, 0.9), intensity=1.1), pose=light_pose((2, 3, -2)))
scene.add(sr.DirectionalLight(color=(0.6, 0.7, 1.0), intensity=0.35), pose=light_pose((-2, 1, 1)))
camera = sr.PerspectiveCamera(fov_y=40.0, width=480, height=360)
camera.look_at(eye=(1.7, 0.9, -2.3), target=(0.0, 0.05, 0.15))
frame = sr.Renderer(480, 360).render(scene, camera, background=(0.1, 0.1, 0.12))
sr.imwrite(out / "07_textured_spot.png", frame.color)

# 2. A checkerboard (64 x 64 checks of 8 x 8 texels) on a plane seen at a grazing angle.
n = 512
rows, cols = np.mgrid[0:n, 0:n] // 8
checker = (((rows + cols) % 2) * 255).astype(np.uint8)[:, :, None]
plane = sr.Mesh([[-4, 0, -4], [4, 0, -4], [4, 0, 4], [-4, 0, 4]], [[0, 2, 1], [0, 3, 2]],
                uvs=[[0, 1], [1, 1], [1, 0], [0, 0]],
                material=sr.Material(base_color=(1, 1, 1), base_color_texture=sr.Texture(checker),
                                     model="unlit"))
board = sr.Scene()
board.add(plane)
w, h = 320, 200
view = sr.PerspectiveCamera(fov_y=50.0, width=w, height=h)
view.look_at(eye=(0.0, 0.35, 4.3), target=(0.0, 0.0, -1.0))
renderer = sr.Renderer(w, h)
label_h = 18
grid = np.zeros((2 * (h + label_h), 2 * w, 3), np.uint8)
for k, name in enumerate(sr.texture.FILTERS):
    image = renderer.render(board, view, texture_filter=name, background=(0.3, 0.4, 0.6)).color
    tile = Image.new("RGB", (w, label_h), (24, 24, 24))
    ImageDraw.Draw(tile).text((4, 3), name, fill=(230, 230, 230))
    r, c = divmod(k, 2)
    grid[r * (h + label_h): r * (h + label_h) + label_h, c * w:(c + 1) * w] = np.asarray(tile)
    grid[r * (h + label_h) + label_h:(r + 1) * (h + label_h), c * w:(c + 1) * w] = image
sr.imwrite(out / "07_filters.png", grid)

# 3. Alpha masks (glTF's alphaMode MASK): a lattice whose gaps are alpha 0 in an RGBA texture,
# on one quad between the camera and the cow. Fragments with alpha < alpha_cutoff are discarded
# before the depth test, so the cow shows through the gaps (in the depth and ids too).
m = 256
v, u = np.mgrid[0:m, 0:m] / m
bars = (np.abs(((u + v) * 6) % 1 - 0.5) > 0.38) | (np.abs(((u - v) * 6) % 1 - 0.5) > 0.38)
lattice = np.dstack([np.full((m, m), 150), 95 + 40 * v, np.full((m, m), 50), bars * 255]).astype(np.uint8)
fence = sr.Mesh([[-0.7, -0.45, 0], [0.7, -0.45, 0], [0.7, 0.45, 0], [-0.7, 0.45, 0]], [[0, 1, 2], [0, 2, 3]],
                uvs=[[0, 0], [1, 0], [1, 1], [0, 1]],
                material=sr.Material(base_color_texture=sr.Texture(lattice), model="pbr",
                                     roughness=0.8, double_sided=True, alpha_mode="mask",
                                     alpha_cutoff=0.5))
to_camera = np.asarray(camera.pose)[:3, 3] - np.array([0.0, 0.05, 0.15])
pose = light_pose(0.45 * to_camera + np.array([0.0, 0.05, 0.15]), target=camera.pose[:3, 3])
pose[:3, 2] *= -1  # the quad faces the camera (+z toward it)
pose[:3, 0] *= -1
scene.add(fence, pose=pose)
frame = sr.Renderer(480, 360).render(scene, camera, background=(0.1, 0.1, 0.12))
sr.imwrite(out / "07_alpha_mask.png", frame.color)
print(f"wrote {out / '07_textured_spot.png'}, {out / '07_filters.png'} and {out / '07_alpha_mask.png'}")
