"""Anti-aliasing, lines and points: textured Spot without anti-aliasing, with msaa=4 and with
ssaa=4 (08_spot_*.png), zoomed on its outline (08_zoom.png); the msaa render composited over a
gradient with its alpha output (08_composite.png: no fringe, since radiance is premultiplied);
its wireframe over the solid (08_wireframe.png: front edges shown, back ones hidden); and a
point cloud sampled on its surface with axis lines, depth-tested against a ground quad
(08_points.png)."""
import sys
from pathlib import Path

import numpy as np
import trimesh
from PIL import Image, ImageDraw

import softrast as sr

root = Path(__file__).resolve().parent.parent
out = Path(sys.argv[1] if len(sys.argv) > 1 else "out")
out.mkdir(parents=True, exist_ok=True)

tm = trimesh.load(root / "assets/meshes/spot.obj", process=False)
texture = sr.load_texture(root / "assets/meshes/spot_texture.png")
material = sr.Material(base_color=(1.0, 1.0, 1.0), base_color_texture=texture, ks=(0.25, 0.25, 0.25),
                       shininess=40.0, model="blinn_phong")
scene = sr.Scene(ambient_light=(0.15, 0.15, 0.17))
scene.add(sr.Mesh(tm.vertices, tm.faces, normals=tm.vertex_normals, uvs=tm.visual.uv, material=material))
# A light shines along its pose's -z: look_at_pose from the light's position at the cow.
scene.add(sr.DirectionalLight(color=(1.0, 0.95, 0.9), intensity=1.1),
          pose=sr.look_at_pose(eye=(2, 3, -2), target=(0, 0, 0)))

w, h = 320, 240
camera = sr.PerspectiveCamera(fov_y=45.0, width=w, height=h, near=0.05, far=20.0)
camera.look_at(eye=(1.7, 0.9, -2.3), target=(0.0, 0.05, 0.15))
renderer = sr.Renderer(w, h)

# The same view three ways; every other output (depth, ids, normals) stays exact and unblended.
modes = {"off": {}, "msaa=4": {"msaa": 4}, "ssaa=4": {"ssaa": 4}}
frames = {name: renderer.render(scene, camera, outputs=("color", "radiance", "alpha", "triangle_id"),
                                **mode) for name, mode in modes.items()}
for name, frame in frames.items():
    sr.imwrite(out / f"08_spot_{name.replace('=', '')}.png", frame.color)
    ids = np.unique(frame.triangle_id[frame.alpha > 0])
    print(f"{name:>7}: {np.count_nonzero((frame.alpha > 0) & (frame.alpha < 1)):5d} edge pixels, "
          f"ids all real faces: {bool(ids.min() >= 0)}")

# Zoom 6x (nearest neighbour) on the 40x40 window with the most partly covered pixels.
size, zoom = 40, 6
partial = ((frames["msaa=4"].alpha > 0) & (frames["msaa=4"].alpha < 1)).astype(np.int64)
sums = np.pad(partial.cumsum(0).cumsum(1), ((1, 0), (1, 0)))
windows = sums[size:, size:] - sums[:-size, size:] - sums[size:, :-size] + sums[:-size, :-size]
y0, x0 = np.unravel_index(np.argmax(windows), windows.shape)
tiles = []
for name, frame in frames.items():
    crop = frame.color[y0:y0 + size, x0:x0 + size]
    tile = Image.fromarray(np.kron(crop, np.ones((zoom, zoom, 1), np.uint8)))
    ImageDraw.Draw(tile).text((6, 4), name, fill=(255, 255, 255))
    tiles.append(np.asarray(tile))
sr.imwrite(out / "08_zoom.png", np.concatenate(tiles, axis=1))

# Compositing with alpha: radiance is premultiplied, so radiance + (1 - alpha) * background in
# linear light is exactly the render over that background (no dark fringe at the silhouette).
frame = frames["msaa=4"]
t = np.linspace(0.0, 1.0, w)[None, :, None]
background = (1 - t) * np.array([0.9, 0.5, 0.2]) + t * np.array([0.1, 0.3, 0.8])  # linear
composite = frame.radiance + (1.0 - frame.alpha[..., None]) * background
encoded = np.where(composite <= 0.0031308, 12.92 * composite,
                   1.055 * np.power(np.clip(composite, 0.0031308, 1.0), 1 / 2.4) - 0.055)
sr.imwrite(out / "08_composite.png", np.rint(np.clip(encoded, 0, 1) * 255).astype(np.uint8))
print("sample positions of msaa=4 (pixel units from the top-left corner):",
      sr.sample_positions(msaa=4).tolist())

# The wireframe over the solid: every edge as a line with a small depth bias, so the front
# edges show and the back ones stay hidden behind the faces.
frame = renderer.render(scene, camera, wireframe=True, line_color=(0.02, 0.05, 0.2), msaa=4,
                        background=(1, 1, 1))
sr.imwrite(out / "08_wireframe.png", frame.color)

# A point cloud: 200,000 points on the cow's surface, coloured by height, standing on a ground
# quad (depth-tested against it and each other), with the three axes at a corner as lines of
# width 3.
rng = np.random.default_rng(0)
points, _ = trimesh.sample.sample_surface(tm, 200_000, seed=0)
height = (points[:, 1] - points[:, 1].min()) / np.ptp(points[:, 1])
colors = np.stack([height, 0.3 + 0.4 * (1 - height), 1 - height], axis=1) ** 2.2  # linear
cloud = sr.Scene(ambient_light=(0.3, 0.3, 0.3))
cloud.add(sr.Points(points, colors=colors, size=1.0))
o = (0.75, -0.72, 0.1)  # the axes' origin, just above the ground beside the cow
axes = sr.Lines(np.array([[0, 0, 0], [0.6, 0, 0], [0, 0, 0], [0, 0.6, 0], [0, 0, 0], [0, 0, 0.6]]) + o,
                [[0, 1], [2, 3], [4, 5]], colors=[[1, 0, 0]] * 2 + [[0, 1, 0]] * 2 + [[0, 0, 1]] * 2,
                width=3.0)
cloud.add(axes)
ground = sr.Mesh([[-2, -0.74, -2], [2, -0.74, -2], [2, -0.74, 2], [-2, -0.74, 2]], [[0, 2, 1], [0, 3, 2]],
                 material=sr.Material(base_color=(0.5, 0.5, 0.5), double_sided=True))
cloud.add(ground)
frame = renderer.render(cloud, camera, outputs=("color", "instance_id"), cull="none",
                        background=(0.05, 0.05, 0.08))
sr.imwrite(out / "08_points.png", frame.color)
