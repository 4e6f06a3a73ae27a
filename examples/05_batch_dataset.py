"""Batch rendering: an orbit of views of one mesh with Renderer.render_many (views rendered
concurrently, frames yielded in order), colour + depth + ids + the surface outputs saved with
Frame.save, and each camera's OpenCV K and pose saved beside the images."""
import sys
from pathlib import Path

import numpy as np

import softrast as sr

root = Path(__file__).resolve().parent.parent
out = Path(sys.argv[1] if len(sys.argv) > 1 else "out") / "05_views"
out.mkdir(parents=True, exist_ok=True)

scene = sr.Scene()
scene.add(sr.load_mesh(root / "assets" / "meshes" / "spot.obj"), instance_id=1)
w, h = 256, 256
renderer = sr.Renderer(w, h)  # threads=0: all cores; the images are identical for any count

# Eight poses on a turntable around the cow, 20 degrees up, 3 units away.
cameras = []
for pose in sr.orbit(target=(0.0, 0.1, 0.2), radius=3.0, n=8, elevation=20.0):
    camera = sr.PerspectiveCamera(fov_y=40.0, width=w, height=h, near=0.05, far=20.0)
    camera.pose = pose
    cameras.append(camera)

outputs = ("color", "depth", "instance_id", "position", "uv")
for i, frame in enumerate(renderer.render_many(scene, cameras, outputs=outputs)):
    # view_000_color.png, view_000_depth.tif, view_000_instance_id.png (id + 1), ..._uv.tif;
    # sr.Frame.load(out, "view_000") reads them back exactly.
    frame.save(out, f"view_{i:03d}", formats={"position": "npy"})
# K in OpenCV's convention (pixel (row i, col j) centred at (u, v) = (j, i)) and the poses
# (camera-to-world, OpenGL axes): camera.unproject(depth) turns a depth image back into points.
np.savez(out / "cameras.npz", K=cameras[0].K, poses=np.stack([c.pose for c in cameras]),
         width=w, height=h)
print(f"wrote {len(cameras)} views to {out}")
