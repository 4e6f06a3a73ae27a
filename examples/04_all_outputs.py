"""Every output of one render: colour, depth, mask, normals, triangle and instance ids."""
import sys
from pathlib import Path

import numpy as np
import trimesh

import softrast as sr

out = Path(sys.argv[1] if len(sys.argv) > 1 else "out")
out.mkdir(parents=True, exist_ok=True)

sphere = sr.Mesh.from_trimesh(trimesh.creation.icosphere(subdivisions=4))
box = sr.Mesh.from_trimesh(trimesh.creation.box(extents=(1.2, 1.2, 1.2)), smooth=False)
scene = sr.Scene()
scene.add(sphere, pose=np.eye(4), instance_id=1, color=(0.2, 0.6, 0.9))
pose = np.eye(4)
pose[:3, 3] = (1.3, 0.0, -0.8)
scene.add(box, pose=pose, instance_id=2, color=(0.9, 0.4, 0.3))

camera = sr.OrthographicCamera(xmag=2.4, ymag=1.8, near=0.1, far=20.0)  # depth is right here too
camera.look_at(eye=(2.0, 2.0, 5.0), target=(0.5, 0.0, -0.3))
frame = sr.Renderer(400, 300).render(scene, camera, outputs=sr.OUTPUTS)

sr.imwrite(out / "04_color.png", frame.color)
sr.imwrite(out / "04_depth.tif", frame.depth)
sr.imwrite(out / "04_normal.png", ((frame.normal * 0.5 + 0.5) * 255).astype(np.uint8))
sr.imwrite(out / "04_instance_id.png", (frame.instance_id * 100 + 50).clip(0, 255).astype(np.uint8))
for name in frame.outputs:
    array = getattr(frame, name)
    print(f"{name:12s} {str(array.shape):14s} {array.dtype}")
