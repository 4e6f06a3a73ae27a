"""An OpenCV-convention camera (K, R, t) whose pixels agree with cv2.projectPoints."""
import sys
from pathlib import Path

import numpy as np
import trimesh

import softrast as sr

out = Path(sys.argv[1] if len(sys.argv) > 1 else "out")
out.mkdir(parents=True, exist_ok=True)

width, height = 400, 300
fx = fy = 380.0
cx, cy = 210.5, 140.0  # off-centre principal point, in OpenCV pixel-centre coordinates
camera = sr.IntrinsicsCamera(fx, fy, cx, cy, width, height, near=0.1, far=50.0, convention="opencv")
# up is the world direction that points up in the image, in both conventions (OpenCV's y axis
# pointing down the image changes nothing here): up=(0, -1, 0) would render the world upside down.
camera.look_at(eye=(2.0, -1.5, -3.0), target=(0.0, 0.0, 0.0), up=(0, 1, 0))
# The same camera from an OpenCV calibration (K, R, t) and back: sr.IntrinsicsCamera.from_opencv(K,
# rvec_or_R, tvec, width, height) and camera.to_opencv() -> (K, R, t, dist).
K, R, t, _ = camera.to_opencv()

scene = sr.Scene()
box = sr.Mesh.from_trimesh(trimesh.creation.box(extents=(1.0, 1.0, 1.0)), smooth=False)  # flat faces
scene.add(box, color=(0.9, 0.6, 0.2))
frame = sr.Renderer(width, height).render(scene, camera, outputs=("color", "depth"))

# Project the box's corners the way OpenCV does and mark them: they land on the box's corners.
corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
cam_pts = corners @ R.T + t  # x_cam = R X + t
uv = cam_pts[:, :2] / cam_pts[:, 2:] * [K[0, 0], K[1, 1]] + K[:2, 2]  # = cv2.projectPoints(corners, rvec, t, K, None)
image = frame.color.copy()
for u, v in np.round(uv).astype(int):
    if 0 <= v < height and 0 <= u < width:
        image[max(v - 2, 0):v + 3, max(u - 2, 0):u + 3] = (255, 0, 0)
sr.imwrite(out / "03_opencv_camera.png", image)
print("wrote", out / "03_opencv_camera.png")
