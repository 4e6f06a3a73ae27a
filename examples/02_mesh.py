"""A real mesh: Spot the cow with the default headlight, plus depth (EXR) and mask (PNG)."""
import sys
from pathlib import Path

import numpy as np

import softrast as sr

root = Path(__file__).resolve().parent.parent
out = Path(sys.argv[1] if len(sys.argv) > 1 else "out")
out.mkdir(parents=True, exist_ok=True)

mesh = sr.load_mesh(root / "assets" / "meshes" / "spot.obj")  # trimesh underneath
scene = sr.Scene()
scene.add(mesh, pose=np.eye(4))

camera = sr.PerspectiveCamera(fov_y=45.0, width=640, height=480, near=0.05, far=100.0)
camera.look_at(eye=(1.7, 0.9, -2.3), target=(0.0, 0.05, 0.15), up=(0, 1, 0))

frame = sr.Renderer(640, 480).render(scene, camera, outputs=("color", "depth", "mask"))
sr.imwrite(out / "02_spot.png", frame.color)        # (480, 640, 3) uint8
sr.imwrite(out / "02_spot_depth.tif", frame.depth)  # (480, 640) float32, 0 = background
sr.imwrite(out / "02_spot_mask.png", frame.mask)    # bool -> 0 / 255
hit = frame.depth[frame.mask]
print(f"covered {frame.mask.mean():.1%} of the image, depth {hit.min():.3f}..{hit.max():.3f}")
