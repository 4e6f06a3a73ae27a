"""The smallest render: one vertex-coloured triangle, unlit, written to a PNG."""
import sys
from pathlib import Path

import numpy as np

import softrast as sr

out = Path(sys.argv[1] if len(sys.argv) > 1 else "out")
out.mkdir(parents=True, exist_ok=True)

positions = np.array([[-0.8, -0.6, 0.0], [0.8, -0.6, 0.0], [0.0, 0.7, 0.0]])  # counter-clockwise
faces = np.array([[0, 1, 2]])
colors = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])  # interpolated per pixel
mesh = sr.Mesh(positions, faces, colors=colors)

scene = sr.Scene()
scene.add(mesh)
camera = sr.PerspectiveCamera(fov_y=60.0, near=0.1, far=10.0)
camera.look_at(eye=(0.0, 0.0, 2.0), target=(0.0, 0.0, 0.0))

frame = sr.Renderer(320, 240).render(scene, camera, outputs="color", shading="unlit")
sr.imwrite(out / "01_triangle.png", frame.color)
print("wrote", out / "01_triangle.png", frame.color.shape, frame.color.dtype)
