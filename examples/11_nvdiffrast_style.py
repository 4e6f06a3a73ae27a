"""nvdiffrast code on a CPU: clip-space positions -> rasterize -> interpolate, on NumPy arrays.

With nvdiffrast this would be ``import nvdiffrast.torch as dr`` and CUDA tensors; here the same
calls take NumPy arrays. nvdiffrast's images have row 0 at the BOTTOM: flip them for a PNG.
"""
import sys
from pathlib import Path

import numpy as np

import softrast as sr
import softrast.nv as dr

out = Path(sys.argv[1] if len(sys.argv) > 1 else "out")
out.mkdir(parents=True, exist_ok=True)

# A cube: 8 corners, 12 triangles, one colour per corner (its position mapped to RGB).
corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)], np.float32)
tri = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], np.int32)
colors = corners + 0.5


def projection(fov_y_deg=45.0, aspect=1.0, n=0.1, f=10.0):
    """OpenGL's perspective matrix (gluPerspective): view space -> clip space."""
    t = 1.0 / np.tan(np.radians(fov_y_deg) / 2.0)
    return np.array([[t / aspect, 0, 0, 0], [0, t, 0, 0],
                     [0, 0, -(f + n) / (f - n), -2 * f * n / (f - n)], [0, 0, -1, 0]])


def rotate_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]])


def rotate_y(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1]])


# A minibatch of 4 views (instanced mode): each image has its own clip-space positions.
batch = []
for k in range(4):
    model_view = np.eye(4)
    model_view[2, 3] = -2.5  # push the cube in front of the camera (it looks down -z)
    model_view = model_view @ rotate_x(0.5) @ rotate_y(-0.4 - k * np.pi / 8)
    mvp = projection() @ model_view
    batch.append(np.c_[corners, np.ones(8)] @ mvp.T)  # (x, y, z, 1) -> clip space
pos = np.stack(batch).astype(np.float32)  # (4, 8, 4)

glctx = dr.RasterizeCudaContext()  # a no-op stand-in: nvdiffrast code runs unchanged
rast, rast_db = dr.rasterize(glctx, pos, tri, resolution=[256, 256])  # (4, 256, 256, 4)
color, _ = dr.interpolate(colors, rast, tri)  # (4, 256, 256, 3), 0 where empty

images = np.clip(np.rint(color[:, ::-1] * 255), 0, 255).astype(np.uint8)  # flip: row 0 = top
sr.imwrite(out / "11_nvdiffrast_cube.png", np.concatenate(list(images), axis=1))  # 4 side by side
covered = rast[..., 3] > 0  # triangle_id + 1, 0 = background
print("wrote", out / "11_nvdiffrast_cube.png", f"coverage per view: {covered.mean(axis=(1, 2)).round(3)}")
