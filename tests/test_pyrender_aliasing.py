"""pyrender under OSMesa renders aliased: the README and benchmarks once said
pyrender "always renders 4x MSAA". It asks for a 4-sample framebuffer only where its platform
supports framebuffers (EGL, pyglet's window); OSMesaPlatform.supports_framebuffers() is False,
so OffscreenRenderer draws into OSMesa's own single-sample buffer. A flat white sphere on black
therefore has no blended silhouette pixel, while softrast's msaa=4 blends many. This backs what
README.md says of the anti-aliasing rows of bench_vs_pyrender.py (which compare softrast's
msaa=4 against that aliased pyrender render)."""
from __future__ import annotations

import math
import pathlib
import pickle

import numpy as np
import trimesh

import softrast as sr
from support.pyrender_runner import run_pyrender_child

CHILD = pathlib.Path(__file__).resolve().parent / "support" / "pyrender_to_child.py"
W, H = 640, 480
NEAR, FAR = 0.5, 20.0
YFOV = math.radians(45.0)


def _silhouette(covered: np.ndarray) -> np.ndarray:
    """Pixels with a 4-neighbour of the other kind (covered / not covered)."""
    pad = np.pad(covered, 1, mode="edge")
    differs = np.zeros_like(covered)
    for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        differs |= pad[1 + dy:1 + dy + covered.shape[0], 1 + dx:1 + dx + covered.shape[1]] != covered
    return differs


def test_pyrender_osmesa_does_not_antialias_silhouettes(tmp_path):
    sphere = trimesh.creation.icosphere(subdivisions=6, radius=1.0)  # the anti-aliasing rows' mesh
    pose = np.eye(4)
    pose[2, 3] = 3.0
    job = {"name": "flat_sphere", "width": W, "height": H,
           "direct": {"meshes": [{"positions": np.asarray(sphere.vertices, np.float32),
                                  "faces": np.asarray(sphere.faces, np.int32), "colors": None,
                                  "base": (1.0, 1.0, 1.0, 1.0), "pose": np.eye(4)}],
                      "camera": {"kind": "perspective", "yfov": YFOV, "pose": pose},
                      "znear": NEAR, "zfar": FAR}}
    (tmp_path / "jobs.pkl").write_bytes(pickle.dumps([job]))
    parent = str(pathlib.Path(sr.__file__).resolve().parent.parent)
    run_pyrender_child(CHILD, [parent, tmp_path / "jobs.pkl", tmp_path], timeout=300)
    result = pickle.loads((tmp_path / "flat_sphere.pkl").read_bytes())
    assert result["error"] is None, result["error"]
    color, depth = result["renders"]["flat"]
    grey = color[..., 0].astype(int)
    band = _silhouette(depth > 0)
    assert band.sum() > 1000  # a real silhouette (2,316 pixels here)
    # every pixel is background (0) or the white sphere (255): nothing blended at the silhouette
    assert set(np.unique(grey).tolist()) == {0, 255}
    assert ((grey > 0) & (grey < 255) & band).sum() == 0

    # softrast's msaa=4 on the same view blends silhouette pixels (the comparison is not like
    # for like: softrast shades 4 samples' coverage there, pyrender 1)
    scene = sr.Scene(ambient_light=(1.0, 1.0, 1.0))
    scene.add(sr.Mesh(sphere.vertices, sphere.faces), material=sr.Material(base_color=(1.0, 1.0, 1.0)))
    cam = sr.PerspectiveCamera(fov_y=45.0, width=W, height=H, near=NEAR, far=FAR)
    cam.pose = pose
    frame = sr.Renderer(W, H).render(scene, cam, outputs=("color",), shading="unlit", msaa=4)
    sr_grey = frame.color[..., 0].astype(int)
    assert ((sr_grey > 0) & (sr_grey < 255)).sum() > 0.3 * band.sum()
