"""Checks softrast.reference.shading's "pbr" against pyrender 0.1.45 (OSMesa) to the byte.

Renders a finely tessellated unit sphere with analytic normals under a directional, a point and a
spot light for several metallic / roughness pairs, a light from behind only (pyrender's NdotL
floor of 0.001 leaks it) and smooth vertex colours (pyrender multiplies the final colour by
them). Positions come from pyrender's depth; the reference's radiance + pyrender's emissive^2,
encoded with pyrender_encode (pow 1/2.2), is compared with pyrender's bytes away from the
silhouette. Expected: max diff <= 1 everywhere. See docs/pbr_notes.md.
Usage: bash benchmarks/setup_baselines.sh && python3 benchmarks/check_reference_vs_pyrender.py
"""
import os, sys, math
os.environ["PYOPENGL_PLATFORM"] = "osmesa"
import numpy as np, pyrender, trimesh
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "python"))
from softrast.reference import shading as ref
import softrast as sr

W, H = 160, 120
rng = np.random.default_rng(1)
sphere = trimesh.creation.icosphere(subdivisions=6)
def run(metallic, roughness, base, lights, ambient, emissive=(0,0,0)):
    scene = pyrender.Scene(ambient_light=np.array(ambient), bg_color=[0,0,0,1])
    mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=list(base)+[1.0], metallicFactor=metallic,
                                             roughnessFactor=roughness, emissiveFactor=list(emissive))
    tm = trimesh.Trimesh(sphere.vertices, sphere.faces, vertex_normals=sphere.vertices, process=False)
    scene.add(pyrender.Mesh.from_trimesh(tm, material=mat, smooth=True))
    recs = []
    for kind, color, inten, pose, extra in lights:
        if kind == 0: L = pyrender.DirectionalLight(color=color, intensity=inten); sl = sr.DirectionalLight(color, inten)
        elif kind == 1: L = pyrender.PointLight(color=color, intensity=inten); sl = sr.PointLight(color, inten)
        else: L = pyrender.SpotLight(color=color, intensity=inten, innerConeAngle=extra[0], outerConeAngle=extra[1]); sl = sr.SpotLight(color, inten, extra[0], extra[1])
        scene.add(L, pose=pose); recs.append(sl._record_fields(pose))
    cam = sr.PerspectiveCamera(fov_y=40.0, near=0.5, far=10.0); cam.look_at((0.5, 0.8, 3.0), (0, 0, 0))
    scene.add(pyrender.PerspectiveCamera(yfov=math.radians(40.0), znear=0.5, zfar=10.0, aspectRatio=W/H), pose=cam.pose)
    r = pyrender.OffscreenRenderer(W, H)
    color, depth = r.render(scene)
    r.delete()
    view, proj = cam._render_matrices(W, H)
    m = depth > 0
    rows, cols = np.nonzero(m)
    p = ref.unproject(depth, view, proj, rows, cols)
    n = p / np.linalg.norm(p, axis=1, keepdims=True)
    M = sr.Material(base_color=base, metallic=metallic, roughness=roughness)
    rad = ref.radiance("pbr", n, p, base, M, recs, ambient, cam.pose[:3, 3])
    rad += np.asarray(emissive)**2  # pyrender adds emissive_factor squared
    want = ref.pyrender_encode(rad)
    got = color[rows, cols]
    d = np.abs(got.astype(int) - want.astype(int))
    # interior only (silhouette pixels: MSAA + tessellation)
    inner = (n @ (np.array((0.5,0.8,3.0))/np.linalg.norm((0.5,0.8,3.0)))) > 0.3
    print("  median byte", np.median(got[inner]), end="; ")
    print(f"m={metallic} r={roughness}: pixels {len(d)}, max diff {d[inner].max()}, mean {d[inner].mean():.3f}, frac>1 {(d[inner]>1).mean():.4f}")
    return d[inner]

def pose_dir(dirn, pos=(0,0,0)):
    z = -np.asarray(dirn, float); z /= np.linalg.norm(z)
    x = np.cross([0.3, 1, 0.1], z); x /= np.linalg.norm(x); y = np.cross(z, x)
    P = np.eye(4); P[:3,0], P[:3,1], P[:3,2], P[:3,3] = x, y, z, pos; return P
