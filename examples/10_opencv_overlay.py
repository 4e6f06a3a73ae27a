"""An OpenCV calibration with lens distortion: render through it and overlay the render on a photo.

The "photo" here is itself rendered (a checkerboard floor seen through a wide-angle lens with
strong barrel distortion), so the example runs anywhere; with a real photo, pass its K, dist, rvec
and tvec from cv2.calibrateCamera / cv2.solvePnP instead. Writes 10_opencv_overlay.png: left, the
cow's outline drawn as an ideal pinhole would see it (it drifts off towards the edges); right, as
the distorted camera sees it (on the cow), with cv2.projectPoints of the floor's corners (red
dots) landing on the board's corners.
"""
import sys
from pathlib import Path

import cv2
import numpy as np
import trimesh

import softrast as sr

root = Path(__file__).resolve().parent.parent
out = Path(sys.argv[1] if len(sys.argv) > 1 else "out")
out.mkdir(parents=True, exist_ok=True)

# 1. The calibration, as OpenCV gives it: K, distortion (k1, k2, p1, p2, k3), and the world-to-camera
#    rvec/tvec of one view (here: a camera 2.3 units from the origin, looking down at it).
width, height = 480, 360
K = np.array([[260.0, 0.0, 243.2], [0.0, 260.0, 176.9], [0.0, 0.0, 1.0]])
dist = np.array([-0.32, 0.11, 0.0008, -0.0006, -0.018])
look = sr.IntrinsicsCamera(K[0, 0], K[1, 1], K[0, 2], K[1, 2], width, height)
look.look_at(eye=(0.9, 1.3, 1.7), target=(0.0, 0.2, 0.0), up=(0, 1, 0))
_, R, t, _ = look.to_opencv()
rvec = cv2.Rodrigues(R)[0]

camera = sr.IntrinsicsCamera.from_opencv(K, rvec, t, width, height, dist=dist, near=0.05, far=20.0)
pinhole = sr.IntrinsicsCamera.from_opencv(K, rvec, t, width, height, near=0.05, far=20.0)  # dist ignored

# 2. The "photo": a checkerboard floor through the distorted lens.
board = np.kron((np.indices((8, 8)).sum(axis=0) % 2), np.ones((32, 32)))
board = (np.stack([board] * 3, axis=-1) * 200 + 30).astype(np.uint8)
floor_pts = np.array([[-1.6, 0.0, -1.6], [1.6, 0.0, -1.6], [1.6, 0.0, 1.6], [-1.6, 0.0, 1.6]])
floor = sr.Mesh(floor_pts, [[0, 2, 1], [0, 3, 2]], uvs=[[0, 0], [1, 0], [1, 1], [0, 1]],
                material=sr.Material(base_color_texture=sr.Texture(board, filter="anisotropic")))
photo_scene = sr.Scene()
photo_scene.add(floor)
renderer = sr.Renderer(width, height)
photo = renderer.render(photo_scene, camera, "color", shading="unlit", cull="none",
                        background=(0.35, 0.4, 0.45)).color

# 3. The object to overlay (Spot the cow), rendered with the same calibration: its mask's outline
#    drawn on the photo, BGR as OpenCV wants it.
tm = trimesh.load(root / "assets/meshes/spot.obj", process=False)
scene = sr.Scene()
scene.add(sr.Mesh(tm.vertices, tm.faces), pose=trimesh.transformations.translation_matrix((0.0, 0.737, 0.0)))
panels = []
for cam in (pinhole, camera):
    frame = renderer.render(scene, cam, ("color", "mask"))
    image = sr.opencv.to_bgr(photo)
    seen = frame.mask
    image[seen] = (0.5 * image[seen] + 0.5 * sr.opencv.to_bgr(frame.color)[seen]).astype(np.uint8)
    sr.opencv.draw_outline(image, seen, color=(0, 255, 0), thickness=1)
    # the floor's corners and centre through OpenCV's own projection (with the distortion)
    uv, _ = cv2.projectPoints(np.r_[floor_pts, [[0.0, 0.0, 0.0]]], rvec, t, K, dist)
    for u, v in uv.reshape(-1, 2):
        cv2.circle(image, (int(round(u)), int(round(v))), 3, (0, 0, 255), -1)
    panels.append(image[..., ::-1])  # back to RGB for imwrite

sr.imwrite(out / "10_opencv_overlay.png", np.ascontiguousarray(np.concatenate(panels, axis=1)))
print("wrote", out / "10_opencv_overlay.png")
