"""Batch rendering: many views of one mesh, reusing one renderer and its frame (out=)."""
import sys
from pathlib import Path

import numpy as np

import softrast as sr

root = Path(__file__).resolve().parent.parent
out = Path(sys.argv[1] if len(sys.argv) > 1 else "out") / "05_views"
out.mkdir(parents=True, exist_ok=True)

scene = sr.Scene()
scene.add(sr.load_mesh(root / "assets" / "meshes" / "spot.obj"))
renderer = sr.Renderer(256, 256)  # threads=0: all cores; the images are identical for any count
camera = sr.PerspectiveCamera(fov_y=40.0, near=0.05, far=20.0)

frame = None
for i, angle in enumerate(np.linspace(0.0, 2.0 * np.pi, 8, endpoint=False)):
    camera.look_at(eye=(3.0 * np.sin(angle), 1.0, 3.0 * np.cos(angle)), target=(0.0, 0.1, 0.2))
    # out=frame renders into the previous frame's arrays: no allocation per view.
    frame = renderer.render(scene, camera, outputs=("color", "depth", "mask"), out=frame)
    sr.imwrite(out / f"view_{i:03d}.png", frame.color)
    sr.imwrite(out / f"view_{i:03d}_depth.exr", frame.depth)
    np.save(out / f"view_{i:03d}_pose.npy", camera.pose)
print("wrote 8 views to", out)