lights = [(0, (1.0, 0.9, 0.8), 2.0, pose_dir((-0.3, -1, -0.5)), None),
          (1, (0.5, 0.7, 1.0), 6.0, pose_dir((0,0,-1), (1.5, 1.0, 2.0)), None),
          (2, (1.0, 1.0, 0.6), 8.0, pose_dir((-0.8, -0.2, -1.0), (1.2, 0.3, 1.8)), (0.1, 0.4))]
for met, rough in [(0.0, 0.5), (1.0, 0.3), (0.3, 0.8), (0.0, 0.02), (0.5, 1.0)]:
    run(met, rough, (0.8, 0.5, 0.3), lights, (0.1, 0.1, 0.15), emissive=(0.1, 0.0, 0.05))
run(0.2, 0.6, (0.9, 0.9, 0.9), lights[:1], (0.0, 0.0, 0.0))

# back light only: nl clamped to 0.001 leaks light (visible after the 1/2.2 gamma)
d = run(0.0, 0.5, (0.8, 0.5, 0.3), [(0, (1.0, 1.0, 1.0), 3.0, pose_dir((0.5, 0.8, 3.0)), None)], (0, 0, 0))
# vertex colours: pyrender multiplies the final colour by COLOR_0
scene = pyrender.Scene(ambient_light=np.array([0.2, 0.2, 0.2]), bg_color=[0,0,0,1])
f = lambda q: 0.55 + 0.4 * np.stack([q[:,0], q[:,1]*0.8, -q[:,2]*0.6], 1)
vc = f(sphere.vertices)
vc8 = np.round(vc * 255).astype(np.uint8)
tm = trimesh.Trimesh(sphere.vertices, sphere.faces, vertex_normals=sphere.vertices, vertex_colors=np.hstack([vc8, np.full((len(vc8),1),255,np.uint8)]), process=False)
scene.add(pyrender.Mesh.from_trimesh(tm, smooth=True))
L = lights[0]; scene.add(pyrender.DirectionalLight(color=L[1], intensity=L[2]), pose=L[3])
recs = [sr.DirectionalLight(L[1], L[2])._record_fields(L[3])]
cam = sr.PerspectiveCamera(fov_y=40.0, near=0.5, far=10.0); cam.look_at((0.5, 0.8, 3.0), (0, 0, 0))
scene.add(pyrender.PerspectiveCamera(yfov=math.radians(40.0), znear=0.5, zfar=10.0, aspectRatio=W/H), pose=cam.pose)
r = pyrender.OffscreenRenderer(W, H); color, depth = r.render(scene); r.delete()
view, proj = cam._render_matrices(W, H)
rows, cols = np.nonzero(depth > 0)
p = ref.unproject(depth, view, proj, rows, cols); n = p / np.linalg.norm(p, axis=1, keepdims=True)
inner = (n @ (np.array((0.5,0.8,3.0))/np.linalg.norm((0.5,0.8,3.0)))) > 0.5
# interpolate vertex colours: nearest vertex is too coarse; compare only statistics via barycentric-free check:
M = sr.Material(base_color=(1,1,1), metallic=0.2, roughness=0.8)
white = ref.radiance("pbr", n, p, (1,1,1), M, recs, (0.2,0.2,0.2), cam.pose[:3,3])
# vertex colour at pixel: from the nearest vertex (subdiv 6, 40962 verts: small triangles)
from scipy.spatial import cKDTree
_, idx = cKDTree(sphere.vertices).query(n)
c = f(n)
post = ref.pyrender_encode(white * c)
albedo = ref.pyrender_encode(ref.radiance("pbr", n, p, c, M, recs, (0.2,0.2,0.2), cam.pose[:3,3]))
got = color[rows, cols].astype(int)
print("vertex colours: post-multiplied median diff", np.median(np.abs(got - post)[inner]), " as albedo median diff", np.median(np.abs(got - albedo)[inner]))
